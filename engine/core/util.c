/* engine/core/util.c - result codes, diagnostics, string and colour helpers.
   (Reading and atomically writing files is io/core/file.c.) */
#include "internal.h"

#include <ctype.h>
#include <math.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
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

static const char *file_kind(mode_t m)
{
	if (S_ISDIR(m))
		return "a directory";
	if (S_ISFIFO(m))
		return "a FIFO";
	if (S_ISCHR(m))
		return "a character device";
	if (S_ISBLK(m))
		return "a block device";
	if (S_ISSOCK(m))
		return "a socket";
	return "not a file";
}

int loom__open_input(const char *path, int *fd, uint64_t *size, loom_diag *diag)
{
	struct stat st;
	int f, fl, e;

	*fd = -1;
	*size = 0;
	/* O_NONBLOCK: opening a FIFO without a writer (or a serial device)
	   returns at once instead of waiting forever */
	do
		f = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
	while (f < 0 && errno == EINTR);
	if (f < 0)
		return loom__fail(diag, LOOM_EIO, "%s: cannot open: %s", path,
		                  strerror(errno));
	if (fstat(f, &st) != 0) {
		e = errno;
		close(f);
		return loom__fail(diag, LOOM_EIO, "%s: cannot stat: %s", path,
		                  strerror(e));
	}
	if (!S_ISREG(st.st_mode)) {
		close(f);
		return loom__fail(diag, LOOM_EIO, "%s: not a regular file (%s)", path,
		                  file_kind(st.st_mode));
	}
	fl = fcntl(f, F_GETFL);
	if (fl < 0 || fcntl(f, F_SETFL, fl & ~O_NONBLOCK) != 0) {
		e = errno;
		close(f);
		return loom__fail(diag, LOOM_EIO, "%s: cannot open: %s", path,
		                  strerror(e));
	}
	*fd = f;
	*size = st.st_size > 0 ? (uint64_t)st.st_size : 0;
	return LOOM_OK;
}

int loom__check_input_size(const char *path, uint64_t size, uint64_t limit,
                           const char *kind, loom_diag *diag)
{
	const char *env = getenv("LOOM_MAX_INPUT_BYTES");

	if (env && *env) {
		char *end;
		unsigned long long v;
		errno = 0;
		v = strtoull(env, &end, 10);
		if (!errno && *end == 0 && env[0] != '-')
			limit = v;
	}
	if (size > limit)
		return loom__fail(diag, LOOM_ERANGE, "%s: %llu bytes, more than the "
		                  "limit of %llu bytes for %s files (LOOM_MAX_INPUT_BYTES "
		                  "raises it)", path, (unsigned long long)size,
		                  (unsigned long long)limit, kind);
	return LOOM_OK;
}

const char *loom__size_text(char *buf, size_t n, double bytes)
{
	if (bytes < 1048576.0)
		snprintf(buf, n, "%.0f bytes", bytes < 0 ? 0 : bytes);
	else
		snprintf(buf, n, "%.1f MiB", bytes / 1048576.0);
	return buf;
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
