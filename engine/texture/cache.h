/*
 * engine/texture/cache.h - the brick cache: a fixed-budget, thread-safe page cache
 * of decompressed exemplar bricks.  Internal to libloom (loom__ prefix).
 *
 * WHAT IT IS
 *   Every voxel lookup ends in a brick: a fixed-size block of decompressed
 *   exemplar voxels (all bricks have the same byte size).  The cache maps a
 *   64-bit brick id to a frame holding that brick's bytes.  A miss calls the
 *   owner's loader (the exemplar database: pread, CRC check, libdeflate) to
 *   fill a frame; the loader runs OUTSIDE every lock.  Callers pin a brick
 *   with loom__cache_get() and unpin it with loom__cache_release(); pinned
 *   bricks are never evicted.  Replacement is CLOCK (second chance).
 *
 * THE MEMORY IT OWNS (all of it counted against budget_bytes)
 *   - one bookkeeping block, malloc'ed at open: the cache header, the lock
 *     stripes, the frame descriptors, the hash buckets (2 per frame) and
 *     max_threads thread slots (each with its per-thread brick cache);
 *   - the frame slab: n_frames frames of brick_bytes (rounded up to 64,
 *     at least LOOM__CACHE_MIN_FRAME) in one anonymous mapping.  Mapping
 *     reserves address space only; a frame's pages are charged when the
 *     frame is first loaded, and made resident then in one madvise
 *     (MADV_POPULATE_WRITE: a page fault per page costs 4-6x more here);
 *     transparent huge pages are off for the slab, so resident and
 *     charged bytes agree.  Frames of a stripe are first used in index
 *     order, so the charged pages of a stripe are a prefix of its range;
 *   - one loader scratch per thread slot (the database puts a libdeflate
 *     decompressor there), made by the owner's scratch_new on the slot's
 *     first miss, charged as the declared scratch_bytes, freed at close.
 *   n_frames is the largest count for which all of that, at its maximum,
 *   fits in budget_bytes; so the bytes in use can never exceed the budget.
 *   A budget that cannot hold one frame plus the bookkeeping is
 *   LOOM_EBUDGET at open.  Outside the count: malloc's own header on the
 *   bookkeeping block (16 bytes) and what scratch_new really allocates
 *   beyond the declared scratch_bytes.
 *
 * PICTURE (one stripe; the cache has n_stripes of them, chosen by id hash:
 * each has its own lock, CLOCK hand, free list and share of the frames)
 *
 *     buckets[2F] --> frame --> frame          frames[F]: FREE | LOADING |
 *        (chains through frame.next)                      VALID | FAILED
 *     free list  --> frame --> frame          hand: CLOCK position
 *     thread slot k: tlc[K] = {brick_id, frame, data, refs}, counters,
 *                    loader scratch
 *
 * FRAME STATES AND INVARIANTS (checked by loom__cache_check)
 *   Each frame has a pin word (a count, or CLOSED) and a tag (its brick
 *   id while VALID, else NO_TAG), both atomic: the lock-free probe of
 *   step 3a reads them, and the chain links, without the lock.
 *   FREE     on its stripe's free list, not hashed, pin word CLOSED.
 *   LOADING  hashed, pins >= 1 (the loading thread and the threads that
 *            joined it, and probes about to let go); only the loading
 *            thread writes its bytes; tag NO_TAG.
 *   VALID    hashed; bytes immutable until evicted (except parts the owner
 *            fills later under its own protocol while pinned: the
 *            texture's density units); evictable iff pins == 0;
 *            tag = its id (stored with release after the bytes).
 *   FAILED   not hashed, pins >= 1 (waiters that have not yet collected
 *            the error); becomes FREE (CLOSED) when pins reaches 0.
 *   I1  A brick id is hashed at most once in the whole cache.
 *   I2  Without the stripe lock, pins grows only in a probe's
 *       compare-and-swap from a count that is not CLOSED, and the probe
 *       keeps the pin only if the tag still equals its id afterwards;
 *       under the lock, steps 4, 5, 7 add pins.  Eviction (step 6b) claims
 *       a VALID frame only by swapping its pin word from 0 to CLOSED, then
 *       sets the tag to NO_TAG, so a probe either pinned it first (the
 *       swap fails, the frame stays) or finds it CLOSED or re-tagged and
 *       lets go.  Step 7 opens the word again (pins = 1).  Pins may shrink
 *       without the lock (release); a FAILED frame is closed (compare-and-
 *       swap 0 -> CLOSED) under the lock by whoever drops its last pin.
 *   I3  A thread slot's tlc entries are touched only by the thread using
 *       the slot (no atomics on the tlc path).  A used entry holds one pin:
 *       IN_USE (refs > 0, the caller holds it) or IDLE (refs == 0, kept
 *       privately for the next get of the same brick).
 *   I4  bytes_in_use <= budget_bytes at every instant.
 *
 * DEADLOCK RULE
 *   When every frame of a stripe is pinned, get() sleeps on a condition
 *   variable instead of exceeding the budget.  Pins come in two kinds:
 *   caller pins (a get not yet released) which callers must release
 *   promptly, and private IDLE tlc pins, at most K per thread, which an
 *   idle thread may keep indefinitely (a sleeping thread first drops its
 *   own, step 6c).  With T = max_threads and F = the frames of the smallest
 *   stripe, open chooses K so that each thread may hold
 *
 *       pin_limit = (F - 1 - (T - 1) K) / T + 1      (integer division)
 *
 *   caller pins (distinct bricks) at once; loom__cache_pin_limit() returns
 *   it, and with K = 0 (tlc off) it is (F - 1) / T + 1.  Then T - 1 idle
 *   threads' private pins plus T threads each blocked while holding
 *   pin_limit - 1 caller pins cover at most F - 1 frames, so a frame is
 *   always free for one of them.  get() enforces the limit: a get beyond
 *   it returns LOOM_EBUDGET instead of risking a deadlock.  Callers must
 *   also never wait on another thread while holding pins, and never call
 *   the cache from inside the loader.  opts.pins_per_thread asks open for
 *   a larger guaranteed limit (fewer tlc entries, fewer stripes, or
 *   LOOM_EBUDGET when the budget cannot give it).
 *
 * FETCH STEPS (loom__cache_get; the code cites them)
 *   Step 1.  Probe the thread's own tlc (no lock, no atomics): an IN_USE
 *            entry for the id gets one more reference (a tlc hit).
 *   Step 2.  Deadlock rule: if the thread already holds pin_limit caller
 *            pins, fail with LOOM_EBUDGET.  An IDLE entry for the id turns
 *            IN_USE (a tlc hit).
 *   Step 3a. Lock-free hit: follow the id's hash chain without the lock (at
 *            most 8 links); a frame whose tag is the id is pinned by a
 *            compare-and-swap unless CLOSED, and kept if its tag is still
 *            the id (a hit, no lock taken); otherwise the pin is dropped
 *            under the lock and the get goes on with step 3.
 *   Step 3.  Lock the id's stripe and look the id up in its hash chain.
 *   Step 4.  VALID: pin, set the reference bit, unlock.  A hit.
 *   Step 5.  LOADING: pin, sleep until the loading thread publishes it.
 *            VALID: share it.  FAILED: copy the error, unpin, return it.
 *   Step 6.  Absent: find a frame.  (a) the free list; (b) a CLOCK sweep
 *            for an unpinned VALID frame, clearing reference bits on the
 *            way (at most two turns); (c) announce a waiter, sweep again,
 *            drop this thread's IDLE tlc pins on the stripe and sweep once
 *            more; (d) sleep until a pin is dropped, then go back to step 3
 *            (another thread may have loaded the id meanwhile).
 *   Step 7.  Claim the frame: unhash its old brick (an eviction), hash the
 *            id, state LOADING, pins = 1, unlock.
 *   Step 8.  Outside every lock: charge the frame's slab pages and make
 *            the thread scratch if this is their first use, then call the
 *            loader.
 *   Step 9.  Relock.  Success: VALID.  Failure: unhash, FAILED, keep the
 *            message in the frame's bytes for the joined waiters, unpin.
 *            Wake the sleepers; unlock.
 *   Step 10. Record the pin in a tlc entry (an unused one, or the least
 *            recently used IDLE one, whose pin is dropped); if every entry
 *            is IN_USE, the pin stays a direct pin.  Return the bytes.
 *
 * RELEASE STEPS (loom__cache_release; no lock unless someone sleeps)
 *   Step R1. A tlc entry holding the pointer: one reference less; at zero
 *            the entry is IDLE and keeps its pin for the next get.
 *   Step R2. Otherwise a direct pin: the frame index is the pointer's
 *            offset in the slab over the frame size (checked); unpin it.
 *   Step R3. Unpinning a frame to zero while a thread sleeps in step 6d on
 *            its stripe takes the stripe lock and wakes it.  (The waiter
 *            announces itself before its last sweep and the unpinner
 *            decrements before it looks, both sequentially consistent, so
 *            either the sweep sees the frame or the unpinner sees the
 *            waiter.)
 *
 * THREADS
 *   Each thread that uses the cache attaches once and gets a thread handle
 *   (loom__cache_thread_attach) from a pool of max_threads slots fixed at
 *   open; get/release take that handle.  A handle is used by one thread at
 *   a time.  Explicit handles rather than pthread keys: the per-thread
 *   memory stays bounded by max_threads whatever threads come and go, the
 *   pin limit can be enforced per thread, there is no race between thread
 *   exit and close, and no process-wide key is consumed.  A slot's scratch
 *   survives detach and is reused by the next thread attached to it.  A
 *   thread about to go idle for long may call loom__cache_thread_flush to
 *   give its IDLE pins back to the cache.  Everything else on the cache
 *   may be called from any thread at any time except loom__cache_close (no
 *   other call may be in flight).
 */
