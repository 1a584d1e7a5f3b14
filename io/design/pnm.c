/*
 * io/design/pnm.c - Netpbm images: PBM (P1 plain, P4 raw), PGM (P2, P5) and PPM
 * (P3, P6), read strictly; P4, P5 and P6 written.
 *
 * Layout (netpbm.sourceforge.net/doc): a magic "Pn", then width, height and
 * (except PBM) maxval as decimal numbers separated by whitespace, where
 * '#' starts a comment running to the end of the line.  Binary formats put
 * exactly one whitespace byte after the last header number and then the
 * raster: P4 rows of ceil(width/8) bytes, MSB first, 1 = black; P5/P6 one
 * byte per sample when maxval < 256, else two bytes big-endian.  Plain
 * formats give the samples as text ('0'/'1' digits for P1, which need no
 * separators; decimal numbers for P2/P3); comments are accepted there too.
 *
 * Strictness: samples above maxval, a missing or short raster and text
 * after the last plain sample are errors; bytes after a binary raster (the
 * next image of a stream) are ignored with a warning.  Header and plain
 * errors name the line; binary raster errors name the byte offset.
 */
#include "image_internal.h"

#include <stdlib.h>
#include <string.h>

typedef struct pnm_rd {
	const uint8_t *p;   /* the file */
	size_t len;         /* bytes in p */
	size_t pos;         /* next byte */
	unsigned line;      /* 1-based line of pos (text parts only) */
	const char *name;   /* for messages */
	loom_diag *diag;
	int kind;           /* 1..6 from the magic */
	unsigned flags;     /* LOOM__IMG_* */
	uint32_t width, height, maxval;
} pnm_rd;

static int is_space(uint8_t c)
{
	return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' ||
	       c == '\f';
}

/* Skip whitespace and '#' comments, counting lines. */
static void skip_space(pnm_rd *r)
{
	while (r->pos < r->len) {
		uint8_t c = r->p[r->pos];
		if (c == '#') {
			while (r->pos < r->len && r->p[r->pos] != '\n' &&
			       r->p[r->pos] != '\r')
				r->pos++;
			continue;
		}
		if (!is_space(c))
			return;
		if (c == '\n' || (c == '\r' && (r->pos + 1 >= r->len ||
		                                r->p[r->pos + 1] != '\n')))
			r->line++;
		r->pos++;
	}
}

/* Line for an "ends early" message: the last line that has any bytes. */
static unsigned eof_line(const pnm_rd *r)
{
	if (r->pos >= r->len && r->len > 0 && r->p[r->len - 1] == '\n' && r->line > 1)
		return r->line - 1;
	return r->line;
}

/* Describe the byte at pos for "got ..." in messages. */
static const char *got(const pnm_rd *r, char *buf, size_t n)
{
	uint8_t c;
	if (r->pos >= r->len)
		return "end of file";
	c = r->p[r->pos];
	if (c >= 0x21 && c < 0x7f)
		snprintf(buf, n, "'%c'", c);
	else
		snprintf(buf, n, "byte 0x%02x", c);
	return buf;
}

/* Read a decimal number (after whitespace/comments) up to UINT32_MAX. */
static int read_uint(pnm_rd *r, const char *what, uint32_t *v)
{
	uint64_t x = 0;
	char buf[16];

	skip_space(r);
	if (r->pos >= r->len)
		return loom__fail(r->diag, LOOM_ETRUNCATED, "%s:%u: expected %s (a "
		                  "decimal number), got end of file", r->name,
		                  eof_line(r), what);
	if (r->p[r->pos] < '0' || r->p[r->pos] > '9')
		return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: expected %s (a decimal "
		                  "number), got %s", r->name, r->line, what,
		                  got(r, buf, sizeof buf));
	while (r->pos < r->len && r->p[r->pos] >= '0' && r->p[r->pos] <= '9') {
		x = x * 10 + (uint64_t)(r->p[r->pos++] - '0');
		if (x > 0xffffffffu)
			return loom__fail(r->diag, LOOM_ERANGE, "%s:%u: %s is too large",
			                  r->name, r->line, what);
	}
	if (r->pos < r->len && !is_space(r->p[r->pos]) && r->p[r->pos] != '#')
		return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: expected whitespace "
		                  "after %s %llu, got %s", r->name, r->line, what,
		                  (unsigned long long)x, got(r, buf, sizeof buf));
	*v = (uint32_t)x;
	return LOOM_OK;
}

