/*
 * io/volume/mitsuba_vol.c - Mitsuba 0.5/0.6 grid volumes (.vol).
 *
 * Layout (little-endian; byte offsets):
 *    0  'V' 'O' 'L'
 *    3  version byte, 3
 *    4  int32 encoding: 1 float32, 2 float16, 3 uint8, 4 quantized directions
 *    8  int32 xres, 12 int32 yres, 16 int32 zres
 *   20  int32 channels (3 for encoding 4)
 *   24  float32 xmin ymin zmin xmax ymax zmax
 *   48  data: value (x,y,z,c) at ((z*yres + y)*xres + x)*channels + c;
 *       encoding 4 stores 2 bytes (theta, phi) per voxel instead.
 * docs/volumes.md has the full description and the decoding rules.
 *
 * The writer streams: the header goes out at open (everything in it is
 * known up front), voxels are appended in file order through a fixed
 * 64 KiB encode buffer, and finish refuses to commit unless exactly the
 * declared number of voxels arrived.  The reader validates the header and
 * the file size before anything else, so a lying header can never make it
 * allocate or read past the file.
 */
#include "core/internal.h"
#include "io/core/file.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define ENCODE_BUF_BYTES 65536
#define PI_D 3.14159265358979323846

/* ---- little-endian helpers --------------------------------------------- */

static uint32_t get_u32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
	       (uint32_t)p[3] << 24;
}

static void put_u32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}

static float get_f32(const uint8_t *p)
{
	uint32_t b = get_u32(p);
	float f;
	memcpy(&f, &b, 4);
	return f;
}

static void put_f32(uint8_t *p, float f)
{
	uint32_t b;
	memcpy(&b, &f, 4);
	put_u32(p, b);
}

/* ---- header -------------------------------------------------------------- */

static const char *encoding_name(int32_t e)
{
	switch (e) {
	case LOOM_VOL_FLOAT32: return "float32";
	case LOOM_VOL_FLOAT16: return "float16";
	case LOOM_VOL_UINT8: return "uint8";
	case LOOM_VOL_QDIR: return "quantized directions";
	default: return "unknown";
	}
}

/* Bytes per voxel on disk; 0 for an invalid encoding. */
static uint64_t voxel_bytes(int32_t encoding, uint32_t channels)
{
	switch (encoding) {
	case LOOM_VOL_FLOAT32: return 4ull * channels;
	case LOOM_VOL_FLOAT16: return 2ull * channels;
	case LOOM_VOL_UINT8: return 1ull * channels;
	case LOOM_VOL_QDIR: return 2;
	default: return 0;
	}
}

/* "byte N: " for messages about a parsed header, "" for a caller's struct. */
static void where_at(char *buf, size_t n, int at, int offset)
{
	if (at)
		snprintf(buf, n, "byte %d: ", offset);
	else
		buf[0] = 0;
}

/* Validate a header's fields; `name` and `at` (1: byte offsets of a parsed
   header, 0: a caller's struct) shape the messages. */
