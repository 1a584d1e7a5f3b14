/*
 * engine/render/surface_field.c - cloth on a mesh without texture
 * coordinates: a smooth warp-direction field over the surface and one
 * rigid, field-aligned planar map per triangle whose offsets continue the
 * neighbours' (after Magda and Kriegman 2003, "Fast texture synthesis on
 * arbitrary meshes"; no global parameterisation).
 *
 * Field.  Each triangle f gets a unit tangent w_f (the warp direction):
 * the user's direction d projected onto the triangle's plane, with
 * confidence c_f = |d - (d.n_f) n_f| / |d| (0 where d is normal to the
 * surface, e.g. the poles of a sphere seen along its axis).  Jacobi
 * smoothing, `smooth_iters` rounds, each
 *
 *     w_f <- normalise( 2 c_f t_f + sum over edge neighbours g of
 *                       proj_f(w_g) )
 *
 * (proj_f: onto f's plane), so low-confidence triangles take their
 * direction from their neighbours and the field turns smoothly.
 *
 * Principal curvature (source LOOM_FIELD_CURVATURE_MAX or _MIN).  Each
 * triangle's second fundamental form II (2 x 2, symmetric) is fitted by
 * least squares to the change of the vertex normals along its three
 * edges, II e = dn (Rusinkiewicz 2004, "Estimating curvatures and their
 * derivatives on triangle meshes"; vertex normals: angle-weighted face
 * normals).  Its eigenvectors are the principal directions; t_f is the
 * one of larger |kappa| (MAX: the direction of strongest bending, round
 * a cylinder or a torus's tube) or the other one (MIN: along a cylinder's
 * axis, round a torus's hole), with confidence the anisotropy
 * c_f = |k1 - k2| / (|k1| + |k2|).  A principal direction is a line, not
 * a vector: the smoothing turns each neighbour's and the data term's sign
 * to agree with w_f before adding (the 2-fold symmetry of a line field),
 * and after smoothing the signs are made consistent breadth-first (a
 * triangle's map and its neighbour's must not be half a turn apart).
 * Near umbilics (c_f < 0.1: a sphere, a flat region) the triangle takes
 * the user's direction instead, at confidence 0.1 times its projection's,
 * so a sphere gets the direction field and umbilic points of a curved
 * surface take their neighbours' direction.
 *
 * Local maps.  Triangle f is laid flat rigidly in the frame
 *     e_v = w_f (warps run along voxel y),  e_u = e_v x n_f,
 * so each triangle keeps its exact shape: crossing-size distortion is 1
 * on the mesh (the shell adds (1 + h kappa) at height h, as with UVs).
 * What remains to choose is the translation t_f of each map.  Triangles
 * are visited breadth-first from a seed per connected component; each
 * visited triangle's already-placed edge neighbours each propose the t_f
 * that makes their shared edge's endpoints land where the neighbour put
 * them.  With a period (the design repeat in UV) the proposals are first
 * moved by whole periods next to the BFS parent's (the "best matching
 * continuation" of the weave: a shift by one repeat continues the same
 * pattern), then the proposals within a quarter period of the parent's
 * are averaged, edge-length weighted; proposals further away (two fronts
 * meeting after going round a handle) are ignored, leaving a seam there
 * rather than smearing it over both edges.  That placement keeps, per
 * edge, the whole number of periods of its continuation; a least-squares
 * relaxation (relax_translations) then moves the translations so the
 * remaining mismatch, the curl of the frame field (a field whose
 * cross-curves are not geodesics cannot be unrolled without seams or
 * stretch), is spread thinly over all edges instead of piling up where
 * the breadth-first fronts meet.  Measured figures: docs/rendering.md.
 *
 * Output: a copy of the mesh with 3 texture coordinates per triangle
 * (unshared), which the ordinary shell maps.  Memory: O(triangles), once.
 */
#include "render_internal.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

#define FIELD_NONE UINT32_MAX

typedef struct edge_key {
	uint64_t key;  /* (min position << 32) | max */
	uint32_t tri;
	uint8_t e;     /* edge e: corner e -> corner (e + 1) % 3 */
} edge_key;

static int edge_key_cmp(const void *a, const void *b)
{
	const edge_key *x = a, *y = b;
	if (x->key != y->key)
		return x->key < y->key ? -1 : 1;
	if (x->tri != y->tri)
		return x->tri < y->tri ? -1 : 1;
	return (int)x->e - (int)y->e;
}

/* nbr[3 t + e]: the triangle across edge e of t when exactly two triangles
   share the edge, else FIELD_NONE.  */
