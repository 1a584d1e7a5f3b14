/*
 * tests/unit/test_preview.c - loom_preview against a brute-force top-surface
 * search with point lookups (heights, kinds, albedo) at 1:1, minified and
 * magnified sizes and on several threads; shading sanity; the texture
 * volume source of the renderer against point lookups.
 */
#include "loom.h"
#include "check.h"
#include "tmpdir.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char db_path[4200];
static loom_db *g_db;
static loom_design *g_design;
static loom_fabric *g_fab;
static loom_texture *g_tex;
static uint32_t B[3];
static loom_paint *g_paint;   /* when set: previews painted, brute force by
                                 loom_paint_sample */
static int g_blocks_strict;   /* BLOCKS compared as EXACT (every piece painted) */

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static void setup(void)
{
	loom_exgen_params p;
	loom_diag d = {0};
	loom_fabric_db_identity id;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;

	if (tmpdir_make())
		return;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	CHECK_EQ_INT(loom_exgen_preset("tiny", &p), LOOM_OK);
	p.seed = 5;
	p.threads = 2;
	p.brick[0] = 4;
	p.brick[1] = 4;
	p.brick[2] = 8;
	CHECK_EQ_INT(loom_exgen_write_db(db_path, &p, NULL, &d), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(db_path, &g_db, NULL), LOOM_OK);
	if (!g_db)
		return;
	CHECK_EQ_INT(loom_design_new(7, 9, &g_design), LOOM_OK);
	CHECK_EQ_INT(loom_design_set_types(g_design, 3), LOOM_OK);
	for (size_t i = 0; i < 63; i++) {
		uint64_t h = mix(i + 77);
		g_design->weave[i] = h & 1;
		g_design->warp_type[i] = (uint8_t)(h >> 8 & 1);
		g_design->weft_type[i] = (uint8_t)(1 + (h >> 16 & 1));
	}
	for (uint32_t k = 0; k < 3; k++) {
		g_design->types[k].albedo[0] = 0.1f + 0.3f * (float)k;
		g_design->types[k].albedo[1] = 0.9f - 0.2f * (float)k;
		g_design->types[k].albedo[2] = 0.05f * (float)(k + 1);
		g_design->types[k].alignment = 0.1f * (float)(k + 1);
	}
	CHECK_EQ_INT(loom_fabric_synthesize(g_design, g_db, db_path, NULL, &g_fab, &d),
	             LOOM_OK);
	if (!g_fab)
		return;
	loom_fabric_get_db_identity(g_fab, &id);
	memcpy(B, id.block, sizeof B);
	o.budget_bytes = (size_t)4 << 20;
	CHECK_EQ_INT(loom_texture_open(g_fab, g_db, &o, &g_tex, &d), LOOM_OK);
	printf("  block %ux%ux%u, design 7x9\n", B[0], B[1], B[2]);
}

/* Brute force: top-most voxel of column (x, y) with density byte >= thr. */
static void top_of(int64_t x, int64_t y, int64_t z0, int64_t z1, int thr,
                   float *h, uint8_t *kind, float al[3], float ori[3], float *align)
{
	*h = 0;
	*kind = 0;
	al[0] = al[1] = al[2] = 0;
	for (int64_t z = z1 - 1; z >= z0; z--) {
		loom_texel tx;
		if (g_paint) {
			double q[3] = {x + 0.5, y + 0.5, z + 0.5};
			CHECK_EQ_INT(loom_paint_sample(g_paint, q, &tx), LOOM_OK);
		} else {
			CHECK_EQ_INT(loom_texture_voxel(g_tex, x, y, z, &tx), LOOM_OK);
		}
		if ((int)lrintf(tx.density * 255.0f) >= thr) {
			*h = (float)(z + 1);
			*kind = tx.kind;
			memcpy(al, tx.albedo, 3 * sizeof(float));
			memcpy(ori, tx.orientation, 3 * sizeof(float));
			*align = tx.alignment;
			return;
		}
	}
}

/* Pixel k of P over [lo, lo + n): columns whose centre is inside, else the
   one under the centre (docs/preview.md), by floating point. */
static void span_of(int64_t lo, int64_t n, uint32_t P, uint32_t k, int64_t *a,
                    int64_t *b)
{
	double s = ceil((double)k * n / P - 0.5), e = ceil((double)(k + 1) * n / P - 0.5);
	if (e <= s) {
		s = floor((k + 0.5) * (double)n / P);
		e = s + 1;
	}
	*a = lo + (int64_t)s;
	*b = lo + (int64_t)e;
}

