/*
 * engine/synth/fabric.c - a design bound to an exemplar database by synthesis.
 *
 * What it owns (engine/synth/fabric_internal.h has the struct):
 *   design            3 bytes per crossing (weave, two type maps)
 *   base              2 bytes per crossing (source block of each crossing)
 *   edge-fix tables   4 b1 b2 (rh + rv) + 16 K r bytes, size-independent
 *   exemplar set, block table, edge profiles: O(K), rebuilt from the
 *                     database whenever the fabric is bound to it
 * Nothing is proportional to the bolt: every crossing of the unbounded
 * bolt is evaluated on demand (loom_synth_src, loom_edgefix_block).
 *
 * Synthesis, step by step (loom_fabric_synthesize):
 *   1. check the options and the design; copy the design;
 *   2. record the database identity (hash, geometry) and attach to it:
 *      exemplar set from the exemplar weaves, per-block table, edge
 *      profiles, internal step (attach_db);
 *   3. base assignment (loom_synth_assign), randomised lookup;
 *   4. edge-fix tables at rank r (loom_edgefix_build);
 *   5. metrics: repeat (base), bolt window (randomised), seams.
 * Opening a file (loom_fabric_open, io/store/fabric_file.c) parses it into
 * a detached fabric (loom__fabric_alloc here), then binds it here: hash and
 * geometry checks, attach_db, the tables from the file or rebuilt, the
 * lookup (loom__fabric_bind).  This file opens no file.
 */
#include "fabric_internal.h"
#include "seam_acc.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- allocation ---------------------------------------------------------- */

loom_fabric *loom__fabric_alloc(void)
{
	loom_fabric *f = calloc(1, sizeof *f);
	if (!f)
		return NULL;
	f->db_path = calloc(1, 1);
	if (!f->db_path) {
		free(f);
		return NULL;
	}
	return f;
}

/* ---- block corners ------------------------------------------------------
 *
 * Where four output blocks meet, the edge fix leaves four corner columns
 * whose offsets come from the N/S edges alone (the paper's rule: the
 * corners belong to the N and S edges), so the W/E seams do not meet there
 * and synthesized corners jumped 1.4-2.5 times as much as the woven
 * cloth's (docs/fidelity.md, "Block corners").  The corner term sets the
 * four corner columns' heights to their mean, each plus the offset its
 * source block's corner had from the mean of the four corner columns that
 * met there in its own exemplar (so the woven cloth's own corner jumps are
 * kept, as the calibrated fix keeps the seams'; 0 on the exemplar's
 * border, where the corner is closed).  The corner columns are Dirichlet
 * samples no interior equation of the fix reads, so nothing else moves.
 */

/* Height of block t's corner column c (0 NW, 1 NE, 2 SW, 3 SE) in its
   profiles. */
static float corner_height(const loom_fabric *f, uint32_t t, int c)
{
	const float *h = f->heights + (size_t)t * LOOM_EDGE_RECORD(f->b1, f->b2);
	uint32_t x = loom__fabric_corner_x(f, c);
	return c < 2 ? h[LOOM_EDGE_N(f->b1, f->b2) + x] : h[LOOM_EDGE_S(f->b1, f->b2) + x];
}

/* f->corner_off from f->heights and f->set once f->ef exists; none (NULL)
   when the fix has rank 0 (no edge fix at all).  LOOM_OK or LOOM_ENOMEM. */
static int corner_offsets(loom_fabric *f)
{
	uint32_t K = f->n_blocks;
	loom_edgefix_tables tb;
	free(f->corner_off);
	f->corner_off = NULL;
	loom_edgefix_get_tables(f->ef, &tb);
	if (tb.rank_h + tb.rank_v == 0)
		return LOOM_OK;
	f->corner_off = calloc((size_t)K * 4, sizeof(float));
	if (!f->corner_off)
		return LOOM_ENOMEM;
	for (uint32_t t = 0; t < K; t++) {
		loom_synth_block sb, vb;
		loom_synth_block_info(f->set, t, &sb);
		for (int c = 0; c < 4; c++) {
			uint32_t v = c < 2 ? sb.up : sb.down;
			uint32_t hz = (c & 1) ? sb.right : sb.left, d = LOOM_SYNTH_NONE;
			if (v < K) {
				loom_synth_block_info(f->set, v, &vb);
				d = (c & 1) ? vb.right : vb.left;
			}
			if (v < K && hz < K && d < K) {
				float own = corner_height(f, t, c);
				float m = 0.25f * (own + corner_height(f, v, c ^ 2) +
				                   corner_height(f, hz, c ^ 1) +
				                   corner_height(f, d, c ^ 3));
				f->corner_off[(size_t)t * 4 + c] = own - m;
			}
		}
	}
	return LOOM_OK;
}

