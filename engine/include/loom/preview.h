/*
 * loom/preview.h - pictures of a fabric's virtual texture: a fast shaded
 * orthographic top view (loom_preview) and the adapter that lets the path
 * tracer of loom/render.h render a fabric (loom_texture_volume_source).
 * Include <loom.h>, not this file.  docs/preview.md explains both.
 */
#ifndef LOOM_PREVIEW_H
#define LOOM_PREVIEW_H

#include "common.h"
#include "fabric.h"
#include "render.h"
#include "texture.h"

#ifdef __cplusplus
extern "C" {
#endif

#define LOOM_PREVIEW_MAX_SIDE 65536u /* largest output width or height */

/* Options of loom_preview.  Initialise with LOOM_PREVIEW_OPTIONS_INIT. */
typedef struct loom_preview_options {
	size_t size;            /* sizeof(loom_preview_options) */
	int64_t lo[3], hi[3];   /* the box [lo, hi) in voxels: x, y any range
	                           (the bolt is unbounded), z clipped to
	                           [0, b3); hi[2] <= lo[2] means all of
	                           [0, b3) */
	uint32_t width;         /* output pixels across x, 1..65536 */
	uint32_t height;        /* output pixels along y; 0 = keep the box's
	                           aspect (round(width * ny / nx), >= 1) */
	uint32_t threads;       /* worker threads; 0 = online CPUs */
	float threshold;        /* a voxel is surface when density >= this
	                           (compared in the raw byte: density*255 >=
	                           ceil(threshold*255 - 1e-3), at least 1);
	                           <= 0 = 0.2 */
	double light[3];        /* direction towards the light (any length);
	                           all zero = (-0.4, 0.5, 0.77) */
	float background[3];    /* linear RGB of columns with no surface */
	void (*progress)(void *user, uint64_t done, uint64_t total);
	                        /* optional: pixels looked up so far; called
	                           from worker threads, one at a time */
	void *progress_user;
} loom_preview_options;

#define LOOM_PREVIEW_OPTIONS_INIT                                          \
	{sizeof(loom_preview_options), {0, 0, 0}, {0, 0, 0}, 512, 0, 0, 0.2f, \
	 {0.0, 0.0, 0.0}, {0.0f, 0.0f, 0.0f}, NULL, NULL}

/* Optional per-pixel outputs of loom_preview (width * height entries each,
   row 0 at the top = largest y; NULL = not wanted). */
typedef struct loom_preview_maps {
	float *height;          /* top of the surface voxel, z + 1 in voxels
	                           (absolute z); 0 where the column is empty */
	float *albedo;          /* 3 per pixel: the surface voxel's yarn albedo
	                           (linear RGB); the background where empty */
	uint8_t *kind;          /* 0 empty, 1 warp, 2 weft on top */
} loom_preview_maps;

typedef struct loom_preview_stats {
	uint64_t pixels;        /* width * height */
	uint64_t columns;       /* voxel columns read (one per pixel, fewer
	                           when pixels share a column) */
	uint64_t region_reads;  /* loom_texture_read_region calls */
	uint64_t empty;         /* pixels with no surface */
	double seconds;         /* wall time of loom_preview */
} loom_preview_stats;

/*
 * Output size for opt: *w = opt->width, *h = opt->height or the box's
 * aspect.  LOOM_OK; LOOM_EINVAL (NULL, width 0, empty box in x or y);
 * LOOM_ERANGE (a side above LOOM_PREVIEW_MAX_SIDE or a box side above
 * 2^46 voxels).
 */
LOOM_API int loom_preview_size(const loom_preview_options *opt, uint32_t *w,
                               uint32_t *h);

/*
 * Orthographic top view of the box of fabric f through its texture t.
 * Pixel (i, j) (column i, row j from the top) shows the voxel column
 *   x = lo0 + floor((i + 0.5) nx / W),  y = hi1 - 1 - floor((j + 0.5) ny / H)
 * (its centre; no filtering).  Per column the top-most voxel with density
 * at or above the threshold is the surface: its height z + 1, its fibre
 * orientation and its yarn's albedo.  Shading (linear RGB into rgb, 3 floats
 * per pixel, caller-allocated):
 *   n  = normalize(-dh/dx, -dh/dy, 1) from central differences of the
 *        height map (in voxels per voxel of distance),
 *   t  = fibre direction, L = light, H = normalize(L + (0,0,1)),
 *   rgb = albedo * (0.12 + 0.88 * max(0, n.L) * (0.3 + 0.7 sqrt(1-(t.L)^2)))
 *         * occlusion + 0.25 (1 - alignment) sqrt(1-(t.H)^2)^24 max(0, n.L)
 *   occlusion = 0.45 + 0.55 (h - lo2) / (hi2 - lo2).
 * Reads are streamed: pixels are ordered by the source block of their
 * crossing (so the bricks of one exemplar block are decompressed once,
 * whatever the cache budget) and read as runs of up to 64 neighbouring
 * columns per loom_texture_read_region call (z fastest).  Memory besides
 * the caller's buffers: 4 bytes per pixel, plus 4 when maps->height is
 * NULL, plus a few KiB per thread.  Deterministic: the result depends on
 * the inputs only, not on the thread count.  maps and stats may be NULL.
 * Returns LOOM_OK; errors of loom_preview_size; LOOM_EINVAL (NULL t, f or
 * rgb); LOOM_ENOMEM; a region read's error code (brick read failures;
 * the message in diag).
 */
LOOM_API int loom_preview(loom_texture *t, const loom_fabric *f,
                          const loom_preview_options *opt, float *rgb,
                          const loom_preview_maps *maps,
                          loom_preview_stats *stats, loom_diag *diag);

/*
 * Fill *src so that loom_render draws fabric f through its texture t:
 * an unbounded slab (nx = ny = 0), nz = b3, voxel_mm from the database,
 * max_density 1; the lookup is loom_texture_sample with `filter`
 * (LOOM_FILTER_NEAREST or LOOM_FILTER_TRILINEAR): density, fibre direction,
 * yarn albedo and alignment.  Per-thread hooks give each render thread's
 * texture state back when it ends (loom_texture_thread_done).  t and f are
 * borrowed and must outlive the render; set src->nx, src->ny for a window.
 * Returns LOOM_OK or LOOM_EINVAL (NULL, unknown filter, detached fabric).
 */
LOOM_API int loom_texture_volume_source(loom_texture *t, const loom_fabric *f,
                                        int filter, loom_volume_source *src);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_PREVIEW_H */
