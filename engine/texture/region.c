/*
 * engine/texture/region.c - region reads of the virtual texture
 * (loom_texture_read_region): whole boxes of voxels in raw encodings.
 *
 * THE PLAN (the lookup steps cited are lookup.c's)
 *   Region reads go crossing by crossing and, in a crossing, by groups of
 *   adjacent output columns of one row whose source columns share their
 *   bricks (up to a brick's width, at most GMAX; group_fill): steps 3-4 once per
 *   column (offset and valid z range), step 5 once per brick of the group,
 *   then each column's z-run in that brick is copied; z above, below or
 *   beyond the source block is filled with zeros.  A column whose offset
 *   has a fraction is copied like a whole-voxel column with its nearer
 *   whole offset (the other planes are then final); the surface voxels
 *   of each segment from its highest solid voxel up are then blended in
 *   place (raw_blend's density rule).  With SSE2 and bricks whose height
 *   is a multiple of SEG_Z, at most 64 (the default 64; no segment then
 *   crosses a brick), right after each brick line's copy, from 64-bit
 *   masks of the line (line_blend; the voxel beyond the line's end
 *   carried to the next line of the pass); a density-only read with
 *   AVX-512BW copies and blends each line in one load and one masked
 *   store (line_copy_blend_512), with AVX2 alone in two loads, the
 *   masks and the smear in the vector as well (line_copy_blend_256).
 *   Otherwise the one source
 *   voxel past the run is read in the same brick pass, with whether the
 *   segment of its last voxel goes on above it with a solid voxel, and
 *   after the pass the column is blended segment by segment (blend_col),
 *   only between the first and last stored brick the pass read (an empty
 *   nearer voxel stays empty).
 *   label -> kind / type
 *   16 voxels at a time with PSHUFB where the CPU has SSSE3 (checked at
 *   open) and the exemplar's labels with a kind are below 128
 *   (kind_type), else through 256-entry tables.  z-fastest output: the
 *   runs go straight out (region_zfast).  x-fastest output: per band of
 *   crossing rows, chunk columns of up to RCOLS output columns, whatever
 *   crossing pieces they span (so output rows are written whole); per
 *   chunk column, the z planes where all of it is surely empty (outside
 *   the block, or in bricks stored as nothing: chunk_extent) are zeroed
 *   plane by plane (zero_rect, sequential writes; one span a plane when
 *   the chunk is whole output rows; outputs of NT_MIN bytes and more
 *   with non-temporal stores, no read for ownership); then slabs of RZ
 *   z-values, rows (xchunk): the z rows where the chunk is
 *   surely empty are zeroed directly; the rest is gathered piece by piece
 *   into the slot's buffer and transposed 16 x 16 at a time (SSE2; with
 *   SSSE3 kind and type come from the transposed labels instead of being
 *   gathered and transposed), each output row of the chunk written whole
 *   and the next chunk's rows prefetched meanwhile (they are a plane
 *   apart, where the hardware prefetchers do not go) (region_xfast).
 */
#include "texture_impl.h"

#include <stdint.h>
#include <stdlib.h>
#ifdef __SSE2__
#include <emmintrin.h>
#define REGION_SSE2 1
#endif
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <tmmintrin.h> /* SSSE3, used under a target attribute after a CPU check */
#define HAVE_KT_SSSE3 1
#if defined(__x86_64__)
#include <immintrin.h> /* AVX-512BW, the same way (line_masks_512) */
#define HAVE_LINE_512 1
#endif
#ifndef REGION_SSE2
/* gcc's immintrin.h leaves __SSE2__ defined after its target pragmas
   even when the build undefined it (make test-portable: -U__SSE2__);
   without this the SSE2 paths were compiled there too */
#undef __SSE2__
#endif
#endif

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

/* n < 16 bytes from s to d as two overlapping moves of 8, 4 or 1 bytes
   (inline: the x-fastest gather copies many runs shorter than 16, and the
   memcpy calls for them and for partial output rows were ~10 % of the
   samples of the all-channel x-fastest read). */
static inline void copy_small(uint8_t *restrict d, const uint8_t *restrict s, size_t n)
{
	if (n >= 8) {
		uint64_t a, b;
		memcpy(&a, s, 8);
		memcpy(&b, s + n - 8, 8);
		memcpy(d, &a, 8);
		memcpy(d + n - 8, &b, 8);
	} else if (n >= 4) {
		uint32_t a, b;
		memcpy(&a, s, 4);
		memcpy(&b, s + n - 4, 4);
		memcpy(d, &a, 4);
		memcpy(d + n - 4, &b, 4);
	} else if (n) {
		uint8_t a = s[0], b = s[n / 2], c = s[n - 1];
		d[0] = a;
		d[n / 2] = b;
		d[n - 1] = c;
	}
}

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
#else
	if (n >= 16) { /* copy_small moves fewer than 16 bytes only */
		memcpy(d, s, n);
		return;
	}
#endif
	copy_small(d, s, n);
}

static inline void zero_run(uint8_t *d, size_t n)
{
	static const uint8_t z16[16];
	if (n < 16)
		copy_small(d, z16, n); /* inline, like copy_run's short runs */
	else
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

/* ------------------------------------------- the sub-voxel density blend */

/* raw_blend's density rule for region reads: a column whose offset has a
   fraction is first copied like a whole-voxel column with its nearer
   whole offset (every plane the nearer voxel's, as raw_blend keeps
   them).  Only voxels at or above the highest solid voxel of their
   segment (SEG_Z, texture_impl.h) can differ from that copy.  Two forms:
   line_blend, brick line by brick line in the pass (SSE2, brick heights
   a multiple of SEG_Z up to 64), and blend_col after the pass, segment by
   segment (blend_seg16, or byte by byte with dens_blend's arithmetic
   without SSE2); test_texture's region_blend_edges holds both to the
   reference. */

/* dens_blend's arithmetic for a voxel of density n over an empty
   farther voxel of weight g / DZ_SUB. */
static inline uint8_t dens_far_empty(unsigned n, unsigned g)
{
	return (uint8_t)(((DZ_SUB - g) * n + DZ_SUB / 2) / DZ_SUB);
}

#ifdef __SSE2__
/* Lane masks: lanes_ge[k] has lanes k .. 15 set (k = 0 .. 16). */
static const uint8_t lanes_ge[17][16] = {
#define LG(k) {0 >= k ? 255 : 0, 1 >= k ? 255 : 0, 2 >= k ? 255 : 0, 3 >= k ? 255 : 0,  \
	       4 >= k ? 255 : 0, 5 >= k ? 255 : 0, 6 >= k ? 255 : 0, 7 >= k ? 255 : 0,  \
	       8 >= k ? 255 : 0, 9 >= k ? 255 : 0, 10 >= k ? 255 : 0, 11 >= k ? 255 : 0, \
	       12 >= k ? 255 : 0, 13 >= k ? 255 : 0, 14 >= k ? 255 : 0, 15 >= k ? 255 : 0}
	LG(0), LG(1), LG(2), LG(3), LG(4), LG(5), LG(6), LG(7), LG(8),
	LG(9), LG(10), LG(11), LG(12), LG(13), LG(14), LG(15), LG(16)
#undef LG
};

/* Blend the lanes lo .. hi - 1 of one segment, held in 16 densities v
   with their farther voxels o: the surface voxels (non-empty over an
   empty farther voxel) from the segment's highest solid voxel up, none
   when `blocked` (a solid voxel above the run in this segment), become
   ((DZ_SUB - g) n + DZ_SUB/2) / DZ_SUB.  Returns v so changed, *any when
   a lane was. */
