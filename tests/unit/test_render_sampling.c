/*
 * tests/unit/test_render_sampling.c - the path tracer's sampling
 * (engine/render/sampler.c and the sampling loop of engine/render/render.c;
 * docs/rendering.md, "Sampling").
 *
 *  - Sobol points: the first 2^m unscrambled points of dimensions 0 and 1
 *    form a (0, m, 2)-net (every elementary interval of area 2^-m holds
 *    exactly one point, m <= 10) and every dimension 0..3 is stratified
 *    into 2^m intervals; after the index shuffle and Owen scrambling the
 *    same holds per pixel, in the first and in a later group; across
 *    pixels one point is uniform (chi-square over 4 x 4 cells, and the
 *    mean of every dimension).
 *  - Renders of a small scene (wavy fibre tubes in a bounded slab seen at
 *    an angle, background around it, a sun with a disc): identical bytes
 *    on 1, 2 and 3 threads for sobol, adaptive and progressive; sobol and
 *    random converge to the same image (per-pixel z-scores and the image
 *    mean at 256 spp); sobol's RMSE against a 2048-spp reference is
 *    below random's at 4, 16 and 64 spp (the figures docs/rendering.md
 *    quotes are printed).
 *  - Adaptive: background pixels stop at 16 samples, cloth pixels take
 *    more, the sample map adds up to the paths, and the error against the
 *    reference is within the threshold.
 *  - Progressive: the callback sees valid partial images; the final image
 *    is byte-identical to the non-progressive one; bad options refused.
 */
#include "loom.h"
#include "check.h"
#include "render/sampler.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 32
#define H 24
#define NPX (W * H)

/* ---- Sobol points ------------------------------------------------------ */

/* 1 when the n = 2^m points (x[i], y[i]) form a (0, m, 2)-net. */
static int is_net(const double *x, const double *y, int m)
{
	uint32_t n = 1u << m;
	unsigned char *cnt = malloc(n);
	int ok = 1;

	for (int a = 0; a <= m && ok; a++) {
		memset(cnt, 0, n);
		for (uint32_t i = 0; i < n; i++) {
			uint32_t cx = (uint32_t)(x[i] * (double)(1u << a));
			uint32_t cy = (uint32_t)(y[i] * (double)(1u << (m - a)));
			cnt[(cx << (m - a)) | cy]++;
		}
		for (uint32_t i = 0; i < n; i++)
			ok &= cnt[i] == 1;
	}
	free(cnt);
	return ok;
}

/* 1 when the n = 2^m values x[i] fall one in each interval [k/n, (k+1)/n). */
static int is_stratified(const double *x, int m)
{
	unsigned char cnt[1024] = {0};
	int ok = 1;
	for (uint32_t i = 0; i < (1u << m); i++)
		cnt[(uint32_t)(x[i] * (double)(1u << m))]++;
	for (uint32_t i = 0; i < (1u << m); i++)
		ok &= cnt[i] == 1;
	return ok;
}

static void test_sobol_nets(void)
{
	double x[1024], y[1024];

	for (int m = 0; m <= 10; m++) {
		uint32_t n = 1u << m;
		for (uint32_t i = 0; i < n; i++) {
			x[i] = loom__sobol32(i, 0) * (1.0 / 4294967296.0);
			y[i] = loom__sobol32(i, 1) * (1.0 / 4294967296.0);
		}
		CHECK(is_net(x, y, m));
		for (uint32_t d = 0; d < 4; d++) {
			for (uint32_t i = 0; i < n; i++)
				x[i] = loom__sobol32(i, d) * (1.0 / 4294967296.0);
			CHECK(is_stratified(x, m));
		}
	}
	/* known first points of dimension 1 (x + 1): 0, 1/2, 3/4, 1/4 */
	CHECK(loom__sobol32(1, 1) == 0x80000000u);
	CHECK(loom__sobol32(2, 1) == 0xC0000000u);
	CHECK(loom__sobol32(3, 1) == 0x40000000u);
	/* the shuffle maps every aligned block of 2^m indices one to one
	   onto an aligned block of 2^m */
	for (int m = 0; m <= 10; m++) {
		unsigned char seen[1024] = {0};
		uint32_t n = 1u << m, base = loom__ld_shuffle(3 * n, 0x1234567ull * (m + 1)) & ~(n - 1);
		for (uint32_t i = 0; i < n; i++) {
			uint32_t j = loom__ld_shuffle(i + 3 * n, 0x1234567ull * (m + 1));
			CHECK(j >= base && j - base < n);
			if (j >= base && j - base < n)
				seen[j - base]++;
		}
		for (uint32_t i = 0; i < n; i++)
			CHECK(seen[i] == 1);
	}
}