static int edge_neighbours(const loom_mesh *m, uint32_t *nbr)
{
	size_t ne = 3 * (size_t)m->n_triangles;
	edge_key *k = malloc((ne ? ne : 1) * sizeof *k);

	if (!k)
		return LOOM_ENOMEM;
	for (uint32_t t = 0; t < m->n_triangles; t++)
		for (int e = 0; e < 3; e++) {
			uint64_t a = m->tri_v[3 * (size_t)t + e];
			uint64_t b = m->tri_v[3 * (size_t)t + (e + 1) % 3];
			edge_key *r = &k[3 * (size_t)t + e];
			r->key = a < b ? (a << 32) | b : (b << 32) | a;
			r->tri = t;
			r->e = (uint8_t)e;
			nbr[3 * (size_t)t + e] = FIELD_NONE;
		}
	qsort(k, ne, sizeof *k, edge_key_cmp);
	for (size_t i = 0; i < ne;) {
		size_t j = i + 1;
		while (j < ne && k[j].key == k[i].key)
			j++;
		if (j - i == 2 && k[i].tri != k[i + 1].tri &&
		    (k[i].key >> 32) != (k[i].key & 0xffffffffu)) {
			nbr[3 * (size_t)k[i].tri + k[i].e] = k[i + 1].tri;
			nbr[3 * (size_t)k[i + 1].tri + k[i + 1].e] = k[i].tri;
		}
		i = j;
	}
	free(k);
	return LOOM_OK;
}

static void corner(const loom_mesh *m, uint32_t t, int i, double p[3])
{
	const float *x = m->positions + 3 * (size_t)m->tri_v[3 * (size_t)t + i];
	p[0] = x[0];
	p[1] = x[1];
	p[2] = x[2];
}

/* Unit normal and twice the area of triangle t (0: degenerate). */
static double face_normal(const loom_mesh *m, uint32_t t, double n[3])
{
	double p0[3], p1[3], p2[3], e1[3], e2[3];
	corner(m, t, 0, p0);
	corner(m, t, 1, p1);
	corner(m, t, 2, p2);
	for (int j = 0; j < 3; j++) {
		e1[j] = p1[j] - p0[j];
		e2[j] = p2[j] - p0[j];
	}
	loom__cross3(e1, e2, n);
	return loom__normalize3(n);
}

/* v minus its component along unit n. */
static void project(const double v[3], const double n[3], double o[3])
{
	double d = loom__dot3(v, n);
	for (int j = 0; j < 3; j++)
		o[j] = v[j] - d * n[j];
}

/* Reduce x to (-p/2, p/2] when p > 0. */
static double wrap(double x, double p)
{
	return p > 0 ? x - p * floor(x / p + 0.5) : x;
}

