/*
 * engine/synth/assign.c - yarn-level synthesis: which exemplar block each crossing
 * copies (paper 5.3, 5.4).
 *
 * The exemplar set (loom_synth_set) is built once and is immutable.  It
 * holds, per source block t = base_u + r*n_u + c: its exemplar, row,
 * column, neighbourhood code and contiguous neighbours (up/down/left/right,
 * NONE across the edge of a non-periodic exemplar); per exemplar its
 * translational symmetries; and per neighbourhood code (32 of them) two
 * candidate lists:
 *
 *   full[code]     every correct block with the largest number of matching
 *                  neighbour bits (consistency), increasing t;
 *   reduced[code]  the same restricted to "representative columns": one
 *                  column per orbit of the chain symmetries of the exemplar
 *                  (all symmetries if the exemplar is periodic, those with
 *                  dr = 0 otherwise: the ones that map a vertical run of
 *                  blocks onto a vertical run).
 *
 * Of each crossing's list the DP uses only the blocks whose float runs
 * (loom_synth_runs) are nearest the design crossing's (run_ok; a mask per
 * row, so the lists below are these smaller lists).  Symmetries keep float
 * runs, so everything said of the lists holds for the masked ones.
 *
 * A symmetry g maps a block onto a block with the same code, and a chain
 * symmetry maps a vertical run onto a vertical run, so any column solution
 * over full lists maps run by run onto one over reduced lists with the same
 * consistency and the same vertical continuity: the paper's "consider just
 * one column" shortcut, made exact.  After the DP each run is lifted back
 * by the chain symmetry that best continues the column on its left.
 *
 * The DP (Eq. 1) on one column, O(K) per row.  gain(t', t) = 1 only for
 * t' = up(t), so f(i, t) = max(max_t' f(i-1, t'), f(i-1, up(t)) + 1): one
 * lookup per candidate instead of a scan of all t'.  The value of a path is
 * the pair (V, H) compared lexicographically (packed as V*2^32 + H): V the
 * vertical links (the paper's continuity along the warp), H the crossings
 * that continue the already-assigned column on the left (a tie-break the
 * paper does not have; it never costs a vertical link):
 *   f(i, t) = h(i, t) + max(best(i-1), f(i-1, up(t)) + 2^32).
 * Step 1: the column is a cycle (row M-1 lies above row 0).  Cut it where
 *         some optimal cyclic solution breaks (dp_cut): at a row no
 *         candidate can continue into if there is one; otherwise from the
 *         chain lengths of one backward pass, the greedy interval cover
 *         gives the linear optimum and, for each start block x of row 0
 *         whose up(x) is a candidate of row M-1, whether keeping the wrap
 *         link does better (then cut at the end of x's chain).
 * Step 2: forward pass of the recurrence from the cut (dp_lex), values of
 *         every row kept for the backtrack.
 * Step 3: backtrack from a seeded best of the last row: continue through
 *         up(t) when that was the max, else take a seeded best of the row
 *         above (ties are broken by the seed, deterministically).
 * Step 4: lift each vertical run by the chain symmetry that continues the
 *         left column best (votes; seeded when there are none).  With the
 *         reduced lists this turns representatives back into blocks of any
 *         column; with full lists a run moves only to a shift that matches
 *         the left column better or, when no shift matches at all, to a
 *         seeded one (variety; it cannot lose a link).
 *
 * Columns are processed in batches of BATCH adjacent ends so that the
 * design and the base assignment are read and written row by row.
 * Working memory: O(M * (BATCH + 8 * max list length)) bytes, never
 * O(M * N).
 */
#include "assign_impl.h"

#include <stdlib.h>
#include <string.h>

/* ---- hashing for choices ------------------------------------------------ */

enum { H_NAIVE = 1, H_GREEDY, H_PICK, H_LIFT, H_RAND };

static inline uint64_t hash4(uint64_t seed, uint64_t a, uint64_t b,
                             uint64_t what)
{
	return loom_synth_mix(seed ^ loom_synth_mix(a ^ loom_synth_mix(b ^ (what << 56))));
}

/* ---- naive and greedy --------------------------------------------------- */