float loom__fabric_corner_dz(const loom_fabric *f, int64_t I, int64_t J, int k)
{
	/* the four crossings meeting at corner k of (I, J), each with the
	   index of its corner there: self k, vertical k^2, horizontal k^1,
	   diagonal k^3 */
	int64_t di = k < 2 ? -1 : 1, dj = (k & 1) ? 1 : -1;
	int64_t ci[4] = {I, I + di, I, I + di}, cj[4] = {J, J, J + dj, J + dj};
	int cc[4] = {k, k ^ 2, k ^ 1, k ^ 3};
	float H[4], o[4], own_h = 0;
	float mh, mo;

	for (int m = 0; m < 4; m++) {
		loom_synth_nbhd nb;
		uint32_t x = loom__fabric_corner_x(f, cc[m]), y = loom__fabric_corner_y(f, cc[m]);
		float h;
		loom__fabric_nbhd(f, ci[m], cj[m], &nb);
		h = corner_height(f, nb.self, cc[m]);
		if (m == 0)
			own_h = h;
		H[m] = h + loom_edgefix_at(f->ef, &nb, x, y);
		o[m] = f->corner_off[(size_t)nb.self * 4 + cc[m]];
	}
	mh = 0.25f * ((H[0] + H[1]) + (H[2] + H[3]));
	mo = 0.25f * ((o[0] + o[1]) + (o[2] + o[3]));
	return (mh + (o[0] - mo)) - own_h;
}

/* Drop what attach_db built (keeps the file's data). */
static void detach(loom_fabric *f)
{
	loom_synth_set_free(f->set);
	f->set = NULL;
	free(f->blocks);
	f->blocks = NULL;
	free(f->heights);
	f->heights = NULL;
	free(f->corner_off);
	f->corner_off = NULL;
	memset(&f->prof, 0, sizeof f->prof);
	memset(&f->lk, 0, sizeof f->lk);
	f->attached = 0;
	f->db = NULL;
}

LOOM_API void loom_fabric_free(loom_fabric *f)
{
	if (!f)
		return;
	if (f->parent) {
		/* a painted weave: only the newest patch is this fabric's own */
		loom__fabric_patch *p = (loom__fabric_patch *)f->patch;
		free(p->src);
		free(p->weave);
		free(p);
		loom_fabric_free(f->parent);
		free(f);
		return;
	}
	detach(f);
	loom_db_close(f->db_owned);
	loom_design_free(f->design);
	loom_edgefix_free(f->ef);
	free(f->base);
	free(f->usage);
	free(f->db_path);
	free(f);
}

/* ---- attaching to a database -------------------------------------------- */

/* Build the exemplar set, block table and edge profiles from db.  If
   f->n_blocks is set (an opened file), K must equal it. */
