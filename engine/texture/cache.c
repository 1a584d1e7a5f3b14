/* engine/texture/cache.c - the brick cache.  The design, the invariants and the
   numbered fetch steps cited below are in cache.h. */
#include "cache.h"

#include <inttypes.h>
#include <pthread.h>
#include <sys/mman.h>
#include <unistd.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Frame states (under the stripe lock). */
enum { F_FREE, F_LOADING, F_VALID, F_FAILED };
#define NO_TAG UINT64_MAX /* a frame's tag when not VALID (brick id
                             UINT64_MAX always takes the locked path) */

#define NONE UINT32_MAX
#define ALIGN 64
#define MAX_STRIPES 1024u
#define MIN_FRAMES_PER_STRIPE 8u  /* below this, fewer stripes */

/* The pin word: a count, or CLOSED (a FREE frame, or one being claimed
   under the lock in steps 6-7): lock-free hits (step 3a) cannot pin it. */
#define CLOSED 0x80000000u
#define MAX_WALK 8u /* frames a lock-free probe follows before giving up */
#define PIN_COUNT(v) ((v) & ~CLOSED)
#define FRAME_IS_PINNED(fr) (PIN_COUNT(atomic_load(&(fr)->pins)) != 0)
#define TLC_IS_IDLE(e) ((e)->used && (e)->refs == 0) /* a private pin */

struct frame {
	uint64_t brick_id;     /* unless FREE (under the stripe lock) */
	_Atomic uint64_t tag;  /* brick_id while VALID, else NO_TAG: what the
	                          lock-free probe matches (step 3a) */
	_Atomic uint32_t pins; /* caller pins + private tlc pins + waiters +
	                          probes in flight; CLOSED when FREE */
	_Atomic uint32_t next; /* hash chain (hashed) or free list (FREE);
	                          written under the lock, read by probes */
	int load_rc;           /* FAILED: the loader's result code */
	uint16_t stripe;       /* owning stripe, fixed at open */
	uint8_t state;         /* F_*, under the stripe lock */
	_Atomic uint8_t ref;   /* CLOCK reference bit */
	uint8_t touched;       /* its slab bytes were charged (first load) */
};

struct stripe {
	pthread_mutex_t lock;
	pthread_cond_t cond;          /* broadcast: load published, pin dropped */
	_Atomic uint32_t n_waiting;   /* threads inside step 6c/6d */
	uint32_t first, n;            /* frames [first, first + n) */
	uint32_t hand;                /* CLOCK position, 0 .. n-1 */
	uint32_t free_head;           /* free list of FREE frames */
	uint32_t n_buckets;           /* 2 n */
	_Atomic uint32_t *buckets;    /* chain heads (frame index or NONE);
	                                 written under the lock */
	uint32_t index;               /* this stripe's number */
	_Atomic uint64_t charged_end; /* slab bytes charged: from the page of
	                                 frame `first` up to this page end */
} __attribute__((aligned(ALIGN)));

/* Per-thread cache entry; touched only by the slot's thread (I3). */
struct tlc_entry {
	uint64_t brick_id;     /* when used */
	const uint8_t *data;   /* the frame's bytes, when used */
	uint32_t frame;        /* when used */
	uint32_t refs;         /* caller references (0: IDLE, a private pin) */
	uint32_t stamp;        /* last use, for LRU among IDLE entries */
	uint32_t used;         /* holds one pin on frame */
};

/* Per-slot counters: written only by the slot's current thread (relaxed
   load + store), read by loom__cache_get_stats. */
struct counters {
	_Atomic uint64_t lookups, hits, tlc_hits, lf_hits, misses, loads, load_errors,
	    evictions, waits, tlc_drops, bytes_loaded, load_ns;
};

struct loom__cache_thread {
	loom__cache *cache;
	struct tlc_entry tlc[LOOM__CACHE_TLC_MAX];
	void *scratch;          /* the loader's per-thread scratch, lazily */
	uint32_t n_held;        /* caller pins: IN_USE entries + direct pins */
	uint32_t clock;         /* stamp source for the tlc LRU */
	int attached;           /* under cache->slots_lock */
	struct counters cnt;
} __attribute__((aligned(ALIGN)));

struct loom__cache {
	loom__cache_opts o;
	uint32_t n_frames;
	uint32_t n_stripes;
	uint32_t max_threads;
	uint32_t pin_limit;
	uint32_t tlc_n;               /* tlc entries per thread (K) */
	size_t frame_alloc;           /* bytes of one frame in the slab */
	size_t page;                  /* the system page size */
	size_t block_bytes;           /* the bookkeeping block (this struct...) */
	uint8_t *slab;                /* n_frames * frame_alloc bytes, mmap'ed;
	                                 pages are charged when first touched */
	size_t slab_bytes;            /* mapped length (page multiple) */
	struct stripe *stripes;
	struct frame *frames;
	struct loom__cache_thread *slots;
	pthread_mutex_t slots_lock;   /* attach / detach */
	_Atomic uint64_t bytes_in_use;
	_Atomic uint64_t peak_bytes;
	_Atomic uint32_t evicted;     /* a frame has been evicted (once set, set) */
};

/* ---------------------------------------------------------------- helpers */

static size_t round_up(size_t n, size_t a)
{
	return (n + a - 1) / a * a;
}

static uint64_t mix64(uint64_t x) /* splitmix64 finaliser */
{
	x ^= x >> 30;
	x *= 0xbf58476d1ce4e5b9ull;
	x ^= x >> 27;
	x *= 0x94d049bb133111ebull;
	x ^= x >> 31;
	return x;
}

static uint64_t now_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void bump(_Atomic uint64_t *ctr, uint64_t n) /* single writer */
{
	atomic_store_explicit(ctr, atomic_load_explicit(ctr, memory_order_relaxed) + n,
	                      memory_order_relaxed);
}

