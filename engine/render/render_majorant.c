/*
 * engine/render/render_majorant.c - the majorant grid of a fabric's virtual
 * texture (docs/rendering.md, "Majorant grid"): an upper bound of the
 * density over every cell of sx x sy voxels (at most 4 x 4, tiling a
 * crossing of b1 x b2) by Z voxels of height, so the tracer takes long free
 * flights through empty space and short ones only where the fibres are
 * (with whole-crossing cells three quarters of the tentative collisions on
 * the cotton database fell between fibres).
 *
 * Built once from the database: per source block (every block of every
 * exemplar), per cell column of the block and per z layer, the largest
 * raw density of the column's voxels in that layer: n_blocks * nsub * b3
 * bytes, O(source blocks), never proportional to the bolt or the design.
 *
 * Per crossing (I, J) of the bolt, at render time: the crossing's source
 * block (loom_fabric_source_at, randomisation included) and a range
 * [dz_lo, dz_hi] holding its edge-fix offsets.  The offset map is a sum
 * of basis solutions of the screened discrete Laplace equation
 * (docs/synthesis.md), so its positive maximum and negative minimum lie
 * on the block's border (maximum principle) and the interior between 0
 * and the border's values: only the 2 (b1 + b2) - 4 border columns are
 * evaluated, not the b1 b2 of the map (at full rank from the edge data,
 * side_profiles, not the tables), and the range is widened to hold 0
 * (the corner term replaces the four corner columns, which no interior
 * value depends on: their values, loom_fabric_corner_dz, widen the
 * range); a margin covers
 * float rounding, and the texture's rounding to 1/16 voxel blends source voxels
 * z - ceil(q/16) and z - floor(q/16) (q = round(16 dz)), both inside
 * [z - ceil(dz_hi), z - floor(dz_lo)], with weights summing to 1;
 * output layer z reads source layer z - dz, so its bound is the largest
 * layer maximum over source z in [z - dz_hi, z - dz_lo].  A trilinear
 * lookup blends the 8 voxels around the point, which may lie in the
 * neighbouring cells, crossings and layers: its bound is the maximum over
 * every cell of the 3 x 3 crossings and one more layer on each side.  Per
 * render thread a small direct-mapped cache of crossings (fixed size)
 * keeps each crossing's source block and offset range, so its edge-fix
 * offsets are computed once per thread while it stays cached; a nearest
 * cell's bound is then the largest of its column's few source layers.
 * Every value depends only on the fabric, never on the thread or the
 * order, so images stay identical for any thread count.
 */
#include "render_internal.h"
#include "loom/preview.h"
#include "synth/fabric_internal.h"
#include "texture/texture_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CACHE_ENTRIES 1024u /* crossings cached per render thread */
#define MAX_ZCELLS 64u     /* z cells per crossing (Z grows to fit) */
#define CELL_XY 4u         /* target cell size in x and y (voxels) */
#define EXACT_ENTRIES 256u /* crossings with exact cell columns per thread */

/* The divisor of b nearest CELL_XY, at most 2 CELL_XY, the smaller on a
   tie (cells tile a crossing).  The largest divisor at most CELL_XY gave
   1 for the paper's b1 = 115 (5 x 23) and 2 for b2 = 70: 4025 cells a
   block, a 0.5 GB grid at the paper's scale; 5 x 5 gives 322. */
static uint32_t cell_side(uint32_t b)
{
	uint32_t best = 1;
	for (uint32_t s = 1; s <= 2 * CELL_XY && s <= b; s++)
		if (b % s == 0 && (s > CELL_XY ? s - CELL_XY : CELL_XY - s) <
		                          (best > CELL_XY ? best - CELL_XY : CELL_XY - best))
			best = s;
	return best;
}

struct loom_majorant {
	const loom_fabric *f;
	loom_texture *t;          /* set by loom_texture_volume_source_grid */
	int filter;
	uint32_t b1, b2, b3, zcell, nzc;
	uint32_t sx, sy;          /* cell size in x, y (divides b1, b2) */
	uint32_t nsx, nsy, nsub;  /* cells per crossing in x, y; nsub = nsx nsy */
	uint32_t n_exemplars;
	uint32_t *off;            /* first block of each exemplar */
	uint32_t *bcols;          /* block columns of each exemplar */
	uint64_t n_blocks;
	uint8_t *layer;           /* n_blocks * nsub * b3: largest raw density
	                             of each block's cell column per layer */
	uint32_t *span;           /* n_blocks * nsub * 2: first and last
	                             non-zero layer of each cell column (1, 0:
	                             none) */
	loom_edgefix_tables ef;   /* the fabric's edge fix (ef.coef NULL:
	                             none) */
	float *frange;            /* min, max of each field: 2 rh, then 2 rv */
	loom_edge_profiles tp;    /* full rank (tp.heights not NULL): the
	                             fabric's edge profiles, whose targets
	                             (target) the fix matches (border_range) */
	uint32_t *dslot;          /* with tp: 2 per block (N, W), where the
	                             block's target starts in dbuf, or
	                             UINT32_MAX (read in place: target) */
	float *dbuf;              /* the targets of blocks that borrow a
	                             donor's seam (loom__edgefix_target) */
	size_t dfloats;           /* floats in dbuf */
};

static int border_init(loom_majorant *m, const loom_fabric *f, loom_diag *diag);

typedef struct mj_entry {
	int64_t I, J;
	int valid;
	const uint8_t *blk;       /* the source block's nsub * b3 cell layers */
	int64_t dlo, dhi;         /* range of the crossing's edge-fix offsets */
	uint8_t tri[MAX_ZCELLS];  /* trilinear: bound of each z cell */
	uint32_t xslot;           /* exact: the crossing's record (x_rec) */
	int64_t zlo, zhi;         /* nearest: z cells outside which every cell
	                             of the crossing is empty (mj_cell_zbox) */
} mj_entry;

/* Exact cell columns of one crossing (see x_fill). */
typedef struct mj_exact {
	int64_t I, J;
	int valid;
	uint32_t pad;
	/* then: uint64_t zmask[nsub]; uint8_t filled[nsub]; uint8_t cmax[nsub * nzc] */
} mj_exact;

