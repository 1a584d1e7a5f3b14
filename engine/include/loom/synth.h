/*
 * loom/synth.h - yarn-level synthesis (paper 5.3, 5.4) and edge fixing
 * (paper 5.5).  Include <loom.h>, not this file.  docs/synthesis.md explains
 * the algorithms, the conventions and the measured figures.
 *
 * Everything here is pure computation on plain data: exemplar weaves in,
 * a base assignment (one uint16_t per crossing of the design repeat) out;
 * edge height profiles in, size-independent edge-fix tables out.  Nothing
 * reads or writes files.
 *
 * Source blocks.  Exemplar u has a weave S_u of m_u rows (picks, y) by n_u
 * columns (ends, x), periodic (its neighbours wrap).  Block (u, r, c) gets
 * the global index t = base_u + r*n_u + c with base_u = sum of m_v*n_v over
 * v < u; at most LOOM_SYNTH_MAX_BLOCKS blocks, LOOM_SYNTH_NONE means "no
 * block".
 *
 * Neighbourhood code of a crossing (i, j) of W, or of a block of S_u, with
 * wrapping indices (the same bits as LOOM_DB_CODE_*):
 *   bit 0 own W(i,j), bit 1 N = W(i-1,j), bit 2 S = W(i+1,j),
 *   bit 3 W = W(i,j-1), bit 4 E = W(i,j+1).
 *
 * Bolt.  The design is a repeat of M x N crossings tiling an unbounded bolt.
 * Absolute crossing (I, J) (int64_t, any sign) copies
 *   loom_synth_src(lk, I, J) = shift(base[I mod M][J mod N], group(I, J))
 * where the group of m^ x m^ crossings containing (I, J) picks, from the
 * randomisation key, one translational symmetry per exemplar (paper 5.4).
 *
 * Edge fix.  dz(x, y) is the amount by which the content of an output block
 * is RAISED at its voxel column (x, y), x in [0, b1), y in [0, b2): a lookup
 * of output voxel z reads the source voxel at z - dz.
 *
 * Thread safety: every function taking only const pointers may be called
 * from any number of threads at once.
 */
#ifndef LOOM_SYNTH_H
#define LOOM_SYNTH_H

#include "common.h"
#include "design.h"

