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
#include "core/internal.h"

#include <stdlib.h>
#include <string.h>

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

static int is_symmetry(const ex_info *e, uint32_t dr, uint32_t dc)
{
	for (uint32_t r = 0; r < e->rows; r++) {
		const uint8_t *a = e->weave + (size_t)r * e->cols;
		const uint8_t *b = e->weave + (size_t)((r + dr) % e->rows) * e->cols;
		for (uint32_t c = 0; c < e->cols; c++) {
			uint32_t c2 = c + dc;
			if (c2 >= e->cols)
				c2 -= e->cols;
			if (a[c] != b[c2])
				return 0;
		}
	}
	return 1;
}

/*
 * All symmetries of S_u.  They form a subgroup of Z_m x Z_n; its part with
 * dr = 0 is generated by the horizontal period p, and for each dr the valid
 * dc form one coset of that part, so it suffices to try dc < p.
 */
static int find_symmetries(ex_info *e)
{
	uint32_t m = e->rows, n = e->cols, p = n, cnt = 0;

	for (uint32_t dc = 1; dc < n; dc++)
		if (n % dc == 0 && is_symmetry(e, 0, dc)) {
			p = dc;
			break;
		}
	e->sym = malloc(sizeof(uint16_t) * 2 * (size_t)m * (n / p));
	e->chain_idx = malloc(sizeof(int32_t) * (size_t)m * n);
	if (!e->sym || !e->chain_idx)
		return LOOM_ENOMEM;
	for (uint32_t dr = 0; dr < m; dr++)
		for (uint32_t dc0 = 0; dc0 < p; dc0++)
			if (is_symmetry(e, dr, dc0)) {
				for (uint32_t dc = dc0; dc < n; dc += p) {
					e->sym[2 * cnt] = (uint16_t)dr;
					e->sym[2 * cnt + 1] = (uint16_t)dc;
					cnt++;
				}
				break;
			}
	/* sort by dr*n + dc (within a dr they are already increasing except
	   for the coset start, so a simple insertion sort is enough) */
	for (uint32_t a = 1; a < cnt; a++) {
		uint16_t r0 = e->sym[2 * a], c0 = e->sym[2 * a + 1];
		uint32_t key = (uint32_t)r0 * n + c0, b = a;
		while (b > 0 && (uint32_t)e->sym[2 * (b - 1)] * n + e->sym[2 * (b - 1) + 1] > key) {
			e->sym[2 * b] = e->sym[2 * (b - 1)];
			e->sym[2 * b + 1] = e->sym[2 * (b - 1) + 1];
			b--;
		}
		e->sym[2 * b] = r0;
		e->sym[2 * b + 1] = c0;
	}
	e->n_sym = cnt;
	e->chain = malloc(sizeof(uint16_t) * 2 * cnt);
	if (!e->chain)
		return LOOM_ENOMEM;
	for (size_t k = 0; k < (size_t)m * n; k++)
		e->chain_idx[k] = -1;
	e->n_chain = 0;
	for (uint32_t k = 0; k < cnt; k++)
		if (e->periodic || e->sym[2 * k] == 0) {
			e->chain[2 * e->n_chain] = e->sym[2 * k];
			e->chain[2 * e->n_chain + 1] = e->sym[2 * k + 1];
			e->chain_idx[(size_t)e->sym[2 * k] * n + e->sym[2 * k + 1]] =
			        (int32_t)e->n_chain;
			e->n_chain++;
		}
	e->n_rand = cnt < MAX_RAND_SYM ? cnt : MAX_RAND_SYM;
	return LOOM_OK;
}

static uint32_t block_code(const ex_info *e, uint32_t r, uint32_t c)
{
	uint32_t m = e->rows, n = e->cols;
	const uint8_t *w = e->weave;
	uint32_t rm = r ? r - 1 : m - 1, rp = r + 1 == m ? 0 : r + 1;
	uint32_t cm = c ? c - 1 : n - 1, cp = c + 1 == n ? 0 : c + 1;
	return (uint32_t)(w[(size_t)r * n + c] | w[(size_t)rm * n + c] << 1 |
	                  w[(size_t)rp * n + c] << 2 | w[(size_t)r * n + cm] << 3 |
	                  w[(size_t)r * n + cp] << 4);
}

/* Image of block (r, c) of e under (dr, dc). */
static inline uint16_t shift_block(const ex_info *e, uint32_t r, uint32_t c,
                                   uint32_t dr, uint32_t dc)
{
	return (uint16_t)(e->base + ((r + dr) % e->rows) * e->cols + (c + dc) % e->cols);
}

