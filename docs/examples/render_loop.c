/*
 * docs/examples/render_loop.c - a renderer's inner loop calling the
 * samplers: a tiny volume ray marcher.
 *
 * An orthographic camera looks down -z at the cloth; for each pixel the
 * ray steps through the cloth's thickness calling loom_texture_sample
 * (trilinear), accumulates single-scattering from a light above with
 * Beer-Lambert attenuation (density x sigma per voxel) and the yarn
 * albedo, and writes a binary PPM.  Rows are shared by threads.  A real
 * renderer would add the microflake phase function from the orientation
 * (docs/rendering.md); this shows the calls and their cost model.
 *
 *   cc render_loop.c $(pkg-config --cflags --libs loom) -pthread -lm
 *   ./a.out /usr/local/share/loom/default.ldb out.ppm
 */
#include "common.h"

#include <math.h>
#include <pthread.h>

#define W 160
#define H 120
#define THREADS 2
#define ZTOP 64.0   /* voxels: above the cloth */
#define STEP 0.5    /* voxels per ray step */
#define SIGMA 0.6   /* extinction per voxel at density 1 */

static loom_texture *tex;
static unsigned char img[H][W][3];
static double coverage[H];

static void render_row(int py)
{
	double covered = 0;
	for (int px = 0; px < W; px++) {
		double p[3] = {0.5 + px, 0.5 + py, ZTOP}, T = 1.0, c[3] = {0, 0, 0};
		for (; p[2] > 0 && T > 1e-3; p[2] -= STEP) {
			loom_texel v;
			double a;
			if (loom_texture_sample(tex, p, LOOM_FILTER_TRILINEAR, &v) != LOOM_OK)
				break;
			if (v.density <= 0)
				continue;
			a = 1.0 - exp(-SIGMA * v.density * STEP);
			/* light from above, lit as much as the ray so far (same path) */
			for (int k = 0; k < 3; k++)
				c[k] += T * a * v.albedo[k] * T;
			T *= 1.0 - a;
		}
		covered += T < 0.5;
		for (int k = 0; k < 3; k++) {
			/* white background behind the cloth, then sRGB-ish gamma */
			double lin = c[k] + T * 1.0;
			int b = (int)(255.0 * pow(lin < 1 ? lin : 1, 1 / 2.2) + 0.5);
			img[py][px][k] = (unsigned char)b;
		}
	}
	coverage[py] = covered / W;
}

static void *worker(void *arg)
{
	for (int py = (int)(intptr_t)arg; py < H; py += THREADS)
		render_row(py);
	loom_texture_thread_done(tex);
	return NULL;
}

int main(int argc, char **argv)
{
	example e;
	pthread_t th[THREADS];
	double cov = 0;
	FILE *f;

	if (argc < 3) {
		fprintf(stderr, "usage: %s DATABASE.ldb OUT.ppm\n", argv[0]);
		return 2;
	}
	example_open(&e, argv[1], "plain", 16, 16, 64, THREADS);
	tex = e.tex;
	for (intptr_t k = 0; k < THREADS; k++)
		pthread_create(&th[k], NULL, worker, (void *)k);
	for (int k = 0; k < THREADS; k++)
		pthread_join(th[k], NULL);
	for (int y = 0; y < H; y++)
		cov += coverage[y] / H;
	if (!(f = fopen(argv[2], "wb"))) {
		perror(argv[2]);
		return 1;
	}
	fprintf(f, "P6\n%d %d\n255\n", W, H);
	fwrite(img, 1, sizeof img, f);
	if (fclose(f) != 0)
		return 1;
	printf("%s %dx%d coverage %.3f\n", argv[2], W, H, cov);
	example_close(&e);
	return 0;
}
