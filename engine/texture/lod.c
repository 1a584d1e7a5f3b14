/*
 * engine/texture/lod.c - level of detail: prefiltered coarse levels of the
 * exemplars (2x, 4x, 8x box filters) and lookups at a coarse level
 * (docs/rendering.md, "Level of detail"; the voxel format is in
 * docs/formats.md, "Coarse levels").
 *
 * COARSE LEVELS
 *   Level k (1..LOD_MAX) of exemplar u has ceil(size / 2^k) voxels per
 *   axis; coarse voxel (X, Y, Z) is the box filter of the 2^k x 2^k x 2^k
 *   level-0 voxels [2^k X, 2^k X + 2^k) per axis (voxels outside the
 *   exemplar count as empty):
 *     density     fitted to the box's transmittance along 13 directions
 *                 with projected areas (lod_density);
 *     orientation the principal axis of the second-moment tensor
 *                 T = sum d_i v_i v_i^T of the fibre directions weighted by
 *                 the density bytes (Jacobi eigen-solver, double), encoded
 *                 as a level-0 orientation code;
 *     anisotropy  a = (3 lambda_1 / trace T - 1) / 2 in [0, 1] (1: one
 *                 direction, 0: isotropic) as round(255 a);
 *     label       of the kind (warp or weft) with the larger density sum
 *                 (warp on ties), that kind's densest voxel's label (the
 *                 first in brick order on ties); with no voxel of a kind,
 *                 the densest voxel's label.
 *   Coarse bricks hold five planes (density, the two orientation bytes,
 *   label, anisotropy) of bx x by x bz/2 coarse voxels (5/8 of a level-0
 *   brick, so they share its cache frames), index (ly * bx + lx) * bz/2 +
 *   lz as level 0.  Their ids follow the database's: exemplar after
 *   exemplar, level 1 to LOD_MAX, bricks in level-0 order.
 *
 * WHERE THEY COME FROM
 *   Built on demand by the cache loader from the level-0 bricks they cover
 *   (2^k x 2^k x 2^(k-1) of them, read with the thread's database reader
 *   into one brick of scratch): since 2^k divides the brick shape, every
 *   coarse voxel's support lies in one level-0 brick, so each is filtered
 *   while its brick is in the scratch.  Empty level-0 bricks are not read.
 *   They page through the same frames as level-0 bricks and count in the
 *   same budget (texture.c); nothing is stored in the database.
 */
#include "texture_impl.h"

#include <math.h>
#include <stdlib.h>

unsigned loom__lod_levels_for(const uint32_t b[3])
{
	unsigned k = 0;

	if (b[2] < 2 || (b[2] & 1))
		return 0;
	while (k < LOD_MAX && b[0] % (2u << k) == 0 && b[1] % (2u << k) == 0 &&
	       b[2] % (2u << k) == 0)
		k++;
	return k;
}

unsigned loom__lod_setup(loom_texture *t)
{
	uint64_t next = t->n_bricks;

	loom_db_info di;

	t->lod = loom__lod_levels_for(t->bs);
	if (!t->lod)
		return 0;
	/* the extinction of one density byte over a voxel (lod_density) */
	t->lod_sigma = loom_db_get_info(t->db, &di) == LOOM_OK && di.voxel_size_um > 0
	                       ? LOOM__LOD_EXTINCTION_MM * di.voxel_size_um * 1e-3 / 255.0
	                       : 0;
	t->cbs[0] = t->bs[0];
	t->cbs[1] = t->bs[1];
	t->cbs[2] = t->bs[2] / 2;
	t->cbv = (size_t)t->cbs[0] * t->cbs[1] * t->cbs[2];
	for (uint32_t u = 0; u < t->n_ex; u++) {
		struct exm *e = &t->ex[u];
		for (unsigned k = 1; k <= t->lod; k++) {
			uint64_t n = 1;
			for (int a = 0; a < 3; a++) {
				e->lsize[k][a] = (e->size[a] + (1u << k) - 1) >> k;
				e->lnb[k][a] = (e->lsize[k][a] + t->cbs[a] - 1) / t->cbs[a];
				n *= e->lnb[k][a];
			}
			if (next + n > UINT32_MAX) { /* ids beyond 32 bits: LOD off */
				t->lod = 0;
				return 0;
			}
			e->lfirst[k] = (uint32_t)next;
			next += n;
		}
	}
	return t->lod;
}

