/*
 * engine/render/render_internal.h - what render.c, shell.c and microflake.c share
 * inside libloom (never installed).  loom/render.h is the public side.
 */
#ifndef LOOM_RENDER_INTERNAL_H
#define LOOM_RENDER_INTERNAL_H

#include "core/internal.h"
#include "loom/texture.h"

#include <math.h>
#include <string.h>

/* splitmix64 step: advance *state and return the next 64 random bits. */
static inline uint64_t loom__splitmix64(uint64_t *state)
{
	uint64_t z = (*state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

/* Uniform in [0, 1) with 53 random bits. */
static inline double loom__rand01(uint64_t *state)
{
	return (double)(loom__splitmix64(state) >> 11) * (1.0 / 9007199254740992.0);
}

/* ---- small vector helpers (double[3]) ---------------------------------- */
static inline double loom__dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void loom__cross3(const double a[3], const double b[3], double o[3])
{
	double x = a[1] * b[2] - a[2] * b[1];
	double y = a[2] * b[0] - a[0] * b[2];
	double z = a[0] * b[1] - a[1] * b[0];
	o[0] = x;
	o[1] = y;
	o[2] = z;
}

/* Normalise in place; returns the old length (0: v untouched). */
static inline double loom__normalize3(double v[3])
{
	double l = sqrt(loom__dot3(v, v));
	if (l > 0) {
		v[0] /= l;
		v[1] /= l;
		v[2] /= l;
	}
	return l;
}

/*
 * 3-D DDA (Amanatides and Woo) over the grid of cells [c*cell, (c+1)*cell)
 * per axis, along o + t d for t in [t0, t1].  After init, cell c is the one
 * holding o + t0 d and the ray stays in it until loom__dda_exit(); next
 * moves to the following cell and returns 0 once t1 is reached.  Cell
 * boundaries are recomputed from o at every step (no accumulated error;
 * times by a multiplication with 1 / d, within an ulp of the quotient);
 * where two planes are crossed at the same t the ray visits a cell for a
 * zero length, which trackers skip for free.
 */
typedef struct loom__dda {
	int64_t c[3];
	int step[3];
	double cell[3];
	double o[3], d[3];
	double inv[3];           /* 1 / d (0 where d is 0) */
	double tnext[3];
	double t, t1;
} loom__dda;

void loom__dda_init(loom__dda *g, const double o[3], const double d[3],
                    const int64_t cell[3], double t0, double t1);
/* (inline: the trackers call it once per cell, ~100 times a path) */
static inline int loom__dda_next(loom__dda *g)
{
	int a = g->tnext[0] <= g->tnext[1] ? 0 : 1;
	if (g->tnext[2] < g->tnext[a])
		a = 2;
	if (!(g->tnext[a] < g->t1)) {
		g->t = g->t1;
		return 0;
	}
	g->t = g->tnext[a];
	g->c[a] += g->step[a];
	g->tnext[a] = ((double)(g->c[a] + (g->step[a] > 0)) * g->cell[a] - g->o[a]) *
	              g->inv[a];
	return 1;
}
/*
 * The current cell lies outside [lo, hi], the z cells of its column that can
 * hold density (lo > hi: none).  Move the DDA to the last cell it would visit
 * before it either enters [lo, hi] or leaves the column (or reaches t1),
 * the very state (cell, next crossing times) that loom__dda_next would
 * reach step by step, so trackers skip the empty cells between without
 * visiting them: they hold no optical depth and draw no random numbers, so
 * the image is the same.  The z crossing times depend only on the cell
 * index (recomputed from o), which makes the jump exact.
 */
static inline double loom__dda_zt(const loom__dda *g, int64_t c)
{
	/* time the ray leaves z cell c in its direction of travel */
	return ((double)(c + (g->step[2] > 0)) * g->cell[2] - g->o[2]) * g->inv[2];
}
static inline void loom__dda_skip_z(loom__dda *g, int64_t lo, int64_t hi)
{
	int a = g->tnext[0] <= g->tnext[1] ? 0 : 1, s = g->step[2];
	double tx = g->tnext[a] < g->t1 ? g->tnext[a] : g->t1;
	int64_t c = g->c[2];
	double tn = g->tnext[2], t = g->t;

	/* z steps while its crossing time is below tx (what loom__dda_next
	   would choose), into cells outside [lo, hi]; a few cells a call */
	while (tn < tx && ((c + s) < lo || (c + s) > hi)) {
		c += s;
		t = tn;
		tn = loom__dda_zt(g, c);
	}
	g->c[2] = c;
	g->tnext[2] = tn;
	g->t = t;
}

/*
 * The current cell's column lies in the box of columns [box[0], box[1]) x
 * [box[2], box[3]) and the cell outside [lo, hi], the z cells that can hold
 * density anywhere in the box.  Take loom__dda_next's steps, with no
 * query, while the next cell stays in the box and outside [lo, hi]: the
 * cells passed are empty (no optical depth, no random numbers), and the
 * state is the one stepping reaches, bit for bit.  The next
 * loom__dda_next then leaves the box, enters [lo, hi] or ends the walk.
 */
static inline void loom__dda_skip_box(loom__dda *g, const int64_t box[4], int64_t lo,
                                      int64_t hi)
{
	for (;;) {
		int a = g->tnext[0] <= g->tnext[1] ? 0 : 1;
		int64_t n;
		if (g->tnext[2] < g->tnext[a])
			a = 2;
		if (!(g->tnext[a] < g->t1))
			return;
		n = g->c[a] + g->step[a];
		if (a == 2 ? n >= lo && n <= hi : n < box[2 * a] || n >= box[2 * a + 1])
			return;
		g->t = g->tnext[a];
		g->c[a] = n;
		g->tnext[a] = ((double)(n + (g->step[a] > 0)) * g->cell[a] - g->o[a]) * g->inv[a];
	}
}

static inline double loom__dda_exit(const loom__dda *g)
{
	double e = g->tnext[0] < g->tnext[1] ? g->tnext[0] : g->tnext[1];
	e = g->tnext[2] < e ? g->tnext[2] : e;
	return e < g->t1 ? e : g->t1;
}

/*
 * The tracer's projected area A(s, cos) for one roughness s (microflake.c):
 * a row of A at nodes y_k = k / (LOOM__MF_ROW - 1) with |cos| = 1 - y^4
 * (angle ~ sqrt(2) y^2 near the fibre, dense where A changes on the scale
 * of s, like the master table's nodes), filled from the master table,
 * read linearly in y: two square roots, no acos, exp or log per lookup.
 * Relative error against quadrature below 1e-3 (tested).  A thread keeps a
 * few rows keyed on s; the values are a pure function of s.
 */
#define LOOM__MF_ROW 513
typedef struct loom__mf_row {
	double s;                  /* the row's roughness (NaN: unused) */
	double a[LOOM__MF_ROW];
} loom__mf_row;

void loom__mf_row_fill(loom__mf_row *r, double s);
static inline double loom__mf_row_area(const loom__mf_row *r, double cos_w)
{
	double c = cos_w < 0 ? -cos_w : cos_w;
	double y = sqrt(sqrt(c < 1.0 ? 1.0 - c : 0.0)) * (LOOM__MF_ROW - 1);
	int k = (int)y;
	if (k > LOOM__MF_ROW - 2)
		k = LOOM__MF_ROW - 2;
	y -= k;
	return r->a[k] + y * (r->a[k + 1] - r->a[k]);
}

/*
 * Shell internals used by the tracer.
 *
 * loom__shell_map: world point -> voxel point, trying the prism *hint first
 * (updated to the prism found; start with LOOM_MESH_NONE).  When jac is not
 * NULL it receives d(world)/d(voxel) as a row-major 3x3 matrix (columns:
 * world vector of one voxel step along x, y, z), used to carry fibre
 * directions into world space.  *n_queries is incremented per Embree
 * closest-point query.  Returns 1 when inside the shell, else 0.
 */
int loom__shell_map(const loom_shell *s, const double w[3], uint32_t *hint,
                    double v[3], double jac[9], uint64_t *n_queries);

/*
 * First crossing of the ray o + t d (d unit) with the shell boundary for
 * t in (tnear, tfar).  Returns 1 and sets *t and *exiting (1 when the ray
 * leaves the shell there, i.e. the segment before the hit is inside), or 0
 * when nothing is hit.
 */
int loom__shell_hit(const loom_shell *s, const double o[3], const double d[3],
                    double tnear, double tfar, double *t, int *exiting);

/*
 * Next stretch [*a, *b] of the ray o + t d (d unit) inside the shell,
 * beyond *cur and cut at tmax.  Returns 1 and advances *cur to the end of
 * the stretch's last crossing, or 0 (with *cur = tmax) when there is none.
 * Crossings are counted, not alternated: where the shell overlaps itself
 * (two panels closer than its thickness, as at a pillow's pinched
 * corners) an entry while inside deepens the count and the stretch runs
 * on until the count returns to zero.
 */
int loom__shell_segment(const loom_shell *s, const double o[3], const double d[3],
                        double tmax, double *cur, double *a, double *b);

/* World-length epsilon for restarting rays at shell crossings. */
double loom__shell_eps(const loom_shell *s);

/* The shell's nz (voxels across the thickness). */
int64_t loom__shell_nz(const loom_shell *s);

/* Nonzero after Embree reported an error on the shell's device. */
int loom__shell_failed(const loom_shell *s);

/* ---- the floor (ground.c) ----------------------------------------------- */

/* Distance t > 0 along (o, d) to the ground plane; INFINITY when none (a
   ray starting on the plane does not hit it again). */
double loom__ground_hit(const loom_ground *g, const double o[3], const double d[3]);
/* Lambertian lobe max(0, n . wo) / pi (albedo excluded) and its exact
   cosine-weighted sampler (pdf = the lobe). */
double loom__lambert_eval(const double n[3], const double wo[3]);
void loom__lambert_sample(const double n[3], uint64_t *rng, double wo[3]);
/* LOOM_OK or LOOM_EINVAL (with the reason) for a bad enabled ground. */
int loom__ground_check(const loom_ground *g, loom_diag *diag);

/* ---- AOV accumulation (aov.c) ------------------------------------------ */

typedef struct loom__aov_hit {  /* one camera sample's first event */
	int hit;
	double albedo[3], normal[3], depth;
} loom__aov_hit;

typedef struct loom__aov_acc {  /* one pixel's sums, in sample order */
	uint32_t n, n_hit;
	double s[3], s2[3], albedo[3], normal[3], depth;
} loom__aov_acc;

void loom__aov_begin(loom__aov_acc *a);
void loom__aov_add(loom__aov_acc *a, const double L[3], const loom__aov_hit *h);
void loom__aov_store(const loom__aov_acc *a, const loom_render_aov *out, size_t pix);
void loom__aov_normal(const double g[3], const double d[3], double n[3]);

/* The medium of texel tx (the virtual texture's volume sources: render_texture.c,
   render_majorant.c); out->spread is the caller's. */
static inline void loom__texel_medium(const loom_texel *tx, loom_medium_sample *out)
{
	out->density = tx->density;
	memcpy(out->orient, tx->orientation, sizeof out->orient);
	memcpy(out->albedo, tx->albedo, sizeof out->albedo);
	out->alignment = tx->alignment;
	out->spread = 0; /* full resolution (the level-of-detail lookups set it) */
}

/* Level of detail for a ray footprint of fp voxels with `levels` coarse
   levels: floor(log2 fp) clamped to [0, levels] (render_texture.c). */
unsigned loom__lod_level(double fp, unsigned levels);

/* Whether majorant m reads its crossings' border offsets from the edge
   data (full rank, side_profiles in render_majorant.c) rather than the
   tables' dot products: for tests. */
int loom__majorant_border_data(const struct loom_majorant *m);

#endif /* LOOM_RENDER_INTERNAL_H */