static int attach_db(loom_fabric *f, const loom_db *db, const char *name,
                     loom_diag *diag)
{
	loom_synth_exemplar *ex = NULL;
	uint32_t n_ex = f->n_exemplars, K, rec;
	double step = 0;
	int rc;

	ex = calloc(n_ex, sizeof *ex);
	if (!ex)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	for (uint32_t u = 0; u < n_ex; u++) {
		loom_db_exemplar_info e;
		rc = loom_db_exemplar(db, u, &e);
		if (rc) {
			free(ex);
			return loom__fail(diag, rc, "%s: database exemplar %u: %s", name, u,
			                  loom_strerror(rc));
		}
		ex[u].rows = e.rows;
		ex[u].cols = e.cols;
		ex[u].weave = e.weave;
		ex[u].periodic = 0; /* generated and scanned windows are cut */
	}
	rc = loom_synth_set_new(ex, n_ex, &f->set, diag);
	free(ex);
	if (rc)
		return rc;
	K = loom_synth_set_blocks(f->set);
	if (f->n_blocks && K != f->n_blocks)
		return loom__fail(diag, LOOM_EMISMATCH,
		                  "%s: made with %u source blocks, the database has %u",
		                  name, f->n_blocks, K);
	f->n_blocks = K;
	rec = LOOM_EDGE_RECORD(f->b1, f->b2);
	f->blocks = calloc(K, sizeof *f->blocks);
	f->heights = malloc(sizeof(float) * rec * (size_t)K);
	if (!f->blocks || !f->heights)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	for (uint32_t t = 0; t < K; t++) {
		loom_synth_block sb;
		loom_db_block_info bi;
		float *h = f->heights + (size_t)t * rec;
		loom_synth_block_info(f->set, t, &sb);
		rc = loom_db_block(db, sb.exemplar, sb.row, sb.col, &bi);
		if (rc)
			return loom__fail(diag, rc, "%s: database block %u (exemplar %u, "
			                  "row %u, col %u): %s", name, t, sb.exemplar, sb.row,
			                  sb.col, loom_strerror(rc));
		f->blocks[t].exemplar = (uint16_t)sb.exemplar;
		f->blocks[t].row = (uint16_t)sb.row;
		f->blocks[t].col = (uint16_t)sb.col;
		f->blocks[t].code = (uint8_t)sb.code;
		f->blocks[t].x0 = sb.col * f->b1;
		f->blocks[t].y0 = sb.row * f->b2;
		memcpy(h + LOOM_EDGE_N(f->b1, f->b2), bi.north, sizeof(float) * f->b1);
		memcpy(h + LOOM_EDGE_S(f->b1, f->b2), bi.south, sizeof(float) * f->b1);
		memcpy(h + LOOM_EDGE_W(f->b1, f->b2), bi.west, sizeof(float) * f->b2);
		memcpy(h + LOOM_EDGE_E(f->b1, f->b2), bi.east, sizeof(float) * f->b2);
		step += 0.5 * ((double)bi.mean_dh_x + (double)bi.mean_dh_y);
	}
	f->prof.b1 = f->b1;
	f->prof.b2 = f->b2;
	f->prof.n_blocks = K;
	f->prof.heights = f->heights;
	f->prof.set = f->set; /* the fix keeps the exemplars' own seam jumps */
	f->internal_step = step / K;
	f->db = db;
	return LOOM_OK;
}

/* Effective ranks of a build at `rank` (as loom_edgefix_build clips). */
static void edge_ranks(const loom_edgefix *ef, uint32_t *rh, uint32_t *rv)
{
	loom_edgefix_tables t;
	loom_edgefix_get_tables(ef, &t);
	*rh = t.rank_h;
	*rv = t.rank_v;
}

static int init_lookup(loom_fabric *f)
{
	loom_synth_options so = LOOM_SYNTH_OPTIONS_INIT;
	so.algo = f->params.algo;
	so.seed = f->params.seed;
	so.group = f->params.group;
	so.flags = f->params.flags;
	return loom_synth_lookup_init(&f->lk, f->set, f->base, f->design->rows,
	                              f->design->cols, &so);
}

int loom__fabric_bind(loom_fabric *f, const loom_db *db, int check_hash,
                      const char *name, loom_diag *diag)
{
	loom_db_info info;
	int rc;

	if (!f || !db)
		return loom__fail(diag, LOOM_EINVAL, "%s: no database to bind to", name);
	loom_db_get_info(db, &info);
	if (check_hash && info.content_hash != f->db_hash)
		return loom__fail(diag, LOOM_EMISMATCH,
		                  "%s: made with database '%s' (content hash %016llx), "
		                  "but the database given has content hash %016llx",
		                  name, f->db_path, (unsigned long long)f->db_hash,
		                  (unsigned long long)info.content_hash);
	if (info.block[0] != f->b1 || info.block[1] != f->b2 ||
	    info.block[2] != f->b3 || info.n_exemplars != f->n_exemplars)
		return loom__fail(diag, LOOM_EMISMATCH,
		                  "%s: made for blocks %ux%ux%u and %u exemplars, the "
		                  "database has %ux%ux%u and %u", name, f->b1, f->b2, f->b3,
		                  f->n_exemplars, info.block[0], info.block[1],
		                  info.block[2], info.n_exemplars);
	rc = attach_db(f, db, name, diag);
	if (rc) {
		detach(f);
		return rc;
	}
	if (!f->ef) {
		uint32_t rh, rv;
		rc = loom_edgefix_build(&f->prof, f->params.rank, &f->ef, diag);
		if (rc) {
			detach(f);
			return rc;
		}
		edge_ranks(f->ef, &rh, &rv);
		if (rh != f->params.rank_h || rv != f->params.rank_v) {
			loom_edgefix_free(f->ef);
			f->ef = NULL;
			detach(f);
			return loom__fail(diag, LOOM_EMISMATCH,
			                  "%s: edge-fix ranks rebuilt as %u/%u, the file "
			                  "records %u/%u", name, rh, rv, f->params.rank_h,
			                  f->params.rank_v);
		}
	}
	if (corner_offsets(f) != LOOM_OK) {
		detach(f);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	}
	rc = init_lookup(f);
	if (rc) {
		detach(f);
		return loom__fail(diag, rc, "%s: lookup set-up failed", name);
	}
	f->attached = 1;
	return LOOM_OK;
}

