/*
 * engine/synth/edgefix_impl.h - the edge fix's shared pieces, private to
 * its files: edgefix.c (tables: building, evaluation, import/export; the
 * essay), laplace.c (the discrete Laplace solver and the symmetric
 * eigensolver behind the low-rank basis), edgefix_ref.c (the reference
 * formulations: exact per-block solve, the paper's per-output-block
 * tables), seam.c (the seam metric).
 */
#ifndef LOOM_EDGEFIX_IMPL_H
#define LOOM_EDGEFIX_IMPL_H

#include "core/internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CELLS (1u << 24)

struct loom_edgefix {
	uint32_t b1, b2, K, rh, rv;
	float *coef;      /* K * (2 rh + 2 rv) */
	float *field_h;   /* compact (loom_edgefix_tables): row y's b1 cells
	                     of pre[y] ranks from off[y] */
	float *field_v;   /* compact: cell (x, y)'s pre[b2 + x] ranks from
	                     y*off[b2 + b1] + off[b2 + x] */
	float *basis_h;   /* b1*rh */
	float *basis_v;   /* (b2-2)*rv */
	float *mean_h;    /* b1 */
	float *mean_v;    /* b2-2 */
	uint8_t *pre;     /* b2 + b1: the ranks stored and summed along each
	                     row (N/S fields), then each column (W/E fields):
	                     the fields past them are exactly 0 there
	                     (loom__edgefix_finish; the whole ranks until then,
	                     when the compact layout is the whole one) */
	uint32_t *off;    /* b2 + b1 + 1: the offsets of the compact layout
	                     (set_offsets in edgefix.c) */
};

struct loom_edgefix_paper {
	uint32_t b1, b2, rows, cols, rT, rL;
	float *CT;        /* rows*cols*rT */
	float *CL;        /* rows*cols*rL */
	float *fT;        /* b1*b2*rT */
	float *fL;        /* b1*b2*rL */
};

/* The screening of the edge fix's equation, (4 + kappa) u = the sum of the
   four neighbours: kappa = 1 / l^2 with l = min(b1, b2) / BAND voxels, the
   distance over which a seam's correction decays by a factor of about e
   (edgefix.c, "Calibration"). */
#define LOOM__EDGEFIX_BAND 8.0
double loom__edgefix_kappa(uint32_t b1, uint32_t b2);

/* Sine modes and decay profiles of one block size. */
typedef struct lap {
	uint32_t b1, b2, nx, ny;
	double kappa; /* loom__edgefix_kappa(b1, b2) */
	double *sx;   /* nx*nx: sx[(x-1)*nx + m-1] = sin(m pi x / (b1-1)) */
	double *sy;   /* ny*ny */
	double *phi;  /* nx*b2: phi[(m-1)*b2 + y] (N-edge problem) */
	double *psi;  /* ny*b1: psi[(m-1)*b1 + x] (W-edge problem) */
} lap;

/* laplace.c: sine modes and decay profiles of a b1 x b2 block (LOOM_OK or
   LOOM_ENOMEM); free with loom__lap_free (a zeroed lap is a no-op). */
int loom__lap_init(lap *L, uint32_t b1, uint32_t b2);
void loom__lap_free(lap *L);
/* laplace.c: fields of r N/S-edge (solve_ns) or W/E-edge (solve_we) data
   vectors v (and, when not NULL, the opposite edge's vs / ve), written to
   out (b1*b2*r, field k of cell c at out[c*r + k]); g is work space. */
void loom__lap_solve_ns(const lap *L, const double *v, const double *vs,
                        uint32_t r, double *out, double *g);
void loom__lap_solve_we(const lap *L, const double *v, const double *ve,
                        uint32_t r, double *out, double *g);
/* laplace.c: the top r eigenvectors of the symmetric n x n matrix G, as
   the columns of B (n x r); nonzero on failure. */
int loom__top_eigen(const double *G, uint32_t n, uint32_t r, double *B);

/* edgefix.c: check a profile table (LOOM_OK, or an error in diag). */
int loom__edgefix_check(const loom_edge_profiles *p, loom_diag *diag);
/* edgefix.c: the edge data the fix works on: *q = *p when p has no set;
   else q's heights (in *buf, malloc'd, the caller frees) are the mid-seam
   profiles (see loom_edge_profiles.set).  LOOM_OK, LOOM_EINVAL (the set
   has another K), LOOM_ENOMEM. */
int loom__edgefix_targets(const loom_edge_profiles *p, loom_edge_profiles *q,
                          float **buf);
/* edgefix.c: the basis fields of the N/S (Bh, rank rh) and W/E (Bv, rank
   rv) bases into field_h, field_v; nonzero when out of memory. */
int loom__edgefix_fields(const lap *L, const double *Bh, uint32_t rh,
                         const double *Bv, uint32_t rv, float *fh, float *fv);

/* Profile j (0 N, 1 S, 2 W, 3 E) of block t. */
static inline const float *prof(const loom_edge_profiles *p, uint32_t t, int j)
{
	const float *rec = p->heights + (size_t)t * LOOM_EDGE_RECORD(p->b1, p->b2);
	switch (j) {
	case 0: return rec;
	case 1: return rec + p->b1;
	case 2: return rec + 2 * (size_t)p->b1;
	default: return rec + 2 * (size_t)p->b1 + p->b2;
	}
}

static inline int nb_ok(const loom_synth_nbhd *nb, uint32_t K)
{
	return nb->self < K && nb->n < K && nb->s < K && nb->w < K && nb->e < K;
}

/* ---- evaluation (hot: inline) ---- */

typedef struct avec {
	float n[LOOM_EDGEFIX_MAX_RANK], s[LOOM_EDGEFIX_MAX_RANK];
	float w[LOOM_EDGEFIX_MAX_RANK], e[LOOM_EDGEFIX_MAX_RANK];
} avec;

static inline void ef_avec(const loom_edgefix *ef, const loom_synth_nbhd *nb, avec *a)
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
	uint32_t b1 = ef->b1, b2 = ef->b2, ys = b2 - 1 - y, xe = b1 - 1 - x;
	const uint8_t *pre = ef->pre;
	const uint32_t *off = ef->off;
	size_t row_v = (size_t)y * off[b2 + b1];
	/* the ranks stored along each row and column: those past them are
	   +-0, so the same sums as over every rank */
	return dot(a->n, ef->field_h + off[y] + (size_t)x * pre[y], pre[y]) +
	       dot(a->s, ef->field_h + off[ys] + (size_t)x * pre[ys], pre[ys]) +
	       dot(a->w, ef->field_v + row_v + off[b2 + x], pre[b2 + x]) +
	       dot(a->e, ef->field_v + row_v + off[b2 + xe], pre[b2 + xe]);
}

#endif /* LOOM_EDGEFIX_IMPL_H */
