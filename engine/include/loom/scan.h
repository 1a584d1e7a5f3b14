/*
 * loom/scan.h - exemplar creation from volume scans (paper section 6).
 *
 * Turns a scan of a simple weave (density, optionally fibre orientation) into
 * what the exemplar database stores: an aligned volume cropped to whole
 * crossings, with density, orientation and a yarn label per voxel, the weave
 * pattern of its crossings and a yarn table.  Everything works on volumes in
 * memory; reading files is io/'s job, writing the database is db_write's.
 *
 * Conventions (as everywhere in loom, see DESIGN.md):
 *  - axes: x across the ends (along a weft), y along the warps, z up.
 *    Warps run roughly along y, wefts roughly along x.
 *  - volumes: index (z*ny + y)*nx + x; density in [0,1]; orientation is a
 *    line direction (v and -v are the same), the zero vector = undefined.
 *  - weave pattern: row i = pick (weft) i ordered by y, column j = end (warp)
 *    j ordered by x, W(i,j) = 1 when the warp is over.
 *  - labels: 0 = empty / unassigned, L >= 1 = yarn L of the caller's curve
 *    list (curve L-1) or of a result's yarn table (yarns[L-1]).
 *  - aligned frame: the scan rotated about z by -rotation_degrees about the
 *    centre c = ((nx-1)/2, (ny-1)/2) of its xy extent, same dimensions:
 *    aligned (ax, ay, z) shows scan voxel  c + R(rotation) * ((ax,ay) - c).
 *    rotation_degrees is the counter-clockwise angle (from +x toward +y) of
 *    the scan's weave grid relative to the axes.  The crop [x0, y0, w, h] is
 *    given in the aligned frame.
 *
 * The pipeline (loom_scan_build) runs the steps below in order; each step is
 * also callable on its own.  Failures return a loom_result code and leave a
 * message "scan: <step>: ..." in diag:
 *   LOOM_EINVAL       bad arguments (NULL, zero sizes, parameters out of range)
 *   LOOM_EMISMATCH    the data disagree with the user's yarn counts
 *   LOOM_EUNSUPPORTED the data do not support the step (too noisy, tracking
 *                     lost, ambiguous crossings, nothing complete to crop)
 *   LOOM_ENOMEM       allocation failed
 * Memory: besides the caller's volume, loom_scan_build allocates 16-bit
 * orientation codes when no orientation is given (2 bytes per scan voxel,
 * reused in place for the output's codes), the output's density and
 * labels (5 bytes per crop voxel; 7 when the orientation was given), a
 * 1-byte-per-column top map, one code plane, and per-thread working
 * buffers of O(nx * max(ny, nz)) floats; nothing else grows with the
 * volume (docs/scan.md, "Memory").  All functions are thread-safe on
 * distinct data and deterministic: the same input and parameters give the
 * same bytes for any thread count.
 * docs/scan.md describes each step, its parameters and its failure messages.
 */
#ifndef LOOM_SCAN_H
#define LOOM_SCAN_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define LOOM_SCAN_MAX_YARNS 127 /* per kind; labels fit in 8 bits */

enum loom_scan_kind { LOOM_SCAN_WARP = 0, LOOM_SCAN_WEFT = 1 };

/* Pipeline steps, for progress reports and per-step timings. */
enum loom_scan_step {
	LOOM_SCAN_STEP_DENOISE = 0,
	LOOM_SCAN_STEP_ORIENT,
	LOOM_SCAN_STEP_ENDPOINTS,
	LOOM_SCAN_STEP_TRACK,
	LOOM_SCAN_STEP_WEAVE,
	LOOM_SCAN_STEP_SEGMENT,
	LOOM_SCAN_STEP_ALIGN,
	LOOM_SCAN_STEP_REGISTER,
	LOOM_SCAN_STEP_CROP,
	LOOM_SCAN_STEP_COUNT_
};

/* Short name of a step ("denoise", "orientation", ...); never NULL. */
LOOM_API const char *loom_scan_step_name(int step);

/* ---- Volumes ------------------------------------------------------------ */

/*
 * A volume in memory: plain data.  Whoever allocates the arrays frees them;
 * loom_scan_volume_alloc / loom_scan_volume_release use malloc / free.
 */
