/*
 * tests/unit/test_texture.c - the virtual texture (loom/texture.h) against a
 * brute-force materialisation built from first principles in this file:
 * the base assignment and randomisation from the synth API
 * (loom_synth_assign, loom_synth_src), the edge-fix offsets from
 * loom_edgefix_build + loom_edgefix_block, the source voxels from
 * loom_db_read_box, yarn kinds from the exemplar yarn tables and types and
 * albedo from the design.  Nothing of engine/texture/ is reused except
 * where a test says so.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"
#include "raise_block.h"
#include "synth/fabric_internal.h"
#include "texture/texture_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char db_path[4200], db2_path[4200], db_np2_path[4200];

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static uint64_t rng_state;
static uint64_t rnd(void)
{
	return mix(rng_state++);
}
static int64_t rnd_range(int64_t lo, int64_t hi) /* [lo, hi) */
{
	return lo + (int64_t)(rnd() % (uint64_t)(hi - lo));
}

/* ------------------------------------------------------------- fixture */

static int make_db_block(const char *path, const char *preset, const uint32_t brick[3],
                         uint64_t seed, const uint32_t block[3])
{
	loom_exgen_params p;
	loom_diag d = {0};
	int rc = loom_exgen_preset(preset, &p);
	if (rc)
		return rc;
	p.seed = seed;
	p.threads = 2;
	if (brick)
		memcpy(p.brick, brick, sizeof p.brick);
	if (block) { /* wide blocks, two weaves: a small file */
		memcpy(p.block, block, sizeof p.block);
		p.n_weaves = 2;
	}
	rc = loom_exgen_write_db(path, &p, NULL, &d);
	if (rc)
		printf("  exgen: %s\n", d.message);
	return rc;
}

static int make_db(const char *path, const char *preset, const uint32_t brick[3],
                   uint64_t seed)
{
	return make_db_block(path, preset, brick, seed, NULL);
}

/* A random M x N design with three yarn types of distinct colours. */
static loom_design *random_design(uint32_t M, uint32_t N, uint64_t seed)
{
	loom_design *d = NULL;
	if (loom_design_new(M, N, &d) || loom_design_set_types(d, 3))
		return NULL;
	for (size_t i = 0; i < (size_t)M * N; i++) {
		uint64_t h = mix(seed * 1000003u + i);
		d->weave[i] = h & 1;
		d->warp_type[i] = (uint8_t)(h >> 8 & 1);       /* 0 or 1 */
		d->weft_type[i] = (uint8_t)(1 + (h >> 16 & 1)); /* 1 or 2 */
	}
	for (uint32_t k = 0; k < 3; k++) {
		d->types[k].albedo[0] = 0.1f + 0.3f * k;
		d->types[k].albedo[1] = 0.9f - 0.2f * k;
		d->types[k].albedo[2] = 0.05f * (k + 1);
		d->types[k].alignment = 0.1f * (k + 1);
	}
	return d;
}

static uint32_t g_rank; /* edge-fix rank of synth(); 0: the default */

static loom_fabric *synth(const loom_design *d, loom_db *db)
{
	loom_fabric *f = NULL;
	loom_diag dg = {0};
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	if (g_rank)
		o.rank = g_rank;
	if (loom_fabric_synthesize(d, db, db_path, &o, &f, &dg)) {
		printf("  synthesize: %s\n", dg.message);
		return NULL;
	}
	return f;
}

static loom_texture *open_tex(const loom_fabric *f, const loom_db *db, size_t budget,
                              unsigned threads)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag d = {0};
	o.budget_bytes = budget;
	o.max_threads = threads;
	if (loom_texture_open(f, db, &o, &t, &d))
		printf("  texture open: %s\n", d.message);
	return t;
}

/* The smallest budget that opens (from the EBUDGET message). */
static size_t min_budget(const loom_fabric *f, const loom_db *db, unsigned threads)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag d = {0};
	const char *p;
	o.budget_bytes = 1;
	o.max_threads = threads;
	if (loom_texture_open(f, db, &o, &t, &d) != LOOM_EBUDGET) {
		loom_texture_close(t);
		return 0;
	}
	p = strstr(d.message, "needs at least ");
	return p ? (size_t)strtoull(p + 15, NULL, 10) : 0;
}

/* ------------------------------------------------------------ reference */

typedef struct ref {
	const loom_db *db;
	const loom_design *d;
	uint32_t b1, b2, b3, n_ex;
	uint32_t solid;      /* top_threshold, at least 1 */
	loom_synth_set *set;
	uint16_t *base;
	loom_synth_lookup lk;
	loom_edgefix *ef;
	float *heights;
	loom_db_exemplar_info *ex;
	uint8_t **dens, **lab;
	uint16_t **ori;
	int64_t cI, cJ;      /* crossing of dz */
	float *dz;
	uint64_t n_dz_blocks;
	uint32_t rank;       /* the fabric's edge-fix rank (0: no fix, no corners) */
} ref;

static int ref_init(ref *r, const loom_fabric *f, const loom_db *db)
{
	loom_fabric_params fp;
	loom_synth_options so = LOOM_SYNTH_OPTIONS_INIT;
	loom_synth_exemplar *se;
	loom_edge_profiles prof;
	loom_db_info info;
	uint32_t K, rec;

	memset(r, 0, sizeof *r);
	r->db = db;
	r->d = loom_fabric_design(f);
	loom_db_get_info(db, &info);
	r->b1 = info.block[0];
	r->b2 = info.block[1];
	r->b3 = info.block[2];
	r->solid = info.top_threshold ? info.top_threshold : 1;
	r->n_ex = info.n_exemplars;
	r->ex = calloc(r->n_ex, sizeof *r->ex);
	se = calloc(r->n_ex, sizeof *se);
	r->dens = calloc(r->n_ex, sizeof *r->dens);
	r->lab = calloc(r->n_ex, sizeof *r->lab);
	r->ori = calloc(r->n_ex, sizeof *r->ori);
	for (uint32_t u = 0; u < r->n_ex; u++) {
		uint32_t o[3] = {0, 0, 0};
		size_t n;
		loom_db_exemplar(db, u, &r->ex[u]);
		se[u].rows = r->ex[u].rows;
		se[u].cols = r->ex[u].cols;
		se[u].weave = r->ex[u].weave;
		se[u].periodic = 0;
		n = (size_t)r->ex[u].size[0] * r->ex[u].size[1] * r->ex[u].size[2];
		r->dens[u] = malloc(n);
		r->lab[u] = malloc(n);
		r->ori[u] = malloc(2 * n);
		if (loom_db_read_box(db, u, o, r->ex[u].size, r->dens[u], r->ori[u], r->lab[u],
		                     NULL))
			return -1;
	}
	if (loom_synth_set_new(se, r->n_ex, &r->set, NULL))
		return -1;
	free(se);
	loom_fabric_get_params(f, &fp);
	so.algo = fp.algo;
	so.seed = fp.seed;
	so.group = fp.group;
	so.flags = fp.flags;
	r->base = malloc(sizeof *r->base * r->d->rows * r->d->cols);
	if (loom_synth_assign(r->set, r->d, &so, r->base, NULL) ||
	    loom_synth_lookup_init(&r->lk, r->set, r->base, r->d->rows, r->d->cols, &so))
		return -1;
	K = loom_synth_set_blocks(r->set);
	rec = LOOM_EDGE_RECORD(r->b1, r->b2);
	r->heights = malloc(sizeof(float) * rec * K);
	for (uint32_t t = 0; t < K; t++) {
		loom_synth_block sb;
		loom_db_block_info bi;
		float *h = r->heights + (size_t)t * rec;
		loom_synth_block_info(r->set, t, &sb);
		loom_db_block(db, sb.exemplar, sb.row, sb.col, &bi);
		memcpy(h + LOOM_EDGE_N(r->b1, r->b2), bi.north, 4 * r->b1);
		memcpy(h + LOOM_EDGE_S(r->b1, r->b2), bi.south, 4 * r->b1);
		memcpy(h + LOOM_EDGE_W(r->b1, r->b2), bi.west, 4 * r->b2);
		memcpy(h + LOOM_EDGE_E(r->b1, r->b2), bi.east, 4 * r->b2);
	}
	prof.b1 = r->b1;
	prof.b2 = r->b2;
	prof.n_blocks = K;
	prof.heights = r->heights;
	prof.set = r->set; /* as the fabric builds it */
	if (loom_edgefix_build(&prof, fp.rank, &r->ef, NULL))
		return -1;
	r->rank = fp.rank;
	r->dz = malloc(sizeof(float) * r->b1 * r->b2);
	r->cI = INT64_MIN;
	return 0;
}

static void ref_free(ref *r)
{
	for (uint32_t u = 0; u < r->n_ex; u++) {
		free(r->dens[u]);
		free(r->lab[u]);
		free(r->ori[u]);
	}
	free(r->dens);
	free(r->lab);
	free(r->ori);
	free(r->ex);
	free(r->base);
	free(r->heights);
	free(r->dz);
	loom_edgefix_free(r->ef);
	loom_synth_set_free(r->set);
}

static int64_t floor_div(int64_t a, int64_t b)
{
	int64_t q = a / b;
	return (a % b != 0 && a < 0) ? q - 1 : q;
}

/* Expected raw voxel: density byte, orientation code, label; kind, type. */
typedef struct rv {
	uint8_t d, l, k, ty;
	uint16_t o;
} rv;

/* Source voxel zs of column (lx, ly) of crossing (I, J), straight from
   the exemplar arrays; empty outside [0, b3). */
static rv ref_src(ref *r, int64_t I, int64_t J, uint32_t lx, uint32_t ly, int64_t zs)
{
	rv v = {0, 0, 0, 0, 0};
	loom_synth_block sb;
	const loom_db_exemplar_info *e;
	uint32_t sx, sy;
	size_t i, cell;
	uint16_t t;

	if (zs < 0 || zs >= r->b3)
		return v;
	t = loom_synth_src(&r->lk, I, J);
	loom_synth_block_info(r->set, t, &sb);
	e = &r->ex[sb.exemplar];
	sx = sb.col * r->b1 + lx;
	sy = sb.row * r->b2 + ly;
	i = ((size_t)zs * e->size[1] + sy) * e->size[0] + sx;
	v.d = r->dens[sb.exemplar][i];
	v.o = r->ori[sb.exemplar][i];
	v.l = r->lab[sb.exemplar][i];
	v.k = v.l <= e->n_yarns ? e->yarns[v.l].kind : 0;
	cell = (size_t)(((I % r->d->rows) + r->d->rows) % r->d->rows) * r->d->cols +
	       (size_t)(((J % r->d->cols) + r->d->cols) % r->d->cols);
	v.ty = v.k == LOOM_YARN_WARP ? r->d->warp_type[cell] :
	       v.k == LOOM_YARN_WEFT ? r->d->weft_type[cell] : 0;
	return v;
}

/* The documented offset in 1/16 voxel: dz clamped to +-2047, times 16,
   rounded (halves away from zero). */
static long ref_dz16(float dz)
{
	if (dz != dz)
		return 0;
	if (dz >= 2047.0f)
		return 2047 * 16;
	if (dz <= -2047.0f)
		return -2047 * 16;
	return lroundf(dz * 16.0f);
}

/* Height of the corner column c (0 NW, 1 NE, 2 SW, 3 SE) of exemplar u's
   block (row, col), from the database's profiles; NAN outside the
   exemplar. */
static float ref_corner_h(const ref *r, uint32_t u, int64_t row, int64_t col, int c)
{
	loom_db_block_info bi;
	uint32_t x = (c & 1) ? r->b1 - 1 : 0;
	if (row < 0 || col < 0 || row >= r->ex[u].rows || col >= r->ex[u].cols ||
	    loom_db_block(r->db, u, (uint32_t)row, (uint32_t)col, &bi))
		return NAN;
	return c < 2 ? bi.north[x] : bi.south[x];
}

/* The corner term written out (docs/synthesis.md, "Block corners"): the
   four crossings meeting at corner k of (I, J) take the mean of their
   corrected corner heights, each plus its source corner's offset from the
   mean of the four corner columns around it in its exemplar (read from the
   database's blocks, 0 where the exemplar ends). */
/* The woven corner offset of set block t at its corner c; 0 and *inside
   = 0 when the corner is on its exemplar's border. */
static float ref_woven_off(const ref *r, uint32_t t, int c, int *inside)
{
	loom_synth_block sb;
	int64_t vr = c < 2 ? -1 : 1, hc = (c & 1) ? 1 : -1;
	float h, v, hz, d;
	loom_synth_block_info(r->set, t, &sb);
	h = ref_corner_h(r, sb.exemplar, sb.row, sb.col, c);
	v = ref_corner_h(r, sb.exemplar, (int64_t)sb.row + vr, sb.col, c ^ 2);
	hz = ref_corner_h(r, sb.exemplar, sb.row, (int64_t)sb.col + hc, c ^ 1);
	d = ref_corner_h(r, sb.exemplar, (int64_t)sb.row + vr, (int64_t)sb.col + hc, c ^ 3);
	*inside = !(isnan(v) || isnan(hz) || isnan(d));
	return *inside ? h - 0.25f * (h + v + hz + d) : 0;
}

static float ref_corner_dz(const ref *r, int64_t I, int64_t J, int k)
{
	int64_t di = k < 2 ? -1 : 1, dj = (k & 1) ? 1 : -1;
	int64_t ci[4] = {I, I + di, I, I + di}, cj[4] = {J, J, J + dj, J + dj};
	float H[4], o[4], own = 0, mh, mo;
	for (int m = 0; m < 4; m++) {
		int c = m == 0 ? k : m == 1 ? k ^ 2 : m == 2 ? k ^ 1 : k ^ 3;
		uint32_t x = (c & 1) ? r->b1 - 1 : 0, y = (c & 2) ? r->b2 - 1 : 0;
		loom_synth_nbhd nb;
		loom_synth_block sb;
		float h;
		int inside;
		loom_synth_nbhd_at(&r->lk, ci[m], cj[m], &nb);
		loom_synth_block_info(r->set, nb.self, &sb);
		h = ref_corner_h(r, sb.exemplar, sb.row, sb.col, c);
		o[m] = ref_woven_off(r, nb.self, c, &inside);
		H[m] = h + loom_edgefix_at(r->ef, &nb, x, y);
		if (m == 0)
			own = h;
	}
	mh = 0.25f * ((H[0] + H[1]) + (H[2] + H[3]));
	mo = 0.25f * ((o[0] + o[1]) + (o[2] + o[3]));
	return (mh + (o[0] - mo)) - own;
}

/* The offset map of crossing (I, J): the edge fix's, the corner term at
   the four corners (with a fix). */
static void ref_dz_block(const ref *r, int64_t I, int64_t J, float *dz)
{
	loom_synth_nbhd nb;
	loom_synth_nbhd_at(&r->lk, I, J, &nb);
	loom_edgefix_block(r->ef, &nb, dz);
	if (r->rank)
		for (int k = 0; k < 4; k++)
			dz[((k & 2) ? r->b2 - 1 : 0) * r->b1 + ((k & 1) ? r->b1 - 1 : 0)] =
				ref_corner_dz(r, I, J, k);
}

/* Whether no voxel above source voxel zn of the column up to the next
   multiple of 16 or the block's top, whichever comes first, is solid
   (density byte at least the database's top_threshold; docs/engine.md),
   whatever the brick shape. */
static int ref_seg_top(ref *r, int64_t I, int64_t J, uint32_t lx, uint32_t ly, int64_t zn)
{
	int64_t end = (zn / 16 + 1) * 16;
	if (r->b3 < end)
		end = r->b3;
	for (int64_t z = zn + 1; z < end; z++)
		if (ref_src(r, I, J, lx, ly, z).d >= r->solid)
			return 0;
	return 1;
}

