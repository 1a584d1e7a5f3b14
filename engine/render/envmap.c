/*
 * engine/render/envmap.c - an HDR environment map in latitude-longitude
 * layout, evaluated and importance-sampled for the path tracer
 * (docs/rendering.md, "Environment maps").
 *
 * Layout.  Pixel (x, y) of a W x H map covers azimuth
 * phi in [2 pi x / W, 2 pi (x+1) / W) (counter-clockwise from +x towards +y,
 * before the rotation) and polar angle theta in [pi y / H, pi (y+1) / H)
 * from +z (row 0 is the zenith).  The radiance is constant over a pixel
 * (nearest lookup), so the map is exactly a piecewise-constant function on
 * the sphere.
 *
 * Sampling.  Pixel (x, y) is chosen with probability proportional to its
 * luminance times its solid angle (2 pi / W)(cos theta0 - cos theta1): row
 * y by the marginal CDF (the sum over the row), then column x by that row's
 * conditional CDF; inside the pixel, phi is uniform and cos theta uniform,
 * so the pdf per steradian is constant over the pixel:
 *     pdf = P(y) P(x | y) / ((2 pi / W)(cos theta0 - cos theta1)).
 * Both CDFs are stored, and pdf() reads the probabilities back as CDF
 * differences, so sampling and pdf agree to rounding.  The marginal is in
 * doubles, the conditional in floats (W + 1 per row).
 *
 * Memory: 12 bytes per pixel (RGB) + 4 (W + 1) H + 8 (H + 1) bytes,
 * loom_envmap_bytes(); immutable after loom_envmap_new.
 */
#include "render_internal.h"

#include <stdlib.h>
#include <string.h>

struct loom_envmap {
	uint32_t w, h;
	float *rgb;       /* 3 w h, row 0 = zenith, scaled by the intensity */
	float *cond;      /* (w + 1) h: per row CDF over columns, 0 .. 1 */
	double *marg;     /* h + 1: CDF over rows, 0 .. 1 */
	double rot;       /* rotation about +z, radians */
	double total;     /* sum of luminance x solid angle (0: no sampling) */
};

static double lum(const float *c)
{
	return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}

static double band(uint32_t y, uint32_t h)
{
	return cos(M_PI * y / h) - cos(M_PI * (y + 1) / h);
}

LOOM_API size_t loom_envmap_bytes(uint32_t width, uint32_t height)
{
	return sizeof(loom_envmap) + (size_t)width * height * 3 * sizeof(float) +
	       ((size_t)width + 1) * height * sizeof(float) +
	       ((size_t)height + 1) * sizeof(double);
}

LOOM_API void loom_envmap_free(loom_envmap *m)
{
	if (!m)
		return;
	free(m->rgb);
	free(m->cond);
	free(m->marg);
	free(m);
}

LOOM_API int loom_envmap_new(const float *rgb, uint32_t width, uint32_t height,
                             double rotate_deg, double intensity,
                             loom_envmap **out, loom_diag *diag)
{
	loom_envmap *m;
	size_t n;

	if (!out || !rgb)
		return loom__fail(diag, LOOM_EINVAL, "loom_envmap_new: NULL argument");
	*out = NULL;
	if (width < 1 || height < 1 ||
	    (uint64_t)width * height > LOOM_ENVMAP_MAX_PIXELS)
		return loom__fail(diag, LOOM_ERANGE,
		                  "environment map %u x %u: at least 1 x 1 and at most "
		                  "%llu pixels", width, height,
		                  (unsigned long long)LOOM_ENVMAP_MAX_PIXELS);
	if (!isfinite(rotate_deg) || !(intensity >= 0) || !isfinite(intensity))
		return loom__fail(diag, LOOM_EINVAL,
		                  "environment map: rotation must be finite and intensity "
		                  "finite and >= 0 (got %g, %g)", rotate_deg, intensity);
	n = (size_t)width * height;
	for (size_t i = 0; i < 3 * n; i++)
		if (!(rgb[i] >= 0) || !isfinite(rgb[i]))
			return loom__fail(diag, LOOM_EINVAL,
			                  "environment map: pixel (%zu, %zu) channel %zu is %g; "
			                  "radiance must be finite and >= 0", (i / 3) % width,
			                  (i / 3) / width, i % 3, (double)rgb[i]);
	m = calloc(1, sizeof *m);
	if (!m)
		return loom__fail(diag, LOOM_ENOMEM, "environment map: out of memory");
	m->w = width;
	m->h = height;
	m->rot = fmod(rotate_deg, 360.0) * M_PI / 180.0;
	m->rgb = malloc(3 * n * sizeof *m->rgb);
	m->cond = malloc(((size_t)width + 1) * height * sizeof *m->cond);
	m->marg = malloc(((size_t)height + 1) * sizeof *m->marg);
	if (!m->rgb || !m->cond || !m->marg) {
		loom_envmap_free(m);
		return loom__fail(diag, LOOM_ENOMEM, "environment map: out of memory");
	}
	for (size_t i = 0; i < 3 * n; i++)
		m->rgb[i] = (float)(rgb[i] * intensity);
	m->marg[0] = 0;
	for (uint32_t y = 0; y < height; y++) {
		float *cd = m->cond + (size_t)y * (width + 1);
		double s = 0, sa = band(y, height) * 2.0 * M_PI / width;
		cd[0] = 0;
		for (uint32_t x = 0; x < width; x++) {
			s += lum(m->rgb + 3 * ((size_t)y * width + x));
			cd[x + 1] = (float)s;
		}
		for (uint32_t x = 1; x <= width; x++)
			cd[x] = s > 0 ? (float)(cd[x] / s) : (float)x / (float)width;
		cd[width] = 1.0f;
		m->marg[y + 1] = m->marg[y] + s * sa;
	}
	m->total = m->marg[height];
	for (uint32_t y = 1; y <= height; y++)
		m->marg[y] = m->total > 0 ? m->marg[y] / m->total : (double)y / height;
	m->marg[height] = 1.0;
	*out = m;
	return LOOM_OK;
}

