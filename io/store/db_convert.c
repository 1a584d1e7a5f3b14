/*
 * io/store/db_convert.c - rewrite a database in another storage: format
 * version (voxel layout) and density planes raw or deflated
 * (loom_db_convert, `loom exemplar convert`; docs/exemplars.md,
 * "Converting a database").
 *
 * Every exemplar is copied with its record (name, weave, yarn table,
 * material pair) and its bricks decoded one at a time and encoded again by
 * the streaming writer, which rebuilds the block tables from the same
 * voxels (so they are the same tables).  Memory: one decoded brick, the
 * reader's scratch and the writer's (docs/exemplars.md); the output is
 * written to a temporary name and renamed (loom__dbw_finish).
 */
#include "io/store/db_write.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* The header bytes (level and flags are not in the public info). */
static int read_header(const char *path, uint8_t h[LOOM__DB_HEADER_BYTES], loom_diag *diag)
{
	FILE *f = fopen(path, "rb");
	size_t n;

	if (!f)
		return loom__fail(diag, LOOM_EIO, "%s: cannot open for reading", path);
	n = fread(h, 1, LOOM__DB_HEADER_BYTES, f);
	fclose(f);
	if (n != LOOM__DB_HEADER_BYTES)
		return loom__fail(diag, LOOM_EIO, "%s: cannot read its header", path);
	return LOOM_OK;
}

/* Whether a and b name the same file (both exist). */
static int same_file(const char *a, const char *b)
{
	struct stat sa, sb;

	return stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_dev == sb.st_dev &&
	       sa.st_ino == sb.st_ino;
}

/*
 * The voxel rule (docs/formats.md): orientation code 0 wherever density is
 * 0.  Files that `loom exemplar generate` or `loom exemplar build` wrote
 * before 2026-12-05 could keep the code of voxels whose density quantised
 * to 0; converting clears it (what `loom exemplar verify` tells the user
 * to do).
 */
static uint64_t clear_empty_orient(uint8_t *brick, size_t nv)
{
	uint64_t n = 0;

	for (size_t i = 0; i < nv; i++)
		if (brick[i] == 0 && (brick[nv + i] | brick[2 * nv + i])) {
			brick[nv + i] = brick[2 * nv + i] = 0;
			n++;
		}
	return n;
}

LOOM_API int loom_db_convert(const char *in, const char *out, uint32_t db_version,
                             int density_raw,
                             void (*progress)(void *user, uint64_t done, uint64_t total),
                             void *user, uint64_t *hash, loom_diag *diag)
{
	loom_db *db = NULL;
	loom_db_info info;
	loom__dbw_params p;
	loom__dbw *w = NULL;
	loom__db_reader *r = NULL;
	uint8_t hdr[LOOM__DB_HEADER_BYTES], *buf = NULL;
	uint64_t done = 0, cleared = 0;
	size_t nv;
	int rc;

	if (!in || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_db_convert: NULL path");
	if (db_version > LOOM__DB_VERSION || density_raw < -1 || density_raw > 1)
		return loom__fail(diag, LOOM_EINVAL, "loom_db_convert: format version %u, "
		                  "density_raw %d (expected 0 to keep, 1 to %u; -1 to keep, "
		                  "0 deflated, 1 raw)", db_version, density_raw,
		                  LOOM__DB_VERSION);
	if (same_file(in, out))
		return loom__fail(diag, LOOM_EINVAL, "%s: the output is the input; write "
		                  "the converted database to another file", out);
	if ((rc = loom_db_open(in, &db, diag)) != LOOM_OK)
		return rc;
	loom_db_get_info(db, &info);
	if ((rc = read_header(in, hdr, diag)) != LOOM_OK)
		goto done;
	loom__dbw_params_like(&info, hdr, &p); /* what is not asked for is kept */
	p.n_exemplars = info.n_exemplars;
	if (db_version)
		p.layout = db_version;
	if (density_raw >= 0)
		p.density_raw = (uint32_t)density_raw;
	if (p.density_raw && p.layout == LOOM__DB_LAYOUT_PLANES) {
		rc = loom__fail(diag, LOOM_EINVAL, "%s: density planes stored raw need "
		                "format version 2, 3 or 4 (version 1 stores a brick as one "
		                "stream)", out);
		goto done;
	}
	r = loom__db_reader_new(db);
	nv = (size_t)info.brick[0] * info.brick[1] * info.brick[2];
	buf = malloc(nv * LOOM__VOXEL_PLANES);
	if (!r || !buf) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", in);
		goto done;
	}
	if ((rc = loom__dbw_create(out, &p, &w, diag)) != LOOM_OK)
		goto done;
	for (uint32_t k = 0; k < info.n_exemplars && rc == LOOM_OK; k++) {
		loom_db_exemplar_info e;
		loom__dbw_exemplar x;
		uint64_t nb;
		loom_db_exemplar(db, k, &e);
		memset(&x, 0, sizeof x);
		x.name = e.name;
		x.weave_name = e.weave_name;
		x.rows = e.rows;
		x.cols = e.cols;
		x.weave = e.weave;
		x.n_yarns = e.n_yarns;
		x.yarns = e.yarns;
		memcpy(x.fibre, e.fibre, sizeof x.fibre);
		if ((rc = loom__dbw_begin_exemplar(w, &x, diag)) != LOOM_OK)
			break;
		/* the writer's order is the file's: by, bx, then bz fastest */
		nb = (uint64_t)e.bricks[0] * e.bricks[1] * e.bricks[2];
		for (uint64_t i = 0; i < nb && rc == LOOM_OK; i++) {
			rc = loom__db_reader_read(r, e.first_brick + (uint32_t)i, buf, NULL, diag);
			if (rc == LOOM_OK) {
				cleared += clear_empty_orient(buf, nv);
				rc = loom__dbw_add_brick(w, buf, diag);
			}
			if (progress && (++done % 256 == 0 || done == info.n_bricks))
				progress(user, done, info.n_bricks);
		}
	}
	if (rc == LOOM_OK) {
		rc = loom__dbw_finish(w, hash, diag);
		w = NULL;
	}
	if (rc == LOOM_OK && cleared)
		loom__warn(diag, "%s: cleared the orientation codes of %" PRIu64 " voxel%s of "
		           "density 0 (the voxel rule, docs/formats.md); %s keeps the rule",
		           in, cleared, cleared == 1 ? "" : "s", out);
done:
	if (w)
		loom__dbw_abort(w);
	free(buf);
	if (r)
		loom__db_reader_free(r);
	loom_db_close(db);
	return rc;
}
