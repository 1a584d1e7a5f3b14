/*
 * io/volume/raw_read.c - raw volumes (headerless voxel arrays), scalar types,
 * half floats and the in-memory float volume (loom_volbuf).
 *
 * A raw volume is nx*ny*nz voxels of `channels` interleaved values of one
 * scalar type, x fastest, optionally after `offset` bytes of something
 * else.  Nothing in the file says how big it is, so the one defence
 * against wrong dimensions is the size check: the data must fill the file
 * exactly (unless the caller allows trailing bytes), and both the expected
 * and the actual size go into the message.  The NRRD reader reuses this
 * for raw-encoded NRRD data.
 *
 * Memory: whole reads allocate the float output only (the file is read in
 * 1 MiB pieces straight into conversion); the streaming reader owns one
 * 1 MiB buffer.
 */
#include "core/internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PIECE_BYTES (1u << 20)

/* ---- scalar types --------------------------------------------------- */

LOOM_API size_t loom_scalar_size(int type)
{
	switch (type) {
	case LOOM_SCALAR_U8:
	case LOOM_SCALAR_I8:
		return 1;
	case LOOM_SCALAR_U16:
	case LOOM_SCALAR_I16:
	case LOOM_SCALAR_F16:
		return 2;
	case LOOM_SCALAR_U32:
	case LOOM_SCALAR_I32:
	case LOOM_SCALAR_F32:
		return 4;
	case LOOM_SCALAR_F64:
		return 8;
	default:
		return 0;
	}
}

LOOM_API const char *loom_scalar_name(int type)
{
	static const char *const names[] = {"unknown", "u8",  "i8",  "u16", "i16",
	                                    "u32",     "i32", "f16", "f32", "f64"};
	if (type < LOOM_SCALAR_U8 || type > LOOM_SCALAR_F64)
		return names[0];
	return names[type];
}

LOOM_API int loom_scalar_parse(const char *name, int *type)
{
	static const struct {
		const char *name;
		int type;
	} tab[] = {
		{"u8", LOOM_SCALAR_U8},     {"uint8", LOOM_SCALAR_U8},
		{"uchar", LOOM_SCALAR_U8},  {"i8", LOOM_SCALAR_I8},
		{"int8", LOOM_SCALAR_I8},   {"u16", LOOM_SCALAR_U16},
		{"uint16", LOOM_SCALAR_U16}, {"ushort", LOOM_SCALAR_U16},
		{"i16", LOOM_SCALAR_I16},   {"int16", LOOM_SCALAR_I16},
		{"short", LOOM_SCALAR_I16}, {"u32", LOOM_SCALAR_U32},
		{"uint32", LOOM_SCALAR_U32}, {"uint", LOOM_SCALAR_U32},
		{"i32", LOOM_SCALAR_I32},   {"int32", LOOM_SCALAR_I32},
		{"int", LOOM_SCALAR_I32},   {"f16", LOOM_SCALAR_F16},
		{"half", LOOM_SCALAR_F16},  {"float16", LOOM_SCALAR_F16},
		{"f32", LOOM_SCALAR_F32},   {"float", LOOM_SCALAR_F32},
		{"float32", LOOM_SCALAR_F32}, {"f64", LOOM_SCALAR_F64},
		{"double", LOOM_SCALAR_F64}, {"float64", LOOM_SCALAR_F64},
	};
	if (!name || !type)
		return LOOM_EINVAL;
	for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
		if (loom__strieq(name, tab[i].name)) {
			*type = tab[i].type;
			return LOOM_OK;
		}
	return LOOM_EINVAL;
}

/* ---- half floats ------------------------------------------------------ */

LOOM_API float loom_half_to_float(uint16_t h)
{
	uint32_t sign = (uint32_t)(h >> 15) << 31;
	uint32_t exp = (h >> 10) & 0x1f;
	uint32_t man = h & 0x3ff;
	uint32_t bits;
	float f;

	if (exp == 0x1f) {
		bits = sign | 0x7f800000u | (man << 13); /* inf / NaN (payload kept) */
	} else if (exp != 0) {
		bits = sign | ((exp + 112) << 23) | (man << 13);
	} else if (man == 0) {
		bits = sign;
	} else {
		/* subnormal: man * 2^-24, exact in float */
		f = (float)man * 0x1p-24f;
		return sign ? -f : f;
	}
	memcpy(&f, &bits, 4);
	return f;
}