/* ---- synthesis ----------------------------------------------------------- */

static int check_options(const loom_fabric_options *o, loom_diag *diag)
{
	if (o->size < sizeof *o)
		return loom__fail(diag, LOOM_EINVAL, "synth: options.size %zu, expected %zu "
		                  "(use LOOM_FABRIC_OPTIONS_INIT)", o->size, sizeof *o);
	if (o->algo < LOOM_SYNTH_NAIVE || o->algo > LOOM_SYNTH_IDENTITY)
		return loom__fail(diag, LOOM_EINVAL, "synth: unknown algorithm %d", o->algo);
	if (o->algo == LOOM_SYNTH_IDENTITY && (o->group || o->rank))
		return loom__fail(diag, LOOM_EINVAL, "synth: identity copies the ground truth "
		                  "unchanged: it needs group 0 and rank 0 (got %u, %u)",
		                  o->group, o->rank);
	if (o->group > 65536)
		return loom__fail(diag, LOOM_EINVAL, "synth: group %u, expected 0..65536",
		                  o->group);
	if (o->rank > LOOM_EDGEFIX_MAX_RANK)
		return loom__fail(diag, LOOM_EINVAL, "synth: rank %u, expected 0..%u",
		                  o->rank, LOOM_EDGEFIX_MAX_RANK);
	if (o->flags & ~(uint32_t)(LOOM_SYNTH_FULL_LISTS | LOOM_SYNTH_NO_HPREF))
		return loom__fail(diag, LOOM_EINVAL, "synth: unknown flags 0x%x", o->flags);
	if (o->window > LOOM_FABRIC_MAX_WINDOW)
		return loom__fail(diag, LOOM_EINVAL, "synth: window %u, expected 0..%u",
		                  o->window, LOOM_FABRIC_MAX_WINDOW);
	if (o->fibre[0] >= LOOM_FIBRE_COUNT_ || o->fibre[1] >= LOOM_FIBRE_COUNT_)
		return loom__fail(diag, LOOM_EINVAL, "synth: default materials %u, %u, "
		                  "expected 0..%d", o->fibre[0], o->fibre[1],
		                  LOOM_FIBRE_COUNT_ - 1);
	if (o->edge_storage > LOOM_FABRIC_EDGE_REBUILD)
		return loom__fail(diag, LOOM_EINVAL, "synth: edge_storage %u", o->edge_storage);
	return LOOM_OK;
}

/* Bytes of the edge-fix tables as the file stores them. */
static uint64_t edge_table_bytes(const loom_edgefix *ef)
{
	loom_edgefix_tables t;
	uint64_t cells, n;
	loom_edgefix_get_tables(ef, &t);
	cells = (uint64_t)t.b1 * t.b2;
	n = (uint64_t)t.n_blocks * (2u * t.rank_h + 2u * t.rank_v) +
	    cells * (t.rank_h + t.rank_v) + (uint64_t)t.b1 * t.rank_h +
	    (uint64_t)(t.b2 - 2) * t.rank_v + t.b1 + (t.b2 - 2);
	return 4 * n;
}

static void fabric_seam(loom_fabric *f, uint64_t rows, uint64_t cols);

