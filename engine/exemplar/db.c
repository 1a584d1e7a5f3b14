/*
 * engine/exemplar/db.c - reader of exemplar databases (.ldb); format in
 * docs/formats.md, layout summary in db_internal.h.
 *
 * Open (numbered steps, cited below):
 *   1. open + fstat; the file must hold a header and a trailer;
 *   2. header: magic, version (before anything else, so a newer layout is
 *      reported as a version), header CRC, geometry fields;
 *   3. trailer (last 64 bytes): magic (else the file is truncated or
 *      unfinished), trailer CRC, recorded file size;
 *   4. metadata: range, read, CRC32, content hash;
 *   5. parse the exemplar table, per-exemplar sections and brick index,
 *      checking every count, offset and size against the file.
 *   6. measure one decompressor (for loom__db_reader_bytes).
 * After open the handle is immutable; memory is the parsed metadata only
 * (O(exemplars + blocks + bricks)), never brick data.  Bricks are read by
 * loom__db_read_brick with pread: thread-safe.
 */
#include "db_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <libdeflate.h>
#include <malloc.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct db_brick {
	uint64_t offset;       /* absolute, 0 for empty */
	uint32_t stored;       /* bytes on disk */
	uint32_t crc;          /* CRC32 of the stored bytes */
	uint8_t storage;       /* LOOM__DB_STORE_* */
	uint32_t ub[LOOM__DB_UNITS], uc[LOOM__DB_UNITS]; /* layout 2: unit bytes, CRC */
} db_brick;

typedef struct db_exm {
	loom_db_exemplar_info pub;  /* pointers below */
	uint8_t *weave;
	loom_db_yarn yarns[256]; /* rows beyond n_yarns are zero */
	uint16_t *sym;
	uint8_t *bmeta;        /* rows*cols * 4: code, centre kind, gaps(2) */
	float *bf;             /* rows*cols * (3 + 2*b1 + 2*b2) */
} db_exm;

struct loom_db {
	int fd;
	char *path;
	loom_db_info info;
	uint32_t n_bricks;
	size_t brick_voxels, brick_bytes;
	size_t max_stored;
	size_t reader_bytes;   /* bound of one loom__db_reader, set at open */
	uint64_t data_end;     /* = metadata offset: bricks lie in [128, data_end) */
	size_t entry_bytes;    /* brick index entry: 24 (version 1) or 56 */
	db_exm *ex;
	/* The brick index in memory: only the stored (non-empty) bricks, in id
	   order, found by rank in a bitmap, so that a database of small
	   bricks (most of them empty air) does not hold an entry for each
	   (a 16 x 16 x 16-brick paper database: 47 k stored of 243 k, 2.6 MB
	   instead of 13.6 MB; brick_at) */
	db_brick *bricks;      /* n_stored */
	uint64_t *stored_bits; /* bit id: brick id is stored */
	uint32_t *stored_rank; /* per word of stored_bits: stored bricks before it */
	uint32_t n_stored;
};

static const db_brick empty_brick; /* storage LOOM__DB_STORE_EMPTY, no bytes */

/* Brick id's index entry (id < n_bricks); empty_brick when not stored. */
static const db_brick *brick_at(const loom_db *db, uint32_t id)
{
	uint64_t w = db->stored_bits[id >> 6], bit = 1ull << (id & 63);

	if (!(w & bit))
		return &empty_brick;
	return &db->bricks[db->stored_rank[id >> 6] +
	                   (uint32_t)__builtin_popcountll(w & (bit - 1))];
}

static int read_at(int fd, void *buf, size_t n, uint64_t off, size_t *got)
{
	size_t done = 0;

	while (done < n) {
		ssize_t r = pread(fd, (uint8_t *)buf + done, n - done, (off_t)(off + done));
		if (r < 0) {
			if (errno == EINTR)
				continue;
			*got = done;
			return -1;
		}
		if (r == 0)
			break;
		done += (size_t)r;
	}
	*got = done;
	return 0;
}

/* ---- open ------------------------------------------------------------- */

#define FAILF(code, ...) loom__fail(diag, code, __VA_ARGS__)

/* Reserved bytes must be zero (docs/formats.md). */
static size_t first_nonzero(const uint8_t *b, size_t n)
{
	size_t i = 0;
	while (i < n && b[i] == 0)
		i++;
	return i;
}

static int all_zero(const uint8_t *b, size_t n)
{
	return first_nonzero(b, n) == n;
}

static int parse_header(loom_db *db, const uint8_t *h, loom_diag *diag)
{
	const char *p = db->path;
	uint32_t v;
	static const char *const axis[3] = {"x", "y", "z"};

	if (memcmp(h, LOOM__DB_MAGIC, 8) != 0)
		return FAILF(LOOM_EFORMAT, "%s: offset 0: bad magic %02x %02x %02x %02x "
		             "%02x %02x %02x %02x, expected 89 4c 44 42 0d 0a 1a 0a (not "
		             "an exemplar database)", p, h[0], h[1], h[2], h[3], h[4], h[5],
		             h[6], h[7]);
	v = loom__le32(h + 8);
	if (v < LOOM__DB_VERSION_PLANES1 || v > LOOM__DB_VERSION)
		return FAILF(LOOM_EVERSION, "%s: offset 8: format version %u, this loom "
		             "reads versions 1 to %u", p, v, LOOM__DB_VERSION);
	if (loom__le32(h + 124) != libdeflate_crc32(0, h, 124))
		return FAILF(LOOM_ECORRUPT, "%s: offset 124: header CRC32 0x%08x does not "
		             "match the header (0x%08x)", p, loom__le32(h + 124),
		             libdeflate_crc32(0, h, 124));
	if (loom__le32(h + 12) != LOOM__DB_HEADER_BYTES)
		return FAILF(LOOM_EFORMAT, "%s: offset 12: header size %u, expected %u", p,
		             loom__le32(h + 12), LOOM__DB_HEADER_BYTES);
	db->info.version = v;
	db->info.n_exemplars = loom__le32(h + 16);
	if (db->info.n_exemplars < 1 || db->info.n_exemplars > LOOM__DB_MAX_EXEMPLARS)
		return FAILF(LOOM_EFORMAT, "%s: offset 16: %u exemplars, expected 1..%u",
		             p, db->info.n_exemplars, LOOM__DB_MAX_EXEMPLARS);
	for (int a = 0; a < 3; a++) {
		db->info.block[a] = loom__le32(h + 20 + 4 * a);
		db->info.brick[a] = loom__le32(h + 32 + 4 * a);
		if (db->info.block[a] < 1 || db->info.block[a] > LOOM__DB_MAX_BLOCK)
			return FAILF(LOOM_EFORMAT, "%s: offset %d: block size %u along %s, "
			             "expected 1..%u", p, 20 + 4 * a, db->info.block[a],
			             axis[a], LOOM__DB_MAX_BLOCK);
		if (db->info.brick[a] < 1 || db->info.brick[a] > LOOM__DB_MAX_BRICK)
			return FAILF(LOOM_EFORMAT, "%s: offset %d: brick size %u along %s, "
			             "expected 1..%u", p, 32 + 4 * a, db->info.brick[a],
			             axis[a], LOOM__DB_MAX_BRICK);
	}
	db->brick_voxels = (size_t)db->info.brick[0] * db->info.brick[1] * db->info.brick[2];
	db->brick_bytes = db->brick_voxels * LOOM__VOXEL_PLANES;
	if (db->brick_bytes > LOOM__DB_MAX_BRICK_BYTES)
		return FAILF(LOOM_EFORMAT, "%s: offset 32: brick %ux%ux%u is larger than "
		             "%u bytes", p, db->info.brick[0], db->info.brick[1],
		             db->info.brick[2], LOOM__DB_MAX_BRICK_BYTES);
	/* version 1 stores a brick as one stream (layout 1), version 2 each
	   plane as a unit of its own (layout 2), version 3 the density unit in
	   segments (layout 3), version 4 the density unit zero-run coded
	   (layout 4): the layout is the version */
	db->info.voxel_layout = v;
	db->entry_bytes = v == 1 ? LOOM__DB_INDEX_BYTES : LOOM__DB_INDEX2_BYTES;
	if (loom__le32(h + 44) != db->info.voxel_layout)
		return FAILF(LOOM_EUNSUPPORTED, "%s: offset 44: voxel layout %u, expected "
		             "%u (format version %u)", p, loom__le32(h + 44),
		             db->info.voxel_layout, v);
	db->info.voxel_size_um = loom__lef32(h + 48);
	if (!(db->info.voxel_size_um > 0.0f) || !(db->info.voxel_size_um < 1e6f))
		return FAILF(LOOM_EFORMAT, "%s: offset 48: voxel size %g um", p,
		             (double)db->info.voxel_size_um);
	db->info.top_threshold = loom__le32(h + 52);
	if (db->info.top_threshold > 255)
		return FAILF(LOOM_EFORMAT, "%s: offset 52: top threshold %u > 255", p,
		             db->info.top_threshold);
	if (loom__le32(h + 56) > 12)
		return FAILF(LOOM_EFORMAT, "%s: offset 56: deflate level %u, expected "
		             "0..12", p, loom__le32(h + 56));
	if (loom__le32(h + 60) & ~1u)
		return FAILF(LOOM_EFORMAT, "%s: offset 60: flags 0x%x, only bit 0 is "
		             "defined", p, loom__le32(h + 60));
	if (!all_zero(h + 72, 52))
		return FAILF(LOOM_EFORMAT, "%s: offset %zu: reserved header byte is not "
		             "zero", p, 72 + first_nonzero(h + 72, 52));
	db->info.seed = loom__le64(h + 64);
	return LOOM_OK;
}

