/*
 * tools/loom/cmd_demo.c - `loom demo`: the main job on the built-in data.
 *
 * The demo is a list of stages run in order over one shared context; each
 * stage reads what earlier ones left in it:
 *
 *   1. designs  elementary weaves from the generators, a Jacquard design
 *               built in memory from a generated two-colour picture
 *               (paper 5.2, Fig. 13c: 1/7 twill and 7/1 satin), and every
 *               *.wif draft in the data directory;
 *   2. write    each design's weave as DIR/NAME.png;
 *   3. table    a short info table on stdout;
 *   4. cloth    the demo cloth: a drawn motif (rings and a diamond) mapped
 *               to 1/4 and 4/1 satin, red warp and gold weft, so the motif
 *               shows gold on red; synthesized over the default exemplar
 *               database (loom_fabric_synthesize) into DIR/cloth.loomf;
 *   5. preview  a shaded top view of one repeat (loom_preview) as
 *               DIR/cloth-preview.png and .exr;
 *   6. render   a small path-traced picture of the cloth at an angle
 *               (loom_render), DIR/cloth-render.png;
 *   7. export   one 64 x 64 x b3 tile in each export format (vol, nrrd,
 *               exr) through `loom export`, in DIR/export-FORMAT/;
 *   8. files    a table of every file written, with its size.
 *
 * Stages 4-7 need the exemplar database (--db, $LOOM_DB, or default.ldb in
 * the data directory); without one they are skipped with a warning.  A
 * stage that fails for one item reports it, marks the run failed (exit 1)
 * and lets the others go on.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "progress.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <limits.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define DEMO_MAX_ITEMS 64
#define DEMO_MAX_FILES 128

typedef struct demo_item {
	char name[64];        /* file stem, e.g. "twill-2-3" */
	char source[96];      /* where it came from, for the table */
	loom_design *design;  /* owned */
} demo_item;

typedef struct demo_file {
	char path[PATH_MAX];
	char what[64];
	long long bytes;      /* -1: the file's size at print time */
} demo_file;

typedef struct demo_ctx {
	const char *dir;      /* output directory */
	const char *db_opt;   /* --db */
	int quiet;
	double t0;            /* start, seconds */
	loom_db *db;          /* stages 4-7 */
	loom_fabric *fabric;
	char fabric_path[PATH_MAX];
	demo_file files[DEMO_MAX_FILES];
	int n_files;
	demo_item items[DEMO_MAX_ITEMS];
	int n_items;
	int failed;           /* some item failed in some stage */
} demo_ctx;

typedef void (*demo_stage_fn)(demo_ctx *ctx);

static const char about_demo[] =
	"Run the main job on the built-in default data (docs/preview.md):\n"
	" - designs from the weave generators (2/3 twill, 1/4 satin, herringbone,\n"
	"   ...), a Jacquard design from a generated two-colour picture, and one\n"
	"   from every sample WIF draft in the data directory; each weave as\n"
	"   DIR/NAME.png and a table of their size, repeat, floats and yarn types;\n"
	" - the demo cloth: a drawn motif woven in 1/4 and 4/1 satin with a red\n"
	"   warp and a gold weft, synthesized over the default exemplar database\n"
	"   (DIR/cloth.loomf), a preview of it (DIR/cloth-preview.png and .exr), a\n"
	"   small path-traced render (DIR/cloth-render.png), and one tile exported\n"
	"   in each format (DIR/export-vol, export-nrrd, export-exr);\n"
	" - a table of the files written and their sizes.\n";

static const char footer_demo[] =
	"The data directory is $LOOM_DATA, else share/loom next to the loom\n"
	"binary, else ../share/loom.\n";

/* Progress on stderr when it is a terminal (never with --quiet). */
static void note(const demo_ctx *ctx, const char *fmt, const char *arg)
{
	if (ctx->quiet || !isatty(2))
		return;
	fputs("loom demo: ", stderr);
	fprintf(stderr, fmt, arg);
	fputc('\n', stderr);
}

