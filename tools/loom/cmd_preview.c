/*
 * tools/loom/cmd_preview.c - `loom preview FABRIC`: a shaded orthographic
 * top view of a fabric (loom_preview, docs/preview.md) as PNG (8-bit sRGB)
 * or EXR (linear float RGB), optionally with its height map.
 */
#include "cli.h"
#include "commands.h"
#include "paintfile.h"
#include "opts.h"
#include "picture.h"
#include "progress.h"

#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"loom preview FABRIC [--region X0,Y0:X1,Y1 | X0,Y0,Z0:X1,Y1,Z1]\n"
	"             [--width PX] [--height PX] [--budget MB] [--db DB]\n"
	"             [--threads N] [--threshold D] [--exposure STOPS]\n"
	"             [--filter auto|exact|blocks] [--scale-bar]\n"
	"             [--height-map FILE] [--json] [--quiet] -o OUT.png|OUT.exr\n";

static const char about[] =
	"Draw the fabric from straight above (orthographic), pick 1 at the top and\n"
	"end 1 at the left as in the drawdown: per pixel the mean of the voxel\n"
	"columns under it (an area average, so a whole repeat shows its motif at\n"
	"any width), each shaded from its top surface and fibre direction with one\n"
	"light and coloured by its yarn (docs/preview.md).  Streamed through the\n"
	"virtual texture in bounded memory and written band by band; a 4096-pixel\n"
	"preview of a whole large fabric takes seconds.  FABRIC may be a paint\n"
	"file (loom paint): its painted regions are shown.\n";

static const opt_choice filter_names[] = {
	{"auto", LOOM_PREVIEW_AUTO}, {"exact", LOOM_PREVIEW_EXACT},
	{"blocks", LOOM_PREVIEW_BLOCKS}, {NULL, 0}};

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

