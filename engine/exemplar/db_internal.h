/*
 * engine/exemplar/db_internal.h - exemplar database internals shared by the reader
 * (engine/exemplar/db.c), the writer (io/store/db_write.c), the generator (engine/exemplar/exgen.c)
 * and the virtual-texture engine.  Never installed.
 *
 * File layout (docs/formats.md, "Exemplar database (.ldb)"), little-endian:
 *
 *   +--------------------+ 0
 *   | header  (128 B)    |  magic, version, geometry, header CRC
 *   +--------------------+ 128
 *   | brick data         |  stored bricks back to back (deflate or raw);
 *   |                    |  empty bricks take no bytes
 *   +--------------------+ metadata_offset (8-aligned)
 *   | metadata           |  meta header, exemplar table, per exemplar:
 *   |                    |  weave, yarn table, symmetries, block tables;
 *   |                    |  brick index (24 B per brick)
 *   +--------------------+
 *   | trailer (64 B)     |  metadata offset/size/CRC, file size, content
 *   +--------------------+  hash, trailer CRC  (written last)
 *
 * Engine use: geometry once, then per brick miss
 *   loom__db_brick_id -> loom__db_brick_empty? -> loom__db_read_brick
 * with a per-thread libdeflate decompressor and scratch buffer of
 * loom__db_scratch_bytes().  The reader holds no mutable state: reads are
 * thread-safe (pread on one descriptor).
 */
#ifndef LOOM_DB_INTERNAL_H
#define LOOM_DB_INTERNAL_H

#include "core/internal.h"
#include "loom/db.h"
#include "voxel.h"

#include <string.h>

struct libdeflate_decompressor;

/* ---- format constants ------------------------------------------------- */

#define LOOM__DB_MAGIC "\x89LDB\r\n\x1a\n"   /* 8 bytes */
#define LOOM__DB_META_MAGIC "LDBMETA1"        /* 8 bytes */
#define LOOM__DB_TRAILER_MAGIC "LDBTRAIL"     /* 8 bytes */
#define LOOM__DB_VERSION 4u                   /* newest read and written */
#define LOOM__DB_VERSION_DEFAULT 4u           /* written when none is asked */
#define LOOM__DB_VERSION_UNITS2 2u            /* plane units, density whole */
#define LOOM__DB_VERSION_PLANES1 1u           /* whole-brick streams */
#define LOOM__DB_HEADER_BYTES 128u
#define LOOM__DB_TRAILER_BYTES 64u
#define LOOM__DB_META_HEADER_BYTES 64u
#define LOOM__DB_EXEMPLAR_BYTES 192u
#define LOOM__DB_INDEX_BYTES 24u              /* version 1 */
#define LOOM__DB_INDEX2_BYTES 56u             /* version 2: + 4 unit entries */
#define LOOM__DB_LAYOUT_PLANES 1u             /* voxel_layout: 4 byte planes */
#define LOOM__DB_LAYOUT_UNITS 2u              /* the planes stored apart */
#define LOOM__DB_LAYOUT_SEGS 3u               /* units, the density one in
                                                 segments (version 3) */
#define LOOM__DB_LAYOUT_ZRUN 4u               /* units, the density one
                                                 zero-run coded (version 4) */
#define LOOM__DB_UNITS 4u                     /* units of a layout-2/3 brick */
#define LOOM__DB_SEGS 8u                      /* segments of a layout-3
                                                 density unit */
#define LOOM__DB_SEG_HEADER (4u * LOOM__DB_SEGS) /* their sizes, u32 each */
#define LOOM__DB_TOP_THRESHOLD 64u            /* density of the surface rule */

/* Brick storage kinds (index entry byte 20). */
#define LOOM__DB_STORE_EMPTY 0u
#define LOOM__DB_STORE_DEFLATE 1u
#define LOOM__DB_STORE_RAW 2u

/* Limits the reader enforces (a malformed file cannot make it allocate or
   read more). */
#define LOOM__DB_MAX_BLOCK 4096u        /* b1, b2, b3 */
#define LOOM__DB_MAX_BRICK 1024u        /* brick side */
#define LOOM__DB_MAX_BRICK_BYTES (64u << 20)
#define LOOM__DB_MAX_EXEMPLARS 4096u
#define LOOM__DB_MAX_CROSSINGS 1024u    /* rows, cols */
#define LOOM__DB_MAX_EXTENT 65536u      /* exemplar voxels along x or y */
#define LOOM__DB_MAX_META_BYTES (1ull << 30)

/* Per-block table entry: 16 bytes + four float profiles. */
static inline size_t loom__db_block_entry_bytes(uint32_t b1, uint32_t b2)
{
	return 16u + 8u * ((size_t)b1 + b2);
}

/* ---- little-endian helpers -------------------------------------------- */

