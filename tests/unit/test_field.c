/*
 * tests/unit/test_field.c - cloth on meshes without texture coordinates
 * (engine/render/surface_field.c): the field-aligned UVs are rigid per
 * triangle and follow the warp field; through the shell no crossing is
 * stretched beyond the documented bound (finite differences of
 * loom_shell_world_to_voxel at random points of the shell); the seam
 * figures stay small; loom_mesh_measure_uv against hand-computed values
 * (and a latitude-longitude sphere, whose poles the bound rejects);
 * determinism and bad arguments.
 */
#include "loom.h"
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- meshes built here, no vt ----------------------------------------- */

typedef struct gen {
	double *v;
	uint32_t nv, cap_v;
	uint32_t *f;
	uint32_t nf, cap_f;
} gen;

static uint32_t gen_v(gen *g, double x, double y, double z)
{
	if (g->nv == g->cap_v) {
		g->cap_v = g->cap_v ? 2 * g->cap_v : 64;
		g->v = realloc(g->v, 3 * (size_t)g->cap_v * sizeof *g->v);
	}
	g->v[3 * g->nv] = x;
	g->v[3 * g->nv + 1] = y;
	g->v[3 * g->nv + 2] = z;
	return g->nv++;
}

static void gen_f(gen *g, uint32_t a, uint32_t b, uint32_t c)
{
	if (g->nf == g->cap_f) {
		g->cap_f = g->cap_f ? 2 * g->cap_f : 64;
		g->f = realloc(g->f, 3 * (size_t)g->cap_f * sizeof *g->f);
	}
	g->f[3 * g->nf] = a;
	g->f[3 * g->nf + 1] = b;
	g->f[3 * g->nf + 2] = c;
	g->nf++;
}

/* OBJ text of g parsed into a loom_mesh (exercises the reader too). */
static loom_mesh *gen_mesh(gen *g)
{
	size_t cap = 64 * ((size_t)g->nv + g->nf) + 64, n = 0;
	char *t = malloc(cap);
	loom_mesh *m = NULL;
	loom_diag d;
	for (uint32_t i = 0; i < g->nv; i++)
		n += (size_t)snprintf(t + n, cap - n, "v %.9g %.9g %.9g\n", g->v[3 * i],
		                      g->v[3 * i + 1], g->v[3 * i + 2]);
	for (uint32_t i = 0; i < g->nf; i++)
		n += (size_t)snprintf(t + n, cap - n, "f %u %u %u\n", g->f[3 * i] + 1,
		                      g->f[3 * i + 1] + 1, g->f[3 * i + 2] + 1);
	memset(&d, 0, sizeof d);
	if (loom_obj_parse(t, n, "gen.obj", &m, &d) != LOOM_OK)
		printf("  parse: %s\n", d.message);
	free(t);
	free(g->v);
	free(g->f);
	memset(g, 0, sizeof *g);
	return m;
}

/* Latitude-longitude grid on the unit sphere (poles on z), welded; with
   vt = (longitude, latitude) when with_vt.  nu x nv cells. */
static loom_mesh *latlong(int nu, int nv, int with_vt)
{
	size_t cap = 200 * (size_t)(nu + 1) * (nv + 1), n = 0;
	char *t = malloc(cap);
	loom_mesh *m = NULL;
	loom_diag d;
	/* positions: the poles once, rings j = 1 .. nv-1 of nu points */
	n += (size_t)snprintf(t + n, cap - n, "v 0 0 -1\nv 0 0 1\n");
	for (int j = 1; j < nv; j++)
		for (int i = 0; i < nu; i++) {
			double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
			n += (size_t)snprintf(t + n, cap - n, "v %.9g %.9g %.9g\n",
			                      sin(th) * cos(ph), sin(th) * sin(ph), -cos(th));
		}
	for (int j = 0; j <= nv; j++)
		for (int i = 0; i <= nu; i++)
			n += (size_t)snprintf(t + n, cap - n, "vt %.9g %.9g\n",
			                      2 * M_PI * i / nu, M_PI * j / nv);
	for (int j = 0; j < nv; j++)
		for (int i = 0; i < nu; i++) {
			int vid[4], tid[4], ci[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1},
			                               {i, j + 1}};
			for (int k = 0; k < 4; k++) {
				int ii = ci[k][0] % nu, jj = ci[k][1];
				vid[k] = jj == 0 ? 1 : jj == nv ? 2 : 3 + (jj - 1) * nu + ii;
				tid[k] = 1 + ci[k][1] * (nu + 1) + ci[k][0];
			}
			for (int h = 0; h < 2; h++) {
				int a = 0, b = h ? 2 : 1, c = h ? 3 : 2;
				if (vid[a] == vid[b] || vid[b] == vid[c] || vid[a] == vid[c])
					continue;
				if (with_vt)
					n += (size_t)snprintf(t + n, cap - n, "f %d/%d %d/%d %d/%d\n",
					                      vid[a], tid[a], vid[b], tid[b], vid[c],
					                      tid[c]);
				else
					n += (size_t)snprintf(t + n, cap - n, "f %d %d %d\n",
					                      vid[a], vid[b], vid[c]);
			}
		}
	memset(&d, 0, sizeof d);
	if (loom_obj_parse(t, n, "latlong.obj", &m, &d) != LOOM_OK)
		printf("  parse: %s\n", d.message);
	free(t);
	return m;
}

