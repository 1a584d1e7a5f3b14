/* tests/unit/test_cache.c - the brick cache (engine/texture/cache.h) against a
   deterministic loader: brick bytes are a function of the brick id, so every
   byte a get returns can be checked; a reference CLOCK model checks the
   replacement order; threads hammer one cache (also run under make tsan). */
#include "check.h"
#include "texture/cache.h"

#include <malloc.h>
#include <pthread.h>
#include <stdatomic.h>
#include <time.h>
#include <unistd.h>

/* ------------------------------------------------------------ the loader */

struct loader {
	atomic_uint calls;           /* every load call */
	atomic_uint calls_id;        /* calls for watch_id */
	uint64_t watch_id;
	atomic_int fail;             /* fail loads of fail_id when set */
	uint64_t fail_id;
	uint64_t fail_mod;           /* if set, ids with id % fail_mod == 3 fail */
	unsigned sleep_us;           /* sleep inside every load */
	unsigned jitter_us;          /* plus up to this, pseudo-random */
	atomic_int in_load;          /* loads in progress */
	atomic_uint scratch_made, scratch_freed;
	atomic_int scratch_fail;     /* scratch_new returns NULL while set */
	atomic_uint scratch_misuse;  /* a scratch used by two loads at once */
	atomic_uint bad_scratch;     /* load got a NULL scratch */
};

struct scratch {
	atomic_int busy;
	uint32_t magic;
};

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static uint64_t brick_word(uint64_t id, size_t i)
{
	return mix(id * 0x100000001b3ull + i);
}

/* 1 if p holds brick id's n bytes */
static int brick_ok(const void *p, uint64_t id, size_t n)
{
	const uint64_t *w = p;
	for (size_t i = 0; i < n / 8; i++)
		if (w[i] != brick_word(id, i))
			return 0;
	return 1;
}

static void sleep_us(unsigned us)
{
	struct timespec ts = {us / 1000000u, (long)(us % 1000000u) * 1000};
	nanosleep(&ts, NULL);
}

static int test_load(void *ctx, uint64_t id, void *dst, void *scratch, loom_diag *diag)
{
	struct loader *L = ctx;
	struct scratch *s = scratch;
	uint64_t *w = dst;

	atomic_fetch_add(&L->calls, 1);
	if (id == L->watch_id)
		atomic_fetch_add(&L->calls_id, 1);
	if (!s || s->magic != 0x5c7a7c4u)
		atomic_fetch_add(&L->bad_scratch, 1);
	else if (atomic_exchange(&s->busy, 1) != 0)
		atomic_fetch_add(&L->scratch_misuse, 1);
	atomic_fetch_add(&L->in_load, 1);
	if (L->sleep_us || L->jitter_us)
		sleep_us(L->sleep_us + (L->jitter_us ? (unsigned)(mix(id) % L->jitter_us) : 0));
	atomic_fetch_sub(&L->in_load, 1);
	if (s)
		atomic_store(&s->busy, 0);
	if ((atomic_load(&L->fail) && id == L->fail_id) ||
	    (L->fail_mod && id % L->fail_mod == 3))
		return loom__fail(diag, LOOM_ECORRUPT,
		                  "test.db:brick %llu: CRC mismatch (stored 0x1234)",
		                  (unsigned long long)id);
	for (size_t i = 0; i < 512; i++) /* bricks are 4096 bytes in these tests */
		w[i] = brick_word(id, i);
	return LOOM_OK;
}

static void *test_scratch_new(void *ctx)
{
	struct loader *L = ctx;
	struct scratch *s;

	if (atomic_load(&L->scratch_fail))
		return NULL;
	s = calloc(1, sizeof *s);
	if (s) {
		s->magic = 0x5c7a7c4u;
		atomic_fetch_add(&L->scratch_made, 1);
	}
	return s;
}

static void test_scratch_free(void *ctx, void *p)
{
	struct loader *L = ctx;
	atomic_fetch_add(&L->scratch_freed, 1);
	free(p);
}

#define BRICK 4096u
#define FRAME_ALLOC 4096u   /* a 4096-byte brick takes one page of slab */
#define SCRATCH_BYTES 1000u

static loom__cache_opts base_opts(struct loader *L, size_t budget)
{
	loom__cache_opts o = {0};
	o.budget_bytes = budget;
	o.brick_bytes = BRICK;
	o.load = test_load;
	o.ctx = L;
	o.scratch_new = test_scratch_new;
	o.scratch_free = test_scratch_free;
	o.scratch_bytes = SCRATCH_BYTES;
	o.max_threads = 1;
	o.n_stripes = 1; /* one CLOCK: replacement order is checkable */
	o.tlc_entries = -1;
	return o;
}

static loom__cache *open_ok(const loom__cache_opts *o)
{
	loom__cache *c = NULL;
	loom_diag d = {0};
	int rc = loom__cache_open(o, &c, &d);
	if (rc != LOOM_OK)
		printf("  open: %s\n", d.message);
	CHECK_EQ_INT(rc, LOOM_OK);
	return c;
}

/* Smallest budget that gives at least k frames (binary search on open). */
static size_t budget_for(loom__cache_opts o, uint32_t k)
{
	size_t lo = 1, hi = (size_t)k * 8192 + (1u << 20);
	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		loom__cache *c = NULL;
		loom__cache_stats st;
		o.budget_bytes = mid;
		if (loom__cache_open(&o, &c, NULL) == LOOM_OK) {
			loom__cache_get_stats(c, &st);
			loom__cache_close(c);
			if (st.n_frames >= k) {
				hi = mid;
				continue;
			}
		}
		lo = mid + 1;
	}
	return lo;
}

static void check_quiet(loom__cache *c)
{
	loom_diag d = {0};
	int ok = loom__cache_check(c, &d);
	if (!ok)
		printf("  invariant: %s\n", d.message);
	CHECK(ok);
}

