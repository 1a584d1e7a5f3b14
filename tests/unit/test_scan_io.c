/*
 * tests/unit/test_scan_io.c - scans from files into databases: every input
 * format loom exemplar build reads (Mitsuba .vol uint8 / float32 density,
 * orientation float32 x3 / quantized encoding 4, NRRD, raw u16) goes
 * through loom_scan_build with the weave, rotation, crop and labels checked
 * against the sheet's ground truth (labels >= 97%); loom_scan_write_db
 * creates a database and appends to one, leaving the existing exemplars
 * byte-identical.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"
#include "test_scan_synth.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const uint8_t TWILL23[25] = {1, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0,
                                    0, 0, 1, 1, 0, 0, 0, 0, 1, 1};

/* the small sheet, turned by angle, with truth labels and tangents */
static int make_sheet(loom_scan_sheet *s, float angle, uint64_t seed,
                      loom_scan_volume *v, uint8_t **truth)
{
	loom_scan_sheet_preset("small", s);
	s->weave = TWILL23;
	s->rep_rows = s->rep_cols = 5;
	s->angle_deg = angle;
	s->seed = seed;
	if (loom_scan_volume_alloc(v, s->nx, s->ny, s->nz,
	                           LOOM_SCAN_DENSITY | LOOM_SCAN_ORIENT) != LOOM_OK)
		return -1;
	*truth = malloc((size_t)s->nx * s->ny * s->nz);
	if (!*truth)
		return -1;
	return loom_scan_sheet_make(s, v, *truth, 2, NULL);
}

static int write_vol(const char *path, const float *data, const loom_scan_sheet *s,
                     uint32_t ch, int enc)
{
	loom_vol_header h;
	loom_vol_writer *w;
	memset(&h, 0, sizeof h);
	h.encoding = enc;
	h.xres = s->nx;
	h.yres = s->ny;
	h.zres = s->nz;
	h.channels = ch;
	h.bbox_max[0] = h.bbox_max[1] = h.bbox_max[2] = 1;
	if (loom_vol_writer_open(path, &h, &w, NULL))
		return -1;
	if (loom_vol_writer_put_slices(w, data, s->nz, NULL)) {
		loom_vol_writer_abort(w);
		return -1;
	}
	return loom_vol_writer_finish(w, NULL) ? -1 : 0;
}

/* take the floats out of a volbuf */
static float *steal(loom_volbuf *b)
{
	float *d = b ? b->data : NULL;
	if (b)
		b->data = NULL;
	loom_volbuf_free(b);
	return d;
}

/* Run the pipeline on v (consumed) and check against the truth. */
static void check_build(const char *what, const loom_scan_sheet *s, loom_scan_volume *v,
                        const uint8_t *truth, double *label_acc)
{
	loom_scan_params p;
	loom_scan_result *r = NULL;
	loom_scan_sheet_grid g;
	loom_diag d = {0};
	double acc[2];
	uint32_t bad = 0;
	int rc;

	loom_scan_params_init(&p);
	p.n_warps = s->nw;
	p.n_wefts = s->nf;
	rc = loom_scan_build(v, &p, &r, &d);
	if (rc)
		printf("  %s: %s\n", what, d.message);
	CHECK_EQ_INT(rc, LOOM_OK);
	CHECK_EQ_INT(loom_scan_sheet_truth(s, &g), LOOM_OK);
	if (!r)
		return;
	CHECK_EQ_INT(r->rows, g.rows);
	CHECK_EQ_INT(r->cols, g.cols);
	CHECK_EQ_INT(r->grid.first_warp, g.first_warp);
	CHECK_EQ_INT(r->grid.first_weft, g.first_weft);
	for (uint32_t i = 0; i < r->rows && i < g.rows; i++)
		for (uint32_t j = 0; j < r->cols && j < g.cols; j++)
			bad += r->weave[i * r->cols + j] !=
			       loom_scan_sheet_w(s, g.first_weft + i, g.first_warp + j);
	CHECK_EQ_INT(bad, 0);
	CHECK(fabs(r->rotation_degrees - s->angle_deg) <= 0.5);
	for (int k = 0; k < 4; k++)
		CHECK(fabs(r->grid.crop[k] - g.crop[k]) <= 2);
	CHECK_EQ_INT(synth_scan_accuracy(v, truth, s->nw, r, acc, 0), LOOM_OK);
	printf("  %-34s rotation %.3f (true %.1f), crop %d %d (true %.1f %.1f), "
	       "labels %.2f%% (%.2f%% above the threshold)\n", what, r->rotation_degrees,
	       (double)s->angle_deg, r->grid.crop[0], r->grid.crop[1], g.crop[0], g.crop[1],
	       100 * acc[0], 100 * acc[1]);
	CHECK(acc[1] >= 0.97);
	CHECK(acc[0] >= 0.96);
	if (label_acc)
		*label_acc = acc[1];
	loom_scan_result_free(r);
}