int cmd_preview(int argc, char **argv)
{
	const char *prog = "loom preview";
	const char *path = NULL, *out = NULL, *db_opt = NULL, *hmap_path = NULL;
	int quiet = 0, json = 0, has_z, rc, filter = LOOM_PREVIEW_AUTO, bar = 0;
	double budget_mb = 64, exposure = 0, thr = 0.2, mm_w, mm_h, vox_mm;
	uint32_t width = 0, height = 0, threads = 0, W, H;
	struct box box = {{0, 0, 0}, {0, 0, 0}, 0};
	int64_t *lo = box.lo, *hi = box.hi;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	loom_preview_stats st;
	loom_fabric_db_identity id;
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_paint *paint = NULL;
	loom_texture *t = NULL;
	cli_progress pr;
	pic_out pic;
	loom_diag diag;
	size_t budget, own;
	double t0;
	opt_entry opts[] = {
		OPT_CALLBACK(0, "region", &box, "BOX", opt_region, "voxels, half-open: x across "
		             "the ends, y along the warps (integers within +-2^46, the preview's "
		             "limit; the bolt is unbounded); "
		             "default one design repeat.  A z range restricts the columns."),
		OPT_U32(0, "width", &width, "PX", 1, LOOM_PREVIEW_MAX_SIDE, "output width, "
		        "%r (default: the region's width, at most 1024)"),
		OPT_U32(0, "height", &height, "PX", 1, LOOM_PREVIEW_MAX_SIDE, "output height, "
		        "%r (default: keep the region's aspect, which is the cloth's: voxels "
		        "are cubes)"),
		OPT_BUDGET(&budget_mb, "memory budget in MiB (default 64): the texture cache "
		           "and, a quarter of it up to 16 MiB, the preview's own buffers"),
		OPT_DB(&db_opt, "exemplar database (default: the one the fabric names)"),
		OPT_THREADS(&threads, 256, "worker threads (default: all CPUs)"),
		OPT_DOUBLE(0, "threshold", &thr, "D", "(]", 0, 1, "a density", "density at "
		           "which a voxel counts as surface, in %r (default 0.2)"),
		OPT_DOUBLE(0, "exposure", &exposure, "STOPS", "[]", -64, 64, "stops",
		           "PNG only: scale by 2^STOPS before the sRGB curve (0)"),
		OPT_ENUM(0, "filter", &filter, "F", filter_names, "auto (default: exact up to 16 "
		         "voxel columns per pixel, else blocks), exact (read every column) or "
		         "blocks (per-source-block tables; docs/preview.md)"),
		OPT_FLAG(0, "scale-bar", &bar, "draw a scale bar (a round length in mm or cm) "
		         "at the bottom left"),
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
	cli_check_output(prog, out);
	if (hmap_path)
		cli_check_output(prog, hmap_path);
	cli_diag_init(&diag, &quiet);

	if (db_opt && loom_db_open(db_opt, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (cli_open_painted(path, db, &f, &paint, &diag) != LOOM_OK) {
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
	budget = (size_t)(budget_mb * 1048576.0);
	own = budget / 4 < ((size_t)16 << 20) ? budget / 4 : (size_t)16 << 20;
	to.budget_bytes = budget - own;
	/* the texture's per-thread state for the threads the preview runs,
	   no more: the budget is not spent on threads a small host lacks */
	if (!threads)
		threads = cli_cpus();
	to.max_threads = threads;
	if (loom_texture_open(f, db, &to, &t, &diag) != LOOM_OK) {
		loom_paint_free(paint);
		loom_fabric_free(f);
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	/* painted weaves are in the fabric; the other regions apply as the
	   preview reads */
	if (paint && loom_paint_bind(paint, t, f) != LOOM_OK) {
		cli_error(prog, "out of memory binding the paint layer");
		goto fail;
	}
	po.paint = paint;
	memcpy(po.lo, box.lo, sizeof box.lo);
	memcpy(po.hi, box.hi, sizeof box.hi);
	po.width = width;
	po.height = height;
	po.threads = threads;
	po.threshold = (float)thr;
	po.filter = filter;
	po.memory_bytes = own;
	rc = loom_preview_size(&po, &W, &H);
	if (rc != LOOM_OK) {
		cli_error(prog, "cannot make a %ux%u preview of that region: %s", width,
		          height, loom_strerror(rc));
		goto fail;
	}
	vox_mm = id.voxel_size_um * 1e-3;
	mm_w = (double)(hi[0] - lo[0]) * vox_mm;
	mm_h = (double)(hi[1] - lo[1]) * vox_mm;
	memset(&pic, 0, sizeof pic);
	pic.path = out;
	pic.height_path = hmap_path;
	pic.exposure = exposure;
	pic.scale_bar = bar;
	pic.mm_per_px = mm_w / W;
	pic.z0 = has_z && lo[2] > 0 ? lo[2] : 0;
	pic.z1 = has_z && hi[2] < (int64_t)id.block[2] ? hi[2] : (int64_t)id.block[2];
	if (pic.z1 <= pic.z0)
		pic.z1 = pic.z0 + 1;
	if (pic_open(&pic, W, H, &diag) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto fail;
	}
	cli_progress_begin(&pr, prog, "pixels", (uint64_t)W * H, quiet);
	po.progress = progress_cb;
	po.progress_user = &pr;
	t0 = cli_now();
	rc = loom_preview_stream(t, f, &po, pic_band, &pic, &st, &diag);
	cli_progress_end(&pr);
	if (rc != LOOM_OK) {
		pic_abort(&pic);
		cli_error(prog, "%s", diag.message);
		goto fail;
	}
	if (pic_finish(&pic) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto fail;
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
		jw_arr(&w, "size_mm");
		jw_num(&w, NULL, mm_w);
		jw_num(&w, NULL, mm_h);
		jw_close(&w);
		jw_num(&w, "um_per_pixel", 1000.0 * mm_w / W);
		if (pic.bar_mm > 0)
			jw_num(&w, "scale_bar_mm", pic.bar_mm);
		jw_str(&w, "filter", st.filter == LOOM_PREVIEW_EXACT ? "exact" : "blocks");
		jw_uint(&w, "columns", st.columns);
		jw_uint(&w, "region_reads", st.region_reads);
		jw_uint(&w, "empty_pixels", st.empty);
		jw_uint(&w, "blocks", st.blocks);
		jw_uint(&w, "texel", st.texel);
		jw_uint(&w, "preview_bytes", st.memory_bytes);
		jw_num(&w, "seconds", st.seconds);
		jw_num(&w, "seconds_total", cli_now() - t0);
		jw_end(&w);
	} else if (!quiet) {
		fprintf(stderr, "loom preview: %s: %ux%u pixels, %.1f x %.1f mm of cloth "
		        "(%.1f um per pixel), %s filter, in %.2f s (%llu columns read)\n",
		        out, W, H, mm_w, mm_h, 1000.0 * mm_w / W,
		        st.filter == LOOM_PREVIEW_EXACT ? "exact" : "blocks", st.seconds,
		        (unsigned long long)st.columns);
	}
	loom_texture_close(t);
	loom_paint_free(paint);
	loom_fabric_free(f);
	loom_db_close(db);
	return 0;
fail:
	loom_texture_close(t);
	loom_paint_free(paint);
	loom_fabric_free(f);
	loom_db_close(db);
	return EXIT_BAD_INPUT;
}
