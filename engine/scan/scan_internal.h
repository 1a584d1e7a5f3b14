/*
 * engine/scan/scan_internal.h - helpers shared by the scan pipeline files
 * (engine/scan_*.c); never installed.
 */
#ifndef LOOM_SCAN_INTERNAL_H
#define LOOM_SCAN_INTERNAL_H

#include "core/internal.h"

#include <math.h>
#include <string.h>

/* A worker: runs part `tid` of `nthreads` of a job.  Workers must write
   disjoint outputs and partition work by tid only, so results do not depend
   on scheduling. */
typedef void (*loom__scan_job)(void *ctx, uint32_t tid, uint32_t nthreads);

/* Run fn for tid = 0..threads-1, tid 0 on the calling thread, the others on
   pthreads (run inline if a thread cannot be created).  threads 0 = 1. */
void loom__scan_parallel(uint32_t threads, loom__scan_job fn, void *ctx);

/* Normalised Gaussian kernel: w[0..2r], r = ceil(3 sigma) capped at
   LOOM__SCAN_MAX_RADIUS.  Returns r (0 for sigma <= 0: w[0] = 1). */
#define LOOM__SCAN_MAX_RADIUS 24
int loom__scan_gauss(float sigma, float w[2 * LOOM__SCAN_MAX_RADIUS + 1]);

/* splitmix64 step: returns the next value and advances *state. */
static inline uint64_t loom__scan_mix(uint64_t *state)
{
	uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
	return z ^ (z >> 31);
}

/* Uniform double in [0,1) from the generator. */
static inline double loom__scan_unif(uint64_t *state)
{
	return (double)(loom__scan_mix(state) >> 11) * (1.0 / 9007199254740992.0);
}

static inline size_t loom__scan_idx(const loom_scan_volume *v, uint32_t x,
                                    uint32_t y, uint32_t z)
{
	return ((size_t)z * v->ny + y) * v->nx + x;
}

/*
 * Vector kernels of the separable filters: o[i] = w*s[i] and o[i] += w*s[i]
 * over n floats, four lanes at a time with GCC/Clang vector extensions
 * (plain -O2 does not vectorise loops of unknown trip count).  Each lane
 * does the scalar tail's arithmetic (one multiply, one add, no fused
 * multiply-add), so results do not depend on alignment or on n.
 */
#if defined(__GNUC__)
typedef float loom__v4 __attribute__((vector_size(16)));

static inline void loom__scan_scale(float *o, const float *s, float w, size_t n)
{
	loom__v4 wv = {w, w, w, w}, a;
	size_t i = 0;
	for (; i + 4 <= n; i += 4) {
		memcpy(&a, s + i, sizeof a);
		a = wv * a;
		memcpy(o + i, &a, sizeof a);
	}
	for (; i < n; i++)
		o[i] = w * s[i];
}

static inline void loom__scan_axpy(float *o, const float *s, float w, size_t n)
{
	loom__v4 wv = {w, w, w, w}, a, b;
	size_t i = 0;
	for (; i + 4 <= n; i += 4) {
		memcpy(&a, o + i, sizeof a);
		memcpy(&b, s + i, sizeof b);
		a = a + wv * b;
		memcpy(o + i, &a, sizeof a);
	}
	for (; i < n; i++)
		o[i] += w * s[i];
}
#else
static inline void loom__scan_scale(float *o, const float *s, float w, size_t n)
{
	for (size_t i = 0; i < n; i++)
		o[i] = w * s[i];
}

static inline void loom__scan_axpy(float *o, const float *s, float w, size_t n)
{
	for (size_t i = 0; i < n; i++)
		o[i] += w * s[i];
}
#endif

/* Decoded orientation codes: 3 floats per code (loom__orient_decode of
   voxel.h), code 0 decoded as the zero vector (undefined).  Built once,
   thread-safe. */
const float *loom__scan_code_lut(void);

/* Orientation of voxel i: from v->orient, else from v->ocode (lut from
   loom__scan_code_lut), else zero. */
static inline void loom__scan_dir(const loom_scan_volume *v, const float *lut,
                                  size_t i, float o[3])
{
	const float *s;
	if (v->orient)
		s = v->orient + 3 * i;
	else if (v->ocode)
		s = lut + 3 * (size_t)v->ocode[i];
	else
		s = lut; /* code 0: zero */
	o[0] = s[0];
	o[1] = s[1];
	o[2] = s[2];
}

/* Allocate n bytes for a large array (2 MiB aligned, transparent huge
   pages requested: far fewer page faults when it is first written), zeroed
   if zero.  Free with free(). */
void *loom__scan_alloc_big(size_t n, int zero);

/* Check a volume's sizes and density pointer; names `what` in messages. */
int loom__scan_check_volume(const loom_scan_volume *v, const char *what,
                            loom_diag *diag);

/* Track every yarn from its endpoint (warps first), in parallel; checks
   that no two neighbours ended on the same yarn.  curves has we->k + fe->k
   entries; released on failure. */
int loom__scan_track_all(const loom_scan_volume *v, const loom_scan_endpoints *we,
                         const loom_scan_endpoints *fe, float thr,
                         const loom_scan_track_lengths *lw,
                         const loom_scan_track_lengths *lf, uint32_t threads,
                         loom_scan_curve *curves, loom_diag *diag);

#endif /* LOOM_SCAN_INTERNAL_H */