static int read_header(pnm_rd *r)
{
	char buf[16];
	int rc;

	r->kind = r->p[1] - '0';
	r->pos = 2;
	r->line = 1;
	if (r->pos < r->len && !is_space(r->p[r->pos]) && r->p[r->pos] != '#')
		return loom__fail(r->diag, LOOM_EFORMAT, "%s:1: expected whitespace "
		                  "after the magic 'P%d', got %s", r->name, r->kind,
		                  got(r, buf, sizeof buf));
	if ((rc = read_uint(r, "width", &r->width)) ||
	    (rc = read_uint(r, "height", &r->height)))
		return rc;
	if (r->width == 0 || r->height == 0)
		return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: image size %ux%u: "
		                  "width and height must be at least 1", r->name,
		                  r->line, r->width, r->height);
	if ((uint64_t)r->width * r->height > LOOM__IMAGE_MAX_PIXELS)
		return loom__fail(r->diag, LOOM_ERANGE, "%s:%u: image size %ux%u is "
		                  "larger than %llu pixels", r->name, r->line, r->width,
		                  r->height, (unsigned long long)LOOM__IMAGE_MAX_PIXELS);
	r->maxval = 1;
	if (r->kind != 1 && r->kind != 4) {
		if ((rc = read_uint(r, "maxval", &r->maxval)))
			return rc;
		if (r->maxval == 0 || r->maxval > 65535)
			return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: maxval %u out of "
			                  "range: expected 1..65535", r->name, r->line,
			                  r->maxval);
	}
	if (r->kind >= 4) { /* exactly one whitespace byte before the raster */
		if (r->pos >= r->len)
			return loom__fail(r->diag, LOOM_ETRUNCATED, "%s:%u: header ends "
			                  "without a raster", r->name, eof_line(r));
		if (!is_space(r->p[r->pos]))
			return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: expected one "
			                  "whitespace byte between the header and the "
			                  "raster, got %s", r->name, r->line,
			                  got(r, buf, sizeof buf));
		r->pos++;
	}
	return LOOM_OK;
}

/* Allocate the output image: channels by kind. */
static int alloc_image(pnm_rd *r, loom_image **out)
{
	uint32_t ch = (r->kind == 3 || r->kind == 6) ? 3 : 1;
	int rc = loom_image_new(r->width, r->height, ch, out);

	if (rc)
		return loom__fail(r->diag, rc, "%s: cannot allocate a %ux%u image: %s",
		                  r->name, r->width, r->height, loom_strerror(rc));
	(*out)->bilevel = r->kind == 1 || r->kind == 4;
	return LOOM_OK;
}

/* Lookup table from stored sample to pixel value (maxval+1 entries). */
static int make_lut(pnm_rd *r, uint8_t **lut)
{
	uint32_t m = r->maxval;

	*lut = malloc((size_t)m + 1);
	if (!*lut)
		return loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory", r->name);
	for (uint32_t v = 0; v <= m; v++) {
		if (r->flags & LOOM__IMG_RAW)
			(*lut)[v] = (uint8_t)(v > 255 ? 0 : v);
		else
			(*lut)[v] = (uint8_t)((v * 255u + m / 2) / m);
	}
	return LOOM_OK;
}

static int raw_too_big(pnm_rd *r, uint32_t v, const char *where)
{
	return loom__fail(r->diag, LOOM_EFORMAT, "%s: %s: sample %u is above 255 "
	                  "and cannot be a type ID", r->name, where, v);
}

/* ---- plain (text) rasters ---------------------------------------------- */

