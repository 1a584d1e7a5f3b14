/*
 * bench/bench_scan.c - exemplar creation from scans (paper section 6):
 * wall and CPU time of every pipeline step and of the whole pipeline, with
 * the orientation estimated (structure tensor) and given (the sheet's true
 * tangents), 2 threads; peak resident memory (getrusage ru_maxrss of a
 * child process per run) against the input size; and whether the result is
 * right (weave, rotation, crop against the truth).  Figures, never
 * pass/fail.
 *
 *   build/bench/bench_scan [--quick] [--max N] [--size N] [--estimated-only]
 *                          [--sweep]
 *
 * Sizes: N x N x 0.3 N for N = 250, 500, 1000 (the paper's scans are
 * 1000 x 1000 x 300; --size N runs one of them).  --quick: N = 250 only;
 * --max N: largest N.  The scan is loom_scan_sheet_preset("paper:N"),
 * twill 2/3: warp spacing 0.115 N, weft spacing 0.07 N, turned by 3
 * degrees, blur 0.8, noise 0.08.  The 1000 run holds the input density
 * (1.2 GB of floats; with the orientation given another 3.6 GB) plus the
 * pipeline's arrays (docs/scan.md, "Memory"); it is skipped when
 * /proc/meminfo reports less than 7 GB available.  Generation time is
 * reported apart.
 *
 * --sweep adds a robustness sweep on the unit tests' small sheet (160 x 160
 * x 40, 7 x 9 yarns): 12 scans per noise level 0.08, 0.15, 0.25 (plain,
 * twill 2/3, satin 1/4 in turn; angle uniform in [-5, 5] degrees, offsets
 * in [3, 9] voxels), counting right results, wrong results (must be 0) and
 * errors by code.
 *
 * Prints a human table and JSON lines (starting with '{').
 */
#include "loom.h"
#include "../tests/unit/test_scan_synth.h"

#include <stdio.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_scan [--quick] [--max N] [--size N] [--estimated-only] [--sweep]\n"
	"Exemplar creation from scans: time of each step, peak memory and\n"
	"correctness on N x N x 0.3 N sheets (N = 250, 500, 1000).\n"
	"  --quick           N = 250 only\n"
	"  --max N           the largest N\n"
	"  --size N          only that N\n"
	"  --estimated-only  skip the runs with the orientation given\n"
	"  --sweep           also the robustness sweep over noise levels\n";

static const char *const TWILL23[] = {"10001", "11000", "01100", "00110", "00011", NULL};

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double proc_cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A field of /proc/self/status or /proc/meminfo in kB (-1 if absent). */
static long proc_kb(const char *file, const char *key)
{
	FILE *fp = fopen(file, "r");
	char line[256];
	long v = -1;
	size_t kl = strlen(key);

	if (!fp)
		return -1;
	while (fgets(line, sizeof line, fp))
		if (strncmp(line, key, kl) == 0) {
			v = strtol(line + kl, NULL, 10);
			break;
		}
	fclose(fp);
	return v;
}

static const uint8_t TWILL23_W[25] = {1, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0,
                                      0, 0, 1, 1, 0, 0, 0, 0, 1, 1};

/* One pipeline run in a child process (so each run's peak RSS is its own):
   generate the paper-like sheet of size n (loom_scan_sheet_preset
   "paper:N", twill 2/3), with the true orientation given or not, run
   loom_scan_build with 2 threads, print a table and a JSON line. */
