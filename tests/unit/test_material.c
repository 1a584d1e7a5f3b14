/*
 * tests/unit/test_material.c - materials per yarn type (docs/exemplars.md,
 * "Materials per yarn type"): databases of several material pairs, their
 * tags, and synthesis restricted to each crossing's pair.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"
#include "synth/fabric_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Small preset, two weaves; n_pairs 0: one pair (cotton), else cotton/cotton
   and silk/cotton. */
static int make_db(const char *path, int two, unsigned threads)
{
	loom_exgen_params p;
	loom_diag diag;
	int rc;

	loom_exgen_preset("small", &p);
	p.n_weaves = 2;
	p.weaves[0] = "twill:2/3";
	p.weaves[1] = "twill:3/2";
	p.threads = threads;
	if (two) {
		p.n_pairs = 2;
		p.pairs[0][0] = "cotton";
		p.pairs[0][1] = "cotton";
		p.pairs[1][0] = "silk";
		p.pairs[1][1] = "cotton";
	} else {
		p.fibre[0] = p.fibre[1] = "cotton";
	}
	rc = loom_exgen_write_db(path, &p, NULL, &diag);
	if (rc)
		printf("  make_db: %s\n", diag.message);
	return rc;
}

/* 15 x 15 crossings of a 2/3 twill; ends 5..9 are silk (type 2). */
#define STRIPE0 5
#define STRIPE1 10
static loom_design *stripe_design(void)
{
	loom_weave_params wp;
	loom_design *d = NULL;

	if (loom_weave_parse("twill:2/3", &wp, NULL) ||
	    loom_design_make(&wp, 15, 15, &d, NULL) || loom_design_set_types(d, 3))
		return NULL;
	snprintf(d->types[2].name, sizeof d->types[2].name, "silkwarp");
	d->types[2].fibre = LOOM_FIBRE_SILK;
	for (uint32_t i = 0; i < d->rows; i++)
		for (uint32_t j = STRIPE0; j < STRIPE1; j++)
			d->warp_type[(size_t)i * d->cols + j] = 2;
	return d;
}

static int in_stripe(int64_t J)
{
	int64_t j = ((J % 15) + 15) % 15;
	return j >= STRIPE0 && j < STRIPE1;
}

/* The tags; the one-pair database untagged; exemplars of a pair are the
   voxels of the one-pair database of that pair. */
static void test_tags(void)
{
	loom_db *one = NULL, *two = NULL;
	loom_db_exemplar_info e;
	size_t nv = 24 * 5 * 16 * 5 * 48;
	uint8_t *a = malloc(nv), *b = malloc(nv);
	uint32_t o[3] = {0, 0, 0}, sz[3] = {120, 80, 48};

	CHECK(loom_db_open(tpath("one.ldb"), &one, NULL) == LOOM_OK);
	CHECK(loom_db_open(tpath("two.ldb"), &two, NULL) == LOOM_OK);
	if (!one || !two || !a || !b)
		goto out;
	CHECK(loom_db_exemplar(one, 0, &e) == LOOM_OK);
	CHECK(e.fibre[0] == 0 && e.fibre[1] == 0);
	for (uint32_t k = 0; k < 4; k++) {
		CHECK(loom_db_exemplar(two, k, &e) == LOOM_OK);
		CHECK_EQ_INT(e.fibre[0], k < 2 ? LOOM_FIBRE_COTTON : LOOM_FIBRE_SILK);
		CHECK_EQ_INT(e.fibre[1], LOOM_FIBRE_COTTON);
		CHECK_STR_CONTAINS(e.name, k < 2 ? "@co-co" : "@si-co");
	}
	/* cotton/cotton exemplar 0 = the one-pair database's exemplar 0 */
	CHECK(loom_db_read_box(one, 0, o, sz, a, NULL, NULL, NULL) == LOOM_OK);
	CHECK(loom_db_read_box(two, 0, o, sz, b, NULL, NULL, NULL) == LOOM_OK);
	CHECK(memcmp(a, b, nv) == 0);
	/* the silk one differs */
	CHECK(loom_db_read_box(two, 2, o, sz, b, NULL, NULL, NULL) == LOOM_OK);
	CHECK(memcmp(a, b, nv) != 0);
out:
	free(a);
	free(b);
	loom_db_close(one);
	loom_db_close(two);
}

