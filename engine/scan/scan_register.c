/*
 * engine/scan/scan_register.c - scan pipeline steps 7 and 8 (alignment by PCA of
 * yarn directions, paper 6.4; weaving-grid registration and crop, 6.5) and
 * the whole pipeline, loom_scan_build.
 *
 * Frames.  The scan frame is the input volume.  The aligned frame is the
 * scan turned by -rotation about z around c = ((nx-1)/2, (ny-1)/2), same
 * size: aligned point a shows scan point s = c + R(rotation)(a - c).  The
 * footprint (aligned points whose s falls inside the scan) is a rotated
 * rectangle; the crop must lie inside it.  The output volume is the crop
 * window [x0, x0+w) x [y0, y0+h) of the aligned frame, resampled from the
 * scan (bilinear density, nearest orientation turned by -rotation), and
 * labelled again by nearest centre curve (curves moved into the output
 * frame), so labels follow the resampled density exactly.
 *
 * Registration (paper 6.5).  b(x,y) is the aligned top-yarn map: 1 where
 * the topmost voxel above the threshold belongs to a warp, 0 where it is a
 * weft, unknown (never agreeing) where there is no material or no scan.
 * (The paper's b writes 0 for warp because its patterns use 0 for warp
 * over; loom's W uses 1 for warp over, so b uses 1 too and "agree" means
 * b == W.)  Step by step:
 *   1. centre of every tracked yarn in the aligned frame; pitches px, py =
 *      least-squares slope of centre against index over the interior yarns;
 *      block b1 x b2 = user's or rounded pitch;
 *   2. the complete yarns: the largest run of warps ja..jb and wefts ia..ib
 *      whose grid window (origin fitted to their centres, cells centred on
 *      the yarns, size (jb-ja+1) b1 x (ib-ia+1) b2) lies inside the
 *      footprint; ties go to the window nearest the scan's centre;
 *   3. summed-area tables of [b == 1] and [b == 0]; for every translation
 *      within half a block of the fitted origin (inside the footprint), the
 *      score is the sum over the window's cells of the fraction of b equal
 *      to the cell's W over the cell's central half (b1/2 x b2/2): O(1) per
 *      cell, O(cells) per candidate, O(b1 b2 cells) in all.  The paper
 *      scores whole cells; with a twill the neighbours' floats then pull
 *      the optimum off the crossings by several voxels (3 of 24 in our
 *      tests), while the top yarn over the central half of a cell is the
 *      crossing's own.  Central halves narrower than the yarn make a
 *      plateau of equal scores: the candidate nearest the centroid of all
 *      candidates within 0.5% per cell of the best wins.  Limiting the
 *      search to half a block keeps a periodic weave (a twill matches
 *      itself shifted one crossing diagonally) from sliding the window onto
 *      incomplete yarns.
 */
#include "scan_internal.h"
#include "exemplar/voxel.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Every cell of the crop must show its crossing's yarn on top over at
   least this fraction of its central half (a check on the weave). */
#define MIN_CELL_AGREEMENT 0.5

#define DEG (57.295779513082320876)
#define PLATEAU_TOL 0.005 /* of the cell count: scores this close tie */

LOOM_API void loom_scan_params_init(loom_scan_params *p)
{
	if (!p)
		return;
	memset(p, 0, sizeof *p);
	p->size = sizeof *p;
	p->denoise_sigma = 1.0f;
	p->tensor_sigma = 1.5f;
	p->cone_cos = 0.7f;
	p->max_slices = 64;
	p->kmeans_iters = 50;
	p->gap_ratio = 0.6f;
	p->step = 15;
	p->c0 = 0.7f;
	p->radius_warp = 20;
	p->radius_weft = 30;
	p->ellipse_warp = 40;
	p->ellipse_weft = 30;
	p->ellipse_z = 60;
	p->correct_iters = 10;
	p->min_linking = 0.25f;
	p->threads = 2;
	p->seed = 20121126u;
}

/* ---- alignment ---------------------------------------------------------- */

LOOM_API int loom_scan_align(const loom_scan_moments *m, const int *kinds,
                             uint32_t n, double *rotation_degrees, float *dirs,
                             loom_diag *diag)
{
	double w[2][2] = {{0, 0}, {0, 0}}, len[2], s[2];
	uint64_t med[2] = {0, 0};
	uint32_t first[2], last[2];

	if (!m || !kinds || !rotation_degrees || n == 0)
		return loom__fail(diag, LOOM_EINVAL, "scan: alignment: bad arguments");
	/* Yarns cut lengthwise by the scan border have skewed voxel sets whose
	   principal axis leans toward the border: with 4 or more yarns of a
	   kind the outermost two are left out, and so is any yarn with fewer
	   than 3/4 of the median voxel count of its kind. */
	for (int k = 0; k < 2; k++) {
		uint32_t cnt = 0;
		first[k] = last[k] = UINT32_MAX;
		for (uint32_t i = 0; i < n; i++)
			if ((kinds[i] == LOOM_SCAN_WARP ? 0 : 1) == k) {
				if (first[k] == UINT32_MAX)
					first[k] = i;
				last[k] = i;
				cnt++;
			}
		if (cnt < 4)
			first[k] = last[k] = UINT32_MAX;
	}
	for (int k = 0; k < 2; k++) {
		uint64_t c[2 * LOOM_SCAN_MAX_YARNS];
		uint32_t nc = 0;
		for (uint32_t i = 0; i < n && nc < 2 * LOOM_SCAN_MAX_YARNS; i++)
			if ((kinds[i] == LOOM_SCAN_WARP ? 0 : 1) == k)
				c[nc++] = m[i].n;
		for (uint32_t a = 1; a < nc; a++) {
			uint64_t t = c[a];
			uint32_t b = a;
			while (b > 0 && c[b - 1] > t) {
				c[b] = c[b - 1];
				b--;
			}
			c[b] = t;
		}
		med[k] = nc ? c[nc / 2] : 0;
	}
	for (uint32_t i = 0; i < n; i++) {
		double N = (double)m[i].n, mx, my, cxx, cxy, cyy, ang, d[2];
		int k = kinds[i] == LOOM_SCAN_WARP ? 0 : 1;
		if (dirs)
			dirs[2 * i] = dirs[2 * i + 1] = 0;
		if (m[i].n < 3)
			continue;
		mx = m[i].sx / N;
		my = m[i].sy / N;
		cxx = m[i].sxx / N - mx * mx;
		cxy = m[i].sxy / N - mx * my;
		cyy = m[i].syy / N - my * my;
		ang = 0.5 * atan2(2 * cxy, cxx - cyy);
		d[0] = cos(ang);
		d[1] = sin(ang);
		if ((k == 0 && d[1] < 0) || (k == 1 && d[0] < 0)) {
			d[0] = -d[0];
			d[1] = -d[1];
		}
		if (dirs) {
			dirs[2 * i] = (float)d[0];
			dirs[2 * i + 1] = (float)d[1];
		}
		if (4 * m[i].n < 3 * med[k] || i == first[k] || i == last[k])
			continue;
		w[k][0] += N * d[0];
		w[k][1] += N * d[1];
	}
	for (int k = 0; k < 2; k++) {
		len[k] = sqrt(w[k][0] * w[k][0] + w[k][1] * w[k][1]);
		if (!(len[k] > 0))
			return loom__fail(diag, LOOM_EUNSUPPORTED,
			                  "scan: alignment: no %s voxels to measure a "
			                  "direction from", k ? "weft" : "warp");
	}
	s[0] = w[0][0] / len[0] + w[1][0] / len[1];
	s[1] = w[0][1] / len[0] + w[1][1] / len[1];
	*rotation_degrees = atan2(s[1], s[0]) * DEG - 45.0;
	return LOOM_OK;
}