/* Torus R = 1, r = 0.4 around z, nu x nv cells. */
static loom_mesh *torus(int nu, int nv)
{
	gen g;
	memset(&g, 0, sizeof g);
	for (int i = 0; i < nu; i++)
		for (int j = 0; j < nv; j++) {
			double a = 2 * M_PI * i / nu, b = 2 * M_PI * j / nv;
			gen_v(&g, (1 + 0.4 * cos(b)) * cos(a), (1 + 0.4 * cos(b)) * sin(a),
			      0.4 * sin(b));
		}
	for (int i = 0; i < nu; i++)
		for (int j = 0; j < nv; j++) {
			uint32_t a = (uint32_t)(i * nv + j), b = (uint32_t)(((i + 1) % nu) * nv + j);
			uint32_t c = (uint32_t)(((i + 1) % nu) * nv + (j + 1) % nv);
			uint32_t e = (uint32_t)(i * nv + (j + 1) % nv);
			gen_f(&g, a, b, c);
			gen_f(&g, a, c, e);
		}
	return gen_mesh(&g);
}

static loom_mesh *field(const loom_mesh *m, double dx, double dy, double dz,
                        double per)
{
	loom_field_uv_params p = LOOM_FIELD_UV_PARAMS_INIT;
	loom_mesh *o = NULL;
	loom_diag d;
	memset(&d, 0, sizeof d);
	p.warp_dir[0] = dx;
	p.warp_dir[1] = dy;
	p.warp_dir[2] = dz;
	p.uv_per_world = 1.0;
	p.period[0] = p.period[1] = per;
	if (loom_mesh_field_uv(m, &p, &o, &d) != LOOM_OK)
		printf("  field: %s\n", d.message);
	return o;
}

static double pos(const loom_mesh *m, uint32_t t, int i, int j)
{
	return m->positions[3 * (size_t)m->tri_v[3 * (size_t)t + i] + j];
}

/* Open cylinder of radius 1 around z, z in [0, 3], nu x nv cells. */
static loom_mesh *cylinder(int nu, int nv)
{
	gen g;
	memset(&g, 0, sizeof g);
	for (int j = 0; j <= nv; j++)
		for (int i = 0; i < nu; i++) {
			double a = 2 * M_PI * i / nu;
			gen_v(&g, cos(a), sin(a), 3.0 * j / nv);
		}
	for (int j = 0; j < nv; j++)
		for (int i = 0; i < nu; i++) {
			uint32_t a = (uint32_t)(j * nu + i), b = (uint32_t)(j * nu + (i + 1) % nu);
			uint32_t c = b + (uint32_t)nu, e = a + (uint32_t)nu;
			gen_f(&g, a, b, c);
			gen_f(&g, a, c, e);
		}
	return gen_mesh(&g);
}

/* World direction of +v on triangle t of a field-mapped mesh (unit) and
   the triangle's unit normal; 0 if degenerate. */
