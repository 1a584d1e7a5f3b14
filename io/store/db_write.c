/*
 * io/store/db_write.c - streaming, atomic writer of exemplar databases.
 *
 * The file is written front to back through loom__atomic (a temporary name,
 * renamed over the target by loom__dbw_finish):
 *
 *   1. create: the 128-byte header (everything in it is known up front);
 *   2. put:    each brick's stored bytes as they arrive (nothing buffered);
 *              its 24-byte index entry is kept in memory, and the column
 *              tops of the brick are merged into the exemplar's height map;
 *   3. the height map is a ring of b2 + brick_y voxel rows: bricks arrive
 *      brick row by brick row (z fastest, then x, then y), and when a brick
 *      row is complete every block row it completes gets its per-block
 *      tables (docs/formats.md, "Block tables"), after which its rows are
 *      reused; so the map's memory is bounded by the exemplar's width, not
 *      its area;
 *   4. finish: metadata (exemplar table, weaves, yarn tables, symmetries,
 *      block tables, index), then the trailer with the metadata CRC and the
 *      content hash; fsync; rename.
 *
 * Invariant: w->pos is the number of bytes written to the temporary file.
 */
#include "db_write.h"
#include "io/core/file.h"

#include <libdeflate.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct dbw_exemplar {
	char name[32];
	char weave_name[32];
	uint32_t rows, cols;
	uint32_t size[3];
	uint32_t bricks[3];
	uint32_t first_brick;
	uint8_t *weave;           /* rows*cols */
	uint32_t n_yarns;
	loom_db_yarn *yarns;      /* n_yarns + 1 */
	uint32_t n_sym;
	uint16_t *sym;            /* 2*n_sym */
	uint8_t *blocks;          /* rows*cols encoded block entries */
	uint64_t raw_bytes, stored_bytes;
	uint8_t fibre[2];         /* material pair tag */
} dbw_exemplar;

struct loom__dbw {
	loom__atomic out;
	loom__dbw_params p;
	size_t brick_voxels, brick_bytes;
	size_t entry_bytes;         /* brick index entry of the layout */
	uint64_t pos;               /* bytes written so far */
	uint8_t hdr[LOOM__DB_HEADER_BYTES]; /* the header as written */
	dbw_exemplar *ex;           /* p.n_exemplars */
	uint32_t n_begun;           /* exemplars begun */
	uint32_t n_bricks;          /* bricks put (all exemplars) */
	uint8_t *index;             /* n_bricks * 24, capacity cap_index */
	size_t cap_index;
	uint32_t n_copied;          /* exemplars copied by loom__dbw_append */
	/* current exemplar */
	uint32_t cur_put;           /* bricks of it put so far */
	uint32_t cur_total;
	int16_t *top;               /* ring: ring_rows*size_x, -1 = no surface */
	uint8_t *top_label;         /* voxel row y is ring row y % ring_rows */
	uint32_t ring_rows;         /* b2 + brick[1] */
	uint32_t next_row;          /* first block row without its tables */
	uint8_t solid[256];
	/* writer-thread encoding */
	struct libdeflate_compressor *comp;
	uint8_t *cbuf;
	int16_t *btop;
	uint8_t *blabel;
	float *prof;                /* 2 (b1 + b2): one block's edge profiles */
	int failed;
};

static int wr(loom__dbw *w, const void *data, size_t n, loom_diag *diag)
{
	if (n && fwrite(data, 1, n, w->out.fp) != n) {
		w->failed = 1;
		return loom__fail(diag, LOOM_EIO, "%s: write failed at offset %llu",
		                  w->out.path, (unsigned long long)w->pos);
	}
	w->pos += n;
	return LOOM_OK;
}

static uint32_t div_up(uint32_t a, uint32_t b)
{
	return (a + b - 1) / b;
}

uint8_t loom__weave_code(const uint8_t *weave, uint32_t rows, uint32_t cols,
                         uint32_t r, uint32_t c)
{
	uint32_t rn = (r + rows - 1) % rows, rs = (r + 1) % rows;
	uint32_t cw = (c + cols - 1) % cols, ce = (c + 1) % cols;
	uint8_t code = 0;

	if (weave[(size_t)r * cols + c])
		code |= LOOM_DB_CODE_SELF;
	if (weave[(size_t)rn * cols + c])
		code |= LOOM_DB_CODE_N;
	if (weave[(size_t)rs * cols + c])
		code |= LOOM_DB_CODE_S;
	if (weave[(size_t)r * cols + cw])
		code |= LOOM_DB_CODE_W;
	if (weave[(size_t)r * cols + ce])
		code |= LOOM_DB_CODE_E;
	return code;
}

uint32_t loom__weave_symmetries(const uint8_t *weave, uint32_t rows,
                                uint32_t cols, uint16_t *out)
{
	uint32_t n = 0;

	for (uint32_t dy = 0; dy < rows; dy++)
		for (uint32_t dx = 0; dx < cols; dx++) {
			int ok = 1;
			for (uint32_t r = 0; r < rows && ok; r++)
				for (uint32_t c = 0; c < cols; c++)
					if (weave[(size_t)((r + dy) % rows) * cols + (c + dx) % cols] !=
					    weave[(size_t)r * cols + c]) {
						ok = 0;
						break;
					}
			if (ok) {
				out[2 * n] = (uint16_t)dx;
				out[2 * n + 1] = (uint16_t)dy;
				n++;
			}
		}
	return n;
}