static int run_child(uint32_t n, int given)
{
	loom_scan_sheet s;
	loom_scan_volume v;
	loom_scan_params p;
	loom_scan_result *r = NULL;
	loom_scan_sheet_grid g;
	loom_diag d = {0};
	char name[32];
	struct rusage ru0, ru;
	double t0, tgen, tpipe, cpu0, cpu, rot_err, cx, cy;
	long hwm_gen, hwm;
	int rc, weave_ok = 1;
	size_t voxels;
	double in_mb;

	snprintf(name, sizeof name, "paper:%u", n);
	if (loom_scan_sheet_preset(name, &s) != LOOM_OK)
		return -1;
	s.seed = 2012;
	s.weave = TWILL23_W;
	s.rep_rows = s.rep_cols = 5;
	voxels = (size_t)s.nx * s.ny * s.nz;
	t0 = now_s();
	if (loom_scan_volume_alloc(&v, s.nx, s.ny, s.nz,
	                           LOOM_SCAN_DENSITY | (given ? LOOM_SCAN_ORIENT : 0))) {
		printf("size %u: cannot allocate the scan\n", n);
		return -1;
	}
	loom_scan_sheet_make(&s, &v, NULL, 2, NULL);
	tgen = now_s() - t0;
	in_mb = voxels * (given ? 16.0 : 4.0) / 1048576.0;
	hwm_gen = proc_kb("/proc/self/status", "VmHWM:");
	loom_scan_params_init(&p);
	p.n_warps = s.nw;
	p.n_wefts = s.nf;
	p.threads = 2;
	getrusage(RUSAGE_SELF, &ru0);
	cpu0 = proc_cpu_s();
	t0 = now_s();
	rc = loom_scan_build(&v, &p, &r, &d);
	tpipe = now_s() - t0;
	cpu = proc_cpu_s() - cpu0;
	getrusage(RUSAGE_SELF, &ru);
	hwm = ru.ru_maxrss; /* kB on Linux */
	if (rc) {
		printf("%ux%ux%u: build failed: %s\n", s.nx, s.ny, s.nz, d.message);
		printf("{\"bench\":\"scan\",\"nx\":%u,\"ny\":%u,\"nz\":%u,\"orientation\":\"%s\","
		       "\"error\":\"%s\"}\n", s.nx, s.ny, s.nz, given ? "given" : "estimated",
		       loom_strerror(rc));
		loom_scan_volume_release(&v);
		return -1;
	}
	loom_scan_sheet_truth(&s, &g);
	for (uint32_t i = 0; i < r->rows; i++)
		for (uint32_t j = 0; j < r->cols; j++)
			if (r->weave[i * r->cols + j] !=
			    loom_scan_sheet_w(&s, r->grid.first_weft + i, r->grid.first_warp + j))
				weave_ok = 0;
	rot_err = r->rotation_degrees - s.angle_deg;
	cx = r->grid.crop[0] - (s.x0 + (r->grid.first_warp - 0.5) * s.sx);
	cy = r->grid.crop[1] - (s.y0 + (r->grid.first_weft - 0.5) * s.sy);

	printf("\n%ux%ux%u (%.0f M voxels, %u warps x %u wefts), orientation %s: "
	       "generated in %.1f s\n", s.nx, s.ny, s.nz, voxels / 1e6, s.nw, s.nf,
	       given ? "given" : "estimated", tgen);
	printf("  %-13s %8s %8s %10s\n", "step", "wall s", "CPU s", "ns/voxel");
	for (int k = 0; k < LOOM_SCAN_STEP_COUNT_; k++)
		printf("  %-13s %8.2f %8.2f %10.2f\n", loom_scan_step_name(k), r->seconds[k],
		       r->cpu_seconds[k], 1e9 * r->seconds[k] / voxels);
	printf("  %-13s %8.2f %8.2f %10.2f\n", "total", tpipe, cpu, 1e9 * tpipe / voxels);
	printf("  peak RSS %.0f MB (getrusage; %.0f MB after generating the input, whose "
	       "arrays take %.0f MB: density float%s); crop %ux%ux%u\n",
	       hwm / 1024.0, hwm_gen / 1024.0, in_mb,
	       given ? " + orientation 3 floats" : "", r->volume.nx, r->volume.ny,
	       r->volume.nz);
	printf("  result: weave %s (%ux%u crossings), rotation %.3f (error %+.3f deg), "
	       "crop %d %d %d %d (error %+.1f %+.1f voxels), block %ux%ux%u\n",
	       weave_ok ? "right" : "WRONG", r->cols, r->rows, r->rotation_degrees, rot_err,
	       r->grid.crop[0], r->grid.crop[1], r->grid.crop[2], r->grid.crop[3], cx, cy,
	       r->b1, r->b2, r->b3);
	printf("{\"bench\":\"scan\",\"nx\":%u,\"ny\":%u,\"nz\":%u,\"voxels\":%zu,"
	       "\"orientation\":\"%s\",\"threads\":2,\"generate_s\":%.3f,\"total_s\":%.3f,"
	       "\"cpu_s\":%.3f,", s.nx, s.ny, s.nz, voxels, given ? "given" : "estimated",
	       tgen, tpipe, cpu);
	for (int k = 0; k < LOOM_SCAN_STEP_COUNT_; k++)
		printf("\"%s_s\":%.3f,\"%s_cpu_s\":%.3f,", loom_scan_step_name(k),
		       r->seconds[k], loom_scan_step_name(k), r->cpu_seconds[k]);
	printf("\"input_mb\":%.1f,\"peak_rss_mb\":%.1f,\"weave_ok\":%s,"
	       "\"rotation_error_deg\":%.4f,\"crop_error\":[%.1f,%.1f]}\n",
	       in_mb, hwm / 1024.0, weave_ok ? "true" : "false", rot_err, cx, cy);
	fflush(stdout);
	(void)ru0;
	loom_scan_result_free(r);
	loom_scan_volume_release(&v);
	return 0;
}

static int run_size(uint32_t n, int given)
{
	pid_t pid;
	int st = 0;

	fflush(stdout);
	pid = fork();
	if (pid < 0)
		return run_child(n, given);
	if (pid == 0)
		_exit(run_child(n, given) ? 1 : 0);
	waitpid(pid, &st, 0);
	return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
}

static const char *const PLAIN[] = {"10", "01", NULL};
static const char *const SATIN14[] = {"10000", "00100", "00001", "01000", "00010", NULL};