static int check_header(const loom_vol_header *h, const char *name, int at,
                        loom_diag *diag)
{
	static const char *const res_names[3] = {"xres", "yres", "zres"};
	static const char *const bbox_names[6] = {"xmin", "ymin", "zmin",
	                                          "xmax", "ymax", "zmax"};
	char where[32];
	uint32_t res[3] = {h->xres, h->yres, h->zres};

	if (h->encoding < LOOM_VOL_FLOAT32 || h->encoding > LOOM_VOL_QDIR) {
		where_at(where, sizeof where, at, 4);
		return loom__fail(diag, LOOM_EFORMAT,
		                  "%s: %sunknown encoding %d (expected 1 float32, 2 "
		                  "float16, 3 uint8 or 4 quantized directions)",
		                  name, where, (int)h->encoding);
	}
	for (int a = 0; a < 3; a++)
		if (res[a] < 1 || res[a] > INT32_MAX) {
			where_at(where, sizeof where, at, 8 + 4 * a);
			return loom__fail(diag, LOOM_EFORMAT,
			                  "%s: %s%s must be 1..2147483647, got %lld", name,
			                  where, res_names[a],
			                  (long long)(int32_t)res[a]);
		}
	where_at(where, sizeof where, at, 20);
	if (h->encoding == LOOM_VOL_QDIR && h->channels != 3)
		return loom__fail(diag, LOOM_EFORMAT,
		                  "%s: %schannels must be 3 for encoding 4 (quantized "
		                  "directions), got %lld",
		                  name, where, (long long)(int32_t)h->channels);
	if (h->channels < 1 || h->channels > INT32_MAX)
		return loom__fail(diag, LOOM_EFORMAT,
		                  "%s: %schannels must be at least 1, got %lld", name,
		                  where, (long long)(int32_t)h->channels);
	if (h->channels > LOOM_VOL_MAX_CHANNELS)
		return loom__fail(diag, LOOM_ERANGE,
		                  "%s: %s%u channels, loom reads at most %d", name, where,
		                  h->channels, LOOM_VOL_MAX_CHANNELS);
	for (int i = 0; i < 6; i++) {
		float v = i < 3 ? h->bbox_min[i] : h->bbox_max[i - 3];
		if (!isfinite(v)) {
			where_at(where, sizeof where, at, 24 + 4 * i);
			return loom__fail(diag, LOOM_EFORMAT,
			                  "%s: %sbounding box %s is not finite", name, where,
			                  bbox_names[i]);
		}
	}
	return LOOM_OK;
}

LOOM_API int loom_vol_header_parse(const uint8_t *data, size_t len,
                                   const char *name, loom_vol_header *h,
                                   loom_diag *diag)
{
	if (!name)
		name = "vol";
	if (!h || (!data && len))
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL argument", name);
	memset(h, 0, sizeof *h);
	if (len >= 3 && memcmp(data, "VOL", 3) != 0)
		return loom__fail(diag, LOOM_EFORMAT,
		                  "%s: byte 0: expected magic \"VOL\", got bytes "
		                  "0x%02x 0x%02x 0x%02x",
		                  name, data[0], data[1], data[2]);
	if (len < LOOM_VOL_HEADER_BYTES)
		return loom__fail(diag, LOOM_ETRUNCATED,
		                  "%s: byte %zu: header truncated, a .vol header has %d "
		                  "bytes",
		                  name, len, LOOM_VOL_HEADER_BYTES);
	if (data[3] != 3)
		return loom__fail(diag, LOOM_EVERSION,
		                  "%s: byte 3: unsupported version %u, expected 3", name,
		                  data[3]);
	h->encoding = (int32_t)get_u32(data + 4);
	h->xres = get_u32(data + 8);
	h->yres = get_u32(data + 12);
	h->zres = get_u32(data + 16);
	h->channels = get_u32(data + 20);
	for (int i = 0; i < 3; i++) {
		h->bbox_min[i] = get_f32(data + 24 + 4 * i);
		h->bbox_max[i] = get_f32(data + 36 + 4 * i);
	}
	return check_header(h, name, 1, diag);
}

LOOM_API int loom_vol_data_bytes(const loom_vol_header *h, uint64_t *bytes)
{
	uint64_t vb, n;

	if (!h || !bytes || check_header(h, "vol", 0, NULL) != LOOM_OK)
		return LOOM_EINVAL;
	vb = voxel_bytes(h->encoding, h->channels);
	n = (uint64_t)h->xres * h->yres; /* < 2^62 */
	if (n > (UINT64_MAX >> 1) / h->zres || n * h->zres > (UINT64_MAX >> 1) / vb)
		return LOOM_ERANGE;
	*bytes = n * h->zres * vb;
	return LOOM_OK;
}

/* ---- quantized directions ------------------------------------------------ */