static void test_scrambled_nets(void)
{
	double x[1024], y[1024], z[1024];
	uint64_t seed = check_seed();

	for (int px = 0; px < 8; px++) {
		uint64_t ps = seed * 0x9e3779b97f4a7c15ull + (uint64_t)px;
		for (uint32_t g = 0; g < 3; g++) {
			for (int m = 0; m <= 10; m++) {
				uint32_t n = 1u << m;
				for (uint32_t i = 0; i < n; i++) {
					loom__ld s;
					loom__ld_start(&s, ps, i);
					x[i] = loom__ld_get(&s, 4 * g);
					y[i] = loom__ld_get(&s, 4 * g + 1);
					z[i] = loom__ld_get(&s, 4 * g + 3);
					CHECK(x[i] >= 0 && x[i] < 1 && y[i] >= 0 && y[i] < 1);
				}
				CHECK(is_net(x, y, m));
				CHECK(is_stratified(z, m));
			}
		}
	}
}

static void test_scrambled_uniform(void)
{
	/* sample 5 of dimension pair (4, 5) over 16000 pixel seeds: a
	   chi-square over 16 cells (15 dof; 37.7 is the 0.001 tail) and each
	   dimension's mean */
	enum { N = 16000 };
	double cnt[16] = {0}, chi = 0, mean[8] = {0};
	for (uint64_t p = 0; p < N; p++) {
		loom__ld s;
		double u, v;
		loom__ld_start(&s, p * 0xd6e8feb86659fd93ull + 1, 5);
		u = loom__ld_get(&s, 4);
		v = loom__ld_get(&s, 5);
		cnt[(int)(u * 4) * 4 + (int)(v * 4)] += 1;
		for (uint32_t d = 0; d < 8; d++)
			mean[d] += loom__ld_get(&s, d) / N;
	}
	for (int i = 0; i < 16; i++)
		chi += (cnt[i] - N / 16.0) * (cnt[i] - N / 16.0) / (N / 16.0);
	printf("  chi2 %.1f for 15 dof\n", chi);
	CHECK(chi < 37.7);
	for (uint32_t d = 0; d < 8; d++) /* sd of the mean 0.0023 */
		CHECK(fabs(mean[d] - 0.5) < 0.0115);
}

/* ---- a small scene ------------------------------------------------------ */

/* Wavy tubes along y in the slab [0,32) x [0,32) x [0,10), fibres along
   the tube. */
static int tubes_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	double cz = 5.0 + 2.0 * sin(p[1] * 0.4 + floor(p[0] / 8.0) * M_PI);
	double dx = fmod(p[0], 8.0) - 4.0, dz = p[2] - cz;
	(void)ctx;
	out->density = dx * dx + dz * dz < 9.0 ? 1.0f : 0.0f;
	out->orient[0] = 0;
	out->orient[1] = 1;
	out->orient[2] = (float)(0.8 * cos(p[1] * 0.4 + floor(p[0] / 8.0) * M_PI));
	out->albedo[0] = 0.9f;
	out->albedo[1] = 0.6f;
	out->albedo[2] = 0.3f;
	out->alignment = 0.2f;
	return 0;
}

static void scene(loom_volume_source *src, loom_render_options *o, uint32_t spp)
{
	loom_volume_source s = LOOM_VOLUME_SOURCE_INIT;
	loom_render_options d = LOOM_RENDER_OPTIONS_INIT;

	s.nx = 32;
	s.ny = 32;
	s.nz = 10;
	s.max_density = 1.0f;
	s.lookup = tubes_lookup;
	*src = s;
	*o = d;
	o->width = W;
	o->height = H;
	o->spp = spp;
	o->threads = 2;
	o->seed = 11;
	o->tile = 8;
	o->density_scale = 2.0;
	o->camera.kind = LOOM_CAMERA_PINHOLE;
	o->camera.eye[0] = 16;
	o->camera.eye[1] = -30;
	o->camera.eye[2] = 40;
	o->camera.target[0] = 16;
	o->camera.target[1] = 16;
	o->camera.target[2] = 5;
	o->camera.up[2] = 1;
	o->camera.fov_y_deg = 50;
	o->light.kind = LOOM_LIGHT_DISTANT;
	o->light.dir[0] = -0.3;
	o->light.dir[1] = 0.6;
	o->light.dir[2] = 0.8;
	o->light.angle_deg = 8.0;
	o->light.rgb[0] = o->light.rgb[1] = o->light.rgb[2] = 3.0f;
	o->env[0] = o->env[1] = o->env[2] = 0.2f;
}

static float *ref_img; /* 2048 spp, random sampler */
static float ref_var[NPX]; /* per-pixel variance of that mean (luminance) */