static inline __m128i blend_seg16(__m128i v, __m128i o, unsigned lo, unsigned hi, int blocked,
                                  uint8_t solid, unsigned g, int *any)
{
	const __m128i zero = _mm_setzero_si128();
	__m128i keep = _mm_andnot_si128(_mm_loadu_si128((const __m128i *)lanes_ge[hi]),
	                                _mm_loadu_si128((const __m128i *)lanes_ge[lo]));
	__m128i c = _mm_and_si128(keep, _mm_andnot_si128(_mm_cmpeq_epi8(v, zero),
	                                                 _mm_cmpeq_epi8(o, zero)));
	unsigned so;
	__m128i w, l, h;

	*any = 0;
	if (blocked || !_mm_movemask_epi8(c))
		return v;
	so = (unsigned)_mm_movemask_epi8(_mm_and_si128(
		keep, _mm_cmpeq_epi8(_mm_max_epu8(v, _mm_set1_epi8((char)solid)), v)));
	if (so) {
		c = _mm_and_si128(c, _mm_loadu_si128((const __m128i *)
		                                     lanes_ge[31 - __builtin_clz(so)]));
		if (!_mm_movemask_epi8(c))
			return v;
	}
	*any = 1;
	w = _mm_set1_epi16((short)(DZ_SUB - g));
	l = _mm_srli_epi16(_mm_add_epi16(_mm_mullo_epi16(_mm_unpacklo_epi8(v, zero), w),
	                                 _mm_set1_epi16(DZ_SUB / 2)), 4);
	h = _mm_srli_epi16(_mm_add_epi16(_mm_mullo_epi16(_mm_unpackhi_epi8(v, zero), w),
	                                 _mm_set1_epi16(DZ_SUB / 2)), 4);
	return _mm_or_si128(_mm_and_si128(c, _mm_packus_epi16(l, h)), _mm_andnot_si128(c, v));
}
#endif

/* Blend the copied densities d[0 .. L) of a fractional column in place:
   voxel i's nearer source voxel is zs + i, its farther d[i + dir] (dir -1:
   below, +1: above), past the ends edge (the source voxel beyond the run,
   0 outside the block), weight g / DZ_SUB (1 .. DZ_SUB / 2).  Only
   d[i0 .. i1) can have density (the rest lies in bricks stored as
   nothing, or failed); above: the segment of the run's last voxel goes
   on above the run (past the box) with a solid voxel there.  Segment by
   segment (whether a voxel has a solid one above it is a question inside
   its segment), with SSE2 16 voxels at a time: a window of the run that
   holds the segment's part and whose farther voxels lie in the run too
   (at the run's ends, shifted inwards, the lanes outside the segment
   kept); at the run's end on the farther side the window there, its
   farther voxels its own shifted by a lane with edge shifted in; in
   runs under 16 voxels a small line; upwards when the farther voxel is
   above, downwards when below, so that the voxels a window reads as
   farther ones are not yet blended. */
static void blend_col(uint8_t *d, size_t L, size_t i0, size_t i1, int64_t zs, int dir,
                      unsigned g, unsigned edge, int above, uint8_t solid)
{
	int64_t first, last, n;
#ifdef __SSE2__
	int64_t wmin, wmax;
#endif

	if (i0 >= i1)
		return;
	first = (int64_t)i0 - (int64_t)(((uint64_t)zs + i0) % SEG_Z);
	last = (int64_t)(i1 - 1) - (int64_t)(((uint64_t)zs + i1 - 1) % SEG_Z);
	n = (last - first) / SEG_Z + 1;
#ifdef __SSE2__
	wmin = dir < 0 ? 1 : 0;                           /* windows w: d[w + dir] and */
	wmax = (int64_t)L - SEG_Z - (dir > 0 ? 1 : 0);    /* d[w + 15 + dir] in the run */
#endif
	for (int64_t q = 0; q < n; q++) {
		int64_t sg = dir > 0 ? first + SEG_Z * q : last - SEG_Z * q;
		int64_t lo = sg > (int64_t)i0 ? sg : (int64_t)i0;
		int64_t hi = sg + SEG_Z < (int64_t)i1 ? sg + SEG_Z : (int64_t)i1;
		int blocked = above && sg + SEG_Z > (int64_t)L;
#ifdef __SSE2__
		int64_t w = sg < wmin ? wmin : sg > wmax ? wmax : sg;
		int any, inside = wmin <= wmax && w <= lo && hi <= w + SEG_Z;
		if (inside || L >= SEG_Z) {
			__m128i v, o, r;
			if (inside) {
				v = _mm_loadu_si128((const __m128i *)(d + w));
				o = _mm_loadu_si128((const __m128i *)(d + w + dir));
			} else { /* the run's end on the farther side (the window
			            there holds the segment's part): the farther
			            voxels are the window's own, shifted by a lane,
			            with edge past the end */
				__m128i e = _mm_cvtsi32_si128((int)edge);
				w = dir > 0 ? (int64_t)L - SEG_Z : 0;
				v = _mm_loadu_si128((const __m128i *)(d + w));
				o = dir > 0 ? _mm_or_si128(_mm_srli_si128(v, 1), _mm_slli_si128(e, 15))
				            : _mm_or_si128(_mm_slli_si128(v, 1), e);
			}
			r = blend_seg16(v, o, (unsigned)(lo - w), (unsigned)(hi - w), blocked, solid, g,
			                &any);
			if (any)
				_mm_storeu_si128((__m128i *)(d + w), r);
		} else { /* through a line: lanes lo .. hi - 1 from d, the rest 0 */
			uint8_t t[48], out[16];
			memset(t, 0, sizeof t);
			memcpy(t + 16 + (lo - sg), d + lo, (size_t)(hi - lo));
			t[16 + (lo - sg) - 1] = (uint8_t)(lo >= 1 ? d[lo - 1] : edge);
			t[16 + (hi - sg)] = (uint8_t)(hi < (int64_t)L ? d[hi] : edge);
			{
				__m128i r = blend_seg16(_mm_loadu_si128((const __m128i *)(t + 16)),
				                        _mm_loadu_si128((const __m128i *)(t + 16 + dir)),
				                        (unsigned)(lo - sg), (unsigned)(hi - sg), blocked,
				                        solid, g, &any);
				if (any) {
					_mm_storeu_si128((__m128i *)out, r);
					memcpy(d + lo, out + (lo - sg), (size_t)(hi - lo));
				}
			}
		}
#else
		{
			int64_t j = hi, h, k;
			while (j > lo && !d[j - 1])
				j--;
			if (j-- == lo || blocked)
				continue;
			for (h = j; h > lo && d[h] < solid; h--)
				;
			for (k = h; k <= j; k++) {
				unsigned o = dir > 0 ? (k + 1 < (int64_t)L ? d[k + 1] : edge)
				                     : (k ? d[k - 1] : edge);
				if (d[k] && !o)
					d[k] = dens_far_empty(d[k], g);
			}
		}
#endif
	}
}

#ifdef __SSE2__
/* The non-empty voxels of a brick line's first 16 nvec voxels (bit i:
   voxel i), and in *sol its solid ones. */
static inline __attribute__((always_inline)) uint64_t
line_masks(const uint8_t *line, unsigned nvec, uint8_t solid, uint64_t *sol)
{
	const __m128i zero = _mm_setzero_si128(), sv = _mm_set1_epi8((char)solid);
	__m128i v[4];
	uint64_t nz = 0, so = 0;

	for (unsigned j = 0; j < nvec; j++) {
		v[j] = _mm_loadu_si128((const __m128i *)(line + SEG_Z * j));
		nz |= (uint64_t)(~(unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(v[j], zero)) & 0xffffu)
		      << (SEG_Z * j);
	}
	for (unsigned j = 0; j < nvec; j++)
		so |= (uint64_t)(unsigned)_mm_movemask_epi8(
			      _mm_cmpeq_epi8(_mm_max_epu8(v[j], sv), v[j]))
		      << (SEG_Z * j);
	*sol = so;
	return nz;
}

#ifdef HAVE_LINE_512
/* line_masks of a 64-voxel line in one load and two compares. */
__attribute__((target("avx512bw"), noinline)) static uint64_t
line_masks_512(const uint8_t *line, uint8_t solid, uint64_t *sol)
{
	__m512i v = _mm512_loadu_si512((const void *)line);
	*sol = _mm512_cmpge_epu8_mask(v, _mm512_set1_epi8((char)solid));
	return _mm512_test_epi8_mask(v, v);
}
#endif

