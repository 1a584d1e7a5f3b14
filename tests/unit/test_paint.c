/*
 * tests/unit/test_paint.c - painted regions (engine/texture/paint.c): the
 * paint file text round trip and its errors; brute force over every voxel
 * of a box around each region against the unpainted texture: a region
 * changes only voxels whose column centre is inside it (defects) or
 * within its blend band (colours), and does change some; a slub only adds
 * voxels of its kind and raises their count; a broken end leaves no warp
 * voxel in its columns; a pull moves its kind up by the lift.
 */
#include "loom.h"
#include "check.h"
#include "tmpdir.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static char db_path[4200];
static loom_db *g_db;
static loom_fabric *g_fab;
static loom_texture *g_tex;
static double g_vmm;
static uint32_t g_b[3];

static void setup(void)
{
	loom_exgen_params p;
	loom_diag d;
	loom_design *des = NULL;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_fabric_db_identity id;

	memset(&d, 0, sizeof d);
	if (tmpdir_make())
		return;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	CHECK_EQ_INT(loom_exgen_preset("tiny", &p), LOOM_OK);
	p.seed = 5;
	p.threads = 1;
	CHECK_EQ_INT(loom_exgen_write_db(db_path, &p, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(db_path, &g_db, NULL), LOOM_OK);
	if (!g_db || loom_design_new(6, 8, &des) || loom_design_set_types(des, 2))
		return;
	for (uint32_t i = 0; i < 6; i++)
		for (uint32_t j = 0; j < 8; j++) {
			des->weave[i * 8 + j] = (uint8_t)((i + j) % 2);
			des->warp_type[i * 8 + j] = 0;
			des->weft_type[i * 8 + j] = 1;
		}
	des->types[0].albedo[0] = des->types[0].albedo[1] = des->types[0].albedo[2] = 0.8f;
	des->types[1].albedo[2] = 0.6f;
	des->types[0].alignment = des->types[1].alignment = 0.5f;
	if (loom_fabric_synthesize(des, g_db, db_path, NULL, &g_fab, &d) != LOOM_OK)
		printf("  synthesize: %s\n", d.message);
	loom_design_free(des);
	if (!g_fab)
		return;
	o.max_threads = 4;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &g_tex, &d), LOOM_OK);
	loom_fabric_get_db_identity(g_fab, &id);
	g_vmm = id.voxel_size_um * 1e-3;
	memcpy(g_b, id.block, sizeof g_b);
}

static const char *const texts[] = {
	"loom-paint 1\nfabric /x/y.loomf\n"
	"# a comment\n"
	"region stain 0.5 0.25 1.5 1 kind=any rgb=0.3,0.2,0.1 strength=0.5 blend=0.1\n"
	"region slub 0 0 2 0.5 kind=weft amount=2\n"
	"region yarn 1 1 2 2 kind=warp rgb=1,0,0 blend=0\n"
	"mask 3 2\n#.#\n.#.\n",
};

static void test_text_round_trip(void)
{
	loom_paint *p = NULL, *q = NULL;
	loom_diag d;
	char *a = NULL, *b = NULL;
	size_t na = 0, nb = 0;
	const loom_paint_region *r;

	memset(&d, 0, sizeof d);
	CHECK_EQ_INT(loom_paint_parse(texts[0], strlen(texts[0]), "t.loomp", &p, &d), LOOM_OK);
	if (!p) {
		printf("  %s\n", d.message);
		return;
	}
	CHECK_EQ_INT(loom_paint_count(p), 3);
	CHECK(!strcmp(loom_paint_fabric(p), "/x/y.loomf"));
	r = loom_paint_get(p, 0);
	CHECK(r && r->effect == LOOM_PAINT_STAIN && r->x0 == 0.5 && r->y1 == 1 &&
	      fabs(r->rgb[1] - 0.2f) < 1e-7 && r->strength == 0.5f && r->blend_mm == 0.1);
	r = loom_paint_get(p, 1);
	CHECK(r && r->effect == LOOM_PAINT_SLUB && r->kind == LOOM_YARN_WEFT && r->amount == 2);
	r = loom_paint_get(p, 2);
	CHECK(r && r->mask_w == 3 && r->mask_h == 2 && r->mask[0] == 1 && r->mask[1] == 0 &&
	      r->mask[4] == 1 && r->kind == LOOM_YARN_WARP);
	CHECK(loom_paint_get(p, 3) == NULL);
	CHECK_EQ_INT(loom_paint_format(p, &a, &na), LOOM_OK);
	CHECK_EQ_INT(loom_paint_parse(a, na, "a", &q, &d), LOOM_OK);
	if (q)
		CHECK_EQ_INT(loom_paint_format(q, &b, &nb), LOOM_OK);
	CHECK(a && b && na == nb && !memcmp(a, b, na));
	free(a);
	free(b);
	loom_paint_free(p);
	loom_paint_free(q);
}

