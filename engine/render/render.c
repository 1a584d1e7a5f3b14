/*
 * engine/render/render.c - a small unidirectional volume path tracer for the cloth
 * volume (the paper renders with Mitsuba's volume path tracer and the
 * microflake model, section 7).  docs/rendering.md is the user's view.
 *
 * Scene.  Either the slab [0,nx) x [0,ny) x [0,nz) of the voxel source in
 * voxel units (scene space = voxel space; nx or ny 0 = unbounded), or a
 * shell over a mesh (scene space = world space, engine/render/shell.c maps points
 * to voxels).  Outside the medium there is nothing but a constant
 * environment; one delta light (distant or point) is sampled explicitly.
 *
 * Medium.  At scene point x seen along unit direction d:
 *     mu_t(x, d) = density * density_scale * A(d . w; s) / len_voxel
 * (A = 2 sigma of loom_microflake_area, 1 for voxels without a fibre
 * direction; len_voxel = 1 for the slab, world_per_voxel for shells) and
 * scattering albedo * mu_t with the microflake phase function.
 *
 * Estimators.
 *   Free flight: delta (Woodcock) tracking against the constant majorant
 *     mu_bar = max_density * density_scale * A_max / len_voxel: tentative
 *     collisions at rate mu_bar, each real with probability mu_t / mu_bar.
 *   Light: next-event estimation at every real collision; transmittance by
 *     ratio tracking (product of 1 - mu_t / mu_bar over tentative points),
 *     with unbiased Russian roulette once it falls below 0.1.
 *   Path: throughput *= albedo at a real collision; the phase function is
 *     sampled exactly (weight 1); the environment is added when the path
 *     escapes; Russian roulette on the throughput after rr_depth events;
 *     at most max_depth events.
 * Segments.  Tracking runs over the parts of the ray inside the medium:
 * one box clip for the slab; for a shell, the pieces between consecutive
 * boundary crossings whose end crossing is an exit (the crossing's outward
 * normal decides), so no inside/outside state has to be carried.
 *
 * Parallelism and determinism.  The image is cut into tiles handed out by
 * an atomic counter to `threads` pthreads.  Sample j of pixel i draws from
 * its own splitmix64 stream seeded by hash(seed, i, j) and, for its first
 * decisions, its Owen-scrambled Sobol point (sampler.h); pixels are
 * averaged in sample order and adaptive sampling stops a pixel on its own
 * samples only, so the bytes do not depend on the thread count, the tile
 * order or progressive passes.  Worker threads set flush-to-zero and denormals-are-
 * zero (Embree's advice; also keeps delta tracking fast in thin media).
 */
#include "render_internal.h"
#include "sampler.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
#endif

#define MAX_THREADS 256
#define MAX_TENTATIVE (1u << 22) /* tentative collisions per path, a guard
                                    against endless grazing rays */

/* A light prepared for sampling. */
typedef struct plight {
	const loom_light *l;
	double dir[3];           /* distant: unit direction towards the light */
	double u[3], v[3];       /* frame around dir */
	double cos_disc;         /* cosine of the disc's half angle (1: point) */
} plight;

typedef struct rctx {
	const loom_volume_source *src;
	const loom_render_options *o;
	const loom_shell *shell;
	double dmax;             /* density bound */
	double len_voxel;        /* scene length of one voxel */
	double mu_bar;           /* majorant per scene length */
	double kscale;           /* density -> mu_t factor per scene length / A */
	double bnd[3];           /* slab extent (INFINITY = unbounded) */
	int grid;                /* track through the source's majorant grid */
	double mu_cell;          /* cell bound (density) -> majorant factor */
	double amax;             /* largest projected area A */
	/* camera */
	double eye[3], fwd[3], right[3], up[3], tan_x, tan_y;
	double lens_r, focus;    /* thin lens: radius (0 = pinhole), focus
	                            distance along fwd */
	/* lights: opt.light (when not NONE) and opt.lights */
	plight pl[1 + LOOM_RENDER_MAX_LIGHTS];
	uint32_t n_pl;
	/* work */
	uint32_t tile, tiles_x, tiles_y;
	uint64_t n_tiles, tiles_done;
	atomic_int error;
	pthread_mutex_t lock;
	float *rgb;
	/* sampling (render_pixel): passes of samples [pass_end[p-1],
	   pass_end[p]) over the whole image, a barrier between them; acc
	   holds each pixel's sums across passes (more than one pass only) */
	int sobol;               /* Owen-scrambled Sobol dimensions */
	int (*zbox)(void *, const int64_t *, int64_t *, int64_t *, int64_t *);
	                         /* the source's cell_zbox, where it has one
	                            (and cell_zspan) */
	int dens_first;          /* the source's density hook tests tentative
	                            collisions first: not with a level of
	                            detail, whose density is not level 0's */
	uint32_t n_passes;
	uint32_t pass_end[34];
	atomic_uint_fast64_t next_in_pass[34];
	struct pixacc *acc;
	uint64_t work_done;      /* tiles x pass samples, for progress */
	uint32_t n_workers, running, bar_count;
	uint64_t bar_gen;
	pthread_cond_t bar_cv, done_cv;
} rctx;

#define AREA_ROWS 4 /* projected-area rows kept per thread (yarn types) */

typedef struct tstate {
	_Alignas(64) rctx *c;     /* own cache lines: no false sharing */
	void *lctx;               /* ctx for lookups made by this thread */
	uint64_t rng;
	uint32_t hint;            /* shell prism of the last lookup */
	uint64_t tentative;       /* per path, for the guard */
	loom__ld ld;              /* the sample's low-discrepancy point */
	uint32_t ld_flight;       /* dimension of the next track's first
	                             free flight (NO_DIM: the stream) */
	loom_render_stats st;
	double fp_o[3], fp0, fp_rate; /* ray footprint (voxels) at x: fp0 +
	                             fp_rate |x - fp_o| (level of detail) */
	uint32_t row_last, row_next; /* area rows: last used, next to refill */
	int zb_ok;                /* zb* hold the box of columns zb and its
	                             z span (cell_zbox) */
	int64_t zb[4], zb_lo, zb_hi;
	int zs_ok;                /* zs_* hold cell column zs_c's z span */
	int64_t zs_c[2], zs_lo, zs_hi;
	loom__mf_row rows[AREA_ROWS];/* A(s, .) of the last roughnesses met */
} tstate;

/* Dimensions of the low-discrepancy point (sampler.h): the pixel, the
   lens, then for each of the first LD_BOUNCES segments of a path the
   first free flight, the first light's disc or sphere and the environment
   map's next-event directions and their shadow rays' first free flights.  Every other decision draws from the
   sample's splitmix64 stream. */
#define NO_DIM 0xffffffffu
#define D_PIXEL 0u
#define D_LENS 2u
#define LD_BOUNCES 2u
#define D_BOUNCE(b) (4u + 8u * (b))
#define D_FLIGHT 0u
#define D_LIGHT 1u   /* and 2 */
#define D_LIGHT_T 3u /* its shadow ray's first free flight */
#define D_ENV 4u     /* and 5 */
#define D_ENV_T 6u

/* Coordinate dim of the sample's point, or the next number of its stream
   (the random sampler, or dim NO_DIM). */
static inline double draw(tstate *t, uint32_t dim)
{
	if (dim != NO_DIM && t->c->sobol)
		return loom__ld_get(&t->ld, dim);
	return loom__rand01(&t->rng);
}

static inline uint32_t dim_at(uint32_t depth, uint32_t off)
{
	return depth < LD_BOUNCES ? D_BOUNCE(depth) + off : NO_DIM;
}

/* The first free flight's uniform number of the current track. */
static inline double first_u(tstate *t)
{
	uint32_t d = t->ld_flight;
	t->ld_flight = NO_DIM;
	return draw(t, d);
}

typedef struct medium {
	double mu;                /* extinction along the queried direction */
	double albedo[3];
	double w[3];              /* unit fibre direction (scene); zero = none */
	double s;                 /* microflake roughness */
	double dens;              /* density (clamped to the bound) */
	int surf;                 /* 1: the ground (Lambertian about n) */
	double n[3];
} medium;

