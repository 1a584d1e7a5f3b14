/*
 * tools/loom/views.h - pictures of a fabric shared by loom look and loom
 * serve: a path-traced view of a region framed from above at an angle
 * (loom_render over the fabric's texture), and progressive rendering
 * (passes of growing samples per pixel averaged, with a noise estimate).
 */
#ifndef LOOM_VIEWS_H
#define LOOM_VIEWS_H

#include "loom.h"

/* Render options for the region [lo, hi) (voxels, x and y) seen from
   elevation 40 degrees, the light and environment of loom render. */
void view_render_setup(const loom_volume_source *src, const int64_t lo[2],
                       const int64_t hi[2], uint32_t width, uint32_t height,
                       loom_render_options *ro);

/* Progressive rendering: passes with seed + k and spp 1, 1, 2, 4, ...
   (at most max_pass_spp), averaged by weight into mean[].  se is the mean
   relative standard error of the pixels' luminance (from the spread of
   the passes), 1 until two passes are in. */
typedef struct view_prog {
	uint32_t width, height;
	double *sum, *sum2;      /* per pixel: sum of w x and w x^2 (luminance) */
	double *acc;             /* per pixel rgb: sum of w x */
	float *pass, *mean;      /* this pass; the running mean (rgb) */
	uint32_t spp_total, passes;
	double se;
} view_prog;

int view_prog_init(view_prog *p, uint32_t width, uint32_t height);
void view_prog_free(view_prog *p);
/* Run one pass of spp samples (seed varies with the pass).  LOOM_OK or
   loom_render's code. */
int view_prog_pass(view_prog *p, const loom_volume_source *src,
                   loom_render_options *ro, uint32_t spp, loom_diag *diag);

#endif
