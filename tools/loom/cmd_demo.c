/*
 * tools/loom/cmd_demo.c - `loom demo`: the main job on the built-in data.
 *
 * The demo is a list of stages run in order over one shared context; each
 * stage reads what earlier ones left in it.  Today:
 *
 *   1. designs  elementary weaves from the generators, a Jacquard design
 *               built in memory from a generated two-colour picture
 *               (paper 5.2, Fig. 13c: 1/7 twill and 7/1 satin), and every
 *               *.wif draft in the data directory;
 *   2. write    each design's weave as DIR/NAME.png;
 *   3. table    a short info table on stdout.
 *
 * Later issues add stages (exemplar database, synthesis, export, render)
 * by appending to stages[]; a stage that fails for one item reports it,
 * marks the run failed (exit 1) and lets the others go on.
 */
#include "cli.h"
#include "commands.h"

#include <dirent.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#define DEMO_MAX_ITEMS 64

typedef struct demo_item {
	char name[64];        /* file stem, e.g. "twill-2-3" */
	char source[96];      /* where it came from, for the table */
	loom_design *design;  /* owned */
} demo_item;

typedef struct demo_ctx {
	const char *dir;      /* output directory */
	int quiet;
	demo_item items[DEMO_MAX_ITEMS];
	int n_items;
	int failed;           /* some item failed in some stage */
} demo_ctx;

typedef void (*demo_stage_fn)(demo_ctx *ctx);

static const char help_demo[] =
	"usage: loom demo [-o DIR] [--quiet]\n"
	"\n"
	"Run the main job on the built-in default data.  For now: make a few\n"
	"designs from the weave generators (2/3 twill, 1/4 satin, herringbone,\n"
	"...), a Jacquard design from a generated two-colour picture, and one\n"
	"from every sample WIF draft in the data directory; write each weave as\n"
	"DIR/NAME.png and print a table of their size, repeat, longest floats\n"
	"and yarn types.\n"
	"\n"
	"options:\n"
	"  -o, --output DIR   output directory (default ./loom-demo; created)\n"
	"  -q, --quiet        no progress or warnings on stderr\n"
	"  -h, --help         this text\n"
	"\n"
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

static const struct {
	const char *name;
	demo_stage_fn fn;
} stages[] = {
	{"designs", stage_designs},
	{"write", stage_write},
	{"table", stage_table},
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
	cli_args a;
	demo_ctx *ctx = calloc(1, sizeof *ctx);
	int failed;

	if (!ctx)
		cli_fail("loom demo", "out of memory");
	ctx->dir = "loom-demo";
	cli_init(&a, argc, argv, "loom demo", help_demo);
	while (cli_more(&a)) {
		if (cli_value(&a, "-o", &ctx->dir) || cli_value(&a, "--output", &ctx->dir))
			continue;
		if (cli_flag(&a, "-q") || cli_flag(&a, "--quiet")) {
			ctx->quiet = 1;
			continue;
		}
		cli_unknown(&a);
	}
	make_dir(ctx->dir);
	for (size_t s = 0; s < sizeof stages / sizeof stages[0]; s++) {
		note(ctx, "stage %s", stages[s].name);
		stages[s].fn(ctx);
	}
	for (int k = 0; k < ctx->n_items; k++)
		loom_design_free(ctx->items[k].design);
	failed = ctx->failed;
	free(ctx);
	return failed ? EXIT_BAD_INPUT : 0;
}