static void charge(loom__cache *c, uint64_t n)
{
	uint64_t now = atomic_fetch_add(&c->bytes_in_use, n) + n;
	uint64_t peak = atomic_load(&c->peak_bytes);
	while (now > peak && !atomic_compare_exchange_weak(&c->peak_bytes, &peak, now))
		;
}

static struct stripe *stripe_of(const loom__cache *c, uint64_t h)
{
	return &c->stripes[h & (c->n_stripes - 1)];
}

static _Atomic uint32_t *bucket_of(const struct stripe *sp, uint64_t h)
{
	/* multiply-shift range reduction of the high 32 bits (the low bits
	   chose the stripe) */
	uint64_t b = ((h >> 32) * (uint64_t)sp->n_buckets) >> 32;
	return &sp->buckets[b];
}

/* Chain links: written under the stripe lock, read by lock-free probes
   too (relaxed: a probe validates what it finds, step 3a). */
static uint32_t link_get(const _Atomic uint32_t *l)
{
	return atomic_load_explicit(l, memory_order_relaxed);
}

static void link_set(_Atomic uint32_t *l, uint32_t f)
{
	atomic_store_explicit(l, f, memory_order_relaxed);
}

static uint32_t hash_find(const loom__cache *c, const struct stripe *sp,
                          uint64_t h, uint64_t id)
{
	uint32_t f = link_get(bucket_of(sp, h));
	while (f != NONE && c->frames[f].brick_id != id)
		f = link_get(&c->frames[f].next);
	return f;
}

static void hash_insert(loom__cache *c, struct stripe *sp, uint64_t h, uint32_t f)
{
	_Atomic uint32_t *head = bucket_of(sp, h);
	link_set(&c->frames[f].next, link_get(head));
	link_set(head, f);
}

static void hash_remove(loom__cache *c, struct stripe *sp, uint32_t f)
{
	_Atomic uint32_t *link = bucket_of(sp, mix64(c->frames[f].brick_id));
	while (link_get(link) != f)
		link = &c->frames[link_get(link)].next;
	link_set(link, link_get(&c->frames[f].next));
	link_set(&c->frames[f].next, NONE);
}

/* Set the CLOCK reference bit (a store only when it is clear: hot frames'
   lines are not written on every hit). */
static void ref_set(struct frame *fr)
{
	if (!atomic_load_explicit(&fr->ref, memory_order_relaxed))
		atomic_store_explicit(&fr->ref, 1, memory_order_relaxed);
}

/* A FREE frame onto its stripe's free list (lock held; pins CLOSED). */
static void free_push(loom__cache *c, struct stripe *sp, uint32_t f)
{
	c->frames[f].state = F_FREE;
	link_set(&c->frames[f].next, sp->free_head);
	sp->free_head = f;
}

/* Drop a pin with the stripe lock held (joined waiters, step 6c). */
static void unpin_locked(loom__cache *c, struct stripe *sp, uint32_t f)
{
	struct frame *fr = &c->frames[f];

	uint32_t zero = 0;

	ref_set(fr);
	if (atomic_fetch_sub(&fr->pins, 1) != 1)
		return;
	/* a probe may pin the FAILED frame meanwhile: it is closed only at
	   zero, and the probe's own unpin (locked, step 3a) finishes the job */
	if (fr->state == F_FAILED && atomic_compare_exchange_strong(&fr->pins, &zero, CLOSED))
		free_push(c, sp, f);
	if (atomic_load(&sp->n_waiting) != 0)
		pthread_cond_broadcast(&sp->cond);
}

/* Drop a pin on a VALID frame without the lock (step R3). */
static void unpin_unlocked(loom__cache *c, uint32_t f)
{
	struct frame *fr = &c->frames[f];
	struct stripe *sp = &c->stripes[fr->stripe];

	ref_set(fr);
	if (atomic_fetch_sub(&fr->pins, 1) == 1 && atomic_load(&sp->n_waiting) != 0) {
		pthread_mutex_lock(&sp->lock);
		pthread_cond_broadcast(&sp->cond);
		pthread_mutex_unlock(&sp->lock);
	}
}

/* ------------------------------------------------------------ open/close */

static size_t slot_bytes(void)
{
	return round_up(sizeof(struct loom__cache_thread), ALIGN);
}

/* Bookkeeping block for n frames, S stripes, T slots (one allocation). */
static size_t plan_block(uint64_t n, uint32_t S, uint32_t T)
{
	return round_up(sizeof(loom__cache), ALIGN) +
	       (size_t)S * round_up(sizeof(struct stripe), ALIGN) +
	       (size_t)T * slot_bytes() +
	       round_up((size_t)n * sizeof(struct frame), ALIGN) +
	       round_up((size_t)n * 2 * sizeof(uint32_t), ALIGN);
}

/* The shape of a cache being planned. */
struct plan {
	size_t frame_alloc;    /* bytes per frame in the slab */
	size_t page;           /* page size */
	uint32_t S, T;         /* stripes, thread slots */
};

/* Frames [first, first + n) of stripe s when n frames are split in S. */
static uint64_t stripe_first(uint64_t n, uint32_t S, uint32_t s)
{
	return n * s / S;
}

/* Most slab bytes ever charged for n frames: per stripe, the pages from
   the one holding its first frame to the one holding its last. */
static uint64_t plan_slab(const struct plan *p, uint64_t n)
{
	uint64_t total = 0;
	for (uint32_t s = 0; s < p->S; s++) {
		uint64_t a = stripe_first(n, p->S, s) * p->frame_alloc;
		uint64_t b = stripe_first(n, p->S, s + 1) * p->frame_alloc;
		if (b > a)
			total += round_up(b, p->page) - a / p->page * p->page;
	}
	return total;
}