/* Range check of a section [off, off+len) inside the metadata. */
static int sect_ok(uint64_t off, uint64_t len, uint64_t meta_len)
{
	return off <= meta_len && len <= meta_len - off;
}

static int parse_exemplar(loom_db *db, uint32_t k, const uint8_t *m,
                          uint64_t mlen, uint32_t *next_brick, loom_diag *diag)
{
	const char *p = db->path;
	size_t xo = LOOM__DB_META_HEADER_BYTES + (size_t)k * LOOM__DB_EXEMPLAR_BYTES;
	const uint8_t *x = m + xo;
	db_exm *e = &db->ex[k];
	loom_db_exemplar_info *pub = &e->pub;
	uint32_t b1 = db->info.block[0], b2 = db->info.block[1];
	size_t esz = loom__db_block_entry_bytes(b1, b2), nblk, nf;
	uint64_t wo, yo, so, bo;

#define XFAIL(code, field, fmt, ...)                                           \
	loom__fail(diag, code, "%s: exemplar %u at metadata offset %zu, field "   \
	           "'%s': " fmt, p, k, xo, field, __VA_ARGS__)
	if (memchr(x, 0, 32) == NULL || x[0] == 0)
		return XFAIL(LOOM_EFORMAT, "name", "%s", "not a NUL-terminated string");
	if (memchr(x + 32, 0, 32) == NULL)
		return XFAIL(LOOM_EFORMAT, "weave_name", "%s", "not a NUL-terminated string");
	{
		size_t nl = strlen((const char *)x), wl = strlen((const char *)x + 32);
		if (!all_zero(x + nl, 32 - nl))
			return XFAIL(LOOM_EFORMAT, "name", "%s", "not NUL-padded");
		if (!all_zero(x + 32 + wl, 32 - wl))
			return XFAIL(LOOM_EFORMAT, "weave_name", "%s", "not NUL-padded");
	}
	if (loom__le32(x + 124) != 0 || !all_zero(x + 178, 14))
		return XFAIL(LOOM_EFORMAT, "reserved", "%s", "not zero (offsets 124, 178)");
	if (x[176] >= LOOM_FIBRE_COUNT_ || x[177] >= LOOM_FIBRE_COUNT_ ||
	    (x[176] == 0) != (x[177] == 0))
		return XFAIL(LOOM_EFORMAT, "fibre", "%u %u, expected two material codes "
		             "1..%d or 0 0", x[176], x[177], LOOM_FIBRE_COUNT_ - 1);
	pub->fibre[0] = x[176];
	pub->fibre[1] = x[177];
	memcpy(pub->name, x, 32);
	memcpy(pub->weave_name, x + 32, 32);
	pub->rows = loom__le32(x + 64);
	pub->cols = loom__le32(x + 68);
	if (pub->rows < 1 || pub->cols < 1 || pub->rows > LOOM__DB_MAX_CROSSINGS ||
	    pub->cols > LOOM__DB_MAX_CROSSINGS)
		return XFAIL(LOOM_EFORMAT, "rows/cols", "%ux%u crossings, expected 1..%u",
		             pub->rows, pub->cols, LOOM__DB_MAX_CROSSINGS);
	for (int a = 0; a < 3; a++) {
		uint32_t want = a == 0 ? pub->cols * b1 : a == 1 ? pub->rows * b2
		                                                  : db->info.block[2];
		pub->size[a] = loom__le32(x + 72 + 4 * a);
		pub->block[a] = loom__le32(x + 84 + 4 * a);
		pub->bricks[a] = loom__le32(x + 100 + 4 * a);
		if (pub->size[a] != want || want > LOOM__DB_MAX_EXTENT)
			return XFAIL(LOOM_EFORMAT, "size", "axis %d is %u voxels, expected %u",
			             a, pub->size[a], want);
		if (pub->block[a] != db->info.block[a])
			return XFAIL(LOOM_EFORMAT, "block", "axis %d is %u, the header says %u",
			             a, pub->block[a], db->info.block[a]);
		if (pub->bricks[a] != (want + db->info.brick[a] - 1) / db->info.brick[a])
			return XFAIL(LOOM_EFORMAT, "bricks", "axis %d has %u bricks, expected %u",
			             a, pub->bricks[a],
			             (want + db->info.brick[a] - 1) / db->info.brick[a]);
	}
	pub->voxel_size_um = loom__lef32(x + 96);
	if (pub->voxel_size_um != db->info.voxel_size_um)
		return XFAIL(LOOM_EFORMAT, "voxel_size", "%g um, the header says %g um",
		             (double)pub->voxel_size_um, (double)db->info.voxel_size_um);
	pub->first_brick = loom__le32(x + 112);
	if (pub->first_brick != *next_brick)
		return XFAIL(LOOM_EFORMAT, "first_brick", "%u, expected %u",
		             pub->first_brick, *next_brick);
	{
		uint64_t nb = (uint64_t)pub->bricks[0] * pub->bricks[1] * pub->bricks[2];
		if (nb > db->n_bricks - *next_brick)
			return XFAIL(LOOM_ERANGE, "bricks", "%llu bricks from %u exceed the "
			             "index of %u bricks", (unsigned long long)nb, *next_brick,
			             db->n_bricks);
		*next_brick += (uint32_t)nb;
	}
	pub->n_yarns = loom__le32(x + 116);
	if (pub->n_yarns > 255)
		return XFAIL(LOOM_EFORMAT, "n_yarns", "%u, expected at most 255",
		             pub->n_yarns);
	pub->n_symmetries = loom__le32(x + 120);
	if (pub->n_symmetries < 1 ||
	    pub->n_symmetries > (uint64_t)pub->rows * pub->cols)
		return XFAIL(LOOM_EFORMAT, "n_symmetries", "%u, expected 1..%u",
		             pub->n_symmetries, pub->rows * pub->cols);
	wo = loom__le64(x + 128);
	yo = loom__le64(x + 136);
	so = loom__le64(x + 144);
	bo = loom__le64(x + 152);
	nblk = (size_t)pub->rows * pub->cols;
	if (!sect_ok(wo, nblk, mlen))
		return XFAIL(LOOM_ERANGE, "weave_offset", "%llu + %zu bytes outside the "
		             "%llu-byte metadata", (unsigned long long)wo, nblk,
		             (unsigned long long)mlen);
	if (!sect_ok(yo, (uint64_t)(pub->n_yarns + 1) * 4, mlen))
		return XFAIL(LOOM_ERANGE, "yarns_offset", "%llu outside the metadata",
		             (unsigned long long)yo);
	if (!sect_ok(so, (uint64_t)pub->n_symmetries * 4, mlen))
		return XFAIL(LOOM_ERANGE, "symmetries_offset", "%llu outside the metadata",
		             (unsigned long long)so);
	if (!sect_ok(bo, (uint64_t)nblk * esz, mlen))
		return XFAIL(LOOM_ERANGE, "blocks_offset", "%llu outside the metadata",
		             (unsigned long long)bo);
	pub->raw_bytes = loom__le64(x + 160);
	pub->stored_bytes = loom__le64(x + 168);
	if (pub->raw_bytes != (uint64_t)pub->size[0] * pub->size[1] * pub->size[2] *
	                          LOOM__VOXEL_PLANES)
		return XFAIL(LOOM_EFORMAT, "raw_bytes", "%llu, expected %llu",
		             (unsigned long long)pub->raw_bytes,
		             (unsigned long long)pub->size[0] * pub->size[1] *
		                     pub->size[2] * LOOM__VOXEL_PLANES);
	nf = 3 + 2 * ((size_t)b1 + b2);
	e->weave = malloc(nblk);
	e->sym = malloc((size_t)pub->n_symmetries * 4);
	e->bmeta = malloc(nblk * 4);
	e->bf = malloc(nblk * nf * sizeof(float));
	if (!e->weave || !e->sym || !e->bmeta || !e->bf)
		return FAILF(LOOM_ENOMEM, "%s: out of memory", p);
	for (size_t i = 0; i < nblk; i++) {
		if (m[wo + i] > 1)
			return XFAIL(LOOM_EFORMAT, "weave", "cell %zu is %u, expected 0 or 1",
			             i, m[wo + i]);
		e->weave[i] = m[wo + i];
	}
	memset(e->yarns, 0, sizeof e->yarns);
	if (!all_zero(m + yo, 4))
		return XFAIL(LOOM_EFORMAT, "yarns", "%s", "entry 0 (the empty label) is "
		             "not zero");
	for (uint32_t l = 1; l <= pub->n_yarns; l++) {
		const uint8_t *y = m + yo + 4 * (size_t)l;
		int32_t idx = (int16_t)loom__le16(y + 2);
		int32_t lim = y[0] == LOOM_YARN_WARP ? (int32_t)pub->cols
		                                     : (int32_t)pub->rows;
		int outside = (y[1] & LOOM_DB_YARN_OUTSIDE) != 0;
		if (y[0] > LOOM_YARN_WEFT || y[1] > 3)
			return XFAIL(LOOM_EFORMAT, "yarns", "label %u has kind %u flags %u", l,
			             y[0], y[1]);
		/* a yarn of the window has its end or pick; a yarn outside is the
		   one just before (-1) or just after (cols or rows); a flyaway
		   fibre has its yarn's index (either); no kind, no index */
		if (y[0] == LOOM_YARN_NONE ? (idx != 0 || y[1] != 0)
		    : outside ? (idx != -1 && idx != lim)
		    : (y[1] & LOOM_DB_YARN_FLYAWAY) ? (idx < -1 || idx > lim)
		                                    : (idx < 0 || idx >= lim))
			return XFAIL(LOOM_ERANGE, "yarns", "label %u: %s index %d out of "
			             "range (%s)", l, y[0] == LOOM_YARN_WARP ? "warp"
			             : y[0] == LOOM_YARN_WEFT ? "weft" : "kindless", (int)idx,
			             y[0] == LOOM_YARN_NONE ? "expected 0, no flags"
			             : outside ? "outside: expected -1 or the count"
			             : (y[1] & LOOM_DB_YARN_FLYAWAY) ? "flyaway: expected -1 .. "
			                                               "the count"
			                                             : "expected 0 .. count - 1");
		e->yarns[l].kind = y[0];
		e->yarns[l].flags = y[1];
		e->yarns[l].index = (int16_t)loom__le16(y + 2);
	}
	for (uint32_t s = 0; s < pub->n_symmetries; s++) {
		uint16_t dx = loom__le16(m + so + 4 * (size_t)s);
		uint16_t dy = loom__le16(m + so + 4 * (size_t)s + 2);
		if (dx >= pub->cols || dy >= pub->rows)
			return XFAIL(LOOM_EFORMAT, "symmetries", "entry %u (%u, %u) outside "
			             "%ux%u", s, dx, dy, pub->rows, pub->cols);
		if (s == 0 ? (dx || dy)
		           : ((uint32_t)dy << 16 | dx) <=
		             ((uint32_t)e->sym[2 * s - 1] << 16 | e->sym[2 * s - 2]))
			return XFAIL(LOOM_EFORMAT, "symmetries", "entry %u (%u, %u) out of "
			             "order ((0, 0) first, then by dy, then dx)", s, dx, dy);
		e->sym[2 * s] = dx;
		e->sym[2 * s + 1] = dy;
	}
	for (size_t i = 0; i < nblk; i++) {
		const uint8_t *b = m + bo + i * esz;
		float *f = e->bf + i * nf;
		size_t r = i / pub->cols, c = i % pub->cols, R = pub->rows, C = pub->cols;
		unsigned code = e->weave[i] | e->weave[(r + R - 1) % R * C + c] << 1 |
		                e->weave[(r + 1) % R * C + c] << 2 |
		                e->weave[r * C + (c + C - 1) % C] << 3 |
		                e->weave[r * C + (c + 1) % C] << 4;
		if (b[0] != code || b[1] > LOOM_YARN_WEFT ||
		    loom__le16(b + 2) > (uint64_t)b1 * b2)
			return XFAIL(LOOM_EFORMAT, "blocks", "block %zu: code %u (the weave "
			             "gives %u), centre kind %u, gap columns %u", i, b[0], code,
			             b[1], loom__le16(b + 2));
		memcpy(e->bmeta + 4 * i, b, 4);
		for (size_t j = 0; j < nf; j++) {
			f[j] = loom__lef32(b + 4 + 4 * j);
			/* heights and mean steps are within the volume's depth */
			if (!(f[j] >= 0.0f && f[j] <= (float)db->info.block[2]))
				return XFAIL(LOOM_ERANGE, "blocks", "block %zu: value %zu is %g, "
				             "expected 0..%u", i, j, (double)f[j],
				             db->info.block[2]);
		}
	}
	pub->weave = e->weave;
	pub->yarns = e->yarns;
	pub->symmetries = e->sym;
#undef XFAIL
	return LOOM_OK;
}

