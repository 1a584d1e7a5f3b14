/*
 * engine/scan/scan_track.c - scan pipeline steps 3 and 4: endpoint detection by
 * K-means on slices and yarn tracking with centre correction (paper 6.1).
 *
 * Endpoints.  A slice perpendicular to y (for warps; x for wefts) cuts every
 * warp once.  Its voxels above the threshold whose orientation lies within
 * the cone |o.axis| >= cone_cos of the slice normal are the warps' cross
 * sections; K-means with K = the user's warp count puts one centre in each.
 * A slice is accepted only when its clusters look like K separate yarns,
 * judged against the lateral profile h(l) (selected voxels per lateral
 * position, summed over 5 neighbouring slices and smoothed): the profile's
 * bumps (local maxima merged until the valley between neighbours falls
 * below gap x the lower peak; bumps under 15% of the median dropped) are
 * the yarns, and there must be exactly one cluster centre per bump.  Also
 * no cluster under 5% of the median size, neighbour gaps within
 * [0.55, 1.45] x median and the largest RMS cluster radius under 0.45 x the
 * median gap.  Among accepted slices the one with the smallest largest RMS
 * cluster radius wins (paper: "minimizes the maximal cluster radius").
 * When none is accepted, the bump counts tell the user why: most slices
 * agreeing on another count means a wrong yarn count (LOOM_EMISMATCH),
 * disagreement means noise or no weave (LOOM_EUNSUPPORTED).
 *
 * Tracking.  From an endpoint p, in both directions along the main axis:
 *   1. t = normalize(sum of w sign(w.t0)) over voxels v with |v - p| <= R,
 *      density > threshold and |w.t0| >= c0 |w| (w = orientation at v);
 *   2. t is kept within 20 degrees of the main axis in xy and 50 degrees
 *      in z (the paper assumes a roughly aligned scan; this stops errors of
 *      the orientation field near crossings from walking the tracker onto
 *      a neighbour); p += d t;
 *   3. centre correction (correct_centre): on the slice through p
 *      perpendicular to the main axis, p moves to the centre of mass of the
 *      elliptical region around it (see the function for the weights),
 *      repeated until it moves less than 0.05 voxel;
 *   4. stop when p leaves the volume: the last point is put on the boundary.
 * Afterwards every curve must be straight in projection (lateral excursion
 * from its least-squares line under 0.3 x spacing) and neighbours must not
 * share a yarn; either failure is reported rather than returned as garbage.
 */
#include "scan_internal.h"

#include <stdlib.h>
#include <string.h>

/* ---- K-means on one slice ----------------------------------------------- */

enum { REASON_OK = 0, REASON_MANY, REASON_FEW, REASON_EMPTY };

#define KM_MAX_POINTS 8192 /* K-means on a regular subsample of this many */

typedef struct slice_res {
	int reason;
	float max_radius;
	float semi[2];             /* cross-section semi-axes (lateral, z) */
	uint32_t bumps;            /* yarns (bumps) in the lateral profile */
	float where;               /* lateral position of the problem */
	float cent[LOOM_SCAN_MAX_YARNS][2]; /* (lateral, z), sorted */
} slice_res;

typedef struct ep_ctx {
	const loom_scan_volume *v;
	int kind;
	uint32_t k;
	float thr;
	const loom_scan_params *p;
	uint32_t nslices;
	uint32_t *slices;
	slice_res *res;
	int failed;
} ep_ctx;

static void kmeans(const float *pts, size_t n, uint32_t k, uint32_t iters,
                   uint64_t seed, float *cent, uint32_t *assign, double *d2)
{
	uint64_t s = seed;
	size_t first = (size_t)(loom__scan_mix(&s) % n);
	double sums[LOOM_SCAN_MAX_YARNS][3];

	cent[0] = pts[2 * first];
	cent[1] = pts[2 * first + 1];
	for (size_t i = 0; i < n; i++) {
		double dx = pts[2 * i] - cent[0], dz = pts[2 * i + 1] - cent[1];
		d2[i] = dx * dx + dz * dz;
	}
	for (uint32_t c = 1; c < k; c++) {
		double total = 0, target, acc = 0;
		size_t pick = n - 1;
		for (size_t i = 0; i < n; i++)
			total += d2[i];
		if (total > 0) {
			target = loom__scan_unif(&s) * total;
			for (size_t i = 0; i < n; i++) {
				acc += d2[i];
				if (acc > target) {
					pick = i;
					break;
				}
			}
		} else {
			pick = (size_t)(loom__scan_mix(&s) % n);
		}
		cent[2 * c] = pts[2 * pick];
		cent[2 * c + 1] = pts[2 * pick + 1];
		for (size_t i = 0; i < n; i++) {
			double dx = pts[2 * i] - cent[2 * c], dz = pts[2 * i + 1] - cent[2 * c + 1];
			double e = dx * dx + dz * dz;
			if (e < d2[i])
				d2[i] = e;
		}
	}
	for (size_t i = 0; i < n; i++)
		assign[i] = UINT32_MAX;
	for (uint32_t it = 0; it < iters; it++) {
		size_t changed = 0;
		for (size_t i = 0; i < n; i++) {
			double best = 1e300;
			uint32_t bc = 0;
			for (uint32_t c = 0; c < k; c++) {
				double dx = pts[2 * i] - cent[2 * c], dz = pts[2 * i + 1] - cent[2 * c + 1];
				double e = dx * dx + dz * dz;
				if (e < best) {
					best = e;
					bc = c;
				}
			}
			d2[i] = best;
			if (assign[i] != bc) {
				assign[i] = bc;
				changed++;
			}
		}
		if (!changed)
			break;
		memset(sums, 0, sizeof(double) * 3 * k);
		for (size_t i = 0; i < n; i++) {
			sums[assign[i]][0] += pts[2 * i];
			sums[assign[i]][1] += pts[2 * i + 1];
			sums[assign[i]][2] += 1;
		}
		for (uint32_t c = 0; c < k; c++) {
			if (sums[c][2] > 0) {
				cent[2 * c] = (float)(sums[c][0] / sums[c][2]);
				cent[2 * c + 1] = (float)(sums[c][1] / sums[c][2]);
			} else {
				/* empty cluster: restart it at the worst-served point */
				size_t far = 0;
				for (size_t i = 1; i < n; i++)
					if (d2[i] > d2[far])
						far = i;
				cent[2 * c] = pts[2 * far];
				cent[2 * c + 1] = pts[2 * far + 1];
				d2[far] = 0;
			}
		}
	}
}