static void formats(void)
{
	loom_scan_sheet s;
	loom_scan_volume v, in;
	uint8_t *truth = NULL;
	size_t n;
	loom_volbuf *b = NULL;
	loom_diag d = {0};

	CHECK(make_sheet(&s, 2.2f, 11, &v, &truth) == 0);
	n = (size_t)s.nx * s.ny * s.nz;

	/* 1. .vol uint8 density + float32 x3 orientation */
	CHECK(write_vol(tpath("d8.vol"), v.density, &s, 1, LOOM_VOL_UINT8) == 0);
	CHECK(write_vol(tpath("of.vol"), v.orient, &s, 3, LOOM_VOL_FLOAT32) == 0);
	memset(&in, 0, sizeof in);
	in.nx = s.nx;
	in.ny = s.ny;
	in.nz = s.nz;
	CHECK_EQ_INT(loom_vol_read(tpath("d8.vol"), SIZE_MAX, NULL, &b, &d), LOOM_OK);
	in.density = steal(b);
	CHECK_EQ_INT(loom_vol_read(tpath("of.vol"), SIZE_MAX, NULL, &b, &d), LOOM_OK);
	in.orient = steal(b);
	check_build(".vol u8 + orientation f32x3", &s, &in, truth, NULL);
	loom_scan_volume_release(&in);

	/* 2. .vol float32 density + quantized directions (encoding 4) */
	CHECK(write_vol(tpath("df.vol"), v.density, &s, 1, LOOM_VOL_FLOAT32) == 0);
	CHECK(write_vol(tpath("oq.vol"), v.orient, &s, 3, LOOM_VOL_QDIR) == 0);
	in.nx = s.nx;
	in.ny = s.ny;
	in.nz = s.nz;
	CHECK_EQ_INT(loom_vol_read(tpath("df.vol"), SIZE_MAX, NULL, &b, &d), LOOM_OK);
	in.density = steal(b);
	CHECK_EQ_INT(loom_vol_read(tpath("oq.vol"), SIZE_MAX, NULL, &b, &d), LOOM_OK);
	in.orient = steal(b);
	check_build(".vol f32 + orientation qdir", &s, &in, truth, NULL);
	loom_scan_volume_release(&in);

	/* 3. NRRD float density, orientation estimated */
	{
		FILE *fp = fopen(tpath("d.nrrd"), "wb");
		CHECK(fp != NULL);
		if (fp) {
			fprintf(fp, "NRRD0004\ntype: float\ndimension: 3\nsizes: %u %u %u\n"
			        "encoding: raw\nendian: little\n\n", s.nx, s.ny, s.nz);
			CHECK(fwrite(v.density, sizeof(float), n, fp) == n);
			fclose(fp);
		}
		in.nx = s.nx;
		in.ny = s.ny;
		in.nz = s.nz;
		CHECK_EQ_INT(loom_nrrd_read(tpath("d.nrrd"), SIZE_MAX, NULL, &b, &d), LOOM_OK);
		in.density = steal(b);
		in.orient = NULL;
		check_build("NRRD f32, orientation estimated", &s, &in, truth, NULL);
		loom_scan_volume_release(&in);
	}

	/* 4. raw u16 (normalised), orientation estimated */
	{
		loom_raw_params rp = LOOM_RAW_PARAMS_INIT;
		uint16_t *u = malloc(n * sizeof *u);
		FILE *fp = fopen(tpath("d16.raw"), "wb");
		CHECK(u && fp);
		if (u && fp) {
			for (size_t i = 0; i < n; i++)
				u[i] = (uint16_t)lrintf(v.density[i] * 65535);
			CHECK(fwrite(u, 2, n, fp) == n);
		}
		if (fp)
			fclose(fp);
		free(u);
		rp.nx = s.nx;
		rp.ny = s.ny;
		rp.nz = s.nz;
		rp.type = LOOM_SCALAR_U16;
		rp.flags = LOOM_RAW_NORMALIZE;
		in.nx = s.nx;
		in.ny = s.ny;
		in.nz = s.nz;
		CHECK_EQ_INT(loom_raw_read(tpath("d16.raw"), &rp, SIZE_MAX, &b, &d), LOOM_OK);
		in.density = steal(b);
		in.orient = NULL;
		check_build("raw u16, orientation estimated", &s, &in, truth, NULL);
		loom_scan_volume_release(&in);
	}
	loom_scan_volume_release(&v);
	free(truth);
}

