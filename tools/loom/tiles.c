/*
 * tools/loom/tiles.c - region and tile options, budget split and the worker
 * pool of `loom export` and `loom scan` (tiles.h).
 */
#include "tiles.h"
#include "paintfile.h"
#include "io/core/file.h" /* io/: loom__open_input */

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

void tiles_init(tiles_job *j)
{
	memset(j, 0, sizeof *j);
	j->shard_n = 1;
	j->threads = 1;
	j->budget_mb = 64;
	j->bolt.len = j->bolt.wid = 1;
}

/* One signed 64-bit integer of exactly the text [s, e). */
static int parse_i64_span(const char *s, const char *e, int64_t *v)
{
	char buf[32];
	size_t n = (size_t)(e - s);

	if (n == 0 || n >= sizeof buf)
		return -1;
	memcpy(buf, s, n);
	buf[n] = 0;
	for (size_t i = 0; i < n; i++)
		if (isspace((unsigned char)buf[i]))
			return -1;
	return cli_parse_i64(buf, v);
}

/* "A,B,C" (count numbers) into v; returns the count parsed or -1. */
static int parse_list(const char *s, int64_t *v, int min, int max)
{
	int n = 0;
	const char *p = s;

	for (;;) {
		const char *c = strchr(p, ',');
		const char *e = c ? c : p + strlen(p);
		if (n >= max || parse_i64_span(p, e, &v[n]))
			return -1;
		n++;
		if (!c)
			break;
		p = c + 1;
	}
	return n >= min ? n : -1;
}

int tiles_parse_region(const char *s, int64_t lo[3], int64_t hi[3])
{
	const char *colon = strchr(s, ':');
	char buf[128];
	size_t n;

	if (!colon || strchr(colon + 1, ':'))
		return -1;
	n = (size_t)(colon - s);
	if (n >= sizeof buf)
		return -1;
	memcpy(buf, s, n);
	buf[n] = 0;
	if (parse_list(buf, lo, 3, 3) != 3 || parse_list(colon + 1, hi, 3, 3) != 3)
		return -1;
	for (int a = 0; a < 3; a++)
		if (lo[a] <= -TILES_COORD_MAX || hi[a] >= TILES_COORD_MAX || hi[a] <= lo[a])
			return -1;
	return 0;
}

int tiles_parse_tile(const char *s, int64_t t[3])
{
	int n = parse_list(s, t, 2, 3);

	if (n < 0)
		return -1;
	if (n == 2)
		t[2] = 0;
	for (int a = 0; a < n; a++)
		if (t[a] < 1 || t[a] > TILES_SIDE_MAX)
			return -1;
	return 0;
}

int tiles_parse_shard(const char *s, uint32_t *i, uint32_t *n)
{
	const char *slash = strchr(s, '/');
	char buf[32];
	size_t len;

	if (!slash)
		return -1;
	len = (size_t)(slash - s);
	if (len == 0 || len >= sizeof buf)
		return -1;
	memcpy(buf, s, len);
	buf[len] = 0;
	if (cli_parse_u32(buf, i) || cli_parse_u32(slash + 1, n) || *n == 0 || *i >= *n)
		return -1;
	return 0;
}

/* "12", "2.5" (repeats) or "50m", "150cm", "900mm"; *mm = 1 with a unit
   (the value is then in mm). */
static int parse_extent(const char *s, double *v, int *mm)
{
	char *end;
	double x = strtod(s, &end);

	if (end == s || !isfinite(x) || x <= 0)
		return -1;
	*mm = 1;
	if (strcmp(end, "mm") == 0)
		*v = x;
	else if (strcmp(end, "cm") == 0)
		*v = 10 * x;
	else if (strcmp(end, "m") == 0)
		*v = 1000 * x;
	else if (*end == 0) {
		*v = x;
		*mm = 0;
	} else
		return -1;
	return 0;
}

int tiles_parse_bolt(const char *s, double *len, int *len_mm, double *wid,
                     int *wid_mm)
{
	char buf[128], *x;

	if (strlen(s) >= sizeof buf || !*s)
		return -1;
	strcpy(buf, s);
	x = strpbrk(buf + 1, "xX");
	if (!x)
		return -1;
	*x = 0;
	if (parse_extent(buf, len, len_mm) || parse_extent(x + 1, wid, wid_mm))
		return -1;
	return 0;
}

