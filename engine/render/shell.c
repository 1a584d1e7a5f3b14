/*
 * engine/render/shell.c - shell mapping (Porumbescu et al. 2005, as Zhao et al.
 * 2011 and the paper's figure 13 use it): the flat cloth volume mapped into
 * a thin shell over a triangle mesh with UVs.
 *
 * Geometry.  Triangle k has corners P_i, unit vertex normals N_i and UVs
 * uv_i (i = 0, 1, 2).  Its prism is
 *
 *     X(b, h) = sum_i b_i (P_i + h N_i),   b_i >= 0, sum b_i = 1,
 *               h in [offset, offset + thickness]
 *
 *            P0+hiN0 ________ P1+hiN1        outer surface  (h = hi)
 *                   /       /|
 *                  /_______/ |               slices of constant h are
 *                  |       | |               flat triangles; side walls
 *                  |  ...  | /               are bilinear patches
 *            P0+loN0 ______|/ P1+loN1        inner surface  (h = lo)
 *
 * and  voxel = ((u - u0) su, (v - v0) sv, (h - offset) / thickness * nz)
 * with (u, v) = sum_i b_i uv_i, su = voxels_per_uv and sv = voxels_per_uv_v
 * (or su when 0): separate scales keep crossings of any aspect at their
 * physical size (loom_uv_mm_scale).  Neighbouring prisms
 * share their side walls (same corners, same normals), so the map is
 * continuous across triangles; inside a prism it is linear in b and in h
 * separately (bilinear overall): the "per-prism linear interpolation" of
 * shell maps.  Porumbescu et al. split each prism into three tetrahedra to
 * make the map piecewise linear; we invert X exactly instead (Newton),
 * which is smoother and just as cheap for one point.
 *
 * Memory: per usable triangle 9 + 9 + 6 + 4 doubles, plus three Embree
 * scenes, all built once in loom_shell_new and only read afterwards.
 *
 *   base   the mesh triangles; rtcPointQuery with a finite radius
 *          (max |height| over the shell) and our own callback computing
 *          point-triangle distances collects the nearest (or K nearest)
 *          triangles, shrinking query->radius once it holds enough.
 *   bound  outer (h = hi) and inner (h = lo) surfaces and, along border
 *          edges, two triangles per side wall; each with its outward
 *          normal, so a ray hit says whether the ray leaves the shell.
 *   uv     the triangles laid out in UV space (z = 0) for voxel -> world:
 *          a short vertical ray finds the triangle containing (u, v).
 *
 * world -> voxel (map_point):
 *   Step 1. Try the hint prism (the last one found on this ray).
 *   Step 2. Closest-point query for the nearest base triangle (the query
 *           radius shrinks to each better distance); try its prism.
 *   Step 3. Otherwise (curved or concave places, where the containing
 *           prism is not over the closest triangle) a second query keeps
 *           the K nearest; try their prisms, nearest first.
 *   Trying a prism = inverting X: Newton on (b0, b1, h) from the face-
 *   plane projection; accepted when b >= -1e-9 and h in [lo, hi] (same
 *   relative tolerance).  No prism: the point is outside the shell.
 */
#include "render_internal.h"

#include "embree_dl.h"
#include <float.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define SHELL_K 16             /* candidate prisms per closest-point query */
#define SHELL_NEWTON_ITERS 40
#define SHELL_B_TOL 1e-9       /* barycentric tolerance of "inside" */

struct loom_shell {
	loom_shell_params p;
	double vpu[2];            /* voxels per UV unit in u and v */
	double lo, hi;            /* heights of the inner / outer surfaces */
	uint32_t n_tri;           /* usable triangles */
	uint32_t *tri_src;        /* mesh triangle index of each */
	double *P;                /* 9 per triangle: corner positions */
	double *N;                /* 9 per triangle: unit corner normals */
	double *UV;               /* 6 per triangle */
	double *Minv;             /* 4 per triangle: d(b0,b1)/d(u,v), row-major */
	double *fn;               /* 3 per triangle: unit face normal, oriented
	                             along the corner normals */
	float *bound_n;           /* 3 per boundary triangle: outward normal */
	uint32_t n_bound;
	double radius;            /* closest-point query radius */
	double eps;               /* ray restart distance */
	double bmin[3], bmax[3];  /* bounds of the shell */
	RTCDevice dev;
	RTCScene base, bound, uv;
	atomic_int failed;        /* Embree reported an error */
	char embree_msg[160];
};

/* ---- Embree error handling ------------------------------------------- */

static void embree_error(void *user, enum RTCError code, const char *str)
{
	loom_shell *s = user;
	int expected = 0;
	if (atomic_compare_exchange_strong(&s->failed, &expected, (int)code + 1))
		snprintf(s->embree_msg, sizeof s->embree_msg, "Embree error %d: %s",
		         (int)code, str ? str : "");
}

/* ---- small geometry ---------------------------------------------------- */

static void sub3(const double a[3], const double b[3], double o[3])
{
	o[0] = a[0] - b[0];
	o[1] = a[1] - b[1];
	o[2] = a[2] - b[2];
}

static double det3(const double a[3], const double b[3], const double c[3])
{
	double x[3];
	loom__cross3(b, c, x);
	return loom__dot3(a, x);
}

