/*
 * bench/bench_texture.c - virtual-texture figures (docs/engine.md), each
 * next to a baseline measured in the same run:
 *
 *   1. warm lookups in a window of the bolt, nearest filter, per core:
 *      coherent (ray marches) and random, loom_texture_voxel against a
 *      dense in-memory array of the same voxels (materialised from the
 *      texture) looked up the same way (a non-inlined call per voxel that
 *      fills the same loom_texel: density, orientation decode, kind, type,
 *      albedo).  Checksums of both must agree.
 *   2. region reads (64 x 64 x b3 tiles, x and z fastest, all five
 *      channels and density alone) in voxels/s against memcpy of the same
 *      bytes, against copying the tile out of the dense array, and against
 *      the same reads with whole-voxel offsets (every column copied with
 *      its nearer whole offset, no sub-voxel blend: issue 13's peer).
 *   3. from cold, per budget (8 MiB .. 1 GiB): coherent and random lookups
 *      over a whole design repeat, rates per core and hit rates.
 *   4. peak resident memory (VmHWM) of `loom sample --random` on a
 *      paper-scale fabric at budgets 16, 64 and 256 MiB, one process each.
 *   5. streamed regions, as `loom scan` reads them: every voxel of 8 x 8
 *      crossings in quarter-crossing tiles, all channels, 1 and 2 threads,
 *      budgets 16 and 64 MiB, both layouts, tiles in crossing-row order or
 *      grouped by source block; against memcpy of the same bytes into the
 *      same buffers; peak RSS (one child process per row).
 *
 * Data: the paper preset database ($LOOM_PAPER_DB, else
 * $BUILD/bench/paper.ldb, generated when missing: ~10-20 s) and a
 * 900 x 1500 Jacquard-like design (twill 2/3 and satin 4/1 over a blocky
 * random mask) synthesised with the default options.
 * Rates are per core: lookups over the thread's CPU seconds, best of REPS
 * (the machine is shared).  BENCH_TEXTURE_SCALE=0.2 shortens every run.
 * Output: tables on stdout and one JSON line per figure ("{...}").
 *
 *   build/bench/bench_texture [PARTS]    PARTS: digits of the parts to run
 *                                        (default 12345)
 *   build/bench/bench_texture --vdb-child ...   bench_vdb's loom child (below)
 */
#include "loom.h"
#include "texture/texture_internal.h" /* loom__texture_region_whole, _simd */

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_texture [PARTS]\n"
	"The virtual texture on the paper-scale fabric, each figure next to a\n"
	"baseline of the same run: 1 warm lookups, 2 region reads, 3 lookups from\n"
	"cold per budget, 4 peak memory of `loom sample`, 5 streamed regions.\n"
	"  PARTS      digits of the parts to run (default 12345)\n"
	"Environment: LOOM_PAPER_DB (default $BUILD/bench/paper.ldb, generated when\n"
	"missing), BENCH_TEXTURE_SCALE=F (0.2: short), BUILD (default build),\n"
	"BENCH_TEXTURE_SIMD=avx2|ssse3 (parts 1-2 as a host with AVX2 but not AVX-512,\n"
	"or SSSE3 but not AVX2, runs them).\n";

#define MIB ((size_t)1 << 20)
#define REPS 3

static double g_scale = 1.0;
static uint32_t B1, B2, B3;

/* ------------------------------------------------------------- helpers */

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static double unit(uint64_t *s) /* [0, 1) */
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

static double cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Twill 2/3 and satin 4/1 over a blocky random mask; warp types 0/1 by
   block, weft type 2. */
static loom_design *jacquard(uint32_t rows, uint32_t cols)
{
	loom_weave_params a, b;
	loom_design *d = NULL;

	loom_weave_parse("twill:2/3", &a, NULL);
	loom_weave_parse("satin:4/1", &b, NULL);
	if (loom_design_make(&a, rows, cols, &d, NULL) != LOOM_OK ||
	    loom_design_set_types(d, 3) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++) {
			uint64_t h = mix(((uint64_t)(i / 48) << 32) | (j / 64));
			size_t c = (size_t)i * cols + j;
			if (h & 1)
				d->weave[c] = (uint8_t)loom_weave_cell(&b, i, j);
			d->warp_type[c] = (uint8_t)(h >> 1 & 1);
			d->weft_type[c] = 2;
		}
	return d;
}

/* ------------------------------------------------------ the dense array */

typedef struct dvox {
	uint16_t o;
	uint8_t d, kind, type, label;
} dvox;

static struct {
	dvox *v;
	int64_t lo[3];
	size_t n[3];
	float dens[256];
	float albedo[256][3];
	float align[256];
} D;

/* Orientation code -> unit direction, z >= 0 (docs/formats.md, "Voxel
   encodings"), inline as in the library's lookups. */
static inline void orient_decode(uint16_t code, float v[3])
{
	float s = (float)(code & 0xff) / 127.5f - 1.0f;
	float t = (float)(code >> 8) / 127.5f - 1.0f;
	float px = 0.5f * (s + t), py = 0.5f * (s - t);
	float pz = 1.0f - fabsf(px) - fabsf(py), n;
	if (pz < 0)
		pz = 0;
	n = 1.0f / sqrtf(px * px + py * py + pz * pz);
	v[0] = px * n, v[1] = py * n, v[2] = pz * n;
}

/* One lookup of the dense array, filling the same texel as the texture.
   Not inlined: a call per voxel, like the library's. */
__attribute__((noinline)) static void dense_lookup(int64_t x, int64_t y, int64_t z,
                                                   loom_texel *out)
{
	uint64_t ix = (uint64_t)(x - D.lo[0]), iy = (uint64_t)(y - D.lo[1]),
	         iz = (uint64_t)(z - D.lo[2]);
	const dvox *v;

	memset(out, 0, sizeof *out);
	if (ix >= D.n[0] || iy >= D.n[1] || iz >= D.n[2])
		return;
	v = &D.v[(iz * D.n[1] + iy) * D.n[0] + ix];
	if (v->d) {
		out->density = D.dens[v->d];
		orient_decode(v->o, out->orientation);
	}
	out->label = v->label;
	out->kind = v->kind;
	if (v->kind) {
		out->type = v->type;
		memcpy(out->albedo, D.albedo[v->type], sizeof out->albedo);
		out->alignment = D.align[v->type];
	}
}

