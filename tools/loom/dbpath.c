/*
 * tools/loom/dbpath.c - where the loom command finds the exemplar
 * database, in this order (docs/exemplars.md):
 *   1. the --db option of the command;
 *   2. the environment variable LOOM_DB;
 *   3. default.ldb in the data directory (cli_data_dir(): $LOOM_DATA, the
 *      build tree's build/share/loom, the installed <prefix>/share/loom).
 */
#include "cli.h"

#include <limits.h>
#include <stdlib.h>
#include <sys/stat.h>

const char *cli_db_path(const char *opt)
{
	static char buf[PATH_MAX + 32];
	const char *env = getenv("LOOM_DB");
	const char *dir;
	struct stat st;

	if (opt && *opt)
		return opt;
	if (env && *env)
		return env;
	dir = cli_data_dir();
	if (!dir)
		return NULL;
	snprintf(buf, sizeof buf, "%s/default.ldb", dir);
	if (stat(buf, &st) != 0)
		return NULL;
	return buf;
}

const char *cli_db_require(const char *opt, const char *prog)
{
	const char *p = cli_db_path(opt);
	const char *dir;

	if (p)
		return p;
	dir = cli_data_dir();
	cli_fail(prog, "no exemplar database: give --db DB, set LOOM_DB, or build "
	         "the default with make (looked for %s/default.ldb)",
	         dir ? dir : "<no data directory>");
}