static void check_stats(loom__cache *c, const struct loader *L)
{
	loom__cache_stats st;
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.hits + st.misses, st.lookups);
	CHECK(st.tlc_hits <= st.hits);
	CHECK_EQ_INT(st.loads, atomic_load(&L->calls));
	CHECK_EQ_INT(st.bytes_loaded, (st.loads - st.load_errors) * BRICK);
	CHECK(st.peak_bytes <= st.budget_bytes);
	CHECK(st.bytes_in_use <= st.peak_bytes);
}

/* ------------------------------------------------------------- the tests */

static void bad_arguments(void)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 1u << 20);
	loom__cache *c = (loom__cache *)&L;
	loom__cache_thread *th;
	loom_diag d = {0};
	const void *p = &L;

	CHECK_EQ_INT(loom__cache_open(NULL, &c, &d), LOOM_EINVAL);
	CHECK(c == NULL);
	CHECK_EQ_INT(loom__cache_open(&o, NULL, &d), LOOM_EINVAL);
	o.load = NULL;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "loader");
	o = base_opts(&L, 1u << 20);
	o.brick_bytes = 0;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EINVAL);
	o = base_opts(&L, 1u << 20);
	o.n_stripes = 3;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "power of two");
	o = base_opts(&L, 1u << 20);
	o.tlc_entries = LOOM__CACHE_TLC_MAX + 1;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EINVAL);
	o.tlc_entries = -2;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EINVAL);
	CHECK(c == NULL);

	loom__cache_close(NULL); /* NULL-safe */
	CHECK_EQ_INT(loom__cache_thread_detach(NULL), LOOM_OK);
	CHECK_EQ_INT(loom__cache_get(NULL, 1, &p, &d), LOOM_EINVAL);
	CHECK(p == NULL);
	CHECK_EQ_INT(loom__cache_release(NULL, &L), LOOM_EINVAL);
	CHECK_EQ_INT(loom__cache_thread_attach(NULL, &th, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom__cache_pin_limit(NULL), 0);

	o = base_opts(&L, 1u << 20);
	c = open_ok(&o);
	if (!c)
		return;
	CHECK_EQ_INT(loom__cache_thread_attach(c, &th, &d), LOOM_OK);
	{
		loom__cache_thread *th2;
		CHECK_EQ_INT(loom__cache_thread_attach(c, &th2, &d), LOOM_EBUDGET);
		CHECK(th2 == NULL);
		CHECK_STR_CONTAINS(d.message, "thread slots");
	}
	CHECK_EQ_INT(loom__cache_get(th, 7, NULL, &d), LOOM_EINVAL);
	{
		uint8_t fake[256] = {0};
		CHECK_EQ_INT(loom__cache_release(th, fake + 128), LOOM_EINVAL);
	}
	CHECK_EQ_INT(loom__cache_get(th, 7, &p, &d), LOOM_OK);
	CHECK(p && brick_ok(p, 7, BRICK));
	CHECK_EQ_INT(loom__cache_thread_detach(th), LOOM_EINVAL); /* holds a pin */
	CHECK_EQ_INT(loom__cache_release(th, p), LOOM_OK);
	CHECK_EQ_INT(loom__cache_release(th, p), LOOM_EINVAL); /* not held any more */
	CHECK_EQ_INT(loom__cache_thread_detach(th), LOOM_OK);
	check_quiet(c);
	loom__cache_close(c);
	CHECK_EQ_INT(atomic_load(&L.scratch_made), 1);
	CHECK_EQ_INT(atomic_load(&L.scratch_freed), 1);
}

static void budget_too_small(void)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 0);
	loom__cache *c = NULL;
	loom__cache_stats st;
	loom_diag d = {0};
	size_t b1;

	o.budget_bytes = 0;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EBUDGET);
	o.budget_bytes = BRICK; /* the brick alone, no room for bookkeeping */
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EBUDGET);
	CHECK_STR_CONTAINS(d.message, "cannot hold one");
	CHECK(c == NULL);

	/* the smallest budget that opens holds exactly one frame, and it is
	   more than the frame itself (bookkeeping and the scratch count) */
	b1 = budget_for(o, 1);
	CHECK(b1 > FRAME_ALLOC + SCRATCH_BYTES);
	CHECK(b1 < FRAME_ALLOC + SCRATCH_BYTES + 4096);
	o.budget_bytes = b1 - 1;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EBUDGET);
	o.budget_bytes = b1;
	c = open_ok(&o);
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.n_frames, 1);
	CHECK_EQ_INT(st.pin_limit, 1);
	CHECK(st.bytes_in_use + FRAME_ALLOC + SCRATCH_BYTES <= b1);
	loom__cache_close(c);

	/* more threads cost more bookkeeping: the same budget no longer opens */
	o.max_threads = 8;
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EBUDGET);

	/* pins_per_thread asks for frames: 2 threads x 3 pins need 5 frames */
	o = base_opts(&L, 0);
	o.max_threads = 2;
	o.budget_bytes = budget_for(o, 4);
	o.pins_per_thread = 3;
	d.message[0] = '\0';
	CHECK_EQ_INT(loom__cache_open(&o, &c, &d), LOOM_EBUDGET);
	CHECK_STR_CONTAINS(d.message, "holds 4 brick frames");
	CHECK_STR_CONTAINS(d.message, "need 5");
	o.pins_per_thread = 1;
	o.budget_bytes = budget_for(o, 5);
	o.pins_per_thread = 3;
	c = open_ok(&o);
	CHECK_EQ_INT(loom__cache_pin_limit(c), 3);
	loom__cache_close(c);
}