static void assign_simple(const loom_synth_set *s, const loom_design *d,
                          int greedy, uint64_t seed, uint16_t *base)
{
	for (uint32_t i = 0; i < d->rows; i++)
		for (uint32_t j = 0; j < d->cols; j++) {
			unsigned code = loom_synth_code(d, i, j);
			const uint16_t *list;
			uint32_t n;
			uint64_t h;
			if (greedy) {
				list = s->cand + s->cand_off[0][code];
				n = s->cand_len[0][code];
				h = hash4(seed, i, j, H_GREEDY);
			} else {
				list = s->own_list[code & 1];
				n = s->own_len[code & 1];
				h = hash4(seed, i, j, H_NAIVE);
			}
			base[(size_t)i * d->cols + j] = list[loom_synth_pick(h, n)];
		}
}

/* Identity: crossing (i, j) copies block (i, j) of exemplar 0 (base 0),
   which must have the design's size and weave. */
static int assign_identity(const loom_synth_set *s, const loom_design *d,
                           uint16_t *base, loom_diag *diag)
{
	const ex_info *e = &s->ex[0];

	if (e->rows != d->rows || e->cols != d->cols)
		return loom__fail(diag, LOOM_EMISMATCH, "synth identity: the design has "
		                  "%ux%u crossings, exemplar 0 of the database %ux%u (a ground "
		                  "truth made from another design?)", d->rows, d->cols,
		                  e->rows, e->cols);
	for (uint32_t i = 0; i < d->rows; i++)
		for (uint32_t j = 0; j < d->cols; j++) {
			size_t c = (size_t)i * d->cols + j;
			if ((d->weave[c] != 0) != (e->weave[c] != 0))
				return loom__fail(diag, LOOM_EMISMATCH, "synth identity: crossing "
				                  "(pick %u, end %u) is %s over in the design, %s over "
				                  "in exemplar 0 of the database", i + 1, j + 1,
				                  d->weave[c] ? "warp" : "weft",
				                  e->weave[c] ? "warp" : "weft");
			base[c] = (uint16_t)(e->base + c);
		}
	return LOOM_OK;
}

/* ---- the column DP ------------------------------------------------------ */

#define ONE_V ((int64_t)1 << 32) /* one vertical link in a (V, H) value */
#define DEAD (INT64_MIN / 4)      /* value of the sentinel slot */
#define H_LEFT 1                  /* continuing the left column */

typedef struct dp_ctx {
	const loom_synth_set *s;
	int mode;             /* 0 full lists, 1 reduced */
	int hpref;            /* horizontal tie-break and run lifting */
	uint64_t seed;
	uint32_t M, K;
	const uint16_t *pos;  /* s->pos[mode]: [code*K + t] */
	const uint32_t *off, *len;
	const uint8_t *hb;    /* [prev*32 + cur]: some cand(cur) continues cand(prev) */
	const uint16_t *pair_up;  /* s->pair_up[mode] or NULL */
	const uint16_t *pair_down;/* s->pair_down[mode] or NULL */
	const uint32_t *pair_off; /* s->pair_off[mode] */
	uint16_t *scratch;    /* max_len: pair map when there is no table */
	uint32_t *reach;      /* M: last row of the longest chain from row q */
	uint32_t *la, *lb;    /* max_len: chain lengths of two rows */
	int64_t *f;           /* (V, H) values of every candidate of every row */
	uint32_t *foff;       /* M + 1: start of each row in f */
	int64_t *best;        /* M: best value of each row */
	uint16_t *tgt;        /* M: block continuing the left column, or NONE */
	const uint8_t *run;   /* 4M: the column's float runs (loom_synth_runs) */
	uint8_t *okb;         /* M * okw: candidate i of row q has the nearest runs */
	uint32_t okw;         /* longest list */
	unsigned *dist;       /* longest list: run distances of one row */
	uint32_t *votes;      /* max_chain */
	uint32_t *touched;    /* max_chain */
} dp_ctx;

/* Index map from cand(c) to cand(other) along up (dir 0) or down (dir 1):
   entry k is the list index of up/down of cand(c)[k], or len(other) (a
   sentinel slot) if it is not a candidate of `other`. */
static inline const uint16_t *pair_map(const dp_ctx *cx, int dir,
                                       unsigned other, unsigned c)
{
	const loom_synth_set *s = cx->s;
	const uint16_t *tab = dir ? cx->pair_down : cx->pair_up;
	const uint16_t *nb;
	const uint16_t *P;
	uint32_t n;

	if (tab)
		return tab + cx->pair_off[other * 32 + c];
	nb = (dir ? s->cand_down : s->cand_up) + cx->off[c];
	P = cx->pos + (size_t)other * cx->K;
	n = cx->len[c];
	for (uint32_t k = 0; k < n; k++)
		cx->scratch[k] = nb[k] == NONE || P[nb[k]] == NONE ? (uint16_t)cx->len[other] : P[nb[k]];
	return cx->scratch;
}

