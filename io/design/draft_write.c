/*
 * io/design/draft_write.c - pictures of a design for weavers: the colour
 * drawdown (loom_color_drawdown_write) and the classic draft diagram
 * (loom_draft_write), both written row by row through the raster writers
 * (no whole image in memory).
 *
 * Draft layout, as weaving programs print it (end 1 at the left, pick 1 at
 * the top, shaft 1 nearest the drawdown):
 *
 *     [warp colours ]   .          .
 *     [threading    ]   [tie-up ]
 *     [drawdown     ]   [treadling]  [weft colours]
 *
 * sections one cell apart; threading, tie-up and treadling (or liftplan)
 * are black marks on white with a grey grid when cells are 4 px or more;
 * the drawdown is in colour: the warp's colour where the warp is over,
 * the weft's elsewhere.
 */
#include "image_internal.h"
#include "loom/io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DRAFT_MAX_SIDE 16384u /* largest side of a draft picture, pixels */

static uint8_t to_srgb8(float lin)
{
	double c = lin <= 0 ? 0 : lin >= 1 ? 1 : lin;
	c = c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1 / 2.4) - 0.055;
	return (uint8_t)lrint(c * 255.0);
}

/* sRGB colour of every yarn type. */
static void type_colors(const loom_design *d, uint8_t (*rgb)[3])
{
	for (uint32_t t = 0; t < d->n_types && t < 256; t++)
		for (int k = 0; k < 3; k++)
			rgb[t][k] = to_srgb8(d->types[t].albedo[k]);
}

static void cell_color(const loom_design *d, uint8_t (*col)[3], uint32_t i, uint32_t j,
                       uint8_t *out)
{
	size_t p = (size_t)i * d->cols + j;
	uint8_t t = d->weave[p] ? d->warp_type[p] : d->weft_type[p];
	memcpy(out, t < d->n_types ? col[t] : (const uint8_t[3]){128, 128, 128}, 3);
}

/* ---- colour drawdown ---------------------------------------------------- */

typedef struct cd_src {
	const loom_design *d;
	uint32_t cell;
	uint8_t col[256][3];
} cd_src;

static void cd_row(void *user, uint32_t y, uint8_t *row)
{
	cd_src *s = user;
	uint32_t i = y / s->cell;

	for (uint32_t j = 0; j < s->d->cols; j++) {
		uint8_t c[3];
		cell_color(s->d, s->col, i, j, c);
		for (uint32_t k = 0; k < s->cell; k++)
			memcpy(row + 3 * ((size_t)j * s->cell + k), c, 3);
	}
}

LOOM_API int loom_color_drawdown_write(const char *path, const loom_design *d,
                                       uint32_t cell, loom_diag *diag)
{
	loom__raster r;
	cd_src *s;
	int fmt, rc;

	if (!path || !d || !d->weave || d->rows == 0 || d->cols == 0 || cell == 0 ||
	    cell > 64)
		return loom__fail(diag, LOOM_EINVAL, "%s: invalid design, path or cell size",
		                  path ? path : "(null)");
	fmt = loom__path_format(path);
	if (fmt != LOOM__FMT_PNG && fmt != LOOM__FMT_PPM)
		return loom__fail(diag, LOOM_EINVAL, "%s: cannot write a colour drawdown as "
		                  "'%s': expected .png or .ppm", path, loom__path_ext(path));
	if ((uint64_t)d->cols * cell > (1u << 24) || (uint64_t)d->rows * cell > (1u << 24))
		return loom__fail(diag, LOOM_ERANGE, "%s: %u x %u crossings at %u px each is "
		                  "too large a picture", path, d->cols, d->rows, cell);
	s = malloc(sizeof *s);
	if (!s)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	s->d = d;
	s->cell = cell;
	type_colors(d, s->col);
	r.width = d->cols * cell;
	r.height = d->rows * cell;
	r.channels = 3;
	r.bit_depth = 8;
	r.row = cd_row;
	r.user = s;
	rc = loom__raster_save(path, fmt, &r, diag);
	free(s);
	return rc;
}

/* ---- draft diagram ------------------------------------------------------- */

typedef struct dr_src {
	const loom_design *d;
	const loom_draft *dr;
	uint32_t c;            /* cell pixels */
	uint32_t ends, picks;  /* drawn */
	uint32_t S, T;         /* shafts, treadle columns (treadles or shafts) */
	uint32_t y_thr, y_dd;  /* first pixel rows of threading and drawdown */
	uint32_t x_tr, x_wc;   /* first pixel columns of tie-up/treadling, weft colours */
	int grid;
	uint8_t col[256][3];
} dr_src;

static const uint8_t WHITE[3] = {255, 255, 255}, BLACK[3] = {24, 24, 24},
                     GRID[3] = {200, 200, 200}, EMPTY[3] = {255, 255, 255};

/* Fill a cell-aligned section: pixel (px) of cell k at local row (ly). */
static void put_cells(const dr_src *s, uint8_t *row, uint32_t x0, uint32_t n,
                      uint32_t ly, const uint8_t *(*cell)(const dr_src *, uint32_t,
                                                          uint32_t, uint8_t *),
                      uint32_t cy)
{
	for (uint32_t k = 0; k < n; k++) {
		uint8_t buf[3];
		const uint8_t *c = cell(s, cy, k, buf);
		for (uint32_t x = 0; x < s->c; x++) {
			const uint8_t *p = c;
			if (s->grid && (x == 0 || ly == 0 || x == s->c - 1 || ly == s->c - 1) &&
			    c == WHITE)
				p = GRID;
			else if (s->grid && (x == 0 || ly == 0))
				p = GRID;
			memcpy(row + 3 * ((size_t)x0 + (size_t)k * s->c + x), p, 3);
		}
	}
}

