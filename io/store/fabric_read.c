/*
 * io/store/fabric_read.c - the fabric file (.loomf): validating reader
 * (the writer is fabric_write.c).
 * Byte-level specification: docs/formats.md, "Fabric file".  Little-endian
 * throughout.
 *
 *   +-----------------------+ 0
 *   | header (64 B)         |  magic, version, rows, cols, n_sections, CRC
 *   +-----------------------+ 64
 *   | section PARM          |  each section: 32-byte section header (tag,
 *   | section YARN          |  encoding, raw and stored sizes, CRC-32 of
 *   | section WEAV          |  the stored body, header CRC) + stored body;
 *   | section WARP          |  body = the raw payload (encoding 0) or a
 *   | section WEFT          |  sequence of chunks of <= 1 MiB raw each, raw
 *   | section BASE          |  DEFLATE or stored (encoding 1)
 *   | section EDGE          |
 *   | section METR          |
 *   +-----------------------+ file size - 32
 *   | trailer (32 B)        |  magic, file size, n_sections, CRC: written
 *   +-----------------------+  last, so a truncated file has none
 *
 * Writer: streams every section through one 1 MiB buffer (memory bounded
 * whatever the design size), writes a placeholder section header, then
 * seeks back to fill in sizes and CRC; atomic (loom__atomic_*).
 *
 * Reader, step by step:
 *   1. header: magic, version, CRC, sizes;
 *   2. trailer: magic (else truncated), CRC, file size;
 *   3. walk the section headers: header CRC, tag order, sizes inside the
 *      file, plausible raw sizes (DEFLATE cannot expand more than 1032:1,
 *      so a small file cannot make the reader allocate a huge design);
 *      the CRC-32 of every body is checked here, before any parsing;
 *   4. parse the sections in order, checking every count, value and index
 *      (types < n_types, base entries < K, finite floats);
 *   5. the tables: loom_edgefix_from_tables (or none: rebuilt at bind).
 */
#include "fabric_format.h"
#include "io/core/file.h"

#include <errno.h>
#include <fcntl.h>
#include <libdeflate.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ======================================================================
 * Reader
 * ====================================================================== */

typedef struct fab_section {
	uint64_t body;         /* absolute offset of the body */
	uint64_t raw_bytes, stored_bytes;
	uint32_t enc;
} fab_section;

typedef struct fab_reader {
	const char *name;
	loom_diag *diag;
	int fd;                /* -1 when reading memory */
	const uint8_t *mem;
	uint64_t size;
	struct libdeflate_decompressor *dec;
	uint8_t *stored;       /* min(FAB_CHUNK, file size + 1) */
	uint8_t *raw;          /* min(FAB_CHUNK, largest section's raw size) */
	fab_section sec[FAB_N_SECTIONS];
} fab_reader;

/* Read exactly n bytes at off (the caller checked off + n <= size). */
static int r_at(fab_reader *r, uint64_t off, void *buf, size_t n)
{
	size_t done = 0;
	if (r->mem) {
		memcpy(buf, r->mem + off, n);
		return LOOM_OK;
	}
	while (done < n) {
		ssize_t got = pread(r->fd, (uint8_t *)buf + done, n - done,
		                    (off_t)(off + done));
		if (got < 0 && errno == EINTR)
			continue;
		if (got <= 0)
			return loom__fail(r->diag, got < 0 ? LOOM_EIO : LOOM_ETRUNCATED,
			                  "%s: read at byte %llu failed: %s", r->name,
			                  (unsigned long long)(off + done),
			                  got < 0 ? strerror(errno) : "end of file");
		done += (size_t)got;
	}
	return LOOM_OK;
}

/* Consumes raw payload bytes [off, off + n); returns a result code. */
typedef int (*consume_fn)(void *ctx, fab_reader *r, uint64_t off,
                          const uint8_t *buf, size_t n);

/* Stream the raw payload of section idx to fn (the CRC is already
   checked). */