LOOM_API int loom_mesh_measure_uv(const loom_mesh *m, const double period[2],
                                 double seam_tol, loom_mesh_uv_stats *st)
{
	uint32_t *nbr = NULL;
	double wa = 0, ua = 0, scale, p[2] = {0, 0}, acc = 0, wsum = 0;
	int rc;

	if (!m || !st)
		return LOOM_EINVAL;
	memset(st, 0, sizeof *st);
	st->stretch_max = 1.0;
	if (!m->tri_vt || !m->n_texcoords || !m->n_triangles)
		return LOOM_EINVAL;
	if (period) {
		p[0] = period[0] > 0 && isfinite(period[0]) ? period[0] : 0;
		p[1] = period[1] > 0 && isfinite(period[1]) ? period[1] : 0;
	}
	/* Global scale: sqrt(UV area / world area) over triangles with UVs. */
	for (uint32_t t = 0; t < m->n_triangles; t++) {
		const uint32_t *vt = m->tri_vt + 3 * (size_t)t;
		double n[3], a, u[3][2];
		if (vt[0] == LOOM_MESH_NONE || vt[1] == LOOM_MESH_NONE ||
		    vt[2] == LOOM_MESH_NONE)
			continue;
		a = face_normal(m, t, n);
		for (int i = 0; i < 3; i++) {
			u[i][0] = m->texcoords[2 * (size_t)vt[i]];
			u[i][1] = m->texcoords[2 * (size_t)vt[i] + 1];
		}
		wa += a;
		ua += fabs((u[1][0] - u[0][0]) * (u[2][1] - u[0][1]) -
		           (u[2][0] - u[0][0]) * (u[1][1] - u[0][1]));
	}
	if (!(wa > 0) || !(ua > 0))
		return LOOM_EINVAL;
	scale = sqrt(ua / wa);
	st->uv_per_world = scale;
	/* Stretch: singular values of d(uv)/d(surface) over the scale. */
	for (uint32_t t = 0; t < m->n_triangles; t++) {
		const uint32_t *vt = m->tri_vt + 3 * (size_t)t;
		double n[3], a, p0[3], p1[3], p2[3], e1[3], e2[3], x1, x2, y2;
		double d1[2], d2[2], J[4], A, B, C, D, tr, dt, disc, s1, s2, str;
		if (vt[0] == LOOM_MESH_NONE || vt[1] == LOOM_MESH_NONE ||
		    vt[2] == LOOM_MESH_NONE)
			continue;
		a = face_normal(m, t, n);
		if (!(a > 0))
			continue;
		corner(m, t, 0, p0);
		corner(m, t, 1, p1);
		corner(m, t, 2, p2);
		for (int j = 0; j < 3; j++) {
			e1[j] = p1[j] - p0[j];
			e2[j] = p2[j] - p0[j];
		}
		/* 2-D frame of the triangle: e1 along x */
		x1 = sqrt(loom__dot3(e1, e1));
		x2 = loom__dot3(e2, e1) / x1;
		y2 = a / x1;
		for (int k = 0; k < 2; k++) {
			d1[k] = m->texcoords[2 * (size_t)vt[1] + k] -
			        m->texcoords[2 * (size_t)vt[0] + k];
			d2[k] = m->texcoords[2 * (size_t)vt[2] + k] -
			        m->texcoords[2 * (size_t)vt[0] + k];
		}
		/* J [x1 x2; 0 y2] = [d1 d2] */
		J[0] = d1[0] / x1;
		J[2] = d1[1] / x1;
		J[1] = (d2[0] - J[0] * x2) / y2;
		J[3] = (d2[1] - J[2] * x2) / y2;
		A = J[0] * J[0] + J[2] * J[2];
		B = J[0] * J[1] + J[2] * J[3];
		D = J[1] * J[1] + J[3] * J[3];
		C = B;
		tr = A + D;
		dt = A * D - B * C;
		disc = sqrt(fmax(0.0, 0.25 * tr * tr - dt));
		s1 = sqrt(fmax(0.0, 0.5 * tr + disc)) / scale;
		s2 = sqrt(fmax(0.0, 0.5 * tr - disc)) / scale;
		str = s2 > 0 ? fmax(s1, 1.0 / s2) : INFINITY;
		if (!isfinite(str) || str > 1e9)
			str = 1e9;
		if (str > st->stretch_max)
			st->stretch_max = str;
		acc += str * a;
		wsum += a;
	}
	st->stretch_mean = wsum > 0 ? acc / wsum : 1.0;
	/* Seams: UV mismatch (mod the period) at the ends of shared edges. */
	nbr = malloc((3 * (size_t)m->n_triangles) * sizeof *nbr);
	if (!nbr)
		return LOOM_ENOMEM;
	if ((rc = edge_neighbours(m, nbr))) {
		free(nbr);
		return rc;
	}
	acc = 0;
	for (uint32_t t = 0; t < m->n_triangles; t++)
		for (int e = 0; e < 3; e++) {
			uint32_t g = nbr[3 * (size_t)t + e];
			double mm = 0;
			if (g == FIELD_NONE || g < t)
				continue;
			if (m->tri_vt[3 * (size_t)t] == LOOM_MESH_NONE ||
			    m->tri_vt[3 * (size_t)g] == LOOM_MESH_NONE)
				continue;
			for (int c = 0; c < 2; c++) {
				uint32_t pv = m->tri_v[3 * (size_t)t + (e + c) % 3];
				uint32_t ti = m->tri_vt[3 * (size_t)t + (e + c) % 3], gi = 0;
				double du, dv;
				for (int i = 0; i < 3; i++)
					if (m->tri_v[3 * (size_t)g + i] == pv)
						gi = m->tri_vt[3 * (size_t)g + i];
				if (gi == LOOM_MESH_NONE || ti == LOOM_MESH_NONE)
					continue;
				du = wrap((double)m->texcoords[2 * (size_t)ti] -
				          m->texcoords[2 * (size_t)gi], p[0]);
				dv = wrap((double)m->texcoords[2 * (size_t)ti + 1] -
				          m->texcoords[2 * (size_t)gi + 1], p[1]);
				mm = fmax(mm, sqrt(du * du + dv * dv));
			}
			st->interior_edges++;
			acc += mm;
			if (mm > st->seam_max)
				st->seam_max = mm;
			if (mm > seam_tol)
				st->seam_edges++;
		}
	st->seam_mean = st->interior_edges ? acc / st->interior_edges : 0.0;
	free(nbr);
	return LOOM_OK;
}

/*
 * The data term of the principal-curvature field (3 per triangle, length
 * c_f, see the top of the file): the user's direction's projection times
 * 0.1 near umbilics.  vn: 3 per position, scratch.  LOOM_ENOMEM never:
 * the caller passes the scratch.
 */