static demo_item *add_item(demo_ctx *ctx, const char *name, const char *source)
{
	demo_item *it;

	if (ctx->n_items == DEMO_MAX_ITEMS) {
		cli_error("loom demo", "warning: more than %d designs; skipping %s",
		          DEMO_MAX_ITEMS, name);
		return NULL;
	}
	it = &ctx->items[ctx->n_items++];
	memset(it, 0, sizeof *it);
	snprintf(it->name, sizeof it->name, "%s", name);
	snprintf(it->source, sizeof it->source, "%s", source);
	return it;
}

/* ---- stage 1: designs ------------------------------------------------------ */

static void add_generated(demo_ctx *ctx, const char *name, const char *weave,
                          uint32_t rows, uint32_t cols)
{
	loom_weave_params p;
	loom_diag d = {0};
	demo_item *it = add_item(ctx, name, weave);

	if (!it)
		return;
	if (loom_weave_parse(weave, &p, &d) ||
	    loom_design_make(&p, rows, cols, &it->design, &d)) {
		cli_error("loom demo", "%s: %s", name, d.message);
		ctx->failed = 1;
	}
}

/* A two-colour picture: a gold diamond with a gold border on red. */
static loom_image *jacquard_picture(uint32_t size)
{
	loom_image *img = NULL;
	int c = (int)size / 2;

	if (loom_image_new(size, size, 3, &img))
		return NULL;
	for (uint32_t y = 0; y < size; y++)
		for (uint32_t x = 0; x < size; x++) {
			int r = abs((int)x - c) + abs((int)y - c);
			int edge = x < 6 || y < 6 || x >= size - 6 || y >= size - 6;
			int gold = r < c / 2 || (r >= c * 3 / 4 && r < c * 7 / 8) || edge;
			uint8_t *px = img->pixels + 3 * ((size_t)y * size + x);
			px[0] = gold ? 0xd4 : 0xa0;
			px[1] = gold ? 0xa0 : 0x10;
			px[2] = gold ? 0x17 : 0x10;
		}
	return img;
}

static void add_jacquard(demo_ctx *ctx)
{
	static const char map[] =
		"# loom demo: paper Fig. 13c, a 1/7 twill and a 7/1 satin\n"
		"yarn red  #a01010 alignment=0.3\n"
		"yarn gold #d4a017 alignment=0.15\n"
		"colour #d4a017 twill:1/7 warp=red weft=gold   # weft-faced: gold\n"
		"colour #a01010 satin:7/1 warp=red weft=gold   # warp-faced: red\n";
	loom_image *img = jacquard_picture(96);
	loom_diag d = {0};
	demo_item *it = add_item(ctx, "jacquard", "picture + map (twill 1/7, satin 7/1)");
	char path[1024];

	if (!it || !img) {
		ctx->failed |= it != NULL;
		loom_image_free(img);
		return;
	}
	d.warn = cli_warn_sink;
	d.user = &ctx->quiet;
	if (loom_design_from_image(img, map, sizeof map - 1, "demo.map", &it->design, &d)) {
		cli_error("loom demo", "jacquard: %s", d.message);
		ctx->failed = 1;
	}
	snprintf(path, sizeof path, "%s/jacquard-picture.png", ctx->dir);
	if (loom_image_write(path, img, &d)) {
		cli_error("loom demo", "%s", d.message);
		ctx->failed = 1;
	}
	loom_image_free(img);
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Names of *.wif files in dir, sorted (deterministic order). */
static int list_wifs(const char *dir, char ***names)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	int n = 0;

	*names = NULL;
	if (!d)
		return 0;
	while ((e = readdir(d))) {
		size_t len = strlen(e->d_name);
		char **grown;
		if (len < 5 || strcasecmp(e->d_name + len - 4, ".wif") != 0)
			continue;
		grown = realloc(*names, (size_t)(n + 1) * sizeof **names);
		if (!grown)
			break;
		*names = grown;
		(*names)[n++] = strdup(e->d_name);
	}
	closedir(d);
	if (n)
		qsort(*names, (size_t)n, sizeof **names, cmp_str);
	return n;
}

static void add_wif(demo_ctx *ctx, const char *dir, const char *file)
{
	char path[1024], stem[64];
	loom_diag d;
	demo_item *it;

	snprintf(stem, sizeof stem, "%.*s", (int)(strlen(file) - 4), file);
	snprintf(path, sizeof path, "%s/%s", dir, file);
	if (!(it = add_item(ctx, stem, file)))
		return;
	cli_diag_init(&d, &ctx->quiet);
	if (loom_design_read(path, &it->design, &d)) {
		cli_error("loom demo", "%s", d.message);
		ctx->failed = 1;
	}
}

