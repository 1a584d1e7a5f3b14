/*
 * io/store/exgen_write.c - the parallel database build of
 * `loom exemplar generate` (loom_exgen_write_db): procedural exemplar
 * models (engine/exemplar/exgen.c) evaluated brick column by brick column
 * and written through the streaming database writer (db_write.c).
 *
 * Tasks are brick columns (all bricks of one (bx, by)), numbered exemplar
 * by exemplar.  Workers take tasks in order, generate, cut into bricks and
 * encode them (deflate + CRC) into a ring of 2 * threads slots; the calling
 * thread writes slots strictly in task order.  Memory: per worker one brick
 * column of voxels and a compressor; per slot one brick column of encoded
 * bricks.
 */
#include "exemplar/exgen.h"
#include "exemplar/db_internal.h"
#include "db_write.h"

#include <libdeflate.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* ---- parallel build ------------------------------------------------------- */

enum { SLOT_FREE, SLOT_BUSY, SLOT_READY };

typedef struct slot {
	int state;
	uint64_t task;
	loom__dbw_brick *b;       /* one per brick of the column */
	uint8_t *cbuf;            /* nbz_max * brick_bytes */
	int16_t *top;             /* nbz_max * bx*by */
	uint8_t *top_label;
} slot;

/* The voxel layout params ask for (db_version 1..4: that layout; 0: the
   default, 4). */
static unsigned exgen_layout(const loom_exgen_params *p)
{
	return p->db_version ? p->db_version : LOOM__DB_VERSION_DEFAULT;
}

typedef struct pipe {
	pthread_mutex_t mu;
	pthread_cond_t cv;
	uint64_t next_task, n_tasks;
	int abort;                /* set on any failure: everyone stops */
	int worker_error;         /* a worker could not allocate */
	slot *slots;
	unsigned n_slots;
	const loom_exgen_params *p;
	loom__exgen **models;
	uint32_t n_models;
	uint64_t *task_start;     /* n_models + 1 prefix sums */
	uint32_t (*nb)[3];        /* bricks per axis per model */
	uint8_t (*solid)[256];
	uint32_t nbz_max;
	size_t brick_bytes, brick_voxels;
} pipe;

static uint32_t model_of_task(const pipe *P, uint64_t t)
{
	uint32_t k = 0;
	while (k + 1 < P->n_models && P->task_start[k + 1] <= t)
		k++;
	return k;
}

/* Copy brick bz of a generated column box into the four planes of pack. */
static void pack_brick(const pipe *P, uint32_t bz, uint32_t nzr, const uint8_t *d,
                       const uint16_t *o, const uint8_t *l, uint8_t *pack)
{
	const uint32_t *bs = P->p->brick;
	size_t nv = P->brick_voxels, ncol = (size_t)bs[0] * bs[1];

	for (size_t col = 0; col < ncol; col++) {
		size_t src = col * nzr + (size_t)bz * bs[2], dst = col * bs[2];
		memcpy(pack + dst, d + src, bs[2]);
		memcpy(pack + 3 * nv + dst, l + src, bs[2]);
		for (uint32_t z = 0; z < bs[2]; z++) {
			uint16_t c = o[src + z];
			pack[nv + dst + z] = (uint8_t)c;
			pack[2 * nv + dst + z] = (uint8_t)(c >> 8);
		}
	}
}