/*
 * The bumps of a lateral profile h[0..n): local maxima, merged while the
 * lowest point between two neighbours is above gap x the lower of them (no
 * real dip), then bumps lower than 15% of the median bump dropped (noise).
 * lo[i] = first index of bump i (lo[0] = 0; a bump ends where the next
 * starts, at the lowest point between them), pk[i] = its peak.  Returns the
 * number of bumps.
 */
static uint32_t find_bumps(const float *h, uint32_t n, float gap, uint32_t *lo,
                           uint32_t *pk)
{
	uint32_t np = 0, changed = 1;
	float hs[64], med;

	for (uint32_t i = 0; i < n; i++) {
		float l = i > 0 ? h[i - 1] : -1, r = i + 1 < n ? h[i + 1] : -1;
		if (h[i] > l && h[i] >= r && h[i] > 0)
			pk[np++] = i;
	}
	while (changed && np > 1) {
		changed = 0;
		for (uint32_t i = 0; i + 1 < np; i++) {
			float valley = h[pk[i]];
			for (uint32_t q = pk[i]; q <= pk[i + 1]; q++)
				if (h[q] < valley)
					valley = h[q];
			if (valley > gap * fminf(h[pk[i]], h[pk[i + 1]])) {
				if (h[pk[i + 1]] > h[pk[i]])
					pk[i] = pk[i + 1];
				memmove(pk + i + 1, pk + i + 2, (np - i - 2) * sizeof *pk);
				np--;
				changed = 1;
				break;
			}
		}
	}
	/* drop noise bumps: lower than 15% of the median height (of up to 64) */
	{
		uint32_t m = np < 64 ? np : 64;
		for (uint32_t i = 0; i < m; i++) {
			float v = h[pk[i]];
			uint32_t q = i;
			while (q > 0 && hs[q - 1] > v) {
				hs[q] = hs[q - 1];
				q--;
			}
			hs[q] = v;
		}
		med = m ? hs[m / 2] : 0;
		for (uint32_t i = 0; i < np;)
			if (h[pk[i]] < 0.15f * med) {
				memmove(pk + i, pk + i + 1, (np - i - 1) * sizeof *pk);
				np--;
			} else {
				i++;
			}
	}
	for (uint32_t i = 0; i < np; i++) {
		uint32_t best = pk[i];
		if (i == 0) {
			lo[i] = 0;
			continue;
		}
		for (uint32_t q = pk[i - 1]; q <= pk[i]; q++)
			if (h[q] < h[best])
				best = q;
		lo[i] = best;
	}
	return np;
}

typedef struct ep_buf {
	float *pts, *sub, *hist, *hs;
	uint32_t *assign, *bump_lo, *bump_pk;
	double *d2;
} ep_buf;

#define SLAB_HALF 2   /* lateral profile over 2*SLAB_HALF+1 slices */
#define GAP_MIN 0.55f /* neighbour gaps within [GAP_MIN, GAP_MAX] x median */
#define GAP_MAX 1.45f
#define RADIUS_MAX 0.45f /* largest RMS cluster radius / median gap */

/* Voxel (x,y,z) is material oriented within the cone of the slice normal. */
static int selected(const loom_scan_volume *v, int warp, uint32_t x, uint32_t y,
                    uint32_t z, float thr, float cone)
{
	size_t i = loom__scan_idx(v, x, y, z);
	float o[3], on2, oa;
	loom__scan_dir(v, loom__scan_code_lut(), i, o);
	on2 = o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
	oa = warp ? o[1] : o[0];
	return v->density[i] > thr && on2 > 0 && oa * oa >= cone * cone * on2;
}