static int read_payload(fab_reader *r, unsigned idx, consume_fn fn, void *ctx)
{
	const fab_section *s = &r->sec[idx];
	const char *tag = fab_tags[idx];
	uint64_t pos = s->body, end = s->body + s->stored_bytes, off = 0;
	int rc;

	if (s->enc == FAB_ENC_RAW) {
		for (; off < s->raw_bytes; off += FAB_CHUNK) {
			size_t n = s->raw_bytes - off < FAB_CHUNK ? (size_t)(s->raw_bytes - off)
			                                          : FAB_CHUNK;
			rc = r_at(r, pos + off, r->raw, n);
			if (!rc)
				rc = fn(ctx, r, off, r->raw, n);
			if (rc)
				return rc;
		}
		return LOOM_OK;
	}
	for (; off < s->raw_bytes; off += FAB_CHUNK) {
		size_t n = s->raw_bytes - off < FAB_CHUNK ? (size_t)(s->raw_bytes - off)
		                                          : FAB_CHUNK;
		uint8_t ch[8];
		uint32_t len, kind;
		if (end - pos < 8)
			return loom__fail(r->diag, LOOM_EFORMAT,
			                  "%s: section %s: chunk at byte %llu: header past the "
			                  "section end", r->name, tag, (unsigned long long)pos);
		rc = r_at(r, pos, ch, 8);
		if (rc)
			return rc;
		len = get32(ch);
		kind = get32(ch + 4);
		if (kind > FAB_CHUNK_STORED || len > end - pos - 8 || len > FAB_CHUNK ||
		    (kind == FAB_CHUNK_STORED && len != n) || (kind == FAB_CHUNK_DEFLATE && len == 0))
			return loom__fail(r->diag, LOOM_EFORMAT,
			                  "%s: section %s: chunk at byte %llu: kind %u, %u "
			                  "stored bytes for %zu raw bytes (%llu left in the "
			                  "section)", r->name, tag, (unsigned long long)pos, kind,
			                  len, n, (unsigned long long)(end - pos - 8));
		rc = r_at(r, pos + 8, kind == FAB_CHUNK_STORED ? r->raw : r->stored, len);
		if (rc)
			return rc;
		if (kind == FAB_CHUNK_DEFLATE &&
		    libdeflate_deflate_decompress(r->dec, r->stored, len, r->raw, n, NULL) !=
		        LIBDEFLATE_SUCCESS)
			return loom__fail(r->diag, LOOM_ECORRUPT,
			                  "%s: section %s: chunk at byte %llu does not inflate to "
			                  "exactly %zu bytes", r->name, tag,
			                  (unsigned long long)pos, n);
		rc = fn(ctx, r, off, r->raw, n);
		if (rc)
			return rc;
		pos += 8 + (uint64_t)len;
	}
	if (pos != end)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: section %s: %llu bytes after the last chunk",
		                  r->name, tag, (unsigned long long)(end - pos));
	return LOOM_OK;
}

static int consume_mem(void *ctx, fab_reader *r, uint64_t off, const uint8_t *buf,
                       size_t n)
{
	(void)r;
	memcpy((uint8_t *)ctx + off, buf, n);
	return LOOM_OK;
}

/* Whole payload of a small section into a new buffer of raw_bytes (the
   walk bounded raw_bytes for these sections). */
static int read_small(fab_reader *r, unsigned idx, uint8_t **out)
{
	uint8_t *p = malloc(r->sec[idx].raw_bytes ? (size_t)r->sec[idx].raw_bytes : 1);
	int rc;
	*out = NULL;
	if (!p)
		return loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory", r->name);
	rc = read_payload(r, idx, consume_mem, p);
	if (rc) {
		free(p);
		return rc;
	}
	*out = p;
	return LOOM_OK;
}

/* ---- steps 1-3: header, trailer, section walk ------------------------------ */

static int check_zero(const uint8_t *p, size_t n)
{
	for (size_t k = 0; k < n; k++)
		if (p[k])
			return 0;
	return 1;
}

static int read_header(fab_reader *r, uint32_t *rows, uint32_t *cols)
{
	uint8_t h[FAB_HEADER_BYTES];
	size_t have = r->size < FAB_HEADER_BYTES ? (size_t)r->size : FAB_HEADER_BYTES;
	uint32_t v;
	int rc = r_at(r, 0, h, have);

	if (rc)
		return rc;
	if (memcmp(h, FAB_MAGIC, have < 8 ? have : 8) != 0)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: not a loom fabric file (bad magic at byte 0)", r->name);
	if (r->size < FAB_HEADER_BYTES + FAB_TRAILER_BYTES)
		return loom__fail(r->diag, LOOM_ETRUNCATED,
		                  "%s: %llu bytes, a fabric file has at least %u", r->name,
		                  (unsigned long long)r->size,
		                  FAB_HEADER_BYTES + FAB_TRAILER_BYTES);
	v = get32(h + 8);
	if (v != FAB_VERSION)
		return loom__fail(r->diag, LOOM_EVERSION,
		                  "%s: fabric format version %u, this loom reads version %u",
		                  r->name, v, FAB_VERSION);
	if (get32(h + 60) != libdeflate_crc32(0, h, 60))
		return loom__fail(r->diag, LOOM_ECORRUPT, "%s: header CRC-32 mismatch",
		                  r->name);
	*rows = get32(h + 16);
	*cols = get32(h + 20);
	if (get32(h + 12) != FAB_HEADER_BYTES || get32(h + 24) != FAB_N_SECTIONS ||
	    get32(h + 28) != 0 || !check_zero(h + 32, 28))
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: header: header_bytes %u (expected 64), n_sections %u "
		                  "(expected 8), flags %u and reserved bytes (expected 0)",
		                  r->name, get32(h + 12), get32(h + 24), get32(h + 28));
	if (*rows == 0 || *cols == 0 || *rows > LOOM_DESIGN_MAX_SIDE ||
	    *cols > LOOM_DESIGN_MAX_SIDE ||
	    (uint64_t)*rows * *cols > LOOM_DESIGN_MAX_CELLS)
		return loom__fail(r->diag, LOOM_ERANGE,
		                  "%s: header: design %ux%u out of range (sides 1..%u, at "
		                  "most 2^32 crossings)", r->name, *rows, *cols,
		                  LOOM_DESIGN_MAX_SIDE);
	return LOOM_OK;
}

