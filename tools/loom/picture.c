/*
 * tools/loom/picture.c - previews streamed to PNG/EXR files (picture.h).
 *
 * The scale bar: a white bar with a black border at the bottom left, a
 * round length (1, 2 or 5 x 10^k mm) near a quarter of the picture's width,
 * its length written above it in a 3 x 5 pixel font scaled to the bar.
 */
#include "picture.h"

#include "cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

double pic_bar_length(double width_mm, char *label, size_t n)
{
	double target = width_mm / 4, p = pow(10.0, floor(log10(target))), len = p;

	if (!(target > 0)) {
		snprintf(label, n, "?");
		return 0;
	}
	if (5 * p <= target)
		len = 5 * p;
	else if (2 * p <= target)
		len = 2 * p;
	if (len >= 10)
		snprintf(label, n, "%g cm", len / 10);
	else if (len >= 1)
		snprintf(label, n, "%g mm", len);
	else
		snprintf(label, n, "%g um", len * 1000);
	return len;
}

/* 5-row glyphs of 3 (5 for m) columns; bit (w - 1) is the left column. */
static const struct glyph {
	char c;
	uint8_t w;
	uint8_t row[5];
} glyphs[] = {
	{'0', 3, {7, 5, 5, 5, 7}}, {'1', 3, {2, 6, 2, 2, 7}}, {'2', 3, {7, 1, 7, 4, 7}},
	{'3', 3, {7, 1, 7, 1, 7}}, {'4', 3, {5, 5, 7, 1, 1}}, {'5', 3, {7, 4, 7, 1, 7}},
	{'6', 3, {7, 4, 7, 5, 7}}, {'7', 3, {7, 1, 1, 1, 1}}, {'8', 3, {7, 5, 7, 5, 7}},
	{'9', 3, {7, 5, 7, 1, 7}}, {'.', 3, {0, 0, 0, 0, 2}}, {'c', 3, {0, 0, 7, 4, 7}},
	{'m', 5, {0, 0, 26, 21, 21}}, {'u', 3, {0, 0, 5, 5, 7}}, {' ', 2, {0, 0, 0, 0, 0}},
};

static void put(uint8_t *rgb, uint32_t w, uint32_t h, int x, int y, uint8_t v)
{
	if (x < 0 || y < 0 || (uint32_t)x >= w || (uint32_t)y >= h)
		return;
	memset(rgb + 3 * ((size_t)y * w + (size_t)x), v, 3);
}

static void text_pass(uint8_t *rgb, uint32_t w, uint32_t h, int x, int y, int s,
                      const char *text, int outline)
{
	for (; *text; text++) {
		const struct glyph *g = NULL;
		for (size_t k = 0; k < sizeof glyphs / sizeof glyphs[0]; k++)
			if (glyphs[k].c == *text)
				g = &glyphs[k];
		if (!g)
			continue;
		for (int r = 0; r < 5; r++)
			for (int col = 0; col < g->w; col++) {
				if (!(g->row[r] >> (g->w - 1 - col) & 1))
					continue;
				for (int dy = -outline; dy < s + outline; dy++)
					for (int dx = -outline; dx < s + outline; dx++)
						put(rgb, w, h, x + col * s + dx, y + r * s + dy,
						    outline ? 0 : 255);
			}
		x += (g->w + 1) * s;
	}
}

void pic_text(uint8_t *rgb, uint32_t w, uint32_t h, int x, int y, int s,
              const char *text)
{
	text_pass(rgb, w, h, x, y, s, text, 1);
	text_pass(rgb, w, h, x, y, s, text, 0);
}

/* Bar geometry of a W x H picture. */
static void bar_box(const pic_out *p, int *x0, int *x1, int *y0, int *y1, int *s)
{
	int m = p->W / 48 > 4 ? (int)(p->W / 48) : 4;
	int bh = p->H / 90 > 3 ? (int)(p->H / 90) : 3;
	double px = p->bar_mm / p->mm_per_px;

	*x0 = m;
	*x1 = m + (int)lround(px);
	*y1 = (int)p->H - m;
	*y0 = *y1 - bh;
	*s = (int)(p->W / 160) > 2 ? (int)(p->W / 160) : 2;
}

/* Overlay the bar and label on rows [row0, row0 + rows) of an 8-bit band. */
static void draw_bar(const pic_out *p, uint8_t *band, uint32_t row0, uint32_t rows)
{
	int x0, x1, y0, y1, s, ty;
	uint8_t *img;
	uint32_t top, bottom;

	bar_box(p, &x0, &x1, &y0, &y1, &s);
	ty = y0 - 7 * s;
	top = ty - 2 > 0 ? (uint32_t)(ty - 2) : 0;
	bottom = (uint32_t)y1 + 1;
	if (row0 + rows <= top || row0 >= bottom)
		return;
	/* draw into a small scratch picture of the bar's rows, copy what falls
	   in this band */
	img = malloc((size_t)p->W * (bottom - top) * 3);
	if (!img)
		return;
	for (uint32_t y = top; y < bottom; y++) {
		if (y >= row0 && y < row0 + rows)
			memcpy(img + (size_t)(y - top) * p->W * 3,
			       band + (size_t)(y - row0) * p->W * 3, (size_t)p->W * 3);
		else
			memset(img + (size_t)(y - top) * p->W * 3, 128, (size_t)p->W * 3);
	}
	for (int y = y0 - 1; y <= y1; y++)
		for (int x = x0 - 1; x <= x1; x++) {
			int edge = y == y0 - 1 || y == y1 || x == x0 - 1 || x == x1;
			put(img, p->W, bottom - top, x, y - (int)top, edge ? 0 : 255);
		}
	pic_text(img, p->W, bottom - top, x0, ty - (int)top, s, p->bar_label);
	for (uint32_t y = top; y < bottom; y++)
		if (y >= row0 && y < row0 + rows)
			memcpy(band + (size_t)(y - row0) * p->W * 3,
			       img + (size_t)(y - top) * p->W * 3, (size_t)p->W * 3);
	free(img);
}

