/*
 * engine/synth/edgefix.c - edge fixing (paper 5.5) with tables per SOURCE block.
 *
 * Offset field of an output block (dz: how much its content is raised; the
 * lookup reads source z - dz).  On the block's grid x in [0,b1), y in
 * [0,b2) dz solves the screened 5-point equation (4 + kappa) dz = the sum of
 * its four neighbours inside (kappa: "Calibration" below) with Dirichlet
 * values
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
 * where four blocks meet and pairwise means cannot all agree.  (A plain
 * 4-way mean at the corners made them worse on the generated database,
 * whose corner columns are gaps with extrapolated profiles; fabrics add a
 * calibrated corner term instead, engine/synth/fabric.c "Block corners",
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
 *     cosh mu_m = 2 + kappa/2 - cos(m pi/(b1-1)),
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
 * Calibration against the woven cloth (docs/fidelity.md).  Closing every
 * seam is not the goal: woven cloth has its own jumps across crossing
 * boundaries, where a yarn passes from over to under (a seam ratio of 3-3.6
 * at the small preset), and a fix that closes them over-smooths (seam ratio
 * 1.5-1.7) and, because the harmonic field reaches across the whole block,
 * moves the blocks' mean heights (block-offset SD above the floor of two
 * weavings).  So two changes, both in the tables only:
 *   - Targets (loom_edge_profiles.set).  The N (W) data of source block t
 *     is not t's own N (W) profile but the S (E) profile of the block above
 *     (left of) t in its own exemplar, where it has one.  The fix then makes
 *     the output seam's jump equal to the jump t had across that edge in its
 *     exemplar: one sample of the woven cloth's own jump for the same
 *     neighbourhood (the assignment matches the codes), not zero.  On the
 *     exemplar's top row and left column, where t has no such seam, it
 *     borrows its donor's: t's own profile plus the jump of its nearest
 *     image under the exemplar's symmetries that has a block above (left
 *     of) it (loom__edgefix_donor, loom__edgefix_target); only in an
 *     exemplar without symmetries does t keep its own profile (the seam is
 *     closed there; it was on every top row and left column before
 *     2026-12-07).  Without a set: the profiles as given.
 *   - Screening.  dz solves (4 + kappa) u = the sum of its four neighbours
 *     instead of Laplace's equation, kappa = 1 / l^2, l = min(b1, b2) / 8:
 *     a seam's correction decays by about e over l voxels (two at the small
 *     preset, 8.75 at the paper's: the same ~45 um), so it bends the yarns
 *     near the edge and leaves the block's interior and mean height as
 *     copied.  Everything below holds with mu_m from
 *     cosh mu_m = 2 + kappa/2 - cos(m pi/(b1-1)).
 *
 * Basis.  Top eigenvectors of the profile Gram matrix (n x n, n = b1 or
 * b2-2) by subspace iteration with a Rayleigh-Ritz step solved by our cyclic
 * Jacobi method; the plain Jacobi method on the whole matrix when the rank
 * is a large part of n.
 */
#include "edgefix_impl.h"
#include "fabric_internal.h"

/* ---- building the tables ------------------------------------------------- */

int loom__edgefix_check(const loom_edge_profiles *p, loom_diag *diag)
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
	free(ef->pre);
	free(ef->off);
	free(ef);
}

/* ef->off from ef->pre: row y's N/S fields start at b1 * (pre[0] + ... +
   pre[y-1]); a row of W/E fields holds pre[b2] + ... + pre[b2+b1-1]
   floats, column x's from the sum of the columns before it.  With every
   prefix at its rank this is the whole layout. */
static void set_offsets(loom_edgefix *ef)
{
	uint32_t b1 = ef->b1, b2 = ef->b2, s = 0;
	for (uint32_t y = 0; y < b2; y++) {
		ef->off[y] = s;
		s += b1 * ef->pre[y];
	}
	s = 0;
	for (uint32_t x = 0; x < b1; x++) {
		ef->off[b2 + x] = s;
		s += ef->pre[b2 + x];
	}
	ef->off[b2 + b1] = s;
}

