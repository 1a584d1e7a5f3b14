/*
 * tools/loom/picture.h - previews streamed to files (PNG or EXR, with an
 * optional height map and scale bar), band by band as loom_preview_stream
 * makes them, so a picture of any size takes memory for one band only.
 * Used by loom preview, loom look and loom serve.
 */
#ifndef LOOM_PICTURE_H
#define LOOM_PICTURE_H

#include "loom.h"

typedef struct pic_out {
	const char *path;        /* .png (8-bit sRGB) or .exr (linear float RGB) */
	const char *height_path; /* NULL, .png (grey, z0..z1) or .exr (float) */
	double exposure;         /* PNG: stops before the sRGB curve */
	double mm_per_px;        /* > 0 with scale_bar: draw a bar */
	int scale_bar;
	int64_t z0, z1;          /* height map range */
	/* state */
	uint32_t W, H;
	loom_png_writer *png, *hpng;
	loom_exr_writer *exr, *hexr;
	uint8_t *row8;           /* one band as 8-bit */
	float *rowf;             /* one band as float (EXR, scale bar) */
	size_t cap_px;
	loom_diag *diag;
	char bar_label[32];      /* "5 mm" */
	double bar_mm;
} pic_out;

/* Open the writers for a W x H picture.  LOOM_OK or a writer's code
   (message in diag). */
int pic_open(pic_out *p, uint32_t W, uint32_t H, loom_diag *diag);
/* A loom_preview_band_fn: user is the pic_out. */
int pic_band(void *user, const loom_preview_band *b);
/* Finish (LOOM_OK or the writer's code) or abort (nothing left behind). */
int pic_finish(pic_out *p);
void pic_abort(pic_out *p);

/* A round length for a scale bar about a quarter of width_mm: 1, 2 or 5
   times a power of ten, in mm; its label ("5 mm", "2 cm", "500 um"). */
double pic_bar_length(double width_mm, char *label, size_t n);

/* Draw text (digits, '.', ' ', 'c', 'm', 'u') white on a black outline into
   an 8-bit RGB image of width w and height h at (x, y) with pixel size s. */
void pic_text(uint8_t *rgb, uint32_t w, uint32_t h, int x, int y, int s,
              const char *text);

#endif
