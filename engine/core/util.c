/* engine/core/util.c - result codes, diagnostics, string and colour helpers.
   (Reading and atomically writing files is io/core/file.c.) */
#include "internal.h"

#include <ctype.h>
#include <math.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *const result_text[LOOM_RESULT_COUNT_] = {
	[LOOM_OK] = "success",
	[LOOM_EINVAL] = "invalid argument",
	[LOOM_ENOMEM] = "out of memory",
	[LOOM_EIO] = "input/output error",
	[LOOM_EFORMAT] = "malformed input",
	[LOOM_EVERSION] = "unsupported version",
	[LOOM_ETRUNCATED] = "input truncated",
	[LOOM_ECORRUPT] = "data corrupted (checksum or size mismatch)",
	[LOOM_ERANGE] = "value out of range",
	[LOOM_EBUDGET] = "memory budget too small",
	[LOOM_EMISMATCH] = "files do not belong together",
	[LOOM_EUNSUPPORTED] = "unsupported",
	[LOOM_EUNUSABLE] = "handle unusable after an earlier error",
	[LOOM_ENOTFOUND] = "not found",
};

LOOM_API const char *loom_strerror(int code)
{
	if (code < 0 || code >= LOOM_RESULT_COUNT_)
		return "unknown error";
	return result_text[code];
}

LOOM_API const char *loom_version(void)
{
	return LOOM_VERSION_STRING;
}

int loom__fail(loom_diag *diag, int code, const char *fmt, ...)
{
	if (diag) {
		va_list ap;
		va_start(ap, fmt);
		vsnprintf(diag->message, sizeof diag->message, fmt, ap);
		va_end(ap);
	}
	return code;
}

void loom__warn(loom_diag *diag, const char *fmt, ...)
{
	char buf[LOOM_DIAG_MSG_MAX];
	va_list ap;

	if (!diag)
		return;
	diag->n_warnings++;
	if (!diag->warn)
		return;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof buf, fmt, ap);
	va_end(ap);
	diag->warn(diag->user, buf);
}

int loom__strieq(const char *a, const char *b)
{
	while (*a && *b) {
		if (tolower((unsigned char)*a) != tolower((unsigned char)*b))
			return 0;
		a++;
		b++;
	}
	return *a == *b;
}

int loom__strnieq(const char *a, const char *b, size_t n)
{
	for (size_t i = 0; i < n; i++) {
		if (tolower((unsigned char)a[i]) != tolower((unsigned char)b[i]))
			return 0;
		if (!a[i])
			return 1;
	}
	return 1;
}

float loom__srgb_to_linear(double c)
{
	return (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
}
