/*
 * tests/unit/test_preview.c - loom_preview against a brute-force top-surface
 * search with point lookups (heights, kinds, albedo) at 1:1, minified and
 * magnified sizes and on several threads; shading sanity; the texture
 * volume source of the renderer against point lookups.
 */
#include "loom.h"
#include "check.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[4096], db_path[4200];
static loom_db *g_db;
static loom_design *g_design;
static loom_fabric *g_fab;
static loom_texture *g_tex;
static uint32_t B[3];

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static void setup(void)
{
	const char *base = getenv("LOOM_TEST_TMP");
	loom_exgen_params p;
	loom_diag d = {0};
	loom_fabric_db_identity id;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;

	snprintf(tmpdir, sizeof tmpdir, "%s/test_preview.XXXXXX", base ? base : "/tmp");
	if (!mkdtemp(tmpdir)) {
		printf("  mkdtemp: %s\n", strerror(errno));
		CHECK(0);
		return;
	}
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
                   float *h, uint8_t *kind, float al[3])
{
	*h = 0;
	*kind = 0;
	al[0] = al[1] = al[2] = 0;
	for (int64_t z = z1 - 1; z >= z0; z--) {
		loom_texel tx;
		CHECK_EQ_INT(loom_texture_voxel(g_tex, x, y, z, &tx), LOOM_OK);
		if ((int)lrintf(tx.density * 255.0f) >= thr) {
			*h = (float)(z + 1);
			*kind = tx.kind;
			memcpy(al, tx.albedo, 3 * sizeof(float));
			return;
		}
	}
}

/* Preview of [lo, hi) at width W on `threads` threads vs brute force. */
static int compare_case(const int64_t lo[3], const int64_t hi[3], uint32_t W,
                        uint32_t threads, float **rgb_out)
{
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	loom_preview_maps maps;
	loom_preview_stats st;
	uint32_t w, h;
	float *rgb, *hm, *al;
	uint8_t *kd;
	int bad = 0;
	int64_t z0 = 0, z1 = B[2];
	int thr = (int)ceil(0.2 * 255.0 - 1e-3);

	memcpy(po.lo, lo, sizeof po.lo);
	memcpy(po.hi, hi, sizeof po.hi);
	po.width = W;
	po.threads = threads;
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
	maps.height = hm;
	maps.albedo = al;
	maps.kind = kd;
	CHECK_EQ_INT(loom_preview(g_tex, g_fab, &po, rgb, &maps, &st, NULL), LOOM_OK);
	CHECK_EQ_INT(st.pixels, (uint64_t)w * h);
	for (uint32_t j = 0; j < h; j++)
		for (uint32_t i = 0; i < w; i++) {
			size_t p = (size_t)j * w + i;
			int64_t nx = hi[0] - lo[0], ny = hi[1] - lo[1];
			int64_t x = lo[0] + (int64_t)((2 * (int64_t)i + 1) * nx / (2 * (int64_t)w));
			int64_t y = hi[1] - 1 - (int64_t)((2 * (int64_t)j + 1) * ny / (2 * (int64_t)h));
			float bh, ba[3];
			uint8_t bk;
			top_of(x, y, z0, z1, thr, &bh, &bk, ba);
			if (bh != hm[p] || bk != kd[p]) {
				if (bad++ < 5)
					printf("  pixel %u,%u (voxel %lld,%lld): height %g kind %d, "
					       "brute force %g %d\n", i, j, (long long)x, (long long)y,
					       hm[p], kd[p], bh, bk);
				continue;
			}
			if (bk == 0) {
				/* empty: the background colour */
				if (rgb[3 * p] != 0.25f || rgb[3 * p + 1] != 0.5f ||
				    rgb[3 * p + 2] != 0.75f)
					bad++;
				continue;
			}
			for (int c = 0; c < 3; c++) {
				if (al[3 * p + (size_t)c] != ba[c])
					bad++;
				if (!(rgb[3 * p + (size_t)c] >= 0.0f) || rgb[3 * p + (size_t)c] > 1.5f)
					bad++;
			}
			/* shading scales the albedo: a darker channel stays darker
			   (the highlight adds the same amount to each) */
			for (int c = 0; c < 2; c++)
				if ((ba[c] < ba[c + 1]) != (rgb[3 * p + (size_t)c] < rgb[3 * p + (size_t)c + 1]) &&
				    ba[c] != ba[c + 1])
					bad++;
		}
	CHECK_EQ_INT(bad, 0);
	free(hm);
	free(al);
	free(kd);
	if (rgb_out)
		*rgb_out = rgb;
	else
		free(rgb);
	return bad;
}

static void brute_force(void)
{
	int64_t lo[3] = {-5, -3, 0}, hi[3];
	float *a = NULL, *b = NULL;
	uint32_t nx;

	if (!g_tex)
		return;
	hi[0] = (int64_t)B[0] * 9 + 7;
	hi[1] = (int64_t)B[1] * 7 + 2;
	hi[2] = 0;
	nx = (uint32_t)(hi[0] - lo[0]);
	compare_case(lo, hi, nx, 1, &a);             /* 1:1 */
	compare_case(lo, hi, nx, 3, &b);             /* same on 3 threads */
	if (a && b) {
		uint32_t w, h;
		loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
		memcpy(po.lo, lo, sizeof lo);
		memcpy(po.hi, hi, sizeof hi);
		po.width = nx;
		loom_preview_size(&po, &w, &h);
		CHECK(memcmp(a, b, (size_t)w * h * 3 * sizeof(float)) == 0);
	}
	free(a);
	free(b);
	compare_case(lo, hi, nx / 3 + 1, 2, NULL);   /* minified: sparse columns */
	compare_case(lo, hi, nx * 2 + 1, 2, NULL);   /* magnified */
	lo[2] = 1;
	hi[2] = (int64_t)B[2] / 2;                  /* a z range */
	compare_case(lo, hi, nx / 2, 1, NULL);
	/* far away on the unbounded bolt */
	lo[0] = -1000003;
	lo[1] = 2000011;
	lo[2] = 0;
	hi[0] = lo[0] + 40;
	hi[1] = lo[1] + 30;
	hi[2] = 0;
	compare_case(lo, hi, 40, 2, NULL);
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
	RUN(bad_arguments);
	RUN(volume_source);
	loom_texture_close(g_tex);
	loom_fabric_free(g_fab);
	loom_design_free(g_design);
	loom_db_close(g_db);
	if (tmpdir[0]) {
		unlink(db_path);
		rmdir(tmpdir);
	}
	CHECK_MAIN_END();
}
