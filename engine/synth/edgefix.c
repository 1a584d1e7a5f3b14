/*
 * engine/synth/edgefix.c - edge fixing (paper 5.5) with tables per SOURCE block.
 *
 * Offset field of an output block (dz: how much its content is raised; the
 * lookup reads source z - dz).  On the block's grid x in [0,b1), y in
 * [0,b2) dz is harmonic inside (5-point Laplacian) with Dirichlet values
 *
 *     N edge, y = 0, all x      :  (S_prof(n)[x] - N_prof(self)[x]) / 2
 *     S edge, y = b2-1, all x   :  (N_prof(s)[x] - S_prof(self)[x]) / 2
 *     W edge, x = 0, 0<y<b2-1   :  (E_prof(w)[y] - W_prof(self)[y]) / 2
 *     E edge, x = b1-1, 0<y<b2-1:  (W_prof(e)[y] - E_prof(self)[y]) / 2
 *
 * so that both sides of every edge meet at the mean height.  The corners
 * belong to the N and S edges, as in the paper (its T has b1 rows, L has
 * b2-2); the interior equations never read a corner.  So the N/S seams meet
 * everywhere and the W/E seams everywhere but at their two corner samples,
 * where four blocks meet and pairwise means cannot all agree.  (A 4-way
 * mean at the corners, which needs the diagonal neighbours, makes them meet
 * when the profiles agree at the shared corner column; on the generated
 * database the corner columns are gaps whose N/S and W/E profiles are
 * extrapolated separately and differ by 3.2 voxels on average, and there
 * that rule did worse than the paper's, so it is not used.  See
 * docs/synthesis.md.)
 *
 *        x=0 .............. x=b1-1
 *   y=0   N  N  N  N  N  N  N          N/S rows own their corners
 *         W  .  .  .  .  .  E
 *         W  .  interior .  E          W/E columns: rows 1..b2-2
 *         W  .  .  .  .  .  E
 *   y=b2-1 S  S  S  S  S  S  S
 *
 * Solver.  With data on one edge only, the discrete problem separates in
 * sine modes: N-edge data v gives
 *     u(x,y) = sum_m g_m sin(m pi x/(b1-1)) phi_m(y),
 *     g_m = 2/(b1-1) sum_{x=1}^{b1-2} v[x] sin(m pi x/(b1-1)),
 *     phi_m(y) = sinh(mu_m (b2-1-y)) / sinh(mu_m (b2-1)),
 *     cosh mu_m = 2 - cos(m pi/(b1-1)),
 * exact for the discrete equations (not an approximation of the continuous
 * one).  W-edge data likewise with x and y exchanged; S and E data are the
 * mirror images.  phi is evaluated as e^{-mu y}(1-e^{-2mu(L-y)})/(1-e^{-2mu L})
 * so large blocks do not overflow.
 *
 * Linearity.  dz of output block i is a sum of terms that each depend on one
 * source block: the four own profiles of src(i) and the facing profile of
 * each neighbour's source.  With a rank-r basis B_h of the N/S profiles
 * (mean removed; the mean cancels in every difference) and B_v of the W/E
 * profiles, each source block t keeps four coefficient vectors
 *     cN(t) = B_h^T (N_prof(t) - mean_h),  cS, cW, cE likewise,
 * and, with F_h[k] / F_v[k] the solutions for N-edge data B_h[:,k] and W-edge
 * data B_v[:,k],
 *     dz(x,y) = aN.F_h(x,y) + aS.F_h(x,b2-1-y) + aW.F_v(x,y) + aE.F_v(b1-1-x,y)
 *     aN = (cS(n) - cN(self))/2,  aS = (cN(s) - cS(self))/2,
 *     aW = (cE(w) - cW(self))/2,  aE = (cW(e) - cE(self))/2.
 * Tables: 2r fields of b1*b2 floats and 4r floats per source block, never
 * anything per output block.
 *
 * Basis.  Top eigenvectors of the profile Gram matrix (n x n, n = b1 or
 * b2-2) by subspace iteration with a Rayleigh-Ritz step solved by our cyclic
 * Jacobi method; the plain Jacobi method on the whole matrix when the rank
 * is a large part of n.
 */
#include "core/internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CELLS (1u << 24)

struct loom_edgefix {
	uint32_t b1, b2, K, rh, rv;
	float *coef;      /* K * (2 rh + 2 rv) */
	float *field_h;   /* b1*b2*rh */
	float *field_v;   /* b1*b2*rv */
	float *basis_h;   /* b1*rh */
	float *basis_v;   /* (b2-2)*rv */
	float *mean_h;    /* b1 */
	float *mean_v;    /* b2-2 */
};

struct loom_edgefix_paper {
	uint32_t b1, b2, rows, cols, rT, rL;
	float *CT;        /* rows*cols*rT */
	float *CL;        /* rows*cols*rL */
	float *fT;        /* b1*b2*rT */
	float *fL;        /* b1*b2*rL */
};

/* ---- the Laplace solver -------------------------------------------------- */

/* Sine modes and decay profiles of one block size. */
typedef struct lap {
	uint32_t b1, b2, nx, ny;
	double *sx;   /* nx*nx: sx[(x-1)*nx + m-1] = sin(m pi x / (b1-1)) */
	double *sy;   /* ny*ny */
	double *phi;  /* nx*b2: phi[(m-1)*b2 + y] (N-edge problem) */
	double *psi;  /* ny*b1: psi[(m-1)*b1 + x] (W-edge problem) */
} lap;

static void lap_free(lap *L)
{
	free(L->sx);
	free(L->sy);
	free(L->phi);
	free(L->psi);
}

/* sinh(mu (len - d)) / sinh(mu len), computed without overflow. */
static double decay(double mu, double len, double d)
{
	return exp(-mu * d) * expm1(-2.0 * mu * (len - d)) / expm1(-2.0 * mu * len);
}

static void modes(uint32_t n, uint32_t span, uint32_t along, double *s,
                  double *prof)
{
	double L = (double)(n + 1); /* = span - 1 */
	(void)span;
	for (uint32_t x = 1; x <= n; x++)
		for (uint32_t m = 1; m <= n; m++)
			s[(size_t)(x - 1) * n + m - 1] = sin(M_PI * (double)m * (double)x / L);
	for (uint32_t m = 1; m <= n; m++) {
		double c = 2.0 - cos(M_PI * (double)m / L);
		double mu = log(c + sqrt(c * c - 1.0));
		for (uint32_t y = 0; y < along; y++)
			prof[(size_t)(m - 1) * along + y] = decay(mu, (double)(along - 1), (double)y);
	}
}

