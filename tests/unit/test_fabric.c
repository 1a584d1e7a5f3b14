/*
 * tests/unit/test_fabric.c - fabrics: synthesis against a small generated
 * database, save / open round trips (design, base, tables, metrics), the
 * same bytes for the same seed, database mismatches, every malformed-file
 * case (truncation, flipped bytes in each section, bad magic and version,
 * out-of-range base entries), and correctness checked on the voxels: at
 * the centre of every crossing the top-most yarn of the copied source
 * block is the warp exactly where the design says warp over.
 */
#include "check.h"
#include "tmpdir.h"
#include "synth/fabric_internal.h"

#include <libdeflate.h>
#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

static char db_path[4200], db2_path[4200], db3_path[4200];
static loom_db *db, *db2, *db3;   /* tiny; tiny with another seed; 12 weaves */

static uint32_t le32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
	       (uint32_t)p[3] << 24;
}
static uint64_t le64(const uint8_t *p)
{
	return (uint64_t)le32(p) | (uint64_t)le32(p + 4) << 32;
}
static void put32(uint8_t *p, uint32_t v)
{
	for (int k = 0; k < 4; k++)
		p[k] = (uint8_t)(v >> (8 * k));
}

/* ---- designs ------------------------------------------------------------ */

static loom_design *weave(const char *name, uint32_t rows, uint32_t cols)
{
	loom_weave_params p;
	loom_design *d = NULL;
	if (loom_weave_parse(name, &p, NULL) != LOOM_OK ||
	    loom_design_make(&p, rows, cols, &d, NULL) != LOOM_OK)
		return NULL;
	return d;
}

/* Jacquard-like: twill 2/3 and satin 4/1 over a blocky mask; warp types
   per column, weft types per row (4 yarn types), or full random maps. */
static loom_design *jacquard(uint32_t rows, uint32_t cols, uint64_t seed, int full_maps)
{
	loom_weave_params a, b;
	loom_design *d = weave("twill:2/3", rows, cols);
	loom_weave_parse("satin:4/1", &b, NULL);
	loom_weave_parse("twill:2/3", &a, NULL);
	if (!d || loom_design_set_types(d, 4) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++) {
			size_t c = (size_t)i * cols + j;
			uint64_t h = loom_synth_mix(seed ^ ((uint64_t)(i / 7) << 32 | (j / 9)));
			if (h & 1)
				d->weave[c] = (uint8_t)loom_weave_cell(&b, i, j);
			if (full_maps) {
				uint64_t g = loom_synth_mix(seed + c);
				d->warp_type[c] = (uint8_t)(g % 4);
				d->weft_type[c] = (uint8_t)((g >> 8) % 4);
			} else {
				d->warp_type[c] = (uint8_t)(j % 3 == 0 ? 2 : 0);
				d->weft_type[c] = (uint8_t)(i % 5 == 0 ? 3 : 1);
			}
		}
	return d;
}

static loom_design *data_wif(const char *name)
{
	const char *top = getenv("LOOM_TOP");
	char path[4200];
	loom_design *d = NULL;
	snprintf(path, sizeof path, "%s/data/%s", top ? top : ".", name);
	if (loom_design_read(path, &d, NULL) != LOOM_OK)
		return NULL;
	return d;
}

static loom_fabric *synth(const loom_design *d, loom_db *with, const char *path,
                          uint64_t seed, uint32_t edge)
{
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_fabric *f = NULL;
	loom_diag diag = {0};
	o.seed = seed;
	o.edge_storage = edge;
	o.window = 24;
	if (loom_fabric_synthesize(d, with, path, &o, &f, &diag) != LOOM_OK)
		printf("  synth: %s\n", diag.message);
	return f;
}

/* ---- comparisons ---------------------------------------------------------- */

static int same_design(const loom_design *a, const loom_design *b)
{
	size_t n = (size_t)a->rows * a->cols;
	if (a->rows != b->rows || a->cols != b->cols || a->n_types != b->n_types)
		return 0;
	if (memcmp(a->weave, b->weave, n) || memcmp(a->warp_type, b->warp_type, n) ||
	    memcmp(a->weft_type, b->weft_type, n))
		return 0;
	for (uint32_t k = 0; k < a->n_types; k++)
		if (memcmp(&a->types[k], &b->types[k], sizeof a->types[k]) != 0)
			return 0;
	return 1;
}

static int same_tables(const loom_edgefix *a, const loom_edgefix *b)
{
	loom_edgefix_tables x, y;
	size_t nh, nv;
	loom_edgefix_get_tables(a, &x);
	loom_edgefix_get_tables(b, &y);
	if (x.b1 != y.b1 || x.b2 != y.b2 || x.n_blocks != y.n_blocks ||
	    x.rank_h != y.rank_h || x.rank_v != y.rank_v)
		return 0;
	/* the compact fields: the same prefixes, then the same values */
	if (memcmp(x.pre, y.pre, (size_t)x.b1 + x.b2))
		return 0;
	nh = (size_t)x.off[x.b2 - 1] + (size_t)x.b1 * x.pre[x.b2 - 1];
	nv = (size_t)x.b2 * x.off[x.b2 + x.b1];
	return !memcmp(x.coef, y.coef, 4 * (size_t)x.n_blocks * (2 * x.rank_h + 2 * x.rank_v)) &&
	       !memcmp(x.field_h, y.field_h, 4 * nh) &&
	       !memcmp(x.field_v, y.field_v, 4 * nv) &&
	       !memcmp(x.basis_h, y.basis_h, 4 * (size_t)x.b1 * x.rank_h) &&
	       !memcmp(x.basis_v, y.basis_v, 4 * (size_t)(x.b2 - 2) * x.rank_v) &&
	       !memcmp(x.mean_h, y.mean_h, 4 * (size_t)x.b1) &&
	       !memcmp(x.mean_v, y.mean_v, 4 * (size_t)(x.b2 - 2));
}

static int same_metrics(const loom_fabric *a, const loom_fabric *b)
{
	loom_fabric_metrics x, y;
	loom_fabric_get_metrics(a, &x);
	loom_fabric_get_metrics(b, &y);
	return !memcmp(&x.repeat, &y.repeat, sizeof x.repeat) &&
	       !memcmp(&x.bolt, &y.bolt, sizeof x.bolt) &&
	       x.seam.samples == y.seam.samples && x.seam.before_mean == y.seam.before_mean &&
	       x.seam.after_mean == y.seam.after_mean &&
	       x.seam.before_max == y.seam.before_max &&
	       x.seam.after_max == y.seam.after_max &&
	       x.seam.corner_samples == y.seam.corner_samples &&
	       x.seam.internal_step == y.seam.internal_step &&
	       x.seam.after_ratio == y.seam.after_ratio &&
	       x.window_rows == y.window_rows && x.n_exemplars == y.n_exemplars &&
	       !memcmp(x.usage, y.usage, 8 * (size_t)x.n_exemplars);
}