typedef struct bcol {
	float h, al[3], t[3], align;
	uint8_t kind;
} bcol;

static void norm3(double v[3])
{
	double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	if (l > 0)
		for (int k = 0; k < 3; k++)
			v[k] /= l;
}

/* The documented shading of column (x, y) of the brute-force grid. */
static void shade_bf(const bcol *g, int64_t gw, int64_t gx, int64_t gy, double z0,
                     double span, const float bg[3], double out[3])
{
	const bcol *c = &g[gy * gw + gx];
	double L[3] = {-0.4, -0.5, 0.77}, Hv[3], n[3], t[3], hl, hr, hu, hd;
	double tl, th, ndl, occ, diff, spec;

	if (c->kind == 0) {
		for (int k = 0; k < 3; k++)
			out[k] = bg[k];
		return;
	}
	norm3(L);
	Hv[0] = L[0];
	Hv[1] = L[1];
	Hv[2] = L[2] + 1;
	norm3(Hv);
	hl = g[gy * gw + gx - 1].h > 0 ? g[gy * gw + gx - 1].h : z0;
	hr = g[gy * gw + gx + 1].h > 0 ? g[gy * gw + gx + 1].h : z0;
	hu = g[(gy - 1) * gw + gx].h > 0 ? g[(gy - 1) * gw + gx].h : z0;
	hd = g[(gy + 1) * gw + gx].h > 0 ? g[(gy + 1) * gw + gx].h : z0;
	n[0] = -(hr - hl) / 2;
	n[1] = -(hd - hu) / 2;
	n[2] = 1;
	norm3(n);
	for (int k = 0; k < 3; k++)
		t[k] = c->t[k];
	norm3(t);
	tl = t[0] * L[0] + t[1] * L[1] + t[2] * L[2];
	th = t[0] * Hv[0] + t[1] * Hv[1] + t[2] * Hv[2];
	ndl = fmax(0, n[0] * L[0] + n[1] * L[1] + n[2] * L[2]);
	occ = 0.45 + 0.55 * (c->h - z0) / span;
	diff = 0.12 + 0.88 * ndl * (0.3 + 0.7 * sqrt(fmax(0, 1 - tl * tl)));
	spec = 0.25 * (1 - c->align) * pow(sqrt(fmax(0, 1 - th * th)), 24) * ndl;
	for (int k = 0; k < 3; k++)
		out[k] = c->al[k] * diff * occ + spec;
}

/* Preview of [lo, hi) at width W on `threads` threads with `filter` vs the
   brute force (EXACT: to 1e-4; BLOCKS: mean difference below 0.02). */