LOOM_API void loom_scan_aligned_to_scan(uint32_t nx, uint32_t ny,
                                        double rotation_degrees, double ax,
                                        double ay, double *sx, double *sy)
{
	double cx = (nx - 1) * 0.5, cy = (ny - 1) * 0.5;
	double c = cos(rotation_degrees / DEG), s = sin(rotation_degrees / DEG);
	double dx = ax - cx, dy = ay - cy;
	if (sx)
		*sx = cx + c * dx - s * dy;
	if (sy)
		*sy = cy + s * dx + c * dy;
}

static void scan_to_aligned(uint32_t nx, uint32_t ny, double rot, double sx,
                            double sy, double *ax, double *ay)
{
	loom_scan_aligned_to_scan(nx, ny, -rot, sx, sy, ax, ay);
}

/* ---- registration ------------------------------------------------------- */

static int in_footprint(uint32_t nx, uint32_t ny, double rot, double ax, double ay)
{
	double sx, sy;
	loom_scan_aligned_to_scan(nx, ny, rot, ax, ay, &sx, &sy);
	return sx >= -1e-6 && sx <= nx - 1 + 1e-6 && sy >= -1e-6 && sy <= ny - 1 + 1e-6;
}

static int rect_ok(uint32_t nx, uint32_t ny, double rot, long x0, long y0,
                   long w, long h)
{
	return in_footprint(nx, ny, rot, (double)x0, (double)y0) &&
	       in_footprint(nx, ny, rot, (double)(x0 + w - 1), (double)y0) &&
	       in_footprint(nx, ny, rot, (double)x0, (double)(y0 + h - 1)) &&
	       in_footprint(nx, ny, rot, (double)(x0 + w - 1), (double)(y0 + h - 1));
}

/* Yarn pitch: least-squares slope of centre against index, over the
   interior yarns when there are 4 or more (border yarns are often cut and
   their centres pulled inward). */
static double fit_pitch(const double *c, uint32_t n)
{
	uint32_t a = n >= 4 ? 1 : 0, b = n >= 4 ? n - 1 : n;
	double mi = 0, mc = 0, sxy = 0, sxx = 0;
	for (uint32_t i = a; i < b; i++) {
		mi += i;
		mc += c[i];
	}
	mi /= (b - a);
	mc /= (b - a);
	for (uint32_t i = a; i < b; i++) {
		sxy += (i - mi) * (c[i] - mc);
		sxx += (i - mi) * (i - mi);
	}
	return sxx > 0 ? sxy / sxx : 0;
}

