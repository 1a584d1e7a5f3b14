/*
 * engine/synth/laplace.c - the numerical kernels of the edge fix
 * (edgefix.c has the essay): the discrete screened 5-point Laplace problem on a
 * b1 x b2 block solved exactly in sine modes, one edge's data at a time,
 * and a symmetric eigensolver (cyclic Jacobi, subspace iteration with a
 * Rayleigh-Ritz step) for the low-rank profile bases.
 */
#include "edgefix_impl.h"

/* ---- the Laplace solver -------------------------------------------------- */


void loom__lap_free(lap *L)
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

double loom__edgefix_kappa(uint32_t b1, uint32_t b2)
{
	double l = (double)(b1 < b2 ? b1 : b2) / LOOM__EDGEFIX_BAND;
	return 1.0 / (l * l);
}

static void modes(uint32_t n, uint32_t span, uint32_t along, double kappa,
                  double *s, double *prof)
{
	double L = (double)(n + 1); /* = span - 1 */
	(void)span;
	for (uint32_t x = 1; x <= n; x++)
		for (uint32_t m = 1; m <= n; m++)
			s[(size_t)(x - 1) * n + m - 1] = sin(M_PI * (double)m * (double)x / L);
	for (uint32_t m = 1; m <= n; m++) {
		double c = 2.0 + 0.5 * kappa - cos(M_PI * (double)m / L);
		double mu = log(c + sqrt(c * c - 1.0));
		for (uint32_t y = 0; y < along; y++)
			prof[(size_t)(m - 1) * along + y] = decay(mu, (double)(along - 1), (double)y);
	}
}

int loom__lap_init(lap *L, uint32_t b1, uint32_t b2)
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
		loom__lap_free(L);
		return LOOM_ENOMEM;
	}
	L->kappa = loom__edgefix_kappa(b1, b2);
	modes(L->nx, b1, b2, L->kappa, L->sx, L->phi);
	modes(L->ny, b2, b1, L->kappa, L->sy, L->psi);
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
void loom__lap_solve_ns(const lap *L, const double *v, const double *vs,
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
void loom__lap_solve_we(const lap *L, const double *v, const double *ve,
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
int loom__top_eigen(const double *G, uint32_t n, uint32_t r, double *B)
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