static int lap_init(lap *L, uint32_t b1, uint32_t b2)
{
	memset(L, 0, sizeof *L);
	L->b1 = b1;
	L->b2 = b2;
	L->nx = b1 - 2;
	L->ny = b2 - 2;
	L->sx = malloc(sizeof(double) * L->nx * L->nx);
	L->sy = malloc(sizeof(double) * L->ny * L->ny);
	L->phi = malloc(sizeof(double) * L->nx * b2);
	L->psi = malloc(sizeof(double) * L->ny * b1);
	if (!L->sx || !L->sy || !L->phi || !L->psi) {
		lap_free(L);
		return LOOM_ENOMEM;
	}
	modes(L->nx, b1, b2, L->sx, L->phi);
	modes(L->ny, b2, b1, L->sy, L->psi);
	return LOOM_OK;
}

/* Number of leading modes m whose decay prof[m*along + d] is >= 1e-18
   (the decay falls as m grows, so the rest contribute nothing). */
static uint32_t modes_above(const double *prof, uint32_t n, uint32_t along,
                            uint32_t d)
{
	uint32_t m = n;
	while (m > 0 && prof[(size_t)(m - 1) * along + d] < 1e-18)
		m--;
	return m;
}

/*
 * Solutions for r sets of N-edge data at once: v[x*r + k] (x = 0..b1-1,
 * corners included) -> out[(y*b1 + x)*r + k].  If vs is not NULL it holds r
 * sets of S-edge data whose (mirrored) solutions are added.  Work buffer g:
 * 2*nx*r doubles.
 */
static void solve_ns(const lap *L, const double *v, const double *vs,
                     uint32_t r, double *out, double *g)
{
	uint32_t b1 = L->b1, b2 = L->b2, nx = L->nx;
	double scale = 2.0 / (double)(b1 - 1);
	double *gs = g + (size_t)nx * r;

	memset(out, 0, sizeof(double) * b1 * b2 * r);
	for (uint32_t m = 0; m < nx; m++)
		for (uint32_t k = 0; k < r; k++) {
			double a = 0, b = 0;
			for (uint32_t x = 1; x <= nx; x++) {
				a += v[(size_t)x * r + k] * L->sx[(size_t)(x - 1) * nx + m];
				if (vs)
					b += vs[(size_t)x * r + k] * L->sx[(size_t)(x - 1) * nx + m];
			}
			g[(size_t)m * r + k] = a * scale;
			gs[(size_t)m * r + k] = b * scale;
		}
	for (uint32_t y = 1; y + 1 < b2; y++) {
		/* phi_m(y) decreases with m: modes past mt (mts) are below 1e-18 */
		uint32_t mt = modes_above(L->phi, nx, b2, y);
		uint32_t mts = vs ? modes_above(L->phi, nx, b2, b2 - 1 - y) : 0;
		for (uint32_t x = 1; x <= nx; x++) {
			double *o = out + ((size_t)y * b1 + x) * r;
			const double *srow = L->sx + (size_t)(x - 1) * nx;
			for (uint32_t m = 0; m < mt; m++) {
				double w = srow[m] * L->phi[(size_t)m * b2 + y];
				const double *gm = g + (size_t)m * r;
				for (uint32_t k = 0; k < r; k++)
					o[k] += w * gm[k];
			}
			for (uint32_t m = 0; m < mts; m++) {
				double w = srow[m] * L->phi[(size_t)m * b2 + (b2 - 1 - y)];
				const double *gm = gs + (size_t)m * r;
				for (uint32_t k = 0; k < r; k++)
					o[k] += w * gm[k];
			}
		}
	}
	for (uint32_t x = 0; x < b1; x++)
		for (uint32_t k = 0; k < r; k++) {
			out[(size_t)x * r + k] = v[(size_t)x * r + k];
			out[((size_t)(b2 - 1) * b1 + x) * r + k] = vs ? vs[(size_t)x * r + k] : 0;
		}
}

/*
 * The same for W-edge data v[(y-1)*r + k] (y = 1..b2-2) and, if ve is not
 * NULL, E-edge data; corners stay 0.
 */
static void solve_we(const lap *L, const double *v, const double *ve,
                     uint32_t r, double *out, double *g)
{
	uint32_t b1 = L->b1, b2 = L->b2, ny = L->ny;
	double scale = 2.0 / (double)(b2 - 1);
	double *ge = g + (size_t)ny * r;

	memset(out, 0, sizeof(double) * b1 * b2 * r);
	for (uint32_t m = 0; m < ny; m++)
		for (uint32_t k = 0; k < r; k++) {
			double a = 0, b = 0;
			for (uint32_t y = 1; y <= ny; y++) {
				a += v[(size_t)(y - 1) * r + k] * L->sy[(size_t)(y - 1) * ny + m];
				if (ve)
					b += ve[(size_t)(y - 1) * r + k] * L->sy[(size_t)(y - 1) * ny + m];
			}
			g[(size_t)m * r + k] = a * scale;
			ge[(size_t)m * r + k] = b * scale;
		}
	for (uint32_t y = 1; y <= ny; y++) {
		const double *srow = L->sy + (size_t)(y - 1) * ny;
		for (uint32_t x = 1; x + 1 < b1; x++) {
			double *o = out + ((size_t)y * b1 + x) * r;
			uint32_t mt = modes_above(L->psi, ny, b1, x);
			uint32_t mte = ve ? modes_above(L->psi, ny, b1, b1 - 1 - x) : 0;
			for (uint32_t m = 0; m < mt; m++) {
				double w = srow[m] * L->psi[(size_t)m * b1 + x];
				const double *gm = g + (size_t)m * r;
				for (uint32_t k = 0; k < r; k++)
					o[k] += w * gm[k];
			}
			for (uint32_t m = 0; m < mte; m++) {
				double w = srow[m] * L->psi[(size_t)m * b1 + (b1 - 1 - x)];
				const double *gm = ge + (size_t)m * r;
				for (uint32_t k = 0; k < r; k++)
					o[k] += w * gm[k];
			}
		}
		for (uint32_t k = 0; k < r; k++) {
			out[((size_t)y * b1) * r + k] = v[(size_t)(y - 1) * r + k];
			out[((size_t)y * b1 + b1 - 1) * r + k] = ve ? ve[(size_t)(y - 1) * r + k] : 0;
		}
	}
}

/* ---- symmetric eigenproblems --------------------------------------------- */

/*
 * Cyclic Jacobi: A (n x n, symmetric, destroyed) -> eigenvalues w[] and
 * eigenvectors as the columns of V (V[i*n + k]), sorted by decreasing
 * eigenvalue.
 */