#ifdef __cplusplus
extern "C" {
#endif

#define LOOM_SYNTH_NONE 0xFFFFu        /* "no block" */
#define LOOM_SYNTH_MAX_BLOCKS 65535u   /* global block indices 0..65534 */

#define LOOM_SYNTH_CODE_SELF 1u
#define LOOM_SYNTH_CODE_N 2u
#define LOOM_SYNTH_CODE_S 4u
#define LOOM_SYNTH_CODE_W 8u
#define LOOM_SYNTH_CODE_E 16u

/* ======================================================================
 * Exemplar set: blocks, symmetries, candidate lists
 * ====================================================================== */

/* One exemplar as synthesis sees it (fill from loom_db_exemplar). */
typedef struct loom_synth_exemplar {
	uint32_t rows, cols;     /* m_u picks x n_u ends (1..1024 each) */
	const uint8_t *weave;    /* rows*cols row-major, 1 = warp over; copied */
	int periodic;            /* 1 if the VOXEL volume tiles seamlessly, so
	                            blocks across its wrap are contiguous (a
	                            procedural, periodic exemplar); 0 for a cut
	                            window or a scan (the usual case) */
} loom_synth_exemplar;

typedef struct loom_synth_set loom_synth_set; /* opaque, immutable */

/*
 * Build the per-exemplar-set tables: block geometry and neighbours,
 * translational symmetries of every S_u, and the candidate lists of every
 * neighbourhood code.  Cost O(32 K) plus the symmetry search (about a
 * millisecond for eight 5x5 exemplars); memory O(32 K) plus the list-to-list
 * index maps (at most 16 MB).
 * Returns LOOM_OK; LOOM_EINVAL (NULL, zero size, n_ex == 0); LOOM_ERANGE
 * (an exemplar side > 1024 or more than LOOM_SYNTH_MAX_BLOCKS blocks);
 * LOOM_EUNSUPPORTED (no block with the warp on top, or none with the weft:
 * correctness would be impossible); LOOM_ENOMEM.  *out is NULL on failure;
 * diag (may be NULL) says which exemplar.
 */
LOOM_API int loom_synth_set_new(const loom_synth_exemplar *ex, uint32_t n_ex,
                                loom_synth_set **out, loom_diag *diag);

/* Free; NULL is a no-op. */
LOOM_API void loom_synth_set_free(loom_synth_set *s);

/* Number of source blocks K (0 for NULL). */
LOOM_API uint32_t loom_synth_set_blocks(const loom_synth_set *s);

/* Number of exemplars (0 for NULL). */
LOOM_API uint32_t loom_synth_set_exemplars(const loom_synth_set *s);

/* Global index of block (u, r, c); LOOM_SYNTH_NONE out of range. */
LOOM_API uint32_t loom_synth_block_index(const loom_synth_set *s, uint32_t u,
                                         uint32_t r, uint32_t c);

/* Facts about one source block. */
typedef struct loom_synth_block {
	uint32_t exemplar, row, col;
	uint32_t code;       /* neighbourhood code in S_u */
	uint32_t up, down;   /* block (r-1, c) / (r+1, c); LOOM_SYNTH_NONE
	                        across the edge of a non-periodic exemplar */
	uint32_t left, right;/* block (r, c-1) / (r, c+1), likewise */
	uint32_t n_sym;      /* translational symmetries of S_u */
} loom_synth_block;

/* LOOM_OK or LOOM_EINVAL (NULL) / LOOM_ERANGE (t >= K). */
LOOM_API int loom_synth_block_info(const loom_synth_set *s, uint32_t t,
                                   loom_synth_block *out);

/*
 * Symmetries of exemplar u: *n pairs (dr, dc), dr in [0, m_u), dc in
 * [0, n_u), with S_u(r+dr, c+dc) = S_u(r, c) for all r, c; (0, 0) first,
 * then increasing dr*n_u + dc.  chain = 0: all of them (the randomisation
 * draws from at most 64 of them, see loom_synth_lookup); chain = 1: the
 * subgroup that keeps vertical runs of blocks contiguous (all for a
 * periodic exemplar, those with dr = 0 otherwise; used by the DP
 * shortcut).  *pairs points into s.  Returns LOOM_OK; LOOM_EINVAL (NULL s,
 * pairs or n); LOOM_ERANGE (u >= number of exemplars).
 */
LOOM_API int loom_synth_symmetries(const loom_synth_set *s, uint32_t u,
                                   int chain, const uint16_t **pairs,
                                   uint32_t *n);

/*
 * Candidate list of a neighbourhood code (0..31): the blocks with the right
 * own bit (correctness) and the largest number of matching neighbour bits
 * (*matches, 0..4).  reduced = 0: all of them, increasing t; reduced = 1:
 * only those in the representative columns of each exemplar (one column per
 * orbit of the chain symmetries: the paper's translational-symmetry
 * shortcut); every candidate is a chain-symmetric image of a reduced one.
 * *list points into s.  LOOM_OK, LOOM_EINVAL.
 */
LOOM_API int loom_synth_candidates(const loom_synth_set *s, unsigned code,
                                   int reduced, const uint16_t **list,
                                   uint32_t *n, uint32_t *matches);

/* Neighbourhood code of crossing (i, j) of the repeat, wrapping. */
static inline unsigned loom_synth_code(const loom_design *d, uint32_t i,
                                       uint32_t j)
{
	uint32_t im = i ? i - 1 : d->rows - 1, ip = i + 1 == d->rows ? 0 : i + 1;
	uint32_t jm = j ? j - 1 : d->cols - 1, jp = j + 1 == d->cols ? 0 : j + 1;
	return (unsigned)(loom_design_at(d, i, j) | loom_design_at(d, im, j) << 1 |
	                  loom_design_at(d, ip, j) << 2 |
	                  loom_design_at(d, i, jm) << 3 |
	                  loom_design_at(d, i, jp) << 4);
}

/* ======================================================================
 * Assignment
 * ====================================================================== */

enum loom_synth_algo {
	LOOM_SYNTH_NAIVE = 0,  /* a random correct block */
	LOOM_SYNTH_GREEDY = 1, /* a random block of maximal consistency */
	LOOM_SYNTH_DP = 2,     /* max consistency, then max continuity along
	                          each column (Eq. 1), O(K) per crossing */
	LOOM_SYNTH_IDENTITY = 3 /* crossing (i, j) copies block (i, j) of
	                          exemplar 0, whose weave must equal the design
	                          (a woven ground truth, docs/fidelity.md) */
};

/* Option flags (DP only). */
#define LOOM_SYNTH_FULL_LISTS 1u /* DP over full candidate lists instead of
                                    the reduced (symmetry-shortcut) ones:
                                    same vertical optimum, longer lists when
                                    exemplars have chain symmetries */
#define LOOM_SYNTH_NO_HPREF 2u   /* do not use ties and run symmetries to
                                    favour horizontal continuity (random
                                    choices instead) */

typedef struct loom_synth_options {
	size_t size;        /* sizeof(loom_synth_options) */
	int algo;           /* enum loom_synth_algo */
	uint64_t seed;      /* ties, naive/greedy choices and randomisation */
	uint32_t group;     /* m^: side of the randomisation groups; 0 = no
	                       randomisation (used by loom_synth_lookup_init) */
	uint32_t flags;     /* LOOM_SYNTH_* flags */
} loom_synth_options;

#define LOOM_SYNTH_DEFAULT_GROUP 3
#define LOOM_SYNTH_OPTIONS_INIT \
	{sizeof(loom_synth_options), LOOM_SYNTH_DP, 1, LOOM_SYNTH_DEFAULT_GROUP, 0}

/*
 * Compute the base assignment of the design repeat: base[i*cols + j] is the
 * source block of crossing (i, j), for all rows*cols crossings (caller
 * allocates).  Neighbours wrap around the repeat.  Every choice is correct
 * (right yarn on top) and of maximal consistency (greedy, dp); dp keeps of
 * those the blocks whose float runs (how far the crossing's value goes on
 * left, right, up, down) are nearest the design's, and
 * maximises, per column, the number of vertically contiguous pairs
 * including the wrap-around pair, then (unless LOOM_SYNTH_NO_HPREF) the
 * number of crossings continuing the column on its left.  Same inputs and
 * options => same bytes.  Thread-safe (the set is only read).
 * Working memory: loom_synth_assign_work_bytes(), O(rows * longest
 * candidate list), never O(rows * cols).
 * identity: the design must have exemplar 0's size and weave
 * (LOOM_EMISMATCH naming the first differing crossing otherwise).
 * Returns LOOM_OK, LOOM_EINVAL (NULL, bad algo, options.size too small),
 * LOOM_EMISMATCH, LOOM_ENOMEM.  base is unspecified on failure.
 */
LOOM_API int loom_synth_assign(const loom_synth_set *s, const loom_design *d,
                               const loom_synth_options *o, uint16_t *base,
                               loom_diag *diag);

/* Bytes loom_synth_assign allocates for its work (besides base). */
LOOM_API size_t loom_synth_assign_work_bytes(const loom_synth_set *s,
                                             const loom_design *d,
                                             const loom_synth_options *o);

/* ======================================================================
 * Randomised lookup on the unbounded bolt (O(1), no per-crossing state)
 * ====================================================================== */

/* Plain data, filled by loom_synth_lookup_init; points into the set and the
   base, which must outlive it. */
typedef struct loom_synth_lookup {
	const uint16_t *base;     /* rows*cols base assignment */
	uint32_t rows, cols;      /* M, N */
	uint32_t group;           /* m^ (0 = no randomisation) */
	uint64_t key;             /* randomisation key (from the seed) */
	const uint16_t *n_sym;    /* per block: symmetries the randomisation
	                             draws from: min(all symmetries of its
	                             exemplar, 64), spread evenly over them */
	const uint32_t *sym_first;/* per block: first entry in sym_image */
	const uint16_t *sym_image;/* image of block t under symmetry k of its
	                             exemplar: sym_image[sym_first[t] + k] */
} loom_synth_lookup;

/* Fill lk from the set, a base assignment of rows x cols and o->seed,
   o->group.  LOOM_OK or LOOM_EINVAL (NULL argument, rows or cols 0).
   o->size is not checked here. */
LOOM_API int loom_synth_lookup_init(loom_synth_lookup *lk,
                                    const loom_synth_set *s,
                                    const uint16_t *base, uint32_t rows,
                                    uint32_t cols,
                                    const loom_synth_options *o);

/* splitmix64 finaliser. */
static inline uint64_t loom_synth_mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

/* 64-bit hash of a randomisation group (gi, gj) under key. */
static inline uint64_t loom_synth_group_hash(uint64_t key, int64_t gi,
                                             int64_t gj)
{
	return loom_synth_mix(key ^ loom_synth_mix((uint64_t)gi ^
	                                           loom_synth_mix((uint64_t)gj)));
}

/* floor(a / b) and a - b*floor(a / b) for b > 0. */
static inline int64_t loom_synth_floordiv(int64_t a, int64_t b)
{
	int64_t q = a / b;
	return (a % b != 0 && a < 0) ? q - 1 : q;
}
static inline uint64_t loom_synth_floormod(int64_t a, uint64_t b)
{
	int64_t m = a % (int64_t)b;
	return (uint64_t)(m < 0 ? m + (int64_t)b : m);
}

/* Index (0 .. n-1) of the symmetry a group hash selects among n. */
static inline uint32_t loom_synth_pick(uint64_t h, uint32_t n)
{
	return (uint32_t)(((h >> 32) * (uint64_t)n) >> 32);
}

/* Source block of absolute crossing (I, J): the base assignment of
   (I mod M, J mod N), shifted by the symmetry its exemplar gets in the
   group (floor(I/m^), floor(J/m^)). */
static inline uint16_t loom_synth_src(const loom_synth_lookup *lk, int64_t I,
                                      int64_t J)
{
	uint64_t i = loom_synth_floormod(I, lk->rows);
	uint64_t j = loom_synth_floormod(J, lk->cols);
	uint16_t t = lk->base[i * lk->cols + j];
	uint64_t h;

	if (lk->group == 0)
		return t;
	h = loom_synth_group_hash(lk->key, loom_synth_floordiv(I, lk->group),
	                          loom_synth_floordiv(J, lk->group));
	return lk->sym_image[lk->sym_first[t] + loom_synth_pick(h, lk->n_sym[t])];
}

/* The sources of a crossing and its four neighbours (edge-fix input). */
typedef struct loom_synth_nbhd {
	uint16_t self, n, s, w, e;
} loom_synth_nbhd;

static inline void loom_synth_nbhd_at(const loom_synth_lookup *lk, int64_t I,
                                      int64_t J, loom_synth_nbhd *nb)
{
	nb->self = loom_synth_src(lk, I, J);
	nb->n = loom_synth_src(lk, I - 1, J);
	nb->s = loom_synth_src(lk, I + 1, J);
	nb->w = loom_synth_src(lk, I, J - 1);
	nb->e = loom_synth_src(lk, I, J + 1);
}

/* ======================================================================
 * Metrics
 * ====================================================================== */

typedef struct loom_synth_metrics {
	uint64_t crossings;     /* crossings measured */
	uint64_t correct;       /* with the right yarn on top */
	uint64_t consistent;    /* whose 4 neighbour bits all match the
	                           source's neighbours */
	uint64_t matches;       /* total consistency: matching neighbour bits,
	                           summed (0..4 per crossing) */
	uint64_t best_matches;  /* the largest total any assignment can reach
	                           (sum of the candidate match counts) */
	uint64_t pairs;         /* neighbour pairs: (I,J)-(I+1,J), (I,J)-(I,J+1)
	                           for every measured crossing */
	uint64_t continuous;    /* pairs copied from contiguous source blocks */
	uint64_t continuous_v;  /* ... of which vertical (along the warps) */
	uint64_t continuous_h;  /* ... of which horizontal */
	double correctness;     /* correct / crossings */
	double consistency;     /* consistent / crossings */
	double continuity;      /* continuous / pairs */
} loom_synth_metrics;

/*
 * Metrics of a base assignment over the repeat, with wrap-around
 * neighbours.  usage (may be NULL): n_exemplars counters, set to the number
 * of crossings copying from each exemplar.  LOOM_OK, LOOM_EINVAL, LOOM_ERANGE
 * (a base entry >= K).
 */
LOOM_API int loom_synth_metrics_repeat(const loom_synth_set *s,
                                       const loom_design *d,
                                       const uint16_t *base, uint64_t *usage,
                                       loom_synth_metrics *m);

/*
 * The same over the absolute window [i0, i0+h) x [j0, j0+w) of the bolt,
 * after randomisation (each crossing's S and E partners may lie outside the
 * window and are evaluated on demand).  lk must come from the same set and
 * the design's repeat size.  O(h*w) time, O(1) memory.  LOOM_OK or
 * LOOM_EINVAL (NULL, empty design, lk of another size or set).
 */
LOOM_API int loom_synth_metrics_window(const loom_synth_set *s,
                                       const loom_design *d,
                                       const loom_synth_lookup *lk,
                                       int64_t i0, int64_t j0, uint64_t h,
                                       uint64_t w, uint64_t *usage,
                                       loom_synth_metrics *m);

/* ======================================================================
 * Edge fix (paper 5.5)
 * ====================================================================== */

/*
 * Edge height profiles of every source block (from the database): heights
 * in voxels of the top surface of the top-most yarn.  Record t (block t) is
 * LOOM_EDGE_RECORD(b1, b2) floats starting at heights + t*record:
 *   N[b1]  y = 0,      x = 0..b1-1
 *   S[b1]  y = b2-1,   x = 0..b1-1
 *   W[b2]  x = 0,      y = 0..b2-1
 *   E[b2]  x = b1-1,   y = 0..b2-1
 */
typedef struct loom_edge_profiles {
	uint32_t b1, b2;        /* block size in voxels: x (across the ends),
	                           y (along the warps); each >= 3 */
	uint32_t n_blocks;      /* K */
	const float *heights;   /* n_blocks records */
	/* Optional (NULL: none): the set the blocks come from (K = n_blocks).
	   With it, the N (W) data of block t is the S (E) profile of the block
	   above (left of) t in its own exemplar, where t has one, so the fix
	   keeps the jump t had across that edge in the woven exemplar instead
	   of closing the seam; on the exemplar's top row (left column) t's
	   own profile plus the jump of the same neighbourhood one repeat
	   further in (engine/synth/edgefix.c, "Calibration"). */
	const loom_synth_set *set;
} loom_edge_profiles;

#define LOOM_EDGE_RECORD(b1, b2) (2u * (b1) + 2u * (b2))
#define LOOM_EDGE_N(b1, b2) 0u
#define LOOM_EDGE_S(b1, b2) (b1)
#define LOOM_EDGE_W(b1, b2) (2u * (b1))
#define LOOM_EDGE_E(b1, b2) (2u * (b1) + (b2))

/* The default rank: full, each side at its whole profile's rank (the
   exact fix; docs/fidelity.md, "Full rank by default").  Rank 15 was the
   default before 2026-12-07: smaller tables, but at the paper's block
   size it cannot follow fibre-scale heights along an edge. */
#define LOOM_EDGEFIX_DEFAULT_RANK 128
#define LOOM_EDGEFIX_MAX_RANK 128

typedef struct loom_edgefix loom_edgefix; /* opaque, immutable */

/*
 * Build the edge-fix tables of a set of source blocks: a rank-r basis of the
 * (mean-removed) N/S profiles and one of the W/E profiles (interior samples
 * y = 1..b2-2; the profiles as p->set makes them), the 2r basis solutions
 * of the screened discrete Laplace equation of loom_edgefix_exact
 * (N-edge and W-edge data; S and E by mirroring) and, per source block, its
 * four coefficient vectors.  The rank of each basis is min(rank, samples,
 * 2K): rh = min(rank, b1, 2K) for N/S, rv = min(rank, b2-2, 2K) for W/E.
 * Memory (loom_edgefix_bytes): 4 (b1 b2 (rh + rv) + 2 K (rh + rv) +
 * b1 rh + (b2-2) rv + b1 + b2 - 2) bytes plus a small header, i.e. about
 * 8 b1 b2 r + 16 K r bytes when rh = rv = r; independent of any design.
 * Rank 0 builds tables with no basis: every dz is 0 (no edge fix).
 * LOOM_OK, LOOM_EINVAL (NULL, b1 or b2 < 3, K = 0, a non-finite
 * height), LOOM_ERANGE (b1*b2 > 2^24, rank > LOOM_EDGEFIX_MAX_RANK),
 * LOOM_ENOMEM.
 */
LOOM_API int loom_edgefix_build(const loom_edge_profiles *p, uint32_t rank,
                                loom_edgefix **out, loom_diag *diag);

/* Free; NULL is a no-op. */
LOOM_API void loom_edgefix_free(loom_edgefix *ef);

/* Bytes the tables occupy. */
LOOM_API size_t loom_edgefix_bytes(const loom_edgefix *ef);

/*
 * Offset map dz of an output block whose own source and neighbours'
 * sources are nb: dz[y*b1 + x], b1*b2 floats.  4r multiply-adds per voxel
 * column.  No argument checks beyond NULL (block indices must be < K).
 */
LOOM_API void loom_edgefix_block(const loom_edgefix *ef,
                                 const loom_synth_nbhd *nb, float *dz);

/* One value dz(x, y) of the same map (x < b1, y < b2). */
LOOM_API float loom_edgefix_at(const loom_edgefix *ef,
                               const loom_synth_nbhd *nb, uint32_t x,
                               uint32_t y);

/*
 * Exact offsets (no basis, double precision): boundary values
 *   N edge (y = 0, all x):          (S_profile(nb.n)[x] - N_profile(self)[x])/2
 *   S edge (y = b2-1, all x):       (N_profile(nb.s)[x] - S_profile(self)[x])/2
 *   W edge (x = 0, 0 < y < b2-1):   (E_profile(nb.w)[y] - W_profile(self)[y])/2
 *   E edge (x = b1-1, 0 < y < b2-1):(W_profile(nb.e)[y] - E_profile(self)[y])/2
 * (the corners belong to the N and S edges, as in the paper; the profiles
 * as p->set makes them), interior from the screened discrete Laplace
 * equation (4 + k) u(x,y) = u(x-1,y)+u(x+1,y)+u(x,y-1)+u(x,y+1) (which
 * never reads a corner), k = (8 / min(b1, b2))^2, so a seam's correction
 * decays over about min(b1, b2) / 8 voxels; solved by separation in sine
 * modes.  LOOM_OK, LOOM_EINVAL, LOOM_ENOMEM.
 */
LOOM_API int loom_edgefix_exact(const loom_edge_profiles *p,
                                const loom_synth_nbhd *nb, float *dz);

/*
 * The tables as plain arrays; pointers into ef.  The basis fields are
 * stored compactly: along each row y the N/S fields of ranks pre[y] and
 * above are exactly 0 (they decay away from their edge), and so are the
 * W/E fields of ranks pre[b2 + x] and above along each column x; those
 * zeros are not stored.  Field k of (x, y) is
 *   N/S: field_h[off[y] + x*pre[y] + k]                      (k < pre[y])
 *   W/E: field_v[y*off[b2 + b1] + off[b2 + x] + k]           (k < pre[b2 + x])
 * and 0 for the ranks past the prefix; loom_edgefix_field reads it.
 * field_h holds b1 * (pre[0] + ... + pre[b2-1]) floats, field_v
 * b2 * off[b2 + b1].  A fabric file stores the fields whole (every rank
 * of every cell, the zeros included).
 */
typedef struct loom_edgefix_tables {
	uint32_t b1, b2, n_blocks;
	uint32_t rank_h, rank_v;  /* ranks of the N/S and W/E bases */
	const float *coef;        /* per block: cN[rank_h] cS[rank_h]
	                             cW[rank_v] cE[rank_v] */
	const float *field_h;     /* N-edge basis solutions (compact, above) */
	const float *field_v;     /* W-edge basis solutions (compact, above) */
	const float *basis_h;     /* b1*rank_h: basis_h[x*rank_h + k] */
	const float *basis_v;     /* (b2-2)*rank_v: basis_v[(y-1)*rank_v + k] */
	const float *mean_h;      /* b1: mean N/S profile */
	const float *mean_v;      /* b2-2: mean W/E profile (interior) */
	const uint8_t *pre;       /* b2 + b1 prefixes (above); NULL for
	                             loom_edgefix_from_tables: the fields are
	                             whole, field_h[(y*b1 + x)*rank_h + k] and
	                             field_v[(y*b1 + x)*rank_v + k] */
	const uint32_t *off;      /* b2 + b1 + 1 offsets (above); derived from
	                             pre, ignored by loom_edgefix_from_tables */
} loom_edgefix_tables;

/* Field k of cell (x, y) of tables t: the N/S field (vertical 0, k <
   rank_h) or the W/E field (vertical 1, k < rank_v), compact (t->pre
   set) or whole. */
static inline float loom_edgefix_field(const loom_edgefix_tables *t, int vertical,
                                       uint32_t x, uint32_t y, uint32_t k)
{
	if (!t->pre)
		return vertical ? t->field_v[((size_t)y * t->b1 + x) * t->rank_v + k] :
		                  t->field_h[((size_t)y * t->b1 + x) * t->rank_h + k];
	if (vertical)
		return k < t->pre[t->b2 + x] ?
		       t->field_v[(size_t)y * t->off[t->b2 + t->b1] + t->off[t->b2 + x] + k] : 0.0f;
	return k < t->pre[y] ? t->field_h[t->off[y] + (size_t)x * t->pre[y] + k] : 0.0f;
}

LOOM_API int loom_edgefix_get_tables(const loom_edgefix *ef,
                                     loom_edgefix_tables *t);

/* Rebuild an edge-fix object from tables (copied; compact when t->pre is
   set, whole when it is NULL).  LOOM_OK, LOOM_EINVAL (NULL, inconsistent
   sizes or a prefix above its rank), LOOM_ENOMEM. */
LOOM_API int loom_edgefix_from_tables(const loom_edgefix_tables *t,
                                      loom_edgefix **out, loom_diag *diag);

/*
 * The paper's per-OUTPUT-block formulation, for verification: stack the
 * N-edge vectors t_i (b1) and interior W-edge vectors l_i (b2-2) of every
 * crossing of an assignment (rows x cols, wrapping) into T and L, take
 * rank-r bases (own eigen-decomposition of T T^t and L L^t, or the bases of
 * `basis` if not NULL), solve the 2r basis problems and evaluate
 *   s_i = sum_k C_T(k,i) s^T_k + C_L(k,i) s^L_k - C_T(k,S(i)) ~s^T_k
 *         - C_L(k,E(i)) ~s^L_k
 * (~ = mirrored copy), with the screened equation of loom_edgefix_exact;
 * the profiles are used as given (p->set is ignored).  Memory 8 r rows cols
 * bytes for C_T and C_L: the paper's ~150 MB at 900 x 1500.
 */
typedef struct loom_edgefix_paper loom_edgefix_paper;

LOOM_API int loom_edgefix_paper_new(const loom_edge_profiles *p,
                                    const uint16_t *assign, uint32_t rows,
                                    uint32_t cols, uint32_t rank,
                                    const loom_edgefix *basis,
                                    loom_edgefix_paper **out,
                                    loom_diag *diag);
LOOM_API int loom_edgefix_paper_block(const loom_edgefix_paper *pp,
                                      uint32_t i, uint32_t j, float *dz);
LOOM_API size_t loom_edgefix_paper_bytes(const loom_edgefix_paper *pp);
LOOM_API void loom_edgefix_paper_free(loom_edgefix_paper *pp);

/* Seam metric over a window of output blocks. */
typedef struct loom_seam_metrics {
	uint64_t samples;       /* edge samples compared: b1 per S edge, b2 per
	                           E edge of every block of the window */
	double before_mean, before_max; /* |height jump| without the fix */
	double after_mean, after_max;   /* with the rank-r offsets */
	uint64_t corner_samples;/* E-edge samples at y = 0, b2-1 (the corners
	                           belong to the N/S edges: loom_edgefix_exact) */
	double corner_before_mean, corner_after_mean;
	double internal_step;   /* input: mean |height change| between
	                           neighbouring voxel columns inside blocks */
	double before_ratio, after_ratio; /* means / internal_step (0 if 0) */
} loom_seam_metrics;

/*
 * Mean and max absolute jump of the top-surface height across the S and E
 * edges of every block of [i0, i0+h) x [j0, j0+w): height = profile +
 * offset on each side.  lk gives the (randomised) sources.  LOOM_OK,
 * LOOM_EINVAL (NULL, sizes differ between ef and p).
 */
LOOM_API int loom_edgefix_seam(const loom_edgefix *ef,
                               const loom_edge_profiles *p,
                               const loom_synth_lookup *lk, int64_t i0,
                               int64_t j0, uint64_t h, uint64_t w,
                               double internal_step, loom_seam_metrics *out);

/* Mean |jump| along the S edge and the E edge of block (I, J), before and
   after: out[0] S before, out[1] S after, out[2] E before, out[3] E after
   (for seam pictures). */
LOOM_API int loom_edgefix_seam_block(const loom_edgefix *ef,
                                     const loom_edge_profiles *p,
                                     const loom_synth_lookup *lk, int64_t I,
                                     int64_t J, double out[4]);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_SYNTH_H */