static int compute_metrics(loom_fabric *f, uint32_t window, loom_diag *diag)
{
	int rc;

	f->usage = calloc(f->n_exemplars, sizeof *f->usage);
	if (!f->usage)
		return loom__fail(diag, LOOM_ENOMEM, "synth: out of memory");
	rc = loom_synth_metrics_repeat(f->set, f->design, f->base, f->usage,
	                               &f->m_repeat);
	if (rc)
		return loom__fail(diag, rc, "synth: metrics failed");
	f->win_rows = f->win_cols = window ? window : LOOM_FABRIC_DEFAULT_WINDOW;
	rc = loom_synth_metrics_window(f->set, f->design, &f->lk, 0, 0, f->win_rows,
	                               f->win_cols, NULL, &f->m_bolt);
	if (rc)
		return loom__fail(diag, rc, "synth: window metrics failed");
	fabric_seam(f, f->win_rows, f->win_cols);
	return LOOM_OK;
}

LOOM_API int loom_fabric_synthesize(const loom_design *d, const loom_db *db,
                                    const char *db_path,
                                    const loom_fabric_options *o,
                                    loom_fabric **out, loom_diag *diag)
{
	static const loom_fabric_options defaults = LOOM_FABRIC_OPTIONS_INIT;
	loom_synth_options so = LOOM_SYNTH_OPTIONS_INIT;
	loom_fabric *f;
	loom_db_info info;
	size_t n;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "synth: NULL output");
	*out = NULL;
	if (!d || !db)
		return loom__fail(diag, LOOM_EINVAL, "synth: NULL %s", d ? "database" : "design");
	if (!o)
		o = &defaults;
	rc = check_options(o, diag);
	if (!rc)
		rc = loom_design_validate(d, diag);
	if (rc)
		return rc;
	/* Step 1: copy the design. */
	f = loom__fabric_alloc();
	if (!f)
		return loom__fail(diag, LOOM_ENOMEM, "synth: out of memory");
	if (db_path) {
		free(f->db_path);
		f->db_path = strdup(db_path);
		if (!f->db_path) {
			loom_fabric_free(f);
			return loom__fail(diag, LOOM_ENOMEM, "synth: out of memory");
		}
	}
	rc = loom_design_clone(d, &f->design);
	n = (size_t)d->rows * d->cols;
	if (!rc && !(f->base = malloc(n * sizeof *f->base)))
		rc = LOOM_ENOMEM;
	if (rc) {
		loom_fabric_free(f);
		return loom__fail(diag, rc, "synth: out of memory copying a %ux%u design",
		                  d->rows, d->cols);
	}
	/* Step 2: database identity and tables. */
	loom_db_get_info(db, &info);
	f->db_hash = info.content_hash;
	f->b1 = info.block[0];
	f->b2 = info.block[1];
	f->b3 = info.block[2];
	f->voxel_size_um = info.voxel_size_um;
	f->n_exemplars = info.n_exemplars;
	f->params.algo = o->algo;
	f->params.seed = o->seed;
	f->params.group = o->group;
	f->params.rank = o->rank;
	f->params.flags = o->flags;
	rc = attach_db(f, db, "synth", diag);
	if (rc)
		goto fail;
	f->params.base_width = f->n_blocks <= 256 ? 1 : 2;
	/* Step 3: assignment and lookup. */
	so.algo = o->algo;
	so.seed = o->seed;
	so.group = o->group;
	so.flags = o->flags;
	{
		int done = 0;
		if (o->algo != LOOM_SYNTH_IDENTITY)
			rc = loom__fabric_assign_materials(f, db, &so, o->fibre, &done, diag);
		if (!rc && !done)
			rc = loom_synth_assign(f->set, f->design, &so, f->base, diag);
	}
	if (!rc)
		rc = init_lookup(f);
	if (rc)
		goto fail;
	/* Step 4: edge-fix tables. */
	rc = loom_edgefix_build(&f->prof, o->rank, &f->ef, diag);
	if (rc)
		goto fail;
	edge_ranks(f->ef, &f->params.rank_h, &f->params.rank_v);
	rc = corner_offsets(f);
	if (rc) {
		loom__fail(diag, rc, "fabric: out of memory");
		goto fail;
	}
	f->params.edge_stored =
		(o->edge_storage == LOOM_FABRIC_EDGE_STORE &&
		 edge_table_bytes(f->ef) + 32 <= LOOM__FABRIC_EDGE_MAX) ||
		(o->edge_storage == LOOM_FABRIC_EDGE_AUTO &&
		 edge_table_bytes(f->ef) <= LOOM_FABRIC_EDGE_STORE_MAX);
	/* Step 5: metrics. */
	rc = compute_metrics(f, o->window, diag);
	if (rc)
		goto fail;
	f->attached = 1;
	*out = f;
	return LOOM_OK;
