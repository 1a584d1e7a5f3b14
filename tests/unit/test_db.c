/*
 * tests/unit/test_db.c - the exemplar database: write, read back every
 * voxel against the generator, empty and raw-stored bricks, tables of a
 * hand-made database, and every malformed-input case (each with its code
 * and a message naming the place; none may crash).
 */
#include "check.h"
#include "tmpdir.h"
#include "exemplar/db_internal.h"
#include "io/store/db_write.h"
#include "exemplar/exgen.h"

#include <fcntl.h>
#include <libdeflate.h>
#include <math.h>
#include <pthread.h>
#include <sys/stat.h>
#include <unistd.h>

/* Recompute the header CRC, metadata CRC, content hash and trailer CRC of
   an edited database image, so that a deliberate inconsistency reaches the
   check behind them. */
static void reseal(uint8_t *b, size_t n)
{
	uint8_t *t = b + n - LOOM__DB_TRAILER_BYTES;
	uint64_t mo = loom__le64(t + 8), ml = loom__le64(t + 16), h;

	loom__put32(b + 124, libdeflate_crc32(0, b, 124));
	if (mo > n || ml > n - mo) /* damaged trailer: nothing to reseal */
		return;
	loom__put32(t + 24, libdeflate_crc32(0, b + mo, ml));
	h = loom__fnv1a64(loom__fnv1a64(LOOM__FNV_OFFSET, b, 128), b + mo, ml);
	loom__put64(t + 40, h);
	loom__put32(t + 60, libdeflate_crc32(0, t, 60));
}

/* Offset of brick id's index entry in the file image. */
static size_t index_entry(const uint8_t *b, size_t n, uint32_t id)
{
	const uint8_t *t = b + n - LOOM__DB_TRAILER_BYTES;
	uint64_t mo = loom__le64(t + 8);
	/* the entry size of the file's version (24 or 56, metadata byte 20) */
	return (size_t)(mo + loom__le64(b + mo + 40) + (uint64_t)id * loom__le32(b + mo + 20));
}

static int open_code(const char *path, loom_diag *d)
{
	loom_db *db = NULL;
	int rc;

	memset(d, 0, sizeof *d);
	rc = loom_db_open(path, &db, d);
	if (rc == LOOM_OK)
		loom_db_close(db);
	else
		CHECK(db == NULL);
	return rc;
}

/* ---- generated database: every voxel equals the generator's ----------------- */

static loom_exgen_params gen_params(void)
{
	loom_exgen_params p;
	loom_exgen_preset("small", &p);
	p.block[0] = 12;
	p.block[1] = 8;
	p.block[2] = 20;
	p.voxel_size_um = 40;
	p.brick[0] = p.brick[1] = p.brick[2] = 8;
	p.n_weaves = 2;
	p.weaves[0] = "twill:2/3";
	p.weaves[1] = "plain";
	p.seed = 7;
	return p;
}

static void test_roundtrip_generated(void)
{
	loom_exgen_params p = gen_params();
	loom_diag d = {0};
	loom_db *db = NULL;
	loom_db_info info;
	uint64_t hash = 0;
	int rc;

	p.db_version = 3; /* gen.ldb: version 3; gen2 and gen1 the older ones */
	rc = loom_exgen_write_db(tpath("gen.ldb"), &p, &hash, &d);
	CHECK_EQ_INT(rc, LOOM_OK);
	if (rc == LOOM_OK) { /* the same exemplars in format version 1 */
		loom_exgen_params p1 = p;
		uint64_t h1 = 0;
		p1.db_version = 1;
		CHECK_EQ_INT(loom_exgen_write_db(tpath("gen1.ldb"), &p1, &h1, &d), LOOM_OK);
		CHECK(h1 != hash);
		p1.db_version = 2; /* and in version 2 */
		CHECK_EQ_INT(loom_exgen_write_db(tpath("gen2.ldb"), &p1, &h1, &d), LOOM_OK);
		CHECK(h1 != hash);
		p1.db_version = 0; /* and in the default, version 4 */
		CHECK_EQ_INT(loom_exgen_write_db(tpath("gen4.ldb"), &p1, &h1, &d), LOOM_OK);
		CHECK(h1 != hash);
	}
	if (rc) {
		printf("  %s\n", d.message);
		return;
	}
	rc = loom_db_open(tpath("gen.ldb"), &db, &d);
	CHECK_EQ_INT(rc, LOOM_OK);
	if (rc) {
		printf("  %s\n", d.message);
		return;
	}
	loom_db_get_info(db, &info);
	CHECK_EQ_INT(info.n_exemplars, 2);
	CHECK(info.content_hash == hash && hash != 0);
	CHECK(loom_db_content_hash(db) == hash);
	CHECK_EQ_INT(info.block[0], 12);
	CHECK_EQ_INT(info.brick[2], 8);
	CHECK(info.n_empty_bricks > 0);
	CHECK(info.n_empty_bricks < info.n_bricks);
	for (uint32_t k = 0; k < 2; k++) {
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		loom_db_exemplar_info e;
		size_t n;
		uint8_t *gd8, *gl8, *rd, *rl;
		uint16_t *go, *ro;
		uint32_t org[3] = {0, 0, 0};
		long bad = 0;

		CHECK_EQ_INT(loom__exgen_new(&p, k, 0, &g, &d), LOOM_OK);
		loom__exgen_describe(g, &gd);
		CHECK_EQ_INT(loom_db_exemplar(db, k, &e), LOOM_OK);
		CHECK_EQ_INT(e.rows, gd.rows);
		CHECK_EQ_INT(e.cols, gd.cols);
		CHECK(strcmp(e.name, gd.name) == 0);
		CHECK(memcmp(e.weave, gd.weave, (size_t)e.rows * e.cols) == 0);
		CHECK_EQ_INT(e.n_yarns, gd.n_yarns);
		for (uint32_t l = 0; l <= e.n_yarns; l++)
			CHECK(e.yarns[l].kind == gd.yarns[l].kind &&
			      e.yarns[l].index == gd.yarns[l].index &&
			      e.yarns[l].flags == gd.yarns[l].flags);
		n = (size_t)e.size[0] * e.size[1] * e.size[2];
		gd8 = malloc(n);
		gl8 = malloc(n);
		go = malloc(2 * n);
		rd = malloc(n);
		rl = malloc(n);
		ro = malloc(2 * n);
		loom__exgen_box(g, 0, 0, 0, e.size[0], e.size[1], e.size[2], gd8, go, gl8);
		CHECK_EQ_INT(loom_db_read_box(db, k, org, e.size, rd, ro, rl, &d), LOOM_OK);
		for (uint32_t y = 0; y < e.size[1]; y++)
			for (uint32_t x = 0; x < e.size[0]; x++)
				for (uint32_t z = 0; z < e.size[2]; z++) {
					size_t gi = ((size_t)y * e.size[0] + x) * e.size[2] + z;
					size_t ri = ((size_t)z * e.size[1] + y) * e.size[0] + x;
					if (gd8[gi] != rd[ri] || go[gi] != ro[ri] || gl8[gi] != rl[ri])
						bad++;
				}
		CHECK_EQ_INT(bad, 0);
		/* density alone (its plane units only) over an odd box across
		   brick borders: the same bytes as the whole read */
		{
			uint32_t o2[3] = {3, 5, 7}, s2[3] = {e.size[0] - 4, e.size[1] - 7, e.size[2] - 9};
			uint8_t *d2 = malloc((size_t)s2[0] * s2[1] * s2[2]);
			long bad2 = 0;
			CHECK_EQ_INT(loom_db_read_box(db, k, o2, s2, d2, NULL, NULL, &d), LOOM_OK);
			for (uint32_t z = 0; z < s2[2]; z++)
				for (uint32_t y = 0; y < s2[1]; y++)
					for (uint32_t x = 0; x < s2[0]; x++)
						bad2 += d2[((size_t)z * s2[1] + y) * s2[0] + x] !=
						        rd[((size_t)(z + o2[2]) * e.size[1] + y + o2[1]) *
						                   e.size[0] + x + o2[0]];
			CHECK_EQ_INT(bad2, 0);
			free(d2);
		}
		/* non-trivial content: yarns of both kinds, empty space above */
		{
			long filled = 0, warp = 0, weft = 0;
			for (size_t i = 0; i < n; i++) {
				filled += rl[i] != 0;
				warp += e.yarns[rl[i]].kind == LOOM_YARN_WARP;
				weft += e.yarns[rl[i]].kind == LOOM_YARN_WEFT;
			}
			CHECK(filled > (long)n / 10 && filled < (long)n / 2);
			CHECK(warp > 0 && weft > 0);
		}
		/* every brick: empty flag <=> all voxels zero; raw reads agree */
		{
			loom__db_geom geo;
			struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
			uint8_t *brick, *scratch;
			loom__db_geometry(db, &geo);
			brick = malloc(geo.brick_bytes);
			scratch = malloc(loom__db_scratch_bytes(db));
			for (uint32_t by = 0; by < e.bricks[1]; by++)
				for (uint32_t bx = 0; bx < e.bricks[0]; bx++)
					for (uint32_t bz = 0; bz < e.bricks[2]; bz++) {
						uint32_t id, kk, x1, y1, z1;
						int nz = 0;
						CHECK_EQ_INT(loom__db_brick_id(db, k, bx, by, bz, &id), LOOM_OK);
						CHECK_EQ_INT(loom__db_brick_coords(db, id, &kk, &x1, &y1, &z1),
						             LOOM_OK);
						CHECK(kk == k && x1 == bx && y1 == by && z1 == bz);
						CHECK_EQ_INT(loom__db_read_brick(db, id, dec, scratch, brick,
						                                 NULL, &d), LOOM_OK);
						for (size_t i = 0; i < geo.brick_bytes; i++)
							nz |= brick[i] != 0;
						CHECK_EQ_INT(loom__db_brick_empty(db, id), !nz);
					}
			free(brick);
			free(scratch);
			libdeflate_free_decompressor(dec);
		}
		free(gd8);
		free(gl8);
		free(go);
		free(rd);
		free(rl);
		free(ro);
		loom__exgen_free(g);
	}
	CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &d), LOOM_OK);
	/* out-of-range queries */
	{
		uint32_t id, org[3] = {0, 0, 0}, sz[3] = {1, 1, 100};
		uint8_t buf[100];
		loom_db_block_info bi;
		CHECK_EQ_INT(loom__db_brick_id(db, 2, 0, 0, 0, &id), LOOM_ERANGE);
		CHECK_EQ_INT(loom__db_brick_id(db, 0, 99, 0, 0, &id), LOOM_ERANGE);
		CHECK_EQ_INT(loom_db_read_box(db, 0, org, sz, buf, NULL, NULL, &d), LOOM_ERANGE);
		CHECK_STR_CONTAINS(d.message, "outside exemplar");
		CHECK_EQ_INT(loom_db_block(db, 0, 5, 0, &bi), LOOM_ERANGE);
		CHECK_EQ_INT(loom_db_read_box(db, 9, org, sz, buf, NULL, NULL, &d), LOOM_ERANGE);
		CHECK_EQ_INT(loom__db_read_brick(db, 1u << 30, NULL, NULL, NULL, NULL, &d),
		             LOOM_ERANGE);
		CHECK_STR_CONTAINS(d.message, "out of range");
	}
	loom_db_close(db);
}

