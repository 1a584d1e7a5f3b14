/*
 * tools/loom/cmd_exemplar.c - `loom exemplar generate|build|info|verify|export`:
 * build, inspect, check and export exemplar databases (docs/exemplars.md).
 *
 * One file per job: this one dispatches and generates procedural
 * databases; exemplar_scan.c writes scan-like test volumes (generate
 * --scan), exemplar_build.c turns a scan into an exemplar, exemplar_info.c
 * inspects, verifies and exports databases (exemplar.h).
 */
#include "cli.h"
#include "commands.h"
#include "exemplar.h"
#include "progress.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char help_main[] =
	"usage: loom exemplar COMMAND [ARGS...]\n"
	"\n"
	"Exemplar databases: volumetric exemplars of simple weaves, stored as\n"
	"compressed voxel bricks (docs/exemplars.md, docs/formats.md).\n"
	"\n"
	"commands:\n"
	"  generate   make procedural CT-like exemplars into a new database\n"
	"             (--scan: a scan-like volume of a woven sheet, for build)\n"
	"  build      turn a scan into an exemplar appended to a database\n"
	"  info       list a database's exemplars\n"
	"  verify     check every brick and checksum of a database\n"
	"  export     write one exemplar volume as NRRD\n"
	"\n"
	"Commands that read a database take it as DB or --db DB; without one they\n"
	"use $LOOM_DB, then default.ldb in the data directory ($LOOM_DATA, the\n"
	"build tree, the installed share/loom).\n";

static const char help_generate[] =
	"usage: loom exemplar generate [--preset small|paper|tiny] [--weaves LIST]\n"
	"                              [--seed N] [OPTIONS] -o DB\n"
	"\n"
	"Generate one procedural exemplar per weave and write the database DB\n"
	"(atomically).  The output is the same for any thread count.  With\n"
	"--scan, write a scan-like volume instead (loom exemplar generate --scan\n"
	"--help).\n"
	"\n"
	"options:\n"
	"  -o, --output DB     database to write (.ldb)\n"
	"  --preset NAME       small (default: block 24x16x48, 24 um voxels),\n"
	"                      paper (115x70x300, 5 um: the paper's scale) or\n"
	"                      tiny (8x6x12, 72 um: test corpora)\n"
	"  --weaves LIST       comma-separated weaves (loom pattern names, e.g.\n"
	"                      twill:2/3,satin:1/4,plain); default: the 2/3, 3/2,\n"
	"                      1/4, 4/1 twills and the same four satins\n"
	"  --seed N            random seed (default 1)\n"
	"  --crossings RxC     crossings per exemplar, multiples of each weave's\n"
	"                      repeat (default: the smallest multiple >= 4, so 5x5\n"
	"                      for the 5-end weaves)\n"
	"  --block B1xB2xB3    block size in voxels (overrides the preset)\n"
	"  --voxel-size UM     voxel edge in micrometres (overrides the preset)\n"
	"  --brick XxYxZ       brick shape (default 16x16x64)\n"
	"  --level L           libdeflate level 1..12 (default 6)\n"
	"  --threads N         worker threads (default 2)\n"
	"  --json              print the result as JSON\n"
	"  --quiet             no progress or summary\n";

/* ---- generate ----------------------------------------------------------- */

typedef struct progress_state {
	int on;
	double t0;
	int last_pct;
} progress_state;

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void progress_cb(void *user, uint64_t done, uint64_t total)
{
	progress_state *ps = user;
	int pct = total ? (int)(100 * done / total) : 100;

	if (!ps->on || pct == ps->last_pct)
		return;
	ps->last_pct = pct;
	fprintf(stderr, "\rloom exemplar generate: %3d%% (%llu/%llu bricks, %.1f s)",
	        pct, (unsigned long long)done, (unsigned long long)total,
	        now_s() - ps->t0);
	if (done == total)
		fputc('\n', stderr);
	fflush(stderr);
}

int exemplar_parse_size3(const char *s, uint32_t v[3])
{
	char buf[96], *a, *b;

	if (!s || strlen(s) >= sizeof buf)
		return -1;
	strcpy(buf, s);
	a = strpbrk(buf, "xX,");
	if (!a)
		return -1;
	*a++ = 0;
	b = strpbrk(a, "xX,");
	if (!b)
		return -1;
	*b++ = 0;
	if (cli_parse_u32(buf, &v[0]) || cli_parse_u32(a, &v[1]) || cli_parse_u32(b, &v[2]))
		return -1;
	return 0;
}

