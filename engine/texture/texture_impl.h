/*
 * engine/texture/texture_impl.h - the virtual texture's shared types and hot
 * inline helpers, included only by the files of engine/texture/ (never
 * installed; the unit tests use texture_internal.h).
 *
 * The texture is split by job:
 *
 *   texture.c   open, close, the memory budget and its split, statistics
 *   slots.c     per-thread slots: the registry of open textures, the
 *               thread-local bindings, the pool and the overflow slot
 *   lookup.c    crossings, edge-fix offsets, bricks; point, trilinear and
 *               batch lookups (the lookup steps 1-6)
 *   region.c    region reads (grouped z-runs, the x-fastest transposes,
 *               the SIMD label mappings)
 *   cache.c     the brick cache (cache.h)
 *   lod.c       level of detail: coarse levels built through the cache,
 *               coarse lookups
 *
 * What is hot stays inline here (slot_enter, the column offset, brick
 * coordinates), so that the split costs no call on the lookup path.
 */
#ifndef LOOM_TEXTURE_IMPL_H
#define LOOM_TEXTURE_IMPL_H

#include "texture_internal.h"

#include "cache.h"
#include "exemplar/db_internal.h"
#include "synth/fabric_internal.h"

#include <pthread.h>
#include <stdatomic.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define XENT_WAYS 4         /* crossing entries per set (LRU inside a set) */
#define XENT_NONE INT64_MIN /* the key of an entry not set up (no crossing:
                               |I| < 2^62 for coordinates below 2^62) */
#define XENT_MAX 256        /* crossing entries per thread slot, at most */
#define TL_BINDINGS 8       /* textures one thread keeps bound at once */
#define NO_BRICK UINT64_MAX
/* Cache key of a density unit (texture.c): this bit | g, a frame of the
   density planes of the stored bricks of ranks 4g .. 4g+3 (dunit_key;
   layout-2 and -3 databases, density-only lookups; LOD off), each plane
   filled segment by segment on first use (loom__dunit_fill; a layout-2
   plane is one segment). */
#define DUNIT_TAG ((uint64_t)1 << 62)
/* t->hint: the frame holds the brick's density unit, not the brick */
#define HINT_DUNIT ((uint32_t)1 << 31)
#define COORD_LIMIT ((int64_t)1 << 62) /* |x|, |y|, |z| below this */
#define DZ_SUB 16           /* dz is kept in 1/DZ_SUB voxel (fixed point; a
                               power of two, dz_split) */
#define DZ_LIMIT 2047       /* |dz| clamp, voxels (int16 fixed point) */
#define ALIGN 64
#define RCOLS 64            /* columns gathered at once (x-fastest regions) */
#define RZ 64               /* z values gathered at once */
#define OCC_T 4             /* side of an occupancy tile, columns */
#define DZ_WAYS 4           /* shared offset maps per set */
#define DZ_RUN 4            /* offsets in a row in one entry before it may
                               take a map from another crossing */
#define DZ_BIAS 32768       /* a map lane holds q + DZ_BIAS (never 0); 0: not
                               computed yet */
#define NO_MAP UINT32_MAX
#define MAP_CLOSED 0x80000000u /* a map's writer count while it is reclaimed */

#define LOOM__HIDDEN __attribute__((visibility("hidden")))

#define LOD_MAX 3           /* coarse levels 1..LOD_MAX (2x, 4x, 8x; lod.c) */
#define LOD_PLANES 5        /* density, orientation lo, hi, label, anisotropy */
#define LOD_BOX (1 << LOD_MAX) /* level-0 voxels per axis of a coarsest voxel */
/* How far a coarse voxel's fibres widen the microflake lobe: the render
   adds LOD_SPREAD_GAIN (1 - a) / 3 to s^2 (a the anisotropy).  Fitted to
   0 on the grazing scene of docs/rendering.md together with
   LOOM__LOD_EXTINCTION_MM: the wider lobe made far cloth brighter (with
   the 13-direction density fit too: gain 1 made 12-40 degrees 7-8
   levels of 255 brighter).  The fit uses the widened lobe (lod.c). */
#define LOD_SPREAD_GAIN 0.0f
#define LOD_DIRS 13 /* path directions of the coarse density fit (lod.c) */
/* The flake lobe width s that the coarse density fit's projected areas
   assume (lod.c, lod_area): the middle of the gallery's yarns (0.15-0.3);
   the renderer's per-yarn s is not known when a level is built. */
