/*
 * bench/bench_fabric.c - fabric synthesis and file figures (docs/fabric.md):
 * time and memory of synthesis (assignment + edge-fix tables, then the
 * whole loom_fabric_synthesize with its metrics), save and open, and the
 * fabric file size: bytes per crossing and the size-independent part.
 *
 *   build/bench/bench_fabric [--quick]      --quick skips 20000 x 20000
 *
 * Databases: $LOOM_DB or $BUILD/share/loom/default.ldb (the "small"
 * preset), and the paper preset from $LOOM_PAPER_DB if that is set and
 * opens (otherwise its rows are skipped, and the program says so).
 * Designs: Jacquard-like, twill 2/3 and satin 4/1 exchanged over a blocky
 * random mask, warp types per end and weft types per pick.  One thread;
 * wall and thread-CPU time (the machine is shared).  Prints a table and
 * JSON lines ("{...}").
 */
#include "loom.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_fabric [--quick]\n"
	"Fabric synthesis time and memory, save and open, file size per crossing.\n"
	"  --quick    skip the 20000 x 20000 design\n"
	"Environment: LOOM_DB (default $BUILD/share/loom/default.ldb), LOOM_PAPER_DB\n"
	"(the paper preset; its rows are skipped without it), BUILD, TMPDIR.\n";

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

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

static loom_design *jacquard(uint32_t rows, uint32_t cols)
{
	loom_weave_params a, b;
	loom_design *d = NULL;
	loom_weave_parse("twill:2/3", &a, NULL);
	loom_weave_parse("satin:4/1", &b, NULL);
	if (loom_design_make(&a, rows, cols, &d, NULL) != LOOM_OK ||
	    loom_design_set_types(d, 4) != LOOM_OK) {
		loom_design_free(d);
		return NULL;
	}
	for (uint32_t i = 0; i < rows; i++) {
		size_t r0 = (size_t)i * cols;
		for (uint32_t j = 0; j < cols; j++) {
			uint64_t h = loom_synth_mix(((uint64_t)(i / 48) << 32) | (j / 64));
			uint32_t ii = i + (uint32_t)(h % 17), jj = j + (uint32_t)((h >> 8) % 23);
			uint64_t h2 = loom_synth_mix(((uint64_t)(ii / 48) << 32) | (jj / 64));
			if (h2 & 1)
				d->weave[r0 + j] = (uint8_t)loom_weave_cell(&b, i, j);
			d->warp_type[r0 + j] = (uint8_t)(j % 6 == 0 ? 2 : 0);
			d->weft_type[r0 + j] = (uint8_t)(i % 8 == 0 ? 3 : 1);
		}
	}
	return d;
}

/* Stored bytes of the design-sized sections (WEAV WARP WEFT BASE) and of
   the rest, from the file's section headers (docs/formats.md). */
static void split_sizes(const char *path, uint64_t *per_design, uint64_t *fixed,
                        uint64_t sec[8])
{
	FILE *fp = fopen(path, "rb");
	uint64_t pos = 64, total = 0;
	*per_design = *fixed = 0;
	if (!fp)
		return;
	fseek(fp, 0, SEEK_END);
	total = (uint64_t)ftell(fp);
	for (int k = 0; k < 8; k++) {
		uint8_t h[32];
		uint64_t stored = 0;
		if (fseek(fp, (long)pos, SEEK_SET) != 0 || fread(h, 1, 32, fp) != 32)
			break;
		for (int b = 0; b < 8; b++)
			stored |= (uint64_t)h[16 + b] << (8 * b);
		sec[k] = 32 + stored;
		if (k >= 2 && k <= 5)
			*per_design += 32 + stored;
		pos += 32 + stored;
	}
	fclose(fp);
	*fixed = total - *per_design;
}

