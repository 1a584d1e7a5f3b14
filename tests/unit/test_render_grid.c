/*
 * tests/unit/test_render_grid.c - the majorant grid of the volume path
 * tracer (engine/render/render_majorant.c, the DDA and grid trackers of
 * engine/render/render.c; docs/rendering.md, "Majorant grid").
 *
 *  - DDA: on random rays and cell sizes the cells visited, and where each
 *    is entered and left, equal a brute-force walk (every plane crossing
 *    of the ray, sorted; the cell of each interval's midpoint); skipping
 *    the cells outside random column and box z spans (loom__dda_skip_z,
 *    loom__dda_skip_box) visits the in-span cells of the plain walk with
 *    the same bits, and fewer cells.
 *  - Majorant: on a synthesized fabric (randomisation and edge fix on),
 *    every voxel of 10 x 10 crossings (negative indices included) is at or
 *    below its cell's nearest bound, and trilinear samples at random points
 *    below the trilinear bound; some cells are empty (the grid skips
 *    space).  Through the grid source (nearest), every cell's bound is
 *    its largest voxel density and a queried column's z span its exact
 *    non-empty layers.
 *  - Renders through the grid: identical bytes on 1, 2 and 3 threads; far
 *    fewer lookups than the global majorant; the same image as the global
 *    majorant within the Monte Carlo error (8 seeds each, per-pixel
 *    z-scores and the image mean); a cell_max error aborts the render with
 *    its code; a zero cell size is refused.
 */
#include "loom.h"
#include "check.h"
#include "tmpdir.h"
#include "raise_block.h"
#include "render/render_internal.h"
#include "synth/fabric_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char db_path[4200];
static loom_db *g_db;
static loom_design *g_design;
static loom_fabric *g_fab;
static loom_texture *g_tex;
static uint32_t B[3];

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static double urand(uint64_t *s)
{
	*s += 1;
	return (double)(mix(*s) >> 11) * (1.0 / 9007199254740992.0);
}

/* ---- DDA against a brute-force walk -------------------------------------- */

typedef struct visit {
	int64_t c[3];
	double t0, t1;
} visit;

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static void test_dda_brute_force(void)
{
	uint64_t rng = 42;
	int bad = 0;

	for (int trial = 0; trial < 3000; trial++) {
		double o[3], d[3], t0, t1, ts[4096];
		int64_t cell[3];
		visit got[2048], want[2048];
		int ng = 0, nw = 0, nt = 0;
		loom__dda g;

		for (int j = 0; j < 3; j++) {
			cell[j] = 1 + (int64_t)(urand(&rng) * 9);
			o[j] = (urand(&rng) - 0.5) * 100;
			d[j] = urand(&rng) - 0.5;
		}
		if (trial % 7 == 0)
			d[trial / 7 % 3] = 0; /* axis-parallel planes never crossed */
		if (loom__normalize3(d) == 0)
			continue;
		t0 = urand(&rng) * 10;
		t1 = t0 + urand(&rng) * 60;
		/* brute force: every plane crossing in (t0, t1), sorted */
		ts[nt++] = t0;
		for (int j = 0; j < 3; j++) {
			double a, b;
			if (d[j] == 0)
				continue;
			a = o[j] + t0 * d[j];
			b = o[j] + t1 * d[j];
			if (a > b) {
				double tmp = a;
				a = b;
				b = tmp;
			}
			for (int64_t k = (int64_t)floor(a / cell[j]) + 1;
			     (double)k * cell[j] < b && nt < 4000; k++) {
				double t = ((double)k * cell[j] - o[j]) / d[j];
				if (t > t0 && t < t1)
					ts[nt++] = t;
			}
		}
		ts[nt++] = t1;
		qsort(ts, (size_t)nt, sizeof ts[0], cmp_double);
		for (int k = 0; k + 1 < nt; k++) {
			double tm = 0.5 * (ts[k] + ts[k + 1]);
			if (ts[k + 1] - ts[k] < 1e-9)
				continue;
			for (int j = 0; j < 3; j++)
				want[nw].c[j] = (int64_t)floor((o[j] + tm * d[j]) / cell[j]);
			want[nw].t0 = ts[k];
			want[nw].t1 = ts[k + 1];
			nw++;
		}
		/* the DDA, zero-length visits dropped */
		loom__dda_init(&g, o, d, cell, t0, t1);
		do {
			double te = loom__dda_exit(&g);
			if (te - g.t >= 1e-9 && ng < 2048) {
				memcpy(got[ng].c, g.c, sizeof g.c);
				got[ng].t0 = g.t;
				got[ng].t1 = te;
				ng++;
			}
		} while (loom__dda_next(&g));
		if (ng != nw) {
			if (bad++ < 3)
				printf("  trial %d: %d cells, brute force %d\n", trial, ng, nw);
			continue;
		}
		for (int k = 0; k < ng; k++)
			if (memcmp(got[k].c, want[k].c, sizeof got[k].c) ||
			    fabs(got[k].t0 - want[k].t0) > 1e-9 ||
			    fabs(got[k].t1 - want[k].t1) > 1e-9) {
				if (bad++ < 3)
					printf("  trial %d cell %d: (%lld %lld %lld) [%g %g], brute "
					       "force (%lld %lld %lld) [%g %g]\n", trial, k,
					       (long long)got[k].c[0], (long long)got[k].c[1],
					       (long long)got[k].c[2], got[k].t0, got[k].t1,
					       (long long)want[k].c[0], (long long)want[k].c[1],
					       (long long)want[k].c[2], want[k].t0, want[k].t1);
				break;
			}
	}
	CHECK_EQ_INT(bad, 0);
}

