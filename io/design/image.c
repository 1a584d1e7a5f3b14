/*
 * io/design/image.c - the loom_image type, format dispatch and atomic image output.
 *
 * Readers are chosen by content (PNG signature, or 'P' and a digit 1-6 for
 * the Netpbm family), writers by the path's extension.  The format code
 * itself lives in pnm.c and png.c; this file only routes.
 */
#include "image_internal.h"
#include "io/core/file.h"

#include <stdlib.h>
#include <string.h>

LOOM_API int loom_image_new(uint32_t width, uint32_t height, uint32_t channels,
                            loom_image **out)
{
	loom_image *img;
	size_t n;

	if (!out)
		return LOOM_EINVAL;
	*out = NULL;
	if (width == 0 || height == 0 || (channels != 1 && channels != 3))
		return LOOM_EINVAL;
	if (!loom__mul_ok(width, height, &n) || !loom__mul_ok(n, channels, &n))
		return LOOM_ERANGE;
	img = calloc(1, sizeof *img);
	if (!img)
		return LOOM_ENOMEM;
	img->pixels = calloc(n, 1);
	if (!img->pixels) {
		free(img);
		return LOOM_ENOMEM;
	}
	img->width = width;
	img->height = height;
	img->channels = channels;
	*out = img;
	return LOOM_OK;
}

LOOM_API void loom_image_free(loom_image *img)
{
	if (!img)
		return;
	free(img->pixels);
	free(img->palette);
	free(img);
}

/* ---- reading ------------------------------------------------------------ */

int loom__image_parse_ex(const uint8_t *data, size_t len, const char *name,
                         unsigned flags, loom_image **out, loom_diag *diag)
{
	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "NULL output");
	*out = NULL;
	if (!name)
		name = "(image)";
	if (!data && len)
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL data", name);
	if (loom__is_png(data, len))
		return loom__png_parse(data, len, name, flags, out, diag);
	if (len >= 2 && data[0] == 'P' && data[1] >= '1' && data[1] <= '6')
		return loom__pnm_parse(data, len, name, flags, out, diag);
	if (len == 0)
		return loom__fail(diag, LOOM_ETRUNCATED, "%s: empty file, expected a "
		                  "PBM, PGM, PPM or PNG image", name);
	return loom__fail(diag, LOOM_EFORMAT, "%s: not a PBM, PGM, PPM or PNG "
	                  "image (starts with bytes 0x%02x 0x%02x; expected 'P1'..'P6' "
	                  "or the PNG signature)", name, data[0],
	                  len > 1 ? data[1] : 0);
}

int loom__image_head(const uint8_t *head, size_t n, const char *path,
                     loom_diag *diag)
{
	if (n == 0 || loom__is_png(head, n) ||
	    (n >= 2 && head[0] == 'P' && head[1] >= '1' && head[1] <= '6') ||
	    (n < 8 && !memcmp(head, "\x89PNG\r\n\x1a\n", n)) ||
	    (n == 1 && head[0] == 'P'))
		return LOOM_OK; /* empty or short: the parser says what is wrong */
	return loom__fail(diag, LOOM_EFORMAT, "%s: not a PBM, PGM, PPM or PNG "
	                  "image (starts with bytes 0x%02x 0x%02x; expected "
	                  "'P1'..'P6' or the PNG signature)", path, head[0],
	                  n > 1 ? head[1] : 0);
}

int loom__image_read_ex(const char *path, unsigned flags, loom_image **out,
                        loom_diag *diag)
{
	uint8_t *data;
	size_t len;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "NULL output");
	*out = NULL;
	if (!path)
		return loom__fail(diag, LOOM_EINVAL, "NULL path");
	rc = loom__read_file_checked(path, LOOM__IMAGE_MAX_FILE_BYTES, "image",
	                             loom__image_head, &data, &len, diag);
	if (rc)
		return rc;
	rc = loom__image_parse_ex(data, len, path, flags, out, diag);
	free(data);
	return rc;
}

LOOM_API int loom_image_parse(const uint8_t *data, size_t len, const char *name,
                              loom_image **out, loom_diag *diag)
{
	return loom__image_parse_ex(data, len, name, 0, out, diag);
}

LOOM_API int loom_image_read(const char *path, loom_image **out, loom_diag *diag)
{
	return loom__image_read_ex(path, 0, out, diag);
}

/* ---- writing ------------------------------------------------------------ */

const char *loom__path_ext(const char *path)
{
	const char *slash = strrchr(path, '/');
	const char *dot = strrchr(path, '.');

	if (!dot || (slash && dot < slash) || dot == path || dot[-1] == '/')
		return "";
	return dot;
}