static void add_wifs(demo_ctx *ctx)
{
	const char *dir = cli_data_dir();
	char **names;
	int n;

	if (!dir) {
		cli_error("loom demo", "warning: no data directory found (set "
		          "LOOM_DATA); skipping the sample drafts");
		return;
	}
	n = list_wifs(dir, &names);
	if (n == 0)
		note(ctx, "no *.wif drafts in %s", dir);
	for (int k = 0; k < n; k++) {
		if (names[k])
			add_wif(ctx, dir, names[k]);
		free(names[k]);
	}
	free(names);
}

static void stage_designs(demo_ctx *ctx)
{
	add_generated(ctx, "twill-2-3", "twill:2/3", 40, 40);
	add_generated(ctx, "twill-2-2-s", "twill:2/2:s", 40, 40);
	add_generated(ctx, "satin-1-4", "satin:1/4", 40, 40);
	add_generated(ctx, "satin-7-1", "satin:7/1:move=3", 40, 40);
	add_generated(ctx, "basket-2", "basket:2/2", 40, 40);
	add_generated(ctx, "herringbone-2-2", "herringbone:2/2:period=4", 40, 48);
	add_generated(ctx, "broken-twill-2-2", "broken-twill:2/2", 40, 40);
	add_generated(ctx, "wavy-twill-2-2", "wavy-twill:2/2:period=5", 40, 48);
	add_jacquard(ctx);
	add_wifs(ctx);
}

/* ---- stage 2: write -------------------------------------------------------- */

static void stage_write(demo_ctx *ctx)
{
	for (int k = 0; k < ctx->n_items; k++) {
		const demo_item *it = &ctx->items[k];
		char path[1024];
		loom_diag d = {0};
		if (!it->design)
			continue;
		snprintf(path, sizeof path, "%s/%s.png", ctx->dir, it->name);
		if (loom_weave_write(path, it->design, &d)) {
			cli_error("loom demo", "%s", d.message);
			ctx->failed = 1;
		}
	}
}

/* ---- stage 3: table --------------------------------------------------------- */

static void stage_table(demo_ctx *ctx)
{
	if (ctx->quiet) /* --quiet: nothing on success */
		return;
	printf("%-20s %-11s %-9s %-11s %-5s %s\n", "name", "size", "repeat",
	       "max floats", "types", "source");
	for (int k = 0; k < ctx->n_items; k++) {
		demo_item *it = &ctx->items[k];
		loom_design_stats st;
		char size[32], rep[32], fl[32];
		if (!it->design) {
			printf("%-20s (failed)\n", it->name);
			continue;
		}
		if (loom_design_analyze(it->design, &st)) {
			printf("%-20s (cannot analyse)\n", it->name);
			ctx->failed = 1;
			continue;
		}
		snprintf(size, sizeof size, "%ux%u", it->design->rows, it->design->cols);
		snprintf(rep, sizeof rep, "%ux%u", st.repeat_rows, st.repeat_cols);
		snprintf(fl, sizeof fl, "%u/%u", st.max_warp_float, st.max_weft_float);
		printf("%-20s %-11s %-9s %-11s %-5u %s\n", it->name, size, rep, fl,
		       st.types_used, it->source);
	}
	printf("(size and repeat: picks x ends; max floats: warp/weft)\n");
	if (!ctx->quiet)
		fprintf(stderr, "loom demo: wrote %d weave images to %s/\n",
		        ctx->n_items, ctx->dir);
}

/* ---- stages 4-8: the demo cloth ------------------------------------------------ */

/* Remember a written file for the final table. */
static void add_file(demo_ctx *ctx, const char *path, const char *what)
{
	demo_file *df;
	size_t n;

	if (ctx->n_files == DEMO_MAX_FILES)
		return;
	df = &ctx->files[ctx->n_files++];
	n = strlen(path);

	if (n >= sizeof df->path)
		n = sizeof df->path - 1;
	memcpy(df->path, path, n);
	df->path[n] = 0;
	snprintf(df->what, sizeof df->what, "%s", what);
	df->bytes = -1;
}