/* Floats the compact fields hold: N/S (*nh) and W/E (*nv). */
static void field_sizes(const loom_edgefix *ef, size_t *nh, size_t *nv)
{
	uint32_t b2 = ef->b2;
	*nh = (size_t)ef->off[b2 - 1] + (size_t)ef->b1 * ef->pre[b2 - 1];
	*nv = (size_t)b2 * ef->off[b2 + ef->b1];
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
	/* + 1: rank 0 (no fix) keeps every array non-NULL */
	ef->coef = malloc(sizeof(float) * (K * (2 * (size_t)rh + 2 * rv) + 1));
	ef->field_h = malloc(sizeof(float) * (cells * rh + 1));
	ef->field_v = malloc(sizeof(float) * (cells * rv + 1));
	ef->basis_h = malloc(sizeof(float) * ((size_t)b1 * rh + 1));
	ef->basis_v = malloc(sizeof(float) * ((size_t)(b2 - 2) * rv + 1));
	ef->mean_h = malloc(sizeof(float) * b1);
	ef->mean_v = malloc(sizeof(float) * (b2 - 2));
	ef->pre = malloc((size_t)b1 + b2);
	ef->off = malloc(sizeof(uint32_t) * ((size_t)b1 + b2 + 1));
	if (!ef->coef || !ef->field_h || !ef->field_v || !ef->basis_h ||
	    !ef->basis_v || !ef->mean_h || !ef->mean_v || !ef->pre || !ef->off) {
		loom_edgefix_free(ef);
		return NULL;
	}
	/* every rank everywhere (the whole layout) until loom__edgefix_finish */
	memset(ef->pre, (int)rh, b2);
	memset(ef->pre + b2, (int)rv, b1);
	set_offsets(ef);
	return ef;
}

void loom__edgefix_target(const loom_edge_profiles *p, uint32_t t, int j, float *out)
{
	uint32_t b1 = p->b1, b2 = p->b2, n = j < 2 ? b1 : b2, d;
	int opp = j == 0 ? 1 : j == 1 ? 0 : j == 2 ? 3 : 2;
	loom_synth_block b;

	d = p->set && (j == 0 || j == 2) ? loom__edgefix_donor(p->set, t, j) : LOOM_SYNTH_NONE;
	if (d == t) { /* the woven neighbour's side */
		loom_synth_block_info(p->set, t, &b);
		memcpy(out, prof(p, j == 0 ? b.up : b.left, opp), sizeof(float) * n);
	} else if (d != LOOM_SYNTH_NONE) { /* t's side plus the donor's woven jump */
		const float *own = prof(p, t, j), *dn = prof(p, d, j), *nb;
		loom_synth_block_info(p->set, d, &b);
		nb = prof(p, j == 0 ? b.up : b.left, opp);
		for (uint32_t i = 0; i < n; i++)
			out[i] = own[i] + (nb[i] - dn[i]);
	} else {
		memcpy(out, prof(p, t, j), sizeof(float) * n);
	}
}