/* Spans for test_dda_skip: columns are grouped in boxes of 3 x 2 (as the
   grid's crossings group cell columns); each column's z span is a hash
   of the column (empty one time in five) and each box's the union of its
   columns' spans. */
static void col_span(int64_t c0, int64_t c1, int64_t *lo, int64_t *hi)
{
	uint64_t h = (uint64_t)c0 * 0x9e3779b97f4a7c15ull ^ (uint64_t)c1 * 0xc2b2ae3d27d4eb4full;
	h ^= h >> 29;
	h *= 0xbf58476d1ce4e5b9ull;
	h ^= h >> 32;
	if (h % 5 == 0) {
		*lo = 1;
		*hi = 0;
		return;
	}
	*lo = (int64_t)(h >> 8 & 15) - 4;
	*hi = *lo + (int64_t)(h >> 16 & 7);
}

static void box_span(const int64_t c[3], int64_t box[4], int64_t *lo, int64_t *hi)
{
	box[0] = (int64_t)floor(c[0] / 3.0) * 3;
	box[1] = box[0] + 3;
	box[2] = (int64_t)floor(c[1] / 2.0) * 2;
	box[3] = box[2] + 2;
	*lo = 1000;
	*hi = -1000;
	for (int64_t y = box[2]; y < box[3]; y++)
		for (int64_t x = box[0]; x < box[1]; x++) {
			int64_t a, b;
			col_span(x, y, &a, &b);
			if (a <= b) {
				*lo = a < *lo ? a : *lo;
				*hi = b > *hi ? b : *hi;
			}
		}
	if (*lo > *hi) {
		*lo = 1;
		*hi = 0;
	}
}

/* loom__dda_skip_z and loom__dda_skip_box against stepping: on random rays
   through columns and boxes of columns with random z spans, a walk that
   skips from every cell outside its box's span (skip_box) or its column's
   (skip_z) visits exactly the in-span cells of the plain walk, with the
   same bits (cell, entry and exit times), and ends at the same time; and
   it visits fewer cells, fewer still with the boxes. */
static void test_dda_skip(void)
{
	uint64_t rng = 7;
	int bad = 0;
	long cells[3] = {0, 0, 0};

	for (int trial = 0; trial < 4000; trial++) {
		double o[3], d[3], t0, t1;
		int64_t cell[3];
		visit ref[1025];
		int nref = 0;
		loom__dda g;

		for (int j = 0; j < 3; j++) {
			cell[j] = 1 + (int64_t)(urand(&rng) * 5);
			o[j] = (urand(&rng) - 0.5) * 60;
			d[j] = urand(&rng) - 0.5;
		}
		if (trial % 5 == 0)
			d[2] *= 0.02; /* grazing: long runs of z cells per column */
		if (trial % 11 == 0)
			d[trial / 11 % 3] = 0;
		if (loom__normalize3(d) == 0)
			continue;
		t0 = urand(&rng) * 5;
		t1 = t0 + urand(&rng) * 80;
		/* mode 0 steps, 1 skips columns, 2 skips boxes and columns */
		for (int mode = 0; mode < 3; mode++) {
			visit v[1025];
			int nv = 0, same;
			loom__dda_init(&g, o, d, cell, t0, t1);
			do {
				int64_t lo, hi, box[4], blo, bhi;
				cells[mode]++;
				box_span(g.c, box, &blo, &bhi);
				col_span(g.c[0], g.c[1], &lo, &hi);
				if (mode == 2 && (g.c[2] < blo || g.c[2] > bhi)) {
					loom__dda_skip_box(&g, box, blo, bhi);
				} else if (g.c[2] >= lo && g.c[2] <= hi) {
					if (nv < 1024) {
						memcpy(v[nv].c, g.c, sizeof g.c);
						v[nv].t0 = g.t;
						v[nv].t1 = loom__dda_exit(&g);
						nv++;
					}
				} else if (mode) {
					loom__dda_skip_z(&g, lo, hi);
				}
			} while (loom__dda_next(&g));
			v[nv].t0 = g.t;
			if (mode == 0) {
				memcpy(ref, v, sizeof v);
				nref = nv;
				continue;
			}
			same = nv == nref && v[nv].t0 == ref[nref].t0;
			for (int k = 0; same && k < nv; k++)
				same = !memcmp(v[k].c, ref[k].c, sizeof v[k].c) &&
				       v[k].t0 == ref[k].t0 && v[k].t1 == ref[k].t1;
			if (!same && bad++ < 3)
				printf("  trial %d mode %d: %d in-span cells, stepping %d\n", trial,
				       mode, nv, nref);
		}
	}
	printf("  cells visited: %ld stepping, %ld skipping columns, %ld boxes too\n",
	       cells[0], cells[1], cells[2]);
	CHECK_EQ_INT(bad, 0);
	CHECK(cells[1] < cells[0] * 85 / 100);
	CHECK(cells[2] < cells[1]);
}

/* ---- a synthesized fabric ------------------------------------------------ */