fail:
	loom_fabric_free(f);
	return rc;
}

/* ---- accessors ----------------------------------------------------------- */

size_t loom__fabric_bytes(const loom_fabric *f)
{
	size_t n, b;
	if (!f)
		return 0;
	n = f->design ? (size_t)f->design->rows * f->design->cols : 0;
	b = sizeof *f + strlen(f->db_path) + 1;
	if (f->design)
		b += sizeof *f->design + 3 * n + sizeof(loom_yarn_type) * f->design->n_types;
	if (f->base)
		b += n * sizeof *f->base;
	b += loom_edgefix_bytes(f->ef);
	if (f->usage)
		b += sizeof *f->usage * f->n_exemplars;
	if (f->blocks)
		b += sizeof *f->blocks * (size_t)f->n_blocks;
	if (f->heights)
		b += sizeof(float) * LOOM_EDGE_RECORD(f->b1, f->b2) * (size_t)f->n_blocks;
	for (const loom__fabric_patch *p = f->patch; p; p = p->prev)
		b += sizeof *p + sizeof *f + 3 * (size_t)p->rows * p->cols;
	return b;
}


LOOM_API const loom_design *loom_fabric_design(const loom_fabric *f)
{
	return f ? f->design : NULL;
}

LOOM_API const loom_db *loom_fabric_db(const loom_fabric *f)
{
	return f && f->attached ? f->db : NULL;
}

LOOM_API int loom_fabric_attached(const loom_fabric *f)
{
	return f && f->attached;
}

LOOM_API int loom_fabric_get_params(const loom_fabric *f, loom_fabric_params *out)
{
	if (!f || !out)
		return LOOM_EINVAL;
	*out = f->params;
	return LOOM_OK;
}

LOOM_API int loom_fabric_get_db_identity(const loom_fabric *f,
                                         loom_fabric_db_identity *out)
{
	if (!f || !out)
		return LOOM_EINVAL;
	out->path = f->db_path;
	out->content_hash = f->db_hash;
	out->block[0] = f->b1;
	out->block[1] = f->b2;
	out->block[2] = f->b3;
	out->voxel_size_um = f->voxel_size_um;
	out->n_exemplars = f->n_exemplars;
	out->n_blocks = f->n_blocks;
	return LOOM_OK;
}

LOOM_API int loom_fabric_get_metrics(const loom_fabric *f, loom_fabric_metrics *out)
{
	if (!f || !out)
		return LOOM_EINVAL;
	out->repeat = f->m_repeat;
	out->bolt = f->m_bolt;
	out->seam = f->seam;
	out->window_rows = f->win_rows;
	out->window_cols = f->win_cols;
	out->n_exemplars = f->n_exemplars;
	out->usage = f->usage;
	return LOOM_OK;
}

LOOM_API int loom_fabric_repeat_voxels(const loom_fabric *f, uint64_t size[3])
{
	if (!f || !size)
		return LOOM_EINVAL;
	size[0] = (uint64_t)f->design->cols * f->b1;
	size[1] = (uint64_t)f->design->rows * f->b2;
	size[2] = f->b3;
	return LOOM_OK;
}

LOOM_API int loom_fabric_bolt_voxels(const loom_fabric *f, double length,
                                     double width, uint64_t size[3],
                                     double *total)
{
	uint64_t rep[3];
	double x, y;

	if (!f || !size || !isfinite(length) || !isfinite(width) || length <= 0 ||
	    width <= 0)
		return LOOM_EINVAL;
	loom_fabric_repeat_voxels(f, rep);
	x = ceil(width * (double)rep[0] - 1e-9);
	y = ceil(length * (double)rep[1] - 1e-9);
	if (x > 4.6e18 || y > 4.6e18)
		return LOOM_ERANGE;
	size[0] = x < 1 ? 1 : (uint64_t)x;
	size[1] = y < 1 ? 1 : (uint64_t)y;
	size[2] = rep[2];
	if (total)
		*total = (double)size[0] * (double)size[1] * (double)size[2];
	return LOOM_OK;
}

/* ---- lookups ------------------------------------------------------------- */