/* ---- tests ---------------------------------------------------------------- */

static void test_roundtrip(void)
{
	loom_design *d = jacquard(40, 56, 3, 0);
	loom_fabric *f = synth(d, db, db_path, 5, LOOM_FABRIC_EDGE_AUTO), *g = NULL;
	loom_fabric_params pf, pg;
	loom_fabric_db_identity idf, idg;
	loom_diag diag = {0};
	uint64_t bytes = 0;
	struct stat st;
	float dzf[8 * 6], dzg[8 * 6];

	CHECK(d && f);
	if (!f)
		return;
	CHECK_EQ_INT(loom_fabric_save(f, tpath("rt.loomf"), &bytes, &diag), LOOM_OK);
	CHECK(stat(tpath("rt.loomf"), &st) == 0 && (uint64_t)st.st_size == bytes);
	CHECK_EQ_INT(loom_fabric_open(tpath("rt.loomf"), db, 0, &g, &diag), LOOM_OK);
	if (!g) {
		printf("  open: %s\n", diag.message);
		loom_fabric_free(f);
		loom_design_free(d);
		return;
	}
	CHECK(loom_fabric_attached(g));
	CHECK(loom_fabric_db(g) == db);
	CHECK(same_design(loom_fabric_design(f), loom_fabric_design(g)));
	CHECK(same_design(d, loom_fabric_design(g)));
	CHECK(!memcmp(f->base, g->base, 2 * (size_t)40 * 56));
	CHECK(same_tables(f->ef, g->ef));
	CHECK(same_metrics(f, g));
	loom_fabric_get_params(f, &pf);
	loom_fabric_get_params(g, &pg);
	CHECK(!memcmp(&pf, &pg, sizeof pf));
	CHECK_EQ_INT(pg.seed, 5);
	CHECK_EQ_INT(pg.group, 3);
	CHECK_EQ_INT(pg.rank, LOOM_EDGEFIX_DEFAULT_RANK);
	CHECK_EQ_INT(pg.edge_stored, 1);
	CHECK_EQ_INT(pg.base_width, 1);
	loom_fabric_get_db_identity(f, &idf);
	loom_fabric_get_db_identity(g, &idg);
	CHECK(strcmp(idg.path, db_path) == 0);
	CHECK(idg.content_hash == loom_db_content_hash(db) && idf.content_hash == idg.content_hash);
	CHECK_EQ_INT(idg.block[0], 8);
	CHECK_EQ_INT(idg.block[1], 6);
	CHECK_EQ_INT(idg.block[2], 12);
	CHECK_EQ_INT(idg.n_exemplars, 8);
	CHECK_EQ_INT(idg.n_blocks, 200);
	/* lookups agree anywhere on the bolt, negative positions included */
	for (int64_t I = -50; I < 90; I += 7)
		for (int64_t J = -61; J < 130; J += 11) {
			loom_fabric_source a, b;
			CHECK_EQ_INT(loom_fabric_source_at(f, I, J, &a), LOOM_OK);
			CHECK_EQ_INT(loom_fabric_source_at(g, I, J, &b), LOOM_OK);
			CHECK(!memcmp(&a, &b, sizeof a));
			loom_fabric_dz(f, I, J, dzf);
			loom_fabric_dz(g, I, J, dzg);
			CHECK(!memcmp(dzf, dzg, sizeof dzf));
		}
	loom_fabric_free(g);
	loom_fabric_free(f);
	loom_design_free(d);
}

static void test_detached_and_recorded_db(void)
{
	loom_design *d = jacquard(16, 20, 9, 1);
	loom_fabric *f = synth(d, db, db_path, 1, LOOM_FABRIC_EDGE_AUTO), *g = NULL;
	loom_fabric_source s;
	loom_diag diag = {0};

	CHECK(f && loom_fabric_save(f, tpath("det.loomf"), NULL, &diag) == LOOM_OK);
	/* detached: file data only */
	CHECK_EQ_INT(loom_fabric_open(tpath("det.loomf"), NULL, LOOM_FABRIC_OPEN_DETACHED,
	                              &g, &diag), LOOM_OK);
	CHECK(g && !loom_fabric_attached(g) && loom_fabric_db(g) == NULL);
	if (g) {
		CHECK(same_design(d, loom_fabric_design(g)));
		CHECK(!memcmp(f->base, g->base, 2 * (size_t)16 * 20));
		CHECK(same_metrics(f, g));
		CHECK_EQ_INT(loom_fabric_source_at(g, 0, 0, &s), LOOM_EUNUSABLE);
		CHECK_EQ_INT(loom_fabric_dz(g, 0, 0, NULL), LOOM_EINVAL);
	}
	loom_fabric_free(g);
	/* no database given: the recorded path is opened and owned */
	g = NULL;
	CHECK_EQ_INT(loom_fabric_open(tpath("det.loomf"), NULL, 0, &g, &diag), LOOM_OK);
	CHECK(g && loom_fabric_attached(g) && loom_fabric_db(g) != NULL &&
	      loom_fabric_db(g) != db);
	if (g)
		CHECK_EQ_INT(loom_fabric_source_at(g, 3, 4, &s), LOOM_OK);
	loom_fabric_free(g);
	loom_fabric_free(f);
	/* a relative recorded path is also looked for next to the fabric */
	f = synth(d, db, "tiny.ldb", 1, LOOM_FABRIC_EDGE_AUTO);
	g = NULL;
	CHECK(f && loom_fabric_save(f, tpath("rel.loomf"), NULL, &diag) == LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("rel.loomf"), NULL, 0, &g, &diag), LOOM_OK);
	loom_fabric_free(g);
	loom_fabric_free(f);
	/* a recorded path that does not exist */
	f = synth(d, db, "/nonexistent/x.ldb", 1, LOOM_FABRIC_EDGE_AUTO);
	g = NULL;
	CHECK(f && loom_fabric_save(f, tpath("gone.loomf"), NULL, &diag) == LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("gone.loomf"), NULL, 0, &g, &diag), LOOM_EIO);
	CHECK_STR_CONTAINS(diag.message, "/nonexistent/x.ldb");
	CHECK(g == NULL);
	loom_fabric_free(f);
	loom_design_free(d);
}

