/*
 * engine/texture/texture.c - the virtual 3D texture of a fabric (loom/texture.h):
 * open, close, the memory budget and statistics.
 *
 * WHAT IT IS
 *   A voxel of the bolt is never stored: each lookup finds the crossing,
 *   its source block (base assignment + randomisation), the edge-fix offset
 *   of its voxel column, and reads the source voxel from an exemplar brick
 *   held in the brick cache (engine/texture/cache.h).  docs/engine.md tells the
 *   same story with figures.
 *
 *   The module's files by job are listed in texture_impl.h: the lookup
 *   steps are in lookup.c, region reads in region.c, per-thread slots in
 *   slots.c.
 *
 * THE MEMORY IT COUNTS (all against the budget)
 *   - the fabric's own memory (loom__fabric_bytes: the design and the base
 *     assignment, 5 bytes per crossing, the edge-fix and per-block
 *     tables): not owned, but resident for as long as the texture is, so
 *     it is taken from the budget first (a large design leaves less for
 *     the cache; one too large for the budget fails at open, naming the
 *     minimum);
 *   - the texture header (density, albedo and alignment tables) and one
 *     block allocated at open (calloc: pages become resident when first
 *     used): per-exemplar tables (first brick, brick counts, label ->
 *     kind), a bit per brick (stored empty), 4 bytes per brick (the
 *     frame it was last got from: lookup.c's prefetch hint), 2 bytes per
 *     4 x 4-column tile of each stored brick (where its density is
 *     non-zero: lookup.c's air test), and
 *     max_threads + 1 thread slots, each holding its cache thread
 *     handle, its current brick, its error message, the region gather
 *     buffer (6 planes of RCOLS x RZ bytes) and n_ent crossing entries
 *     (coefficients, label -> type table; n_ent = 4 .. 256, the most
 *     whose total stays within budget / 32, or budget / 8 up to 256:
 *     ent_fit),
 *     and the shared offset maps (below; 4 .. the most within another
 *     budget / 32);
 *   - the brick cache, opened with budget - (that block): frames,
 *     bookkeeping, and one database reader (decompressor + scratch) per
 *     thread slot.
 *   Nothing else is allocated after open.  bytes_in_use = fabric's +
 *   block + cache's (fixed_bytes = fabric's + block).
 *
 * SHARED OFFSET MAPS
 *   The edge-fix offset of a column (4 dot products) is kept in a map per
 *   crossing shared by every thread: 4 columns a 64-bit word, each lane
 *   q + DZ_BIAS or 0 (not computed yet), so one load answers "computed?"
 *   and "how much".  n_maps maps in sets of DZ_WAYS by a hash of (I, J),
 *   CLOCK inside a set.  A thread's crossing entry records its map and the
 *   map's generation; a lookup reads the lane, then the generation (an
 *   8-byte word per map, hot in L1), and trusts the lane only if it is
 *   unchanged (seqlock: a reclaim makes the generation odd before it
 *   rewrites key and lanes, and even again after).  A thread that computes
 *   an offset ORs it into the lane while it counts as the map's writer,
 *   and only if the generation is still its own; reclaiming closes the
 *   writer count first (compare-and-swap 0 -> closed, under map_lock), so
 *   a map never takes another crossing's offset.  When every map of a set
 *   has a writer in flight, the entry goes without (offsets computed on
 *   the spot).  An entry set up takes only a map never used; it takes one
 *   from another crossing (clearing its lanes) after DZ_RUN offsets
 *   evaluated in a row in it, so scattered lookups do not clear a map
 *   each.  lookup.c has the code.
 *
 * DETERMINISM
 *   Every value is a pure function of the fabric, the database and the
 *   position: the crossing entries and bricks are caches of such values.
 */
#include "texture_impl.h"

#include <inttypes.h>
#include <math.h>
#include <sched.h>
#include <time.h>
#include <stdio.h>
#include <stdlib.h>

/* ------------------------------------------------------------ open/close */

/* Whether the texture keeps an occupancy table for bricks of shape bs
   (heights in a byte, whole tiles). */
static int occ_shape_ok(const uint32_t bs[3])
{
	return bs[2] <= 255 && bs[0] % OCC_T == 0 && bs[1] % OCC_T == 0;
}

