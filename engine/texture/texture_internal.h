/*
 * engine/texture/texture_internal.h - pieces of the virtual-texture engine
 * (the files of engine/texture/) that the unit tests check on their own.  Never
 * installed.
 */
#ifndef LOOM_TEXTURE_INTERNAL_H
#define LOOM_TEXTURE_INTERNAL_H

#include "core/internal.h"

/*
 * Blend n fibre directions (unit lines: v and -v are the same fibre) with
 * weights w[k] >= 0 (zero-weight entries are ignored): the reference is
 * the direction of largest weight (the first on ties); every other
 * direction is flipped to point the same way as the reference (v . ref >= 0)
 * before the weighted sum, which is normalised and folded to z >= 0 (on
 * z == 0: y > 0, or y == 0 and x >= 0).  All weights zero or a zero sum:
 * out = (0, 0, 0).  Deterministic (fixed order, float arithmetic).
 */
void loom__orient_blend(unsigned n, const float *w, const float (*v)[3],
                        float out[3]);

/* loom_texture_sample (nearest, all channels) into a medium sample
   (spread 0), with no texel in between: the renderer's grid source
   (lookup.c). */
struct loom_medium_sample;
int loom__texture_medium(loom_texture *t, const double p[3],
                         struct loom_medium_sample *out);

/* An edge-fix offset in fixed point, 1/16 voxel: dz * 16 rounded to the
   nearest integer (halves away from zero), dz clamped to +-2047 voxels;
   not-a-number gives 0. */
int loom__dz_fixed(float dz);

/* Split a fixed-point offset q (1/16 voxel) into whole voxels w =
   floor(q / 16), returned, and the fraction *f = q - 16 w in [0, 16): the
   lookups' step 3 (dz_split), for the tests. */
int loom__dz_split(int q, int *f);

/* The edge-fix offset (unrounded) the engine computes for column (lx, ly)
   of crossing (I, J): the same arithmetic as loom_edgefix_block, which
   the tests check bit for bit.  0 for NULL or a column out of range. */
float loom__texture_dz(const loom_texture *t, int64_t I, int64_t J, uint32_t lx,
                       uint32_t ly);

/* Region reads map labels to kinds and yarn types 16 voxels at a time
   with SSSE3 (PSHUFB) when the CPU has it (checked at open) and the
   exemplar's labels with a kind are below 128; otherwise through 256-entry
   tables; and build the sub-voxel blend's line masks with AVX-512BW when
   the CPU has it, else with AVX2 (density-only reads) or SSE2.  on = 0
   forces the tables and SSE2, 2 what a host with AVX2 but not AVX-512
   would run, 3 a host with SSSE3 but neither, 1 restores the default.
   For tests and benches
   (both paths must give the same bytes); not thread-safe against reads
   in flight on t.  NULL: no-op. */
void loom__texture_simd(loom_texture *t, int on);

/* The extinction per millimetre of a density-1 voxel for which a coarse
   voxel's density matches its box's transmittance (lod.c, lod_density):
   7 times the default loom render --density-scale of 80, fitted for the
   earlier axis-only rule so the grazing scene of docs/rendering.md
   rendered with the mean colour of full resolution; kept for the
   13-direction fit, which it moves little (doubling it: 1 level). */
#define LOOM__LOD_EXTINCTION_MM 560.0

/* on = 1: region reads of t copy every column with its nearer whole
   offset (the offset rounded to whole voxels, halves down), no sub-voxel
   blend: the whole-voxel path, which bench_texture measures as the peer
   of sub-voxel reads (issue 13); the bytes then differ from point lookups.
   0 restores the default.  Not thread-safe against reads in flight on t.
   NULL: no-op. */
void loom__texture_region_whole(loom_texture *t, int on);

/* One brick line through region.c's line blend, for the tests: path 0
   line_blend with SSE2 masks, 1 with AVX-512BW masks, 2 the fused copy and
   blend of density-only reads (line_copy_blend_512), 3 their AVX2 form
   (line_copy_blend_256); bz the brick height (a multiple of 16 up to 64;
   64 for paths 1-3), line its bz density
   bytes, lo .. hi - 1 the voxels copied and blended into out[0 ..
   hi - lo), nv the line's voxels inside the block, dir -1 / +1 the farther
   voxel's side and g (1 .. DZ_SUB / 2) its weight, pn the voxel below the
   line is not empty, more: another brick line follows.  Returns 1 when
   the line's top voxel is a candidate left waiting for the next line
   (not written), 0 when not, -1 when the path is not available here
   (no SSE2, no AVX-512BW, no AVX2) or an argument is out of range. */
int loom__texture_line_blend(int path, unsigned bz, const uint8_t *line, unsigned lo,
                             unsigned hi, unsigned nv, int dir, unsigned g, unsigned pn,
                             int more, unsigned solid, uint8_t *out);

/* on = 0: region reads of t bound their output rows by the stored bricks
   alone, without the every-plane occupancy table (the bench's peer and the
   tests' check that the table changes no byte); 1 (the default) restores
   it.  Not thread-safe against reads in flight on t.  NULL: no-op. */
void loom__texture_region_occ(loom_texture *t, int on);

/* Tiles of t's every-plane occupancy table (t->occa, texture_impl.h) now
   known, and of those the ones whose heights are narrower than their
   brick (the ones that bound region reads more tightly than the bricks
   do).  Both 0 without a table. */
void loom__texture_occ_tiles(const loom_texture *t, uint64_t *known, uint64_t *narrow);

/* Coarse voxel (X, Y, Z) of level k (1..loom_texture_lod_levels) of
   exemplar u, read through the brick cache: its five bytes (density,
   orientation code low and high, label, anisotropy; lod.c), zeros outside
   the level's volume.  LOOM_EINVAL for a level that is not there. */
int loom__lod_voxel(loom_texture *t, uint32_t u, unsigned k, int64_t X, int64_t Y,
                    int64_t Z, uint8_t out[5]);

#endif /* LOOM_TEXTURE_INTERNAL_H */