/*
 * Float runs (docs/fidelity.md, "Float runs"): of the candidates of row q
 * only those whose float runs are nearest the design crossing's
 * (run_dist; cx->okb, run_dmin) take part.  Among the blocks of one
 * neighbourhood code this copies a long float from the longest floats the
 * set has, at the same place along the float: the code sees whether a
 * float goes on, not how long it is, and a block from a 4-float sits at
 * the height of a 4-float.  With the lists restricted this way the DP is
 * Eq. 1 over smaller lists, so the cut and the recurrence stay exact.
 */
static inline int run_ok(const dp_ctx *cx, uint32_t q, unsigned c, uint32_t i)
{
	(void)c;
	return cx->okb[(size_t)q * cx->okw + i];
}

/* Which candidates of every row of the column have the nearest runs. */
static void run_dmin(dp_ctx *cx, const uint8_t *codes)
{
	const uint8_t *br = cx->s->blk_run;

	for (uint32_t q = 0; q < cx->M; q++) {
		const uint16_t *list = cx->s->cand + cx->off[codes[q]];
		const uint8_t *want = cx->run + 4 * (size_t)q;
		uint8_t *ok = cx->okb + (size_t)q * cx->okw;
		uint32_t n = cx->len[codes[q]];
		unsigned dmin = ~0u;
		if (!run_long(want)) {
			memset(ok, 1, n);
			continue;
		}
		for (uint32_t i = 0; i < n; i++) {
			unsigned d = run_dist(want, br + 4 * (size_t)list[i], codes[q] & 1u);
			cx->dist[i] = d;
			dmin = d < dmin ? d : dmin;
		}
		for (uint32_t i = 0; i < n; i++)
			ok[i] = cx->dist[i] == dmin;
	}
}

/* Block t is a candidate of row q (in its list and of the nearest runs). */
static inline int row_has(const dp_ctx *cx, const uint8_t *codes, uint32_t q,
                          uint16_t t)
{
	uint16_t p = cx->pos[(size_t)codes[q] * cx->K + t];
	return p != NONE && run_ok(cx, q, codes[q], p);
}

/*
 * Where to cut the cyclic column so that the linear DP from the cut reaches
 * the cyclic optimum of vertical continuity.  Returns the cut row; *full is
 * set to a block whose chain closes around the whole column (then that
 * chain is the answer), else NONE.
 *
 * A row that no candidate continues into (a "hard break") is a break of
 * every solution: cut there.  Otherwise, with R(a) the last row the longest
 * chain from row a reaches (one backward pass, O(K) per row), the linear
 * optimum from row 0 is the greedy cover 0 -> R(0)+1 -> ..., and a solution
 * that keeps the wrap link starts with a block x of row 0 whose up(x) is a
 * candidate of row M-1: x's chain covers [0, rho), greedy jumps cover the
 * rest, and the last segment must hold the chain that ends in up(x).  It
 * beats the cut at 0 only with as many segments; then cut at rho, one of
 * its breaks.  O(segments) per x, O(M K) in all.
 */
