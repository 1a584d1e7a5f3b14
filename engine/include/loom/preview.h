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

/* How a pixel's colour is made (loom_preview_options.filter). */
enum loom_preview_filter {
	LOOM_PREVIEW_AUTO = 0,   /* EXACT when the box has at most 16 voxel
	                            columns per pixel, else BLOCKS */
	LOOM_PREVIEW_EXACT = 1,  /* every column under the pixel is read through
	                            the texture, shaded and averaged */
	LOOM_PREVIEW_BLOCKS = 2  /* area average from per-source-block tables:
	                            each source block used is read and shaded
	                            once (at its first crossing), and a pixel
	                            integrates the tables of the crossings it
	                            covers, in their yarn colours */
};

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
	double light[3];        /* direction towards the light in voxel space
	                           (any length); all zero = (-0.4, -0.5, 0.77),
	                           from the upper left of the picture */
	float background[3];    /* linear RGB of columns with no surface */
	void (*progress)(void *user, uint64_t done, uint64_t total);
	                        /* optional: work done of total (units: voxel
	                           columns read plus pixels made); called from
	                           worker threads, one at a time */
	void *progress_user;
	int filter;             /* enum loom_preview_filter */
	size_t memory_bytes;    /* cap on the preview's own working memory
	                           (row buffers, block tables); 0 = 16 MiB */
	const loom_yarn_type *types; /* yarn table to colour by (type IDs as
	                           the design's: a colour change needs no new
	                           synthesis); NULL = the fabric's design */
	uint32_t n_types;       /* entries of types */
	const struct loom_paint *paint; /* optional paint layer (loom/paint.h),
	                           bound to the texture (loom_paint_bind):
	                           its slubs, broken ends, missing picks and
	                           pulls shape the columns and its colours
	                           and stains tint them, column for column as
	                           loom_paint_sample; BLOCKS reads the pieces
	                           of a pixel that the paint reaches column by
	                           column.  NULL = none */
} loom_preview_options;

#define LOOM_PREVIEW_OPTIONS_INIT                                          \
	{sizeof(loom_preview_options), {0, 0, 0}, {0, 0, 0}, 512, 0, 0, 0.2f, \
	 {0.0, 0.0, 0.0}, {0.0f, 0.0f, 0.0f}, NULL, NULL, LOOM_PREVIEW_AUTO, 0, \
	 NULL, 0, NULL}

/* Optional per-pixel outputs of loom_preview (width * height entries each,
   row 0 at the top = smallest y, pick 0; NULL = not wanted). */
typedef struct loom_preview_maps {
	float *height;          /* mean top of the surface voxel, z + 1 in
	                           voxels (absolute z), over the pixel's
	                           non-empty columns; 0 when all are empty */
	float *albedo;          /* 3 per pixel: mean yarn albedo of the pixel's
	                           columns (linear RGB; the background where
	                           empty) */
	uint8_t *kind;          /* 0 all empty, else 1 (warp) or 2 (weft),
	                           whichever tops more of the pixel's columns
	                           (warp on a tie) */
} loom_preview_maps;

/* One band of output rows, handed to a loom_preview_stream callback. */
typedef struct loom_preview_band {
	uint32_t row0, rows;    /* rows [row0, row0 + rows) of the picture */
	uint32_t width;
	const float *rgb;       /* rows * width * 3, linear RGB */
	const float *height;    /* rows * width, as loom_preview_maps.height */
	const float *albedo;    /* rows * width * 3 */
	const uint8_t *kind;    /* rows * width */
} loom_preview_band;

/* Called with the bands in order, from the thread that called
   loom_preview_stream; the arrays are valid during the call only.  A
   non-zero return stops the preview, which then returns that value. */
typedef int (*loom_preview_band_fn)(void *user, const loom_preview_band *band);

