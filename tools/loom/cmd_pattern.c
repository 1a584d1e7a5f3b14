/*
 * tools/loom/cmd_pattern.c - `loom pattern`: make, convert, from-image and
 * inspect weave patterns (docs/designs.md is the reference).
 *
 *   loom pattern make KIND [--over N --under N --move N --direction z|s
 *                           --period P] [--size MxN] -o OUT
 *   loom pattern convert IN -o OUT [type-map options]
 *   loom pattern from-image IMAGE --map MAPFILE -o OUT [type-map options]
 *   loom pattern info IN [--json] [--map MAPFILE] [--warp-map F --weft-map F]
 *
 * Exit status: 0 success, 1 bad input or failed operation, 2 usage error.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "io/core/file.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define MAP_FILE_MAX ((size_t)16 << 20)

/* Options shared by the sub-subcommands (each accepts a subset). */
typedef struct pat_opts {
	const char *in;        /* IN / IMAGE */
	const char *out;       /* -o */
	const char *map;       /* --map MAPFILE */
	const char *warp_in;   /* --warp-map */
	const char *weft_in;   /* --weft-map */
	const char *warp_out;  /* --write-warp-map */
	const char *weft_out;  /* --write-weft-map */
	int json;
	int quiet;
} pat_opts;

/* Table entries of those options. */
#define PAT_OPT_OUT(o, h) OPT_OUTPUT(&(o)->out, "OUT", h)
#define PAT_OPT_MAP(o, h) OPT_STRING(0, "map", &(o)->map, "MAPFILE", h)
#define PAT_OPT_MAPS_IN(o) \
	OPT_STRING(0, "warp-map", &(o)->warp_in, "FILE", "read the warp-type map of an " \
	           "image IN (.pgm or .png, pixel value = yarn type ID)"), \
	OPT_STRING(0, "weft-map", &(o)->weft_in, "FILE", \
	           "read the weft-type map of an image IN")
#define PAT_OPT_MAPS_OUT(o) \
	OPT_STRING(0, "write-warp-map", &(o)->warp_out, "FILE", \
	           "also write the warp-type map (.pgm or .png)"), \
	OPT_STRING(0, "write-weft-map", &(o)->weft_out, "FILE", \
	           "also write the weft-type map (.pgm or .png)")
#define PAT_OPT_QUIET(o) OPT_QUIET(&(o)->quiet, "nothing on success (no warnings, no " \
	                                          "text report)")

static const char about_pattern[] =
	"Make, convert and inspect weave patterns.  A weave image has one pixel\n"
	"per crossing: row = pick (weft), column = end (warp), black = warp over.\n";

static const char about_make[] =
	"Generate an elementary weave and write it as a weave image.\n"
	"\n"
	"KIND is plain, twill, satin, basket, herringbone, broken-twill or\n"
	"wavy-twill, or a full weave name such as twill:2/3, twill:2/3:s,\n"
	"satin:1/4:move=2, basket:2/3 or herringbone:2/2:period=4.  Options\n"
	"override what the name says.  A bare KIND means twill 2/2, satin 1/4,\n"
	"basket 2/2, herringbone, broken-twill and wavy-twill 2/2.\n";

static const char about_convert[] =
	"Read a design and write its weave pattern as an image: black = warp\n"
	"over, first row = first pick, first column = first end.  For a WIF\n"
	"draft that is exactly its drawdown.  --color writes the colour drawdown\n"
	"instead (the warp's colour where it is on top, the weft's elsewhere);\n"
	"--draft the draft diagram (threading, tie-up, treadling or liftplan and\n"
	"the colour drawdown, as weaving programs print it; the draft is recovered\n"
	"from the drawdown: one shaft per distinct end, one treadle per distinct\n"
	"pick, a liftplan when more than 24 treadles would be needed).\n"
	"\n"
	"IN is a WIF draft (.wif) or a weave image (.pbm, .png, .pgm: two\n"
	"levels, the darker one warp over).  OUT is .pbm (P4) or .png (1-bit);\n"
	".png or .ppm with --color or --draft.\n";

