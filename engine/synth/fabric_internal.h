/*
 * engine/synth/fabric_internal.h - the fabric as the virtual-texture engine sees
 * it.  Never installed.
 *
 * A fabric (engine/synth/fabric.c; file format io/store/fabric_*.c, docs/formats.md)
 * is immutable once made; everything below only reads it, so it may be
 * called from any number of threads at once.
 *
 * Lookup of output voxel (x, y, z) of the bolt, step by step (DESIGN.md,
 * "Lookup"); b1, b2, b3 = f->b1, f->b2, f->b3:
 *
 *   1. Crossing and local position: I = floor(y / b2), J = floor(x / b1),
 *      ly = y - I*b2, lx = x - J*b1.
 *   2. Source: t = loom__fabric_src(f, I, J) (base assignment of
 *      (I mod M, J mod N), shifted by its group's symmetry; O(1)), then
 *      blk = loom__fabric_blk(f, t): exemplar blk->exemplar, voxel origin
 *      (blk->x0, blk->y0) in that exemplar.
 *   3. Edge fix: loom__fabric_nbhd(f, I, J, &nb) and, once per output
 *      block (cache it), loom__fabric_dz_block(f, &nb, dz) (b1*b2 floats),
 *      or loom__fabric_dz_at(f, &nb, lx, ly) for one column.
 *   4. Source voxel: exemplar blk->exemplar at (blk->x0 + lx, blk->y0 + ly,
 *      z - dz[ly*b1 + lx]) (round as the engine documents; outside
 *      [0, b3) is empty).
 *   5. Yarn type: the voxel's label -> exemplar yarn table -> kind (warp or
 *      weft); loom__fabric_types(f, I, J, &warp, &weft) gives the type IDs,
 *      f->design->types[id] the optical data.
 *
 * loom__fabric_crossing() does steps 2, 3 (neighbourhood) and 5 (types) at
 * once.  All are O(1): two integer divisions per crossing coordinate, a
 * hash, and table reads; no allocation.
 *
 * Valid only when f->attached (bound to a database); a detached fabric
 * (LOOM_FABRIC_OPEN_DETACHED) has base, design and metrics but no lookup.
 */
#ifndef LOOM_FABRIC_INTERNAL_H
#define LOOM_FABRIC_INTERNAL_H

#include "core/internal.h"

/*
 * The edge fix's targets (engine/synth/edgefix.c, "Calibration"; the
 * render majorant reads them too).  A block's N (j = 0) and W (j = 2)
 * data is the other side of the seam it had in its woven exemplar, so the
 * fix keeps that seam's jump instead of closing it.  A block on its
 * exemplar's top row (left column) has no such seam; it borrows the one
 * of its donor: its nearest image under the exemplar's translational
 * symmetries that has a block above (left of) it, i.e. the same
 * neighbourhood woven one repeat further in.
 *
 * loom__edgefix_donor: t itself when t has a block above (j = 0) or left
 * of (j = 2) it in its exemplar; else the donor; LOOM_SYNTH_NONE when no
 * image has one (an exemplar without symmetries: the seam is closed).
 * loom__edgefix_target: profile j of block t as the fix matches it (b1
 * floats for N/S, b2 for W/E) into out: S and E t's own; N (W) the S (E)
 * profile of the block above (left of) t, or t's own N (W) plus the
 * donor's woven jump (the S (E) profile above (left of) the donor minus
 * the donor's N (W)), or t's own without a set or a donor.
 */
uint32_t loom__edgefix_donor(const loom_synth_set *s, uint32_t t, int j);
void loom__edgefix_target(const loom_edge_profiles *p, uint32_t t, int j, float *out);

/* The edge-fix coefficient vectors of a crossing whose sources are nb,
   from the tables' per-block coefficients coef (2 rh + 2 rv floats a
   block: cN cS cW cE), as the edge fix combines them (half the
   difference of the two sides' profile coefficients on each edge): a[0,
   rh) N, a[rh, 2 rh) S, a[2 rh, 2 rh + rv) W, then E.  The texture's
   crossing entries and the render majorant read them. */