static void setup(void)
{
	loom_exgen_params p;
	loom_diag d = {0};
	loom_fabric_db_identity id;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;

	if (tmpdir_make())
		return;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	CHECK_EQ_INT(loom_exgen_preset("tiny", &p), LOOM_OK);
	p.seed = 9;
	p.threads = 2;
	CHECK_EQ_INT(loom_exgen_write_db(db_path, &p, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(db_path, &g_db, NULL), LOOM_OK);
	if (!g_db)
		return;
	CHECK_EQ_INT(loom_design_new(6, 5, &g_design), LOOM_OK);
	CHECK_EQ_INT(loom_design_set_types(g_design, 3), LOOM_OK);
	for (size_t i = 0; i < 30; i++) {
		uint64_t h = mix(i + 11);
		g_design->weave[i] = h & 1;
		g_design->warp_type[i] = (uint8_t)(h >> 8 & 1);
		g_design->weft_type[i] = (uint8_t)(1 + (h >> 16 & 1));
	}
	for (uint32_t k = 0; k < 3; k++) {
		g_design->types[k].albedo[0] = 0.2f + 0.3f * (float)k;
		g_design->types[k].albedo[1] = 0.9f - 0.2f * (float)k;
		g_design->types[k].albedo[2] = 0.3f;
		g_design->types[k].alignment = 0.1f * (float)(k + 1);
	}
	CHECK_EQ_INT(loom_fabric_synthesize(g_design, g_db, db_path, NULL, &g_fab, &d),
	             LOOM_OK);
	if (!g_fab)
		return;
	loom_fabric_get_db_identity(g_fab, &id);
	memcpy(B, id.block, sizeof B);
	o.budget_bytes = (size_t)8 << 20;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &g_tex, &d), LOOM_OK);
	printf("  block %ux%ux%u\n", B[0], B[1], B[2]);
}

/* Every voxel of crossing (I, J) against its cell's nearest bound nb and
   `samples` trilinear samples at random points against the trilinear
   bound tb (loom_majorant_bound's cells, `cell` voxels each): each above
   its bound adds 1 to *under (the first 3 printed); *voxels counts the
   voxels, *filled those with density. */
static void crossing_vs_bounds(loom_texture *t, int64_t I, int64_t J, const int64_t cell[3],
                               const uint8_t *nb, const uint8_t *tb, int samples,
                               uint64_t *rng, long *under, long *voxels, long *filled)
{
	int64_t nsx = B[0] / cell[0], nzc = ((int64_t)B[2] + cell[2] - 1) / cell[2];

	for (int64_t y = I * B[1]; y < (I + 1) * B[1]; y++)
		for (int64_t x = J * B[0]; x < (J + 1) * B[0]; x++)
			for (int64_t z = 0; z < B[2]; z++) {
				loom_texel tx;
				int64_t u = ((y - I * B[1]) / cell[1]) * nsx + (x - J * B[0]) / cell[0];
				uint8_t bound = nb[u * nzc + z / cell[2]];
				CHECK_EQ_INT(loom_texture_voxel(t, x, y, z, &tx), LOOM_OK);
				(*voxels)++;
				*filled += tx.density > 0;
				if (tx.density > (float)bound / 255.0f && (*under)++ < 3)
					printf("  voxel (%lld %lld %lld) density %g, bound %u\n",
					       (long long)x, (long long)y, (long long)z, tx.density, bound);
			}
	for (int k = 0; k < samples; k++) {
		double p[3] = {(J + urand(rng)) * B[0], (I + urand(rng)) * B[1], urand(rng) * B[2]};
		loom_texel tx;
		int64_t u = ((int64_t)floor(p[1] - I * B[1]) / cell[1]) * nsx +
		            (int64_t)floor(p[0] - J * B[0]) / cell[0];
		uint8_t bound = tb[u * nzc + (int64_t)floor(p[2]) / cell[2]];
		CHECK_EQ_INT(loom_texture_sample(t, p, LOOM_FILTER_TRILINEAR, &tx), LOOM_OK);
		if (tx.density > (float)bound / 255.0f * 1.0001f && (*under)++ < 3)
			printf("  trilinear (%g %g %g) density %g, bound %u\n", p[0], p[1], p[2],
			       tx.density, bound);
	}
}

