/* tests/unit/test_assign.c - yarn-level synthesis (engine/synth/assign.c) against
   brute-force references. */
#include "check.h"
#include "loom.h"

static uint64_t rng_state;

static uint32_t rnd(uint32_t n)
{
	rng_state = loom_synth_mix(rng_state);
	return (uint32_t)(rng_state % n);
}

/* ---- helpers ------------------------------------------------------------- */

typedef struct exdef {
	uint32_t rows, cols;
	uint8_t w[64];
	int periodic;
} exdef;

static exdef ex_from(const char *const *rows, int periodic)
{
	exdef e;
	memset(&e, 0, sizeof e);
	e.cols = (uint32_t)strlen(rows[0]);
	while (rows[e.rows]) {
		for (uint32_t c = 0; c < e.cols; c++)
			e.w[e.rows * e.cols + c] = (uint8_t)(rows[e.rows][c] == '1');
		e.rows++;
	}
	e.periodic = periodic;
	return e;
}

/* A random exemplar of 1..maxside rows/cols with both bits present. */
static exdef ex_random(uint32_t maxside)
{
	exdef e;
	memset(&e, 0, sizeof e);
	do {
		int has0 = 0, has1 = 0;
		e.rows = 1 + rnd(maxside);
		e.cols = 1 + rnd(maxside);
		if (e.rows * e.cols < 2)
			continue;
		/* sometimes a regular twill-like weave, sometimes noise */
		if (rnd(2)) {
			uint32_t over = 1 + rnd(e.rows);
			for (uint32_t r = 0; r < e.rows; r++)
				for (uint32_t c = 0; c < e.cols; c++)
					e.w[r * e.cols + c] = (uint8_t)((r + e.rows - c % e.rows) % e.rows < over);
		} else {
			for (uint32_t k = 0; k < e.rows * e.cols; k++)
				e.w[k] = (uint8_t)rnd(2);
		}
		for (uint32_t k = 0; k < e.rows * e.cols; k++) {
			has0 |= !e.w[k];
			has1 |= e.w[k];
		}
		if (has0 && has1)
			break;
	} while (1);
	e.periodic = (int)rnd(2);
	return e;
}

static loom_synth_set *make_set(const exdef *e, uint32_t n)
{
	loom_synth_exemplar ex[8];
	loom_synth_set *s = NULL;
	loom_diag diag = {0};
	for (uint32_t u = 0; u < n; u++) {
		ex[u].rows = e[u].rows;
		ex[u].cols = e[u].cols;
		ex[u].weave = e[u].w;
		ex[u].periodic = e[u].periodic;
	}
	if (loom_synth_set_new(ex, n, &s, &diag) != LOOM_OK)
		printf("  set_new: %s\n", diag.message);
	return s;
}

static loom_design *design_random(uint32_t rows, uint32_t cols)
{
	loom_design *d = NULL;
	if (loom_design_new(rows, cols, &d) != LOOM_OK)
		return NULL;
	for (size_t k = 0; k < (size_t)rows * cols; k++)
		d->weave[k] = (uint8_t)rnd(2);
	return d;
}

static loom_design *design_weave(const char *name, uint32_t rows, uint32_t cols)
{
	loom_weave_params p;
	loom_design *d = NULL;
	if (loom_weave_parse(name, &p, NULL) != LOOM_OK ||
	    loom_design_make(&p, rows, cols, &d, NULL) != LOOM_OK)
		return NULL;
	return d;
}

static unsigned ex_code(const exdef *e, uint32_t r, uint32_t c)
{
	uint32_t m = e->rows, n = e->cols;
	return (unsigned)(e->w[r * n + c] | e->w[((r + m - 1) % m) * n + c] << 1 |
	                  e->w[((r + 1) % m) * n + c] << 2 |
	                  e->w[r * n + (c + n - 1) % n] << 3 | e->w[r * n + (c + 1) % n] << 4);
}

static unsigned nmatch(unsigned a, unsigned b)
{
	unsigned x = ~(a ^ b) & 0x1eu;
	return (unsigned)__builtin_popcount(x);
}

static int assign(const loom_synth_set *s, const loom_design *d, int algo,
                  uint64_t seed, uint32_t flags, uint16_t *base)
{
	loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
	loom_diag diag = {0};
	int rc;
	o.algo = algo;
	o.seed = seed;
	o.flags = flags;
	rc = loom_synth_assign(s, d, &o, base, &diag);
	if (rc)
		printf("  assign: %s\n", diag.message);
	return rc;
}

