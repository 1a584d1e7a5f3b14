/*
 * io/store/db_write.h - streaming writer of exemplar databases (.ldb).  Internal.
 *
 * Use:
 *   loom__dbw_create(path, params)            header written
 *   for each exemplar k:
 *     loom__dbw_begin_exemplar(desc)
 *     for each brick in id order (brick column by column: by, then bx,
 *       then bz fastest):
 *         loom__dbw_encode(...)  (thread-safe, any thread)
 *         loom__dbw_put(...)     (writer's thread, in order)
 *       or loom__dbw_add_brick(raw) to do both on the writer's thread
 *   loom__dbw_finish(&hash)                   tables, index, trailer, rename
 *   (loom__dbw_abort on any failure: the target is never touched)
 *
 * Memory: the index (24 B per brick), the exemplars' tables and, for the
 * exemplar being written, its top-surface height map (3 B per voxel
 * column).  Brick data goes straight to the file.
 */
#ifndef LOOM_DB_WRITE_H
#define LOOM_DB_WRITE_H

#include "exemplar/db_internal.h"

struct libdeflate_compressor;

typedef struct loom__dbw loom__dbw;

typedef struct loom__dbw_params {
	uint32_t n_exemplars;
	uint32_t block[3];      /* b1, b2, b3 */
	uint32_t brick[3];      /* brick shape */
	float voxel_size_um;
	uint8_t top_threshold;  /* density threshold of the top-surface rule */
	int level;              /* libdeflate level */
	uint64_t seed;
	uint32_t flags;         /* header flags (bit 0: procedural) */
	uint32_t layout;        /* voxel layout = format version: 0 or
	                           LOOM__DB_LAYOUT_ZRUN (4, the default),
	                           LOOM__DB_LAYOUT_UNITS (2) or _SEGS (3:
	                           asked for) or LOOM__DB_LAYOUT_PLANES (1:
	                           appending to an old file, tests) */
	uint32_t density_raw;   /* layouts 2..4: density units stored raw */
} loom__dbw_params;

/* With layout 2, 3 or 4 in loom__dbw_encode's layout: the density unit is
   stored raw (copied, never deflated; readers know a raw unit by its size,
   so the format does not change). */
#define LOOM__DBW_DENSITY_RAW 0x100u

typedef struct loom__dbw_exemplar {
	const char *name;        /* < 32 bytes */
	const char *weave_name;  /* < 32 bytes, may be "" */
	uint32_t rows, cols;
	const uint8_t *weave;    /* rows*cols, 1 = warp over */
	uint32_t n_yarns;        /* labels 1..n_yarns */
	const loom_db_yarn *yarns; /* n_yarns + 1 rows, row 0 empty */
	uint8_t fibre[2];        /* material pair tag (0 0: none) */
} loom__dbw_exemplar;

/* One encoded brick.  The caller provides top[] and top_label[] (bx*by
   entries each) before loom__dbw_encode fills them. */
typedef struct loom__dbw_brick {
	uint8_t storage;         /* LOOM__DB_STORE_* */
	uint32_t stored_bytes;
	uint32_t crc;            /* CRC32 of the stored bytes */
	const uint8_t *data;     /* stored bytes (cbuf or the raw brick) */
	uint32_t unit_bytes[4];  /* layouts 2..4: the planes' units in data, */
	uint32_t unit_crc[4];    /* back to back (0 bytes: an all-zero plane) */
	int16_t *top;            /* per column (ly*bx + lx): local z of the top
	                            solid voxel, -1 if none */
	uint8_t *top_label;      /* label of that voxel (0 if none) */
} loom__dbw_brick;

int loom__dbw_create(const char *path, const loom__dbw_params *p,
                     loom__dbw **out, loom_diag *diag);
int loom__dbw_begin_exemplar(loom__dbw *w, const loom__dbw_exemplar *e,
                             loom_diag *diag);