#define FIELD_UMBILIC 0.1
static void curvature_data(const loom_mesh *m, const double *fn, const double d[3],
                           int source, double *vn, double *data)
{
	size_t nt = m->n_triangles, np = m->n_positions;
	double dl = sqrt(loom__dot3(d, d));

	/* vertex normals: face normals weighted by the corner's angle (an
	   area weight tilts the normals of an open rim, whose corners are
	   split unevenly between the two sides) */
	memset(vn, 0, 3 * np * sizeof *vn);
	for (size_t t = 0; t < nt; t++) {
		const double *n = fn + 3 * t;
		if (!(loom__dot3(n, n) > 0.5))
			continue;
		for (int i = 0; i < 3; i++) {
			double p0[3], p1[3], p2[3], e1[3], e2[3], l1, l2, ang;
			corner(m, (uint32_t)t, i, p0);
			corner(m, (uint32_t)t, (i + 1) % 3, p1);
			corner(m, (uint32_t)t, (i + 2) % 3, p2);
			for (int j = 0; j < 3; j++) {
				e1[j] = p1[j] - p0[j];
				e2[j] = p2[j] - p0[j];
			}
			l1 = sqrt(loom__dot3(e1, e1));
			l2 = sqrt(loom__dot3(e2, e2));
			if (!(l1 > 0 && l2 > 0))
				continue;
			ang = acos(fmax(-1.0, fmin(1.0, loom__dot3(e1, e2) / (l1 * l2))));
			for (int j = 0; j < 3; j++)
				vn[3 * (size_t)m->tri_v[3 * t + (size_t)i] + j] += ang * n[j];
		}
	}
	for (size_t v = 0; v < np; v++)
		loom__normalize3(vn + 3 * v);
	for (size_t t = 0; t < nt; t++) {
		const double *n = fn + 3 * t;
		double eu[3], ev[3], A[3][3] = {{0}}, b[3] = {0}, x[3], k1, k2, th, c;
		double *out = data + 3 * t;
		memset(out, 0, 3 * sizeof *out);
		if (!(loom__dot3(n, n) > 0.5))
			continue; /* degenerate */
		/* the triangle's frame: eu along its first edge */
		{
			double p0[3], p1[3];
			corner(m, (uint32_t)t, 0, p0);
			corner(m, (uint32_t)t, 1, p1);
			for (int j = 0; j < 3; j++)
				eu[j] = p1[j] - p0[j];
			loom__normalize3(eu);
			loom__cross3(n, eu, ev);
		}
		/* II = [x0 x1; x1 x2]: rows (eu.e, ev.e, 0) x = eu.dn and
		   (0, eu.e, ev.e) x = ev.dn per edge; normal equations */
		for (int i = 0; i < 3; i++) {
			uint32_t a = m->tri_v[3 * t + (size_t)i];
			uint32_t bb = m->tri_v[3 * t + (size_t)(i + 1) % 3];
			double e[3], dn[3], r1[3], r2[3], y1, y2;
			for (int j = 0; j < 3; j++) {
				e[j] = m->positions[3 * (size_t)bb + j] - m->positions[3 * (size_t)a + j];
				dn[j] = vn[3 * (size_t)bb + j] - vn[3 * (size_t)a + j];
			}
			r1[0] = loom__dot3(e, eu);
			r1[1] = loom__dot3(e, ev);
			r1[2] = 0;
			r2[0] = 0;
			r2[1] = r1[0];
			r2[2] = r1[1];
			y1 = loom__dot3(dn, eu);
			y2 = loom__dot3(dn, ev);
			for (int r = 0; r < 3; r++) {
				for (int q = 0; q < 3; q++)
					A[r][q] += r1[r] * r1[q] + r2[r] * r2[q];
				b[r] += r1[r] * y1 + r2[r] * y2;
			}
		}
		/* 3 x 3 solve (Cramer; the system is positive definite for a
		   non-degenerate triangle) */
		{
			double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
			             A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
			             A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
			if (!(fabs(det) > 1e-300))
				continue;
			for (int k = 0; k < 3; k++) {
				double M[3][3];
				memcpy(M, A, sizeof M);
				for (int r = 0; r < 3; r++)
					M[r][k] = b[r];
				x[k] = (M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
				        M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
				        M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0])) / det;
			}
		}
		/* eigen: k1 >= k2 (signed), th the angle of k1's direction */
		{
			double hm = 0.5 * (x[0] + x[2]), hd = 0.5 * (x[0] - x[2]);
			double r = sqrt(hd * hd + x[1] * x[1]);
			k1 = hm + r;
			k2 = hm - r;
			th = 0.5 * atan2(2 * x[1], x[0] - x[2]);
		}
		c = fabs(k1) + fabs(k2) > 0 ? fabs(k1 - k2) / (fabs(k1) + fabs(k2)) : 0;
		if (c >= FIELD_UMBILIC) {
			/* the direction of larger |kappa| for MAX, the other for MIN */
			int along_k1 = (fabs(k1) >= fabs(k2)) == (source == LOOM_FIELD_CURVATURE_MAX);
			double a = along_k1 ? th : th + 0.5 * M_PI;
			for (int j = 0; j < 3; j++)
				out[j] = c * (cos(a) * eu[j] + sin(a) * ev[j]);
		} else {
			project(d, n, out);
			for (int j = 0; j < 3; j++)
				out[j] *= FIELD_UMBILIC / dl;
		}
	}
}

/* Flip q to agree with ref (a line field's 2-fold symmetry). */
static void agree(double q[3], const double ref[3])
{
	if (loom__dot3(q, ref) < 0)
		for (int j = 0; j < 3; j++)
			q[j] = -q[j];
}

/*
 * The smooth warp field: w (3 per triangle, unit or 0 for degenerate)
 * from the data term (3 per triangle, length c_f) in tmp[0 .. 3 nt);
 * line: the data is a line field (signs free; see the top of the file).
 */