static int compare_case(const int64_t lo[3], const int64_t hi[3], uint32_t W,
                        uint32_t threads, int filter, float **rgb_out)
{
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	loom_preview_maps maps;
	loom_preview_stats st;
	uint32_t w, h;
	float *rgb, *hm, *al;
	uint8_t *kd;
	int bad = 0;
	int64_t z0 = 0, z1 = B[2], nx = hi[0] - lo[0], ny = hi[1] - lo[1];
	int64_t gw = nx + 2, gh = ny + 2;
	int thr = (int)ceil(0.2 * 255.0 - 1e-3);
	bcol *g;
	double sum_diff = 0;

	memcpy(po.lo, lo, sizeof po.lo);
	memcpy(po.hi, hi, sizeof po.hi);
	po.width = W;
	po.threads = threads;
	po.filter = filter;
	po.paint = g_paint;
	po.memory_bytes = (size_t)1 << 20; /* small: several bands */
	po.background[0] = 0.25f;
	po.background[1] = 0.5f;
	po.background[2] = 0.75f;
	if (hi[2] > lo[2]) {
		z0 = lo[2] < 0 ? 0 : lo[2];
		z1 = hi[2] < z1 ? hi[2] : z1;
	}
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_OK);
	rgb = calloc((size_t)w * h * 3, sizeof *rgb);
	hm = calloc((size_t)w * h, sizeof *hm);
	al = calloc((size_t)w * h * 3, sizeof *al);
	kd = calloc((size_t)w * h, 1);
	g = calloc((size_t)gw * gh, sizeof *g);
	maps.height = hm;
	maps.albedo = al;
	maps.kind = kd;
	CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, rgb, &maps, &st, NULL), LOOM_OK);
	CHECK_EQ_INT(st.pixels, (uint64_t)w * h);
	CHECK_EQ_INT(st.filter, filter);
	CHECK(st.memory_bytes <= po.memory_bytes);
	for (int64_t y = 0; y < gh; y++)
		for (int64_t x = 0; x < gw; x++) {
			bcol *c = &g[y * gw + x];
			top_of(lo[0] - 1 + x, lo[1] - 1 + y, z0, z1, thr, &c->h, &c->kind, c->al,
			       c->t, &c->align);
		}
	for (uint32_t j = 0; j < h; j++)
		for (uint32_t i = 0; i < w; i++) {
			size_t p = (size_t)j * w + i;
			int64_t xa, xb, ya, yb, n = 0, nw = 0, nf = 0;
			double want[3] = {0, 0, 0}, wal[3] = {0, 0, 0}, hs = 0;
			span_of(lo[0], nx, w, i, &xa, &xb);
			span_of(lo[1], ny, h, j, &ya, &yb);
			for (int64_t y = ya; y < yb; y++)
				for (int64_t x = xa; x < xb; x++) {
					double c3[3];
					const bcol *c = &g[(y - lo[1] + 1) * gw + x - lo[0] + 1];
					shade_bf(g, gw, x - lo[0] + 1, y - lo[1] + 1, (double)z0,
					         (double)(z1 - z0), po.background, c3);
					for (int k = 0; k < 3; k++) {
						want[k] += c3[k];
						wal[k] += c->kind ? c->al[k] : po.background[k];
					}
					if (c->kind) {
						hs += c->h;
						nw += c->kind == 1;
						nf += c->kind == 2;
					}
					n++;
				}
			for (int k = 0; k < 3; k++) {
				double d = fabs(rgb[3 * p + (size_t)k] - want[k] / (double)n);
				sum_diff += d;
				if ((filter == LOOM_PREVIEW_EXACT || g_blocks_strict) &&
				    (d > 1e-4 || fabs(al[3 * p + (size_t)k] - wal[k] / (double)n) > 1e-5)) {
					if (bad++ < 5)
						printf("  pixel %u,%u channel %d: %g, brute force %g\n", i, j,
						       k, rgb[3 * p + (size_t)k], want[k] / (double)n);
				}
			}
			if (filter == LOOM_PREVIEW_EXACT) {
				uint8_t wk = nw + nf == 0 ? 0 : nw >= nf ? 1 : 2;
				double wh = nw + nf ? hs / (double)(nw + nf) : 0;
				if (kd[p] != wk || fabs(hm[p] - wh) > 1e-3) {
					if (bad++ < 5)
						printf("  pixel %u,%u: kind %d height %g, brute force %d %g\n",
						       i, j, kd[p], hm[p], wk, wh);
				}
			}
		}
	if (filter == LOOM_PREVIEW_BLOCKS && !g_blocks_strict) {
		double mean = sum_diff / (3.0 * w * h);
		printf("  blocks %ux%u: mean |difference| from brute force %.4f\n", w, h, mean);
		if (!(mean < 0.02))
			bad++;
	}
	CHECK_EQ_INT(bad, 0);
	free(hm);
	free(al);
	free(kd);
	free(g);
	if (rgb_out)
		*rgb_out = rgb;
	else
		free(rgb);
	return bad;
}

