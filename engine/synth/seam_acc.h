/*
 * engine/synth/seam_acc.h - the seam metric's running sums, shared by the
 * edge fix's metric (seam.c: loom_edgefix_seam) and the fabric's, which
 * measures the offsets lookups apply (fabric.c: fabric_seam).
 */
#ifndef LOOM_SEAM_ACC_H
#define LOOM_SEAM_ACC_H

#include "loom/synth.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct loom__seam_acc {
	double sum_b, max_b, sum_a, max_a, sum_cb, sum_ca;
	uint64_t n, nc; /* samples; corner samples (the E edge's y = 0, b2 - 1) */
} loom__seam_acc;

/* One seam sample: its height jump before and after the fix. */
static inline void loom__seam_add(loom__seam_acc *s, double before,
                                  double after, int corner)
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
		s->sum_ca += after;
		s->nc++;
	}
}

/* The metrics of acc, with internal_step as the baseline of the ratios. */
static inline void loom__seam_finish(const loom__seam_acc *acc,
                                     double internal_step,
                                     loom_seam_metrics *out)
{
	memset(out, 0, sizeof *out);
	out->samples = acc->n;
	out->before_mean = acc->n ? acc->sum_b / (double)acc->n : 0;
	out->after_mean = acc->n ? acc->sum_a / (double)acc->n : 0;
	out->before_max = acc->max_b;
	out->after_max = acc->max_a;
	out->corner_samples = acc->nc;
	out->corner_before_mean = acc->nc ? acc->sum_cb / (double)acc->nc : 0;
	out->corner_after_mean = acc->nc ? acc->sum_ca / (double)acc->nc : 0;
	out->internal_step = internal_step;
	if (internal_step > 0) {
		out->before_ratio = out->before_mean / internal_step;
		out->after_ratio = out->after_mean / internal_step;
	}
}

#endif
