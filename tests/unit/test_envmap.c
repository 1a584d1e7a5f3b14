/*
 * tests/unit/test_envmap.c - HDR environment maps (engine/render/envmap.c)
 * and their use by the path tracer: the sampler's pdf integrates to 1 and
 * matches the histogram of its samples, MIS weights sum to 1, a white
 * non-absorbing medium under a constant map converges to the map (furnace),
 * a map with one bright pixel matches a sun of the same direction, solid
 * angle and irradiance, determinism over thread counts, bad input.
 */
#include "loom.h"
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 12345;

static double urand(void)
{
	return loom_rng_uniform(&rng_state);
}

/* A map with varied positive values (and one black row). */
static float *test_map(uint32_t w, uint32_t h)
{
	float *m = malloc((size_t)w * h * 3 * sizeof *m);
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++)
			for (int c = 0; c < 3; c++)
				m[3 * ((size_t)y * w + x) + c] =
				    y == 2 ? 0.0f
				           : (float)(0.1 + (x * 7 + y * 3 + c) % 11 *
				                               (y == 1 ? 5.0 : 0.3));
	return m;
}

static void pixel_of(double th, double ph, uint32_t w, uint32_t h, uint32_t *x,
                     uint32_t *y)
{
	double u = ph / (2 * M_PI);
	u -= floor(u);
	*x = (uint32_t)(u * w);
	*y = (uint32_t)(th / M_PI * h);
	if (*x >= w)
		*x = w - 1;
	if (*y >= h)
		*y = h - 1;
}

static void test_pdf_and_histogram(void)
{
	uint32_t w = 16, h = 8;
	float *rgb = test_map(w, h);
	loom_envmap *m = NULL;
	double integral = 0, worst = 0, chi2 = 0;
	int nth = 400, nph = 800, n = 400000, bad_pdf = 0;
	double *cnt = calloc((size_t)w * h, sizeof *cnt);

	CHECK_EQ_INT(loom_envmap_new(rgb, w, h, 30.0, 2.0, &m, NULL), LOOM_OK);
	/* midpoint rule over the sphere */
	for (int i = 0; i < nth; i++) {
		double th = M_PI * (i + 0.5) / nth;
		for (int j = 0; j < nph; j++) {
			double ph = 2 * M_PI * (j + 0.5) / nph;
			double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
			integral += loom_envmap_pdf(m, d) * sin(th) * (M_PI / nth) *
			            (2 * M_PI / nph);
		}
	}
	printf("  integral of the pdf: %.6f\n", integral);
	CHECK(fabs(integral - 1.0) < 2e-3);
	/* histogram of samples per pixel against pdf x solid angle; the map
	   is rotated by 30 degrees, so bin by the unrotated azimuth */
	for (int k = 0; k < n; k++) {
		double d[3], p = loom_envmap_sample(m, urand(), urand(), d), th, ph;
		uint32_t x, y;
		if (fabs(p - loom_envmap_pdf(m, d)) > 1e-6 * p)
			bad_pdf++;
		th = acos(d[2] > 1 ? 1 : d[2] < -1 ? -1 : d[2]);
		ph = atan2(d[1], d[0]) - 30.0 * M_PI / 180.0;
		pixel_of(th, ph, w, h, &x, &y);
		cnt[(size_t)y * w + x] += 1;
	}
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++) {
			double th = M_PI * (y + 0.5) / h;
			double ph = 2 * M_PI * (x + 0.5) / w + 30.0 * M_PI / 180.0;
			double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
			double sa = 2 * M_PI / w * (cos(M_PI * y / h) - cos(M_PI * (y + 1) / h));
			double e = loom_envmap_pdf(m, d) * sa * n, z;
			double lum = 0.2126 * rgb[3 * (y * w + x)] +
			             0.7152 * rgb[3 * (y * w + x) + 1] +
			             0.0722 * rgb[3 * (y * w + x) + 2];
			if (lum == 0) { /* black pixels are never sampled */
				CHECK(cnt[y * w + x] == 0);
				CHECK(e == 0);
				continue;
			}
			z = (cnt[y * w + x] - e) / sqrt(e);
			chi2 += z * z;
			if (fabs(z) > worst)
				worst = fabs(z);
		}
	printf("  histogram: chi2 %.1f over %u bins, worst z %.2f, pdf mismatches %d\n",
	       chi2, (w * h) - w, worst, bad_pdf);
	CHECK(worst < 5.0);
	CHECK(chi2 < 2.0 * (w * h));
	CHECK_EQ_INT(bad_pdf, 0);
	free(cnt);
	free(rgb);
	loom_envmap_free(m);
}

