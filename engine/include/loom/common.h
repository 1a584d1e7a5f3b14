/*
 * loom/common.h - result codes, diagnostics and export macros shared by every
 * loom module.  Include <loom.h>, not this file.
 *
 * Conventions (see docs/api.md):
 *  - Every fallible function returns an int result code: LOOM_OK (0) on
 *    success, one of the LOOM_E* values below on failure.  loom_strerror()
 *    accepts any integer.
 *  - Functions that parse or open outside data take an optional loom_diag*:
 *    on failure its message holds the detail ("file:line: what was
 *    expected"); warnings go to its callback (or are dropped if none).
 *  - Handles are opaque and closed with a NULL-safe *_close / *_free.
 */
#ifndef LOOM_COMMON_H
#define LOOM_COMMON_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(LOOM_BUILDING) && defined(__GNUC__)
#define LOOM_API __attribute__((visibility("default")))
#else
#define LOOM_API
#endif

#define LOOM_VERSION_MAJOR 0
#define LOOM_VERSION_MINOR 1
#define LOOM_VERSION_PATCH 0
#define LOOM_VERSION_STRING "0.1.0"

/* Result codes.  Values are stable: they are part of the ABI. */
enum loom_result {
	LOOM_OK = 0,
	LOOM_EINVAL = 1,       /* invalid argument (NULL, out of range) */
	LOOM_ENOMEM = 2,       /* allocation failed */
	LOOM_EIO = 3,          /* read/write/open failed (see errno text) */
	LOOM_EFORMAT = 4,      /* input is malformed */
	LOOM_EVERSION = 5,     /* unsupported file version */
	LOOM_ETRUNCATED = 6,   /* input ends early */
	LOOM_ECORRUPT = 7,     /* checksum or size mismatch */
	LOOM_ERANGE = 8,       /* index or size out of range / too large */
	LOOM_EBUDGET = 9,      /* memory budget too small or exhausted */
	LOOM_EMISMATCH = 10,   /* files do not belong together */
	LOOM_EUNSUPPORTED = 11,/* valid input loom cannot handle */
	LOOM_EUNUSABLE = 12,   /* handle hit an earlier fatal error */
	LOOM_ENOTFOUND = 13,   /* named item does not exist */
	LOOM_RESULT_COUNT_
};

/* Short English text for a result code; never NULL, any int accepted. */
LOOM_API const char *loom_strerror(int code);

/* Library version string, e.g. "0.1.0". */
LOOM_API const char *loom_version(void);

#define LOOM_DIAG_MSG_MAX 512

/*
 * Diagnostics sink passed to parsers and writers.  Zero-initialise it
 * (loom_diag d = {0};).  On failure `message` holds a NUL-terminated
 * description; `warn`, if set, receives each warning as it is found.
 */
typedef struct loom_diag {
	char message[LOOM_DIAG_MSG_MAX]; /* detail of the last error */
	void (*warn)(void *user, const char *msg); /* optional warning sink */
	void *user;                      /* passed to warn */
	unsigned n_warnings;             /* warnings reported so far */
} loom_diag;

#ifdef __cplusplus
}
#endif
#endif /* LOOM_COMMON_H */
