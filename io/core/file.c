/* io/core/file.c - whole-file reads and atomic output files (file.h). */
#include "file.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

/* read exactly n bytes at the current position; LOOM_OK or an error */
static int read_full(int fd, uint8_t *buf, size_t n, const char *path,
                     loom_diag *diag)
{
	while (n > 0) {
		ssize_t got = read(fd, buf, n);
		if (got < 0 && errno == EINTR)
			continue;
		if (got < 0)
			return loom__fail(diag, LOOM_EIO, "%s: read error: %s", path,
			                  strerror(errno));
		if (got == 0)
			return loom__fail(diag, LOOM_ETRUNCATED, "%s: the file shrank "
			                  "while it was read", path);
		buf += got;
		n -= (size_t)got;
	}
	return LOOM_OK;
}

int loom__read_file_checked(const char *path, size_t max_bytes,
                            const char *kind, loom__head_check check,
                            uint8_t **data, size_t *len, loom_diag *diag)
{
	uint8_t *buf;
	uint64_t size;
	size_t head;
	int fd, rc;

	*data = NULL;
	*len = 0;
	rc = loom__open_input(path, &fd, &size, diag);
	if (rc)
		return rc;
	/* the first bytes first: a file that does not even start right is
	   refused before its size matters or the rest is read */
	if (check) {
		uint8_t first[LOOM__HEAD_BYTES];
		head = size < sizeof first ? (size_t)size : sizeof first;
		rc = read_full(fd, first, head, path, diag);
		if (!rc)
			rc = check(first, head, path, diag);
		if (!rc && lseek(fd, 0, SEEK_SET) != 0)
			rc = loom__fail(diag, LOOM_EIO, "%s: cannot seek: %s", path,
			                strerror(errno));
		if (rc) {
			close(fd);
			return rc;
		}
	}
	rc = loom__check_input_size(path, size, max_bytes, kind ? kind : "such",
	                            diag);
	if (!rc && size >= SIZE_MAX)
		rc = loom__fail(diag, LOOM_ERANGE, "%s: file too large", path);
	if (rc) {
		close(fd);
		return rc;
	}
	/* never more than the size fstat gave plus the terminating NUL */
	buf = malloc((size_t)size + 1);
	if (!buf) {
		close(fd);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory (%llu bytes)",
		                  path, (unsigned long long)size);
	}
	rc = read_full(fd, buf, (size_t)size, path, diag);
	close(fd);
	if (rc) {
		free(buf);
		return rc;
	}
	buf[size] = 0;
	*data = buf;
	*len = (size_t)size;
	return LOOM_OK;
}

int loom__read_file(const char *path, size_t max_bytes, uint8_t **data,
                    size_t *len, loom_diag *diag)
{
	return loom__read_file_checked(path, max_bytes, NULL, NULL, data, len,
	                               diag);
}

int loom__head_text(const uint8_t *head, size_t n, const char *path,
                    loom_diag *diag)
{
	const uint8_t *z = memchr(head, 0, n);

	if (z)
		return loom__fail(diag, LOOM_EFORMAT, "%s: byte %zu is a NUL: not a "
		                  "text file", path, (size_t)(z - head));
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
	/* the lock says "my writer is alive" to loom__atomic_sweep (it goes
	   with the process, whatever kills it) */
	if (a->fp)
		(void)flock(fileno(a->fp), LOCK_EX | LOCK_NB);
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

/* "<pid>" or "<pid>.<n>", decimal digits: the pid, else 0 */
static long tmp_suffix_pid(const char *s)
{
	long pid = 0;
	int digits = 0;

	for (; *s >= '0' && *s <= '9'; s++, digits++) {
		if (pid > (long)INT_MAX / 10)
			return 0;
		pid = pid * 10 + (*s - '0');
	}
	if (!digits)
		return 0;
	if (*s == '.') {
		s++;
		if (!(*s >= '0' && *s <= '9'))
			return 0;
		while (*s >= '0' && *s <= '9')
			s++;
	}
	return *s ? 0 : pid;
}

int loom__atomic_sweep(const char *path)
{
	const char *slash = strrchr(path, '/');
	const char *base = slash ? slash + 1 : path;
	size_t blen = strlen(base), dlen = slash ? (size_t)(slash - path) : 0;
	char dir[PATH_MAX], cand[PATH_MAX];
	struct dirent *de;
	int removed = 0;
	DIR *dp;

	if (!blen || dlen + 1 >= sizeof dir)
		return 0;
	if (slash) {
		memcpy(dir, path, dlen ? dlen : 1);
		dir[dlen ? dlen : 1] = 0;
	} else {
		strcpy(dir, ".");
	}
	dp = opendir(dir);
	if (!dp)
		return 0;
	while ((de = readdir(dp)) != NULL) {
		const char *n = de->d_name;
		struct stat st;
		long pid;
		int fd, gone;

		if (strncmp(n, base, blen) != 0 || strncmp(n + blen, ".tmp.", 5) != 0)
			continue;
		pid = tmp_suffix_pid(n + blen + 5);
		/* a live pid (ours, or anyone's we may not signal) keeps it */
		if (pid <= 0 || pid == (long)getpid() ||
		    kill((pid_t)pid, 0) == 0 || errno != ESRCH)
			continue;
		if (snprintf(cand, sizeof cand, "%s/%s", dir, n) >= (int)sizeof cand)
			continue;
		/* and so does a writer's lock (one on another host sharing the
		   directory, whose pid means nothing here) */
		fd = open(cand, O_RDONLY | O_NONBLOCK | O_NOFOLLOW | O_CLOEXEC);
		if (fd < 0)
			continue;
		gone = fstat(fd, &st) == 0 && S_ISREG(st.st_mode) &&
		       flock(fd, LOCK_EX | LOCK_NB) == 0;
		if (gone && unlink(cand) == 0)
			removed++;
		close(fd);
	}
	closedir(dp);
	return removed;
}