/* The brick-line form of blend_col, when the brick height is a multiple
   of SEG_Z and at most 64 (t->seg_brick; the default 64): segments then
   never cross a brick, so the whole rule is a question about one brick
   line, the source column's bz voxels of the brick, with one voxel of the
   neighbouring brick at each end.  Bit i of a mask is the line's voxel i:
   nz its non-empty voxels (the first nv of them: the rest lies above the
   block), sol its solid ones.  Returns the voxels in bits lo .. hi - 1
   to blend: non-empty over an empty farther voxel (nz shifted by one;
   past the line's lower end pn, the voxel below it; past its upper end
   treated as empty here, see group_fill), and no solid voxel above them
   in their segment (a 16-bit lane of sol, smeared downwards inside the
   lane). */
static inline uint64_t line_blend_mask(const uint8_t *line, unsigned bz, unsigned nv, int dir,
                                       uint64_t pn, unsigned lo, unsigned hi, uint8_t solid,
                                       int avx512)
{
	const uint64_t m1 = 0x7fff7fff7fff7fffull, m2 = 0x3fff3fff3fff3fffull,
	               m4 = 0x0fff0fff0fff0fffull, m8 = 0x00ff00ff00ff00ffull;
	uint64_t nz, sol, up, keep, cand;

#ifdef HAVE_LINE_512
	if (avx512 && bz == 64)
		nz = line_masks_512(line, solid, &sol);
	else
#else
	(void)avx512;
#endif
	/* the constant 4 lets the default height's loop unroll */
	nz = bz == 64 ? line_masks(line, 4, solid, &sol) : line_masks(line, bz / SEG_Z, solid, &sol);
	if (nv < 64) {
		nz &= ((uint64_t)1 << nv) - 1;
		sol &= ((uint64_t)1 << nv) - 1;
	}
	keep = (hi >= 64 ? ~(uint64_t)0 : ((uint64_t)1 << hi) - 1) & ~(((uint64_t)1 << lo) - 1);
	cand = nz & ~(dir > 0 ? nz >> 1 : nz << 1 | pn) & keep;
	up = (sol >> 1) & m1; /* a solid voxel above, in the lane */
	up |= (up >> 1) & m1;
	up |= (up >> 2) & m2;
	up |= (up >> 4) & m4;
	up |= (up >> 8) & m8;
	return cand & ~up;
}
#endif

/* Columns handled together by group_fill at most. */
#define GMAX 64

/* Per column of a group: how its densities blend. */
struct fcol {
	int8_t dir;    /* 0: whole offset; -1, +1: the farther voxel */
	uint8_t g;     /* the farther voxel's weight, 1 .. DZ_SUB/2 */
	uint8_t edge;  /* density of the end voxel (the farther voxel past
	                  the run; 0 outside the block or its brick failed) */
	int64_t xz;    /* source z of the end voxel, below the run for dir -1,
	                  above it for dir +1 (-1: outside the block) */
	int64_t xk;    /* the brick (z index) holding it; -1: none */
	int64_t az;    /* source z of the first voxel above the run in the
	                  segment of its last voxel; -1: the segment ends there */
	uint32_t an;   /* how many voxels from az to the segment's end */
	uint8_t above; /* one of those is solid (blend_col) */
	uint8_t pn;    /* line path: the previous brick line's top voxel is
	                  not empty */
	uint8_t pv;    /* line path: the source density of *pend */
	uint8_t *pend; /* line path: a voxel to blend when the next brick
	                  line's first voxel is empty */
};

/* Blend the voxels of set m (bits below bz) of brick line `line`, copied
   to out (out[0]: voxel lo), from the brick bytes. */
static inline void line_blend_bits(const struct fcol *F, uint8_t *out, const uint8_t *line,
                                   uint64_t m, unsigned lo, unsigned bz)
{
	{ /* one voxel or none in 96 % of the lines (the paper database): the
	     first without a branch, into a scratch byte when there is none */
		unsigned i = (unsigned)__builtin_ctzll(m | (uint64_t)1 << (bz - 1));
		uint8_t scratch, *q = m ? out + (i - lo) : &scratch;
		*q = dens_far_empty(line[i], F->g);
		m &= m - 1;
	}
	for (; __builtin_expect(m != 0, 0); m &= m - 1) {
		unsigned i = (unsigned)__builtin_ctzll(m);
		out[i - lo] = dens_far_empty(line[i], F->g);
	}
}

/* The line paths' blend set m of a line copied to out (out[0]: voxel
   lo) without its top voxel `top` when that is a candidate of a column
   moved up and another brick line follows (more): it waits in F->pend
   for that line's first voxel (group_fill). */
static inline uint64_t line_top_waits(struct fcol *F, uint64_t m, uint8_t *out,
                                      const uint8_t *line, unsigned top, unsigned lo, int more)
{
	if (F->dir > 0 && more && (m >> top & 1)) {
		m &= ~((uint64_t)1 << top);
		F->pend = out + (top - lo);
		F->pv = line[top];
	}
	return m;
}

#ifdef __SSE2__
/* The line path of group_fill: blend the voxels lo .. hi - 1 of brick
   line `line` (nv of its bz voxels in the block), just copied to out
   (out[0]: voxel lo); pn: the voxel below the line is not empty.  The
   line's top voxel, when it is a candidate and a brick line follows
   (more), waits in F->pend for that line's first voxel. */
static inline void line_blend(struct fcol *F, uint8_t *out, const uint8_t *line, unsigned bz,
                              unsigned lo, unsigned hi, unsigned nv, int more, unsigned pn,
                              uint8_t solid, int avx512)
{
	uint64_t m = line_blend_mask(line, bz, nv, F->dir, pn, lo, hi, solid, avx512);

	line_blend_bits(F, out, line, line_top_waits(F, m, out, line, bz - 1, lo, more), lo, bz);
}
#endif

#ifdef HAVE_LINE_512
/* The CPU runs the AVX-512BW line paths (BMI2 too, for their bzhi). */
static int cpu_line512(void)
{
	__builtin_cpu_init();
	return __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("bmi2");
}

/* The CPU runs the AVX2 line path (BMI2 too, for its bzhi). */
static int cpu_line256(void)
{
	__builtin_cpu_init();
	return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi2");
}

#define DZ_SHIFT 4 /* log2 DZ_SUB: dens_far_empty's division as a shift */
_Static_assert(1 << DZ_SHIFT == DZ_SUB, "DZ_SHIFT is log2 DZ_SUB");

/* The copy and line_blend of a density-only read in one (AVX-512BW, bricks
   64 high): the voxels lo .. hi - 1 of brick line `line` (its first nv
   voxels in the block) to out (voxel lo), the chosen ones blended, from
   one 64-byte load and one masked store.  line_blend_mask's rule with the
   solid voxels above smeared in the vector (each 16-byte lane of
   _mm512_bsrli_epi128 is a segment), no trip through general registers
   but for the line's top voxel (docs/performance.md, "One load and one
   masked store"). */