static int read_trailer(fab_reader *r)
{
	uint8_t t[FAB_TRAILER_BYTES];
	int rc = r_at(r, r->size - FAB_TRAILER_BYTES, t, sizeof t);

	if (rc)
		return rc;
	if (memcmp(t, FAB_TRAILER_MAGIC, 8) != 0)
		return loom__fail(r->diag, LOOM_ETRUNCATED,
		                  "%s: no trailer in the last 32 bytes: the file is truncated "
		                  "or was not completely written", r->name);
	if (get32(t + 28) != libdeflate_crc32(0, t, 28))
		return loom__fail(r->diag, LOOM_ECORRUPT, "%s: trailer CRC-32 mismatch",
		                  r->name);
	if (get64(t + 8) != r->size)
		return loom__fail(r->diag, get64(t + 8) > r->size ? LOOM_ETRUNCATED
		                                                  : LOOM_EFORMAT,
		                  "%s: trailer says %llu bytes, the file has %llu", r->name,
		                  (unsigned long long)get64(t + 8),
		                  (unsigned long long)r->size);
	if (get32(t + 16) != FAB_N_SECTIONS || !check_zero(t + 20, 8))
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: trailer: n_sections %u (expected 8) or reserved bytes "
		                  "not 0", r->name, get32(t + 16));
	return LOOM_OK;
}

/* CRC-32 of a section body, streamed through r->stored. */
static int body_crc(fab_reader *r, const fab_section *s, uint32_t *crc)
{
	uint32_t c = 0;
	for (uint64_t off = 0; off < s->stored_bytes; off += FAB_CHUNK) {
		size_t n = s->stored_bytes - off < FAB_CHUNK ? (size_t)(s->stored_bytes - off)
		                                             : FAB_CHUNK;
		int rc = r_at(r, s->body + off, r->stored, n);
		if (rc)
			return rc;
		c = libdeflate_crc32(c, r->stored, n);
	}
	*crc = c;
	return LOOM_OK;
}

static int walk_sections(fab_reader *r, uint64_t crossings)
{
	uint64_t pos = FAB_HEADER_BYTES, end = r->size - FAB_TRAILER_BYTES;

	for (unsigned k = 0; k < FAB_N_SECTIONS; k++) {
		fab_section *s = &r->sec[k];
		uint8_t h[FAB_SECTION_BYTES];
		uint32_t crc;
		uint64_t chunks, limit;
		int rc;

		if (end - pos < FAB_SECTION_BYTES)
			return loom__fail(r->diag, LOOM_ETRUNCATED,
			                  "%s: section %s: header at byte %llu past the end of "
			                  "the sections", r->name, fab_tags[k],
			                  (unsigned long long)pos);
		rc = r_at(r, pos, h, sizeof h);
		if (rc)
			return rc;
		if (get32(h + 28) != libdeflate_crc32(0, h, 28))
			return loom__fail(r->diag, LOOM_ECORRUPT,
			                  "%s: section %u (expected %s) at byte %llu: header "
			                  "CRC-32 mismatch", r->name, k, fab_tags[k],
			                  (unsigned long long)pos);
		if (memcmp(h, fab_tags[k], 4) != 0)
			return loom__fail(r->diag, LOOM_EFORMAT,
			                  "%s: section %u at byte %llu: tag '%.4s', expected "
			                  "'%s'", r->name, k, (unsigned long long)pos,
			                  (const char *)h, fab_tags[k]);
		s->enc = get32(h + 4);
		s->raw_bytes = get64(h + 8);
		s->stored_bytes = get64(h + 16);
		s->body = pos + FAB_SECTION_BYTES;
		if (s->enc > FAB_ENC_CHUNKED || s->stored_bytes > end - s->body)
			return loom__fail(r->diag, LOOM_EFORMAT,
			                  "%s: section %s at byte %llu: encoding %u, %llu stored "
			                  "bytes (%llu left before the trailer)", r->name,
			                  fab_tags[k], (unsigned long long)pos, s->enc,
			                  (unsigned long long)s->stored_bytes,
			                  (unsigned long long)(end - s->body));
		/* Plausible sizes: raw = stored, or chunk headers present and no
		   chunk expanding beyond DEFLATE's limit. */
		chunks = (s->raw_bytes + FAB_CHUNK - 1) / FAB_CHUNK;
		limit = s->stored_bytes * FAB_MAX_RATIO + 64;
		if ((s->enc == FAB_ENC_RAW && s->raw_bytes != s->stored_bytes) ||
		    (s->enc == FAB_ENC_CHUNKED &&
		     (s->stored_bytes < 8 * chunks || s->raw_bytes > limit)))
			return loom__fail(r->diag, LOOM_EFORMAT,
			                  "%s: section %s at byte %llu: %llu raw bytes cannot "
			                  "come from %llu stored bytes", r->name, fab_tags[k],
			                  (unsigned long long)pos,
			                  (unsigned long long)s->raw_bytes,
			                  (unsigned long long)s->stored_bytes);
		rc = body_crc(r, s, &crc);
		if (rc)
			return rc;
		if (crc != get32(h + 24))
			return loom__fail(r->diag, LOOM_ECORRUPT,
			                  "%s: section %s at byte %llu: CRC-32 of the %llu-byte "
			                  "body is %08x, the header says %08x", r->name,
			                  fab_tags[k], (unsigned long long)pos,
			                  (unsigned long long)s->stored_bytes, crc,
			                  get32(h + 24));
		pos = s->body + s->stored_bytes;
	}
	if (pos != end)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: %llu bytes between the last section and the trailer",
		                  r->name, (unsigned long long)(end - pos));
	/* the base holds 1 or 2 bytes per crossing: this bounds the design */
	if (r->sec[S_BASE].raw_bytes != crossings &&
	    r->sec[S_BASE].raw_bytes / 2 != crossings)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: section BASE: %llu raw bytes for %llu crossings",
		                  r->name, (unsigned long long)r->sec[S_BASE].raw_bytes,
		                  (unsigned long long)crossings);
	/* small sections are read whole */
	if (r->sec[S_PARM].raw_bytes > FAB_PARM_BYTES + FAB_MAX_PATH ||
	    r->sec[S_YARN].raw_bytes > 8 + FAB_YARN_BYTES * LOOM_MAX_YARN_TYPES ||
	    r->sec[S_METR].raw_bytes > FAB_METR_FIXED + 8 * 4096 ||
	    r->sec[S_EDGE].raw_bytes > LOOM__FABRIC_EDGE_MAX)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: section PARM, YARN, EDGE or METR larger than the "
		                  "format allows", r->name);
	return LOOM_OK;
}

