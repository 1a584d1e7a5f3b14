/*
 * engine/scan/scan_orient.c - scan pipeline steps 1 and 2: denoising, threshold
 * and per-voxel fibre orientation (paper section 6, the "basic processing"
 * of its predecessor), plus the small shared helpers (threads, kernels,
 * volumes).
 *
 * Orientation by the structure tensor.  For every voxel with density above
 * the threshold:
 *
 *   g = central-difference gradient of the (denoised) density
 *   T = G_sigma * (g g^T)              six channels, separable Gaussian
 *   fibre direction = eigenvector of the smallest eigenvalue of T
 *
 * Inside a yarn the density varies across fibres and little along them, so
 * the direction of least variation is the fibre direction.  Memory stays
 * bounded: the volume is cut into tiles of TILE_ROWS rows (y); a thread
 * walks its tiles plane by plane, keeping a ring of 2r+1 xy-smoothed tensor
 * planes of its tile (r = kernel radius), so the working set is
 * O(nx * (TILE_ROWS + 2r) * (2r+1) * 6) floats per thread, whatever ny and
 * nz.  Planes are computed lazily: tiles and planes with no voxel above the
 * threshold in reach cost nothing, rows without material skip the z pass.
 * The filters run on 4-lane vector kernels (loom__scan_axpy); the eigen
 * solve of the hot loop is the closed form in single precision.  Each output voxel is computed by the
 * same arithmetic whichever thread runs its tile, so results are identical
 * for any thread count; per-tile statistics are reduced in tile order.
 */
#include "scan_internal.h"
#include "exemplar/voxel.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* ---- shared helpers ----------------------------------------------------- */

typedef struct par_arg {
	loom__scan_job fn;
	void *ctx;
	uint32_t tid, n;
} par_arg;

static void *par_main(void *a)
{
	par_arg *p = a;
	p->fn(p->ctx, p->tid, p->n);
	return NULL;
}

void loom__scan_parallel(uint32_t threads, loom__scan_job fn, void *ctx)
{
	enum { MAXT = 64 };
	pthread_t th[MAXT];
	par_arg arg[MAXT];
	int started[MAXT];

	if (threads == 0)
		threads = 1;
	if (threads > MAXT)
		threads = MAXT;
	for (uint32_t t = 1; t < threads; t++) {
		arg[t] = (par_arg){fn, ctx, t, threads};
		started[t] = pthread_create(&th[t], NULL, par_main, &arg[t]) == 0;
	}
	fn(ctx, 0, threads);
	for (uint32_t t = 1; t < threads; t++) {
		if (started[t])
			pthread_join(th[t], NULL);
		else
			fn(ctx, t, threads); /* could not start: run it here */
	}
}

int loom__scan_gauss(float sigma, float w[2 * LOOM__SCAN_MAX_RADIUS + 1])
{
	int r;
	double sum = 0;

	if (!(sigma > 0)) {
		w[0] = 1;
		return 0;
	}
	r = (int)ceilf(3 * sigma);
	if (r > LOOM__SCAN_MAX_RADIUS)
		r = LOOM__SCAN_MAX_RADIUS;
	if (r < 1)
		r = 1;
	for (int k = -r; k <= r; k++) {
		double e = exp(-0.5 * (double)k * k / ((double)sigma * sigma));
		w[k + r] = (float)e;
		sum += e;
	}
	for (int k = 0; k <= 2 * r; k++)
		w[k] = (float)(w[k] / sum);
	return r;
}

int loom__scan_check_volume(const loom_scan_volume *v, const char *what,
                            loom_diag *diag)
{
	if (!v || !v->density)
		return loom__fail(diag, LOOM_EINVAL, "scan: %s: no density", what);
	if (v->nx < 3 || v->ny < 3 || v->nz < 1)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: %s: volume %ux%ux%u too small", what,
		                  v->nx, v->ny, v->nz);
	return LOOM_OK;
}

void *loom__scan_alloc_big(size_t n, int zero)
{
	void *p = NULL;
	size_t align = (size_t)2 << 20;

	if (n < align) {
		return zero ? calloc(1, n ? n : 1) : malloc(n ? n : 1);
	}
	if (posix_memalign(&p, align, n) != 0)
		return NULL;
#ifdef MADV_HUGEPAGE
	madvise(p, n, MADV_HUGEPAGE);
#endif
	if (zero)
		memset(p, 0, n);
	return p;
}