typedef struct mj_thread {
	loom_majorant *m;
	int exact;                /* exact cell columns (x_ok) */
	float a[4 * LOOM_EDGEFIX_MAX_RANK]; /* a crossing's coefficients */
	mj_entry *last;           /* the entry of the last query */
	int64_t cx0, cy0;         /* its crossing's first cell in x, y */
	uint8_t *xpool;           /* exact: EXACT_ENTRIES records of x_bytes */
	uint8_t *scratch;         /* exact: a cell column's density bytes */
	const uint8_t *lcmax;     /* exact: the filled cell column (lc0, lc1)
	                             last queried, its nzc maxima (NULL: none);
	                             a DDA visits 2-4 z cells of a column in a
	                             row, each then a byte read */
	int64_t lc0, lc1;
	mj_entry cache[CACHE_ENTRIES];
} mj_thread;

/* Each cell column's first and last non-zero source layer, so a tracker
   can pass the empty layers above and below the cloth without a bound
   query per cell (mj_cell_zspan). */
static int fill_spans(loom_majorant *m)
{
	uint64_t n = m->n_blocks * m->nsub;

	if (!(m->span = malloc((2u * n + 1u) * sizeof *m->span)))
		return LOOM_ENOMEM;
	for (uint64_t k = 0; k < n; k++) {
		const uint8_t *col = m->layer + k * m->b3;
		uint32_t lo = 0, hi = m->b3;
		while (lo < m->b3 && !col[lo])
			lo++;
		while (hi > lo && !col[hi - 1])
			hi--;
		m->span[2 * k] = lo < m->b3 ? lo : 1;
		m->span[2 * k + 1] = lo < m->b3 ? hi - 1 : 0;
	}
	return LOOM_OK;
}

/* The grid's header: cell geometry, block offsets and edge-fix ranges,
   everything but the layer bounds (so its size is known before they are
   read: loom_majorant_size). */
static int mj_geometry(const loom_fabric *f, loom_majorant **out, loom_diag *diag)
{
	const loom_db *db;
	loom_db_info info;
	loom_majorant *m;
	int rc;

	*out = NULL;
	if (!f || !loom_fabric_attached(f) || !(db = loom_fabric_db(f)))
		return loom__fail(diag, LOOM_EINVAL,
		                  "majorant: the fabric is NULL or not attached to a database");
	if ((rc = loom_db_get_info(db, &info)) != LOOM_OK)
		return loom__fail(diag, rc, "majorant: cannot read the database's info");
	m = calloc(1, sizeof *m);
	if (!m)
		return loom__fail(diag, LOOM_ENOMEM, "majorant: out of memory");
	m->f = f;
	m->b1 = info.block[0];
	m->b2 = info.block[1];
	m->b3 = info.block[2];
	m->zcell = 1; /* fibre data is dense in every layer of the cloth: thin cells */
	while ((m->b3 + m->zcell - 1) / m->zcell > MAX_ZCELLS)
		m->zcell *= 2;
	m->nzc = (m->b3 + m->zcell - 1) / m->zcell;
	m->sx = cell_side(m->b1);
	m->sy = cell_side(m->b2);
	m->nsx = m->b1 / m->sx;
	m->nsy = m->b2 / m->sy;
	m->nsub = m->nsx * m->nsy;
	m->n_exemplars = info.n_exemplars;
	m->off = calloc(info.n_exemplars + 1u, sizeof *m->off);
	m->bcols = calloc(info.n_exemplars + 1u, sizeof *m->bcols);
	if (!m->off || !m->bcols) {
		rc = loom__fail(diag, LOOM_ENOMEM, "majorant: out of memory");
		goto fail;
	}
	for (uint32_t u = 0; u < info.n_exemplars; u++) {
		loom_db_exemplar_info ei;
		if ((rc = loom_db_exemplar(db, u, &ei)) != LOOM_OK) {
			rc = loom__fail(diag, rc, "majorant: cannot read exemplar %u", u);
			goto fail;
		}
		m->off[u] = (uint32_t)m->n_blocks;
		m->bcols[u] = ei.cols;
		m->n_blocks += (uint64_t)ei.rows * ei.cols;
	}
	if (f->ef && loom_edgefix_get_tables(f->ef, &m->ef) == LOOM_OK &&
	    m->ef.coef && m->ef.b1 == m->b1 && m->ef.b2 == m->b2) {
		uint32_t rh = m->ef.rank_h, rv = m->ef.rank_v;
		m->frange = malloc(2u * (rh + rv + 1u) * sizeof *m->frange);
		if (!m->frange) {
			rc = loom__fail(diag, LOOM_ENOMEM, "majorant: out of memory");
			goto fail;
		}
		for (uint32_t k = 0; k < rh + rv; k++) {
			int vert = k >= rh;
			uint32_t kk = vert ? k - rh : k;
			float lo = INFINITY, hi = -INFINITY;
			for (uint32_t c = 0; c < m->b1 * m->b2; c++) {
				float v = loom_edgefix_field(&m->ef, vert, c % m->b1, c / m->b1, kk);
				lo = v < lo ? v : lo;
				hi = v > hi ? v : hi;
			}
			m->frange[2 * k] = lo;
			m->frange[2 * k + 1] = hi;
		}
		if ((rc = border_init(m, f, diag)) != LOOM_OK)
			goto fail;
	} else {
		memset(&m->ef, 0, sizeof m->ef);
	}
	*out = m;
	return LOOM_OK;
fail:
	loom_majorant_free(m);
	return rc;
}

LOOM_API int loom_majorant_size(const loom_fabric *f, uint32_t threads, size_t *bytes,
                                loom_diag *diag)
{
	loom_majorant *m;
	int rc;

	if (!bytes)
		return loom__fail(diag, LOOM_EINVAL, "majorant: NULL argument");
	*bytes = 0;
	if ((rc = mj_geometry(f, &m, diag)) != LOOM_OK)
		return rc;
	*bytes = loom_majorant_bytes(m, threads);
	loom_majorant_free(m);
	return LOOM_OK;
}

