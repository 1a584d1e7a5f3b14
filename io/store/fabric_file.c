/*
 * io/store/fabric_file.c - the public calls that put a fabric into a file
 * and take it out again: loom_fabric_save (fabric_write.c writes) and
 * loom_fabric_open (fabric_read.c parses into a detached fabric, then the
 * engine binds it to its database: loom__fabric_bind).  The database path
 * recorded in the file is opened here, relative paths also beside the file.
 */
#include "synth/fabric_internal.h"
#include "fabric_format.h"

#include <stdlib.h>
#include <string.h>

LOOM_API int loom_fabric_save(const loom_fabric *f, const char *path,
                              uint64_t *bytes, loom_diag *diag)
{
	if (!f || !path)
		return loom__fail(diag, LOOM_EINVAL, "fabric save: NULL %s",
		                  f ? "path" : "fabric");
	if (f->patch)
		return loom__fail(diag, LOOM_EINVAL, "%s: a fabric with painted weaves "
		                  "is saved as its paint file (loom paint), not as a "
		                  "fabric", path);
	if (!f->ef)
		return loom__fail(diag, LOOM_EINVAL, "%s: the fabric has no edge-fix tables "
		                  "(opened detached from a file that did not store them)",
		                  path);
	return loom__fabric_write(f, path, bytes, diag);
}

/* dirname(fabric_path) + "/" + rel, or NULL. */
static char *beside(const char *fabric_path, const char *rel)
{
	const char *slash = strrchr(fabric_path, '/');
	size_t dl, rl = strlen(rel);
	char *p;

	if (!slash)
		return NULL;
	dl = (size_t)(slash - fabric_path) + 1;
	p = malloc(dl + rl + 1);
	if (!p)
		return NULL;
	memcpy(p, fabric_path, dl);
	memcpy(p + dl, rel, rl + 1);
	return p;
}

/* Open the database path recorded in f. */
static int open_recorded_db(loom_fabric *f, const char *path, loom_diag *diag)
{
	loom_diag d2 = {0};
	char *alt;
	int rc;

	if (!f->db_path[0])
		return loom__fail(diag, LOOM_ENOTFOUND,
		                  "%s: records no database path; pass the database", path);
	rc = loom_db_open(f->db_path, &f->db_owned, &d2);
	if (rc == LOOM_OK)
		return LOOM_OK;
	if (f->db_path[0] != '/' && (alt = beside(path, f->db_path)) != NULL) {
		int rc2 = loom_db_open(alt, &f->db_owned, NULL);
		free(alt);
		if (rc2 == LOOM_OK)
			return LOOM_OK;
	}
	return loom__fail(diag, rc, "%s: cannot open its database: %s", path, d2.message);
}

LOOM_API int loom_fabric_file_size(const char *path, uint32_t *rows, uint32_t *cols,
                                   loom_diag *diag)
{
	if (!path || !rows || !cols)
		return loom__fail(diag, LOOM_EINVAL, "fabric file size: NULL argument");
	*rows = *cols = 0;
	return loom__fabric_read_size(path, rows, cols, diag);
}

LOOM_API int loom_fabric_open(const char *path, const loom_db *db,
                              unsigned flags, loom_fabric **out,
                              loom_diag *diag)
{
	loom_fabric *f = NULL;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "fabric open: NULL output");
	*out = NULL;
	if (!path)
		return loom__fail(diag, LOOM_EINVAL, "fabric open: NULL path");
	if (flags & ~(unsigned)LOOM_FABRIC_OPEN_DETACHED)
		return loom__fail(diag, LOOM_EINVAL, "fabric open: unknown flags 0x%x", flags);
	rc = loom__fabric_read(path, NULL, 0, &f, diag);
	if (rc)
		return rc;
	if (!(flags & LOOM_FABRIC_OPEN_DETACHED)) {
		if (!db) {
			rc = open_recorded_db(f, path, diag);
			db = f->db_owned;
		}
		if (!rc)
			rc = loom__fabric_bind(f, db, 1, path, diag);
		if (rc) {
			loom_fabric_free(f);
			return rc;
		}
	}
	*out = f;
	return LOOM_OK;
}
