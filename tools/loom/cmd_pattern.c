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

enum { OPT_OUT = 1, OPT_MAP = 2, OPT_MAPS_IN = 4, OPT_MAPS_OUT = 8, OPT_JSON = 16 };

static const char help_pattern[] =
	"usage: loom pattern COMMAND [ARGS...]\n"
	"\n"
	"Make, convert and inspect weave patterns.  A weave image has one pixel\n"
	"per crossing: row = pick (weft), column = end (warp), black = warp over.\n"
	"\n"
	"commands:\n"
	"  make KIND         generate an elementary weave (plain, twill, satin, ...)\n"
	"  convert IN        a WIF draft or weave image to a .pbm or .png weave\n"
	"  from-image IMAGE  posterized image + mapping file -> design (Jacquard)\n"
	"  info IN           size, repeat, float lengths and yarn types\n"
	"\n"
	"  loom pattern COMMAND --help   options of one command\n"
	"\n"
	"Exit status: 0 success, 1 bad input or failed operation, 2 usage error.\n"
	"Reference: docs/designs.md.\n";

static const char help_make[] =
	"usage: loom pattern make KIND [OPTIONS] -o OUT\n"
	"\n"
	"Generate an elementary weave and write it as a weave image.\n"
	"\n"
	"KIND is plain, twill, satin, basket, herringbone, broken-twill or\n"
	"wavy-twill, or a full weave name such as twill:2/3, twill:2/3:s,\n"
	"satin:1/4:move=2, basket:2/3 or herringbone:2/2:period=4.  Options\n"
	"override what the name says.  A bare KIND means twill 2/2, satin 1/4,\n"
	"basket 2/2, herringbone, broken-twill and wavy-twill 2/2.\n"
	"\n"
	"options:\n"
	"  --over N          warp-over picks per repeat (basket: rows per block)\n"
	"  --under N         warp-under picks per repeat (basket: ends per block)\n"
	"  --move N          satin move number, coprime with over+under\n"
	"                    (default: the smallest valid move)\n"
	"  --direction z|s   twill direction: z rises to the right, s to the left\n"
	"  --period P        ends per section (herringbone, broken-twill,\n"
	"                    wavy-twill)\n"
	"  --size MxN        M picks (rows) by N ends (columns), the weave tiled\n"
	"                    from the top-left corner (default: one repeat)\n"
	"  -o, --output OUT  write OUT: .pbm (binary P4) or .png (1-bit grey)\n"
	"  -q, --quiet       no warnings\n"
	"  -h, --help        this text\n";

static const char help_convert[] =
	"usage: loom pattern convert IN -o OUT [OPTIONS]\n"
	"\n"
	"Read a design and write its weave pattern as an image: black = warp\n"
	"over, first row = first pick, first column = first end.  For a WIF\n"
	"draft that is exactly its drawdown.\n"
	"\n"
	"IN is a WIF draft (.wif) or a weave image (.pbm, .png, .pgm: two\n"
	"levels, the darker one warp over).  OUT is .pbm (P4) or .png (1-bit).\n"
	"\n"
	"options:\n"
	"  -o, --output OUT        the weave image to write\n"
	"  --warp-map FILE         read the warp-type map of an image IN\n"
	"  --weft-map FILE         read the weft-type map of an image IN\n"
	"                          (.pgm or .png, pixel value = yarn type ID)\n"
	"  --write-warp-map FILE   also write the warp-type map (.pgm or .png)\n"
	"  --write-weft-map FILE   also write the weft-type map (.pgm or .png)\n"
	"  -q, --quiet             no warnings\n"
	"  -h, --help              this text\n";

