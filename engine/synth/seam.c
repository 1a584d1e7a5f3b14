/*
 * engine/synth/seam.c - the seam metric: height jumps across block edges
 * before and after the edge fix (loom_edgefix_seam, _seam_block).
 */
#include "edgefix_impl.h"
#include "seam_acc.h"

/* ---- seam metric --------------------------------------------------------- */

/* Add the S and E edges of block (I, J) to acc (if not NULL); out (if not
   NULL) receives their own mean jumps as loom_edgefix_seam_block. */
static void seam_one(const loom_edgefix *ef, const loom_edge_profiles *p,
                     const loom_synth_lookup *lk, int64_t I, int64_t J,
                     loom__seam_acc *acc, double out[4])
{
	loom_synth_nbhd a, below, right;
	avec va, vb, vr;
	uint32_t b1 = p->b1, b2 = p->b2;
	loom__seam_acc local[2];

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
		loom__seam_add(&local[0], h0 - h1, (h0 + d0) - (h1 + d1), 0);
		if (acc)
			loom__seam_add(acc, h0 - h1, (h0 + d0) - (h1 + d1), 0);
	}
	for (uint32_t y = 0; y < b2; y++) {
		double h0 = prof(p, a.self, 3)[y], h1 = prof(p, right.self, 2)[y];
		double d0 = ef_eval(ef, &va, b1 - 1, y), d1 = ef_eval(ef, &vr, 0, y);
		int corner = y == 0 || y == b2 - 1;
		loom__seam_add(&local[1], h0 - h1, (h0 + d0) - (h1 + d1), corner);
		if (acc)
			loom__seam_add(acc, h0 - h1, (h0 + d0) - (h1 + d1), corner);
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
	if (!ef || !lk || loom__edgefix_check(p, NULL) != LOOM_OK)
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
	loom__seam_acc acc;

	if (!out || seam_args(ef, p, lk))
		return LOOM_EINVAL;
	memset(&acc, 0, sizeof acc);
	for (uint64_t a = 0; a < h; a++)
		for (uint64_t b = 0; b < w; b++)
			seam_one(ef, p, lk, i0 + (int64_t)a, j0 + (int64_t)b, &acc, NULL);
	loom__seam_finish(&acc, internal_step, out);
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