static void test_text_errors(void)
{
	static const struct {
		const char *text, *msg;
	} cases[] = {
		{"loom-paint 4\nfabric f\n", "not a loom paint file"},
		{"LOOM-paint 1\n", "not a loom paint file"},
		{"loom-paint 1\nregion stain 0 0 1 1\n", "t:2: expected 'fabric PATH' first"},
		{"loom-paint 1\n", "t:1: no 'fabric PATH' line"},
		{"loom-paint 1\nfabric f\nfabric g\n", "t:3: a second 'fabric' line"},
		{"loom-paint 1\nfabric f\nregion glitter 0 0 1 1\n", "t:3: expected 'region EFFECT"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 nan 1\n", "t:3: expected a finite number"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 1\n", "t:3: expected 'region EFFECT"},
		{"loom-paint 1\nfabric f\nregion stain 1 0 0 1\n", "t:3: paint: the rectangle"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 1 1 color=1\n", "t:3: unknown key"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 1 1 rgb=1,2,0\n", "t:3: paint: rgb"},
		{"loom-paint 1\nfabric f\nregion slub 0 0 1 1 amount=2\n", "needs kind warp or weft"},
		{"loom-paint 1\nfabric f\nregion pull 0 0 1 1 kind=warp amount=65\n", "lift must be 1..64"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 1 1\nmask 2 2\n#.\n#\n", "t:6: expected a row of W characters"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 1 1\nmask 5000 1\n", "t:4: grid size must be"},
		{"loom-paint 1\nfabric f\nmask 1 1\n#\n", "t:3: expected 'region', 'mask' or 'weave'"},
		{"loom-paint 1\nfabric f\nregion stain 0 0 1 1\n\nbogus\n", "t:5: expected 'region', 'mask' or 'weave'"},
		{"loom-paint 1\nfabric f\nregion weave 0 0 1 1\nweave 1 1\n#\n", "t:3: a weave region needs version 2"},
		{"loom-paint 2\nfabric f\nregion weave 0 0 1 1 band=1\n", "t:3: paint: a weave region needs its weave"},
		{"loom-paint 2\nfabric f\nregion weave 0 0 1 1 band=9\nweave 1 1\n#\n", "t:3: band must be a whole number 0..8"},
		{"loom-paint 2\nfabric f\nregion stain 0 0 1 1 band=1\n", "t:3: band goes with 'region weave'"},
		{"loom-paint 2\nfabric f\nregion fibre 0 0 1 1 fibre=silk\n", "t:3: a fibre region needs version 3"},
		{"loom-paint 3\nfabric f\nregion fibre 0 0 1 1 kind=warp\n", "t:3: paint: a fibre region needs a material"},
		{"loom-paint 3\nfabric f\nregion fibre 0 0 1 1 fibre=tweed\n", "t:3: fibre must be cotton, rayon"},
		{"loom-paint 3\nfabric f\nregion fibre 0 0 1 1 fibre=default\n", "t:3: fibre must be cotton, rayon"},
		{"loom-paint 3\nfabric f\nregion stain 0 0 1 1 fibre=silk\n", "t:3: fibre goes with 'region fibre'"},
		{"loom-paint 2\nfabric f\nregion stain 0 0 1 1\nweave 1 1\n#\n", "t:4: 'weave W H' goes once after"},
		{"loom-paint 2\nfabric f\nregion weave 0 0 1 1\nweave 2 1\n#\n", "t:5: expected a row of W"},
		{"loom-paint 2\nfabric f\nregion weave 0 0 1 1\nweave 1 1\n#\nweave 1 1\n#\n", "t:6: 'weave W H' goes once"},
	};
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		loom_paint *p = NULL;
		loom_diag d;
		memset(&d, 0, sizeof d);
		CHECK(loom_paint_parse(cases[i].text, strlen(cases[i].text), "t", &p, &d) != LOOM_OK);
		CHECK(p == NULL);
		CHECK_STR_CONTAINS(d.message, cases[i].msg);
	}
	{
		/* a NUL byte, and the size limit */
		const char t[] = "loom-paint 1\nfabric f\0\n";
		loom_paint *p = NULL;
		loom_diag d;
		memset(&d, 0, sizeof d);
		CHECK_EQ_INT(loom_paint_parse(t, sizeof t - 1, "t", &p, &d), LOOM_EFORMAT);
		CHECK_EQ_INT(loom_paint_parse(t, (size_t)LOOM_PAINT_MAX_FILE + 1, "t", &p, &d),
		             LOOM_ERANGE);
	}
}