LOOM_API int loom_fabric_source_at(const loom_fabric *f, int64_t I, int64_t J,
                                   loom_fabric_source *out)
{
	loom__fabric_xing x;

	if (!f || !out)
		return LOOM_EINVAL;
	if (!f->attached)
		return LOOM_EUNUSABLE;
	loom__fabric_crossing(f, I, J, &x);
	memset(out, 0, sizeof *out); /* padding too: callers compare records */
	out->block = x.nb.self;
	out->exemplar = x.blk->exemplar;
	out->row = x.blk->row;
	out->col = x.blk->col;
	out->warp_over = x.warp_over;
	out->warp_type = x.warp_type;
	out->weft_type = x.weft_type;
	out->nbhd = x.nb;
	return LOOM_OK;
}

LOOM_API int loom_fabric_dz(const loom_fabric *f, int64_t I, int64_t J, float *dz)
{
	loom_synth_nbhd nb;

	if (!f || !dz)
		return LOOM_EINVAL;
	if (!f->attached)
		return LOOM_EUNUSABLE;
	loom__fabric_nbhd(f, I, J, &nb);
	loom__fabric_dz_block(f, &nb, dz);
	if (f->corner_off)
		for (int k = 0; k < 4; k++)
			dz[(size_t)loom__fabric_corner_y(f, k) * f->b1 + loom__fabric_corner_x(f, k)] =
				loom__fabric_corner_dz(f, I, J, k);
	return LOOM_OK;
}

LOOM_API int loom_fabric_corner_dz(const loom_fabric *f, int64_t I, int64_t J,
                                   float dz[4])
{
	if (!f || !dz)
		return LOOM_EINVAL;
	if (!f->attached)
		return LOOM_EUNUSABLE;
	if (f->corner_off) {
		for (int k = 0; k < 4; k++)
			dz[k] = loom__fabric_corner_dz(f, I, J, k);
	} else { /* no term: the edge fix's values there (0 at rank 0) */
		loom_synth_nbhd nb;
		loom__fabric_nbhd(f, I, J, &nb);
		for (int k = 0; k < 4; k++)
			dz[k] = loom_edgefix_at(f->ef, &nb, loom__fabric_corner_x(f, k),
			                        loom__fabric_corner_y(f, k));
	}
	return LOOM_OK;
}

/* The offset of column (x, y) of crossing (I, J), whose sources are nb. */
static float dz_at_ij(const loom_fabric *f, int64_t I, int64_t J,
                      const loom_synth_nbhd *nb, uint32_t x, uint32_t y)
{
	int k = loom__fabric_corner_of(f, x, y);
	return k >= 0 ? loom__fabric_corner_dz(f, I, J, k) : loom_edgefix_at(f->ef, nb, x, y);
}

/* dz_at_ij with the edge fix's value v of column (x, y) already known. */
static float corner_or(const loom_fabric *f, int64_t I, int64_t J, uint32_t x, uint32_t y,
                       float v)
{
	int k = loom__fabric_corner_of(f, x, y);
	return k >= 0 ? loom__fabric_corner_dz(f, I, J, k) : v;
}

/* Sides up to this many columns are evaluated a side at a time. */
#define SEAM_SIDE 1024u

/* The seam metric of the fabric as it is looked up: |height jump| across
   the S and E edges of blocks, without the fix (profiles alone) and with
   the offsets a lookup applies (the edge fix and the corner term).  The
   same definition as loom_edgefix_seam / _seam_block, which know only the
   edge fix: with the corner term the four corner columns of every block
   take loom__fabric_corner_dz instead.  fabric_seam_one adds the S edge
   of crossing (I, J) to se and its E edge to ee. */