/* ---- tests --------------------------------------------------------------- */

static void symmetries_brute_force(void)
{
	rng_state = check_seed();
	for (int trial = 0; trial < 200; trial++) {
		exdef e = ex_random(6);
		loom_synth_set *s = make_set(&e, 1);
		const uint16_t *pairs, *chain;
		uint32_t n, nc, k = 0, kc = 0;
		CHECK(s != NULL);
		if (!s)
			return;
		CHECK_EQ_INT(loom_synth_symmetries(s, 0, 0, &pairs, &n), LOOM_OK);
		CHECK_EQ_INT(loom_synth_symmetries(s, 0, 1, &chain, &nc), LOOM_OK);
		for (uint32_t dr = 0; dr < e.rows; dr++)
			for (uint32_t dc = 0; dc < e.cols; dc++) {
				int ok = 1;
				for (uint32_t r = 0; r < e.rows && ok; r++)
					for (uint32_t c = 0; c < e.cols; c++)
						if (e.w[((r + dr) % e.rows) * e.cols + (c + dc) % e.cols] !=
						    e.w[r * e.cols + c]) {
							ok = 0;
							break;
						}
				if (!ok)
					continue;
				CHECK(k < n && pairs[2 * k] == dr && pairs[2 * k + 1] == dc);
				k++;
				if (e.periodic || dr == 0) {
					CHECK(kc < nc && chain[2 * kc] == dr && chain[2 * kc + 1] == dc);
					kc++;
				}
			}
		CHECK_EQ_INT(k, n);
		CHECK_EQ_INT(kc, nc);
		loom_synth_set_free(s);
	}
}

static void candidates_brute_force(void)
{
	rng_state = check_seed() + 1;
	for (int trial = 0; trial < 100; trial++) {
		exdef e[3];
		uint32_t ne = 1 + rnd(3), K = 0, base[3];
		loom_synth_set *s;
		for (uint32_t u = 0; u < ne; u++) {
			e[u] = ex_random(5);
			base[u] = K;
			K += e[u].rows * e[u].cols;
		}
		s = make_set(e, ne);
		CHECK(s != NULL);
		if (!s)
			return;
		CHECK_EQ_INT(loom_synth_set_blocks(s), K);
		for (unsigned code = 0; code < 32; code++) {
			const uint16_t *full, *red;
			uint32_t nf, nr, mf, mr, best = 0, cnt = 0;
			loom_synth_candidates(s, code, 0, &full, &nf, &mf);
			loom_synth_candidates(s, code, 1, &red, &nr, &mr);
			for (uint32_t u = 0; u < ne; u++)
				for (uint32_t r = 0; r < e[u].rows; r++)
					for (uint32_t c = 0; c < e[u].cols; c++) {
						unsigned bc = ex_code(&e[u], r, c);
						if ((bc & 1) == (code & 1) && nmatch(bc, code) > best)
							best = nmatch(bc, code);
					}
			CHECK_EQ_INT(mf, best);
			CHECK_EQ_INT(mr, best);
			for (uint32_t u = 0; u < ne; u++)
				for (uint32_t r = 0; r < e[u].rows; r++)
					for (uint32_t c = 0; c < e[u].cols; c++) {
						unsigned bc = ex_code(&e[u], r, c);
						if ((bc & 1) == (code & 1) && nmatch(bc, code) == best) {
							CHECK(cnt < nf && full[cnt] == base[u] + r * e[u].cols + c);
							cnt++;
						}
					}
			CHECK_EQ_INT(cnt, nf);
			CHECK(nr >= 1 && nr <= nf);
			/* every full candidate is a chain image of a reduced one */
			for (uint32_t a = 0; a < nf; a++) {
				loom_synth_block bi;
				const uint16_t *ch;
				uint32_t nch, found = 0;
				loom_synth_block_info(s, full[a], &bi);
				loom_synth_symmetries(s, bi.exemplar, 1, &ch, &nch);
				for (uint32_t k = 0; k < nch && !found; k++) {
					uint32_t t = loom_synth_block_index(
					        s, bi.exemplar, (bi.row + ch[2 * k]) % e[bi.exemplar].rows,
					        (bi.col + ch[2 * k + 1]) % e[bi.exemplar].cols);
					for (uint32_t b = 0; b < nr; b++)
						found |= red[b] == t;
				}
				CHECK(found);
			}
		}
		loom_synth_set_free(s);
	}
}