/* ------------------------------------------------------------ the filter */

/* Largest eigenvalue of the symmetric 3x3 matrix m (row-major, overwritten)
   and its unit eigenvector, by cyclic Jacobi rotations. */
static double eig_max(double m[9], double v[3])
{
	double q[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
	int best = 0;

	for (int sweep = 0; sweep < 32; sweep++) {
		double off = fabs(m[1]) + fabs(m[2]) + fabs(m[5]);
		double scale = fabs(m[0]) + fabs(m[4]) + fabs(m[8]);
		if (!(off > 1e-15 * scale))
			break;
		for (int p = 0; p < 2; p++)
			for (int r = p + 1; r < 3; r++) {
				double apr = m[3 * p + r], th, tt, c, s;
				if (apr == 0)
					continue;
				th = (m[3 * r + r] - m[3 * p + p]) / (2 * apr);
				tt = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1));
				c = 1 / sqrt(tt * tt + 1);
				s = tt * c;
				for (int k = 0; k < 3; k++) { /* m = J^T m J */
					double mkp = m[3 * k + p], mkr = m[3 * k + r];
					m[3 * k + p] = c * mkp - s * mkr;
					m[3 * k + r] = s * mkp + c * mkr;
				}
				for (int k = 0; k < 3; k++) {
					double mpk = m[3 * p + k], mrk = m[3 * r + k];
					m[3 * p + k] = c * mpk - s * mrk;
					m[3 * r + k] = s * mpk + c * mrk;
				}
				for (int k = 0; k < 3; k++) {
					double qkp = q[3 * k + p], qkr = q[3 * k + r];
					q[3 * k + p] = c * qkp - s * qkr;
					q[3 * k + r] = s * qkp + c * qkr;
				}
			}
	}
	for (int k = 1; k < 3; k++)
		if (m[4 * k] > m[4 * best])
			best = k;
	for (int k = 0; k < 3; k++)
		v[k] = q[3 * k + best];
	return m[4 * best];
}

/* The 13 path directions of lod_density: the 3 axes, the 6 face and the
   4 body diagonals of the box, as steps of -1, 0 or 1 voxel per axis. */
static const int8_t lod_dirs[LOD_DIRS][3] = {
	{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1},
	{0, 1, 1}, {0, 1, -1}, {1, 1, 1}, {1, 1, -1}, {1, -1, 1}, {1, -1, -1}};

/* Projected area of a fibre of direction v (unit) seen along unit w, up to
   a constant factor: the microflake model's A (engine/render/microflake.c)
   for a narrow lobe of width s, (4/pi) sqrt(sin^2 + (pi/2) s^2) (exact as
   s -> 0 across and along the fibre), without the 4/pi, which the
   reference extinction absorbs. */
static double lod_area(const double w[3], const double v[3], double s)
{
	double c = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
	double s2 = 1 - c * c;
	return sqrt((s2 > 0 ? s2 : 0) + 1.5707963267948966 * s * s);
}

/* The coarse density byte of an n x n x n box (density bytes d, unit fibre
   directions v, index (x * n + y) * n + z, summing to sum > 0) whose
   coarse fibre axis is vc, after Zhao, Wu, Durand and Ramamoorthi 2016
   (extinction = density x projected area): along each direction w of
   lod_dirs (step g, w = g / |g|), the n^2 straight paths of n steps from
   the voxel centres of one face, wrapping around the box (each voxel once
   per direction), give the fine mean transmittance T(w) = mean
   exp(-sigma |g| sum d_i A(w, v_i)) (sigma the extinction of a density
   byte over one voxel); the uniform coarse box of byte D transmits
   exp(-sigma n |g| D A(w, vc)), vc with the coarse lobe width sc.  D is the least-
   squares fit in log, sum_w a_w b_w / sum_w a_w^2, a_w = A(w, vc), b_w =
   -log T(w) / (sigma n |g|) (the mean of d_i A(w, v_i) when T(w)
   underflows), rounded to [1, 255].  Gaps between yarns stay as open as
   at level 0 along every direction, not only along the axes; with sigma 0
   the rounded mean. */