typedef struct loom_scan_volume {
	uint32_t nx, ny, nz;
	float *density;   /* nx*ny*nz, in [0,1] */
	float *orient;    /* 3 floats per voxel at 3*index, or NULL */
	uint8_t *label;   /* 1 byte per voxel, or NULL */
	uint16_t *ocode;  /* orientation as 16-bit codes (loom_orientation_
	                     encode, the database's encoding; 0 = undefined),
	                     1 per voxel, or NULL; used when orient is NULL */
} loom_scan_volume;

#define LOOM_SCAN_DENSITY 1u /* channel flags for loom_scan_volume_alloc */
#define LOOM_SCAN_ORIENT 2u
#define LOOM_SCAN_LABEL 4u
#define LOOM_SCAN_OCODE 8u

/* Zero *v and allocate the channels named by `channels` (zero-filled).
   LOOM_EINVAL (NULL, a zero size, no channel), LOOM_ERANGE (more than 2^40
   voxels), LOOM_ENOMEM. */
LOOM_API int loom_scan_volume_alloc(loom_scan_volume *v, uint32_t nx,
                                    uint32_t ny, uint32_t nz,
                                    unsigned channels);
/* free() the four arrays and zero *v; NULL is a no-op. */
LOOM_API void loom_scan_volume_release(loom_scan_volume *v);

/* ---- Parameters --------------------------------------------------------- */

/*
 * Distances marked (paper) are in the paper's voxels (5 um, warp spacing
 * about 115 and weft spacing about 70 voxels) and are multiplied by `scale`.
 * Initialise with loom_scan_params_init, then set n_warps and n_wefts.
 */
typedef struct loom_scan_params {
	size_t size;          /* sizeof(loom_scan_params), set by _init */
	uint32_t n_warps;     /* warps in the scan, partial border ones included */
	uint32_t n_wefts;     /* wefts in the scan */
	uint32_t block_x;     /* b1: crossing width in voxels; 0 = measured */
	uint32_t block_y;     /* b2: crossing height in voxels; 0 = measured */
	uint32_t block_z;     /* b3: output depth in voxels, centred on the
	                         cloth (mean z of the centre curves), zero
	                         padded outside the scan; 0 = the scan's nz */
	float threshold;      /* non-empty density; 0 = Otsu on denoised data */
	float denoise_sigma;  /* Gaussian sigma, voxels; 0 = no denoising (1) */
	float tensor_sigma;   /* structure-tensor smoothing sigma, voxels (1.5) */
	float cone_cos;       /* endpoints: voxels with |o.axis| >= this (0.7) */
	uint32_t max_slices;  /* endpoints: slices tried per axis (64) */
	uint32_t kmeans_iters;/* Lloyd iterations at most (50) */
	float gap_ratio;      /* endpoints: neighbouring yarns need a dip below
	                         gap_ratio x the lower peak between them (0.6) */
	float scale;          /* scan voxels per paper voxel; 0 = from measured
	                         spacings: (sx/115 + sy/70)/2 */
	float step;           /* d (paper): 15 */
	float c0;             /* tangent gate |w.t0| >= c0: 0.7 */
	float radius_warp;    /* R for warps (paper): 20 */
	float radius_weft;    /* R for wefts (paper): 30 */
	float ellipse_warp;   /* centre correction: lateral semi-axis for warps
	                         (paper): 40 */
	float ellipse_weft;   /* lateral semi-axis for wefts (paper): 30 */
	float ellipse_z;      /* z semi-axis (paper): 60 */
	uint32_t correct_iters; /* centre-of-mass iterations per step (10) */
	float min_linking;    /* |L| every crossing of the crop must reach (0.25) */
	uint32_t threads;     /* worker threads, >= 1 (2) */
	uint64_t seed;        /* k-means++ seeding (20121126) */
	/* Optional progress report, called on the calling thread at the start
	   (fraction 0) and end (fraction 1) of every step. */
	void (*progress)(void *user, int step, double fraction);
	void *progress_user;
} loom_scan_params;

/* Fill *p with the defaults above (n_warps = n_wefts = 0). */
LOOM_API void loom_scan_params_init(loom_scan_params *p);

/* ---- Step 1: denoising -------------------------------------------------- */

