/*
 * loom/io.h - reading and writing designs and images (io/).
 *
 * Every reader takes a path (or a buffer plus a name for messages) and an
 * optional loom_diag; on failure the diag message names the file, the place
 * (line or byte offset) and what was expected.  Every writer writes to a
 * temporary name in the same directory and renames it over the target when
 * complete, so an existing file is never left half-overwritten.
 */
#ifndef LOOM_IO_H
#define LOOM_IO_H

#include "common.h"
#include "design.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- WIF 1.1 (weaving information file) ------------------------------- */

/* Parse WIF text (len bytes, need not be NUL-terminated).  `name` is used in
   messages ("name:line: ...").  Yarn types come from warp/weft colours and
   thicknesses.  Returns LOOM_OK; LOOM_EFORMAT (malformed, or no drawdown
   possible: name:line and what was expected); LOOM_ERANGE (a number or
   size beyond loom's limits, more than 256 yarn types); LOOM_ENOMEM;
   LOOM_EINVAL (NULL out, NULL text with len > 0).  Warnings go to diag. */
LOOM_API int loom_wif_parse(const char *text, size_t len, const char *name,
                            loom_design **out, loom_diag *diag);
/* Read and parse a WIF file: loom_wif_parse's codes plus LOOM_EIO,
   LOOM_ERANGE (a file over the size limit) and LOOM_EINVAL (NULL path). */
LOOM_API int loom_wif_read(const char *path, loom_design **out, loom_diag *diag);

/* ---- Images ------------------------------------------------------------ */

/* An 8-bit image: 1 channel (grey) or 3 channels (RGB), rows top to bottom. */
typedef struct loom_image {
	uint32_t width, height;
	uint32_t channels;     /* 1 or 3 */
	uint8_t *pixels;       /* width*height*channels bytes */
	int bilevel;           /* 1 when read from a PBM or a 1-bit grey PNG
	                          (pixels still 0 = black, 255 = white); set it
	                          to have loom_image_write make a 1-bit PNG */
	uint32_t n_palette;    /* entries of palette (indexed PNG), else 0 */
	uint8_t *palette;      /* n_palette*3 bytes RGB, or NULL; owned; the
	                          pixels are already expanded to RGB */
} loom_image;

/*
 * Allocate a width x height image of `channels` (1 or 3) channels, all
 * pixels 0, no palette.  Returns LOOM_OK, LOOM_EINVAL (NULL out, zero size,
 * other channel counts), LOOM_ERANGE (size overflows), LOOM_ENOMEM; *out is
 * NULL on failure.  Thread-safe.
 */
LOOM_API int loom_image_new(uint32_t width, uint32_t height, uint32_t channels,
                            loom_image **out);
/* Free an image and its palette; NULL is a no-op. */
LOOM_API void loom_image_free(loom_image *img);

/*
 * Read PBM (P1, P4), PGM (P2, P5), PPM (P3, P6) or PNG (any colour type,
 * palette expanded, 16-bit reduced to 8).  Format chosen by content.
 * PBM pixels are returned as 1 channel, 255 = white, 0 = black; PGM/PPM
 * samples are scaled from maxval to 0..255; PNG alpha is ignored.
 * Returns LOOM_OK, LOOM_EFORMAT (not one of these formats, or malformed;
 * diag names the line or byte offset), LOOM_ETRUNCATED (data ending early,
 * an empty file), LOOM_ERANGE (larger than 2^30 pixels, a file over
 * 4 GiB), LOOM_EUNSUPPORTED (an interlaced PNG too large to decode),
 * LOOM_EIO (loom_image_read), LOOM_ENOMEM, LOOM_EINVAL (NULL out or
 * path, NULL data with len > 0).  *out is NULL on failure; free it with
 * loom_image_free.  Thread-safe.
 */
LOOM_API int loom_image_read(const char *path, loom_image **out, loom_diag *diag);
LOOM_API int loom_image_parse(const uint8_t *data, size_t len, const char *name,
                              loom_image **out, loom_diag *diag);

/*
 * Write by the path's extension: .png (1-bit grey when img->bilevel, else
 * 8-bit grey or RGB), .pbm (P4; pixels below 128 are black), .pgm (P5),
 * .ppm (P6), .pnm (P5 or P6 by channels).  An RGB image is not written as
 * PGM (LOOM_EINVAL).  Atomic.  Returns LOOM_OK, LOOM_EINVAL, LOOM_EIO.
 */
LOOM_API int loom_image_write(const char *path, const loom_image *img,
                              loom_diag *diag);

/*
 * Streaming PNG writer (8-bit grey or RGB, rows top to bottom), for images
 * too large to hold: open, put the rows in order (any number per call),
 * finish.  Written to a temporary name and renamed by finish; abort (or a
 * finish with rows missing) leaves nothing.  open: LOOM_OK, LOOM_EINVAL
 * (NULL, zero or huge size, channels not 1 or 3), LOOM_EIO, LOOM_ENOMEM.
 * put_rows: LOOM_OK, LOOM_EINVAL, LOOM_ERANGE (more rows than the height),
 * LOOM_EIO, LOOM_EUNUSABLE (after a failure).  finish: LOOM_OK,
 * LOOM_ETRUNCATED (rows missing), LOOM_EIO; it frees the writer whatever
 * it returns.  abort accepts NULL.  One writer per thread.
 */
typedef struct loom_png_writer loom_png_writer;
LOOM_API int loom_png_writer_open(const char *path, uint32_t width, uint32_t height,
                                  uint32_t channels, loom_png_writer **out,
                                  loom_diag *diag);
LOOM_API int loom_png_writer_put_rows(loom_png_writer *w, const uint8_t *pixels,
                                      uint32_t n_rows, loom_diag *diag);
