/*
 * engine/render/render_texture.c - a loom_volume_source over a fabric's virtual
 * texture, so loom_render path-traces synthesized fabrics (docs/rendering.md,
 * "Rendering a fabric").  Lookups go through loom_texture_sample; the
 * texture keeps its own per-thread state, and the thread_done hook hands it
 * back when a render thread ends.
 */
#include "render_internal.h"
#include "loom/preview.h"

#include <math.h>

#include <string.h>

static int lookup_common(loom_texture *t, const double p[3], int filter,
                         loom_medium_sample *out)
{
	loom_texel tx;
	int rc = loom_texture_sample(t, p, filter, &tx);

	if (rc != LOOM_OK)
		return rc;
	loom__texel_medium(&tx, out);
	return LOOM_OK;
}

static int lookup_nearest(void *ctx, const double p[3], loom_medium_sample *out)
{
	return lookup_common(ctx, p, LOOM_FILTER_NEAREST, out);
}

static int lookup_trilinear(void *ctx, const double p[3], loom_medium_sample *out)
{
	return lookup_common(ctx, p, LOOM_FILTER_TRILINEAR, out);
}

unsigned loom__lod_level(double fp, unsigned levels)
{
	unsigned k = 0;

	while (k < levels && fp >= (double)(2u << k))
		k++;
	return k;
}

/* Level of detail (docs/rendering.md): the level the footprint asks for. */
static int lookup_lod_common(loom_texture *t, const double p[3], double fp, int filter,
                             loom_medium_sample *out)
{
	loom_texel tx;
	float spread = 0;
	int rc = loom_texture_sample_lod(t, p, filter,
	                                 loom__lod_level(fp, loom_texture_lod_levels(t)),
	                                 &tx, &spread);

	if (rc != LOOM_OK)
		return rc;
	loom__texel_medium(&tx, out);
	out->spread = spread;
	return LOOM_OK;
}

static int lookup_lod_nearest(void *ctx, const double p[3], double fp,
                              loom_medium_sample *out)
{
	return lookup_lod_common(ctx, p, fp, LOOM_FILTER_NEAREST, out);
}

static int lookup_lod_trilinear(void *ctx, const double p[3], double fp,
                                loom_medium_sample *out)
{
	return lookup_lod_common(ctx, p, fp, LOOM_FILTER_TRILINEAR, out);
}

static void *tex_thread_init(void *ctx)
{
	return ctx; /* the texture makes the thread's state on first use */
}

static void tex_thread_done(void *ctx, void *thread_ctx)
{
	(void)thread_ctx;
	loom_texture_thread_done(ctx);
}

LOOM_API int loom_texture_volume_source(loom_texture *t, const loom_fabric *f,
                                        int filter, loom_volume_source *src)
{
	loom_fabric_db_identity id;
	loom_volume_source s = LOOM_VOLUME_SOURCE_INIT;

	if (!t || !f || !src)
		return LOOM_EINVAL;
	if (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR)
		return LOOM_EINVAL;
	if (!loom_fabric_attached(f) || loom_fabric_get_db_identity(f, &id) != LOOM_OK)
		return LOOM_EINVAL;
	s.nx = 0;
	s.ny = 0;
	s.nz = (int64_t)id.block[2];
	s.voxel_mm = (double)id.voxel_size_um * 1e-3;
	s.max_density = 1.0f;
	s.lookup = filter == LOOM_FILTER_NEAREST ? lookup_nearest : lookup_trilinear;
	if (loom_texture_lod_levels(t)) /* opened with options.lod */
		s.lookup_lod = filter == LOOM_FILTER_NEAREST ? lookup_lod_nearest
		                                             : lookup_lod_trilinear;
	s.ctx = t;
	s.thread_init = tex_thread_init;
	s.thread_done = tex_thread_done;
	*src = s;
	return LOOM_OK;
}
