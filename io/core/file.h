/*
 * io/core/file.h - whole-file reads and atomic output files, for the
 * format readers and writers under io/.  Internal; the engine opens no
 * files (docs/architecture.md).
 */
#ifndef LOOM_IO_FILE_H
#define LOOM_IO_FILE_H

#include "core/internal.h"

#include <stdio.h>

/*
 * Read a whole file into a malloc'ed buffer (NUL-terminated for
 * convenience; *len excludes the NUL).  The file is opened with
 * loom__open_input (never blocks, regular files only); check, if not NULL,
 * sees the first min(size, LOOM__HEAD_BYTES) bytes and refuses a file that
 * does not start as its format must (an error naming path), before the
 * size is compared with max_bytes (loom__check_input_size; kind names the
 * format in the message) and before anything is allocated; the buffer is
 * the file's size plus one.  Errors name the path.
 */
#define LOOM__HEAD_BYTES 512
typedef int (*loom__head_check)(const uint8_t *head, size_t n,
                                const char *path, loom_diag *diag);
int loom__read_file_checked(const char *path, size_t max_bytes,
                            const char *kind, loom__head_check check,
                            uint8_t **data, size_t *len, loom_diag *diag);
int loom__read_file(const char *path, size_t max_bytes, uint8_t **data,
                    size_t *len, loom_diag *diag);
/* A head check for text formats (WIF, OBJ, mapping files): no NUL byte. */
int loom__head_text(const uint8_t *head, size_t n, const char *path,
                    loom_diag *diag);

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
/*
 * Remove the temporaries a dead writer left for path: the regular files
 * "<path>.tmp.<pid>.<n>" (loom__atomic_open) and "<path>.tmp.<pid>" (the
 * CLI's own temporaries) whose pid is no live process here and that no
 * process holds a lock on (loom__atomic_open locks its temporary, so a
 * writer on another host sharing the directory keeps its file).  Nothing
 * else is touched.  Returns how many were removed.  Commands call it
 * through cli_check_output before their work.
 */
int loom__atomic_sweep(const char *path);
int loom__atomic_commit(loom__atomic *a, loom_diag *diag);
void loom__atomic_abort(loom__atomic *a);

#endif /* LOOM_IO_FILE_H */