static void warp_field(const loom_mesh *m, const uint32_t *nbr, const double *fn,
                       uint32_t iters, int line, double *w, double *tmp)
{
	size_t nt = m->n_triangles;

	memcpy(w, tmp, nt * 3 * sizeof *w);
	/* Triangles whose projection vanishes need neighbours from the start:
	   normalise the data term only for the initial guess. */
	for (uint32_t it = 0; it < iters; it++) {
		double *next = tmp + 3 * nt;
		for (size_t t = 0; t < nt; t++) {
			double acc[3], q[3], ref[3];
			memcpy(ref, w + 3 * t, sizeof ref);
			for (int j = 0; j < 3; j++)
				acc[j] = 2.0 * tmp[3 * t + j];
			if (line && loom__dot3(ref, ref) > 0)
				agree(acc, ref);
			for (int e = 0; e < 3; e++) {
				uint32_t g = nbr[3 * t + e];
				if (g == FIELD_NONE)
					continue;
				project(w + 3 * (size_t)g, fn + 3 * t, q);
				if (line) {
					/* w_f not set yet: the first term is the reference */
					if (!(loom__dot3(ref, ref) > 0))
						memcpy(ref, loom__dot3(acc, acc) > 0 ? acc : q, sizeof ref);
					agree(q, ref);
				}
				for (int j = 0; j < 3; j++)
					acc[j] += q[j];
			}
			memcpy(next + 3 * t, acc, sizeof acc);
		}
		for (size_t t = 0; t < nt; t++) {
			double *x = next + 3 * t;
			if (loom__normalize3(x) > 1e-300)
				memcpy(w + 3 * t, x, 3 * sizeof *x);
		}
	}
	for (size_t t = 0; t < nt; t++) {
		double *x = w + 3 * t;
		project(x, fn + 3 * t, x);
		if (!(loom__normalize3(x) > 1e-12)) {
			/* no information at all (an isolated triangle seen along
			   d): any tangent, the first edge */
			double p0[3], p1[3];
			corner(m, (uint32_t)t, 0, p0);
			corner(m, (uint32_t)t, 1, p1);
			for (int j = 0; j < 3; j++)
				x[j] = p1[j] - p0[j];
			loom__normalize3(x);
		}
	}
}

/* A line field's signs made consistent breadth-first from the lowest
   triangle of each component: a neighbour whose direction points against
   the projection of the visiting triangle's is flipped.  queue: nt
   entries; seen: nt bytes, zero. */
static void orient_field(const loom_mesh *m, const uint32_t *nbr, const double *fn,
                         double *w, uint32_t *queue, uint8_t *seen)
{
	size_t nt = m->n_triangles;

	for (size_t seed = 0; seed < nt; seed++) {
		size_t head = 0, tail = 0;
		if (seen[seed])
			continue;
		seen[seed] = 1;
		queue[tail++] = (uint32_t)seed;
		while (head < tail) {
			uint32_t t = queue[head++];
			for (int e = 0; e < 3; e++) {
				uint32_t g = nbr[3 * (size_t)t + e];
				double q[3];
				if (g == FIELD_NONE || seen[g])
					continue;
				seen[g] = 1;
				project(w + 3 * (size_t)t, fn + 3 * (size_t)g, q);
				if (loom__dot3(q, w + 3 * (size_t)g) < 0)
					for (int j = 0; j < 3; j++)
						w[3 * (size_t)g + j] = -w[3 * (size_t)g + j];
				queue[tail++] = g;
			}
		}
	}
}

/* Local UV of corner i of triangle t (before the translation). */
static void local_uv(const loom_mesh *m, uint32_t t, int i, const double *fn,
                     const double *w, double scale, double uv[2])
{
	const double *n = fn + 3 * (size_t)t, *ev = w + 3 * (size_t)t;
	double eu[3], p[3];
	loom__cross3(ev, n, eu);
	corner(m, t, i, p);
	uv[0] = loom__dot3(p, eu) * scale;
	uv[1] = loom__dot3(p, ev) * scale;
}

/*
 * Least-squares relaxation of the translations tr (2 per triangle) over
 * the interior edges: minimise
 *     sum_e w_e |t_a - t_b - D_ab|^2 + eps sum_f |t_f - t0_f|^2
 * where t_a = t_b + D_ab makes edge e's ends agree (its mean), D_ab moved
 * by the whole periods the breadth-first placement chose (so the integer
 * part of each continuation stays), w_e the edge's UV length.  The curl of
 * the frame field is spread over all edges instead of piling up where
 * breadth-first fronts meet.  Conjugate gradients, column by column;
 * deterministic (sequential sums).
 */
