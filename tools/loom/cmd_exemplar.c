/*
 * tools/loom/cmd_exemplar.c - `loom exemplar generate|info|verify|export`:
 * build, inspect, check and export exemplar databases (docs/exemplars.md).
 */
#include "cli.h"
#include "commands.h"

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
	"(atomically).  The output is the same for any thread count.\n"
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

static const char help_info[] =
	"usage: loom exemplar info [DB] [--db DB] [--json]\n"
	"\n"
	"List the exemplars of a database: weave, crossings, block size, voxel\n"
	"count, raw and compressed bytes, compression ratio.\n"
	"\n"
	"options:\n"
	"  --db DB    database (or give it as the first argument)\n"
	"  --json     JSON object with an \"exemplars\" array (name, weave: one\n"
	"             string of 0/1 per pick, crossings, block, raw_bytes,\n"
	"             compressed_bytes, ...)\n";

static const char help_verify[] =
	"usage: loom exemplar verify [DB] [--db DB] [--quiet]\n"
	"\n"
	"Read every brick of a database, check its CRC32, decompress it to the\n"
	"exact size and check its labels.  Exit status 0 when all are good, 1\n"
	"naming the first bad brick otherwise.\n";

static const char help_export[] =
	"usage: loom exemplar export [DB] [--db DB] --exemplar K -o FILE\n"
	"                            [--channel C] [--detached]\n"
	"\n"
	"Write one exemplar volume as NRRD (raw data, axes x y z, spacing = voxel\n"
	"size in mm) for viewing in standard tools (unu, ParaView, 3D Slicer).\n"
	"\n"
	"options:\n"
	"  --exemplar K    exemplar name or index (see `loom exemplar info`)\n"
	"  -o, --output F  output file: F.nrrd (attached) or F.nhdr (detached)\n"
	"  --channel C     density (uint8, default), label (uint8), kind (uint8:\n"
	"                  0 empty, 1 warp, 2 weft), orientation (3 x float32)\n"
	"                  or orient-code (uint16)\n"
	"  --detached      header in FILE, data in FILE with the extension .raw\n";

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

static int parse_size3(const char *s, uint32_t v[3])
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
	if (block_s && parse_size3(block_s, p.block))
		cli_usage(&a, "bad --block '%s' (expected B1xB2xB3)", block_s);
	if (brick_s && parse_size3(brick_s, p.brick))
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

/* ---- shared: open the database of info/verify/export ---------------------- */