static void test_majorant_bounds(void)
{
	loom_majorant *m = NULL;
	loom_diag d = {0};
	int64_t cell[3];
	uint8_t *nb, *tb;
	int64_t nsx, nsy, nzc;
	long under = 0, voxels = 0, filled = 0, empty_cells = 0, cells = 0, dzs = 0;
	uint64_t rng = 7;
	float *dz;

	if (!g_tex)
		return;
	CHECK_EQ_INT(loom_majorant_build(g_fab, &m, &d), LOOM_OK);
	if (!m)
		return;
	/* the default fabric has the full-rank fix: its border offsets come
	   from the edge data (checked against the tables at build), and the
	   bounds below hold with them */
	CHECK_EQ_INT(loom__majorant_border_data(m), 1);
	loom_majorant_cell_size(m, cell);
	/* cells tile a crossing: at most 8 voxels across (docs/rendering.md) */
	CHECK(cell[0] >= 1 && cell[0] <= 8 && B[0] % cell[0] == 0);
	CHECK(cell[1] >= 1 && cell[1] <= 8 && B[1] % cell[1] == 0);
	/* the size known before the build is the built grid's */
	for (uint32_t th = 1; th <= 2; th++) {
		size_t pre = 0;
		CHECK_EQ_INT(loom_majorant_size(g_fab, th, &pre, &d), LOOM_OK);
		CHECK_EQ_INT(pre, loom_majorant_bytes(m, th));
	}
	CHECK(cell[2] >= 1 && (B[2] + cell[2] - 1) / cell[2] <= 64);
	nsx = B[0] / cell[0];
	nsy = B[1] / cell[1];
	nzc = ((int64_t)B[2] + cell[2] - 1) / cell[2];
	nb = malloc((size_t)(nsx * nsy * nzc));
	tb = malloc((size_t)(nsx * nsy * nzc));
	CHECK(loom_majorant_bytes(m, 1) < loom_majorant_bytes(m, 2));
	dz = malloc((size_t)B[0] * B[1] * sizeof *dz);
	for (int64_t I = -3; I < 7; I++)
		for (int64_t J = -3; J < 7; J++) {
			CHECK_EQ_INT(loom_majorant_bound(m, LOOM_FILTER_NEAREST, I, J, nb), LOOM_OK);
			CHECK_EQ_INT(loom_majorant_bound(m, LOOM_FILTER_TRILINEAR, I, J, tb), LOOM_OK);
			if (dz && loom_fabric_dz(g_fab, I, J, dz) == LOOM_OK)
				for (uint32_t k = 0; k < B[0] * B[1]; k++)
					dzs += lroundf(dz[k]) != 0;
			for (int64_t c = 0; c < nsx * nsy * nzc; c++) {
				cells++;
				empty_cells += nb[c] == 0;
				if (tb[c] < nb[c])
					under++; /* trilinear covers more: never smaller */
			}
			crossing_vs_bounds(g_tex, I, J, cell, nb, tb, 200, &rng, &under, &voxels,
			                   &filled);
		}
	printf("  %ld voxels checked, %ld of %ld cells empty, %ld columns with dz != 0\n",
	       voxels, empty_cells, cells, dzs);
	CHECK_EQ_INT((int)under, 0);
	CHECK(empty_cells > 0 && empty_cells < cells);
	CHECK(dzs > 0); /* the edge fix moved columns: the dz range is exercised */
	CHECK_EQ_INT(loom_majorant_bound(m, 5, 0, 0, nb), LOOM_EINVAL);
	free(dz);
	free(nb);
	free(tb);
	loom_majorant_free(m);
}

/* A crossing whose whole border the edge fix raises (its source block's
   edges lowered in the fabric's tables, as if the block lay lower in z):
   the screened fix sinks back towards 0 inside, below the border's least
   value, so the majorant's offset range must hold 0, not only the border
   columns' range (dz_range).  Every voxel of the crossing and its eight
   neighbours at or below its cell's nearest bound, trilinear samples
   below the trilinear bound.  With the border's range alone the interior
   columns' cloth lay under cells bounded by 0. */
static void test_majorant_raised_block(void)
{
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_majorant *m = NULL;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_fabric_source src;
	loom_diag d = {0};
	int64_t I = -1, J = -1, cell[3], nsx, nsy, nzc;
	float *dz = NULL, blo = INFINITY, ilo = INFINITY;
	uint8_t *nb = NULL, *tb = NULL;
	long under = 0, voxels = 0, filled = 0;
	uint64_t rng = 3;

	if (!g_fab)
		return;
	CHECK_EQ_INT(loom_fabric_synthesize(g_design, g_db, db_path, NULL, &f, &d), LOOM_OK);
	if (!f)
		return;
	/* a crossing whose source block is none of its neighbours' */
	for (int64_t i = 0; i < (int64_t)g_design->rows && I < 0; i++)
		for (int64_t j = 0; j < (int64_t)g_design->cols && I < 0; j++) {
			loom_synth_nbhd *n = &src.nbhd;
			CHECK_EQ_INT(loom_fabric_source_at(f, i, j, &src), LOOM_OK);
			if (n->self != n->n && n->self != n->s && n->self != n->w &&
			    n->self != n->e) {
				I = i;
				J = j;
			}
		}
	CHECK(I >= 0);
	dz = malloc(sizeof(float) * B[0] * B[1]);
	if (I < 0 || !dz)
		goto done;
	/* and its corner columns, which the corner term reads from the
	   fabric's profiles */
	lower_block(f->ef, src.nbhd.self, 3.0f * (float)B[2],
	            f->heights + (size_t)src.nbhd.self * LOOM_EDGE_RECORD(B[0], B[1]));
	CHECK_EQ_INT(loom_fabric_dz(f, I, J, dz), LOOM_OK);
	for (uint32_t y = 0; y < B[1]; y++)
		for (uint32_t x = 0; x < B[0]; x++) {
			float v = dz[y * B[0] + x];
			if ((x == 0 || x == B[0] - 1) && (y == 0 || y == B[1] - 1))
				continue; /* the corner term's */
			if (x == 0 || y == 0 || x == B[0] - 1 || y == B[1] - 1)
				blo = v < blo ? v : blo;
			else
				ilo = v < ilo ? v : ilo;
		}
	printf("  crossing (%lld,%lld): border offsets >= %.2f, interior down to %.2f\n",
	       (long long)I, (long long)J, blo, ilo);
	CHECK(blo > 1.0f && ilo < blo - 1.5f); /* the premise */
	o.budget_bytes = (size_t)8 << 20;
	CHECK_EQ_INT(loom_texture_open(f, g_db, &o, &t, &d), LOOM_OK);
	CHECK_EQ_INT(loom_majorant_build(f, &m, &d), LOOM_OK);
	if (!t || !m)
		goto done;
	loom_majorant_cell_size(m, cell);
	nsx = B[0] / cell[0];
	nsy = B[1] / cell[1];
	nzc = ((int64_t)B[2] + cell[2] - 1) / cell[2];
	nb = malloc((size_t)(nsx * nsy * nzc));
	tb = malloc((size_t)(nsx * nsy * nzc));
	if (!nb || !tb)
		goto done;
	for (int64_t ci = I - 1; ci <= I + 1; ci++)
		for (int64_t cj = J - 1; cj <= J + 1; cj++) {
			CHECK_EQ_INT(loom_majorant_bound(m, LOOM_FILTER_NEAREST, ci, cj, nb), LOOM_OK);
			CHECK_EQ_INT(loom_majorant_bound(m, LOOM_FILTER_TRILINEAR, ci, cj, tb),
			             LOOM_OK);
			crossing_vs_bounds(t, ci, cj, cell, nb, tb, 2000, &rng, &under, &voxels,
			                   &filled);
		}
	printf("  %ld voxels with density, %ld above their bound\n", filled, under);
	CHECK(filled > 0);
	CHECK_EQ_INT((int)under, 0);
done:
	free(nb);
	free(tb);
	free(dz);
	loom_majorant_free(m);
	loom_texture_close(t);
	loom_fabric_free(f);
}