#ifndef LOOM_CACHE_H
#define LOOM_CACHE_H

#include "core/internal.h"

/* Per-thread recent-brick entries (tlc) at most; see opts.tlc_entries. */
#define LOOM__CACHE_TLC_MAX 8
/* Thread slots when opts.max_threads is 0. */
#define LOOM__CACHE_DEFAULT_THREADS 16
/* Lock stripes when opts.n_stripes is 0 (a power of two; open uses fewer
   when a stripe would hold fewer than 8 frames). */
#define LOOM__CACHE_DEFAULT_STRIPES 4
/* Frames never smaller than this (a failed load's message lives there
   for the threads that waited on it). */
#define LOOM__CACHE_MIN_FRAME LOOM_DIAG_MSG_MAX

/*
 * Loader: fill dst (exactly brick_bytes) with brick brick_id.  Returns
 * LOOM_OK or a loom result code with the detail in diag (never NULL here).
 * thread_scratch is this thread's scratch (NULL when no scratch_new was
 * given).  Called concurrently from several threads, each with its own
 * scratch; must not call back into the cache.
 */
typedef int (*loom__cache_load_fn)(void *ctx, uint64_t brick_id, void *dst,
                                   void *thread_scratch, loom_diag *diag);

typedef struct loom__cache_opts {
	size_t budget_bytes;       /* everything the cache may hold, bytes */
	size_t brick_bytes;        /* decompressed size of every brick, > 0 */
	loom__cache_load_fn load;  /* required */
	void *ctx;                 /* passed to load, scratch_new, scratch_free */
	void *(*scratch_new)(void *ctx);          /* optional; NULL = failure */
	void (*scratch_free)(void *ctx, void *scratch); /* optional */
	size_t scratch_bytes;      /* budget charge of one scratch, bytes */
	unsigned max_threads;      /* thread slots; 0 -> DEFAULT_THREADS */
	unsigned n_stripes;        /* wanted lock stripes (power of two);
	                              0 -> DEFAULT_STRIPES; open may use fewer */
	unsigned pins_per_thread;  /* pin_limit open must guarantee; 0 -> 1 */
	int tlc_entries;           /* per-thread entries K: -1 off, 0 auto
	                              (min(TLC_MAX, stripe frames / (4 T))),
	                              1..TLC_MAX at most (open lowers K while
	                              the pin limit is below pins_per_thread) */
} loom__cache_opts;