/* Density statistics of warp voxels: mean density and the fraction under
   0.25 (a fibre's edge or a lone fibre: hairs, loops, the fringe). */
typedef struct wstat {
	double n, sum, thin;
} wstat;

static void add(wstat *s, float dens)
{
	s->n += 1;
	s->sum += dens;
	s->thin += dens < 0.25f;
}

/* Every crossing of the bolt window copies an exemplar of its pair; the
   texture's warp voxels in the stripe have silk's statistics. */
static void test_synth_stripe(void)
{
	loom_db *two = NULL;
	loom_design *d = stripe_design();
	loom_fabric *f = NULL;
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag diag;
	wstat ex[2], tx[2];
	int bad = 0, silk_blocks = 0;

	memset(ex, 0, sizeof ex);
	memset(tx, 0, sizeof tx);
	CHECK(d != NULL);
	CHECK(loom_db_open(tpath("two.ldb"), &two, NULL) == LOOM_OK);
	if (!d || !two)
		goto out;
	CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f, &diag) == LOOM_OK);
	if (!f)
		goto out;
	for (int64_t I = -20; I < 25; I++)
		for (int64_t J = -20; J < 25; J++) {
			loom_fabric_source s;
			loom_db_exemplar_info e;
			CHECK(loom_fabric_source_at(f, I, J, &s) == LOOM_OK);
			loom_db_exemplar(two, s.exemplar, &e);
			if (e.fibre[0] != (in_stripe(J) ? LOOM_FIBRE_SILK : LOOM_FIBRE_COTTON) ||
			    e.fibre[1] != LOOM_FIBRE_COTTON)
				bad++;
			silk_blocks += e.fibre[0] == LOOM_FIBRE_SILK;
		}
	CHECK_EQ_INT(bad, 0);
	CHECK_EQ_INT(silk_blocks, 45 * 15); /* 3 stripes of 5 ends in 45 columns */
	{
		loom_fabric_metrics m;
		loom_fabric_get_metrics(f, &m);
		CHECK(m.repeat.correctness == 1.0);
	}
	/* statistics of the exemplars themselves: warp voxels by material */
	for (uint32_t k = 0; k < 4; k++) {
		uint32_t o3[3] = {0, 0, 0}, sz[3] = {120, 80, 48};
		size_t nv = 120 * 80 * 48;
		uint8_t *dn = malloc(nv), *lb = malloc(nv);
		loom_db_exemplar_info e;
		loom_db_exemplar(two, k, &e);
		if (dn && lb && loom_db_read_box(two, k, o3, sz, dn, NULL, lb, NULL) == LOOM_OK)
			for (size_t v = 0; v < nv; v++)
				if (dn[v] && e.yarns[lb[v]].kind == LOOM_YARN_WARP)
					add(&ex[k >= 2], dn[v] / 255.0f);
		free(dn);
		free(lb);
	}
	/* the same through the texture, over the design's first repeat */
	CHECK(loom_texture_open(f, two, NULL, &t, &diag) == LOOM_OK);
	if (t)
		for (int64_t I = 0; I < 15; I++)
			for (int64_t J = 0; J < 15; J++)
				for (int64_t y = I * 16; y < I * 16 + 16; y++)
					for (int64_t x = J * 24; x < J * 24 + 24; x++)
						for (int64_t z = 0; z < 48; z++) {
							loom_texel v;
							if (loom_texture_voxel(t, x, y, z, &v) != LOOM_OK) {
								bad++;
								continue;
							}
							if (v.kind == LOOM_YARN_WARP && v.density > 0)
								add(&tx[in_stripe(J)], v.density);
						}
	CHECK_EQ_INT(bad, 0);
	{
		double me[2], te[2], he[2], ht[2];
		for (int m = 0; m < 2; m++) {
			me[m] = ex[m].sum / ex[m].n;
			te[m] = tx[m].sum / tx[m].n;
			he[m] = ex[m].thin / ex[m].n;
			ht[m] = tx[m].thin / tx[m].n;
		}
		printf("  warp voxels: exemplars cotton mean %.4f thin %.4f, silk mean %.4f "
		       "thin %.4f; texture outside %.4f thin %.4f, stripe %.4f thin %.4f\n",
		       me[0], he[0], me[1], he[1], te[0], ht[0], te[1], ht[1]);
		/* Silk's fewer hairs and loops and tighter filaments leave fewer
		   thinly covered warp voxels than cotton's (exemplars: 0.188 against
		   0.231 at 24 um).  The texture's stripe shows the same drop from
		   the cotton around it (0.223 against 0.265; the texture's own
		   levels differ from the exemplars' by where the design's crossings
		   sample the blocks and the edge fix): the drop is at least 0.02 and
		   within half of the exemplars' drop, which copying cotton blocks
		   into the stripe (drop 0) or silk ones outside would break. */
		CHECK(he[0] - he[1] > 0.03);
		CHECK(ht[0] - ht[1] > 0.02);
		CHECK(fabs((ht[0] - ht[1]) - (he[0] - he[1])) < 0.5 * (he[0] - he[1]));
	}