LOOM_API uint16_t loom_half_from_float(float f)
{
	uint32_t bits;
	uint16_t sign;
	uint32_t exp, man;

	memcpy(&bits, &f, 4);
	sign = (uint16_t)((bits >> 16) & 0x8000);
	exp = (bits >> 23) & 0xff;
	man = bits & 0x7fffff;
	if (exp == 0xff) /* inf, NaN (keep it a NaN: set the top mantissa bit) */
		return (uint16_t)(sign | 0x7c00 | (man ? 0x200 | (man >> 13) : 0));
	if (exp > 142) /* >= 2^16: beyond the largest half (65504) after rounding */
		return (uint16_t)(sign | 0x7c00);
	if (exp >= 113) { /* normal half: rebias 127 -> 15, round to nearest even */
		uint32_t h = ((exp - 112) << 10) | (man >> 13);
		uint32_t rest = man & 0x1fff;
		if (rest > 0x1000 || (rest == 0x1000 && (h & 1)))
			h++; /* may carry into the exponent, up to infinity: correct */
		return (uint16_t)(sign | h);
	}
	if (exp >= 102) { /* subnormal half: value = m * 2^-24 */
		uint32_t m = man | 0x800000; /* 24-bit significand */
		uint32_t shift = 126 - exp;  /* 14 .. 24 */
		uint32_t h = m >> shift;
		uint32_t rest = m & ((1u << shift) - 1);
		uint32_t halfway = 1u << (shift - 1);
		if (rest > halfway || (rest == halfway && (h & 1)))
			h++;
		return (uint16_t)(sign | h);
	}
	return sign; /* underflows to zero */
}

/* ---- loom_volbuf ------------------------------------------------------ */

LOOM_API int loom_volbuf_new(uint32_t nx, uint32_t ny, uint32_t nz,
                             uint32_t channels, size_t max_bytes,
                             loom_volbuf **out, loom_diag *diag)
{
	size_t n, bytes;
	loom_volbuf *v;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "loom_volbuf_new: out is NULL");
	*out = NULL;
	if (!nx || !ny || !nz || !channels)
		return loom__fail(diag, LOOM_EINVAL,
		                  "volume %ux%ux%u with %u channels is empty", nx, ny,
		                  nz, channels);
	if (!loom__mul_ok(nx, ny, &n) || !loom__mul_ok(n, nz, &n) ||
	    !loom__mul_ok(n, channels, &n) || !loom__mul_ok(n, sizeof(float), &bytes))
		return loom__fail(diag, LOOM_ERANGE,
		                  "volume %ux%ux%u with %u channels is too large to hold",
		                  nx, ny, nz, channels);
	if (max_bytes && bytes > max_bytes)
		return loom__fail(diag, LOOM_EBUDGET,
		                  "volume %ux%ux%u with %u channels needs %zu bytes as "
		                  "floats, over the %zu-byte limit",
		                  nx, ny, nz, channels, bytes, max_bytes);
	v = calloc(1, sizeof *v);
	if (v)
		v->data = calloc(n, sizeof(float));
	if (!v || !v->data) {
		free(v);
		return loom__fail(diag, LOOM_ENOMEM,
		                  "volume %ux%ux%u with %u channels: cannot allocate "
		                  "%zu bytes",
		                  nx, ny, nz, channels, bytes);
	}
	v->nx = nx;
	v->ny = ny;
	v->nz = nz;
	v->channels = channels;
	for (int a = 0; a < 3; a++) {
		v->spacing[a] = 1.0;
		v->origin[a] = 0.0;
	}
	v->source_type = LOOM_SCALAR_F32;
	*out = v;
	return LOOM_OK;
}

LOOM_API void loom_volbuf_free(loom_volbuf *v)
{
	if (!v)
		return;
	free(v->data);
	free(v);
}

/* ---- conversion ------------------------------------------------------- */

static uint64_t load_uint(const uint8_t *p, size_t size, int big)
{
	uint64_t v = 0;
	if (big)
		for (size_t i = 0; i < size; i++)
			v = (v << 8) | p[i];
	else
		for (size_t i = size; i-- > 0;)
			v = (v << 8) | p[i];
	return v;
}