static rv ref_raw(ref *r, int64_t x, int64_t y, int64_t z)
{
	rv v = {0, 0, 0, 0, 0}, a, b;
	int64_t I, J;
	uint32_t lx, ly;
	long q, f, w;

	if (z < 0 || z >= r->b3)
		return v;
	I = floor_div(y, r->b2);
	J = floor_div(x, r->b1);
	lx = (uint32_t)(x - J * r->b1);
	ly = (uint32_t)(y - I * r->b2);
	if (I != r->cI || J != r->cJ) {
		ref_dz_block(r, I, J, r->dz);
		r->cI = I;
		r->cJ = J;
		r->n_dz_blocks++;
	}
	/* source height z - q/16: voxels z - w - 1 (weight f/16) and z - w */
	q = ref_dz16(r->dz[ly * r->b1 + lx]);
	f = ((q % 16) + 16) % 16;
	w = (q - f) / 16;
	b = ref_src(r, I, J, lx, ly, z - w);
	if (f == 0)
		return b;
	a = ref_src(r, I, J, lx, ly, z - w - 1);
	/* the nearer voxel (b on a tie) decides: empty where it is empty;
	   else its planes and density, but where the other is empty and
	   nothing solid lies above the nearer in its segment (the top of a
	   surface) the density is the linear blend, rounded */
	{
		rv near = f > 8 ? a : b, other = f > 8 ? b : a;
		uint8_t d = (uint8_t)((a.d * f + b.d * (16 - f) + 8) / 16);
		v = near;
		if (near.d && !other.d && ref_seg_top(r, I, J, lx, ly, f > 8 ? z - w - 1 : z - w))
			v.d = d;
	}
	return v;
}

static loom_texel ref_texel(ref *r, int64_t x, int64_t y, int64_t z)
{
	rv v = ref_raw(r, x, y, z);
	loom_texel t;
	memset(&t, 0, sizeof t);
	if (v.d) {
		t.density = v.d / 255.0f;
		loom_orientation_decode(v.o, t.orientation);
	}
	t.label = v.l;
	t.kind = v.k;
	if (v.k) {
		t.type = v.ty;
		memcpy(t.albedo, r->d->types[v.ty].albedo, sizeof t.albedo);
		t.alignment = r->d->types[v.ty].alignment;
	}
	return t;
}

static int texel_eq(const loom_texel *a, const loom_texel *b)
{
	return a->density == b->density && a->orientation[0] == b->orientation[0] &&
	       a->orientation[1] == b->orientation[1] &&
	       a->orientation[2] == b->orientation[2] && a->albedo[0] == b->albedo[0] &&
	       a->albedo[1] == b->albedo[1] && a->albedo[2] == b->albedo[2] &&
	       a->alignment == b->alignment && a->kind == b->kind && a->type == b->type &&
	       a->label == b->label;
}

/* ------------------------------------------------------------- globals */

static loom_db *g_db;
static loom_design *g_design;
static loom_fabric *g_fab;
static ref g_ref;
static int g_ok;

/* Compare every voxel of a box (x fastest, or a random order) through
   loom_texture_voxel; returns mismatches. */
static uint64_t check_box(loom_texture *t, ref *r, const int64_t lo[3],
                          const int64_t hi[3], int shuffled, uint64_t *nonempty)
{
	uint64_t bad = 0, n = (uint64_t)(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
	for (uint64_t k = 0; k < n; k++) {
		uint64_t i = shuffled ? rnd() % n : k;
		int64_t x = lo[0] + (int64_t)(i % (uint64_t)(hi[0] - lo[0]));
		int64_t y = lo[1] + (int64_t)(i / (uint64_t)(hi[0] - lo[0]) % (uint64_t)(hi[1] - lo[1]));
		int64_t z = lo[2] + (int64_t)(i / (uint64_t)(hi[0] - lo[0]) / (uint64_t)(hi[1] - lo[1]));
		loom_texel a, b = ref_texel(r, x, y, z);
		int rc = loom_texture_voxel(t, x, y, z, &a);
		if (rc != LOOM_OK || !texel_eq(&a, &b)) {
			if (bad < 3)
				printf("  voxel (%lld,%lld,%lld): rc %d density %g/%g kind %d/%d "
				       "type %d/%d label %d/%d orient %g,%g,%g/%g,%g,%g albedo %g/%g\n",
				       (long long)x, (long long)y, (long long)z, rc, a.density,
				       b.density, a.kind, b.kind, a.type, b.type, a.label, b.label,
				       a.orientation[0], a.orientation[1], a.orientation[2],
				       b.orientation[0], b.orientation[1], b.orientation[2],
				       a.albedo[0], b.albedo[0]);
			bad++;
		}
		if (nonempty && b.density > 0)
			(*nonempty)++;
	}
	return bad;
}

/* ---------------------------------------------------------------- tests */

static void setup(void)
{
	const uint32_t brick[3] = {4, 4, 8};
	const uint32_t brick_np2[3] = {3, 5, 7};

	if (tmpdir_make())
		return;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	snprintf(db2_path, sizeof db2_path, "%s/tiny2.ldb", tmpdir);
	snprintf(db_np2_path, sizeof db_np2_path, "%s/np2.ldb", tmpdir);
	CHECK_EQ_INT(make_db(db_path, "tiny", brick, 1), LOOM_OK);
	CHECK_EQ_INT(make_db(db2_path, "tiny", brick, 2), LOOM_OK);
	CHECK_EQ_INT(make_db(db_np2_path, "tiny", brick_np2, 1), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(db_path, &g_db, NULL), LOOM_OK);
	g_design = random_design(7, 9, 3);
	CHECK(g_design != NULL);
	if (!g_db || !g_design)
		return;
	g_fab = synth(g_design, g_db);
	CHECK(g_fab != NULL);
	if (!g_fab)
		return;
	CHECK_EQ_INT(ref_init(&g_ref, g_fab, g_db), 0);
	g_ok = check_fail_count == 0;
}

static void bad_arguments(void)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = (loom_texture *)1;
	loom_db *db2 = NULL;
	loom_diag d = {0};
	loom_texel tx;
	int64_t lo[3] = {0, 0, 0}, hi[3] = {2, 2, 2};
	loom_texture_region reg = {0};
	double p[3] = {1, 2, 3};
	uint8_t buf[8];

	if (!g_ok)
		return;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, NULL, NULL, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_open(NULL, g_db, NULL, &t, &d), LOOM_EINVAL);
	CHECK(t == NULL);
	o.size = 4;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &t, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "options.size");
	o.size = sizeof o;
	o.max_threads = LOOM_TEXTURE_MAX_THREADS + 1;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &t, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "max_threads");
	/* another database (other seed): identity mismatch */
	CHECK_EQ_INT(loom_db_open(db2_path, &db2, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_texture_open(g_fab, db2, NULL, &t, &d), LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(d.message, "content hash");
	CHECK(t == NULL);
	loom_db_close(db2);
	/* a detached fabric cannot be looked up */
	{
		char fpath[4300];
		loom_fabric *det = NULL;
		snprintf(fpath, sizeof fpath, "%s/f.lfab", tmpdir);
		if (loom_fabric_save(g_fab, fpath, NULL, NULL) == LOOM_OK &&
		    loom_fabric_open(fpath, NULL, LOOM_FABRIC_OPEN_DETACHED, &det, NULL) ==
		            LOOM_OK) {
			CHECK_EQ_INT(loom_texture_open(det, g_db, NULL, &t, &d), LOOM_EUNUSABLE);
			CHECK_STR_CONTAINS(d.message, "detached");
			loom_fabric_free(det);
		} else {
			printf("  (fabric save/open unavailable: detached case skipped)\n");
		}
	}
	/* db NULL: the fabric's own database */
	CHECK_EQ_INT(loom_texture_open(g_fab, NULL, NULL, &t, &d), LOOM_OK);
	CHECK_EQ_INT(loom_texture_voxel(NULL, 0, 0, 0, &tx), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_voxel(t, 0, 0, 0, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_voxel(t, (int64_t)1 << 62, 0, 0, &tx), LOOM_ERANGE);
	CHECK_EQ_INT(loom_texture_voxel(t, 0, INT64_MIN, 0, &tx), LOOM_ERANGE);
	CHECK_EQ_INT(loom_texture_voxel(t, 0, 0, INT64_MAX, &tx), LOOM_ERANGE);
	CHECK(tx.density == 0 && tx.kind == 0);
	CHECK_EQ_INT(loom_texture_voxel(t, 0, 0, -1, &tx), LOOM_OK); /* empty */
	CHECK(tx.density == 0 && tx.kind == 0 && tx.orientation[0] == 0);
	CHECK_EQ_INT(loom_texture_sample(t, p, 7, &tx), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_sample(t, NULL, 0, &tx), LOOM_EINVAL);
	p[1] = NAN;
	CHECK_EQ_INT(loom_texture_sample(t, p, 0, &tx), LOOM_EINVAL);
	p[1] = 1e300;
	CHECK_EQ_INT(loom_texture_sample(t, p, 1, &tx), LOOM_ERANGE);
	CHECK_EQ_INT(loom_texture_sample_batch(t, 1, NULL, p, p, 0,
	                                       &(loom_texture_channels){0}), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_sample_batch(t, 0, NULL, NULL, NULL, 0,
	                                       &(loom_texture_channels){0}), LOOM_OK);
	CHECK_EQ_INT(loom_texture_sample_batch(t, 0, NULL, NULL, NULL, 0, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, NULL), LOOM_EINVAL);
	reg.layout = 2;
	CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_EINVAL);
	reg.layout = LOOM_REGION_Z_FASTEST;
	CHECK_EQ_INT(loom_texture_read_region(NULL, lo, hi, &reg), LOOM_EINVAL);
	hi[1] = -1;
	CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_EINVAL);
	hi[1] = 0; /* empty box */
	reg.density = buf;
	memset(buf, 0xAA, sizeof buf);
	CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_OK);
	CHECK(buf[0] == 0xAA);
	hi[1] = (int64_t)1 << 62;
	CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_ERANGE);
	lo[0] = -((int64_t)1 << 61);
	hi[0] = (int64_t)1 << 61;
	hi[1] = (int64_t)1 << 61;
	CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_ERANGE); /* size */
	CHECK_EQ_INT(loom_texture_get_stats(t, NULL), LOOM_EINVAL);
	CHECK_STR_CONTAINS(loom_texture_errmsg(NULL), "NULL");
	CHECK_EQ_INT((int)strlen(loom_texture_errmsg(t)), 0);
	loom_texture_thread_done(NULL);
	loom_texture_thread_done(t);
	loom_texture_thread_done(t); /* no state: no-op */
	CHECK_EQ_INT(loom_texture_voxel(t, 0, 0, 3, &tx), LOOM_OK); /* new state */
	loom_texture_close(t);
	loom_texture_close(NULL);
}

static void budget_too_small(void)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_texture_stats st;
	loom_diag d = {0};
	size_t need;

	if (!g_ok)
		return;
	o.budget_bytes = 100;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &t, &d), LOOM_EBUDGET);
	CHECK_STR_CONTAINS(d.message, "needs at least");
	CHECK(t == NULL);
	for (unsigned threads = 1; threads <= 16; threads *= 4) {
		need = min_budget(g_fab, g_db, threads);
		CHECK(need > 0);
		o.max_threads = threads;
		o.budget_bytes = need - 1;
		CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &t, &d), LOOM_EBUDGET);
		o.budget_bytes = need;
		CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &t, &d), LOOM_OK);
		if (!t)
			continue;
		CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
		CHECK(st.budget_bytes == need);
		/* the design and base assignment (5 bytes a crossing) count */
		CHECK(st.fixed_bytes >= 5 * (uint64_t)loom_fabric_design(g_fab)->rows *
		                                loom_fabric_design(g_fab)->cols);
		CHECK_EQ_INT(st.max_threads, threads);
		/* T + 1 cache threads, each with one reserved frame, + 1 */
		CHECK(st.cache_frames >= threads + 2);
		CHECK(st.cache_frames <= 2 * (threads + 2));
		printf("  %u threads: minimum budget %zu bytes, %u frames of %llu bytes, "
		       "fixed %llu\n", threads, need, st.cache_frames,
		       (unsigned long long)st.brick_bytes, (unsigned long long)st.fixed_bytes);
		loom_texture_close(t);
		t = NULL;
	}
}

static void orient_blend_no_cancel(void)
{
	float w[3] = {0.5f, 0.5f, 0}, v[3][3], out[3], naive[3];
	float n = sqrtf(1.0f + 0.05f * 0.05f);

	/* two lines nearly along x, tilted opposite ways: as stored (z >= 0)
	   they point in opposite x directions, so a plain average cancels */
	v[0][0] = 1 / n, v[0][1] = 0, v[0][2] = 0.05f / n;
	v[1][0] = -1 / n, v[1][1] = 0, v[1][2] = 0.05f / n;
	v[2][0] = 0, v[2][1] = 0, v[2][2] = 1;
	for (int a = 0; a < 3; a++)
		naive[a] = 0.5f * (v[0][a] + v[1][a]);
	CHECK(fabsf(naive[0]) < 1e-6f && naive[2] > 0); /* naive: vertical */
	loom__orient_blend(3, w, (const float(*)[3])v, out);
	CHECK(fabsf(out[0]) > 0.9999f); /* blend: along x */
	CHECK(fabsf(out[2]) < 1e-6f);
	CHECK(out[0] > 0); /* folded: z == 0, y == 0 -> x >= 0 */
	/* v and -v with different weights: the line itself */
	w[0] = 0.2f, w[1] = 0.8f;
	v[1][0] = -v[0][0], v[1][1] = -v[0][1], v[1][2] = -v[0][2];
	loom__orient_blend(2, w, (const float(*)[3])v, out);
	for (int a = 0; a < 3; a++)
		CHECK(fabsf(out[a] - v[0][a]) < 1e-6f);
	/* zero weights -> zeros; one entry -> itself (folded) */
	w[0] = w[1] = 0;
	loom__orient_blend(2, w, (const float(*)[3])v, out);
	CHECK(out[0] == 0 && out[1] == 0 && out[2] == 0);
	w[1] = 1;
	loom__orient_blend(2, w, (const float(*)[3])v, out);
	CHECK(fabsf(out[0] - v[0][0]) < 1e-6f && out[2] > 0);
	/* perpendicular lines, equal weight: the bisector, unit length */
	w[0] = w[1] = 1;
	v[0][0] = 1, v[0][1] = 0, v[0][2] = 0;
	v[1][0] = 0, v[1][1] = 1, v[1][2] = 0;
	loom__orient_blend(2, w, (const float(*)[3])v, out);
	CHECK(fabsf(out[0] - 0.70710678f) < 1e-6f && fabsf(out[1] - 0.70710678f) < 1e-6f);
	/* rounding rule of dz */
	CHECK_EQ_INT(loom__dz_fixed(0.5f / 16), 1);
	CHECK_EQ_INT(loom__dz_fixed(-0.5f / 16), -1);
	CHECK_EQ_INT(loom__dz_fixed(0.49999997f / 16), 0);
	CHECK_EQ_INT(loom__dz_fixed(-2.6f), -42);
	CHECK_EQ_INT(loom__dz_fixed(1.25f), 20);
	CHECK_EQ_INT(loom__dz_fixed(1e9f), 2047 * 16);
	CHECK_EQ_INT(loom__dz_fixed(-1e9f), -2047 * 16);
	CHECK_EQ_INT(loom__dz_fixed(NAN), 0);
	/* the split of every offset in range (both signs) against floor */
	{
		int bad = 0;
		for (int q = -2047 * 16; q <= 2047 * 16; q++) {
			int f = -1, wv = loom__dz_split(q, &f);
			if (wv != (int)floor(q / 16.0) || f != q - 16 * wv || f < 0 || f >= 16)
				bad++;
		}
		CHECK_EQ_INT(bad, 0);
	}
}

/* The fabric's own dz equals the reference built from the database
   (so the reference is the fabric's, not a lookalike). */
static void reference_matches_fabric(void)
{
	float *a, *b;
	size_t n;
	uint64_t bad = 0;

	if (!g_ok)
		return;
	n = (size_t)g_ref.b1 * g_ref.b2;
	a = malloc(4 * n);
	b = malloc(4 * n);
	for (int64_t I = -3; I < 10; I++)
		for (int64_t J = -3; J < 12; J++) {
			loom_synth_nbhd nb;
			loom_fabric_source src;
			loom_synth_nbhd_at(&g_ref.lk, I, J, &nb);
			ref_dz_block(&g_ref, I, J, a);
			CHECK_EQ_INT(loom_fabric_dz(g_fab, I, J, b), LOOM_OK);
			bad += memcmp(a, b, 4 * n) != 0;
			CHECK_EQ_INT(loom_fabric_source_at(g_fab, I, J, &src), LOOM_OK);
			bad += src.block != nb.self;
		}
	CHECK_EQ_INT(bad, 0);
	/* the engine's own evaluation of the offsets: bit for bit the edge-fix
	   module's, before rounding (so rounding never differs) */
	{
		loom_texture *t = open_tex(g_fab, g_db, 4u << 20, 1);
		uint64_t diff = 0, nonzero = 0;
		for (int64_t I = -40; t && I < 40; I += 3)
			for (int64_t J = -50; J < 50; J += 7) {
				ref_dz_block(&g_ref, I, J, a);
				for (uint32_t ly = 0; ly < g_ref.b2; ly++)
					for (uint32_t lx = 0; lx < g_ref.b1; lx++) {
						float v = loom__texture_dz(t, I, J, lx, ly);
						float w = a[ly * g_ref.b1 + lx];
						diff += memcmp(&v, &w, sizeof v) != 0;
						nonzero += lroundf(w) != 0;
					}
			}
		CHECK_EQ_INT(diff, 0);
		CHECK(nonzero > 100); /* the offsets are not all zero */
		printf("  %llu columns with a non-zero whole-voxel offset\n",
		       (unsigned long long)nonzero);
		loom_texture_close(t);
	}
	free(a);
	free(b);
}

