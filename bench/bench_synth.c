/*
 * bench/bench_synth.c - yarn-level synthesis and edge-fix figures
 * (docs/synthesis.md).  Prints a human table and JSON lines ("{...}").
 *
 *   build/bench/bench_synth [--quick]     --quick skips 20000 x 20000
 *
 * Exemplars: eight 5x5 weaves (twills and satins, non-periodic windows as
 * the generator makes them).  Designs: Jacquard-like, twill 2/3 and satin
 * 4/1 (move 2) exchanged over a blocky random mask.  Edge profiles are
 * synthetic smooth random curves (1/f^2 spectrum) until the database
 * provides real ones.  One thread; wall-clock (CLOCK_MONOTONIC).
 */
#include "loom.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_synth [--quick]\n"
	"Yarn-level synthesis and edge-fix figures on generated designs up to\n"
	"20000 x 20000 crossings.\n"
	"  --quick    skip 20000 x 20000\n";

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of this thread: the machine is shared, so wall time can be
   inflated by other jobs; both are reported. */
static double cpu(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double peak_mib(void)
{
	struct rusage ru;
	getrusage(RUSAGE_SELF, &ru);
	return (double)ru.ru_maxrss / 1024.0;
}

static uint64_t rng = 12345;

static double urand(void)
{
	rng = loom_synth_mix(rng);
	return (double)(rng >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

/* ---- exemplars and designs ---------------------------------------------- */

static const char *const weaves[] = {"twill:2/3", "twill:3/2", "twill:1/4", "twill:4/1",
                                     "satin:1/4", "satin:4/1", "satin:1/4:move=3",
                                     "satin:4/1:move=3"};

static loom_synth_set *exemplar_set(void)
{
	loom_synth_exemplar ex[8];
	loom_design *d[8];
	uint32_t n = 0;
	loom_synth_set *s = NULL;
	loom_diag diag = {0};
	for (unsigned k = 0; k < 8; k++) {
		loom_weave_params p;
		if (loom_weave_parse(weaves[k], &p, &diag) != LOOM_OK ||
		    loom_design_make(&p, 5, 5, &d[n], &diag) != LOOM_OK) {
			fprintf(stderr, "bench_synth: %s: %s\n", weaves[k], diag.message);
			continue;
		}
		ex[n].rows = 5;
		ex[n].cols = 5;
		ex[n].weave = d[n]->weave;
		ex[n].periodic = 0;
		n++;
	}
	if (loom_synth_set_new(ex, n, &s, &diag) != LOOM_OK)
		fprintf(stderr, "bench_synth: %s\n", diag.message);
	for (uint32_t k = 0; k < n; k++)
		loom_design_free(d[k]);
	return s;
}

/* Twill 2/3 with satin 4/1 inside the cells of a blocky random mask
   (rectangles of 16..80 crossings). */
static loom_design *jacquard(uint32_t rows, uint32_t cols)
{
	loom_weave_params a, b;
	loom_design *d = NULL;
	uint32_t cell_r = 48, cell_c = 64;
	loom_weave_parse("twill:2/3", &a, NULL);
	loom_weave_parse("satin:4/1", &b, NULL);
	if (loom_design_make(&a, rows, cols, &d, NULL) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < rows; i++) {
		uint8_t *row = d->weave + (size_t)i * cols;
		for (uint32_t j = 0; j < cols; j++) {
			uint64_t h = loom_synth_mix(((uint64_t)(i / cell_r) << 32) | (j / cell_c));
			/* jitter the cell borders so blocks are not all the same size */
			uint32_t ii = i + (uint32_t)(h % 17), jj = j + (uint32_t)((h >> 8) % 23);
			uint64_t h2 = loom_synth_mix(((uint64_t)(ii / cell_r) << 32) | (jj / cell_c));
			if (h2 & 1)
				row[j] = (uint8_t)loom_weave_cell(&b, i, j);
		}
	}
	return d;
}

/* ---- assignment ---------------------------------------------------------- */

static const char *const algo_name[] = {"naive", "greedy", "dp", "dp-full"};

static void bench_assign(const loom_synth_set *s, uint32_t rows, uint32_t cols,
                         int with_metrics)
{
	double t0 = now(), tdes;
	loom_design *d = jacquard(rows, cols);
	size_t n = (size_t)rows * cols;
	uint16_t *base = malloc(n * 2);

	tdes = now() - t0;
	if (!d || !base) {
		fprintf(stderr, "bench_synth: out of memory at %ux%u\n", rows, cols);
		free(base);
		loom_design_free(d);
		return;
	}
	for (int a = 0; a < 4; a++) {
		loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
		loom_synth_metrics m;
		uint64_t usage[8];
		double t, tc, tm = 0;
		int rc;
		if (a == 3 && n > 30000000)
			continue; /* the full-list DP only where it is quick */
		o.algo = a == 3 ? LOOM_SYNTH_DP : a;
		o.flags = a == 3 ? LOOM_SYNTH_FULL_LISTS : 0;
		o.seed = 7;
		t = now();
		tc = cpu();
		rc = loom_synth_assign(s, d, &o, base, NULL);
		tc = cpu() - tc;
		t = now() - t;
		memset(&m, 0, sizeof m);
		memset(usage, 0, sizeof usage);
		if (rc == LOOM_OK && (with_metrics || a == 2)) {
			tm = now();
			loom_synth_metrics_repeat(s, d, base, usage, &m);
			tm = now() - tm;
		}
		printf("  %6ux%-6u %-8s %8.3f s cpu (%.3f wall) %6.1f ns/crossing  work %6.2f MiB  "
		       "consistency %.4f continuity %.4f (v %.3f h %.3f)\n",
		       rows, cols, algo_name[a], tc, t, 1e9 * tc / (double)n,
		       loom_synth_assign_work_bytes(s, d, &o) / 1048576.0, m.consistency,
		       m.continuity, m.crossings ? (double)m.continuous_v / m.crossings : 0,
		       m.crossings ? (double)m.continuous_h / m.crossings : 0);
		printf("{\"bench\":\"synth_assign\",\"rows\":%u,\"cols\":%u,\"algo\":\"%s\","
		       "\"rc\":%d,\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"ns_per_crossing\":%.2f,"
		       "\"work_bytes\":%zu,\"base_bytes\":%zu,\"design_bytes\":%zu,"
		       "\"correctness\":%.6f,\"consistency\":%.6f,\"continuity\":%.6f,"
		       "\"continuity_v\":%.6f,\"continuity_h\":%.6f,\"metrics_seconds\":%.4f,"
		       "\"usage\":[%llu,%llu,%llu,%llu,%llu,%llu,%llu,%llu],"
		       "\"design_make_seconds\":%.3f,\"peak_rss_mib\":%.1f}\n",
		       rows, cols, algo_name[a], rc, t, tc, 1e9 * tc / (double)n,
		       loom_synth_assign_work_bytes(s, d, &o), n * 2, n * 3, m.correctness,
		       m.consistency, m.continuity,
		       m.crossings ? (double)m.continuous_v / m.crossings : 0,
		       m.crossings ? (double)m.continuous_h / m.crossings : 0, tm,
		       (unsigned long long)usage[0], (unsigned long long)usage[1],
		       (unsigned long long)usage[2], (unsigned long long)usage[3],
		       (unsigned long long)usage[4], (unsigned long long)usage[5],
		       (unsigned long long)usage[6], (unsigned long long)usage[7], tdes,
		       peak_mib());
		fflush(stdout);
	}
	/* randomised window metrics (after the dp above was overwritten by
	   dp-full where it ran: same consistency, same optimum) */
	if (with_metrics) {
		loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
		loom_synth_lookup lk;
		loom_synth_metrics m;
		double t;
		loom_synth_assign(s, d, &o, base, NULL);
		loom_synth_lookup_init(&lk, s, base, rows, cols, &o);
		t = now();
		loom_synth_metrics_window(s, d, &lk, -1000, 123456789, 1000, 1000, NULL, &m);
		t = now() - t;
		printf("  randomised m^=3 window 1000x1000: consistency %.4f continuity %.4f "
		       "(%.0f ns per crossing incl. 3 lookups)\n",
		       m.consistency, m.continuity, 1e9 * t / 1e6);
		printf("{\"bench\":\"synth_window\",\"rows\":%u,\"cols\":%u,\"group\":3,"
		       "\"correctness\":%.6f,\"consistency\":%.6f,\"continuity\":%.6f,"
		       "\"ns_per_crossing\":%.1f}\n",
		       rows, cols, m.correctness, m.consistency, m.continuity, 1e9 * t / 1e6);
	}
	free(base);
	loom_design_free(d);
}

/* ---- edge fix ------------------------------------------------------------ */

static void curve(float *v, uint32_t n, double base, double amp)
{
	double a[24], b[24];
	for (int f = 0; f < 24; f++) {
		a[f] = urand();
		b[f] = urand();
	}
	for (uint32_t i = 0; i < n; i++) {
		double s = (double)i / (double)(n - 1), h = base;
		for (int f = 1; f <= 24; f++)
			h += amp / (f * f) * (a[f - 1] * cos(M_PI * f * s) + b[f - 1] * sin(M_PI * f * s));
		v[i] = (float)h;
	}
}

static float *profiles(uint32_t K, uint32_t b1, uint32_t b2, loom_edge_profiles *p)
{
	uint32_t rec = LOOM_EDGE_RECORD(b1, b2);
	float *h = malloc(sizeof(float) * rec * K);
	for (uint32_t t = 0; t < K; t++) {
		float *r = h + (size_t)t * rec;
		float *N = r, *S = r + b1, *W = r + 2 * b1, *E = r + 2 * b1 + b2;
		double base = 0.5 * b2 + 0.05 * b2 * urand(), amp = 0.08 * b2;
		curve(N, b1, base, amp);
		curve(S, b1, base, amp);
		curve(W, b2, base, amp);
		curve(E, b2, base, amp);
		W[0] = N[0];
		E[0] = N[b1 - 1];
		W[b2 - 1] = S[0];
		E[b2 - 1] = S[b1 - 1];
	}
	p->b1 = b1;
	p->b2 = b2;
	p->n_blocks = K;
	p->heights = h;
	p->set = NULL;
	return h;
}

static void bench_edgefix_build(uint32_t b1, uint32_t b2, uint32_t K, uint32_t rank)
{
	loom_edge_profiles p;
	float *h = profiles(K, b1, b2, &p);
	loom_edgefix *ef = NULL;
	double t = now(), best = 1e9;
	int reps = b1 > 50 ? 5 : 50;
	double bestc = 1e9;
	for (int k = 0; k < reps; k++) {
		double t1 = now(), c1 = cpu();
		loom_edgefix_free(ef);
		ef = NULL;
		loom_edgefix_build(&p, rank, &ef, NULL);
		c1 = cpu() - c1;
		t1 = now() - t1;
		if (t1 < best)
			best = t1;
		if (c1 < bestc)
			bestc = c1;
	}
	t = now() - t;
	printf("  edge-fix tables %3ux%-3u K=%u r=%-2u: build %.2f ms cpu (%.2f wall), %.0f KiB\n",
	       b1, b2, K, rank, 1e3 * bestc, 1e3 * best, loom_edgefix_bytes(ef) / 1024.0);
	printf("{\"bench\":\"edgefix_build\",\"b1\":%u,\"b2\":%u,\"blocks\":%u,\"rank\":%u,"
	       "\"seconds\":%.6f,\"cpu_seconds\":%.6f,\"bytes\":%zu}\n",
	       b1, b2, K, rank, best, bestc, loom_edgefix_bytes(ef));
	loom_edgefix_free(ef);
	free(h);
}

static void bench_edgefix_eval(uint32_t b1, uint32_t b2, uint32_t K, uint32_t rank)
{
	loom_edge_profiles p;
	float *h = profiles(K, b1, b2, &p), *dz = malloc(sizeof(float) * b1 * b2);
	loom_edgefix *ef = NULL;
	loom_synth_nbhd nb[64];
	double t, sink = 0;
	uint64_t cols = 0, blocks = 0;
	loom_edgefix_build(&p, rank, &ef, NULL);
	for (int k = 0; k < 64; k++) {
		uint16_t v[5];
		for (int q = 0; q < 5; q++)
			v[q] = (uint16_t)(loom_synth_mix((uint64_t)k * 5 + q) % K);
		nb[k] = (loom_synth_nbhd){v[0], v[1], v[2], v[3], v[4]};
	}
	t = cpu();
	while (cpu() - t < 0.5) {
		for (int k = 0; k < 64; k++)
			loom_edgefix_block(ef, &nb[k], dz);
		blocks += 64;
		sink += dz[7];
	}
	t = cpu() - t;
	double per_block = t / (double)blocks;
	t = cpu();
	while (cpu() - t < 0.5) {
		for (uint32_t k = 0; k < 4096; k++)
			sink += loom_edgefix_at(ef, &nb[k & 63], (k * 37) % b1, (k * 11) % b2);
		cols += 4096;
	}
	t = cpu() - t;
	printf("  offsets %3ux%-3u r=%-2u: block map %.1f us (%.0f M columns/s), single "
	       "column %.0f ns (%.1f M/s)%s\n",
	       b1, b2, rank, 1e6 * per_block, b1 * b2 / per_block / 1e6, 1e9 * t / (double)cols,
	       (double)cols / t / 1e6, sink == 12345.678 ? "!" : "");
	printf("{\"bench\":\"edgefix_eval\",\"b1\":%u,\"b2\":%u,\"rank\":%u,"
	       "\"block_map_seconds\":%.9f,\"columns_per_second_block\":%.0f,"
	       "\"single_column_seconds\":%.10f}\n",
	       b1, b2, rank, per_block, b1 * b2 / per_block, t / (double)cols);
	loom_edgefix_free(ef);
	free(h);
	free(dz);
}

/* Truncation error of our per-source tables and of the paper's per-block
   tables (own SVD of T and L) against the exact solve, on a DP assignment
   of a 16 x 20 Jacquard piece over K = 200 source blocks. */
static void bench_truncation(const loom_synth_set *s, uint32_t b1, uint32_t b2)
{
	static const uint32_t ranks[4] = {5, 10, 15, 30};
	uint32_t K = loom_synth_set_blocks(s), R = 16, C = 20;
	size_t cells = (size_t)b1 * b2;
	loom_edge_profiles p;
	float *h = profiles(K, b1, b2, &p);
	float *exact = malloc(sizeof(float) * cells * R * C), *dz = malloc(sizeof(float) * cells);
	loom_design *d = jacquard(R, C);
	uint16_t base[16 * 20];
	loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
	loom_synth_lookup lk;
	double step = 0;

	o.group = 0;
	loom_synth_assign(s, d, &o, base, NULL);
	loom_synth_lookup_init(&lk, s, base, R, C, &o);
	for (uint32_t i = 0; i < R; i++)
		for (uint32_t j = 0; j < C; j++) {
			loom_synth_nbhd nb;
			loom_synth_nbhd_at(&lk, i, j, &nb);
			loom_edgefix_exact(&p, &nb, exact + (i * C + j) * cells);
		}
	/* stand-in for the database's internal step: mean |dh| along profiles */
	for (uint32_t t = 0; t < K; t++) {
		const float *r = h + (size_t)t * LOOM_EDGE_RECORD(b1, b2);
		for (uint32_t x = 0; x + 1 < b1; x++)
			step += fabs(r[x + 1] - r[x]);
	}
	step /= (double)K * (b1 - 1);
	for (int k = 0; k < 4; k++) {
		loom_edgefix *ef = NULL;
		loom_edgefix_paper *pp = NULL;
		double mo = 0, so = 0, mp = 0, sp = 0;
		loom_seam_metrics sm;
		loom_edgefix_build(&p, ranks[k], &ef, NULL);
		loom_edgefix_paper_new(&p, base, R, C, ranks[k], NULL, &pp, NULL);
		for (uint32_t i = 0; i < R; i++)
			for (uint32_t j = 0; j < C; j++) {
				const float *ex = exact + (i * C + j) * cells;
				loom_synth_nbhd nb;
				loom_synth_nbhd_at(&lk, i, j, &nb);
				loom_edgefix_block(ef, &nb, dz);
				for (size_t c = 0; c < cells; c++) {
					double e = fabs((double)dz[c] - ex[c]);
					so += e;
					mo = e > mo ? e : mo;
				}
				loom_edgefix_paper_block(pp, i, j, dz);
				for (size_t c = 0; c < cells; c++) {
					double e = fabs((double)dz[c] - ex[c]);
					sp += e;
					mp = e > mp ? e : mp;
				}
			}
		so /= (double)cells * R * C;
		sp /= (double)cells * R * C;
		loom_edgefix_seam(ef, &p, &lk, 0, 0, R, C, step, &sm);
		printf("  truncation %3ux%-3u r=%-2u: ours max %.4f mean %.5f | paper max %.4f mean "
		       "%.5f voxels; seam %.3f -> %.3f (corners %.3f -> %.3f), internal step %.3f\n",
		       b1, b2, ranks[k], mo, so, mp, sp, sm.before_mean, sm.after_mean,
		       sm.corner_before_mean, sm.corner_after_mean, step);
		printf("{\"bench\":\"edgefix_truncation\",\"b1\":%u,\"b2\":%u,\"rank\":%u,"
		       "\"ours_max\":%.6f,\"ours_mean\":%.7f,\"paper_max\":%.6f,\"paper_mean\":%.7f,"
		       "\"paper_bytes\":%zu,\"ours_bytes\":%zu,\"seam_before\":%.5f,"
		       "\"seam_after\":%.5f,\"seam_before_corners\":%.5f,\"seam_after_corners\":%.5f,"
		       "\"seam_before_max\":%.4f,\"seam_after_max\":%.4f,\"internal_step\":%.5f}\n",
		       b1, b2, ranks[k], mo, so, mp, sp, loom_edgefix_paper_bytes(pp),
		       loom_edgefix_bytes(ef), sm.before_mean, sm.after_mean, sm.corner_before_mean,
		       sm.corner_after_mean, sm.before_max, sm.after_max, step);
		loom_edgefix_free(ef);
		loom_edgefix_paper_free(pp);
	}
	loom_design_free(d);
	free(exact);
	free(dz);
	free(h);
}

/* The target: 900 x 1500, dp assignment plus the edge-fix tables
   (115 x 70, K = 200, r = 15), best of 5. */
static void bench_target(const loom_synth_set *s)
{
	loom_design *d = jacquard(900, 1500);
	uint16_t *base = malloc((size_t)900 * 1500 * 2);
	loom_edge_profiles p;
	float *h = profiles(loom_synth_set_blocks(s), 115, 70, &p);
	double bw = 1e9, bc = 1e9;
	for (int k = 0; k < 5 && d && base; k++) {
		loom_synth_options o = LOOM_SYNTH_OPTIONS_INIT;
		loom_edgefix *ef = NULL;
		double w = now(), c = cpu();
		loom_synth_assign(s, d, &o, base, NULL);
		loom_edgefix_build(&p, LOOM_EDGEFIX_DEFAULT_RANK, &ef, NULL);
		c = cpu() - c;
		w = now() - w;
		bw = w < bw ? w : bw;
		bc = c < bc ? c : bc;
		loom_edgefix_free(ef);
	}
	printf("  target 900x1500 dp + edge-fix tables (115x70, r=15): %.1f ms cpu, %.1f ms wall "
	       "(best of 5)\n", 1e3 * bc, 1e3 * bw);
	printf("{\"bench\":\"synth_target\",\"rows\":900,\"cols\":1500,\"cpu_seconds\":%.6f,"
	       "\"seconds\":%.6f}\n", bc, bw);
	free(h);
	free(base);
	loom_design_free(d);
}

int main(int argc, char **argv)
{
	int quick = argc > 1 && strcmp(argv[1], "--quick") == 0;
	loom_synth_set *s;
	double t;

	bench_help(argc, argv, USAGE);
	for (int i = 1; i < argc; i++)
		if (strcmp(argv[i], "--quick") != 0)
			bench_reject("bench_synth", argv[i], USAGE);
	s = exemplar_set();
	if (!s)
		return 1;
	printf("bench_synth: %u exemplars, %u source blocks\n", loom_synth_set_exemplars(s),
	       loom_synth_set_blocks(s));
	t = now();
	{
		loom_synth_set *s2 = exemplar_set();
		loom_synth_set_free(s2);
	}
	printf("{\"bench\":\"synth_set\",\"blocks\":%u,\"seconds\":%.6f}\n",
	       loom_synth_set_blocks(s), now() - t);
	printf("assignment (one core):\n");
	bench_target(s);
	bench_assign(s, 900, 1500, 1);
	bench_assign(s, 5000, 5000, 1);
	if (!quick)
		bench_assign(s, 20000, 20000, 0);
	printf("edge fix:\n");
	bench_edgefix_build(115, 70, loom_synth_set_blocks(s), 15);
	bench_edgefix_build(24, 16, loom_synth_set_blocks(s), 15);
	bench_edgefix_build(115, 70, loom_synth_set_blocks(s), 30);
	bench_edgefix_eval(115, 70, loom_synth_set_blocks(s), 15);
	bench_edgefix_eval(24, 16, loom_synth_set_blocks(s), 15);
	bench_truncation(s, 115, 70);
	bench_truncation(s, 24, 16);
	loom_synth_set_free(s);
	return 0;
}