static void test_mis_weights(void)
{
	uint32_t w = 16, h = 8;
	float *rgb = test_map(w, h);
	loom_envmap *m = NULL;
	double wmax = 0;
	const double fibre[3] = {0.3, 0.9, 0.1};

	CHECK_EQ_INT(loom_envmap_new(rgb, w, h, 0.0, 1.0, &m, NULL), LOOM_OK);
	for (int k = 0; k < 2000; k++) {
		double wi[3], wo[3], pe, pf, sum;
		double ct = 2 * urand() - 1, st = sqrt(1 - ct * ct), ph = 2 * M_PI * urand();
		wi[0] = st * cos(ph);
		wi[1] = st * sin(ph);
		wi[2] = ct;
		if (k % 2)
			loom_microflake_sample(0.2, fibre, wi, &rng_state, wo);
		else
			loom_envmap_sample(m, urand(), urand(), wo);
		pe = loom_envmap_pdf(m, wo);
		pf = loom_microflake_eval(0.2, fibre, wi, wo);
		sum = loom_mis_power(pe, pf) + loom_mis_power(pf, pe);
		if (pe > 0 || pf > 0)
			wmax = fmax(wmax, fabs(sum - 1.0));
	}
	printf("  MIS weights: largest |w_env + w_phase - 1| = %.3g\n", wmax);
	CHECK(wmax < 1e-12);
	CHECK(loom_mis_power(0.0, 3.0) == 0.0);
	CHECK(loom_mis_power(2.0, 0.0) == 1.0);
	CHECK(fabs(loom_mis_power(1.0, 1.0) - 0.5) < 1e-15);
	free(rgb);
	loom_envmap_free(m);
}

/* A uniform slab with fibres along y. */
static int slab_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	const float *albedo = ctx;
	(void)p;
	out->density = 1.0f;
	out->orient[0] = 0;
	out->orient[1] = 1;
	out->orient[2] = 0.3f;
	memcpy(out->albedo, albedo, sizeof out->albedo);
	out->alignment = 0.2f;
	return 0;
}

static void setup(loom_volume_source *src, loom_render_options *o,
                  const float *albedo, uint32_t spp)
{
	loom_volume_source sd = LOOM_VOLUME_SOURCE_INIT;
	loom_render_options od = LOOM_RENDER_OPTIONS_INIT;
	*src = sd;
	src->nz = 6;
	src->voxel_mm = 0.005;
	src->lookup = slab_lookup;
	src->ctx = (void *)albedo;
	*o = od;
	o->width = 16;
	o->height = 12;
	o->spp = spp;
	o->threads = 2;
	o->seed = 3;
	o->density_scale = 0.8;
	o->camera.kind = LOOM_CAMERA_PINHOLE;
	o->camera.eye[0] = 0;
	o->camera.eye[1] = -20;
	o->camera.eye[2] = 30;
	memset(o->camera.target, 0, sizeof o->camera.target);
	o->camera.up[0] = o->camera.up[1] = 0;
	o->camera.up[2] = 1;
	o->camera.fov_y_deg = 40;
}

static void mean_se(const float *img, size_t npx, double *mean, double *se)
{
	double s = 0, s2 = 0;
	for (size_t i = 0; i < npx; i++) {
		double v = img[3 * i];
		s += v;
		s2 += v * v;
	}
	*mean = s / npx;
	*se = sqrt(fmax(0.0, s2 / npx - *mean * *mean) / npx);
}