/* Squared distance from p to triangle (a, b, c): the closest point by the
   Voronoi region of the triangle it falls in (vertex, edge or face). */
static double point_tri_dist2(const double p[3], const double a[3],
                              const double b[3], const double c[3])
{
	double ab[3], ac[3], ap[3], bp[3], cp[3], q[3], d[3];
	double d1, d2, d3, d4, d5, d6, va, vb, vc, v, w, den;

	sub3(b, a, ab);
	sub3(c, a, ac);
	sub3(p, a, ap);
	d1 = loom__dot3(ab, ap);
	d2 = loom__dot3(ac, ap);
	if (d1 <= 0 && d2 <= 0)
		return loom__dot3(ap, ap); /* vertex a */
	sub3(p, b, bp);
	d3 = loom__dot3(ab, bp);
	d4 = loom__dot3(ac, bp);
	if (d3 >= 0 && d4 <= d3)
		return loom__dot3(bp, bp); /* vertex b */
	vc = d1 * d4 - d3 * d2;
	if (vc <= 0 && d1 >= 0 && d3 <= 0) { /* edge ab */
		v = d1 / (d1 - d3);
		for (int j = 0; j < 3; j++)
			q[j] = a[j] + v * ab[j];
		goto done;
	}
	sub3(p, c, cp);
	d5 = loom__dot3(ab, cp);
	d6 = loom__dot3(ac, cp);
	if (d6 >= 0 && d5 <= d6)
		return loom__dot3(cp, cp); /* vertex c */
	vb = d5 * d2 - d1 * d6;
	if (vb <= 0 && d2 >= 0 && d6 <= 0) { /* edge ac */
		w = d2 / (d2 - d6);
		for (int j = 0; j < 3; j++)
			q[j] = a[j] + w * ac[j];
		goto done;
	}
	va = d3 * d6 - d5 * d4;
	if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) { /* edge bc */
		w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
		for (int j = 0; j < 3; j++)
			q[j] = b[j] + w * (c[j] - b[j]);
		goto done;
	}
	den = 1.0 / (va + vb + vc); /* face */
	v = vb * den;
	w = vc * den;
	for (int j = 0; j < 3; j++)
		q[j] = a[j] + ab[j] * v + ac[j] * w;
done:
	sub3(p, q, d);
	return loom__dot3(d, d);
}

/* ---- prism map --------------------------------------------------------- */

/* X(b0, b1, h) of triangle k and, if wanted, its partial derivatives. */
static void prism_eval(const loom_shell *s, uint32_t k, double b0, double b1,
                       double h, double X[3], double Xb0[3], double Xb1[3],
                       double Xh[3])
{
	const double *P = s->P + 9 * (size_t)k, *N = s->N + 9 * (size_t)k;
	double b2 = 1.0 - b0 - b1;
	for (int j = 0; j < 3; j++) {
		double q0 = P[j] + h * N[j], q1 = P[3 + j] + h * N[3 + j];
		double q2 = P[6 + j] + h * N[6 + j];
		X[j] = b0 * q0 + b1 * q1 + b2 * q2;
		if (Xb0) {
			Xb0[j] = q0 - q2;
			Xb1[j] = q1 - q2;
			Xh[j] = b0 * N[j] + b1 * N[3 + j] + b2 * N[6 + j];
		}
	}
}

/*
 * Invert X for world point w in prism k.  Returns 1 when Newton converged;
 * b[3], *h receive the solution and *viol how far it is outside the prism
 * (0 inside; in barycentric / relative-height units).
 */
static int prism_invert(const loom_shell *s, uint32_t k, const double w[3],
                        double b[3], double *h, double *viol)
{
	const double *P = s->P + 9 * (size_t)k, *fn = s->fn + 3 * (size_t)k;
	double d[3], b0 = 1.0 / 3, b1 = 1.0 / 3, hh, scale;
	double X[3], Xb0[3], Xb1[3], Xh[3], F[3];
	int it;

	sub3(w, P, d);
	hh = loom__dot3(d, fn);
	scale = s->p.thickness + fabs(hh);
	for (it = 0; it < SHELL_NEWTON_ITERS; it++) {
		double det, db0, db1, dh, step;
		prism_eval(s, k, b0, b1, hh, X, Xb0, Xb1, Xh);
		sub3(X, w, F);
		det = det3(Xb0, Xb1, Xh);
		if (!(fabs(det) > 1e-300))
			return 0;
		/* Cramer: J (db0, db1, dh) = -F */
		db0 = -det3(F, Xb1, Xh) / det;
		db1 = -det3(Xb0, F, Xh) / det;
		dh = -det3(Xb0, Xb1, F) / det;
		b0 += db0;
		b1 += db1;
		hh += dh;
		step = fabs(db0) + fabs(db1) + fabs(dh) / scale;
		if (!isfinite(step) || fabs(b0) > 1e6 || fabs(b1) > 1e6)
			return 0;
		if (step < 1e-13)
			break;
	}
	if (it == SHELL_NEWTON_ITERS)
		return 0;
	b[0] = b0;
	b[1] = b1;
	b[2] = 1.0 - b0 - b1;
	*h = hh;
	{
		double v = 0, th = s->p.thickness;
		for (int j = 0; j < 3; j++)
			if (-b[j] > v)
				v = -b[j];
		if ((s->lo - hh) / th > v)
			v = (s->lo - hh) / th;
		if ((hh - s->hi) / th > v)
			v = (hh - s->hi) / th;
		*viol = v;
	}
	return 1;
}

