/* bench/bench_layout.c - what the byte layout inside a brick costs
   trilinear samples along rays, with nothing of loom's lookup around it
   (docs/performance.md, "Lines per step"; bench/ray_lines.py models the
   same in cache lines).

   Data: a 1024 x 1024 x 128 volume of density bytes (a 70-voxel slab of
   cloth, 3 voxels in 8 non-zero, the rest air) in 16 x 16 x 64 bricks,
   each layout in its own 128 MiB slab whose bricks are placed in a
   shuffled order (as a brick cache holds them), found through a table of
   brick pointers:
     z lines   loom's bricks today: z fastest, a 64-byte line is one
               column's 64 z;
     2x2x16    64-byte tiles of a 2 x 2 group of columns, 16 z;
     4x4x4     64-byte tiles of 4 x 4 x 4 voxels.
   Rays: random start and direction, unit steps, up to 256 steps inside
   the volume (bench_vdb's rays); each sample is the trilinear blend of
   its 8 corner bytes, each corner found by brick pointer and offset.
   The three layouts run the same rays in turn, REPS times interleaved;
   per-core rates (samples over the thread's CPU seconds), medians, and
   each layout over z lines.  The sums must agree (exit 1 otherwise).
   Figures, never pass/fail.  About 10 s and 400 MiB. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_layout\n"
	"Trilinear samples along random unit-step rays over a 128 MiB byte volume\n"
	"in 16x16x64 bricks, the bytes of a brick in three layouts (z lines as\n"
	"loom's bricks, 2x2x16 tiles, 4x4x4 tiles); per-core rates, medians of 5\n"
	"interleaved repetitions, and each layout over z lines.  About 10 s and\n"
	"400 MiB.  Figures, never pass/fail (exit 1 if the layouts' sums differ).\n";

#define NX 1024
#define NY 1024
#define NZ 128
#define BX (NX / 16)
#define BY (NY / 16)
#define BZ (NZ / 64)
#define NB (BX * BY * BZ)
#define BRICK 16384
#define NRAYS 20000
#define STEPS 256
#define REPS 5
#define NLAY 3

static const char *const lay_name[NLAY] = {"z lines", "2x2x16 tiles", "4x4x4 tiles"};
static const char *const lay_key[NLAY] = {"z_lines", "tiles_2x2x16", "tiles_4x4x4"};

/* Byte of voxel (lx, ly, lz) of a brick in each layout. */
static inline size_t off_z(unsigned lx, unsigned ly, unsigned lz)
{
	return ((size_t)ly * 16 + lx) * 64 + lz;
}

static inline size_t off_2216(unsigned lx, unsigned ly, unsigned lz)
{
	return (((size_t)(ly >> 1) * 8 + (lx >> 1)) * 4 + (lz >> 4)) * 64 + (ly & 1) * 32 +
	       (lx & 1) * 16 + (lz & 15);
}

static inline size_t off_444(unsigned lx, unsigned ly, unsigned lz)
{
	return (((size_t)(ly >> 2) * 4 + (lx >> 2)) * 16 + (lz >> 2)) * 64 + (ly & 3) * 16 +
	       (lx & 3) * 4 + (lz & 3);
}

static inline size_t lay_off(int lay, unsigned lx, unsigned ly, unsigned lz)
{
	return lay == 0 ? off_z(lx, ly, lz) : lay == 1 ? off_2216(lx, ly, lz) : off_444(lx, ly, lz);
}

static uint64_t rng_state = 88172645463325252ull;

