/*
 * engine/render/ground.c - the optional floor of loom_render (loom_ground):
 * ray-plane intersection and the Lambertian lobe the path tracer samples
 * at a floor hit in place of the microflake phase function.  With the
 * albedo carried in the path throughput (as a medium's single-scattering
 * albedo), the lobe f(wo) = max(0, n . wo) / pi is both the BRDF times the
 * cosine and the pdf of cosine-weighted sampling, so a bounce has weight 1
 * exactly as a phase-function bounce.
 */
#include "render_internal.h"

double loom__ground_hit(const loom_ground *g, const double o[3], const double d[3])
{
	double t;
	if (!(d[2] != 0))
		return INFINITY;
	t = (g->height - o[2]) / d[2];
	return t > 0 && isfinite(t) ? t : INFINITY;
}

double loom__lambert_eval(const double n[3], const double wo[3])
{
	double c = loom__dot3(n, wo);
	return c > 0 ? c / M_PI : 0.0;
}

void loom__lambert_sample(const double n[3], uint64_t *rng, double wo[3])
{
	/* a point uniform on the unit disc lifted to the hemisphere (Malley) */
	double r = sqrt(loom__rand01(rng)), ph = 2.0 * M_PI * loom__rand01(rng);
	double x = r * cos(ph), y = r * sin(ph), z = sqrt(fmax(0.0, 1.0 - r * r));
	double t[3] = {0, 0, 0}, u[3], v[3];
	t[fabs(n[0]) < 0.6 ? 0 : fabs(n[1]) < 0.6 ? 1 : 2] = 1.0;
	loom__cross3(n, t, u);
	loom__normalize3(u);
	loom__cross3(n, u, v);
	for (int j = 0; j < 3; j++)
		wo[j] = x * u[j] + y * v[j] + z * n[j];
	loom__normalize3(wo);
}

int loom__ground_check(const loom_ground *g, loom_diag *diag)
{
	if (!g->enabled)
		return LOOM_OK;
	if (!isfinite(g->height))
		return loom__fail(diag, LOOM_EINVAL, "render: ground height must be finite");
	for (int j = 0; j < 3; j++)
		if (!(g->albedo[j] >= 0 && g->albedo[j] <= 1))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: ground albedo must be in [0, 1], got %g",
			                  (double)g->albedo[j]);
	return LOOM_OK;
}
