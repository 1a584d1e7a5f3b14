/* bench/bench_cache.c - brick cache (engine/texture/cache.h) figures: get/release
   rates with 1 and 2 threads, hit rates for coherent and random streams at
   several budgets, each next to a baseline measured in the same run: the
   same bytes read straight from a plain in-memory array.

   Data: a 512 x 512 x 128 voxel volume of 1-byte voxels cut into 32^3
   bricks (1024 bricks of 32 KiB, 32 MiB).  The loader copies a brick out of
   the plain array (memcpy, no decompression: the figures are the cache's
   own overhead, not libdeflate's).  Streams, precomputed per thread:
     coherent  ray marches: random start and direction, 0.7-voxel steps,
               256 steps per ray (about 28 accesses per brick change);
     random    uniform voxels anywhere in the volume;
     hot       8 bricks in turn, 64 accesses each, voxels in their first
               2 KiB: all in L1, so the figure is the cache's own cost.
   Every access: get the brick, read one voxel, release; the baseline reads
   the same voxel from the array.  Sums are compared, so a wrong byte shows.
   Rates are given per core (accesses over the CPU seconds of the threads,
   best of REPS runs: the machine may be shared, and CPU time leaves out the
   time other processes hold the core) and over wall time (all threads).
   Output: a table on stdout and one JSON line per figure ("{...}").
   BENCH_CACHE_SCALE=0.1 shortens every run. */
#include "texture/cache.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_cache\n"
	"The brick cache's get/release rates (1 and 2 threads) and hit rates of\n"
	"coherent, random and hot streams at budgets 1-40 MiB, each next to the same\n"
	"reads from a plain array.  Figures, never pass/fail.\n"
	"Environment: BENCH_CACHE_SCALE=F multiplies every run's length (0.1: short).\n";

#define B 32                        /* brick edge, voxels */
#define BRICK ((size_t)B * B * B)   /* bytes */
#define NX 16                       /* bricks along x, y, z */
#define NY 16
#define NZ 4
#define N_BRICKS (NX * NY * NZ)
#define MIB ((size_t)1 << 20)

static uint8_t *g_volume;           /* N_BRICKS bricks, brick-major */
static double g_scale = 1.0;