#define LOD_FLAKE_S 0.2

/* Per exemplar, read-only after open. */
struct exm {
	uint32_t first_brick;    /* global id of brick (0, 0, 0) */
	uint32_t nb[3];          /* bricks along x, y, z */
	uint8_t kind[256];       /* label -> enum loom_yarn_kind */
	uint8_t ngrp;            /* labels with a kind are below 16 * ngrp
	                            (region reads: kind_type's PSHUFB tables);
	                            0: above 8 groups, table lookups instead */
	uint32_t size[3];        /* voxels (level 0) */
	uint32_t lfirst[LOD_MAX + 1];   /* coarse level k: id of its brick
	                                   (0, 0, 0), n_bricks + ... (lod.c) */
	uint32_t lsize[LOD_MAX + 1][3]; /* its voxels: ceil(size / 2^k) */
	uint32_t lnb[LOD_MAX + 1][3];   /* its bricks along x, y, z */
};

/* One crossing of a thread's small cache (steps 2-3). */
struct xent {
	int64_t I, J;            /* crossing */
	int64_t x0, y0;          /* its first output voxel: J*b1, I*b2 */
	const struct exm *ex;    /* source exemplar */
	uint32_t sx0, sy0;       /* source block origin in the exemplar */
	uint32_t stamp;          /* last use (LRU); set up: the slot's etag */
	uint8_t tok[4];          /* yarn type by kind: 0, warp, weft, 0 */
	uint8_t tlut_ok;         /* tlut is built */
	uint32_t map;            /* the shared offset map of (I, J) (NO_MAP: none,
	                            every offset computed on the spot) */
	uint64_t gen;            /* the map's generation when attached */
	_Atomic uint64_t *w;     /* the map's lanes (4 columns a word) */
	float *a;                /* edge-fix coefficients n[rh] s[rh] w[rv] e[rv] */
	int32_t wlo, whi;        /* every column of the crossing but its four
	                            corners reads output voxel z from source
	                            voxels in [z - whi, z - wlo]; wlo > whi: no
	                            bound (lookup.c xent_bound, src_air) */
	/* what point lookups use is above (the first two cache lines); the
	   region reads' table last */
	uint8_t tlut[256];       /* label -> yarn type (region reads) */
};

/* Header of a shared offset map (texture.c: "shared offset maps"). */
struct dzmap {
	_Atomic int64_t I, J;    /* its crossing, under the generation */
	_Atomic uint32_t refs;   /* writers in flight; MAP_CLOSED while it is
	                            being reclaimed for another crossing */
	_Atomic uint32_t used;   /* CLOCK bit (replacement inside a set) */
};

/* Per-slot counters: written by the slot's current thread only (relaxed
   load + store), summed by loom_texture_get_stats. */
struct counters {
	_Atomic uint64_t lookups, memo_hits, empty, xings, dz, errors;
	_Atomic uint64_t dfills, dfill_ns; /* density unit fills (one or more
	                                     segments each) */
	_Atomic uint64_t dfill_bytes;     /* the bytes they inflated */
};

/* A trilinear corner column's steps 2-3 (lookup.c pair_raw): output
   column (x, y), its crossing entry, source column and offset. */
struct colmemo {
	int64_t x, y;
	struct xent *e;          /* NULL: empty (cleared when an entry is set up) */
	uint32_t sx, sy;
	int q;
};

