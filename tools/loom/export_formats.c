/*
 * tools/loom/export_formats.c - the tile writers of `loom export`, one per
 * format: Mitsuba .vol and NRRD (one file per channel per tile), OpenEXR
 * (one multi-channel image per z slice per tile).  docs/batch.md lists the
 * files and their layout; the writers are libloom's (docs/volumes.md).
 */
#include "cli.h"
#include "export.h"

#include "io/volume/nrrd.h" /* io/: the NRRD writer (internal to libloom) */
#include "io/volume/vdb.h"  /* io/: the OpenVDB / NanoVDB shim (internal) */

#include <stdlib.h>
#include <string.h>

/* One row (x0..x1 at y, z of the tile buffers, nx x ny) of channel ch as
   floats, comps per voxel. */
static void fill_row(const struct export_ctx *c, const struct ewstate *w, int ch,
                     size_t off, size_t nx, float *out)
{
	const uint8_t *d = w->d + off, *k = w->k + off, *ty = w->ty + off;
	const uint16_t *o = w->o + off;

	if (c->lod) { /* the coarse tile: LOD_FLOATS per voxel */
		static const unsigned first[N_CH] = {0, 1, 4, 7, 8};
		for (size_t i = 0; i < nx; i++)
			for (unsigned q = 0; q < ch_comps[ch]; q++)
				out[i * ch_comps[ch] + q] = w->lv[(off + i) * LOD_FLOATS + first[ch] + q];
		return;
	}
	switch (ch) {
	case CH_DENSITY:
		for (size_t i = 0; i < nx; i++)
			out[i] = (float)d[i] / 255.0f;
		break;
	case CH_ORIENT:
		for (size_t i = 0; i < nx; i++) {
			if (d[i])
				loom_orientation_decode(o[i], out + 3 * i);
			else
				out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = 0.0f;
		}
		break;
	case CH_ALBEDO:
		for (size_t i = 0; i < nx; i++) {
			if (k[i] && w->tint) {
				/* the tile buffers are x fastest: off + i is (x, y, z) */
				size_t v = off + i, nxy = (size_t)w->n[0];
				int64_t x = w->lo[0] + (int64_t)(v % nxy);
				int64_t y = w->lo[1] + (int64_t)(v / nxy % (size_t)w->n[1]);
				export_albedo(c, w, x, y, k[i], ty[i], out + 3 * i);
			} else if (k[i])
				memcpy(out + 3 * i, c->albedo[ty[i]], 3 * sizeof(float));
			else
				out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = 0.0f;
		}
		break;
	case CH_KIND:
		for (size_t i = 0; i < nx; i++)
			out[i] = (float)k[i];
		break;
	default:
		for (size_t i = 0; i < nx; i++)
			out[i] = (float)ty[i];
		break;
	}
}

/* ---- writers ----------------------------------------------------------------- */

static int write_vol(struct export_ctx *c, struct ewstate *w, const char *stem, int ch,
                     const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	loom_vol_header h;
	loom_vol_writer *vw = NULL;
	loom_diag diag;
	char name[512], path[4096];
	double vmm = c->vmm;

	snprintf(name, sizeof name, "%s.%s.vol", stem, ch_names[ch]);
	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	memset(&h, 0, sizeof h);
	/* density: bytes as stored, or with --lod the coarse means as floats */
	h.encoding = ch == CH_DENSITY && !c->lod ? LOOM_VOL_UINT8 : LOOM_VOL_FLOAT32;
	h.xres = (uint32_t)nx;
	h.yres = (uint32_t)ny;
	h.zres = (uint32_t)nz;
	h.channels = ch_comps[ch];
	for (int a = 0; a < 3; a++) {
		/* node-centred: first to last voxel centre (one voxel when res 1) */
		h.bbox_min[a] = (float)(((double)lo[a] + 0.5) * vmm);
		h.bbox_max[a] = hi[a] - lo[a] > 1 ? (float)(((double)hi[a] - 0.5) * vmm)
		                                  : (float)(((double)lo[a] + 1.5) * vmm);
	}
	cli_diag_init(&diag, NULL);
	if (loom_vol_writer_open(path, &h, &vw, &diag) != LOOM_OK)
		goto fail;
	for (size_t z = 0; z < nz; z++)
		for (size_t y = 0; y < ny; y++) {
			fill_row(c, w, ch, (z * ny + y) * nx, nx, w->row);
			if (loom_vol_writer_put_voxels(vw, w->row, nx, &diag) != LOOM_OK)
				goto fail;
		}
	if (loom_vol_writer_finish(vw, &diag) != LOOM_OK) {
		vw = NULL;
		goto fail;
	}
	return export_record_file(c, w, name, msg, msz);
fail:
	loom_vol_writer_abort(vw);
	snprintf(msg, msz, "%s", diag.message);
	return -1;
}