static const char *const unit_names[LOOM__DB_UNITS] = {
	"density", "orientation low byte", "orientation high byte", "label"};

/* Layout 2: the four unit entries of brick i (bytes 24..55 of its index
   entry).  A unit is 0 bytes (an all-zero plane, CRC 0), V bytes (raw) or
   1..V-1 (DEFLATE); they lie back to back from the brick's offset and
   add up to its stored_bytes; the brick's own CRC field is 0. */
static int parse_units(loom_db *db, uint32_t i, db_brick *b, const uint8_t *x,
                       uint64_t io, loom_diag *diag)
{
	uint64_t sum = 0;
	char name[192];

	for (unsigned u = 0; u < LOOM__DB_UNITS; u++) {
		b->ub[u] = loom__le32(x + 24 + 8 * u);
		b->uc[u] = loom__le32(x + 28 + 8 * u);
		sum += b->ub[u];
		if (b->ub[u] > db->brick_voxels || (b->ub[u] == 0 && b->uc[u])) {
			loom__db_brick_name(db, i, name, sizeof name);
			return FAILF(LOOM_ERANGE, "%s, unit %u (%s): index entry at metadata "
			             "offset %zu: %u bytes (CRC 0x%08x), expected 0..%zu (CRC 0 "
			             "when 0)", name, u, unit_names[u],
			             (size_t)(io + (size_t)i * db->entry_bytes), b->ub[u],
			             b->uc[u], db->brick_voxels);
		}
	}
	if (sum != b->stored || b->crc != 0 ||
	    (b->storage == LOOM__DB_STORE_EMPTY) != (sum == 0)) {
		loom__db_brick_name(db, i, name, sizeof name);
		return FAILF(LOOM_EFORMAT, "%s: index entry at metadata offset %zu: units "
		             "of %llu bytes, stored_bytes %u, CRC field 0x%08x, storage %u "
		             "(expected the sum, 0, and 0 exactly when empty)", name,
		             (size_t)(io + (size_t)i * db->entry_bytes),
		             (unsigned long long)sum, b->stored, b->crc, b->storage);
	}
	return LOOM_OK;
}

/* 1 if no unit of a layout-2 brick is compressed. */
static int units_raw(const loom_db *db, const db_brick *b)
{
	for (unsigned u = 0; u < LOOM__DB_UNITS; u++)
		if (b->ub[u] && b->ub[u] != db->brick_voxels)
			return 0;
	return 1;
}

