/*
 * engine/texture/lookup.c - point lookups of the virtual texture: crossings,
 * edge-fix offsets and bricks (the lookup steps), and the nearest,
 * trilinear and batch lookups built on them (loom/texture.h).
 *
 * LOOKUP STEPS (voxel_raw; the code cites them)
 *   Step 1.  z outside [0, b3): empty, done.
 *   Step 2.  Crossing: if (x, y) lies in the thread's current crossing
 *            entry, use it; else I = floor(y / b2), J = floor(x / b1) and
 *            find (I, J) in its set of XENT_WAYS among the thread's n_ent
 *            entries (the set: low bits of I and J, a tile of crossings;
 *            its keys in one cache line, the slot's etag), or
 *            set one up (evicting the set's least recently
 *            used): the crossing's sources
 *            and its neighbours' (loom__fabric_crossing: base assignment of
 *            (I mod M, J mod N) shifted by its group's symmetry), the
 *            yarn types of its warp and weft, the 4 (rh + rv) edge-fix
 *            coefficients of the block, and its shared offset map
 *            (texture.c: found by (I, J), or claimed in its set).
 *   Step 3.  Column offset dz(lx, ly): one load of its lane in the shared
 *            map (checked against the map's generation); on first use by
 *            any thread computed (4 dot products of length r with the
 *            fabric's basis fields, the same arithmetic as
 *            loom_edgefix_block) and stored there in 1/16 voxel
 *            (loom__dz_fixed): q = 16 w + f.
 *   Step 4.  Source voxel (x0 + lx, y0 + ly, z - w) of the block's
 *            exemplar (outside [0, b3): empty); when f > 0 also voxel
 *            z - w - 1, and steps 5-6 for both, blended (raw_blend:
 *            the nearer voxel's planes and density, or empty where the
 *            nearer voxel is empty; the density blended with the empty
 *            farther voxel only where no voxel above the nearer one in
 *            its segment is solid, read from the brick line's bytes
 *            above it, pair_top).
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
 *   Lookups in the same crossing skip step 2, in the same column the offset
 *   evaluation, in the same brick the cache.  A point lookup next to the
 *   last one (a walk) prefetches the next columns' lanes and lines
 *   (walk_next); a trilinear sample reuses the corner columns of the last
 *   one (pair_raw, the slot's column memo).
 *
 * PINS AND THE CACHE'S DEADLOCK RULE
 *   A thread holds at most one caller pin: its current brick, kept across
 *   calls (it is released before any other get).  So an idle thread keeps
 *   one caller pin plus its IDLE per-thread pins, and a sleeping get holds
 *   none: the cache is opened with pins_per_thread = 2, which reserves one
 *   frame per thread for that (cache.h, the deadlock rule).
 */
#include "texture_impl.h"
#include "loom/render.h"

#include <math.h>
#include <stdlib.h>

int loom__dz_fixed(float dz)
{
	if (!(dz == dz))
		return 0;
	if (dz >= (float)DZ_LIMIT)
		return DZ_LIMIT * DZ_SUB;
	if (dz <= -(float)DZ_LIMIT)
		return -DZ_LIMIT * DZ_SUB;
	return (int)lroundf(dz * (float)DZ_SUB);
}

