/*
 * engine/core/internal.h - helpers shared inside libloom; never installed.
 * Internal symbols use the loom__ prefix (double underscore) and hidden
 * visibility, so the shared library exports only the public loom_ API.
 */
#ifndef LOOM_INTERNAL_H
#define LOOM_INTERNAL_H

#include "loom.h"

#include <stdarg.h>
#include <stdio.h>

#if defined(__GNUC__)
#define LOOM_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define LOOM_PRINTF(a, b)
#endif

/* Record an error message in diag (may be NULL) and return code. */
int loom__fail(loom_diag *diag, int code, const char *fmt, ...) LOOM_PRINTF(3, 4);
/* Report a warning through diag->warn (if any) and count it. */
void loom__warn(loom_diag *diag, const char *fmt, ...) LOOM_PRINTF(2, 3);

/*
 * Open path read-only for a reader, safely: the open never blocks
 * (O_NONBLOCK, cleared once the descriptor is known to be a regular file),
 * anything but a regular file (FIFO, device, directory, socket) is refused
 * with "PATH: not a regular file (a FIFO)" and the like, and *size is the
 * size fstat reports.  LOOM_OK with *fd open (close it), else an error
 * naming the path.  Every reader of loom opens its inputs through this.
 */
int loom__open_input(const char *path, int *fd, uint64_t *size, loom_diag *diag);
/*
 * Refuse an input of size bytes above the reader's limit (bytes; the
 * environment variable LOOM_MAX_INPUT_BYTES, a byte count, replaces every
 * such limit): LOOM_ERANGE "PATH: N bytes, more than the limit of M bytes
 * for KIND files".  Readers call it before allocating anything.
 */
int loom__check_input_size(const char *path, uint64_t size, uint64_t limit,
                           const char *kind, loom_diag *diag);

/* A memory size for messages into buf (n >= 32): "12.3 MiB", or "10485
   bytes" below 1 MiB, where a MiB figure would read 0.0.  Returns buf. */
const char *loom__size_text(char *buf, size_t n, double bytes);

/* sRGB-encoded component c in [0,1] to linear (IEC 61966-2-1).  Colours
   users type (#RRGGBB, WIF colour tables) are sRGB; albedo is linear. */
/*
 * Edge-fix tables of the shape of t (block, blocks, ranks; t's arrays are
 * not read) with uninitialised arrays, for a reader that fills them in
 * place: arrays[0..6] receive coef, field_h, field_v, basis_h, basis_v,
 * mean_h, mean_v (sizes as in loom_edgefix_tables).  LOOM_EINVAL for a shape
 * out of range, LOOM_ENOMEM.  Free with loom_edgefix_free.
 */
struct loom_edgefix_tables;
struct loom_edgefix;
int loom__edgefix_alloc(const struct loom_edgefix_tables *t, struct loom_edgefix **out,
                        float *arrays[7], loom_diag *diag);
/* After the arrays are filled (whole): find where the fields are exactly 0
   (the ranks each row and column stores and sums) and compact them
   (loom_edgefix_tables; edgefix.c). */
void loom__edgefix_finish(struct loom_edgefix *ef);
/* The offsets along one side of a block whose sources are nb (side 0: row
   0, b1 values; 1: row b2-1; 2: column 0, b2 values; 3: column b1-1), as
   loom_edgefix_at gives them one by one (edgefix.c). */
struct loom_synth_nbhd;
void loom__edgefix_side(const struct loom_edgefix *ef, const struct loom_synth_nbhd *nb,
                        int side, float *out);

float loom__srgb_to_linear(double c);

/* Case-insensitive ASCII string compare helpers. */
int loom__strieq(const char *a, const char *b);
int loom__strnieq(const char *a, const char *b, size_t n);

/* Overflow-checked size multiply: returns 0 on overflow. */
static inline int loom__mul_ok(size_t a, size_t b, size_t *out)
{
	if (a != 0 && b > (size_t)-1 / a)
		return 0;
	*out = a * b;
	return 1;
}

#endif /* LOOM_INTERNAL_H */