/* Total consistency over all correct assignments of a 3x3 design with two
   2x2 exemplars (4^9 assignments), against greedy and dp. */
static void max_consistency_brute_force(void)
{
	static const char *const plain[] = {"10", "01", NULL};
	static const char *const rib[] = {"11", "00", NULL};
	exdef e[2];
	loom_synth_set *s;
	uint16_t base[9];
	uint16_t corr[2][4];
	uint32_t nc[2] = {0, 0};

	rng_state = check_seed() + 2;
	e[0] = ex_from(plain, 0);
	e[1] = ex_from(rib, 1);
	s = make_set(e, 2);
	CHECK(s != NULL);
	if (!s)
		return;
	for (uint32_t t = 0; t < 8; t++) {
		loom_synth_block bi;
		loom_synth_block_info(s, t, &bi);
		corr[bi.code & 1][nc[bi.code & 1]++] = (uint16_t)t;
	}
	CHECK(nc[0] == 4 && nc[1] == 4);
	for (int trial = 0; trial < 12; trial++) {
		loom_design *d = design_random(3, 3);
		uint64_t best = 0;
		loom_synth_metrics m;
		for (uint32_t combo = 0; combo < (1u << 18); combo++) {
			uint64_t tot = 0;
			for (uint32_t k = 0; k < 9; k++) {
				uint32_t own = d->weave[k];
				base[k] = corr[own][(combo >> (2 * k)) & 3];
			}
			for (uint32_t k = 0; k < 9; k++) {
				loom_synth_block bi;
				loom_synth_block_info(s, base[k], &bi);
				tot += nmatch(bi.code, loom_synth_code(d, k / 3, k % 3));
			}
			if (tot > best)
				best = tot;
		}
		for (int algo = LOOM_SYNTH_GREEDY; algo <= LOOM_SYNTH_DP; algo++)
			for (uint32_t flags = 0; flags < 4; flags++) {
				CHECK_EQ_INT(assign(s, d, algo, (uint64_t)trial, flags, base), LOOM_OK);
				CHECK_EQ_INT(loom_synth_metrics_repeat(s, d, base, NULL, &m), LOOM_OK);
				CHECK_EQ_INT(m.matches, best);
				CHECK_EQ_INT(m.best_matches, best);
				CHECK_EQ_INT(m.correct, 9);
			}
		loom_design_free(d);
	}
	loom_synth_set_free(s);
}

/* Crossings continuing (r, c)'s value from it along (dr, dc), cyclic, at
   most 15 and fewer than the weave's side (the float runs of
   docs/fidelity.md, written out). */
static unsigned run_ref(const uint8_t *w, uint32_t rows, uint32_t cols,
                        uint32_t r, uint32_t c, int dr, int dc)
{
	uint32_t side = dr ? rows : cols;
	unsigned k = 0;
	for (uint32_t step = 1; step < side && k < 15; step++) {
		uint32_t r2 = (uint32_t)(((int64_t)r + dr * (int64_t)step) % rows + rows) % rows;
		uint32_t c2 = (uint32_t)(((int64_t)c + dc * (int64_t)step) % cols + cols) % cols;
		if ((w[r2 * cols + c2] & 1) != (w[r * cols + c] & 1))
			break;
		k++;
	}
	return k;
}

static unsigned runs_dist_ref(const uint8_t *wa, uint32_t ma, uint32_t na, uint32_t ra,
                              uint32_t ca, const uint8_t *wb, uint32_t mb, uint32_t nb,
                              uint32_t rb, uint32_t cb)
{
	static const int dir[4][2] = {{0, -1}, {0, 1}, {-1, 0}, {1, 0}};
	unsigned d = 0, ra4[4];
	for (int k = 0; k < 4; k++)
		ra4[k] = run_ref(wa, ma, na, ra, ca, dir[k][0], dir[k][1]);
	/* the rule is for floats of 6 or more (along the row or the column) */
	if (ra4[0] + ra4[1] + 1 < 6 && ra4[2] + ra4[3] + 1 < 6)
		return 0;
	/* the runs along the crossing's top yarn first (the row for the weft,
	   value 0; the column for the warp), those across it break ties */
	unsigned along = 0, across = 0, top_warp = wa[ra * na + ca] & 1;
	for (int k = 0; k < 4; k++) {
		unsigned a = run_ref(wa, ma, na, ra, ca, dir[k][0], dir[k][1]);
		unsigned b = run_ref(wb, mb, nb, rb, cb, dir[k][0], dir[k][1]);
		if ((k >= 2) == (top_warp != 0))
			along += a > b ? a - b : b - a;
		else
			across += a > b ? a - b : b - a;
	}
	d = along * 1000 + across;
	return d;
}