static void brute_force(void)
{
	int64_t lo[3] = {-5, -3, 0}, hi[3];
	float *a = NULL, *b = NULL, *c = NULL;
	uint32_t nx;

	if (!g_tex)
		return;
	hi[0] = (int64_t)B[0] * 9 + 7;
	hi[1] = (int64_t)B[1] * 7 + 2;
	hi[2] = 0;
	nx = (uint32_t)(hi[0] - lo[0]);
	compare_case(lo, hi, nx, 1, LOOM_PREVIEW_EXACT, &a);     /* 1:1 */
	compare_case(lo, hi, nx, 3, LOOM_PREVIEW_EXACT, &b);     /* same on 3 threads */
	{
		uint32_t w, h;
		loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
		memcpy(po.lo, lo, sizeof lo);
		memcpy(po.hi, hi, sizeof hi);
		po.width = nx;
		po.background[0] = 0.25f;
		po.background[1] = 0.5f;
		po.background[2] = 0.75f;
		loom_preview_size(&po, &w, &h);
		/* the default options (AUTO, 16 MiB) give the same bytes */
		c = calloc((size_t)w * h * 3, sizeof *c);
		CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, c, NULL, NULL, NULL), LOOM_OK);
		if (a && b && c) {
			CHECK(memcmp(a, b, (size_t)w * h * 3 * sizeof(float)) == 0);
			CHECK(memcmp(a, c, (size_t)w * h * 3 * sizeof(float)) == 0);
		}
	}
	free(a);
	free(b);
	free(c);
	compare_case(lo, hi, nx / 3 + 1, 2, LOOM_PREVIEW_EXACT, NULL);  /* area average */
	compare_case(lo, hi, nx / 5, 2, LOOM_PREVIEW_BLOCKS, NULL);     /* tables */
	compare_case(lo, hi, nx / 3 + 1, 1, LOOM_PREVIEW_BLOCKS, NULL);
	compare_case(lo, hi, nx * 2 + 1, 2, LOOM_PREVIEW_EXACT, NULL);  /* magnified */
	lo[2] = 1;
	hi[2] = (int64_t)B[2] / 2;                  /* a z range */
	compare_case(lo, hi, nx / 2, 1, LOOM_PREVIEW_EXACT, NULL);
	/* far away on the unbounded bolt */
	lo[0] = -1000003;
	lo[1] = 2000011;
	lo[2] = 0;
	hi[0] = lo[0] + 40;
	hi[1] = lo[1] + 30;
	hi[2] = 0;
	compare_case(lo, hi, 40, 2, LOOM_PREVIEW_EXACT, NULL);
	compare_case(lo, hi, 13, 2, LOOM_PREVIEW_BLOCKS, NULL);
}

/*
 * A painted fabric (loom_preview_options.paint): EXACT against the brute
 * force over loom_paint_sample (every effect, partly overlapping; 1:1,
 * minified, 2 threads); BLOCKS with a paint over the whole box (each
 * piece read column by column) to the same tolerance; and the painted
 * preview differs from the unpainted one.
 */
static void painted(void)
{
	loom_fabric_db_identity id;
	loom_paint_region r;
	double vx;
	int64_t lo[3] = {-3, -2, 0}, hi[3];
	float *a = NULL, *b = NULL;
	uint32_t nx, w, h;

	if (!g_tex)
		return;
	loom_fabric_get_db_identity(g_fab, &id);
	vx = id.voxel_size_um * 1e-3;
	hi[0] = (int64_t)B[0] * 4 + 5;
	hi[1] = (int64_t)B[1] * 3 + 2;
	hi[2] = 0;
	nx = (uint32_t)(hi[0] - lo[0]);
	CHECK_EQ_INT(loom_paint_new("f", &g_paint, NULL), LOOM_OK);
	memset(&r, 0, sizeof r);
	r.effect = LOOM_PAINT_SLUB;
	r.kind = LOOM_YARN_WEFT;
	r.amount = 2;
	r.x0 = 0;
	r.x1 = 3.0 * B[0] * vx;
	r.y0 = 0.2 * B[1] * vx;
	r.y1 = 0.9 * B[1] * vx;
	CHECK_EQ_INT(loom_paint_add(g_paint, &r, NULL), LOOM_OK);
	r.effect = LOOM_PAINT_PULL;
	r.kind = LOOM_YARN_WARP;
	r.amount = 3;
	r.x0 = 1.2 * B[0] * vx;
	r.x1 = 2.1 * B[0] * vx;
	r.y0 = 0.5 * B[1] * vx;
	r.y1 = 2.5 * B[1] * vx;
	CHECK_EQ_INT(loom_paint_add(g_paint, &r, NULL), LOOM_OK);
	r.effect = LOOM_PAINT_BROKEN_END;
	r.kind = 0;
	r.amount = 0;
	r.x0 = 3.1 * B[0] * vx;
	r.x1 = 3.6 * B[0] * vx;
	CHECK_EQ_INT(loom_paint_add(g_paint, &r, NULL), LOOM_OK);
	r.effect = LOOM_PAINT_STAIN;
	r.rgb[0] = 0.3f;
	r.rgb[1] = 0.2f;
	r.rgb[2] = 0.1f;
	r.strength = 0.9f;
	r.blend_mm = 3 * vx;
	r.x0 = 0.5 * B[0] * vx;
	r.x1 = 2.5 * B[0] * vx;
	r.y0 = 1.5 * B[1] * vx;
	r.y1 = 2.6 * B[1] * vx;
	CHECK_EQ_INT(loom_paint_add(g_paint, &r, NULL), LOOM_OK);
	r.effect = LOOM_PAINT_YARN;
	r.kind = LOOM_YARN_WARP;
	r.rgb[0] = 0.9f;
	r.rgb[1] = 0.7f;
	r.rgb[2] = 0.0f;
	r.x0 = 2.2 * B[0] * vx;
	r.x1 = 4.0 * B[0] * vx;
	r.y0 = 0;
	r.y1 = 1.4 * B[1] * vx;
	CHECK_EQ_INT(loom_paint_add(g_paint, &r, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_paint_bind(g_paint, g_tex, g_fab), LOOM_OK);
	compare_case(lo, hi, nx, 1, LOOM_PREVIEW_EXACT, &a);
	compare_case(lo, hi, nx / 3 + 1, 2, LOOM_PREVIEW_EXACT, NULL);
	compare_case(lo, hi, nx * 2, 2, LOOM_PREVIEW_EXACT, NULL);
	{
		loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
		memcpy(po.lo, lo, sizeof lo);
		memcpy(po.hi, hi, sizeof hi);
		po.width = nx;
		po.background[0] = 0.25f;
		po.background[1] = 0.5f;
		po.background[2] = 0.75f;
		loom_preview_size(&po, &w, &h);
		b = calloc((size_t)w * h * 3, sizeof *b);
		CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, b, NULL, NULL, NULL), LOOM_OK);
		CHECK(a && b && memcmp(a, b, (size_t)w * h * 3 * sizeof(float)) != 0);
	}
	/* a stain over everything: BLOCKS reads every piece column by column */
	r.effect = LOOM_PAINT_STAIN;
	r.x0 = -100.0 * B[0] * vx;
	r.x1 = 100.0 * B[0] * vx;
	r.y0 = -100.0 * B[1] * vx;
	r.y1 = 100.0 * B[1] * vx;
	CHECK_EQ_INT(loom_paint_add(g_paint, &r, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_paint_bind(g_paint, g_tex, g_fab), LOOM_OK);
	g_blocks_strict = 1;
	compare_case(lo, hi, nx / 5, 2, LOOM_PREVIEW_BLOCKS, NULL);
	compare_case(lo, hi, nx / 3 + 1, 1, LOOM_PREVIEW_BLOCKS, NULL);
	g_blocks_strict = 0;
	loom_paint_free(g_paint);
	g_paint = NULL;
	free(a);
	free(b);
}

