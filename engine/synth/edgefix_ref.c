/*
 * engine/synth/edgefix_ref.c - reference formulations of the edge fix,
 * for tests and benchmarks: the exact per-block solve (no low-rank basis)
 * and the paper's per-output-block coefficient tables (section 5.5), whose
 * memory grows with the design (edgefix.c explains the per-source-block
 * tables loom uses instead).
 */
#include "edgefix_impl.h"

/* ---- exact per-block solve ----------------------------------------------- */


LOOM_API int loom_edgefix_exact(const loom_edge_profiles *p,
                                const loom_synth_nbhd *nb, float *dz)
{
	uint32_t b1, b2, nv;
	double *vn, *vs, *vw, *ve, *o1, *o2, *g;
	size_t cells;
	loom_edge_profiles q;
	float *tbuf = NULL;
	lap L;
	int rc = LOOM_ENOMEM;

	if (!nb || !dz || loom__edgefix_check(p, NULL) != LOOM_OK || !nb_ok(nb, p->n_blocks))
		return LOOM_EINVAL;
	rc = loom__edgefix_targets(p, &q, &tbuf);
	if (rc)
		return rc;
	rc = LOOM_ENOMEM;
	p = &q;
	b1 = p->b1;
	b2 = p->b2;
	nv = b2 - 2;
	cells = (size_t)b1 * b2;
	if (loom__lap_init(&L, b1, b2)) {
		free(tbuf);
		return LOOM_ENOMEM;
	}
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
	loom__lap_solve_ns(&L, vn, vs, 1, o1, g);
	loom__lap_solve_we(&L, vw, ve, 1, o2, g);
	for (size_t k = 0; k < cells; k++)
		dz[k] = (float)(o1[k] + o2[k]);
	rc = LOOM_OK;
done:
	free(vn);
	free(tbuf);
	loom__lap_free(&L);
	return rc;
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
	rc = loom__edgefix_check(p, diag);
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
	if (loom__lap_init(&L, b1, b2))
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
			int erc = loom__top_eigen(G, b1, rT, BT);
			if (erc == LOOM_OK)
				erc = loom__top_eigen(GL, nv, rL, BL);
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
	if (loom__edgefix_fields(&L, BT, rT, BL, rL, pp->fT, pp->fL))
		goto done;
	rc = LOOM_OK;
done:
	loom__lap_free(&L);
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