static void jacobi(double *A, uint32_t n, double *V, double *w)
{
	for (uint32_t i = 0; i < n; i++)
		for (uint32_t k = 0; k < n; k++)
			V[(size_t)i * n + k] = i == k;
	for (int sweep = 0; sweep < 100; sweep++) {
		double off = 0, tot = 0;
		for (uint32_t p = 0; p < n; p++)
			for (uint32_t q = 0; q < n; q++) {
				double a = A[(size_t)p * n + q];
				tot += a * a;
				if (p != q)
					off += a * a;
			}
		if (off <= 1e-30 * tot || off == 0)
			break;
		for (uint32_t p = 0; p + 1 < n; p++)
			for (uint32_t q = p + 1; q < n; q++) {
				double apq = A[(size_t)p * n + q], app, aqq, th, t, c, s;
				if (apq == 0)
					continue;
				app = A[(size_t)p * n + p];
				aqq = A[(size_t)q * n + q];
				th = (aqq - app) / (2.0 * apq);
				t = (th >= 0 ? 1.0 : -1.0) / (fabs(th) + sqrt(th * th + 1.0));
				c = 1.0 / sqrt(t * t + 1.0);
				s = t * c;
				for (uint32_t k = 0; k < n; k++) {
					double akp = A[(size_t)k * n + p], akq = A[(size_t)k * n + q];
					A[(size_t)k * n + p] = c * akp - s * akq;
					A[(size_t)k * n + q] = s * akp + c * akq;
				}
				for (uint32_t k = 0; k < n; k++) {
					double apk = A[(size_t)p * n + k], aqk = A[(size_t)q * n + k];
					A[(size_t)p * n + k] = c * apk - s * aqk;
					A[(size_t)q * n + k] = s * apk + c * aqk;
				}
				for (uint32_t k = 0; k < n; k++) {
					double vkp = V[(size_t)k * n + p], vkq = V[(size_t)k * n + q];
					V[(size_t)k * n + p] = c * vkp - s * vkq;
					V[(size_t)k * n + q] = s * vkp + c * vkq;
				}
			}
	}
	for (uint32_t i = 0; i < n; i++)
		w[i] = A[(size_t)i * n + i];
	/* selection sort of the eigenpairs, decreasing */
	for (uint32_t a = 0; a < n; a++) {
		uint32_t best = a;
		for (uint32_t b = a + 1; b < n; b++)
			if (w[b] > w[best])
				best = b;
		if (best != a) {
			double tw = w[a];
			w[a] = w[best];
			w[best] = tw;
			for (uint32_t i = 0; i < n; i++) {
				double tv = V[(size_t)i * n + a];
				V[(size_t)i * n + a] = V[(size_t)i * n + best];
				V[(size_t)i * n + best] = tv;
			}
		}
	}
}