static int dense_build(loom_texture *t, const loom_design *d, const int64_t lo[3],
                       const int64_t hi[3])
{
	size_t n;
	loom_texture_region r;
	uint8_t *dn, *kd, *ty, *lb;
	uint16_t *or;
	int rc;

	for (int a = 0; a < 3; a++) {
		D.lo[a] = lo[a];
		D.n[a] = (size_t)(hi[a] - lo[a]);
	}
	n = D.n[0] * D.n[1] * D.n[2];
	D.v = malloc(n * sizeof *D.v);
	dn = malloc(n), kd = malloc(n), ty = malloc(n), lb = malloc(n);
	or = malloc(2 * n);
	if (!D.v || !dn || !kd || !ty || !lb || !or)
		return -1;
	memset(&r, 0, sizeof r); /* x fastest, as the dense array is indexed */
	r.density = dn, r.orientation = or, r.kind = kd, r.type = ty, r.label = lb;
	rc = loom_texture_read_region(t, lo, hi, &r);
	for (size_t i = 0; i < n; i++) {
		D.v[i].d = dn[i];
		D.v[i].o = or[i];
		D.v[i].kind = kd[i];
		D.v[i].type = ty[i];
		D.v[i].label = lb[i];
	}
	for (int k = 0; k < 256; k++)
		D.dens[k] = (float)k / 255.0f;
	for (uint32_t k = 0; k < d->n_types; k++) {
		memcpy(D.albedo[k], d->types[k].albedo, sizeof D.albedo[k]);
		D.align[k] = d->types[k].alignment;
	}
	free(dn), free(kd), free(ty), free(lb), free(or);
	return rc;
}

/* ------------------------------------------------------------- streams */

enum { S_COHERENT, S_RANDOM, S_REGION };
static const char *const stream_name[] = {"coherent", "random", "region"};

/* Parameters of a stream: positions inside [lo, hi). */
struct stream {
	int kind;
	int64_t lo[3], hi[3];
	uint64_t seed;
	uint64_t n;               /* lookups */
};

/* Run a stream through lookup fn (texture when t, else the dense array);
   returns the density checksum, *cpu the thread CPU seconds. */
static double run_stream(const struct stream *s, loom_texture *t, double *cpu,
                         uint64_t *errors)
{
	uint64_t st = s->seed, done = 0;
	double sum = 0, c0 = cpu_s();
	double ext[3];

	for (int a = 0; a < 3; a++)
		ext[a] = (double)(s->hi[a] - s->lo[a]);
	*errors = 0;
	while (done < s->n) {
		if (s->kind == S_RANDOM) {
			loom_texel tx;
			int64_t x = s->lo[0] + (int64_t)(unit(&st) * ext[0]);
			int64_t y = s->lo[1] + (int64_t)(unit(&st) * ext[1]);
			int64_t z = s->lo[2] + (int64_t)(unit(&st) * ext[2]);
			if (t)
				*errors += loom_texture_voxel(t, x, y, z, &tx) != LOOM_OK;
			else
				dense_lookup(x, y, z, &tx);
			sum += tx.density + tx.type;
			done++;
		} else {
			/* a ray: random start, random direction (mostly across the
			   cloth), 0.7-voxel steps, up to 256 steps inside the box */
			double p[3], dir[3], len = 0;
			for (int a = 0; a < 3; a++) {
				p[a] = (double)s->lo[a] + unit(&st) * ext[a];
				dir[a] = 2 * unit(&st) - 1;
				len += dir[a] * dir[a];
			}
			len = 0.7 / sqrt(len);
			for (int a = 0; a < 3; a++)
				dir[a] *= len;
			for (int k = 0; k < 256 && done < s->n; k++) {
				loom_texel tx;
				int64_t q[3];
				int in = 1;
				for (int a = 0; a < 3; a++) {
					q[a] = (int64_t)floor(p[a]);
					in &= q[a] >= s->lo[a] && q[a] < s->hi[a];
					p[a] += dir[a];
				}
				if (!in)
					break;
				if (t)
					*errors += loom_texture_voxel(t, q[0], q[1], q[2], &tx) != LOOM_OK;
				else
					dense_lookup(q[0], q[1], q[2], &tx);
				sum += tx.density + tx.type;
				done++;
			}
		}
	}
	*cpu = cpu_s() - c0;
	return sum;
}

/* ------------------------------------------------------ 1. warm lookups */

struct tjob {
	struct stream s;
	loom_texture *t;
	double cpu, sum;
	uint64_t errors;
};

static void *tjob_run(void *arg)
{
	struct tjob *j = arg;
	j->sum = run_stream(&j->s, j->t, &j->cpu, &j->errors);
	return NULL;
}

static void warm_lookups(loom_texture *t, const int64_t lo[3], const int64_t hi[3])
{
	printf("\n1. warm lookups, window %lldx%lldx%lld voxels, nearest, per core "
	       "(M lookups/s, best of %d)\n", (long long)(hi[0] - lo[0]),
	       (long long)(hi[1] - lo[1]), (long long)(hi[2] - lo[2]), REPS);
	printf("%-9s %7s %9s %9s %7s %s\n", "stream", "threads", "dense", "texture", "ratio",
	       "checksums");
	for (int k = 0; k < 2; k++)
		for (unsigned nt = 1; nt <= 2; nt++) {
			double best_d = 0, best_t = 0, sum_d = 0, sum_t = 0;
			uint64_t errors = 0;
			for (int rep = 0; rep < REPS; rep++) {
				struct tjob j[2];
				pthread_t th[2];
				for (int pass = 0; pass < 2; pass++) { /* dense, texture */
					double rate = 0;
					for (unsigned i = 0; i < nt; i++) {
						j[i].s.kind = k;
						memcpy(j[i].s.lo, lo, sizeof j[i].s.lo);
						memcpy(j[i].s.hi, hi, sizeof j[i].s.hi);
						j[i].s.seed = 1000 * rep + 17 * i + 1;
						j[i].s.n = (uint64_t)(g_scale * (k == S_COHERENT ? 4e6 : 2e6));
						j[i].t = pass ? t : NULL;
						pthread_create(&th[i], NULL, tjob_run, &j[i]);
					}
					for (unsigned i = 0; i < nt; i++) {
						pthread_join(th[i], NULL);
						rate += (double)j[i].s.n / j[i].cpu / nt;
						if (pass)
							sum_t += j[i].sum, errors += j[i].errors;
						else
							sum_d += j[i].sum;
					}
					if (pass && rate > best_t)
						best_t = rate;
					if (!pass && rate > best_d)
						best_d = rate;
				}
			}
			printf("%-9s %7u %9.2f %9.2f %7.3f %s%s\n", stream_name[k], nt, best_d / 1e6,
			       best_t / 1e6, best_t / best_d, sum_d == sum_t ? "equal" : "DIFFER",
			       errors ? " (errors!)" : "");
			printf("{\"bench\":\"texture_warm\",\"stream\":\"%s\",\"threads\":%u,"
			       "\"dense_per_core\":%.0f,\"texture_per_core\":%.0f,\"ratio\":%.4f,"
			       "\"checksums_equal\":%s}\n", stream_name[k], nt, best_d, best_t,
			       best_t / best_d, sum_d == sum_t ? "true" : "false");
		}
}

