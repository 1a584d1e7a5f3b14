/*
 * tests/unit/raise_block.h - a block whose whole border the edge fix
 * raises, for the tests of the offset bounds (test_texture,
 * test_render_grid).
 */
#ifndef LOOM_TEST_RAISE_BLOCK_H
#define LOOM_TEST_RAISE_BLOCK_H

#include "loom.h"

#include <stdint.h>

/* Lower block t's four edge profiles by lam times the projection of a
   constant onto the bases (its coefficients in tb), so that a crossing
   copying t has its whole border raised by about lam / 2. */
static inline void lower_block(const loom_edgefix *ef, uint32_t t, float lam)
{
	loom_edgefix_tables tb;
	float *c, vh = 0, vv = 0;
	if (loom_edgefix_get_tables(ef, &tb) != LOOM_OK)
		return;
	/* the tables are the edge fix's own heap copies: edited in place, as
	   a database whose block t lay lower in z would have them.  Only the
	   first basis vectors (the profiles' mean level: one sign along the
	   edge, checked by the caller), so that the texture's interval bound
	   is nearly as tight as the field's own range */
	c = (float *)(uintptr_t)(tb.coef + (size_t)t * 2 * (tb.rank_h + tb.rank_v));
	for (uint32_t x = 0; x < tb.b1; x++)
		vh += tb.basis_h[x * tb.rank_h];
	for (uint32_t y = 0; y + 2 < tb.b2; y++)
		vv += tb.basis_v[y * tb.rank_v];
	c[0] -= lam * vh;
	c[tb.rank_h] -= lam * vh;
	c[2 * tb.rank_h] -= lam * vv;
	c[2 * tb.rank_h + tb.rank_v] -= lam * vv;
}

#endif
