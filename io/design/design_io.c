/*
 * io/design/design_io.c - designs as files: a weave image (PBM or 1-bit PNG, black
 * = warp over, first row = pick 0, first column = end 0), optional
 * yarn-type maps (8-bit grey PGM/PNG, pixel value = type ID), or a WIF
 * draft (io/design/wif.c).
 */
#include "image_internal.h"
#include "io/core/file.h"

#include <stdlib.h>
#include <string.h>

/* ---- image -> weave ----------------------------------------------------- */

static uint32_t pixel_key(const loom_image *img, size_t k)
{
	const uint8_t *p = img->pixels + k * img->channels;
	if (img->channels == 1)
		return (uint32_t)p[0] << 16 | (uint32_t)p[0] << 8 | p[0];
	return (uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2];
}

/* Luma of a packed RGB key, times 1000. */
static uint32_t key_luma(uint32_t key)
{
	return 299u * (key >> 16) + 587u * ((key >> 8) & 255) + 114u * (key & 255);
}

static void describe_key(const loom_image *img, uint32_t key, char *buf, size_t n)
{
	if (img->channels == 1)
		snprintf(buf, n, "grey level %u", key & 255);
	else
		snprintf(buf, n, "colour #%06x", key);
}

int loom__weave_from_image(const loom_image *img, const char *name,
                           uint8_t *weave, loom_diag *diag)
{
	size_t n = (size_t)img->width * img->height;
	uint32_t lev[2] = {pixel_key(img, 0), 0};
	int n_lev = 1;
	uint32_t dark;

	for (size_t k = 0; k < n; k++) {
		uint32_t key = pixel_key(img, k);
		char a[32], b[32], c[32];
		if (key == lev[0] || (n_lev == 2 && key == lev[1]))
			continue;
		if (n_lev == 1) {
			lev[n_lev++] = key;
			continue;
		}
		describe_key(img, key, a, sizeof a);
		describe_key(img, lev[0], b, sizeof b);
		describe_key(img, lev[1], c, sizeof c);
		return loom__fail(diag, LOOM_EFORMAT, "%s: pixel x=%zu, y=%zu has a third "
		                  "level (%s; the others are %s and %s): a weave image "
		                  "must be two-level (dark = warp over); threshold it "
		                  "first", name, k % img->width, k / img->width, a, b, c);
	}
	if (n_lev == 2 && key_luma(lev[0]) == key_luma(lev[1]))
		return loom__fail(diag, LOOM_EFORMAT, "%s: its two colours #%06x and "
		                  "#%06x are equally dark; cannot tell warp over from "
		                  "under", name, lev[0], lev[1]);
	if (n_lev == 1)
		dark = key_luma(lev[0]) < 128000 ? lev[0] : 0xffffffffu;
	else
		dark = key_luma(lev[0]) < key_luma(lev[1]) ? lev[0] : lev[1];
	for (size_t k = 0; k < n; k++)
		weave[k] = pixel_key(img, k) == dark;
	return LOOM_OK;
}

static int design_from_weave_image(const loom_image *img, const char *name,
                                   loom_design **out, loom_diag *diag)
{
	loom_design *d;
	int rc = loom_design_new(img->height, img->width, &d);

	if (rc)
		return loom__fail(diag, rc, "%s: cannot make a %ux%u design: %s", name,
		                  img->height, img->width, loom_strerror(rc));
	rc = loom__weave_from_image(img, name, d->weave, diag);
	if (rc) {
		loom_design_free(d);
		return rc;
	}
	*out = d;
	return LOOM_OK;
}

static int is_image(const uint8_t *data, size_t len)
{
	return loom__is_png(data, len) ||
	       (len >= 2 && data[0] == 'P' && data[1] >= '1' && data[1] <= '6');
}

/* head check of a design of unknown extension: an image, else WIF text */
static int design_head(const uint8_t *head, size_t n, const char *path,
                       loom_diag *diag)
{
	if (is_image(head, n))
		return LOOM_OK;
	return loom__head_text(head, n, path, diag);
}

/* An image extension means an image; no known extension: sniff the content
   (an image, else a WIF, whose text may begin with anything). */
static int design_from_bytes(const uint8_t *data, size_t len, const char *path,
                             loom_design **out, loom_diag *diag)
{
	loom_image *img;
	int rc;

	if (loom__path_format(path) == LOOM__FMT_UNKNOWN && !is_image(data, len))
		return loom_wif_parse((const char *)data, len, path, out, diag);
	rc = loom_image_parse(data, len, path, &img, diag);
	if (rc)
		return rc;
	rc = design_from_weave_image(img, path, out, diag);
	loom_image_free(img);
	return rc;
}

LOOM_API int loom_design_read(const char *path, loom_design **out,
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
	if (loom__path_format(path) == LOOM__FMT_WIF)
		return loom_wif_read(path, out, diag);
	rc = loom__read_file_checked(path, LOOM__IMAGE_MAX_FILE_BYTES, "design",
	                             loom__path_format(path) == LOOM__FMT_UNKNOWN
	                             ? design_head : loom__image_head,
	                             &data, &len, diag);
	if (rc)
		return rc;
	rc = design_from_bytes(data, len, path, out, diag);
	free(data);
	return rc;
}

