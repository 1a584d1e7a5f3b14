/*
 * io/store/scan_db.c - store a scan pipeline result as one exemplar of a
 * database (loom exemplar build): a new database, or an existing one
 * extended by loom__dbw_append (old bricks and tables copied verbatim).
 */
#include "scan/scan_internal.h"
#include "exemplar/db_internal.h"
#include "db_write.h"

#include <stdlib.h>
#include <sys/stat.h>

LOOM_API void loom_scan_db_params_init(loom_scan_db_params *p)
{
	if (!p)
		return;
	memset(p, 0, sizeof *p);
	p->size = sizeof *p;
	p->name = "scan";
	p->weave_name = "";
	p->voxel_size_um = 5.0f;
	p->brick[0] = LOOM_DB_DEFAULT_BRICK_X;
	p->brick[1] = LOOM_DB_DEFAULT_BRICK_Y;
	p->brick[2] = LOOM_DB_DEFAULT_BRICK_Z;
	p->level = LOOM_DB_DEFAULT_LEVEL;
}

/* Fill the four planes of brick (bx, by, bz) from the result volume. */
static void fill_brick(const loom_scan_volume *v, const uint32_t br[3], uint32_t bx,
                       uint32_t by, uint32_t bz, uint8_t *raw)
{
	size_t nv = (size_t)br[0] * br[1] * br[2];
	uint8_t *dp = raw, *lo = raw + nv, *hi = raw + 2 * nv, *lp = raw + 3 * nv;

	memset(raw, 0, nv * LOOM__VOXEL_PLANES);
	for (uint32_t ly = 0; ly < br[1]; ly++) {
		uint32_t y = by * br[1] + ly;
		if (y >= v->ny)
			break;
		for (uint32_t lx = 0; lx < br[0]; lx++) {
			uint32_t x = bx * br[0] + lx;
			if (x >= v->nx)
				break;
			for (uint32_t lz = 0; lz < br[2]; lz++) {
				uint32_t z = bz * br[2] + lz;
				size_t i, o = ((size_t)ly * br[0] + lx) * br[2] + lz;
				uint8_t d, l;
				uint16_t c = 0;
				if (z >= v->nz)
					break;
				i = loom__scan_idx(v, x, y, z);
				d = loom__density_encode(v->density[i]);
				l = v->label ? v->label[i] : 0;
				/* a voxel of density 0 has code 0, labelled or not:
				   point lookups report no orientation there and region
				   reads copy the stored code, which must agree */
				if (d && v->ocode)
					c = v->ocode[i];
				else if (d && v->orient)
					c = loom__orient_encode(v->orient[3 * i], v->orient[3 * i + 1],
					                        v->orient[3 * i + 2]);
				dp[o] = d;
				lo[o] = (uint8_t)c;
				hi[o] = (uint8_t)(c >> 8);
				lp[o] = l;
			}
		}
	}
}

