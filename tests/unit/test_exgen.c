/*
 * tests/unit/test_exgen.c - the procedural exemplar generator: determinism
 * by seed, independence of the thread count, the right yarn on top at every
 * crossing centre, per-block tables against a brute-force recomputation
 * from the voxels, symmetries, and a few realism properties (twist
 * direction, fibre orientation along the yarn, empty space above/below).
 */
#include "check.h"
#include "tmpdir.h"
#include "exemplar/db_internal.h"
#include "io/store/db_write.h"
#include "exemplar/exgen.h"

#include <math.h>
#include <unistd.h>

/* A whole exemplar volume from the generator, x fastest. */
typedef struct vol {
	uint32_t s[3];
	uint8_t *d, *l;
	uint16_t *o;
} vol;

static void vol_gen(const loom__exgen *g, vol *v)
{
	loom__exgen_desc gd;
	size_t n;
	uint8_t *d, *l;
	uint16_t *o;

	loom__exgen_describe(g, &gd);
	memcpy(v->s, gd.size, sizeof v->s);
	n = (size_t)v->s[0] * v->s[1] * v->s[2];
	d = malloc(n);
	l = malloc(n);
	o = malloc(2 * n);
	v->d = malloc(n);
	v->l = malloc(n);
	v->o = malloc(2 * n);
	loom__exgen_box(g, 0, 0, 0, v->s[0], v->s[1], v->s[2], d, o, l);
	for (uint32_t y = 0; y < v->s[1]; y++)
		for (uint32_t x = 0; x < v->s[0]; x++)
			for (uint32_t z = 0; z < v->s[2]; z++) {
				size_t gi = ((size_t)y * v->s[0] + x) * v->s[2] + z;
				size_t vi = ((size_t)z * v->s[1] + y) * v->s[0] + x;
				v->d[vi] = d[gi];
				v->l[vi] = l[gi];
				v->o[vi] = o[gi];
			}
	free(d);
	free(l);
	free(o);
}

static void vol_free(vol *v)
{
	free(v->d);
	free(v->l);
	free(v->o);
}

static size_t vi(const vol *v, uint32_t x, uint32_t y, uint32_t z)
{
	return ((size_t)z * v->s[1] + y) * v->s[0] + x;
}

/* Top-surface rule of docs/formats.md: z of the highest voxel with a
   non-flyaway yarn label and density >= 64, or -1. */
static int top_z(const vol *v, const loom_db_yarn *yarns, uint32_t x, uint32_t y)
{
	for (int z = (int)v->s[2] - 1; z >= 0; z--) {
		size_t i = vi(v, x, y, (uint32_t)z);
		uint8_t l = v->l[i];
		if (l && yarns[l].kind && !(yarns[l].flags & LOOM_DB_YARN_FLYAWAY) &&
		    v->d[i] >= LOOM__DB_TOP_THRESHOLD)
			return z;
	}
	return -1;
}

static loom_exgen_params params(const char *preset)
{
	loom_exgen_params p;
	loom_exgen_preset(preset, &p);
	return p;
}

static void test_determinism(void)
{
	loom_exgen_params p = params("small");
	loom__exgen *a = NULL, *b = NULL, *c = NULL;
	loom_diag d = {0};
	const uint32_t n = 24 * 20 * 48;
	uint8_t *da = malloc(n), *db = malloc(n), *la = malloc(n), *lb = malloc(n);
	uint16_t *oa = malloc(2 * n), *ob = malloc(2 * n);

	CHECK_EQ_INT(loom__exgen_new(&p, 4, 0, &a, &d), LOOM_OK);
	CHECK_EQ_INT(loom__exgen_new(&p, 4, 0, &b, &d), LOOM_OK);
	p.seed = 2;
	CHECK_EQ_INT(loom__exgen_new(&p, 4, 0, &c, &d), LOOM_OK);
	if (!a || !b || !c)
		goto out;
	/* same seed: same bytes, also for a box evaluated in another order
	   (two halves vs one) */
	loom__exgen_box(a, 30, 10, 0, 24, 20, 48, da, oa, la);
	loom__exgen_box(b, 30, 10, 0, 24, 20, 48, db, ob, lb);
	CHECK(memcmp(da, db, n) == 0 && memcmp(la, lb, n) == 0 &&
	      memcmp(oa, ob, 2 * n) == 0);
	{
		/* the top half of the box by itself */
		uint32_t m = 24 * 20 * 24;
		uint8_t *dh = malloc(m), *lh = malloc(m);
		uint16_t *oh = malloc(2 * m);
		long bad = 0;
		loom__exgen_box(b, 30, 10, 24, 24, 20, 24, dh, oh, lh);
		for (uint32_t col = 0; col < 24 * 20; col++)
			for (uint32_t z = 0; z < 24; z++)
				if (dh[col * 24 + z] != da[col * 48 + 24 + z] ||
				    lh[col * 24 + z] != la[col * 48 + 24 + z] ||
				    oh[col * 24 + z] != oa[col * 48 + 24 + z])
					bad++;
		CHECK_EQ_INT(bad, 0);
		free(dh);
		free(lh);
		free(oh);
	}
	/* another seed: different voxels */
	loom__exgen_box(c, 30, 10, 0, 24, 20, 48, db, ob, lb);
	CHECK(memcmp(da, db, n) != 0);
out:
	loom__exgen_free(a);
	loom__exgen_free(b);
	loom__exgen_free(c);
	free(da);
	free(db);
	free(la);
	free(lb);
	free(oa);
	free(ob);
}

static void test_threads(void)
{
	loom_exgen_params p = params("small");
	loom_diag d = {0};
	uint64_t h[3] = {0, 0, 0};
	uint8_t *f[3];
	size_t n[3];
	const unsigned th[3] = {1, 2, 3};
	const char *names[3] = {"t1.ldb", "t2.ldb", "t3.ldb"};

	p.n_weaves = 3;
	p.weaves[0] = "twill:2/3";
	p.weaves[1] = "satin:1/4";
	p.weaves[2] = "twill:2/3"; /* a second variant of the same weave */
	p.brick[0] = p.brick[1] = 16; /* several tasks per exemplar */
	p.brick[2] = 16;
	for (int i = 0; i < 3; i++) {
		p.threads = th[i];
		CHECK_EQ_INT(loom_exgen_write_db(tpath(names[i]), &p, &h[i], &d), LOOM_OK);
		f[i] = slurp(tpath(names[i]), &n[i]);
	}
	CHECK(h[0] == h[1] && h[1] == h[2] && h[0] != 0);
	CHECK(f[0] && f[1] && f[2] && n[0] == n[1] && n[1] == n[2] &&
	      memcmp(f[0], f[1], n[0]) == 0 && memcmp(f[0], f[2], n[0]) == 0);
	for (int i = 0; i < 3; i++)
		free(f[i]);
	/* variant 2 of a weave differs from variant 1 and has its own name */
	{
		loom_db *db = NULL;
		loom_db_exemplar_info e0, e2;
		CHECK_EQ_INT(loom_db_open(tpath("t1.ldb"), &db, &d), LOOM_OK);
		if (db) {
			loom_db_exemplar(db, 0, &e0);
			loom_db_exemplar(db, 2, &e2);
			CHECK(strcmp(e0.name, "twill-2-3") == 0);
			CHECK(strcmp(e2.name, "twill-2-3-2") == 0);
			CHECK(e0.stored_bytes != e2.stored_bytes);
			loom_db_close(db);
		}
	}
}

/* At every crossing centre the top-most yarn is the warp exactly where
   S_u says 1 (all default weaves and a few others). */