static int same(const loom_texel *a, const loom_texel *b)
{
	return a->density == b->density && a->kind == b->kind && a->type == b->type &&
	       !memcmp(a->albedo, b->albedo, sizeof a->albedo) &&
	       !memcmp(a->orientation, b->orientation, sizeof a->orientation);
}

/*
 * Region r (mm) alone over the texture: every voxel of a box reaching
 * `margin` voxels beyond it compared with the unpainted texture.  Returns
 * the number of changed voxels; fails a CHECK for a change outside the
 * allowed area (inside, or within the blend band for colours).
 */
static uint64_t brute(const loom_paint_region *r, int64_t margin, uint64_t *kind_before,
                      uint64_t *kind_after, int *pull_ok, int *broken_ok)
{
	loom_paint *p = NULL;
	loom_volume_source src;
	uint64_t changed = 0, outside = 0;
	double x0 = r->x0 / g_vmm, x1 = r->x1 / g_vmm, y0 = r->y0 / g_vmm, y1 = r->y1 / g_vmm;
	double band = r->blend_mm / g_vmm;
	int64_t lo[2] = {(int64_t)floor(x0) - margin, (int64_t)floor(y0) - margin};
	int64_t hi[2] = {(int64_t)ceil(x1) + margin, (int64_t)ceil(y1) + margin};

	*kind_before = *kind_after = 0;
	*pull_ok = *broken_ok = 1;
	if (loom_paint_new("f", &p, NULL) || loom_paint_add(p, r, NULL) ||
	    loom_paint_volume_source(p, g_tex, g_fab, LOOM_FILTER_NEAREST, &src)) {
		CHECK(0);
		loom_paint_free(p);
		return 0;
	}
	for (int64_t y = lo[1]; y < hi[1]; y++)
		for (int64_t x = lo[0]; x < hi[0]; x++) {
			double cx = x + 0.5, cy = y + 0.5, dist = INFINITY;
			int inside = 0, allowed;
			/* the painted cells (the whole rectangle without a mask),
			   brute force over all of them */
			uint32_t mw = r->mask_w ? r->mask_w : 1, mh = r->mask_h ? r->mask_h : 1;
			for (uint32_t j = 0; j < mh; j++)
				for (uint32_t i = 0; i < mw; i++) {
					double ax = x0 + (x1 - x0) * i / mw, bx = x0 + (x1 - x0) * (i + 1) / mw;
					double ay = y0 + (y1 - y0) * j / mh, by = y0 + (y1 - y0) * (j + 1) / mh;
					double dx = fmax(fmax(ax - cx, cx - bx), 0), dy = fmax(fmax(ay - cy, cy - by), 0);
					if (r->mask_w && !r->mask[j * mw + i])
						continue;
					if (cx >= ax && cx < bx && cy >= ay && cy < by)
						inside = 1;
					dist = fmin(dist, sqrt(dx * dx + dy * dy));
				}
			allowed = inside || dist < band;
			for (int64_t z = 0; z < (int64_t)g_b[2]; z++) {
				double q[3] = {x + 0.5, y + 0.5, z + 0.5};
				loom_texel a, b;
				CHECK_EQ_INT(loom_texture_sample(g_tex, q, LOOM_FILTER_NEAREST, &a), LOOM_OK);
				CHECK_EQ_INT(loom_paint_sample(p, q, &b), LOOM_OK);
				if (!same(&a, &b)) {
					changed++;
					if (!allowed)
						outside++;
				}
				if (inside && r->kind) {
					*kind_before += a.kind == r->kind;
					*kind_after += b.kind == r->kind;
				}
				if (inside && r->effect == LOOM_PAINT_BROKEN_END && b.kind == LOOM_YARN_WARP)
					*broken_ok = 0;
				if (inside && r->effect == LOOM_PAINT_PULL) {
					loom_texel c;
					double s[3] = {q[0], q[1], q[2] - r->amount};
					loom_texture_sample(g_tex, s, LOOM_FILTER_NEAREST, &c);
					if ((c.kind == r->kind) != (b.kind == r->kind))
						*pull_ok = 0;
				}
				if (r->effect == LOOM_PAINT_SLUB && a.kind == r->kind && !same(&a, &b))
					*pull_ok = 0; /* a slub only adds */
			}
		}
	if (outside)
		printf("  %s: %llu voxels changed outside the region and its band\n",
		       loom_paint_effect_name(r->effect), (unsigned long long)outside);
	CHECK(outside == 0);
	loom_paint_free(p);
	return changed;
}

