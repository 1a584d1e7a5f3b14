/*
 * bench/bench_db.c - exemplar database figures (never pass/fail):
 *
 *   1. brick shape study on one paper-scale exemplar (575 x 350 x 300,
 *      twill 2/3): for each shape and libdeflate level 1, 6, 9 the
 *      compression ratio, compression MB/s, decompression GiB/s of voxels
 *      (4 bytes each) on one core, and the cost of reading one full z-run
 *      (a voxel column) cold: every brick it touches read from the
 *      compressed store and decompressed;
 *   2. generation time of the small and paper presets (2 threads);
 *   3. reader open time and resident memory (in a fresh child process).
 *
 *   build/bench/bench_db [--quick] [--fibre F]
 *       --quick: fewer shapes, no paper DB; --fibre F: fibre-level yarns of
 *       preset F (cotton, ...) instead of the smooth ones
 *
 * Prints a human table and JSON lines (starting with '{').
 */
#include "exemplar/db_internal.h"
#include "exemplar/exgen.h"

#include <libdeflate.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_db [--quick] [--fibre F]\n"
	"Exemplar database figures: brick shapes and deflate levels on a\n"
	"paper-scale exemplar, generation time of the presets, open time and memory.\n"
	"  --quick    fewer shapes, no paper-scale database\n"
	"  --fibre F  fibre-level yarns of preset F (cotton, ...) instead of smooth\n"
	"Environment: TMPDIR (the databases written, removed after).\n";

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of the calling thread: single-core figures stay meaningful on a
   machine shared with other jobs. */
static double cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* CPU time of the whole process (all threads). */
static double proc_cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* VmHWM and VmRSS in kB from /proc/self/status. */
static void mem_kb(long *hwm, long *rss)
{
	FILE *fp = fopen("/proc/self/status", "r");
	char line[256];

	*hwm = *rss = -1;
	if (!fp)
		return;
	while (fgets(line, sizeof line, fp)) {
		if (strncmp(line, "VmHWM:", 6) == 0)
			*hwm = strtol(line + 6, NULL, 10);
		else if (strncmp(line, "VmRSS:", 6) == 0)
			*rss = strtol(line + 6, NULL, 10);
	}
	fclose(fp);
}

/* ---- child mode: open a database and report ------------------------------- */