int loom__edgefix_targets(const loom_edge_profiles *p, loom_edge_profiles *q,
                          float **buf)
{
	uint32_t K = p->n_blocks, b1 = p->b1, b2 = p->b2;
	size_t rec = LOOM_EDGE_RECORD(b1, b2);
	float *h;

	*q = *p;
	q->set = NULL;
	*buf = NULL;
	if (!p->set)
		return LOOM_OK;
	if (loom_synth_set_blocks(p->set) != K)
		return LOOM_EINVAL;
	h = malloc(sizeof(float) * rec * K);
	if (!h)
		return LOOM_ENOMEM;
	memcpy(h, p->heights, sizeof(float) * rec * K);
	for (uint32_t t = 0; t < K; t++) {
		/* N and W: the woven seam's other side (loom__edgefix_target);
		   S, E: t's own */
		float *o = h + (size_t)t * rec;
		loom__edgefix_target(p, t, 0, o + LOOM_EDGE_N(b1, b2));
		loom__edgefix_target(p, t, 2, o + LOOM_EDGE_W(b1, b2));
	}
	q->heights = h;
	*buf = h;
	return LOOM_OK;
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

/* Solve the basis problems: fields of columns of B (n x r, double), in
   groups of FIELD_GROUP columns (each field's arithmetic does not depend
   on the others, so the same values as one solve of all of them) so the
   work space stays small at full rank: 8050 cells x 115 fields of
   doubles would be 7.4 MB at the paper's block size. */
#define FIELD_GROUP 8u
static void fields_of(const lap *L, const double *B, uint32_t n, uint32_t r,
                      int ns, float *f, double *out, double *g, double *v)
{
	size_t cells = (size_t)L->b1 * L->b2;
	for (uint32_t k0 = 0; k0 < r; k0 += FIELD_GROUP) {
		uint32_t c = r - k0 < FIELD_GROUP ? r - k0 : FIELD_GROUP;
		for (uint32_t i = 0; i < n; i++)
			for (uint32_t j = 0; j < c; j++)
				v[(size_t)i * c + j] = B[(size_t)i * r + k0 + j];
		if (ns)
			loom__lap_solve_ns(L, v, NULL, c, out, g);
		else
			loom__lap_solve_we(L, v, NULL, c, out, g);
		for (size_t q = 0; q < cells; q++)
			for (uint32_t j = 0; j < c; j++)
				f[q * r + k0 + j] = (float)out[q * c + j];
	}
}

int loom__edgefix_fields(const lap *L, const double *Bh, uint32_t rh,
                         const double *Bv, uint32_t rv, float *fh, float *fv)
{
	size_t cells = (size_t)L->b1 * L->b2;
	uint32_t nmax = L->nx > L->ny ? L->nx : L->ny;
	uint32_t rows = L->b1 > L->b2 ? L->b1 : L->b2;
	double *out = malloc(sizeof(double) * cells * FIELD_GROUP);
	double *g = malloc(sizeof(double) * 2 * nmax * FIELD_GROUP);
	double *v = malloc(sizeof(double) * rows * FIELD_GROUP);
	if (!out || !g || !v) {
		free(out);
		free(g);
		free(v);
		return LOOM_ENOMEM;
	}
	if (rh)
		fields_of(L, Bh, L->b1, rh, 1, fh, out, g, v);
	if (rv)
		fields_of(L, Bv, L->b2 - 2, rv, 0, fv, out, g, v);
	free(out);
	free(g);
	free(v);
	return LOOM_OK;
}

/* The basis of a side at full rank (n x n, column k of row i at
   B[i*n + k]): the orthonormal sine modes sqrt(2 / (m + 1)) sin(pi k' i' /
   (m + 1)) over the side's interior samples, lowest frequency first, and
   with corners (the N/S sides: samples 0 and n-1 are the block corners,
   which no interior equation reads) one unit vector each, last.  It spans
   every profile as the eigenvectors do, so the fix is the exact solve; but
   the solution of mode k is sin x phi_k(y), which falls below float
   resolution within a few voxels of its edge for all but the lowest
   modes, so a lookup inside the block sums a short prefix of the ranks
   (loom_texture's dz_eval). */
static void exact_basis(uint32_t n, int corners, double *B)
{
	uint32_t m = corners ? n - 2 : n; /* interior samples */
	double c = sqrt(2.0 / (m + 1));
	memset(B, 0, sizeof(double) * n * n);
	for (uint32_t i = 0; i < m; i++)
		for (uint32_t k = 0; k < m; k++)
			B[(size_t)(i + (corners ? 1 : 0)) * n + k] =
			    c * sin(M_PI * (double)(k + 1) * (i + 1) / (m + 1));
	if (corners) {
		B[n - 2] = 1;                       /* row 0, column n-2 */
		B[(size_t)(n - 1) * n + n - 1] = 1; /* row n-1, column n-1 */
	}
}

/* Values of the full-rank fields below 2^-30 to exactly 0, so the tables
   need not store them nor lookups sum them (loom__edgefix_finish).  A
   term dropped is at most 2^-30 times its coefficient: below 1e-6 voxel
   for coefficients up to 1000, and a block's coefficients are projections
   of its edge heights, a few hundred voxels at most. */
static void flush_tail(float *f, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (fabsf(f[i]) < 0x1p-30f)
			f[i] = 0;
}

/* How many leading ranks of the fields of tables t (ef's current layout)
   are not all exactly 0 (-0 counts as 0) along row i (vertical 0: N/S
   fields) or column i (1: W/E). */
static uint8_t nonzero_ranks(const loom_edgefix_tables *t, int vertical, uint32_t i)
{
	uint32_t n = vertical ? t->b2 : t->b1, p = 0;
	uint32_t r = vertical ? t->pre[t->b2 + i] : t->pre[i];
	for (uint32_t j = 0; j < n; j++)
		for (uint32_t k = r; k > p; k--)
			if (loom_edgefix_field(t, vertical, vertical ? i : j, vertical ? j : i, k - 1) != 0) {
				p = k;
				break;
			}
	return (uint8_t)p;
}

/* Shrink an array to n floats (kept as it is if realloc fails). */
static float *shrink(float *f, size_t n)
{
	float *g = realloc(f, sizeof(float) * (n + 1));
	return g ? g : f;
}

/*
 * The prefixes from the fields, then the fields compacted to them, in
 * place: the layouts run in the same order (rows, then cells, then ranks)
 * and no value moves up, so each is written at or below where it is read,
 * after everything below it was read.
 */
void loom__edgefix_finish(loom_edgefix *ef)
{
	uint32_t b1 = ef->b1, b2 = ef->b2;
	uint8_t *np = malloc((size_t)b1 + b2);
	uint32_t *noff = malloc(sizeof(uint32_t) * ((size_t)b1 + b2 + 1));
	loom_edgefix_tables t;
	size_t nh, nv;

	if (!np || !noff) { /* keep the current layout: still exact */
		free(np);
		free(noff);
		return;
	}
	loom_edgefix_get_tables(ef, &t);
	for (uint32_t y = 0; y < b2; y++)
		np[y] = nonzero_ranks(&t, 0, y);
	for (uint32_t x = 0; x < b1; x++)
		np[b2 + x] = nonzero_ranks(&t, 1, x);
	{ /* the new offsets (set_offsets on a copy) */
		loom_edgefix tmp = *ef;
		tmp.pre = np;
		tmp.off = noff;
		set_offsets(&tmp);
	}
	for (uint32_t y = 0; y < b2; y++)
		for (uint32_t x = 0; x < b1; x++)
			for (uint32_t k = 0; k < np[y]; k++)
				ef->field_h[noff[y] + (size_t)x * np[y] + k] =
				    ef->field_h[ef->off[y] + (size_t)x * ef->pre[y] + k];
	for (uint32_t y = 0; y < b2; y++)
		for (uint32_t x = 0; x < b1; x++)
			for (uint32_t k = 0; k < np[b2 + x]; k++)
				ef->field_v[(size_t)y * noff[b2 + b1] + noff[b2 + x] + k] =
				    ef->field_v[(size_t)y * ef->off[b2 + b1] + ef->off[b2 + x] + k];
	free(ef->pre);
	free(ef->off);
	ef->pre = np;
	ef->off = noff;
	field_sizes(ef, &nh, &nv);
	ef->field_h = shrink(ef->field_h, nh);
	ef->field_v = shrink(ef->field_v, nv);
}

LOOM_API int loom_edgefix_build(const loom_edge_profiles *p, uint32_t rank,
                                loom_edgefix **out, loom_diag *diag)
{
	uint32_t b1, b2, K, nv, rh, rv, nmax, stride;
	double *G = NULL, *mh = NULL, *mv = NULL, *Bh = NULL, *Bv = NULL;
	loom_edgefix *ef = NULL;
	loom_edge_profiles q;
	float *tbuf = NULL;
	lap L;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "edge fix: NULL output");
	*out = NULL;
	rc = loom__edgefix_check(p, diag);
	if (rc)
		return rc;
	if (rank > LOOM_EDGEFIX_MAX_RANK)
		return loom__fail(diag, LOOM_ERANGE, "edge fix: rank %u, expected 0..%u",
		                  rank, LOOM_EDGEFIX_MAX_RANK);
	rc = loom__edgefix_targets(p, &q, &tbuf);
	if (rc)
		return loom__fail(diag, rc, rc == LOOM_ENOMEM ? "edge fix: out of memory" :
		                  "edge fix: the set has %u blocks, the profiles %u",
		                  loom_synth_set_blocks(p->set), p->n_blocks);
	p = &q;
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
	if (loom__lap_init(&L, b1, b2) != LOOM_OK) {
		free(tbuf);
		return loom__fail(diag, LOOM_ENOMEM, "edge fix: out of memory");
	}
	ef = ef_alloc(b1, b2, K, rh, rv);
	G = malloc(sizeof(double) * ((size_t)nmax * nmax + nmax));
	mh = malloc(sizeof(double) * b1);
	mv = malloc(sizeof(double) * nv);
	Bh = malloc(sizeof(double) * ((size_t)b1 * rh + 1));
	Bv = malloc(sizeof(double) * ((size_t)nv * rv + 1));
	rc = LOOM_ENOMEM;
	if (!ef || !G || !mh || !mv || !Bh || !Bv)
		goto done;
	/* a basis of every profile (rank at the side's dimension): the sine
	   modes, whose solutions decay fastest to zero (below) */
	gram(p, 0, 1, 0, b1, mh, G);
	if (rh == b1 && b1 >= 3)
		exact_basis(b1, 1, Bh);
	else if (rh && loom__top_eigen(G, b1, rh, Bh))
		goto done;
	gram(p, 2, 3, 1, nv, mv, G);
	if (rv == nv && nv >= 1)
		exact_basis(nv, 0, Bv);
	else if (rv && loom__top_eigen(G, nv, rv, Bv))
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
	if (loom__edgefix_fields(&L, Bh, rh, Bv, rv, ef->field_h, ef->field_v))
		goto done;
	if (rh == b1 && b1 >= 3)
		flush_tail(ef->field_h, (size_t)b1 * b2 * rh);
	if (rv == nv && nv >= 1)
		flush_tail(ef->field_v, (size_t)b1 * b2 * rv);
	loom__edgefix_finish(ef);
	rc = LOOM_OK;
done:
	loom__lap_free(&L);
	free(tbuf);
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
	size_t nh, nv;
	if (!ef)
		return 0;
	field_sizes(ef, &nh, &nv);
	return sizeof *ef + sizeof(float) * ((size_t)ef->K * (2 * ef->rh + 2 * ef->rv) +
	                                     nh + nv + ef->b1 * ef->rh +
	                                     (ef->b2 - 2) * ef->rv + ef->b1 + ef->b2 - 2) +
	       ef->b1 + ef->b2 + sizeof(uint32_t) * (ef->b1 + ef->b2 + 1); /* pre, off */
}