/* ---- database: create, append ------------------------------------------ */

static uint64_t le64(const uint8_t *p)
{
	uint64_t v = 0;
	for (int k = 7; k >= 0; k--)
		v = v << 8 | p[k];
	return v;
}

/* every voxel, tables and facts of exemplar k of a and b agree */
/* Exemplar ka of a and kb of b: the same records, tables and voxels, and
   (same_storage) the same stored bytes. */
static int same_exemplar_as(const loom_db *a, uint32_t ka, const loom_db *b, uint32_t kb,
                            int same_storage)
{
	loom_db_exemplar_info ea, eb;
	uint32_t o[3] = {0, 0, 0};
	size_t nv, ok = 1;
	uint8_t *da, *db_, *la, *lb;
	uint16_t *oa, *ob;
	loom_diag d = {0};

	if (loom_db_exemplar(a, ka, &ea) || loom_db_exemplar(b, kb, &eb))
		return 0;
	if (strcmp(ea.name, eb.name) || strcmp(ea.weave_name, eb.weave_name) ||
	    ea.rows != eb.rows || ea.cols != eb.cols || ea.n_yarns != eb.n_yarns ||
	    ea.n_symmetries != eb.n_symmetries || ea.first_brick != eb.first_brick ||
	    (same_storage && ea.stored_bytes != eb.stored_bytes) ||
	    memcmp(ea.weave, eb.weave, (size_t)ea.rows * ea.cols) ||
	    memcmp(ea.yarns, eb.yarns, (ea.n_yarns + 1) * sizeof *ea.yarns) ||
	    memcmp(ea.symmetries, eb.symmetries, 4 * (size_t)ea.n_symmetries) ||
	    memcmp(ea.size, eb.size, sizeof ea.size))
		return 0;
	for (uint32_t r = 0; r < ea.rows; r++)
		for (uint32_t c = 0; c < ea.cols; c++) {
			loom_db_block_info x, y;
			if (loom_db_block(a, ka, r, c, &x) || loom_db_block(b, kb, r, c, &y))
				return 0;
			if (x.code != y.code || x.centre_kind != y.centre_kind ||
			    x.gap_columns != y.gap_columns || x.mean_dh_x != y.mean_dh_x ||
			    x.mean_dh_y != y.mean_dh_y || x.mean_height != y.mean_height ||
			    memcmp(x.north, y.north, ea.block[0] * sizeof(float)) ||
			    memcmp(x.south, y.south, ea.block[0] * sizeof(float)) ||
			    memcmp(x.west, y.west, ea.block[1] * sizeof(float)) ||
			    memcmp(x.east, y.east, ea.block[1] * sizeof(float)))
				return 0;
		}
	nv = (size_t)ea.size[0] * ea.size[1] * ea.size[2];
	da = malloc(nv);
	db_ = malloc(nv);
	la = malloc(nv);
	lb = malloc(nv);
	oa = malloc(2 * nv);
	ob = malloc(2 * nv);
	if (!da || !db_ || !la || !lb || !oa || !ob ||
	    loom_db_read_box(a, ka, o, ea.size, da, oa, la, &d) ||
	    loom_db_read_box(b, kb, o, eb.size, db_, ob, lb, &d) || memcmp(da, db_, nv) ||
	    memcmp(la, lb, nv) || memcmp(oa, ob, 2 * nv))
		ok = 0;
	free(da);
	free(db_);
	free(la);
	free(lb);
	free(oa);
	free(ob);
	return (int)ok;
}

