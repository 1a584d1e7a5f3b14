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

/* Eigenvector of the largest eigenvalue of the symmetric 3x3 matrix a
   (cyclic Jacobi rotations, a fixed number of sweeps: deterministic). */
static void principal_eigvec(double a[3][3], double out[3])
{
	double v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
	int best = 0;

	for (int sweep = 0; sweep < 32; sweep++) {
		double off = fabs(a[0][1]) + fabs(a[0][2]) + fabs(a[1][2]);
		double scale = fabs(a[0][0]) + fabs(a[1][1]) + fabs(a[2][2]);
		if (off <= 1e-15 * scale || off == 0.0)
			break;
		for (int p = 0; p < 2; p++)
			for (int q = p + 1; q < 3; q++) {
				double theta, t, c, s;
				if (a[p][q] == 0.0)
					continue;
				theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
				t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
				c = 1.0 / sqrt(t * t + 1.0);
				s = t * c;
				/* A' = R^T A R with the rotation in the (p, q) plane */
				for (int k = 0; k < 3; k++) {
					double akp = a[k][p], akq = a[k][q];
					a[k][p] = c * akp - s * akq;
					a[k][q] = s * akp + c * akq;
				}
				for (int k = 0; k < 3; k++) {
					double apk = a[p][k], aqk = a[q][k];
					a[p][k] = c * apk - s * aqk;
					a[q][k] = s * apk + c * aqk;
				}
				for (int k = 0; k < 3; k++) {
					double vkp = v[k][p], vkq = v[k][q];
					v[k][p] = c * vkp - s * vkq;
					v[k][q] = s * vkp + c * vkq;
				}
			}
	}
	for (int k = 1; k < 3; k++)
		if (a[k][k] > a[best][best])
			best = k;
	for (int k = 0; k < 3; k++)
		out[k] = v[k][best];
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
								for (int q = 0; q < 3; q++)
									alb[q] += r * c->albedo[ty][q];
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