LOOM_API void loom_vol_qdir_decode(const uint8_t tp[2], float v[3])
{
	/* Mitsuba's tables: angle i*pi/255 for i < 255; index 255 is exactly
	   theta = pi (cos -1, sin 0) and phi = 2pi (cos 1, sin 0). */
	double st, ct, sp, cp;

	if (tp[0] == 255) {
		st = 0.0;
		ct = -1.0;
	} else {
		double t = tp[0] * (PI_D / 255.0);
		st = sin(t);
		ct = cos(t);
	}
	if (tp[1] == 255) {
		sp = 0.0;
		cp = 1.0;
	} else {
		double p = 2.0 * tp[1] * (PI_D / 255.0);
		sp = sin(p);
		cp = cos(p);
	}
	v[0] = (float)(cp * st);
	v[1] = (float)(sp * st);
	v[2] = (float)ct;
}

LOOM_API void loom_vol_qdir_encode(const float v[3], uint8_t tp[2])
{
	double x = v[0], y = v[1], z = v[2];
	double n = sqrt(x * x + y * y + z * z);
	double t, p;
	long ti, pi;

	tp[0] = tp[1] = 0;
	if (!(n > 0.0) || !isfinite(n))
		return;
	z /= n;
	if (z > 1.0)
		z = 1.0;
	if (z < -1.0)
		z = -1.0;
	t = acos(z) * (255.0 / PI_D);
	p = atan2(y, x);
	if (p < 0.0)
		p += 2.0 * PI_D;
	p *= 255.0 / (2.0 * PI_D);
	ti = lround(t);
	pi = lround(p);
	if (ti > 255)
		ti = 255;
	if (pi >= 255) /* 255 is phi = 2pi, the same as 0 */
		pi = 0;
	if (ti == 0 || ti == 255) /* the poles: phi does not matter */
		pi = 0;
	tp[0] = (uint8_t)ti;
	tp[1] = (uint8_t)pi;
}

/* ---- decoding ------------------------------------------------------------- */

/* Decode n voxels of encoded data into floats (channels per voxel). */
static void decode_voxels(const loom_vol_header *h, const uint8_t *src,
                          size_t n, float *dst)
{
	size_t nv = n * h->channels;

	switch (h->encoding) {
	case LOOM_VOL_FLOAT32:
		for (size_t i = 0; i < nv; i++)
			dst[i] = get_f32(src + 4 * i);
		break;
	case LOOM_VOL_FLOAT16:
		for (size_t i = 0; i < nv; i++)
			dst[i] = loom_half_to_float(
				(uint16_t)(src[2 * i] | (uint16_t)src[2 * i + 1] << 8));
		break;
	case LOOM_VOL_UINT8:
		for (size_t i = 0; i < nv; i++)
			dst[i] = src[i] == 255 ? 1.0f : (float)src[i] / 255.0f;
		break;
	case LOOM_VOL_QDIR:
		for (size_t i = 0; i < n; i++)
			loom_vol_qdir_decode(src + 2 * i, dst + 3 * i);
		break;
	default:
		break;
	}
}

static void fill_geometry(const loom_vol_header *h, loom_volbuf *v)
{
	uint32_t res[3] = {h->xres, h->yres, h->zres};

	for (int a = 0; a < 3; a++) {
		double ext = (double)h->bbox_max[a] - (double)h->bbox_min[a];
		v->origin[a] = h->bbox_min[a];
		v->spacing[a] = res[a] > 1 ? ext / (res[a] - 1) : ext;
	}
	switch (h->encoding) {
	case LOOM_VOL_FLOAT16: v->source_type = LOOM_SCALAR_F16; break;
	case LOOM_VOL_UINT8: v->source_type = LOOM_SCALAR_U8; break;
	case LOOM_VOL_QDIR: v->source_type = LOOM_SCALAR_U8; break;
	default: v->source_type = LOOM_SCALAR_F32; break;
	}
}