static void brute_force_voxels(void)
{
	loom_texture *t;
	loom_texture_stats st;
	uint64_t bad, nonempty = 0;
	int64_t M, N, b1, b2, b3;

	if (!g_ok)
		return;
	M = g_design->rows, N = g_design->cols;
	b1 = g_ref.b1, b2 = g_ref.b2, b3 = g_ref.b3;
	t = open_tex(g_fab, g_db, 8u << 20, 2);
	if (!t)
		return;
	{
		/* two repeats and a margin, negative coordinates included, z beyond
		   both faces, in order */
		int64_t lo[3] = {-2 * b1 - 3, -2 * b2 - 1, -3};
		int64_t hi[3] = {(N + 2) * b1, (M + 2) * b2 + 2, b3 + 3};
		bad = check_box(t, &g_ref, lo, hi, 0, &nonempty);
		CHECK_EQ_INT(bad, 0);
		CHECK(nonempty > 1000); /* not a vacuous comparison */
		printf("  %lld x %lld x %lld voxels, %llu non-empty, %llu dz blocks\n",
		       (long long)(hi[0] - lo[0]), (long long)(hi[1] - lo[1]),
		       (long long)(hi[2] - lo[2]), (unsigned long long)nonempty,
		       (unsigned long long)g_ref.n_dz_blocks);
		/* and in random order */
		bad = check_box(t, &g_ref, lo, hi, 1, NULL);
		CHECK_EQ_INT(bad, 0);
	}
	{
		/* far away on the bolt: 64-bit coordinates, other random groups */
		int64_t lo[3] = {1000000000007ll, -700000000001ll, 0};
		int64_t hi[3] = {lo[0] + 5 * b1, lo[1] + 4 * b2, b3};
		bad = check_box(t, &g_ref, lo, hi, 0, NULL);
		CHECK_EQ_INT(bad, 0);
		/* across 2^32 (crossings found by a multiply below it, by
		   division above: the last block edges below it included) */
		lo[0] = ((int64_t)1 << 32) - 2 * b1 - 1, lo[1] = ((int64_t)1 << 32) - 2 * b2 - 3;
		hi[0] = lo[0] + 4 * b1 + 2, hi[1] = lo[1] + 4 * b2 + 2;
		bad = check_box(t, &g_ref, lo, hi, 1, NULL);
		CHECK_EQ_INT(bad, 0);
		lo[0] = -((int64_t)1 << 61) - 5, lo[1] = ((int64_t)1 << 61) + 3;
		hi[0] = lo[0] + 3 * b1, hi[1] = lo[1] + 3 * b2;
		bad = check_box(t, &g_ref, lo, hi, 1, NULL);
		CHECK_EQ_INT(bad, 0);
	}
	CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
	CHECK(st.lookups > 0 && st.brick_requests > 0);
	CHECK_EQ_INT(st.hits + st.misses + st.empty_bricks, st.brick_requests);
	CHECK_EQ_INT(st.errors, 0);
	CHECK(st.bytes_decompressed == st.misses * st.brick_bytes);
	CHECK(st.peak_bytes <= st.budget_bytes);
	CHECK(st.bytes_in_use <= st.peak_bytes);
	printf("  lookups %llu, requests %llu, hits %llu, misses %llu, empty %llu, "
	       "crossings %llu, dz %llu\n", (unsigned long long)st.lookups,
	       (unsigned long long)st.brick_requests, (unsigned long long)st.hits,
	       (unsigned long long)st.misses, (unsigned long long)st.empty_bricks,
	       (unsigned long long)st.crossings, (unsigned long long)st.dz_columns);
	loom_texture_close(t);
}

/* A 16 x 16-crossing tile, anywhere on the bolt (negative crossings too),
   fits the 256 crossing entries a thread gets at 64 MiB: looked up in
   random order again and again, each crossing is set up once (the
   entries' sets are tiles of crossings; a hash of (I, J) put more than
   XENT_WAYS of them in some sets, which then set crossings up again on
   every pass).  The values equal the reference throughout. */
static void crossing_tile_fits(void)
{
	const int64_t origins[2][2] = {{-5, 37}, {1000003, -2000001}};
	int64_t b1, b2, b3;

	if (!g_ok)
		return;
	b1 = g_ref.b1, b2 = g_ref.b2, b3 = g_ref.b3;
	for (int o = 0; o < 2; o++) {
		loom_texture *t = open_tex(g_fab, g_db, 64u << 20, 1);
		loom_texture_stats st;
		uint64_t bad = 0;
		if (!t)
			return;
		for (int pass = 0; pass < 4; pass++)
			for (int k = 0; k < 256; k++) {
				uint64_t c = rnd() % 256;
				int64_t I = origins[o][0] + (int64_t)(c / 16), J = origins[o][1] + (int64_t)(c % 16);
				int64_t x = J * b1 + rnd_range(0, b1), y = I * b2 + rnd_range(0, b2);
				int64_t z = rnd_range(0, b3);
				loom_texel a, b = ref_texel(&g_ref, x, y, z);
				if (loom_texture_voxel(t, x, y, z, &a) != LOOM_OK || !texel_eq(&a, &b))
					bad++;
			}
		/* and every crossing at least once */
		for (int64_t c = 0; c < 256; c++) {
			int64_t I = origins[o][0] + c / 16, J = origins[o][1] + c % 16;
			loom_texel a, b = ref_texel(&g_ref, J * b1, I * b2, b3 / 2);
			if (loom_texture_voxel(t, J * b1, I * b2, b3 / 2, &a) != LOOM_OK ||
			    !texel_eq(&a, &b))
				bad++;
		}
		CHECK_EQ_INT(bad, 0);
		CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
		CHECK_EQ_INT(st.crossings, 256);
		loom_texture_close(t);
	}
}

/* Non-power-of-two brick shape (3x5x7): the division path. */
static void odd_brick_shape(void)
{
	loom_db *db = NULL;
	loom_fabric *f;
	ref r;
	loom_texture *t;

	if (!g_ok)
		return;
	CHECK_EQ_INT(loom_db_open(db_np2_path, &db, NULL), LOOM_OK);
	if (!db)
		return;
	f = synth(g_design, db);
	if (f && ref_init(&r, f, db) == 0) {
		int64_t lo[3] = {-20, -13, -2};
		int64_t hi[3] = {60, 40, (int64_t)r.b3 + 2};
		t = open_tex(f, db, min_budget(f, db, 1), 1);
		CHECK(t != NULL);
		if (t) {
			CHECK_EQ_INT(check_box(t, &r, lo, hi, 1, NULL), 0);
			loom_texture_close(t);
		}
		ref_free(&r);
	}
	loom_fabric_free(f);
	loom_db_close(db);
}

/* Region reads equal point lookups (and so the reference). */
static void region_equals_points(void)
{
	loom_texture *t, *tp;
	uint64_t bad = 0;

	if (!g_ok)
		return;
	t = open_tex(g_fab, g_db, 4u << 20, 2);
	tp = open_tex(g_fab, g_db, 4u << 20, 2);
	if (!t || !tp)
		goto done;
	for (int it = 0; it < 40; it++) {
		int64_t lo[3], hi[3];
		size_t n;
		loom_texture_region reg = {0};
		uint8_t *dn, *kd, *ty, *lb;
		uint16_t *or;
		int rc, skip = it % 6;
		lo[0] = rnd_range(-200, 200);
		lo[1] = rnd_range(-150, 150);
		lo[2] = rnd_range(-6, (int64_t)g_ref.b3 + 2);
		hi[0] = lo[0] + rnd_range(1, 80);  /* up to 10 crossings: several */
		hi[1] = lo[1] + rnd_range(1, 30);  /* gather chunks of 32 columns */
		hi[2] = lo[2] + rnd_range(1, 25);
		if (it == 0) { /* the whole thickness and more */
			lo[2] = -5;
			hi[2] = g_ref.b3 + 5;
		}
		if (it == 1) { /* far away */
			lo[0] += 123456789012345ll;
			hi[0] += 123456789012345ll;
			lo[1] -= 98765432109ll;
			hi[1] -= 98765432109ll;
		}
		n = (size_t)(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
		dn = malloc(n), kd = malloc(n), ty = malloc(n), lb = malloc(n);
		or = malloc(2 * n);
		memset(dn, 0xAB, n);
		memset(ty, 0xAB, n);
		reg.density = skip == 1 ? NULL : dn;
		reg.orientation = skip == 2 ? NULL : or;
		reg.kind = skip == 3 ? NULL : kd;
		reg.type = skip == 4 ? NULL : ty;
		reg.label = skip == 5 ? NULL : lb;
		reg.layout = it % 4 < 2 ? LOOM_REGION_X_FASTEST : LOOM_REGION_Z_FASTEST;
		rc = loom_texture_read_region(t, lo, hi, &reg);
		CHECK_EQ_INT(rc, LOOM_OK);
		for (size_t i = 0; i < n; i++) {
			size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
			size_t nz = (size_t)(hi[2] - lo[2]);
			int64_t x, y, z;
			if (reg.layout == LOOM_REGION_X_FASTEST) {
				x = lo[0] + (int64_t)(i % nx);
				y = lo[1] + (int64_t)(i / nx % ny);
				z = lo[2] + (int64_t)(i / nx / ny);
			} else {
				z = lo[2] + (int64_t)(i % nz);
				x = lo[0] + (int64_t)(i / nz % nx);
				y = lo[1] + (int64_t)(i / nz / nx);
			}
			loom_texel p;
			rv e = ref_raw(&g_ref, x, y, z);
			loom_texture_voxel(tp, x, y, z, &p);
			if (reg.density && (dn[i] != e.d || fabsf(dn[i] / 255.0f - p.density) > 0))
				bad++;
			if (reg.orientation && or[i] != e.o)
				bad++;
			if (reg.kind && (kd[i] != e.k || kd[i] != p.kind))
				bad++;
			if (reg.type && (ty[i] != e.ty || ty[i] != p.type))
				bad++;
			if (reg.label && (lb[i] != e.l || lb[i] != p.label))
				bad++;
		}
		if (!reg.density) /* untouched */
			CHECK(dn[0] == 0xAB && dn[n - 1] == 0xAB);
		if (!reg.type)
			CHECK(ty[0] == 0xAB);
		free(dn), free(kd), free(ty), free(lb), free(or);
	}
	CHECK_EQ_INT(bad, 0);
done:
	loom_texture_close(t);
	loom_texture_close(tp);
}

/* A few bricks: still every voxel right; evictions happen; peak within the
   budget; and identical region bytes at every budget. */
static void tiny_budgets_deterministic(void)
{
	int64_t lo[3] = {-17, -11, -2}, hi[3] = {83, 61, 0};
	size_t n, budgets[4];
	uint8_t *ref_bytes = NULL;

	if (!g_ok)
		return;
	hi[2] = g_ref.b3 + 1;
	n = (size_t)(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
	budgets[0] = min_budget(g_fab, g_db, 1);
	budgets[1] = budgets[0] + 3000;
	budgets[2] = min_budget(g_fab, g_db, 4) + 20000;
	budgets[3] = 64u << 20;
	for (int b = 0; b < 4; b++) {
		loom_texture *t = open_tex(g_fab, g_db, budgets[b], b < 2 ? 1 : 4);
		loom_texture_stats st;
		loom_texture_region reg = {0};
		uint8_t *buf;
		if (!t)
			continue;
		buf = malloc(6 * n);
		reg.density = buf;
		reg.orientation = (uint16_t *)(buf + 2 * n);
		reg.kind = buf + 4 * n;
		reg.type = buf + n;
		reg.label = buf + 5 * n;
		CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_OK);
		if (b < 2) /* point lookups in random order, all right */
			CHECK_EQ_INT(check_box(t, &g_ref, lo, hi, 1, NULL), 0);
		loom_texture_get_stats(t, &st);
		printf("  budget %zu: %u frames, misses %llu, evictions %llu, peak %llu\n",
		       budgets[b], st.cache_frames, (unsigned long long)st.misses,
		       (unsigned long long)st.evictions, (unsigned long long)st.peak_bytes);
		CHECK(st.peak_bytes <= budgets[b]);
		if (b == 0) {
			CHECK(st.cache_frames <= 8);
			CHECK(st.evictions > 1000);
		}
		if (!ref_bytes)
			ref_bytes = buf;
		else {
			CHECK(memcmp(ref_bytes, buf, 6 * n) == 0);
			free(buf);
		}
		loom_texture_close(t);
	}
	free(ref_bytes);
}

/* A database NAME of the tiny preset with the given brick, seed and block
   shape in tmpdir, a fabric of g_design over it and its reference: 0, or
   -1 with what was made freed (*db, *f NULL). */
static int block_fixture(const char *name, const uint32_t brick[3], uint64_t seed,
                         const uint32_t block[3], loom_db **db, loom_fabric **f, ref *r)
{
	char path[4300];

	*db = NULL;
	*f = NULL;
	snprintf(path, sizeof path, "%s/%s", tmpdir, name);
	CHECK_EQ_INT(make_db_block(path, "tiny", brick, seed, block), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(path, db, NULL), LOOM_OK);
	if (!*db)
		return -1;
	*f = synth(g_design, *db);
	if (!*f || ref_init(r, *f, *db) != 0) {
		CHECK(0);
		loom_fabric_free(*f);
		loom_db_close(*db);
		*f = NULL;
		*db = NULL;
		return -1;
	}
	return 0;
}

/* Blocks 70 voxels wide: region reads gather and transpose whole 16-column
   blocks and 64-column chunks (the tiny preset's 8-voxel blocks never
   fill one); both layouts against the reference. */
static void wide_blocks_region_rank(uint32_t rank)
{
	const uint32_t block[3] = {70, 5, 20}, brick[3] = {16, 4, 16};
	loom_db *db;
	loom_fabric *f;
	loom_texture *t = NULL;
	loom_fabric_params fp;
	ref r;
	uint64_t bad = 0, dzdiff = 0;
	int fx;

	g_rank = rank;
	fx = block_fixture(rank ? "wide-full.ldb" : "wide.ldb", brick, 5, block, &db, &f, &r);
	g_rank = 0;
	if (fx != 0)
		return;
	loom_fabric_get_params(f, &fp);
	printf("  ranks %u / %u\n", fp.rank_h, fp.rank_v);
	t = open_tex(f, db, 8u << 20, 1);
	/* the engine's offsets (dz_eval: the ranks past each row's and
	   column's prefix skipped) bit for bit the fabric's */
	for (int64_t I = -6; t && I < 6; I++)
		for (int64_t J = -5; J < 5; J++) {
			float dz[70 * 5];
			CHECK_EQ_INT(loom_fabric_dz(f, I, J, dz), LOOM_OK);
			for (uint32_t ly = 0; ly < 5; ly++)
				for (uint32_t lx = 0; lx < 70; lx++) {
					float v = loom__texture_dz(t, I, J, lx, ly);
					dzdiff += memcmp(&v, &dz[ly * 70 + lx], sizeof v) != 0;
				}
		}
	CHECK_EQ_INT(dzdiff, 0);
	for (int it = 0; t && it < 12; it++) {
		int64_t lo[3], hi[3];
		size_t nx, ny, nz, n;
		uint8_t *buf;
		loom_texture_region reg = {0};
		lo[0] = rnd_range(-300, 300);
		lo[1] = rnd_range(-40, 40);
		lo[2] = rnd_range(-3, 3);
		hi[0] = lo[0] + rnd_range(60, 220);
		hi[1] = lo[1] + rnd_range(1, 12);
		hi[2] = lo[2] + rnd_range(14, 26);
		nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]), nz = (size_t)(hi[2] - lo[2]);
		n = nx * ny * nz;
		/* orientation after density, at an even offset (n may be odd) */
		buf = malloc(6 * n + 1);
		reg.density = buf;
		reg.orientation = (uint16_t *)(buf + (n + 1) / 2 * 2);
		reg.kind = (uint8_t *)(reg.orientation + n);
		reg.type = reg.kind + n;
		reg.label = reg.type + n;
		reg.layout = it & 1;
		CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_OK);
		for (size_t i = 0; i < n; i++) {
			int64_t x, y, z;
			rv e;
			if (reg.layout == LOOM_REGION_X_FASTEST) {
				x = lo[0] + (int64_t)(i % nx);
				y = lo[1] + (int64_t)(i / nx % ny);
				z = lo[2] + (int64_t)(i / nx / ny);
			} else {
				z = lo[2] + (int64_t)(i % nz);
				x = lo[0] + (int64_t)(i / nz % nx);
				y = lo[1] + (int64_t)(i / nz / nx);
			}
			e = ref_raw(&r, x, y, z);
			bad += buf[i] != e.d || reg.orientation[i] != e.o || reg.kind[i] != e.k ||
			       reg.type[i] != e.ty || reg.label[i] != e.l;
		}
		free(buf);
	}
	CHECK_EQ_INT(bad, 0);
	loom_texture_close(t);
	t = NULL;
	/* full rank: an entry's coefficients take 8 (70 + 3) bytes; 256 of
	   them a slot still fit an 8 MiB budget (texture.c ent_fit), so warm
	   random lookups over a 16 x 16-crossing tile set each crossing up
	   once (with entries held to 1/32 of the budget: 128, and crossings
	   set up again on most passes) */
	if (rank)
		t = open_tex(f, db, 8u << 20, 1);
	if (t) {
		loom_texture_stats st;
		uint64_t wrong = 0;
		for (int pass = 0; pass < 4; pass++)
			for (int64_t c = 0; c < 256; c++) {
				int64_t I = -7 + c / 16, J = 3 + c % 16;
				int64_t x = J * 70 + rnd_range(0, 70), y = I * 5 + rnd_range(0, 5);
				int64_t z = rnd_range(0, r.b3);
				loom_texel a, b = ref_texel(&r, x, y, z);
				wrong += loom_texture_voxel(t, x, y, z, &a) != LOOM_OK || !texel_eq(&a, &b);
			}
		CHECK_EQ_INT(wrong, 0);
		CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
		printf("  full rank, 8 MiB: %llu crossings set up for 1024 lookups over 256\n",
		       (unsigned long long)st.crossings);
		CHECK_EQ_INT(st.crossings, 256);
		loom_texture_close(t);
	}
	ref_free(&r);
	loom_fabric_free(f);
	loom_db_close(db);
}