static void test_furnace(void)
{
	static const float white[3] = {1, 1, 1};
	uint32_t w = 8, h = 4;
	float map[8 * 4 * 3], *img = malloc(16 * 12 * 3 * sizeof *img);
	loom_envmap *m = NULL;
	loom_volume_source src;
	loom_render_options o;
	loom_render_stats st;
	double mean, se;

	for (int i = 0; i < 8 * 4 * 3; i++)
		map[i] = 0.6f;
	CHECK_EQ_INT(loom_envmap_new(map, w, h, 0.0, 1.0, &m, NULL), LOOM_OK);
	setup(&src, &o, white, 32);
	o.light.kind = LOOM_LIGHT_NONE;
	o.max_depth = 100000;
	o.rr_depth = 100000;
	o.envmap = m;
	CHECK_EQ_INT(loom_render(&src, &o, img, &st, NULL), LOOM_OK);
	mean_se(img, 16 * 12, &mean, &se);
	printf("  furnace under a constant map 0.6: %.5f +- %.5f (%llu scatterings)\n",
	       mean, se, (unsigned long long)st.scatterings);
	CHECK(st.scatterings > st.paths);
	CHECK(fabs(mean - 0.6) < 4 * se + 1e-6);
	CHECK(se < 0.02);
	free(img);
	loom_envmap_free(m);
}

static void test_bright_pixel_is_a_sun(void)
{
	static const float albedo[3] = {0.8f, 0.8f, 0.8f};
	enum { W = 64, H = 32 };
	uint32_t px = 20, py = 8;
	float *map = calloc(W * H * 3, sizeof *map);
	float *a = malloc(16 * 12 * 3 * sizeof *a), *b = malloc(16 * 12 * 3 * sizeof *b);
	loom_envmap *m = NULL;
	loom_volume_source src;
	loom_render_options o;
	double V = 400.0, th = M_PI * (py + 0.5) / H, ph = 2 * M_PI * (px + 0.5) / W;
	double sa = 2 * M_PI / W * (cos(M_PI * py / H) - cos(M_PI * (py + 1) / H));
	double ma, sea, mb, seb;

	for (int c = 0; c < 3; c++)
		map[3 * (py * W + px) + c] = (float)V;
	CHECK_EQ_INT(loom_envmap_new(map, W, H, 0.0, 1.0, &m, NULL), LOOM_OK);
	setup(&src, &o, albedo, 256);
	/* straight down, orthographic: every pixel has the same expectation,
	   so the spread over pixels is the Monte Carlo error */
	o.camera.kind = LOOM_CAMERA_ORTHO;
	o.camera.eye[1] = 0;
	o.camera.up[1] = 1;
	o.camera.up[2] = 0;
	o.camera.ortho_size[0] = 16;
	o.camera.ortho_size[1] = 12;
	o.light.kind = LOOM_LIGHT_NONE;
	o.envmap = m;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	/* the same light as a sun: direction of the pixel's centre, disc of the
	   same solid angle, irradiance = radiance x solid angle */
	o.envmap = NULL;
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.light.kind = LOOM_LIGHT_DISTANT;
	o.light.dir[0] = sin(th) * cos(ph);
	o.light.dir[1] = sin(th) * sin(ph);
	o.light.dir[2] = cos(th);
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = (float)(V * sa);
	o.light.angle_deg = 2.0 * acos(1.0 - sa / (2 * M_PI)) * 180.0 / M_PI;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	mean_se(a, 16 * 12, &ma, &sea);
	mean_se(b, 16 * 12, &mb, &seb);
	printf("  one bright pixel %.5f +- %.5f, sun %.5f +- %.5f (disc %.2f deg)\n",
	       ma, sea, mb, seb, o.light.angle_deg);
	CHECK(mb > 0.01);
	CHECK(fabs(ma - mb) < 4 * sqrt(sea * sea + seb * seb) + 0.01 * mb);
	free(map);
	free(a);
	free(b);
	loom_envmap_free(m);
}