static inline void loom__edgefix_combine(const float *coef, uint32_t rh, uint32_t rv,
                                         const loom_synth_nbhd *nb, float *a)
{
	uint32_t st = 2 * rh + 2 * rv;
	const float *cs = coef + (size_t)nb->self * st;
	const float *cn = coef + (size_t)nb->n * st;
	const float *css = coef + (size_t)nb->s * st;
	const float *cw = coef + (size_t)nb->w * st;
	const float *ce = coef + (size_t)nb->e * st;
	float *an = a, *as = a + rh, *aw = a + 2 * rh, *ae = a + 2 * rh + rv;

	for (uint32_t k = 0; k < rh; k++) {
		an[k] = 0.5f * (cn[rh + k] - cs[k]);
		as[k] = 0.5f * (css[k] - cs[rh + k]);
	}
	for (uint32_t k = 0; k < rv; k++) {
		aw[k] = 0.5f * (cw[2 * rh + rv + k] - cs[2 * rh + k]);
		ae[k] = 0.5f * (ce[2 * rh + k] - cs[2 * rh + rv + k]);
	}
}

/* Bytes the fabric holds in memory: the design (3 per crossing), the base
   assignment (2 per crossing), the edge-fix tables and the per-block tables
   (not the database or the synthesis set, which hold no per-crossing data).
   The texture counts them against its budget (loom_texture_open). */
size_t loom__fabric_bytes(const loom_fabric *f);

/* A painted weave (loom__fabric_reweave): crossings [I0, I0+rows) x
   [J0, J0+cols) of the bolt, of which those with src != LOOM_SYNTH_NONE
   copy block src instead of the fabric's source and have warp-over bit
   weave.  Patches chain: prev is applied first (a later one wins). */
typedef struct loom__fabric_patch {
	const struct loom__fabric_patch *prev;
	int64_t I0, J0;
	uint32_t rows, cols;
	uint16_t *src;          /* rows*cols */
	uint8_t *weave;         /* rows*cols, 0 or 1 */
} loom__fabric_patch;

/* Most crossings one patch may span (rows * cols): 3 bytes each. */
#define LOOM__FABRIC_PATCH_MAX (1u << 22)

/* Per source block t: where its voxels are. */
typedef struct loom__fabric_block {
	uint16_t exemplar;     /* u */
	uint16_t row, col;     /* block (row, col) of S_u */
	uint8_t code;          /* neighbourhood code in S_u (LOOM_SYNTH_CODE_*) */
	uint8_t pad_;
	uint32_t x0, y0;       /* voxel origin in exemplar u: col*b1, row*b2 */
} loom__fabric_block;

struct loom_fabric {
	/* ---- design ---- */
	loom_design *design;   /* owned; rows x cols repeat */

	/* ---- database identity (as recorded) ---- */
	char *db_path;         /* as given at synthesis; owned, never NULL */
	uint64_t db_hash;      /* content hash */
	uint32_t b1, b2, b3;   /* block size, voxels */
	float voxel_size_um;
	uint32_t n_exemplars;
	uint32_t n_blocks;     /* K */

	/* ---- parameters ---- */
	loom_fabric_params params;

	/* ---- synthesis results ---- */
	uint16_t *base;        /* rows*cols source blocks (< K), owned */
	loom_edgefix *ef;      /* edge-fix tables; NULL only when detached and
	                          the file did not store them */

	/* ---- metrics ---- */
	loom_synth_metrics m_repeat;
	loom_synth_metrics m_bolt;
	loom_seam_metrics seam;
	uint64_t win_rows, win_cols; /* bolt metrics window [0,h) x [0,w) */
	uint64_t *usage;       /* n_exemplars counters, owned */

	/* ---- binding to a database (attached only) ---- */
	int attached;          /* 1: everything below is valid */
	const loom_db *db;     /* the database in use (borrowed or db_owned) */
	loom_db *db_owned;     /* opened by loom_fabric_open, closed at free */
	loom_synth_set *set;   /* rebuilt from the database's exemplar weaves */
	loom__fabric_block *blocks; /* K entries */
	float *heights;        /* K edge-profile records (LOOM_EDGE_RECORD) */
	loom_edge_profiles prof; /* points at heights */
	float *corner_off;     /* K x 4 (NW, NE, SW, SE): the woven offset of
	                          block t's corner column from the mean of the
	                          four corner columns meeting there in its own
	                          exemplar (0 on the exemplar's border); NULL:
	                          no corner term (loom__fabric_corner_dz) */
	double internal_step;  /* mean |dh| between neighbouring columns inside
	                          blocks (the database's, for the seam metric) */
	loom_synth_lookup lk;  /* randomised O(1) source lookup; points into
	                          set and base */

	/* ---- painted weaves (a fabric made by loom__fabric_reweave) ---- */
	const loom__fabric_patch *patch; /* newest first; NULL: none */
	loom_fabric *parent;   /* owned: the fabric this one shares everything
	                          above with (its struct was copied) */
};

/* The patch entry of (I, J), newest patch first: *k its index; NULL when
   no patch covers (I, J). */