out:
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(two);
}

/* Painting a weave over the stripe's border keeps every crossing's pair. */
static void test_reweave(void)
{
	loom_db *two = NULL;
	loom_design *d = stripe_design();
	loom_fabric *f = NULL;
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	uint8_t want[6 * 10];
	int bad = 0, changed = 0;

	CHECK(loom_db_open(tpath("two.ldb"), &two, NULL) == LOOM_OK);
	if (!two || !d)
		goto out;
	CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f, NULL) == LOOM_OK);
	if (!f)
		goto out;
	for (int r = 0; r < 6; r++) /* a 1/1 plain weave over ends 2..11 */
		for (int c = 0; c < 10; c++)
			want[r * 10 + c] = (uint8_t)(1 + ((r + c) & 1));
	CHECK(loom__fabric_reweave(&f, 3, 2, 6, 10, want, 2, 0, 0, NULL) == LOOM_OK);
	for (int64_t I = 1; I < 11; I++)
		for (int64_t J = 0; J < 14; J++) {
			loom_fabric_source s;
			loom_db_exemplar_info e;
			loom_fabric_source_at(f, I, J, &s);
			loom_db_exemplar(two, s.exemplar, &e);
			if (e.fibre[0] != (in_stripe(J) ? LOOM_FIBRE_SILK : LOOM_FIBRE_COTTON))
				bad++;
			if (I >= 3 && I < 9 && J >= 2 && J < 12) {
				/* painted: warp over where r + c is odd, i.e. I + J even */
				loom_synth_block b;
				loom_synth_block_info(f->set, s.block, &b);
				changed += (b.code & 1u) == (((I + J) & 1) == 0);
			}
		}
	CHECK_EQ_INT(bad, 0);
	CHECK_EQ_INT(changed, 60); /* the painted crossings copy plain-weave bits */
out:
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(two);
}

static int same_texel(const loom_texel *a, const loom_texel *b)
{
	return a->density == b->density && a->kind == b->kind && a->type == b->type &&
	       !memcmp(a->albedo, b->albedo, sizeof a->albedo) &&
	       !memcmp(a->orientation, b->orientation, sizeof a->orientation);
}

/* Painting a silk warp over cotton crossings (loom paint --yarn warp
   --fibre silk): the painted crossings copy silk/cotton blocks with the
   weave kept, the band keeps its pairs, everything else its sources, and
   the voxels change only at the re-assigned crossings and their four
   neighbours (brute force against the unpainted fabric); a pair the
   database lacks is LOOM_EMISMATCH naming it and the database's pairs. */
