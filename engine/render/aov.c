/*
 * engine/render/aov.c - per-pixel accumulation of loom_render's arbitrary
 * output variables (loom_render_aov): the first event's albedo, normal and
 * depth, and the standard error of the pixel's mean radiance.  Sums are
 * kept in double in sample order, so the values do not depend on threads.
 */
#include "render_internal.h"

#include <string.h>

void loom__aov_begin(loom__aov_acc *a)
{
	memset(a, 0, sizeof *a);
}

void loom__aov_add(loom__aov_acc *a, const double L[3], const loom__aov_hit *h)
{
	a->n++;
	for (int j = 0; j < 3; j++) {
		double v = isfinite(L[j]) ? L[j] : 0.0;
		a->s[j] += v;
		a->s2[j] += v * v;
	}
	if (!h->hit)
		return;
	a->n_hit++;
	a->depth += h->depth;
	for (int j = 0; j < 3; j++) {
		a->albedo[j] += h->albedo[j];
		a->normal[j] += h->normal[j];
	}
}

void loom__aov_store(const loom__aov_acc *a, const loom_render_aov *out, size_t pix)
{
	double n = a->n > 0 ? (double)a->n : 1.0;
	for (int j = 0; j < 3; j++) {
		if (out->albedo)
			out->albedo[3 * pix + (size_t)j] = (float)(a->albedo[j] / n);
		if (out->normal)
			out->normal[3 * pix + (size_t)j] = (float)(a->normal[j] / n);
		if (out->noise) {
			double var = 0;
			if (a->n > 1) {
				double mean = a->s[j] / n;
				var = fmax(0.0, (a->s2[j] - n * mean * mean) / (n - 1.0));
			}
			out->noise[3 * pix + (size_t)j] = (float)sqrt(var / n);
		}
	}
	if (out->depth)
		out->depth[pix] = a->n_hit ? (float)(a->depth / a->n_hit) : 0.0f;
}

/* Unit normal from a density gradient g (minus g, turned to face -d);
   -d when the gradient vanishes. */
void loom__aov_normal(const double g[3], const double d[3], double n[3])
{
	double v[3] = {-g[0], -g[1], -g[2]};
	if (!(loom__normalize3(v) > 0) || !isfinite(v[0] + v[1] + v[2])) {
		for (int j = 0; j < 3; j++)
			n[j] = -d[j];
		return;
	}
	if (loom__dot3(v, d) > 0)
		for (int j = 0; j < 3; j++)
			v[j] = -v[j];
	memcpy(n, v, sizeof v);
}
