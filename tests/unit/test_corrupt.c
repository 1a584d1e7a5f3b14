/*
 * tests/unit/test_corrupt.c - the corruption sweep: every byte of a tiny
 * exemplar database (.ldb) and of a tiny fabric file (.loomf) is flipped
 * (XOR 0xff) in turn, and the reader must refuse each altered file (the
 * .ldb: loom_db_open, then loom_db_verify over every brick; the .loomf:
 * loom_fabric_open bound to its database).  The flips run in a child
 * process that reports each result on a pipe, so a crash is counted (and
 * the sweep goes on after it) instead of ending the test.  Prints
 * "detected N crashed N silent N" per format; both crashed and silent
 * must be 0 (docs/formats.md lists the checks that make it so).
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static char db_path[4200], fab_path[4200], work_path[4200];
static loom_db *db;

/* 1 if the reader accepts the file at path (a silent corruption) */
static int accepts_ldb(const char *path)
{
	loom_diag d = {0};
	loom_db *x = NULL;
	int ok;

	if (loom_db_open(path, &x, &d) != LOOM_OK)
		return d.message[0] ? 0 : 2; /* an error without a message: a bug */
	ok = loom_db_verify(x, NULL, NULL, &d) == LOOM_OK;
	loom_db_close(x);
	return ok;
}

static int accepts_loomf(const char *path)
{
	loom_diag d = {0};
	loom_fabric *f = NULL;

	if (loom_fabric_open(path, db, 0, &f, &d) != LOOM_OK)
		return d.message[0] ? 0 : 2;
	loom_fabric_free(f);
	return 1;
}

/* Flip every byte of orig in turn into work_path and ask accepts();
   counts[0..2] = detected, crashed, silent; the first silent offsets are
   printed. */
static void sweep(const char *what, const uint8_t *orig, size_t len,
                  int (*accepts)(const char *), unsigned counts[3])
{
	uint8_t *buf = malloc(len);
	size_t i = 0;
	unsigned shown = 0;

	memset(counts, 0, 3 * sizeof *counts);
	if (!buf)
		return;
	while (i < len) {
		int fd[2], status;
		pid_t pid;
		char r;

		if (pipe(fd) != 0)
			break;
		fflush(stdout);
		pid = fork();
		if (pid == 0) {
			close(fd[0]);
			memcpy(buf, orig, len);
			for (size_t k = i; k < len; k++) {
				int a;
				buf[k] ^= 0xff;
				if (!spit(work_path, buf, len))
					_exit(3);
				a = accepts(work_path);
				buf[k] ^= 0xff;
				r = a == 0 ? 'D' : a == 1 ? 'S' : 'M';
				if (write(fd[1], &r, 1) != 1)
					_exit(3);
			}
			_exit(0);
		}
		close(fd[1]);
		while (read(fd[0], &r, 1) == 1) {
			if (r == 'D') {
				counts[0]++;
			} else {
				counts[2]++;
				if (shown++ < 8)
					printf("  %s: byte %zu flipped: %s\n", what, i,
					       r == 'S' ? "accepted" : "refused without a message");
			}
			i++;
		}
		close(fd[0]);
		waitpid(pid, &status, 0);
		if (i < len) { /* the child died on byte i */
			printf("  %s: byte %zu flipped: the reader crashed (status %d)\n", what,
			       i, status);
			counts[1]++;
			i++;
		}
	}
	free(buf);
	printf("  %s: %zu bytes: detected %u crashed %u silent %u\n", what, len,
	       counts[0], counts[1], counts[2]);
}

static void ldb_sweep(void)
{
	uint8_t *orig;
	size_t len;
	unsigned c[3];

	CHECK((orig = slurp(db_path, &len)) != NULL);
	if (check_fail_count)
		return;
	CHECK(accepts_ldb(db_path) == 1); /* the sweep means nothing otherwise */
	sweep("tiny.ldb", orig, len, accepts_ldb, c);
	CHECK_EQ_INT(c[0] + c[1] + c[2], len);
	CHECK_EQ_INT(c[1], 0);
	CHECK_EQ_INT(c[2], 0);
	free(orig);
}

static void loomf_sweep(void)
{
	uint8_t *orig;
	size_t len;
	unsigned c[3];

	CHECK((orig = slurp(fab_path, &len)) != NULL);
	if (check_fail_count)
		return;
	CHECK(accepts_loomf(fab_path) == 1);
	sweep("tiny.loomf", orig, len, accepts_loomf, c);
	CHECK_EQ_INT(c[0] + c[1] + c[2], len);
	CHECK_EQ_INT(c[1], 0);
	CHECK_EQ_INT(c[2], 0);
	free(orig);
}

int main(void)
{
	loom_exgen_params p;
	loom_weave_params wp;
	loom_design *d = NULL;
	loom_fabric *f = NULL;
	loom_diag diag = {0};

	CHECK_MAIN_BEGIN("test_corrupt");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	snprintf(fab_path, sizeof fab_path, "%s/tiny.loomf", tmpdir);
	snprintf(work_path, sizeof work_path, "%s/flipped", tmpdir);
	/* one plain exemplar of 2x2 crossings in one brick; a 4x4 plain design */
	if (loom_exgen_preset("tiny", &p) != LOOM_OK) {
		printf("FAIL test_corrupt/setup (preset)\n");
		return 1;
	}
	p.n_weaves = 1;
	p.weaves[0] = "plain";
	p.rows = p.cols = 2;
	if (loom_exgen_write_db(db_path, &p, NULL, &diag) != LOOM_OK ||
	    loom_db_open(db_path, &db, &diag) != LOOM_OK ||
	    loom_weave_parse("plain", &wp, &diag) != LOOM_OK ||
	    loom_design_make(&wp, 4, 4, &d, &diag) != LOOM_OK ||
	    loom_fabric_synthesize(d, db, db_path, NULL, &f, &diag) != LOOM_OK ||
	    loom_fabric_save(f, fab_path, NULL, &diag) != LOOM_OK) {
		printf("FAIL test_corrupt/setup (%s)\n", diag.message);
		return 1;
	}
	loom_fabric_free(f);
	loom_design_free(d);
	RUN(ldb_sweep);
	RUN(loomf_sweep);
	loom_db_close(db);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
