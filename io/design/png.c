/*
 * io/design/png.c - PNG through libpng 1.6.
 *
 * Reading: any colour type and bit depth.  Palettes are expanded to RGB
 * (the palette itself is kept in loom_image.palette), grey below 8 bits is
 * scaled to 0..255, 16-bit samples are rounded to 8, alpha is dropped.  In
 * raw mode (type maps) stored values are kept: indices, unscaled grey, and
 * 16-bit samples that must fit in 8 bits.
 *
 * Error handling: libpng reports errors by calling our error function,
 * which longjmps back to the setjmp in decode().  Everything that must be
 * freed afterwards lives in a png_ctx owned by the *caller* of decode(), so
 * no local of the function that called setjmp is read after a longjmp
 * (C11 7.13.2.1), and the caller frees it all whatever happened.
 *
 * Memory: a non-interlaced image is decoded row by row into a pixel buffer
 * that grows as rows arrive, so a small file that claims a huge size fails
 * on its missing data, not on a huge allocation.  Interlaced images need
 * the whole decoded image at once and are limited to 256 MiB decoded.
 */
#include "image_internal.h"

#include <png.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>

#define PNG_MAX_SIDE (1u << 24)
#define PNG_MAX_INTERLACED_BYTES ((size_t)256 << 20)

typedef struct png_ctx {
	png_structp png;
	png_infop info;
	const char *name;
	loom_diag *diag;
	unsigned flags;
	int code;              /* result for the next libpng error */
	char msg[200];         /* libpng's last error text */
	const uint8_t *data;   /* reading: the file */
	size_t len, pos;
	FILE *fp;              /* writing: the output */
	uint8_t *buf;          /* decoded row(s) or one row to write */
	loom_image *img;       /* being filled */
	size_t cap_rows;       /* rows allocated in img->pixels */
} png_ctx;

int loom__is_png(const uint8_t *data, size_t len)
{
	return len >= 8 && png_sig_cmp(data, 0, 8) == 0;
}

static void on_error(png_structp png, png_const_charp msg)
{
	png_ctx *c = png_get_error_ptr(png);
	snprintf(c->msg, sizeof c->msg, "%s", msg ? msg : "unknown error");
	png_longjmp(png, 1);
}

static void on_warning(png_structp png, png_const_charp msg)
{
	(void)png; /* benign (e.g. an sRGB profile note): not worth a warning */
	(void)msg;
}

static void on_read(png_structp png, png_bytep out, size_t n)
{
	png_ctx *c = png_get_io_ptr(png);
	if (c->len - c->pos < n) {
		c->code = LOOM_ETRUNCATED;
		png_error(png, "file ends early");
	}
	memcpy(out, c->data + c->pos, n);
	c->pos += n;
}

/* ---- reading ------------------------------------------------------------ */

/* Set transforms and update the info; returns the number of passes. */
static int set_transforms(png_ctx *c)
{
	int passes;
	int depth = png_get_bit_depth(c->png, c->info);
	int type = png_get_color_type(c->png, c->info);

	if (c->flags & LOOM__IMG_RAW) {
		if (depth < 8)
			png_set_packing(c->png);
	} else {
		png_set_expand(c->png);
		if (depth == 16)
			png_set_scale_16(c->png);
		if (type == PNG_COLOR_TYPE_GRAY && depth == 1)
			c->img->bilevel = 1;
	}
	passes = png_set_interlace_handling(c->png);
	png_read_update_info(c->png, c->info);
	return passes;
}

static int keep_palette(png_ctx *c)
{
	png_colorp pal;
	int n = 0;

	if (c->flags & LOOM__IMG_RAW ||
	    png_get_color_type(c->png, c->info) != PNG_COLOR_TYPE_PALETTE ||
	    !png_get_PLTE(c->png, c->info, &pal, &n) || n <= 0)
		return LOOM_OK;
	c->img->palette = malloc((size_t)n * 3);
	if (!c->img->palette)
		return LOOM_ENOMEM;
	for (int k = 0; k < n; k++) {
		c->img->palette[3 * k] = pal[k].red;
		c->img->palette[3 * k + 1] = pal[k].green;
		c->img->palette[3 * k + 2] = pal[k].blue;
	}
	c->img->n_palette = (uint32_t)n;
	return LOOM_OK;
}