struct tslot {
	loom__cache_thread *cth; /* attached at open, for the slot's life */
	struct xent *cur;        /* the entry of the last lookup (or NULL) */
	uint64_t memo_id;        /* current brick (NO_BRICK: none) */
	const uint8_t *memo;     /* its bytes; NULL for an empty brick */
	int memo_pinned;         /* memo holds a caller pin */
	uint32_t memo_off;       /* memo - its frame (a density unit's plane) */
	uint8_t memo_seg;        /* a density unit's plane: bit q set when
	                            segment q is known filled (0xff: all, and
	                            for whole bricks) */
	int64_t wx, wy;          /* footprint of the last lookup (lookup.c
	                            walk_next: hints only) */
	uint32_t wsx, wsy, wsz;  /* the last source voxel read (in memo) */
	int8_t wdx, wdy;         /* the last unit steps' signs along x, y */
	int64_t tx, ty;          /* the last density-only trilinear footprint's
	                            corner, and the signs of its last moves
	                            along x, y (lookup.c tri_next: hints only) */
	int8_t tdx, tdy;
	struct colmemo cm[4];    /* by the parity of x and y: the last
	                            trilinear footprint's 2 x 2 columns */
	int shared;              /* the overflow slot */
	const struct xent *dz_prev; /* the entry of the last offset evaluated */
	uint32_t dz_run;         /* offsets evaluated in a row in dz_prev
	                            (lookup.c, loom__dz_slow: when a map may
	                            be taken from another crossing) */
	uint32_t clock;          /* stamps for the entries' LRU */
	uint32_t next_free;      /* pool free list */
	struct xent *ent;        /* n_ent crossing entries: n_ent / XENT_WAYS
	                            sets of XENT_WAYS, set = hash(I, J) */
	int64_t *etag;           /* entry k's (I, J) at 2k, 2k + 1 (XENT_NONE:
	                            not set up), so that a set's XENT_WAYS keys
	                            are one cache line (lookup.c xent_enter) */
	uint8_t *rbuf;           /* region gather buffer: 6 planes of RCOLS*RZ */
	struct counters cnt;
	char msg[LOOM_DIAG_MSG_MAX]; /* last error of this slot */
} __attribute__((aligned(ALIGN)));