static void test_threads_and_errors(void)
{
	static const float albedo[3] = {0.9f, 0.7f, 0.5f};
	uint32_t w = 16, h = 8;
	float *rgb = test_map(w, h);
	size_t n = 16 * 12 * 3;
	float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
	loom_envmap *m = NULL;
	loom_volume_source src;
	loom_render_options o;
	loom_diag d = {0};

	CHECK_EQ_INT(loom_envmap_new(rgb, w, h, 45.0, 0.5, &m, NULL), LOOM_OK);
	setup(&src, &o, albedo, 4);
	o.envmap = m;
	o.threads = 1;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	o.threads = 3;
	o.tile = 5;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) == 0);
	loom_envmap_free(m);
	CHECK(loom_envmap_bytes(w, h) >= (size_t)w * h * 16);
	rgb[7] = -1.0f;
	CHECK_EQ_INT(loom_envmap_new(rgb, w, h, 0.0, 1.0, &m, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "pixel (2, 0)");
	rgb[7] = NAN;
	CHECK_EQ_INT(loom_envmap_new(rgb, w, h, 0.0, 1.0, &m, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_envmap_new(rgb, 0, h, 0.0, 1.0, &m, &d), LOOM_ERANGE);
	CHECK_EQ_INT(loom_envmap_new(rgb, 4096, 2048, 0.0, 1.0, &m, &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, "at most");
	CHECK(m == NULL);
	free(rgb);
	free(a);
	free(b);
}

/* The built-in studio sky: its shape, the map loom render builds from it
   against quadrature of the analytic sky, and importance sampling of the
   map estimating the analytic sky's integral without bias. */
static void test_studio_sky(void)
{
	const double el = 35.0 * M_PI / 180.0, az = 0.7;
	double sun[3] = {cos(el) * cos(az), cos(el) * sin(az), sin(el)};
	double zen[3], hor[3], nad[3], toward[3], away[3];
	const uint32_t W = LOOM_SKY_MAP_W, H = LOOM_SKY_MAP_H;
	float *px = malloc((size_t)3 * W * H * sizeof *px);
	loom_envmap *m = NULL;
	double qa[3] = {0, 0, 0}, qe = 0, ma[3] = {0, 0, 0}, me = 0;
	uint64_t rng = 12345;
	enum { NQ = 1024, NS = 200000 };

	CHECK(px != NULL);
	if (!px)
		return;
	{
		double dz[3] = {0, 0, 1}, dh[3] = {cos(az + M_PI), sin(az + M_PI), 0};
		double dn[3] = {0, 0, -1};
		double dt[3] = {cos(el) * cos(az), cos(el) * sin(az), sin(el)};
		double da[3] = {cos(el) * cos(az + M_PI), cos(el) * sin(az + M_PI), sin(el)};
		loom_sky_studio(sun, dz, zen);
		loom_sky_studio(sun, dh, hor);
		loom_sky_studio(sun, dn, nad);
		loom_sky_studio(sun, dt, toward);
		loom_sky_studio(sun, da, away);
	}
	for (int j = 0; j < 3; j++) {
		CHECK(zen[j] > hor[j] * 2);           /* brighter zenith */
		CHECK(fabs(nad[j] - 0.05) < 1e-9);   /* dark floor */
		CHECK(hor[j] > nad[j]);
		CHECK(toward[j] > away[j] + 0.5);     /* glow round the sun */
	}
	CHECK(toward[0] > toward[2]);                /* a warm glow */
	/* the map against the analytic sky: integral of radiance over the
	   sphere and irradiance on the cloth's plane (quadrature uniform in
	   cos theta and phi, NQ x 2NQ midpoints) */
	CHECK_EQ_INT(loom_sky_studio_map(sun, W, H, px), LOOM_OK);
	for (int a = 0; a < NQ; a++) {
		double ct = 1.0 - 2.0 * (a + 0.5) / NQ, st = sqrt(1.0 - ct * ct);
		for (int b = 0; b < 2 * NQ; b++) {
			double ph = M_PI * (b + 0.5) / NQ, d[3] = {st * cos(ph), st * sin(ph), ct};
			double v[3];
			loom_sky_studio(sun, d, v);
			for (int j = 0; j < 3; j++)
				qa[j] += v[j];
			if (ct > 0)
				qe += (0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]) * ct;
		}
	}
	for (int j = 0; j < 3; j++)
		qa[j] *= 4.0 * M_PI / (2.0 * NQ * NQ);
	qe *= 4.0 * M_PI / (2.0 * NQ * NQ);
	for (uint32_t y = 0; y < H; y++) {
		double c0 = cos(M_PI * y / H), c1 = cos(M_PI * (y + 1) / H);
		double sa = (c0 - c1) * 2.0 * M_PI / W;
		for (uint32_t x = 0; x < W; x++) {
			const float *c = px + 3 * ((size_t)y * W + x);
			for (int j = 0; j < 3; j++)
				ma[j] += c[j] * sa;
			if (y < H / 2)
				me += (0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]) * sa *
				      0.5 * (c0 + c1);
		}
	}
	printf("  studio sky: integral map %.5f %.5f %.5f, analytic %.5f %.5f %.5f; "
	       "irradiance map %.5f, analytic %.5f\n", ma[0], ma[1], ma[2], qa[0], qa[1],
	       qa[2], me, qe);
	for (int j = 0; j < 3; j++)
		CHECK(fabs(ma[j] - qa[j]) < 2e-3 * qa[j]);
	CHECK(fabs(me - qe) < 5e-3 * qe);
	/* importance sampling the map: E[sky(d) / pdf(d)] = the analytic
	   integral, within the map's piecewise-constant approximation */
	CHECK_EQ_INT(loom_envmap_new(px, W, H, 0.0, 1.0, &m, NULL), LOOM_OK);
	if (m) {
		double s[3] = {0, 0, 0}, s2 = 0, lq, se, mean;
		for (int k = 0; k < NS; k++) {
			double d[3], v[3], pdf, u1 = loom_rng_uniform(&rng), u2 = loom_rng_uniform(&rng);
			pdf = loom_envmap_sample(m, u1, u2, d);
			CHECK(pdf > 0);
			if (!(pdf > 0))
				break;
			CHECK(fabs(loom_envmap_pdf(m, d) - pdf) < 1e-6 * pdf);
			loom_sky_studio(sun, d, v);
			for (int j = 0; j < 3; j++)
				s[j] += v[j] / pdf;
			lq = (0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]) / pdf;
			s2 += lq * lq;
		}
		lq = 0.2126 * qa[0] + 0.7152 * qa[1] + 0.0722 * qa[2];
		mean = (0.2126 * s[0] + 0.7152 * s[1] + 0.0722 * s[2]) / NS;
		se = sqrt(fmax(0.0, s2 / NS - mean * mean) / NS);
		printf("  sampled luminance integral %.5f +- %.5f, analytic %.5f\n", mean, se, lq);
		CHECK(fabs(mean - lq) < 4 * se + 2e-3 * lq);
		for (int j = 0; j < 3; j++)
			CHECK(fabs(s[j] / NS - qa[j]) < 0.01 * qa[j]);
		loom_envmap_free(m);
	}
	/* bad arguments */
	{
		double zero[3] = {0, 0, 0}, nan3[3] = {NAN, 0, 1};
		CHECK_EQ_INT(loom_sky_studio_map(NULL, W, H, px), LOOM_EINVAL);
		CHECK_EQ_INT(loom_sky_studio_map(sun, 0, H, px), LOOM_EINVAL);
		CHECK_EQ_INT(loom_sky_studio_map(sun, W, H, NULL), LOOM_EINVAL);
		CHECK_EQ_INT(loom_sky_studio_map(zero, W, H, px), LOOM_EINVAL);
		CHECK_EQ_INT(loom_sky_studio_map(nan3, W, H, px), LOOM_EINVAL);
		CHECK_EQ_INT(loom_sky_studio_map(sun, 1u << 12, 1u << 11, px), LOOM_ERANGE);
	}
	free(px);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_envmap");
	RUN(test_pdf_and_histogram);
	RUN(test_mis_weights);
	RUN(test_furnace);
	RUN(test_bright_pixel_is_a_sun);
	RUN(test_threads_and_errors);
	RUN(test_studio_sky);
	CHECK_MAIN_END();
}