int pic_open(pic_out *p, uint32_t W, uint32_t H, loom_diag *diag)
{
	static const loom_exr_channel rgb_ch[3] = {
		{"R", LOOM_EXR_FLOAT}, {"G", LOOM_EXR_FLOAT}, {"B", LOOM_EXR_FLOAT}};
	static const loom_exr_channel h_ch[1] = {{"height", LOOM_EXR_FLOAT}};
	loom_exr_options eo = LOOM_EXR_OPTIONS_INIT;
	int rc;

	p->W = W;
	p->H = H;
	p->diag = diag;
	p->png = p->hpng = NULL;
	p->exr = p->hexr = NULL;
	p->row8 = NULL;
	p->rowf = NULL;
	p->cap_px = 0;
	p->bar_mm = 0;
	if (p->scale_bar && p->mm_per_px > 0)
		p->bar_mm = pic_bar_length(p->mm_per_px * W, p->bar_label, sizeof p->bar_label);
	if (cli_ends_with(p->path, ".exr"))
		rc = loom_exr_writer_open(p->path, W, H, rgb_ch, 3, &eo, &p->exr, diag);
	else
		rc = loom_png_writer_open(p->path, W, H, 3, &p->png, diag);
	if (rc == LOOM_OK && p->height_path) {
		if (cli_ends_with(p->height_path, ".exr"))
			rc = loom_exr_writer_open(p->height_path, W, H, h_ch, 1, &eo, &p->hexr,
			                          diag);
		else
			rc = loom_png_writer_open(p->height_path, W, H, 1, &p->hpng, diag);
	}
	if (rc != LOOM_OK)
		pic_abort(p);
	return rc;
}

int pic_band(void *user, const loom_preview_band *b)
{
	pic_out *p = user;
	size_t n = (size_t)b->rows * b->width;
	int rc;

	if (n > p->cap_px) {
		free(p->row8);
		free(p->rowf);
		p->row8 = malloc(n * 3);
		p->rowf = malloc(n * 3 * sizeof(float));
		p->cap_px = p->row8 && p->rowf ? n : 0;
		if (!p->cap_px) {
			if (p->diag)
				snprintf(p->diag->message, sizeof p->diag->message,
				         "%s: out of memory for a band of %u rows", p->path, b->rows);
			return LOOM_ENOMEM;
		}
	}
	if (p->exr) {
		memcpy(p->rowf, b->rgb, n * 3 * sizeof(float));
		if (p->bar_mm > 0) {
			/* the bar drawn in 8 bits, copied back where it is pure */
			loom_render_to_srgb8(b->rgb, n, 0, p->row8);
			draw_bar(p, p->row8, b->row0, b->rows);
			for (size_t k = 0; k < n * 3; k++)
				if (p->row8[k] == 0 || p->row8[k] == 255)
					p->rowf[k] = p->row8[k] ? 1.0f : 0.0f;
		}
		rc = loom_exr_writer_put_rows(p->exr, p->rowf, b->rows, p->diag);
	} else {
		loom_render_to_srgb8(b->rgb, n, p->exposure, p->row8);
		if (p->bar_mm > 0)
			draw_bar(p, p->row8, b->row0, b->rows);
		rc = loom_png_writer_put_rows(p->png, p->row8, b->rows, p->diag);
	}
	if (rc != LOOM_OK)
		return rc;
	if (p->hexr)
		return loom_exr_writer_put_rows(p->hexr, b->height, b->rows, p->diag);
	if (p->hpng) {
		double span = (double)(p->z1 - p->z0);
		for (size_t k = 0; k < n; k++) {
			double v = b->height[k] > 0 ? ((double)b->height[k] - (double)p->z0) / span : 0;
			v = v < 0 ? 0 : v > 1 ? 1 : v;
			p->row8[k] = (uint8_t)(v * 255.0 + 0.5);
		}
		return loom_png_writer_put_rows(p->hpng, p->row8, b->rows, p->diag);
	}
	return LOOM_OK;
}

int pic_finish(pic_out *p)
{
	int rc = LOOM_OK, r2;

	if (p->png)
		rc = loom_png_writer_finish(p->png, p->diag);
	if (p->exr)
		rc = loom_exr_writer_finish(p->exr, p->diag);
	p->png = NULL;
	p->exr = NULL;
	if (p->hpng) {
		r2 = rc == LOOM_OK ? loom_png_writer_finish(p->hpng, p->diag) : LOOM_OK;
		if (rc != LOOM_OK)
			loom_png_writer_abort(p->hpng);
		rc = rc ? rc : r2;
	}
	if (p->hexr) {
		r2 = rc == LOOM_OK ? loom_exr_writer_finish(p->hexr, p->diag) : LOOM_OK;
		if (rc != LOOM_OK)
			loom_exr_writer_abort(p->hexr);
		rc = rc ? rc : r2;
	}
	p->hpng = NULL;
	p->hexr = NULL;
	free(p->row8);
	free(p->rowf);
	p->row8 = NULL;
	p->rowf = NULL;
	return rc;
}

void pic_abort(pic_out *p)
{
	loom_png_writer_abort(p->png);
	loom_png_writer_abort(p->hpng);
	loom_exr_writer_abort(p->exr);
	loom_exr_writer_abort(p->hexr);
	p->png = p->hpng = NULL;
	p->exr = p->hexr = NULL;
	free(p->row8);
	free(p->rowf);
	p->row8 = NULL;
	p->rowf = NULL;
}