/* The deadlock rule's constant, hand-checked: (F - 1) / T + 1. */
static void pin_limit_rule(void)
{
	/* (F - 1 - (T - 1) K) / T + 1; an asked K too large is lowered until
	   the limit is at least 1 */
	static const struct { uint32_t frames, threads; int tlc; uint32_t k, limit; } cases[] = {
		{1, 1, -1, 0, 1}, {1, 16, -1, 0, 1}, {4, 2, -1, 0, 2}, {10, 3, -1, 0, 4},
		{9, 4, -1, 0, 3}, {3, 1, -1, 0, 3}, {3, 1, 8, 8, 3}, {10, 3, 1, 1, 3},
		{64, 8, 2, 2, 7}, {2, 2, 2, 1, 1}, {3, 4, 2, 0, 1}, {64, 8, 0, 2, 7},
	};
	struct loader L = {0};

	for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
		loom__cache_opts o = base_opts(&L, 0);
		loom__cache *c;
		loom__cache_stats st;
		o.max_threads = cases[k].threads;
		o.tlc_entries = cases[k].tlc;
		o.budget_bytes = budget_for(o, cases[k].frames);
		c = open_ok(&o);
		if (!c)
			continue;
		loom__cache_get_stats(c, &st);
		CHECK_EQ_INT(st.n_frames, cases[k].frames);
		CHECK_EQ_INT(st.tlc_entries, cases[k].k);
		CHECK_EQ_INT(st.pin_limit, cases[k].limit);
		loom__cache_close(c);
	}

	/* enforcement: 4 frames, 2 threads -> 2 pins, the third is refused */
	{
		loom__cache_opts o = base_opts(&L, 0);
		loom__cache *c;
		loom__cache_thread *th;
		loom_diag d = {0};
		const void *p[3];
		o.max_threads = 2;
		o.tlc_entries = 1; /* (4 - 1 - 1) / 2 + 1 = 2 */
		o.budget_bytes = budget_for(o, 4);
		c = open_ok(&o);
		if (!c)
			return;
		if (loom__cache_pin_limit(c) != 2) {
			CHECK_EQ_INT(loom__cache_pin_limit(c), 2);
			loom__cache_close(c);
			return;
		}
		CHECK_EQ_INT(loom__cache_thread_attach(c, &th, &d), LOOM_OK);
		CHECK_EQ_INT(loom__cache_get(th, 1, &p[0], &d), LOOM_OK);
		CHECK_EQ_INT(loom__cache_get(th, 2, &p[1], &d), LOOM_OK);
		CHECK_EQ_INT(loom__cache_get(th, 3, &p[2], &d), LOOM_EBUDGET);
		CHECK_STR_CONTAINS(d.message, "deadlock rule");
		CHECK(p[2] == NULL);
		/* brick 1 sits IN_USE in the one tlc entry, 2 is a direct pin:
		   getting 1 again is not a new pin, getting 2 again is */
		CHECK_EQ_INT(loom__cache_get(th, 2, &p[2], &d), LOOM_EBUDGET);
		CHECK_EQ_INT(loom__cache_get(th, 1, &p[2], &d), LOOM_OK);
		CHECK(p[2] == p[0]);
		loom__cache_release(th, p[2]);
		loom__cache_release(th, p[1]);
		CHECK_EQ_INT(loom__cache_get(th, 3, &p[2], &d), LOOM_OK);
		CHECK(brick_ok(p[2], 3, BRICK) && brick_ok(p[0], 1, BRICK));
		loom__cache_release(th, p[2]);
		loom__cache_release(th, p[0]);
		CHECK_EQ_INT(loom__cache_thread_detach(th), LOOM_OK);
		check_quiet(c);
		loom__cache_close(c);
	}
}

/* Default stripes: 4, fewer while a stripe would hold under 8 frames
   (the budget is the smallest that gives the frame count, so a count just
   above a multiple of 8 stripes is where the choice flips). */
static void stripe_choice(void)
{
	static const struct { uint32_t frames; unsigned asked, stripes; } cases[] = {
		{64, 0, 4}, {33, 0, 4}, {31, 0, 2}, {20, 0, 2}, {15, 0, 1}, {3, 0, 1},
		{256, 16, 16}, {300, 64, 32}, {100, 1, 1},
	};
	struct loader L = {0};

	for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
		loom__cache_opts o = base_opts(&L, 0);
		loom__cache *c;
		loom__cache_stats st;
		o.n_stripes = cases[k].asked;
		o.budget_bytes = budget_for(o, cases[k].frames);
		c = open_ok(&o);
		if (!c)
			continue;
		loom__cache_get_stats(c, &st);
		CHECK_EQ_INT(st.n_frames, cases[k].frames);
		CHECK_EQ_INT(st.n_stripes, cases[k].stripes);
		check_quiet(c);
		loom__cache_close(c);
	}
}

/* Reference CLOCK: free frames first (in index order), then a hand that
   clears reference bits; a hit sets the bit, a load sets it. */
struct ref_clock {
	uint32_t n, used, hand;
	uint64_t id[64];
	uint8_t bit[64];
	uint64_t hits, misses, evictions;
};

static void ref_access(struct ref_clock *r, uint64_t id)
{
	for (uint32_t i = 0; i < r->used; i++)
		if (r->id[i] == id) {
			r->bit[i] = 1;
			r->hits++;
			return;
		}
	r->misses++;
	if (r->used < r->n) {
		r->id[r->used] = id;
		r->bit[r->used++] = 1;
		return;
	}
	for (;;) {
		uint32_t i = r->hand;
		r->hand = (r->hand + 1) % r->n;
		if (r->bit[i]) {
			r->bit[i] = 0;
			continue;
		}
		r->id[i] = id;
		r->bit[i] = 1;
		r->evictions++;
		return;
	}
}