/* ---- medium lookups ---------------------------------------------------- */

static double clamp_in(double v, double n)
{
	if (v < 0)
		return 0;
	if (v >= n)
		return nextafter(n, 0);
	return v;
}

/* The thread's area row of roughness s (filled on a miss: a pure function
   of s, so the image does not depend on which thread fills what). */
static const loom__mf_row *area_row(tstate *t, double s)
{
	loom__mf_row *r;

	if (t->rows[t->row_last].s == s)
		return &t->rows[t->row_last];
	for (uint32_t i = 0; i < AREA_ROWS; i++)
		if (t->rows[i].s == s) {
			t->row_last = i;
			return &t->rows[i];
		}
	t->row_last = t->row_next;
	t->row_next = (t->row_next + 1) % AREA_ROWS;
	r = &t->rows[t->row_last];
	loom__mf_row_fill(r, s);
	return r;
}

/* Evaluate the medium at scene point x for direction d.  Returns 0, or the
   lookup's error code. */
static int medium_at(tstate *t, const double x[3], const double d[3], medium *m)
{
	rctx *c = t->c;
	loom_medium_sample ms;
	double v[3], jac[9], w[3], dens;
	int rc, have_jac = 0;

	m->mu = 0;
	m->dens = 0;
	m->surf = 0;
	if (c->shell) {
		if (!loom__shell_map(c->shell, x, &t->hint, v, jac, &t->st.shell_queries))
			return 0;
		have_jac = 1;
		for (int j = 0; j < 2; j++) /* outside a bounded source: empty */
			if (!isinf(c->bnd[j]) && (v[j] < 0 || v[j] >= c->bnd[j]))
				return 0;
		v[2] = clamp_in(v[2], c->bnd[2]);
	} else {
		v[0] = isinf(c->bnd[0]) ? x[0] : clamp_in(x[0], c->bnd[0]);
		v[1] = isinf(c->bnd[1]) ? x[1] : clamp_in(x[1], c->bnd[1]);
		v[2] = clamp_in(x[2], c->bnd[2]);
	}
	memset(&ms, 0, sizeof ms);
	t->st.lookups++;
	if (c->src->lookup_lod && !c->shell) {
		double dx = x[0] - t->fp_o[0], dy = x[1] - t->fp_o[1], dz = x[2] - t->fp_o[2];
		rc = c->src->lookup_lod(t->lctx, v,
		                        t->fp0 + t->fp_rate * sqrt(dx * dx + dy * dy + dz * dz),
		                        &ms);
	} else {
		rc = c->src->lookup(t->lctx, v, &ms);
	}
	if (rc)
		return rc;
	dens = ms.density;
	if (!(dens > 0))
		return 0;
	if (dens > c->dmax)
		dens = c->dmax;
	m->dens = dens;
	for (int j = 0; j < 3; j++) {
		double a = ms.albedo[j];
		m->albedo[j] = a > 0 ? (a < 1 ? a : 1) : 0;
	}
	m->s = ms.alignment > 0 ? ms.alignment : c->o->alignment;
	if (ms.spread > 0) /* fibres averaged by a coarse level: a wider lobe */
		m->s = sqrt(m->s * m->s + ms.spread);
	if (have_jac) {
		for (int j = 0; j < 3; j++)
			w[j] = jac[3 * j] * ms.orient[0] + jac[3 * j + 1] * ms.orient[1] +
			       jac[3 * j + 2] * ms.orient[2];
	} else {
		w[0] = ms.orient[0];
		w[1] = ms.orient[1];
		w[2] = ms.orient[2];
	}
	if (isfinite(w[0] + w[1] + w[2]) && loom__normalize3(w) > 1e-12) {
		memcpy(m->w, w, sizeof w);
		m->mu = dens * c->kscale * loom__mf_row_area(area_row(t, m->s), loom__dot3(d, w));
	} else {
		memset(m->w, 0, sizeof m->w);
		m->mu = dens * c->kscale;
	}
	return 0;
}

/* The source's density alone at slab point x (clamped to the bound as
   medium_at does), for a first test of a tentative collision: its
   extinction is at most dens * kscale * amax in any direction, evaluated in
   medium_at's order so the bound holds after rounding too.  Not counted as
   a lookup (the caller counts one per tentative collision). */
static int density_at(tstate *t, const double x[3], double *dens)
{
	rctx *c = t->c;
	double v[3];
	float f = 0.0f;
	int rc;

	v[0] = isinf(c->bnd[0]) ? x[0] : clamp_in(x[0], c->bnd[0]);
	v[1] = isinf(c->bnd[1]) ? x[1] : clamp_in(x[1], c->bnd[1]);
	v[2] = clamp_in(x[2], c->bnd[2]);
	if ((rc = c->src->density(t->lctx, v, &f)))
		return rc;
	*dens = f > 0 ? (f > c->dmax ? c->dmax : (double)f) : 0.0;
	return 0;
}

/* ---- segments of a ray inside the medium ------------------------------- */

/* Slab: clip (o, d) to the box; returns 1 with [*a, *b] within [0, tmax]. */
static int slab_clip(const rctx *c, const double o[3], const double d[3],
                     double tmax, double *a, double *b)
{
	double t0 = 0, t1 = tmax;
	for (int j = 0; j < 3; j++) {
		double lo, hi;
		if (isinf(c->bnd[j]))
			continue;
		if (d[j] == 0) {
			if (o[j] < 0 || o[j] >= c->bnd[j])
				return 0;
			continue;
		}
		lo = (0 - o[j]) / d[j];
		hi = (c->bnd[j] - o[j]) / d[j];
		if (lo > hi) {
			double tmp = lo;
			lo = hi;
			hi = tmp;
		}
		if (lo > t0)
			t0 = lo;
		if (hi < t1)
			t1 = hi;
	}
	*a = t0;
	*b = t1;
	return t0 < t1;
}

/*
 * Next inside segment [*a, *b] of the ray beyond *cur (and before tmax).
 * Returns 1 and advances *cur, or 0 when there is none.
 */
static int next_segment(tstate *t, const double o[3], const double d[3],
                        double tmax, double *cur, double *a, double *b)
{
	rctx *c = t->c;

	if (!c->shell) {
		if (*cur > 0 || !slab_clip(c, o, d, tmax, a, b)) {
			*cur = tmax;
			return 0;
		}
		*cur = tmax;
		return 1;
	}
	return loom__shell_segment(c->shell, o, d, tmax, cur, a, b);
}

/* ---- majorant grid ----------------------------------------------------- */

void loom__dda_init(loom__dda *g, const double o[3], const double d[3],
                    const int64_t cell[3], double t0, double t1)
{
	for (int j = 0; j < 3; j++) {
		double p = o[j] + t0 * d[j];
		g->cell[j] = (double)cell[j];
		g->o[j] = o[j];
		g->d[j] = d[j];
		g->c[j] = (int64_t)floor(p / g->cell[j]);
		g->step[j] = d[j] > 0 ? 1 : d[j] < 0 ? -1 : 0;
		g->inv[j] = d[j] != 0 ? 1.0 / d[j] : 0.0;
		if (d[j] > 0)
			g->tnext[j] = ((double)(g->c[j] + 1) * g->cell[j] - o[j]) * g->inv[j];
		else if (d[j] < 0)
			g->tnext[j] = ((double)g->c[j] * g->cell[j] - o[j]) * g->inv[j];
		else
			g->tnext[j] = INFINITY;
	}
	g->t = t0;
	g->t1 = t1;
}

/* Majorant (per scene length) of the DDA's current cell: 0 for an empty
   cell, -1 for one outside its column's z span (empty too, and the tracker
   may skip the column's cells up to the span with loom__dda_skip_z), -2
   for one outside its box's z span (loom__dda_skip_box). */