/* Robust noise level (standard deviation) of the density: m / 0.6745 /
   sqrt 6, m the median of |d| over second differences d = v[x-1] - 2 v[x]
   + v[x+1] along x (sd of d = sqrt 6 x the noise's; median |N(0,s)| =
   0.6745 s), on a regular sample of up to 2^20 voxels (structure touches
   few of them, so the median sees the noise).  The median comes from two
   passes of a 4096-bin histogram (resolution 4 / 4096^2), not a sort.
   0 for NULL, nx < 3 or out of memory.  Thread-safe. */
LOOM_API float loom_scan_noise(const loom_scan_volume *v);

/* Separable Gaussian blur of v->density in place, sigma in voxels (kernel
   radius ceil(3 sigma), borders clamped).  sigma 0 is a no-op.
   LOOM_EINVAL, LOOM_ENOMEM. */
LOOM_API int loom_scan_denoise(loom_scan_volume *v, float sigma,
                               uint32_t threads, loom_diag *diag);

/* Otsu threshold of the density histogram (256 bins on [0,1], a sample of
   16 M voxels for larger volumes); when a clean gap makes a plateau of
   equally good thresholds, its middle.  LOOM_EINVAL (NULL),
   LOOM_EUNSUPPORTED when the volume is constant. */
LOOM_API int loom_scan_threshold(const loom_scan_volume *v, float *threshold,
                                 loom_diag *diag);

/* ---- Step 2: orientation ------------------------------------------------ */

typedef struct loom_scan_orient_info {
	uint64_t voxels;      /* voxels above threshold that got a direction */
	float coherence;      /* their mean (l2 - l3) / (l2 + l3) of the tensor
	                         eigenvalues l1 >= l2 >= l3: 1 = clean lines */
} loom_scan_orient_info;

/*
 * Fibre orientation from the structure tensor: gradient by central
 * differences, tensor g g^T smoothed by a Gaussian of tensor_sigma (radius
 * ceil(3 sigma)), fibre direction = unit eigenvector of the smallest
 * eigenvalue (closed form), written to v->orient (3 floats per voxel) or,
 * when that is NULL, as a 16-bit code to v->ocode (one of them must be
 * allocated) for voxels with density > threshold, zero elsewhere and
 * where the tensor has no single smallest direction.  Bounded memory: each
 * thread works on y-tiles of 32 rows with a ring of 2r+1 smoothed tensor
 * planes (about 24 x nx x (32 + 2r) x (2r+1) bytes).  info may be NULL.
 * Same bytes for any thread count.  LOOM_EINVAL, LOOM_ENOMEM.
 */
LOOM_API int loom_scan_orient(loom_scan_volume *v, float threshold,
                              float tensor_sigma, uint32_t threads,
                              loom_scan_orient_info *info, loom_diag *diag);

/* Eigen-decomposition helper: the unit eigenvector of the smallest
   eigenvalue of the symmetric matrix [a00 a01 a02; . a11 a12; . . a22]
   (m = {a00, a01, a02, a11, a12, a22}); eigenvalues descending in ev (may
   be NULL).  Returns 0 when the matrix is (numerically) isotropic and
   dir is set to zero, 1 otherwise. */
LOOM_API int loom_scan_eigen_min(const double m[6], double dir[3],
                                 double ev[3]);

/* ---- Step 3: endpoint detection ----------------------------------------- */

typedef struct loom_scan_endpoints {
	int kind;             /* LOOM_SCAN_WARP (slices y = const) or WEFT (x) */
	uint32_t k;           /* clusters = yarns */
	uint32_t slice;       /* chosen slice (y for warps, x for wefts) */
	float max_radius;     /* its largest RMS cluster radius, voxels */
	float spacing;        /* median distance of neighbouring centres */
	float semi_axes[2];   /* cross-section semi-axes (lateral, z) estimated
	                         from the clusters' RMS spreads (x2) */
	uint32_t slices_tried, slices_valid;
	float centre[LOOM_SCAN_MAX_YARNS][3]; /* x,y,z, by lateral coordinate */
} loom_scan_endpoints;

