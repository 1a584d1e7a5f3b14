/*
 * engine/scan/scan_sheet.c - scan-like test volumes of a woven sheet with known
 * ground truth (loom exemplar generate --scan, tests, bench).
 *
 * The sheet lives in the aligned frame (u, v, z): warp j is a tube along v
 * at u = x0 + j*sx, weft i a tube along u at v = y0 + i*sy.  Centre lines
 * rise and fall with the weave (crimp): at crossing (i,j) the warp is at
 * zc + warp_amp when W(i,j) = 1 and zc - warp_amp otherwise, the weft the
 * opposite, with cosine blends between crossings.  Cross sections are
 * ellipses measured perpendicular to the tangent.  Inside, the density has
 * a fibre texture (value noise on the cross-section coordinates, constant
 * along the yarn) so the structure tensor sees fibres.  The scan shows the
 * sheet turned by angle_deg about z around c = ((nx-1)/2, (ny-1)/2): scan
 * point s shows aligned point a = c + R(-angle)(s - c).  Then a Gaussian
 * blur (the scanner's PSF) and Gaussian noise, clamped to [0,1].
 */
#include "scan_internal.h"

#include <stdlib.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static uint64_t sh_mix(uint64_t z)
{
	z += 0x9E3779B97F4A7C15ull;
	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
	return z ^ (z >> 31);
}

static double sh_unit(uint64_t h)
{
	return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}

LOOM_API int loom_scan_sheet_w(const loom_scan_sheet *s, long i, long j)
{
	long R = s->rep_rows, C = s->rep_cols;
	if (R <= 0 || C <= 0 || !s->weave)
		return 0;
	i %= R;
	j %= C;
	if (i < 0)
		i += R;
	if (j < 0)
		j += C;
	return s->weave[i * C + j] != 0;
}

/* crimp profile h in [-1,1] and its derivative along the yarn */
static void crimp(const loom_scan_sheet *s, int warp, long yarn, double pos,
                  double p0, double step, double *h, double *dh)
{
	double f = (pos - p0) / step;
	long k = (long)floor(f);
	double t = f - (double)k, a, b;
	if (warp) {
		a = loom_scan_sheet_w(s, k, yarn) ? 1 : -1;
		b = loom_scan_sheet_w(s, k + 1, yarn) ? 1 : -1;
	} else {
		a = loom_scan_sheet_w(s, yarn, k) ? -1 : 1;
		b = loom_scan_sheet_w(s, yarn, k + 1) ? -1 : 1;
	}
	*h = a * 0.5 * (1 + cos(M_PI * t)) + b * 0.5 * (1 - cos(M_PI * t));
	*dh = (b - a) * 0.5 * M_PI * sin(M_PI * t) / step;
}

/* Foot point of (pos, z) on a yarn's centre curve by Newton steps:
   height and slope there, signed distance along the normal. */
static void foot(const loom_scan_sheet *s, int warp, long yarn, double pos,
                 double z, double p0, double step, double amp, double *zc,
                 double *slope, double *dn)
{
	double f = pos, h, dh, n;
	for (int it = 0; it < 4; it++) {
		double zf, sl;
		crimp(s, warp, yarn, f, p0, step, &h, &dh);
		zf = s->zc + amp * h;
		sl = amp * dh;
		f += ((pos - f) + sl * (z - zf)) / (1 + sl * sl);
	}
	crimp(s, warp, yarn, f, p0, step, &h, &dh);
	*zc = s->zc + amp * h;
	*slope = amp * dh;
	n = sqrt(1 + *slope * *slope);
	*dn = (-(*slope) * (pos - f) + (z - *zc)) / n;
}

static double fibre(uint64_t seed, long yarn, double a, double b, double cell)
{
	double fa = a / cell, fb = b / cell;
	long ia = (long)floor(fa), ib = (long)floor(fb);
	double ta = fa - (double)ia, tb = fb - (double)ib, v[2][2];
	ta = ta * ta * (3 - 2 * ta);
	tb = tb * tb * (3 - 2 * tb);
	for (int p = 0; p < 2; p++)
		for (int q = 0; q < 2; q++)
			v[p][q] = sh_unit(sh_mix(seed ^ sh_mix((uint64_t)yarn * 1000003u ^
			                  sh_mix((uint64_t)(ia + p) * 92821u ^
			                         (uint64_t)(ib + q) * 68917u))));
	return (1 - ta) * ((1 - tb) * v[0][0] + tb * v[0][1]) +
	       ta * ((1 - tb) * v[1][0] + tb * v[1][1]);
}

