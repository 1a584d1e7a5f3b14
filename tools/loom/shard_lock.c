/*
 * tools/loom/shard_lock.c - fcntl locks of the runs that write into an
 * export directory (shard_lock.h explains the roles of the bytes).
 */
#include "shard_lock.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#define SPLIT_END ((off_t)1 << 32)     /* split bytes: [1, 2^32) */
#define SHARD_BASE ((off_t)1 << 33)    /* shard I: 2^33 + I */
#define MERGE_AT ((off_t)1 << 34)

static int lock_at(int fd, int type, off_t start, off_t len)
{
	struct flock fl;

	memset(&fl, 0, sizeof fl);
	fl.l_type = (short)type;
	fl.l_whence = SEEK_SET;
	fl.l_start = start;
	fl.l_len = len;
	return fcntl(fd, F_SETLK, &fl);
}

/* Another process's lock on [start, start+len) that a write lock would
   meet: 1 with its first byte and pid, 0 none, -1 error. */
static int held_by_other(int fd, off_t start, off_t len, off_t *at, long *pid)
{
	struct flock fl;

	if (len <= 0)
		return 0;
	memset(&fl, 0, sizeof fl);
	fl.l_type = F_WRLCK;
	fl.l_whence = SEEK_SET;
	fl.l_start = start;
	fl.l_len = len;
	if (fcntl(fd, F_GETLK, &fl) != 0)
		return -1;
	if (fl.l_type == F_UNLCK)
		return 0;
	*at = fl.l_start;
	*pid = (long)fl.l_pid;
	return 1;
}

static void who(char *buf, size_t n, long pid)
{
	/* l_pid is 0 for a lock held on another NFS client */
	if (pid > 0)
		snprintf(buf, n, "process %ld", pid);
	else
		snprintf(buf, n, "a process on another host");
}

/* Open the lock file and take split n; check no other split runs. */
static int take_split(shard_lock *l, const char *dir, uint32_t n, char *msg, size_t msz)
{
	char path[4096], w[64];
	off_t at;
	long pid;
	int r;

	l->fd = -1;
	snprintf(path, sizeof path, "%s/%s", dir, SHARD_LOCK_NAME);
	l->fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
	if (l->fd < 0) {
		snprintf(msg, msz, "%.3000s: cannot open the lock file: %s", path, strerror(errno));
		return -1;
	}
	if (lock_at(l->fd, F_RDLCK, (off_t)n, 1) != 0) {
		snprintf(msg, msz, "%.3000s: cannot lock: %s", path, strerror(errno));
		shard_lock_release(l);
		return -1;
	}
	r = held_by_other(l->fd, 1, (off_t)n - 1, &at, &pid);
	if (r == 0)
		r = held_by_other(l->fd, (off_t)n + 1, SPLIT_END - (off_t)n - 1, &at, &pid);
	if (r != 0) {
		if (r < 0)
			snprintf(msg, msz, "%.3000s: cannot test the lock: %s", path, strerror(errno));
		else {
			who(w, sizeof w, pid);
			snprintf(msg, msz, "%.3000s is being written by a %s export (%s): runs of "
			         "another shard split write the same tiles; wait for it to end, or "
			         "use another -o DIR", dir, at == 1 ? "unsharded" : "differently "
			         "sharded", w);
		}
		shard_lock_release(l);
		return -1;
	}
	return 0;
}

int shard_lock_shard(shard_lock *l, const char *dir, uint32_t i, uint32_t n, char *msg,
                     size_t msz)
{
	char w[64];
	off_t at;
	long pid;

	if (take_split(l, dir, n, msg, msz) != 0)
		return -1;
	if (lock_at(l->fd, F_WRLCK, SHARD_BASE + (off_t)i, 1) != 0) {
		int e = errno;
		if (e == EAGAIN || e == EACCES) {
			pid = 0;
			held_by_other(l->fd, SHARD_BASE + (off_t)i, 1, &at, &pid);
			who(w, sizeof w, pid);
			if (n > 1)
				snprintf(msg, msz, "shard %u/%u of %.3000s is being written by another "
				         "run (%s): not starting a second one (it would only write the "
				         "same files)", i, n, dir, w);
			else
				snprintf(msg, msz, "%.3000s is being written by another run of this "
				         "export (%s): not starting a second one", dir, w);
		} else
			snprintf(msg, msz, "%.3000s: cannot lock: %s", dir, strerror(e));
		shard_lock_release(l);
		return -1;
	}
	return 0;
}

int shard_lock_merge(shard_lock *l, const char *dir, uint32_t n, char *msg, size_t msz)
{
	char w[64];
	off_t at;
	long pid;
	int r;

	if (take_split(l, dir, n, msg, msz) != 0)
		return -1;
	r = held_by_other(l->fd, SHARD_BASE, (off_t)n, &at, &pid);
	if (r > 0) {
		who(w, sizeof w, pid);
		snprintf(msg, msz, "shard %lld/%u of %.3000s is still running (%s): merge when "
		         "it has ended", (long long)(at - SHARD_BASE), n, dir, w);
		shard_lock_release(l);
		return -1;
	}
	if (r < 0 || lock_at(l->fd, F_WRLCK, MERGE_AT, 1) != 0) {
		if (r == 0 && (errno == EAGAIN || errno == EACCES))
			snprintf(msg, msz, "another merge of %.3000s is running", dir);
		else
			snprintf(msg, msz, "%.3000s: cannot lock: %s", dir, strerror(errno));
		shard_lock_release(l);
		return -1;
	}
	return 0;
}

void shard_lock_release(shard_lock *l)
{
	if (l && l->fd >= 0) {
		close(l->fd);
		l->fd = -1;
	}
}

int shard_lock_running(const char *dir, uint32_t n, uint8_t *running)
{
	char path[4096];
	off_t start = SHARD_BASE, end = SHARD_BASE + (off_t)n, at;
	long pid;
	int fd;

	memset(running, 0, n);
	snprintf(path, sizeof path, "%s/%s", dir, SHARD_LOCK_NAME);
	fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return -1;
	while (start < end && held_by_other(fd, start, end - start, &at, &pid) == 1) {
		if (at < start || at >= end)
			break;
		running[at - SHARD_BASE] = 1;
		start = at + 1;
	}
	close(fd);
	return 0;
}