static int cell_majorant(tstate *t, const loom__dda *g, double *mu)
{
	rctx *c = t->c;
	float bound = 0.0f;
	int rc;

	t->st.cells++;
	if (c->zbox) {
		/* above or below everything in the box of columns: no query */
		if (!t->zb_ok || g->c[0] < t->zb[0] || g->c[0] >= t->zb[1] ||
		    g->c[1] < t->zb[2] || g->c[1] >= t->zb[3]) {
			t->zb_ok = 0;
			if ((rc = c->zbox(t->lctx, g->c, t->zb, &t->zb_lo, &t->zb_hi)))
				return rc;
			t->zb_ok = g->c[0] >= t->zb[0] && g->c[0] < t->zb[1] &&
			           g->c[1] >= t->zb[2] && g->c[1] < t->zb[3];
		}
		if (t->zb_ok && (g->c[2] < t->zb_lo || g->c[2] > t->zb_hi)) {
			*mu = -2.0;
			return 0;
		}
	}
	if (c->src->cell_zspan) {
		/* the empty layers above and below the cloth: no bound query */
		if (!t->zs_ok || g->c[0] != t->zs_c[0] || g->c[1] != t->zs_c[1]) {
			t->zs_ok = 0;
			if ((rc = c->src->cell_zspan(t->lctx, g->c, &t->zs_lo, &t->zs_hi)))
				return rc;
			t->zs_c[0] = g->c[0];
			t->zs_c[1] = g->c[1];
			t->zs_ok = 1;
		}
		if (g->c[2] < t->zs_lo || g->c[2] > t->zs_hi) {
			*mu = -1.0; /* empty, and so is the column beyond zs_* */
			return 0;
		}
	}
	if ((rc = c->src->cell_max(t->lctx, g->c, &bound)))
		return rc;
	*mu = bound > 0 ? fmin((double)bound, c->dmax) * c->mu_cell : 0.0;
	return 0;
}

/* After cell_majorant's mu < 0: pass the empty cells beyond the current
   one (its box's, mu = -2, or its column's, mu = -1) and return the exit
   time of the last one passed. */
static inline double skip_empty(const tstate *t, loom__dda *g, double mu)
{
	if (mu < -1.5)
		loom__dda_skip_box(g, t->zb, t->zb_lo, t->zb_hi);
	else
		loom__dda_skip_z(g, t->zs_lo, t->zs_hi);
	return loom__dda_exit(g);
}

/* Exponential optical depth at unit majorant (distance to the next
   tentative collision times the majorant). */
static inline double free_depth(uint64_t *rng)
{
	return -log(1.0 - loom__rand01(rng));
}

/*
 * Delta tracking over [a, b] through the majorant grid: an optical depth
 * tau is drawn once per tentative collision and spent cell by cell at each
 * cell's own majorant (the piecewise-constant majorant's exact free-flight
 * distribution), so an empty cell costs one DDA step and no lookup.
 * Returns as track().
 */
static int track_grid(tstate *t, const double o[3], const double d[3], double a,
                      double b, double pos[3], medium *m)
{
	loom__dda g;
	double tt = a, tau = -log(1.0 - first_u(t));

	loom__dda_init(&g, o, d, t->c->src->cell, a, b);
	for (;;) {
		double te = loom__dda_exit(&g), mu;
		int rc;
		if ((rc = cell_majorant(t, &g, &mu)))
			return -rc;
		if (mu > 0) {
			while (tt + tau / mu < te) {
				tt += tau / mu;
				if (++t->tentative > MAX_TENTATIVE)
					return 0;
				for (int j = 0; j < 3; j++)
					pos[j] = o[j] + tt * d[j];
				if (t->c->dens_first) {
					/* density first: most tentative collisions are
					   rejected by it (the same uniform number and
					   decision as the full test, which needs the
					   fibre direction, so the same image) */
					double dn, xi;
					if ((rc = density_at(t, pos, &dn)))
						return -rc;
					xi = loom__rand01(&t->rng);
					if (xi * mu < dn * t->c->kscale * t->c->amax) {
						if ((rc = medium_at(t, pos, d, m)))
							return -rc;
						if (xi * mu < m->mu)
							return 1;
					} else {
						t->st.lookups++;
					}
				} else {
					if ((rc = medium_at(t, pos, d, m)))
						return -rc;
					if (loom__rand01(&t->rng) * mu < m->mu)
						return 1;
				}
				tau = free_depth(&t->rng);
			}
			tau -= mu * (te - tt);
			if (tau < 0)
				tau = 0;
		} else if (mu < 0) {
			te = skip_empty(t, &g, mu);
		}
		tt = te;
		if (!loom__dda_next(&g))
			return 0;
	}
}

/* Ratio tracking over [a, b] through the grid: *tr is multiplied by the
   segment's estimate (Russian roulette below 0.1 as transmittance()).
   Returns 0 or a negative lookup error. */
static int transmit_grid(tstate *t, const double o[3], const double d[3],
                         double a, double b, double *tr)
{
	loom__dda g;
	double tt = a, tau = -log(1.0 - first_u(t)), p[3];
	medium m;

	loom__dda_init(&g, o, d, t->c->src->cell, a, b);
	for (;;) {
		double te = loom__dda_exit(&g), mu;
		int rc;
		if ((rc = cell_majorant(t, &g, &mu)))
			return -rc;
		if (mu > 0) {
			while (tt + tau / mu < te) {
				tt += tau / mu;
				if (++t->tentative > MAX_TENTATIVE) {
					*tr = 0;
					return 0;
				}
				for (int j = 0; j < 3; j++)
					p[j] = o[j] + tt * d[j];
				m.mu = 0.0;
				if (t->c->dens_first) { /* empty: a factor of 1 */
					double dn;
					if ((rc = density_at(t, p, &dn)))
						return -rc;
					if (dn > 0) {
						if ((rc = medium_at(t, p, d, &m)))
							return -rc;
					} else {
						t->st.lookups++;
					}
				} else if ((rc = medium_at(t, p, d, &m))) {
					return -rc;
				}
				/* fmax: a point rounded into the next cell must not
				   make the estimate negative */
				*tr *= fmax(0.0, 1.0 - m.mu / mu);
				if (*tr < 0.1) {
					if (loom__rand01(&t->rng) < 0.5) {
						*tr = 0;
						return 0;
					}
					*tr *= 2.0;
				}
				tau = free_depth(&t->rng);
			}
			tau -= mu * (te - tt);
			if (tau < 0)
				tau = 0;
		} else if (mu < 0) {
			te = skip_empty(t, &g, mu);
		}
		tt = te;
		if (!loom__dda_next(&g))
			return 0;
	}
}

/* ---- tracking ---------------------------------------------------------- */

/*
 * Delta tracking from o along d up to tmax.  Returns 1 at a real collision
 * (position in pos, medium in *m), 0 when the ray leaves, or a negative
 * lookup error (-code).
 */
static int track(tstate *t, const double o[3], const double d[3], double tmax,
                 double pos[3], medium *m)
{
	rctx *c = t->c;
	double cur = 0, a, b;

	if (!(c->mu_bar > 0))
		return 0;
	while (next_segment(t, o, d, tmax, &cur, &a, &b)) {
		double tt = a;
		int first = 1;
		if (c->grid) {
			int r = track_grid(t, o, d, a, b, pos, m);
			if (r)
				return r;
			continue;
		}
		for (;;) {
			int rc;
			tt -= log(1.0 - (first ? first_u(t) : loom__rand01(&t->rng))) / c->mu_bar;
			first = 0;
			if (tt >= b)
				break;
			if (++t->tentative > MAX_TENTATIVE)
				return 0;
			for (int j = 0; j < 3; j++)
				pos[j] = o[j] + tt * d[j];
			if ((rc = medium_at(t, pos, d, m)))
				return -rc;
			if (loom__rand01(&t->rng) * c->mu_bar < m->mu)
				return 1;
		}
	}
	return 0;
}

/* Ratio-tracking transmittance along (o, d) over [0, tmax]; returns 0 or a
   negative lookup error. */