/* Every crossing of column j copies a block whose float runs are as near
   the design's as those of any candidate of its code. */
static int column_runs_nearest(const loom_synth_set *s, const exdef *e,
                               const loom_design *d, const uint16_t *base, uint32_t j)
{
	for (uint32_t q = 0; q < d->rows; q++) {
		const uint16_t *all;
		uint32_t n;
		unsigned dmin = ~0u, got = 0;
		loom_synth_candidates(s, loom_synth_code(d, q, j), 0, &all, &n, NULL);
		for (uint32_t k = 0; k <= n; k++) {
			loom_synth_block bi;
			unsigned dd;
			loom_synth_block_info(s, k < n ? all[k] : base[q * d->cols + j], &bi);
			dd = runs_dist_ref(d->weave, d->rows, d->cols, q, j, e[bi.exemplar].w,
			                   e[bi.exemplar].rows, e[bi.exemplar].cols, bi.row, bi.col);
			if (k < n)
				dmin = dd < dmin ? dd : dmin;
			else
				got = dd;
		}
		if (got != dmin)
			return 0;
	}
	return 1;
}

/* Largest cyclic vertical continuity of column j over all choices of
   max-consistency candidates whose float runs are nearest the design
   crossing's (brute force). */
static long column_best(const loom_synth_set *s, const exdef *e,
                        const loom_design *d, uint32_t j)
{
	const uint16_t *all;
	uint16_t lists[8][64];
	uint32_t lens[8], idx[8] = {0}, M = d->rows, n;
	uint64_t total = 1;
	long best = -1;
	for (uint32_t q = 0; q < M; q++) {
		unsigned dmin = ~0u;
		loom_synth_candidates(s, loom_synth_code(d, q, j), 0, &all, &n, NULL);
		lens[q] = 0;
		for (int pass = 0; pass < 2; pass++)
			for (uint32_t k = 0; k < n; k++) {
				loom_synth_block bi;
				unsigned dd;
				loom_synth_block_info(s, all[k], &bi);
				dd = runs_dist_ref(d->weave, d->rows, d->cols, q, j,
				                   e[bi.exemplar].w, e[bi.exemplar].rows,
				                   e[bi.exemplar].cols, bi.row, bi.col);
				if (pass == 0)
					dmin = dd < dmin ? dd : dmin;
				else if (dd == dmin && lens[q] < 64)
					lists[q][lens[q]++] = all[k];
			}
		total *= lens[q];
	}
	if (total > 300000)
		return -2;
	for (uint64_t it = 0; it < total; it++) {
		long v = 0;
		for (uint32_t q = 0; q < M; q++) {
			loom_synth_block bi;
			loom_synth_block_info(s, lists[q][idx[q]], &bi);
			v += bi.down == lists[(q + 1) % M][idx[(q + 1) % M]];
		}
		if (v > best)
			best = v;
		for (uint32_t q = 0; q < M; q++) {
			if (++idx[q] < lens[q])
				break;
			idx[q] = 0;
		}
	}
	return best;
}

static long column_value(const loom_synth_set *s, const uint16_t *base,
                         uint32_t M, uint32_t N, uint32_t j)
{
	long v = 0;
	for (uint32_t q = 0; q < M; q++) {
		loom_synth_block bi;
		loom_synth_block_info(s, base[q * N + j], &bi);
		v += bi.down == base[((q + 1) % M) * N + j];
	}
	return v;
}

