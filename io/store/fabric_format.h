/*
 * io/store/fabric_format.h - constants and little-endian helpers shared by
 * the fabric file writer (fabric_write.c) and reader (fabric_read.c), and
 * their entry points.  Internal to io/store.  The format byte by byte:
 * docs/formats.md, "Fabric file"; the layout and the reader's steps:
 * fabric_read.c.
 */
#ifndef LOOM_FABRIC_FORMAT_H
#define LOOM_FABRIC_FORMAT_H

#include "synth/fabric_internal.h"

#include <string.h>

#define FAB_MAGIC "\x89LFB\r\n\x1a\n"
#define FAB_TRAILER_MAGIC "LFBTRAIL"
#define FAB_VERSION 1u
#define FAB_HEADER_BYTES 64u
#define FAB_TRAILER_BYTES 32u
#define FAB_SECTION_BYTES 32u
#define FAB_N_SECTIONS 8u
#define FAB_CHUNK (1u << 20)
#define FAB_ENC_RAW 0u
#define FAB_ENC_CHUNKED 1u
#define FAB_CHUNK_DEFLATE 0u
#define FAB_CHUNK_STORED 1u
#define FAB_PARM_BYTES 96u
#define FAB_MAX_PATH 4096u
#define FAB_YARN_BYTES 52u
#define FAB_EDGE_HEADER 32u
#define FAB_METR_FIXED 240u
#define FAB_LEVEL 6
#define FAB_MAX_RATIO 1100u /* > DEFLATE's 1032:1 */

enum { S_PARM, S_YARN, S_WEAV, S_WARP, S_WEFT, S_BASE, S_EDGE, S_METR };
static const char fab_tags[FAB_N_SECTIONS][5] __attribute__((unused)) = {"PARM", "YARN", "WEAV", "WARP",
                                                 "WEFT", "BASE", "EDGE", "METR"};

/* Type-map modes. */
enum { MAP_FULL = 0, MAP_COLUMNS = 1, MAP_ROWS = 2, MAP_CONST = 3 };

/* ---- little-endian helpers ------------------------------------------------ */

static inline uint32_t get32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
	       (uint32_t)p[3] << 24;
}
static inline uint64_t get64(const uint8_t *p)
{
	return (uint64_t)get32(p) | (uint64_t)get32(p + 4) << 32;
}
static inline float getf(const uint8_t *p)
{
	uint32_t u = get32(p);
	float f;
	memcpy(&f, &u, 4);
	return f;
}
static inline double getd(const uint8_t *p)
{
	uint64_t u = get64(p);
	double d;
	memcpy(&d, &u, 8);
	return d;
}
static inline void put32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}
static inline void put64(uint8_t *p, uint64_t v)
{
	put32(p, (uint32_t)v);
	put32(p + 4, (uint32_t)(v >> 32));
}
static inline void putf(uint8_t *p, float f)
{
	uint32_t u;
	memcpy(&u, &f, 4);
	put32(p, u);
}
static inline void putd(uint8_t *p, double d)
{
	uint64_t u;
	memcpy(&u, &d, 8);
	put64(p, u);
}

/* Payload bytes of a type map stored in mode (MAP_*). */
static inline uint64_t map_data_bytes(uint32_t mode, uint32_t rows, uint32_t cols)
{
	switch (mode) {
	case MAP_FULL: return (uint64_t)rows * cols;
	case MAP_COLUMNS: return cols;
	case MAP_ROWS: return rows;
	default: return 1;
	}
}

/* Write the file (fabric_write.c). */
int loom__fabric_write(const loom_fabric *f, const char *path,
                       uint64_t *bytes, loom_diag *diag);

/* Parse a fabric file into a detached fabric, from a path (mem NULL) or
   from memory (mem, len; path used in messages only) (fabric_read.c). */
/* Step 1 only: the design size from the 64-byte header (magic, version,
   CRC, sizes checked), nothing else read (loom_fabric_file_size). */
int loom__fabric_read_size(const char *path, uint32_t *rows, uint32_t *cols,
                           loom_diag *diag);

int loom__fabric_read(const char *path, const uint8_t *mem, size_t len,
                      loom_fabric **out, loom_diag *diag);

#endif /* LOOM_FABRIC_FORMAT_H */