LOOM_API int loom_scan_register(uint32_t nx, uint32_t ny, const uint8_t *top,
                                const loom_scan_curve *curves, uint32_t nw,
                                uint32_t nf, const uint8_t *weave,
                                double rot, uint32_t block_x,
                                uint32_t block_y, loom_scan_grid *out,
                                loom_diag *diag)
{
	double cx[LOOM_SCAN_MAX_YARNS], cy[LOOM_SCAN_MAX_YARNS];
	double px, py, pre_x[LOOM_SCAN_MAX_YARNS + 1], pre_y[LOOM_SCAN_MAX_YARNS + 1];
	long b1, b2, best_cells = 0, bx0 = 0, by0 = 0;
	uint32_t bja = 0, bjb = 0, bia = 0, bib = 0;
	double best_dist = 0, best_score = -1;
	uint8_t *b = NULL;
	uint32_t *s1 = NULL, *s0 = NULL;
	size_t W1 = (size_t)nx + 1;
	long best_dx = 0, best_dy = 0;
	double *cand_score, chosen = 0;
	size_t nc;

	if (!top || !curves || !weave || !out || nw < 2 || nf < 2 ||
	    nw > LOOM_SCAN_MAX_YARNS || nf > LOOM_SCAN_MAX_YARNS || nx < 2 || ny < 2)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: registration: bad arguments (need >= 2 warps and "
		                  "wefts)");
	memset(out, 0, sizeof *out);
	/* 1. yarn centres in the aligned frame, pitches, block */
	for (uint32_t i = 0; i < nw + nf; i++) {
		double sum = 0;
		const loom_scan_curve *c = &curves[i];
		if (!c->n || !c->pts)
			return loom__fail(diag, LOOM_EINVAL, "scan: registration: empty curve %u", i);
		for (uint32_t k = 0; k < c->n; k++) {
			double ax, ay;
			scan_to_aligned(nx, ny, rot, c->pts[3 * k], c->pts[3 * k + 1], &ax, &ay);
			sum += i < nw ? ax : ay;
		}
		if (i < nw)
			cx[i] = sum / c->n;
		else
			cy[i - nw] = sum / c->n;
	}
	for (uint32_t i = 0; i + 1 < nw; i++)
		if (!(cx[i + 1] > cx[i]))
			return loom__fail(diag, LOOM_EUNSUPPORTED,
			                  "scan: registration: warps %u and %u are not ordered "
			                  "along x (centres %.1f, %.1f)", i, i + 1, cx[i], cx[i + 1]);
	for (uint32_t i = 0; i + 1 < nf; i++)
		if (!(cy[i + 1] > cy[i]))
			return loom__fail(diag, LOOM_EUNSUPPORTED,
			                  "scan: registration: wefts %u and %u are not ordered "
			                  "along y (centres %.1f, %.1f)", i, i + 1, cy[i], cy[i + 1]);
	px = fit_pitch(cx, nw);
	py = fit_pitch(cy, nf);
	b1 = block_x ? (long)block_x : lround(px);
	b2 = block_y ? (long)block_y : lround(py);
	if (b1 < 1)
		b1 = 1;
	if (b2 < 1)
		b2 = 1;
	if (fabs(b1 - px) > 0.1 * px || fabs(b2 - py) > 0.1 * py)
		loom__warn(diag, "scan: registration: block %ldx%ld differs from the "
		           "measured yarn spacing %.1fx%.1f by more than 10%%",
		           b1, b2, px, py);
	/* 2. the largest window of complete yarns inside the footprint */
	pre_x[0] = pre_y[0] = 0;
	for (uint32_t j = 0; j < nw; j++)
		pre_x[j + 1] = pre_x[j] + cx[j] - (double)j * b1;
	for (uint32_t i = 0; i < nf; i++)
		pre_y[i + 1] = pre_y[i] + cy[i] - (double)i * b2;
	for (uint32_t ja = 0; ja < nw; ja++)
		for (uint32_t jb = ja + 1; jb < nw; jb++) {
			long w = (long)(jb - ja + 1) * b1;
			/* origin: mean of cx_j - (j - ja + 0.5) b1 over the run */
			long x0 = lround((pre_x[jb + 1] - pre_x[ja]) / (jb - ja + 1) +
			                 (double)ja * b1 - 0.5 * b1);
			for (uint32_t ia = 0; ia < nf; ia++)
				for (uint32_t ib = ia + 1; ib < nf; ib++) {
					long h = (long)(ib - ia + 1) * b2;
					long y0 = lround((pre_y[ib + 1] - pre_y[ia]) / (ib - ia + 1) +
					                 (double)ia * b2 - 0.5 * b2);
					long cells = (long)(jb - ja + 1) * (ib - ia + 1);
					double ddx = x0 + 0.5 * w - (nx - 1) * 0.5;
					double ddy = y0 + 0.5 * h - (ny - 1) * 0.5;
					double dist = ddx * ddx + ddy * ddy;
					if (cells < best_cells || (cells == best_cells && dist >= best_dist))
						continue;
					if (!rect_ok(nx, ny, rot, x0, y0, w, h))
						continue;
					best_cells = cells;
					best_dist = dist;
					bja = ja;
					bjb = jb;
					bia = ia;
					bib = ib;
					bx0 = x0;
					by0 = y0;
				}
		}
	if (best_cells == 0)
		return loom__fail(diag, LOOM_EUNSUPPORTED,
		                  "scan: registration: no window of 2 x 2 complete "
		                  "crossings (blocks %ldx%ld) fits inside the scan", b1, b2);
	out->first_warp = bja;
	out->first_weft = bia;
	out->cols = bjb - bja + 1;
	out->rows = bib - bia + 1;
	out->b1 = (uint32_t)b1;
	out->b2 = (uint32_t)b2;
	out->pitch_x = (float)px;
	out->pitch_y = (float)py;
	/* 3. aligned top-yarn map and its summed-area tables */
	b = malloc((size_t)nx * ny);
	s1 = calloc(W1 * (ny + 1), sizeof *s1);
	s0 = calloc(W1 * (ny + 1), sizeof *s0);
	if (!b || !s1 || !s0) {
		free(b);
		free(s1);
		free(s0);
		return loom__fail(diag, LOOM_ENOMEM, "scan: registration: out of memory");
	}
	for (uint32_t y = 0; y < ny; y++)
		for (uint32_t x = 0; x < nx; x++) {
			double sx, sy;
			long ix, iy;
			uint8_t v = 2, lab;
			loom_scan_aligned_to_scan(nx, ny, rot, x, y, &sx, &sy);
			ix = lround(sx);
			iy = lround(sy);
			if (ix >= 0 && iy >= 0 && ix < (long)nx && iy < (long)ny) {
				lab = top[(size_t)iy * nx + (size_t)ix];
				if (lab >= 1 && lab <= nw)
					v = 1;
				else if (lab > nw && lab <= nw + nf)
					v = 0;
			}
			b[(size_t)y * nx + x] = v;
		}
	for (uint32_t y = 0; y < ny; y++)
		for (uint32_t x = 0; x < nx; x++) {
			size_t o = (size_t)(y + 1) * W1 + x + 1;
			uint8_t v = b[(size_t)y * nx + x];
			s1[o] = s1[o - 1] + s1[o - W1] - s1[o - W1 - 1] + (v == 1);
			s0[o] = s0[o - 1] + s0[o - W1] - s0[o - W1 - 1] + (v == 0);
		}
	/* score every candidate; keep them for the plateau step */
	nc = (size_t)(2 * (b1 / 2) + 1) * (size_t)(2 * (b2 / 2) + 1);
	cand_score = malloc(nc * sizeof *cand_score);
	if (!cand_score) {
		free(b);
		free(s1);
		free(s0);
		return loom__fail(diag, LOOM_ENOMEM, "scan: registration: out of memory");
	}
	for (long dy = -b2 / 2, q = 0; dy <= b2 / 2; dy++)
		for (long dx = -b1 / 2; dx <= b1 / 2; dx++, q++) {
			long x0 = bx0 + dx, y0 = by0 + dy;
			double score = 0;
			cand_score[q] = -1;
			if (x0 < 0 || y0 < 0 || x0 + out->cols * b1 > (long)nx ||
			    y0 + out->rows * b2 > (long)ny ||
			    !rect_ok(nx, ny, rot, x0, y0, out->cols * b1, out->rows * b2))
				continue;
			for (uint32_t i = 0; i < out->rows; i++)
				for (uint32_t j = 0; j < out->cols; j++) {
					/* the cell's central half: the top yarn there is the
					   crossing's, whatever the neighbours do */
					size_t xa = (size_t)(x0 + (long)j * b1 + b1 / 4);
					size_t xb = (size_t)(x0 + (long)j * b1 + b1 - b1 / 4);
					size_t ya = (size_t)(y0 + (long)i * b2 + b2 / 4);
					size_t yb = (size_t)(y0 + (long)i * b2 + b2 - b2 / 4);
					int wv = weave[(size_t)(bia + i) * nw + bja + j];
					const uint32_t *S = wv ? s1 : s0;
					uint32_t cnt = S[yb * W1 + xb] - S[ya * W1 + xb] -
					               S[yb * W1 + xa] + S[ya * W1 + xa];
					score += (double)cnt / (double)((xb - xa) * (yb - ya));
				}
			cand_score[q] = score;
			if (score > best_score)
				best_score = score;
		}
	/* The best scores form a plateau when a yarn is narrower than its
	   cell's central half can tell: take the candidate nearest to the
	   centroid of all candidates within PLATEAU_TOL x cells of the best. */
	if (best_score >= 0) {
		double tol = PLATEAU_TOL * out->rows * out->cols, mx = 0, my = 0, cnt = 0;
		double bestd = 1e300;
		for (long dy = -b2 / 2, q = 0; dy <= b2 / 2; dy++)
			for (long dx = -b1 / 2; dx <= b1 / 2; dx++, q++)
				if (cand_score[q] >= best_score - tol) {
					mx += dx;
					my += dy;
					cnt++;
				}
		mx /= cnt;
		my /= cnt;
		for (long dy = -b2 / 2, q = 0; dy <= b2 / 2; dy++)
			for (long dx = -b1 / 2; dx <= b1 / 2; dx++, q++) {
				double dd = (dx - mx) * (dx - mx) + (dy - my) * (dy - my);
				if (cand_score[q] >= best_score - tol && dd < bestd - 1e-9) {
					bestd = dd;
					best_dx = dx;
					best_dy = dy;
					chosen = cand_score[q];
				}
			}
	}
	free(cand_score);
	/* the weakest cell of the chosen window */
	out->min_cell = 2;
	if (best_score >= 0)
		for (uint32_t i = 0; i < out->rows; i++)
			for (uint32_t j = 0; j < out->cols; j++) {
				long x0 = bx0 + best_dx, y0 = by0 + best_dy;
				size_t xa = (size_t)(x0 + (long)j * b1 + b1 / 4);
				size_t xb = (size_t)(x0 + (long)j * b1 + b1 - b1 / 4);
				size_t ya = (size_t)(y0 + (long)i * b2 + b2 / 4);
				size_t yb = (size_t)(y0 + (long)i * b2 + b2 - b2 / 4);
				const uint32_t *S = weave[(size_t)(bia + i) * nw + bja + j] ? s1 : s0;
				double a = (double)(S[yb * W1 + xb] - S[ya * W1 + xb] -
				                    S[yb * W1 + xa] + S[ya * W1 + xa]) /
				           (double)((xb - xa) * (yb - ya));
				if (a < out->min_cell) {
					out->min_cell = a;
					out->worst[0] = i;
					out->worst[1] = j;
				}
			}
	free(b);
	free(s1);
	free(s0);
	if (best_score < 0)
		return loom__fail(diag, LOOM_EUNSUPPORTED,
		                  "scan: registration: the crop window leaves the scan");
	out->shift[0] = (int32_t)best_dx;
	out->shift[1] = (int32_t)best_dy;
	out->crop[0] = (int32_t)(bx0 + best_dx);
	out->crop[1] = (int32_t)(by0 + best_dy);
	out->crop[2] = (int32_t)(out->cols * b1);
	out->crop[3] = (int32_t)(out->rows * b2);
	out->score = chosen / (out->rows * out->cols);
	return LOOM_OK;
}

