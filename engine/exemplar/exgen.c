/*
 * engine/exemplar/exgen.c - procedural CT-like exemplars (the models behind
 * `loom exemplar generate`).  docs/exemplars.md describes the model
 * for users; this is the implementer's summary.
 *
 * Sheet.  An endless sheet woven with the weave W (periodic with the
 * window), ends (warps) along y at x = (c + 1/2) Sx, picks (wefts) along x
 * at y = (r + 1/2) Sy, with Sx = b1 * voxel, Sy = b2 * voxel.  The exemplar
 * is the window of rows x cols crossings starting at crossing (0, 0); the
 * yarns just outside it (c = -1, cols; r = -1, rows) exist too, with their
 * own irregularities, so the window's borders are real cuts.
 *
 * Yarn centre curves are closed-form functions of the along-yarn coordinate
 * s (y for a warp, x for a weft):
 *   height  z(s) = z0 + A * crimp(s) + jz * n1(s)
 *           crimp interpolates +1 (over) / -1 (under) between the crossing
 *           centres with a smoothstep (C1: flat on floats, S-shaped where
 *           the yarn changes side);
 *   lateral l(s) = centre + jl * n1'(s)
 *   radii   a(s), c(s): elliptical cross-section (half-width along the
 *           lateral axis, half-height), per-yarn scale and along-yarn noise.
 * n1 is 1-D value noise keyed by the yarn's seed.  Warp and weft differ in
 * radii, crimp amplitude, twist pitch and direction (warp Z, weft S),
 * density and fibre size, so an exemplar cannot be rotated or mirrored.
 *
 * Voxels.  Per voxel column only the three nearest warps and wefts can
 * reach it; for each, the column's z-interval inside the ellipse (in the
 * yarn's cross-section frame e1, e2 around the tangent T) is a quadratic
 * solved once per column.  Inside, per voxel: (u, v) = normalised
 * cross-section coordinates, rho^2 = u^2 + v^2 (the yarn with the smallest
 * rho owns the voxel);
 *   density      dmax * core(rho) * edge(distance to boundary) *
 *                fibres(u', v'), where (u', v') co-rotates with the twist,
 *                so the 2-D fibre noise becomes helical striations;
 *   orientation  the helix tangent T + omega (-(a/c) p2 e1 + (c/a) p1 e2)
 *                plus a small per-fibre misalignment;
 *   label        the yarn.
 * Flyaway fibres: cubic Bezier arcs leaving a yarn's top surface, inside
 * the block of their root, sampled every 0.4 voxel and splatted with max();
 * they only fill voxels outside yarns and have their own labels (flag
 * FLYAWAY).
 *
 * Determinism: every value is a function of the voxel position, the
 * parameters and the seed (splitmix-style hashing), so boxes can be made
 * in any order on any number of threads.
 *
 * The parallel database build that drives these models (loom_exgen_write_db)
 * writes a file, so it lives in io/store/exgen_write.c.
 */
#include "exgen.h"
#include "db_internal.h"

#include <math.h>
#include <stdlib.h>

#define KIND_WARP 1
#define KIND_WEFT 2
#define MAX_SIDE 64         /* crossings per side a generated window may have */
#define MAX_FLY 16
#define DESIGN_LABELS 119  /* labels per yarn kind when they must be shared */
#define ZCHUNK 512         /* fibre-level columns are made in runs of this */
#define MAX_FIB 4000       /* fibres per yarn */

/* Woven mechanics (docs/exemplars.md, "Crimp and floats"). */
#define FLOAT_RISE 0.25f /* a long float's middle rises by this much of the
                            crimp amplitude above an interlacing */
#define COMPRESS 0.2f    /* half-height lost where a yarn is pressed */
#define SPREAD 0.12f     /* half-width gained in a long float's middle */
#define HAIR_CLEAR 0.25f /* yarn radii a hair or loop reaches at least
                            beyond the surface (so all are flyaways) */

/* ---- hashing and noise ------------------------------------------------- */

