/*
 * tools/loom/cmd_exemplar.c - `loom exemplar generate|build|info|verify|export|convert`:
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
#include "opts.h"
#include "progress.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char about_main[] =
	"Exemplar databases: volumetric exemplars of simple weaves, stored as\n"
	"compressed voxel bricks (docs/exemplars.md, docs/formats.md).\n";

static const char footer_main[] =
	"\n"
	"Commands that read a database take it as DB or --db DB; without one they\n"
	"use $LOOM_DB, then default.ldb in the data directory ($LOOM_DATA, the\n"
	"build tree, the installed share/loom).\n";

static const char usage_generate[] =
	"loom exemplar generate [--preset small|paper|tiny] [--weaves LIST]\n"
	"                       [--seed N] [OPTIONS] -o DB\n"
	"loom exemplar generate --design DESIGN [--map MAPFILE]\n"
	"                       [--preset P | --like DB] [--window R0,C0:R1,C1]\n"
	"                       [--seed N] [OPTIONS] -o GT.ldb\n";

static const char about_generate[] =
	"Generate one procedural exemplar per weave and write the database DB\n"
	"(atomically).  The output is the same for any thread count.  With\n"
	"--scan, write a scan-like volume instead (loom exemplar generate --scan\n"
	"--help).  With --design, write the woven ground truth of a design: one\n"
	"exemplar whose weave is the whole design (docs/fidelity.md).\n";

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

/* --preset: a name loom_exgen_preset knows. */
static const char *opt_preset(const char *text, void *dest)
{
	loom_exgen_params p;

	*(const char **)dest = text;
	return loom_exgen_preset(text, &p) == LOOM_OK ? NULL : "small, paper or tiny";
}

/* --window R0,C0:R1,C1 (half-open crossings). */
static const char *opt_window(const char *text, void *dest)
{
	uint32_t *w = dest;
	char tail;

	if (sscanf(text, "%u,%u:%u,%u%c", &w[0], &w[1], &w[2], &w[3], &tail) != 4 ||
	    w[2] <= w[0] || w[3] <= w[1])
		return "R0,C0:R1,C1 with R0 < R1 and C0 < C1 (crossings, half-open)";
	return NULL;
}

/* The design (or its window) as the weave of one exemplar. */
static uint8_t *design_weave(const char *prog, const char *path, const char *map,
                             const uint32_t *win, int have_win,
                             const loom_exgen_params *p, uint32_t *rows,
                             uint32_t *cols, loom_diag *diag)
{
	loom_design *d = synth_load_design(prog, path, map, NULL, NULL, diag);
	uint32_t r0 = 0, c0 = 0, r1 = d->rows, c1 = d->cols;
	uint32_t lr = loom_exgen_design_limit(p->block[1]);
	uint32_t lc = loom_exgen_design_limit(p->block[0]);
	uint8_t *w;

	if (have_win) {
		if (win[2] > d->rows || win[3] > d->cols)
			cli_fail(prog, "--window %u,%u:%u,%u: outside %s (%ux%u crossings)",
			         win[0], win[1], win[2], win[3], path, d->rows, d->cols);
		r0 = win[0];
		c0 = win[1];
		r1 = win[2];
		c1 = win[3];
	}
	if (r1 - r0 > lr || c1 - c0 > lc)
		cli_fail(prog, "%s%s: %ux%u crossings, but a ground truth at block %ux%u has "
		         "at most %ux%u (picks x ends); choose a part with --window "
		         "R0,C0:R1,C1", path, have_win ? " (window)" : "", r1 - r0, c1 - c0,
		         p->block[0], p->block[1], lr, lc);
	*rows = r1 - r0;
	*cols = c1 - c0;
	w = malloc((size_t)*rows * *cols);
	if (!w)
		cli_fail(prog, "out of memory");
	for (uint32_t r = r0; r < r1; r++)
		memcpy(w + (size_t)(r - r0) * *cols, d->weave + (size_t)r * d->cols + c0,
		       *cols);
	loom_design_free(d);
	return w;
}

/* Two positive numbers "AxB" (or "A,B"; one number "A" means A and A when
   `one_ok`) into v[2]; 1 on success. */
static int parse_pair(const char *text, double v[2], int one_ok)
{
	char *end;
	double a = strtod(text, &end), b;

	if (end == text || !(a > 0) || !isfinite(a))
		return 0;
	if (*end == '\0' && one_ok) {
		v[0] = v[1] = a;
		return 1;
	}
	if (*end != 'x' && *end != 'X' && *end != ',')
		return 0;
	text = end + 1;
	b = strtod(text, &end);
	if (end == text || *end || !(b > 0) || !isfinite(b))
		return 0;
	v[0] = a;
	v[1] = b;
	return 1;
}