static int parse_index(loom_db *db, const uint8_t *m, uint64_t mlen,
                       uint64_t io, loom_diag *diag)
{
	size_t words = ((size_t)db->n_bricks + 63) / 64;
	uint32_t n = 0, k = 0;

	/* the stored bricks first (the storage byte; checked below), so that
	   only they get an entry in memory */
	for (uint32_t i = 0; i < db->n_bricks; i++)
		n += m[io + (size_t)i * db->entry_bytes + 20] != LOOM__DB_STORE_EMPTY;
	db->bricks = calloc(n ? n : 1, sizeof *db->bricks);
	db->stored_bits = calloc(words ? words : 1, sizeof *db->stored_bits);
	db->stored_rank = calloc(words ? words : 1, sizeof *db->stored_rank);
	if (!db->bricks || !db->stored_bits || !db->stored_rank)
		return FAILF(LOOM_ENOMEM, "%s: out of memory (index of %u stored bricks)",
		             db->path, n);
	for (uint32_t i = 0; i < db->n_bricks; i++) {
		const uint8_t *x = m + io + (size_t)i * db->entry_bytes;
		db_brick bb, *b = &bb;
		uint32_t raw = loom__le32(x + 12);
		char name[192];

		memset(b, 0, sizeof *b);
		b->offset = loom__le64(x);
		b->stored = loom__le32(x + 8);
		b->crc = loom__le32(x + 16);
		b->storage = x[20];
		if (b->storage > (db->entry_bytes == LOOM__DB_INDEX_BYTES ?
		                  LOOM__DB_STORE_RAW : LOOM__DB_STORE_DEFLATE) ||
		    x[21] || x[22] || x[23]) {
			loom__db_brick_name(db, i, name, sizeof name);
			return FAILF(LOOM_EFORMAT, "%s: index entry at metadata offset %zu: "
			             "storage kind %u", name,
			             (size_t)(io + (size_t)i * db->entry_bytes), b->storage);
		}
		if (db->entry_bytes == LOOM__DB_INDEX2_BYTES) {
			int rc = parse_units(db, i, b, x, io, diag);
			if (rc)
				return rc;
		}
		if (raw != db->brick_bytes) {
			loom__db_brick_name(db, i, name, sizeof name);
			return FAILF(LOOM_ECORRUPT, "%s: uncompressed size %u in the index, "
			             "expected %zu (decompressed size mismatch)", name, raw,
			             db->brick_bytes);
		}
		if (b->storage == LOOM__DB_STORE_EMPTY) {
			if (b->offset || b->stored || b->crc) {
				loom__db_brick_name(db, i, name, sizeof name);
				return FAILF(LOOM_EFORMAT, "%s: empty brick with offset %llu, "
				             "size %u", name, (unsigned long long)b->offset,
				             b->stored);
			}
			db->info.n_empty_bricks++;
			continue;
		}
		if (b->storage == LOOM__DB_STORE_RAW && b->stored != db->brick_bytes) {
			loom__db_brick_name(db, i, name, sizeof name);
			return FAILF(LOOM_ECORRUPT, "%s: raw brick of %u bytes, expected %zu "
			             "(size mismatch)", name, b->stored, db->brick_bytes);
		}
		if (b->stored == 0 || b->stored > db->brick_bytes + 1024) {
			loom__db_brick_name(db, i, name, sizeof name);
			return FAILF(LOOM_ERANGE, "%s: stored size %u out of range 1..%zu",
			             name, b->stored, db->brick_bytes + 1024);
		}
		if (b->offset < LOOM__DB_HEADER_BYTES || b->offset > db->data_end ||
		    b->stored > db->data_end - b->offset) {
			loom__db_brick_name(db, i, name, sizeof name);
			return FAILF(LOOM_ERANGE, "%s: bytes [%llu, %llu) outside the brick "
			             "data [%u, %llu) (index out of range)", name,
			             (unsigned long long)b->offset,
			             (unsigned long long)b->offset + b->stored,
			             LOOM__DB_HEADER_BYTES, (unsigned long long)db->data_end);
		}
		if (b->storage == LOOM__DB_STORE_RAW ||
		    (db->entry_bytes == LOOM__DB_INDEX2_BYTES && units_raw(db, b)))
			db->info.n_raw_bricks++;
		if (db->entry_bytes == LOOM__DB_INDEX2_BYTES && b->ub[0] == db->brick_voxels)
			db->info.n_raw_density++;
		db->info.stored_bytes += b->stored;
		if (b->stored > db->max_stored)
			db->max_stored = b->stored;
		db->bricks[k++] = *b;
		db->stored_bits[i >> 6] |= 1ull << (i & 63);
	}
	db->n_stored = k;
	for (size_t w = 1; w < words; w++)
		db->stored_rank[w] = db->stored_rank[w - 1] +
		                     (uint32_t)__builtin_popcountll(db->stored_bits[w - 1]);
	(void)mlen;
	return LOOM_OK;
}

/* After the index: each exemplar's stored_bytes is the sum over its
   bricks, and between the end of the last stored brick and the metadata
   there are 0 to 7 zero bytes (the alignment to 8). */
static int check_stored(loom_db *db, loom_diag *diag)
{
	uint64_t end = LOOM__DB_HEADER_BYTES;
	uint8_t pad[8];
	size_t got;

	for (uint32_t k = 0; k < db->info.n_exemplars; k++) {
		const loom_db_exemplar_info *x = &db->ex[k].pub;
		uint64_t nb = (uint64_t)x->bricks[0] * x->bricks[1] * x->bricks[2], sum = 0;
		for (uint64_t i = 0; i < nb; i++)
			sum += brick_at(db, (uint32_t)(x->first_brick + i))->stored;
		if (sum != x->stored_bytes)
			return FAILF(LOOM_EFORMAT, "%s: exemplar %u at metadata offset %zu, "
			             "field 'stored_bytes': %llu, its bricks store %llu",
			             db->path, k, (size_t)LOOM__DB_META_HEADER_BYTES +
			             (size_t)k * LOOM__DB_EXEMPLAR_BYTES,
			             (unsigned long long)x->stored_bytes,
			             (unsigned long long)sum);
	}
	for (uint32_t i = 0; i < db->n_stored; i++)
		if (db->bricks[i].offset + db->bricks[i].stored > end)
			end = db->bricks[i].offset + db->bricks[i].stored;
	if (db->data_end - end >= 8)
		return FAILF(LOOM_EFORMAT, "%s: offset %llu: %llu bytes between the brick "
		             "data and the metadata, expected at most 7", db->path,
		             (unsigned long long)end,
		             (unsigned long long)(db->data_end - end));
	if (read_at(db->fd, pad, (size_t)(db->data_end - end), end, &got) != 0 ||
	    got != db->data_end - end)
		return FAILF(LOOM_EIO, "%s: cannot read at offset %llu", db->path,
		             (unsigned long long)end);
	if (!all_zero(pad, got))
		return FAILF(LOOM_EFORMAT, "%s: offset %llu: padding before the metadata "
		             "is not zero", db->path,
		             (unsigned long long)(end + first_nonzero(pad, got)));
	return LOOM_OK;
}

static int parse_metadata(loom_db *db, const uint8_t *m, uint64_t mlen,
                          uint32_t trailer_bricks, loom_diag *diag)
{
	const char *p = db->path;
	uint64_t xo, io;
	uint32_t next = 0;
	int rc;

	if (mlen < LOOM__DB_META_HEADER_BYTES)
		return FAILF(LOOM_EFORMAT, "%s: metadata of %llu bytes is shorter than its "
		             "header", p, (unsigned long long)mlen);
	if (memcmp(m, LOOM__DB_META_MAGIC, 8) != 0)
		return FAILF(LOOM_EFORMAT, "%s: metadata offset 0: bad magic, expected "
		             "'LDBMETA1'", p);
	if (loom__le32(m + 8) != db->info.n_exemplars)
		return FAILF(LOOM_EFORMAT, "%s: metadata offset 8: %u exemplars, the "
		             "header says %u", p, loom__le32(m + 8), db->info.n_exemplars);
	if (loom__le32(m + 12) != LOOM__DB_EXEMPLAR_BYTES ||
	    loom__le32(m + 20) != db->entry_bytes ||
	    loom__le32(m + 24) != loom__db_block_entry_bytes(db->info.block[0],
	                                                     db->info.block[1]))
		return FAILF(LOOM_EFORMAT, "%s: metadata offset 12: entry sizes %u/%u/%u, "
		             "expected %u/%u/%zu", p, loom__le32(m + 12), loom__le32(m + 20),
		             loom__le32(m + 24), LOOM__DB_EXEMPLAR_BYTES,
		             (unsigned)db->entry_bytes,
		             loom__db_block_entry_bytes(db->info.block[0], db->info.block[1]));
	if (loom__le32(m + 28) != 0 || !all_zero(m + 48, 16))
		return FAILF(LOOM_EFORMAT, "%s: metadata offset %d: reserved field is not "
		             "zero", p, loom__le32(m + 28) ? 28 : 48);
	db->n_bricks = loom__le32(m + 16);
	if (db->n_bricks != trailer_bricks)
		return FAILF(LOOM_EFORMAT, "%s: metadata offset 16: %u bricks, the trailer "
		             "says %u", p, db->n_bricks, trailer_bricks);
	xo = loom__le64(m + 32);
	io = loom__le64(m + 40);
	if (xo != LOOM__DB_META_HEADER_BYTES ||
	    !sect_ok(xo, (uint64_t)db->info.n_exemplars * LOOM__DB_EXEMPLAR_BYTES, mlen))
		return FAILF(LOOM_ERANGE, "%s: metadata offset 32: exemplar table at %llu "
		             "outside the %llu-byte metadata", p, (unsigned long long)xo,
		             (unsigned long long)mlen);
	if (!sect_ok(io, (uint64_t)db->n_bricks * db->entry_bytes, mlen))
		return FAILF(LOOM_ERANGE, "%s: metadata offset 40: brick index at %llu "
		             "(%u bricks) outside the %llu-byte metadata", p,
		             (unsigned long long)io, db->n_bricks, (unsigned long long)mlen);
	db->ex = calloc(db->info.n_exemplars, sizeof *db->ex);
	if (!db->ex)
		return FAILF(LOOM_ENOMEM, "%s: out of memory", p);
	for (uint32_t k = 0; k < db->info.n_exemplars; k++) {
		rc = parse_exemplar(db, k, m, mlen, &next, diag);
		if (rc)
			return rc;
		db->info.raw_bytes += db->ex[k].pub.raw_bytes;
	}
	if (next != db->n_bricks)
		return FAILF(LOOM_EFORMAT, "%s: the exemplars cover %u bricks, the index "
		             "has %u", p, next, db->n_bricks);
	rc = parse_index(db, m, mlen, io, diag);
	if (rc)
		return rc;
	db->info.n_bricks = db->n_bricks;
	return check_stored(db, diag);
}

