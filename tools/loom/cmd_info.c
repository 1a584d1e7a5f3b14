/*
 * tools/loom/cmd_info.c - `loom info FABRIC`: what a fabric file holds
 * (docs/fabric.md): design, voxel dimensions, virtual size of a bolt,
 * synthesis parameters and metrics, and its database.
 */
#include "cli.h"
#include "commands.h"
#include "tiles.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char about[] =
	"Describe a fabric file made by `loom synth`: design size, voxel\n"
	"dimensions and physical size of one repeat, total virtual voxels of a\n"
	"bolt, synthesis parameters, metrics, and the database it belongs to.\n";

static int file_exists(const char *p)
{
	struct stat st;
	return p && *p && stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

int cmd_info(int argc, char **argv)
{
	const char *prog = "loom info";
	const char *path = NULL, *db_opt = NULL, *check = NULL;
	int json = 0, quiet = 0, found = 0, matches = 0;
	double len, wid, rep_mm[3], total;
	uint64_t rep[3], bolt[3], db_hash = 0, fbytes = 0;
	tiles_bolt b = {1, 1, 0, 0, NULL};
	loom_fabric *f = NULL;
	loom_fabric_params p;
	loom_fabric_db_identity id;
	loom_fabric_metrics m;
	const loom_design *d;
	loom_diag diag;
	struct stat st;
	opt_entry opts[] = {
		OPT_DB(&db_opt, "check the fabric against this database: exit 1 if its content "
		       "hash differs (without --db the path recorded in the fabric is checked, "
		       "if it exists)"),
		OPT_CALLBACK(0, "bolt", &b, "LxW", tiles_opt_bolt, "bolt LENGTH (along the "
		             "warps) by WIDTH (across): numbers of repeats (\"10x2\", fractions "
		             "allowed) or lengths with a unit mm, cm or m (\"50mx1.5m\"); default "
		             "1x1 (one repeat)"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog,
	              .usage = "loom info FABRIC [--db DB] [--bolt LENGTHxWIDTH] [--json]",
	              .about = about, .exit1 = "bad input or database mismatch",
	              .opts = opts, .pos_name = "FABRIC", .pos_min = 1, .pos_max = 1,
	              .pos = &path};

	opts_parse(&c, argc, argv);
	len = b.len;
	wid = b.wid;
	cli_diag_init(&diag, &quiet);

	if (db_opt) {
		/* an explicit database must match: open bound to it */
		loom_db *db = NULL;
		if (loom_db_open(db_opt, &db, &diag) != LOOM_OK)
			cli_fail(prog, "%s", diag.message);
		if (loom_fabric_open(path, db, 0, &f, &diag) != LOOM_OK)
			cli_fail(prog, "%s", diag.message);
		db_hash = loom_db_content_hash(db);
		loom_fabric_free(f);
		loom_db_close(db);
		f = NULL;
		check = db_opt;
		found = matches = 1;
	}
	if (loom_fabric_open(path, NULL, LOOM_FABRIC_OPEN_DETACHED, &f, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (stat(path, &st) == 0)
		fbytes = (uint64_t)st.st_size;
	loom_fabric_get_params(f, &p);
	loom_fabric_get_db_identity(f, &id);
	loom_fabric_get_metrics(f, &m);
	d = loom_fabric_design(f);
	if (!db_opt && file_exists(id.path)) {
		loom_db *db = NULL;
		check = id.path;
		if (loom_db_open(id.path, &db, NULL) == LOOM_OK) {
			found = 1;
			db_hash = loom_db_content_hash(db);
			matches = db_hash == id.content_hash;
			loom_db_close(db);
			if (!matches && !json)
				cli_warn_sink(&quiet, "the database at the recorded path has changed "
				              "(see below)");
		}
	}
	loom_fabric_repeat_voxels(f, rep);
	for (int k = 0; k < 3; k++)
		rep_mm[k] = (double)rep[k] * id.voxel_size_um / 1000.0;
	if (b.len_mm)
		len /= rep_mm[1];
	if (b.wid_mm)
		wid /= rep_mm[0];
	if (loom_fabric_bolt_voxels(f, len, wid, bolt, &total) != LOOM_OK)
		cli_fail(prog, "--bolt '%s': too large", b.text ? b.text : "1x1");

	if (json) {
		json_w w;
		char hs[32];
		jw_begin(&w, stdout);
		jw_str(&w, "fabric", path);
		jw_uint(&w, "file_bytes", fbytes);
		jw_obj(&w, "design");
		jw_uint(&w, "rows", d->rows);
		jw_uint(&w, "cols", d->cols);
		jw_uint(&w, "crossings", (uint64_t)d->rows * d->cols);
		jw_uint(&w, "yarn_types", d->n_types);
		jw_close(&w);
		jw_arr(&w, "repeat_voxels");
		for (int k = 0; k < 3; k++)
			jw_uint(&w, NULL, rep[k]);
		jw_close(&w);
		jw_num(&w, "voxel_size_um", id.voxel_size_um);
		jw_arr(&w, "repeat_mm");
		for (int k = 0; k < 3; k++)
			jw_num(&w, NULL, rep_mm[k]);
		jw_close(&w);
		jw_obj(&w, "bolt");
		jw_num(&w, "length_repeats", len);
		jw_num(&w, "width_repeats", wid);
		jw_num(&w, "length_mm", len * rep_mm[1]);
		jw_num(&w, "width_mm", wid * rep_mm[0]);
		jw_arr(&w, "voxels");
		for (int k = 0; k < 3; k++)
			jw_uint(&w, NULL, bolt[k]);
		jw_close(&w);
		if (bolt[0] && bolt[1] <= UINT64_MAX / bolt[0] &&
		    bolt[2] <= UINT64_MAX / (bolt[0] * bolt[1]))
			jw_uint(&w, "total_voxels", bolt[0] * bolt[1] * bolt[2]);
		else
			jw_num(&w, "total_voxels", total);
		jw_close(&w);
		jw_obj(&w, "params");
		jw_str(&w, "algo", loom_fabric_algo_name(p.algo));
		jw_uint(&w, "seed", p.seed);
		jw_uint(&w, "group", p.group);
		jw_uint(&w, "rank", p.rank);
		jw_uint(&w, "rank_h", p.rank_h);
		jw_uint(&w, "rank_v", p.rank_v);
		jw_uint(&w, "flags", p.flags);
		jw_bool(&w, "edge_tables_stored", p.edge_stored);
		jw_close(&w);
		jw_obj(&w, "metrics");
		jw_num(&w, "correctness", m.repeat.correctness);
		jw_num(&w, "consistency", m.repeat.consistency);
		jw_num(&w, "continuity", m.repeat.continuity);
		jw_num(&w, "bolt_continuity", m.bolt.continuity);
		jw_uint(&w, "window_rows", m.window_rows);
		jw_uint(&w, "window_cols", m.window_cols);
		jw_num(&w, "seam_before", m.seam.before_mean);
		jw_num(&w, "seam_after", m.seam.after_mean);
		jw_num(&w, "internal_step", m.seam.internal_step);
		jw_num(&w, "seam_before_ratio", m.seam.before_ratio);
		jw_num(&w, "seam_after_ratio", m.seam.after_ratio);
		jw_arr(&w, "usage");
		for (uint32_t u = 0; u < m.n_exemplars; u++)
			jw_uint(&w, NULL, m.usage[u]);
		jw_close(&w);
		jw_close(&w);
		jw_obj(&w, "database");
		jw_str(&w, "path", id.path);
		snprintf(hs, sizeof hs, "%016llx", (unsigned long long)id.content_hash);
		jw_str(&w, "content_hash", hs);
		jw_uint(&w, "exemplars", id.n_exemplars);
		jw_uint(&w, "blocks", id.n_blocks);
		jw_arr(&w, "block");
		jw_uint(&w, NULL, id.block[0]);
		jw_uint(&w, NULL, id.block[1]);
		jw_uint(&w, NULL, id.block[2]);
		jw_close(&w);
		if (check)
			jw_str(&w, "checked", check);
		jw_bool(&w, "found", found);
		if (found) {
			snprintf(hs, sizeof hs, "%016llx", (unsigned long long)db_hash);
			jw_str(&w, "found_hash", hs);
			jw_bool(&w, "matches", matches);
		}
		jw_close(&w);
		jw_end(&w);
	} else {
		printf("fabric %s (%llu bytes)\n", path, (unsigned long long)fbytes);
		printf("  design      %u x %u crossings (picks x ends), %u yarn types\n",
		       d->rows, d->cols, d->n_types);
		printf("  repeat      %llu x %llu x %llu voxels (x, y, z = cols*b1, rows*b2, "
		       "b3) of %g um = %.3f x %.3f x %.3f mm\n", (unsigned long long)rep[0],
		       (unsigned long long)rep[1], (unsigned long long)rep[2],
		       (double)id.voxel_size_um, rep_mm[0], rep_mm[1], rep_mm[2]);
		printf("  bolt        %g x %g repeats (%.1f x %.1f mm, length x width): "
		       "%llu x %llu x %llu = %.4g voxels\n", len, wid, len * rep_mm[1],
		       wid * rep_mm[0], (unsigned long long)bolt[0],
		       (unsigned long long)bolt[1], (unsigned long long)bolt[2], total);
		printf("  synthesis   %s, seed %llu, group %u, rank %u (%u/%u), edge tables "
		       "%s\n", loom_fabric_algo_name(p.algo), (unsigned long long)p.seed,
		       p.group, p.rank, p.rank_h, p.rank_v,
		       p.edge_stored ? "stored" : "rebuilt at open");
		printf("  metrics     correctness %.3f, consistency %.3f, continuity %.3f "
		       "(bolt %.3f); seams %.3f -> %.3f voxels (internal step %.3f)\n",
		       m.repeat.correctness, m.repeat.consistency, m.repeat.continuity,
		       m.bolt.continuity, m.seam.before_mean, m.seam.after_mean,
		       m.seam.internal_step);
		printf("  database    %s (%016llx): %u exemplars, %u blocks of %ux%ux%u",
		       id.path, (unsigned long long)id.content_hash, id.n_exemplars,
		       id.n_blocks, id.block[0], id.block[1], id.block[2]);
		if (!check)
			printf("; not found (give --db DB to check)\n");
		else if (matches)
			printf("; %s matches\n", check);
		else if (found)
			printf("; %s DIFFERS (content hash %016llx)\n", check,
			       (unsigned long long)db_hash);
		else
			printf("; %s cannot be opened\n", check);
	}
	loom_fabric_free(f);
	return 0;
}