LOOM_API const char *loom_scan_step_name(int step)
{
	static const char *const names[LOOM_SCAN_STEP_COUNT_] = {
		"denoise", "orientation", "endpoints", "tracking", "weave",
		"segmentation", "alignment", "registration", "crop"};
	if (step < 0 || step >= LOOM_SCAN_STEP_COUNT_)
		return "unknown step";
	return names[step];
}

LOOM_API int loom_scan_volume_alloc(loom_scan_volume *v, uint32_t nx,
                                    uint32_t ny, uint32_t nz,
                                    unsigned channels)
{
	size_t n;

	if (!v)
		return LOOM_EINVAL;
	memset(v, 0, sizeof *v);
	if (!nx || !ny || !nz || !(channels & 15u))
		return LOOM_EINVAL;
	if ((uint64_t)nx * ny * nz > (1ull << 40))
		return LOOM_ERANGE;
	n = (size_t)nx * ny * nz;
	v->nx = nx;
	v->ny = ny;
	v->nz = nz;
	if ((channels & LOOM_SCAN_DENSITY) &&
	    !(v->density = loom__scan_alloc_big(n * sizeof(float), 1)))
		goto oom;
	if ((channels & LOOM_SCAN_ORIENT) &&
	    !(v->orient = loom__scan_alloc_big(n * 3 * sizeof(float), 1)))
		goto oom;
	if ((channels & LOOM_SCAN_LABEL) && !(v->label = loom__scan_alloc_big(n, 1)))
		goto oom;
	if ((channels & LOOM_SCAN_OCODE) &&
	    !(v->ocode = loom__scan_alloc_big(n * sizeof *v->ocode, 1)))
		goto oom;
	return LOOM_OK;
oom:
	loom_scan_volume_release(v);
	return LOOM_ENOMEM;
}

static float code_lut[3 * 65536];
static pthread_once_t code_lut_once = PTHREAD_ONCE_INIT;

static void code_lut_init(void)
{
	for (uint32_t c = 1; c < 65536; c++)
		loom__orient_decode((uint16_t)c, code_lut + 3 * c);
}

const float *loom__scan_code_lut(void)
{
	pthread_once(&code_lut_once, code_lut_init);
	return code_lut;
}

LOOM_API void loom_scan_volume_release(loom_scan_volume *v)
{
	if (!v)
		return;
	free(v->density);
	free(v->orient);
	free(v->label);
	free(v->ocode);
	memset(v, 0, sizeof *v);
}

/* ---- noise and threshold ------------------------------------------------ */

/*
 * Second differences d = v[x-1] - 2 v[x] + v[x+1] of i.i.d. noise of level s
 * have standard deviation s*sqrt(6); the median of |d| of a normal variable
 * is 0.6745 of its deviation.  Structure (edges) only touches a minority of
 * voxels, so the median ignores it.  Up to 2^20 samples on a regular
 * lattice; the median comes from a 4096-bin histogram of |d| refined by a
 * second pass inside the median's bin (no sort).
 */
LOOM_API float loom_scan_noise(const loom_scan_volume *v)
{
	enum { BINS = 4096 };
	size_t lines, span, stride, cap = 1u << 20, n = 0, half, acc = 0;
	uint32_t *h;
	double lo = 0, width = 4.0 / BINS; /* |d| <= 4 for densities in [0,1] */
	float med = 0;

	if (!v || !v->density || v->nx < 3)
		return 0;
	lines = (size_t)v->ny * v->nz;
	span = lines * (v->nx - 2);
	stride = (span + cap - 1) / cap;
	if (stride < 1)
		stride = 1;
	h = calloc(BINS, sizeof *h);
	if (!h)
		return 0;
	for (int pass = 0; pass < 2; pass++) {
		size_t below = 0;
		memset(h, 0, BINS * sizeof *h);
		n = 0;
		for (size_t i = 0; i < span; i += stride) {
			size_t line = i / (v->nx - 2), x = 1 + i % (v->nx - 2);
			const float *d = v->density + line * v->nx;
			double a = fabs((double)d[x - 1] - 2.0 * d[x] + d[x + 1]) - lo;
			long b = (long)(a / width);
			n++;
			if (b < 0) {
				below++;
				continue;
			}
			if (b >= BINS)
				b = BINS - 1;
			h[b]++;
		}
		half = n / 2;
		acc = below;
		for (int b = 0; b < BINS; b++) {
			if (acc + h[b] > half) {
				/* the median is in bin b: refine inside it */
				med = (float)(lo + (b + 0.5) * width);
				lo += b * width;
				width /= BINS;
				break;
			}
			acc += h[b];
		}
	}
	free(h);
	return (float)(med / 0.6745 / sqrt(6.0));
}