/* The same at the default rank and at full rank (the sine basis, whose
   fields vanish inside the block: edgefix.c exact_basis). */
static void wide_blocks_region(void)
{
	wide_blocks_region_rank(0);
	wide_blocks_region_rank(LOOM_EDGEFIX_MAX_RANK);
}

/* Read box [lo, hi) with the channels of mask (bit 0 density, 1
   orientation, 2 kind, 3 type, 4 label) in layout lay and compare every
   voxel with the reference; returns mismatches (+1 for a wrong result code
   or a NULL channel written).  Compared column by column (the reference
   caches one crossing's offsets). */
static uint64_t region_vs_ref(loom_texture *t, ref *r, const int64_t lo[3],
                              const int64_t hi[3], unsigned mask, int lay)
{
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]), n = nx * ny * nz;
	uint8_t *buf = malloc(6 * n + 1);
	loom_texture_region reg = {0};
	uint64_t bad = 0;
	int rc;

	if (!buf)
		return 1;
	memset(buf, 0xA5, 6 * n + 1);
	/* orientation first (aligned), then density, kind, type, label */
	reg.density = mask & 1 ? buf + 2 * n : NULL;
	reg.orientation = mask & 2 ? (uint16_t *)buf : NULL;
	reg.kind = mask & 4 ? buf + 3 * n : NULL;
	reg.type = mask & 8 ? buf + 4 * n : NULL;
	reg.label = mask & 16 ? buf + 5 * n : NULL;
	reg.layout = lay;
	rc = loom_texture_read_region(t, lo, hi, &reg);
	bad += rc != LOOM_OK;
	for (size_t y = 0; y < ny; y++)
		for (size_t x = 0; x < nx; x++)
			for (size_t z = 0; z < nz; z++) {
				size_t i = lay == LOOM_REGION_X_FASTEST ? (z * ny + y) * nx + x
				                                        : (y * nx + x) * nz + z;
				rv e = ref_raw(r, lo[0] + (int64_t)x, lo[1] + (int64_t)y,
				               lo[2] + (int64_t)z);
				uint64_t b = (reg.density && reg.density[i] != e.d) +
				             (reg.orientation && reg.orientation[i] != e.o) +
				             (reg.kind && reg.kind[i] != e.k) +
				             (reg.type && reg.type[i] != e.ty) +
				             (reg.label && reg.label[i] != e.l);
				if (b && bad < 3)
					printf("  layout %d mask %u voxel (%lld,%lld,%lld): d %d/%d o %d/%d "
					       "k %d/%d t %d/%d l %d/%d\n", lay, mask,
					       (long long)(lo[0] + (int64_t)x), (long long)(lo[1] + (int64_t)y),
					       (long long)(lo[2] + (int64_t)z), buf[2 * n + i], e.d,
					       (mask & 2) ? reg.orientation[i] : 0, e.o,
					       buf[3 * n + i], e.k, buf[4 * n + i], e.ty, buf[5 * n + i], e.l);
				bad += b;
			}
	/* channels not asked for are untouched */
	for (int c = 0; c < 5; c++) {
		static const size_t at[5] = {2, 0, 3, 4, 5};
		size_t len = c == 1 ? 2 * n : n;
		if (mask >> c & 1)
			continue;
		for (size_t i = 0; i < len; i++)
			if (buf[at[c] * n + i] != 0xA5) {
				bad++;
				break;
			}
	}
	bad += buf[6 * n] != 0xA5; /* nothing past the end */
	free(buf);
	return bad;
}

/* The region-read paths (brick-grouped runs, empty slabs of the x-fastest
   chunks, PSHUFB and table label mappings, every channel subset) against
   the reference: odd boxes, negative coordinates, boxes across design
   repeats and beyond both faces of the cloth, both layouts, on three brick
   shapes (4x4x8; 3x5x7, not powers of two; 16x4x32 under 40x12x90
   blocks, several bricks per column and labels above 15). */
static void region_paths(void)
{
	const uint32_t block[3] = {40, 12, 90}, brick[3] = {16, 4, 32};
	const char *paths[3] = {db_path, db_np2_path, NULL};
	char tall[4300];
	uint64_t bad = 0, boxes = 0;

	if (!g_ok)
		return;
	snprintf(tall, sizeof tall, "%s/tall.ldb", tmpdir);
	CHECK_EQ_INT(make_db_block(tall, "tiny", brick, 7, block), LOOM_OK);
	paths[2] = tall;
	for (int d = 0; d < 3; d++) {
		loom_db *db = NULL;
		loom_fabric *f = NULL;
		loom_texture *t = NULL;
		ref r;
		int64_t rx, ry; /* repeat, voxels */
		if (loom_db_open(paths[d], &db, NULL) != LOOM_OK) {
			CHECK(0);
			continue;
		}
		f = synth(g_design, db);
		if (!f || ref_init(&r, f, db) != 0) {
			CHECK(0);
			loom_fabric_free(f);
			loom_db_close(db);
			continue;
		}
		rx = (int64_t)g_design->cols * r.b1;
		ry = (int64_t)g_design->rows * r.b2;
		/* a small budget: misses and evictions inside one read */
		t = open_tex(f, db, min_budget(f, db, 1) + 40000, 1);
		for (int it = 0; t && it < 14; it++) {
			int64_t lo[3], hi[3];
			unsigned mask = it < 2 ? 31 : (unsigned)(rnd() % 31) + 1;
			int lay = it & 1;
			/* around a repeat boundary (either sign), odd sizes */
			int64_t kx = rnd_range(-3, 4), ky = rnd_range(-3, 4);
			lo[0] = kx * rx + rnd_range(-(int64_t)r.b1 * 2, (int64_t)r.b1);
			lo[1] = ky * ry + rnd_range(-(int64_t)r.b2 * 2, (int64_t)r.b2);
			hi[0] = lo[0] + rnd_range(1, 2 * (int64_t)r.b1 + 40);
			hi[1] = lo[1] + rnd_range(1, 2 * (int64_t)r.b2 + 3);
			lo[2] = rnd_range(-(int64_t)r.b3 / 2, (int64_t)r.b3);
			hi[2] = lo[2] + rnd_range(1, (int64_t)r.b3 + 10);
			if (it % 5 == 0) { /* the whole thickness and beyond both faces */
				lo[2] = -7;
				hi[2] = (int64_t)r.b3 + 9;
			}
			if (it == 3) { /* entirely below the cloth */
				lo[2] = -20;
				hi[2] = -1;
			}
			/* the PSHUFB path and the 256-entry tables; the line paths
			   of AVX2 hosts (level 2), of this CPU, and SSE2 */
			for (int simd = 2; simd >= 0; simd--) {
				loom__texture_simd(t, simd);
				bad += region_vs_ref(t, &r, lo, hi, mask, lay);
				boxes++;
			}
			loom__texture_simd(t, 1);
		}
		/* kind or type alone (the other NULL) in both layouts */
		for (int lay = 0; t && lay < 2; lay++) {
			int64_t lo[3] = {-5, -3, -2}, hi[3] = {(int64_t)r.b1 + 19, (int64_t)r.b2 + 1, 0};
			hi[2] = (int64_t)r.b3 + 2;
			bad += region_vs_ref(t, &r, lo, hi, 4, lay);
			bad += region_vs_ref(t, &r, lo, hi, 8, lay);
			boxes += 2;
		}
		loom_texture_close(t);
		ref_free(&r);
		loom_fabric_free(f);
		loom_db_close(db);
	}
	printf("  %llu boxes, %llu mismatches\n", (unsigned long long)boxes,
	       (unsigned long long)bad);
	CHECK_EQ_INT(bad, 0);
}

/* Region reads bound their output rows by the every-plane occupancy
   table (loom__texture_region_occ): on the 16x4x32-brick database under
   40x12x90 blocks, boxes read once to fill the table (whole-brick loads),
   then again with the table and without it, both layouts, every channel
   and density alone, each against the reference voxel for voxel; a guard
   that the table is filled and narrower than its bricks in places (else
   the check would prove nothing), and that with it the reads of either
   layout request fewer bricks. */
static void region_occupancy(void)
{
	const uint32_t block[3] = {40, 12, 90}, brick[3] = {16, 4, 32};
	loom_db *db;
	loom_fabric *f;
	loom_texture *t = NULL;
	ref r;
	uint64_t bad = 0, boxes = 0, known = 0, narrow = 0, req[2][2] = {{0, 0}, {0, 0}};
	int64_t box[12][6];

	if (!g_ok || block_fixture("occ.ldb", brick, 7, block, &db, &f, &r) != 0)
		return;
	t = open_tex(f, db, (size_t)64 << 20, 1); /* nothing evicted */
	for (int b = 0; b < 12; b++) { /* 3 whole columns, 9 from random heights */
		box[b][0] = rnd_range(-90, 60);
		box[b][1] = rnd_range(-30, 20);
		box[b][2] = b < 3 ? -3 : rnd_range(0, (int64_t)r.b3 - 20);
		box[b][3] = box[b][0] + rnd_range(20, 130);
		box[b][4] = box[b][1] + rnd_range(3, 30);
		box[b][5] = b < 3 ? (int64_t)r.b3 + 2 : rnd_range(box[b][2] + 1, (int64_t)r.b3);
	}
	for (int pass = 0; t && pass < 3; pass++) /* 0: fills the table */
		for (int b = 0; b < 12; b++)
			for (int lay = 0; lay < 2; lay++)
				for (int m = 0; m < 2; m++) {
					loom_texture_stats st0, st1;
					loom__texture_region_occ(t, pass != 1);
					loom_texture_get_stats(t, &st0);
					bad += region_vs_ref(t, &r, box[b], box[b] + 3, m ? 31 : 1, lay);
					loom_texture_get_stats(t, &st1);
					if (pass)
						req[lay][pass - 1] += st1.brick_requests - st0.brick_requests;
					boxes++;
				}
	loom__texture_region_occ(t, 1);
	loom__texture_occ_tiles(t, &known, &narrow);
	printf("  %llu boxes, %llu mismatches; table: %llu tiles known, %llu narrower than "
	       "their brick; brick requests without it / with it: x fastest %llu / %llu, "
	       "z fastest %llu / %llu\n",
	       (unsigned long long)boxes, (unsigned long long)bad, (unsigned long long)known,
	       (unsigned long long)narrow, (unsigned long long)req[0][0],
	       (unsigned long long)req[0][1], (unsigned long long)req[1][0],
	       (unsigned long long)req[1][1]);
	CHECK_EQ_INT(bad, 0);
	CHECK(known > 0 && narrow > 0);
	CHECK(req[0][1] < req[0][0] && req[1][1] < req[1][0]);
	loom_texture_close(t);
	/* with LOD on, the level-0 loader fills the tables too (it did not
	   before 2026-12-05: region reads were bounded by bricks, lookups had
	   no air test), and the reads still equal the reference */
	{
		loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
		loom_diag d = {0};
		uint64_t lbad = 0, lknown = 0, lnarrow = 0;
		t = NULL;
		o.budget_bytes = (size_t)64 << 20;
		o.max_threads = 1;
		o.lod = 1;
		if (loom_texture_open(f, db, &o, &t, &d))
			printf("  texture open (LOD): %s\n", d.message);
		CHECK(t != NULL && loom_texture_lod_levels(t) > 0);
		for (int pass = 0; t && pass < 2; pass++)
			for (int b = 0; b < 12; b++)
				for (int lay = 0; lay < 2; lay++)
					lbad += region_vs_ref(t, &r, box[b], box[b] + 3, 31, lay);
		if (t)
			loom__texture_occ_tiles(t, &lknown, &lnarrow);
		printf("  LOD on: %llu mismatches; %llu tiles known, %llu narrower\n",
		       (unsigned long long)lbad, (unsigned long long)lknown,
		       (unsigned long long)lnarrow);
		CHECK_EQ_INT(lbad, 0);
		CHECK(lknown > 0 && lnarrow > 0);
		loom_texture_close(t);
	}
	ref_free(&r);
	loom_fabric_free(f);
	loom_db_close(db);
}

/* Sub-voxel offsets in region reads: a database 150 voxels thick in
   bricks 32 high, so an x-fastest read gathers several 64-voxel slabs and
   a column's run crosses bricks; boxes that start and end inside the
   cloth (the end voxel past a run, blended columns of every length), both
   layouts, every channel subset with density, the SSSE3 and SSE2 blends,
   against the reference voxel for voxel.  A guard that columns of both
   blend directions and whole columns are there; two x-fastest boxes of
   4 MiB and more (non-temporal zeroing); and the bench's whole-voxel peer
   (loom__texture_region_whole) changes densities only. */