static void test_rebuild_tables(void)
{
	loom_design *d = jacquard(24, 30, 4, 0);
	loom_fabric *fs = synth(d, db, db_path, 2, LOOM_FABRIC_EDGE_STORE);
	loom_fabric *fr = synth(d, db, db_path, 2, LOOM_FABRIC_EDGE_REBUILD), *g = NULL;
	loom_fabric_params p;
	loom_diag diag = {0};
	uint64_t bs = 0, br = 0;

	CHECK(fs && fr);
	if (!fs || !fr)
		goto done;
	CHECK_EQ_INT(loom_fabric_save(fs, tpath("st.loomf"), &bs, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_save(fr, tpath("rb.loomf"), &br, &diag), LOOM_OK);
	CHECK(br + 2000 < bs); /* the tables: 22 KB raw, 3.3 KB deflated here */
	CHECK_EQ_INT(loom_fabric_open(tpath("rb.loomf"), db, 0, &g, &diag), LOOM_OK);
	if (g) {
		loom_fabric_get_params(g, &p);
		CHECK_EQ_INT(p.edge_stored, 0);
		CHECK(same_tables(fs->ef, g->ef)); /* the rebuild is bit-identical */
		CHECK(!memcmp(fs->base, g->base, 2 * (size_t)24 * 30));
	}
	loom_fabric_free(g);
	/* detached, a rebuild-mode fabric has no tables and cannot be saved */
	g = NULL;
	CHECK_EQ_INT(loom_fabric_open(tpath("rb.loomf"), NULL, LOOM_FABRIC_OPEN_DETACHED,
	                              &g, &diag), LOOM_OK);
	if (g)
		CHECK_EQ_INT(loom_fabric_save(g, tpath("rb2.loomf"), NULL, &diag), LOOM_EINVAL);
	loom_fabric_free(g);
done:
	loom_fabric_free(fs);
	loom_fabric_free(fr);
	loom_design_free(d);
}

static void test_determinism(void)
{
	loom_design *d = jacquard(30, 44, 8, 1);
	loom_fabric *a = synth(d, db, db_path, 77, 0), *b = synth(d, db, db_path, 77, 0);
	loom_fabric *c = synth(d, db, db_path, 78, 0), *g = NULL;
	uint8_t *x, *y, *z, *w;
	size_t nx, ny, nz, nw;
	loom_diag diag = {0};

	CHECK(a && b && c);
	if (!a || !b || !c)
		goto done;
	loom_fabric_save(a, tpath("da.loomf"), NULL, &diag);
	loom_fabric_save(b, tpath("db.loomf"), NULL, &diag);
	loom_fabric_save(c, tpath("dc.loomf"), NULL, &diag);
	x = slurp(tpath("da.loomf"), &nx);
	y = slurp(tpath("db.loomf"), &ny);
	z = slurp(tpath("dc.loomf"), &nz);
	CHECK(x && y && z);
	CHECK(nx == ny && x && y && memcmp(x, y, nx) == 0);
	CHECK(x && z && (nx != nz || memcmp(x, z, nx) != 0));
	/* open + save gives the same bytes again */
	CHECK_EQ_INT(loom_fabric_open(tpath("da.loomf"), db, 0, &g, &diag), LOOM_OK);
	if (g)
		loom_fabric_save(g, tpath("dd.loomf"), NULL, &diag);
	w = slurp(tpath("dd.loomf"), &nw);
	CHECK(w && nw == nx && x && memcmp(x, w, nx) == 0);
	loom_fabric_free(g);
	free(x);
	free(y);
	free(z);
	free(w);
done:
	loom_fabric_free(a);
	loom_fabric_free(b);
	loom_fabric_free(c);
	loom_design_free(d);
}

static void test_mismatch(void)
{
	loom_design *d = weave("twill:2/3", 10, 10);
	loom_fabric *f = synth(d, db, db_path, 1, 0), *g = NULL;
	loom_diag diag = {0};
	char h1[32], h2[32];

	CHECK(f && loom_fabric_save(f, tpath("mm.loomf"), NULL, &diag) == LOOM_OK);
	CHECK(loom_db_content_hash(db) != loom_db_content_hash(db2));
	CHECK_EQ_INT(loom_fabric_open(tpath("mm.loomf"), db2, 0, &g, &diag), LOOM_EMISMATCH);
	CHECK(g == NULL);
	snprintf(h1, sizeof h1, "%016llx", (unsigned long long)loom_db_content_hash(db));
	snprintf(h2, sizeof h2, "%016llx", (unsigned long long)loom_db_content_hash(db2));
	CHECK_STR_CONTAINS(diag.message, h1);
	CHECK_STR_CONTAINS(diag.message, h2);
	CHECK_STR_CONTAINS(diag.message, "mm.loomf");
	/* another geometry entirely (more exemplars): refused too */
	CHECK_EQ_INT(loom_fabric_open(tpath("mm.loomf"), db3, 0, &g, &diag), LOOM_EMISMATCH);
	/* the bind check without the hash still catches the exemplar count */
	{
		loom_fabric *h = NULL;
		CHECK_EQ_INT(loom_fabric_open(tpath("mm.loomf"), NULL, LOOM_FABRIC_OPEN_DETACHED,
		                              &h, &diag), LOOM_OK);
		if (h)
			CHECK_EQ_INT(loom__fabric_bind(h, db3, 0, "mm", &diag), LOOM_EMISMATCH);
		loom_fabric_free(h);
	}
	loom_fabric_free(f);
	loom_design_free(d);
}

/* Offsets of the 8 section headers of a file image. */
static int sections(const uint8_t *b, size_t n, size_t off[8])
{
	size_t pos = 64;
	for (int k = 0; k < 8; k++) {
		if (pos + 32 > n)
			return -1;
		off[k] = pos;
		pos += 32 + (size_t)le64(b + pos + 16);
	}
	return pos + 32 == n ? 0 : -1;
}

static int open_bytes(const uint8_t *b, size_t n, loom_diag *diag)
{
	loom_fabric *f = NULL;
	int rc;
	spit(tpath("bad.loomf"), b, n);
	rc = loom_fabric_open(tpath("bad.loomf"), db, 0, &f, diag);
	if (rc == LOOM_OK)
		loom_fabric_free(f);
	else if (f != NULL || diag->message[0] == 0)
		rc = -1; /* an error must leave *out NULL and say why */
	return rc;
}

static void test_truncation(void)
{
	loom_design *d = jacquard(20, 24, 1, 1);
	loom_fabric *f = synth(d, db, db_path, 1, 0);
	loom_diag diag = {0};
	uint8_t *b;
	size_t n, bad = 0, tried = 0;

	CHECK(f && loom_fabric_save(f, tpath("tr.loomf"), NULL, &diag) == LOOM_OK);
	b = slurp(tpath("tr.loomf"), &n);
	CHECK(b && n > 1000);
	for (size_t cut = 0; b && cut < n; cut += cut < 300 ? 1 : n - cut > 300 ? 97 : 1) {
		int rc;
		diag.message[0] = 0;
		rc = open_bytes(b, cut, &diag);
		tried++;
		if (rc != LOOM_ETRUNCATED) {
			if (bad++ < 5)
				printf("  cut %zu: rc %d (%s)\n", cut, rc, diag.message);
		}
	}
	/* every cut in the first 300 bytes, every cut in the last 204..300
	   (where the 97-byte steps end), every 97th in between: at least
	   504 + (n - 600) / 97 cuts, whatever n is modulo 97 */
	CHECK(n < 600 || tried >= 504 + (n - 600) / 97);
	CHECK_EQ_INT(bad, 0);
	/* bytes appended after the trailer: the trailer is no longer last */
	if (b) {
		uint8_t *c = malloc(n + 5);
		memcpy(c, b, n);
		memset(c + n, 0, 5);
		CHECK_EQ_INT(open_bytes(c, n + 5, &diag), LOOM_ETRUNCATED);
		free(c);
	}
	free(b);
	loom_fabric_free(f);
	loom_design_free(d);
}

static void test_flipped_bytes(void)
{
	loom_design *d = jacquard(20, 24, 2, 1);
	loom_fabric *f = synth(d, db, db_path, 1, 0);
	loom_diag diag = {0};
	size_t n, off[8];
	uint8_t *b;

	CHECK(f && loom_fabric_save(f, tpath("fl.loomf"), NULL, &diag) == LOOM_OK);
	b = slurp(tpath("fl.loomf"), &n);
	CHECK(b && sections(b, n, off) == 0);
	if (!b || sections(b, n, off) != 0)
		goto done;
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_OK);
	for (int k = 0; k < 8; k++) {
		size_t body = off[k] + 32, len = (size_t)le64(b + off[k] + 16);
		size_t where[3] = {body, body + len / 2, body + len - 1};
		/* each part of the body */
		for (int w = 0; w < 3; w++) {
			b[where[w]] ^= 0x10;
			CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(diag.message, "CRC");
			b[where[w]] ^= 0x10;
		}
		/* each field of the section header */
		for (size_t h = 0; h < 32; h += 5) {
			b[off[k] + h] ^= 0x01;
			CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_ECORRUPT);
			b[off[k] + h] ^= 0x01;
		}
	}
	/* file header fields (after magic and version) and the trailer */
	for (size_t h = 12; h < 64; h += 4) {
		b[h] ^= 0x02;
		CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_ECORRUPT);
		b[h] ^= 0x02;
	}
	for (size_t h = 8; h < 32; h += 4) {
		b[n - 32 + h] ^= 0x02;
		CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_ECORRUPT);
		b[n - 32 + h] ^= 0x02;
	}
	b[n - 32] ^= 0x02; /* trailer magic */
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_ETRUNCATED);
	b[n - 32] ^= 0x02;
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_OK);
done:
	free(b);
	loom_fabric_free(f);
	loom_design_free(d);
}