struct loom_texture {
	const loom_fabric *fab;
	const loom_db *db;
	uint64_t serial;         /* unique per open, never reused */
	uint32_t b1, b2, b3;
	uint32_t bs[3];          /* brick shape */
	uint32_t sh[3], mk[3];   /* shifts and masks when pow2 */
	int pow2;                /* every brick side a power of two */
	int seg_brick;           /* the brick height a multiple of SEG_Z: a
	                            segment lies in one brick line */
	uint8_t solid;           /* a solid density byte is >= this: the
	                            database's top_threshold (at least 1) */
	int ssse3;               /* the CPU has SSSE3 (kind_type) */
	int avx512;              /* the CPU has AVX-512BW (region.c's line masks) */
	int avx2;                /* the CPU has AVX2 (region.c's line path
	                            for density alone without AVX-512BW) */
	int region_whole;        /* region reads copy every column with its
	                            nearer whole offset, no blend (the bench's
	                            whole-voxel peer; loom__texture_region_whole) */
	int region_no_occ;       /* region reads do not use occa
	                            (loom__texture_region_occ) */
	size_t bv;               /* voxels per brick (plane size) */
	uint32_t rh, rv;         /* edge-fix ranks */
	const float *coef, *field_h, *field_v; /* the fabric's tables */
	const uint8_t *rpre;     /* ranks stored and summed: b2 rows (N/S
	                            fields), then b1 columns (W/E) */
	const uint32_t *roff;    /* offsets of the compact fields (the
	                            fabric's loom_edgefix_tables pre, off) */
	float frange[4][4 * LOOM_EDGEFIX_MAX_RANK]; /* min, max of each basis
	                            field (2 rh, then 2 rv) over the block's
	                            first row, last row, first column, last
	                            column (lookup.c xent_bound) */
	float dens[256];         /* density byte -> d / 255 (correctly rounded) */
	float albedo[LOOM_MAX_YARN_TYPES][3];
	float align[LOOM_MAX_YARN_TYPES];
	struct exm *ex;          /* n_ex entries (in mem) */
	uint32_t n_ex;
	uint64_t *empty;         /* bit per brick: stored as nothing (in mem) */
	uint32_t *ne_rank;       /* per word of empty: the stored (non-empty)
	                            bricks before it (in mem); density units
	                            group stored bricks by this rank */
	uint32_t n_stored;       /* bricks not empty */
	_Atomic uint16_t *occ;   /* per stored brick (by rank), per tile of
	                            OCC_T x OCC_T columns: 0 not known yet;
	                            else lo | (hi + 1) << 8, the heights in the
	                            brick of the tile's first and last voxel of
	                            non-zero density (0x00ff: none); filled when
	                            a brick's density plane is read whole (in
	                            mem; NULL: no table, lookup.c src_air) */
	_Atomic uint16_t *occa;  /* the same over every plane (the heights of
	                            the first and last voxel with any non-zero
	                            byte), filled when a brick is read whole;
	                            region reads bound their output rows by it
	                            (region.c chunk_extent); NULL with occ */
	uint32_t occ_tx, occ_nt; /* tiles per brick row, per brick */
	_Atomic uint64_t dunit_loads; /* unit frames claimed (they read nothing) */
	_Atomic uint64_t *dstate; /* per density unit (in mem): bit 8j + q
	                            segment q of plane j filled, bit 32 + 8j + q
	                            being filled; reset by the unit's load
	                            (loom__dunit_fill) */
	_Atomic uint32_t *hint;  /* per brick: 1 + the cache frame it was last
	                            got from, 0 = none, | HINT_DUNIT when that
	                            frame is its density unit (a prefetch hint
	                            only, lookup.c src_prefetch; in mem) */
	uint32_t n_bricks;
	uint8_t *slots;          /* n_slots thread slots (in mem) */
	loom__cache *cache;
	unsigned n_slots;        /* max_threads + 1 (the last is the overflow) */
	size_t slot_bytes;
	uint32_t n_ent;          /* crossing entries per slot (a power of two,
	                            XENT_WAYS .. XENT_MAX, from the budget) */
	uint32_t xent_ib, xent_jb; /* a set's index: the low xent_ib bits of I
	                              beside the low xent_jb bits of J */
	uint64_t rb1, rb2;       /* ceil(2^64 / b) for b1, b2 (0 for b = 1):
	                            x / b1 by a multiply for 0 <= x < 2^32
	                            (lookup.c xing_div) */
	uint32_t n_maps;         /* shared offset maps (DZ_WAYS x a power of
	                            two, from the budget) */
	size_t map_words;        /* 64-bit words of one map */
	struct dzmap *maps;      /* n_maps headers (in mem) */
	_Atomic uint64_t *mapgen; /* n_maps generations: even, 0 = never used;
	                            odd while being reclaimed (in mem) */
	_Atomic uint64_t *mapw;  /* n_maps x map_words lanes (in mem) */
	pthread_mutex_t map_lock; /* reclaiming a map */
	uint8_t *mem;            /* the block allocated at open */
	size_t fixed_bytes;      /* what the budget counts for it */
	size_t budget;
	pthread_mutex_t pool_lock;
	uint32_t free_head;      /* pool free list (n_slots: none) */
	_Atomic uint32_t n_free; /* pool slots free */
	pthread_mutex_t overflow_lock;
	pthread_mutex_t msg_lock;
	char msg[LOOM_DIAG_MSG_MAX]; /* last error of any thread */
	_Atomic uint64_t bytes_read;
	unsigned lod;            /* coarse levels available (0: LOD off; lod.c) */
	int dunits;              /* density-only lookups use density units */
	unsigned dsegs;          /* segments of a density plane (8; 1 for a
	                            layout-2 database) */
	uint32_t dseg_rows;      /* brick rows per density segment */
	uint8_t dseg_pad;        /* segment bits past the database's (set) */
	uint32_t cbs[3];         /* coarse brick shape: bx, by, bz / 2 */
	size_t cbv;              /* voxels per coarse brick */
	double lod_sigma;        /* extinction of a density byte over one voxel
	                            for the coarse density (lod.c) */
	loom_texture *live_next; /* registry (slots.c, under its lock) */
};

/* One thread's binding of a texture to a slot (slots.c). */
struct loom__binding {
	uint64_t serial;               /* 0: unused */
	loom_texture *tex;             /* only followed once found alive */
	struct tslot *slot;
};

/* The calling thread's bindings, most recent first (slots.c). */
extern _Thread_local struct loom__binding loom__tl_bind[TL_BINDINGS] LOOM__HIDDEN;

static inline size_t round_up(size_t n, size_t a)
{
	return (n + a - 1) / a * a;
}

static inline void bump(_Atomic uint64_t *c, uint64_t n) /* single writer */
{
	atomic_store_explicit(c, atomic_load_explicit(c, memory_order_relaxed) + n,
	                      memory_order_relaxed);
}

static inline uint64_t rd(const _Atomic uint64_t *c)
{
	return atomic_load_explicit(c, memory_order_relaxed);
}

static inline struct tslot *slot_at(const loom_texture *t, unsigned i)
{
	return (struct tslot *)(t->slots + (size_t)i * t->slot_bytes);
}