/* ------------------------------------------------------- 2. region reads */

/* Copy a tile of the dense array into x-fastest channel buffers. */
static void dense_tile(const int64_t a[3], size_t tile, size_t nz, const loom_texture_region *r)
{
	for (size_t z = 0; z < nz; z++)
		for (size_t y = 0; y < tile; y++) {
			const dvox *v = &D.v[((size_t)(a[2] - D.lo[2]) + z) * D.n[0] * D.n[1] +
			                     ((size_t)(a[1] - D.lo[1]) + y) * D.n[0] +
			                     (size_t)(a[0] - D.lo[0])];
			size_t o = (z * tile + y) * tile;
			for (size_t x = 0; x < tile; x++) {
				r->density[o + x] = v[x].d;
				if (r->orientation) {
					r->orientation[o + x] = v[x].o;
					r->kind[o + x] = v[x].kind;
					r->type[o + x] = v[x].type;
					r->label[o + x] = v[x].label;
				}
			}
		}
}

/* Point r's channels at buf (n voxels, bpv bytes each). */
static void region_at(loom_texture_region *r, uint8_t *buf, size_t n, int dens_only)
{
	r->density = buf;
	if (!dens_only) {
		r->orientation = (uint16_t *)(buf + n);
		r->kind = buf + 3 * n;
		r->type = buf + 4 * n;
		r->label = buf + 5 * n;
	}
}

static void region_reads(loom_texture *t, const int64_t lo[3], const int64_t hi[3])
{
	const size_t tile = 64, ring_bytes = (size_t)768 << 20;
	size_t nz = (size_t)(hi[2] - lo[2]), n = tile * tile * nz;
	uint8_t *buf = malloc(6 * n), *src = malloc(6 * n + 64), *ring = malloc(ring_bytes);

	if (!buf || !src || !ring) {
		printf("\n2. region reads: skipped (out of memory)\n");
		free(buf), free(src), free(ring);
		return;
	}
	printf("\n2. region reads, %zux%zux%zu tiles, M voxels/s per core (best of %d).\n"
	       "   memcpy: the same number of output bytes.  hot: every tile into the same\n"
	       "   buffer (it stays in cache); fresh: tiles into successive parts of a\n"
	       "   768 MiB ring (beyond the caches, as an export writes them).  whole: the\n"
	       "   same reads with whole-voxel offsets (no sub-voxel blend); s/w: texture\n"
	       "   over whole\n", tile, tile, nz, REPS + (REPS & 1));
	printf("%-9s %-9s %4s | %9s %9s %9s %6s %6s | %9s %9s %9s %6s %6s | %9s %6s\n",
	       "channels", "layout", "B/v", "memcpy", "texture", "whole", "ratio", "s/w", "memcpy",
	       "texture", "whole", "ratio", "s/w", "dense", "t/d");
	printf("%-24s | %-46s | %-46s |\n", "", "hot", "fresh");
	memset(src, 1, 6 * n + 64);
	memset(buf, 0, 6 * n);
	memset(ring, 0, ring_bytes); /* resident before timing */
	for (int cfg = 0; cfg < 4; cfg++) {
		int dens_only = cfg & 1, zf = cfg >> 1;
		size_t bpv = dens_only ? 1 : 6, tb = bpv * n, slots = ring_bytes / tb;
		/* memcpy hot, tex hot, memcpy fresh, tex fresh, dense, whole hot,
		   whole fresh; interleaved within each repetition, the texture and
		   whole-voxel reads (the same tiles) in turn first: the second to
		   read a repetition's tiles finds their bricks warm in the CPU's
		   caches, which biased s/w by up to 0.05 when whole always went
		   second (an A/A run, whole in both slots: 0.93-0.96 z fastest) */
		static const int order[2][7] = {{0, 1, 2, 3, 4, 5, 6}, {0, 5, 2, 6, 4, 1, 3}};
		double best[7] = {0, 0, 0, 0, 0, 0, 0};
		uint64_t next = 0;
		for (int rep = 0; rep < REPS + (REPS & 1); rep++) { /* as many of each order */
			int tiles = (int)(40 * g_scale) + 1;
			for (int mi = 0; mi < 7; mi++) {
				int m = order[rep & 1][mi];
				double c0 = cpu_s();
				uint64_t s = (uint64_t)rep * 77 + 5;
				int fresh = m == 2 || m == 3 || m == 6;
				if (m == 4 && zf)
					continue; /* the dense array is x fastest */
				loom__texture_region_whole(t, m >= 5);
				for (int k = 0; k < tiles; k++) {
					int64_t a[3], b[3];
					uint8_t *dst = fresh ? ring + (next++ % slots) * tb : buf;
					loom_texture_region r = {0};
					r.layout = zf ? LOOM_REGION_Z_FASTEST : LOOM_REGION_X_FASTEST;
					region_at(&r, dst, n, dens_only);
					a[0] = lo[0] + (int64_t)(unit(&s) * (double)((size_t)(hi[0] - lo[0]) - tile));
					a[1] = lo[1] + (int64_t)(unit(&s) * (double)((size_t)(hi[1] - lo[1]) - tile));
					a[2] = lo[2];
					b[0] = a[0] + (int64_t)tile, b[1] = a[1] + (int64_t)tile, b[2] = hi[2];
					if (m == 0 || m == 2)
						memcpy(dst, src + k % 61, tb);
					else if (m == 4)
						dense_tile(a, tile, nz, &r);
					else
						loom_texture_read_region(t, a, b, &r);
				}
				loom__texture_region_whole(t, 0);
				{
					double rate = (double)tiles * (double)n / (cpu_s() - c0);
					if (rate > best[m])
						best[m] = rate;
				}
			}
		}
		printf("%-9s %-9s %4zu | %8.0fM %8.0fM %8.0fM %6.3f %6.3f | %8.0fM %8.0fM %8.0fM "
		       "%6.3f %6.3f | ", dens_only ? "density" : "all five",
		       zf ? "z-fastest" : "x-fastest", bpv, best[0] / 1e6, best[1] / 1e6,
		       best[5] / 1e6, best[1] / best[0], best[1] / best[5], best[2] / 1e6,
		       best[3] / 1e6, best[6] / 1e6, best[3] / best[2], best[3] / best[6]);
		if (zf)
			printf("%9s %6s\n", "-", "-");
		else
			printf("%8.0fM %6.3f\n", best[4] / 1e6, best[1] / best[4]);
		printf("{\"bench\":\"texture_region\",\"channels\":\"%s\",\"layout\":\"%s\","
		       "\"bytes_per_voxel\":%zu,\"memcpy_hot\":%.0f,\"texture_hot\":%.0f,"
		       "\"ratio_hot\":%.4f,\"memcpy_fresh\":%.0f,\"texture_fresh\":%.0f,"
		       "\"ratio_fresh\":%.4f,\"dense\":%.0f,\"whole_hot\":%.0f,"
		       "\"whole_fresh\":%.0f,\"sub_over_whole_hot\":%.4f,"
		       "\"sub_over_whole_fresh\":%.4f}\n", dens_only ? "density" : "all",
		       zf ? "z" : "x", bpv, best[0], best[1], best[1] / best[0], best[2], best[3],
		       best[3] / best[2], best[4], best[5], best[6], best[1] / best[5],
		       best[3] / best[6]);
	}
	free(buf);
	free(src);
	free(ring);
}