static loom_db *open_db(const char *prog, const char *pos, const char *opt)
{
	const char *path = pos ? pos : cli_db_require(opt, prog);
	loom_diag diag;
	loom_db *db;

	cli_diag_init(&diag, NULL);
	if (loom_db_open(path, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	return db;
}

/* ---- info ---------------------------------------------------------------- */

static void weave_row(const loom_db_exemplar_info *e, uint32_t r, char *buf)
{
	for (uint32_t c = 0; c < e->cols; c++)
		buf[c] = e->weave[(size_t)r * e->cols + c] ? '1' : '0';
	buf[e->cols] = 0;
}

static int sub_info(int argc, char **argv)
{
	const char *prog = "loom exemplar info", *dbopt = NULL, *pos = NULL, *s;
	int json = 0;
	loom_db *db;
	loom_db_info info;
	char hs[32], row[1100];
	cli_args a;

	cli_init(&a, argc, argv, prog, help_info);
	while (cli_more(&a)) {
		if (cli_value(&a, "--db", &dbopt))
			continue;
		if (cli_flag(&a, "--json")) {
			json = 1;
			continue;
		}
		if (!pos && (s = cli_positional(&a)) != NULL) {
			pos = s;
			continue;
		}
		cli_unknown(&a);
	}
	db = open_db(prog, pos, dbopt);
	loom_db_get_info(db, &info);
	snprintf(hs, sizeof hs, "%016llx", (unsigned long long)info.content_hash);
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "path", pos ? pos : cli_db_path(dbopt));
		jw_uint(&w, "version", info.version);
		jw_str(&w, "content_hash", hs);
		jw_arr(&w, "block");
		for (int k = 0; k < 3; k++)
			jw_uint(&w, NULL, info.block[k]);
		jw_close(&w);
		jw_arr(&w, "brick");
		for (int k = 0; k < 3; k++)
			jw_uint(&w, NULL, info.brick[k]);
		jw_close(&w);
		jw_num(&w, "voxel_size_um", info.voxel_size_um);
		jw_uint(&w, "seed", info.seed);
		jw_uint(&w, "file_bytes", info.file_bytes);
		jw_uint(&w, "raw_bytes", info.raw_bytes);
		jw_uint(&w, "compressed_bytes", info.stored_bytes);
		jw_num(&w, "ratio", info.stored_bytes ?
		               (double)info.raw_bytes / (double)info.stored_bytes : 0.0);
		jw_uint(&w, "bricks", info.n_bricks);
		jw_uint(&w, "empty_bricks", info.n_empty_bricks);
		jw_uint(&w, "raw_bricks", info.n_raw_bricks);
		jw_arr(&w, "exemplars");
		for (uint32_t k = 0; k < info.n_exemplars; k++) {
			loom_db_exemplar_info e;
			loom_db_exemplar(db, k, &e);
			jw_obj(&w, NULL);
			jw_uint(&w, "index", k);
			jw_str(&w, "name", e.name);
			jw_str(&w, "weave_name", e.weave_name);
			jw_arr(&w, "weave");
			for (uint32_t r = 0; r < e.rows; r++) {
				weave_row(&e, r, row);
				jw_str(&w, NULL, row);
			}
			jw_close(&w);
			jw_arr(&w, "crossings");
			jw_uint(&w, NULL, e.rows);
			jw_uint(&w, NULL, e.cols);
			jw_close(&w);
			jw_arr(&w, "block");
			for (int i = 0; i < 3; i++)
				jw_uint(&w, NULL, e.block[i]);
			jw_close(&w);
			jw_arr(&w, "size");
			for (int i = 0; i < 3; i++)
				jw_uint(&w, NULL, e.size[i]);
			jw_close(&w);
			jw_num(&w, "voxel_size_um", e.voxel_size_um);
			jw_uint(&w, "voxels", (unsigned long long)e.size[0] * e.size[1] * e.size[2]);
			jw_uint(&w, "raw_bytes", e.raw_bytes);
			jw_uint(&w, "compressed_bytes", e.stored_bytes);
			jw_num(&w, "ratio", e.stored_bytes ?
			               (double)e.raw_bytes / (double)e.stored_bytes : 0.0);
			jw_uint(&w, "yarn_labels", e.n_yarns);
			jw_arr(&w, "symmetries");
			for (uint32_t i = 0; i < e.n_symmetries; i++) {
				jw_arr(&w, NULL);
				jw_uint(&w, NULL, e.symmetries[2 * i]);
				jw_uint(&w, NULL, e.symmetries[2 * i + 1]);
				jw_close(&w);
			}
			jw_close(&w);
			jw_close(&w);
		}
		jw_close(&w);
		jw_end(&w);
	} else {
		printf("database %s\n", pos ? pos : cli_db_path(dbopt));
		printf("  format version %u, content hash %s, %llu bytes\n", info.version,
		       hs, (unsigned long long)info.file_bytes);
		printf("  block %ux%ux%u voxels of %g um, brick %ux%ux%u, %llu bricks "
		       "(%llu empty, %llu stored raw)\n", info.block[0], info.block[1],
		       info.block[2], (double)info.voxel_size_um, info.brick[0],
		       info.brick[1], info.brick[2], (unsigned long long)info.n_bricks,
		       (unsigned long long)info.n_empty_bricks,
		       (unsigned long long)info.n_raw_bricks);
		printf("\n  %-3s %-16s %-14s %-9s %12s %12s %12s %7s  %s\n", "#", "name",
		       "weave", "crossings", "voxels", "raw bytes", "compressed", "ratio",
		       "weave rows (pick 0 first)");
		for (uint32_t k = 0; k < info.n_exemplars; k++) {
			loom_db_exemplar_info e;
			char cr[24];
			loom_db_exemplar(db, k, &e);
			snprintf(cr, sizeof cr, "%ux%u", e.rows, e.cols);
			printf("  %-3u %-16s %-14s %-9s %12llu %12llu %12llu %6.1fx  ", k, e.name,
			       e.weave_name[0] ? e.weave_name : "-", cr,
			       (unsigned long long)e.size[0] * e.size[1] * e.size[2],
			       (unsigned long long)e.raw_bytes,
			       (unsigned long long)e.stored_bytes,
			       e.stored_bytes ? (double)e.raw_bytes / (double)e.stored_bytes : 0.0);
			for (uint32_t r = 0; r < e.rows; r++) {
				weave_row(&e, r, row);
				printf("%s%s", r ? " " : "", row);
			}
			printf("\n");
		}
		printf("\n  total %llu raw bytes in %llu (%.1fx)\n",
		       (unsigned long long)info.raw_bytes,
		       (unsigned long long)info.stored_bytes,
		       info.stored_bytes ? (double)info.raw_bytes / (double)info.stored_bytes
		                         : 0.0);
	}
	loom_db_close(db);
	return 0;
}

