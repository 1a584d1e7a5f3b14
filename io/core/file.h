/*
 * io/core/file.h - whole-file reads and atomic output files, for the
 * format readers and writers under io/.  Internal; the engine opens no
 * files (docs/architecture.md).
 */
#ifndef LOOM_IO_FILE_H
#define LOOM_IO_FILE_H

#include "core/internal.h"

#include <stdio.h>

/* Read a whole file into a malloc'ed buffer (NUL-terminated for
   convenience; *len excludes the NUL).  max_bytes guards against absurd
   inputs.  Errors name the path. */
int loom__read_file(const char *path, size_t max_bytes, uint8_t **data,
                    size_t *len, loom_diag *diag);

/*
 * Atomic output: loom__atomic_open creates "<path>.tmp.<pid>.<n>" in the
 * target's directory; loom__atomic_commit flushes, fsyncs, closes and
 * renames it over path; loom__atomic_abort closes and unlinks it.  The
 * target is untouched until commit succeeds.
 */
typedef struct loom__atomic {
	FILE *fp;
	char *tmp_path;
	char *path;
} loom__atomic;
int loom__atomic_open(loom__atomic *a, const char *path, loom_diag *diag);
int loom__atomic_commit(loom__atomic *a, loom_diag *diag);
void loom__atomic_abort(loom__atomic *a);

#endif /* LOOM_IO_FILE_H */