/* Deterministic pseudo-random numbers in [-1, 1). */
static double rnd(uint64_t *state)
{
	*state += 1;
	return (double)(loom_synth_mix(*state) >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

/* Modified Gram-Schmidt (twice) on the p columns of Q (n x p, Q[i*p + k]);
   a column that vanishes is replaced by a random one. */
static void orthonormalize(double *Q, uint32_t n, uint32_t p, uint64_t *state)
{
	for (uint32_t k = 0; k < p; k++) {
		for (int attempt = 0; attempt < 8; attempt++) {
			double ref = 0, nrm = 0;
			for (uint32_t i = 0; i < n; i++)
				ref += Q[(size_t)i * p + k] * Q[(size_t)i * p + k];
			for (int pass = 0; pass < 2; pass++)
				for (uint32_t l = 0; l < k; l++) {
					double dot = 0;
					for (uint32_t i = 0; i < n; i++)
						dot += Q[(size_t)i * p + l] * Q[(size_t)i * p + k];
					for (uint32_t i = 0; i < n; i++)
						Q[(size_t)i * p + k] -= dot * Q[(size_t)i * p + l];
				}
			for (uint32_t i = 0; i < n; i++)
				nrm += Q[(size_t)i * p + k] * Q[(size_t)i * p + k];
			if (ref > 1e-300 && nrm > 1e-20 * ref) {
				nrm = 1.0 / sqrt(nrm);
				for (uint32_t i = 0; i < n; i++)
					Q[(size_t)i * p + k] *= nrm;
				break;
			}
			for (uint32_t i = 0; i < n; i++)
				Q[(size_t)i * p + k] = rnd(state);
		}
	}
}

/*
 * The r eigenvectors of the symmetric n x n matrix G with the largest
 * eigenvalues, as the columns of B (B[i*r + k]), each with its largest
 * entry positive.  Returns LOOM_OK or LOOM_ENOMEM.
 */
static int top_eigen(const double *G, uint32_t n, uint32_t r, double *B)
{
	uint32_t p = r + 8 < n ? r + 8 : n;
	uint64_t state = 0x45494745ull; /* "EIGE" */
	int rc = LOOM_ENOMEM;

	if (n <= 48 || 2 * p >= n) {
		double *A = malloc(sizeof(double) * n * n), *V = malloc(sizeof(double) * n * n);
		double *w = malloc(sizeof(double) * n);
		if (A && V && w) {
			memcpy(A, G, sizeof(double) * n * n);
			jacobi(A, n, V, w);
			for (uint32_t i = 0; i < n; i++)
				for (uint32_t k = 0; k < r; k++)
					B[(size_t)i * r + k] = V[(size_t)i * n + k];
			rc = LOOM_OK;
		}
		free(A);
		free(V);
		free(w);
	} else {
		/* subspace iteration with Rayleigh-Ritz */
		double *Q = malloc(sizeof(double) * n * p), *Z = malloc(sizeof(double) * n * p);
		double *H = malloc(sizeof(double) * p * p), *U = malloc(sizeof(double) * p * p);
		double *th = malloc(sizeof(double) * p), *V = malloc(sizeof(double) * n * p);
		double *W = malloc(sizeof(double) * n * p);
		if (Q && Z && H && U && th && V && W) {
			for (size_t k = 0; k < (size_t)n * p; k++)
				Q[k] = rnd(&state);
			orthonormalize(Q, n, p, &state);
			for (int it = 0; it < 300; it++) {
				double res = 0;
				for (uint32_t i = 0; i < n; i++)
					for (uint32_t k = 0; k < p; k++) {
						double a = 0;
						for (uint32_t l = 0; l < n; l++)
							a += G[(size_t)i * n + l] * Q[(size_t)l * p + k];
						Z[(size_t)i * p + k] = a;
					}
				for (uint32_t a = 0; a < p; a++)
					for (uint32_t b = a; b < p; b++) {
						double s = 0;
						for (uint32_t i = 0; i < n; i++)
							s += Q[(size_t)i * p + a] * Z[(size_t)i * p + b];
						H[(size_t)a * p + b] = s;
					}
				for (uint32_t a = 0; a < p; a++)
					for (uint32_t b = 0; b < a; b++)
						H[(size_t)a * p + b] = H[(size_t)b * p + a];
				jacobi(H, p, U, th);
				for (uint32_t i = 0; i < n; i++)
					for (uint32_t k = 0; k < p; k++) {
						double v = 0, w = 0;
						for (uint32_t l = 0; l < p; l++) {
							v += Q[(size_t)i * p + l] * U[(size_t)l * p + k];
							w += Z[(size_t)i * p + l] * U[(size_t)l * p + k];
						}
						V[(size_t)i * p + k] = v;
						W[(size_t)i * p + k] = w;
					}
				for (uint32_t k = 0; k < r; k++) {
					double e = 0;
					for (uint32_t i = 0; i < n; i++) {
						double d = W[(size_t)i * p + k] - th[k] * V[(size_t)i * p + k];
						e += d * d;
					}
					if (e > res)
						res = e;
				}
				if (th[0] <= 0 || sqrt(res) <= 1e-11 * th[0])
					break;
				memcpy(Q, W, sizeof(double) * n * p);
				orthonormalize(Q, n, p, &state);
			}
			for (uint32_t i = 0; i < n; i++)
				for (uint32_t k = 0; k < r; k++)
					B[(size_t)i * r + k] = V[(size_t)i * p + k];
			rc = LOOM_OK;
		}
		free(Q);
		free(Z);
		free(H);
		free(U);
		free(th);
		free(V);
		free(W);
	}
	if (rc)
		return rc;
	for (uint32_t k = 0; k < r; k++) {
		uint32_t big = 0;
		for (uint32_t i = 1; i < n; i++)
			if (fabs(B[(size_t)i * r + k]) > fabs(B[(size_t)big * r + k]))
				big = i;
		if (B[(size_t)big * r + k] < 0)
			for (uint32_t i = 0; i < n; i++)
				B[(size_t)i * r + k] = -B[(size_t)i * r + k];
	}
	return LOOM_OK;
}

/* ---- building the tables ------------------------------------------------- */

static int check_profiles(const loom_edge_profiles *p, loom_diag *diag)
{
	size_t rec, n;
	if (!p || !p->heights)
		return loom__fail(diag, LOOM_EINVAL, "edge fix: NULL profiles");
	if (p->b1 < 3 || p->b2 < 3)
		return loom__fail(diag, LOOM_EINVAL,
		                  "edge fix: block %ux%u, expected at least 3x3", p->b1, p->b2);
	if ((uint64_t)p->b1 * p->b2 > MAX_CELLS)
		return loom__fail(diag, LOOM_ERANGE, "edge fix: block %ux%u too large",
		                  p->b1, p->b2);
	if (p->n_blocks == 0 || p->n_blocks > LOOM_SYNTH_MAX_BLOCKS)
		return loom__fail(diag, LOOM_EINVAL, "edge fix: %u source blocks",
		                  p->n_blocks);
	rec = LOOM_EDGE_RECORD(p->b1, p->b2);
	n = rec * p->n_blocks;
	for (size_t k = 0; k < n; k++)
		if (!isfinite(p->heights[k]))
			return loom__fail(diag, LOOM_EINVAL,
			                  "edge fix: block %zu: height sample %zu is not finite",
			                  k / rec, k % rec);
	return LOOM_OK;
}

LOOM_API void loom_edgefix_free(loom_edgefix *ef)
{
	if (!ef)
		return;
	free(ef->coef);
	free(ef->field_h);
	free(ef->field_v);
	free(ef->basis_h);
	free(ef->basis_v);
	free(ef->mean_h);
	free(ef->mean_v);
	free(ef);
}

static loom_edgefix *ef_alloc(uint32_t b1, uint32_t b2, uint32_t K,
                              uint32_t rh, uint32_t rv)
{
	loom_edgefix *ef = calloc(1, sizeof *ef);
	size_t cells = (size_t)b1 * b2;
	if (!ef)
		return NULL;
	ef->b1 = b1;
	ef->b2 = b2;
	ef->K = K;
	ef->rh = rh;
	ef->rv = rv;
	ef->coef = malloc(sizeof(float) * K * (2 * (size_t)rh + 2 * rv));
	ef->field_h = malloc(sizeof(float) * cells * rh);
	ef->field_v = malloc(sizeof(float) * cells * rv);
	ef->basis_h = malloc(sizeof(float) * b1 * rh);
	ef->basis_v = malloc(sizeof(float) * (b2 - 2) * rv);
	ef->mean_h = malloc(sizeof(float) * b1);
	ef->mean_v = malloc(sizeof(float) * (b2 - 2));
	if (!ef->coef || !ef->field_h || !ef->field_v || !ef->basis_h ||
	    !ef->basis_v || !ef->mean_h || !ef->mean_v) {
		loom_edgefix_free(ef);
		return NULL;
	}
	return ef;
}

/* Profile j (0 N, 1 S, 2 W, 3 E) of block t. */
static const float *prof(const loom_edge_profiles *p, uint32_t t, int j)
{
	const float *rec = p->heights + (size_t)t * LOOM_EDGE_RECORD(p->b1, p->b2);
	switch (j) {
	case 0: return rec;
	case 1: return rec + p->b1;
	case 2: return rec + 2 * (size_t)p->b1;
	default: return rec + 2 * (size_t)p->b1 + p->b2;
	}
}

/* Mean and Gram matrix of the 2K vectors v = profile[first + off .. +n) for
   profiles j0, j1 of every block. */
static void gram(const loom_edge_profiles *p, int j0, int j1, uint32_t off,
                 uint32_t n, double *mean, double *G)
{
	uint32_t K = p->n_blocks;
	double *d = G + (size_t)n * n; /* scratch after G: n doubles */
	for (uint32_t i = 0; i < n; i++)
		mean[i] = 0;
	for (uint32_t t = 0; t < K; t++)
		for (int j = 0; j < 2; j++) {
			const float *v = prof(p, t, j ? j1 : j0) + off;
			for (uint32_t i = 0; i < n; i++)
				mean[i] += v[i];
		}
	for (uint32_t i = 0; i < n; i++)
		mean[i] /= 2.0 * K;
	memset(G, 0, sizeof(double) * n * n);
	for (uint32_t t = 0; t < K; t++)
		for (int j = 0; j < 2; j++) {
			const float *v = prof(p, t, j ? j1 : j0) + off;
			for (uint32_t i = 0; i < n; i++)
				d[i] = v[i] - mean[i];
			for (uint32_t a = 0; a < n; a++) {
				double da = d[a];
				double *row = G + (size_t)a * n;
				for (uint32_t b = a; b < n; b++)
					row[b] += da * d[b];
			}
		}
	for (uint32_t a = 0; a < n; a++)
		for (uint32_t b = 0; b < a; b++)
			G[(size_t)a * n + b] = G[(size_t)b * n + a];
}

/* Solve the basis problems: fields of columns of B (n x r, double). */
static int basis_fields(const lap *L, const double *Bh, uint32_t rh,
                        const double *Bv, uint32_t rv, float *fh, float *fv)
{
	size_t cells = (size_t)L->b1 * L->b2;
	uint32_t rmax = rh > rv ? rh : rv;
	uint32_t nmax = L->nx > L->ny ? L->nx : L->ny;
	double *out = malloc(sizeof(double) * cells * (rmax ? rmax : 1));
	double *g = malloc(sizeof(double) * 2 * nmax * (rmax ? rmax : 1));
	if (!out || !g) {
		free(out);
		free(g);
		return LOOM_ENOMEM;
	}
	if (rh) {
		solve_ns(L, Bh, NULL, rh, out, g);
		for (size_t k = 0; k < cells * rh; k++)
			fh[k] = (float)out[k];
	}
	if (rv) {
		solve_we(L, Bv, NULL, rv, out, g);
		for (size_t k = 0; k < cells * rv; k++)
			fv[k] = (float)out[k];
	}
	free(out);
	free(g);
	return LOOM_OK;
}

LOOM_API int loom_edgefix_build(const loom_edge_profiles *p, uint32_t rank,
                                loom_edgefix **out, loom_diag *diag)
{
	uint32_t b1, b2, K, nv, rh, rv, nmax, stride;
	double *G = NULL, *mh = NULL, *mv = NULL, *Bh = NULL, *Bv = NULL;
	loom_edgefix *ef = NULL;
	lap L;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "edge fix: NULL output");
	*out = NULL;
	rc = check_profiles(p, diag);
	if (rc)
		return rc;
	if (rank == 0 || rank > LOOM_EDGEFIX_MAX_RANK)
		return loom__fail(diag, rank ? LOOM_ERANGE : LOOM_EINVAL,
		                  "edge fix: rank %u, expected 1..%u", rank,
		                  LOOM_EDGEFIX_MAX_RANK);
	b1 = p->b1;
	b2 = p->b2;
	K = p->n_blocks;
	nv = b2 - 2;
	rh = rank < b1 ? rank : b1;
	rv = rank < nv ? rank : nv;
	if (rh > 2 * K)
		rh = 2 * K;
	if (rv > 2 * K)
		rv = 2 * K;
	nmax = b1 > nv ? b1 : nv;
	if (lap_init(&L, b1, b2) != LOOM_OK)
		return loom__fail(diag, LOOM_ENOMEM, "edge fix: out of memory");
	ef = ef_alloc(b1, b2, K, rh, rv);
	G = malloc(sizeof(double) * ((size_t)nmax * nmax + nmax));
	mh = malloc(sizeof(double) * b1);
	mv = malloc(sizeof(double) * nv);
	Bh = malloc(sizeof(double) * b1 * rh);
	Bv = malloc(sizeof(double) * nv * rv);
	rc = LOOM_ENOMEM;
	if (!ef || !G || !mh || !mv || !Bh || !Bv)
		goto done;
	gram(p, 0, 1, 0, b1, mh, G);
	if (top_eigen(G, b1, rh, Bh))
		goto done;
	gram(p, 2, 3, 1, nv, mv, G);
	if (top_eigen(G, nv, rv, Bv))
		goto done;
	for (uint32_t i = 0; i < b1; i++) {
		ef->mean_h[i] = (float)mh[i];
		for (uint32_t k = 0; k < rh; k++)
			ef->basis_h[(size_t)i * rh + k] = (float)Bh[(size_t)i * rh + k];
	}
	for (uint32_t i = 0; i < nv; i++) {
		ef->mean_v[i] = (float)mv[i];
		for (uint32_t k = 0; k < rv; k++)
			ef->basis_v[(size_t)i * rv + k] = (float)Bv[(size_t)i * rv + k];
	}
	/* coefficients: cN cS (on B_h), cW cE (on B_v, interior samples) */
	stride = 2 * rh + 2 * rv;
	for (uint32_t t = 0; t < K; t++) {
		float *c = ef->coef + (size_t)t * stride;
		for (int j = 0; j < 4; j++) {
			const float *v = prof(p, t, j);
			uint32_t n = j < 2 ? b1 : nv, r = j < 2 ? rh : rv;
			const double *B = j < 2 ? Bh : Bv, *mean = j < 2 ? mh : mv;
			float *cj = c + (j == 0 ? 0 : j == 1 ? rh : j == 2 ? 2 * rh : 2 * rh + rv);
			if (j >= 2)
				v++; /* interior samples y = 1..b2-2 */
			for (uint32_t k = 0; k < r; k++) {
				double s = 0;
				for (uint32_t i = 0; i < n; i++)
					s += B[(size_t)i * r + k] * (v[i] - mean[i]);
				cj[k] = (float)s;
			}
		}
	}
	if (basis_fields(&L, Bh, rh, Bv, rv, ef->field_h, ef->field_v))
		goto done;
	rc = LOOM_OK;
done:
	lap_free(&L);
	free(G);
	free(mh);
	free(mv);
	free(Bh);
	free(Bv);
	if (rc) {
		loom_edgefix_free(ef);
		return loom__fail(diag, rc, "edge fix: out of memory");
	}
	*out = ef;
	return LOOM_OK;
}

LOOM_API size_t loom_edgefix_bytes(const loom_edgefix *ef)
{
	size_t cells;
	if (!ef)
		return 0;
	cells = (size_t)ef->b1 * ef->b2;
	return sizeof *ef + sizeof(float) * ((size_t)ef->K * (2 * ef->rh + 2 * ef->rv) +
	                                     cells * (ef->rh + ef->rv) + ef->b1 * ef->rh +
	                                     (ef->b2 - 2) * ef->rv + ef->b1 + ef->b2 - 2);
}

/* ---- evaluation ---------------------------------------------------------- */

typedef struct avec {
	float n[LOOM_EDGEFIX_MAX_RANK], s[LOOM_EDGEFIX_MAX_RANK];
	float w[LOOM_EDGEFIX_MAX_RANK], e[LOOM_EDGEFIX_MAX_RANK];
} avec;

static void ef_avec(const loom_edgefix *ef, const loom_synth_nbhd *nb, avec *a)
{
	uint32_t rh = ef->rh, rv = ef->rv, stride = 2 * rh + 2 * rv;
	const float *cs = ef->coef + (size_t)nb->self * stride;
	const float *cn = ef->coef + (size_t)nb->n * stride;
	const float *css = ef->coef + (size_t)nb->s * stride;
	const float *cw = ef->coef + (size_t)nb->w * stride;
	const float *ce = ef->coef + (size_t)nb->e * stride;
	for (uint32_t k = 0; k < rh; k++) {
		a->n[k] = 0.5f * (cn[rh + k] - cs[k]);
		a->s[k] = 0.5f * (css[k] - cs[rh + k]);
	}
	for (uint32_t k = 0; k < rv; k++) {
		a->w[k] = 0.5f * (cw[2 * rh + rv + k] - cs[2 * rh + k]);
		a->e[k] = 0.5f * (ce[2 * rh + k] - cs[2 * rh + rv + k]);
	}
}

static inline float dot(const float *a, const float *b, uint32_t n)
{
	float s = 0;
	for (uint32_t k = 0; k < n; k++)
		s += a[k] * b[k];
	return s;
}

static inline float ef_eval(const loom_edgefix *ef, const avec *a, uint32_t x,
                            uint32_t y)
{
	uint32_t b1 = ef->b1, b2 = ef->b2, rh = ef->rh, rv = ef->rv;
	return dot(a->n, ef->field_h + ((size_t)y * b1 + x) * rh, rh) +
	       dot(a->s, ef->field_h + ((size_t)(b2 - 1 - y) * b1 + x) * rh, rh) +
	       dot(a->w, ef->field_v + ((size_t)y * b1 + x) * rv, rv) +
	       dot(a->e, ef->field_v + ((size_t)y * b1 + (b1 - 1 - x)) * rv, rv);
}

LOOM_API void loom_edgefix_block(const loom_edgefix *ef,
                                 const loom_synth_nbhd *nb, float *dz)
{
	avec a;
	if (!ef || !nb || !dz)
		return;
	ef_avec(ef, nb, &a);
	for (uint32_t y = 0; y < ef->b2; y++)
		for (uint32_t x = 0; x < ef->b1; x++)
			dz[(size_t)y * ef->b1 + x] = ef_eval(ef, &a, x, y);
}

LOOM_API float loom_edgefix_at(const loom_edgefix *ef,
                               const loom_synth_nbhd *nb, uint32_t x,
                               uint32_t y)
{
	avec a;
	if (!ef || !nb || x >= ef->b1 || y >= ef->b2)
		return 0;
	ef_avec(ef, nb, &a);
	return ef_eval(ef, &a, x, y);
}

/* ---- exact per-block solve ----------------------------------------------- */

static int nb_ok(const loom_synth_nbhd *nb, uint32_t K)
{
	return nb->self < K && nb->n < K && nb->s < K && nb->w < K && nb->e < K;
}

LOOM_API int loom_edgefix_exact(const loom_edge_profiles *p,
                                const loom_synth_nbhd *nb, float *dz)
{
	uint32_t b1, b2, nv;
	double *vn, *vs, *vw, *ve, *o1, *o2, *g;
	size_t cells;
	lap L;
	int rc = LOOM_ENOMEM;

	if (!nb || !dz || check_profiles(p, NULL) != LOOM_OK || !nb_ok(nb, p->n_blocks))
		return LOOM_EINVAL;
	b1 = p->b1;
	b2 = p->b2;
	nv = b2 - 2;
	cells = (size_t)b1 * b2;
	if (lap_init(&L, b1, b2))
		return LOOM_ENOMEM;
	vn = malloc(sizeof(double) * (2 * (size_t)b1 + 2 * nv + 2 * cells + 2 * (b1 + b2)));
	if (!vn)
		goto done;
	vs = vn + b1;
	vw = vs + b1;
	ve = vw + nv;
	o1 = ve + nv;
	o2 = o1 + cells;
	g = o2 + cells;
	for (uint32_t x = 0; x < b1; x++) {
		vn[x] = 0.5 * ((double)prof(p, nb->n, 1)[x] - prof(p, nb->self, 0)[x]);
		vs[x] = 0.5 * ((double)prof(p, nb->s, 0)[x] - prof(p, nb->self, 1)[x]);
	}
	for (uint32_t y = 1; y + 1 < b2; y++) {
		vw[y - 1] = 0.5 * ((double)prof(p, nb->w, 3)[y] - prof(p, nb->self, 2)[y]);
		ve[y - 1] = 0.5 * ((double)prof(p, nb->e, 2)[y] - prof(p, nb->self, 3)[y]);
	}
	solve_ns(&L, vn, vs, 1, o1, g);
	solve_we(&L, vw, ve, 1, o2, g);
	for (size_t k = 0; k < cells; k++)
		dz[k] = (float)(o1[k] + o2[k]);
	rc = LOOM_OK;
done:
	free(vn);
	lap_free(&L);
	return rc;
}

/* ---- tables -------------------------------------------------------------- */

LOOM_API int loom_edgefix_get_tables(const loom_edgefix *ef,
                                     loom_edgefix_tables *t)
{
	if (!ef || !t)
		return LOOM_EINVAL;
	t->b1 = ef->b1;
	t->b2 = ef->b2;
	t->n_blocks = ef->K;
	t->rank_h = ef->rh;
	t->rank_v = ef->rv;
	t->coef = ef->coef;
	t->field_h = ef->field_h;
	t->field_v = ef->field_v;
	t->basis_h = ef->basis_h;
	t->basis_v = ef->basis_v;
	t->mean_h = ef->mean_h;
	t->mean_v = ef->mean_v;
	return LOOM_OK;
}

int loom__edgefix_alloc(const loom_edgefix_tables *t, loom_edgefix **out,
                        float *arrays[7], loom_diag *diag)
{
	loom_edgefix *ef;

	*out = NULL;
	if (t->b1 < 3 || t->b2 < 3 || (uint64_t)t->b1 * t->b2 > MAX_CELLS ||
	    t->n_blocks == 0 || t->n_blocks > LOOM_SYNTH_MAX_BLOCKS ||
	    t->rank_h > LOOM_EDGEFIX_MAX_RANK || t->rank_v > LOOM_EDGEFIX_MAX_RANK ||
	    t->rank_h > t->b1 || t->rank_v > t->b2 - 2)
		return loom__fail(diag, LOOM_EINVAL,
		                  "edge fix tables: block %ux%u, %u blocks, ranks %u/%u out of range",
		                  t->b1, t->b2, t->n_blocks, t->rank_h, t->rank_v);
	ef = ef_alloc(t->b1, t->b2, t->n_blocks, t->rank_h, t->rank_v);
	if (!ef)
		return loom__fail(diag, LOOM_ENOMEM, "edge fix tables: out of memory");
	arrays[0] = ef->coef;
	arrays[1] = ef->field_h;
	arrays[2] = ef->field_v;
	arrays[3] = ef->basis_h;
	arrays[4] = ef->basis_v;
	arrays[5] = ef->mean_h;
	arrays[6] = ef->mean_v;
	*out = ef;
	return LOOM_OK;
}

LOOM_API int loom_edgefix_from_tables(const loom_edgefix_tables *t,
                                      loom_edgefix **out, loom_diag *diag)
{
	loom_edgefix *ef;
	float *a[7];
	size_t cells;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "edge fix tables: NULL output");
	*out = NULL;
	if (!t || !t->coef || !t->field_h || !t->field_v || !t->basis_h ||
	    !t->basis_v || !t->mean_h || !t->mean_v)
		return loom__fail(diag, LOOM_EINVAL, "edge fix tables: NULL array");
	rc = loom__edgefix_alloc(t, &ef, a, diag);
	if (rc)
		return rc;
	cells = (size_t)t->b1 * t->b2;
	memcpy(a[0], t->coef, sizeof(float) * t->n_blocks * (2 * (size_t)t->rank_h + 2 * t->rank_v));
	memcpy(a[1], t->field_h, sizeof(float) * cells * t->rank_h);
	memcpy(a[2], t->field_v, sizeof(float) * cells * t->rank_v);
	memcpy(a[3], t->basis_h, sizeof(float) * t->b1 * t->rank_h);
	memcpy(a[4], t->basis_v, sizeof(float) * (t->b2 - 2) * t->rank_v);
	memcpy(a[5], t->mean_h, sizeof(float) * t->b1);
	memcpy(a[6], t->mean_v, sizeof(float) * (t->b2 - 2));
	*out = ef;
	return LOOM_OK;
}

