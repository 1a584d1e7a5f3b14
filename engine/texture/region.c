/*
 * engine/texture/texture.c - the virtual 3D texture of a fabric (loom/texture.h).
 *
 * WHAT IT IS
 *   A voxel of the bolt is never stored: each lookup finds the crossing,
 *   its source block (base assignment + randomisation), the edge-fix offset
 *   of its voxel column, and reads the source voxel from an exemplar brick
 *   held in the brick cache (engine/texture/cache.h).  docs/engine.md tells the
 *   same story with figures.
 *
 * LOOKUP STEPS (voxel_raw; the code cites them)
 *   Step 1.  z outside [0, b3): empty, done.
 *   Step 2.  Crossing: if (x, y) lies in the thread's current crossing
 *            entry, use it; else I = floor(y / b2), J = floor(x / b1) and
 *            find (I, J) among the thread's XENT entries, or set one up
 *            (evicting the least recently used): the crossing's sources
 *            and its neighbours' (loom__fabric_crossing: base assignment of
 *            (I mod M, J mod N) shifted by its group's symmetry), the
 *            yarn types of its warp and weft, the 4 (rh + rv) edge-fix
 *            coefficients of the block, and an empty column bitmap.
 *   Step 3.  Column offset dz(lx, ly): computed on first use in the entry
 *            (4 dot products of length r with the fabric's basis fields,
 *            the same arithmetic as loom_edgefix_block), rounded to whole
 *            voxels (loom__dz_round), kept in the entry.
 *   Step 4.  Source voxel (x0 + lx, y0 + ly, z - dz) of the block's
 *            exemplar; z - dz outside [0, b3): empty, done.
 *   Step 5.  Brick id of that voxel.  The thread's current brick (memo)
 *            answers without a cache call when the id matches; otherwise
 *            the memo's pin is released and the brick is taken from the
 *            cache (loom__cache_get: per-thread recent bricks, then the
 *            shared frames, else read + CRC + inflate).  A brick stored as
 *            nothing (all empty) is never read.  A read error is returned
 *            with its message; nothing stays pinned.
 *   Step 6.  The four byte planes at the voxel; label -> kind through the
 *            exemplar's yarn table; kind -> the crossing's warp or weft
 *            type; the type's albedo and alignment from the design.
 *   Region reads go crossing by crossing and, in a crossing, by groups of
 *   adjacent output columns of one row whose source columns share their
 *   bricks (up to a brick's width, at most GMAX; group_fill): steps 3-4 once per
 *   column (offset and valid z range), step 5 once per brick of the group,
 *   then each column's z-run in that brick is copied; z above, below or
 *   beyond the source block is filled with zeros.  label -> kind / type
 *   16 voxels at a time with PSHUFB where the CPU has SSSE3 (checked at
 *   open) and the exemplar's labels with a kind are below 128
 *   (kind_type), else through 256-entry tables.  z-fastest output: the
 *   runs go straight out (region_zfast).  x-fastest output: per crossing,
 *   the z planes where the whole piece is surely empty (outside the block,
 *   or in bricks stored as nothing: chunk_extent) are zeroed plane by
 *   plane (zero_rect, sequential writes); then slabs of RZ z-values, rows,
 *   chunks of up to RCOLS columns (xchunk): the z rows where the chunk is
 *   surely empty are zeroed directly; the rest is gathered
 *   into the slot's buffer and transposed 16 x 16 at a time (SSE2; with
 *   SSSE3 kind and type come from the transposed labels instead of being
 *   gathered and transposed), each output row of the chunk written whole
 *   (region_xfast).
 *
 * THE MEMORY IT OWNS (all counted against the budget)
 *   - the texture header (density, albedo and alignment tables) and one
 *     block allocated at open (calloc: pages become resident when first
 *     used): per-exemplar tables (first brick, brick counts, label ->
 *     kind), a bit per brick (stored empty), and max_threads + 1 thread
 *     slots, each holding its cache thread handle, its current brick, its
 *     error message, the region gather buffer (6 planes of RCOLS x RZ
 *     bytes) and XENT crossing entries (coefficients, label -> type table,
 *     column bitmap, dz of b1*b2 columns as int16);
 *   - the brick cache, opened with budget - (that block): frames,
 *     bookkeeping, and one database reader (decompressor + scratch) per
 *     thread slot.
 *   Nothing else is allocated after open.  bytes_in_use = block + cache's.
 *
 * THREADS
 *   Each calling thread is bound to a slot on its first call: a
 *   thread-local table of (texture serial, slot) bindings, most recent
 *   first, so the common case is one thread-local load and compare.  Slots
 *   come from the texture's pool of max_threads; when it is empty the
 *   thread binds to the overflow slot, which every overflow thread uses
 *   under a mutex (and leaves as soon as a pool slot is free).  A slot
 *   goes back to the pool when its thread calls loom_texture_thread_done,
 *   evicts the binding (more than TL_BINDINGS textures in use), or exits
 *   (a pthread key destructor).  Thread exit may race with close: both
 *   take the process-wide registry lock, and a binding is only followed
 *   to a texture found alive in the registry (same address and serial;
 *   serials are never reused).  The registry is the only process-wide
 *   state: a mutex, a list of open textures, a serial counter, one key.
 *
 * PINS AND THE CACHE'S DEADLOCK RULE
 *   A thread holds at most one caller pin: its current brick, kept across
 *   calls (it is released before any other get).  So an idle thread keeps
 *   one caller pin plus its IDLE per-thread pins, and a sleeping get holds
 *   none: the cache is opened with pins_per_thread = 2, which reserves one
 *   frame per thread for that (cache.h, the deadlock rule).
 *
 * DETERMINISM
 *   Every value is a pure function of the fabric, the database and the
 *   position: the crossing entries and bricks are caches of such values.
 */
#include "texture_internal.h"

#include "cache.h"
#include "exemplar/db_internal.h"
#include "synth/fabric_internal.h"

#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <tmmintrin.h> /* SSSE3, used under a target attribute after a CPU check */
#define HAVE_KT_SSSE3 1
#endif

#define XENT 4              /* crossing entries per thread slot */
#define TL_BINDINGS 8       /* textures one thread keeps bound at once */
#define NO_BRICK UINT64_MAX
#define COORD_LIMIT ((int64_t)1 << 62) /* |x|, |y|, |z| below this */
#define DZ_LIMIT 4096       /* |dz| clamp: b3 <= LOOM__DB_MAX_BLOCK */
#define ALIGN 64
#define RCOLS 64            /* columns gathered at once (x-fastest regions) */
#define RZ 64               /* z values gathered at once */

/* ---------------------------------------------------------------- types */

/* Per exemplar, read-only after open. */
struct exm {
	uint32_t first_brick;    /* global id of brick (0, 0, 0) */
	uint32_t nb[3];          /* bricks along x, y, z */
	uint8_t kind[256];       /* label -> enum loom_yarn_kind */
	uint8_t ngrp;            /* labels with a kind are below 16 * ngrp
	                            (region reads: kind_type's PSHUFB tables);
	                            0: above 8 groups, table lookups instead */
};

/* One crossing of a thread's small cache (steps 2-3). */
struct xent {
	int64_t I, J;            /* crossing */
	int64_t x0, y0;          /* its first output voxel: J*b1, I*b2 */
	const struct exm *ex;    /* source exemplar */
	uint32_t sx0, sy0;       /* source block origin in the exemplar */
	uint32_t stamp;          /* last use (LRU) */
	uint8_t valid;
	uint8_t tok[4];          /* yarn type by kind: 0, warp, weft, 0 */
	uint8_t tlut_ok;         /* tlut is built */
	uint8_t tlut[256];       /* label -> yarn type (region reads) */
	float *a;                /* edge-fix coefficients n[rh] s[rh] w[rv] e[rv] */
	uint64_t *have;          /* bit per column: dz computed */
	int16_t *dz;             /* b1*b2 whole-voxel offsets, where have */
};

/* Per-slot counters: written by the slot's current thread only (relaxed
   load + store), summed by loom_texture_get_stats. */
struct counters {
	_Atomic uint64_t lookups, memo_hits, empty, xings, dz, errors;
};

struct tslot {
	loom__cache_thread *cth; /* attached at open, for the slot's life */
	struct xent *cur;        /* the entry of the last lookup (or NULL) */
	uint64_t memo_id;        /* current brick (NO_BRICK: none) */
	const uint8_t *memo;     /* its bytes; NULL for an empty brick */
	int memo_pinned;         /* memo holds a caller pin */
	int shared;              /* the overflow slot */
	uint32_t clock;          /* stamps for the entries' LRU */
	uint32_t next_free;      /* pool free list */
	struct xent ent[XENT];
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
	int ssse3;               /* the CPU has SSSE3 (kind_type) */
	size_t bv;               /* voxels per brick (plane size) */
	uint32_t rh, rv;         /* edge-fix ranks */
	const float *coef, *field_h, *field_v; /* the fabric's tables */
	float dens[256];         /* density byte -> d / 255 (correctly rounded) */
	float albedo[LOOM_MAX_YARN_TYPES][3];
	float align[LOOM_MAX_YARN_TYPES];
	struct exm *ex;          /* n_ex entries (in mem) */
	uint32_t n_ex;
	uint64_t *empty;         /* bit per brick: stored as nothing (in mem) */
	uint32_t n_bricks;
	uint8_t *slots;          /* n_slots thread slots (in mem) */
	loom__cache *cache;
	unsigned n_slots;        /* max_threads + 1 (the last is the overflow) */
	size_t slot_bytes;
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
	loom_texture *live_next; /* registry (under g_lock) */
};

/* --------------------------------------------------------------- helpers */

static size_t round_up(size_t n, size_t a)
{
	return (n + a - 1) / a * a;
}

static void bump(_Atomic uint64_t *c, uint64_t n) /* single writer */
{
	atomic_store_explicit(c, atomic_load_explicit(c, memory_order_relaxed) + n,
	                      memory_order_relaxed);
}

static uint64_t rd(const _Atomic uint64_t *c)
{
	return atomic_load_explicit(c, memory_order_relaxed);
}

static struct tslot *slot_at(const loom_texture *t, unsigned i)
{
	return (struct tslot *)(t->slots + (size_t)i * t->slot_bytes);
}

/* 1 if brick id is stored as nothing (all empty). */
static inline int brick_empty(const loom_texture *t, uint64_t id)
{
	return id < t->n_bricks && (t->empty[id >> 6] >> (id & 63) & 1);
}