/* Check that len bytes (the whole file) hold the declared data. */
static int check_size(const loom_vol_header *h, uint64_t len, const char *name,
                      uint64_t *data_bytes, loom_diag *diag)
{
	uint64_t need;

	if (loom_vol_data_bytes(h, &need) != LOOM_OK)
		return loom__fail(diag, LOOM_ERANGE,
		                  "%s: %ux%ux%u voxels of %u %s channels overflow", name,
		                  h->xres, h->yres, h->zres, h->channels,
		                  encoding_name(h->encoding));
	if (len - LOOM_VOL_HEADER_BYTES < need)
		return loom__fail(diag, LOOM_ETRUNCATED,
		                  "%s: byte %llu: truncated: %ux%ux%u voxels x %u %s "
		                  "channels need %llu data bytes from byte 48 (file "
		                  "size %llu), the file has %llu",
		                  name, (unsigned long long)len, h->xres, h->yres,
		                  h->zres, h->channels, encoding_name(h->encoding),
		                  (unsigned long long)need,
		                  (unsigned long long)(need + LOOM_VOL_HEADER_BYTES),
		                  (unsigned long long)len);
	*data_bytes = need;
	return LOOM_OK;
}

static int new_output(const loom_vol_header *h, const char *name,
                      size_t max_bytes, loom_volbuf **out, loom_diag *diag)
{
	int rc = loom_volbuf_new(h->xres, h->yres, h->zres, h->channels, max_bytes,
	                         out, diag);
	if (rc) {
		char msg[LOOM_DIAG_MSG_MAX];
		if (diag) {
			snprintf(msg, sizeof msg, "%s", diag->message);
			loom__fail(diag, rc, "%s: %s", name, msg);
		}
		return rc;
	}
	fill_geometry(h, *out);
	return LOOM_OK;
}

static void warn_trailing(const char *name, uint64_t len, uint64_t need,
                          loom_diag *diag)
{
	if (len - LOOM_VOL_HEADER_BYTES > need)
		loom__warn(diag, "%s: byte %llu: %llu bytes after the voxel data "
		           "ignored",
		           name, (unsigned long long)(need + LOOM_VOL_HEADER_BYTES),
		           (unsigned long long)(len - LOOM_VOL_HEADER_BYTES - need));
}

LOOM_API int loom_vol_parse(const uint8_t *data, size_t len, const char *name,
                            size_t max_bytes, loom_vol_header *h,
                            loom_volbuf **out, loom_diag *diag)
{
	loom_vol_header hh;
	uint64_t need;
	int rc;

	if (!name)
		name = "vol";
	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "%s: out is NULL", name);
	*out = NULL;
	rc = loom_vol_header_parse(data, len, name, &hh, diag);
	if (!rc)
		rc = check_size(&hh, len, name, &need, diag);
	if (!rc)
		rc = new_output(&hh, name, max_bytes, out, diag);
	if (rc)
		return rc;
	warn_trailing(name, len, need, diag);
	decode_voxels(&hh, data + LOOM_VOL_HEADER_BYTES,
	              (size_t)hh.xres * hh.yres * hh.zres, (*out)->data);
	if (h)
		*h = hh;
	return LOOM_OK;
}

/* ---- random-access reader -------------------------------------------------- */

struct loom_vol_reader {
	int fd;
	char *path;
	loom_vol_header h;
	uint64_t vbytes;       /* bytes per voxel on disk */
	uint8_t *row;          /* one row of xres voxels, encoded */
	int failed;
};

static int pread_all(int fd, uint8_t *buf, size_t n, uint64_t off,
                     const char *path, loom_diag *diag)
{
	size_t got = 0;
	while (got < n) {
		ssize_t m = pread(fd, buf + got, n - got, (off_t)(off + got));
		if (m < 0 && errno == EINTR)
			continue;
		if (m < 0)
			return loom__fail(diag, LOOM_EIO, "%s: read error at byte %llu: %s",
			                  path, (unsigned long long)(off + got),
			                  strerror(errno));
		if (m == 0)
			return loom__fail(diag, LOOM_ETRUNCATED,
			                  "%s: byte %llu: unexpected end of file", path,
			                  (unsigned long long)(off + got));
		got += (size_t)m;
	}
	return LOOM_OK;
}