static int warp_world(const loom_mesh *o, uint32_t t, double wv[3], double n[3])
{
	double e1[3], e2[3], u1[2], u2[2], det, l;
	for (int j = 0; j < 3; j++) {
		e1[j] = pos(o, t, 1, j) - pos(o, t, 0, j);
		e2[j] = pos(o, t, 2, j) - pos(o, t, 0, j);
	}
	for (int j = 0; j < 2; j++) {
		u1[j] = o->texcoords[2 * o->tri_vt[3 * t + 1] + j] -
		        o->texcoords[2 * o->tri_vt[3 * t] + j];
		u2[j] = o->texcoords[2 * o->tri_vt[3 * t + 2] + j] -
		        o->texcoords[2 * o->tri_vt[3 * t] + j];
	}
	det = u1[0] * u2[1] - u2[0] * u1[1];
	if (!(fabs(det) > 0))
		return 0;
	for (int j = 0; j < 3; j++)
		wv[j] = -u2[0] / det * e1[j] + u1[0] / det * e2[j];
	l = sqrt(wv[0] * wv[0] + wv[1] * wv[1] + wv[2] * wv[2]);
	for (int j = 0; j < 3; j++)
		wv[j] /= l;
	n[0] = e1[1] * e2[2] - e1[2] * e2[1];
	n[1] = e1[2] * e2[0] - e1[0] * e2[2];
	n[2] = e1[0] * e2[1] - e1[1] * e2[0];
	l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
	for (int j = 0; j < 3; j++)
		n[j] /= l;
	return 1;
}

static loom_mesh *curv_field(const loom_mesh *m, int source)
{
	loom_field_uv_params p = LOOM_FIELD_UV_PARAMS_INIT;
	loom_mesh *o = NULL;
	loom_diag d;
	memset(&d, 0, sizeof d);
	/* a user direction along neither principal direction: the curvature
	   must do the aligning */
	p.warp_dir[0] = 0.3;
	p.warp_dir[1] = 0.5;
	p.warp_dir[2] = 1.0;
	p.uv_per_world = 1.0;
	p.source = source;
	if (loom_mesh_field_uv(m, &p, &o, &d) != LOOM_OK)
		printf("  field: %s\n", d.message);
	return o;
}

/* Largest angle (degrees) between the warp line on each triangle and the
   line `ref` gives at its centroid (ref fills a unit tangent). */
static double line_error(const loom_mesh *o, void (*ref)(const double c[3], double r[3]),
                         int *count)
{
	double worst = 0;
	*count = 0;
	for (uint32_t t = 0; t < o->n_triangles; t++) {
		double wv[3], n[3], c[3] = {0, 0, 0}, r[3], cs;
		if (!warp_world(o, t, wv, n))
			continue;
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				c[j] += pos(o, t, i, j) / 3;
		ref(c, r);
		cs = fabs(wv[0] * r[0] + wv[1] * r[1] + wv[2] * r[2]);
		worst = fmax(worst, acos(fmin(1.0, cs)) * 180 / M_PI);
		(*count)++;
	}
	return worst;
}

static void ref_axis(const double c[3], double r[3])
{
	(void)c;
	r[0] = r[1] = 0;
	r[2] = 1;
}

static void ref_round_z(const double c[3], double r[3])
{
	/* the circle round the z axis through c */
	double l = sqrt(c[0] * c[0] + c[1] * c[1]);
	r[0] = -c[1] / l;
	r[1] = c[0] / l;
	r[2] = 0;
}

static void ref_tube(const double c[3], double r[3])
{
	/* the torus tube's circle through c (R = 1): in the plane of z and
	   the radial direction, perpendicular to c - the tube's centre */
	double l = sqrt(c[0] * c[0] + c[1] * c[1]), q[3], rad[3] = {c[0] / l, c[1] / l, 0};
	double z[3] = {0, 0, 1}, ql;
	for (int j = 0; j < 3; j++)
		q[j] = c[j] - rad[j];
	ql = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
	/* tangent of the tube circle: rotate q/|q| by 90 degrees in the
	   (rad, z) plane */
	{
		double a = (q[0] * rad[0] + q[1] * rad[1]) / ql, b = q[2] / ql;
		for (int j = 0; j < 3; j++)
			r[j] = -b * rad[j] + a * z[j];
	}
}

/* Mean and largest turn (degrees) of the warp line between triangles
   sharing an edge (the neighbour's direction projected onto the
   triangle's plane): the field's smoothness. */