int loom__dz_round(float dz)
{
	if (!(dz == dz))
		return 0;
	if (dz >= (float)DZ_LIMIT)
		return DZ_LIMIT;
	if (dz <= -(float)DZ_LIMIT)
		return -DZ_LIMIT;
	return (int)lroundf(dz);
}

void loom__orient_blend(unsigned n, const float *w, const float (*v)[3],
                        float out[3])
{
	unsigned ref = n;
	float s[3] = {0, 0, 0}, len;

	out[0] = out[1] = out[2] = 0;
	for (unsigned k = 0; k < n; k++)
		if (w[k] > 0 && (ref == n || w[k] > w[ref]))
			ref = k;
	if (ref == n)
		return;
	for (unsigned k = 0; k < n; k++) {
		float sg;
		if (!(w[k] > 0))
			continue;
		sg = v[k][0] * v[ref][0] + v[k][1] * v[ref][1] + v[k][2] * v[ref][2] < 0
		             ? -w[k]
		             : w[k];
		s[0] += sg * v[k][0];
		s[1] += sg * v[k][1];
		s[2] += sg * v[k][2];
	}
	len = sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
	if (!(len > 0))
		return;
	if (s[2] < 0 || (s[2] == 0 && (s[1] < 0 || (s[1] == 0 && s[0] < 0))))
		len = -len;
	out[0] = s[0] / len;
	out[1] = s[1] / len;
	out[2] = s[2] / len;
}

/* ------------------------------------------------------------- registry */

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static loom_texture *g_live;       /* open textures */
static uint64_t g_serial;          /* last serial given (under g_lock) */
static pthread_once_t g_once = PTHREAD_ONCE_INIT;
static pthread_key_t g_key;
static int g_key_ok;

struct binding {
	uint64_t serial;               /* 0: unused */
	loom_texture *tex;             /* only followed once found alive */
	struct tslot *slot;
};

static _Thread_local struct binding tl_bind[TL_BINDINGS];
static _Thread_local int tl_keyed;
static _Thread_local char tl_msg[LOOM_DIAG_MSG_MAX];

static void memo_drop(struct tslot *s)
{
	if (s->memo_pinned)
		loom__cache_release(s->cth, s->memo);
	s->memo_pinned = 0;
	s->memo = NULL;
	s->memo_id = NO_BRICK;
}

/* Give slot s (the calling thread's) back to t's pool; t is alive. */
static void slot_return(loom_texture *t, struct tslot *s)
{
	if (s->shared)
		return;
	memo_drop(s);
	loom__cache_thread_flush(s->cth);
	pthread_mutex_lock(&t->pool_lock);
	s->next_free = t->free_head;
	t->free_head = (uint32_t)(((uint8_t *)s - (uint8_t *)slot_at(t, 0)) / t->slot_bytes);
	atomic_fetch_add(&t->n_free, 1);
	pthread_mutex_unlock(&t->pool_lock);
}

/* Drop binding b, returning its slot if its texture is still open. */
static void unbind(struct binding *b)
{
	if (b->serial) {
		pthread_mutex_lock(&g_lock);
		for (loom_texture *p = g_live; p; p = p->live_next)
			if (p == b->tex && p->serial == b->serial) {
				slot_return(p, b->slot); /* no-op for the overflow slot */
				break;
			}
		pthread_mutex_unlock(&g_lock);
	}
	memset(b, 0, sizeof *b);
}

static void thread_exit(void *unused)
{
	(void)unused;
	for (int k = 0; k < TL_BINDINGS; k++)
		unbind(&tl_bind[k]);
}

static void make_key(void)
{
	g_key_ok = pthread_key_create(&g_key, thread_exit) == 0;
}

/* A pool slot, or NULL when the pool is empty. */
static struct tslot *pool_take(loom_texture *t)
{
	struct tslot *s = NULL;

	pthread_mutex_lock(&t->pool_lock);
	if (t->free_head != t->n_slots) {
		s = slot_at(t, t->free_head);
		t->free_head = s->next_free;
		atomic_fetch_sub(&t->n_free, 1);
	}
	pthread_mutex_unlock(&t->pool_lock);
	return s;
}

/* The slow path of slot_of: another binding, or a new one. */
static struct tslot *slot_bind(loom_texture *t)
{
	struct binding b;
	int k;

	for (k = 1; k < TL_BINDINGS; k++)
		if (tl_bind[k].serial == t->serial)
			break;
	if (k < TL_BINDINGS) {
		b = tl_bind[k];
		memmove(&tl_bind[1], &tl_bind[0], (size_t)k * sizeof b);
		tl_bind[0] = b;
		return b.slot;
	}
	if (!tl_keyed) {
		pthread_once(&g_once, make_key);
		/* without the key a slot is not returned at thread exit (it stays
		   bound until close): still correct */
		if (g_key_ok && pthread_setspecific(g_key, &tl_keyed) == 0)
			tl_keyed = 1;
	}
	b.serial = t->serial;
	b.tex = t;
	b.slot = pool_take(t);
	if (!b.slot)
		b.slot = slot_at(t, t->n_slots - 1);
	if (tl_bind[TL_BINDINGS - 1].serial)
		unbind(&tl_bind[TL_BINDINGS - 1]);
	memmove(&tl_bind[1], &tl_bind[0], (TL_BINDINGS - 1) * sizeof b);
	tl_bind[0] = b;
	return b.slot;
}

/* The calling thread's slot on t, locked if it is the overflow slot. */
static struct tslot *slot_enter(loom_texture *t)
{
	struct tslot *s = tl_bind[0].serial == t->serial ? tl_bind[0].slot : slot_bind(t);

	if (s->shared) {
		struct tslot *p;
		if (atomic_load_explicit(&t->n_free, memory_order_relaxed) &&
		    (p = pool_take(t)) != NULL) {
			tl_bind[0].slot = p; /* leave the overflow slot */
			return p;
		}
		pthread_mutex_lock(&t->overflow_lock);
	}
	return s;
}

static void slot_leave(loom_texture *t, struct tslot *s)
{
	if (s->shared)
		pthread_mutex_unlock(&t->overflow_lock);
}

/* Record a failed brick read on the slot and the texture. */
static int slot_error(loom_texture *t, struct tslot *s, int rc, const char *msg)
{
	snprintf(s->msg, sizeof s->msg, "%s", msg);
	pthread_mutex_lock(&t->msg_lock);
	snprintf(t->msg, sizeof t->msg, "%s", msg);
	pthread_mutex_unlock(&t->msg_lock);
	bump(&s->cnt.errors, 1);
	return rc;
}

/* ------------------------------------------------------------ crossings */

/* Edge-fix coefficients of a block with sources nb (as the edge-fix
   module combines them: half the difference of the two sides' profile
   coefficients on each edge). */
static void xent_coef(const loom_texture *t, const loom_synth_nbhd *nb, float *a)
{
	uint32_t rh = t->rh, rv = t->rv, st = 2 * rh + 2 * rv;
	const float *cs = t->coef + (size_t)nb->self * st;
	const float *cn = t->coef + (size_t)nb->n * st;
	const float *css = t->coef + (size_t)nb->s * st;
	const float *cw = t->coef + (size_t)nb->w * st;
	const float *ce = t->coef + (size_t)nb->e * st;
	float *an = a, *as = a + rh, *aw = a + 2 * rh, *ae = a + 2 * rh + rv;

	for (uint32_t k = 0; k < rh; k++) {
		an[k] = 0.5f * (cn[rh + k] - cs[k]);
		as[k] = 0.5f * (css[k] - cs[rh + k]);
	}
	for (uint32_t k = 0; k < rv; k++) {
		aw[k] = 0.5f * (cw[2 * rh + rv + k] - cs[2 * rh + k]);
		ae[k] = 0.5f * (ce[2 * rh + k] - cs[2 * rh + rv + k]);
	}
}

/* Step 3: dz of column (x, y) of an entry, in the edge-fix module's
   order of operations (so equal to loom_edgefix_block bit for bit). */
static float dz_eval(const loom_texture *t, const float *a, uint32_t x, uint32_t y)
{
	uint32_t b1 = t->b1, b2 = t->b2, rh = t->rh, rv = t->rv;
	const float *fn = t->field_h + ((size_t)y * b1 + x) * rh;
	const float *fs = t->field_h + ((size_t)(b2 - 1 - y) * b1 + x) * rh;
	const float *fw = t->field_v + ((size_t)y * b1 + x) * rv;
	const float *fe = t->field_v + ((size_t)y * b1 + (b1 - 1 - x)) * rv;
	const float *an = a, *as = a + rh, *aw = a + 2 * rh, *ae = a + 2 * rh + rv;
	float sn = 0, ss = 0, sw = 0, se = 0;
	uint32_t k = 0, m = rh < rv ? rh : rv;

	/* the four dot products interleaved: independent chains, each summed
	   in k order, so the same values as four separate loops */
	for (; k < m; k++) {
		sn += an[k] * fn[k];
		ss += as[k] * fs[k];
		sw += aw[k] * fw[k];
		se += ae[k] * fe[k];
	}
	for (uint32_t j = k; j < rh; j++) {
		sn += an[j] * fn[j];
		ss += as[j] * fs[j];
	}
	for (uint32_t j = k; j < rv; j++) {
		sw += aw[j] * fw[j];
		se += ae[j] * fe[j];
	}
	return sn + ss + sw + se;
}

static inline int xent_dz(const loom_texture *t, struct tslot *s, struct xent *e,
                          uint32_t lx, uint32_t ly)
{
	size_t c = (size_t)ly * t->b1 + lx;
	if (!(e->have[c >> 6] >> (c & 63) & 1)) {
		e->dz[c] = (int16_t)loom__dz_round(dz_eval(t, e->a, lx, ly));
		e->have[c >> 6] |= (uint64_t)1 << (c & 63);
		bump(&s->cnt.dz, 1);
	}
	return e->dz[c];
}

float loom__texture_dz(const loom_texture *t, int64_t I, int64_t J, uint32_t lx,
                       uint32_t ly)
{
	float a[4 * LOOM_EDGEFIX_MAX_RANK];
	loom_synth_nbhd nb;

	if (!t || lx >= t->b1 || ly >= t->b2)
		return 0;
	loom__fabric_nbhd(t->fab, I, J, &nb);
	xent_coef(t, &nb, a);
	return dz_eval(t, a, lx, ly);
}

/* Step 2: the entry of the crossing holding (x, y). */
static struct xent *xent_enter(loom_texture *t, struct tslot *s, int64_t x, int64_t y)
{
	int64_t I = loom_synth_floordiv(y, t->b2), J = loom_synth_floordiv(x, t->b1);
	struct xent *e = NULL;
	loom__fabric_xing xg;