static const char help_from_image[] =
	"usage: loom pattern from-image IMAGE --map MAPFILE -o OUT [OPTIONS]\n"
	"\n"
	"Build a design from a posterized image (paper 5.2): every colour of\n"
	"IMAGE gets the elementary weave and warp/weft yarn types of its line in\n"
	"MAPFILE, and W(x,y) = V_p(I(x,y))(x,y), each weave tiled from the\n"
	"top-left corner (row y = pick y, column x = end x).  IMAGE is PNG, PPM,\n"
	"PGM or PBM with at most 64 colours.  The mapping-file format is in\n"
	"docs/designs.md.\n"
	"\n"
	"options:\n"
	"  --map MAPFILE           the mapping file (required)\n"
	"  -o, --output OUT        the weave image to write (.pbm or .png)\n"
	"  --write-warp-map FILE   also write the warp-type map (.pgm or .png)\n"
	"  --write-weft-map FILE   also write the weft-type map (.pgm or .png)\n"
	"  -q, --quiet             no warnings\n"
	"  -h, --help              this text\n";

static const char help_info[] =
	"usage: loom pattern info IN [--json] [OPTIONS]\n"
	"\n"
	"Print a design's size, smallest repeat, float lengths (counted across\n"
	"the repeat's edges, as the bolt tiles it) and yarn types.\n"
	"\n"
	"IN is a WIF draft (.wif) or a weave image (.pbm, .png, .pgm).\n"
	"\n"
	"options:\n"
	"  --json              JSON output (keys in docs/designs.md)\n"
	"  --map MAPFILE       IN is a posterized image: map it as from-image does\n"
	"  --warp-map FILE     read the warp-type map of an image IN\n"
	"  --weft-map FILE     read the weft-type map of an image IN\n"
	"  -q, --quiet         no warnings\n"
	"  -h, --help          this text\n";

/* ---- option parsing ------------------------------------------------------ */

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

/* One option of the set `allowed`; 0 if the argument is not one. */
static int take_option(cli_args *a, pat_opts *o, unsigned allowed)
{
	if ((allowed & OPT_OUT) &&
	    (cli_value(a, "-o", &o->out) || cli_value(a, "--output", &o->out)))
		return 1;
	if ((allowed & OPT_MAP) && cli_value(a, "--map", &o->map))
		return 1;
	if ((allowed & OPT_MAPS_IN) && (cli_value(a, "--warp-map", &o->warp_in) ||
	                                cli_value(a, "--weft-map", &o->weft_in)))
		return 1;
	if ((allowed & OPT_MAPS_OUT) &&
	    (cli_value(a, "--write-warp-map", &o->warp_out) ||
	     cli_value(a, "--write-weft-map", &o->weft_out)))
		return 1;
	if ((allowed & OPT_JSON) && cli_flag(a, "--json")) {
		o->json = 1;
		return 1;
	}
	if (cli_flag(a, "-q") || cli_flag(a, "--quiet")) {
		o->quiet = 1;
		return 1;
	}
	return 0;
}

/* Parse IN and options; checks output extensions. */
static void parse_common(cli_args *a, pat_opts *o, unsigned allowed,
                         const char *in_name)
{
	while (cli_more(a)) {
		const char *p;
		if (take_option(a, o, allowed))
			continue;
		if ((p = cli_positional(a)) && !o->in) {
			o->in = p;
			continue;
		}
		if (p)
			cli_usage(a, "unexpected argument '%s'", p);
		cli_unknown(a);
	}
	if (!o->in)
		cli_usage(a, "missing %s", in_name);
	if ((allowed & OPT_OUT) && !o->out)
		cli_usage(a, "missing -o OUT");
	if (o->out && !ends_with(o->out, weave_exts))
		cli_usage(a, "output '%s': expected a .pbm or .png file name", o->out);
	if ((o->warp_out && !ends_with(o->warp_out, map_exts)) ||
	    (o->weft_out && !ends_with(o->weft_out, map_exts)))
		cli_usage(a, "type maps are written as .pgm or .png files");
}

/* ---- loading and saving -------------------------------------------------- */

