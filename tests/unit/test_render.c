/*
 * tests/unit/test_render.c - the microflake phase function
 * (engine/render/microflake.c) and the volume path tracer (engine/render/render.c).
 *
 * Phase function: normalisation of D, projected-area table against direct
 * quadrature and its known limits, f integrating to 1, a chi-square test of
 * sampling against evaluation.  Tracer: white furnace, empty source =
 * background, Beer-Lambert transmittance (isotropic and along / across the
 * fibres), exact single scattering from a distant and a point light,
 * determinism over seeds and thread counts, the half-dense preview, shell
 * rendering against the slab, bad options, lookup errors, tone mapping.
 */
#include "loom.h"
#include "check.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* ---- synthetic sources ------------------------------------------------- */

enum { SRC_CONST, SRC_HALF, SRC_EMPTY, SRC_FAIL, SRC_YARN };

typedef struct synth {
	int kind;
	float density;
	float orient[3];
	float albedo[3];
	float alignment;
	double half_x;    /* SRC_HALF: dense where x < half_x */
} synth;

static int synth_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	const synth *s = ctx;
	out->alignment = s->alignment;
	memcpy(out->orient, s->orient, sizeof out->orient);
	memcpy(out->albedo, s->albedo, sizeof out->albedo);
	switch (s->kind) {
	case SRC_CONST:
		out->density = s->density;
		break;
	case SRC_HALF:
		out->density = p[0] < s->half_x ? s->density : 0.0f;
		break;
	case SRC_YARN: /* wavy tubes along y, fibres along the tube */
	{
		double cz = 4.0 + 2.0 * sin(p[1] * 0.3 + floor(p[0] / 8.0) * M_PI);
		double dx = fmod(p[0], 8.0) - 4.0, dz = p[2] - cz;
		out->density = dx * dx + dz * dz < 9.0 ? s->density : 0.0f;
		out->orient[0] = 0;
		out->orient[1] = 1;
		out->orient[2] = (float)(0.6 * cos(p[1] * 0.3 + floor(p[0] / 8.0) * M_PI));
		break;
	}
	case SRC_FAIL:
		return LOOM_EIO;
	default:
		out->density = 0;
	}
	return 0;
}

static void init_src(loom_volume_source *src, synth *s, int64_t nx, int64_t ny,
                     int64_t nz)
{
	loom_volume_source def = LOOM_VOLUME_SOURCE_INIT;
	*src = def;
	src->nx = nx;
	src->ny = ny;
	src->nz = nz;
	src->voxel_mm = 0.005;
	src->lookup = synth_lookup;
	src->ctx = s;
}

static void init_opt(loom_render_options *o, uint32_t w, uint32_t h, uint32_t spp)
{
	loom_render_options def = LOOM_RENDER_OPTIONS_INIT;
	*o = def;
	o->width = w;
	o->height = h;
	o->spp = spp;
	o->threads = 2;
	o->seed = 7;
}

static double image_mean(const float *rgb, size_t n_px, int ch)
{
	double s = 0;
	for (size_t i = 0; i < n_px; i++)
		s += rgb[3 * i + ch];
	return s / (double)n_px;
}

/* ---- microflake -------------------------------------------------------- */

static void test_microflake_distribution(void)
{
	static const double ss[] = {0.005, 0.02, 0.1, 0.3, 0.7, 1.0};
	uint64_t rng = check_seed();
	double maxrel = 0;

	for (size_t i = 0; i < sizeof ss / sizeof ss[0]; i++) {
		/* integral of D over the sphere = 2 pi int_{-1}^{1} D dt = 1 */
		double sum = 0;
		int n = 200000;
		for (int k = 0; k < n; k++) {
			double t = -1.0 + 2.0 * (k + 0.5) / n;
			sum += loom_microflake_D(ss[i], t);
		}
		sum *= 2 * M_PI * 2.0 / n;
		CHECK(fabs(sum - 1.0) < 1e-6);
		/* largest across the fibre, smallest along it, monotone */
		{
			double prev = INFINITY;
			for (int k = 0; k <= 40; k++) {
				double a = loom_microflake_area(ss[i], k / 40.0);
				CHECK(a <= prev + 1e-12);
				prev = a;
			}
			CHECK(loom_microflake_area(ss[i], 0.0) > loom_microflake_area(ss[i], 1.0));
			CHECK(loom_microflake_area(ss[i], 0.0) <= loom_microflake_area_max() + 1e-12);
		}
		/* an isotropic average of A is 1 (mean projected area of a unit
		   flake over directions is 1/2) */
		{
			double avg = 0;
			for (int k = 0; k < 400; k++)
				avg += loom_microflake_area_exact(ss[i], (k + 0.5) / 400.0);
			CHECK(fabs(avg / 400.0 - 1.0) < 1e-4);
		}
	}
	/* table against quadrature at random points */
	for (int k = 0; k < 300; k++) {
		double s = exp(log(0.005) + loom_rng_uniform(&rng) * log(200.0));
		double c = loom_rng_uniform(&rng);
		double a = loom_microflake_area(s, c), e = loom_microflake_area_exact(s, c);
		maxrel = fmax(maxrel, fabs(a - e) / e);
	}
	printf("  area table: max relative error %.2g\n", maxrel);
	CHECK(maxrel < 2e-3);
	/* limits: s -> 0 across the fibre 4/pi; along it A = 2 E|t| */
	CHECK(fabs(loom_microflake_area_exact(0.005, 0.0) - 4.0 / M_PI) < 1e-3);
	CHECK(fabs(loom_microflake_area_exact(0.01, 1.0) - 2.0 * 0.01 * sqrt(2.0 / M_PI)) < 1e-5);
	CHECK(fabs(loom_microflake_area_max() - 4.0 / M_PI) < 1e-3);
}