/*
 * Endpoints of k yarns of a kind: on up to p->max_slices evenly spaced
 * slices perpendicular to y (warps) or x (wefts), K-means (k-means++ seeded
 * from p->seed and the slice, at most 50 Lloyd iterations, on up to 8192
 * points) over the voxels with density > threshold and |o.axis| >=
 * p->cone_cos |o|.  A slice is accepted when its lateral profile (selected
 * voxels per lateral position over 5 slices, smoothed) has bumps separated
 * by dips below p->gap_ratio of the lower peak, one cluster centre per bump,
 * no cluster tiny (< 5% of the median), neighbour gaps within [0.55, 1.45]
 * of the median gap and the largest RMS cluster radius below 0.45 of it.
 * The accepted slice with the smallest largest radius wins.  v->orient must
 * be set (or v->ocode).  Errors: LOOM_EINVAL; LOOM_EMISMATCH when most slices show
 * another number of yarns than k (the message says how many);
 * LOOM_EUNSUPPORTED when no slice shows k separated yarns and the slices
 * disagree (noise, not a simple weave) or there is no oriented material.
 */
LOOM_API int loom_scan_endpoints_find(const loom_scan_volume *v, int kind,
                                      uint32_t k, float threshold,
                                      const loom_scan_params *p,
                                      loom_scan_endpoints *out,
                                      loom_diag *diag);

/* ---- Step 4: tracking --------------------------------------------------- */

typedef struct loom_scan_curve {
	int kind;             /* LOOM_SCAN_WARP or LOOM_SCAN_WEFT */
	uint32_t n;           /* points */
	float *pts;           /* 3n floats (x,y,z), ordered by increasing y
	                         (warps) or x (wefts); malloc'ed */
} loom_scan_curve;

/* free(c->pts) and zero *c; NULL is a no-op. */
LOOM_API void loom_scan_curve_release(loom_scan_curve *c);

/* Effective tracking lengths in scan voxels (paper values times scale). */
typedef struct loom_scan_track_lengths {
	float step, radius, ellipse_lateral, ellipse_z, c0;
	uint32_t correct_iters;
} loom_scan_track_lengths;

/* The lengths for a yarn kind at a scale (p's paper values x scale). */
LOOM_API void loom_scan_track_lengths_get(const loom_scan_params *p, int kind,
                                          float scale,
                                          loom_scan_track_lengths *out);

/*
 * Track one yarn from start in both directions: tangent t = normalize(sum
 * of orientations w, sign-flipped to agree with t0, over voxels with density
 * > threshold inside the ball of radius R with |w.t0| >= c0 |w|; ball
 * sampled every ceil(R/8) voxels); the step direction is kept within 20
 * degrees of the main axis in xy and 50 degrees in z (the scan is roughly
 * aligned); p += d t; then p moves toward the centre of mass on the
 * elliptical region of the slice perpendicular to the main axis, weighted by
 * density x (1 - r^2): z from the voxels oriented along the yarn (|w.t| >=
 * c0 |w|), the lateral position from all material, capped at half the
 * lateral semi-axis from the prediction; repeated until it moves < 0.05.
 * Stops at the volume boundary (the last point is on it).
 * LOOM_EUNSUPPORTED "tracking lost" when no oriented material is found, the
 * tangent turns back (more than 80 degrees), or 2 n/d + 16 steps do not
 * reach the boundary.  *out is released on failure.  Thread-safe.
 */
LOOM_API int loom_scan_track(const loom_scan_volume *v, int kind,
                             const float start[3], float threshold,
                             const loom_scan_track_lengths *len,
                             loom_scan_curve *out, loom_diag *diag);

/* ---- Step 5: weave pattern ---------------------------------------------- */

/* Gaussian linking integral of two open polylines (na, nb points, xyz),
   evaluated exactly per segment pair (solid-angle form). */
LOOM_API double loom_scan_linking(const float *a, uint32_t na,
                                  const float *b, uint32_t nb);

/*
 * Weave pattern of tracked yarns: each warp (parameterised by increasing y)
 * and weft (by decreasing x, so the projected tangents (t_warp, t_weft) are
 * a positively oriented basis) is extended from both ends by 1000 volume
 * diagonals along its end-to-end direction; L > 0 means the warp is above:
 * weave[i*nw + j] = 1 (warp over) if L(warp j, weft i) > 0, else 0.  (The
 * paper writes 0 in that case because its patterns use 0 for warp on top.)
 * linking (nf*nw, may be NULL) receives L.  LOOM_EINVAL.
 */