/* Pixel of direction d (unit). */
static void pixel_of(const loom_envmap *m, const double d[3], uint32_t *x,
                     uint32_t *y)
{
	double ct = d[2] > 1 ? 1 : d[2] < -1 ? -1 : d[2];
	double th = acos(ct), ph = atan2(d[1], d[0]) - m->rot;
	double u = ph / (2.0 * M_PI);
	int64_t xi, yi;

	u -= floor(u);
	xi = (int64_t)(u * m->w);
	yi = (int64_t)(th / M_PI * m->h);
	*x = (uint32_t)(xi < 0 ? 0 : xi >= m->w ? m->w - 1 : xi);
	*y = (uint32_t)(yi < 0 ? 0 : yi >= m->h ? m->h - 1 : yi);
}

LOOM_API void loom_envmap_eval(const loom_envmap *m, const double d[3],
                               double rgb[3])
{
	uint32_t x, y;
	const float *c;

	pixel_of(m, d, &x, &y);
	c = m->rgb + 3 * ((size_t)y * m->w + x);
	rgb[0] = c[0];
	rgb[1] = c[1];
	rgb[2] = c[2];
}

static double pdf_pixel(const loom_envmap *m, uint32_t x, uint32_t y)
{
	const float *cd = m->cond + (size_t)y * (m->w + 1);
	double p = (m->marg[y + 1] - m->marg[y]) * ((double)cd[x + 1] - cd[x]);
	double sa = band(y, m->h) * 2.0 * M_PI / m->w;
	return sa > 0 ? p / sa : 0.0;
}

LOOM_API double loom_envmap_pdf(const loom_envmap *m, const double d[3])
{
	uint32_t x, y;

	if (!(m->total > 0))
		return 0.0;
	pixel_of(m, d, &x, &y);
	return pdf_pixel(m, x, y);
}

/* Last index i in [0, n) with cdf[i] <= u (cdf[0] = 0 <= u < 1 = cdf[n])
   whose interval is not empty. */
static uint32_t find_d(const double *cdf, uint32_t n, double u)
{
	uint32_t lo = 0, hi = n;
	while (hi - lo > 1) {
		uint32_t mid = lo + (hi - lo) / 2;
		if (cdf[mid] <= u)
			lo = mid;
		else
			hi = mid;
	}
	while (lo + 1 < n && !(cdf[lo + 1] > cdf[lo]))
		lo++;
	return lo;
}

static uint32_t find_f(const float *cdf, uint32_t n, double u)
{
	uint32_t lo = 0, hi = n;
	while (hi - lo > 1) {
		uint32_t mid = lo + (hi - lo) / 2;
		if ((double)cdf[mid] <= u)
			lo = mid;
		else
			hi = mid;
	}
	while (lo + 1 < n && !(cdf[lo + 1] > cdf[lo]))
		lo++;
	return lo;
}