static int transmittance(tstate *t, const double o[3], const double d[3],
                         double tmax, double *T)
{
	rctx *c = t->c;
	double cur = 0, a, b, tr = 1.0, p[3];
	medium m;

	*T = 1.0;
	if (c->o->ground.enabled && loom__ground_hit(&c->o->ground, o, d) < tmax) {
		*T = 0.0; /* the floor is opaque */
		return 0;
	}
	if (!(c->mu_bar > 0))
		return 0;
	while (next_segment(t, o, d, tmax, &cur, &a, &b)) {
		double tt = a;
		if (c->grid) {
			int rc = transmit_grid(t, o, d, a, b, &tr);
			if (rc)
				return rc;
			if (tr == 0) {
				*T = 0;
				return 0;
			}
			continue;
		}
		int first = 1;
		for (;;) {
			int rc;
			tt -= log(1.0 - (first ? first_u(t) : loom__rand01(&t->rng))) / c->mu_bar;
			first = 0;
			if (tt >= b)
				break;
			if (++t->tentative > MAX_TENTATIVE) {
				*T = 0;
				return 0;
			}
			for (int j = 0; j < 3; j++)
				p[j] = o[j] + tt * d[j];
			if ((rc = medium_at(t, p, d, &m)))
				return -rc;
			tr *= 1.0 - m.mu / c->mu_bar;
			if (tr < 0.1) { /* Russian roulette, unbiased */
				if (loom__rand01(&t->rng) < 0.5) {
					*T = 0;
					return 0;
				}
				tr *= 2.0;
			}
		}
	}
	*T = tr;
	return 0;
}

/* ---- one path ---------------------------------------------------------- */

/* Camera ray through image point (sx, sy) in [0,1)^2.  A thin lens draws
   two more numbers from rng (a pinhole none, so aperture 0 gives the
   pinhole's bytes): a point uniform on the lens disc, aimed at where the
   pinhole ray meets the plane in focus. */
static int camera_ray(tstate *t, double sx, double sy, double o[3], double d[3])
{
	const rctx *c = t->c;
	const loom_camera *cam = &c->o->camera;
	if (cam->kind == LOOM_CAMERA_ORTHO) {
		double ox = (sx - 0.5) * cam->ortho_size[0];
		double oy = (0.5 - sy) * cam->ortho_size[1];
		for (int j = 0; j < 3; j++) {
			o[j] = c->eye[j] + ox * c->right[j] + oy * c->up[j];
			d[j] = c->fwd[j];
		}
	} else {
		for (int j = 0; j < 3; j++) {
			o[j] = c->eye[j];
			d[j] = c->fwd[j] + (2 * sx - 1) * c->tan_x * c->right[j] +
			       (1 - 2 * sy) * c->tan_y * c->up[j];
		}
		if (c->lens_r > 0) {
			/* d . fwd = 1 here: the focus point is eye + focus d */
			double r = c->lens_r * sqrt(draw(t, D_LENS));
			double ph = 2.0 * M_PI * draw(t, D_LENS + 1);
			double lx = r * cos(ph), ly = r * sin(ph);
			for (int j = 0; j < 3; j++) {
				double fp = c->eye[j] + c->focus * d[j];
				o[j] = c->eye[j] + lx * c->right[j] + ly * c->up[j];
				d[j] = fp - o[j];
			}
		}
		loom__normalize3(d);
	}
	return 0;
}

/* A direction uniform in solid angle over the cone of half angle
   acos(cos_max) around unit axis (frame u, v), from dimensions dim and
   dim + 1 of the sample. */
static void cone_direction(tstate *t, const double axis[3], const double u[3],
                           const double v[3], double cos_max, uint32_t dim,
                           double wl[3])
{
	double ct = 1.0 - draw(t, dim) * (1.0 - cos_max);
	double st = sqrt(fmax(0.0, 1.0 - ct * ct));
	double ph = 2.0 * M_PI * draw(t, dim == NO_DIM ? NO_DIM : dim + 1);
	for (int j = 0; j < 3; j++)
		wl[j] = ct * axis[j] + st * (cos(ph) * u[j] + sin(ph) * v[j]);
	loom__normalize3(wl);
}

/* Unit vectors u, v completing unit a to an orthonormal frame. */
static void frame_of(const double a[3], double u[3], double v[3])
{
	double t[3] = {0, 0, 0};
	t[fabs(a[0]) < 0.6 ? 0 : fabs(a[1]) < 0.6 ? 1 : 2] = 1.0;
	loom__cross3(a, t, u);
	loom__normalize3(u);
	loom__cross3(a, u, v);
}

/* The phase function at a collision, the Lambertian lobe on the ground
   (both exact samplers: pdf = value). */
static double scat_eval(const medium *m, const double wi[3], const double wo[3])
{
	return m->surf ? loom__lambert_eval(m->n, wo)
	               : loom_microflake_eval(m->s, m->w, wi, wo);
}

static void scat_sample(const medium *m, const double wi[3], uint64_t *rng,
                        double wo[3])
{
	if (m->surf)
		loom__lambert_sample(m->n, rng, wo);
	else
		loom_microflake_sample(m->s, m->w, wi, rng, wo);
}

/*
 * Next-event estimation of one light from a real collision at pos (medium
 * m, wi towards where the path came from): adds beta x the estimate to L.
 * Distant lights with a disc and spheres draw a direction uniform in
 * solid angle over the disc / the cone the sphere subtends (radiance is
 * uniform over either), so irradiance-per-solid-angle x phase x
 * transmittance over the cone's pdf is unbiased.  Returns 0 or a negative
 * lookup error.
 */
static int light_nee(tstate *t, const plight *p, const medium *m,
                     const double pos[3], const double wi[3],
                     const double beta[3], uint32_t dim, double L[3])
{
	const loom_light *l = p->l;
	double wl[3], dist = INFINITY, scale = 1.0, T, f;
	int rc;

	if (l->kind == LOOM_LIGHT_DISTANT && p->cos_disc < 1.0) {
		cone_direction(t, p->dir, p->u, p->v, p->cos_disc, dim, wl);
	} else if (l->kind == LOOM_LIGHT_DISTANT) {
		memcpy(wl, p->dir, sizeof wl);
	} else if (l->kind == LOOM_LIGHT_POINT) {
		for (int j = 0; j < 3; j++)
			wl[j] = l->pos[j] - pos[j];
		dist = loom__normalize3(wl);
		scale = dist > 0 ? 1.0 / (dist * dist) : 0.0;
	} else { /* sphere */
		double a[3], u[3], v[3], dc, r = l->radius, cmax, ct, disc;
		for (int j = 0; j < 3; j++)
			a[j] = l->pos[j] - pos[j];
		dc = loom__normalize3(a);
		if (!(dc > r)) /* inside the light: it lights nothing here */
			return 0;
		cmax = sqrt(fmax(0.0, 1.0 - (r / dc) * (r / dc)));
		frame_of(a, u, v);
		cone_direction(t, a, u, v, cmax, dim, wl);
		ct = loom__dot3(wl, a);
		disc = r * r - dc * dc * fmax(0.0, 1.0 - ct * ct);
		dist = dc * ct - sqrt(fmax(0.0, disc));
		/* radiance I / (pi r^2) over the cone's pdf 1 / (2 pi (1 - cmax)) */
		scale = 2.0 * (1.0 - cmax) / (r * r);
	}
	f = scat_eval(m, wi, wl);
	if (scale > 0 && f > 0) {
		t->st.rays++;
		t->ld_flight = dim == NO_DIM ? NO_DIM : dim - D_LIGHT + D_LIGHT_T;
		if ((rc = transmittance(t, pos, wl, dist, &T)))
			return rc;
		for (int j = 0; j < 3; j++)
			L[j] += beta[j] * l->rgb[j] * scale * T * f;
	}
	return 0;
}

/* The floor hit at distance tg along (org, dir) as an event: a Lambertian
   surface facing the ray (position exactly on the plane, so rays leaving
   it do not hit it again). */