LOOM_API int loom_scan_threshold(const loom_scan_volume *v, float *threshold,
                                 loom_diag *diag)
{
	uint64_t hist[256] = {0}, total = 0;
	size_t n, stride;
	double sum = 0, sum0 = 0, best = -1, between[255];
	uint64_t w0 = 0;
	int best_t = -1;
	int rc = loom__scan_check_volume(v, "threshold", diag);

	if (rc)
		return rc;
	if (!threshold)
		return loom__fail(diag, LOOM_EINVAL, "scan: threshold: NULL output");
	n = (size_t)v->nx * v->ny * v->nz;
	stride = n > (64u << 20) ? n / (16u << 20) : 1;
	for (size_t i = 0; i < n; i += stride) {
		float d = v->density[i];
		int b = d <= 0 ? 0 : d >= 1 ? 255 : (int)(d * 256.0f);
		if (b > 255)
			b = 255;
		hist[b]++;
		total++;
	}
	for (int b = 0; b < 256; b++)
		sum += (double)b * hist[b];
	for (int t = 0; t < 255; t++) {
		double m0, m1;
		w0 += hist[t];
		sum0 += (double)t * hist[t];
		between[t] = -1;
		if (w0 == 0 || w0 == total)
			continue;
		m0 = sum0 / w0;
		m1 = (sum - sum0) / (total - w0);
		between[t] = (double)w0 * (total - w0) * (m1 - m0) * (m1 - m0);
		if (between[t] > best)
			best = between[t];
	}
	/* with a clean gap between the classes every threshold inside it
	   scores the same: take the middle of that plateau, not its edge */
	if (best > 0) {
		int first = -1, last = -1;
		for (int t = 0; t < 255; t++)
			if (between[t] >= best * (1 - 1e-4)) {
				if (first < 0)
					first = t;
				last = t;
			}
		best_t = (first + last) / 2;
	}
	if (best_t < 0)
		return loom__fail(diag, LOOM_EUNSUPPORTED,
		                  "scan: threshold: the density is constant; no "
		                  "material to separate from empty space");
	*threshold = (float)(best_t + 1) / 256.0f;
	return LOOM_OK;
}

/* ---- denoising ---------------------------------------------------------- */

typedef struct blur_ctx {
	loom_scan_volume *v;
	const float *w;
	int r;
	int axis;
	int failed;
} blur_ctx;

/* out[i] = sum_k w[k] * in[clamp(i + k - r)], for n samples with stride 1
   in `in` (already padded copy in pad: pad[k] = in[clamp(k - r)]). */
static void conv_line(float *out, const float *pad, size_t n, const float *w,
                      int r)
{
	loom__scan_scale(out, pad, w[0], n);
	for (int k = 1; k <= 2 * r; k++)
		loom__scan_axpy(out, pad + k, w[k], n);
}

