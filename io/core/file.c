/* io/core/file.c - whole-file reads and atomic output files (file.h). */
#include "file.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int loom__read_file(const char *path, size_t max_bytes, uint8_t **data,
                    size_t *len, loom_diag *diag)
{
	FILE *fp;
	uint8_t *buf = NULL;
	size_t cap = 0, n = 0;

	*data = NULL;
	*len = 0;
	fp = fopen(path, "rb");
	if (!fp)
		return loom__fail(diag, LOOM_EIO, "%s: cannot open: %s", path,
		                  strerror(errno));
	for (;;) {
		size_t got;
		if (n == cap) {
			size_t ncap = cap ? cap * 2 : 65536;
			uint8_t *nb;
			if (cap >= max_bytes + 1) {
				free(buf);
				fclose(fp);
				return loom__fail(diag, LOOM_ERANGE,
				                  "%s: file larger than %zu bytes",
				                  path, max_bytes);
			}
			nb = realloc(buf, ncap + 1);
			if (!nb) {
				free(buf);
				fclose(fp);
				return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
			}
			buf = nb;
			cap = ncap;
		}
		got = fread(buf + n, 1, cap - n, fp);
		n += got;
		if (got == 0)
			break;
	}
	if (ferror(fp)) {
		int e = errno;
		free(buf);
		fclose(fp);
		return loom__fail(diag, LOOM_EIO, "%s: read error: %s", path, strerror(e));
	}
	fclose(fp);
	if (n > max_bytes) {
		free(buf);
		return loom__fail(diag, LOOM_ERANGE, "%s: file larger than %zu bytes",
		                  path, max_bytes);
	}
	if (!buf) {
		buf = malloc(1);
		if (!buf)
			return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	buf[n] = 0;
	*data = buf;
	*len = n;
	return LOOM_OK;
}

int loom__atomic_open(loom__atomic *a, const char *path, loom_diag *diag)
{
	static unsigned counter;
	size_t n = strlen(path) + 48;

	memset(a, 0, sizeof *a);
	a->tmp_path = malloc(n);
	a->path = malloc(strlen(path) + 1);
	if (!a->tmp_path || !a->path) {
		free(a->tmp_path);
		free(a->path);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	strcpy(a->path, path);
	snprintf(a->tmp_path, n, "%s.tmp.%ld.%u", path, (long)getpid(),
	         __atomic_fetch_add(&counter, 1, __ATOMIC_RELAXED));
	a->fp = fopen(a->tmp_path, "wb");
	if (!a->fp) {
		int e = errno;
		free(a->tmp_path);
		free(a->path);
		memset(a, 0, sizeof *a);
		return loom__fail(diag, LOOM_EIO, "%s: cannot create: %s", path,
		                  strerror(e));
	}
	return LOOM_OK;
}

int loom__atomic_commit(loom__atomic *a, loom_diag *diag)
{
	int bad = 0, e = 0;

	if (!a->fp)
		return loom__fail(diag, LOOM_EINVAL, "atomic write not open");
	if (fflush(a->fp) != 0 || ferror(a->fp)) {
		bad = 1;
		e = errno;
	}
	if (!bad && fsync(fileno(a->fp)) != 0 && errno != EINVAL) {
		bad = 1;
		e = errno;
	}
	if (fclose(a->fp) != 0 && !bad) {
		bad = 1;
		e = errno;
	}
	a->fp = NULL;
	if (!bad && rename(a->tmp_path, a->path) != 0) {
		bad = 1;
		e = errno;
	}
	if (bad) {
		unlink(a->tmp_path);
		loom__fail(diag, LOOM_EIO, "%s: write failed: %s", a->path, strerror(e));
	}
	free(a->tmp_path);
	free(a->path);
	a->tmp_path = a->path = NULL;
	return bad ? LOOM_EIO : LOOM_OK;
}

void loom__atomic_abort(loom__atomic *a)
{
	if (a->fp) {
		fclose(a->fp);
		a->fp = NULL;
	}
	if (a->tmp_path)
		unlink(a->tmp_path);
	free(a->tmp_path);
	free(a->path);
	a->tmp_path = a->path = NULL;
}