static uint32_t dp_cut(dp_ctx *cx, const uint8_t *codes, uint16_t *full)
{
	const loom_synth_set *s = cx->s;
	uint32_t M = cx->M, nu = 0, *la = cx->la, *lb = cx->lb, *tmp;
	unsigned c0 = codes[0];

	*full = NONE;
	for (uint32_t q = 0; q < M; q++)
		if (!cx->hb[codes[q ? q - 1 : M - 1] * 32u + codes[q]])
			return q;
	/* backward pass: chain lengths, reach */
	for (uint32_t k = 0; k < cx->len[codes[M - 1]]; k++)
		la[k] = (uint32_t)run_ok(cx, M - 1, codes[M - 1], k);
	la[cx->len[codes[M - 1]]] = 0;
	cx->reach[M - 1] = M - 1;
	for (uint32_t q = M - 1; q-- > 0;) {
		unsigned c = codes[q];
		const uint16_t *dn = pair_map(cx, 1, codes[q + 1], c);
		uint32_t n = cx->len[c], mx = 1;
		for (uint32_t k = 0; k < n; k++) {
			uint32_t l = run_ok(cx, q, c, k) ? la[dn[k]] + 1 : 0;
			lb[k] = l;
			mx = l > mx ? l : mx;
		}
		lb[n] = 0;
		cx->reach[q] = q + mx - 1;
		tmp = la;
		la = lb;
		lb = tmp;
	}
	/* la: chain lengths at row 0 */
	for (uint32_t a = 0; a < M; a = cx->reach[a] + 1)
		nu++;
	for (uint32_t k = 0; k < cx->len[c0]; k++) {
		uint16_t x = s->cand[cx->off[c0] + k], u = s->up[x], y;
		uint32_t rho = la[k], cnt = 1, last = 0, a;
		if (rho == 0 || u == NONE || !row_has(cx, codes, M - 1, u))
			continue;
		if (rho >= M) { /* x's chain covers the column: does it close? */
			y = x;
			for (uint32_t q = 1; q < M; q++)
				y = s->down[y];
			if (s->down[y] == x) {
				*full = x;
				return 0;
			}
			continue;
		}
		for (a = rho; a < M; a = cx->reach[a] + 1) {
			cnt++;
			last = a;
		}
		if (cnt != nu)
			continue;
		/* the chain ending in up(x) at row M-1 must reach up to `last` */
		y = u;
		for (uint32_t q = M - 1;; q--) {
			if (!row_has(cx, codes, q, y))
				break;
			if (q == last)
				return rho;
			y = s->up[y];
			if (y == NONE)
				break;
		}
	}
	return 0;
}

/* Seeded choice among the maxima of one DP row. */
static uint32_t dp_argmax(const int64_t *fr, uint32_t n, int64_t best, uint64_t h)
{
	uint32_t cnt = 0, k;
	for (uint32_t i = 0; i < n; i++)
		cnt += fr[i] == best;
	k = loom_synth_pick(h, cnt);
	for (uint32_t i = 0; i < n; i++)
		if (fr[i] == best && k-- == 0)
			return i;
	return 0; /* not reached */
}

/*
 * Eq. 1 from row `cut` around the column, with the value of a path the
 * pair (vertical links, horizontal links to the left column) compared
 * lexicographically and packed as V * 2^32 + H:
 *   f(k, t) = h(k, t) + max(best(k-1), f(k-1, up(t)) + ONE_V)
 * O(len(cand)) per row.  Backtrack from the seeded best of the last row: a
 * row continues from up(t) when that was the max, else it takes a seeded
 * best of the row above.
 */
static void dp_lex(dp_ctx *cx, const uint8_t *codes, uint32_t j, uint32_t cut,
                   uint16_t *out)
{
	const loom_synth_set *s = cx->s;
	uint32_t M = cx->M, K = cx->K, o = 0, ti;
	uint32_t q = cut, qp = 0;

	for (uint32_t k = 0; k < M; k++) {
		unsigned c = codes[q];
		uint32_t n = cx->len[c];
		int64_t *fr = cx->f + o, mx;
		uint16_t tg = cx->tgt[q];
		cx->foff[k] = o;
		if (k == 0) {
			for (uint32_t i = 0; i < n; i++)
				fr[i] = 0;
			mx = 0;
		} else {
			const uint16_t *up = pair_map(cx, 0, codes[qp], c);
			const int64_t *fp = cx->f + cx->foff[k - 1];
			int64_t B = cx->best[k - 1];
			mx = B;
			for (uint32_t i = 0; i < n; i++) {
				int64_t v = fp[up[i]] + ONE_V;
				v = v > B ? v : B;
				fr[i] = v;
				mx = v > mx ? v : mx;
			}
		}
		mx = DEAD;
		for (uint32_t i = 0; i < n; i++) {
			if (!run_ok(cx, q, c, i))
				fr[i] = DEAD;
			mx = fr[i] > mx ? fr[i] : mx;
		}
		fr[n] = DEAD; /* sentinel slot: "up() is not a candidate" */
		if (tg != NONE && cx->pos[(size_t)c * K + tg] != NONE) {
			int64_t v = fr[cx->pos[(size_t)c * K + tg]] += H_LEFT;
			mx = v > mx ? v : mx;
		}
		cx->best[k] = mx;
		o += n + 1;
		qp = q;
		q = q + 1 == M ? 0 : q + 1;
	}
	/* backtrack */
	q = cut == 0 ? M - 1 : cut - 1;
	ti = dp_argmax(cx->f + cx->foff[M - 1], cx->len[codes[q]], cx->best[M - 1],
	               hash4(cx->seed, j, q, H_PICK));
	for (uint32_t k = M - 1;; k--) {
		uint16_t t = s->cand[cx->off[codes[q]] + ti], u;
		uint16_t p;
		out[q] = t;
		if (k == 0)
			break;
		qp = q == 0 ? M - 1 : q - 1;
		u = s->up[t];
		p = u == NONE ? NONE : cx->pos[(size_t)codes[qp] * K + u];
		if (p != NONE && cx->f[cx->foff[k - 1] + p] + ONE_V >= cx->best[k - 1])
			ti = p;
		else
			ti = dp_argmax(cx->f + cx->foff[k - 1], cx->len[codes[qp]],
			               cx->best[k - 1], hash4(cx->seed, j, qp, H_PICK));
		q = qp;
	}
}