/* ---- step 4: sections ------------------------------------------------------ */

static int parse_parm(fab_reader *r, loom_fabric *f)
{
	uint8_t *p;
	uint64_t n = r->sec[S_PARM].raw_bytes;
	uint32_t pl;
	int rc;

	if (n < FAB_PARM_BYTES)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: section PARM: %llu bytes, expected at least %u",
		                  r->name, (unsigned long long)n, FAB_PARM_BYTES);
	rc = read_small(r, S_PARM, &p);
	if (rc)
		return rc;
	f->params.algo = (int)get32(p);
	f->params.flags = get32(p + 4);
	f->params.seed = get64(p + 8);
	f->params.group = get32(p + 16);
	f->params.rank = get32(p + 20);
	f->n_exemplars = get32(p + 24);
	f->n_blocks = get32(p + 28);
	f->b1 = get32(p + 32);
	f->b2 = get32(p + 36);
	f->b3 = get32(p + 40);
	f->voxel_size_um = getf(p + 44);
	f->db_hash = get64(p + 48);
	f->params.base_width = get32(p + 56);
	pl = get32(p + 60);
	rc = LOOM_EFORMAT;
	if (get32(p) > LOOM_SYNTH_IDENTITY)
		loom__fail(r->diag, rc, "%s: PARM: algorithm %u (expected 0..3)", r->name, get32(p));
	else if (f->params.flags & ~3u)
		loom__fail(r->diag, rc, "%s: PARM: flags 0x%x", r->name, f->params.flags);
	else if (f->params.group > 65536)
		loom__fail(r->diag, rc, "%s: PARM: group %u (expected 0..65536)", r->name,
		           f->params.group);
	else if (f->params.rank > LOOM_EDGEFIX_MAX_RANK)
		loom__fail(r->diag, rc, "%s: PARM: rank %u (expected 0..%u)", r->name,
		           f->params.rank, LOOM_EDGEFIX_MAX_RANK);
	else if (f->n_exemplars < 1 || f->n_exemplars > 4096 || f->n_blocks < 1 ||
	         f->n_blocks > LOOM_SYNTH_MAX_BLOCKS)
		loom__fail(r->diag, rc, "%s: PARM: %u exemplars, %u blocks", r->name,
		           f->n_exemplars, f->n_blocks);
	else if (f->b1 < 3 || f->b2 < 3 || f->b3 < 1 || f->b1 > 4096 ||
	         f->b2 > 4096 || f->b3 > 4096 ||
	         !(f->voxel_size_um > 0) || !isfinite(f->voxel_size_um))
		loom__fail(r->diag, rc, "%s: PARM: block %ux%ux%u, voxel size %g um", r->name,
		           f->b1, f->b2, f->b3, (double)f->voxel_size_um);
	else if (f->params.base_width != (f->n_blocks <= 256 ? 1u : 2u))
		loom__fail(r->diag, rc, "%s: PARM: base width %u for %u blocks", r->name,
		           f->params.base_width, f->n_blocks);
	else if (pl > FAB_MAX_PATH || n != FAB_PARM_BYTES + (uint64_t)pl ||
	         memchr(p + FAB_PARM_BYTES, 0, pl) != NULL || !check_zero(p + 64, 32))
		loom__fail(r->diag, rc, "%s: PARM: path of %u bytes in a %llu-byte section "
		           "(or a NUL in it, or reserved bytes not 0)", r->name, pl,
		           (unsigned long long)n);
	else if (r->sec[S_BASE].raw_bytes !=
	         (uint64_t)f->params.base_width * f->design->rows * f->design->cols)
		loom__fail(r->diag, rc, "%s: BASE: %llu raw bytes, expected %u per crossing",
		           r->name, (unsigned long long)r->sec[S_BASE].raw_bytes,
		           f->params.base_width);
	else
		rc = LOOM_OK;
	if (!rc) {
		char *path = malloc((size_t)pl + 1);
		if (!path) {
			rc = loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory", r->name);
		} else {
			memcpy(path, p + FAB_PARM_BYTES, pl);
			path[pl] = 0;
			free(f->db_path);
			f->db_path = path;
		}
	}
	free(p);
	return rc;
}