static int same_exemplar(const loom_db *a, uint32_t ka, const loom_db *b, uint32_t kb)
{
	return same_exemplar_as(a, ka, b, kb, 1);
}

static void database_append(void)
{
	loom_scan_sheet s;
	loom_scan_volume v;
	uint8_t *truth = NULL, *old = NULL, *neu = NULL;
	size_t old_len, new_len, old_len2;
	loom_scan_params p;
	loom_scan_result *r = NULL;
	loom_scan_db_params dp;
	loom_exgen_params gp;
	loom_db *a = NULL, *b = NULL;
	loom_db_info ia, ib;
	loom_db_exemplar_info e;
	loom_diag d = {0};
	int appended = -1, rc;
	const char *db = tpath("gen.ldb"), *copy = tpath("gen0.ldb");

	CHECK(make_sheet(&s, -1.8f, 12, &v, &truth) == 0);
	free(v.orient);
	v.orient = NULL;
	loom_scan_params_init(&p);
	p.n_warps = s.nw;
	p.n_wefts = s.nf;
	CHECK_EQ_INT(loom_scan_build(&v, &p, &r, &d), LOOM_OK);
	if (!r) {
		printf("  build failed: %s\n", d.message);
		loom_scan_volume_release(&v);
		free(truth);
		return;
	}
	CHECK_EQ_INT(r->b1, 24);
	CHECK_EQ_INT(r->b2, 18);
	CHECK_EQ_INT(r->b3, 40);

	/* a generated database with the same blocks */
	CHECK_EQ_INT(loom_exgen_preset("small", &gp), LOOM_OK);
	gp.block[0] = 24;
	gp.block[1] = 18;
	gp.block[2] = 40;
	gp.n_weaves = 2;
	gp.weaves[0] = "plain";
	gp.weaves[1] = "twill:2/3";
	CHECK_EQ_INT(loom_exgen_write_db(db, &gp, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_exgen_write_db(copy, &gp, NULL, &d), LOOM_OK);
	old = slurp(db, &old_len);
	CHECK(old && old_len > 192);

	/* a labelled voxel of density that quantises to 0 (a volume built
	   elsewhere, or a threshold below 1/510): it keeps its label, and its
	   orientation code is 0 like every voxel of density 0 */
	for (size_t i = 0; r->volume.label && i < (size_t)r->volume.nx * r->volume.ny * r->volume.nz;
	     i++)
		if (r->volume.label[i] && r->volume.density[i] > 0.5f &&
		    (r->volume.ocode ? r->volume.ocode[i] != 0 : r->volume.orient != NULL)) {
			r->volume.density[i] = 1e-4f;
			break;
		}
	loom_scan_db_params_init(&dp);
	dp.name = "scan-twill";
	dp.weave_name = "twill:2/3";
	dp.voxel_size_um = 24;
	CHECK_EQ_INT(loom_scan_write_db(r, db, &dp, &appended, &d), LOOM_OK);
	CHECK_EQ_INT(appended, 1);
	neu = slurp(db, &new_len);
	CHECK(neu && old && new_len > old_len);
	if (neu && old && old_len > 64) {
		/* the old brick data sit at the same offsets, byte for byte */
		uint64_t meta_off = le64(old + old_len - 64 + 8);
		CHECK(meta_off <= old_len && meta_off <= new_len);
		CHECK(memcmp(old + 128, neu + 128, meta_off - 128) == 0);
		CHECK(memcmp(old, neu, 16) == 0); /* magic, version, header size */
	}
	CHECK_EQ_INT(loom_db_open(copy, &a, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(db, &b, &d), LOOM_OK);
	if (a && b) {
		loom_db_get_info(a, &ia);
		loom_db_get_info(b, &ib);
		CHECK_EQ_INT(ib.n_exemplars, 3);
		CHECK(ib.content_hash != ia.content_hash);
		CHECK(same_exemplar(a, 0, b, 0));
		CHECK(same_exemplar(a, 1, b, 1));
		CHECK_EQ_INT(loom_db_verify(b, NULL, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(loom_db_exemplar(b, 2, &e), LOOM_OK);
		CHECK(strcmp(e.name, "scan-twill") == 0);
		CHECK_EQ_INT(e.rows, r->rows);
		CHECK_EQ_INT(e.cols, r->cols);
		CHECK(memcmp(e.weave, r->weave, (size_t)r->rows * r->cols) == 0);
		CHECK_EQ_INT(e.n_yarns, r->n_yarns);
		/* the voxels are the result's, quantised */
		{
			size_t nv = (size_t)e.size[0] * e.size[1] * e.size[2], bad = 0;
			uint32_t o[3] = {0, 0, 0};
			size_t labelled_air = 0, oriented_air = 0;
			uint8_t *dd = malloc(nv), *ll = malloc(nv);
			uint16_t *oo = malloc(2 * nv);
			CHECK(dd && ll && oo);
			if (dd && ll && oo) {
				CHECK_EQ_INT(loom_db_read_box(b, 2, o, e.size, dd, oo, ll, &d), LOOM_OK);
				for (size_t i = 0; i < nv; i++) {
					float x = r->volume.density[i];
					uint8_t q = !(x > 0) ? 0 : x >= 1 ? 255 : (uint8_t)(x * 255 + 0.5f);
					bad += dd[i] != q || ll[i] != r->volume.label[i];
					/* a voxel of density 0 has orientation code 0 (what
					   point lookups report there, and what region reads
					   copy), labelled or not */
					if (!q && r->volume.label[i])
						labelled_air++;
					oriented_air += !q && oo[i] != 0;
				}
			}
			printf("  %zu voxels of density 0 with a label, %zu with an orientation\n",
			       labelled_air, oriented_air);
			CHECK_EQ_INT(bad, 0);
			CHECK(labelled_air > 0);
			CHECK_EQ_INT(oriented_air, 0);
			free(dd);
			free(ll);
			free(oo);
		}
	}
	loom_db_close(a);
	loom_db_close(b);

	/* the same name again: refused, file untouched */
	rc = loom_scan_write_db(r, db, &dp, &appended, &d);
	CHECK_EQ_INT(rc, LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "already named");
	free(old);
	old = slurp(db, &old_len2);
	CHECK(old && neu && old_len2 == new_len && memcmp(old, neu, new_len) == 0);

	/* other blocks: refused, file untouched */
	CHECK_EQ_INT(loom_exgen_preset("small", &gp), LOOM_OK);
	gp.n_weaves = 1;
	CHECK_EQ_INT(loom_exgen_write_db(copy, &gp, NULL, &d), LOOM_OK);
	free(old);
	old = slurp(copy, &old_len);
	dp.name = "other";
	rc = loom_scan_write_db(r, copy, &dp, &appended, &d);
	CHECK_EQ_INT(rc, LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(d.message, "blocks are 24x16x48");
	free(neu);
	neu = slurp(copy, &new_len);
	CHECK(old && neu && old_len == new_len && memcmp(old, neu, new_len) == 0);

	/* a new database */
	rc = loom_scan_write_db(r, tpath("new.ldb"), &dp, &appended, &d);
	CHECK_EQ_INT(rc, LOOM_OK);
	CHECK_EQ_INT(appended, 0);
	CHECK_EQ_INT(loom_db_open(tpath("new.ldb"), &a, &d), LOOM_OK);
	if (a) {
		loom_db_get_info(a, &ia);
		CHECK_EQ_INT(ia.n_exemplars, 1);
		CHECK_EQ_INT(ia.block[0], 24);
		CHECK_EQ_INT(ia.block[1], 18);
		CHECK_EQ_INT(ia.block[2], 40);
		CHECK(fabsf(ia.voxel_size_um - 24) < 1e-4f);
		CHECK_EQ_INT(loom_db_verify(a, NULL, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(ia.version, 4);
		CHECK_EQ_INT(ia.n_raw_density, 0);
		loom_db_close(a);
	}

	/* storage of a new database: version 3, density raw; the same voxels */
	dp.db_version = 1;
	dp.density_raw = 1;
	CHECK_EQ_INT(loom_scan_write_db(r, tpath("raw.ldb"), &dp, &appended, &d), LOOM_EINVAL);
	dp.db_version = 5;
	dp.density_raw = 0;
	CHECK_EQ_INT(loom_scan_write_db(r, tpath("raw.ldb"), &dp, &appended, &d), LOOM_EINVAL);
	dp.db_version = 3;
	dp.density_raw = 1;
	CHECK_EQ_INT(loom_scan_write_db(r, tpath("raw.ldb"), &dp, &appended, &d), LOOM_OK);
	a = b = NULL;
	CHECK_EQ_INT(loom_db_open(tpath("new.ldb"), &a, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(tpath("raw.ldb"), &b, &d), LOOM_OK);
	if (a && b) {
		loom_db_get_info(b, &ib);
		CHECK_EQ_INT(ib.version, 3);
		CHECK(ib.n_raw_density > 0);
		CHECK_EQ_INT(ib.n_raw_density, ib.n_bricks - ib.n_empty_bricks);
		CHECK(same_exemplar_as(a, 0, b, 0, 0));
		CHECK_EQ_INT(loom_db_verify(b, NULL, NULL, &d), LOOM_OK);
	}
	loom_db_close(a);
	loom_db_close(b);
	/* appending keeps a database's storage; asking for another is refused,
	   the file untouched */
	free(old);
	old = slurp(tpath("new.ldb"), &old_len);
	dp.name = "again";
	rc = loom_scan_write_db(r, tpath("new.ldb"), &dp, &appended, &d);
	CHECK_EQ_INT(rc, LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(d.message, "density planes are compressed");
	dp.density_raw = 0;
	rc = loom_scan_write_db(r, tpath("new.ldb"), &dp, &appended, &d);
	CHECK_EQ_INT(rc, LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(d.message, "format version 4, not 3");
	free(neu);
	neu = slurp(tpath("new.ldb"), &new_len);
	CHECK(old && neu && old_len == new_len && memcmp(old, neu, new_len) == 0);
	dp.db_version = 0;
	CHECK_EQ_INT(loom_scan_write_db(r, tpath("raw.ldb"), &dp, &appended, &d), LOOM_OK);
	CHECK_EQ_INT(appended, 1);
	CHECK_EQ_INT(loom_db_open(tpath("raw.ldb"), &b, &d), LOOM_OK);
	if (b) {
		loom_db_get_info(b, &ib);
		CHECK_EQ_INT(ib.n_exemplars, 2);
		CHECK_EQ_INT(ib.version, 3);
		CHECK_EQ_INT(ib.n_raw_density, ib.n_bricks - ib.n_empty_bricks);
		loom_db_close(b);
	}
	free(old);
	free(neu);
	loom_scan_result_free(r);
	loom_scan_volume_release(&v);
	free(truth);
}

static void sheet_truth_and_determinism(void)
{
	loom_scan_sheet s;
	loom_scan_sheet_grid g;
	loom_scan_volume a, b;
	uint8_t *ta = NULL, *tb = NULL;
	size_t n;

	CHECK_EQ_INT(loom_scan_sheet_preset("frob", &s), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_sheet_preset("paper:10", &s), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_sheet_preset("paper", &s), LOOM_OK);
	CHECK_EQ_INT(s.nx, 1000);
	CHECK_EQ_INT(s.nz, 300);
	CHECK(fabsf(s.sx - 115) < 1e-3f && fabsf(s.sy - 70) < 1e-3f);
	/* unrotated small sheet, 160 voxels wide: warps at 6 + 24 j, cells
	   [c - 12, c + 12): warp 0's starts at -6 and warp 6's ends at 162
	   (outside), so the crop holds warps 1..5: x from 18, 120 wide */
	CHECK_EQ_INT(make_sheet(&s, 0, 1, &a, &ta), LOOM_OK);
	CHECK_EQ_INT(loom_scan_sheet_truth(&s, &g), LOOM_OK);
	CHECK_EQ_INT(g.first_warp, 1);
	CHECK_EQ_INT(g.cols, 5);
	CHECK(fabs(g.crop[0] - 18) < 1e-9 && fabs(g.crop[2] - 120) < 1e-9);
	CHECK_EQ_INT(loom_scan_sheet_w(&s, 0, 0), 1);
	CHECK_EQ_INT(loom_scan_sheet_w(&s, 0, 1), 0);
	CHECK_EQ_INT(loom_scan_sheet_w(&s, -1, 4), 1); /* wraps */
	/* the truth labels: warp 3's centre column is warp 3 at mid-height */
	{
		uint32_t x = (uint32_t)lroundf(s.x0 + 3 * s.sx), y = 80;
		int found = 0;
		for (uint32_t z = 0; z < s.nz; z++)
			found |= ta[((size_t)z * s.ny + y) * s.nx + x] == 4;
		CHECK(found);
	}
	/* thread count does not change the bytes */
	loom_scan_volume_release(&a);
	free(ta);
	CHECK(make_sheet(&s, 2, 5, &a, &ta) == 0);
	loom_scan_sheet_preset("small", &s);
	s.weave = TWILL23;
	s.rep_rows = s.rep_cols = 5;
	s.angle_deg = 2;
	s.seed = 5;
	n = (size_t)s.nx * s.ny * s.nz;
	CHECK_EQ_INT(loom_scan_volume_alloc(&b, s.nx, s.ny, s.nz,
	                                    LOOM_SCAN_DENSITY | LOOM_SCAN_ORIENT), LOOM_OK);
	tb = malloc(n);
	CHECK_EQ_INT(loom_scan_sheet_make(&s, &b, tb, 1, NULL), LOOM_OK);
	CHECK(memcmp(a.density, b.density, n * sizeof(float)) == 0);
	CHECK(memcmp(a.orient, b.orient, 3 * n * sizeof(float)) == 0);
	CHECK(memcmp(ta, tb, n) == 0);
	loom_scan_volume_release(&a);
	loom_scan_volume_release(&b);
	free(ta);
	free(tb);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_scan_io");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(sheet_truth_and_determinism);
	RUN(formats);
	RUN(database_append);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