static int relax_translations(const loom_mesh *m, const uint32_t *nbr,
                              const double *fn, const double *w, double scale,
                              const double per[2], double *tr)
{
	size_t nt = m->n_triangles, ne = 0, k = 0;
	uint32_t *ea;
	double *ed, *vec, wsum = 0, eps;

	for (size_t t = 0; t < nt; t++)
		for (int e = 0; e < 3; e++)
			if (nbr[3 * t + e] != FIELD_NONE && nbr[3 * t + e] > t)
				ne++;
	ea = malloc((2 * ne + 1) * sizeof *ea);
	ed = malloc((3 * ne + 1) * sizeof *ed);
	vec = malloc((10 * nt + 1) * sizeof *vec);
	if (!ea || !ed || !vec) {
		free(ea);
		free(ed);
		free(vec);
		return LOOM_ENOMEM;
	}
	for (size_t t = 0; t < nt; t++)
		for (int e = 0; e < 3; e++) {
			uint32_t g = nbr[3 * t + e];
			double D[2] = {0, 0}, len = 0;
			if (g == FIELD_NONE || g <= t)
				continue;
			for (int c = 0; c < 2; c++) {
				int ci = (e + c) % 3, gi = 0;
				uint32_t pv = m->tri_v[3 * t + (size_t)ci];
				double luv[2], guv[2];
				for (int i = 0; i < 3; i++)
					if (m->tri_v[3 * (size_t)g + i] == pv)
						gi = i;
				local_uv(m, (uint32_t)t, ci, fn, w, scale, luv);
				local_uv(m, g, gi, fn, w, scale, guv);
				D[0] += 0.5 * (guv[0] - luv[0]);
				D[1] += 0.5 * (guv[1] - luv[1]);
			}
			{
				double p0[3], p1[3], dd[3];
				corner(m, (uint32_t)t, e, p0);
				corner(m, (uint32_t)t, (e + 1) % 3, p1);
				for (int j = 0; j < 3; j++)
					dd[j] = p1[j] - p0[j];
				len = sqrt(loom__dot3(dd, dd)) * scale;
			}
			/* t_t = t_g + D (+ the periods placement chose) */
			for (int c = 0; c < 2; c++)
				if (per[c] > 0)
					D[c] += per[c] * floor((tr[2 * t + c] - tr[2 * (size_t)g + c] -
					                        D[c]) / per[c] + 0.5);
			ea[2 * k] = (uint32_t)t;
			ea[2 * k + 1] = g;
			ed[3 * k] = D[0];
			ed[3 * k + 1] = D[1];
			ed[3 * k + 2] = len;
			wsum += len;
			k++;
		}
	eps = 1e-6 * (ne ? wsum / (double)ne : 1.0);
	for (int c = 0; c < 2; c++) {
		double *x = vec, *b = vec + nt, *r = vec + 2 * nt, *d = vec + 3 * nt;
		double *q = vec + 4 * nt, rr, rr0, bb = 0;
		for (size_t t = 0; t < nt; t++) {
			x[t] = tr[2 * t + c];
			b[t] = eps * x[t];
		}
		for (size_t i = 0; i < ne; i++) {
			double wd = ed[3 * i + 2] * ed[3 * i + c];
			b[ea[2 * i]] += wd;
			b[ea[2 * i + 1]] -= wd;
		}
		/* r = b - A x */
		for (size_t t = 0; t < nt; t++)
			r[t] = b[t] - eps * x[t];
		for (size_t i = 0; i < ne; i++) {
			uint32_t a = ea[2 * i], g = ea[2 * i + 1];
			double f = ed[3 * i + 2] * (x[a] - x[g]);
			r[a] -= f;
			r[g] += f;
		}
		rr = 0;
		for (size_t t = 0; t < nt; t++) {
			d[t] = r[t];
			rr += r[t] * r[t];
			bb += b[t] * b[t];
		}
		rr0 = rr;
		for (int it = 0; it < 4000 && rr > 1e-24 * (bb + rr0); it++) {
			double dq = 0, alpha, rn = 0;
			for (size_t t = 0; t < nt; t++)
				q[t] = eps * d[t];
			for (size_t i = 0; i < ne; i++) {
				uint32_t a = ea[2 * i], g = ea[2 * i + 1];
				double f = ed[3 * i + 2] * (d[a] - d[g]);
				q[a] += f;
				q[g] -= f;
			}
			for (size_t t = 0; t < nt; t++)
				dq += d[t] * q[t];
			if (!(dq > 0))
				break;
			alpha = rr / dq;
			for (size_t t = 0; t < nt; t++) {
				x[t] += alpha * d[t];
				r[t] -= alpha * q[t];
				rn += r[t] * r[t];
			}
			for (size_t t = 0; t < nt; t++)
				d[t] = r[t] + rn / rr * d[t];
			rr = rn;
		}
		for (size_t t = 0; t < nt; t++)
			tr[2 * t + c] = x[t];
	}
	free(ea);
	free(ed);
	free(vec);
	return LOOM_OK;
}