/* Does the maximal footprint of n frames fit the budget? */
static int plan_fits(const loom__cache_opts *o, const struct plan *p, uint64_t n)
{
	return (uint64_t)plan_block(n, p->S, p->T) + plan_slab(p, n) +
	       (uint64_t)p->T * o->scratch_bytes <= o->budget_bytes;
}

/* Largest n whose maximal footprint fits the budget (0 if none). */
static uint64_t plan_frames(const loom__cache_opts *o, const struct plan *p)
{
	uint64_t fixed = (uint64_t)plan_block(0, p->S, p->T) +
	                 (uint64_t)p->T * o->scratch_bytes;
	uint64_t per = (uint64_t)p->frame_alloc + sizeof(struct frame) + 2 * sizeof(uint32_t);
	uint64_t n;

	if (o->budget_bytes <= fixed)
		return 0;
	n = (o->budget_bytes - fixed) / per; /* an upper bound */
	if (n > NONE / 4)
		n = NONE / 4;
	while (n > 0 && !plan_fits(o, p, n)) {
		/* step down by what the excess is worth, at least one frame */
		uint64_t need = (uint64_t)plan_block(n, p->S, p->T) + plan_slab(p, n) +
		                (uint64_t)p->T * o->scratch_bytes - o->budget_bytes;
		uint64_t step = need / per;
		n -= step > 1 && step < n ? step : 1;
	}
	while (n < NONE / 4 && plan_fits(o, p, n + 1)) /* the steps may undershoot */
		n++;
	return n;
}

static int check_opts(const loom__cache_opts *o, loom_diag *diag)
{
	if (!o->load)
		return loom__fail(diag, LOOM_EINVAL, "cache: no loader given");
	if (o->brick_bytes == 0 || o->brick_bytes > SIZE_MAX / 4)
		return loom__fail(diag, LOOM_EINVAL, "cache: brick size %zu bytes out of range",
		                  o->brick_bytes);
	if (o->scratch_bytes > SIZE_MAX / 4096)
		return loom__fail(diag, LOOM_EINVAL, "cache: scratch size %zu bytes out of range",
		                  o->scratch_bytes);
	if (o->n_stripes & (o->n_stripes - 1) || o->n_stripes > MAX_STRIPES)
		return loom__fail(diag, LOOM_EINVAL,
		                  "cache: %u lock stripes, expected a power of two <= %u",
		                  o->n_stripes, MAX_STRIPES);
	if (o->tlc_entries < -1 || o->tlc_entries > LOOM__CACHE_TLC_MAX)
		return loom__fail(diag, LOOM_EINVAL,
		                  "cache: %d per-thread entries, expected -1..%d",
		                  o->tlc_entries, LOOM__CACHE_TLC_MAX);
	if (o->max_threads > 65536)
		return loom__fail(diag, LOOM_EINVAL, "cache: %u thread slots, at most 65536",
		                  o->max_threads);
	return LOOM_OK;
}

/* The deadlock rule (cache.h): caller pins per thread for F frames per
   stripe, T threads and K private tlc pins per thread; 0 if none. */
static uint32_t pin_limit(uint64_t F, uint32_t T, uint32_t K)
{
	uint64_t reserved = (uint64_t)(T - 1) * K;
	if (F < 1 + reserved)
		return 0;
	return (uint32_t)((F - 1 - reserved) / T + 1);
}

/* Carve the bookkeeping block and initialise stripes and frames. */
static int lay_out(loom__cache *c, uint8_t *block)
{
	uint8_t *p = block + round_up(sizeof(loom__cache), ALIGN);
	_Atomic uint32_t *buckets;
	uint32_t S = c->n_stripes, n = c->n_frames;

	c->stripes = (struct stripe *)p;
	p += (size_t)S * round_up(sizeof(struct stripe), ALIGN);
	c->slots = (struct loom__cache_thread *)p;
	p += (size_t)c->max_threads * slot_bytes();
	c->frames = (struct frame *)p;
	p += round_up((size_t)n * sizeof(struct frame), ALIGN);
	buckets = (_Atomic uint32_t *)p;
	for (size_t b = 0; b < (size_t)n * 2; b++)
		atomic_init(&buckets[b], NONE);

	for (uint32_t s = 0; s < S; s++) {
		struct stripe *sp = &c->stripes[s];
		sp->index = s;
		sp->first = (uint32_t)((uint64_t)n * s / S);
		sp->n = (uint32_t)((uint64_t)n * (s + 1) / S) - sp->first;
		if (pthread_mutex_init(&sp->lock, NULL) != 0)
			return LOOM_ENOMEM;
		if (pthread_cond_init(&sp->cond, NULL) != 0) {
			pthread_mutex_destroy(&sp->lock);
			return LOOM_ENOMEM;
		}
		sp->n_buckets = 2 * sp->n;
		sp->buckets = buckets + 2 * (size_t)sp->first; /* also: lock made */
		sp->free_head = NONE;
		atomic_init(&sp->charged_end,
		            (uint64_t)sp->first * c->frame_alloc / c->page * c->page);
		for (uint32_t k = sp->n; k-- > 0;) {
			struct frame *fr = &c->frames[sp->first + k];
			fr->stripe = (uint16_t)s;
			atomic_init(&fr->tag, NO_TAG);
			atomic_init(&fr->pins, CLOSED);
			free_push(c, sp, sp->first + k);
		}
	}
	for (uint32_t t = 0; t < c->max_threads; t++)
		c->slots[t].cache = c;
	return LOOM_OK;
}