static void dp_column_optimal(void)
{
	uint16_t base[8 * 5];
	int compared = 0;
	rng_state = check_seed() + 3;
	for (int trial = 0; trial < 300; trial++) {
		exdef e[3];
		uint32_t ne = 1 + rnd(3), M = 1 + rnd(7), N = 1 + rnd(5);
		if (trial % 3 == 0)
			M = 6 + rnd(2); /* room for floats of 6 (the float-run rule) */
		loom_synth_set *s;
		loom_design *d;
		for (uint32_t u = 0; u < ne; u++)
			e[u] = ex_random(4);
		s = make_set(e, ne);
		d = design_random(M, N);
		if (!s || !d) {
			CHECK(0);
			return;
		}
		/* bias some designs to copy an exemplar (long runs exist) */
		if (rnd(2))
			for (uint32_t i = 0; i < M; i++)
				for (uint32_t j = 0; j < N; j++)
					d->weave[i * N + j] =
					        e[0].w[(i % e[0].rows) * e[0].cols + j % e[0].cols];
		/* a long float down one column (the float-run rule) */
		if (trial % 3 == 0) {
			uint32_t j0 = rnd(N);
			uint8_t v = (uint8_t)rnd(2);
			for (uint32_t i = 0; i < M; i++)
				d->weave[i * N + j0] = v;
		}
		for (uint32_t flags = 0; flags < 4; flags++) {
			loom_synth_metrics m;
			CHECK_EQ_INT(assign(s, d, LOOM_SYNTH_DP, (uint64_t)trial * 7 + flags, flags, base),
			             LOOM_OK);
			loom_synth_metrics_repeat(s, d, base, NULL, &m);
			CHECK_EQ_INT(m.correct, M * N);
			CHECK_EQ_INT(m.matches, m.best_matches);
			for (uint32_t j = 0; j < N; j++) {
				long want;
				CHECK(column_runs_nearest(s, e, d, base, j));
				want = column_best(s, e, d, j);
				if (want < -1)
					continue;
				compared++;
				if (column_value(s, base, M, N, j) != want) {
					printf("  trial %d flags %u column %u: dp %ld, best %ld (M=%u)\n",
					       trial, flags, j, column_value(s, base, M, N, j), want, M);
					CHECK(0);
				}
			}
		}
		loom_design_free(d);
		loom_synth_set_free(s);
	}
	CHECK(compared > 1000);
}

/* Hand-checked: a 10x10 twill 2/3 design with its own 5x5 exemplar. */
static void twill_by_hand(void)
{
	static const char *const tw[] = {"10001", "11000", "01100", "00110", "00011", NULL};
	uint16_t base[100];
	for (int periodic = 0; periodic < 2; periodic++) {
		exdef e = ex_from(tw, periodic);
		loom_synth_set *s = make_set(&e, 1);
		loom_design *d = design_weave("twill:2/3", 10, 10);
		loom_synth_metrics m;
		uint64_t usage[1];
		CHECK(s && d);
		if (!s || !d)
			return;
		CHECK_EQ_INT(assign(s, d, LOOM_SYNTH_DP, 5, 0, base), LOOM_OK);
		CHECK_EQ_INT(loom_synth_metrics_repeat(s, d, base, usage, &m), LOOM_OK);
		CHECK_EQ_INT(m.crossings, 100);
		CHECK_EQ_INT(usage[0], 100);
		CHECK_EQ_INT(m.consistent, 100);
		if (periodic) {
			/* the exemplar tiles: everything continuous */
			CHECK_EQ_INT(m.continuous_v, 100);
			CHECK_EQ_INT(m.continuous_h, 100);
		} else {
			/* runs of at most 5 blocks: 2 breaks per column of 10, 8 links */
			CHECK_EQ_INT(m.continuous_v, 80);
			CHECK_EQ_INT(m.continuous_h, 80);
		}
		loom_design_free(d);
		loom_synth_set_free(s);
	}
}

static void correctness_random_designs(void)
{
	exdef e[4];
	loom_synth_set *s;
	uint16_t *base = malloc(sizeof(uint16_t) * 150 * 170);
	rng_state = check_seed() + 4;
	for (uint32_t u = 0; u < 4; u++)
		e[u] = ex_random(6);
	s = make_set(e, 4);
	CHECK(s && base);
	for (int trial = 0; s && base && trial < 6; trial++) {
		uint32_t M = 1 + rnd(150), N = 1 + rnd(170);
		loom_design *d = design_random(M, N);
		for (int algo = 0; algo <= 2; algo++) {
			loom_synth_metrics m;
			CHECK_EQ_INT(assign(s, d, algo, 99, 0, base), LOOM_OK);
			CHECK_EQ_INT(loom_synth_metrics_repeat(s, d, base, NULL, &m), LOOM_OK);
			CHECK_EQ_INT(m.correct, (uint64_t)M * N);
			CHECK(m.correctness == 1.0);
			if (algo)
				CHECK_EQ_INT(m.matches, m.best_matches);
		}
		loom_design_free(d);
	}
	loom_synth_set_free(s);
	free(base);
}