static void stage_fail(demo_ctx *ctx, const char *what, const char *msg)
{
	cli_error("loom demo", "%s: %s", what, msg);
	ctx->failed = 1;
}

/* The demo cloth's picture, `rows` picks by `cols` ends (crossings are
   b1 x b2 = 24 x 16 voxels, so rows = 1.5 cols looks square): gold rings
   and a gold diamond on red, with a gold border. */
static loom_image *cloth_picture(uint32_t rows, uint32_t cols)
{
	loom_image *img = NULL;

	if (loom_image_new(cols, rows, 3, &img))
		return NULL;
	for (uint32_t y = 0; y < rows; y++)
		for (uint32_t x = 0; x < cols; x++) {
			/* physical coordinates in units of a crossing's width */
			double u = ((double)x + 0.5) / cols - 0.5;
			double v = (((double)y + 0.5) / rows - 0.5) * (2.0 / 3.0) * rows / cols;
			double r = sqrt(u * u + v * v);
			double dm = fabs(u) + fabs(v);
			int border = x < 3 || y < 4 || x >= cols - 3 || y >= rows - 4;
			int gold = border || (r > 0.36 && r < 0.44) || dm < 0.2 ||
			           (r > 0.27 && r < 0.30);
			uint8_t *px = img->pixels + 3 * ((size_t)y * cols + x);
			px[0] = gold ? 0xd4 : 0xa0;
			px[1] = gold ? 0xa0 : 0x10;
			px[2] = gold ? 0x17 : 0x10;
		}
	return img;
}

static void stage_cloth(demo_ctx *ctx)
{
	static const char map[] =
		"# loom demo cloth: weft-faced 1/4 satin shows the gold weft,\n"
		"# warp-faced 4/1 satin the red warp\n"
		"yarn red  #b01818 alignment=0.3\n"
		"yarn gold #e0b030 alignment=0.15\n"
		"colour #d4a017 satin:1/4 warp=red weft=gold\n"
		"colour #a01010 satin:4/1 warp=red weft=gold\n";
	const char *db_path = cli_db_path(ctx->db_opt);
	char abs_db[PATH_MAX], path[PATH_MAX];
	loom_image *img;
	loom_design *d = NULL;
	loom_diag diag;
	uint64_t bytes = 0;

	if (!db_path) {
		if (!ctx->quiet)
			cli_error("loom demo", "warning: no exemplar database (give --db, set "
			          "LOOM_DB, or build default.ldb with make); skipping the "
			          "cloth, preview, render and export stages");
		return;
	}
	cli_diag_init(&diag, &ctx->quiet);
	if (loom_db_open(db_path, &ctx->db, &diag) != LOOM_OK) {
		stage_fail(ctx, "cloth", diag.message);
		return;
	}
	if (!realpath(db_path, abs_db))
		snprintf(abs_db, sizeof abs_db, "%s", db_path);
	img = cloth_picture(144, 96);
	if (!img) {
		stage_fail(ctx, "cloth", "out of memory");
		return;
	}
	snprintf(path, sizeof path, "%s/cloth-picture.png", ctx->dir);
	if (loom_image_write(path, img, &diag) != LOOM_OK)
		stage_fail(ctx, "cloth", diag.message);
	else
		add_file(ctx, path, "the motif (posterized picture)");
	if (loom_design_from_image(img, map, sizeof map - 1, "cloth.map", &d, &diag)) {
		loom_image_free(img);
		stage_fail(ctx, "cloth", diag.message);
		return;
	}
	loom_image_free(img);
	snprintf(path, sizeof path, "%s/cloth-weave.png", ctx->dir);
	if (loom_weave_write(path, d, &diag) != LOOM_OK)
		stage_fail(ctx, "cloth", diag.message);
	else
		add_file(ctx, path, "its weave (black = warp over)");
	if (loom_fabric_synthesize(d, ctx->db, abs_db, NULL, &ctx->fabric, &diag) != LOOM_OK) {
		loom_design_free(d);
		stage_fail(ctx, "cloth synthesis", diag.message);
		return;
	}
	loom_design_free(d);
	snprintf(ctx->fabric_path, sizeof ctx->fabric_path, "%s/cloth.loomf", ctx->dir);
	if (loom_fabric_save(ctx->fabric, ctx->fabric_path, &bytes, &diag) != LOOM_OK) {
		stage_fail(ctx, "cloth", diag.message);
		ctx->fabric_path[0] = 0;
		return;
	}
	add_file(ctx, ctx->fabric_path, "fabric (design + synthesis)");
}

