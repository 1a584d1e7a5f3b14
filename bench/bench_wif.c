/*
 * bench/bench_wif.c - WIF reader speed: parse a 1,000-end x 8,000-pick
 * draft into a design.
 *
 *   build/bench/bench_wif [RUNS]      (default 21 runs)
 *
 * The WIF text is built in memory first (not timed): a realistic 16-shaft,
 * 16-treadle dobby draft with a point-twill threading, a tie-up of broken
 * twills, a point treadling with a second treadle on some picks, warp and
 * weft colour stripes and a thickness per end.  Each run times
 * loom_wif_parse (text -> loom_design, yarn types included) and frees the
 * design.  Prints one JSON line and one human line: median seconds and
 * MB/s of WIF text.  Target: median under 0.1 s.
 *
 * A design this size is 3 x 8 MB of fresh memory (weave, warp and weft type
 * maps); on a virtual machine the first-touch page faults of that memory
 * can cost more than the parse itself.  So the bench also times that floor
 * alone (malloc + memset + free of the same three arrays, "touch_floor_s"):
 * median_s - touch_floor_s is what the reader adds.  Then, on glibc, it
 * asks malloc to keep freed memory (mallopt) and times the parse again with
 * the pages already mapped ("warm_median_s"): the reader's own cost.
 */
#include "loom.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef __GLIBC__
#include <malloc.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_wif [RUNS]\n"
	"WIF reader speed on a 1000-end x 8000-pick dobby draft.\n"
	"  RUNS       parses timed, 1-10000 (default 21)\n";
#endif

#define ENDS 1000
#define PICKS 8000
#define SHAFTS 16
#define TREADLES 16

typedef struct { char *s; size_t n, cap; } sbuf;