static void test_crossing_centres(void)
{
	const char *extra[] = {"plain", "twill:2/2", "basket:2", "twill:2/1:s",
	                       "herringbone:2/2:period=4", "satin:3/4"};
	loom_exgen_params p = params("small");
	loom_diag d = {0};
	long checked = 0, bad = 0;

	for (int set = 0; set < 2; set++) {
		if (set == 1) {
			p.n_weaves = 6;
			for (int i = 0; i < 6; i++)
				p.weaves[i] = extra[i];
		}
		for (uint32_t k = 0; k < p.n_weaves; k++) {
			loom__exgen *g = NULL;
			loom__exgen_desc gd;
			vol v;
			if (loom__exgen_new(&p, k, 0, &g, &d) != LOOM_OK) {
				printf("  %s: %s\n", p.weaves[k], d.message);
				bad++;
				continue;
			}
			loom__exgen_describe(g, &gd);
			vol_gen(g, &v);
			for (uint32_t r = 0; r < gd.rows; r++)
				for (uint32_t c = 0; c < gd.cols; c++) {
					uint32_t x = c * p.block[0] + p.block[0] / 2;
					uint32_t y = r * p.block[1] + p.block[1] / 2;
					int z = top_z(&v, gd.yarns, x, y);
					int want = gd.weave[r * gd.cols + c] ? LOOM_YARN_WARP
					                                     : LOOM_YARN_WEFT;
					checked++;
					if (z < 0 || gd.yarns[v.l[vi(&v, x, y, (uint32_t)z)]].kind != want) {
						if (bad < 5)
							printf("  %s crossing (%u,%u): top kind %d, want %d\n",
							       gd.name, r, c,
							       z < 0 ? 0 : gd.yarns[v.l[vi(&v, x, y, (uint32_t)z)]].kind,
							       want);
						bad++;
					}
				}
			vol_free(&v);
			loom__exgen_free(g);
		}
	}
	printf("  %ld crossings checked\n", checked);
	CHECK(checked >= 8 * 25 + 30);
	CHECK_EQ_INT(bad, 0);
}

static float fill_ref(float *v, uint32_t n, float fallback)
{
	/* reference gap fill: for each gap the nearest known samples on both
	   sides (linear), one side (constant), none (fallback) */
	float *out = malloc(n * sizeof *out);
	for (uint32_t i = 0; i < n; i++) {
		int64_t lo = -1, hi = -1;
		if (v[i] == v[i]) {
			out[i] = v[i];
			continue;
		}
		for (int64_t j = i; j >= 0; j--)
			if (v[j] == v[j]) {
				lo = j;
				break;
			}
		for (uint32_t j = i; j < n; j++)
			if (v[j] == v[j]) {
				hi = j;
				break;
			}
		if (lo < 0 && hi < 0)
			out[i] = fallback;
		else if (lo < 0)
			out[i] = v[hi];
		else if (hi < 0)
			out[i] = v[lo];
		else
			out[i] = v[lo] + (v[hi] - v[lo]) * (float)((int64_t)i - lo) /
			                         (float)(hi - lo);
	}
	memcpy(v, out, n * sizeof *out);
	free(out);
	return 0;
}

/* Tables of a generated database against a brute-force recomputation
   from the voxels read back from it. */
static void test_tables_brute_force(void)
{
	loom_exgen_params p = params("small");
	loom_diag d = {0};
	loom_db *db = NULL;
	long bad = 0, gaps = 0;
	uint32_t b1 = p.block[0], b2 = p.block[1];

	p.n_weaves = 3;
	p.weaves[0] = "twill:1/4";
	p.weaves[1] = "satin:3/2";
	p.weaves[2] = "plain";
	CHECK_EQ_INT(loom_exgen_write_db(tpath("tab.ldb"), &p, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(tpath("tab.ldb"), &db, &d), LOOM_OK);
	if (!db)
		return;
	for (uint32_t k = 0; k < 3; k++) {
		loom_db_exemplar_info e;
		vol v;
		float *h, prof[4][64];
		uint32_t org[3] = {0, 0, 0};
		size_t n;

		loom_db_exemplar(db, k, &e);
		memcpy(v.s, e.size, sizeof v.s);
		n = (size_t)e.size[0] * e.size[1] * e.size[2];
		v.d = malloc(n);
		v.l = malloc(n);
		v.o = NULL;
		CHECK_EQ_INT(loom_db_read_box(db, k, org, e.size, v.d, NULL, v.l, &d), LOOM_OK);
		h = malloc(sizeof(float) * e.size[0] * e.size[1]);
		for (uint32_t y = 0; y < e.size[1]; y++)
			for (uint32_t x = 0; x < e.size[0]; x++) {
				int z = top_z(&v, e.yarns, x, y);
				h[(size_t)y * e.size[0] + x] = z < 0 ? NAN : (float)z + 1.0f;
			}
		for (uint32_t r = 0; r < e.rows; r++)
			for (uint32_t c = 0; c < e.cols; c++) {
				loom_db_block_info b;
				double sum = 0, sx = 0, sy = 0;
				long nn = 0, nx = 0, ny = 0, ng = 0;
				float mean;
				uint32_t x0 = c * b1, y0 = r * b2;
				int ck;
				const float *got[4];
				uint32_t len[4] = {b1, b1, b2, b2};

				CHECK_EQ_INT(loom_db_block(db, k, r, c, &b), LOOM_OK);
				for (uint32_t y = y0; y < y0 + b2; y++)
					for (uint32_t x = x0; x < x0 + b1; x++) {
						float hh = h[(size_t)y * e.size[0] + x];
						if (hh != hh) {
							ng++;
							continue;
						}
						sum += hh;
						nn++;
						if (x + 1 < x0 + b1 && h[(size_t)y * e.size[0] + x + 1] ==
						                              h[(size_t)y * e.size[0] + x + 1]) {
							sx += fabs(h[(size_t)y * e.size[0] + x + 1] - hh);
							nx++;
						}
						if (y + 1 < y0 + b2 && h[(size_t)(y + 1) * e.size[0] + x] ==
						                              h[(size_t)(y + 1) * e.size[0] + x]) {
							sy += fabs(h[(size_t)(y + 1) * e.size[0] + x] - hh);
							ny++;
						}
					}
				gaps += ng;
				mean = nn ? (float)(sum / nn) : 0.0f;
				for (uint32_t i = 0; i < b1; i++) {
					prof[0][i] = h[(size_t)y0 * e.size[0] + x0 + i];
					prof[1][i] = h[(size_t)(y0 + b2 - 1) * e.size[0] + x0 + i];
				}
				for (uint32_t i = 0; i < b2; i++) {
					prof[2][i] = h[(size_t)(y0 + i) * e.size[0] + x0];
					prof[3][i] = h[(size_t)(y0 + i) * e.size[0] + x0 + b1 - 1];
				}
				got[0] = b.north;
				got[1] = b.south;
				got[2] = b.west;
				got[3] = b.east;
				for (int s = 0; s < 4; s++) {
					fill_ref(prof[s], len[s], mean);
					for (uint32_t i = 0; i < len[s]; i++)
						if (fabsf(prof[s][i] - got[s][i]) > 1e-4f)
							bad++;
				}
				if (fabs(b.mean_dh_x - (nx ? sx / nx : 0)) > 1e-4 ||
				    fabs(b.mean_dh_y - (ny ? sy / ny : 0)) > 1e-4 ||
				    fabs(b.mean_height - mean) > 1e-3 || b.gap_columns != ng)
					bad++;
				{
					uint32_t cx = x0 + b1 / 2, cy = y0 + b2 / 2;
					int z = top_z(&v, e.yarns, cx, cy);
					ck = z < 0 ? 0 : e.yarns[v.l[vi(&v, cx, cy, (uint32_t)z)]].kind;
				}
				if (b.centre_kind != ck ||
				    ck != (e.weave[r * e.cols + c] ? LOOM_YARN_WARP : LOOM_YARN_WEFT))
					bad++;
				if (b.code != loom__weave_code(e.weave, e.rows, e.cols, r, c))
					bad++;
				/* the code's own bit and neighbours, by hand */
				if (((b.code >> 0) & 1) != e.weave[r * e.cols + c] ||
				    ((b.code >> 1) & 1) !=
				            e.weave[((r + e.rows - 1) % e.rows) * e.cols + c] ||
				    ((b.code >> 4) & 1) != e.weave[r * e.cols + (c + 1) % e.cols])
					bad++;
				/* the profiles are real surfaces: within the cloth */
				if (!(b.mean_height > 5 && b.mean_height < e.size[2] - 5))
					bad++;
			}
		free(h);
		free(v.d);
		free(v.l);
	}
	printf("  %ld gap columns in the three exemplars\n", gaps);
	CHECK(gaps > 0); /* the gaps between yarns exercise the gap fill */
	CHECK_EQ_INT(bad, 0);
	loom_db_close(db);
}

static void test_symmetries(void)
{
	/* by hand: a 5-end twill or satin in a 5x5 window has exactly the 5
	   shifts along its diagonal; plain in 4x4 has the 8 shifts with
	   dx + dy even; a 1x1 window only (0,0) */
	uint8_t tw[25], pl[16], one[1] = {1};
	uint16_t sym[2 * 25];
	uint32_t n;
	loom_weave_params wp;

	loom_weave_parse("twill:2/3", &wp, NULL);
	for (int r = 0; r < 5; r++)
		for (int c = 0; c < 5; c++)
			tw[r * 5 + c] = (uint8_t)loom_weave_cell(&wp, r, c);
	n = loom__weave_symmetries(tw, 5, 5, sym);
	CHECK_EQ_INT(n, 5);
	for (uint32_t i = 0; i < n; i++) {
		CHECK(sym[2 * i + 1] == i);                    /* one per row shift */
		CHECK((sym[2 * i] + 5 - sym[2 * i + 1]) % 5 == 0 ||
		      (sym[2 * i] + sym[2 * i + 1]) % 5 == 0); /* along a diagonal */
	}
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++)
			pl[r * 4 + c] = (uint8_t)((r + c) % 2 == 0);
	n = loom__weave_symmetries(pl, 4, 4, sym);
	CHECK_EQ_INT(n, 8);
	for (uint32_t i = 0; i < n; i++)
		CHECK((sym[2 * i] + sym[2 * i + 1]) % 2 == 0);
	CHECK_EQ_INT(loom__weave_symmetries(one, 1, 1, sym), 1);
	/* the database's symmetries satisfy the definition and are complete */
	{
		loom_db *db = NULL;
		loom_diag d = {0};
		CHECK_EQ_INT(loom_db_open(tpath("tab.ldb"), &db, &d), LOOM_OK);
		if (!db)
			return;
		for (uint32_t k = 0; k < 3; k++) {
			loom_db_exemplar_info e;
			uint32_t count = 0;
			loom_db_exemplar(db, k, &e);
			for (uint32_t dy = 0; dy < e.rows; dy++)
				for (uint32_t dx = 0; dx < e.cols; dx++) {
					int ok = 1, listed = 0;
					for (uint32_t r = 0; r < e.rows; r++)
						for (uint32_t c = 0; c < e.cols; c++)
							if (e.weave[((r + dy) % e.rows) * e.cols + (c + dx) % e.cols] !=
							    e.weave[r * e.cols + c])
								ok = 0;
					for (uint32_t i = 0; i < e.n_symmetries; i++)
						if (e.symmetries[2 * i] == dx && e.symmetries[2 * i + 1] == dy)
							listed = 1;
					CHECK_EQ_INT(listed, ok);
					count += (uint32_t)ok;
				}
			CHECK_EQ_INT(e.n_symmetries, count);
		}
		loom_db_close(db);
	}
}