LOOM_API double loom_envmap_sample(const loom_envmap *m, double u1, double u2,
                                   double d[3])
{
	uint32_t x, y;
	const float *cd;
	double r, ph, ct, st, c0, c1, fy, fx;

	if (!(m->total > 0))
		return 0.0;
	y = find_d(m->marg, m->h, u1);
	cd = m->cond + (size_t)y * (m->w + 1);
	x = find_f(cd, m->w, u2);
	/* the residuals of u1, u2 inside the chosen cells place the point */
	fy = (u1 - m->marg[y]) / (m->marg[y + 1] - m->marg[y]);
	fx = (u2 - cd[x]) / ((double)cd[x + 1] - cd[x]);
	fy = fy < 0 ? 0 : fy > 1 ? 1 : fy;
	fx = fx < 0 ? 0 : fx > 1 ? 1 : fx;
	c0 = cos(M_PI * y / m->h);
	c1 = cos(M_PI * (y + 1) / m->h);
	ct = c0 + fy * (c1 - c0);
	st = sqrt(fmax(0.0, 1.0 - ct * ct));
	ph = 2.0 * M_PI * (x + fx) / m->w + m->rot;
	d[0] = st * cos(ph);
	d[1] = st * sin(ph);
	d[2] = ct;
	r = pdf_pixel(m, x, y);
	return r;
}

LOOM_API double loom_mis_power(double pdf_a, double pdf_b)
{
	double a = pdf_a * pdf_a, b = pdf_b * pdf_b;
	if (!(a > 0))
		return 0.0;
	if (isinf(a))
		return 1.0;
	return a / (a + b);
}

/* ---- the built-in studio sky -------------------------------------------- */

/* Zenith, horizon and floor radiance, and the glow's colour and width
   (1 - cos of the angle to the sun at which it falls to 1/e: about 15
   degrees). */
static const double SKY_ZEN[3] = {0.32, 0.34, 0.37};
static const double SKY_HOR[3] = {0.13, 0.13, 0.14};
static const double SKY_FLOOR[3] = {0.05, 0.05, 0.05};
static const double SKY_GLOW[3] = {0.9, 0.82, 0.68};
#define SKY_GLOW_W 0.034
#define SKY_BLEND 0.04 /* z over which the horizon fades into the floor */

LOOM_API void loom_sky_studio(const double sun[3], const double d[3], double rgb[3])
{
	double z = d[2] > 1 ? 1 : d[2] < -1 ? -1 : d[2];
	double ns = sqrt(sun[0] * sun[0] + sun[1] * sun[1] + sun[2] * sun[2]);
	double cg = ns > 0 ? (sun[0] * d[0] + sun[1] * d[1] + sun[2] * d[2]) / ns : -1;
	double glow = exp(-(1.0 - cg) / SKY_GLOW_W);
	double up = z > 0 ? sqrt(z) : 0.0;                /* 0 horizon .. 1 zenith */
	double sky = z >= 0 ? 1.0 : exp(z / SKY_BLEND);  /* 1 above, fading below */

	for (int j = 0; j < 3; j++) {
		double dome = SKY_HOR[j] + (SKY_ZEN[j] - SKY_HOR[j]) * up;
		rgb[j] = SKY_FLOOR[j] + sky * (dome + SKY_GLOW[j] * glow - SKY_FLOOR[j]);
	}
}

LOOM_API int loom_sky_studio_map(const double sun[3], uint32_t width, uint32_t height,
                                 float *rgb)
{
	enum { SUB = 4 };

	if (!sun || !rgb || width < 1 || height < 1)
		return LOOM_EINVAL;
	if ((uint64_t)width * height > LOOM_ENVMAP_MAX_PIXELS)
		return LOOM_ERANGE;
	if (!isfinite(sun[0] + sun[1] + sun[2]) ||
	    !(sun[0] * sun[0] + sun[1] * sun[1] + sun[2] * sun[2] > 0))
		return LOOM_EINVAL;
	for (uint32_t y = 0; y < height; y++) {
		double c0 = cos(M_PI * y / height), c1 = cos(M_PI * (y + 1) / height);
		for (uint32_t x = 0; x < width; x++) {
			double acc[3] = {0, 0, 0};
			/* SUB x SUB directions at the centres of equal-solid-angle
			   cells (uniform in cos theta and phi) */
			for (int a = 0; a < SUB; a++) {
				double ct = c0 + (c1 - c0) * (a + 0.5) / SUB;
				double st = sqrt(fmax(0.0, 1.0 - ct * ct));
				for (int b = 0; b < SUB; b++) {
					double ph = 2.0 * M_PI * (x + (b + 0.5) / SUB) / width;
					double d[3] = {st * cos(ph), st * sin(ph), ct}, v[3];
					loom_sky_studio(sun, d, v);
					for (int j = 0; j < 3; j++)
						acc[j] += v[j];
				}
			}
			for (int j = 0; j < 3; j++)
				rgb[3 * ((size_t)y * width + x) + j] = (float)(acc[j] / (SUB * SUB));
		}
	}
	return LOOM_OK;
}
