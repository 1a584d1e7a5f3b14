/*
 * engine/exemplar/voxel.h - the exemplar voxel record: encodings and brick layout.
 * Internal (never installed); everything is static inline so the engine's
 * lookup paths decode without calls.
 *
 * One voxel holds three channels (docs/formats.md, "Voxel encodings"):
 *
 *   density      uint8   d / 255 in [0, 1]
 *   orientation  uint16  a line direction (v and -v are the same fibre):
 *                        folded to the upper hemisphere, projected onto the
 *                        octahedron |x|+|y|+|z| = 1, its (x, y) diamond
 *                        rotated 45 degrees onto the square [-1,1]^2
 *                        (s = x + y, t = x - y), s and t quantised to 8 bits
 *                        each: code = qs | qt << 8, q = round((s+1)*127.5).
 *                        The angular error is at most
 *                        LOOM__ORIENT_MAX_ERR_DEG (tests/unit/test_voxel.c
 *                        measures it).  Empty voxels store code 0.
 *   label        uint8   0 = empty, else a row of the exemplar's yarn table
 *                        (label -> kind warp/weft, yarn index, flags)
 *
 * Brick layout: a brick is bx*by*bz voxels stored as four byte planes of
 * V = bx*by*bz bytes each, in this order:
 *
 *   plane 0  density
 *   plane 1  orientation low byte  (qs)
 *   plane 2  orientation high byte (qt)
 *   plane 3  label
 *
 * Inside a plane, index(lx, ly, lz) = (ly * bx + lx) * bz + lz: z is the
 * fastest axis, so a z-run of one voxel column is contiguous in every plane.
 */
#ifndef LOOM_VOXEL_H
#define LOOM_VOXEL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#define LOOM__VOXEL_PLANES 4        /* byte planes per brick */
#define LOOM__PLANE_DENSITY 0
#define LOOM__PLANE_ORIENT_LO 1
#define LOOM__PLANE_ORIENT_HI 2
#define LOOM__PLANE_LABEL 3
/* Bound on the angle between a direction and its decoded code, in degrees.
   The worst case is near the octant centres (|x| = |y| = |z|), where the
   octahedral projection stretches most: measured maximum 0.551 over 6e7
   directions (test_voxel.c checks it).  Choosing the best of the 2x2
   neighbouring codes instead of rounding does not lower the maximum. */
#define LOOM__ORIENT_MAX_ERR_DEG 0.56

static inline uint8_t loom__density_encode(float d)
{
	if (!(d > 0.0f))
		return 0;
	if (d >= 1.0f)
		return 255;
	return (uint8_t)(d * 255.0f + 0.5f);
}

static inline float loom__density_decode(uint8_t v)
{
	return (float)v * (1.0f / 255.0f);
}

/* Decode an orientation code into a unit vector with z >= 0. */
static inline void loom__orient_decode(uint16_t code, float out[3])
{
	float s = (float)(code & 0xff) * (1.0f / 127.5f) - 1.0f;
	float t = (float)(code >> 8) * (1.0f / 127.5f) - 1.0f;
	float px = 0.5f * (s + t), py = 0.5f * (s - t);
	float pz = 1.0f - fabsf(px) - fabsf(py);
	float inv;

	if (pz < 0.0f)
		pz = 0.0f;
	inv = 1.0f / sqrtf(px * px + py * py + pz * pz);
	out[0] = px * inv;
	out[1] = py * inv;
	out[2] = pz * inv;
}

/* Quantise s or t in [-1, 1] to 0..255 (round to nearest). */
static inline int loom__orient_q(float v)
{
	int q = (int)floorf((v + 1.0f) * 127.5f + 0.5f);
	return q < 0 ? 0 : q > 255 ? 255 : q;
}

/*
 * Encode a direction (any length; the line through it).  Zero, NaN or
 * infinite input gives code 0.  encode(v) == encode(-v) for every v.
 */
static inline uint16_t loom__orient_encode(float x, float y, float z)
{
	float n = fabsf(x) + fabsf(y) + fabsf(z);
	float px, py;

	if (!(n > 0.0f) || !(n < INFINITY))
		return 0;
	/* Fold to the upper hemisphere; on the equator keep y > 0, or
	   y == 0 and x > 0, so that v and -v fold to the same vector. */
	if (z < 0.0f || (z == 0.0f && (y < 0.0f || (y == 0.0f && x < 0.0f)))) {
		x = -x;
		y = -y;
	}
	px = x / n;
	py = y / n;
	return (uint16_t)(loom__orient_q(px + py) | loom__orient_q(px - py) << 8);
}

/* Offsets of the planes of a brick of V voxels. */
static inline size_t loom__brick_plane(size_t n_voxels, int plane)
{
	return n_voxels * (size_t)plane;
}

/* Index of voxel (lx, ly, lz) inside a plane of a bx x by x bz brick. */
static inline size_t loom__brick_index(uint32_t bx, uint32_t bz, uint32_t lx,
                                       uint32_t ly, uint32_t lz)
{
	return ((size_t)ly * bx + lx) * bz + lz;
}

/* Orientation code of voxel i of a brick of n voxels. */
static inline uint16_t loom__brick_orient(const uint8_t *brick, size_t n, size_t i)
{
	return (uint16_t)(brick[n + i] | (uint16_t)brick[2 * n + i] << 8);
}

#endif /* LOOM_VOXEL_H */
