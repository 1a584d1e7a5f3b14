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
   messages ("name:line: ...").  Yarn types come from warp/weft colours. */
LOOM_API int loom_wif_parse(const char *text, size_t len, const char *name,
                            loom_design **out, loom_diag *diag);
/* Read and parse a WIF file. */
LOOM_API int loom_wif_read(const char *path, loom_design **out, loom_diag *diag);

/* ---- Images ------------------------------------------------------------ */

/* An 8-bit image: 1 channel (grey) or 3 channels (RGB), rows top to bottom. */
typedef struct loom_image {
	uint32_t width, height;
	uint32_t channels;     /* 1 or 3 */
	uint8_t *pixels;       /* width*height*channels bytes */
	int bilevel;           /* 1 when read from a PBM (0/1 data, 1 = black) */
} loom_image;

LOOM_API int loom_image_new(uint32_t width, uint32_t height, uint32_t channels,
                            loom_image **out);
LOOM_API void loom_image_free(loom_image *img);

/* Read PBM (P1, P4), PGM (P2, P5), PPM (P3, P6) or PNG (any colour type,
   palette expanded, 16-bit reduced to 8).  Format chosen by content.
   PBM pixels are returned as 1 channel, 255 = white, 0 = black. */
LOOM_API int loom_image_read(const char *path, loom_image **out, loom_diag *diag);
LOOM_API int loom_image_parse(const uint8_t *data, size_t len, const char *name,
                              loom_image **out, loom_diag *diag);

/* Write as PNG, or as PNM (PGM/PPM binary) by the path's extension
   (.png, .pgm, .ppm, .pnm).  Atomic. */
LOOM_API int loom_image_write(const char *path, const loom_image *img,
                              loom_diag *diag);

/* ---- Designs as files -------------------------------------------------- */

/* Read a weave pattern: .wif (WIF), .pbm, .png, .pgm (dark = warp over;
   a PNG/PGM must be two-level).  Chosen by extension, then content. */
LOOM_API int loom_design_read(const char *path, loom_design **out,
                              loom_diag *diag);

/* Write W as .pbm (P4) or .png (1-bit grey): black = warp over, first row =
   pick 0, first column = end 0.  Chosen by extension.  Atomic. */
LOOM_API int loom_weave_write(const char *path, const loom_design *d,
                              loom_diag *diag);

/* Posterized image to weave (paper 5.2): W(x,y) = V_p(I(x,y))(x,y).
   `map_text` is a mapping file (format in docs/formats.md) assigning each
   colour an elementary weave and warp/weft yarn types. */
LOOM_API int loom_design_from_image(const loom_image *img, const char *map_text,
                                    size_t map_len, const char *map_name,
                                    loom_design **out, loom_diag *diag);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_IO_H */
