/*
 * io/design/image_internal.h - pieces shared by the image and design readers/writers
 * of io/ (image.c, pnm.c, png.c, design_io.c, mapfile.c).  Never installed.
 *
 * Readers share one shape: bytes in memory plus a name for messages, flags,
 * a freshly allocated loom_image out.  Writers take a row callback so that a
 * design can be written without first building an image.
 */
#ifndef LOOM_IO_INTERNAL_H
#define LOOM_IO_INTERNAL_H

#include "core/internal.h"

/* Largest image accepted by the readers, in pixels (a 32768^2 weave fits). */
#define LOOM__IMAGE_MAX_PIXELS (1ull << 30)
/* Largest image file read into memory. */
#define LOOM__IMAGE_MAX_FILE_BYTES ((size_t)1 << 32)

/* Reader flags. */
enum {
	/* Keep sample values as stored, for type maps: PBM gives 1 = black,
	   PGM/PNG grey gives the stored value (error if above 255), an indexed
	   PNG gives its palette indices, low-bit-depth PNG grey is not scaled. */
	LOOM__IMG_RAW = 1
};

/* Parse PBM/PGM/PPM bytes (the caller has checked the 'P' magic). */
int loom__pnm_parse(const uint8_t *data, size_t len, const char *name,
                    unsigned flags, loom_image **out, loom_diag *diag);
/* Parse PNG bytes (the caller has checked the signature). */
int loom__png_parse(const uint8_t *data, size_t len, const char *name,
                    unsigned flags, loom_image **out, loom_diag *diag);
/* 1 if data starts with the PNG signature. */
int loom__is_png(const uint8_t *data, size_t len);
/* Content sniffing plus dispatch, with reader flags. */
int loom__image_parse_ex(const uint8_t *data, size_t len, const char *name,
                         unsigned flags, loom_image **out, loom_diag *diag);
/* Read a file and parse it with loom__image_parse_ex. */
/* loom__head_check of the image readers: PNG signature or 'P1'..'P6' */
int loom__image_head(const uint8_t *head, size_t n, const char *path,
                     loom_diag *diag);
int loom__image_read_ex(const char *path, unsigned flags, loom_image **out,
                        loom_diag *diag);

/*
 * Row source for the writers: fill `row` with row y of the output in the
 * file's own packing (1-bit rows: MSB first, bit 1 = black for PBM but
 * bit 1 = white for PNG grey; 8-bit rows: one byte per sample).
 */
typedef void (*loom__row_fn)(void *user, uint32_t y, uint8_t *row);

typedef struct loom__raster {
	uint32_t width, height;
	uint32_t channels;    /* 1 or 3 */
	uint32_t bit_depth;   /* 1 or 8 */
	loom__row_fn row;     /* produces each row */
	void *user;           /* passed to row */
} loom__raster;

/* Write a binary PNM: P4 (channels 1, depth 1), P5 (1, 8) or P6 (3, 8). */
int loom__pnm_write(FILE *fp, const loom__raster *r, const char *name,
                    loom_diag *diag);
/* Write a PNG: grey 1-bit, grey 8-bit or RGB 8-bit. */
int loom__png_write(FILE *fp, const loom__raster *r, const char *name,
                    loom_diag *diag);

/* Output format chosen by a path's extension (case-insensitive). */
enum loom__fmt {
	LOOM__FMT_UNKNOWN = 0,
	LOOM__FMT_PBM,
	LOOM__FMT_PGM,
	LOOM__FMT_PPM,
	LOOM__FMT_PNM,
	LOOM__FMT_PNG,
	LOOM__FMT_WIF
};
int loom__path_format(const char *path);
/* The extension of path including the dot ("" if none), for messages. */
const char *loom__path_ext(const char *path);

/* Write a raster to path atomically, as PNM or PNG by `fmt`. */
int loom__raster_save(const char *path, int fmt, const loom__raster *r,
                      loom_diag *diag);

/*
 * Turn a two-level image into a weave: the darker level is warp over (1).
 * A single-level image is all over if its level is below 128.  More than
 * two levels is LOOM_EFORMAT naming the first pixel of the third level.
 * `weave` has width*height bytes.
 */
int loom__weave_from_image(const loom_image *img, const char *name,
                           uint8_t *weave, loom_diag *diag);

#endif /* LOOM_IO_INTERNAL_H */
