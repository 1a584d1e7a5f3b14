/*
 * loom/paint.h - painted regions of a fabric (engine/texture/paint.c,
 * docs/fabric.md "Painted regions", docs/formats.md "Paint file"):
 * rectangles or masks in cloth millimetres that recolour a yarn kind, stain
 * the cloth, weave another weave, or add a defect (slub, broken end, missing pick, pulled
 * thread), evaluated at lookup time over a fabric's texture.  Include
 * <loom.h>, not this file.
 */
#ifndef LOOM_PAINT_H
#define LOOM_PAINT_H

#include "common.h"
#include "render.h"
#include "texture.h"

#ifdef __cplusplus
extern "C" {
#endif

enum loom_paint_effect {
	LOOM_PAINT_YARN = 1,         /* yarns of `kind` take colour rgb */
	LOOM_PAINT_STAIN = 2,        /* albedo times lerp(1, rgb, strength) */
	LOOM_PAINT_SLUB = 3,         /* yarns of `kind` thicker by `amount` voxels */
	LOOM_PAINT_BROKEN_END = 4,   /* warp voxels removed */
	LOOM_PAINT_MISSING_PICK = 5, /* weft voxels removed */
	LOOM_PAINT_PULL = 6,         /* yarns of `kind` lifted `amount` voxels */
	LOOM_PAINT_WEAVE = 7,        /* another weave: crossings re-synthesised */
	LOOM_PAINT_FIBRE = 8         /* yarns of `kind` of material `fibre`:
	                                crossings re-synthesised from the
	                                exemplars of their new material pair */
};

#define LOOM_PAINT_MAX_REGIONS 4096u
#define LOOM_PAINT_MAX_MASK 4096u    /* mask width and height limit */
#define LOOM_PAINT_MAX_FILE (16u << 20) /* paint file size limit, bytes */
#define LOOM_PAINT_MAX_BAND 8u       /* weave: border band limit, crossings */

typedef struct loom_paint_region {
	int effect;             /* enum loom_paint_effect */
	double x0, y0, x1, y1;  /* cloth mm: x across (ends), y along the
	                           warps; x0 < x1, y0 < y1 */
	uint32_t mask_w, mask_h;/* 0: the whole rectangle; else a mask of
	                           mask_w x mask_h cells over it, row 0 at y0 */
	const uint8_t *mask;    /* mask_w * mask_h bytes, 0 or 1 (owned by the
	                           paint; copied by loom_paint_add) */
	int kind;               /* 0 any, LOOM_YARN_WARP, LOOM_YARN_WEFT */
	float rgb[3];           /* yarn colour / stain tint, linear 0..1 */
	float strength;         /* stain strength 0..1 */
	double blend_mm;        /* colour effects: soft edge outside the region */
	uint32_t amount;        /* slub radius 1..16, pull lift 1..64 voxels */
	/* LOOM_PAINT_WEAVE only: the weave's repeat, weave_w ends x weave_h
	   picks (1..LOOM_PAINT_MAX_MASK each), weave[i*weave_w + j] = 1 where
	   the warp is over at pick i, end j; tiled from crossing (0, 0) of
	   the bolt (copied by loom_paint_add) */
	uint32_t weave_w, weave_h;
	const uint8_t *weave;
	uint32_t band;          /* weave and fibre: crossings re-synthesised
	                           around the painted ones, 0..LOOM_PAINT_MAX_BAND */
	int fibre;              /* LOOM_PAINT_FIBRE only: the material, enum
	                           loom_fibre (not LOOM_FIBRE_DEFAULT) */
} loom_paint_region;

typedef struct loom_paint loom_paint;

/* A new empty paint layer over the fabric file `fabric` (a path, copied). */
LOOM_API int loom_paint_new(const char *fabric, loom_paint **out, loom_diag *diag);
LOOM_API void loom_paint_free(loom_paint *p);
/* Check and append a region (its mask copied).  LOOM_EINVAL with the
   reason; LOOM_ERANGE past LOOM_PAINT_MAX_REGIONS. */
LOOM_API int loom_paint_add(loom_paint *p, const loom_paint_region *r, loom_diag *diag);
LOOM_API uint32_t loom_paint_count(const loom_paint *p);
LOOM_API const loom_paint_region *loom_paint_get(const loom_paint *p, uint32_t i);
LOOM_API const char *loom_paint_fabric(const loom_paint *p);

/* Parse paint-file text (len bytes; name for "name:line:" messages):
   LOOM_EFORMAT naming the line, LOOM_ERANGE, LOOM_ENOMEM. */
LOOM_API int loom_paint_parse(const char *text, size_t len, const char *name,
                              loom_paint **out, loom_diag *diag);
/* The paint file's text (malloc'ed, NUL-terminated; *len its length). */
LOOM_API int loom_paint_format(const loom_paint *p, char **text, size_t *len);
/* Effect names as in the file: "yarn", "stain", "slub", "broken-end",
   "missing-pick", "pull", "weave", "fibre"; NULL for others. */
LOOM_API const char *loom_paint_effect_name(int effect);
LOOM_API int loom_paint_effect_parse(const char *name);

/*
 * The fabric with the painted weaves applied (LOOM_PAINT_WEAVE and
 * LOOM_PAINT_FIBRE regions, in file order; docs/fabric.md "Painted
 * weaves", "Painted fibres"): the crossings whose
 * centre a weave region contains take its weave (a fibre region: their
 * yarns of its kind take its material), and they and `band`
 * crossings around them are assigned exemplar blocks again with the
 * synthesis rules; the edge fix then runs across the border.  On success
 * *f is replaced by a fabric that owns the old one (free only the new
 * one; it cannot be saved as a fabric file); with no weave region *f is
 * kept.  Open the texture on the result.  Memory 3 bytes per crossing of
 * each region's rectangle widened by its band.  LOOM_EINVAL, LOOM_ERANGE
 * (a region over more than 4194304 crossings), LOOM_EUNUSABLE (detached),
 * LOOM_ENOMEM, LOOM_EMISMATCH (a fibre region needing a material pair the
 * database has no exemplars of); *f unchanged on failure.
 */
LOOM_API int loom_paint_apply_weaves(const loom_paint *p, loom_fabric **f,
                                     loom_diag *diag);

/*
 * A volume source over texture t (of fabric f) with the paint applied at
 * lookup time: first the structural effects (slub, broken end, missing
 * pick, pull; inside their regions only, seeing the unpainted cloth),
 * then the colour effects (yarn, stain; inside and, fading linearly, up
 * to blend_mm outside).  A voxel column belongs to a region when its
 * centre does.  p must outlive the source and is bound to t (one binding
 * at a time).  LOOM_EINVAL for NULL or a bad filter.
 */
LOOM_API int loom_paint_volume_source(loom_paint *p, loom_texture *t,
                                      const loom_fabric *f, int filter,
                                      loom_volume_source *src);
/* One lookup of that source as a texel (kind and type kept; type 0 and
   kind 0 where a defect emptied the voxel).  Thread-safe like
   loom_texture_sample. */
LOOM_API int loom_paint_sample(const loom_paint *p, const double pos[3],
                               loom_texel *out);

/*
 * The bulk reads (docs/fabric.md "Painted regions in bulk reads"): what
 * loom_preview, loom export and loom serve read a box at a time, with the
 * paint applied voxel for voxel as loom_paint_sample applies it with the
 * nearest filter.  Bind first (loom_paint_volume_source binds too; one
 * binding at a time: the last one counts).  Memory per call O(regions +
 * voxel columns of 33 columns' height), never O(box) beyond the output.
 */
/* Bind p to texture t of fabric f (the regions in voxels, the nearest
   filter for loom_paint_sample).  LOOM_EINVAL, LOOM_ENOMEM. */
LOOM_API int loom_paint_bind(loom_paint *p, loom_texture *t, const loom_fabric *f);

#define LOOM_PAINT_TOUCH_SHAPE 1u  /* a slub, broken end, missing pick or pull */
#define LOOM_PAINT_TOUCH_COLOUR 2u /* a yarn colour or stain (with its blend) */
/* Which effects reach the voxel columns [lo[0], hi[0]) x [lo[1], hi[1])
   of a bound paint (a column is reached when its centre lies in the
   region, or for colours within its blend band; bounds test, so a
   masked region may be reported where its mask is empty): OR of
   LOOM_PAINT_TOUCH_*, 0 when none (or p NULL, unbound). */
LOOM_API unsigned loom_paint_touches(const loom_paint *p, const int64_t lo[2],
                                     const int64_t hi[2]);
/* loom_texture_read_region of the bound texture with the structural
   effects (slub, broken end, missing pick, pull) applied: every channel
   equal to loom_paint_sample's texel at the voxel centre (nearest filter)
   in its raw encoding.  Returns as loom_texture_read_region, LOOM_ENOMEM.
   Thread-safe. */
LOOM_API int loom_paint_read_region(const loom_paint *p, const int64_t lo[3],
                                    const int64_t hi[3],
                                    const loom_texture_region *out);
/* The colour effects (yarn colour, stain) on `albedo`, the yarn-type
   albedo of a voxel of `kind` (1 warp, 2 weft; 0: unchanged) in column
   (x, y): as loom_paint_sample colours it.  Thread-safe. */
LOOM_API void loom_paint_albedo(const loom_paint *p, int64_t x, int64_t y, int kind,
                                float albedo[3]);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_PAINT_H */