LOOM_API int loom_majorant_build(const loom_fabric *f, loom_majorant **out,
                                 loom_diag *diag)
{
	const loom_db *db;
	loom_db_info info;
	loom_majorant *m;
	uint8_t *buf = NULL;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "majorant: NULL argument");
	if ((rc = mj_geometry(f, out, diag)) != LOOM_OK)
		return rc;
	m = *out;
	*out = NULL;
	db = loom_fabric_db(f);
	loom_db_get_info(db, &info);
	m->layer = calloc(m->n_blocks * m->nsub * m->b3 + 1u, 1);
	if (!m->layer) {
		rc = loom__fail(diag, LOOM_ENOMEM, "majorant: out of memory");
		goto fail;
	}
	/* One block at a time: b1 x b2 x b3 bytes of scratch (2.4 MB at the
	   paper's scale; a row of blocks was up to 19 MB, outside --budget) */
	buf = malloc((size_t)m->b1 * m->b2 * m->b3);
	if (!buf) {
		rc = loom__fail(diag, LOOM_ENOMEM, "majorant: out of memory");
		goto fail;
	}
	for (uint32_t u = 0; u < info.n_exemplars; u++) {
		loom_db_exemplar_info ei;
		loom_db_exemplar(db, u, &ei);
		for (uint32_t r = 0; r < ei.rows; r++)
			for (uint32_t c = 0; c < ei.cols; c++) {
				uint32_t org[3] = {c * m->b1, r * m->b2, 0};
				uint32_t size[3] = {m->b1, m->b2, m->b3};
				uint8_t *blk = m->layer +
				    ((uint64_t)m->off[u] + (uint64_t)r * ei.cols + c) * m->nsub * m->b3;
				if ((rc = loom_db_read_box(db, u, org, size, buf, NULL, NULL, diag)))
					goto fail;
				/* per row, the largest byte of each cell's sx voxels,
				   then one compare with the cell's layer bound */
				for (uint32_t z = 0; z < m->b3; z++)
					for (uint32_t y = 0; y < m->b2; y++) {
						const uint8_t *row = buf + ((size_t)z * m->b2 + y) * m->b1;
						uint8_t *dst = blk + (size_t)(y / m->sy) * m->nsx * m->b3 + z;
						for (uint32_t cx = 0; cx < m->nsx; cx++, row += m->sx,
						              dst += m->b3) {
							uint8_t v = 0;
							for (uint32_t x = 0; x < m->sx; x++)
								v = row[x] > v ? row[x] : v;
							if (v > *dst)
								*dst = v;
						}
					}
			}
	}
	free(buf);
	buf = NULL;
	if ((rc = fill_spans(m))) {
		rc = loom__fail(diag, rc, "majorant: out of memory");
		goto fail;
	}
	*out = m;
	return LOOM_OK;
fail:
	free(buf);
	loom_majorant_free(m);
	return rc;
}

LOOM_API void loom_majorant_free(loom_majorant *m)
{
	if (!m)
		return;
	free(m->off);
	free(m->bcols);
	free(m->layer);
	free(m->span);
	free(m->frange);
	free(m->dslot);
	free(m->dbuf);
	free(m);
}

static size_t x_bytes(const loom_majorant *m);

LOOM_API size_t loom_majorant_bytes(const loom_majorant *m, uint32_t threads)
{
	size_t per_thread;

	if (!m)
		return 0;
	per_thread = sizeof(mj_thread);
	if (m->zcell == 1 && m->b3 <= 64) /* exact cell columns (nearest) */
		per_thread += EXACT_ENTRIES * x_bytes(m) + (size_t)m->sx * m->sy * m->b3;
	return sizeof *m + 2u * (m->n_exemplars + 1u) * sizeof(uint32_t) +
	       (m->frange ? 2u * (m->ef.rank_h + m->ef.rank_v + 1u) * sizeof(float) : 0) +
	       (m->dslot ? 2u * (size_t)m->n_blocks * sizeof(uint32_t) : 0) + m->dfloats * sizeof(float) +
	       (size_t)m->n_blocks * m->nsub * (m->b3 + 2u * sizeof *m->span) + (size_t)threads * per_thread;
}

LOOM_API void loom_majorant_cell_size(const loom_majorant *m, int64_t cell[3])
{
	cell[0] = m ? m->sx : 0;
	cell[1] = m ? m->sy : 0;
	cell[2] = m ? m->zcell : 0;
}

/* The edge-fix offset at column (x, y) for coefficient vectors a (as the
   edge fix evaluates it: docs/synthesis.md). */
static float dz_at(const loom_edgefix_tables *t, const float *a, uint32_t x,
                   uint32_t y)
{
	uint32_t b1 = t->b1, b2 = t->b2, rh = t->rank_h, rv = t->rank_v;
	uint32_t ys = b2 - 1 - y, xe = b1 - 1 - x;
	const uint8_t *pre = t->pre;
	size_t row_v = (size_t)y * t->off[b2 + b1];
	const float *fn = t->field_h + t->off[y] + (size_t)x * pre[y];
	const float *fs = t->field_h + t->off[ys] + (size_t)x * pre[ys];
	const float *fw = t->field_v + row_v + t->off[b2 + x];
	const float *fe = t->field_v + row_v + t->off[b2 + xe];
	float v = 0;

	/* the ranks the compact tables store along this row and column (the
	   rest are 0) */
	for (uint32_t k = 0; k < pre[y]; k++)
		v += a[k] * fn[k];
	for (uint32_t k = 0; k < pre[ys]; k++)
		v += a[rh + k] * fs[k];
	for (uint32_t k = 0; k < pre[b2 + x]; k++)
		v += a[2 * rh + k] * fw[k];
	for (uint32_t k = 0; k < pre[b2 + xe]; k++)
		v += a[2 * rh + rv + k] * fe[k];
	return v;
}


/* Profile j (0 N, 1 S, 2 W, 3 E) of block b as the edge fix matches it
   (loom__edgefix_target: a block's N and W profiles are the S and E
   profiles of the blocks above and left of it in its exemplar, where
   there are some, else its own plus a donor's woven jump, precomputed in
   m->dbuf: the fix keeps the exemplars' own seams). */
static const float *target(const loom_majorant *m, uint32_t b, int j)
{
	const loom_edge_profiles *p = &m->tp;
	uint32_t b1 = m->b1, b2 = m->b2, K = p->n_blocks;
	size_t rec = LOOM_EDGE_RECORD(b1, b2);

	if (p->set && (j == 0 || j == 2)) {
		loom_synth_block sb;
		if (m->dslot && m->dslot[2 * (size_t)b + (j == 2)] != UINT32_MAX)
			return m->dbuf + m->dslot[2 * (size_t)b + (j == 2)];
		loom_synth_block_info(p->set, b, &sb);
		if (j == 0 && sb.up < K)
			return p->heights + (size_t)sb.up * rec + LOOM_EDGE_S(b1, b2);
		if (j == 2 && sb.left < K)
			return p->heights + (size_t)sb.left * rec + LOOM_EDGE_E(b1, b2);
	}
	return p->heights + (size_t)b * rec +
	       (j == 0 ? LOOM_EDGE_N(b1, b2) : j == 1 ? LOOM_EDGE_S(b1, b2) :
	        j == 2 ? LOOM_EDGE_W(b1, b2) : LOOM_EDGE_E(b1, b2));
}