static void *worker(void *arg)
{
	pipe *P = arg;
	const uint32_t *bs = P->p->brick;
	uint32_t nzr = P->nbz_max * bs[2];
	size_t ncol = (size_t)bs[0] * bs[1], nbox = ncol * nzr;
	struct libdeflate_compressor *comp = libdeflate_alloc_compressor(P->p->level);
	uint8_t *d = malloc(nbox), *l = malloc(nbox), *pack = malloc(P->brick_bytes);
	uint16_t *o = malloc(nbox * sizeof *o);

	if (!comp || !d || !l || !o || !pack) {
		pthread_mutex_lock(&P->mu);
		P->abort = P->worker_error = 1;
		pthread_cond_broadcast(&P->cv);
		pthread_mutex_unlock(&P->mu);
		goto out;
	}
	for (;;) {
		uint64_t t, local;
		uint32_t k, bx, by;
		slot *s;

		pthread_mutex_lock(&P->mu);
		for (;;) {
			if (P->abort || P->next_task >= P->n_tasks) {
				pthread_mutex_unlock(&P->mu);
				goto out;
			}
			s = &P->slots[P->next_task % P->n_slots];
			if (s->state == SLOT_FREE)
				break;
			pthread_cond_wait(&P->cv, &P->mu);
		}
		t = P->next_task++;
		s->state = SLOT_BUSY;
		s->task = t;
		pthread_mutex_unlock(&P->mu);

		k = model_of_task(P, t);
		local = t - P->task_start[k];
		bx = (uint32_t)(local % P->nb[k][0]);
		by = (uint32_t)(local / P->nb[k][0]);
		if (loom__exgen_box(P->models[k], (int64_t)bx * bs[0], (int64_t)by * bs[1],
		                    0, bs[0], bs[1], P->nb[k][2] * bs[2], d, o, l) != LOOM_OK) {
			pthread_mutex_lock(&P->mu);
			P->abort = P->worker_error = 1;
			pthread_cond_broadcast(&P->cv);
			pthread_mutex_unlock(&P->mu);
			goto out;
		}
		for (uint32_t bz = 0; bz < P->nb[k][2]; bz++) {
			loom__dbw_brick *b = &s->b[bz];
			uint8_t *cb = s->cbuf + (size_t)bz * P->brick_bytes;
			pack_brick(P, bz, P->nb[k][2] * bs[2], d, o, l, pack);
			b->top = s->top + bz * ncol;
			b->top_label = s->top_label + bz * ncol;
			loom__dbw_encode(pack, bs, P->solid[k], LOOM__DB_TOP_THRESHOLD,
			                 exgen_layout(P->p) |
			                         (P->p->density_raw ? LOOM__DBW_DENSITY_RAW : 0),
			                 comp, cb, b);
			if (b->storage == LOOM__DB_STORE_RAW) {
				memcpy(cb, pack, P->brick_bytes);
				b->data = cb;
			}
		}
		pthread_mutex_lock(&P->mu);
		s->state = SLOT_READY;
		pthread_cond_broadcast(&P->cv);
		pthread_mutex_unlock(&P->mu);
	}
out:
	if (comp)
		libdeflate_free_compressor(comp);
	free(d);
	free(l);
	free(o);
	free(pack);
	return NULL;
}

/* The writer's side: put every task's bricks in order. */
static int drain(pipe *P, loom__dbw *w, loom_diag *diag)
{
	uint64_t bricks_done = 0, bricks_total = 0;

	for (uint32_t k = 0; k < P->n_models; k++)
		bricks_total += (uint64_t)P->nb[k][0] * P->nb[k][1] * P->nb[k][2];
	for (uint64_t t = 0; t < P->n_tasks; t++) {
		slot *s = &P->slots[t % P->n_slots];
		uint32_t k = model_of_task(P, t);
		int rc = LOOM_OK;

		pthread_mutex_lock(&P->mu);
		while (!(s->state == SLOT_READY && s->task == t) && !P->abort)
			pthread_cond_wait(&P->cv, &P->mu);
		pthread_mutex_unlock(&P->mu);
		if (P->abort)
			return loom__fail(diag, LOOM_ENOMEM, "generator: out of memory in a "
			                  "worker thread");
		if (t == P->task_start[k]) {
			loom__exgen_desc d;
			loom__dbw_exemplar e;
			loom__exgen_describe(P->models[k], &d);
			e.name = d.name;
			e.weave_name = d.weave_name;
			e.rows = d.rows;
			e.cols = d.cols;
			e.weave = d.weave;
			e.n_yarns = d.n_yarns;
			e.yarns = d.yarns;
			e.fibre[0] = d.fibre[0];
			e.fibre[1] = d.fibre[1];
			rc = loom__dbw_begin_exemplar(w, &e, diag);
		}
		for (uint32_t bz = 0; !rc && bz < P->nb[k][2]; bz++)
			rc = loom__dbw_put(w, &s->b[bz], diag);
		if (rc)
			return rc;
		bricks_done += P->nb[k][2];
		if (P->p->progress)
			P->p->progress(P->p->user, bricks_done, bricks_total);
		pthread_mutex_lock(&P->mu);
		s->state = SLOT_FREE;
		pthread_cond_broadcast(&P->cv);
		pthread_mutex_unlock(&P->mu);
	}
	return LOOM_OK;
}