typedef struct loom__cache_stats {
	uint64_t lookups;      /* gets past the argument and pin-limit checks */
	uint64_t hits;         /* brick resident and valid at first look */
	uint64_t tlc_hits;     /* of hits, served by the per-thread cache */
	uint64_t lf_hits;      /* of hits, served by the lock-free probe
	                          (step 3a) */
	uint64_t misses;       /* not resident at first look (lookups - hits) */
	uint64_t loads;        /* frames claimed for loading (step 7); equals
	                          loader calls unless a thread scratch could
	                          not be made */
	uint64_t load_errors;  /* of loads, failed (loader error, or ENOMEM
	                          from scratch_new) */
	uint64_t evictions;    /* VALID frames recycled for another brick */
	uint64_t waits;        /* sleeps: on another thread's load or step 6d */
	uint64_t tlc_drops;    /* IDLE tlc pins a thread dropped in step 6c */
	uint64_t bytes_loaded; /* decompressed bytes delivered by the loader */
	uint64_t load_ns;      /* nanoseconds spent inside the loader */
	uint64_t bytes_in_use; /* now: bookkeeping + charged slab pages +
	                          scratches */
	uint64_t peak_bytes;   /* maximum of bytes_in_use since open */
	uint64_t budget_bytes; /* as opened */
	uint64_t brick_bytes;  /* as opened */
	uint32_t n_frames;     /* frames the budget holds */
	uint32_t n_stripes;    /* lock stripes in use */
	uint32_t max_threads;  /* thread slots */
	uint32_t pin_limit;    /* caller pins one thread may hold (distinct) */
	uint32_t tlc_entries;  /* per-thread cache entries K */
} loom__cache_stats;