/* --------------------------------------------------------- 3. budgets */

static void budgets(const loom_fabric *f, loom_db *db)
{
	static const size_t mib[] = {8, 16, 32, 64, 128, 256, 512, 1024};
	uint64_t rep[3];

	loom_fabric_repeat_voxels(f, rep);
	printf("\n3. from cold, per budget: over one repeat (%llux%llux%llu), 1 thread, per\n"
	       "   core: ray marches, random voxels, region reads (32x32xb3 tiles, z fastest,\n"
	       "   all channels; lookups = voxels); decomp%%: time reading + inflating\n"
	       "   bricks over the wall time\n", (unsigned long long)rep[0], (unsigned long long)rep[1],
	       (unsigned long long)rep[2]);
	printf("%8s %-9s %9s %10s %8s %9s %9s %8s %8s\n", "budget", "stream", "lookups",
	       "lookups/s", "hit", "misses", "evict", "decomp%", "peakMiB");
	for (size_t b = 0; b < sizeof mib / sizeof mib[0]; b++)
		for (int k = 0; k < 3; k++) {
			loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
			loom_texture *t = NULL;
			loom_texture_stats st;
			struct stream s;
			double cpu, wall0 = now_s(), limit = 2.0 * g_scale;
			uint64_t errors, total = 0;
			double cpu_total = 0;
			o.budget_bytes = mib[b] * MIB;
			o.max_threads = 1;
			if (loom_texture_open(f, db, &o, &t, NULL) != LOOM_OK)
				continue;
			s.kind = k;
			s.lo[0] = s.lo[1] = s.lo[2] = 0;
			for (int a = 0; a < 3; a++)
				s.hi[a] = (int64_t)rep[a];
			/* time-bounded: chunks until `limit` seconds */
			for (int c = 0; now_s() - wall0 < limit; c++) {
				s.seed = 1 + (uint64_t)c;
				if (k == S_REGION) { /* 8 tiles of 32 x 32 x b3, z fastest */
					static uint8_t buf[6 * 32 * 32 * 4096];
					size_t n = 32 * 32 * (size_t)rep[2];
					loom_texture_region r = {0};
					double c0 = cpu_s();
					r.layout = LOOM_REGION_Z_FASTEST;
					region_at(&r, buf, n, 0);
					for (int q = 0; q < 8; q++) {
						int64_t a[3], e[3];
						a[0] = (int64_t)(unit(&s.seed) * (double)(rep[0] - 32));
						a[1] = (int64_t)(unit(&s.seed) * (double)(rep[1] - 32));
						a[2] = 0;
						e[0] = a[0] + 32, e[1] = a[1] + 32, e[2] = (int64_t)rep[2];
						loom_texture_read_region(t, a, e, &r);
					}
					total += 8 * n;
					cpu_total += cpu_s() - c0;
					continue;
				}
				s.n = k == S_COHERENT ? 200000 : 20000;
				run_stream(&s, t, &cpu, &errors);
				total += s.n;
				cpu_total += cpu;
			}
			loom_texture_get_stats(t, &st);
			{
				double hr = st.hits + st.misses ? (double)st.hits / (double)(st.hits + st.misses) : 1;
				double wall = now_s() - wall0;
				double dec = wall > 0 ? (double)st.decompress_ns * 1e-9 / wall : 0;
				printf("%6zuMi %-9s %9llu %10.0f %8.4f %9llu %9llu %7.1f%% %8.1f\n", mib[b],
				       stream_name[k], (unsigned long long)total, (double)total / cpu_total,
				       hr, (unsigned long long)st.misses, (unsigned long long)st.evictions,
				       100 * dec, (double)st.peak_bytes / MIB);
				printf("{\"bench\":\"texture_budget\",\"budget_mib\":%zu,\"stream\":\"%s\","
				       "\"lookups\":%llu,\"lookups_per_s_per_core\":%.0f,\"hit_rate\":%.5f,"
				       "\"misses\":%llu,\"evictions\":%llu,\"decompress_share\":%.4f,"
				       "\"peak_bytes\":%llu}\n", mib[b], stream_name[k],
				       (unsigned long long)total, (double)total / cpu_total, hr,
				       (unsigned long long)st.misses, (unsigned long long)st.evictions, dec,
				       (unsigned long long)st.peak_bytes);
			}
			loom_texture_close(t);
		}
}

/* ---------------------------------------------------------- 4. peak RSS */