static inline const loom__fabric_patch *
loom__fabric_patch_at(const loom_fabric *f, int64_t I, int64_t J, size_t *k)
{
	for (const loom__fabric_patch *p = f->patch; p; p = p->prev) {
		uint64_t di = (uint64_t)I - (uint64_t)p->I0;
		uint64_t dj = (uint64_t)J - (uint64_t)p->J0;
		if (di < p->rows && dj < p->cols &&
		    p->src[di * p->cols + dj] != LOOM_SYNTH_NONE) {
			*k = (size_t)(di * p->cols + dj);
			return p;
		}
	}
	return NULL;
}

/* Step 2: source block of absolute crossing (I, J). */
static inline uint16_t loom__fabric_src(const loom_fabric *f, int64_t I,
                                        int64_t J)
{
	if (f->patch) {
		size_t k;
		const loom__fabric_patch *p = loom__fabric_patch_at(f, I, J, &k);
		if (p)
			return p->src[k];
	}
	return loom_synth_src(&f->lk, I, J);
}

/* Step 2: where source block t (< K) lies. */
static inline const loom__fabric_block *loom__fabric_blk(const loom_fabric *f,
                                                         uint16_t t)
{
	return &f->blocks[t];
}

/* Index of (I, J) in the repeat's arrays (weave, type maps, base). */
static inline size_t loom__fabric_cell(const loom_fabric *f, int64_t I,
                                       int64_t J)
{
	return (size_t)loom_synth_floormod(I, f->design->rows) * f->design->cols +
	       (size_t)loom_synth_floormod(J, f->design->cols);
}

/* Step 5: yarn-type IDs of the warp and the weft at (I, J). */
static inline void loom__fabric_types(const loom_fabric *f, int64_t I,
                                      int64_t J, uint8_t *warp, uint8_t *weft)
{
	size_t c = loom__fabric_cell(f, I, J);
	*warp = f->design->warp_type[c];
	*weft = f->design->weft_type[c];
}

/* Step 3: sources of (I, J) and its four neighbours. */
static inline void loom__fabric_nbhd(const loom_fabric *f, int64_t I,
                                     int64_t J, loom_synth_nbhd *nb)
{
	if (!f->patch) {
		loom_synth_nbhd_at(&f->lk, I, J, nb);
		return;
	}
	nb->self = loom__fabric_src(f, I, J);
	nb->n = loom__fabric_src(f, I - 1, J);
	nb->s = loom__fabric_src(f, I + 1, J);
	nb->w = loom__fabric_src(f, I, J - 1);
	nb->e = loom__fabric_src(f, I, J + 1);
}

/* Step 3: the block's dz map, dz[ly*b1 + lx] (b1*b2 floats), and one
   value of it. */
static inline void loom__fabric_dz_block(const loom_fabric *f,
                                         const loom_synth_nbhd *nb, float *dz)
{
	loom_edgefix_block(f->ef, nb, dz);
}
static inline float loom__fabric_dz_at(const loom_fabric *f,
                                       const loom_synth_nbhd *nb, uint32_t lx,
                                       uint32_t ly)
{
	return loom_edgefix_at(f->ef, nb, lx, ly);
}

/* Step 3 at a block corner: the corner term (docs/synthesis.md, "Block
   corners") replaces the offset of the four corner columns.  The index
   (0 NW, 1 NE, 2 SW, 3 SE) of column (lx, ly), or -1 when it is not a
   corner or the fabric has no corner term. */
static inline int loom__fabric_corner_of(const loom_fabric *f, uint32_t lx,
                                         uint32_t ly)
{
	if (!f->corner_off || (lx != 0 && lx != f->b1 - 1) ||
	    (ly != 0 && ly != f->b2 - 1))
		return -1;
	return (ly ? 2 : 0) + (lx ? 1 : 0);
}
/* Column of corner k (0 NW, 1 NE, 2 SW, 3 SE) in a block. */
static inline uint32_t loom__fabric_corner_x(const loom_fabric *f, int k)
{
	return (k & 1) ? f->b1 - 1 : 0;
}
static inline uint32_t loom__fabric_corner_y(const loom_fabric *f, int k)
{
	return (k & 2) ? f->b2 - 1 : 0;
}
/* The offset of corner k of crossing (I, J) with the corner term (f has
   corner_off). */
float loom__fabric_corner_dz(const loom_fabric *f, int64_t I, int64_t J, int k);

/* Everything about one crossing at once. */
typedef struct loom__fabric_xing {
	const loom__fabric_block *blk; /* source block of (I, J) */
	loom_synth_nbhd nb;            /* nb.self = its index t */
	uint8_t warp_over;             /* W(I mod M, J mod N) */
	uint8_t warp_type, weft_type;
} loom__fabric_xing;

