/*
 * tests/unit/tmpdir.h - a unit test program's scratch directory: made as
 * PROGRAM.XXXXXX under $LOOM_TEST_TMP (tests/run.sh sets it; /tmp
 * otherwise), paths in it, whole-file reads and writes, and its removal as the
 * program's last test (kept, with a line saying where, when a test
 * failed, so the files can be looked at).
 */
#ifndef LOOM_TEST_TMPDIR_H
#define LOOM_TEST_TMPDIR_H

#include "check.h"

#include <dirent.h>
#include <errno.h>
#include <ftw.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[4096];

/* Make the directory of this program (check_prog): 0, or 1 after a
   failed check saying why (tmpdir then ""). */
static inline int tmpdir_make(void)
{
	const char *base = getenv("LOOM_TEST_TMP");

	snprintf(tmpdir, sizeof tmpdir, "%s/%s.XXXXXX", base ? base : "/tmp", check_prog);
	if (!mkdtemp(tmpdir)) {
		printf("  cannot create a directory %s/%s.XXXXXX: %s\n", base ? base : "/tmp",
		       check_prog, strerror(errno));
		check_fail_count++;
		tmpdir[0] = 0;
		return 1;
	}
	return 0;
}

/* The same as a test of its own, for main: RUN(tmpdir_setup), then stop
   if tmpdir is "". */
static inline void tmpdir_setup(void)
{
	tmpdir_make();
}

/* tmpdir/name, in one of 8 buffers used in turn (a call may take up to 8
   paths at once). */
static inline const char *tpath(const char *name)
{
	static char buf[8][4200];
	static int slot;
	char *p = buf[slot++ & 7];

	snprintf(p, sizeof buf[0], "%s/%s", tmpdir, name);
	return p;
}

static inline int file_exists(const char *p)
{
	struct stat st;
	return stat(p, &st) == 0;
}

/* Files in tmpdir whose name has ".tmp." (a writer's temporary); -1 when
   tmpdir cannot be read. */
static inline int temp_files_left(void)
{
	DIR *d = opendir(tmpdir);
	struct dirent *e;
	int n = 0;

	if (!d)
		return -1;
	while ((e = readdir(d)))
		if (strstr(e->d_name, ".tmp."))
			n++;
	closedir(d);
	return n;
}

/* The whole file, with a 0 byte after it; NULL (and *len 0) when it cannot
   be read.  The caller frees it. */
static inline uint8_t *slurp(const char *path, size_t *len)
{
	FILE *fp = fopen(path, "rb");
	uint8_t *b = NULL;
	long n;

	*len = 0;
	if (!fp)
		return NULL;
	if (fseek(fp, 0, SEEK_END) == 0 && (n = ftell(fp)) >= 0 &&
	    fseek(fp, 0, SEEK_SET) == 0 && (b = malloc((size_t)n + 1))) {
		if (fread(b, 1, (size_t)n, fp) == (size_t)n) {
			b[n] = 0;
			*len = (size_t)n;
		} else {
			free(b);
			b = NULL;
		}
	}
	fclose(fp);
	return b;
}

/* Write n bytes to path (replacing it): 1 when written and closed, else
   0. */
static inline int spit(const char *path, const void *data, size_t n)
{
	FILE *fp = fopen(path, "wb");
	int ok = fp && fwrite(data, 1, n, fp) == n;

	if (fp && fclose(fp) != 0)
		ok = 0;
	return ok;
}

static inline int tmpdir_rm_one(const char *path, const struct stat *st, int flag,
                                struct FTW *ftw)
{
	(void)st;
	(void)flag;
	(void)ftw;
	return remove(path);
}

/* The program's last test, RUN(tmpdir_remove) after every handle on its
   files is closed: tmpdir and all in it removed when every test passed,
   else kept. */
static inline void tmpdir_remove(void)
{
	if (!tmpdir[0])
		return;
	if (check_tests_failed) {
		printf("  files kept in %s\n", tmpdir);
		return;
	}
	CHECK(nftw(tmpdir, tmpdir_rm_one, 16, FTW_DEPTH | FTW_PHYS) == 0);
	CHECK(!file_exists(tmpdir));
}

#endif
