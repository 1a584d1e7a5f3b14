/*
 * docs/examples/sample_threads.c - many threads sampling one texture.
 *
 * A loom_texture is shared by every thread of a renderer: each thread
 * calls the samplers directly (no lock of yours), gets a private brick
 * cursor on its first call and shares the brick cache under one budget.
 * Here 4 threads look up a grid of points with the trilinear filter in
 * batches, and the result is checked against one thread doing all of it.
 *
 *   cc sample_threads.c $(pkg-config --cflags --libs loom) -pthread
 *   ./a.out /usr/local/share/loom/default.ldb
 */
#include "common.h"

#include <pthread.h>
#include <string.h>

#define NX 96
#define NY 96
#define NZ 40
#define NPTS (NX * NY * NZ)
#define THREADS 4
#define BATCH 512

static loom_texture *tex;
static float dens_mt[NPTS], dens_1[NPTS], orient[3 * NPTS];

/* points first .. last-1 of the grid, at off-centre positions (voxel units) */
static int sample_range(size_t first, size_t last, float *dens, float *orie)
{
	double x[BATCH], y[BATCH], z[BATCH];

	for (size_t i = first; i < last; i += BATCH) {
		size_t n = last - i < BATCH ? last - i : BATCH;
		loom_texture_channels ch;
		for (size_t k = 0; k < n; k++) {
			size_t q = i + k;
			x[k] = 0.37 + 1.5 * (double)(q % NX);
			y[k] = 0.61 + 1.5 * (double)(q / NX % NY);
			z[k] = 0.25 + 1.25 * (double)(q / NX / NY);
		}
		memset(&ch, 0, sizeof ch);
		ch.density = dens + i;
		ch.orientation = orie ? orie + 3 * i : NULL;
		if (loom_texture_sample_batch(tex, n, x, y, z, LOOM_FILTER_TRILINEAR, &ch) !=
		    LOOM_OK) {
			fprintf(stderr, "sample: %s\n", loom_texture_errmsg(tex));
			return -1;
		}
	}
	return 0;
}

static void *worker(void *arg)
{
	size_t k = (size_t)arg;
	size_t first = NPTS * k / THREADS, last = NPTS * (k + 1) / THREADS;
	return (void *)(intptr_t)sample_range(first, last, dens_mt, orient);
}

int main(int argc, char **argv)
{
	example e;
	pthread_t th[THREADS];
	int bad = 0;
	double sum = 0;
	size_t filled = 0;
	loom_texture_stats st;

	if (argc < 2) {
		fprintf(stderr, "usage: %s DATABASE.ldb\n", argv[0]);
		return 2;
	}
	example_open(&e, argv[1], "twill:2/3", 12, 12, 64, THREADS);
	tex = e.tex;
	for (size_t k = 0; k < THREADS; k++)
		pthread_create(&th[k], NULL, worker, (void *)k);
	for (size_t k = 0; k < THREADS; k++) {
		void *r;
		pthread_join(th[k], &r);
		bad |= r != NULL;
	}
	bad |= sample_range(0, NPTS, dens_1, NULL) != 0;
	for (size_t i = 0; i < NPTS; i++) {
		sum += dens_mt[i];
		filled += dens_mt[i] > 0;
	}
	loom_texture_get_stats(tex, &st);
	printf("points %d threads %d identical %s filled %.3f mean_density %.4f "
	       "peak_within_budget %s\n", NPTS, THREADS,
	       !bad && memcmp(dens_mt, dens_1, sizeof dens_1) == 0 ? "yes" : "no",
	       (double)filled / NPTS, sum / NPTS,
	       st.peak_bytes <= st.budget_bytes ? "yes" : "no");
	example_close(&e);
	return bad;
}