static void analyse_slice(ep_ctx *c, ep_buf *b, uint32_t slice, slice_res *res)
{
	const loom_scan_volume *v = c->v;
	int warp = c->kind == LOOM_SCAN_WARP;
	uint32_t nlat = warp ? v->nx : v->ny, k = c->k;
	float cone = c->p->cone_cos, gap = c->p->gap_ratio;
	size_t n = 0, ns, stride;
	uint32_t order[LOOM_SCAN_MAX_YARNS], counts[LOOM_SCAN_MAX_YARNS];
	double rad[LOOM_SCAN_MAX_YARNS], var[LOOM_SCAN_MAX_YARNS][2];
	float cent[2 * LOOM_SCAN_MAX_YARNS];
	float sw[2 * LOOM__SCAN_MAX_RADIUS + 1];
	int sr = loom__scan_gauss(1.0f, sw);
	uint32_t med;

	memset(res, 0, sizeof *res);
	for (uint32_t z = 0; z < v->nz; z++)
		for (uint32_t l = 0; l < nlat; l++)
			if (selected(v, warp, warp ? l : slice, warp ? slice : l, z,
			             c->thr, cone)) {
				b->pts[2 * n] = (float)l;
				b->pts[2 * n + 1] = (float)z;
				n++;
			}
	if (n < (size_t)k * 8) {
		res->reason = REASON_EMPTY;
		return;
	}
	/* lateral profile over a slab of SLAB_HALF slices on either side (the
	   yarns run across it, so they stay in place while counts add up),
	   smoothed with a Gaussian of one voxel */
	memset(b->hist, 0, nlat * sizeof *b->hist);
	{
		uint32_t na = warp ? v->ny : v->nx;
		uint32_t s0 = slice >= SLAB_HALF ? slice - SLAB_HALF : 0;
		uint32_t s1 = slice + SLAB_HALF < na ? slice + SLAB_HALF : na - 1;
		/* slab slices innermost: for wefts (x = const) the slices share
		   cache lines */
		for (uint32_t z = 0; z < v->nz; z++)
			for (uint32_t l = 0; l < nlat; l++)
				for (uint32_t sl = s0; sl <= s1; sl++)
					if (selected(v, warp, warp ? l : sl, warp ? sl : l, z,
					             c->thr, cone))
						b->hist[l] += 1;
	}
	for (long l = 0; l < (long)nlat; l++) {
		float acc = 0;
		for (int j = -sr; j <= sr; j++) {
			long q = l + j;
			q = q < 0 ? 0 : q >= (long)nlat ? (long)nlat - 1 : q;
			acc += sw[j + sr] * b->hist[q];
		}
		b->hs[l] = acc;
	}
	res->bumps = find_bumps(b->hs, nlat, gap, b->bump_lo, b->bump_pk);
	/* K-means on at most KM_MAX_POINTS points (regular subsample) */
	stride = (n + KM_MAX_POINTS - 1) / KM_MAX_POINTS;
	ns = 0;
	for (size_t i = 0; i < n; i += stride) {
		b->sub[2 * ns] = b->pts[2 * i];
		b->sub[2 * ns + 1] = b->pts[2 * i + 1];
		ns++;
	}
	kmeans(b->sub, ns, k, c->p->kmeans_iters,
	       c->p->seed ^ ((uint64_t)c->kind << 40) ^ ((uint64_t)slice * 0x9E3779B97F4A7C15ull),
	       cent, b->assign, b->d2);
	memset(counts, 0, sizeof counts);
	memset(rad, 0, sizeof rad);
	memset(var, 0, sizeof var);
	for (size_t i = 0; i < ns; i++) {
		uint32_t a = b->assign[i];
		double dl = b->sub[2 * i] - cent[2 * a], dz = b->sub[2 * i + 1] - cent[2 * a + 1];
		counts[a]++;
		rad[a] += dl * dl + dz * dz;
		var[a][0] += dl * dl;
		var[a][1] += dz * dz;
	}
	for (uint32_t j = 0; j < k; j++)
		order[j] = j;
	for (uint32_t j = 1; j < k; j++) { /* insertion sort by lateral, then z */
		uint32_t t = order[j], m = j;
		while (m > 0 && (cent[2 * order[m - 1]] > cent[2 * t] ||
		                 (cent[2 * order[m - 1]] == cent[2 * t] &&
		                  cent[2 * order[m - 1] + 1] > cent[2 * t + 1]))) {
			order[m] = order[m - 1];
			m--;
		}
		order[m] = t;
	}
	res->max_radius = 0;
	for (uint32_t j = 0; j < k; j++) {
		uint32_t cj = order[j];
		float r = counts[cj] ? (float)sqrt(rad[cj] / counts[cj]) : 0;
		res->cent[j][0] = cent[2 * cj];
		res->cent[j][1] = cent[2 * cj + 1];
		if (r > res->max_radius)
			res->max_radius = r;
	}
	/* cross-section semi-axes: a uniform ellipse with semi-axes (A, B)
	   has RMS spreads (A/2, B/2); median over the interior clusters (the
	   outer ones may be cut by the scan border) */
	for (int ax = 0; ax < 2; ax++) {
		float sp[LOOM_SCAN_MAX_YARNS];
		uint32_t m = 0, j0 = k > 2 ? 1 : 0, j1 = k > 2 ? k - 1 : k;
		for (uint32_t j = j0; j < j1; j++) {
			uint32_t cj = order[j];
			float sd = counts[cj] ? (float)sqrt(var[cj][ax] / counts[cj]) : 0;
			uint32_t q = m++;
			while (q > 0 && sp[q - 1] > sd) {
				sp[q] = sp[q - 1];
				q--;
			}
			sp[q] = sd;
		}
		res->semi[ax] = m ? 2 * sp[m / 2] : 0;
	}
	/* tiny clusters: noise taken for a yarn */
	{
		uint32_t sorted[LOOM_SCAN_MAX_YARNS];
		memcpy(sorted, counts, k * sizeof *counts);
		for (uint32_t j = 1; j < k; j++) {
			uint32_t t = sorted[j], m = j;
			while (m > 0 && sorted[m - 1] > t) {
				sorted[m] = sorted[m - 1];
				m--;
			}
			sorted[m] = t;
		}
		med = sorted[k / 2];
		for (uint32_t j = 0; j < k; j++)
			if (counts[order[j]] * 20 < med) {
				res->reason = REASON_MANY;
				res->where = res->cent[j][0];
				return;
			}
	}
	/* centres evenly spaced: a gap far below the median means a yarn was
	   split, far above it that a cluster spans two yarns; and no cluster
	   may be wide compared to the spacing (two yarns in it) */
	if (k >= 3) {
		float gaps[LOOM_SCAN_MAX_YARNS], sorted[LOOM_SCAN_MAX_YARNS], medg;
		for (uint32_t j = 0; j + 1 < k; j++) {
			float g = res->cent[j + 1][0] - res->cent[j][0];
			uint32_t m = j;
			gaps[j] = g;
			while (m > 0 && sorted[m - 1] > g) {
				sorted[m] = sorted[m - 1];
				m--;
			}
			sorted[m] = g;
		}
		medg = sorted[(k - 1) / 2];
		for (uint32_t j = 0; j + 1 < k; j++) {
			if (gaps[j] < GAP_MIN * medg) {
				res->reason = REASON_MANY;
				res->where = 0.5f * (res->cent[j][0] + res->cent[j + 1][0]);
				return;
			}
			if (gaps[j] > GAP_MAX * medg) {
				res->reason = REASON_FEW;
				res->where = 0.5f * (res->cent[j][0] + res->cent[j + 1][0]);
				return;
			}
		}
		if (res->max_radius > RADIUS_MAX * medg) {
			res->reason = REASON_FEW;
			res->where = -1;
			return;
		}
	}
	/* the lateral profile's bumps are the yarns: exactly one centre each */
	{
		uint32_t nb = res->bumps;
		uint32_t prev = UINT32_MAX, used = 0, jb = 0;
		for (uint32_t j = 0; j < k; j++) {
			float cl = res->cent[j][0];
			while (jb + 1 < nb && cl >= (float)b->bump_lo[jb + 1])
				jb++;
			if (jb == prev) {
				res->reason = REASON_MANY; /* two centres on one yarn */
				res->where = cl;
				return;
			}
			if (prev != UINT32_MAX && jb > prev + 1) {
				res->reason = REASON_FEW; /* a yarn without a centre */
				res->where = (float)b->bump_pk[prev + 1];
				return;
			}
			prev = jb;
			used++;
		}
		if (nb > used) {
			res->reason = REASON_FEW;
			res->where = (float)b->bump_pk[b->bump_lo[0] == 0 &&
			                               res->cent[0][0] >= b->bump_lo[nb > 1 ? 1 : 0]
			                           ? 0 : nb - 1];
			return;
		}
	}
	res->reason = REASON_OK;
}


