/*
 * engine/synth/reweave.c - painting another weave into a fabric
 * (loom__fabric_reweave, fabric_internal.h; docs/fabric.md "Painted
 * weaves").
 *
 * The painted crossings get the new weave's bits; they and a band of
 * crossings around them are assigned again with the synthesis rules
 * (correctness, then consistency with the bits around each crossing, then
 * continuity with the neighbours already fixed), while the rest of the
 * bolt keeps its sources.  The result is a patch: a dense table over the
 * widened bounding rectangle, 3 bytes per crossing, chained onto a copy of
 * the fabric struct.  The edge fix needs nothing more: its offsets are a
 * function of the five sources of a neighbourhood (loom__fabric_nbhd reads
 * the patch), so it runs across the patch's border like anywhere else.
 */
#include "fabric_internal.h"

#include <stdlib.h>
#include <string.h>

typedef struct rw {
	const loom_fabric *f;         /* the fabric painted over */
	int64_t I0, J0;               /* patch origin (band included) */
	uint32_t R, C;                /* patch size */
	uint8_t *bit;                 /* R*C: the new warp-over bits */
	uint8_t *in;                  /* R*C: 1 = assigned again */
	uint16_t *src;                /* R*C: new sources (NONE until set) */
	const uint8_t *tag;           /* per exemplar: material pair tag, when
	                                 the database has two or more pairs or
	                                 a fibre is painted; NULL otherwise
	                                 (engine/synth/material.c) */
	const uint8_t *painted;       /* R*C: 1 = painted (not the band) */
	int kind, fibre;              /* painted fibre: the yarn kind (0 any)
	                                 and its material; fibre 0 = keep */
} rw;

/* The pair a crossing of old pair `pair` has after painting. */
static uint8_t new_pair(const rw *w, uint8_t pair)
{
	unsigned wm = pair / LOOM_FIBRE_COUNT_, em = pair % LOOM_FIBRE_COUNT_;

	if (w->kind != LOOM_YARN_WEFT)
		wm = (unsigned)w->fibre;
	if (w->kind != LOOM_YARN_WARP)
		em = (unsigned)w->fibre;
	return (uint8_t)(wm * LOOM_FIBRE_COUNT_ + em);
}

/* Warp-over bit of (I, J) after painting. */
static unsigned bit_at(const rw *w, int64_t I, int64_t J)
{
	uint64_t di = (uint64_t)I - (uint64_t)w->I0, dj = (uint64_t)J - (uint64_t)w->J0;
	loom__fabric_xing x;

	if (di < w->R && dj < w->C)
		return w->bit[di * w->C + dj];
	loom__fabric_crossing(w->f, I, J, &x);
	return x.warp_over;
}

/* Source of (I, J) as far as known: the patch's choice, LOOM_SYNTH_NONE
   for a crossing of the patch not assigned yet, else the fabric's. */
static uint16_t src_at(const rw *w, int64_t I, int64_t J)
{
	uint64_t di = (uint64_t)I - (uint64_t)w->I0, dj = (uint64_t)J - (uint64_t)w->J0;

	if (di < w->R && dj < w->C && w->in[di * w->C + dj])
		return w->src[di * w->C + dj];
	return loom__fabric_src(w->f, I, J);
}