typedef struct loom_preview_stats {
	uint64_t pixels;        /* width * height */
	uint64_t columns;       /* voxel columns read through the texture */
	uint64_t region_reads;  /* loom_texture_read_region calls */
	uint64_t empty;         /* pixels with no surface in any column */
	double seconds;         /* wall time of the preview */
	int filter;             /* the filter used (EXACT or BLOCKS) */
	uint32_t blocks;        /* BLOCKS: source blocks tabulated */
	uint32_t texel;         /* BLOCKS: voxels per table texel side */
	size_t memory_bytes;    /* peak working memory of the preview */
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
 * Orthographic top view of the box of fabric f through its texture t,
 * streamed: the picture is made in bands of rows and each band is handed
 * to fn as soon as it is done, so memory does not grow with the picture.
 * Orientation: row 0 at the top is the smallest y (pick 0), column 0 the
 * smallest x (end 0), as a drawdown; so image down = +y.
 * Pixel (i, j) covers the voxel columns whose centres fall in it,
 *   x in [lo0 + ceil(i nx / W - 1/2), lo0 + ceil((i+1) nx / W - 1/2)),
 * the same along y; when that is empty (magnifying) the column under the
 * pixel's centre, lo0 + floor((i + 1/2) nx / W).  Its colour is the mean
 * of those columns' shaded colours (an area average: no aliasing at any
 * minification).  Per column, the top-most voxel with density at or above
 * the threshold is the surface: its height h = z + 1, fibre direction t
 * and yarn's albedo.  With L the light and H = normalize(L + (0,0,1)):
 *   n   = normalize(-dh/dx, -dh/dy, 1), central differences of the
 *         neighbouring columns' heights (empty ones count as lo2),
 *   rgb = albedo * (0.12 + 0.88 max(0, n.L) (0.3 + 0.7 sqrt(1-(t.L)^2)))
 *         * (0.45 + 0.55 (h - lo2) / (hi2 - lo2))
 *         + 0.25 (1 - alignment) sqrt(1-(t.H)^2)^24 max(0, n.L);
 * an empty column is the background.  opt->filter chooses how: EXACT reads
 * every column (ordered by source block within each band of rows, so the
 * texture's working set stays small); BLOCKS shades each source block the
 * fabric uses once, at its first crossing in the box (row-major), and
 * integrates those tables over each pixel's footprint, in the yarn colours
 * of each crossing it covers (exact but for the edge-fix offsets and
 * borders of that one crossing; a pixel covering more than 4 crossings
 * along an axis samples 4 evenly spaced ones).  Working memory (row
 * buffers, block tables, one band of output) stays under
 * opt->memory_bytes; LOOM_EBUDGET when it cannot (an EXACT preview needs
 * (voxel rows per pixel + 2) x (nx + 2) x 8 bytes at least).
 * Deterministic: the result depends on the inputs only, not on the thread
 * count.  stats may be NULL.
 * Returns LOOM_OK; errors of loom_preview_size; LOOM_EINVAL (NULL t, f or
 * fn, unknown filter, detached fabric); LOOM_EBUDGET; LOOM_ENOMEM; a
 * region read's error code (brick read failures; the message in diag); or
 * fn's non-zero return.
 */
LOOM_API int loom_preview_stream(loom_texture *t, const loom_fabric *f,
                                 const loom_preview_options *opt,
                                 loom_preview_band_fn fn, void *user,
                                 loom_preview_stats *stats, loom_diag *diag);

/*
 * loom_preview_stream into caller-allocated arrays: rgb (width * height *
 * 3 floats, linear RGB, row 0 at the top) and the non-NULL arrays of maps
 * (maps may be NULL).  Same pixels, errors and determinism.
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

/*
 * Majorant grid of a fabric (docs/rendering.md, "Majorant grid"): per
 * source block of the database and per z layer the largest density, built
 * by reading every block once (n_blocks * b3 bytes; never proportional to
 * the bolt).  Cells are about 4 x 4 voxels of a crossing (the divisors
 * of b1, b2 nearest 4, at most 8) by Z voxels (1, more when b3 > 64).  f is borrowed.  Returns LOOM_OK; LOOM_EINVAL (NULL,
 * detached fabric); read errors of loom_db_read_box; LOOM_ENOMEM.
 */
typedef struct loom_majorant loom_majorant;
LOOM_API int loom_majorant_build(const loom_fabric *f, loom_majorant **out,
                                 loom_diag *diag);
LOOM_API void loom_majorant_free(loom_majorant *m);
/* Bytes the grid takes, with `threads` render threads' caches. */
LOOM_API size_t loom_majorant_bytes(const loom_majorant *m, uint32_t threads);
/* What loom_majorant_bytes will say of f's grid, from the database's
   geometry alone (nothing read, nothing large allocated): to refuse a
   budget before building.  LOOM_OK; LOOM_EINVAL (NULL, detached fabric);
   LOOM_ENOMEM. */
LOOM_API int loom_majorant_size(const loom_fabric *f, uint32_t threads, size_t *bytes,
                                loom_diag *diag);
/* Cell size in voxels (x, y, z). */
LOOM_API void loom_majorant_cell_size(const loom_majorant *m, int64_t cell[3]);
/* Raw density bounds (0..255) of the cells of crossing (I, J) for lookups
   with `filter`, into out[(cy * nsx + cx) * nzc + z cell] (nsx, nsy: cells
   per crossing in x, y; nzc = ceil(b3 / Z); for tests and tools).  LOOM_OK,
   LOOM_EINVAL, LOOM_ENOMEM, or an error of the fabric's lookups. */
LOOM_API int loom_majorant_bound(loom_majorant *m, int filter, int64_t I,
                                 int64_t J, uint8_t *out);
/*
 * loom_texture_volume_source with the majorant grid m attached (cell,
 * cell_max): loom_render then tracks through the grid.  m must have been
 * built for f and must outlive the render; one texture per grid at a time.
 */
LOOM_API int loom_texture_volume_source_grid(loom_texture *t, const loom_fabric *f,
                                             int filter, loom_majorant *m,
                                             loom_volume_source *src);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_PREVIEW_H */