static uint8_t lod_density(const uint8_t *d, const float (*v)[3], uint32_t n,
                           uint64_t sum, const double vc[3], double sc, double sigma)
{
	uint64_t n3 = (uint64_t)n * n * n, mean = (sum + n3 / 2) / n3;
	double num = 0, den = 0, D;

	if (!(sigma > 0))
		return (uint8_t)mean;
	for (int j = 0; j < LOD_DIRS; j++) {
		const int8_t *g = lod_dirs[j];
		int a = g[0] ? 0 : g[1] ? 1 : 2, b = (a + 1) % 3, c = (a + 2) % 3;
		double len = sqrt((double)(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]));
		double w[3] = {g[0] / len, g[1] / len, g[2] / len}, tsum = 0, esum = 0, bw, aw;
		for (uint32_t i = 0; i < n; i++)
			for (uint32_t k = 0; k < n; k++) {
				uint32_t p[3];
				double e = 0;
				p[a] = 0;
				p[b] = i;
				p[c] = k;
				for (uint32_t m = 0; m < n; m++) {
					size_t q = ((size_t)p[0] * n + p[1]) * n + p[2];
					if (d[q]) {
						double fv[3] = {v[q][0], v[q][1], v[q][2]};
						e += d[q] * lod_area(w, fv, LOD_FLAKE_S);
					}
					for (int r = 0; r < 3; r++)
						p[r] = (p[r] + n + (uint32_t)(int32_t)g[r]) % n;
				}
				tsum += exp(-sigma * len * e);
				esum += e;
			}
		tsum /= (double)n * n;
		bw = tsum > 1e-300 ? -log(tsum) / (sigma * n * len) : esum / (double)n3;
		aw = lod_area(w, vc, sc);
		num += aw * bw;
		den += aw * aw;
	}
	D = floor(num / den + 0.5);
	return (uint8_t)(D < 1 ? 1 : D > 255 ? 255 : D);
}

/* Coarse voxel of the n x n x n level-0 voxels from (x0, y0, z0) of brick
   b (shape bs, V voxels a plane); kind maps labels to kinds; sigma the
   extinction of a density byte over one voxel (lod_density). */
static void filter_box(const uint8_t *b, const uint32_t bs[3], size_t V,
                       const uint8_t *kind, uint32_t x0, uint32_t y0, uint32_t z0,
                       uint32_t n, double sigma, uint8_t out[LOD_PLANES])
{
	uint64_t sum = 0;
	uint8_t bd[LOD_BOX * LOD_BOX * LOD_BOX]; /* the box's density bytes, */
	float bv[LOD_BOX * LOD_BOX * LOD_BOX][3]; /* fibre directions (lod_density) */
	double T[9] = {0}, kw[3] = {0, 0, 0}, ev[3], l1, tr;
	uint8_t best[3] = {0, 0, 0}, bestd[3] = {0, 0, 0};
	uint16_t code;
	int kd;

	memset(bd, 0, (size_t)n * n * n);
	for (uint32_t y = y0; y < y0 + n; y++)
		for (uint32_t x = x0; x < x0 + n; x++) {
			size_t i0 = ((size_t)y * bs[0] + x) * bs[2];
			for (uint32_t z = z0; z < z0 + n; z++) {
				size_t i = i0 + z;
				uint8_t d = b[i], l = b[3 * V + i], k;
				float v[3];
				if (!d)
					continue;
				sum += d;
				loom__orient_decode((uint16_t)(b[V + i] | b[2 * V + i] << 8), v);
				{
					size_t q = ((size_t)(x - x0) * n + (y - y0)) * n + (z - z0);
					bd[q] = d;
					memcpy(bv[q], v, sizeof v);
				}
				for (int r = 0; r < 3; r++)
					for (int c = 0; c < 3; c++)
						T[3 * r + c] += (double)d * v[r] * v[c];
				k = kind[l] <= 2 ? kind[l] : 0;
				kw[k] += d;
				if (d > bestd[k]) {
					bestd[k] = d;
					best[k] = l;
				}
			}
		}
	for (int p = 0; p < LOD_PLANES; p++)
		out[p] = 0;
	if (!sum)
		return;
	tr = T[0] + T[4] + T[8];
	l1 = eig_max(T, ev);
	{
		double a = tr > 0 ? (3 * l1 / tr - 1) / 2 : 0;
		a = a < 0 ? 0 : a > 1 ? 1 : a;
		out[4] = (uint8_t)lround(a * 255);
	}
	code = loom__orient_encode((float)ev[0], (float)ev[1], (float)ev[2]);
	out[1] = (uint8_t)(code & 0xff);
	out[2] = (uint8_t)(code >> 8);
	{ /* the axis as the renderer decodes it */
		float cv[3];
		double vc[3];
		loom__orient_decode(code, cv);
		for (int a = 0; a < 3; a++)
			vc[a] = cv[a];
		/* the lobe the renderer gives it: s widened by the spread */
		double sc = sqrt(LOD_FLAKE_S * LOD_FLAKE_S +
		                 LOD_SPREAD_GAIN * (1 - out[4] / 255.0) / 3);
		out[0] = lod_density(bd, (const float(*)[3])bv, n, sum, vc, sc, sigma);
	}
	kd = kw[2] > kw[1] ? 2 : kw[1] > 0 ? 1 : 0;
	out[3] = best[kd]; /* kd 0: no voxel of a kind, all are kind 0 */
}