int loom__cache_open(const loom__cache_opts *opts, loom__cache **out, loom_diag *diag)
{
	loom__cache_opts o;
	uint32_t T, S, P, K;
	uint64_t n = 0;
	size_t block;
	struct plan pl;
	loom__cache *c;
	long page = sysconf(_SC_PAGESIZE);
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "cache: NULL output handle");
	*out = NULL;
	if (!opts)
		return loom__fail(diag, LOOM_EINVAL, "cache: NULL options");
	o = *opts;
	if ((rc = check_opts(&o, diag)) != LOOM_OK)
		return rc;
	T = o.max_threads ? o.max_threads : LOOM__CACHE_DEFAULT_THREADS;
	S = o.n_stripes ? o.n_stripes : LOOM__CACHE_DEFAULT_STRIPES;
	P = o.pins_per_thread ? o.pins_per_thread : 1;
	pl.frame_alloc = round_up(o.brick_bytes > LOOM__CACHE_MIN_FRAME ?
	                          o.brick_bytes : LOOM__CACHE_MIN_FRAME, ALIGN);
	pl.page = page > 0 ? (size_t)page : 4096;
	pl.T = T;

	/* Fewer stripes while a stripe would be too small for the deadlock
	   rule (T (P-1) + 1 frames) or for CLOCK to have a choice. */
	for (;;) {
		uint64_t need = (uint64_t)T * (P - 1) + 1;
		pl.S = S;
		n = plan_frames(&o, &pl);
		if (S == 1 || (n / S >= need && n / S >= MIN_FRAMES_PER_STRIPE))
			break;
		S >>= 1;
	}
	if (n == 0)
		return loom__fail(diag, LOOM_EBUDGET,
		                  "cache: budget of %zu bytes cannot hold one %zu-byte brick "
		                  "frame plus %" PRIu64 " bytes of bookkeeping for %u threads",
		                  o.budget_bytes, o.brick_bytes,
		                  (uint64_t)plan_block(1, 1, T) + plan_slab(&pl, 1) -
		                      o.brick_bytes + (uint64_t)T * o.scratch_bytes, T);
	/* per-thread entries: as asked (auto: a quarter of a stripe's frames
	   shared by the threads), fewer while the pin limit would drop below P */
	if (o.tlc_entries < 0)
		K = 0;
	else if (o.tlc_entries > 0)
		K = (uint32_t)o.tlc_entries;
	else
		K = (uint32_t)(n / S / (4u * T) < LOOM__CACHE_TLC_MAX ?
		               n / S / (4u * T) : LOOM__CACHE_TLC_MAX);
	while (K > 0 && pin_limit(n / S, T, K) < P)
		K--;
	if (pin_limit(n / S, T, 0) < P)
		return loom__fail(diag, LOOM_EBUDGET,
		                  "cache: budget of %zu bytes holds %" PRIu64 " brick frames; "
		                  "%u threads with %u pins each need %" PRIu64,
		                  o.budget_bytes, n, T, P, (uint64_t)T * (P - 1) + 1);

	block = plan_block(n, S, T);
	c = aligned_alloc(ALIGN, block);
	if (!c)
		return loom__fail(diag, LOOM_ENOMEM, "cache: out of memory (%zu bytes)", block);
	memset(c, 0, block);
	c->slab_bytes = round_up((size_t)n * pl.frame_alloc, pl.page);
	c->slab = mmap(NULL, c->slab_bytes, PROT_READ | PROT_WRITE,
	               MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
	if (c->slab == MAP_FAILED) {
		free(c);
		return loom__fail(diag, LOOM_ENOMEM, "cache: cannot map %zu bytes of frames",
		                  (size_t)n * pl.frame_alloc);
	}
#ifdef MADV_NOHUGEPAGE
	/* 4 KiB pages, so resident bytes follow the charged bytes exactly */
	madvise(c->slab, c->slab_bytes, MADV_NOHUGEPAGE);
#endif
	c->o = o;
	c->n_frames = (uint32_t)n;
	c->n_stripes = S;
	c->max_threads = T;
	c->tlc_n = K;
	c->pin_limit = pin_limit(n / S, T, K);
	c->frame_alloc = pl.frame_alloc;
	c->page = pl.page;
	c->block_bytes = block;
	if (pthread_mutex_init(&c->slots_lock, NULL) != 0) {
		munmap(c->slab, c->slab_bytes);
		free(c);
		return loom__fail(diag, LOOM_ENOMEM, "cache: cannot create a mutex");
	}
	if (lay_out(c, (uint8_t *)c) != LOOM_OK) {
		loom__cache_close(c);
		return loom__fail(diag, LOOM_ENOMEM, "cache: cannot create stripe locks");
	}
	charge(c, block);
	*out = c;
	return LOOM_OK;
}

void loom__cache_close(loom__cache *c)
{
	if (!c)
		return;
	for (uint32_t t = 0; t < c->max_threads; t++)
		if (c->slots[t].scratch && c->o.scratch_free)
			c->o.scratch_free(c->o.ctx, c->slots[t].scratch);
	munmap(c->slab, c->slab_bytes);
	for (uint32_t s = 0; s < c->n_stripes; s++) {
		if (c->stripes[s].buckets == NULL)
			continue; /* lay_out failed before this stripe */
		pthread_mutex_destroy(&c->stripes[s].lock);
		pthread_cond_destroy(&c->stripes[s].cond);
	}
	pthread_mutex_destroy(&c->slots_lock);
	free(c);
}

/* --------------------------------------------------------------- threads */

int loom__cache_thread_attach(loom__cache *c, loom__cache_thread **out, loom_diag *diag)
{
	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "cache: NULL thread handle output");
	*out = NULL;
	if (!c)
		return loom__fail(diag, LOOM_EINVAL, "cache: NULL cache");
	pthread_mutex_lock(&c->slots_lock);
	for (uint32_t t = 0; t < c->max_threads; t++) {
		if (!c->slots[t].attached) {
			c->slots[t].attached = 1;
			*out = &c->slots[t];
			break;
		}
	}
	pthread_mutex_unlock(&c->slots_lock);
	if (!*out)
		return loom__fail(diag, LOOM_EBUDGET,
		                  "cache: all %u thread slots are attached", c->max_threads);
	return LOOM_OK;
}