static void single_thread_clock(void)
{
	uint64_t seed = check_seed();
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 0);
	loom__cache *c;
	loom__cache_thread *th;
	loom__cache_stats st;
	struct ref_clock r = {0};
	loom_diag d = {0};
	int bad = 0;

	o.budget_bytes = budget_for(o, 16);
	c = open_ok(&o);
	if (!c)
		return;
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.n_frames, 16);
	r.n = 16;
	loom__cache_thread_attach(c, &th, &d);

	/* hand-checked: 16 ids twice -> 16 misses then 16 hits; a cyclic scan
	   of 17 ids misses every time under CLOCK (as under LRU) */
	for (int pass = 0; pass < 2; pass++)
		for (uint64_t id = 100; id < 116; id++) {
			const void *p;
			CHECK_EQ_INT(loom__cache_get(th, id, &p, &d), LOOM_OK);
			bad += !brick_ok(p, id, BRICK);
			loom__cache_release(th, p);
			ref_access(&r, id);
		}
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.misses, 16);
	CHECK_EQ_INT(st.hits, 16);
	CHECK_EQ_INT(st.evictions, 0);
	for (int pass = 0; pass < 3; pass++)
		for (uint64_t id = 200; id < 217; id++) {
			const void *p;
			CHECK_EQ_INT(loom__cache_get(th, id, &p, &d), LOOM_OK);
			bad += !brick_ok(p, id, BRICK);
			loom__cache_release(th, p);
			ref_access(&r, id);
		}
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.misses, 16 + 51);
	CHECK_EQ_INT(st.evictions, 51);

	/* random stream with locality: the cache follows the reference model */
	for (int k = 0; k < 20000; k++) {
		uint64_t x = mix(seed + (uint64_t)k);
		uint64_t id = (x & 3) ? 1000 + (x >> 8) % 24 : 2000 + (x >> 8) % 200;
		const void *p;
		if (loom__cache_get(th, id, &p, &d) != LOOM_OK) {
			bad++;
			continue;
		}
		bad += !brick_ok(p, id, BRICK);
		loom__cache_release(th, p);
		ref_access(&r, id);
	}
	CHECK_EQ_INT(bad, 0);
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.hits, r.hits);
	CHECK_EQ_INT(st.misses, r.misses);
	CHECK_EQ_INT(st.evictions, r.evictions);
	CHECK_EQ_INT(st.loads, r.misses);
	CHECK(st.hits > 1000 && st.misses > 1000); /* both paths exercised */
	check_stats(c, &L);
	loom__cache_thread_detach(th);
	check_quiet(c);
	loom__cache_close(c);
}

static long resident_bytes(void)
{
	long pages = 0, rss = 0;
	FILE *fp = fopen("/proc/self/statm", "r");
	if (fp) {
		if (fscanf(fp, "%ld %ld", &pages, &rss) != 2)
			rss = 0;
		fclose(fp);
	}
	return rss * sysconf(_SC_PAGESIZE);
}

/* Bytes in use: the bookkeeping block at open, one page of slab per 4 KiB
   frame the first time it is used, one scratch charge; never above the
   budget.  mallinfo2 and /proc/self/statm check the count independently. */
static void accounting_round(int round)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 0);
	loom__cache *c;
	loom__cache_thread *th;
	loom__cache_stats st0, st;
	loom_diag d = {0};
	struct mallinfo2 m0, m1;
	size_t heap0, heap1;
	long rss0, rss1;

	o.budget_bytes = budget_for(o, 8) + 100;
	rss0 = resident_bytes();
	m0 = mallinfo2();
	c = open_ok(&o);
	if (!c)
		return;
	loom__cache_get_stats(c, &st0);
	CHECK_EQ_INT(st0.n_frames, 8);
	CHECK(st0.bytes_in_use > 0);
	CHECK_EQ_INT(st0.peak_bytes, st0.bytes_in_use);
	loom__cache_thread_attach(c, &th, &d);
	for (uint64_t id = 0; id < 3; id++) {
		const void *p;
		loom__cache_get(th, id, &p, &d);
		loom__cache_release(th, p);
	}
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.bytes_in_use, st0.bytes_in_use + 3 * FRAME_ALLOC + SCRATCH_BYTES);
	for (uint64_t id = 0; id < 100; id++) {
		const void *p;
		loom__cache_get(th, id * 7919, &p, &d);
		loom__cache_release(th, p);
	}
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.bytes_in_use, st0.bytes_in_use + 8 * FRAME_ALLOC + SCRATCH_BYTES);
	CHECK_EQ_INT(st.peak_bytes, st.bytes_in_use);
	CHECK(st.peak_bytes <= o.budget_bytes);
	CHECK(o.budget_bytes - st.peak_bytes < FRAME_ALLOC + 200); /* no waste */
	m1 = mallinfo2();
	rss1 = resident_bytes();
	heap0 = m0.uordblks + m0.hblkhd;
	heap1 = m1.uordblks + m1.hblkhd;
	/* Independent view: the heap grew by the bookkeeping block (and the
	   16-byte test scratch, counted as SCRATCH_BYTES); resident memory by
	   the 8 slab pages as well.  Sanitizers replace malloc (mallinfo2 then
	   reports nothing) and add shadow memory, so only plain builds check. */
	if (round == 1) { /* round 0 brought the code pages in */
		printf("  heap grew %zu bytes, resident %ld bytes; cache counts %llu "
		       "(block %llu) of budget %zu\n", heap1 - heap0, rss1 - rss0,
		       (unsigned long long)st.bytes_in_use,
		       (unsigned long long)st0.bytes_in_use, o.budget_bytes);
#if !defined(__SANITIZE_THREAD__) && !defined(__SANITIZE_ADDRESS__)
		CHECK(heap1 - heap0 <= st0.bytes_in_use + 64);
		CHECK(heap1 - heap0 + 64 >= st0.bytes_in_use);
		CHECK(rss1 - rss0 >= 8 * 4096);
		CHECK((uint64_t)(rss1 - rss0) <= st.bytes_in_use + 4096);
#endif
	}
	loom__cache_thread_detach(th);
	check_quiet(c);
	loom__cache_close(c);
}

static void budget_accounting(void)
{
	accounting_round(0);
	accounting_round(1);
}