/* ------------------------------------------------------------ the loader */

struct lodscratch {
	loom__db_reader *r;
	uint8_t *buf; /* one level-0 brick */
};

size_t loom__lod_scratch_bytes(const loom_db *db)
{
	loom__db_geom g;
	loom__db_geometry(db, &g);
	return loom__db_reader_bytes(db) + sizeof(struct lodscratch) + g.brick_bytes;
}

void *loom__lod_scratch_new(void *ctx)
{
	loom_texture *t = ctx;
	loom__db_geom g;
	struct lodscratch *s = calloc(1, sizeof *s);

	if (!s)
		return NULL;
	loom__db_geometry(t->db, &g);
	s->r = loom__db_reader_new(t->db);
	s->buf = malloc(g.brick_bytes);
	if (!s->r || !s->buf) {
		loom__lod_scratch_free(ctx, s);
		return NULL;
	}
	return s;
}

void loom__lod_scratch_free(void *ctx, void *scratch)
{
	struct lodscratch *s = scratch;
	(void)ctx;
	if (!s)
		return;
	loom__db_reader_free(s->r);
	free(s->buf);
	free(s);
}

int loom__lod_load(void *ctx, uint64_t id, void *dst, void *scratch, loom_diag *diag)
{
	loom_texture *t = ctx;
	struct lodscratch *s = scratch;
	uint8_t *out = dst;
	const struct exm *e = NULL;
	uint32_t u = 0, k = 0, loc, ci, cj, ck, n;
	size_t cv = t->cbv;

	if (id < t->n_bricks) {
		size_t nr = 0;
		int rc = loom__db_reader_read(s->r, (uint32_t)id, dst, &nr, diag);
		atomic_fetch_add_explicit(&t->bytes_read, nr, memory_order_relaxed);
		if (rc == LOOM_OK) /* the air tests and region extents, as without LOD */
			loom__texture_occ_loaded(t, id, dst);
		return rc;
	}
	/* which exemplar and level: the last (u, k) whose first id is <= id */
	for (uint32_t v = 0; v < t->n_ex; v++)
		for (uint32_t l = 1; l <= t->lod; l++)
			if (t->ex[v].lfirst[l] <= id) {
				u = v;
				k = l;
			}
	e = &t->ex[u];
	if (!k || id - e->lfirst[k] >= (uint64_t)e->lnb[k][0] * e->lnb[k][1] * e->lnb[k][2])
		return loom__fail(diag, LOOM_EINVAL, "texture: coarse brick %llu out of range",
		                  (unsigned long long)id);
	loc = (uint32_t)(id - e->lfirst[k]);
	ck = loc % e->lnb[k][2];
	ci = loc / e->lnb[k][2] % e->lnb[k][0];
	cj = loc / e->lnb[k][2] / e->lnb[k][0];
	n = 1u << k;
	memset(out, 0, LOD_PLANES * cv);
	/* the level-0 bricks it covers: 2^k x 2^k x 2^(k-1) */
	for (uint32_t fj = cj * n; fj < (cj + 1) * n && fj < e->nb[1]; fj++)
		for (uint32_t fi = ci * n; fi < (ci + 1) * n && fi < e->nb[0]; fi++)
			for (uint32_t fk = ck * n / 2; fk < (ck + 1) * n / 2 && fk < e->nb[2]; fk++) {
				uint32_t fid = e->first_brick + (fj * e->nb[0] + fi) * e->nb[2] + fk;
				size_t nr = 0;
				int rc;
				if (brick_empty(t, fid))
					continue;
				rc = loom__db_reader_read(s->r, fid, s->buf, &nr, diag);
				atomic_fetch_add_explicit(&t->bytes_read, nr, memory_order_relaxed);
				if (rc != LOOM_OK)
					return rc;
				/* its coarse voxels: bs / n per axis */
				for (uint32_t y = 0; y < t->bs[1] / n; y++)
					for (uint32_t x = 0; x < t->bs[0] / n; x++)
						for (uint32_t z = 0; z < t->bs[2] / n; z++) {
							uint32_t lx = (fi - ci * n) * (t->bs[0] / n) + x;
							uint32_t ly = (fj - cj * n) * (t->bs[1] / n) + y;
							uint32_t lz = (fk - ck * n / 2) * (t->bs[2] / n) + z;
							size_t i = ((size_t)ly * t->cbs[0] + lx) * t->cbs[2] + lz;
							uint8_t v[LOD_PLANES];
							filter_box(s->buf, t->bs, t->bv, e->kind, x * n, y * n,
							           z * n, n, t->lod_sigma, v);
							for (int p = 0; p < LOD_PLANES; p++)
								out[p * cv + i] = v[p];
						}
			}
	return LOOM_OK;
}