LOOM_API void loom_scan_sheet_voxel(const loom_scan_sheet *s, uint32_t x,
                                    uint32_t y, uint32_t z, float *dens,
                                    uint8_t *lab, float tan_out[3], float *rad)
{
	double cx = (s->nx - 1) * 0.5, cy = (s->ny - 1) * 0.5;
	double th = s->angle_deg * M_PI / 180, c = cos(th), sn = sin(th);
	double dx = x - cx, dy = y - cy;
	double u = cx + c * dx + sn * dy, v = cy - sn * dx + c * dy;
	double best = 1e30, bt[3] = {0, 0, 0}, bl = 0, bz = 0;
	long by = -1;
	long jn = lround((u - s->x0) / s->sx), in_ = lround((v - s->y0) / s->sy);

	for (long j = jn - 1; j <= jn + 1; j++) {
		double du, zc, slope, dz, r2, n;
		if (j < 0 || j >= (long)s->nw)
			continue;
		du = u - (s->x0 + (double)j * s->sx);
		if (fabs(du) >= 1.5 * s->warp_w ||
		    fabs(z - s->zc) >= s->warp_amp + 1.5 * s->warp_h)
			continue;
		foot(s, 1, j, v, z, s->y0, s->sy, s->warp_amp, &zc, &slope, &dz);
		r2 = (du / s->warp_w) * (du / s->warp_w) + (dz / s->warp_h) * (dz / s->warp_h);
		if (r2 < best) {
			best = r2;
			by = j;
			n = sqrt(1 + slope * slope);
			bt[0] = -sn / n;
			bt[1] = c / n;
			bt[2] = slope / n;
			bl = du;
			bz = dz;
		}
	}
	for (long i = in_ - 1; i <= in_ + 1; i++) {
		double dv, zc, slope, dz, r2, n;
		if (i < 0 || i >= (long)s->nf)
			continue;
		dv = v - (s->y0 + (double)i * s->sy);
		if (fabs(dv) >= 1.5 * s->weft_w ||
		    fabs(z - s->zc) >= s->weft_amp + 1.5 * s->weft_h)
			continue;
		foot(s, 0, i, u, z, s->x0, s->sx, s->weft_amp, &zc, &slope, &dz);
		r2 = (dv / s->weft_w) * (dv / s->weft_w) + (dz / s->weft_h) * (dz / s->weft_h);
		if (r2 < best) {
			best = r2;
			by = (long)s->nw + i;
			n = sqrt(1 + slope * slope);
			bt[0] = c / n;
			bt[1] = sn / n;
			bt[2] = slope / n;
			bl = dv;
			bz = dz;
		}
	}
	if (rad)
		*rad = best < 81 ? (float)sqrt(best) : 9.0f;
	if (best < 1) {
		*dens = (float)(0.55 + 0.45 * fibre(s->seed, by, bl, bz, s->fibre));
		*lab = (uint8_t)(by + 1);
		for (int k = 0; k < 3; k++)
			tan_out[k] = (float)bt[k];
	} else {
		*dens = 0;
		*lab = 0;
		tan_out[0] = tan_out[1] = tan_out[2] = 0;
	}
}