/* Section cells: (cy = cell row in the section, k = cell column). */
static const uint8_t *warp_strip(const dr_src *s, uint32_t cy, uint32_t k, uint8_t *b)
{
	uint8_t t = s->d->warp_type[k];
	(void)cy;
	memcpy(b, t < s->d->n_types ? s->col[t] : GRID, 3);
	return b;
}

static const uint8_t *weft_strip(const dr_src *s, uint32_t cy, uint32_t k, uint8_t *b)
{
	uint8_t t = s->d->weft_type[(size_t)cy * s->d->cols];
	(void)k;
	memcpy(b, t < s->d->n_types ? s->col[t] : GRID, 3);
	return b;
}

/* threading: section row cy is shaft S - 1 - cy (shaft 1 at the bottom) */
static const uint8_t *thread_cell(const dr_src *s, uint32_t cy, uint32_t k, uint8_t *b)
{
	(void)b;
	return s->dr->threading[k] == s->S - 1 - cy ? BLACK : WHITE;
}

static const uint8_t *tieup_cell(const dr_src *s, uint32_t cy, uint32_t k, uint8_t *b)
{
	uint32_t shaft = s->S - 1 - cy;
	(void)b;
	if (s->dr->treadles)
		return s->dr->tieup[(size_t)shaft * s->dr->treadles + k] ? BLACK : WHITE;
	return shaft == k ? BLACK : WHITE; /* liftplan: a direct tie-up */
}

static const uint8_t *tread_cell(const dr_src *s, uint32_t cy, uint32_t k, uint8_t *b)
{
	(void)b;
	if (s->dr->treadles)
		return s->dr->treadling[cy] == k ? BLACK : WHITE;
	return s->dr->liftplan[(size_t)cy * s->dr->shafts + k] ? BLACK : WHITE;
}

static const uint8_t *down_cell(const dr_src *s, uint32_t cy, uint32_t k, uint8_t *b)
{
	cell_color(s->d, (uint8_t(*)[3])s->col, cy, k, b);
	return b;
}

static void dr_row(void *user, uint32_t y, uint8_t *row)
{
	dr_src *s = user;
	uint32_t c = s->c, W = s->x_wc + c;

	for (uint32_t x = 0; x < W; x++)
		memcpy(row + 3 * (size_t)x, EMPTY, 3);
	if (y < c) {
		put_cells(s, row, 0, s->ends, y, warp_strip, 0);
	} else if (y >= s->y_thr && y < s->y_thr + s->S * c) {
		uint32_t cy = (y - s->y_thr) / c, ly = (y - s->y_thr) % c;
		put_cells(s, row, 0, s->ends, ly, thread_cell, cy);
		put_cells(s, row, s->x_tr, s->T, ly, tieup_cell, cy);
	} else if (y >= s->y_dd) {
		uint32_t cy = (y - s->y_dd) / c, ly = (y - s->y_dd) % c;
		put_cells(s, row, 0, s->ends, ly, down_cell, cy);
		put_cells(s, row, s->x_tr, s->T, ly, tread_cell, cy);
		put_cells(s, row, s->x_wc, 1, ly, weft_strip, cy);
	}
}

LOOM_API int loom_draft_write(const char *path, const loom_design *d,
                              const loom_draft *dr, uint32_t cell,
                              uint32_t max_threads, loom_diag *diag)
{
	loom__raster r;
	dr_src *s;
	uint32_t side;
	int fmt, rc;

	if (!path || !d || !dr || !d->weave || dr->rows != d->rows || dr->cols != d->cols)
		return loom__fail(diag, LOOM_EINVAL, "%s: invalid design or draft",
		                  path ? path : "(null)");
	fmt = loom__path_format(path);
	if (fmt != LOOM__FMT_PNG && fmt != LOOM__FMT_PPM)
		return loom__fail(diag, LOOM_EINVAL, "%s: cannot write a draft as '%s': "
		                  "expected .png or .ppm", path, loom__path_ext(path));
	s = calloc(1, sizeof *s);
	if (!s)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	s->d = d;
	s->dr = dr;
	s->ends = max_threads && d->cols > max_threads ? max_threads : d->cols;
	s->picks = max_threads && d->rows > max_threads ? max_threads : d->rows;
	s->S = dr->shafts;
	s->T = dr->treadles ? dr->treadles : dr->shafts;
	side = s->ends + s->T + 3 > s->picks + s->S + 3 ? s->ends + s->T + 3
	                                                : s->picks + s->S + 3;
	s->c = cell ? cell : 1100 / side;
	if (s->c < 1)
		s->c = 1;
	if (s->c > 16 && !cell)
		s->c = 16;
	if ((uint64_t)side * s->c > DRAFT_MAX_SIDE) {
		rc = loom__fail(diag, LOOM_ERANGE, "%s: a draft of %u ends, %u picks, %u "
		                "shafts and %u treadles at %u px per cell is larger than %u "
		                "px", path, s->ends, s->picks, s->S, s->T, cell ? cell : 1,
		                DRAFT_MAX_SIDE);
		free(s);
		return rc;
	}
	s->grid = s->c >= 4;
	type_colors(d, s->col);
	s->y_thr = 2 * s->c;
	s->y_dd = s->y_thr + (s->S + 1) * s->c;
	s->x_tr = (s->ends + 1) * s->c;
	s->x_wc = s->x_tr + (s->T + 1) * s->c;
	r.width = s->x_wc + s->c;
	r.height = s->y_dd + s->picks * s->c;
	r.channels = 3;
	r.bit_depth = 8;
	r.row = dr_row;
	r.user = s;
	rc = loom__raster_save(path, fmt, &r, diag);
	free(s);
	return rc;
}