static int parse_yarn(fab_reader *r, loom_fabric *f)
{
	uint64_t n = r->sec[S_YARN].raw_bytes;
	uint32_t nt;
	uint8_t *p;
	int rc;

	if (n < 8)
		return loom__fail(r->diag, LOOM_EFORMAT, "%s: YARN: %llu bytes", r->name,
		                  (unsigned long long)n);
	rc = read_small(r, S_YARN, &p);
	if (rc)
		return rc;
	nt = get32(p);
	if (nt < 1 || nt > LOOM_MAX_YARN_TYPES || get32(p + 4) != FAB_YARN_BYTES ||
	    n != 8 + (uint64_t)FAB_YARN_BYTES * nt) {
		uint32_t eb = get32(p + 4);
		free(p);
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: YARN: %u types of %u bytes in %llu bytes (expected "
		                  "1..256 types of 52)", r->name, nt, eb,
		                  (unsigned long long)n);
	}
	rc = loom_design_set_types(f->design, nt);
	for (uint32_t k = 0; !rc && k < nt; k++) {
		const uint8_t *e = p + 8 + (size_t)FAB_YARN_BYTES * k;
		loom_yarn_type *y = &f->design->types[k];
		if (!memchr(e, 0, 32)) {
			rc = loom__fail(r->diag, LOOM_EFORMAT,
			                "%s: YARN: type %u: name not NUL-terminated", r->name, k);
			break;
		}
		memcpy(y->name, e, 32);
		y->albedo[0] = getf(e + 32);
		y->albedo[1] = getf(e + 36);
		y->albedo[2] = getf(e + 40);
		y->alignment = getf(e + 44);
		y->thickness = getf(e + 48);
		for (int c = 0; c < 5; c++)
			if (!isfinite(getf(e + 32 + 4 * c)))
				rc = loom__fail(r->diag, LOOM_EFORMAT,
				                "%s: YARN: type %u: value %d is not finite", r->name,
				                k, c);
	}
	free(p);
	if (rc && rc != LOOM_EFORMAT)
		return loom__fail(r->diag, rc, "%s: out of memory", r->name);
	return rc;
}

static int consume_weave(void *ctx, fab_reader *r, uint64_t off, const uint8_t *buf,
                         size_t n)
{
	loom_design *d = ctx;
	uint64_t total = (uint64_t)d->rows * d->cols;
	for (size_t k = 0; k < n; k++) {
		uint64_t c0 = (off + k) * 8;
		for (unsigned bit = 0; bit < 8; bit++) {
			unsigned v = (buf[k] >> bit) & 1u;
			if (c0 + bit < total)
				d->weave[c0 + bit] = (uint8_t)v;
			else if (v)
				return loom__fail(r->diag, LOOM_EFORMAT,
				                  "%s: WEAV: padding bit %u of the last byte is set",
				                  r->name, bit);
		}
	}
	return LOOM_OK;
}

typedef struct map_dst {
	uint8_t *map;          /* rows*cols */
	uint8_t *line;         /* max(rows, cols): data of the compact modes */
	uint8_t pre[8];
	uint32_t mode;
	uint64_t raw_bytes;
	uint32_t rows, cols, n_types;
	const char *tag;
} map_dst;

static int consume_map(void *ctx, fab_reader *r, uint64_t off, const uint8_t *buf,
                       size_t n)
{
	map_dst *m = ctx;
	for (size_t k = 0; k < n; k++) {
		uint64_t p = off + k;
		if (p < 8) {
			m->pre[p] = buf[k];
			continue;
		}
		if (p == 8) {
			m->mode = get32(m->pre);
			if (m->mode > MAP_CONST || get32(m->pre + 4) != 0 ||
			    m->raw_bytes != 8 + map_data_bytes(m->mode, m->rows, m->cols))
				return loom__fail(r->diag, LOOM_EFORMAT,
				                  "%s: %s: mode %u with %llu bytes of data (modes: 0 "
				                  "full, 1 per column, 2 per row, 3 constant)",
				                  r->name, m->tag, m->mode,
				                  (unsigned long long)(m->raw_bytes - 8));
		}
		if (buf[k] >= m->n_types)
			return loom__fail(r->diag, LOOM_ERANGE,
			                  "%s: %s: entry %llu is type %u, the yarn table has %u",
			                  r->name, m->tag, (unsigned long long)(p - 8), buf[k],
			                  m->n_types);
		if (m->mode == MAP_FULL)
			m->map[p - 8] = buf[k];
		else
			m->line[p - 8] = buf[k];
	}
	return LOOM_OK;
}