/* One occupancy table of stored brick id from its first np planes (z
   fastest, t->bv bytes apart, from d): for each tile, the union of its
   columns' voxels over those planes, then the first and last non-zero
   height.  np 1 fills t->occ (density), np LOOM__VOXEL_PLANES t->occa
   (any byte).  Every thread computes the same values from the same
   bytes, so concurrent stores agree. */
static void occ_fill(loom_texture *t, uint64_t id, const uint8_t *d, unsigned np)
{
	uint32_t bx = t->bs[0], bz = t->bs[2], nw = (bz + 7) / 8; /* <= 32 */
	_Atomic uint16_t *o = (np == 1 ? t->occ : t->occa) +
	                      (size_t)stored_rank(t, id) * t->occ_nt;

	/* filled before (the table outlives evictions; 0 is unknown, and a
	   tile of air is 255): below the working set a brick comes back
	   many times */
	if (atomic_load_explicit(&o[t->occ_nt - 1], memory_order_acquire) != 0)
		return; /* (the last tile is stored last, with release) */
	/* the union in 8-byte words (a tile's 16 columns OR-ed word by word:
	   an eighth of the operations of a byte loop, which cost more than
	   a zero-run decode of the plane) */
	for (uint32_t ty = 0; ty < t->bs[1] / OCC_T; ty++)
		for (uint32_t tx = 0; tx < t->occ_tx; tx++) {
			uint64_t u[32] = {0};
			uint8_t b[8];
			uint32_t lo = 255, hi1 = 0, w, k;
			for (unsigned pl = 0; pl < np; pl++)
				for (uint32_t j = 0; j < OCC_T; j++)
					for (uint32_t i = 0; i < OCC_T; i++) {
						const uint8_t *c = d + pl * t->bv +
						                   ((size_t)(ty * OCC_T + j) * bx +
						                    tx * OCC_T + i) * bz;
						uint64_t x;
						for (w = 0; w < bz / 8; w++) {
							memcpy(&x, c + 8 * w, 8);
							u[w] |= x;
						}
						if (bz % 8) { /* a last partial word */
							memset(b, 0, 8);
							memcpy(b, c + 8 * w, bz % 8);
							memcpy(&x, b, 8);
							u[w] |= x;
						}
					}
			for (w = 0; w < nw && !u[w]; w++)
				;
			if (w < nw) {
				memcpy(b, &u[w], 8);
				for (k = 0; !b[k]; k++)
					;
				lo = 8 * w + k;
				for (w = nw; !u[w - 1]; w--)
					;
				memcpy(b, &u[w - 1], 8);
				for (k = 8; !b[k - 1]; k--)
					;
				hi1 = 8 * (w - 1) + k;
			}
			atomic_store_explicit(&o[ty * t->occ_tx + tx], (uint16_t)(lo | hi1 << 8),
			                      memory_order_release);
		}
}

/* A density unit (DUNIT_TAG | g): one frame for the density planes of the
   stored bricks of ranks 4g .. 4g+3 (dunit_key), each segment of each
   plane inflated from its layout-3 unit (layout 2: the whole plane, one
   segment) only when a lookup first needs it (loom__dunit_fill): a random
   voxel needs one segment of one plane, and inflating more on a miss cost
   more than the hits it brought when the budget is below the working
   set.  The load itself only marks every segment absent. */
static int dunit_load(loom_texture *t, uint64_t g)
{
	atomic_store_explicit(&t->dstate[g], 0, memory_order_release);
	atomic_fetch_add_explicit(&t->dunit_loads, 1, memory_order_relaxed);
	return LOOM_OK;
}