/* Realism checks: empty space above and below, twist direction per kind,
   fibre orientation along the yarn, warp and weft different. */
static void test_realism(void)
{
	loom_exgen_params p = params("small");
	loom__exgen *g = NULL;
	loom__exgen_desc gd;
	loom_diag d = {0};
	vol v;
	long empty_top = 0, empty_bot = 0, slant[3] = {0, 0, 0}, nslant[3] = {0, 0, 0};
	long along[3] = {0, 0, 0}, nyarn[3] = {0, 0, 0}, thick[3] = {0, 0, 0};
	long ncol[3] = {0, 0, 0}, fly = 0, fly_split = 0;
	uint32_t fly_block[256] = {0};

	p.block[0] = 48; /* finer voxels so that the surface fibres resolve */
	p.block[1] = 32;
	p.block[2] = 96;
	p.voxel_size_um = 12;
	CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
	if (!g)
		return;
	loom__exgen_describe(g, &gd);
	vol_gen(g, &v);
	for (uint32_t y = 0; y < v.s[1]; y++)
		for (uint32_t x = 0; x < v.s[0]; x++) {
			int z = top_z(&v, gd.yarns, x, y);
			uint8_t lab[3] = {0, 0, 0};
			empty_top += v.l[vi(&v, x, y, v.s[2] - 1)] != 0;
			empty_bot += v.l[vi(&v, x, y, 0)] != 0;
			if (z >= 0) {
				size_t i = vi(&v, x, y, (uint32_t)z);
				int kind = gd.yarns[v.l[i]].kind;
				float o[3];
				loom__orient_decode(v.o[i], o);
				slant[kind] += o[0] * o[1] > 0 ? 1 : -1;
				nslant[kind]++;
			}
			for (uint32_t zz = 0; zz < v.s[2]; zz++) {
				size_t i = vi(&v, x, y, zz);
				int kind = gd.yarns[v.l[i]].kind;
				float o[3];
				if (!v.l[i])
					continue;
				if (gd.yarns[v.l[i]].flags & LOOM_DB_YARN_FLYAWAY) {
					/* a flyaway stays in one block: never cut at a
					   block edge when the block is copied */
					uint32_t blk = (y / p.block[1]) * 1024 + x / p.block[0];
					if (!fly_block[v.l[i]])
						fly_block[v.l[i]] = blk + 1;
					else if (fly_block[v.l[i]] != blk + 1)
						fly_split++;
					fly++;
					continue;
				}
				loom__orient_decode(v.o[i], o);
				along[kind] += fabsf(kind == LOOM_YARN_WARP ? o[1] : o[0]) > 0.8f;
				nyarn[kind]++;
				if (!lab[kind]) {
					lab[kind] = 1;
					ncol[kind]++;
				}
				thick[kind]++;
			}
		}
	/* nothing touches the top or bottom slice */
	CHECK_EQ_INT(empty_top, 0);
	CHECK_EQ_INT(empty_bot, 0);
	/* surface fibres slant "/" on both kinds: Z twist on warps (along y),
	   S twist on wefts (along x) */
	printf("  surface slant: warp %+.2f, weft %+.2f\n",
	       (double)slant[1] / (double)nslant[1], (double)slant[2] / (double)nslant[2]);
	CHECK((double)slant[1] / (double)nslant[1] > 0.5);
	CHECK((double)slant[2] / (double)nslant[2] > 0.5);
	/* most yarn voxels point along their yarn */
	CHECK((double)along[1] / (double)nyarn[1] > 0.8);
	CHECK((double)along[2] / (double)nyarn[2] > 0.8);
	/* wefts are thicker than warps (per covered column) */
	printf("  mean thickness: warp %.1f, weft %.1f voxels\n",
	       (double)thick[1] / (double)ncol[1], (double)thick[2] / (double)ncol[2]);
	CHECK((double)thick[2] / (double)ncol[2] > 1.1 * (double)thick[1] / (double)ncol[1]);
	CHECK(fly > 0);
	CHECK_EQ_INT(fly_split, 0);
	vol_free(&v);
	loom__exgen_free(g);
}

/* Bottom-surface counterpart of top_z. */
static int bottom_z(const vol *v, const loom_db_yarn *yarns, uint32_t x, uint32_t y)
{
	for (uint32_t z = 0; z < v->s[2]; z++) {
		size_t i = vi(v, x, y, z);
		uint8_t l = v->l[i];
		if (l && yarns[l].kind && !(yarns[l].flags & LOOM_DB_YARN_FLYAWAY) &&
		    v->d[i] >= LOOM__DB_TOP_THRESHOLD)
			return (int)z;
	}
	return -1;
}

/* Every exemplar of a database has its cloth mid-plane at the same z: the
   middle of the cloth at crossing centres, averaged separately over
   warp-over and weft-over crossings, agrees between all the default
   weaves within one voxel.  The depth is 160 voxels so that an offset of
   a few percent of b3 per exemplar would show.  For smooth yarns and for
   cotton fibre-level yarns (the command's default). */