/* ---- the paper's per-output-block formulation ---------------------------- */

LOOM_API void loom_edgefix_paper_free(loom_edgefix_paper *pp)
{
	if (!pp)
		return;
	free(pp->CT);
	free(pp->CL);
	free(pp->fT);
	free(pp->fL);
	free(pp);
}

LOOM_API size_t loom_edgefix_paper_bytes(const loom_edgefix_paper *pp)
{
	if (!pp)
		return 0;
	return sizeof *pp + sizeof(float) * ((size_t)pp->rows * pp->cols * (pp->rT + pp->rL) +
	                                     (size_t)pp->b1 * pp->b2 * (pp->rT + pp->rL));
}

/* t_i (b1) and l_i (b2-2) of crossing (i, j). */
static void paper_tl(const loom_edge_profiles *p, const uint16_t *as,
                     uint32_t rows, uint32_t cols, uint32_t i, uint32_t j,
                     double *t, double *l)
{
	uint16_t s = as[(size_t)i * cols + j];
	uint16_t n = as[(size_t)(i ? i - 1 : rows - 1) * cols + j];
	uint16_t w = as[(size_t)i * cols + (j ? j - 1 : cols - 1)];
	for (uint32_t x = 0; x < p->b1; x++)
		t[x] = 0.5 * ((double)prof(p, n, 1)[x] - prof(p, s, 0)[x]);
	for (uint32_t y = 1; y + 1 < p->b2; y++)
		l[y - 1] = 0.5 * ((double)prof(p, w, 3)[y] - prof(p, s, 2)[y]);
}

