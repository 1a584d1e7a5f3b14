/*
 * engine/design/draft.c - the draft behind a drawdown (loom_draft_from_design).
 *
 * A design's drawdown W is woven by a threading and a liftplan when ends
 * with the same column of W share a shaft: shaft s lifts on pick i iff
 * W(i, j) = 1 for the ends j on s.  So the shafts are the distinct columns
 * of W (found by hashing each column, then comparing the columns whose
 * hashes meet), and the liftplan row of pick i is W(i, j_s) for the first
 * end j_s of each shaft.  Likewise the treadles are the distinct liftplan
 * rows, and the tie-up column of a treadle is that row.  Hash tables are
 * open-addressed, twice the entries, so memory is O(rows + cols) beside the
 * liftplan (rows x shafts bytes).
 */
#include "core/internal.h"
#include "loom/design.h"

#include <stdlib.h>
#include <string.h>

static uint64_t mix64(uint64_t h)
{
	h ^= h >> 33;
	h *= 0xff51afd7ed558ccdull;
	h ^= h >> 33;
	h *= 0xc4ceb9fe1a85ec53ull;
	return h ^ (h >> 33);
}

typedef struct uniq {
	uint32_t *slot;   /* entry index + 1, 0 = empty */
	size_t mask;
} uniq;

static int uniq_init(uniq *u, size_t n)
{
	size_t cap = 16;
	while (cap < 2 * n)
		cap *= 2;
	u->slot = calloc(cap, sizeof *u->slot);
	u->mask = cap - 1;
	return u->slot != NULL;
}

/* Column j of W as a hash. */
static uint64_t col_hash(const loom_design *d, uint32_t j)
{
	uint64_t h = 0x9e3779b97f4a7c15ull;
	for (uint32_t i = 0; i < d->rows; i++)
		h = mix64(h ^ ((uint64_t)d->weave[(size_t)i * d->cols + j] << (i & 31)) ^ i);
	return h;
}

static int col_eq(const loom_design *d, uint32_t a, uint32_t b)
{
	for (uint32_t i = 0; i < d->rows; i++)
		if (d->weave[(size_t)i * d->cols + a] != d->weave[(size_t)i * d->cols + b])
			return 0;
	return 1;
}

static uint64_t row_hash(const uint8_t *r, uint32_t n)
{
	uint64_t h = 0x51ed270b27e3b1f7ull ^ n;
	for (uint32_t k = 0; k < n; k++)
		h = mix64(h ^ ((uint64_t)r[k] << (k & 31)) ^ ((uint64_t)k << 40));
	return h;
}

LOOM_API void loom_draft_free(loom_draft *dr)
{
	if (!dr)
		return;
	free(dr->threading);
	free(dr->liftplan);
	free(dr->tieup);
	free(dr->treadling);
	free(dr);
}

LOOM_API int loom_draft_from_design(const loom_design *d, uint32_t max_treadles,
                                    loom_draft **out, loom_diag *diag)
{
	loom_draft *dr;
	uniq u = {NULL, 0};
	uint32_t *first = NULL; /* first end of each shaft / first pick of a treadle */
	int rc = LOOM_ENOMEM;

	if (out)
		*out = NULL;
	if (!d || !out || !d->weave || d->rows == 0 || d->cols == 0)
		return loom__fail(diag, LOOM_EINVAL, "loom_draft_from_design: bad argument");
	dr = calloc(1, sizeof *dr);
	if (!dr)
		return loom__fail(diag, LOOM_ENOMEM, "out of memory");
	dr->rows = d->rows;
	dr->cols = d->cols;
	dr->threading = malloc((size_t)d->cols * sizeof *dr->threading);
	first = malloc(((size_t)LOOM_DRAFT_MAX_SHAFTS + 1) * sizeof *first);
	if (!dr->threading || !first || !uniq_init(&u, d->cols))
		goto fail;
	/* shafts: distinct columns */
	for (uint32_t j = 0; j < d->cols; j++) {
		size_t s = (size_t)col_hash(d, j) & u.mask;
		for (;;) {
			uint32_t e = u.slot[s];
			if (e == 0) {
				if (dr->shafts == LOOM_DRAFT_MAX_SHAFTS) {
					rc = loom__fail(diag, LOOM_EUNSUPPORTED, "the design has more than "
					                "%u distinct ends (a jacquard design): no loom "
					                "draft to draw", LOOM_DRAFT_MAX_SHAFTS);
					goto out;
				}
				first[dr->shafts] = j;
				u.slot[s] = dr->shafts + 1;
				dr->threading[j] = dr->shafts++;
				break;
			}
			if (col_eq(d, first[e - 1], j)) {
				dr->threading[j] = e - 1;
				break;
			}
			s = (s + 1) & u.mask;
		}
	}
	free(u.slot);
	u.slot = NULL;
	dr->liftplan = malloc((size_t)d->rows * dr->shafts);
	if (!dr->liftplan)
		goto fail;
	for (uint32_t i = 0; i < d->rows; i++)
		for (uint32_t s = 0; s < dr->shafts; s++)
			dr->liftplan[(size_t)i * dr->shafts + s] =
				d->weave[(size_t)i * d->cols + first[s]];
	/* treadles: distinct liftplan rows, if few enough */
	if (max_treadles > 0) {
		uint32_t *tfirst = malloc(((size_t)max_treadles + 1) * sizeof *tfirst);
		uint32_t nt = 0;
		int ok = 1;
		dr->treadling = malloc((size_t)d->rows * sizeof *dr->treadling);
		if (!tfirst || !dr->treadling || !uniq_init(&u, d->rows)) {
			free(tfirst);
			goto fail;
		}
		for (uint32_t i = 0; i < d->rows && ok; i++) {
			const uint8_t *r = dr->liftplan + (size_t)i * dr->shafts;
			size_t s = (size_t)row_hash(r, dr->shafts) & u.mask;
			for (;;) {
				uint32_t e = u.slot[s];
				if (e == 0) {
					if (nt == max_treadles) {
						ok = 0;
						break;
					}
					tfirst[nt] = i;
					u.slot[s] = nt + 1;
					dr->treadling[i] = nt++;
					break;
				}
				if (!memcmp(dr->liftplan + (size_t)tfirst[e - 1] * dr->shafts, r,
				            dr->shafts)) {
					dr->treadling[i] = e - 1;
					break;
				}
				s = (s + 1) & u.mask;
			}
		}
		if (ok) {
			dr->treadles = nt;
			dr->tieup = malloc((size_t)dr->shafts * nt);
			if (!dr->tieup) {
				free(tfirst);
				goto fail;
			}
			for (uint32_t s = 0; s < dr->shafts; s++)
				for (uint32_t t = 0; t < nt; t++)
					dr->tieup[(size_t)s * nt + t] =
						dr->liftplan[(size_t)tfirst[t] * dr->shafts + s];
		} else {
			free(dr->treadling);
			dr->treadling = NULL;
		}
		free(tfirst);
	}
	free(u.slot);
	free(first);
	*out = dr;
	return LOOM_OK;
fail:
	rc = loom__fail(diag, LOOM_ENOMEM, "out of memory for the draft");
out:
	free(u.slot);
	free(first);
	loom_draft_free(dr);
	return rc;
}
