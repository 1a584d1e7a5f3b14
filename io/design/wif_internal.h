/*
 * io/design/wif_internal.h - internal entry points of the WIF reader (io/design/wif.c),
 * for the fuzz target and the tests; never installed.
 */
#ifndef LOOM_WIF_INTERNAL_H
#define LOOM_WIF_INTERNAL_H

#include "core/internal.h"

/* Largest WIF file loom_wif_read accepts. */
#define LOOM__WIF_MAX_FILE_BYTES ((size_t)512 << 20)

/*
 * loom_wif_parse with a caller-chosen cap on picks x ends (loom_wif_parse
 * uses LOOM_DESIGN_MAX_CELLS).  The fuzz target passes a small cap so that a
 * few bytes cannot make it allocate gigabytes.  Same results and messages.
 */
int loom__wif_parse_limited(const char *text, size_t len, const char *name,
                            uint64_t max_cells, loom_design **out,
                            loom_diag *diag);

#endif