/* Shift one vertical run (rows a, a+1, ... cyclically, len rows) by the
   chain symmetry that continues the left column best (seeded if none). */
static void dp_lift(dp_ctx *cx, uint32_t j, const uint16_t *prev,
                    uint16_t *out, uint32_t a, uint32_t len)
{
	const loom_synth_set *s = cx->s;
	const ex_info *e = &s->ex[s->blk_ex[out[a]]];
	uint32_t ntouch = 0, best = 0, bestv = 0, M = cx->M;
	uint32_t dr, dc;

	if (e->n_chain <= 1)
		return;
	if (prev && cx->hpref) {
		for (uint32_t k = 0, q = a; k < len; k++, q = q + 1 == M ? 0 : q + 1) {
			uint16_t y = s->right[prev[q]], x = out[q];
			int32_t g;
			if (y == NONE || s->blk_ex[y] != s->blk_ex[x])
				continue;
			dr = s->blk_r[y] >= s->blk_r[x] ? (uint32_t)(s->blk_r[y] - s->blk_r[x]) :
			     e->rows + s->blk_r[y] - s->blk_r[x];
			dc = s->blk_c[y] >= s->blk_c[x] ? (uint32_t)(s->blk_c[y] - s->blk_c[x]) :
			     e->cols + s->blk_c[y] - s->blk_c[x];
			g = e->chain_idx[dr * e->cols + dc];
			if (g < 0)
				continue;
			if (cx->votes[g]++ == 0)
				cx->touched[ntouch++] = (uint32_t)g;
		}
		for (uint32_t k = 0; k < ntouch; k++) {
			uint32_t g = cx->touched[k];
			if (cx->votes[g] > bestv || (cx->votes[g] == bestv && g < best)) {
				bestv = cx->votes[g];
				best = g;
			}
			cx->votes[g] = 0;
		}
	}
	if (bestv == 0)
		best = loom_synth_pick(hash4(cx->seed, j, a, H_LIFT), e->n_chain);
	if (best == 0)
		return;
	dr = e->chain[2 * best];
	dc = e->chain[2 * best + 1];
	for (uint32_t k = 0, q = a; k < len; k++, q = q + 1 == M ? 0 : q + 1) {
		uint16_t x = out[q];
		out[q] = shift_block(e, s->blk_r[x], s->blk_c[x], dr, dc);
	}
}

static inline int dp_break(const loom_synth_set *s, const uint16_t *out,
                           uint32_t M, uint32_t q)
{
	return out[q] != s->down[out[q == 0 ? M - 1 : q - 1]];
}

/* Step 4: lift every vertical run.  A run's end is found before the run
   is shifted, so a shift never changes where later runs start. */
static void dp_runs(dp_ctx *cx, uint32_t j, const uint16_t *prev, uint16_t *out)
{
	uint32_t M = cx->M, b0 = M, start;

	for (uint32_t q = 0; q < M; q++)
		if (dp_break(cx->s, out, M, q)) {
			b0 = q;
			break;
		}
	if (b0 == M) { /* the whole column is one cyclic run */
		dp_lift(cx, j, prev, out, 0, M);
		return;
	}
	start = b0;
	for (uint32_t k = 1, q = b0; k <= M; k++) {
		q = q + 1 == M ? 0 : q + 1;
		if (k == M || dp_break(cx->s, out, M, q)) {
			uint32_t len = (q + M - start) % M;
			dp_lift(cx, j, prev, out, start, len ? len : M);
			start = q;
		}
	}
}

