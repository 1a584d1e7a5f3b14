/*
 * bench/bench_export.c - `loom export` and `loom scan` on the paper-scale
 * fabric, through the loom command (figures, never pass/fail).
 *
 * 1. Export rate per format: a 256 x 256 x 300 region (density and
 *    orientation, 128 x 128 tiles, 2 threads) as .vol, NRRD and EXR, and in
 *    the same run a plain sequential write of the same number of bytes into
 *    the same number of files (fwrite, fflush, fsync, fclose), as
 *    bench_volio does.
 * 2. `loom scan --reduce checksum` over a part of the repeat (default 1 %:
 *    x in [0, 17250), all y and z; $LOOM_BENCH_SCAN_FRACTION overrides) at
 *    budgets 16 and 64 MiB on 1 and 2 threads: voxels/s (wall and per CPU
 *    second), peak RSS, and the time extrapolated to the whole repeat
 *    (3.26 x 10^12 voxels).
 *
 * Data: $BUILD/bench/texture-paper.lfab and paper.ldb, made by
 * bench_texture (run it first; this bench skips without them).
 * Output: a table and JSON lines ("{"bench":"export",...}").
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_export\n"
	"`loom export` (.vol, NRRD, EXR) and `loom scan --reduce checksum` on the\n"
	"paper-scale fabric, against plain sequential writes of the same bytes.\n"
	"Needs $BUILD/bench/texture-paper.lfab and paper.ldb (run bench_texture\n"
	"first; skipped without them).\n"
	"Environment: BUILD (default build), LOOM_BENCH_SCAN_FRACTION (part of the\n"
	"repeat scanned, default 0.01), TMPDIR.\n";

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Run a command, return its stdout (malloc'ed) or NULL. */
static char *run(const char *cmd)
{
	FILE *p = popen(cmd, "r");
	char *buf;
	size_t n = 0, cap = 1 << 16;

	if (!p)
		return NULL;
	buf = malloc(cap);
	if (!buf) {
		pclose(p);
		return NULL;
	}
	for (;;) {
		size_t got = fread(buf + n, 1, cap - n - 1, p);
		n += got;
		if (got == 0)
			break;
		if (cap - n < 1024) {
			char *nb = realloc(buf, cap * 2);
			if (!nb)
				break;
			buf = nb;
			cap *= 2;
		}
	}
	buf[n] = 0;
	if (pclose(p) != 0) {
		fprintf(stderr, "bench_export: failed: %s\n%s\n", cmd, buf);
		free(buf);
		return NULL;
	}
	return buf;
}

static double key_num(const char *json, const char *key)
{
	char pat[64];
	const char *p;

	snprintf(pat, sizeof pat, "\"%s\": ", key);
	p = strstr(json, pat);
	return p ? strtod(p + strlen(pat), NULL) : -1;
}

static void key_str(const char *json, const char *key, char *out, size_t n)
{
	char pat[64];
	const char *p;
	size_t i = 0;

	out[0] = 0;
	snprintf(pat, sizeof pat, "\"%s\": \"", key);
	p = strstr(json, pat);
	if (!p)
		return;
	for (p += strlen(pat); *p && *p != '"' && i + 1 < n; p++)
		out[i++] = *p;
	out[i] = 0;
}

/* Plain write of `bytes` bytes into `files` files in dir; seconds. */
static double plain_write(const char *dir, double bytes, double files)
{
	static char block[1 << 20];
	long nf = files > 0 ? (long)files : 1;
	double per = (double)(long long)(bytes / (double)nf + 0.5), t0 = now_s();

	memset(block, 0x5a, sizeof block);
	for (long f = 0; f < nf; f++) {
		char path[4096];
		FILE *fp;
		double left = per;
		snprintf(path, sizeof path, "%s/plain-%ld.bin", dir, f);
		fp = fopen(path, "wb");
		if (!fp)
			return -1;
		while (left > 0) {
			size_t n = left < (double)sizeof block ? (size_t)left : sizeof block;
			if (fwrite(block, 1, n, fp) != n)
				break;
			left -= (double)n;
		}
		fflush(fp);
		fsync(fileno(fp));
		fclose(fp);
	}
	return now_s() - t0;
}