/* --sett ENDSxPICKS: threads per cm, each in (0, 10000]. */
static const char *opt_sett(const char *text, void *dest)
{
	double *v = dest;

	if (!parse_pair(text, v, 0) || v[0] > 10000 || v[1] > 10000)
		return "ENDS_PER_CMxPICKS_PER_CM, two numbers in (0, 10000] such as 54x54";
	return NULL;
}

/* --yarn-diameter UM or WARP,WEFT: micrometres, each in (0, 10000]. */
static const char *opt_yarn_diameter(const char *text, void *dest)
{
	double *v = dest;

	if (!parse_pair(text, v, 1) || v[0] > 10000 || v[1] > 10000)
		return "UM or WARP_UM,WEFT_UM, micrometres in (0, 10000] such as 180,220";
	return NULL;
}

static int sub_generate(int argc, char **argv)
{
	const char *prog = "loom exemplar generate";
	const char *out = NULL, *preset = "small", *weaves = NULL;
	const char *design = NULL, *map = NULL, *like = NULL, *name = NULL;
	uint32_t win[4] = {0}, drows = 0, dcols = 0;
	uint8_t *dweave = NULL;
	char *wbuf = NULL;
	int quiet = 0, json = 0, scan = 0, raw_density = 0, rc;
	uint32_t cross[2], block[3], brick[3], level = 0, threads = 0, fmt = 0;
	uint32_t min_cross = 0;
	uint64_t seed = 0;
	double vs = 0, sett[2] = {0, 0}, ydiam[2] = {0, 0};
	const char *sett_from = NULL, *fibre = "cotton";
	char fbuf[64], *fcomma;
	loom_exgen_params p;
	loom_diag diag;
	progress_state ps;
	uint64_t hash = 0;
	double t0;
	opt_entry opts[] = {
		OPT_OUTPUT(&out, "DB", "database to write (.ldb)"),
		OPT_CALLBACK(0, "preset", &preset, "NAME", opt_preset, "small (default: block "
		             "24x16x48, 24 um voxels),\npaper (115x70x300, 5 um: the paper's "
		             "scale) or\ntiny (8x6x12, 72 um: test corpora)"),
		OPT_STRING(0, "weaves", &weaves, "LIST", "comma-separated weaves (loom pattern "
		           "names, e.g. twill:2/3,satin:1/4,plain); default: the 2/3, 3/2, 1/4, "
		           "4/1 twills and the same four satins, the 2/3 and 3/2 S twills, "
		           "basket:1/3, satin:1/7 and satin:7/1"),
		OPT_SEED(&seed, "N", "random seed (default 1)"),
		OPT_SIZE2(0, "crossings", cross, "RxC", 1, UINT32_MAX, "crossings per exemplar, "
		          "multiples of each weave's repeat (default: the smallest multiple >= "
		          "4, so 5x5 for the 5-end weaves)"),
		OPT_U32(0, "min-crossings", &min_cross, "N", 1, 64, "without --crossings: "
		        "each side the smallest multiple of the weave's repeat >= N, %r "
		        "(default 4; 10 makes 10x10 twills and 16x16 1/7 satins, a file 4x "
		        "larger whose figures vary less from seed to seed, as the default "
		        "database and the databases made for a draft's sett)"),
		OPT_SIZE3(0, "block", block, "B1xB2xB3", 0, UINT32_MAX,
		          "block size in voxels (overrides the preset)"),
		OPT_DOUBLE(0, "voxel-size", &vs, "UM", "(]", 0, 10000, "micrometres",
		           "voxel edge in micrometres, %r (overrides the preset)"),
		OPT_CALLBACK(0, "sett", sett, "ENDSxPICKS", opt_sett, "sett in ends and "
		             "picks per cm, e.g. 54x54: sets the block's b1 x b2 at the "
		             "voxel size (b1 = 10000 / (ends per cm x voxel um)), b3 deep "
		             "enough for the cloth"),
		OPT_CALLBACK(0, "yarn-diameter", ydiam, "UM[,UM]", opt_yarn_diameter,
		             "free yarn diameter in micrometres, warp and weft (one "
		             "number: both); default: in proportion to the spacing"),
		OPT_STRING(0, "fibre", &fibre, "F[,F]", "fibre-level yarns (plies of "
		           "twisted fibres), warp and weft (one name: both): cotton, rayon, "
		           "silk, polyester, wool, linen, monofilament (default: cotton), "
		           "or none (smooth yarns with fibre-like noise)"),
		OPT_STRING(0, "sett-from", &sett_from, "DRAFT", "take the sett and yarn "
		           "diameters the draft states (WIF [WARP]/[WEFT] Spacing, "
		           "Thickness, Units and the SPACING/THICKNESS tables); --sett and "
		           "--yarn-diameter override them"),
		OPT_SIZE3(0, "brick", brick, "XxYxZ", 0, UINT32_MAX,
		          "brick shape (default 16x16x64)"),
		OPT_U32(0, "level", &level, "L", 1, 12, "libdeflate level %r (default 6)"),
		OPT_U32(0, "format-version", &fmt, "N", 1, 4, "database format %r (default 4: "
		        "density planes zero-run coded, decoded several times faster than "
		        "DEFLATE; 2: all planes deflated, a smaller file; 3: as "
		        "2, the density plane in eight segments; docs/formats.md)"),
		OPT_FLAG(0, "raw-density", &raw_density, "store the density planes raw (a "
		         "larger file; density misses copy instead of decoding; "
		         "docs/exemplars.md)"),
		OPT_THREADS(&threads, 64, "worker threads (default 2; %r)"),
		OPT_STRING(0, "design", &design, "DESIGN", "write the woven ground truth of "
		           "DESIGN (WIF, weave image, or an image with --map): one exemplar "
		           "whose weave is the whole design (docs/fidelity.md)"),
		OPT_STRING(0, "map", &map, "MAPFILE", "with --design: DESIGN is a posterized "
		           "image, MAPFILE maps its colours (docs/designs.md)"),
		OPT_STRING(0, "like", &like, "DB", "with --design: the block, voxel size, "
		           "brick shape and seed of database DB (instead of --preset)"),
		OPT_CALLBACK(0, "window", win, "R0,C0:R1,C1", opt_window, "with --design: "
		             "only picks R0..R1-1 and ends C0..C1-1 (for designs beyond the "
		             "limit, 1024 a side and 65536 voxels)"),
		OPT_STRING(0, "name", &name, "NAME", "with --design: the exemplar's name "
		           "(default: design)"),
		OPT_FLAG(0, "scan", &scan, "write a scan-like volume of a woven sheet instead, "
		         "for loom exemplar build (its options: loom exemplar generate --scan "
		         "--help)"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_QUIET(&quiet, "no progress or summary"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage_generate, .about = about_generate,
	              .opts = opts};

	opts_parse(&c, argc, argv);
	if (!out)
		opts_usage(&c, "missing -o DB");
	cli_check_output(prog, out);
	if (loom_exgen_preset(preset, &p) != LOOM_OK)
		opts_usage(&c, "--preset: expected small, paper or tiny, got '%s'", preset);
	if (!design && (map || like || opt_given(&c, win) || name))
		opts_usage(&c, "--map, --like, --window and --name go with --design");
	if (design && (weaves || opt_given(&c, cross)))
		opts_usage(&c, "--design makes one exemplar of the whole design: no --weaves "
		           "or --crossings");
	if (like && opt_given(&c, &preset))
		opts_usage(&c, "--like and --preset both set the geometry: give one");
	if (like) {
		loom_db *ldb;
		loom_db_info li;
		cli_diag_init(&diag, &quiet);
		if (loom_db_open(like, &ldb, &diag) != LOOM_OK)
			cli_fail(prog, "--like: %s", diag.message);
		loom_db_get_info(ldb, &li);
		memcpy(p.block, li.block, sizeof p.block);
		memcpy(p.brick, li.brick, sizeof p.brick);
		p.voxel_size_um = li.voxel_size_um;
		p.seed = li.seed ? li.seed : 1;
		loom_db_close(ldb);
	}
	if (weaves) {
		char *s, *tok, *save = NULL;
		wbuf = strdup(weaves);
		if (!wbuf)
			cli_fail(prog, "out of memory");
		p.n_weaves = 0;
		for (s = wbuf; (tok = strtok_r(s, ",", &save)) != NULL; s = NULL) {
			if (p.n_weaves == LOOM_EXGEN_MAX_WEAVES)
				opts_usage(&c, "more than %d weaves", LOOM_EXGEN_MAX_WEAVES);
			p.weaves[p.n_weaves++] = tok;
		}
		if (p.n_weaves == 0)
			opts_usage(&c, "--weaves needs at least one weave");
	}
	/* the options override the preset */
	if (opt_given(&c, &seed))
		p.seed = seed;
	if (opt_given(&c, cross)) {
		p.rows = cross[0];
		p.cols = cross[1];
		if (opt_given(&c, &min_cross))
			opts_usage(&c, "--min-crossings and --crossings exclude each other");
	}
	if (opt_given(&c, &min_cross))
		p.min_crossings = min_cross;
	if (opt_given(&c, block))
		memcpy(p.block, block, sizeof p.block);
	if (opt_given(&c, brick))
		memcpy(p.brick, brick, sizeof p.brick);
	if (opt_given(&c, &vs))
		p.voxel_size_um = (float)vs;
	cli_diag_init(&diag, &quiet);
	if (sett_from) {
		loom_design *d = NULL;
		if (loom_design_read(sett_from, &d, &diag) != LOOM_OK)
			cli_fail(prog, "%s", diag.message);
		if (!opt_given(&c, sett) && d->sett[0] > 0 && d->sett[1] > 0) {
			sett[0] = d->sett[0];
			sett[1] = d->sett[1];
		} else if (!opt_given(&c, sett) && (d->sett[0] > 0 || d->sett[1] > 0)) {
			/* one side stated: square crossings */
			sett[0] = sett[1] = d->sett[0] > 0 ? d->sett[0] : d->sett[1];
			if (!quiet)
				fprintf(stderr, "loom: warning: %s states the %s sett only; using "
				        "%.4g per cm for both\n", sett_from,
				        d->sett[0] > 0 ? "warp" : "weft", sett[0]);
		} else if (!opt_given(&c, sett))
			if (!quiet)
				fprintf(stderr, "loom: warning: %s states no sett; the block "
				        "stays %ux%u\n", sett_from, p.block[0], p.block[1]);
		if (!opt_given(&c, ydiam)) {
			ydiam[0] = d->yarn_um[0] > 0 ? d->yarn_um[0] : d->yarn_um[1];
			ydiam[1] = d->yarn_um[1] > 0 ? d->yarn_um[1] : d->yarn_um[0];
		}
		loom_design_free(d);
	}
	if (sett[0] > 0 && opt_given(&c, block))
		opts_usage(&c, "--block and a sett (--sett, --sett-from) both set the "
		           "block size; give one");
	p.yarn_diameter_um[0] = (float)ydiam[0];
	p.yarn_diameter_um[1] = (float)ydiam[1];
	snprintf(fbuf, sizeof fbuf, "%s", fibre);
	fcomma = strchr(fbuf, ',');
	if (fcomma)
		*fcomma++ = '\0';
	p.fibre[0] = fbuf;
	p.fibre[1] = fcomma ? fcomma : fbuf;
	if (loom_exgen_check_params(&p, &diag) != LOOM_OK && strstr(diag.message, "fibre"))
		opts_usage(&c, "--fibre: %s", diag.message);
	if (sett[0] > 0 && loom_exgen_set_sett(&p, sett[0], sett[1], &diag) != LOOM_OK) {
		if (opt_given(&c, sett))
			opts_usage(&c, "--sett: %s", diag.message);
		cli_fail(prog, "%s: %s", sett_from, diag.message);
	}
	if (opt_given(&c, &level))
		p.level = (int)level;
	if (opt_given(&c, &fmt))
		p.db_version = fmt;
	if (raw_density && p.db_version == 1)
		opts_usage(&c, "--raw-density needs format version 2, 3 or 4 (version 1 "
		           "stores a brick as one stream)");
	p.density_raw = (uint32_t)raw_density;
	if (opt_given(&c, &threads))
		p.threads = threads;
	memset(&ps, 0, sizeof ps);
	ps.on = !quiet && isatty(2);
	ps.last_pct = -1;
	ps.t0 = t0 = now_s();
	p.progress = progress_cb;
	p.user = &ps;
	cli_diag_init(&diag, &quiet);
	if (design) {
		dweave = design_weave(prog, design, map, win, opt_given(&c, win) != 0, &p,
		                      &drows, &dcols, &diag);
		rc = loom_exgen_write_design(out, &p, name, drows, dcols, dweave, &hash, &diag);
		free(dweave);
	} else {
		rc = loom_exgen_write_db(out, &p, &hash, &diag);
	}
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

/* generate, or generate --scan when --scan is among the arguments. */
static int sub_generate_any(int argc, char **argv)
{
	for (int i = 1; i < argc; i++)
		if (strcmp(argv[i], "--scan") == 0)
			return exemplar_generate_scan(argc, argv);
	return sub_generate(argc, argv);
}

int cmd_exemplar(int argc, char **argv)
{
	static const opts_sub subs[] = {
		{"generate", NULL, sub_generate_any, "make procedural CT-like exemplars into a "
		 "new database\n(--scan: a scan-like volume of a woven sheet, for build)"},
		{"build", NULL, exemplar_build, "turn a scan into an exemplar appended to a "
		 "database"},
		{"info", NULL, exemplar_info, "list a database's exemplars"},
		{"verify", NULL, exemplar_verify, "check every brick and checksum of a database"},
		{"export", NULL, exemplar_export, "write one exemplar volume as NRRD"},
		{"convert", NULL, exemplar_convert, "write a database again in another format "
		 "version\nor with its density planes raw or deflated"},
		{NULL, NULL, NULL, NULL},
	};
	static const opts_dispatch d = {"loom exemplar", about_main, footer_main, subs};

	return opts_run_sub(&d, argc, argv);
}
