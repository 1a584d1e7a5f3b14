/*
 * io/volume/nrrd.h - NRRD (teem) volume writer.  Internal.
 *
 * Writes NRRD0004 with raw encoding, either attached (header, blank line,
 * data in one file) or detached (header in PATH, data in PATH with its
 * extension replaced by ".raw", named in the header's "data file" field).
 * Data is streamed: loom__nrrd_begin, any number of loom__nrrd_write calls
 * (fastest axis first, exactly the product of the sizes in elements),
 * loom__nrrd_finish.  Both files are written atomically.  Multi-byte
 * samples are written little-endian ("endian: little") on any host.
 *
 * NRRD reading, when it is added, lives in its own file.
 */
#ifndef LOOM_NRRD_H
#define LOOM_NRRD_H

#include "core/internal.h"
#include "io/core/file.h"

enum loom__nrrd_type {
	LOOM__NRRD_UINT8 = 0,
	LOOM__NRRD_UINT16,
	LOOM__NRRD_FLOAT
};

typedef struct loom__nrrd_desc {
	int type;              /* enum loom__nrrd_type */
	uint32_t components;   /* 1: scalar; 3: a 3-vector axis comes first */
	uint64_t sizes[3];     /* spatial axes, fastest first (x, y, z) */
	double spacing[3];     /* sample spacing along each spatial axis */
	double origin[3];      /* position of the first sample's centre */
	const char *units;     /* unit of spacing/origin ("mm"), or NULL */
	const char *content;   /* "content:" text (one line), or NULL */
} loom__nrrd_desc;

typedef struct loom__nrrd_w {
	loom__atomic hdr;      /* the header file (also the data if attached) */
	loom__atomic data;     /* detached data file */
	int detached;
	size_t elem_bytes;     /* bytes per sample */
	uint64_t expected;     /* bytes of data announced */
	uint64_t written;
} loom__nrrd_w;

int loom__nrrd_begin(loom__nrrd_w *w, const char *path, int detached,
                     const loom__nrrd_desc *d, loom_diag *diag);
/* Append n samples (n * elem_bytes bytes, host byte order). */
int loom__nrrd_write(loom__nrrd_w *w, const void *samples, size_t n,
                     loom_diag *diag);
/* Check the amount written, commit both files. */
int loom__nrrd_finish(loom__nrrd_w *w, loom_diag *diag);
void loom__nrrd_abort(loom__nrrd_w *w);

#endif /* LOOM_NRRD_H */