/* m->dslot and m->dbuf: the targets of the blocks whose N or W seam is a
   donor's (loom__edgefix_donor neither the block nor none). */
static int donor_init(loom_majorant *m)
{
	const loom_edge_profiles *p = &m->tp;
	uint32_t K = p->n_blocks;
	size_t n = 0;

	if (!p->set)
		return LOOM_OK;
	for (uint32_t b = 0; b < K; b++)
		for (int j = 0; j <= 2; j += 2) {
			uint32_t d = loom__edgefix_donor(p->set, b, j);
			if (d != b && d != LOOM_SYNTH_NONE)
				n += j ? m->b2 : m->b1;
		}
	if (!n)
		return LOOM_OK;
	m->dslot = malloc(sizeof(uint32_t) * 2 * (size_t)K);
	m->dbuf = malloc(sizeof(float) * n);
	if (!m->dslot || !m->dbuf)
		return LOOM_ENOMEM;
	m->dfloats = n;
	n = 0;
	for (uint32_t b = 0; b < K; b++)
		for (int j = 0; j <= 2; j += 2) {
			uint32_t d = loom__edgefix_donor(p->set, b, j);
			m->dslot[2 * (size_t)b + (j == 2)] = UINT32_MAX;
			if (d != b && d != LOOM_SYNTH_NONE) {
				loom__edgefix_target(p, b, j, m->dbuf + n);
				m->dslot[2 * (size_t)b + (j == 2)] = (uint32_t)n;
				n += j ? m->b2 : m->b1;
			}
		}
	return LOOM_OK;
}

/* The coefficient vectors a (2 (rh + rv) floats) of a crossing whose
   sources are nb, the same combinations as the edge fix's, and the sum
   of magnitudes sum_k |a_k| max |F_k| that dz_range's margin scales
   with. */
static double coef_vectors(const loom_majorant *m, const loom_synth_nbhd *nb, float *a)
{
	uint32_t rh = m->ef.rank_h, rv = m->ef.rank_v;
	double mag = 0;

	loom__edgefix_combine(m->ef.coef, rh, rv, nb, a);
	for (uint32_t k = 0; k < rh; k++)
		mag += (fabs(a[k]) + fabs(a[rh + k])) *
		       fmax(fabs(m->frange[2 * k]), fabs(m->frange[2 * k + 1]));
	for (uint32_t k = 0; k < rv; k++) {
		const float *fr = m->frange + 2 * (rh + k);
		mag += (fabs(a[2 * rh + k]) + fabs(a[2 * rh + rv + k])) *
		       fmax(fabs(fr[0]), fabs(fr[1]));
	}
	return mag;
}

/* At full rank the fix matches the edge data exactly on the border, so
   the offset at a border sample is half the data's jump across that edge
   (the basis is complete and orthonormal, B B^t = 1: docs/synthesis.md),
   with no dot product over the ranks.  Side j (0 N: row 0, 1 S: row
   b2 - 1, 2 W: column 0, 3 E: column b1 - 1) of a crossing whose sources
   are nb: sample i's offset is (p[j][0][i] - p[j][1][i]) / 2, for i in
   0 .. b1 - 1 on N and S and 1 .. b2 - 2 on W and E (the corners belong
   to the N and S edges). */
static void side_profiles(const loom_majorant *m, const loom_synth_nbhd *nb,
                          const float *p[4][2])
{
	p[0][0] = target(m, nb->n, 1), p[0][1] = target(m, nb->self, 0);
	p[1][0] = target(m, nb->s, 0), p[1][1] = target(m, nb->self, 1);
	p[2][0] = target(m, nb->w, 3), p[2][1] = target(m, nb->self, 2);
	p[3][0] = target(m, nb->e, 2), p[3][1] = target(m, nb->self, 3);
}

/* The offset at border sample i of side j, from side_profiles' p. */
static inline double side_value(const float *const p[4][2], int j, uint32_t i)
{
	return 0.5 * ((double)p[j][0][i] - p[j][1][i]);
}

/* Border sample i of side j (as side_profiles numbers them) as a column
   (*x, *y) of the block. */
static void side_sample(const loom_majorant *m, int j, uint32_t i, uint32_t *x, uint32_t *y)
{
	*x = j < 2 ? i : j == 2 ? 0 : m->b1 - 1;
	*y = j >= 2 ? i : j == 0 ? 0 : m->b2 - 1;
}

/* The least and greatest offset along the border of the crossing whose
   sources are nb: from the edge data at full rank (m->tp set,
   side_profiles), else the tables' dot products (a: its coefficient
   vectors). */
static void border_range(const loom_majorant *m, const loom_synth_nbhd *nb, const float *a,
                         double *lo, double *hi)
{
	double l = INFINITY, h = -INFINITY;
	const float *p[4][2];

	if (m->tp.heights)
		side_profiles(m, nb, p);
	for (int j = 0; j < 4; j++) {
		uint32_t i0 = j < 2 ? 0 : 1, i1 = j < 2 ? m->b1 : m->b2 - 1, x, y;
		for (uint32_t i = i0; i < i1; i++) {
			double v;
			if (m->tp.heights) {
				v = side_value(p, j, i);
			} else {
				side_sample(m, j, i, &x, &y);
				v = dz_at(&m->ef, a, x, y);
			}
			l = v < l ? v : l;
			h = v > h ? v : h;
		}
	}
	*lo = l;
	*hi = h;
}

/*
 * [*dlo, *dhi] holds every rounded edge-fix offset of the crossing whose
 * sources are nb (maximum principle: only the border columns are
 * evaluated, see the top of this file).  a: scratch of 2 (rh + rv) floats.
 */
static void dz_range(const loom_majorant *m, const loom_synth_nbhd *nb, float *a,
                     int64_t *dlo, int64_t *dhi)
{
	const loom_edgefix_tables *t = &m->ef;
	double lo = INFINITY, hi = -INFINITY, mag, margin;

	if (!t->coef) { /* no edge fix: no offset */
		*dlo = *dhi = 0;
		return;
	}
	if (nb->self >= t->n_blocks || nb->n >= t->n_blocks || nb->s >= t->n_blocks ||
	    nb->w >= t->n_blocks || nb->e >= t->n_blocks) {
		*dlo = -4096;
		*dhi = 4096;
		return;
	}
	mag = coef_vectors(m, nb, a);
	border_range(m, nb, a, &lo, &hi);
	/* float dot products of 4r terms, float basis fields: errors far
	   below 1e-4 of the sum of magnitudes */
	margin = 1e-3 + 1e-4 * mag;
	lo -= margin;
	hi += margin;
	/* screened fields: the interior lies between 0 and the border's
	   values, not always between the border's extremes (a block whose
	   whole border is raised sinks back towards 0 inside) */
	lo = lo < 0 ? lo : 0;
	hi = hi > 0 ? hi : 0;
	lo = lo < -4096.0 ? -4096.0 : lo > 4096.0 ? 4096.0 : lo;
	hi = hi < -4096.0 ? -4096.0 : hi > 4096.0 ? 4096.0 : hi;
	*dlo = (int64_t)floor(lo);
	*dhi = (int64_t)ceil(hi);
}