static void row(const char *dbname, const char *dbpath, loom_db *db,
                uint32_t rows, uint32_t cols, const char *tmp)
{
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_synth_options so = LOOM_SYNTH_OPTIONS_INIT;
	loom_design *d = jacquard(rows, cols);
	loom_fabric *f = NULL, *g = NULL;
	loom_fabric_metrics m;
	loom_diag diag = {0};
	uint64_t bytes = 0, per = 0, fixed = 0, sec[8] = {0};
	uint64_t n = (uint64_t)rows * cols;
	double t_core = 0, c_core = 0, t_syn, c_syn, t_save, t_open, mem0, mem1;
	char path[4200];

	if (!d) {
		printf("%s %ux%u: cannot make the design (out of memory?)\n", dbname, rows, cols);
		return;
	}
	mem0 = peak_mib();
	/* (a) the target: assignment + edge-fix tables, measured inside
	   a synthesis by timing the same calls on the fabric's own set */
	t_syn = now();
	c_syn = cpu();
	if (loom_fabric_synthesize(d, db, dbpath, &o, &f, &diag) != LOOM_OK) {
		printf("%s %ux%u: %s\n", dbname, rows, cols, diag.message);
		loom_design_free(d);
		return;
	}
	c_syn = cpu() - c_syn;
	t_syn = now() - t_syn;
	mem1 = peak_mib();
	{
		/* repeat the two core steps alone (same inputs, same work) */
		loom_synth_set *s = NULL;
		loom_edgefix *ef = NULL;
		loom_synth_exemplar ex[64];
		loom_db_info info;
		uint16_t *base = malloc(n * sizeof *base);
		loom_db_get_info(db, &info);
		for (uint32_t u = 0; u < info.n_exemplars && u < 64; u++) {
			loom_db_exemplar_info e;
			loom_db_exemplar(db, u, &e);
			ex[u].rows = e.rows;
			ex[u].cols = e.cols;
			ex[u].weave = e.weave;
			ex[u].periodic = 0;
		}
		if (base && loom_synth_set_new(ex, info.n_exemplars, &s, NULL) == LOOM_OK) {
			uint32_t K = loom_synth_set_blocks(s), b1 = info.block[0], b2 = info.block[1];
			uint32_t rec = LOOM_EDGE_RECORD(b1, b2), t = 0;
			float *h = malloc(sizeof(float) * rec * K);
			loom_edge_profiles p = {b1, b2, K, h, NULL};
			for (uint32_t u = 0; h && u < info.n_exemplars; u++) {
				loom_db_exemplar_info e;
				loom_db_exemplar(db, u, &e);
				for (uint32_t r = 0; r < e.rows; r++)
					for (uint32_t c = 0; c < e.cols; c++, t++) {
						loom_db_block_info bi;
						float *q = h + (size_t)t * rec;
						loom_db_block(db, u, r, c, &bi);
						memcpy(q, bi.north, 4 * b1);
						memcpy(q + b1, bi.south, 4 * b1);
						memcpy(q + 2 * b1, bi.west, 4 * b2);
						memcpy(q + 2 * b1 + b2, bi.east, 4 * b2);
					}
			}
			t_core = now();
			c_core = cpu();
			loom_synth_assign(s, d, &so, base, NULL);
			loom_edgefix_build(&p, o.rank, &ef, NULL);
			c_core = cpu() - c_core;
			t_core = now() - t_core;
			free(h);
		}
		loom_edgefix_free(ef);
		loom_synth_set_free(s);
		free(base);
	}
	loom_design_free(d);
	snprintf(path, sizeof path, "%s/bench_%s_%ux%u.loomf", tmp, dbname, rows, cols);
	t_save = now();
	if (loom_fabric_save(f, path, &bytes, &diag) != LOOM_OK)
		printf("  save: %s\n", diag.message);
	t_save = now() - t_save;
	split_sizes(path, &per, &fixed, sec);
	loom_fabric_get_metrics(f, &m);
	loom_fabric_free(f);
	t_open = now();
	if (loom_fabric_open(path, db, 0, &g, &diag) != LOOM_OK)
		printf("  open: %s\n", diag.message);
	t_open = now() - t_open;
	loom_fabric_free(g);
	unlink(path);
	printf("%-6s %6ux%-6u %8.3f %8.3f %8.3f %8.3f %7.3f %7.3f %8.0f %8.0f %11llu %6.3f %9llu %6.3f %6.3f\n",
	       dbname, rows, cols, t_core, c_core, t_syn, c_syn, t_save, t_open, mem0, mem1,
	       (unsigned long long)bytes, (double)per / (double)n,
	       (unsigned long long)fixed, m.repeat.correctness, m.repeat.continuity);
	printf("{\"bench\":\"fabric\",\"db\":\"%s\",\"rows\":%u,\"cols\":%u,"
	       "\"assign_tables_s\":%.4f,\"assign_tables_cpu_s\":%.4f,"
	       "\"synth_s\":%.4f,\"synth_cpu_s\":%.4f,\"save_s\":%.4f,\"open_s\":%.4f,"
	       "\"peak_rss_before_mib\":%.0f,\"peak_rss_mib\":%.0f,\"fabric_bytes\":%llu,"
	       "\"design_bytes_per_crossing\":%.4f,\"fixed_bytes\":%llu,"
	       "\"weav\":%llu,\"warp\":%llu,\"weft\":%llu,\"base\":%llu,\"edge\":%llu,"
	       "\"correctness\":%.4f,\"consistency\":%.4f,\"continuity\":%.4f,"
	       "\"seam_before\":%.4f,\"seam_after\":%.4f}\n",
	       dbname, rows, cols, t_core, c_core, t_syn, c_syn, t_save, t_open, mem0, mem1,
	       (unsigned long long)bytes, (double)per / (double)n,
	       (unsigned long long)fixed, (unsigned long long)sec[2],
	       (unsigned long long)sec[3], (unsigned long long)sec[4],
	       (unsigned long long)sec[5], (unsigned long long)sec[6], m.repeat.correctness,
	       m.repeat.consistency, m.repeat.continuity, m.seam.before_mean,
	       m.seam.after_mean);
	fflush(stdout);
}

