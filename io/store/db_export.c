/*
 * io/store/db_export.c - one exemplar channel of a database as a NRRD volume
 * (`loom exemplar export`).  Reads one z-layer of bricks at a time
 * (size_x * size_y * brick_z voxels of the one channel) and streams it
 * through the NRRD writer, so memory does not grow with the exemplar
 * height.
 */
#include "exemplar/db_internal.h"
#include "io/volume/nrrd.h"

#include <stdlib.h>

LOOM_API int loom_db_export_nrrd(const loom_db *db, uint32_t k, int channel,
                                 const char *path, int detached,
                                 loom_diag *diag)
{
	static const char *const ch_name[LOOM_DB_CH_COUNT_] = {
		"density", "label", "kind", "orientation", "orientation code"};
	loom_db_exemplar_info e;
	loom_db_info info;
	loom__nrrd_desc d;
	loom__nrrd_w w;
	const loom_db_yarn *yarns;
	char content[128];
	size_t slice, layer_vox;
	uint8_t *b8 = NULL;
	uint16_t *b16 = NULL;
	float *fv = NULL;
	int rc;

	if (!db || !path)
		return loom__fail(diag, LOOM_EINVAL, "loom_db_export_nrrd: NULL argument");
	if (channel < 0 || channel >= LOOM_DB_CH_COUNT_)
		return loom__fail(diag, LOOM_EINVAL, "export: unknown channel %d", channel);
	if (loom_db_exemplar(db, k, &e) != LOOM_OK)
		return loom__fail(diag, LOOM_ERANGE, "export: exemplar %u out of range", k);
	loom_db_get_info(db, &info);
	yarns = loom__db_yarn_lut(db, k);
	memset(&d, 0, sizeof d);
	d.type = channel == LOOM_DB_CH_ORIENTATION ? LOOM__NRRD_FLOAT :
	         channel == LOOM_DB_CH_ORIENT_CODE ? LOOM__NRRD_UINT16 : LOOM__NRRD_UINT8;
	d.components = channel == LOOM_DB_CH_ORIENTATION ? 3 : 1;
	for (int a = 0; a < 3; a++) {
		d.sizes[a] = e.size[a];
		d.spacing[a] = info.voxel_size_um / 1000.0;
		d.origin[a] = 0.5 * d.spacing[a];
	}
	d.units = "mm";
	snprintf(content, sizeof content, "loom exemplar %s %s", e.name, ch_name[channel]);
	d.content = content;
	slice = (size_t)e.size[0] * e.size[1];
	layer_vox = slice * info.brick[2];
	if (channel == LOOM_DB_CH_ORIENTATION || channel == LOOM_DB_CH_ORIENT_CODE)
		b16 = malloc(layer_vox * sizeof *b16);
	else
		b8 = malloc(layer_vox);
	if (channel == LOOM_DB_CH_ORIENTATION)
		fv = malloc(slice * 3 * sizeof *fv);
	if ((!b8 && !b16) || (channel == LOOM_DB_CH_ORIENTATION && !fv)) {
		free(b8);
		free(b16);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	rc = loom__nrrd_begin(&w, path, detached, &d, diag);
	for (uint32_t z0 = 0; !rc && z0 < e.size[2]; z0 += info.brick[2]) {
		uint32_t nz = e.size[2] - z0 < info.brick[2] ? e.size[2] - z0 : info.brick[2];
		uint32_t org[3] = {0, 0, z0}, sz[3] = {e.size[0], e.size[1], nz};
		size_t n = slice * nz;

		switch (channel) {
		case LOOM_DB_CH_DENSITY:
			rc = loom_db_read_box(db, k, org, sz, b8, NULL, NULL, diag);
			break;
		case LOOM_DB_CH_LABEL:
		case LOOM_DB_CH_KIND:
			rc = loom_db_read_box(db, k, org, sz, NULL, NULL, b8, diag);
			if (!rc && channel == LOOM_DB_CH_KIND)
				for (size_t i = 0; i < n; i++)
					b8[i] = yarns[b8[i]].kind;
			break;
		default:
			rc = loom_db_read_box(db, k, org, sz, NULL, b16, NULL, diag);
			break;
		}
		if (rc)
			break;
		if (channel == LOOM_DB_CH_ORIENTATION) {
			for (uint32_t z = 0; z < nz && !rc; z++) {
				for (size_t i = 0; i < slice; i++)
					loom__orient_decode(b16[(size_t)z * slice + i], fv + 3 * i);
				rc = loom__nrrd_write(&w, fv, slice * 3, diag);
			}
		} else if (b16) {
			rc = loom__nrrd_write(&w, b16, n, diag);
		} else {
			rc = loom__nrrd_write(&w, b8, n, diag);
		}
	}
	if (!rc)
		rc = loom__nrrd_finish(&w, diag);
	else
		loom__nrrd_abort(&w);
	free(b8);
	free(b16);
	free(fv);
	return rc;
}
