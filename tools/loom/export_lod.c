/*
 * tools/loom/export_lod.c - `loom export --lod L`: a tile's voxels
 * downsampled by s = 2^L before it is written (docs/batch.md, "Level of
 * detail").  Coarse voxel (I, J, K) covers the fine voxels [I*s, (I+1)*s)
 * x [J*s, (J+1)*s) x [K*s, (K+1)*s) of the virtual texture, so a coarse
 * tile sits exactly where its fine voxels were and tiles stay edge to edge
 * in millimetres.  Per coarse voxel, over its s^3 fine voxels:
 *
 *   density      the mean (empty voxels count as 0)
 *   orientation  the principal eigenvector of T = sum rho w w^T (the
 *                density-weighted structure tensor: w and -w are the same
 *                fibre, so vectors are not averaged), unit, z >= 0
 *   albedo       sum rho a / sum rho over the voxels with a yarn
 *   kind, type   the value with the largest summed density (ties: the
 *                smaller value); 0 when the coarse voxel is empty
 */
#include "export.h"

#include <math.h>
#include <string.h>

/* Unit eigenvector of the largest eigenvalue of the symmetric 3x3 matrix a,
   by loom_scan_eigen_min (the scan's structure-tensor solver) on -a.  When
   the two largest eigenvalues are equal, any axis normal to the smallest
   one's eigenvector is principal; when all three are, any axis is. */
static void principal_eigvec(double a[3][3], double out[3])
{
	double m[6] = {-a[0][0], -a[0][1], -a[0][2], -a[1][1], -a[1][2], -a[2][2]};
	double n[3], len;
	int k = 0;

	if (loom_scan_eigen_min(m, out, NULL))
		return;
	for (int i = 0; i < 6; i++)
		m[i] = -m[i];
	if (!loom_scan_eigen_min(m, n, NULL)) {
		out[0] = 1, out[1] = 0, out[2] = 0;
		return;
	}
	for (int i = 1; i < 3; i++) /* the axis least aligned with n */
		if (fabs(n[i]) < fabs(n[k]))
			k = i;
	out[0] = k == 0 ? 0 : k == 1 ? -n[2] : n[1]; /* n x e_k */
	out[1] = k == 0 ? n[2] : k == 1 ? 0 : -n[0];
	out[2] = k == 0 ? -n[1] : k == 1 ? n[0] : 0;
	len = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
	for (int i = 0; i < 3; i++)
		out[i] /= len;
}

void export_albedo(const struct export_ctx *c, const struct ewstate *w, int64_t x,
                   int64_t y, uint8_t kd, uint8_t ty, float out[3])
{
	memcpy(out, c->albedo[ty], 3 * sizeof(float));
	if (w->tint)
		loom_paint_albedo(c->j->paint, x, y, kd, out);
}

void export_lod_tile(const struct export_ctx *c, struct ewstate *w, const int64_t n[3])
{
	const size_t s = (size_t)1 << c->lod;
	const size_t nx = (size_t)n[0], ny = (size_t)n[1];
	const size_t cx = nx / s, cy = ny / s, cz = (size_t)n[2] / s;
	const double inv = 1.0 / (double)(s * s * s);
	float *lv = w->lv;

	for (size_t k = 0; k < cz; k++)
		for (size_t j = 0; j < cy; j++)
			for (size_t i = 0; i < cx; i++) {
				double rho = 0, t[3][3] = {{0}}, alb[3] = {0}, wa = 0, kw[3] = {0};
				float *o = lv + ((k * cy + j) * cx + i) * LOD_FLOATS;
				uint8_t seen[256];
				unsigned nseen = 0;

				for (size_t z = k * s; z < (k + 1) * s; z++)
					for (size_t y = j * s; y < (j + 1) * s; y++)
						for (size_t x = i * s; x < (i + 1) * s; x++) {
							size_t f = (z * ny + y) * nx + x;
							double r = w->d[f] / 255.0;
							float dir[3];
							uint8_t kd = w->k[f], ty = w->ty[f];
							if (!w->d[f])
								continue;
							rho += r;
							if (c->chmask & 1u << CH_ORIENT) {
								loom_orientation_decode(w->o[f], dir);
								for (int a = 0; a < 3; a++)
									for (int b = 0; b < 3; b++)
										t[a][b] += r * dir[a] * dir[b];
							}
							if (kd) {
								if (kd < 3)
									kw[kd] += r;
								wa += r;
								float a3[3];
								export_albedo(c, w, w->lo[0] + (int64_t)x,
								              w->lo[1] + (int64_t)y, kd, ty, a3);
								for (int q = 0; q < 3; q++)
									alb[q] += r * a3[q];
								if (w->tw[ty] == 0.0) {
									seen[nseen++] = ty;
								}
								w->tw[ty] += r;
							}
						}
				memset(o, 0, LOD_FLOATS * sizeof *o);
				o[0] = (float)(rho * inv);
				if (rho > 0 && (c->chmask & 1u << CH_ORIENT)) {
					double e[3], len;
					principal_eigvec(t, e);
					len = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
					/* a line direction: z >= 0 (then x, then y, for z = 0) */
					if (e[2] < 0 || (e[2] == 0 && (e[0] < 0 || (e[0] == 0 && e[1] < 0))))
						len = -len;
					for (int q = 0; q < 3; q++)
						o[1 + q] = (float)(e[q] / len);
				}
				if (wa > 0) {
					unsigned best_kind = kw[2] > kw[1] ? 2 : 1;
					int best_type = -1;
					for (int q = 0; q < 3; q++)
						o[4 + q] = (float)(alb[q] / wa);
					for (unsigned u = 0; u < nseen; u++) {
						int ty = seen[u];
						if (best_type < 0 || w->tw[ty] > w->tw[best_type] ||
						    (w->tw[ty] == w->tw[best_type] && ty < best_type))
							best_type = ty;
					}
					o[7] = (float)best_kind;
					o[8] = (float)best_type;
				}
				for (unsigned u = 0; u < nseen; u++)
					w->tw[seen[u]] = 0.0;
			}
	/* the raw kind and type of the coarse voxels, for writers that take
	   bytes (NRRD): the fine ones are no longer needed */
	for (size_t v = 0; v < cx * cy * cz; v++) {
		w->k[v] = (uint8_t)lv[v * LOD_FLOATS + 7];
		w->ty[v] = (uint8_t)lv[v * LOD_FLOATS + 8];
	}
}