/* Pick 0 at the top, end 0 at the left: the top-left pixel of a 1:1
   preview of crossing (0, 0) shows the yarn W(0,0) puts on top, and the
   picture is not the drawdown flipped (checked on every crossing). */
static void orientation(void)
{
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	uint32_t w, h, agree = 0, flipped = 0, n = 0;
	uint8_t *kd;
	loom_preview_maps maps;
	float *rgb;

	if (!g_tex)
		return;
	po.hi[0] = (int64_t)B[0] * 9;
	po.hi[1] = (int64_t)B[1] * 7;
	po.width = 9 * 4;
	po.height = 7 * 4;
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_OK);
	rgb = calloc((size_t)w * h * 3, sizeof *rgb);
	kd = calloc((size_t)w * h, 1);
	memset(&maps, 0, sizeof maps);
	maps.kind = kd;
	CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, rgb, &maps, NULL, NULL), LOOM_OK);
	for (uint32_t i = 0; i < 7; i++)
		for (uint32_t j = 0; j < 9; j++) {
			/* the centre 2x2 pixels of crossing (i, j) */
			uint8_t k = kd[(size_t)(4 * i + 2) * w + 4 * j + 2];
			uint8_t kf = kd[(size_t)(4 * (6 - i) + 2) * w + 4 * j + 2];
			uint8_t want = loom_design_at(g_design, i, j) ? 1 : 2;
			agree += k == want;
			flipped += kf == want;
			n++;
		}
	printf("  crossing centres with the yarn W puts on top: %u of %u (flipped: %u)\n",
	       agree, n, flipped);
	CHECK(agree >= n * 9 / 10);
	CHECK(agree > flipped);
	free(rgb);
	free(kd);
}