/* 1 if brick id is stored as nothing (all empty). */
static inline int brick_empty(const loom_texture *t, uint64_t id)
{
	return id < t->n_bricks && (t->empty[id >> 6] >> (id & 63) & 1);
}

/* The bits set in x, inline: the portable build (no -mpopcnt) would call
   libgcc's __popcountdi2 for __builtin_popcountll, 3 % of warm random
   lookups in a profile. */
static inline uint32_t pop64(uint64_t x)
{
	x -= (x >> 1) & 0x5555555555555555ull;
	x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
	x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0full;
	return (uint32_t)((x * 0x0101010101010101ull) >> 56);
}

/* The rank of stored brick id among the stored bricks (ids in order). */
static inline uint32_t stored_rank(const loom_texture *t, uint64_t id)
{
	uint64_t below = ((uint64_t)1 << (id & 63)) - 1;
	return t->ne_rank[id >> 6] + pop64(~t->empty[id >> 6] & below);
}

/* The cache key of stored brick id's density unit, and where its density
   plane lies in that unit's frame.  A unit holds the stored bricks of
   ranks 4g .. 4g+3: empty bricks take no place (most brick columns of an
   exemplar have empty bricks above and below the cloth, so units of
   consecutive ids held 1.4 used planes of 4 on the paper database). */
static inline uint64_t dunit_key(const loom_texture *t, uint64_t id)
{
	return DUNIT_TAG | stored_rank(t, id) >> 2;
}

static inline size_t dunit_off(const loom_texture *t, uint64_t id)
{
	return (size_t)(stored_rank(t, id) & 3) * t->bv;
}

static inline void memo_drop(struct tslot *s)
{
	if (s->memo_pinned)
		loom__cache_release(s->cth, s->memo - s->memo_off);
	s->memo_pinned = 0;
	s->memo_off = 0;
	s->memo_seg = 0xff;
	s->memo = NULL;
	s->memo_id = NO_BRICK;
}

static inline int coord_ok(int64_t v)
{
	return v > -COORD_LIMIT && v < COORD_LIMIT;
}

/* ------------------------------------------------ slots.c (threads) */

/* The slow path of slot_enter: another binding, or a new one. */
struct tslot *loom__slot_bind(loom_texture *t);
/* A pool slot, or NULL when the pool is empty. */
struct tslot *loom__pool_take(loom_texture *t);
/* Record a failed brick read on the slot and the texture; returns rc. */
int loom__slot_error(loom_texture *t, struct tslot *s, int rc, const char *msg);
/* Give slot s (the calling thread's) back to t's pool; t is alive. */
void loom__slot_return(loom_texture *t, struct tslot *s);
/* Add t to the registry of open textures (gives it its serial); remove
   it (bindings to it are no longer followed). */
void loom__registry_add(loom_texture *t);
void loom__registry_remove(loom_texture *t);

/* The calling thread's slot on t, locked if it is the overflow slot. */
static inline struct tslot *slot_enter(loom_texture *t)
{
	struct tslot *s = loom__tl_bind[0].serial == t->serial ? loom__tl_bind[0].slot
	                                                       : loom__slot_bind(t);

	if (s->shared) {
		struct tslot *p;
		if (atomic_load_explicit(&t->n_free, memory_order_relaxed) &&
		    (p = loom__pool_take(t)) != NULL) {
			loom__tl_bind[0].slot = p; /* leave the overflow slot */
			return p;
		}
		pthread_mutex_lock(&t->overflow_lock);
	}
	return s;
}

static inline void slot_leave(loom_texture *t, struct tslot *s)
{
	if (s->shared)
		pthread_mutex_unlock(&t->overflow_lock);
}

/* ------------------------------------------ lookup.c (crossings, bricks) */

/* Step 2: the entry of the crossing holding (x, y). */
struct xent *loom__xent_enter(loom_texture *t, struct tslot *s, int64_t x, int64_t y);
/* Step 5: make brick id the slot's current brick. */
int loom__memo_switch(loom_texture *t, struct tslot *s, uint64_t id);
/* Step 5 when the slot's current brick may already be id: switch to id
   only if it is not (a hit is counted). */