/* Convert one decoded row (8 or 16 bits, 1-4 channels) into image row y. */
static int convert_row(png_ctx *c, const uint8_t *src, uint32_t y)
{
	uint32_t w = c->img->width, oc = c->img->channels;
	uint32_t ic = png_get_channels(c->png, c->info);
	int wide = png_get_bit_depth(c->png, c->info) == 16;
	uint8_t *dst = c->img->pixels + (size_t)y * w * oc;

	for (uint32_t x = 0; x < w; x++) {
		for (uint32_t k = 0; k < oc; k++) {
			size_t s = (size_t)x * ic + k;
			unsigned v = wide ? (unsigned)src[2 * s] << 8 | src[2 * s + 1] : src[s];
			if (v > 255)
				return loom__fail(c->diag, LOOM_EFORMAT, "%s: pixel x=%u, "
				                  "y=%u: sample %u is above 255 and cannot be a "
				                  "type ID", c->name, x, y, v);
			dst[(size_t)x * oc + k] = (uint8_t)v;
		}
	}
	return LOOM_OK;
}

/* Make room in img->pixels for rows [0, need). */
static int grow_rows(png_ctx *c, size_t need)
{
	size_t stride = (size_t)c->img->width * c->img->channels, rows, bytes;
	uint8_t *p;

	if (need <= c->cap_rows)
		return LOOM_OK;
	rows = c->cap_rows ? c->cap_rows * 2 : ((size_t)1 << 22) / stride + 1;
	if (rows < need)
		rows = need;
	if (rows > c->img->height)
		rows = c->img->height;
	bytes = rows * stride;
	p = realloc(c->img->pixels, bytes);
	if (!p)
		return loom__fail(c->diag, LOOM_ENOMEM, "%s: out of memory", c->name);
	c->img->pixels = p;
	c->cap_rows = rows;
	return LOOM_OK;
}

static int read_rows(png_ctx *c, int passes)
{
	size_t rowbytes = png_get_rowbytes(c->png, c->info);
	uint32_t h = c->img->height;
	int rc;

	if (passes == 1) {
		c->buf = malloc(rowbytes);
		if (!c->buf)
			return loom__fail(c->diag, LOOM_ENOMEM, "%s: out of memory", c->name);
		for (uint32_t y = 0; y < h; y++) {
			png_read_row(c->png, c->buf, NULL);
			if ((rc = grow_rows(c, (size_t)y + 1)) ||
			    (rc = convert_row(c, c->buf, y)))
				return rc;
		}
		return LOOM_OK;
	}
	if (rowbytes > PNG_MAX_INTERLACED_BYTES / h)
		return loom__fail(c->diag, LOOM_EUNSUPPORTED, "%s: interlaced PNG of "
		                  "%ux%u is too large to decode (limit %zu MiB); save "
		                  "it without interlacing", c->name, c->img->width, h,
		                  PNG_MAX_INTERLACED_BYTES >> 20);
	c->buf = calloc(h, rowbytes);
	if (!c->buf)
		return loom__fail(c->diag, LOOM_ENOMEM, "%s: out of memory", c->name);
	for (int pass = 0; pass < passes; pass++)
		for (uint32_t y = 0; y < h; y++)
			png_read_row(c->png, c->buf + (size_t)y * rowbytes, NULL);
	if ((rc = grow_rows(c, h)))
		return rc;
	for (uint32_t y = 0; y < h; y++)
		if ((rc = convert_row(c, c->buf + (size_t)y * rowbytes, y)))
			return rc;
	return LOOM_OK;
}

/* Everything between png_create_read_struct and png_destroy_read_struct;
   the only function here that calls setjmp. */
static int decode(png_ctx *c)
{
	png_uint_32 w, h;
	int passes, rc;

	if (setjmp(png_jmpbuf(c->png)))
		return c->code;
	png_set_read_fn(c->png, c, on_read);
	png_set_user_limits(c->png, PNG_MAX_SIDE, PNG_MAX_SIDE);
	png_set_chunk_malloc_max(c->png, (png_alloc_size_t)8 << 20);
	png_read_info(c->png, c->info);
	w = png_get_image_width(c->png, c->info);
	h = png_get_image_height(c->png, c->info);
	if ((uint64_t)w * h > LOOM__IMAGE_MAX_PIXELS)
		return loom__fail(c->diag, LOOM_ERANGE, "%s: image size %ux%u is "
		                  "larger than %llu pixels", c->name, w, h,
		                  (unsigned long long)LOOM__IMAGE_MAX_PIXELS);
	c->img = calloc(1, sizeof *c->img);
	if (!c->img)
		return loom__fail(c->diag, LOOM_ENOMEM, "%s: out of memory", c->name);
	c->img->width = w;
	c->img->height = h;
	if (keep_palette(c))
		return loom__fail(c->diag, LOOM_ENOMEM, "%s: out of memory", c->name);
	passes = set_transforms(c);
	c->img->channels = png_get_channels(c->png, c->info) >= 3 ? 3 : 1;
	rc = read_rows(c, passes);
	if (rc)
		return rc;
	png_read_end(c->png, NULL);
	return LOOM_OK;
}