static void midplane(const char *fibre)
{
	loom_exgen_params p = params("small");
	double lo[2] = {1e9, 1e9}, hi[2] = {-1e9, -1e9};

	p.block[2] = 160;
	p.fibre[0] = p.fibre[1] = fibre;
	for (uint32_t k = 0; k < p.n_weaves; k++) {
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		loom_diag d = {0};
		double sum[2] = {0, 0};
		long n[2] = {0, 0};
		vol v;
		CHECK_EQ_INT(loom__exgen_new(&p, k, 0, &g, &d), LOOM_OK);
		if (!g)
			return;
		loom__exgen_describe(g, &gd);
		vol_gen(g, &v);
		for (uint32_t r = 0; r < gd.rows; r++)
			for (uint32_t c = 0; c < gd.cols; c++) {
				uint32_t x = c * p.block[0] + p.block[0] / 2;
				uint32_t y = r * p.block[1] + p.block[1] / 2;
				int t = top_z(&v, gd.yarns, x, y), b = bottom_z(&v, gd.yarns, x, y);
				int over = gd.weave[r * gd.cols + c] != 0;
				CHECK(t >= 0 && b >= 0);
				sum[over] += 0.5 * (t + b);
				n[over]++;
			}
		for (int o = 0; o < 2; o++) {
			double m = sum[o] / (double)n[o];
			printf("  %s %-12s %s over: mid-plane z %.2f\n", fibre ? fibre : "smooth",
			       gd.name, o ? "warp" : "weft", m);
			lo[o] = m < lo[o] ? m : lo[o];
			hi[o] = m > hi[o] ? m : hi[o];
		}
		CHECK(fabsf(loom__exgen_mid_z(g) - (float)(p.block[2] - 1) / 2.0f) < 0.01f);
		vol_free(&v);
		loom__exgen_free(g);
	}
	printf("  %s: spread %.2f (weft over), %.2f (warp over) voxels\n",
	       fibre ? fibre : "smooth", hi[0] - lo[0], hi[1] - lo[1]);
	CHECK(hi[0] - lo[0] <= 1.0);
	CHECK(hi[1] - lo[1] <= 1.0);
}

static void test_midplane(void)
{
	midplane(NULL);
	midplane("cotton");
}

/* Mean over covered columns of the number of voxels of one kind of yarn
   (its thickness in voxels), flyaways excluded. */
static double kind_thickness(const vol *v, const loom_db_yarn *yarns, int kind)
{
	long t = 0, ncol = 0;

	for (uint32_t y = 0; y < v->s[1]; y++)
		for (uint32_t x = 0; x < v->s[0]; x++) {
			long c = 0;
			for (uint32_t z = 0; z < v->s[2]; z++) {
				uint8_t l = v->l[vi(v, x, y, z)];
				c += l && yarns[l].kind == kind &&
				     !(yarns[l].flags & LOOM_DB_YARN_FLYAWAY);
			}
			t += c;
			ncol += c > 0;
		}
	return ncol ? (double)t / (double)ncol : 0;
}

/* A sett sets b1 x b2 at the voxel size (square -> square, 2:1 -> 2:1),
   b3 grows to hold thick yarns, the yarn diameter sets the thickness;
   bad setts and diameters are errors naming the range. */