static double lum(const float *p)
{
	return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

static int render(loom_render_options *o, const loom_volume_source *src,
                  float *rgb, loom_render_stats *st)
{
	loom_diag d = {0};
	int rc = loom_render(src, o, rgb, st, &d);
	if (rc)
		printf("  render: %s\n", d.message);
	return rc;
}

/* The reference: 8 renders of 256 spp (random sampler, distinct seeds),
   averaged; their spread gives each pixel's variance. */
static void make_reference(void)
{
	enum { R = 8 };
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(sizeof(float) * 3 * NPX);
	double s1[NPX] = {0}, s2[NPX] = {0};

	ref_img = calloc(3 * NPX, sizeof(float));
	scene(&src, &o, 256);
	o.sampler = LOOM_SAMPLER_RANDOM;
	for (int r = 0; r < R; r++) {
		o.seed = 1000 + (uint64_t)r;
		CHECK_EQ_INT(render(&o, &src, img, NULL), LOOM_OK);
		for (int i = 0; i < NPX; i++) {
			double l = lum(img + 3 * i);
			for (int j = 0; j < 3; j++)
				ref_img[3 * i + j] += img[3 * i + j] / R;
			s1[i] += l;
			s2[i] += l * l;
		}
	}
	for (int i = 0; i < NPX; i++) {
		double m = s1[i] / R;
		ref_var[i] = (float)(fmax(s2[i] / R - m * m, 0.0) * R / (R - 1) / R);
	}
	free(img);
}

static double rmse(const float *a)
{
	double e = 0;
	for (int i = 0; i < 3 * NPX; i++)
		e += (a[i] - ref_img[i]) * (double)(a[i] - ref_img[i]);
	return sqrt(e / (3 * NPX));
}

static void test_thread_invariance(void)
{
	loom_volume_source src;
	loom_render_options o;
	static float a[3 * NPX], b[3 * NPX];
	static uint32_t na[NPX], nb[NPX];

	scene(&src, &o, 24);
	for (int mode = 0; mode < 3; mode++) {
		o.noise = mode >= 1 ? 0.05 : 0.0;
		o.samples = na;
		o.threads = 1;
		CHECK_EQ_INT(render(&o, &src, a, NULL), LOOM_OK);
		for (uint32_t th = 2; th <= 3; th++) {
			o.threads = th;
			o.tile = th == 3 ? 5 : 8;
			o.samples = nb;
			CHECK_EQ_INT(render(&o, &src, b, NULL), LOOM_OK);
			CHECK(memcmp(a, b, sizeof a) == 0);
			CHECK(memcmp(na, nb, sizeof na) == 0);
		}
	}
	o.samples = NULL;
}

static void test_same_mean(void)
{
	/* sobol and random at 256 spp: per-pixel z-scores against the
	   reference's spread and the image means */
	loom_volume_source src;
	loom_render_options o;
	static float img[2][3 * NPX];
	double mean[3] = {0, 0, 0};
	int bad = 0;

	scene(&src, &o, 256);
	for (int k = 0; k < 2; k++) {
		o.sampler = k ? LOOM_SAMPLER_RANDOM : LOOM_SAMPLER_SOBOL;
		o.seed = 77;
		CHECK_EQ_INT(render(&o, &src, img[k], NULL), LOOM_OK);
		for (int i = 0; i < NPX; i++)
			mean[k] += lum(img[k] + 3 * i) / NPX;
	}
	for (int i = 0; i < NPX; i++) {
		/* a 256-spp render has 8x the variance of the 2048-spp mean */
		double sd = sqrt(9.0 * ref_var[i]) + 1e-6;
		double z = (lum(img[0] + 3 * i) - lum(ref_img + 3 * i)) / sd;
		bad += fabs(z) > 5;
		mean[2] += lum(ref_img + 3 * i) / NPX;
	}
	printf("  image mean sobol %.5f random %.5f reference %.5f; %d of %d "
	       "pixels with |z| > 5\n", mean[0], mean[1],
	       mean[2], bad, NPX);
	CHECK(bad <= 2);
	CHECK(fabs(mean[0] - mean[1]) < 0.01 * mean[1]);
}

static void test_rmse(void)
{
	loom_volume_source src;
	loom_render_options o;
	static float img[3 * NPX];
	static const uint32_t spps[] = {4, 16, 64};

	printf("  RMSE against 2048 spp (mean of 4 seeds): spp, sobol, random\n");
	for (int k = 0; k < 3; k++) {
		double e[2] = {0, 0};
		for (int s = 0; s < 2; s++) {
			scene(&src, &o, spps[k]);
			o.sampler = s ? LOOM_SAMPLER_RANDOM : LOOM_SAMPLER_SOBOL;
			for (int r = 0; r < 4; r++) {
				o.seed = 500 + (uint64_t)r;
				CHECK_EQ_INT(render(&o, &src, img, NULL), LOOM_OK);
				e[s] += rmse(img) / 4;
			}
		}
		printf("  %u %.5f %.5f (ratio %.2f)\n", spps[k], e[0], e[1], e[0] / e[1]);
		CHECK(e[0] < e[1]);
	}
}

static void test_adaptive(void)
{
	loom_volume_source src;
	loom_render_options o;
	loom_render_stats st;
	static float img[3 * NPX];
	static uint32_t n[NPX];
	const double noise = 0.05;
	uint64_t sum = 0;
	int bg = 0, bg_early = 0, cl = 0, over = 0;
	double cl_n = 0, e2 = 0;

	scene(&src, &o, 512);
	o.noise = noise;
	o.samples = n;
	CHECK_EQ_INT(render(&o, &src, img, &st), LOOM_OK);
	for (int i = 0; i < NPX; i++) {
		double r = lum(ref_img + 3 * i), a = lum(img + 3 * i), rel;
		sum += n[i];
		CHECK(n[i] >= 16 && n[i] <= 512);
		if (fabs(r - 0.2) < 1e-6 && ref_var[i] == 0) { /* background */
			bg++;
			bg_early += n[i] == 16;
			continue;
		}
		cl++;
		cl_n += n[i];
		rel = (a - r) / r;
		e2 += rel * rel;
		over += fabs(rel) > 3 * noise + 3 * sqrt(ref_var[i]) / r;
	}
	printf("  background %d pixels (%d at 16 samples), cloth %d pixels at "
	       "%.1f samples on average; relative error rms %.4f, %d over 3x\n",
	       bg, bg_early, cl, cl_n / (cl ? cl : 1), sqrt(e2 / (cl ? cl : 1)), over);
	CHECK_EQ_INT(sum, st.paths);
	CHECK(bg > 50 && bg_early == bg);
	CHECK(cl > 100 && cl_n / cl > 32);
	CHECK(sqrt(e2 / cl) <= 1.5 * noise);
	CHECK(over <= cl / 50);
}

typedef struct pcall {
	int calls, bad;
} pcall;

static void on_progress(void *user, const float *rgb)
{
	pcall *p = user;
	p->calls++;
	for (int i = 0; i < 3 * NPX; i++)
		p->bad += !(rgb[i] >= 0 && isfinite(rgb[i]));
}

static void test_progressive(void)
{
	loom_volume_source src;
	loom_render_options o;
	loom_render_stats st;
	static float a[3 * NPX], b[3 * NPX];
	static uint32_t na[NPX], nb[NPX];
	loom_diag d = {0};

	scene(&src, &o, 200);
	for (int mode = 0; mode < 2; mode++) {
		pcall pc = {0, 0};
		o.noise = mode ? 0.03 : 0.0;
		o.samples = na;
		o.progressive_seconds = 0;
		o.progressive = NULL;
		CHECK_EQ_INT(render(&o, &src, a, NULL), LOOM_OK);
		o.samples = nb;
		o.progressive_seconds = 0.002;
		o.progressive = on_progress;
		o.progressive_user = &pc;
		o.threads = 3;
		CHECK_EQ_INT(render(&o, &src, b, &st), LOOM_OK);
		o.threads = 2;
		printf("  %s: %d intermediate images in %.2f s\n",
		       mode ? "adaptive" : "fixed spp", pc.calls, st.seconds);
		CHECK(memcmp(a, b, sizeof a) == 0);
		CHECK(memcmp(na, nb, sizeof na) == 0);
		CHECK_EQ_INT(pc.bad, 0);
		/* not a speed check: only when the render outlasted many periods */
		if (st.seconds > 0.2)
			CHECK(pc.calls >= 1);
	}
	{
		/* one sample: a single pass, nothing to show in between */
		pcall pc = {0, 0};
		o.samples = NULL;
		o.spp = 1;
		o.progressive_seconds = 0.001;
		o.progressive_user = &pc;
		CHECK_EQ_INT(render(&o, &src, b, NULL), LOOM_OK);
		CHECK_EQ_INT(pc.calls, 0);
		o.progressive_seconds = 0;
		CHECK_EQ_INT(render(&o, &src, a, NULL), LOOM_OK);
		CHECK(memcmp(a, b, sizeof a) == 0);
	}
	o.samples = NULL;
	o.progressive = NULL;
	o.progressive_seconds = 1.0;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "progressive");
	o.progressive_seconds = 0;
	o.noise = -1;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "noise");
	o.noise = 0;
	o.sampler = 7;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "sampler");
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_render_sampling");
	RUN(test_sobol_nets);
	RUN(test_scrambled_nets);
	RUN(test_scrambled_uniform);
	make_reference();
	RUN(test_thread_invariance);
	RUN(test_same_mean);
	RUN(test_rmse);
	RUN(test_adaptive);
	RUN(test_progressive);
	free(ref_img);
	CHECK_MAIN_END();
}