static loom_texture *open_texture(demo_ctx *ctx, size_t budget, const char *what)
{
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag diag;

	cli_diag_init(&diag, &ctx->quiet);
	to.budget_bytes = budget;
	if (loom_texture_open(ctx->fabric, ctx->db, &to, &t, &diag) != LOOM_OK) {
		stage_fail(ctx, what, diag.message);
		return NULL;
	}
	return t;
}

static void stage_preview(demo_ctx *ctx)
{
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	uint64_t rep[3];
	uint32_t W, H;
	float *rgb;
	loom_texture *t;
	loom_diag diag;
	char path[PATH_MAX];

	if (!ctx->fabric)
		return;
	if (!(t = open_texture(ctx, (size_t)64 << 20, "preview")))
		return;
	cli_diag_init(&diag, &ctx->quiet);
	loom_fabric_repeat_voxels(ctx->fabric, rep);
	po.hi[0] = (int64_t)rep[0];
	po.hi[1] = (int64_t)rep[1];
	po.width = rep[0] < 1024 ? (uint32_t)rep[0] : 1024;
	if (loom_preview_size(&po, &W, &H) != LOOM_OK ||
	    !(rgb = malloc((size_t)W * H * 3 * sizeof *rgb))) {
		stage_fail(ctx, "preview", "cannot size or allocate the preview");
		loom_texture_close(t);
		return;
	}
	if (loom_preview(t, ctx->fabric, &po, rgb, NULL, NULL, &diag) != LOOM_OK) {
		stage_fail(ctx, "preview", diag.message);
	} else {
		snprintf(path, sizeof path, "%s/cloth-preview.png", ctx->dir);
		if (cli_write_rgb(path, rgb, W, H, 0.0, &diag) != LOOM_OK)
			stage_fail(ctx, "preview", diag.message);
		else
			add_file(ctx, path, "preview from above, sRGB");
		snprintf(path, sizeof path, "%s/cloth-preview.exr", ctx->dir);
		if (cli_write_rgb(path, rgb, W, H, 0.0, &diag) != LOOM_OK)
			stage_fail(ctx, "preview", diag.message);
		else
			add_file(ctx, path, "the same, linear float RGB");
	}
	free(rgb);
	loom_texture_close(t);
}

static void stage_render(demo_ctx *ctx)
{
	loom_render_options ro = LOOM_RENDER_OPTIONS_INIT;
	loom_volume_source src;
	loom_texture *t;
	loom_diag diag;
	uint64_t rep[3];
	float *rgb;
	char path[PATH_MAX];
	double cx, cy, span, el = 0.5; /* radians above the cloth (about 29 degrees) */

	if (!ctx->fabric)
		return;
	if (!(t = open_texture(ctx, (size_t)128 << 20, "render")))
		return;
	cli_diag_init(&diag, &ctx->quiet);
	loom_texture_volume_source(t, ctx->fabric, LOOM_FILTER_NEAREST, &src);
	loom_fabric_repeat_voxels(ctx->fabric, rep);
	ro.width = 360;
	ro.height = 240;
	ro.spp = 6;
	ro.seed = 1;
	ro.density_scale = 2;
	ro.max_depth = 16;
	ro.light.dir[0] = -0.35;
	ro.light.dir[1] = -0.45;
	ro.light.dir[2] = 1.0;
	ro.light.rgb[0] = ro.light.rgb[1] = ro.light.rgb[2] = 2.6f;
	ro.env[0] = ro.env[1] = ro.env[2] = 0.18f;
	/* a pinhole camera looking along +y at the middle of the motif */
	cx = 0.5 * (double)rep[0];
	cy = 0.5 * (double)rep[1];
	span = 0.62 * (double)rep[0];
	ro.camera.kind = LOOM_CAMERA_PINHOLE;
	ro.camera.fov_y_deg = 30;
	ro.camera.target[0] = cx;
	ro.camera.target[1] = cy;
	ro.camera.target[2] = 0.5 * (double)src.nz;
	ro.camera.eye[0] = cx;
	ro.camera.eye[1] = cy - 2.2 * span * cos(el);
	ro.camera.eye[2] = 0.5 * (double)src.nz + 2.2 * span * sin(el);
	ro.camera.up[0] = 0;
	ro.camera.up[1] = 0;
	ro.camera.up[2] = 1;
	rgb = malloc((size_t)ro.width * ro.height * 3 * sizeof *rgb);
	if (!rgb) {
		stage_fail(ctx, "render", "out of memory");
	} else if (loom_render(&src, &ro, rgb, NULL, &diag) != LOOM_OK) {
		stage_fail(ctx, "render", diag.message);
	} else {
		snprintf(path, sizeof path, "%s/cloth-render.png", ctx->dir);
		if (cli_write_rgb(path, rgb, ro.width, ro.height, 0.0, &diag) != LOOM_OK)
			stage_fail(ctx, "render", diag.message);
		else
			add_file(ctx, path, "path-traced, 6 spp");
	}
	free(rgb);
	loom_texture_close(t);
}