const char *tiles_opt_bolt(const char *text, void *bolt)
{
	tiles_bolt *b = bolt;

	b->text = text;
	if (tiles_parse_bolt(text, &b->len, &b->len_mm, &b->wid, &b->wid_mm))
		return "LENGTHxWIDTH (repeats, or lengths with mm, cm or m: 10x2, 50mx1.5m)";
	return NULL;
}

const char *tiles_opt_tile(const char *text, void *job)
{
	tiles_job *j = job;

	j->tile_s = text;
	if (tiles_parse_tile(text, j->tsize))
		return "TX,TY or TX,TY,TZ (tile sides in voxels, 1..2147483647)";
	return NULL;
}

const char *tiles_opt_shard(const char *text, void *job)
{
	tiles_job *j = job;

	j->shard_s = text;
	j->shard_auto = strcmp(text, "auto") == 0;
	if (j->shard_auto) {
		j->shard_i = 0; /* resolved by tiles_parse */
		j->shard_n = 1;
		return NULL;
	}
	if (tiles_parse_shard(text, &j->shard_i, &j->shard_n))
		return "I/N with 0 <= I < N (e.g. 0/4), or auto";
	return NULL;
}

/* The value of environment variable `name` as a u32: 1, 0 when unset,
   -1 when set but not a number (msg says so). */
static int env_u32(const char *name, uint32_t *v, char *msg, size_t msz)
{
	const char *e = getenv(name);

	if (!e || !*e)
		return 0;
	if (cli_parse_u32(e, v)) {
		snprintf(msg, msz, "$%s is '%.40s', not a number", name, e);
		return -1;
	}
	return 1;
}

int tiles_shard_auto(uint32_t *i, uint32_t *n, char *from, size_t fsz, char *msg,
                     size_t msz)
{
	const char *iname = "LOOM_SHARD_INDEX", *nname = "LOOM_SHARD_COUNT";
	int hi, hn;

	if ((hi = env_u32(iname, i, msg, msz)) < 0)
		return -1;
	if (hi == 0) {
		iname = "SLURM_ARRAY_TASK_ID";
		if ((hi = env_u32(iname, i, msg, msz)) < 0)
			return -1;
	}
	if ((hn = env_u32(nname, n, msg, msz)) < 0)
		return -1;
	if (hn == 0) {
		uint32_t lo = 0, top = 0;
		int hl, ht;
		nname = "SLURM_ARRAY_TASK_COUNT";
		if ((hn = env_u32(nname, n, msg, msz)) < 0)
			return -1;
		if ((hl = env_u32("SLURM_ARRAY_TASK_MIN", &lo, msg, msz)) < 0 ||
		    (ht = env_u32("SLURM_ARRAY_TASK_MAX", &top, msg, msz)) < 0)
			return -1;
		/* a resubmitted part of an array (--array=3) counts 1 task: N must
		   then come from $LOOM_SHARD_COUNT */
		if (hn > 0 && ((hl > 0 && lo != 0) || (ht > 0 && top + 1 != *n))) {
			snprintf(msg, msz, "this job array has %u task%s numbered %u..%u, not "
			         "0..%u: set LOOM_SHARD_COUNT to the number of shards (e.g. "
			         "sbatch --export=ALL,LOOM_SHARD_COUNT=N; tools/slurm/submit.sh "
			         "does)", *n, *n == 1 ? "" : "s", lo, top, *n ? *n - 1 : 0);
			return -1;
		}
	}
	if (hi == 0 && hn == 0) {
		snprintf(msg, msz, "$SLURM_ARRAY_TASK_ID and $SLURM_ARRAY_TASK_COUNT (or "
		         "$LOOM_SHARD_INDEX and $LOOM_SHARD_COUNT) are not set: not a job array "
		         "task? (or give --shard I/N)");
		return -1;
	}
	if (hi == 0 || hn == 0) {
		snprintf(msg, msz, "%s is not set", hi == 0 ? "$SLURM_ARRAY_TASK_ID (or "
		         "$LOOM_SHARD_INDEX)" : "$SLURM_ARRAY_TASK_COUNT (or $LOOM_SHARD_COUNT)");
		return -1;
	}
	if (*n == 0 || *i >= *n) {
		snprintf(msg, msz, "$%s = %u and $%s = %u: expected 0 <= I < N", iname, *i,
		         nname, *n);
		return -1;
	}
	snprintf(from, fsz, "$%s, $%s", iname, nname);
	return 0;
}

