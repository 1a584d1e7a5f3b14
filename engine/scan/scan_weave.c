/*
 * engine/scan/scan_weave.c - scan pipeline steps 5 and 6: weave pattern by the
 * Gaussian linking integral (paper 6.2) and voxel segmentation by nearest
 * centre curve (paper 6.3).
 *
 * Linking.  For polylines the double integral
 *
 *   L = 1/(4 pi) \int\int < (p1 - p2)/|p1 - p2|^3, p1' x p2' > dt1 dt2
 *
 * splits into segment pairs, and each pair's integral is the signed solid
 * angle of the quadrilateral spanned by the four vectors between the
 * segments' end points, divided by 4 pi (Klenin and Langowski's closed form
 * for the writhe of polygons): exact, no quadrature step to choose.  Open
 * curves are closed "at infinity": each is extended from both ends along its
 * end-to-end direction by 1000 volume diagonals.  A warp and a weft that
 * cross once in projection then have L -> +-1/2 as the extension grows
 * (the map (t1,t2) -> unit(p1 - p2) covers one hemisphere once), with the
 * sign telling which is on top.  Warps are parameterised by increasing y and
 * wefts by decreasing x, so that the projected tangents (t_warp, t_weft) =
 * (+y, -x) form a positively oriented basis as the paper asks; then L > 0
 * exactly when the warp is above (for straight lines at heights h > 0 apart
 * the integrand is h / (s^2 + u^2 + h^2)^(3/2), integral 2 pi, L = +1/2).
 *
 * Segmentation.  Every voxel above the threshold gets the label of the curve
 * whose polyline is nearest (exact point-segment distance), if one is
 * within max_dist.  The paper's distance is Euclidean; with per-curve
 * semi-axes (A, B) the offset from a segment is measured along it, across
 * it horizontally and across it "vertically" and divided by (A, A, B), so
 * yarns with flat elliptical cross sections meet where their ellipses do
 * (the pipeline measures A, B at the endpoints; with the Euclidean rule
 * 2-6% of the voxels of our synthetic plain weave change yarn at the
 * crossings).  A 2D grid of 16 x 16 columns lists the segments whose xy
 * bounding box, grown by max_dist, touches the cell.  Blocks of 4 x 4
 * columns share one candidate list sorted by a lower bound of the distance
 * (xy distance from the block centre minus its half-diagonal, scaled by the
 * metric's smallest factor); a voxel walks the list, starting with the
 * winner of the voxel above it, and stops at the first bound beyond the
 * best distance found: a handful of exact distances per voxel.  Columns are
 * processed in runs of 64 along x, top plane first, so the density is read
 * in rows and the topmost voxel of each column is known for the top map.
 * Ties go to the first candidate in list order: the same for any threads.
 *
 * Refinement (loom_scan_refine) runs the same pass on the columns that lie
 * in some curve point's window only, summing the labelled density around
 * each point in integers, and moves the points to those centres of mass.
 */
#include "scan_internal.h"

#include <stdlib.h>
#include <string.h>

/* ---- linking integral --------------------------------------------------- */

static void sub3(double o[3], const double a[3], const double b[3])
{
	o[0] = a[0] - b[0];
	o[1] = a[1] - b[1];
	o[2] = a[2] - b[2];
}