static void blur_worker(void *vctx, uint32_t tid, uint32_t nt)
{
	blur_ctx *c = vctx;
	loom_scan_volume *v = c->v;
	size_t nx = v->nx, ny = v->ny, nz = v->nz, plane = nx * ny;
	int r = c->r;
	float *tmp;

	if (c->axis == 0) {
		tmp = malloc((nx + 2 * (size_t)r) * sizeof *tmp);
		if (!tmp) {
			__atomic_store_n(&c->failed, 1, __ATOMIC_RELAXED);
			return;
		}
		for (size_t line = tid; line < ny * nz; line += nt) {
			float *d = v->density + line * nx;
			for (int k = 0; k < r; k++) {
				tmp[k] = d[0];
				tmp[r + nx + k] = d[nx - 1];
			}
			memcpy(tmp + r, d, nx * sizeof *d);
			conv_line(d, tmp, nx, c->w, r);
		}
	} else if (c->axis == 1) {
		tmp = malloc(plane * sizeof *tmp);
		if (!tmp) {
			__atomic_store_n(&c->failed, 1, __ATOMIC_RELAXED);
			return;
		}
		for (size_t z = tid; z < nz; z += nt) {
			float *d = v->density + z * plane;
			memcpy(tmp, d, plane * sizeof *d);
			for (size_t y = 0; y < ny; y++) {
				float *o = d + y * nx;
				for (int k = -r; k <= r; k++) {
					long yy = (long)y + k;
					yy = yy < 0 ? 0 : yy >= (long)ny ? (long)ny - 1 : yy;
					if (k == -r)
						loom__scan_scale(o, tmp + (size_t)yy * nx, c->w[0], nx);
					else
						loom__scan_axpy(o, tmp + (size_t)yy * nx, c->w[k + r], nx);
				}
			}
		}
	} else {
		tmp = malloc(nx * nz * sizeof *tmp);
		if (!tmp) {
			__atomic_store_n(&c->failed, 1, __ATOMIC_RELAXED);
			return;
		}
		for (size_t y = tid; y < ny; y += nt) {
			for (size_t z = 0; z < nz; z++)
				memcpy(tmp + z * nx, v->density + z * plane + y * nx,
				       nx * sizeof *tmp);
			for (size_t z = 0; z < nz; z++) {
				float *o = v->density + z * plane + y * nx;
				for (int k = -r; k <= r; k++) {
					long zz = (long)z + k;
					zz = zz < 0 ? 0 : zz >= (long)nz ? (long)nz - 1 : zz;
					if (k == -r)
						loom__scan_scale(o, tmp + (size_t)zz * nx, c->w[0], nx);
					else
						loom__scan_axpy(o, tmp + (size_t)zz * nx, c->w[k + r], nx);
				}
			}
		}
	}
	free(tmp);
}

LOOM_API int loom_scan_denoise(loom_scan_volume *v, float sigma,
                               uint32_t threads, loom_diag *diag)
{
	float w[2 * LOOM__SCAN_MAX_RADIUS + 1];
	blur_ctx c;
	int rc = loom__scan_check_volume(v, "denoise", diag);

	if (rc)
		return rc;
	if (!(sigma >= 0) || sigma > 8)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: denoise: sigma %g outside [0, 8]", sigma);
	if (sigma == 0)
		return LOOM_OK;
	memset(&c, 0, sizeof c);
	c.v = v;
	c.w = w;
	c.r = loom__scan_gauss(sigma, w);
	for (c.axis = 0; c.axis < 3; c.axis++) {
		if ((c.axis == 2 && v->nz < 2))
			continue;
		loom__scan_parallel(threads, blur_worker, &c);
		if (c.failed)
			return loom__fail(diag, LOOM_ENOMEM, "scan: denoise: out of memory");
	}
	return LOOM_OK;
}

/* ---- eigen solver ------------------------------------------------------- */

LOOM_API int loom_scan_eigen_min(const double m[6], double dir[3], double ev[3])
{
	double a00 = m[0], a01 = m[1], a02 = m[2], a11 = m[3], a12 = m[4],
	       a22 = m[5];
	double p1 = a01 * a01 + a02 * a02 + a12 * a12;
	double q = (a00 + a11 + a22) / 3;
	double b00 = a00 - q, b11 = a11 - q, b22 = a22 - q;
	double p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2 * p1;
	double p = sqrt(p2 / 6), r, phi, e1, e2, e3;
	double r0[3], r1[3], r2[3], c[3][3], best = 0, scale;
	int bi = -1;

	dir[0] = dir[1] = dir[2] = 0;
	scale = fabs(a00) + fabs(a11) + fabs(a22) + sqrt(p1);
	if (!(scale > 0) || p <= 1e-9 * scale) {
		if (ev)
			ev[0] = ev[1] = ev[2] = q;
		return 0;
	}
	/* r = det(B)/2 with B = (A - qI)/p */
	r = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) +
	     a02 * (a01 * a12 - b11 * a02)) / (2 * p * p * p);
	r = r < -1 ? -1 : r > 1 ? 1 : r;
	phi = acos(r) / 3;
	{
		/* cos(phi + 2 pi/3) = -cos(phi)/2 - sin(phi) sqrt(3)/2 */
		double cp = cos(phi), sp = sin(phi);
		e1 = q + 2 * p * cp;
		e3 = q + p * (-cp - 1.7320508075688772935 * sp);
	}
	e2 = 3 * q - e1 - e3;
	if (ev) {
		ev[0] = e1;
		ev[1] = e2;
		ev[2] = e3;
	}
	/* eigenvector of e3: cross product of two independent rows of A - e3 I */
	r0[0] = a00 - e3; r0[1] = a01; r0[2] = a02;
	r1[0] = a01; r1[1] = a11 - e3; r1[2] = a12;
	r2[0] = a02; r2[1] = a12; r2[2] = a22 - e3;