/* Convert n stored values to floats. */
static void convert(const uint8_t *src, size_t n, int type, int big,
                    int normalize, float *dst)
{
	size_t sz = loom_scalar_size(type);

	switch (type) {
	case LOOM_SCALAR_U8:
		for (size_t i = 0; i < n; i++)
			dst[i] = normalize ? (float)src[i] / 255.0f : (float)src[i];
		break;
	case LOOM_SCALAR_I8:
		for (size_t i = 0; i < n; i++) {
			float v = (float)(int8_t)src[i];
			dst[i] = normalize ? v / 127.0f : v;
		}
		break;
	case LOOM_SCALAR_U16:
		for (size_t i = 0; i < n; i++) {
			float v = (float)load_uint(src + 2 * i, 2, big);
			dst[i] = normalize ? v / 65535.0f : v;
		}
		break;
	case LOOM_SCALAR_I16:
		for (size_t i = 0; i < n; i++) {
			float v = (float)(int16_t)(uint16_t)load_uint(src + 2 * i, 2, big);
			dst[i] = normalize ? v / 32767.0f : v;
		}
		break;
	case LOOM_SCALAR_U32:
		for (size_t i = 0; i < n; i++) {
			double v = (double)load_uint(src + 4 * i, 4, big);
			dst[i] = (float)(normalize ? v / 4294967295.0 : v);
		}
		break;
	case LOOM_SCALAR_I32:
		for (size_t i = 0; i < n; i++) {
			double v = (double)(int32_t)(uint32_t)load_uint(src + 4 * i, 4, big);
			dst[i] = (float)(normalize ? v / 2147483647.0 : v);
		}
		break;
	case LOOM_SCALAR_F16:
		for (size_t i = 0; i < n; i++)
			dst[i] = loom_half_to_float((uint16_t)load_uint(src + 2 * i, 2, big));
		break;
	case LOOM_SCALAR_F32:
		for (size_t i = 0; i < n; i++) {
			uint32_t b = (uint32_t)load_uint(src + 4 * i, 4, big);
			memcpy(&dst[i], &b, 4);
		}
		break;
	case LOOM_SCALAR_F64:
		for (size_t i = 0; i < n; i++) {
			uint64_t b = load_uint(src + 8 * i, 8, big);
			double d;
			memcpy(&d, &b, 8);
			dst[i] = (float)d;
		}
		break;
	default:
		(void)sz;
		break;
	}
}

/* ---- parameters and size checks ---------------------------------------- */

typedef struct raw_layout {
	uint64_t n_values;     /* nx*ny*nz*channels */
	uint64_t data_bytes;   /* n_values * size */
	uint64_t offset;       /* where the data start in the file */
	size_t elem;           /* bytes per value */
} raw_layout;

static int check_params(const loom_raw_params *p, const char *name,
                        loom_diag *diag)
{
	if (!p)
		return loom__fail(diag, LOOM_EINVAL, "%s: raw parameters are NULL", name);
	if (p->size < sizeof(loom_raw_params))
		return loom__fail(diag, LOOM_EINVAL,
		                  "%s: raw parameters not initialised with "
		                  "LOOM_RAW_PARAMS_INIT (size %zu)",
		                  name, p->size);
	if (!p->nx || !p->ny || !p->nz || !p->channels)
		return loom__fail(diag, LOOM_EINVAL,
		                  "%s: raw dimensions %ux%ux%u with %u channels: every "
		                  "one must be at least 1",
		                  name, p->nx, p->ny, p->nz, p->channels);
	if (!loom_scalar_size(p->type))
		return loom__fail(diag, LOOM_EINVAL, "%s: unknown raw value type %d",
		                  name, p->type);
	return LOOM_OK;
}

/* Work out where the data are in a file of file_bytes bytes, and check the
   size.  See the file comment. */