static void test_bad_magic_version(void)
{
	loom_design *d = weave("satin:1/4", 10, 15);
	loom_fabric *f = synth(d, db, db_path, 1, 0);
	loom_diag diag = {0};
	uint8_t *b;
	size_t n;

	CHECK(f && loom_fabric_save(f, tpath("mv.loomf"), NULL, &diag) == LOOM_OK);
	b = slurp(tpath("mv.loomf"), &n);
	if (!b)
		goto done;
	b[1] = 'X';
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(diag.message, "not a loom fabric");
	CHECK_EQ_INT(open_bytes(b, 5, &diag), LOOM_EFORMAT); /* short and wrong */
	b[1] = 'L';
	CHECK_EQ_INT(open_bytes(b, 5, &diag), LOOM_ETRUNCATED); /* short, right */
	put32(b + 8, 2); /* version checked before the CRC ... */
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_EVERSION);
	CHECK_STR_CONTAINS(diag.message, "version 2");
	put32(b + 60, libdeflate_crc32(0, b, 60)); /* ... and with a valid CRC */
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_EVERSION);
	put32(b + 8, 1);
	put32(b + 60, libdeflate_crc32(0, b, 60));
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_OK);
	/* a valid-CRC header with an absurd design size */
	put32(b + 16, 0);
	put32(b + 60, libdeflate_crc32(0, b, 60));
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_ERANGE);
	/* rows*cols claiming far more than the base section could hold */
	put32(b + 16, 60000);
	put32(b + 20, 60000);
	put32(b + 60, libdeflate_crc32(0, b, 60));
	CHECK_EQ_INT(open_bytes(b, n, &diag), LOOM_EFORMAT);
	free(b);
done:
	loom_fabric_free(f);
	loom_design_free(d);
}