#define CROSS(o, u, v)                                                      \
	((o)[0] = (u)[1] * (v)[2] - (u)[2] * (v)[1],                            \
	 (o)[1] = (u)[2] * (v)[0] - (u)[0] * (v)[2],                            \
	 (o)[2] = (u)[0] * (v)[1] - (u)[1] * (v)[0])
	CROSS(c[0], r0, r1);
	CROSS(c[1], r0, r2);
	CROSS(c[2], r1, r2);
#undef CROSS
	for (int i = 0; i < 3; i++) {
		double n2 = c[i][0] * c[i][0] + c[i][1] * c[i][1] + c[i][2] * c[i][2];
		if (n2 > best) {
			best = n2;
			bi = i;
		}
	}
	/* A rank-1 A - e3 I means e2 == e3: no single fibre direction. */
	if (bi < 0 || best <= 1e-18 * (e1 - e3) * (e1 - e3) * (e1 - e3) * (e1 - e3) ||
	    !(e1 - e3 > 0))
		return 0;
	best = 1 / sqrt(best);
	dir[0] = c[bi][0] * best;
	dir[1] = c[bi][1] * best;
	dir[2] = c[bi][2] * best;
	return 1;
}

/* ---- structure-tensor orientation --------------------------------------- */

/*
 * loom_scan_eigen_min in single precision, for the hot loop: the same
 * closed form (trigonometric eigenvalues, eigenvector as the largest cross
 * product of two rows of A - l3 I).  Structure tensors are positive
 * semi-definite and only the direction matters, so float is plenty (the
 * unit tests compare the result with the true fibre direction).  coh gets
 * (l2 - l3) / (l2 + l3).  Returns 0 (dir untouched) when undefined.
 */
static int eigen_min_f(const float m[6], float dir[3], float *coh)
{
	float a00 = m[0], a01 = m[1], a02 = m[2], a11 = m[3], a12 = m[4], a22 = m[5];
	float p1 = a01 * a01 + a02 * a02 + a12 * a12;
	float q = (a00 + a11 + a22) * (1.0f / 3);
	float b00 = a00 - q, b11 = a11 - q, b22 = a22 - q;
	float p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2 * p1;
	float p = sqrtf(p2 * (1.0f / 6)), r, phi, cp, sp, e1, e2, e3, best = 0, n;
	float r0[3], r1[3], r2[3], cr[3][3];
	float scale = fabsf(a00) + fabsf(a11) + fabsf(a22) + sqrtf(p1);
	int bi = -1;

	if (!(scale > 0) || p <= 1e-6f * scale)
		return 0;
	r = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) +
	     a02 * (a01 * a12 - b11 * a02)) / (2 * p * p * p);
	r = r < -1 ? -1 : r > 1 ? 1 : r;
	phi = acosf(r) * (1.0f / 3);
	cp = cosf(phi);
	sp = sinf(phi);
	e1 = q + 2 * p * cp;
	e3 = q + p * (-cp - 1.7320508f * sp);
	e2 = 3 * q - e1 - e3;
	if (!(e1 - e3 > 0))
		return 0;
	r0[0] = a00 - e3; r0[1] = a01; r0[2] = a02;
	r1[0] = a01; r1[1] = a11 - e3; r1[2] = a12;
	r2[0] = a02; r2[1] = a12; r2[2] = a22 - e3;
	cr[0][0] = r0[1] * r1[2] - r0[2] * r1[1];
	cr[0][1] = r0[2] * r1[0] - r0[0] * r1[2];
	cr[0][2] = r0[0] * r1[1] - r0[1] * r1[0];
	cr[1][0] = r0[1] * r2[2] - r0[2] * r2[1];
	cr[1][1] = r0[2] * r2[0] - r0[0] * r2[2];
	cr[1][2] = r0[0] * r2[1] - r0[1] * r2[0];
	cr[2][0] = r1[1] * r2[2] - r1[2] * r2[1];
	cr[2][1] = r1[2] * r2[0] - r1[0] * r2[2];
	cr[2][2] = r1[0] * r2[1] - r1[1] * r2[0];
	for (int i = 0; i < 3; i++) {
		float n2 = cr[i][0] * cr[i][0] + cr[i][1] * cr[i][1] + cr[i][2] * cr[i][2];
		if (n2 > best) {
			best = n2;
			bi = i;
		}
	}
	/* A - l3 I of rank 1 (l2 == l3): no single fibre direction */
	n = (e1 - e3) * (e1 - e3);
	if (bi < 0 || best <= 1e-8f * n * n)
		return 0;
	n = 1 / sqrtf(best);
	dir[0] = cr[bi][0] * n;
	dir[1] = cr[bi][1] * n;
	dir[2] = cr[bi][2] * n;
	*coh = e2 + e3 > 0 ? (e2 - e3) / (e2 + e3) : 0;
	return 1;
}