static inline uint32_t loom__le32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
	       (uint32_t)p[3] << 24;
}
static inline uint16_t loom__le16(const uint8_t *p)
{
	return (uint16_t)(p[0] | p[1] << 8);
}
static inline uint64_t loom__le64(const uint8_t *p)
{
	return (uint64_t)loom__le32(p) | (uint64_t)loom__le32(p + 4) << 32;
}
static inline float loom__lef32(const uint8_t *p)
{
	uint32_t u = loom__le32(p);
	float f;
	memcpy(&f, &u, 4);
	return f;
}
static inline void loom__put16(uint8_t *p, uint16_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
}
static inline void loom__put32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}
static inline void loom__put64(uint8_t *p, uint64_t v)
{
	loom__put32(p, (uint32_t)v);
	loom__put32(p + 4, (uint32_t)(v >> 32));
}
static inline void loom__putf32(uint8_t *p, float f)
{
	uint32_t u;
	memcpy(&u, &f, 4);
	loom__put32(p, u);
}

/* FNV-1a 64 (content hash): start with LOOM__FNV_OFFSET. */
#define LOOM__FNV_OFFSET 0xcbf29ce484222325ull
#define LOOM__FNV_PRIME 0x100000001b3ull
static inline uint64_t loom__fnv1a64(uint64_t h, const void *data, size_t n)
{
	const uint8_t *p = data;
	for (size_t i = 0; i < n; i++) {
		h ^= p[i];
		h *= LOOM__FNV_PRIME;
	}
	return h;
}

/* ---- brick geometry ----------------------------------------------------- */

typedef struct loom__db_geom {
	uint32_t brick[3];      /* bx, by, bz voxels */
	uint32_t block[3];      /* b1, b2, b3 */
	size_t brick_voxels;    /* bx*by*bz */
	size_t brick_bytes;     /* brick_voxels * LOOM__VOXEL_PLANES */
	uint32_t n_exemplars;
	uint32_t n_bricks;      /* all exemplars */
	uint8_t top_threshold;
} loom__db_geom;

void loom__db_geometry(const loom_db *db, loom__db_geom *g);

/* Global id of brick (bx, by, bz) of exemplar k:
   first_brick + (by * bricks_x + bx) * bricks_z + bz.  LOOM_ERANGE. */
int loom__db_brick_id(const loom_db *db, uint32_t k, uint32_t bx, uint32_t by,
                      uint32_t bz, uint32_t *id);

/* Inverse: exemplar and brick coordinates of a global id.  LOOM_ERANGE. */
int loom__db_brick_coords(const loom_db *db, uint32_t id, uint32_t *k,
                          uint32_t *bx, uint32_t *by, uint32_t *bz);

/* 1 if brick id is stored as nothing (all voxels empty), 0 otherwise
   (also for an id out of range). */
int loom__db_brick_empty(const loom_db *db, uint32_t id);

/* Bytes of scratch loom__db_read_brick needs (largest stored brick). */
size_t loom__db_scratch_bytes(const loom_db *db);

/* "db.ldb: brick 17 (exemplar 0 'twill-2-3', brick x=1 y=0 z=5)" */
void loom__db_brick_name(const loom_db *db, uint32_t id, char *buf, size_t n);

/*
 * Read brick id into out (brick_bytes, the four planes of voxel.h):
 * pread, CRC32 of the stored bytes, then decompress to exactly brick_bytes
 * (raw bricks are copied, empty bricks zero-filled).  dec is the caller's
 * libdeflate decompressor (one per thread); scratch holds
 * loom__db_scratch_bytes() bytes.  Returns LOOM_OK, LOOM_ERANGE (id),
 * LOOM_EIO, LOOM_ETRUNCATED (file shorter than the index says),
 * LOOM_ECORRUPT (CRC or decompressed size mismatch); the message names the
 * brick.  Thread-safe; *n_read (may be NULL) gets the bytes read.
 */
int loom__db_read_brick(const loom_db *db, uint32_t id,
                        struct libdeflate_decompressor *dec, uint8_t *scratch,
                        uint8_t *out, size_t *n_read, loom_diag *diag);

/*
 * Per-thread reader state, for callers that keep one per worker (the brick
 * cache's loader scratch): a libdeflate decompressor plus a scratch buffer
 * of loom__db_scratch_bytes().  loom__db_reader_bytes() is an upper bound
 * of the memory one reader holds, measured when the database was opened
 * (malloc_usable_size of a probe decompressor, plus the scratch and the
 * struct).  new returns NULL when out of memory; free accepts NULL.
 */