/* The fabric's majorant grid and the nearest-filter grid source over the
   shared texture; 0 (nothing to free) when there is no texture or a call
   failed (checked). */
static int nearest_grid(loom_majorant **m, loom_volume_source *src)
{
	loom_diag d = {0};

	*m = NULL;
	if (!g_tex)
		return 0;
	CHECK_EQ_INT(loom_majorant_build(g_fab, m, &d), LOOM_OK);
	if (!*m)
		return 0;
	CHECK_EQ_INT(loom_texture_volume_source_grid(g_tex, g_fab, LOOM_FILTER_NEAREST, *m, src),
	             LOOM_OK);
	return 1;
}

/* The grid source's lookups (nearest: loom__texture_medium, which writes
   the medium sample without a texel between; trilinear: through a texel)
   equal loom_texture_sample's texel as a medium sample, every field
   written, at random points of 6 x 6 crossings (negative ones too), bit
   for bit. */
static void test_grid_lookup(void)
{
	uint64_t rng = 99;
	long differ = 0, dense = 0;

	for (int filter = LOOM_FILTER_NEAREST; filter <= LOOM_FILTER_TRILINEAR; filter++) {
		loom_majorant *m = NULL;
		loom_volume_source src;
		void *th;
		if (!nearest_grid(&m, &src))
			return;
		if (filter != LOOM_FILTER_NEAREST)
			CHECK_EQ_INT(loom_texture_volume_source_grid(g_tex, g_fab, filter, m, &src),
			             LOOM_OK);
		th = src.thread_init(src.ctx);
		CHECK(th != NULL);
		for (int k = 0; th && k < 20000; k++) {
			double p[3] = {(urand(&rng) * 6 - 2) * B[0], (urand(&rng) * 6 - 2) * B[1],
			               urand(&rng) * B[2]};
			loom_medium_sample got, want;
			loom_texel tx;
			memset(&got, 0x55, sizeof got);
			memset(&want, 0, sizeof want);
			CHECK_EQ_INT(src.lookup(th, p, &got), LOOM_OK);
			CHECK_EQ_INT(loom_texture_sample(g_tex, p, filter, &tx), LOOM_OK);
			loom__texel_medium(&tx, &want);
			dense += want.density > 0;
			differ += memcmp(&got, &want, sizeof got) != 0;
		}
		if (th)
			src.thread_done(src.ctx, th);
		loom_majorant_free(m);
	}
	printf("  %ld of 40000 lookups differ (%ld dense)\n", differ, dense);
	CHECK_EQ_INT((int)differ, 0);
	CHECK(dense > 4000);
}

/* The grid source's z span of a cell column never hides a non-zero cell:
   every z cell outside it has bound 0 (against cell_max of every cell of
   10 x 10 crossings, nearest), and it is tighter than the slab somewhere.
   Trilinear gives the whole slab. */
static void test_majorant_zspan(void)
{
	loom_majorant *m = NULL;
	loom_volume_source src;
	void *th;
	int64_t cell[3], nzc, c[3], lo, hi;
	long hidden = 0, columns = 0, tight = 0, skipped = 0;

	if (!nearest_grid(&m, &src))
		return;
	CHECK(src.cell_zspan != NULL);
	loom_majorant_cell_size(m, cell);
	nzc = ((int64_t)B[2] + cell[2] - 1) / cell[2];
	th = src.thread_init(src.ctx);
	CHECK(th != NULL);
	for (c[1] = -3 * (B[1] / cell[1]); th && c[1] < 7 * (B[1] / cell[1]); c[1]++)
		for (c[0] = -3 * (B[0] / cell[0]); c[0] < 7 * (B[0] / cell[0]); c[0]++) {
			c[2] = 0;
			CHECK_EQ_INT(src.cell_zspan(th, c, &lo, &hi), LOOM_OK);
			columns++;
			tight += lo > 0 || hi < nzc - 1;
			for (c[2] = 0; c[2] < nzc; c[2]++) {
				float bound = 0;
				if (c[2] >= lo && c[2] <= hi)
					continue;
				skipped++;
				CHECK_EQ_INT(src.cell_max(th, c, &bound), LOOM_OK);
				if (bound > 0 && hidden++ < 3)
					printf("  cell (%lld %lld %lld) bound %g outside span [%lld %lld]\n",
					       (long long)c[0], (long long)c[1], (long long)c[2], bound,
					       (long long)lo, (long long)hi);
			}
		}
	printf("  z spans: %ld columns, %ld tighter than the slab, %ld cells outside\n",
	       columns, tight, skipped);
	CHECK_EQ_INT((int)hidden, 0);
	CHECK(tight > columns / 2);
	if (th)
		src.thread_done(src.ctx, th);
	CHECK_EQ_INT(loom_texture_volume_source_grid(g_tex, g_fab, LOOM_FILTER_TRILINEAR, m,
	                                             &src), LOOM_OK);
	th = src.thread_init(src.ctx);
	c[0] = c[1] = c[2] = 0;
	CHECK(th && src.cell_zspan(th, c, &lo, &hi) == LOOM_OK && lo == 0 && hi == nzc - 1);
	if (th)
		src.thread_done(src.ctx, th);
	loom_majorant_free(m);
}

