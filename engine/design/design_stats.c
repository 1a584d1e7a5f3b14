/*
 * engine/design/design_stats.c - loom_design_analyze: smallest repeat, float
 * lengths, yarn types used, interlacing.
 *
 * Everything is counted cyclically, because a design is a repeat that tiles
 * the bolt: a float that runs off the bottom of a column continues at its
 * top, and a column of only 1s is one float as long as the column.
 *
 * One row-major pass over W does all the counting in O(rows*cols) time and
 * O(rows + cols) extra memory:
 *   - per column: the current run of 1s (warp float), the longest finished
 *     one, its count of 1s and an XOR hash of the rows holding a 1;
 *   - per row: its runs of 0s (weft floats), merged across the wrap, its
 *     count of 1s and an XOR hash of the columns holding a 1.
 * The XOR hashes (random 64-bit keys per row and per column) make "row i
 * equals row i+p" an O(1) test, so the smallest period that divides the
 * size is found by trying each divisor on the hashes (O(size) each) and
 * then confirmed on the cells themselves (one O(cells) pass; a hash
 * collision only sends the search on to the next divisor).  The column
 * loop is branch-free so the compiler can vectorise it.
 */
#include "core/internal.h"

#include <stdlib.h>
#include <string.h>

typedef struct col_acc {
	uint32_t *cur;    /* current run of 1s, per column */
	uint32_t *best;   /* longest run of 1s ended by a 0, per column */
	uint32_t *ones;   /* 1s per column */
	uint32_t *lead;   /* 1s above the first 0 (rows if none), per column */
	uint64_t *hash;   /* XOR of row keys where W = 1, per column */
	uint64_t *ckey;   /* random key per column */
	uint64_t *rkey;   /* random key per row */
	uint64_t *rhash;  /* XOR of column keys where W = 1, per row */
} col_acc;