__attribute__((target("avx512bw,bmi2"), noinline)) static void
line_copy_blend_512(struct fcol *F, uint8_t *out, const uint8_t *line, unsigned lo, unsigned hi,
                    unsigned nv, int more, unsigned pn, uint8_t solid)
{
	const uint64_t ones = ~(uint64_t)0;
	const __m512i w = _mm512_set1_epi16((short)(DZ_SUB - F->g)),
	              half = _mm512_set1_epi16(DZ_SUB / 2), zero = _mm512_setzero_si512();
	__m512i v = _mm512_loadu_si512((const void *)line), y, a, b;
	uint64_t in = _bzhi_u64(ones, nv), keep = _bzhi_u64(ones, hi) & ~_bzhi_u64(ones, lo);
	uint64_t nz = _mm512_mask_test_epi8_mask(in, v, v), m;
	__mmask64 sol = _mm512_mask_cmpge_epu8_mask(in, v, _mm512_set1_epi8((char)solid));

	/* a solid voxel above in the segment: the solid bytes moved down one
	   and smeared downwards inside each lane */
	y = _mm512_bsrli_epi128(_mm512_movm_epi8(sol), 1);
	y = _mm512_or_si512(y, _mm512_bsrli_epi128(y, 1));
	y = _mm512_or_si512(y, _mm512_bsrli_epi128(y, 2));
	y = _mm512_or_si512(y, _mm512_bsrli_epi128(y, 4));
	y = _mm512_or_si512(y, _mm512_bsrli_epi128(y, 8));
	m = nz & ~(F->dir > 0 ? nz >> 1 : nz << 1 | pn) & keep & _mm512_testn_epi8_mask(y, y);
	m = line_top_waits(F, m, out, line, 63, lo, more);
	/* dens_far_empty of every voxel in 16-bit lanes (unpacked and packed
	   back inside each 128-bit lane: the order is kept) */
	a = _mm512_unpacklo_epi8(v, zero);
	b = _mm512_unpackhi_epi8(v, zero);
	a = _mm512_srli_epi16(_mm512_add_epi16(_mm512_mullo_epi16(a, w), half), DZ_SHIFT);
	b = _mm512_srli_epi16(_mm512_add_epi16(_mm512_mullo_epi16(b, w), half), DZ_SHIFT);
	/* out - lo: the masked store touches only voxels lo .. hi - 1 */
	_mm512_mask_storeu_epi8((void *)((uintptr_t)out - lo), keep,
	                        _mm512_mask_mov_epi8(v, m, _mm512_packus_epi16(a, b)));
}

/* line_copy_blend_512 for hosts with AVX2 but not AVX-512BW (no byte-masked
   store there): the line's masks from two 32-byte loads, the solid voxels
   above smeared in the vector as line_copy_blend_512 does them (each
   16-byte lane of _mm256_bsrli_epi128 is a segment), the copy as two
   overlapping moves, and the chosen voxels blended after it as
   line_blend blends them
   (docs/performance.md, "Hosts with AVX2"). */
__attribute__((target("avx2,bmi2"), noinline)) static void
line_copy_blend_256(struct fcol *F, uint8_t *out, const uint8_t *line, unsigned lo, unsigned hi,
                    unsigned nv, int more, unsigned pn, uint8_t solid)
{
	const uint64_t ones = ~(uint64_t)0;
	const __m256i idx = _mm256_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15,
	                                     16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28,
	                                     29, 30, 31),
	              sv = _mm256_set1_epi8((char)solid), zero = _mm256_setzero_si256();
	__m256i v0 = _mm256_loadu_si256((const __m256i *)line),
	        v1 = _mm256_loadu_si256((const __m256i *)(line + 32)), y0, y1;
	/* the voxels inside the block: byte i of the line below nv (nv <= 64,
	   so both differences fit a signed byte) */
	__m256i n0 = _mm256_cmpgt_epi8(_mm256_set1_epi8((char)nv), idx),
	        n1 = _mm256_cmpgt_epi8(_mm256_set1_epi8((char)((int)nv - 32)), idx);
	uint64_t keep = _bzhi_u64(ones, hi) & ~_bzhi_u64(ones, lo), nz, m;

	nz = ~((uint64_t)(uint32_t)_mm256_movemask_epi8(_mm256_cmpeq_epi8(v0, zero)) |
	       (uint64_t)(uint32_t)_mm256_movemask_epi8(_mm256_cmpeq_epi8(v1, zero)) << 32) &
	     _bzhi_u64(ones, nv);
	/* a solid voxel above in the segment: the solid bytes moved down one
	   and smeared downwards inside each lane */
	y0 = _mm256_and_si256(_mm256_cmpeq_epi8(_mm256_max_epu8(v0, sv), v0), n0);
	y1 = _mm256_and_si256(_mm256_cmpeq_epi8(_mm256_max_epu8(v1, sv), v1), n1);
	y0 = _mm256_bsrli_epi128(y0, 1);
	y1 = _mm256_bsrli_epi128(y1, 1);
	y0 = _mm256_or_si256(y0, _mm256_bsrli_epi128(y0, 1));
	y1 = _mm256_or_si256(y1, _mm256_bsrli_epi128(y1, 1));
	y0 = _mm256_or_si256(y0, _mm256_bsrli_epi128(y0, 2));
	y1 = _mm256_or_si256(y1, _mm256_bsrli_epi128(y1, 2));
	y0 = _mm256_or_si256(y0, _mm256_bsrli_epi128(y0, 4));
	y1 = _mm256_or_si256(y1, _mm256_bsrli_epi128(y1, 4));
	y0 = _mm256_or_si256(y0, _mm256_bsrli_epi128(y0, 8));
	y1 = _mm256_or_si256(y1, _mm256_bsrli_epi128(y1, 8));
	m = nz & ~(F->dir > 0 ? nz >> 1 : nz << 1 | pn) & keep &
	    ~((uint64_t)(uint32_t)_mm256_movemask_epi8(y0) |
	      (uint64_t)(uint32_t)_mm256_movemask_epi8(y1) << 32);
	/* the copy: the line's bytes lo .. hi - 1 in two overlapping moves
	   (inside the line's 64 bytes; copy_run's loop became a memmove call
	   under this target) */
	if (hi - lo >= 32) {
		__m256i p = _mm256_loadu_si256((const __m256i *)(line + lo)),
		        q = _mm256_loadu_si256((const __m256i *)(line + hi - 32));
		_mm256_storeu_si256((__m256i *)out, p);
		_mm256_storeu_si256((__m256i *)(out + (hi - lo) - 32), q);
	} else if (hi - lo >= 16) {
		__m128i p = _mm_loadu_si128((const __m128i *)(line + lo)),
		        q = _mm_loadu_si128((const __m128i *)(line + hi - 16));
		_mm_storeu_si128((__m128i *)out, p);
		_mm_storeu_si128((__m128i *)(out + (hi - lo) - 16), q);
	} else {
		copy_small(out, line + lo, hi - lo);
	}
	line_blend_bits(F, out, line, line_top_waits(F, m, out, line, 63, lo, more), lo, 64);
}
#endif

/*
 * The z-range [za, zb) of n (1..GMAX) consecutive output columns (lx0 + c,
 * ly), c < n, of crossing e whose source columns lie in one brick column
 * (so they share every brick id), into sink k: column c from offset
 * off + c*cstride (voxel za).  Steps 3-5 once per column (offset, valid
 * range), then per brick of the union of the columns' source z ranges:
 * one brick resolution (the slot's memo) and each column's run in it.
 * A column whose offset has a fraction (q = DZ_SUB w + f, f > 0) is
 * copied the same way with its nearer whole offset wn (w, or w + 1 when
 * f > DZ_SUB/2): every plane is the nearer voxel's (raw_blend), and an
 * output voxel whose nearer voxel lies outside the block is empty.  With
 * density wanted, the surface voxels with no solid voxel above them in
 * their segment are blended in place: line by line right after each
 * copy (line_blend, lpath), or after the pass (blend_col), for which the
 * one source voxel past the run on the farther side (the end voxel) and
 * whether the segment of its last voxel has a solid voxel above the run
 * are read in the same brick pass.  Fraction 0 is the whole-voxel path
 * unchanged.  Voxels whose brick fails are empty (or blended with
 * empty); the first error is returned.
 */