static void smoothness(const loom_mesh *o, const loom_mesh *m, double *mean, double *max)
{
	double acc = 0;
	size_t n = 0;
	*max = 0;
	for (uint32_t t = 0; t < m->n_triangles; t++)
		for (uint32_t g = t + 1; g < m->n_triangles; g++) {
			int shared = 0;
			double wt[3], nt[3], wg[3], ng[3], d, q[3], ql, cs;
			for (int i = 0; i < 3; i++)
				for (int k = 0; k < 3; k++)
					shared += m->tri_v[3 * t + i] == m->tri_v[3 * g + k];
			if (shared != 2 || !warp_world(o, t, wt, nt) || !warp_world(o, g, wg, ng))
				continue;
			d = wg[0] * nt[0] + wg[1] * nt[1] + wg[2] * nt[2];
			for (int j = 0; j < 3; j++)
				q[j] = wg[j] - d * nt[j];
			ql = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
			cs = fabs(q[0] * wt[0] + q[1] * wt[1] + q[2] * wt[2]) / ql;
			cs = acos(fmin(1.0, cs)) * 180 / M_PI;
			acc += cs;
			*max = fmax(*max, cs);
			n++;
		}
	*mean = n ? acc / (double)n : 0;
}

/*
 * Principal-curvature fields: on a cylinder curvature-max runs round it
 * and curvature-min along the axis, on a torus curvature-max follows the
 * tube's circles and curvature-min the circles round the hole, each within
 * 3 degrees on every triangle although the user direction (0.3, 0.5, 1)
 * is along neither (the direction field with it is far off: the test can
 * fail); the field turns smoothly between neighbours (at most 10
 * degrees across an edge); on a sphere (all umbilic) curvature-max falls
 * back to the user direction's field (within 5 degrees away from its
 * poles: the discrete estimate is not exactly umbilic there).
 */
static void test_curvature(void)
{
	loom_mesh *cy = cylinder(48, 24), *to = torus(48, 24), *sp = latlong(48, 24, 0);
	loom_mesh *a = cy ? curv_field(cy, LOOM_FIELD_CURVATURE_MAX) : NULL;
	loom_mesh *b = cy ? curv_field(cy, LOOM_FIELD_CURVATURE_MIN) : NULL;
	loom_mesh *c = to ? curv_field(to, LOOM_FIELD_CURVATURE_MAX) : NULL;
	loom_mesh *d = to ? curv_field(to, LOOM_FIELD_CURVATURE_MIN) : NULL;
	loom_mesh *e = to ? curv_field(to, LOOM_FIELD_DIRECTION) : NULL;
	loom_mesh *f = sp ? curv_field(sp, LOOM_FIELD_CURVATURE_MAX) : NULL;
	loom_mesh *fd = sp ? curv_field(sp, LOOM_FIELD_DIRECTION) : NULL;
	int n1, n2, n3, n4, n5;
	double e1, e2, e3, e4, e5, sm, sx, dm, dx;

	CHECK(a && b && c && d && e && f && fd);
	if (!(a && b && c && d && e && f && fd))
		goto done;
	e1 = line_error(a, ref_round_z, &n1);
	e2 = line_error(b, ref_axis, &n2);
	e3 = line_error(c, ref_tube, &n3);
	e4 = line_error(d, ref_round_z, &n4);
	e5 = line_error(e, ref_tube, &n5);
	smoothness(c, to, &sm, &sx);
	smoothness(e, to, &dm, &dx);
	printf("  cylinder: curvature-max off the circumference <= %.2f deg, "
	       "curvature-min off the axis <= %.2f deg (%d triangles)\n", e1, e2, n1);
	printf("  torus: curvature-max off the tube's circles <= %.2f deg, "
	       "curvature-min off the circles round the hole <= %.2f deg; the "
	       "direction field off the tube's circles up to %.1f deg\n", e3, e4, e5);
	printf("  torus smoothness: turn between neighbours mean %.2f max %.2f deg "
	       "(direction field: mean %.2f max %.2f)\n", sm, sx, dm, dx);
	CHECK(n1 == 2 * 48 * 24 && n2 == n1 && n3 == n1 && n4 == n1);
	CHECK(e1 < 3.0);
	CHECK(e2 < 3.0);
	CHECK(e3 < 3.0);
	CHECK(e4 < 3.0);
	CHECK(e5 > 20.0);
	CHECK(sx < 10.0);
	/* the sphere: umbilic everywhere, the user direction's field (away
	   from its poles, where the normal is within 45 degrees of it) */
	{
		double dd[3] = {0.3, 0.5, 1.0}, dl = sqrt(0.09 + 0.25 + 1.0), worst = 0;
		int used = 0;
		for (uint32_t t = 0; t < f->n_triangles; t++) {
			double w1[3], w2[3], n[3], cs;
			if (!warp_world(f, t, w1, n) || !warp_world(fd, t, w2, n) ||
			    fabs(n[0] * dd[0] + n[1] * dd[1] + n[2] * dd[2]) / dl > 0.7)
				continue;
			cs = fabs(w1[0] * w2[0] + w1[1] * w2[1] + w1[2] * w2[2]);
			worst = fmax(worst, acos(fmin(1.0, cs)) * 180 / M_PI);
			used++;
		}
		printf("  sphere: curvature-max off the direction field <= %.2f deg "
		       "(%d triangles away from its poles)\n", worst, used);
		CHECK(used > 1000);
		CHECK(worst < 5.0);
	}
done:
	loom_mesh_free(a);
	loom_mesh_free(b);
	loom_mesh_free(c);
	loom_mesh_free(d);
	loom_mesh_free(e);
	loom_mesh_free(f);
	loom_mesh_free(fd);
	loom_mesh_free(cy);
	loom_mesh_free(to);
	loom_mesh_free(sp);
}