/* Run `loom export` in a child process (it exits on errors). */
static int run_export(demo_ctx *ctx, char **argv, int argc)
{
	pid_t pid;
	int status = 0;

	fflush(stdout);
	fflush(stderr);
	pid = fork();
	if (pid < 0)
		return -1;
	if (pid == 0) {
		int rc = cmd_export(argc, argv);
		fflush(stdout);
		fflush(stderr);
		_exit(rc & 0xff);
	}
	(void)ctx;
	if (waitpid(pid, &status, 0) != pid)
		return -1;
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Count the regular files under dir (one level of subdirectories) and
   their bytes; add each to the table when add is set. */
static void add_dir_files(demo_ctx *ctx, const char *dir, const char *what, int depth,
                          int add, int *count, long long *bytes)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	char **names = NULL;
	int n = 0;

	if (!d)
		return;
	while ((e = readdir(d))) {
		char **grown;
		if (e->d_name[0] == '.')
			continue;
		grown = realloc(names, (size_t)(n + 1) * sizeof *names);
		if (!grown)
			break;
		names = grown;
		names[n++] = strdup(e->d_name);
	}
	closedir(d);
	if (n)
		qsort(names, (size_t)n, sizeof *names, cmp_str);
	for (int k = 0; k < n; k++) {
		char path[PATH_MAX];
		struct stat st;
		if (!names[k])
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, names[k]);
		if (stat(path, &st) == 0 && S_ISDIR(st.st_mode) && depth > 0) {
			add_dir_files(ctx, path, what, depth - 1, add, count, bytes);
		} else if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) {
			(*count)++;
			*bytes += (long long)st.st_size;
			if (add)
				add_file(ctx, path, what);
		}
		free(names[k]);
	}
	free(names);
}

static void stage_export(demo_ctx *ctx)
{
	static const char *const formats[] = {"vol", "nrrd", "exr"};
	char region[96], out[PATH_MAX];
	uint64_t rep[3];

	if (!ctx->fabric || !ctx->fabric_path[0])
		return;
	loom_fabric_repeat_voxels(ctx->fabric, rep);
	snprintf(region, sizeof region, "0,0,0:64,64,%llu", (unsigned long long)rep[2]);
	for (size_t k = 0; k < sizeof formats / sizeof formats[0]; k++) {
		char what[64];
		char *argv[12];
		int argc = 0, rc;
		snprintf(out, sizeof out, "%s/export-%s", ctx->dir, formats[k]);
		{
			/* the demo's own directory: a run over an earlier demo's (another
			   fabric, e.g. after a new default database) starts the export
			   over instead of resuming one that is not this export */
			char man[PATH_MAX + 16];
			snprintf(man, sizeof man, "%s/manifest.json", out);
			if (unlink(man) != 0 && errno != ENOENT)
				fprintf(stderr, "loom demo: warning: cannot remove %s: %s\n", man,
				        strerror(errno));
		}
		argv[argc++] = "export";
		argv[argc++] = ctx->fabric_path;
		argv[argc++] = "--region";
		argv[argc++] = region;
		argv[argc++] = "--format";
		argv[argc++] = (char *)formats[k];
		argv[argc++] = "-o";
		argv[argc++] = out;
		argv[argc++] = "--quiet";
		argv[argc] = NULL;
		rc = run_export(ctx, argv, argc);
		if (rc != 0) {
			char msg[160];
			snprintf(msg, sizeof msg, "loom export --format %s failed (status %d)",
			         formats[k], rc);
			stage_fail(ctx, "export", msg);
			continue;
		}
		snprintf(what, sizeof what, "64x64x%llu tile, %s", (unsigned long long)rep[2],
		         formats[k]);
		{
			int count = 0;
			long long bytes = 0;
			add_dir_files(ctx, out, what, 1, 0, &count, &bytes);
			if (count <= 6) {
				count = 0;
				add_dir_files(ctx, out, what, 1, 1, &count, &bytes);
			} else if (ctx->n_files < DEMO_MAX_FILES) {
				/* many files (EXR z-slices): one line for the directory */
				char dpath[PATH_MAX + 2];
				snprintf(dpath, sizeof dpath, "%s/", out);
				snprintf(what, sizeof what, "%d files: 64x64x%llu tile, %s z-slices",
				         count, (unsigned long long)rep[2], formats[k]);
				add_file(ctx, dpath, what);
				ctx->files[ctx->n_files - 1].bytes = bytes;
			}
		}
	}
}