static void fabric_seam_one(const loom_fabric *f, int64_t I, int64_t J,
                            loom__seam_acc *se, loom__seam_acc *ee)
{
	loom_synth_nbhd a, below, right;
	uint32_t b1 = f->b1, b2 = f->b2;
	const float *hs, *hb, *hr;

	loom__fabric_nbhd(f, I, J, &a);
	loom__fabric_nbhd(f, I + 1, J, &below);
	loom__fabric_nbhd(f, I, J + 1, &right);
	hs = f->heights + (size_t)a.self * LOOM_EDGE_RECORD(b1, b2);
	hb = f->heights + (size_t)below.self * LOOM_EDGE_RECORD(b1, b2);
	hr = f->heights + (size_t)right.self * LOOM_EDGE_RECORD(b1, b2);
	if (b1 <= SEAM_SIDE && b2 <= SEAM_SIDE && f->ef) {
		/* each side's offsets from one coefficient vector (the same
		   values), the corner columns from the corner term */
		float s0[SEAM_SIDE], s1[SEAM_SIDE];
		loom__edgefix_side(f->ef, &a, 1, s0);
		loom__edgefix_side(f->ef, &below, 0, s1);
		for (uint32_t x = 0; x < b1; x++) {
			double h0 = hs[LOOM_EDGE_S(b1, b2) + x], h1 = hb[LOOM_EDGE_N(b1, b2) + x];
			double d0 = corner_or(f, I, J, x, b2 - 1, s0[x]);
			double d1 = corner_or(f, I + 1, J, x, 0, s1[x]);
			loom__seam_add(se, h0 - h1, (h0 + d0) - (h1 + d1), 0);
		}
		loom__edgefix_side(f->ef, &a, 3, s0);
		loom__edgefix_side(f->ef, &right, 2, s1);
		for (uint32_t y = 0; y < b2; y++) {
			double h0 = hs[LOOM_EDGE_E(b1, b2) + y], h1 = hr[LOOM_EDGE_W(b1, b2) + y];
			double d0 = corner_or(f, I, J, b1 - 1, y, s0[y]);
			double d1 = corner_or(f, I, J + 1, 0, y, s1[y]);
			loom__seam_add(ee, h0 - h1, (h0 + d0) - (h1 + d1), y == 0 || y == b2 - 1);
		}
		return;
	}
	for (uint32_t x = 0; x < b1; x++) {
		double h0 = hs[LOOM_EDGE_S(b1, b2) + x], h1 = hb[LOOM_EDGE_N(b1, b2) + x];
		double d0 = dz_at_ij(f, I, J, &a, x, b2 - 1);
		double d1 = dz_at_ij(f, I + 1, J, &below, x, 0);
		loom__seam_add(se, h0 - h1, (h0 + d0) - (h1 + d1), 0);
	}
	for (uint32_t y = 0; y < b2; y++) {
		double h0 = hs[LOOM_EDGE_E(b1, b2) + y], h1 = hr[LOOM_EDGE_W(b1, b2) + y];
		double d0 = dz_at_ij(f, I, J, &a, b1 - 1, y);
		double d1 = dz_at_ij(f, I, J + 1, &right, 0, y);
		loom__seam_add(ee, h0 - h1, (h0 + d0) - (h1 + d1), y == 0 || y == b2 - 1);
	}
}

/* f->seam over the crossings [0, rows) x [0, cols) (compute_metrics). */
static void fabric_seam(loom_fabric *f, uint64_t rows, uint64_t cols)
{
	loom__seam_acc acc;

	memset(&acc, 0, sizeof acc);
	for (uint64_t a = 0; a < rows; a++)
		for (uint64_t b = 0; b < cols; b++)
			fabric_seam_one(f, (int64_t)a, (int64_t)b, &acc, &acc);
	loom__seam_finish(&acc, f->internal_step, &f->seam);
}

/* The same definition as loom_edgefix_seam_block (|height jump| means along
   the S and E edges), with the corner term, and without its per-call
   profile scan: a seam picture calls it for every crossing. */
LOOM_API int loom_fabric_seam_block(const loom_fabric *f, int64_t I, int64_t J,
                                    double out[4])
{
	loom__seam_acc se, ee;

	if (!f || !out)
		return LOOM_EINVAL;
	if (!f->attached)
		return LOOM_EUNUSABLE;
	memset(&se, 0, sizeof se);
	memset(&ee, 0, sizeof ee);
	fabric_seam_one(f, I, J, &se, &ee);
	out[0] = se.sum_b / f->b1;
	out[1] = se.sum_a / f->b1;
	out[2] = ee.sum_b / f->b2;
	out[3] = ee.sum_a / f->b2;
	return LOOM_OK;
}

/* ---- names --------------------------------------------------------------- */

static const char *const algo_names[] = {"naive", "greedy", "dp", "identity"};

LOOM_API const char *loom_fabric_algo_name(int algo)
{
	return algo >= 0 && algo <= LOOM_SYNTH_IDENTITY ? algo_names[algo] : "?";
}

LOOM_API int loom_fabric_algo_parse(const char *name, int *algo)
{
	if (!name || !algo)
		return LOOM_EINVAL;
	for (int k = 0; k <= LOOM_SYNTH_IDENTITY; k++)
		if (strcmp(name, algo_names[k]) == 0) {
			*algo = k;
			return LOOM_OK;
		}
	return LOOM_EINVAL;
}