LOOM_API void loom_synth_set_free(loom_synth_set *s)
{
	if (!s)
		return;
	if (s->ex)
		for (uint32_t u = 0; u < s->n_ex; u++) {
			free(s->ex[u].weave);
			free(s->ex[u].sym);
			free(s->ex[u].chain);
			free(s->ex[u].chain_idx);
		}
	free(s->ex);
	free(s->blk_ex);
	free(s->blk_r);
	free(s->blk_c);
	free(s->blk_code);
	free(s->up);
	free(s->down);
	free(s->left);
	free(s->right);
	free(s->canon);
	free(s->n_sym);
	free(s->sym_first);
	free(s->sym_image);
	free(s->cand);
	free(s->cand_up);
	free(s->cand_down);
	for (int mode = 0; mode < 2; mode++) {
		free(s->pair_up[mode]);
		free(s->pair_down[mode]);
	}
	free(s->pos[0]);
	free(s->pos[1]);
	free(s->own_list[0]);
	free(s->own_list[1]);
	free(s);
}

static int alloc_blocks(loom_synth_set *s)
{
	size_t K = s->K;
	s->blk_ex = malloc(K * sizeof *s->blk_ex);
	s->blk_r = malloc(K * sizeof *s->blk_r);
	s->blk_c = malloc(K * sizeof *s->blk_c);
	s->blk_code = malloc(K);
	s->up = malloc(K * 2);
	s->down = malloc(K * 2);
	s->left = malloc(K * 2);
	s->right = malloc(K * 2);
	s->canon = malloc(K * 2);
	s->n_sym = malloc(K * 2);
	s->sym_first = malloc(K * 4);
	s->pos[0] = malloc(32 * K * 2);
	s->pos[1] = malloc(32 * K * 2);
	s->own_list[0] = malloc(K * 2);
	s->own_list[1] = malloc(K * 2);
	if (!s->blk_ex || !s->blk_r || !s->blk_c || !s->blk_code || !s->up ||
	    !s->down || !s->left || !s->right || !s->canon || !s->n_sym ||
	    !s->sym_first || !s->pos[0] || !s->pos[1] || !s->own_list[0] ||
	    !s->own_list[1])
		return LOOM_ENOMEM;
	return LOOM_OK;
}

/* Per-block geometry, neighbours, canonical representative, symmetry
   images for the randomisation. */
static int fill_blocks(loom_synth_set *s)
{
	size_t n_img = 0;

	for (uint32_t u = 0; u < s->n_ex; u++)
		n_img += (size_t)s->ex[u].rows * s->ex[u].cols * s->ex[u].n_rand;
	s->sym_image = malloc(n_img * 2 + 2);
	if (!s->sym_image)
		return LOOM_ENOMEM;
	n_img = 0;
	for (uint32_t u = 0; u < s->n_ex; u++) {
		const ex_info *e = &s->ex[u];
		uint32_t m = e->rows, n = e->cols;
		for (uint32_t r = 0; r < m; r++)
			for (uint32_t c = 0; c < n; c++) {
				uint32_t t = e->base + r * n + c, best_c = c, best_r = r;
				s->blk_ex[t] = u;
				s->blk_r[t] = (uint16_t)r;
				s->blk_c[t] = (uint16_t)c;
				s->blk_code[t] = (uint8_t)block_code(e, r, c);
				s->up[t] = (r > 0) ? (uint16_t)(t - n) :
				           e->periodic ? (uint16_t)(t + (m - 1) * n) : NONE;
				s->down[t] = (r + 1 < m) ? (uint16_t)(t + n) :
				             e->periodic ? (uint16_t)(t - (m - 1) * n) : NONE;
				s->left[t] = (c > 0) ? (uint16_t)(t - 1) :
				             e->periodic ? (uint16_t)(t + n - 1) : NONE;
				s->right[t] = (c + 1 < n) ? (uint16_t)(t + 1) :
				              e->periodic ? (uint16_t)(t - (n - 1)) : NONE;
				/* representative: the image with the smallest column,
				   then the smallest row */
				for (uint32_t k = 0; k < e->n_chain; k++) {
					uint32_t r2 = (r + e->chain[2 * k]) % m;
					uint32_t c2 = (c + e->chain[2 * k + 1]) % n;
					if (c2 < best_c || (c2 == best_c && r2 < best_r)) {
						best_c = c2;
						best_r = r2;
					}
				}
				s->canon[t] = (uint16_t)(e->base + best_r * n + best_c);
				s->n_sym[t] = (uint16_t)e->n_rand;
				s->sym_first[t] = (uint32_t)n_img;
				for (uint32_t k = 0; k < e->n_rand; k++) {
					/* spread the draws over the whole group */
					uint32_t q = (uint32_t)((uint64_t)k * e->n_sym / e->n_rand);
					s->sym_image[n_img++] =
					        shift_block(e, r, c, e->sym[2 * q], e->sym[2 * q + 1]);
				}
			}
	}
	return LOOM_OK;
}