static int parse_map(fab_reader *r, loom_fabric *f, unsigned idx)
{
	loom_design *d = f->design;
	map_dst m;
	int rc;

	memset(&m, 0, sizeof m);
	m.map = idx == S_WARP ? d->warp_type : d->weft_type;
	m.rows = d->rows;
	m.cols = d->cols;
	m.n_types = d->n_types;
	m.tag = fab_tags[idx];
	m.raw_bytes = r->sec[idx].raw_bytes;
	if (m.raw_bytes < 9)
		return loom__fail(r->diag, LOOM_EFORMAT, "%s: %s: %llu bytes, expected at "
		                  "least 9", r->name, m.tag, (unsigned long long)m.raw_bytes);
	m.line = malloc(d->rows > d->cols ? d->rows : d->cols);
	if (!m.line)
		return loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory", r->name);
	rc = read_payload(r, idx, consume_map, &m);
	if (!rc && m.mode != MAP_FULL) {
		for (uint32_t i = 0; i < d->rows; i++) {
			uint8_t *row = m.map + (size_t)i * d->cols;
			if (m.mode == MAP_COLUMNS)
				memcpy(row, m.line, d->cols);
			else
				memset(row, m.mode == MAP_ROWS ? m.line[i] : m.line[0], d->cols);
		}
	}
	free(m.line);
	return rc;
}

typedef struct base_dst {
	uint16_t *base;
	uint32_t width, K, cols;
	uint8_t carry;         /* low byte of a 2-byte entry split by a chunk */
} base_dst;

static int bad_base(fab_reader *r, const base_dst *b, uint64_t k, unsigned v)
{
	return loom__fail(r->diag, LOOM_ERANGE,
	                  "%s: BASE: crossing (%llu,%llu) copies block %u, the database "
	                  "has %u", r->name, (unsigned long long)(k / b->cols),
	                  (unsigned long long)(k % b->cols), v, b->K);
}

static int consume_base(void *ctx, fab_reader *r, uint64_t off, const uint8_t *buf,
                        size_t n)
{
	base_dst *b = ctx;
	if (b->width == 1) {
		for (size_t k = 0; k < n; k++) {
			if (buf[k] >= b->K)
				return bad_base(r, b, off + k, buf[k]);
			b->base[off + k] = buf[k];
		}
		return LOOM_OK;
	}
	for (size_t k = 0; k < n; k++) {
		uint64_t p = off + k;
		if (!(p & 1)) {
			b->carry = buf[k];
			continue;
		}
		{
			unsigned v = (unsigned)b->carry | (unsigned)buf[k] << 8;
			if (v >= b->K)
				return bad_base(r, b, p >> 1, v);
			b->base[p >> 1] = (uint16_t)v;
		}
	}
	return LOOM_OK;
}

static int parse_base(fab_reader *r, loom_fabric *f)
{
	base_dst b;
	size_t n = (size_t)f->design->rows * f->design->cols;

	f->base = malloc(n * sizeof *f->base);
	if (!f->base)
		return loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory for the base "
		                  "assignment of %zu crossings", r->name, n);
	b.base = f->base;
	b.width = f->params.base_width;
	b.K = f->n_blocks;
	b.cols = f->design->cols;
	b.carry = 0;
	return read_payload(r, S_BASE, consume_base, &b);
}

static int parse_edge(fab_reader *r, loom_fabric *f)
{
	uint64_t n = r->sec[S_EDGE].raw_bytes, want;
	uint32_t mode, rh, rv, b1 = f->b1, b2 = f->b2, K = f->n_blocks, rank = f->params.rank;
	uint32_t max_h = rank < b1 ? rank : b1, max_v = rank < b2 - 2 ? rank : b2 - 2;
	size_t cells = (size_t)b1 * b2, cnt[7], total = 0;
	float *arr[7] = {0};
	loom_edgefix_tables t;
	loom_edgefix *ef;
	uint8_t *p;
	int rc;

	if (max_h > 2 * K)
		max_h = 2 * K;
	if (max_v > 2 * K)
		max_v = 2 * K;
	if (n < FAB_EDGE_HEADER)
		return loom__fail(r->diag, LOOM_EFORMAT, "%s: EDGE: %llu bytes", r->name,
		                  (unsigned long long)n);
	rc = read_small(r, S_EDGE, &p);
	if (rc)
		return rc;
	/* the last section: the reader's chunk buffers are no longer needed */
	free(r->raw);
	free(r->stored);
	r->raw = r->stored = NULL;
	mode = get32(p);
	rh = get32(p + 4);
	rv = get32(p + 8);
	if ((mode != 1 && mode != 2) || (rank && (rh < 1 || rv < 1)) || rh > max_h ||
	    rv > max_v ||
	    get32(p + 12) != b1 || get32(p + 16) != b2 || get32(p + 20) != K ||
	    !check_zero(p + 24, 8)) {
		uint32_t fb1 = get32(p + 12), fb2 = get32(p + 16), fK = get32(p + 20);
		free(p);
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: EDGE: storage %u, ranks %u/%u (at most %u/%u), block "
		                  "%ux%u, %u blocks (expected 1 or 2, %ux%u, %u)", r->name,
		                  mode, rh, rv, max_h, max_v, fb1, fb2, fK, b1, b2, K);
	}
	f->params.rank_h = rh;
	f->params.rank_v = rv;
	f->params.edge_stored = mode == 1;
	cnt[0] = (size_t)K * (2u * rh + 2u * rv);
	cnt[1] = cells * rh;
	cnt[2] = cells * rv;
	cnt[3] = (size_t)b1 * rh;
	cnt[4] = (size_t)(b2 - 2) * rv;
	cnt[5] = b1;
	cnt[6] = b2 - 2;
	if (mode == 1)
		for (int k = 0; k < 7; k++)
			total += cnt[k];
	want = FAB_EDGE_HEADER + 4 * (uint64_t)total;
	if (n != want) {
		free(p);
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: EDGE: %llu bytes, expected %llu", r->name,
		                  (unsigned long long)n, (unsigned long long)want);
	}
	if (mode == 2) {
		free(p);
		return LOOM_OK; /* rebuilt from the database at bind */
	}
	/* the tables are parsed straight into the edge fix (no second copy) */
	t.b1 = b1;
	t.b2 = b2;
	t.n_blocks = K;
	t.rank_h = rh;
	t.rank_v = rv;
	rc = loom__edgefix_alloc(&t, &ef, arr, r->diag);
	if (rc) {
		free(p);
		return rc;
	}
	{
		const uint8_t *q = p + FAB_EDGE_HEADER;
		for (int k = 0; k < 7 && !rc; k++) {
			for (size_t i = 0; i < cnt[k]; i++, q += 4) {
				arr[k][i] = getf(q);
				if (!isfinite(arr[k][i])) {
					rc = loom__fail(r->diag, LOOM_EFORMAT,
					                "%s: EDGE: value at byte %zu is not finite",
					                r->name, (size_t)(q - p));
					break;
				}
			}
		}
	}
	free(p);
	if (rc) {
		loom_edgefix_free(ef);
	} else {
		loom__edgefix_finish(ef);
		f->ef = ef;
	}
	return rc;
}