static void ground_event(const loom_ground *g, const double org[3],
                         const double dir[3], double tg, double pos[3], medium *m)
{
	memset(m, 0, sizeof *m);
	for (int j = 0; j < 3; j++) {
		pos[j] = org[j] + tg * dir[j];
		m->albedo[j] = g->albedo[j];
	}
	pos[2] = g->height;
	m->surf = 1;
	m->n[2] = dir[2] < 0 ? 1.0 : -1.0;
}

/* The AOVs of a camera ray's first event at pos: albedo, depth and the
   normal (the plane's, or from the density gradient by central
   differences one voxel apart).  Lookups only: the path's random numbers
   and so the beauty image are unchanged.  Returns 0 or a lookup error. */
static int first_event(tstate *t, const double org[3], const double dir[3],
                       const double pos[3], const medium *m, loom__aov_hit *h)
{
	double g[3] = {0, 0, 0}, d2 = 0;
	uint32_t hint = t->hint;

	h->hit = 1;
	for (int j = 0; j < 3; j++) {
		h->albedo[j] = m->albedo[j];
		d2 += (pos[j] - org[j]) * (pos[j] - org[j]);
	}
	h->depth = sqrt(d2);
	if (m->surf) {
		memcpy(h->normal, m->n, sizeof h->normal);
		return 0;
	}
	for (int j = 0; j < 3; j++) {
		for (int k = -1; k <= 1; k += 2) {
			double p[3] = {pos[0], pos[1], pos[2]};
			medium q;
			int rc;
			p[j] += k * t->c->len_voxel;
			if ((rc = medium_at(t, p, dir, &q)))
				return rc;
			g[j] += k * q.dens;
		}
	}
	t->hint = hint;
	loom__aov_normal(g, dir, h->normal);
	return 0;
}

/* Radiance of one camera sample; returns 0 or a lookup error code.  h (may
   be NULL) receives the first event's AOVs. */
static int trace_path(tstate *t, double sx, double sy, double L[3],
                      loom__aov_hit *h)
{
	rctx *c = t->c;
	const loom_render_options *o = c->o;
	double org[3], dir[3], pos[3], beta[3] = {1, 1, 1}, phase_pdf = 0;
	uint32_t depth = 0;
	medium m;

	L[0] = L[1] = L[2] = 0;
	if (h)
		h->hit = 0;
	t->tentative = 0;
	t->hint = LOOM_MESH_NONE;
	camera_ray(t, sx, sy, org, dir);
	memcpy(t->fp_o, org, sizeof t->fp_o);
	if (o->camera.kind == LOOM_CAMERA_ORTHO) {
		t->fp0 = o->camera.ortho_size[1] / o->height;
		t->fp_rate = 0;
	} else {
		t->fp0 = 0;
		t->fp_rate = 2 * c->tan_y / o->height;
	}
	t->st.paths++;
	for (;;) {
		int r;
		double wi[3], wo[3];
		double tg = o->ground.enabled ? loom__ground_hit(&o->ground, org, dir)
		                              : INFINITY;

		t->st.rays++;
		t->ld_flight = dim_at(depth, D_FLIGHT);
		r = track(t, org, dir, tg, pos, &m);
		if (r < 0)
			return -r;
		if (r == 0 && tg < INFINITY) {
			ground_event(&o->ground, org, dir, tg, pos, &m);
			r = 1;
		}
		if (r == 0) {
			if (o->envmap) {
				/* weighted against environment sampling when the path
				   scattered (its direction had the phase pdf) */
				double le[3], wgt = 1.0;
				loom_envmap_eval(o->envmap, dir, le);
				if (depth > 0)
					wgt = loom_mis_power(phase_pdf,
					                     loom_envmap_pdf(o->envmap, dir));
				for (int j = 0; j < 3; j++)
					L[j] += beta[j] * le[j] * wgt;
			} else {
				for (int j = 0; j < 3; j++)
					L[j] += beta[j] * o->env[j];
			}
			return 0;
		}
		if (depth == 0 && h && (r = first_event(t, org, dir, pos, &m, h)))
			return r;
		depth++;
		t->st.scatterings++;
		if (depth == 1) { /* later rays keep the first event's footprint */
			double dx = pos[0] - t->fp_o[0], dy = pos[1] - t->fp_o[1],
			       dz = pos[2] - t->fp_o[2];
			t->fp0 += t->fp_rate * sqrt(dx * dx + dy * dy + dz * dz);
			t->fp_rate = 0;
		}
		for (int j = 0; j < 3; j++) {
			beta[j] *= m.albedo[j];
			wi[j] = -dir[j];
		}
		if (beta[0] == 0 && beta[1] == 0 && beta[2] == 0)
			return 0;
		/* Next-event estimation of every light. */
		for (uint32_t k = 0; k < c->n_pl; k++) {
			int rc = light_nee(t, &c->pl[k], &m, pos, wi, beta,
			                   k == 0 ? dim_at(depth - 1, D_LIGHT) : NO_DIM, L);
			if (rc)
				return -rc;
		}
		/* Next-event estimation of the environment map, weighted
		   against phase sampling (the phase pdf is f itself). */
		if (o->envmap) {
			double wl[3], T, f, pe, le[3], wgt;
			int rc;
			double u1 = draw(t, dim_at(depth - 1, D_ENV));
			double u2 = draw(t, dim_at(depth - 1, D_ENV + 1));
			pe = loom_envmap_sample(o->envmap, u1, u2, wl);
			if (pe > 0) {
				f = scat_eval(&m, wi, wl);
				if (f > 0) {
					t->st.rays++;
					t->ld_flight = dim_at(depth - 1, D_ENV_T);
					if ((rc = transmittance(t, pos, wl, INFINITY, &T)))
						return -rc;
					loom_envmap_eval(o->envmap, wl, le);
					wgt = loom_mis_power(pe, f) / pe;
					for (int j = 0; j < 3; j++)
						L[j] += beta[j] * le[j] * f * T * wgt;
				}
			}
		}
		if (depth >= o->max_depth)
			return 0;
		if (depth >= o->rr_depth) {
			double q = fmax(beta[0], fmax(beta[1], beta[2]));
			if (q < 1.0) {
				if (loom__rand01(&t->rng) >= q)
					return 0;
				for (int j = 0; j < 3; j++)
					beta[j] /= q;
			}
		}
		scat_sample(&m, wi, &t->rng, wo);
		if (o->envmap)
			phase_pdf = scat_eval(&m, wi, wo);
		memcpy(org, pos, sizeof org);
		memcpy(dir, wo, sizeof dir);
	}
}

/* ---- workers ----------------------------------------------------------- */

static uint64_t hash64(uint64_t x)
{
	x ^= x >> 33;
	x *= 0xff51afd7ed558ccdull;
	x ^= x >> 33;
	x *= 0xc4ceb9fe1a85ec53ull;
	x ^= x >> 33;
	return x;
}

/* One pixel's sums over the samples taken so far. */
typedef struct pixacc {
	double sum[3];            /* radiance (non-finite samples count 0) */
	double sy2;               /* sum of squared luminances */
	uint32_t n;               /* samples taken */
	uint32_t done;            /* adaptive: the pixel has converged */
	loom__aov_acc aov;        /* AOV sums (used when o->aov is set) */
} pixacc;

static const double LUM[3] = {0.2126, 0.7152, 0.0722}; /* Rec. 709 */

/* Adaptive sampling's test, from the pixel's own samples only: the
   standard error of its mean luminance at most `noise` times that mean
   (radiance is >= 0, so a zero mean has zero variance and stops). */
static int converged(const pixacc *a, double noise)
{
	double n = (double)a->n;
	double sy = LUM[0] * a->sum[0] + LUM[1] * a->sum[1] + LUM[2] * a->sum[2];
	double mean = sy / n, var = (a->sy2 - sy * mean) / (n - 1.0);
	return sqrt(fmax(var, 0.0) / n) <= noise * mean;
}