LOOM_API int loom_db_open(const char *path, loom_db **out, loom_diag *diag)
{
	loom_db *db;
	uint8_t h[LOOM__DB_HEADER_BYTES], t[LOOM__DB_TRAILER_BYTES];
	uint8_t *meta = NULL;
	uint64_t size, mo, ml, fb, hash;
	size_t got;
	int rc;

	if (!out || !path)
		return loom__fail(diag, LOOM_EINVAL, "loom_db_open: NULL argument");
	*out = NULL;
	db = calloc(1, sizeof *db);
	if (!db)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	db->fd = -1;
	db->path = strdup(path);
	if (!db->path) {
		free(db);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	/* Step 1. */
	rc = loom__open_input(path, &db->fd, &size, diag);
	if (rc)
		goto fail;
	db->info.file_bytes = size;
	if (size < LOOM__DB_HEADER_BYTES) {
		/* a short file may still say what it is: check the magic we have */
		if (read_at(db->fd, h, (size_t)size, 0, &got) == 0 && got >= 8 &&
		    memcmp(h, LOOM__DB_MAGIC, 8) != 0) {
			rc = parse_header(db, h, diag);
			goto fail;
		}
		rc = FAILF(LOOM_ETRUNCATED, "%s: file of %llu bytes ends inside the "
		           "%u-byte header (truncated)", path, (unsigned long long)size,
		           LOOM__DB_HEADER_BYTES);
		goto fail;
	}
	/* Step 2. */
	if (read_at(db->fd, h, sizeof h, 0, &got) != 0 || got != sizeof h) {
		rc = FAILF(LOOM_EIO, "%s: cannot read the header: %s", path, strerror(errno));
		goto fail;
	}
	rc = parse_header(db, h, diag);
	if (rc)
		goto fail;
	/* Step 3. */
	if (size < LOOM__DB_HEADER_BYTES + LOOM__DB_TRAILER_BYTES) {
		rc = FAILF(LOOM_ETRUNCATED, "%s: file of %llu bytes ends before the "
		           "trailer (truncated)", path, (unsigned long long)size);
		goto fail;
	}
	if (read_at(db->fd, t, sizeof t, size - sizeof t, &got) != 0 || got != sizeof t) {
		rc = FAILF(LOOM_EIO, "%s: cannot read the trailer: %s", path, strerror(errno));
		goto fail;
	}
	if (memcmp(t, LOOM__DB_TRAILER_MAGIC, 8) != 0) {
		rc = FAILF(LOOM_ETRUNCATED, "%s: no trailer in the last 64 bytes (offset "
		           "%llu): the file is truncated or was not completely written",
		           path, (unsigned long long)(size - sizeof t));
		goto fail;
	}
	if (loom__le32(t + 60) != libdeflate_crc32(0, t, 60)) {
		rc = FAILF(LOOM_ECORRUPT, "%s: offset %llu: trailer CRC32 mismatch", path,
		           (unsigned long long)(size - 4));
		goto fail;
	}
	if (!all_zero(t + 48, 12)) {
		rc = FAILF(LOOM_EFORMAT, "%s: offset %llu: reserved trailer byte is not "
		           "zero", path, (unsigned long long)(size - sizeof t + 48 +
		                                              first_nonzero(t + 48, 12)));
		goto fail;
	}
	fb = loom__le64(t + 32);
	if (fb != size) {
		rc = FAILF(fb > size ? LOOM_ETRUNCATED : LOOM_EFORMAT,
		           "%s: the trailer records %llu bytes, the file has %llu%s", path,
		           (unsigned long long)fb, (unsigned long long)size,
		           fb > size ? " (truncated)" : "");
		goto fail;
	}
	/* Step 4. */
	mo = loom__le64(t + 8);
	ml = loom__le64(t + 16);
	if (mo < LOOM__DB_HEADER_BYTES || (mo & 7) || ml > LOOM__DB_MAX_META_BYTES ||
	    mo > size || ml != size - LOOM__DB_TRAILER_BYTES - mo) {
		rc = FAILF(LOOM_ERANGE, "%s: offset %llu: metadata [%llu, +%llu) does not "
		           "end at the trailer", path,
		           (unsigned long long)(size - sizeof t + 8), (unsigned long long)mo,
		           (unsigned long long)ml);
		goto fail;
	}
	db->data_end = mo;
	meta = malloc(ml ? (size_t)ml : 1);
	if (!meta) {
		rc = FAILF(LOOM_ENOMEM, "%s: out of memory", path);
		goto fail;
	}
	if (read_at(db->fd, meta, (size_t)ml, mo, &got) != 0 || got != ml) {
		rc = FAILF(got < ml ? LOOM_ETRUNCATED : LOOM_EIO, "%s: cannot read the "
		           "metadata at offset %llu", path, (unsigned long long)mo);
		goto fail;
	}
	if (libdeflate_crc32(0, meta, (size_t)ml) != loom__le32(t + 24)) {
		rc = FAILF(LOOM_ECORRUPT, "%s: metadata at offset %llu: CRC32 0x%08x, the "
		           "trailer says 0x%08x", path, (unsigned long long)mo,
		           libdeflate_crc32(0, meta, (size_t)ml), loom__le32(t + 24));
		goto fail;
	}
	hash = loom__fnv1a64(loom__fnv1a64(LOOM__FNV_OFFSET, h, sizeof h), meta, (size_t)ml);
	if (hash != loom__le64(t + 40)) {
		rc = FAILF(LOOM_ECORRUPT, "%s: content hash %016llx, the trailer says "
		           "%016llx", path, (unsigned long long)hash,
		           (unsigned long long)loom__le64(t + 40));
		goto fail;
	}
	db->info.content_hash = hash;
	db->info.metadata_bytes = ml;
	/* Step 5. */
	rc = parse_metadata(db, meta, ml, loom__le32(t + 28), diag);
	if (rc)
		goto fail;
	free(meta);
	{
		/* Step 6: measure one decompressor for loom__db_reader_bytes */
		struct libdeflate_decompressor *probe = libdeflate_alloc_decompressor();
		size_t dsz = probe ? malloc_usable_size(probe) : 0;
		if (probe)
			libdeflate_free_decompressor(probe);
		db->reader_bytes = (dsz ? dsz : 65536) + loom__db_scratch_bytes(db) + 64 +
		                   sizeof(void *) * 4;
	}
	*out = db;
	return LOOM_OK;
fail:
	free(meta);
	loom_db_close(db);
	return rc;
}

LOOM_API void loom_db_close(loom_db *db)
{
	if (!db)
		return;
	if (db->fd >= 0)
		close(db->fd);
	if (db->ex)
		for (uint32_t k = 0; k < db->info.n_exemplars; k++) {
			free(db->ex[k].weave);
			free(db->ex[k].sym);
			free(db->ex[k].bmeta);
			free(db->ex[k].bf);
		}
	free(db->ex);
	free(db->bricks);
	free(db->stored_bits);
	free(db->stored_rank);
	free(db->path);
	free(db);
}

/* ---- queries ------------------------------------------------------------ */

LOOM_API int loom_db_get_info(const loom_db *db, loom_db_info *info)
{
	if (!db || !info)
		return LOOM_EINVAL;
	*info = db->info;
	return LOOM_OK;
}

LOOM_API uint64_t loom_db_content_hash(const loom_db *db)
{
	return db ? db->info.content_hash : 0;
}

LOOM_API int loom_db_exemplar(const loom_db *db, uint32_t k, loom_db_exemplar_info *out)
{
	if (!db || !out)
		return LOOM_EINVAL;
	if (k >= db->info.n_exemplars)
		return LOOM_ERANGE;
	*out = db->ex[k].pub;
	return LOOM_OK;
}

LOOM_API int loom_db_find_exemplar(const loom_db *db, const char *s, uint32_t *k)
{
	char *end;
	unsigned long v;

	if (!db || !s || !k)
		return LOOM_EINVAL;
	for (uint32_t i = 0; i < db->info.n_exemplars; i++)
		if (strcmp(db->ex[i].pub.name, s) == 0) {
			*k = i;
			return LOOM_OK;
		}
	if (*s >= '0' && *s <= '9') {
		errno = 0;
		v = strtoul(s, &end, 10);
		if (!errno && !*end && v < db->info.n_exemplars) {
			*k = (uint32_t)v;
			return LOOM_OK;
		}
	}
	return LOOM_ENOTFOUND;
}

LOOM_API int loom_db_block(const loom_db *db, uint32_t k, uint32_t row,
                           uint32_t col, loom_db_block_info *out)
{
	const db_exm *e;
	size_t i, nf;
	const float *f;

	if (!db || !out)
		return LOOM_EINVAL;
	if (k >= db->info.n_exemplars)
		return LOOM_ERANGE;
	e = &db->ex[k];
	if (row >= e->pub.rows || col >= e->pub.cols)
		return LOOM_ERANGE;
	i = (size_t)row * e->pub.cols + col;
	nf = 3 + 2 * ((size_t)db->info.block[0] + db->info.block[1]);
	f = e->bf + i * nf;
	out->code = e->bmeta[4 * i];
	out->centre_kind = e->bmeta[4 * i + 1];
	out->gap_columns = loom__le16(e->bmeta + 4 * i + 2);
	out->mean_dh_x = f[0];
	out->mean_dh_y = f[1];
	out->mean_height = f[2];
	out->north = f + 3;
	out->south = out->north + db->info.block[0];
	out->west = out->south + db->info.block[0];
	out->east = out->west + db->info.block[1];
	return LOOM_OK;
}

/* ---- bricks ------------------------------------------------------------- */

void loom__db_geometry(const loom_db *db, loom__db_geom *g)
{
	memcpy(g->brick, db->info.brick, sizeof g->brick);
	memcpy(g->block, db->info.block, sizeof g->block);
	g->brick_voxels = db->brick_voxels;
	g->brick_bytes = db->brick_bytes;
	g->n_exemplars = db->info.n_exemplars;
	g->n_bricks = db->n_bricks;
	g->top_threshold = (uint8_t)db->info.top_threshold;
}

int loom__db_brick_id(const loom_db *db, uint32_t k, uint32_t bx, uint32_t by,
                      uint32_t bz, uint32_t *id)
{
	const loom_db_exemplar_info *e;

	if (k >= db->info.n_exemplars)
		return LOOM_ERANGE;
	e = &db->ex[k].pub;
	if (bx >= e->bricks[0] || by >= e->bricks[1] || bz >= e->bricks[2])
		return LOOM_ERANGE;
	*id = e->first_brick + (by * e->bricks[0] + bx) * e->bricks[2] + bz;
	return LOOM_OK;
}

int loom__db_brick_coords(const loom_db *db, uint32_t id, uint32_t *k,
                          uint32_t *bx, uint32_t *by, uint32_t *bz)
{
	uint32_t lo = 0, hi = db->info.n_exemplars, local;
	const loom_db_exemplar_info *e;

	if (!db->ex || id >= db->n_bricks)
		return LOOM_ERANGE;
	while (hi - lo > 1) { /* last exemplar with first_brick <= id */
		uint32_t mid = (lo + hi) / 2;
		if (db->ex[mid].pub.first_brick <= id)
			lo = mid;
		else
			hi = mid;
	}
	e = &db->ex[lo].pub;
	local = id - e->first_brick;
	*k = lo;
	*bz = local % e->bricks[2];
	*bx = (local / e->bricks[2]) % e->bricks[0];
	*by = local / e->bricks[2] / e->bricks[0];
	return LOOM_OK;
}

void loom__db_brick_name(const loom_db *db, uint32_t id, char *buf, size_t n)
{
	uint32_t k, bx, by, bz;

	if (loom__db_brick_coords(db, id, &k, &bx, &by, &bz) == LOOM_OK &&
	    db->ex[k].pub.name[0])
		snprintf(buf, n, "%s: brick %u (exemplar %u '%s', brick x=%u y=%u z=%u)",
		         db->path, id, k, db->ex[k].pub.name, bx, by, bz);
	else
		snprintf(buf, n, "%s: brick %u", db->path, id);
}

int loom__db_brick_empty(const loom_db *db, uint32_t id)
{
	return id < db->n_bricks && brick_at(db, id)->storage == LOOM__DB_STORE_EMPTY;
}

size_t loom__db_scratch_bytes(const loom_db *db)
{
	return db->max_stored ? db->max_stored : 1;
}

const loom_db_yarn *loom__db_yarn_lut(const loom_db *db, uint32_t k)
{
	return k < db->info.n_exemplars ? db->ex[k].yarns : NULL;
}

static const char *inflate_error(enum libdeflate_result r)
{
	return r == LIBDEFLATE_SHORT_OUTPUT ? "decompressed size mismatch: fewer bytes" :
	       r == LIBDEFLATE_INSUFFICIENT_SPACE ? "decompressed size mismatch: more bytes" :
	                                            "invalid deflate data";
}

/* A segmented density unit (layout 3) of brick id, its n stored bytes src
   (CRC checked) at file offset off: check the segment header, then
   inflate segments q0 .. q1-1 into their rows of plane. */
static int segs_decode(const loom_db *db, uint32_t id,
                       struct libdeflate_decompressor *dec, const uint8_t *src,
                       size_t n, uint64_t off, uint8_t *plane, unsigned q0, unsigned q1,
                       loom_diag *diag)
{
	size_t at = LOOM__DB_SEG_HEADER, lo[LOOM__DB_SEGS], len[LOOM__DB_SEGS];
	uint32_t c[LOOM__DB_SEGS];
	enum libdeflate_result r;
	char name[192];

	for (unsigned q = 0; q < LOOM__DB_SEGS; q++) {
		loom__db_seg_range(db->info.brick, LOOM__DB_SEGS, q, &lo[q], &len[q]);
		c[q] = loom__le32(src + 4 * q);
		if (c[q] > len[q] || c[q] > n - at) {
			loom__db_brick_name(db, id, name, sizeof name);
			return loom__fail(diag, LOOM_ECORRUPT, "%s, unit 0 (density) at offset "
			                  "%llu: segment %u of %u bytes, expected 0..%zu within "
			                  "the unit's %zu bytes", name, (unsigned long long)off,
			                  q, c[q], len[q], n);
		}
		at += c[q];
	}
	if (at != n) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ECORRUPT, "%s, unit 0 (density) at offset %llu: "
		                  "segments of %zu bytes with their header, the unit has %zu",
		                  name, (unsigned long long)off, at, n);
	}
	at = LOOM__DB_SEG_HEADER;
	for (unsigned q = 0; q < q1; at += c[q], q++) {
		if (q < q0)
			continue;
		if (c[q] == 0) {
			memset(plane + lo[q], 0, len[q]);
		} else if (c[q] == len[q]) {
			memcpy(plane + lo[q], src + at, len[q]);
		} else {
			r = libdeflate_deflate_decompress(dec, src + at, c[q], plane + lo[q],
			                                  len[q], NULL);
			if (r != LIBDEFLATE_SUCCESS) {
				loom__db_brick_name(db, id, name, sizeof name);
				return loom__fail(diag, LOOM_ECORRUPT, "%s, unit 0 (density), "
				                  "segment %u at offset %llu: %s (expected %zu "
				                  "bytes)", name, q,
				                  (unsigned long long)(off + at), inflate_error(r),
				                  len[q]);
			}
		}
	}
	return LOOM_OK;
}