#define TILE_ROWS 32

typedef struct orient_ctx {
	loom_scan_volume *v;
	float thr;
	const float *w;
	int r;
	uint32_t ntiles;
	double *tile_coh;     /* per tile: sum of coherence */
	uint64_t *tile_count; /* per tile: oriented voxels */
	int failed;
} orient_ctx;

/* Raw tensor g g^T of rows [ya, yb) of plane q into raw[c][(y-ya)*nx + x],
   then smoothed along x in place. */
static void tensor_rows(const loom_scan_volume *v, uint32_t q, uint32_t ya,
                        uint32_t yb, float *raw[6], float *pad, const float *w,
                        int r)
{
	size_t nx = v->nx, ny = v->ny, nz = v->nz, plane = nx * ny;
	const float *d = v->density + (size_t)q * plane;
	const float *dzm = v->density + (size_t)(q > 0 ? q - 1 : q) * plane;
	const float *dzp = v->density + (size_t)(q + 1 < nz ? q + 1 : q) * plane;
	float fz = (q > 0 && q + 1 < nz) ? 0.5f : 1.0f;

	if (nz == 1)
		fz = 0;
	for (uint32_t y = ya; y < yb; y++) {
		const float *row = d + (size_t)y * nx;
		const float *rym = d + (size_t)(y > 0 ? y - 1 : y) * nx;
		const float *ryp = d + (size_t)(y + 1 < ny ? y + 1 : y) * nx;
		float fy = (y > 0 && y + 1 < ny) ? 0.5f : 1.0f;
		size_t o = (size_t)(y - ya) * nx;
		for (size_t x = 0; x < nx; x++) {
			float gx, gy, gz;
			if (x == 0)
				gx = row[1] - row[0];
			else if (x + 1 == nx)
				gx = row[x] - row[x - 1];
			else
				gx = 0.5f * (row[x + 1] - row[x - 1]);
			gy = fy * (ryp[x] - rym[x]);
			gz = fz * (dzp[y * nx + x] - dzm[y * nx + x]);
			raw[0][o + x] = gx * gx;
			raw[1][o + x] = gx * gy;
			raw[2][o + x] = gx * gz;
			raw[3][o + x] = gy * gy;
			raw[4][o + x] = gy * gz;
			raw[5][o + x] = gz * gz;
		}
		for (int c = 0; c < 6; c++) {
			float *line = raw[c] + o;
			for (int k = 0; k < r; k++) {
				pad[k] = line[0];
				pad[r + nx + k] = line[nx - 1];
			}
			memcpy(pad + r, line, nx * sizeof *line);
			conv_line(line, pad, nx, w, r);
		}
	}
}

static int plane_has_material(const loom_scan_volume *v, uint32_t z,
                              uint32_t y0, uint32_t y1, float thr)
{
	const float *d = v->density + ((size_t)z * v->ny + y0) * v->nx;
	size_t n = (size_t)(y1 - y0) * v->nx;
	for (size_t i = 0; i < n; i++)
		if (d[i] > thr)
			return 1;
	return 0;
}