/* A base entry >= K written by a (doctored) fabric: refused on open. */
static void test_bad_base(void)
{
	loom_design *d = weave("twill:3/2", 12, 10);
	loom_design *d3 = jacquard(14, 18, 5, 0);
	loom_fabric *f = synth(d, db, db_path, 1, 0), *g = NULL;
	loom_fabric *f3 = synth(d3, db3, db3_path, 1, 0);
	loom_diag diag = {0};
	loom_fabric_params p;

	CHECK(f && f3);
	if (!f || !f3)
		goto done;
	f->base[7] = (uint16_t)f->n_blocks; /* 200: fits the 1-byte width */
	CHECK_EQ_INT(loom_fabric_save(f, tpath("bb.loomf"), NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("bb.loomf"), db, 0, &g, &diag), LOOM_ERANGE);
	CHECK_STR_CONTAINS(diag.message, "crossing (0,7) copies block 200");
	f->base[7] = 255;
	CHECK_EQ_INT(loom_fabric_save(f, tpath("bb.loomf"), NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("bb.loomf"), NULL, LOOM_FABRIC_OPEN_DETACHED,
	                              &g, &diag), LOOM_ERANGE);
	/* two-byte entries (more than 256 blocks) */
	loom_fabric_get_params(f3, &p);
	CHECK_EQ_INT(p.base_width, 2);
	CHECK(f3->n_blocks > 256);
	CHECK_EQ_INT(loom_fabric_save(f3, tpath("b3.loomf"), NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("b3.loomf"), db3, 0, &g, &diag), LOOM_OK);
	if (g)
		CHECK(!memcmp(g->base, f3->base, 2 * (size_t)14 * 18));
	loom_fabric_free(g);
	g = NULL;
	f3->base[14 * 18 - 1] = (uint16_t)f3->n_blocks;
	CHECK_EQ_INT(loom_fabric_save(f3, tpath("b3.loomf"), NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("b3.loomf"), db3, 0, &g, &diag), LOOM_ERANGE);
	CHECK_STR_CONTAINS(diag.message, "crossing (13,17)");
	f3->base[0] = 0xFFFF;
	CHECK_EQ_INT(loom_fabric_save(f3, tpath("b3.loomf"), NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_open(tpath("b3.loomf"), db3, 0, &g, &diag), LOOM_ERANGE);
	CHECK_STR_CONTAINS(diag.message, "crossing (0,0) copies block 65535");
done:
	loom_fabric_free(f);
	loom_fabric_free(f3);
	loom_design_free(d);
	loom_design_free(d3);
}

/* Kind of the top-most yarn voxel of the centre column of every source
   block, read from the voxels (the surface rule of docs/formats.md). */
static uint8_t *centre_kinds(loom_db *with, uint32_t K)
{
	loom_db_info info;
	uint8_t *kind = calloc(K, 1), *den, *lab;
	uint32_t t = 0;

	loom_db_get_info(with, &info);
	den = malloc(info.block[2]);
	lab = malloc(info.block[2]);
	for (uint32_t u = 0; u < info.n_exemplars; u++) {
		loom_db_exemplar_info e;
		loom_db_exemplar(with, u, &e);
		for (uint32_t r = 0; r < e.rows; r++)
			for (uint32_t c = 0; c < e.cols; c++, t++) {
				uint32_t org[3] = {c * info.block[0] + info.block[0] / 2,
				                   r * info.block[1] + info.block[1] / 2, 0};
				uint32_t sz[3] = {1, 1, info.block[2]};
				if (t >= K || loom_db_read_box(with, u, org, sz, den, NULL, lab, NULL))
					continue;
				for (int z = (int)info.block[2] - 1; z >= 0; z--) {
					const loom_db_yarn *y = &e.yarns[lab[z]];
					if (lab[z] && y->kind && !(y->flags & LOOM_DB_YARN_FLYAWAY) &&
					    den[z] >= 64) {
						kind[t] = y->kind;
						break;
					}
				}
			}
	}
	free(den);
	free(lab);
	return kind;
}

static void check_correct(loom_design *d, const char *what)
{
	loom_fabric *f = synth(d, db, db_path, 11, 0);
	static uint8_t *kind;
	loom_fabric_metrics m;
	uint64_t wrong = 0, seen = 0;

	CHECK(f != NULL);
	if (!f)
		return;
	if (!kind)
		kind = centre_kinds(db, f->n_blocks);
	loom_fabric_get_metrics(f, &m);
	CHECK(m.repeat.correctness == 1.0 && m.repeat.correct == m.repeat.crossings);
	CHECK(m.bolt.correctness == 1.0);
	CHECK_EQ_INT(m.repeat.crossings, (uint64_t)d->rows * d->cols);
	/* every crossing of the repeat (first repeat of the bolt, randomised),
	   and one shifted repeat at negative positions */
	for (int rep = 0; rep < 2; rep++)
		for (uint32_t i = 0; i < d->rows; i++)
			for (uint32_t j = 0; j < d->cols; j++) {
				int64_t I = rep ? (int64_t)i - 3 * (int64_t)d->rows : i;
				int64_t J = rep ? (int64_t)j - 5 * (int64_t)d->cols : j;
				loom_fabric_source s;
				uint8_t want = loom_design_at(d, i, j) ? LOOM_YARN_WARP : LOOM_YARN_WEFT;
				loom_fabric_source_at(f, I, J, &s);
				seen++;
				if (kind[s.block] != want || s.warp_over != loom_design_at(d, i, j)) {
					if (wrong++ < 3)
						printf("  %s: crossing (%lld,%lld) copies block %u "
						       "(exemplar %u r%u c%u) whose top is %u, W = %u\n",
						       what, (long long)I, (long long)J, s.block, s.exemplar,
						       s.row, s.col, kind[s.block], loom_design_at(d, i, j));
				}
			}
	CHECK(seen > 0);
	CHECK_EQ_INT(wrong, 0);
	loom_fabric_free(f);
}

static void test_correctness_on_voxels(void)
{
	loom_design *d;
	const char *wifs[] = {"herringbone-8.wif", "overshot-sampler.wif"};

	for (int k = 0; k < 2; k++) {
		d = data_wif(wifs[k]);
		CHECK(d != NULL);
		if (d)
			check_correct(d, wifs[k]);
		loom_design_free(d);
	}
	d = jacquard(60, 70, 21, 0);
	check_correct(d, "jacquard");
	loom_design_free(d);
	d = weave("plain", 6, 6);
	check_correct(d, "plain");
	loom_design_free(d);
	d = weave("basket:2", 8, 8);
	check_correct(d, "basket");
	loom_design_free(d);
}

static void test_algorithms(void)
{
	loom_design *d = jacquard(32, 40, 13, 0);
	const int algos[3] = {LOOM_SYNTH_NAIVE, LOOM_SYNTH_GREEDY, LOOM_SYNTH_DP};
	double cont[3] = {0};

	for (int a = 0; a < 3; a++) {
		loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
		loom_fabric *f = NULL, *g = NULL;
		loom_fabric_metrics m;
		loom_fabric_params p;
		loom_diag diag = {0};
		o.algo = algos[a];
		CHECK_EQ_INT(loom_fabric_synthesize(d, db, db_path, &o, &f, &diag), LOOM_OK);
		if (!f)
			continue;
		loom_fabric_get_metrics(f, &m);
		CHECK(m.repeat.correctness == 1.0);
		cont[a] = m.repeat.continuity;
		CHECK_EQ_INT(loom_fabric_save(f, tpath("al.loomf"), NULL, &diag), LOOM_OK);
		CHECK_EQ_INT(loom_fabric_open(tpath("al.loomf"), db, 0, &g, &diag), LOOM_OK);
		if (g) {
			loom_fabric_get_params(g, &p);
			CHECK_EQ_INT(p.algo, algos[a]);
			CHECK(!memcmp(f->base, g->base, 2 * (size_t)32 * 40));
		}
		loom_fabric_free(g);
		loom_fabric_free(f);
	}
	CHECK(cont[2] > cont[1] && cont[2] > cont[0]); /* the DP's purpose */
	loom_design_free(d);
}

/* Brute force of one crossing's seam jumps after the fix: the heights plus
   loom_fabric_dz's offsets (the corner term included) along its S and E
   edges.  Adds the |jumps| to sum[0] (S edge), sum[1] (E edge) and sum[2]
   (the E edge's corner samples, y = 0 and b2 - 1), the largest to *max. */
static int brute_seam(const loom_fabric *f, int64_t I, int64_t J, double sum[3],
                      double *max)
{
	uint32_t b1 = f->b1, b2 = f->b2, rec = LOOM_EDGE_RECORD(b1, b2);
	float *d0 = malloc(sizeof(float) * b1 * b2), *ds = malloc(sizeof(float) * b1 * b2);
	float *de = malloc(sizeof(float) * b1 * b2);
	loom_fabric_source s0, ss, se;
	int ok = d0 && ds && de;

	if (ok) {
		loom_fabric_dz(f, I, J, d0);
		loom_fabric_dz(f, I + 1, J, ds);
		loom_fabric_dz(f, I, J + 1, de);
		loom_fabric_source_at(f, I, J, &s0);
		loom_fabric_source_at(f, I + 1, J, &ss);
		loom_fabric_source_at(f, I, J + 1, &se);
		for (uint32_t x = 0; x < b1; x++) {
			double h0 = f->heights[(size_t)s0.block * rec + LOOM_EDGE_S(b1, b2) + x];
			double h1 = f->heights[(size_t)ss.block * rec + LOOM_EDGE_N(b1, b2) + x];
			double j = fabs((h0 + d0[(b2 - 1) * b1 + x]) - (h1 + ds[x]));
			sum[0] += j;
			*max = j > *max ? j : *max;
		}
		for (uint32_t y = 0; y < b2; y++) {
			double h0 = f->heights[(size_t)s0.block * rec + LOOM_EDGE_E(b1, b2) + y];
			double h1 = f->heights[(size_t)se.block * rec + LOOM_EDGE_W(b1, b2) + y];
			double j = fabs((h0 + d0[y * b1 + b1 - 1]) - (h1 + de[y * b1]));
			sum[1] += j;
			if (y == 0 || y == b2 - 1)
				sum[2] += j;
			*max = j > *max ? j : *max;
		}
	}
	free(d0);
	free(ds);
	free(de);
	return ok;
}

static void test_seam_block_and_sizes(void)
{
	loom_design *d = jacquard(18, 22, 6, 0);
	loom_fabric *f = synth(d, db, db_path, 3, 0);
	uint64_t rep[3], bolt[3], bytes = 0;
	double total, win[3] = {0, 0, 0}, win_max = 0;
	loom_fabric_metrics m;
	loom_diag diag = {0};

	CHECK(f != NULL);
	if (!f)
		goto done;
	/* the jumps before the fix as loom_edgefix_seam_block's; after it, the
	   mean |jump| of the heights plus loom_fabric_dz's offsets (the corner
	   term included) along the S and E edges */
	for (int64_t I = -4; I < 30; I += 3)
		for (int64_t J = -7; J < 30; J += 5) {
			double a[4], b[4], sum[3] = {0, 0, 0}, mx = 0;
			CHECK_EQ_INT(loom_fabric_seam_block(f, I, J, a), LOOM_OK);
			CHECK_EQ_INT(loom_edgefix_seam_block(f->ef, &f->prof, &f->lk, I, J, b), LOOM_OK);
			CHECK(fabs(a[0] - b[0]) < 1e-9);
			CHECK(fabs(a[2] - b[2]) < 1e-9);
			CHECK(brute_seam(f, I, J, sum, &mx));
			CHECK(fabs(a[1] - sum[0] / f->b1) < 1e-9);
			CHECK(fabs(a[3] - sum[1] / f->b2) < 1e-9);
		}
	/* the fabric's own metrics (loom synth's "seams ... corners ..." line)
	   measure the offsets a lookup applies, corner term included, over the
	   metrics window; before the fix as loom_edgefix_seam's */
	CHECK_EQ_INT(loom_fabric_get_metrics(f, &m), LOOM_OK);
	CHECK(f->corner_off != NULL);
	for (uint64_t I = 0; I < m.window_rows; I++)
		for (uint64_t J = 0; J < m.window_cols; J++)
			CHECK(brute_seam(f, (int64_t)I, (int64_t)J, win, &win_max));
	{
		uint64_t n = m.window_rows * m.window_cols, ns = n * (f->b1 + f->b2);
		loom_seam_metrics e;
		CHECK_EQ_INT(m.seam.samples, ns);
		CHECK_EQ_INT(m.seam.corner_samples, 2 * n);
		CHECK(fabs(m.seam.after_mean - (win[0] + win[1]) / (double)ns) < 1e-9);
		CHECK(fabs(m.seam.corner_after_mean - win[2] / (double)(2 * n)) < 1e-9);
		CHECK(fabs(m.seam.after_max - win_max) < 1e-9);
		CHECK_EQ_INT(loom_edgefix_seam(f->ef, &f->prof, &f->lk, 0, 0, m.window_rows,
		                               m.window_cols, f->internal_step, &e), LOOM_OK);
		CHECK(fabs(m.seam.before_mean - e.before_mean) < 1e-9);
		CHECK(fabs(m.seam.corner_before_mean - e.corner_before_mean) < 1e-9);
		CHECK(fabs(m.seam.after_ratio - m.seam.after_mean / f->internal_step) < 1e-12);
		/* the edge fix alone differs at the corners (else this test
		   could not tell the two apart) */
		CHECK(fabs(e.corner_after_mean - m.seam.corner_after_mean) > 1e-3);
	}
	CHECK_EQ_INT(loom_fabric_repeat_voxels(f, rep), LOOM_OK);
	CHECK_EQ_INT(rep[0], 22 * 8);
	CHECK_EQ_INT(rep[1], 18 * 6);
	CHECK_EQ_INT(rep[2], 12);
	CHECK_EQ_INT(loom_fabric_bolt_voxels(f, 2.5, 1, bolt, &total), LOOM_OK);
	CHECK_EQ_INT(bolt[0], 176);
	CHECK_EQ_INT(bolt[1], 270);
	CHECK(total == 176.0 * 270 * 12);
	CHECK_EQ_INT(loom_fabric_bolt_voxels(f, 0, 1, bolt, &total), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_bolt_voxels(f, NAN, 1, bolt, &total), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_bolt_voxels(f, 1e30, 1, bolt, &total), LOOM_ERANGE);
	/* size budget: at most 4 bytes per crossing + the tables (< 2 MB) */
	CHECK_EQ_INT(loom_fabric_save(f, tpath("sz.loomf"), &bytes, &diag), LOOM_OK);
	CHECK(bytes <= 4 * 18 * 22 + 2000000);
done:
	loom_fabric_free(f);
	loom_design_free(d);
}

/* The corner term (docs/synthesis.md, "Block corners"): at every point
   where four crossings meet, their corner columns' heights (profile +
   loom_fabric_corner_dz) differ from their mean exactly by the sources'
   woven corner offsets minus the offsets' mean; the mean |jump| between
   the four is smaller than with the paper's rule (the N/S edges' values,
   loom_edgefix_at) on this fabric; rank 0 has no term (all zero). */
static void test_corner_term(void)
{
	loom_design *d = jacquard(18, 22, 7, 0);
	loom_fabric *f = synth(d, db, db_path, 5, 0);
	loom_fabric *f0 = NULL;
	loom_fabric_options opt = LOOM_FABRIC_OPTIONS_INIT;
	loom_diag diag = {0};
	double jump = 0, jump_paper = 0, worst = 0;
	uint64_t points = 0, off_nonzero = 0;

	CHECK(f != NULL && f->corner_off != NULL);
	if (!f || !f->corner_off)
		goto done;
	for (int64_t I = -3; I < 21; I++)
		for (int64_t J = -4; J < 25; J++) {
			/* the point at the SE corner of (I, J): (I, J) SE, (I, J+1) SW,
			   (I+1, J) NE, (I+1, J+1) NW */
			int64_t ci[4] = {I, I, I + 1, I + 1}, cj[4] = {J, J + 1, J, J + 1};
			int cc[4] = {3, 2, 1, 0};
			double h[4], hp[4], o[4], mh = 0, mo = 0;
			for (int m = 0; m < 4; m++) {
				loom_fabric_source s;
				float cd[4];
				uint32_t x = (cc[m] & 1) ? f->b1 - 1 : 0, y = (cc[m] & 2) ? f->b2 - 1 : 0;
				const float *rec;
				double p;
				CHECK_EQ_INT(loom_fabric_source_at(f, ci[m], cj[m], &s), LOOM_OK);
				CHECK_EQ_INT(loom_fabric_corner_dz(f, ci[m], cj[m], cd), LOOM_OK);
				rec = f->heights + (size_t)s.block * LOOM_EDGE_RECORD(f->b1, f->b2);
				p = cc[m] < 2 ? rec[LOOM_EDGE_N(f->b1, f->b2) + x]
				              : rec[LOOM_EDGE_S(f->b1, f->b2) + x];
				h[m] = p + cd[cc[m]];
				hp[m] = p + loom_edgefix_at(f->ef, &s.nbhd, x, y);
				o[m] = f->corner_off[(size_t)s.block * 4 + cc[m]];
				off_nonzero += o[m] != 0;
				mh += h[m] / 4;
				mo += o[m] / 4;
			}
			for (int m = 0; m < 4; m++) {
				double e = fabs((h[m] - mh) - (o[m] - mo));
				worst = e > worst ? e : worst;
			}
			for (int a = 0; a < 4; a++)
				for (int b = a + 1; b < 4; b++) {
					jump += fabs(h[a] - h[b]);
					jump_paper += fabs(hp[a] - hp[b]);
				}
			points++;
		}
	printf("  %llu corner points: mean |jump| %.3f voxels with the corner term, %.3f "
	       "with the paper's rule; largest deviation from the woven offsets %.2e; "
	       "%llu non-zero offsets\n", (unsigned long long)points, jump / (6.0 * points),
	       jump_paper / (6.0 * points), worst, (unsigned long long)off_nonzero);
	CHECK(worst < 1e-4);
	CHECK(off_nonzero > points); /* the offsets are not all zero */
	CHECK(jump < jump_paper);
	/* rank 0: no edge fix, no corner term */
	opt.rank = 0;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, db_path, &opt, &f0, &diag), LOOM_OK);
	if (f0) {
		float cd[4] = {1, 1, 1, 1};
		CHECK(f0->corner_off == NULL);
		CHECK_EQ_INT(loom_fabric_corner_dz(f0, 2, 3, cd), LOOM_OK);
		CHECK(cd[0] == 0 && cd[1] == 0 && cd[2] == 0 && cd[3] == 0);
	}
	CHECK_EQ_INT(loom_fabric_corner_dz(NULL, 0, 0, NULL), LOOM_EINVAL);
