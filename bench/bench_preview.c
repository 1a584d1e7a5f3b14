/*
 * bench/bench_preview.c - figures of the designer's pictures (never pass/fail):
 *
 *   1. loom_preview_stream of the whole paper-scale fabric (900 x 1500
 *      crossings of 115 x 70 x 300 voxels, the paper preset database) at
 *      4096 and 1024 pixels wide, 2 threads, 16 MiB of preview memory and a
 *      48 MiB brick cache (the blocks filter: 42 voxel columns per pixel);
 *      target: 4096 px in at most 10 s.  Peer in the same run: the exact
 *      filter on a 1024 x 1024 window at 1:1 (every column read), whose
 *      rate in columns per second says what reading all 10.9 G columns of
 *      the repeat would cost.
 *   2. `loom look` (the command, a child process) of a 200 x 200 draft on
 *      the default database: seconds to its first render and to its last
 *      file; target: under 30 s.
 * Load average printed before each part (the machine is shared); the
 * figures interleave repetitions and keep the best and the median.
 *
 *   build/bench/bench_preview [PARTS]    PARTS: digits (default 12)
 */
#include "loom.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_preview [PARTS]\n"
	"The designer's pictures: 1 the whole paper-scale fabric streamed as a\n"
	"preview at 4096 and 1024 pixels; 2 `loom look` of a 200 x 200 draft.\n"
	"  PARTS      digits of the parts to run (default 12)\n"
	"Environment: BUILD (default build), LOOM_PAPER_DB.\n";

#define MIB ((size_t)1 << 20)

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void loadavg(const char *when)
{
	double l[3] = {0, 0, 0};
	FILE *fp = fopen("/proc/loadavg", "r");
	if (fp) {
		if (fscanf(fp, "%lf %lf %lf", &l[0], &l[1], &l[2]) != 3)
			l[0] = -1;
		fclose(fp);
	}
	printf("load average %.2f %.2f %.2f (%s)\n", l[0], l[1], l[2], when);
}

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

/* 900 x 1500: twill 2/3 and satin 4/1 over a blocky random mask, two
   yarn colours, like bench_texture's Jacquard design. */
static loom_design *jacquard(uint32_t rows, uint32_t cols)
{
	loom_design *d = NULL;
	if (loom_design_new(rows, cols, &d) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++) {
			int m = (int)(mix((uint64_t)(i / 60) * 977 + j / 60) & 1);
			size_t p = (size_t)i * cols + j;
			d->weave[p] = m ? ((i + 5 - j % 5) % 5 < 2) : ((i * 2 + j * 3) % 5 != 0);
		}
	d->types[0].albedo[0] = 0.6f;
	d->types[0].albedo[1] = 0.08f;
	d->types[0].albedo[2] = 0.07f;
	d->types[1].albedo[0] = 0.75f;
	d->types[1].albedo[1] = 0.65f;
	d->types[1].albedo[2] = 0.4f;
	return d;
}

static int discard(void *user, const loom_preview_band *b)
{
	(void)user;
	(void)b;
	return 0;
}