void loom__cache_thread_flush(loom__cache_thread *th)
{
	if (!th)
		return;
	for (uint32_t i = 0; i < th->cache->tlc_n; i++) {
		struct tlc_entry *e = &th->tlc[i];
		if (TLC_IS_IDLE(e)) {
			e->used = 0;
			unpin_unlocked(th->cache, e->frame);
		}
	}
}

int loom__cache_thread_detach(loom__cache_thread *th)
{
	loom__cache *c;

	if (!th)
		return LOOM_OK;
	c = th->cache;
	if (th->n_held != 0)
		return LOOM_EINVAL;
	loom__cache_thread_flush(th);
	pthread_mutex_lock(&c->slots_lock);
	th->attached = 0;
	pthread_mutex_unlock(&c->slots_lock);
	return LOOM_OK;
}

/* ------------------------------------------------------------------- get */

/* Step 6b: CLOCK sweep for an unpinned VALID frame (two turns at most). */
static uint32_t clock_sweep(loom__cache_thread *th, struct stripe *sp)
{
	loom__cache *c = th->cache;

	for (uint64_t i = 0; i < 2 * (uint64_t)sp->n; i++) {
		uint32_t f = sp->first + sp->hand;
		struct frame *fr = &c->frames[f];

		sp->hand = sp->hand + 1 == sp->n ? 0 : sp->hand + 1;
		if (fr->state != F_VALID || FRAME_IS_PINNED(fr))
			continue;
		if (atomic_load_explicit(&fr->ref, memory_order_relaxed)) {
			atomic_store_explicit(&fr->ref, 0, memory_order_relaxed);
			continue;
		}
		{
			/* close the pin word: a probe that pinned it first keeps it
			   (I2 with lock-free hits: pins grows without the lock only
			   from a non-zero, non-CLOSED count it then validates) */
			uint32_t zero = 0;
			if (!atomic_compare_exchange_strong(&fr->pins, &zero, CLOSED))
				continue;
		}
		atomic_store(&fr->tag, NO_TAG);
		hash_remove(c, sp, f);
		bump(&th->cnt.evictions, 1);
		if (!atomic_load_explicit(&c->evicted, memory_order_relaxed))
			atomic_store_explicit(&c->evicted, 1, memory_order_relaxed);
		return f;
	}
	return NONE;
}

/* Step 6c: drop this thread's own IDLE tlc pins on this stripe. */
static unsigned drop_idle(loom__cache_thread *th, struct stripe *sp)
{
	loom__cache *c = th->cache;
	unsigned n = 0;

	for (uint32_t i = 0; i < c->tlc_n; i++) {
		struct tlc_entry *e = &th->tlc[i];
		if (TLC_IS_IDLE(e) && c->frames[e->frame].stripe == sp->index) {
			e->used = 0;
			unpin_locked(c, sp, e->frame);
			n++;
		}
	}
	bump(&th->cnt.tlc_drops, n);
	return n;
}

/* Step 6a-6c: a frame to load into, or NONE.  Lock held. */
static uint32_t take_frame(loom__cache_thread *th, struct stripe *sp, int may_drop)
{
	uint32_t f = sp->free_head;

	if (f != NONE) { /* Step 6a */
		sp->free_head = link_get(&th->cache->frames[f].next);
		return f;
	}
	f = clock_sweep(th, sp); /* Step 6b */
	if (f != NONE || !may_drop || drop_idle(th, sp) == 0) /* Step 6c */
		return f;
	return clock_sweep(th, sp);
}

static uint8_t *frame_data(const loom__cache *c, uint32_t f)
{
	return c->slab + (size_t)f * c->frame_alloc;
}

/* First use of frame f: charge the slab pages it brings in.  Frames of a
   stripe are first used in index order (the free list starts sorted and
   only used frames return to it), so the charged range is a prefix. */
static void charge_first_use(loom__cache *c, uint32_t f)
{
	struct frame *fr = &c->frames[f];
	struct stripe *sp = &c->stripes[fr->stripe];
	uint64_t end = round_up(((size_t)f + 1) * c->frame_alloc, c->page);
	uint64_t old = atomic_load(&sp->charged_end);

	fr->touched = 1;
	while (old < end && !atomic_compare_exchange_weak(&sp->charged_end, &old, end))
		;
	if (old < end) {
		charge(c, end - old);
#ifdef MADV_POPULATE_WRITE
		/* one call instead of a page fault per page (4-6x faster here);
		   kernels before 5.14 refuse it and the pages fault as usual */
		madvise(c->slab + old, end - old, MADV_POPULATE_WRITE);
#endif
	}
}

/* Step 8: outside every lock, the frame belongs to this thread. */
static int load_frame(loom__cache_thread *th, uint32_t f, loom_diag *ld)
{
	loom__cache *c = th->cache;
	struct frame *fr = &c->frames[f];
	uint64_t t0, t1;
	void *scratch;
	int rc;

	if (!fr->touched)
		charge_first_use(c, f);
	if ((rc = loom__cache_thread_scratch(th, &scratch, ld)) != LOOM_OK)
		return rc;
	t0 = now_ns();
	rc = c->o.load(c->o.ctx, fr->brick_id, frame_data(c, f), scratch, ld);
	t1 = now_ns();
	bump(&th->cnt.load_ns, t1 - t0);
	if (rc == LOOM_OK)
		bump(&th->cnt.bytes_loaded, c->o.brick_bytes);
	else if (ld->message[0] == '\0')
		loom__fail(ld, rc, "cache: loading brick %" PRIu64 " failed: %s",
		           fr->brick_id, loom_strerror(rc));
	return rc;
}