static inline int memo_use(loom_texture *t, struct tslot *s, uint64_t id)
{
	if (id != s->memo_id)
		return loom__memo_switch(t, s, id);
	bump(&s->cnt.memo_hits, 1);
	return LOOM_OK;
}

/* Inflate segment q of stored brick id's density plane into its unit's
   pinned frame unless it is there already (texture.c; waits while another
   thread fills it). */
int loom__dunit_fill(loom_texture *t, struct tslot *s, uint64_t id, unsigned q,
                     const uint8_t *frame, loom_diag *diag);
/* The segments of stored brick id's density plane filled in its unit
   (bit q), with the bits past the database's segments set. */
uint8_t loom__dunit_segs(const loom_texture *t, uint64_t id);
int loom__memo_seg_fill(loom_texture *t, struct tslot *s, uint32_t sy);

/* After memo_use of a density unit: make sure the segment of source row
   sy is filled (nothing to do for whole bricks and full planes). */
static inline int memo_seg_use(loom_texture *t, struct tslot *s, uint32_t sy)
{
	if (__builtin_expect(s->memo_seg == 0xff, 1))
		return LOOM_OK;
	return loom__memo_seg_fill(t, s, sy);
}

/* Step 3: dz of column (x, y) of an entry, in the edge-fix module's
   order of operations (so equal to loom_edgefix_block bit for bit). */
static inline float dz_eval(const loom_texture *t, const float *a, uint32_t x,
                            uint32_t y)
{
	uint32_t b1 = t->b1, b2 = t->b2, rh = t->rh, rv = t->rv;
	uint32_t ys = b2 - 1 - y, xe = b1 - 1 - x;
	const float *an = a, *as = a + rh, *aw = a + 2 * rh, *ae = a + 2 * rh + rv;
	/* each sum over the ranks stored along this row or column (t->rpre):
	   the terms left out are +-0 */
	uint32_t pn = t->rpre[y], ps = t->rpre[ys];
	uint32_t pw = t->rpre[b2 + x], pe = t->rpre[b2 + xe];
	size_t row_v = (size_t)y * t->roff[b2 + b1];
	const float *fn = t->field_h + t->roff[y] + (size_t)x * pn;
	const float *fs = t->field_h + t->roff[ys] + (size_t)x * ps;
	const float *fw = t->field_v + row_v + t->roff[b2 + x];
	const float *fe = t->field_v + row_v + t->roff[b2 + xe];
	float sn = 0, ss = 0, sw = 0, se = 0;
	uint32_t k = 0, m = pn < ps ? pn : ps;

	m = m < pw ? m : pw;
	m = m < pe ? m : pe;
	/* the four dot products interleaved while all four run: independent
	   chains, each summed in k order, so the same values as four separate
	   loops */
	for (; k < m; k++) {
		sn += an[k] * fn[k];
		ss += as[k] * fs[k];
		sw += aw[k] * fw[k];
		se += ae[k] * fe[k];
	}
	for (uint32_t j = k; j < pn; j++)
		sn += an[j] * fn[j];
	for (uint32_t j = k; j < ps; j++)
		ss += as[j] * fs[j];
	for (uint32_t j = k; j < pw; j++)
		sw += aw[j] * fw[j];
	for (uint32_t j = k; j < pe; j++)
		se += ae[j] * fe[j];
	return sn + ss + sw + se;
}

/* Step 3 when the entry's shared map does not answer: attach it again if
   it was reclaimed, evaluate the offset, store it in the map (lookup.c). */
int loom__dz_slow(const loom_texture *t, struct tslot *s, struct xent *e, uint32_t lx,
                  uint32_t ly);
/* Step 2's part: attach entry e (I, J set) to the shared map of its
   crossing, claiming one if none holds it; with evict 0 only a map no
   crossing has used yet (lookup.c). */
void loom__dzmap_attach(loom_texture *t, struct xent *e, int evict);

/* Step 3, from the shared offset map of the entry's crossing: the offset
   of column (lx, ly) in 1/DZ_SUB voxel (loom__dz_fixed).  One load of the
   column's lane (computed and value in one), then the map's generation
   (a small array, in L1): a map reclaimed since the entry attached it
   changed its generation before any lane (seqlock order: lanes read with
   acquire, written with release), so a lane read with the generation
   unchanged is this crossing's. */