done:
	loom_fabric_free(f0);
	loom_fabric_free(f);
	loom_design_free(d);
}

/* The paper's example: 900 x 1500 crossings of 115 x 70 x 300 voxels. */
static void test_paper_bolt(void)
{
	loom_fabric *f = loom__fabric_alloc();
	uint64_t rep[3], bolt[3];
	double total = 0;

	CHECK(f && loom_design_new(900, 1500, &f->design) == LOOM_OK);
	if (!f || !f->design) {
		loom_fabric_free(f);
		return;
	}
	f->b1 = 115;
	f->b2 = 70;
	f->b3 = 300;
	loom_fabric_repeat_voxels(f, rep);
	CHECK_EQ_INT(rep[0], 172500);
	CHECK_EQ_INT(rep[1], 63000);
	CHECK_EQ_INT(rep[2], 300);
	CHECK_EQ_INT(loom_fabric_bolt_voxels(f, 1, 1, bolt, &total), LOOM_OK);
	CHECK(total == 3260250000000.0);
	CHECK_EQ_INT(loom_fabric_bolt_voxels(f, 100, 2, bolt, &total), LOOM_OK);
	CHECK_EQ_INT(bolt[1], 6300000);
	CHECK(total == 3260250000000.0 * 200);
	loom_fabric_free(f);
}

