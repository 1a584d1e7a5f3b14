/*
 * tests/unit/test_scan_synth.h - synthetic "scans" of a woven sheet with
 * known ground truth, for tests/unit/test_scan.c and bench/bench_scan.c.
 * Independent of the library code it checks (own blur, own geometry).
 *
 * The sheet lives in the aligned frame (u, v, z): warp j is a tube along v
 * at u = x0 + j*sx, weft i a tube along u at v = y0 + i*sy.  Centre lines
 * rise and fall with the weave (crimp): at crossing (i,j) the warp is at
 * zc + warp_amp when W(i,j) = 1 (warp over) and zc - warp_amp otherwise, the
 * weft the opposite, with cosine blends between crossings.  Cross sections
 * are ellipses (lateral semi-axis, z semi-axis measured perpendicular to the
 * tangent).  Inside, the density has a fibre texture: value noise on the
 * cross-section coordinates, constant along the yarn, so the structure
 * tensor sees fibres.  The scan shows the sheet turned by angle_deg about z
 * around the volume centre c = ((nx-1)/2, (ny-1)/2): scan point s shows
 * aligned point a = c + R(-angle)(s - c), the same convention as
 * loom_scan_aligned_to_scan.  Then Gaussian blur (the scanner's PSF) and
 * Gaussian noise, clamped to [0,1].
 */
#ifndef LOOM_TEST_SCAN_SYNTH_H
#define LOOM_TEST_SCAN_SYNTH_H

#include "loom.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct synth_spec {
	uint32_t nx, ny, nz;
	uint32_t nw, nf;          /* warps and wefts of the sheet */
	float sx, sy;             /* spacing */
	float x0, y0;             /* aligned u of warp 0, v of weft 0 */
	float warp_w, warp_h;     /* warp semi-axes: lateral, z */
	float weft_w, weft_h;
	float warp_amp, weft_amp; /* crimp amplitudes */
	float zc;                 /* mid-plane */
	float angle_deg;
	float blur, noise;        /* PSF sigma (voxels), noise sigma */
	float fibre;              /* fibre texture cell size (voxels) */
	uint64_t seed;
	const char *const *weave; /* repeat rows ('1' = warp over), NULL-ended */
	int with_orient;          /* fill vol.orient with the true tangents */
	int pure_noise;           /* no sheet: uniform noise */
	long rep_r, rep_c;        /* weave repeat size (set by synth_alloc) */
} synth_spec;

typedef struct synth_out {
	loom_scan_volume vol;     /* density (+ orient) */
	uint8_t *truth;           /* 0 empty, 1..nw warps, nw+1..nw+nf wefts */
	float *tangent;           /* 3 per voxel, unit, zero outside yarns */
	float *inside;            /* normalised radius r (< 1 inside), 9 outside */
} synth_out;

static inline uint64_t synth_mix(uint64_t z)
{
	z += 0x9E3779B97F4A7C15ull;
	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
	return z ^ (z >> 31);
}

static inline double synth_unit(uint64_t h)
{
	return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}

static inline int synth_w(const synth_spec *s, long i, long j)
{
	long R = s->rep_r, C = s->rep_c;
	if (!R) {
		C = (long)strlen(s->weave[0]);
		while (s->weave[R])
			R++;
	}
	i %= R;
	j %= C;
	if (i < 0)
		i += R;
	if (j < 0)
		j += C;
	return s->weave[i][j] == '1';
}

/* crimp profile h in [-1,1] and its derivative along the yarn, for a yarn
   whose crossing values are val(k) at positions p0 + k*step */
static inline void synth_crimp(const synth_spec *s, int warp, long yarn,
                               double pos, double p0, double step, double *h,
                               double *dh)
{
	double f = (pos - p0) / step;
	long k = (long)floor(f);
	double t = f - k, a, b;
	if (warp) {
		a = synth_w(s, k, yarn) ? 1 : -1;
		b = synth_w(s, k + 1, yarn) ? 1 : -1;
	} else {
		a = synth_w(s, yarn, k) ? -1 : 1;
		b = synth_w(s, yarn, k + 1) ? -1 : 1;
	}
	*h = a * 0.5 * (1 + cos(M_PI * t)) + b * 0.5 * (1 - cos(M_PI * t));
	*dh = (b - a) * 0.5 * M_PI * sin(M_PI * t) / step;
}

/* Foot point of (pos, z) on a yarn's centre curve z = zc + amp h(pos) in
   the (pos, z) plane, by Newton steps on the projection onto the tangent:
   returns the curve's height and slope there and the signed distance along
   the normal, so (lateral, normal) coordinates are constant along offset
   curves (fibres) and the tangent at the foot is the fibre direction. */
static inline void synth_foot(const synth_spec *s, int warp, long yarn,
                              double pos, double z, double p0, double step,
                              double amp, double *zc, double *slope, double *dn)
{
	double f = pos, h, dh, n;
	for (int it = 0; it < 4; it++) {
		double zf, sl;
		synth_crimp(s, warp, yarn, f, p0, step, &h, &dh);
		zf = s->zc + amp * h;
		sl = amp * dh;
		f += ((pos - f) + sl * (z - zf)) / (1 + sl * sl);
	}
	synth_crimp(s, warp, yarn, f, p0, step, &h, &dh);
	*zc = s->zc + amp * h;
	*slope = amp * dh;
	n = sqrt(1 + *slope * *slope);
	*dn = (-(*slope) * (pos - f) + (z - *zc)) / n;
}

