/* tools/loom/paintfile.h - paint files for the commands (cmd_paint.c):
   read with the checks of every loom format, and a fabric-or-paint opener
   for the commands that honour paint (render, preview, export, serve:
   every region; others, e.g. scan: the painted weaves). */
#ifndef LOOM_PAINTFILE_H
#define LOOM_PAINTFILE_H

#include "loom.h"

/* 1 when path is a regular file starting with the paint magic. */
int cli_is_paint(const char *path);
/* Read and parse a paint file: a regular file of at most
   LOOM_PAINT_MAX_FILE bytes.  LOOM_OK or an error with the path in diag. */
int cli_paint_read(const char *path, loom_paint **out, loom_diag *diag);
/* Open path as a fabric, or as a paint file and its fabric (*paint set,
   else NULL).  LOOM_OK or an error with diag. */
/* The note of a command that shows only the painted weaves (scan): the
   other regions, if any, named on stderr. */
void cli_paint_note(const char *prog, const char *path, const loom_paint *p);
/* Write text to path atomically (a temporary name in the same directory,
   then rename).  LOOM_OK, or LOOM_EIO / LOOM_EINVAL with the path in d. */
int cli_write_atomic(const char *path, const char *text, size_t len, loom_diag *d);
int cli_open_painted(const char *path, loom_db *db, loom_fabric **f,
                     loom_paint **paint, loom_diag *diag);

#endif
