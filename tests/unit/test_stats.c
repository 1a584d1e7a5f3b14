/* tests/unit/test_stats.c - loom_design_analyze on hand-checked patterns and
   against a brute-force reference on seeded random designs. */
#include "check.h"
#include "loom.h"

#include <math.h>

/* A design from rows of '0'/'1'. */
static loom_design *from_rows(const char *const *rows)
{
	loom_design *d = NULL;
	uint32_t nr = 0, nc = (uint32_t)strlen(rows[0]);

	while (rows[nr])
		nr++;
	if (loom_design_new(nr, nc, &d) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < nr; i++)
		for (uint32_t j = 0; j < nc; j++)
			d->weave[(size_t)i * nc + j] = (uint8_t)(rows[i][j] == '1');
	return d;
}

static loom_design *make(const char *name, uint32_t rows, uint32_t cols)
{
	loom_weave_params p;
	loom_design *d = NULL;
	if (loom_weave_parse(name, &p, NULL) || loom_design_make(&p, rows, cols, &d, NULL))
		return NULL;
	return d;
}

static void twill_2_3(void)
{
	loom_design *d = make("twill:2/3", 10, 15);
	loom_design_stats st;

	CHECK(d != NULL);
	if (!d)
		return;
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 5);
	CHECK_EQ_INT(st.repeat_cols, 5);
	CHECK_EQ_INT(st.warp_over, 60);   /* 2 of every 5 */
	CHECK_EQ_INT(st.max_warp_float, 2);
	CHECK_EQ_INT(st.max_weft_float, 3);
	CHECK(fabs(st.mean_warp_float - 2.0) < 1e-12);
	CHECK(fabs(st.mean_weft_float - 3.0) < 1e-12);
	CHECK_EQ_INT(st.types_used, 2);
	CHECK_EQ_INT(st.interlaced, 1);
	loom_design_free(d);
}

static void plain_and_satin(void)
{
	loom_design *d = make("plain", 4, 6);
	loom_design_stats st;

	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 2);
	CHECK_EQ_INT(st.repeat_cols, 2);
	CHECK_EQ_INT(st.max_warp_float, 1);
	CHECK_EQ_INT(st.max_weft_float, 1);
	loom_design_free(d);
	d = make("satin:1/7", 0, 0); /* 8x8, 1 over then 7 under */
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 8);
	CHECK_EQ_INT(st.repeat_cols, 8);
	CHECK_EQ_INT(st.max_warp_float, 1);
	CHECK_EQ_INT(st.max_weft_float, 7);
	CHECK(fabs(st.mean_weft_float - 7.0) < 1e-12);
	CHECK_EQ_INT(st.interlaced, 1);
	loom_design_free(d);
}

/* Floats that wrap around the repeat's edges. */
static void wrapping_floats(void)
{
	/* column 0 is 1,1,0,1: one float of 3 through the wrap (rows 3,0,1);
	   column 1 is 0,0,1,1: one float of 2.  Rows' 0-runs: 1,1,1, none.
	   Row 3 is all 1s, so the cloth is not interlaced. */
	static const char *const w[] = {"10", "10", "01", "11", NULL};
	static const char *const w2[] = {"01100", "11111", "00000", NULL};
	loom_design *d = from_rows(w);
	loom_design_stats st;

	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.max_warp_float, 3);
	CHECK(fabs(st.mean_warp_float - 2.5) < 1e-12);
	CHECK_EQ_INT(st.max_weft_float, 1);
	CHECK(fabs(st.mean_weft_float - 1.0) < 1e-12);
	CHECK_EQ_INT(st.interlaced, 0);
	CHECK_EQ_INT(st.repeat_rows, 4);
	CHECK_EQ_INT(st.repeat_cols, 2);
	CHECK_EQ_INT(st.warp_over, 5);
	loom_design_free(d);
	/* row 0: zeros at 0,3,4 form one cyclic run of 3; row 2 is one endless
	   run of 5.  Columns 1,2 are 1,1,0 (run 2), columns 0,3,4 are 0,1,0
	   (run 1): mean (1+2+2+1+1)/5. */
	d = from_rows(w2);
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.max_weft_float, 5);
	CHECK(fabs(st.mean_weft_float - 4.0) < 1e-12); /* 8 zeros, 2 runs */
	CHECK_EQ_INT(st.max_warp_float, 2);
	CHECK(fabs(st.mean_warp_float - 7.0 / 5.0) < 1e-12);
	CHECK_EQ_INT(st.repeat_rows, 3);
	CHECK_EQ_INT(st.repeat_cols, 5);
	loom_design_free(d);
}