static int assign_one(rw *w, uint32_t r, uint32_t c, uint64_t key)
{
	int64_t I = w->I0 + r, J = w->J0 + c;
	unsigned code = bit_at(w, I, J) | bit_at(w, I - 1, J) << 1 |
	                bit_at(w, I + 1, J) << 2 | bit_at(w, I, J - 1) << 3 |
	                bit_at(w, I, J + 1) << 4;
	uint16_t nb[4] = {src_at(w, I - 1, J), src_at(w, I + 1, J),
	                  src_at(w, I, J - 1), src_at(w, I, J + 1)};
	const uint16_t *list;
	uint32_t n, matches, best = LOOM_SYNTH_NONE;
	int best_score = -1;
	uint64_t best_h = 0;
	int rc;

	if (w->tag) {
		/* keep the crossing's material pair: the blocks of the exemplars
		   with the tag of its old source, most matching bits first */
		loom_synth_block ob;
		uint32_t K = loom_synth_set_blocks(w->f->set);
		uint8_t pair;
		int best_m = -1;
		loom_synth_block_info(w->f->set, loom__fabric_src(w->f, I, J), &ob);
		pair = w->tag[ob.exemplar];
		if (w->fibre && w->painted[(size_t)r * w->C + c])
			pair = new_pair(w, pair);
		for (uint32_t t = 0; t < K; t++) {
			loom_synth_block b;
			int m, score;
			uint64_t h;
			loom_synth_block_info(w->f->set, t, &b);
			if (w->tag[b.exemplar] != pair || (b.code & 1u) != (code & 1u))
				continue;
			m = __builtin_popcount(~(b.code ^ code) & 0x1eu);
			score = (nb[0] != LOOM_SYNTH_NONE && b.up == nb[0]) +
			        (nb[1] != LOOM_SYNTH_NONE && b.down == nb[1]) +
			        (nb[2] != LOOM_SYNTH_NONE && b.left == nb[2]) +
			        (nb[3] != LOOM_SYNTH_NONE && b.right == nb[3]);
			h = loom_synth_mix(key ^ loom_synth_mix((uint64_t)I * 0x9e3779b97f4a7c15ull ^
			                                        (uint64_t)J) ^ t);
			if (m > best_m || (m == best_m && score > best_score) ||
			    (m == best_m && score == best_score && h < best_h)) {
				best_m = m;
				best_score = score;
				best_h = h;
				best = t;
			}
		}
		if (best == LOOM_SYNTH_NONE)
			return LOOM_EUNSUPPORTED;
		w->src[(size_t)r * w->C + c] = (uint16_t)best;
		return LOOM_OK;
	}
	if ((rc = loom_synth_candidates(w->f->set, code, 0, &list, &n, &matches)) != LOOM_OK)
		return rc;
	if (n == 0)
		return LOOM_EUNSUPPORTED;
	for (uint32_t k = 0; k < n; k++) {
		loom_synth_block b;
		int score = 0;
		uint64_t h;
		if (loom_synth_block_info(w->f->set, list[k], &b) != LOOM_OK)
			return LOOM_EINVAL;
		/* continuity: t's contiguous neighbour is the one already there */
		score += nb[0] != LOOM_SYNTH_NONE && b.up == nb[0];
		score += nb[1] != LOOM_SYNTH_NONE && b.down == nb[1];
		score += nb[2] != LOOM_SYNTH_NONE && b.left == nb[2];
		score += nb[3] != LOOM_SYNTH_NONE && b.right == nb[3];
		h = loom_synth_mix(key ^ loom_synth_mix((uint64_t)I * 0x9e3779b97f4a7c15ull ^
		                                        (uint64_t)J) ^ list[k]);
		if (score > best_score || (score == best_score && h < best_h)) {
			best_score = score;
			best_h = h;
			best = list[k];
		}
	}
	w->src[(size_t)r * w->C + c] = (uint16_t)best;
	return LOOM_OK;
}

static int check_pairs(const rw *w, const uint8_t *tag, uint32_t n_ex,
                       loom_diag *diag)
{
	int have[LOOM_FIBRE_COUNT_ * LOOM_FIBRE_COUNT_];
	char list[256];

	memset(have, 0, sizeof have);
	for (uint32_t u = 0; u < n_ex; u++)
		have[tag[u]] = 1;
	loom__fabric_pair_list(tag, n_ex, list, sizeof list);
	for (uint32_t r = 0; r < w->R; r++)
		for (uint32_t c = 0; c < w->C; c++) {
			int64_t I = w->I0 + r, J = w->J0 + c;
			loom_synth_block ob;
			uint8_t old, np;
			if (!w->painted[(size_t)r * w->C + c])
				continue;
			loom_synth_block_info(w->f->set, loom__fabric_src(w->f, I, J), &ob);
			old = tag[ob.exemplar];
			if (!old)
				return loom__fail(diag, LOOM_EMISMATCH, "painted fibre: the "
				                  "fabric's database records no material pairs "
				                  "(its exemplars are not tagged)");
			np = new_pair(w, old);
			if (!have[np])
				return loom__fail(diag, LOOM_EMISMATCH, "painted fibre: crossing "
				                  "(%lld, %lld) would have the (warp, weft) pair "
				                  "%s/%s, but the database has exemplars of the "
				                  "pairs %s only", (long long)I, (long long)J,
				                  loom_fibre_name(np / LOOM_FIBRE_COUNT_),
				                  loom_fibre_name(np % LOOM_FIBRE_COUNT_), list);
		}
	return LOOM_OK;
}