int loom__dbw_create(const char *path, const loom__dbw_params *p,
                     loom__dbw **out, loom_diag *diag)
{
	loom__dbw *w;
	uint8_t *h;
	int rc;

	*out = NULL;
	if (!path || !p)
		return loom__fail(diag, LOOM_EINVAL, "database writer: NULL argument");
	if (p->n_exemplars < 1 || p->n_exemplars > LOOM__DB_MAX_EXEMPLARS)
		return loom__fail(diag, LOOM_EINVAL, "%s: %u exemplars (expected 1..%u)",
		                  path, p->n_exemplars, LOOM__DB_MAX_EXEMPLARS);
	for (int a = 0; a < 3; a++) {
		if (p->block[a] < 1 || p->block[a] > LOOM__DB_MAX_BLOCK)
			return loom__fail(diag, LOOM_EINVAL, "%s: block size %u on axis %d "
			                  "(expected 1..%u)", path, p->block[a], a,
			                  LOOM__DB_MAX_BLOCK);
		if (p->brick[a] < 1 || p->brick[a] > LOOM__DB_MAX_BRICK)
			return loom__fail(diag, LOOM_EINVAL, "%s: brick size %u on axis %d "
			                  "(expected 1..%u)", path, p->brick[a], a,
			                  LOOM__DB_MAX_BRICK);
	}
	if ((uint64_t)p->brick[0] * p->brick[1] * p->brick[2] * LOOM__VOXEL_PLANES >
	    LOOM__DB_MAX_BRICK_BYTES)
		return loom__fail(diag, LOOM_EINVAL, "%s: brick %ux%ux%u is larger than "
		                  "%u bytes", path, p->brick[0], p->brick[1], p->brick[2],
		                  LOOM__DB_MAX_BRICK_BYTES);
	if (p->level < 1 || p->level > 12)
		return loom__fail(diag, LOOM_EINVAL, "%s: deflate level %d (expected 1..12)",
		                  path, p->level);
	if (!(p->voxel_size_um > 0.0f) || !(p->voxel_size_um < 1e6f))
		return loom__fail(diag, LOOM_EINVAL, "%s: voxel size %g um", path,
		                  (double)p->voxel_size_um);
	w = calloc(1, sizeof *w);
	if (!w)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	w->p = *p;
	if (w->p.layout < LOOM__DB_LAYOUT_PLANES || w->p.layout > LOOM__DB_LAYOUT_ZRUN)
		w->p.layout = LOOM__DB_VERSION_DEFAULT;
	w->entry_bytes = w->p.layout == LOOM__DB_LAYOUT_PLANES ? LOOM__DB_INDEX_BYTES :
	                                                         LOOM__DB_INDEX2_BYTES;
	w->brick_voxels = (size_t)p->brick[0] * p->brick[1] * p->brick[2];
	w->brick_bytes = w->brick_voxels * LOOM__VOXEL_PLANES;
	w->ex = calloc(p->n_exemplars, sizeof *w->ex);
	w->comp = libdeflate_alloc_compressor(p->level);
	w->cbuf = malloc(w->brick_bytes);
	w->btop = malloc((size_t)p->brick[0] * p->brick[1] * sizeof *w->btop);
	w->blabel = malloc((size_t)p->brick[0] * p->brick[1]);
	w->prof = malloc(sizeof(float) * 2 * ((size_t)p->block[0] + p->block[1]));
	if (!w->ex || !w->comp || !w->cbuf || !w->btop || !w->blabel || !w->prof) {
		loom__dbw_abort(w);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	rc = loom__atomic_open(&w->out, path, diag);
	if (rc) {
		loom__dbw_abort(w);
		return rc;
	}
	h = w->hdr;
	memcpy(h, LOOM__DB_MAGIC, 8);
	loom__put32(h + 8, w->p.layout); /* the version is the layout */
	loom__put32(h + 12, LOOM__DB_HEADER_BYTES);
	loom__put32(h + 16, p->n_exemplars);
	loom__put32(h + 20, p->block[0]);
	loom__put32(h + 24, p->block[1]);
	loom__put32(h + 28, p->block[2]);
	loom__put32(h + 32, p->brick[0]);
	loom__put32(h + 36, p->brick[1]);
	loom__put32(h + 40, p->brick[2]);
	loom__put32(h + 44, w->p.layout);
	loom__putf32(h + 48, p->voxel_size_um);
	loom__put32(h + 52, p->top_threshold);
	loom__put32(h + 56, (uint32_t)p->level);
	loom__put32(h + 60, p->flags);
	loom__put64(h + 64, p->seed);
	loom__put32(h + 124, libdeflate_crc32(0, h, 124));
	rc = wr(w, h, LOOM__DB_HEADER_BYTES, diag);
	if (rc) {
		loom__dbw_abort(w);
		return rc;
	}
	*out = w;
	return LOOM_OK;
}

/* ---- block tables ---------------------------------------------------------- */

/* Fill the gaps (NaN) of a profile: linear between known samples, constant
   past the ends, `fallback` if no sample is known. */
static void fill_profile(float *v, uint32_t n, float fallback)
{
	int64_t last = -1;

	for (uint32_t i = 0; i < n; i++) {
		if (v[i] != v[i])
			continue;
		if (last < 0) {
			for (uint32_t k = 0; k < i; k++)
				v[k] = v[i];
		} else if ((int64_t)i > last + 1) {
			float a = v[last], b = v[i];
			for (int64_t k = last + 1; k < (int64_t)i; k++)
				v[k] = a + (b - a) * (float)(k - last) / (float)((int64_t)i - last);
		}
		last = i;
	}
	if (last < 0) {
		for (uint32_t k = 0; k < n; k++)
			v[k] = fallback;
		return;
	}
	for (uint32_t k = (uint32_t)last + 1; k < n; k++)
		v[k] = v[last];
}

/* Height of column (x, y) of the current exemplar, NaN for a gap. */
static size_t ring_at(const loom__dbw *w, const dbw_exemplar *e, uint32_t x, uint32_t y)
{
	return (size_t)(y % w->ring_rows) * e->size[0] + x;
}

static float col_h(const loom__dbw *w, const dbw_exemplar *e, uint32_t x, uint32_t y)
{
	int16_t t = w->top[ring_at(w, e, x, y)];
	return t < 0 ? (float)NAN : (float)t + 1.0f;
}

/* The block tables of block row r of the current exemplar, from the height
   map (its rows r*b2 .. r*b2+b2-1 must be in the ring). */
static void block_row(loom__dbw *w, uint32_t r)
{
	dbw_exemplar *e = &w->ex[w->n_begun - 1];
	uint32_t b1 = w->p.block[0], b2 = w->p.block[1];
	size_t esz = loom__db_block_entry_bytes(b1, b2);
	float *prof = w->prof;

	for (uint32_t c = 0; c < e->cols; c++) {
		uint8_t *b = e->blocks + ((size_t)r * e->cols + c) * esz;
		uint32_t x0 = c * b1, y0 = r * b2;
		double sum = 0, sdx = 0, sdy = 0;
		uint64_t nv = 0, ndx = 0, ndy = 0;
		uint32_t gaps = 0;
		float mean;
		float *pn = prof, *ps = prof + b1, *pw = prof + 2 * b1, *pe = pw + b2;
		uint8_t clab;

		for (uint32_t y = y0; y < y0 + b2; y++)
			for (uint32_t x = x0; x < x0 + b1; x++) {
				float h = col_h(w, e, x, y);
				if (h != h) {
					gaps++;
					continue;
				}
				sum += h;
				nv++;
				if (x + 1 < x0 + b1) {
					float h2 = col_h(w, e, x + 1, y);
					if (h2 == h2) {
						sdx += h2 > h ? h2 - h : h - h2;
						ndx++;
					}
				}
				if (y + 1 < y0 + b2) {
					float h2 = col_h(w, e, x, y + 1);
					if (h2 == h2) {
						sdy += h2 > h ? h2 - h : h - h2;
						ndy++;
					}
				}
			}
		mean = nv ? (float)(sum / (double)nv) : 0.0f;
		for (uint32_t i = 0; i < b1; i++) {
			pn[i] = col_h(w, e, x0 + i, y0);
			ps[i] = col_h(w, e, x0 + i, y0 + b2 - 1);
		}
		for (uint32_t i = 0; i < b2; i++) {
			pw[i] = col_h(w, e, x0, y0 + i);
			pe[i] = col_h(w, e, x0 + b1 - 1, y0 + i);
		}
		fill_profile(pn, b1, mean);
		fill_profile(ps, b1, mean);
		fill_profile(pw, b2, mean);
		fill_profile(pe, b2, mean);
		clab = w->top_label[ring_at(w, e, x0 + b1 / 2, y0 + b2 / 2)];
		b[0] = loom__weave_code(e->weave, e->rows, e->cols, r, c);
		b[1] = clab <= e->n_yarns ? e->yarns[clab].kind : 0;
		loom__put16(b + 2, (uint16_t)(gaps > 65535 ? 65535 : gaps));
		loom__putf32(b + 4, ndx ? (float)(sdx / (double)ndx) : 0.0f);
		loom__putf32(b + 8, ndy ? (float)(sdy / (double)ndy) : 0.0f);
		loom__putf32(b + 12, mean);
		for (size_t i = 0; i < 2 * ((size_t)b1 + b2); i++)
			loom__putf32(b + 16 + 4 * i, prof[i]);
	}
}

/* Block tables of every block row whose voxel rows are all below `done`. */
static void block_rows_upto(loom__dbw *w, uint32_t done)
{
	dbw_exemplar *e = &w->ex[w->n_begun - 1];
	while (w->next_row < e->rows && (w->next_row + 1) * w->p.block[1] <= done)
		block_row(w, w->next_row++);
}

static int finish_exemplar(loom__dbw *w, loom_diag *diag)
{
	dbw_exemplar *e = &w->ex[w->n_begun - 1];

	if (w->cur_put != w->cur_total)
		return loom__fail(diag, LOOM_EINVAL, "%s: exemplar %u '%s' has %u of %u "
		                  "bricks", w->out.path, w->n_begun - 1, e->name,
		                  w->cur_put, w->cur_total);
	block_rows_upto(w, e->size[1]); /* done already: the last brick row did it */
	free(w->top);
	free(w->top_label);
	w->top = NULL;
	w->top_label = NULL;
	return LOOM_OK;
}

int loom__dbw_begin_exemplar(loom__dbw *w, const loom__dbw_exemplar *d,
                             loom_diag *diag)
{
	dbw_exemplar *e;
	size_t ncol;
	int rc;

	if (w->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: writer failed earlier",
		                  w->out.path);
	if (w->n_begun > w->n_copied && (rc = finish_exemplar(w, diag)) != LOOM_OK)
		return w->failed = 1, rc;
	if (w->n_begun >= w->p.n_exemplars)
		return loom__fail(diag, LOOM_EINVAL, "%s: more than the %u exemplars "
		                  "announced", w->out.path, w->p.n_exemplars);
	if (!d->name || strlen(d->name) >= 32 || !d->name[0] ||
	    (d->weave_name && strlen(d->weave_name) >= 32))
		return loom__fail(diag, LOOM_EINVAL, "%s: exemplar name missing or "
		                  "longer than 31 bytes", w->out.path);
	if (d->fibre[0] >= LOOM_FIBRE_COUNT_ || d->fibre[1] >= LOOM_FIBRE_COUNT_ ||
	    (d->fibre[0] == 0) != (d->fibre[1] == 0))
		return loom__fail(diag, LOOM_EINVAL, "%s: exemplar '%s': material tag %u "
		                  "%u (expected two codes 1..%d or 0 0)", w->out.path,
		                  d->name, d->fibre[0], d->fibre[1], LOOM_FIBRE_COUNT_ - 1);
	if (d->rows < 1 || d->cols < 1 || d->rows > LOOM__DB_MAX_CROSSINGS ||
	    d->cols > LOOM__DB_MAX_CROSSINGS || !d->weave)
		return loom__fail(diag, LOOM_EINVAL, "%s: exemplar '%s': %ux%u crossings "
		                  "(expected 1..%u each)", w->out.path, d->name, d->rows,
		                  d->cols, LOOM__DB_MAX_CROSSINGS);
	if (d->n_yarns > 255 || !d->yarns)
		return loom__fail(diag, LOOM_EINVAL, "%s: exemplar '%s': %u yarn labels "
		                  "(at most 255)", w->out.path, d->name, d->n_yarns);
	for (uint32_t l = 1; l <= d->n_yarns; l++) {
		/* what readers accept (docs/formats.md, yarn table) */
		const loom_db_yarn *y = &d->yarns[l];
		int32_t lim = y->kind == LOOM_YARN_WARP ? (int32_t)d->cols : (int32_t)d->rows;
		if (y->kind > LOOM_YARN_WEFT || y->flags > 3 ||
		    (y->kind == LOOM_YARN_NONE ? (y->index != 0 || y->flags != 0)
		     : (y->flags & LOOM_DB_YARN_OUTSIDE) ? (y->index != -1 && y->index != lim)
		     : (y->flags & LOOM_DB_YARN_FLYAWAY) ? (y->index < -1 || y->index > lim)
		                                         : (y->index < 0 || y->index >= lim)))
			return loom__fail(diag, LOOM_EINVAL, "%s: exemplar '%s': yarn label %u: "
			                  "kind %u, flags %u, index %d out of range", w->out.path,
			                  d->name, l, y->kind, y->flags, (int)y->index);
	}
	if ((uint64_t)d->cols * w->p.block[0] > LOOM__DB_MAX_EXTENT ||
	    (uint64_t)d->rows * w->p.block[1] > LOOM__DB_MAX_EXTENT)
		return loom__fail(diag, LOOM_EINVAL, "%s: exemplar '%s' larger than %u "
		                  "voxels along x or y", w->out.path, d->name,
		                  LOOM__DB_MAX_EXTENT);
	e = &w->ex[w->n_begun];
	snprintf(e->name, sizeof e->name, "%s", d->name);
	snprintf(e->weave_name, sizeof e->weave_name, "%s",
	         d->weave_name ? d->weave_name : "");
	e->rows = d->rows;
	e->cols = d->cols;
	e->fibre[0] = d->fibre[0];
	e->fibre[1] = d->fibre[1];
	e->size[0] = d->cols * w->p.block[0];
	e->size[1] = d->rows * w->p.block[1];
	e->size[2] = w->p.block[2];
	for (int a = 0; a < 3; a++)
		e->bricks[a] = div_up(e->size[a], w->p.brick[a]);
	if ((uint64_t)w->n_bricks + (uint64_t)e->bricks[0] * e->bricks[1] * e->bricks[2] >
	    0x7fffffffu)
		return loom__fail(diag, LOOM_EINVAL, "%s: too many bricks", w->out.path);
	e->first_brick = w->n_bricks;
	e->raw_bytes = (uint64_t)e->size[0] * e->size[1] * e->size[2] * LOOM__VOXEL_PLANES;
	e->n_yarns = d->n_yarns;
	e->weave = malloc((size_t)d->rows * d->cols);
	e->yarns = calloc(d->n_yarns + 1, sizeof *e->yarns);
	e->sym = malloc(sizeof(uint16_t) * 2 * (size_t)d->rows * d->cols);
	ncol = (size_t)e->size[0] * e->size[1];
	w->ring_rows = w->p.block[1] + w->p.brick[1];
	if (w->ring_rows > e->size[1])
		w->ring_rows = e->size[1];
	ncol = (size_t)e->size[0] * w->ring_rows;
	w->next_row = 0;
	w->top = malloc(ncol * sizeof *w->top);
	w->top_label = calloc(ncol, 1);
	e->blocks = calloc((size_t)d->rows * d->cols,
	                   loom__db_block_entry_bytes(w->p.block[0], w->p.block[1]));
	if (!e->weave || !e->yarns || !e->sym || !w->top || !w->top_label || !e->blocks) {
		w->failed = 1;
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", w->out.path);
	}
	w->n_begun++;
	memcpy(e->weave, d->weave, (size_t)d->rows * d->cols);
	for (size_t i = 0; i < (size_t)d->rows * d->cols; i++)
		e->weave[i] = e->weave[i] ? 1 : 0;
	memcpy(e->yarns, d->yarns, (d->n_yarns + 1) * sizeof *e->yarns);
	memset(&e->yarns[0], 0, sizeof e->yarns[0]);
	e->n_sym = loom__weave_symmetries(e->weave, e->rows, e->cols, e->sym);
	for (size_t i = 0; i < ncol; i++)
		w->top[i] = -1;
	loom__db_solid_lut(e->yarns, e->n_yarns, w->solid);
	w->cur_put = 0;
	w->cur_total = e->bricks[0] * e->bricks[1] * e->bricks[2];
	return LOOM_OK;
}

const uint8_t *loom__dbw_solid(const loom__dbw *w)
{
	return w->solid;
}

unsigned loom__dbw_layout(const loom__dbw *w)
{
	return w->p.layout;
}

/* Layout 3's density unit (docs/formats.md, "Segmented density units"):
   the segment header and the eight segments at c (room for 32 + V
   bytes); its size, or 0 when that is not below V (the caller stores the
   plane raw). */
static size_t encode_segs(const uint8_t *pl, const uint32_t brick[3], size_t nv,
                          struct libdeflate_compressor *comp, uint8_t *c)
{
	size_t at = LOOM__DB_SEG_HEADER, lo, len, n, i;

	if (nv <= LOOM__DB_SEG_HEADER)
		return 0;
	for (unsigned q = 0; q < LOOM__DB_SEGS; q++) {
		loom__db_seg_range(brick, LOOM__DB_SEGS, q, &lo, &len);
		for (i = 0; i < len && pl[lo + i] == 0; i++)
			;
		n = 0;
		if (i < len) {
			n = len > 1 ? libdeflate_deflate_compress(comp, pl + lo, len, c + at,
			                                          len - 1) : 0;
			if (n == 0) {
				memcpy(c + at, pl + lo, len);
				n = len;
			}
		}
		loom__put32(c + 4 * q, (uint32_t)n);
		at += n;
	}
	return at < nv ? at : 0;
}

/* Layouts 2, 3 and 4: each of the four planes as a unit of its own, back
   to back in cbuf (4V bytes: every unit is at most V; the density unit,
   the first, may use V + 32 while it is encoded). */
static void encode_units(const uint8_t *raw, const uint32_t brick[3], unsigned layout,
                         struct libdeflate_compressor *comp, uint8_t *cbuf,
                         loom__dbw_brick *out)
{
	size_t nv = (size_t)brick[0] * brick[1] * brick[2];
	size_t at = 0;
	int draw = (layout & LOOM__DBW_DENSITY_RAW) != 0;

	layout &= ~LOOM__DBW_DENSITY_RAW;
	for (unsigned u = 0; u < LOOM__DB_UNITS; u++) {
		const uint8_t *pl = raw + u * nv;
		size_t n = 0, i = 0;
		while (i < nv && pl[i] == 0)
			i++;
		if (i < nv && u == 0 && draw) {
			memcpy(cbuf + at, pl, nv); /* raw: the reader's copy, no inflate */
			n = nv;
		} else if (i < nv && u == 0 && layout == LOOM__DB_LAYOUT_SEGS) {
			n = encode_segs(pl, brick, nv, comp, cbuf + at);
			if (n == 0) {
				memcpy(cbuf + at, pl, nv);
				n = nv;
			}
		} else if (i < nv && u == 0 && layout == LOOM__DB_LAYOUT_ZRUN) {
			n = loom__zrun_encode(pl, nv, cbuf + at, nv - 1);
			if (n == 0) {
				memcpy(cbuf + at, pl, nv);
				n = nv;
			}
		} else if (i < nv) {
			n = nv > 1 ? libdeflate_deflate_compress(comp, pl, nv, cbuf + at,
			                                         nv - 1) : 0;
			if (n == 0) {
				memcpy(cbuf + at, pl, nv);
				n = nv;
			}
		}
		out->unit_bytes[u] = (uint32_t)n;
		out->unit_crc[u] = n ? libdeflate_crc32(0, cbuf + at, n) : 0;
		at += n;
	}
	out->storage = LOOM__DB_STORE_DEFLATE;
	out->stored_bytes = (uint32_t)at;
	out->data = cbuf;
	out->crc = 0;
}

void loom__dbw_encode(const uint8_t *raw, const uint32_t brick[3],
                      const uint8_t solid[256], uint8_t threshold,
                      unsigned layout, struct libdeflate_compressor *comp,
                      uint8_t *cbuf, loom__dbw_brick *out)
{
	size_t nv = (size_t)brick[0] * brick[1] * brick[2];
	size_t nb = nv * LOOM__VOXEL_PLANES, ncol = (size_t)brick[0] * brick[1];
	const uint8_t *dens = raw, *lab = raw + 3 * nv;
	size_t csize;
	int any = 0;

	for (size_t i = 0; i < nb; i++)
		if (raw[i]) {
			any = 1;
			break;
		}
	for (size_t col = 0; col < ncol; col++) {
		out->top[col] = -1;
		out->top_label[col] = 0;
	}
	memset(out->unit_bytes, 0, sizeof out->unit_bytes);
	memset(out->unit_crc, 0, sizeof out->unit_crc);
	if (!any) {
		out->storage = LOOM__DB_STORE_EMPTY;
		out->stored_bytes = 0;
		out->crc = 0;
		out->data = NULL;
		return;
	}
	for (size_t col = 0; col < ncol; col++) {
		size_t base = col * brick[2];
		for (uint32_t z = brick[2]; z-- > 0;)
			if (solid[lab[base + z]] && dens[base + z] >= threshold) {
				out->top[col] = (int16_t)z;
				out->top_label[col] = lab[base + z];
				break;
			}
	}
	if ((layout & ~LOOM__DBW_DENSITY_RAW) != LOOM__DB_LAYOUT_PLANES) {
		encode_units(raw, brick, layout, comp, cbuf, out);
		return;
	}
	csize = libdeflate_deflate_compress(comp, raw, nb, cbuf, nb - 1);
	if (csize == 0) {
		out->storage = LOOM__DB_STORE_RAW;
		out->stored_bytes = (uint32_t)nb;
		out->data = raw;
	} else {
		out->storage = LOOM__DB_STORE_DEFLATE;
		out->stored_bytes = (uint32_t)csize;
		out->data = cbuf;
	}
	out->crc = libdeflate_crc32(0, out->data, out->stored_bytes);
}

int loom__dbw_put(loom__dbw *w, const loom__dbw_brick *b, loom_diag *diag)
{
	dbw_exemplar *e;
	uint32_t local, bx, by, bz;
	uint8_t *ent;
	int rc;

	if (w->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: writer failed earlier",
		                  w->out.path);
	if (!w->n_begun || w->cur_put >= w->cur_total)
		return loom__fail(diag, LOOM_EINVAL, "%s: brick outside any exemplar",
		                  w->out.path);
	e = &w->ex[w->n_begun - 1];
	if (w->n_bricks == w->cap_index) {
		size_t nc = w->cap_index ? 2 * w->cap_index : 1024;
		uint8_t *ni = realloc(w->index, nc * w->entry_bytes);
		if (!ni) {
			w->failed = 1;
			return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", w->out.path);
		}
		w->index = ni;
		w->cap_index = nc;
	}
	ent = w->index + (size_t)w->n_bricks * w->entry_bytes;
	memset(ent, 0, w->entry_bytes);
	if (b->storage != LOOM__DB_STORE_EMPTY) {
		loom__put64(ent, w->pos);
		loom__put32(ent + 8, b->stored_bytes);
		loom__put32(ent + 16, b->crc);
		rc = wr(w, b->data, b->stored_bytes, diag);
		if (rc)
			return rc;
		e->stored_bytes += b->stored_bytes;
	}
	loom__put32(ent + 12, (uint32_t)w->brick_bytes);
	ent[20] = b->storage;
	if (w->entry_bytes == LOOM__DB_INDEX2_BYTES)
		for (unsigned u = 0; u < LOOM__DB_UNITS; u++) {
			loom__put32(ent + 24 + 8 * u, b->unit_bytes[u]);
			loom__put32(ent + 28 + 8 * u, b->unit_crc[u]);
		}
	/* merge the column tops into the exemplar's height map */
	local = w->cur_put;
	bz = local % e->bricks[2];
	bx = (local / e->bricks[2]) % e->bricks[0];
	by = local / e->bricks[2] / e->bricks[0];
	if (bx == 0 && bz == 0) { /* a new brick row: its ring rows start empty */
		for (uint32_t ly = 0; ly < w->p.brick[1]; ly++) {
			uint32_t y = by * w->p.brick[1] + ly;
			if (y >= e->size[1])
				break;
			memset(w->top_label + ring_at(w, e, 0, y), 0, e->size[0]);
			for (uint32_t x = 0; x < e->size[0]; x++)
				w->top[ring_at(w, e, x, y)] = -1;
		}
	}
	if (b->storage != LOOM__DB_STORE_EMPTY)
		for (uint32_t ly = 0; ly < w->p.brick[1]; ly++) {
			uint32_t y = by * w->p.brick[1] + ly;
			if (y >= e->size[1])
				break;
			for (uint32_t lx = 0; lx < w->p.brick[0]; lx++) {
				uint32_t x = bx * w->p.brick[0] + lx;
				size_t col = (size_t)ly * w->p.brick[0] + lx, m;
				int32_t z;
				if (x >= e->size[0])
					break;
				if (b->top[col] < 0)
					continue;
				z = (int32_t)(bz * w->p.brick[2]) + b->top[col];
				if (z >= (int32_t)e->size[2])
					continue;
				m = ring_at(w, e, x, y);
				if (z > w->top[m]) {
					w->top[m] = (int16_t)z;
					w->top_label[m] = b->top_label[col];
				}
			}
		}
	w->n_bricks++;
	w->cur_put++;
	if (w->cur_put % (e->bricks[0] * e->bricks[2]) == 0) /* brick row done */
		block_rows_upto(w, (by + 1) * w->p.brick[1] < e->size[1] ?
		                   (by + 1) * w->p.brick[1] : e->size[1]);
	return LOOM_OK;
}

int loom__dbw_add_brick(loom__dbw *w, const uint8_t *raw, loom_diag *diag)
{
	loom__dbw_brick b;

	b.top = w->btop;
	b.top_label = w->blabel;
	loom__dbw_encode(raw, w->p.brick, w->solid, w->p.top_threshold,
	                 w->p.layout | (w->p.density_raw ? LOOM__DBW_DENSITY_RAW : 0), w->comp,
	                 w->cbuf, &b);
	return loom__dbw_put(w, &b, diag);
}

static size_t pad8(size_t n)
{
	return (n + 7) & ~(size_t)7;
}

/* Build the metadata blob (docs/formats.md, "Metadata"). */
static uint8_t *build_metadata(loom__dbw *w, size_t *len)
{
	size_t esz = loom__db_block_entry_bytes(w->p.block[0], w->p.block[1]);
	size_t off = LOOM__DB_META_HEADER_BYTES +
	             (size_t)w->p.n_exemplars * LOOM__DB_EXEMPLAR_BYTES;
	size_t *wo = calloc(w->p.n_exemplars * 4, sizeof *wo), index_off;
	uint8_t *m;

	if (!wo)
		return NULL;
	for (uint32_t k = 0; k < w->p.n_exemplars; k++) {
		dbw_exemplar *e = &w->ex[k];
		wo[4 * k] = off;
		off += pad8((size_t)e->rows * e->cols);
		wo[4 * k + 1] = off;
		off += pad8((size_t)(e->n_yarns + 1) * 4);
		wo[4 * k + 2] = off;
		off += pad8((size_t)e->n_sym * 4);
		wo[4 * k + 3] = off;
		off += pad8((size_t)e->rows * e->cols * esz);
	}
	index_off = off;
	off += (size_t)w->n_bricks * w->entry_bytes;
	m = calloc(1, off);
	if (!m) {
		free(wo);
		return NULL;
	}
	memcpy(m, LOOM__DB_META_MAGIC, 8);
	loom__put32(m + 8, w->p.n_exemplars);
	loom__put32(m + 12, LOOM__DB_EXEMPLAR_BYTES);
	loom__put32(m + 16, w->n_bricks);
	loom__put32(m + 20, (uint32_t)w->entry_bytes);
	loom__put32(m + 24, (uint32_t)esz);
	loom__put64(m + 32, LOOM__DB_META_HEADER_BYTES);
	loom__put64(m + 40, index_off);
	for (uint32_t k = 0; k < w->p.n_exemplars; k++) {
		dbw_exemplar *e = &w->ex[k];
		uint8_t *x = m + LOOM__DB_META_HEADER_BYTES + (size_t)k * LOOM__DB_EXEMPLAR_BYTES;
		memcpy(x, e->name, strlen(e->name));
		memcpy(x + 32, e->weave_name, strlen(e->weave_name));
		loom__put32(x + 64, e->rows);
		loom__put32(x + 68, e->cols);
		for (int a = 0; a < 3; a++) {
			loom__put32(x + 72 + 4 * a, e->size[a]);
			loom__put32(x + 84 + 4 * a, w->p.block[a]);
			loom__put32(x + 100 + 4 * a, e->bricks[a]);
		}
		loom__putf32(x + 96, w->p.voxel_size_um);
		loom__put32(x + 112, e->first_brick);
		loom__put32(x + 116, e->n_yarns);
		loom__put32(x + 120, e->n_sym);
		loom__put64(x + 128, wo[4 * k]);
		loom__put64(x + 136, wo[4 * k + 1]);
		loom__put64(x + 144, wo[4 * k + 2]);
		loom__put64(x + 152, wo[4 * k + 3]);
		loom__put64(x + 160, e->raw_bytes);
		loom__put64(x + 168, e->stored_bytes);
		x[176] = e->fibre[0];
		x[177] = e->fibre[1];
		memcpy(m + wo[4 * k], e->weave, (size_t)e->rows * e->cols);
		for (uint32_t l = 0; l <= e->n_yarns; l++) {
			uint8_t *y = m + wo[4 * k + 1] + 4 * (size_t)l;
			y[0] = e->yarns[l].kind;
			y[1] = e->yarns[l].flags;
			loom__put16(y + 2, (uint16_t)e->yarns[l].index);
		}
		for (uint32_t s = 0; s < e->n_sym; s++) {
			loom__put16(m + wo[4 * k + 2] + 4 * (size_t)s, e->sym[2 * s]);
			loom__put16(m + wo[4 * k + 2] + 4 * (size_t)s + 2, e->sym[2 * s + 1]);
		}
		memcpy(m + wo[4 * k + 3], e->blocks, (size_t)e->rows * e->cols * esz);
	}
	memcpy(m + index_off, w->index, (size_t)w->n_bricks * w->entry_bytes);
	free(wo);
	*len = off;
	return m;
}

int loom__dbw_finish(loom__dbw *w, uint64_t *hash, loom_diag *diag)
{
	static const uint8_t zeros[8];
	uint8_t t[LOOM__DB_TRAILER_BYTES];
	uint8_t *meta = NULL;
	size_t meta_len = 0;
	uint64_t meta_off, h;
	int rc;

	if (w->failed) {
		loom__dbw_abort(w);
		return loom__fail(diag, LOOM_EUNUSABLE, "writer failed earlier");
	}
	if (w->n_begun != w->p.n_exemplars) {
		rc = loom__fail(diag, LOOM_EINVAL, "%s: %u of %u exemplars written",
		                w->out.path, w->n_begun, w->p.n_exemplars);
		loom__dbw_abort(w);
		return rc;
	}
	rc = w->n_begun > w->n_copied ? finish_exemplar(w, diag) : LOOM_OK;
	if (rc) {
		loom__dbw_abort(w);
		return rc;
	}
	rc = wr(w, zeros, pad8(w->pos) - w->pos, diag);
	meta_off = w->pos;
	if (!rc) {
		meta = build_metadata(w, &meta_len);
		if (!meta)
			rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", w->out.path);
	}
	if (!rc)
		rc = wr(w, meta, meta_len, diag);
	if (rc) {
		free(meta);
		loom__dbw_abort(w);
		return rc;
	}
	h = loom__fnv1a64(LOOM__FNV_OFFSET, w->hdr, LOOM__DB_HEADER_BYTES);
	h = loom__fnv1a64(h, meta, meta_len);
	memset(t, 0, sizeof t);
	memcpy(t, LOOM__DB_TRAILER_MAGIC, 8);
	loom__put64(t + 8, meta_off);
	loom__put64(t + 16, meta_len);
	loom__put32(t + 24, libdeflate_crc32(0, meta, meta_len));
	loom__put32(t + 28, w->n_bricks);
	loom__put64(t + 32, meta_off + meta_len + LOOM__DB_TRAILER_BYTES);
	loom__put64(t + 40, h);
	loom__put32(t + 60, libdeflate_crc32(0, t, 60));
	free(meta);
	rc = wr(w, t, sizeof t, diag);
	if (rc) {
		loom__dbw_abort(w);
		return rc;
	}
	rc = loom__atomic_commit(&w->out, diag);
	if (rc) {
		loom__dbw_abort(w);
		return rc;
	}
	if (hash)
		*hash = h;
	loom__dbw_abort(w); /* frees; the temporary is already renamed */
	return LOOM_OK;
}

void loom__dbw_abort(loom__dbw *w)
{
	if (!w)
		return;
	if (w->out.fp || w->out.tmp_path)
		loom__atomic_abort(&w->out);
	if (w->ex)
		for (uint32_t k = 0; k < w->p.n_exemplars; k++) {
			free(w->ex[k].weave);
			free(w->ex[k].yarns);
			free(w->ex[k].sym);
			free(w->ex[k].blocks);
		}
	free(w->ex);
	free(w->index);
	free(w->top);
	free(w->top_label);
	if (w->comp)
		libdeflate_free_compressor(w->comp);
	free(w->cbuf);
	free(w->btop);
	free(w->blabel);
	free(w->prof);
	free(w);
}

/* ---- append ---------------------------------------------------------------- */

static int read_exact(FILE *f, void *buf, size_t n, uint64_t off)
{
	if (fseeko(f, (off_t)off, SEEK_SET) != 0)
		return -1;
	return fread(buf, 1, n, f) == n ? 0 : -1;
}

/* Copy old exemplar k's record and sections from the metadata blob m (of
   meta_len bytes, already checked by loom_db_open) into e. */
static int copy_exemplar(const uint8_t *m, size_t meta_len, uint32_t k, size_t esz,
                         dbw_exemplar *e)
{
	const uint8_t *x = m + LOOM__DB_META_HEADER_BYTES + (size_t)k * LOOM__DB_EXEMPLAR_BYTES;
	uint64_t ow = loom__le64(x + 128), oy = loom__le64(x + 136);
	uint64_t os = loom__le64(x + 144), ob = loom__le64(x + 152);
	size_t nw, nb;

	memcpy(e->name, x, 31);
	memcpy(e->weave_name, x + 32, 31);
	e->rows = loom__le32(x + 64);
	e->cols = loom__le32(x + 68);
	for (int a = 0; a < 3; a++) {
		e->size[a] = loom__le32(x + 72 + 4 * a);
		e->bricks[a] = loom__le32(x + 100 + 4 * a);
	}
	e->first_brick = loom__le32(x + 112);
	e->n_yarns = loom__le32(x + 116);
	e->n_sym = loom__le32(x + 120);
	e->raw_bytes = loom__le64(x + 160);
	e->stored_bytes = loom__le64(x + 168);
	e->fibre[0] = x[176];
	e->fibre[1] = x[177];
	nw = (size_t)e->rows * e->cols;
	nb = nw * esz;
	if (ow + nw > meta_len || oy + 4 * ((size_t)e->n_yarns + 1) > meta_len ||
	    os + 4 * (size_t)e->n_sym > meta_len || ob + nb > meta_len ||
	    e->n_yarns > 255 || e->n_sym > nw)
		return -1;
	e->weave = malloc(nw);
	e->yarns = calloc(e->n_yarns + 1, sizeof *e->yarns);
	e->sym = malloc(sizeof(uint16_t) * 2 * (e->n_sym ? e->n_sym : 1));
	e->blocks = malloc(nb);
	if (!e->weave || !e->yarns || !e->sym || !e->blocks)
		return -1;
	memcpy(e->weave, m + ow, nw);
	for (uint32_t l = 0; l <= e->n_yarns; l++) {
		const uint8_t *y = m + oy + 4 * (size_t)l;
		e->yarns[l].kind = y[0];
		e->yarns[l].flags = y[1];
		e->yarns[l].index = (int16_t)loom__le16(y + 2);
	}
	for (uint32_t s = 0; s < e->n_sym; s++) {
		e->sym[2 * s] = loom__le16(m + os + 4 * (size_t)s);
		e->sym[2 * s + 1] = loom__le16(m + os + 4 * (size_t)s + 2);
	}
	memcpy(e->blocks, m + ob, nb);
	return 0;
}

void loom__dbw_params_like(const loom_db_info *info,
                           const uint8_t hdr[LOOM__DB_HEADER_BYTES], loom__dbw_params *p)
{
	memset(p, 0, sizeof *p);
	for (int a = 0; a < 3; a++) {
		p->block[a] = info->block[a];
		p->brick[a] = info->brick[a];
	}
	p->voxel_size_um = info->voxel_size_um;
	p->top_threshold = (uint8_t)info->top_threshold;
	p->level = (int)loom__le32(hdr + 56);
	if (p->level < 1 || p->level > 12)
		p->level = LOOM_DB_DEFAULT_LEVEL;
	p->flags = loom__le32(hdr + 60);
	p->seed = info->seed;
	p->layout = info->voxel_layout;
	/* raw when every stored brick's density plane is (written with
	   density_raw) */
	p->density_raw = info->n_raw_density > 0 &&
	                 info->n_raw_density == info->n_bricks - info->n_empty_bricks;
}

int loom__dbw_append(const char *path, uint32_t n_new, uint32_t clear_flags,
                     loom__dbw **out, loom__dbw_params *old, loom_diag *diag)
{
	loom_db *db = NULL;
	loom_db_info info;
	loom__dbw_params p;
	loom__dbw *w = NULL;
	uint8_t hdr[LOOM__DB_HEADER_BYTES], tr[LOOM__DB_TRAILER_BYTES], *meta = NULL;
	uint8_t *buf = NULL;
	uint64_t meta_off, meta_len, index_off;
	uint32_t n_old, n_bricks;
	size_t esz;
	FILE *f = NULL;
	int rc;

	*out = NULL;
	if (!path || n_new < 1)
		return loom__fail(diag, LOOM_EINVAL, "database append: bad arguments");
	rc = loom_db_open(path, &db, diag); /* checks header, trailer, CRCs */
	if (rc)
		return rc;
	loom_db_get_info(db, &info);
	loom_db_close(db);
	n_old = info.n_exemplars;
	if ((uint64_t)n_old + n_new > LOOM__DB_MAX_EXEMPLARS)
		return loom__fail(diag, LOOM_EINVAL, "%s: %u exemplars plus %u is more "
		                  "than %u", path, n_old, n_new, LOOM__DB_MAX_EXEMPLARS);
	f = fopen(path, "rb");
	if (!f)
		return loom__fail(diag, LOOM_EIO, "%s: cannot open for reading", path);
	if (read_exact(f, hdr, sizeof hdr, 0) ||
	    read_exact(f, tr, sizeof tr, info.file_bytes - LOOM__DB_TRAILER_BYTES)) {
		fclose(f);
		return loom__fail(diag, LOOM_EIO, "%s: read failed", path);
	}
	meta_off = loom__le64(tr + 8);
	meta_len = loom__le64(tr + 16);
	/* an old file keeps its layout and density storage */
	loom__dbw_params_like(&info, hdr, &p);
	p.n_exemplars = n_old + n_new;
	p.flags &= ~clear_flags;
	if (old)
		*old = p;
	meta = malloc(meta_len ? meta_len : 1);
	buf = malloc(1u << 20);
	if (!meta || !buf) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	if (read_exact(f, meta, meta_len, meta_off)) {
		rc = loom__fail(diag, LOOM_EIO, "%s: read failed", path);
		goto done;
	}
	rc = loom__dbw_create(path, &p, &w, diag);
	if (rc)
		goto done;
	/* the brick data, verbatim: every stored brick keeps its offset */
	if (fseeko(f, LOOM__DB_HEADER_BYTES, SEEK_SET) != 0) {
		rc = loom__fail(diag, LOOM_EIO, "%s: seek failed", path);
		goto done;
	}
	for (uint64_t left = meta_off - LOOM__DB_HEADER_BYTES; left > 0;) {
		size_t n = left > (1u << 20) ? (1u << 20) : (size_t)left;
		if (fread(buf, 1, n, f) != n) {
			rc = loom__fail(diag, LOOM_EIO, "%s: read failed", path);
			goto done;
		}
		if ((rc = wr(w, buf, n, diag)) != LOOM_OK)
			goto done;
		left -= n;
	}
	/* tables and index */
	esz = loom__db_block_entry_bytes(p.block[0], p.block[1]);
	n_bricks = loom__le32(meta + 16);
	index_off = loom__le64(meta + 40);
	if (index_off + (uint64_t)n_bricks * w->entry_bytes > meta_len) {
		rc = loom__fail(diag, LOOM_ECORRUPT, "%s: brick index out of range", path);
		goto done;
	}
	for (uint32_t k = 0; k < n_old; k++)
		if (copy_exemplar(meta, meta_len, k, esz, &w->ex[k])) {
			rc = loom__fail(diag, LOOM_ENOMEM, "%s: exemplar %u: out of memory or "
			                "tables out of range", path, k);
			goto done;
		}
	w->cap_index = n_bricks > 1024 ? n_bricks : 1024;
	w->index = malloc(w->cap_index * w->entry_bytes);
	if (!w->index) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	memcpy(w->index, meta + index_off, (size_t)n_bricks * w->entry_bytes);
	w->n_bricks = n_bricks;
	w->n_begun = w->n_copied = n_old;
done:
	free(meta);
	free(buf);
	fclose(f);
	if (rc) {
		loom__dbw_abort(w);
		return rc;
	}
	*out = w;
	return LOOM_OK;
}