void tiles_parse(const opts_cmd *c, tiles_job *j, int need_region)
{
	if (j->region_s && j->all)
		opts_usage(c, "give --region or --all, not both");
	if (need_region && !j->region_s && !j->all)
		opts_usage(c, "give --region X0,Y0,Z0:X1,Y1,Z1 or --all");
	/* the wording of tests/cli/test_export.sh and test_scan.sh */
	if (j->region_s && tiles_parse_region(j->region_s, j->lo, j->hi))
		opts_usage(c, "bad --region '%s' (expected X0,Y0,Z0:X1,Y1,Z1: integer voxel "
		           "coordinates of a half-open box with X0<X1, Y0<Y1, Z0<Z1, each "
		           "below 2^62 in magnitude)", j->region_s);
	if (j->bolt.text && !j->all)
		opts_usage(c, "--bolt goes with --all");
	if (j->shard_auto) {
		char msg[512];
		if (tiles_shard_auto(&j->shard_i, &j->shard_n, j->shard_from,
		                     sizeof j->shard_from, msg, sizeof msg) != 0)
			opts_usage(c, "--shard auto: %s", msg);
	}
}

void tiles_open_fabric(tiles_job *j, const char *prog, const char *path,
                       int64_t def_xy)
{
	loom_fabric_db_identity id;
	loom_diag diag;
	uint64_t total = 1;

	cli_diag_init(&diag, NULL);
	if (j->db_s && loom_db_open(j->db_s, &j->db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	/* a design too large for --budget: refused before it is read */
	cli_fabric_fits(prog, path, j->budget_mb * 1048576.0, "this job needs", EXIT_USAGE);
	{
		loom_paint *paint = NULL;
		if (cli_open_painted(path, j->db, &j->f, &paint, &diag) != LOOM_OK) {
			loom_db_close(j->db);
			cli_fail(prog, "%s", diag.message);
		}
		if (paint && j->keep_paint) {
			j->paint = paint; /* bound to the texture when it opens */
		} else if (paint) {
			/* painted weaves are in the fabric now */
			cli_paint_note(prog, path, paint);
			loom_paint_free(paint);
		}
	}
	loom_fabric_repeat_voxels(j->f, j->rep);
	loom_fabric_get_db_identity(j->f, &id);
	j->voxel_mm = (double)id.voxel_size_um / 1000.0;
	if (j->all) {
		uint64_t size[3];
		double len = j->bolt.len, wid = j->bolt.wid, vox;
		if (j->bolt.len_mm)
			len /= (double)j->rep[1] * j->voxel_mm;
		if (j->bolt.wid_mm)
			wid /= (double)j->rep[0] * j->voxel_mm;
		if (loom_fabric_bolt_voxels(j->f, len, wid, size, &vox) != LOOM_OK)
			cli_fail(prog, "--bolt '%s': too large", j->bolt.text ? j->bolt.text : "1x1");
		for (int a = 0; a < 3; a++) {
			j->lo[a] = 0;
			j->hi[a] = (int64_t)size[a];
		}
	}
	for (int a = 0; a < 3; a++) {
		int64_t ext = j->hi[a] - j->lo[a];
		int64_t t = j->tsize[a];
		if (t == 0)
			t = a < 2 ? def_xy : ext;
		if (t > ext)
			t = ext;
		if (t > TILES_SIDE_MAX)
			cli_fail(prog, "the region is %lld voxels along %c: give --tile with a "
			         "side of at most %lld", (long long)ext, "xyz"[a], TILES_SIDE_MAX);
		j->tsize[a] = t;
		j->nt[a] = (uint64_t)(ext / t + (ext % t != 0));
		if (__builtin_mul_overflow(total, j->nt[a], &total))
			cli_fail(prog, "too many tiles (more than 2^64): use a larger --tile");
	}
	j->total = total;
}

/* Smallest --budget, whole MiB, with which the texture opens beside
   `buffers` bytes of buffers (0 if none up to 4 TiB). */
static double min_budget_mb(tiles_job *j, double buffers)
{
	double lo = floor(j->budget_mb), hi = lo + 1;
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t;

	o.max_threads = j->threads;
	for (;;) { /* lo fails; find an hi that opens */
		o.budget_bytes = (size_t)(hi * 1048576.0 - buffers);
		if (loom_texture_open(j->f, j->db, &o, &t, NULL) == LOOM_OK)
			break;
		if (hi > 4194304.0)
			return 0;
		lo = hi;
		hi *= 2;
	}
	loom_texture_close(t);
	while (hi - lo > 1) {
		double mid = floor((lo + hi) / 2);
		o.budget_bytes = (size_t)(mid * 1048576.0 - buffers);
		if (loom_texture_open(j->f, j->db, &o, &t, NULL) == LOOM_OK) {
			loom_texture_close(t);
			hi = mid;
		} else {
			lo = mid;
		}
	}
	return hi;
}

void tiles_open_texture(tiles_job *j, const char *prog, size_t worker_bytes)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	double budget = j->budget_mb * 1048576.0;
	double buffers = (double)worker_bytes * j->threads + (double)j->job_bytes;
	loom_diag diag;
	int rc;

	j->worker_bytes = worker_bytes;
	cli_diag_init(&diag, NULL);
	char s1[40], s2[40], s3[40], s4[40]; /* loom__size_text */

	/* Advice by the larger part: many tiles (a manifest line each) want
	   larger tiles or shards; large tiles want smaller ones. */
	if (buffers >= budget && (double)j->job_bytes > (double)worker_bytes * j->threads) {
		fprintf(stderr, "%s: %llu tiles need about %s for the manifest and "
		        "%s of buffers on %u thread%s: more than --budget %s (use "
		        "a larger --tile, --shard I/N or a larger --budget)\n", prog,
		        (unsigned long long)tiles_in_shard(j),
		        loom__size_text(s1, sizeof s1, (double)j->job_bytes),
		        loom__size_text(s2, sizeof s2, (double)worker_bytes * j->threads),
		        j->threads, j->threads == 1 ? "" : "s",
		        loom__size_text(s3, sizeof s3, budget));
		tiles_close(j);
		exit(EXIT_USAGE);
	}
	if (buffers >= budget) {
		fprintf(stderr, "%s: tile %lld x %lld x %lld needs %s of buffers per "
		        "thread, %s on %u thread%s: more than --budget %s (use a "
		        "smaller --tile, fewer --threads or a larger --budget)\n", prog,
		        (long long)j->tsize[0], (long long)j->tsize[1], (long long)j->tsize[2],
		        loom__size_text(s1, sizeof s1, (double)worker_bytes),
		        loom__size_text(s2, sizeof s2, buffers), j->threads,
		        j->threads == 1 ? "" : "s", loom__size_text(s3, sizeof s3, budget));
		tiles_close(j);
		exit(EXIT_USAGE);
	}
	j->texture_budget = (size_t)(budget - buffers);
	o.budget_bytes = j->texture_budget;
	o.max_threads = j->threads;
	rc = loom_texture_open(j->f, j->db, &o, &j->t, &diag);
	if (rc != LOOM_OK) {
		int code = rc == LOOM_EBUDGET ? EXIT_USAGE : EXIT_BAD_INPUT;
		if (rc == LOOM_EBUDGET) {
			double need = min_budget_mb(j, buffers);
			fprintf(stderr, "%s: --budget %s minus %s of tile buffers (and manifest) "
			        "leaves %s for the texture: %s\n", prog,
			        loom__size_text(s1, sizeof s1, budget),
			        loom__size_text(s2, sizeof s2, buffers),
			        loom__size_text(s4, sizeof s4, (double)j->texture_budget),
			        diag.message);
			if (need > 0)
				fprintf(stderr, "%s: this job needs at least --budget %.0f\n",
				        prog, need);
		} else {
			fprintf(stderr, "%s: %s\n", prog, diag.message);
		}
		tiles_close(j);
		exit(code);
	}
	if (j->paint && loom_paint_bind(j->paint, j->t, j->f) != LOOM_OK) {
		fprintf(stderr, "%s: out of memory binding the paint layer\n", prog);
		tiles_close(j);
		exit(EXIT_BAD_INPUT);
	}
}

void tiles_close(tiles_job *j)
{
	loom_texture_close(j->t);
	loom_paint_free(j->paint);
	loom_fabric_free(j->f);
	loom_db_close(j->db);
	j->paint = NULL;
	j->t = NULL;
	j->f = NULL;
	j->db = NULL;
}

/* ---- source order and shards (tiles.h) ------------------------------------ */

/* Chunks: cw tiles of a row by cr rows (cr * cw <= TILES_CHUNK_TILES), cpr
   chunks across a band of rows, cpl bands per z layer. */
static void chunk_geom(const tiles_job *j, uint64_t *cr, uint64_t *cw, uint64_t *cpr,
                       uint64_t *cpl)
{
	*cw = j->nt[0] < TILES_CHUNK_TILES ? j->nt[0] : TILES_CHUNK_TILES;
	if (*cw < 1)
		*cw = 1;
	*cr = TILES_CHUNK_TILES / *cw;
	*cpr = (j->nt[0] + *cw - 1) / *cw;
	*cpl = (j->nt[1] + *cr - 1) / *cr;
}

/* Start of part i of N of a chunk of n tiles (n <= TILES_CHUNK_TILES). */
static uint64_t part_at(uint64_t n, uint32_t i, uint32_t N)
{
	return n * i / N;
}

uint64_t tiles_in_shard(const tiles_job *j)
{
	uint64_t cr, cw, cpr, cpl, sum = 0;

	if (j->shard_n <= 1)
		return j->total;
	if (j->total == 0)
		return 0;
	chunk_geom(j, &cr, &cw, &cpr, &cpl);
	/* four kinds of chunk: full, last of a band (narrower), last band
	   (fewer rows), both */
	for (int a = 0; a < 2; a++)
		for (int b = 0; b < 2; b++) {
			uint64_t na = a ? 1 : cpr - 1, nb = b ? 1 : cpl - 1;
			uint64_t w = a ? j->nt[0] - (cpr - 1) * cw : cw;
			uint64_t r = b ? j->nt[1] - (cpl - 1) * cr : cr;
			uint64_t n = w * r;
			sum += na * nb * j->nt[2] *
			       (part_at(n, j->shard_i + 1, j->shard_n) - part_at(n, j->shard_i, j->shard_n));
		}
	return sum;
}

void tiles_box(const tiles_job *j, uint64_t index, int64_t lo[3], int64_t hi[3],
               int64_t tile[3])
{
	uint64_t t[3];

	t[0] = index % j->nt[0];
	t[1] = index / j->nt[0] % j->nt[1];
	t[2] = index / j->nt[0] / j->nt[1];
	for (int a = 0; a < 3; a++) {
		lo[a] = j->lo[a] + (int64_t)t[a] * j->tsize[a];
		hi[a] = j->hi[a] - lo[a] < j->tsize[a] ? j->hi[a] : lo[a] + j->tsize[a];
		if (tile)
			tile[a] = (int64_t)t[a];
	}
}

uint64_t tiles_voxels(const tiles_job *j, uint64_t index)
{
	int64_t lo[3], hi[3];

	tiles_box(j, index, lo, hi, NULL);
	return (uint64_t)(hi[0] - lo[0]) * (uint64_t)(hi[1] - lo[1]) * (uint64_t)(hi[2] - lo[2]);
}

static int ord_cmp(const void *a, const void *b)
{
	const struct tiles_ord *x = a, *y = b;
	if (x->key != y->key)
		return x->key < y->key ? -1 : 1;
	return x->index < y->index ? -1 : x->index > y->index;
}

static int ord_cmp_index(const void *a, const void *b)
{
	const struct tiles_ord *x = a, *y = b;
	return x->index < y->index ? -1 : x->index > y->index;
}

int tiles_iter_init(tiles_iter *it, const tiles_job *j, int index_order)
{
	loom_db_info di;

	memset(it, 0, sizeof *it);
	it->j = j;
	it->index_order = index_order;
	if (j->total == 0)
		return 0;
	chunk_geom(j, &it->chunk_rows, &it->chunk_cols, &it->cpr, &it->cpl);
	it->n_chunks = it->cpr * it->cpl * j->nt[2];
	it->ord = malloc(sizeof *it->ord * it->chunk_rows * it->chunk_cols);
	if (!it->ord)
		return -1;
	if (loom_db_get_info(loom_fabric_db(j->f), &di) != LOOM_OK) {
		free(it->ord);
		it->ord = NULL;
		return -1;
	}
	it->block[0] = di.block[0];
	it->block[1] = di.block[1];
	return 0;
}

/* Fill the order of chunk c and select this shard's part of it. */
static int iter_load(tiles_iter *it, uint64_t c)
{
	const tiles_job *j = it->j;
	uint64_t cr = it->chunk_rows, cw = it->chunk_cols;
	uint64_t t2 = c / (it->cpr * it->cpl), band = c / it->cpr % it->cpl, cc = c % it->cpr;
	uint64_t row0 = band * cr, col0 = cc * cw;
	uint64_t nr = j->nt[1] - row0 < cr ? j->nt[1] - row0 : cr;
	uint64_t w = j->nt[0] - col0 < cw ? j->nt[0] - col0 : cw;
	/* keys are needed to sort, and to find a shard's part */
	int keyed = !it->index_order || j->shard_n > 1;
	uint64_t n = 0;

	for (uint64_t t1 = row0; t1 < row0 + nr; t1++)
		for (uint64_t t0 = col0; t0 < col0 + w; t0++) {
			uint64_t idx = t0 + j->nt[0] * (t1 + j->nt[1] * t2);
			uint32_t key = 0;
			if (keyed) {
				int64_t lo[3], hi[3];
				loom_fabric_source src;
				tiles_box(j, idx, lo, hi, NULL);
				int64_t J = loom_synth_floordiv(lo[0] + (hi[0] - lo[0]) / 2, it->block[0]);
				int64_t I = loom_synth_floordiv(lo[1] + (hi[1] - lo[1]) / 2, it->block[1]);
				if (loom_fabric_source_at(j->f, I, J, &src) != LOOM_OK)
					return -1;
				key = src.block;
			}
			it->ord[n].index = idx;
			it->ord[n++].key = key;
		}
	if (keyed)
		qsort(it->ord, n, sizeof *it->ord, ord_cmp);
	it->pos = part_at(n, j->shard_i, j->shard_n);
	it->end = part_at(n, j->shard_i + 1, j->shard_n);
	if (it->index_order && keyed)
		qsort(it->ord + it->pos, it->end - it->pos, sizeof *it->ord, ord_cmp_index);
	return 0;
}

int tiles_iter_next(tiles_iter *it, uint64_t *index)
{
	while (it->pos >= it->end) {
		if (it->chunk >= it->n_chunks)
			return 0;
		if (iter_load(it, it->chunk++) != 0)
			return -1;
	}
	*index = it->ord[it->pos++].index;
	return 1;
}

void tiles_iter_free(tiles_iter *it)
{
	free(it->ord);
	it->ord = NULL;
}

int tiles_shard_list(const tiles_job *j, int index_order, uint64_t *list)
{
	tiles_iter it;
	uint64_t n = 0, max = tiles_in_shard(j), idx;
	int r;

	if (tiles_iter_init(&it, j, index_order) != 0)
		return -1;
	while ((r = tiles_iter_next(&it, &idx)) == 1 && n < max)
		list[n++] = idx;
	tiles_iter_free(&it);
	return r < 0 || n != max ? -1 : 0;
}

uint64_t tiles_shard_voxels(const tiles_job *j)
{
	tiles_iter it;
	uint64_t sum = 0, idx;

	if (j->shard_n == 1) {
		uint64_t v = 1;
		for (int a = 0; a < 3; a++)
			v *= (uint64_t)(j->hi[a] - j->lo[a]);
		return v;
	}
	if (tiles_iter_init(&it, j, 1) != 0)
		return 0;
	while (tiles_iter_next(&it, &idx) == 1)
		sum += tiles_voxels(j, idx);
	tiles_iter_free(&it);
	return sum;
}

/* ---- pool ------------------------------------------------------------------- */

struct worker {
	tiles_pool *p;
	unsigned w;
};

static void *worker_main(void *arg)
{
	struct worker *wk = arg;
	tiles_pool *p = wk->p;
	tiles_job *j = p->job;
	uint64_t n = tiles_in_shard(j);
	char msg[sizeof p->msg];

	while (!atomic_load_explicit(&p->stop, memory_order_relaxed)) {
		uint64_t k, idx = 0;
		int got = 1;
		/* the next tile of the shard's order */
		pthread_mutex_lock(&p->lock);
		if (p->list) {
			got = p->next < n;
			if (got)
				idx = p->list[p->next];
		} else {
			got = tiles_iter_next(&p->it, &idx);
			if (got < 0 && !atomic_load(&p->stop)) {
				snprintf(p->msg, sizeof p->msg, "cannot order the tiles (out of "
				         "memory, or the fabric has no database)");
				atomic_store(&p->stop, 1);
			}
		}
		k = p->next;
		if (got == 1)
			p->next++;
		pthread_mutex_unlock(&p->lock);
		if (got != 1)
			break;
		if (!p->skip || !p->skip[k]) {
			msg[0] = 0;
			if (p->fn(p->ctx, wk->w, k, idx, msg, sizeof msg) != 0) {
				pthread_mutex_lock(&p->lock);
				if (!atomic_load(&p->stop)) {
					snprintf(p->msg, sizeof p->msg, "%s", msg[0] ? msg : "failed");
					atomic_store(&p->stop, 1);
				}
				pthread_mutex_unlock(&p->lock);
				break;
			}
		}
		atomic_fetch_add(&p->done_voxels, (unsigned long long)tiles_voxels(j, idx));
		atomic_fetch_add(&p->done_tiles, 1);
	}
	loom_texture_thread_done(j->t);
	pthread_mutex_lock(&p->lock);
	p->finished++;
	pthread_cond_signal(&p->cond);
	pthread_mutex_unlock(&p->lock);
	return NULL;
}

int tiles_index_order_wanted(void)
{
	const char *e = getenv("LOOM_TILE_ORDER");
	return e && strcmp(e, "index") == 0;
}

int tiles_run(tiles_pool *p)
{
	tiles_job *j = p->job;
	pthread_t *th = calloc(j->threads, sizeof *th);
	struct worker *wk = calloc(j->threads, sizeof *wk);
	unsigned started = 0;

	atomic_init(&p->done_tiles, 0);
	atomic_init(&p->done_voxels, 0);
	atomic_init(&p->stop, 0);
	p->next = 0;
	p->msg[0] = 0;
	p->finished = 0;
	memset(&p->it, 0, sizeof p->it);
	if (!th || !wk || (!p->list && tiles_iter_init(&p->it, j, p->index_order) != 0)) {
		snprintf(p->msg, sizeof p->msg, "out of memory");
		free(th);
		free(wk);
		return -1;
	}
	pthread_mutex_init(&p->lock, NULL);
	pthread_cond_init(&p->cond, NULL);
	for (unsigned w = 0; w < j->threads; w++) {
		wk[w].p = p;
		wk[w].w = w;
		if (pthread_create(&th[w], NULL, worker_main, &wk[w]) != 0) {
			atomic_store(&p->stop, 1);
			snprintf(p->msg, sizeof p->msg, "cannot start thread %u", w);
			break;
		}
		started++;
	}
	for (;;) {
		struct timespec ts;
		unsigned fin;
		if (p->progress)
			cli_progress_update(p->progress, p->progress_voxels
			                                         ? atomic_load(&p->done_voxels)
			                                         : atomic_load(&p->done_tiles));
		if (p->tick)
			p->tick(p->ctx);
		clock_gettime(CLOCK_REALTIME, &ts);
		ts.tv_nsec += 100000000;
		if (ts.tv_nsec >= 1000000000) {
			ts.tv_sec++;
			ts.tv_nsec -= 1000000000;
		}
		pthread_mutex_lock(&p->lock);
		if (p->finished < started)
			pthread_cond_timedwait(&p->cond, &p->lock, &ts);
		fin = p->finished;
		pthread_mutex_unlock(&p->lock);
		if (fin >= started)
			break;
	}
	for (unsigned w = 0; w < started; w++)
		pthread_join(th[w], NULL);
	if (p->progress && !atomic_load(&p->stop)) {
		cli_progress_update(p->progress, p->progress_voxels
		                                         ? atomic_load(&p->done_voxels)
		                                         : atomic_load(&p->done_tiles));
		cli_progress_end(p->progress);
	} else if (p->progress)
		cli_progress_end(p->progress);
	pthread_mutex_destroy(&p->lock);
	pthread_cond_destroy(&p->cond);
	tiles_iter_free(&p->it);
	free(th);
	free(wk);
	return atomic_load(&p->stop) ? -1 : 0;
}

uint64_t tiles_peak_rss(void)
{
	struct rusage ru;

	if (getrusage(RUSAGE_SELF, &ru) != 0)
		return 0;
	return (uint64_t)ru.ru_maxrss * 1024u;
}

double tiles_cpu_seconds(void)
{
	struct rusage ru;

	if (getrusage(RUSAGE_SELF, &ru) != 0)
		return 0;
	return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
	       (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
}

char *tiles_list_text(const uint8_t *flag, uint32_t n)
{
	size_t cap = 64, len = 0;
	char *s = malloc(cap);

	if (!s)
		return NULL;
	s[0] = 0;
	for (uint32_t i = 0; i < n; i++) {
		uint32_t e = i;
		char item[32];
		int k;
		if (!flag[i])
			continue;
		while (e + 1 < n && flag[e + 1])
			e++;
		k = e == i ? snprintf(item, sizeof item, "%s%u", len ? "," : "", i)
		           : snprintf(item, sizeof item, "%s%u-%u", len ? "," : "", i, e);
		if (len + (size_t)k + 1 > cap) {
			char *ns;
			cap = 2 * cap + (size_t)k;
			ns = realloc(s, cap);
			if (!ns) {
				free(s);
				return NULL;
			}
			s = ns;
		}
		memcpy(s + len, item, (size_t)k + 1);
		len += (size_t)k;
		i = e;
	}
	return s;
}

uint64_t tiles_mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

char *tiles_read_text(const char *path, size_t max, size_t *len)
{
	char *buf = NULL;
	size_t n = 0, cap = 0;
	uint64_t size;
	FILE *fp;
	int fd;

	/* never blocks on a FIFO; anything but a regular file: EINVAL */
	errno = EINVAL;
	if (loom__open_input(path, &fd, &size, NULL) != LOOM_OK)
		return NULL;
	if (size > max) {
		close(fd);
		errno = EFBIG;
		return NULL;
	}
	fp = fdopen(fd, "rb");
	if (!fp) {
		close(fd);
		return NULL;
	}
	for (;;) {
		size_t got;
		if (cap - n < 65536) {
			char *nb;
			cap = cap ? 2 * cap : 65536;
			if (cap > max + 65536) {
				free(buf);
				fclose(fp);
				errno = EFBIG;
				return NULL;
			}
			nb = realloc(buf, cap + 1);
			if (!nb) {
				free(buf);
				fclose(fp);
				errno = ENOMEM;
				return NULL;
			}
			buf = nb;
		}
		got = fread(buf + n, 1, cap - n, fp);
		n += got;
		if (got == 0)
			break;
	}
	if (ferror(fp)) {
		free(buf);
		fclose(fp);
		errno = EIO;
		return NULL;
	}
	fclose(fp);
	buf[n] = 0;
	if (len)
		*len = n;
	return buf;
}
