/*
 * engine/synth/material.c - synthesis restricted to each crossing's
 * material pair (docs/exemplars.md, "Materials per yarn type").
 *
 * A database woven with several (warp, weft) material pairs tags each
 * exemplar with its pair.  A crossing of the design has exactly one pair
 * (the materials of its warp's and its weft's yarn types, unset ones taking
 * the side's default), and may copy only blocks of exemplars with that tag.
 * For every pair the design uses, the assignment runs over the whole design
 * with an exemplar set of that pair's exemplars only (same algorithm, seed
 * and options), and the crossings of the pair take its result, mapped to
 * the global block indices of the full set.  Work memory: one base of the
 * design (2 bytes per crossing) and one pair index per crossing, besides
 * what loom_synth_assign needs.
 */
#include "fabric_internal.h"

#include <stdlib.h>
#include <string.h>

/* Material of yarn type t, unset -> def -> cotton. */
static int material(const loom_design *d, uint8_t t, uint8_t def)
{
	int m = t < d->n_types ? d->types[t].fibre : 0;
	if (m == LOOM_FIBRE_DEFAULT)
		m = def;
	return m == LOOM_FIBRE_DEFAULT ? LOOM_FIBRE_COTTON : m;
}

int loom__fabric_db_pairs(const loom_db *db, uint32_t n_ex, uint8_t *tag,
                          uint32_t *n_pairs)
{
	uint32_t n = 0;
	int seen[LOOM_FIBRE_COUNT_ * LOOM_FIBRE_COUNT_];

	memset(seen, 0, sizeof seen);
	for (uint32_t u = 0; u < n_ex; u++) {
		loom_db_exemplar_info e;
		int rc = loom_db_exemplar(db, u, &e);
		if (rc)
			return rc;
		tag[u] = (uint8_t)(e.fibre[0] * LOOM_FIBRE_COUNT_ + e.fibre[1]);
		if (tag[u] && !seen[tag[u]]++)
			n++;
	}
	*n_pairs = n;
	return LOOM_OK;
}

void loom__fabric_pair_list(const uint8_t *tag, uint32_t n_ex, char *buf, size_t n)
{
	int seen[LOOM_FIBRE_COUNT_ * LOOM_FIBRE_COUNT_];
	size_t w = 0;

	memset(seen, 0, sizeof seen);
	buf[0] = '\0';
	for (uint32_t u = 0; u < n_ex && w < n; u++)
		if (tag[u] && !seen[tag[u]]++)
			w += (size_t)snprintf(buf + w, n - w, "%s%s/%s", w ? ", " : "",
			                      loom_fibre_name(tag[u] / LOOM_FIBRE_COUNT_),
			                      loom_fibre_name(tag[u] % LOOM_FIBRE_COUNT_));
}

int loom__fabric_assign_materials(loom_fabric *f, const loom_db *db,
                                  const loom_synth_options *so,
                                  const uint8_t def[2], int *done,
                                  loom_diag *diag)
{
	const loom_design *d = f->design;
	size_t n = (size_t)d->rows * d->cols;
	uint32_t n_ex = f->n_exemplars, n_pairs;
	uint8_t *tag = NULL, *cell = NULL;
	uint16_t *tmp = NULL;
	loom_synth_exemplar *ex = NULL;
	uint32_t *full = NULL;
	int used[LOOM_FIBRE_COUNT_ * LOOM_FIBRE_COUNT_], have[LOOM_FIBRE_COUNT_ * LOOM_FIBRE_COUNT_];
	int rc;

	*done = 0;
	tag = malloc(n_ex ? n_ex : 1);
	if (!tag)
		return loom__fail(diag, LOOM_ENOMEM, "synth: out of memory");
	rc = loom__fabric_db_pairs(db, n_ex, tag, &n_pairs);
	if (rc || n_pairs < 2) { /* one pair or none recorded: all exemplars */
		free(tag);
		return rc;
	}
	memset(have, 0, sizeof have);
	for (uint32_t u = 0; u < n_ex; u++)
		have[tag[u]] = 1;
	cell = malloc(n);
	tmp = malloc(n * sizeof *tmp);
	ex = calloc(n_ex, sizeof *ex);
	full = calloc(n_ex, sizeof *full);
	if (!cell || !tmp || !ex || !full) {
		rc = loom__fail(diag, LOOM_ENOMEM, "synth: out of memory for the "
		                "material pairs of a %ux%u design", d->rows, d->cols);
		goto out;
	}
	memset(used, 0, sizeof used);
	for (size_t k = 0; k < n; k++) {
		int w = material(d, d->warp_type[k], def[0]);
		int e = material(d, d->weft_type[k], def[1]);
		cell[k] = (uint8_t)(w * LOOM_FIBRE_COUNT_ + e);
		if (!have[cell[k]]) {
			char list[256];
			loom__fabric_pair_list(tag, n_ex, list, sizeof list);
			rc = loom__fail(diag, LOOM_EMISMATCH, "synth: crossing (%zu, %zu) has "
			                "warp yarn type '%s' of %s and weft yarn type '%s' of "
			                "%s, but the database has exemplars of the pairs %s "
			                "only", k / d->cols, k % d->cols,
			                d->types[d->warp_type[k]].name, loom_fibre_name(w),
			                d->types[d->weft_type[k]].name, loom_fibre_name(e), list);
			goto out;
		}
		used[cell[k]] = 1;
	}
	for (int pr = 1; pr < LOOM_FIBRE_COUNT_ * LOOM_FIBRE_COUNT_; pr++) {
		loom_synth_set *sub = NULL;
		uint32_t m = 0;
		if (!used[pr])
			continue;
		for (uint32_t u = 0; u < n_ex; u++) {
			loom_db_exemplar_info e;
			if (tag[u] != pr)
				continue;
			loom_db_exemplar(db, u, &e);
			ex[m].rows = e.rows;
			ex[m].cols = e.cols;
			ex[m].weave = e.weave;
			ex[m].periodic = 0;
			full[m++] = u;
		}
		rc = loom_synth_set_new(ex, m, &sub, diag);
		if (!rc)
			rc = loom_synth_assign(sub, d, so, tmp, diag);
		if (rc) {
			loom_synth_set_free(sub);
			if (diag) {
				char why[LOOM_DIAG_MSG_MAX];
				snprintf(why, sizeof why, "%s", diag->message);
				loom__fail(diag, rc, "synth: exemplars of %s/%s: %s",
				           loom_fibre_name(pr / LOOM_FIBRE_COUNT_),
				           loom_fibre_name(pr % LOOM_FIBRE_COUNT_), why);
			}
			goto out;
		}
		for (size_t k = 0; k < n; k++) {
			loom_synth_block b;
			if (cell[k] != pr)
				continue;
			loom_synth_block_info(sub, tmp[k], &b);
			f->base[k] = (uint16_t)loom_synth_block_index(f->set, full[b.exemplar],
			                                              b.row, b.col);
		}
		loom_synth_set_free(sub);
	}
	*done = 1;
out:
	free(tag);
	free(cell);
	free(tmp);
	free(ex);
	free(full);
	return rc;
}