static int cmp_d(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static void part_paper(const char *build)
{
	char dbp[8300];
	loom_db *db = NULL;
	loom_design *d;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_diag diag = {0};
	struct stat st;
	uint64_t rep[3];
	double t0, ts[2][3];
	loom_preview_stats ps[2];
	const char *paper = getenv("LOOM_PAPER_DB");

	if (paper && *paper)
		snprintf(dbp, sizeof dbp, "%s", paper);
	else
		snprintf(dbp, sizeof dbp, "%s/bench/paper.ldb", build);
	if (stat(dbp, &st) != 0) {
		loom_exgen_params p;
		printf("generating the paper preset database %s (once)\n", dbp);
		fflush(stdout);
		loom_exgen_preset("paper", &p);
		if (loom_exgen_write_db(dbp, &p, NULL, &diag) != LOOM_OK) {
			printf("bench_preview: %s\n", diag.message);
			return;
		}
	}
	if (loom_db_open(dbp, &db, &diag) != LOOM_OK) {
		printf("bench_preview: %s\n", diag.message);
		return;
	}
	d = jacquard(900, 1500);
	t0 = now_s();
	if (!d || loom_fabric_synthesize(d, db, dbp, NULL, &f, &diag) != LOOM_OK) {
		printf("bench_preview: synthesis: %s\n", diag.message);
		return;
	}
	printf("paper-scale fabric 900x1500 synthesized in %.1f s\n", now_s() - t0);
	loom_fabric_repeat_voxels(f, rep);
	o.budget_bytes = 48 * MIB;
	o.max_threads = 4;
	if (loom_texture_open(f, db, &o, &t, &diag) != LOOM_OK) {
		printf("bench_preview: %s\n", diag.message);
		return;
	}
	loadavg("before the whole-repeat previews");
	/* interleaved: 4096, 1024, 4096, 1024, ... */
	for (int r = 0; r < 3; r++)
		for (int k = 0; k < 2; k++) {
			loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
			po.hi[0] = (int64_t)rep[0];
			po.hi[1] = (int64_t)rep[1];
			po.width = k == 0 ? 4096 : 1024;
			po.threads = 2;
			po.memory_bytes = 16 * MIB;
			t0 = now_s();
			if (loom_preview_stream(t, f, &po, discard, NULL, &ps[k], &diag) != LOOM_OK) {
				printf("bench_preview: %s\n", diag.message);
				return;
			}
			ts[k][r] = now_s() - t0;
		}
	for (int k = 0; k < 2; k++) {
		qsort(ts[k], 3, sizeof ts[k][0], cmp_d);
		printf("whole repeat (%llu x %llu voxels) at %u px: best %.2f s, median %.2f s; "
		       "blocks filter, %u tables of %u-voxel texels, %llu columns read, %.1f MiB "
		       "working memory\n", (unsigned long long)rep[0], (unsigned long long)rep[1],
		       k == 0 ? 4096u : 1024u, ts[k][0], ts[k][1], ps[k].blocks, ps[k].texel,
		       (unsigned long long)ps[k].columns, (double)ps[k].memory_bytes / MIB);
		printf("{\"bench\":\"preview_whole_repeat\",\"width\":%u,\"best_s\":%.3f,"
		       "\"median_s\":%.3f,\"blocks\":%u,\"columns\":%llu,\"memory_bytes\":%zu}\n",
		       k == 0 ? 4096u : 1024u, ts[k][0], ts[k][1], ps[k].blocks,
		       (unsigned long long)ps[k].columns, ps[k].memory_bytes);
	}
	/* peer: every column of a 1024 x 1024 window, exact filter */
	{
		loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
		loom_preview_stats s;
		double best = 1e9;
		po.lo[0] = 5000;
		po.lo[1] = 3000;
		po.hi[0] = 5000 + 1024;
		po.hi[1] = 3000 + 1024;
		po.width = 1024;
		po.threads = 2;
		po.filter = LOOM_PREVIEW_EXACT;
		for (int r = 0; r < 2; r++) {
			t0 = now_s();
			if (loom_preview_stream(t, f, &po, discard, NULL, &s, &diag) != LOOM_OK) {
				printf("bench_preview: %s\n", diag.message);
				return;
			}
			if (now_s() - t0 < best)
				best = now_s() - t0;
		}
		printf("exact filter, 1024 x 1024 window at 1:1: %.2f s, %.2f M columns/s; all "
		       "%.1f G columns of the repeat would take %.0f s\n", best,
		       (double)s.columns / best / 1e6, (double)rep[0] * rep[1] / 1e9,
		       (double)rep[0] * rep[1] / ((double)s.columns / best));
		printf("{\"bench\":\"preview_exact_window\",\"seconds\":%.3f,\"columns_per_s\":%.0f}\n",
		       best, (double)s.columns / best);
	}
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(db);
}

static void part_look(const char *build)
{
	char cmd[20000], tmp[] = "/tmp/bench_look.XXXXXX", line[4096];
	FILE *fp;
	double first = -1, last = -1, t0;

	if (!mkdtemp(tmp))
		return;
	loadavg("before loom look");
	snprintf(cmd, sizeof cmd, "%s/loom pattern make herringbone:2/2:period=25 --size 200x200 "
	         "-o %s/d200.png && cd %s && %s/loom look d200.png -o look 2>&1", build, tmp, tmp,
	         build);
	t0 = now_s();
	fp = popen(cmd, "r");
	if (!fp)
		return;
	while (fgets(line, sizeof line, fp)) {
		double at;
		char path[4096];
		if (sscanf(line, "loom look: %lf s %4095s", &at, path) == 2) {
			if (strstr(path, "-render.png") && first < 0)
				first = at;
			last = at;
		}
	}
	pclose(fp);
	printf("loom look of a 200 x 200 draft: first render at %.1f s, last file at %.1f s "
	       "(%.1f s in all)\n", first, last, now_s() - t0);
	printf("{\"bench\":\"look_200\",\"first_render_s\":%.2f,\"last_file_s\":%.2f}\n",
	       first, last);
	snprintf(cmd, sizeof cmd, "rm -rf %s", tmp);
	if (system(cmd) != 0)
		printf("bench_preview: could not remove %s\n", tmp);
}

int main(int argc, char **argv)
{
	const char *build = getenv("BUILD");
	const char *parts = argc > 1 ? argv[1] : "12";
	char top[4000];

	bench_help(argc, argv, USAGE);
	if (argc > 2 || !bench_digits_in(parts, "12"))
		bench_reject("bench_preview", argv[argc > 2 ? 2 : 1], USAGE);
	if (!build || !*build)
		build = "build";
	if (build[0] != '/' && getcwd(top, sizeof top)) {
		static char abs_build[4200];
		snprintf(abs_build, sizeof abs_build, "%s/%s", top, build);
		build = abs_build;
	}
	if (strchr(parts, '1'))
		part_paper(build);
	if (strchr(parts, '2'))
		part_look(build);
	return 0;
}