static int child_open(const char *path)
{
	loom_db *db;
	loom_diag d = {0};
	loom_db_info info;
	double t0 = now_s(), t1;
	long hwm, rss, hwm2, rss2;
	loom__db_geom geo;
	struct libdeflate_decompressor *dec;
	uint8_t *brick, *scratch;
	uint64_t nread = 0;

	if (loom_db_open(path, &db, &d) != LOOM_OK) {
		fprintf(stderr, "%s\n", d.message);
		return 1;
	}
	t1 = now_s();
	mem_kb(&hwm, &rss);
	loom_db_get_info(db, &info);
	/* then read every brick once through one buffer: memory must not grow */
	loom__db_geometry(db, &geo);
	dec = libdeflate_alloc_decompressor();
	brick = malloc(geo.brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	for (uint32_t id = 0; id < geo.n_bricks; id++) {
		size_t n = 0;
		if (loom__db_read_brick(db, id, dec, scratch, brick, &n, &d) != LOOM_OK) {
			fprintf(stderr, "%s\n", d.message);
			return 1;
		}
		nread += n;
	}
	mem_kb(&hwm2, &rss2);
	printf("{\"bench\":\"db_open\",\"file_bytes\":%llu,\"metadata_bytes\":%llu,"
	       "\"open_ms\":%.3f,\"vmhwm_kb_after_open\":%ld,\"vmrss_kb_after_open\":%ld,"
	       "\"vmhwm_kb_after_all_bricks\":%ld,\"vmrss_kb_after_all_bricks\":%ld,"
	       "\"bricks\":%u,\"bytes_read\":%llu}\n",
	       (unsigned long long)info.file_bytes, (unsigned long long)info.metadata_bytes,
	       1000 * (t1 - t0), hwm, rss, hwm2, rss2, geo.n_bricks,
	       (unsigned long long)nread);
	free(brick);
	free(scratch);
	libdeflate_free_decompressor(dec);
	loom_db_close(db);
	return 0;
}

static void run_child(const char *self, const char *path)
{
	pid_t pid = fork();
	if (pid == 0) {
		execl(self, self, "--open", path, (char *)NULL);
		_exit(127);
	}
	if (pid > 0)
		waitpid(pid, NULL, 0);
}

/* ---- shape study ------------------------------------------------------------ */

typedef struct volume {
	uint32_t s[3];
	uint8_t *d, *l;   /* column-major, z fastest: ((y*sx)+x)*sz + z */
	uint16_t *o;
} volume;

static void pack(const volume *v, const uint32_t bs[3], uint32_t bx, uint32_t by,
                 uint32_t bz, uint8_t *out)
{
	size_t nv = (size_t)bs[0] * bs[1] * bs[2];

	memset(out, 0, 4 * nv);
	for (uint32_t ly = 0; ly < bs[1]; ly++)
		for (uint32_t lx = 0; lx < bs[0]; lx++) {
			uint32_t x = bx * bs[0] + lx, y = by * bs[1] + ly, z0 = bz * bs[2];
			size_t src, dst = ((size_t)ly * bs[0] + lx) * bs[2];
			uint32_t n;
			if (x >= v->s[0] || y >= v->s[1] || z0 >= v->s[2])
				continue;
			n = v->s[2] - z0 < bs[2] ? v->s[2] - z0 : bs[2];
			src = ((size_t)y * v->s[0] + x) * v->s[2] + z0;
			memcpy(out + dst, v->d + src, n);
			memcpy(out + 3 * nv + dst, v->l + src, n);
			for (uint32_t z = 0; z < n; z++) {
				out[nv + dst + z] = (uint8_t)v->o[src + z];
				out[2 * nv + dst + z] = (uint8_t)(v->o[src + z] >> 8);
			}
		}
}

typedef struct cbrick {
	uint8_t *data;   /* NULL = empty */
	uint32_t size;
	int raw;
} cbrick;

static void study(const volume *v, const uint32_t bs[3], int level, int json_only)
{
	uint32_t nb[3];
	size_t nv = (size_t)bs[0] * bs[1] * bs[2], bb = 4 * nv, n_bricks;
	uint8_t *raw = malloc(bb), *out = malloc(bb);
	cbrick *cb;
	struct libdeflate_compressor *comp = libdeflate_alloc_compressor(level);
	struct libdeflate_decompressor *dec = libdeflate_alloc_decompressor();
	double tc = 0, td, t0, traw_in = 0;
	uint64_t stored = 0, n_empty = 0, n_full = 0, dec_bytes = 0;
	double runs_us, amp, warm_ns;
	uint64_t rng = 42, run_dec = 0;
	const int n_runs = 2000;
	uint8_t col[4][1024];

	for (int a = 0; a < 3; a++)
		nb[a] = (v->s[a] + bs[a] - 1) / bs[a];
	n_bricks = (size_t)nb[0] * nb[1] * nb[2];
	cb = calloc(n_bricks, sizeof *cb);
	for (uint32_t by = 0; by < nb[1]; by++)
		for (uint32_t bx = 0; bx < nb[0]; bx++)
			for (uint32_t bz = 0; bz < nb[2]; bz++) {
				size_t id = ((size_t)by * nb[0] + bx) * nb[2] + bz, cs;
				int any = 0;
				pack(v, bs, bx, by, bz, raw);
				for (size_t i = 0; i < bb && !any; i++)
					any = raw[i] != 0;
				if (!any) {
					n_empty++;
					continue;
				}
				t0 = cpu_s();
				cs = libdeflate_deflate_compress(comp, raw, bb, out, bb - 1);
				tc += cpu_s() - t0;
				traw_in += (double)bb;
				cb[id].raw = cs == 0;
				cb[id].size = cs ? (uint32_t)cs : (uint32_t)bb;
				cb[id].data = malloc(cb[id].size);
				memcpy(cb[id].data, cs ? out : raw, cb[id].size);
				stored += cb[id].size;
				n_full++;
			}
	/* decompression of every stored brick, one core */
	t0 = cpu_s();
	for (size_t id = 0; id < n_bricks; id++) {
		if (!cb[id].data)
			continue;
		if (cb[id].raw)
			memcpy(raw, cb[id].data, bb);
		else if (libdeflate_deflate_decompress(dec, cb[id].data, cb[id].size, raw, bb,
		                                       NULL) != LIBDEFLATE_SUCCESS)
			abort();
		dec_bytes += bb;
	}
	td = cpu_s() - t0;
	/* cold z-runs: a random column, every brick along z decompressed (empty
	   bricks: zeros), its run copied out plane by plane */
	t0 = cpu_s();
	for (int r = 0; r < n_runs; r++) {
		uint32_t x, y, lx, ly;
		rng = rng * 6364136223846793005ull + 1442695040888963407ull;
		x = (uint32_t)((rng >> 33) % v->s[0]);
		y = (uint32_t)((rng >> 13) % v->s[1]);
		lx = x % bs[0];
		ly = y % bs[1];
		for (uint32_t bz = 0; bz < nb[2]; bz++) {
			size_t id = ((size_t)(y / bs[1]) * nb[0] + x / bs[0]) * nb[2] + bz;
			size_t base = ((size_t)ly * bs[0] + lx) * bs[2];
			uint32_t z0 = bz * bs[2], n = v->s[2] - z0 < bs[2] ? v->s[2] - z0 : bs[2];
			if (!cb[id].data) {
				for (int p = 0; p < 4; p++)
					memset(col[p] + z0, 0, n);
				continue;
			}
			if (cb[id].raw)
				memcpy(raw, cb[id].data, bb);
			else
				libdeflate_deflate_decompress(dec, cb[id].data, cb[id].size, raw, bb,
				                              NULL);
			run_dec += bb;
			for (int p = 0; p < 4; p++)
				memcpy(col[p] + z0, raw + p * nv + base, n);
		}
	}
	runs_us = 1e6 * (cpu_s() - t0) / n_runs;
	amp = (double)run_dec / ((double)n_runs * v->s[2] * 4);
	/* warm z-runs: every brick already decompressed (a cache hit per brick:
	   one table lookup, four plane copies) */
	{
		uint8_t **dbr = calloc(n_bricks, sizeof *dbr);
		for (size_t id = 0; id < n_bricks; id++) {
			if (!cb[id].data)
				continue;
			dbr[id] = malloc(bb);
			if (cb[id].raw)
				memcpy(dbr[id], cb[id].data, bb);
			else
				libdeflate_deflate_decompress(dec, cb[id].data, cb[id].size, dbr[id],
				                              bb, NULL);
		}
		t0 = cpu_s();
		for (int r = 0; r < 20 * n_runs; r++) {
			uint32_t x, y, lx, ly;
			rng = rng * 6364136223846793005ull + 1442695040888963407ull;
			x = (uint32_t)((rng >> 33) % v->s[0]);
			y = (uint32_t)((rng >> 13) % v->s[1]);
			lx = x % bs[0];
			ly = y % bs[1];
			for (uint32_t bz = 0; bz < nb[2]; bz++) {
				size_t id = ((size_t)(y / bs[1]) * nb[0] + x / bs[0]) * nb[2] + bz;
				size_t base = ((size_t)ly * bs[0] + lx) * bs[2];
				uint32_t z0 = bz * bs[2], n = v->s[2] - z0 < bs[2] ? v->s[2] - z0 : bs[2];
				for (int p = 0; p < 4; p++) {
					if (dbr[id])
						memcpy(col[p] + z0, dbr[id] + p * nv + base, n);
					else
						memset(col[p] + z0, 0, n);
				}
			}
			__asm__ volatile("" : : "r"(col) : "memory");
		}
		warm_ns = 1e9 * (cpu_s() - t0) / (20.0 * n_runs);
		for (size_t id = 0; id < n_bricks; id++)
			free(dbr[id]);
		free(dbr);
	}
	{
		double raw_total = (double)v->s[0] * v->s[1] * v->s[2] * 4;
		double ratio = raw_total / ((double)stored + 24.0 * (double)n_bricks);
		double cmbs = traw_in / (tc > 0 ? tc : 1e-9) / 1e6;
		double dgib = (double)dec_bytes / (td > 0 ? td : 1e-9) / (1024.0 * 1024 * 1024);
		if (!json_only)
			printf("  %3ux%3ux%3u %5zu KiB  L%d  %6.1fx  %7.0f  %6.2f  %5.1f%%  %8.1f  %6.1f  %7.0f\n",
			       bs[0], bs[1], bs[2], bb / 1024, level, ratio, cmbs, dgib,
			       100.0 * (double)n_empty / (double)n_bricks, runs_us, amp, warm_ns);
		printf("{\"bench\":\"db_brick_shape\",\"brick\":[%u,%u,%u],\"brick_bytes\":%zu,"
		       "\"level\":%d,\"ratio\":%.3f,\"compress_mb_s\":%.1f,"
		       "\"decompress_gib_s\":%.3f,\"bricks\":%zu,\"empty_fraction\":%.4f,"
		       "\"zrun_cold_us\":%.2f,\"zrun_amplification\":%.2f,\"zrun_warm_ns\":%.1f,"
		       "\"stored_bytes\":%llu}\n",
		       bs[0], bs[1], bs[2], bb, level, ratio, cmbs, dgib, n_bricks,
		       (double)n_empty / (double)n_bricks, runs_us, amp, warm_ns,
		       (unsigned long long)stored);
		fflush(stdout);
	}
	for (size_t id = 0; id < n_bricks; id++)
		free(cb[id].data);
	free(cb);
	free(raw);
	free(out);
	libdeflate_free_compressor(comp);
	libdeflate_free_decompressor(dec);
}

/* ---- generation ---------------------------------------------------------------- */

static const char *fibre; /* --fibre F, or NULL: smooth yarns */

static void gen_db(const char *preset, const char *path)
{
	loom_exgen_params p;
	loom_diag d = {0};
	loom_db_info info;
	loom_db *db;
	double t0, t, c0, cpu;
	long hwm, rss;


	loom_exgen_preset(preset, &p);
	p.fibre[0] = p.fibre[1] = fibre;
	t0 = now_s();
	c0 = proc_cpu_s();
	if (loom_exgen_write_db(path, &p, NULL, &d) != LOOM_OK) {
		fprintf(stderr, "bench_db: %s\n", d.message);
		return;
	}
	t = now_s() - t0;
	cpu = proc_cpu_s() - c0;
	mem_kb(&hwm, &rss);
	if (loom_db_open(path, &db, &d) != LOOM_OK) {
		fprintf(stderr, "bench_db: %s\n", d.message);
		return;
	}
	loom_db_get_info(db, &info);
	printf("  %-6s %u exemplars  %7.2f s wall  %7.2f s cpu  %8.1f MB raw  %7.2f MB file  "
	       "%5.1fx  %5.1f Mvoxel/s\n", preset, info.n_exemplars, t, cpu,
	       (double)info.raw_bytes / 1e6,
	       (double)info.file_bytes / 1e6, (double)info.raw_bytes / (double)info.file_bytes,
	       (double)info.raw_bytes / 4 / t / 1e6);
	printf("{\"bench\":\"db_generate\",\"preset\":\"%s\",\"threads\":%u,\"exemplars\":%u,"
	       "\"seconds\":%.3f,\"cpu_seconds\":%.3f,\"raw_bytes\":%llu,\"file_bytes\":%llu,\"ratio\":%.3f,"
	       "\"voxels_per_s\":%.0f,\"process_vmhwm_kb\":%ld}\n",
	       preset, p.threads, info.n_exemplars, t, cpu, (unsigned long long)info.raw_bytes,
	       (unsigned long long)info.file_bytes,
	       (double)info.raw_bytes / (double)info.file_bytes,
	       (double)info.raw_bytes / 4 / t, hwm);
	fflush(stdout);
	loom_db_close(db);
}

int main(int argc, char **argv)
{
	static const uint32_t shapes[][3] = {
		{16, 16, 64}, {32, 32, 32}, {16, 16, 32}, {16, 16, 16}, {16, 16, 128},
		{32, 32, 16}, {32, 32, 64}, {64, 64, 32}, {64, 64, 64}, {16, 16, 300},
	};
	static const int levels[] = {1, 6, 9};
	int quick = 0;
	const char *tmp = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
	char small_path[4096], paper_path[4096];
	loom_exgen_params p;
	loom__exgen *g = NULL;
	loom_diag d = {0};
	volume v;
	double t0;
	size_t n;

	bench_help(argc, argv, USAGE);
	if (argc > 2 && strcmp(argv[1], "--open") == 0)
		return child_open(argv[2]);
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--quick") == 0)
			quick = 1;
		else if (strcmp(argv[i], "--fibre") == 0 && i + 1 < argc)
			fibre = argv[++i];
		else
			bench_reject("bench_db", argv[i], USAGE);
	}
	printf("yarns: %s\n", fibre ? fibre : "smooth");
	snprintf(small_path, sizeof small_path, "%s/bench_db_small.%d.ldb", tmp, (int)getpid());
	snprintf(paper_path, sizeof paper_path, "%s/bench_db_paper.%d.ldb", tmp, (int)getpid());

	printf("== exemplar database generation (2 threads)\n");
	gen_db("small", small_path);
	if (!quick)
		gen_db("paper", paper_path);

	printf("\n== reader: open time and resident memory (fresh process)\n");
	run_child("/proc/self/exe", small_path);
	if (!quick)
		run_child("/proc/self/exe", paper_path);
	unlink(small_path);
	unlink(paper_path);

	/* one paper-scale exemplar in memory */
	loom_exgen_preset("paper", &p);
	p.fibre[0] = p.fibre[1] = fibre;
	p.n_weaves = 1;
	p.weaves[0] = "twill:2/3";
	if (loom__exgen_new(&p, 0, 0, &g, &d) != LOOM_OK) {
		fprintf(stderr, "bench_db: %s\n", d.message);
		return 1;
	}
	v.s[0] = 5 * 115;
	v.s[1] = 5 * 70;
	v.s[2] = 300;
	n = (size_t)v.s[0] * v.s[1] * v.s[2];
	v.d = malloc(n);
	v.l = malloc(n);
	v.o = malloc(2 * n);
	t0 = cpu_s();
	loom__exgen_box(g, 0, 0, 0, v.s[0], v.s[1], v.s[2], v.d, v.o, v.l);
	printf("\n== brick shapes: one paper exemplar (575x350x300 twill 2/3, generated "
	       "in %.2f s cpu on one core)\n", cpu_s() - t0);
	printf("{\"bench\":\"db_generate_one\",\"voxels\":%zu,\"cpu_seconds\":%.3f}\n",
	       n, cpu_s() - t0);
	printf("  %-11s %9s  %-3s %7s  %7s  %6s  %6s  %8s  %6s  %7s\n", "shape", "raw", "lvl",
	       "ratio", "comp", "dec", "empty", "zrun", "amp", "zrun");
	printf("  %-11s %9s  %-3s %7s  %7s  %6s  %6s  %8s  %6s  %7s\n", "", "", "", "",
	       "MB/s", "GiB/s", "", "cold us", "", "warm ns");
	for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; s++) {
		if (quick && s > 2)
			break;
		for (size_t l = 0; l < sizeof levels / sizeof levels[0]; l++)
			study(&v, shapes[s], levels[l], 0);
	}
	printf("  ratio: raw voxel bytes / (stored bricks + 24-byte index entries);\n"
	       "  dec: GiB/s of decompressed brick bytes (4 B per voxel), non-empty bricks;\n"
	       "  zrun: one full 300-voxel column read cold (all its bricks decompressed);\n"
	       "  amp: voxels decompressed per voxel of the run;\n"
	       "  zrun warm: the same run from already decompressed bricks.\n"
	       "  Times are CPU time of one thread.\n");
	free(v.d);
	free(v.l);
	free(v.o);
	loom__exgen_free(g);
	return 0;
}