/*
 * Encode raw (four planes, voxel.h) for storage: all-zero -> empty;
 * layout 1: deflate at the compressor's level into cbuf (brick_bytes) if it
 * shrinks, else raw (data = raw); layout 2: each plane on its own into
 * cbuf (deflated if that shrinks it, else copied; an all-zero plane is 0
 * bytes), data = cbuf; layout 3: as 2 with the density plane's unit in
 * eight segments (docs/formats.md); layout 4: as 2 with the density
 * plane zero-run coded (loom__zrun_encode) if that shrinks it;
 * | LOOM__DBW_DENSITY_RAW: layout 2, 3 or 4 with the density unit raw.
 * Fills the top-surface columns with solid[] (loom__db_solid_lut) and
 * threshold.  Thread-safe given its own
 * compressor and buffers.
 */
void loom__dbw_encode(const uint8_t *raw, const uint32_t brick[3],
                      const uint8_t solid[256], uint8_t threshold,
                      unsigned layout, struct libdeflate_compressor *comp,
                      uint8_t *cbuf, loom__dbw_brick *out);
/* The voxel layout the writer writes (LOOM__DB_LAYOUT_*). */
unsigned loom__dbw_layout(const loom__dbw *w);

/*
 * Append to an existing database: opens and checks `path` (loom_db_open),
 * then starts a writer for the same path (temporary file, renamed by
 * loom__dbw_finish) announcing its exemplars plus n_new, with the same
 * geometry, voxel size, level and seed, and header flags minus clear_flags.
 * The old brick data are copied verbatim (every stored brick keeps its
 * offset), and so are the old exemplars' records, weaves, yarn tables,
 * symmetries, block tables and index entries; the caller then begins the
 * n_new exemplars as after loom__dbw_create.  *old (may be NULL) receives
 * the database's parameters (n_exemplars = old + n_new).  Memory: the old
 * metadata and a 1 MiB copy buffer.  Errors as loom_db_open, LOOM_EIO,
 * LOOM_ENOMEM, LOOM_EINVAL (more than 4096 exemplars in all).
 */
/* The parameters that write a database in the storage of the one with
   info and header bytes hdr: its block, brick, voxel size, threshold,
   level and flags (from hdr), seed, layout, and density_raw when every
   stored brick's density plane is raw; n_exemplars 0 (loom__dbw_append,
   loom_db_convert). */
void loom__dbw_params_like(const loom_db_info *info,
                           const uint8_t hdr[LOOM__DB_HEADER_BYTES], loom__dbw_params *p);

int loom__dbw_append(const char *path, uint32_t n_new, uint32_t clear_flags,
                     loom__dbw **out, loom__dbw_params *old, loom_diag *diag);

/* Append the next brick of the current exemplar. */
int loom__dbw_put(loom__dbw *w, const loom__dbw_brick *b, loom_diag *diag);

/* Encode with the writer's own compressor and put. */
int loom__dbw_add_brick(loom__dbw *w, const uint8_t *raw, loom_diag *diag);

/* Solid-label table of the current exemplar (for loom__dbw_encode). */
const uint8_t *loom__dbw_solid(const loom__dbw *w);

/* Write tables, index and trailer; rename into place; free w. */
int loom__dbw_finish(loom__dbw *w, uint64_t *hash, loom_diag *diag);

/* Discard everything; NULL is a no-op. */
void loom__dbw_abort(loom__dbw *w);

/* Translational symmetries of a rows x cols weave (periodic): pairs
   (dx, dy) in out (2 per entry, room for rows*cols entries); returns the
   count, (0, 0) first. */
uint32_t loom__weave_symmetries(const uint8_t *weave, uint32_t rows,
                                uint32_t cols, uint16_t *out);

/* Neighbourhood code (LOOM_DB_CODE_*) of block (r, c), wrapping. */
uint8_t loom__weave_code(const uint8_t *weave, uint32_t rows, uint32_t cols,
                         uint32_t r, uint32_t c);

#endif /* LOOM_DB_WRITE_H */
