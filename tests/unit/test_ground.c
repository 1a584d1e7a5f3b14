/*
 * tests/unit/test_ground.c - the renderer's floor (loom_ground), its AOV
 * outputs (loom_render_aov) and tone curves (engine/render/ground.c,
 * aov.c, tone.c): a diffuse plane under a constant environment and a sun
 * with the cloth removed gives the analytic radiance A (L + E cos / pi)
 * exactly, and under a constant environment map (MIS) converges to A L;
 * the cloth's shadow on the floor is darker than the lit floor; AOVs are
 * the floor's albedo, normal and depth where they are known, the noise
 * estimate matches the spread of identically distributed pixels, asking
 * for AOVs leaves the beauty bytes alone, and every output is the same
 * for any thread count; the filmic curve; bad input.
 */
#include "loom.h"
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { W = 24, H = 16, NPX = W * H };

/* A grey slab with fibres along x (bounded by the source's nx, ny). */
static int slab_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	(void)ctx;
	(void)p;
	out->density = 1.0f;
	out->orient[0] = 1;
	out->albedo[0] = out->albedo[1] = out->albedo[2] = 0.7f;
	out->alignment = 0.3f;
	return 0;
}

/* Slab [0,10) x [0,10) x [0,2); floor z = -5 of albedo (0.6, 0.4, 0.2);
   orthographic camera straight down on [x0, x0 + 30] x [-5, 15]. */
static void setup(loom_volume_source *src, loom_render_options *o, double x0)
{
	loom_volume_source sd = LOOM_VOLUME_SOURCE_INIT;
	loom_render_options od = LOOM_RENDER_OPTIONS_INIT;
	*src = sd;
	src->nx = 10;
	src->ny = 10;
	src->nz = 2;
	src->max_density = 1;
	src->lookup = slab_lookup;
	*o = od;
	o->width = W;
	o->height = H;
	o->spp = 8;
	o->threads = 2;
	o->seed = 5;
	o->density_scale = 20.0; /* opaque */
	o->camera.kind = LOOM_CAMERA_ORTHO;
	o->camera.eye[0] = o->camera.target[0] = x0 + 15;
	o->camera.eye[1] = o->camera.target[1] = 5;
	o->camera.eye[2] = 20;
	o->camera.target[2] = 0;
	o->camera.up[0] = o->camera.up[2] = 0;
	o->camera.up[1] = 1;
	o->camera.ortho_size[0] = 30;
	o->camera.ortho_size[1] = 20;
	o->ground.enabled = 1;
	o->ground.height = -5;
	o->ground.albedo[0] = 0.6f;
	o->ground.albedo[1] = 0.4f;
	o->ground.albedo[2] = 0.2f;
}

/* Floor only (the cloth removed: density scale 0; out of view is not
   enough, a grazing bounce can reach it): exact radiance per pixel. */
static void test_floor_exact(void)
{
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(NPX * 3 * sizeof *img);
	double E = 2.0, L = 0.25, cosv = 0.8, worst = 0;

	setup(&src, &o, 100);
	o.density_scale = 0;
	o.env[0] = o.env[1] = o.env[2] = (float)L;
	o.light.kind = LOOM_LIGHT_DISTANT;
	o.light.dir[0] = 0;
	o.light.dir[1] = 0.6;
	o.light.dir[2] = cosv;
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = (float)E;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int i = 0; i < NPX; i++)
		for (int c = 0; c < 3; c++) {
			double want = o.ground.albedo[c] * (L + E * cosv / M_PI);
			double e = fabs(img[3 * i + c] - want) / want;
			worst = e > worst ? e : worst;
		}
	printf("  floor A (L + E cos / pi): worst relative error %.2e\n", worst);
	CHECK(worst < 1e-5);
	free(img);
}

/* Floor under a constant environment map, the cloth removed: MIS of map
   and cosine sampling converges to A L. */
static void test_floor_furnace(void)
{
	loom_volume_source src;
	loom_render_options o;
	loom_envmap *m = NULL;
	float map[16 * 8 * 3], *img = malloc(NPX * 3 * sizeof *img);
	double s[3] = {0, 0, 0}, s2[3] = {0, 0, 0};

	for (int i = 0; i < 16 * 8 * 3; i++)
		map[i] = 0.5f;
	CHECK_EQ_INT(loom_envmap_new(map, 16, 8, 10.0, 1.0, &m, NULL), LOOM_OK);
	setup(&src, &o, 100);
	o.density_scale = 0;
	o.light.kind = LOOM_LIGHT_NONE;
	o.envmap = m;
	o.spp = 4;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int i = 0; i < NPX; i++)
		for (int c = 0; c < 3; c++) {
			s[c] += img[3 * i + c];
			s2[c] += (double)img[3 * i + c] * img[3 * i + c];
		}
	for (int c = 0; c < 3; c++) {
		double mean = s[c] / NPX, se = sqrt(fmax(0, s2[c] / NPX - mean * mean) / NPX);
		double want = 0.5 * o.ground.albedo[c];
		printf("  floor under a constant map, channel %d: %.5f +- %.5f (want %.5f)\n",
		       c, mean, se, want);
		CHECK(fabs(mean - want) < 4 * se + 1e-6);
	}
	free(img);
	loom_envmap_free(m);
}