static inline int xent_dz(const loom_texture *t, struct tslot *s, struct xent *e,
                          uint32_t lx, uint32_t ly)
{
	size_t c = (size_t)ly * t->b1 + lx;
	if (e->map != NO_MAP) {
		uint64_t w = atomic_load_explicit(&e->w[c >> 2], memory_order_acquire);
		unsigned v = (unsigned)(w >> (16 * (c & 3))) & 0xffffu;
		if (v && atomic_load_explicit(&t->mapgen[e->map], memory_order_relaxed) == e->gen)
			return (int)v - DZ_BIAS;
	}
	return loom__dz_slow(t, s, e, lx, ly);
}

/* Split a fixed-point offset q into whole voxels w = floor(q / DZ_SUB) and
   the fraction f = q - w * DZ_SUB in [0, DZ_SUB). */
static inline int dz_split(int q, int *f)
{
	/* DZ_SUB is a power of two: the remainder by masking (two's
	   complement), then an exact division */
	int r = (int)((unsigned)q & (DZ_SUB - 1));
	*f = r;
	return (q - r) / DZ_SUB;
}

/* Raw voxel: the encodings plus kind and type. */
typedef struct rawvox {
	uint8_t d, l, k, ty;
	uint16_t o;
} rawvox;

/* The voxel at source height z - w - f/DZ_SUB (0 < f < DZ_SUB) from its
   two source voxels a = z - w - 1 (weight f/DZ_SUB) and b = z - w (weight
   1 - f/DZ_SUB).  The nearer one (b when f <= DZ_SUB/2) decides: where it
   is empty the voxel is empty; otherwise the voxel has the nearer one's
   planes (orientation, label, kind, type), and its density too, except
   at the top of a surface: where the farther one is empty and no voxel
   above the nearer one in its segment (SEG_Z below) is *solid* (density
   byte at least the database's top-surface threshold, t->solid), the
   density byte is blended linearly with the empty voxel and rounded, in
   integer arithmetic, ((DZ_SUB - g) n + DZ_SUB/2) / DZ_SUB, g the farther
   voxel's weight (g <= DZ_SUB/2: at least half the nearer's density, and
   at least 1).  So every density is the woven cloth's own at one of the
   two heights, or a voxel of the top surface (or of the loose fibres over
   it) at half its density or more, as the generator makes them (it fills
   a voxel whose centre is inside a yarn, at half density or more at its
   edge); never the faint voxel a blend with the air beyond a surface
   makes, nor the average of two fibres, nor a fibre halved over the gap
   below it inside the yarn (docs/fidelity.md, "Densities at the floor"
   and "Blending the top voxel only").  The top surface still moves with
   f (its voxel's density falls as its farther weight grows; a voxel
   appears, at half density or more, where it becomes the nearer).  Only
   the density plane needs both source voxels, and the segment's only
   for a surface. */

/* A segment: the voxels of a source column from a multiple of SEG_Z to
   the next (cut at the block's top).  Fibre cloth has a surface over
   every gap between fibres; blending each of them halved fibre voxels at
   every depth, which the woven cloth does not do.  Solid, not merely
   non-empty: the loose fibre ends over a yarn (faint voxels) must not
   keep its surface voxel from moving (they did, and the seams and
   corners measured on the top surface jumped more).  The segment bounds
   the search for a solid voxel above to 15 bytes, of the brick line the
   lookup holds when the brick height is a multiple of SEG_Z
   (t->seg_brick; the default 64 is); the voxels are the same for every
   brick shape. */
#define SEG_Z 16

/* The end (exclusive) of the segment of source voxel z, z < b3. */
static inline uint32_t seg_end(uint32_t z, uint32_t b3)
{
	uint32_t e = (z / SEG_Z + 1) * SEG_Z;
	return e < b3 ? e : b3;
}

/* 1 when none of the n density bytes p[0 .. n) is at least solid (>= 1). */
static inline int none_solid(const uint8_t *p, uint32_t n, uint8_t solid)
{
	for (uint32_t i = 0; i < n; i++)
		if (p[i] >= solid)
			return 0;
	return 1;
}

/* The same for bytes lo .. hi - 1 (lo <= hi <= SEG_Z) of a segment whose
   SEG_Z bytes from seg on are all readable (a brick line, t->seg_brick):
   one load and one compare. */