LOOM_API int loom_scan_weave(const loom_scan_curve *warps, uint32_t nw,
                             const loom_scan_curve *wefts, uint32_t nf,
                             uint32_t nx, uint32_t ny, uint32_t nz,
                             uint8_t *weave, float *linking, loom_diag *diag);

/* ---- Step 6: segmentation ----------------------------------------------- */

/* Integer moments of a yarn's voxel (x,y) positions (exact, so sums do not
   depend on the thread split). */
typedef struct loom_scan_moments {
	uint64_t n;
	int64_t sx, sy, sxx, sxy, syy;
} loom_scan_moments;

/*
 * Label every voxel with density > threshold by the nearest centre curve, if
 * one is within max_dist; label = curve index + 1.  Distance to a polyline
 * is exact per segment.  semi_axes (2n floats: lateral, vertical
 * semi-axis of each curve's cross-section, in voxels) makes the distance
 * elliptical: the offset from the segment is measured across it
 * horizontally and vertically and divided by the curve's semi-axes (times
 * the largest semi-axis, so units stay voxels); NULL = Euclidean, the
 * paper's rule.  Candidates come from a 2D grid of segments.  Outputs, each
 * may be NULL: label (per voxel), top (nx*ny: label of the topmost voxel
 * with density > threshold, 0 if none or unassigned), moments (n entries).
 * n <= 2*LOOM_SCAN_MAX_YARNS.  LOOM_EINVAL, LOOM_ENOMEM.
 */
LOOM_API int loom_scan_segment(const loom_scan_volume *v, float threshold,
                               const loom_scan_curve *curves, uint32_t n,
                               const float *semi_axes, float max_dist,
                               uint32_t threads, uint8_t *label, uint8_t *top,
                               loom_scan_moments *moments, loom_diag *diag);

/*
 * Centre refinement (a loom addition to step 6): one segmentation pass with
 * semi_axes (required) in which every interior point of every curve sums
 * the density of the voxels labelled with its own yarn on its plane
 * (perpendicular to the main axis) within 1.3 x 1.6 semi-axes of it; the
 * point then moves (lateral and z) to that centre of mass.  Corrects the
 * tracker's pull toward crossing yarns, where the orientation field is
 * least reliable.  Sums are integers: deterministic for any thread count.
 * LOOM_EINVAL, LOOM_ENOMEM.
 */
LOOM_API int loom_scan_refine(const loom_scan_volume *v, float threshold,
                              loom_scan_curve *curves, uint32_t n,
                              const float *semi_axes, float max_dist,
                              uint32_t threads, loom_diag *diag);

/* ---- Step 7: alignment -------------------------------------------------- */

/*
 * Rotation of the weave grid from the PCA of each yarn's voxel positions:
 * w0 = voxel-count-weighted mean principal direction of the warps (oriented
 * to +y), w1 of the wefts (to +x); rotation = angle of (w0 + w1)/2 minus 45
 * degrees.  Yarns cut lengthwise by the scan border lean: with 4 or more
 * yarns of a kind, the first and last of it in the list are left out, and
 * so is any yarn with fewer than 3/4 of its kind's median voxel count.
 * kinds[i] is the kind of moments[i]; yarns of a kind in lateral order.
 * dirs (2n, may be NULL) receives each yarn's unit direction.  LOOM_EINVAL,
 * LOOM_EUNSUPPORTED (a kind without usable voxels).
 */
LOOM_API int loom_scan_align(const loom_scan_moments *moments,
                             const int *kinds, uint32_t n,
                             double *rotation_degrees, float *dirs,
                             loom_diag *diag);

/* Scan-frame position of an aligned-frame point (see the top comment). */
LOOM_API void loom_scan_aligned_to_scan(uint32_t nx, uint32_t ny,
                                        double rotation_degrees, double ax,
                                        double ay, double *sx, double *sy);

/* ---- Step 8: registration and crop -------------------------------------- */