static void uniform_dir(uint64_t *r, double o[3])
{
	double z = 1 - 2 * loom_rng_uniform(r), p = 2 * M_PI * loom_rng_uniform(r);
	double q = sqrt(fmax(0, 1 - z * z));
	o[0] = q * cos(p);
	o[1] = q * sin(p);
	o[2] = z;
}

static void test_phase_normalised(void)
{
	static const double ss[] = {0.1, 0.3, 1.0};
	static const double ang[] = {0.0, 0.6, 1.2, M_PI / 2};
	uint64_t rng = check_seed();
	const double w[3] = {0, 0, 1};

	for (size_t i = 0; i < 3; i++)
		for (size_t a = 0; a < 4; a++) {
			double wi[3] = {sin(ang[a]), 0, cos(ang[a])}, sum = 0, sum2 = 0, mean, se;
			int n = 100000;
			for (int k = 0; k < n; k++) {
				double wo[3], f;
				uniform_dir(&rng, wo);
				f = 4 * M_PI * loom_microflake_eval(ss[i], w, wi, wo);
				sum += f;
				sum2 += f * f;
			}
			mean = sum / n;
			se = sqrt(fmax(0, sum2 / n - mean * mean) / n);
			if (fabs(mean - 1) > 4 * se + 0.01)
				printf("  s %g angle %g: integral %.4f +- %.4f\n", ss[i], ang[a],
				       mean, se);
			CHECK(fabs(mean - 1) < 4 * se + 0.01);
		}
	/* isotropic (no fibre) */
	{
		double z[3] = {0, 0, 0}, wi[3] = {0, 0, 1}, wo[3] = {1, 0, 0};
		CHECK(fabs(loom_microflake_eval(0.3, z, wi, wo) - 1 / (4 * M_PI)) < 1e-15);
	}
}

/* Chi-square of sampled directions against integrated f over bins of
   (cos theta, phi) in the fibre frame. */
static void chi2_case(double s, double alpha, uint64_t *rng)
{
	enum { NT = 10, NP = 20, SUB = 8 };
	static double expct[NT][NP];
	static long obs[NT][NP];
	const double w[3] = {0, 0, 1};
	double wi[3] = {sin(alpha), 0, cos(alpha)}, chi2 = 0, pool_e = 0;
	long pool_o = 0;
	int n = 200000, dof = -1;

	memset(obs, 0, sizeof obs);
	for (int k = 0; k < n; k++) {
		double wo[3];
		int it, ip;
		double phi;
		loom_microflake_sample(s, w, wi, rng, wo);
		it = (int)((wo[2] + 1) / 2 * NT);
		phi = atan2(wo[1], wo[0]);
		if (phi < 0)
			phi += 2 * M_PI;
		ip = (int)(phi / (2 * M_PI) * NP);
		it = it < 0 ? 0 : it >= NT ? NT - 1 : it;
		ip = ip < 0 ? 0 : ip >= NP ? NP - 1 : ip;
		obs[it][ip]++;
	}
	for (int it = 0; it < NT; it++)
		for (int ip = 0; ip < NP; ip++) {
			double sum = 0;
			for (int a = 0; a < SUB; a++)
				for (int b = 0; b < SUB; b++) {
					double z = -1 + 2.0 * (it + (a + 0.5) / SUB) / NT;
					double phi = 2 * M_PI * (ip + (b + 0.5) / SUB) / NP;
					double r = sqrt(fmax(0, 1 - z * z));
					double wo[3] = {r * cos(phi), r * sin(phi), z};
					sum += loom_microflake_eval(s, w, wi, wo);
				}
			/* bin solid angle = (2/NT) (2 pi / NP) */
			expct[it][ip] = n * sum / (SUB * SUB) * (2.0 / NT) * (2 * M_PI / NP);
		}
	for (int it = 0; it < NT; it++)
		for (int ip = 0; ip < NP; ip++) {
			if (expct[it][ip] < 20) {
				pool_e += expct[it][ip];
				pool_o += obs[it][ip];
				continue;
			}
			chi2 += (obs[it][ip] - expct[it][ip]) * (obs[it][ip] - expct[it][ip]) /
			        expct[it][ip];
			dof++;
		}
	if (pool_e > 20) {
		chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
		dof++;
	}
	printf("  chi2 s=%g alpha=%.2f: %.1f for %d dof\n", s, alpha, chi2, dof);
	/* mean dof, sd sqrt(2 dof): 5 sd is far beyond chance, while a wrong
	   sampler (e.g. a missing |wi.m| factor) gives thousands */
	CHECK(dof > 20);
	CHECK(chi2 < dof + 5 * sqrt(2.0 * dof) + 10);
}

static void test_phase_sampling_chi2(void)
{
	uint64_t rng = check_seed();
	chi2_case(0.3, 0.7, &rng);
	chi2_case(0.15, 1.3, &rng);
	chi2_case(1.0, 0.2, &rng);
}

/* ---- tracer ------------------------------------------------------------ */