static void peak_rss(const char *loom, const char *fabric, const char *db)
{
	static const int mib[] = {16, 64, 256};
	printf("\n4. peak RSS of `loom sample FABRIC --random N` (one process per budget, "
	       "900x1500 paper-scale fabric)\n");
	printf("%8s %9s %12s %12s %12s %10s\n", "budget", "lookups", "peak cache", "peak RSS",
	       "RSS-budget", "target");
	for (int k = 0; k < 4; k++) {
		char cmd[16384], line[512];
		unsigned long long rss = 0, cache = 0, n = k == 0 ? 1 : (unsigned long long)(60000 * g_scale) + 1000;
		int b = k == 0 ? 16 : mib[k - 1];
		FILE *p;
		/* k == 0: a single lookup, the fixed part (binary, fabric, db index) */
		snprintf(cmd, sizeof cmd, "'%s' sample '%s' --db '%s' --random %llu --seed 7 "
		         "--budget %d --json --quiet", loom, fabric, db, n, b);
		p = popen(cmd, "r");
		if (!p)
			continue;
		while (fgets(line, sizeof line, p)) {
			sscanf(line, " \"peak_rss_bytes\": %llu", &rss);
			sscanf(line, " \"peak_cache_bytes\": %llu", &cache);
		}
		pclose(p);
		printf("%6dMi %9llu %10.1fMi %10.1fMi %10.1fMi %10s\n", b, n, (double)cache / MIB,
		       (double)rss / MIB, ((double)rss - (double)b * MIB) / MIB,
		       k == 0 ? "(1 lookup)" : rss <= (unsigned long long)(b + 16) * MIB ? "met" : "MISSED");
		printf("{\"bench\":\"texture_rss\",\"budget_mib\":%d,\"lookups\":%llu,"
		       "\"peak_cache_bytes\":%llu,\"peak_rss_bytes\":%llu}\n", b, n, cache, rss);
	}
}

/* ------------------------------------------- 5. streamed regions (scan) */

/* A scan-like stream: every voxel of a region of SC_ROWS x SC_COLS
   crossings, crossing-aligned tiles split in 2 x 2 sub-tiles, read by nt
   threads (tile k by thread k mod nt) into per-thread buffers, with all
   five channels; then the same bytes memcpy'd into the same buffers.  Tile
   order "rows": crossing rows in order; "source": crossings sorted by
   source block (loom_fabric_source_at), so that the crossings that copy
   the same block follow one another and their bricks are reused from the
   cache.  Run in a child process per configuration (bench_texture --stream
   ...), so that its peak RSS is the stream's alone. */
#define SC_ROWS 8
#define SC_COLS 8

struct sc_tile {
	uint64_t key;
	int64_t lo[3], hi[3];
};

struct sc_job {
	loom_texture *t;
	const struct sc_tile *tiles;
	int n_tiles, id, nt, layout;
	uint8_t *buf, *src;
	size_t cap;
	double cpu, cpu_copy, t0, t1; /* t0, t1: wall clock of the reads */
	uint64_t voxels, sum;
	int errors;
	pthread_barrier_t *bar;
};

static int sc_cmp(const void *a, const void *b)
{
	const struct sc_tile *p = a, *q = b;
	return p->key < q->key ? -1 : p->key > q->key;
}

static void *sc_run(void *arg)
{
	struct sc_job *j = arg;
	double c0;

	pthread_barrier_wait(j->bar);
	j->t0 = now_s();
	c0 = cpu_s();
	for (int k = j->id; k < j->n_tiles; k += j->nt) {
		const struct sc_tile *tl = &j->tiles[k];
		size_t n = (size_t)(tl->hi[0] - tl->lo[0]) * (size_t)(tl->hi[1] - tl->lo[1]) *
		           (size_t)(tl->hi[2] - tl->lo[2]);
		loom_texture_region r = {0};
		r.layout = j->layout;
		region_at(&r, j->buf, n, 0);
		j->errors += loom_texture_read_region(j->t, tl->lo, tl->hi, &r) != LOOM_OK;
		j->voxels += n;
		j->sum += j->buf[(size_t)k * 7919 % n] + j->buf[5 * n - 1 - (size_t)k % n];
	}
	j->cpu = cpu_s() - c0;
	j->t1 = now_s();
	c0 = cpu_s();
	for (int k = j->id; k < j->n_tiles; k += j->nt) {
		const struct sc_tile *tl = &j->tiles[k];
		size_t n = (size_t)(tl->hi[0] - tl->lo[0]) * (size_t)(tl->hi[1] - tl->lo[1]) *
		           (size_t)(tl->hi[2] - tl->lo[2]);
		memcpy(j->buf, j->src + k % 61, 6 * n);
		j->sum += j->buf[(size_t)k * 7919 % n];
	}
	j->cpu_copy = cpu_s() - c0;
	return NULL;
}

/* A "Vm...:" field of /proc/self/status in KiB (key with its colon), -1
   when absent. */
static long vm_kib(const char *key)
{
	char line[256];
	long v = -1;
	size_t n = strlen(key);
	FILE *fp = fopen("/proc/self/status", "r");
	if (!fp)
		return -1;
	while (fgets(line, sizeof line, fp))
		if (strncmp(line, key, n) == 0)
			v = atol(line + n);
	fclose(fp);
	return v;
}

static long vm_hwm(void)
{
	return vm_kib("VmHWM:");
}

/* The child: bench_texture --stream LAYOUT THREADS BUDGET_MIB ORDER;
   prints one JSON line. */