LOOM_API int loom_scan_sheet_preset(const char *name, loom_scan_sheet *s)
{
	if (!s || !name)
		return LOOM_EINVAL;
	memset(s, 0, sizeof *s);
	s->size = sizeof *s;
	if (strcmp(name, "small") == 0) {
		/* 7 x 9 yarns, spacing 24 x 18, yarns 18 x 10 and 14 x 10 voxels */
		s->nx = 160;
		s->ny = 160;
		s->nz = 40;
		s->nw = 7;
		s->nf = 9;
		s->sx = 24;
		s->sy = 18;
		s->x0 = 6;
		s->y0 = 7;
		s->warp_w = 9;
		s->warp_h = 5;
		s->weft_w = 7;
		s->weft_h = 5;
		s->warp_amp = 5.5f;
		s->weft_amp = 5.5f;
		s->zc = 20;
		s->fibre = 1.5f;
	} else if (strncmp(name, "paper", 5) == 0 &&
	           (name[5] == 0 || name[5] == ':')) {
		/* the paper's proportions (warp spacing 0.115 n, weft 0.07 n,
		   n x n x 0.3 n; n = 1000 by default: 5 um voxels) */
		char *end;
		unsigned long n = 1000;
		if (name[5] == ':') {
			n = strtoul(name + 6, &end, 10);
			if (*end || n < 64 || n > 4000)
				return LOOM_EINVAL;
		}
		s->nx = s->ny = (uint32_t)n;
		s->nz = (uint32_t)(0.3 * (double)n);
		s->sx = 0.115f * (float)n;
		s->sy = 0.07f * (float)n;
		s->x0 = 0.3f * s->sx;
		s->y0 = 0.4f * s->sy;
		s->nw = (uint32_t)(((float)n - 0.6f * s->sx) / s->sx) + 1;
		s->nf = (uint32_t)(((float)n - 0.8f * s->sy) / s->sy) + 1;
		s->warp_w = 0.39f * s->sx;
		s->weft_w = 0.39f * s->sy;
		s->warp_h = s->weft_h = 0.3f * s->sy;
		s->warp_amp = s->weft_amp = 1.1f * s->warp_h;
		s->zc = 0.5f * (float)(s->nz - 1);
		s->fibre = 1.5f;
	} else {
		return LOOM_EINVAL;
	}
	s->angle_deg = 3;
	s->blur = 0.8f;
	s->noise = 0.08f;
	s->seed = 7;
	return LOOM_OK;
}

LOOM_API int loom_scan_sheet_truth(const loom_scan_sheet *s,
                                   loom_scan_sheet_grid *g)
{
	long best = 0;
	double best_d = 0, cx, cy;

	if (!s || !g || s->nw < 2 || s->nf < 2 || !(s->sx > 0) || !(s->sy > 0))
		return LOOM_EINVAL;
	memset(g, 0, sizeof *g);
	cx = (s->nx - 1) * 0.5;
	cy = (s->ny - 1) * 0.5;
	for (uint32_t ja = 0; ja < s->nw; ja++)
		for (uint32_t jb = ja + 1; jb < s->nw; jb++)
			for (uint32_t ia = 0; ia < s->nf; ia++)
				for (uint32_t ib = ia + 1; ib < s->nf; ib++) {
					double x0 = s->x0 + (ja - 0.5) * s->sx, x1 = s->x0 + (jb + 0.5) * s->sx - 1;
					double y0 = s->y0 + (ia - 0.5) * s->sy, y1 = s->y0 + (ib + 0.5) * s->sy - 1;
					double dd = pow((x0 + x1) / 2 - cx, 2) + pow((y0 + y1) / 2 - cy, 2);
					long cells = (long)(jb - ja + 1) * (ib - ia + 1);
					double corners[4][2] = {{x0, y0}, {x1, y0}, {x0, y1}, {x1, y1}};
					int inside = 1;
					if (cells < best || (cells == best && dd >= best_d))
						continue;
					for (int k = 0; k < 4; k++) {
						double sx, sy;
						loom_scan_aligned_to_scan(s->nx, s->ny, s->angle_deg,
						                          corners[k][0], corners[k][1], &sx, &sy);
						if (sx < 0 || sy < 0 || sx > s->nx - 1 || sy > s->ny - 1)
							inside = 0;
					}
					if (!inside)
						continue;
					best = cells;
					best_d = dd;
					g->first_warp = ja;
					g->cols = jb - ja + 1;
					g->first_weft = ia;
					g->rows = ib - ia + 1;
				}
	if (!best)
		return LOOM_EUNSUPPORTED;
	g->b1 = (uint32_t)lround(s->sx);
	g->b2 = (uint32_t)lround(s->sy);
	g->crop[0] = s->x0 + (g->first_warp - 0.5) * s->sx;
	g->crop[1] = s->y0 + (g->first_weft - 0.5) * s->sy;
	g->crop[2] = (double)g->cols * g->b1;
	g->crop[3] = (double)g->rows * g->b2;
	return LOOM_OK;
}