/* 1, 2, 3 frames: pins up to the limit, random ids, every byte checked. */
static void tiny_budgets(void)
{
	uint64_t seed = check_seed();
	struct loader L = {0};

	for (uint32_t frames = 1; frames <= 3; frames++) {
		for (int tlc = -1; tlc <= 2; tlc += 3) {
			loom__cache_opts o = base_opts(&L, 0);
			loom__cache *c;
			loom__cache_thread *th;
			loom__cache_stats st;
			loom_diag d = {0};
			const void *held[3];
			uint64_t held_id[3];
			unsigned n_held = 0, limit;
			int bad = 0;

			atomic_store(&L.calls, 0);
			o.tlc_entries = tlc;
			o.budget_bytes = budget_for(o, frames);
			c = open_ok(&o);
			if (!c)
				continue;
			loom__cache_get_stats(c, &st);
			CHECK_EQ_INT(st.n_frames, frames);
			limit = loom__cache_pin_limit(c);
			CHECK_EQ_INT(limit, frames);
			loom__cache_thread_attach(c, &th, &d);
			for (int k = 0; k < 3000; k++) {
				uint64_t x = mix(seed ^ (uint64_t)k * 77);
				if (n_held == limit || (n_held && (x & 1))) {
					unsigned i = (unsigned)(x >> 8) % n_held;
					bad += !brick_ok(held[i], held_id[i], BRICK);
					bad += loom__cache_release(th, held[i]) != LOOM_OK;
					held[i] = held[--n_held];
					held_id[i] = held_id[n_held];
				} else {
					uint64_t id = (x >> 16) % 5;
					if (loom__cache_get(th, id, &held[n_held], &d) != LOOM_OK) {
						printf("  get: %s\n", d.message);
						bad++;
						continue;
					}
					bad += !brick_ok(held[n_held], id, BRICK);
					held_id[n_held++] = id;
				}
			}
			while (n_held)
				loom__cache_release(th, held[--n_held]);
			CHECK_EQ_INT(bad, 0);
			loom__cache_get_stats(c, &st);
			CHECK(st.evictions > 100);
			check_stats(c, &L);
			loom__cache_thread_detach(th);
			check_quiet(c);
			loom__cache_close(c);
		}
	}
}

/* Pinned bricks keep their frame and bytes while others churn. */
static void pinned_survive(void)
{
	struct loader L = {0};

	for (int tlc = -1; tlc <= 4; tlc += 5) {
		loom__cache_opts o = base_opts(&L, 0);
		loom__cache *c;
		loom__cache_thread *th;
		loom__cache_stats st;
		loom_diag d = {0};
		const void *pin[5];
		int bad = 0;

		atomic_store(&L.calls, 0);
		o.tlc_entries = tlc;
		o.budget_bytes = budget_for(o, 8);
		c = open_ok(&o);
		if (!c)
			continue;
		loom__cache_thread_attach(c, &th, &d);
		for (int i = 0; i < 5; i++)
			CHECK_EQ_INT(loom__cache_get(th, 50 + (uint64_t)i, &pin[i], &d), LOOM_OK);
		for (uint64_t k = 0; k < 500; k++) {
			const void *p;
			uint64_t id = 1000 + k % 37;
			if (loom__cache_get(th, id, &p, &d) != LOOM_OK) {
				bad++;
				continue;
			}
			bad += !brick_ok(p, id, BRICK);
			for (int i = 0; i < 5; i++)
				bad += p == pin[i];
			loom__cache_release(th, p);
		}
		for (int i = 0; i < 5; i++) {
			const void *p;
			CHECK(brick_ok(pin[i], 50 + (uint64_t)i, BRICK));
			/* still resident: a hit on the same frame */
			CHECK_EQ_INT(loom__cache_get(th, 50 + (uint64_t)i, &p, &d), LOOM_OK);
			CHECK(p == pin[i]);
			loom__cache_release(th, p);
		}
		CHECK_EQ_INT(bad, 0);
		loom__cache_get_stats(c, &st);
		CHECK(st.evictions >= 400);
		CHECK_EQ_INT(st.loads, 5 + 500); /* 37 ids through 3 frames: all miss */
		for (int i = 0; i < 5; i++)
			loom__cache_release(th, pin[i]);
		check_stats(c, &L);
		loom__cache_thread_detach(th);
		check_quiet(c);
		loom__cache_close(c);
	}
}

/* The per-thread cache: repeated gets of one brick load once and touch
   no shared state; IDLE entries keep their frames pinned until replaced,
   flushed, or dropped by their own thread when it needs a frame. */
static void thread_cache(void)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 0);
	loom__cache *c;
	loom__cache_thread *a;
	loom__cache_stats st;
	loom_diag d = {0};
	const void *p, *q;

	o.tlc_entries = 2;
	o.budget_bytes = budget_for(o, 2);
	c = open_ok(&o);
	if (!c)
		return;
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.n_frames, 2);
	CHECK_EQ_INT(st.tlc_entries, 2);
	loom__cache_thread_attach(c, &a, &d);
	for (int k = 0; k < 100; k++) {
		CHECK_EQ_INT(loom__cache_get(a, 9, &p, &d), LOOM_OK);
		CHECK(brick_ok(p, 9, BRICK));
		loom__cache_release(a, p);
	}
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.loads, 1);
	CHECK_EQ_INT(st.tlc_hits, 99);
	CHECK_EQ_INT(st.hits, 99);
	/* nested gets of a held brick: same pointer, one pin */
	CHECK_EQ_INT(loom__cache_get(a, 9, &p, &d), LOOM_OK);
	CHECK_EQ_INT(loom__cache_get(a, 9, &q, &d), LOOM_OK);
	CHECK(p == q);
	loom__cache_release(a, p);
	loom__cache_release(a, q);
	/* 9 and 10 IDLE in the tlc pin both frames; 11 needs a frame: the
	   thread drops its own IDLE pins (step 6c) rather than sleeping */
	CHECK_EQ_INT(loom__cache_get(a, 10, &p, &d), LOOM_OK);
	loom__cache_release(a, p);
	CHECK_EQ_INT(loom__cache_get(a, 11, &q, &d), LOOM_OK);
	CHECK(brick_ok(q, 11, BRICK));
	loom__cache_release(a, q);
	loom__cache_get_stats(c, &st);
	CHECK_EQ_INT(st.tlc_drops, 2);
	CHECK_EQ_INT(st.waits, 0);
	CHECK_EQ_INT(st.evictions, 1);
	/* flush drops IDLE pins: with no thread attached none remain (check) */
	loom__cache_thread_flush(a);
	CHECK_EQ_INT(loom__cache_get(a, 12, &p, &d), LOOM_OK);
	CHECK(brick_ok(p, 12, BRICK));
	loom__cache_release(a, p);
	loom__cache_thread_flush(NULL);
	check_stats(c, &L);
	CHECK_EQ_INT(loom__cache_thread_detach(a), LOOM_OK);
	check_quiet(c);
	loom__cache_close(c);
}

