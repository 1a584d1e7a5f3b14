/*
 * engine/synth/assign_impl.h - the exemplar set's representation, shared
 * by its builder (candidates.c) and the assignment that reads it
 * (assign.c, which has the essay).  Private to engine/synth.
 */
#ifndef LOOM_ASSIGN_IMPL_H
#define LOOM_ASSIGN_IMPL_H

#include "core/internal.h"

#define NONE LOOM_SYNTH_NONE
#define MAX_SIDE 1024u
#define MAX_RAND_SYM 64u   /* symmetries the randomisation draws from */
#define BATCH 64u          /* columns per DP batch */

typedef struct ex_info {
	uint32_t rows, cols, base;
	int periodic;
	uint8_t *weave;        /* rows*cols */
	uint32_t n_sym;        /* all symmetries */
	uint16_t *sym;         /* 2*n_sym: (dr, dc) */
	uint32_t n_chain;      /* chain symmetries */
	uint16_t *chain;       /* 2*n_chain */
	int32_t *chain_idx;    /* rows*cols: index of (dr,dc) in chain, or -1 */
	uint32_t n_rand;       /* symmetries used by the randomisation */
} ex_info;

struct loom_synth_set {
	uint32_t n_ex, K;
	ex_info *ex;
	uint32_t *blk_ex;        /* K */
	uint16_t *blk_r, *blk_c; /* K */
	uint8_t *blk_code;       /* K */
	uint8_t *blk_run;        /* 4K: float runs (loom_synth_runs) */
	uint16_t *up, *down, *left, *right; /* K */
	uint16_t *canon;         /* K: representative of t's chain orbit */
	/* randomisation tables (loom_synth_lookup) */
	uint16_t *n_sym;         /* K */
	uint32_t *sym_first;     /* K */
	uint16_t *sym_image;
	/* candidate lists: [0] full, [1] reduced */
	uint32_t cand_off[2][32], cand_len[2][32];
	uint32_t cand_match[32];
	uint16_t *cand;          /* all lists back to back */
	uint16_t *cand_up;       /* up(list[k]) alongside cand */
	uint16_t *cand_down;     /* down(list[k]) alongside cand */
	uint8_t hb[2][1024];     /* [prev*32 + cur]: some candidate of cur has
	                            up() among the candidates of prev */
	uint16_t *pair_up[2];    /* per (other, code) pair and list entry k of
	                            code: index of up(cand[k]) in list(other),
	                            len(other) if none (a sentinel slot) */
	uint16_t *pair_down[2];  /* the same along down(); NULL if too big */
	uint32_t pair_off[2][1024]; /* [other*32 + code]: start in pair_* */
	uint16_t *pos[2];        /* [code*K + t]: index of t in list, or NONE */
	uint32_t max_len[2];
	uint16_t *own_list[2];   /* naive: blocks with own bit 0 / 1 */
	uint32_t own_len[2];
	uint32_t max_chain;
};

static inline unsigned popc5(unsigned x)
{
	return (unsigned)__builtin_popcount(x);
}

/* Matching neighbour bits between two codes (bits 1..4). */
static inline unsigned match_bits(unsigned a, unsigned b)
{
	return popc5(~(a ^ b) & 0x1eu);
}

/*
 * Float runs through crossing (r, c) of a rows x cols weave (cyclic): how
 * many crossings on each side continue the crossing's own value, left,
 * right, up and down, each capped at RUN_CAP.  The neighbourhood code sees
 * only whether a float goes on; these say how long it is and where the
 * crossing sits in it (a 9-float's middle lies lower than a 4-float's).
 */
#define RUN_CAP 15u
static inline unsigned run_along(const uint8_t *w, size_t at, size_t step,
                                 size_t wrap, uint32_t side, uint32_t pos, int back)
{
	unsigned v = w[at] & 1u, k = 0;
	size_t i = at;

	/* step through the cyclic line (side crossings, `step` apart, the
	   line's start wrap * step before the end) without a division */
	while (k < RUN_CAP && k + 1 < side) {
		if (back) {
			if (pos == 0) {
				pos = side - 1;
				i += wrap;
			} else {
				pos--;
				i -= step;
			}
		} else if (++pos == side) {
			pos = 0;
			i -= wrap;
		} else {
			i += step;
		}
		if ((w[i] & 1u) != v)
			break;
		k++;
	}
	return k;
}

static inline void loom_synth_runs(const uint8_t *w, uint32_t rows, uint32_t cols,
                                   uint32_t r, uint32_t c, uint8_t out[4])
{
	size_t at = (size_t)r * cols + c;

	out[0] = (uint8_t)run_along(w, at, 1, cols - 1, cols, c, 1);
	out[1] = (uint8_t)run_along(w, at, 1, cols - 1, cols, c, 0);
	out[2] = (uint8_t)run_along(w, at, cols, (size_t)(rows - 1) * cols, rows, r, 1);
	out[3] = (uint8_t)run_along(w, at, cols, (size_t)(rows - 1) * cols, rows, r, 0);
}

/*
 * The rule applies to crossings on a float of RUN_LONG crossings or more
 * (along the row or the column): shorter floats are those of the 5-end
 * weaves the code already tells apart, and forcing their runs costs
 * vertical continuity for no better height (docs/fidelity.md, "Float
 * runs").
 */
#define RUN_LONG 6u
static inline int run_long(const uint8_t r[4])
{
	return r[0] + r[1] + 1u >= RUN_LONG || r[2] + r[3] + 1u >= RUN_LONG;
}

/*
 * How far two crossings' float runs differ (0 = the same), for crossings
 * of value v (1: the warp on top).  The runs along the top yarn (the row
 * for the weft, v = 0; the column for the warp) come first, those across
 * it break ties: the top surface is the top yarn's float, and where no
 * block matches both axes (a 1/9 satin's places copied from a 1/7's,
 * whose moves differ) the plain sum traded the place along the top float
 * for the place along the float underneath (docs/fidelity.md, "Runs
 * along the top yarn first").  Each axis sums two runs of at most 15:
 * below 64.
 */
static inline unsigned run_dist(const uint8_t a[4], const uint8_t b[4], unsigned v)
{
	unsigned d[2] = {0, 0};
	for (int k = 0; k < 4; k++)
		d[k >> 1] += (unsigned)(a[k] > b[k] ? a[k] - b[k] : b[k] - a[k]);
	return v ? d[1] * 64u + d[0] : d[0] * 64u + d[1];
}

/* Image of block (r, c) of e under (dr, dc). */
static inline uint16_t shift_block(const ex_info *e, uint32_t r, uint32_t c,
                                   uint32_t dr, uint32_t dc)
{
	return (uint16_t)(e->base + ((r + dr) % e->rows) * e->cols + (c + dc) % e->cols);
}

#endif /* LOOM_ASSIGN_IMPL_H */
