/*
 * bench/bench_volio.c - export write throughput: Mitsuba .vol and OpenEXR
 * z-slices against a plain sequential fwrite of the same bytes.
 *
 *   build/bench/bench_volio [N [RUNS [DIR]]]   (default 256, 3 runs,
 *                                               DIR build/bench/volio-tmp)
 *
 * The volume is N^3 voxels of yarn-like data, made in memory first (not
 * timed): elliptical yarns along x and y, density a smooth bump inside
 * them (about 70% of voxels empty), orientation the yarn direction, albedo
 * one colour per yarn family.  Each case writes the volume and includes
 * closing the file(s) and fsync, as the atomic writers do; the baseline
 * writes the byte count the case's format stores uncompressed
 * (header + voxel data for .vol, the raw pixel data for EXR) with fwrite,
 * fflush, fsync and fclose.  Medians of RUNS of wall time and of process
 * CPU time (user + system; robust to other load and to fsync waits);
 * ratio = format / fwrite, for each.  Prints a table and one JSON line per case.
 */
#include "loom.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_volio [N [RUNS [DIR]]]\n"
	"Export write throughput: Mitsuba .vol and OpenEXR z-slices of an N^3\n"
	"volume against a plain sequential write of the same bytes.\n"
	"  N          volume side, at least 16 (default 256)\n"
	"  RUNS       repetitions, medians (default 3)\n"
	"  DIR        where the files go (default build/bench/volio-tmp)\n";

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double cpu_now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_d(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof *v, cmp_d);
	return v[n / 2];
}

static int N, RUNS;
static char DIR_[1024];
static float *dens, *orient, *albedo; /* N^3, N^3*3, N^3*3 */

static void make_volume(void)
{
	size_t n = (size_t)N * N * N;
	double pitch = N / 4.0, a = pitch * 0.45, b = N * 0.12;

	dens = malloc(n * 4);
	orient = malloc(n * 12);
	albedo = malloc(n * 12);
	if (!dens || !orient || !albedo)
		exit(1);
	for (int z = 0; z < N; z++)
		for (int y = 0; y < N; y++)
			for (int x = 0; x < N; x++) {
				size_t i = ((size_t)z * N + y) * N + x;
				/* warps run along y (centre x), wefts along x (centre y) */
				double dx = fmod(x + 0.5, pitch) - pitch / 2;
				double dy = fmod(y + 0.5, pitch) - pitch / 2;
				double zw = N * (0.5 + 0.15 * cos(2 * M_PI * y / (2 * pitch)));
				double zf = N * (0.5 - 0.15 * cos(2 * M_PI * x / (2 * pitch)));
				double rw = (dx / a) * (dx / a) + ((z - zw) / b) * ((z - zw) / b);
				double rf = (dy / a) * (dy / a) + ((z - zf) / b) * ((z - zf) / b);
				float d = 0, o[3] = {0, 0, 0}, c[3] = {0, 0, 0};
				if (rw < 1 && rw <= rf) {
					d = (float)(1 - rw);
					o[1] = 1;
					c[0] = 0.8f; c[1] = 0.2f; c[2] = 0.1f;
				} else if (rf < 1) {
					d = (float)(1 - rf);
					o[0] = 1;
					c[0] = 0.1f; c[1] = 0.3f; c[2] = 0.7f;
				}
				dens[i] = d;
				memcpy(orient + 3 * i, o, 12);
				memcpy(albedo + 3 * i, c, 12);
			}
}

static const char *path_in_dir(const char *name)
{
	static char buf[1200];
	snprintf(buf, sizeof buf, "%s/%s", DIR_, name);
	return buf;
}

/* Baseline: write `bytes` bytes in `files` files of equal size, from a
   buffer of real data, in pieces of `piece` bytes. */
static double time_fwrite(uint64_t bytes, int files, size_t piece)
{
	uint64_t per = bytes / (uint64_t)files;
	const uint8_t *src = (const uint8_t *)dens;
	size_t src_len = (size_t)N * N * N * 4;
	double t0 = now();
	for (int f = 0; f < files; f++) {
		FILE *fp = fopen(path_in_dir("plain.bin"), "wb");
		uint64_t left = per, off = 0;
		if (!fp)
			exit(1);
		while (left) {
			size_t k = left < piece ? (size_t)left : piece;
			if ((size_t)(off % src_len) + k > src_len)
				off = 0;
			if (fwrite(src + off % src_len, 1, k, fp) != k)
				exit(1);
			left -= k;
			off += k;
		}
		fflush(fp);
		fsync(fileno(fp));
		fclose(fp);
	}
	return now() - t0;
}

