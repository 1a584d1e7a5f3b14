/*
 * tools/loom/cmd_look.c - `loom look DRAFT`: the designer's one command.
 * Read the draft, synthesize it over the default exemplar database, and
 * write into DIR: the colour drawdown, the draft diagram, an anti-aliased
 * preview of one repeat with a scale bar, a close-up of a few crossings,
 * and a progressive render (rewritten after each pass until a time or
 * noise limit); then list what it wrote (docs/designers.md).
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "picture.h"
#include "progress.h"
#include "views.h"

#include <errno.h>
#include <spawn.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

extern char **environ;

static const char usage[] =
	"loom look DRAFT [-o DIR] [--open] [--time S] [--noise N] [--width PX]\n"
	"                [--db DB] [--seed N] [--threads N] [--json] [--quiet]\n";

static const char about[] =
	"Show what a draft will look like woven, in one command: read DRAFT (a WIF\n"
	"draft or any design loom reads), synthesize the cloth over the exemplar\n"
	"database, and write into DIR (default NAME-look/, NAME the draft's file\n"
	"name) the colour drawdown, the draft diagram, an anti-aliased preview of\n"
	"one repeat with a scale bar, a close-up of a few crossings, and a render\n"
	"that is written after a first quick pass and rewritten as it refines,\n"
	"until --time seconds or --noise; then print the files.  Every picture has\n"
	"pick 1 at the top and end 1 at the left, as the drawdown.\n";

#define LOOK_MAX_FILES 8

typedef struct look_file {
	char path[4200];
	const char *what;
	double at;              /* seconds since start when written */
} look_file;

typedef struct look {
	const char *prog, *dir, *name;
	int quiet;
	double t0;
	look_file files[LOOK_MAX_FILES];
	int n_files;
} look;

static const char *file_in(look *lk, const char *suffix, char *buf, size_t n)
{
	snprintf(buf, n, "%s/%s%s", lk->dir, lk->name, suffix);
	return buf;
}

static void wrote(look *lk, const char *path, const char *what)
{
	look_file *f = NULL;

	for (int k = 0; k < lk->n_files; k++)
		if (!strcmp(lk->files[k].path, path))
			f = &lk->files[k];
	if (!f && lk->n_files < LOOK_MAX_FILES)
		f = &lk->files[lk->n_files++];
	if (!f)
		return;
	snprintf(f->path, sizeof f->path, "%s", path);
	f->what = what;
	f->at = cli_now() - lk->t0;
	if (!lk->quiet)
		fprintf(stderr, "%s: %5.1f s  %s  (%s)\n", lk->prog, f->at, path, what);
}

/* Base name of path without directory and extension, into buf. */
static const char *stem(const char *path, char *buf, size_t n)
{
	const char *b = strrchr(path, '/'), *dot;
	size_t len;

	b = b ? b + 1 : path;
	dot = strrchr(b, '.');
	len = dot && dot > b ? (size_t)(dot - b) : strlen(b);
	if (len >= n)
		len = n - 1;
	memcpy(buf, b, len);
	buf[len] = 0;
	if (!buf[0])
		snprintf(buf, n, "draft");
	return buf;
}

/* A preview of [lo, hi) at width W into path. */
static int look_preview(look *lk, loom_texture *t, const loom_fabric *f,
                        const int64_t lo[2], const int64_t hi[2], uint32_t W,
                        uint32_t threads, double vox_mm, const char *path,
                        const char *what, loom_diag *diag)
{
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	pic_out pic;
	uint32_t w, h;
	int rc;

	po.lo[0] = lo[0];
	po.lo[1] = lo[1];
	po.hi[0] = hi[0];
	po.hi[1] = hi[1];
	po.width = W;
	po.threads = threads;
	if ((rc = loom_preview_size(&po, &w, &h)) != LOOM_OK)
		return rc;
	memset(&pic, 0, sizeof pic);
	pic.path = path;
	pic.scale_bar = 1;
	pic.mm_per_px = (double)(hi[0] - lo[0]) * vox_mm / w;
	if ((rc = pic_open(&pic, w, h, diag)) != LOOM_OK)
		return rc;
	rc = loom_preview_stream(t, f, &po, pic_band, &pic, NULL, diag);
	if (rc != LOOM_OK) {
		pic_abort(&pic);
		return rc;
	}
	if ((rc = pic_finish(&pic)) == LOOM_OK)
		wrote(lk, path, what);
	return rc;
}

