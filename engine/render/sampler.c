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
}

uint32_t loom__sobol32(uint32_t i, uint32_t dim)
{
	uint32_t x = 0;
	const uint32_t *v;

	pthread_once(&sobol_once, sobol_init);
	v = sobol_v[dim & 3u];
	i &= LD_MASK;
	for (int b = 0; i; b++, i >>= 1)
		if (i & 1u)
			x ^= v[b];
	return x;
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

/* A hash of seed s, nesting level `level` and the digits `prefix` that
   decide it (distinct (level, prefix) give distinct values for one s). */
static inline uint64_t node_hash(uint64_t s, uint32_t level, uint32_t prefix)
{
	uint64_t key = ((uint64_t)level << 32) | prefix;
	return fmix64(s ^ (key * 0x9e3779b97f4a7c15ull));
}

double loom__owen01(uint32_t x, uint64_t s)
{
	uint32_t hi = x >> (32 - LOOM__LD_BITS), y = 0;
	uint64_t tail;

	for (uint32_t b = 0; b < LOOM__LD_BITS; b++) {
		uint32_t bit = (hi >> (LOOM__LD_BITS - 1 - b)) & 1u;
		uint32_t prefix = b ? hi >> (LOOM__LD_BITS - b) : 0u;
		bit ^= (uint32_t)(node_hash(s, b, prefix) >> 63);
		y = (y << 1) | bit;
	}
	/* the digits below the nesting: uniform, one draw per cell */
	tail = node_hash(s, LOOM__LD_BITS, hi) >> (64 - (53 - LOOM__LD_BITS));
	return (double)(((uint64_t)y << (53 - LOOM__LD_BITS)) | tail) *
	       (1.0 / 9007199254740992.0);
}

uint32_t loom__ld_shuffle(uint32_t i, uint64_t s)
{
	uint32_t low = i & LD_MASK, out = 0;

	for (uint32_t j = 0; j < LOOM__LD_BITS; j++) {
		uint32_t above = j + 1 < LOOM__LD_BITS ? low >> (j + 1) : 0u;
		uint32_t bit = ((low >> j) & 1u) ^
		               (uint32_t)(node_hash(s, 32 + j, above) >> 63);
		out |= bit << j;
	}
	return (i & ~LD_MASK) | out;
}

void loom__ld_start(loom__ld *s, uint64_t pixel_seed, uint32_t index)
{
	s->seed = pixel_seed;
	s->index = index;
	s->group = ~0u;
	s->shuffled = 0;
}

double loom__ld_get(loom__ld *s, uint32_t dim)
{
	uint32_t g = dim >> 2, j = dim & 3u;
	uint64_t gs = fmix64(s->seed + (uint64_t)(g + 1) * 0xd1b54a32d192ed03ull);

	if (s->group != g) {
		s->group = g;
		s->shuffled = loom__ld_shuffle(s->index, gs);
	}
	return loom__owen01(loom__sobol32(s->shuffled, j),
	                    fmix64(gs ^ ((uint64_t)(j + 1) * 0x8cb92ba72f3d8dd7ull)));
}