static void free_pipe(pipe *P)
{
	if (P->slots)
		for (unsigned i = 0; i < P->n_slots; i++) {
			free(P->slots[i].b);
			free(P->slots[i].cbuf);
			free(P->slots[i].top);
			free(P->slots[i].top_label);
		}
	free(P->slots);
	if (P->models)
		for (uint32_t k = 0; k < P->n_models; k++)
			loom__exgen_free(P->models[k]);
	free(P->models);
	free(P->task_start);
	free(P->nb);
	free(P->solid);
}

/* Lay out the tasks of model k (P->models[k] set). */
static void plan_model(pipe *P, const loom_exgen_params *p, uint32_t k)
{
	loom__exgen_desc d;
	loom__exgen_describe(P->models[k], &d);
	for (int a = 0; a < 3; a++)
		P->nb[k][a] = (d.size[a] + p->brick[a] - 1) / (p->brick[a] ? p->brick[a] : 1);
	if (P->nb[k][2] > P->nbz_max)
		P->nbz_max = P->nb[k][2];
	P->task_start[k + 1] = P->task_start[k] + (uint64_t)P->nb[k][0] * P->nb[k][1];
	loom__db_solid_lut(d.yarns, d.n_yarns, P->solid[k]);
}

static int alloc_pipe(pipe *P, const loom_exgen_params *p, uint32_t n_models,
                      loom_diag *diag)
{
	memset(P, 0, sizeof *P);
	P->p = p;
	P->n_models = n_models;
	P->models = calloc(P->n_models, sizeof *P->models);
	P->task_start = calloc(P->n_models + 1, sizeof *P->task_start);
	P->nb = calloc(P->n_models, sizeof *P->nb);
	P->solid = calloc(P->n_models, sizeof *P->solid);
	if (!P->models || !P->task_start || !P->nb || !P->solid) {
		free_pipe(P);
		return loom__fail(diag, LOOM_ENOMEM, "generator: out of memory");
	}
	return LOOM_OK;
}

static int run_pipe(const char *path, const loom_exgen_params *p, pipe *P,
                    uint64_t *hash, loom_diag *diag);

LOOM_API int loom_exgen_write_db(const char *path, const loom_exgen_params *p,
                                 uint64_t *hash, loom_diag *diag)
{
	pipe P;
	int rc;
	uint32_t n_sets;

	if (!path)
		return loom__fail(diag, LOOM_EINVAL, "generator: NULL path");
	rc = loom__exgen_check(p, diag);
	if (rc)
		return rc;
	/* one set of exemplars per material pair (docs/exemplars.md, "Materials
	   per yarn type"); a single pair is fibre[] and untagged */
	n_sets = p->n_pairs >= 2 ? p->n_pairs : 1;
	rc = alloc_pipe(&P, p, n_sets * p->n_weaves, diag);
	if (rc)
		return rc;
	for (uint32_t m = 0; m < P.n_models; m++) {
		uint32_t k = m % p->n_weaves, set = m / p->n_weaves, variant = 0;
		loom_exgen_params q = *p;
		int code[2];
		for (uint32_t j = 0; j < k; j++)
			if (strcmp(p->weaves[j], p->weaves[k]) == 0)
				variant++;
		if (n_sets > 1) {
			for (int a = 0; a < 2; a++) {
				q.fibre[a] = p->pairs[set][a] ? p->pairs[set][a]
				                              : p->pairs[set][1 - a];
				loom_fibre_parse(q.fibre[a], &code[a]); /* checked above */
			}
			q.n_pairs = 0;
		}
		rc = loom__exgen_new(&q, k, variant, &P.models[m], diag);
		if (rc) {
			free_pipe(&P);
			return rc;
		}
		if (n_sets > 1)
			loom__exgen_tag(P.models[m], code[0], code[1]);
		plan_model(&P, p, m);
	}
	return run_pipe(path, p, &P, hash, diag);
}