static int layout_for(const loom_raw_params *p, uint64_t file_bytes,
                      const char *name, raw_layout *L, loom_diag *diag)
{
	int rc = check_params(p, name, diag);
	uint64_t n;

	if (rc)
		return rc;
	L->elem = loom_scalar_size(p->type);
	n = (uint64_t)p->nx * p->ny; /* < 2^64 */
	if (n > UINT64_MAX / p->nz || n * p->nz > UINT64_MAX / p->channels ||
	    n * p->nz * p->channels > (UINT64_MAX >> 1) / L->elem)
		return loom__fail(diag, LOOM_ERANGE,
		                  "%s: raw dimensions %ux%ux%u x %u channels overflow",
		                  name, p->nx, p->ny, p->nz, p->channels);
	L->n_values = n * p->nz * p->channels;
	L->data_bytes = L->n_values * L->elem;
	if (p->flags & LOOM_RAW_DATA_AT_END) {
		if (file_bytes < L->data_bytes)
			return loom__fail(diag, LOOM_ETRUNCATED,
			                  "%s: truncated: %ux%ux%u x %u %s values need "
			                  "%llu bytes, the file has only %llu",
			                  name, p->nx, p->ny, p->nz, p->channels,
			                  loom_scalar_name(p->type),
			                  (unsigned long long)L->data_bytes,
			                  (unsigned long long)file_bytes);
		L->offset = file_bytes - L->data_bytes;
		return LOOM_OK;
	}
	L->offset = p->offset;
	if (p->offset > file_bytes || file_bytes - p->offset < L->data_bytes)
		return loom__fail(diag, LOOM_ETRUNCATED,
		                  "%s: truncated at byte %llu: %ux%ux%u x %u %s values "
		                  "need %llu bytes from byte %llu (file size %llu "
		                  "expected), the file has %llu bytes",
		                  name, (unsigned long long)file_bytes, p->nx, p->ny,
		                  p->nz, p->channels, loom_scalar_name(p->type),
		                  (unsigned long long)L->data_bytes,
		                  (unsigned long long)p->offset,
		                  (unsigned long long)(p->offset + L->data_bytes),
		                  (unsigned long long)file_bytes);
	if (file_bytes - p->offset > L->data_bytes &&
	    !(p->flags & LOOM_RAW_ALLOW_TRAILING))
		return loom__fail(diag, LOOM_ECORRUPT,
		                  "%s: size mismatch: %ux%ux%u x %u %s values need "
		                  "%llu bytes from byte %llu (file size %llu), the "
		                  "file has %llu (%llu extra bytes at byte %llu): "
		                  "wrong dimensions or type?",
		                  name, p->nx, p->ny, p->nz, p->channels,
		                  loom_scalar_name(p->type),
		                  (unsigned long long)L->data_bytes,
		                  (unsigned long long)p->offset,
		                  (unsigned long long)(p->offset + L->data_bytes),
		                  (unsigned long long)file_bytes,
		                  (unsigned long long)(file_bytes - p->offset -
		                                       L->data_bytes),
		                  (unsigned long long)(p->offset + L->data_bytes));
	return LOOM_OK;
}

static int new_volbuf(const loom_raw_params *p, const char *name,
                      size_t max_bytes, loom_volbuf **out, loom_diag *diag)
{
	int rc = loom_volbuf_new(p->nx, p->ny, p->nz, p->channels, max_bytes, out,
	                         diag);
	if (rc) {
		char msg[LOOM_DIAG_MSG_MAX];
		if (diag) {
			snprintf(msg, sizeof msg, "%s", diag->message);
			loom__fail(diag, rc, "%s: %s", name, msg);
		}
		return rc;
	}
	for (int a = 0; a < 3; a++) {
		(*out)->spacing[a] = p->spacing[a];
		(*out)->origin[a] = p->origin[a];
	}
	(*out)->source_type = p->type;
	return LOOM_OK;
}

LOOM_API int loom_raw_parse(const uint8_t *data, size_t len, const char *name,
                            const loom_raw_params *p, size_t max_bytes,
                            loom_volbuf **out, loom_diag *diag)
{
	raw_layout L;
	int rc;

	if (!name)
		name = "raw";
	if (!out || (!data && len))
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL argument", name);
	*out = NULL;
	rc = layout_for(p, len, name, &L, diag);
	if (rc)
		return rc;
	rc = new_volbuf(p, name, max_bytes, out, diag);
	if (rc)
		return rc;
	convert(data + L.offset, (size_t)L.n_values, p->type, p->big_endian,
	        (p->flags & LOOM_RAW_NORMALIZE) != 0, (*out)->data);
	return LOOM_OK;
}

/* ---- streaming reader -------------------------------------------------- */