static void test_white_furnace(void)
{
	synth s = {SRC_CONST, 1.0f, {1, 0, 0}, {1, 1, 1}, 0.2f, 0};
	loom_volume_source src;
	loom_render_options o;
	loom_render_stats st;
	float *img = malloc(16 * 16 * 3 * sizeof *img);
	int bad = 0;

	init_src(&src, &s, 0, 0, 6);
	init_opt(&o, 16, 16, 4);
	o.env[0] = 0.7f;
	o.env[1] = 0.5f;
	o.env[2] = 0.25f;
	o.light.kind = LOOM_LIGHT_NONE;
	o.max_depth = 100000;
	o.rr_depth = 100000;
	o.density_scale = 0.8;
	/* oblique pinhole view of an anisotropic slab */
	o.camera.kind = LOOM_CAMERA_PINHOLE;
	o.camera.eye[0] = 0;
	o.camera.eye[1] = -20;
	o.camera.eye[2] = 30;
	memset(o.camera.target, 0, sizeof o.camera.target);
	o.camera.up[0] = 0;
	o.camera.up[1] = 0;
	o.camera.up[2] = 1;
	o.camera.fov_y_deg = 60;
	CHECK_EQ_INT(loom_render(&src, &o, img, &st, NULL), LOOM_OK);
	for (int i = 0; i < 16 * 16; i++)
		for (int j = 0; j < 3; j++)
			if (fabs(img[3 * i + j] - o.env[j]) > 1e-5 * o.env[j])
				bad++;
	printf("  furnace: %llu scatterings over %llu paths, %d pixels off\n",
	       (unsigned long long)st.scatterings, (unsigned long long)st.paths, bad);
	CHECK_EQ_INT(bad, 0);
	CHECK(st.scatterings > st.paths); /* it did scatter */
	CHECK_EQ_INT(st.paths, 16 * 16 * 4);
	free(img);
}

static void test_empty_is_background(void)
{
	synth s = {SRC_EMPTY, 0, {0, 0, 0}, {1, 1, 1}, 0, 0};
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(8 * 8 * 3 * sizeof *img);
	int bad = 0;

	init_src(&src, &s, 32, 32, 16);
	init_opt(&o, 8, 8, 3);
	CHECK_EQ_INT(loom_camera_top(&src, 0, 0, 32, 32, &o.camera), LOOM_OK);
	o.env[0] = 0.25f;
	o.env[1] = 0.5f;
	o.env[2] = 1.0f;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int i = 0; i < 8 * 8 * 3; i++)
		if (img[i] != o.env[i % 3])
			bad++;
	CHECK_EQ_INT(bad, 0);
	/* density_scale 0: also exactly the background */
	s.kind = SRC_CONST;
	s.density = 1;
	o.density_scale = 0;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int i = 0; i < 8 * 8 * 3; i++)
		if (img[i] != o.env[i % 3])
			bad++;
	CHECK_EQ_INT(bad, 0);
	free(img);
}

/* Pure absorber seen from above against a white background: mean pixel =
   exp(-density * scale * A * nz). */
static double absorber_mean(const float orient[3], double scale, double *se)
{
	synth s = {SRC_CONST, 0.5f, {0, 0, 0}, {0, 0, 0}, 0.3f, 0};
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(8 * 8 * 3 * sizeof *img);
	double m;

	memcpy(s.orient, orient, sizeof s.orient);
	init_src(&src, &s, 0, 0, 4);
	init_opt(&o, 8, 8, 256);
	loom_camera_top(&src, 0, 0, 8, 8, &o.camera);
	o.env[0] = o.env[1] = o.env[2] = 1.0f;
	o.light.kind = LOOM_LIGHT_NONE;
	o.density_scale = scale;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	m = image_mean(img, 64, 0);
	*se = sqrt(m * (1 - m) / (64.0 * 256.0));
	free(img);
	return m;
}

static void test_transmittance(void)
{
	static const float iso[3] = {0, 0, 0}, along[3] = {0, 0, 1}, across[3] = {1, 0, 0};
	double se, m, expect;

	m = absorber_mean(iso, 0.4, &se);
	expect = exp(-0.5 * 0.4 * 4);
	printf("  isotropic: %.4f expected %.4f (se %.4f)\n", m, expect, se);
	CHECK(fabs(m - expect) < 4 * se);
	/* a ray along the fibres sees little area, across them the most */
	m = absorber_mean(along, 0.4, &se);
	expect = exp(-0.5 * 0.4 * loom_microflake_area(0.3, 1.0) * 4);
	printf("  along fibres: %.4f expected %.4f (se %.4f)\n", m, expect, se);
	CHECK(fabs(m - expect) < 4 * se);
	m = absorber_mean(across, 0.4, &se);
	expect = exp(-0.5 * 0.4 * loom_microflake_area(0.3, 0.0) * 4);
	printf("  across fibres: %.4f expected %.4f (se %.4f)\n", m, expect, se);
	CHECK(fabs(m - expect) < 4 * se);
}

/* Single scattering (max_depth 1) of an isotropic slab lit from straight
   above, seen from straight above: L = E / (4 pi) (1 - exp(-2 tau)) / 2. */