/* One column: codes[M] in, out[M] source blocks. */
static void dp_column(dp_ctx *cx, const uint8_t *codes, uint32_t j,
                      const uint16_t *prev, uint16_t *out)
{
	const loom_synth_set *s = cx->s;
	uint32_t M = cx->M, cut;
	uint16_t full;

	for (uint32_t q = 0; q < M; q++) {
		uint16_t y = NONE;
		if (prev && cx->hpref) {
			y = s->right[prev[q]];
			if (y != NONE && cx->mode)
				y = s->canon[y];
		}
		cx->tgt[q] = y;
	}
	run_dmin(cx, codes);
	cut = dp_cut(cx, codes, &full);
	if (full != NONE) {
		for (uint32_t q = 0; q < M; q++) {
			out[q] = full;
			full = s->down[full];
		}
	} else {
		dp_lex(cx, codes, j, cut, out);
	}
	dp_runs(cx, j, prev, out);
}

static size_t dp_work_bytes(const loom_synth_set *s, uint32_t M, int mode)
{
	size_t ml = s->max_len[mode];
	return (size_t)BATCH * M * 7 + (size_t)M * (2 + 4 + 4 + 8 + 2) +
	       (size_t)M * (ml ? ml : 1) + (ml + 1) * sizeof(unsigned) +
	       (size_t)M * (ml + 1) * 8 + (ml + 1) * (2 + 4 + 4) +
	       ((size_t)s->max_chain + 1) * 8;
}

static int assign_dp(const loom_synth_set *s, const loom_design *d,
                     const loom_synth_options *o, uint16_t *base)
{
	dp_ctx cx;
	uint32_t M = d->rows, N = d->cols, ml;
	uint8_t *codes = NULL, *runs = NULL;
	uint16_t *outb = NULL, *prevcol = NULL;
	int rc = LOOM_ENOMEM;

	memset(&cx, 0, sizeof cx);
	cx.s = s;
	cx.mode = (o->flags & LOOM_SYNTH_FULL_LISTS) ? 0 : 1;
	cx.hpref = !(o->flags & LOOM_SYNTH_NO_HPREF);
	cx.seed = o->seed;
	cx.M = M;
	cx.K = s->K;
	ml = s->max_len[cx.mode];
	cx.pos = s->pos[cx.mode];
	cx.off = s->cand_off[cx.mode];
	cx.len = s->cand_len[cx.mode];
	cx.hb = s->hb[cx.mode];
	cx.pair_up = s->pair_up[cx.mode];
	cx.pair_down = s->pair_down[cx.mode];
	cx.pair_off = s->pair_off[cx.mode];
	cx.scratch = malloc((size_t)ml * 2);
	cx.reach = malloc((size_t)M * 4);
	cx.la = malloc(((size_t)ml + 1) * 4);
	cx.lb = malloc(((size_t)ml + 1) * 4);
	cx.f = malloc((size_t)M * (ml + 1) * 8);
	cx.foff = malloc(((size_t)M + 1) * 4);
	cx.best = malloc((size_t)M * 8);
	cx.tgt = malloc((size_t)M * 2);
	cx.okw = ml ? ml : 1;
	cx.okb = malloc((size_t)M * cx.okw);
	cx.dist = malloc(((size_t)ml + 1) * sizeof *cx.dist);
	cx.votes = calloc((size_t)s->max_chain + 1, 4);
	cx.touched = malloc(((size_t)s->max_chain + 1) * 4);
	codes = malloc((size_t)BATCH * M);
	runs = malloc((size_t)BATCH * M * 4);
	outb = malloc((size_t)BATCH * M * 2);
	prevcol = malloc((size_t)M * 2);
	if (!cx.scratch || !cx.reach || !cx.la || !cx.lb || !cx.f || !cx.foff ||
	    !cx.best || !cx.tgt || !cx.okb || !cx.dist || !cx.votes || !cx.touched || !codes || !runs ||
	    !outb || !prevcol)
		goto done;

	for (uint32_t j0 = 0; j0 < N; j0 += BATCH) {
		uint32_t nb = N - j0 < BATCH ? N - j0 : BATCH;
		/* codes of the batch, column-major */
		for (uint32_t i = 0; i < M; i++) {
			const uint8_t *r0 = d->weave + (size_t)i * N;
			const uint8_t *rm = d->weave + (size_t)(i ? i - 1 : M - 1) * N;
			const uint8_t *rp = d->weave + (size_t)(i + 1 == M ? 0 : i + 1) * N;
			for (uint32_t jj = 0; jj < nb; jj++) {
				uint32_t j = j0 + jj;
				uint32_t jm = j ? j - 1 : N - 1, jp = j + 1 == N ? 0 : j + 1;
				codes[(size_t)jj * M + i] =
				        (uint8_t)((r0[j] & 1) | (rm[j] & 1) << 1 | (rp[j] & 1) << 2 |
				                  (r0[jm] & 1) << 3 | (r0[jp] & 1) << 4);
				loom_synth_runs(d->weave, M, N, i, j,
				                runs + ((size_t)jj * M + i) * 4);
			}
		}
		for (uint32_t jj = 0; jj < nb; jj++) {
			const uint16_t *prev = jj ? outb + (size_t)(jj - 1) * M :
			                       j0 ? prevcol : NULL;
			cx.run = runs + (size_t)jj * M * 4;
			dp_column(&cx, codes + (size_t)jj * M, j0 + jj, prev,
			          outb + (size_t)jj * M);
		}
		memcpy(prevcol, outb + (size_t)(nb - 1) * M, (size_t)M * 2);
		for (uint32_t i = 0; i < M; i++) {
			uint16_t *row = base + (size_t)i * N + j0;
			for (uint32_t jj = 0; jj < nb; jj++)
				row[jj] = outb[(size_t)jj * M + i];
		}
	}
	rc = LOOM_OK;
done:
	free(cx.scratch);
	free(cx.reach);
	free(cx.la);
	free(cx.lb);
	free(cx.f);
	free(cx.foff);
	free(cx.best);
	free(cx.tgt);
	free(cx.okb);
	free(cx.dist);
	free(cx.votes);
	free(cx.touched);
	free(codes);
	free(runs);
	free(outb);
	free(prevcol);
	return rc;
}