/* Unit u of brick id (layouts 2 and 3), its stored bytes src (already
   read): CRC, then zero, copy or inflate the rows of segments q0 .. q1-1
   (all: 0 .. LOOM__DB_SEGS; a layout-2 unit or one stored raw has one
   segment, the plane) at out, which holds the whole plane. */
static int unit_decode_segs(const loom_db *db, uint32_t id, unsigned u,
                            struct libdeflate_decompressor *dec, const uint8_t *src,
                            uint64_t off, uint8_t *out, unsigned q0, unsigned q1,
                            int checked, loom_diag *diag)
{
	const db_brick *b = brick_at(db, id);
	size_t V = db->brick_voxels, lo = 0, len = V;
	uint32_t crc;
	enum libdeflate_result r;
	char name[192];

	if (q1 - q0 < LOOM__DB_SEGS) /* one segment: its rows */
		loom__db_seg_range(db->info.brick, LOOM__DB_SEGS, q0, &lo, &len);
	if (b->ub[u] == 0) {
		memset(out + lo, 0, len);
		return LOOM_OK;
	}
	crc = checked ? b->uc[u] : libdeflate_crc32(0, src, b->ub[u]);
	if (crc != b->uc[u]) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ECORRUPT, "%s, unit %u (%s): CRC32 mismatch at "
		                  "offset %llu (%u bytes): computed 0x%08x, index says "
		                  "0x%08x", name, u, unit_names[u], (unsigned long long)off,
		                  b->ub[u], crc, b->uc[u]);
	}
	if (b->ub[u] == V) {
		if (src != out)
			memcpy(out + lo, src + lo, len);
		return LOOM_OK;
	}
	if (u == 0 && db->info.voxel_layout == LOOM__DB_LAYOUT_SEGS) {
		if (b->ub[u] < LOOM__DB_SEG_HEADER) {
			loom__db_brick_name(db, id, name, sizeof name);
			return loom__fail(diag, LOOM_ECORRUPT, "%s, unit 0 (density) at offset "
			                  "%llu: %u bytes, shorter than its %u-byte segment "
			                  "header", name, (unsigned long long)off, b->ub[u],
			                  LOOM__DB_SEG_HEADER);
		}
		return segs_decode(db, id, dec, src, b->ub[u], off, out, q0, q1, diag);
	}
	if (u == 0 && db->info.voxel_layout == LOOM__DB_LAYOUT_ZRUN) {
		size_t at;
		if (loom__zrun_decode(src, b->ub[u], out, V, &at) != 0) {
			loom__db_brick_name(db, id, name, sizeof name);
			return loom__fail(diag, LOOM_ECORRUPT, "%s, unit 0 (density) at offset "
			                  "%llu: zero-run code malformed at byte %zu of %u "
			                  "(a run past the plane's %zu bytes or past the unit, "
			                  "or too few bytes)", name, (unsigned long long)off,
			                  at, b->ub[u], V);
		}
		return LOOM_OK;
	}
	r = libdeflate_deflate_decompress(dec, src, b->ub[u], out, V, NULL);
	if (r != LIBDEFLATE_SUCCESS) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ECORRUPT, "%s, unit %u (%s) at offset %llu: %s "
		                  "(expected %zu bytes)", name, u, unit_names[u],
		                  (unsigned long long)off, inflate_error(r), V);
	}
	return LOOM_OK;
}