static void test_single_scattering(void)
{
	synth s = {SRC_CONST, 1.0f, {0, 0, 0}, {1, 1, 1}, 0.3f, 0};
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(8 * 8 * 3 * sizeof *img);
	double mu = 0.15, Z = 5, m, expect, sum = 0;
	int n = 20000;

	init_src(&src, &s, 0, 0, (int64_t)Z);
	init_opt(&o, 8, 8, 512);
	loom_camera_top(&src, 0, 0, 8, 8, &o.camera);
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.density_scale = mu;
	o.max_depth = 1;
	o.light.kind = LOOM_LIGHT_DISTANT;
	o.light.dir[0] = o.light.dir[1] = 0;
	o.light.dir[2] = 1;
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = 10.0f;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	m = image_mean(img, 64, 1);
	expect = 10.0 / (4 * M_PI) * (1 - exp(-2 * mu * Z)) / 2;
	printf("  single scattering, distant light: %.5f expected %.5f\n", m, expect);
	CHECK(fabs(m - expect) < 0.03 * expect);

	/* point light 20 above the top at the view centre: the view is a
	   single column (tiny window), depth z below the top has light
	   distance 20 + z */
	loom_camera_top(&src, 3.999, 3.999, 4.001, 4.001, &o.camera);
	o.light.kind = LOOM_LIGHT_POINT;
	o.light.pos[0] = 4;
	o.light.pos[1] = 4;
	o.light.pos[2] = Z + 20;
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = 4000.0f;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	m = image_mean(img, 64, 1);
	for (int k = 0; k < n; k++) {
		double z = (k + 0.5) / n * Z;
		sum += mu * exp(-2 * mu * z) / ((20 + z) * (20 + z));
	}
	expect = 4000.0 / (4 * M_PI) * sum * Z / n;
	printf("  single scattering, point light: %.5f expected %.5f\n", m, expect);
	CHECK(fabs(m - expect) < 0.03 * expect);
	free(img);
}

/* A distant light with a disc (angle_deg 90: half angle 45 degrees) over an
   isotropic slab seen from above, single scattering: the mean over the
   disc's directions (uniform in solid angle, cos uniform in [cos 45, 1])
   of the exact slab integral; the slab is optically thick (mu Z = 5), where
   the disc's mean differs from the point light's by about 9 %. */
static void test_sun_disc(void)
{
	synth s = {SRC_CONST, 1.0f, {0, 0, 0}, {1, 1, 1}, 0.3f, 0};
	loom_volume_source src;
	loom_render_options o;
	loom_diag d = {0};
	float *img = malloc(8 * 8 * 3 * sizeof *img);
	double mu = 1.0, Z = 5, m, disc = 0, point, c0 = cos(M_PI / 4);
	int n = 20000;

	init_src(&src, &s, 0, 0, (int64_t)Z);
	init_opt(&o, 8, 8, 512);
	loom_camera_top(&src, 0, 0, 8, 8, &o.camera);
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.density_scale = mu;
	o.max_depth = 1;
	o.light.kind = LOOM_LIGHT_DISTANT;
	o.light.dir[0] = o.light.dir[1] = 0;
	o.light.dir[2] = 1;
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = 10.0f;
	o.light.angle_deg = 90;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	m = image_mean(img, 64, 1);
	for (int k = 0; k < n; k++) {
		double c = c0 + (k + 0.5) / n * (1 - c0), g = 1 + 1 / c;
		disc += (1 - exp(-mu * Z * g)) / g;
	}
	disc *= 10.0 / (4 * M_PI) / n;
	point = 10.0 / (4 * M_PI) * (1 - exp(-2 * mu * Z)) / 2;
	printf("  sun disc 90 degrees: %.5f expected %.5f (a point: %.5f)\n", m, disc,
	       point);
	CHECK(fabs(m - disc) < 0.02 * disc);
	CHECK(fabs(m - point) > 0.05 * point);
	o.light.angle_deg = 91;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "angle_deg");
	free(img);
}

static void rows_mean(const float *img, uint32_t w, uint32_t r0, uint32_t r1,
                      double *mean, double *se);

/* A small sphere light far away lights the cloth as a sun of the same
   irradiance and angular size; a sun given in opt.lights is the same
   light as opt.light (same bytes); two half suns make one. */
static void test_sphere_and_extra_lights(void)
{
	synth s = {SRC_CONST, 1.0f, {0.2f, 1, 0.1f}, {0.8f, 0.8f, 0.8f}, 0.3f, 0};
	loom_volume_source src;
	loom_render_options o;
	loom_light extra[2];
	loom_diag d = {0};
	size_t n = 16 * 16 * 3;
	float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
	double dir[3] = {0.3, -0.5, 0.8}, D = 2000.0, r = 10.0, ma, mb, sa, sb;
	double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);

	init_src(&src, &s, 0, 0, 6);
	init_opt(&o, 16, 16, 64);
	o.camera.kind = LOOM_CAMERA_ORTHO;
	o.camera.eye[0] = 8;
	o.camera.eye[1] = 8;
	o.camera.eye[2] = 20;
	o.camera.target[0] = 8;
	o.camera.target[1] = 8;
	o.camera.target[2] = 0;
	o.camera.ortho_size[0] = o.camera.ortho_size[1] = 16;
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.density_scale = 1.0;
	o.light.kind = LOOM_LIGHT_SPHERE;
	for (int j = 0; j < 3; j++) {
		o.light.pos[j] = 8.0 * (j < 2) + 3.0 * (j == 2) + D * dir[j] / len;
		o.light.rgb[j] = (float)(3.0 * D * D);
	}
	o.light.radius = r;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	o.light.kind = LOOM_LIGHT_DISTANT;
	memcpy(o.light.dir, dir, sizeof dir);
	o.light.rgb[0] = o.light.rgb[1] = o.light.rgb[2] = 3.0f;
	o.light.angle_deg = 2.0 * asin(r / D) * 180.0 / M_PI;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	rows_mean(a, 16, 0, 16, &ma, &sa);
	rows_mean(b, 16, 0, 16, &mb, &sb);
	printf("  sphere light %.5f +- %.5f, sun %.5f +- %.5f\n", ma, sa, mb, sb);
	CHECK(mb > 0.05);
	CHECK(fabs(ma - mb) < 4 * sqrt(sa * sa + sb * sb) + 0.005 * mb);
	/* the sun as an extra light: the same bytes */
	extra[0] = o.light;
	o.light.kind = LOOM_LIGHT_NONE;
	o.lights = extra;
	o.n_lights = 1;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) == 0);
	/* two half suns */
	extra[0].rgb[0] = extra[0].rgb[1] = extra[0].rgb[2] = 1.5f;
	extra[1] = extra[0];
	o.n_lights = 2;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	rows_mean(a, 16, 0, 16, &ma, &sa);
	printf("  two half suns %.5f +- %.5f\n", ma, sa);
	CHECK(fabs(ma - mb) < 4 * sqrt(sa * sa + sb * sb));
	/* bad lights */
	extra[1].kind = LOOM_LIGHT_SPHERE;
	extra[1].radius = 0;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "radius");
	o.n_lights = LOOM_RENDER_MAX_LIGHTS + 1;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "n_lights");
	free(a);
	free(b);
}