static int stream_child(char **argv, const char *dbp, const char *fabp)
{
	int layout = atoi(argv[2]), nt = atoi(argv[3]), order = atoi(argv[5]);
	size_t budget = (size_t)atoi(argv[4]) * MIB;
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture_stats st;
	loom_diag diag = {0};
	loom_db_info info;
	struct sc_tile *tiles;
	struct sc_job j[2];
	pthread_t th[2];
	int n = 0;
	size_t cap = 0;
	double wall;
	long rss0;
	pthread_barrier_t bar;

	if (nt < 1 || nt > 2 || loom_db_open(dbp, &db, &diag) != LOOM_OK ||
	    loom_fabric_open(fabp, db, 0, &f, &diag) != LOOM_OK) {
		printf("{\"error\":\"%s\"}\n", diag.message);
		return 1;
	}
	loom_db_get_info(db, &info);
	o.budget_bytes = budget;
	o.max_threads = (unsigned)nt;
	if (loom_texture_open(f, db, &o, &t, &diag) != LOOM_OK) {
		printf("{\"error\":\"%s\"}\n", diag.message);
		return 1;
	}
	tiles = malloc(sizeof *tiles * SC_ROWS * SC_COLS * 4);
	for (int64_t I = 11; I < 11 + SC_ROWS; I++)
		for (int64_t J = 7; J < 7 + SC_COLS; J++) {
			loom_fabric_source so;
			int64_t x0 = J * info.block[0], y0 = I * info.block[1];
			int64_t xm = x0 + info.block[0] / 2, ym = y0 + info.block[1] / 2;
			loom_fabric_source_at(f, I, J, &so);
			for (int q = 0; q < 4; q++) {
				struct sc_tile *tl = &tiles[n++];
				size_t v;
				/* source order: by block, then crossing, then quarter */
				tl->key = (order ? (uint64_t)so.block << 32 : 0) | (uint64_t)n;
				tl->lo[0] = q & 1 ? xm : x0;
				tl->hi[0] = q & 1 ? x0 + info.block[0] : xm;
				tl->lo[1] = q & 2 ? ym : y0;
				tl->hi[1] = q & 2 ? y0 + info.block[1] : ym;
				tl->lo[2] = 0;
				tl->hi[2] = info.block[2];
				v = (size_t)(tl->hi[0] - tl->lo[0]) * (size_t)(tl->hi[1] - tl->lo[1]) *
				    info.block[2];
				if (v > cap)
					cap = v;
			}
		}
	qsort(tiles, (size_t)n, sizeof *tiles, sc_cmp);
	rss0 = vm_hwm();
	for (int i = 0; i < nt; i++) {
		memset(&j[i], 0, sizeof j[i]);
		j[i].t = t, j[i].tiles = tiles, j[i].n_tiles = n, j[i].id = i, j[i].nt = nt;
		j[i].layout = layout ? LOOM_REGION_Z_FASTEST : LOOM_REGION_X_FASTEST;
		j[i].cap = cap;
		j[i].buf = malloc(6 * cap);
		j[i].src = malloc(6 * cap + 64);
		memset(j[i].buf, 0, 6 * cap);
		memset(j[i].src, 1, 6 * cap + 64);
	}
	pthread_barrier_init(&bar, NULL, (unsigned)nt);
	for (int i = 0; i < nt; i++) {
		j[i].bar = &bar;
		pthread_create(&th[i], NULL, sc_run, &j[i]);
	}
	for (int i = 0; i < nt; i++)
		pthread_join(th[i], NULL);
	pthread_barrier_destroy(&bar);
	wall = 0;
	for (int i = 0; i < nt; i++) /* first start to last end of the reads */
		if (j[i].t1 - j[0].t0 > wall)
			wall = j[i].t1 - (j[0].t0 < j[nt - 1].t0 ? j[0].t0 : j[nt - 1].t0);
	loom_texture_get_stats(t, &st);
	{
		double cpu = 0, cpu_copy = 0;
		uint64_t vox = 0;
		int errors = 0;
		for (int i = 0; i < nt; i++) {
			cpu += j[i].cpu, cpu_copy += j[i].cpu_copy, vox += j[i].voxels;
			errors += j[i].errors;
		}
		printf("{\"bench\":\"texture_stream\",\"layout\":\"%s\",\"threads\":%d,"
		       "\"budget_mib\":%d,\"order\":\"%s\",\"voxels\":%llu,\"wall_s\":%.3f,"
		       "\"per_core\":%.0f,\"memcpy_per_core\":%.0f,\"ratio\":%.4f,"
		       "\"wall_rate\":%.0f,\"hit_rate\":%.5f,\"misses\":%llu,\"peak_bytes\":%llu,"
		       "\"rss_before_kib\":%ld,\"peak_rss_kib\":%ld,\"buffers_bytes\":%zu,"
		       "\"errors\":%d}\n",
		       layout ? "z" : "x", nt, atoi(argv[4]), order ? "source" : "rows",
		       (unsigned long long)vox, wall, (double)vox / cpu, (double)vox / cpu_copy,
		       cpu_copy / cpu, (double)vox / wall,
		       st.hits + st.misses ? (double)st.hits / (double)(st.hits + st.misses) : 1,
		       (unsigned long long)st.misses, (unsigned long long)st.peak_bytes, rss0,
		       vm_hwm(), (size_t)nt * 12 * cap + 64, errors);
	}
	for (int i = 0; i < nt; i++)
		free(j[i].buf), free(j[i].src);
	free(tiles);
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	return 0;
}

static void streams(const char *self)
{
	static const int budgets[] = {16, 64};
	printf("\n5. streamed regions (a scan): %dx%d crossings (%d x %d x %u voxels), tiles\n"
	       "   of a quarter crossing, all five channels, per-thread buffers; one child\n"
	       "   process per row.  per core = voxels over the threads' CPU seconds; memcpy =\n"
	       "   the same bytes into the same buffers, same threads; wall: the reads only;\n"
	       "   over = peak RSS of the process (binary, database index, fabric, texture)\n"
	       "   beyond the budget, not counting the bench's buffers (output + memcpy\n"
	       "   source, 2 x 3.6 MB per thread)\n",
	       SC_ROWS, SC_COLS, SC_COLS * (int)B1, SC_ROWS * (int)B2, B3);
	printf("%-6s %7s %6s %-7s | %9s %9s %6s | %9s %7s %8s %9s %8s\n", "layout", "threads",
	       "budget", "order", "M/s/core", "memcpy", "ratio", "wall M/s", "hit", "misses",
	       "peak MiB", "over");
	for (int lay = 1; lay >= 0; lay--)
		for (int nt = 1; nt <= 2; nt++)
			for (int b = 0; b < 2; b++)
				for (int order = 0; order < 2; order++) {
					char cmd[8400], line[2048];
					FILE *p;
					snprintf(cmd, sizeof cmd, "'%s' --stream %d %d %d %d", self, lay, nt,
					         budgets[b], order);
					p = popen(cmd, "r");
					if (!p)
						continue;
					while (fgets(line, sizeof line, p)) {
						double pc = 0, mc = 0, ratio = 0, wr = 0, hit = 0;
						unsigned long long miss = 0, peak = 0, bufs = 0;
						long hwm = 0;
						char *q;
						if (!strstr(line, "texture_stream")) {
							printf("%s", line);
							continue;
						}
#define FIELD(name, fmt, var) \
	if ((q = strstr(line, "\"" name "\":")) != NULL) \
		sscanf(q + strlen(name) + 3, fmt, &var);
						FIELD("per_core", "%lf", pc)
						FIELD("memcpy_per_core", "%lf", mc)
						FIELD("ratio", "%lf", ratio)
						FIELD("wall_rate", "%lf", wr)
						FIELD("hit_rate", "%lf", hit)
						FIELD("misses", "%llu", miss)
						FIELD("peak_bytes", "%llu", peak)
						FIELD("peak_rss_kib", "%ld", hwm)
						FIELD("buffers_bytes", "%llu", bufs)
#undef FIELD
						printf("%-6s %7d %4dMi %-7s | %8.0fM %8.0fM %6.3f | %8.0fM %7.4f "
						       "%8llu %9.1f %6.1fMi\n", lay ? "z" : "x", nt, budgets[b],
						       order ? "source" : "rows", pc / 1e6, mc / 1e6, ratio,
						       wr / 1e6, hit, miss, (double)peak / MIB,
						       ((double)hwm * 1024 - (double)bufs) / MIB - budgets[b]);
						printf("%s", line);
					}
					pclose(p);
				}
}