LOOM_API int loom_vol_open(const char *path, loom_vol_reader **out,
                           loom_diag *diag)
{
	loom_vol_reader *r;
	uint8_t hdr[LOOM_VOL_HEADER_BYTES];
	uint64_t need, fsize;
	ssize_t got;
	int rc;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_open: NULL argument");
	*out = NULL;
	r = calloc(1, sizeof *r);
	if (!r)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	rc = loom__open_input(path, &r->fd, &fsize, diag);
	if (rc) {
		free(r);
		return rc;
	}
	do
		got = pread(r->fd, hdr, sizeof hdr, 0);
	while (got < 0 && errno == EINTR);
	if (got < 0) {
		rc = loom__fail(diag, LOOM_EIO, "%s: read error: %s", path,
		                strerror(errno));
		goto fail;
	}
	rc = loom_vol_header_parse(hdr, (size_t)got, path, &r->h, diag);
	if (!rc)
		rc = check_size(&r->h, fsize, path, &need, diag);
	if (rc)
		goto fail;
	warn_trailing(path, fsize, need, diag);
	r->vbytes = voxel_bytes(r->h.encoding, r->h.channels);
	r->path = strdup(path);
	/* xres*vbytes <= data bytes <= file size, so this is a sane size */
	r->row = malloc((size_t)(r->h.xres * r->vbytes));
	if (!r->path || !r->row) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
		goto fail;
	}
	*out = r;
	return LOOM_OK;
fail:
	loom_vol_close(r);
	return rc;
}

LOOM_API const loom_vol_header *loom_vol_reader_header(const loom_vol_reader *r)
{
	return r ? &r->h : NULL;
}

LOOM_API int loom_vol_read_box(loom_vol_reader *r, uint32_t x0, uint32_t y0,
                               uint32_t z0, uint32_t nx, uint32_t ny,
                               uint32_t nz, float *out, loom_diag *diag)
{
	const loom_vol_header *h;
	size_t row_floats;

	if (!r)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_read_box: reader is NULL");
	h = &r->h;
	if (r->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: reader failed earlier",
		                  r->path);
	if (x0 > h->xres || nx > h->xres - x0 || y0 > h->yres ||
	    ny > h->yres - y0 || z0 > h->zres || nz > h->zres - z0)
		return loom__fail(diag, LOOM_ERANGE,
		                  "%s: box [%u,%u)x[%u,%u)x[%u,%u) leaves the %ux%ux%u "
		                  "volume",
		                  r->path, x0, x0 + nx, y0, y0 + ny, z0, z0 + nz,
		                  h->xres, h->yres, h->zres);
	if (!nx || !ny || !nz)
		return LOOM_OK;
	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_read_box: out is NULL");
	row_floats = (size_t)nx * h->channels;
	for (uint32_t z = z0; z < z0 + nz; z++)
		for (uint32_t y = y0; y < y0 + ny; y++) {
			uint64_t vox = ((uint64_t)z * h->yres + y) * h->xres + x0;
			int rc = pread_all(r->fd, r->row, (size_t)(nx * r->vbytes),
			                   LOOM_VOL_HEADER_BYTES + vox * r->vbytes, r->path,
			                   diag);
			if (rc) {
				r->failed = 1;
				return rc;
			}
			decode_voxels(h, r->row, nx, out);
			out += row_floats;
		}
	return LOOM_OK;
}

LOOM_API void loom_vol_close(loom_vol_reader *r)
{
	if (!r)
		return;
	if (r->fd >= 0)
		close(r->fd);
	free(r->row);
	free(r->path);
	free(r);
}