static const char about_from_image[] =
	"Build a design from a posterized image (paper 5.2): every colour of\n"
	"IMAGE gets the elementary weave and warp/weft yarn types of its line in\n"
	"MAPFILE, and W(x,y) = V_p(I(x,y))(x,y), each weave tiled from the\n"
	"top-left corner (row y = pick y, column x = end x).  IMAGE is PNG, PPM,\n"
	"PGM or PBM with at most 64 colours.  The mapping-file format is in\n"
	"docs/designs.md.\n";

static const char about_info[] =
	"Print a design's size, smallest repeat, float lengths (counted across\n"
	"the repeat's edges, as the bolt tiles it) and yarn types.\n"
	"\n"
	"IN is a WIF draft (.wif) or a weave image (.pbm, .png, .pgm).\n";

/* ---- option checks --------------------------------------------------------- */

static int ends_with(const char *path, const char *const *exts)
{
	size_t n = strlen(path);
	for (; *exts; exts++) {
		size_t k = strlen(*exts);
		if (n > k && strcasecmp(path + n - k, *exts) == 0)
			return 1;
	}
	return 0;
}

static const char *const weave_exts[] = {".pbm", ".png", NULL};
static const char *const map_exts[] = {".pgm", ".png", NULL};

/* After opts_parse: the checks of convert, from-image and info. */
static void check_common(const opts_cmd *c, const pat_opts *o, int need_out)
{
	if (need_out && !o->out)
		opts_usage(c, "missing -o OUT");
	if (o->out)
		cli_check_output(c->prog, o->out);
	if (o->out && !ends_with(o->out, weave_exts))
		opts_usage(c, "output '%s': expected a .pbm or .png file name", o->out);
	if ((o->warp_out && !ends_with(o->warp_out, map_exts)) ||
	    (o->weft_out && !ends_with(o->weft_out, map_exts)))
		opts_usage(c, "type maps are written as .pgm or .png files");
}

/* ---- loading and saving -------------------------------------------------- */