/* Rigid per triangle (edge lengths kept) and the v axis along the
   projected warp where the projection is well defined. */
static void test_rigid_and_aligned(void)
{
	loom_mesh *m = latlong(48, 24, 0), *o = m ? field(m, 0, 0, 1, 0) : NULL;
	double maxlen = 0, maxang = 0;
	int aligned = 0;

	CHECK(o != NULL);
	if (!o) {
		loom_mesh_free(m);
		return;
	}
	CHECK_EQ_INT(o->n_triangles, m->n_triangles);
	CHECK_EQ_INT(o->n_texcoords, 3 * m->n_triangles);
	for (uint32_t t = 0; t < o->n_triangles; t++) {
		double n[3], e1[3], e2[3], c, dz[3] = {0, 0, 1}, pr[3], wv[3];
		double J[2][2], u1[2], u2[2], det;
		for (int i = 0; i < 3; i++) {
			int k = (i + 1) % 3;
			double w2 = 0, u = 0;
			for (int j = 0; j < 3; j++)
				w2 += (pos(o, t, k, j) - pos(o, t, i, j)) * (pos(o, t, k, j) - pos(o, t, i, j));
			for (int j = 0; j < 2; j++) {
				double du = o->texcoords[2 * o->tri_vt[3 * t + k] + j] -
				            o->texcoords[2 * o->tri_vt[3 * t + i] + j];
				u += du * du;
			}
			maxlen = fmax(maxlen, fabs(sqrt(u) - sqrt(w2)) / sqrt(w2));
		}
		/* world direction of +v: solve [e1 e2] = J^-1 [du1 du2] */
		for (int j = 0; j < 3; j++) {
			e1[j] = pos(o, t, 1, j) - pos(o, t, 0, j);
			e2[j] = pos(o, t, 2, j) - pos(o, t, 0, j);
		}
		for (int j = 0; j < 2; j++) {
			u1[j] = o->texcoords[2 * o->tri_vt[3 * t + 1] + j] -
			        o->texcoords[2 * o->tri_vt[3 * t] + j];
			u2[j] = o->texcoords[2 * o->tri_vt[3 * t + 2] + j] -
			        o->texcoords[2 * o->tri_vt[3 * t] + j];
		}
		det = u1[0] * u2[1] - u2[0] * u1[1];
		/* a e1 + b e2 has uv (0, 1): a u1 + b u2 = (0, 1) */
		J[0][0] = -u2[0] / det;
		J[0][1] = u1[0] / det;
		for (int j = 0; j < 3; j++)
			wv[j] = J[0][0] * e1[j] + J[0][1] * e2[j];
		n[0] = e1[1] * e2[2] - e1[2] * e2[1];
		n[1] = e1[2] * e2[0] - e1[0] * e2[2];
		n[2] = e1[0] * e2[1] - e1[1] * e2[0];
		c = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
		for (int j = 0; j < 3; j++)
			n[j] /= c;
		c = n[2];
		for (int j = 0; j < 3; j++)
			pr[j] = dz[j] - c * n[j];
		/* away from the poles (|n.z| < 0.7) the smoothed field keeps to
		   the projection */
		if (fabs(c) < 0.7) {
			double a = sqrt(pr[0] * pr[0] + pr[1] * pr[1] + pr[2] * pr[2]);
			double b = sqrt(wv[0] * wv[0] + wv[1] * wv[1] + wv[2] * wv[2]);
			double cs = (pr[0] * wv[0] + pr[1] * wv[1] + pr[2] * wv[2]) / (a * b);
			maxang = fmax(maxang, acos(fmin(1.0, cs)) * 180 / M_PI);
			aligned++;
		}
	}
	printf("  edge length error %.2e, warp off the projection <= %.2f deg "
	       "over %d triangles\n", maxlen, maxang, aligned);
	CHECK(maxlen < 1e-5);
	CHECK(aligned > 500);
	CHECK(maxang < 3.0);
	loom_mesh_free(o);
	loom_mesh_free(m);
}