LOOM_API int loom_edgefix_paper_new(const loom_edge_profiles *p,
                                    const uint16_t *assign, uint32_t rows,
                                    uint32_t cols, uint32_t rank,
                                    const loom_edgefix *basis,
                                    loom_edgefix_paper **out, loom_diag *diag)
{
	uint32_t b1, b2, nv, rT, rL, nmax;
	size_t MN;
	loom_edgefix_paper *pp = NULL;
	double *G = NULL, *BT = NULL, *BL = NULL, *t = NULL, *l = NULL;
	lap L;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "paper edge fix: NULL output");
	*out = NULL;
	rc = check_profiles(p, diag);
	if (rc)
		return rc;
	if (!assign || rows == 0 || cols == 0 || rank == 0 || rank > LOOM_EDGEFIX_MAX_RANK)
		return loom__fail(diag, LOOM_EINVAL, "paper edge fix: bad assignment or rank");
	MN = (size_t)rows * cols;
	for (size_t k = 0; k < MN; k++)
		if (assign[k] >= p->n_blocks)
			return loom__fail(diag, LOOM_EINVAL,
			                  "paper edge fix: crossing %zu copies block %u of %u", k,
			                  assign[k], p->n_blocks);
	b1 = p->b1;
	b2 = p->b2;
	nv = b2 - 2;
	if (basis && (basis->b1 != b1 || basis->b2 != b2))
		return loom__fail(diag, LOOM_EINVAL, "paper edge fix: basis of another block size");
	rT = basis ? basis->rh : (rank < b1 ? rank : b1);
	rL = basis ? basis->rv : (rank < nv ? rank : nv);
	nmax = b1 > nv ? b1 : nv;
	if (lap_init(&L, b1, b2))
		return loom__fail(diag, LOOM_ENOMEM, "paper edge fix: out of memory");
	pp = calloc(1, sizeof *pp);
	G = malloc(sizeof(double) * nmax * nmax);
	BT = malloc(sizeof(double) * b1 * rT);
	BL = malloc(sizeof(double) * nv * rL);
	t = malloc(sizeof(double) * b1);
	l = malloc(sizeof(double) * nv);
	rc = LOOM_ENOMEM;
	if (!pp || !G || !BT || !BL || !t || !l)
		goto done;
	pp->b1 = b1;
	pp->b2 = b2;
	pp->rows = rows;
	pp->cols = cols;
	pp->rT = rT;
	pp->rL = rL;
	pp->CT = malloc(sizeof(float) * MN * rT);
	pp->CL = malloc(sizeof(float) * MN * rL);
	pp->fT = malloc(sizeof(float) * b1 * b2 * rT);
	pp->fL = malloc(sizeof(float) * b1 * b2 * rL);
	if (!pp->CT || !pp->CL || !pp->fT || !pp->fL)
		goto done;
	if (basis) {
		for (size_t k = 0; k < (size_t)b1 * rT; k++)
			BT[k] = basis->basis_h[k];
		for (size_t k = 0; k < (size_t)nv * rL; k++)
			BL[k] = basis->basis_v[k];
	} else {
		/* T T^t and L L^t, uncentred as in the paper */
		double *GL;
		memset(G, 0, sizeof(double) * nmax * nmax);
		GL = malloc(sizeof(double) * nv * nv);
		if (!GL)
			goto done;
		memset(GL, 0, sizeof(double) * nv * nv);
		for (uint32_t i = 0; i < rows; i++)
			for (uint32_t j = 0; j < cols; j++) {
				paper_tl(p, assign, rows, cols, i, j, t, l);
				for (uint32_t a = 0; a < b1; a++)
					for (uint32_t b = 0; b < b1; b++)
						G[(size_t)a * b1 + b] += t[a] * t[b];
				for (uint32_t a = 0; a < nv; a++)
					for (uint32_t b = 0; b < nv; b++)
						GL[(size_t)a * nv + b] += l[a] * l[b];
			}
		{
			int erc = top_eigen(G, b1, rT, BT);
			if (erc == LOOM_OK)
				erc = top_eigen(GL, nv, rL, BL);
			free(GL);
			if (erc)
				goto done;
		}
	}
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++) {
			size_t idx = (size_t)i * cols + j;
			paper_tl(p, assign, rows, cols, i, j, t, l);
			for (uint32_t k = 0; k < rT; k++) {
				double s = 0;
				for (uint32_t x = 0; x < b1; x++)
					s += BT[(size_t)x * rT + k] * t[x];
				pp->CT[idx * rT + k] = (float)s;
			}
			for (uint32_t k = 0; k < rL; k++) {
				double s = 0;
				for (uint32_t y = 0; y < nv; y++)
					s += BL[(size_t)y * rL + k] * l[y];
				pp->CL[idx * rL + k] = (float)s;
			}
		}
	if (basis_fields(&L, BT, rT, BL, rL, pp->fT, pp->fL))
		goto done;
	rc = LOOM_OK;