LOOM_API int loom_vol_read(const char *path, size_t max_bytes,
                           loom_vol_header *h, loom_volbuf **out,
                           loom_diag *diag)
{
	loom_vol_reader *r;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_read: out is NULL");
	*out = NULL;
	rc = loom_vol_open(path, &r, diag);
	if (rc)
		return rc;
	rc = new_output(&r->h, path, max_bytes, out, diag);
	if (!rc)
		rc = loom_vol_read_box(r, 0, 0, 0, r->h.xres, r->h.yres, r->h.zres,
		                       (*out)->data, diag);
	if (rc) {
		loom_volbuf_free(*out);
		*out = NULL;
	} else if (h) {
		*h = r->h;
	}
	loom_vol_close(r);
	return rc;
}

/* ---- streaming writer ----------------------------------------------------- */

struct loom_vol_writer {
	loom__atomic file;
	loom_vol_header h;
	uint64_t vbytes;       /* bytes per voxel on disk */
	uint64_t total;        /* voxels declared */
	uint64_t written;      /* voxels appended so far */
	uint8_t buf[ENCODE_BUF_BYTES];
	int failed;
};

static void encode_voxels(const loom_vol_header *h, const float *src, size_t n,
                          uint8_t *dst)
{
	size_t nv = n * h->channels;

	switch (h->encoding) {
	case LOOM_VOL_FLOAT32:
		for (size_t i = 0; i < nv; i++)
			put_f32(dst + 4 * i, src[i]);
		break;
	case LOOM_VOL_FLOAT16:
		for (size_t i = 0; i < nv; i++) {
			uint16_t b = loom_half_from_float(src[i]);
			dst[2 * i] = (uint8_t)b;
			dst[2 * i + 1] = (uint8_t)(b >> 8);
		}
		break;
	case LOOM_VOL_UINT8:
		for (size_t i = 0; i < nv; i++) {
			float v = src[i];
			dst[i] = !(v > 0.0f) ? 0 : v >= 1.0f ? 255
			                                     : (uint8_t)lrintf(v * 255.0f);
		}
		break;
	case LOOM_VOL_QDIR:
		for (size_t i = 0; i < n; i++)
			loom_vol_qdir_encode(src + 3 * i, dst + 2 * i);
		break;
	default:
		break;
	}
}