static void seeds(void)
{
	static const char *const tw[] = {"10001", "11000", "01100", "00110", "00011", NULL};
	static const char *const sa[] = {"10000", "00100", "00001", "01000", "00010", NULL};
	exdef e[2];
	loom_synth_set *s;
	loom_design *d;
	uint16_t *a = malloc(2 * 60 * 70), *b = malloc(2 * 60 * 70), *c = malloc(2 * 60 * 70);
	rng_state = check_seed() + 5;
	e[0] = ex_from(tw, 0);
	e[1] = ex_from(sa, 0);
	s = make_set(e, 2);
	d = design_random(60, 70);
	CHECK(s && d && a && b && c);
	for (int algo = 0; s && d && a && b && c && algo <= 2; algo++) {
		CHECK_EQ_INT(assign(s, d, algo, 1234, 0, a), LOOM_OK);
		CHECK_EQ_INT(assign(s, d, algo, 1234, 0, b), LOOM_OK);
		CHECK_EQ_INT(assign(s, d, algo, 1235, 0, c), LOOM_OK);
		CHECK(memcmp(a, b, 2 * 60 * 70) == 0);
		CHECK(memcmp(a, c, 2 * 60 * 70) != 0);
	}
	loom_design_free(d);
	loom_synth_set_free(s);
	free(a);
	free(b);
	free(c);
}

/* Reference for the randomisation, written from the documentation. */
static uint16_t ref_src(const loom_synth_set *s, const exdef *e,
                        const loom_synth_lookup *lk, int64_t I, int64_t J)
{
	int64_t M = lk->rows, N = lk->cols, g = lk->group;
	int64_t i = ((I % M) + M) % M, j = ((J % N) + N) % N;
	int64_t gi = (I >= 0 ? I / g : -((-I + g - 1) / g));
	int64_t gj = (J >= 0 ? J / g : -((-J + g - 1) / g));
	uint16_t t = lk->base[i * N + j];
	loom_synth_block bi;
	const uint16_t *sym;
	uint32_t n, nr, k, q;
	uint64_t h;
	loom_synth_block_info(s, t, &bi);
	loom_synth_symmetries(s, bi.exemplar, 0, &sym, &n);
	nr = n < 64 ? n : 64;
	h = loom_synth_group_hash(lk->key, gi, gj);
	k = (uint32_t)(((h >> 32) * nr) >> 32);
	q = (uint32_t)((uint64_t)k * n / nr);
	return (uint16_t)loom_synth_block_index(
	        s, bi.exemplar, (bi.row + sym[2 * q]) % e[bi.exemplar].rows,
	        (bi.col + sym[2 * q + 1]) % e[bi.exemplar].cols);
}