/* Voxel coordinates of (b, h) in triangle k. */
static void to_voxel(const loom_shell *s, uint32_t k, const double b[3],
                     double h, double v[3])
{
	const double *uv = s->UV + 6 * (size_t)k;
	double u = b[0] * uv[0] + b[1] * uv[2] + b[2] * uv[4];
	double vv = b[0] * uv[1] + b[1] * uv[3] + b[2] * uv[5];
	v[0] = (u - s->p.uv_origin[0]) * s->vpu[0];
	v[1] = (vv - s->p.uv_origin[1]) * s->vpu[1];
	v[2] = (h - s->lo) / s->p.thickness * (double)s->p.nz;
}

/* d(world)/d(voxel), row-major, at (b, h) of triangle k. */
static void jacobian(const loom_shell *s, uint32_t k, const double b[3],
                     double h, double jac[9])
{
	const double *M = s->Minv + 4 * (size_t)k;
	double X[3], Xb0[3], Xb1[3], Xh[3];
	double inv_su = 1.0 / s->vpu[0], inv_sv = 1.0 / s->vpu[1];
	double hz = s->p.thickness / (double)s->p.nz;

	prism_eval(s, k, b[0], b[1], h, X, Xb0, Xb1, Xh);
	for (int j = 0; j < 3; j++) {
		jac[3 * j + 0] = (Xb0[j] * M[0] + Xb1[j] * M[2]) * inv_su;
		jac[3 * j + 1] = (Xb0[j] * M[1] + Xb1[j] * M[3]) * inv_sv;
		jac[3 * j + 2] = Xh[j] * hz;
	}
}

/* ---- closest-point query ----------------------------------------------- */

typedef struct pq_state {
	const loom_shell *s;
	double q[3];
	int kmax;                  /* candidates wanted (1 or SHELL_K) */
	int n;                     /* candidates held */
	uint32_t id[SHELL_K];      /* sorted by distance */
	double d2[SHELL_K];
} pq_state;

static bool pq_callback(struct RTCPointQueryFunctionArguments *args)
{
	pq_state *st = args->userPtr;
	const loom_shell *s = st->s;
	uint32_t k = args->primID;
	const double *P = s->P + 9 * (size_t)k;
	double d2 = point_tri_dist2(st->q, P, P + 3, P + 6);
	double r = args->query->radius;
	int pos;

	if (d2 > r * r)
		return false;
	if (st->n == st->kmax && d2 >= st->d2[st->kmax - 1])
		return false;
	pos = st->n < st->kmax ? st->n++ : st->kmax - 1;
	while (pos > 0 && st->d2[pos - 1] > d2) {
		st->d2[pos] = st->d2[pos - 1];
		st->id[pos] = st->id[pos - 1];
		pos--;
	}
	st->d2[pos] = d2;
	st->id[pos] = k;
	if (st->n == st->kmax) {
		/* Shrink to the K-th distance (a hair more: Embree culls in
		   float). */
		float nr = (float)(sqrt(st->d2[st->kmax - 1]) * (1.0 + 1e-6) + s->eps);
		if (nr < args->query->radius) {
			args->query->radius = nr;
			return true;
		}
	}
	return false;
}

/* Collect the kmax nearest base triangles to w into st. */
static void nearest_triangles(const loom_shell *s, const double w[3], int kmax,
                              pq_state *st, uint64_t *n_queries)
{
	RTC_ALIGN(16) struct RTCPointQuery q;
	struct RTCPointQueryContext ctx;

	st->s = s;
	st->q[0] = w[0];
	st->q[1] = w[1];
	st->q[2] = w[2];
	st->kmax = kmax;
	st->n = 0;
	q.x = (float)w[0];
	q.y = (float)w[1];
	q.z = (float)w[2];
	q.time = 0.0f;
	q.radius = (float)s->radius;
	rtcInitPointQueryContext(&ctx);
	rtcPointQuery(s->base, &q, &ctx, pq_callback, st);
	if (n_queries)
		(*n_queries)++;
}

/* Try prism k; on success fill v (and jac) and return 1. */
static int try_prism(const loom_shell *s, uint32_t k, const double w[3],
                     double v[3], double jac[9])
{
	double b[3], h, viol;

	if (!prism_invert(s, k, w, b, &h, &viol) || viol > SHELL_B_TOL)
		return 0;
	to_voxel(s, k, b, h, v);
	if (jac)
		jacobian(s, k, b, h, jac);
	return 1;
}

int loom__shell_map(const loom_shell *s, const double w[3], uint32_t *hint,
                    double v[3], double jac[9], uint64_t *n_queries)
{
	pq_state st;
	uint32_t tried = LOOM_MESH_NONE;

	/* Step 1: the hint prism. */
	if (hint && *hint < s->n_tri && try_prism(s, *hint, w, v, jac))
		return 1;
	/* Step 2a: the closest base triangle (the radius shrinks to it). */
	nearest_triangles(s, w, 1, &st, n_queries);
	if (st.n == 0)
		return 0;
	if (try_prism(s, st.id[0], w, v, jac)) {
		if (hint)
			*hint = st.id[0];
		return 1;
	}
	/* Step 2b and 3: the K nearest, nearest first (curved or concave
	   places where the containing prism is not over the closest
	   triangle). */
	tried = st.id[0];
	nearest_triangles(s, w, SHELL_K, &st, n_queries);
	for (int i = 0; i < st.n; i++) {
		uint32_t k = st.id[i];
		if (k != tried && try_prism(s, k, w, v, jac)) {
			if (hint)
				*hint = k;
			return 1;
		}
	}
	return 0;
}