/* The slab's shadow: a sun from (1, 0, 1) casts the slab [0,10) x [0,2)
   onto the floor z = -5 over x in [-7, 5); from above, x in [-5, 0) is
   floor in shadow and x in [12, 25) floor in the open. */
static void test_shadow(void)
{
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(NPX * 3 * sizeof *img);
	double sh = 0, lit = 0, want;
	int nsh = 0, nlit = 0;

	setup(&src, &o, -10);
	o.env[0] = o.env[1] = o.env[2] = 0.05f;
	o.light.kind = LOOM_LIGHT_DISTANT;
	o.light.dir[0] = 1;
	o.light.dir[1] = 0;
	o.light.dir[2] = 1;
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = 3.0f;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			double wx = -10 + 30.0 * (x + 0.5) / W;
			double wy = 15 - 20.0 * (y + 0.5) / H;
			double v = img[3 * (y * W + x)];
			if (wy < 1 || wy > 9)
				continue;
			if (wx > -4.5 && wx < -0.5) {
				sh += v;
				nsh++;
			} else if (wx > 12.5) {
				lit += v;
				nlit++;
			}
		}
	CHECK(nsh > 0 && nlit > 0);
	sh /= nsh;
	lit /= nlit;
	want = 0.6 * (0.05 + 3.0 / sqrt(2.0) / M_PI);
	printf("  floor in shadow %.4f, in the open %.4f (direct alone %.4f)\n", sh,
	       lit, want);
	CHECK(sh < 0.3 * lit);
	CHECK(lit > 0.97 * want && lit < 1.3 * want);
	free(img);
}

static void test_aovs(void)
{
	loom_volume_source src;
	loom_render_options o;
	size_t n = NPX;
	float *a = malloc(n * 3 * sizeof *a), *b = malloc(n * 3 * sizeof *b);
	float *bufs[2][4];
	loom_render_aov av[2];
	int ok_albedo = 1, ok_normal = 1, ok_depth = 1, nslab = 0;

	for (int k = 0; k < 2; k++) {
		bufs[k][0] = malloc(n * 3 * sizeof(float));
		bufs[k][1] = malloc(n * 3 * sizeof(float));
		bufs[k][2] = malloc(n * sizeof(float));
		bufs[k][3] = malloc(n * 3 * sizeof(float));
		av[k].albedo = bufs[k][0];
		av[k].normal = bufs[k][1];
		av[k].depth = bufs[k][2];
		av[k].noise = bufs[k][3];
	}
	setup(&src, &o, -10);
	o.light.dir[0] = 0.4;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	o.aov = &av[0];
	o.threads = 1;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * 3 * sizeof *a) == 0); /* AOVs leave the beauty */
	o.aov = &av[1];
	o.threads = 3;
	o.tile = 5;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * 3 * sizeof *a) == 0);
	CHECK(memcmp(bufs[0][0], bufs[1][0], n * 3 * sizeof(float)) == 0);
	CHECK(memcmp(bufs[0][1], bufs[1][1], n * 3 * sizeof(float)) == 0);
	CHECK(memcmp(bufs[0][2], bufs[1][2], n * sizeof(float)) == 0);
	CHECK(memcmp(bufs[0][3], bufs[1][3], n * 3 * sizeof(float)) == 0);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			size_t i = (size_t)y * W + x;
			double wx = -10 + 30.0 * (x + 0.5) / W, wy = 15 - 20.0 * (y + 0.5) / H;
			const float *al = av[0].albedo + 3 * i, *nr = av[0].normal + 3 * i;
			if (wx > 0.5 && wx < 9.5 && wy > 0.5 && wy < 9.5) {
				/* the slab's top: albedo 0.7, normal up, depth 18 */
				nslab++;
				if (fabs(al[0] - 0.7) > 1e-6)
					ok_albedo = 0;
				if (!(nr[2] > 0.9))
					ok_normal = 0;
				if (!(av[0].depth[i] > 17.5 && av[0].depth[i] < 18.1))
					ok_depth = 0;
			} else if (wx < -0.5 || wx > 10.5 || wy < -0.5 || wy > 10.5) {
				/* the floor: exact values */
				if (fabs(al[0] - 0.6f) > 1e-6 || fabs(al[2] - 0.2f) > 1e-6)
					ok_albedo = 0;
				if (nr[0] != 0 || nr[1] != 0 || fabs(nr[2] - 1) > 1e-6)
					ok_normal = 0;
				if (fabs(av[0].depth[i] - 25.0) > 1e-4)
					ok_depth = 0;
			}
		}
	CHECK(nslab > 20);
	CHECK(ok_albedo);
	CHECK(ok_normal);
	CHECK(ok_depth);
	for (int k = 0; k < 2; k++)
		for (int j = 0; j < 4; j++)
			free(bufs[k][j]);
	free(a);
	free(b);
}