/* Two threads reading every brick concurrently get the same bytes. */
typedef struct reader_arg {
	const loom_db *db;
	uint64_t sum;
	int rc;
} reader_arg;

static void *reader(void *p)
{
	reader_arg *a = p;
	loom__db_geom geo;
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	uint8_t *brick, *scratch;
	loom_diag d = {0};

	loom__db_geometry(a->db, &geo);
	brick = malloc(geo.brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(a->db));
	for (int rep = 0; rep < 3; rep++)
		for (uint32_t id = 0; id < geo.n_bricks; id++) {
			a->rc |= loom__db_read_brick(a->db, id, dec, scratch, brick, NULL, &d);
			a->sum = loom__fnv1a64(a->sum, brick, geo.brick_bytes);
		}
	free(brick);
	free(scratch);
	libdeflate_free_decompressor(dec);
	return NULL;
}

static void test_threaded_reads(void)
{
	loom_db *db = NULL;
	loom_diag d = {0};
	pthread_t t[2];
	reader_arg a[2];

	CHECK_EQ_INT(loom_db_open(tpath("gen.ldb"), &db, &d), LOOM_OK);
	if (!db)
		return;
	for (int i = 0; i < 2; i++) {
		a[i].db = db;
		a[i].sum = LOOM__FNV_OFFSET;
		a[i].rc = 0;
		pthread_create(&t[i], NULL, reader, &a[i]);
	}
	for (int i = 0; i < 2; i++)
		pthread_join(t[i], NULL);
	CHECK_EQ_INT(a[0].rc, 0);
	CHECK_EQ_INT(a[1].rc, 0);
	CHECK(a[0].sum == a[1].sum);
	loom_db_close(db);
}

