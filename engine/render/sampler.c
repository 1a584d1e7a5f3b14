/*
 * engine/render/sampler.c - Owen-scrambled Sobol points per pixel for the
 * path tracer (sampler.h explains the construction; docs/rendering.md,
 * "Sampling", the user's view).
 */
#include "sampler.h"

#include <pthread.h>

#define LD_MASK ((1u << LOOM__LD_BITS) - 1u)

/* Direction numbers of the first four Sobol dimensions, top bits of a
   32-bit fraction: v[d][b] is what index bit b XORs in. */
static uint32_t sobol_v[4][LOOM__LD_BITS];
/* sobol_t[d][k][b]: the XOR of the direction numbers of the set bits of
   byte b of the index at byte position k (bits 8k..8k+7) */
static uint32_t sobol_t[4][3][256];
static pthread_once_t sobol_once = PTHREAD_ONCE_INIT;

/*
 * Dimension 0 is the van der Corput sequence (v_b = 2^-(b+1)).  The others
 * follow the primitive polynomials and initial numbers m_1..m_s of Joe
 * and Kuo's table (x + 1: m = 1; x^2 + x + 1: m = 1, 3; x^3 + x + 1:
 * m = 1, 3, 1) and the recurrence
 *     v_i = v_{i-s} ^ (v_{i-s} >> s) ^ XOR_{k=1..s-1} a_k v_{i-k}
 * with v_i = m_i / 2^i (i from 1).
 */
static void sobol_init(void)
{
	static const struct {
		int s;
		unsigned a;
		uint32_t m[3];
	} poly[3] = {{1, 0, {1, 0, 0}}, {2, 1, {1, 3, 0}}, {3, 1, {1, 3, 1}}};

	for (int b = 0; b < LOOM__LD_BITS; b++)
		sobol_v[0][b] = 1u << (31 - b);
	for (int d = 1; d < 4; d++) {
		int s = poly[d - 1].s;
		unsigned a = poly[d - 1].a;
		uint32_t *v = sobol_v[d];
		for (int i = 0; i < LOOM__LD_BITS; i++) {
			if (i < s) {
				v[i] = poly[d - 1].m[i] << (31 - i);
				continue;
			}
			v[i] = v[i - s] ^ (v[i - s] >> s);
			for (int k = 1; k < s; k++)
				if ((a >> (s - 1 - k)) & 1u)
					v[i] ^= v[i - k];
		}
	}
	for (int d = 0; d < 4; d++)
		for (int k = 0; k < 3; k++)
			for (uint32_t b = 0; b < 256; b++) {
				uint32_t x = 0;
				for (int j = 0; j < 8 && 8 * k + j < LOOM__LD_BITS; j++)
					if (b >> j & 1u)
						x ^= sobol_v[d][8 * k + j];
				sobol_t[d][k][b] = x;
			}
}

uint32_t loom__sobol32(uint32_t i, uint32_t dim)
{
	const uint32_t (*t)[256];

	pthread_once(&sobol_once, sobol_init);
	t = sobol_t[dim & 3u];
	i &= LD_MASK;
	return t[0][i & 255u] ^ t[1][(i >> 8) & 255u] ^ t[2][i >> 16];
}

static inline uint64_t fmix64(uint64_t x)
{
	x ^= x >> 33;
	x *= 0xff51afd7ed558ccdull;
	x ^= x >> 33;
	x *= 0xc4ceb9fe1a85ec53ull;
	x ^= x >> 33;
	return x;
}

static inline uint32_t rev32(uint32_t x)
{
	x = __builtin_bswap32(x);
	x = (x & 0x0f0f0f0fu) << 4 | (x >> 4 & 0x0f0f0f0fu);
	x = (x & 0x33333333u) << 2 | (x >> 2 & 0x33333333u);
	return (x & 0x55555555u) << 1 | (x >> 1 & 0x55555555u);
}

/*
 * A nested scramble of bit-reversed digits (Laine and Karras's
 * construction): adding, multiplying by an odd number and x ^= x * even
 * change bit k of r only as a function of bits 0..k, so on the reversed
 * value each digit is flipped by a function of the seed and the digits
 * above it.  Two operations take the seed, three fixed even multipliers
 * (the fractional parts of sqrt 2, 3, 5, made even) mix the lower digits
 * into the higher ones.
 */
static inline uint32_t nest(uint32_t r, uint64_t s)
{
	r ^= r * 0x6a09e666u;
	r += (uint32_t)s;
	r *= (uint32_t)(s >> 32) | 1u;
	r ^= r * 0xbb67ae84u;
	r ^= r * 0x3c6ef372u;
	return r;
}

double loom__owen01(uint32_t x, uint64_t s)
{
	return (double)rev32(nest(rev32(x), s)) * (1.0 / 4294967296.0);
}

uint32_t loom__ld_shuffle(uint32_t i, uint64_t s)
{
	/* bit j of the index is the top bit j of its reversal */
	return (i & ~LD_MASK) | (rev32(nest(rev32(i & LD_MASK), s)) & LD_MASK);
}

void loom__ld_start(loom__ld *s, uint64_t pixel_seed, uint32_t index)
{
	s->seed = pixel_seed;
	s->index = index;
	s->group = ~0u;
	s->shuffled = 0;
	s->gseed = 0;
}

double loom__ld_get(loom__ld *s, uint32_t dim)
{
	uint32_t g = dim >> 2, j = dim & 3u;

	if (s->group != g) {
		s->group = g;
		s->gseed = fmix64(s->seed + (uint64_t)(g + 1) * 0xd1b54a32d192ed03ull);
		s->shuffled = loom__ld_shuffle(s->index, s->gseed);
	}
	return loom__owen01(loom__sobol32(s->shuffled, j),
	                    fmix64(s->gseed ^ ((uint64_t)(j + 1) * 0x8cb92ba72f3d8dd7ull)));
}