/* Read a whole text file (at most MAP_FILE_MAX bytes); exit 1 on failure. */
static char *read_text(const char *prog, const char *path, size_t *len)
{
	FILE *fp = fopen(path, "rb");
	char *buf = NULL;
	size_t cap = 0, got;

	if (!fp)
		cli_fail(prog, "%s: cannot open: %s", path, strerror(errno));
	*len = 0;
	do {
		char *grown;
		if (*len == cap) {
			cap = cap ? 2 * cap : 4096;
			grown = cap > 2 * MAP_FILE_MAX ? NULL : realloc(buf, cap);
			if (!grown) {
				free(buf);
				fclose(fp);
				cli_fail(prog, "%s: larger than 16 MiB or out of memory", path);
			}
			buf = grown;
		}
		got = fread(buf + *len, 1, cap - *len, fp);
		*len += got;
	} while (got > 0 && *len <= MAP_FILE_MAX);
	if (ferror(fp) || *len > MAP_FILE_MAX) {
		int e = ferror(fp);
		fclose(fp);
		free(buf);
		cli_fail(prog, "%s: %s", path, e ? "read error" : "larger than 16 MiB");
	}
	fclose(fp);
	return buf;
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

typedef struct make_opts {
	const char *over, *under, *move, *direction, *period, *size;
} make_opts;

/* Options each kind uses (bit per make_opts field, in order). */
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
static void parse_kind(const cli_args *a, const char *kind, loom_weave_params *p)
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
		cli_usage(a, "%s", d.message);
}

static uint32_t u32_opt(const cli_args *a, const char *name, const char *v)
{
	uint32_t x;
	if (cli_parse_u32(v, &x) || x == 0)
		cli_usage(a, "%s: expected a positive whole number, got '%s'", name, v);
	return x;
}

static void apply_make_opts(const cli_args *a, const make_opts *m,
                            loom_weave_params *p)
{
	const char *given[5] = {m->over, m->under, m->move, m->direction, m->period};
	static const char *const names[5] = {"--over", "--under", "--move",
	                                     "--direction", "--period"};
	unsigned uses = kind_uses(p->kind);
	char kind[64];
	loom_diag d = {0};
	uint32_t r, c;

	loom_weave_name(p, kind, sizeof kind);
	for (int k = 0; k < 5; k++)
		if (given[k] && !(uses & (1u << k)))
			cli_usage(a, "%s does not apply to %s", names[k], kind);
	if (m->over)
		p->over = u32_opt(a, "--over", m->over);
	if (m->under)
		p->under = u32_opt(a, "--under", m->under);
	if (m->move)
		p->move = u32_opt(a, "--move", m->move);
	if (m->period)
		p->period = u32_opt(a, "--period", m->period);
	if (m->direction) {
		if (strcasecmp(m->direction, "z") && strcasecmp(m->direction, "s"))
			cli_usage(a, "--direction: expected z or s, got '%s'", m->direction);
		p->direction = strcasecmp(m->direction, "s") == 0 ? -1 : 1;
	}
	if (loom_weave_repeat(p, &r, &c, &d))
		cli_usage(a, "%s", d.message);
}