typedef struct sheet_job {
	const loom_scan_sheet *s;
	loom_scan_volume *v;
	uint8_t *truth;
} sheet_job;

static void sheet_worker(void *ctx, uint32_t tid, uint32_t nth)
{
	sheet_job *j = ctx;
	const loom_scan_sheet *s = j->s;
	loom_scan_volume *v = j->v;

	for (uint32_t z = tid; z < s->nz; z += nth)
		for (uint32_t y = 0; y < s->ny; y++)
			for (uint32_t x = 0; x < s->nx; x++) {
				size_t i = loom__scan_idx(v, x, y, z);
				float t[3];
				uint8_t lab;
				if (s->pure_noise) {
					v->density[i] = (float)sh_unit(sh_mix(s->seed ^ (i * 7919u)));
					continue;
				}
				loom_scan_sheet_voxel(s, x, y, z, &v->density[i], &lab, t, NULL);
				if (j->truth)
					j->truth[i] = lab;
				if (v->orient)
					memcpy(v->orient + 3 * i, t, sizeof t);
			}
}

typedef struct noise_job {
	const loom_scan_sheet *s;
	float *d;
	size_t n;
} noise_job;

static void noise_worker(void *ctx, uint32_t tid, uint32_t nth)
{
	noise_job *j = ctx;
	size_t a = j->n * tid / nth, b = j->n * (tid + 1) / nth;
	for (size_t i = a; i < b; i++) {
		double d = j->d[i];
		if (j->s->noise > 0) {
			double u1 = sh_unit(sh_mix(j->s->seed * 31 + 2 * i + 1));
			double u2 = sh_unit(sh_mix(j->s->seed * 31 + 2 * i + 2));
			d += j->s->noise * sqrt(-2 * log(u1 + 1e-300)) * cos(2 * M_PI * u2);
		}
		j->d[i] = (float)(d < 0 ? 0 : d > 1 ? 1 : d);
	}
}

LOOM_API int loom_scan_sheet_make(const loom_scan_sheet *s, loom_scan_volume *v,
                                  uint8_t *truth, uint32_t threads,
                                  loom_diag *diag)
{
	sheet_job j;
	int rc;

	if (!s || s->size != sizeof *s || !v || !v->density)
		return loom__fail(diag, LOOM_EINVAL, "scan sheet: bad arguments");
	if (v->nx != s->nx || v->ny != s->ny || v->nz != s->nz)
		return loom__fail(diag, LOOM_EINVAL, "scan sheet: volume is %ux%ux%u, the "
		                  "sheet %ux%ux%u", v->nx, v->ny, v->nz, s->nx, s->ny, s->nz);
	if (!s->pure_noise &&
	    (s->nw < 1 || s->nf < 1 || s->nw + s->nf > 2 * LOOM_SCAN_MAX_YARNS ||
	     !(s->sx > 0) || !(s->sy > 0) || !s->weave || !s->rep_rows || !s->rep_cols ||
	     !(s->warp_w > 0) || !(s->warp_h > 0) || !(s->weft_w > 0) ||
	     !(s->weft_h > 0) || !(s->fibre > 0)))
		return loom__fail(diag, LOOM_EINVAL, "scan sheet: bad yarn counts, "
		                  "spacings, sizes or weave");
	j.s = s;
	j.v = v;
	j.truth = truth;
	loom__scan_parallel(threads ? threads : 1, sheet_worker, &j);
	if (s->pure_noise)
		return LOOM_OK;
	if (s->blur > 0) {
		float *o = v->orient;
		v->orient = NULL; /* the blur only reads density */
		rc = loom_scan_denoise(v, s->blur, threads, diag);
		v->orient = o;
		if (rc)
			return rc;
	}
	{
		noise_job nj = {s, v->density, (size_t)v->nx * v->ny * v->nz};
		loom__scan_parallel(threads ? threads : 1, noise_worker, &nj);
	}
	return LOOM_OK;
}