int loom__path_format(const char *path)
{
	static const struct {
		const char *ext;
		int fmt;
	} table[] = {
		{".pbm", LOOM__FMT_PBM}, {".pgm", LOOM__FMT_PGM},
		{".ppm", LOOM__FMT_PPM}, {".pnm", LOOM__FMT_PNM},
		{".png", LOOM__FMT_PNG}, {".wif", LOOM__FMT_WIF},
	};
	const char *ext = loom__path_ext(path);

	for (size_t k = 0; k < sizeof table / sizeof table[0]; k++)
		if (loom__strieq(ext, table[k].ext))
			return table[k].fmt;
	return LOOM__FMT_UNKNOWN;
}

int loom__raster_save(const char *path, int fmt, const loom__raster *r,
                      loom_diag *diag)
{
	loom__atomic a;
	int rc;

	rc = loom__atomic_open(&a, path, diag);
	if (rc)
		return rc;
	if (fmt == LOOM__FMT_PNG)
		rc = loom__png_write(a.fp, r, path, diag);
	else
		rc = loom__pnm_write(a.fp, r, path, diag);
	if (rc) {
		loom__atomic_abort(&a);
		return rc;
	}
	return loom__atomic_commit(&a, diag);
}

/* Row sources over a loom_image. */
static void row_bytes(void *user, uint32_t y, uint8_t *row)
{
	const loom_image *img = user;
	size_t n = (size_t)img->width * img->channels;
	memcpy(row, img->pixels + (size_t)y * n, n);
}

static uint8_t luma(const loom_image *img, size_t k)
{
	const uint8_t *p = img->pixels + k * img->channels;
	if (img->channels == 1)
		return p[0];
	return (uint8_t)((299u * p[0] + 587u * p[1] + 114u * p[2] + 500u) / 1000u);
}

/* 1-bit rows; PBM wants 1 = black, PNG grey wants 1 = white. */
static void row_bits(const loom_image *img, uint32_t y, uint8_t *row, int one_is_black)
{
	size_t base = (size_t)y * img->width;
	memset(row, 0, (img->width + 7) / 8);
	for (uint32_t x = 0; x < img->width; x++) {
		int black = luma(img, base + x) < 128;
		if (black == one_is_black)
			row[x >> 3] |= (uint8_t)(0x80u >> (x & 7));
	}
}

static void row_bits_pbm(void *user, uint32_t y, uint8_t *row)
{
	row_bits(user, y, row, 1);
}

static void row_bits_png(void *user, uint32_t y, uint8_t *row)
{
	row_bits(user, y, row, 0);
}

/* Grey expanded to RGB for .ppm output of a 1-channel image. */
static void row_grey_to_rgb(void *user, uint32_t y, uint8_t *row)
{
	const loom_image *img = user;
	const uint8_t *src = img->pixels + (size_t)y * img->width;
	for (uint32_t x = 0; x < img->width; x++)
		row[3 * x] = row[3 * x + 1] = row[3 * x + 2] = src[x];
}

/* Fill r for writing img as fmt; LOOM_EINVAL if the pairing is impossible. */
static int image_raster(const loom_image *img, int fmt, const char *path,
                        loom__raster *r, loom_diag *diag)
{
	r->width = img->width;
	r->height = img->height;
	r->user = (void *)img;
	r->channels = img->channels;
	r->bit_depth = 8;
	r->row = row_bytes;
	if (fmt == LOOM__FMT_PBM || (fmt == LOOM__FMT_PNG && img->bilevel)) {
		r->channels = 1;
		r->bit_depth = 1;
		r->row = fmt == LOOM__FMT_PBM ? row_bits_pbm : row_bits_png;
	} else if (fmt == LOOM__FMT_PGM && img->channels != 1) {
		return loom__fail(diag, LOOM_EINVAL, "%s: cannot write an RGB image as "
		                  "PGM (use .ppm, .pnm or .png)", path);
	} else if (fmt == LOOM__FMT_PPM && img->channels == 1) {
		r->channels = 3;
		r->row = row_grey_to_rgb;
	}
	return LOOM_OK;
}

LOOM_API int loom_image_write(const char *path, const loom_image *img,
                              loom_diag *diag)
{
	loom__raster r;
	int fmt, rc;

	if (!path || !img || !img->pixels || img->width == 0 || img->height == 0 ||
	    (img->channels != 1 && img->channels != 3))
		return loom__fail(diag, LOOM_EINVAL, "%s: invalid image or path",
		                  path ? path : "(null)");
	fmt = loom__path_format(path);
	if (fmt == LOOM__FMT_UNKNOWN || fmt == LOOM__FMT_WIF)
		return loom__fail(diag, LOOM_EINVAL, "%s: unknown image extension '%s' "
		                  "(expected .png, .pbm, .pgm, .ppm or .pnm)", path,
		                  loom__path_ext(path));
	rc = image_raster(img, fmt, path, &r, diag);
	if (rc)
		return rc;
	return loom__raster_save(path, fmt, &r, diag);
}