static void stage_files(demo_ctx *ctx)
{
	uint64_t total = 0;

	if (ctx->n_files == 0 || ctx->quiet)
		return;
	printf("\n%-44s %10s  %s\n", "file", "bytes", "what");
	for (int k = 0; k < ctx->n_files; k++) {
		struct stat st;
		long long size = ctx->files[k].bytes;
		if (size < 0)
			size = stat(ctx->files[k].path, &st) == 0 ? (long long)st.st_size : -1;
		if (size >= 0)
			total += (uint64_t)size;
		printf("%-44s %10lld  %s\n", ctx->files[k].path, size, ctx->files[k].what);
	}
	printf("%d files, %llu bytes, in %.1f s\n", ctx->n_files, (unsigned long long)total,
	       cli_now() - ctx->t0);
}

static const struct {
	const char *name;
	demo_stage_fn fn;
} stages[] = {
	{"designs", stage_designs},
	{"write", stage_write},
	{"table", stage_table},
	{"cloth", stage_cloth},
	{"preview", stage_preview},
	{"render", stage_render},
	{"export", stage_export},
	{"files", stage_files},
};

/* ---- driver -------------------------------------------------------------------- */

static void make_dir(const char *dir)
{
	struct stat st;

	if (mkdir(dir, 0777) == 0)
		return;
	if (errno == EEXIST && stat(dir, &st) == 0 && S_ISDIR(st.st_mode))
		return;
	cli_fail("loom demo", "cannot create directory %s: %s", dir,
	         errno == EEXIST ? "a file of that name exists" : strerror(errno));
}

int cmd_demo(int argc, char **argv)
{
	demo_ctx *ctx = calloc(1, sizeof *ctx);
	int failed;

	if (!ctx)
		cli_fail("loom demo", "out of memory");
	ctx->dir = "loom-demo";
	{
		opt_entry opts[] = {
			OPT_OUTPUT(&ctx->dir, "DIR", "output directory (default ./loom-demo; "
			           "created)"),
			OPT_DB(&ctx->db_opt, "exemplar database (default: $LOOM_DB, then "
			       "default.ldb in the data directory)"),
			OPT_QUIET(&ctx->quiet, "nothing on success (no progress, warnings nor report)"),
			OPT_END()
		};
		opts_cmd c = {.prog = "loom demo", .usage = "loom demo [-o DIR] [--db DB] "
		              "[--quiet]", .about = about_demo, .footer = footer_demo,
		              .opts = opts};
		opts_parse(&c, argc, argv);
	}
	make_dir(ctx->dir);
	ctx->t0 = cli_now();
	for (size_t s = 0; s < sizeof stages / sizeof stages[0]; s++) {
		note(ctx, "stage %s", stages[s].name);
		stages[s].fn(ctx);
	}
	for (int k = 0; k < ctx->n_items; k++)
		loom_design_free(ctx->items[k].design);
	loom_fabric_free(ctx->fabric);
	loom_db_close(ctx->db);
	failed = ctx->failed;
	free(ctx);
	return failed ? EXIT_BAD_INPUT : 0;
}