static void test_determinism(void)
{
	synth s = {SRC_YARN, 1.0f, {0, 1, 0}, {0.8f, 0.6f, 0.4f}, 0.2f, 0};
	loom_volume_source src;
	loom_render_options o;
	size_t n = 24 * 20 * 3;
	float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
	loom_render_stats sa, sb;

	init_src(&src, &s, 0, 0, 8);
	init_opt(&o, 24, 20, 4);
	o.tile = 7;
	o.density_scale = 2.0;
	o.camera.kind = LOOM_CAMERA_PINHOLE;
	o.camera.eye[0] = 16;
	o.camera.eye[1] = -10;
	o.camera.eye[2] = 30;
	o.camera.target[0] = 16;
	o.camera.target[1] = 16;
	o.camera.target[2] = 4;
	o.camera.up[2] = 1;
	o.camera.up[1] = 0;
	o.threads = 1;
	CHECK_EQ_INT(loom_render(&src, &o, a, &sa, NULL), LOOM_OK);
	o.threads = 2;
	CHECK_EQ_INT(loom_render(&src, &o, b, &sb, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) == 0);
	CHECK(sa.rays == sb.rays && sa.lookups == sb.lookups);
	o.threads = 3;
	o.tile = 5; /* tiling does not matter either */
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) == 0);
	o.seed = 8;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) != 0);
	CHECK(image_mean(a, n / 3, 0) > 0.01);
	free(a);
	free(b);
}

/* Mean and standard error of channel 0 over rows [r0, r1) of a w-wide
   image whose pixels all have the same expectation. */
static void rows_mean(const float *img, uint32_t w, uint32_t r0, uint32_t r1,
                      double *mean, double *se)
{
	double s = 0, s2 = 0, n = (double)w * (r1 - r0);
	for (uint32_t y = r0; y < r1; y++)
		for (uint32_t x = 0; x < w; x++) {
			double v = img[3 * ((size_t)y * w + x)];
			s += v;
			s2 += v * v;
		}
	*mean = s / n;
	*se = sqrt(fmax(0.0, s2 / n - *mean * *mean) / n);
}

/* Column profile (channel 0 averaged over the rows) and its largest jump
   between neighbouring columns. */
static double max_column_jump(const float *img, uint32_t w, uint32_t h)
{
	double prev = 0, jump = 0;
	for (uint32_t x = 0; x < w; x++) {
		double c = 0;
		for (uint32_t y = 0; y < h; y++)
			c += img[3 * ((size_t)y * w + x)];
		c /= h;
		if (x > 0 && fabs(c - prev) > jump)
			jump = fabs(c - prev);
		prev = c;
	}
	return jump;
}