/* ---- crop --------------------------------------------------------------- */

/* Where an output column samples the scan: the bilinear cell's first
   voxel and weights, and the nearest voxel, as offsets in a plane. */
typedef struct crop_tap {
	uint32_t i00, inear;
	float fx, fy;
} crop_tap;

typedef struct crop_ctx {
	const loom_scan_volume *scan;
	loom_scan_volume *out;
	const crop_tap *tap; /* one per output column */
	float c, s;          /* cos, sin of -rotation for orientation vectors */
	size_t z, zs;        /* output plane being made, scan plane it shows */
	const float *src;    /* its input orientation plane: floats, or */
	const uint16_t *csrc;/* codes (maybe a copy) */
	const float *lut;    /* loom__scan_code_lut() */
	const uint16_t *rot; /* code -> code of the turned direction */
} crop_ctx;

/* Resample rows tid, tid + nt, ... of output plane c->z. */
static void crop_worker(void *vctx, uint32_t tid, uint32_t nt)
{
	crop_ctx *c = vctx;
	const loom_scan_volume *in = c->scan;
	loom_scan_volume *o = c->out;
	size_t ncol = (size_t)o->nx * o->ny, splane = (size_t)in->nx * in->ny;
	size_t sx = in->nx, z = c->z;
	const float *d = in->density + c->zs * splane;
	float *od = o->density + z * ncol;
	uint16_t *oc = o->ocode + z * ncol;

	for (size_t y = tid; y < o->ny; y += nt)
		for (size_t q = y * o->nx; q < (y + 1) * o->nx; q++) {
			const crop_tap *t = &c->tap[q];
			const float *a = d + t->i00, *w;
			float fx = t->fx, fy = t->fy;
			od[q] = (1 - fy) * ((1 - fx) * a[0] + fx * a[1]) +
			        fy * ((1 - fx) * a[sx] + fx * a[sx + 1]);
			if (!c->src) {
				oc[q] = c->rot[c->csrc[t->inear]];
				continue;
			}
			w = c->src + 3 * (size_t)t->inear;
			oc[q] = w[0] == 0 && w[1] == 0 && w[2] == 0
			            ? 0
			            : loom__orient_encode(c->c * w[0] - c->s * w[1],
			                                  c->s * w[0] + c->c * w[1], w[2]);
		}
}