LOOM_API int loom_exgen_write_design(const char *path, const loom_exgen_params *p,
                                     const char *name, uint32_t rows,
                                     uint32_t cols, const uint8_t *weave,
                                     uint64_t *hash, loom_diag *diag)
{
	static const char *const one[1] = {"design"};
	loom_exgen_params q;
	pipe P;
	int rc;

	if (!path || !p || !weave)
		return loom__fail(diag, LOOM_EINVAL, "generator: NULL %s",
		                  !path ? "path" : !p ? "parameters" : "weave");
	if (p->size != sizeof *p)
		return loom__exgen_check(p, diag);
	q = *p;
	q.n_weaves = 1;
	q.weaves[0] = one[0];
	q.rows = q.cols = 0;
	rc = alloc_pipe(&P, &q, 1, diag);
	if (rc)
		return rc;
	rc = loom__exgen_new_design(&q, name, rows, cols, weave, &P.models[0], diag);
	if (rc) {
		free_pipe(&P);
		return rc;
	}
	plan_model(&P, &q, 0);
	return run_pipe(path, &q, &P, hash, diag);
}

static int run_pipe(const char *path, const loom_exgen_params *p, pipe *P_,
                    uint64_t *hash, loom_diag *diag)
{
	pipe P = *P_;
	loom__dbw_params wp;
	loom__dbw *w = NULL;
	pthread_t th[64];
	unsigned nth, started = 0;
	int rc;

	memset(&wp, 0, sizeof wp);
	wp.n_exemplars = P.n_models;
	memcpy(wp.block, p->block, sizeof wp.block);
	memcpy(wp.brick, p->brick, sizeof wp.brick);
	wp.voxel_size_um = p->voxel_size_um;
	wp.top_threshold = LOOM__DB_TOP_THRESHOLD;
	wp.level = p->level;
	wp.seed = p->seed;
	wp.flags = 1;
	wp.layout = exgen_layout(p);
	wp.density_raw = p->density_raw;
	rc = loom__dbw_create(path, &wp, &w, diag);
	if (rc) {
		free_pipe(&P);
		return rc;
	}
	P.n_tasks = P.task_start[P.n_models];
	P.brick_voxels = (size_t)p->brick[0] * p->brick[1] * p->brick[2];
	P.brick_bytes = P.brick_voxels * LOOM__VOXEL_PLANES;
	nth = p->threads ? p->threads : 2;
	P.n_slots = 2 * nth;
	P.slots = calloc(P.n_slots, sizeof *P.slots);
	if (!P.slots) {
		loom__dbw_abort(w);
		free_pipe(&P);
		return loom__fail(diag, LOOM_ENOMEM, "generator: out of memory");
	}
	for (unsigned i = 0; i < P.n_slots; i++) {
		slot *s = &P.slots[i];
		size_t ncol = (size_t)p->brick[0] * p->brick[1];
		s->b = calloc(P.nbz_max, sizeof *s->b);
		s->cbuf = malloc(P.nbz_max * P.brick_bytes);
		s->top = malloc(P.nbz_max * ncol * sizeof *s->top);
		s->top_label = malloc(P.nbz_max * ncol);
		if (!s->b || !s->cbuf || !s->top || !s->top_label) {
			loom__dbw_abort(w);
			free_pipe(&P);
			return loom__fail(diag, LOOM_ENOMEM, "generator: out of memory");
		}
	}
	pthread_mutex_init(&P.mu, NULL);
	pthread_cond_init(&P.cv, NULL);
	for (; started < nth; started++)
		if (pthread_create(&th[started], NULL, worker, &P) != 0)
			break;
	if (started == 0)
		rc = loom__fail(diag, LOOM_ENOMEM, "generator: cannot start a thread");
	else
		rc = drain(&P, w, diag);
	pthread_mutex_lock(&P.mu);
	if (rc)
		P.abort = 1;
	pthread_cond_broadcast(&P.cv);
	pthread_mutex_unlock(&P.mu);
	for (unsigned i = 0; i < started; i++)
		pthread_join(th[i], NULL);
	pthread_mutex_destroy(&P.mu);
	pthread_cond_destroy(&P.cv);
	if (rc)
		loom__dbw_abort(w);
	else
		rc = loom__dbw_finish(w, hash, diag);
	free_pipe(&P);
	return rc;
}