typedef struct loom_scan_grid {
	uint32_t first_warp, first_weft; /* tracked index of crop column/row 0 */
	uint32_t cols, rows;  /* complete warps and wefts in the crop */
	uint32_t b1, b2;      /* block size in voxels */
	float pitch_x, pitch_y; /* measured yarn spacing in the aligned frame */
	int32_t crop[4];      /* x0, y0, width, height in the aligned frame */
	int32_t shift[2];     /* registration's move from the curve estimate */
	double score;         /* mean agreement of b with W over the cells */
	double min_cell;      /* the lowest agreement of one cell (central
	                         half) of the chosen window */
	uint32_t worst[2];    /* that cell: row (pick), column (end) */
} loom_scan_grid;

/*
 * Choose the crop (paper 6.5).  top: nx*ny scan-frame labels (from
 * loom_scan_segment); curves: the nw warps ordered by x then the nf wefts
 * ordered by y (labels 1..nw+nf, as given to loom_scan_segment); weave:
 * nf*nw pattern of all of them.  Steps: yarn centres in the aligned frame
 * and pitches (least-squares over the interior yarns); block b1 x b2 =
 * block_x/y or the rounded pitch (a warning through diag when they differ by
 * more than 10%); the largest run of complete yarns whose grid window (cells
 * centred on the yarns) lies inside the scan's footprint; then, with
 * summed-area tables of [b == 1] and [b == 0] on the aligned top-yarn map b
 * (1 = warp on top, 0 = weft, else unknown), every translation within half
 * a block of that window is scored by the sum over cells of the fraction of
 * the cell's central half agreeing with W; the candidate nearest to the
 * centroid of those within 0.5% (per cell) of the best score wins.
 * LOOM_EINVAL, LOOM_EUNSUPPORTED (unordered yarns, fewer than 2 x 2
 * complete crossings, or no window inside the scan).
 */
LOOM_API int loom_scan_register(uint32_t nx, uint32_t ny, const uint8_t *top,
                                const loom_scan_curve *curves, uint32_t nw,
                                uint32_t nf, const uint8_t *weave,
                                double rotation_degrees, uint32_t block_x,
                                uint32_t block_y, loom_scan_grid *out,
                                loom_diag *diag);

/* ---- The whole pipeline ------------------------------------------------- */

typedef struct loom_scan_yarn {
	int kind;             /* LOOM_SCAN_WARP or LOOM_SCAN_WEFT */
	int32_t index;        /* column (warp) / row (weft) of the crop's grid;
	                         < 0 or >= cols/rows: a yarn outside the crop */
	uint32_t tracked;     /* index among tracked yarns of its kind */
	float direction[2];   /* PCA direction in the scan frame (0,0 if the
	                         yarn had too few voxels) */
	uint64_t voxels;      /* voxels with this label in the cropped volume */
	uint32_t n_points;    /* centre curve, cropped volume's coordinates */
	float *points;        /* 3*n_points */
} loom_scan_yarn;

typedef struct loom_scan_result {
	/* What the database writer stores. */
	loom_scan_volume volume; /* aligned and cropped: nx = cols*b1,
	                            ny = rows*b2, nz = b3 (scan planes z0 ..
	                            z0+b3-1, see z0); density (denoised,
	                            bilinear), ocode (orientation codes:
	                            nearest, turned with the volume; orient is
	                            NULL), label */
	uint32_t rows, cols;     /* crossings: picks, ends */
	uint8_t *weave;          /* rows*cols, 1 = warp over */
	uint32_t b1, b2, b3;     /* block size in voxels */
	int32_t z0;              /* scan plane of output plane 0 (0 unless
	                            block_z is set) */
	uint32_t n_yarns;        /* label L <-> yarns[L-1] */
	loom_scan_yarn *yarns;   /* warps by x first, then wefts by y */
	/* Diagnostics. */
	float noise_before, noise_after; /* loom_scan_noise before/after */
	float threshold;         /* density threshold used */
	int orientation_estimated; /* 1 if the scan had no orientation */
	loom_scan_orient_info orient;
	loom_scan_endpoints warp_ends, weft_ends;
	float scale;             /* scan voxels per paper voxel used */
	uint32_t warps_tracked, wefts_tracked;
	uint32_t full_rows, full_cols; /* pattern of all tracked yarns */
	uint8_t *full_weave;     /* full_rows*full_cols */
	float *linking;          /* full_rows*full_cols linking integrals */
	double rotation_degrees; /* see the top comment */
	loom_scan_grid grid;     /* crop, registration score */
	double seconds[LOOM_SCAN_STEP_COUNT_]; /* wall time per step */
	double cpu_seconds[LOOM_SCAN_STEP_COUNT_]; /* process CPU time per step
	                                              (all threads) */
} loom_scan_result;

