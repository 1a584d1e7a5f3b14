/*
 * tests/unit/test_scan_synth.h - synthetic "scans" of a woven sheet with
 * known ground truth, for tests/unit/test_scan.c: a thin wrapper around
 * the library's generator (loom_scan_sheet_*, engine/scan/scan_sheet.c, which
 * `loom exemplar generate --scan` uses too) taking the weave as strings.
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
#include <stdio.h>
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

/* The library's sheet for a spec (wbuf: room for the repeat). */
static inline void synth_sheet(const synth_spec *s, loom_scan_sheet *sh, uint8_t *wbuf)
{
	long R = 0, C = s->weave ? (long)strlen(s->weave[0]) : 0;
	loom_scan_sheet_preset("small", sh);
	while (s->weave && s->weave[R])
		R++;
	for (long i = 0; i < R; i++)
		for (long j = 0; j < C; j++)
			wbuf[i * C + j] = s->weave[i][j] == '1';
	sh->nx = s->nx;
	sh->ny = s->ny;
	sh->nz = s->nz;
	sh->nw = s->nw;
	sh->nf = s->nf;
	sh->sx = s->sx;
	sh->sy = s->sy;
	sh->x0 = s->x0;
	sh->y0 = s->y0;
	sh->warp_w = s->warp_w;
	sh->warp_h = s->warp_h;
	sh->weft_w = s->weft_w;
	sh->weft_h = s->weft_h;
	sh->warp_amp = s->warp_amp;
	sh->weft_amp = s->weft_amp;
	sh->zc = s->zc;
	sh->angle_deg = s->angle_deg;
	sh->blur = s->blur;
	sh->noise = s->noise;
	sh->fibre = s->fibre;
	sh->seed = s->seed;
	sh->rep_rows = (uint32_t)R;
	sh->rep_cols = (uint32_t)C;
	sh->weave = wbuf;
	sh->pure_noise = s->pure_noise;
}

static inline void synth_free(synth_out *o)
{
	loom_scan_volume_release(&o->vol);
	free(o->truth);
	free(o->tangent);
	memset(o, 0, sizeof *o);
}

/* Make the scan with loom_scan_sheet_make (engine/scan/scan_sheet.c): density,
   truth labels, true tangents (also in vol.orient when with_orient). */
static inline int synth_make(synth_spec *s, synth_out *o)
{
	size_t n = (size_t)s->nx * s->ny * s->nz;
	uint8_t wbuf[1024];
	loom_scan_sheet sh;
	memset(o, 0, sizeof *o);
	s->rep_c = s->weave ? (long)strlen(s->weave[0]) : 0;
	s->rep_r = 0;
	while (s->weave && s->weave[s->rep_r])
		s->rep_r++;
	synth_sheet(s, &sh, wbuf);
	if (loom_scan_volume_alloc(&o->vol, s->nx, s->ny, s->nz,
	                           LOOM_SCAN_DENSITY | LOOM_SCAN_ORIENT) != LOOM_OK ||
	    !(o->truth = calloc(n, 1)) ||
	    loom_scan_sheet_make(&sh, &o->vol, o->truth, 2, NULL) != LOOM_OK) {
		synth_free(o);
		return -1;
	}
	if (s->with_orient) {
		o->tangent = malloc(3 * n * sizeof(float));
		if (!o->tangent) {
			synth_free(o);
			return -1;
		}
		memcpy(o->tangent, o->vol.orient, 3 * n * sizeof(float));
	} else {
		o->tangent = o->vol.orient;
		o->vol.orient = NULL;
	}
	return 0;
}

/* Labels against the truth in the scan frame: segment the (denoised) scan
   vol with the result's centre curves moved back to the scan frame.
   acc[0]: fraction of all truth yarn voxels labelled with the right yarn
   (voxels the blur pushed below the threshold count as wrong); acc[1]: the
   same over the truth yarn voxels above the threshold (the labelling
   alone).  Truth labels: 1..nw warps, nw+1.. wefts.  Returns a loom code. */
static inline int synth_scan_accuracy(const loom_scan_volume *vol, const uint8_t *truth,
                                      uint32_t nw, const loom_scan_result *r,
                                      double acc[2], int verbose)
{
	loom_scan_curve *c = calloc(r->n_yarns, sizeof *c);
	size_t n = (size_t)vol->nx * vol->ny * vol->nz, total = 0, right = 0, unl = 0;
	size_t confused = 0;
	uint8_t *lab = malloc(n);
	float *axes = malloc(2 * r->n_yarns * sizeof *axes);
	loom_diag d = {0};
	int rc;

	acc[0] = acc[1] = 0;
	if (!c || !lab || !axes) {
		free(c);
		free(lab);
		free(axes);
		return LOOM_ENOMEM;
	}
	for (uint32_t i = 0; i < r->n_yarns; i++) {
		const loom_scan_yarn *y = &r->yarns[i];
		const float *ax = y->kind == LOOM_SCAN_WARP ? r->warp_ends.semi_axes
		                                            : r->weft_ends.semi_axes;
		c[i].kind = y->kind;
		c[i].n = y->n_points;
		c[i].pts = malloc(3 * y->n_points * sizeof(float));
		for (uint32_t k = 0; k < y->n_points; k++) {
			double sx, sy;
			loom_scan_aligned_to_scan(vol->nx, vol->ny, r->rotation_degrees,
			                          y->points[3 * k] + r->grid.crop[0],
			                          y->points[3 * k + 1] + r->grid.crop[1], &sx, &sy);
			c[i].pts[3 * k] = (float)sx;
			c[i].pts[3 * k + 1] = (float)sy;
			c[i].pts[3 * k + 2] = y->points[3 * k + 2];
		}
		axes[2 * i] = ax[0];
		axes[2 * i + 1] = ax[1];
	}
	rc = loom_scan_segment(vol, r->threshold, c, r->n_yarns, axes,
	                       fmaxf(r->grid.pitch_x, r->grid.pitch_y), 2, lab, NULL, NULL, &d);
	for (size_t i = 0; i < n && rc == LOOM_OK; i++) {
		int t = truth[i], L = lab[i], want;
		const loom_scan_yarn *y;
		if (!t)
			continue;
		total++;
		if (!L) {
			unl++;
			continue;
		}
		y = &r->yarns[L - 1];
		want = y->kind == LOOM_SCAN_WARP ? (int)y->tracked + 1
		                                 : (int)(nw + y->tracked + 1);
		right += want == t;
		confused += (want <= (int)nw) != (t <= (int)nw);
	}
	acc[0] = total ? (double)right / total : 0;
	acc[1] = total > unl ? (double)right / (total - unl) : 0;
	if (verbose && total)
		printf("  scan frame: %.2f%% of %zu yarn voxels labelled with the right yarn; "
		       "%.2f%% of those above the threshold (%.2f%% below it, %.2f%% warp/weft "
		       "confusion; semi-axes warp %.1f x %.1f, weft %.1f x %.1f)\n",
		       100 * acc[0], total, 100 * acc[1], 100.0 * unl / total,
		       100.0 * confused / total, r->warp_ends.semi_axes[0],
		       r->warp_ends.semi_axes[1], r->weft_ends.semi_axes[0],
		       r->weft_ends.semi_axes[1]);
	for (uint32_t i = 0; i < r->n_yarns; i++)
		loom_scan_curve_release(&c[i]);
	free(c);
	free(lab);
	free(axes);
	return rc;
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