static int write_nrrd(struct export_ctx *c, struct ewstate *w, const char *stem, int ch,
                      const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	loom__nrrd_desc d;
	loom__nrrd_w nw;
	loom_diag diag;
	char name[512], path[4096], content[64];
	int rc = LOOM_OK;

	snprintf(name, sizeof name, "%s.%s.nrrd", stem, ch_names[ch]);
	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	snprintf(content, sizeof content, "loom %s", ch_names[ch]);
	memset(&d, 0, sizeof d);
	d.type = ch == CH_KIND || ch == CH_TYPE ? LOOM__NRRD_UINT8 : LOOM__NRRD_FLOAT;
	d.components = ch_comps[ch];
	d.sizes[0] = nx;
	d.sizes[1] = ny;
	d.sizes[2] = nz;
	for (int a = 0; a < 3; a++) {
		d.spacing[a] = c->vmm;
		d.origin[a] = ((double)lo[a] + 0.5) * c->vmm;
	}
	d.units = "mm";
	d.content = content;
	cli_diag_init(&diag, NULL);
	if (loom__nrrd_begin(&nw, path, 0, &d, &diag) != LOOM_OK) {
		snprintf(msg, msz, "%s", diag.message);
		return -1;
	}
	if (ch == CH_KIND || ch == CH_TYPE) {
		rc = loom__nrrd_write(&nw, ch == CH_KIND ? w->k : w->ty, nx * ny * nz, &diag);
	} else {
		for (size_t r = 0; r < ny * nz && rc == LOOM_OK; r++) {
			fill_row(c, w, ch, r * nx, nx, w->row);
			rc = loom__nrrd_write(&nw, w->row, nx * ch_comps[ch], &diag);
		}
	}
	if (rc == LOOM_OK)
		rc = loom__nrrd_finish(&nw, &diag);
	else
		loom__nrrd_abort(&nw);
	if (rc != LOOM_OK) {
		snprintf(msg, msz, "%s", diag.message);
		return -1;
	}
	return export_record_file(c, w, name, msg, msz);
}

