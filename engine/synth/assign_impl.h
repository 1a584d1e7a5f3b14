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

/* Image of block (r, c) of e under (dr, dc). */
static inline uint16_t shift_block(const ex_info *e, uint32_t r, uint32_t c,
                                   uint32_t dr, uint32_t dc)
{
	return (uint16_t)(e->base + ((r + dr) % e->rows) * e->cols + (c + dc) % e->cols);
}

#endif /* LOOM_ASSIGN_IMPL_H */