/* ---- weave -> file ------------------------------------------------------ */

typedef struct cells_src {
	const uint8_t *cells; /* rows*cols, row-major */
	uint32_t cols;
	int mode;             /* 0: PBM bits 1 = set; 1: PNG bits 1 = clear;
	                         2: bytes as they are */
} cells_src;

static void cells_row(void *user, uint32_t y, uint8_t *row)
{
	const cells_src *s = user;
	const uint8_t *src = s->cells + (size_t)y * s->cols;

	if (s->mode == 2) {
		memcpy(row, src, s->cols);
		return;
	}
	memset(row, 0, ((size_t)s->cols + 7) / 8);
	for (uint32_t x = 0; x < s->cols; x++)
		if ((src[x] != 0) != (s->mode == 1))
			row[x >> 3] |= (uint8_t)(0x80u >> (x & 7));
}

LOOM_API int loom_weave_write(const char *path, const loom_design *d,
                              loom_diag *diag)
{
	loom__raster r;
	cells_src s;
	int fmt;

	if (!path || !d || !d->weave || d->rows == 0 || d->cols == 0)
		return loom__fail(diag, LOOM_EINVAL, "%s: invalid design or path",
		                  path ? path : "(null)");
	fmt = loom__path_format(path);
	if (fmt != LOOM__FMT_PBM && fmt != LOOM__FMT_PNG)
		return loom__fail(diag, LOOM_EINVAL, "%s: cannot write a weave as '%s': "
		                  "expected .pbm or .png", path, loom__path_ext(path));
	s.cells = d->weave;
	s.cols = d->cols;
	s.mode = fmt == LOOM__FMT_PNG;
	r.width = d->cols;
	r.height = d->rows;
	r.channels = 1;
	r.bit_depth = 1;
	r.row = cells_row;
	r.user = &s;
	return loom__raster_save(path, fmt, &r, diag);
}

/* ---- yarn-type maps ----------------------------------------------------- */

LOOM_API int loom_type_map_write(const char *path, const loom_design *d,
                                 int which, loom_diag *diag)
{
	loom__raster r;
	cells_src s;
	int fmt;

	if (!path || !d || d->rows == 0 || d->cols == 0 ||
	    (which != LOOM_MAP_WARP && which != LOOM_MAP_WEFT))
		return loom__fail(diag, LOOM_EINVAL, "%s: invalid design, map or path",
		                  path ? path : "(null)");
	fmt = loom__path_format(path);
	if (fmt != LOOM__FMT_PGM && fmt != LOOM__FMT_PNG)
		return loom__fail(diag, LOOM_EINVAL, "%s: cannot write a type map as "
		                  "'%s': expected .pgm or .png", path,
		                  loom__path_ext(path));
	s.cells = which == LOOM_MAP_WARP ? d->warp_type : d->weft_type;
	s.cols = d->cols;
	s.mode = 2;
	r.width = d->cols;
	r.height = d->rows;
	r.channels = 1;
	r.bit_depth = 8;
	r.row = cells_row;
	r.user = &s;
	return loom__raster_save(path, fmt, &r, diag);
}

static uint32_t max_id(const uint8_t *ids, size_t n)
{
	uint8_t m = 0;
	for (size_t k = 0; k < n; k++)
		if (ids[k] > m)
			m = ids[k];
	return m;
}

LOOM_API int loom_type_map_read(const char *path, loom_design *d, int which,
                                loom_diag *diag)
{
	const char *what = which == LOOM_MAP_WARP ? "warp" : "weft";
	loom_image *img;
	uint32_t top;
	size_t n;
	int rc;

	if (!path || !d || (which != LOOM_MAP_WARP && which != LOOM_MAP_WEFT))
		return loom__fail(diag, LOOM_EINVAL, "%s: invalid design, map or path",
		                  path ? path : "(null)");
	rc = loom__image_read_ex(path, LOOM__IMG_RAW, &img, diag);
	if (rc)
		return rc;
	if (img->channels != 1)
		rc = loom__fail(diag, LOOM_EFORMAT, "%s: a %s-type map must be a grey "
		                "image (pixel value = type ID), this one has colour",
		                path, what);
	else if (img->width != d->cols || img->height != d->rows)
		rc = loom__fail(diag, LOOM_EMISMATCH, "%s: %s-type map is %ux%u "
		                "(width x height) but the weave has %u ends x %u picks",
		                path, what, img->width, img->height, d->cols, d->rows);
	n = (size_t)img->width * img->height;
	top = rc ? 0 : max_id(img->pixels, n);
	if (!rc && top >= d->n_types) {
		uint32_t old = d->n_types;
		rc = loom_design_set_types(d, top + 1);
		if (rc)
			loom__fail(diag, rc, "%s: out of memory", path);
		else
			loom__warn(diag, "%s: type IDs up to %u but the yarn table had %u "
			           "entries; added default types %u..%u", path, top, old,
			           old, top);
	}
	if (!rc)
		memcpy(which == LOOM_MAP_WARP ? d->warp_type : d->weft_type,
		       img->pixels, n);
	loom_image_free(img);
	return rc;
}