static void region_sub_voxel(void)
{
	const uint32_t block[3] = {40, 6, 150}, brick[3] = {16, 2, 32};
	loom_db *db;
	loom_fabric *f;
	loom_texture *t = NULL;
	ref r;
	uint64_t bad = 0, boxes = 0, cols[3] = {0, 0, 0};

	if (!g_ok || block_fixture("thick.ldb", brick, 11, block, &db, &f, &r) != 0)
		return;
	/* whole (f = 0), below (1..8), above (9..15) in a few crossings */
	for (int64_t I = 0; I < 3; I++)
		for (int64_t J = 0; J < 3; J++) {
			ref_raw(&r, J * (int64_t)r.b1, I * (int64_t)r.b2, 0); /* r.dz of (I, J) */
			for (uint32_t c = 0; c < r.b1 * r.b2; c++) {
				long q = ref_dz16(r.dz[c]), fr = ((q % 16) + 16) % 16;
				cols[fr == 0 ? 0 : fr <= 8 ? 1 : 2]++;
			}
		}
	printf("  columns: %llu whole, %llu blended with the voxel below, %llu above\n",
	       (unsigned long long)cols[0], (unsigned long long)cols[1],
	       (unsigned long long)cols[2]);
	CHECK(cols[0] > 0 && cols[1] > 0 && cols[2] > 0);
	t = open_tex(f, db, min_budget(f, db, 1) + 60000, 1);
	for (int it = 0; t && it < 16; it++) {
		static const unsigned masks[4] = {1, 3, 31, 17};
		int64_t lo[3], hi[3];
		unsigned mask = it < 4 ? masks[it] : (unsigned)(rnd() % 16) * 2 + 1;
		lo[0] = rnd_range(-60, 60);
		lo[1] = rnd_range(-8, 8);
		hi[0] = lo[0] + rnd_range(1, 90);
		hi[1] = lo[1] + rnd_range(1, 7);
		lo[2] = rnd_range(-3, (int64_t)r.b3 - 20);
		hi[2] = lo[2] + rnd_range(1, (int64_t)r.b3 + 3 - lo[2]);
		if (it % 4 == 0) { /* whole columns: every slab, both faces */
			lo[2] = -2;
			hi[2] = (int64_t)r.b3 + 2;
		}
		/* bricks 32 high: no line path of 64-high bricks, so level 2
		   (AVX2) would repeat level 1 */
		for (int simd = 1; simd >= 0; simd--) {
			loom__texture_simd(t, simd);
			bad += region_vs_ref(t, &r, lo, hi, mask, it & 1);
			boxes++;
		}
		loom__texture_simd(t, 1);
	}
	/* x-fastest outputs of 4 MiB and more (NT_MIN in region.c): the surely
	   empty rows are zeroed with non-temporal stores; whole rows (one span
	   per plane, nx < 64) and 64-column chunks of wider rows, through
	   both faces, misaligned heads and tails */
	for (int it = 0; t && it < 2; it++) {
		int64_t lo[3] = {-37, -50, -3}, hi[3] = {13, 46, 0};
		if (it) {
			lo[0] = -101, lo[1] = -11;
			hi[0] = 49, hi[1] = 19;
		}
		hi[2] = (int64_t)r.b3 + 3;
		CHECK((size_t)(hi[0] - lo[0]) * (size_t)(hi[1] - lo[1]) * (size_t)(hi[2] - lo[2]) * 6 >=
		      (size_t)4 << 20);
		bad += region_vs_ref(t, &r, lo, hi, 31, LOOM_REGION_X_FASTEST);
		boxes++;
	}
	/* the whole-voxel peer: other planes identical, some density not */
	if (t) {
		int64_t lo[3] = {-13, -5, 0}, hi[3] = {67, 7, 0};
		size_t n;
		uint8_t *a, *b;
		loom_texture_region ra = {0}, rb = {0};
		hi[2] = r.b3;
		n = (size_t)80 * 12 * r.b3;
		a = malloc(6 * n), b = malloc(6 * n);
		ra.density = a, ra.orientation = (uint16_t *)(a + n), ra.label = a + 3 * n;
		ra.kind = a + 4 * n, ra.type = a + 5 * n;
		rb.density = b, rb.orientation = (uint16_t *)(b + n), rb.label = b + 3 * n;
		rb.kind = b + 4 * n, rb.type = b + 5 * n;
		CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &ra), LOOM_OK);
		loom__texture_region_whole(t, 1);
		CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &rb), LOOM_OK);
		loom__texture_region_whole(t, 0);
		CHECK(memcmp(a, b, n) != 0);
		CHECK(memcmp(a + n, b + n, 5 * n) == 0);
		free(a), free(b);
	}
	printf("  %llu boxes, %llu mismatches\n", (unsigned long long)boxes,
	       (unsigned long long)bad);
	CHECK_EQ_INT(bad, 0);
	loom_texture_close(t);
	ref_free(&r);
	loom_fabric_free(f);
	loom_db_close(db);
}

/* The sub-voxel blend at brick boundaries and run ends (a fractional
   column's copied runs from several bricks; the end voxel past the
   column's run): on bricks 8, 7, 32, 16 and 64 high (the tiny and np2
   databases, region_sub_voxel's 150 voxels thick, then 160 and 128
   thick, so the cloth crosses the brick boundary at z = 80 and 64: 32,
   16 and 64 go through region.c's brick lines, which carry the voxel
   below a line and the candidate at its top to the next line, 64 with
   AVX-512 where the CPU has it, and SSE2 too; 8 and 7 through
   blend_col), boxes whose z range starts and ends at z = 0, at the top
   of the block, inside the cloth, just below, at and above brick
   boundaries, runs of odd lengths below and
   above 16 and runs across two, three and all bricks; density alone, with
   orientation and with every channel, both layouts, SSSE3 and SSE2
   blends, against the reference.  (Written for a blend fused into the
   brick pass, tried in session 28 and dropped: a dropped carry or end
   voxel there gave thousands of mismatches here.) */
static void region_blend_edges(void)
{
	const uint32_t block[3] = {40, 6, 150}, brick[3] = {16, 2, 32}, brick16[3] = {16, 2, 16};
	const uint32_t block160[3] = {40, 6, 160}; /* the cloth across z = 80 */
	const uint32_t brick64[3] = {16, 2, 64}, block128[3] = {40, 6, 128}; /* across 64 */
	static const unsigned masks[3] = {1, 3, 31};
	const int64_t bzs[5] = {8, 7, 32, 16, 64};
	uint64_t bad = 0, boxes = 0;

	if (!g_ok)
		return;
	for (int d = 0; d < 5; d++) {
		loom_db *db = NULL;
		loom_fabric *f = NULL;
		loom_texture *t = NULL;
		ref r;
		int64_t bz = bzs[d], b3;
		if (d >= 2) {
			static const char *const names[3] = {"thick.ldb", "thick16.ldb", "thick64.ldb"};
			const uint32_t *bk = d == 2 ? brick : d == 3 ? brick16 : brick64;
			const uint32_t *bl = d == 2 ? block : d == 3 ? block160 : block128;
			if (block_fixture(names[d - 2], bk, 11, bl, &db, &f, &r) != 0) {
				CHECK(0);
				continue;
			}
		} else {
			if (loom_db_open(d ? db_np2_path : db_path, &db, NULL) != LOOM_OK) {
				CHECK(0);
				continue;
			}
			f = synth(g_design, db);
			if (!f || ref_init(&r, f, db) != 0) {
				CHECK(0);
				loom_fabric_free(f);
				loom_db_close(db);
				continue;
			}
		}
		b3 = (int64_t)r.b3;
		t = open_tex(f, db, min_budget(f, db, 1) + 60000, 1);
		for (int zi = 0; t && zi < 23; zi++) {
			const int64_t zr[23][2] = {
				{b3 / 2 - 33, b3 / 2 + 1}, {b3 / 2 - 1, b3 / 2 + 33},
				{b3 / 3, 2 * b3 / 3}, {b3 / 2 - 48, b3 / 2 - 8},
				{b3 / 2 + 8, b3 / 2 + 48},
				{0, b3}, {0, 1}, {0, bz - 1}, {0, bz + 1}, {0, 17}, {0, 33},
				{b3 - 1, b3}, {b3 - 7, b3}, {b3 - 19, b3}, {bz - 1, bz + 1},
				{bz - 1, 2 * bz + 1}, {bz, 2 * bz}, {bz + 1, 3 * bz - 1},
				{-3, 5}, {b3 - 5, b3 + 4}, {1, b3 - 1}, {20, 100}, {5, 140}};
			int64_t lo[3] = {-21, -3, zr[zi][0]}, hi[3] = {59, 4, zr[zi][1]};
			if (lo[2] < -3)
				lo[2] = -3;
			if (hi[2] > b3 + 4)
				hi[2] = b3 + 4;
			if (hi[2] <= lo[2])
				continue;
			for (int m = 0; m < 3; m++)
				for (int lay = 0; lay < 2; lay++)
					for (int simd = 2; simd >= 0; simd--) {
						loom__texture_simd(t, simd);
						bad += region_vs_ref(t, &r, lo, hi, masks[m], lay);
						boxes++;
					}
			loom__texture_simd(t, 1);
		}
		loom_texture_close(t);
		ref_free(&r);
		loom_fabric_free(f);
		loom_db_close(db);
	}
	printf("  %llu boxes, %llu mismatches\n", (unsigned long long)boxes,
	       (unsigned long long)bad);
	CHECK_EQ_INT(bad, 0);
}

/* The brick-line blend rule, written out voxel by voxel: the voxels
   lo .. hi - 1 of a line copied to out, those not empty over an empty
   farther voxel (dir +1: the one above, empty above nv, and at the line's
   top left waiting when more lines follow; dir -1: the one below, pn
   below voxel 0) with no solid voxel above them in their 16-voxel
   segment (below nv) blended with empty at weight g.  Returns 1 when the
   top voxel is left waiting. */
static int ref_line_blend(unsigned bz, const uint8_t *line, unsigned lo, unsigned hi,
                          unsigned nv, int dir, unsigned g, unsigned pn, int more,
                          unsigned solid, uint8_t *out)
{
	int pend = 0;

	for (unsigned i = lo; i < hi; i++) {
		unsigned far, end = (i / 16 + 1) * 16 < nv ? (i / 16 + 1) * 16 : nv, above = 0;
		out[i - lo] = line[i];
		if (!line[i])
			continue;
		if (dir > 0)
			far = i + 1 < nv ? line[i + 1] : 0;
		else
			far = i ? line[i - 1] : pn;
		for (unsigned j = i + 1; j < end; j++)
			above |= line[j] >= solid;
		if (far || above)
			continue;
		if (dir > 0 && more && i == bz - 1)
			pend = 1;
		else
			out[i - lo] = (uint8_t)(((16 - g) * line[i] + 8) / 16);
	}
	return pend;
}

/* region.c's brick-line blends (SSE2 masks, AVX-512BW masks, the fused
   copy and blend of density-only reads with AVX-512BW and with AVX2) on
   random lines of empty, thin
   and solid runs against ref_line_blend: every distance from a surface
   voxel to the solid voxel above it in its segment (1-15), lines cut at
   both ends and by the block's top, both sides, every weight. */
static void line_blend_rule(void)
{
	uint64_t cases[4] = {0, 0, 0, 0}, bad = 0, far_solid = 0;

	for (int it = 0; it < 30000; it++) {
		static const unsigned bzs[3] = {16, 32, 64};
		unsigned bz = bzs[it % 3], solid = (unsigned)rnd_range(1, 256);
		unsigned lo = (unsigned)rnd_range(0, bz), hi, nv = bz, g;
		int dir = rnd() & 1 ? 1 : -1, more = (int)(rnd() & 1);
		unsigned pn = (unsigned)(rnd() & 1);
		uint8_t line[64], want[64], got[64];
		for (unsigned i = 0; i < bz;) { /* runs of 1-12: empty, thin, solid */
			unsigned len = (unsigned)rnd_range(1, 13), kind = (unsigned)(rnd() % 3);
			for (; len-- && i < bz; i++)
				line[i] = kind == 0                       ? 0
				          : kind == 1 && solid > 1        ? (uint8_t)rnd_range(1, solid)
				          : (uint8_t)rnd_range(solid, 256);
		}
		if (rnd() % 4 == 0) { /* the block's top inside the line */
			nv = (unsigned)rnd_range(lo + 1, bz + 1);
			more = 0;
		}
		hi = (unsigned)rnd_range(lo + 1, nv + 1);
		g = (unsigned)rnd_range(1, 9);
		for (unsigned i = lo; i < hi; i++) { /* a surface voxel with its solid 9+ above */
			unsigned end = (i / 16 + 1) * 16 < nv ? (i / 16 + 1) * 16 : nv, j = i + 1;
			while (j < end && line[j] < solid)
				j++;
			far_solid += line[i] && j < end && j - i >= 9;
		}
		int pw = ref_line_blend(bz, line, lo, hi, nv, dir, g, pn, more, solid, want);
		for (int path = 0; path < 4; path++) {
			memset(got, 0xa5, sizeof got);
			int pg = loom__texture_line_blend(path, bz, line, lo, hi, nv, dir, g, pn, more,
			                                  solid, got);
			if (pg < 0)
				continue;
			cases[path]++;
			if (pg != pw || memcmp(got, want, hi - lo) != 0) {
				if (bad++ < 3)
					printf("  path %d bz %u lo %u hi %u nv %u dir %d g %u pn %u more %d "
					       "solid %u: differs\n", path, bz, lo, hi, nv, dir, g, pn, more,
					       solid);
			}
			for (unsigned i = hi - lo; i < 64; i++) /* nothing written past hi */
				bad += got[i] != 0xa5;
		}
	}
	printf("  lines: %llu SSE2, %llu AVX-512 masks, %llu fused, %llu AVX2 fused (AVX-512 and "
	       "AVX2 ones: 0 without them); "
	       "%llu surface voxels with the solid one 9-15 above; %llu mismatches\n",
	       (unsigned long long)cases[0], (unsigned long long)cases[1],
	       (unsigned long long)cases[2], (unsigned long long)cases[3],
	       (unsigned long long)far_solid, (unsigned long long)bad);
#ifdef __SSE2__
	CHECK(cases[0] > 0);
#else
	/* a build without SSE2 (make test-portable) has no brick lines: region.c
	   must not have compiled its SSE2 paths after all (gcc's immintrin.h
	   defined __SSE2__ there again until 2026-12-07) */
	CHECK(cases[0] == 0 && cases[1] == 0 && cases[2] == 0 && cases[3] == 0);
#endif
	CHECK(far_solid > 1000);
	CHECK_EQ_INT(bad, 0);
}

/* Labels: the exemplars of the tall database have labels above 15 (the
   PSHUFB mapping uses more than one group of 16); a guard that the test
   above covers that case. */
static void labels_above_15(void)
{
	char tall[4300];
	loom_db *db = NULL;
	loom_db_exemplar_info e;
	uint32_t top = 0;

	if (!g_ok)
		return;
	snprintf(tall, sizeof tall, "%s/tall.ldb", tmpdir);
	CHECK_EQ_INT(loom_db_open(tall, &db, NULL), LOOM_OK);
	if (!db)
		return;
	for (uint32_t k = 0; loom_db_exemplar(db, k, &e) == LOOM_OK; k++)
		if (e.n_yarns > top)
			top = e.n_yarns;
	printf("  largest label %u\n", top);
	CHECK(top >= 16);
	loom_db_close(db);
}

/* Trilinear density and orientation from the 8 reference voxels; the
   nearest kind/type; nearest filter = floor. */
static void filtered_lookups_at(size_t budget);

/* At a budget holding the working set and at the smallest one (a corner
   column pair's source voxels evicting each other's bricks). */
static void filtered_lookups(void)
{
	filtered_lookups_at(8u << 20);
	filtered_lookups_at(min_budget(g_fab, g_db, 2));
}

/* The trilinear density and orientation at p from the 8 reference voxels
   (the documented blend: the orientations summed with the signs that
   align them to the corner of largest w * density).  Returns 1 when an
   orientation was blended (some corner has density). */
static int ref_trilinear(const double p[3], float *dens, float ori[3])
{
	double u[3], f[3];
	int64_t i0[3];
	float w[8], wd[8], v[8][3], s[3] = {0, 0, 0}, len;
	int r = -1;

	*dens = 0;
	ori[0] = ori[1] = ori[2] = 0;
	for (int k = 0; k < 3; k++) {
		u[k] = p[k] - 0.5;
		i0[k] = (int64_t)floor(u[k]);
		f[k] = u[k] - (double)i0[k];
	}
	for (int c = 0; c < 8; c++) {
		int dz = c & 1, dx = c >> 1 & 1, dy = c >> 2 & 1;
		loom_texel q = ref_texel(&g_ref, i0[0] + dx, i0[1] + dy, i0[2] + dz);
		w[c] = (float)((dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) *
		               (dz ? f[2] : 1 - f[2]));
		*dens += w[c] * q.density;
		wd[c] = w[c] * q.density;
		memcpy(v[c], q.orientation, sizeof v[c]);
	}
	for (int c = 0; c < 8; c++)
		if (wd[c] > 0 && (r < 0 || wd[c] > wd[r]))
			r = c;
	if (r < 0)
		return 0;
	for (int c = 0; c < 8; c++) {
		float d = v[c][0] * v[r][0] + v[c][1] * v[r][1] + v[c][2] * v[r][2];
		float sg = d < 0 ? -wd[c] : wd[c];
		if (!(wd[c] > 0))
			continue;
		for (int k = 0; k < 3; k++)
			s[k] += sg * v[c][k];
	}
	len = sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
	if (s[2] < 0 || (s[2] == 0 && (s[1] < 0 || (s[1] == 0 && s[0] < 0))))
		len = -len;
	if (len != 0)
		for (int k = 0; k < 3; k++)
			ori[k] = s[k] / len;
	return 1;
}