/*
 * Stretch through the shell: at random points of the shell, voxel steps
 * of a small world step along two tangent directions (central
 * differences inside one prism) against the nominal voxels_per_uv.  The
 * documented bound: max(s1, 1/s2) <= 1 + (thickness / 2) kappa_max + 0.02
 * (the shell's height term plus normal interpolation), here kappa_max = 1
 * / 0.4 for the torus and 1 for the sphere.
 */
static double shell_stretch(const loom_mesh *o, double thick, double vpu,
                            int n, uint64_t *rng)
{
	loom_shell_params sp = LOOM_SHELL_PARAMS_INIT;
	loom_shell *s = NULL;
	loom_diag d;
	double worst = 1.0;
	int used = 0;

	memset(&d, 0, sizeof d);
	sp.thickness = thick;
	sp.offset = -thick / 2;
	sp.voxels_per_uv = vpu;
	sp.nz = 16;
	if (loom_shell_new(o, &sp, &s, &d) != LOOM_OK) {
		printf("  shell: %s\n", d.message);
		return INFINITY;
	}
	for (int k = 0; k < n; k++) {
		uint32_t t = (uint32_t)(loom_rng_uniform(rng) * o->n_triangles);
		double b0 = loom_rng_uniform(rng), b1 = loom_rng_uniform(rng), b2;
		double h = (loom_rng_uniform(rng) - 0.5) * 0.9 * thick, P[3], e1[3], e2[3];
		double nn[3], c, tan1[3], tan2[3], v[2][2][3], g[2][2], step = 1e-4;
		double A, B, D, tr, dt, disc, s1, s2;
		uint32_t tri[2][2];
		int ok = 1;
		if (b0 + b1 > 1) {
			b0 = 1 - b0;
			b1 = 1 - b1;
		}
		b2 = 1 - b0 - b1;
		if (t >= o->n_triangles)
			t = o->n_triangles - 1;
		for (int j = 0; j < 3; j++) {
			e1[j] = pos(o, t, 1, j) - pos(o, t, 0, j);
			e2[j] = pos(o, t, 2, j) - pos(o, t, 0, j);
		}
		nn[0] = e1[1] * e2[2] - e1[2] * e2[1];
		nn[1] = e1[2] * e2[0] - e1[0] * e2[2];
		nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
		c = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
		for (int j = 0; j < 3; j++) {
			nn[j] /= c;
			P[j] = b0 * pos(o, t, 0, j) + b1 * pos(o, t, 1, j) + b2 * pos(o, t, 2, j) +
			       h * nn[j];
		}
		c = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
		for (int j = 0; j < 3; j++)
			tan1[j] = e1[j] / c;
		tan2[0] = nn[1] * tan1[2] - nn[2] * tan1[1];
		tan2[1] = nn[2] * tan1[0] - nn[0] * tan1[2];
		tan2[2] = nn[0] * tan1[1] - nn[1] * tan1[0];
		for (int a = 0; a < 2 && ok; a++)
			for (int sg = 0; sg < 2 && ok; sg++) {
				double w[3];
				for (int j = 0; j < 3; j++)
					w[j] = P[j] + (sg ? step : -step) * (a ? tan2[j] : tan1[j]);
				ok = loom_shell_world_to_voxel(s, w, v[a][sg], &tri[a][sg]) == LOOM_OK;
			}
		if (!ok || tri[0][0] != tri[0][1] || tri[1][0] != tri[1][1] ||
		    tri[0][0] != tri[1][0])
			continue; /* straddles two prisms */
		for (int a = 0; a < 2; a++)
			for (int j = 0; j < 2; j++)
				g[a][j] = (v[a][1][j] - v[a][0][j]) / (2 * step * vpu);
		A = g[0][0] * g[0][0] + g[0][1] * g[0][1];
		B = g[0][0] * g[1][0] + g[0][1] * g[1][1];
		D = g[1][0] * g[1][0] + g[1][1] * g[1][1];
		tr = A + D;
		dt = A * D - B * B;
		disc = sqrt(fmax(0, 0.25 * tr * tr - dt));
		s1 = sqrt(0.5 * tr + disc);
		s2 = sqrt(fmax(0, 0.5 * tr - disc));
		worst = fmax(worst, fmax(s1, s2 > 0 ? 1 / s2 : INFINITY));
		used++;
	}
	printf("  %d points inside one prism, worst stretch %.4f\n", used, worst);
	if (used < n / 2)
		worst = INFINITY;
	loom_shell_free(s);
	return worst;
}

