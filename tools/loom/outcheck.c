/*
 * tools/loom/outcheck.c - checks of an output path before any long work
 * (cli_check_output, cli_check_output_dir): a directory where a file is
 * expected, a missing or unwritable parent directory.  The writers still
 * write a temporary file and rename it; this only moves the failure to
 * the start of the command.  cli_check_output also removes the stale
 * temporaries of earlier runs that were killed while writing the same
 * output (loom__atomic_sweep: "<path>.tmp.<pid>[.<n>]" of dead writers).
 */
#include "cli.h"
#include "io/core/file.h" /* io/: loom__atomic_sweep */

#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* The directory part of path ("." when none) into buf. */
static void parent_of(const char *path, char *buf, size_t n)
{
	const char *slash = strrchr(path, '/');
	size_t len;

	if (!slash) {
		snprintf(buf, n, ".");
		return;
	}
	len = (size_t)(slash - path);
	if (len == 0)
		len = 1; /* "/x" */
	if (len >= n)
		len = n - 1;
	memcpy(buf, path, len);
	buf[len] = 0;
}

void cli_check_output(const char *prog, const char *path)
{
	char dir[PATH_MAX];
	struct stat s;

	if (!path || !*path)
		cli_fail(prog, "empty output file name");
	if (stat(path, &s) == 0 && S_ISDIR(s.st_mode))
		cli_fail(prog, "%s: is a directory; expected the name of a file to write",
		         path);
	parent_of(path, dir, sizeof dir);
	if (stat(dir, &s) != 0)
		cli_fail(prog, "%s: cannot create it: directory %s: %s", path, dir,
		         strerror(errno));
	if (!S_ISDIR(s.st_mode))
		cli_fail(prog, "%s: cannot create it: %s is not a directory", path, dir);
	if (access(dir, W_OK | X_OK) != 0)
		cli_fail(prog, "%s: cannot create it: directory %s: %s", path, dir,
		         strerror(errno));
	/* what an earlier run killed while writing path left behind */
	loom__atomic_sweep(path);
}

void cli_check_output_dir(const char *prog, const char *dir)
{
	char parent[PATH_MAX];
	struct stat s;

	if (!dir || !*dir)
		cli_fail(prog, "empty output directory name");
	if (stat(dir, &s) == 0) {
		if (!S_ISDIR(s.st_mode))
			cli_fail(prog, "%s: exists and is not a directory", dir);
		if (access(dir, W_OK | X_OK) != 0)
			cli_fail(prog, "%s: cannot write there: %s", dir, strerror(errno));
		return;
	}
	parent_of(dir, parent, sizeof parent);
	if (stat(parent, &s) != 0 || !S_ISDIR(s.st_mode))
		cli_fail(prog, "%s: cannot create it: directory %s does not exist", dir,
		         parent);
	if (access(parent, W_OK | X_OK) != 0)
		cli_fail(prog, "%s: cannot create it in %s: %s", dir, parent, strerror(errno));
}