static inline double synth_fibre(uint64_t seed, long yarn, double a, double b,
                                 double cell)
{
	double fa = a / cell, fb = b / cell;
	long ia = (long)floor(fa), ib = (long)floor(fb);
	double ta = fa - ia, tb = fb - ib, v[2][2];
	ta = ta * ta * (3 - 2 * ta);
	tb = tb * tb * (3 - 2 * tb);
	for (int p = 0; p < 2; p++)
		for (int q = 0; q < 2; q++)
			v[p][q] = synth_unit(synth_mix(seed ^ synth_mix((uint64_t)yarn * 1000003u ^
			                     synth_mix((uint64_t)(ia + p) * 92821u ^
			                               (uint64_t)(ib + q) * 68917u))));
	return (1 - ta) * ((1 - tb) * v[0][0] + tb * v[0][1]) +
	       ta * ((1 - tb) * v[1][0] + tb * v[1][1]);
}

/* Evaluate the clean sheet at scan voxel (x,y,z). */
static inline void synth_voxel(const synth_spec *s, uint32_t x, uint32_t y,
                               uint32_t z, float *dens, uint8_t *lab,
                               float tan_out[3], float *rad)
{
	double cx = (s->nx - 1) * 0.5, cy = (s->ny - 1) * 0.5;
	double th = s->angle_deg * M_PI / 180, c = cos(th), sn = sin(th);
	double dx = x - cx, dy = y - cy;
	double u = cx + c * dx + sn * dy, v = cy - sn * dx + c * dy;
	double best = 1e30, bt[3] = {0, 0, 0}, bl = 0, bz = 0;
	long by = -1;

	/* warps near u */
	long jn = lround((u - s->x0) / s->sx);
	for (long j = jn - 1; j <= jn + 1; j++) {
		double du, zc, slope, dz, r2, n;
		if (j < 0 || j >= (long)s->nw)
			continue;
		du = u - (s->x0 + j * s->sx);
		if (fabs(du) >= 1.5 * s->warp_w ||
		    fabs(z - s->zc) >= s->warp_amp + 1.5 * s->warp_h)
			continue; /* far: r > 1.5 */
		synth_foot(s, 1, j, v, z, s->y0, s->sy, s->warp_amp, &zc, &slope, &dz);
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
	long in_ = lround((v - s->y0) / s->sy);
	for (long i = in_ - 1; i <= in_ + 1; i++) {
		double dv, zc, slope, dz, r2, n;
		if (i < 0 || i >= (long)s->nf)
			continue;
		dv = v - (s->y0 + i * s->sy);
		if (fabs(dv) >= 1.5 * s->weft_w ||
		    fabs(z - s->zc) >= s->weft_amp + 1.5 * s->weft_h)
			continue;
		synth_foot(s, 0, i, u, z, s->x0, s->sx, s->weft_amp, &zc, &slope, &dz);
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
	*rad = best < 81 ? (float)sqrt(best) : 9.0f;
	if (best < 1) {
		*dens = (float)(0.55 + 0.45 * synth_fibre(s->seed, by, bl, bz, s->fibre));
		*lab = (uint8_t)(by + 1);
		for (int k = 0; k < 3; k++)
			tan_out[k] = (float)bt[k];
	} else {
		*dens = 0;
		*lab = 0;
		tan_out[0] = tan_out[1] = tan_out[2] = 0;
	}
}

/* Separable Gaussian blur with clamped borders (reference code). */
static inline int synth_blur(float *d, uint32_t nx, uint32_t ny, uint32_t nz,
                             float sigma)
{
	int r = (int)ceil(3 * sigma);
	double w[64], sum = 0;
	size_t n[3] = {nx, ny, nz}, st[3] = {1, nx, (size_t)nx * ny};
	size_t maxn = nx > ny ? nx : ny;
	float *line;

	if (!(sigma > 0))
		return 0;
	if (r > 31)
		r = 31;
	for (int k = -r; k <= r; k++)
		sum += w[k + r] = exp(-0.5 * k * k / ((double)sigma * sigma));
	for (int k = 0; k <= 2 * r; k++)
		w[k] /= sum;
	maxn = maxn > nz ? maxn : nz;
	line = malloc(maxn * sizeof *line);
	if (!line)
		return -1;
	for (int a = 0; a < 3; a++) {
		size_t total = (size_t)nx * ny * nz, lines = total / n[a];
		if (n[a] < 2)
			continue;
		for (size_t li = 0; li < lines; li++) {
			size_t base;
			/* the li-th line along axis a */
			if (a == 0)
				base = li * nx;
			else if (a == 1)
				base = (li / nx) * nx * ny + li % nx;
			else
				base = li;
			for (size_t i = 0; i < n[a]; i++)
				line[i] = d[base + i * st[a]];
			for (size_t i = 0; i < n[a]; i++) {
				double acc = 0;
				for (int k = -r; k <= r; k++) {
					long q = (long)i + k;
					q = q < 0 ? 0 : q >= (long)n[a] ? (long)n[a] - 1 : q;
					acc += w[k + r] * line[q];
				}
				d[base + i * st[a]] = (float)acc;
			}
		}
	}
	free(line);
	return 0;
}

static inline void synth_free(synth_out *o)
{
	loom_scan_volume_release(&o->vol);
	free(o->truth);
	free(o->tangent);
	free(o->inside);
	memset(o, 0, sizeof *o);
}

/* Generate planes [z0, z1) of the clean sheet (density, truth) into o,
   which synth_make allocated; used to split work across threads. */
static inline void synth_planes(const synth_spec *s, synth_out *o, uint32_t z0,
                                uint32_t z1)
{
	for (uint32_t z = z0; z < z1; z++)
		for (uint32_t y = 0; y < s->ny; y++)
			for (uint32_t x = 0; x < s->nx; x++) {
				size_t i = ((size_t)z * s->ny + y) * s->nx + x;
				float t[3], r;
				uint8_t lab;
				if (s->pure_noise) {
					o->vol.density[i] = (float)synth_unit(synth_mix(s->seed ^ (i * 7919u)));
					continue;
				}
				synth_voxel(s, x, y, z, &o->vol.density[i], &lab, t, &r);
				if (o->truth)
					o->truth[i] = lab;
				if (o->tangent)
					memcpy(o->tangent + 3 * i, t, sizeof t);
				if (o->inside)
					o->inside[i] = r;
			}
}

/* Blur, add noise, clamp, copy orientation; after all planes are made. */
static inline int synth_finish(const synth_spec *s, synth_out *o)
{
	size_t n = (size_t)s->nx * s->ny * s->nz;
	if (s->pure_noise)
		return 0;
	if (synth_blur(o->vol.density, s->nx, s->ny, s->nz, s->blur))
		return -1;
	for (size_t i = 0; i < n; i++) {
		double d = o->vol.density[i];
		if (s->noise > 0) {
			double u1 = synth_unit(synth_mix(s->seed * 31 + 2 * i + 1));
			double u2 = synth_unit(synth_mix(s->seed * 31 + 2 * i + 2));
			d += s->noise * sqrt(-2 * log(u1 + 1e-300)) * cos(2 * M_PI * u2);
		}
		o->vol.density[i] = (float)(d < 0 ? 0 : d > 1 ? 1 : d);
	}
	if (s->with_orient && o->tangent)
		memcpy(o->vol.orient, o->tangent, 3 * n * sizeof(float));
	return 0;
}

/* Allocate o; keep_truth 0 (and no with_orient) allocates the density
   only (bench: less memory). */
static inline int synth_alloc(synth_spec *s, synth_out *o, int keep_truth)
{
	size_t n = (size_t)s->nx * s->ny * s->nz;
	memset(o, 0, sizeof *o);
	s->rep_c = s->weave ? (long)strlen(s->weave[0]) : 0;
	s->rep_r = 0;
	while (s->weave && s->weave[s->rep_r])
		s->rep_r++;
	if (loom_scan_volume_alloc(&o->vol, s->nx, s->ny, s->nz,
	                           LOOM_SCAN_DENSITY |
	                               (s->with_orient ? LOOM_SCAN_ORIENT : 0)) != LOOM_OK)
		return -1;
	if (!keep_truth && !s->with_orient)
		return 0; /* density only (bench) */
	o->truth = malloc(n);
	if (!o->truth)
		return -1;
	{
		o->tangent = malloc(3 * n * sizeof(float));
		o->inside = malloc(n * sizeof(float));
		if (!o->tangent || !o->inside)
			return -1;
	}
	return 0;
}

static inline int synth_make(synth_spec *s, synth_out *o)
{
	if (synth_alloc(s, o, 1)) {
		synth_free(o);
		return -1;
	}
	synth_planes(s, o, 0, s->nz);
	if (synth_finish(s, o)) {
		synth_free(o);
		return -1;
	}
	return 0;
}

/* A default small sheet: 160 x 160 x 40, 7 warps x 9 wefts (spacing 24 x
   18, yarns 18 x 10 and 14 x 10 voxels), turned by 3 degrees, partial yarns
   at the borders. */
static inline synth_spec synth_default(const char *const *weave)
{
	synth_spec s;
	memset(&s, 0, sizeof s);
	s.nx = 160;
	s.ny = 160;
	s.nz = 40;
	s.nw = 7;
	s.nf = 9;
	s.sx = 24;
	s.sy = 18;
	s.x0 = 6;
	s.y0 = 7;
	s.warp_w = 9;
	s.warp_h = 5;
	s.weft_w = 7;
	s.weft_h = 5;
	s.warp_amp = 5.5f;
	s.weft_amp = 5.5f;
	s.zc = 20;
	s.angle_deg = 3;
	s.blur = 0.8f;
	s.noise = 0.08f;
	s.fibre = 1.5f;
	s.seed = 7;
	s.weave = weave;
	return s;
}

#endif