static void test_paint_fibre(void)
{
	const int64_t PI0 = 3, PI1 = 7, PJ0 = 1, PJ1 = 4, M = 3; /* painted, margin */
	const uint32_t band = 1;
	loom_db *two = NULL;
	loom_design *d = stripe_design();
	loom_fabric *f0 = NULL, *f = NULL;
	loom_texture *t0 = NULL, *t = NULL;
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_fabric_db_identity id;
	loom_paint *p = NULL, *q = NULL;
	loom_paint_region r;
	loom_diag diag;
	char *text = NULL;
	size_t len = 0;
	double vmm;
	uint64_t changed = 0, outside = 0, painted_silk = 0, band_kept = 0, rest_kept = 0;
	uint64_t bits_kept = 0, changed_painted = 0;

	memset(&diag, 0, sizeof diag);
	CHECK(loom_db_open(tpath("two.ldb"), &two, NULL) == LOOM_OK);
	if (!two || !d)
		goto out;
	CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f0, NULL) == LOOM_OK);
	CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f, NULL) == LOOM_OK);
	if (!f0 || !f)
		goto out;
	loom_fabric_get_db_identity(f, &id);
	vmm = id.voxel_size_um * 1e-3;
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_FIBRE;
	r.kind = LOOM_YARN_WARP;
	r.fibre = LOOM_FIBRE_SILK;
	r.band = band;
	r.x0 = (PJ0 + 0.25) * id.block[0] * vmm;
	r.x1 = (PJ1 - 0.25) * id.block[0] * vmm;
	r.y0 = (PI0 + 0.25) * id.block[1] * vmm;
	r.y1 = (PI1 - 0.25) * id.block[1] * vmm;
	CHECK_EQ_INT(loom_paint_new("f", &p, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_paint_add(p, &r, &diag), LOOM_OK);
	/* the text round trip (version 3) */
	CHECK_EQ_INT(loom_paint_format(p, &text, &len), LOOM_OK);
	CHECK(text && !strncmp(text, "loom-paint 3\n", 13) && strstr(text, " fibre=silk\n"));
	CHECK_EQ_INT(loom_paint_parse(text, len, "w", &q, &diag), LOOM_OK);
	if (q) {
		const loom_paint_region *rq = loom_paint_get(q, 0);
		CHECK(rq && rq->effect == LOOM_PAINT_FIBRE && rq->fibre == LOOM_FIBRE_SILK &&
		      rq->kind == LOOM_YARN_WARP && rq->band == band && rq->x0 == r.x0 &&
		      rq->y1 == r.y1);
	}
	/* a fibre region in a version-2 file is refused */
	if (text) {
		text[11] = '2';
		loom_paint_free(q);
		q = NULL;
		CHECK_EQ_INT(loom_paint_parse(text, len, "w", &q, &diag), LOOM_EFORMAT);
		CHECK(strstr(diag.message, "needs version 3") != NULL);
	}
	CHECK_EQ_INT(loom_paint_apply_weaves(p, &f, &diag), LOOM_OK);
	CHECK(loom_texture_open(f0, two, NULL, &t0, &diag) == LOOM_OK);
	CHECK(loom_texture_open(f, two, NULL, &t, &diag) == LOOM_OK);
	if (!t0 || !t)
		goto out;
	for (int64_t I = PI0 - M; I < PI1 + M; I++)
		for (int64_t J = PJ0 - M; J < PJ1 + M; J++) {
			int64_t di = I < PI0 ? PI0 - I : I >= PI1 ? I - PI1 + 1 : 0;
			int64_t dj = J < PJ0 ? PJ0 - J : J >= PJ1 ? J - PJ1 + 1 : 0;
			int64_t cheb = di > dj ? di : dj;
			int allowed = cheb <= (int64_t)band + 1 &&
			              !(di == (int64_t)band + 1 && dj == (int64_t)band + 1);
			/* the corner term: a corner column also depends on the
			   crossings meeting there and their four neighbours
			   (docs/synthesis.md, "Block corners"): re-assigned
			   crossings within 2 x 1 or 1 x 2 */
			int64_t ei = di > (int64_t)band ? di - (int64_t)band : 0;
			int64_t ej = dj > (int64_t)band ? dj - (int64_t)band : 0;
			int corner_allowed = (ei <= 2 && ej <= 1) || (ei <= 1 && ej <= 2);
			loom_fabric_source s0, s;
			loom_db_exemplar_info e;
			loom_synth_block b0, b;
			loom_fabric_source_at(f0, I, J, &s0);
			loom_fabric_source_at(f, I, J, &s);
			loom_db_exemplar(two, s.exemplar, &e);
			loom_synth_block_info(f->set, s.block, &b);
			loom_synth_block_info(f->set, s0.block, &b0);
			if (cheb == 0) {
				painted_silk += e.fibre[0] == LOOM_FIBRE_SILK &&
				                e.fibre[1] == LOOM_FIBRE_COTTON;
				bits_kept += (b.code & 1u) == (b0.code & 1u);
			} else if (cheb <= (int64_t)band) {
				band_kept += e.fibre[0] == (in_stripe(J) ? LOOM_FIBRE_SILK
				                                          : LOOM_FIBRE_COTTON);
			} else {
				rest_kept += s.block == s0.block;
			}
			for (uint32_t ly = 0; ly < id.block[1]; ly++)
				for (uint32_t lx = 0; lx < id.block[0]; lx++)
					for (uint32_t z = 0; z < id.block[2]; z++) {
						double pt[3] = {J * (double)id.block[0] + lx + 0.5,
						                I * (double)id.block[1] + ly + 0.5, z + 0.5};
						loom_texel a, c;
						if (loom_texture_sample(t0, pt, LOOM_FILTER_NEAREST, &a) ||
						    loom_texture_sample(t, pt, LOOM_FILTER_NEAREST, &c)) {
							outside++;
							continue;
						}
						if (!same_texel(&a, &c)) {
							changed++;
							changed_painted += cheb == 0;
							outside += !allowed &&
							           !(corner_allowed &&
							             (lx == 0 || lx == id.block[0] - 1) &&
							             (ly == 0 || ly == id.block[1] - 1));
						}
					}
		}
	{
		const uint64_t n_p = (uint64_t)(PI1 - PI0) * (PJ1 - PJ0);
		const uint64_t n_b = (uint64_t)(PI1 - PI0 + 2) * (PJ1 - PJ0 + 2) - n_p;
		const uint64_t n_all = (uint64_t)(PI1 - PI0 + 2 * M) * (PJ1 - PJ0 + 2 * M);
		printf("  painted fibre: %llu voxels changed (%llu at painted crossings), "
		       "%llu outside the allowed set\n", (unsigned long long)changed,
		       (unsigned long long)changed_painted, (unsigned long long)outside);
		CHECK_EQ_INT(painted_silk, n_p);
		CHECK_EQ_INT(bits_kept, n_p);
		CHECK_EQ_INT(band_kept, n_b);
		CHECK_EQ_INT(rest_kept, n_all - n_p - n_b);
		CHECK_EQ_INT(outside, 0);
		CHECK(changed_painted > 1000);
	}
	/* then a weft of silk over the silk warps: silk/silk, which the
	   database lacks */
	{
		loom_paint *pw = NULL;
		loom_fabric *keep = f;
		r.kind = LOOM_YARN_WEFT;
		CHECK_EQ_INT(loom_paint_new("f", &pw, NULL), LOOM_OK);
		CHECK_EQ_INT(loom_paint_add(pw, &r, &diag), LOOM_OK);
		CHECK_EQ_INT(loom_paint_apply_weaves(pw, &f, &diag), LOOM_EMISMATCH);
		CHECK(f == keep);
		CHECK(strstr(diag.message, "pair silk/silk") != NULL &&
		      strstr(diag.message, "pairs cotton/cotton, silk/cotton only") != NULL);
		loom_paint_free(pw);
	}
out:
	free(text);
	loom_paint_free(p);
	loom_paint_free(q);
	loom_texture_close(t0);
	loom_texture_close(t);
	loom_fabric_free(f0);
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(two);
}