static int sub_generate(int argc, char **argv)
{
	const char *prog = "loom exemplar generate";
	const char *out = NULL, *preset = "small", *weaves = NULL;
	const char *seed_s = NULL, *cross_s = NULL, *block_s = NULL, *vs_s = NULL;
	const char *brick_s = NULL, *level_s = NULL, *threads_s = NULL;
	char *wbuf = NULL;
	int quiet = 0, json = 0, rc;
	loom_exgen_params p;
	loom_diag diag;
	progress_state ps;
	uint64_t hash = 0;
	cli_args a;
	double t0;

	cli_init(&a, argc, argv, prog, help_generate);
	while (cli_more(&a)) {
		if (cli_value(&a, "-o", &out) || cli_value(&a, "--output", &out) ||
		    cli_value(&a, "--preset", &preset) || cli_value(&a, "--weaves", &weaves) ||
		    cli_value(&a, "--seed", &seed_s) || cli_value(&a, "--crossings", &cross_s) ||
		    cli_value(&a, "--block", &block_s) ||
		    cli_value(&a, "--voxel-size", &vs_s) || cli_value(&a, "--brick", &brick_s) ||
		    cli_value(&a, "--level", &level_s) || cli_value(&a, "--threads", &threads_s))
			continue;
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if (cli_flag(&a, "--json")) {
			json = 1;
			continue;
		}
		cli_unknown(&a);
	}
	if (!out)
		cli_usage(&a, "missing -o DB");
	if (loom_exgen_preset(preset, &p) != LOOM_OK)
		cli_usage(&a, "unknown preset '%s' (expected small, paper or tiny)", preset);
	if (weaves) {
		char *s, *tok, *save = NULL;
		wbuf = strdup(weaves);
		if (!wbuf)
			cli_fail(prog, "out of memory");
		p.n_weaves = 0;
		for (s = wbuf; (tok = strtok_r(s, ",", &save)) != NULL; s = NULL) {
			if (p.n_weaves == LOOM_EXGEN_MAX_WEAVES)
				cli_usage(&a, "more than %d weaves", LOOM_EXGEN_MAX_WEAVES);
			p.weaves[p.n_weaves++] = tok;
		}
		if (p.n_weaves == 0)
			cli_usage(&a, "--weaves needs at least one weave");
	}
	if (seed_s && cli_parse_u64(seed_s, &p.seed))
		cli_usage(&a, "bad --seed '%s'", seed_s);
	if (cross_s && (cli_parse_size2(cross_s, &p.rows, &p.cols) || !p.rows || !p.cols))
		cli_usage(&a, "bad --crossings '%s' (expected RxC)", cross_s);
	if (block_s && exemplar_parse_size3(block_s, p.block))
		cli_usage(&a, "bad --block '%s' (expected B1xB2xB3)", block_s);
	if (brick_s && exemplar_parse_size3(brick_s, p.brick))
		cli_usage(&a, "bad --brick '%s' (expected XxYxZ)", brick_s);
	if (vs_s) {
		double d;
		if (cli_parse_double(vs_s, &d) || !(d > 0) || d > 10000)
			cli_usage(&a, "bad --voxel-size '%s'", vs_s);
		p.voxel_size_um = (float)d;
	}
	if (level_s) {
		uint32_t l;
		if (cli_parse_u32(level_s, &l) || l < 1 || l > 12)
			cli_usage(&a, "bad --level '%s' (expected 1..12)", level_s);
		p.level = (int)l;
	}
	if (threads_s && (cli_parse_u32(threads_s, &p.threads) || !p.threads ||
	                  p.threads > 64))
		cli_usage(&a, "bad --threads '%s' (expected 1..64)", threads_s);
	memset(&ps, 0, sizeof ps);
	ps.on = !quiet && isatty(2);
	ps.last_pct = -1;
	ps.t0 = t0 = now_s();
	p.progress = progress_cb;
	p.user = &ps;
	cli_diag_init(&diag, &quiet);
	rc = loom_exgen_write_db(out, &p, &hash, &diag);
	free(wbuf);
	if (rc)
		cli_fail(prog, "%s", diag.message);
	if (json || !quiet) {
		loom_db *db;
		loom_db_info info;
		if (loom_db_open(out, &db, &diag) != LOOM_OK)
			cli_fail(prog, "%s", diag.message);
		loom_db_get_info(db, &info);
		if (json) {
			json_w w;
			jw_begin(&w, stdout);
			jw_str(&w, "path", out);
			jw_uint(&w, "exemplars", info.n_exemplars);
			jw_uint(&w, "bricks", info.n_bricks);
			jw_uint(&w, "raw_bytes", info.raw_bytes);
			jw_uint(&w, "file_bytes", info.file_bytes);
			jw_num(&w, "ratio", (double)info.raw_bytes / (double)info.file_bytes);
			{
				char hs[32];
				snprintf(hs, sizeof hs, "%016llx", (unsigned long long)hash);
				jw_str(&w, "content_hash", hs);
			}
			jw_num(&w, "seconds", now_s() - t0);
			jw_end(&w);
		} else {
			printf("%s: %u exemplars, %llu bricks, %.1f MB raw in %.2f MB (%.1fx), "
			       "hash %016llx, %.2f s\n", out, info.n_exemplars,
			       (unsigned long long)info.n_bricks, (double)info.raw_bytes / 1e6,
			       (double)info.file_bytes / 1e6,
			       (double)info.raw_bytes / (double)info.file_bytes,
			       (unsigned long long)hash, now_s() - t0);
		}
		loom_db_close(db);
	}
	return 0;
}

int cmd_exemplar(int argc, char **argv)
{
	const char *sub;

	if (argc < 2) {
		fputs(help_main, stderr);
		return EXIT_USAGE;
	}
	sub = argv[1];
	if (strcmp(sub, "--help") == 0 || strcmp(sub, "-h") == 0 ||
	    strcmp(sub, "help") == 0) {
		fputs(help_main, stdout);
		return 0;
	}
	if (strcmp(sub, "generate") == 0) {
		for (int i = 2; i < argc; i++)
			if (strcmp(argv[i], "--scan") == 0)
				return exemplar_generate_scan(argc - 1, argv + 1);
		return sub_generate(argc - 1, argv + 1);
	}
	if (strcmp(sub, "build") == 0)
		return exemplar_build(argc - 1, argv + 1);
	if (strcmp(sub, "info") == 0)
		return exemplar_info(argc - 1, argv + 1);
	if (strcmp(sub, "verify") == 0)
		return exemplar_verify(argc - 1, argv + 1);
	if (strcmp(sub, "export") == 0)
		return exemplar_export(argc - 1, argv + 1);
	fprintf(stderr, "loom exemplar: unknown command '%s'\nTry 'loom exemplar "
	        "--help'.\n", sub);
	return EXIT_USAGE;
}