done:
	lap_free(&L);
	free(G);
	free(BT);
	free(BL);
	free(t);
	free(l);
	if (rc) {
		loom_edgefix_paper_free(pp);
		return loom__fail(diag, rc, "paper edge fix: out of memory");
	}
	*out = pp;
	return LOOM_OK;
}

LOOM_API int loom_edgefix_paper_block(const loom_edgefix_paper *pp,
                                      uint32_t i, uint32_t j, float *dz)
{
	uint32_t b1, b2, rT, rL;
	const float *ci, *li, *ck, *le;

	if (!pp || !dz)
		return LOOM_EINVAL;
	if (i >= pp->rows || j >= pp->cols)
		return LOOM_ERANGE;
	b1 = pp->b1;
	b2 = pp->b2;
	rT = pp->rT;
	rL = pp->rL;
	ci = pp->CT + ((size_t)i * pp->cols + j) * rT;
	li = pp->CL + ((size_t)i * pp->cols + j) * rL;
	ck = pp->CT + ((size_t)(i + 1 == pp->rows ? 0 : i + 1) * pp->cols + j) * rT;
	le = pp->CL + ((size_t)i * pp->cols + (j + 1 == pp->cols ? 0 : j + 1)) * rL;
	for (uint32_t y = 0; y < b2; y++)
		for (uint32_t x = 0; x < b1; x++)
			dz[(size_t)y * b1 + x] =
			        dot(ci, pp->fT + ((size_t)y * b1 + x) * rT, rT) +
			        dot(li, pp->fL + ((size_t)y * b1 + x) * rL, rL) -
			        dot(ck, pp->fT + ((size_t)(b2 - 1 - y) * b1 + x) * rT, rT) -
			        dot(le, pp->fL + ((size_t)y * b1 + (b1 - 1 - x)) * rL, rL);
	return LOOM_OK;
}