/* The grid source's cells (nearest) are exact: every cell's bound is its
   largest voxel density (as raw_bound widens a byte), never below it, and
   once a cell column has been queried its z span is exactly its first and
   last non-empty layer (every voxel of 8 x 8 crossings, negative indices
   included, against loom_texture_voxel). */
static void test_majorant_exact(void)
{
	loom_majorant *m = NULL;
	loom_volume_source src;
	void *th;
	int64_t cell[3], nzc, c[3], lo, hi;
	long wrong = 0, cells = 0, nonzero = 0, spans = 0;

	if (!nearest_grid(&m, &src))
		return;
	loom_majorant_cell_size(m, cell);
	CHECK_EQ_INT((int)cell[2], 1);
	nzc = B[2];
	th = src.thread_init(src.ctx);
	CHECK(th != NULL);
	for (c[1] = -2 * (B[1] / cell[1]); th && c[1] < 6 * (B[1] / cell[1]); c[1]++)
		for (c[0] = -2 * (B[0] / cell[0]); c[0] < 6 * (B[0] / cell[0]); c[0]++) {
			int64_t first = -1, last = -1;
			for (c[2] = 0; c[2] < nzc; c[2]++) {
				float bound = -1, dmax = 0, want;
				CHECK_EQ_INT(src.cell_max(th, c, &bound), LOOM_OK);
				for (int64_t y = c[1] * cell[1]; y < (c[1] + 1) * cell[1]; y++)
					for (int64_t x = c[0] * cell[0]; x < (c[0] + 1) * cell[0]; x++) {
						loom_texel tx;
						CHECK_EQ_INT(loom_texture_voxel(g_tex, x, y, c[2], &tx), LOOM_OK);
						dmax = tx.density > dmax ? tx.density : dmax;
					}
				want = dmax > 0 ? (float)lroundf(dmax * 255.0f) / 255.0f * 1.0001f : 0.0f;
				cells++;
				nonzero += dmax > 0;
				if (dmax > 0 && first < 0)
					first = c[2];
				if (dmax > 0)
					last = c[2];
				if ((bound != want || bound < dmax) && wrong++ < 3)
					printf("  cell (%lld %lld %lld) bound %g, largest density %g\n",
					       (long long)c[0], (long long)c[1], (long long)c[2], bound, dmax);
			}
			c[2] = 0;
			CHECK_EQ_INT(src.cell_zspan(th, c, &lo, &hi), LOOM_OK);
			if (first < 0 ? lo <= hi : (lo != first || hi != last)) {
				if (wrong++ < 3)
					printf("  column (%lld %lld) span [%lld %lld], non-empty [%lld %lld]\n",
					       (long long)c[0], (long long)c[1], (long long)lo, (long long)hi,
					       (long long)first, (long long)last);
			}
			spans++;
		}
	printf("  exact bounds: %ld cells (%ld non-empty), %ld column spans\n", cells,
	       nonzero, spans);
	CHECK_EQ_INT((int)wrong, 0);
	CHECK(nonzero > 0 && nonzero < cells);
	if (th)
		src.thread_done(src.ctx, th);
	loom_majorant_free(m);
}

/* ---- renders ------------------------------------------------------------- */

static void init_opt(loom_render_options *o, uint32_t w, uint32_t h, uint32_t spp)
{
	loom_render_options def = LOOM_RENDER_OPTIONS_INIT;
	*o = def;
	o->width = w;
	o->height = h;
	o->spp = spp;
	o->max_depth = 16;
	o->density_scale = 0.6;
	o->camera.kind = LOOM_CAMERA_PINHOLE;
	o->camera.eye[0] = 20;
	o->camera.eye[1] = -25;
	o->camera.eye[2] = 30;
	o->camera.target[0] = 24;
	o->camera.target[1] = 20;
	o->camera.target[2] = 4;
	o->camera.up[0] = 0;
	o->camera.up[1] = 0;
	o->camera.up[2] = 1;
	o->camera.fov_y_deg = 35;
	o->light.dir[0] = -0.3;
	o->light.dir[1] = -0.5;
	o->light.dir[2] = 1.0;
	o->env[0] = o->env[1] = o->env[2] = 0.2f;
}