/* ----------------------------------------------------- threaded helpers */

struct barrier_run {
	loom__cache *c;
	pthread_barrier_t bar;
	uint64_t id;
	const void *ptr[8];
	int rc[8];
	char msg[8][LOOM_DIAG_MSG_MAX];
	atomic_uint next;
};

static void *get_once(void *arg)
{
	struct barrier_run *r = arg;
	unsigned me = atomic_fetch_add(&r->next, 1);
	loom__cache_thread *th;
	loom_diag d = {0};

	if (loom__cache_thread_attach(r->c, &th, &d) != LOOM_OK) {
		r->rc[me] = -1;
		return NULL;
	}
	pthread_barrier_wait(&r->bar);
	r->rc[me] = loom__cache_get(th, r->id, &r->ptr[me], &d);
	memcpy(r->msg[me], d.message, sizeof d.message);
	if (r->rc[me] == LOOM_OK) {
		if (!brick_ok(r->ptr[me], r->id, BRICK))
			r->rc[me] = -2;
		loom__cache_release(th, r->ptr[me]);
	}
	loom__cache_thread_detach(th);
	return NULL;
}

static void run_get_once(struct barrier_run *r, unsigned n)
{
	pthread_t t[8];
	atomic_store(&r->next, 0);
	pthread_barrier_init(&r->bar, NULL, n);
	for (unsigned i = 0; i < n; i++)
		pthread_create(&t[i], NULL, get_once, r);
	for (unsigned i = 0; i < n; i++)
		pthread_join(t[i], NULL);
	pthread_barrier_destroy(&r->bar);
}

/* Eight threads miss the same brick together: one load, one frame. */
static void concurrent_miss_loads_once(void)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 1u << 20);
	struct barrier_run r;
	loom__cache_stats st;

	memset(&r, 0, sizeof r);
	o.max_threads = 8;
	L.sleep_us = 200000;
	L.watch_id = 4242;
	r.c = open_ok(&o);
	if (!r.c)
		return;
	r.id = 4242;
	run_get_once(&r, 8);
	for (int i = 0; i < 8; i++) {
		CHECK_EQ_INT(r.rc[i], LOOM_OK);
		CHECK(r.ptr[i] == r.ptr[0]);
	}
	CHECK_EQ_INT(atomic_load(&L.calls_id), 1);
	loom__cache_get_stats(r.c, &st);
	CHECK_EQ_INT(st.loads, 1);
	CHECK_EQ_INT(st.lookups, 8);
	CHECK_EQ_INT(st.hits + st.misses, 8);
	CHECK(st.waits >= 1);
	CHECK(st.load_ns >= 200000000u);
	check_stats(r.c, &L);
	check_quiet(r.c);
	loom__cache_close(r.c);
	CHECK_EQ_INT(atomic_load(&L.scratch_made), atomic_load(&L.scratch_freed));
}

/* A failing load: every waiter gets the code and message, the frame is
   freed, the cache keeps working, a later get retries and succeeds. */
static void load_errors_propagate(void)
{
	struct loader L = {0};

	for (uint32_t frames = 1; frames <= 16; frames += 15) {
		loom__cache_opts o = base_opts(&L, 0);
		struct barrier_run r;
		loom__cache_stats st;
		loom__cache_thread *th;
		loom_diag d = {0};
		const void *p;
		unsigned calls0;

		memset(&r, 0, sizeof r);
		o.max_threads = 4;
		o.budget_bytes = budget_for(o, frames);
		L.sleep_us = 200000;
		L.fail_id = 13;
		L.watch_id = 13;
		atomic_store(&L.calls_id, 0);
		atomic_store(&L.fail, 1);
		calls0 = atomic_load(&L.calls);
		r.c = open_ok(&o);
		if (!r.c)
			continue;
		r.id = 13;
		run_get_once(&r, 4);
		for (int i = 0; i < 4; i++) {
			CHECK_EQ_INT(r.rc[i], LOOM_ECORRUPT);
			CHECK_STR_CONTAINS(r.msg[i], "test.db:brick 13: CRC mismatch");
		}
		CHECK_EQ_INT(atomic_load(&L.calls_id), 1);
		check_quiet(r.c);
		loom__cache_get_stats(r.c, &st);
		CHECK_EQ_INT(st.load_errors, 1);
		CHECK_EQ_INT(st.loads, 1);
		CHECK_EQ_INT(st.bytes_loaded, 0);

		/* the cache stays usable: other bricks, then the retry */
		L.sleep_us = 0;
		loom__cache_thread_attach(r.c, &th, &d);
		for (uint64_t id = 20; id < 30; id++) {
			CHECK_EQ_INT(loom__cache_get(th, id, &p, &d), LOOM_OK);
			CHECK(brick_ok(p, id, BRICK));
			loom__cache_release(th, p);
		}
		CHECK_EQ_INT(loom__cache_get(th, 13, &p, &d), LOOM_ECORRUPT); /* retried */
		CHECK(p == NULL);
		atomic_store(&L.fail, 0);
		CHECK_EQ_INT(loom__cache_get(th, 13, &p, &d), LOOM_OK);
		CHECK(p && brick_ok(p, 13, BRICK));
		loom__cache_release(th, p);
		CHECK_EQ_INT(atomic_load(&L.calls_id), 3);
		loom__cache_get_stats(r.c, &st);
		CHECK_EQ_INT(st.load_errors, 2);
		CHECK_EQ_INT(st.loads, atomic_load(&L.calls) - calls0);

		/* a scratch that cannot be made is an error too, then recovers */
		loom__cache_thread_detach(th);
		loom__cache_close(r.c);
		r.c = open_ok(&o);
		loom__cache_thread_attach(r.c, &th, &d);
		atomic_store(&L.scratch_fail, 1);
		CHECK_EQ_INT(loom__cache_get(th, 5, &p, &d), LOOM_ENOMEM);
		CHECK_STR_CONTAINS(d.message, "scratch");
		atomic_store(&L.scratch_fail, 0);
		CHECK_EQ_INT(loom__cache_get(th, 5, &p, &d), LOOM_OK);
		CHECK(p && brick_ok(p, 5, BRICK));
		loom__cache_release(th, p);
		loom__cache_thread_detach(th);
		check_quiet(r.c);
		loom__cache_close(r.c);
	}
	CHECK_EQ_INT(atomic_load(&L.scratch_made), atomic_load(&L.scratch_freed));
}