/* Robustness sweep on the small sheet: right / wrong / error counts. */
static void sweep(void)
{
	static const float noises[3] = {0.08f, 0.15f, 0.25f};
	printf("\nrobustness sweep: 160x160x40, 7 warps x 9 wefts, 12 scans per noise level\n");
	printf("  %-6s %6s %6s %10s %12s   %s\n", "noise", "right", "WRONG", "mismatch",
	       "unsupported", "worst rotation / crop error of the right ones");
	for (int k = 0; k < 3; k++) {
		int right = 0, wrong = 0, mism = 0, unsup = 0;
		double worst_rot = 0, worst_crop = 0;
		for (int t = 0; t < 12; t++) {
			const char *const *w = t % 3 == 0 ? PLAIN : t % 3 == 1 ? TWILL23 : SATIN14;
			synth_spec s = synth_default(w);
			synth_out o;
			loom_scan_params p;
			loom_scan_result *r = NULL;
			loom_diag d = {0};
			uint64_t h = synth_mix(1000 + 100 * k + t);
			int rc, ok = 1;
			s.seed = h;
			s.noise = noises[k];
			s.angle_deg = (float)(synth_unit(synth_mix(h + 1)) * 10 - 5);
			s.x0 = (float)(3 + synth_unit(synth_mix(h + 2)) * 6);
			s.y0 = (float)(3 + synth_unit(synth_mix(h + 3)) * 6);
			if (synth_make(&s, &o))
				continue;
			loom_scan_params_init(&p);
			p.n_warps = s.nw;
			p.n_wefts = s.nf;
			rc = loom_scan_build(&o.vol, &p, &r, &d);
			if (rc == LOOM_EMISMATCH)
				mism++;
			else if (rc)
				unsup++;
			else {
				double er = fabs(r->rotation_degrees - s.angle_deg);
				double ex = fabs(r->grid.crop[0] - (s.x0 + (r->grid.first_warp - 0.5) * s.sx));
				double ey = fabs(r->grid.crop[1] - (s.y0 + (r->grid.first_weft - 0.5) * s.sy));
				for (uint32_t i = 0; i < r->rows; i++)
					for (uint32_t j = 0; j < r->cols; j++)
						if (r->weave[i * r->cols + j] !=
						    synth_w(&s, r->grid.first_weft + i, r->grid.first_warp + j))
							ok = 0;
				if (ok) {
					right++;
					worst_rot = er > worst_rot ? er : worst_rot;
					worst_crop = ex > worst_crop ? ex : worst_crop;
					worst_crop = ey > worst_crop ? ey : worst_crop;
				} else {
					wrong++;
				}
				loom_scan_result_free(r);
			}
			synth_free(&o);
		}
		printf("  %-6.2f %6d %6d %10d %12d   %.3f deg / %.1f voxels\n", noises[k], right,
		       wrong, mism, unsup, worst_rot, worst_crop);
		printf("{\"bench\":\"scan_sweep\",\"noise\":%.2f,\"scans\":12,\"right\":%d,"
		       "\"wrong\":%d,\"mismatch\":%d,\"unsupported\":%d,"
		       "\"worst_rotation_error_deg\":%.4f,\"worst_crop_error\":%.1f}\n",
		       noises[k], right, wrong, mism, unsup, worst_rot, worst_crop);
		fflush(stdout);
	}
}

int main(int argc, char **argv)
{
	uint32_t sizes[] = {250, 500, 1000}, max = 1000;
	int do_sweep = 0, with_given = 1;
	uint32_t only = 0;
	long avail = proc_kb("/proc/meminfo", "MemAvailable:");

	bench_help(argc, argv, USAGE);
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--quick") == 0)
			max = 250;
		else if (strcmp(argv[i], "--max") == 0 && i + 1 < argc)
			max = (uint32_t)strtoul(argv[++i], NULL, 10);
		else if (strcmp(argv[i], "--sweep") == 0)
			do_sweep = 1;
		else if (strcmp(argv[i], "--estimated-only") == 0)
			with_given = 0;
		else if (strcmp(argv[i], "--size") == 0 && i + 1 < argc)
			only = (uint32_t)strtoul(argv[++i], NULL, 10);
		else
			bench_reject("bench_scan", argv[i], USAGE);
	}
	printf("bench_scan: scan pipeline (loom_scan_build), 2 threads; memory "
	       "available %.1f GB\n", avail / 1048576.0);
	for (size_t k = 0; k < sizeof sizes / sizeof *sizes; k++) {
		if (sizes[k] > max)
			break;
		if (only && sizes[k] != only)
			continue;
		if (sizes[k] >= 1000 && avail >= 0 && avail < 7L * 1024 * 1024) {
			printf("\nskipping %ux%ux%u: %.1f GB available, 7 GB needed\n", sizes[k],
			       sizes[k], (uint32_t)(0.3 * sizes[k]), avail / 1048576.0);
			break;
		}
		run_size(sizes[k], 0);
		if (with_given)
			run_size(sizes[k], 1);
	}
	if (do_sweep)
		sweep();
	return 0;
}