static void filtered_lookups_at(size_t budget)
{
	loom_texture *t = open_tex(g_fab, g_db, budget, 2);
	uint64_t bad = 0, blended = 0;

	printf("  budget %zu\n", budget);
	if (!t)
		return;
	for (int it = 0; it < 20000; it++) {
		double p[3];
		loom_texel a, e;
		double u[3], f[3];
		int64_t i0[3];
		float dens, ori[3];
		int near;
		p[0] = rnd_range(-300, 300) + (double)(rnd() % 1000) / 1000.0;
		p[1] = rnd_range(-200, 200) + (double)(rnd() % 1000) / 1000.0;
		p[2] = rnd_range(-1, g_ref.b3 + 1) + (double)(rnd() % 1000) / 1000.0;
		if (it % 7 == 0) /* voxel centres: the voxel itself */
			p[0] = floor(p[0]) + 0.5, p[1] = floor(p[1]) + 0.5, p[2] = floor(p[2]) + 0.5;
		CHECK_EQ_INT(loom_texture_sample(t, p, LOOM_FILTER_NEAREST, &a), LOOM_OK);
		e = ref_texel(&g_ref, (int64_t)floor(p[0]), (int64_t)floor(p[1]),
		              (int64_t)floor(p[2]));
		bad += !texel_eq(&a, &e);
		CHECK_EQ_INT(loom_texture_sample(t, p, LOOM_FILTER_TRILINEAR, &a), LOOM_OK);
		for (int k = 0; k < 3; k++) {
			u[k] = p[k] - 0.5;
			i0[k] = (int64_t)floor(u[k]);
			f[k] = u[k] - (double)i0[k];
		}
		blended += ref_trilinear(p, &dens, ori);
		if (fabsf(a.density - dens) > 1e-6f)
			bad++;
		for (int k = 0; k < 3; k++)
			if (fabsf(a.orientation[k] - ori[k]) > 1e-5f)
				bad++;
		near = (f[2] >= 0.5) | (f[0] >= 0.5) << 1 | (f[1] >= 0.5) << 2;
		e = ref_texel(&g_ref, i0[0] + (near >> 1 & 1), i0[1] + (near >> 2 & 1),
		              i0[2] + (near & 1));
		if (a.kind != e.kind || a.type != e.type || a.label != e.label ||
		    a.albedo[0] != e.albedo[0])
			bad++;
		/* the voxel containing p is that corner */
		if (e.label != ref_texel(&g_ref, (int64_t)floor(p[0]), (int64_t)floor(p[1]),
		                         (int64_t)floor(p[2])).label)
			bad++;
		if (it % 7 == 0) {
			loom_texel c = ref_texel(&g_ref, (int64_t)floor(p[0]), (int64_t)floor(p[1]),
			                         (int64_t)floor(p[2]));
			if (fabsf(a.density - c.density) > 1e-6f)
				bad++;
		}
	}
	CHECK_EQ_INT(bad, 0);
	CHECK(blended > 5000);
	loom_texture_close(t);
}

/* Batch = one sample per point; NULL channels untouched. */
/* A trilinear sample of texture t at p with channels ch (into *a)
   against the reference's (ref_trilinear, of g_ref): the number of
   values that differ (density; orientation when ch has it). */
static uint64_t tri_mismatch(loom_texture *t, const double p[3], unsigned ch, loom_texel *a)
{
	float dens, ori[3];
	uint64_t bad = 0;

	CHECK_EQ_INT(loom_texture_sample_ch(t, p, LOOM_FILTER_TRILINEAR, ch, a), LOOM_OK);
	ref_trilinear(p, &dens, ori);
	bad += fabsf(a->density - dens) > 1e-6f;
	for (int k = 0; k < 3 && (ch & LOOM_CHANNEL_ORIENTATION); k++)
		bad += fabsf(a->orientation[k] - ori[k]) > 1e-5f;
	return bad;
}

static loom_texel masked(loom_texel a, unsigned ch);

/* Lookups in the air (lookup.c src_air): a voxel whose source bricks,
   for every offset the crossing's bound allows, are stored as nothing, or
   (lookups that read no label) whose source tiles the occupancy table
   shows empty at those heights, is answered without the column's offset.
   Two fixtures: bricks 1 voxel deep (the empty bricks follow the cloth's
   surface closely, so a bound too tight by a voxel gives wrong voxels)
   and 8 x 8 x 16 bricks (every brick holds the whole slab, none is empty:
   only the occupancy table of 4 x 4-column tiles answers).  Every voxel
   of two repeats, with every channel and then density alone and with
   orientation (twice: the table is filled as bricks are read), and
   trilinear samples, equal the reference.  The slab's top layer, air in
   the tiny exemplars, is answered without an offset but at most at the
   corner columns (which the bound leaves out where the corner term sets
   them): at most 4 offsets per crossing without the edge fix. */
static void air_without_offsets(void)
{
	const uint32_t bricks[2][3] = {{4, 4, 1}, {8, 8, 16}};
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t;
	loom_texture_stats st;
	ref r;
	uint64_t nonempty = 0, bad = 0, top = 0;
	int64_t M = g_design ? g_design->rows : 0, N = g_design ? g_design->cols : 0;

	if (!g_ok)
		return;
	for (int fx = 1; fx >= 0; fx--) {
		loom_db_info info;
		if (block_fixture(fx ? "tiles.ldb" : "thin.ldb", bricks[fx], 1, NULL, &db, &f,
		                  &r) != 0)
			return;
		loom_db_get_info(db, &info);
		int64_t lo[3] = {-3, -2, -2};
		int64_t hi[3] = {2 * N * r.b1 + 3, 2 * M * r.b2 + 1, (int64_t)r.b3 + 2};
		t = open_tex(f, db, 8u << 20, 1);
		CHECK(t != NULL);
		if (t) {
			nonempty = 0;
			CHECK_EQ_INT(check_box(t, &r, lo, hi, 0, &nonempty), 0);
			CHECK_EQ_INT(check_box(t, &r, lo, hi, 1, NULL), 0);
			CHECK(nonempty > 1000);
			CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
			if (fx) /* no empty brick, and the table answers no label lookup */
				CHECK(info.n_empty_bricks == 0 && st.empty_bricks == 0);
			bad = 0;
			for (int pass = 0; pass < 4; pass++) {
				unsigned ch = pass & 1 ? LOOM_CHANNEL_DENSITY | LOOM_CHANNEL_ORIENTATION
				                       : LOOM_CHANNEL_DENSITY;
				for (int64_t z = lo[2]; z < hi[2]; z++)
					for (int64_t y = lo[1]; y < hi[1]; y++)
						for (int64_t x = lo[0]; x < hi[0]; x++) {
							loom_texel a, e = masked(ref_texel(&r, x, y, z), ch);
							CHECK_EQ_INT(loom_texture_voxel_ch(t, x, y, z, ch, &a),
							             LOOM_OK);
							bad += !texel_eq(&a, &e);
						}
			}
			CHECK_EQ_INT(bad, 0);
			CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
			printf("  bricks %ux%ux%u: %llu lookups, %llu requests for empty bricks or "
			       "answered as air\n", bricks[fx][0], bricks[fx][1], bricks[fx][2],
			       (unsigned long long)st.lookups, (unsigned long long)st.empty_bricks);
			if (fx) /* the occupancy table answered density lookups */
				CHECK(st.empty_bricks > st.lookups / 10);
			CHECK_EQ_INT(st.hits + st.misses + st.empty_bricks, st.brick_requests);
			/* trilinear samples, density alone and with orientation,
			   against the reference's (ref_trilinear reads g_ref: this
			   fixture's reference swapped in) */
			ref saved = g_ref;
			g_ref = r;
			for (int k = 0; k < 20000; k++) {
				double p[3] = {
					(double)rnd_range(-40, 200) + (double)(rnd() % 1000) / 1000.0,
					(double)rnd_range(-40, 200) + (double)(rnd() % 1000) / 1000.0,
					(double)rnd_range(0, r.b3) + (double)(rnd() % 1000) / 1000.0};
				unsigned ch = k & 1 ? LOOM_CHANNEL_DENSITY
				                    : LOOM_CHANNEL_DENSITY | LOOM_CHANNEL_ORIENTATION;
				loom_texel a;
				bad += tri_mismatch(t, p, ch, &a);
			}
			/* and every density-only footprint of the box, corner
			   columns included (tri_dens answers air columns with
			   src_air; a joint test of all four was tried, and this
			   caught it ignoring a corner column or a tile) */
			for (int64_t z = -1; z <= (int64_t)r.b3; z++)
				for (int64_t y = lo[1]; y < hi[1]; y++)
					for (int64_t x = lo[0]; x < hi[0]; x++) {
						double p[3] = {(double)x + 0.75, (double)y + 0.75,
						               (double)z + 0.25};
						loom_texel a;
						bad += tri_mismatch(t, p, LOOM_CHANNEL_DENSITY, &a);
					}
			g_ref = saved;
			CHECK_EQ_INT(bad, 0);
			loom_texture_close(t);
		}
		if (!fx)
			break; /* the thin fixture stays for the top layer */
		ref_free(&r);
		loom_fabric_free(f);
		loom_db_close(db);
	}
	/* the top layer: the fixed fabric evaluates offsets for a minority of
	   its columns (those whose bound reaches the cloth's top bricks); the
	   same design without the fix (every offset 0: each column reads its
	   own source voxel, in an empty brick) for at most the corners */
	for (int k = 0; k < 2; k++) {
		loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
		loom_fabric *f0 = f;
		int64_t z = (int64_t)r.b3 - 1;
		if (k) {
			o.rank = 0;
			f0 = NULL;
			CHECK_EQ_INT(loom_fabric_synthesize(g_design, db, "thin.ldb", &o, &f0, NULL),
			             LOOM_OK);
			if (!f0)
				break;
		}
		t = open_tex(f0, db, 8u << 20, 1);
		CHECK(t != NULL);
		bad = top = 0;
		for (int64_t y = 0; t && y < M * r.b2; y++)
			for (int64_t x = 0; x < N * r.b1; x++) {
				loom_texel a;
				CHECK_EQ_INT(loom_texture_voxel(t, x, y, z, &a), LOOM_OK);
				if (!k) { /* the fixed fabric is the reference's */
					loom_texel b = ref_texel(&r, x, y, z);
					bad += !texel_eq(&a, &b);
				}
				top += a.density > 0;
			}
		if (t) {
			CHECK_EQ_INT(bad, 0);
			CHECK_EQ_INT(top, 0); /* the fixture's premise: air there */
			CHECK_EQ_INT(loom_texture_get_stats(t, &st), LOOM_OK);
			printf("  top layer, %s: %llu lookups, %llu crossings, %llu offsets "
			       "evaluated\n", k ? "no edge fix" : "edge fix",
			       (unsigned long long)st.lookups, (unsigned long long)st.crossings,
			       (unsigned long long)st.dz_columns);
			CHECK(st.crossings == (uint64_t)(M * N));
			if (k)
				CHECK(st.dz_columns <= 4 * st.crossings);
			else
				CHECK(st.dz_columns * 2 < st.lookups);
			CHECK_EQ_INT(st.hits + st.misses + st.empty_bricks, st.brick_requests);
			loom_texture_close(t);
		}
		if (k)
			loom_fabric_free(f0);
	}
	ref_free(&r);
	loom_fabric_free(f);
	loom_db_close(db);
}


/* A crossing whose whole border is raised by 14 voxels or more (its
   source block's edge coefficients lowered): the screened fix sinks back
   to about 2 inside, so its columns read source voxels 2 to 70 below
   their own, far more than any woven fabric's.  Points, density-only
   points, trilinear footprints and region reads against the reference,
   at the smallest budget and a large one.  The crossing's offset bound
   (xent_bound) must hold the interior's low offsets; it does by
   construction (each side's ranges pass through corner rows or columns
   where the other sides' fields vanish, so the bound holds 0: this test
   passed before the widening too), unlike the render majorant's, which
   test_render_grid checks on such a block. */
static void raised_block(void)
{
	const uint32_t brick[3] = {4, 4, 1};
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t;
	ref r;
	loom_synth_nbhd nb = {0, 0, 0, 0, 0};
	int64_t I = -1, J = -1;
	float *dz, blo = INFINITY, ilo = INFINITY;
	uint64_t bad = 0, nonempty = 0;

	if (!g_ok || block_fixture("raised.ldb", brick, 1, NULL, &db, &f, &r) != 0)
		return;
	/* a crossing whose source block is none of its neighbours' */
	for (int64_t i = 1; i + 1 < (int64_t)g_design->rows && I < 0; i++)
		for (int64_t j = 1; j + 1 < (int64_t)g_design->cols && I < 0; j++) {
			loom_synth_nbhd_at(&r.lk, i, j, &nb);
			if (nb.self != nb.n && nb.self != nb.s && nb.self != nb.w &&
			    nb.self != nb.e) {
				I = i;
				J = j;
			}
		}
	CHECK(I >= 0);
	dz = malloc(sizeof(float) * r.b1 * r.b2);
	if (I >= 0 && dz) {
		float lam = 3.0f * (float)r.b3;
		lower_block(f->ef, nb.self, lam, NULL);
		lower_block(r.ef, nb.self, lam, NULL);
		r.cI = INT64_MIN;
		loom_edgefix_block(r.ef, &nb, dz);
		for (uint32_t y = 0; y < r.b2; y++)
			for (uint32_t x = 0; x < r.b1; x++) {
				float v = dz[y * r.b1 + x];
				int corner = (x == 0 || x == r.b1 - 1) && (y == 0 || y == r.b2 - 1);
				if (corner)
					continue; /* the corner term's */
				if (x == 0 || y == 0 || x == r.b1 - 1 || y == r.b2 - 1)
					blo = v < blo ? v : blo;
				else
					ilo = v < ilo ? v : ilo;
			}
		printf("  crossing (%lld,%lld), block %u x %u x %u: border offsets >= %.2f, "
		       "interior down to %.2f voxels\n", (long long)I, (long long)J, r.b1, r.b2,
		       r.b3, blo, ilo);
		/* the premise: raised all round, and sinking inside by more than
		   a voxel below the border's least value */
		CHECK(blo > 1.0f);
		CHECK(ilo < blo - 1.5f);
		for (int pass = 0; pass < 2; pass++) {
			int64_t lo[3] = {(J - 1) * r.b1, (I - 1) * r.b2, -2};
			int64_t hi[3] = {(J + 2) * r.b1, (I + 2) * r.b2, 3 * (int64_t)r.b3};
			t = open_tex(f, db, pass ? 8u << 20 : min_budget(f, db, 1), 1);
			CHECK(t != NULL);
			if (!t)
				continue;
			nonempty = 0;
			bad += check_box(t, &r, lo, hi, pass, &nonempty);
			for (int64_t z = lo[2]; z < hi[2]; z++)
				for (int64_t y = lo[1]; y < hi[1]; y++)
					for (int64_t x = lo[0]; x < hi[0]; x++) {
						loom_texel a, e = masked(ref_texel(&r, x, y, z),
						                         LOOM_CHANNEL_DENSITY);
						CHECK_EQ_INT(loom_texture_voxel_ch(t, x, y, z,
						                                   LOOM_CHANNEL_DENSITY, &a),
						             LOOM_OK);
						bad += !texel_eq(&a, &e);
					}
			ref saved = g_ref;
			g_ref = r;
			for (int64_t z = lo[2]; z < hi[2]; z++)
				for (int64_t y = lo[1]; y < hi[1]; y++)
					for (int64_t x = lo[0]; x < hi[0]; x++) {
						double p[3] = {(double)x + 0.5, (double)y + 0.25,
						               (double)z + 0.75};
						loom_texel a;
						bad += tri_mismatch(t, p, LOOM_CHANNEL_DENSITY, &a);
					}
			g_ref = saved;
			for (int lay = 0; lay < 2; lay++) { /* density alone, every channel */
				bad += region_vs_ref(t, &r, lo, hi, 1, lay);
				bad += region_vs_ref(t, &r, lo, hi, 31, lay);
			}
			CHECK(nonempty > 100);
			loom_texture_close(t);
		}
		CHECK_EQ_INT(bad, 0);
	}
	free(dz);
	ref_free(&r);
	loom_fabric_free(f);
	loom_db_close(db);
}

/* Batches equal point lookups, at a budget holding the working set and at
   one far below it (evictions inside the batch, 2 thread slots), and a
   bad position fails alone in a small and a large batch, the batch
   returning the first bad index's error. */