/* The loader runs outside the locks: while one thread sits in a slow load,
   another gets a resident brick of the same stripe. */
static void load_outside_lock(void)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 1u << 20);
	struct barrier_run r;
	loom__cache_thread *th;
	loom_diag d = {0};
	const void *p;
	pthread_t t;
	int during = 0;

	memset(&r, 0, sizeof r);
	o.max_threads = 2;
	o.n_stripes = 1;
	r.c = open_ok(&o);
	if (!r.c)
		return;
	loom__cache_thread_attach(r.c, &th, &d);
	CHECK_EQ_INT(loom__cache_get(th, 1, &p, &d), LOOM_OK);
	loom__cache_release(th, p);
	L.sleep_us = 300000;
	r.id = 2;
	atomic_store(&r.next, 0);
	pthread_barrier_init(&r.bar, NULL, 1);
	pthread_create(&t, NULL, get_once, &r);
	for (int k = 0; k < 200 && !atomic_load(&L.in_load); k++)
		sleep_us(1000);
	CHECK_EQ_INT(loom__cache_get(th, 1, &p, &d), LOOM_OK);
	during = atomic_load(&L.in_load) == 1;
	loom__cache_release(th, p);
	pthread_join(t, NULL);
	pthread_barrier_destroy(&r.bar);
	CHECK(during);
	CHECK_EQ_INT(r.rc[0], LOOM_OK);
	loom__cache_thread_detach(th);
	loom__cache_close(r.c);
}

/* ------------------------------------------------------------- hammering */

struct hammer {
	loom__cache *c;
	uint64_t seed;
	int ops;
	int coherent;
	uint64_t id_range;
	uint64_t fail_mod;           /* the loader fails these ids */
	atomic_uint expected_fails;
	atomic_uint next;
	atomic_uint bad;
	atomic_uint errors;
};

static void *hammer_thread(void *arg)
{
	struct hammer *H = arg;
	unsigned me = atomic_fetch_add(&H->next, 1);
	uint64_t s = mix(H->seed + me * 0x1234567u);
	loom__cache_thread *th;
	loom_diag d = {0};
	const void *held[4];
	uint64_t held_id[4];
	unsigned n_held = 0, hold_max, bad = 0, errors = 0;
	uint64_t walk = me * 1000u;

	if (loom__cache_thread_attach(H->c, &th, &d) != LOOM_OK) {
		atomic_fetch_add(&H->errors, 1);
		return NULL;
	}
	hold_max = loom__cache_pin_limit(H->c);
	if (hold_max > 4)
		hold_max = 4;
	for (int k = 0; k < H->ops; k++) {
		uint64_t x = mix(s + (uint64_t)k);
		if (n_held == hold_max || (n_held && (x & 3) == 0)) {
			unsigned i = (unsigned)(x >> 8) % n_held;
			bad += !brick_ok(held[i], held_id[i], BRICK);
			errors += loom__cache_release(th, held[i]) != LOOM_OK;
			held[i] = held[--n_held];
			held_id[i] = held_id[n_held];
			continue;
		}
		uint64_t id;
		if (H->coherent) { /* a walk: mostly the same few bricks */
			if ((x >> 12) % 16 == 0)
				walk += 1 + (x >> 20) % 3;
			id = (walk + (x >> 24) % 2) % H->id_range;
		} else {
			id = (x >> 16) % H->id_range;
		}
		int rc = loom__cache_get(th, id, &held[n_held], &d);
		if (H->fail_mod && id % H->fail_mod == 3) {
			if (rc == LOOM_ECORRUPT && strstr(d.message, "CRC mismatch") &&
			    held[n_held] == NULL) {
				atomic_fetch_add(&H->expected_fails, 1);
			} else {
				if (errors++ == 0)
					printf("  thread %u: brick %llu should fail, got %d\n", me,
					       (unsigned long long)id, rc);
				if (rc == LOOM_OK)
					loom__cache_release(th, held[n_held]);
			}
			continue;
		}
		if (rc != LOOM_OK) {
			if (errors++ == 0)
				printf("  thread %u: %s\n", me, d.message);
			continue;
		}
		/* check a few words on every get, the whole brick now and then */
		if ((x >> 40) % 8 == 0)
			bad += !brick_ok(held[n_held], id, BRICK);
		else {
			const uint64_t *w = held[n_held];
			size_t i = (x >> 44) % (BRICK / 8);
			bad += w[0] != brick_word(id, 0) || w[i] != brick_word(id, i) ||
			       w[BRICK / 8 - 1] != brick_word(id, BRICK / 8 - 1);
		}
		held_id[n_held++] = id;
	}
	while (n_held) {
		n_held--;
		bad += !brick_ok(held[n_held], held_id[n_held], BRICK);
		errors += loom__cache_release(th, held[n_held]) != LOOM_OK;
	}
	errors += loom__cache_thread_detach(th) != LOOM_OK;
	atomic_fetch_add(&H->bad, bad);
	atomic_fetch_add(&H->errors, errors);
	return NULL;
}

