/*
 * engine/exemplar/exgen.h - procedural CT-like exemplars (docs/exemplars.md).
 * Internal.
 *
 * A model (loom__exgen) describes one exemplar: a window of rows x cols
 * crossings cut from an endless woven sheet with closed-form yarn centre
 * curves.  Any box of voxels can be evaluated independently, in any order
 * and on any thread, and always gives the same bytes: the database writer
 * evaluates brick columns in parallel; tests evaluate whole volumes.
 */
#ifndef LOOM_EXGEN_H
#define LOOM_EXGEN_H

#include "core/internal.h"
#include "loom/db.h"

typedef struct loom__exgen loom__exgen;

/* What the database records about a generated exemplar. */
typedef struct loom__exgen_desc {
	const char *name;          /* "twill-2-3" (variant suffix "-2", ...) */
	const char *weave_name;    /* "twill:2/3" */
	uint32_t rows, cols;
	const uint8_t *weave;      /* rows*cols, 1 = warp over */
	uint32_t size[3];          /* voxels */
	uint32_t n_yarns;
	const loom_db_yarn *yarns; /* n_yarns + 1 rows */
	uint8_t fibre[2];          /* material pair tag (0 0: none) */
} loom__exgen_desc;

/* Check the parameters that do not depend on a weave. */
int loom__exgen_check(const loom_exgen_params *p, loom_diag *diag);

/*
 * Model of exemplar k of p (weave p->weaves[k]).  `variant` counts earlier
 * exemplars with the same weave (0 for the first): it changes the seed and
 * the name suffix.  LOOM_EINVAL (message names the weave), LOOM_ENOMEM.
 */
int loom__exgen_new(const loom_exgen_params *p, uint32_t k, uint32_t variant,
                    loom__exgen **out, loom_diag *diag);
/*
 * Model of a whole design as one exemplar (the woven ground truth,
 * docs/fidelity.md): weave = rows x cols cells (1 = warp over), used as
 * given (no offset), periodic with the window as every exemplar.  The seed
 * is keyed on `name`.  At most LOOM_EXGEN_MAX_DESIGN crossings a side and
 * LOOM__DB_MAX_EXTENT voxels along x and y (LOOM_ERANGE, message with the
 * limit).
 */
int loom__exgen_new_design(const loom_exgen_params *p, const char *name,
                           uint32_t rows, uint32_t cols, const uint8_t *weave,
                           loom__exgen **out, loom_diag *diag);
/* Tag the exemplar with material pair (warp, weft), enum loom_fibre codes,
   and append "@WW-FF" (loom_fibre_short) to its name: the exemplars of a
   database of several pairs (docs/exemplars.md).  The voxels do not
   change. */
void loom__exgen_tag(loom__exgen *g, int warp, int weft);
void loom__exgen_free(loom__exgen *g);
void loom__exgen_describe(const loom__exgen *g, loom__exgen_desc *d);

/*
 * Evaluate the box [x0, x0+nx) x [y0, y0+ny) x [z0, z0+nz) (voxels; parts
 * outside the exemplar are empty).  Output index ((y-y0)*nx + (x-x0))*nz +
 * (z-z0): z fastest, as in a brick.  Thread-safe.  LOOM_OK, or
 * LOOM_ENOMEM (fibre-level yarns: a few hundred KB of fibre lines).
 */
int loom__exgen_box(const loom__exgen *g, int64_t x0, int64_t y0, int64_t z0,
                    uint32_t nx, uint32_t ny, uint32_t nz, uint8_t *density,
                    uint16_t *orientation, uint8_t *label);

/* Fibre-level yarns of a kind (1 warp, 2 weft) as the model uses them;
   all zero for smooth yarns. */
typedef struct loom__exgen_fibre {
	uint32_t plies, per_ply;   /* per_ply: fibres aimed for in each ply */
	float fibre_deg, ply_deg;  /* helix angles seen on the yarn's top */
	float hair_per_mm, loop_per_mm;
	uint32_t placed;           /* fibres placed in yarn 0 of the kind */
} loom__exgen_fibre;
void loom__exgen_fibres(const loom__exgen *g, int kind, loom__exgen_fibre *f);

/* Nominal mid-plane of the cloth, in voxels (for tests). */
float loom__exgen_mid_z(const loom__exgen *g);

/* Yarn index (-1 .. cols or rows) of a kind (1 warp, 2 weft) at voxel t
   along it: out = lateral centre and height (voxel indices), half-width
   and half-height (voxels) of its cross-section (for tests). */
void loom__exgen_section(const loom__exgen *g, int kind, int index, float t,
                         float out[4]);

#endif /* LOOM_EXGEN_H */