int loom__png_parse(const uint8_t *data, size_t len, const char *name,
                    unsigned flags, loom_image **out, loom_diag *diag)
{
	png_ctx c;
	int rc;

	*out = NULL;
	memset(&c, 0, sizeof c);
	c.name = name;
	c.diag = diag;
	c.flags = flags;
	c.data = data;
	c.len = len;
	c.code = LOOM_EFORMAT;
	c.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &c, on_error,
	                               on_warning);
	if (c.png)
		c.info = png_create_info_struct(c.png);
	if (!c.png || !c.info) {
		png_destroy_read_struct(c.png ? &c.png : NULL, NULL, NULL);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	}
	rc = decode(&c);
	if (rc && c.msg[0])
		loom__fail(diag, rc, "%s: byte %zu: %s PNG: %s", name, c.pos,
		           rc == LOOM_ETRUNCATED ? "truncated" : "malformed", c.msg);
	png_destroy_read_struct(&c.png, &c.info, NULL);
	free(c.buf);
	if (rc) {
		loom_image_free(c.img);
		return rc;
	}
	*out = c.img;
	return LOOM_OK;
}

/* ---- writing ------------------------------------------------------------ */

static void on_write(png_structp png, png_bytep in, size_t n)
{
	png_ctx *c = png_get_io_ptr(png);
	if (fwrite(in, 1, n, c->fp) != n) {
		c->code = LOOM_EIO;
		png_error(png, "write failed");
	}
}

static void on_flush(png_structp png)
{
	(void)png;
}

static int encode(png_ctx *c, const loom__raster *r)
{
	if (setjmp(png_jmpbuf(c->png)))
		return c->code;
	png_set_write_fn(c->png, c, on_write, on_flush);
	png_set_IHDR(c->png, c->info, r->width, r->height, (int)r->bit_depth,
	             r->channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY,
	             PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
	             PNG_FILTER_TYPE_DEFAULT);
	png_write_info(c->png, c->info);
	for (uint32_t y = 0; y < r->height; y++) {
		r->row(r->user, y, c->buf);
		png_write_row(c->png, c->buf);
	}
	png_write_end(c->png, NULL);
	return LOOM_OK;
}

int loom__png_write(FILE *fp, const loom__raster *r, const char *name,
                    loom_diag *diag)
{
	png_ctx c;
	size_t stride;
	int rc;

	if (!((r->bit_depth == 1 && r->channels == 1) ||
	      (r->bit_depth == 8 && (r->channels == 1 || r->channels == 3))))
		return loom__fail(diag, LOOM_EINVAL, "%s: no PNG form for %u channels "
		                  "of %u bits", name, r->channels, r->bit_depth);
	memset(&c, 0, sizeof c);
	c.fp = fp;
	c.code = LOOM_EFORMAT;
	stride = r->bit_depth == 1 ? ((size_t)r->width + 7) / 8
	                           : (size_t)r->width * r->channels;
	c.buf = malloc(stride);
	c.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &c, on_error,
	                                on_warning);
	if (c.png)
		c.info = png_create_info_struct(c.png);
	if (!c.buf || !c.png || !c.info) {
		png_destroy_write_struct(c.png ? &c.png : NULL, NULL);
		free(c.buf);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	}
	rc = encode(&c, r);
	if (rc)
		loom__fail(diag, rc, "%s: PNG write failed: %s", name, c.msg);
	png_destroy_write_struct(&c.png, &c.info);
	free(c.buf);
	return rc;
}

/* ---- streaming writer (loom_png_writer_*, loom/io.h) ---------------------- */

#include "io/core/file.h"

struct loom_png_writer {
	png_ctx c;
	loom__atomic out;
	uint32_t width, height, channels, rows_done;
	char *path;
	int failed;
};

static int start_png(loom_png_writer *w)
{
	png_ctx *c = &w->c;
	if (setjmp(png_jmpbuf(c->png)))
		return c->code;
	png_set_write_fn(c->png, c, on_write, on_flush);
	png_set_IHDR(c->png, c->info, w->width, w->height, 8,
	             w->channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY,
	             PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
	             PNG_FILTER_TYPE_DEFAULT);
	png_write_info(c->png, c->info);
	return LOOM_OK;
}