LOOM_API int loom_shell_world_to_voxel(const loom_shell *s, const double w[3],
                                       double v[3], uint32_t *tri)
{
	uint32_t hint = LOOM_MESH_NONE;
	double vv[3];

	if (!s || !w || !v)
		return LOOM_EINVAL;
	if (atomic_load(&s->failed))
		return LOOM_EUNUSABLE;
	if (!loom__shell_map(s, w, &hint, vv, NULL, NULL))
		return atomic_load(&s->failed) ? LOOM_EUNUSABLE : LOOM_ENOTFOUND;
	memcpy(v, vv, sizeof vv);
	if (tri)
		*tri = s->tri_src[hint];
	return LOOM_OK;
}

LOOM_API int loom_shell_voxel_to_world(const loom_shell *s, const double v[3],
                                       double w[3], uint32_t *tri)
{
	struct RTCIntersectContext ictx;
	RTC_ALIGN(16) struct RTCRayHit rh;
	double u, vv, b[3], h, X[3];
	const double *uv, *M;
	uint32_t k;

	if (!s || !v || !w)
		return LOOM_EINVAL;
	if (atomic_load(&s->failed))
		return LOOM_EUNUSABLE;
	u = v[0] / s->vpu[0] + s->p.uv_origin[0];
	vv = v[1] / s->vpu[1] + s->p.uv_origin[1];
	memset(&rh, 0, sizeof rh);
	rh.ray.org_x = (float)u;
	rh.ray.org_y = (float)vv;
	rh.ray.org_z = 1.0f;
	rh.ray.dir_x = 0.0f;
	rh.ray.dir_y = 0.0f;
	rh.ray.dir_z = -1.0f;
	rh.ray.tnear = 0.0f;
	rh.ray.tfar = 2.0f;
	rh.ray.time = 0.0f;
	rh.ray.mask = 0xFFFFFFFFu;
	rh.ray.flags = 0;
	rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
	rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
	rtcInitIntersectContext(&ictx);
	rtcIntersect1(s->uv, &ictx, &rh);
	if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
		return atomic_load(&s->failed) ? LOOM_EUNUSABLE : LOOM_ENOTFOUND;
	k = rh.hit.primID;
	uv = s->UV + 6 * (size_t)k;
	M = s->Minv + 4 * (size_t)k;
	b[0] = M[0] * (u - uv[4]) + M[1] * (vv - uv[5]);
	b[1] = M[2] * (u - uv[4]) + M[3] * (vv - uv[5]);
	b[2] = 1.0 - b[0] - b[1];
	h = s->lo + v[2] / (double)s->p.nz * s->p.thickness;
	prism_eval(s, k, b[0], b[1], h, X, NULL, NULL, NULL);
	memcpy(w, X, sizeof X);
	if (tri)
		*tri = s->tri_src[k];
	return LOOM_OK;
}

int loom__shell_hit(const loom_shell *s, const double o[3], const double d[3],
                    double tnear, double tfar, double *t, int *exiting)
{
	struct RTCIntersectContext ictx;
	RTC_ALIGN(16) struct RTCRayHit rh;
	const float *n;

	rh.ray.org_x = (float)o[0];
	rh.ray.org_y = (float)o[1];
	rh.ray.org_z = (float)o[2];
	rh.ray.dir_x = (float)d[0];
	rh.ray.dir_y = (float)d[1];
	rh.ray.dir_z = (float)d[2];
	rh.ray.tnear = (float)tnear;
	rh.ray.tfar = tfar < FLT_MAX ? (float)tfar : INFINITY;
	rh.ray.time = 0.0f;
	rh.ray.mask = 0xFFFFFFFFu;
	rh.ray.flags = 0;
	rh.ray.id = 0;
	rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
	rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
	rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
	rtcInitIntersectContext(&ictx);
	rtcIntersect1(s->bound, &ictx, &rh);
	if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
		return 0;
	n = s->bound_n + 3 * (size_t)rh.hit.primID;
	*t = rh.ray.tfar;
	*exiting = d[0] * n[0] + d[1] * n[1] + d[2] * n[2] > 0;
	return 1;
}

int loom__shell_segment(const loom_shell *s, const double o[3], const double d[3],
                        double tmax, double *cur, double *a, double *b)
{
	double start = *cur, last_exit = -1, th;
	int depth = 0, exiting;

	for (;;) {
		if (!(*cur < tmax))
			break;
		if (!loom__shell_hit(s, o, d, *cur > 0 ? *cur + s->eps : 0.0, INFINITY, &th,
		                     &exiting)) {
			*cur = tmax;
			break;
		}
		if (!exiting) {
			if (depth++ == 0) {
				start = th;
				last_exit = -1;
			}
			*cur = th;
			continue;
		}
		/* an exit with nothing counted: the ray started inside */
		if (depth > 0)
			depth--;
		*cur = th;
		last_exit = th;
		if (depth == 0) {
			*a = start;
			*b = th < tmax ? th : tmax;
			if (*a < *b)
				return 1;
			start = th;
			last_exit = -1;
		}
	}
	/* Crossings ran out with entries still counted: where the shell folds
	   over itself (a corner's offset surfaces turn inside out) some walls
	   face the wrong way, so entries outnumber exits.  The stretch ends at
	   its last exit. */
	if (depth > 0 && last_exit > start) {
		*a = start;
		*b = last_exit < tmax ? last_exit : tmax;
		if (*a < *b)
			return 1;
	}
	return 0;
}