/* ---- verify -------------------------------------------------------------- */

static void verify_progress(void *user, uint64_t done, uint64_t total)
{
	(void)user;
	fprintf(stderr, "\rloom exemplar verify: %llu/%llu bricks", (unsigned long long)done,
	        (unsigned long long)total);
	if (done == total)
		fputc('\n', stderr);
}

static int sub_verify(int argc, char **argv)
{
	const char *prog = "loom exemplar verify", *dbopt = NULL, *pos = NULL, *s;
	int quiet = 0, rc;
	loom_db *db;
	loom_db_info info;
	loom_diag diag;
	cli_args a;

	cli_init(&a, argc, argv, prog, help_verify);
	while (cli_more(&a)) {
		if (cli_value(&a, "--db", &dbopt))
			continue;
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if (!pos && (s = cli_positional(&a)) != NULL) {
			pos = s;
			continue;
		}
		cli_unknown(&a);
	}
	db = open_db(prog, pos, dbopt);
	cli_diag_init(&diag, &quiet);
	rc = loom_db_verify(db, !quiet && isatty(2) ? verify_progress : NULL, NULL, &diag);
	loom_db_get_info(db, &info);
	loom_db_close(db);
	if (rc)
		cli_fail(prog, "%s", diag.message);
	if (!quiet)
		printf("%s: ok (%llu bricks, %llu empty, content hash %016llx)\n",
		       pos ? pos : cli_db_path(dbopt), (unsigned long long)info.n_bricks,
		       (unsigned long long)info.n_empty_bricks,
		       (unsigned long long)info.content_hash);
	return 0;
}

/* ---- export -------------------------------------------------------------- */

static int sub_export(int argc, char **argv)
{
	const char *prog = "loom exemplar export", *dbopt = NULL, *pos = NULL, *s;
	const char *ex = NULL, *out = NULL, *ch = "density";
	int detached = 0, channel;
	uint32_t k;
	loom_db *db;
	loom_diag diag;
	cli_args a;

	cli_init(&a, argc, argv, prog, help_export);
	while (cli_more(&a)) {
		if (cli_value(&a, "--db", &dbopt) || cli_value(&a, "--exemplar", &ex) ||
		    cli_value(&a, "-o", &out) || cli_value(&a, "--output", &out) ||
		    cli_value(&a, "--channel", &ch))
			continue;
		if (cli_flag(&a, "--detached")) {
			detached = 1;
			continue;
		}
		if (!pos && (s = cli_positional(&a)) != NULL) {
			pos = s;
			continue;
		}
		cli_unknown(&a);
	}
	if (!ex)
		cli_usage(&a, "missing --exemplar K");
	if (!out)
		cli_usage(&a, "missing -o FILE");
	if (loom_db_channel_parse(ch, &channel) != LOOM_OK)
		cli_usage(&a, "unknown channel '%s' (expected density, label, kind, "
		          "orientation or orient-code)", ch);
	db = open_db(prog, pos, dbopt);
	if (loom_db_find_exemplar(db, ex, &k) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "no exemplar '%s' (see loom exemplar info)", ex);
	}
	cli_diag_init(&diag, NULL);
	if (loom_db_export_nrrd(db, k, channel, out, detached, &diag) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	loom_db_close(db);
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
	if (strcmp(sub, "generate") == 0)
		return sub_generate(argc - 1, argv + 1);
	if (strcmp(sub, "info") == 0)
		return sub_info(argc - 1, argv + 1);
	if (strcmp(sub, "verify") == 0)
		return sub_verify(argc - 1, argv + 1);
	if (strcmp(sub, "export") == 0)
		return sub_export(argc - 1, argv + 1);
	fprintf(stderr, "loom exemplar: unknown command '%s'\nTry 'loom exemplar "
	        "--help'.\n", sub);
	return EXIT_USAGE;
}