static void test_stretch_bound(void)
{
	uint64_t rng = check_seed();
	loom_mesh *sph = latlong(48, 24, 0), *tor = torus(72, 30);
	loom_mesh *sphuv = latlong(48, 24, 1);
	loom_mesh *fs = sph ? field(sph, 0, 0, 1, 0.05) : NULL;
	loom_mesh *ft = tor ? field(tor, 1, 0, 0, 0.05) : NULL;
	double th = 0.03;

	CHECK(fs && ft && sphuv);
	if (fs)
		CHECK(shell_stretch(fs, th, 200, 400, &rng) <= 1 + th / 2 * 1.0 + 0.02);
	if (ft)
		CHECK(shell_stretch(ft, th, 200, 400, &rng) <= 1 + th / 2 / 0.4 + 0.02);
	/* the same measure fails the latitude-longitude UVs (poles) */
	if (sphuv) {
		loom_mesh_uv_stats st;
		CHECK_EQ_INT(loom_mesh_measure_uv(sphuv, NULL, 1e-6, &st), LOOM_OK);
		printf("  lat-long UVs: stretch max %.2f mean %.3f\n", st.stretch_max,
		       st.stretch_mean);
		CHECK(st.stretch_max > 1 + th / 2 + 0.02);
		CHECK(shell_stretch(sphuv, th, 200 / st.uv_per_world, 400, &rng) >
		      1 + th / 2 + 0.02);
	}
	loom_mesh_free(fs);
	loom_mesh_free(ft);
	loom_mesh_free(sph);
	loom_mesh_free(tor);
	loom_mesh_free(sphuv);
}

/* Seams: mismatch at shared edge ends, modulo the period, stays a small
   part of an edge on average; with the period a whole-period jump costs
   nothing. */
static void test_seams(void)
{
	loom_mesh *sph = latlong(48, 24, 0), *tor = torus(72, 30);
	loom_mesh *meshes[2] = {sph, tor};
	double dirs[2][3] = {{0, 0, 1}, {1, 0, 0}}, edge[2] = {0.065, 0.085};

	for (int k = 0; k < 2; k++) {
		loom_mesh *o = meshes[k] ? field(meshes[k], dirs[k][0], dirs[k][1],
		                                 dirs[k][2], 0.05) : NULL;
		loom_mesh_uv_stats st;
		double per[2] = {0.05, 0.05};
		CHECK(o != NULL);
		if (!o)
			continue;
		CHECK_EQ_INT(loom_mesh_measure_uv(o, per, 0.1 * edge[k], &st), LOOM_OK);
		printf("  %s: %u interior edges, mismatch mean %.4f max %.4f (edge ~%.3f), "
		       "%u over a tenth of an edge\n", k ? "torus" : "sphere",
		       st.interior_edges, st.seam_mean, st.seam_max, edge[k],
		       st.seam_edges);
		CHECK(st.stretch_max < 1 + 1e-4);
		CHECK(st.interior_edges == 3 * meshes[k]->n_triangles / 2);
		CHECK(st.seam_mean < 0.25 * edge[k]);
		CHECK(st.seam_max <= 0.5 * sqrt(2) * 0.05 + 1e-9);
		loom_mesh_free(o);
	}
	loom_mesh_free(sph);
	loom_mesh_free(tor);
}