	for (int k = 0; k < XENT; k++) {
		struct xent *q = &s->ent[k];
		if (q->valid && q->I == I && q->J == J) {
			e = q;
			goto found;
		}
		if (!e || !q->valid || (e->valid && q->stamp < e->stamp))
			e = q;
	}
	loom__fabric_crossing(t->fab, I, J, &xg);
	e->I = I;
	e->J = J;
	e->x0 = J * (int64_t)t->b1;
	e->y0 = I * (int64_t)t->b2;
	e->ex = &t->ex[xg.blk->exemplar];
	e->sx0 = xg.blk->x0;
	e->sy0 = xg.blk->y0;
	e->tok[0] = 0;
	e->tok[LOOM_YARN_WARP] = xg.warp_type;
	e->tok[LOOM_YARN_WEFT] = xg.weft_type;
	e->tok[3] = 0;
	e->tlut_ok = 0;
	xent_coef(t, &xg.nb, e->a);
	memset(e->have, 0, ((size_t)t->b1 * t->b2 + 63) / 64 * 8);
	e->valid = 1;
	bump(&s->cnt.xings, 1);
found:
	e->stamp = ++s->clock;
	s->cur = e;
	return e;
}

/* ---------------------------------------------------------------- bricks */

/* Step 5: make brick id the slot's current brick. */
static int memo_switch(loom_texture *t, struct tslot *s, uint64_t id)
{
	loom_diag d;
	const void *p;
	int rc;

	memo_drop(s);
	if (brick_empty(t, id)) {
		s->memo_id = id;
		bump(&s->cnt.empty, 1);
		return LOOM_OK;
	}
	d.message[0] = 0;
	d.warn = NULL;
	d.user = NULL;
	d.n_warnings = 0;
	rc = loom__cache_get(s->cth, id, &p, &d);
	if (rc != LOOM_OK)
		return slot_error(t, s, rc, d.message);
	s->memo_id = id;
	s->memo = p;
	s->memo_pinned = 1;
	return LOOM_OK;
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

/* Raw voxel: the encodings plus kind and type. */
typedef struct rawvox {
	uint8_t d, l, k, ty;
	uint16_t o;
} rawvox;

static const rawvox raw_empty;

/* Steps 1-6 for voxel (x, y, z) (coordinates already range-checked). */
static inline int voxel_raw(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                            int64_t z, rawvox *r)
{
	struct xent *e = s->cur;
	uint32_t lx, ly, sx, sy, sz;
	uint64_t id;
	int64_t zs;
	size_t i;
	const uint8_t *p;

	*r = raw_empty;
	if ((uint64_t)z >= t->b3) /* Step 1 */
		return LOOM_OK;
	if (!e || (uint64_t)(x - e->x0) >= t->b1 || (uint64_t)(y - e->y0) >= t->b2)
		e = xent_enter(t, s, x, y); /* Step 2 */
	lx = (uint32_t)(x - e->x0);
	ly = (uint32_t)(y - e->y0);
	zs = z - xent_dz(t, s, e, lx, ly); /* Step 3 */
	if ((uint64_t)zs >= t->b3) /* Step 4 */
		return LOOM_OK;
	sx = e->sx0 + lx;
	sy = e->sy0 + ly;
	sz = (uint32_t)zs;
	id = e->ex->first_brick +
	     ((uint64_t)brick_of(t, 1, sy) * e->ex->nb[0] + brick_of(t, 0, sx)) *
	             e->ex->nb[2] +
	     brick_of(t, 2, sz);
	if (id != s->memo_id) { /* Step 5 */
		int rc = memo_switch(t, s, id);
		if (rc != LOOM_OK)
			return rc;
	} else {
		bump(&s->cnt.memo_hits, 1);
	}
	p = s->memo;
	if (!p)
		return LOOM_OK;
	i = ((size_t)in_brick(t, 1, sy) * t->bs[0] + in_brick(t, 0, sx)) * t->bs[2] +
	    in_brick(t, 2, sz); /* Step 6 */
	r->d = p[i];
	r->o = (uint16_t)(p[t->bv + i] | p[2 * t->bv + i] << 8);
	r->l = p[3 * t->bv + i];
	r->k = e->ex->kind[r->l];
	r->ty = e->tok[r->k];
	return LOOM_OK;
}

static void texel_of(const loom_texture *t, const rawvox *r, loom_texel *out)
{
	memset(out, 0, sizeof *out);
	if (r->d) {
		out->density = t->dens[r->d];
		loom__orient_decode(r->o, out->orientation);
	}
	out->label = r->l;
	out->kind = r->k;
	if (r->k) {
		out->type = r->ty;
		memcpy(out->albedo, t->albedo[r->ty], sizeof out->albedo);
		out->alignment = t->align[r->ty];
	}
}

static int coord_ok(int64_t v)
{
	return v > -COORD_LIMIT && v < COORD_LIMIT;
}

/* ------------------------------------------------------------ open/close */

static int tex_load(void *ctx, uint64_t id, void *dst, void *scratch, loom_diag *diag)
{
	loom_texture *t = ctx;
	size_t n = 0;
	int rc = loom__db_reader_read(scratch, (uint32_t)id, dst, &n, diag);
	atomic_fetch_add_explicit(&t->bytes_read, n, memory_order_relaxed);
	return rc;
}

static void *tex_scratch_new(void *ctx)
{
	return loom__db_reader_new(((loom_texture *)ctx)->db);
}

static void tex_scratch_free(void *ctx, void *scratch)
{
	(void)ctx;
	loom__db_reader_free(scratch);
}

/* Smallest cache budget that opens with co's other settings (0 if none
   below 2^48). */
static size_t cache_min_budget(const loom__cache_opts *co)
{
	loom__cache_opts o = *co;
	size_t lo = 0, hi = 1u << 16;
	loom__cache *c;

	for (;;) {
		o.budget_bytes = hi;
		if (loom__cache_open(&o, &c, NULL) == LOOM_OK) {
			loom__cache_close(c);
			break;
		}
		if (hi >= (size_t)1 << 48)
			return 0;
		lo = hi;
		hi *= 2;
	}
	while (hi - lo > 1) {
		size_t mid = lo + (hi - lo) / 2;
		o.budget_bytes = mid;
		if (loom__cache_open(&o, &c, NULL) == LOOM_OK) {
			loom__cache_close(c);
			hi = mid;
		} else {
			lo = mid;
		}
	}
	return hi;
}

static int budget_fail(loom_diag *diag, size_t budget, size_t fixed, size_t cache,
                       unsigned T, size_t brick)
{
	return loom__fail(diag, LOOM_EBUDGET, "texture: budget of %zu bytes too small: "
	                  "this fabric needs at least %zu bytes with %u threads (%zu for "
	                  "per-thread state and tables, %zu for the smallest brick cache: "
	                  "at least %u frames of %zu bytes, a decompressor per thread, "
	                  "bookkeeping)", budget, fixed + cache, T, fixed, cache, T + 2,
	                  brick);
}

static int check_identity(const loom_fabric *fab, const loom_db *db, loom_diag *diag)
{
	loom_fabric_db_identity id;
	loom_db_info info;
	uint64_t h = loom_db_content_hash(db);

	if (loom_fabric_get_db_identity(fab, &id) != LOOM_OK ||
	    loom_db_get_info(db, &info) != LOOM_OK)
		return loom__fail(diag, LOOM_EINVAL, "texture: cannot read the fabric's or "
		                  "the database's identity");
	if (id.content_hash != h)
		return loom__fail(diag, LOOM_EMISMATCH, "texture: the fabric was made with "
		                  "database %s (content hash %016" PRIx64 "), this database's "
		                  "content hash is %016" PRIx64, id.path ? id.path : "?",
		                  id.content_hash, h);
	if (memcmp(id.block, info.block, sizeof id.block) != 0 ||
	    id.n_exemplars != info.n_exemplars ||
	    fab->b1 != info.block[0] || fab->b2 != info.block[1] || fab->b3 != info.block[2])
		return loom__fail(diag, LOOM_EMISMATCH, "texture: block size %ux%ux%u or "
		                  "%u exemplars of the fabric differ from the database's "
		                  "%ux%ux%u, %u exemplars", id.block[0], id.block[1],
		                  id.block[2], id.n_exemplars, info.block[0], info.block[1],
		                  info.block[2], info.n_exemplars);
	return LOOM_OK;
}

static int is_pow2(uint32_t v)
{
	return v && !(v & (v - 1));
}

static uint32_t log2u(uint32_t v)
{
	uint32_t s = 0;
	while ((1u << s) < v)
		s++;
	return s;
}

/* Fill the per-exemplar tables; LOOM_OK or a database error. */
static int load_exemplars(loom_texture *t, loom_diag *diag)
{
	for (uint32_t k = 0; k < t->n_ex; k++) {
		loom_db_exemplar_info e;
		const loom_db_yarn *y = loom__db_yarn_lut(t->db, k);
		int rc = loom_db_exemplar(t->db, k, &e);
		if (rc != LOOM_OK || !y)
			return loom__fail(diag, rc ? rc : LOOM_EINVAL, "texture: exemplar %u "
			                  "unreadable", k);
		t->ex[k].first_brick = e.first_brick;
		memcpy(t->ex[k].nb, e.bricks, sizeof e.bricks);
		unsigned top = 0;
		for (int l = 0; l < 256; l++) {
			t->ex[k].kind[l] = y[l].kind <= LOOM_YARN_WEFT ? y[l].kind : 0;
			if (t->ex[k].kind[l])
				top = (unsigned)l + 1;
		}
		t->ex[k].ngrp = (uint8_t)((top + 15) / 16 <= 8 ? (top + 15) / 16 : 0);
		if (top == 0) /* no yarn at all: one group of zeros */
			t->ex[k].ngrp = 1;
	}
	return LOOM_OK;
}

/* Carve the slots out of t->mem and initialise them. */
static void lay_out_slots(loom_texture *t)
{
	size_t cols = (size_t)t->b1 * t->b2;
	size_t a_bytes = round_up(sizeof(float) * 2 * (t->rh + t->rv), ALIGN);
	size_t h_bytes = round_up((cols + 63) / 64 * 8, ALIGN);

	for (unsigned i = 0; i < t->n_slots; i++) {
		struct tslot *s = slot_at(t, i);
		uint8_t *p = (uint8_t *)s + round_up(sizeof *s, ALIGN);
		s->memo_id = NO_BRICK;
		s->shared = i == t->n_slots - 1;
		s->next_free = i + 1 < t->n_slots - 1 ? i + 1 : t->n_slots;
		s->rbuf = p;
		p += 6 * RCOLS * RZ;
		for (int k = 0; k < XENT; k++) {
			s->ent[k].a = (float *)p;
			p += a_bytes;
			s->ent[k].have = (uint64_t *)p;
			p += h_bytes;
			s->ent[k].dz = (int16_t *)p;
			p += round_up(cols * sizeof(int16_t), ALIGN);
		}
	}
	t->free_head = t->n_slots > 1 ? 0 : t->n_slots;
	atomic_init(&t->n_free, t->n_slots - 1);
}

LOOM_API int loom_texture_open(const loom_fabric *fabric, const loom_db *db,
                               const loom_texture_options *opts,
                               loom_texture **out, loom_diag *diag)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_edgefix_tables tb;
	loom__db_geom g;
	loom__cache_opts co;
	loom_texture *t;
	size_t cols, slot_bytes, ex_bytes, mem_bytes, fixed;
	unsigned T;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "loom_texture_open: NULL output");
	*out = NULL;
	if (!fabric)
		return loom__fail(diag, LOOM_EINVAL, "loom_texture_open: NULL fabric");
	if (opts) {
		if (opts->size < sizeof(loom_texture_options))
			return loom__fail(diag, LOOM_EINVAL, "loom_texture_open: options.size "
			                  "%zu too small (initialise with "
			                  "LOOM_TEXTURE_OPTIONS_INIT)", opts->size);
		o.budget_bytes = opts->budget_bytes;
		o.max_threads = opts->max_threads;
	}
	if (!o.budget_bytes)
		o.budget_bytes = LOOM_TEXTURE_DEFAULT_BUDGET;
	T = o.max_threads ? o.max_threads : LOOM_TEXTURE_DEFAULT_THREADS;
	if (T > LOOM_TEXTURE_MAX_THREADS)
		return loom__fail(diag, LOOM_EINVAL, "loom_texture_open: max_threads %u above "
		                  "%u", T, LOOM_TEXTURE_MAX_THREADS);
	if (!loom_fabric_attached(fabric) || !fabric->ef)
		return loom__fail(diag, LOOM_EUNUSABLE, "loom_texture_open: the fabric is "
		                  "detached (opened without its database): no lookups");
	if (!db)
		db = loom_fabric_db(fabric);
	if ((rc = check_identity(fabric, db, diag)) != LOOM_OK)
		return rc;
	if (loom_edgefix_get_tables(fabric->ef, &tb) != LOOM_OK || tb.b1 != fabric->b1 ||
	    tb.b2 != fabric->b2 || tb.n_blocks != fabric->n_blocks)
		return loom__fail(diag, LOOM_EINVAL, "loom_texture_open: the fabric's edge-fix "
		                  "tables do not match its block size");
	loom__db_geometry(db, &g);

	cols = (size_t)fabric->b1 * fabric->b2;
	slot_bytes = round_up(sizeof(struct tslot), ALIGN) + 6 * RCOLS * RZ +
	             XENT * (round_up(sizeof(float) * 2 * (tb.rank_h + tb.rank_v), ALIGN) +
	                     round_up((cols + 63) / 64 * 8, ALIGN) +
	                     round_up(cols * sizeof(int16_t), ALIGN));
	ex_bytes = round_up(sizeof(struct exm) * g.n_exemplars, ALIGN) +
	           round_up(((size_t)g.n_bricks + 63) / 64 * 8, ALIGN);
	mem_bytes = ex_bytes + (size_t)(T + 1) * slot_bytes;
	fixed = round_up(sizeof *t, ALIGN) + mem_bytes;

	memset(&co, 0, sizeof co);
	co.brick_bytes = g.brick_bytes;
	co.load = tex_load;
	co.scratch_new = tex_scratch_new;
	co.scratch_free = tex_scratch_free;
	co.scratch_bytes = loom__db_reader_bytes(db);
	co.max_threads = T + 1;
	co.pins_per_thread = 2;
	if (o.budget_bytes <= fixed) {
		size_t need = cache_min_budget(&co);
		return budget_fail(diag, o.budget_bytes, fixed, need, T, g.brick_bytes);
	}
	co.budget_bytes = o.budget_bytes - fixed;

	t = aligned_alloc(ALIGN, round_up(sizeof *t, ALIGN));
	if (!t)
		return loom__fail(diag, LOOM_ENOMEM, "texture: out of memory");
	memset(t, 0, sizeof *t);
	t->mem = calloc(1, mem_bytes);
	if (!t->mem) {
		free(t);
		return loom__fail(diag, LOOM_ENOMEM, "texture: out of memory (%zu bytes)",
		                  mem_bytes);
	}
	t->fab = fabric;
	t->db = db;
	t->b1 = fabric->b1;
	t->b2 = fabric->b2;
	t->b3 = fabric->b3;
	memcpy(t->bs, g.brick, sizeof t->bs);
	t->pow2 = is_pow2(t->bs[0]) && is_pow2(t->bs[1]) && is_pow2(t->bs[2]);
	loom__texture_simd(t, 1); /* CPU check for the region reads */
	for (int a = 0; a < 3; a++) {
		t->sh[a] = log2u(t->bs[a]);
		t->mk[a] = t->bs[a] - 1;
	}
	t->bv = g.brick_voxels;
	for (int k = 0; k < 256; k++)
		t->dens[k] = (float)k / 255.0f;
	t->rh = tb.rank_h;
	t->rv = tb.rank_v;
	t->coef = tb.coef;
	t->field_h = tb.field_h;
	t->field_v = tb.field_v;
	for (uint32_t k = 0; k < fabric->design->n_types && k < LOOM_MAX_YARN_TYPES; k++) {
		memcpy(t->albedo[k], fabric->design->types[k].albedo, sizeof t->albedo[k]);
		t->align[k] = fabric->design->types[k].alignment;
	}
	t->n_ex = g.n_exemplars;
	t->ex = (struct exm *)t->mem;
	t->empty = (uint64_t *)(t->mem + round_up(sizeof(struct exm) * g.n_exemplars, ALIGN));
	t->n_bricks = g.n_bricks;
	for (uint32_t id = 0; id < g.n_bricks; id++)
		if (loom__db_brick_empty(db, id))
			t->empty[id >> 6] |= (uint64_t)1 << (id & 63);
	t->slots = t->mem + ex_bytes;
	t->n_slots = T + 1;
	t->slot_bytes = slot_bytes;
	t->fixed_bytes = fixed;
	t->budget = o.budget_bytes;
	pthread_mutex_init(&t->pool_lock, NULL);
	pthread_mutex_init(&t->overflow_lock, NULL);
	pthread_mutex_init(&t->msg_lock, NULL);
	lay_out_slots(t);
	if ((rc = load_exemplars(t, diag)) != LOOM_OK)
		goto fail;

	co.ctx = t;
	if ((rc = loom__cache_open(&co, &t->cache, diag)) != LOOM_OK) {
		if (rc == LOOM_EBUDGET) {
			size_t need = cache_min_budget(&co);
			rc = budget_fail(diag, o.budget_bytes, fixed, need, T, g.brick_bytes);
		}
		goto fail;
	}
	for (unsigned i = 0; i < t->n_slots; i++)
		if ((rc = loom__cache_thread_attach(t->cache, &slot_at(t, i)->cth, diag)) !=
		    LOOM_OK)
			goto fail;

	pthread_mutex_lock(&g_lock);
	t->serial = ++g_serial;
	t->live_next = g_live;
	g_live = t;
	pthread_mutex_unlock(&g_lock);
	*out = t;
	return LOOM_OK;