static void ep_worker(void *vctx, uint32_t tid, uint32_t nt)
{
	ep_ctx *c = vctx;
	const loom_scan_volume *v = c->v;
	uint32_t nlat = c->kind == LOOM_SCAN_WARP ? v->nx : v->ny;
	size_t maxp = (size_t)nlat * v->nz;
	ep_buf b;

	b.pts = malloc(2 * maxp * sizeof *b.pts);
	b.sub = malloc(2 * (size_t)KM_MAX_POINTS * sizeof *b.sub);
	b.hist = malloc(2 * (size_t)nlat * sizeof *b.hist);
	b.assign = malloc((size_t)KM_MAX_POINTS * sizeof *b.assign);
	b.bump_lo = malloc(2 * (size_t)nlat * sizeof *b.bump_lo);
	b.d2 = malloc((size_t)KM_MAX_POINTS * sizeof *b.d2);
	if (!b.pts || !b.sub || !b.hist || !b.assign || !b.bump_lo || !b.d2) {
		__atomic_store_n(&c->failed, 1, __ATOMIC_RELAXED);
	} else {
		b.hs = b.hist + nlat;
		b.bump_pk = b.bump_lo + nlat;
		for (uint32_t s = tid; s < c->nslices; s += nt)
		{
			analyse_slice(c, &b, c->slices[s], &c->res[s]);
		}
	}
	free(b.pts);
	free(b.sub);
	free(b.hist);
	free(b.assign);
	free(b.bump_lo);
	free(b.d2);
}

LOOM_API int loom_scan_endpoints_find(const loom_scan_volume *v, int kind,
                                      uint32_t k, float threshold,
                                      const loom_scan_params *p,
                                      loom_scan_endpoints *out,
                                      loom_diag *diag)
{
	const char *what = kind == LOOM_SCAN_WARP ? "warps" : "wefts";
	char axis = kind == LOOM_SCAN_WARP ? 'y' : 'x';
	char lat = kind == LOOM_SCAN_WARP ? 'x' : 'y';
	ep_ctx c;
	uint32_t n_axis, lo, hi, count[4] = {0};
	long best = -1;
	int rc = loom__scan_check_volume(v, "endpoints", diag);

	if (rc)
		return rc;
	if (!out || !p || (kind != LOOM_SCAN_WARP && kind != LOOM_SCAN_WEFT))
		return loom__fail(diag, LOOM_EINVAL, "scan: endpoints: bad arguments");
	if (!v->orient && !v->ocode)
		return loom__fail(diag, LOOM_EINVAL, "scan: endpoints: no orientation");
	if (k < 2 || k > LOOM_SCAN_MAX_YARNS)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: endpoints: %u %s requested; need 2..%u", k,
		                  what, LOOM_SCAN_MAX_YARNS);
	if (p->max_slices < 1 || p->kmeans_iters < 1 || !(p->gap_ratio > 0) ||
	    !(p->gap_ratio < 1) || !(p->cone_cos >= 0) || p->cone_cos > 1)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: endpoints: max_slices, kmeans_iters, gap_ratio "
		                  "in (0,1) or cone_cos in [0,1] out of range");
	memset(out, 0, sizeof *out);
	memset(&c, 0, sizeof c);
	n_axis = kind == LOOM_SCAN_WARP ? v->ny : v->nx;
	if ((kind == LOOM_SCAN_WARP ? v->nx : v->ny) < 2 * k)
		return loom__fail(diag, LOOM_EMISMATCH,
		                  "scan: endpoints: %u %s cannot fit in %u voxels along %c",
		                  k, what, kind == LOOM_SCAN_WARP ? v->nx : v->ny, lat);
	lo = n_axis > 8 ? 2 : 0;
	hi = n_axis > 8 ? n_axis - 3 : n_axis - 1;
	c.nslices = hi - lo + 1 < p->max_slices ? hi - lo + 1 : p->max_slices;
	c.slices = malloc(c.nslices * sizeof *c.slices);
	c.res = malloc(c.nslices * sizeof *c.res);
	if (!c.slices || !c.res) {
		free(c.slices);
		free(c.res);
		return loom__fail(diag, LOOM_ENOMEM, "scan: endpoints: out of memory");
	}
	for (uint32_t s = 0; s < c.nslices; s++)
		c.slices[s] = c.nslices > 1
		                  ? lo + (uint32_t)(((uint64_t)(hi - lo) * s) / (c.nslices - 1))
		                  : (lo + hi) / 2;
	c.v = v;
	c.kind = kind;
	c.k = k;
	c.thr = threshold;
	c.p = p;
	loom__scan_parallel(p->threads, ep_worker, &c);
	if (c.failed) {
		free(c.slices);
		free(c.res);
		return loom__fail(diag, LOOM_ENOMEM, "scan: endpoints: out of memory");
	}
	for (uint32_t s = 0; s < c.nslices; s++) {
		count[c.res[s].reason]++;
		if (c.res[s].reason == REASON_OK &&
		    (best < 0 || c.res[s].max_radius < c.res[best].max_radius))
			best = s;
	}
	out->kind = kind;
	out->k = k;
	out->slices_tried = c.nslices;
	out->slices_valid = count[REASON_OK];
	if (best < 0) {
		/* what do the slices show?  The most common number of bumps
		   (yarns) in the lateral profiles, if most slices agree */
		uint32_t mode = 0, mode_n = 0, nonempty = c.nslices - count[REASON_EMPTY];
		for (uint32_t s = 0; s < c.nslices; s++) {
			uint32_t cnt = 0;
			if (c.res[s].reason == REASON_EMPTY)
				continue;
			for (uint32_t q = 0; q < c.nslices; q++)
				cnt += c.res[q].reason != REASON_EMPTY &&
				       c.res[q].bumps == c.res[s].bumps;
			if (cnt > mode_n || (cnt == mode_n && c.res[s].bumps < mode)) {
				mode_n = cnt;
				mode = c.res[s].bumps;
			}
		}
		if (nonempty == 0)
			rc = loom__fail(diag, LOOM_EUNSUPPORTED,
			                "scan: endpoints: no slice perpendicular to %c has %u "
			                "%s worth of material oriented along %c (threshold "
			                "%.3f); wrong axis, empty or too noisy scan?",
			                axis, k, what, axis, threshold);
		else if (2 * mode_n > nonempty && mode != k)
			rc = loom__fail(diag, LOOM_EMISMATCH,
			                "scan: endpoints: %u %s requested, but %u of %u slices "
			                "perpendicular to %c show %u",
			                k, what, mode_n, nonempty, axis, mode);
		else
			rc = loom__fail(diag, LOOM_EUNSUPPORTED,
			                "scan: endpoints: no slice perpendicular to %c shows "
			                "%u separated %s (%u slices split a yarn, %u merge "
			                "two; their profiles show %u yarns in only %u of %u "
			                "slices); too noisy or not a simple weave?",
			                axis, k, what, count[REASON_MANY], count[REASON_FEW],
			                mode, mode_n, nonempty);
		free(c.slices);
		free(c.res);
		return rc;
	}
	out->slice = c.slices[best];
	out->max_radius = c.res[best].max_radius;
	out->semi_axes[0] = c.res[best].semi[0];
	out->semi_axes[1] = c.res[best].semi[1];
	{
		float gaps[LOOM_SCAN_MAX_YARNS];
		for (uint32_t j = 0; j + 1 < k; j++) {
			float g = c.res[best].cent[j + 1][0] - c.res[best].cent[j][0];
			uint32_t m = j;
			while (m > 0 && gaps[m - 1] > g) {
				gaps[m] = gaps[m - 1];
				m--;
			}
			gaps[m] = g;
		}
		out->spacing = gaps[(k - 1) / 2];
	}
	for (uint32_t j = 0; j < k; j++) {
		float l = c.res[best].cent[j][0], z = c.res[best].cent[j][1];
		out->centre[j][0] = kind == LOOM_SCAN_WARP ? l : (float)out->slice;
		out->centre[j][1] = kind == LOOM_SCAN_WARP ? (float)out->slice : l;
		out->centre[j][2] = z;
	}
	free(c.slices);
	free(c.res);
	return LOOM_OK;
}