/* The whole unit u of brick id at out (V bytes). */
static int unit_decode(const loom_db *db, uint32_t id, unsigned u,
                       struct libdeflate_decompressor *dec, const uint8_t *src,
                       uint64_t off, uint8_t *out, loom_diag *diag)
{
	return unit_decode_segs(db, id, u, dec, src, off, out, 0, LOOM__DB_SEGS, 0, diag);
}

/* pread n bytes of brick id at off; the error names the brick. */
static int brick_pread(const loom_db *db, uint32_t id, uint8_t *dst, size_t n,
                       uint64_t off, size_t *n_read, loom_diag *diag)
{
	size_t got;
	char name[192];

	if (read_at(db->fd, dst, n, off, &got) != 0) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_EIO, "%s: read at offset %llu failed: %s",
		                  name, (unsigned long long)off, strerror(errno));
	}
	if (n_read)
		*n_read += got;
	if (got != n) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ETRUNCATED, "%s: file ends after %zu of %zu "
		                  "bytes at offset %llu (truncated)", name, got, n,
		                  (unsigned long long)off);
	}
	return LOOM_OK;
}

/* Layout 2, the whole brick: one pread of its units, each checked. */
static int read_units(const loom_db *db, uint32_t id,
                      struct libdeflate_decompressor *dec, uint8_t *scratch,
                      uint8_t *out, size_t *n_read, loom_diag *diag)
{
	const db_brick *b = brick_at(db, id);
	uint64_t off = b->offset;
	int rc = brick_pread(db, id, scratch, b->stored, off, n_read, diag);

	for (unsigned u = 0; u < LOOM__DB_UNITS && !rc; u++) {
		rc = unit_decode(db, id, u, dec, scratch + (off - b->offset), off,
		                 out + u * db->brick_voxels, diag);
		off += b->ub[u];
	}
	return rc;
}

int loom__db_read_brick(const loom_db *db, uint32_t id,
                        struct libdeflate_decompressor *dec, uint8_t *scratch,
                        uint8_t *out, size_t *n_read, loom_diag *diag)
{
	const db_brick *b;
	uint8_t *dst;
	size_t got;
	uint32_t crc;
	enum libdeflate_result r;
	char name[192];

	if (n_read)
		*n_read = 0;
	if (id >= db->n_bricks)
		return loom__fail(diag, LOOM_ERANGE, "%s: brick %u out of range (the "
		                  "database has %u bricks)", db->path, id, db->n_bricks);
	b = brick_at(db, id);
	if (b->storage == LOOM__DB_STORE_EMPTY) {
		memset(out, 0, db->brick_bytes);
		return LOOM_OK;
	}
	if (db->entry_bytes == LOOM__DB_INDEX2_BYTES)
		return read_units(db, id, dec, scratch, out, n_read, diag);
	dst = b->storage == LOOM__DB_STORE_RAW ? out : scratch;
	if (read_at(db->fd, dst, b->stored, b->offset, &got) != 0) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_EIO, "%s: read at offset %llu failed: %s",
		                  name, (unsigned long long)b->offset, strerror(errno));
	}
	if (n_read)
		*n_read = got;
	if (got != b->stored) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ETRUNCATED, "%s: file ends after %zu of its %u "
		                  "bytes at offset %llu (truncated)", name, got, b->stored,
		                  (unsigned long long)b->offset);
	}
	crc = libdeflate_crc32(0, dst, b->stored);
	if (crc != b->crc) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ECORRUPT, "%s: CRC32 mismatch at offset %llu "
		                  "(%u bytes): computed 0x%08x, index says 0x%08x", name,
		                  (unsigned long long)b->offset, b->stored, crc, b->crc);
	}
	if (b->storage == LOOM__DB_STORE_RAW)
		return LOOM_OK;
	r = libdeflate_deflate_decompress(dec, scratch, b->stored, out, db->brick_bytes,
	                                  NULL);
	if (r != LIBDEFLATE_SUCCESS) {
		loom__db_brick_name(db, id, name, sizeof name);
		return loom__fail(diag, LOOM_ECORRUPT, "%s: %s (expected %zu bytes)", name,
		                  inflate_error(r), db->brick_bytes);
	}
	return LOOM_OK;
}

struct loom__db_reader {
	const loom_db *db;
	struct libdeflate_decompressor *dec;
	uint8_t *scratch;
	/* scratch holds the density unit of brick seg_id, CRC checked (read_seg:
	   the next segment of the same brick reads nothing) */
	uint32_t seg_id;
	int seg_held;
};

loom__db_reader *loom__db_reader_new(const loom_db *db)
{
	loom__db_reader *r = calloc(1, sizeof *r);

	if (!r)
		return NULL;
	r->db = db;
	r->dec = libdeflate_alloc_decompressor();
	r->scratch = malloc(loom__db_scratch_bytes(db));
	if (!r->dec || !r->scratch) {
		loom__db_reader_free(r);
		return NULL;
	}
	return r;
}

void loom__db_reader_free(loom__db_reader *r)
{
	if (!r)
		return;
	if (r->dec)
		libdeflate_free_decompressor(r->dec);
	free(r->scratch);
	free(r);
}

size_t loom__db_reader_bytes(const loom_db *db)
{
	return db->reader_bytes;
}

int loom__db_reader_read(loom__db_reader *r, uint32_t id, uint8_t *out,
                         size_t *n_read, loom_diag *diag)
{
	r->seg_held = 0; /* scratch is overwritten */
	return loom__db_read_brick(r->db, id, r->dec, r->scratch, out, n_read, diag);
}

unsigned loom__db_layout(const loom_db *db)
{
	return db->info.voxel_layout;
}

int loom__db_reader_read_unit(loom__db_reader *r, uint32_t id, unsigned u,
                              uint8_t *out, size_t *n_read, loom_diag *diag)
{
	const loom_db *db = r->db;
	const db_brick *b;
	uint64_t off;
	uint8_t *src;
	int rc;

	if (n_read)
		*n_read = 0;
	r->seg_held = 0; /* scratch may be overwritten */
	if (id >= db->n_bricks || u >= LOOM__DB_UNITS)
		return loom__fail(diag, LOOM_ERANGE, "%s: brick %u unit %u out of range "
		                  "(the database has %u bricks)", db->path, id, u,
		                  db->n_bricks);
	if (db->entry_bytes != LOOM__DB_INDEX2_BYTES)
		return loom__fail(diag, LOOM_EUNSUPPORTED, "%s: voxel layout %u stores "
		                  "whole bricks, not plane units", db->path,
		                  db->info.voxel_layout);
	b = brick_at(db, id);
	off = b->offset;
	for (unsigned k = 0; k < u; k++)
		off += b->ub[k];
	if (b->ub[u] == 0) {
		memset(out, 0, db->brick_voxels);
		return LOOM_OK;
	}
	src = b->ub[u] == db->brick_voxels ? out : r->scratch;
	rc = brick_pread(db, id, src, b->ub[u], off, n_read, diag);
	return rc ? rc : unit_decode(db, id, u, r->dec, src, off, out, diag);
}

unsigned loom__db_dsegs(const loom_db *db)
{
	return db->info.voxel_layout == LOOM__DB_LAYOUT_SEGS ? LOOM__DB_SEGS :
	       db->info.voxel_layout == LOOM__DB_LAYOUT_PLANES ? 0u : 1u;
}

int loom__db_reader_read_seg(loom__db_reader *r, uint32_t id, unsigned q, uint8_t *plane,
                             int checked, size_t *n_read, loom_diag *diag)
{
	const loom_db *db = r->db;
	unsigned ns = loom__db_dsegs(db);
	const db_brick *b;
	size_t lo, len;
	int rc;

	if (n_read)
		*n_read = 0;
	if (id >= db->n_bricks || q >= ns)
		return loom__fail(diag, ns ? LOOM_ERANGE : LOOM_EUNSUPPORTED, "%s: brick %u "
		                  "density segment %u out of range (the database has %u "
		                  "bricks, %u segments a density plane)", db->path, id, q,
		                  db->n_bricks, ns);
	if (ns == 1)
		return loom__db_reader_read_unit(r, id, 0, plane, n_read, diag);
	b = brick_at(db, id);
	if (b->ub[0] == 0) {
		loom__db_seg_range(db->info.brick, ns, q, &lo, &len);
		memset(plane + lo, 0, len);
		return LOOM_OK;
	}
	/* into scratch even when raw: only the segment's rows are written; a
	   unit still there from this reader's last segment is not read again */
	if (r->seg_held && r->seg_id == id) {
		checked = 1;
	} else {
		r->seg_held = 0;
		if ((rc = brick_pread(db, id, r->scratch, b->ub[0], b->offset, n_read, diag)))
			return rc;
	}
	rc = unit_decode_segs(db, id, 0, r->dec, r->scratch, b->offset, plane, q, q + 1,
	                      checked, diag);
	/* held once its CRC matched (a segment that fails to inflate leaves
	   the others readable) */
	if (rc == LOOM_OK || checked || libdeflate_crc32(0, r->scratch, b->ub[0]) == b->uc[0]) {
		r->seg_id = id;
		r->seg_held = 1;
	}
	return rc;
}