/* Clamp v to [lo, hi] and round down (v >= 0 after clamping). */
static long clamp_floor(double v, long lo, long hi)
{
	long i = v < lo ? lo : v > hi ? hi : (long)v;
	return i;
}

/*
 * Resample the crop and label it; fills r->volume (density, ocode, label),
 * r->yarns.  The output orientation is always stored as 16-bit codes.  When
 * reuse_orient is set, scan->ocode is a buffer loom allocated (the
 * estimated field): the output codes are written into it in place and
 * the buffer moves to the result, so it is neither duplicated nor faulted
 * in twice.  In place works plane by plane
 * in increasing z: output plane z, smaller than an input plane, lies over
 * input planes <= z, of which only plane z itself is still unread; that
 * plane is copied aside first when they overlap.  Planes are processed one
 * after the other, their rows split between the threads.  Output plane k
 * shows scan plane z0 + k (zeros outside the scan); in place needs
 * 0 <= z0 and z0 + nzo <= nz, else the output gets its own buffer.
 */
static int crop_volume(loom_scan_volume *scan, float thr,
                       const loom_scan_curve *curves, uint32_t nw, uint32_t nf,
                       const float *dirs, const float *axes, double rot,
                       const loom_scan_grid *g, int32_t z0, uint32_t nzo,
                       uint32_t threads, float max_dist, int reuse_orient,
                       loom_scan_result *r, loom_diag *diag)
{
	uint32_t w = (uint32_t)g->crop[2], h = (uint32_t)g->crop[3], n = nw + nf;
	loom_scan_curve *tc = NULL;
	loom_scan_moments *mom = NULL;
	crop_tap *tap = NULL;
	uint16_t *plane_copy = NULL;
	size_t ncol = (size_t)w * h, splane = (size_t)scan->nx * scan->ny;
	crop_ctx c;
	int rc;

	/* every voxel is written below: no need to zero the arrays */
	r->volume.nx = w;
	r->volume.ny = h;
	r->volume.nz = nzo;
	if (z0 < 0 || (int64_t)z0 + nzo > (int64_t)scan->nz)
		reuse_orient = 0; /* see above; the scan's buffer is freed by the caller */
	r->volume.density = loom__scan_alloc_big(ncol * nzo * sizeof(float), 0);
	r->volume.ocode = reuse_orient ? scan->ocode
	                               : loom__scan_alloc_big(ncol * nzo * sizeof(uint16_t), 0);
	r->volume.label = loom__scan_alloc_big(ncol * nzo, 0);
	plane_copy = malloc(splane * sizeof *plane_copy);
	if (reuse_orient)
		scan->ocode = NULL; /* owned by the result from now on */
	if (!r->volume.density || !r->volume.ocode || !r->volume.label || !plane_copy) {
		free(plane_copy);
		return loom__fail(diag, LOOM_ENOMEM,
		                  "scan: crop: cannot allocate %ux%ux%u voxels", w, h,
		                  scan->nz);
	}
	tap = malloc((size_t)w * h * sizeof *tap);
	tc = calloc(n, sizeof *tc);
	mom = calloc(n, sizeof *mom);
	r->yarns = calloc(n, sizeof *r->yarns);
	if (!tap || !tc || !mom || !r->yarns) {
		rc = loom__fail(diag, LOOM_ENOMEM, "scan: crop: out of memory");
		goto done;
	}
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++) {
			double sx, sy, fx, fy;
			long x0, y0, xn, yn;
			crop_tap *t = &tap[(size_t)y * w + x];
			loom_scan_aligned_to_scan(scan->nx, scan->ny, rot, g->crop[0] + (double)x,
			                          g->crop[1] + (double)y, &sx, &sy);
			x0 = clamp_floor(sx, 0, (long)scan->nx - 2);
			y0 = clamp_floor(sy, 0, (long)scan->ny - 2);
			fx = sx - x0;
			fy = sy - y0;
			xn = clamp_floor(sx + 0.5, 0, (long)scan->nx - 1);
			yn = clamp_floor(sy + 0.5, 0, (long)scan->ny - 1);
			t->i00 = (uint32_t)((size_t)y0 * scan->nx + (size_t)x0);
			t->inear = (uint32_t)((size_t)yn * scan->nx + (size_t)xn);
			t->fx = (float)(fx < 0 ? 0 : fx > 1 ? 1 : fx);
			t->fy = (float)(fy < 0 ? 0 : fy > 1 ? 1 : fy);
		}
	c.scan = scan;
	c.out = &r->volume;
	c.tap = tap;
	c.c = (float)cos(-rot / DEG);
	c.s = (float)sin(-rot / DEG);
	c.lut = loom__scan_code_lut();
	c.rot = NULL;
	if (!scan->orient) {
		/* codes in, codes out: turning is a table lookup */
		uint16_t *rt = malloc(65536 * sizeof *rt);
		if (!rt) {
			rc = loom__fail(diag, LOOM_ENOMEM, "scan: crop: out of memory");
			goto done;
		}
		rt[0] = 0;
		for (uint32_t k = 1; k < 65536; k++) {
			const float *dv = c.lut + 3 * (size_t)k;
			rt[k] = loom__orient_encode(c.c * dv[0] - c.s * dv[1],
			                            c.s * dv[0] + c.c * dv[1], dv[2]);
		}
		c.rot = rt;
	}
	for (size_t k = 0; k < nzo; k++) {
		long zs = (long)z0 + (long)k;
		if (zs < 0 || zs >= (long)scan->nz) {
			/* padding outside the scan */
			memset(r->volume.density + k * ncol, 0, ncol * sizeof(float));
			memset(r->volume.ocode + k * ncol, 0, ncol * sizeof(uint16_t));
			continue;
		}
		c.z = k;
		c.zs = (size_t)zs;
		c.src = scan->orient ? scan->orient + 3 * (size_t)zs * splane : NULL;
		c.csrc = NULL;
		if (!c.src) {
			const uint16_t *in = (reuse_orient ? r->volume.ocode : scan->ocode) +
			                     (size_t)zs * splane;
			c.csrc = in;
			/* in place: does output plane k reach into input plane zs? */
			if (reuse_orient && (k + 1) * ncol > (size_t)zs * splane) {
				memcpy(plane_copy, in, splane * sizeof *plane_copy);
				c.csrc = plane_copy;
			}
		}
		loom__scan_parallel(threads, crop_worker, &c);
	}
	free((void *)c.rot);
	c.rot = NULL;
	if (reuse_orient) {
		/* give back the tail the crop does not use */
		uint16_t *shrunk = realloc(r->volume.ocode, ncol * nzo * sizeof(uint16_t));
		if (shrunk)
			r->volume.ocode = shrunk;
	}
	/* centre curves in the output frame */
	for (uint32_t i = 0; i < n; i++) {
		tc[i].kind = curves[i].kind;
		tc[i].n = curves[i].n;
		tc[i].pts = malloc(3 * (size_t)curves[i].n * sizeof(float));
		if (!tc[i].pts) {
			rc = loom__fail(diag, LOOM_ENOMEM, "scan: crop: out of memory");
			goto done;
		}
		for (uint32_t k = 0; k < curves[i].n; k++) {
			double ax, ay;
			scan_to_aligned(scan->nx, scan->ny, rot, curves[i].pts[3 * k],
			                curves[i].pts[3 * k + 1], &ax, &ay);
			tc[i].pts[3 * k] = (float)(ax - g->crop[0]);
			tc[i].pts[3 * k + 1] = (float)(ay - g->crop[1]);
			tc[i].pts[3 * k + 2] = curves[i].pts[3 * k + 2] - (float)z0;
		}
	}
	rc = loom_scan_segment(&r->volume, thr, tc, n, axes, max_dist, threads,
	                       r->volume.label, NULL, mom, diag);
	if (rc)
		goto done;
	r->n_yarns = n;
	for (uint32_t i = 0; i < n; i++) {
		loom_scan_yarn *y = &r->yarns[i];
		int warp = i < nw;
		y->kind = warp ? LOOM_SCAN_WARP : LOOM_SCAN_WEFT;
		y->tracked = warp ? i : i - nw;
		y->index = (int32_t)y->tracked - (int32_t)(warp ? g->first_warp : g->first_weft);
		y->direction[0] = dirs[2 * i];
		y->direction[1] = dirs[2 * i + 1];
		y->voxels = mom[i].n;
		y->n_points = tc[i].n;
		y->points = tc[i].pts;
		tc[i].pts = NULL;
	}