/* ------------------------------------------- bench_vdb's loom child */

/*
 * bench_vdb's below-the-working-set child for loom, in C so that the peak
 * RSS it reports is loom's and not that of OpenVDB, TBB and libstdc++
 * (34 MiB mapped before loom opens anything in the C++ bench):
 *
 *   bench_texture --vdb-child DB FABRIC X0 Y0 NX NY NZ NPTS NRAYS BUDGET_MIB
 *
 * The same work as bench_vdb's child (its work_make with seed 99: random
 * voxels, then ray walks of unit steps, up to 256 inside the voxel
 * centres' hull; density through loom_texture_voxel_ch), so the checksums
 * agree with OpenVDB's.  Prints "RESULT rnd_rate ray_rate ck_rnd ck_ray
 * hwm_kib base_kib".
 */
static int vdb_child(char **argv)
{
	long base = vm_kib("VmRSS:");
	const char *dbp = argv[2], *fabp = argv[3];
	int64_t lo[3] = {atoll(argv[4]), atoll(argv[5]), 0};
	int n[3] = {atoi(argv[6]), atoi(argv[7]), atoi(argv[8])};
	size_t n_pts = (size_t)atoll(argv[9]), n_rays = (size_t)atoll(argv[10]);
	size_t budget = (size_t)atoll(argv[11]) * MIB;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_diag diag = {0};
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	int32_t *pi = malloc(3 * n_pts * sizeof *pi);
	double *ray = malloc(6 * n_rays * sizeof *ray);
	uint64_t s = 99, ck[2] = {0, 0}, cnt[2] = {0, 0};
	double rate[2];
	int errors = 0, warmed = 0;

	if (!pi || !ray)
		return 1;
	/* bench_vdb's work_make: the real positions are drawn too (unused) */
	for (size_t i = 0; i < n_pts; i++)
		for (int a = 0; a < 3; a++) {
			pi[3 * i + a] = (int32_t)(unit(&s) * n[a]);
			(void)unit(&s);
		}
	for (size_t i = 0; i < n_rays; i++) {
		double dir[3], len = 0;
		for (int a = 0; a < 3; a++) {
			ray[6 * i + a] = 0.5 + unit(&s) * (n[a] - 1);
			dir[a] = 2 * unit(&s) - 1;
			len += dir[a] * dir[a];
		}
		len = sqrt(len);
		for (int a = 0; a < 3; a++)
			ray[6 * i + 3 + a] = len > 0 ? dir[a] / len : (a == 2);
	}
	if (loom_db_open(dbp, &db, &diag) != LOOM_OK ||
	    loom_fabric_open(fabp, db, 0, &f, &diag) != LOOM_OK) {
		printf("bench_texture: vdb child: %s\n", diag.message);
		return 1;
	}
	o.budget_bytes = budget;
	o.max_threads = 2;
	if (loom_texture_open(f, db, &o, &t, &diag) != LOOM_OK) {
		printf("bench_texture: vdb child: %s\n", diag.message);
		return 1;
	}
	for (int k = 0; k < 2; k++) {
		double c0 = cpu_s();
		loom_texel tx;
		if (k == 0) {
			ck[0] = 0;
			for (size_t i = 0; i < n_pts; i++) {
				const int32_t *q = &pi[3 * i];
				errors += loom_texture_voxel_ch(t, lo[0] + q[0], lo[1] + q[1], lo[2] + q[2],
				                                LOOM_CHANNEL_DENSITY, &tx) != LOOM_OK;
				ck[0] += (uint64_t)lroundf(tx.density * 255.0f);
			}
			cnt[0] = n_pts;
		} else {
			for (size_t i = 0; i < n_rays; i++) {
				const double *r = &ray[6 * i];
				double p[3] = {r[0], r[1], r[2]};
				for (int st = 0; st < 256; st++) {
					if (!(p[0] >= 0.5 && p[0] <= n[0] - 0.5 && p[1] >= 0.5 &&
					      p[1] <= n[1] - 0.5 && p[2] >= 0.5 && p[2] <= n[2] - 0.5))
						break;
					errors += loom_texture_voxel_ch(t, lo[0] + (int32_t)p[0],
					                                lo[1] + (int32_t)p[1],
					                                lo[2] + (int32_t)p[2],
					                                LOOM_CHANNEL_DENSITY, &tx) != LOOM_OK;
					ck[1] += (uint64_t)lroundf(tx.density * 255.0f);
					cnt[1]++;
					p[0] += r[3], p[1] += r[4], p[2] += r[5];
				}
			}
		}
		rate[k] = (double)cnt[k] / fmax(cpu_s() - c0, 1e-9);
		if (getenv("BENCH_VDB_CHILD_STATS")) { /* for profiling: not parsed */
			loom_texture_stats ts;
			loom_texture_get_stats(t, &ts);
			printf("stats after %s: lookups %llu crossings %llu dz %llu hits %llu misses "
			       "%llu rate %.0f/s; frames %u fixed %.1f MiB empty %llu inflated %.1f MiB "
			       "in %.2f s\n", k ? "rays" : "random",
			       (unsigned long long)ts.lookups, (unsigned long long)ts.crossings,
			       (unsigned long long)ts.dz_columns, (unsigned long long)ts.hits,
			       (unsigned long long)ts.misses, rate[k], ts.cache_frames,
			       ts.fixed_bytes / (double)MIB, (unsigned long long)ts.empty_bricks,
			       ts.bytes_decompressed / (double)MIB, ts.decompress_ns * 1e-9);
		}
		if (k == 0 && getenv("BENCH_VDB_CHILD_WARM") && !warmed++)
			k = -1; /* for profiling: the random pass again, warm */
	}
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	free(pi);
	free(ray);
	if (errors) {
		printf("bench_texture: vdb child: %d lookups failed\n", errors);
		return 1;
	}
	printf("RESULT %.0f %.0f %llu %llu %ld %ld\n", rate[0], rate[1], (unsigned long long)ck[0],
	       (unsigned long long)ck[1], vm_kib("VmHWM:"), base);
	return 0;
}