static int read_p1(pnm_rd *r, loom_image *img)
{
	size_t n = (size_t)r->width * r->height;
	uint8_t black = (r->flags & LOOM__IMG_RAW) ? 1 : 0;
	uint8_t white = (r->flags & LOOM__IMG_RAW) ? 0 : 255;
	char buf[16];

	for (size_t k = 0; k < n; k++) {
		uint8_t c;
		skip_space(r);
		if (r->pos >= r->len)
			return loom__fail(r->diag, LOOM_ETRUNCATED, "%s:%u: data ends after "
			                  "%zu of %zu pixels", r->name, eof_line(r), k, n);
		c = r->p[r->pos];
		if (c != '0' && c != '1')
			return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: expected '0' or "
			                  "'1' for pixel x=%zu, y=%zu, got %s", r->name,
			                  r->line, k % r->width, k / r->width,
			                  got(r, buf, sizeof buf));
		img->pixels[k] = c == '1' ? black : white;
		r->pos++;
	}
	return LOOM_OK;
}

static int read_plain_samples(pnm_rd *r, loom_image *img, const uint8_t *lut)
{
	size_t n = (size_t)r->width * r->height * img->channels;
	char where[64];

	for (size_t k = 0; k < n; k++) {
		uint32_t v;
		int rc = read_uint(r, "a sample", &v);
		if (rc == LOOM_ETRUNCATED)
			return loom__fail(r->diag, rc, "%s:%u: data ends after %zu of %zu "
			                  "samples", r->name, eof_line(r), k, n);
		if (rc)
			return rc;
		if (v > r->maxval)
			return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: sample %u of pixel "
			                  "x=%zu, y=%zu exceeds maxval %u", r->name, r->line,
			                  v, (k / img->channels) % r->width,
			                  (k / img->channels) / r->width, r->maxval);
		if ((r->flags & LOOM__IMG_RAW) && v > 255) {
			snprintf(where, sizeof where, "line %u", r->line);
			return raw_too_big(r, v, where);
		}
		img->pixels[k] = lut[v];
	}
	return LOOM_OK;
}

static int check_plain_end(pnm_rd *r)
{
	char buf[16];

	skip_space(r);
	if (r->pos < r->len)
		return loom__fail(r->diag, LOOM_EFORMAT, "%s:%u: expected end of data "
		                  "after the last of %ux%u pixels, got %s", r->name,
		                  r->line, r->width, r->height, got(r, buf, sizeof buf));
	return LOOM_OK;
}

/* ---- binary rasters ---------------------------------------------------- */

static int need_bytes(pnm_rd *r, uint64_t need)
{
	size_t have = r->len - r->pos;

	if (have < need)
		return loom__fail(r->diag, LOOM_ETRUNCATED, "%s: byte %zu: raster ends "
		                  "after %zu of %llu bytes (%ux%u image)", r->name,
		                  r->len, have, (unsigned long long)need, r->width,
		                  r->height);
	if (have > need)
		loom__warn(r->diag, "%s: byte %llu: ignored %llu bytes after the image "
		           "(only the first image of a stream is read)", r->name,
		           (unsigned long long)(r->pos + need),
		           (unsigned long long)(have - need));
	return LOOM_OK;
}

/*
 * Before allocating: the raster must fit in what is left of the file.  A
 * binary raster has an exact size; a plain one needs at least one byte per
 * P1 pixel and two per P2/P3 sample (digit and separator), so a short file
 * cannot make the reader allocate a huge image.
 */
static int check_raster_size(pnm_rd *r)
{
	uint64_t px = (uint64_t)r->width * r->height;
	uint64_t samples = px * ((r->kind == 3 || r->kind == 6) ? 3 : 1);
	uint64_t left = r->len - r->pos;

	if (r->kind == 4)
		return need_bytes(r, (uint64_t)((r->width + 7ull) / 8) * r->height);
	if (r->kind >= 5)
		return need_bytes(r, samples * (r->maxval > 255 ? 2 : 1));
	if (r->kind == 1 ? left < px : left + 1 < 2 * samples)
		return loom__fail(r->diag, LOOM_ETRUNCATED, "%s:%u: data ends early: "
		                  "%llu %s need at least %llu bytes, %llu remain",
		                  r->name, r->line, (unsigned long long)samples,
		                  r->kind == 1 ? "pixels" : "samples",
		                  (unsigned long long)(r->kind == 1 ? px : 2 * samples - 1),
		                  (unsigned long long)left);
	return LOOM_OK;
}