static void test_regions_brute_force(void)
{
	loom_paint_region r;
	uint64_t kb, ka, n;
	int pull_ok, broken_ok;
	double vx = g_vmm;

	if (!g_tex) {
		CHECK(0);
		return;
	}
	/* stain, soft edge of 3 voxels */
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_STAIN;
	r.x0 = 5.3 * vx;
	r.y0 = 4.2 * vx;
	r.x1 = 20.7 * vx;
	r.y1 = 17.1 * vx;
	r.rgb[0] = 0.5f;
	r.strength = 0.8f;
	r.blend_mm = 3 * vx;
	n = brute(&r, 6, &kb, &ka, &pull_ok, &broken_ok);
	printf("  stain: %llu voxels changed\n", (unsigned long long)n);
	CHECK(n > 100);
	/* yarn colour of the wefts, with a mask (a diagonal of cells) */
	{
		uint8_t m[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
		r.effect = LOOM_PAINT_YARN;
		r.kind = LOOM_YARN_WEFT;
		r.rgb[0] = 1;
		r.rgb[1] = r.rgb[2] = 0;
		r.mask_w = r.mask_h = 3;
		r.mask = m;
		r.blend_mm = 2 * vx;
		r.x0 = 0;
		r.y0 = 0;
		r.x1 = 3.0 * g_b[0] * vx;
		r.y1 = 3.0 * g_b[1] * vx;
		n = brute(&r, 4, &kb, &ka, &pull_ok, &broken_ok);
		printf("  weft colour (mask): %llu voxels changed\n", (unsigned long long)n);
		CHECK(n > 50);
		r.mask_w = r.mask_h = 0;
		r.mask = NULL;
	}
	/* broken end over two crossings' width */
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_BROKEN_END;
	r.x0 = (g_b[0] + 0.0) * vx;
	r.x1 = (2 * g_b[0] + 0.0) * vx;
	r.y0 = 0;
	r.y1 = 4.0 * g_b[1] * vx;
	n = brute(&r, 4, &kb, &ka, &pull_ok, &broken_ok);
	printf("  broken end: %llu voxels emptied\n", (unsigned long long)n);
	CHECK(n > 50);
	CHECK(broken_ok);
	/* slub on the wefts */
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_SLUB;
	r.kind = LOOM_YARN_WEFT;
	r.amount = 2;
	r.x0 = 0;
	r.x1 = 4.0 * g_b[0] * vx;
	r.y0 = 0.5 * g_b[1] * vx;
	r.y1 = 1.5 * g_b[1] * vx;
	n = brute(&r, 4, &kb, &ka, &pull_ok, &broken_ok);
	printf("  slub: weft voxels %llu -> %llu\n", (unsigned long long)kb,
	       (unsigned long long)ka);
	CHECK(ka > kb + kb / 10);
	CHECK(pull_ok);
	/* pull of the warps by 3 voxels */
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_PULL;
	r.kind = LOOM_YARN_WARP;
	r.amount = 3;
	r.x0 = 2.0 * g_b[0] * vx;
	r.x1 = 3.0 * g_b[0] * vx;
	r.y0 = 0;
	r.y1 = 3.0 * g_b[1] * vx;
	n = brute(&r, 4, &kb, &ka, &pull_ok, &broken_ok);
	printf("  pull: %llu voxels changed\n", (unsigned long long)n);
	CHECK(n > 20);
	CHECK(pull_ok);
}


/*
 * The bulk reads against the point lookups: one paint with every effect
 * (overlapping, in file order, a masked one, soft colour edges), read as
 * boxes in both layouts - some reaching above and below the cloth, where
 * a pull puts yarn - and compared with loom_paint_sample at every voxel
 * centre, channel by channel; the albedo by loom_paint_albedo over the
 * design's yarn colour.  Also: boxes away from the paint read as the
 * texture does, and loom_paint_touches says which effects reach a box.
 */
static void test_bulk_equals_point(void)
{
	loom_paint *p = NULL;
	loom_paint_region r;
	double vx = g_vmm;
	uint8_t m[6] = {1, 0, 1, 0, 1, 1};
	const loom_design *des = g_fab ? loom_fabric_design(g_fab) : NULL;
	uint64_t compared = 0, differ = 0, shaped = 0, coloured = 0;

	if (!g_tex || !des) {
		CHECK(0);
		return;
	}
	CHECK_EQ_INT(loom_paint_new("f", &p, NULL), LOOM_OK);
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_SLUB;
	r.kind = LOOM_YARN_WEFT;
	r.amount = 3;
	r.x0 = 0.4 * vx;
	r.x1 = 2.6 * g_b[0] * vx;
	r.y0 = 0.3 * g_b[1] * vx;
	r.y1 = 1.2 * g_b[1] * vx;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	r.kind = LOOM_YARN_WARP;
	r.amount = 2;
	r.y0 = 1.1 * g_b[1] * vx;
	r.y1 = 2.5 * g_b[1] * vx;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_PULL;
	r.kind = LOOM_YARN_WARP;
	r.amount = 4;
	r.x0 = 1.5 * g_b[0] * vx;
	r.x1 = 2.9 * g_b[0] * vx;
	r.y0 = 0.2 * g_b[1] * vx;
	r.y1 = 2.0 * g_b[1] * vx;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	r.effect = LOOM_PAINT_BROKEN_END;
	r.kind = 0;
	r.amount = 0;
	r.x0 = 0.2 * g_b[0] * vx;
	r.x1 = 0.9 * g_b[0] * vx;
	r.mask_w = 2;
	r.mask_h = 3;
	r.mask = m;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	r.mask_w = r.mask_h = 0;
	r.mask = NULL;
	r.effect = LOOM_PAINT_MISSING_PICK;
	r.x0 = 2.0 * g_b[0] * vx;
	r.x1 = 3.0 * g_b[0] * vx;
	r.y0 = 1.6 * g_b[1] * vx;
	r.y1 = 2.2 * g_b[1] * vx;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_STAIN;
	r.x0 = 3.3 * vx;
	r.y0 = 5.2 * vx;
	r.x1 = 1.7 * g_b[0] * vx;
	r.y1 = 1.9 * g_b[1] * vx;
	r.rgb[0] = 0.4f;
	r.rgb[1] = 0.2f;
	r.strength = 0.7f;
	r.blend_mm = 4 * vx;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	r.effect = LOOM_PAINT_YARN;
	r.kind = LOOM_YARN_WARP;
	r.rgb[0] = 0.9f;
	r.rgb[1] = 0.6f;
	r.rgb[2] = 0.1f;
	r.blend_mm = 2.5 * vx;
	r.x0 = 1.2 * g_b[0] * vx;
	r.x1 = 2.4 * g_b[0] * vx;
	r.y0 = 0.7 * g_b[1] * vx;
	r.y1 = 2.8 * g_b[1] * vx;
	CHECK_EQ_INT(loom_paint_add(p, &r, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_paint_bind(p, g_tex, g_fab), LOOM_OK);

	for (int layout = 0; layout < 2; layout++) {
		/* one box over all regions and beyond, reaching 5 voxels above
		   and below the cloth; one inside a region */
		int64_t boxes[2][6] = {
			{-3, -2, -5, 3 * (int64_t)g_b[0] + 4, 3 * (int64_t)g_b[1] + 3,
			 (int64_t)g_b[2] + 5},
			{(int64_t)g_b[0] + 3, (int64_t)g_b[1] / 2, 1, (int64_t)g_b[0] + 11,
			 (int64_t)g_b[1] / 2 + 5, (int64_t)g_b[2] - 1}};
		for (int bx = 0; bx < 2; bx++) {
			const int64_t *lo = boxes[bx], *hi = boxes[bx] + 3;
			int64_t nx = hi[0] - lo[0], ny = hi[1] - lo[1], nz = hi[2] - lo[2];
			size_t n = (size_t)(nx * ny * nz);
			uint8_t *d = malloc(n), *k = malloc(n), *ty = malloc(n), *lb = malloc(n);
			uint16_t *o = malloc(n * sizeof *o);
			loom_texture_region reg;
			if (!d || !k || !ty || !lb || !o) {
				CHECK(0);
				goto next;
			}
			memset(&reg, 0, sizeof reg);
			reg.density = d;
			reg.orientation = o;
			reg.kind = k;
			reg.type = ty;
			reg.label = lb;
			reg.layout = layout;
			CHECK_EQ_INT(loom_paint_read_region(p, lo, hi, &reg), LOOM_OK);
			for (int64_t z = lo[2]; z < hi[2]; z++)
				for (int64_t y = lo[1]; y < hi[1]; y++)
					for (int64_t x = lo[0]; x < hi[0]; x++) {
						double q[3] = {x + 0.5, y + 0.5, z + 0.5};
						loom_texel a, u;
						float al[3] = {0, 0, 0}, dec[3] = {0, 0, 0};
						size_t i = layout == LOOM_REGION_Z_FASTEST
						         ? (size_t)(((y - lo[1]) * nx + (x - lo[0])) * nz + (z - lo[2]))
						         : (size_t)(((z - lo[2]) * ny + (y - lo[1])) * nx + (x - lo[0]));
						int bad = 0;
						CHECK_EQ_INT(loom_paint_sample(p, q, &a), LOOM_OK);
						loom_texture_sample(g_tex, q, LOOM_FILTER_NEAREST, &u);
						if (d[i])
							loom_orientation_decode(o[i], dec);
						if (k[i] && ty[i] < des->n_types) {
							memcpy(al, des->types[ty[i]].albedo, sizeof al);
							loom_paint_albedo(p, x, y, k[i], al);
						}
						bad |= (float)d[i] / 255.0f != a.density;
						bad |= k[i] != a.kind || ty[i] != a.type || lb[i] != a.label;
						bad |= memcmp(dec, a.orientation, sizeof dec) != 0;
						bad |= memcmp(al, a.albedo, sizeof al) != 0;
						if (bad && differ++ < 5)
							printf("  voxel %lld %lld %lld (layout %d): bulk d %u k %u "
							       "t %u, point d %g k %u t %u\n", (long long)x,
							       (long long)y, (long long)z, layout, d[i], k[i],
							       ty[i], a.density, a.kind, a.type);
						shaped += u.kind != a.kind;
						coloured += u.kind == a.kind && a.kind &&
						            memcmp(u.albedo, a.albedo, sizeof al);
						compared++;
					}
		next:
			free(d);
			free(k);
			free(ty);
			free(lb);
			free(o);
		}
	}
	printf("  %llu voxels compared, %llu differ; %llu changed in kind, %llu in "
	       "colour by the paint\n", (unsigned long long)compared,
	       (unsigned long long)differ, (unsigned long long)shaped,
	       (unsigned long long)coloured);
	CHECK(differ == 0);
	CHECK(shaped > 500);
	CHECK(coloured > 500);
	{
		/* far away: nothing touches; read equals the texture's */
		int64_t lo[3] = {10 * (int64_t)g_b[0], 0, 0}, hi[3] = {10 * (int64_t)g_b[0] + 6, 4,
		                                                        (int64_t)g_b[2]};
		int64_t near_lo[2] = {0, 0}, near_hi[2] = {2, 2};
		size_t n = (size_t)(6 * 4 * g_b[2]);
		uint8_t *a = calloc(n, 1), *b = calloc(n, 1);
		loom_texture_region ra, rb;
		CHECK_EQ_INT(loom_paint_touches(p, lo, hi), 0);
		CHECK_EQ_INT(loom_paint_touches(p, near_lo, near_hi),
		             LOOM_PAINT_TOUCH_COLOUR); /* the stain's blend band */
		memset(&ra, 0, sizeof ra);
		memset(&rb, 0, sizeof rb);
		ra.kind = a;
		rb.kind = b;
		CHECK_EQ_INT(loom_paint_read_region(p, lo, hi, &ra), LOOM_OK);
		CHECK_EQ_INT(loom_texture_read_region(g_tex, lo, hi, &rb), LOOM_OK);
		CHECK(a && b && !memcmp(a, b, n));
		free(a);
		free(b);
	}
	CHECK_EQ_INT(loom_paint_read_region(NULL, NULL, NULL, NULL), LOOM_EINVAL);
	loom_paint_free(p);
}

/* Top yarn kind of the column at (x, y) voxels: the first voxel with yarn
   from the top; 0 for an empty column. */
static int top_kind(loom_texture *t, double x, double y)
{
	for (int64_t z = (int64_t)g_b[2] - 1; z >= 0; z--) {
		double q[3] = {x, y, z + 0.5};
		loom_texel a;
		if (loom_texture_sample(t, q, LOOM_FILTER_NEAREST, &a) != LOOM_OK)
			return -1;
		if (a.kind)
			return a.kind;
	}
	return 0;
}

/*
 * A painted weave (a 2/2 twill into the plain weave, band 1): every voxel
 * of a box 3 crossings beyond the region is compared with the unpainted
 * texture, and changes only within the re-assigned crossings (painted and
 * band) and their four neighbours (whose edge fix sees them); the top
 * yarn at the painted crossings' centres is the twill's; the seam jumps
 * (loom_fabric_seam_block, after the edge fix) around the border are no
 * larger on average than over the unpainted repeat.
 */
static void test_weave(void)
{
	loom_paint *p = NULL;
	loom_paint_region r;
	loom_weave_params wp;
	loom_design *tw = NULL;
	loom_fabric *f2 = NULL, *keep;
	loom_texture *t2 = NULL;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_diag d;
	const int64_t PI0 = 2, PI1 = 6, PJ0 = 3, PJ1 = 10, M = 3; /* painted, margin */
	const uint32_t band = 1;
	uint64_t changed = 0, outside = 0, tops = 0, top_ok = 0, base_ok = 0;
	double seam_border = 0, seam_all = 0;
	uint64_t n_border = 0, n_all = 0;
	double vx = g_vmm;

	memset(&d, 0, sizeof d);
	if (!g_tex || !g_fab) {
		CHECK(0);
		return;
	}
	CHECK_EQ_INT(loom_weave_parse("twill:2/2", &wp, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_design_make(&wp, 0, 0, &tw, NULL), LOOM_OK);
	if (!tw)
		return;
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_WEAVE;
	/* the crossings PI0..PI1-1 x PJ0..PJ1-1: their centres, +- a quarter */
	r.x0 = (PJ0 + 0.25) * g_b[0] * vx;
	r.x1 = (PJ1 - 0.25) * g_b[0] * vx;
	r.y0 = (PI0 + 0.25) * g_b[1] * vx;
	r.y1 = (PI1 - 0.25) * g_b[1] * vx;
	r.weave_w = tw->cols;
	r.weave_h = tw->rows;
	r.weave = tw->weave;
	r.band = band;
	CHECK_EQ_INT(loom_paint_new("f", &p, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_paint_add(p, &r, &d), LOOM_OK);
	/* the text round trip keeps the weave (version 2) */
	{
		char *text = NULL;
		size_t len = 0;
		loom_paint *q = NULL;
		const loom_paint_region *rq;
		CHECK_EQ_INT(loom_paint_format(p, &text, &len), LOOM_OK);
		CHECK(text && !strncmp(text, "loom-paint 2\n", 13));
		CHECK_EQ_INT(loom_paint_parse(text, len, "w", &q, &d), LOOM_OK);
		rq = loom_paint_get(q, 0);
		CHECK(rq && rq->effect == LOOM_PAINT_WEAVE && rq->band == band &&
		      rq->weave_w == tw->cols && rq->weave_h == tw->rows &&
		      !memcmp(rq->weave, tw->weave, (size_t)tw->rows * tw->cols));
		loom_paint_free(q);
		free(text);
	}
	/* a second fabric, the same as g_fab, painted */
	CHECK_EQ_INT(loom_fabric_synthesize(loom_fabric_design(g_fab), g_db, db_path, NULL,
	                                    &f2, &d), LOOM_OK);
	keep = f2;
	CHECK_EQ_INT(loom_paint_apply_weaves(p, &f2, &d), LOOM_OK);
	CHECK(f2 != keep);
	o.max_threads = 2;
	CHECK_EQ_INT(loom_texture_open(f2, g_db, &o, &t2, &d), LOOM_OK);
	if (!t2)
		goto done;
	for (int64_t I = PI0 - M; I < PI1 + M; I++)
		for (int64_t J = PJ0 - M; J < PJ1 + M; J++) {
			/* Chebyshev distance to the painted crossings */
			int64_t di = I < PI0 ? PI0 - I : I >= PI1 ? I - PI1 + 1 : 0;
			int64_t dj = J < PJ0 ? PJ0 - J : J >= PJ1 ? J - PJ1 + 1 : 0;
			int64_t cheb = di > dj ? di : dj;
			/* re-assigned, or a 4-neighbour of one re-assigned */
			int allowed = cheb <= (int64_t)band + 1 &&
			              !(di == (int64_t)band + 1 && dj == (int64_t)band + 1);
			/* the corner term: a corner column also depends on the
			   crossings meeting there and their four neighbours
			   (docs/synthesis.md, "Block corners"): re-assigned
			   crossings within 2 x 1 or 1 x 2 */
			int64_t ei = di > (int64_t)band ? di - (int64_t)band : 0;
			int64_t ej = dj > (int64_t)band ? dj - (int64_t)band : 0;
			int corner_allowed = (ei <= 2 && ej <= 1) || (ei <= 1 && ej <= 2);
			int painted = cheb == 0;
			for (uint32_t ly = 0; ly < g_b[1]; ly++)
				for (uint32_t lx = 0; lx < g_b[0]; lx++)
					for (uint32_t z = 0; z < g_b[2]; z++) {
						double q[3] = {J * (double)g_b[0] + lx + 0.5,
						               I * (double)g_b[1] + ly + 0.5, z + 0.5};
						loom_texel a, b;
						CHECK_EQ_INT(loom_texture_sample(g_tex, q, LOOM_FILTER_NEAREST,
						                                 &a), LOOM_OK);
						CHECK_EQ_INT(loom_texture_sample(t2, q, LOOM_FILTER_NEAREST,
						                                 &b), LOOM_OK);
						if (!same(&a, &b)) {
							changed++;
							outside += !allowed &&
							           !(corner_allowed &&
							             (lx == 0 || lx == g_b[0] - 1) &&
							             (ly == 0 || ly == g_b[1] - 1));
						}
					}
			if (painted) {
				double cx = (J + 0.5) * g_b[0], cy = (I + 0.5) * g_b[1];
				int want = loom_design_at(tw, (uint32_t)(I % tw->rows),
				                          (uint32_t)(J % tw->cols));
				loom_fabric_source src;
				tops++;
				top_ok += top_kind(t2, cx, cy) == (want ? LOOM_YARN_WARP : LOOM_YARN_WEFT);
				base_ok += top_kind(g_tex, cx, cy) ==
				           (((I + J) % 2) ? LOOM_YARN_WARP : LOOM_YARN_WEFT);
				CHECK_EQ_INT(loom_fabric_source_at(f2, I, J, &src), LOOM_OK);
				CHECK_EQ_INT(src.warp_over, want);
			}
			if (cheb >= 1 && cheb <= (int64_t)band + 1) {
				/* the border: crossings around the painted area */
				double s[4];
				CHECK_EQ_INT(loom_fabric_seam_block(f2, I, J, s), LOOM_OK);
				seam_border += s[1] + s[3];
				n_border++;
			}
		}
	for (int64_t I = 0; I < 24; I++)
		for (int64_t J = 0; J < 24; J++) {
			double s[4];
			CHECK_EQ_INT(loom_fabric_seam_block(g_fab, I, J, s), LOOM_OK);
			seam_all += s[1] + s[3];
			n_all++;
		}
	seam_border /= (double)n_border;
	seam_all /= (double)n_all;
	printf("  weave: %llu voxels changed, %llu outside; top yarn as painted at "
	       "%llu/%llu centres (unpainted fabric: %llu/%llu as its design); seam "
	       "after the fix: border %.3f, unpainted %.3f voxels\n",
	       (unsigned long long)changed, (unsigned long long)outside,
	       (unsigned long long)top_ok, (unsigned long long)tops,
	       (unsigned long long)base_ok, (unsigned long long)tops, seam_border, seam_all);
	CHECK(outside == 0);
	CHECK(changed > 1000);
	CHECK(tops == (uint64_t)((PI1 - PI0) * (PJ1 - PJ0)));
	CHECK(top_ok == tops);
	CHECK(seam_border <= seam_all * 1.1 + 1e-9);
done:
	loom_texture_close(t2);
	loom_fabric_free(f2);
	loom_paint_free(p);
	loom_design_free(tw);
}

static void test_bad_args(void)
{
	loom_paint *p = NULL;
	loom_paint_region r;
	loom_volume_source src;
	loom_texel tx;
	double q[3] = {0, 0, 0};
	loom_diag d;

	memset(&d, 0, sizeof d);
	memset(&r, 0, sizeof r);
	CHECK_EQ_INT(loom_paint_new(NULL, &p, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_paint_new("a\nb", &p, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_paint_new("f", &p, &d), LOOM_OK);
	r.effect = 9;
	CHECK_EQ_INT(loom_paint_add(p, &r, &d), LOOM_EINVAL);
	r.effect = LOOM_PAINT_STAIN;
	CHECK_EQ_INT(loom_paint_add(p, &r, &d), LOOM_EINVAL); /* empty rectangle */
	r.x1 = r.y1 = 1;
	r.mask_w = 2;
	CHECK_EQ_INT(loom_paint_add(p, &r, &d), LOOM_EINVAL);
	r.mask_w = 0;
	CHECK_EQ_INT(loom_paint_add(p, &r, &d), LOOM_OK);
	CHECK_EQ_INT(loom_paint_sample(p, q, &tx), LOOM_EINVAL); /* not bound */
	CHECK_EQ_INT(loom_paint_volume_source(p, NULL, g_fab, LOOM_FILTER_NEAREST, &src),
	             LOOM_EINVAL);
	CHECK_EQ_INT(loom_paint_volume_source(p, g_tex, g_fab, 7, &src), LOOM_EINVAL);
	CHECK(loom_paint_effect_name(0) == NULL);
	CHECK_EQ_INT(loom_paint_effect_parse("pull"), LOOM_PAINT_PULL);
	CHECK_EQ_INT(loom_paint_count(NULL), 0);
	loom_paint_free(p);
	loom_paint_free(NULL);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_paint");
	RUN(setup);
	RUN(test_text_round_trip);
	RUN(test_text_errors);
	RUN(test_regions_brute_force);
	RUN(test_bulk_equals_point);
	RUN(test_weave);
	RUN(test_bad_args);
	loom_texture_close(g_tex);
	loom_fabric_free(g_fab);
	loom_db_close(g_db);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