typedef struct loom__db_reader loom__db_reader;
loom__db_reader *loom__db_reader_new(const loom_db *db);
void loom__db_reader_free(loom__db_reader *r);
size_t loom__db_reader_bytes(const loom_db *db);
/* loom__db_read_brick with the reader's decompressor and scratch. */
int loom__db_reader_read(loom__db_reader *r, uint32_t id, uint8_t *out,
                         size_t *n_read, loom_diag *diag);

/*
 * Read plane unit u (0 density, 1 and 2 orientation low and high byte,
 * 3 label) of brick id into out (brick_voxels bytes).  Layout 2 reads and
 * checks that unit only; layout 1 cannot (LOOM_EUNSUPPORTED: callers ask
 * loom__db_layout first).  Errors name the brick and the unit.
 */
int loom__db_reader_read_unit(loom__db_reader *r, uint32_t id, unsigned u,
                              uint8_t *out, size_t *n_read, loom_diag *diag);
/* voxel_layout of the database: LOOM__DB_LAYOUT_PLANES, _UNITS, _SEGS or
   _ZRUN. */
unsigned loom__db_layout(const loom_db *db);

/*
 * Segments of the density plane a reader can inflate one by one: 8 in
 * layout 3, 1 (the whole plane) in layouts 2 and 4, 0 in layout 1.
 */
unsigned loom__db_dsegs(const loom_db *db);

/*
 * Read segment q (0 .. loom__db_dsegs - 1) of brick id's density plane
 * into its place in plane (brick_voxels bytes): only the bytes of the
 * segment's rows are written (loom__db_seg_range), so threads may fill
 * different segments of one plane at once.  The whole unit is read and
 * its CRC checked (unless checked: a caller that has read another segment
 * of the same unit through this open database, whose file loom only ever
 * replaces by renaming, so its bytes cannot have changed); only segment q
 * is inflated.  The segment header is checked either way.  Errors as
 * read_unit's, naming the segment.
 */
int loom__db_reader_read_seg(loom__db_reader *r, uint32_t id, unsigned q,
                             uint8_t *plane, int checked, size_t *n_read,
                             loom_diag *diag);

/*
 * Rows per density segment when a plane of brick (bx, by, bz) is cut into
 * nseg segments (docs/formats.md, "Segmented density units"): segment q
 * holds rows [q R, min((q+1) R, by)), R = ceil(by / nseg).
 */
static inline uint32_t loom__db_seg_rows(const uint32_t brick[3], unsigned nseg)
{
	return (brick[1] + nseg - 1) / nseg;
}

/* Segment q's bytes [*lo, *lo + *len) in the plane (len 0 past by). */
static inline void loom__db_seg_range(const uint32_t brick[3], unsigned nseg, unsigned q,
                                      size_t *lo, size_t *len)
{
	uint32_t R = loom__db_seg_rows(brick, nseg), y0 = q * R, y1 = y0 + R;
	size_t row = (size_t)brick[0] * brick[2];

	if (y0 > brick[1])
		y0 = brick[1];
	if (y1 > brick[1])
		y1 = brick[1];
	*lo = y0 * row;
	*len = (y1 - y0) * row;
}

/* Yarn table of exemplar k for label lookups: 256 entries, labels beyond
   n_yarns are kind 0.  NULL if k is out of range. */
const loom_db_yarn *loom__db_yarn_lut(const loom_db *db, uint32_t k);

/* ---- surface rule (shared by writer and tests) ---------------------------- */

/*
 * solid[label] = 1 when a voxel with that label counts for the top surface
 * (a yarn, not a flyaway fibre).  Built from a yarn table of n_yarns + 1
 * rows.
 */
static inline void loom__db_solid_lut(const loom_db_yarn *yarns, uint32_t n_yarns,
                                      uint8_t solid[256])
{
	memset(solid, 0, 256);
	for (uint32_t l = 1; l <= n_yarns && l < 256; l++)
		solid[l] = yarns[l].kind != LOOM_YARN_NONE &&
		           !(yarns[l].flags & LOOM_DB_YARN_FLYAWAY);
}

/*
 * The zero-run code of a layout-4 density unit (engine/exemplar/zrun.c,
 * docs/formats.md).  encode: the code of in[0..n) at out; its length, or
 * 0 when it would not fit in cap bytes (the writer passes n - 1 and
 * stores the plane raw on 0).  Deterministic.  decode: m bytes at in to
 * exactly n bytes at out; 0, or 1 when the stream is malformed (a run
 * past n bytes or past the stream, or fewer than n bytes), with *where
 * (may be NULL) the offset of the token at fault or m.  Bytes of out past
 * the decoded ones may be written before they are decoded.
 */
size_t loom__zrun_encode(const uint8_t *in, size_t n, uint8_t *out, size_t cap);
int loom__zrun_decode(const uint8_t *in, size_t m, uint8_t *out, size_t n,
                      size_t *where);

#endif /* LOOM_DB_INTERNAL_H */