/* ---- tracking ----------------------------------------------------------- */

LOOM_API void loom_scan_track_lengths_get(const loom_scan_params *p, int kind,
                                          float scale,
                                          loom_scan_track_lengths *out)
{
	int warp = kind == LOOM_SCAN_WARP;
	if (!p || !out)
		return;
	if (!(scale > 0))
		scale = 1;
	out->step = p->step * scale;
	out->radius = (warp ? p->radius_warp : p->radius_weft) * scale;
	out->ellipse_lateral = (warp ? p->ellipse_warp : p->ellipse_weft) * scale;
	out->ellipse_z = p->ellipse_z * scale;
	out->c0 = p->c0;
	out->correct_iters = p->correct_iters;
	if (out->step < 0.5f)
		out->step = 0.5f;
	if (out->radius < 1.5f)
		out->radius = 1.5f;
	if (out->ellipse_lateral < 1.0f)
		out->ellipse_lateral = 1.0f;
	if (out->ellipse_z < 1.0f)
		out->ellipse_z = 1.0f;
}

/* Mean orientation around p (step 1).  Returns 0 when nothing qualifies. */
static int tangent_at(const loom_scan_volume *v, const double p[3],
                      const double t0[3], float thr,
                      const loom_scan_track_lengths *len, double t[3])
{
	double R = len->radius, c0 = len->c0, sum[3] = {0, 0, 0}, n;
	int s = R > 8 ? (int)ceil(R / 8) : 1;
	long cx = lround(p[0]), cy = lround(p[1]), cz = lround(p[2]);
	long rr = (long)floor(R / s);

	for (long k = -rr; k <= rr; k++) {
		long z = cz + k * s;
		if (z < 0 || z >= (long)v->nz)
			continue;
		for (long j = -rr; j <= rr; j++) {
			long y = cy + j * s;
			if (y < 0 || y >= (long)v->ny)
				continue;
			for (long i = -rr; i <= rr; i++) {
				long x = cx + i * s;
				double dx = x - p[0], dy = y - p[1], dz = z - p[2], c;
				size_t idx;
				float w[3];
				if (x < 0 || x >= (long)v->nx ||
				    dx * dx + dy * dy + dz * dz > R * R)
					continue;
				idx = loom__scan_idx(v, (uint32_t)x, (uint32_t)y, (uint32_t)z);
				if (!(v->density[idx] > thr))
					continue;
				loom__scan_dir(v, loom__scan_code_lut(), idx, w);
				c = w[0] * t0[0] + w[1] * t0[1] + w[2] * t0[2];
				if (fabs(c) < c0 * sqrt((double)w[0] * w[0] + (double)w[1] * w[1] +
				                        (double)w[2] * w[2]) ||
				    c == 0)
					continue;
				if (c < 0) {
					sum[0] -= w[0];
					sum[1] -= w[1];
					sum[2] -= w[2];
				} else {
					sum[0] += w[0];
					sum[1] += w[1];
					sum[2] += w[2];
				}
			}
		}
	}
	n = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
	if (!(n > 0))
		return 0;
	t[0] = sum[0] / n;
	t[1] = sum[1] / n;
	t[2] = sum[2] / n;
	return 1;
}

/*
 * Centre correction (step 3) on the slice through p perpendicular to axis a.
 * Each iteration takes the material (density > threshold) inside the
 * ellipse around p, weighted by density times an Epanechnikov falloff
 * 1 - r^2 (r = ellipse radius), so the far rim, where a neighbour may
 * start, weighs little.  The new z is the centre of mass of the voxels whose
 * orientation agrees with the tangent (|w.t| >= c0): a crossing yarn lying in
 * the slice, above or below, does not pull p off its own yarn.  The new
 * lateral position is the centre of mass of all material: a crossing yarn
 * runs across the slice symmetrically about p, while the own yarn's
 * orientation is least reliable exactly where it touches it.  The lateral
 * move from the predicted point is capped at half the lateral semi-axis so
 * the iteration cannot walk onto a neighbour.  Returns 0 when the ellipse
 * holds no material oriented along the yarn.
 */