fail:
	loom__cache_close(t->cache);
	pthread_mutex_destroy(&t->pool_lock);
	pthread_mutex_destroy(&t->overflow_lock);
	pthread_mutex_destroy(&t->msg_lock);
	free(t->mem);
	free(t);
	return rc;
}

LOOM_API void loom_texture_close(loom_texture *t)
{
	if (!t)
		return;
	pthread_mutex_lock(&g_lock);
	for (loom_texture **pp = &g_live; *pp; pp = &(*pp)->live_next)
		if (*pp == t) {
			*pp = t->live_next;
			break;
		}
	pthread_mutex_unlock(&g_lock);
	/* bindings left in threads' tables no longer match a live texture */
	if (tl_bind[0].serial == t->serial)
		memset(&tl_bind[0], 0, sizeof tl_bind[0]);
	loom__cache_close(t->cache);
	pthread_mutex_destroy(&t->pool_lock);
	pthread_mutex_destroy(&t->overflow_lock);
	pthread_mutex_destroy(&t->msg_lock);
	free(t->mem);
	free(t);
}

LOOM_API void loom_texture_thread_done(loom_texture *t)
{
	int k;

	if (!t)
		return;
	for (k = 0; k < TL_BINDINGS; k++)
		if (tl_bind[k].serial == t->serial)
			break;
	if (k == TL_BINDINGS)
		return;
	slot_return(t, tl_bind[k].slot);
	memmove(&tl_bind[k], &tl_bind[k + 1], (size_t)(TL_BINDINGS - 1 - k) * sizeof tl_bind[0]);
	memset(&tl_bind[TL_BINDINGS - 1], 0, sizeof tl_bind[0]);
}

LOOM_API const char *loom_texture_errmsg(const loom_texture *ct)
{
	loom_texture *t = (loom_texture *)ct; /* locks are not part of the value */
	int k;

	if (!t) {
		snprintf(tl_msg, sizeof tl_msg, "loom_texture_errmsg: NULL texture");
		return tl_msg;
	}
	for (k = 0; k < TL_BINDINGS; k++)
		if (tl_bind[k].serial == t->serial)
			break;
	if (k < TL_BINDINGS && tl_bind[k].slot->shared) {
		pthread_mutex_lock(&t->overflow_lock);
		snprintf(tl_msg, sizeof tl_msg, "%s", tl_bind[k].slot->msg);
		pthread_mutex_unlock(&t->overflow_lock);
	} else if (k < TL_BINDINGS) {
		snprintf(tl_msg, sizeof tl_msg, "%s", tl_bind[k].slot->msg);
	} else {
		tl_msg[0] = 0;
	}
	return tl_msg;
}

/* --------------------------------------------------------------- lookups */

LOOM_API int loom_texture_voxel(loom_texture *t, int64_t x, int64_t y, int64_t z,
                                loom_texel *out)
{
	struct tslot *s;
	rawvox r;
	int rc;

	if (!t || !out) {
		if (out)
			memset(out, 0, sizeof *out);
		return LOOM_EINVAL;
	}
	if (!coord_ok(x) || !coord_ok(y) || !coord_ok(z)) {
		memset(out, 0, sizeof *out);
		return LOOM_ERANGE;
	}
	s = slot_enter(t);
	rc = voxel_raw(t, s, x, y, z, &r);
	bump(&s->cnt.lookups, 1);
	slot_leave(t, s);
	texel_of(t, &r, out);
	return rc;
}