/*
 * Run the pipeline on scan (at least 16 x 16 x 3 voxels): noise estimate,
 * denoise, threshold (p->threshold or Otsu), orientation (when scan->orient
 * is NULL), endpoints of p->n_warps warps and p->n_wefts wefts, scale (p->
 * scale or (warp spacing/115 + weft spacing/70)/2), tracking, weave of all
 * tracked yarns, segmentation (elliptical metric with the cross-section
 * semi-axes measured at the endpoints, one centre refinement), alignment,
 * registration (checks |L| >= p->min_linking on every crossing of the
 * crop, and that every cell's central half shows the crossing's yarn on
 * top for at least half its columns: grid.min_cell >= 0.5), crop.  The
 * scan's density is denoised in place (p->denoise_sigma > 0).  When the
 * scan has neither orient nor ocode, the orientation field is estimated
 * into 16-bit codes lent to scan->ocode while the steps run, which then
 * become, resampled in place, the result's ocode: scan->ocode is NULL again
 * on return (success or failure).  On success *out holds the result
 * (free with loom_scan_result_free); on failure *out is NULL, the code says
 * what kind of failure (see the top comment) and diag says which step and
 * why ("scan: <step>: ...").  p->progress is called on this thread.  Not
 * reentrant on the same scan; distinct scans may run concurrently.
 */
LOOM_API int loom_scan_build(loom_scan_volume *scan, const loom_scan_params *p,
                             loom_scan_result **out, loom_diag *diag);

/* Free a result and everything it owns; NULL is a no-op. */
LOOM_API void loom_scan_result_free(loom_scan_result *r);

/* ---- Storing a result in an exemplar database ---------------------------- */

typedef struct loom_scan_db_params {
	size_t size;            /* sizeof(loom_scan_db_params), set by _init */
	const char *name;       /* exemplar name, 1..31 bytes, unique in the
	                           database ("scan") */
	const char *weave_name; /* free text, < 32 bytes ("") */
	float voxel_size_um;    /* voxel edge of a new database (5); checked
	                           against an existing one (warning) */
	uint32_t brick[3];      /* brick shape of a new database (16x16x64) */
	int level;              /* deflate level of a new database (6) */
	uint32_t db_version;    /* format version of a new database: 0 (the
	                           default, 4), 1, 2, 3 or 4; appending: 0 or
	                           the database's own (else LOOM_EMISMATCH) */
	uint32_t density_raw;   /* 1: density planes stored raw (versions 2
	                           to 4); appending: only to a database whose
	                           density planes are raw (else LOOM_EMISMATCH:
	                           loom_db_convert it first) */
} loom_scan_db_params;

LOOM_API void loom_scan_db_params_init(loom_scan_db_params *p);

/*
 * Store r as one exemplar (weave r->weave, volume r->volume quantised to
 * the database's voxel encodings, yarn table from r->yarns: warps kind 1,
 * wefts kind 2, yarns outside the crop flagged LOOM_DB_YARN_OUTSIDE) at the
 * end of the database `path`, creating it if it does not exist (block =
 * r->b1 x b2 x b3, format p->db_version, density planes raw if
 * p->density_raw).  An existing database is rewritten atomically (temporary
 * file + rename): its brick data and tables are copied verbatim, so its
 * exemplars read back byte-identical; its header flag "procedural" is
 * cleared.  *appended (may be NULL) says which case happened.  Errors:
 * LOOM_EINVAL (bad arguments, name taken), LOOM_EMISMATCH (the database's
 * block size differs from the result's), the database open errors
 * (loom_db_open), LOOM_EIO, LOOM_ENOMEM; LOOM_EINVAL for db_version > 4
 * or density_raw with version 1, LOOM_EMISMATCH when appending with a
 * db_version or density_raw the database does not have.  Memory: one
 * brick plus the old database's metadata.
 */
LOOM_API int loom_scan_write_db(const loom_scan_result *r, const char *path,
                                const loom_scan_db_params *p, int *appended,
                                loom_diag *diag);

/* ---- Scan-like test volumes (loom exemplar generate --scan) -------------- */