/* .vol of one channel set: encoding enc, ch channels from src. */
static double time_vol(int enc, uint32_t ch, const float *src, uint64_t *bytes)
{
	loom_vol_header h = {enc, (uint32_t)N, (uint32_t)N, (uint32_t)N, ch,
	                     {0, 0, 0}, {N * 0.005f, N * 0.005f, N * 0.005f}};
	loom_vol_writer *w;
	loom_diag d = {0};
	double t0 = now();
	struct stat st;

	if (loom_vol_writer_open(path_in_dir("b.vol"), &h, &w, &d)) {
		fprintf(stderr, "bench_volio: %s\n", d.message);
		exit(1);
	}
	for (int z = 0; z < N; z++)
		if (loom_vol_writer_put_slices(w, src + (size_t)z * N * N * ch, 1, &d)) {
			fprintf(stderr, "bench_volio: %s\n", d.message);
			exit(1);
		}
	if (loom_vol_writer_finish(w, &d)) {
		fprintf(stderr, "bench_volio: %s\n", d.message);
		exit(1);
	}
	t0 = now() - t0;
	stat(path_in_dir("b.vol"), &st);
	*bytes = (uint64_t)st.st_size;
	return t0;
}

/* EXR slices: channels density (+ orientation.xyz, R G B when full). */
static double time_exr(int full, int half, int openexr_zip, uint64_t *raw_bytes,
                       uint64_t *file_bytes)
{
	loom_exr_channel ch[7] = {
		{"density", LOOM_EXR_FLOAT},      {"orientation.x", LOOM_EXR_FLOAT},
		{"orientation.y", LOOM_EXR_FLOAT}, {"orientation.z", LOOM_EXR_FLOAT},
		{"R", LOOM_EXR_FLOAT},            {"G", LOOM_EXR_FLOAT},
		{"B", LOOM_EXR_FLOAT}};
	uint32_t nch = full ? 7 : 1;
	float *row = malloc((size_t)N * nch * 4);
	double t0;
	uint64_t total = 0;

	for (uint32_t c = 1; c < nch; c++)
		if (half)
			ch[c].pixel = LOOM_EXR_HALF;
	*raw_bytes = 0;
	for (uint32_t c = 0; c < nch; c++)
		*raw_bytes += (uint64_t)N * N * N * (ch[c].pixel == LOOM_EXR_HALF ? 2 : 4);
	t0 = now();
	for (int z = 0; z < N; z++) {
		loom_exr_writer *w;
		loom_exr_stats st;
		loom_exr_options o = LOOM_EXR_OPTIONS_INIT;
		loom_diag d = {0};
		char name[64];
		o.stats = &st;
		o.openexr_zip = openexr_zip;
		o.has_slice = 1;
		o.slice_z = z;
		snprintf(name, sizeof name, "s%04d.exr", z);
		if (loom_exr_writer_open(path_in_dir(name), (uint32_t)N, (uint32_t)N, ch,
		                         nch, &o, &w, &d)) {
			fprintf(stderr, "bench_volio: %s\n", d.message);
			exit(1);
		}
		for (int y = 0; y < N; y++) {
			size_t base = ((size_t)z * N + y) * N;
			for (int x = 0; x < N; x++) {
				float *p = row + (size_t)x * nch;
				p[0] = dens[base + x];
				if (full) {
					memcpy(p + 1, orient + 3 * (base + x), 12);
					memcpy(p + 4, albedo + 3 * (base + x), 12);
				}
			}
			if (loom_exr_writer_put_rows(w, row, 1, &d)) {
				fprintf(stderr, "bench_volio: %s\n", d.message);
				exit(1);
			}
		}
		if (loom_exr_writer_finish(w, &d)) {
			fprintf(stderr, "bench_volio: %s\n", d.message);
			exit(1);
		}
		total += st.file_bytes;
	}
	t0 = now() - t0;
	*file_bytes = total;
	for (int z = 0; z < N; z++) {
		char name[64];
		snprintf(name, sizeof name, "s%04d.exr", z);
		unlink(path_in_dir(name));
	}
	free(row);
	return t0;
}

