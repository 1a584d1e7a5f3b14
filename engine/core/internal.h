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