typedef struct loom__cache loom__cache;
typedef struct loom__cache_thread loom__cache_thread;

/* Open a cache.  LOOM_EINVAL: NULL opts/out, brick_bytes 0, no loader,
   n_stripes not a power of two or above 1024, tlc_entries out of range,
   max_threads above 65536; LOOM_EBUDGET:
   budget too small for one frame (or for pins_per_thread); LOOM_ENOMEM.
   *out is NULL on failure. */
int loom__cache_open(const loom__cache_opts *opts, loom__cache **out,
                     loom_diag *diag);
/* Free everything (scratches through scratch_free).  NULL-safe.  No other
   call on the cache, nor on its thread handles, may be in flight. */
void loom__cache_close(loom__cache *c);

/* Take a free thread slot.  LOOM_EBUDGET when all max_threads slots are
   attached.  Thread-safe. */
int loom__cache_thread_attach(loom__cache *c, loom__cache_thread **out,
                              loom_diag *diag);
/* Return the slot (its IDLE tlc pins are dropped, its scratch kept for
   the next user).  LOOM_EINVAL (and nothing done) if the thread still
   holds caller pins.  NULL-safe. */
int loom__cache_thread_detach(loom__cache_thread *th);
/* Drop the thread's IDLE tlc pins (caller pins stay).  NULL-safe. */
void loom__cache_thread_flush(loom__cache_thread *th);

/* Pin brick_id and set *data to its brick_bytes read-only bytes (valid
   until the matching release).  Loads it on a miss (once, however many
   threads miss it together).  Errors: the loader's code and message
   (every waiter gets them; a later get retries), LOOM_ENOMEM, LOOM_EBUDGET
   (the thread holds pin_limit bricks already), LOOM_EINVAL.  On error
   *data is NULL and nothing is pinned.  Thread-safe across handles; one
   thread at a time per handle. */
int loom__cache_get(loom__cache_thread *th, uint64_t brick_id,
                    const void **data, loom_diag *diag);
/* Unpin a pointer returned by get (each get is matched by one release).
   LOOM_EINVAL if data is not a frame of this cache or the thread holds no
   pin (checked by arithmetic; data is never read). */
int loom__cache_release(loom__cache_thread *th, const void *data);

/* The thread's loader scratch (made and charged on first use, as a load
   would): for a caller that fills part of a pinned frame itself (the
   texture's density units, filled plane by plane).  LOOM_ENOMEM. */
int loom__cache_thread_scratch(loom__cache_thread *th, void **scratch, loom_diag *diag);

/* Prefetch hints (the texture's brick table, lookup.c): the frame of a
   pointer returned by get (arithmetic; data is never read), and for a
   frame f that held brick_id when last seen, the prefetch of the hash
   bucket and frame descriptor a get of brick_id reads, returning f's
   bytes.  Nothing is pinned and f may hold another brick by now: the
   bytes must never be read through the result, only prefetched. */
uint32_t loom__cache_frame_of(const loom__cache_thread *th, const void *data);
const void *loom__cache_hint(const loom__cache_thread *th, uint64_t brick_id, uint32_t f);

/* 1 once the cache has evicted a frame (the budget has been below the
   working set since open); a hint, relaxed. */
int loom__cache_evicted(const loom__cache *c);

/* Statistics snapshot (counters are exact when no call is in flight). */
void loom__cache_get_stats(const loom__cache *c, loom__cache_stats *st);
/* Caller pins (distinct bricks) one thread may hold at once (deadlock
   rule); 0 for NULL. */
unsigned loom__cache_pin_limit(const loom__cache *c);
/* Verify the invariants above (locks each stripe in turn); returns 1 when
   they hold, else 0 with the first violation in diag.  For tests. */
int loom__cache_check(loom__cache *c, loom_diag *diag);

#endif /* LOOM_CACHE_H */