LOOM_API int loom_png_writer_finish(loom_png_writer *w, loom_diag *diag);
LOOM_API void loom_png_writer_abort(loom_png_writer *w);

/* ---- Designs as files -------------------------------------------------- */

/* Read a weave pattern: .wif (WIF), .pbm, .png, .pgm, .ppm, .pnm (dark =
   warp over; an image must be two-level: the darker level is warp over, a
   one-level image is all over when darker than 128).  Chosen by extension,
   else by content.  An image gives the default yarn table and maps of
   loom_design_new.  LOOM_OK; the errors of loom_wif_read or
   loom_image_read; LOOM_EFORMAT (an image with a third level, or two
   levels of equal luma); LOOM_ERANGE (an image beyond the design limits);
   LOOM_EINVAL (NULL).  *out NULL on failure. */
LOOM_API int loom_design_read(const char *path, loom_design **out,
                              loom_diag *diag);

/* Write W as .pbm (P4) or .png (1-bit grey): black = warp over, first row =
   pick 0, first column = end 0.  Chosen by extension.  Atomic.  LOOM_OK;
   LOOM_EINVAL (NULL, empty design, another extension); LOOM_EIO;
   LOOM_ENOMEM. */
LOOM_API int loom_weave_write(const char *path, const loom_design *d,
                              loom_diag *diag);

/*
 * The colour drawdown: one cell of `cell` x `cell` pixels (1..64) per
 * crossing, in the sRGB colour of the warp's yarn type where the warp is
 * over and of the weft's elsewhere; first row = pick 0, first column =
 * end 0.  .png or .ppm (RGB), written row by row, atomic.  LOOM_OK;
 * LOOM_EINVAL (NULL, empty design, bad cell size, another extension);
 * LOOM_ERANGE (a side above 2^24 pixels); LOOM_EIO; LOOM_ENOMEM.
 */
LOOM_API int loom_color_drawdown_write(const char *path, const loom_design *d,
                                       uint32_t cell, loom_diag *diag);

/*
 * The draft diagram of d and its draft dr (loom_draft_from_design) as
 * weaving programs print it: warp colours and threading on top (shaft 1
 * nearest the drawdown), the tie-up to their right, the colour drawdown
 * below with the treadling (or liftplan, beside a direct tie-up) and the
 * weft colours on its right; end 1 at the left, pick 1 at the top.  `cell`
 * pixels per cell (0 = fit about 1100 px, at most 16); at most max_threads
 * ends and picks are drawn (0 = all).  .png or .ppm, atomic.  LOOM_OK;
 * LOOM_EINVAL (NULL, a draft of another size, another extension);
 * LOOM_ERANGE (a side above 16384 pixels); LOOM_EIO; LOOM_ENOMEM.
 */
LOOM_API int loom_draft_write(const char *path, const loom_design *d,
                              const loom_draft *dr, uint32_t cell,
                              uint32_t max_threads, loom_diag *diag);

/*
 * Yarn-type maps as images: one grey pixel per cell, pixel value = type ID
 * (.pgm P5 maxval 255, or .png 8-bit grey), same size as the weave.
 * `which` selects the warp-type or the weft-type map.
 *
 * loom_type_map_write writes d's map atomically; LOOM_OK, LOOM_EINVAL
 * (NULL, unknown extension), LOOM_EIO.
 *
 * loom_type_map_read reads a map into an existing design d, replacing its
 * map.  Any PGM/PNG grey image is accepted, its stored values taken as they
 * are (a PGM with maxval 7 gives IDs 0..7; a 4-bit PNG gives 0..15; an
 * indexed PNG gives its palette indices; a PBM gives 1 for black).  IDs
 * beyond the yarn table extend it with default entries (named "typeK"),
 * with a warning.  Errors: LOOM_EMISMATCH (size differs from the design),
 * LOOM_EFORMAT (colour image, value above 255, malformed), LOOM_EIO,
 * LOOM_ENOMEM; d is unchanged on failure.  Thread-safe on distinct designs.
 */
enum loom_type_map_which {
	LOOM_MAP_WARP = 0,  /* d->warp_type */
	LOOM_MAP_WEFT = 1   /* d->weft_type */
};
LOOM_API int loom_type_map_write(const char *path, const loom_design *d,
                                 int which, loom_diag *diag);
LOOM_API int loom_type_map_read(const char *path, loom_design *d, int which,
                                loom_diag *diag);

/*
 * Posterized image to weave (paper 5.2): W(x,y) = V_p(I(x,y))(x,y), each
 * elementary weave tiled from the image origin (row y = pick y, column
 * x = end x).  `map_text` (map_len bytes, need not be NUL-terminated) is a
 * mapping file, format in docs/designs.md: yarn lines build the yarn table,
 * colour lines assign each image colour (#RRGGBB, grey level or palette
 * index) an elementary weave and warp/weft yarn types.  `map_name` is used
 * in messages ("map_name:line: ...").
 * Errors (LOOM_EFORMAT unless noted): a malformed line (file:line and what
 * was expected), an image colour without a mapping (names the colour and
 * its first pixel); LOOM_ERANGE: more than 64 distinct image colours, more
 * than 256 yarns or too many colour lines in the mapping, a design too
 * large; LOOM_EINVAL: an impossible weave, NULL img or out, an empty
 * image or one with other than 1 or 3 channels, NULL map_text with
 * map_len > 0; LOOM_ENOMEM.  Mapped colours absent from the image are
 * warned about.  *out is NULL on failure.  Thread-safe.
 */
LOOM_API int loom_design_from_image(const loom_image *img, const char *map_text,
                                    size_t map_len, const char *map_name,
                                    loom_design **out, loom_diag *diag);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_IO_H */