int main(int argc, char **argv)
{
	static const uint32_t sizes[3][2] = {{900, 1500}, {5000, 5000}, {20000, 20000}};
	int quick = argc > 1 && strcmp(argv[1], "--quick") == 0;
	const char *build = getenv("BUILD") ? getenv("BUILD") : "build";
	const char *tmp = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
	const char *paper = getenv("LOOM_PAPER_DB");
	char def[4200];
	loom_db *db = NULL, *pdb = NULL;
	loom_diag diag = {0};

	bench_help(argc, argv, USAGE);
	for (int i = 1; i < argc; i++)
		if (strcmp(argv[i], "--quick") != 0)
			bench_reject("bench_fabric", argv[i], USAGE);

	if (getenv("LOOM_DB") && *getenv("LOOM_DB"))
		snprintf(def, sizeof def, "%s", getenv("LOOM_DB"));
	else
		snprintf(def, sizeof def, "%s/share/loom/default.ldb", build);
	if (loom_db_open(def, &db, &diag) != LOOM_OK) {
		printf("bench_fabric: no default database: %s (run make first)\n", diag.message);
		return 0;
	}
	if (paper && *paper && loom_db_open(paper, &pdb, &diag) != LOOM_OK) {
		printf("bench_fabric: $LOOM_PAPER_DB: %s\n", diag.message);
		pdb = NULL;
	}
	printf("fabric synthesis (one thread; times in s: wall and thread CPU; memory: peak RSS MiB\n"
	       "before and after synthesis; bytes: file, design-sized sections per crossing, the rest)\n");
	printf("%-6s %13s %8s %8s %8s %8s %7s %7s %8s %8s %11s %6s %9s %6s %6s\n", "db", "design",
	       "a+t", "a+t cpu", "synth", "syn cpu", "save", "open", "rss0", "rss1",
	       "bytes", "B/x", "fixed", "corr", "cont");
	for (int k = 0; k < 3; k++) {
		if (quick && k == 2)
			continue;
		row("small", def, db, sizes[k][0], sizes[k][1], tmp);
	}
	if (!pdb)
		printf("paper preset: skipped ($LOOM_PAPER_DB %s)\n",
		       paper && *paper ? "does not open" : "is not set");
	else
		for (int k = 0; k < 3; k++) {
			if (quick && k == 2)
				continue;
			row("paper", paper, pdb, sizes[k][0], sizes[k][1], tmp);
		}
	loom_db_close(db);
	loom_db_close(pdb);
	return 0;
}