int loom__dunit_fill(loom_texture *t, struct tslot *s, uint64_t id, unsigned q,
                     const uint8_t *frame, loom_diag *diag)
{
	uint32_t r = stored_rank(t, id);
	_Atomic uint64_t *st = &t->dstate[r >> 2];
	uint64_t plane = ((uint64_t)0xff >> (8 - t->dsegs)) << 8 * (r & 3); /* its segments */
	uint64_t have = (uint64_t)1 << (8 * (r & 3) + q), busy = have << 32;
	uint64_t v = atomic_load_explicit(st, memory_order_acquire), want, done;
	void *scratch;
	size_t n, lo, len;
	int rc;

	while (!(v & have)) {
		if (v & busy) { /* another thread inflates it: wait (it holds a pin) */
			sched_yield();
			v = atomic_load_explicit(st, memory_order_acquire);
			continue;
		}
		/* while the cache has evicted nothing, the budget holds all that
		   was read so far: the plane's other missing segments are filled
		   too, from the same read of the unit (once it evicts, a miss
		   inflates only the segment asked for) */
		want = have;
		if (!loom__cache_evicted(t->cache))
			want |= plane & ~v & ~(v >> 32);
		if (!atomic_compare_exchange_weak_explicit(st, &v, v | want << 32,
		                                           memory_order_acquire,
		                                           memory_order_acquire))
			continue;
		/* claimed: the segments' bytes are this thread's until published */
		struct timespec t0, t1;
		clock_gettime(CLOCK_MONOTONIC, &t0);
		done = 0;
		rc = loom__cache_thread_scratch(s->cth, &scratch, diag);
		for (unsigned k = 0; k < t->dsegs && rc == LOOM_OK; k++) {
			unsigned qk = (q + k) % t->dsegs; /* q first: its error is reported */
			uint64_t bit = (uint64_t)1 << (8 * (r & 3) + qk);
			if (!(want & bit))
				continue;
			/* the unit's CRC was checked by the fill of any segment of the
			   plane already in this frame */
			n = 0;
			rc = loom__db_reader_read_seg(scratch, (uint32_t)id, qk,
			                              (uint8_t *)frame + dunit_off(t, id),
			                              ((v | done) & plane) != 0, &n, diag);
			atomic_fetch_add_explicit(&t->bytes_read, n, memory_order_relaxed);
			if (rc != LOOM_OK)
				break;
			done |= bit;
			loom__db_seg_range(t->bs, t->dsegs, qk, &lo, &len);
			bump(&s->cnt.dfill_bytes, len);
		}
		if (done) /* one miss, however many segments it filled */
			bump(&s->cnt.dfills, 1);
		clock_gettime(CLOCK_MONOTONIC, &t1);
		bump(&s->cnt.dfill_ns, (uint64_t)((t1.tv_sec - t0.tv_sec) * 1000000000LL +
		                                  (t1.tv_nsec - t0.tv_nsec)));
		/* publish what was filled, release every claim */
		v = atomic_fetch_xor_explicit(st, want << 32 | done, memory_order_acq_rel);
		if (t->occ && done && ((v | done) & plane) == plane) /* the plane is whole */
			occ_fill(t, id, frame + dunit_off(t, id), 1);
		return done & have ? LOOM_OK : rc;
	}
	return LOOM_OK;
}

uint8_t loom__dunit_segs(const loom_texture *t, uint64_t id)
{
	uint32_t r = stored_rank(t, id);
	uint64_t v = atomic_load_explicit(&t->dstate[r >> 2], memory_order_acquire);

	return (uint8_t)(v >> 8 * (r & 3)) | t->dseg_pad;
}

void loom__texture_occ_loaded(loom_texture *t, uint64_t id, const uint8_t *brick)
{
	if (t->occ && !brick_empty(t, id)) {
		occ_fill(t, id, brick, 1); /* plane 0: density */
		occ_fill(t, id, brick, LOOM__VOXEL_PLANES); /* every plane: region reads */
	}
}