static void test_camera_lens_and_ortho(void)
{
	synth s = {SRC_HALF, 1.0f, {0, 0, 0}, {0.8f, 0.8f, 0.8f}, 0.3f, 16.0};
	loom_volume_source src;
	loom_render_options o;
	loom_diag d = {0};
	uint32_t w = 32, h = 8;
	size_t n = (size_t)w * h * 3;
	float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
	double sharp, in_focus, blurred, m0, m1, se0, se1;

	/* straight down on an edge (dense where x < 16), 16 voxels across */
	init_src(&src, &s, 0, 0, 6);
	init_opt(&o, w, h, 64);
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.density_scale = 2.0;
	o.camera.kind = LOOM_CAMERA_PINHOLE;
	o.camera.eye[0] = 16;
	o.camera.eye[1] = 4;
	o.camera.eye[2] = 40;
	o.camera.target[0] = 16;
	o.camera.target[1] = 4;
	o.camera.target[2] = 6;
	o.camera.up[0] = 0;
	o.camera.up[1] = 1;
	o.camera.up[2] = 0;
	o.camera.fov_y_deg = 2.0 * atan(8.0 / 34.0 / 4.0) * 180.0 / M_PI;
	o.light.dir[0] = 0;
	o.light.dir[1] = 0;
	o.light.dir[2] = 1;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	sharp = max_column_jump(a, w, h);
	/* aperture 0 is the pinhole, byte for byte, whatever the focus */
	o.camera.focus_dist = 3.0;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) == 0);
	/* a wide lens focused on the top of the cloth keeps the edge sharp;
	   focused far behind it blurs the edge over several pixels */
	o.camera.aperture = 8.0;
	o.camera.focus_dist = 34.0;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, n * sizeof *a) != 0);
	in_focus = max_column_jump(b, w, h);
	o.camera.focus_dist = 340.0;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, NULL), LOOM_OK);
	blurred = max_column_jump(b, w, h);
	printf("  edge step: pinhole %.4f, lens in focus %.4f, out of focus %.4f\n",
	       sharp, in_focus, blurred);
	CHECK(sharp > 0.05);
	CHECK(in_focus > 0.6 * sharp);
	CHECK(blurred < 0.35 * sharp);
	o.camera.aperture = -1;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "aperture");
	o.camera.aperture = 1;
	o.camera.kind = LOOM_CAMERA_ORTHO;
	o.camera.ortho_size[0] = o.camera.ortho_size[1] = 8;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "no lens");

	/* A uniform unbounded slab seen obliquely: every orthographic ray sees
	   the same thing, so the top and bottom halves agree within the Monte
	   Carlo error; a wide pinhole sees grazing rays at the top. */
	s.kind = SRC_CONST;
	o.camera.aperture = 0;
	o.camera.kind = LOOM_CAMERA_ORTHO;
	o.camera.eye[0] = 0;
	o.camera.eye[1] = -40;
	o.camera.eye[2] = 40;
	o.camera.target[0] = o.camera.target[1] = o.camera.target[2] = 0;
	o.camera.up[0] = o.camera.up[1] = 0;
	o.camera.up[2] = 1;
	o.camera.ortho_size[0] = 64;
	o.camera.ortho_size[1] = 16;
	o.light.dir[1] = -0.5;
	o.spp = 16;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	rows_mean(a, w, 0, h / 2, &m0, &se0);
	rows_mean(a, w, h / 2, h, &m1, &se1);
	printf("  ortho: top %.4f +- %.4f, bottom %.4f +- %.4f\n", m0, se0, m1, se1);
	CHECK(m0 > 0.01);
	CHECK(fabs(m0 - m1) < 4.0 * sqrt(se0 * se0 + se1 * se1));
	o.camera.kind = LOOM_CAMERA_PINHOLE;
	o.camera.fov_y_deg = 60;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	rows_mean(a, w, 0, h / 2, &m0, &se0);
	rows_mean(a, w, h / 2, h, &m1, &se1);
	printf("  pinhole: top %.4f +- %.4f, bottom %.4f +- %.4f\n", m0, se0, m1, se1);
	CHECK(fabs(m0 - m1) > 4.0 * sqrt(se0 * se0 + se1 * se1));
	free(a);
	free(b);
}

static void test_half_dense_preview(void)
{
	synth s = {SRC_HALF, 1.0f, {1, 0, 0}, {0.8f, 0.8f, 0.8f}, 0.3f, 32};
	loom_volume_source src;
	loom_render_options o;
	float *img = malloc(16 * 8 * 3 * sizeof *img);
	double left = 0, right = 0;

	init_src(&src, &s, 64, 32, 8);
	init_opt(&o, 16, 8, 8);
	CHECK_EQ_INT(loom_camera_top(&src, 0, 0, 64, 32, &o.camera), LOOM_OK);
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.density_scale = 1.0;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int y = 0; y < 8; y++)
		for (int x = 0; x < 16; x++) {
			double v = img[3 * (y * 16 + x)];
			if (x < 8)
				left += v / 64;
			else
				right += v / 64;
		}
	printf("  half dense: left %.4f right %.4f\n", left, right);
	CHECK(left > 0.05);
	CHECK(right == 0.0); /* lit from above, black background: nothing */
	free(img);
}

static void test_shell_matches_slab(void)
{
	synth s = {SRC_YARN, 1.0f, {0, 1, 0}, {0.9f, 0.7f, 0.5f}, 0.2f, 0};
	loom_volume_source src;
	loom_render_options o;
	loom_mesh *m = NULL;
	loom_shell *sh = NULL;
	loom_shell_params p = LOOM_SHELL_PARAMS_INIT;
	loom_render_stats st;
	char path[1024];
	const char *top = getenv("LOOM_TOP");
	float *a = malloc(12 * 12 * 3 * sizeof *a), *b = malloc(12 * 12 * 3 * sizeof *b);
	double ma, mb;
	loom_diag d;

	memset(&d, 0, sizeof d);
	snprintf(path, sizeof path, "%s/tests/data/meshes/quad.obj", top ? top : ".");
	CHECK_EQ_INT(loom_obj_read(path, &m, &d), LOOM_OK);
	if (!m)
		return;
	p.thickness = 8;
	p.voxels_per_uv = 64;
	p.nz = 8;
	CHECK_EQ_INT(loom_shell_new(m, &p, &sh, &d), LOOM_OK);
	loom_mesh_free(m);
	if (!sh)
		return;
	init_src(&src, &s, 64, 64, 8);
	init_opt(&o, 12, 12, 64);
	loom_camera_top(&src, 8, 8, 56, 56, &o.camera);
	o.density_scale = 1.5;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	o.shell = sh;
	CHECK_EQ_INT(loom_render(&src, &o, b, &st, NULL), LOOM_OK);
	ma = image_mean(a, 144, 1);
	mb = image_mean(b, 144, 1);
	printf("  slab %.4f shell %.4f (%llu closest-point queries, %llu lookups)\n",
	       ma, mb, (unsigned long long)st.shell_queries,
	       (unsigned long long)st.lookups);
	CHECK(fabs(ma - mb) < 0.03 * ma);
	CHECK(st.shell_queries > 0 && st.shell_queries < st.lookups);
	/* shell renders are deterministic over thread counts too */
	o.threads = 1;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	CHECK(memcmp(a, b, 12 * 12 * 3 * sizeof *a) == 0);
	/* nz mismatch */
	src.nz = 9;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, &d), LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(d.message, "nz");
	loom_shell_free(sh);
	free(a);
	free(b);
}

