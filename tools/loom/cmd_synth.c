/*
 * tools/loom/cmd_synth.c - `loom synth`: design + exemplar database ->
 * fabric file (paper 5.3-5.5; docs/fabric.md).
 *
 *   loom synth DESIGN [--db DB | --fibre F[,F]] [--yarn-fibre TYPE=F ...]
 *              [--algo dp|greedy|naive] [--seed N]
 *              [--rank R] [--edge-fix on|off|full] [--identity] [--group M] [--map MAPFILE] [--warp-map F]
 *              [--weft-map F] -o FABRIC [--json] [--assignment-map PNG]
 *              [--seam-map PNG] [--edge-tables auto|store|rebuild] [--quiet]
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "io/core/file.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char about[] =
	"Choose, for every crossing of DESIGN, the exemplar block it copies and\n"
	"compute the edge-fix tables that hide the seams between blocks (paper\n"
	"sections 5.3-5.5); write the fabric file FABRIC (docs/fabric.md).\n"
	"\n"
	"DESIGN is any design loom reads: a WIF draft, a PBM/PNG/PGM weave (dark =\n"
	"warp over), or a posterized image with --map.  A design with a float\n"
	"longer than any in the database gets a warning: blocks along it are\n"
	"copied from shorter floats (docs/fidelity.md, \"Float runs\").\n";

static const opt_choice algo_names[] = {
	{"dp", LOOM_SYNTH_DP}, {"greedy", LOOM_SYNTH_GREEDY}, {"naive", LOOM_SYNTH_NAIVE},
	{NULL, 0}};
static const opt_choice edge_fix_names[] = {{"on", 1}, {"off", 0}, {"full", 2}, {NULL, 0}};
static const opt_choice edge_names[] = {
	{"auto", LOOM_FABRIC_EDGE_AUTO}, {"store", LOOM_FABRIC_EDGE_STORE},
	{"rebuild", LOOM_FABRIC_EDGE_REBUILD}, {NULL, 0}};

#define MAP_TEXT_MAX (16u << 20)
#define ASSIGN_MAP_MAX 4096u /* crossings per side drawn */
#define SEAM_MAP_MIN 64u
#define SEAM_MAP_MAX 256u

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static char *read_text(const char *prog, const char *path, size_t *len)
{
	uint8_t *buf;
	loom_diag diag = {0};

	if (loom__read_file_checked(path, MAP_TEXT_MAX, "mapping", loom__head_text,
	                            &buf, len, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	return (char *)buf;
}

loom_design *synth_load_design(const char *prog, const char *in, const char *map,
                                const char *warp, const char *weft, loom_diag *diag)
{
	loom_design *d = NULL;
	int rc;

	if (map) {
		loom_image *img = NULL;
		size_t len;
		char *text = read_text(prog, map, &len);
		rc = loom_image_read(in, &img, diag);
		if (!rc)
			rc = loom_design_from_image(img, text, len, map, &d, diag);
		free(text);
		loom_image_free(img);
	} else {
		rc = loom_design_read(in, &d, diag);
	}
	if (rc)
		cli_fail(prog, "%s", diag->message);
	if ((warp && loom_type_map_read(warp, d, LOOM_MAP_WARP, diag)) ||
	    (weft && loom_type_map_read(weft, d, LOOM_MAP_WEFT, diag))) {
		loom_design_free(d);
		cli_fail(prog, "%s", diag->message);
	}
	return d;
}

/* ---- pictures ---------------------------------------------------------------- */

static void hsv(double h, double s, double v, uint8_t *rgb)
{
	double c = v * s, hp = fmod(h, 1.0) * 6.0, x = c * (1 - fabs(fmod(hp, 2.0) - 1));
	double r = 0, g = 0, b = 0, m = v - c;
	switch ((int)hp) {
	case 0: r = c; g = x; break;
	case 1: r = x; g = c; break;
	case 2: g = c; b = x; break;
	case 3: g = x; b = c; break;
	case 4: r = x; b = c; break;
	default: r = c; b = x; break;
	}
	rgb[0] = (uint8_t)lround(255 * (r + m));
	rgb[1] = (uint8_t)lround(255 * (g + m));
	rgb[2] = (uint8_t)lround(255 * (b + m));
}

static uint32_t scale_for(uint32_t h, uint32_t w, uint32_t target, uint32_t lo,
                          uint32_t hi)
{
	uint32_t m = h > w ? h : w, s = target / (m ? m : 1);
	return s < lo ? lo : s > hi ? hi : s;
}

static void fill_cell(loom_image *img, uint32_t x0, uint32_t y0, uint32_t s,
                      const uint8_t rgb[3])
{
	for (uint32_t y = 0; y < s; y++)
		for (uint32_t x = 0; x < s; x++)
			memcpy(img->pixels + 3 * ((size_t)(y0 + y) * img->width + x0 + x), rgb, 3);
}

/* Fig. 4 (right): hue = exemplar, brightness = block of that exemplar. */
static void assignment_map(const char *prog, const loom_fabric *f, const loom_db *db,
                           const char *path, uint32_t *drawn, loom_diag *diag)
{
	const loom_design *d = loom_fabric_design(f);
	uint32_t h = d->rows < ASSIGN_MAP_MAX ? d->rows : ASSIGN_MAP_MAX;
	uint32_t w = d->cols < ASSIGN_MAP_MAX ? d->cols : ASSIGN_MAP_MAX;
	uint32_t s = scale_for(h, w, 1024, 1, 16), n_ex;
	loom_fabric_db_identity id;
	loom_image *img;
	uint32_t *ncols, *nblk;

	loom_fabric_get_db_identity(f, &id);
	n_ex = id.n_exemplars;
	ncols = calloc(n_ex, sizeof *ncols);
	nblk = calloc(n_ex, sizeof *nblk);
	if (!ncols || !nblk || loom_image_new(w * s, h * s, 3, &img) != LOOM_OK)
		cli_fail(prog, "out of memory for the assignment map");
	for (uint32_t u = 0; u < n_ex; u++) {
		loom_db_exemplar_info e;
		loom_db_exemplar(db, u, &e);
		ncols[u] = e.cols;
		nblk[u] = e.rows * e.cols;
	}
	for (uint32_t i = 0; i < h; i++)
		for (uint32_t j = 0; j < w; j++) {
			loom_fabric_source src;
			uint8_t rgb[3];
			double v;
			loom_fabric_source_at(f, i, j, &src);
			v = 0.30 + 0.70 * (double)(src.row * ncols[src.exemplar] + src.col + 1) /
			               (double)nblk[src.exemplar];
			/* golden-ratio hues: neighbouring exemplar indices differ */
			hsv(fmod(0.61803398875 * src.exemplar, 1.0), 0.80, v, rgb);
			fill_cell(img, j * s, i * s, s, rgb);
		}
	if (loom_image_write(path, img, diag) != LOOM_OK)
		cli_fail(prog, "%s", diag->message);
	loom_image_free(img);
	free(ncols);
	free(nblk);
	drawn[0] = h;
	drawn[1] = w;
	drawn[2] = s;
}

/* Colour ramp for t in [0, 1]: black, blue, magenta, orange, pale yellow. */
static void ramp(double t, uint8_t *rgb)
{
	static const double stop[5][3] = {{0, 0, 0}, {40, 40, 200}, {200, 40, 160},
	                                  {250, 140, 30}, {255, 255, 200}};
	double x;
	int k;
	if (!(t > 0))
		t = 0;
	if (t > 1)
		t = 1;
	x = t * 4;
	k = x >= 4 ? 3 : (int)x;
	x -= k;
	for (int c = 0; c < 3; c++)
		rgb[c] = (uint8_t)lround(stop[k][c] + (stop[k + 1][c] - stop[k][c]) * x);
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* 99th percentile of the before jumps (S and E) of n cells. */
static double p99_before(const double *v, size_t n)
{
	double *b = malloc(sizeof(double) * 2 * n), r;
	if (!b)
		return 0;
	for (size_t k = 0; k < n; k++) {
		b[2 * k] = v[4 * k];
		b[2 * k + 1] = v[4 * k + 2];
	}
	qsort(b, 2 * n, sizeof *b, cmp_double);
	r = b[(size_t)(0.99 * (double)(2 * n - 1))];
	free(b);
	return r;
}

/* Before | after, each cell: interior = mean of its S and E jumps, bottom row
   = S jump, right column = E jump; a ramp strip below.  The ramp spans 0 ..
   the 99th percentile of the before jumps (returned). */
static double seam_map(const char *prog, const loom_fabric *f, const char *path,
                       uint32_t *drawn, loom_diag *diag)
{
	const loom_design *d = loom_fabric_design(f);
	/* the bolt around the first repeat: at least 64, at most 256 a side */
	uint32_t h = d->rows < SEAM_MAP_MIN ? SEAM_MAP_MIN
	             : d->rows < SEAM_MAP_MAX ? d->rows : SEAM_MAP_MAX;
	uint32_t w = d->cols < SEAM_MAP_MIN ? SEAM_MAP_MIN
	             : d->cols < SEAM_MAP_MAX ? d->cols : SEAM_MAP_MAX;
	uint32_t s = scale_for(h, w, 512, 3, 16), gap = 8, strip = 12;
	uint32_t pw = w * s, ph = h * s;
	double *v = malloc(sizeof(double) * 4 * (size_t)h * w), vmax = 0;
	loom_image *img;

	if (!v || loom_image_new(2 * pw + gap, ph + gap + strip, 3, &img) != LOOM_OK)
		cli_fail(prog, "out of memory for the seam map");
	memset(img->pixels, 255, (size_t)img->width * img->height * 3);
	for (uint32_t i = 0; i < h; i++)
		for (uint32_t j = 0; j < w; j++) {
			double *q = v + 4 * ((size_t)i * w + j);
			loom_fabric_seam_block(f, i, j, q);
		}
	vmax = p99_before(v, (size_t)h * w);
	if (!(vmax > 0))
		vmax = 1;
	for (int panel = 0; panel < 2; panel++)
		for (uint32_t i = 0; i < h; i++)
			for (uint32_t j = 0; j < w; j++) {
				const double *q = v + 4 * ((size_t)i * w + j);
				double sj = q[panel], ej = q[2 + panel];
				uint32_t x0 = panel * (pw + gap) + j * s, y0 = i * s;
				uint8_t c[3];
				ramp(0.5 * (sj + ej) / vmax, c);
				fill_cell(img, x0, y0, s, c);
				ramp(sj / vmax, c);
				for (uint32_t x = 0; x < s; x++)
					memcpy(img->pixels + 3 * ((size_t)(y0 + s - 1) * img->width + x0 + x), c, 3);
				ramp(ej / vmax, c);
				for (uint32_t y = 0; y < s; y++)
					memcpy(img->pixels + 3 * ((size_t)(y0 + y) * img->width + x0 + s - 1), c, 3);
			}
	for (uint32_t x = 0; x < img->width; x++) {
		uint8_t c[3];
		ramp((double)x / (img->width - 1), c);
		for (uint32_t y = ph + gap; y < img->height; y++)
			memcpy(img->pixels + 3 * ((size_t)y * img->width + x), c, 3);
	}
	if (loom_image_write(path, img, diag) != LOOM_OK)
		cli_fail(prog, "%s", diag->message);
	loom_image_free(img);
	free(v);
	drawn[0] = h;
	drawn[1] = w;
	drawn[2] = s;
	return vmax;
}

/* ---- output -------------------------------------------------------------------- */

typedef struct run {
	const char *design_path, *db_path, *out;
	const loom_fabric *f;
	const loom_db *db;
	double seconds, t_synth, t_save;
	uint64_t bytes;
	const char *amap, *smap;
	uint32_t adrawn[3], sdrawn[3];
	double smax;
	uint32_t dfloat[2], xfloat[2]; /* longest warp, weft float: design, database */
	int floats;                    /* dfloat, xfloat set (not --identity) */
} run;

static void print_json(const run *r)
{
	const loom_design *d = loom_fabric_design(r->f);
	loom_fabric_params p;
	loom_fabric_db_identity id;
	loom_fabric_metrics m;
	uint64_t crossings = (uint64_t)d->rows * d->cols;
	char hs[32];
	json_w w;

	loom_fabric_get_params(r->f, &p);
	loom_fabric_get_db_identity(r->f, &id);
	loom_fabric_get_metrics(r->f, &m);
	snprintf(hs, sizeof hs, "%016llx", (unsigned long long)id.content_hash);
	jw_begin(&w, stdout);
	jw_str(&w, "design", r->design_path);
	jw_uint(&w, "rows", d->rows);
	jw_uint(&w, "cols", d->cols);
	jw_uint(&w, "crossings", crossings);
	jw_str(&w, "fabric", r->out);
	jw_uint(&w, "fabric_bytes", r->bytes);
	jw_num(&w, "bytes_per_crossing", (double)r->bytes / (double)crossings);
	jw_num(&w, "seconds", r->seconds);
	jw_num(&w, "seconds_synth", r->t_synth);
	jw_num(&w, "seconds_save", r->t_save);
	jw_str(&w, "algo", loom_fabric_algo_name(p.algo));
	jw_uint(&w, "seed", p.seed);
	jw_uint(&w, "group", p.group);
	jw_uint(&w, "rank", p.rank);
	jw_uint(&w, "rank_h", p.rank_h);
	jw_uint(&w, "rank_v", p.rank_v);
	jw_str(&w, "edge_tables", p.edge_stored ? "stored" : "rebuilt at open");
	jw_num(&w, "correctness", m.repeat.correctness);
	jw_num(&w, "consistency", m.repeat.consistency);
	jw_num(&w, "continuity", m.repeat.continuity);
	jw_num(&w, "continuity_v", crossings ? (double)m.repeat.continuous_v / crossings : 0);
	jw_num(&w, "continuity_h", crossings ? (double)m.repeat.continuous_h / crossings : 0);
	jw_uint(&w, "matches", m.repeat.matches);
	jw_uint(&w, "best_matches", m.repeat.best_matches);
	jw_num(&w, "seam_before", m.seam.before_mean);
	jw_num(&w, "seam_after", m.seam.after_mean);
	jw_num(&w, "seam_before_max", m.seam.before_max);
	jw_num(&w, "seam_after_max", m.seam.after_max);
	jw_num(&w, "seam_corner_before", m.seam.corner_before_mean);
	jw_num(&w, "seam_corner_after", m.seam.corner_after_mean);
	jw_num(&w, "internal_step", m.seam.internal_step);
	jw_num(&w, "seam_before_ratio", m.seam.before_ratio);
	jw_num(&w, "seam_after_ratio", m.seam.after_ratio);
	jw_obj(&w, "bolt_window");
	jw_uint(&w, "rows", m.window_rows);
	jw_uint(&w, "cols", m.window_cols);
	jw_num(&w, "correctness", m.bolt.correctness);
	jw_num(&w, "consistency", m.bolt.consistency);
	jw_num(&w, "continuity", m.bolt.continuity);
	jw_uint(&w, "seam_samples", m.seam.samples);
	jw_close(&w);
	jw_obj(&w, "database");
	jw_str(&w, "path", id.path);
	jw_str(&w, "content_hash", hs);
	jw_uint(&w, "exemplars", id.n_exemplars);
	jw_uint(&w, "blocks", id.n_blocks);
	jw_arr(&w, "block");
	jw_uint(&w, NULL, id.block[0]);
	jw_uint(&w, NULL, id.block[1]);
	jw_uint(&w, NULL, id.block[2]);
	jw_close(&w);
	jw_num(&w, "voxel_size_um", id.voxel_size_um);
	jw_close(&w);
	if (r->floats) {
		jw_obj(&w, "longest_float");
		jw_uint(&w, "design_warp", r->dfloat[0]);
		jw_uint(&w, "design_weft", r->dfloat[1]);
		jw_uint(&w, "database_warp", r->xfloat[0]);
		jw_uint(&w, "database_weft", r->xfloat[1]);
		jw_close(&w);
	}
	jw_arr(&w, "usage");
	for (uint32_t u = 0; u < m.n_exemplars; u++) {
		loom_db_exemplar_info e;
		loom_db_exemplar(r->db, u, &e);
		jw_obj(&w, NULL);
		jw_uint(&w, "exemplar", u);
		jw_str(&w, "name", e.name);
		jw_uint(&w, "crossings", m.usage[u]);
		jw_num(&w, "fraction", (double)m.usage[u] / (double)crossings);
		jw_close(&w);
	}
	jw_close(&w);
	if (r->amap) {
		jw_obj(&w, "assignment_map");
		jw_str(&w, "path", r->amap);
		jw_uint(&w, "rows", r->adrawn[0]);
		jw_uint(&w, "cols", r->adrawn[1]);
		jw_uint(&w, "scale", r->adrawn[2]);
		jw_close(&w);
	}
	if (r->smap) {
		jw_obj(&w, "seam_map");
		jw_str(&w, "path", r->smap);
		jw_uint(&w, "rows", r->sdrawn[0]);
		jw_uint(&w, "cols", r->sdrawn[1]);
		jw_uint(&w, "scale", r->sdrawn[2]);
		jw_num(&w, "max_voxels", r->smax);
		jw_close(&w);
	}
	jw_end(&w);
}

static void print_summary(const run *r)
{
	const loom_design *d = loom_fabric_design(r->f);
	loom_fabric_params p;
	loom_fabric_db_identity id;
	loom_fabric_metrics m;
	uint64_t crossings = (uint64_t)d->rows * d->cols;

	loom_fabric_get_params(r->f, &p);
	loom_fabric_get_db_identity(r->f, &id);
	loom_fabric_get_metrics(r->f, &m);
	printf("%s: %ux%u design (%llu crossings), %s, seed %llu, group %u, rank %u\n",
	       r->out, d->rows, d->cols, (unsigned long long)crossings,
	       loom_fabric_algo_name(p.algo), (unsigned long long)p.seed, p.group, p.rank);
	printf("  database %s (%016llx): %u exemplars, %u blocks of %ux%ux%u voxels\n",
	       id.path, (unsigned long long)id.content_hash, id.n_exemplars, id.n_blocks,
	       id.block[0], id.block[1], id.block[2]);
	printf("  correctness %.3f  consistency %.3f  continuity %.3f (vertical %.3f, "
	       "horizontal %.3f)\n", m.repeat.correctness, m.repeat.consistency,
	       m.repeat.continuity, (double)m.repeat.continuous_v / crossings,
	       (double)m.repeat.continuous_h / crossings);
	printf("  bolt %llux%llu after randomisation: consistency %.3f, continuity %.3f\n",
	       (unsigned long long)m.window_rows, (unsigned long long)m.window_cols,
	       m.bolt.consistency, m.bolt.continuity);
	printf("  seams %.3f -> %.3f voxels (internal step %.3f: %.2fx -> %.2fx; "
	       "corners %.3f -> %.3f)\n", m.seam.before_mean, m.seam.after_mean,
	       m.seam.internal_step, m.seam.before_ratio, m.seam.after_ratio,
	       m.seam.corner_before_mean, m.seam.corner_after_mean);
	if (r->floats)
		printf("  longest floats: warp %u, weft %u crossings (database: warp %u, weft %u)\n",
		       r->dfloat[0], r->dfloat[1], r->xfloat[0], r->xfloat[1]);
	printf("  usage:");
	for (uint32_t u = 0; u < m.n_exemplars; u++) {
		loom_db_exemplar_info e;
		loom_db_exemplar(r->db, u, &e);
		printf(" %s %.1f%%", e.name, 100.0 * (double)m.usage[u] / (double)crossings);
	}
	printf("\n  %llu bytes (%.3f per crossing), edge tables %s, %.3f s\n",
	       (unsigned long long)r->bytes, (double)r->bytes / (double)crossings,
	       p.edge_stored ? "stored" : "rebuilt at open", r->seconds);
	if (r->amap)
		printf("  assignment map %s (%ux%u crossings, %u px each)\n", r->amap,
		       r->adrawn[0], r->adrawn[1], r->adrawn[2]);
	if (r->smap)
		printf("  seam map %s (%ux%u crossings, %u px each, ramp 0..%.3f voxels)\n",
		       r->smap, r->sdrawn[0], r->sdrawn[1], r->sdrawn[2], r->smax);
}

/* ---- --yarn-fibre TYPE=F ------------------------------------------------------------ */

typedef struct yarn_fibres {
	uint32_t n;
	const char *spec[LOOM_MAX_YARN_TYPES]; /* "TYPE=F" as given */
} yarn_fibres;

static const char *opt_yarn_fibre(const char *text, void *dest)
{
	yarn_fibres *y = dest;
	const char *eq = strrchr(text, '=');
	int code;

	if (!eq || eq == text || loom_fibre_parse(eq + 1, &code) != LOOM_OK)
		return "TYPE=F: a yarn type (name or index) and a fibre: cotton, rayon, "
		       "silk, polyester, wool, linen, monofilament or none";
	if (y->n == LOOM_MAX_YARN_TYPES)
		return "at most 256 of them";
	y->spec[y->n++] = text;
	return NULL;
}

/* Set the materials --yarn-fibre names.  A type d does not have is a usage
   error: the message goes to err (n bytes) and 0 is returned, so that the
   caller frees d before exiting (LeakSanitizer would turn exit 2 into 1). */
static int apply_yarn_fibres(loom_design *d, const yarn_fibres *y, char *err,
                             size_t n)
{
	for (uint32_t i = 0; i < y->n; i++) {
		const char *eq = strrchr(y->spec[i], '=');
		size_t len = (size_t)(eq - y->spec[i]);
		uint32_t t = d->n_types;
		int code = 0;
		loom_fibre_parse(eq + 1, &code);
		for (uint32_t k = 0; k < d->n_types; k++)
			if (strlen(d->types[k].name) == len &&
			    !memcmp(d->types[k].name, y->spec[i], len))
				t = k;
		if (t == d->n_types && len > 0 && len < 4 &&
		    strspn(y->spec[i], "0123456789") == len) {
			unsigned long v = strtoul(y->spec[i], NULL, 10);
			if (v < d->n_types)
				t = (uint32_t)v;
		}
		if (t == d->n_types) {
			char names[512];
			size_t w = 0;
			names[0] = '\0';
			for (uint32_t k = 0; k < d->n_types && w < sizeof names; k++)
				w += (size_t)snprintf(names + w, sizeof names - w, "%s%u '%s'",
				                      k ? ", " : "", k, d->types[k].name);
			snprintf(err, n, "--yarn-fibre %s: the design has no yarn type '%.*s' "
			         "(its types: %s)", y->spec[i], (int)len, y->spec[i], names);
			return 0;
		}
		d->types[t].fibre = (uint8_t)code;
	}
	return 1;
}

/* ---- the command ----------------------------------------------------------------- */

int cmd_synth(int argc, char **argv)
{
	const char *prog = "loom synth";
	const char *in = NULL, *out = NULL, *db_opt = NULL, *map = NULL;
	const char *warp = NULL, *weft = NULL, *amap = NULL, *smap = NULL;
	const char *fibre = NULL;
	yarn_fibres yf = {0, {NULL}};
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	int quiet = 0, json = 0, progress, edge = LOOM_FABRIC_EDGE_AUTO, edge_fix = 1;
	int identity = 0;
	loom_design *d;
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_diag diag;
	run r;
	double t0;
	opt_entry opts[] = {
		OPT_OUTPUT(&out, "FABRIC", "fabric file to write (.loomf), atomically"),
		OPT_DB(&db_opt, "exemplar database (default: $LOOM_DB, then, for a draft "
		       "that states its sett, a database generated for that sett and "
		       "cached in $LOOM_CACHE_DIR or $XDG_CACHE_HOME/loom, then "
		       "default.ldb in the data directory)"),
		OPT_STRING(0, "fibre", &fibre, "F[,F]", "yarns of the generated database, warp "
		           "and weft (one name: both): cotton (default), rayon, silk, "
		           "polyester, wool, linen, monofilament or none (smooth); a "
		           "database for the draft's sett (or the small preset's when it "
		           "states none) with these yarns is made and cached"),
		OPT_CALLBACK(0, "yarn-fibre", &yf, "TYPE=F", opt_yarn_fibre, "material of "
		             "one yarn type of the design (its name in the yarn table, as "
		             "loom pattern info lists it, or its index), repeatable; F as "
		             "--fibre; types not named take --fibre's (cotton).  Without "
		             "--db, a design of several (warp, weft) pairs gets a "
		             "database with exemplars of each pair (at most 4), and each "
		             "crossing copies blocks of its own pair (docs/exemplars.md)"),
		OPT_ENUM(0, "algo", &o.algo, "A", algo_names, "dp (default), greedy or naive"),
		OPT_SEED(&o.seed, "N", "random seed (default 1)"),
		OPT_U32(0, "rank", &o.rank, "R", 0, LOOM_EDGEFIX_MAX_RANK,
		        "edge-fix rank, %r (default 128: each side at its whole profile's "
		        "rank, the exact fix; 0 = no edge fix; 15 = the smaller tables of "
		        "the default before 2026-12-07)"),
		OPT_ENUM(0, "edge-fix", &edge_fix, "on|off|full", edge_fix_names, "on "
		         "(default: rank --rank), off: no edge fix, the same as --rank 0 (to "
		         "see what the fix does), or full: the exact fix, every edge "
		         "sample matched (the rank of each side's whole profile, the "
		         "default; closest to the woven cloth's seams: docs/fidelity.md)"),
		OPT_U32(0, "group", &o.group, "M", 0, 65536, "randomisation group side m^, %r "
		        "(default 3; 0 = no randomisation)"),
		OPT_FLAG(0, "identity", &identity, "copy the ground truth block by block: "
		         "crossing (i, j) takes block (i, j) of exemplar 0 of DB (the ground "
		         "truth loom exemplar generate makes of DESIGN), no randomisation, no edge fix "
		         "(docs/fidelity.md)"),
		OPT_STRING(0, "map", &map, "MAPFILE", "DESIGN is a posterized image: map its "
		           "colours to weaves and yarns (docs/designs.md)"),
		OPT_STRING(0, "warp-map", &warp, "FILE",
		           "warp-type map, one grey pixel per crossing"),
		OPT_STRING(0, "weft-map", &weft, "FILE", "weft-type map"),
		OPT_ENUM(0, "edge-tables", &edge, "HOW", edge_names, "auto (default: store the "
		         "tables when they take at most 1.5 MiB), store, or rebuild (at open)"),
		OPT_STRING(0, "assignment-map", &amap, "PNG", "draw which exemplar (hue) and "
		           "block (brightness) each crossing of the first repeat copies"),
		OPT_STRING(0, "seam-map", &smap, "PNG", "draw the seam jumps before (left) and "
		           "after (right) the edge fix, colour ramp in docs/fabric.md"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_QUIET(&quiet, "no progress or summary"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = "loom synth DESIGN [OPTIONS] -o FABRIC",
	              .about = about, .opts = opts, .pos_name = "DESIGN", .pos_min = 1,
	              .pos_max = 1, .pos = &in};

	opts_parse(&c, argc, argv);
	if (!out)
		opts_usage(&c, "missing -o FABRIC");
	o.edge_storage = (uint32_t)edge;
	if (edge_fix == 2 && opt_given(&c, &o.rank))
		opts_usage(&c, "--edge-fix full sets the rank (every side's whole "
		           "profile): no --rank");
	if (!edge_fix)
		o.rank = 0;
	else if (edge_fix == 2)
		o.rank = LOOM_EDGEFIX_MAX_RANK;
	if (identity) {
		if (opt_given(&c, &o.algo) || (opt_given(&c, &o.rank) && o.rank) ||
		    (opt_given(&c, &o.group) && o.group))
			opts_usage(&c, "--identity copies the ground truth unchanged: no --algo, "
			           "--group or --rank other than 0");
		o.algo = LOOM_SYNTH_IDENTITY;
		o.group = 0;
		o.rank = 0;
	}
	if ((amap && !cli_ends_with(amap, ".png") && !cli_ends_with(amap, ".ppm")) ||
	    (smap && !cli_ends_with(smap, ".png") && !cli_ends_with(smap, ".ppm")))
		opts_usage(&c, "maps are written as .png (or .ppm) files");
	if (fibre && (db_opt || (getenv("LOOM_DB") && *getenv("LOOM_DB"))))
		opts_usage(&c, "--fibre chooses the yarns of a generated database; "
		           "%s names one already made", db_opt ? "--db" : "LOOM_DB");
	if (fibre) {
		/* the names, before any work (the generator's own check) */
		loom_exgen_params fp;
		char fb[64], *fc;
		snprintf(fb, sizeof fb, "%s", fibre);
		fc = strchr(fb, ',');
		if (fc)
			*fc++ = '\0';
		loom_exgen_preset("small", &fp);
		fp.fibre[0] = fb;
		fp.fibre[1] = fc ? fc : fb;
		if (loom_exgen_check_params(&fp, &diag) != LOOM_OK)
			opts_usage(&c, "--fibre: %s", diag.message);
		for (int k = 0; k < 2; k++) {
			int code = 0;
			loom_fibre_parse(fp.fibre[k], &code);
			o.fibre[k] = (uint8_t)code;
		}
	}
	cli_check_output(prog, out);
	if (amap)
		cli_check_output(prog, amap);
	if (smap)
		cli_check_output(prog, smap);
	progress = !quiet && !json && isatty(2);
	cli_diag_init(&diag, &quiet);

	d = synth_load_design(prog, in, map, warp, weft, &diag);
	{
		char err[1024];
		if (!apply_yarn_fibres(d, &yf, err, sizeof err)) {
			loom_design_free(d);
			opts_usage(&c, "%s", err);
		}
	}
	memset(&r, 0, sizeof r);
	{
		const char *env = getenv("LOOM_DB");
		uint8_t pairs[2][2];
		uint32_t np = cli_design_pairs(d, o.fibre, pairs, 2);
		/* materials other than all cotton need a database woven with them */
		int materials = np > 1 || pairs[0][0] != LOOM_FIBRE_COTTON ||
		                pairs[0][1] != LOOM_FIBRE_COTTON;
		/* a sett stated for one side only: square crossings */
		if (!(d->sett[0] > 0))
			d->sett[0] = d->sett[1];
		if (!(d->sett[1] > 0))
			d->sett[1] = d->sett[0];
		if (!db_opt && !(env && *env) && (d->sett[0] > 0 || fibre || materials))
			r.db_path = cli_sett_db(prog, d, fibre, quiet);
		else
			r.db_path = cli_db_require(db_opt, prog);
	}
	if (loom_db_open(r.db_path, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	cli_sett_check(d, db, r.db_path, quiet);
	if (yf.n && !quiet && (db_opt || (getenv("LOOM_DB") && *getenv("LOOM_DB")))) {
		loom_db_info info;
		uint8_t *tag;
		uint32_t np = 0;
		loom_db_get_info(db, &info);
		tag = malloc(info.n_exemplars ? info.n_exemplars : 1);
		for (uint32_t u = 0; tag && u < info.n_exemplars; u++) {
			loom_db_exemplar_info e;
			loom_db_exemplar(db, u, &e);
			tag[u] = (uint8_t)(e.fibre[0] * LOOM_FIBRE_COUNT_ + e.fibre[1]);
			if (tag[u] && !memchr(tag, tag[u], u))
				np++;
		}
		free(tag);
		if (np < 2)
			fprintf(stderr, "loom synth: warning: --yarn-fibre: %s has exemplars of "
			        "one material pair, so every crossing copies from all of them "
			        "(omit --db to weave a database of the design's pairs)\n",
			        r.db_path);
	}
	if (!identity)
		r.floats = cli_float_check(prog, d, db, quiet, r.dfloat, r.xfloat);
	if (progress)
		fprintf(stderr, "%s: %ux%u crossings: assigning, edge-fix tables...", prog,
		        d->rows, d->cols);
	t0 = now_s();
	if (loom_fabric_synthesize(d, db, r.db_path, &o, &f, &diag) != LOOM_OK)
		cli_fail(prog, "%s%s", progress ? "\n" : "", diag.message);
	r.t_synth = now_s() - t0;
	loom_design_free(d);
	if (progress)
		fprintf(stderr, " writing...");
	if (loom_fabric_save(f, out, &r.bytes, &diag) != LOOM_OK)
		cli_fail(prog, "%s%s", progress ? "\n" : "", diag.message);
	r.seconds = now_s() - t0;
	r.t_save = r.seconds - r.t_synth;
	if (progress)
		fprintf(stderr, " done (%.2f s)\n", r.seconds);
	r.design_path = in;
	r.out = out;
	r.f = f;
	r.db = db;
	if (amap) {
		assignment_map(prog, f, db, amap, r.adrawn, &diag);
		r.amap = amap;
	}
	if (smap) {
		r.smax = seam_map(prog, f, smap, r.sdrawn, &diag);
		r.smap = smap;
	}
	if (json)
		print_json(&r);
	else if (!quiet)
		print_summary(&r);
	loom_fabric_free(f);
	loom_db_close(db);
	return 0;
}