static void degenerate(void)
{
	loom_design *d;
	loom_design_stats st;

	CHECK_EQ_INT(loom_design_new(3, 4, &d), LOOM_OK); /* all 0 */
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 1);
	CHECK_EQ_INT(st.repeat_cols, 1);
	CHECK_EQ_INT(st.max_weft_float, 4);
	CHECK(fabs(st.mean_weft_float - 4.0) < 1e-12);
	CHECK_EQ_INT(st.max_warp_float, 0);
	CHECK(st.mean_warp_float == 0.0);
	CHECK_EQ_INT(st.interlaced, 0);
	memset(d->weave, 1, 12);
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.max_warp_float, 3);
	CHECK_EQ_INT(st.max_weft_float, 0);
	CHECK_EQ_INT(st.warp_over, 12);
	loom_design_free(d);
	CHECK_EQ_INT(loom_design_new(1, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 1);
	CHECK_EQ_INT(st.max_weft_float, 1);
	CHECK_EQ_INT(loom_design_analyze(NULL, &st), LOOM_EINVAL);
	CHECK_EQ_INT(loom_design_analyze(d, NULL), LOOM_EINVAL);
	loom_design_free(d);
}

static void repeats(void)
{
	/* a 3x2 tile repeated to 6x4, then one cell changed */
	static const char *const tile[] = {"10", "11", "00", NULL};
	loom_design *d;
	loom_design_stats st;

	CHECK_EQ_INT(loom_design_new(6, 4, &d), LOOM_OK);
	for (uint32_t i = 0; i < 6; i++)
		for (uint32_t j = 0; j < 4; j++)
			d->weave[i * 4 + j] = (uint8_t)(tile[i % 3][j % 2] == '1');
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 3);
	CHECK_EQ_INT(st.repeat_cols, 2);
	d->weave[0] ^= 1;
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 6);
	CHECK_EQ_INT(st.repeat_cols, 4);
	loom_design_free(d);
	/* herringbone 2/2 period 4 is 4 x 8; tiled 8 x 24 keeps that repeat */
	d = make("herringbone:2/2:period=4", 8, 24);
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.repeat_rows, 4);
	CHECK_EQ_INT(st.repeat_cols, 8);
	loom_design_free(d);
}

static void types_used(void)
{
	loom_design *d = make("twill:2/2", 4, 4);
	loom_design_stats st;

	CHECK_EQ_INT(loom_design_set_types(d, 6), LOOM_OK);
	d->warp_type[5] = 3;
	d->weft_type[7] = 5;
	d->weft_type[8] = 5;
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.types_used, 4); /* 0, 1, 3, 5 */
	memset(d->warp_type, 2, 16);
	memset(d->weft_type, 2, 16);
	CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
	CHECK_EQ_INT(st.types_used, 1);
	loom_design_free(d);
}

/* ---- brute force --------------------------------------------------------- */

static uint64_t rng_state;
static uint32_t rnd(uint32_t n)
{
	uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return (uint32_t)((z ^ (z >> 31)) % n);
}

typedef struct ref_stats {
	uint32_t rr, rc, maxw, maxf;
	double meanw, meanf;
	int inter;
} ref_stats;

/* Walk each run from its start cell (a 1 whose predecessor is 0). */
static void ref_runs(const loom_design *d, int along_cols, int val,
                     uint32_t *max, double *mean)
{
	uint32_t outer = along_cols ? d->cols : d->rows;
	uint32_t len = along_cols ? d->rows : d->cols;
	uint64_t total = 0, runs = 0;

	*max = 0;
	for (uint32_t o = 0; o < outer; o++) {
		uint32_t count = 0;
		for (uint32_t k = 0; k < len; k++)
			count += (along_cols ? loom_design_at(d, k, o) : loom_design_at(d, o, k)) == val;
		if (count == len) {
			runs++;
			total += len;
			*max = *max > len ? *max : len;
			continue;
		}
		for (uint32_t k = 0; k < len; k++) {
			uint32_t prev = (k + len - 1) % len, n = 0;
			int v = along_cols ? loom_design_at(d, k, o) : loom_design_at(d, o, k);
			int pv = along_cols ? loom_design_at(d, prev, o) : loom_design_at(d, o, prev);
			if (v != val || pv == val)
				continue;
			while (n < len && (along_cols ? loom_design_at(d, (k + n) % len, o)
			                              : loom_design_at(d, o, (k + n) % len)) == val)
				n++;
			runs++;
			total += n;
			*max = *max > n ? *max : n;
		}
	}
	*mean = runs ? (double)total / (double)runs : 0;
}