static int correct_centre(const loom_scan_volume *v, int a, double p[3],
                          const double t[3], float thr,
                          const loom_scan_track_lengths *len)
{
	int l = 1 - a; /* lateral axis: x (0) for warps, y (1) for wefts */
	uint32_t nl = l == 0 ? v->nx : v->ny, na = a == 0 ? v->nx : v->ny;
	long ia = lround(p[a]);
	double el = len->ellipse_lateral, ez = len->ellipse_z, c0 = len->c0;
	double l_pred = p[l];
	uint32_t iters = len->correct_iters ? len->correct_iters : 1;

	ia = ia < 0 ? 0 : ia >= (long)na ? (long)na - 1 : ia;
	for (uint32_t it = 0; it < iters; it++) {
		double sw = 0, sz = 0, uw = 0, ul = 0, nl_, nz_, shift;
		long l0 = (long)ceil(p[l] - el), l1 = (long)floor(p[l] + el);
		long z0 = (long)ceil(p[2] - ez), z1 = (long)floor(p[2] + ez);
		l0 = l0 < 0 ? 0 : l0;
		l1 = l1 >= (long)nl ? (long)nl - 1 : l1;
		z0 = z0 < 0 ? 0 : z0;
		z1 = z1 >= (long)v->nz ? (long)v->nz - 1 : z1;
		for (long z = z0; z <= z1; z++)
			for (long q = l0; q <= l1; q++) {
				double dl = (q - p[l]) / el, dz = (z - p[2]) / ez;
				double r2 = dl * dl + dz * dz, c, wn, d;
				size_t idx;
				float w[3];
				if (r2 > 1)
					continue;
				idx = l == 0 ? loom__scan_idx(v, (uint32_t)q, (uint32_t)ia, (uint32_t)z)
				             : loom__scan_idx(v, (uint32_t)ia, (uint32_t)q, (uint32_t)z);
				if (!(v->density[idx] > thr))
					continue;
				d = v->density[idx] * (1 - r2);
				uw += d;
				ul += d * q;
				loom__scan_dir(v, loom__scan_code_lut(), idx, w);
				c = w[0] * t[0] + w[1] * t[1] + w[2] * t[2];
				wn = sqrt((double)w[0] * w[0] + (double)w[1] * w[1] +
				          (double)w[2] * w[2]);
				if (c == 0 || fabs(c) < c0 * wn)
					continue;
				sw += d;
				sz += d * z;
			}
		if (!(sw > 0) || !(uw > 0))
			return 0;
		nl_ = ul / uw;
		nz_ = sz / sw;
		if (nl_ > l_pred + 0.5 * el)
			nl_ = l_pred + 0.5 * el;
		else if (nl_ < l_pred - 0.5 * el)
			nl_ = l_pred - 0.5 * el;
		shift = fabs(nl_ - p[l]) + fabs(nz_ - p[2]);
		p[l] = nl_;
		p[2] = nz_;
		if (shift < 0.05)
			break;
	}
	return 1;
}

#define MAX_LATERAL_TAN 0.36397 /* tan(20 degrees) */
#define MAX_RISE_TAN 1.19175    /* tan(50 degrees): steepest crimp */
#define MIN_FORWARD 0.17365     /* cos(80 degrees): turned back = lost */
#define MAX_EXCURSION 0.3       /* of the yarn spacing */

typedef struct pt_list {
	float *p;
	uint32_t n, cap;
} pt_list;

static int pt_push(pt_list *l, const double p[3])
{
	if (l->n == l->cap) {
		uint32_t nc = l->cap ? 2 * l->cap : 64;
		float *np = realloc(l->p, 3 * (size_t)nc * sizeof *np);
		if (!np)
			return 0;
		l->p = np;
		l->cap = nc;
	}
	l->p[3 * l->n] = (float)p[0];
	l->p[3 * l->n + 1] = (float)p[1];
	l->p[3 * l->n + 2] = (float)p[2];
	l->n++;
	return 1;
}

/* Track from p0 in direction dir (+1/-1 along axis a); appends the points
   after p0 to l.  Returns LOOM_OK or an error with diag set. */