/*
 * Samples a->n, a->n + 1, ... of pixel (x, y) until k1 (or, adaptive,
 * until the test passes at a multiple of 8 samples from 16 on).  Sample k
 * seeds its splitmix64 stream with hash(seed, pixel, k) and its Sobol
 * point with (hash(seed, pixel), k); sums run in sample order.  So a
 * pixel's value depends on nothing but its own samples: not the thread,
 * the tile order or the passes.  Returns 0 or a lookup error code.
 */
static int render_pixel(tstate *t, uint32_t x, uint32_t y, uint32_t k1, pixacc *a)
{
	rctx *c = t->c;
	const loom_render_options *o = c->o;
	uint64_t pix = (uint64_t)y * o->width + x;
	uint64_t pseed = hash64(o->seed ^ hash64(pix * 0xc2b2ae3d27d4eb4full + 0x27bb2ee687b0b0fdull));

	while (a->n < k1 && !a->done) {
		double L[3], jx, jy, lum = 0;
		loom__aov_hit ah;
		uint32_t k = a->n;
		int rc;
		t->rng = hash64(o->seed ^ hash64(pix * 0x9e3779b97f4a7c15ull + k + 1));
		loom__ld_start(&t->ld, pseed, k);
		jx = draw(t, D_PIXEL);
		jy = draw(t, D_PIXEL + 1);
		rc = trace_path(t, (x + jx) / o->width, (y + jy) / o->height, L,
		                o->aov ? &ah : NULL);
		if (rc)
			return rc;
		if (o->aov)
			loom__aov_add(&a->aov, L, &ah);
		for (int j = 0; j < 3; j++) {
			double v = isfinite(L[j]) ? L[j] : 0.0;
			a->sum[j] += v;
			lum += LUM[j] * v;
		}
		a->sy2 += lum * lum;
		a->n++;
		if (o->noise > 0 && a->n >= 16 && a->n % 8 == 0 && converged(a, o->noise))
			a->done = 1;
	}
	return 0;
}

/* The pixel's image value and sample count from its sums. */
static void finish_pixel(const rctx *c, uint64_t pix, const pixacc *a)
{
	for (int j = 0; j < 3; j++)
		c->rgb[3 * pix + j] = a->n ? (float)(a->sum[j] / a->n) : 0.0f;
	if (c->o->samples)
		c->o->samples[pix] = a->n;
	if (c->o->aov)
		loom__aov_store(&a->aov, c->o->aov, pix);
}

/* Pass p of one tile. */
static int render_tile(tstate *t, uint64_t tile, uint32_t p)
{
	rctx *c = t->c;
	const loom_render_options *o = c->o;
	uint32_t tx = (uint32_t)(tile % c->tiles_x), ty = (uint32_t)(tile / c->tiles_x);
	uint32_t x0 = tx * c->tile, y0 = ty * c->tile;
	uint32_t x1 = x0 + c->tile < o->width ? x0 + c->tile : o->width;
	uint32_t y1 = y0 + c->tile < o->height ? y0 + c->tile : o->height;

	for (uint32_t y = y0; y < y1; y++) {
		if (atomic_load(&c->error))
			return 0;
		for (uint32_t x = x0; x < x1; x++) {
			uint64_t pix = (uint64_t)y * o->width + x;
			pixacc a;
			int rc;
			if (c->acc)
				a = c->acc[pix]; /* only this thread writes it now */
			else
				memset(&a, 0, sizeof a);
			rc = render_pixel(t, x, y, c->pass_end[p], &a);
			if (rc) {
				int expected = 0;
				atomic_compare_exchange_strong(&c->error, &expected, rc);
				return rc;
			}
			if (c->acc) {
				/* the progressive snapshot reads under the lock */
				pthread_mutex_lock(&c->lock);
				c->acc[pix] = a;
				pthread_mutex_unlock(&c->lock);
			} else {
				finish_pixel(c, pix, &a);
			}
		}
	}
	return 0;
}

/* Wait until every worker has finished the pass. */
static void pass_barrier(rctx *c)
{
	pthread_mutex_lock(&c->lock);
	uint64_t gen = c->bar_gen;
	if (++c->bar_count >= c->n_workers) {
		c->bar_count = 0;
		c->bar_gen++;
		pthread_cond_broadcast(&c->bar_cv);
	} else {
		while (gen == c->bar_gen)
			pthread_cond_wait(&c->bar_cv, &c->lock);
	}
	pthread_mutex_unlock(&c->lock);
}

static void *worker(void *arg)
{
	tstate *t = arg;
	rctx *c = t->c;
	int ok = 1;

#if defined(__x86_64__) || defined(__i386__)
	_mm_setcsr(_mm_getcsr() | 0x8040); /* FTZ | DAZ */
#endif
	for (uint32_t i = 0; i < AREA_ROWS; i++)
		t->rows[i].s = -1.0; /* no roughness is negative */
	t->lctx = c->src->ctx;
	if (c->src->thread_init) {
		t->lctx = c->src->thread_init(c->src->ctx);
		if (!t->lctx) {
			int expected = 0;
			atomic_compare_exchange_strong(&c->error, &expected, LOOM_ENOMEM);
			ok = 0;
		}
	}
	for (uint32_t p = 0; p < c->n_passes; p++) {
		uint32_t len = c->pass_end[p] - (p ? c->pass_end[p - 1] : 0);
		while (ok) {
			uint64_t tile = atomic_fetch_add(&c->next_in_pass[p], 1);
			if (tile >= c->n_tiles || atomic_load(&c->error))
				break;
			if (render_tile(t, tile, p)) {
				ok = 0;
				break;
			}
			if (c->o->progress) {
				/* in tiles of the whole render: each tile's share of
				   the samples */
				pthread_mutex_lock(&c->lock);
				c->work_done += len;
				c->o->progress(c->o->progress_user, c->work_done / c->o->spp,
				               c->n_tiles);
				pthread_mutex_unlock(&c->lock);
			}
		}
		if (c->n_passes > 1)
			pass_barrier(c); /* every worker passes every barrier */
	}
	if (c->src->thread_init && c->src->thread_done && t->lctx)
		c->src->thread_done(c->src->ctx, t->lctx);
	pthread_mutex_lock(&c->lock);
	c->running--;
	pthread_cond_broadcast(&c->done_cv);
	pthread_mutex_unlock(&c->lock);
	return NULL;
}

/* The image so far into c->rgb (and the sample counts); call with
   c->lock held while workers run. */
static void snapshot(rctx *c)
{
	uint64_t n = (uint64_t)c->o->width * c->o->height;
	for (uint64_t i = 0; i < n; i++)
		finish_pixel(c, i, &c->acc[i]);
}

/* ---- setup ------------------------------------------------------------- */

static int finite3(const double v[3])
{
	return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static int setup_camera(rctx *c, loom_diag *diag)
{
	const loom_camera *cam = &c->o->camera;
	double f[3], r[3], u[3], dist;

	if (cam->kind != LOOM_CAMERA_ORTHO && cam->kind != LOOM_CAMERA_PINHOLE)
		return loom__fail(diag, LOOM_EINVAL, "render: unknown camera kind %d",
		                  cam->kind);
	if (!finite3(cam->eye) || !finite3(cam->target) || !finite3(cam->up))
		return loom__fail(diag, LOOM_EINVAL, "render: camera vectors must be finite");
	for (int j = 0; j < 3; j++)
		f[j] = cam->target[j] - cam->eye[j];
	if ((dist = loom__normalize3(f)) <= 0)
		return loom__fail(diag, LOOM_EINVAL, "render: camera target equals eye");
	loom__cross3(f, cam->up, r);
	if (loom__normalize3(r) < 1e-9)
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: camera up is zero or parallel to the view direction");
	loom__cross3(r, f, u);
	memcpy(c->eye, cam->eye, sizeof c->eye);
	memcpy(c->fwd, f, sizeof f);
	memcpy(c->right, r, sizeof r);
	memcpy(c->up, u, sizeof u);
	if (cam->kind == LOOM_CAMERA_PINHOLE) {
		if (!(cam->fov_y_deg > 0 && cam->fov_y_deg < 180))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: fov_y_deg must be in (0, 180), got %g",
			                  cam->fov_y_deg);
		c->tan_y = tan(cam->fov_y_deg * M_PI / 360.0);
		c->tan_x = c->tan_y * c->o->width / c->o->height;
		if (!(cam->aperture >= 0) || !isfinite(cam->aperture) ||
		    !(cam->focus_dist >= 0) || !isfinite(cam->focus_dist))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: aperture and focus_dist must be finite and "
			                  ">= 0, got %g and %g", cam->aperture, cam->focus_dist);
		c->lens_r = 0.5 * cam->aperture;
		c->focus = cam->focus_dist > 0 ? cam->focus_dist : dist;
	} else if (cam->aperture != 0) {
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: an orthographic camera has no lens (aperture %g)",
		                  cam->aperture);
	} else if (!(cam->ortho_size[0] > 0 && cam->ortho_size[1] > 0 &&
	             isfinite(cam->ortho_size[0]) && isfinite(cam->ortho_size[1]))) {
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: ortho_size must be > 0, got %g x %g",
		                  cam->ortho_size[0], cam->ortho_size[1]);
	}
	return LOOM_OK;
}