static void orient_worker(void *vctx, uint32_t tid, uint32_t nt)
{
	orient_ctx *c = vctx;
	loom_scan_volume *v = c->v;
	size_t nx = v->nx, ny = v->ny, nz = v->nz;
	int r = c->r, S = 2 * r + 1;
	size_t ext_rows = TILE_ROWS + 2 * (size_t)r;
	size_t raw_n = ext_rows * nx, slot_n = (size_t)TILE_ROWS * nx;
	float *mem, *raw[6], *pad, *zs[6];
	float **slot; /* slot[s*6 + c] */
	float *rowbuf = NULL; /* one row of directions when writing codes */
	long *slot_plane;
	uint8_t *has;

	mem = malloc((6 * raw_n + (size_t)S * 6 * slot_n + nx + 2 * (size_t)r +
	              6 * nx) * sizeof(float));
	slot = malloc((size_t)S * 6 * sizeof *slot);
	slot_plane = malloc((size_t)S * sizeof *slot_plane);
	has = malloc(nz);
	if (!v->orient)
		rowbuf = malloc(3 * nx * sizeof *rowbuf);
	if (!mem || !slot || !slot_plane || !has || (!v->orient && !rowbuf)) {
		__atomic_store_n(&c->failed, 1, __ATOMIC_RELAXED);
		goto out;
	}
	for (int k = 0; k < 6; k++)
		raw[k] = mem + (size_t)k * raw_n;
	for (int s = 0; s < S * 6; s++)
		slot[s] = mem + 6 * raw_n + (size_t)s * slot_n;
	pad = mem + 6 * raw_n + (size_t)S * 6 * slot_n;
	for (int k = 0; k < 6; k++)
		zs[k] = pad + nx + 2 * (size_t)r + (size_t)k * nx;

	for (uint32_t t = tid; t < c->ntiles; t += nt) {
		uint32_t y0 = t * TILE_ROWS;
		uint32_t y1 = y0 + TILE_ROWS < ny ? y0 + TILE_ROWS : (uint32_t)ny;
		uint32_t ya = y0 >= (uint32_t)r ? y0 - (uint32_t)r : 0;
		uint32_t yb = y1 + (uint32_t)r < ny ? y1 + (uint32_t)r : (uint32_t)ny;
		double coh_sum = 0;
		uint64_t count = 0;

		for (int s = 0; s < S; s++)
			slot_plane[s] = -1;
		for (size_t z = 0; z < nz; z++)
			has[z] = (uint8_t)plane_has_material(v, (uint32_t)z, y0, y1, c->thr);
		for (size_t z = 0; z < nz; z++) {
			size_t base = ((size_t)z * ny + y0) * nx;
			float *o = v->orient ? v->orient + 3 * base : NULL;
			uint16_t *oc = v->orient ? NULL : v->ocode + base;
			if (!has[z]) {
				if (o)
					memset(o, 0, 3 * (size_t)(y1 - y0) * nx * sizeof *o);
				else
					memset(oc, 0, (size_t)(y1 - y0) * nx * sizeof *oc);
				continue;
			}
			/* make sure planes clamp(z-r) .. clamp(z+r) are in the ring */
			for (int k = -r; k <= r; k++) {
				long q = (long)z + k;
				int s;
				q = q < 0 ? 0 : q >= (long)nz ? (long)nz - 1 : q;
				s = (int)(q % S);
				if (slot_plane[s] == q)
					continue;
				tensor_rows(v, (uint32_t)q, ya, yb, raw, pad, c->w, r);
				for (int ch = 0; ch < 6; ch++) {
					float *dst = slot[s * 6 + ch];
					for (uint32_t y = y0; y < y1; y++) {
						float *od = dst + (size_t)(y - y0) * nx;
						for (int kk = -r; kk <= r; kk++) {
							long yy = (long)y + kk;
							const float *sr;
							yy = yy < 0 ? 0 : yy >= (long)ny ? (long)ny - 1 : yy;
							sr = raw[ch] + (size_t)(yy - ya) * nx;
							if (kk == -r)
								loom__scan_scale(od, sr, c->w[0], nx);
							else
								loom__scan_axpy(od, sr, c->w[kk + r], nx);
						}
					}
				}
				slot_plane[s] = q;
			}
			for (uint32_t y = y0; y < y1; y++) {
				const float *dens = v->density + ((size_t)z * ny + y) * nx;
				float *orow = o ? o + 3 * (size_t)(y - y0) * nx : rowbuf;
				uint16_t *crow = oc ? oc + (size_t)(y - y0) * nx : NULL;
				{
					/* rows without material need no tensor */
					int any = 0;
					for (size_t x = 0; x < nx && !any; x++)
						any = dens[x] > c->thr;
					if (!any) {
						if (crow)
							memset(crow, 0, nx * sizeof *crow);
						else
							memset(orow, 0, 3 * nx * sizeof *orow);
						continue;
					}
				}
				for (int ch = 0; ch < 6; ch++) {
					float *zd = zs[ch];
					for (int k = -r; k <= r; k++) {
						long q = (long)z + k;
						const float *sr;
						q = q < 0 ? 0 : q >= (long)nz ? (long)nz - 1 : q;
						sr = slot[(int)(q % S) * 6 + ch] + (size_t)(y - y0) * nx;
						if (k == -r)
							loom__scan_scale(zd, sr, c->w[0], nx);
						else
							loom__scan_axpy(zd, sr, c->w[k + r], nx);
					}
				}
				for (size_t x = 0; x < nx; x++) {
					float m[6], coh;
					float *ov = orow + 3 * x;
					if (!(dens[x] > c->thr)) {
						ov[0] = ov[1] = ov[2] = 0;
						continue;
					}
					for (int ch = 0; ch < 6; ch++)
						m[ch] = zs[ch][x];
					if (!eigen_min_f(m, ov, &coh)) {
						ov[0] = ov[1] = ov[2] = 0;
						continue;
					}
					coh_sum += coh;
					count++;
				}
				if (crow)
					for (size_t x = 0; x < nx; x++) {
						const float *ov = orow + 3 * x;
						crow[x] = ov[0] == 0 && ov[1] == 0 && ov[2] == 0
						              ? 0
						              : loom__orient_encode(ov[0], ov[1], ov[2]);
					}
			}
		}
		c->tile_coh[t] = coh_sum;
		c->tile_count[t] = count;
	}
out:
	free(rowbuf);
	free(mem);
	free(slot);
	free(slot_plane);
	free(has);
}