struct loom_raw_reader {
	int fd;
	char *path;
	loom_raw_params p;
	raw_layout L;
	uint64_t slice_values; /* nx*ny*channels */
	uint8_t *buf;          /* PIECE_BYTES */
	int failed;
};

LOOM_API int loom_raw_open(const char *path, const loom_raw_params *p,
                           loom_raw_reader **out, loom_diag *diag)
{
	loom_raw_reader *r;
	uint64_t fsize;
	int rc;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_raw_open: NULL argument");
	*out = NULL;
	rc = check_params(p, path, diag);
	if (rc)
		return rc;
	r = calloc(1, sizeof *r);
	if (!r)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	rc = loom__open_input(path, &r->fd, &fsize, diag);
	if (rc) {
		free(r);
		return rc;
	}
	rc = layout_for(p, fsize, path, &r->L, diag);
	if (rc)
		goto fail;
	r->p = *p;
	r->slice_values = (uint64_t)p->nx * p->ny * p->channels;
	r->path = strdup(path);
	r->buf = malloc(PIECE_BYTES);
	if (!r->path || !r->buf) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
		goto fail;
	}
	*out = r;
	return LOOM_OK;
fail:
	loom_raw_close(r);
	return rc;
}

/* Read n values starting at value index first into dst. */
static int read_values(loom_raw_reader *r, uint64_t first, uint64_t n,
                       float *dst, loom_diag *diag)
{
	size_t per = PIECE_BYTES / r->L.elem;
	uint64_t pos = r->L.offset + first * r->L.elem;

	while (n > 0) {
		size_t k = n < per ? (size_t)n : per;
		size_t want = k * r->L.elem, got = 0;
		while (got < want) {
			ssize_t m = pread(r->fd, r->buf + got, want - got, (off_t)(pos + got));
			if (m < 0 && errno == EINTR)
				continue;
			if (m < 0)
				return loom__fail(diag, LOOM_EIO, "%s: read error at byte %llu: %s",
				                  r->path, (unsigned long long)(pos + got),
				                  strerror(errno));
			if (m == 0)
				return loom__fail(diag, LOOM_ETRUNCATED,
				                  "%s: file shrank: end of file at byte %llu",
				                  r->path, (unsigned long long)(pos + got));
			got += (size_t)m;
		}
		convert(r->buf, k, r->p.type, r->p.big_endian,
		        (r->p.flags & LOOM_RAW_NORMALIZE) != 0, dst);
		dst += k;
		n -= k;
		pos += want;
	}
	return LOOM_OK;
}

LOOM_API int loom_raw_read_slices(loom_raw_reader *r, uint32_t z0, uint32_t nz,
                                  float *out, loom_diag *diag)
{
	int rc;

	if (!r || (!out && nz))
		return loom__fail(diag, LOOM_EINVAL, "loom_raw_read_slices: NULL argument");
	if (r->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: reader failed earlier",
		                  r->path);
	if (z0 > r->p.nz || nz > r->p.nz - z0)
		return loom__fail(diag, LOOM_ERANGE,
		                  "%s: slices %u..%u requested, the volume has %u", r->path,
		                  z0, z0 + nz, r->p.nz);
	rc = read_values(r, (uint64_t)z0 * r->slice_values,
	                 (uint64_t)nz * r->slice_values, out, diag);
	if (rc)
		r->failed = 1;
	return rc;
}

LOOM_API void loom_raw_close(loom_raw_reader *r)
{
	if (!r)
		return;
	if (r->fd >= 0)
		close(r->fd);
	free(r->buf);
	free(r->path);
	free(r);
}

LOOM_API int loom_raw_read(const char *path, const loom_raw_params *p,
                           size_t max_bytes, loom_volbuf **out,
                           loom_diag *diag)
{
	loom_raw_reader *r;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "loom_raw_read: out is NULL");
	*out = NULL;
	rc = loom_raw_open(path, p, &r, diag);
	if (rc)
		return rc;
	rc = new_volbuf(p, path, max_bytes, out, diag);
	if (!rc) {
		rc = read_values(r, 0, r->L.n_values, (*out)->data, diag);
		if (rc) {
			loom_volbuf_free(*out);
			*out = NULL;
		}
	}
	loom_raw_close(r);
	return rc;
}