int loom__fabric_reweave(loom_fabric **fp, int64_t I0, int64_t J0,
                         uint32_t rows, uint32_t cols, const uint8_t *want,
                         uint32_t band, int kind, int fibre, loom_diag *diag)
{
	rw w;
	loom_fabric *f, *g = NULL;
	loom__fabric_patch *p = NULL;
	uint8_t *tmp = NULL, *tag = NULL, *painted = NULL;
	size_t n;
	uint64_t key;
	uint32_t n_pairs = 0;
	int rc = LOOM_ENOMEM;

	if (!fp || !*fp || !want || !rows || !cols)
		return loom__fail(diag, LOOM_EINVAL, "reweave: NULL argument or empty area");
	f = *fp;
	if (!f->attached)
		return loom__fail(diag, LOOM_EUNUSABLE, "reweave: the fabric is detached");
	if (band > LOOM__FABRIC_BAND_MAX)
		return loom__fail(diag, LOOM_EINVAL, "reweave: band %u crossings, at most %u",
		                  band, LOOM__FABRIC_BAND_MAX);
	if (fibre < 0 || fibre >= LOOM_FIBRE_COUNT_ || kind < 0 || kind > LOOM_YARN_WEFT)
		return loom__fail(diag, LOOM_EINVAL, "reweave: fibre %d or kind %d out of "
		                  "range", fibre, kind);
	if ((uint64_t)rows + 2 * band > LOOM__FABRIC_PATCH_MAX ||
	    (uint64_t)cols + 2 * band > LOOM__FABRIC_PATCH_MAX ||
	    ((uint64_t)rows + 2 * band) * ((uint64_t)cols + 2 * band) > LOOM__FABRIC_PATCH_MAX)
		return loom__fail(diag, LOOM_ERANGE, "painted weave: %u x %u crossings with "
		                  "its band of %u; at most %u crossings", rows, cols, band,
		                  LOOM__FABRIC_PATCH_MAX);
	if (I0 < -(INT64_C(1) << 60) || I0 > (INT64_C(1) << 60) ||
	    J0 < -(INT64_C(1) << 60) || J0 > (INT64_C(1) << 60))
		return loom__fail(diag, LOOM_ERANGE, "painted weave: crossing (%lld, %lld) "
		                  "too far out", (long long)I0, (long long)J0);
	memset(&w, 0, sizeof w);
	w.f = f;
	w.I0 = I0 - band;
	w.J0 = J0 - band;
	w.R = rows + 2 * band;
	w.C = cols + 2 * band;
	n = (size_t)w.R * w.C;
	w.bit = malloc(n);
	w.in = calloc(n, 1);
	w.src = malloc(n * sizeof *w.src);
	tmp = calloc(n, 1);
	painted = calloc(n, 1);
	p = calloc(1, sizeof *p);
	g = malloc(sizeof *g);
	tag = malloc(f->n_exemplars ? f->n_exemplars : 1);
	if (!w.bit || !w.in || !w.src || !tmp || !painted || !p || !g || !tag)
		goto fail;
	if ((rc = loom__fabric_db_pairs(f->db, f->n_exemplars, tag, &n_pairs)) != LOOM_OK) {
		rc = loom__fail(diag, rc, "painted weave: database exemplars: %s",
		                loom_strerror(rc));
		goto fail_quiet;
	}
	w.tag = n_pairs >= 2 || fibre ? tag : NULL;
	w.painted = painted;
	w.kind = kind;
	w.fibre = fibre;
	/* the bits after painting, and the painted crossings */
	for (uint32_t r = 0; r < w.R; r++)
		for (uint32_t c = 0; c < w.C; c++) {
			size_t k = (size_t)r * w.C + c;
			uint8_t v = 0;
			loom__fabric_xing x;
			if (r >= band && r < band + rows && c >= band && c < band + cols)
				v = want[(size_t)(r - band) * cols + (c - band)];
			if (v > 2) {
				rc = loom__fail(diag, LOOM_EINVAL, "reweave: want values are 0, 1, 2");
				goto fail_quiet;
			}
			if (v) {
				w.bit[k] = (uint8_t)(v - 1);
				tmp[k] = 1;
				painted[k] = 1;
			} else {
				loom__fabric_crossing(f, w.I0 + r, w.J0 + c, &x);
				w.bit[k] = x.warp_over;
			}
			w.src[k] = LOOM_SYNTH_NONE;
		}
	/* a painted fibre: every painted crossing's new pair must have
	   exemplars in the database */
	if (fibre && (rc = check_pairs(&w, tag, f->n_exemplars, diag)) != LOOM_OK)
		goto fail_quiet;
	/* widen by the band (Chebyshev): along rows, then along columns */
	for (uint32_t r = 0; r < w.R; r++)
		for (uint32_t c = 0; c < w.C; c++) {
			uint32_t c0 = c >= band ? c - band : 0, c1 = c + band < w.C ? c + band : w.C - 1;
			for (uint32_t q = c0; q <= c1; q++)
				if (tmp[(size_t)r * w.C + q]) {
					w.in[(size_t)r * w.C + c] = 1;
					break;
				}
		}
	memcpy(tmp, w.in, n);
	for (uint32_t r = 0; r < w.R; r++)
		for (uint32_t c = 0; c < w.C; c++) {
			uint32_t r0 = r >= band ? r - band : 0, r1 = r + band < w.R ? r + band : w.R - 1;
			w.in[(size_t)r * w.C + c] = 0;
			for (uint32_t q = r0; q <= r1; q++)
				if (tmp[(size_t)q * w.C + c]) {
					w.in[(size_t)r * w.C + c] = 1;
					break;
				}
		}
	/* assign again, in raster order */
	key = loom_synth_mix(f->params.seed ^ 0x7061696e74ull); /* "paint" */
	for (const loom__fabric_patch *q = f->patch; q; q = q->prev)
		key = loom_synth_mix(key);
	for (uint32_t r = 0; r < w.R; r++)
		for (uint32_t c = 0; c < w.C; c++)
			if (w.in[(size_t)r * w.C + c] && (rc = assign_one(&w, r, c, key)) != LOOM_OK) {
				rc = loom__fail(diag, rc, "painted weave: no exemplar block for "
				                "crossing (%lld, %lld)", (long long)(w.I0 + r),
				                (long long)(w.J0 + c));
				goto fail_quiet;
			}
	/* the unassigned rest of the rectangle keeps the fabric's bits */
	for (size_t k = 0; k < n; k++)
		if (!w.in[k])
			w.src[k] = LOOM_SYNTH_NONE;
	free(tmp);
	free(tag);
	free(painted);
	free(w.in);
	p->prev = f->patch;
	p->I0 = w.I0;
	p->J0 = w.J0;
	p->rows = w.R;
	p->cols = w.C;
	p->src = w.src;
	p->weave = w.bit;
	*g = *f;
	g->patch = p;
	g->parent = f;
	*fp = g;
	return LOOM_OK;
fail:
	rc = loom__fail(diag, LOOM_ENOMEM, "painted weave: out of memory");
fail_quiet:
	free(w.bit);
	free(w.in);
	free(w.src);
	free(tmp);
	free(tag);
	free(painted);
	free(p);
	free(g);
	return rc;
}