static void test_grid_renders(void)
{
	loom_majorant *m = NULL;
	loom_volume_source grid, glob;
	loom_render_options o;
	loom_render_stats sg, sl;
	loom_diag d = {0};
	enum { W = 12, H = 9, K = 8 };
	float *a, *b, *c;
	double sum[2][W * H * 3], sq[2][W * H * 3], mean[2] = {0, 0};
	int big = 0, n = W * H * 3;

	if (!g_tex)
		return;
	CHECK_EQ_INT(loom_majorant_build(g_fab, &m, &d), LOOM_OK);
	if (!m)
		return;
	CHECK_EQ_INT(loom_texture_volume_source_grid(g_tex, g_fab, LOOM_FILTER_NEAREST, m,
	                                             &grid), LOOM_OK);
	CHECK_EQ_INT(loom_texture_volume_source(g_tex, g_fab, LOOM_FILTER_NEAREST, &glob),
	             LOOM_OK);
	a = malloc(W * H * 3 * sizeof *a);
	b = malloc(W * H * 3 * sizeof *b);
	c = malloc(W * H * 3 * sizeof *c);
	/* determinism over thread counts, through the grid */
	init_opt(&o, W, H, 16);
	o.tile = 4;
	o.threads = 1;
	CHECK_EQ_INT(loom_render(&grid, &o, a, &sg, &d), LOOM_OK);
	o.threads = 2;
	CHECK_EQ_INT(loom_render(&grid, &o, b, NULL, &d), LOOM_OK);
	o.threads = 3;
	CHECK_EQ_INT(loom_render(&grid, &o, c, NULL, &d), LOOM_OK);
	CHECK(memcmp(a, b, W * H * 3 * sizeof *a) == 0);
	CHECK(memcmp(a, c, W * H * 3 * sizeof *a) == 0);
	CHECK(sg.cells > 0);
	/* the optional hooks change nothing but the cost: without the
	   column z spans that pass a column's empty layers with no cell_max
	   calls (h = 0), or without the density-first test of tentative
	   collisions (camera, scattered and shadow rays; h = 1, on a
	   trilinear grid: a nearest grid's exact cells do not offer it), the
	   same bytes, lookups and tentative collisions */
	CHECK(grid.density == NULL && grid.cell_zspan != NULL);
	for (int h = 0; h < 2; h++) {
		loom_volume_source s = grid, r = grid;
		loom_render_stats sn, sr = sg;
		o.threads = 2;
		if (h) {
			CHECK_EQ_INT(loom_texture_volume_source_grid(g_tex, g_fab, LOOM_FILTER_TRILINEAR,
			                                             m, &r), LOOM_OK);
			CHECK(r.density != NULL);
			CHECK_EQ_INT(loom_render(&r, &o, a, &sr, &d), LOOM_OK);
			s = r;
			s.density = NULL;
		} else {
			s.cell_zspan = NULL;
		}
		CHECK_EQ_INT(loom_render(&s, &o, b, &sn, &d), LOOM_OK);
		if (!h) { /* the box hook alone off: the same again, more cells */
			loom_render_stats sb;
			loom_volume_source nb = grid;
			CHECK(grid.cell_zbox != NULL);
			nb.cell_zbox = NULL;
			CHECK_EQ_INT(loom_render(&nb, &o, c, &sb, &d), LOOM_OK);
			CHECK(memcmp(a, c, W * H * 3 * sizeof *a) == 0);
			CHECK(sb.lookups == sr.lookups);
			CHECK(sb.cells > sr.cells && sb.cells < sn.cells);
			/* a source built before cell_zbox (its size ends there) */
			nb = grid;
			nb.size = offsetof(loom_volume_source, cell_zbox);
			CHECK_EQ_INT(loom_render(&nb, &o, c, &sb, &d), LOOM_OK);
			CHECK(memcmp(a, c, W * H * 3 * sizeof *a) == 0);
		}
		CHECK(memcmp(a, b, W * H * 3 * sizeof *a) == 0);
		CHECK(sn.lookups == sr.lookups);
		CHECK(sn.scatterings == sr.scatterings);
		/* cells: the spans also let the tracker skip a column's
		   empty layers without visiting them (loom__dda_skip_z) */
		CHECK(h ? sn.cells == sr.cells : sn.cells > sr.cells);
	}
	/* back to nearest (the grid serves one filter at a time) */
	CHECK_EQ_INT(loom_texture_volume_source_grid(g_tex, g_fab, LOOM_FILTER_NEAREST, m,
	                                             &grid), LOOM_OK);
	/* the same image, and fewer lookups, than the global majorant */
	o.flags = LOOM_RENDER_GLOBAL_MAJORANT;
	CHECK_EQ_INT(loom_render(&grid, &o, b, &sl, &d), LOOM_OK);
	CHECK_EQ_INT((int)sl.cells, 0);
	printf("  lookups per path: grid %.1f, global %.1f\n",
	       (double)sg.lookups / sg.paths, (double)sl.lookups / sl.paths);
	CHECK(sg.lookups * 2 < sl.lookups);
	memset(sum, 0, sizeof sum);
	memset(sq, 0, sizeof sq);
	o.threads = 2;
	o.spp = 64;
	for (int v = 0; v < 2; v++)
		for (int k = 0; k < K; k++) {
			o.flags = v ? LOOM_RENDER_GLOBAL_MAJORANT : 0;
			o.seed = 1000 + (uint64_t)k * 17 + (uint64_t)v * 5;
			CHECK_EQ_INT(loom_render(v ? &glob : &grid, &o, a, NULL, &d), LOOM_OK);
			for (int i = 0; i < n; i++) {
				sum[v][i] += a[i];
				sq[v][i] += (double)a[i] * a[i];
				mean[v] += a[i];
			}
		}
	{
		double se_img = 0, zimg;
		for (int i = 0; i < n; i++) {
			double m0 = sum[0][i] / K, m1 = sum[1][i] / K;
			double v0 = (sq[0][i] / K - m0 * m0) * K / (K - 1);
			double v1 = (sq[1][i] / K - m1 * m1) * K / (K - 1);
			double se = sqrt(fmax(v0, 0) / K + fmax(v1, 0) / K) + 1e-6;
			if (fabs(m0 - m1) / se > 5.0)
				big++;
			se_img += (fmax(v0, 0) + fmax(v1, 0)) / K;
		}
		zimg = fabs(mean[0] - mean[1]) / K / sqrt(se_img);
		printf("  image mean grid %.5f, global %.5f (z %.2f), %d of %d "
		       "channels with |z| > 5\n", mean[0] / K / n, mean[1] / K / n, zimg,
		       big, n);
		CHECK(zimg < 4.0);
		CHECK(big <= n / 100);
	}
	free(a);
	free(b);
	free(c);
	loom_majorant_free(m);
}