static int group_fill(loom_texture *t, struct tslot *s, struct xent *e, uint32_t lx0,
                      uint32_t ly, uint32_t n, int64_t za, int64_t zb, const struct sink *k,
                      size_t off, size_t cstride)
{
	int64_t b3 = t->b3, bz = t->bs[2];
	int64_t sa[GMAX], sb[GMAX], dzs[GMAX]; /* source z range, offset */
	struct fcol fc[GMAX];
	int64_t smin = INT64_MAX, smax = INT64_MIN;
	int64_t slo = INT64_MAX, shi = INT64_MIN; /* the stored bricks read */
	int64_t va0 = za > 0 ? za : 0, vb0 = zb < b3 ? zb : b3;
	uint32_t sx = e->sx0 + lx0, sy = e->sy0 + ly;
	uint64_t base;
	size_t col;
	int rc = LOOM_OK, nfrac = 0;
	uint8_t *D = k->raw ? k->rd : k->d;
#ifdef __SSE2__
	/* the brick-line form of the blend (line_blend_mask) */
	const int lpath = D && t->seg_brick && bz <= 64;
#else
	const int lpath = 0;
#endif
#ifdef HAVE_LINE_512
	/* density alone, 64-high bricks: line_copy_blend_512 with AVX-512BW,
	   else line_copy_blend_256 with AVX2 */
	const int ldens = lpath && bz == 64 &&
	                  (k->raw ? !k->rlo && !k->rl && !k->rk && !k->rt
	                          : !k->o && !k->l && !k->k && !k->ty);
	const int l512 = ldens && t->avx512, l256 = ldens && !t->avx512 && t->avx2;
#endif

	for (uint32_t c = 0; c < n; c++) {
		int f;
		int64_t dz = dz_split(xent_dz(t, s, e, lx0 + c, ly), &f);
		int64_t va = va0, vb = vb0;
		size_t o = off + c * cstride;
		struct fcol *F = &fc[c];
		int far_up = 2 * f > DZ_SUB; /* nearer voxel z - w - 1 */
		if (t->region_whole)
			f = 0; /* the bench's whole-voxel peer: the nearer copy only */
		F->dir = 0;
		F->xk = -1;
		F->az = -1;
		F->above = 0;
		F->pn = 0;
		F->pend = NULL;
		dz += far_up; /* the nearer whole offset */
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
		if (f && D) {
			nfrac++;
			F->g = (uint8_t)(far_up ? DZ_SUB - f : f);
			F->dir = (int8_t)(far_up ? 1 : -1);
			F->edge = 0;
			/* the farther voxel of the run's end voxel, when in the block:
			   its brick is read in the pass (the line path reads it and
			   the rest of the top segment in the brick lines; the other
			   path keeps it in F->edge) */
			F->xz = far_up ? sb[c] : sa[c] - 1;
			if (F->xz >= 0 && F->xz < b3) {
				F->xk = lpath ? -1 : (int64_t)brick_of(t, 2, (uint32_t)F->xz);
				if (F->xz < smin)
					smin = F->xz;
				if (F->xz + 1 > smax)
					smax = F->xz + 1;
			} else {
				F->xz = -1;
			}
			if (!lpath && sb[c] < b3) { /* the run's top segment may go on past it */
				uint32_t end = seg_end((uint32_t)(sb[c] - 1), (uint32_t)b3);
				if (end > sb[c]) { /* read in the pass */
					F->az = sb[c];
					F->an = end - (uint32_t)sb[c];
					if (end > smax)
						smax = end;
				}
			}
		}
	}
	if (smin >= smax)
		return rc;
	base = e->ex->first_brick +
	       ((uint64_t)brick_of(t, 1, sy) * e->ex->nb[0] + brick_of(t, 0, sx)) *
	               e->ex->nb[2];
	col = ((size_t)in_brick(t, 1, sy) * t->bs[0] + in_brick(t, 0, sx)) * t->bs[2];
	for (int64_t kz = brick_of(t, 2, (uint32_t)smin); kz * bz < smax; kz++) {
		int64_t z0 = kz * bz, z1 = z0 + bz;
		uint64_t id = base + (uint64_t)kz;
		const uint8_t *p;
		int e2 = memo_use(t, s, id);
		if (e2 != LOOM_OK && rc == LOOM_OK)
			rc = e2;
		p = e2 == LOOM_OK ? s->memo : NULL;
		if (p && !brick_empty(t, id)) {
			if (z0 < slo)
				slo = z0;
			shi = z1;
		}
		for (uint32_t c = 0; c < n; c++) {
			int64_t a = sa[c] > z0 ? sa[c] : z0, b = sb[c] < z1 ? sb[c] : z1;
			struct fcol *F = &fc[c];
			size_t o;
			const uint8_t *line = p ? p + col + (size_t)c * bz : NULL;
			unsigned pn = 0;
			if (F->dir && lpath) {
				if (F->pend) { /* the last line's top voxel, over this one's first */
					if (!line || !line[0])
						*F->pend = dens_far_empty(F->pv, F->g);
					F->pend = NULL;
				}
				pn = F->pn;
				/* the voxel below the next line, for a column moved
				   down whose run goes on into it: lines outside the
				   column's run (but in the group's) are not loaded */
				F->pn = F->dir < 0 && line && (a < b || sa[c] == z1) && line[bz - 1];
			} else if (F->dir) {
				if (F->xk == kz && line) /* the end voxel is in this brick */
					F->edge = line[F->xz - z0];
				if (F->az >= 0 && F->az < z1 && F->az + F->an > z0 && line) {
					/* the rest of the top segment (in this brick) */
					int64_t u = F->az > z0 ? F->az : z0, v = F->az + F->an;
					v = v < z1 ? v : z1;
					F->above |= !line_none_solid(t, line, (uint32_t)z0, (uint32_t)u,
					                             (uint32_t)v);
				}
			}
			if (a >= b)
				continue;
			o = off + c * cstride + (size_t)(a + dzs[c] - za);
			if (!line) {
				sink_empty(k, o, (size_t)(b - a));
				continue;
			}
#ifdef HAVE_LINE_512
			if (l512 && F->dir) {
				line_copy_blend_512(F, D + o, line, (unsigned)(a - z0), (unsigned)(b - z0),
				                    z1 > b3 ? (unsigned)(b3 - z0) : (unsigned)bz, z1 < b3, pn,
				                    t->solid);
				continue;
			}
			if (l256 && F->dir) {
				line_copy_blend_256(F, D + o, line, (unsigned)(a - z0), (unsigned)(b - z0),
				                    z1 > b3 ? (unsigned)(b3 - z0) : (unsigned)bz, z1 < b3, pn,
				                    t->solid);
				continue;
			}
#endif
			sink_run(t, k, o, line + (a - z0), (size_t)(b - a));
#ifdef __SSE2__
			if (lpath && F->dir)
				line_blend(F, D + o, line, (unsigned)bz, (unsigned)(a - z0),
				           (unsigned)(b - z0), z1 > b3 ? (unsigned)(b3 - z0) : (unsigned)bz,
				           z1 < b3, pn, t->solid, t->avx512);
#else
			(void)pn;
#endif
		}
	}
	if (lpath) /* blended in the pass: a top voxel left waiting always
	              had its next line read (the end voxel's brick is) */
		return rc;
	/* the fractional columns' densities, from the copied ones, only
	   between the first and last stored brick read: bricks stored as
	   nothing (or failed) gave empty voxels, and an empty nearer voxel
	   stays empty; the voxel past that part, when inside the run, is
	   such a voxel, the farther voxel at that end */
	if (nfrac && slo < shi)
		for (uint32_t c = 0; c < n; c++) {
			const struct fcol *F = &fc[c];
			int64_t bl = sa[c] > slo ? sa[c] : slo, bh = sb[c] < shi ? sb[c] : shi;
			if (!F->dir || bl >= bh)
				continue;
			blend_col(D + off + c * cstride + (size_t)(sa[c] + dzs[c] - za),
			          (size_t)(sb[c] - sa[c]), (size_t)(bl - sa[c]), (size_t)(bh - sa[c]),
			          sa[c], F->dir, F->g, F->edge, F->above, t->solid);
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
	int stream;   /* x-fastest, output of NT_MIN bytes or more: the surely
	                 empty rows zeroed with non-temporal stores (zero_span) */
};

/* Output bytes (all requested channels) from which region_xfast zeroes
   the surely empty part with non-temporal stores: past the per-core L2
   (0.5-2 MiB on current x86) and about a core's share of the L3 on common
   parts (the size class of glibc's memcpy threshold, 3/4 of the L3 per
   thread), such an output is not in the caches when the read returns
   anyway, so storing past them costs a reader nothing; smaller outputs
   (loom scan's tiles, ~1 MiB) stay cached for the reader that follows. */
#define NT_MIN ((size_t)4 << 20)

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

static void chunk_extent(loom_texture *t, struct tslot *s, struct xent *e, uint32_t lx0,
                         uint32_t ly, uint32_t cn, int64_t *ea, int64_t *eb);

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
			struct xent *e = loom__xent_enter(t, s, xb, yb);
			int64_t xe = e->x0 + t->b1 < g->hi[0] ? e->x0 + t->b1 : g->hi[0];
			k.kl = e->ex->kind;
			k.ngrp = e->ex->ngrp;
			k.tl = out->type ? xent_tlut(e) : NULL;
			for (int64_t y = yb; y < ye; y++)
				for (int64_t x = xb; x < xe;) {
					uint32_t lx = (uint32_t)(x - e->x0), n = group_len(t, e, lx, xe - x);
					size_t off = ((size_t)(y - g->lo[1]) * g->nx + (size_t)(x - g->lo[0])) *
					             g->nz;
					int64_t ea, eb;
					int e2;
					/* the group's rows outside its extent are zeroed
					   without reading their bricks (the group's output
					   columns are adjacent: one run when all are empty) */
					chunk_extent(t, s, e, lx, (uint32_t)(y - e->y0), n, &ea, &eb);
					if (ea < g->lo[2])
						ea = g->lo[2];
					if (eb > g->hi[2])
						eb = g->hi[2];
					if (ea >= eb) {
						sink_empty(&k, off, n * g->nz);
						x += n;
						continue;
					}
					for (uint32_t c = 0; c < n; c++) {
						sink_empty(&k, off + c * g->nz, (size_t)(ea - g->lo[2]));
						sink_empty(&k, off + c * g->nz + (size_t)(eb - g->lo[2]),
						           (size_t)(g->hi[2] - eb));
					}
					e2 = group_fill(t, s, e, lx, (uint32_t)(y - e->y0), n, ea, eb, &k,
					                off + (size_t)(ea - g->lo[2]), g->nz);
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
		copy_small(d, tmp, n);
	}
}
#endif