/* The calling thread's slot is s; p is finite and in range. */
static int sample_one(loom_texture *t, struct tslot *s, const double p[3], int filter,
                      loom_texel *out)
{
	double u[3], f[3];
	int64_t i0[3];
	rawvox r[8];
	float w[8], wd[8], v[8][3], dens = 0;
	int rc = LOOM_OK, near = 0;

	if (filter == LOOM_FILTER_NEAREST) {
		int64_t q[3];
		for (int a = 0; a < 3; a++)
			q[a] = (int64_t)floor(p[a]);
		rc = voxel_raw(t, s, q[0], q[1], q[2], &r[0]);
		bump(&s->cnt.lookups, 1);
		texel_of(t, &r[0], out);
		return rc;
	}
	for (int a = 0; a < 3; a++) {
		u[a] = p[a] - 0.5;
		i0[a] = (int64_t)floor(u[a]);
		f[a] = u[a] - (double)i0[a];
	}
	/* corners: bit 0 = z (fastest in a brick), bit 1 = x, bit 2 = y */
	for (int c = 0; c < 8; c++) {
		int dz = c & 1, dx = c >> 1 & 1, dy = c >> 2 & 1;
		int e = voxel_raw(t, s, i0[0] + dx, i0[1] + dy, i0[2] + dz, &r[c]);
		if (e != LOOM_OK && rc == LOOM_OK)
			rc = e;
		w[c] = (float)((dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) *
		               (dz ? f[2] : 1 - f[2]));
		wd[c] = 0;
		v[c][0] = v[c][1] = v[c][2] = 0;
		if (r[c].d) {
			float d = t->dens[r[c].d];
			dens += w[c] * d;
			wd[c] = w[c] * d;
			loom__orient_decode(r[c].o, v[c]);
		}
	}
	bump(&s->cnt.lookups, 8);
	near = (f[2] >= 0.5) | (f[0] >= 0.5) << 1 | (f[1] >= 0.5) << 2;
	texel_of(t, &r[near], out);
	out->density = dens;
	loom__orient_blend(8, wd, (const float(*)[3])v, out->orientation);
	return rc;
}

static int pos_check(const double p[3])
{
	for (int a = 0; a < 3; a++) {
		if (!isfinite(p[a]))
			return LOOM_EINVAL;
		if (!(fabs(p[a]) < (double)(COORD_LIMIT / 2)))
			return LOOM_ERANGE;
	}
	return LOOM_OK;
}