static const uint8_t *get_synth_metrics(const uint8_t *p, loom_synth_metrics *m)
{
	memset(m, 0, sizeof *m);
	m->crossings = get64(p + 0);
	m->correct = get64(p + 8);
	m->consistent = get64(p + 16);
	m->matches = get64(p + 24);
	m->best_matches = get64(p + 32);
	m->pairs = get64(p + 40);
	m->continuous = get64(p + 48);
	m->continuous_v = get64(p + 56);
	m->continuous_h = get64(p + 64);
	m->correctness = m->crossings ? (double)m->correct / (double)m->crossings : 0;
	m->consistency = m->crossings ? (double)m->consistent / (double)m->crossings : 0;
	m->continuity = m->pairs ? (double)m->continuous / (double)m->pairs : 0;
	return p + 72;
}

static int synth_metrics_ok(const loom_synth_metrics *m)
{
	return m->correct <= m->crossings && m->consistent <= m->crossings &&
	       m->matches <= 4 * m->crossings && m->best_matches <= 4 * m->crossings &&
	       m->matches <= m->best_matches && m->pairs == 2 * m->crossings &&
	       m->continuous <= m->pairs &&
	       m->continuous == m->continuous_v + m->continuous_h &&
	       m->continuous_v <= m->crossings && m->continuous_h <= m->crossings;
}

static int parse_metr(fab_reader *r, loom_fabric *f)
{
	uint64_t n = r->sec[S_METR].raw_bytes, sum = 0;
	uint64_t crossings = (uint64_t)f->design->rows * f->design->cols;
	loom_seam_metrics *s = &f->seam;
	const uint8_t *q;
	uint8_t *p;
	int rc, ok;

	if (n != FAB_METR_FIXED + 8 * (uint64_t)f->n_exemplars)
		return loom__fail(r->diag, LOOM_EFORMAT, "%s: METR: %llu bytes, expected %llu",
		                  r->name, (unsigned long long)n,
		                  (unsigned long long)(FAB_METR_FIXED + 8 * (uint64_t)f->n_exemplars));
	rc = read_small(r, S_METR, &p);
	if (rc)
		return rc;
	q = get_synth_metrics(p, &f->m_repeat);
	q = get_synth_metrics(q, &f->m_bolt);
	f->win_rows = get64(q);
	f->win_cols = get64(q + 8);
	memset(s, 0, sizeof *s);
	s->samples = get64(q + 16);
	s->before_mean = getd(q + 24);
	s->before_max = getd(q + 32);
	s->after_mean = getd(q + 40);
	s->after_max = getd(q + 48);
	s->corner_samples = get64(q + 56);
	s->corner_before_mean = getd(q + 64);
	s->corner_after_mean = getd(q + 72);
	s->internal_step = getd(q + 80);
	ok = get32(q + 88) == f->n_exemplars && check_zero(q + 92, 4) &&
	     f->m_repeat.crossings == crossings && synth_metrics_ok(&f->m_repeat) &&
	     f->m_bolt.crossings == f->win_rows * f->win_cols &&
	     f->win_rows >= 1 && f->win_cols >= 1 &&
	     f->win_rows <= LOOM_FABRIC_MAX_WINDOW && f->win_cols <= LOOM_FABRIC_MAX_WINDOW &&
	     synth_metrics_ok(&f->m_bolt) && s->corner_samples <= s->samples;
	for (int k = 0; k < 8; k++) {
		double v = getd(q + 24 + 8 * k);
		if (k != 4 && (!isfinite(v) || v < 0))
			ok = 0;
	}
	f->usage = calloc(f->n_exemplars, sizeof *f->usage);
	if (!f->usage) {
		free(p);
		return loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory", r->name);
	}
	for (uint32_t u = 0; u < f->n_exemplars; u++) {
		f->usage[u] = get64(q + 96 + 8 * (size_t)u);
		if (f->usage[u] > crossings)
			ok = 0;
		else
			sum += f->usage[u];
	}
	free(p);
	if (!ok || sum != crossings)
		return loom__fail(r->diag, LOOM_EFORMAT,
		                  "%s: METR: inconsistent counts or values", r->name);
	s->before_ratio = s->internal_step > 0 ? s->before_mean / s->internal_step : 0;
	s->after_ratio = s->internal_step > 0 ? s->after_mean / s->internal_step : 0;
	return LOOM_OK;
}