/* out[o + z*plane + c] = buf[c*RZ + z] for c < cn, z < zn (bytes).  The
   buffer holds RCOLS columns of RZ bytes: 16 x 16 blocks are read whole
   (stale bytes past cn or zn are read, never stored).  All column blocks of
   a z block are transposed first so that each output row is then written
   in one go (whole cache lines, whatever the row stride).  pf (voxels, 0:
   none): where the next chunk's rows are from these; each row written
   prefetches its lines there (for writing), so that their reads for
   ownership overlap this chunk and the next one's gather (the rows are a
   plane apart, 4 KiB and more: the hardware prefetchers, which stay in a
   page, never see them coming; ~10 % of the read, hot and fresh). */
static void tr_plane(uint8_t *restrict out, size_t o, size_t plane,
                     const uint8_t *restrict buf, size_t cn, size_t zn, ptrdiff_t pf)
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
			if (pf) {
				__builtin_prefetch(d + pf, 1);
				__builtin_prefetch(d + pf + cn - 1, 1);
			}
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

/* The same for orientation codes from their byte planes (pf in codes). */
static void tr_orient(uint16_t *restrict out, size_t o, size_t plane,
                      const uint8_t *restrict lo, const uint8_t *restrict hi, size_t cn,
                      size_t zn, ptrdiff_t pf)
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
			if (pf) {
				__builtin_prefetch(d + 2 * pf, 1);
				__builtin_prefetch(d + 2 * pf + 64, 1);
				__builtin_prefetch(d + 2 * pf + 2 * cn - 1, 1);
			}
			for (size_t k = 0; k < nb; k++) {
				__m128i p0 = _mm_unpacklo_epi8(a[k][j], b[k][j]);
				__m128i p1 = _mm_unpackhi_epi8(a[k][j], b[k][j]);
				if (k + 1 < nb || last == 16) {
					_mm_storeu_si128((__m128i *)(d + 32 * k), p0);
					_mm_storeu_si128((__m128i *)(d + 32 * k + 16), p1);
				} else {
					if (last >= 8) {
						_mm_storeu_si128((__m128i *)(d + 32 * k), p0);
						store_part(d + 32 * k + 16, p1, 2 * last - 16);
					} else {
						store_part(d + 32 * k, p0, 2 * last);
					}
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
   ng as in kt_ssse3; pf as in tr_plane. */
__attribute__((target("ssse3"))) static void
tr_label_kt(uint8_t *lab_out, uint8_t *kind, uint8_t *type, size_t o, size_t plane,
            const uint8_t *restrict buf, size_t cn, size_t zn, const uint8_t *kl,
            const uint8_t *tl, unsigned ng, ptrdiff_t pf)
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
			if (pf) {
				if (lab_out) {
					__builtin_prefetch(lab_out + r + pf, 1);
					__builtin_prefetch(lab_out + r + pf + cn - 1, 1);
				}
				if (kind) {
					__builtin_prefetch(kind + r + pf, 1);
					__builtin_prefetch(kind + r + pf + cn - 1, 1);
				}
				if (type) {
					__builtin_prefetch(type + r + pf, 1);
					__builtin_prefetch(type + r + pf + cn - 1, 1);
				}
			}
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
   source block (z - dz outside [0, b3)), in bricks stored as nothing, or,
   in a stored brick whose every-plane occupancy (t->occa) is known, at
   heights where the column's tile has no non-zero byte in any plane (an
   output voxel copies its nearer source voxel's planes, and a voxel whose
   nearer voxel is all zero is all zero).  At the paper scale the stored
   bricks' heights cover 50 % of a 64 x 64 x 300 tile, the tiles' 20 %.
   Empty when *ea >= *eb. */
static void chunk_extent(loom_texture *t, struct tslot *s, struct xent *e, uint32_t lx0,
                         uint32_t ly, uint32_t cn, int64_t *ea, int64_t *eb)
{
	int64_t b3 = t->b3, bz = t->bs[2], a = INT64_MAX, b = INT64_MIN;
	uint32_t sy = e->sy0 + ly;
	const _Atomic uint16_t *occa = t->region_no_occ ? NULL : t->occa;
	size_t trow = occa ? (size_t)in_brick(t, 1, sy) / OCC_T * t->occ_tx : 0;

	for (uint32_t c = 0; c < cn;) {
		uint32_t n = group_len(t, e, lx0 + c, cn - c), sx = e->sx0 + lx0 + c;
		uint32_t tx0 = in_brick(t, 0, sx) / OCC_T;
		uint32_t ntl = (in_brick(t, 0, sx) + n - 1) / OCC_T - tx0 + 1;
		uint64_t base = e->ex->first_brick +
		                ((uint64_t)brick_of(t, 1, sy) * e->ex->nb[0] + brick_of(t, 0, sx)) *
		                        e->ex->nb[2];
		/* the source heights [slo, shi) that may hold a non-zero byte,
		   per occupancy tile of the group (whole bricks without a table) */
		int64_t slo[GMAX / OCC_T + 1], shi[GMAX / OCC_T + 1];
		for (uint32_t i = 0; i < ntl; i++)
			slo[i] = INT64_MAX, shi[i] = INT64_MIN;
		for (uint32_t kz = 0; kz < e->ex->nb[2]; kz++) {
			uint64_t id = base + kz;
			const _Atomic uint16_t *ot;
			if (brick_empty(t, id))
				continue;
			ot = occa ? occa + (size_t)stored_rank(t, id) * t->occ_nt + trow + tx0 : NULL;
			for (uint32_t i = 0; i < ntl; i++) {
				unsigned v = ot ? atomic_load_explicit(&ot[i], memory_order_relaxed) : 0;
				int64_t l = kz * bz, h = l + bz;
				if (v) { /* known: lo | (hi + 1) << 8, hi + 1 = 0 for none */
					if (!(v >> 8))
						continue;
					h = l + (v >> 8);
					l += v & 0xffu;
				}
				if (l < slo[i])
					slo[i] = l;
				if (h > shi[i])
					shi[i] = h;
			}
		}
		for (uint32_t q = c; q < c + n; q++) {
			uint32_t i = (in_brick(t, 0, e->sx0 + lx0 + q)) / OCC_T - tx0;
			int f;
			int64_t dz, lo, hi;
			if (slo[i] >= shi[i])
				continue;
			dz = dz_split(xent_dz(t, s, e, lx0 + q, ly), &f);
			lo = slo[i] + dz;
			hi = shi[i] + dz + (f != 0);
			if (lo < dz)
				lo = dz;
			if (hi > b3 + dz + (f != 0))
				hi = b3 + dz + (f != 0);
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

/* n zero bytes at d; with stream, the whole 64-byte lines inside through
   non-temporal stores (no read for ownership of lines about to be
   overwritten whole; region_xfast fences), the partial lines at either
   end as zero_row does. */
static inline void zero_span(uint8_t *d, size_t n, int stream)
{
#ifdef __SSE2__
	size_t h = (size_t)(-(uintptr_t)d & 63);
	if (stream && n >= h + 64) {
		const __m128i z = _mm_setzero_si128();
		uint8_t *e = d + h + (n - h) / 64 * 64;
		zero_row(d, h);
		for (uint8_t *p = d + h; p < e; p += 64) {
			_mm_stream_si128((__m128i *)p, z);
			_mm_stream_si128((__m128i *)(p + 16), z);
			_mm_stream_si128((__m128i *)(p + 32), z);
			_mm_stream_si128((__m128i *)(p + 48), z);
		}
		zero_row(e, (size_t)(d + n - e));
		return;
	}
#else
	(void)stream;
#endif
	zero_row(d, n);
}

/* Zero the x-fastest output over [xa, xb) x [ya, yb) x [za, zb) (every
   requested channel), plane by plane; rows after row, or one span per
   plane when the rows are the output's whole rows (adjacent). */
static void zero_rect(const loom_texture_region *out, const struct region *g, int64_t xa,
                      int64_t xb, int64_t ya, int64_t yb, int64_t za, int64_t zb)
{
	size_t cn = (size_t)(xb - xa), ny = (size_t)(yb - ya);

	if (cn == g->nx) { /* whole rows: the ny rows of a plane are adjacent */
		cn *= ny;
		ny = 1;
	}
	for (int64_t z = za; z < zb; z++)
		for (size_t y = 0; y < ny; y++) {
			size_t r = (size_t)(z - g->lo[2]) * g->plane +
			           ((size_t)(ya - g->lo[1]) + y) * g->nx + (size_t)(xa - g->lo[0]);
			if (out->density)
				zero_span(out->density + r, cn, g->stream);
			if (out->orientation)
				zero_span((uint8_t *)(out->orientation + r), 2 * cn, g->stream);
			if (out->label)
				zero_span(out->label + r, cn, g->stream);
			if (out->kind)
				zero_span(out->kind + r, cn, g->stream);
			if (out->type)
				zero_span(out->type + r, cn, g->stream);
		}
}

/* The label -> kind and label -> type tables of an x-fastest chunk column
   (a local copy: the crossing entries of its pieces may be recycled while
   it is read), shared by all its pieces when same is set. */
struct xtabs {
	int same;                /* every piece has the same exemplar and types */
	const struct exm *ex;    /* the first piece's exemplar */
	uint8_t tok[4];          /* and its yarn types by kind */
	uint8_t tlut[256];       /* label -> type of the first piece */
};

/* One chunk of the x-fastest output: columns [x, xc) of row y, which may
   span several crossing pieces, z values [zc, zc + zn) within [0, b3):
   the rows where the whole chunk is surely empty (ext, in whole 16-row
   steps) are zeroed; the rest is gathered piece by piece and group by
   group into the thread's buffer and transposed once for the chunk, so
   that every output row of the chunk is written whole (a chunk is a whole
   64-byte line of each byte plane when the output is aligned; a piece at
   a time wrote parts of lines that were evicted before the neighbouring
   piece wrote the rest, and paid partial 16-column transposes at each
   piece's edges).  pf: the next chunk's rows from this one's (voxels, 0:
   none; tr_plane). */
static int xchunk(loom_texture *t, struct tslot *s, const struct region *g,
                  const struct sink *k0, const struct xtabs *tb, int kt_after, int64_t x,
                  int64_t xc, int64_t y, int64_t zc, size_t zn, const int64_t *ext,
                  ptrdiff_t pf)
{
	const loom_texture_region *out = g->out;
	const uint8_t *rd = s->rbuf, *rlo = rd + RCOLS * RZ, *rhi = rlo + RCOLS * RZ;
	const uint8_t *rl = rhi + RCOLS * RZ, *rk = rl + RCOLS * RZ, *rt = rk + RCOLS * RZ;
	size_t cn = (size_t)(xc - x), za, zb;
	size_t o = (size_t)(zc - g->lo[2]) * g->plane + (size_t)(y - g->lo[1]) * g->nx +
	           (size_t)(x - g->lo[0]);
	int64_t ea = ext[0], eb = ext[1];
	int rc = LOOM_OK;
	struct sink k = *k0;

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
		struct xent *e = loom__xent_enter(t, s, q, y);
		int64_t qe = e->x0 + t->b1 < xc ? e->x0 + t->b1 : xc;
		if (!kt_after) { /* kind and type gathered with this piece's tables */
			k.kl = e->ex->kind;
			k.ngrp = e->ex->ngrp;
			k.tl = out->type ? xent_tlut(e) : NULL;
		}
		while (q < qe) {
			uint32_t lx = (uint32_t)(q - e->x0);
			uint32_t n = group_len(t, e, lx, qe - q);
			int e2 = group_fill(t, s, e, lx, (uint32_t)(y - e->y0), n, zc + (int64_t)za,
			                    zc + (int64_t)zb, &k, (size_t)(q - x) * RZ + za, RZ);
			if (e2 != LOOM_OK && rc == LOOM_OK)
				rc = e2;
			q += n;
		}
	}
	o += za * g->plane;
	rd += za, rlo += za, rhi += za, rl += za, rk += za, rt += za;
	zn = zb - za;
	if (out->density)
		tr_plane(out->density, o, g->plane, rd, cn, zn, pf);
	if (out->orientation)
		tr_orient(out->orientation, o, g->plane, rlo, rhi, cn, zn, pf);
#ifdef HAVE_TR_KT
	if (kt_after) {
		tr_label_kt(out->label, out->kind, out->type, o, g->plane, rl, cn, zn,
		            tb->ex->kind, out->type ? tb->tlut : NULL, tb->ex->ngrp, pf);
		return rc;
	}
#else
	(void)tb;
#endif
	if (out->label)
		tr_plane(out->label, o, g->plane, rl, cn, zn, pf);
	if (out->kind)
		tr_plane(out->kind, o, g->plane, rk, cn, zn, pf);
	if (out->type)
		tr_plane(out->type, o, g->plane, rt, cn, zn, pf);
	return rc;
}

/* Rows of a crossing band whose chunk extents region_xfast keeps, at most
   (4 KiB of stack); past it they are computed again for every slab. */
#define XEXT 256

/* The extent (chunk_extent) of columns [x, xc) of row y over the crossing
   pieces they span: the union of the pieces'. */
static void xchunk_extent(loom_texture *t, struct tslot *s, int64_t x, int64_t xc,
                          int64_t y, int64_t *ea, int64_t *eb)
{
	*ea = INT64_MAX, *eb = INT64_MIN;
	for (int64_t q = x; q < xc;) {
		struct xent *e = loom__xent_enter(t, s, q, y);
		int64_t qe = e->x0 + t->b1 < xc ? e->x0 + t->b1 : xc, a, b;
		chunk_extent(t, s, e, (uint32_t)(q - e->x0), (uint32_t)(y - e->y0),
		             (uint32_t)(qe - q), &a, &b);
		if (a < b && a < *ea)
			*ea = a;
		if (a < b && b > *eb)
			*eb = b;
		q = qe;
	}
}

/* Whether the pieces spanning columns [x, xc) of band row y share their
   kind and type tables (tb keeps the first piece's). */
static void xchunk_tabs(loom_texture *t, struct tslot *s, int64_t x, int64_t xc, int64_t y,
                        struct xtabs *tb)
{
	tb->same = 1;
	tb->ex = NULL;
	for (int64_t q = x; q < xc;) {
		struct xent *e = loom__xent_enter(t, s, q, y);
		if (!tb->ex) {
			tb->ex = e->ex;
			memcpy(tb->tok, e->tok, 4);
			memcpy(tb->tlut, xent_tlut(e), 256);
		} else if (e->ex != tb->ex || memcmp(e->tok, tb->tok, 4)) {
			tb->same = 0;
		}
		q = e->x0 + t->b1;
	}
}

/* x-fastest: band of crossing rows by band; per band, chunk columns of up
   to RCOLS output columns (each may span several crossing pieces: xchunk);
   per chunk column, slabs of RZ z values (outermost, so the rows written
   meanwhile stay few whatever the plane size), rows (each row's extent
   computed once per chunk column, not per slab).  z planes outside
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
	struct xtabs tb;
	int64_t ext[2 * XEXT];

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
		int keep;
		if (ye > g->hi[1])
			ye = g->hi[1];
		keep = ye - yb <= XEXT;
		for (int64_t x = g->lo[0]; x < g->hi[0]; x += RCOLS) {
			int64_t xc = g->hi[0] - x > RCOLS ? x + RCOLS : g->hi[0];
			/* kind and type: from the transposed labels (PSHUFB) when
			   every piece of the chunk column has the same tables, else
			   gathered and transposed like the other planes */
			int kt_after = 0;
			xchunk_tabs(t, s, x, xc, yb, &tb);
#ifdef HAVE_TR_KT
			kt_after = tb.same && t->ssse3 && tb.ex->ngrp && (out->kind || out->type);
#endif
			k.rl = out->label || kt_after ? rl : NULL;
			k.rk = out->kind && !kt_after ? rk : NULL;
			k.rt = out->type && !kt_after ? rt : NULL;
			/* z rows where the whole chunk column is surely empty:
			   zeroed plane by plane, row after row (sequential); the
			   slabs cover the rest */
			int64_t pa = INT64_MAX, pb = INT64_MIN, zs = za0, ze = zb0;
			for (int64_t y = yb; y < ye; y++) {
				int64_t a, b;
				xchunk_extent(t, s, x, xc, y, &a, &b);
				if (keep) {
					ext[2 * (y - yb)] = a;
					ext[2 * (y - yb) + 1] = b;
				}
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
			zero_rect(out, g, x, xc, yb, ye, za0, zs);
			zero_rect(out, g, x, xc, yb, ye, ze, zb0);
			for (int64_t zc = zs; zc < ze; zc += RZ) {
				size_t zn = ze - zc < RZ ? (size_t)(ze - zc) : RZ;
				for (int64_t y = yb; y < ye; y++) {
					int64_t e1[2];
					int e2;
					if (!keep) {
						xchunk_extent(t, s, x, xc, y, &e1[0], &e1[1]);
					} else {
						e1[0] = ext[2 * (y - yb)];
						e1[1] = ext[2 * (y - yb) + 1];
					}
					/* the next chunk's rows, from this one's (voxels):
					   the next band row's, or the next slab's first */
					ptrdiff_t pf = 0;
					if (y + 1 < ye)
						pf = (ptrdiff_t)g->nx;
					else if (zc + 2 * RZ <= ze) /* a whole slab */
						pf = (ptrdiff_t)(RZ * g->plane) -
						     (ptrdiff_t)(ye - 1 - yb) * (ptrdiff_t)g->nx;
					e2 = xchunk(t, s, g, &k, &tb, kt_after, x, xc, y, zc, zn, e1, pf);
					if (e2 != LOOM_OK && rc == LOOM_OK)
						rc = e2;
				}
			}
		}
		yb = ye;
	}
#ifdef __SSE2__
	if (g->stream)
		_mm_sfence(); /* the non-temporal stores visible before we return */
#endif
	return rc;
}

LOOM_API int loom_texture_read_region(loom_texture *t, const int64_t lo[3],
                                      const int64_t hi[3],
                                      const loom_texture_region *out)
{
	struct region g;
	struct tslot *s;
	size_t total, bpv;
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
	bpv = (size_t)!!out->density + 2 * (size_t)!!out->orientation + (size_t)!!out->label +
	      (size_t)!!out->kind + (size_t)!!out->type;
	g.stream = bpv && total >= (NT_MIN + bpv - 1) / bpv;
	s = slot_enter(t);
	rc = out->layout == LOOM_REGION_Z_FASTEST ? region_zfast(t, s, &g) :
	                                            region_xfast(t, s, &g);
	bump(&s->cnt.lookups, total);
	slot_leave(t, s);
	return rc;
}

void loom__texture_region_whole(loom_texture *t, int on)
{
	if (t)
		t->region_whole = on != 0;
}

int loom__texture_line_blend(int path, unsigned bz, const uint8_t *line, unsigned lo,
                             unsigned hi, unsigned nv, int dir, unsigned g, unsigned pn,
                             int more, unsigned solid, uint8_t *out)
{
#ifdef __SSE2__
	struct fcol F = {0};
	int avx512 = 0, avx2 = 0;

	if (bz % SEG_Z || bz > 64 || !bz || lo >= hi || hi > nv || nv > bz || !dir || !g ||
	    g > DZ_SUB / 2 || !solid || solid > 255 || path < 0 || path > 3)
		return -1;
#ifdef HAVE_LINE_512
	avx512 = cpu_line512();
	avx2 = cpu_line256();
#endif
	if (path == 3 ? !avx2 || bz != 64 : path && (!avx512 || bz != 64))
		return -1;
	F.dir = (int8_t)(dir > 0 ? 1 : -1);
	F.g = (uint8_t)g;
#ifdef HAVE_LINE_512
	if (path == 2)
		line_copy_blend_512(&F, out, line, lo, hi, nv, more, pn != 0, (uint8_t)solid);
	else if (path == 3)
		line_copy_blend_256(&F, out, line, lo, hi, nv, more, pn != 0, (uint8_t)solid);
	else
#endif
	{
		memcpy(out, line + lo, hi - lo);
		line_blend(&F, out, line, bz, lo, hi, nv, more, pn != 0, (uint8_t)solid, path == 1);
	}
	return F.pend != NULL;
#else
	(void)path, (void)bz, (void)line, (void)lo, (void)hi, (void)nv, (void)dir, (void)g;
	(void)pn, (void)more, (void)solid, (void)out;
	return -1;
#endif
}

void loom__texture_region_occ(loom_texture *t, int on)
{
	if (t)
		t->region_no_occ = on == 0;
}

void loom__texture_occ_tiles(const loom_texture *t, uint64_t *known, uint64_t *narrow)
{
	*known = *narrow = 0;
	if (!t || !t->occa)
		return;
	for (size_t i = 0; i < (size_t)t->n_stored * t->occ_nt; i++) {
		unsigned v = atomic_load_explicit(&t->occa[i], memory_order_relaxed);
		if (!v)
			continue;
		++*known;
		*narrow += (v >> 8) == 0 || (v & 0xffu) > 0 || (v >> 8) < t->bs[2];
	}
}

void loom__texture_simd(loom_texture *t, int on)
{
	if (!t)
		return;
	t->ssse3 = 0;
	t->avx512 = 0;
	t->avx2 = 0;
#ifdef HAVE_KT_SSSE3
	if (on) {
		__builtin_cpu_init();
		t->ssse3 = __builtin_cpu_supports("ssse3") != 0;
#ifdef HAVE_LINE_512
		t->avx512 = on == 1 && cpu_line512();
		t->avx2 = on <= 2 && cpu_line256();
#endif
	}
#else
	(void)on;
#endif
}