/*
 * m->tp at full rank: the fabric's edge profiles, whose targets (target)
 * the fix matches, so that dz_range reads the border offsets from them
 * (side_profiles).  Checked against the tables:
 * every block's coefficients must give back its edge data, and the
 * border of up to 16 blocks with made-up neighbours must agree with the
 * tables' dot products, within dz_range's margin; if not (tables edited,
 * or from other profiles), m->tp stays unset and the tables are used.
 */
static int border_init(loom_majorant *m, const loom_fabric *f, loom_diag *diag)
{
	const loom_edge_profiles *p = &f->prof;
	const loom_edgefix_tables *t = &m->ef;
	uint32_t K = t->n_blocks, rh = t->rank_h, rv = t->rank_v;
	float *a;
	int ok = 1;

	memset(&m->tp, 0, sizeof m->tp);
	if (rh != m->b1 || rv != m->b2 - 2 || !p->heights || p->n_blocks != K ||
	    p->b1 != m->b1 || p->b2 != m->b2 || (p->set && loom_synth_set_blocks(p->set) != K))
		return LOOM_OK;
	m->tp = *p; /* the fabric's: it outlives the majorant */
	a = malloc(sizeof(float) * (2u * (rh + rv) + 1u));
	if (!a || donor_init(m) != LOOM_OK) {
		free(a);
		return loom__fail(diag, LOOM_ENOMEM, "majorant: out of memory");
	}
	/* every block's coefficients give back its edge data (so the border
	   identity holds for any neighbours: it is linear in them) */
	for (uint32_t b = 0; b < K && ok; b++) {
		const float *c = t->coef + (size_t)b * (2 * rh + 2 * rv);
		for (int j = 0; j < 4 && ok; j++) {
			uint32_t n = j < 2 ? m->b1 : m->b2 - 2, r = j < 2 ? rh : rv;
			const float *B = j < 2 ? t->basis_h : t->basis_v, *mean = j < 2 ? t->mean_h : t->mean_v;
			const float *cj = c + (j == 0 ? 0 : j == 1 ? rh : j == 2 ? 2 * rh : 2 * rh + rv);
			const float *v = target(m, b, j) + (j < 2 ? 0 : 1); /* W/E: interior */
			for (uint32_t i = 0; i < n && ok; i++) {
				double sum = mean[i], mg = fabs(mean[i]);
				for (uint32_t k = 0; k < r; k++) {
					sum += (double)B[(size_t)i * r + k] * cj[k];
					mg += fabs((double)B[(size_t)i * r + k] * cj[k]);
				}
				if (fabs(sum - v[i]) > 0.25e-3 + 0.25e-4 * mg)
					ok = 0;
			}
		}
	}
	/* and the tables' dot products on the border give the same offsets
	   (16 blocks with made-up neighbours) */
	for (uint32_t b = 0; b < K && b < 16 && ok; b++) {
		loom_synth_nbhd nb = {0};
		const float *sp[4][2];
		double tol;
		nb.self = b;
		nb.n = (b + 1) % K;
		nb.s = (b + 2) % K;
		nb.w = (b + 3) % K;
		nb.e = (b + 4) % K;
		tol = 0.5e-3 + 0.5e-4 * coef_vectors(m, &nb, a);
		side_profiles(m, &nb, sp);
		for (int j = 0; j < 4 && ok; j++) {
			uint32_t i0 = j < 2 ? 0 : 1, i1 = j < 2 ? m->b1 : m->b2 - 1, x, y;
			for (uint32_t i = i0; i < i1; i++) {
				side_sample(m, j, i, &x, &y);
				if (fabs(side_value(sp, j, i) - dz_at(t, a, x, y)) > tol)
					ok = 0;
			}
		}
	}
	free(a);
	if (!ok) {
		memset(&m->tp, 0, sizeof m->tp);
		free(m->dslot);
		free(m->dbuf);
		m->dslot = NULL;
		m->dbuf = NULL;
		m->dfloats = 0;
	}
	return LOOM_OK;
}

int loom__majorant_border_data(const loom_majorant *m)
{
	return m && m->tp.heights != NULL;
}

/* The source block's cell layers and the edge-fix offset range of
   crossing (I, J). */
static int crossing_src(const loom_majorant *m, float *a, int64_t I, int64_t J,
                        const uint8_t **blk, int64_t *dlo, int64_t *dhi)
{
	loom_fabric_source s;
	int rc;

	if ((rc = loom_fabric_source_at(m->f, I, J, &s)) != LOOM_OK)
		return rc;
	if (s.exemplar >= m->n_exemplars)
		return LOOM_ECORRUPT;
	dz_range(m, &s.nbhd, a, dlo, dhi);
	if (m->ef.coef) { /* the corner columns' offsets (the corner term) */
		float cd[4];
		if ((rc = loom_fabric_corner_dz(m->f, I, J, cd)) != LOOM_OK)
			return rc;
		for (int k = 0; k < 4; k++) {
			double lo = fmax(-4096.0, (double)cd[k] - 1e-3);
			double hi = fmin(4096.0, (double)cd[k] + 1e-3);
			int64_t l = (int64_t)floor(lo), h = (int64_t)ceil(hi);
			*dlo = l < *dlo ? l : *dlo;
			*dhi = h > *dhi ? h : *dhi;
		}
	}
	*blk = m->layer + ((uint64_t)m->off[s.exemplar] +
	                   (uint64_t)s.row * m->bcols[s.exemplar] + s.col) * m->nsub * m->b3;
	return LOOM_OK;
}

/* Bound of output layers [z0, z1] of one cell column col (b3 source layer
   maxima) whose crossing has offsets in [dlo, dhi]: output layer z reads
   source layer z - dz. */
