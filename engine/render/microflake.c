/*
 * engine/render/microflake.c - the microflake phase function of Jakob et al. 2010
 * with the Gaussian fibre distribution of Zhao et al. 2011 (the model the
 * paper renders with, section 7).  docs/rendering.md has the derivations.
 *
 * The flake-normal distribution around fibre direction w, t = m.w:
 *
 *     D(m) = C(s) exp(-t^2 / (2 s^2)),
 *     C(s) = 1 / (2 pi * s sqrt(2 pi) * erf(1 / (s sqrt 2)))
 *
 * (the integral of exp over t in [-1, 1] times 2 pi for the azimuth).
 *
 * Projected area.  sigma(omega) = int |omega.m| D(m) dm.  With omega at
 * angle alpha from w, omega.m = t cos(alpha) + sin(alpha) sqrt(1-t^2) cos phi
 * and the azimuthal integral has a closed form,
 *
 *     G(a, b) = int_0^{2pi} |a + b cos phi| dphi
 *             = 2 pi |a|                            if |a| >= b
 *             = 2a (2 phi0 - pi) + 4 b sin phi0,    phi0 = acos(-a/b), else
 *
 * so sigma is a 1-D integral over t, done by composite Simpson split at the
 * kink t = sin(alpha).  The tracer needs it at every tentative collision,
 * so log A (A = 2 sigma) is tabulated once (pthread_once) on a 64 x 129 grid:
 * log-spaced s in [LOOM_MF_SIGMA_MIN, LOOM_MF_SIGMA_MAX] and angle nodes
 * alpha_k = (pi/2)(k/128)^2, dense near the fibre axis where A changes on
 * the scale of s.  Lookups are bilinear in (log s, sqrt alpha) on log A,
 * which is exact along the fibre where A is proportional to s.
 *
 * Sampling.  Flake normals with density |wi.m| D(m) / sigma(wi), mirrored:
 * wo = 2 (wi.m) m - wi.  In the frame (w, e1, e2) with wi = c w + b e1,
 * |wi.m| <= |c||t| + b|cos phi|, so the proposal
 *
 *     g(m) = (|c| |t| + b |cos phi|) D(m)
 *
 * bounds the target; it is a mixture of |t| D (t by inverting its CDF, phi
 * uniform; mass c1(s) in closed form) and |cos phi| D (t from the truncated
 * Gaussian, phi from |cos phi|; mass 2/pi), weighted |c| c1 : b 2/pi.  A
 * proposal is accepted with probability |wi.m| / (|c||t| + b|cos phi|).
 * Every step is exact, so the samples follow f exactly (no table enters);
 * acceptance is sigma(wi) / (|c| c1 + b 2/pi), above 0.6 in practice.
 */
#include "render_internal.h"

#include <pthread.h>

#define MF_NS 64          /* s nodes */
#define MF_NA 129         /* angle nodes */
#define MF_TABLE_STEPS 400 /* Simpson intervals per table entry */
#define MF_EXACT_STEPS 20000

static double mf_table[MF_NS][MF_NA]; /* log A, A = 2 sigma; written once */
static double mf_amax;
static pthread_once_t mf_once = PTHREAD_ONCE_INIT;

static double clamp_s(double s)
{
	if (!(s >= LOOM_MF_SIGMA_MIN)) /* also NaN */
		return LOOM_MF_SIGMA_MIN;
	return s > LOOM_MF_SIGMA_MAX ? LOOM_MF_SIGMA_MAX : s;
}

static double norm_c(double s)
{
	return 1.0 / (2.0 * M_PI * s * sqrt(2.0 * M_PI) * erf(1.0 / (s * M_SQRT2)));
}

LOOM_API double loom_microflake_D(double s, double cos_theta)
{
	s = clamp_s(s);
	return norm_c(s) * exp(-cos_theta * cos_theta / (2.0 * s * s));
}

/* G(a, b) = integral over phi of |a + b cos phi|, b >= 0. */
static double azimuth_integral(double a, double b)
{
	double r, phi0;

	if (b <= fabs(a))
		return 2.0 * M_PI * fabs(a);
	r = -a / b;
	phi0 = acos(r);
	return 2.0 * a * (2.0 * phi0 - M_PI) + 4.0 * b * sqrt(fmax(0.0, 1.0 - r * r));
}

/* Simpson's rule of exp(-t^2/2s^2) G(t ca, sa sqrt(1-t^2)) over [t0, t1]. */
static double simpson(double s, double ca, double sa, double t0, double t1, int n)
{
	double h, sum = 0;

	if (t1 <= t0)
		return 0;
	n += n & 1;
	h = (t1 - t0) / n;
	for (int k = 0; k <= n; k++) {
		double t = k == n ? t1 : t0 + k * h;
		double f = exp(-t * t / (2 * s * s)) *
		           azimuth_integral(t * ca, sa * sqrt(fmax(0.0, 1.0 - t * t)));
		sum += f * (k == 0 || k == n ? 1 : (k & 1) ? 4 : 2);
	}
	return sum * h / 3;
}