static void cross3(double o[3], const double a[3], const double b[3])
{
	o[0] = a[1] * b[2] - a[2] * b[1];
	o[1] = a[2] * b[0] - a[0] * b[2];
	o[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static int unit3(double a[3])
{
	double n = sqrt(dot3(a, a));
	if (!(n > 0))
		return 0;
	a[0] /= n;
	a[1] /= n;
	a[2] /= n;
	return 1;
}

static double asin_c(double x)
{
	return asin(x < -1 ? -1 : x > 1 ? 1 : x);
}

/* Gauss integral of segment p1->p2 against segment p3->p4. */
static double seg_pair(const double p1[3], const double p2[3],
                       const double p3[3], const double p4[3])
{
	double r13[3], r14[3], r23[3], r24[3], r12[3], r34[3];
	double n1[3], n2[3], n3[3], n4[3], c[3], omega, s;

	sub3(r13, p3, p1);
	sub3(r14, p4, p1);
	sub3(r23, p3, p2);
	sub3(r24, p4, p2);
	sub3(r12, p2, p1);
	sub3(r34, p4, p3);
	cross3(n1, r13, r14);
	cross3(n2, r14, r24);
	cross3(n3, r24, r23);
	cross3(n4, r23, r13);
	if (!unit3(n1) || !unit3(n2) || !unit3(n3) || !unit3(n4))
		return 0; /* coplanar or touching: no contribution */
	omega = asin_c(dot3(n1, n2)) + asin_c(dot3(n2, n3)) + asin_c(dot3(n3, n4)) +
	        asin_c(dot3(n4, n1));
	cross3(c, r34, r12);
	s = dot3(c, r13);
	if (s == 0)
		return 0;
	return (s > 0 ? omega : -omega) / (4 * 3.14159265358979323846);
}

static double linking_d(const double *a, uint32_t na, const double *b, uint32_t nb)
{
	double sum = 0;
	for (uint32_t i = 0; i + 1 < na; i++)
		for (uint32_t j = 0; j + 1 < nb; j++)
			sum += seg_pair(a + 3 * i, a + 3 * (i + 1), b + 3 * j, b + 3 * (j + 1));
	return sum;
}

LOOM_API double loom_scan_linking(const float *a, uint32_t na, const float *b,
                                  uint32_t nb)
{
	double *da, *db, r;

	if (!a || !b || na < 2 || nb < 2)
		return 0;
	da = malloc(3 * ((size_t)na + nb) * sizeof *da);
	if (!da)
		return 0;
	db = da + 3 * (size_t)na;
	for (size_t i = 0; i < 3 * (size_t)na; i++)
		da[i] = a[i];
	for (size_t i = 0; i < 3 * (size_t)nb; i++)
		db[i] = b[i];
	r = linking_d(da, na, db, nb);
	free(da);
	return r;
}

/* Copy c into out (n + 2 points) extended by ext along its end-to-end
   direction (or `axis` for a single point); reversed if rev. */
static void extend_curve(const loom_scan_curve *c, int axis, double ext, int rev,
                         double *out)
{
	double u[3] = {0, 0, 0};
	uint32_t n = c->n;

	if (n >= 2) {
		for (int k = 0; k < 3; k++)
			u[k] = (double)c->pts[3 * (n - 1) + k] - c->pts[k];
	}
	if (!unit3(u)) {
		u[0] = u[1] = u[2] = 0;
		u[axis] = 1;
	}
	for (int k = 0; k < 3; k++) {
		out[k] = c->pts[k] - ext * u[k];
		out[3 * (n + 1) + k] = c->pts[3 * (n - 1) + k] + ext * u[k];
	}
	for (uint32_t i = 0; i < n; i++)
		for (int k = 0; k < 3; k++)
			out[3 * (i + 1) + k] = c->pts[3 * i + k];
	if (rev)
		for (uint32_t i = 0, j = n + 1; i < j; i++, j--)
			for (int k = 0; k < 3; k++) {
				double t = out[3 * i + k];
				out[3 * i + k] = out[3 * j + k];
				out[3 * j + k] = t;
			}
}

LOOM_API int loom_scan_weave(const loom_scan_curve *warps, uint32_t nw,
                             const loom_scan_curve *wefts, uint32_t nf,
                             uint32_t nx, uint32_t ny, uint32_t nz,
                             uint8_t *weave, float *linking, loom_diag *diag)
{
	double ext = 1000.0 * sqrt((double)nx * nx + (double)ny * ny + (double)nz * nz);
	double **ew, **ef;
	int rc = LOOM_OK;

	if (!warps || !wefts || !weave || !nw || !nf || nw > LOOM_SCAN_MAX_YARNS ||
	    nf > LOOM_SCAN_MAX_YARNS)
		return loom__fail(diag, LOOM_EINVAL, "scan: weave: bad arguments");
	for (uint32_t i = 0; i < nw; i++)
		if (!warps[i].pts || !warps[i].n)
			return loom__fail(diag, LOOM_EINVAL, "scan: weave: warp %u is empty", i);
	for (uint32_t i = 0; i < nf; i++)
		if (!wefts[i].pts || !wefts[i].n)
			return loom__fail(diag, LOOM_EINVAL, "scan: weave: weft %u is empty", i);
	ew = calloc(nw, sizeof *ew);
	ef = calloc(nf, sizeof *ef);
	if (!ew || !ef) {
		rc = LOOM_ENOMEM;
		goto done;
	}
	for (uint32_t j = 0; j < nw; j++) {
		if (!(ew[j] = malloc(3 * ((size_t)warps[j].n + 2) * sizeof(double)))) {
			rc = LOOM_ENOMEM;
			goto done;
		}
		extend_curve(&warps[j], 1, ext, 0, ew[j]);
	}
	for (uint32_t i = 0; i < nf; i++) {
		if (!(ef[i] = malloc(3 * ((size_t)wefts[i].n + 2) * sizeof(double)))) {
			rc = LOOM_ENOMEM;
			goto done;
		}
		extend_curve(&wefts[i], 0, ext, 1, ef[i]);
	}
	for (uint32_t i = 0; i < nf; i++)
		for (uint32_t j = 0; j < nw; j++) {
			double L = linking_d(ew[j], warps[j].n + 2, ef[i], wefts[i].n + 2);
			weave[(size_t)i * nw + j] = L > 0;
			if (linking)
				linking[(size_t)i * nw + j] = (float)L;
		}
done:
	if (ew)
		for (uint32_t j = 0; j < nw; j++)
			free(ew[j]);
	if (ef)
		for (uint32_t i = 0; i < nf; i++)
			free(ef[i]);
	free(ew);
	free(ef);
	if (rc == LOOM_ENOMEM)
		return loom__fail(diag, rc, "scan: weave: out of memory");
	return rc;
}

/* ---- segmentation ------------------------------------------------------- */

#define SEG_CELL 16 /* grid cell of segment lists, columns */
#define SEG_RUN 64  /* columns processed together along x */
#define SEG_B 4     /* SEG_B x SEG_B columns share a sorted candidate list */

typedef struct seg {
	float a[3], u[3];
	float inv, inv_xy;   /* 1/|u|^2, 1/|u_xy|^2 (0 if degenerate) */
	float e[3][3];       /* metric rows: along/A, lateral/A, normal/B */
	float lb;            /* 1/max(A,B): xy distance * lb <= distance */
	uint32_t curve;
} seg;

typedef struct cand {
	float d2;            /* squared xy distance: lower bound */
	uint32_t s;
} cand;

typedef struct seg_ctx {
	const loom_scan_volume *v;
	float thr, max2, maxr2; /* max distance^2: voxels, in metric units */
	float max_dist;
	const seg *segs;
	const uint32_t *cell_start, *cell_ids;
	uint32_t gx, max_list, ncurves;
	uint8_t *label, *top;
	loom_scan_moments *mom; /* threads * ncurves */
	/* centre refinement (loom_scan_refine), else NULL */
	const loom_scan_curve *curves;
	const int32_t *plane_pt; /* per curve, per main-axis plane: point or -1 */
	const size_t *plane_off; /* first entry of curve i in plane_pt */
	const uint32_t *pt_off;  /* first accumulator of curve i */
	const float *ell;        /* per curve: lateral, z semi-axes of the window */
	int64_t *acc;            /* threads * points * 3: sum w, w*lat, w*z */
	uint32_t npts;
	const uint8_t *need;     /* refinement: nx*ny, columns inside a window */
	int failed;
} seg_ctx;

/* Refinement: voxel (x,y,z) of density d got label lab; add it to the
   window of its yarn's curve point on the same plane, if any.  Weights are
   integers (density in 1/65536) so sums do not depend on the thread split. */
static void refine_add(const seg_ctx *c, int64_t *acc, uint32_t lab, long x,
                       long y, long z, float d)
{
	uint32_t i = lab - 1;
	int warp = c->curves[i].kind == LOOM_SCAN_WARP;
	long m = warp ? y : x, lat = warp ? x : y;
	int32_t k = c->plane_pt[c->plane_off[i] + (size_t)m];
	const float *p;
	double dl, dz;
	int64_t w;

	if (k < 0)
		return;
	p = c->curves[i].pts + 3 * k;
	dl = (lat - p[warp ? 0 : 1]) / c->ell[2 * i];
	dz = (z - p[2]) / c->ell[2 * i + 1];
	if (dl * dl + dz * dz > 1)
		return;
	w = (int64_t)lrintf(d * 65536.0f);
	acc += 3 * ((size_t)c->pt_off[i] + (size_t)k);
	acc[0] += w;
	acc[1] += w * lat;
	acc[2] += w * z;
}

static float seg_dist2_xy(const seg *s, float x, float y)
{
	float wx = x - s->a[0], wy = y - s->a[1];
	float t = (wx * s->u[0] + wy * s->u[1]) * s->inv_xy;
	t = t < 0 ? 0 : t > 1 ? 1 : t;
	wx -= t * s->u[0];
	wy -= t * s->u[1];
	return wx * wx + wy * wy;
}

/* Squared distance from (x,y,z) to the segment in the segment's metric:
   w = offset from the nearest point of the segment, measured along the
   segment, across it horizontally and across it "vertically", divided by
   the semi-axes (A, A, B); plain Euclidean when A = B = 1. */
static float seg_dist2(const seg *s, float x, float y, float z)
{
	float wx = x - s->a[0], wy = y - s->a[1], wz = z - s->a[2], r = 0;
	float t = (wx * s->u[0] + wy * s->u[1] + wz * s->u[2]) * s->inv;
	t = t < 0 ? 0 : t > 1 ? 1 : t;
	wx -= t * s->u[0];
	wy -= t * s->u[1];
	wz -= t * s->u[2];
	for (int k = 0; k < 3; k++) {
		float c = s->e[k][0] * wx + s->e[k][1] * wy + s->e[k][2] * wz;
		r += c * c;
	}
	return r;
}

/* Metric rows of a segment with semi-axes A (lateral) and B (vertical),
   scaled so that a yarn with semi-axes (ref, ref) measures in voxels. */
static void seg_metric(seg *s, float A, float B, float ref)
{
	float n = sqrtf(s->u[0] * s->u[0] + s->u[1] * s->u[1] + s->u[2] * s->u[2]);
	float ua[3] = {1, 0, 0}, lat[3], nz[3], ln;
	if (n > 0)
		for (int k = 0; k < 3; k++)
			ua[k] = s->u[k] / n;
	/* lateral: horizontal and across the segment (u x z) */
	lat[0] = ua[1];
	lat[1] = -ua[0];
	lat[2] = 0;
	ln = sqrtf(lat[0] * lat[0] + lat[1] * lat[1]);
	if (ln > 1e-6f) {
		lat[0] /= ln;
		lat[1] /= ln;
	} else {
		lat[0] = 1;
		lat[1] = 0;
	}
	nz[0] = ua[1] * lat[2] - ua[2] * lat[1];
	nz[1] = ua[2] * lat[0] - ua[0] * lat[2];
	nz[2] = ua[0] * lat[1] - ua[1] * lat[0];
	for (int k = 0; k < 3; k++) {
		s->e[0][k] = ua[k] * ref / A;
		s->e[1][k] = lat[k] * ref / A;
		s->e[2][k] = nz[k] * ref / B;
	}
	s->lb = ref / (A > B ? A : B);
}

static void seg_worker(void *vctx, uint32_t tid, uint32_t nt)
{
	seg_ctx *c = vctx;
	const loom_scan_volume *v = c->v;
	size_t nx = v->nx, ny = v->ny, nz = v->nz, plane = nx * ny;
	size_t stride = (size_t)c->max_list + 1;
	cand *cands = malloc((SEG_RUN / SEG_B) * stride * sizeof *cands);
	uint32_t ncand[SEG_RUN / SEG_B], last[SEG_B][SEG_RUN];
	uint8_t found[SEG_B][SEG_RUN];
	loom_scan_moments *mom = c->mom + (size_t)tid * c->ncurves;

	if (!cands) {
		__atomic_store_n(&c->failed, 1, __ATOMIC_RELAXED);
		return;
	}
	/* bands of SEG_B rows, runs of SEG_RUN columns, blocks of SEG_B x SEG_B
	   columns sharing one candidate list (SEG_CELL is a multiple of SEG_B,
	   so a block lies in one grid cell) */
	for (size_t y0 = (size_t)tid * SEG_B; y0 < ny; y0 += (size_t)nt * SEG_B) {
		size_t rows = ny - y0 < SEG_B ? ny - y0 : SEG_B;
		uint32_t cy = (uint32_t)(y0 / SEG_CELL);
		for (size_t x0 = 0; x0 < nx; x0 += SEG_RUN) {
			size_t run = nx - x0 < SEG_RUN ? nx - x0 : SEG_RUN;
			for (size_t b = 0; b * SEG_B < run; b++) {
				size_t bx = x0 + b * SEG_B, bw = run - b * SEG_B;
				uint32_t cell = cy * c->gx + (uint32_t)(bx / SEG_CELL);
				cand *cl = cands + b * stride;
				uint32_t m = 0, k0 = c->cell_start[cell], k1 = c->cell_start[cell + 1];
				float mx, my, half;
				int needed = !c->need;
				bw = bw < SEG_B ? bw : SEG_B;
				for (size_t r = 0; r < rows && !needed; r++)
					for (size_t q = 0; q < bw && !needed; q++)
						needed = c->need[(y0 + r) * nx + bx + q];
				if (!needed)
					k1 = k0; /* the refinement does not look here */
				/* lower bound for every column of the block: xy distance
				   from the block centre minus its half-diagonal */
				mx = (float)bx + 0.5f * (float)(bw - 1);
				my = (float)y0 + 0.5f * (float)(rows - 1);
				half = 0.5f * sqrtf((float)((bw - 1) * (bw - 1) + (rows - 1) * (rows - 1)));
				for (uint32_t k = k0; k < k1; k++) {
					uint32_t sid = c->cell_ids[k];
					const seg *sg = &c->segs[sid];
					float d = sqrtf(seg_dist2_xy(sg, mx, my)) - half, d2;
					uint32_t q;
					if (d > c->max_dist)
						continue;
					d = d < 0 ? 0 : d * sg->lb;
					d2 = d * d;
					/* insertion by (bound, segment): deterministic */
					q = m++;
					while (q > 0 && cl[q - 1].d2 > d2) {
						cl[q] = cl[q - 1];
						q--;
					}
					cl[q].d2 = d2;
					cl[q].s = sid;
				}
				ncand[b] = m;
			}
			for (size_t r = 0; r < rows; r++)
				for (size_t i = 0; i < run; i++) {
					found[r][i] = 0;
					last[r][i] = UINT32_MAX;
				}
			for (size_t z = nz; z-- > 0;)
				for (size_t r = 0; r < rows; r++) {
					size_t y = y0 + r, row = z * plane + y * nx + x0;
					const float *dens = v->density + row;
					const uint8_t *need = c->need ? c->need + y * nx + x0 : NULL;
					for (size_t i = 0; i < run; i++) {
						const cand *cl = cands + (i / SEG_B) * stride;
						uint32_t nc = ncand[i / SEG_B], lab = 0, bk = UINT32_MAX;
						float best = c->maxr2 * 1.000001f + 1e-6f;
						float fx = (float)(x0 + i), fy = (float)y, fz = (float)z;
						if (need && !need[i])
							continue; /* skipped by the refinement */
						if (!(dens[i] > c->thr)) {
							if (c->label)
								c->label[row + i] = 0;
							continue;
						}
						/* warm start with the winner of the voxel above; the
						   result is still the first minimum in list order */
						if (last[r][i] != UINT32_MAX) {
							const seg *sg = &c->segs[cl[last[r][i]].s];
							float d2 = seg_dist2(sg, fx, fy, fz);
							if (d2 < best) {
								best = d2;
								bk = last[r][i];
								lab = sg->curve + 1;
							}
						}
						for (uint32_t k = 0; k < nc && cl[k].d2 <= best; k++) {
							const seg *sg;
							float d2;
							if (k == bk)
								continue;
							sg = &c->segs[cl[k].s];
							d2 = seg_dist2(sg, fx, fy, fz);
							if (d2 < best || (d2 == best && k < bk)) {
								best = d2;
								bk = k;
								lab = sg->curve + 1;
							}
						}
						last[r][i] = bk;
						if (c->label)
							c->label[row + i] = (uint8_t)lab;
						if (!found[r][i]) {
							found[r][i] = 1;
							if (c->top)
								c->top[y * nx + x0 + i] = (uint8_t)lab;
						}
						if (lab && c->acc)
							refine_add(c, c->acc + (size_t)tid * c->npts * 3, lab,
							           (long)(x0 + i), (long)y, (long)z, dens[i]);
						if (lab) {
							loom_scan_moments *mm = &mom[lab - 1];
							int64_t xx = (int64_t)(x0 + i), yy = (int64_t)y;
							mm->n++;
							mm->sx += xx;
							mm->sy += yy;
							mm->sxx += xx * xx;
							mm->sxy += xx * yy;
							mm->syy += yy * yy;
						}
					}
				}
			if (c->top)
				for (size_t r = 0; r < rows; r++)
					for (size_t i = 0; i < run; i++)
						if (!found[r][i])
							c->top[(y0 + r) * nx + x0 + i] = 0;
		}
	}
	free(cands);
}

/* The segmentation pass; ext (may be NULL) carries the refinement
   fields of seg_ctx, which are copied in. */
static int segment_run(const loom_scan_volume *v, float threshold,
                       const loom_scan_curve *curves, uint32_t n,
                       const float *semi_axes, float max_dist, uint32_t threads,
                       uint8_t *label, uint8_t *top, loom_scan_moments *moments,
                       const seg_ctx *ext, loom_diag *diag)
{
	seg_ctx c;
	seg *segs = NULL;
	float ref = 1;
	uint32_t nseg = 0, gx, gy, *start = NULL, *ids = NULL, *fill = NULL;
	size_t total = 0;
	int rc = loom__scan_check_volume(v, "segmentation", diag);

	if (rc)
		return rc;
	if (!curves || n == 0 || n > 2 * LOOM_SCAN_MAX_YARNS || !(max_dist > 0))
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: segmentation: need 1..%u curves and max_dist > 0",
		                  2 * LOOM_SCAN_MAX_YARNS);
	if (threads == 0)
		threads = 1;
	for (uint32_t i = 0; i < n && semi_axes; i++)
		if (!(semi_axes[2 * i] > 0) || !(semi_axes[2 * i + 1] > 0))
			return loom__fail(diag, LOOM_EINVAL,
			                  "scan: segmentation: semi-axes of curve %u not > 0", i);
	/* distances are in units of the reference semi-axis, so max_dist keeps
	   its meaning in voxels for a yarn of that size */
	if (semi_axes) {
		ref = 0;
		for (uint32_t i = 0; i < 2 * n; i++)
			ref = semi_axes[i] > ref ? semi_axes[i] : ref;
	}
	for (uint32_t i = 0; i < n; i++) {
		if (!curves[i].pts || !curves[i].n)
			return loom__fail(diag, LOOM_EINVAL,
			                  "scan: segmentation: curve %u is empty", i);
		nseg += curves[i].n > 1 ? curves[i].n - 1 : 1;
	}
	memset(&c, 0, sizeof c);
	gx = (v->nx + SEG_CELL - 1) / SEG_CELL;
	gy = (v->ny + SEG_CELL - 1) / SEG_CELL;
	segs = malloc(nseg * sizeof *segs);
	start = calloc((size_t)gx * gy + 1, sizeof *start);
	fill = calloc((size_t)gx * gy, sizeof *fill);
	c.mom = calloc((size_t)threads * n, sizeof *c.mom);
	if (!segs || !start || !fill || !c.mom)
		goto oom;
	nseg = 0;
	for (uint32_t i = 0; i < n; i++) {
		const float *p = curves[i].pts;
		uint32_t m = curves[i].n > 1 ? curves[i].n - 1 : 1;
		for (uint32_t k = 0; k < m; k++) {
			seg *s = &segs[nseg++];
			const float *b = curves[i].n > 1 ? p + 3 * (k + 1) : p + 3 * k;
			float l2, l2xy;
			for (int q = 0; q < 3; q++) {
				s->a[q] = p[3 * k + q];
				s->u[q] = b[q] - p[3 * k + q];
			}
			l2xy = s->u[0] * s->u[0] + s->u[1] * s->u[1];
			l2 = l2xy + s->u[2] * s->u[2];
			s->inv = l2 > 0 ? 1 / l2 : 0;
			s->inv_xy = l2xy > 0 ? 1 / l2xy : 0;
			s->curve = i;
			seg_metric(s, semi_axes ? semi_axes[2 * i] : 1,
			           semi_axes ? semi_axes[2 * i + 1] : 1, ref);
		}
	}
	/* two passes over the segments' grown boxes: count, then fill */
	for (int pass = 0; pass < 2; pass++) {
		for (uint32_t s = 0; s < nseg; s++) {
			float x0 = fminf(segs[s].a[0], segs[s].a[0] + segs[s].u[0]) - max_dist;
			float x1 = fmaxf(segs[s].a[0], segs[s].a[0] + segs[s].u[0]) + max_dist;
			float y0 = fminf(segs[s].a[1], segs[s].a[1] + segs[s].u[1]) - max_dist;
			float y1 = fmaxf(segs[s].a[1], segs[s].a[1] + segs[s].u[1]) + max_dist;
			long cx0 = (long)floorf(x0 / SEG_CELL), cx1 = (long)floorf(x1 / SEG_CELL);
			long cy0 = (long)floorf(y0 / SEG_CELL), cy1 = (long)floorf(y1 / SEG_CELL);
			if (cx1 < 0 || cy1 < 0 || cx0 >= (long)gx || cy0 >= (long)gy)
				continue;
			cx0 = cx0 < 0 ? 0 : cx0;
			cy0 = cy0 < 0 ? 0 : cy0;
			cx1 = cx1 >= (long)gx ? (long)gx - 1 : cx1;
			cy1 = cy1 >= (long)gy ? (long)gy - 1 : cy1;
			for (long cy = cy0; cy <= cy1; cy++)
				for (long cx = cx0; cx <= cx1; cx++) {
					size_t cell = (size_t)cy * gx + (size_t)cx;
					if (pass == 0)
						start[cell + 1]++;
					else
						ids[start[cell] + fill[cell]++] = s;
				}
		}
		if (pass == 0) {
			for (size_t cell = 0; cell < (size_t)gx * gy; cell++) {
				uint32_t len = start[cell + 1];
				if (len > c.max_list)
					c.max_list = len;
				start[cell + 1] = start[cell] + len;
			}
			total = start[(size_t)gx * gy];
			ids = malloc((total ? total : 1) * sizeof *ids);
			if (!ids)
				goto oom;
		}
	}
	c.v = v;
	c.thr = threshold;
	c.max2 = max_dist * max_dist;
	c.max_dist = max_dist;
	c.maxr2 = c.max2;
	c.segs = segs;
	c.cell_start = start;
	c.cell_ids = ids;
	c.gx = gx;
	c.ncurves = n;
	c.label = label;
	c.top = top;
	if (ext) {
		c.curves = ext->curves;
		c.plane_pt = ext->plane_pt;
		c.plane_off = ext->plane_off;
		c.pt_off = ext->pt_off;
		c.ell = ext->ell;
		c.acc = ext->acc;
		c.npts = ext->npts;
		c.need = ext->need;
	}
	loom__scan_parallel(threads, seg_worker, &c);
	if (c.failed)
		goto oom;
	if (moments) {
		memset(moments, 0, n * sizeof *moments);
		for (uint32_t t = 0; t < threads; t++)
			for (uint32_t i = 0; i < n; i++) {
				const loom_scan_moments *m = &c.mom[(size_t)t * n + i];
				moments[i].n += m->n;
				moments[i].sx += m->sx;
				moments[i].sy += m->sy;
				moments[i].sxx += m->sxx;
				moments[i].sxy += m->sxy;
				moments[i].syy += m->syy;
			}
	}
	free(segs);
	free(start);
	free(fill);
	free(ids);
	free(c.mom);
	return LOOM_OK;
oom:
	free(segs);
	free(start);
	free(fill);
	free(ids);
	free(c.mom);
	return loom__fail(diag, LOOM_ENOMEM, "scan: segmentation: out of memory");
}

LOOM_API int loom_scan_segment(const loom_scan_volume *v, float threshold,
                               const loom_scan_curve *curves, uint32_t n,
                               const float *semi_axes, float max_dist,
                               uint32_t threads, uint8_t *label, uint8_t *top,
                               loom_scan_moments *moments, loom_diag *diag)
{
	return segment_run(v, threshold, curves, n, semi_axes, max_dist, threads,
	                   label, top, moments, NULL, diag);
}

/*
 * Centre refinement: one segmentation pass that, for every interior point of
 * every curve, sums the density of the voxels labelled with its own yarn on
 * the point's plane (perpendicular to the main axis) inside the window of
 * semi-axes 1.3 A x 1.6 B; each point then moves to that centre of mass.
 * Unlike the tracker's correction, which must guess its yarn's material from
 * the orientation field, this uses the labels: material of the crossing yarn
 * and of the contact zone, where orientation is least reliable, is split
 * between the two yarns by the segmentation rule itself.
 */
LOOM_API int loom_scan_refine(const loom_scan_volume *v, float threshold,
                              loom_scan_curve *curves, uint32_t n,
                              const float *semi_axes, float max_dist,
                              uint32_t threads, loom_diag *diag)
{
	seg_ctx ext;
	size_t total_planes = 0;
	uint32_t npts = 0;
	int32_t *plane_pt = NULL;
	uint8_t *need = NULL;
	size_t *plane_off = NULL;
	uint32_t *pt_off = NULL;
	float *ell = NULL;
	int64_t *acc = NULL;
	int rc = loom__scan_check_volume(v, "refinement", diag);

	if (rc)
		return rc;
	if (!curves || !semi_axes || n == 0 || n > 2 * LOOM_SCAN_MAX_YARNS)
		return loom__fail(diag, LOOM_EINVAL, "scan: refinement: bad arguments");
	if (threads == 0)
		threads = 1;
	if (threads > 64)
		threads = 64;
	for (uint32_t i = 0; i < n; i++) {
		if (!curves[i].pts || !curves[i].n)
			return loom__fail(diag, LOOM_EINVAL, "scan: refinement: curve %u is empty", i);
		total_planes += curves[i].kind == LOOM_SCAN_WARP ? v->ny : v->nx;
		npts += curves[i].n;
	}
	need = calloc((size_t)v->nx * v->ny, 1);
	plane_pt = malloc(total_planes * sizeof *plane_pt);
	plane_off = malloc(n * sizeof *plane_off);
	pt_off = malloc(n * sizeof *pt_off);
	ell = malloc(2 * (size_t)n * sizeof *ell);
	acc = calloc((size_t)threads * npts * 3, sizeof *acc);
	if (!need || !plane_pt || !plane_off || !pt_off || !ell || !acc) {
		rc = loom__fail(diag, LOOM_ENOMEM, "scan: refinement: out of memory");
		goto done;
	}
	total_planes = 0;
	npts = 0;
	for (uint32_t i = 0; i < n; i++) {
		int warp = curves[i].kind == LOOM_SCAN_WARP;
		uint32_t nm = warp ? v->ny : v->nx;
		plane_off[i] = total_planes;
		pt_off[i] = npts;
		for (uint32_t m = 0; m < nm; m++)
			plane_pt[total_planes + m] = -1;
		/* interior points only: the end points sit on the boundary */
		for (uint32_t k = 1; k + 1 < curves[i].n; k++) {
			long m = lround(curves[i].pts[3 * k + (warp ? 1 : 0)]);
			if (m >= 0 && m < (long)nm && plane_pt[total_planes + (size_t)m] < 0) {
				/* labels are needed only on that plane, inside the
				   window: mark those columns */
				float lat = curves[i].pts[3 * k + (warp ? 0 : 1)];
				float half = 1.3f * semi_axes[2 * i] + 1;
				long q0 = (long)floorf(lat - half), q1 = (long)ceilf(lat + half);
				uint32_t nl = warp ? v->nx : v->ny;
				plane_pt[total_planes + (size_t)m] = (int32_t)k;
				q0 = q0 < 0 ? 0 : q0;
				q1 = q1 >= (long)nl ? (long)nl - 1 : q1;
				for (long q = q0; q <= q1; q++)
					need[warp ? (size_t)m * v->nx + (size_t)q
					          : (size_t)q * v->nx + (size_t)m] = 1;
			}
		}
		ell[2 * i] = 1.3f * semi_axes[2 * i];
		ell[2 * i + 1] = 1.6f * semi_axes[2 * i + 1];
		total_planes += nm;
		npts += curves[i].n;
	}
	memset(&ext, 0, sizeof ext);
	ext.curves = curves;
	ext.plane_pt = plane_pt;
	ext.plane_off = plane_off;
	ext.pt_off = pt_off;
	ext.ell = ell;
	ext.acc = acc;
	ext.npts = npts;
	ext.need = need;
	rc = segment_run(v, threshold, curves, n, semi_axes, max_dist, threads, NULL,
	                 NULL, NULL, &ext, diag);
	if (rc == LOOM_OK)
		for (uint32_t i = 0; i < n; i++) {
			int warp = curves[i].kind == LOOM_SCAN_WARP;
			for (uint32_t k = 1; k + 1 < curves[i].n; k++) {
				int64_t sw = 0, sl = 0, sz = 0;
				for (uint32_t t = 0; t < threads; t++) {
					const int64_t *a = acc + 3 * ((size_t)t * npts + pt_off[i] + k);
					sw += a[0];
					sl += a[1];
					sz += a[2];
				}
				if (sw > 0) {
					curves[i].pts[3 * k + (warp ? 0 : 1)] = (float)((double)sl / sw);
					curves[i].pts[3 * k + 2] = (float)((double)sz / sw);
				}
			}
		}
done:
	free(need);
	free(plane_pt);
	free(plane_off);
	free(pt_off);
	free(ell);
	free(acc);
	return rc;
}