static int rows_png(loom_png_writer *w, const uint8_t *pixels, uint32_t n)
{
	png_ctx *c = &w->c;
	size_t stride = (size_t)w->width * w->channels;
	if (setjmp(png_jmpbuf(c->png)))
		return c->code;
	for (uint32_t y = 0; y < n; y++)
		png_write_row(c->png, (png_const_bytep)(pixels + (size_t)y * stride));
	return LOOM_OK;
}

static int end_png(loom_png_writer *w)
{
	png_ctx *c = &w->c;
	if (setjmp(png_jmpbuf(c->png)))
		return c->code;
	png_write_end(c->png, NULL);
	return LOOM_OK;
}

LOOM_API int loom_png_writer_open(const char *path, uint32_t width, uint32_t height,
                                  uint32_t channels, loom_png_writer **out,
                                  loom_diag *diag)
{
	loom_png_writer *w;
	int rc;

	if (out)
		*out = NULL;
	if (!path || !out || width == 0 || height == 0 || width > PNG_MAX_SIDE ||
	    height > PNG_MAX_SIDE || (channels != 1 && channels != 3))
		return loom__fail(diag, LOOM_EINVAL, "loom_png_writer_open: bad argument");
	w = calloc(1, sizeof *w);
	if (!w || !(w->path = strdup(path))) {
		free(w);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	w->width = width;
	w->height = height;
	w->channels = channels;
	w->c.name = w->path;
	w->c.code = LOOM_EIO;
	if ((rc = loom__atomic_open(&w->out, path, diag)) != LOOM_OK) {
		free(w->path);
		free(w);
		return rc;
	}
	w->c.fp = w->out.fp;
	w->c.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &w->c, on_error,
	                                   on_warning);
	if (w->c.png)
		w->c.info = png_create_info_struct(w->c.png);
	if (!w->c.png || !w->c.info) {
		loom_png_writer_abort(w);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	if ((rc = start_png(w)) != LOOM_OK) {
		loom__fail(diag, rc, "%s: PNG write failed: %s", path, w->c.msg);
		loom_png_writer_abort(w);
		return rc;
	}
	*out = w;
	return LOOM_OK;
}

LOOM_API int loom_png_writer_put_rows(loom_png_writer *w, const uint8_t *pixels,
                                      uint32_t n_rows, loom_diag *diag)
{
	int rc;

	if (!w || (!pixels && n_rows))
		return loom__fail(diag, LOOM_EINVAL, "loom_png_writer_put_rows: NULL");
	if (w->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: writer failed earlier", w->path);
	if (n_rows > w->height - w->rows_done)
		return loom__fail(diag, LOOM_ERANGE, "%s: %u rows given, %u left", w->path,
		                  n_rows, w->height - w->rows_done);
	if ((rc = rows_png(w, pixels, n_rows)) != LOOM_OK) {
		w->failed = 1;
		return loom__fail(diag, rc, "%s: PNG write failed: %s", w->path, w->c.msg);
	}
	w->rows_done += n_rows;
	return LOOM_OK;
}

LOOM_API int loom_png_writer_finish(loom_png_writer *w, loom_diag *diag)
{
	int rc;

	if (!w)
		return loom__fail(diag, LOOM_EINVAL, "loom_png_writer_finish: NULL");
	if (w->failed || w->rows_done != w->height) {
		rc = w->failed ? LOOM_EUNUSABLE : LOOM_ETRUNCATED;
		loom__fail(diag, rc, "%s: %u of %u rows written; nothing kept", w->path,
		           w->rows_done, w->height);
		loom_png_writer_abort(w);
		return rc;
	}
	if ((rc = end_png(w)) != LOOM_OK) {
		loom__fail(diag, rc, "%s: PNG write failed: %s", w->path, w->c.msg);
		loom_png_writer_abort(w);
		return rc;
	}
	png_destroy_write_struct(&w->c.png, &w->c.info);
	rc = loom__atomic_commit(&w->out, diag);
	free(w->path);
	free(w);
	return rc;
}

LOOM_API void loom_png_writer_abort(loom_png_writer *w)
{
	if (!w)
		return;
	if (w->c.png)
		png_destroy_write_struct(&w->c.png, w->c.info ? &w->c.info : NULL);
	loom__atomic_abort(&w->out);
	free(w->path);
	free(w);
}
