/*
 * tests/unit/test_fidelity.c - the woven ground truth of a design
 * (loom_exgen_write_design) and the identity fabric that copies it
 * (LOOM_SYNTH_IDENTITY): brute force, voxel by voxel (docs/fidelity.md).
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"

#include <unistd.h>

/* A design of rows x cols with a broken-twill-like pattern (not periodic
   with a small repeat, so a shifted copy would be caught). */
static loom_design *make_design(uint32_t rows, uint32_t cols)
{
	loom_design *d = NULL;
	if (loom_design_new(rows, cols, &d) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++)
			d->weave[(size_t)i * cols + j] =
			        (uint8_t)(((i + (j / 3 % 2 ? cols - j : j)) % 4) < 2);
	return d;
}

/* Identity fabric: every voxel of the repeat equals the exemplar's. */
static void identity_copies_ground_truth(void)
{
	loom_exgen_params p;
	loom_design *d = make_design(7, 9);
	loom_db *db = NULL;
	loom_db_exemplar_info e;
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_diag diag = {0};
	const char *path = tpath("gt.ldb");
	uint32_t org[3] = {0, 0, 0}, size[3];
	size_t n, diff = 0, nonempty = 0;
	uint8_t *dd, *dl, *td, *tl;
	uint16_t *dor, *tor;

	CHECK(d != NULL);
	CHECK_EQ_INT(loom_exgen_preset("tiny", &p), LOOM_OK);
	p.seed = 7;
	CHECK_EQ_INT(loom_exgen_write_design(path, &p, "gt", d->rows, d->cols, d->weave,
	                                     NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(path, &db, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_db_exemplar(db, 0, &e), LOOM_OK);
	CHECK_EQ_INT(e.rows, 7);
	CHECK_EQ_INT(e.cols, 9);
	CHECK(memcmp(e.weave, d->weave, 63) == 0);
	CHECK_STR_CONTAINS(e.name, "gt");
	o.algo = LOOM_SYNTH_IDENTITY;
	o.group = 0;
	o.rank = 0;
	CHECK_EQ_INT(loom_fabric_synthesize(d, db, path, &o, &f, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_texture_open(f, db, NULL, &t, &diag), LOOM_OK);
	memcpy(size, e.size, sizeof size);
	n = (size_t)size[0] * size[1] * size[2];
	dd = malloc(n);
	dl = malloc(n);
	td = calloc(n, 1);
	tl = calloc(n, 1);
	dor = malloc(2 * n);
	tor = calloc(n, 2);
	CHECK(dd && dl && td && tl && dor && tor);
	CHECK_EQ_INT(loom_db_read_box(db, 0, org, size, dd, dor, dl, &diag), LOOM_OK);
	{
		int64_t lo[3] = {0, 0, 0}, hi[3] = {size[0], size[1], size[2]};
		loom_texture_region r = {0};
		r.density = td;
		r.orientation = tor;
		r.label = tl;
		r.layout = LOOM_REGION_X_FASTEST;
		CHECK_EQ_INT(loom_texture_read_region(t, lo, hi, &r), LOOM_OK);
	}
	for (size_t k = 0; k < n; k++) {
		diff += dd[k] != td[k] || dl[k] != tl[k] || (dd[k] && dor[k] != tor[k]);
		nonempty += dd[k] != 0;
	}
	CHECK_EQ_INT(diff, 0);
	CHECK(nonempty > n / 10);
	/* the next repeat of the bolt is the same cloth again */
	{
		loom_texel a, b;
		CHECK_EQ_INT(loom_texture_voxel(t, 5, 7, size[2] / 2, &a), LOOM_OK);
		CHECK_EQ_INT(loom_texture_voxel(t, 5 + size[0], 7 + 2 * (int64_t)size[1],
		                                size[2] / 2, &b), LOOM_OK);
		CHECK(a.density == b.density && a.kind == b.kind);
	}
	loom_texture_close(t);
	loom_fabric_free(f);
	/* identity on another design: refused, naming the crossing */
	{
		loom_design *d2 = make_design(7, 9);
		d2->weave[3 * 9 + 4] ^= 1;
		CHECK_EQ_INT(loom_fabric_synthesize(d2, db, path, &o, &f, &diag),
		             LOOM_EMISMATCH);
		CHECK_STR_CONTAINS(diag.message, "pick 4, end 5");
		loom_design_free(d2);
		d2 = make_design(8, 9);
		CHECK_EQ_INT(loom_fabric_synthesize(d2, db, path, &o, &f, &diag),
		             LOOM_EMISMATCH);
		CHECK_STR_CONTAINS(diag.message, "8x9");
		loom_design_free(d2);
	}
	free(dd);
	free(dl);
	free(td);
	free(tl);
	free(dor);
	free(tor);
	loom_db_close(db);
	loom_design_free(d);
	unlink(path);
}

/* Big designs: more yarns than labels share labels with the right kind;
   past the limit an error gives it. */
static void large_design_and_limit(void)
{
	loom_exgen_params p;
	loom_design *d = make_design(120, 125);
	loom_db *db = NULL;
	loom_db_exemplar_info e;
	loom_diag diag = {0};
	const char *path = tpath("big.ldb");
	uint8_t *w;

	CHECK_EQ_INT(loom_exgen_preset("tiny", &p), LOOM_OK);
	p.block[2] = 8;
	CHECK_EQ_INT(loom_exgen_write_design(path, &p, NULL, d->rows, d->cols, d->weave,
	                                     NULL, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(path, &db, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_db_exemplar(db, 0, &e), LOOM_OK);
	CHECK_EQ_INT(e.rows, 120);
	CHECK_EQ_INT(e.cols, 125);
	CHECK(e.n_yarns <= 255);
	/* every label's kind: warp labels first, then weft labels */
	for (uint32_t l = 1; l <= e.n_yarns; l++)
		CHECK(e.yarns[l].kind == LOOM_YARN_WARP || e.yarns[l].kind == LOOM_YARN_WEFT);
	CHECK_EQ_INT(loom_db_verify(db, NULL, NULL, &diag), LOOM_OK);
	loom_db_close(db);
	unlink(path);
	loom_design_free(d);
	/* the limit: 65536 voxels a side at block 8 = 1024 crossings; 1025 fails */
	CHECK_EQ_INT(loom_exgen_design_limit(8), 1024);
	CHECK_EQ_INT(loom_exgen_design_limit(115), 569);
	w = calloc(1025, 1);
	CHECK_EQ_INT(loom_exgen_write_design(path, &p, NULL, 1, 1025, w, NULL, &diag),
	             LOOM_ERANGE);
	CHECK_STR_CONTAINS(diag.message, "1024");
	CHECK(access(path, F_OK) != 0);
	free(w);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_fidelity");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(identity_copies_ground_truth);
	RUN(large_design_and_limit);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
