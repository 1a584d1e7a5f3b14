/*
 * tools/loom/exemplar_info.c - `loom exemplar info|verify|export`: list a
 * database's exemplars, check every brick, write one exemplar as NRRD
 * (docs/exemplars.md).
 */
#include "cli.h"
#include "exemplar.h"
#include "opts.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char about_info[] =
	"List the exemplars of a database: weave, crossings, block size, voxel\n"
	"count, raw and compressed bytes, compression ratio.\n";

static const char about_verify[] =
	"Read every brick of a database, check its CRC32, decompress it to the\n"
	"exact size and check its labels.  Exit status 0 when all are good, 1\n"
	"naming the first bad brick otherwise.  A voxel of density 0 with an\n"
	"orientation code breaks the voxel rule (docs/formats.md): `loom exemplar\n"
	"convert` writes such a file again with those codes cleared.\n";

static const char about_export[] =
	"Write one exemplar volume as NRRD (raw data, axes x y z, spacing = voxel\n"
	"size in mm) for viewing in standard tools (unu, ParaView, 3D Slicer).\n";

#define DB_POS_HELP "database (or give it as the first argument)"

/* --channel: a name loom_db_channel_parse knows. */
static const char *opt_channel(const char *text, void *channel)
{
	if (loom_db_channel_parse(text, channel) != LOOM_OK)
		return "density, label, kind, orientation or orient-code";
	return NULL;
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

int exemplar_info(int argc, char **argv)
{
	const char *prog = "loom exemplar info", *dbopt = NULL, *pos = NULL;
	int json = 0;
	loom_db *db;
	loom_db_info info;
	char hs[32], row[1100];
	opt_entry opts[] = {
		OPT_DB(&dbopt, DB_POS_HELP),
		OPT_JSON(&json, "JSON object with an \"exemplars\" array (name, weave: one "
		         "string of 0/1 per pick, crossings, block, raw_bytes, "
		         "compressed_bytes, ...)"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = "loom exemplar info [DB] [--db DB] [--json]",
	              .about = about_info, .opts = opts, .pos_name = "DB", .pos_max = 1,
	              .pos = &pos};

	opts_parse(&c, argc, argv);
	db = open_db(prog, pos, dbopt);
	loom_db_get_info(db, &info);
	snprintf(hs, sizeof hs, "%016llx", (unsigned long long)info.content_hash);
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "path", pos ? pos : cli_db_path(dbopt));
		jw_uint(&w, "version", info.version);
		jw_uint(&w, "voxel_layout", info.voxel_layout);
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
		jw_uint(&w, "raw_density_planes", info.n_raw_density);
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
			if (e.fibre[0]) {
				jw_str(&w, "fibre_warp", loom_fibre_name(e.fibre[0]));
				jw_str(&w, "fibre_weft", loom_fibre_name(e.fibre[1]));
			}
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
		printf("  format version %u (%s), content hash %s, %llu bytes\n",
		       info.version, info.voxel_layout == 4 ? "each plane of a brick stored "
		       "apart, density zero-run coded" : info.voxel_layout == 3 ?
		       "each plane of a brick stored apart, density in 8 segments" :
		       info.voxel_layout == 2 ?
		       "each plane of a brick stored apart" : "one stream a brick", hs,
		       (unsigned long long)info.file_bytes);
		printf("  block %ux%ux%u voxels of %g um, brick %ux%ux%u, %llu bricks "
		       "(%llu empty, %llu stored raw, %llu density planes raw)\n",
		       info.block[0], info.block[1], info.block[2], (double)info.voxel_size_um,
		       info.brick[0], info.brick[1], info.brick[2],
		       (unsigned long long)info.n_bricks, (unsigned long long)info.n_empty_bricks,
		       (unsigned long long)info.n_raw_bricks,
		       (unsigned long long)info.n_raw_density);
		printf("\n  %-3s %-18s %-14s %-9s %12s %12s %12s %7s  %s\n", "#", "name",
		       "weave", "crossings", "voxels", "raw bytes", "compressed", "ratio",
		       "weave rows (pick 0 first)");
		for (uint32_t k = 0; k < info.n_exemplars; k++) {
			loom_db_exemplar_info e;
			char cr[24];
			loom_db_exemplar(db, k, &e);
			snprintf(cr, sizeof cr, "%ux%u", e.rows, e.cols);
			printf("  %-3u %-18s %-14s %-9s %12llu %12llu %12llu %6.1fx  ", k, e.name,
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

/* Progress of a pass over every brick; user: the command's name. */
static void bricks_progress(void *user, uint64_t done, uint64_t total)
{
	fprintf(stderr, "\r%s: %llu/%llu bricks", (const char *)user,
	        (unsigned long long)done, (unsigned long long)total);
	if (done == total)
		fputc('\n', stderr);
}

int exemplar_verify(int argc, char **argv)
{
	const char *prog = "loom exemplar verify", *dbopt = NULL, *pos = NULL;
	int quiet = 0, rc;
	loom_db *db;
	loom_db_info info;
	loom_diag diag;
	opt_entry opts[] = {
		OPT_DB(&dbopt, DB_POS_HELP),
		OPT_QUIET(&quiet, "no progress, no summary: the exit status says"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = "loom exemplar verify [DB] [--db DB] [--quiet]",
	              .about = about_verify, .exit1 = "a bad brick or file", .opts = opts,
	              .pos_name = "DB", .pos_max = 1, .pos = &pos};

	opts_parse(&c, argc, argv);
	db = open_db(prog, pos, dbopt);
	cli_diag_init(&diag, &quiet);
	rc = loom_db_verify(db, !quiet && isatty(2) ? bricks_progress : NULL, (void *)prog, &diag);
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

int exemplar_export(int argc, char **argv)
{
	const char *prog = "loom exemplar export", *dbopt = NULL, *pos = NULL;
	const char *ex = NULL, *out = NULL;
	int detached = 0, channel = LOOM_DB_CH_DENSITY;
	uint32_t k;
	loom_db *db;
	loom_diag diag;
	opt_entry opts[] = {
		OPT_DB(&dbopt, DB_POS_HELP),
		OPT_STRING(0, "exemplar", &ex, "K",
		           "exemplar name or index (see `loom exemplar info`)"),
		OPT_OUTPUT(&out, "FILE", "output file: FILE.nrrd (attached) or FILE.nhdr "
		           "(detached)"),
		OPT_CALLBACK(0, "channel", &channel, "C", opt_channel, "density (uint8, "
		             "default), label (uint8), kind (uint8: 0 empty, 1 warp, 2 weft), "
		             "orientation (3 x float32) or orient-code (uint16)"),
		OPT_FLAG(0, "detached", &detached,
		         "header in FILE, data in FILE with the extension .raw"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = "loom exemplar export [DB] [--db DB] "
	              "--exemplar K -o FILE\n                     [--channel C] [--detached]",
	              .about = about_export, .opts = opts, .pos_name = "DB", .pos_max = 1,
	              .pos = &pos};

	opts_parse(&c, argc, argv);
	if (!ex)
		opts_usage(&c, "missing --exemplar K");
	if (!out)
		opts_usage(&c, "missing -o FILE");
	cli_check_output(prog, out);
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

/* ---- convert ------------------------------------------------------------- */

static const char about_convert[] =
	"Write a database again in another storage: --format-version N (1 to 4)\n"
	"and the density planes raw (--raw-density: a larger file, no decoding on\n"
	"a miss) or compressed (--deflate-density: DEFLATE in versions 1 to 3,\n"
	"zero runs in version 4).  Without an option each is\n"
	"kept.  The voxels, exemplars and block tables are the same (but for\n"
	"orientation codes on voxels of density 0, against the voxel rule of\n"
	"docs/formats.md: they are cleared, and a warning says how many); the\n"
	"content hash is not, so fabrics made over DB need `loom synth` again\n"
	"over OUT.\n"
	"One brick in memory at a time; OUT appears only when complete.\n";

int exemplar_convert(int argc, char **argv)
{
	const char *prog = "loom exemplar convert", *dbopt = NULL, *pos = NULL, *out = NULL;
	const char *in;
	int quiet = 0, json = 0, raw = 0, deflated = 0, rc;
	uint32_t fmt = 0;
	uint64_t hash = 0;
	loom_db *db;
	loom_db_info a, b;
	loom_diag diag;
	opt_entry opts[] = {
		OPT_DB(&dbopt, DB_POS_HELP),
		OPT_OUTPUT(&out, "OUT", "database to write (.ldb; not the input)"),
		OPT_U32(0, "format-version", &fmt, "N", 1, 4, "format of OUT %r (default: "
		        "the input's; docs/formats.md)"),
		OPT_FLAG(0, "raw-density", &raw, "store the density planes raw"),
		OPT_FLAG(0, "deflate-density", &deflated, "store the density planes compressed "
		         "(DEFLATE; zero runs in version 4)"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_QUIET(&quiet, "no progress, no summary"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = "loom exemplar convert [DB] [--db DB] -o OUT "
	              "[--format-version N]\n                      [--raw-density | "
	              "--deflate-density]\n                      [--json] [--quiet]",
	              .about = about_convert, .exit1 = "a bad input, a failed read or write",
	              .opts = opts, .pos_name = "DB", .pos_max = 1, .pos = &pos};

	opts_parse(&c, argc, argv);
	if (!out)
		opts_usage(&c, "missing -o OUT");
	if (raw && deflated)
		opts_usage(&c, "--raw-density and --deflate-density: give one");
	if (raw && fmt == 1)
		opts_usage(&c, "--raw-density needs format version 2 or 3 (version 1 stores "
		           "a brick as one stream)");
	cli_check_output(prog, out);
	db = open_db(prog, pos, dbopt); /* the input checked, named as given */
	loom_db_get_info(db, &a);
	loom_db_close(db);
	in = pos ? pos : cli_db_path(dbopt);
	cli_diag_init(&diag, &quiet);
	rc = loom_db_convert(in, out, fmt, raw ? 1 : deflated ? 0 : -1,
	                     !quiet && !json && isatty(2) ? bricks_progress : NULL, (void *)prog,
	                     &hash, &diag);
	if (rc != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (loom_db_open(out, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	loom_db_get_info(db, &b);
	loom_db_close(db);
	if (json) {
		json_w w;
		char hs[2][24];
		snprintf(hs[0], sizeof hs[0], "%016llx", (unsigned long long)a.content_hash);
		snprintf(hs[1], sizeof hs[1], "%016llx", (unsigned long long)b.content_hash);
		jw_begin(&w, stdout);
		jw_str(&w, "input", in);
		jw_str(&w, "output", out);
		jw_uint(&w, "version", b.version);
		jw_uint(&w, "raw_density_planes", b.n_raw_density);
		jw_uint(&w, "bricks", b.n_bricks);
		jw_uint(&w, "input_bytes", a.file_bytes);
		jw_uint(&w, "file_bytes", b.file_bytes);
		jw_str(&w, "input_content_hash", hs[0]);
		jw_str(&w, "content_hash", hs[1]);
		jw_end(&w);
	} else if (!quiet) {
		printf("%s: version %u, %llu bricks (%llu density planes raw), %llu bytes "
		       "(input %llu), content hash %016llx\n", out, b.version,
		       (unsigned long long)b.n_bricks, (unsigned long long)b.n_raw_density,
		       (unsigned long long)b.file_bytes, (unsigned long long)a.file_bytes,
		       (unsigned long long)b.content_hash);
	}
	return 0;
}