/* ---- seam metric --------------------------------------------------------- */

typedef struct seam_acc {
	double sum_b, max_b, sum_a, max_a, sum_cb, sum_c;
	uint64_t n, nc;
} seam_acc;

static void seam_add(seam_acc *s, double before, double after, int corner)
{
	before = fabs(before);
	after = fabs(after);
	s->sum_b += before;
	s->sum_a += after;
	if (before > s->max_b)
		s->max_b = before;
	if (after > s->max_a)
		s->max_a = after;
	s->n++;
	if (corner) {
		s->sum_cb += before;
		s->sum_c += after;
		s->nc++;
	}
}

/* Add the S and E edges of block (I, J) to acc (if not NULL); out (if not
   NULL) receives their own mean jumps as loom_edgefix_seam_block. */
static void seam_one(const loom_edgefix *ef, const loom_edge_profiles *p,
                     const loom_synth_lookup *lk, int64_t I, int64_t J,
                     seam_acc *acc, double out[4])
{
	loom_synth_nbhd a, below, right;
	avec va, vb, vr;
	uint32_t b1 = p->b1, b2 = p->b2;
	seam_acc local[2];

	memset(local, 0, sizeof local);
	loom_synth_nbhd_at(lk, I, J, &a);
	loom_synth_nbhd_at(lk, I + 1, J, &below);
	loom_synth_nbhd_at(lk, I, J + 1, &right);
	ef_avec(ef, &a, &va);
	ef_avec(ef, &below, &vb);
	ef_avec(ef, &right, &vr);
	for (uint32_t x = 0; x < b1; x++) {
		double h0 = prof(p, a.self, 1)[x], h1 = prof(p, below.self, 0)[x];
		double d0 = ef_eval(ef, &va, x, b2 - 1), d1 = ef_eval(ef, &vb, x, 0);
		seam_add(&local[0], h0 - h1, (h0 + d0) - (h1 + d1), 0);
		if (acc)
			seam_add(acc, h0 - h1, (h0 + d0) - (h1 + d1), 0);
	}
	for (uint32_t y = 0; y < b2; y++) {
		double h0 = prof(p, a.self, 3)[y], h1 = prof(p, right.self, 2)[y];
		double d0 = ef_eval(ef, &va, b1 - 1, y), d1 = ef_eval(ef, &vr, 0, y);
		int corner = y == 0 || y == b2 - 1;
		seam_add(&local[1], h0 - h1, (h0 + d0) - (h1 + d1), corner);
		if (acc)
			seam_add(acc, h0 - h1, (h0 + d0) - (h1 + d1), corner);
	}
	if (out) {
		out[0] = local[0].sum_b / b1;
		out[1] = local[0].sum_a / b1;
		out[2] = local[1].sum_b / b2;
		out[3] = local[1].sum_a / b2;
	}
}

static int seam_args(const loom_edgefix *ef, const loom_edge_profiles *p,
                     const loom_synth_lookup *lk)
{
	if (!ef || !lk || check_profiles(p, NULL) != LOOM_OK)
		return LOOM_EINVAL;
	if (ef->b1 != p->b1 || ef->b2 != p->b2 || ef->K != p->n_blocks)
		return LOOM_EINVAL;
	return LOOM_OK;
}

LOOM_API int loom_edgefix_seam(const loom_edgefix *ef,
                               const loom_edge_profiles *p,
                               const loom_synth_lookup *lk, int64_t i0,
                               int64_t j0, uint64_t h, uint64_t w,
                               double internal_step, loom_seam_metrics *out)
{
	seam_acc acc;

	if (!out || seam_args(ef, p, lk))
		return LOOM_EINVAL;
	memset(&acc, 0, sizeof acc);
	for (uint64_t a = 0; a < h; a++)
		for (uint64_t b = 0; b < w; b++)
			seam_one(ef, p, lk, i0 + (int64_t)a, j0 + (int64_t)b, &acc, NULL);
	memset(out, 0, sizeof *out);
	out->samples = acc.n;
	out->before_mean = acc.n ? acc.sum_b / (double)acc.n : 0;
	out->after_mean = acc.n ? acc.sum_a / (double)acc.n : 0;
	out->before_max = acc.max_b;
	out->after_max = acc.max_a;
	out->corner_samples = acc.nc;
	out->corner_before_mean = acc.nc ? acc.sum_cb / (double)acc.nc : 0;
	out->corner_after_mean = acc.nc ? acc.sum_c / (double)acc.nc : 0;
	out->internal_step = internal_step;
	if (internal_step > 0) {
		out->before_ratio = out->before_mean / internal_step;
		out->after_ratio = out->after_mean / internal_step;
	}
	return LOOM_OK;
}

LOOM_API int loom_edgefix_seam_block(const loom_edgefix *ef,
                                     const loom_edge_profiles *p,
                                     const loom_synth_lookup *lk, int64_t I,
                                     int64_t J, double out[4])
{
	if (!out || seam_args(ef, p, lk))
		return LOOM_EINVAL;
	seam_one(ef, p, lk, I, J, NULL, out);
	return LOOM_OK;
}