static int check_options(const loom_volume_source *src, const loom_render_options *o,
                         loom_diag *diag)
{
	if (src->size < offsetof(loom_volume_source, cell_zbox))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: source size %zu, expected %zu (use "
		                  "LOOM_VOLUME_SOURCE_INIT)", src->size,
		                  sizeof(loom_volume_source));
	if (o->size < sizeof(loom_render_options))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: options size %zu, expected %zu (use "
		                  "LOOM_RENDER_OPTIONS_INIT)", o->size,
		                  sizeof(loom_render_options));
	if (!src->lookup)
		return loom__fail(diag, LOOM_EINVAL, "render: the source has no lookup");
	if (src->nz <= 0 || src->nx < 0 || src->ny < 0)
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: source extent %lld x %lld x %lld: nz must be "
		                  "> 0, nx and ny >= 0 (0 = unbounded)",
		                  (long long)src->nx, (long long)src->ny, (long long)src->nz);
	if (!(src->max_density >= 0) || !isfinite(src->max_density))
		return loom__fail(diag, LOOM_EINVAL, "render: max_density must be >= 0");
	if (o->width < 1 || o->height < 1 || o->width > 65536 || o->height > 65536)
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: image %u x %u, each side must be 1..65536",
		                  o->width, o->height);
	if (o->spp < 1 || o->max_depth < 1)
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: spp (%u) and max_depth (%u) must be >= 1",
		                  o->spp, o->max_depth);
	if (!(o->density_scale >= 0) || !isfinite(o->density_scale))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: density_scale must be finite and >= 0, got %g",
		                  o->density_scale);
	if (!(o->alignment > 0) || !isfinite(o->alignment))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: alignment must be > 0, got %g", o->alignment);
	for (int j = 0; j < 3; j++)
		if (!(o->env[j] >= 0) || !isfinite(o->env[j]))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: env and light colours must be finite and >= 0");
	if (!(o->world_per_voxel >= 0) || !isfinite(o->world_per_voxel))
		return loom__fail(diag, LOOM_EINVAL, "render: world_per_voxel must be >= 0");
	if (o->sampler != LOOM_SAMPLER_SOBOL && o->sampler != LOOM_SAMPLER_RANDOM)
		return loom__fail(diag, LOOM_EINVAL, "render: unknown sampler %u", o->sampler);
	if (!(o->noise >= 0) || !isfinite(o->noise))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: noise must be finite and >= 0 (0 = off), got %g",
		                  o->noise);
	if (!(o->progressive_seconds >= 0) || !isfinite(o->progressive_seconds) ||
	    (o->progressive_seconds > 0 && !o->progressive))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: progressive_seconds must be finite and >= 0, "
		                  "and > 0 only with a progressive callback, got %g",
		                  o->progressive_seconds);
	return LOOM_OK;
}

/* Check light l and prepare it for sampling. */
static int prep_light(const loom_light *l, plight *p, loom_diag *diag)
{
	memset(p, 0, sizeof *p);
	p->l = l;
	p->cos_disc = 1.0;
	for (int j = 0; j < 3; j++)
		if (!(l->rgb[j] >= 0) || !isfinite(l->rgb[j]))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: env and light colours must be finite and >= 0");
	switch (l->kind) {
	case LOOM_LIGHT_DISTANT:
		memcpy(p->dir, l->dir, sizeof p->dir);
		if (!finite3(p->dir) || loom__normalize3(p->dir) <= 0)
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: distant light direction must be finite and non-zero");
		if (!(l->angle_deg >= 0 && l->angle_deg <= 90))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: distant light angle_deg must be in [0, 90], got %g",
			                  l->angle_deg);
		frame_of(p->dir, p->u, p->v);
		if (l->angle_deg > 0)
			p->cos_disc = cos(0.5 * l->angle_deg * M_PI / 180.0);
		return LOOM_OK;
	case LOOM_LIGHT_POINT:
		if (!finite3(l->pos))
			return loom__fail(diag, LOOM_EINVAL, "render: point light position must be finite");
		return LOOM_OK;
	case LOOM_LIGHT_SPHERE:
		if (!finite3(l->pos) || !(l->radius > 0) || !isfinite(l->radius))
			return loom__fail(diag, LOOM_EINVAL,
			                  "render: sphere light needs a finite position and a "
			                  "radius > 0, got radius %g", l->radius);
		return LOOM_OK;
	default:
		return loom__fail(diag, LOOM_EINVAL, "render: unknown light kind %d", l->kind);
	}
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