LOOM_API int loom_scan_orient(loom_scan_volume *v, float threshold,
                              float tensor_sigma, uint32_t threads,
                              loom_scan_orient_info *info, loom_diag *diag)
{
	float w[2 * LOOM__SCAN_MAX_RADIUS + 1];
	orient_ctx c;
	double coh = 0;
	uint64_t count = 0;
	int rc = loom__scan_check_volume(v, "orientation", diag);

	if (rc)
		return rc;
	if (!v->orient && !v->ocode)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: orientation: no orientation array to fill");
	if (!(tensor_sigma > 0) || tensor_sigma > 8)
		return loom__fail(diag, LOOM_EINVAL,
		                  "scan: orientation: tensor sigma %g outside (0, 8]",
		                  tensor_sigma);
	memset(&c, 0, sizeof c);
	c.v = v;
	c.thr = threshold;
	c.w = w;
	c.r = loom__scan_gauss(tensor_sigma, w);
	c.ntiles = (v->ny + TILE_ROWS - 1) / TILE_ROWS;
	c.tile_coh = calloc(c.ntiles, sizeof *c.tile_coh);
	c.tile_count = calloc(c.ntiles, sizeof *c.tile_count);
	if (!c.tile_coh || !c.tile_count) {
		free(c.tile_coh);
		free(c.tile_count);
		return loom__fail(diag, LOOM_ENOMEM, "scan: orientation: out of memory");
	}
	loom__scan_parallel(threads, orient_worker, &c);
	for (uint32_t t = 0; t < c.ntiles; t++) {
		coh += c.tile_coh[t];
		count += c.tile_count[t];
	}
	free(c.tile_coh);
	free(c.tile_count);
	if (c.failed)
		return loom__fail(diag, LOOM_ENOMEM, "scan: orientation: out of memory");
	if (info) {
		info->voxels = count;
		info->coherence = count ? (float)(coh / count) : 0;
	}
	return LOOM_OK;
}