double loom__shell_eps(const loom_shell *s)
{
	return s->eps;
}

int64_t loom__shell_nz(const loom_shell *s)
{
	return s->p.nz;
}

int loom__shell_failed(const loom_shell *s)
{
	return atomic_load(&s->failed) != 0;
}

LOOM_API int loom_uv_mm_scale(const double uv_mm[2], const uint32_t block[2],
                              double voxel_mm, const float sett[2],
                              double voxels_per_uv[2], double pitch_mm[2])
{
	double pitch[2];

	if (!uv_mm || !block || !sett || !voxels_per_uv)
		return LOOM_EINVAL;
	if (!(uv_mm[0] > 0) || !(uv_mm[1] > 0) || !isfinite(uv_mm[0]) ||
	    !isfinite(uv_mm[1]) || !block[0] || !block[1] || !(voxel_mm > 0) ||
	    !isfinite(voxel_mm) || !(sett[0] >= 0) || !(sett[1] >= 0) ||
	    !isfinite(sett[0]) || !isfinite(sett[1]))
		return LOOM_EINVAL;
	/* an unstated sett: square crossings of the exemplar crossing's area;
	   one side stated: square crossings of that pitch */
	pitch[0] = pitch[1] = sqrt((double)block[0] * (double)block[1]) * voxel_mm;
	for (int j = 0; j < 2; j++) {
		float st = sett[j] > 0 ? sett[j] : sett[1 - j];
		if (st > 0)
			pitch[j] = 10.0 / (double)st;
		voxels_per_uv[j] = uv_mm[j] * (double)block[j] / pitch[j];
		if (pitch_mm)
			pitch_mm[j] = pitch[j];
	}
	return LOOM_OK;
}

LOOM_API void loom_shell_bounds(const loom_shell *s, double lo[3], double hi[3])
{
	if (!s)
		return;
	memcpy(lo, s->bmin, sizeof s->bmin);
	memcpy(hi, s->bmax, sizeof s->bmax);
}

LOOM_API double loom_shell_voxel_length(const loom_shell *s)
{
	return s ? s->p.thickness / (double)s->p.nz : 0.0;
}

LOOM_API uint32_t loom_shell_triangle_count(const loom_shell *s)
{
	return s ? s->n_tri : 0;
}

/* ---- construction ------------------------------------------------------ */

LOOM_API void loom_shell_free(loom_shell *s)
{
	if (!s)
		return;
	if (s->base)
		rtcReleaseScene(s->base);
	if (s->bound)
		rtcReleaseScene(s->bound);
	if (s->uv)
		rtcReleaseScene(s->uv);
	if (s->dev)
		rtcReleaseDevice(s->dev);
	free(s->tri_src);
	free(s->P);
	free(s->N);
	free(s->UV);
	free(s->Minv);
	free(s->fn);
	free(s->bound_n);
	free(s);
}

/* Area-weighted vertex normals per position (3 * n_positions doubles). */
static double *vertex_normals(const loom_mesh *m)
{
	double *vn = calloc((size_t)m->n_positions * 3 + 1, sizeof *vn);
	if (!vn)
		return NULL;
	for (uint32_t t = 0; t < m->n_triangles; t++) {
		double p[3][3], e1[3], e2[3], n[3];
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				p[i][j] = m->positions[3 * (size_t)m->tri_v[3 * (size_t)t + i] + j];
		sub3(p[1], p[0], e1);
		sub3(p[2], p[0], e2);
		loom__cross3(e1, e2, n); /* length = 2 area */
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				vn[3 * (size_t)m->tri_v[3 * (size_t)t + i] + j] += n[j];
	}
	for (uint32_t v = 0; v < m->n_positions; v++)
		loom__normalize3(vn + 3 * (size_t)v);
	return vn;
}