struct access {
	uint32_t brick;
	uint32_t off;
};

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static double unit(uint64_t *s) /* [0,1) */
{
	*s = mix(*s);
	return (double)(*s >> 11) / 9007199254740992.0;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static struct access voxel(long x, long y, long z)
{
	long W = NX * B, H = NY * B, D = NZ * B;
	struct access a;
	x = ((x % W) + W) % W;
	y = ((y % H) + H) % H;
	z = ((z % D) + D) % D;
	a.brick = (uint32_t)((z / B) * NX * NY + (y / B) * NX + x / B);
	a.off = (uint32_t)((z % B) * B * B + (y % B) * B + x % B);
	return a;
}

/* kind: 0 random, 1 coherent, 2 hot (8 bricks in turn, 64 accesses each,
   voxels in the first 2 KiB: everything in L1, the cache's own cost) */
static struct access *make_stream(int kind, size_t n, uint64_t seed)
{
	struct access *s = malloc(n * sizeof *s);
	uint64_t r = seed;
	size_t i = 0;

	if (!s)
		return NULL;
	while (i < n) {
		if (kind == 2) {
			s[i].brick = (uint32_t)((i / 64 + seed) % 8 * 37);
			s[i].off = (uint32_t)(mix(seed + i) % 2048);
			i++;
		} else if (kind == 1) {
			double px = unit(&r) * NX * B, py = unit(&r) * NY * B, pz = unit(&r) * NZ * B;
			double th = acos(2 * unit(&r) - 1), ph = 2 * M_PI * unit(&r);
			double dx = 0.7 * sin(th) * cos(ph), dy = 0.7 * sin(th) * sin(ph),
			       dz = 0.7 * cos(th);
			for (int k = 0; k < 256 && i < n; k++, i++) {
				s[i] = voxel((long)floor(px), (long)floor(py), (long)floor(pz));
				px += dx, py += dy, pz += dz;
			}
		} else {
			s[i++] = voxel((long)(unit(&r) * NX * B), (long)(unit(&r) * NY * B),
			               (long)(unit(&r) * NZ * B));
		}
	}
	return s;
}

static int copy_load(void *ctx, uint64_t id, void *dst, void *scratch, loom_diag *diag)
{
	(void)ctx, (void)scratch;
	if (id >= N_BRICKS)
		return loom__fail(diag, LOOM_ERANGE, "bench: brick %llu", (unsigned long long)id);
	memcpy(dst, g_volume + id * BRICK, BRICK);
	return LOOM_OK;
}

struct run {
	loom__cache *c;             /* NULL: the baseline */
	const struct access *stream;
	size_t n;
	pthread_barrier_t *bar;
	uint64_t sum;
	int errors;
	double t0, t1;              /* this thread's start and end, wall */
	double cpu;                 /* this thread's CPU seconds in the loop */
};

static double cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void *run_thread(void *arg)
{
	struct run *r = arg;
	loom__cache_thread *th = NULL;
	uint64_t sum = 0;
	double c0;

	if (r->c && loom__cache_thread_attach(r->c, &th, NULL) != LOOM_OK)
		r->errors++;
	pthread_barrier_wait(r->bar);
	r->t0 = now_s();
	c0 = cpu_s();
	if (!r->c) {
		for (size_t i = 0; i < r->n; i++)
			sum += g_volume[(size_t)r->stream[i].brick * BRICK + r->stream[i].off];
	} else if (th) {
		for (size_t i = 0; i < r->n; i++) {
			const void *p;
			if (loom__cache_get(th, r->stream[i].brick, &p, NULL) != LOOM_OK) {
				r->errors++;
				continue;
			}
			sum += ((const uint8_t *)p)[r->stream[i].off];
			loom__cache_release(th, p);
		}
	}
	r->cpu = cpu_s() - c0;
	r->t1 = now_s();
	if (th)
		loom__cache_thread_detach(th);
	r->sum = sum;
	return NULL;
}

/* Seconds of one run: wall (first start to last end) and CPU (summed over
   the threads; time spent descheduled by other processes is not in it). */
struct timing {
	double wall, cpu;
};

/* Run n accesses per thread; returns the timing and the checksum. */
static struct timing timed(loom__cache *c, struct access **streams, int threads, size_t n,
                           uint64_t *sum, int *errors)
{
	pthread_t t[2];
	struct run r[2];
	pthread_barrier_t bar;
	double t0 = 1e300, t1 = 0;
	struct timing tm = {0, 0};

	pthread_barrier_init(&bar, NULL, (unsigned)threads);
	for (int i = 0; i < threads; i++) {
		r[i] = (struct run){c, streams[i], n, &bar, 0, 0, 0, 0, 0};
		pthread_create(&t[i], NULL, run_thread, &r[i]);
	}
	*sum = 0;
	*errors = 0;
	for (int i = 0; i < threads; i++) {
		pthread_join(t[i], NULL);
		*sum += r[i].sum;
		*errors += r[i].errors;
		t0 = r[i].t0 < t0 ? r[i].t0 : t0;
		t1 = r[i].t1 > t1 ? r[i].t1 : t1;
		tm.cpu += r[i].cpu;
	}
	pthread_barrier_destroy(&bar);
	tm.wall = t1 - t0;
	return tm;
}

/* Best of REPS runs, each measure on its own (the machine is shared: the
   minimum is the figure). */
#define REPS 7
static struct timing best_of(loom__cache *c, struct access **streams, int threads,
                             size_t n, uint64_t *sum, int *errors)
{
	struct timing best = {1e300, 1e300};
	for (int k = 0; k < REPS; k++) {
		struct timing t = timed(c, streams, threads, n, sum, errors);
		best.wall = t.wall < best.wall ? t.wall : best.wall;
		best.cpu = t.cpu < best.cpu ? t.cpu : best.cpu;
	}
	return best;
}

static loom__cache *open_cache(size_t budget, int tlc, unsigned stripes, unsigned threads)
{
	loom__cache_opts o = {0};
	loom__cache *c = NULL;
	loom_diag d = {0};

	o.budget_bytes = budget;
	o.brick_bytes = BRICK;
	o.load = copy_load;
	o.max_threads = threads;
	o.n_stripes = stripes;
	o.tlc_entries = tlc;
	if (loom__cache_open(&o, &c, &d) != LOOM_OK) {
		fprintf(stderr, "bench_cache: %s\n", d.message);
		exit(1);
	}
	return c;
}

/* get/release rate against the baseline, warm cache (everything fits). */
struct baseline {
	struct timing t;
	uint64_t sum;
};

static struct baseline baseline(struct access **streams, int threads, size_t n)
{
	struct baseline b;
	int err;
	b.t = best_of(NULL, streams, threads, n, &b.sum, &err);
	return b;
}

static void rate(const char *stream_name, struct access **streams, size_t n, int threads,
                 int tlc, unsigned stripes, size_t budget, struct baseline base)
{
	loom__cache *c = open_cache(budget, tlc, stripes, 2);
	loom__cache_stats st;
	uint64_t sum_c;
	int err_c, ok;
	struct timing tc;
	double total = (double)n * threads;
	double core_c, core_b, wall_c, wall_b;

	timed(c, streams, threads, n, &sum_c, &err_c); /* warm up */
	tc = best_of(c, streams, threads, n, &sum_c, &err_c);
	loom__cache_get_stats(c, &st);
	ok = sum_c == base.sum && !err_c;
	core_c = total / tc.cpu / 1e6;     /* per core: accesses per CPU second */
	core_b = total / base.t.cpu / 1e6;
	wall_c = total / tc.wall / 1e6;    /* all threads together */
	wall_b = total / base.t.wall / 1e6;
	printf("%-9s %7d %4u %7u %10.1f %10.1f %7.3f %9.1f %9.1f %7.3f %8.4f %s\n",
	       stream_name, threads, st.tlc_entries, st.n_stripes, core_c, core_b,
	       core_c / core_b, wall_c, wall_b, wall_c / wall_b,
	       (double)st.hits / (double)st.lookups, ok ? "ok" : "MISMATCH");
	printf("{\"bench\":\"cache\",\"case\":\"rate\",\"stream\":\"%s\",\"threads\":%d,"
	       "\"tlc\":%u,\"stripes\":%u,\"budget_bytes\":%zu,\"accesses\":%.0f,"
	       "\"mops_per_core\":%.2f,\"baseline_mops_per_core\":%.2f,\"ratio_per_core\":%.4f,"
	       "\"ns_per_access\":%.2f,\"mops_wall\":%.2f,\"baseline_mops_wall\":%.2f,"
	       "\"ratio_wall\":%.4f,\"hit_rate\":%.5f,\"same_sum\":%s}\n",
	       stream_name, threads, st.tlc_entries, st.n_stripes, budget, total, core_c,
	       core_b, core_c / core_b, 1e3 / core_c, wall_c, wall_b, wall_c / wall_b,
	       (double)st.hits / (double)st.lookups, ok ? "true" : "false");
	loom__cache_close(c);
}

/* Hit rate and per-core rate from cold at a given budget (1 thread). */
static void hit_rate(const char *stream_name, struct access **streams, size_t n,
                     size_t budget, unsigned stripes)
{
	loom__cache *c = open_cache(budget, 0, stripes, 1);
	loom__cache_stats st;
	uint64_t sum_c, sum_b;
	int err_c, err_b, ok;
	struct timing tb, tc;
	double mc, mb;

	tb = best_of(NULL, streams, 1, n, &sum_b, &err_b);
	tc = timed(c, streams, 1, n, &sum_c, &err_c); /* from cold: once */
	loom__cache_get_stats(c, &st);
	mc = (double)n / tc.cpu / 1e6;
	mb = (double)n / tb.cpu / 1e6;
	ok = sum_c == sum_b && !err_c && st.peak_bytes <= budget;
	printf("%-9s %8.2f %7u %7u %8.4f %8.4f %9llu %9.1f %10.2f %10.1f %8.4f %8.2f %s\n",
	       stream_name, (double)budget / MIB, st.n_frames, st.n_stripes,
	       (double)st.hits / (double)st.lookups, (double)st.tlc_hits / (double)st.lookups,
	       (unsigned long long)st.evictions,
	       st.loads ? (double)st.load_ns / (double)st.loads / 1e3 : 0.0, mc, mb, mc / mb,
	       (double)st.peak_bytes / MIB, ok ? "ok" : "MISMATCH");
	printf("{\"bench\":\"cache\",\"case\":\"hit_rate\",\"stream\":\"%s\",\"budget_bytes\":%zu,"
	       "\"frames\":%u,\"stripes\":%u,\"accesses\":%zu,\"hit_rate\":%.5f,"
	       "\"tlc_hit_rate\":%.5f,\"loads\":%llu,\"evictions\":%llu,\"load_ms\":%.1f,\"mops_per_core\":%.3f,"
	       "\"baseline_mops_per_core\":%.2f,\"ratio_per_core\":%.5f,\"peak_bytes\":%llu,"
	       "\"same_sum\":%s}\n",
	       stream_name, budget, st.n_frames, st.n_stripes, n,
	       (double)st.hits / (double)st.lookups,
	       (double)st.tlc_hits / (double)st.lookups, (unsigned long long)st.loads,
	       (unsigned long long)st.evictions, (double)st.load_ns / 1e6, mc, mb, mc / mb,
	       (unsigned long long)st.peak_bytes, ok ? "true" : "false");
	loom__cache_close(c);
}

int main(int argc, char **argv)
{
	const char *sc = getenv("BENCH_CACHE_SCALE");
	size_t n_rate, n_hit;
	struct access *coh[2], *rnd[2], *hot[2];
	static const size_t budgets_mib[] = {1, 2, 4, 8, 16, 24, 40};

	bench_help(argc, argv, USAGE);
	if (argc > 1)
		bench_reject("bench_cache", argv[1], USAGE);

	if (sc)
		g_scale = atof(sc);
	n_rate = (size_t)(2e6 * g_scale);
	n_hit = (size_t)(1e6 * g_scale);
	if (n_rate < 1000)
		n_rate = 1000;
	if (n_hit < 1000)
		n_hit = 1000;
	g_volume = malloc(N_BRICKS * BRICK);
	if (!g_volume)
		return 1;
	for (size_t i = 0; i < N_BRICKS * BRICK / 8; i++) {
		uint64_t w = mix(i);
		memcpy(g_volume + 8 * i, &w, 8);
	}
	for (int t = 0; t < 2; t++) {
		coh[t] = make_stream(1, n_rate, 1000 + (uint64_t)t);
		rnd[t] = make_stream(0, n_rate, 2000 + (uint64_t)t);
		hot[t] = make_stream(2, n_rate, 3000 + (uint64_t)t);
		if (!coh[t] || !rnd[t] || !hot[t])
			return 1;
	}

	{
		double load[1] = {-1};
		if (getloadavg(load, 1) < 1)
			load[0] = -1;
		printf("brick cache: %d bricks of %zu KiB (%zu MiB), loader = memcpy, "
		       "load average %.2f at start\n\n", N_BRICKS, BRICK / 1024,
		       N_BRICKS * BRICK / MIB, load[0]);
		printf("{\"bench\":\"cache\",\"case\":\"setup\",\"bricks\":%d,"
		       "\"brick_bytes\":%zu,\"loadavg\":%.2f,\"reps\":%d}\n", N_BRICKS, BRICK,
		       load[0], REPS);
	}
	printf("get + 1-voxel read + release, warm cache (48 MiB budget), Maccesses/s:\n"
	       "per core = accesses / CPU seconds of the threads; wall = all threads "
	       "together; array = the same voxels read from the plain array\n");
	printf("%-9s %7s %4s %7s %10s %10s %7s %9s %9s %7s %8s %s\n", "stream", "threads",
	       "tlc", "stripes", "core", "array", "ratio", "wall", "array", "ratio", "hitrate",
	       "check");
	for (int threads = 1; threads <= 2; threads++) {
		for (int s = 0; s < 3; s++) {
			struct access **st = s == 2 ? hot : s ? rnd : coh;
			const char *name = s == 2 ? "hot" : s ? "random" : "coherent";
			struct baseline b = baseline(st, threads, n_rate);
			if (threads == 1) { /* tlc size, one mutex */
				static const int ks[] = {-1, 1, 2, 4, 8};
				for (size_t k = 0; k < sizeof ks / sizeof ks[0]; k++)
					rate(name, st, n_rate, 1, ks[k], 1, 48 * MIB, b);
			} else { /* one mutex or four stripes, tlc off or auto */
				rate(name, st, n_rate, 2, -1, 1, 48 * MIB, b);
				rate(name, st, n_rate, 2, -1, 4, 48 * MIB, b);
				rate(name, st, n_rate, 2, 0, 1, 48 * MIB, b);
				rate(name, st, n_rate, 2, 0, 4, 48 * MIB, b);
			}
		}
	}

	printf("\nfrom cold, 1 thread, tlc auto, %zu accesses; per core Maccesses/s\n", n_hit);
	printf("%-9s %8s %7s %7s %8s %8s %9s %9s %10s %10s %8s %8s %s\n", "stream",
	       "budgetMB", "frames", "stripes", "hitrate", "tlc", "evictions", "us/load", "core",
	       "array", "ratio", "peakMB", "check");
	for (int s = 0; s < 2; s++) {
		for (size_t k = 0; k < sizeof budgets_mib / sizeof budgets_mib[0]; k++)
			hit_rate(s ? "random" : "coherent", s ? rnd : coh, n_hit,
			         budgets_mib[k] * MIB, 1);
		for (size_t k = 1; k < sizeof budgets_mib / sizeof budgets_mib[0]; k += 2)
			hit_rate(s ? "random" : "coherent", s ? rnd : coh, n_hit,
			         budgets_mib[k] * MIB, 4); /* striped CLOCK: same hit rate? */
	}

	for (int t = 0; t < 2; t++) {
		free(coh[t]);
		free(rnd[t]);
		free(hot[t]);
	}
	free(g_volume);
	return 0;
}