static uint64_t rnd(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

static double u01(void)
{
	return (double)(rnd() >> 11) * (1.0 / 9007199254740992.0);
}

/* The volume's byte at (x, y, z): cloth in 30 < z < 100. */
static uint8_t voxel(unsigned x, unsigned y, unsigned z)
{
	uint32_t h = x * 73856093u ^ y * 19349663u ^ z * 83492791u;
	h ^= h >> 13;
	h *= 0x5bd1e995u;
	h ^= h >> 15;
	return (z > 30 && z < 100 && (h & 7) < 3) ? (uint8_t)(h >> 24 | 1) : 0;
}

static uint8_t *bricks[NLAY][NB];
static double ray_o[NRAYS][3], ray_d[NRAYS][3];

/* The ray samples of one layout, body written out per layout so that the
   offset function is inlined. */
#define RAYS(OFF, TAB)                                                                   \
	do {                                                                             \
		for (int r = 0; r < NRAYS; r++) {                                        \
			double p[3] = {ray_o[r][0], ray_o[r][1], ray_o[r][2]};           \
			for (int s = 0; s < STEPS; s++) {                                \
				double f[3], d = 0;                                      \
				unsigned i[3];                                           \
				int in = 1;                                              \
				for (int a = 0; a < 3; a++) {                            \
					double u = p[a] - 0.5, fl = floor(u);           \
					long lim = a == 0 ? NX : a == 1 ? NY : NZ;     \
					f[a] = u - fl;                                   \
					if (fl < 0 || fl + 1 >= (double)lim)             \
						in = 0;                                  \
					i[a] = in ? (unsigned)fl : 0;                    \
				}                                                        \
				if (!in)                                                 \
					break;                                           \
				for (int c = 0; c < 8; c++) {                            \
					unsigned x = i[0] + (c >> 1 & 1), y = i[1] + (c >> 2 & 1); \
					unsigned z = i[2] + (c & 1);                     \
					double w = ((c >> 1 & 1) ? f[0] : 1 - f[0]) *    \
					           ((c >> 2 & 1) ? f[1] : 1 - f[1]) *    \
					           ((c & 1) ? f[2] : 1 - f[2]);          \
					const uint8_t *b = TAB[((y >> 4) * BX + (x >> 4)) * BZ + (z >> 6)]; \
					d += w * b[OFF(x & 15, y & 15, z & 63)];         \
				}                                                        \
				sum += d;                                                \
				n++;                                                     \
				for (int a = 0; a < 3; a++)                              \
					p[a] += ray_d[r][a];                             \
			}                                                                \
		}                                                                        \
	} while (0)

static double cpu_seconds(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
	static size_t perm[NB];
	uint8_t *slab[NLAY];
	double rate[NLAY][REPS], med[NLAY], sums[NLAY][REPS], load[3] = {0, 0, 0};
	long samples = 0;
	int bad = 0;

	bench_help(argc, argv, USAGE);
	if (argc > 1)
		bench_reject("bench_layout", argv[1], USAGE);
	for (int l = 0; l < NLAY; l++) {
		slab[l] = aligned_alloc(64, (size_t)NB * BRICK);
		if (!slab[l]) {
			fprintf(stderr, "bench_layout: out of memory (%d MiB a layout)\n",
			        NB * BRICK >> 20);
			return 1;
		}
	}
	for (size_t i = 0; i < NB; i++)
		perm[i] = i;
	for (size_t i = NB - 1; i > 0; i--) {
		size_t j = rnd() % (i + 1), t = perm[i];
		perm[i] = perm[j];
		perm[j] = t;
	}
	for (int l = 0; l < NLAY; l++)
		for (size_t i = 0; i < NB; i++)
			bricks[l][i] = slab[l] + perm[i] * BRICK;
	for (unsigned z = 0; z < NZ; z++)
		for (unsigned y = 0; y < NY; y++)
			for (unsigned x = 0; x < NX; x++) {
				uint8_t v = voxel(x, y, z);
				size_t id = ((size_t)(y / 16) * BX + x / 16) * BZ + z / 64;
				for (int l = 0; l < NLAY; l++)
					bricks[l][id][lay_off(l, x % 16, y % 16, z % 64)] = v;
			}
	for (int r = 0; r < NRAYS; r++) {
		double th = acos(2 * u01() - 1), ph = 2 * 3.14159265358979323846 * u01();
		ray_d[r][0] = sin(th) * cos(ph);
		ray_d[r][1] = sin(th) * sin(ph);
		ray_d[r][2] = cos(th);
		ray_o[r][0] = 1 + u01() * (NX - 2);
		ray_o[r][1] = 1 + u01() * (NY - 2);
		ray_o[r][2] = 31 + u01() * 68;
	}
	{
		FILE *f = fopen("/proc/loadavg", "r");
		if (f) {
			if (fscanf(f, "%lf %lf %lf", &load[0], &load[1], &load[2]) != 3)
				load[0] = load[1] = load[2] = 0;
			fclose(f);
		}
	}
	printf("bench_layout: trilinear rays over %d x %d x %d bytes in 16x16x64 bricks "
	       "(%d MiB a layout), %d rays of up to %d unit steps; load average %.2f %.2f %.2f\n",
	       NX, NY, NZ, NB * BRICK >> 20, NRAYS, STEPS, load[0], load[1], load[2]);
	for (int rep = 0; rep < REPS; rep++)
		for (int l = 0; l < NLAY; l++) {
			double sum = 0, t0;
			long n = 0;
			t0 = cpu_seconds();
			if (l == 0)
				RAYS(off_z, bricks[0]);
			else if (l == 1)
				RAYS(off_2216, bricks[1]);
			else
				RAYS(off_444, bricks[2]);
			rate[l][rep] = (double)n / (cpu_seconds() - t0);
			sums[l][rep] = sum;
			samples = n;
		}
	for (int l = 0; l < NLAY; l++) {
		double r[REPS];
		memcpy(r, rate[l], sizeof r);
		qsort(r, REPS, sizeof r[0], cmp_double);
		med[l] = r[REPS / 2];
		for (int rep = 0; rep < REPS; rep++)
			bad |= sums[l][rep] != sums[0][0];
	}
	printf("layout           M samples/s per core (median of %d)   / z lines\n", REPS);
	for (int l = 0; l < NLAY; l++) {
		printf("%-16s %8.2f %30.3f\n", lay_name[l], med[l] / 1e6, med[l] / med[0]);
		printf("{\"bench\":\"layout\",\"layout\":\"%s\",\"samples\":%ld,\"per_core\":%.0f,"
		       "\"vs_z_lines\":%.4f,\"sums_equal\":%s,\"load\":\"%.2f %.2f %.2f\"}\n",
		       lay_key[l], samples, med[l], med[l] / med[0], bad ? "false" : "true",
		       load[0], load[1], load[2]);
	}
	printf("sums %s\n", bad ? "DIFFER" : "equal");
	for (int l = 0; l < NLAY; l++)
		free(slab[l]);
	return bad;
}