/* Fill triangle arrays; returns LOOM_OK and sets s->n_tri. */
static int collect_triangles(loom_shell *s, const loom_mesh *m, int file_normals,
                             const double *vnorm, uint32_t *skipped)
{
	size_t nt = m->n_triangles;
	uint32_t n = 0;

	s->tri_src = malloc((nt ? nt : 1) * sizeof *s->tri_src);
	s->P = malloc((nt ? nt : 1) * 9 * sizeof *s->P);
	s->N = malloc((nt ? nt : 1) * 9 * sizeof *s->N);
	s->UV = malloc((nt ? nt : 1) * 6 * sizeof *s->UV);
	s->Minv = malloc((nt ? nt : 1) * 4 * sizeof *s->Minv);
	s->fn = malloc((nt ? nt : 1) * 3 * sizeof *s->fn);
	if (!s->tri_src || !s->P || !s->N || !s->UV || !s->Minv || !s->fn)
		return LOOM_ENOMEM;
	*skipped = 0;
	for (uint32_t t = 0; t < m->n_triangles; t++) {
		double *P = s->P + 9 * (size_t)n, *N = s->N + 9 * (size_t)n;
		double *UV = s->UV + 6 * (size_t)n, *M = s->Minv + 4 * (size_t)n;
		double *fn = s->fn + 3 * (size_t)n;
		double e1[3], e2[3], area2, a, b, c, d, det, navg[3] = {0, 0, 0};
		int ok = 1;

		for (int i = 0; i < 3; i++) {
			size_t c3 = 3 * (size_t)t + i;
			uint32_t vi = m->tri_v[c3], ti = m->tri_vt[c3];
			if (ti == LOOM_MESH_NONE) {
				ok = 0;
				break;
			}
			for (int j = 0; j < 3; j++)
				P[3 * i + j] = m->positions[3 * (size_t)vi + j];
			UV[2 * i] = m->texcoords[2 * (size_t)ti];
			UV[2 * i + 1] = m->texcoords[2 * (size_t)ti + 1];
			if (file_normals) {
				uint32_t ni = m->tri_vn[c3];
				for (int j = 0; j < 3; j++)
					N[3 * i + j] = m->normals[3 * (size_t)ni + j];
			} else {
				for (int j = 0; j < 3; j++)
					N[3 * i + j] = vnorm[3 * (size_t)vi + j];
			}
			if (loom__normalize3(N + 3 * i) < 1e-20)
				ok = 0;
			for (int j = 0; j < 3; j++)
				navg[j] += N[3 * i + j];
		}
		if (!ok) {
			(*skipped)++;
			continue;
		}
		sub3(P + 3, P, e1);
		sub3(P + 6, P, e2);
		loom__cross3(e1, e2, fn);
		area2 = loom__normalize3(fn);
		if (!(area2 > 1e-300) ||
		    area2 < 1e-12 * (loom__dot3(e1, e1) + loom__dot3(e2, e2))) {
			(*skipped)++;
			continue;
		}
		if (loom__dot3(fn, navg) < 0)
			for (int j = 0; j < 3; j++)
				fn[j] = -fn[j];
		/* (u, v) - uv2 = [[u0-u2, u1-u2], [v0-v2, v1-v2]] (b0, b1) */
		a = UV[0] - UV[4];
		b = UV[2] - UV[4];
		c = UV[1] - UV[5];
		d = UV[3] - UV[5];
		det = a * d - b * c;
		if (!(fabs(det) > 1e-14 * (a * a + b * b + c * c + d * d)) ||
		    !isfinite(det)) {
			(*skipped)++;
			continue;
		}
		M[0] = d / det;
		M[1] = -b / det;
		M[2] = -c / det;
		M[3] = a / det;
		s->tri_src[n++] = t;
	}
	s->n_tri = n;
	return LOOM_OK;
}

/* New triangle geometry of n triangles with unshared vertices; returns the
   vertex array (3 floats per vertex, 3 vertices per triangle). */
static float *new_tri_geometry(RTCDevice dev, RTCScene scene, uint32_t n)
{
	RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
	float *vb;
	unsigned *ib;

	if (!g)
		return NULL;
	vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
	                             3 * sizeof(float), (size_t)n * 3);
	ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
	                             3 * sizeof(unsigned), n);
	if (!vb || !ib) {
		rtcReleaseGeometry(g);
		return NULL;
	}
	for (size_t i = 0; i < (size_t)n * 3; i++)
		ib[i] = (unsigned)i;
	rtcCommitGeometry(g);
	rtcAttachGeometry(scene, g);
	rtcReleaseGeometry(g);
	return vb;
}

static void put3(float *dst, const double *src, double h, const double *nrm)
{
	for (int j = 0; j < 3; j++)
		dst[j] = (float)(src[j] + h * (nrm ? nrm[j] : 0.0));
}

/* An edge of a usable triangle, for finding border edges. */
typedef struct edge_rec {
	uint64_t key;   /* (min position index << 32) | max */
	uint32_t tri;   /* usable triangle */
	uint8_t e;      /* edge e goes from corner e to corner (e+1)%3 */
} edge_rec;

static int edge_cmp(const void *a, const void *b)
{
	const edge_rec *x = a, *y = b;
	if (x->key != y->key)
		return x->key < y->key ? -1 : 1;
	return x->tri < y->tri ? -1 : x->tri > y->tri;
}

/* Border edges (used by exactly one usable triangle); *out malloc'ed. */
static int border_edges(const loom_shell *s, const loom_mesh *m,
                        edge_rec **out, uint32_t *n_out)
{
	size_t ne = 3 * (size_t)s->n_tri, nb = 0;
	edge_rec *e = malloc((ne ? ne : 1) * sizeof *e);

	if (!e)
		return LOOM_ENOMEM;
	for (uint32_t k = 0; k < s->n_tri; k++) {
		const uint32_t *tv = m->tri_v + 3 * (size_t)s->tri_src[k];
		for (int i = 0; i < 3; i++) {
			uint64_t a = tv[i], b = tv[(i + 1) % 3];
			edge_rec *r = &e[3 * (size_t)k + i];
			r->key = a < b ? (a << 32) | b : (b << 32) | a;
			r->tri = k;
			r->e = (uint8_t)i;
		}
	}
	qsort(e, ne, sizeof *e, edge_cmp);
	for (size_t i = 0; i < ne;) {
		size_t j = i + 1;
		while (j < ne && e[j].key == e[i].key)
			j++;
		if (j - i == 1)
			e[nb++] = e[i];
		i = j;
	}
	*out = e;
	*n_out = (uint32_t)nb;
	return LOOM_OK;
}