/* Step 9: publish the load (lock held). */
static void publish(loom__cache *c, struct stripe *sp, uint32_t f, int rc,
                    const loom_diag *ld)
{
	struct frame *fr = &c->frames[f];

	if (rc == LOOM_OK) {
		fr->state = F_VALID;
		atomic_store_explicit(&fr->ref, 1, memory_order_relaxed);
		/* release: a probe that reads the tag sees the loaded bytes */
		atomic_store_explicit(&fr->tag, fr->brick_id, memory_order_release);
	} else {
		hash_remove(c, sp, f);
		fr->state = F_FAILED;
		fr->load_rc = rc;
		/* the message, for the waiters, where the bytes would have been */
		memcpy(frame_data(c, f), ld->message, LOOM__CACHE_MIN_FRAME);
		frame_data(c, f)[LOOM__CACHE_MIN_FRAME - 1] = '\0';
		unpin_locked(c, sp, f);
	}
	pthread_cond_broadcast(&sp->cond);
}

static void count_lookup(loom__cache_thread *th, int hit)
{
	bump(&th->cnt.lookups, 1);
	bump(hit ? &th->cnt.hits : &th->cnt.misses, 1);
}

/* Step 3a: a hit without the lock.  Follow the id's chain (at most
   MAX_WALK links, read while others may change them), pin the frame whose
   tag is the id unless its pin word is CLOSED, then read the tag again:
   still the id means the frame is VALID with this brick and, pinned, stays
   so.  Anything else (no match, CLOSED, a tag that changed) is left to
   the locked path; a pin taken in vain is dropped under the lock (the
   frame may have become FAILED and need freeing). */
static uint32_t probe(loom__cache *c, struct stripe *sp, uint64_t h, uint64_t id)
{
	uint32_t f = link_get(bucket_of(sp, h));
	struct frame *fr;
	uint32_t v;

	for (uint32_t k = 0;; k++) {
		if (f == NONE || k == MAX_WALK || f >= c->n_frames)
			return NONE;
		fr = &c->frames[f];
		if (atomic_load_explicit(&fr->tag, memory_order_relaxed) == id)
			break;
		f = link_get(&fr->next);
	}
	v = atomic_load_explicit(&fr->pins, memory_order_relaxed);
	do {
		if (v & CLOSED)
			return NONE;
	} while (!atomic_compare_exchange_weak(&fr->pins, &v, v + 1));
	if (atomic_load_explicit(&fr->tag, memory_order_acquire) == id) {
		ref_set(fr);
		return f;
	}
	pthread_mutex_lock(&sp->lock);
	unpin_locked(c, sp, f);
	pthread_mutex_unlock(&sp->lock);
	return NONE;
}

/* Steps 3-9: pin brick id in the shared table; *out = its frame. */
static int shared_get(loom__cache_thread *th, uint64_t id, uint32_t *out,
                      loom_diag *diag)
{
	loom__cache *c = th->cache;
	uint64_t h = mix64(id);
	struct stripe *sp = stripe_of(c, h);
	int first_look = 1, hit = 0;
	uint32_t f;

	if (id != NO_TAG && (f = probe(c, sp, h, id)) != NONE) { /* Step 3a */
		count_lookup(th, 1);
		bump(&th->cnt.lf_hits, 1);
		*out = f;
		return LOOM_OK;
	}
	pthread_mutex_lock(&sp->lock);
	for (;;) {
		struct frame *fr;

		f = hash_find(c, sp, h, id); /* Step 3 */
		if (f != NONE) {
			fr = &c->frames[f];
			atomic_fetch_add(&fr->pins, 1);
			if (fr->state == F_VALID) { /* Step 4 */
				ref_set(fr);
				hit = first_look;
				pthread_mutex_unlock(&sp->lock);
				count_lookup(th, hit);
				*out = f;
				return LOOM_OK;
			}
			/* Step 5: another thread is loading it */
			bump(&th->cnt.waits, 1);
			while (fr->state == F_LOADING)
				pthread_cond_wait(&sp->cond, &sp->lock);
			count_lookup(th, 0);
			if (fr->state == F_VALID) {
				pthread_mutex_unlock(&sp->lock);
				*out = f;
				return LOOM_OK;
			}
			{
				int rc = fr->load_rc;
				loom__fail(diag, rc, "%s", (const char *)frame_data(c, f));
				unpin_locked(c, sp, f);
				pthread_mutex_unlock(&sp->lock);
				return rc;
			}
		}
		first_look = 0;
		/* Step 6 */
		f = take_frame(th, sp, 0);
		if (f != NONE)
			break;
		atomic_fetch_add(&sp->n_waiting, 1);
		f = take_frame(th, sp, 1); /* after announcing: see cache.h R3 */
		if (f != NONE) {
			atomic_fetch_sub(&sp->n_waiting, 1);
			break;
		}
		bump(&th->cnt.waits, 1); /* Step 6d */
		pthread_cond_wait(&sp->cond, &sp->lock);
		atomic_fetch_sub(&sp->n_waiting, 1);
	}

	/* Step 7 */
	{
		struct frame *fr = &c->frames[f];
		loom_diag ld = {0};
		int rc;

		fr->brick_id = id;
		fr->state = F_LOADING;
		atomic_store(&fr->pins, 1); /* opens the CLOSED word */
		hash_insert(c, sp, h, f);
		pthread_mutex_unlock(&sp->lock);
		count_lookup(th, 0);

		/* Step 8 */
		if (diag) {
			ld.warn = diag->warn;
			ld.user = diag->user;
		}
		bump(&th->cnt.loads, 1);
		rc = load_frame(th, f, &ld);
		if (diag)
			diag->n_warnings += ld.n_warnings;
		if (rc != LOOM_OK)
			bump(&th->cnt.load_errors, 1);

		/* Step 9 */
		pthread_mutex_lock(&sp->lock);
		publish(c, sp, f, rc, &ld);
		pthread_mutex_unlock(&sp->lock);
		if (rc != LOOM_OK)
			return loom__fail(diag, rc, "%s", ld.message);
		*out = f;
		return LOOM_OK;
	}
}