static void test_bad_args(void)
{
	loom_design *d = weave("plain", 4, 4);
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_fabric *f = (loom_fabric *)1;
	loom_fabric_params p;
	loom_diag diag = {0};
	int algo;

	CHECK_EQ_INT(loom_fabric_synthesize(NULL, db, "", &o, &f, &diag), LOOM_EINVAL);
	CHECK(f == NULL);
	CHECK_EQ_INT(loom_fabric_synthesize(d, NULL, "", &o, &f, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, NULL, &diag), LOOM_EINVAL);
	o.rank = 129;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "rank 129");
	o.rank = 15;
	o.algo = 4;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	o.algo = LOOM_SYNTH_IDENTITY; /* needs group 0 and rank 0 */
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "identity");
	o.algo = LOOM_SYNTH_DP;
	o.group = 70000;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	o.group = 3;
	o.flags = 4;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	o.flags = 0;
	o.window = 5000;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	o.window = 0;
	o.size = 8;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", &o, &f, &diag), LOOM_EINVAL);
	d->weave[3] = 2;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, "", NULL, &f, &diag), LOOM_EFORMAT);
	d->weave[3] = 1;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, NULL, NULL, &f, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_fabric_save(NULL, tpath("x.loomf"), NULL, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_save(f, NULL, NULL, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_save(f, "/nonexistent/dir/x.loomf", NULL, &diag), LOOM_EIO);
	CHECK_EQ_INT(loom_fabric_save(f, tpath("nopath.loomf"), NULL, &diag), LOOM_OK);
	loom_fabric_free(f);
	f = NULL;
	CHECK_EQ_INT(loom_fabric_open(tpath("nopath.loomf"), NULL, 0, &f, &diag),
	             LOOM_ENOTFOUND);
	CHECK_EQ_INT(loom_fabric_open(NULL, db, 0, &f, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_open(tpath("x.loomf"), db, 8, &f, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_open(tpath("missing.loomf"), db, 0, &f, &diag), LOOM_EIO);
	CHECK_STR_CONTAINS(diag.message, "missing.loomf");
	CHECK_EQ_INT(loom_fabric_open(tmpdir, db, 0, &f, &diag), LOOM_EIO);
	CHECK_EQ_INT(loom_fabric_open(tpath("x.loomf"), db, 0, NULL, &diag), LOOM_EINVAL);
	CHECK(f == NULL);
	loom_fabric_free(NULL);
	CHECK(loom_fabric_design(NULL) == NULL);
	CHECK(loom_fabric_db(NULL) == NULL);
	CHECK_EQ_INT(loom_fabric_attached(NULL), 0);
	CHECK_EQ_INT(loom_fabric_get_params(NULL, &p), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_source_at(NULL, 0, 0, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_fabric_algo_parse("dp", &algo), LOOM_OK);
	CHECK_EQ_INT(algo, LOOM_SYNTH_DP);
	CHECK_EQ_INT(loom_fabric_algo_parse("greedy", &algo), LOOM_OK);
	CHECK_EQ_INT(algo, LOOM_SYNTH_GREEDY);
	CHECK_EQ_INT(loom_fabric_algo_parse("DP", &algo), LOOM_EINVAL);
	CHECK(strcmp(loom_fabric_algo_name(LOOM_SYNTH_NAIVE), "naive") == 0);
	CHECK(strcmp(loom_fabric_algo_name(9), "?") == 0);
	/* an empty file and a directory-less garbage file */
	spit(tpath("empty.loomf"), (const uint8_t *)"", 0);
	CHECK_EQ_INT(loom_fabric_open(tpath("empty.loomf"), db, 0, &f, &diag), LOOM_ETRUNCATED);
	spit(tpath("text.loomf"), (const uint8_t *)"hello world, not a fabric file at all", 37);
	CHECK_EQ_INT(loom_fabric_open(tpath("text.loomf"), db, 0, &f, &diag), LOOM_EFORMAT);
	loom_design_free(d);
}

/* Type maps in every storage mode survive the round trip. */
static void test_map_modes(void)
{
	for (int mode = 0; mode < 4; mode++) {
		loom_design *d = jacquard(13, 17, 30 + mode, mode == 0);
		loom_fabric *f, *g = NULL;
		loom_diag diag = {0};
		if (!d)
			continue;
		for (uint32_t i = 0; i < 13; i++)
			for (uint32_t j = 0; j < 17; j++) {
				size_t c = (size_t)i * 17 + j;
				if (mode == 1) /* per column / per row */
					d->warp_type[c] = (uint8_t)(j % 4), d->weft_type[c] = (uint8_t)(i % 4);
				if (mode == 2) /* the other way round */
					d->warp_type[c] = (uint8_t)(i % 4), d->weft_type[c] = (uint8_t)(j % 4);
				if (mode == 3) /* constant */
					d->warp_type[c] = 3, d->weft_type[c] = 0;
			}
		f = synth(d, db, db_path, 1, 0);
		CHECK(f && loom_fabric_save(f, tpath("mm2.loomf"), NULL, &diag) == LOOM_OK);
		CHECK_EQ_INT(loom_fabric_open(tpath("mm2.loomf"), NULL, LOOM_FABRIC_OPEN_DETACHED,
		                              &g, &diag), LOOM_OK);
		CHECK(g && same_design(d, loom_fabric_design(g)));
		loom_fabric_free(g);
		loom_fabric_free(f);
		loom_design_free(d);
	}
}

static int make_db(const char *path, uint64_t seed, int twelve, loom_db **out)
{
	static const char *const w12[12] = {"twill:2/3", "twill:3/2", "twill:1/4", "twill:4/1",
	                                    "satin:1/4", "satin:4/1", "satin:2/3", "satin:3/2",
	                                    "plain", "basket:2", "twill:2/2", "twill:1/3"};
	/* the paper's eight (200 blocks: one-byte base entries) */
	static const char *const w8[8] = {"twill:2/3", "twill:3/2", "twill:1/4", "twill:4/1",
	                                  "satin:2/3", "satin:3/2", "satin:1/4", "satin:4/1"};
	loom_exgen_params p;
	loom_diag d = {0};
	if (loom_exgen_preset("tiny", &p) != LOOM_OK)
		return -1;
	p.seed = seed;
	p.n_weaves = twelve ? 12 : 8;
	for (uint32_t k = 0; k < p.n_weaves; k++)
		p.weaves[k] = twelve ? w12[k] : w8[k];
	if (loom_exgen_write_db(path, &p, NULL, &d) != LOOM_OK ||
	    loom_db_open(path, out, &d) != LOOM_OK) {
		printf("  database %s: %s\n", path, d.message);
		return -1;
	}
	return 0;
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_fabric");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	snprintf(db2_path, sizeof db2_path, "%s/tiny2.ldb", tmpdir);
	snprintf(db3_path, sizeof db3_path, "%s/tiny12.ldb", tmpdir);
	if (make_db(db_path, 1, 0, &db) || make_db(db2_path, 2, 0, &db2) ||
	    make_db(db3_path, 1, 1, &db3)) {
		printf("FAIL test_fabric/setup (cannot make the databases)\n");
		return 1;
	}
	RUN(test_roundtrip);
	RUN(test_detached_and_recorded_db);
	RUN(test_rebuild_tables);
	RUN(test_determinism);
	RUN(test_mismatch);
	RUN(test_truncation);
	RUN(test_flipped_bytes);
	RUN(test_bad_magic_version);
	RUN(test_bad_base);
	RUN(test_correctness_on_voxels);
	RUN(test_algorithms);
	RUN(test_seam_block_and_sizes);
	RUN(test_corner_term);
	RUN(test_paper_bolt);
	RUN(test_bad_args);
	RUN(test_map_modes);
	loom_db_close(db);
	loom_db_close(db2);
	loom_db_close(db3);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