static uint8_t column_bound(const loom_majorant *m, const uint8_t *col, int64_t z0,
                            int64_t z1, int64_t dlo, int64_t dhi)
{
	int64_t s0 = z0 - dhi, s1 = z1 - dlo;
	uint8_t best = 0;

	if (s0 < 0)
		s0 = 0;
	if (s1 > (int64_t)m->b3 - 1)
		s1 = (int64_t)m->b3 - 1;
	for (int64_t sz = s0; sz <= s1; sz++)
		best = col[sz] > best ? col[sz] : best;
	return best;
}

/*
 * Exact cell columns (nearest lookups through the texture, z cells of one
 * layer, b3 <= 64).  The first time a cell of a cell column has a non-zero
 * database bound (entry_bound), the column's output densities (sx x sy x
 * b3 voxels) are read from the texture (loom_texture_read_region, voxel
 * for voxel equal to its point lookups) and its cells' largest density
 * bytes and the mask of its non-empty layers are kept in a per-thread
 * direct-mapped cache of EXACT_ENTRIES crossings.  So a cell's bound is
 * its exact maximum, not the source column's maxima over the crossing's
 * whole edge-fix offset range (on the Cycles bench scene 21 tentative
 * collisions per path instead of 57), and a filled column's z span is its
 * exact first and last non-empty layer.  A cell whose database bound is 0
 * is empty, so every bound is the exact maximum whether or not its column
 * was filled before: pure functions of the fabric, the same for any
 * thread or order.
 */
static int x_ok(const loom_majorant *m)
{
	return m->t && m->filter == LOOM_FILTER_NEAREST && m->zcell == 1 && m->b3 <= 64;
}

static size_t x_bytes(const loom_majorant *m)
{
	size_t n = sizeof(mj_exact) + (size_t)m->nsub * (8u + 1u + m->nzc);
	return (n + 7u) / 8u * 8u;
}

static inline mj_exact *x_rec(const mj_thread *th, const mj_entry *e)
{
	return (mj_exact *)(th->xpool + (size_t)e->xslot * x_bytes(th->m));
}

static inline uint64_t *x_zmask(mj_exact *x)
{
	return (uint64_t *)(x + 1);
}

static inline uint8_t *x_filled(const loom_majorant *m, mj_exact *x)
{
	return (uint8_t *)(x_zmask(x) + m->nsub);
}

static inline uint8_t *x_cmax(const loom_majorant *m, mj_exact *x)
{
	return x_filled(m, x) + m->nsub;
}

/* The record of entry e's crossing (claimed, nothing filled, when it
   holds another one). */
static inline mj_exact *x_of(mj_thread *th, const mj_entry *e)
{
	mj_exact *x = x_rec(th, e);

	if (!x->valid || x->I != e->I || x->J != e->J) {
		th->lcmax = NULL; /* it may point into this record */
		x->I = e->I;
		x->J = e->J;
		x->valid = 1;
		memset(x_filled(th->m, x), 0, th->m->nsub);
	}
	return x;
}

/* Fill cell column (cx, cy) (within the crossing) of record x. */
static int x_fill(mj_thread *th, mj_exact *x, uint32_t cx, uint32_t cy)
{
	loom_majorant *m = th->m;
	uint32_t u = cy * m->nsx + cx;
	int64_t lo[3] = {x->J * (int64_t)m->b1 + (int64_t)cx * m->sx,
	                 x->I * (int64_t)m->b2 + (int64_t)cy * m->sy, 0};
	int64_t hi[3] = {lo[0] + m->sx, lo[1] + m->sy, m->b3};
	loom_texture_region r;
	uint8_t *cz = x_cmax(m, x) + (size_t)u * m->nzc;
	uint64_t all = 0;
	int rc;

	memset(&r, 0, sizeof r);
	r.density = th->scratch;
	r.layout = LOOM_REGION_Z_FASTEST;
	if ((rc = loom_texture_read_region(m->t, lo, hi, &r)) != LOOM_OK)
		return rc;
	memset(cz, 0, m->nzc);
	for (uint32_t k = 0; k < m->sx * m->sy; k++) {
		const uint8_t *col = th->scratch + (size_t)k * m->b3;
		for (uint32_t z = 0; z < m->b3; z++) {
			all |= (uint64_t)(col[z] != 0) << z;
			cz[z] = col[z] > cz[z] ? col[z] : cz[z];
		}
	}
	x_zmask(x)[u] = all;
	x_filled(m, x)[u] = 1;
	return LOOM_OK;
}

/* Output layers [lo, hi] (source layers shifted by edge-fix offsets, so
   possibly outside the slab) as the z cells [*zlo, *zhi] that hold them,
   clamped to the slab; (1, 0) when none does. */
static void layer_cells(const loom_majorant *m, int64_t lo, int64_t hi, int64_t *zlo,
                        int64_t *zhi)
{
	lo = lo < 0 ? 0 : lo;
	hi = hi > (int64_t)m->b3 - 1 ? (int64_t)m->b3 - 1 : hi;
	*zlo = hi < lo ? 1 : lo / m->zcell;
	*zhi = hi < lo ? 0 : hi / m->zcell;
}

/* Fill entry e for crossing (I, J).  Nearest: the source block and offset
   range (cell bounds are read from them per query, a few bytes each).
   Trilinear: the 8 voxels around a point may lie in any neighbouring
   cell, crossing or layer, so every cell of the crossing takes the
   largest bound over the 3 x 3 crossings' cells, one layer more on each
   side: tri[z cell]. */
static int fill_entry(mj_thread *th, int filter, int64_t I, int64_t J, mj_entry *e)
{
	loom_majorant *m = th->m;
	int rc;

	if ((rc = crossing_src(m, th->a, I, J, &e->blk, &e->dlo, &e->dhi)))
		return rc;
	if (filter == LOOM_FILTER_TRILINEAR) {
		memset(e->tri, 0, sizeof e->tri);
		for (int k = 0; k < 9; k++) {
			const uint8_t *blk = e->blk; /* k == 4: the crossing itself */
			int64_t dlo = e->dlo, dhi = e->dhi;
			if (k != 4 && (rc = crossing_src(m, th->a, I + k / 3 - 1, J + k % 3 - 1,
			                                 &blk, &dlo, &dhi)))
				return rc;
			for (uint32_t c = 0; c < m->nzc; c++) {
				int64_t z0 = (int64_t)c * m->zcell - 1, z1 = z0 + m->zcell + 1;
				for (uint32_t u = 0; u < m->nsub; u++) {
					uint8_t v = column_bound(m, blk + (size_t)u * m->b3, z0, z1, dlo, dhi);
					e->tri[c] = v > e->tri[c] ? v : e->tri[c];
				}
			}
		}
	}
	e->zlo = 0;
	e->zhi = (int64_t)m->nzc - 1;
	if (filter == LOOM_FILTER_NEAREST) { /* the union of the column spans */
		const uint32_t *sp = m->span + (size_t)(e->blk - m->layer) / m->b3 * 2u;
		int64_t lo = INT64_MAX, hi = -1;
		for (uint32_t u = 0; u < m->nsub; u++, sp += 2)
			if (sp[0] <= sp[1]) {
				lo = (int64_t)sp[0] + e->dlo < lo ? (int64_t)sp[0] + e->dlo : lo;
				hi = (int64_t)sp[1] + e->dhi > hi ? (int64_t)sp[1] + e->dhi : hi;
			}
		layer_cells(m, lo, hi, &e->zlo, &e->zhi);
	}
	e->I = I;
	e->J = J;
	e->xslot = (uint32_t)(((uint64_t)I * 0x9e3779b97f4a7c15ull ^
	                       (uint64_t)J * 0xc2b2ae3d27d4eb4full) >> 40) % EXACT_ENTRIES;
	e->valid = 1;
	return LOOM_OK;
}

