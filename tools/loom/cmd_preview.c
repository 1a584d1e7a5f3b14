/*
 * tools/loom/cmd_preview.c - `loom preview FABRIC`: a shaded orthographic
 * top view of a fabric (loom_preview, docs/preview.md) as PNG (8-bit sRGB)
 * or EXR (linear float RGB), optionally with its height map.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "progress.h"

#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"loom preview FABRIC [--region X0,Y0:X1,Y1 | X0,Y0,Z0:X1,Y1,Z1]\n"
	"             [--width PX] [--height PX] [--budget MB] [--db DB]\n"
	"             [--threads N] [--threshold D] [--exposure STOPS]\n"
	"             [--height-map FILE] [--json] [--quiet] -o OUT.png|OUT.exr\n";

static const char about[] =
	"Draw the fabric from straight above (orthographic): per pixel the top-most\n"
	"voxel of the column under its centre, shaded from the height map and the\n"
	"fibre direction with one light, coloured by the yarn albedo\n"
	"(docs/preview.md).  Reads are streamed through the virtual texture in\n"
	"bounded memory; a 4096-pixel preview of a whole large fabric takes seconds.\n";

/* "X0,Y0:X1,Y1" or "X0,Y0,Z0:X1,Y1,Z1" */
static int parse_box(const char *s, int64_t lo[3], int64_t hi[3], int *has_z)
{
	char buf[256], *colon, *parts[2];
	int dims = -1;

	if (strlen(s) >= sizeof buf)
		return -1;
	strcpy(buf, s);
	colon = strchr(buf, ':');
	if (!colon)
		return -1;
	*colon = 0;
	parts[0] = buf;
	parts[1] = colon + 1;
	for (int k = 0; k < 2; k++) {
		int64_t *v = k ? hi : lo;
		char *p = parts[k];
		int n = 0;
		for (;;) {
			char *comma = strchr(p, ',');
			if (comma)
				*comma = 0;
			if (n == 3 || cli_parse_i64(p, &v[n]))
				return -1;
			n++;
			if (!comma)
				break;
			p = comma + 1;
		}
		if (n < 2 || (dims >= 0 && n != dims))
			return -1;
		dims = n;
	}
	*has_z = dims == 3;
	if (!*has_z) {
		lo[2] = 0;
		hi[2] = 0;
	}
	for (int a = 0; a < dims; a++)
		if (hi[a] <= lo[a])
			return -1;
	return 0;
}

/* --region: the box into a struct box. */
struct box {
	int64_t lo[3], hi[3];
	int has_z;
};

static const char *opt_region(const char *text, void *dest)
{
	struct box *b = dest;

	if (parse_box(text, b->lo, b->hi, &b->has_z))
		return "X0,Y0:X1,Y1 or X0,Y0,Z0:X1,Y1,Z1 with X0 < X1, Y0 < Y1 (and Z0 < Z1)";
	return NULL;
}

static void progress_cb(void *user, uint64_t done, uint64_t total)
{
	(void)total;
	cli_progress_update(user, done);
}

static int write_height(const char *path, const float *hm, uint32_t w, uint32_t h,
                        int64_t z0, int64_t z1, loom_diag *diag)
{
	if (cli_ends_with(path, ".exr")) {
		static const loom_exr_channel ch[1] = {{"height", LOOM_EXR_FLOAT}};
		return cli_write_exr(path, w, h, ch, 1, hm, diag);
	} else {
		loom_image *img = NULL;
		double span = (double)(z1 - z0);
		int rc = loom_image_new(w, h, 1, &img);
		if (rc != LOOM_OK)
			return rc;
		for (size_t p = 0; p < (size_t)w * h; p++) {
			double v = hm[p] > 0 ? ((double)hm[p] - (double)z0) / span : 0;
			v = v < 0 ? 0 : v > 1 ? 1 : v;
			img->pixels[p] = (uint8_t)(v * 255.0 + 0.5);
		}
		rc = loom_image_write(path, img, diag);
		loom_image_free(img);
		return rc;
	}
}