static void bad_arguments(void)
{
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	uint32_t w, h;
	float rgb[3 * 16];
	loom_diag d = {0};

	po.hi[0] = 10;
	po.hi[1] = 10;
	po.width = 0;
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_EINVAL);
	po.width = 4;
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_OK);
	CHECK_EQ_INT(w, 4);
	CHECK_EQ_INT(h, 4);
	po.hi[1] = 0;
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_EINVAL);
	po.hi[1] = 10;
	po.width = LOOM_PREVIEW_MAX_SIDE + 1;
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_ERANGE);
	po.width = 4;
	po.hi[0] = (int64_t)1 << 50;
	CHECK_EQ_INT(loom_preview_size(&po, &w, &h), LOOM_ERANGE);
	po.hi[0] = 10;
	CHECK_EQ_INT(loom_preview(NULL, g_fab, &po, rgb, NULL, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "NULL");
	po.width = 0;
	CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, rgb, NULL, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "width 0");
	/* z range outside the slab: every pixel is background */
	po.width = 4;
	po.lo[2] = (int64_t)B[2] + 5;
	po.hi[2] = (int64_t)B[2] + 9;
	po.background[1] = 0.5f;
	if (g_tex) {
		CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, rgb, NULL, NULL, &d), LOOM_OK);
		for (int k = 0; k < 16; k++)
			CHECK(rgb[3 * k] == 0.0f && rgb[3 * k + 1] == 0.5f && rgb[3 * k + 2] == 0.0f);
	}
}

static void volume_source(void)
{
	loom_volume_source src;
	void *tctx;
	int bad = 0;

	if (!g_tex)
		return;
	CHECK_EQ_INT(loom_texture_volume_source(NULL, g_fab, 0, &src), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_volume_source(g_tex, g_fab, 7, &src), LOOM_EINVAL);
	CHECK_EQ_INT(loom_texture_volume_source(g_tex, g_fab, LOOM_FILTER_NEAREST, &src),
	             LOOM_OK);
	CHECK_EQ_INT(src.nz, B[2]);
	CHECK_EQ_INT(src.nx, 0);
	CHECK(src.max_density == 1.0f);
	{
		loom_db_info info;
		CHECK_EQ_INT(loom_db_get_info(g_db, &info), LOOM_OK);
		CHECK(fabs(src.voxel_mm - info.voxel_size_um * 1e-3) < 1e-9);
	}
	tctx = src.thread_init ? src.thread_init(src.ctx) : src.ctx;
	CHECK(tctx != NULL);
	for (int k = 0; k < 500; k++) {
		uint64_t h = mix((uint64_t)k * 31 + 9);
		int64_t x = (int64_t)(h % 200) - 50, y = (int64_t)((h >> 16) % 150) - 20;
		int64_t z = (int64_t)((h >> 32) % B[2]);
		double p[3] = {(double)x + 0.25, (double)y + 0.75, (double)z + 0.5};
		loom_medium_sample ms;
		loom_texel tx;
		CHECK_EQ_INT(src.lookup(tctx, p, &ms), 0);
		CHECK_EQ_INT(loom_texture_voxel(g_tex, x, y, z, &tx), LOOM_OK);
		if (ms.density != tx.density || ms.albedo[0] != tx.albedo[0] ||
		    ms.albedo[2] != tx.albedo[2] || ms.orient[1] != tx.orientation[1] ||
		    ms.alignment != tx.alignment)
			bad++;
	}
	CHECK_EQ_INT(bad, 0);
	if (src.thread_done)
		src.thread_done(src.ctx, tctx);
	/* a tiny render, identical on 1 and 2 threads */
	{
		loom_render_options ro = LOOM_RENDER_OPTIONS_INIT;
		float a[16 * 12 * 3], b[16 * 12 * 3];
		double sum = 0;
		ro.width = 16;
		ro.height = 12;
		ro.spp = 2;
		ro.density_scale = 4;
		ro.threads = 1;
		CHECK_EQ_INT(loom_camera_top(&src, 0, 0, 32, 24, &ro.camera), LOOM_OK);
		CHECK_EQ_INT(loom_render(&src, &ro, a, NULL, NULL), LOOM_OK);
		ro.threads = 2;
		CHECK_EQ_INT(loom_render(&src, &ro, b, NULL, NULL), LOOM_OK);
		CHECK(memcmp(a, b, sizeof a) == 0);
		for (size_t k = 0; k < sizeof a / sizeof a[0]; k++)
			sum += a[k];
		CHECK(sum > 0);
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_preview");
	RUN(setup);
	RUN(brute_force);
	RUN(painted);
	RUN(orientation);
	RUN(bad_arguments);
	RUN(volume_source);
	loom_texture_close(g_tex);
	loom_fabric_free(g_fab);
	loom_design_free(g_design);
	loom_db_close(g_db);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