int main(int argc, char **argv)
{
	const char *build = getenv("BUILD") ? getenv("BUILD") : "build";
	const char *frac_s = getenv("LOOM_BENCH_SCAN_FRACTION");
	const char *tmp = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
	double frac = frac_s ? atof(frac_s) : 0.01;
	char loom[1024], fab[1024], dir[1024], cmd[4096];

	bench_help(argc, argv, USAGE);
	if (argc > 1)
		bench_reject("bench_export", argv[1], USAGE);
	static const char *const fmts[] = {"vol", "nrrd", "exr"};
	struct stat st;

	snprintf(loom, sizeof loom, "%s/loom", build);
	snprintf(fab, sizeof fab, "%s/bench/texture-paper.lfab", build);
	setvbuf(stdout, NULL, _IOLBF, 0);
	if (stat(loom, &st) != 0 || stat(fab, &st) != 0) {
		printf("bench_export: %s or %s missing (run make and bench_texture first): "
		       "skipped\n", loom, fab);
		return 0;
	}
	if (!(frac > 0 && frac <= 1))
		frac = 0.01;
	snprintf(dir, sizeof dir, "%s/loom-bench-export.%ld", tmp, (long)getpid());

	printf("1. export of 256 x 256 x 300 voxels (density, orientation; tiles 128 x "
	       "128; 2 threads) vs a plain write of the same bytes and files\n");
	printf("%-6s %10s %8s %9s %10s %9s %7s\n", "format", "MiB", "files", "export s",
	       "plain s", "ratio", "MiB/s");
	for (int f = 0; f < 3; f++) {
		char *out;
		double secs, bytes, files, plain;
		snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s", dir, dir);
		if (system(cmd) != 0)
			return 1;
		snprintf(cmd, sizeof cmd, "%s export %s --region 0,0,0:256,256,300 --format %s "
		         "--channels density,orientation --tile 128,128 --threads 2 --quiet "
		         "--json -o %s/out", loom, fab, fmts[f], dir);
		out = run(cmd);
		if (!out)
			continue;
		secs = key_num(out, "seconds");
		bytes = key_num(out, "bytes_written");
		files = key_num(out, "files_written");
		free(out);
		plain = plain_write(dir, bytes, files);
		printf("%-6s %10.1f %8.0f %9.3f %10.3f %9.2f %7.1f\n", fmts[f], bytes / 1048576.0,
		       files, secs, plain, plain > 0 ? secs / plain : 0, bytes / 1048576.0 / secs);
		printf("{\"bench\":\"export\",\"format\":\"%s\",\"voxels\":%d,\"bytes\":%.0f,"
		       "\"files\":%.0f,\"seconds\":%.4f,\"plain_seconds\":%.4f,\"ratio\":%.3f}\n",
		       fmts[f], 256 * 256 * 300, bytes, files, secs, plain,
		       plain > 0 ? secs / plain : 0);
	}
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	if (system(cmd) != 0)
		return 1;

	{
		long x1 = (long)(172500 * frac + 0.5);
		double voxels = (double)x1 * 63000.0 * 300.0, whole = 172500.0 * 63000.0 * 300.0;
		printf("\n2. loom scan --reduce checksum over x in [0, %ld) of the repeat "
		       "(%.3g voxels, %.2f %%)\n", x1, voxels, 100.0 * frac);
		printf("%-7s %-7s %9s %9s %12s %14s %10s %12s %s\n", "budget", "threads",
		       "wall s", "CPU s", "voxels/s", "voxels/CPU s", "RSS MiB",
		       "whole (h)", "checksum");
		for (int b = 0; b < 2; b++)
			for (int t = 1; t <= 2; t++) {
				int budget = b ? 64 : 16;
				char cs[32], *out;
				double secs, cpu, rss, rate;
				snprintf(cmd, sizeof cmd, "%s scan %s --region 0,0,0:%ld,63000,300 "
				         "--reduce checksum --threads %d --budget %d --quiet --json",
				         loom, fab, x1, t, budget);
				out = run(cmd);
				if (!out)
					continue;
				secs = key_num(out, "seconds");
				cpu = key_num(out, "cpu_seconds");
				rss = key_num(out, "peak_rss_bytes");
				rate = key_num(out, "voxels_per_second");
				key_str(out, "checksum", cs, sizeof cs);
				free(out);
				printf("%-7d %-7d %9.2f %9.2f %12.4g %14.4g %10.1f %12.2f %s\n", budget,
				       t, secs, cpu, rate, voxels / cpu, rss / 1048576.0,
				       whole / rate / 3600.0, cs);
				printf("{\"bench\":\"scan\",\"budget_mb\":%d,\"threads\":%d,\"voxels\":%.0f,"
				       "\"seconds\":%.3f,\"cpu_seconds\":%.3f,\"voxels_per_second\":%.4g,"
				       "\"voxels_per_cpu_second\":%.4g,\"peak_rss_bytes\":%.0f,"
				       "\"whole_repeat_hours\":%.3f,\"checksum\":\"%s\"}\n", budget, t,
				       voxels, secs, cpu, rate, voxels / cpu, rss, whole / rate / 3600.0, cs);
			}
	}
	return 0;
}