static int check_args(const loom_synth_set *s, const loom_design *d,
                      const loom_synth_options *o, loom_diag *diag)
{
	if (!s || !d || !o)
		return loom__fail(diag, LOOM_EINVAL, "synth assign: NULL argument");
	if (o->size < sizeof(loom_synth_options))
		return loom__fail(diag, LOOM_EINVAL,
		                  "synth assign: options.size %zu, expected %zu",
		                  o->size, sizeof(loom_synth_options));
	if (o->algo < LOOM_SYNTH_NAIVE || o->algo > LOOM_SYNTH_IDENTITY)
		return loom__fail(diag, LOOM_EINVAL, "synth assign: unknown algorithm %d",
		                  o->algo);
	if (!d->weave || d->rows == 0 || d->cols == 0)
		return loom__fail(diag, LOOM_EINVAL, "synth assign: empty design");
	return LOOM_OK;
}

LOOM_API size_t loom_synth_assign_work_bytes(const loom_synth_set *s,
                                             const loom_design *d,
                                             const loom_synth_options *o)
{
	if (check_args(s, d, o, NULL) != LOOM_OK || o->algo != LOOM_SYNTH_DP)
		return 0;
	return dp_work_bytes(s, d->rows, (o->flags & LOOM_SYNTH_FULL_LISTS) ? 0 : 1);
}

LOOM_API int loom_synth_assign(const loom_synth_set *s, const loom_design *d,
                               const loom_synth_options *o, uint16_t *base,
                               loom_diag *diag)
{
	int rc = check_args(s, d, o, diag);

	if (rc)
		return rc;
	if (!base)
		return loom__fail(diag, LOOM_EINVAL, "synth assign: NULL output");
	if (o->algo == LOOM_SYNTH_IDENTITY)
		return assign_identity(s, d, base, diag);
	if (o->algo != LOOM_SYNTH_DP) {
		assign_simple(s, d, o->algo == LOOM_SYNTH_GREEDY, o->seed, base);
		return LOOM_OK;
	}
	rc = assign_dp(s, d, o, base);
	if (rc)
		return loom__fail(diag, rc, "synth assign: out of memory (%zu bytes of work)",
		                  dp_work_bytes(s, d->rows, (o->flags & LOOM_SYNTH_FULL_LISTS) ? 0 : 1));
	return LOOM_OK;
}

/* ---- lookup ------------------------------------------------------------- */