/* Raw bound of cell (cx, cy) (within the crossing) and z cell cz of the
   filled entry e. */
static uint8_t entry_bound(const loom_majorant *m, int filter, const mj_entry *e,
                           uint32_t cx, uint32_t cy, uint32_t cz)
{
	int64_t z0 = (int64_t)cz * m->zcell;

	if (filter == LOOM_FILTER_TRILINEAR)
		return e->tri[cz];
	return column_bound(m, e->blk + ((size_t)cy * m->nsx + cx) * m->b3, z0,
	                    z0 + m->zcell - 1, e->dlo, e->dhi);
}

/* A raw bound byte as a density: raw / 255 as the texture computes it,
   widened a little so that no rounding of a blend can exceed it. */
static inline float raw_bound(uint8_t v)
{
	return v ? (float)v / 255.0f * 1.0001f : 0.0f;
}

/* The filled entry of the crossing holding cell column (c0, c1); th->cx0,
   cy0 become its first cell. */
static int entry_of(mj_thread *th, int64_t c0, int64_t c1, mj_entry **out)
{
	loom_majorant *m = th->m;
	mj_entry *e = th->last;
	uint64_t h;
	int64_t I, J;
	int rc;

	/* most queries fall in the last query's crossing (a DDA walks 4 x 4
	   cells of a 24 x 16 crossing): no 64-bit divisions then */
	if (e && (uint64_t)(c0 - th->cx0) < m->nsx && (uint64_t)(c1 - th->cy0) < m->nsy) {
		*out = e;
		return LOOM_OK;
	}
	I = loom_synth_floordiv(c1, m->nsy);
	J = loom_synth_floordiv(c0, m->nsx);
	if (!e || e->I != I || e->J != J) {
		h = (uint64_t)I * 0x9e3779b97f4a7c15ull ^ (uint64_t)J * 0xc2b2ae3d27d4eb4full;
		e = &th->cache[(h >> 40) % CACHE_ENTRIES];
		if (!e->valid || e->I != I || e->J != J) {
			e->valid = 0;
			th->last = NULL;
			if ((rc = fill_entry(th, m->filter, I, J, e)))
				return rc;
		}
		th->last = e;
	}
	th->cx0 = J * m->nsx;
	th->cy0 = I * m->nsy;
	*out = e;
	return LOOM_OK;
}

static int mj_cell_max(void *thread_ctx, const int64_t c[3], float *bound)
{
	mj_thread *th = thread_ctx;
	loom_majorant *m = th->m;
	mj_entry *e;
	uint32_t cx, cy;
	uint8_t v;
	int rc;

	*bound = 0.0f;
	if (c[2] < 0 || c[2] >= (int64_t)m->nzc)
		return LOOM_OK;
	if (th->lcmax && c[0] == th->lc0 && c[1] == th->lc1) {
		/* the exact maxima of the last filled column: the same value as
		   below (where the database bound v is 0 the maximum is 0) */
		*bound = raw_bound(th->lcmax[c[2]]);
		return LOOM_OK;
	}
	if ((rc = entry_of(th, c[0], c[1], &e)))
		return rc;
	cx = (uint32_t)(c[0] - th->cx0);
	cy = (uint32_t)(c[1] - th->cy0);
	v = entry_bound(m, m->filter, e, cx, cy, (uint32_t)c[2]);
	if (v && th->exact) { /* the exact maximum, at most v */
		mj_exact *x = x_of(th, e);
		uint32_t u = cy * m->nsx + cx;
		if (!x_filled(m, x)[u] && (rc = x_fill(th, x, cx, cy)))
			return rc;
		th->lcmax = x_cmax(m, x) + (size_t)u * m->nzc;
		th->lc0 = c[0];
		th->lc1 = c[1];
		v = th->lcmax[c[2]];
	}
	*bound = raw_bound(v);
	return LOOM_OK;
}

/* z cells [*zlo, *zhi] of cell column (c[0], c[1]) outside which every
   cell's bound is 0: the column's non-zero source layers shifted by the
   crossing's edge-fix offsets (output layer z reads source z - dz).
   Trilinear: every z cell (its bounds blend neighbouring columns). */
static int mj_cell_zspan(void *thread_ctx, const int64_t c[3], int64_t *zlo, int64_t *zhi)
{
	mj_thread *th = thread_ctx;
	loom_majorant *m = th->m;
	const uint32_t *sp;
	mj_entry *e;
	int rc;

	*zlo = 0;
	*zhi = (int64_t)m->nzc - 1;
	if (m->filter == LOOM_FILTER_TRILINEAR)
		return LOOM_OK;
	if ((rc = entry_of(th, c[0], c[1], &e)))
		return rc;
	if (th->exact) { /* a filled column: its exact span */
		mj_exact *x = x_of(th, e);
		uint32_t u = (uint32_t)(c[1] - th->cy0) * m->nsx + (uint32_t)(c[0] - th->cx0);
		if (x_filled(m, x)[u]) {
			uint64_t b = x_zmask(x)[u];
			th->lcmax = x_cmax(m, x) + (size_t)u * m->nzc;
			th->lc0 = c[0];
			th->lc1 = c[1];
			if (b) {
				*zlo = __builtin_ctzll(b);
				*zhi = 63 - __builtin_clzll(b);
			} else {
				*zlo = 1;
				*zhi = 0;
			}
			return LOOM_OK;
		}
	}
	sp = m->span + ((size_t)(e->blk - m->layer) / m->b3 +
	                (size_t)(c[1] - th->cy0) * m->nsx + (size_t)(c[0] - th->cx0)) * 2u;
	if (sp[0] > sp[1]) { /* an empty column */
		*zlo = 1;
		*zhi = 0;
		return LOOM_OK;
	}
	layer_cells(m, (int64_t)sp[0] + e->dlo, (int64_t)sp[1] + e->dhi, zlo, zhi);
	return LOOM_OK;
}