static uint32_t ref_period(const loom_design *d, int rows)
{
	uint32_t n = rows ? d->rows : d->cols;
	for (uint32_t p = 1; p <= n; p++) {
		int ok = n % p == 0;
		for (uint32_t i = 0; ok && i < d->rows; i++)
			for (uint32_t j = 0; ok && j < d->cols; j++)
				ok = loom_design_at(d, i, j) ==
				     (rows ? loom_design_at(d, (i + p) % n, j)
				           : loom_design_at(d, i, (j + p) % n));
		if (ok)
			return p;
	}
	return n;
}

static void reference(const loom_design *d, ref_stats *r)
{
	r->rr = ref_period(d, 1);
	r->rc = ref_period(d, 0);
	ref_runs(d, 1, 1, &r->maxw, &r->meanw);
	ref_runs(d, 0, 0, &r->maxf, &r->meanf);
	r->inter = 1;
	for (uint32_t i = 0; i < d->rows; i++) {
		uint32_t ones = 0;
		for (uint32_t j = 0; j < d->cols; j++)
			ones += loom_design_at(d, i, j);
		if (ones == 0 || ones == d->cols)
			r->inter = 0;
	}
	for (uint32_t j = 0; j < d->cols; j++) {
		uint32_t ones = 0;
		for (uint32_t i = 0; i < d->rows; i++)
			ones += loom_design_at(d, i, j);
		if (ones == 0 || ones == d->rows)
			r->inter = 0;
	}
}

static loom_design *random_design(void)
{
	uint32_t tr = 1 + rnd(6), tc = 1 + rnd(6);
	uint32_t rows = tr * (1 + rnd(4)), cols = tc * (1 + rnd(4));
	uint8_t tile[36];
	loom_design *d;
	int density = (int)rnd(5); /* 0..4: from sparse to dense */

	for (int k = 0; k < 36; k++)
		tile[k] = (uint8_t)((int)rnd(4) < density);
	if (loom_design_new(rows, cols, &d))
		return NULL;
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++)
			d->weave[i * cols + j] = tile[(i % tr) * 6 + j % tc];
	if (rnd(3) == 0)
		d->weave[rnd(rows * cols)] ^= 1;
	return d;
}

static void brute_force(void)
{
	rng_state = check_seed();
	for (int it = 0; it < 2000; it++) {
		loom_design *d = random_design();
		loom_design_stats st;
		ref_stats r;
		if (!d) {
			CHECK(d != NULL);
			return;
		}
		reference(d, &r);
		CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
		if (st.repeat_rows != r.rr || st.repeat_cols != r.rc ||
		    st.max_warp_float != r.maxw || st.max_weft_float != r.maxf ||
		    fabs(st.mean_warp_float - r.meanw) > 1e-9 ||
		    fabs(st.mean_weft_float - r.meanf) > 1e-9 || st.interlaced != r.inter) {
			printf("  iteration %d (%ux%u): got repeat %ux%u floats %u/%u "
			       "%.3f/%.3f inter %d; expected %ux%u %u/%u %.3f/%.3f %d\n",
			       it, d->rows, d->cols, st.repeat_rows, st.repeat_cols,
			       st.max_warp_float, st.max_weft_float, st.mean_warp_float,
			       st.mean_weft_float, st.interlaced, r.rr, r.rc, r.maxw,
			       r.maxf, r.meanw, r.meanf, r.inter);
			CHECK(0);
			loom_design_free(d);
			return;
		}
		loom_design_free(d);
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_stats");
	RUN(twill_2_3);
	RUN(plain_and_satin);
	RUN(wrapping_floats);
	RUN(degenerate);
	RUN(repeats);
	RUN(types_used);
	RUN(brute_force);
	CHECK_MAIN_END();
}