static int build_scenes(loom_shell *s, const edge_rec *border, uint32_t n_border)
{
	uint32_t nt = s->n_tri;
	size_t nbound = 2 * (size_t)nt + 2 * (size_t)n_border;
	float *vb;

	s->base = rtcNewScene(s->dev);
	s->bound = rtcNewScene(s->dev);
	s->uv = rtcNewScene(s->dev);
	if (!s->base || !s->bound || !s->uv)
		return LOOM_EIO;
	rtcSetSceneFlags(s->bound, RTC_SCENE_FLAG_ROBUST);
	rtcSetSceneFlags(s->uv, RTC_SCENE_FLAG_ROBUST);
	for (int j = 0; j < 3; j++) {
		s->bmin[j] = INFINITY;
		s->bmax[j] = -INFINITY;
	}

	/* base: the mesh itself */
	if (!(vb = new_tri_geometry(s->dev, s->base, nt)))
		return LOOM_EIO;
	for (size_t k = 0; k < nt; k++)
		for (int i = 0; i < 3; i++)
			put3(vb + 9 * k + 3 * i, s->P + 9 * k + 3 * i, 0.0, NULL);

	/* uv: triangles in the plane z = 0 */
	if (!(vb = new_tri_geometry(s->dev, s->uv, nt)))
		return LOOM_EIO;
	for (size_t k = 0; k < nt; k++)
		for (int i = 0; i < 3; i++) {
			vb[9 * k + 3 * i] = (float)s->UV[6 * k + 2 * i];
			vb[9 * k + 3 * i + 1] = (float)s->UV[6 * k + 2 * i + 1];
			vb[9 * k + 3 * i + 2] = 0.0f;
		}

	/* bound: outer, inner, then two triangles per border wall */
	s->n_bound = (uint32_t)nbound;
	s->bound_n = malloc(nbound * 3 * sizeof *s->bound_n + 1);
	if (!s->bound_n || !(vb = new_tri_geometry(s->dev, s->bound, (uint32_t)nbound)))
		return s->bound_n ? LOOM_EIO : LOOM_ENOMEM;
	for (size_t k = 0; k < nt; k++) {
		const double *P = s->P + 9 * k, *N = s->N + 9 * k, *fn = s->fn + 3 * k;
		for (int i = 0; i < 3; i++) {
			float *o = vb + 9 * k + 3 * i, *in = vb + 9 * (nt + k) + 3 * i;
			put3(o, P + 3 * i, s->hi, N + 3 * i);
			put3(in, P + 3 * i, s->lo, N + 3 * i);
			for (int j = 0; j < 3; j++) {
				double lo = fmin(o[j], in[j]), hi = fmax(o[j], in[j]);
				s->bmin[j] = fmin(s->bmin[j], lo);
				s->bmax[j] = fmax(s->bmax[j], hi);
			}
		}
		for (int j = 0; j < 3; j++) {
			s->bound_n[3 * k + j] = (float)fn[j];
			s->bound_n[3 * (nt + k) + j] = (float)-fn[j];
		}
	}
	for (uint32_t e = 0; e < n_border; e++) {
		size_t k = border[e].tri, w0 = 2 * nt + 2 * (size_t)e;
		int ia = border[e].e, ib = (ia + 1) % 3, ic = (ia + 2) % 3;
		const double *P = s->P + 9 * k, *N = s->N + 9 * k;
		double ain[3], bin[3], aout[3], e1[3], e2[3], n[3], mid[3];
		for (int j = 0; j < 3; j++) {
			ain[j] = P[3 * ia + j] + s->lo * N[3 * ia + j];
			bin[j] = P[3 * ib + j] + s->lo * N[3 * ib + j];
			aout[j] = P[3 * ia + j] + s->hi * N[3 * ia + j];
			mid[j] = 0.5 * (P[3 * ia + j] + P[3 * ib + j]) - P[3 * ic + j];
		}
		sub3(bin, ain, e1);
		sub3(aout, ain, e2);
		loom__cross3(e1, e2, n);
		loom__normalize3(n);
		if (loom__dot3(n, mid) < 0)
			for (int j = 0; j < 3; j++)
				n[j] = -n[j];
		put3(vb + 9 * w0 + 0, P + 3 * ia, s->lo, N + 3 * ia);
		put3(vb + 9 * w0 + 3, P + 3 * ib, s->lo, N + 3 * ib);
		put3(vb + 9 * w0 + 6, P + 3 * ib, s->hi, N + 3 * ib);
		put3(vb + 9 * (w0 + 1) + 0, P + 3 * ia, s->lo, N + 3 * ia);
		put3(vb + 9 * (w0 + 1) + 3, P + 3 * ib, s->hi, N + 3 * ib);
		put3(vb + 9 * (w0 + 1) + 6, P + 3 * ia, s->hi, N + 3 * ia);
		for (int j = 0; j < 3; j++)
			s->bound_n[3 * w0 + j] = s->bound_n[3 * (w0 + 1) + j] = (float)n[j];
	}
	rtcCommitScene(s->base);
	rtcCommitScene(s->uv);
	rtcCommitScene(s->bound);
	return atomic_load(&s->failed) ? LOOM_EIO : LOOM_OK;
}