static void hammer_f(unsigned threads, uint32_t frames, unsigned stripes, int tlc,
                     int coherent, uint64_t id_range, int ops, uint64_t seed,
                     uint64_t fail_mod)
{
	struct loader L = {0};
	loom__cache_opts o = base_opts(&L, 0);
	struct hammer H;
	pthread_t t[8];
	loom__cache_stats st;

	memset(&H, 0, sizeof H);
	o.max_threads = threads;
	o.n_stripes = stripes;
	o.tlc_entries = tlc;
	L.jitter_us = 30;
	L.fail_mod = fail_mod;
	o.budget_bytes = budget_for(o, frames);
	H.c = open_ok(&o);
	if (!H.c)
		return;
	H.seed = seed;
	H.ops = ops;
	H.coherent = coherent;
	H.id_range = id_range;
	H.fail_mod = fail_mod;
	for (unsigned i = 0; i < threads; i++)
		pthread_create(&t[i], NULL, hammer_thread, &H);
	for (unsigned i = 0; i < threads; i++)
		pthread_join(t[i], NULL);
	loom__cache_get_stats(H.c, &st);
	printf("  %u threads, %u frames (%u stripes, tlc %u, pin limit %u), %s: "
	       "%llu lookups, hit rate %.3f (lock-free %llu), %llu loads, %llu waits, "
	       "%llu tlc drops\n",
	       threads, st.n_frames, st.n_stripes, st.tlc_entries, st.pin_limit,
	       coherent ? "coherent" : "random", (unsigned long long)st.lookups,
	       st.lookups ? (double)st.hits / (double)st.lookups : 0.0,
	       (unsigned long long)st.lf_hits,
	       (unsigned long long)st.loads, (unsigned long long)st.waits,
	       (unsigned long long)st.tlc_drops);
	CHECK_EQ_INT(atomic_load(&H.bad), 0);
	CHECK_EQ_INT(atomic_load(&H.errors), 0);
	if (fail_mod) {
		CHECK(atomic_load(&H.expected_fails) > 0);
		CHECK(st.load_errors > 0);
		CHECK(st.load_errors <= atomic_load(&H.expected_fails));
	}
	CHECK_EQ_INT(atomic_load(&L.scratch_misuse), 0);
	CHECK_EQ_INT(atomic_load(&L.bad_scratch), 0);
	CHECK(atomic_load(&L.scratch_made) <= threads);
	CHECK(st.lookups > 0);
	CHECK(st.lf_hits + st.tlc_hits <= st.hits);
	if (tlc < 0 && !fail_mod) /* every hit of a random stream past the tlc */
		CHECK(st.lf_hits > 0);
	check_stats(H.c, &L);
	check_quiet(H.c);
	loom__cache_close(H.c);
	CHECK_EQ_INT(atomic_load(&L.scratch_made), atomic_load(&L.scratch_freed));
}

static void hammer(unsigned threads, uint32_t frames, unsigned stripes, int tlc,
                   int coherent, uint64_t id_range, int ops, uint64_t seed)
{
	hammer_f(threads, frames, stripes, tlc, coherent, id_range, ops, seed, 0);
}

static int hammer_ops(void)
{
	const char *s = getenv("LOOM_CACHE_TEST_OPS");
	return s ? atoi(s) : 4000;
}

static void threads_random(void)
{
	uint64_t seed = check_seed();
	int ops = hammer_ops();
	hammer(2, 2, 1, -1, 0, 50, ops, seed);     /* 1 pin each, constant waiting */
	hammer(2, 3, 1, 2, 0, 20, ops, seed + 1);  /* tlc 1 + drops at 3 frames */
	hammer(8, 64, 1, 0, 0, 200, ops, seed + 2);
	hammer(8, 64, 4, 0, 0, 200, ops, seed + 3); /* 4 stripes */
}

/* Failing loads under contention: ids = 3 (mod 7) always fail; every get
   of one must say so, with the message, and the rest stay correct. */
static void threads_failing(void)
{
	uint64_t seed = check_seed();
	int ops = hammer_ops();
	hammer_f(4, 3, 1, -1, 0, 14, ops, seed, 7);
	hammer_f(4, 12, 2, 0, 1, 40, ops, seed + 1, 7);
}

/* Lock-free hits (step 3a) racing evictions: no per-thread cache, so
   every hit is a probe; few frames against more ids, so frames are
   recycled under the probes' feet; every byte a get returns is checked. */
static void threads_lockfree(void)
{
	uint64_t seed = check_seed();
	int ops = hammer_ops();
	hammer(4, 8, 1, -1, 0, 12, ops, seed);      /* churn: 12 ids, 8 frames */
	hammer(8, 16, 2, -1, 0, 18, ops, seed + 1); /* 2 stripes */
	hammer(8, 64, 1, -1, 1, 80, ops, seed + 2); /* coherent, mostly hits */
	hammer_f(4, 6, 1, -1, 0, 10, ops, seed + 3, 7); /* failing loads */
}

static void threads_coherent(void)
{
	uint64_t seed = check_seed();
	int ops = hammer_ops();
	hammer(2, 8, 1, 0, 1, 100, ops, seed);
	hammer(4, 5, 1, 4, 1, 64, ops, seed + 1);   /* K lowered to 1 */
	hammer(8, 96, 2, 0, 1, 1000, ops, seed + 2);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_cache");
	RUN(bad_arguments);
	RUN(budget_too_small);
	RUN(pin_limit_rule);
	RUN(stripe_choice);
	RUN(single_thread_clock);
	RUN(budget_accounting);
	RUN(tiny_budgets);
	RUN(pinned_survive);
	RUN(thread_cache);
	RUN(concurrent_miss_loads_once);
	RUN(load_errors_propagate);
	RUN(load_outside_lock);
	RUN(threads_random);
	RUN(threads_coherent);
	RUN(threads_failing);
	RUN(threads_lockfree);
	CHECK_MAIN_END();
}