/* A = 2 sigma by quadrature with about n intervals. */
static double area_quad(double s, double cos_w, int n)
{
	double ca = fmin(1.0, fabs(cos_w)), sa = sqrt(fmax(0.0, 1.0 - ca * ca));
	double tmax = fmin(1.0, 10.0 * s), kink = sa, integral;

	/* The integrand is even in t: twice the integral over [0, tmax],
	   split at the kink of G (where |t ca| = sa sqrt(1 - t^2), t = sa). */
	if (kink > 0 && kink < tmax) {
		int n1 = (int)(n * kink / tmax) + 2;
		integral = simpson(s, ca, sa, 0, kink, n1) +
		           simpson(s, ca, sa, kink, tmax, n - n1 + 4);
	} else {
		integral = simpson(s, ca, sa, 0, tmax, n);
	}
	return 2.0 * (2.0 * norm_c(s) * integral);
}

LOOM_API double loom_microflake_area_exact(double s, double cos_w)
{
	return area_quad(clamp_s(s), cos_w, MF_EXACT_STEPS);
}

static double node_s(int i)
{
	double l0 = log(LOOM_MF_SIGMA_MIN), l1 = log(LOOM_MF_SIGMA_MAX);
	return exp(l0 + (l1 - l0) * i / (MF_NS - 1));
}

static void build_tables(void)
{
	double amax = 1.0;

	for (int i = 0; i < MF_NS; i++) {
		double s = node_s(i);
		for (int k = 0; k < MF_NA; k++) {
			double u = (double)k / (MF_NA - 1);
			double alpha = 0.5 * M_PI * u * u;
			double a = area_quad(s, cos(alpha), MF_TABLE_STEPS);
			mf_table[i][k] = log(a);
			if (a > amax)
				amax = a;
		}
	}
	mf_amax = amax;
}

static void ensure_tables(void)
{
	pthread_once(&mf_once, build_tables);
}

LOOM_API double loom_microflake_area(double s, double cos_w)
{
	double fs, fa, ca, alpha;
	int i, k;

	ensure_tables();
	s = clamp_s(s);
	fs = (log(s) - log(LOOM_MF_SIGMA_MIN)) /
	     (log(LOOM_MF_SIGMA_MAX) - log(LOOM_MF_SIGMA_MIN)) * (MF_NS - 1);
	ca = fabs(cos_w);
	alpha = acos(ca < 1.0 ? ca : 1.0);
	fa = sqrt(alpha / (0.5 * M_PI)) * (MF_NA - 1);
	i = (int)fs;
	k = (int)fa;
	if (i > MF_NS - 2)
		i = MF_NS - 2;
	if (i < 0)
		i = 0;
	if (k > MF_NA - 2)
		k = MF_NA - 2;
	if (k < 0)
		k = 0;
	fs -= i;
	fa -= k;
	return exp((1 - fs) * ((1 - fa) * mf_table[i][k] + fa * mf_table[i][k + 1]) +
	           fs * ((1 - fa) * mf_table[i + 1][k] + fa * mf_table[i + 1][k + 1]));
}

void loom__mf_row_fill(loom__mf_row *r, double s)
{
	r->s = s;
	for (int k = 0; k < LOOM__MF_ROW; k++) {
		double y = (double)k / (LOOM__MF_ROW - 1), y2 = y * y;
		r->a[k] = loom_microflake_area(s, 1.0 - y2 * y2);
	}
}

LOOM_API double loom_microflake_area_max(void)
{
	ensure_tables();
	return mf_amax;
}

LOOM_API double loom_rng_uniform(uint64_t *rng)
{
	return loom__rand01(rng);
}

/* Unit copy of w; returns 0 when w is (nearly) zero. */
static int unit_axis(const double w[3], double out[3])
{
	out[0] = w[0];
	out[1] = w[1];
	out[2] = w[2];
	return loom__normalize3(out) > 1e-12;
}

LOOM_API double loom_microflake_eval(double s, const double w[3],
                                     const double wi[3], const double wo[3])
{
	double axis[3], h[3], len;

	if (!unit_axis(w, axis))
		return 1.0 / (4.0 * M_PI);
	h[0] = wi[0] + wo[0];
	h[1] = wi[1] + wo[1];
	h[2] = wi[2] + wo[2];
	len = sqrt(loom__dot3(h, h));
	if (len < 1e-12)
		return 0.0;
	return loom_microflake_D(s, loom__dot3(h, axis) / len) /
	       loom_microflake_area(s, loom__dot3(wi, axis));
}