/* ------------------------------------------------------------- lookups */

/* Coarse voxel (X, Y, Z) of level k of exemplar e into v (zeros outside
   the level's volume). */
static int lod_read(loom_texture *t, struct tslot *s, const struct exm *e, unsigned k,
                    int64_t X, int64_t Y, int64_t Z, uint8_t v[LOD_PLANES])
{
	uint64_t id;
	size_t i;
	int rc;

	memset(v, 0, LOD_PLANES);
	if (X < 0 || Y < 0 || Z < 0 || X >= e->lsize[k][0] || Y >= e->lsize[k][1] ||
	    Z >= e->lsize[k][2])
		return LOOM_OK;
	id = e->lfirst[k] +
	     ((uint64_t)(Y / t->cbs[1]) * e->lnb[k][0] + (uint64_t)(X / t->cbs[0])) *
	             e->lnb[k][2] +
	     (uint64_t)(Z / t->cbs[2]);
	if ((rc = memo_use(t, s, id)) != LOOM_OK)
		return rc;
	if (!s->memo)
		return LOOM_OK;
	i = ((size_t)(Y % t->cbs[1]) * t->cbs[0] + (size_t)(X % t->cbs[0])) * t->cbs[2] +
	    (size_t)(Z % t->cbs[2]);
	for (int p = 0; p < LOD_PLANES; p++)
		v[p] = s->memo[p * t->cbv + i];
	return LOOM_OK;
}

int loom__lod_voxel(loom_texture *t, uint32_t u, unsigned k, int64_t X, int64_t Y,
                    int64_t Z, uint8_t out[5])
{
	struct tslot *s;
	int rc;

	if (!t || !out || u >= t->n_ex || k < 1 || k > t->lod)
		return LOOM_EINVAL;
	s = slot_enter(t);
	rc = lod_read(t, s, &t->ex[u], k, X, Y, Z, out);
	slot_leave(t, s);
	return rc;
}

/* Clamp a coarse coordinate to [0, n) in x and y (edge voxels repeat). */
static int64_t clampc(int64_t v, uint32_t n)
{
	return v < 0 ? 0 : v >= (int64_t)n ? (int64_t)n - 1 : v;
}

/* Level-k lookup at p (checked): the crossing and column offset of level 0
   at floor(p), the source position scaled by 2^-k, then the coarse voxel
   containing it (nearest) or the 8 around it (trilinear). */