/* The noise AOV against the spread of pixels with one distribution: an
   unbounded slab seen straight down. */
static void test_noise_estimate(void)
{
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(NPX * 3 * sizeof *img), *nz = malloc(NPX * 3 * sizeof *nz);
	loom_render_aov av = {NULL, NULL, NULL, nz};
	double s = 0, s2 = 0, ms = 0, sd;

	setup(&src, &o, 0);
	src.nx = src.ny = 0;
	o.ground.enabled = 0;
	o.density_scale = 0.3;
	o.spp = 16;
	o.aov = &av;
	/* the estimate is the standard error of independent samples: with the
	   random sampler it matches the spread of pixel means; with Sobol
	   (stratified, so the means spread less) it is an upper bound */
	for (int pass = 0; pass < 2; pass++) {
		o.sampler = pass ? LOOM_SAMPLER_SOBOL : LOOM_SAMPLER_RANDOM;
		s = s2 = ms = 0;
		CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
		for (int i = 0; i < NPX; i++) {
			s += img[3 * i];
			s2 += (double)img[3 * i] * img[3 * i];
			ms += (double)nz[3 * i] * nz[3 * i];
		}
		sd = sqrt(fmax(0, s2 / NPX - (s / NPX) * (s / NPX)));
		ms = sqrt(ms / NPX);
		printf("  %s: spread of pixel means %.5f, rms noise estimate %.5f\n",
		       pass ? "sobol" : "random", sd, ms);
		CHECK(ms > 0);
		if (pass)
			CHECK(sd < ms);
		else
			CHECK(fabs(ms - sd) < 0.25 * sd);
	}
	free(img);
	free(nz);
}

static void test_tone_and_errors(void)
{
	float px[6] = {0.0f, 0.18f, 0.5f, 1.0f, 8.0f, NAN};
	uint8_t a[6], b[6];
	loom_volume_source src;
	loom_render_options o;
	float img[NPX * 3];
	loom_diag d = {0};
	double prev = -1;

	CHECK(loom_tone_filmic(0) == 0 && loom_tone_filmic(NAN) == 0);
	CHECK(fabs(loom_tone_filmic(0.18) - 0.18 * (2.51 * 0.18 + 0.03) /
	                                     (0.18 * (2.43 * 0.18 + 0.59) + 0.14)) < 1e-15);
	CHECK(loom_tone_filmic(7.25) == 1.0 && loom_tone_filmic(7.2) < 1.0);
	for (int i = 0; i <= 800; i++) {
		double y = loom_tone_filmic(i * 0.01);
		CHECK(y >= prev);
		prev = y;
	}
	loom_render_to_srgb8(px, 2, 0.5, a);
	loom_render_to_srgb8_tone(px, 2, 0.5, LOOM_TONE_LINEAR, b);
	CHECK(memcmp(a, b, 6) == 0);
	loom_render_to_srgb8_tone(px, 2, 0.0, LOOM_TONE_FILMIC, b);
	CHECK(b[0] == 0 && b[3] < 255 && b[4] == 255 && b[5] == 0);
	{
		/* 0.18 through the curve, then the sRGB transfer curve */
		double y = loom_tone_filmic((double)0.18f);
		y = 1.055 * pow(y, 1.0 / 2.4) - 0.055;
		CHECK(b[1] == (uint8_t)(y * 255.0 + 0.5));
		CHECK(b[1] > a[1]); /* brighter mid-tones than linear at +0.5 */
	}
	setup(&src, &o, 0);
	o.ground.albedo[1] = 1.5f;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "ground albedo");
	o.ground.albedo[1] = 0.5f;
	o.ground.height = INFINITY;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "ground height");
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_ground");
	RUN(test_floor_exact);
	RUN(test_floor_furnace);
	RUN(test_shadow);
	RUN(test_aovs);
	RUN(test_noise_estimate);
	RUN(test_tone_and_errors);
	CHECK_MAIN_END();
}