static int read_p4(pnm_rd *r, loom_image *img)
{
	size_t stride = ((size_t)r->width + 7) / 8;
	uint8_t black = (r->flags & LOOM__IMG_RAW) ? 1 : 0;
	uint8_t white = (r->flags & LOOM__IMG_RAW) ? 0 : 255;

	for (uint32_t y = 0; y < r->height; y++) {
		const uint8_t *src = r->p + r->pos + (size_t)y * stride;
		uint8_t *dst = img->pixels + (size_t)y * r->width;
		for (uint32_t x = 0; x < r->width; x++)
			dst[x] = (src[x >> 3] & (0x80u >> (x & 7))) ? black : white;
	}
	return LOOM_OK;
}

static int read_binary_samples(pnm_rd *r, loom_image *img, const uint8_t *lut)
{
	size_t n = (size_t)r->width * r->height * img->channels;
	size_t bps = r->maxval > 255 ? 2 : 1;
	const uint8_t *src;
	char where[64];

	src = r->p + r->pos;
	for (size_t k = 0; k < n; k++) {
		uint32_t v = bps == 2 ? (uint32_t)src[2 * k] << 8 | src[2 * k + 1] : src[k];
		if (v > r->maxval)
			return loom__fail(r->diag, LOOM_EFORMAT, "%s: byte %zu: sample %u "
			                  "exceeds maxval %u", r->name, r->pos + k * bps, v,
			                  r->maxval);
		if ((r->flags & LOOM__IMG_RAW) && v > 255) {
			snprintf(where, sizeof where, "byte %zu", r->pos + k * bps);
			return raw_too_big(r, v, where);
		}
		img->pixels[k] = lut[v];
	}
	return LOOM_OK;
}

static int read_raster(pnm_rd *r, loom_image *img)
{
	uint8_t *lut = NULL;
	int rc;

	if (r->kind == 1)
		return read_p1(r, img);
	if (r->kind == 4)
		return read_p4(r, img);
	rc = make_lut(r, &lut);
	if (rc)
		return rc;
	if (r->kind == 2 || r->kind == 3)
		rc = read_plain_samples(r, img, lut);
	else
		rc = read_binary_samples(r, img, lut);
	free(lut);
	return rc;
}

int loom__pnm_parse(const uint8_t *data, size_t len, const char *name,
                    unsigned flags, loom_image **out, loom_diag *diag)
{
	pnm_rd r;
	loom_image *img = NULL;
	int rc;

	*out = NULL;
	memset(&r, 0, sizeof r);
	r.p = data;
	r.len = len;
	r.name = name;
	r.diag = diag;
	r.flags = flags;
	rc = read_header(&r);
	if (!rc)
		rc = check_raster_size(&r);
	if (!rc)
		rc = alloc_image(&r, &img);
	if (!rc)
		rc = read_raster(&r, img);
	if (!rc && r.kind <= 3)
		rc = check_plain_end(&r);
	if (rc) {
		loom_image_free(img);
		return rc;
	}
	*out = img;
	return LOOM_OK;
}

/* ---- writer ------------------------------------------------------------ */

int loom__pnm_write(FILE *fp, const loom__raster *r, const char *name,
                    loom_diag *diag)
{
	size_t stride;
	uint8_t *row;
	int ok;

	if (r->bit_depth == 1 && r->channels == 1) {
		stride = ((size_t)r->width + 7) / 8;
		fprintf(fp, "P4\n%u %u\n", r->width, r->height);
	} else if (r->bit_depth == 8 && (r->channels == 1 || r->channels == 3)) {
		stride = (size_t)r->width * r->channels;
		fprintf(fp, "P%d\n%u %u\n255\n", r->channels == 1 ? 5 : 6, r->width,
		        r->height);
	} else {
		return loom__fail(diag, LOOM_EINVAL, "%s: no PNM form for %u channels "
		                  "of %u bits", name, r->channels, r->bit_depth);
	}
	row = malloc(stride);
	if (!row)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	ok = 1;
	for (uint32_t y = 0; ok && y < r->height; y++) {
		r->row(r->user, y, row);
		ok = fwrite(row, 1, stride, fp) == stride;
	}
	free(row);
	if (!ok || ferror(fp))
		return loom__fail(diag, LOOM_EIO, "%s: write failed", name);
	return LOOM_OK;
}