static int write_exr(struct export_ctx *c, struct ewstate *w, const char *stem,
                     const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	static const char *const names[N_CH][3] = {
		{"density"}, {"orientation.x", "orientation.y", "orientation.z"},
		{"R", "G", "B"}, {"kind"}, {"type"}};
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	loom_exr_channel chans[9];
	uint32_t nch = 0;
	float tmp[3 * 4096];
	loom_diag diag;

	for (int ch = 0; ch < N_CH; ch++)
		if (c->chmask & 1u << ch)
			for (unsigned q = 0; q < ch_comps[ch]; q++) {
				chans[nch].name = names[ch][q];
				chans[nch].pixel = LOOM_EXR_FLOAT;
				nch++;
			}
	cli_diag_init(&diag, NULL);
	for (size_t z = 0; z < nz; z++) {
		loom_exr_options o = LOOM_EXR_OPTIONS_INIT;
		loom_exr_writer *ew = NULL;
		char name[512], path[4096];
		int64_t az = lo[2] + (int64_t)z;

		snprintf(name, sizeof name, "%s.z%lld.exr", stem, (long long)az);
		snprintf(path, sizeof path, "%s/%s", c->dir, name);
		o.has_slice = 1;
		o.slice_z = (int32_t)az;
		for (int a = 0; a < 3; a++)
			o.voxel_mm[a] = c->vmm;
		o.origin_mm[0] = ((double)lo[0] + 0.5) * c->vmm;
		o.origin_mm[1] = ((double)lo[1] + 0.5) * c->vmm;
		o.origin_mm[2] = ((double)az + 0.5) * c->vmm;
		if (loom_exr_writer_open(path, (uint32_t)nx, (uint32_t)ny, chans, nch, &o, &ew,
		                         &diag) != LOOM_OK)
			goto fail;
		for (size_t y = 0; y < ny; y++) {
			size_t off = (z * ny + y) * nx;
			/* interleave the channels of the row, 4096 voxels at a time */
			for (size_t x0 = 0; x0 < nx; x0 += 4096) {
				size_t m = nx - x0 < 4096 ? nx - x0 : 4096;
				uint32_t base = 0;
				for (int ch = 0; ch < N_CH; ch++) {
					if (!(c->chmask & 1u << ch))
						continue;
					fill_row(c, w, ch, off + x0, m, tmp);
					for (size_t i = 0; i < m; i++)
						for (unsigned q = 0; q < ch_comps[ch]; q++)
							w->row[(x0 + i) * nch + base + q] = tmp[i * ch_comps[ch] + q];
					base += ch_comps[ch];
				}
			}
			if (loom_exr_writer_put_rows(ew, w->row, 1, &diag) != LOOM_OK)
				goto fail;
		}
		if (loom_exr_writer_finish(ew, &diag) != LOOM_OK)
			goto fail_done;
		if (export_record_file(c, w, name, msg, msz))
			return -1;
		continue;
	fail:
		loom_exr_writer_abort(ew);
	fail_done:
		snprintf(msg, msz, "%s", diag.message);
		return -1;
	}
	return 0;
}

/* One .vdb or .nvdb file per tile with a grid per chosen channel. */
static int write_vdb(struct export_ctx *c, struct ewstate *w, const char *stem,
                     const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	int nano = c->format == F_NVDB;
	loom__vdb *v = NULL;
	loom_diag diag;
	char name[512], path[4096];

	snprintf(name, sizeof name, "%s.%s", stem, nano ? "nvdb" : "vdb");
	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	cli_diag_init(&diag, NULL);
	if (loom__vdb_open(&v, nano ? LOOM__VDB_NANOVDB : LOOM__VDB_OPENVDB, c->codec,
	                   c->vmm, &diag) != LOOM_OK)
		goto fail;
	for (int ch = 0; ch < N_CH; ch++) {
		int kind = ch_comps[ch] == 3 ? LOOM__VDB_VEC3
		           : ch == CH_DENSITY ? LOOM__VDB_FLOAT : LOOM__VDB_INT32;
		if (!(c->chmask & 1u << ch))
			continue;
		if (loom__vdb_grid(v, vdb_grid_names[ch], kind, lo, hi, &diag) != LOOM_OK)
			goto fail;
		for (size_t z = 0; z < nz; z++)
			for (size_t y = 0; y < ny; y++) {
				fill_row(c, w, ch, (z * ny + y) * nx, nx, w->row);
				if (loom__vdb_row(v, lo[0], lo[1] + (int64_t)y, lo[2] + (int64_t)z, nx,
				                  w->row, &diag) != LOOM_OK)
					goto fail;
			}
	}
	if (loom__vdb_write(v, path, &diag) != LOOM_OK)
		goto fail;
	loom__vdb_free(v);
	return export_record_file(c, w, name, msg, msz);
fail:
	loom__vdb_free(v);
	snprintf(msg, msz, "%s", diag.message);
	return -1;
}

/* ---- dispatch ----------------------------------------------------------------- */

int export_write_tile(struct export_ctx *c, struct ewstate *w, const char *stem,
                      const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	if (c->format == F_EXR) {
		if (write_exr(c, w, stem, lo, hi, msg, msz))
			return -1;
	} else if (c->format == F_VDB || c->format == F_NVDB) {
		if (write_vdb(c, w, stem, lo, hi, msg, msz))
			return -1;
	} else {
		for (int ch = 0; ch < N_CH; ch++) {
			if (!(c->chmask & 1u << ch))
				continue;
			if ((c->format == F_VOL ? write_vol : write_nrrd)(c, w, stem, ch, lo, hi,
			                                                  msg, msz))
				return -1;
		}
	}
	return 0;
}