static void test_sett(void)
{
	loom_exgen_params p = params("paper");
	loom_diag d = {0};
	double t1[3], t2[3];

	CHECK_EQ_INT(loom_exgen_set_sett(&p, 54.0, 54.0, &d), LOOM_OK);
	CHECK(p.block[0] == 37 && p.block[1] == 37); /* 10000 / (54 * 5) = 37.04 */
	CHECK_EQ_INT(p.block[2], 300);
	CHECK_EQ_INT(loom_exgen_set_sett(&p, 54.0, 27.0, &d), LOOM_OK);
	CHECK(p.block[0] == 37 && p.block[1] == 74);
	p = params("small");
	CHECK_EQ_INT(loom_exgen_set_sett(&p, 20.0, 10.0, &d), LOOM_OK);
	CHECK(p.block[0] == 21 && p.block[1] == 42); /* 20.8 and 41.7 */
	CHECK(p.block[2] >= 48);
	/* a crossing under 4 voxels */
	CHECK_EQ_INT(loom_exgen_set_sett(&p, 200.0, 20.0, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "200 ends per cm at 24 um voxels gives crossings "
	                   "of 2.1 voxels (at least 4");
	CHECK_EQ_INT(loom_exgen_set_sett(&p, 20.0, 0.0, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "0 picks per cm (expected a positive number)");
	CHECK_EQ_INT(loom_exgen_set_sett(&p, 20.0, -3.0, &d), LOOM_EINVAL);
	/* yarn diameter: thicker yarns, thicker cloth, and a deeper block */
	for (int k = 0; k < 2; k++) {
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		vol v;
		p = params("small");
		p.weaves[0] = "plain";
		p.voxel_size_um = 10;
		p.yarn_diameter_um[0] = p.yarn_diameter_um[1] = k ? 240.0f : 120.0f;
		CHECK_EQ_INT(loom_exgen_set_sett(&p, 30.0, 30.0, &d), LOOM_OK);
		CHECK(p.block[0] == 33 && p.block[1] == 33);
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (!g)
			return;
		loom__exgen_describe(g, &gd);
		vol_gen(g, &v);
		(k ? t2 : t1)[1] = kind_thickness(&v, gd.yarns, LOOM_YARN_WARP);
		(k ? t2 : t1)[2] = kind_thickness(&v, gd.yarns, LOOM_YARN_WEFT);
		(k ? t2 : t1)[0] = (double)p.block[2];
		/* nothing reaches the top or bottom slice */
		for (uint32_t y = 0; y < v.s[1]; y++)
			for (uint32_t x = 0; x < v.s[0]; x++) {
				uint8_t lt = v.l[vi(&v, x, y, v.s[2] - 1)];
				uint8_t lb = v.l[vi(&v, x, y, 0)];
				CHECK(!(lt && !(gd.yarns[lt].flags & LOOM_DB_YARN_FLYAWAY)));
				CHECK(!lb);
			}
		vol_free(&v);
		loom__exgen_free(g);
	}
	/* 120 um round yarns: 156 um wide, 0.85 * 120^2 / 156 = 78 um thick; 240
	   um: 0.92 * 330 = 304 um wide (the spacing caps it), 161 um thick.  In
	   a plain weave every crossing is an interlacing, where the yarn is
	   pressed to 1 - 0.2 of its half-height (COMPRESS); and the mean over the
	   columns an ellipse covers is pi/4 of its height. */
	printf("  yarn thickness (voxels): 120 um warp %.1f weft %.1f, 240 um warp "
	       "%.1f weft %.1f\n", t1[1], t1[2], t2[1], t2[2]);
	for (int k = 1; k < 3; k++) {
		CHECK(fabs(t1[k] / (0.7854 * 0.8 * 7.8) - 1.0) < 0.15);
		CHECK(fabs(t2[k] / (0.7854 * 0.8 * 16.1) - 1.0) < 0.15);
	}
	/* 400 um yarns on 30 per cm need a deeper block (the cloth is about
	   1 mm thick) */
	p = params("small");
	p.voxel_size_um = 10;
	p.yarn_diameter_um[0] = p.yarn_diameter_um[1] = 400.0f;
	CHECK_EQ_INT(loom_exgen_set_sett(&p, 30.0, 30.0, &d), LOOM_OK);
	printf("  b3 for 400 um yarns: %u\n", p.block[2]);
	CHECK(p.block[2] > 100);
	CHECK_EQ_INT(loom__exgen_check(&p, &d), LOOM_OK);
	p.block[2] -= 2;
	CHECK_EQ_INT(loom__exgen_check(&p, &d), LOOM_EINVAL);
	p = params("small");
	p.yarn_diameter_um[1] = 2000.0f; /* 4 x 384 um = 1536 at most */
	CHECK_EQ_INT(loom__exgen_check(&p, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "weft yarn diameter 2000 um (expected 0 < d <= "
	                   "1536 um");
	p.yarn_diameter_um[1] = 600.0f;
	CHECK_EQ_INT(loom__exgen_check(&p, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "block depth 48 voxels is too thin");
}

/* Extent of warp c's voxels in the slice y (x width, z height), voxels. */
static void warp_extent(const vol *v, const loom__exgen_desc *gd, uint32_t c,
                        uint32_t y, int *w, int *h)
{
	int xlo = INT32_MAX, xhi = -1, zlo = INT32_MAX, zhi = -1;

	for (uint32_t z = 0; z < v->s[2]; z++)
		for (uint32_t x = 0; x < v->s[0]; x++) {
			uint8_t l = v->l[vi(v, x, y, z)];
			if (!l || gd->yarns[l].kind != LOOM_YARN_WARP ||
			    gd->yarns[l].index != (int16_t)c ||
			    (gd->yarns[l].flags & LOOM_DB_YARN_FLYAWAY) || v->d[vi(v, x, y, z)] < 64)
				continue;
			xlo = (int)x < xlo ? (int)x : xlo;
			xhi = (int)x > xhi ? (int)x : xhi;
			zlo = (int)z < zlo ? (int)z : zlo;
			zhi = (int)z > zhi ? (int)z : zhi;
		}
	*w = xhi - xlo + 1;
	*h = zhi - zlo + 1;
}

/* Woven mechanics: a warp float lies higher the longer it is (mean top of
   the warp-over crossing centres: plain < 2/2 twill < the middle of the
   4/1 satin's floats; expected about 8.0, 8.9 and 9.7 voxels above the
   mid-plane from the crimp and half-heights), and a warp
   is flatter (larger width / height) where a weft presses it at an
   interlacing than in the middle of a 4-pick float.  For smooth yarns and
   for cotton fibre-level yarns (the command's default). */
static void mechanics(const char *fibre)
{
	static const char *const weaves[3] = {"plain", "twill:2/2", "satin:4/1"};
	loom_exgen_params p = params("small");
	double top[3];
	double asp_pressed = 0, asp_free = 0;
	int n_pressed = 0, n_free = 0;

	p.fibre[0] = p.fibre[1] = fibre;
	p.block[0] = p.block[1] = 32;
	p.block[2] = 96;
	p.voxel_size_um = 10;
	for (int k = 0; k < 3; k++) {
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		loom_diag d = {0};
		double sum = 0;
		long n = 0;
		vol v;
		p.weaves[0] = weaves[k];
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (!g)
			return;
		loom__exgen_describe(g, &gd);
		vol_gen(g, &v);
		for (uint32_t r = 0; r < gd.rows; r++)
			for (uint32_t c = 0; c < gd.cols; c++) {
				uint32_t x = c * 32 + 16, y = r * 32 + 16;
				uint32_t up = (r + gd.rows - 1) % gd.rows, dn = (r + 1) % gd.rows;
				int w, h;
				if (!gd.weave[r * gd.cols + c])
					continue;
				/* the satin's 4-pick floats: their middle */
				if (k < 2 || (gd.weave[up * gd.cols + c] && gd.weave[dn * gd.cols + c])) {
					sum += top_z(&v, gd.yarns, x, y);
					n++;
				}
				if (k != 2)
					continue;
				/* in the satin: the middle of a float (over on both sides) */
				if (gd.weave[up * gd.cols + c] && gd.weave[dn * gd.cols + c]) {
					warp_extent(&v, &gd, c, y, &w, &h);
					asp_free += (double)w / h;
					n_free++;
				}
			}
		if (k == 2)
			for (uint32_t r = 0; r < gd.rows; r++)
				for (uint32_t c = 0; c < gd.cols; c++) {
					int w, h;
					if (gd.weave[r * gd.cols + c])
						continue; /* the single pick the warp passes under */
					warp_extent(&v, &gd, c, r * 32 + 16, &w, &h);
					asp_pressed += (double)w / h;
					n_pressed++;
				}
		top[k] = sum / (double)n;
		printf("  %s %-10s mean top of warp floats: z %.2f (%ld crossings)\n",
		       fibre ? fibre : "smooth", weaves[k], top[k], n);
		vol_free(&v);
		loom__exgen_free(g);
	}
	if (!fibre) { /* see test_mechanics */
		CHECK(top[1] > top[0] + 0.5);
		CHECK(top[2] > top[1] + 0.5);
	}
	CHECK(n_pressed > 0 && n_free > 0);
	asp_pressed /= n_pressed;
	asp_free /= n_free;
	printf("  %s warp aspect (width/height): pressed %.2f, middle of a float %.2f\n",
	       fibre ? fibre : "smooth", asp_pressed, asp_free);
	CHECK(asp_pressed > 1.1 * asp_free);
}

static int cmp_int(const void *a, const void *b)
{
	return *(const int *)a - *(const int *)b;
}

/* Float height on cotton.  The top of a 2-ply yarn rises and falls by a
   quarter of its half-height with the ply twist (the two plies' crests
   pass every half ply pitch, about two crossings at this scale), and hairs
   and loops stand above it, so one column per crossing hides the float's
   rise of under a voxel (one seed measured 53.9, 55.5, 55.1).  Here each
   warp-over crossing gives the median top of the warp over the central
   16 x 16 columns of its block (the warp's top, hairs and the ply crests
   of one phase no more than the others), averaged over its crossings and
   over 4 seeds (4 windows of other yarns at other ply phases); the spread
   between seeds bounds the noise left. */
static void test_float_height_cotton(void)
{
	static const char *const weaves[3] = {"plain", "twill:2/2", "satin:4/1"};
	enum { SEEDS = 4 };
	double top[SEEDS][3], mean[3] = {0, 0, 0}, sd[3] = {0, 0, 0};
	int *col = malloc(sizeof(int) * 16 * 16);

	if (!col)
		return;
	for (int s = 0; s < SEEDS; s++)
		for (int k = 0; k < 3; k++) {
			loom_exgen_params p = params("small");
			loom__exgen *g = NULL;
			loom__exgen_desc gd;
			double sum = 0;
			long n = 0;
			vol v;
			p.fibre[0] = p.fibre[1] = "cotton";
			p.block[0] = p.block[1] = 32;
			p.block[2] = 96;
			p.voxel_size_um = 10;
			p.seed = 11 + (uint64_t)s;
			p.weaves[0] = weaves[k];
			CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, NULL), LOOM_OK);
			if (!g) {
				free(col);
				return;
			}
			loom__exgen_describe(g, &gd);
			vol_gen(g, &v);
			for (uint32_t r = 0; r < gd.rows; r++)
				for (uint32_t c = 0; c < gd.cols; c++) {
					uint32_t up = (r + gd.rows - 1) % gd.rows, dn = (r + 1) % gd.rows;
					int m = 0;
					if (!gd.weave[r * gd.cols + c] ||
					    (k == 2 && !(gd.weave[up * gd.cols + c] &&
					                 gd.weave[dn * gd.cols + c])))
						continue;
					for (uint32_t y = r * 32 + 8; y < r * 32 + 24; y++)
						for (uint32_t x = c * 32 + 8; x < c * 32 + 24; x++) {
							int z = top_z(&v, gd.yarns, x, y);
							if (z >= 0 && gd.yarns[v.l[vi(&v, x, y, (uint32_t)z)]].kind ==
							              LOOM_YARN_WARP)
								col[m++] = z;
						}
					if (m < 64)
						continue; /* the warp hardly shows: not a float's top */
					qsort(col, (size_t)m, sizeof *col, cmp_int);
					sum += col[m / 2];
					n++;
				}
			top[s][k] = n ? sum / (double)n : 0;
			CHECK(n >= 5);
			vol_free(&v);
			loom__exgen_free(g);
		}
	free(col);
	for (int k = 0; k < 3; k++) {
		for (int s = 0; s < SEEDS; s++)
			mean[k] += top[s][k] / SEEDS;
		for (int s = 0; s < SEEDS; s++)
			sd[k] += (top[s][k] - mean[k]) * (top[s][k] - mean[k]) / (SEEDS - 1);
		sd[k] = sqrt(sd[k]);
		printf("  cotton %-10s median top of warp floats: z %.2f (seeds %.2f %.2f "
		       "%.2f %.2f, sd %.2f)\n", weaves[k], mean[k], top[0][k], top[1][k],
		       top[2][k], top[3][k], sd[k]);
	}
	/* each rise is larger than 3 standard errors of the difference of two
	   4-seed means, and than a third of a voxel */
	for (int k = 1; k < 3; k++) {
		double se = sqrt((sd[k] * sd[k] + sd[k - 1] * sd[k - 1]) / SEEDS);
		CHECK(mean[k] - mean[k - 1] > 3 * se);
		CHECK(mean[k] - mean[k - 1] > 0.33);
	}
}

/* The float heights of single crossings are checked on smooth yarns here,
   on cotton by test_float_height_cotton (averaged); the pressed / free
   aspect on both. */
static void test_mechanics(void)
{
	mechanics(NULL);
	mechanics("cotton");
}

static void test_bad_params(void)
{
	loom_exgen_params p = params("small");
	loom_diag d = {0};
	loom__exgen *g = NULL;

	p.weaves[0] = "plain";
	p.rows = p.cols = 5; /* plain repeats every 2: 5 is not a multiple */
	CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "weave 'plain' repeats every 2x2");
	p = params("small");
	p.weaves[0] = "twill:0/3";
	CHECK_EQ_INT(loom_exgen_write_db(tpath("bad.ldb"), &p, NULL, &d), LOOM_EINVAL);
	CHECK(access(tpath("bad.ldb"), F_OK) != 0);
	p = params("small");
	p.size = 8;
	CHECK_EQ_INT(loom_exgen_write_db(tpath("bad.ldb"), &p, NULL, &d), LOOM_EINVAL);
	p = params("small");
	p.block[2] = 2;
	CHECK_EQ_INT(loom_exgen_write_db(tpath("bad.ldb"), &p, NULL, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_exgen_preset("huge", &p), LOOM_EINVAL);
	/* auto window: 4x4 for plain, 6x6 for a 3-end twill, 5x5 for 5-end */
	p = params("small");
	p.weaves[0] = "plain";
	CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
	if (g) {
		loom__exgen_desc gd;
		loom__exgen_describe(g, &gd);
		CHECK(gd.rows == 4 && gd.cols == 4);
		loom__exgen_free(g);
	}
	p.weaves[0] = "twill:2/1";
	CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
	if (g) {
		loom__exgen_desc gd;
		loom__exgen_describe(g, &gd);
		CHECK(gd.rows == 6 && gd.cols == 6);
		loom__exgen_free(g);
	}
	/* min_crossings: the smallest multiple of the repeat >= it, per side */
	p.min_crossings = 10;
	{
		const char *w[] = {"plain", "twill:2/1", "satin:1/7", "basket:1/3"};
		const uint32_t want[][2] = {{10, 10}, {12, 12}, {16, 16}, {10, 12}};
		for (int i = 0; i < 4; i++) {
			uint32_t rr, rc;
			loom_weave_params wv;
			p.weaves[0] = w[i];
			CHECK_EQ_INT(loom_weave_parse(w[i], &wv, &d), LOOM_OK);
			CHECK_EQ_INT(loom_weave_repeat(&wv, &rr, &rc, &d), LOOM_OK);
			CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
			if (g) {
				loom__exgen_desc gd;
				loom__exgen_describe(g, &gd);
				/* brute force: the first multiple of the repeat >= 10 */
				CHECK(gd.rows >= 10 && gd.rows % rr == 0 && gd.rows - rr < 10);
				CHECK(gd.cols >= 10 && gd.cols % rc == 0 && gd.cols - rc < 10);
				CHECK(gd.rows == want[i][0] && gd.cols == want[i][1]);
				loom__exgen_free(g);
			}
		}
	}
	p.weaves[0] = "twill:2/3";
	p.min_crossings = 61; /* 65 > 64 */
	CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "is 65x65, above the largest window (64 a side)");
	p.min_crossings = 65;
	CHECK_EQ_INT(loom_exgen_check_params(&p, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "at least 65 crossings per side asked (at most 64)");
}


/* ---- fibre-level yarns -------------------------------------------------- */

/* 4-connected components of the voxels of plane (w x h) set in m; with
   code, neighbours join only if their codes are equal. */
static uint32_t components(uint8_t *m, int w, int h, int *stack,
                           const uint16_t *code)
{
	uint32_t n = 0;
	for (int i = 0; i < w * h; i++) {
		int sp = 0;
		if (!m[i])
			continue;
		n++;
		m[i] = 0;
		stack[sp++] = i;
		while (sp) {
			int c = stack[--sp], x = c % w, y = c / w;
			const int nb[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
			for (int k = 0; k < 4; k++) {
				int xx = x + nb[k][0], yy = y + nb[k][1];
				if (xx < 0 || yy < 0 || xx >= w || yy >= h || !m[yy * w + xx] ||
				    (code && code[yy * w + xx] != code[c]))
					continue;
				m[yy * w + xx] = 0;
				stack[sp++] = yy * w + xx;
			}
		}
	}
	return n;
}

/* Paper-scale cross-sections of the warps: the fibres counted as connected
   components of density >= 128 (half covered) whose voxels share one
   orientation (at 0.4-0.6 packing fibres touch and overlap, and a CT
   analysis separates them by their directions, as this does) come out at
   plies x fibres per ply (hairs add a few, overlapped fibres hide). */
static void test_fibre_count(void)
{
	/* (wool is left out: at this yarn size it has so few fibres that its
	   hair outnumbers them) */
	static const char *const fib[] = {"cotton", "silk", "rayon", "polyester"};
	loom_diag d = {0};

	for (size_t f = 0; f < sizeof fib / sizeof fib[0]; f++) {
		loom_exgen_params p = params("paper");
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		loom__exgen_fibre fi;
		uint8_t *dn, *lb, *m;
		uint16_t *o, *oc;
		int *stack;
		double total = 0;
		uint32_t slices = 0;

		p.n_weaves = 1;
		p.weaves[0] = "twill:2/3";
		p.fibre[0] = p.fibre[1] = fib[f];
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (!g)
			continue;
		loom__exgen_describe(g, &gd);
		loom__exgen_fibres(g, 1, &fi);
		dn = malloc((size_t)gd.size[0] * gd.size[2]);
		lb = malloc((size_t)gd.size[0] * gd.size[2]);
		o = malloc(2 * (size_t)gd.size[0] * gd.size[2]);
		m = malloc((size_t)gd.size[0] * gd.size[2]);
		stack = malloc(sizeof(int) * gd.size[0] * gd.size[2]);
		oc = malloc(2 * (size_t)gd.size[0] * gd.size[2]);
		for (uint32_t r = 0; r < gd.rows; r++) {
			uint32_t y = r * p.block[1] + p.block[1] / 2; /* crossing centre */
			loom__exgen_box(g, 0, y, 0, gd.size[0], 1, gd.size[2], dn, o, lb);
			for (uint32_t c = 1; c + 1 < gd.cols; c++) {
				uint8_t L = 0;
				for (uint32_t k = 1; k <= gd.n_yarns; k++)
					if (gd.yarns[k].kind == 1 && gd.yarns[k].index == (int)c &&
					    !(gd.yarns[k].flags & LOOM_DB_YARN_FLYAWAY))
						L = (uint8_t)k;
				/* plane (x, z) of the warp's voxels */
				for (uint32_t x = 0; x < gd.size[0]; x++)
					for (uint32_t z = 0; z < gd.size[2]; z++) {
						size_t i = (size_t)x * gd.size[2] + z;
						m[z * gd.size[0] + x] = lb[i] == L && dn[i] >= 128;
						oc[z * gd.size[0] + x] = o[i];
					}
				total += components(m, (int)gd.size[0], (int)gd.size[2], stack, oc);
				slices++;
			}
		}
		{
			double mean = total / slices, want = (double)fi.plies * fi.per_ply;
			printf("  %-10s %u plies x %u fibres (%u placed): %.1f components per "
			       "cross-section\n", fib[f], fi.plies, fi.per_ply, fi.placed, mean);
			CHECK(fabs(mean / want - 1.0) <= 0.25);
		}
		free(dn);
		free(lb);
		free(o);
		free(m);
		free(stack);
		free(oc);
		loom__exgen_free(g);
	}
}

/* The fibres' helix angle read from the orientation channel on the top of
   the warp floats (middle quarter of the yarn's width, where the surface is
   flat; the outermost fibres) is the preset's, within 3 degrees (median
   over the voxels). */
static void test_fibre_twist(void)
{
	static const char *const fib[] = {"polyester", "linen"};
	loom_diag d = {0};

	for (size_t f = 0; f < 2; f++) {
		loom_exgen_params p = params("paper");
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		loom__exgen_fibre fi;
		uint8_t *dn, *lb;
		uint16_t *o;
		float *ang;
		size_t na = 0;
		uint32_t nz;

		p.n_weaves = 1;
		p.weaves[0] = "satin:4/1"; /* warp floats of 4 */
		p.fibre[0] = p.fibre[1] = fib[f];
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (!g)
			continue;
		loom__exgen_describe(g, &gd);
		loom__exgen_fibres(g, 1, &fi);
		nz = gd.size[2];
		dn = malloc((size_t)p.block[0] * nz);
		lb = malloc((size_t)p.block[0] * nz);
		o = malloc(2 * (size_t)p.block[0] * nz);
		ang = malloc(sizeof(float) * gd.size[1] * p.block[0]);
		for (uint32_t c = 1; c + 1 < gd.cols; c++)
			for (uint32_t y = 0; y < gd.size[1]; y++) {
				uint32_t r = y / p.block[1], x0 = c * p.block[0] + p.block[0] / 4;
				/* middle of a warp float of 4: its crossing and neighbours are
				   warp-over */
				if (!gd.weave[r * gd.cols + c] ||
				    !gd.weave[((r + 1) % gd.rows) * gd.cols + c] ||
				    !gd.weave[((r + gd.rows - 1) % gd.rows) * gd.cols + c])
					continue;
				int ztop[64];
				float atop[64];
				int zmax = -1;
				uint32_t nx = p.block[0] / 4 < 64 ? p.block[0] / 4 : 64;
				x0 = c * p.block[0] + p.block[0] / 2 - nx / 2;
				loom__exgen_box(g, x0, y, 0, nx, 1, nz, dn, o, lb);
				for (uint32_t i = 0; i < nx; i++) {
					ztop[i] = -1;
					for (int z = (int)nz - 1; z >= 0; z--) {
						size_t k = (size_t)i * nz + (size_t)z;
						float v[3];
						if (!lb[k] || dn[k] < 128)
							continue;
						if (gd.yarns[lb[k]].kind == 1 &&
						    !(gd.yarns[lb[k]].flags & LOOM_DB_YARN_FLYAWAY)) {
							loom__orient_decode(o[k], v);
							if (fabsf(v[2]) < 0.2f) {
								ztop[i] = z;
								atop[i] = atan2f(fabsf(v[0]), fabsf(v[1])) * 57.29578f;
								if (z > zmax)
									zmax = z;
							}
						}
						break;
					}
				}
				/* the outermost fibres (within 2 voxels of the top) carry
				   the surface angle; deeper ones seen through gaps less */
				for (uint32_t i = 0; i < nx; i++)
					if (ztop[i] >= 0 && ztop[i] >= zmax - 2)
						ang[na++] = atop[i];
			}
		CHECK(na > 100);
		if (na) {
			float med;
			for (size_t i = 1; i < na; i++) /* insertion sort */
				for (size_t j = i; j > 0 && ang[j - 1] > ang[j]; j--) {
					float t = ang[j];
					ang[j] = ang[j - 1];
					ang[j - 1] = t;
				}
			med = ang[na / 2];
			printf("  %-10s twist: preset %.1f deg, median on the floats %.1f deg "
			       "(%zu voxels)\n", fib[f], (double)fi.fibre_deg, (double)med, na);
			CHECK(fabsf(med - fi.fibre_deg) <= 3.0f);
		}
		free(dn);
		free(lb);
		free(o);
		free(ang);
		loom__exgen_free(g);
	}
}

/* Label of the interior yarn (kind 1 warp, 2 weft) of index i. */
static uint8_t yarn_label(const loom__exgen_desc *gd, int kind, int i)
{
	for (uint32_t k = 1; k <= gd->n_yarns; k++)
		if (gd->yarns[k].kind == kind && gd->yarns[k].index == i &&
		    !(gd->yarns[k].flags & LOOM_DB_YARN_FLYAWAY))
			return (uint8_t)k;
	return 0;
}

/* The warps in the middle of their 4/1 satin floats (unpressed), in x-z
   slices: the mean density inside their elliptical cross-section (voxels
   of the warp or empty; the weft below may reach in), and the angular
   harmonics of the density in the normalised (round) section, |sum d
   e^(i m theta)| / sum d over the ring 0.15 < r < 0.9 (hm[m], m = 1..4,
   averaged over the slices): n plies put n density lobes around the yarn
   centre.  Returns the fill, -1 on failure. */
static double fibre_section(const char *preset, const char *fibre, double hm[5])
{
	loom_exgen_params p = params(preset);
	loom__exgen *g = NULL;
	loom__exgen_desc gd;
	loom_diag d = {0};
	double sum = 0;
	size_t cnt = 0, ns = 0;
	uint8_t *dn, *lb;
	uint16_t *o;

	for (int m = 0; m < 5; m++)
		hm[m] = 0;
	p.n_weaves = 1;
	p.weaves[0] = "satin:4/1";
	p.fibre[0] = p.fibre[1] = fibre;
	if (loom__exgen_new(&p, 0, 0, &g, &d) != LOOM_OK)
		return -1;
	loom__exgen_describe(g, &gd);
	dn = malloc((size_t)gd.size[0] * gd.size[2]);
	lb = malloc((size_t)gd.size[0] * gd.size[2]);
	o = malloc(2 * (size_t)gd.size[0] * gd.size[2]);
	for (uint32_t r = 0; r < gd.rows; r++) {
		uint32_t y = r * p.block[1] + p.block[1] / 2;
		loom__exgen_box(g, 0, y, 0, gd.size[0], 1, gd.size[2], dn, o, lb);
		for (uint32_t c = 0; c < gd.cols; c++) {
			uint8_t L = yarn_label(&gd, 1, (int)c);
			double re[5] = {0}, im[5] = {0}, ring = 0;
			float sec[4];
			if (!gd.weave[r * gd.cols + c] ||
			    !gd.weave[((r + 1) % gd.rows) * gd.cols + c] ||
			    !gd.weave[((r + gd.rows - 1) % gd.rows) * gd.cols + c])
				continue;
			loom__exgen_section(g, 1, (int)c, (float)y, sec);
			for (uint32_t x = 0; x < gd.size[0]; x++)
				for (uint32_t z = 0; z < gd.size[2]; z++) {
					float u = ((float)x - sec[0]) / sec[2];
					float v = ((float)z - sec[1]) / sec[3];
					float r2 = u * u + v * v, th = atan2f(v, u);
					size_t i = (size_t)x * gd.size[2] + z;
					double dv = dn[i] / 255.0;
					if (r2 > 1.0f || (lb[i] && lb[i] != L))
						continue;
					sum += dv;
					cnt++;
					if (r2 < 0.15f * 0.15f || r2 > 0.81f)
						continue;
					ring += dv;
					for (int m = 1; m < 5; m++) {
						re[m] += dv * cos(m * th);
						im[m] += dv * sin(m * th);
					}
				}
			for (int m = 1; m < 5 && ring > 0; m++)
				hm[m] += sqrt(re[m] * re[m] + im[m] * im[m]) / ring;
			ns++;
		}
	}
	for (int m = 1; m < 5 && ns; m++)
		hm[m] /= (double)ns;
	free(dn);
	free(lb);
	free(o);
	loom__exgen_free(g);
	return cnt ? sum / (double)cnt : -1;
}

/* Fill: the fibres cover 0.4-0.6 of the yarn's cross-section, the fibre
   area fraction of real yarns, at 5 um (paper) and at 24 um (small; the
   coverage voxelization keeps the mean: within 0.08, the area where fibres
   overlap, which a 5 um voxel counts once and a 24 um one sums).  Plies:
   the strongest harmonic (m = 2..4) is the ply count and stands out
   (> 0.15) for plied presets; single-ply ones have no lobes (< 0.1). */
static void test_fibre_fill(void)
{
	static const char *const fib[] = {"cotton", "rayon", "silk", "polyester",
	                                  "wool", "linen"};
	loom_diag d = {0};

	for (size_t f = 0; f < sizeof fib / sizeof fib[0]; f++) {
		double hm[5], h24[5];
		double f5 = fibre_section("paper", fib[f], hm);
		double f24 = fibre_section("small", fib[f], h24);
		loom_exgen_params p = params("paper");
		loom__exgen *g = NULL;
		loom__exgen_fibre fi = {0};
		int best = 2;

		p.n_weaves = 1;
		p.weaves[0] = "plain";
		p.fibre[0] = p.fibre[1] = fib[f];
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (g)
			loom__exgen_fibres(g, 1, &fi);
		loom__exgen_free(g);
		for (int m = 3; m < 5; m++)
			if (hm[m] > hm[best])
				best = m;
		printf("  %-10s fill %.3f at 5 um, %.3f at 24 um; %u plies: harmonics "
		       "%.3f %.3f %.3f %.3f\n", fib[f], f5, f24, fi.plies, hm[1], hm[2],
		       hm[3], hm[4]);
		CHECK(f5 >= 0.4 && f5 <= 0.6);
		CHECK(f24 >= 0.4 && f24 <= 0.6);
		CHECK(fabs(f5 - f24) <= 0.08);
		if (fi.plies > 1) {
			CHECK(best == (int)fi.plies);
			CHECK(hm[best] > 0.15);
		} else {
			CHECK(hm[2] < 0.1 && hm[3] < 0.1 && hm[4] < 0.1);
		}
	}
}

/* Hairiness: per warp of a 4/1 satin at 10 um voxels (the paper preset's
   crossings), the voxels of the warp's label with density >= 32 outside
   1.2 times its cross-section (normalised radius), grouped into
   26-connected components of at least 15 voxels (a fibre piece some 50 um
   long; smaller ones are the ends of a fibre cut where it passes through
   another yarn): each is one hair or loop fibre, so their count per mm of
   warp is within 25 % of the preset's hair + loop per mm. */
static void test_fibre_hair(void)
{
	static const char *const fib[] = {"cotton", "rayon", "wool", "linen"};
	loom_diag d = {0};
	for (size_t f = 0; f < sizeof fib / sizeof fib[0]; f++) {
		loom_exgen_params p = params("paper");
		loom__exgen *g = NULL;
		loom__exgen_desc gd;
		loom__exgen_fibre fi;
		uint8_t *dn, *lb, *m;
		uint16_t *o;
		int32_t *stack;
		uint32_t nx, ny, nz, comps = 0;
		double mm = 0;

		p.n_weaves = 1;
		p.weaves[0] = "satin:4/1";
		p.fibre[0] = p.fibre[1] = fib[f];
		p.voxel_size_um = 10.0f;
		p.block[0] = 58;
		p.block[1] = 35;
		p.block[2] = 150;
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (!g)
			continue;
		loom__exgen_describe(g, &gd);
		loom__exgen_fibres(g, 1, &fi);
		nx = 2 * p.block[0];
		ny = gd.size[1];
		nz = gd.size[2];
		dn = malloc((size_t)nx * ny * nz);
		lb = malloc((size_t)nx * ny * nz);
		m = malloc((size_t)nx * ny * nz);
		o = malloc(2 * (size_t)nx * ny * nz);
		stack = malloc(sizeof *stack * (size_t)nx * ny * nz);
		for (uint32_t c = 0; c < gd.cols && dn && lb && m && o && stack; c++) {
			uint8_t L = yarn_label(&gd, 1, (int)c);
			int64_t x0 = (int64_t)c * p.block[0] - p.block[0] / 2;
			loom__exgen_box(g, x0, 0, 0, nx, ny, nz, dn, o, lb);
			for (uint32_t y = 0; y < ny; y++) {
				float sec[4];
				loom__exgen_section(g, 1, (int)c, (float)y, sec);
				for (uint32_t x = 0; x < nx; x++)
					for (uint32_t z = 0; z < nz; z++) {
						size_t i = ((size_t)y * nx + x) * nz + z;
						float u = ((float)(x0 + x) - sec[0]) / sec[2];
						float v = ((float)z - sec[1]) / sec[3];
						m[i] = lb[i] == L && dn[i] >= 32 && u * u + v * v > 1.44f;
					}
			}
			for (size_t i = 0; i < (size_t)nx * ny * nz; i++) {
				size_t sp = 0;
				if (!m[i])
					continue;
				size_t sz = 0;
				m[i] = 0;
				stack[sp++] = (int32_t)i;
				while (sp) {
					size_t q = (size_t)stack[--sp];
					sz++;
					int z = (int)(q % nz), x = (int)(q / nz % nx), y = (int)(q / nz / nx);
					for (int dy = -1; dy <= 1; dy++)
						for (int dx = -1; dx <= 1; dx++)
							for (int dz = -1; dz <= 1; dz++) {
								int yy = y + dy, xx = x + dx, zz = z + dz;
								size_t k;
								if (yy < 0 || xx < 0 || zz < 0 || yy >= (int)ny ||
								    xx >= (int)nx || zz >= (int)nz)
									continue;
								k = ((size_t)yy * nx + (size_t)xx) * nz + (size_t)zz;
								if (m[k]) {
									m[k] = 0;
									stack[sp++] = (int32_t)k;
								}
							}
				}
				comps += sz >= 15;
			}
			mm += ny * p.voxel_size_um / 1000.0;
		}
		{
			double want = fi.hair_per_mm + fi.loop_per_mm, got = comps / mm;
			printf("  %-10s %.1f hair and loop fibres per mm (preset %.1f), %u in "
			       "%.2f mm\n", fib[f], got, want, comps, mm);
			CHECK(fabs(got / want - 1.0) <= 0.25);
		}
		free(dn);
		free(lb);
		free(m);
		free(o);
		free(stack);
		loom__exgen_free(g);
	}
}

/* Fibre-level databases are the same bytes for 1, 2 and 3 threads. */
static void test_fibre_threads(void)
{
	loom_exgen_params p = params("small");
	loom_diag d = {0};
	uint64_t h[3] = {0, 0, 0};
	uint8_t *f[3];
	size_t n[3];
	const char *names[3] = {"f1.ldb", "f2.ldb", "f3.ldb"};

	p.n_weaves = 2;
	p.weaves[0] = "twill:2/3";
	p.weaves[1] = "satin:1/4";
	p.fibre[0] = "wool";
	p.fibre[1] = "cotton";
	p.brick[0] = p.brick[1] = 16;
	p.brick[2] = 16;
	for (int i = 0; i < 3; i++) {
		p.threads = (unsigned)i + 1;
		CHECK_EQ_INT(loom_exgen_write_db(tpath(names[i]), &p, &h[i], &d), LOOM_OK);
		f[i] = slurp(tpath(names[i]), &n[i]);
	}
	CHECK(h[0] == h[1] && h[1] == h[2] && h[0] != 0);
	CHECK(f[0] && f[1] && f[2] && n[0] == n[1] && n[1] == n[2] &&
	      memcmp(f[0], f[1], n[0]) == 0 && memcmp(f[0], f[2], n[0]) == 0);
	for (int i = 0; i < 3; i++)
		free(f[i]);
	/* any box gives the same voxels: a box made whole and in four parts
	   (split in x and in z) */
	{
		loom__exgen *g = NULL;
		enum { NX = 24, NY = 20, NZ = 48 };
		static uint8_t da[NX * NY * NZ], la[NX * NY * NZ], dq[NX * NY * NZ],
		        lq[NX * NY * NZ];
		static uint16_t oa[NX * NY * NZ], oq[NX * NY * NZ];
		int same = 1;
		CHECK_EQ_INT(loom__exgen_new(&p, 0, 0, &g, &d), LOOM_OK);
		if (g) {
			loom__exgen_box(g, 30, 10, 0, NX, NY, NZ, da, oa, la);
			for (int part = 0; part < 4; part++) {
				int x0 = (part & 1) * 11, z0 = (part >> 1) * 19;
				int nx = part & 1 ? NX - 11 : 11, nz = part >> 1 ? NZ - 19 : 19;
				loom__exgen_box(g, 30 + x0, 10, z0, (uint32_t)nx, NY, (uint32_t)nz,
				                dq, oq, lq);
				for (int y = 0; y < NY; y++)
					for (int x = 0; x < nx; x++)
						for (int z = 0; z < nz; z++) {
							size_t i = ((size_t)y * NX + (size_t)(x + x0)) * NZ +
							           (size_t)(z + z0);
							size_t j = ((size_t)y * nx + (size_t)x) * nz + (size_t)z;
							if (da[i] != dq[j] || oa[i] != oq[j] || la[i] != lq[j])
								same = 0;
						}
			}
			CHECK(same);
			loom__exgen_free(g);
		}
	}
	/* an unknown fibre, and none mixed with a fibre, are refused */
	p.fibre[0] = "hemp";
	CHECK_EQ_INT(loom_exgen_check_params(&p, &d), LOOM_EINVAL);
	CHECK(strstr(d.message, "hemp") != NULL);
	p.fibre[0] = "none";
	CHECK_EQ_INT(loom_exgen_check_params(&p, &d), LOOM_EINVAL);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_exgen");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(test_determinism);
	RUN(test_threads);
	RUN(test_crossing_centres);
	RUN(test_tables_brute_force);
	RUN(test_symmetries);
	RUN(test_realism);
	RUN(test_midplane);
	RUN(test_sett);
	RUN(test_mechanics);
	RUN(test_float_height_cotton);
	RUN(test_bad_params);
	RUN(test_fibre_count);
	RUN(test_fibre_twist);
	RUN(test_fibre_fill);
	RUN(test_fibre_hair);
	RUN(test_fibre_threads);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