/* Step 10: keep the new pin in a tlc entry: an unused one, else the
   least recently used IDLE one (its private pin is dropped). */
static void tlc_record(loom__cache_thread *th, uint32_t f, uint64_t id)
{
	loom__cache *c = th->cache;
	struct tlc_entry *best = NULL;

	for (uint32_t i = 0; i < c->tlc_n; i++) {
		struct tlc_entry *e = &th->tlc[i];
		if (!e->used) {
			best = e;
			break;
		}
		if (e->refs == 0 && (!best || e->stamp < best->stamp))
			best = e;
	}
	if (!best)
		return; /* every entry IN_USE: a direct pin */
	if (best->used)
		unpin_unlocked(c, best->frame);
	best->brick_id = id;
	best->data = frame_data(c, f);
	best->frame = f;
	best->refs = 1;
	best->stamp = ++th->clock;
	best->used = 1;
}

int loom__cache_get(loom__cache_thread *th, uint64_t brick_id, const void **data,
                    loom_diag *diag)
{
	loom__cache *c;
	struct tlc_entry *e = NULL;
	uint32_t f;
	int rc;

	if (!data)
		return loom__fail(diag, LOOM_EINVAL, "cache: NULL data output");
	*data = NULL;
	if (!th)
		return loom__fail(diag, LOOM_EINVAL, "cache: NULL thread handle");
	c = th->cache;

	/* Step 1 */
	for (uint32_t i = 0; i < c->tlc_n; i++) {
		if (th->tlc[i].used && th->tlc[i].brick_id == brick_id) {
			e = &th->tlc[i];
			break;
		}
	}
	if (e && e->refs > 0) {
		e->refs++;
		e->stamp = ++th->clock;
		count_lookup(th, 1);
		bump(&th->cnt.tlc_hits, 1);
		*data = e->data;
		return LOOM_OK;
	}

	/* Step 2 */
	if (th->n_held >= c->pin_limit)
		return loom__fail(diag, LOOM_EBUDGET,
		                  "cache: thread already holds %u pinned bricks, the limit "
		                  "for %u frames and %u threads (deadlock rule)",
		                  th->n_held, c->n_frames, c->max_threads);
	if (e) { /* IDLE: the private pin becomes a caller pin */
		e->refs = 1;
		e->stamp = ++th->clock;
		th->n_held++;
		count_lookup(th, 1);
		bump(&th->cnt.tlc_hits, 1);
		*data = e->data;
		return LOOM_OK;
	}

	/* Steps 3-9 */
	if ((rc = shared_get(th, brick_id, &f, diag)) != LOOM_OK)
		return rc;
	/* Step 10 */
	th->n_held++;
	tlc_record(th, f, brick_id);
	*data = frame_data(c, f);
	return LOOM_OK;
}

int loom__cache_thread_scratch(loom__cache_thread *th, void **scratch, loom_diag *diag)
{
	loom__cache *c = th->cache;

	if (c->o.scratch_new && !th->scratch) {
		th->scratch = c->o.scratch_new(c->o.ctx);
		if (!th->scratch)
			return loom__fail(diag, LOOM_ENOMEM,
			                  "cache: cannot create the loader's thread scratch");
		charge(c, c->o.scratch_bytes);
	}
	*scratch = th->scratch;
	return LOOM_OK;
}

uint32_t loom__cache_frame_of(const loom__cache_thread *th, const void *data)
{
	const loom__cache *c = th->cache;
	return (uint32_t)((size_t)((const uint8_t *)data - c->slab) / c->frame_alloc);
}

const void *loom__cache_hint(const loom__cache_thread *th, uint64_t id, uint32_t f)
{
	const loom__cache *c = th->cache;
	uint64_t h = mix64(id);

	if (f >= c->n_frames)
		return NULL;
	__builtin_prefetch(bucket_of(stripe_of(c, h), h));
	__builtin_prefetch(&c->frames[f]);
	return frame_data(c, f);
}

int loom__cache_release(loom__cache_thread *th, const void *data)
{
	loom__cache *c;
	size_t off;

	if (!th || !data)
		return LOOM_EINVAL;
	c = th->cache;
	/* Step R1 */
	for (uint32_t i = 0; i < c->tlc_n; i++) {
		struct tlc_entry *e = &th->tlc[i];
		if (e->data == data && e->used && e->refs > 0) {
			if (--e->refs == 0)
				th->n_held--;
			return LOOM_OK;
		}
	}
	/* Step R2 */
	off = (size_t)((uintptr_t)data - (uintptr_t)c->slab);
	if ((uintptr_t)data < (uintptr_t)c->slab || off >= (size_t)c->n_frames * c->frame_alloc ||
	    off % c->frame_alloc != 0 || th->n_held == 0)
		return LOOM_EINVAL;
	th->n_held--;
	unpin_unlocked(c, (uint32_t)(off / c->frame_alloc)); /* Step R3 */
	return LOOM_OK;
}

/* ----------------------------------------------------------------- stats */

static uint64_t rd(const _Atomic uint64_t *ctr)
{
	return atomic_load_explicit(ctr, memory_order_relaxed);
}