LOOM_API int loom_vol_writer_open(const char *path, const loom_vol_header *h,
                                  loom_vol_writer **out, loom_diag *diag)
{
	loom_vol_writer *w;
	uint8_t hdr[LOOM_VOL_HEADER_BYTES];
	uint64_t bytes;
	int rc;

	if (!path || !h || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_writer_open: NULL argument");
	*out = NULL;
	rc = check_header(h, path, 0, diag);
	if (rc)
		return rc == LOOM_EFORMAT ? LOOM_EINVAL : rc;
	if (loom_vol_data_bytes(h, &bytes) != LOOM_OK)
		return loom__fail(diag, LOOM_ERANGE, "%s: %ux%ux%u volume too large",
		                  path, h->xres, h->yres, h->zres);
	w = calloc(1, sizeof *w);
	if (!w)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	w->h = *h;
	w->vbytes = voxel_bytes(h->encoding, h->channels);
	w->total = (uint64_t)h->xres * h->yres * h->zres;
	memcpy(hdr, "VOL", 3);
	hdr[3] = 3;
	put_u32(hdr + 4, (uint32_t)h->encoding);
	put_u32(hdr + 8, h->xres);
	put_u32(hdr + 12, h->yres);
	put_u32(hdr + 16, h->zres);
	put_u32(hdr + 20, h->channels);
	for (int i = 0; i < 3; i++) {
		put_f32(hdr + 24 + 4 * i, h->bbox_min[i]);
		put_f32(hdr + 36 + 4 * i, h->bbox_max[i]);
	}
	rc = loom__atomic_open(&w->file, path, diag);
	if (rc) {
		free(w);
		return rc;
	}
	if (fwrite(hdr, 1, sizeof hdr, w->file.fp) != sizeof hdr) {
		rc = loom__fail(diag, LOOM_EIO, "%s: write failed: %s", path,
		                strerror(errno));
		loom__atomic_abort(&w->file);
		free(w);
		return rc;
	}
	*out = w;
	return LOOM_OK;
}

LOOM_API int loom_vol_writer_put_voxels(loom_vol_writer *w, const float *values,
                                        uint64_t n_voxels, loom_diag *diag)
{
	size_t per;

	if (!w)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_writer_put_voxels: NULL writer");
	if (w->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: writer failed earlier",
		                  w->file.path);
	if (n_voxels > w->total - w->written) {
		w->failed = 1;
		return loom__fail(diag, LOOM_ERANGE,
		                  "%s: %llu voxels appended after %llu, the volume has "
		                  "only %llu (%ux%ux%u)",
		                  w->file.path, (unsigned long long)n_voxels,
		                  (unsigned long long)w->written,
		                  (unsigned long long)w->total, w->h.xres, w->h.yres,
		                  w->h.zres);
	}
	if (n_voxels && !values)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_writer_put_voxels: values is NULL");
	per = (size_t)(ENCODE_BUF_BYTES / w->vbytes); /* >= 256: channels <= 64 */
	while (n_voxels > 0) {
		size_t k = n_voxels < per ? (size_t)n_voxels : per;
		size_t nb = (size_t)(k * w->vbytes);
		encode_voxels(&w->h, values, k, w->buf);
		if (fwrite(w->buf, 1, nb, w->file.fp) != nb) {
			w->failed = 1;
			return loom__fail(diag, LOOM_EIO, "%s: write failed: %s",
			                  w->file.path, strerror(errno));
		}
		values += k * w->h.channels;
		n_voxels -= k;
		w->written += k;
	}
	return LOOM_OK;
}

LOOM_API int loom_vol_writer_put_slices(loom_vol_writer *w, const float *values,
                                        uint32_t n_slices, loom_diag *diag)
{
	if (!w)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_writer_put_slices: NULL writer");
	if (!w->failed && w->written % ((uint64_t)w->h.xres * w->h.yres) != 0) {
		w->failed = 1;
		return loom__fail(diag, LOOM_EINVAL,
		                  "%s: put_slices after a partial slice (%llu voxels "
		                  "written)",
		                  w->file.path, (unsigned long long)w->written);
	}
	return loom_vol_writer_put_voxels(
		w, values, (uint64_t)n_slices * w->h.xres * w->h.yres, diag);
}

LOOM_API int loom_vol_writer_finish(loom_vol_writer *w, loom_diag *diag)
{
	int rc;

	if (!w)
		return loom__fail(diag, LOOM_EINVAL, "loom_vol_writer_finish: NULL writer");
	if (w->failed) {
		rc = loom__fail(diag, LOOM_EUNUSABLE,
		                "%s: writer failed earlier; nothing written",
		                w->file.path);
		loom_vol_writer_abort(w);
		return rc;
	}
	if (w->written != w->total) {
		uint64_t slice = (uint64_t)w->h.xres * w->h.yres;
		rc = loom__fail(diag, LOOM_ETRUNCATED,
		                "%s: only %llu of %u z-slices written (%llu of %llu "
		                "voxels); file not created",
		                w->file.path, (unsigned long long)(w->written / slice),
		                w->h.zres, (unsigned long long)w->written,
		                (unsigned long long)w->total);
		loom_vol_writer_abort(w);
		return rc;
	}
	rc = loom__atomic_commit(&w->file, diag);
	free(w);
	return rc;
}

LOOM_API void loom_vol_writer_abort(loom_vol_writer *w)
{
	if (!w)
		return;
	loom__atomic_abort(&w->file);
	free(w);
}