static inline uint64_t mix64(uint64_t z)
{
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static inline uint64_t hash2(uint64_t seed, int64_t a, int64_t b)
{
	return mix64(seed ^ ((uint64_t)a * 0x9e3779b97f4a7c15ull) ^
	             ((uint64_t)b * 0xc2b2ae3d27d4eb4full));
}

static inline float u01(uint64_t h)
{
	return (float)(h >> 40) * (1.0f / 16777216.0f);
}

static inline float smooth(float f)
{
	return f * f * (3.0f - 2.0f * f);
}

/* 1-D value noise in [-1, 1], knots at integers. */
static float noise1(uint64_t seed, float t)
{
	float fl = floorf(t), f = t - fl;
	int64_t i = (int64_t)fl;
	float a = 2.0f * u01(hash2(seed, i, 0)) - 1.0f;
	float b = 2.0f * u01(hash2(seed, i + 1, 0)) - 1.0f;
	return a + (b - a) * smooth(f);
}

/* 2-D value noise in [0, 1]. */
static inline float noise2(uint64_t seed, float x, float y)
{
	float fx = floorf(x), fy = floorf(y);
	int64_t ix = (int64_t)fx, iy = (int64_t)fy;
	float sx = smooth(x - fx), sy = smooth(y - fy);
	float v00 = u01(hash2(seed, ix, iy)), v10 = u01(hash2(seed, ix + 1, iy));
	float v01 = u01(hash2(seed, ix, iy + 1)), v11 = u01(hash2(seed, ix + 1, iy + 1));
	float a = v00 + (v10 - v00) * sx, b = v01 + (v11 - v01) * sx;
	return a + (b - a) * sy;
}

/* ---- fibre presets (docs/exemplars.md, "Fibre-level yarns") ------------
 * The model's form follows Zhao, Luan and Bala (SIGGRAPH 2016): plies
 * twisted about the yarn centre, fibres twisted about the ply centre, drawn
 * from the radial density ((1 - 2 eps) ((e - e^R) / (e - 1))^beta + eps),
 * migrating between rmin and rmax of their radius, plus hair and loop
 * fibres.  The numbers are loom's choices from textile data (fibre
 * diameters, typical twist angles), not the paper's fitted table. */
typedef struct fibre_preset {
	const char *name;
	float d;            /* fibre diameter, um; 0: one fibre filling the yarn */
	uint32_t plies;
	float ply_deg;      /* ply helix angle at the ply centres */
	float fib_deg;      /* fibre helix angle at the ply surface */
	float fill;         /* fibre area fraction of the yarn's cross-section */
	float eps, beta;    /* radial density */
	float rmin, rmax;   /* migration range, fraction of a fibre's radius */
	float mig;          /* migration period, yarn diameters */
	float hair, loop;   /* hair and loop fibres per mm of yarn */
	float hair_len;     /* mean hair length, um (loops: 0.4 of it) */
	float hair_out;     /* how far hairs reach beyond the surface, yarn radii */
} fibre_preset;

static const fibre_preset fibre_presets[] = {
	/* name          d   ply ply  fib  fill  eps   beta rmin rmax mig hair loop len  out */
	{"cotton",      15,  2, 20,  28, 0.58f, 0.05f, 1.5f, .85f, 1, 2.0f, 3,  5, 400, 0.6f},
	{"rayon",       13,  2, 18,  22, 0.60f, 0.10f, 1.0f, .88f, 1, 3.0f, 1,  3, 300, 0.4f},
	{"silk",        11,  2, 12,  10, 0.60f, 0.20f, 0.5f, .92f, 1, 4.0f, 0.3f, 1, 200, 0.3f},
	{"polyester",   14,  1,  0,  14, 0.60f, 0.20f, 0.5f, .90f, 1, 4.0f, 0.3f, 2, 250, 0.3f},
	{"wool",        24,  2, 22,  30, 0.52f, 0.05f, 2.0f, .80f, 1, 1.5f, 5,  8, 600, 0.9f},
	{"linen",       18,  1,  0,  20, 0.58f, 0.10f, 1.0f, .85f, 1, 2.5f, 2,  3, 500, 0.5f},
	{"monofilament", 0,  1,  0,   0, 1.00f, 0.00f, 1.0f, 1.0f, 1, 1.0f, 0,  0,   0, 0.0f},
};

static const fibre_preset *fibre_find(const char *name)
{
	if (!name || !strcmp(name, "none"))
		return NULL;
	for (size_t i = 0; i < sizeof fibre_presets / sizeof fibre_presets[0]; i++)
		if (!strcmp(name, fibre_presets[i].name))
			return &fibre_presets[i];
	return NULL;
}

/* ---- model ------------------------------------------------------------- */

typedef struct kind_params {
	float a, c;          /* half-width (lateral), half-height, um */
	float crimp;         /* crimp amplitude A, um */
	float omega;         /* twist, rad per um along the yarn; > 0: Z twist */
	float dmax;          /* density at the core */
	float fibre;         /* fibre noise cell, um */
	float jit_lat, jit_z;/* path jitter amplitudes, um */
	float jit_r;         /* radius jitter (fraction) */
	float noise_len;     /* along-yarn correlation length, um */
	float misalign;      /* fibre direction noise */
	float spacing;       /* crossing spacing along the yarn, um */
	/* fibre-level yarns (fp != NULL) */
	const struct fibre_preset *fp;
	uint32_t plies, per_ply; /* fibres per ply (as packed) */
	float rp;            /* ply half-axis towards the yarn centre, fraction
	                        of the yarn's radius (the ply centre at 1 - rp) */
	float rt;            /* ply half-axis across it (rt >= rp: plies pressed
	                        against each other widen) */
	float om_p, om_f;    /* ply and fibre twist, rad per um */
	float w1, w2;        /* fibre footprint in the cross-section, um */
	float mig_k;         /* migration, rad per um */
	float cell;          /* along-yarn cell of one hair or loop fibre, um */
	float hair_max;      /* longest hair or loop, um */
	float out;           /* farthest reach of hairs, yarn radii */
} kind_params;

typedef struct yarn {
	int kind;            /* KIND_WARP or KIND_WEFT */
	int index;           /* c (warp) or r (weft), -1 .. cols/rows */
	uint8_t label;
	uint64_t seed;
	float centre;        /* nominal lateral position, um */
	float wscale, hscale;/* per-yarn radius factors */
	float phase;         /* twist phase, rad */
	uint32_t period;     /* crossings per repeat along the yarn */
	const float *hgt;    /* period crossing heights (units of the crimp) */
	const float *wfac;   /* period half-width factors */
	const float *cfac;   /* period half-height factors */
	const float *fib;    /* fibre-level: 6 floats per fibre (ply-unit
	                        radius, cos/sin angle, cos/sin migration phase,
	                        ply index) */
	uint32_t n_fib;
} yarn;

typedef struct flyaway {
	uint8_t label;
	float peak;          /* density 0..1 at the axis */
	float r;             /* radius, voxels */
	uint32_t n;          /* samples */
	float *pos;          /* 3n, voxel units (voxel i's centre at i) */
	uint16_t *code;      /* n orientation codes */
	float lo[3], hi[3];  /* bounding box incl. radius, voxel units */
} flyaway;

struct loom__exgen {
	uint32_t b1, b2, b3, rows, cols;
	uint32_t size[3];
	float vs;            /* voxel size, um */
	float Sx, Sy;        /* crossing spacings, um */
	float z0;            /* cloth mid-plane, um */
	uint64_t seed;
	uint8_t *weave;
	char name[32], weave_name[32];
	uint8_t tag[2];      /* material pair tag (loom__exgen_tag) */
	kind_params kp[3];   /* by kind */
	float *mech;         /* the yarns' hgt/wfac/cfac tables */
	float *fibs;         /* the yarns' fibre tables */
	yarn *warps;         /* cols + 2: c = -1 .. cols */
	yarn *wefts;         /* rows + 2 */
	uint32_t n_fly;
	flyaway fly[MAX_FLY];
	uint32_t n_labels;
	int fibres;          /* fibre-level yarns (either kind) */
	loom_db_yarn table[256];
};

static inline int weave_at(const loom__exgen *g, int64_t i, int64_t j)
{
	int64_t r = ((i % g->rows) + g->rows) % g->rows;
	int64_t c = ((j % g->cols) + g->cols) % g->cols;
	return g->weave[r * g->cols + c];
}

/* +1 where yarn y passes over at its crossing number i, -1 under. */
static inline float crossing_sign(const loom__exgen *g, const yarn *y, int64_t i)
{
	if (y->kind == KIND_WARP)
		return weave_at(g, i, y->index) ? 1.0f : -1.0f;
	return weave_at(g, y->index, i) ? -1.0f : 1.0f;
}

/* Centre curve of yarn y at along-yarn coordinate s (um): the crossing
   heights joined by a cubic Hermite spline with Catmull-Rom tangents (C1;
   flat at an isolated interlacing, a smooth arch over a float), the
   cross-section factors by a smoothstep. */
static void yarn_eval(const loom__exgen *g, const yarn *y, float s, float *lat,
                      float *zc, float *ha, float *hc)
{
	const kind_params *kp = &g->kp[y->kind];
	float t = s / kp->spacing - 0.5f;
	float fl = floorf(t), f = t - fl, f2 = f * f, f3 = f2 * f;
	int64_t P = y->period, i = (((int64_t)fl % P) + P) % P;
	int64_t im = (i + P - 1) % P, i1 = (i + 1) % P, i2 = (i + 2) % P;
	float h0 = y->hgt[i], h1 = y->hgt[i1];
	float m0 = 0.5f * (h1 - y->hgt[im]), m1 = 0.5f * (y->hgt[i2] - h0);
	float hz = (2 * f3 - 3 * f2 + 1) * h0 + (f3 - 2 * f2 + f) * m0 +
	           (-2 * f3 + 3 * f2) * h1 + (f3 - f2) * m1;
	float sf = smooth(f);
	float wf = y->wfac[i] + (y->wfac[i1] - y->wfac[i]) * sf;
	float cf = y->cfac[i] + (y->cfac[i1] - y->cfac[i]) * sf;
	float u = s / kp->noise_len;

	*zc = g->z0 + kp->crimp * hz + kp->jit_z * noise1(y->seed ^ 0x11, u);
	*lat = y->centre + kp->jit_lat * noise1(y->seed ^ 0x22, u);
	*ha = kp->a * wf * y->wscale * (1.0f + kp->jit_r * noise1(y->seed ^ 0x33, u));
	*hc = kp->c * cf * y->hscale * (1.0f + kp->jit_r * noise1(y->seed ^ 0x44, u));
}

static void normalize3(float v[3])
{
	float n = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	if (n > 0) {
		v[0] /= n;
		v[1] /= n;
		v[2] /= n;
	}
}

static void cross3(const float a[3], const float b[3], float o[3])
{
	o[0] = a[1] * b[2] - a[2] * b[1];
	o[1] = a[2] * b[0] - a[0] * b[2];
	o[2] = a[0] * b[1] - a[1] * b[0];
}

/* Tangent and cross-section frame of yarn y at s: T along the yarn; e1
   lateral (-x for warps, +y for wefts) so that e2 = T x e1 points up and
   (e1, e2, T) is right-handed for both kinds. */
static void yarn_frame(const loom__exgen *g, const yarn *y, float s, float T[3],
                       float e1[3], float e2[3])
{
	float h = g->vs, l0, l1, z0, z1, a, c, d;
	int warp = y->kind == KIND_WARP;

	yarn_eval(g, y, s - h, &l0, &z0, &a, &c);
	yarn_eval(g, y, s + h, &l1, &z1, &a, &c);
	T[0] = warp ? (l1 - l0) / (2 * h) : 1.0f;
	T[1] = warp ? 1.0f : (l1 - l0) / (2 * h);
	T[2] = (z1 - z0) / (2 * h);
	normalize3(T);
	e1[0] = warp ? -1.0f : 0.0f;
	e1[1] = warp ? 0.0f : 1.0f;
	e1[2] = 0.0f;
	d = e1[0] * T[0] + e1[1] * T[1];
	for (int k = 0; k < 3; k++)
		e1[k] -= d * T[k];
	normalize3(e1);
	cross3(T, e1, e2);
}

/* One yarn's contribution to one voxel column. */
typedef struct hit {
	const yarn *y;
	const kind_params *kp;
	float zc, a, c;
	float al1, be1, al2, be2;  /* p1 = al1 + be1*dz, p2 = al2 + be2*dz */
	float T[3], e1[3], e2[3];
	float cs, sn;              /* co-rotation of the fibre pattern */
	float fscale;              /* sqrt(a c) / fibre cell */
	int zlo, zhi;              /* voxel z range (inclusive) */
} hit;

/* Column (px, py) in um against yarn y: fill h, return 1 if it reaches. */
static int column_hit(const loom__exgen *g, const yarn *y, float px, float py,
                      hit *h, float reach)
{
	int warp = y->kind == KIND_WARP;
	float s = warp ? py : px, lat, zc, a, c, off;
	float A, B, C, disc, sq, dzlo, dzhi, psi;
	float La[3]; /* lateral axis of the column's offset */

	yarn_eval(g, y, s, &lat, &zc, &a, &c);
	h->a = a;
	h->c = c;
	a *= reach; /* reach > 1: hairs outside the yarn's ellipse */
	c *= reach;
	off = (warp ? px : py) - lat;
	if (fabsf(off) > a * 1.1f + g->vs)
		return 0;
	yarn_frame(g, y, s, h->T, h->e1, h->e2);
	La[0] = warp ? 1.0f : 0.0f;
	La[1] = warp ? 0.0f : 1.0f;
	La[2] = 0.0f;
	h->al1 = off * (h->e1[0] * La[0] + h->e1[1] * La[1]);
	h->be1 = h->e1[2];
	h->al2 = off * (h->e2[0] * La[0] + h->e2[1] * La[1]);
	h->be2 = h->e2[2];
	A = h->be1 * h->be1 / (a * a) + h->be2 * h->be2 / (c * c);
	B = 2.0f * (h->al1 * h->be1 / (a * a) + h->al2 * h->be2 / (c * c));
	C = h->al1 * h->al1 / (a * a) + h->al2 * h->al2 / (c * c) - 1.0f;
	disc = B * B - 4.0f * A * C;
	if (!(disc > 0.0f) || !(A > 0.0f))
		return 0;
	sq = sqrtf(disc);
	dzlo = (-B - sq) / (2.0f * A);
	dzhi = (-B + sq) / (2.0f * A);
	h->zlo = (int)ceilf((zc + dzlo) / g->vs - 0.5f);
	h->zhi = (int)floorf((zc + dzhi) / g->vs - 0.5f);
	if (h->zhi < h->zlo)
		return 0;
	h->y = y;
	h->kp = &g->kp[y->kind];
	h->zc = zc;
	psi = h->kp->omega * s + y->phase;
	h->cs = cosf(psi);
	h->sn = sinf(psi);
	h->fscale = sqrtf(h->a * h->c) / h->kp->fibre;
	return 1;
}

/* Voxel z (index) of a column from hit h, with u, v already known. */
static void voxel_value(const loom__exgen *g, const hit *h, float u, float v,
                        float r2, uint8_t *dens, uint16_t *orient)
{
	const kind_params *kp = h->kp;
	float rho = sqrtf(r2), gu = u / h->a, gv = v / h->c;
	float grad = sqrtf(gu * gu + gv * gv) / (rho > 1e-4f ? rho : 1e-4f);
	float dist = (1.0f - rho) / (grad > 1e-9f ? grad : 1e-9f);
	float edge = dist / g->vs + 0.5f;
	float up = u * h->cs + v * h->sn, vp = v * h->cs - u * h->sn;
	float X = up * h->fscale, Y = vp * h->fscale;
	float fine = noise2(h->y->seed ^ 0x55, X, Y);
	float coarse = noise2(h->y->seed ^ 0x66, X * 0.3f, Y * 0.3f);
	float fib = 0.42f + 0.58f * (0.6f * fine + 0.4f * coarse);
	float core = 0.82f + 0.18f * (1.0f - r2);
	float p1 = u * h->a, p2 = v * h->c, dir[3];
	uint64_t hm = hash2(h->y->seed ^ 0x77, (int64_t)floorf(X + 0.5f),
	                    (int64_t)floorf(Y + 0.5f));
	float d1 = (u01(hm) - 0.5f) * 2.0f * kp->misalign;
	float d2 = (u01(mix64(hm)) - 0.5f) * 2.0f * kp->misalign;
	float w1 = -kp->omega * (h->a / h->c) * p2 + d1;
	float w2 = kp->omega * (h->c / h->a) * p1 + d2;

	if (edge > 1.0f)
		edge = 1.0f;
	if (edge < 0.0f)
		edge = 0.0f;
	*dens = loom__density_encode(kp->dmax * core * fib * edge);
	for (int k = 0; k < 3; k++)
		dir[k] = h->T[k] + w1 * h->e1[k] + w2 * h->e2[k];
	/* the voxel rule (docs/formats.md): no orientation where density is 0 */
	*orient = *dens ? loom__orient_encode(dir[0], dir[1], dir[2]) : 0;
}

/* Fill voxel column (x, y), z in [zs, ze), into column arrays whose index 0
   is z = zbase. */
static void gen_column(const loom__exgen *g, int64_t x, int64_t y, int64_t zs,
                       int64_t ze, int64_t zbase, uint8_t *dens, uint16_t *orient,
                       uint8_t *label)
{
	float px = ((float)x + 0.5f) * g->vs, py = ((float)y + 0.5f) * g->vs;
	int64_t cw = (int64_t)floorf(px / g->Sx), rw = (int64_t)floorf(py / g->Sy);
	hit hits[6];
	int n = 0, zmin = INT32_MAX, zmax = INT32_MIN;

	for (int64_t c = cw - 1; c <= cw + 1; c++)
		if (c >= -1 && c <= (int64_t)g->cols &&
		    column_hit(g, &g->warps[c + 1], px, py, &hits[n], 1.0f))
			n++;
	for (int64_t r = rw - 1; r <= rw + 1; r++)
		if (r >= -1 && r <= (int64_t)g->rows &&
		    column_hit(g, &g->wefts[r + 1], px, py, &hits[n], 1.0f))
			n++;
	for (int i = 0; i < n; i++) {
		if (hits[i].zlo < zmin)
			zmin = hits[i].zlo;
		if (hits[i].zhi > zmax)
			zmax = hits[i].zhi;
	}
	if (zmin < zs)
		zmin = (int)zs;
	if (zmax > ze - 1)
		zmax = (int)(ze - 1);
	for (int z = zmin; z <= zmax; z++) {
		float pz = ((float)z + 0.5f) * g->vs, best = 1.0f, bu = 0, bv = 0;
		int bi = -1;
		for (int i = 0; i < n; i++) {
			const hit *h = &hits[i];
			float dz, u, v, r2;
			if (z < h->zlo || z > h->zhi)
				continue;
			dz = pz - h->zc;
			u = (h->al1 + h->be1 * dz) / h->a;
			v = (h->al2 + h->be2 * dz) / h->c;
			r2 = u * u + v * v;
			if (r2 <= best) {
				best = r2;
				bi = i;
				bu = u;
				bv = v;
			}
		}
		if (bi < 0)
			continue;
		voxel_value(g, &hits[bi], bu, bv, best, &dens[z - zbase], &orient[z - zbase]);
		label[z - zbase] = hits[bi].y->label;
	}
}

/* ---- fibre-level yarns ---------------------------------------------------- */

/* Overlap of the voxel [d - vs/2, d + vs/2] with [-w/2, w/2], over vs. */
static inline float overlap1(float d, float w, float vs)
{
	float lo = fmaxf(d - 0.5f * vs, -0.5f * w), hi = fminf(d + 0.5f * vs, 0.5f * w);
	return hi > lo ? (hi - lo) / vs : 0.0f;
}

/* One fibre of a yarn at one along-yarn coordinate: its position (um) in
   the cross-section frame and its direction; code: its orientation code,
   0 until first needed. */
typedef struct fibre_pt {
	float f1, f2, dir[3];
	uint16_t code;
} fibre_pt;

/* Add fibre f to the column of hit h (coverage; index 0 = z zbase). */
static void splat_fibre(const loom__exgen *g, const hit *h, fibre_pt *f, int zs,
                        int ze, int zbase, float *cov, float *best, uint16_t *bor,
                        uint8_t *blab)
{
	const kind_params *kp = h->kp;
	float dzs, p1s, half2 = 0.5f * (kp->w2 + g->vs), f1 = f->f1, f2 = f->f2;
	int zlo, zhi;

	if (!(h->be2 > 0.05f))
		return;
	dzs = (f2 - h->al2) / h->be2;
	p1s = h->al1 + h->be1 * dzs;
	if (fabsf(p1s - f1) >= 0.5f * (kp->w1 + g->vs) + fabsf(h->be1) * half2)
		return;
	zlo = (int)ceilf((h->zc + dzs - half2 / h->be2) / g->vs - 0.5f);
	zhi = (int)floorf((h->zc + dzs + half2 / h->be2) / g->vs - 0.5f);
	if (zlo < zs)
		zlo = zs;
	if (zhi > ze - 1)
		zhi = ze - 1;
	for (int z = zlo; z <= zhi; z++) {
		float dz = ((float)z + 0.5f) * g->vs - h->zc;
		float p1 = h->al1 + h->be1 * dz, p2 = h->al2 + h->be2 * dz;
		float c = overlap1(p1 - f1, kp->w1, g->vs) * overlap1(p2 - f2, kp->w2, g->vs);
		int i = z - zbase;
		if (!(c > 0.0f))
			continue;
		cov[i] += c;
		if (c > best[i]) {
			if (!f->code)
				f->code = loom__orient_encode(f->dir[0], f->dir[1], f->dir[2]);
			best[i] = c;
			bor[i] = f->code;
			blab[i] = h->y->label;
		}
	}
}

/* Direction of a fibre whose normalised cross-section position moves by
   (dX, dY) per um along the yarn. */
static void fibre_dir(const hit *h, float dX, float dY, float dir[3])
{
	for (int k = 0; k < 3; k++)
		dir[k] = h->T[k] + h->a * dX * h->e1[k] + h->c * dY * h->e2[k];
}

/* Monofilament column of hit h: the fibre is the yarn. */
static void mono_column(const loom__exgen *g, const hit *h, int zs, int ze, int zbase,
                        float *cov, float *best, uint16_t *bor, uint8_t *blab)
{
	for (int z = zs; z < ze; z++) {
		float dz = ((float)z + 0.5f) * g->vs - h->zc;
		float u = (h->al1 + h->be1 * dz) / h->a, v = (h->al2 + h->be2 * dz) / h->c;
		float rho = sqrtf(u * u + v * v), gu = u / h->a, gv = v / h->c;
		float grad = sqrtf(gu * gu + gv * gv) / (rho > 1e-4f ? rho : 1e-4f);
		float c = (1.0f - rho) / (grad > 1e-9f ? grad : 1e-9f) / g->vs + 0.5f;
		int i = z - zbase;
		c = fminf(fmaxf(c, 0.0f), 1.0f);
		if (!(c > 0.0f))
			continue;
		cov[i] += c;
		if (c > best[i]) {
			best[i] = c;
			bor[i] = loom__orient_encode(h->T[0], h->T[1], h->T[2]);
			blab[i] = h->y->label;
		}
	}
}

/* Most fibres (plies, hairs and loops) one yarn of kind kp can have at
   one along-yarn coordinate (the size of a fibre_line). */
static uint32_t line_capacity(const loom__exgen *g, const kind_params *kp,
                              const yarn *ys, uint32_t n)
{
	uint32_t m = 0;

	for (uint32_t i = 0; i < n; i++)
		m = ys[i].n_fib > m ? ys[i].n_fib : m;
	(void)g;
	if (kp->cell > 0.0f)
		m += (uint32_t)ceilf(kp->hair_max / kp->cell) + 2u;
	return m;
}

/* Every fibre (plies, hairs and loops) of the yarn of hit h at along-yarn
   coordinate s, into f; returns how many.  They depend on the yarn and s
   only, so one line serves every column of a row across the yarn. */
static uint32_t fibre_line(const hit *h, float s, fibre_pt *f)
{
	const kind_params *kp = h->kp;
	const yarn *y = h->y;
	uint32_t np = kp->plies, n = 0;
	float cf = cosf(kp->om_f * s), sf = sinf(kp->om_f * s);
	float cm = cosf(kp->mig_k * s), sm = sinf(kp->mig_k * s);
	float rmid = 0.5f * (kp->fp->rmin + kp->fp->rmax);
	float ramp = 0.5f * (kp->fp->rmax - kp->fp->rmin);
	float cx[8], cy[8], dcx[8], dcy[8], cp[8], sp[8];

	/* ply j: centre (cx, cy) turning at om_p, its frame (cp, sp) the
	   direction from the yarn centre; a fibre at (R, alpha) in the ply
	   frame (alpha = its own angle less the frame's) sits at R (rp cos
	   alpha, rt sin alpha) in it */
	for (uint32_t j = 0; j < np; j++) {
		float psi = kp->om_p * s + y->phase + 6.2831853f * (float)j / (float)np;
		float rc = np > 1 ? 1.0f - kp->rp : 0.0f;
		cp[j] = cosf(psi);
		sp[j] = sinf(psi);
		cx[j] = rc * cp[j];
		cy[j] = rc * sp[j];
		dcx[j] = -kp->om_p * cy[j];
		dcy[j] = kp->om_p * cx[j];
	}
	for (uint32_t i = 0; i < y->n_fib; i++) {
		const float *fb = y->fib + 6 * i;
		uint32_t j = (uint32_t)fb[5];
		float cph = fb[1] * cf - fb[2] * sf, sph = fb[2] * cf + fb[1] * sf;
		float ca = cph * cp[j] + sph * sp[j], sa = sph * cp[j] - cph * sp[j];
		float cmi = fb[3] * cm - fb[4] * sm, smi = fb[4] * cm + fb[3] * sm;
		float R = fb[0] * (rmid + ramp * cmi), dR = -fb[0] * ramp * smi * kp->mig_k;
		float da = kp->om_f - kp->om_p;
		float A = kp->rp * R * ca, B = kp->rt * R * sa;
		float dA = kp->rp * (dR * ca - R * da * sa), dB = kp->rt * (dR * sa + R * da * ca);
		float X = cx[j] + A * cp[j] - B * sp[j], Y = cy[j] + A * sp[j] + B * cp[j];
		float dX = dcx[j] + dA * cp[j] - dB * sp[j] - kp->om_p * (A * sp[j] + B * cp[j]);
		float dY = dcy[j] + dA * sp[j] + dB * cp[j] + kp->om_p * (A * cp[j] - B * sp[j]);
		fibre_dir(h, dX, dY, f[n].dir);
		f[n].f1 = X * h->a;
		f[n].f2 = Y * h->c;
		f[n++].code = 0;
	}
	/* hair and loop fibres: one per cell of kp->cell um along the yarn,
	   leaving the surface at a random angle; a hair rises steadily to its
	   free end, a loop rises and returns */
	if (kp->cell > 0.0f) {
		int64_t k0 = (int64_t)floorf((s - kp->hair_max) / kp->cell);
		int64_t k1 = (int64_t)floorf(s / kp->cell);
		float ph = kp->fp->hair / (kp->fp->hair + kp->fp->loop);
		for (int64_t k = k0; k <= k1; k++) {
			uint64_t hh = hash2(y->seed ^ 0x4a17, k, 0);
			int is_hair = u01(hh) < ph;
			float s0 = ((float)k + u01(mix64(hh ^ 1))) * kp->cell;
			float len = kp->fp->hair_len * (is_hair ? 0.5f + u01(mix64(hh ^ 2))
			                                        : 0.25f + 0.3f * u01(mix64(hh ^ 2)));
			float t = (s - s0) / len, th, out, R, dR, X, Y, dX, dY;
			if (t < 0.0f || t > 1.0f)
				continue;
			/* every one clears the yarn by HAIR_CLEAR radii at least */
			out = HAIR_CLEAR + kp->fp->hair_out * (0.4f + 0.6f * u01(mix64(hh ^ 3)));
			/* it leaves the top or the bottom face, within 50 degrees of
			   the vertical (sideways it would run into the next yarn), and
			   no longer follows the twist once it is out */
			th = (u01(mix64(hh ^ 5)) < 0.5f ? 1.5707963f : -1.5707963f) +
			     1.7453293f * (u01(mix64(hh ^ 4)) - 0.5f);
			if (is_hair) {
				R = 0.95f + out * t;
				dR = out / len;
			} else {
				R = 0.95f + out * sinf(3.1415927f * t);
				dR = out * 3.1415927f / len * cosf(3.1415927f * t);
			}
			X = R * cosf(th);
			Y = R * sinf(th);
			dX = dR * cosf(th);
			dY = dR * sinf(th);
			fibre_dir(h, dX, dY, f[n].dir);
			f[n].f1 = X * h->a;
			f[n].f2 = Y * h->c;
			f[n++].code = 0;
		}
	}
	return n;
}

/*
 * Fibre lines of a box, cached: a warp's fibres at row y serve every
 * column of that row, a weft's at column x every row of the box.  Slots
 * are direct-mapped: warps by (index mod 4) for the current row, wefts by
 * (column in the tile, index mod 4); the three yarns of a kind that reach
 * a column have distinct indices mod 4, so a line is computed once per
 * row (warps) or per column of the tile (wefts).  The values are what the
 * column would compute itself, so the bytes do not depend on the cache.
 */
#define LINE_TILE 16 /* box columns per tile along x */
typedef struct line_slot {
	const yarn *y;  /* NULL: empty */
	int64_t at;     /* voxel index along the yarn */
	uint32_t n;
	fibre_pt *f;
} line_slot;
typedef struct line_cache {
	line_slot warp[4], weft[4 * LINE_TILE];
	fibre_pt *mem;
} line_cache;

static int line_cache_init(const loom__exgen *g, line_cache *lc)
{
	uint32_t cw = line_capacity(g, &g->kp[KIND_WARP], g->warps, g->cols + 2);
	uint32_t cf = line_capacity(g, &g->kp[KIND_WEFT], g->wefts, g->rows + 2);
	fibre_pt *m;

	memset(lc, 0, sizeof *lc);
	lc->mem = m = malloc(((size_t)4 * cw + (size_t)4 * LINE_TILE * cf + 1) * sizeof *m);
	if (!m)
		return LOOM_ENOMEM;
	for (int k = 0; k < 4; k++, m += cw)
		lc->warp[k].f = m;
	for (int k = 0; k < 4 * LINE_TILE; k++, m += cf)
		lc->weft[k].f = m;
	return LOOM_OK;
}

/* Fibre-level column: coverage summed over the yarns and fibres; the
   orientation and label of the fibre covering most of the voxel.  Scratch
   arrays of ze - zs entries; xt: the column's place in its tile. */
static void gen_column_fibres(const loom__exgen *g, line_cache *lc, int64_t x,
                              int64_t y, uint32_t xt, int64_t zs, int64_t ze,
                              int64_t zbase, uint8_t *dens, uint16_t *orient,
                              uint8_t *label, float *cov, float *best)
{
	float px = ((float)x + 0.5f) * g->vs, py = ((float)y + 0.5f) * g->vs;
	int64_t cw = (int64_t)floorf(px / g->Sx), rw = (int64_t)floorf(py / g->Sy);
	uint16_t *bor = orient + (zs - zbase);
	uint8_t *blab = label + (zs - zbase);
	hit h;

	for (int64_t z = zs; z < ze; z++) {
		cov[z - zs] = 0.0f;
		best[z - zs] = 0.0f;
	}
	for (int pass = 0; pass < 2; pass++) {
		int64_t mid = pass ? rw : cw, lim = pass ? g->rows : g->cols;
		for (int64_t c = mid - 1; c <= mid + 1; c++) {
			const yarn *yy;
			line_slot *ls;
			int64_t at;
			if (c < -1 || c > lim)
				continue;
			yy = pass ? &g->wefts[c + 1] : &g->warps[c + 1];
			if (!column_hit(g, yy, px, py, &h, g->kp[yy->kind].out))
				continue;
			if (h.kp->fp->d == 0.0f) {
				mono_column(g, &h, (int)zs, (int)ze, (int)zs, cov, best, bor, blab);
				continue;
			}
			at = pass ? x : y;
			ls = pass ? &lc->weft[xt * 4 + (uint32_t)((c + 1) & 3)]
			          : &lc->warp[(c + 1) & 3];
			if (ls->y != yy || ls->at != at) {
				ls->y = yy;
				ls->at = at;
				ls->n = fibre_line(&h, pass ? px : py, ls->f);
			}
			for (uint32_t i = 0; i < ls->n; i++)
				splat_fibre(g, &h, &ls->f[i], (int)zs, (int)ze, (int)zs, cov, best,
				            bor, blab);
		}
	}
	for (int64_t z = zs; z < ze; z++)
		if (best[z - zs] > 0.0f) {
			dens[z - zbase] = loom__density_encode(fminf(cov[z - zs], 1.0f));
			if (!dens[z - zbase]) /* the voxel rule: no orientation there */
				bor[z - zs] = 0;
		}
}

/* Flyaway overlay on a box (same layout as loom__exgen_box). */
static void overlay_flyaways(const loom__exgen *g, int64_t x0, int64_t y0,
                             int64_t z0, uint32_t nx, uint32_t ny, uint32_t nz,
                             uint8_t *dens, uint16_t *orient, uint8_t *label)
{
	int64_t lo[3] = {x0 < 0 ? 0 : x0, y0 < 0 ? 0 : y0, z0 < 0 ? 0 : z0};
	int64_t hi[3] = {x0 + nx, y0 + ny, z0 + nz}; /* exclusive */

	for (int a = 0; a < 3; a++)
		if (hi[a] > (int64_t)g->size[a])
			hi[a] = g->size[a];
	for (uint32_t f = 0; f < g->n_fly; f++) {
		const flyaway *fa = &g->fly[f];
		float r2max = fa->r * fa->r;
		if (fa->hi[0] < lo[0] || fa->lo[0] > hi[0] - 1 || fa->hi[1] < lo[1] ||
		    fa->lo[1] > hi[1] - 1 || fa->hi[2] < lo[2] || fa->lo[2] > hi[2] - 1)
			continue;
		for (uint32_t k = 0; k < fa->n; k++) {
			const float *q = fa->pos + 3 * k;
			int64_t vlo[3], vhi[3];
			int skip = 0;
			for (int a = 0; a < 3; a++) {
				vlo[a] = (int64_t)ceilf(q[a] - fa->r);
				vhi[a] = (int64_t)floorf(q[a] + fa->r);
				if (vlo[a] < lo[a])
					vlo[a] = lo[a];
				if (vhi[a] > hi[a] - 1)
					vhi[a] = hi[a] - 1;
				if (vlo[a] > vhi[a])
					skip = 1;
			}
			if (skip)
				continue;
			for (int64_t y = vlo[1]; y <= vhi[1]; y++)
				for (int64_t x = vlo[0]; x <= vhi[0]; x++)
					for (int64_t z = vlo[2]; z <= vhi[2]; z++) {
						float dx = (float)x - q[0], dy = (float)y - q[1];
						float dz = (float)z - q[2], d2 = dx * dx + dy * dy + dz * dz;
						size_t i;
						uint8_t dv, lv;
						if (d2 >= r2max)
							continue;
						i = ((size_t)(y - y0) * nx + (size_t)(x - x0)) * nz +
						    (size_t)(z - z0);
						lv = label[i];
						if (lv && !(g->table[lv].flags & LOOM_DB_YARN_FLYAWAY))
							continue; /* inside a yarn */
						dv = loom__density_encode(fa->peak * (1.0f - d2 / r2max));
						if (dv > dens[i]) {
							dens[i] = dv;
							orient[i] = fa->code[k];
							label[i] = fa->label;
						}
					}
		}
	}
}

int loom__exgen_box(const loom__exgen *g, int64_t x0, int64_t y0, int64_t z0,
                    uint32_t nx, uint32_t ny, uint32_t nz, uint8_t *density,
                    uint16_t *orientation, uint8_t *label)
{
	size_t n = (size_t)nx * ny * nz;
	int64_t zs = z0 < 0 ? 0 : z0, ze = z0 + nz;
	float cov[ZCHUNK], best[ZCHUNK];
	line_cache lc;

	memset(density, 0, n);
	memset(orientation, 0, n * sizeof *orientation);
	memset(label, 0, n);
	if (ze > (int64_t)g->size[2])
		ze = g->size[2];
	if (g->fibres && line_cache_init(g, &lc) != LOOM_OK)
		return LOOM_ENOMEM;
	/* tiles of LINE_TILE columns along x, rows within a tile */
	for (uint32_t i0 = 0; i0 < nx; i0 += LINE_TILE) {
		uint32_t i1 = i0 + LINE_TILE < nx ? i0 + LINE_TILE : nx;
		for (uint32_t j = 0; j < ny; j++) {
			int64_t y = y0 + j;
			if (y < 0 || y >= (int64_t)g->size[1])
				continue;
			for (uint32_t i = i0; i < i1; i++) {
				int64_t x = x0 + i;
				size_t col = ((size_t)j * nx + i) * nz;
				if (x < 0 || x >= (int64_t)g->size[0] || zs >= ze)
					continue;
				if (!g->fibres) {
					gen_column(g, x, y, zs, ze, z0, density + col, orientation + col,
					           label + col);
					continue;
				}
				for (int64_t za = zs; za < ze; za += ZCHUNK)
					gen_column_fibres(g, &lc, x, y, i - i0, za,
					                  za + ZCHUNK < ze ? za + ZCHUNK : ze, z0,
					                  density + col, orientation + col, label + col,
					                  cov, best);
			}
		}
	}
	if (g->fibres)
		free(lc.mem);
	overlay_flyaways(g, x0, y0, z0, nx, ny, nz, density, orientation, label);
	return LOOM_OK;
}

/* ---- construction -------------------------------------------------------- */

/* Half-width and half-height (um) of a yarn of free diameter d (um) lying
   at lateral spacing S: flattened to 1.3 d wide (at most 0.92 S, where it
   meets its neighbours) and 0.85 of its area kept (the yarn is pressed),
   so a round 200 um yarn becomes 260 x 111 um.  d = 0: the defaults. */
static void yarn_radii(float d, float S, float a_def, float c_def, float *a,
                       float *c)
{
	float w;

	if (!(d > 0.0f)) {
		*a = a_def;
		*c = c_def;
		return;
	}
	w = fminf(1.3f * d, 0.92f * S);
	*a = 0.5f * w;
	*c = 0.5f * 0.85f * d * d / w;
}

/* Cross-sections and crimp of both kinds from the spacings Sx, Sy (um) and
   the free yarn diameters (0 = in proportion to the spacing). */
static void kind_shapes(kind_params kp[3], float Sx, float Sy, const float d[2])
{
	kind_params *w = &kp[KIND_WARP], *f = &kp[KIND_WEFT];
	float total;

	/* warp: wide, flat, little crimp (it is under tension), Z twist */
	yarn_radii(d[0], Sx, 0.44f * Sx, 0.17f * Sy, &w->a, &w->c);
	/* weft: narrower, rounder, more crimp, S twist, more twist */
	yarn_radii(d[1], Sy, 0.43f * Sy, 0.21f * Sy, &f->a, &f->c);
	/* at an interlacing both yarns are pressed to (1 - COMPRESS) of their
	   half-height and touch */
	total = (1.0f - COMPRESS) * (w->c + f->c);
	w->crimp = 0.38f * total;
	f->crimp = 0.62f * total;
}

/* Largest distance (um) of a yarn surface from the mid-plane, with margin
   for the per-yarn and along-yarn variation. */
static float cloth_half_um(float Sx, float Sy, const float d[2])
{
	kind_params kp[3];

	kind_shapes(kp, Sx, Sy, d);
	return 1.2f * fmaxf((1.0f + FLOAT_RISE) * kp[KIND_WARP].crimp + kp[KIND_WARP].c,
	                    (1.0f + FLOAT_RISE) * kp[KIND_WEFT].crimp + kp[KIND_WEFT].c);
}

static void set_kinds(loom__exgen *g, const float diam[2])
{
	kind_params *w = &g->kp[KIND_WARP], *f = &g->kp[KIND_WEFT];

	kind_shapes(g->kp, g->Sx, g->Sy, diam);
	w->omega = 2.0f * (float)M_PI / (7.0f * g->Sx);
	f->omega = -2.0f * (float)M_PI / (7.0f * g->Sy);
	w->dmax = 0.86f;
	f->dmax = 0.78f;
	w->fibre = fmaxf(12.0f, 1.2f * g->vs);
	f->fibre = fmaxf(15.0f, 1.2f * g->vs);
	w->jit_lat = 0.025f * g->Sx;
	f->jit_lat = 0.03f * g->Sy;
	w->jit_z = 0.06f * w->c;
	f->jit_z = 0.08f * f->c;
	w->jit_r = 0.05f;
	f->jit_r = 0.06f;
	w->spacing = g->Sy;
	f->spacing = g->Sx;
	w->noise_len = 0.9f * g->Sy;
	f->noise_len = 0.9f * g->Sx;
	w->misalign = 0.05f;
	f->misalign = 0.07f;
}

/* Fibre-level parameters of a kind from its preset and cross-section. */
static void fibre_setup(loom__exgen *g, int kind, const fibre_preset *fp)
{
	kind_params *kp = &g->kp[kind];
	float Req = sqrtf(kp->a * kp->c), sgn = kind == KIND_WARP ? 1.0f : -1.0f;
	float sn, n;

	kp->fp = fp;
	kp->plies = fp->plies;
	sn = sinf((float)M_PI / (float)fp->plies);
	kp->rp = fp->plies > 1 ? sn / (1.0f + sn) : 1.0f;
	/* two plies pressed together flatten against each other and widen into
	   the room beside them (Zhao et al.'s elliptical plies): half-axes
	   0.6 towards the yarn centre (centres 0.4 from it, so that the plies
	   meet along a chord instead of touching at a point, with no hole down
	   the middle of the yarn) and 0.75 across */
	if (fp->plies == 2) {
		kp->rp = 0.6f;
		kp->rt = 0.75f;
	} else {
		kp->rt = kp->rp;
	}
	if (fp->d > 0.0f) {
		/* the fibres cover fp->fill of the yarn's (round) section */
		n = fp->fill * 4.0f * Req * Req / ((float)fp->plies * fp->d * fp->d);
		n = fminf(fmaxf(n, 1.0f), (float)(MAX_FIB / fp->plies));
		kp->per_ply = (uint32_t)lroundf(n);
	} else {
		kp->per_ply = 1;
	}
	/* singles twisted Z, plied S on the warp; the weft the other way.  The
	   angles are those seen on the top of the flattened yarn (as under a
	   microscope): a fibre at the ply surface (its mean migration radius
	   less the fibre's radius) and a ply centre, at half-width a.  On the
	   ply's outer side a fibre moves across at R (rt (om_f - om_p) +
	   rp om_p) per um (the fibre turns at om_f, the ply frame at om_p) */
	{
		float rtop = 0.5f * (fp->rmin + fp->rmax) * (1.0f - (fp->d > 0 ? 0.5f * fp->d / (kp->rt * Req) : 0));
		float want = tanf(fp->fib_deg * (float)M_PI / 180.0f) / (kp->a * rtop);
		kp->om_p = fp->plies > 1 ? -sgn * tanf(fp->ply_deg * (float)M_PI / 180.0f) /
		                                   ((1.0f - kp->rp) * kp->a)
		                         : 0.0f;
		kp->om_f = sgn * want / kp->rt + kp->om_p * (1.0f - kp->rp / kp->rt);
	}
	/* the fibre footprint: a disc of the fibre's area, flattened with the
	   yarn (half-width a, half-height c against the round yarn of radius
	   Req), as a rectangle of the same area */
	kp->w1 = fp->d * 0.886227f * kp->a / Req;
	kp->w2 = fp->d * 0.886227f * kp->c / Req;
	kp->mig_k = 2.0f * (float)M_PI / (fp->mig * 2.0f * Req);
	kp->cell = fp->hair + fp->loop > 0.0f ? 1000.0f / (fp->hair + fp->loop) : 0.0f;
	kp->hair_max = 1.5f * fp->hair_len;
	kp->out = 1.0f + 1.05f * (HAIR_CLEAR + fp->hair_out) + fp->d / fminf(kp->a, kp->c);
	if (fp->d == 0.0f)
		kp->out = 1.0f;
}

/* Radial density of fibres in a ply (R in [0, 1]), at most 1. */
static float fibre_density(const fibre_preset *fp, float R)
{
	float e = 2.7182818f, q = (e - expf(R)) / (e - 1.0f);
	return ((1.0f - 2.0f * fp->eps) * powf(q > 0 ? q : 0, fp->beta) + fp->eps) /
	       (1.0f - fp->eps);
}

/* Fibres of yarn y (tab: 6 floats per fibre): per ply, darts drawn from the
   radial density in the ply's unit disc and kept FIB_GAP fibre diameters
   apart from the ply's other fibres (in the round yarn, the disc scaled
   to the ply's larger half-axis; fibres of a pressed ply and of different
   plies may overlap a little, as in a compressed yarn), until per_ply are
   placed or FIB_MISS darts in a row miss.  A grid of cells one gap wide
   finds the neighbours.  Sets y->n_fib; LOOM_ENOMEM. */
#define FIB_GAP 0.8f
#define FIB_MISS 400
static int make_fibres(const loom__exgen *g, yarn *y, float *tab)
{
	const kind_params *kp = &g->kp[y->kind];
	const fibre_preset *fp = kp->fp;
	float Req = sqrtf(kp->a * kp->c);
	float fr = fp->d > 0 ? 0.5f * fp->d / (kp->rt * Req) : 0.0f; /* ply units */
	float dmin = 2.0f * FIB_GAP * fr, Rmax = 1.0f - fr, cell;
	uint32_t n = 0, G;
	int32_t *head, *next;

	y->fib = tab;
	y->n_fib = 0;
	G = dmin > 0.0f ? (uint32_t)ceilf(2.0f / dmin) : 1;
	if (G > 256)
		G = 256;
	cell = 2.0f / (float)G;
	head = malloc(sizeof *head * (size_t)G * G);
	next = malloc(sizeof *next * (kp->per_ply + 1));
	if (!head || !next) {
		free(head);
		free(next);
		return LOOM_ENOMEM;
	}
	for (uint32_t j = 0; j < kp->plies; j++) {
		uint32_t first = n, miss = 0;
		uint64_t k = 0;
		for (size_t c = 0; c < (size_t)G * G; c++)
			head[c] = -1;
		while (n - first < kp->per_ply && miss < FIB_MISS) {
			uint64_t h = hash2(y->seed ^ 0xf1b, j, (int64_t)k++);
			float R = fp->d > 0 ? Rmax * sqrtf(u01(h)) : 0.0f;
			float th = 6.2831853f * u01(mix64(h ^ 1)), X, Y;
			int ok = fp->d == 0.0f || u01(mix64(h ^ 2)) < fibre_density(fp, R);
			int gx, gy;
			X = R * cosf(th);
			Y = R * sinf(th);
			gx = (int)((X + 1.0f) / cell);
			gy = (int)((Y + 1.0f) / cell);
			gx = gx < 0 ? 0 : gx >= (int)G ? (int)G - 1 : gx;
			gy = gy < 0 ? 0 : gy >= (int)G ? (int)G - 1 : gy;
			for (int yy = gy - 1; ok && yy <= gy + 1; yy++)
				for (int xx = gx - 1; ok && xx <= gx + 1; xx++) {
					if (xx < 0 || yy < 0 || xx >= (int)G || yy >= (int)G)
						continue;
					for (int32_t i = head[yy * (int)G + xx]; ok && i >= 0;
					     i = next[i]) {
						const float *f = tab + 6 * (first + (uint32_t)i);
						float dx = f[0] * f[1] - X, dy = f[0] * f[2] - Y;
						if (dx * dx + dy * dy < dmin * dmin)
							ok = 0;
					}
				}
			if (!ok) {
				miss++;
				continue;
			}
			miss = 0;
			{
				float mu = 6.2831853f * u01(mix64(h ^ 3)), *f = tab + 6 * n;
				f[0] = R;
				f[1] = cosf(th);
				f[2] = sinf(th);
				f[3] = cosf(mu);
				f[4] = sinf(mu);
				f[5] = (float)j;
			}
			next[n - first] = head[gy * (int)G + gx];
			head[gy * (int)G + gx] = (int32_t)(n - first);
			n++;
		}
	}
	free(head);
	free(next);
	y->n_fib = n;
	return LOOM_OK;
}

/*
 * Crossing heights and cross-section factors of yarn y, one per crossing of
 * its repeat (tab: 3 x period floats).  At crossing i in a run of L equal
 * crossings (a float of length L; b before and f after i), with the profile
 * p = sin(pi (b + 1/2) / L) (1 in the middle of a long float, small at its
 * ends) and free = 1 - 1/L (0 for an interlacing):
 *   height      sign * (1 + FLOAT_RISE * free * p): a float is not pulled
 *               down between its ends, and its stiffness arches it up, the
 *               more the longer it is;
 *   half-width  (1 + COMPRESS/2 * pressed) (1 + SPREAD * free * p);
 *   half-height 1 - COMPRESS * pressed, where pressed = 1 at an interlacing
 *               (L = 1), 1/2 at a float's ends, 0 inside a float:
 *               lenticular where the crossing yarn presses it, spread and
 *               rounder where it floats free.
 */
static void yarn_mechanics(const loom__exgen *g, yarn *y, float *tab)
{
	uint32_t P = y->kind == KIND_WARP ? g->rows : g->cols;

	y->period = P;
	y->hgt = tab;
	y->wfac = tab + P;
	y->cfac = tab + 2 * P;
	for (uint32_t i = 0; i < P; i++) {
		float sg = crossing_sign(g, y, i), loose, prof, pressed;
		uint32_t b = 0, f = 0, L;
		while (b < P && crossing_sign(g, y, (int64_t)i - b - 1) == sg)
			b++;
		while (f < P && crossing_sign(g, y, (int64_t)i + f + 1) == sg)
			f++;
		if (b + f + 1 >= P) { /* the whole repeat floats */
			L = P;
			prof = 1.0f;
			pressed = 0.0f;
		} else {
			L = b + f + 1;
			prof = sinf((float)M_PI * ((float)b + 0.5f) / (float)L);
			pressed = L == 1 ? 1.0f : (b == 0 || f == 0) ? 0.5f : 0.0f;
		}
		loose = 1.0f - 1.0f / (float)L;
		tab[i] = sg * (1.0f + FLOAT_RISE * loose * prof);
		tab[P + i] = (1.0f + 0.5f * COMPRESS * pressed) * (1.0f + SPREAD * loose * prof);
		tab[2 * P + i] = 1.0f - COMPRESS * pressed;
	}
}

static void init_yarn(loom__exgen *g, yarn *y, int kind, int index, uint8_t label)
{
	uint64_t h = hash2(g->seed, kind, index);

	y->kind = kind;
	y->index = index;
	y->label = label;
	y->seed = h;
	y->centre = ((float)index + 0.5f) * (kind == KIND_WARP ? g->Sx : g->Sy);
	y->wscale = 1.0f + 0.08f * (u01(mix64(h ^ 1)) - 0.5f);
	y->hscale = 1.0f + 0.12f * (u01(mix64(h ^ 2)) - 0.5f);
	y->phase = 6.2831853f * u01(mix64(h ^ 3));
	g->table[label].kind = (uint8_t)kind;
	g->table[label].index = (int16_t)index;
	g->table[label].flags = (index < 0 || index >= (int)(kind == KIND_WARP ? g->cols
	                                                                       : g->rows))
	                                ? LOOM_DB_YARN_OUTSIDE : 0;
}

static void bezier(const float P[4][3], float t, float p[3], float d[3])
{
	float s = 1.0f - t;
	for (int k = 0; k < 3; k++) {
		p[k] = s * s * s * P[0][k] + 3 * s * s * t * P[1][k] +
		       3 * s * t * t * P[2][k] + t * t * t * P[3][k];
		d[k] = 3 * s * s * (P[1][k] - P[0][k]) + 6 * s * t * (P[2][k] - P[1][k]) +
		       3 * t * t * (P[3][k] - P[2][k]);
	}
}

static int make_flyaway(loom__exgen *g, uint32_t f)
{
	flyaway *fa = &g->fly[f];
	uint64_t h = hash2(g->seed ^ 0xf1f1, f, 0);
	int warp = (h & 1) != 0;
	const yarn *y = warp ? &g->warps[1 + (h >> 8) % g->cols]
	                     : &g->wefts[1 + (h >> 8) % g->rows];
	const kind_params *kp = &g->kp[y->kind];
	float extent = warp ? (float)g->size[1] * g->vs : (float)g->size[0] * g->vs;
	float s0 = (0.1f + 0.8f * u01(mix64(h ^ 10))) * extent;
	float lat, zc, a, c, P[4][3], dirh[3], len = 0, L, H, Hend, side, mixl;
	float blo[2], bhi[2]; /* the root's block, less the fibre's margin */
	float fr = 7.0f; /* fibre radius, um */
	float zmax = (float)g->size[2] * g->vs - 2.0f * g->vs;

	yarn_eval(g, y, s0, &lat, &zc, &a, &c);
	side = u01(mix64(h ^ 11)) - 0.5f;
	/* root on the top surface, a little off the yarn axis */
	P[0][0] = warp ? lat + side * a : s0;
	P[0][1] = warp ? s0 : lat + side * a;
	P[0][2] = zc + c * sqrtf(1.0f - side * side) * 0.9f;
	L = kp->spacing * (0.8f + 1.4f * u01(mix64(h ^ 12)));
	H = c * (1.0f + 2.0f * u01(mix64(h ^ 13)));
	Hend = H * (0.2f + 0.8f * u01(mix64(h ^ 14)));
	mixl = 0.8f * (u01(mix64(h ^ 15)) - 0.5f);
	/* the fibre stays inside the block (crossing) of its root, so that a
	   block copied elsewhere never shows a flyaway cut at its edge: it
	   leans towards the farther end of the block along its yarn and is
	   shortened to fit (a Bezier curve lies in the hull of its control
	   points) */
	{
		float S[2] = {g->Sx, g->Sy}, margin = fr + g->vs;
		for (int k = 0; k < 2; k++) {
			float b0 = floorf(P[0][k] / S[k]) * S[k];
			blo[k] = b0 + margin;
			bhi[k] = b0 + S[k] - margin;
			if (P[0][k] < blo[k])
				P[0][k] = blo[k];
			if (P[0][k] > bhi[k])
				P[0][k] = bhi[k];
		}
	}
	{
		int along = warp ? 1 : 0;
		float sgn = P[0][along] - blo[along] > bhi[along] - P[0][along] ? -1.0f : 1.0f;
		dirh[along] = sgn;
		dirh[1 - along] = mixl;
	}
	dirh[2] = 0.0f;
	normalize3(dirh);
	for (int k = 0; k < 2; k++) {
		float room = dirh[k] > 0 ? (bhi[k] - P[0][k]) / dirh[k]
		             : dirh[k] < 0 ? (blo[k] - P[0][k]) / dirh[k] : INFINITY;
		if (L > room)
			L = room > 0 ? room : 0;
	}
	for (int k = 0; k < 2; k++) {
		P[1][k] = P[0][k] + dirh[k] * L * 0.25f;
		P[2][k] = P[0][k] + dirh[k] * L * 0.7f;
		P[3][k] = P[0][k] + dirh[k] * L;
	}
	P[1][2] = P[0][2] + H;
	P[2][2] = P[0][2] + H * 1.1f;
	P[3][2] = P[0][2] + Hend;
	for (int i = 1; i < 4; i++) {
		float d2 = 0;
		if (P[i][2] > zmax)
			P[i][2] = zmax;
		for (int k = 0; k < 3; k++)
			d2 += (P[i][k] - P[i - 1][k]) * (P[i][k] - P[i - 1][k]);
		len += sqrtf(d2);
	}
	fa->n = (uint32_t)ceilf(len / (0.4f * g->vs)) + 1;
	if (fa->n > 20000)
		fa->n = 20000;
	fa->pos = malloc(sizeof(float) * 3 * fa->n);
	fa->code = malloc(sizeof(uint16_t) * fa->n);
	if (!fa->pos || !fa->code)
		return LOOM_ENOMEM;
	fa->r = fmaxf(fr / g->vs, 0.75f);
	fa->peak = 0.8f * fminf(1.0f, (fr / g->vs) * (fr / g->vs) / (fa->r * fa->r));
	fa->label = (uint8_t)(g->n_labels + 1);
	g->n_labels++;
	g->table[fa->label].kind = (uint8_t)y->kind;
	g->table[fa->label].index = (int16_t)y->index;
	g->table[fa->label].flags = LOOM_DB_YARN_FLYAWAY;
	for (int k = 0; k < 3; k++) {
		fa->lo[k] = INFINITY;
		fa->hi[k] = -INFINITY;
	}
	for (uint32_t i = 0; i < fa->n; i++) {
		float p[3], d[3], t = fa->n > 1 ? (float)i / (float)(fa->n - 1) : 0.0f;
		bezier((const float(*)[3])P, t, p, d);
		for (int k = 0; k < 3; k++) {
			float q = p[k] / g->vs - 0.5f;
			fa->pos[3 * i + k] = q;
			fa->lo[k] = fminf(fa->lo[k], q - fa->r);
			fa->hi[k] = fmaxf(fa->hi[k], q + fa->r);
		}
		fa->code[i] = loom__orient_encode(d[0], d[1], d[2]);
	}
	return LOOM_OK;
}

int loom__exgen_check(const loom_exgen_params *p, loom_diag *diag)
{
	if (!p)
		return loom__fail(diag, LOOM_EINVAL, "generator: NULL parameters");
	if (p->size != sizeof *p)
		return loom__fail(diag, LOOM_EINVAL, "generator: parameters of size %zu, "
		                  "expected %zu (initialise with loom_exgen_preset)",
		                  p->size, sizeof *p);
	if (p->db_version > LOOM__DB_VERSION)
		return loom__fail(diag, LOOM_EINVAL, "exemplar generator: database version "
		                  "%u, expected 0 (the default, 4) or 1..%u", p->db_version,
		                  LOOM__DB_VERSION);
	if (p->density_raw > 1 || (p->density_raw && p->db_version == 1))
		return loom__fail(diag, LOOM_EINVAL, "exemplar generator: density_raw %u "
		                  "with database version %u (expected 0 or 1, and 1 only with "
		                  "version 0, 2, 3 or 4: version 1 stores a brick as one stream)",
		                  p->density_raw, p->db_version);
	if (p->block[0] < 2 || p->block[1] < 2 || p->block[2] < 4 ||
	    p->block[0] > LOOM__DB_MAX_BLOCK || p->block[1] > LOOM__DB_MAX_BLOCK ||
	    p->block[2] > LOOM__DB_MAX_BLOCK)
		return loom__fail(diag, LOOM_EINVAL, "generator: block %ux%ux%u (expected "
		                  "at least 2x2x4, at most %u per axis)", p->block[0],
		                  p->block[1], p->block[2], LOOM__DB_MAX_BLOCK);
	if (!(p->voxel_size_um > 0.0f) || !(p->voxel_size_um <= 10000.0f))
		return loom__fail(diag, LOOM_EINVAL, "generator: voxel size %g um (expected "
		                  "0 < size <= 10000)", (double)p->voxel_size_um);
	if (p->n_weaves < 1 || p->n_weaves > LOOM_EXGEN_MAX_WEAVES)
		return loom__fail(diag, LOOM_EINVAL, "generator: %u weaves (expected 1..%u)",
		                  p->n_weaves, LOOM_EXGEN_MAX_WEAVES);
	if (p->rows > MAX_SIDE || p->cols > MAX_SIDE)
		return loom__fail(diag, LOOM_EINVAL, "generator: %ux%u crossings (at most "
		                  "%u per side)", p->rows, p->cols, MAX_SIDE);
	if (p->min_crossings > MAX_SIDE)
		return loom__fail(diag, LOOM_EINVAL, "generator: at least %u crossings per "
		                  "side asked (at most %u)", p->min_crossings, MAX_SIDE);
	for (int k = 0; k < 2; k++) {
		const char *f = p->fibre[k];
		if (f && strcmp(f, "none") && !fibre_find(f))
			return loom__fail(diag, LOOM_EINVAL, "generator: %s fibre '%s' (expected "
			                  "none, cotton, rayon, silk, polyester, wool, linen or "
			                  "monofilament)", k ? "weft" : "warp", f);
	}
	if (p->n_pairs > LOOM_EXGEN_MAX_PAIRS)
		return loom__fail(diag, LOOM_EINVAL, "generator: %u material pairs (at "
		                  "most %d)", p->n_pairs, LOOM_EXGEN_MAX_PAIRS);
	if (p->n_pairs >= 2 && (uint64_t)p->n_pairs * p->n_weaves > LOOM__DB_MAX_EXEMPLARS)
		return loom__fail(diag, LOOM_EINVAL, "generator: %u pairs x %u weaves "
		                  "are more than %u exemplars", p->n_pairs, p->n_weaves,
		                  LOOM__DB_MAX_EXEMPLARS);
	for (uint32_t i = 0; p->n_pairs >= 2 && i < p->n_pairs; i++) {
		int c[2];
		for (int k = 0; k < 2; k++) {
			const char *f = p->pairs[i][k] ? p->pairs[i][k] : p->pairs[i][1 - k];
			if (!f || loom_fibre_parse(f, &c[k]) != LOOM_OK)
				return loom__fail(diag, LOOM_EINVAL, "generator: pair %u: %s fibre "
				                  "'%s' (expected none, cotton, rayon, silk, "
				                  "polyester, wool, linen or monofilament)", i + 1,
				                  k ? "weft" : "warp", f ? f : "(none given)");
		}
		if ((c[0] == LOOM_FIBRE_NONE) != (c[1] == LOOM_FIBRE_NONE))
			return loom__fail(diag, LOOM_EINVAL, "generator: pair %u: fibres "
			                  "'none' and '%s' cannot be mixed", i + 1,
			                  loom_fibre_name(c[0] == LOOM_FIBRE_NONE ? c[1] : c[0]));
		for (uint32_t j = 0; j < i; j++) {
			int e[2];
			for (int k = 0; k < 2; k++)
				loom_fibre_parse(p->pairs[j][k] ? p->pairs[j][k] : p->pairs[j][1 - k],
				                 &e[k]);
			if (e[0] == c[0] && e[1] == c[1])
				return loom__fail(diag, LOOM_EINVAL, "generator: pairs %u and %u "
				                  "are both %s/%s", j + 1, i + 1,
				                  loom_fibre_name(c[0]), loom_fibre_name(c[1]));
		}
	}
	if ((fibre_find(p->fibre[0]) && p->fibre[1] && !fibre_find(p->fibre[1])) ||
	    (fibre_find(p->fibre[1]) && p->fibre[0] && !fibre_find(p->fibre[0])))
		return loom__fail(diag, LOOM_EINVAL, "generator: fibres 'none' and '%s' "
		                  "cannot be mixed (both yarns fibre-level or neither)",
		                  fibre_find(p->fibre[0]) ? p->fibre[0] : p->fibre[1]);
	if (p->threads > 64)
		return loom__fail(diag, LOOM_EINVAL, "generator: %u threads (at most 64)",
		                  p->threads);
	for (int k = 0; k < 2; k++) {
		float S = (float)p->block[k] * p->voxel_size_um, d = p->yarn_diameter_um[k];
		if (d == 0.0f)
			continue;
		if (!(d > 0.0f) || !(d <= 4.0f * S))
			return loom__fail(diag, LOOM_EINVAL, "generator: %s yarn diameter %g "
			                  "um (expected 0 < d <= %g um: 4 times the %s "
			                  "spacing of %g um)", k ? "weft" : "warp", (double)d,
			                  4.0 * S, k ? "pick" : "end", (double)S);
	}
	if (p->yarn_diameter_um[0] > 0.0f || p->yarn_diameter_um[1] > 0.0f) {
		float half = cloth_half_um((float)p->block[0] * p->voxel_size_um,
		                           (float)p->block[1] * p->voxel_size_um,
		                           p->yarn_diameter_um);
		uint32_t need = 2 * (uint32_t)ceilf(half / p->voxel_size_um) + 4;
		if (p->block[2] < need)
			return loom__fail(diag, LOOM_EINVAL, "generator: block depth %u voxels "
			                  "is too thin for yarns of %g and %g um (needs at "
			                  "least %u)", p->block[2], (double)p->yarn_diameter_um[0],
			                  (double)p->yarn_diameter_um[1], need);
	}
	return LOOM_OK;
}

LOOM_API int loom_exgen_check_params(const loom_exgen_params *p, loom_diag *diag)
{
	return loom__exgen_check(p, diag);
}

LOOM_API int loom_exgen_set_sett(loom_exgen_params *p, double ends_per_cm,
                                 double picks_per_cm, loom_diag *diag)
{
	const double sett[2] = {ends_per_cm, picks_per_cm};
	static const char *const what[2] = {"ends", "picks"};
	uint32_t b[2], need;
	float half;

	if (!p || !(p->voxel_size_um > 0.0f))
		return loom__fail(diag, LOOM_EINVAL, "sett: no parameters or voxel size");
	for (int k = 0; k < 2; k++) {
		double v;
		if (!(sett[k] > 0.0) || !(sett[k] <= 1e5))
			return loom__fail(diag, LOOM_EINVAL, "sett: %g %s per cm (expected a "
			                  "positive number)", sett[k], what[k]);
		v = 1e4 / (sett[k] * p->voxel_size_um);
		if (v < 3.5)
			return loom__fail(diag, LOOM_EINVAL, "sett: %g %s per cm at %g um "
			                  "voxels gives crossings of %.1f voxels (at least 4: "
			                  "at most %.4g %s per cm at this voxel size, or a "
			                  "voxel size of at most %.3g um)", sett[k], what[k],
			                  (double)p->voxel_size_um, v,
			                  1e4 / (3.5 * p->voxel_size_um), what[k],
			                  1e4 / (3.5 * sett[k]));
		if (v >= LOOM__DB_MAX_BLOCK + 0.5)
			return loom__fail(diag, LOOM_EINVAL, "sett: %g %s per cm at %g um "
			                  "voxels gives crossings of %.0f voxels (at most %u: "
			                  "use coarser voxels)", sett[k], what[k],
			                  (double)p->voxel_size_um, v, LOOM__DB_MAX_BLOCK);
		b[k] = (uint32_t)lround(v);
		if (sett[k] < 2 || sett[k] > 200)
			loom__warn(diag, "sett: %g %s per cm is unusual for woven cloth "
			           "(2..200)", sett[k], what[k]);
	}
	p->block[0] = b[0];
	p->block[1] = b[1];
	half = cloth_half_um((float)b[0] * p->voxel_size_um,
	                     (float)b[1] * p->voxel_size_um, p->yarn_diameter_um);
	need = 2 * (uint32_t)ceilf(half / p->voxel_size_um) + 4;
	if (need > LOOM__DB_MAX_BLOCK)
		need = LOOM__DB_MAX_BLOCK;
	if (p->block[2] < need)
		p->block[2] = need;
	return LOOM_OK;
}

/* The least side of an automatic window: p->min_crossings, 0 meaning 4. */
static uint32_t min_side(const loom_exgen_params *p)
{
	return p->min_crossings ? p->min_crossings : 4;
}

/* The smallest multiple of repeat >= min_side(p). */
static uint32_t auto_side(const loom_exgen_params *p, uint32_t repeat)
{
	uint32_t m = repeat;
	while (m < min_side(p))
		m += repeat;
	return m;
}

/* Geometry, seed and the weave array of a model whose rows, cols and
   weave_name are set (the weave cells are filled by the caller). */
static int model_init(loom__exgen *g, const loom_exgen_params *p,
                      uint32_t variant, const char *key)
{
	g->b1 = p->block[0];
	g->b2 = p->block[1];
	g->b3 = p->block[2];
	g->size[0] = g->cols * g->b1;
	g->size[1] = g->rows * g->b2;
	g->size[2] = g->b3;
	g->vs = p->voxel_size_um;
	g->Sx = (float)g->b1 * g->vs;
	g->Sy = (float)g->b2 * g->vs;
	g->seed = mix64(p->seed ^ loom__fnv1a64(LOOM__FNV_OFFSET, key, strlen(key)) ^
	                mix64(variant + 0x5151));
	g->weave = malloc((size_t)g->rows * g->cols);
	return g->weave ? LOOM_OK : LOOM_ENOMEM;
}

/* Mid-plane, yarn sizes and fibres, yarns, labels, mechanics and
   flyaways of a model with its weave.  More yarns than labels (a whole
   design, loom__exgen_new_design): the interior labels are reused
   cyclically, so a label's kind is exact and its index is that of one of
   the yarns sharing it.  LOOM_ENOMEM (the caller frees g). */
static int model_yarns(loom__exgen *g, const loom_exgen_params *p)
{
	uint32_t nw = g->cols + 2, nf = g->rows + 2, wl = nw, fl = nf;
	int shared = 0;

	/* mid-plane: the same z in every exemplar of a database (blocks copied
	   from different exemplars must not step in height) */
	g->z0 = (float)g->b3 * g->vs * 0.5f;
	set_kinds(g, p->yarn_diameter_um);
	{
		const fibre_preset *fw = fibre_find(p->fibre[0]), *ff = fibre_find(p->fibre[1]);
		if (!fw && !p->fibre[0])
			fw = ff;
		if (!ff && !p->fibre[1])
			ff = fw;
		if (fw && ff) {
			fibre_setup(g, KIND_WARP, fw);
			fibre_setup(g, KIND_WEFT, ff);
		}
	}
	g->warps = calloc(g->cols + 2, sizeof *g->warps);
	g->wefts = calloc(g->rows + 2, sizeof *g->wefts);
	if (!g->warps || !g->wefts)
		return LOOM_ENOMEM;
	if (nw + nf + MAX_FLY > 255) {
		wl = nw < DESIGN_LABELS ? nw : DESIGN_LABELS;
		fl = nf < DESIGN_LABELS ? nf : DESIGN_LABELS;
		shared = wl < nw || fl < nf;
	}
	for (int c = -1; c <= (int)g->cols; c++)
		init_yarn(g, &g->warps[c + 1], KIND_WARP, c,
		          (uint8_t)(1 + (uint32_t)(c + 1) % wl));
	for (int r = -1; r <= (int)g->rows; r++)
		init_yarn(g, &g->wefts[r + 1], KIND_WEFT, r,
		          (uint8_t)(1 + wl + (uint32_t)(r + 1) % fl));
	g->n_labels = wl + fl;
	/* a shared label is an interior yarn's: no "outside" flag, and the
	   index of a window yarn (the cut yarns at -1 and cols/rows also share
	   labels, so clamp their index into the window, as readers require) */
	for (uint32_t l = 1; shared && l <= g->n_labels; l++) {
		int32_t lim = l <= wl ? (int32_t)g->cols : (int32_t)g->rows;
		g->table[l].flags = 0;
		if (g->table[l].index < 0)
			g->table[l].index = 0;
		if (g->table[l].index >= lim)
			g->table[l].index = (int16_t)(lim - 1);
	}
	g->mech = malloc(sizeof(float) * 3 * ((size_t)(g->cols + 2) * g->rows +
	                                     (size_t)(g->rows + 2) * g->cols));
	if (!g->mech)
		return LOOM_ENOMEM;
	{
		float *t = g->mech;
		for (uint32_t c = 0; c < g->cols + 2; c++, t += 3 * g->rows)
			yarn_mechanics(g, &g->warps[c], t);
		for (uint32_t r = 0; r < g->rows + 2; r++, t += 3 * g->cols)
			yarn_mechanics(g, &g->wefts[r], t);
	}
	if (g->kp[KIND_WARP].fp) {
		size_t used = 0;
		size_t tot = 6 * ((size_t)(g->cols + 2) * g->kp[KIND_WARP].plies *
		                          g->kp[KIND_WARP].per_ply +
		                  (size_t)(g->rows + 2) * g->kp[KIND_WEFT].plies *
		                          g->kp[KIND_WEFT].per_ply);
		g->fibres = 1;
		g->fibs = malloc(sizeof(float) * tot);
		if (!g->fibs)
			return LOOM_ENOMEM;
		for (uint32_t c = 0; c < g->cols + 2; c++) {
			if (make_fibres(g, &g->warps[c], g->fibs + used) != LOOM_OK)
				return LOOM_ENOMEM;
			used += 6 * (size_t)g->warps[c].n_fib;
		}
		for (uint32_t r = 0; r < g->rows + 2; r++) {
			if (make_fibres(g, &g->wefts[r], g->fibs + used) != LOOM_OK)
				return LOOM_ENOMEM;
			used += 6 * (size_t)g->wefts[r].n_fib;
		}
	}
	g->n_fly = g->rows * g->cols / 4;
	if (g->n_fly < 2)
		g->n_fly = 2;
	if (g->n_fly > MAX_FLY)
		g->n_fly = MAX_FLY;
	for (uint32_t f = 0; f < g->n_fly; f++)
		if (make_flyaway(g, f) != LOOM_OK)
			return LOOM_ENOMEM;
	return LOOM_OK;
}

int loom__exgen_new(const loom_exgen_params *p, uint32_t k, uint32_t variant,
                    loom__exgen **out, loom_diag *diag)
{
	loom_weave_params wp;
	loom__exgen *g;
	uint32_t rr, rc, r0, c0;
	uint64_t h;
	int rcode;

	*out = NULL;
	rcode = loom__exgen_check(p, diag);
	if (rcode)
		return rcode;
	if (k >= p->n_weaves || !p->weaves[k])
		return loom__fail(diag, LOOM_EINVAL, "generator: no weave %u", k);
	rcode = loom_weave_parse(p->weaves[k], &wp, diag);
	if (!rcode)
		rcode = loom_weave_repeat(&wp, &rr, &rc, diag);
	if (rcode) {
		if (diag) {
			char why[LOOM_DIAG_MSG_MAX];
			snprintf(why, sizeof why, "%s", diag->message);
			loom__fail(diag, rcode, "weave %u '%s': %s", k + 1, p->weaves[k], why);
		}
		return rcode;
	}
	g = calloc(1, sizeof *g);
	if (!g)
		return loom__fail(diag, LOOM_ENOMEM, "generator: out of memory");
	g->rows = p->rows ? p->rows : auto_side(p, rr);
	g->cols = p->cols ? p->cols : auto_side(p, rc);
	if ((!p->rows && g->rows > MAX_SIDE) || (!p->cols && g->cols > MAX_SIDE)) {
		loom__exgen_free(g);
		return loom__fail(diag, LOOM_EINVAL, "weave '%s' repeats every %ux%u "
		                  "crossings: its smallest multiple of at least %u crossings "
		                  "a side is %ux%u, above the largest window (%u a side)",
		                  p->weaves[k], rr, rc, min_side(p),
		                  auto_side(p, rr), auto_side(p, rc), MAX_SIDE);
	}
	if (g->rows % rr || g->cols % rc || g->rows > MAX_SIDE || g->cols > MAX_SIDE) {
		loom__exgen_free(g);
		return loom__fail(diag, LOOM_EINVAL, "weave '%s' repeats every %ux%u "
		                  "crossings, which does not tile a %ux%u window (use "
		                  "multiples of the repeat, at most %u)", p->weaves[k], rr,
		                  rc, p->rows ? p->rows : auto_side(p, rr),
		                  p->cols ? p->cols : auto_side(p, rc), MAX_SIDE);
	}
	loom_weave_name(&wp, g->weave_name, sizeof g->weave_name);
	snprintf(g->name, sizeof g->name, "%s", g->weave_name);
	for (char *s = g->name; *s; s++)
		if (*s == ':' || *s == '/' || *s == '=')
			*s = '-';
	if (variant) {
		size_t n = strlen(g->name);
		snprintf(g->name + (n > 24 ? 24 : n), sizeof g->name - (n > 24 ? 24 : n),
		         "-%u", variant + 1);
	}
	rcode = model_init(g, p, variant, g->weave_name);
	if (rcode) {
		loom__exgen_free(g);
		return loom__fail(diag, rcode, "generator: out of memory");
	}
	h = mix64(g->seed ^ 0xabc);
	r0 = (uint32_t)(h % rr);
	c0 = (uint32_t)((h >> 32) % rc);
	for (uint32_t r = 0; r < g->rows; r++)
		for (uint32_t c = 0; c < g->cols; c++)
			g->weave[(size_t)r * g->cols + c] =
			        (uint8_t)loom_weave_cell(&wp, r + r0, c + c0);
	rcode = model_yarns(g, p);
	if (rcode) {
		loom__exgen_free(g);
		return loom__fail(diag, rcode, "generator: out of memory");
	}
	*out = g;
	return LOOM_OK;
}

int loom__exgen_new_design(const loom_exgen_params *p, const char *name,
                           uint32_t rows, uint32_t cols, const uint8_t *weave,
                           loom__exgen **out, loom_diag *diag)
{
	loom__exgen *g;
	int rc;

	*out = NULL;
	rc = loom__exgen_check(p, diag);
	if (rc)
		return rc;
	if (!weave || rows < 1 || cols < 1 || rows > LOOM_EXGEN_MAX_DESIGN ||
	    cols > LOOM_EXGEN_MAX_DESIGN ||
	    (uint64_t)cols * p->block[0] > LOOM__DB_MAX_EXTENT ||
	    (uint64_t)rows * p->block[1] > LOOM__DB_MAX_EXTENT)
		return loom__fail(diag, LOOM_ERANGE, "generator: a design of %ux%u crossings "
		                  "(at most %u per side and %u voxels along x and y: %ux%u "
		                  "crossings at block %ux%u)", rows, cols,
		                  LOOM_EXGEN_MAX_DESIGN, LOOM__DB_MAX_EXTENT,
		                  loom_exgen_design_limit(p->block[1]),
		                  loom_exgen_design_limit(p->block[0]), p->block[0],
		                  p->block[1]);
	g = calloc(1, sizeof *g);
	if (!g)
		return loom__fail(diag, LOOM_ENOMEM, "generator: out of memory");
	g->rows = rows;
	g->cols = cols;
	snprintf(g->name, sizeof g->name, "%s", name && *name ? name : "design");
	snprintf(g->weave_name, sizeof g->weave_name, "design:%ux%u", rows, cols);
	rc = model_init(g, p, 0, g->name);
	if (!rc) {
		memcpy(g->weave, weave, (size_t)rows * cols);
		rc = model_yarns(g, p);
	}
	if (rc) {
		loom__exgen_free(g);
		return loom__fail(diag, rc, "generator: out of memory");
	}
	*out = g;
	return LOOM_OK;
}

LOOM_API uint32_t loom_exgen_design_limit(uint32_t block)
{
	uint32_t n = LOOM__DB_MAX_EXTENT / (block ? block : 1);
	return n < LOOM_EXGEN_MAX_DESIGN ? n : LOOM_EXGEN_MAX_DESIGN;
}

void loom__exgen_free(loom__exgen *g)
{
	if (!g)
		return;
	for (uint32_t f = 0; f < MAX_FLY; f++) {
		free(g->fly[f].pos);
		free(g->fly[f].code);
	}
	free(g->weave);
	free(g->warps);
	free(g->wefts);
	free(g->mech);
	free(g->fibs);
	free(g);
}

void loom__exgen_describe(const loom__exgen *g, loom__exgen_desc *d)
{
	d->name = g->name;
	d->weave_name = g->weave_name;
	d->rows = g->rows;
	d->cols = g->cols;
	d->weave = g->weave;
	memcpy(d->size, g->size, sizeof d->size);
	d->n_yarns = g->n_labels;
	d->yarns = g->table;
	d->fibre[0] = g->tag[0];
	d->fibre[1] = g->tag[1];
}

void loom__exgen_tag(loom__exgen *g, int warp, int weft)
{
	size_t n = strlen(g->name);

	g->tag[0] = (uint8_t)warp;
	g->tag[1] = (uint8_t)weft;
	if (n > 24) /* "@WW-FF" fits in the 31 bytes */
		n = 24;
	snprintf(g->name + n, sizeof g->name - n, "@%s-%s", loom_fibre_short(warp),
	         loom_fibre_short(weft));
}

void loom__exgen_fibres(const loom__exgen *g, int kind, loom__exgen_fibre *f)
{
	const kind_params *kp = &g->kp[kind == 2 ? KIND_WEFT : KIND_WARP];

	memset(f, 0, sizeof *f);
	if (!kp->fp)
		return;
	f->plies = kp->plies;
	f->per_ply = kp->per_ply;
	f->fibre_deg = kp->fp->fib_deg;
	f->ply_deg = kp->fp->ply_deg;
	f->hair_per_mm = kp->fp->hair;
	f->loop_per_mm = kp->fp->loop;
	f->placed = kind == 2 ? g->wefts[1].n_fib : g->warps[1].n_fib;
}

float loom__exgen_mid_z(const loom__exgen *g)
{
	return g->z0 / g->vs - 0.5f;
}

void loom__exgen_section(const loom__exgen *g, int kind, int index, float t,
                         float out[4])
{
	const yarn *y = kind == 2 ? &g->wefts[index + 1] : &g->warps[index + 1];
	float lat, zc, a, c;

	yarn_eval(g, y, (t + 0.5f) * g->vs, &lat, &zc, &a, &c);
	out[0] = lat / g->vs - 0.5f;
	out[1] = zc / g->vs - 0.5f;
	out[2] = a / g->vs;
	out[3] = c / g->vs;
}

/* ---- presets ------------------------------------------------------------ */

/* The paper's eight, then three that complete the neighbourhood codes
   (docs/fidelity.md, "Exemplar coverage"): the S twills give the corners
   of herringbone turns, broken twills and baskets (codes 10, 11, 20, 21),
   basket 1/3 the warp and weft ribs (6, 9, 14, 17, 22, 25), so every code
   of loom_synth_code has a source block.  The 1/7 and 7/1 satins add floats
   of seven (the others' are at most four): the 5-bit code sees a float's
   neighbours but not its length, and a long float sits higher than a short
   one ("Per-block height offsets" there). */
static const char *const default_weaves[] = {
	"twill:2/3", "twill:3/2", "twill:1/4", "twill:4/1",
	"satin:2/3", "satin:3/2", "satin:1/4", "satin:4/1",
	"twill:2/3:s", "twill:3/2:s", "basket:1/3",
	"satin:1/7", "satin:7/1",
};
#define N_DEFAULT_WEAVES (sizeof default_weaves / sizeof default_weaves[0])

LOOM_API int loom_exgen_preset(const char *name, loom_exgen_params *p)
{
	static const struct {
		const char *name;
		uint32_t b[3];
		float vs;
	} presets[] = {
		{"paper", {115, 70, 300}, 5.0f},
		{"small", {24, 16, 48}, 24.0f},
		{"tiny", {8, 6, 12}, 72.0f},
	};

	if (!name || !p)
		return LOOM_EINVAL;
	for (size_t i = 0; i < sizeof presets / sizeof presets[0]; i++) {
		if (strcmp(name, presets[i].name) != 0)
			continue;
		memset(p, 0, sizeof *p);
		p->size = sizeof *p;
		memcpy(p->block, presets[i].b, sizeof p->block);
		p->voxel_size_um = presets[i].vs;
		p->n_weaves = (uint32_t)N_DEFAULT_WEAVES;
		for (size_t k = 0; k < N_DEFAULT_WEAVES; k++)
			p->weaves[k] = default_weaves[k];
		p->seed = 1;
		p->brick[0] = LOOM_DB_DEFAULT_BRICK_X;
		p->brick[1] = LOOM_DB_DEFAULT_BRICK_Y;
		p->brick[2] = LOOM_DB_DEFAULT_BRICK_Z;
		p->level = LOOM_DB_DEFAULT_LEVEL;
		p->threads = 2;
		return LOOM_OK;
	}
	return LOOM_EINVAL;
}