static int tex_load(void *ctx, uint64_t id, void *dst, void *scratch, loom_diag *diag)
{
	loom_texture *t = ctx;
	size_t n = 0;
	int rc;

	if (id & DUNIT_TAG)
		return dunit_load(t, id & ~DUNIT_TAG);
	rc = loom__db_reader_read(scratch, (uint32_t)id, dst, &n, diag);
	atomic_fetch_add_explicit(&t->bytes_read, n, memory_order_relaxed);
	if (rc == LOOM_OK)
		loom__texture_occ_loaded(t, id, dst);
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

/* " (N MiB)", need rounded up, from 1 MiB on; "" below */
static const char *min_text(char *buf, size_t n, size_t need)
{
	buf[0] = 0;
	if (need >= ((size_t)1 << 20))
		snprintf(buf, n, " (%zu MiB)", (need + ((size_t)1 << 20) - 1) >> 20);
	return buf;
}

static int budget_fail(loom_diag *diag, size_t budget, size_t fab, size_t fixed,
                       size_t cache, unsigned T, size_t brick, uint64_t xings)
{
	char m[48];
	return loom__fail(diag, LOOM_EBUDGET, "texture: budget of %zu bytes too small: "
	                  "this fabric needs at least %zu bytes%s with %u threads "
	                  "(%zu for the fabric held in memory: design and base "
	                  "assignment of %" PRIu64 " crossings, 5 bytes each, and "
	                  "edge-fix tables; %zu for per-thread state and tables; %zu "
	                  "for the smallest brick cache: at least %u frames of %zu "
	                  "bytes, a decompressor per thread, bookkeeping)", budget,
	                  fixed + cache, min_text(m, sizeof m, fixed + cache), T, fab,
	                  xings, fixed - fab, cache, T + 2, brick);
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
		memcpy(t->ex[k].size, e.size, sizeof e.size);
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

/* t->frange: the least and greatest value of each edge-fix basis field
   over each side of the block (row 0, row b2 - 1, column 0, column
   b1 - 1), for each crossing's offset bound (lookup.c xent_bound). */
static void field_ranges(loom_texture *t, const loom_edgefix_tables *tb)
{
	for (uint32_t k = 0; k < t->rh + t->rv; k++) {
		int vert = k >= t->rh;
		uint32_t kk = vert ? k - t->rh : k;
		for (int side = 0; side < 4; side++) {
			/* side 0, 1: a row (x varies); 2, 3: a column (y varies) */
			uint32_t n = side < 2 ? t->b1 : t->b2;
			float lo = INFINITY, hi = -INFINITY;
			for (uint32_t i = 0; i < n; i++) {
				uint32_t x = side < 2 ? i : side == 2 ? 0 : t->b1 - 1;
				uint32_t y = side >= 2 ? i : side == 0 ? 0 : t->b2 - 1;
				float v = loom_edgefix_field(tb, vert, x, y, kk);
				lo = v < lo ? v : lo;
				hi = v > hi ? v : hi;
			}
			t->frange[side][2 * k] = lo;
			t->frange[side][2 * k + 1] = hi;
		}
	}
}

/* Carve the slots out of t->mem and initialise them. */
static void lay_out_slots(loom_texture *t)
{
	size_t a_bytes = round_up(sizeof(float) * 2 * (t->rh + t->rv), ALIGN);

	for (unsigned i = 0; i < t->n_slots; i++) {
		struct tslot *s = slot_at(t, i);
		uint8_t *p = (uint8_t *)s + round_up(sizeof *s, ALIGN);
		s->memo_id = NO_BRICK;
		s->shared = i == t->n_slots - 1;
		s->next_free = i + 1 < t->n_slots - 1 ? i + 1 : t->n_slots;
		s->rbuf = p;
		p += 6 * RCOLS * RZ;
		s->ent = (struct xent *)p;
		p += round_up(sizeof(struct xent) * t->n_ent, ALIGN);
		s->etag = (int64_t *)p;
		p += round_up(2 * sizeof(int64_t) * t->n_ent, ALIGN);
		for (uint32_t k = 0; k < 2 * t->n_ent; k++)
			s->etag[k] = XENT_NONE;
		for (uint32_t k = 0; k < t->n_ent; k++) {
			s->ent[k].a = (float *)p;
			s->ent[k].map = NO_MAP;
			p += a_bytes;
		}
	}
	t->free_head = t->n_slots > 1 ? 0 : t->n_slots;
	atomic_init(&t->n_free, t->n_slots - 1);
}

/* Bytes of n shared offset maps of map_words lanes each (headers,
   generations, lanes). */
static size_t maps_bytes(uint32_t n, size_t map_words)
{
	return round_up(sizeof(struct dzmap) * n, ALIGN) + round_up(sizeof(uint64_t) * n, ALIGN) +
	       (size_t)n * map_words * sizeof(uint64_t);
}

/* Whether n crossing entries per slot (T + 1 slots) of ent_bytes each fit
   their share of the budget: 1/32 of it; up to 1/8 for the first 256 a
   slot, whose coefficients grow with the edge fix's rank (1.8 KB an entry
   at the full rank of the paper's block size against 0.6 KB at rank 15),
   so that a full-rank fix keeps a 16 x 16-crossing working set set up
   instead of rebuilding an entry at most lookups. */
static int ent_fit(unsigned T, uint32_t n, size_t ent_bytes, size_t budget)
{
	size_t bytes = (size_t)(T + 1) * n * ent_bytes;
	return bytes <= budget / 32 || (n <= 256 && bytes <= budget / 8);
}

/* The fixed part of the budget with n_ent crossing entries per slot and
   n_maps shared offset maps (the header and the block allocated at open);
   *slot_bytes: one slot. */
static size_t fixed_bytes(unsigned T, uint32_t n_ent, size_t ent_bytes, size_t ex_bytes,
                          uint32_t n_maps, size_t map_words, size_t *slot_bytes)
{
	*slot_bytes = round_up(sizeof(struct tslot), ALIGN) + 6 * RCOLS * RZ +
	              round_up(sizeof(struct xent) * n_ent, ALIGN) +
	              round_up(2 * sizeof(int64_t) * n_ent, ALIGN) +
	              n_ent * (ent_bytes - sizeof(struct xent));
	return round_up(sizeof(struct loom_texture), ALIGN) + ex_bytes +
	       maps_bytes(n_maps, map_words) + (size_t)(T + 1) * *slot_bytes;
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
	size_t cols, slot_bytes, ex_bytes, mem_bytes, fixed, ent_bytes, fab, map_words;
	uint64_t xings;
	uint32_t n_ent, n_maps, n_stored = 0;
	size_t occ_nt = 0;
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
		o.lod = opts->lod;
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

	if (occ_shape_ok(g.brick)) { /* the occupancy table: stored bricks only */
		loom_db_info info;
		loom_db_get_info(db, &info);
		n_stored = (uint32_t)(info.n_bricks - info.n_empty_bricks);
		occ_nt = (size_t)(g.brick[0] / OCC_T) * (g.brick[1] / OCC_T);
	}
	cols = (size_t)fabric->b1 * fabric->b2;
	/* crossing entries per slot: XENT_WAYS, doubled (up to XENT_MAX) while
	   all slots' entries stay within 1/32 of the budget */
	ent_bytes = sizeof(struct xent) +
	            round_up(sizeof(float) * 2 * (tb.rank_h + tb.rank_v), ALIGN);
	ex_bytes = round_up(sizeof(struct exm) * g.n_exemplars, ALIGN) +
	           round_up(((size_t)g.n_bricks + 63) / 64 * 8, ALIGN) +
	           round_up(((size_t)g.n_bricks + 63) / 64 * 4, ALIGN) + /* t->ne_rank */
	           round_up(((size_t)g.n_bricks + 3) / 4 * 8, ALIGN) + /* t->dstate */
	           round_up(sizeof(uint32_t) * g.n_bricks, ALIGN) + /* t->hint */
	           2 * round_up(sizeof(uint16_t) * occ_nt * n_stored, ALIGN); /* occ, occa */
	/* a shared offset map: 4 columns a 64-bit word, whole cache lines */
	map_words = round_up((cols + 3) / 4, ALIGN / sizeof(uint64_t));
	n_ent = XENT_WAYS;
	n_maps = DZ_WAYS;
	/* the design, base assignment and tables the fabric holds count too */
	fab = loom__fabric_bytes(fabric);
	xings = (uint64_t)fabric->design->rows * fabric->design->cols;
	fixed = fab + fixed_bytes(T, n_ent, ent_bytes, ex_bytes, n_maps, map_words, &slot_bytes);

	memset(&co, 0, sizeof co);
	co.brick_bytes = g.brick_bytes;
	co.load = tex_load;
	co.scratch_new = tex_scratch_new;
	co.scratch_free = tex_scratch_free;
	co.scratch_bytes = loom__db_reader_bytes(db);
	if (o.lod && loom__lod_levels_for(g.brick)) { /* lod.c */
		co.load = loom__lod_load;
		co.scratch_new = loom__lod_scratch_new;
		co.scratch_free = loom__lod_scratch_free;
		co.scratch_bytes = loom__lod_scratch_bytes(db);
	} else {
		o.lod = 0;
	}
	co.max_threads = T + 1;
	co.pins_per_thread = 2;
	if (o.budget_bytes <= fixed) {
		size_t need = cache_min_budget(&co);
		return budget_fail(diag, o.budget_bytes, fab, fixed, need, T, g.brick_bytes,
		                   xings);
	}
	/* more entries only while the smallest cache still fits beside them
	   (so the minimum budget reported above always opens) */
	if (ent_fit(T, 2 * n_ent, ent_bytes, o.budget_bytes) ||
	    maps_bytes(2 * n_maps, map_words) <= o.budget_bytes / 32) {
		size_t cmin = cache_min_budget(&co), sb, f2;
		while (n_ent < XENT_MAX && ent_fit(T, 2 * n_ent, ent_bytes, o.budget_bytes) &&
		       (f2 = fab + fixed_bytes(T, 2 * n_ent, ent_bytes, ex_bytes, n_maps,
		                               map_words, &sb)) + cmin <= o.budget_bytes) {
			n_ent *= 2;
			fixed = f2;
			slot_bytes = sb;
		}
		/* shared offset maps: doubled while within another 1/32 */
		while (n_maps < (1u << 24) &&
		       maps_bytes(2 * n_maps, map_words) <= o.budget_bytes / 32 &&
		       (f2 = fab + fixed_bytes(T, n_ent, ent_bytes, ex_bytes, 2 * n_maps,
		                               map_words, &sb)) + cmin <= o.budget_bytes) {
			n_maps *= 2;
			fixed = f2;
		}
	}
	mem_bytes = fixed - fab - round_up(sizeof *t, ALIGN);
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
	t->seg_brick = t->bs[2] % SEG_Z == 0;
	t->solid = g.top_threshold ? g.top_threshold : 1;
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
	t->rpre = tb.pre;
	t->roff = tb.off;
	field_ranges(t, &tb);
	for (uint32_t k = 0; k < fabric->design->n_types && k < LOOM_MAX_YARN_TYPES; k++) {
		memcpy(t->albedo[k], fabric->design->types[k].albedo, sizeof t->albedo[k]);
		t->align[k] = fabric->design->types[k].alignment;
	}
	t->n_ex = g.n_exemplars;
	t->ex = (struct exm *)t->mem;
	t->empty = (uint64_t *)(t->mem + round_up(sizeof(struct exm) * g.n_exemplars, ALIGN));
	t->ne_rank = (uint32_t *)((uint8_t *)t->empty +
	                          round_up(((size_t)g.n_bricks + 63) / 64 * 8, ALIGN));
	t->dstate = (_Atomic uint64_t *)((uint8_t *)t->ne_rank +
	                                 round_up(((size_t)g.n_bricks + 63) / 64 * 4, ALIGN));
	t->hint = (_Atomic uint32_t *)((uint8_t *)t->dstate +
	                               round_up(((size_t)g.n_bricks + 3) / 4 * 8, ALIGN));
	if (occ_nt) {
		t->occ = (_Atomic uint16_t *)((uint8_t *)t->hint +
		                              round_up(sizeof(uint32_t) * g.n_bricks, ALIGN));
		t->occa = (_Atomic uint16_t *)((uint8_t *)t->occ +
		                               round_up(sizeof(uint16_t) * occ_nt * n_stored, ALIGN));
		t->occ_tx = g.brick[0] / OCC_T;
		t->occ_nt = (uint32_t)occ_nt;
	}
	t->n_bricks = g.n_bricks;
	for (uint32_t id = 0; id < g.n_bricks; id++)
		if (loom__db_brick_empty(db, id))
			t->empty[id >> 6] |= (uint64_t)1 << (id & 63);
	if (g.n_bricks & 63) /* ids past the end count as empty (never stored) */
		t->empty[g.n_bricks >> 6] |= ~(uint64_t)0 << (g.n_bricks & 63);
	for (uint32_t w = 0; w < (g.n_bricks + 63) / 64; w++) {
		t->ne_rank[w] = t->n_stored;
		t->n_stored += (uint32_t)__builtin_popcountll(~t->empty[w]);
	}
	if (t->n_stored > n_stored) /* the index disagrees with its count: no table */
		t->occ = t->occa = NULL;
	t->n_maps = n_maps;
	t->map_words = map_words;
	t->maps = (struct dzmap *)(t->mem + ex_bytes);
	t->mapgen = (_Atomic uint64_t *)(t->mem + ex_bytes +
	                                 round_up(sizeof(struct dzmap) * n_maps, ALIGN));
	t->mapw = t->mapgen + round_up(sizeof(uint64_t) * n_maps, ALIGN) / sizeof(uint64_t);
	t->slots = t->mem + ex_bytes + maps_bytes(n_maps, map_words);
	t->n_slots = T + 1;
	t->slot_bytes = slot_bytes;
	t->n_ent = n_ent;
	{
		uint32_t lg = (uint32_t)__builtin_ctz(n_ent / XENT_WAYS);
		t->xent_jb = (lg + 1) / 2;
		t->xent_ib = lg - t->xent_jb;
		t->rb1 = UINT64_MAX / t->b1 + 1;
		t->rb2 = UINT64_MAX / t->b2 + 1;
	}
	t->fixed_bytes = fixed;
	t->budget = o.budget_bytes;
	pthread_mutex_init(&t->pool_lock, NULL);
	pthread_mutex_init(&t->overflow_lock, NULL);
	pthread_mutex_init(&t->msg_lock, NULL);
	pthread_mutex_init(&t->map_lock, NULL);
	lay_out_slots(t);
	if ((rc = load_exemplars(t, diag)) != LOOM_OK)
		goto fail;
	if (o.lod)
		loom__lod_setup(t);
	/* density units need a layout-2 or -3 database and the plain loader
	   (the LOD loader reads whole level-0 bricks); LOOM_DUNITS=0 turns
	   them off (benchmarks, tests of both paths) */
	t->dunits = !o.lod && loom__db_dsegs(db) > 0 &&
	            t->bv * LOOM__VOXEL_PLANES == g.brick_bytes &&
	            !(getenv("LOOM_DUNITS") && !strcmp(getenv("LOOM_DUNITS"), "0"));
	if (t->dunits) {
		unsigned ns = loom__db_dsegs(db);
		t->dsegs = ns;
		t->dseg_rows = loom__db_seg_rows(t->bs, ns);
		t->dseg_pad = (uint8_t)(0xffu << ns);
	}

	co.ctx = t;
	if ((rc = loom__cache_open(&co, &t->cache, diag)) != LOOM_OK) {
		if (rc == LOOM_EBUDGET) {
			size_t need = cache_min_budget(&co);
			rc = budget_fail(diag, o.budget_bytes, fab, fixed, need, T,
			                 g.brick_bytes, xings);
		}
		goto fail;
	}
	for (unsigned i = 0; i < t->n_slots; i++)
		if ((rc = loom__cache_thread_attach(t->cache, &slot_at(t, i)->cth, diag)) !=
		    LOOM_OK)
			goto fail;

	loom__registry_add(t);
	*out = t;
	return LOOM_OK;
fail:
	loom__cache_close(t->cache);
	pthread_mutex_destroy(&t->pool_lock);
	pthread_mutex_destroy(&t->overflow_lock);
	pthread_mutex_destroy(&t->msg_lock);
	pthread_mutex_destroy(&t->map_lock);
	free(t->mem);
	free(t);
	return rc;
}

LOOM_API void loom_texture_close(loom_texture *t)
{
	if (!t)
		return;
	loom__registry_remove(t);
	loom__cache_close(t->cache);
	pthread_mutex_destroy(&t->pool_lock);
	pthread_mutex_destroy(&t->overflow_lock);
	pthread_mutex_destroy(&t->msg_lock);
	pthread_mutex_destroy(&t->map_lock);
	free(t->mem);
	free(t);
}

/* ------------------------------------------------------------ statistics */

LOOM_API int loom_texture_get_stats(const loom_texture *t, loom_texture_stats *st)
{
	loom__cache_stats cs;
	uint64_t memo = 0, empty = 0, fills = 0, fill_ns = 0, fill_bytes = 0, uloads;

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
		fills += rd(&k->dfills);
		fill_ns += rd(&k->dfill_ns);
		fill_bytes += rd(&k->dfill_bytes);
	}
	/* a density unit's frame reads nothing when loaded; its planes'
	   segments are read by the fills: those are the misses that read */
	uloads = atomic_load_explicit(&((loom_texture *)t)->dunit_loads, memory_order_relaxed);
	st->brick_requests = memo + empty + cs.lookups;
	st->misses = cs.misses - (uloads < cs.misses ? uloads : cs.misses) + fills;
	st->hits = memo + cs.lookups > st->misses ? memo + cs.lookups - st->misses : 0;
	st->empty_bricks = empty;
	st->evictions = cs.evictions;
	st->bytes_read = atomic_load_explicit(&((loom_texture *)t)->bytes_read,
	                                      memory_order_relaxed);
	st->bytes_decompressed = cs.bytes_loaded - uloads * cs.brick_bytes + fill_bytes;
	st->decompress_ns = cs.load_ns + fill_ns;
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