static int track_dir(const loom_scan_volume *v, int a, const double p0[3],
                     int dir, float thr, const loom_scan_track_lengths *len,
                     pt_list *l, const char *what, loom_diag *diag)
{
	double p[3] = {p0[0], p0[1], p0[2]}, t0[3] = {0, 0, 0}, t[3];
	double hi[3] = {v->nx - 1.0, v->ny - 1.0, v->nz - 1.0};
	uint32_t na = a == 0 ? v->nx : v->ny;
	uint32_t max_steps = (uint32_t)(2.0 * na / len->step) + 16;

	t0[a] = dir;
	for (uint32_t s = 0; s < max_steps; s++) {
		double q[3], f = 1;
		int out = 0;
		if (!tangent_at(v, p, t0, thr, len, t))
			return loom__fail(diag, LOOM_EUNSUPPORTED,
			                  "scan: tracking: %s lost at (%.1f, %.1f, %.1f): no "
			                  "voxel within R = %.1f oriented within the c0 = %.2f "
			                  "cone of the yarn; too noisy?",
			                  what, p[0], p[1], p[2], len->radius, len->c0);
		if (t[a] * dir < MIN_FORWARD)
			return loom__fail(diag, LOOM_EUNSUPPORTED,
			                  "scan: tracking: %s lost at (%.1f, %.1f, %.1f): the "
			                  "tangent turned %.0f degrees away from the %c axis",
			                  what, p[0], p[1], p[2],
			                  acos(t[a] * dir > 1 ? 1 : t[a] * dir < -1 ? -1 : t[a] * dir) *
			                      57.29577951,
			                  a == 0 ? 'x' : 'y');
		/* the scan is roughly aligned (paper 6.1): in the xy plane a
		   step may not leave the main axis by more than MAX_LATERAL, so
		   orientation errors near crossings cannot walk the tracker
		   sideways onto a neighbour */
		{
			int lat = 1 - a, clamped = 0;
			double lim = fabs(t[a]) * MAX_LATERAL_TAN, rise = fabs(t[a]) * MAX_RISE_TAN;
			if (fabs(t[lat]) > lim) {
				t[lat] = t[lat] < 0 ? -lim : lim;
				clamped = 1;
			}
			if (fabs(t[2]) > rise) {
				t[2] = t[2] < 0 ? -rise : rise;
				clamped = 1;
			}
			if (clamped) {
				double tn = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
				for (int i = 0; i < 3; i++)
					t[i] /= tn;
			}
		}
		for (int i = 0; i < 3; i++)
			q[i] = p[i] + len->step * t[i];
		/* leaving the volume: cut the step at the first boundary it hits */
		for (int i = 0; i < 3; i++) {
			double fi = 1;
			if (q[i] < 0)
				fi = (0 - p[i]) / (q[i] - p[i]);
			else if (q[i] > hi[i])
				fi = (hi[i] - p[i]) / (q[i] - p[i]);
			if (fi < f) {
				f = fi < 0 ? 0 : fi;
				out = 1;
			}
		}
		if (out) {
			for (int i = 0; i < 3; i++)
				q[i] = p[i] + f * (q[i] - p[i]);
			if (!pt_push(l, q))
				return loom__fail(diag, LOOM_ENOMEM, "scan: tracking: out of memory");
			return LOOM_OK;
		}
		if (!correct_centre(v, a, q, t, thr, len))
			return loom__fail(diag, LOOM_EUNSUPPORTED,
			                  "scan: tracking: %s lost at (%.1f, %.1f, %.1f): no "
			                  "material oriented along the yarn in the correction "
			                  "ellipse", what, q[0], q[1], q[2]);
		for (int i = 0; i < 3; i++)
			q[i] = q[i] < 0 ? 0 : q[i] > hi[i] ? hi[i] : q[i];
		if (!pt_push(l, q))
			return loom__fail(diag, LOOM_ENOMEM, "scan: tracking: out of memory");
		if (q[a] <= 0 || q[a] >= hi[a])
			return LOOM_OK;
		memcpy(p, q, sizeof p);
		memcpy(t0, t, sizeof t0);
	}
	return loom__fail(diag, LOOM_EUNSUPPORTED,
	                  "scan: tracking: %s lost near (%.1f, %.1f, %.1f): %u steps "
	                  "without reaching the volume boundary",
	                  what, p[0], p[1], p[2], max_steps);
}

LOOM_API void loom_scan_curve_release(loom_scan_curve *c)
{
	if (!c)
		return;
	free(c->pts);
	memset(c, 0, sizeof *c);
}

LOOM_API int loom_scan_track(const loom_scan_volume *v, int kind,
                             const float start[3], float threshold,
                             const loom_scan_track_lengths *len,
                             loom_scan_curve *out, loom_diag *diag)
{
	int a = kind == LOOM_SCAN_WARP ? 1 : 0;
	const char *what = kind == LOOM_SCAN_WARP ? "warp" : "weft";
	double p[3], t[3] = {0, 0, 0};
	pt_list fw = {0}, bw = {0};
	int rc = loom__scan_check_volume(v, "tracking", diag);

	if (rc)
		return rc;
	if (!out || !start || !len || (kind != LOOM_SCAN_WARP && kind != LOOM_SCAN_WEFT))
		return loom__fail(diag, LOOM_EINVAL, "scan: tracking: bad arguments");
	memset(out, 0, sizeof *out);
	if (!v->orient && !v->ocode)
		return loom__fail(diag, LOOM_EINVAL, "scan: tracking: no orientation");
	if (!(len->step > 0) || !(len->radius > 0) || !(len->ellipse_lateral > 0) ||
	    !(len->ellipse_z > 0) || !(len->c0 >= 0) || len->c0 > 1)
		return loom__fail(diag, LOOM_EINVAL, "scan: tracking: bad lengths");
	for (int i = 0; i < 3; i++)
		p[i] = start[i];
	if (!(p[0] >= 0 && p[0] <= v->nx - 1.0 && p[1] >= 0 && p[1] <= v->ny - 1.0 &&
	      p[2] >= 0 && p[2] <= v->nz - 1.0))
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: tracking: start (%.1f, %.1f, %.1f) outside the "
		                  "volume", p[0], p[1], p[2]);
	t[a] = 1;
	if (!correct_centre(v, a, p, t, threshold, len))
		return loom__fail(diag, LOOM_EUNSUPPORTED,
		                  "scan: tracking: %s start (%.1f, %.1f, %.1f) has no "
		                  "material oriented along the %c axis around it",
		                  what, p[0], p[1], p[2], a == 0 ? 'x' : 'y');
	rc = track_dir(v, a, p, -1, threshold, len, &bw, what, diag);
	if (rc == LOOM_OK)
		rc = track_dir(v, a, p, +1, threshold, len, &fw, what, diag);
	if (rc == LOOM_OK) {
		uint32_t n = bw.n + 1 + fw.n;
		out->pts = malloc(3 * (size_t)n * sizeof *out->pts);
		if (!out->pts) {
			rc = loom__fail(diag, LOOM_ENOMEM, "scan: tracking: out of memory");
		} else {
			for (uint32_t i = 0; i < bw.n; i++)
				memcpy(out->pts + 3 * i, bw.p + 3 * (bw.n - 1 - i), 3 * sizeof(float));
			out->pts[3 * bw.n] = (float)p[0];
			out->pts[3 * bw.n + 1] = (float)p[1];
			out->pts[3 * bw.n + 2] = (float)p[2];
			if (fw.n)
				memcpy(out->pts + 3 * (bw.n + 1), fw.p, 3 * (size_t)fw.n * sizeof(float));
			out->n = n;
			out->kind = kind;
		}
	}
	free(fw.p);
	free(bw.p);
	return rc;
}

/* ---- tracking every yarn ------------------------------------------------ */

typedef struct tr_ctx {
	const loom_scan_volume *v;
	const loom_scan_endpoints *ends[2];
	const loom_scan_track_lengths *len[2];
	float thr;
	loom_scan_curve *curves;
	int *rc;
	loom_diag *diags;
	uint32_t n;
} tr_ctx;