/* ---- evaluation ---------------------------------------------------------- */





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

void loom__edgefix_side(const loom_edgefix *ef, const loom_synth_nbhd *nb, int side,
                        float *out)
{
	avec a;
	uint32_t n = side < 2 ? ef->b1 : ef->b2;
	ef_avec(ef, nb, &a);
	for (uint32_t i = 0; i < n; i++) {
		uint32_t x = side < 2 ? i : side == 2 ? 0 : ef->b1 - 1;
		uint32_t y = side >= 2 ? i : side == 0 ? 0 : ef->b2 - 1;
		out[i] = ef_eval(ef, &a, x, y);
	}
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
	t->pre = ef->pre;
	t->off = ef->off;
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
	size_t cells, nh, nv;
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
	nh = cells * t->rank_h;
	nv = cells * t->rank_v;
	if (t->pre) { /* compact: the prefixes first (each at most its rank) */
		for (uint32_t i = 0; i < t->b1 + t->b2; i++)
			if (t->pre[i] > (i < t->b2 ? t->rank_h : t->rank_v)) {
				uint32_t r = i < t->b2 ? t->rank_h : t->rank_v;
				loom_edgefix_free(ef);
				return loom__fail(diag, LOOM_EINVAL, "edge fix tables: %s %u's "
				                  "prefix %u above the rank %u", i < t->b2 ?
				                  "row" : "column", i < t->b2 ? i : i - t->b2,
				                  t->pre[i], r);
			}
		memcpy(ef->pre, t->pre, (size_t)t->b1 + t->b2);
		set_offsets(ef);
		field_sizes(ef, &nh, &nv);
	}
	memcpy(a[0], t->coef, sizeof(float) * t->n_blocks * (2 * (size_t)t->rank_h + 2 * t->rank_v));
	memcpy(a[1], t->field_h, sizeof(float) * nh);
	memcpy(a[2], t->field_v, sizeof(float) * nv);
	memcpy(a[3], t->basis_h, sizeof(float) * t->b1 * t->rank_h);
	memcpy(a[4], t->basis_v, sizeof(float) * (t->b2 - 2) * t->rank_v);
	memcpy(a[5], t->mean_h, sizeof(float) * t->b1);
	memcpy(a[6], t->mean_v, sizeof(float) * (t->b2 - 2));
	loom__edgefix_finish(ef);
	*out = ef;
	return LOOM_OK;
}