static int pattern_make(int argc, char **argv)
{
	cli_args a;
	pat_opts o = {0};
	make_opts m = {0};
	loom_weave_params p;
	loom_design *d = NULL;
	loom_diag diag;
	uint32_t rows = 0, cols = 0;
	int rc;

	cli_init(&a, argc, argv, "loom pattern make", help_make);
	while (cli_more(&a)) {
		const char *v;
		if (cli_value(&a, "--over", &m.over) || cli_value(&a, "--under", &m.under) ||
		    cli_value(&a, "--move", &m.move) || cli_value(&a, "--period", &m.period) ||
		    cli_value(&a, "--direction", &m.direction) ||
		    cli_value(&a, "--size", &m.size) || take_option(&a, &o, OPT_OUT))
			continue;
		if ((v = cli_positional(&a)) && !o.in) {
			o.in = v;
			continue;
		}
		if (v)
			cli_usage(&a, "unexpected argument '%s'", v);
		cli_unknown(&a);
	}
	if (!o.in)
		cli_usage(&a, "missing KIND (plain, twill, satin, basket, herringbone, "
		          "broken-twill, wavy-twill)");
	if (!o.out)
		cli_usage(&a, "missing -o OUT");
	if (!ends_with(o.out, weave_exts))
		cli_usage(&a, "output '%s': expected a .pbm or .png file name", o.out);
	if (m.size && (cli_parse_size2(m.size, &rows, &cols) || rows == 0 || cols == 0 ||
	               rows > LOOM_DESIGN_MAX_SIDE || cols > LOOM_DESIGN_MAX_SIDE ||
	               (uint64_t)rows * cols > LOOM_DESIGN_MAX_CELLS))
		cli_usage(&a, "--size: expected MxN, 1..%u each and at most 2^32 cells, "
		          "got '%s'", LOOM_DESIGN_MAX_SIDE, m.size);
	parse_kind(&a, o.in, &p);
	apply_make_opts(&a, &m, &p);
	cli_diag_init(&diag, &o.quiet);
	rc = loom_design_make(&p, rows, cols, &d, &diag);
	if (rc)
		cli_fail(a.prog, "%s", diag.message);
	save(a.prog, &o, d, &diag);
	return 0;
}

/* ---- convert, from-image -------------------------------------------------- */

static int pattern_convert(int argc, char **argv)
{
	cli_args a;
	pat_opts o = {0};
	loom_diag diag;

	cli_init(&a, argc, argv, "loom pattern convert", help_convert);
	parse_common(&a, &o, OPT_OUT | OPT_MAPS_IN | OPT_MAPS_OUT, "IN");
	cli_diag_init(&diag, &o.quiet);
	save(a.prog, &o, load(a.prog, &o, &diag), &diag);
	return 0;
}

static int pattern_from_image(int argc, char **argv)
{
	cli_args a;
	pat_opts o = {0};
	loom_diag diag;

	cli_init(&a, argc, argv, "loom pattern from-image", help_from_image);
	parse_common(&a, &o, OPT_OUT | OPT_MAP | OPT_MAPS_OUT, "IMAGE");
	if (!o.map)
		cli_usage(&a, "missing --map MAPFILE");
	cli_diag_init(&diag, &o.quiet);
	save(a.prog, &o, load(a.prog, &o, &diag), &diag);
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
	cli_args a;
	pat_opts o = {0};
	loom_diag diag;
	loom_design *d;
	loom_design_stats st;
	uint8_t used[256];

	cli_init(&a, argc, argv, "loom pattern info", help_info);
	parse_common(&a, &o, OPT_MAP | OPT_MAPS_IN | OPT_JSON, "IN");
	cli_diag_init(&diag, &o.quiet);
	d = load(a.prog, &o, &diag);
	if (loom_design_analyze(d, &st)) {
		loom_design_free(d);
		cli_fail(a.prog, "%s: cannot analyse the design (out of memory)", o.in);
	}
	types_in_use(d, used);
	if (o.json)
		info_json(&o, d, &st, used);
	else
		info_text(&o, d, &st, used);
	loom_design_free(d);
	return 0;
}

/* ---- dispatch ---------------------------------------------------------------- */

int cmd_pattern(int argc, char **argv)
{
	static const struct {
		const char *name;
		cli_cmd_fn fn;
	} subs[] = {
		{"make", pattern_make},
		{"convert", pattern_convert},
		{"from-image", pattern_from_image},
		{"info", pattern_info},
	};

	if (argc < 2) {
		fputs(help_pattern, stderr);
		return EXIT_USAGE;
	}
	if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
	    strcmp(argv[1], "help") == 0) {
		fputs(help_pattern, stdout);
		return 0;
	}
	for (size_t k = 0; k < sizeof subs / sizeof subs[0]; k++)
		if (strcmp(argv[1], subs[k].name) == 0)
			return subs[k].fn(argc - 1, argv + 1);
	fprintf(stderr, "loom pattern: unknown command '%s'\nTry 'loom pattern --help'.\n",
	        argv[1]);
	return EXIT_USAGE;
}