static inline int seg_none_solid(const uint8_t *seg, uint32_t lo, uint32_t hi, uint8_t solid)
{
#ifdef __SSE2__
	__m128i v = _mm_loadu_si128((const __m128i *)seg);
	unsigned m = (unsigned)_mm_movemask_epi8(
		_mm_cmpeq_epi8(_mm_max_epu8(v, _mm_set1_epi8((char)solid)), v));
	return !(m & ((1u << hi) - 1u) & ~((1u << lo) - 1u));
#else
	return none_solid(seg + lo, hi - lo, solid);
#endif
}

/* 1 when none of source voxels u .. v - 1 (u <= v, one segment) of a
   brick line is solid; line points at the line's voxel z (any voxel of
   the line).  With t->seg_brick the segment's SEG_Z bytes all lie in the
   line: one load (seg_none_solid); else byte by byte. */
static inline int line_none_solid(const loom_texture *t, const uint8_t *line, uint32_t z,
                                  uint32_t u, uint32_t v)
{
	if (u >= v)
		return 1;
	if (t->seg_brick) {
		uint32_t s0 = (v - 1) / SEG_Z * SEG_Z; /* the segment's first voxel */
		return seg_none_solid(line + ((int64_t)s0 - (int64_t)z), u - s0, v - s0, t->solid);
	}
	return none_solid(line + (u - z), v - u, t->solid);
}

/* The density of the voxel blended from a = z - w - 1 and b = z - w with
   fraction f (as above): top is whether no voxel above the nearer one in
   its segment is solid, which only matters (and is only computed by the
   callers) where dens_surface holds. */
static inline int dens_surface(uint8_t a, uint8_t b, int f)
{
	return 2 * f > DZ_SUB ? a && !b : b && !a;
}
static inline uint8_t dens_blend(uint8_t a, uint8_t b, int f, int top)
{
	uint8_t n = 2 * f > DZ_SUB ? a : b;
	if (!top || !dens_surface(a, b, f))
		return n;
	return (uint8_t)(((unsigned)a * (unsigned)f + (unsigned)b * (unsigned)(DZ_SUB - f) +
	                  DZ_SUB / 2) / DZ_SUB);
}

/* The whole voxel: every plane the nearer source voxel's, the density
   by dens_blend. */
static inline void raw_blend(const rawvox *a, const rawvox *b, int f, int top, rawvox *r)
{
	*r = *(2 * f > DZ_SUB ? a : b);
	r->d = dens_blend(a->d, b->d, f, top);
}

/* Brick coordinates: split v along axis a into brick index and offset. */
static inline uint32_t brick_of(const loom_texture *t, int a, uint32_t v)
{
	return t->pow2 ? v >> t->sh[a] : v / t->bs[a];
}
static inline uint32_t in_brick(const loom_texture *t, int a, uint32_t v)
{
	return t->pow2 ? v & t->mk[a] : v % t->bs[a];
}

/* ------------------------------------------------ texture.c (the loader) */

/* After a whole-brick load of stored brick id into brick (its four
   planes): fill its density and every-plane occupancy tables (the air
   tests of lookups, the extents of region reads), when t has them.  Both
   loaders call it (tex_load, and loom__lod_load for level-0 ids). */
void loom__texture_occ_loaded(loom_texture *t, uint64_t id, const uint8_t *brick);

/* ------------------------------------------------ lod.c (level of detail) */

/* Set up the coarse levels of t (t->db, t->ex, t->n_bricks set): the
   levels the brick shape allows, each exemplar's coarse brick tables.
   Leaves t->lod 0 when none is possible.  Returns the levels. */
unsigned loom__lod_setup(loom_texture *t);
/* Coarse levels a database of brick shape b allows: the largest k <= LOD_MAX
   with 2^k dividing bx, by and bz / 2 (bz even); 0 when none. */
unsigned loom__lod_levels_for(const uint32_t b[3]);
/* Cache loader, scratch and its budget charge with LOD on: level-0 ids
   as the database reader, coarse ids built from their level-0 bricks. */
int loom__lod_load(void *ctx, uint64_t id, void *dst, void *scratch, loom_diag *diag);
void *loom__lod_scratch_new(void *ctx);
void loom__lod_scratch_free(void *ctx, void *scratch);
size_t loom__lod_scratch_bytes(const loom_db *db);

#endif /* LOOM_TEXTURE_IMPL_H */