/* ---- whole-exemplar helpers -------------------------------------------------- */

LOOM_API int loom_db_read_box(const loom_db *db, uint32_t k,
                              const uint32_t origin[3], const uint32_t size[3],
                              uint8_t *density, uint16_t *orientation,
                              uint8_t *label, loom_diag *diag)
{
	const loom_db_exemplar_info *e;
	struct libdeflate_decompressor *dec;
	uint8_t *brick, *scratch;
	uint32_t bmin[3], bmax[3];
	const uint32_t *bs;
	size_t nv;
	loom__db_reader rd;
	int rc = LOOM_OK, density_only;

	if (!db || !origin || !size)
		return loom__fail(diag, LOOM_EINVAL, "loom_db_read_box: NULL argument");
	if (k >= db->info.n_exemplars)
		return loom__fail(diag, LOOM_ERANGE, "%s: exemplar %u out of range (%u "
		                  "exemplars)", db->path, k, db->info.n_exemplars);
	e = &db->ex[k].pub;
	for (int a = 0; a < 3; a++)
		if (size[a] == 0 || origin[a] >= e->size[a] || size[a] > e->size[a] - origin[a])
			return loom__fail(diag, LOOM_ERANGE, "%s: box [%u, +%u) on axis %d "
			                  "outside exemplar '%s' (%u voxels)", db->path,
			                  origin[a], size[a], a, e->name, e->size[a]);
	bs = db->info.brick;
	nv = db->brick_voxels;
	dec = libdeflate_alloc_decompressor();
	brick = malloc(db->brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	if (!dec || !brick || !scratch) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", db->path);
		goto done;
	}
	for (int a = 0; a < 3; a++) {
		bmin[a] = origin[a] / bs[a];
		bmax[a] = (origin[a] + size[a] - 1) / bs[a];
	}
	/* density alone from a database of plane units: read and inflate the
	   density unit of each brick only (the majorant grid's build: 2-3x
	   less inflating than whole bricks) */
	density_only = density && !orientation && !label &&
	               db->entry_bytes == LOOM__DB_INDEX2_BYTES;
	rd.db = db;
	rd.dec = dec;
	rd.scratch = scratch;
	for (uint32_t by = bmin[1]; by <= bmax[1] && !rc; by++)
		for (uint32_t bx = bmin[0]; bx <= bmax[0] && !rc; bx++)
			for (uint32_t bz = bmin[2]; bz <= bmax[2] && !rc; bz++) {
				uint32_t id = 0, lo[3], hi[3];
				loom__db_brick_id(db, k, bx, by, bz, &id);
				if (density_only) /* its plane unit alone (the first plane) */
					rc = loom__db_reader_read_unit(&rd, id, 0, brick, NULL, diag);
				else
					rc = loom__db_read_brick(db, id, dec, scratch, brick, NULL, diag);
				if (rc)
					break;
				lo[0] = bx * bs[0];
				lo[1] = by * bs[1];
				lo[2] = bz * bs[2];
				for (int a = 0; a < 3; a++) {
					hi[a] = lo[a] + bs[a];
					if (lo[a] < origin[a])
						lo[a] = origin[a];
					if (hi[a] > origin[a] + size[a])
						hi[a] = origin[a] + size[a];
				}
				/* x innermost: the output rows are written in order
				   (the brick, a few KiB a plane, is read across) */
				for (uint32_t z = lo[2]; z < hi[2]; z++)
					for (uint32_t y = lo[1]; y < hi[1]; y++) {
						size_t s = loom__brick_index(bs[0], bs[2], lo[0] - bx * bs[0],
						                             y - by * bs[1], z - bz * bs[2]);
						size_t d = ((size_t)(z - origin[2]) * size[1] +
						            (y - origin[1])) * size[0] + (lo[0] - origin[0]);
						for (uint32_t x = lo[0]; x < hi[0]; x++, s += bs[2], d++) {
							if (density)
								density[d] = brick[s];
							if (orientation)
								orientation[d] = loom__brick_orient(brick, nv, s);
							if (label)
								label[d] = brick[3 * nv + s];
						}
					}
			}
done:
	if (dec)
		libdeflate_free_decompressor(dec);
	free(brick);
	free(scratch);
	return rc;
}

/*
 * The voxel rule of docs/formats.md: every voxel of density 0 has
 * orientation code 0 (point lookups report none there, region reads copy
 * the stored code).  `loom exemplar generate` and `loom exemplar build`
 * broke it before 2026-12-05; loom_db_convert writes such a file again
 * with the codes cleared.
 */
static int check_orient_rule(const loom_db *db, uint32_t id, uint32_t bx,
                             uint32_t by, uint32_t bz, const uint8_t *brick,
                             loom_diag *diag)
{
	const uint32_t *bs = db->info.brick;
	size_t nv = db->brick_voxels;

	for (size_t i = 0; i < nv; i++) {
		uint16_t code;
		char name[192];
		if (brick[i] != 0 || (brick[nv + i] | brick[2 * nv + i]) == 0)
			continue;
		code = loom__brick_orient(brick, nv, i);
		loom__db_brick_name(db, id, name, sizeof name);
		/* i = (ly * bx + lx) * bz + lz */
		return loom__fail(diag, LOOM_ECORRUPT, "%s: voxel (%llu, %llu, %llu) of "
		                  "the exemplar has density 0 and orientation code 0x%04x "
		                  "(expected 0: docs/formats.md; `loom exemplar generate` "
		                  "and `loom exemplar build` wrote such codes before "
		                  "2026-12-05: generate the database again, or `loom "
		                  "exemplar convert` writes it again with the codes "
		                  "cleared)", name,
		                  (unsigned long long)bx * bs[0] + (i / bs[2]) % bs[0],
		                  (unsigned long long)by * bs[1] + i / ((size_t)bs[2] * bs[0]),
		                  (unsigned long long)bz * bs[2] + i % bs[2], code);
	}
	return LOOM_OK;
}

LOOM_API int loom_db_verify(const loom_db *db,
                            void (*progress)(void *user, uint64_t done,
                                             uint64_t total),
                            void *user, loom_diag *diag)
{
	struct libdeflate_decompressor *dec;
	uint8_t *brick, *scratch;
	int rc = LOOM_OK;

	if (!db)
		return loom__fail(diag, LOOM_EINVAL, "loom_db_verify: NULL database");
	dec = libdeflate_alloc_decompressor();
	brick = malloc(db->brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	if (!dec || !brick || !scratch) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", db->path);
		goto done;
	}
	for (uint32_t id = 0; id < db->n_bricks; id++) {
		uint32_t k, bx, by, bz;
		const uint8_t *lab = brick + 3 * db->brick_voxels;

		rc = loom__db_read_brick(db, id, dec, scratch, brick, NULL, diag);
		if (rc)
			break;
		loom__db_brick_coords(db, id, &k, &bx, &by, &bz);
		for (size_t i = 0; i < db->brick_voxels; i++)
			if (lab[i] > db->ex[k].pub.n_yarns) {
				char name[192];
				loom__db_brick_name(db, id, name, sizeof name);
				rc = loom__fail(diag, LOOM_ECORRUPT, "%s: voxel %zu has label %u, "
				                "the yarn table has %u labels", name, i, lab[i],
				                db->ex[k].pub.n_yarns);
				break;
			}
		if (rc)
			break;
		if ((rc = check_orient_rule(db, id, bx, by, bz, brick, diag)) != LOOM_OK)
			break;
		if (progress && ((id & 63) == 63 || id + 1 == db->n_bricks))
			progress(user, id + 1, db->n_bricks);
	}
done:
	if (dec)
		libdeflate_free_decompressor(dec);
	free(brick);
	free(scratch);
	return rc;
}

/* ---- voxel encodings (public wrappers of voxel.h) ---------------------------- */

LOOM_API void loom_orientation_decode(uint16_t code, float dir[3])
{
	loom__orient_decode(code, dir);
}

LOOM_API uint16_t loom_orientation_encode(const float dir[3])
{
	return loom__orient_encode(dir[0], dir[1], dir[2]);
}

LOOM_API int loom_db_channel_parse(const char *s, int *channel)
{
	static const char *const names[LOOM_DB_CH_COUNT_] = {
		"density", "label", "kind", "orientation", "orient-code"};

	if (!s || !channel)
		return LOOM_EINVAL;
	for (int c = 0; c < LOOM_DB_CH_COUNT_; c++)
		if (strcmp(s, names[c]) == 0) {
			*channel = c;
			return LOOM_OK;
		}
	return LOOM_EINVAL;
}
