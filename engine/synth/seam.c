/*
 * engine/synth/seam.c - the seam metric: height jumps across block edges
 * before and after the edge fix (loom_edgefix_seam, _seam_block).
 */
#include "edgefix_impl.h"

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