LOOM_API int loom_shell_new(const loom_mesh *m, const loom_shell_params *p,
                            loom_shell **out, loom_diag *diag)
{
	loom_shell *s;
	double *vnorm = NULL, diag_len;
	edge_rec *border = NULL;
	uint32_t n_border = 0, skipped = 0;
	int file_normals, rc;

	if (out)
		*out = NULL;
	if (!m || !p || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_shell_new: NULL argument");
	if (p->size < sizeof(loom_shell_params))
		return loom__fail(diag, LOOM_EINVAL,
		                  "loom_shell_new: params.size %zu, expected %zu "
		                  "(use LOOM_SHELL_PARAMS_INIT)",
		                  p->size, sizeof(loom_shell_params));
	if (!(p->thickness > 0) || !isfinite(p->thickness) || !isfinite(p->offset) ||
	    !(p->voxels_per_uv > 0) || !isfinite(p->voxels_per_uv) ||
	    !(p->voxels_per_uv_v >= 0) || !isfinite(p->voxels_per_uv_v) ||
	    !isfinite(p->uv_origin[0]) || !isfinite(p->uv_origin[1]) || p->nz <= 0)
		return loom__fail(diag, LOOM_EINVAL,
		                  "shell: thickness (%g) and voxels_per_uv (%g) must be "
		                  "finite and > 0, voxels_per_uv_v (%g) finite and >= 0, "
		                  "nz (%lld) > 0, offset finite",
		                  p->thickness, p->voxels_per_uv, p->voxels_per_uv_v,
		                  (long long)p->nz);
	if (!m->tri_vt || !m->n_texcoords)
		return loom__fail(diag, LOOM_EINVAL,
		                  "shell: the mesh has no texture coordinates (faces "
		                  "need v/vt or v/vt/vn corners)");
	if (m->n_triangles == 0)
		return loom__fail(diag, LOOM_EINVAL, "shell: the mesh has no triangles");

	s = calloc(1, sizeof *s);
	if (!s)
		return loom__fail(diag, LOOM_ENOMEM, "shell: out of memory");
	s->p = *p;
	s->p.size = sizeof s->p;
	s->vpu[0] = p->voxels_per_uv;
	s->vpu[1] = p->voxels_per_uv_v > 0 ? p->voxels_per_uv_v : p->voxels_per_uv;
	s->lo = p->offset;
	s->hi = p->offset + p->thickness;
	atomic_init(&s->failed, 0);

	file_normals = !(p->flags & LOOM_SHELL_COMPUTE_NORMALS) && m->tri_vn != NULL;
	if (file_normals)
		for (size_t c = 0; c < 3 * (size_t)m->n_triangles; c++)
			if (m->tri_vn[c] == LOOM_MESH_NONE) {
				file_normals = 0;
				break;
			}
	if (!file_normals && !(vnorm = vertex_normals(m))) {
		rc = loom__fail(diag, LOOM_ENOMEM, "shell: out of memory");
		goto fail;
	}
	if ((rc = collect_triangles(s, m, file_normals, vnorm, &skipped))) {
		loom__fail(diag, rc, "shell: out of memory");
		goto fail;
	}
	if (s->n_tri == 0) {
		rc = loom__fail(diag, LOOM_EINVAL,
		                "shell: no usable triangle (all %u are degenerate in "
		                "space or UV, or lack texture coordinates or normals)",
		                m->n_triangles);
		goto fail;
	}
	if (skipped)
		loom__warn(diag, "shell: %u of %u triangles skipped (degenerate in "
		           "space or UV, or missing texture coordinates)",
		           skipped, m->n_triangles);
	if ((rc = border_edges(s, m, &border, &n_border))) {
		loom__fail(diag, rc, "shell: out of memory");
		goto fail;
	}

	if ((rc = loom__embree_load(diag)))
		goto fail;
	s->dev = rtcNewDevice("threads=1");
	if (!s->dev) {
		rc = loom__fail(diag, LOOM_EIO, "shell: cannot create an Embree device "
		                "(error %d)", (int)rtcGetDeviceError(NULL));
		goto fail;
	}
	rtcSetDeviceErrorFunction(s->dev, embree_error, s);
	if ((rc = build_scenes(s, border, n_border))) {
		loom__fail(diag, rc, "shell: building Embree scenes failed: %s",
		           s->embree_msg[0] ? s->embree_msg : loom_strerror(rc));
		goto fail;
	}
	diag_len = 0;
	for (int j = 0; j < 3; j++)
		diag_len += (s->bmax[j] - s->bmin[j]) * (s->bmax[j] - s->bmin[j]);
	diag_len = sqrt(diag_len);
	s->eps = 1e-6 * diag_len + 1e-30;
	s->radius = fmax(fabs(s->lo), fabs(s->hi)) * (1.0 + 1e-6) + 4 * s->eps;
	free(vnorm);
	free(border);
	*out = s;
	return LOOM_OK;
fail:
	free(vnorm);
	free(border);
	loom_shell_free(s);
	return rc;
}