static void write_index(look *lk)
{
	char path[4200], tmp[4300];
	FILE *fp;

	snprintf(path, sizeof path, "%s/index.html", lk->dir);
	snprintf(tmp, sizeof tmp, "%s.tmp.%d", path, (int)getpid());
	fp = fopen(tmp, "w");
	if (!fp)
		return;
	fprintf(fp, "<!doctype html>\n<meta charset=\"utf-8\">\n<title>%s: loom look"
	        "</title>\n<style>body{font-family:sans-serif;background:#222;color:#ddd}"
	        "figure{display:inline-block;margin:1em;vertical-align:top}"
	        "img{max-width:46vw;image-rendering:pixelated;border:1px solid #555}"
	        "</style>\n<h1>%s</h1>\n", lk->name, lk->name);
	for (int k = 0; k < lk->n_files; k++) {
		const char *base = strrchr(lk->files[k].path, '/');
		base = base ? base + 1 : lk->files[k].path;
		if (!cli_ends_with(base, ".png"))
			continue;
		fprintf(fp, "<figure><img src=\"%s\" alt=\"%s\"><figcaption>%s</figcaption>"
		        "</figure>\n", base, lk->files[k].what, lk->files[k].what);
	}
	if (fclose(fp) == 0 && rename(tmp, path) == 0)
		wrote(lk, path, "a page showing them all");
	else
		unlink(tmp);
}