/* Whether column c of exemplar e is a representative column (the smallest
   column of its orbit under the chain symmetries). */
static int rep_column(const ex_info *e, uint32_t c)
{
	for (uint32_t k = 0; k < e->n_chain; k++)
		if ((c + e->chain[2 * k + 1]) % e->cols < c)
			return 0;
	return 1;
}

#define PAIR_TABLE_MAX (8u << 20) /* bytes for pair_up + pair_down per mode */

/* Pair maps and hard-break table of both list modes. */
static int build_pairs(loom_synth_set *s)
{
	for (int mode = 0; mode < 2; mode++) {
		size_t total = 0;
		const uint16_t *pos = s->pos[mode];
		for (unsigned o = 0; o < 32; o++)
			for (unsigned c = 0; c < 32; c++) {
				s->pair_off[mode][o * 32 + c] = (uint32_t)total;
				total += s->cand_len[mode][c];
			}
		if (total * 4 <= PAIR_TABLE_MAX) {
			s->pair_up[mode] = malloc(total * 2 + 2);
			s->pair_down[mode] = malloc(total * 2 + 2);
			if (!s->pair_up[mode] || !s->pair_down[mode])
				return LOOM_ENOMEM;
		}
		for (unsigned o = 0; o < 32; o++)
			for (unsigned c = 0; c < 32; c++) {
				const uint16_t *P = pos + (size_t)o * s->K;
				uint32_t off = s->cand_off[mode][c], n = s->cand_len[mode][c];
				int any = 0;
				for (uint32_t k = 0; k < n; k++) {
					uint16_t u = s->cand_up[off + k], d = s->cand_down[off + k];
					uint16_t pu = (u == NONE || P[u] == NONE) ? (uint16_t)s->cand_len[mode][o] : P[u];
					uint16_t pd = (d == NONE || P[d] == NONE) ? (uint16_t)s->cand_len[mode][o] : P[d];
					any |= u != NONE && P[u] != NONE;
					if (s->pair_up[mode]) {
						s->pair_up[mode][s->pair_off[mode][o * 32 + c] + k] = pu;
						s->pair_down[mode][s->pair_off[mode][o * 32 + c] + k] = pd;
					}
				}
				s->hb[mode][o * 32 + c] = (uint8_t)any;
			}
	}
	return LOOM_OK;
}

static int build_candidates(loom_synth_set *s)
{
	uint32_t K = s->K, total = 0;
	uint8_t *rep = malloc(K);

	if (!rep)
		return LOOM_ENOMEM;
	for (uint32_t t = 0; t < K; t++)
		rep[t] = (uint8_t)rep_column(&s->ex[s->blk_ex[t]], s->blk_c[t]);
	for (unsigned code = 0; code < 32; code++) {
		uint32_t best = 0, nf = 0, nr = 0;
		for (uint32_t t = 0; t < K; t++)
			if ((s->blk_code[t] & 1u) == (code & 1u)) {
				uint32_t mb = match_bits(s->blk_code[t], code);
				if (mb > best) {
					best = mb;
					nf = nr = 0;
				}
				if (mb == best) {
					nf++;
					nr += rep[t];
				}
			}
		s->cand_match[code] = best;
		s->cand_len[0][code] = nf;
		s->cand_len[1][code] = nr;
		total += nf + nr;
	}
	s->cand = malloc((size_t)total * 2 + 2);
	s->cand_up = malloc((size_t)total * 2 + 2);
	s->cand_down = malloc((size_t)total * 2 + 2);
	if (!s->cand || !s->cand_up || !s->cand_down) {
		free(rep);
		return LOOM_ENOMEM;
	}
	memset(s->pos[0], 0xff, 32 * (size_t)K * 2);
	memset(s->pos[1], 0xff, 32 * (size_t)K * 2);
	total = 0;
	s->max_len[0] = s->max_len[1] = 0;
	for (int mode = 0; mode < 2; mode++)
		for (unsigned code = 0; code < 32; code++) {
			uint32_t k = 0;
			s->cand_off[mode][code] = total;
			for (uint32_t t = 0; t < K; t++)
				if ((s->blk_code[t] & 1u) == (code & 1u) &&
				    match_bits(s->blk_code[t], code) == s->cand_match[code] &&
				    (mode == 0 || rep[t])) {
					s->cand[total + k] = (uint16_t)t;
					s->cand_up[total + k] = s->up[t];
					s->cand_down[total + k] = s->down[t];
					s->pos[mode][(size_t)code * K + t] = (uint16_t)k;
					k++;
				}
			total += k;
			if (k > s->max_len[mode])
				s->max_len[mode] = k;
		}
	free(rep);
	if (build_pairs(s) != LOOM_OK)
		return LOOM_ENOMEM;
	s->own_len[0] = s->own_len[1] = 0;
	for (uint32_t t = 0; t < K; t++) {
		int b = s->blk_code[t] & 1;
		s->own_list[b][s->own_len[b]++] = (uint16_t)t;
	}
	return LOOM_OK;
}