static void batch_lookups(void)
{
	enum { n = 3000 };
	size_t budgets[2];
	double *x = malloc(8 * n), *y = malloc(8 * n), *z = malloc(8 * n);
	float *dens = malloc(4 * n), *ori = malloc(12 * n), *alb = malloc(12 * n);
	uint8_t *kind = malloc(n), *type = malloc(n);
	uint64_t bad = 0;

	budgets[0] = 8u << 20;
	budgets[1] = min_budget(g_fab, g_db, 2) + 3000;
	for (int b = 0; b < 2; b++) {
		loom_texture *t = open_tex(g_fab, g_db, budgets[b], 2);
		if (!t)
			break;
		for (int i = 0; i < n; i++) {
			x[i] = (double)rnd_range(-500, 500) + 0.37 * (i % 3);
			y[i] = (double)rnd_range(-500, 500) + 0.11 * (i % 5);
			z[i] = (double)rnd_range(-2, g_ref.b3 + 2) + 0.5;
		}
		for (int filter = 0; filter < 2; filter++) {
			loom_texture_channels ch = {dens, ori, kind, type, alb};
			memset(type, 0xEE, n);
			if (filter)
				ch.type = NULL;
			CHECK_EQ_INT(loom_texture_sample_batch(t, n, x, y, z, filter, &ch), LOOM_OK);
			for (int i = 0; i < n; i++) {
				double p[3] = {x[i], y[i], z[i]};
				loom_texel a;
				loom_texture_sample(t, p, filter, &a);
				if (dens[i] != a.density || memcmp(ori + 3 * i, a.orientation, 12) ||
				    kind[i] != a.kind || memcmp(alb + 3 * i, a.albedo, 12))
					bad++;
				if (filter ? type[i] != 0xEE : type[i] != a.type)
					bad++;
			}
		}
		/* a bad position fails alone, in a small and a large batch */
		x[5] = NAN;
		z[2500] = 1e300;
		{
			loom_texture_channels ch = {dens, NULL, kind, NULL, NULL};
			CHECK_EQ_INT(loom_texture_sample_batch(t, 10, x, y, z, 0, &ch), LOOM_EINVAL);
			CHECK(dens[5] == 0 && kind[5] == 0);
			/* the first bad index's error: EINVAL (NaN at 5), not ERANGE */
			CHECK_EQ_INT(loom_texture_sample_batch(t, n, x, y, z, 1, &ch), LOOM_EINVAL);
			CHECK(dens[5] == 0 && kind[5] == 0 && dens[2500] == 0 && kind[2500] == 0);
			for (int i = 0; i < n; i++) {
				double p[3] = {x[i], y[i], z[i]};
				loom_texel a;
				if (i == 5 || i == 2500)
					continue;
				loom_texture_sample(t, p, 1, &a);
				if (dens[i] != a.density || kind[i] != a.kind)
					bad++;
			}
		}
		loom_texture_close(t);
	}
	CHECK_EQ_INT(bad, 0);
	free(x), free(y), free(z), free(dens), free(ori), free(alb), free(kind), free(type);
}

/* t's fields outside channel mask ch zeroed (what the _ch calls return). */
static loom_texel masked(loom_texel a, unsigned ch)
{
	if (!(ch & LOOM_CHANNEL_DENSITY))
		a.density = 0;
	if (!(ch & LOOM_CHANNEL_ORIENTATION))
		a.orientation[0] = a.orientation[1] = a.orientation[2] = 0;
	if (!(ch & LOOM_CHANNEL_MATERIAL)) {
		a.albedo[0] = a.albedo[1] = a.albedo[2] = a.alignment = 0;
		a.kind = a.type = a.label = 0;
	}
	return a;
}

/* Channel masks: every mask, point lookups against the brute-force
   reference, nearest and trilinear samples against the full sample
   (itself checked against the reference by filtered_lookups), batches
   with one channel against single samples; at the smallest budget (the
   bricks churn, corner pairs straddle bricks: 8-deep bricks) and a large
   one, with the lookups of all masks interleaved on one thread state. */
/* n density-only lookups at random voxels (z in 0..b3) of texture t, or
   until the first that inflates anything (first_fill); the statistics
   after them in *st.  Returns 1. */
static int cold_density(loom_texture *t, int64_t b3, int n, int first_fill,
                        loom_texture_stats *st)
{
	for (int it = 0; it < n; it++) {
		loom_texel a;
		loom_texture_voxel_ch(t, rnd_range(-300, 300), rnd_range(-200, 200),
		                      rnd_range(0, b3), LOOM_CHANNEL_DENSITY, &a);
		if (first_fill) {
			loom_texture_get_stats(t, st);
			if (st->bytes_decompressed)
				break;
		}
	}
	loom_texture_get_stats(t, st);
	return 1;
}

/* Format versions 1, 2 (each plane a unit; density-only lookups then
   cache density units, texture.c) and 3 (the density unit in segments,
   filled one by one): the same exemplars in each, every mask against each
   one's brute-force reference, at the smallest budget (below the working
   set) and a large one; version 2 reads fewer bytes for density alone
   than version 1, and version 3 inflates fewer than version 2.  The
   fourth: version 2 with its density planes stored raw (density_raw),
   whose density misses read each plane's bytes as they are; the fifth:
   the default, version 4 (density zero-run coded), which reads more than
   version 2's deflated planes and less than raw ones. */
static void old_format_same_lookups(void)
{
	char path[5][4200];
	uint32_t brick[3] = {8, 8, 8};
	uint64_t read_d[5] = {0, 0, 0, 0, 0}, infl_d[5] = {0, 0, 0, 0, 0};

	for (int v = 0; v < 5; v++) {
		snprintf(path[v], sizeof path[v], "%s/v%d.ldb", tmpdir, v + 1);
		loom_exgen_params p;
		loom_diag d = {0};
		loom_db *db = NULL;
		loom_fabric *f = NULL;
		ref r;
		loom_exgen_preset("tiny", &p);
		p.seed = 5;
		p.threads = 2;
		memcpy(p.brick, brick, sizeof p.brick);
		p.db_version = v < 3 ? (uint32_t)v + 1 : v == 3 ? 2 : 0;
		p.density_raw = v == 3;
		CHECK_EQ_INT(loom_exgen_write_db(path[v], &p, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_open(path[v], &db, &d), LOOM_OK);
		if (db)
			f = synth(g_design, db);
		if (!f || ref_init(&r, f, db) != 0) {
			CHECK(0);
			loom_fabric_free(f);
			loom_db_close(db);
			continue;
		}
		{
			loom_db_info info;
			loom_db_get_info(db, &info);
			CHECK_EQ_INT(info.version, v < 3 ? v + 1 : v == 3 ? 2 : 4);
		}
		for (int b = 0; b < 2; b++) {
			size_t budget = b ? 8u << 20 : min_budget(f, db, 1);
			loom_texture *t = open_tex(f, db, budget, 1);
			loom_texture_stats st;
			uint64_t bad = 0;
			if (!t)
				continue;
			for (int it = 0; it < 4000; it++) {
				unsigned ch = it % 3 ? LOOM_CHANNEL_DENSITY : (unsigned)(it % 8);
				int64_t x = rnd_range(-300, 300), y = rnd_range(-200, 200),
				        z = rnd_range(-2, r.b3 + 2);
				loom_texel a, e = masked(ref_texel(&r, x, y, z), ch);
				CHECK_EQ_INT(loom_texture_voxel_ch(t, x, y, z, ch, &a), LOOM_OK);
				bad += !texel_eq(&a, &e);
			}
			CHECK_EQ_INT(bad, 0);
			if (b == 1 && v == 2) {
				/* while nothing is evicted, a density-only miss on
				   version 3 fills the whole plane (all its segments)
				   from one read of its unit */
				loom_texture_close(t);
				t = open_tex(f, db, budget, 1);
				if (t && cold_density(t, r.b3, 1000, 1, &st)) {
					CHECK_EQ_INT(st.evictions, 0);
					CHECK_EQ_INT(st.bytes_decompressed, 8 * 8 * 8);
					CHECK_EQ_INT(st.misses, 1);
				}
			}
			if (b == 0) { /* density alone, from cold */
				loom_texture_close(t);
				t = open_tex(f, db, budget, 1);
				if (t && cold_density(t, r.b3, 2000, 0, &st)) {
					read_d[v] = st.bytes_read;
					infl_d[v] = st.bytes_decompressed;
				}
			}
			loom_texture_close(t);
		}
		ref_free(&r);
		loom_fabric_free(f);
		loom_db_close(db);
	}
	printf("  density-only lookups at the smallest budget read / inflate %llu / "
	       "%llu bytes (version 1), %llu / %llu (version 2), %llu / %llu (version "
	       "3), %llu / %llu (version 2, density raw), %llu / %llu (version 4)\n",
	       (unsigned long long)read_d[0], (unsigned long long)infl_d[0],
	       (unsigned long long)read_d[1], (unsigned long long)infl_d[1],
	       (unsigned long long)read_d[2], (unsigned long long)infl_d[2],
	       (unsigned long long)read_d[3], (unsigned long long)infl_d[3],
	       (unsigned long long)read_d[4], (unsigned long long)infl_d[4]);
	CHECK(read_d[1] > 0 && read_d[1] < read_d[0]);
	/* raw: every density byte read as it is (no smaller than version 2's
	   deflated reads) and nothing inflated beyond it */
	CHECK(read_d[3] > read_d[1] && read_d[3] == infl_d[3]);
	CHECK(infl_d[2] > 0 && infl_d[2] < infl_d[1] && infl_d[1] < infl_d[0]);
	/* zero runs: between deflate and raw in bytes read, and fewer read
	   than decoded */
	CHECK(read_d[4] > read_d[1] && read_d[4] < read_d[3]);
	CHECK(infl_d[4] > read_d[4]);
}

static void channel_masks(void)
{
	size_t budgets[2];
	uint64_t bad = 0, nonempty = 0;

	budgets[0] = min_budget(g_fab, g_db, 1);
	budgets[1] = 8u << 20;
	for (int b = 0; b < 2; b++) {
		loom_texture *t = open_tex(g_fab, g_db, budgets[b], 1);
		loom_texture *full = open_tex(g_fab, g_db, 8u << 20, 1);
		loom_texel a, e;
		if (!t || !full) {
			loom_texture_close(t);
			loom_texture_close(full);
			return;
		}
		CHECK_EQ_INT(loom_texture_voxel_ch(t, 0, 0, 0, 8, &a), LOOM_EINVAL);
		CHECK_EQ_INT(loom_texture_sample_ch(t, (double[3]){0, 0, 0}, 0, 9, &a), LOOM_EINVAL);
		for (int it = 0; it < 6000; it++) {
			unsigned ch = (unsigned)(it % 8);
			int64_t x = rnd_range(-300, 300), y = rnd_range(-200, 200),
			        z = rnd_range(-2, g_ref.b3 + 2);
			double p[3];
			e = masked(ref_texel(&g_ref, x, y, z), ch);
			CHECK_EQ_INT(loom_texture_voxel_ch(t, x, y, z, ch, &a), LOOM_OK);
			bad += !texel_eq(&a, &e);
			nonempty += e.density > 0;
			p[0] = (double)x + (double)(rnd() % 1000) / 1000.0;
			p[1] = (double)y + (double)(rnd() % 1000) / 1000.0;
			p[2] = (double)z + (double)(rnd() % 1000) / 1000.0;
			for (int filter = 0; filter < 2; filter++) {
				CHECK_EQ_INT(loom_texture_sample(full, p, filter, &e), LOOM_OK);
				e = masked(e, ch);
				CHECK_EQ_INT(loom_texture_sample_ch(t, p, filter, ch, &a), LOOM_OK);
				bad += !texel_eq(&a, &e);
			}
		}
		/* batches of one channel each */
		{
			enum { n = 500 };
			double x[n], y[n], z[n];
			float dens[n], ori[3 * n];
			uint8_t kind[n];
			for (int i = 0; i < n; i++) {
				x[i] = (double)rnd_range(-400, 400) + 0.29 * (i % 4);
				y[i] = (double)rnd_range(-400, 400) + 0.13 * (i % 7);
				z[i] = (double)rnd_range(-2, g_ref.b3 + 2) + 0.61;
			}
			for (int filter = 0; filter < 2; filter++)
				for (int c = 0; c < 3; c++) {
					loom_texture_channels chs = {NULL, NULL, NULL, NULL, NULL};
					if (c == 0)
						chs.density = dens;
					else if (c == 1)
						chs.orientation = ori;
					else
						chs.kind = kind;
					CHECK_EQ_INT(loom_texture_sample_batch(t, n, x, y, z, filter, &chs),
					             LOOM_OK);
					for (int i = 0; i < n; i++) {
						double p[3] = {x[i], y[i], z[i]};
						loom_texture_sample(full, p, filter, &e);
						if (c == 0)
							bad += dens[i] != e.density;
						else if (c == 1)
							bad += memcmp(ori + 3 * i, e.orientation, 12) != 0;
						else
							bad += kind[i] != e.kind;
					}
				}
		}
		loom_texture_close(t);
		loom_texture_close(full);
	}
	CHECK_EQ_INT(bad, 0);
	CHECK(nonempty > 500);
}


/* Ray walks (unit steps, random directions; lookup.c walk_next prefetches
   the columns ahead of point lookups, trilinear corner columns are
   reused from the last sample's footprint), with a jump to a far
   crossing now and then (five: at the smallest budget a thread state
   holds only 4 crossing entries, so the jumps evict the entries that the
   kept corner columns point to): every point lookup, each mask, equals the brute-force
   reference, every trilinear sample the reference's trilinear blend. */
static void walks_equal_reference(void)
{
	uint64_t bad = 0, steps = 0, nonempty = 0, tri_fast_checked = 0;

	for (int b = 0; b < 2; b++) {
		size_t budget = b ? 8u << 20 : min_budget(g_fab, g_db, 1);
		loom_texture *t = open_tex(g_fab, g_db, budget, 1);
		if (!t)
			continue;
		for (int w = 0; w < 300; w++) {
			double p[3], d[3], len = 0;
			p[0] = (double)rnd_range(-300, 300) + (double)(rnd() % 1000) / 1000.0;
			p[1] = (double)rnd_range(-200, 200) + (double)(rnd() % 1000) / 1000.0;
			p[2] = (double)rnd_range(0, g_ref.b3) + (double)(rnd() % 1000) / 1000.0;
			for (int k = 0; k < 3; k++) {
				d[k] = (double)rnd_range(-1000, 1001) / (k == 2 ? 8000.0 : 1000.0);
				len += d[k] * d[k]; /* mostly across: the fabric is thin */
			}
			len = len > 0 ? sqrt(len) : 1;
			for (int k = 0; k < 3; k++)
				d[k] /= len;
			if (w % 5 == 0) /* along z only: the same column again */
				d[0] = d[1] = 0, d[2] = 1;
			for (int st = 0; st < 80; st++, steps++) {
				unsigned ch = (unsigned)(st + w) % 8;
				int64_t q[3] = {(int64_t)floor(p[0]), (int64_t)floor(p[1]),
				                (int64_t)floor(p[2])};
				loom_texel a, e = masked(ref_texel(&g_ref, q[0], q[1], q[2]), ch);
				CHECK_EQ_INT(loom_texture_voxel_ch(t, q[0], q[1], q[2], ch, &a), LOOM_OK);
				bad += !texel_eq(&a, &e);
				nonempty += e.density > 0;
				ch = st % 3 ? LOOM_CHANNEL_DENSITY | LOOM_CHANNEL_ORIENTATION
				            : LOOM_CHANNEL_DENSITY;
				bad += tri_mismatch(t, p, ch, &a);
				if (ch == LOOM_CHANNEL_DENSITY) {
					/* density alone (tri_dens_fast) is bit for bit the
					   density of the general path */
					loom_texel g;
					CHECK_EQ_INT(loom_texture_sample_ch(t, p, LOOM_FILTER_TRILINEAR,
					                                    LOOM_CHANNEL_ALL, &g),
					             LOOM_OK);
					bad += memcmp(&a.density, &g.density, sizeof a.density) != 0;
					tri_fast_checked++;
				}
				for (int j = 0; st % 13 == 12 && j < 5; j++) { /* jumps, and back */
					int64_t x = rnd_range(-3000, 3000), y = rnd_range(-2000, 2000);
					e = ref_texel(&g_ref, x, y, q[2]);
					CHECK_EQ_INT(loom_texture_voxel(t, x, y, q[2], &a), LOOM_OK);
					bad += !texel_eq(&a, &e);
				}
				for (int k = 0; k < 3; k++)
					p[k] += d[k];
			}
		}
		loom_texture_close(t);
	}
	printf("  %llu steps, %llu non-empty, %llu density-only trilinear samples\n",
	       (unsigned long long)steps, (unsigned long long)nonempty,
	       (unsigned long long)tri_fast_checked);
	CHECK_EQ_INT(bad, 0);
	CHECK(nonempty > 1000);
	CHECK(tri_fast_checked > 5000);
}

/* Flip a byte of a stored brick in a copy of the database: the lookups
   that need that brick fail with LOOM_ECORRUPT naming it; all other voxels
   stay right; the failure repeats (retry) and the texture stays usable. */
static uint64_t le64(const uint8_t *p)
{
	uint64_t v = 0;
	for (int i = 7; i >= 0; i--)
		v = v << 8 | p[i];
	return v;
}

static uint32_t le32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Flip a byte in the density data of every third stored brick of the
   .ldb image data[0 .. len) (version 1: the middle of the brick's one
   stream; version 2: of its density unit); returns how many. */
static unsigned corrupt_every_third(uint8_t *data, size_t len)
{
	const uint8_t *tr = data + len - 64, *meta;
	uint64_t mo = le64(tr + 8), io;
	uint32_t nb = le32(tr + 28), eb;
	unsigned stored = 0, hit = 0;

	if (len < 192 || mo + 64 > len)
		return 0;
	meta = data + mo;
	eb = le32(meta + 20);
	io = le64(meta + 40);
	for (uint32_t id = 0; id < nb && mo + io + (uint64_t)(id + 1) * eb <= len; id++) {
		const uint8_t *e = meta + io + (size_t)id * eb;
		uint64_t off = le64(e);
		uint32_t n = eb == 56 ? le32(e + 24) : le32(e + 8); /* density unit / brick */
		if (!off || !n || off + n > mo)
			continue;
		if (stored++ % 3 == 1) {
			data[off + n / 2] ^= 0x5A;
			hit++;
		}
	}
	return hit;
}

static void corrupt_brick(void)
{
	char path[4300];
	loom_db *bad_db = NULL;
	loom_db_info info;
	loom_texture *t = NULL;
	uint8_t *data = NULL;
	size_t len;
	FILE *fp;
	uint64_t wrong = 0, failed = 0, failed_again = 0;
	int64_t lo[3] = {-30, -20, 0}, hi[3];

	if (!g_ok)
		return;
	snprintf(path, sizeof path, "%s/corrupt.ldb", tmpdir);
	loom_db_get_info(g_db, &info);
	fp = fopen(db_path, "rb");
	if (!fp)
		return;
	fseek(fp, 0, SEEK_END);
	len = (size_t)ftell(fp);
	rewind(fp);
	data = malloc(len);
	CHECK(fread(data, 1, len, fp) == len);
	fclose(fp);
	/* every third stored brick (in id order) gets one byte of its
	   density plane flipped (found through the trailer, the metadata
	   header and the brick index, docs/formats.md), so the region below
	   meets corrupt and sound bricks whatever blocks synthesis chose */
	CHECK(corrupt_every_third(data, len) > 0);
	fp = fopen(path, "wb");
	CHECK(fwrite(data, 1, len, fp) == len);
	fclose(fp);
	free(data);
	CHECK_EQ_INT(loom_db_open(path, &bad_db, NULL), LOOM_OK); /* index intact */
	if (!bad_db)
		return;
	t = open_tex(g_fab, bad_db, 1u << 20, 2);
	if (!t)
		goto done;
	hi[0] = (int64_t)g_design->cols * g_ref.b1 * 2;
	hi[1] = (int64_t)g_design->rows * g_ref.b2 * 2;
	hi[2] = g_ref.b3;
	for (int pass = 0; pass < 2; pass++)
		for (int64_t z = lo[2]; z < hi[2]; z++)
			for (int64_t y = lo[1]; y < hi[1]; y++)
				for (int64_t x = lo[0]; x < hi[0]; x++) {
					loom_texel a, e;
					int rc = loom_texture_voxel(t, x, y, z, &a);
					if (rc != LOOM_OK) {
						CHECK_EQ_INT(rc, LOOM_ECORRUPT);
						if (pass == 0 && failed == 0) {
							const char *m = loom_texture_errmsg(t);
							printf("  %s\n", m);
							CHECK_STR_CONTAINS(m, "corrupt.ldb: brick ");
							CHECK_STR_CONTAINS(m, "exemplar");
						}
						CHECK(a.density == 0 && a.kind == 0);
						if (pass == 0)
							failed++;
						else
							failed_again++;
						continue;
					}
					e = ref_texel(&g_ref, x, y, z);
					wrong += !texel_eq(&a, &e);
				}
	CHECK(failed > 0);
	CHECK_EQ_INT(failed_again, failed); /* retried, same result */
	CHECK_EQ_INT(wrong, 0);
	{
		/* density-only trilinear (tri_dens) fails where the general path
		   (density + orientation) fails, and agrees bit for bit elsewhere */
		uint64_t differ = 0, tri_failed = 0;
		for (int it = 0; it < 4000; it++) {
			double p[3] = {(double)rnd_range(lo[0], hi[0] - 1) + (double)(rnd() % 1000) / 1000.0,
			               (double)rnd_range(lo[1], hi[1] - 1) + (double)(rnd() % 1000) / 1000.0,
			               (double)rnd_range(lo[2], hi[2] - 1) + (double)(rnd() % 1000) / 1000.0};
			loom_texel a, g;
			int ra = loom_texture_sample_ch(t, p, LOOM_FILTER_TRILINEAR,
			                                LOOM_CHANNEL_DENSITY, &a);
			int rg = loom_texture_sample_ch(t, p, LOOM_FILTER_TRILINEAR,
			                                LOOM_CHANNEL_DENSITY | LOOM_CHANNEL_ORIENTATION,
			                                &g);
			differ += ra != rg || memcmp(&a.density, &g.density, sizeof a.density) != 0;
			tri_failed += ra != LOOM_OK;
		}
		printf("  density-only trilinear: %llu of 4000 samples failed, as the general "
		       "path\n", (unsigned long long)tri_failed);
		CHECK_EQ_INT(differ, 0);
		CHECK(tri_failed > 0);
	}
	{
		loom_texture_stats st;
		loom_texture_region reg = {0};
		uint8_t *buf = malloc((size_t)(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]));
		reg.density = buf;
		CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &reg), LOOM_ECORRUPT);
		free(buf);
		loom_texture_get_stats(t, &st);
		CHECK(st.errors >= 2 * failed); /* each failed voxel retried the read */
		printf("  %llu voxels failed (twice), %llu read errors, others right\n",
		       (unsigned long long)failed, (unsigned long long)st.errors);
	}