/* Same bytes for any thread count, and the same fabric twice. */
static void test_determinism(void)
{
	size_t n1, n2, m1, m2;
	uint8_t *a, *b, *fa = NULL, *fb = NULL;
	loom_db *two = NULL;
	loom_design *d = stripe_design();

	CHECK(make_db(tpath("two3.ldb"), 1, 3) == LOOM_OK);
	a = slurp(tpath("two.ldb"), &n1);
	b = slurp(tpath("two3.ldb"), &n2);
	CHECK(a && b && n1 == n2 && memcmp(a, b, n1) == 0);
	free(a);
	free(b);
	CHECK(loom_db_open(tpath("two.ldb"), &two, NULL) == LOOM_OK);
	for (int k = 0; two && d && k < 2; k++) {
		loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
		loom_fabric *f = NULL;
		CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f, NULL) == LOOM_OK);
		CHECK(f && loom_fabric_save(f, tpath(k ? "b.loomf" : "a.loomf"), NULL,
		                            NULL) == LOOM_OK);
		loom_fabric_free(f);
	}
	fa = slurp(tpath("a.loomf"), &m1);
	fb = slurp(tpath("b.loomf"), &m2);
	CHECK(fa && fb && m1 == m2 && memcmp(fa, fb, m1) == 0);
	free(fa);
	free(fb);
	loom_design_free(d);
	loom_db_close(two);
}