done:
	if (tc)
		for (uint32_t i = 0; i < n; i++)
			free(tc[i].pts);
	free(tc);
	free(mom);
	free(tap);
	free(plane_copy);
	return rc;
}

/* ---- the pipeline ------------------------------------------------------- */

LOOM_API void loom_scan_result_free(loom_scan_result *r)
{
	if (!r)
		return;
	loom_scan_volume_release(&r->volume);
	if (r->yarns)
		for (uint32_t i = 0; i < r->n_yarns; i++)
			free(r->yarns[i].points);
	free(r->yarns);
	free(r->weave);
	free(r->full_weave);
	free(r->linking);
	free(r);
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double cpu_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

typedef struct step_clock {
	const loom_scan_params *p;
	loom_scan_result *r;
	int step;
	double t0, c0;
} step_clock;

static void step_begin(step_clock *sc, int step)
{
	sc->step = step;
	sc->t0 = now_s();
	sc->c0 = cpu_s();
	if (sc->p->progress)
		sc->p->progress(sc->p->progress_user, step, 0.0);
}

static void step_end(step_clock *sc)
{
	sc->r->seconds[sc->step] = now_s() - sc->t0;
	sc->r->cpu_seconds[sc->step] = cpu_s() - sc->c0;
	if (sc->p->progress)
		sc->p->progress(sc->p->progress_user, sc->step, 1.0);
}

static int check_params(const loom_scan_params *p, loom_diag *diag)
{
	if (p->size != sizeof *p)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: parameters not initialised with "
		                  "loom_scan_params_init (size %zu, expected %zu)",
		                  p->size, sizeof *p);
	if (p->n_warps < 2 || p->n_warps > LOOM_SCAN_MAX_YARNS || p->n_wefts < 2 ||
	    p->n_wefts > LOOM_SCAN_MAX_YARNS)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: %u warps and %u wefts given; each must be in "
		                  "2..%u", p->n_warps, p->n_wefts, LOOM_SCAN_MAX_YARNS);
	if (!(p->threshold >= 0) || p->threshold >= 1 || !(p->scale >= 0) ||
	    p->scale > 100 || !(p->step > 0) || !(p->c0 >= 0) || p->c0 > 1 ||
	    !(p->radius_warp > 0) || !(p->radius_weft > 0) || !(p->ellipse_warp > 0) ||
	    !(p->ellipse_weft > 0) || !(p->ellipse_z > 0) || !(p->min_linking >= 0) ||
	    p->min_linking > 0.5f || p->threads < 1 || p->threads > 64 ||
	    p->block_x > 65535 || p->block_y > 65535 || p->block_z > 65535)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: a parameter is out of range (threshold in "
		                  "[0,1), scale in [0,100], step, radii, ellipse > 0, "
		                  "c0 in [0,1], min_linking in [0,0.5], threads 1..64, "
		                  "blocks <= 65535)");
	return LOOM_OK;
}