LOOM_API int loom_synth_set_new(const loom_synth_exemplar *ex, uint32_t n_ex,
                                loom_synth_set **out, loom_diag *diag)
{
	loom_synth_set *s;
	uint64_t K = 0;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "synth set: NULL output");
	*out = NULL;
	if (!ex || n_ex == 0)
		return loom__fail(diag, LOOM_EINVAL, "synth set: no exemplars");
	for (uint32_t u = 0; u < n_ex; u++) {
		if (!ex[u].weave || ex[u].rows == 0 || ex[u].cols == 0)
			return loom__fail(diag, LOOM_EINVAL,
			                  "synth set: exemplar %u: empty weave", u);
		if (ex[u].rows > MAX_SIDE || ex[u].cols > MAX_SIDE)
			return loom__fail(diag, LOOM_ERANGE,
			                  "synth set: exemplar %u: %ux%u crossings, at most %u per side",
			                  u, ex[u].rows, ex[u].cols, MAX_SIDE);
		K += (uint64_t)ex[u].rows * ex[u].cols;
	}
	if (K > LOOM_SYNTH_MAX_BLOCKS)
		return loom__fail(diag, LOOM_ERANGE,
		                  "synth set: %llu source blocks, at most %u",
		                  (unsigned long long)K, LOOM_SYNTH_MAX_BLOCKS);
	s = calloc(1, sizeof *s);
	if (!s)
		return loom__fail(diag, LOOM_ENOMEM, "synth set: out of memory");
	s->n_ex = n_ex;
	s->K = (uint32_t)K;
	s->ex = calloc(n_ex, sizeof *s->ex);
	if (!s->ex)
		goto nomem;
	K = 0;
	for (uint32_t u = 0; u < n_ex; u++) {
		ex_info *e = &s->ex[u];
		size_t n = (size_t)ex[u].rows * ex[u].cols;
		e->rows = ex[u].rows;
		e->cols = ex[u].cols;
		e->base = (uint32_t)K;
		e->periodic = ex[u].periodic != 0;
		e->weave = malloc(n);
		if (!e->weave)
			goto nomem;
		for (size_t k = 0; k < n; k++)
			e->weave[k] = ex[u].weave[k] ? 1 : 0;
		if (find_symmetries(e) != LOOM_OK)
			goto nomem;
		if (e->n_chain > s->max_chain)
			s->max_chain = e->n_chain;
		K += n;
	}
	if (alloc_blocks(s) != LOOM_OK || fill_blocks(s) != LOOM_OK ||
	    build_candidates(s) != LOOM_OK)
		goto nomem;
	if (s->own_len[0] == 0 || s->own_len[1] == 0) {
		rc = loom__fail(diag, LOOM_EUNSUPPORTED,
		                "synth set: no exemplar block has the %s on top",
		                s->own_len[0] == 0 ? "weft" : "warp");
		loom_synth_set_free(s);
		return rc;
	}
	*out = s;
	return LOOM_OK;
nomem:
	loom_synth_set_free(s);
	return loom__fail(diag, LOOM_ENOMEM, "synth set: out of memory");
}

LOOM_API uint32_t loom_synth_set_blocks(const loom_synth_set *s)
{
	return s ? s->K : 0;
}

LOOM_API uint32_t loom_synth_set_exemplars(const loom_synth_set *s)
{
	return s ? s->n_ex : 0;
}

LOOM_API uint32_t loom_synth_block_index(const loom_synth_set *s, uint32_t u,
                                         uint32_t r, uint32_t c)
{
	if (!s || u >= s->n_ex || r >= s->ex[u].rows || c >= s->ex[u].cols)
		return NONE;
	return s->ex[u].base + r * s->ex[u].cols + c;
}