/*
 * A woven sheet as a scanner would show it (engine/scan/scan_sheet.c): warp j
 * is a tube along y at aligned u = x0 + j*sx, weft i along x at v = y0 +
 * i*sy, elliptical cross-sections (semi-axes *_w lateral, *_h vertical),
 * centre lines at zc +- amp following the weave (cosine blends between
 * crossings), fibre texture of cell size `fibre` inside; the sheet turned
 * by angle_deg about z around the volume centre (the convention of
 * loom_scan_aligned_to_scan), then Gaussian blur (sigma `blur`) and
 * Gaussian noise (sigma `noise`) on the density, clamped to [0,1].
 * Labels of the ground truth: 1..nw warps by x, nw+1..nw+nf wefts by y.
 */
typedef struct loom_scan_sheet {
	size_t size;              /* sizeof(loom_scan_sheet), set by _preset */
	uint32_t nx, ny, nz;      /* scan voxels */
	uint32_t nw, nf;          /* warps and wefts of the sheet */
	float sx, sy;             /* yarn spacing (voxels) */
	float x0, y0;             /* aligned u of warp 0, v of weft 0 */
	float warp_w, warp_h, weft_w, weft_h; /* semi-axes */
	float warp_amp, weft_amp; /* crimp amplitudes */
	float zc;                 /* mid-plane */
	float angle_deg;          /* rotation about z, counter-clockwise */
	float blur, noise;        /* PSF sigma (voxels), noise sigma */
	float fibre;              /* fibre texture cell (voxels) */
	uint64_t seed;
	uint32_t rep_rows, rep_cols; /* weave repeat: picks x ends */
	const uint8_t *weave;     /* rep_rows*rep_cols, 1 = warp over */
	int pure_noise;           /* no sheet: uniform noise in [0,1) */
} loom_scan_sheet;

/* Presets (weave left unset): "small" 160x160x40, 7 warps x 9 wefts at
   24 x 18 voxels; "paper" or "paper:N" N x N x 0.3N (N = 1000: the paper's
   5 um resolution) with warp spacing 0.115 N and weft spacing 0.07 N.
   Both turned by 3 degrees, blur 0.8, noise 0.08, seed 7.  LOOM_EINVAL
   for another name. */
LOOM_API int loom_scan_sheet_preset(const char *name, loom_scan_sheet *s);

/* W(i, j) of the sheet's (periodic) weave: 1 = warp over. */
LOOM_API int loom_scan_sheet_w(const loom_scan_sheet *s, long i, long j);

/* The clean sheet at scan voxel (x, y, z): density (before blur and
   noise), truth label, unit fibre tangent (zero outside), normalised
   elliptical radius to the nearest yarn (< 1 inside; 9 if far; rad may be
   NULL). */
LOOM_API void loom_scan_sheet_voxel(const loom_scan_sheet *s, uint32_t x,
                                    uint32_t y, uint32_t z, float *density,
                                    uint8_t *label, float tangent[3],
                                    float *rad);

/* Fill v (allocated by the caller with the sheet's size: density required;
   orient, if set, receives the true tangents) and truth (nx*ny*nz labels,
   may be NULL); blur and noise applied to the density.  Same bytes for any
   thread count.  LOOM_EINVAL, LOOM_ENOMEM. */
LOOM_API int loom_scan_sheet_make(const loom_scan_sheet *s, loom_scan_volume *v,
                                  uint8_t *truth, uint32_t threads,
                                  loom_diag *diag);

/* Ground truth of the crop loom_scan_build should find: the largest run of
   complete yarns whose cells (centred on the yarns) lie inside the scan's
   footprint, ties by distance to the scan centre (loom_scan_register's
   rule). */
typedef struct loom_scan_sheet_grid {
	uint32_t first_warp, first_weft, cols, rows;
	uint32_t b1, b2;          /* round(sx), round(sy) */
	double crop[4];           /* x0, y0, width, height in the aligned frame */
} loom_scan_sheet_grid;

/* LOOM_EINVAL, LOOM_EUNSUPPORTED (no 2 x 2 window fits). */
LOOM_API int loom_scan_sheet_truth(const loom_scan_sheet *s,
                                   loom_scan_sheet_grid *g);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_SCAN_H */