done:
	loom_texture_close(t);
	loom_db_close(bad_db);
}

/* At each crossing centre, the top-most yarn voxel (density >= the
   database's top threshold, not a flyaway) is warp exactly where W says
   warp over. */
static uint64_t warp_on_top(const loom_design *d, loom_db *db, uint32_t max_side,
                            uint64_t *checked)
{
	loom_fabric *f = synth(d, db);
	loom_texture *t;
	loom_db_info info;
	uint64_t bad = 0;
	uint32_t rows, cols;

	*checked = 0;
	if (!f)
		return 1;
	t = open_tex(f, db, 16u << 20, 1);
	loom_db_get_info(db, &info);
	rows = d->rows < max_side ? d->rows : max_side;
	cols = d->cols < max_side ? d->cols : max_side;
	for (int rep = 0; rep < 2 && t; rep++) {
		int64_t I0 = rep ? 100003 * (int64_t)d->rows : 0;  /* another group */
		int64_t J0 = rep ? -7919 * (int64_t)d->cols : 0;
		for (int64_t I = I0; I < I0 + rows; I++)
			for (int64_t J = J0; J < J0 + cols; J++) {
				int64_t x = J * info.block[0] + info.block[0] / 2;
				int64_t y = I * info.block[1] + info.block[1] / 2;
				int top = 0;
				for (int64_t z = info.block[2] - 1; z >= 0 && !top; z--) {
					loom_texel a;
					loom_db_exemplar_info e;
					if (loom_texture_voxel(t, x, y, z, &a) != LOOM_OK)
						bad++;
					if (a.kind == 0 || a.density * 255.0f + 0.5f < info.top_threshold)
						continue;
					/* flyaway fibres do not count: check the label's flags
					   in any exemplar (labels are per exemplar; the source
					   exemplar is the fabric's) */
					{
						loom_fabric_source src;
						loom_fabric_source_at(f, I, J, &src);
						loom_db_exemplar(db, src.exemplar, &e);
						if (e.yarns[a.label].flags & LOOM_DB_YARN_FLYAWAY)
							continue;
					}
					top = a.kind;
				}
				{
					uint8_t w = loom_design_at(d, (uint32_t)(((I % d->rows) + d->rows) % d->rows),
					                           (uint32_t)(((J % d->cols) + d->cols) % d->cols));
					if (top != (w ? LOOM_YARN_WARP : LOOM_YARN_WEFT)) {
						if (bad < 3)
							printf("  crossing (%lld,%lld): W %d, top kind %d\n",
							       (long long)I, (long long)J, w, top);
						bad++;
					}
				}
				(*checked)++;
			}
	}
	loom_texture_close(t);
	loom_fabric_free(f);
	return bad;
}

static void warp_on_top_real_designs(void)
{
	static const char map[] =
		"yarn red  #a01010 alignment=0.3\n"
		"yarn gold #d4a017 alignment=0.15\n"
		"colour #d4a017 twill:1/7 warp=red weft=gold\n"
		"colour #a01010 satin:7/1 warp=red weft=gold\n";
	const char *top = getenv("LOOM_TOP");
	const char *wifs[2] = {"data/herringbone-8.wif", "data/overshot-sampler.wif"};
	loom_image *img = NULL;
	loom_design *d = NULL;
	uint64_t checked;
	char path[4300];

	if (!g_ok)
		return;
	for (int k = 0; k < 2; k++) {
		snprintf(path, sizeof path, "%s/%s", top ? top : ".", wifs[k]);
		CHECK_EQ_INT(loom_wif_read(path, &d, NULL), LOOM_OK);
		if (!d)
			continue;
		CHECK_EQ_INT(warp_on_top(d, g_db, 48, &checked), 0);
		printf("  %s: %u x %u, %llu crossing centres checked\n", wifs[k], d->rows,
		       d->cols, (unsigned long long)checked);
		loom_design_free(d);
		d = NULL;
	}
	/* a generated Jacquard: a two-colour picture through a mapping file */
	CHECK_EQ_INT(loom_image_new(40, 40, 3, &img), LOOM_OK);
	if (!img)
		return;
	for (uint32_t y = 0; y < 40; y++)
		for (uint32_t x = 0; x < 40; x++) {
			int r = abs((int)x - 20) + abs((int)y - 20);
			int gold = r < 10 || (r >= 15 && r < 18);
			uint8_t *px = img->pixels + 3 * ((size_t)y * 40 + x);
			px[0] = gold ? 0xd4 : 0xa0;
			px[1] = gold ? 0xa0 : 0x10;
			px[2] = gold ? 0x17 : 0x10;
		}
	CHECK_EQ_INT(loom_design_from_image(img, map, sizeof map - 1, "t.map", &d, NULL),
	             LOOM_OK);
	loom_image_free(img);
	if (!d)
		return;
	CHECK_EQ_INT(warp_on_top(d, g_db, 40, &checked), 0);
	printf("  jacquard: %u x %u, %llu crossing centres checked\n", d->rows, d->cols,
	       (unsigned long long)checked);
	loom_design_free(d);
}

/* Top surface of column (x, y): the highest height where the density
   (nearest lookups) rises through thr going down, interpolated linearly
   between the two voxels around it; -1 for a column that never does. */
static float surface(loom_texture *t, int64_t x, int64_t y, uint32_t b3, float thr)
{
	float up = 0;
	for (int64_t z = (int64_t)b3 - 1; z >= 0; z--) {
		loom_texel tx;
		if (loom_texture_voxel(t, x, y, z, &tx) != LOOM_OK)
			return -2;
		if (tx.density >= thr)
			return (float)z + (tx.density - thr) / (tx.density - up);
		up = tx.density;
	}
	return -1;
}

/* No terraces: between neighbouring columns of one block whose surfaces
   differ by at most half a voxel in the fabric without the edge fix
   (rank 0, the woven reference: same sources, no offsets) and whose
   edge-fix offsets differ by at most a quarter voxel, the edge-fixed
   surfaces differ by less than a whole voxel.  Offsets rounded to whole
   voxels step by one voxel wherever the rounding changes, which this
   catches (43 steps on this fabric with the old rounding, 0 now). */
static void no_terraces(void)
{
	loom_texture *t[2] = {NULL, NULL};
	loom_fabric *f[2] = {NULL, NULL};
	loom_db_info info;
	uint32_t b1, b2, b3;
	int64_t W, H;
	float *h[2] = {NULL, NULL};
	long pairs = 0, steps = 0, corner_pairs = 0, corner_steps = 0;

	if (!g_ok)
		return;
	loom_db_get_info(g_db, &info);
	b1 = info.block[0], b2 = info.block[1], b3 = info.block[2];
	W = (int64_t)g_design->cols * b1;
	H = (int64_t)g_design->rows * b2;
	for (int k = 0; k < 2; k++) {
		loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
		loom_diag d = {0};
		o.rank = k ? 0 : o.rank;
		CHECK_EQ_INT(loom_fabric_synthesize(g_design, g_db, db_path, &o, &f[k], &d), LOOM_OK);
		if (!f[k])
			goto out;
		t[k] = open_tex(f[k], g_db, 16u << 20, 1);
		CHECK(t[k] != NULL);
		if (!t[k])
			goto out;
		h[k] = malloc(sizeof(float) * (size_t)(W * H));
		for (int64_t y = 0; y < H; y++)
			for (int64_t x = 0; x < W; x++)
				h[k][y * W + x] = surface(t[k], x, y, b3, 0.1f);
	}
	for (int64_t y = 0; y < H; y++)
		for (int64_t x = 0; x + 1 < W; x++) {
			int64_t I = y / b2, J = x / b1;
			float r0 = h[1][y * W + x], r1 = h[1][y * W + x + 1];
			float f0 = h[0][y * W + x], f1 = h[0][y * W + x + 1], d0, d1;
			if ((x + 1) % b1 == 0 || r0 < 0 || r1 < 0 || f0 < 0 || f1 < 0 ||
			    fabsf(r1 - r0) > 0.5f)
				continue;
			d0 = loom__texture_dz(t[0], I, J, (uint32_t)(x % b1), (uint32_t)(y % b2));
			d1 = loom__texture_dz(t[0], I, J, (uint32_t)((x + 1) % b1), (uint32_t)(y % b2));
			if (fabsf(d1 - d0) > 0.25f)
				continue;
			if ((x % b1 == 0 || (x + 1) % b1 == b1 - 1) &&
			    (y % b2 == 0 || y % b2 == b2 - 1)) {
				/* a block's corner column: the corner term sets its
				   offset apart from the smooth field (docs/synthesis.md,
				   "Block corners"; its values equal the reference's in
				   reference_matches_fabric) */
				corner_pairs++;
				corner_steps += fabsf(f1 - f0) >= 1;
				continue;
			}
			pairs++;
			if (fabsf(f1 - f0) >= 1)
				steps++;
		}
	printf("  %ld smooth neighbour pairs, %ld steps of a voxel (with a corner column: "
	       "%ld pairs, %ld steps)\n", pairs, steps, corner_pairs, corner_steps);
	CHECK(pairs > 200);
	CHECK_EQ_INT((int)steps, 0);
out:
	for (int k = 0; k < 2; k++) {
		free(h[k]);
		loom_texture_close(t[k]);
		loom_fabric_free(f[k]);
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_texture");
	rng_state = check_seed();
	RUN(setup);
	RUN(bad_arguments);
	RUN(budget_too_small);
	RUN(orient_blend_no_cancel);
	RUN(reference_matches_fabric);
	RUN(brute_force_voxels);
	RUN(crossing_tile_fits);
	RUN(odd_brick_shape);
	RUN(air_without_offsets);
	RUN(raised_block);
	RUN(region_equals_points);
	RUN(tiny_budgets_deterministic);
	RUN(wide_blocks_region);
	RUN(region_paths);
	RUN(region_occupancy);
	RUN(region_sub_voxel);
	RUN(region_blend_edges);
	RUN(line_blend_rule);
	RUN(labels_above_15);
	RUN(filtered_lookups);
	RUN(batch_lookups);
	RUN(channel_masks);
	RUN(walks_equal_reference);
	RUN(old_format_same_lookups);
	RUN(corrupt_brick);
	RUN(warp_on_top_real_designs);
	RUN(no_terraces);
	if (g_ok)
		ref_free(&g_ref);
	loom_fabric_free(g_fab);
	loom_design_free(g_design);
	loom_db_close(g_db);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