LOOM_API int loom_scan_write_db(const loom_scan_result *r, const char *path,
                                const loom_scan_db_params *p, int *appended,
                                loom_diag *diag)
{
	loom__dbw *w = NULL;
	loom__dbw_params wp;
	loom__dbw_exemplar ex;
	loom_db_yarn *yt = NULL;
	uint8_t *raw = NULL;
	struct stat st;
	uint32_t nb[3];
	int rc, exists;

	if (appended)
		*appended = 0;
	if (!r || !path || !p || p->size != sizeof *p || !p->name)
		return loom__fail(diag, LOOM_EINVAL, "scan: database: bad arguments");
	if (r->n_yarns > 255 || !r->volume.density || !r->rows || !r->cols)
		return loom__fail(diag, LOOM_EINVAL, "scan: database: empty result or "
		                  "more than 255 yarns");
	if (!p->name[0] || strlen(p->name) >= 32 ||
	    (p->weave_name && strlen(p->weave_name) >= 32))
		return loom__fail(diag, LOOM_EINVAL, "scan: database: exemplar name '%s' "
		                  "is empty or longer than 31 bytes", p->name);
	if (p->db_version > LOOM__DB_VERSION || p->density_raw > 1 ||
	    (p->density_raw && p->db_version == LOOM__DB_VERSION_PLANES1))
		return loom__fail(diag, LOOM_EINVAL, "scan: database: format version %u "
		                  "with density_raw %u (expected version 0..%u, raw density "
		                  "only with version 0, 2, 3 or 4)", p->db_version,
		                  p->density_raw, LOOM__DB_VERSION);
	exists = stat(path, &st) == 0;
	if (exists) {
		loom_db *db;
		uint32_t k;
		rc = loom_db_open(path, &db, diag);
		if (rc)
			return rc;
		rc = loom_db_find_exemplar(db, p->name, &k);
		loom_db_close(db);
		if (rc == LOOM_OK)
			return loom__fail(diag, LOOM_EINVAL, "%s: exemplar %u is already named "
			                  "'%s'; choose another --name", path, k, p->name);
		rc = loom__dbw_append(path, 1, 1u /* no longer all procedural */, &w,
		                      &wp, diag);
		if (rc)
			return rc;
		if (wp.block[0] != r->b1 || wp.block[1] != r->b2 || wp.block[2] != r->b3) {
			loom__dbw_abort(w);
			return loom__fail(diag, LOOM_EMISMATCH, "%s: the database's blocks are "
			                  "%ux%ux%u voxels, the scan's crossings %ux%ux%u; pass "
			                  "--block %ux%u (and a scan of %u planes or --depth)",
			                  path, wp.block[0], wp.block[1], wp.block[2], r->b1,
			                  r->b2, r->b3, wp.block[0], wp.block[1], wp.block[2]);
		}
		if ((p->db_version && p->db_version != wp.layout) ||
		    (p->density_raw && !wp.density_raw)) {
			loom__dbw_abort(w);
			if (p->density_raw && !wp.density_raw)
				return loom__fail(diag, LOOM_EMISMATCH, "%s: the database's "
				                  "density planes are compressed; appending keeps "
				                  "its storage (convert it first: loom exemplar "
				                  "convert --raw-density)", path);
			return loom__fail(diag, LOOM_EMISMATCH, "%s: the database is format "
			                  "version %u, not %u; appending keeps its version "
			                  "(convert it first: loom exemplar convert "
			                  "--format-version %u)", path, wp.layout,
			                  p->db_version, p->db_version);
		}
		if (p->voxel_size_um > 0 &&
		    fabsf(wp.voxel_size_um - p->voxel_size_um) > 1e-3f * wp.voxel_size_um)
			loom__warn(diag, "%s: voxel size %g um, the scan's %g um; the "
			           "database's is kept", path, (double)wp.voxel_size_um,
			           (double)p->voxel_size_um);
		if (appended)
			*appended = 1;
	} else {
		memset(&wp, 0, sizeof wp);
		wp.n_exemplars = 1;
		wp.block[0] = r->b1;
		wp.block[1] = r->b2;
		wp.block[2] = r->b3;
		memcpy(wp.brick, p->brick, sizeof wp.brick);
		wp.voxel_size_um = p->voxel_size_um;
		wp.top_threshold = LOOM__DB_TOP_THRESHOLD;
		wp.level = p->level;
		wp.seed = 0;
		wp.flags = 0;
		wp.layout = p->db_version ? p->db_version : LOOM__DB_VERSION_DEFAULT;
		wp.density_raw = p->density_raw;
		rc = loom__dbw_create(path, &wp, &w, diag);
		if (rc)
			return rc;
	}
	yt = calloc((size_t)r->n_yarns + 1, sizeof *yt);
	raw = malloc((size_t)wp.brick[0] * wp.brick[1] * wp.brick[2] * LOOM__VOXEL_PLANES);
	if (!yt || !raw) {
		rc = loom__fail(diag, LOOM_ENOMEM, "scan: database: out of memory");
		goto fail;
	}
	for (uint32_t i = 0; i < r->n_yarns; i++) {
		const loom_scan_yarn *y = &r->yarns[i];
		int32_t lim = y->kind == LOOM_SCAN_WARP ? (int32_t)r->cols : (int32_t)r->rows;
		yt[i + 1].kind = y->kind == LOOM_SCAN_WARP ? LOOM_YARN_WARP : LOOM_YARN_WEFT;
		yt[i + 1].index = (int16_t)(y->index < -1 ? -1 : y->index > lim ? lim : y->index);
		yt[i + 1].flags = y->index < 0 || y->index >= lim ? LOOM_DB_YARN_OUTSIDE : 0;
	}
	memset(&ex, 0, sizeof ex);
	ex.name = p->name;
	ex.weave_name = p->weave_name ? p->weave_name : "";
	ex.rows = r->rows;
	ex.cols = r->cols;
	ex.weave = r->weave;
	ex.n_yarns = r->n_yarns;
	ex.yarns = yt;
	rc = loom__dbw_begin_exemplar(w, &ex, diag);
	if (rc)
		goto fail;
	for (int a = 0; a < 3; a++) {
		uint32_t sz = a == 0 ? r->volume.nx : a == 1 ? r->volume.ny : r->volume.nz;
		nb[a] = (sz + wp.brick[a] - 1) / wp.brick[a];
	}
	for (uint32_t by = 0; by < nb[1] && !rc; by++)
		for (uint32_t bx = 0; bx < nb[0] && !rc; bx++)
			for (uint32_t bz = 0; bz < nb[2] && !rc; bz++) {
				fill_brick(&r->volume, wp.brick, bx, by, bz, raw);
				rc = loom__dbw_add_brick(w, raw, diag);
			}
	if (rc)
		goto fail;
	free(yt);
	free(raw);
	return loom__dbw_finish(w, NULL, diag);
fail:
	free(yt);
	free(raw);
	loom__dbw_abort(w);
	return rc;
}