LOOM_API int loom_mesh_field_uv(const loom_mesh *m,
                                const loom_field_uv_params *p,
                                loom_mesh **out, loom_diag *diag)
{
	size_t nt, np;
	uint32_t *nbr = NULL, *queue = NULL, *parent = NULL;
	double *fn = NULL, *w = NULL, *tmp = NULL, *tr = NULL;
	uint8_t *placed = NULL;
	loom_mesh *o = NULL;
	double d[3], per[2];
	int rc = LOOM_ENOMEM;

	if (out)
		*out = NULL;
	if (!m || !p || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_mesh_field_uv: NULL argument");
	if (p->size < sizeof *p)
		return loom__fail(diag, LOOM_EINVAL, "loom_mesh_field_uv: params.size "
		                  "%zu, expected %zu (use LOOM_FIELD_UV_PARAMS_INIT)",
		                  p->size, sizeof *p);
	memcpy(d, p->warp_dir, sizeof d);
	if (!isfinite(d[0]) || !isfinite(d[1]) || !isfinite(d[2]) ||
	    !(loom__dot3(d, d) > 0))
		return loom__fail(diag, LOOM_EINVAL, "field: the warp direction must be "
		                  "finite and non-zero");
	if (!(p->uv_per_world > 0) || !isfinite(p->uv_per_world))
		return loom__fail(diag, LOOM_EINVAL, "field: uv_per_world (%g) must be "
		                  "finite and > 0", p->uv_per_world);
	if (p->source != LOOM_FIELD_DIRECTION && p->source != LOOM_FIELD_CURVATURE_MAX &&
	    p->source != LOOM_FIELD_CURVATURE_MIN)
		return loom__fail(diag, LOOM_EINVAL, "field: source %d is not a "
		                  "LOOM_FIELD_* value", p->source);
	if (p->smooth_iters > 100000)
		return loom__fail(diag, LOOM_EINVAL, "field: smooth_iters %u > 100000",
		                  p->smooth_iters);
	for (int k = 0; k < 2; k++) {
		per[k] = p->period[k];
		if (!isfinite(per[k]) || per[k] < 0)
			return loom__fail(diag, LOOM_EINVAL, "field: period must be "
			                  "finite and >= 0");
	}
	nt = m->n_triangles;
	np = m->n_positions;
	if (!nt)
		return loom__fail(diag, LOOM_EINVAL, "field: the mesh has no triangles");

	nbr = malloc(3 * nt * sizeof *nbr);
	fn = malloc(3 * nt * sizeof *fn);
	w = malloc(3 * nt * sizeof *w);
	tmp = malloc(6 * nt * sizeof *tmp);
	tr = malloc(2 * nt * sizeof *tr);
	queue = malloc(nt * sizeof *queue);
	parent = malloc(nt * sizeof *parent);
	placed = calloc(nt, 1);
	o = calloc(1, sizeof *o);
	if (!nbr || !fn || !w || !tmp || !tr || !queue || !parent || !placed || !o)
		goto oom;
	o->n_positions = m->n_positions;
	o->n_triangles = m->n_triangles;
	o->n_texcoords = (uint32_t)(3 * nt);
	o->positions = malloc(3 * np * sizeof *o->positions + 1);
	o->tri_v = malloc(3 * nt * sizeof *o->tri_v);
	o->tri_vt = malloc(3 * nt * sizeof *o->tri_vt);
	o->texcoords = malloc(6 * nt * sizeof *o->texcoords);
	if (!o->positions || !o->tri_v || !o->tri_vt || !o->texcoords)
		goto oom;
	if (3 * nt > UINT32_MAX) {
		rc = loom__fail(diag, LOOM_ERANGE, "field: %zu triangles is too many "
		                "(three texture coordinates each)", nt);
		goto fail;
	}
	memcpy(o->positions, m->positions, 3 * np * sizeof *o->positions);
	memcpy(o->tri_v, m->tri_v, 3 * nt * sizeof *o->tri_v);
	if (m->tri_vn && m->n_normals) {
		o->n_normals = m->n_normals;
		o->normals = malloc(3 * (size_t)m->n_normals * sizeof *o->normals);
		o->tri_vn = malloc(3 * nt * sizeof *o->tri_vn);
		if (!o->normals || !o->tri_vn)
			goto oom;
		memcpy(o->normals, m->normals, 3 * (size_t)m->n_normals * sizeof *o->normals);
		memcpy(o->tri_vn, m->tri_vn, 3 * nt * sizeof *o->tri_vn);
	}
	if ((rc = edge_neighbours(m, nbr)))
		goto oom;
	for (size_t t = 0; t < nt; t++)
		if (!(face_normal(m, (uint32_t)t, fn + 3 * t) > 0))
			for (int e = 0; e < 3; e++) {
				/* degenerate: no neighbour relations either way */
				uint32_t g = nbr[3 * t + e];
				nbr[3 * t + e] = FIELD_NONE;
				if (g != FIELD_NONE)
					for (int f = 0; f < 3; f++)
						if (nbr[3 * (size_t)g + f] == t)
							nbr[3 * (size_t)g + f] = FIELD_NONE;
			}
	if (p->source == LOOM_FIELD_DIRECTION) {
		/* c_f t_f: the raw projection over |d| (length c_f) */
		double dl = sqrt(loom__dot3(d, d));
		for (size_t t = 0; t < nt; t++) {
			project(d, fn + 3 * t, tmp + 3 * t);
			for (int j = 0; j < 3; j++)
				tmp[3 * t + j] /= dl;
		}
	} else {
		double *vn = malloc(3 * np * sizeof *vn + 1);
		if (!vn)
			goto oom;
		curvature_data(m, fn, d, p->source, vn, tmp);
		free(vn);
	}
	warp_field(m, nbr, fn, p->smooth_iters, p->source != LOOM_FIELD_DIRECTION, w, tmp);
	if (p->source != LOOM_FIELD_DIRECTION) {
		orient_field(m, nbr, fn, w, queue, placed);
		memset(placed, 0, nt);
	}

	/* Breadth-first placement, one seed per connected component: the
	   triangle of highest confidence is not needed; the lowest index is
	   deterministic and as good. */
	for (size_t seed = 0; seed < nt; seed++) {
		size_t head = 0, tail = 0;
		if (placed[seed])
			continue;
		placed[seed] = 1;
		tr[2 * seed] = tr[2 * seed + 1] = 0;
		{
			/* the seed's first corner at the origin */
			double uv[2];
			local_uv(m, (uint32_t)seed, 0, fn, w, p->uv_per_world, uv);
			tr[2 * seed] = -uv[0];
			tr[2 * seed + 1] = -uv[1];
		}
		parent[seed] = FIELD_NONE;
		for (int e = 0; e < 3; e++) {
			uint32_t g = nbr[3 * seed + e];
			if (g != FIELD_NONE && !placed[g]) {
				placed[g] = 2; /* queued */
				parent[g] = (uint32_t)seed;
				queue[tail++] = g;
			}
		}
		while (head < tail) {
			uint32_t t = queue[head++];
			double prop[3][2], wt[3], ref[2] = {0, 0}, sum[2] = {0, 0}, ws = 0;
			int np_ = 0, iref = -1;
			for (int e = 0; e < 3; e++) {
				uint32_t g = nbr[3 * (size_t)t + e];
				double luv[2][2], guv[2][2], len = 0;
				if (g == FIELD_NONE || placed[g] != 1)
					continue;
				for (int c = 0; c < 2; c++) {
					int ci = (e + c) % 3, gi = 0;
					uint32_t pv = m->tri_v[3 * (size_t)t + ci];
					for (int i = 0; i < 3; i++)
						if (m->tri_v[3 * (size_t)g + i] == pv)
							gi = i;
					local_uv(m, t, ci, fn, w, p->uv_per_world, luv[c]);
					local_uv(m, g, gi, fn, w, p->uv_per_world, guv[c]);
					guv[c][0] += tr[2 * (size_t)g];
					guv[c][1] += tr[2 * (size_t)g + 1];
				}
				for (int k = 0; k < 2; k++) {
					double dk = luv[1][k] - luv[0][k];
					prop[np_][k] = 0.5 * (guv[0][k] - luv[0][k] + guv[1][k] - luv[1][k]);
					len += dk * dk;
				}
				wt[np_] = sqrt(len) + 1e-300;
				if (g == parent[t])
					iref = np_;
				np_++;
			}
			if (iref < 0)
				iref = 0; /* cannot happen: the parent is placed */
			ref[0] = prop[iref][0];
			ref[1] = prop[iref][1];
			for (int i = 0; i < np_; i++) {
				double du = prop[i][0] - ref[0], dv = prop[i][1] - ref[1];
				if (per[0] > 0)
					du = wrap(du, per[0]);
				if (per[1] > 0)
					dv = wrap(dv, per[1]);
				/* proposals far from the parent's: fronts meeting */
				{
					double lim = 0.25 * (per[0] > 0 && per[1] > 0 ?
					             fmin(per[0], per[1]) : 2.0 * wt[iref]);
					if (i != iref && du * du + dv * dv > lim * lim)
						continue;
				}
				sum[0] += wt[i] * (ref[0] + du);
				sum[1] += wt[i] * (ref[1] + dv);
				ws += wt[i];
			}
			tr[2 * (size_t)t] = sum[0] / ws;
			tr[2 * (size_t)t + 1] = sum[1] / ws;
			placed[t] = 1;
			for (int e = 0; e < 3; e++) {
				uint32_t g = nbr[3 * (size_t)t + e];
				if (g != FIELD_NONE && !placed[g]) {
					placed[g] = 2;
					parent[g] = t;
					queue[tail++] = g;
				}
			}
		}
	}
	if (relax_translations(m, nbr, fn, w, p->uv_per_world, per, tr))
		goto oom;
	for (size_t t = 0; t < nt; t++)
		for (int i = 0; i < 3; i++) {
			double uv[2];
			local_uv(m, (uint32_t)t, i, fn, w, p->uv_per_world, uv);
			o->texcoords[6 * t + 2 * i] = (float)(uv[0] + tr[2 * t]);
			o->texcoords[6 * t + 2 * i + 1] = (float)(uv[1] + tr[2 * t + 1]);
			o->tri_vt[3 * t + i] = (uint32_t)(3 * t + (size_t)i);
		}
	free(nbr);
	free(fn);
	free(w);
	free(tmp);
	free(tr);
	free(queue);
	free(parent);
	free(placed);
	*out = o;
	return LOOM_OK;
oom:
	rc = loom__fail(diag, LOOM_ENOMEM, "field: out of memory (%zu triangles)", nt);
fail:
	free(nbr);
	free(fn);
	free(w);
	free(tmp);
	free(tr);
	free(queue);
	free(parent);
	free(placed);
	if (o) {
		free(o->positions);
		free(o->texcoords);
		free(o->normals);
		free(o->tri_v);
		free(o->tri_vt);
		free(o->tri_vn);
		free(o);
	}
	return rc;
}