static void report(const char *name, uint64_t raw, uint64_t file, double t,
                   double tbase, double cpu, double cpubase)
{
	double mib = (double)raw / (1 << 20);
	printf("%-34s %7.1f %7.1f %7.3f %7.1f %6.3f | %7.3f %7.1f %6.3f | %5.2f %5.2f\n",
	       name, mib, (double)file / (1 << 20), t, mib / t, cpu, tbase,
	       mib / tbase, cpubase, t / tbase, cpu / cpubase);
	printf("{\"bench\":\"volio\",\"case\":\"%s\",\"voxels\":%llu,\"raw_bytes\":%llu,"
	       "\"file_bytes\":%llu,\"seconds\":%.4f,\"mib_per_s\":%.1f,"
	       "\"cpu_seconds\":%.4f,\"fwrite_seconds\":%.4f,"
	       "\"fwrite_mib_per_s\":%.1f,\"fwrite_cpu_seconds\":%.4f,"
	       "\"ratio\":%.3f,\"cpu_ratio\":%.3f}\n",
	       name, (unsigned long long)N * N * N, (unsigned long long)raw,
	       (unsigned long long)file, t, mib / t, cpu, tbase, mib / tbase,
	       cpubase, t / tbase, cpu / cpubase);
	fflush(stdout);
}

int main(int argc, char **argv)
{
	static const struct {
		const char *name;
		int enc;
		uint32_t ch;
		int src; /* 0 density, 1 orientation, 2 albedo */
	} vols[] = {
		{"vol density float32", LOOM_VOL_FLOAT32, 1, 0},
		{"vol density uint8", LOOM_VOL_UINT8, 1, 0},
		{"vol orientation float32 x3", LOOM_VOL_FLOAT32, 3, 1},
		{"vol orientation qdir", LOOM_VOL_QDIR, 3, 1},
		{"vol albedo uint8 x3", LOOM_VOL_UINT8, 3, 2},
	};
	bench_help(argc, argv, USAGE);
	if (argc > 4)
		bench_reject("bench_volio", argv[4], USAGE);
	if (argc > 1 && !bench_int_in(argv[1], 16, 4096))
		bench_reject("bench_volio", argv[1], USAGE);
	if (argc > 2 && !bench_int_in(argv[2], 1, 1000))
		bench_reject("bench_volio", argv[2], USAGE);
	N = argc > 1 ? atoi(argv[1]) : 256;
	RUNS = argc > 2 ? atoi(argv[2]) : 3;
	snprintf(DIR_, sizeof DIR_, "%s", argc > 3 ? argv[3] : "build/bench/volio-tmp");
	mkdir(DIR_, 0777);
	make_volume();
	printf("bench_volio: %d^3 voxels, %d runs (medians), files in %s\n", N, RUNS, DIR_);
	printf("%-34s %7s %7s %7s %7s %6s | %7s %7s %6s | %5s %5s\n", "case",
	       "raw MiB", "file", "wall s", "MiB/s", "cpu s", "fwrite", "MiB/s",
	       "cpu s", "ratio", "cpu");
	for (size_t k = 0; k < sizeof vols / sizeof vols[0]; k++) {
		double t[16], tb[16], c[16], cb[16], c0;
		uint64_t bytes = 0;
		const float *src = vols[k].src == 0 ? dens : vols[k].src == 1 ? orient : albedo;
		for (int r = 0; r < RUNS && r < 16; r++) {
			c0 = cpu_now();
			t[r] = time_vol(vols[k].enc, vols[k].ch, src, &bytes);
			c[r] = cpu_now() - c0;
			c0 = cpu_now();
			tb[r] = time_fwrite(bytes, 1, (size_t)N * N * 4);
			cb[r] = cpu_now() - c0;
		}
		report(vols[k].name, bytes, bytes, median(t, RUNS), median(tb, RUNS),
		       median(c, RUNS), median(cb, RUNS));
	}
	unlink(path_in_dir("b.vol"));
	for (int k = 0; k < 5; k++) {
		static const struct {
			const char *name;
			int full, half, openexr_zip;
		} ex[5] = {
			{"exr density float", 0, 0, 0},
			{"exr density float, OpenEXR zlib", 0, 0, 1},
			{"exr 7 float channels", 1, 0, 0},
			{"exr density f32 + 6 half", 1, 1, 0},
			{"exr density f32 + 6 half, OpenEXR", 1, 1, 1},
		};
		double t[16], tb[16], c[16], cb[16], c0;
		uint64_t raw = 0, file = 0;
		for (int r = 0; r < RUNS && r < 16; r++) {
			c0 = cpu_now();
			t[r] = time_exr(ex[k].full, ex[k].half, ex[k].openexr_zip, &raw, &file);
			c[r] = cpu_now() - c0;
			c0 = cpu_now();
			tb[r] = time_fwrite(raw, N, (size_t)N * 4 * 16);
			cb[r] = cpu_now() - c0;
		}
		report(ex[k].name, raw, file, median(t, RUNS), median(tb, RUNS),
		       median(c, RUNS), median(cb, RUNS));
	}
	unlink(path_in_dir("plain.bin"));
	rmdir(DIR_);
	free(dens);
	free(orient);
	free(albedo);
	return 0;
}