/* ---- the whole file ---------------------------------------------------------- */

static int parse_all(fab_reader *r, loom_fabric *f)
{
	uint32_t rows = 0, cols = 0;
	int rc = read_header(r, &rows, &cols);

	if (!rc)
		rc = read_trailer(r);
	if (!rc)
		rc = walk_sections(r, (uint64_t)rows * cols);
	if (rc)
		return rc;
	{
		uint64_t most = 1;
		for (unsigned k = 0; k < FAB_N_SECTIONS; k++)
			if (r->sec[k].raw_bytes > most)
				most = r->sec[k].raw_bytes;
		r->raw = malloc(most < FAB_CHUNK ? (size_t)most : FAB_CHUNK);
		if (!r->raw)
			return loom__fail(r->diag, LOOM_ENOMEM, "%s: out of memory", r->name);
	}
	rc = loom_design_new(rows, cols, &f->design);
	if (rc)
		return loom__fail(r->diag, rc, "%s: cannot allocate a %ux%u design: %s",
		                  r->name, rows, cols, loom_strerror(rc));
	rc = parse_parm(r, f);
	if (!rc)
		rc = parse_yarn(r, f);
	if (!rc)
		rc = read_payload(r, S_WEAV, consume_weave, f->design);
	if (!rc && r->sec[S_WEAV].raw_bytes != ((uint64_t)rows * cols + 7) / 8)
		rc = loom__fail(r->diag, LOOM_EFORMAT, "%s: WEAV: %llu bytes for %llu "
		                "crossings", r->name,
		                (unsigned long long)r->sec[S_WEAV].raw_bytes,
		                (unsigned long long)rows * cols);
	if (!rc)
		rc = parse_map(r, f, S_WARP);
	if (!rc)
		rc = parse_map(r, f, S_WEFT);
	if (!rc)
		rc = parse_base(r, f);
	/* METR before EDGE: EDGE is the last section read, so the chunk
	   buffers can go before its tables are built (lower peak memory) */
	if (!rc)
		rc = parse_metr(r, f);
	if (!rc)
		rc = parse_edge(r, f);
	return rc;
}

int loom__fabric_read_size(const char *path, uint32_t *rows, uint32_t *cols,
                           loom_diag *diag)
{
	fab_reader r;
	int rc;

	memset(&r, 0, sizeof r);
	r.name = path;
	r.diag = diag;
	r.fd = -1;
	rc = loom__open_input(path, &r.fd, &r.size, diag);
	if (rc)
		return rc;
	rc = r.size == 0 ? loom__fail(diag, LOOM_ETRUNCATED, "%s: empty file", r.name)
	                 : read_header(&r, rows, cols);
	close(r.fd);
	return rc;
}

int loom__fabric_read(const char *path, const uint8_t *mem, size_t len,
                      loom_fabric **out, loom_diag *diag)
{
	fab_reader r;
	loom_fabric *f;
	int rc;

	*out = NULL;
	memset(&r, 0, sizeof r);
	r.name = path ? path : "(memory)";
	r.diag = diag;
	r.fd = -1;
	if (mem) {
		r.mem = mem;
		r.size = len;
	} else {
		rc = loom__open_input(path, &r.fd, &r.size, diag);
		if (rc)
			return rc;
	}
	f = loom__fabric_alloc();
	r.dec = libdeflate_alloc_decompressor();
	/* stored chunks are never larger than the file; raw chunks get their
	   buffer after the walk (step 3), sized to the largest section */
	r.stored = malloc(r.size < FAB_CHUNK ? (size_t)r.size + 1 : FAB_CHUNK);
	if (!f || !r.dec || !r.stored)
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", r.name);
	else if (r.size == 0)
		rc = loom__fail(diag, LOOM_ETRUNCATED, "%s: empty file", r.name);
	else
		rc = parse_all(&r, f);
	if (r.fd >= 0)
		close(r.fd);
	libdeflate_free_decompressor(r.dec);
	free(r.stored);
	free(r.raw);
	if (rc) {
		loom_fabric_free(f);
		return rc;
	}
	*out = f;
	return LOOM_OK;
}