/* The per-thread reader object the brick cache uses. */
static void test_reader_object(void)
{
	loom_db *db = NULL;
	loom_diag d = {0};
	loom__db_reader *r;
	loom__db_geom geo;
	uint8_t *a, *b, *scratch;
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	int bad = 0;

	CHECK_EQ_INT(loom_db_open(tpath("gen.ldb"), &db, &d), LOOM_OK);
	if (!db) {
		libdeflate_free_decompressor(dec);
		return;
	}
	loom__db_geometry(db, &geo);
	r = loom__db_reader_new(db);
	CHECK(r != NULL);
	/* the bound covers the decompressor (about 10 KB in libdeflate 1.14)
	   and the scratch */
	CHECK(loom__db_reader_bytes(db) > loom__db_scratch_bytes(db) + 4096);
	CHECK(loom__db_reader_bytes(db) < loom__db_scratch_bytes(db) + (1u << 20));
	a = malloc(geo.brick_bytes);
	b = malloc(geo.brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	for (uint32_t id = 0; id < geo.n_bricks && r; id++) {
		size_t n1 = 0, n2 = 0;
		bad |= loom__db_reader_read(r, id, a, &n1, &d) != LOOM_OK;
		bad |= loom__db_read_brick(db, id, dec, scratch, b, &n2, &d) != LOOM_OK;
		bad |= memcmp(a, b, geo.brick_bytes) != 0 || n1 != n2;
		bad |= loom__db_brick_empty(db, id) ? n1 != 0 : n1 == 0;
	}
	CHECK(!bad);
	CHECK_EQ_INT(loom__db_reader_read(r, geo.n_bricks, a, NULL, &d), LOOM_ERANGE);
	loom__db_reader_free(r);
	loom__db_reader_free(NULL);
	free(a);
	free(b);
	free(scratch);
	libdeflate_free_decompressor(dec);
	loom_db_close(db);
	loom_db_close(NULL);
}

/* ---- hand-made database: raw bricks, empty bricks, tables ------------------- */

/*
 * One exemplar, plain weave 2x2 crossings, block 4x4x8, brick 4x4x4, so the
 * volume 8x8x8 is 2x2x2 bricks.  Label 1 = warp, 2 = weft, 3 = flyaway,
 * labels up to 255 exist (kind weft) so that noise labels are valid.
 * Brick (0,0,0): noise (stored raw); (0,0,1): empty; the others: a known
 * height map, top surface at h(x,y) = 2 + (x + 2y) % 5 over solid voxels,
 * a flyaway voxel above it at (5,5) which the tables must ignore.
 */
static uint32_t hm(uint32_t x, uint32_t y)
{
	return 2 + (x + 2 * y) % 5;
}

static void fill_brick(uint8_t *raw, uint32_t bx, uint32_t by, uint32_t bz,
                       uint64_t *rng)
{
	size_t nv = 64;

	memset(raw, 0, 4 * nv);
	if (bx == 0 && by == 0 && bz == 0) {
		for (size_t i = 0; i < 4 * nv; i++) {
			*rng = *rng * 6364136223846793005ull + 1442695040888963407ull;
			raw[i] = (uint8_t)(*rng >> 56);
		}
		return;
	}
	if (bx == 0 && by == 0 && bz == 1)
		return;
	for (uint32_t ly = 0; ly < 4; ly++)
		for (uint32_t lx = 0; lx < 4; lx++) {
			uint32_t x = bx * 4 + lx, y = by * 4 + ly;
			for (uint32_t lz = 0; lz < 4; lz++) {
				uint32_t z = bz * 4 + lz;
				size_t i = loom__brick_index(4, 4, lx, ly, lz);
				if (z < hm(x, y)) {
					raw[i] = 200;
					raw[3 * nv + i] = (x / 4 + y / 4) % 2 ? 2 : 1;
					raw[nv + i] = 7;
				} else if (x == 5 && y == 5 && z == 7) {
					raw[i] = 255;
					raw[3 * nv + i] = 3; /* flyaway */
				}
			}
		}
}

/* The hand-made exemplar, into a new database of voxel layout `layout`
   (0: the current one; | 0x100: its density planes stored raw), or
   appended to path's when append is set. */
/* A 2 x 2 plain exemplar record for the writer, labels 1..n_yarns. */
static void plain_exemplar(loom__dbw_exemplar *e, const char *name, const uint8_t *weave,
                           const loom_db_yarn *yarns, uint32_t n_yarns)
{
	e->name = name;
	e->weave_name = "plain";
	e->rows = e->cols = 2;
	e->weave = weave;
	e->n_yarns = n_yarns;
	e->yarns = yarns;
}

static int write_hand(const char *path, unsigned layout, int append, uint64_t *hash,
                      loom_diag *d)
{
	loom__dbw_params wp;
	loom__dbw_exemplar e;
	loom_db_yarn yarns[256];
	uint8_t weave[4] = {1, 0, 0, 1}, raw[256];
	loom__dbw *w;
	uint64_t rng = 12345;
	int rc;

	memset(&wp, 0, sizeof wp);
	memset(&e, 0, sizeof e);
	wp.n_exemplars = 1;
	wp.block[0] = wp.block[1] = 4;
	wp.block[2] = 8;
	wp.brick[0] = wp.brick[1] = wp.brick[2] = 4;
	wp.voxel_size_um = 10;
	wp.top_threshold = 64;
	wp.level = 6;
	wp.layout = layout & 0xff; /* 0x100: density raw; 0x200: one bad voxel */
	wp.density_raw = (layout & 0x100) != 0;
	memset(yarns, 0, sizeof yarns);
	for (int l = 1; l < 256; l++) {
		yarns[l].kind = LOOM_YARN_WEFT;
		yarns[l].index = (int16_t)(l % 2); /* a pick of the 2x2 window */
	}
	yarns[1].kind = LOOM_YARN_WARP;
	yarns[1].index = 0;
	yarns[3].flags = LOOM_DB_YARN_FLYAWAY;
	plain_exemplar(&e, "hand", weave, yarns, 255);
	rc = append ? loom__dbw_append(path, 1, 0, &w, NULL, d) :
	              loom__dbw_create(path, &wp, &w, d);
	if (rc != LOOM_OK)
		return rc;
	if ((rc = loom__dbw_begin_exemplar(w, &e, d)) != LOOM_OK) {
		loom__dbw_abort(w);
		return rc;
	}
	for (uint32_t by = 0; by < 2; by++)
		for (uint32_t bx = 0; bx < 2; bx++)
			for (uint32_t bz = 0; bz < 2; bz++) {
				fill_brick(raw, bx, by, bz, &rng);
				if ((layout & 0x200) && bx == 1 && by == 0 && bz == 1) {
					/* break the voxel rule at (6, 1, 7): density 0, a
					   label and an orientation code 0x1234 */
					size_t i = loom__brick_index(4, 4, 2, 1, 3);
					raw[i] = 0;
					raw[64 + i] = 0x34;
					raw[128 + i] = 0x12;
					raw[192 + i] = 1;
				}
				if ((rc = loom__dbw_add_brick(w, raw, d)) != LOOM_OK) {
					loom__dbw_abort(w);
					return rc;
				}
			}
	return loom__dbw_finish(w, hash, d);
}

static int write_handmade(const char *path, uint64_t *hash, loom_diag *d)
{
	return write_hand(path, 0, 0, hash, d);
}

/* The last warning given (test_orient_rule). */
static char warn_last[LOOM_DIAG_MSG_MAX];

static void warn_keep(void *user, const char *msg)
{
	(void)user;
	snprintf(warn_last, sizeof warn_last, "%s", msg);
}

/* The voxel rule (docs/formats.md): orientation code 0 wherever density
   is 0.  loom_db_verify refuses a file that breaks it, naming the voxel
   and the code; loom_db_convert writes it again with that code cleared
   and every other byte the same. */
static void test_orient_rule(void)
{
	const char *bad = tpath("orule.ldb"), *good = tpath("orule-fixed.ldb");
	loom_diag d = {0};
	loom_db *a = NULL, *b = NULL;
	uint64_t h = 0;
	uint32_t org[3] = {0, 0, 0}, sz[3] = {8, 8, 8};
	uint8_t da[512], db_[512], la[512], lb[512];
	uint16_t oa[512], ob[512];
	size_t at = ((size_t)7 * 8 + 1) * 8 + 6, differ = 0;

	CHECK_EQ_INT(write_hand(bad, 0x200, 0, &h, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(bad, &a, &d), LOOM_OK);
	if (!a)
		return;
	CHECK_EQ_INT(loom_db_verify(a, NULL, NULL, &d), LOOM_ECORRUPT);
	CHECK(strstr(d.message, "voxel (6, 1, 7)") != NULL);
	CHECK(strstr(d.message, "code 0x1234") != NULL);
	CHECK(strstr(d.message, "loom exemplar convert") != NULL);
	d.n_warnings = 0;
	d.warn = warn_keep;
	d.user = NULL;
	warn_last[0] = 0;
	CHECK_EQ_INT(loom_db_convert(bad, good, 0, -1, NULL, NULL, &h, &d), LOOM_OK);
	/* the user is told what was cleared */
	CHECK_EQ_INT(d.n_warnings, 1);
	CHECK(strstr(warn_last, "cleared the orientation codes of 1 voxel of density 0") !=
	      NULL);
	d.warn = NULL;
	d.n_warnings = 0;
	CHECK_EQ_INT(loom_db_convert(good, tpath("orule-again.ldb"), 0, -1, NULL, NULL, &h, &d),
	             LOOM_OK);
	CHECK_EQ_INT(d.n_warnings, 0); /* nothing to clear: no warning */
	CHECK_EQ_INT(loom_db_open(good, &b, &d), LOOM_OK);
	if (!b) {
		loom_db_close(a);
		return;
	}
	CHECK_EQ_INT(loom_db_verify(b, NULL, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_read_box(a, 0, org, sz, da, oa, la, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_read_box(b, 0, org, sz, db_, ob, lb, &d), LOOM_OK);
	CHECK(memcmp(da, db_, sizeof da) == 0 && memcmp(la, lb, sizeof la) == 0);
	CHECK_EQ_INT(da[at], 0);
	CHECK_EQ_INT(la[at], 1);
	CHECK_EQ_INT(oa[at], 0x1234);
	CHECK_EQ_INT(ob[at], 0);
	for (size_t i = 0; i < 512; i++)
		differ += oa[i] != ob[i];
	CHECK_EQ_INT(differ, 1);
	loom_db_close(a);
	loom_db_close(b);
}

/* Appending keeps the database's layout: a version-1 file stays version 1
   (its bricks are copied verbatim), a version-2 file version 2, a
   version-3 file version 3, and a version-2 file whose density planes
   are all raw (density_raw) stays so; the appended exemplar reads back
   equal to the first in each. */
static void test_append_layouts(void)
{
	for (unsigned k = 1; k <= 5; k++) {
		unsigned lay = k == 4 ? 2 : k == 5 ? 4 : k;
		loom_diag d = {0};
		loom_db *db = NULL;
		loom_db_info info;
		uint64_t h = 0;
		const char *p = tpath(k == 1 ? "app1.ldb" : k == 2 ? "app2.ldb" :
		                      k == 3 ? "app3.ldb" : k == 4 ? "app2r.ldb" : "app4.ldb");
		uint32_t org[3] = {0, 0, 0}, sz[3] = {8, 8, 8};
		uint8_t a[512], b[512], al[512], bl[512];
		uint16_t ao[512], bo[512];
		CHECK_EQ_INT(write_hand(p, lay | (k == 4 ? 0x100u : 0), 0, &h, &d), LOOM_OK);
		CHECK_EQ_INT(write_hand(p, 0, 1, &h, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_open(p, &db, &d), LOOM_OK);
		if (!db) {
			printf("  %s\n", d.message);
			continue;
		}
		loom_db_get_info(db, &info);
		CHECK_EQ_INT(info.version, lay);
		CHECK_EQ_INT(info.voxel_layout, lay);
		CHECK_EQ_INT(info.n_exemplars, 2);
		if (k == 4) /* every stored brick's density raw, the appended too */
			CHECK_EQ_INT(info.n_raw_density, info.n_bricks - info.n_empty_bricks);
		CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_read_box(db, 0, org, sz, a, ao, al, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_read_box(db, 1, org, sz, b, bo, bl, &d), LOOM_OK);
		CHECK(memcmp(a, b, sizeof a) == 0 && memcmp(al, bl, sizeof al) == 0 &&
		      memcmp(ao, bo, sizeof ao) == 0);
		loom_db_close(db);
	}
}

/* Appending to a database written with density_raw keeps its density
   planes raw (test_append_layouts' 64-voxel planes never compress, so
   this one appends a 16 x 16 x 64 brick that does): to a raw tiny
   database the appended brick's density is raw, to a deflated one it is
   deflated. */
static void test_append_raw_density(void)
{
	{ /* version 1 stores a brick as one stream: refused */
		loom_exgen_params p;
		loom_diag d = {0};
		loom_exgen_preset("tiny", &p);
		p.density_raw = 1;
		p.db_version = 1;
		CHECK_EQ_INT(loom_exgen_check_params(&p, &d), LOOM_EINVAL);
		CHECK(strstr(d.message, "density_raw") != NULL);
		p.db_version = 3;
		CHECK_EQ_INT(loom_exgen_check_params(&p, &d), LOOM_OK);
	}
	for (int r = 0; r < 2; r++) {
		loom_exgen_params p;
		loom_diag d = {0};
		loom_db *db = NULL;
		loom_db_info before, after;
		loom__dbw *w = NULL;
		loom__dbw_exemplar e;
		loom_db_yarn yarns[256];
		uint8_t weave[4] = {1, 0, 0, 1}, *raw;
		const char *path = tpath(r ? "app-raw.ldb" : "app-deflated.ldb");
		size_t nv = 16 * 16 * 64;

		loom_exgen_preset("tiny", &p);
		p.n_weaves = 1;
		p.weaves[0] = "twill:2/3";
		p.density_raw = (uint32_t)r;
		CHECK_EQ_INT(loom_exgen_write_db(path, &p, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_open(path, &db, &d), LOOM_OK);
		if (!db)
			continue;
		loom_db_get_info(db, &before);
		loom_db_close(db);
		db = NULL;
		CHECK(before.n_bricks > before.n_empty_bricks);
		CHECK_EQ_INT(before.n_raw_density,
		             r ? before.n_bricks - before.n_empty_bricks : 0);
		/* a 2 x 2 exemplar of 16 x 12 x 12 voxels: one brick, its lower half
		   dense warp (compresses well) */
		raw = calloc(4, nv);
		memset(&e, 0, sizeof e); /* fibre: none recorded */
		memset(yarns, 0, sizeof yarns);
		yarns[1].kind = LOOM_YARN_WARP;
		plain_exemplar(&e, "appended", weave, yarns, 1);
		for (uint32_t col = 0; col < 16 * 16 && raw; col++)
			for (uint32_t z = 0; z < 32; z++) {
				raw[col * 64 + z] = 100;
				raw[nv + col * 64 + z] = 7;
				raw[3 * nv + col * 64 + z] = 1;
			}
		CHECK(raw != NULL);
		if (raw && loom__dbw_append(path, 1, 0, &w, NULL, &d) == LOOM_OK) {
			int rc = loom__dbw_begin_exemplar(w, &e, &d);
			if (rc == LOOM_OK)
				rc = loom__dbw_add_brick(w, raw, &d);
			if (rc == LOOM_OK)
				rc = loom__dbw_finish(w, NULL, &d);
			else
				loom__dbw_abort(w);
			CHECK_EQ_INT(rc, LOOM_OK);
			if (rc != LOOM_OK)
				printf("  %s\n", d.message);
		} else {
			CHECK(0);
		}
		free(raw);
		CHECK_EQ_INT(loom_db_open(path, &db, &d), LOOM_OK);
		if (!db)
			continue;
		loom_db_get_info(db, &after);
		CHECK_EQ_INT(after.n_bricks, before.n_bricks + 1);
		CHECK_EQ_INT(after.n_raw_density, before.n_raw_density + (r ? 1 : 0));
		CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &d), LOOM_OK);
		loom_db_close(db);
	}
}

static void test_handmade(void)
{
	loom_diag d = {0};
	loom_db *db = NULL;
	loom_db_info info;
	loom_db_exemplar_info e;
	loom_db_block_info b;
	uint64_t hash = 0, rng = 12345;
	uint8_t want[256], got[256], scratch[512];
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	int rc;

	rc = write_handmade(tpath("hand.ldb"), &hash, &d);
	CHECK_EQ_INT(rc, LOOM_OK);
	rc = loom_db_open(tpath("hand.ldb"), &db, &d);
	CHECK_EQ_INT(rc, LOOM_OK);
	if (rc) {
		printf("  %s\n", d.message);
		libdeflate_free_decompressor(dec);
		return;
	}
	loom_db_get_info(db, &info);
	CHECK_EQ_INT(info.n_bricks, 8);
	CHECK_EQ_INT(info.n_empty_bricks, 1);
	CHECK_EQ_INT(info.n_raw_bricks, 1);
	CHECK(loom__db_brick_empty(db, 1));
	/* every brick reads back as written (raw, empty and deflate) */
	for (uint32_t by = 0; by < 2; by++)
		for (uint32_t bx = 0; bx < 2; bx++)
			for (uint32_t bz = 0; bz < 2; bz++) {
				uint32_t id;
				fill_brick(want, bx, by, bz, &rng);
				loom__db_brick_id(db, 0, bx, by, bz, &id);
				CHECK_EQ_INT(loom__db_read_brick(db, id, dec, scratch, got, NULL, &d),
				             LOOM_OK);
				CHECK(memcmp(want, got, 256) == 0);
			}
	CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &d), LOOM_OK);
	/* tables (brute force from the known height map) */
	CHECK_EQ_INT(loom_db_exemplar(db, 0, &e), LOOM_OK);
	CHECK_EQ_INT(e.n_symmetries, 2); /* plain: (0,0) and (1,1) */
	CHECK(e.symmetries[0] == 0 && e.symmetries[1] == 0);
	CHECK(e.symmetries[2] == 1 && e.symmetries[3] == 1);
	for (uint32_t r = 0; r < 2; r++)
		for (uint32_t c = 0; c < 2; c++) {
			uint32_t x0 = c * 4, y0 = r * 4;
			double sx = 0, sy = 0, sum = 0;
			int nx = 0, ny = 0, nn = 0;
			CHECK_EQ_INT(loom_db_block(db, 0, r, c, &b), LOOM_OK);
			/* plain weave: own bit = (r == c), all four neighbours opposite */
			CHECK_EQ_INT(b.code, r == c ? LOOM_DB_CODE_SELF
			                            : LOOM_DB_CODE_N | LOOM_DB_CODE_S |
			                                      LOOM_DB_CODE_W | LOOM_DB_CODE_E);
			if (r == 0 && c == 0) {
				/* brick (0,0,0) is noise: its labels are random, skip values */
				continue;
			}
			for (uint32_t i = 0; i < 4; i++) {
				CHECK(b.north[i] == (float)hm(x0 + i, y0));
				CHECK(b.south[i] == (float)hm(x0 + i, y0 + 3));
				CHECK(b.west[i] == (float)hm(x0, y0 + i));
				CHECK(b.east[i] == (float)hm(x0 + 3, y0 + i));
			}
			for (uint32_t y = y0; y < y0 + 4; y++)
				for (uint32_t x = x0; x < x0 + 4; x++) {
					sum += hm(x, y);
					nn++;
					if (x + 1 < x0 + 4) {
						sx += fabs((double)hm(x + 1, y) - hm(x, y));
						nx++;
					}
					if (y + 1 < y0 + 4) {
						sy += fabs((double)hm(x, y + 1) - hm(x, y));
						ny++;
					}
				}
			CHECK(fabs(b.mean_dh_x - sx / nx) < 1e-5);
			CHECK(fabs(b.mean_dh_y - sy / ny) < 1e-5);
			CHECK(fabs(b.mean_height - sum / nn) < 1e-5);
			CHECK_EQ_INT(b.gap_columns, 0);
			CHECK_EQ_INT(b.centre_kind, (c + r) % 2 ? LOOM_YARN_WEFT : LOOM_YARN_WARP);
		}
	libdeflate_free_decompressor(dec);
	loom_db_close(db);
}

/* ---- the height map streamed by block rows ----------------------------- */

/* Top height of column (x, y) of exemplar u of the streamed test (0: gap). */
static uint32_t ring_h(uint32_t u, uint32_t x, uint32_t y)
{
	if ((x * 5 + y * 3 + u) % 13 == 0)
		return 0;
	return 1 + (x * 7 + y * 3 + u * 5 + (x * y) % 4) % 7;
}

/* Write two exemplars of R x C crossings with block b1 x b2 x 8 and brick
   k1 x k2 x 4 (so block rows and brick rows do not line up), then check
   every block's tables against a brute force over ring_h: the writer keeps
   only b2 + k2 rows of the height map, so this reads the map after it has
   wrapped around many times. */
static void streamed_case(uint32_t b1, uint32_t b2, uint32_t k1, uint32_t k2)
{
	enum { R = 7, C = 3, Z = 8, KZ = 4 };
	loom__dbw_params wp;
	loom__dbw_exemplar e;
	loom_db_yarn yarns[3];
	uint8_t weave[R * C];
	uint8_t *raw = malloc(4 * (size_t)k1 * k2 * KZ);
	size_t nv = (size_t)k1 * k2 * KZ;
	loom__dbw *w = NULL;
	loom_db *db = NULL;
	loom_diag d = {0};
	uint64_t hash;
	uint32_t sx = C * b1, sy = R * b2, bad = 0, blocks = 0;

	memset(&wp, 0, sizeof wp);
	memset(&e, 0, sizeof e);
	wp.n_exemplars = 2;
	wp.block[0] = b1;
	wp.block[1] = b2;
	wp.block[2] = Z;
	wp.brick[0] = k1;
	wp.brick[1] = k2;
	wp.brick[2] = KZ;
	wp.voxel_size_um = 10;
	wp.top_threshold = 64;
	wp.level = 1;
	memset(yarns, 0, sizeof yarns);
	yarns[1].kind = LOOM_YARN_WARP;
	yarns[2].kind = LOOM_YARN_WEFT;
	for (int k = 0; k < R * C; k++)
		weave[k] = (uint8_t)((k * 7 / 3) % 2);
	e.weave_name = "test";
	e.rows = R;
	e.cols = C;
	e.weave = weave;
	e.n_yarns = 2;
	e.yarns = yarns;
	CHECK_EQ_INT(loom__dbw_create(tpath("ring.ldb"), &wp, &w, &d), LOOM_OK);
	for (uint32_t u = 0; u < 2 && w; u++) {
		e.name = u ? "second" : "first";
		CHECK_EQ_INT(loom__dbw_begin_exemplar(w, &e, &d), LOOM_OK);
		for (uint32_t by = 0; by * k2 < sy; by++)
			for (uint32_t bx = 0; bx * k1 < sx; bx++)
				for (uint32_t bz = 0; bz * KZ < Z; bz++) {
					memset(raw, 0, 4 * nv);
					for (uint32_t ly = 0; ly < k2; ly++)
						for (uint32_t lx = 0; lx < k1; lx++)
							for (uint32_t lz = 0; lz < KZ; lz++) {
								uint32_t x = bx * k1 + lx, y = by * k2 + ly, z = bz * KZ + lz;
								size_t i = loom__brick_index(k1, KZ, lx, ly, lz);
								if (x >= sx || y >= sy || z >= ring_h(u, x, y))
									continue;
								raw[i] = 200;
								raw[nv + i] = 7;
								raw[3 * nv + i] = (uint8_t)(1 + (x + y) % 2);
							}
					CHECK_EQ_INT(loom__dbw_add_brick(w, raw, &d), LOOM_OK);
				}
	}
	CHECK_EQ_INT(loom__dbw_finish(w, &hash, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(tpath("ring.ldb"), &db, &d), LOOM_OK);
	for (uint32_t u = 0; u < 2 && db; u++)
		for (uint32_t r = 0; r < R; r++)
			for (uint32_t c = 0; c < C; c++) {
				loom_db_block_info b;
				uint32_t x0 = c * b1, y0 = r * b2, gaps = 0, nn = 0, nx = 0, ny = 0, h;
				double sum = 0, dx = 0, dy = 0;
				int ok = 1;
				CHECK_EQ_INT(loom_db_block(db, u, r, c, &b), LOOM_OK);
				for (uint32_t y = y0; y < y0 + b2; y++)
					for (uint32_t x = x0; x < x0 + b1; x++) {
						if (!(h = ring_h(u, x, y))) {
							gaps++;
							continue;
						}
						sum += h;
						nn++;
						if (x + 1 < x0 + b1 && ring_h(u, x + 1, y)) {
							dx += fabs((double)ring_h(u, x + 1, y) - h);
							nx++;
						}
						if (y + 1 < y0 + b2 && ring_h(u, x, y + 1)) {
							dy += fabs((double)ring_h(u, x, y + 1) - h);
							ny++;
						}
					}
				ok &= b.gap_columns == gaps;
				ok &= fabs(b.mean_height - sum / nn) < 1e-4;
				ok &= fabs(b.mean_dh_x - (nx ? dx / nx : 0)) < 1e-4;
				ok &= fabs(b.mean_dh_y - (ny ? dy / ny : 0)) < 1e-4;
				h = ring_h(u, x0 + b1 / 2, y0 + b2 / 2);
				ok &= b.centre_kind == (h ? 1 + (x0 + b1 / 2 + y0 + b2 / 2) % 2 : 0);
				for (uint32_t i = 0; i < b1; i++) { /* surface columns */
					if ((h = ring_h(u, x0 + i, y0)) != 0)
						ok &= b.north[i] == (float)h;
					if ((h = ring_h(u, x0 + i, y0 + b2 - 1)) != 0)
						ok &= b.south[i] == (float)h;
				}
				for (uint32_t i = 0; i < b2; i++) {
					if ((h = ring_h(u, x0, y0 + i)) != 0)
						ok &= b.west[i] == (float)h;
					if ((h = ring_h(u, x0 + b1 - 1, y0 + i)) != 0)
						ok &= b.east[i] == (float)h;
				}
				bad += !ok;
				blocks++;
			}
	printf("  block %ux%u, brick %ux%u: %u of %u blocks differ\n", b1, b2, k1, k2,
	       bad, blocks);
	CHECK_EQ_INT(blocks, 2 * R * C);
	CHECK_EQ_INT(bad, 0);
	loom_db_close(db);
	free(raw);
}

static void test_streamed_height_map(void)
{
	streamed_case(5, 7, 4, 3);  /* several brick rows per block row */
	streamed_case(6, 3, 4, 8);  /* several block rows per brick row */
	streamed_case(4, 5, 3, 5);  /* aligned */
	streamed_case(3, 4, 16, 16); /* one brick row: the ring is the exemplar */
}

/* ---- malformed inputs ----------------------------------------------------- */

static void test_bad_magic_version(void)
{
	size_t n;
	uint8_t *b = slurp(tpath("hand.ldb"), &n), *c;
	loom_diag d;

	CHECK(b != NULL);
	if (!b)
		return;
	c = malloc(n);
	memcpy(c, b, n);
	c[1] = 'X';
	spit(tpath("bad_magic.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("bad_magic.ldb"), &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "bad_magic.ldb: offset 0: bad magic");
	/* a text file */
	spit(tpath("text.ldb"), (const uint8_t *)"hello\n", 6);
	CHECK_EQ_INT(open_code(tpath("text.ldb"), &d), LOOM_ETRUNCATED);
	spit(tpath("text2.ldb"), (const uint8_t *)"hello world, not a db\n", 22);
	CHECK_EQ_INT(open_code(tpath("text2.ldb"), &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "bad magic");
	/* version 5 (or 0), even with a valid CRC, is a version error */
	memcpy(c, b, n);
	loom__put32(c + 8, 5);
	reseal(c, n);
	spit(tpath("v5.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("v5.ldb"), &d), LOOM_EVERSION);
	CHECK_STR_CONTAINS(d.message, "offset 8: format version 5, this loom reads "
	                   "versions 1 to 4");
	loom__put32(c + 8, 0);
	reseal(c, n);
	spit(tpath("v4.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("v4.ldb"), &d), LOOM_EVERSION);
	/* a version whose layout field disagrees */
	memcpy(c, b, n);
	loom__put32(c + 44, loom__le32(c + 8) == 1 ? 2 : 1);
	reseal(c, n);
	spit(tpath("vlay.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("vlay.ldb"), &d), LOOM_EUNSUPPORTED);
	CHECK_STR_CONTAINS(d.message, "offset 44: voxel layout");
	/* header CRC */
	memcpy(c, b, n);
	c[100] ^= 1;
	spit(tpath("hcrc.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("hcrc.ldb"), &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, "header CRC32");
	/* a bad geometry field behind a valid CRC */
	memcpy(c, b, n);
	loom__put32(c + 32, 0);
	reseal(c, n);
	spit(tpath("brick0.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("brick0.ldb"), &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "offset 32: brick size 0");
	/* trailer CRC and metadata CRC */
	memcpy(c, b, n);
	c[n - 10] ^= 1;
	spit(tpath("tcrc.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("tcrc.ldb"), &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, "trailer CRC32");
	memcpy(c, b, n);
	c[n - LOOM__DB_TRAILER_BYTES - 30] ^= 1;
	spit(tpath("mcrc.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("mcrc.ldb"), &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, "metadata at offset");
	/* content hash alone */
	memcpy(c, b, n);
	c[n - LOOM__DB_TRAILER_BYTES + 40] ^= 1;
	loom__put32(c + n - 4, libdeflate_crc32(0, c + n - 64, 60));
	spit(tpath("hash.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("hash.ldb"), &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, "content hash");
	/* missing file, NULL */
	CHECK_EQ_INT(open_code(tpath("nonexistent.ldb"), &d), LOOM_EIO);
	CHECK_STR_CONTAINS(d.message, "nonexistent.ldb: cannot open");
	CHECK_EQ_INT(loom_db_open(NULL, NULL, NULL), LOOM_EINVAL);
	free(b);
	free(c);
}

static void test_truncation(void)
{
	size_t n;
	uint8_t *b = slurp(tpath("gen.ldb"), &n);
	int bad = 0, tested = 0;
	loom_diag d;

	CHECK(b != NULL);
	if (!b)
		return;
	for (size_t len = 0; len < n; len += (len < 300 || len + 300 > n) ? 1 : 97) {
		int rc;
		spit(tpath("trunc.ldb"), b, len);
		rc = open_code(tpath("trunc.ldb"), &d);
		tested++;
		if (rc != LOOM_ETRUNCATED || !strstr(d.message, "trunc.ldb") ||
		    !strstr(d.message, "truncated")) {
			if (!bad)
				printf("  length %zu: code %d, '%s'\n", len, rc, d.message);
			bad++;
		}
	}
	printf("  %d truncation lengths tested\n", tested);
	CHECK_EQ_INT(bad, 0);
	/* the whole file still opens */
	spit(tpath("trunc.ldb"), b, n);
	CHECK_EQ_INT(open_code(tpath("trunc.ldb"), &d), LOOM_OK);
	/* trailing garbage */
	{
		uint8_t *c = malloc(n + 5);
		memcpy(c, b, n);
		memcpy(c + n, "extra", 5);
		spit(tpath("long.ldb"), c, n + 5);
		CHECK(open_code(tpath("long.ldb"), &d) != LOOM_OK);
		free(c);
	}
	free(b);
}

/* The file shrinks after it was opened: brick reads say so. */
static void test_truncated_after_open(void)
{
	size_t n;
	uint8_t *b = slurp(tpath("gen.ldb"), &n), *brick, *scratch;
	loom_db *db = NULL;
	loom_diag d = {0};
	loom__db_geom geo;
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	int rc = LOOM_OK;
	uint32_t id;

	spit(tpath("shrink.ldb"), b, n);
	CHECK_EQ_INT(loom_db_open(tpath("shrink.ldb"), &db, &d), LOOM_OK);
	if (!db) {
		free(b);
		libdeflate_free_decompressor(dec);
		return;
	}
	CHECK_EQ_INT(truncate(tpath("shrink.ldb"), 200), 0);
	loom__db_geometry(db, &geo);
	brick = malloc(geo.brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	for (id = 0; id < geo.n_bricks && rc == LOOM_OK; id++)
		rc = loom__db_read_brick(db, id, dec, scratch, brick, NULL, &d);
	CHECK_EQ_INT(rc, LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(d.message, "shrink.ldb: brick ");
	CHECK_STR_CONTAINS(d.message, "(exemplar 0 'twill-2-3', brick x=");
	CHECK_STR_CONTAINS(d.message, "truncated");
	CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &d), LOOM_ETRUNCATED);
	free(brick);
	free(scratch);
	free(b);
	libdeflate_free_decompressor(dec);
	loom_db_close(db);
}

/* First non-empty deflate brick of an image. */
static uint32_t first_deflate(const uint8_t *b, size_t n)
{
	uint32_t nb = loom__le32(b + n - LOOM__DB_TRAILER_BYTES + 28);
	for (uint32_t id = 0; id < nb; id++)
		if (b[index_entry(b, n, id) + 20] == LOOM__DB_STORE_DEFLATE)
			return id;
	return 0;
}

static void test_crc_mismatch(void)
{
	size_t n;
	uint8_t *b = slurp(tpath("gen.ldb"), &n), *brick, *scratch;
	uint32_t id = first_deflate(b, n);
	size_t e = index_entry(b, n, id);
	uint64_t off = loom__le64(b + e);
	uint32_t sz = loom__le32(b + e + 8);
	loom_db *db = NULL;
	loom_diag d = {0};
	loom__db_geom geo;
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	char want[64];

	b[off + sz / 2] ^= 0x20; /* one flipped byte inside the brick */
	spit(tpath("flip.ldb"), b, n);
	CHECK_EQ_INT(loom_db_open(tpath("flip.ldb"), &db, &d), LOOM_OK);
	if (!db) {
		free(b);
		libdeflate_free_decompressor(dec);
		return;
	}
	loom__db_geometry(db, &geo);
	brick = malloc(geo.brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	CHECK_EQ_INT(loom__db_read_brick(db, id, dec, scratch, brick, NULL, &d),
	             LOOM_ECORRUPT);
	snprintf(want, sizeof want, "flip.ldb: brick %u (exemplar", id);
	CHECK_STR_CONTAINS(d.message, want);
	CHECK_STR_CONTAINS(d.message, "CRC32 mismatch");
	memset(&d, 0, sizeof d);
	CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, want);
	/* the handle stays usable: another brick still reads */
	CHECK_EQ_INT(loom__db_read_brick(db, id + 1 < geo.n_bricks ? id + 1 : 0, dec,
	                                 scratch, brick, NULL, &d), LOOM_OK);
	free(brick);
	free(scratch);
	free(b);
	libdeflate_free_decompressor(dec);
	loom_db_close(db);
}

/* Version 3 (and 2) against version 1 of the same exemplars: every voxel
   of every channel equal; each unit alone equals its plane of the whole
   brick; a damaged unit is named, and the brick's other units still read. */
static void test_units(void)
{
	loom_db *d2 = NULL, *d1 = NULL;
	loom_db_info i1, i2;
	loom_diag d = {0};
	loom__db_geom g;
	loom__db_reader *r = NULL;
	uint8_t *brick = NULL, *plane = NULL, *b = NULL, *c = NULL;
	size_t n = 0;
	uint32_t id;
	char want[80];

	CHECK_EQ_INT(loom_db_open(tpath("gen.ldb"), &d2, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(tpath("gen1.ldb"), &d1, &d), LOOM_OK);
	if (!d1 || !d2)
		goto out;
	loom_db_get_info(d1, &i1);
	loom_db_get_info(d2, &i2);
	CHECK_EQ_INT(i1.version, 1);
	CHECK_EQ_INT(i1.voxel_layout, 1);
	CHECK_EQ_INT(i2.version, 3);
	CHECK_EQ_INT(i2.voxel_layout, 3);
	CHECK_EQ_INT(i1.n_empty_bricks, i2.n_empty_bricks);
	{
		loom_db *dv2 = NULL;
		loom_db_info iv2;
		CHECK_EQ_INT(loom_db_open(tpath("gen2.ldb"), &dv2, &d), LOOM_OK);
		if (dv2) {
			loom_db_get_info(dv2, &iv2);
			CHECK_EQ_INT(iv2.version, 2);
			CHECK_EQ_INT(iv2.voxel_layout, 2);
			CHECK_EQ_INT(loom__db_dsegs(dv2), 1);
			loom_db_close(dv2);
		}
		CHECK_EQ_INT(loom__db_dsegs(d2), 8);
		CHECK_EQ_INT(loom__db_dsegs(d1), 0);
		CHECK_EQ_INT(loom_db_open(tpath("gen4.ldb"), &dv2, &d), LOOM_OK);
		if (dv2) {
			loom_db_get_info(dv2, &iv2);
			CHECK_EQ_INT(iv2.version, 4);
			CHECK_EQ_INT(iv2.voxel_layout, 4);
			CHECK_EQ_INT(iv2.n_empty_bricks, i1.n_empty_bricks);
			CHECK_EQ_INT(loom__db_dsegs(dv2), 1);
			loom_db_close(dv2);
		}
	}
	for (uint32_t k = 0; k < i1.n_exemplars; k++) {
		loom_db_exemplar_info e;
		uint32_t org[3] = {0, 0, 0};
		size_t nv;
		uint8_t *a8, *b8, *al, *bl;
		uint16_t *ao, *bo;
		loom_db_exemplar(d1, k, &e);
		nv = (size_t)e.size[0] * e.size[1] * e.size[2];
		a8 = malloc(nv), b8 = malloc(nv), al = malloc(nv), bl = malloc(nv);
		ao = malloc(2 * nv), bo = malloc(2 * nv);
		CHECK_EQ_INT(loom_db_read_box(d1, k, org, e.size, a8, ao, al, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_read_box(d2, k, org, e.size, b8, bo, bl, &d), LOOM_OK);
		CHECK(memcmp(a8, b8, nv) == 0 && memcmp(al, bl, nv) == 0 &&
		      memcmp(ao, bo, 2 * nv) == 0);
		free(a8), free(b8), free(al), free(bl), free(ao), free(bo);
	}
	CHECK_EQ_INT(loom_db_verify(d2, NULL, NULL, &d), LOOM_OK);
	loom__db_geometry(d2, &g);
	r = loom__db_reader_new(d2);
	brick = malloc(g.brick_bytes);
	plane = malloc(g.brick_voxels);
	{
		long bad = 0;
		for (id = 0; id < g.n_bricks; id++) {
			CHECK_EQ_INT(loom__db_reader_read(r, id, brick, NULL, &d), LOOM_OK);
			for (unsigned u = 0; u < 4; u++) {
				memset(plane, 0xa5, g.brick_voxels);
				CHECK_EQ_INT(loom__db_reader_read_unit(r, id, u, plane, NULL, &d),
				             LOOM_OK);
				bad += memcmp(plane, brick + u * g.brick_voxels, g.brick_voxels) != 0;
			}
		}
		CHECK_EQ_INT(bad, 0);
	}
	/* a version-1 database has no units */
	{
		loom__db_reader *r1 = loom__db_reader_new(d1);
		CHECK_EQ_INT(loom__db_reader_read_unit(r1, 0, 0, plane, NULL, &d),
		             LOOM_EUNSUPPORTED);
		loom__db_reader_free(r1);
	}
	/* flip a byte inside the density unit of the first stored brick */
	b = slurp(tpath("gen.ldb"), &n);
	c = malloc(n);
	id = first_deflate(b, n);
	{
		size_t e = index_entry(b, n, id);
		uint64_t off = loom__le64(b + e);
		uint32_t u0 = loom__le32(b + e + 24), u3 = loom__le32(b + e + 48);
		loom_db *bd = NULL;
		loom__db_reader *br;
		CHECK(u0 > 0 && u3 > 0);
		memcpy(c, b, n);
		c[off + u0 / 2] ^= 0x10;
		spit(tpath("unit.ldb"), c, n);
		CHECK_EQ_INT(loom_db_open(tpath("unit.ldb"), &bd, &d), LOOM_OK);
		if (bd) {
			br = loom__db_reader_new(bd);
			snprintf(want, sizeof want, "unit.ldb: brick %u (exemplar", id);
			memset(&d, 0, sizeof d);
			CHECK_EQ_INT(loom__db_reader_read_unit(br, id, 0, plane, NULL, &d),
			             LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, want);
			CHECK_STR_CONTAINS(d.message, "unit 0 (density): CRC32 mismatch");
			CHECK_EQ_INT(loom__db_reader_read_unit(br, id, 3, plane, NULL, &d),
			             LOOM_OK);
			memset(&d, 0, sizeof d);
			CHECK_EQ_INT(loom__db_reader_read(br, id, brick, NULL, &d), LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, "unit 0 (density)");
			memset(&d, 0, sizeof d);
			CHECK_EQ_INT(loom_db_verify(bd, NULL, NULL, &d), LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, want);
			loom__db_reader_free(br);
			loom_db_close(bd);
		}
		/* the index: units that do not add up to stored_bytes */
		memcpy(c, b, n);
		loom__put32(c + e + 24, u0 + 1);
		reseal(c, n);
		spit(tpath("unit.ldb"), c, n);
		CHECK_EQ_INT(open_code(tpath("unit.ldb"), &d), LOOM_EFORMAT);
		CHECK_STR_CONTAINS(d.message, "units of");
		/* a unit larger than a plane */
		memcpy(c, b, n);
		loom__put32(c + e + 48, (uint32_t)g.brick_voxels + 1);
		reseal(c, n);
		spit(tpath("unit.ldb"), c, n);
		CHECK_EQ_INT(open_code(tpath("unit.ldb"), &d), LOOM_ERANGE);
		CHECK_STR_CONTAINS(d.message, "unit 3 (label)");
	}
out:
	free(b);
	free(c);
	free(brick);
	free(plane);
	loom__db_reader_free(r);
	loom_db_close(d1);
	loom_db_close(d2);
}

/* test_segments' damaged images: c (n bytes) resealed, written and opened;
   a reader on it (NULL when it does not open, which is checked). */
static loom__db_reader *damaged_reader(uint8_t *c, size_t n, loom_db **bd, loom_diag *d)
{
	reseal(c, n);
	spit(tpath("segbad.ldb"), c, n);
	CHECK_EQ_INT(loom_db_open(tpath("segbad.ldb"), bd, d), LOOM_OK);
	memset(d, 0, sizeof *d);
	return *bd ? loom__db_reader_new(*bd) : NULL;
}

static void damaged_close(loom__db_reader *br, loom_db **bd)
{
	loom__db_reader_free(br);
	loom_db_close(*bd);
	*bd = NULL;
}

/* Version 3's density segments (brick 16 x 12 x 32: R = 2 rows, six
   segments used, two past the brick's rows): each segment alone equals
   its rows of the whole plane and writes nothing else; the segment
   header is checked; a damaged segment is named and the others still
   read. */
static void test_segments(void)
{
	loom_exgen_params p = gen_params();
	loom_db *db = NULL, *d1 = NULL, *d2 = NULL, *bd = NULL;
	loom__db_reader *r = NULL, *br = NULL;
	loom__db_geom g;
	loom_diag d = {0};
	uint8_t *plane = NULL, *seg = NULL, *b = NULL, *c = NULL;
	size_t n = 0, kinds[3] = {0, 0, 0}; /* segments zero, raw, deflated */
	long bad = 0, outside = 0;
	uint32_t id, did = UINT32_MAX, dq = 0;

	p.brick[0] = 16;
	p.brick[1] = 12;
	p.brick[2] = 32;
	p.db_version = 3;
	CHECK_EQ_INT(loom_exgen_write_db(tpath("seg.ldb"), &p, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(tpath("seg.ldb"), &db, &d), LOOM_OK);
	if (!db)
		return;
	loom__db_geometry(db, &g);
	CHECK_EQ_INT(loom__db_seg_rows(p.brick, 8), 2);
	r = loom__db_reader_new(db);
	plane = malloc(g.brick_voxels);
	seg = malloc(g.brick_voxels);
	b = slurp(tpath("seg.ldb"), &n);
	for (id = 0; id < g.n_bricks; id++) {
		size_t e = index_entry(b, n, id), at = 32;
		uint32_t u0 = loom__le32(b + e + 24);
		const uint8_t *unit = b + loom__le64(b + e);
		CHECK_EQ_INT(loom__db_reader_read_unit(r, id, 0, plane, NULL, &d), LOOM_OK);
		for (unsigned q = 0; q < 8; q++) {
			size_t lo, len;
			loom__db_seg_range(p.brick, 8, q, &lo, &len);
			CHECK(len == (q < 6 ? 2u * 16 * 32 : 0u) && lo == (q < 6 ? q : 6u) * 1024);
			if (u0 > 0 && u0 < g.brick_voxels) { /* segmented: count kinds */
				uint32_t cq = loom__le32(unit + 4 * q);
				if (len)
					kinds[cq == 0 ? 0 : cq == len ? 1 : 2]++;
				if (cq && cq < len && did == UINT32_MAX) {
					did = id; /* the first deflated segment: damaged below */
					dq = q;
				}
				at += cq;
			}
			memset(seg, 0xa5, g.brick_voxels);
			CHECK_EQ_INT(loom__db_reader_read_seg(r, id, q, seg, 0, NULL, &d), LOOM_OK);
			bad += memcmp(seg + lo, plane + lo, len) != 0;
			for (size_t i = 0; i < g.brick_voxels; i++)
				outside += (i < lo || i >= lo + len) && seg[i] != 0xa5;
		}
		if (u0 > 0 && u0 < g.brick_voxels)
			CHECK_EQ_INT(at, u0);
	}
	CHECK_EQ_INT(bad, 0);
	CHECK_EQ_INT(outside, 0);
	printf("  segments: %zu zero, %zu raw, %zu deflated\n", kinds[0], kinds[1],
	       kinds[2]);
	CHECK(kinds[0] > 0 && kinds[2] > 0);
	CHECK_EQ_INT(loom__db_reader_read_seg(r, 0, 8, seg, 0, NULL, &d), LOOM_ERANGE);
	/* the next segment of the brick whose unit the reader holds reads
	   nothing more; another read in between drops it */
	if (did != UINT32_MAX) {
		size_t n1 = 0, n2 = 1, n3 = 0;
		CHECK_EQ_INT(loom__db_reader_read_seg(r, did, 0, seg, 0, &n1, &d), LOOM_OK);
		CHECK_EQ_INT(loom__db_reader_read_seg(r, did, 1, seg, 0, &n2, &d), LOOM_OK);
		CHECK_EQ_INT(loom__db_reader_read_unit(r, did, 3, plane, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(loom__db_reader_read_seg(r, did, 2, seg, 0, &n3, &d), LOOM_OK);
		CHECK(n1 > 0 && n2 == 0 && n3 == n1);
	}
	/* version 1 has no segments; version 2 has one, the whole plane */
	CHECK_EQ_INT(loom_db_open(tpath("gen1.ldb"), &d1, &d), LOOM_OK);
	if (d1) {
		loom__db_reader *r1 = loom__db_reader_new(d1);
		CHECK_EQ_INT(loom__db_reader_read_seg(r1, 0, 0, seg, 0, NULL, &d),
		             LOOM_EUNSUPPORTED);
		loom__db_reader_free(r1);
	}
	CHECK_EQ_INT(loom_db_open(tpath("gen2.ldb"), &d2, &d), LOOM_OK);
	if (d2) {
		loom__db_reader *r2 = loom__db_reader_new(d2);
		loom__db_geom g2;
		long bad2 = 0;
		loom__db_geometry(d2, &g2);
		for (id = 0; id < g2.n_bricks; id++) {
			CHECK_EQ_INT(loom__db_reader_read_unit(r2, id, 0, plane, NULL, &d), LOOM_OK);
			CHECK_EQ_INT(loom__db_reader_read_seg(r2, id, 0, seg, 0, NULL, &d), LOOM_OK);
			bad2 += memcmp(seg, plane, g2.brick_voxels) != 0;
		}
		CHECK_EQ_INT(bad2, 0);
		CHECK_EQ_INT(loom__db_reader_read_seg(r2, 0, 1, seg, 0, NULL, &d), LOOM_ERANGE);
		loom__db_reader_free(r2);
	}
	CHECK(did != UINT32_MAX);
	if (did == UINT32_MAX)
		goto out;
	c = malloc(n);
	{
		size_t e = index_entry(b, n, did), at = 32;
		uint64_t off = loom__le64(b + e);
		uint32_t u0 = loom__le32(b + e + 24);
		char want[96];
		for (unsigned q = 0; q < dq; q++)
			at += loom__le32(b + off + 4 * q);
		/* segment dq's first block given the reserved type 3: invalid, and
		   the unit's CRC made to match */
		memcpy(c, b, n);
		c[off + at] |= 0x06;
		loom__put32(c + e + 28, libdeflate_crc32(0, c + off, u0));
		if ((br = damaged_reader(c, n, &bd, &d)) != NULL) {
			CHECK_EQ_INT(loom__db_reader_read_seg(br, did, dq, seg, 0, NULL, &d),
			             LOOM_ECORRUPT);
			snprintf(want, sizeof want, "segbad.ldb: brick %u (exemplar", did);
			CHECK_STR_CONTAINS(d.message, want);
			snprintf(want, sizeof want, "unit 0 (density), segment %u at offset", dq);
			CHECK_STR_CONTAINS(d.message, want);
			CHECK_STR_CONTAINS(d.message, "invalid deflate data");
			/* the other segments still read; the whole plane does not */
			CHECK_EQ_INT(loom__db_reader_read_seg(br, did, dq ? 0 : 1, seg, 0, NULL, &d),
			             LOOM_OK);
			CHECK_EQ_INT(loom__db_reader_read_unit(br, did, 0, plane, NULL, &d),
			             LOOM_ECORRUPT);
			memset(&d, 0, sizeof d);
			CHECK_EQ_INT(loom_db_verify(bd, NULL, NULL, &d), LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, "segment");
			damaged_close(br, &bd);
		}
		/* a unit CRC that does not match: a segment read checks it, one
		   told the unit was checked already does not (and still reads
		   the right bytes) */
		memcpy(c, b, n);
		loom__put32(c + e + 28, loom__le32(c + e + 28) ^ 1u);
		if ((br = damaged_reader(c, n, &bd, &d)) != NULL) {
			size_t lo, len;
			CHECK_EQ_INT(loom__db_reader_read_seg(br, did, dq, seg, 0, NULL, &d),
			             LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, "unit 0 (density): CRC32 mismatch");
			CHECK_EQ_INT(loom__db_reader_read_unit(r, did, 0, plane, NULL, &d), LOOM_OK);
			CHECK_EQ_INT(loom__db_reader_read_seg(br, did, dq, seg, 1, NULL, &d), LOOM_OK);
			loom__db_seg_range(p.brick, 8, dq, &lo, &len);
			CHECK(memcmp(seg + lo, plane + lo, len) == 0);
			damaged_close(br, &bd);
		}
		/* a header whose sizes do not add up to the unit */
		memcpy(c, b, n);
		loom__put32(c + off + 4 * dq, loom__le32(c + off + 4 * dq) - 1);
		loom__put32(c + e + 28, libdeflate_crc32(0, c + off, u0));
		if ((br = damaged_reader(c, n, &bd, &d)) != NULL) {
			CHECK_EQ_INT(loom__db_reader_read_seg(br, did, 7, seg, 0, NULL, &d),
			             LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, "unit 0 (density) at offset");
			CHECK_STR_CONTAINS(d.message, "segments of");
			damaged_close(br, &bd);
		}
		/* a segment larger than its rows */
		memcpy(c, b, n);
		loom__put32(c + off + 4 * dq, 2u * 16 * 32 + 1);
		loom__put32(c + e + 28, libdeflate_crc32(0, c + off, u0));
		if ((br = damaged_reader(c, n, &bd, &d)) != NULL) {
			CHECK_EQ_INT(loom__db_reader_read_unit(br, did, 0, plane, NULL, &d),
			             LOOM_ECORRUPT);
			snprintf(want, sizeof want, "segment %u of 1025 bytes, expected 0..1024", dq);
			CHECK_STR_CONTAINS(d.message, want);
			damaged_close(br, &bd);
		}
	}
out:
	free(b);
	free(c);
	free(plane);
	free(seg);
	loom__db_reader_free(r);
	loom_db_close(db);
	loom_db_close(d1);
	loom_db_close(d2);
	loom_db_close(bd);
}

/* One brick of 16 x 16 x 8 (segments of 2 rows, 256 bytes) whose density
   rows 0-1 are noise (a raw segment), rows 2-3 zero (a zero segment), the
   rest a smooth ramp (deflated): the writer's choice per segment, and
   each reads back alone. */
static void test_segment_kinds(void)
{
	loom__dbw_params wp;
	loom__dbw_exemplar e;
	loom_db_yarn yarns[256];
	uint8_t weave[4] = {1, 0, 0, 1}, raw[4 * 2048], plane[2048];
	uint64_t rng = 99;
	loom__dbw *w = NULL;
	loom_db *db = NULL;
	loom__db_reader *r;
	loom_diag d = {0};
	uint8_t *b;
	size_t n, e0;
	const uint32_t brick[3] = {16, 16, 8};

	memset(&wp, 0, sizeof wp);
	memset(&e, 0, sizeof e);
	memset(yarns, 0, sizeof yarns);
	wp.n_exemplars = 1;
	wp.block[0] = wp.block[1] = wp.block[2] = 8;
	memcpy(wp.brick, brick, sizeof brick);
	wp.voxel_size_um = 10;
	wp.top_threshold = 64;
	wp.level = 6;
	wp.layout = LOOM__DB_LAYOUT_SEGS;
	yarns[1].kind = LOOM_YARN_WARP;
	plain_exemplar(&e, "segkinds", weave, yarns, 1);
	memset(raw, 0, sizeof raw);
	for (size_t i = 0; i < 2048; i++) {
		size_t y = i / (16 * 8);
		if (y < 2) {
			rng = rng * 6364136223846793005ull + 1442695040888963407ull;
			raw[i] = (uint8_t)(rng >> 56) | 1;
		} else if (y >= 4) {
			raw[i] = (uint8_t)(16 * y + i % 8);
		}
		raw[3 * 2048 + i] = raw[i] ? 1 : 0;
	}
	CHECK_EQ_INT(loom__dbw_create(tpath("segk.ldb"), &wp, &w, &d), LOOM_OK);
	if (!w)
		return;
	CHECK_EQ_INT(loom__dbw_begin_exemplar(w, &e, &d), LOOM_OK);
	CHECK_EQ_INT(loom__dbw_add_brick(w, raw, &d), LOOM_OK);
	CHECK_EQ_INT(loom__dbw_finish(w, NULL, &d), LOOM_OK);
	b = slurp(tpath("segk.ldb"), &n);
	e0 = index_entry(b, n, 0);
	{
		const uint8_t *u = b + loom__le64(b + e0);
		uint32_t u0 = loom__le32(b + e0 + 24);
		CHECK(u0 > 32 + 256 && u0 < 2048);
		CHECK_EQ_INT(loom__le32(u + 0), 256);  /* noise: raw */
		CHECK_EQ_INT(loom__le32(u + 4), 0);    /* zero */
		for (unsigned q = 2; q < 8; q++) /* the ramp: deflated */
			CHECK(loom__le32(u + 4 * q) > 0 && loom__le32(u + 4 * q) < 256);
	}
	free(b);
	CHECK_EQ_INT(loom_db_open(tpath("segk.ldb"), &db, &d), LOOM_OK);
	if (!db)
		return;
	r = loom__db_reader_new(db);
	for (unsigned q = 0; q < 8; q++) {
		memset(plane, 0xa5, sizeof plane);
		CHECK_EQ_INT(loom__db_reader_read_seg(r, 0, q, plane, 0, NULL, &d), LOOM_OK);
		for (size_t i = 0; i < 2048; i++)
			if (plane[i] != (i / 256 == q ? raw[i] : 0xa5)) {
				CHECK(plane[i] == (i / 256 == q ? raw[i] : 0xa5));
				break;
			}
	}
	CHECK_EQ_INT(loom__db_reader_read_unit(r, 0, 0, plane, NULL, &d), LOOM_OK);
	CHECK(memcmp(plane, raw, 2048) == 0);
	loom__db_reader_free(r);
	loom_db_close(db);
}

/* The zero-run code alone: a reference decoder written from
   docs/formats.md, every encoding decoded by both; the encoder's choices
   on a hand-worked plane; every malformed stream refused with the token
   at fault; random streams never write past the plane. */
static int zr_reference(const uint8_t *in, size_t m, uint8_t *out, size_t n)
{
	size_t i = 0, o = 0;
	while (i < m) {
		unsigned t = in[i++];
		size_t len = t < 128 ? t + 1u : t - 127u;
		if (o + len > n || (t >= 128 && i + len > m))
			return 1;
		for (size_t k = 0; k < len; k++)
			out[o + k] = t < 128 ? 0 : in[i + k];
		if (t >= 128)
			i += len;
		o += len;
	}
	return o != n;
}

static void test_zero_runs(void)
{
	static const uint8_t plane[] = {0, 0, 0, 5, 6, 0, 7, 0, 0, 9, 0};
	static const uint8_t want[] = {2, 131, 5, 6, 0, 7, 1, 128, 9, 0};
	uint8_t enc[1200], a[1200], b[1200];
	uint64_t rng = 7;
	size_t m, at;
	long bad = 0, refused = 0;

	m = loom__zrun_encode(plane, sizeof plane, enc, sizeof enc);
	CHECK_EQ_INT(m, sizeof want);
	CHECK(memcmp(enc, want, sizeof want) == 0);
	CHECK_EQ_INT(loom__zrun_encode(plane, sizeof plane, enc, sizeof want - 1), 0);
	/* runs at and past 128 of either kind, and planes of every length up
	   to 1024 from noise with zeros in runs of every length */
	for (int it = 0; it < 3000; it++) {
		size_t n = it < 4 ? 1024 : 1 + (size_t)(it % 1024);
		for (size_t i = 0; i < n;) {
			size_t run;
			rng = rng * 6364136223846793005ull + 1442695040888963407ull;
			run = 1 + (rng >> 33) % (it % 3 ? 12 : 300);
			for (size_t k = 0; k < run && i < n; k++, i++)
				a[i] = it == 0 ? 0 : it == 1 ? (uint8_t)(1 + i % 255) :
				       (rng >> 40) & 1 ? 0 : (uint8_t)(1 + (rng >> 50) % 200);
		}
		m = loom__zrun_encode(a, n, enc, sizeof enc);
		memset(b, 0xa5, sizeof b);
		bad += m == 0 || loom__zrun_decode(enc, m, b, n, NULL) != 0 ||
		       memcmp(a, b, n) != 0 || b[n] != 0xa5;
		memset(b, 0x5a, sizeof b);
		bad += zr_reference(enc, m, b, n) != 0 || memcmp(a, b, n) != 0;
	}
	CHECK_EQ_INT(bad, 0);
	/* 1024 zeros: eight tokens of 128; 300 literals: 128 + 128 + 44 */
	memset(a, 0, 1024);
	CHECK_EQ_INT(loom__zrun_encode(a, 1024, enc, sizeof enc), 8);
	CHECK_EQ_INT(enc[0], 127);
	memset(a, 3, 300);
	CHECK_EQ_INT(loom__zrun_encode(a, 300, enc, sizeof enc), 303);
	CHECK(enc[0] == 255 && enc[129] == 255 && enc[258] == 127 + 44);
	/* malformed: a zero run past the plane, a literal past the stream, a
	   stream short of the plane */
	CHECK_EQ_INT(loom__zrun_decode((const uint8_t[]){0, 4}, 2, b, 5, &at), 1);
	CHECK_EQ_INT(at, 1);
	CHECK_EQ_INT(loom__zrun_decode((const uint8_t[]){130, 1, 2}, 3, b, 3, &at), 1);
	CHECK_EQ_INT(at, 0);
	CHECK_EQ_INT(loom__zrun_decode((const uint8_t[]){1, 129, 1, 2}, 4, b, 5, &at), 1);
	CHECK_EQ_INT(at, 4);
	CHECK_EQ_INT(loom__zrun_decode((const uint8_t[]){1, 129, 1, 2}, 4, b, 4, NULL), 0);
	/* random streams, and valid ones with a byte replaced: accepted
	   exactly when the reference accepts them, the same bytes, nothing
	   written past the plane */
	for (int it = 0; it < 20000; it++) {
		size_t n = 1 + it % 700, len = 1 + (size_t)(it * 7) % 40;
		int ra, rb;
		if (it % 2) {
			for (size_t i = 0; i < n; i++) {
				rng = rng * 6364136223846793005ull + 1442695040888963407ull;
				a[i] = (rng >> 60) < 9 ? 0 : (uint8_t)(rng >> 52);
			}
			len = loom__zrun_encode(a, n, enc, sizeof enc);
			rng = rng * 6364136223846793005ull + 1442695040888963407ull;
			enc[(rng >> 33) % len] = (uint8_t)(rng >> 56);
		} else {
			for (size_t i = 0; i < len; i++) {
				rng = rng * 6364136223846793005ull + 1442695040888963407ull;
				enc[i] = (uint8_t)(rng >> 56);
			}
		}
		memset(a, 0xa5, sizeof a);
		memset(b, 0xa5, sizeof b);
		ra = loom__zrun_decode(enc, len, a, n, NULL);
		rb = zr_reference(enc, len, b, n);
		refused += ra;
		bad += ra != rb || a[n] != 0xa5 || (!ra && memcmp(a, b, n) != 0);
	}
	CHECK_EQ_INT(bad, 0);
	printf("  zero runs: %ld of 20000 streams refused\n", refused);
	CHECK(refused > 10000 && refused < 19000);
}

/* Version 4 in a file: the density unit zero-run coded (smaller than
   the plane, never what version 2 stores), the other units as version
   2's; a damaged run is named and the other units still read. */
static void test_zero_run_units(void)
{
	loom_db *db = NULL, *bd = NULL;
	loom__db_reader *r = NULL, *br;
	loom__db_geom g;
	loom_diag d = {0};
	uint8_t *b = NULL, *c = NULL, *plane = NULL, *dec = NULL;
	size_t n = 0;
	uint32_t id, zr = 0, did = UINT32_MAX;
	long bad = 0;

	CHECK_EQ_INT(loom_db_open(tpath("gen4.ldb"), &db, &d), LOOM_OK);
	if (!db)
		return;
	loom__db_geometry(db, &g);
	r = loom__db_reader_new(db);
	b = slurp(tpath("gen4.ldb"), &n);
	plane = malloc(g.brick_voxels);
	dec = malloc(g.brick_voxels);
	for (id = 0; id < g.n_bricks; id++) {
		size_t e = index_entry(b, n, id);
		uint32_t u0 = loom__le32(b + e + 24);
		if (u0 == 0 || u0 == g.brick_voxels)
			continue;
		CHECK_EQ_INT(loom__db_reader_read_unit(r, id, 0, plane, NULL, &d), LOOM_OK);
		bad += loom__zrun_decode(b + loom__le64(b + e), u0, dec, g.brick_voxels,
		                         NULL) != 0 ||
		       memcmp(dec, plane, g.brick_voxels) != 0;
		zr++;
		if (did == UINT32_MAX && u0 > 8 && b[loom__le64(b + e)] < 127)
			did = id; /* starts with a zero run of at most 127: damaged below */
	}
	CHECK_EQ_INT(bad, 0);
	CHECK(zr > 0 && did != UINT32_MAX);
	printf("  version 4: %u density units zero-run coded\n", zr);
	if (did == UINT32_MAX)
		goto out;
	c = malloc(n);
	{
		size_t e = index_entry(b, n, did);
		uint64_t off = loom__le64(b + e);
		uint32_t u0 = loom__le32(b + e + 24);
		char want[96];
		/* the first zero run one longer: the stream runs past the plane */
		memcpy(c, b, n);
		c[off]++;
		loom__put32(c + e + 28, libdeflate_crc32(0, c + off, u0));
		if ((br = damaged_reader(c, n, &bd, &d)) != NULL) {
			CHECK_EQ_INT(loom__db_reader_read_unit(br, did, 0, plane, NULL, &d),
			             LOOM_ECORRUPT);
			snprintf(want, sizeof want, "segbad.ldb: brick %u (exemplar", did);
			CHECK_STR_CONTAINS(d.message, want);
			CHECK_STR_CONTAINS(d.message, "unit 0 (density) at offset");
			CHECK_STR_CONTAINS(d.message, "zero-run code malformed at byte");
			CHECK_EQ_INT(loom__db_reader_read_unit(br, did, 3, plane, NULL, &d), LOOM_OK);
			memset(&d, 0, sizeof d);
			CHECK_EQ_INT(loom_db_verify(bd, NULL, NULL, &d), LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(d.message, "zero-run");
			damaged_close(br, &bd);
		}
	}
out:
	free(b);
	free(c);
	free(plane);
	free(dec);
	loom__db_reader_free(r);
	loom_db_close(db);
}

static void test_index_out_of_range(void)
{
	size_t n;
	uint8_t *b = slurp(tpath("gen1.ldb"), &n), *c = malloc(n);
	uint32_t id = first_deflate(b, n);
	size_t e = index_entry(b, n, id);
	loom_diag d;
	char want[64];

	snprintf(want, sizeof want, "gen_oor.ldb: brick %u (exemplar 0", id);
	/* offset past the brick data */
	memcpy(c, b, n);
	loom__put64(c + e, n - 100);
	reseal(c, n);
	spit(tpath("gen_oor.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("gen_oor.ldb"), &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, want);
	CHECK_STR_CONTAINS(d.message, "index out of range");
	/* offset inside the header */
	memcpy(c, b, n);
	loom__put64(c + e, 16);
	reseal(c, n);
	spit(tpath("gen_oor.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("gen_oor.ldb"), &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, want);
	/* huge stored size */
	memcpy(c, b, n);
	loom__put32(c + e + 8, 0xfffffff0u);
	reseal(c, n);
	spit(tpath("gen_oor.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("gen_oor.ldb"), &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, want);
	/* unknown storage kind */
	memcpy(c, b, n);
	c[e + 20] = 9;
	reseal(c, n);
	spit(tpath("gen_oor.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("gen_oor.ldb"), &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, want);
	/* exemplar table: rows out of range */
	memcpy(c, b, n);
	{
		uint64_t mo = loom__le64(c + n - 64 + 8);
		loom__put32(c + mo + 64 + 64, 5000);
	}
	reseal(c, n);
	spit(tpath("gen_oor.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("gen_oor.ldb"), &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "exemplar 0 at metadata offset 64, field 'rows/cols'");
	/* metadata range in the trailer */
	memcpy(c, b, n);
	loom__put64(c + n - 64 + 8, 3);
	loom__put32(c + n - 4, libdeflate_crc32(0, c + n - 64, 60));
	spit(tpath("gen_oor.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("gen_oor.ldb"), &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, "metadata");
	free(b);
	free(c);
}

static void test_size_mismatch(void)
{
	size_t n, csz;
	uint8_t *b = slurp(tpath("gen1.ldb"), &n), *c = malloc(n), *brick, *scratch;
	uint32_t id = first_deflate(b, n);
	size_t e = index_entry(b, n, id);
	uint64_t off = loom__le64(b + e);
	uint32_t sz = loom__le32(b + e + 8);
	loom_diag d;
	loom_db *db = NULL;
	loom__db_geom geo;
	struct libdeflate_compressor *comp = libdeflate_alloc_compressor(6);
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	uint8_t *zeros, *tmp;
	char want[64];

	snprintf(want, sizeof want, "size.ldb: brick %u (exemplar 0", id);
	/* (a) the index's uncompressed size disagrees with the brick shape */
	memcpy(c, b, n);
	loom__put32(c + e + 12, loom__le32(b + e + 12) - 4);
	reseal(c, n);
	spit(tpath("size.ldb"), c, n);
	CHECK_EQ_INT(open_code(tpath("size.ldb"), &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, want);
	CHECK_STR_CONTAINS(d.message, "decompressed size mismatch");
	/* (b) a valid deflate stream that inflates to too few / too many bytes,
	   with a matching CRC: caught at read time */
	CHECK_EQ_INT(loom_db_open(tpath("gen1.ldb"), &db, &d), LOOM_OK);
	if (!db)
		goto out;
	loom__db_geometry(db, &geo);
	loom_db_close(db);
	zeros = calloc(1, geo.brick_bytes + 100);
	tmp = malloc(geo.brick_bytes + 200);
	for (int variant = 0; variant < 2; variant++) {
		size_t len = variant ? geo.brick_bytes + 100 : geo.brick_bytes - 100;
		csz = libdeflate_deflate_compress(comp, zeros, len, tmp, geo.brick_bytes + 200);
		CHECK(csz > 0 && csz <= sz);
		memcpy(c, b, n);
		memcpy(c + off, tmp, csz);
		loom__put32(c + e + 8, (uint32_t)csz);
		loom__put32(c + e + 16, libdeflate_crc32(0, tmp, csz));
		{ /* exemplar 0's stored_bytes follows its brick's (an open check) */
			uint64_t mo = loom__le64(c + n - 64 + 8);
			loom__put64(c + mo + 64 + 168,
			            loom__le64(c + mo + 64 + 168) - sz + csz);
		}
		reseal(c, n);
		spit(tpath("size.ldb"), c, n);
		db = NULL;
		CHECK_EQ_INT(loom_db_open(tpath("size.ldb"), &db, &d), LOOM_OK);
		if (!db)
			continue;
		brick = malloc(geo.brick_bytes);
		scratch = malloc(loom__db_scratch_bytes(db));
		memset(&d, 0, sizeof d);
		CHECK_EQ_INT(loom__db_read_brick(db, id, dec, scratch, brick, NULL, &d),
		             LOOM_ECORRUPT);
		CHECK_STR_CONTAINS(d.message, want);
		CHECK_STR_CONTAINS(d.message, variant ? "decompressed size mismatch: more"
		                                      : "decompressed size mismatch: fewer");
		free(brick);
		free(scratch);
		loom_db_close(db);
	}
	free(zeros);
	free(tmp);
out:
	libdeflate_free_compressor(comp);
	libdeflate_free_decompressor(dec);
	free(b);
	free(c);
}

/* Random damage anywhere (with and without resealing) never crashes. */
static void test_random_damage(void)
{
	size_t n;
	uint8_t *b = slurp(tpath("hand.ldb"), &n), *c = malloc(n);
	uint64_t rng = check_seed();
	int opened = 0;

	for (int it = 0; it < 400; it++) {
		loom_diag d = {0};
		loom_db *db = NULL;
		memcpy(c, b, n);
		for (int k = 0; k < 1 + it % 4; k++) {
			rng = rng * 6364136223846793005ull + 1442695040888963407ull;
			c[(rng >> 20) % n] ^= (uint8_t)(1u << ((rng >> 8) & 7));
		}
		if (it & 1)
			reseal(c, n);
		spit(tpath("dmg.ldb"), c, n);
		if (loom_db_open(tpath("dmg.ldb"), &db, &d) == LOOM_OK) {
			opened++;
			loom_db_verify(db, NULL, NULL, &d);
			loom_db_close(db);
		} else {
			CHECK(d.message[0] != 0);
		}
	}
	printf("  %d of 400 damaged images opened\n", opened);
	free(b);
	free(c);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_db");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(test_roundtrip_generated);
	RUN(test_threaded_reads);
	RUN(test_reader_object);
	RUN(test_handmade);
	RUN(test_orient_rule);
	RUN(test_append_layouts);
	RUN(test_append_raw_density);
	RUN(test_streamed_height_map);
	RUN(test_bad_magic_version);
	RUN(test_truncation);
	RUN(test_truncated_after_open);
	RUN(test_crc_mismatch);
	RUN(test_units);
	RUN(test_segments);
	RUN(test_segment_kinds);
	RUN(test_zero_runs);
	RUN(test_zero_run_units);
	RUN(test_index_out_of_range);
	RUN(test_size_mismatch);
	RUN(test_random_damage);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