int cmd_look(int argc, char **argv)
{
	const char *prog = "loom look";
	const char *in = NULL, *dir_opt = NULL, *db_opt = NULL, *db_path;
	int quiet = 0, json = 0, open_it = 0, rc;
	double time_limit = 25, noise = 0.02, vox_mm;
	uint32_t rwidth = 360, threads = 0;
	uint64_t seed = 1, rep[3];
	char name[256], dirbuf[4096], path[4200];
	loom_design *d = NULL;
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_fabric_options fo = LOOM_FABRIC_OPTIONS_INIT;
	loom_fabric_db_identity id;
	loom_diag diag;
	look lk;
	opt_entry opts[] = {
		OPT_OUTPUT(&dir_opt, "DIR", "directory for the pictures (default NAME-look, "
		           "made if missing)"),
		OPT_FLAG(0, "open", &open_it, "open the page of pictures (DIR/index.html) "
		         "with xdg-open when done"),
		OPT_DOUBLE(0, "time", &time_limit, "S", "(]", 0, 3600, "seconds",
		           "stop refining the render after S seconds in all, %r (default 25)"),
		OPT_DOUBLE(0, "noise", &noise, "N", "(]", 0, 1, NULL, "or once the render's "
		           "relative noise (standard error) is below N, %r (default 0.02)"),
		OPT_U32(0, "width", &rwidth, "PX", 16, 4096, "render width, %r (default 360; "
		        "height 5/8 of it)"),
		OPT_DB(&db_opt, "exemplar database (default: $LOOM_DB, then default.ldb in "
		       "the data directory)"),
		OPT_SEED(&seed, "N", "seed of synthesis and render (default 1)"),
		OPT_THREADS(&threads, 256, "worker threads (default: all CPUs)"),
		OPT_JSON(&json, "print the files written as JSON on stdout"),
		OPT_QUIET(&quiet, "no progress, no list"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage, .about = about, .opts = opts,
	              .pos_name = "DRAFT", .pos_min = 1, .pos_max = 1, .pos = &in};

	opts_parse(&c, argc, argv);
	memset(&lk, 0, sizeof lk);
	lk.prog = prog;
	lk.quiet = quiet || json;
	lk.t0 = cli_now();
	lk.name = stem(in, name, sizeof name);
	if (dir_opt) {
		lk.dir = dir_opt;
	} else {
		snprintf(dirbuf, sizeof dirbuf, "%s-look", name);
		lk.dir = dirbuf;
	}
	/* everything that can fail fast, before the long work */
	cli_check_output_dir(prog, lk.dir);
	db_path = cli_db_require(db_opt, prog);
	cli_diag_init(&diag, &quiet);
	if (loom_design_read(in, &d, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (mkdir(lk.dir, 0777) != 0 && errno != EEXIST)
		cli_fail(prog, "%s: cannot create: %s", lk.dir, strerror(errno));
	if (!lk.quiet)
		fprintf(stderr, "%s: %s: %u picks x %u ends; pictures into %s/\n", prog, in,
		        d->rows, d->cols, lk.dir);

	/* the weaver's pictures first: they need no synthesis */
	rc = loom_color_drawdown_write(file_in(&lk, "-drawdown.png", path, sizeof path), d,
	                               d->rows > 400 || d->cols > 400 ? 1
	                               : d->rows < 13 && d->cols < 13 ? 64
	                               : 800 / (d->rows > d->cols ? d->rows : d->cols) + 1,
	                               &diag);
	if (rc != LOOM_OK)
		goto fail_diag;
	wrote(&lk, path, "colour drawdown");
	{
		loom_draft *dr = NULL;
		rc = loom_draft_from_design(d, 24, &dr, &diag);
		if (rc == LOOM_OK)
			rc = loom_draft_write(file_in(&lk, "-draft.png", path, sizeof path), d, dr,
			                      0, 600, &diag);
		loom_draft_free(dr);
		if (rc == LOOM_OK)
			wrote(&lk, path, "draft diagram");
		else if (rc == LOOM_EUNSUPPORTED && !lk.quiet)
			fprintf(stderr, "%s: no draft diagram: %s\n", prog, diag.message);
		else if (rc != LOOM_EUNSUPPORTED)
			goto fail_diag;
	}

	/* synthesis */
	if (loom_db_open(db_path, &db, &diag) != LOOM_OK)
		goto fail_diag;
	fo.seed = seed;
	{
		uint32_t dfl[2], xfl[2];
		cli_float_check(prog, d, db, quiet, dfl, xfl);
	}
	if (loom_fabric_synthesize(d, db, db_path, &fo, &f, &diag) != LOOM_OK)
		goto fail_diag;
	if (loom_fabric_save(f, file_in(&lk, ".loomf", path, sizeof path), NULL, &diag) !=
	    LOOM_OK)
		goto fail_diag;
	wrote(&lk, path, "fabric (loom preview, render, serve, export read it)");
	loom_fabric_get_db_identity(f, &id);
	loom_fabric_repeat_voxels(f, rep);
	vox_mm = id.voxel_size_um * 1e-3;
	to.budget_bytes = (size_t)96 << 20;
	to.max_threads = 64;
	if (loom_texture_open(f, db, &to, &t, &diag) != LOOM_OK)
		goto fail_diag;

	/* previews: one repeat, and a close-up of 8 x 8 crossings at its centre */
	{
		int64_t lo[2] = {0, 0}, hi[2] = {(int64_t)rep[0], (int64_t)rep[1]};
		uint32_t ce = d->cols < 8 ? d->cols : 8, cp = d->rows < 8 ? d->rows : 8;
		int64_t cx = (int64_t)(d->cols / 2 - ce / 2) * id.block[0];
		int64_t cy = (int64_t)(d->rows / 2 - cp / 2) * id.block[1];
		int64_t clo[2] = {cx, cy};
		int64_t chi[2] = {cx + (int64_t)ce * id.block[0], cy + (int64_t)cp * id.block[1]};
		if (look_preview(&lk, t, f, lo, hi, 1024, threads, vox_mm,
		                 file_in(&lk, "-preview.png", path, sizeof path),
		                 "preview of one repeat", &diag) != LOOM_OK ||
		    look_preview(&lk, t, f, clo, chi, 640, threads, vox_mm,
		                 file_in(&lk, "-closeup.png", path, sizeof path),
		                 "close-up of 8 x 8 crossings", &diag) != LOOM_OK)
			goto fail_diag;
	}

	/* progressive render of one repeat (at most 48 crossings across) */
	{
		loom_volume_source src;
		loom_render_options ro = LOOM_RENDER_OPTIONS_INIT;
		view_prog vp;
		uint32_t rh = rwidth * 5 / 8, spp = 1;
		uint32_t ce = d->cols < 48 ? d->cols : 48, cp = d->rows < 30 ? d->rows : 30;
		int64_t lo[2] = {0, 0};
		int64_t hi[2] = {(int64_t)ce * id.block[0], (int64_t)cp * id.block[1]};
		double t_pass;
		loom_texture_volume_source(t, f, LOOM_FILTER_NEAREST, &src);
		view_render_setup(&src, lo, hi, rwidth, rh, &ro);
		ro.threads = threads;
		ro.seed = seed;
		if (view_prog_init(&vp, rwidth, rh) != LOOM_OK)
			cli_fail(prog, "out of memory for a %ux%u render", rwidth, rh);
		file_in(&lk, "-render.png", path, sizeof path);
		for (;;) {
			double t1 = cli_now();
			char what[96];
			if (view_prog_pass(&vp, &src, &ro, spp, &diag) != LOOM_OK) {
				view_prog_free(&vp);
				goto fail_diag;
			}
			t_pass = cli_now() - t1;
			if (cli_write_rgb(path, vp.mean, rwidth, rh, 0, &diag) != LOOM_OK) {
				view_prog_free(&vp);
				goto fail_diag;
			}
			snprintf(what, sizeof what, "render, %u spp, noise %.3f", vp.spp_total,
			         vp.passes > 1 ? vp.se : 1.0);
			wrote(&lk, path, "render (rewritten after each pass)");
			if (!lk.quiet && vp.passes > 1)
				fprintf(stderr, "%s:          %s\n", prog, what);
			if (vp.passes > 1 && vp.se < noise)
				break;
			/* the next pass doubles the samples so far (at most 64 spp);
			   stop when it would end past the time limit */
			{
				uint32_t next = vp.passes == 1 ? 1 : vp.spp_total < 64 ? vp.spp_total : 64;
				if (cli_now() - lk.t0 + t_pass * next / spp > time_limit)
					break;
				spp = next;
			}
		}
		write_index(&lk);
		if (json) {
			json_w w;
			jw_begin(&w, stdout);
			jw_str(&w, "draft", in);
			jw_str(&w, "dir", lk.dir);
			jw_uint(&w, "rows", d->rows);
			jw_uint(&w, "cols", d->cols);
			jw_uint(&w, "render_spp", vp.spp_total);
			jw_uint(&w, "render_passes", vp.passes);
			jw_num(&w, "render_noise", vp.se);
			jw_arr(&w, "files");
			for (int k = 0; k < lk.n_files; k++) {
				jw_obj(&w, NULL);
				jw_str(&w, "path", lk.files[k].path);
				jw_str(&w, "what", lk.files[k].what);
				jw_num(&w, "seconds", lk.files[k].at);
				jw_close(&w);
			}
			jw_close(&w);
			jw_num(&w, "seconds", cli_now() - lk.t0);
			jw_end(&w);
		}
		view_prog_free(&vp);
	}
	if (!lk.quiet) {
		printf("%s: wrote, in %.1f s:\n", in, cli_now() - lk.t0);
		for (int k = 0; k < lk.n_files; k++)
			printf("  %-44s %s\n", lk.files[k].path, lk.files[k].what);
	}
	if (open_it) {
		/* xdg-open DIR/index.html, without a shell (any path is safe) */
		char page[4200];
		char *args[] = {"xdg-open", page, NULL};
		pid_t pid;
		snprintf(page, sizeof page, "%s/index.html", lk.dir);
		if (posix_spawnp(&pid, "xdg-open", NULL, NULL, args, environ) != 0)
			fprintf(stderr, "%s: --open: cannot run xdg-open; open %s in a browser\n",
			        prog, page);
	}
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	loom_design_free(d);
	return 0;
fail_diag:
	cli_error(prog, "%s", diag.message);
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	loom_design_free(d);
	return EXIT_BAD_INPUT;
}