/* A design's pair the database lacks: an error naming the crossing, its
   types and materials and the pairs the database has; bad options. */
static void test_errors(void)
{
	loom_db *two = NULL;
	loom_design *d = stripe_design();
	loom_fabric_options o = LOOM_FABRIC_OPTIONS_INIT;
	loom_fabric *f = NULL;
	loom_diag diag;
	int code = -1;

	CHECK(loom_db_open(tpath("two.ldb"), &two, NULL) == LOOM_OK);
	if (!two || !d)
		goto out;
	d->types[2].fibre = LOOM_FIBRE_WOOL;
	CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f, &diag) == LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(diag.message, "crossing (0, 5) has warp yarn type 'silkwarp' "
	                   "of wool and weft yarn type 'weft' of cotton");
	CHECK_STR_CONTAINS(diag.message, "pairs cotton/cotton, silk/cotton only");
	d->types[2].fibre = LOOM_FIBRE_SILK;
	o.fibre[0] = LOOM_FIBRE_COUNT_;
	CHECK(loom_fabric_synthesize(d, two, "two.ldb", &o, &f, &diag) == LOOM_EINVAL);
	d->types[2].fibre = 200;
	CHECK(loom_design_validate(d, &diag) == LOOM_EFORMAT);
	CHECK(loom_fibre_parse("silk", &code) == LOOM_OK && code == LOOM_FIBRE_SILK);
	CHECK(loom_fibre_parse("Silk", &code) == LOOM_EINVAL);
	CHECK(loom_fibre_parse("default", &code) == LOOM_EINVAL);
	CHECK(strcmp(loom_fibre_name(LOOM_FIBRE_POLYESTER), "polyester") == 0);
	CHECK(loom_fibre_name(LOOM_FIBRE_COUNT_) == NULL);
	{
		loom_exgen_params p;
		loom_exgen_preset("small", &p);
		p.n_pairs = 5;
		CHECK(loom_exgen_check_params(&p, &diag) == LOOM_EINVAL);
		CHECK_STR_CONTAINS(diag.message, "5 material pairs (at most 4)");
		p.n_pairs = 2;
		p.pairs[0][0] = p.pairs[1][0] = "silk";
		p.pairs[0][1] = NULL;
		p.pairs[1][1] = "silk";
		CHECK(loom_exgen_check_params(&p, &diag) == LOOM_EINVAL);
		CHECK_STR_CONTAINS(diag.message, "pairs 1 and 2 are both silk/silk");
		p.pairs[1][1] = "satin";
		CHECK(loom_exgen_check_params(&p, &diag) == LOOM_EINVAL);
		CHECK_STR_CONTAINS(diag.message, "pair 2: weft fibre 'satin'");
	}
out:
	loom_design_free(d);
	loom_db_close(two);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_material");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	if (make_db(tpath("one.ldb"), 0, 2) || make_db(tpath("two.ldb"), 1, 2)) {
		printf("FAIL test_material/setup (cannot make the databases)\n");
		return 1;
	}
	RUN(test_tags);
	RUN(test_synth_stripe);
	RUN(test_reweave);
	RUN(test_paint_fibre);
	RUN(test_determinism);
	RUN(test_errors);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