static void tr_worker(void *vctx, uint32_t tid, uint32_t nt)
{
	tr_ctx *c = vctx;
	uint32_t nw = c->ends[0]->k;
	for (uint32_t i = tid; i < c->n; i += nt) {
		int kind = i < nw ? LOOM_SCAN_WARP : LOOM_SCAN_WEFT;
		uint32_t j = i < nw ? i : i - nw;
		c->rc[i] = loom_scan_track(c->v, kind, c->ends[kind]->centre[j], c->thr,
		                           c->len[kind], &c->curves[i], &c->diags[i]);
	}
}

int loom__scan_track_all(const loom_scan_volume *v, const loom_scan_endpoints *we,
                         const loom_scan_endpoints *fe, float thr,
                         const loom_scan_track_lengths *lw,
                         const loom_scan_track_lengths *lf, uint32_t threads,
                         loom_scan_curve *curves, loom_diag *diag)
{
	tr_ctx c;
	int rc = LOOM_OK;
	uint32_t n = we->k + fe->k;

	memset(&c, 0, sizeof c);
	c.v = v;
	c.ends[0] = we;
	c.ends[1] = fe;
	c.len[0] = lw;
	c.len[1] = lf;
	c.thr = thr;
	c.curves = curves;
	c.n = n;
	c.rc = calloc(n, sizeof *c.rc);
	c.diags = calloc(n, sizeof *c.diags);
	if (!c.rc || !c.diags) {
		free(c.rc);
		free(c.diags);
		return loom__fail(diag, LOOM_ENOMEM, "scan: tracking: out of memory");
	}
	loom__scan_parallel(threads, tr_worker, &c);
	for (uint32_t i = 0; i < n && rc == LOOM_OK; i++)
		if (c.rc[i] != LOOM_OK) {
			int warp = i < we->k;
			rc = loom__fail(diag, c.rc[i], "%s (%s %u of %u, from (%.1f, %.1f, %.1f))",
			                c.diags[i].message, warp ? "warp" : "weft",
			                warp ? i : i - we->k, warp ? we->k : fe->k,
			                warp ? we->centre[i][0] : fe->centre[i - we->k][0],
			                warp ? we->centre[i][1] : fe->centre[i - we->k][1],
			                warp ? we->centre[i][2] : fe->centre[i - we->k][2]);
		}
	/* a yarn is straight in projection: a tracker that jumped to a
	   neighbour shows as a lateral excursion from the yarn's line */
	for (uint32_t i = 0; i < n && rc == LOOM_OK; i++) {
		int warp = i < we->k;
		int a = warp ? 1 : 0, l = 1 - a;
		const loom_scan_curve *cv = &curves[i];
		float spacing = warp ? we->spacing : fe->spacing;
		double sm = 0, sl = 0, smm = 0, sml = 0, slope, icpt, worst = 0, at = 0;
		for (uint32_t k = 0; k < cv->n; k++) {
			double m = cv->pts[3 * k + a], q = cv->pts[3 * k + l];
			sm += m;
			sl += q;
			smm += m * m;
			sml += m * q;
		}
		slope = cv->n * smm - sm * sm;
		slope = slope > 0 ? (cv->n * sml - sm * sl) / slope : 0;
		icpt = (sl - slope * sm) / cv->n;
		for (uint32_t k = 0; k < cv->n; k++) {
			double dev = fabs(cv->pts[3 * k + l] - (icpt + slope * cv->pts[3 * k + a]));
			if (dev > worst) {
				worst = dev;
				at = cv->pts[3 * k + a];
			}
		}
		if (worst > MAX_EXCURSION * spacing) {
			uint32_t j = warp ? i : i - we->k;
			rc = loom__fail(diag, LOOM_EUNSUPPORTED,
			                "scan: tracking: %s %u wanders %.1f voxels off its "
			                "straight line near %c = %.0f (more than %.2f of the "
			                "%.1f-voxel spacing): tracking jumped between yarns; "
			                "too noisy?",
			                warp ? "warp" : "weft", j, worst, a ? 'y' : 'x', at,
			                MAX_EXCURSION, spacing);
		}
	}
	/* two trackers that ended on the same yarn */
	for (uint32_t i = 0; i + 1 < n && rc == LOOM_OK; i++) {
		int warp = i < we->k;
		int a = warp ? 1 : 0, l = 1 - a;
		const loom_scan_curve *c1 = &curves[i], *c2 = &curves[i + 1];
		float spacing = warp ? we->spacing : fe->spacing;
		uint32_t close = 0, total = 0;
		if (i + 1 == we->k)
			continue; /* last warp / first weft */
		for (uint32_t s = 0; s < c1->n; s++) {
			float pa = c1->pts[3 * s + a];
			/* lateral position of c2 at the same main coordinate */
			for (uint32_t u = 0; u + 1 < c2->n; u++) {
				float qa = c2->pts[3 * u + a], qb = c2->pts[3 * (u + 1) + a];
				if ((pa >= qa && pa <= qb) || (pa <= qa && pa >= qb)) {
					float f = qb != qa ? (pa - qa) / (qb - qa) : 0;
					float ql = c2->pts[3 * u + l] + f * (c2->pts[3 * (u + 1) + l] -
					                                     c2->pts[3 * u + l]);
					float qz = c2->pts[3 * u + 2] + f * (c2->pts[3 * (u + 1) + 2] -
					                                     c2->pts[3 * u + 2]);
					float dl = ql - c1->pts[3 * s + l], dz = qz - c1->pts[3 * s + 2];
					total++;
					if (dl * dl + dz * dz < 0.09f * spacing * spacing)
						close++;
					break;
				}
			}
		}
		if (total && 2 * close > total) {
			uint32_t j = warp ? i : i - we->k;
			rc = loom__fail(diag, LOOM_EMISMATCH,
			                "scan: tracking: %s %u and %u end up on the same yarn "
			                "(closer than 0.3 spacing along %u of %u points): "
			                "more yarns requested than the scan has?",
			                warp ? "warps" : "wefts", j, j + 1, close, total);
		}
	}
	free(c.rc);
	free(c.diags);
	if (rc != LOOM_OK)
		for (uint32_t i = 0; i < n; i++)
			loom_scan_curve_release(&curves[i]);
	return rc;
}