/* ---------------------------------------------------------------- main */

int main(int argc, char **argv)
{
	const char *parts = argc > 1 ? argv[1] : "12345";
	const char *build = getenv("BUILD") ? getenv("BUILD") : "build";
	const char *paper = getenv("LOOM_PAPER_DB");
	const char *sc = getenv("BENCH_TEXTURE_SCALE");
	char dbp[4200], fabp[4200], loomp[4200];
	loom_db *db = NULL;
	loom_design *d;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_diag diag = {0};
	loom_db_info info;
	struct stat st;
	double t0;
	int simd = 0;

	if (sc)
		g_scale = atof(sc) > 0 ? atof(sc) : 1.0;
	if (getenv("BENCH_TEXTURE_SIMD")) { /* loom__texture_simd's levels */
		const char *v = getenv("BENCH_TEXTURE_SIMD");
		simd = !strcmp(v, "avx2") ? 2 : !strcmp(v, "ssse3") ? 3 : 0;
		if (!simd) {
			fprintf(stderr, "bench_texture: BENCH_TEXTURE_SIMD=%s: expected avx2 or ssse3\n",
			        v);
			return 2;
		}
	}
	snprintf(loomp, sizeof loomp, "%s/loom", build);
	if (paper && *paper)
		snprintf(dbp, sizeof dbp, "%s", paper);
	else
		snprintf(dbp, sizeof dbp, "%s/bench/paper.ldb", build);
	snprintf(fabp, sizeof fabp, "%s/bench/texture-paper.lfab", build);
	if (argc == 12 && strcmp(argv[1], "--vdb-child") == 0)
		return vdb_child(argv);
	if (argc == 6 && strcmp(argv[1], "--stream") == 0)
		return stream_child(argv, dbp, fabp);
	bench_help(argc, argv, USAGE);
	if (argc > 2 || !bench_digits_in(parts, "12345"))
		bench_reject("bench_texture", argv[argc > 2 ? 2 : 1], USAGE);
	if (!(paper && *paper) && stat(dbp, &st) == 0 &&
	    loom_db_open(dbp, &db, &diag) == LOOM_OK) { /* another format: again */
		loom_db_get_info(db, &info);
		loom_db_close(db);
		db = NULL;
		if (info.version != 4) { /* the default, which bench_vdb shares */
			printf("%s is of format version %u: generated again in version 4\n",
			       dbp, info.version);
			unlink(dbp);
		}
	}
	if (stat(dbp, &st) != 0) {
		loom_exgen_params p;
		printf("generating the paper preset database %s (once, ~10-20 s)\n", dbp);
		fflush(stdout);
		loom_exgen_preset("paper", &p);
		if (loom_exgen_write_db(dbp, &p, NULL, &diag) != LOOM_OK) {
			printf("bench_texture: %s\n", diag.message);
			return 0;
		}
	}
	if (loom_db_open(dbp, &db, &diag) != LOOM_OK) {
		printf("bench_texture: %s\n", diag.message);
		return 0;
	}
	loom_db_get_info(db, &info);
	B1 = info.block[0], B2 = info.block[1], B3 = info.block[2];
	printf("database %s: %.1f MB, %u exemplars, block %ux%ux%u%s\n", dbp,
	       info.file_bytes / 1e6, info.n_exemplars, B1, B2, B3,
	       paper && *paper ? " (LOOM_PAPER_DB)" : " (the library's paper preset, "
	       "smooth yarns: not the CLI's cotton --preset paper, docs/exemplars.md)");
	d = jacquard(900, 1500);
	t0 = now_s();
	if (!d || loom_fabric_synthesize(d, db, dbp, NULL, &f, &diag) != LOOM_OK) {
		printf("bench_texture: synthesis: %s\n", diag.message);
		return 0;
	}
	printf("paper-scale fabric: 900x1500 crossings, blocks %ux%ux%u, bricks %ux%ux%u "
	       "(%llu bytes); synthesis %.2f s\n", B1, B2, B3, info.brick[0], info.brick[1],
	       info.brick[2], (unsigned long long)info.brick[0] * info.brick[1] * info.brick[2] * 4,
	       now_s() - t0);

	{
		/* a window of 2 x 3 crossings away from the origin, the whole
		   thickness; the texture warm (its bricks all cached) */
		int64_t lo[3] = {7 * (int64_t)B1 + 30, 11 * (int64_t)B2 + 20, 0};
		int64_t hi[3] = {lo[0] + 192, lo[1] + 192, B3};
		o.budget_bytes = 512 * MIB;
		o.max_threads = 2;
		if (loom_texture_open(f, db, &o, &t, &diag) != LOOM_OK) {
			printf("bench_texture: %s\n", diag.message);
			return 0;
		}
		if (simd) {
			loom__texture_simd(t, simd);
			printf("lookups and region reads as on a host with %s\n",
			       simd == 2 ? "AVX2 but not AVX-512" : "SSSE3 but not AVX2");
		}
		if (dense_build(t, d, lo, hi) != 0) {
			printf("bench_texture: cannot materialise the window\n");
			return 0;
		}
		if (strchr(parts, '1'))
			warm_lookups(t, lo, hi);
		if (strchr(parts, '2'))
			region_reads(t, lo, hi);
		loom_texture_close(t);
		free(D.v);
	}
	if (strchr(parts, '3'))
		budgets(f, db);
	if (!strchr(parts, '4'))
		;
	else if (loom_fabric_save(f, fabp, NULL, &diag) == LOOM_OK && stat(loomp, &st) == 0)
		peak_rss(loomp, fabp, dbp);
	else
		printf("\n4. peak RSS: skipped (%s)\n", diag.message[0] ? diag.message : "no loom binary");
	if (!strchr(parts, '5'))
		;
	else if (loom_fabric_save(f, fabp, NULL, &diag) == LOOM_OK)
		streams(argv[0]);
	else
		printf("\n5. streamed regions: skipped (%s)\n", diag.message);
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(db);
	return 0;
}