/* An unbounded source accepts negative voxel coordinates through a shell
   too: with uv_origin (0.5, 0.5) half of the quad maps to x < 0. */
static void test_shell_unbounded(void)
{
	synth s = {SRC_CONST, 1.0f, {1, 0, 0}, {0.8f, 0.8f, 0.8f}, 0.3f, 0};
	loom_volume_source src;
	loom_render_options o;
	loom_mesh *m = NULL;
	loom_shell *sh = NULL;
	loom_shell_params p = LOOM_SHELL_PARAMS_INIT;
	char path[1024];
	const char *top = getenv("LOOM_TOP");
	float img[8 * 8 * 3];
	int dark = 0;

	snprintf(path, sizeof path, "%s/tests/data/meshes/quad.obj", top ? top : ".");
	CHECK_EQ_INT(loom_obj_read(path, &m, NULL), LOOM_OK);
	if (!m)
		return;
	p.thickness = 4;
	p.voxels_per_uv = 64;
	p.uv_origin[0] = p.uv_origin[1] = 0.5;
	p.nz = 4;
	CHECK_EQ_INT(loom_shell_new(m, &p, &sh, NULL), LOOM_OK);
	loom_mesh_free(m);
	if (!sh)
		return;
	init_src(&src, &s, 0, 0, 4);
	init_opt(&o, 8, 8, 4);
	loom_camera_top(&src, 4, 4, 60, 60, &o.camera);
	o.env[0] = o.env[1] = o.env[2] = 0;
	o.shell = sh;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, NULL), LOOM_OK);
	for (int i = 0; i < 64; i++)
		if (!(img[3 * i] > 0))
			dark++;
	CHECK_EQ_INT(dark, 0);
	loom_shell_free(sh);
}

/* Per-thread lookup state through thread_init / thread_done. */
typedef struct tctx {
	uint32_t magic;
	synth *s;
	long lookups;
} tctx;
static int n_init, n_done;
static long n_tlookups;
static pthread_mutex_t tlock = PTHREAD_MUTEX_INITIALIZER;

static void *t_init(void *ctx)
{
	tctx *t = calloc(1, sizeof *t);
	if (!t)
		return NULL;
	t->magic = 0x600d;
	t->s = ctx;
	pthread_mutex_lock(&tlock);
	n_init++;
	pthread_mutex_unlock(&tlock);
	return t;
}

static void t_done(void *ctx, void *tc)
{
	tctx *t = tc;
	(void)ctx;
	pthread_mutex_lock(&tlock);
	n_done++;
	n_tlookups += t->lookups;
	pthread_mutex_unlock(&tlock);
	free(t);
}

static int t_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	tctx *t = ctx;
	if (t->magic != 0x600d)
		return LOOM_ECORRUPT;
	t->lookups++;
	return synth_lookup(t->s, p, out);
}

static void *t_init_fail(void *ctx)
{
	(void)ctx;
	return NULL;
}

static void test_thread_hooks(void)
{
	synth s = {SRC_YARN, 1.0f, {0, 1, 0}, {0.8f, 0.6f, 0.4f}, 0.2f, 0};
	loom_volume_source src;
	loom_render_options o;
	loom_render_stats st;
	float a[16 * 16 * 3], b[16 * 16 * 3];
	loom_diag d;

	memset(&d, 0, sizeof d);
	init_src(&src, &s, 0, 0, 8);
	init_opt(&o, 16, 16, 2);
	loom_camera_top(&src, 0, 0, 32, 32, &o.camera);
	o.tile = 4;
	CHECK_EQ_INT(loom_render(&src, &o, a, NULL, NULL), LOOM_OK);
	src.lookup = t_lookup;
	src.thread_init = t_init;
	src.thread_done = t_done;
	n_init = n_done = 0;
	n_tlookups = 0;
	CHECK_EQ_INT(loom_render(&src, &o, b, &st, NULL), LOOM_OK);
	CHECK_EQ_INT(n_init, 2);
	CHECK_EQ_INT(n_done, 2);
	CHECK_EQ_INT(n_tlookups, (long)st.lookups);
	CHECK(memcmp(a, b, sizeof a) == 0);
	src.thread_init = t_init_fail;
	CHECK_EQ_INT(loom_render(&src, &o, b, NULL, &d), LOOM_ENOMEM);
	CHECK_STR_CONTAINS(d.message, "thread_init");
}

static int n_progress;
static uint64_t last_done, last_total;
static void progress(void *u, uint64_t done, uint64_t total)
{
	(void)u;
	n_progress++;
	last_done = done;
	last_total = total;
}