int loom__dz_split(int q, int *f)
{
	return dz_split(q, f);
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


/* ------------------------------------------------------------ crossings */

/* Edge-fix coefficients of a block with sources nb (as the edge-fix
   module combines them: half the difference of the two sides' profile
   coefficients on each edge). */
static void xent_coef(const loom_texture *t, const loom_synth_nbhd *nb, float *a)
{
	loom__edgefix_combine(t->coef, t->rh, t->rv, nb, a);
}

/* The whole-voxel bound [e->wlo, e->whi] of the offsets dz_eval gives
   crossing e's columns (every column but the four corners when the
   corner term sets those): each of them reads its source voxels for
   output voxel z between z - e->whi and z - e->wlo.  The offset map is a
   sum of basis solutions of the screened Laplace equation
   (docs/synthesis.md), so its positive maximum and negative minimum lie
   on the block's border and its interior between 0 and the border's
   values (as the render majorant uses too); on each side of the border,
   interval arithmetic over the coefficients e->a and each basis field's
   range along the row or column it reads there (t->frange), widened by
   the float error of the dot products (from that side's magnitudes) and
   to hold 0, then rounded to 1/DZ_SUB and split as loom__dz_fixed and
   dz_split do.  Not finite or beyond DZ_LIMIT (a corrupt table): no
   bound. */
static void xent_bound(const loom_texture *t, struct xent *e)
{
	/* the four groups of coefficients (n, s, w, e) in e->a: their first
	   index, their rank and their first basis field in t->frange; and
	   which side's range each group reads on each side of the block (n
	   fields at (x, y), s at (x, b2 - 1 - y), w at (x, y), e at
	   (b1 - 1 - x, y); sides 0 N (row 0), 1 S (last row), 2 W (column
	   0), 3 E (last column)) */
	const uint32_t first[4] = {0, t->rh, 2 * t->rh, 2 * t->rh + t->rv};
	const uint32_t rank[4] = {t->rh, t->rh, t->rv, t->rv};
	const uint32_t field[4] = {0, 0, t->rh, t->rh};
	static const int reads[4][4] = {
		/* n  s  w  e */
		{0, 1, 0, 0}, /* on N */
		{1, 0, 1, 1}, /* on S */
		{2, 2, 2, 3}, /* on W */
		{3, 3, 3, 2}, /* on E */
	};
	double lo = INFINITY, hi = -INFINITY;

	for (int side = 0; side < 4; side++) {
		double l = 0, h = 0, mag = 0;
		for (int g = 0; g < 4; g++) {
			const float *fr = t->frange[reads[side][g]] + 2 * field[g];
			for (uint32_t k = 0; k < rank[g]; k++) {
				double a = e->a[first[g] + k], f0 = a * fr[2 * k], f1 = a * fr[2 * k + 1];
				l += f0 < f1 ? f0 : f1;
				h += f0 < f1 ? f1 : f0;
				mag += fabs(f0) > fabs(f1) ? fabs(f0) : fabs(f1);
			}
		}
		l -= 1e-3 + 1e-4 * mag;
		h += 1e-3 + 1e-4 * mag;
		lo = l < lo ? l : lo;
		hi = h > hi ? h : hi;
	}
	/* the screened fields take their extremes on the border only where
	   they are positive (negative): the interior lies between 0 and the
	   border's values (a block whose whole border is raised sinks back
	   towards 0 inside).  Each side's ranges pass through the corner
	   rows or columns, where the other sides' fields are 0, so l <= 0 <= h
	   already for sides 2 and 3; held here whatever the tables */
	lo = lo < 0 ? lo : 0;
	hi = hi > 0 ? hi : 0;
	if (!(lo >= -(double)DZ_LIMIT && hi <= (double)DZ_LIMIT)) { /* also NaN */
		e->wlo = 1;
		e->whi = 0;
		return;
	}
	/* lroundf is monotonic: q in [lround(DZ_SUB lo), lround(DZ_SUB hi)]
	   (DZ_SUB dz is exact in float); a column of offset q reads source
	   voxels z - ceil(q / DZ_SUB) to z - floor(q / DZ_SUB) */
	e->wlo = (int32_t)floor((double)lround(DZ_SUB * lo) / DZ_SUB);
	e->whi = (int32_t)ceil((double)lround(DZ_SUB * hi) / DZ_SUB);
}

/* Step 3: the offset of column (lx, ly) of crossing (I, J) whose
   coefficient vectors are a: the corner term at a block corner (the
   fabric's own function, so equal to loom_fabric_dz), else dz_eval. */
static float dz_value(const loom_texture *t, const float *a, int64_t I, int64_t J,
                      uint32_t lx, uint32_t ly)
{
	int k = loom__fabric_corner_of(t->fab, lx, ly);
	if (__builtin_expect(k >= 0, 0))
		return loom__fabric_corner_dz(t->fab, I, J, k);
	return dz_eval(t, a, lx, ly);
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
	return dz_value(t, a, I, J, lx, ly);
}

/* floor(v / b) for a block side b, rb = floor((2^64 - 1) / b) + 1
   (texture.c; 0 for b = 1): for 0 <= v < 2^32 the high half of rb * v,
   exact for every 32-bit v and b > 1 (Lemire, Kaser and Kurz 2019,
   "Faster remainder by direct computation"), instead of two 64-bit
   divisions on the way to every new crossing's entry. */
static inline int64_t xing_div(int64_t v, uint32_t b, uint64_t rb)
{
#ifdef __SIZEOF_INT128__
	__extension__ typedef unsigned __int128 u128;
	if ((uint64_t)v <= UINT32_MAX && rb)
		return (int64_t)(((u128)rb * (uint64_t)v) >> 64);
#else
	(void)rb;
#endif
	return loom_synth_floordiv(v, b);
}

/* The set of crossing (I, J): the low bits of J and I side by side (a
   tile of 2^jb x 2^ib crossings, n_ent / XENT_WAYS sets), so that any
   rectangle of up to XENT_WAYS tiles' worth of crossings (16 x 16 with
   256 entries) fills every set evenly; a hash left a sixth of the warm
   random lookups of such a region setting up a crossing again
   (conflicts in sets holding more than XENT_WAYS of its crossings). */
static inline uint32_t xent_set(const loom_texture *t, int64_t I, int64_t J)
{
	return ((uint32_t)(uint64_t)I & ((1u << t->xent_ib) - 1)) << t->xent_jb |
	       ((uint32_t)(uint64_t)J & ((1u << t->xent_jb) - 1));
}

/* The entry of set si holding (I, J), or NULL.  The keys only (one cache
   line for the set; the entries are 352 bytes apart), without branches:
   which way holds a random lookup's crossing is unpredictable. */
static inline struct xent *xent_find(struct tslot *s, uint32_t si, int64_t I, int64_t J)
{
	const int64_t *tag = s->etag + (size_t)si * 2 * XENT_WAYS;
	int hit = -1;

	for (int k = 0; k < XENT_WAYS; k++)
		hit = ((tag[2 * k] ^ I) | (tag[2 * k + 1] ^ J)) == 0 ? k : hit;
	return hit < 0 ? NULL : s->ent + (size_t)si * XENT_WAYS + hit;
}

struct xent *loom__xent_enter(loom_texture *t, struct tslot *s, int64_t x, int64_t y)
{
	int64_t I = xing_div(y, t->b2, t->rb2), J = xing_div(x, t->b1, t->rb1);
	uint32_t si = xent_set(t, I, J);
	struct xent *set = s->ent + (size_t)si * XENT_WAYS, *e;
	int64_t *tag = s->etag + (size_t)si * 2 * XENT_WAYS;
	loom__fabric_xing xg;
	int v = 0;

	if ((e = xent_find(s, si, I, J)) != NULL)
		goto found;
	/* the victim: a way not set up, else the least recently used */
	for (int k = 1; k < XENT_WAYS && tag[2 * v] != XENT_NONE; k++)
		if (tag[2 * k] == XENT_NONE || set[k].stamp < set[v].stamp)
			v = k;
	e = &set[v];
	tag[2 * v] = I;
	tag[2 * v + 1] = J;
	loom__fabric_crossing(t->fab, I, J, &xg);
	for (int k = 0; k < 4; k++) /* the column memo may hold e */
		s->cm[k].e = NULL;
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
	xent_bound(t, e);
	loom__dzmap_attach(t, e, 0); /* evicting waits for a run (loom__dz_slow) */
	bump(&s->cnt.xings, 1);
found:
	e->stamp = ++s->clock;
	s->cur = e;
	return e;
}

/* ---------------------------------------------------- shared offset maps */

/* The set of DZ_WAYS maps that may hold crossing (I, J). */
static uint32_t map_set(const loom_texture *t, int64_t I, int64_t J)
{
	uint64_t h = ((uint64_t)I * 0xd6e8feb86659fd93ull) ^ ((uint64_t)J * 0x9e3779b97f4a7c15ull);
	h ^= h >> 29;
	return (uint32_t)(h & (t->n_maps / DZ_WAYS - 1)) * DZ_WAYS;
}

static _Atomic uint64_t *map_lanes(const loom_texture *t, uint32_t m)
{
	return t->mapw + (size_t)m * t->map_words;
}

/* Map m holds (I, J): its generation (even, not 0) read on both sides of
   the key, unchanged (seqlock).  Returns the generation or 0. */
static uint64_t map_holds(const loom_texture *t, uint32_t m, int64_t I, int64_t J)
{
	uint64_t g1 = atomic_load_explicit(&t->mapgen[m], memory_order_acquire), g2;
	int64_t mi, mj;

	if (g1 == 0 || (g1 & 1))
		return 0;
	mi = atomic_load_explicit(&t->maps[m].I, memory_order_acquire);
	mj = atomic_load_explicit(&t->maps[m].J, memory_order_acquire);
	g2 = atomic_load_explicit(&t->mapgen[m], memory_order_relaxed);
	return g1 == g2 && mi == I && mj == J ? g1 : 0;
}

static int map_find(loom_texture *t, struct xent *e, uint32_t set)
{
	for (uint32_t k = 0; k < DZ_WAYS; k++) {
		uint64_t g = map_holds(t, set + k, e->I, e->J);
		if (g) {
			e->map = set + k;
			e->gen = g;
			e->w = map_lanes(t, set + k);
			if (!atomic_load_explicit(&t->maps[set + k].used, memory_order_relaxed))
				atomic_store_explicit(&t->maps[set + k].used, 1, memory_order_relaxed);
			return 1;
		}
	}
	return 0;
}

/* Reclaim map m for e's crossing (map_lock held, m closed): generation to
   odd, the key and every lane rewritten (release stores), generation to
   the next even value (release), then open to writers again.  A reader
   loads a lane or key with acquire and the generation after it: a value
   from the reclaim (or from a writer's OR after it, in the same release
   sequence) makes the odd generation visible, so the reader sees the
   generation changed. */
static void map_reclaim(loom_texture *t, uint32_t m, struct xent *e)
{
	_Atomic uint64_t *w = map_lanes(t, m);
	uint64_t g = atomic_load_explicit(&t->mapgen[m], memory_order_relaxed);

	atomic_store_explicit(&t->mapgen[m], g + 1, memory_order_relaxed);
	atomic_store_explicit(&t->maps[m].I, e->I, memory_order_release);
	atomic_store_explicit(&t->maps[m].J, e->J, memory_order_release);
	for (size_t i = 0; i < t->map_words; i++)
		atomic_store_explicit(&w[i], 0, memory_order_release);
	atomic_store_explicit(&t->mapgen[m], g + 2, memory_order_release);
	atomic_store_explicit(&t->maps[m].used, 1, memory_order_relaxed);
	atomic_store(&t->maps[m].refs, 0); /* open */
	e->map = m;
	e->gen = g + 2;
	e->w = w;
}

void loom__dzmap_attach(loom_texture *t, struct xent *e, int evict)
{
	uint32_t set = map_set(t, e->I, e->J);

	e->map = NO_MAP;
	if (map_find(t, e, set))
		return;
	pthread_mutex_lock(&t->map_lock);
	if (!map_find(t, e, set)) {
		/* CLOCK inside the set: never-used maps first, then one whose
		   bit is clear (clearing bits on the way); a map with a writer
		   in flight cannot be closed and is passed over */
		for (uint32_t k = 0; k < (evict ? 3 : 1) * DZ_WAYS; k++) {
			uint32_t m = set + k % DZ_WAYS, zero = 0;
			int fresh = atomic_load_explicit(&t->mapgen[m], memory_order_relaxed) == 0;
			if (!fresh && k < DZ_WAYS)
				continue;
			if (!fresh && atomic_load_explicit(&t->maps[m].used, memory_order_relaxed)) {
				atomic_store_explicit(&t->maps[m].used, 0, memory_order_relaxed);
				continue;
			}
			if (atomic_compare_exchange_strong(&t->maps[m].refs, &zero, MAP_CLOSED)) {
				map_reclaim(t, m, e);
				break;
			}
		}
	}
	pthread_mutex_unlock(&t->map_lock);
}

/* Store offset q of column c in e's map: only while a writer (refs > 0,
   not closed) and the generation is still e's, so a map reclaimed for
   another crossing never takes this crossing's offset.  Every thread
   computes the same q for a column, so OR-ing its lane in is idempotent. */
static void map_put(loom_texture *t, const struct xent *e, size_t c, int q)
{
	struct dzmap *m = &t->maps[e->map];
	uint32_t v = atomic_load_explicit(&m->refs, memory_order_relaxed);

	do {
		if (v & MAP_CLOSED)
			return;
	} while (!atomic_compare_exchange_weak(&m->refs, &v, v + 1));
	if (atomic_load(&t->mapgen[e->map]) == e->gen)
		atomic_fetch_or_explicit(&e->w[c >> 2],
		                         (uint64_t)(unsigned)(q + DZ_BIAS) << (16 * (c & 3)),
		                         memory_order_relaxed);
	atomic_fetch_sub(&m->refs, 1);
}

int loom__dz_slow(const loom_texture *tc, struct tslot *s, struct xent *e, uint32_t lx,
                  uint32_t ly)
{
	loom_texture *t = (loom_texture *)tc; /* the map lock */
	size_t c = (size_t)ly * t->b1 + lx;
	int q;

	/* Taking a map from another crossing clears its 16-bit lanes (16 KiB
	   for a paper-scale block) and pays only if this crossing's columns
	   are looked up again: so only after DZ_RUN offsets evaluated in a
	   row in this entry (a walk, a region, a footprint), never for
	   lookups scattered over more crossings than the maps hold (random
	   points below the working set: they only find maps or free ones). */
	s->dz_run = s->dz_prev == e ? s->dz_run + 1 : 1;
	s->dz_prev = e;
	if (e->map == NO_MAP && s->dz_run < DZ_RUN) {
		bump(&s->cnt.dz, 1);
		return loom__dz_fixed(dz_value(t, e->a, e->I, e->J, lx, ly));
	}
	if (e->map == NO_MAP ||
	    atomic_load_explicit(&t->mapgen[e->map], memory_order_relaxed) != e->gen) {
		loom__dzmap_attach(t, e, 1); /* reclaimed meanwhile: find or claim */
		if (e->map != NO_MAP) {   /* another thread may have computed it */
			uint64_t w = atomic_load_explicit(&e->w[c >> 2], memory_order_acquire);
			unsigned v = (unsigned)(w >> (16 * (c & 3))) & 0xffffu;
			if (v && atomic_load_explicit(&t->mapgen[e->map], memory_order_relaxed) ==
			                 e->gen)
				return (int)v - DZ_BIAS;
		}
	}
	q = loom__dz_fixed(dz_value(t, e->a, e->I, e->J, lx, ly));
	bump(&s->cnt.dz, 1);
	if (e->map != NO_MAP)
		map_put(t, e, c, q);
	return q;
}

/* ---------------------------------------------------------------- bricks */

int loom__memo_switch(loom_texture *t, struct tslot *s, uint64_t id)
{
	loom_diag d;
	const void *p;
	int rc;

	uint64_t bid = id & ~DUNIT_TAG; /* the brick; id may be its density unit */

	memo_drop(s);
	if (brick_empty(t, bid)) {
		s->memo_id = id;
		bump(&s->cnt.empty, 1);
		return LOOM_OK;
	}
	d.message[0] = 0;
	d.warn = NULL;
	d.user = NULL;
	d.n_warnings = 0;
	rc = loom__cache_get(s->cth, id == bid ? id : dunit_key(t, bid), &p, &d);
	if (rc != LOOM_OK)
		return loom__slot_error(t, s, rc, d.message);
	/* a density unit's segments are filled as lookups need them
	   (memo_seg_use) */
	s->memo_seg = id == bid ? 0xff : loom__dunit_segs(t, bid);
	s->memo_off = id == bid ? 0 : (uint32_t)dunit_off(t, bid);
	s->memo_id = id;
	s->memo = (const uint8_t *)p + s->memo_off;
	s->memo_pinned = 1;
	if (bid < t->n_bricks) { /* src_prefetch's hint (a store only when new) */
		uint32_t h = (loom__cache_frame_of(s->cth, p) + 1) | (id == bid ? 0 : HINT_DUNIT);
		if (atomic_load_explicit(&t->hint[bid], memory_order_relaxed) != h)
			atomic_store_explicit(&t->hint[bid], h, memory_order_relaxed);
	}
	return LOOM_OK;
}

/* memo_seg_use's slow path: fill the segment of source row sy of the
   density unit's plane in memo. */
int loom__memo_seg_fill(loom_texture *t, struct tslot *s, uint32_t sy)
{
	unsigned q = in_brick(t, 1, sy) / t->dseg_rows;
	loom_diag d;
	int rc;

	if (s->memo_seg >> q & 1)
		return LOOM_OK;
	d.message[0] = 0;
	d.warn = NULL;
	d.user = NULL;
	d.n_warnings = 0;
	rc = loom__dunit_fill(t, s, s->memo_id & ~DUNIT_TAG, q, s->memo - s->memo_off, &d);
	if (rc != LOOM_OK)
		return loom__slot_error(t, s, rc, d.message);
	s->memo_seg = loom__dunit_segs(t, s->memo_id & ~DUNIT_TAG); /* q, maybe more */
	return LOOM_OK;
}

static const rawvox raw_empty;

/* Planes a channel mask needs: density (also for orientation, which is
   zero where the density is), the two orientation bytes, the label. */
#define CH_D LOOM_CHANNEL_DENSITY
#define CH_O LOOM_CHANNEL_ORIENTATION
#define CH_M LOOM_CHANNEL_MATERIAL
#define CH_ALL LOOM_CHANNEL_ALL

/* Step 6 for the voxel at index i of brick p: only the planes of ch. */
static inline void planes_read(const loom_texture *t, const struct xent *e,
                               const uint8_t *p, size_t i, unsigned ch, rawvox *r)
{
	if (ch & (CH_D | CH_O))
		r->d = p[i];
	if ((ch & CH_O) && r->d)
		r->o = (uint16_t)(p[t->bv + i] | p[2 * t->bv + i] << 8);
	if (ch & CH_M) {
		r->l = p[3 * t->bv + i];
		r->k = e->ex->kind[r->l];
		r->ty = e->tok[r->k];
	}
}

/* Step 5's brick id and step 6's index in it of source voxel (sx, sy, sz)
   of crossing e. */
static inline uint64_t src_brick(const loom_texture *t, const struct xent *e, uint32_t sx,
                                 uint32_t sy, uint32_t sz)
{
	return e->ex->first_brick +
	       ((uint64_t)brick_of(t, 1, sy) * e->ex->nb[0] + brick_of(t, 0, sx)) * e->ex->nb[2] +
	       brick_of(t, 2, sz);
}

static inline size_t src_index(const loom_texture *t, uint32_t sx, uint32_t sy, uint32_t sz)
{
	return ((size_t)in_brick(t, 1, sy) * t->bs[0] + in_brick(t, 0, sx)) * t->bs[2] +
	       in_brick(t, 2, sz);
}

/* Before step 3: prefetch the density line of source voxel (sx, sy, z),
   the voxel steps 4-6 read when the column's offset keeps it in the same
   brick (a brick's column of bz voxels is one line at bz = 64), and the
   cache's bucket and frame descriptor of its brick, so that the offset
   lane's cache miss and the brick's overlap instead of following each
   other.  The frame comes from the texture's brick table (t->hint: the
   frame each brick was last got from, one relaxed load, no pin): only a
   hint, nothing is read through it; a stale or wrong guess costs a
   prefetch. */
static inline void src_prefetch(const loom_texture *t, const struct tslot *s,
                                const struct xent *e, uint32_t sx, uint32_t sy, uint32_t z,
                                unsigned ch)
{
	uint64_t id = src_brick(t, e, sx, sy, z);
	const uint8_t *p;
	int whole; /* p is a whole brick (not a density unit's plane) */

	if (id == (s->memo_id & ~DUNIT_TAG)) {
		p = s->memo;
		whole = !(s->memo_id & DUNIT_TAG);
	} else {
		uint32_t h;
		if (id >= t->n_bricks || brick_empty(t, id))
			return;
		h = atomic_load_explicit(&t->hint[id], memory_order_relaxed);
		if (!h)
			return;
		whole = !(h & HINT_DUNIT);
		if (h & HINT_DUNIT) { /* a density unit's frame: the brick's plane in it */
			p = loom__cache_hint(s->cth, dunit_key(t, id), (h & ~HINT_DUNIT) - 1);
			if (p)
				p += dunit_off(t, id);
		} else {
			p = loom__cache_hint(s->cth, id, h - 1);
		}
	}
	if (p) {
		size_t i = src_index(t, sx, sy, z);
		__builtin_prefetch(p + i);
		if ((ch & CH_O) && whole) {
			/* the orientation bytes too: read only once the density is
			   known not to be 0, they would otherwise miss after it */
			__builtin_prefetch(p + t->bv + i);
			__builtin_prefetch(p + 2 * t->bv + i);
		}
	}
}

/* Steps 4-6 for source voxel (sx, sy, zs) of crossing e. */
static inline int src_raw(loom_texture *t, struct tslot *s, const struct xent *e,
                          uint32_t sx, uint32_t sy, int64_t zs, unsigned ch, rawvox *r)
{
	uint64_t id;
	size_t i;
	uint32_t sz;
	int rc;

	*r = raw_empty;
	if ((uint64_t)zs >= t->b3) /* Step 4 */
		return LOOM_OK;
	sz = (uint32_t)zs;
	s->wsx = sx; /* walk_next's last source voxel */
	s->wsy = sy;
	s->wsz = sz;
	id = src_brick(t, e, sx, sy, sz);
	if (ch == CH_D && t->dunits && id < t->n_bricks) /* only the density plane: its unit */
		id |= DUNIT_TAG;
	if ((rc = memo_use(t, s, id)) != LOOM_OK || /* Step 5 */
	    (rc = memo_seg_use(t, s, sy)) != LOOM_OK)
		return rc;
	if (!s->memo)
		return LOOM_OK;
	i = src_index(t, sx, sy, sz); /* Step 6 */
	planes_read(t, e, s->memo, i, ch, r);
	return LOOM_OK;
}

/* Whether no voxel above the nearer one of the blended pair a = zu - 1,
   b = zu of source column (sx, sy) of crossing e in its segment is solid
   (dens_blend), when the pair is a surface (else 0, and nothing is
   read).  The bytes above zu in the segment come from the slot's brick
   when it is zu's and holds them all (the pair's readers read zu last:
   always so with the default brick height), else voxel by voxel through
   src_raw (ch: the caller's planes).  A voxel there that fails to read
   sets *rc (the caller's voxel is then empty, as any voxel whose source
   fails) and gives 0. */
static inline int pair_top(loom_texture *t, struct tslot *s, const struct xent *e,
                           uint32_t sx, uint32_t sy, const rawvox *a, const rawvox *b, int f,
                           int64_t zu, unsigned ch, int *rc)
{
	uint32_t end;

	if (!dens_surface(a->d, b->d, f))
		return 0;
	if ((uint64_t)zu >= t->b3)
		return 1; /* the nearer is the block's top voxel */
	end = seg_end((uint32_t)zu - (2 * f > DZ_SUB), t->b3);
	if ((uint32_t)zu + 1 >= end)
		return 1; /* no voxel above the nearer in the segment */
	if (s->memo && (s->memo_id & ~DUNIT_TAG) == src_brick(t, e, sx, sy, (uint32_t)zu) &&
	    brick_of(t, 2, end - 1) == brick_of(t, 2, (uint32_t)zu))
		return line_none_solid(t, s->memo + src_index(t, sx, sy, (uint32_t)zu),
		                       (uint32_t)zu, (uint32_t)zu + 1, end);
	for (uint32_t z = (uint32_t)zu + 1; z < end; z++) {
		rawvox r;
		int e2 = src_raw(t, s, e, sx, sy, z, ch, &r);
		if (e2 != LOOM_OK) {
			*rc = e2;
			return 0;
		}
		if (r.d >= t->solid)
			return 0;
	}
	return 1;
}

/* The same for the density bytes of a brick line holding every voxel of
   the segment (t->seg_brick): cu at source voxel zu, zu - 1 at cu[-1];
   the blended density. */
static inline uint8_t dens_pair(const loom_texture *t, const uint8_t *cu, uint32_t zu, int f)
{
	int top = 0;

	if (dens_surface(cu[-1], cu[0], f))
		top = line_none_solid(t, cu, zu, zu + 1, seg_end(zu - (2 * f > DZ_SUB), t->b3));
	return dens_blend(cu[-1], cu[0], f, top);
}

/* Step 2 for output column (x, y): the crossing entry (the slot's current
   one when it holds the column) and the column's source (sx, sy). */
static inline struct xent *xent_at(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                                   uint32_t *sx, uint32_t *sy)
{
	struct xent *e = s->cur;

	if (!e || (uint64_t)(x - e->x0) >= t->b1 || (uint64_t)(y - e->y0) >= t->b2)
		e = loom__xent_enter(t, s, x, y);
	*sx = e->sx0 + (uint32_t)(x - e->x0);
	*sy = e->sy0 + (uint32_t)(y - e->y0);
	return e;
}

/* Voxels za..zb of output column (x, y), whose crossing entry is e and
   source column (sx, sy), are empty whatever the column's offset: every
   brick of the source column that the crossing's offsets could read from
   (z - e->whi to z - e->wlo) is stored as nothing, or none is inside the
   exemplar, or (dens: the lookup reads no label, so a voxel of zero
   density is empty) the occupancy table says the source column's tile
   has no voxel of non-zero density at those heights of that brick.
   Answers most lookups in the air above and below the cloth and between
   its yarns without the offset lane's load (a cache miss for scattered
   lookups).  Corner columns the corner term sets (loom__fabric_corner_of),
   whose offsets the bound does not hold, are never answered so.  Forced
   inline: as a call from the trilinear footprints it cost 5-9 % of their
   rate (docs/performance.md, "Lookups in the air"). */
static inline __attribute__((always_inline)) int src_air(const loom_texture *t, const struct xent *e,
                          uint32_t sx, uint32_t sy, int64_t za, int64_t zb, int dens)
{
	uint32_t lx = sx - e->sx0, ly = sy - e->sy0;
	int64_t z0 = za - e->whi, z1 = zb - e->wlo;
	uint64_t base;

	if (e->wlo > e->whi || loom__fabric_corner_of(t->fab, lx, ly) >= 0)
		return 0;
	z0 = z0 < 0 ? 0 : z0;
	z1 = z1 >= (int64_t)t->b3 ? (int64_t)t->b3 - 1 : z1;
	if (z0 > z1)
		return 1;
	base = src_brick(t, e, sx, sy, 0);
	for (uint32_t b = brick_of(t, 2, (uint32_t)z0); b <= brick_of(t, 2, (uint32_t)z1); b++) {
		uint64_t id = base + b;
		uint32_t v, lo, hi1;
		int64_t zb0 = (int64_t)b * t->bs[2], l, h;
		if (brick_empty(t, id))
			continue;
		if (!dens || !t->occ)
			return 0;
		v = atomic_load_explicit(&t->occ[(size_t)stored_rank(t, id) * t->occ_nt +
		                                 in_brick(t, 1, sy) / OCC_T * t->occ_tx +
		                                 in_brick(t, 0, sx) / OCC_T],
		                         memory_order_relaxed);
		if (!v)
			return 0; /* not known yet */
		lo = v & 0xffu;
		hi1 = v >> 8;
		l = z0 > zb0 ? z0 - zb0 : 0; /* the heights read in this brick */
		h = z1 - zb0 < (int64_t)t->bs[2] - 1 ? z1 - zb0 : (int64_t)t->bs[2] - 1;
		if (hi1 && l < (int64_t)hi1 && h >= (int64_t)lo)
			return 0;
	}
	return 1;
}

/* A lookup answered by src_air: counted as a request for an empty brick,
   and (sx, sy, za) made the walk's last source voxel. */
static inline void air_note(const loom_texture *t, struct tslot *s, uint32_t sx,
                            uint32_t sy, int64_t za)
{
	s->wsx = sx;
	s->wsy = sy;
	s->wsz = (uint32_t)(za < 0 ? 0 : za < (int64_t)t->b3 ? za : (int64_t)t->b3 - 1);
	bump(&s->cnt.empty, 1);
}

/* A walk's or ray's new position (x, y) after the last one (*px, *py):
   both recorded, and the signs of its moves along x and y kept in *dx,
   *dy (a zero move keeps the last sign).  0 for a jump (more than one
   voxel along x or y): not a walk. */
static inline int walk_step(int64_t *px, int64_t *py, int8_t *dx, int8_t *dy, int64_t x,
                            int64_t y)
{
	int64_t ddx = x - *px, ddy = y - *py;

	*px = x;
	*py = y;
	if ((uint64_t)(ddx + 1) > 2 || (uint64_t)(ddy + 1) > 2)
		return 0;
	if (ddx)
		*dx = (int8_t)ddx;
	if (ddy)
		*dy = (int8_t)ddy;
	return 1;
}

/* A walk's next columns (ray marches: unit steps, a point lookup each).
   When column (x, y) is the last point lookup's or next to it, the
   columns one step further along the walk's last x and y directions,
   (x + dx, y), (x, y + dy) and (x + dx, y + dy), are where the next call
   most likely lands: their offset lanes, and their source lines at the
   height just read when they are in the same brick (neighbouring columns'
   offsets differ by a voxel or so: the same 64-voxel brick column), are
   prefetched now, so that the next call finds them on their way instead
   of waiting for the lane and then the line.  (x, y)'s source column and
   height are the last source voxel read (s->wsx, wsy, wsz: in the slot's
   current brick, of the slot's current crossing).  A jump (random
   lookups) only records the column.  Columns of another crossing or brick
   are left alone (nothing is set up or looked up for a guess), and
   nothing is read through these addresses.  Two steps ahead (8 columns)
   and the 2 x 2 trilinear footprint were slower (docs/performance.md). */
static inline void walk_next(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                             unsigned ch)
{
	const struct xent *e = s->cur;
	uint64_t lx, ly;
	uint32_t bx, by;
	size_t c, i;

	if (!walk_step(&s->wx, &s->wy, &s->wdx, &s->wdy, x, y) || !e)
		return; /* a jump: not a walk */
	lx = (uint64_t)s->wsx - e->sx0;
	ly = (uint64_t)s->wsy - e->sy0;
	bx = in_brick(t, 0, s->wsx);
	by = in_brick(t, 1, s->wsy);
	c = (size_t)(ly * t->b1 + lx);
	i = src_index(t, s->wsx, s->wsy, s->wsz);
	for (int k = 1; k < 4; k++) {
		int ox = k & 1 ? s->wdx : 0, oy = k & 2 ? s->wdy : 0;
		if ((k & 1 && !ox) || (k & 2 && !oy))
			continue;
		if (lx + (uint64_t)(int64_t)ox < t->b1 && ly + (uint64_t)(int64_t)oy < t->b2 &&
		    e->map != NO_MAP)
			__builtin_prefetch(&e->w[(c + (size_t)((int64_t)oy * t->b1 + ox)) >> 2]);
		if (s->memo && bx + (uint32_t)ox < t->bs[0] && by + (uint32_t)oy < t->bs[1]) {
			const uint8_t *p = s->memo + i + (ptrdiff_t)(oy * (int)t->bs[0] + ox) *
			                                      (ptrdiff_t)t->bs[2];
			__builtin_prefetch(p);
			if ((ch & CH_O) && !(s->memo_id & DUNIT_TAG)) { /* orientation */
				__builtin_prefetch(p + t->bv);
				__builtin_prefetch(p + 2 * t->bv);
			}
		}
	}
}

/* Steps 1-6 for voxel (x, y, z) (coordinates already range-checked),
   reading only the planes of channel mask ch: with a fractional offset,
   the two source voxels blended (raw_blend). */
static inline int voxel_raw_w(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                              int64_t z, unsigned ch, rawvox *r, int walk)
{
	struct xent *e;
	uint32_t sx, sy;
	int64_t w;
	int f, rc, rc2;
	rawvox a, b;

	*r = raw_empty;
	if ((uint64_t)z >= t->b3) /* Step 1 */
		return LOOM_OK;
	e = xent_at(t, s, x, y, &sx, &sy);
	if (src_air(t, e, sx, sy, z, z, !(ch & CH_M))) { /* empty whatever the offset */
		air_note(t, s, sx, sy, z);
		if (walk)
			walk_next(t, s, x, y, ch);
		return LOOM_OK;
	}
	src_prefetch(t, s, e, sx, sy, (uint32_t)z, ch);
	w = dz_split(xent_dz(t, s, e, sx - e->sx0, sy - e->sy0), &f); /* Step 3 */
	if (!f) {
		rc = src_raw(t, s, e, sx, sy, z - w, ch, r);
	} else if (!(ch & (CH_D | CH_O))) { /* the material is the nearer voxel's */
		rc = src_raw(t, s, e, sx, sy, z - w - (2 * f > DZ_SUB), ch, r);
	} else {
		rc = src_raw(t, s, e, sx, sy, z - w - 1, ch, &a);
		rc2 = src_raw(t, s, e, sx, sy, z - w, ch, &b);
		if (rc == LOOM_OK && rc2 == LOOM_OK) { /* a failed voxel stays empty */
			int top = pair_top(t, s, e, sx, sy, &a, &b, f, z - w, ch, &rc);
			if (rc == LOOM_OK)
				raw_blend(&a, &b, f, top, r);
		} else if (rc == LOOM_OK) {
			rc = rc2;
		}
	}
	if (walk)
		walk_next(t, s, x, y, ch);
	return rc;
}

static inline int voxel_raw(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                            int64_t z, unsigned ch, rawvox *r)
{
	return voxel_raw_w(t, s, x, y, z, ch, r, 1);
}

/* Steps 1-6 for voxels (x, y, z) and (x, y, z + 1), a trilinear corner
   pair: the same as two voxel_raw calls, with one crossing and offset
   look-up, and with a fractional offset three source voxels read instead
   of four (z - w is the upper voxel of z's pair and the lower of z + 1's).
   A failed source voxel leaves each voxel blended from it empty; returns
   the first error, as the two calls would. */
static inline int pair_raw(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                           int64_t z, unsigned ch, rawvox r[2])
{
	struct xent *e;
	uint32_t sx, sy;
	int in0 = (uint64_t)z < t->b3, in1 = (uint64_t)(z + 1) < t->b3;
	struct colmemo *m;
	int64_t w;
	int f, q, rc[3] = {LOOM_OK, LOOM_OK, LOOM_OK};
	rawvox v[3];

	r[0] = r[1] = raw_empty;
	if (!in0 && !in1) /* Step 1 */
		return LOOM_OK;
	m = &s->cm[(x & 1) | (y & 1) << 1];
	if (m->e && m->x == x && m->y == y) { /* steps 2-3 done */
		e = m->e;
		sx = m->sx;
		sy = m->sy;
		q = m->q;
	} else {
		e = xent_at(t, s, x, y, &sx, &sy);
		if (src_air(t, e, sx, sy, z, z + 1, !(ch & CH_M))) { /* both empty whatever the offset */
			air_note(t, s, sx, sy, z);
			return LOOM_OK;
		}
		src_prefetch(t, s, e, sx, sy, (uint32_t)(in0 ? z : z + 1), ch);
		q = xent_dz(t, s, e, sx - e->sx0, sy - e->sy0); /* Step 3 */
		m->x = x;
		m->y = y;
		m->e = e;
		m->sx = sx;
		m->sy = sy;
		m->q = q;
	}
	w = dz_split(q, &f);
	if (!f || !(ch & (CH_D | CH_O))) {
		/* one source voxel each: the nearer one (the material's) */
		int64_t d = f && 2 * f > DZ_SUB;
		if (in0)
			rc[0] = src_raw(t, s, e, sx, sy, z - w - d, ch, &r[0]);
		if (in1)
			rc[1] = src_raw(t, s, e, sx, sy, z + 1 - w - d, ch, &r[1]);
		return rc[0] != LOOM_OK ? rc[0] : rc[1];
	}
	/* v[k] = source voxel z - w - 1 + k */
	v[0] = v[1] = v[2] = raw_empty;
	if (in0 && in1 && (uint64_t)(z - w - 1) < t->b3 - 2 &&
	    brick_of(t, 2, (uint32_t)(z - w - 1)) == brick_of(t, 2, (uint32_t)(z - w + 1))) {
		/* all three in one brick column: one switch, three bytes */
		rc[0] = src_raw(t, s, e, sx, sy, z - w - 1, ch, &v[0]);
		rc[1] = rc[2] = rc[0];
		if (s->memo && rc[0] == LOOM_OK) {
			size_t i = src_index(t, sx, sy, (uint32_t)(z - w - 1));
			planes_read(t, e, s->memo, i + 1, ch, &v[1]);
			planes_read(t, e, s->memo, i + 2, ch, &v[2]);
			bump(&s->cnt.memo_hits, 2);
		}
	} else {
		if (in0)
			rc[0] = src_raw(t, s, e, sx, sy, z - w - 1, ch, &v[0]);
		rc[1] = src_raw(t, s, e, sx, sy, z - w, ch, &v[1]);
		if (in1)
			rc[2] = src_raw(t, s, e, sx, sy, z - w + 1, ch, &v[2]);
	}
	{
		/* the segments above: a failure there empties that voxel only */
		int rt[2] = {LOOM_OK, LOOM_OK}, top;
		if (in0 && rc[0] == LOOM_OK && rc[1] == LOOM_OK) {
			top = pair_top(t, s, e, sx, sy, &v[0], &v[1], f, z - w, ch, &rt[0]);
			if (rt[0] == LOOM_OK)
				raw_blend(&v[0], &v[1], f, top, &r[0]);
		}
		if (in1 && rc[1] == LOOM_OK && rc[2] == LOOM_OK) {
			top = pair_top(t, s, e, sx, sy, &v[1], &v[2], f, z - w + 1, ch, &rt[1]);
			if (rt[1] == LOOM_OK)
				raw_blend(&v[1], &v[2], f, top, &r[1]);
		}
		if (in0 && (rc[0] != LOOM_OK || rc[1] != LOOM_OK))
			return rc[0] != LOOM_OK ? rc[0] : rc[1];
		if (in0 && rt[0] != LOOM_OK)
			return rt[0];
		if (in1 && (rc[1] != LOOM_OK || rc[2] != LOOM_OK))
			return rc[1] != LOOM_OK ? rc[1] : rc[2];
		return rt[1];
	}
}

/* The texel of raw voxel r, the fields of the channels outside ch zero
   (their planes were not read: r holds zeros there). */
static void texel_of(const loom_texture *t, const rawvox *r, unsigned ch, loom_texel *out)
{
	memset(out, 0, sizeof *out);
	if (r->d) {
		if (ch & CH_D)
			out->density = t->dens[r->d];
		if (ch & CH_O)
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

/* --------------------------------------------------------------- lookups */

static int voxel_ch(loom_texture *t, int64_t x, int64_t y, int64_t z, unsigned ch,
                    loom_texel *out)
{
	struct tslot *s;
	rawvox r;
	int rc;

	if (!t || !out || (ch & ~(unsigned)CH_ALL)) {
		if (out)
			memset(out, 0, sizeof *out);
		return LOOM_EINVAL;
	}
	if (!coord_ok(x) || !coord_ok(y) || !coord_ok(z)) {
		memset(out, 0, sizeof *out);
		return LOOM_ERANGE;
	}
	s = slot_enter(t);
	rc = voxel_raw(t, s, x, y, z, ch, &r);
	bump(&s->cnt.lookups, 1);
	slot_leave(t, s);
	texel_of(t, &r, ch, out);
	return rc;
}

LOOM_API int loom_texture_voxel(loom_texture *t, int64_t x, int64_t y, int64_t z,
                                loom_texel *out)
{
	return voxel_ch(t, x, y, z, CH_ALL, out);
}

LOOM_API int loom_texture_voxel_ch(loom_texture *t, int64_t x, int64_t y, int64_t z,
                                   unsigned channels, loom_texel *out)
{
	return voxel_ch(t, x, y, z, channels, out);
}

/* A trilinear corner column (x, y) from z: its crossing entered, its
   offset lane and its voxel line prefetched, so that the 4 columns'
   misses overlap before pair_raw resolves them one after the other. */
static inline void column_prefetch(loom_texture *t, struct tslot *s, int64_t x, int64_t y,
                                   int64_t z, unsigned ch)
{
	struct xent *e;
	uint32_t sx, sy;

	const struct colmemo *m = &s->cm[(x & 1) | (y & 1) << 1];

	if ((uint64_t)z >= t->b3 && (uint64_t)++z >= t->b3)
		return;
	if (m->e && m->x == x && m->y == y)
		return; /* its lane was just read */
	e = xent_at(t, s, x, y, &sx, &sy);
	if (src_air(t, e, sx, sy, z, z + 1, !(ch & CH_M)))
		return; /* pair_raw will answer it so too */
	src_prefetch(t, s, e, sx, sy, (uint32_t)z, ch);
	if (e->map != NO_MAP)
		__builtin_prefetch(&e->w[((size_t)(sy - e->sy0) * t->b1 + (sx - e->sx0)) >> 2]);
}

/* The columns a ray's next footprint most likely adds, after footprint
   i0 (in crossing e, its corner's source column sx, sy; the slot's
   current brick holds source voxel (sx, sy + 1, sz), the last column
   read): the column pair beyond it along the last move in
   x, the row pair along the last move in y, and the corner between them.
   Their offset lanes, and their voxel lines at sz when they are in the
   same crossing and brick column (neighbouring columns' offsets differ by
   about a voxel: the same 64-voxel line), are prefetched, so that the
   next footprint's misses overlap with this one's work.  Hints only:
   nothing is read through these addresses. */
static inline void tri_next(const loom_texture *t, struct tslot *s, const struct xent *e,
                            const int64_t i0[3], uint32_t sx, uint32_t sy, uint32_t sz)
{
	int cx, cy;

	if (!walk_step(&s->tx, &s->ty, &s->tdx, &s->tdy, i0[0], i0[1]))
		return; /* a jump: not a ray */
	/* the new columns' offsets from the footprint's corner: -1 or 2 */
	cx = s->tdx > 0 ? 2 : -1;
	cy = s->tdy > 0 ? 2 : -1;
	for (int k = 0; k < 5; k++) {
		/* (cx, 0) (cx, 1) (0, cy) (1, cy) (cx, cy) */
		int ox = k < 2 ? cx : k < 4 ? k - 2 : cx, oy = k < 2 ? k : cy;
		uint64_t lx = (uint64_t)(i0[0] + ox - e->x0), ly = (uint64_t)(i0[1] + oy - e->y0);
		uint32_t nx = sx + (uint32_t)ox, ny = sy + (uint32_t)oy;
		if ((!s->tdx && (k < 2 || k == 4)) || (!s->tdy && k >= 2) || lx >= t->b1 ||
		    ly >= t->b2)
			continue;
		if (e->map != NO_MAP)
			__builtin_prefetch(&e->w[((size_t)ly * t->b1 + lx) >> 2]);
		if (s->memo && brick_of(t, 0, nx) == brick_of(t, 0, sx) &&
		    brick_of(t, 1, ny) == brick_of(t, 1, sy + 1))
			__builtin_prefetch(s->memo + src_index(t, nx, ny, sz));
	}
}

/* The density bytes of a density-only trilinear footprint (corner i0) into
   d[8] (sample_one's corner order), exactly as pair_raw gives them, column
   by column in the order 0, 1, 3, 2 (a footprint across a brick edge in x
   or y switches bricks at most twice).  A column whose source voxels (the
   two or three its two corners blend from) lie in one brick and inside
   the exemplar, with both z corners in the slab (98 % of the columns of
   bench_vdb's rays), costs its crossing check, its offset lane, a brick
   check and two or three byte reads; any other column goes through
   pair_raw.  A failed brick leaves its column's two corners empty;
   returns the first error, as the general path does. */
static inline int tri_dens(loom_texture *t, struct tslot *s, const int64_t i0[3],
                           uint8_t d[8])
{
	static const int order[4] = {0, 1, 3, 2};
	struct xent *e = NULL;
	uint32_t sx = 0, sy = 0, sz = 0;
	int64_t z = i0[2], x0 = 0, y0 = 0;
	int rc = LOOM_OK, one = 1; /* one: every column fast, in one crossing */

	for (int j = 0; j < 4; j++) {
		int k = order[j], dx = k & 1, dy = k >> 1, f, q, e2;
		int64_t x = i0[0] + dx, y = i0[1] + dy, w, zl, zh;
		uint64_t id;
		const uint8_t *c;

		e = xent_at(t, s, x, y, &sx, &sy);
		if (!j)
			x0 = e->x0, y0 = e->y0;
		one &= e->x0 == x0 && e->y0 == y0; /* (an entry may be recycled) */
		if (src_air(t, e, sx, sy, z, z + 1, 1)) {
			air_note(t, s, sx, sy, z);
			d[2 * k] = d[2 * k + 1] = 0;
			sz = s->wsz;
			continue;
		}
		q = xent_dz(t, s, e, sx - e->sx0, sy - e->sy0);
		w = dz_split(q, &f);
		zl = z - w - (f != 0);
		zh = z + 1 - w;
		if (z < 0 || (uint64_t)(z + 1) >= t->b3 || zl < 0 || (uint64_t)zh >= t->b3 ||
		    brick_of(t, 2, (uint32_t)zl) != brick_of(t, 2, (uint32_t)zh) ||
		    (f && !t->seg_brick)) {
			rawvox r[2];
			e2 = pair_raw(t, s, x, y, z, CH_D, r);
			d[2 * k] = r[0].d;
			d[2 * k + 1] = r[1].d;
			if (e2 != LOOM_OK && rc == LOOM_OK)
				rc = e2;
			one = 0;
			continue;
		}
		id = src_brick(t, e, sx, sy, (uint32_t)zl);
		if (t->dunits && id < t->n_bricks)
			id |= DUNIT_TAG;
		d[2 * k] = d[2 * k + 1] = 0;
		if ((e2 = memo_use(t, s, id)) != LOOM_OK ||
		    (e2 = memo_seg_use(t, s, sy)) != LOOM_OK) {
			if (rc == LOOM_OK)
				rc = e2;
			one = 0;
			continue;
		}
		sz = (uint32_t)(z - w);
		if (!s->memo)
			continue;
		c = s->memo + src_index(t, sx, sy, sz);
		if (!f) {
			d[2 * k] = c[0];
			d[2 * k + 1] = c[1];
		} else {
			d[2 * k] = dens_pair(t, c, sz, f);
			d[2 * k + 1] = dens_pair(t, c + 1, sz + 1, f);
		}
	}
	if (one) /* the last column read was column 2: (sx, sy) = corner + (0, 1) */
		tri_next(t, s, e, i0, sx, sy - 1, sz);
	return rc;
}

/* The calling thread's slot is s; p is finite and in range.  Only the
   planes of channel mask ch are read: the 8 corners for density and
   orientation, the label of the voxel containing p for the material. */
static int sample_one(loom_texture *t, struct tslot *s, const double p[3], int filter,
                      unsigned ch, loom_texel *out)
{
	double u[3], f[3];
	int64_t i0[3];
	rawvox r[8];
	float w[8], wd[8], v[8][3], dens = 0;
	int rc = LOOM_OK, near;

	if (filter == LOOM_FILTER_NEAREST) {
		int64_t q[3];
		for (int a = 0; a < 3; a++)
			q[a] = (int64_t)floor(p[a]);
		rc = voxel_raw(t, s, q[0], q[1], q[2], ch, &r[0]);
		bump(&s->cnt.lookups, 1);
		texel_of(t, &r[0], ch, out);
		return rc;
	}
	for (int a = 0; a < 3; a++) {
		u[a] = p[a] - 0.5;
		i0[a] = (int64_t)floor(u[a]);
		f[a] = u[a] - (double)i0[a];
	}
	/* corners: bit 0 = z (fastest in a brick), bit 1 = x, bit 2 = y; the
	   voxel containing p is corner near */
	near = (f[2] >= 0.5) | (f[0] >= 0.5) << 1 | (f[1] >= 0.5) << 2;
	for (int c = 0; c < 8; c++) {
		int dz = c & 1, dx = c >> 1 & 1, dy = c >> 2 & 1;
		w[c] = (float)((dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) *
		               (dz ? f[2] : 1 - f[2]));
	}
	if (ch == CH_D) { /* density alone: tri_dens */
		uint8_t db[8];
		rc = tri_dens(t, s, i0, db);
		for (int c = 0; c < 8; c++)
			if (db[c])
				dens += w[c] * t->dens[db[c]];
		bump(&s->cnt.lookups, 8);
		memset(out, 0, sizeof *out);
		out->density = dens;
		return rc;
	}
	if (ch) {
		for (int c = 0; c < 8; c += 2)
			column_prefetch(t, s, i0[0] + (c >> 1 & 1), i0[1] + (c >> 2 & 1), i0[2],
			                ch & (CH_D | CH_O));
	}
	for (int c = 0; c < 8; c += 2) {
		int dx = c >> 1 & 1, dy = c >> 2 & 1;
		unsigned cch = (ch & (CH_D | CH_O)) | ((near & 6) == c ? ch & CH_M : 0);
		int e = LOOM_OK;
		r[c] = r[c + 1] = raw_empty;
		if (cch)
			e = pair_raw(t, s, i0[0] + dx, i0[1] + dy, i0[2], cch, &r[c]);
		if (e != LOOM_OK && rc == LOOM_OK)
			rc = e;
	}
	for (int c = 0; c < 8; c++) {
		wd[c] = 0;
		v[c][0] = v[c][1] = v[c][2] = 0;
		if (r[c].d) {
			float d = t->dens[r[c].d];
			dens += w[c] * d;
			wd[c] = w[c] * d;
			if (ch & CH_O)
				loom__orient_decode(r[c].o, v[c]);
		}
	}
	bump(&s->cnt.lookups, 8);
	texel_of(t, &r[near], ch & CH_M, out);
	if (ch & CH_D)
		out->density = dens;
	if (ch & CH_O)
		loom__orient_blend(8, wd, (const float(*)[3])v, out->orientation);
	return rc;
}

#define BATCH_AHEAD 4 /* batch calls prefetch this many points ahead */

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

/* The renderer's nearest lookup (render_majorant.c's grid source): what
   loom_texture_sample gives with the nearest filter, all channels, written
   straight into a medium sample (spread 0) without a texel in between
   (a texel would be cleared and copied twice per tentative collision),
   and without the ray-march prefetch (walk_next): tentative collisions
   are a free path apart, not unit steps. */
int loom__texture_medium(loom_texture *t, const double p[3], loom_medium_sample *out)
{
	struct tslot *s;
	rawvox r;
	int rc;

	memset(out, 0, sizeof *out);
	if ((rc = pos_check(p)) != LOOM_OK)
		return rc;
	s = slot_enter(t);
	rc = voxel_raw_w(t, s, (int64_t)floor(p[0]), (int64_t)floor(p[1]), (int64_t)floor(p[2]),
	                 CH_ALL, &r, 0);
	bump(&s->cnt.lookups, 1);
	slot_leave(t, s);
	if (r.d) {
		out->density = t->dens[r.d];
		loom__orient_decode(r.o, out->orient);
	}
	if (r.k) {
		memcpy(out->albedo, t->albedo[r.ty], sizeof out->albedo);
		out->alignment = t->align[r.ty];
	}
	return rc;
}

static int sample_ch(loom_texture *t, const double p[3], int filter, unsigned ch,
                     loom_texel *out)
{
	struct tslot *s;
	int rc;

	if (out)
		memset(out, 0, sizeof *out);
	if (!t || !p || !out || (ch & ~(unsigned)CH_ALL) ||
	    (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	if ((rc = pos_check(p)) != LOOM_OK)
		return rc;
	s = slot_enter(t);
	rc = sample_one(t, s, p, filter, ch, out);
	slot_leave(t, s);
	return rc;
}

LOOM_API int loom_texture_sample(loom_texture *t, const double p[3], int filter,
                                 loom_texel *out)
{
	return sample_ch(t, p, filter, CH_ALL, out);
}

LOOM_API int loom_texture_sample_ch(loom_texture *t, const double p[3], int filter,
                                    unsigned channels, loom_texel *out)
{
	return sample_ch(t, p, filter, channels, out);
}

LOOM_API int loom_texture_sample_batch(loom_texture *t, size_t n, const double *x,
                                       const double *y, const double *z, int filter,
                                       const loom_texture_channels *out)
{
	struct tslot *s;
	unsigned ch;
	int rc = LOOM_OK;

	if (!t || !out || (n && (!x || !y || !z)) ||
	    (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	if (n == 0)
		return LOOM_OK;
	/* only the planes of the channels asked for */
	ch = (out->density ? CH_D : 0u) | (out->orientation ? CH_O : 0u) |
	     (out->kind || out->type || out->albedo ? CH_M : 0u);
	s = slot_enter(t);
	for (size_t i = 0; i < n; i++) {
		double p[3] = {x[i], y[i], z[i]};
		loom_texel tx;
		int e = pos_check(p);
		if (i + BATCH_AHEAD < n && ch) { /* software pipeline: point i + k's
		                                   lane and line on their way */
			double q[3] = {x[i + BATCH_AHEAD], y[i + BATCH_AHEAD], z[i + BATCH_AHEAD]};
			if (pos_check(q) == LOOM_OK)
				column_prefetch(t, s, (int64_t)floor(q[0]), (int64_t)floor(q[1]),
				                (int64_t)floor(q[2]), ch);
		}
		if (e == LOOM_OK)
			e = sample_one(t, s, p, filter, ch, &tx);
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