static void put(sbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(sbuf *b, const char *fmt, ...)
{
	va_list ap;
	int k;

	for (;;) {
		va_start(ap, fmt);
		k = vsnprintf(b->s + b->n, b->cap - b->n, fmt, ap);
		va_end(ap);
		if (k < 0)
			exit(1);
		if ((size_t)k < b->cap - b->n)
			break;
		b->cap = b->cap * 2 + (size_t)k + 4096;
		b->s = realloc(b->s, b->cap);
		if (!b->s)
			exit(1);
	}
	b->n += (size_t)k;
}

/* Point (zigzag) sequence 1..n..2 over position k. */
static int point(int k, int n)
{
	int p = k % (2 * n - 2);
	return 1 + (p < n ? p : 2 * n - 2 - p);
}

static void make_wif(sbuf *b)
{
	b->cap = 1 << 20;
	b->s = malloc(b->cap);
	b->n = 0;
	put(b, "[WIF]\r\nVersion=1.1\r\nDate=bench\r\nDevelopers=loom\r\n"
	       "Source Program=bench_wif\r\n\r\n[CONTENTS]\r\nCOLOR PALETTE=true\r\n"
	       "WEAVING=true\r\nWARP=true\r\nWEFT=true\r\nCOLOR TABLE=true\r\n"
	       "THREADING=true\r\nTIEUP=true\r\nTREADLING=true\r\n"
	       "WARP COLORS=true\r\nWEFT COLORS=true\r\nWARP THICKNESS=true\r\n\r\n");
	put(b, "[COLOR PALETTE]\r\nEntries=4\r\nForm=RGB\r\nRange=0,255\r\n\r\n");
	put(b, "[COLOR TABLE]\r\n1=240,235,220\r\n2=30,50,110\r\n3=150,30,40\r\n"
	       "4=20,20,20\r\n\r\n");
	put(b, "[WEAVING]\r\nShafts=%d\r\nTreadles=%d\r\nRising Shed=true\r\n\r\n",
	    SHAFTS, TREADLES);
	put(b, "[WARP]\r\nThreads=%d\r\nColor=1\r\nUnits=Decipoints\r\n"
	       "Thickness=10\r\n\r\n[WEFT]\r\nThreads=%d\r\nColor=2\r\n"
	       "Units=Decipoints\r\nThickness=12\r\n\r\n", ENDS, PICKS);
	put(b, "[THREADING]\r\n");
	for (int j = 1; j <= ENDS; j++)
		put(b, "%d=%d\r\n", j, point(j - 1, SHAFTS));
	put(b, "\r\n[TIEUP]\r\n");
	for (int t = 1; t <= TREADLES; t++) { /* 3/1/1/3 broken twill rows */
		static const int on[8] = {1, 1, 1, 0, 1, 0, 0, 0};
		int first = 1;
		put(b, "%d=", t);
		for (int s = 1; s <= SHAFTS; s++)
			if (on[(s - t + 64) % 8]) {
				put(b, first ? "%d" : ",%d", s);
				first = 0;
			}
		put(b, "\r\n");
	}
	put(b, "\r\n[TREADLING]\r\n");
	for (int i = 1; i <= PICKS; i++) {
		int t = point(i - 1, TREADLES);
		if (i % 7 == 0)
			put(b, "%d=%d,%d\r\n", i, t, 1 + (t % TREADLES));
		else
			put(b, "%d=%d\r\n", i, t);
	}
	put(b, "\r\n[WARP COLORS]\r\n");
	for (int j = 1; j <= ENDS; j++)
		put(b, "%d=%d\r\n", j, (j / 24) % 3 == 2 ? 3 : 1);
	put(b, "\r\n[WEFT COLORS]\r\n");
	for (int i = 1; i <= PICKS; i++)
		put(b, "%d=%d\r\n", i, (i / 40) % 4 == 3 ? 4 : 2);
	put(b, "\r\n[WARP THICKNESS]\r\n");
	for (int j = 1; j <= ENDS; j++)
		put(b, "%d=%s\r\n", j, j % 50 == 0 ? "14" : "10");
}

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int cmp_d(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

/* Median time to allocate, fill and free three ENDS x PICKS arrays. */
static double touch_floor(int runs)
{
	double *t = malloc((size_t)runs * sizeof *t), med;
	size_t n = (size_t)ENDS * PICKS;

	for (int r = 0; r < runs; r++) {
		double t0 = now();
		unsigned char *p[3];
		for (int k = 0; k < 3; k++) {
			p[k] = malloc(n);
			if (!p[k])
				exit(1);
			memset(p[k], k + 1, n);
		}
		/* keep the stores */
		if (p[0][n / 2] + p[1][n / 3] + p[2][n - 1] != 6)
			exit(1);
		for (int k = 0; k < 3; k++)
			free(p[k]);
		t[r] = now() - t0;
	}
	qsort(t, (size_t)runs, sizeof *t, cmp_d);
	med = t[runs / 2];
	free(t);
	return med;
}

/* Median seconds of `runs` parses of b into t[] (sorted). */
static double time_parses(const sbuf *b, int runs, double *t)
{
	loom_design *d = NULL;
	loom_diag diag = {0};

	for (int r = 0; r < runs; r++) {
		double t0 = now();
		int rc = loom_wif_parse(b->s, b->n, "bench.wif", &d, &diag);
		t[r] = now() - t0;
		if (rc != LOOM_OK || d->rows != PICKS || d->cols != ENDS) {
			fprintf(stderr, "bench_wif: parse failed: %s\n", diag.message);
			exit(1);
		}
		if (r == 0 && (diag.n_warnings || d->n_types != 6)) {
			fprintf(stderr, "bench_wif: %u warnings, %u types (expected 0, 6)\n",
			        diag.n_warnings, d->n_types);
			exit(1);
		}
		loom_design_free(d);
	}
	qsort(t, (size_t)runs, sizeof *t, cmp_d);
	return t[runs / 2];
}

int main(int argc, char **argv)
{
	int runs = argc > 1 ? atoi(argv[1]) : 21;
	sbuf b = {0};
	double *t, med, mbs, floor_s, warm = -1;

	bench_help(argc, argv, USAGE);
	if (argc > 2)
		bench_reject("bench_wif", argv[2], USAGE);
	if (argc > 1 && !bench_int_in(argv[1], 1, 10000))
		bench_reject("bench_wif", argv[1], USAGE);
	make_wif(&b);
	t = malloc((size_t)runs * sizeof *t);
	med = time_parses(&b, runs, t);
	mbs = b.n / 1e6 / med;
	floor_s = touch_floor(runs);
#ifdef __GLIBC__
	{
		double *tw = malloc((size_t)runs * sizeof *tw);
		mallopt(M_MMAP_THRESHOLD, 1 << 30); /* keep big blocks on the heap */
		mallopt(M_TRIM_THRESHOLD, 1 << 30); /* and do not give them back */
		warm = time_parses(&b, runs, tw);
		free(tw);
	}
#endif
	printf("{\"bench\":\"wif_parse\",\"ends\":%d,\"picks\":%d,\"shafts\":%d,"
	       "\"treadles\":%d,\"bytes\":%zu,\"runs\":%d,\"median_s\":%.6f,"
	       "\"min_s\":%.6f,\"mb_per_s\":%.1f,\"touch_floor_s\":%.6f,"
	       "\"warm_median_s\":%.6f,\"target_s\":0.1}\n",
	       ENDS, PICKS, SHAFTS, TREADLES, b.n, runs, med, t[0], mbs, floor_s,
	       warm);
	printf("wif_parse: %d ends x %d picks (%zu bytes of WIF): median %.4f s "
	       "(min %.4f s) over %d runs, %.1f MB/s; target < 0.1 s: %s\n"
	       "  fresh-memory floor alone (3 x %d x %d bytes malloc+memset): "
	       "%.4f s; warm parse (memory reused): %.4f s%s\n",
	       ENDS, PICKS, b.n, med, t[0], runs, mbs, med < 0.1 ? "met" : "MISSED",
	       PICKS, ENDS, floor_s, warm, warm < 0 ? " (not measured)" : "");
	free(t);
	free(b.s);
	return 0;
}