static void test_options_and_errors(void)
{
	synth s = {SRC_CONST, 1.0f, {0, 0, 0}, {1, 1, 1}, 0.3f, 0};
	loom_volume_source src;
	loom_render_options o;
	float img[4 * 4 * 3];
	loom_diag d;

	memset(&d, 0, sizeof d);
	init_src(&src, &s, 0, 0, 4);
	init_opt(&o, 4, 4, 1);
	loom_camera_top(&src, 0, 0, 4, 4, &o.camera);
	CHECK_EQ_INT(loom_render(NULL, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_render(&src, NULL, img, NULL, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_render(&src, &o, NULL, NULL, &d), LOOM_EINVAL);
#define BAD(field, value, text)                                              \
	do {                                                                     \
		loom_render_options b = o;                                           \
		b.field = value;                                                     \
		CHECK_EQ_INT(loom_render(&src, &b, img, NULL, &d), LOOM_EINVAL);     \
		CHECK_STR_CONTAINS(d.message, text);                                 \
	} while (0)
	BAD(size, 8, "LOOM_RENDER_OPTIONS_INIT");
	BAD(width, 0, "image 0 x 4");
	BAD(spp, 0, "spp");
	BAD(max_depth, 0, "max_depth");
	BAD(density_scale, -1, "density_scale");
	BAD(alignment, 0, "alignment");
	BAD(env[1], NAN, "env");
	BAD(light.kind, 9, "light kind");
	BAD(camera.kind, 5, "camera kind");
	BAD(camera.ortho_size[0], 0, "ortho_size");
	BAD(camera.up[1], 0, "camera up");
	BAD(world_per_voxel, -1, "world_per_voxel");
	{
		loom_render_options b = o;
		b.camera.kind = LOOM_CAMERA_PINHOLE;
		b.camera.fov_y_deg = 180;
		CHECK_EQ_INT(loom_render(&src, &b, img, NULL, &d), LOOM_EINVAL);
		CHECK_STR_CONTAINS(d.message, "fov_y_deg");
		b = o;
		memcpy(b.camera.target, b.camera.eye, sizeof b.camera.eye);
		CHECK_EQ_INT(loom_render(&src, &b, img, NULL, &d), LOOM_EINVAL);
		CHECK_STR_CONTAINS(d.message, "target equals eye");
		b = o;
		b.light.dir[0] = b.light.dir[1] = b.light.dir[2] = 0;
		CHECK_EQ_INT(loom_render(&src, &b, img, NULL, &d), LOOM_EINVAL);
		CHECK_STR_CONTAINS(d.message, "distant light direction");
	}
	src.lookup = NULL;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "no lookup");
	src.lookup = synth_lookup;
	src.nz = 0;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "nz must be > 0");
	src.nz = 4;
	src.size = 4;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "LOOM_VOLUME_SOURCE_INIT");
	src.size = sizeof src;
	CHECK_EQ_INT(loom_camera_top(&src, 1, 0, 1, 4, &o.camera), LOOM_EINVAL);
	CHECK_EQ_INT(loom_camera_top(&src, 0, 0, 4, 4, &o.camera), LOOM_OK);

	/* a failing lookup stops the render with its code */
	s.kind = SRC_FAIL;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_EIO);
	CHECK_STR_CONTAINS(d.message, "lookup (or thread_init) failed with code 3");
	s.kind = SRC_CONST;

	/* progress: once per tile, ending at the total */
	n_progress = 0;
	o.tile = 2;
	o.progress = progress;
	CHECK_EQ_INT(loom_render(&src, &o, img, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(n_progress, 4);
	CHECK_EQ_INT(last_done, 4);
	CHECK_EQ_INT(last_total, 4);
}

static void test_tonemap(void)
{
	const float in[9] = {0.0f, 1.0f, 0.5f, 0.002f, 2.0f, -1.0f, NAN, 0.25f, INFINITY};
	uint8_t out[9];

	loom_render_to_srgb8(in, 3, 0.0, out);
	CHECK_EQ_INT(out[0], 0);
	CHECK_EQ_INT(out[1], 255);
	CHECK_EQ_INT(out[2], 188);  /* 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354 */
	CHECK_EQ_INT(out[3], 7);    /* linear segment: 12.92 * 0.002 * 255 */
	CHECK_EQ_INT(out[4], 255);
	CHECK_EQ_INT(out[5], 0);
	CHECK_EQ_INT(out[6], 0);
	CHECK_EQ_INT(out[7], 137);  /* 0.25 -> 0.5371 */
	CHECK_EQ_INT(out[8], 255);
	loom_render_to_srgb8(in + 6, 1, 1.0, out); /* exposure +1: 0.25 -> 0.5 */
	CHECK_EQ_INT(out[1], 188);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_render");
	RUN(test_microflake_distribution);
	RUN(test_phase_normalised);
	RUN(test_phase_sampling_chi2);
	RUN(test_white_furnace);
	RUN(test_empty_is_background);
	RUN(test_transmittance);
	RUN(test_single_scattering);
	RUN(test_sun_disc);
	RUN(test_sphere_and_extra_lights);
	RUN(test_determinism);
	RUN(test_camera_lens_and_ortho);
	RUN(test_half_dense_preview);
	RUN(test_shell_matches_slab);
	RUN(test_shell_unbounded);
	RUN(test_thread_hooks);
	RUN(test_options_and_errors);
	RUN(test_tonemap);
	CHECK_MAIN_END();
}