LOOM_API int loom_synth_block_info(const loom_synth_set *s, uint32_t t,
                                   loom_synth_block *out)
{
	if (!s || !out)
		return LOOM_EINVAL;
	if (t >= s->K)
		return LOOM_ERANGE;
	out->exemplar = s->blk_ex[t];
	out->row = s->blk_r[t];
	out->col = s->blk_c[t];
	out->code = s->blk_code[t];
	out->up = s->up[t];
	out->down = s->down[t];
	out->left = s->left[t];
	out->right = s->right[t];
	out->n_sym = s->ex[s->blk_ex[t]].n_sym;
	return LOOM_OK;
}

LOOM_API int loom_synth_symmetries(const loom_synth_set *s, uint32_t u,
                                   int chain, const uint16_t **pairs,
                                   uint32_t *n)
{
	if (!s || !pairs || !n)
		return LOOM_EINVAL;
	if (u >= s->n_ex)
		return LOOM_ERANGE;
	*pairs = chain ? s->ex[u].chain : s->ex[u].sym;
	*n = chain ? s->ex[u].n_chain : s->ex[u].n_sym;
	return LOOM_OK;
}

LOOM_API int loom_synth_candidates(const loom_synth_set *s, unsigned code,
                                   int reduced, const uint16_t **list,
                                   uint32_t *n, uint32_t *matches)
{
	int mode = reduced ? 1 : 0;
	if (!s || code > 31)
		return LOOM_EINVAL;
	if (list)
		*list = s->cand + s->cand_off[mode][code];
	if (n)
		*n = s->cand_len[mode][code];
	if (matches)
		*matches = s->cand_match[code];
	return LOOM_OK;
}

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

/* ---- the column DP ------------------------------------------------------ */

#define ONE_V ((int64_t)1 << 32) /* one vertical link in a (V, H) value */
#define DEAD (INT64_MIN / 4)      /* value of the sentinel slot */

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
	uint32_t M = cx->M, K = cx->K, nu = 0, *la = cx->la, *lb = cx->lb, *tmp;
	unsigned c0 = codes[0];

	*full = NONE;
	for (uint32_t q = 0; q < M; q++)
		if (!cx->hb[codes[q ? q - 1 : M - 1] * 32u + codes[q]])
			return q;
	/* backward pass: chain lengths, reach */
	for (uint32_t k = 0; k < cx->len[codes[M - 1]]; k++)
		la[k] = 1;
	la[cx->len[codes[M - 1]]] = 0;
	cx->reach[M - 1] = M - 1;
	for (uint32_t q = M - 1; q-- > 0;) {
		unsigned c = codes[q];
		const uint16_t *dn = pair_map(cx, 1, codes[q + 1], c);
		uint32_t n = cx->len[c], mx = 1;
		for (uint32_t k = 0; k < n; k++) {
			uint32_t l = la[dn[k]] + 1;
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
		if (u == NONE || cx->pos[(size_t)codes[M - 1] * K + u] == NONE)
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
			if (cx->pos[(size_t)codes[q] * K + y] == NONE)
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
		fr[n] = DEAD; /* sentinel slot: "up() is not a candidate" */
		if (tg != NONE && cx->pos[(size_t)c * K + tg] != NONE) {
			int64_t v = ++fr[cx->pos[(size_t)c * K + tg]];
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
	return (size_t)BATCH * M * 3 + (size_t)M * (2 + 4 + 4 + 8 + 2) +
	       (size_t)M * (ml + 1) * 8 + (ml + 1) * (2 + 4 + 4) +
	       ((size_t)s->max_chain + 1) * 8;
}

static int assign_dp(const loom_synth_set *s, const loom_design *d,
                     const loom_synth_options *o, uint16_t *base)
{
	dp_ctx cx;
	uint32_t M = d->rows, N = d->cols, ml;
	uint8_t *codes = NULL;
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
	cx.votes = calloc((size_t)s->max_chain + 1, 4);
	cx.touched = malloc(((size_t)s->max_chain + 1) * 4);
	codes = malloc((size_t)BATCH * M);
	outb = malloc((size_t)BATCH * M * 2);
	prevcol = malloc((size_t)M * 2);
	if (!cx.scratch || !cx.reach || !cx.la || !cx.lb || !cx.f || !cx.foff ||
	    !cx.best || !cx.tgt || !cx.votes || !cx.touched || !codes || !outb ||
	    !prevcol)
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
			}
		}
		for (uint32_t jj = 0; jj < nb; jj++) {
			const uint16_t *prev = jj ? outb + (size_t)(jj - 1) * M :
			                       j0 ? prevcol : NULL;
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
	free(cx.votes);
	free(cx.touched);
	free(codes);
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
	if (o->algo < LOOM_SYNTH_NAIVE || o->algo > LOOM_SYNTH_DP)
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
