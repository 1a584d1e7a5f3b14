/*
 * engine/render/sampler.h - Owen-scrambled Sobol points for the path
 * tracer (docs/rendering.md, "Sampling").  Internal to libloom.
 *
 * Sample k of a pixel gets, for each dimension d, a number in [0, 1):
 * dimensions come in groups of four (g = d / 4), each group the first
 * four Sobol dimensions (Joe and Kuo's direction numbers) at a per-pixel,
 * per-group shuffled index (a nested scramble of k's low LOOM__LD_BITS
 * bits), each coordinate Owen-scrambled with a per-pixel, per-group,
 * per-dimension seed.  Both scrambles are hash-based nested scrambles
 * (Laine and Karras; Burley 2020): the digits are bit-reversed and run
 * through a few operations each of which changes a digit only as a
 * function of the seed and the digits above it, so every digit is
 * flipped by a pseudo-random function of those (a full Owen scramble
 * draws that function uniformly; this one is a hash of it, a few
 * multiplies instead of a hash per digit).  The 32 bits of a coordinate
 * are all scrambled; the Sobol points have LOOM__LD_BITS.  So for every
 * pixel the first 2^m samples of dimensions (4g, 4g+1) form a (0, m,
 * 2)-net and each single dimension is stratified into 2^m equal
 * intervals (m <= LOOM__LD_BITS), while every point on its own is uniform
 * in [0,1)^4 (to 32 bits) and groups are independent (all tested).
 * Everything is a pure function of (seed, pixel, k, d): no state, no
 * dependence on the thread or the order of evaluation.
 */
#ifndef LOOM_RENDER_SAMPLER_H
#define LOOM_RENDER_SAMPLER_H

#include <stdint.h>

#define LOOM__LD_BITS 20 /* scramble depth: stratified up to 2^20 spp */

/* Unscrambled Sobol dimension dim (0..3) of index i, top LOOM__LD_BITS
   bits of a 32-bit fraction (the lower bits zero). */
uint32_t loom__sobol32(uint32_t i, uint32_t dim);

/* Hash-based nested (Owen) scramble of the 32-bit fraction x, seed s:
   bit b (from the top) is flipped by a function of s and the bits above
   it.  Returns a double in [0, 1) (multiples of 2^-32). */
double loom__owen01(uint32_t x, uint64_t s);

/* The index shuffle: a nested scramble of the low LOOM__LD_BITS bits of
   i, each flipped by a function of s and the bits above it.  It
   maps every aligned block of 2^m indices onto an aligned block of 2^m
   (m <= LOOM__LD_BITS), and any aligned block of 2^m Sobol points is a
   net as the first 2^m are. */
uint32_t loom__ld_shuffle(uint32_t i, uint64_t s);

/* Per-sample state: the pixel's seed, the sample index and the shuffled
   index of the last group used. */
typedef struct loom__ld {
	uint64_t seed;
	uint32_t index;
	uint32_t group;   /* group whose seed and shuffled index are cached;
	                     ~0 = none */
	uint32_t shuffled;
	uint64_t gseed;
} loom__ld;

/* Start sample `index` of the pixel whose seed is pixel_seed. */
void loom__ld_start(loom__ld *s, uint64_t pixel_seed, uint32_t index);

/* Coordinate `dim` of the current sample, in [0, 1). */
double loom__ld_get(loom__ld *s, uint32_t dim);

#endif /* LOOM_RENDER_SAMPLER_H */