LOOM_API int loom_render(const loom_volume_source *src,
                         const loom_render_options *o, float *rgb,
                         loom_render_stats *stats, loom_diag *diag)
{
	rctx c;
	tstate *ts;
	pthread_t *th;
	uint32_t nthreads, started = 0;
	double t0 = now_s();
	int rc;

	if (stats)
		memset(stats, 0, sizeof *stats);
	if (!src || !o || !rgb)
		return loom__fail(diag, LOOM_EINVAL, "loom_render: NULL argument");
	if ((rc = check_options(src, o, diag)))
		return rc;
	memset(&c, 0, sizeof c);
	c.src = src;
	c.o = o;
	c.shell = o->shell;
	c.rgb = rgb;
	c.len_voxel = 1.0;
	if ((rc = setup_camera(&c, diag)))
		return rc;
	if ((rc = loom__ground_check(&o->ground, diag)))
		return rc;
	if (c.shell) {
		if (loom__shell_failed(c.shell))
			return loom__fail(diag, LOOM_EUNUSABLE, "render: the shell hit an Embree error");
		if (loom__shell_nz(c.shell) != src->nz)
			return loom__fail(diag, LOOM_EMISMATCH,
			                  "render: the shell was built for nz = %lld, the "
			                  "source has nz = %lld",
			                  (long long)loom__shell_nz(c.shell), (long long)src->nz);
		c.len_voxel = o->world_per_voxel > 0 ? o->world_per_voxel
		                                     : loom_shell_voxel_length(c.shell);
	}
	c.bnd[0] = src->nx > 0 ? (double)src->nx : INFINITY;
	c.bnd[1] = src->ny > 0 ? (double)src->ny : INFINITY;
	c.bnd[2] = (double)src->nz;
	c.dmax = src->max_density > 0 ? src->max_density : 1.0;
	c.kscale = o->density_scale / c.len_voxel;
	c.mu_bar = c.dmax * c.kscale * loom_microflake_area_max();
	c.mu_cell = c.kscale * loom_microflake_area_max();
	c.amax = loom_microflake_area_max();
	c.grid = !c.shell && src->cell_max && !(o->flags & LOOM_RENDER_GLOBAL_MAJORANT);
	c.dens_first = src->density && !(src->lookup_lod && !c.shell);
	if (src->size >= offsetof(loom_volume_source, cell_zbox) + sizeof src->cell_zbox &&
	    src->cell_zspan)
		c.zbox = src->cell_zbox;
	if (c.grid && !(src->cell[0] > 0 && src->cell[1] > 0 && src->cell[2] > 0))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: the source's majorant cell is %lld x %lld x %lld; "
		                  "each side must be > 0", (long long)src->cell[0],
		                  (long long)src->cell[1], (long long)src->cell[2]);
	if (o->n_lights > LOOM_RENDER_MAX_LIGHTS || (o->n_lights && !o->lights))
		return loom__fail(diag, LOOM_EINVAL,
		                  "render: n_lights %u: at most %u, with lights != NULL",
		                  o->n_lights, LOOM_RENDER_MAX_LIGHTS);
	for (uint32_t k = 0; k <= o->n_lights; k++) {
		const loom_light *l = k == 0 ? &o->light : &o->lights[k - 1];
		if (l->kind == LOOM_LIGHT_NONE)
			continue;
		if ((rc = prep_light(l, &c.pl[c.n_pl], diag)))
			return rc;
		c.n_pl++;
	}
	c.tile = o->tile ? o->tile : 16;
	c.tiles_x = (o->width + c.tile - 1) / c.tile;
	c.tiles_y = (o->height + c.tile - 1) / c.tile;
	c.n_tiles = (uint64_t)c.tiles_x * c.tiles_y;
	atomic_init(&c.error, 0);
	c.sobol = o->sampler == LOOM_SAMPLER_SOBOL;
	/* progressive: passes ending at 1, 2, 4, ... samples, so the image
	   sharpens everywhere at once; otherwise one pass of spp */
	c.n_passes = 0;
	if (o->progressive_seconds > 0)
		for (uint32_t e = 1; e < o->spp; e *= 2)
			c.pass_end[c.n_passes++] = e;
	c.pass_end[c.n_passes++] = o->spp;
	for (uint32_t p = 0; p < c.n_passes; p++)
		atomic_init(&c.next_in_pass[p], 0);
	if (c.n_passes > 1) {
		c.acc = calloc((size_t)o->width * o->height, sizeof *c.acc);
		if (!c.acc)
			return loom__fail(diag, LOOM_ENOMEM, "render: out of memory for "
			                  "the progressive sums (%u x %u pixels)",
			                  o->width, o->height);
	}

	nthreads = o->threads;
	if (nthreads == 0) {
		long n = sysconf(_SC_NPROCESSORS_ONLN);
		nthreads = n > 0 ? (uint32_t)n : 1;
	}
	if (nthreads > MAX_THREADS)
		nthreads = MAX_THREADS;
	if (nthreads > c.n_tiles)
		nthreads = (uint32_t)c.n_tiles;
	ts = aligned_alloc(64, nthreads * sizeof *ts);
	th = calloc(nthreads, sizeof *th);
	if (ts)
		memset(ts, 0, nthreads * sizeof *ts);
	if (!ts || !th) {
		free(ts);
		free(th);
		free(c.acc);
		return loom__fail(diag, LOOM_ENOMEM, "render: out of memory");
	}
	pthread_mutex_init(&c.lock, NULL);
	pthread_cond_init(&c.bar_cv, NULL);
	{
		pthread_condattr_t ca;
		pthread_condattr_init(&ca);
		pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
		pthread_cond_init(&c.done_cv, &ca);
		pthread_condattr_destroy(&ca);
	}
	(void)loom_microflake_area_max(); /* build the tables before threads */
	(void)loom__sobol32(0, 0);        /* and the Sobol directions */
	c.n_workers = c.running = nthreads;
	for (uint32_t i = 0; i < nthreads; i++) {
		ts[i].c = &c;
		if (pthread_create(&th[i], NULL, worker, &ts[i]) != 0)
			break;
		started++;
	}
	if (started < nthreads) {
		/* fewer workers: the barrier and the wait count those started */
		pthread_mutex_lock(&c.lock);
		c.n_workers = c.running = started;
		if (started && c.bar_count >= started) {
			c.bar_count = 0;
			c.bar_gen++;
			pthread_cond_broadcast(&c.bar_cv);
		}
		pthread_mutex_unlock(&c.lock);
	}
	if (o->progressive_seconds > 0 && started && c.acc) {
		/* every progressive_seconds, the image so far to the callback
		   (from this thread, while the workers go on) */
		double next = now_s() + o->progressive_seconds;
		pthread_mutex_lock(&c.lock);
		while (c.running > 0) {
			struct timespec dl;
			dl.tv_sec = (time_t)floor(next);
			dl.tv_nsec = (long)((next - floor(next)) * 1e9);
			pthread_cond_timedwait(&c.done_cv, &c.lock, &dl);
			if (c.running == 0 || atomic_load(&c.error))
				break;
			if (now_s() >= next) {
				snapshot(&c);
				pthread_mutex_unlock(&c.lock);
				o->progressive(o->progressive_user, rgb);
				pthread_mutex_lock(&c.lock);
				next = now_s() + o->progressive_seconds;
			}
		}
		pthread_mutex_unlock(&c.lock);
	}
	for (uint32_t i = 0; i < started; i++)
		pthread_join(th[i], NULL);
	pthread_mutex_destroy(&c.lock);
	pthread_cond_destroy(&c.bar_cv);
	pthread_cond_destroy(&c.done_cv);
	if (c.acc) {
		snapshot(&c);
		free(c.acc);
	}
	if (started == 0) {
		free(ts);
		free(th);
		return loom__fail(diag, LOOM_ENOMEM, "render: cannot start a thread");
	}
	if (stats) {
		for (uint32_t i = 0; i < started; i++) {
			stats->paths += ts[i].st.paths;
			stats->rays += ts[i].st.rays;
			stats->lookups += ts[i].st.lookups;
			stats->scatterings += ts[i].st.scatterings;
			stats->shell_queries += ts[i].st.shell_queries;
			stats->cells += ts[i].st.cells;
		}
		stats->seconds = now_s() - t0;
	}
	free(ts);
	free(th);
	rc = atomic_load(&c.error);
	if (rc) {
		int code = rc > 0 && rc < LOOM_RESULT_COUNT_ ? rc : LOOM_EIO;
		return loom__fail(diag, code, "render: the source's lookup (or "
		                  "thread_init) failed with code %d (%s)", rc,
		                  loom_strerror(rc));
	}
	if (c.shell && loom__shell_failed(c.shell))
		return loom__fail(diag, LOOM_EUNUSABLE, "render: Embree reported an error");
	return LOOM_OK;
}

LOOM_API int loom_camera_top(const loom_volume_source *src, double x0,
                             double y0, double x1, double y1, loom_camera *cam)
{
	if (!src || !cam || !(x1 > x0) || !(y1 > y0) || !isfinite(x0 + x1 + y0 + y1))
		return LOOM_EINVAL;
	memset(cam, 0, sizeof *cam);
	cam->kind = LOOM_CAMERA_ORTHO;
	cam->eye[0] = cam->target[0] = 0.5 * (x0 + x1);
	cam->eye[1] = cam->target[1] = 0.5 * (y0 + y1);
	cam->eye[2] = (double)src->nz + 1.0;
	cam->target[2] = 0.0;
	cam->up[1] = 1.0;
	cam->fov_y_deg = 40.0;
	cam->ortho_size[0] = x1 - x0;
	cam->ortho_size[1] = y1 - y0;
	return LOOM_OK;
}

static uint8_t srgb8(double v)
{
	if (!(v > 0))
		return 0;
	if (v >= 1)
		return 255;
	v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
	return (uint8_t)(v * 255.0 + 0.5);
}

LOOM_API void loom_render_to_srgb8(const float *rgb, size_t n_pixels,
                                   double exposure, uint8_t *out)
{
	double k = pow(2.0, exposure);
	if (!rgb || !out)
		return;
	for (size_t i = 0; i < 3 * n_pixels; i++)
		out[i] = srgb8(rgb[i] * k);
}