static uint64_t splitmix64(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static void acc_free(col_acc *a)
{
	free(a->cur);
	free(a->best);
	free(a->ones);
	free(a->lead);
	free(a->hash);
	free(a->ckey);
	free(a->rkey);
	free(a->rhash);
}

static int acc_alloc(col_acc *a, uint32_t rows, uint32_t cols)
{
	memset(a, 0, sizeof *a);
	a->cur = calloc(cols, sizeof *a->cur);
	a->best = calloc(cols, sizeof *a->best);
	a->ones = calloc(cols, sizeof *a->ones);
	a->lead = malloc(cols * sizeof *a->lead);
	a->hash = calloc(cols, sizeof *a->hash);
	a->ckey = malloc(cols * sizeof *a->ckey);
	a->rkey = malloc(rows * sizeof *a->rkey);
	a->rhash = calloc(rows, sizeof *a->rhash);
	if (!a->cur || !a->best || !a->ones || !a->lead || !a->hash || !a->ckey ||
	    !a->rkey || !a->rhash) {
		acc_free(a);
		return LOOM_ENOMEM;
	}
	for (uint32_t j = 0; j < cols; j++)
		a->ckey[j] = splitmix64(j);
	for (uint32_t i = 0; i < rows; i++)
		a->rkey[i] = splitmix64(0x5eed0000000000ull + i);
	return LOOM_OK;
}

/* lead[j]: rows above the first 0 of column j; usually a few rows deep. */
static void leading_ones(const loom_design *d, col_acc *a)
{
	uint32_t open = d->cols;

	for (uint32_t j = 0; j < d->cols; j++)
		a->lead[j] = d->rows;
	for (uint32_t i = 0; i < d->rows && open; i++) {
		const uint8_t *w = d->weave + (size_t)i * d->cols;
		for (uint32_t j = 0; j < d->cols; j++) {
			if (w[j] == 0 && a->lead[j] == d->rows) {
				a->lead[j] = i;
				open--;
			}
		}
	}
}

/* Column counters for one row; returns the 0->1 transitions from prev.
   Masks instead of branches: random weaves would mispredict half the time. */
static uint64_t column_step(col_acc *a, const uint8_t *restrict w,
                            const uint8_t *restrict prev, uint32_t cols,
                            uint64_t rkey)
{
	uint32_t *restrict cur = a->cur, *restrict best = a->best;
	uint32_t *restrict ones = a->ones;
	uint64_t *restrict hash = a->hash;
	uint32_t starts = 0;

	for (uint32_t j = 0; j < cols; j++) {
		uint32_t v = w[j] & 1u, mask = 0u - v, c = cur[j];
		uint32_t end = c & ~mask; /* run of 1s ended by this 0 */
		best[j] = best[j] > end ? best[j] : end;
		cur[j] = (c + 1) & mask;
		ones[j] += v;
		hash[j] ^= rkey & (0 - (uint64_t)v);
		starts += v & ~(uint32_t)prev[j];
	}
	return starts;
}

/* Runs of 0s along one row, merged across the wrap. */
static void row_runs(const uint8_t *w, uint32_t n, uint32_t *max, uint64_t *runs)
{
	uint32_t lead = 0, c = 0, m = 0, r = 0;

	while (lead < n && !w[lead])
		lead++;
	if (lead == n) {
		*max = n;
		*runs = 1;
		return;
	}
	for (uint32_t j = lead; j < n; j++) {
		uint32_t v = w[j] & 1u, mask = 0u - v;
		uint32_t end = c & mask; /* run of 0s ended by this 1 */
		m = m > end ? m : end;
		r += v & (c != 0);
		c = (c + 1) & ~mask;
	}
	c += lead;
	if (c) {
		r++;
		m = m > c ? m : c;
	}
	*max = m;
	*runs = r;
}

static uint64_t row_hash(const uint8_t *w, uint32_t n, const uint64_t *ckey,
                         uint64_t *ones)
{
	uint64_t h = 0, k = 0;
	for (uint32_t j = 0; j < n; j++) {
		h ^= ckey[j] & (0 - (uint64_t)(w[j] & 1));
		k += w[j] & 1;
	}
	*ones = k;
	return h;
}

/* ---- repeat ------------------------------------------------------------- */

static int rows_shift_equal(const loom_design *d, uint32_t p)
{
	size_t stride = d->cols;
	for (uint32_t i = 0; i < d->rows; i++) {
		uint32_t k = i + p < d->rows ? i + p : i + p - d->rows;
		if (memcmp(d->weave + i * stride, d->weave + k * stride, stride))
			return 0;
	}
	return 1;
}

static int cols_shift_equal(const loom_design *d, uint32_t p)
{
	for (uint32_t i = 0; i < d->rows; i++) {
		const uint8_t *w = d->weave + (size_t)i * d->cols;
		if (memcmp(w, w + p, d->cols - p) || memcmp(w + d->cols - p, w, p))
			return 0;
	}
	return 1;
}

static int hash_periodic(const uint64_t *h, uint32_t n, uint32_t p)
{
	for (uint32_t i = 0; i < n; i++)
		if (h[i] != h[i + p < n ? i + p : i + p - n])
			return 0;
	return 1;
}

static uint32_t smallest_period(const loom_design *d, const uint64_t *h,
                                uint32_t n, int by_rows)
{
	for (uint32_t p = 1; p < n; p++) {
		if (n % p || !hash_periodic(h, n, p))
			continue;
		if (by_rows ? rows_shift_equal(d, p) : cols_shift_equal(d, p))
			return p;
	}
	return n;
}

/* ---- the pass ------------------------------------------------------------ */

static void weave_pass(const loom_design *d, col_acc *a, loom_design_stats *st,
                       int *interlaced, uint64_t *warp_runs, uint64_t *weft_runs)
{
	uint32_t rows = d->rows, cols = d->cols;

	for (uint32_t i = 0; i < rows; i++) {
		const uint8_t *w = d->weave + (size_t)i * cols;
		const uint8_t *prev = d->weave + (size_t)(i ? i - 1 : rows - 1) * cols;
		uint32_t m;
		uint64_t r, ones;

		*warp_runs += column_step(a, w, prev, cols, a->rkey[i]);
		a->rhash[i] = row_hash(w, cols, a->ckey, &ones);
		st->warp_over += ones;
		if (ones == 0 || ones == cols)
			*interlaced = 0;
		if (ones == cols)
			continue; /* no weft float in this row */
		row_runs(w, cols, &m, &r);
		*weft_runs += r;
		if (m > st->max_weft_float)
			st->max_weft_float = m;
	}
}

static void column_totals(const loom_design *d, const col_acc *a,
                          loom_design_stats *st, int *interlaced,
                          uint64_t *warp_runs)
{
	for (uint32_t j = 0; j < d->cols; j++) {
		uint32_t m = a->best[j];
		if (a->ones[j] == 0 || a->ones[j] == d->rows)
			*interlaced = 0;
		if (a->ones[j] == d->rows) {
			m = d->rows; /* one endless float */
			(*warp_runs)++;
		} else if (a->cur[j] + a->lead[j] > m) {
			m = a->cur[j] + a->lead[j]; /* bottom run continues at the top */
		}
		if (m > st->max_warp_float)
			st->max_warp_float = m;
	}
}

/* Mark the IDs of one map in seen[]; runs of the same ID (the usual case)
   are skipped 8 bytes at a time. */
static void mark_types(const uint8_t *t, size_t n, uint8_t *seen)
{
	uint8_t last = t[0];
	uint64_t pat = 0x0101010101010101ull * last;
	size_t k = 0;

	seen[last] = 1;
	while (k < n) {
		uint64_t w;
		if (k + 8 <= n) {
			memcpy(&w, t + k, 8);
			if (w == pat) {
				k += 8;
				continue;
			}
		}
		if (t[k] != last) {
			last = t[k];
			pat = 0x0101010101010101ull * last;
			seen[last] = 1;
		}
		k++;
	}
}

static uint32_t count_types(const loom_design *d)
{
	size_t n = (size_t)d->rows * d->cols;
	uint8_t seen[256] = {0};
	uint32_t used = 0;

	mark_types(d->warp_type, n, seen);
	mark_types(d->weft_type, n, seen);
	for (int t = 0; t < 256; t++)
		used += seen[t];
	return used;
}

LOOM_API int loom_design_analyze(const loom_design *d, loom_design_stats *st)
{
	col_acc a;
	uint64_t warp_runs = 0, weft_runs = 0, cells;
	int interlaced = 1;

	if (!d || !st || !d->weave || !d->warp_type || !d->weft_type ||
	    d->rows == 0 || d->cols == 0)
		return LOOM_EINVAL;
	memset(st, 0, sizeof *st);
	if (acc_alloc(&a, d->rows, d->cols))
		return LOOM_ENOMEM;
	leading_ones(d, &a);
	weave_pass(d, &a, st, &interlaced, &warp_runs, &weft_runs);
	column_totals(d, &a, st, &interlaced, &warp_runs);
	cells = (uint64_t)d->rows * d->cols;
	st->mean_warp_float = warp_runs ? (double)st->warp_over / (double)warp_runs : 0;
	st->mean_weft_float = weft_runs ? (double)(cells - st->warp_over) /
	                                  (double)weft_runs : 0;
	st->interlaced = interlaced;
	st->repeat_rows = smallest_period(d, a.rhash, d->rows, 1);
	st->repeat_cols = smallest_period(d, a.hash, d->cols, 0);
	st->types_used = count_types(d);
	acc_free(&a);
	return LOOM_OK;
}