LOOM_API int loom_scan_build(loom_scan_volume *scan, const loom_scan_params *p,
                             loom_scan_result **out, loom_diag *diag)
{
	loom_scan_result *r = NULL;
	loom_scan_curve *curves = NULL;
	loom_scan_moments *mom = NULL;
	loom_scan_track_lengths lw, lf;
	uint8_t *top = NULL;
	int *kinds = NULL, own_orient = 0;
	float *dirs = NULL, *axes = NULL, thr, max_dist;
	uint32_t nw, nf, n;
	step_clock sc;
	int rc;

	if (out)
		*out = NULL;
	if (!scan || !p || !out)
		return loom__fail(diag, LOOM_EINVAL, "scan: NULL argument");
	if ((rc = check_params(p, diag)) != LOOM_OK)
		return rc;
	if ((rc = loom__scan_check_volume(scan, "input", diag)) != LOOM_OK)
		return rc;
	if (scan->nx < 16 || scan->ny < 16 || scan->nz < 3)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: volume %ux%ux%u too small (need at least "
		                  "16x16x3)", scan->nx, scan->ny, scan->nz);
	if ((uint64_t)scan->nx * scan->ny > UINT32_MAX)
		return loom__fail(diag, LOOM_ERANGE,
		                  "scan: planes of %ux%u voxels are too large (at most "
		                  "2^32 per plane)", scan->nx, scan->ny);
	nw = p->n_warps;
	nf = p->n_wefts;
	n = nw + nf;
	r = calloc(1, sizeof *r);
	curves = calloc(n, sizeof *curves);
	mom = calloc(n, sizeof *mom);
	kinds = calloc(n, sizeof *kinds);
	dirs = calloc(2 * (size_t)n, sizeof *dirs);
	axes = calloc(2 * (size_t)n, sizeof *axes);
	top = malloc((size_t)scan->nx * scan->ny);
	if (!r || !curves || !mom || !kinds || !dirs || !axes || !top) {
		rc = loom__fail(diag, LOOM_ENOMEM, "scan: out of memory");
		goto fail;
	}
	sc.p = p;
	sc.r = r;

	/* 1. denoise */
	step_begin(&sc, LOOM_SCAN_STEP_DENOISE);
	r->noise_before = loom_scan_noise(scan);
	if ((rc = loom_scan_denoise(scan, p->denoise_sigma, p->threads, diag)))
		goto fail;
	r->noise_after = loom_scan_noise(scan);
	if (p->threshold > 0)
		thr = p->threshold;
	else if ((rc = loom_scan_threshold(scan, &thr, diag)))
		goto fail;
	r->threshold = thr;
	step_end(&sc);

	/* 2. orientation */
	step_begin(&sc, LOOM_SCAN_STEP_ORIENT);
	if (!scan->orient && !scan->ocode) {
		size_t nv = (size_t)scan->nx * scan->ny * scan->nz;
		/* 16-bit codes, lent to the scan while the steps run; the crop
		   moves them into the result (or the failure path frees them) */
		scan->ocode = loom__scan_alloc_big(nv * sizeof *scan->ocode, 0);
		own_orient = 1;
		if (!scan->ocode) {
			rc = loom__fail(diag, LOOM_ENOMEM,
			                "scan: orientation: cannot allocate %zu bytes",
			                nv * sizeof *scan->ocode);
			goto fail;
		}
		r->orientation_estimated = 1;
		if ((rc = loom_scan_orient(scan, thr, p->tensor_sigma, p->threads,
		                           &r->orient, diag)))
			goto fail;
	}
	step_end(&sc);

	/* 3. endpoints */
	step_begin(&sc, LOOM_SCAN_STEP_ENDPOINTS);
	if ((rc = loom_scan_endpoints_find(scan, LOOM_SCAN_WARP, nw, thr, p,
	                                   &r->warp_ends, diag)) ||
	    (rc = loom_scan_endpoints_find(scan, LOOM_SCAN_WEFT, nf, thr, p,
	                                   &r->weft_ends, diag)))
		goto fail;
	r->scale = p->scale > 0 ? p->scale
	                        : 0.5f * (r->warp_ends.spacing / 115.0f +
	                                  r->weft_ends.spacing / 70.0f);
	step_end(&sc);

	/* 4. tracking */
	step_begin(&sc, LOOM_SCAN_STEP_TRACK);
	loom_scan_track_lengths_get(p, LOOM_SCAN_WARP, r->scale, &lw);
	loom_scan_track_lengths_get(p, LOOM_SCAN_WEFT, r->scale, &lf);
	if ((rc = loom__scan_track_all(scan, &r->warp_ends, &r->weft_ends, thr, &lw,
	                               &lf, p->threads, curves, diag)))
		goto fail;
	r->warps_tracked = nw;
	r->wefts_tracked = nf;
	step_end(&sc);

	/* 5. weave pattern of all tracked yarns */
	step_begin(&sc, LOOM_SCAN_STEP_WEAVE);
	r->full_rows = nf;
	r->full_cols = nw;
	r->full_weave = malloc((size_t)nf * nw);
	r->linking = malloc((size_t)nf * nw * sizeof *r->linking);
	if (!r->full_weave || !r->linking) {
		rc = loom__fail(diag, LOOM_ENOMEM, "scan: out of memory");
		goto fail;
	}
	if ((rc = loom_scan_weave(curves, nw, curves + nw, nf, scan->nx, scan->ny,
	                          scan->nz, r->full_weave, r->linking, diag)))
		goto fail;
	step_end(&sc);

	/* 6. segmentation in the scan frame: top map and moments only */
	step_begin(&sc, LOOM_SCAN_STEP_SEGMENT);
	max_dist = fmaxf(r->warp_ends.spacing, r->weft_ends.spacing);
	if (!(max_dist > 1))
		max_dist = 1;
	for (uint32_t i = 0; i < n; i++) {
		const loom_scan_endpoints *e = i < nw ? &r->warp_ends : &r->weft_ends;
		axes[2 * i] = e->semi_axes[0] > 0.5f ? e->semi_axes[0] : 0.5f;
		axes[2 * i + 1] = e->semi_axes[1] > 0.5f ? e->semi_axes[1] : 0.5f;
	}
	if ((rc = loom_scan_refine(scan, thr, curves, n, axes, max_dist, p->threads,
	                           diag)))
		goto fail;
	if ((rc = loom_scan_segment(scan, thr, curves, n, axes, max_dist, p->threads,
	                            NULL, top, mom, diag)))
		goto fail;
	step_end(&sc);

	/* 7. alignment */
	step_begin(&sc, LOOM_SCAN_STEP_ALIGN);
	for (uint32_t i = 0; i < n; i++)
		kinds[i] = i < nw ? LOOM_SCAN_WARP : LOOM_SCAN_WEFT;
	if ((rc = loom_scan_align(mom, kinds, n, &r->rotation_degrees, dirs, diag)))
		goto fail;
	step_end(&sc);

	/* 8. registration */
	step_begin(&sc, LOOM_SCAN_STEP_REGISTER);
	if ((rc = loom_scan_register(scan->nx, scan->ny, top, curves, nw, nf,
	                             r->full_weave, r->rotation_degrees, p->block_x,
	                             p->block_y, &r->grid, diag)))
		goto fail;
	r->rows = r->grid.rows;
	r->cols = r->grid.cols;
	r->b1 = r->grid.b1;
	r->b2 = r->grid.b2;
	r->b3 = p->block_z ? p->block_z : scan->nz;
	r->z0 = 0;
	if (p->block_z) {
		double zs = 0, zn = 0;
		for (uint32_t i = 0; i < n; i++)
			for (uint32_t k = 0; k < curves[i].n; k++) {
				zs += curves[i].pts[3 * k + 2];
				zn++;
			}
		r->z0 = (int32_t)lround(zs / zn - 0.5 * (r->b3 - 1.0));
	}
	if (r->grid.min_cell < MIN_CELL_AGREEMENT) {
		rc = loom__fail(diag, LOOM_EUNSUPPORTED,
		                "scan: registration: crossing of warp %u and weft %u "
		                "disagrees with the scan's top-yarn map (%.0f%% of its "
		                "centre shows the %s on top, need %.0f%%); tracking went "
		                "wrong or the scan is too noisy",
		                r->grid.first_warp + r->grid.worst[1],
		                r->grid.first_weft + r->grid.worst[0],
		                100 * r->grid.min_cell,
		                r->full_weave[(size_t)(r->grid.first_weft + r->grid.worst[0]) * nw +
		                              r->grid.first_warp + r->grid.worst[1]]
		                    ? "warp"
		                    : "weft",
		                100 * MIN_CELL_AGREEMENT);
		goto fail;
	}
	r->weave = malloc((size_t)r->rows * r->cols);
	if (!r->weave) {
		rc = loom__fail(diag, LOOM_ENOMEM, "scan: out of memory");
		goto fail;
	}
	for (uint32_t i = 0; i < r->rows; i++)
		for (uint32_t j = 0; j < r->cols; j++) {
			size_t k = (size_t)(r->grid.first_weft + i) * nw + r->grid.first_warp + j;
			if (fabsf(r->linking[k]) < p->min_linking) {
				rc = loom__fail(diag, LOOM_EUNSUPPORTED,
				                "scan: weave: crossing of warp %u and weft %u is "
				                "ambiguous (linking integral %.3f, need |L| >= "
				                "%.2f); tracking went wrong or the scan is too noisy",
				                r->grid.first_warp + j, r->grid.first_weft + i,
				                r->linking[k], p->min_linking);
				goto fail;
			}
			r->weave[(size_t)i * r->cols + j] = r->full_weave[k];
		}
	step_end(&sc);

	/* 9. crop */
	step_begin(&sc, LOOM_SCAN_STEP_CROP);
	rc = crop_volume(scan, thr, curves, nw, nf, dirs, axes, r->rotation_degrees,
	                 &r->grid, r->z0, r->b3, p->threads, max_dist, own_orient, r,
	                 diag);
	if (own_orient && scan->ocode) {
		/* not reused in place (block_z reaching outside the scan) */
		free(scan->ocode);
		scan->ocode = NULL;
	}
	own_orient = 0; /* moved to the result or freed */
	if (rc)
		goto fail;
	step_end(&sc);

	for (uint32_t i = 0; i < n; i++)
		loom_scan_curve_release(&curves[i]);
	free(curves);
	free(mom);
	free(kinds);
	free(dirs);
	free(axes);
	free(top);
	*out = r;
	return LOOM_OK;
fail:
	if (curves)
		for (uint32_t i = 0; i < n; i++)
			loom_scan_curve_release(&curves[i]);
	free(curves);
	free(mom);
	free(kinds);
	free(dirs);
	free(axes);
	free(top);
	if (own_orient) {
		free(scan->ocode);
		scan->ocode = NULL;
	}
	loom_scan_result_free(r);
	return rc;
}