void loom__cache_get_stats(const loom__cache *c, loom__cache_stats *st)
{
	if (!st)
		return;
	memset(st, 0, sizeof *st);
	if (!c)
		return;
	for (uint32_t t = 0; t < c->max_threads; t++) {
		const struct counters *k = &c->slots[t].cnt;
		st->lookups += rd(&k->lookups);
		st->hits += rd(&k->hits);
		st->tlc_hits += rd(&k->tlc_hits);
		st->lf_hits += rd(&k->lf_hits);
		st->misses += rd(&k->misses);
		st->loads += rd(&k->loads);
		st->load_errors += rd(&k->load_errors);
		st->evictions += rd(&k->evictions);
		st->waits += rd(&k->waits);
		st->tlc_drops += rd(&k->tlc_drops);
		st->bytes_loaded += rd(&k->bytes_loaded);
		st->load_ns += rd(&k->load_ns);
	}
	st->bytes_in_use = rd(&c->bytes_in_use);
	st->peak_bytes = rd(&c->peak_bytes);
	st->budget_bytes = c->o.budget_bytes;
	st->brick_bytes = c->o.brick_bytes;
	st->n_frames = c->n_frames;
	st->n_stripes = c->n_stripes;
	st->max_threads = c->max_threads;
	st->pin_limit = c->pin_limit;
	st->tlc_entries = c->tlc_n;
}

unsigned loom__cache_pin_limit(const loom__cache *c)
{
	return c ? c->pin_limit : 0;
}

/* ------------------------------------------------------------ invariants */

static int check_stripe(loom__cache *c, struct stripe *sp, loom_diag *diag)
{
	uint32_t n_free = 0, n_hashed = 0;

	for (uint32_t f = sp->free_head; f != NONE; f = c->frames[f].next) {
		if (++n_free > sp->n || f - sp->first >= sp->n)
			return loom__fail(diag, 0, "stripe %u: free list leaves the stripe", sp->index);
		if (c->frames[f].state != F_FREE || atomic_load(&c->frames[f].pins) != CLOSED)
			return loom__fail(diag, 0, "stripe %u: frame %u on free list is not FREE "
			                  "and unpinned", sp->index, f);
	}
	for (uint32_t b = 0; b < sp->n_buckets; b++) {
		for (uint32_t f = sp->buckets[b]; f != NONE; f = c->frames[f].next) {
			const struct frame *fr = &c->frames[f];
			if (++n_hashed > sp->n || f - sp->first >= sp->n)
				return loom__fail(diag, 0, "stripe %u: chain leaves the stripe", sp->index);
			if (fr->state != F_VALID && fr->state != F_LOADING)
				return loom__fail(diag, 0, "frame %u hashed in state %u", f, fr->state);
			if (atomic_load(&fr->tag) != (fr->state == F_VALID ? fr->brick_id : NO_TAG))
				return loom__fail(diag, 0, "frame %u: tag does not match its state", f);
			if (atomic_load(&fr->pins) & CLOSED)
				return loom__fail(diag, 0, "frame %u hashed with a closed pin word", f);
			if (bucket_of(sp, mix64(fr->brick_id)) != &sp->buckets[b] ||
			    stripe_of(c, mix64(fr->brick_id)) != sp)
				return loom__fail(diag, 0, "frame %u in the wrong bucket", f);
			for (uint32_t g = fr->next; g != NONE; g = c->frames[g].next)
				if (c->frames[g].brick_id == fr->brick_id)
					return loom__fail(diag, 0, "brick %" PRIu64 " hashed twice (I1)",
					                  fr->brick_id);
		}
	}
	for (uint32_t k = 0; k < sp->n; k++) {
		const struct frame *fr = &c->frames[sp->first + k];
		uint32_t pins = atomic_load(&fr->pins);
		if (fr->stripe != sp->index)
			return loom__fail(diag, 0, "frame %u: wrong stripe", sp->first + k);
		if ((fr->state == F_LOADING || fr->state == F_FAILED) && PIN_COUNT(pins) == 0)
			return loom__fail(diag, 0, "frame %u: state %u without a pin",
			                  sp->first + k, fr->state);
		if (fr->state == F_FREE)
			n_free--;
		else if (fr->state != F_FAILED)
			n_hashed--;
	}
	if (n_free != 0 || n_hashed != 0)
		return loom__fail(diag, 0, "stripe %u: free list or hash does not match states",
		                  sp->index);
	return 1;
}

int loom__cache_check(loom__cache *c, loom_diag *diag)
{
	int attached = 0;

	if (!c)
		return loom__fail(diag, 0, "NULL cache");
	for (uint32_t s = 0; s < c->n_stripes; s++) {
		int ok;
		pthread_mutex_lock(&c->stripes[s].lock);
		ok = check_stripe(c, &c->stripes[s], diag);
		pthread_mutex_unlock(&c->stripes[s].lock);
		if (!ok)
			return 0;
	}
	if (rd(&c->bytes_in_use) > c->o.budget_bytes || rd(&c->peak_bytes) > c->o.budget_bytes)
		return loom__fail(diag, 0, "bytes in use %" PRIu64 " / peak %" PRIu64
		                  " above the budget %zu (I4)", rd(&c->bytes_in_use),
		                  rd(&c->peak_bytes), c->o.budget_bytes);
	pthread_mutex_lock(&c->slots_lock);
	for (uint32_t t = 0; t < c->max_threads; t++)
		attached |= c->slots[t].attached;
	pthread_mutex_unlock(&c->slots_lock);
	if (!attached) /* quiescent: no thread can hold a pin */
		for (uint32_t f = 0; f < c->n_frames; f++)
			if (FRAME_IS_PINNED(&c->frames[f]))
				return loom__fail(diag, 0, "frame %u pinned with no thread attached", f);
	return 1;
}

int loom__cache_evicted(const loom__cache *c)
{
	return (int)atomic_load_explicit(&((loom__cache *)c)->evicted, memory_order_relaxed);
}