static inline void loom__fabric_crossing(const loom_fabric *f, int64_t I,
                                         int64_t J, loom__fabric_xing *x)
{
	size_t c = loom__fabric_cell(f, I, J), k;
	const loom__fabric_patch *p;
	loom__fabric_nbhd(f, I, J, &x->nb);
	x->blk = &f->blocks[x->nb.self];
	x->warp_over = f->design->weave[c];
	if (f->patch && (p = loom__fabric_patch_at(f, I, J, &k)) != NULL)
		x->warp_over = p->weave[k];
	x->warp_type = f->design->warp_type[c];
	x->weft_type = f->design->weft_type[c];
}

/* ---- between engine/synth/fabric.c and io/store (the .loomf file) ------- */

/* Largest EDGE section (bytes) the format allows; larger tables are never
   stored (rebuilt at open instead). */
#define LOOM__FABRIC_EDGE_MAX (256ull << 20)

/* A zeroed fabric with db_path "" (NULL when out of memory). */
loom_fabric *loom__fabric_alloc(void);

/* Bind a (detached) fabric to db: check the content hash (unless
   check_hash is 0: fuzzing) and the geometry, rebuild the exemplar set,
   block table, profiles and lookup, and the edge-fix tables if the file did
   not store them.  `name` names the fabric in messages. */
/* Material pair tags of the database's exemplars (engine/synth/material.c):
   tag[u] = warp * LOOM_FIBRE_COUNT_ + weft (0: not recorded), *n_pairs =
   distinct tags other than 0. */
int loom__fabric_db_pairs(const loom_db *db, uint32_t n_ex, uint8_t *tag,
                          uint32_t *n_pairs);
/* With a database of two or more tagged pairs: f->base from one
   assignment per pair the design uses (each crossing restricted to its
   pair's exemplars), *done = 1; otherwise nothing, *done = 0.  f->design,
   f->set, f->n_exemplars set.  LOOM_EMISMATCH for a pair the database
   lacks. */
/* "warp/weft, ..." of the pairs the tags hold (first seen first). */
void loom__fabric_pair_list(const uint8_t *tag, uint32_t n_ex, char *buf, size_t n);

int loom__fabric_assign_materials(loom_fabric *f, const loom_db *db,
                                  const loom_synth_options *so,
                                  const uint8_t def[2], int *done,
                                  loom_diag *diag);

int loom__fabric_bind(loom_fabric *f, const loom_db *db, int check_hash,
                      const char *name, loom_diag *diag);

/*
 * Paint another weave into the fabric *fp (engine/synth/reweave.c,
 * docs/fabric.md "Painted weaves"): want[r*cols + c] for crossing
 * (I0 + r, J0 + c) is 0 (not painted), 1 (painted, weft over) or 2
 * (painted, warp over).  The painted crossings and every crossing within
 * `band` (0..LOOM__FABRIC_BAND_MAX, Chebyshev distance) of them are
 * assigned again, in raster order: the blocks of maximal consistency with
 * the new weave bits around them (loom_synth_candidates), among them the
 * most contiguous with the neighbours already fixed (the fabric's outside,
 * the patch's earlier rows and columns), ties by a hash of (seed, I, J, t).
 * With a database of several material pairs the candidates are the blocks
 * of the exemplars with the pair of the crossing's old source, most
 * matching neighbour bits first (engine/synth/material.c).
 * A painted fibre (fibre != 0, enum loom_fibre): the painted crossings'
 * pairs take `fibre` on the side of `kind` (0 any: both sides), and they
 * copy blocks of their new pair (pass want = 1 + the current bits to keep
 * the weave); LOOM_EMISMATCH, naming the pair and the database's pairs,
 * when the database has no exemplar of a new pair.
 * On success *fp becomes a new fabric that owns the old one and shares its
 * tables; the edge fix then runs across the patch's border as anywhere.
 * Memory 3 bytes per crossing of the widened rectangle (at most
 * LOOM__FABRIC_PATCH_MAX: LOOM_ERANGE).  LOOM_EINVAL, LOOM_EUNUSABLE
 * (detached), LOOM_ENOMEM; *fp unchanged on failure.
 */
#define LOOM__FABRIC_BAND_MAX 8u
int loom__fabric_reweave(loom_fabric **fp, int64_t I0, int64_t J0,
                         uint32_t rows, uint32_t cols, const uint8_t *want,
                         uint32_t band, int kind, int fibre, loom_diag *diag);

#endif /* LOOM_FABRIC_INTERNAL_H */