/* loom_mesh_measure_uv against values worked by hand. */
static void test_measure(void)
{
	/* two triangles of the unit square; the right one stretched 2x in u
	   and its shared edge's UVs shifted by 0.25 in v */
	const char *txt = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
	                  "vt 0 0\nvt 2 0\nvt 2 1\nvt 0 1\nvt 0 1.25\nvt 0 0.25\n"
	                  "f 1/1 2/2 3/3\nf 1/6 3/3 4/4\n";
	loom_mesh *m = NULL;
	loom_mesh_uv_stats st;
	double per[2] = {0, 1.0};

	CHECK_EQ_INT(loom_obj_parse(txt, strlen(txt), "m.obj", &m, NULL), LOOM_OK);
	if (!m)
		return;
	CHECK_EQ_INT(loom_mesh_measure_uv(m, NULL, 0.1, &st), LOOM_OK);
	CHECK_EQ_INT(st.interior_edges, 1);
	CHECK_EQ_INT(st.seam_edges, 1);
	CHECK(fabs(st.seam_max - 0.25) < 1e-6);
	/* UV area 1 + 0.75 (second: (0,.25),(2,1),(0,1)) over world area 1 */
	CHECK(fabs(st.uv_per_world - sqrt(1.75)) < 1e-6);
	CHECK(st.stretch_max > 1.3);
	/* a period of 1 in v does not forgive 0.25 */
	CHECK_EQ_INT(loom_mesh_measure_uv(m, per, 0.1, &st), LOOM_OK);
	CHECK(fabs(st.seam_max - 0.25) < 1e-6);
	per[1] = 0.25;
	CHECK_EQ_INT(loom_mesh_measure_uv(m, per, 0.1, &st), LOOM_OK);
	CHECK(st.seam_max < 1e-6);
	CHECK_EQ_INT(st.seam_edges, 0);
	loom_mesh_free(m);
}

static void test_determinism_and_args(void)
{
	loom_mesh *m = torus(24, 12), *a, *b, *o = NULL;
	loom_field_uv_params p = LOOM_FIELD_UV_PARAMS_INIT;
	loom_mesh_uv_stats st;
	loom_diag d;

	memset(&d, 0, sizeof d);
	a = m ? field(m, 0.3, 1, 0.2, 0.1) : NULL;
	b = m ? field(m, 0.3, 1, 0.2, 0.1) : NULL;
	CHECK(a && b);
	if (a && b)
		CHECK(memcmp(a->texcoords, b->texcoords,
		             6 * (size_t)a->n_triangles * sizeof(float)) == 0);
	p.warp_dir[0] = p.warp_dir[1] = p.warp_dir[2] = 0;
	CHECK_EQ_INT(loom_mesh_field_uv(m, &p, &o, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "warp direction");
	CHECK(o == NULL);
	p.warp_dir[1] = 1;
	p.uv_per_world = 0;
	CHECK_EQ_INT(loom_mesh_field_uv(m, &p, &o, &d), LOOM_EINVAL);
	p.uv_per_world = 1;
	p.period[0] = -1;
	CHECK_EQ_INT(loom_mesh_field_uv(m, &p, &o, &d), LOOM_EINVAL);
	p.period[0] = 0;
	p.source = 7;
	CHECK_EQ_INT(loom_mesh_field_uv(m, &p, &o, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "source 7");
	p.source = LOOM_FIELD_DIRECTION;
	p.size = 8;
	CHECK_EQ_INT(loom_mesh_field_uv(m, &p, &o, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_mesh_field_uv(NULL, &p, &o, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_mesh_measure_uv(m, NULL, 0, &st), LOOM_EINVAL); /* no vt */
	CHECK_EQ_INT(loom_mesh_measure_uv(NULL, NULL, 0, &st), LOOM_EINVAL);
	loom_mesh_free(a);
	loom_mesh_free(b);
	loom_mesh_free(m);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_field");
	RUN(test_rigid_and_aligned);
	RUN(test_stretch_bound);
	RUN(test_seams);
	RUN(test_measure);
	RUN(test_determinism_and_args);
	RUN(test_curvature);
	CHECK_MAIN_END();
}