/* Read a whole text file (at most MAP_FILE_MAX bytes); exit 1 on failure. */
static char *read_text(const char *prog, const char *path, size_t *len)
{
	uint8_t *buf;
	loom_diag diag = {0};

	if (loom__read_file_checked(path, MAP_FILE_MAX, "mapping", loom__head_text,
	                            &buf, len, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	return (char *)buf;
}

static int design_from_image_file(const char *prog, const pat_opts *o,
                                  loom_design **d, loom_diag *diag)
{
	loom_image *img = NULL;
	size_t len;
	char *text = read_text(prog, o->map, &len);
	int rc = loom_image_read(o->in, &img, diag);

	if (!rc)
		rc = loom_design_from_image(img, text, len, o->map, d, diag);
	free(text);
	loom_image_free(img);
	return rc;
}

/* Load IN (mapped if --map), then the type maps; exit 1 on failure. */
static loom_design *load(const char *prog, const pat_opts *o, loom_diag *diag)
{
	loom_design *d = NULL;
	int rc = o->map ? design_from_image_file(prog, o, &d, diag)
	                : loom_design_read(o->in, &d, diag);

	if (rc)
		cli_fail(prog, "%s", diag->message);
	if ((o->warp_in && loom_type_map_read(o->warp_in, d, LOOM_MAP_WARP, diag)) ||
	    (o->weft_in && loom_type_map_read(o->weft_in, d, LOOM_MAP_WEFT, diag))) {
		loom_design_free(d);
		cli_fail(prog, "%s", diag->message);
	}
	return d;
}

static void save(const char *prog, const pat_opts *o, loom_design *d,
                 loom_diag *diag)
{
	int rc = loom_weave_write(o->out, d, diag);

	if (!rc && o->warp_out)
		rc = loom_type_map_write(o->warp_out, d, LOOM_MAP_WARP, diag);
	if (!rc && o->weft_out)
		rc = loom_type_map_write(o->weft_out, d, LOOM_MAP_WEFT, diag);
	loom_design_free(d);
	if (rc)
		cli_fail(prog, "%s", diag->message);
}

/* ---- make ---------------------------------------------------------------- */

/* The options of make that change the weave: given (opt_given) or not. */
typedef struct make_opts {
	uint32_t over, under, move, period;
	int direction;
	uint32_t size[2];      /* --size: rows, cols (0: one repeat) */
} make_opts;

/* Options each kind uses (bit per option: over, under, move, direction,
   period). */
static unsigned kind_uses(int kind)
{
	switch (kind) {
	case LOOM_WEAVE_PLAIN: return 0;
	case LOOM_WEAVE_TWILL: return 1 | 2 | 8;
	case LOOM_WEAVE_SATIN: return 1 | 2 | 4;
	case LOOM_WEAVE_BASKET: return 1 | 2;
	default: return 1 | 2 | 16;
	}
}

/* KIND alone ("twill") or a full name ("twill:2/3"). */
static void parse_kind(const opts_cmd *c, const char *kind, loom_weave_params *p)
{
	static const char *const bare[][2] = {
		{"twill", "twill:2/2"}, {"satin", "satin:1/4"}, {"basket", "basket:2/2"},
		{"herringbone", "herringbone:2/2"}, {"broken-twill", "broken-twill:2/2"},
		{"wavy-twill", "wavy-twill:2/2"},
	};
	const char *name = kind;
	loom_diag d = {0};

	for (size_t k = 0; k < sizeof bare / sizeof bare[0]; k++)
		if (strcasecmp(kind, bare[k][0]) == 0)
			name = bare[k][1];
	if (loom_weave_parse(name, p, &d))
		opts_usage(c, "%s", d.message);
}

static void apply_make_opts(const opts_cmd *c, const make_opts *m,
                            loom_weave_params *p)
{
	const void *given[5] = {&m->over, &m->under, &m->move, &m->direction, &m->period};
	static const char *const names[5] = {"--over", "--under", "--move",
	                                     "--direction", "--period"};
	unsigned uses = kind_uses(p->kind);
	char kind[64];
	loom_diag d = {0};
	uint32_t r, cols;

	loom_weave_name(p, kind, sizeof kind);
	for (int k = 0; k < 5; k++)
		if (opt_given(c, given[k]) && !(uses & (1u << k)))
			opts_usage(c, "%s does not apply to %s", names[k], kind);
	if (opt_given(c, &m->over))
		p->over = m->over;
	if (opt_given(c, &m->under))
		p->under = m->under;
	if (opt_given(c, &m->move))
		p->move = m->move;
	if (opt_given(c, &m->period))
		p->period = m->period;
	if (opt_given(c, &m->direction))
		p->direction = m->direction;
	if (loom_weave_repeat(p, &r, &cols, &d))
		opts_usage(c, "%s", d.message);
}

/* --size MxN: rows and columns of the design. */
static const char *opt_size(const char *text, void *dest)
{
	uint32_t *rc = dest;

	if (cli_parse_size2(text, &rc[0], &rc[1]) || rc[0] == 0 || rc[1] == 0 ||
	    rc[0] > LOOM_DESIGN_MAX_SIDE || rc[1] > LOOM_DESIGN_MAX_SIDE ||
	    (uint64_t)rc[0] * rc[1] > LOOM_DESIGN_MAX_CELLS)
		return "MxN, 1..1000000 each and at most 2^32 cells";
	return NULL;
}

static const opt_choice direction_names[] = {{"z", 1}, {"s", -1}, {NULL, 0}};

static int pattern_make(int argc, char **argv)
{
	pat_opts o = {0};
	make_opts m = {0, 0, 0, 0, 1, {0, 0}};
	loom_weave_params p;
	loom_design *d = NULL;
	loom_diag diag;
	int rc;
	opt_entry opts[] = {
		OPT_U32(0, "over", &m.over, "N", 1, UINT32_MAX,
		        "warp-over picks per repeat (basket: rows per block)"),
		OPT_U32(0, "under", &m.under, "N", 1, UINT32_MAX,
		        "warp-under picks per repeat (basket: ends per block)"),
		OPT_U32(0, "move", &m.move, "N", 1, UINT32_MAX, "satin move number, coprime "
		        "with over+under (default: the smallest valid move)"),
		OPT_ENUM_ICASE(0, "direction", &m.direction, "z|s", direction_names,
		               "twill direction: z rises to the right, s to the left"),
		OPT_U32(0, "period", &m.period, "P", 1, UINT32_MAX,
		        "ends per section (herringbone, broken-twill, wavy-twill)"),
		OPT_CALLBACK(0, "size", m.size, "MxN", opt_size, "M picks (rows) by N ends "
		             "(columns), the weave tiled from the top-left corner (default: one "
		             "repeat)"),
		PAT_OPT_OUT(&o, "write OUT: .pbm (binary P4) or .png (1-bit grey)"),
		PAT_OPT_QUIET(&o),
		OPT_END()
	};
	opts_cmd c = {.prog = "loom pattern make", .usage = "loom pattern make KIND "
	              "[OPTIONS] -o OUT", .about = about_make, .opts = opts,
	              .pos_name = "KIND", .pos_missing = "missing KIND (plain, twill, satin, "
	              "basket, herringbone, broken-twill, wavy-twill)", .pos_min = 1,
	              .pos_max = 1, .pos = &o.in};

	opts_parse(&c, argc, argv);
	check_common(&c, &o, 1);
	parse_kind(&c, o.in, &p);
	apply_make_opts(&c, &m, &p);
	cli_diag_init(&diag, &o.quiet);
	rc = loom_design_make(&p, m.size[0], m.size[1], &d, &diag);
	if (rc)
		cli_fail(c.prog, "%s", diag.message);
	save(c.prog, &o, d, &diag);
	return 0;
}

/* ---- convert, from-image -------------------------------------------------- */

#define DRAFT_MAX_TREADLES 24u  /* more distinct picks: a liftplan */
#define DRAFT_MAX_THREADS 600u  /* ends and picks drawn in a draft diagram */

static int pattern_convert(int argc, char **argv)
{
	pat_opts o = {0};
	loom_diag diag;
	int color = 0, draft = 0;
	uint32_t cell = 0;
	opt_entry opts[] = {
		PAT_OPT_OUT(&o, "the weave image to write"),
		OPT_FLAG(0, "color", &color, "write the colour drawdown (.png or .ppm, RGB): "
		         "warp colour where the warp is over, weft colour elsewhere"),
		OPT_FLAG(0, "draft", &draft, "write the draft diagram (.png or .ppm): "
		         "threading, tie-up, treadling or liftplan, colour drawdown"),
		OPT_U32(0, "cell", &cell, "PX", 1, 64, "pixels per crossing with --color "
		        "(default 1) or per cell with --draft (default: about 1100 px in all), "
		        "%r"),
		PAT_OPT_MAP(&o, "IN is a posterized image: map it as from-image does"),
		PAT_OPT_MAPS_IN(&o),
		PAT_OPT_MAPS_OUT(&o),
		PAT_OPT_QUIET(&o),
		OPT_END()
	};
	opts_cmd c = {.prog = "loom pattern convert",
	              .usage = "loom pattern convert IN -o OUT [--color | --draft] [OPTIONS]",
	              .about = about_convert, .opts = opts, .pos_name = "IN", .pos_min = 1,
	              .pos_max = 1, .pos = &o.in};
	static const char *const pic_exts[] = {".png", ".ppm", NULL};

	opts_parse(&c, argc, argv);
	if (color && draft)
		opts_usage(&c, "--color and --draft make different pictures: give one");
	if (opt_given(&c, &cell) && !color && !draft)
		opts_usage(&c, "--cell needs --color or --draft");
	if (color || draft) {
		loom_design *d;
		int rc;
		if (!o.out)
			opts_usage(&c, "missing -o OUT");
		cli_check_output(c.prog, o.out);
		if (!ends_with(o.out, pic_exts))
			opts_usage(&c, "output '%s': expected a .png or .ppm file name with %s",
			           o.out, color ? "--color" : "--draft");
		check_common(&c, &(pat_opts){.warp_out = o.warp_out, .weft_out = o.weft_out}, 0);
		cli_diag_init(&diag, &o.quiet);
		d = load(c.prog, &o, &diag);
		if (color) {
			rc = loom_color_drawdown_write(o.out, d, cell ? cell : 1, &diag);
		} else {
			loom_draft *dr = NULL;
			rc = loom_draft_from_design(d, DRAFT_MAX_TREADLES, &dr, &diag);
			if (!rc && (d->cols > DRAFT_MAX_THREADS || d->rows > DRAFT_MAX_THREADS))
				cli_warn_sink(&o.quiet, "the draft diagram shows the first 600 ends "
				              "and picks of the design");
			if (!rc)
				rc = loom_draft_write(o.out, d, dr, cell, DRAFT_MAX_THREADS, &diag);
			if (!rc && !o.quiet)
				fprintf(stderr, "loom pattern convert: %s: %u shafts, %s%u%s\n", o.out,
				        dr->shafts, dr->treadles ? "" : "liftplan of ",
				        dr->treadles ? dr->treadles : d->rows,
				        dr->treadles ? " treadles" : " picks");
			loom_draft_free(dr);
		}
		if (!rc && o.warp_out)
			rc = loom_type_map_write(o.warp_out, d, LOOM_MAP_WARP, &diag);
		if (!rc && o.weft_out)
			rc = loom_type_map_write(o.weft_out, d, LOOM_MAP_WEFT, &diag);
		loom_design_free(d);
		if (rc)
			cli_fail(c.prog, "%s", diag.message);
		return 0;
	}
	check_common(&c, &o, 1);
	cli_diag_init(&diag, &o.quiet);
	save(c.prog, &o, load(c.prog, &o, &diag), &diag);
	return 0;
}

static int pattern_from_image(int argc, char **argv)
{
	pat_opts o = {0};
	loom_diag diag;
	opt_entry opts[] = {
		PAT_OPT_MAP(&o, "the mapping file (required)"),
		PAT_OPT_OUT(&o, "the weave image to write (.pbm or .png)"),
		PAT_OPT_MAPS_OUT(&o),
		PAT_OPT_QUIET(&o),
		OPT_END()
	};
	opts_cmd c = {.prog = "loom pattern from-image",
	              .usage = "loom pattern from-image IMAGE --map MAPFILE -o OUT [OPTIONS]",
	              .about = about_from_image, .opts = opts, .pos_name = "IMAGE",
	              .pos_min = 1, .pos_max = 1, .pos = &o.in};

	opts_parse(&c, argc, argv);
	check_common(&c, &o, 1);
	if (!o.map)
		opts_usage(&c, "missing --map MAPFILE");
	cli_diag_init(&diag, &o.quiet);
	save(c.prog, &o, load(c.prog, &o, &diag), &diag);
	return 0;
}

/* ---- info ----------------------------------------------------------------- */

/* used[t] = 1 when type t appears in either map. */
static void types_in_use(const loom_design *d, uint8_t used[256])
{
	size_t n = (size_t)d->rows * d->cols;
	memset(used, 0, 256);
	for (size_t k = 0; k < n; k++) {
		used[d->warp_type[k]] = 1;
		used[d->weft_type[k]] = 1;
	}
}

static double round6(float x)
{
	return round((double)x * 1e6) / 1e6;
}

static void info_json(const pat_opts *o, const loom_design *d,
                      const loom_design_stats *st, const uint8_t *used)
{
	json_w w;

	jw_begin(&w, stdout);
	jw_str(&w, "file", o->in);
	jw_uint(&w, "rows", d->rows);
	jw_uint(&w, "cols", d->cols);
	jw_arr(&w, "repeat");
	jw_uint(&w, NULL, st->repeat_rows);
	jw_uint(&w, NULL, st->repeat_cols);
	jw_close(&w);
	jw_uint(&w, "warp_over", st->warp_over);
	jw_obj(&w, "warp_floats");
	jw_uint(&w, "max", st->max_warp_float);
	jw_num(&w, "mean", st->mean_warp_float);
	jw_close(&w);
	jw_obj(&w, "weft_floats");
	jw_uint(&w, "max", st->max_weft_float);
	jw_num(&w, "mean", st->mean_weft_float);
	jw_close(&w);
	jw_bool(&w, "interlaced", st->interlaced);
	jw_uint(&w, "types_used", st->types_used);
	jw_arr(&w, "types");
	for (uint32_t t = 0; t < d->n_types; t++) {
		const loom_yarn_type *y = &d->types[t];
		jw_obj(&w, NULL);
		jw_uint(&w, "id", t);
		jw_str(&w, "name", y->name);
		jw_arr(&w, "albedo");
		for (int c = 0; c < 3; c++)
			jw_num(&w, NULL, round6(y->albedo[c]));
		jw_close(&w);
		jw_num(&w, "alignment", round6(y->alignment));
		jw_num(&w, "thickness", round6(y->thickness));
		jw_bool(&w, "used", used[t]);
		jw_close(&w);
	}
	jw_close(&w);
	jw_end(&w);
}

static void info_text(const pat_opts *o, const loom_design *d,
                      const loom_design_stats *st, const uint8_t *used)
{
	double cells = (double)d->rows * d->cols;
	int nw = 4;

	printf("design       %s\n", o->in);
	printf("size         %u picks x %u ends (rows x columns)\n", d->rows, d->cols);
	printf("repeat       %u x %u\n", st->repeat_rows, st->repeat_cols);
	printf("warp over    %llu of %.0f cells (%.1f%%)\n",
	       (unsigned long long)st->warp_over, cells,
	       100.0 * (double)st->warp_over / cells);
	printf("warp floats  max %u, mean %.2f\n", st->max_warp_float,
	       st->mean_warp_float);
	printf("weft floats  max %u, mean %.2f\n", st->max_weft_float,
	       st->mean_weft_float);
	printf("interlaced   %s\n", st->interlaced ? "yes" : "no (some end or pick never crosses)");
	printf("yarn types   %u in the table, %u used\n", d->n_types, st->types_used);
	for (uint32_t t = 0; t < d->n_types; t++)
		if ((int)strlen(d->types[t].name) > nw)
			nw = (int)strlen(d->types[t].name);
	printf("  %3s  %-*s  %-17s  %-9s  %s\n", "id", nw, "name", "albedo r g b",
	       "alignment", "used");
	for (uint32_t t = 0; t < d->n_types; t++) {
		const loom_yarn_type *y = &d->types[t];
		printf("  %3u  %-*s  %.3f %.3f %.3f  %-9.3f  %s\n", t, nw, y->name,
		       y->albedo[0], y->albedo[1], y->albedo[2], y->alignment,
		       used[t] ? "yes" : "no");
	}
}

static int pattern_info(int argc, char **argv)
{
	pat_opts o = {0};
	loom_diag diag;
	loom_design *d;
	loom_design_stats st;
	uint8_t used[256];
	opt_entry opts[] = {
		OPT_JSON(&o.json, "JSON output (keys in docs/designs.md)"),
		PAT_OPT_MAP(&o, "IN is a posterized image: map it as from-image does"),
		PAT_OPT_MAPS_IN(&o),
		PAT_OPT_QUIET(&o),
		OPT_END()
	};
	opts_cmd c = {.prog = "loom pattern info",
	              .usage = "loom pattern info IN [--json] [OPTIONS]",
	              .about = about_info, .opts = opts, .pos_name = "IN", .pos_min = 1,
	              .pos_max = 1, .pos = &o.in};

	opts_parse(&c, argc, argv);
	check_common(&c, &o, 0);
	cli_diag_init(&diag, &o.quiet);
	d = load(c.prog, &o, &diag);
	if (loom_design_analyze(d, &st)) {
		loom_design_free(d);
		cli_fail(c.prog, "%s: cannot analyse the design (out of memory)", o.in);
	}
	types_in_use(d, used);
	if (o.json)
		info_json(&o, d, &st, used);
	else if (!o.quiet) /* --quiet: nothing on success; --json still prints */
		info_text(&o, d, &st, used);
	loom_design_free(d);
	return 0;
}

/* ---- dispatch ---------------------------------------------------------------- */

int cmd_pattern(int argc, char **argv)
{
	static const opts_sub subs[] = {
		{"make", "KIND", pattern_make,
		 "generate an elementary weave (plain, twill, satin, ...)"},
		{"convert", "IN", pattern_convert,
		 "a WIF draft or weave image to a .pbm or .png weave"},
		{"from-image", "IMAGE", pattern_from_image,
		 "posterized image + mapping file -> design (Jacquard)"},
		{"info", "IN", pattern_info, "size, repeat, float lengths and yarn types"},
		{NULL, NULL, NULL, NULL},
	};
	static const opts_dispatch d = {"loom pattern", about_pattern,
	                                "Reference: docs/designs.md.", subs};

	return opts_run_sub(&d, argc, argv);
}