static int fail_cell(void *ctx, const int64_t c[3], float *bound)
{
	(void)ctx;
	(void)c;
	*bound = 1.0f;
	return LOOM_ECORRUPT;
}

static int const_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	(void)ctx;
	(void)p;
	memset(out, 0, sizeof *out);
	out->density = 1.0f;
	out->albedo[0] = out->albedo[1] = out->albedo[2] = 0.5f;
	return LOOM_OK;
}

static void test_grid_errors(void)
{
	loom_volume_source s = LOOM_VOLUME_SOURCE_INIT;
	loom_render_options o;
	loom_diag d = {0};
	float rgb[4 * 4 * 3];

	s.nz = 8;
	s.lookup = const_lookup;
	s.cell_max = fail_cell;
	s.cell[0] = s.cell[1] = s.cell[2] = 4;
	init_opt(&o, 4, 4, 1);
	o.camera.target[0] = 0;
	o.camera.target[1] = 0;
	o.camera.eye[0] = 0;
	o.camera.eye[1] = -1;
	CHECK_EQ_INT(loom_render(&s, &o, rgb, NULL, &d), LOOM_ECORRUPT);
	o.flags = LOOM_RENDER_GLOBAL_MAJORANT; /* the grid is not consulted */
	CHECK_EQ_INT(loom_render(&s, &o, rgb, NULL, &d), LOOM_OK);
	o.flags = 0;
	s.cell[2] = 0;
	CHECK_EQ_INT(loom_render(&s, &o, rgb, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "majorant cell");
}

/* The tracer's per-roughness area rows (loom__mf_row) against quadrature
   and against the table they are filled from (loom_microflake_area), at
   random points: log-spaced s, cosines uniform and crowded near the fibre
   axis where A changes fastest.  The rows add at most 5e-4 of relative
   error to the table's own (which is largest there, for s near 0.005). */
static void test_area_rows(void)
{
	uint64_t rng = 0x5eed;
	double maxrel = 0, maxtab = 0, maxadd = 0;
	loom__mf_row *r = malloc(sizeof *r);

	CHECK(r != NULL);
	if (!r)
		return;
	for (int k = 0; k < 400; k++) {
		double s = exp(log(0.005) + loom_rng_uniform(&rng) * log(200.0));
		double u = loom_rng_uniform(&rng);
		double c = k & 1 ? u : 1.0 - u * u * u * u * 0.01;
		double a, e, tb;
		loom__mf_row_fill(r, s);
		a = loom__mf_row_area(r, k & 2 ? -c : c);
		tb = loom_microflake_area(s, c);
		e = loom_microflake_area_exact(s, c);
		maxrel = fmax(maxrel, fabs(a - e) / e);
		maxtab = fmax(maxtab, fabs(tb - e) / e);
		maxadd = fmax(maxadd, fabs(a - e) / e - fabs(tb - e) / e);
	}
	printf("  area rows: max relative error %.2g (table %.2g, added %.2g)\n",
	       maxrel, maxtab, maxadd);
	CHECK(maxrel < 3e-3);
	CHECK(maxadd < 5e-4);
	/* the row's ends are the table's */
	loom__mf_row_fill(r, 0.2);
	CHECK(fabs(loom__mf_row_area(r, 1.0) - loom_microflake_area(0.2, 1.0)) < 1e-12);
	CHECK(fabs(loom__mf_row_area(r, 0.0) - loom_microflake_area(0.2, 0.0)) < 1e-12);
	free(r);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_render_grid");
	RUN(test_dda_brute_force);
	RUN(test_dda_skip);
	RUN(test_area_rows);
	RUN(setup);
	RUN(test_majorant_bounds);
	RUN(test_majorant_raised_block);
	RUN(test_majorant_zspan);
	RUN(test_grid_lookup);
	RUN(test_majorant_exact);
	RUN(test_grid_renders);
	RUN(test_grid_errors);
	loom_texture_close(g_tex);
	loom_fabric_free(g_fab);
	loom_design_free(g_design);
	loom_db_close(g_db);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