int cmd_preview(int argc, char **argv)
{
	const char *prog = "loom preview";
	const char *path = NULL, *out = NULL, *db_opt = NULL, *hmap_path = NULL;
	int quiet = 0, json = 0, has_z, rc;
	double budget_mb = 64, exposure = 0, thr = 0.2;
	uint32_t width = 0, height = 0, threads = 0, W, H;
	struct box box = {{0, 0, 0}, {0, 0, 0}, 0};
	int64_t *lo = box.lo, *hi = box.hi;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	loom_preview_stats st;
	loom_preview_maps maps;
	loom_fabric_db_identity id;
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	cli_progress pr;
	float *rgb = NULL, *hm = NULL;
	loom_diag diag;
	double t0;
	opt_entry opts[] = {
		OPT_CALLBACK(0, "region", &box, "BOX", opt_region, "voxels, half-open: x across "
		             "the ends, y along the warps (integers within +-2^46, the preview's "
		             "limit; the bolt is unbounded); "
		             "default one design repeat.  A z range restricts the columns."),
		OPT_U32(0, "width", &width, "PX", 1, LOOM_PREVIEW_MAX_SIDE, "output width, "
		        "%r (default: the region's width, at most 1024)"),
		OPT_U32(0, "height", &height, "PX", 1, LOOM_PREVIEW_MAX_SIDE, "output height, "
		        "%r (default: keep the region's aspect)"),
		OPT_BUDGET(&budget_mb, "texture cache budget in MiB (default 64)"),
		OPT_DB(&db_opt, "exemplar database (default: the one the fabric names)"),
		OPT_THREADS(&threads, 256, "worker threads (default: all CPUs)"),
		OPT_DOUBLE(0, "threshold", &thr, "D", "(]", 0, 1, "a density", "density at "
		           "which a voxel counts as surface, in %r (default 0.2)"),
		OPT_DOUBLE(0, "exposure", &exposure, "STOPS", "[]", -64, 64, "stops",
		           "PNG only: scale by 2^STOPS before the sRGB curve (0)"),
		OPT_STRING(0, "height-map", &hmap_path, "FILE", "also write the surface height: "
		           ".exr (float channel 'height', voxels) or .png (grey, 0 = z0 .. 255 = "
		           "top)"),
		OPT_OUTPUT(&out, "OUT", ".png (8-bit sRGB) or .exr (linear float RGB, ZIP)"),
		OPT_JSON(&json, "print figures as JSON on stdout"),
		OPT_QUIET(&quiet, "no progress or summary"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage, .about = about, .opts = opts,
	              .pos_name = "FABRIC", .pos_min = 1, .pos_max = 1, .pos = &path};

	opts_parse(&c, argc, argv);
	has_z = box.has_z;
	if (!out)
		opts_usage(&c, "missing -o OUT.png|OUT.exr");
	if (!cli_ends_with(out, ".png") && !cli_ends_with(out, ".exr"))
		opts_usage(&c, "output '%s' must end in .png or .exr", out);
	if (hmap_path && !cli_ends_with(hmap_path, ".png") && !cli_ends_with(hmap_path, ".exr"))
		opts_usage(&c, "height map '%s' must end in .png or .exr", hmap_path);
	cli_diag_init(&diag, &quiet);

	if (db_opt && loom_db_open(db_opt, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (loom_fabric_open(path, db, 0, &f, &diag) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	loom_fabric_get_db_identity(f, &id);
	if (!opt_given(&c, &box)) {
		uint64_t size[3];
		loom_fabric_repeat_voxels(f, size);
		hi[0] = (int64_t)size[0];
		hi[1] = (int64_t)size[1];
	}
	if (!width)
		width = hi[0] - lo[0] < 1024 ? (uint32_t)(hi[0] - lo[0]) : 1024;
	to.budget_bytes = (size_t)(budget_mb * 1048576.0);
	to.max_threads = threads ? threads : 16;
	if (loom_texture_open(f, db, &to, &t, &diag) != LOOM_OK) {
		loom_fabric_free(f);
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	memcpy(po.lo, box.lo, sizeof box.lo);
	memcpy(po.hi, box.hi, sizeof box.hi);
	po.width = width;
	po.height = height;
	po.threads = threads;
	po.threshold = (float)thr;
	rc = loom_preview_size(&po, &W, &H);
	if (rc != LOOM_OK) {
		cli_error(prog, "cannot make a %ux%u preview of that region: %s", width,
		          height, loom_strerror(rc));
		goto fail;
	}
	rgb = malloc((size_t)W * H * 3 * sizeof *rgb);
	hm = malloc((size_t)W * H * sizeof *hm);
	if (!rgb || !hm) {
		cli_error(prog, "out of memory for a %ux%u preview", W, H);
		goto fail;
	}
	memset(&maps, 0, sizeof maps);
	maps.height = hm;
	cli_progress_begin(&pr, prog, "pixels", (uint64_t)W * H, quiet);
	po.progress = progress_cb;
	po.progress_user = &pr;
	t0 = cli_now();
	rc = loom_preview(t, f, &po, rgb, &maps, &st, &diag);
	cli_progress_end(&pr);
	if (rc != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto fail;
	}
	if (cli_write_rgb(out, rgb, W, H, exposure, &diag) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto fail;
	}
	if (hmap_path) {
		int64_t z0 = has_z && lo[2] > 0 ? lo[2] : 0;
		int64_t z1 = has_z && hi[2] < (int64_t)id.block[2] ? hi[2] : (int64_t)id.block[2];
		if (z1 <= z0)
			z1 = z0 + 1;
		if (write_height(hmap_path, hm, W, H, z0, z1, &diag) != LOOM_OK) {
			cli_error(prog, "%s", diag.message);
			goto fail;
		}
	}
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "output", out);
		jw_uint(&w, "width", W);
		jw_uint(&w, "height", H);
		jw_arr(&w, "region");
		for (int k = 0; k < 3; k++)
			jw_int(&w, NULL, lo[k]);
		for (int k = 0; k < 3; k++)
			jw_int(&w, NULL, k == 2 && !has_z ? (long long)id.block[2] : hi[k]);
		jw_close(&w);
		jw_uint(&w, "columns", st.columns);
		jw_uint(&w, "region_reads", st.region_reads);
		jw_uint(&w, "empty_pixels", st.empty);
		jw_num(&w, "seconds", st.seconds);
		jw_num(&w, "seconds_total", cli_now() - t0);
		jw_end(&w);
	} else if (!quiet) {
		fprintf(stderr, "loom preview: %s: %ux%u pixels of %lld x %lld voxel columns "
		        "in %.2f s (%llu columns read)\n", out, W, H,
		        (long long)(hi[0] - lo[0]), (long long)(hi[1] - lo[1]), st.seconds,
		        (unsigned long long)st.columns);
	}
	free(rgb);
	free(hm);
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	return 0;
fail:
	free(rgb);
	free(hm);
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	return EXIT_BAD_INPUT;
}