static void randomisation(void)
{
	static const char *const tw[] = {"10001", "11000", "01100", "00110", "00011", NULL};
	static const char *const sa[] = {"10000", "00100", "00001", "01000", "00010", NULL};
	static const char *const pl[] = {"1010", "0101", "1010", "0101", NULL};
	exdef e[3];
	loom_synth_set *s;
	loom_design *d;
	uint16_t base[23 * 17];
	int64_t wi0 = -40, wj0 = 9999999999ll, H = 70, W = 60;
	uint16_t *mat = malloc(sizeof(uint16_t) * 70 * 60);
	uint64_t diff = 0;

	rng_state = check_seed() + 6;
	e[0] = ex_from(tw, 1);
	e[1] = ex_from(sa, 0);
	e[2] = ex_from(pl, 1);
	s = make_set(e, 3);
	d = design_random(23, 17);
	CHECK(s && d && mat);
	if (!s || !d || !mat)
		return;
	/* mostly twill so that long runs exist */
	for (uint32_t i = 0; i < 23; i++)
		for (uint32_t j = 0; j < 17; j++)
			if (j < 12)
				d->weave[i * 17 + j] = e[0].w[(i % 5) * 5 + j % 5];
	for (uint32_t group = 1; group <= 4; group++) {
		loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
		loom_synth_lookup lk;
		loom_synth_metrics mw;
		uint64_t grp_pairs = 0, grp_kept = 0;
		o.group = group;
		o.seed = 77 + group;
		CHECK_EQ_INT(loom_synth_assign(s, d, &o, base, NULL), LOOM_OK);
		CHECK_EQ_INT(loom_synth_lookup_init(&lk, s, base, 23, 17, &o), LOOM_OK);
		/* materialised reference: group by group */
		for (int64_t gi = loom_synth_floordiv(wi0, group);
		     gi * group < wi0 + H; gi++)
			for (int64_t gj = loom_synth_floordiv(wj0, group);
			     gj * group < wj0 + W; gj++)
				for (int64_t a = 0; a < group; a++)
					for (int64_t b = 0; b < group; b++) {
						int64_t I = gi * group + a, J = gj * group + b;
						if (I < wi0 || I >= wi0 + H || J < wj0 || J >= wj0 + W)
							continue;
						mat[(I - wi0) * W + (J - wj0)] = ref_src(s, e, &lk, I, J);
					}
		for (int64_t a = 0; a < H; a++)
			for (int64_t b = 0; b < W; b++) {
				int64_t I = wi0 + a, J = wj0 + b;
				uint16_t t = loom_synth_src(&lk, I, J);
				uint16_t t0 = base[loom_synth_floormod(I, 23) * 17 + loom_synth_floormod(J, 17)];
				loom_synth_block b1, b0;
				unsigned code = loom_synth_code(d, (uint32_t)loom_synth_floormod(I, 23),
				                                (uint32_t)loom_synth_floormod(J, 17));
				CHECK(t == mat[a * W + b]);
				loom_synth_block_info(s, t, &b1);
				loom_synth_block_info(s, t0, &b0);
				/* same code: same correctness and consistency */
				CHECK_EQ_INT(b1.code, b0.code);
				CHECK_EQ_INT(nmatch(b1.code, code), nmatch(b0.code, code));
				diff += t != t0;
				/* continuity inside a group is kept (periodic exemplars) */
				if (a + 1 < H && loom_synth_floordiv(I, group) == loom_synth_floordiv(I + 1, group) &&
				    e[b0.exemplar].periodic) {
					uint16_t u0 = base[loom_synth_floormod(I + 1, 23) * 17 + loom_synth_floormod(J, 17)];
					if (u0 == b0.down) {
						grp_pairs++;
						grp_kept += loom_synth_src(&lk, I + 1, J) == b1.down;
					}
				}
			}
		CHECK(group == 1 || grp_pairs > 100);
		printf("  group %u: %llu contiguous pairs inside groups, %llu kept\n", group,
		       (unsigned long long)grp_pairs, (unsigned long long)grp_kept);
		CHECK_EQ_INT(grp_kept, grp_pairs);
		/* window metrics: correctness and consistency as the base's */
		CHECK_EQ_INT(loom_synth_metrics_window(s, d, &lk, wi0, wj0, (uint64_t)H,
		                                       (uint64_t)W, NULL, &mw), LOOM_OK);
		CHECK(mw.correctness == 1.0);
		CHECK_EQ_INT(mw.matches, mw.best_matches);
	}
	CHECK(diff > 1000); /* the randomisation does move blocks */
	/* group 0: the window over the repeat equals the repeat metrics */
	{
		loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
		loom_synth_lookup lk;
		loom_synth_metrics mr, mw;
		uint64_t ur[3], uw[3];
		o.group = 0;
		loom_synth_assign(s, d, &o, base, NULL);
		loom_synth_lookup_init(&lk, s, base, 23, 17, &o);
		loom_synth_metrics_repeat(s, d, base, ur, &mr);
		loom_synth_metrics_window(s, d, &lk, 23 * 5, -17 * 3, 23, 17, uw, &mw);
		CHECK(memcmp(&mr, &mw, sizeof mr) == 0);
		CHECK(memcmp(ur, uw, sizeof ur) == 0);
		CHECK_EQ_INT(ur[0] + ur[1] + ur[2], 23 * 17);
	}
	loom_design_free(d);
	loom_synth_set_free(s);
	free(mat);
}