LOOM_API int loom_synth_lookup_init(loom_synth_lookup *lk,
                                    const loom_synth_set *s,
                                    const uint16_t *base, uint32_t rows,
                                    uint32_t cols,
                                    const loom_synth_options *o)
{
	if (!lk || !s || !base || !o || rows == 0 || cols == 0)
		return LOOM_EINVAL;
	lk->base = base;
	lk->rows = rows;
	lk->cols = cols;
	lk->group = o->group;
	lk->key = loom_synth_mix(o->seed ^ 0x52414e444f4d4953ull); /* "RANDOMIS" */
	lk->n_sym = s->n_sym;
	lk->sym_first = s->sym_first;
	lk->sym_image = s->sym_image;
	return LOOM_OK;
}

/* ---- metrics ------------------------------------------------------------ */

static void metrics_finish(loom_synth_metrics *m)
{
	m->correctness = m->crossings ? (double)m->correct / (double)m->crossings : 0;
	m->consistency = m->crossings ? (double)m->consistent / (double)m->crossings : 0;
	m->continuity = m->pairs ? (double)m->continuous / (double)m->pairs : 0;
}

/* Account crossing with code `code`, source t, S partner tb, E partner tr. */
static inline void metrics_add(const loom_synth_set *s, loom_synth_metrics *m,
                               uint64_t *usage, unsigned code, uint16_t t,
                               uint16_t tb, uint16_t tr)
{
	unsigned bc = s->blk_code[t], mb = match_bits(bc, code);
	m->crossings++;
	m->correct += (bc & 1u) == (code & 1u);
	m->matches += mb;
	m->consistent += mb == 4;
	m->best_matches += s->cand_match[code];
	m->pairs += 2;
	if (tb == s->down[t])
		m->continuous_v++;
	if (tr == s->right[t])
		m->continuous_h++;
	if (usage)
		usage[s->blk_ex[t]]++;
}

static int metrics_begin(const loom_synth_set *s, const loom_design *d,
                         uint64_t *usage, loom_synth_metrics *m)
{
	if (!s || !d || !m || !d->weave || d->rows == 0 || d->cols == 0)
		return LOOM_EINVAL;
	memset(m, 0, sizeof *m);
	if (usage)
		memset(usage, 0, sizeof(uint64_t) * s->n_ex);
	return LOOM_OK;
}

LOOM_API int loom_synth_metrics_repeat(const loom_synth_set *s,
                                       const loom_design *d,
                                       const uint16_t *base, uint64_t *usage,
                                       loom_synth_metrics *m)
{
	uint32_t M, N;
	if (!base || metrics_begin(s, d, usage, m) != LOOM_OK)
		return LOOM_EINVAL;
	M = d->rows;
	N = d->cols;
	for (size_t k = 0; k < (size_t)M * N; k++)
		if (base[k] >= s->K)
			return LOOM_ERANGE;
	for (uint32_t i = 0; i < M; i++) {
		const uint16_t *row = base + (size_t)i * N;
		const uint16_t *below = base + (size_t)(i + 1 == M ? 0 : i + 1) * N;
		for (uint32_t j = 0; j < N; j++)
			metrics_add(s, m, usage, loom_synth_code(d, i, j), row[j], below[j],
			            row[j + 1 == N ? 0 : j + 1]);
	}
	m->continuous = m->continuous_v + m->continuous_h;
	metrics_finish(m);
	return LOOM_OK;
}

LOOM_API int loom_synth_metrics_window(const loom_synth_set *s,
                                       const loom_design *d,
                                       const loom_synth_lookup *lk,
                                       int64_t i0, int64_t j0, uint64_t h,
                                       uint64_t w, uint64_t *usage,
                                       loom_synth_metrics *m)
{
	if (!lk || metrics_begin(s, d, usage, m) != LOOM_OK ||
	    lk->rows != d->rows || lk->cols != d->cols || lk->n_sym != s->n_sym)
		return LOOM_EINVAL;
	for (uint64_t a = 0; a < h; a++)
		for (uint64_t b = 0; b < w; b++) {
			int64_t I = i0 + (int64_t)a, J = j0 + (int64_t)b;
			unsigned code = loom_synth_code(d, (uint32_t)loom_synth_floormod(I, d->rows),
			                                (uint32_t)loom_synth_floormod(J, d->cols));
			metrics_add(s, m, usage, code, loom_synth_src(lk, I, J),
			            loom_synth_src(lk, I + 1, J), loom_synth_src(lk, I, J + 1));
		}
	m->continuous = m->continuous_v + m->continuous_h;
	metrics_finish(m);
	return LOOM_OK;
}