LOOM_API int loom_texture_sample(loom_texture *t, const double p[3], int filter,
                                 loom_texel *out)
{
	struct tslot *s;
	int rc;

	if (out)
		memset(out, 0, sizeof *out);
	if (!t || !p || !out ||
	    (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	if ((rc = pos_check(p)) != LOOM_OK)
		return rc;
	s = slot_enter(t);
	rc = sample_one(t, s, p, filter, out);
	slot_leave(t, s);
	return rc;
}

LOOM_API int loom_texture_sample_batch(loom_texture *t, size_t n, const double *x,
                                       const double *y, const double *z, int filter,
                                       const loom_texture_channels *out)
{
	struct tslot *s;
	int rc = LOOM_OK;

	if (!t || !out || (n && (!x || !y || !z)) ||
	    (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	if (n == 0)
		return LOOM_OK;
	s = slot_enter(t);
	for (size_t i = 0; i < n; i++) {
		double p[3] = {x[i], y[i], z[i]};
		loom_texel tx;
		int e = pos_check(p);
		if (e == LOOM_OK)
			e = sample_one(t, s, p, filter, &tx);
		else
			memset(&tx, 0, sizeof tx);
		if (e != LOOM_OK && rc == LOOM_OK)
			rc = e;
		if (out->density)
			out->density[i] = tx.density;
		if (out->orientation)
			memcpy(out->orientation + 3 * i, tx.orientation, sizeof tx.orientation);
		if (out->kind)
			out->kind[i] = tx.kind;
		if (out->type)
			out->type[i] = tx.type;
		if (out->albedo)
			memcpy(out->albedo + 3 * i, tx.albedo, sizeof tx.albedo);
	}
	slot_leave(t, s);
	return rc;
}

/* ------------------------------------------------------------ region reads */

/* Where a group's voxels go: the final channels at stride 1 (z-fastest
   output), or the raw planes into the thread's gather buffer (x-fastest
   output, transposed afterwards).  NULL members are not written. */
struct sink {
	int raw;
	uint8_t *d, *k, *ty, *l;   /* final: density, kind, type, label */
	uint16_t *o;               /* final: orientation */
	const uint8_t *kl, *tl;    /* label -> kind, label -> type */
	unsigned ngrp;             /* of the exemplar (struct exm) */
	uint8_t *rd, *rlo, *rhi, *rl, *rk, *rt; /* gathered planes */
};

/* Byte copies and fills of runs of a few dozen bytes: inline 16-byte moves
   (a libc call per run costs as much as the run). */
static inline void copy_run(uint8_t *restrict d, const uint8_t *restrict s, size_t n)
{
#ifdef __SSE2__
	if (n >= 16) {
		size_t i = 0;
		for (; i + 16 < n; i += 16)
			_mm_storeu_si128((__m128i *)(d + i), _mm_loadu_si128((const __m128i *)(s + i)));
		_mm_storeu_si128((__m128i *)(d + n - 16),
		                 _mm_loadu_si128((const __m128i *)(s + n - 16)));
		return;
	}
#endif
	memcpy(d, s, n);
}

static inline void zero_run(uint8_t *d, size_t n)
{
	memset(d, 0, n); /* measured: faster here than inline stores */
}

static void sink_empty(const struct sink *k, size_t off, size_t n)
{
	if (!n)
		return;
	if (k->raw) {
		if (k->rd)
			zero_run(k->rd + off, n);
		if (k->rlo) {
			zero_run(k->rlo + off, n);
			zero_run(k->rhi + off, n);
		}
		if (k->rl)
			zero_run(k->rl + off, n);
		if (k->rk)
			zero_run(k->rk + off, n);
		if (k->rt)
			zero_run(k->rt + off, n);
		return;
	}
	if (k->d)
		zero_run(k->d + off, n);
	if (k->o)
		zero_run((uint8_t *)(k->o + off), 2 * n);
	if (k->k)
		zero_run(k->k + off, n);
	if (k->ty)
		zero_run(k->ty + off, n);
	if (k->l)
		zero_run(k->l + off, n);
}

/* Orientation codes of n voxels from their low and high byte planes
   (little-endian interleave). */
static inline void orient_join(uint16_t *restrict o, const uint8_t *restrict lo,
                               const uint8_t *restrict hi, size_t n)
{
	size_t i = 0;
#ifdef __SSE2__
	for (; i + 16 <= n; i += 16) {
		__m128i a = _mm_loadu_si128((const __m128i *)(lo + i));
		__m128i b = _mm_loadu_si128((const __m128i *)(hi + i));
		_mm_storeu_si128((__m128i *)(o + i), _mm_unpacklo_epi8(a, b));
		_mm_storeu_si128((__m128i *)(o + i + 8), _mm_unpackhi_epi8(a, b));
	}
	if (i < n && n >= 16) { /* the last 16, overlapping */
		i = n - 16;
		__m128i a = _mm_loadu_si128((const __m128i *)(lo + i));
		__m128i b = _mm_loadu_si128((const __m128i *)(hi + i));
		_mm_storeu_si128((__m128i *)(o + i), _mm_unpacklo_epi8(a, b));
		_mm_storeu_si128((__m128i *)(o + i + 8), _mm_unpackhi_epi8(a, b));
		return;
	}
#endif
	for (; i < n; i++)
		o[i] = (uint16_t)(lo[i] | hi[i] << 8);
}

/* label -> kind and label -> type of n voxels (either output may be NULL),
   through the 256-entry tables. */
static void kt_scalar(uint8_t *restrict dk, uint8_t *restrict dt,
                      const uint8_t *restrict lab, size_t n, const uint8_t *restrict kl,
                      const uint8_t *restrict tl)
{
	if (dk && dt) {
		for (size_t i = 0; i < n; i++) {
			dk[i] = kl[lab[i]];
			dt[i] = tl[lab[i]];
		}
	} else if (dk || dt) {
		uint8_t *restrict d = dk ? dk : dt;
		const uint8_t *restrict lut = dk ? kl : tl;
		for (size_t i = 0; i < n; i++)
			d[i] = lut[lab[i]];
	}
}

#ifdef HAVE_KT_SSSE3
/* The same with PSHUFB, 16 voxels at a time, for labels below 16 * ng
   (every label at or above maps to 0).  Group g of 16 table entries is
   looked up with index label - 16 g + 0x70 (saturated): its high bit (a
   zero result) is set exactly for labels outside [16 g, 16 g + 16).
   n >= 16: the last 16 voxels are done overlapping. */
__attribute__((target("ssse3"))) static void kt_ssse3(uint8_t *dk, uint8_t *dt,
                                                        const uint8_t *lab, size_t n,
                                                        const uint8_t *kl,
                                                        const uint8_t *tl, unsigned ng)
{
	const __m128i bias = _mm_set1_epi8(0x70);
	size_t i = 0;

	if (!tl)
		tl = kl;
	for (;;) {
		__m128i l = _mm_loadu_si128((const __m128i *)(lab + i));
		__m128i rk = _mm_setzero_si128(), rt = _mm_setzero_si128();
		for (unsigned g = 0; g < ng; g++) {
			__m128i ix = _mm_adds_epu8(_mm_sub_epi8(l, _mm_set1_epi8((char)(16 * g))), bias);
			rk = _mm_or_si128(rk, _mm_shuffle_epi8(
			                              _mm_loadu_si128((const __m128i *)(kl + 16 * g)), ix));
			rt = _mm_or_si128(rt, _mm_shuffle_epi8(
			                              _mm_loadu_si128((const __m128i *)(tl + 16 * g)), ix));
		}
		if (dk)
			_mm_storeu_si128((__m128i *)(dk + i), rk);
		if (dt)
			_mm_storeu_si128((__m128i *)(dt + i), rt);
		if (i + 16 == n)
			break;
		i = i + 32 <= n ? i + 16 : n - 16;
	}
}
#endif

static inline void kind_type(const loom_texture *t, const struct sink *k, uint8_t *dk,
                             uint8_t *dt, const uint8_t *lab, size_t n)
{
#ifdef HAVE_KT_SSSE3
	if (k->ngrp && t->ssse3 && n >= 16) {
		kt_ssse3(dk, dt, lab, n, k->kl, k->tl, k->ngrp);
		return;
	}
#else
	(void)t;
#endif
	kt_scalar(dk, dt, lab, n, k->kl, k->tl);
}

/* n voxels of a brick z-run; p points at the run in plane 0. */
static inline void sink_run(const loom_texture *t, const struct sink *k, size_t off,
                            const uint8_t *p, size_t n)
{
	const uint8_t *lo = p + t->bv, *hi = p + 2 * t->bv, *lab = p + 3 * t->bv;
	uint8_t *ok = k->k, *ot = k->ty;

	if (k->raw) {
		if (k->rd)
			copy_run(k->rd + off, p, n);
		if (k->rlo) {
			copy_run(k->rlo + off, lo, n);
			copy_run(k->rhi + off, hi, n);
		}
		if (k->rl)
			copy_run(k->rl + off, lab, n);
		ok = k->rk;
		ot = k->rt;
	} else {
		if (k->d)
			copy_run(k->d + off, p, n);
		if (k->o)
			orient_join(k->o + off, lo, hi, n);
		if (k->l)
			copy_run(k->l + off, lab, n);
	}
	if (ok || ot)
		kind_type(t, k, ok ? ok + off : NULL, ot ? ot + off : NULL, lab, n);
}

/* Columns handled together by group_fill at most. */
#define GMAX 64

/*
 * The z-range [za, zb) of n (1..GMAX) consecutive output columns (lx0 + c,
 * ly), c < n, of crossing e whose source columns lie in one brick column
 * (so they share every brick id), into sink k: column c from offset
 * off + c*cstride (voxel za).  Steps 3-5 once per column (offset, valid
 * range), then per brick of the union of the columns' source z ranges:
 * one brick resolution (the slot's memo) and each column's run in it.
 * Voxels whose brick fails are empty; the first error is returned.
 */
static int group_fill(loom_texture *t, struct tslot *s, struct xent *e, uint32_t lx0,
                      uint32_t ly, uint32_t n, int64_t za, int64_t zb, const struct sink *k,
                      size_t off, size_t cstride)
{
	int64_t b3 = t->b3, bz = t->bs[2];
	int64_t sa[GMAX], sb[GMAX], dzs[GMAX]; /* source z range, offset */
	int64_t smin = INT64_MAX, smax = INT64_MIN;
	uint32_t sx = e->sx0 + lx0, sy = e->sy0 + ly;
	uint64_t base;
	size_t col;
	int rc = LOOM_OK;

	for (uint32_t c = 0; c < n; c++) {
		int64_t dz = xent_dz(t, s, e, lx0 + c, ly);
		int64_t va = za > 0 ? za : 0, vb = zb < b3 ? zb : b3;
		size_t o = off + c * cstride;
		/* voxels with 0 <= z < b3 and 0 <= z - dz < b3 */
		if (va < dz)
			va = dz;
		if (vb > b3 + dz)
			vb = b3 + dz;
		if (va >= vb) {
			sink_empty(k, o, (size_t)(zb - za));
			sa[c] = sb[c] = 0;
			continue;
		}
		sink_empty(k, o, (size_t)(va - za));
		sink_empty(k, o + (size_t)(vb - za), (size_t)(zb - vb));
		dzs[c] = dz;
		sa[c] = va - dz;
		sb[c] = vb - dz;
		if (sa[c] < smin)
			smin = sa[c];
		if (sb[c] > smax)
			smax = sb[c];
	}
	if (smin >= smax)
		return LOOM_OK;
	base = e->ex->first_brick +
	       ((uint64_t)brick_of(t, 1, sy) * e->ex->nb[0] + brick_of(t, 0, sx)) *
	               e->ex->nb[2];
	col = ((size_t)in_brick(t, 1, sy) * t->bs[0] + in_brick(t, 0, sx)) * t->bs[2];
	for (int64_t kz = brick_of(t, 2, (uint32_t)smin); kz * bz < smax; kz++) {
		int64_t z0 = kz * bz, z1 = z0 + bz;
		uint64_t id = base + (uint64_t)kz;
		const uint8_t *p;
		int ok = 1;
		if (id != s->memo_id) {
			int e2 = memo_switch(t, s, id);
			if (e2 != LOOM_OK) {
				if (rc == LOOM_OK)
					rc = e2;
				ok = 0;
			}
		} else {
			bump(&s->cnt.memo_hits, 1);
		}
		p = ok ? s->memo : NULL;
		for (uint32_t c = 0; c < n; c++) {
			int64_t a = sa[c] > z0 ? sa[c] : z0, b = sb[c] < z1 ? sb[c] : z1;
			size_t o;
			if (a >= b)
				continue;
			o = off + c * cstride + (size_t)(a + dzs[c] - za);
			if (p)
				sink_run(t, k, o, p + col + (size_t)c * bz + (size_t)(a - z0),
				         (size_t)(b - a));
			else
				sink_empty(k, o, (size_t)(b - a));
		}
	}
	return rc;
}

/* label -> yarn type of crossing e (built on first use). */
static const uint8_t *xent_tlut(struct xent *e)
{
	if (!e->tlut_ok) {
		for (int l = 0; l < 256; l++)
			e->tlut[l] = e->tok[e->ex->kind[l]];
		e->tlut_ok = 1;
	}
	return e->tlut;
}

struct region {
	const loom_texture_region *out;
	int64_t lo[3], hi[3];
	size_t nx, ny, nz, plane;
};

/* Columns from lx of a row of crossing e (source column e->sx0 + lx) up to
   the end of their source brick column, at most max and GMAX. */
static inline uint32_t group_len(const loom_texture *t, const struct xent *e, uint32_t lx,
                                 int64_t max)
{
	int64_t n = (int64_t)t->bs[0] - (int64_t)in_brick(t, 0, e->sx0 + lx);
	if (n > max)
		n = max;
	return (uint32_t)(n < GMAX ? n : GMAX);
}

/* z-fastest: crossing by crossing (so each crossing entry is set up once
   per call), row by row, groups of columns sharing their bricks; each
   column's runs go straight to the output. */
static int region_zfast(loom_texture *t, struct tslot *s, const struct region *g)
{
	const loom_texture_region *out = g->out;
	int rc = LOOM_OK;
	struct sink k = {0};

	k.d = out->density, k.o = out->orientation, k.k = out->kind;
	k.ty = out->type, k.l = out->label;
	for (int64_t yb = g->lo[1]; yb < g->hi[1];) {
		int64_t ye = (loom_synth_floordiv(yb, t->b2) + 1) * (int64_t)t->b2;
		if (ye > g->hi[1])
			ye = g->hi[1];
		for (int64_t xb = g->lo[0]; xb < g->hi[0];) {
			struct xent *e = xent_enter(t, s, xb, yb);
			int64_t xe = e->x0 + t->b1 < g->hi[0] ? e->x0 + t->b1 : g->hi[0];
			k.kl = e->ex->kind;
			k.ngrp = e->ex->ngrp;
			k.tl = out->type ? xent_tlut(e) : NULL;
			for (int64_t y = yb; y < ye; y++)
				for (int64_t x = xb; x < xe;) {
					uint32_t lx = (uint32_t)(x - e->x0), n = group_len(t, e, lx, xe - x);
					size_t off = ((size_t)(y - g->lo[1]) * g->nx + (size_t)(x - g->lo[0])) *
					             g->nz;
					int e2 = group_fill(t, s, e, lx, (uint32_t)(y - e->y0), n, g->lo[2],
					                    g->hi[2], &k, off, g->nz);
					if (e2 != LOOM_OK && rc == LOOM_OK)
						rc = e2;
					x += n;
				}
			xb = xe;
		}
		yb = ye;
	}
	return rc;
}

#ifdef __SSE2__
/* 16 rows of 16 bytes (row r at src + r*stride) -> v[j] = byte j of every
   row: four rounds of byte interleaves of rows k and k + 8. */
static inline __attribute__((always_inline)) void tr16(const uint8_t *src, size_t stride,
                                                       __m128i v[16])
{
	__m128i w[16];
#pragma GCC unroll 16
	for (int r = 0; r < 16; r++)
		v[r] = _mm_loadu_si128((const __m128i *)(src + (size_t)r * stride));
#pragma GCC unroll 4
	for (int round = 0; round < 4; round++) {
#pragma GCC unroll 8
		for (int k = 0; k < 8; k++) {
			w[2 * k] = _mm_unpacklo_epi8(v[k], v[k + 8]);
			w[2 * k + 1] = _mm_unpackhi_epi8(v[k], v[k + 8]);
		}
#pragma GCC unroll 16
		for (int k = 0; k < 16; k++)
			v[k] = w[k];
	}
}

/* Store the first n (1..16) bytes of v at d. */
static inline void store_part(uint8_t *d, __m128i v, size_t n)
{
	if (n == 16) {
		_mm_storeu_si128((__m128i *)d, v);
	} else {
		uint8_t tmp[16];
		_mm_storeu_si128((__m128i *)tmp, v);
		memcpy(d, tmp, n);
	}
}
#endif

/* out[o + z*plane + c] = buf[c*RZ + z] for c < cn, z < zn (bytes).  The
   buffer holds RCOLS columns of RZ bytes: 16 x 16 blocks are read whole
   (stale bytes past cn or zn are read, never stored).  All column blocks of
   a z block are transposed first so that each output row is then written
   in one go (whole cache lines, whatever the row stride). */
static void tr_plane(uint8_t *restrict out, size_t o, size_t plane,
                     const uint8_t *restrict buf, size_t cn, size_t zn)
{
#ifdef __SSE2__
	size_t nb = (cn + 15) / 16, last = cn - (nb - 1) * 16;
	for (size_t z = 0; z < zn; z += 16) {
		size_t h = zn - z < 16 ? zn - z : 16;
		__m128i v[RCOLS / 16][16];
		for (size_t b = 0; b < nb; b++)
			tr16(buf + b * 16 * RZ + z, RZ, v[b]);
		for (size_t j = 0; j < h; j++) {
			uint8_t *d = out + o + (z + j) * plane;
			for (size_t b = 0; b + 1 < nb; b++)
				_mm_storeu_si128((__m128i *)(d + 16 * b), v[b][j]);
			store_part(d + 16 * (nb - 1), v[nb - 1][j], last);
		}
	}
#else
	for (size_t z = 0; z < zn; z++)
		for (size_t q = 0; q < cn; q++)
			out[o + z * plane + q] = buf[q * RZ + z];
#endif
}

/* The same for orientation codes from their byte planes. */
static void tr_orient(uint16_t *restrict out, size_t o, size_t plane,
                      const uint8_t *restrict lo, const uint8_t *restrict hi, size_t cn,
                      size_t zn)
{
#ifdef __SSE2__
	size_t nb = (cn + 15) / 16, last = cn - (nb - 1) * 16;
	for (size_t z = 0; z < zn; z += 16) {
		size_t h = zn - z < 16 ? zn - z : 16;
		__m128i a[RCOLS / 16][16], b[RCOLS / 16][16];
		for (size_t k = 0; k < nb; k++) {
			tr16(lo + k * 16 * RZ + z, RZ, a[k]);
			tr16(hi + k * 16 * RZ + z, RZ, b[k]);
		}
		for (size_t j = 0; j < h; j++) {
			uint8_t *d = (uint8_t *)(out + o + (z + j) * plane);
			for (size_t k = 0; k < nb; k++) {
				__m128i p0 = _mm_unpacklo_epi8(a[k][j], b[k][j]);
				__m128i p1 = _mm_unpackhi_epi8(a[k][j], b[k][j]);
				if (k + 1 < nb || last == 16) {
					_mm_storeu_si128((__m128i *)(d + 32 * k), p0);
					_mm_storeu_si128((__m128i *)(d + 32 * k + 16), p1);
				} else {
					uint8_t tmp[32];
					_mm_storeu_si128((__m128i *)tmp, p0);
					_mm_storeu_si128((__m128i *)(tmp + 16), p1);
					memcpy(d + 32 * k, tmp, 2 * last);
				}
			}
		}
	}
#else
	for (size_t z = 0; z < zn; z++)
		for (size_t q = 0; q < cn; q++)
			out[o + z * plane + q] = (uint16_t)(lo[q * RZ + z] | hi[q * RZ + z] << 8);
#endif
}

#if defined(__SSE2__) && defined(HAVE_KT_SSSE3)
#define HAVE_TR_KT 1
/* tr_plane of the gathered labels, and from the transposed labels the
   kind and type rows through kind_type's PSHUFB groups (so kind and type
   are neither gathered nor transposed).  lab_out, kind, type may be NULL;
   ng as in kt_ssse3. */
__attribute__((target("ssse3"))) static void
tr_label_kt(uint8_t *lab_out, uint8_t *kind, uint8_t *type, size_t o, size_t plane,
            const uint8_t *restrict buf, size_t cn, size_t zn, const uint8_t *kl,
            const uint8_t *tl, unsigned ng)
{
	const __m128i bias = _mm_set1_epi8(0x70), g16 = _mm_set1_epi8(16);
	/* up to two groups (labels below 32, the usual case) in registers */
	const __m128i K0 = _mm_loadu_si128((const __m128i *)kl);
	const __m128i T0 = _mm_loadu_si128((const __m128i *)(tl ? tl : kl));
	const __m128i K1 = ng > 1 ? _mm_loadu_si128((const __m128i *)(kl + 16)) : _mm_setzero_si128();
	const __m128i T1 = ng > 1 ? _mm_loadu_si128((const __m128i *)((tl ? tl : kl) + 16))
	                          : _mm_setzero_si128();
	size_t nb = (cn + 15) / 16, last = cn - (nb - 1) * 16;

	if (!tl)
		tl = kl;
	for (size_t z = 0; z < zn; z += 16) {
		size_t h = zn - z < 16 ? zn - z : 16;
		__m128i v[RCOLS / 16][16];
		for (size_t b = 0; b < nb; b++)
			tr16(buf + b * 16 * RZ + z, RZ, v[b]);
		for (size_t j = 0; j < h; j++) {
			size_t r = o + (z + j) * plane;
			for (size_t b = 0; b < nb; b++) {
				size_t w = b + 1 < nb ? 16 : last;
				__m128i l = v[b][j];
				__m128i i0 = _mm_adds_epu8(l, bias);
				__m128i i1 = _mm_adds_epu8(_mm_sub_epi8(l, g16), bias);
				__m128i rk = _mm_or_si128(_mm_shuffle_epi8(K0, i0), _mm_shuffle_epi8(K1, i1));
				__m128i rt = _mm_or_si128(_mm_shuffle_epi8(T0, i0), _mm_shuffle_epi8(T1, i1));
				for (unsigned g = 2; g < ng; g++) {
					__m128i ix = _mm_adds_epu8(_mm_sub_epi8(l, _mm_set1_epi8((char)(16 * g))),
					                           bias);
					rk = _mm_or_si128(rk, _mm_shuffle_epi8(
					             _mm_loadu_si128((const __m128i *)(kl + 16 * g)), ix));
					rt = _mm_or_si128(rt, _mm_shuffle_epi8(
					             _mm_loadu_si128((const __m128i *)(tl + 16 * g)), ix));
				}
				if (w == 16) {
					if (lab_out)
						_mm_storeu_si128((__m128i *)(lab_out + r + 16 * b), l);
					if (kind)
						_mm_storeu_si128((__m128i *)(kind + r + 16 * b), rk);
					if (type)
						_mm_storeu_si128((__m128i *)(type + r + 16 * b), rt);
					continue;
				}
				if (lab_out)
					store_part(lab_out + r + 16 * b, l, w);
				if (kind)
					store_part(kind + r + 16 * b, rk, w);
				if (type)
					store_part(type + r + 16 * b, rt, w);
			}
		}
	}
}
#endif

/* Output z range [*ea, *eb) outside which columns lx0 .. lx0 + cn - 1 of
   row ly of crossing e are surely empty: outside [0, b3), outside the
   source block (z - dz outside [0, b3)), or in bricks stored as nothing.
   Empty when *ea >= *eb. */
static void chunk_extent(loom_texture *t, struct tslot *s, struct xent *e, uint32_t lx0,
                         uint32_t ly, uint32_t cn, int64_t *ea, int64_t *eb)
{
	int64_t b3 = t->b3, bz = t->bs[2], a = INT64_MAX, b = INT64_MIN;
	uint32_t sy = e->sy0 + ly;

	for (uint32_t c = 0; c < cn;) {
		uint32_t n = group_len(t, e, lx0 + c, cn - c), sx = e->sx0 + lx0 + c;
		uint64_t base = e->ex->first_brick +
		                ((uint64_t)brick_of(t, 1, sy) * e->ex->nb[0] + brick_of(t, 0, sx)) *
		                        e->ex->nb[2];
		int64_t klo = -1, khi = -1; /* stored bricks of the group */
		for (uint32_t kz = 0; kz < e->ex->nb[2]; kz++)
			if (!brick_empty(t, base + kz)) {
				if (klo < 0)
					klo = kz;
				khi = kz;
			}
		if (klo >= 0)
			for (uint32_t q = c; q < c + n; q++) {
				int64_t dz = xent_dz(t, s, e, lx0 + q, ly);
				int64_t lo = klo * bz + dz, hi = (khi + 1) * bz + dz;
				if (lo < dz)
					lo = dz;
				if (hi > b3 + dz)
					hi = b3 + dz;
				if (lo < a)
					a = lo;
				if (hi > b)
					b = hi;
			}
		c += n;
	}
	*ea = a > 0 ? a : 0;
	*eb = b < b3 ? b : b3;
}

/* n zero bytes at d, inline (rows of a chunk or a crossing piece). */
static inline void zero_row(uint8_t *d, size_t n)
{
#ifdef __SSE2__
	if (n >= 16) {
		const __m128i z = _mm_setzero_si128();
		for (size_t i = 0; i + 16 < n; i += 16)
			_mm_storeu_si128((__m128i *)(d + i), z);
		_mm_storeu_si128((__m128i *)(d + n - 16), z);
		return;
	}
#endif
	memset(d, 0, n);
}

/* Zero rows z in [z0, z1) (relative to the chunk's first output row o) of
   cn columns of every requested channel. */
static void zero_rows(const loom_texture_region *out, size_t o, size_t plane, size_t z0,
                      size_t z1, size_t cn)
{
	for (size_t z = z0; z < z1; z++) {
		size_t r = o + z * plane;
		if (out->density)
			zero_row(out->density + r, cn);
		if (out->orientation)
			zero_row((uint8_t *)(out->orientation + r), 2 * cn);
		if (out->label)
			zero_row(out->label + r, cn);
		if (out->kind)
			zero_row(out->kind + r, cn);
		if (out->type)
			zero_row(out->type + r, cn);
	}
}

/* Zero the x-fastest output over [xa, xb) x [ya, yb) x [za, zb) (every
   requested channel), plane by plane and row after row. */
static void zero_rect(const loom_texture_region *out, const struct region *g, int64_t xa,
                      int64_t xb, int64_t ya, int64_t yb, int64_t za, int64_t zb)
{
	size_t cn = (size_t)(xb - xa);

	for (int64_t z = za; z < zb; z++)
		for (int64_t y = ya; y < yb; y++) {
			size_t r = (size_t)(z - g->lo[2]) * g->plane + (size_t)(y - g->lo[1]) * g->nx +
			           (size_t)(xa - g->lo[0]);
			if (out->density)
				zero_row(out->density + r, cn);
			if (out->orientation)
				zero_row((uint8_t *)(out->orientation + r), 2 * cn);
			if (out->label)
				zero_row(out->label + r, cn);
			if (out->kind)
				zero_row(out->kind + r, cn);
			if (out->type)
				zero_row(out->type + r, cn);
		}
}

/* One chunk of the x-fastest output: columns [x, xc) of row y (crossing
   e), z values [zc, zc + zn) within [0, b3): the rows where the chunk is
   surely empty (chunk_extent, in whole 16-row steps) are zeroed; the rest
   is gathered group by group into the thread's buffer and transposed. */
static int xchunk(loom_texture *t, struct tslot *s, struct xent *e, const struct region *g,
                  const struct sink *k, int kt_after, int64_t x, int64_t xc, int64_t y,
                  int64_t zc, size_t zn)
{
	const loom_texture_region *out = g->out;
	const uint8_t *rd = s->rbuf, *rlo = rd + RCOLS * RZ, *rhi = rlo + RCOLS * RZ;
	const uint8_t *rl = rhi + RCOLS * RZ, *rk = rl + RCOLS * RZ, *rt = rk + RCOLS * RZ;
	size_t cn = (size_t)(xc - x), za, zb;
	size_t o = (size_t)(zc - g->lo[2]) * g->plane + (size_t)(y - g->lo[1]) * g->nx +
	           (size_t)(x - g->lo[0]);
	int64_t ea, eb;
	int rc = LOOM_OK;

	chunk_extent(t, s, e, (uint32_t)(x - e->x0), (uint32_t)(y - e->y0), (uint32_t)cn, &ea,
	             &eb);
	if (ea >= eb || eb <= zc || ea >= zc + (int64_t)zn) {
		zero_rows(out, o, g->plane, 0, zn, cn);
		return LOOM_OK;
	}
	za = ea > zc ? (size_t)(ea - zc) / 16 * 16 : 0;
	zb = eb < zc + (int64_t)zn ? (size_t)(eb - zc + 15) / 16 * 16 : zn;
	if (zb > zn)
		zb = zn;
	zero_rows(out, o, g->plane, 0, za, cn);
	zero_rows(out, o, g->plane, zb, zn, cn);
	for (int64_t q = x; q < xc;) {
		uint32_t lx = (uint32_t)(q - e->x0);
		uint32_t n = group_len(t, e, lx, xc - q);
		int e2 = group_fill(t, s, e, lx, (uint32_t)(y - e->y0), n, zc + (int64_t)za,
		                    zc + (int64_t)zb, k, (size_t)(q - x) * RZ + za, RZ);
		if (e2 != LOOM_OK && rc == LOOM_OK)
			rc = e2;
		q += n;
	}
	o += za * g->plane;
	rd += za, rlo += za, rhi += za, rl += za, rk += za, rt += za;
	zn = zb - za;
	if (out->density)
		tr_plane(out->density, o, g->plane, rd, cn, zn);
	if (out->orientation)
		tr_orient(out->orientation, o, g->plane, rlo, rhi, cn, zn);
#ifdef HAVE_TR_KT
	if (kt_after) {
		tr_label_kt(out->label, out->kind, out->type, o, g->plane, rl, cn, zn, k->kl, k->tl,
		            k->ngrp);
		return rc;
	}
#endif
	if (out->label)
		tr_plane(out->label, o, g->plane, rl, cn, zn);
	if (out->kind)
		tr_plane(out->kind, o, g->plane, rk, cn, zn);
	if (out->type)
		tr_plane(out->type, o, g->plane, rt, cn, zn);
	return rc;
}

/* x-fastest: crossing by crossing; per crossing, slabs of RZ z values
   (outermost, so the rows written meanwhile stay few whatever the plane
   size), rows, chunks of up to RCOLS columns (xchunk).  z planes outside
   [0, b3) are zeroed whole. */
static int region_xfast(loom_texture *t, struct tslot *s, const struct region *g)
{
	const loom_texture_region *out = g->out;
	uint8_t *rd = s->rbuf, *rlo = rd + RCOLS * RZ, *rhi = rlo + RCOLS * RZ;
	uint8_t *rl = rhi + RCOLS * RZ, *rk = rl + RCOLS * RZ, *rt = rk + RCOLS * RZ;
	int64_t b3 = t->b3;
	int64_t za0 = g->lo[2] > 0 ? g->lo[2] : 0, zb0 = g->hi[2] < b3 ? g->hi[2] : b3;
	int rc = LOOM_OK;
	struct sink k = {0};

	for (int64_t z = g->lo[2]; z < g->hi[2]; z++) {
		size_t o = (size_t)(z - g->lo[2]) * g->plane;
		if (z >= 0 && z < b3) {
			z = b3 - 1; /* skip the cloth */
			continue;
		}
		if (out->density)
			memset(out->density + o, 0, g->plane);
		if (out->orientation)
			memset(out->orientation + o, 0, 2 * g->plane);
		if (out->label)
			memset(out->label + o, 0, g->plane);
		if (out->kind)
			memset(out->kind + o, 0, g->plane);
		if (out->type)
			memset(out->type + o, 0, g->plane);
	}
	if (za0 >= zb0)
		return LOOM_OK;
	k.raw = 1;
	k.rd = out->density ? rd : NULL;
	k.rlo = out->orientation ? rlo : NULL;
	k.rhi = out->orientation ? rhi : NULL;
	for (int64_t yb = g->lo[1]; yb < g->hi[1];) {
		int64_t ye = (loom_synth_floordiv(yb, t->b2) + 1) * (int64_t)t->b2;
		if (ye > g->hi[1])
			ye = g->hi[1];
		for (int64_t xb = g->lo[0]; xb < g->hi[0];) {
			struct xent *e = xent_enter(t, s, xb, yb);
			int64_t xe = e->x0 + t->b1 < g->hi[0] ? e->x0 + t->b1 : g->hi[0];
			/* kind and type: from the transposed labels (PSHUFB), or
			   gathered and transposed like the other planes */
			int kt_after = 0;
			k.kl = e->ex->kind;
			k.ngrp = e->ex->ngrp;
			k.tl = out->type ? xent_tlut(e) : NULL;
#ifdef HAVE_TR_KT
			kt_after = t->ssse3 && k.ngrp && (out->kind || out->type);
#endif
			k.rl = out->label || kt_after ? rl : NULL;
			k.rk = out->kind && !kt_after ? rk : NULL;
			k.rt = out->type && !kt_after ? rt : NULL;
			/* z rows where the whole piece of the crossing is surely
			   empty: zeroed plane by plane, row after row (sequential);
			   the slabs cover the rest */
			int64_t pa = INT64_MAX, pb = INT64_MIN, zs = za0, ze = zb0;
			for (int64_t y = yb; y < ye; y++)
				for (int64_t x = xb; x < xe; x += RCOLS) {
					int64_t xc = xe - x > RCOLS ? x + RCOLS : xe, a, b;
					chunk_extent(t, s, e, (uint32_t)(x - e->x0), (uint32_t)(y - e->y0),
					             (uint32_t)(xc - x), &a, &b);
					if (a < b && a < pa)
						pa = a;
					if (a < b && b > pb)
						pb = b;
				}
			if (pa < za0)
				pa = za0;
			if (pb > zb0)
				pb = zb0;
			if (pa >= pb) {
				zs = ze = za0;
			} else {
				if (pa > za0)
					zs = za0 + (pa - za0) / 16 * 16;
				if (pb < zb0)
					ze = za0 + (pb - za0 + 15) / 16 * 16 < zb0 ? za0 + (pb - za0 + 15) / 16 * 16
					                                           : zb0;
			}
			zero_rect(out, g, xb, xe, yb, ye, za0, zs);
			zero_rect(out, g, xb, xe, yb, ye, ze, zb0);
			for (int64_t zc = zs; zc < ze; zc += RZ) {
				size_t zn = ze - zc < RZ ? (size_t)(ze - zc) : RZ;
				for (int64_t y = yb; y < ye; y++)
					for (int64_t x = xb; x < xe; x += RCOLS) {
						int64_t xc = xe - x > RCOLS ? x + RCOLS : xe;
						int e2 = xchunk(t, s, e, g, &k, kt_after, x, xc, y, zc, zn);
						if (e2 != LOOM_OK && rc == LOOM_OK)
							rc = e2;
					}
			}
			xb = xe;
		}
		yb = ye;
	}
	return rc;
}

LOOM_API int loom_texture_read_region(loom_texture *t, const int64_t lo[3],
                                      const int64_t hi[3],
                                      const loom_texture_region *out)
{
	struct region g;
	struct tslot *s;
	size_t total;
	int rc;

	if (!t || !lo || !hi || !out ||
	    (out->layout != LOOM_REGION_X_FASTEST && out->layout != LOOM_REGION_Z_FASTEST))
		return LOOM_EINVAL;
	for (int a = 0; a < 3; a++) {
		if (hi[a] < lo[a])
			return LOOM_EINVAL;
		if (!coord_ok(lo[a]) || !coord_ok(hi[a]))
			return LOOM_ERANGE;
		g.lo[a] = lo[a];
		g.hi[a] = hi[a];
	}
	g.out = out;
	g.nx = (size_t)(hi[0] - lo[0]);
	g.ny = (size_t)(hi[1] - lo[1]);
	g.nz = (size_t)(hi[2] - lo[2]);
	if (!loom__mul_ok(g.nx, g.ny, &g.plane) || !loom__mul_ok(g.plane, g.nz, &total))
		return LOOM_ERANGE;
	if (total == 0)
		return LOOM_OK;
	s = slot_enter(t);
	rc = out->layout == LOOM_REGION_Z_FASTEST ? region_zfast(t, s, &g) :
	                                            region_xfast(t, s, &g);
	bump(&s->cnt.lookups, total);
	slot_leave(t, s);
	return rc;
}

void loom__texture_simd(loom_texture *t, int on)
{
	if (!t)
		return;
	t->ssse3 = 0;
#ifdef HAVE_KT_SSSE3
	if (on) {
		__builtin_cpu_init();
		t->ssse3 = __builtin_cpu_supports("ssse3") != 0;
	}
#else
	(void)on;
#endif
}

/* ------------------------------------------------------------ statistics */

LOOM_API int loom_texture_get_stats(const loom_texture *t, loom_texture_stats *st)
{
	loom__cache_stats cs;
	uint64_t memo = 0, empty = 0;

	if (!st)
		return LOOM_EINVAL;
	memset(st, 0, sizeof *st);
	if (!t)
		return LOOM_EINVAL;
	loom__cache_get_stats(t->cache, &cs);
	for (unsigned i = 0; i < t->n_slots; i++) {
		const struct counters *k = &slot_at(t, i)->cnt;
		st->lookups += rd(&k->lookups);
		memo += rd(&k->memo_hits);
		empty += rd(&k->empty);
		st->crossings += rd(&k->xings);
		st->dz_columns += rd(&k->dz);
		st->errors += rd(&k->errors);
	}
	st->brick_requests = memo + empty + cs.lookups;
	st->hits = memo + cs.hits;
	st->misses = cs.misses;
	st->empty_bricks = empty;
	st->evictions = cs.evictions;
	st->bytes_read = atomic_load_explicit(&((loom_texture *)t)->bytes_read,
	                                      memory_order_relaxed);
	st->bytes_decompressed = cs.bytes_loaded;
	st->decompress_ns = cs.load_ns;
	st->bytes_in_use = t->fixed_bytes + cs.bytes_in_use;
	st->peak_bytes = t->fixed_bytes + cs.peak_bytes;
	st->fixed_bytes = t->fixed_bytes;
	st->budget_bytes = t->budget;
	st->brick_bytes = cs.brick_bytes;
	st->cache_frames = cs.n_frames;
	st->max_threads = t->n_slots - 1;
	st->threads = t->n_slots - 1 - atomic_load(&((loom_texture *)t)->n_free);
	return LOOM_OK;
}