static void bad_arguments(void)
{
	static const uint8_t ones[4] = {1, 1, 1, 1};
	static const uint8_t w2[4] = {1, 0, 0, 1};
	loom_synth_exemplar ex = {2, 2, w2, 0};
	loom_synth_exemplar bad = {2, 2, ones, 0};
	loom_synth_exemplar big = {2000, 2, w2, 0};
	loom_synth_set *s = NULL;
	loom_diag diag = {0};
	loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
	loom_design *d = design_random(4, 4);
	uint16_t base[16];
	loom_synth_metrics m;

	CHECK_EQ_INT(loom_synth_set_new(NULL, 1, &s, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_set_new(&ex, 0, &s, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_set_new(&ex, 1, NULL, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_set_new(&bad, 1, &s, &diag), LOOM_EUNSUPPORTED);
	CHECK_STR_CONTAINS(diag.message, "weft");
	CHECK(s == NULL);
	CHECK_EQ_INT(loom_synth_set_new(&big, 1, &s, &diag), LOOM_ERANGE);
	{
		/* 65536 blocks: one too many */
		static uint8_t huge[256 * 256];
		loom_synth_exemplar h = {256, 256, huge, 0};
		huge[0] = 1;
		CHECK_EQ_INT(loom_synth_set_new(&h, 1, &s, &diag), LOOM_ERANGE);
	}
	CHECK_EQ_INT(loom_synth_set_new(&ex, 1, &s, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_synth_set_blocks(s), 4);
	CHECK_EQ_INT(loom_synth_set_blocks(NULL), 0);
	CHECK_EQ_INT(loom_synth_block_index(s, 0, 2, 0), LOOM_SYNTH_NONE);
	CHECK_EQ_INT(loom_synth_block_index(s, 1, 0, 0), LOOM_SYNTH_NONE);
	CHECK_EQ_INT(loom_synth_block_index(s, 0, 1, 1), 3);
	CHECK_EQ_INT(loom_synth_candidates(s, 32, 0, NULL, NULL, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_assign(NULL, d, &o, base, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_assign(s, NULL, &o, base, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_assign(s, d, NULL, base, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_assign(s, d, &o, NULL, &diag), LOOM_EINVAL);
	o.algo = 7;
	CHECK_EQ_INT(loom_synth_assign(s, d, &o, base, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "algorithm");
	o.algo = LOOM_SYNTH_DP;
	o.size = 4;
	CHECK_EQ_INT(loom_synth_assign(s, d, &o, base, &diag), LOOM_EINVAL);
	o.size = sizeof o;
	CHECK_EQ_INT(loom_synth_assign(s, d, &o, base, &diag), LOOM_OK);
	CHECK(loom_synth_assign_work_bytes(s, d, &o) > 0);
	base[5] = 4;
	CHECK_EQ_INT(loom_synth_metrics_repeat(s, d, base, NULL, &m), LOOM_ERANGE);
	CHECK_EQ_INT(loom_synth_metrics_repeat(s, d, NULL, NULL, &m), LOOM_EINVAL);
	CHECK_EQ_INT(loom_synth_lookup_init(NULL, s, base, 4, 4, &o), LOOM_EINVAL);
	{
		loom_synth_block bi;
		CHECK_EQ_INT(loom_synth_block_info(s, 4, &bi), LOOM_ERANGE);
		CHECK_EQ_INT(loom_synth_block_info(s, 1, &bi), LOOM_OK);
		/* block (0,1) of a non-periodic 2x2: no up/left neighbour */
		CHECK_EQ_INT(bi.up, LOOM_SYNTH_NONE);
		CHECK_EQ_INT(bi.down, 3);
		CHECK_EQ_INT(bi.left, 0);
		CHECK_EQ_INT(bi.right, LOOM_SYNTH_NONE);
		/* own 0, N = S = W = E = 1 (the weave wraps) */
		CHECK_EQ_INT(bi.code, 0 | 2 | 4 | 8 | 16);
	}
	loom_synth_set_free(s);
	loom_synth_set_free(NULL);
	loom_design_free(d);
}

static void neighbourhood_code(void)
{
	loom_design *d = NULL;
	loom_design_new(3, 4, &d);
	/* row 0: 1 0 0 1 ; row 1: 0 1 1 0 ; row 2: 1 1 0 0 */
	static const uint8_t w[12] = {1, 0, 0, 1, 0, 1, 1, 0, 1, 1, 0, 0};
	memcpy(d->weave, w, 12);
	/* (0,0): own 1, N = row 2 col 0 = 1, S = 0, W = col 3 = 1, E = 0 */
	CHECK_EQ_INT(loom_synth_code(d, 0, 0), 1 | 2 | 8);
	/* (1,2): own 1, N 0, S 0, W 1, E 0 */
	CHECK_EQ_INT(loom_synth_code(d, 1, 2), 1 | 8);
	/* (2,3): own 0, N 0, S (row 0) 1, W 0, E (col 0) 1 */
	CHECK_EQ_INT(loom_synth_code(d, 2, 3), 4 | 16);
	loom_design_free(d);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_assign");
	RUN(neighbourhood_code);
	RUN(symmetries_brute_force);
	RUN(candidates_brute_force);
	RUN(max_consistency_brute_force);
	RUN(dp_column_optimal);
	RUN(twill_by_hand);
	RUN(correctness_random_designs);
	RUN(seeds);
	RUN(randomisation);
	RUN(bad_arguments);
	CHECK_MAIN_END();
}