/* The crossing holding cell column (c[0], c[1]) as a box of cell columns,
   and the z cells outside which all its cells are empty: the union of its
   columns' spans as mj_cell_zspan gives them from the database (kept in
   the entry).  The read columns' exact spans would be tighter, but on the
   Cycles bench scene they cut only 36 -> 34 cells per path and cost more
   than that in the query.  Trilinear: the whole slab. */
static int mj_cell_zbox(void *thread_ctx, const int64_t c[3], int64_t box[4], int64_t *zlo,
                        int64_t *zhi)
{
	mj_thread *th = thread_ctx;
	loom_majorant *m = th->m;
	mj_entry *e;
	int rc;

	if ((rc = entry_of(th, c[0], c[1], &e)))
		return rc;
	box[0] = th->cx0;
	box[1] = th->cx0 + m->nsx;
	box[2] = th->cy0;
	box[3] = th->cy0 + m->nsy;
	*zlo = e->zlo;
	*zhi = e->zhi;
	return LOOM_OK;
}

static mj_thread *thread_new(loom_majorant *m, int exact)
{
	mj_thread *th = calloc(1, sizeof *th);

	if (!th)
		return NULL;
	th->m = m;
	if (exact && x_ok(m)) {
		th->exact = 1;
		th->xpool = calloc(EXACT_ENTRIES, x_bytes(m));
		th->scratch = malloc((size_t)m->sx * m->sy * m->b3);
		if (!th->xpool || !th->scratch) {
			free(th->xpool);
			free(th->scratch);
			free(th);
			return NULL;
		}
	}
	return th;
}

static void thread_free(mj_thread *th)
{
	if (!th)
		return;
	free(th->xpool);
	free(th->scratch);
	free(th);
}

LOOM_API int loom_majorant_bound(loom_majorant *m, int filter, int64_t I, int64_t J,
                                 uint8_t *out)
{
	mj_thread *th;
	mj_entry *e;
	int rc;

	if (!m || !out || (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	if (!(th = thread_new(m, 0))) /* the database's bound, not the exact one */
		return LOOM_ENOMEM;
	e = &th->cache[0];
	rc = fill_entry(th, filter, I, J, e);
	if (!rc)
		for (uint32_t u = 0; u < m->nsub; u++)
			for (uint32_t c = 0; c < m->nzc; c++)
				out[(size_t)u * m->nzc + c] =
				    entry_bound(m, filter, e, u % m->nsx, u / m->nsx, c);
	thread_free(th);
	return rc;
}

/* ---- the volume source -------------------------------------------------- */

static int grid_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	mj_thread *th = ctx;
	loom_texel tx;
	int rc;

	if (th->m->filter == LOOM_FILTER_NEAREST) /* no texel in between */
		return loom__texture_medium(th->m->t, p, out);
	if ((rc = loom_texture_sample(th->m->t, p, th->m->filter, &tx)) != LOOM_OK)
		return rc;
	loom__texel_medium(&tx, out);
	return LOOM_OK;
}

/* Level of detail through the grid: the coarse density is clamped to the
   bound of its cell (the level-0 grid, unchanged), so the tracker's
   majorant holds: a coarse voxel averages 2^k layers and would otherwise
   spill density into the empty layers above and below the cloth, and at
   a block edge it averages the exemplar's neighbouring block
   (docs/rendering.md, "Level of detail"). */
static int grid_lookup_lod(void *ctx, const double p[3], double fp,
                           loom_medium_sample *out)
{
	mj_thread *th = ctx;
	loom_majorant *m = th->m;
	loom_texel tx;
	float spread = 0, bound;
	int64_t c[3];
	int rc = loom_texture_sample_lod(m->t, p, m->filter,
	                                 loom__lod_level(fp, loom_texture_lod_levels(m->t)),
	                                 &tx, &spread);

	if (rc != LOOM_OK)
		return rc;
	c[0] = loom_synth_floordiv((int64_t)floor(p[0]), m->sx);
	c[1] = loom_synth_floordiv((int64_t)floor(p[1]), m->sy);
	c[2] = (int64_t)floor(p[2]) / m->zcell;
	if ((rc = mj_cell_max(th, c, &bound)))
		return rc;
	loom__texel_medium(&tx, out);
	out->density = tx.density < bound ? tx.density : bound;
	out->spread = spread;
	return LOOM_OK;
}

static int grid_density(void *ctx, const double p[3], float *density)
{
	mj_thread *th = ctx;
	loom_texel tx;
	int rc = loom_texture_sample_ch(th->m->t, p, th->m->filter, LOOM_CHANNEL_DENSITY, &tx);

	*density = rc == LOOM_OK ? tx.density : 0.0f;
	return rc;
}

static void *grid_thread_init(void *ctx)
{
	return thread_new(ctx, 1);
}

static void grid_thread_done(void *ctx, void *thread_ctx)
{
	loom_majorant *m = ctx;

	loom_texture_thread_done(m->t);
	thread_free(thread_ctx);
}

LOOM_API int loom_texture_volume_source_grid(loom_texture *t, const loom_fabric *f,
                                             int filter, loom_majorant *m,
                                             loom_volume_source *src)
{
	int rc;

	if (!m || m->f != f)
		return LOOM_EINVAL;
	if ((rc = loom_texture_volume_source(t, f, filter, src)) != LOOM_OK)
		return rc;
	m->t = t;
	m->filter = filter;
	src->lookup = grid_lookup;
	src->ctx = m;
	src->thread_init = grid_thread_init;
	src->thread_done = grid_thread_done;
	loom_majorant_cell_size(m, src->cell);
	src->cell_max = mj_cell_max;
	src->cell_zspan = mj_cell_zspan;
	src->cell_zbox = mj_cell_zbox;
	if (loom_texture_lod_levels(t))
		src->lookup_lod = grid_lookup_lod;
	/* the density-first test of tentative collisions pays only against
	   loose bounds: with exact cells three in four tentative collisions
	   (Cycles bench scene) have a density above 0 and would be looked up
	   twice */
	src->density = x_ok(m) ? NULL : grid_density;
	return LOOM_OK;
}
