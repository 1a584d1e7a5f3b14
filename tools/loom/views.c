/*
 * tools/loom/views.c - framed renders and progressive rendering (views.h).
 *
 * Progressive: pass i renders s_i samples per pixel with seed + i; the
 * running mean is sum(s_i x_i) / S.  The passes are independent estimates
 * of the same pixel with variance sigma^2 / s_i, so
 *     sum s_i (x_i - m)^2  ~  (N - 1) sigma^2,   var(m) = sigma^2 / S,
 * which gives the standard error of the mean per pixel; `se` is its mean
 * over the picture relative to the pixel's luminance (floored at 0.05).
 */
#include "views.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

void view_render_setup(const loom_volume_source *src, const int64_t lo[2],
                       const int64_t hi[2], uint32_t width, uint32_t height,
                       loom_render_options *ro)
{
	double el = 40 * M_PI / 180, fov = 30, c[3], wspan, dist;
	double aspect = (double)width / height, tanh_y = tan(0.5 * fov * M_PI / 180.0);
	loom_camera *cam = &ro->camera;

	ro->width = width;
	ro->height = height;
	ro->density_scale = 2;
	ro->max_depth = 32;
	ro->light.kind = LOOM_LIGHT_DISTANT;
	ro->light.dir[0] = -0.35;
	ro->light.dir[1] = -0.45;
	ro->light.dir[2] = 1.0;
	ro->light.rgb[0] = ro->light.rgb[1] = ro->light.rgb[2] = 2.6f;
	ro->env[0] = ro->env[1] = ro->env[2] = 0.18f;
	c[0] = 0.5 * (double)(lo[0] + hi[0]);
	c[1] = 0.5 * (double)(lo[1] + hi[1]);
	c[2] = 0.5 * (double)src->nz;
	wspan = (double)(hi[0] - lo[0]) / (2.0 * tanh_y * aspect);
	dist = (double)(hi[1] - lo[1]) * sin(el) / (2.0 * tanh_y);
	dist = (wspan > dist ? wspan : dist) + 0.5 * (double)(hi[1] - lo[1]) * cos(el);
	cam->kind = LOOM_CAMERA_PINHOLE;
	memcpy(cam->target, c, sizeof c);
	cam->eye[0] = c[0];
	cam->eye[1] = c[1] - dist * cos(el);
	cam->eye[2] = c[2] + dist * sin(el);
	cam->up[0] = 0;
	cam->up[1] = 0;
	cam->up[2] = 1;
	cam->fov_y_deg = fov;
}

int view_prog_init(view_prog *p, uint32_t width, uint32_t height)
{
	size_t n = (size_t)width * height;

	memset(p, 0, sizeof *p);
	p->width = width;
	p->height = height;
	p->sum = calloc(n, sizeof *p->sum);
	p->sum2 = calloc(n, sizeof *p->sum2);
	p->acc = calloc(3 * n, sizeof *p->acc);
	p->pass = malloc(3 * n * sizeof *p->pass);
	p->mean = calloc(3 * n, sizeof *p->mean);
	p->se = 1;
	if (!p->sum || !p->sum2 || !p->acc || !p->pass || !p->mean) {
		view_prog_free(p);
		return LOOM_ENOMEM;
	}
	return LOOM_OK;
}

void view_prog_free(view_prog *p)
{
	free(p->sum);
	free(p->sum2);
	free(p->acc);
	free(p->pass);
	free(p->mean);
	memset(p, 0, sizeof *p);
}

int view_prog_pass(view_prog *p, const loom_volume_source *src,
                   loom_render_options *ro, uint32_t spp, loom_diag *diag)
{
	size_t n = (size_t)p->width * p->height;
	uint64_t seed = ro->seed;
	double se = 0, S;
	int rc;

	ro->spp = spp;
	ro->seed = seed + 7919u * p->passes;
	rc = loom_render(src, ro, p->pass, NULL, diag);
	ro->seed = seed;
	if (rc != LOOM_OK)
		return rc;
	p->passes++;
	p->spp_total += spp;
	S = p->spp_total;
	for (size_t k = 0; k < n; k++) {
		const float *x = p->pass + 3 * k;
		double y = 0.2126 * x[0] + 0.7152 * x[1] + 0.0722 * x[2], m, v;
		p->sum[k] += spp * y;
		p->sum2[k] += spp * y * y;
		for (int c = 0; c < 3; c++) {
			p->acc[3 * k + (size_t)c] += spp * (double)x[c];
			p->mean[3 * k + (size_t)c] = (float)(p->acc[3 * k + (size_t)c] / S);
		}
		if (p->passes > 1) {
			m = p->sum[k] / S;
			v = (p->sum2[k] - S * m * m) / ((p->passes - 1) * S);
			se += sqrt(v > 0 ? v : 0) / (m > 0.05 ? m : 0.05);
		}
	}
	p->se = p->passes > 1 ? se / (double)n : 1;
	return LOOM_OK;
}