static int lod_sample(loom_texture *t, struct tslot *s, const double p[3], int filter,
                      unsigned k, loom_texel *out, float *spread)
{
	int64_t x = (int64_t)floor(p[0]), y = (int64_t)floor(p[1]);
	struct xent *e = s->cur;
	double c[3], sc = 1.0 / (double)(1u << k), f[3];
	int64_t i0[3];
	uint8_t v[8][LOD_PLANES];
	float w[8], wd[8], dir[8][3], dens = 0, an = 0, wsum = 0;
	int rc = LOOM_OK, near = 0, nc;
	uint8_t lab;

	memset(out, 0, sizeof *out);
	*spread = 0;
	if (!e || (uint64_t)(x - e->x0) >= t->b1 || (uint64_t)(y - e->y0) >= t->b2)
		e = loom__xent_enter(t, s, x, y);
	{
		uint32_t lx = (uint32_t)(x - e->x0), ly = (uint32_t)(y - e->y0);
		int q = xent_dz(t, s, e, lx, ly);
		c[0] = ((double)e->sx0 + (p[0] - (double)e->x0)) * sc;
		c[1] = ((double)e->sy0 + (p[1] - (double)e->y0)) * sc;
		c[2] = (p[2] - (double)q / DZ_SUB) * sc;
	}
	if (filter == LOOM_FILTER_NEAREST) {
		nc = 1;
		for (int a = 0; a < 3; a++) {
			i0[a] = (int64_t)floor(c[a]);
			f[a] = 0;
		}
	} else {
		nc = 8;
		for (int a = 0; a < 3; a++) {
			double uu = c[a] - 0.5;
			i0[a] = (int64_t)floor(uu);
			f[a] = uu - (double)i0[a];
		}
		near = (f[2] >= 0.5) | (f[0] >= 0.5) << 1 | (f[1] >= 0.5) << 2;
	}
	for (int q = 0; q < nc; q++) {
		int dz = q & 1, dx = q >> 1 & 1, dy = q >> 2 & 1;
		int r2 = lod_read(t, s, e->ex, k, clampc(i0[0] + dx, e->ex->lsize[k][0]),
		                  clampc(i0[1] + dy, e->ex->lsize[k][1]), i0[2] + dz, v[q]);
		if (r2 != LOOM_OK && rc == LOOM_OK)
			rc = r2;
		w[q] = nc == 1 ? 1.0f
		               : (float)((dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) *
		                         (dz ? f[2] : 1 - f[2]));
		wd[q] = 0;
		dir[q][0] = dir[q][1] = dir[q][2] = 0;
		if (v[q][0]) {
			float d = t->dens[v[q][0]];
			dens += w[q] * d;
			wd[q] = w[q] * d;
			wsum += wd[q];
			an += wd[q] * (float)v[q][4] * (1.0f / 255.0f);
			loom__orient_decode((uint16_t)(v[q][1] | v[q][2] << 8), dir[q]);
		}
	}
	bump(&s->cnt.lookups, (uint64_t)nc);
	if (!(dens > 0))
		return rc;
	out->density = dens;
	loom__orient_blend((unsigned)nc, wd, (const float(*)[3])dir, out->orientation);
	lab = v[near][3];
	if (!v[near][0]) /* the nearest corner is empty: the heaviest one's */
		for (int q = 0, b = -1; q < nc; q++)
			if (wd[q] > 0 && (b < 0 || wd[q] > wd[b])) {
				b = q;
				lab = v[q][3];
			}
	out->label = lab;
	out->kind = e->ex->kind[lab];
	if (out->kind) {
		out->type = e->tok[out->kind];
		memcpy(out->albedo, t->albedo[out->type], sizeof out->albedo);
		out->alignment = t->align[out->type];
	}
	an = wsum > 0 ? an / wsum : 0;
	an = an < 0 ? 0 : an > 1 ? 1 : an; /* rounding of the weighted mean */
	*spread = LOD_SPREAD_GAIN * (1.0f - an) / 3.0f;
	return rc;
}

LOOM_API unsigned loom_texture_lod_levels(const loom_texture *t)
{
	return t ? t->lod : 0;
}

LOOM_API int loom_texture_sample_lod(loom_texture *t, const double p[3], int filter,
                                     unsigned level, loom_texel *out, float *spread)
{
	struct tslot *s;
	float sp = 0;
	int rc;

	if (spread)
		*spread = 0;
	if (level == 0 || !t || !t->lod)
		return loom_texture_sample(t, p, filter, out);
	if (out)
		memset(out, 0, sizeof *out);
	if (!p || !out || (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	for (int a = 0; a < 3; a++) {
		if (!isfinite(p[a]))
			return LOOM_EINVAL;
		if (!(fabs(p[a]) < (double)(COORD_LIMIT / 2)))
			return LOOM_ERANGE;
	}
	if (level > t->lod)
		level = t->lod;
	s = slot_enter(t);
	rc = lod_sample(t, s, p, filter, level, out, &sp);
	slot_leave(t, s);
	if (spread)
		*spread = sp;
	return rc;
}