/* Standard normal deviate (Box-Muller, one of the pair). */
static double normal01(uint64_t *rng)
{
	double u1 = 1.0 - loom__rand01(rng), u2 = loom__rand01(rng);
	return sqrt(-2.0 * log(u1)) * cos(2.0 * M_PI * u2);
}

/* t in [-1, 1] with density proportional to exp(-t^2 / 2s^2). */
static double truncated_normal(double s, uint64_t *rng)
{
	for (;;) {
		double t = s * normal01(rng);
		if (t >= -1.0 && t <= 1.0)
			return t;
	}
}

static void uniform_sphere(uint64_t *rng, double out[3])
{
	double z = 1.0 - 2.0 * loom__rand01(rng);
	double r = sqrt(fmax(0.0, 1.0 - z * z)), phi = 2.0 * M_PI * loom__rand01(rng);
	out[0] = r * cos(phi);
	out[1] = r * sin(phi);
	out[2] = z;
}

/* Any unit vector perpendicular to unit a. */
static void perpendicular(const double a[3], double out[3])
{
	double t[3] = {0, 0, 0};
	t[fabs(a[0]) < 0.6 ? 0 : fabs(a[1]) < 0.6 ? 1 : 2] = 1.0;
	loom__cross3(a, t, out);
	loom__normalize3(out);
}

/* loom_microflake_sample's constants of the last roughness (per thread) */
static _Thread_local double mf_last_s = -1.0, mf_last_k1, mf_last_c1;

LOOM_API void loom_microflake_sample(double s, const double w[3],
                                     const double wi[3], uint64_t *rng,
                                     double wo[3])
{
	double axis[3], e1[3], e2[3], c, b, a, c1, p1, m[3], dm;
	double k1;

	if (!unit_axis(w, axis)) {
		uniform_sphere(rng, wo);
		return;
	}
	s = clamp_s(s);
	c = loom__dot3(wi, axis);
	if (c > 1.0)
		c = 1.0;
	if (c < -1.0)
		c = -1.0;
	for (int j = 0; j < 3; j++)
		e1[j] = wi[j] - c * axis[j];
	b = loom__normalize3(e1);
	if (b < 1e-9) {
		perpendicular(axis, e1);
		b = 0.0;
	}
	loom__cross3(axis, e1, e2);
	a = fabs(c);
	/* c1 = int |t| D(m) dm;  the |cos phi| component has mass 2/pi.
	   Both depend on s alone: the thread keeps the last s's (a path
	   meets a few yarn types' roughnesses) */
	if (s != mf_last_s) {
		mf_last_k1 = -expm1(-1.0 / (2.0 * s * s));
		mf_last_c1 = s * sqrt(2.0 / M_PI) * mf_last_k1 / erf(1.0 / (s * M_SQRT2));
		mf_last_s = s;
	}
	k1 = mf_last_k1;
	c1 = mf_last_c1;
	p1 = a * c1 / (a * c1 + b * (2.0 / M_PI));

	for (;;) {
		double t, cp, sp, st, bound, target;
		if (loom__rand01(rng) < p1) {
			double u = loom__rand01(rng);
			t = s * sqrt(-2.0 * log1p(-u * k1));
			if (t > 1.0)
				t = 1.0;
			if (loom__rand01(rng) < 0.5)
				t = -t;
			u = 2.0 * M_PI * loom__rand01(rng);
			cp = cos(u);
			sp = sin(u);
		} else {
			/* phi = asin(v) (+ pi): sin phi = v, cos phi = sqrt(1 - v^2)
			   (the signs of both flipped by the pi) without the trig */
			t = truncated_normal(s, rng);
			sp = 2.0 * loom__rand01(rng) - 1.0;
			cp = sqrt(fmax(0.0, 1.0 - sp * sp));
			if (loom__rand01(rng) < 0.5) {
				sp = -sp;
				cp = -cp;
			}
		}
		st = sqrt(fmax(0.0, 1.0 - t * t));
		bound = a * fabs(t) + b * fabs(cp);
		target = fabs(c * t + b * st * cp);
		if (loom__rand01(rng) * bound < target) {
			for (int j = 0; j < 3; j++)
				m[j] = t * axis[j] + st * (cp * e1[j] + sp * e2[j]);
			break;
		}
	}
	dm = loom__dot3(wi, m);
	for (int j = 0; j < 3; j++)
		wo[j] = 2.0 * dm * m[j] - wi[j];
	loom__normalize3(wo);
}
