/*
 * tests/unit/raise_block.h - a block whose whole border the edge fix
 * raises, for the tests of the offset bounds (test_texture,
 * test_render_grid).
 */
#ifndef LOOM_TEST_RAISE_BLOCK_H
#define LOOM_TEST_RAISE_BLOCK_H

#include "loom.h"

#include <stdint.h>

/* Lower source block t's four edge profiles in the edge fix's tables by
   lam times their first basis vectors (the profiles' mean level, one sign
   along an edge), as a database whose block t lay lower in z would have
   them: a crossing copying t then has its border raised by about lam / 2
   (the callers check the offsets they get).  The tables are the edge
   fix's own heap copies, edited in place.  rec: NULL, or block t's edge
   record (LOOM_EDGE_RECORD floats) whose four corner samples, which the
   corner term reads, are lowered by as much as the N and S profiles are
   there. */
static inline void lower_block(const loom_edgefix *ef, uint32_t t, float lam, float *rec)
{
	loom_edgefix_tables tb;
	float *c, vh = 0, vv = 0;
	if (loom_edgefix_get_tables(ef, &tb) != LOOM_OK)
		return;
	c = (float *)(uintptr_t)(tb.coef + (size_t)t * 2 * (tb.rank_h + tb.rank_v));
	for (uint32_t x = 0; x < tb.b1; x++)
		vh += tb.basis_h[x * tb.rank_h];
	for (uint32_t y = 0; y + 2 < tb.b2; y++)
		vv += tb.basis_v[y * tb.rank_v];
	c[0] -= lam * vh;
	c[tb.rank_h] -= lam * vh;
	c[2 * tb.rank_h] -= lam * vv;
	c[2 * tb.rank_h + tb.rank_v] -= lam * vv;
	for (uint32_t x = 0; rec && x < tb.b1; x += tb.b1 - 1) {
		float drop = lam * vh * tb.basis_h[x * tb.rank_h];
		rec[LOOM_EDGE_N(tb.b1, tb.b2) + x] -= drop;
		rec[LOOM_EDGE_S(tb.b1, tb.b2) + x] -= drop;
	}
}

#endif
