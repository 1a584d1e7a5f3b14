/*
 * io/store/fabric_write.c - the fabric file (.loomf) writer.  Layout and
 * the reader's checks: fabric_read.c; byte by byte: docs/formats.md.
 *
 * Streams every section through one 1 MiB buffer (memory bounded whatever
 * the design size), writes a placeholder section header, then seeks back
 * to fill in sizes and CRC; atomic (loom__atomic_*).
 */
#include "fabric_format.h"
#include "io/core/file.h"

#include <errno.h>
#include <fcntl.h>
#include <libdeflate.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ======================================================================
 * Writer
 * ====================================================================== */

/* Fills buf with raw payload bytes [off, off + n). */
typedef void (*produce_fn)(const void *ctx, uint64_t off, uint8_t *buf, size_t n);

typedef struct fab_writer {
	loom__atomic at;
	const char *path;
	loom_diag *diag;
	uint64_t pos;                       /* bytes written so far */
	struct libdeflate_compressor *comp;
	size_t chunk;                       /* buffer size: FAB_CHUNK or the
	                                       largest section if smaller */
	uint8_t *in;                        /* chunk raw bytes */
	uint8_t *out;                       /* 8 + compress bound */
	size_t out_cap;
} fab_writer;

static int w_bytes(fab_writer *w, const void *p, size_t n)
{
	if (n && fwrite(p, 1, n, w->at.fp) != n)
		return loom__fail(w->diag, LOOM_EIO, "%s: write failed: %s", w->path,
		                  strerror(errno));
	w->pos += n;
	return LOOM_OK;
}

static int write_section(fab_writer *w, unsigned idx, unsigned enc,
                         uint64_t raw_bytes, produce_fn fn, const void *ctx)
{
	uint8_t h[FAB_SECTION_BYTES];
	uint64_t start = w->pos, stored = 0;
	uint32_t crc = 0;
	int rc;

	memset(h, 0, sizeof h);
	rc = w_bytes(w, h, sizeof h);
	for (uint64_t off = 0; !rc && off < raw_bytes; off += FAB_CHUNK) {
		size_t n = raw_bytes - off < FAB_CHUNK ? (size_t)(raw_bytes - off) : FAB_CHUNK;
		fn(ctx, off, w->in, n);
		if (enc == FAB_ENC_RAW) {
			crc = libdeflate_crc32(crc, w->in, n);
			rc = w_bytes(w, w->in, n);
			stored += n;
		} else {
			size_t c = libdeflate_deflate_compress(w->comp, w->in, n, w->out + 8,
			                                       w->out_cap - 8);
			uint32_t kind = FAB_CHUNK_DEFLATE;
			if (c == 0 || c >= n) {
				memcpy(w->out + 8, w->in, n);
				c = n;
				kind = FAB_CHUNK_STORED;
			}
			put32(w->out, (uint32_t)c);
			put32(w->out + 4, kind);
			crc = libdeflate_crc32(crc, w->out, c + 8);
			rc = w_bytes(w, w->out, c + 8);
			stored += c + 8;
		}
	}
	if (rc)
		return rc;
	memcpy(h, fab_tags[idx], 4);
	put32(h + 4, enc);
	put64(h + 8, raw_bytes);
	put64(h + 16, stored);
	put32(h + 24, crc);
	put32(h + 28, libdeflate_crc32(0, h, 28));
	if (fseeko(w->at.fp, (off_t)start, SEEK_SET) != 0 ||
	    fwrite(h, 1, sizeof h, w->at.fp) != sizeof h ||
	    fseeko(w->at.fp, 0, SEEK_END) != 0)
		return loom__fail(w->diag, LOOM_EIO, "%s: write failed: %s", w->path,
		                  strerror(errno));
	return LOOM_OK;
}

/* ---- producers ------------------------------------------------------------ */

typedef struct mem_src {
	const uint8_t *p;
} mem_src;

static void produce_mem(const void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	memcpy(buf, ((const mem_src *)ctx)->p + off, n);
}

static void produce_weave(const void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	const loom_design *d = ctx;
	uint64_t total = (uint64_t)d->rows * d->cols;
	for (size_t k = 0; k < n; k++) {
		uint64_t c0 = (off + k) * 8;
		unsigned b = 0;
		for (unsigned bit = 0; bit < 8 && c0 + bit < total; bit++)
			b |= (unsigned)(d->weave[c0 + bit] & 1u) << bit;
		buf[k] = (uint8_t)b;
	}
}

typedef struct map_src {
	const uint8_t *map;
	uint32_t rows, cols;
	uint32_t mode;
} map_src;

static void produce_map(const void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	const map_src *m = ctx;
	for (size_t k = 0; k < n; k++) {
		uint64_t p = off + k, q;
		if (p < 8) {
			uint8_t pre[8] = {0};
			put32(pre, m->mode);
			buf[k] = pre[p];
			continue;
		}
		q = p - 8;
		switch (m->mode) {
		case MAP_FULL: buf[k] = m->map[q]; break;
		case MAP_COLUMNS: buf[k] = m->map[q]; break;            /* row 0 */
		case MAP_ROWS: buf[k] = m->map[q * m->cols]; break;     /* column 0 */
		default: buf[k] = m->map[0]; break;
		}
	}
}

/* The most compact mode that represents map exactly. */
static uint32_t map_mode(const uint8_t *map, uint32_t rows, uint32_t cols)
{
	int by_col = 1, by_row = 1;
	for (uint32_t i = 0; i < rows && (by_col || by_row); i++) {
		const uint8_t *r = map + (size_t)i * cols;
		if (by_col && i > 0 && memcmp(r, map, cols) != 0)
			by_col = 0;
		for (uint32_t j = 1; by_row && j < cols; j++)
			if (r[j] != r[0])
				by_row = 0;
	}
	if (by_col && by_row)
		return MAP_CONST;
	return by_col ? MAP_COLUMNS : by_row ? MAP_ROWS : MAP_FULL;
}

typedef struct base_src {
	const uint16_t *base;
	uint32_t width;
} base_src;

static void produce_base(const void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	const base_src *b = ctx;
	if (b->width == 1) {
		for (size_t k = 0; k < n; k++)
			buf[k] = (uint8_t)b->base[off + k];
		return;
	}
	for (size_t k = 0; k < n; k++) {
		uint64_t p = off + k;
		uint16_t v = b->base[p >> 1];
		buf[k] = (uint8_t)(p & 1 ? v >> 8 : v);
	}
}

/* ---- small sections built in memory --------------------------------------- */

static uint8_t *build_parm(const loom_fabric *f, size_t *len)
{
	size_t pl = strlen(f->db_path);
	uint8_t *p;

	if (pl > FAB_MAX_PATH)
		return NULL;
	p = calloc(1, FAB_PARM_BYTES + pl);
	if (!p)
		return NULL;
	put32(p + 0, (uint32_t)f->params.algo);
	put32(p + 4, f->params.flags);
	put64(p + 8, f->params.seed);
	put32(p + 16, f->params.group);
	put32(p + 20, f->params.rank);
	put32(p + 24, f->n_exemplars);
	put32(p + 28, f->n_blocks);
	put32(p + 32, f->b1);
	put32(p + 36, f->b2);
	put32(p + 40, f->b3);
	putf(p + 44, f->voxel_size_um);
	put64(p + 48, f->db_hash);
	put32(p + 56, f->params.base_width);
	put32(p + 60, (uint32_t)pl);
	memcpy(p + FAB_PARM_BYTES, f->db_path, pl);
	*len = FAB_PARM_BYTES + pl;
	return p;
}

static uint8_t *build_yarn(const loom_design *d, size_t *len)
{
	uint8_t *p = calloc(1, 8 + (size_t)FAB_YARN_BYTES * d->n_types);
	if (!p)
		return NULL;
	put32(p, d->n_types);
	put32(p + 4, FAB_YARN_BYTES);
	for (uint32_t k = 0; k < d->n_types; k++) {
		uint8_t *e = p + 8 + (size_t)FAB_YARN_BYTES * k;
		const loom_yarn_type *y = &d->types[k];
		size_t nl = strnlen(y->name, LOOM_YARN_NAME_MAX - 1);
		memcpy(e, y->name, nl);
		putf(e + 32, y->albedo[0]);
		putf(e + 36, y->albedo[1]);
		putf(e + 40, y->albedo[2]);
		putf(e + 44, y->alignment);
		putf(e + 48, y->thickness);
	}
	*len = 8 + (size_t)FAB_YARN_BYTES * d->n_types;
	return p;
}

/* Value i of the fields as the file stores them, whole ((y*b1 + x) * rank
   + k), from the compact tables (their zeros written out). */
static float field_whole(const loom_edgefix_tables *t, int vertical, size_t i)
{
	uint32_t r = vertical ? t->rank_v : t->rank_h;
	size_t cell = i / r;
	return loom_edgefix_field(t, vertical, (uint32_t)(cell % t->b1),
	                          (uint32_t)(cell / t->b1), (uint32_t)(i % r));
}

static uint8_t *build_edge(const loom_fabric *f, size_t *len)
{
	loom_edgefix_tables t;
	size_t cells, n[7], total = 0;
	const float *arr[7];
	uint8_t *p, *q;

	loom_edgefix_get_tables(f->ef, &t);
	cells = (size_t)t.b1 * t.b2;
	n[0] = (size_t)t.n_blocks * (2u * t.rank_h + 2u * t.rank_v);
	n[1] = cells * t.rank_h;
	n[2] = cells * t.rank_v;
	n[3] = (size_t)t.b1 * t.rank_h;
	n[4] = (size_t)(t.b2 - 2) * t.rank_v;
	n[5] = t.b1;
	n[6] = t.b2 - 2;
	arr[0] = t.coef;
	arr[1] = arr[2] = NULL; /* field_whole */
	arr[3] = t.basis_h;
	arr[4] = t.basis_v;
	arr[5] = t.mean_h;
	arr[6] = t.mean_v;
	if (f->params.edge_stored)
		for (int k = 0; k < 7; k++)
			total += n[k];
	p = calloc(1, FAB_EDGE_HEADER + 4 * total);
	if (!p)
		return NULL;
	put32(p + 0, f->params.edge_stored ? 1u : 2u);
	put32(p + 4, t.rank_h);
	put32(p + 8, t.rank_v);
	put32(p + 12, t.b1);
	put32(p + 16, t.b2);
	put32(p + 20, t.n_blocks);
	q = p + FAB_EDGE_HEADER;
	if (f->params.edge_stored)
		for (int k = 0; k < 7; k++)
			for (size_t i = 0; i < n[k]; i++, q += 4)
				putf(q, k == 1 || k == 2 ? field_whole(&t, k == 2, i) : arr[k][i]);
	*len = FAB_EDGE_HEADER + 4 * total;
	return p;
}

static uint8_t *put_synth_metrics(uint8_t *p, const loom_synth_metrics *m)
{
	put64(p + 0, m->crossings);
	put64(p + 8, m->correct);
	put64(p + 16, m->consistent);
	put64(p + 24, m->matches);
	put64(p + 32, m->best_matches);
	put64(p + 40, m->pairs);
	put64(p + 48, m->continuous);
	put64(p + 56, m->continuous_v);
	put64(p + 64, m->continuous_h);
	return p + 72;
}

static uint8_t *build_metr(const loom_fabric *f, size_t *len)
{
	size_t n = FAB_METR_FIXED + 8 * (size_t)f->n_exemplars;
	uint8_t *p = calloc(1, n), *q;
	const loom_seam_metrics *s = &f->seam;

	if (!p)
		return NULL;
	q = put_synth_metrics(p, &f->m_repeat);
	q = put_synth_metrics(q, &f->m_bolt);
	put64(q + 0, f->win_rows);
	put64(q + 8, f->win_cols);
	put64(q + 16, s->samples);
	putd(q + 24, s->before_mean);
	putd(q + 32, s->before_max);
	putd(q + 40, s->after_mean);
	putd(q + 48, s->after_max);
	put64(q + 56, s->corner_samples);
	putd(q + 64, s->corner_before_mean);
	putd(q + 72, s->corner_after_mean);
	putd(q + 80, s->internal_step);
	put32(q + 88, f->n_exemplars);
	q += 96;
	for (uint32_t u = 0; u < f->n_exemplars; u++)
		put64(q + 8 * (size_t)u, f->usage[u]);
	*len = n;
	return p;
}

int loom__fabric_write(const loom_fabric *f, const char *path, uint64_t *bytes,
                       loom_diag *diag)
{
	const loom_design *d = f->design;
	uint64_t crossings = (uint64_t)d->rows * d->cols;
	uint8_t head[FAB_HEADER_BYTES], trail[FAB_TRAILER_BYTES];
	uint8_t *parm = NULL, *yarn = NULL, *edge = NULL, *metr = NULL;
	size_t parm_n = 0, yarn_n = 0, edge_n = 0, metr_n = 0;
	map_src warp, weft;
	base_src bs;
	mem_src ms;
	fab_writer w;
	int rc;

	memset(&w, 0, sizeof w);
	w.path = path;
	w.diag = diag;
	parm = build_parm(f, &parm_n);
	yarn = build_yarn(d, &yarn_n);
	edge = build_edge(f, &edge_n);
	metr = build_metr(f, &metr_n);
	{
		/* buffers: one chunk, or the largest section if smaller */
		uint64_t most = crossings * f->params.base_width;
		size_t ms_ = parm_n > yarn_n ? parm_n : yarn_n;
		ms_ = ms_ > edge_n ? ms_ : edge_n;
		ms_ = ms_ > metr_n ? ms_ : metr_n;
		if (most < ms_)
			most = ms_;
		if (most < 8 + crossings)
			most = 8 + crossings; /* a full type map */
		w.chunk = most < FAB_CHUNK ? (size_t)most : FAB_CHUNK;
	}
	w.comp = libdeflate_alloc_compressor(FAB_LEVEL);
	w.in = malloc(w.chunk);
	w.out_cap = 8 + (w.comp ? libdeflate_deflate_compress_bound(w.comp, w.chunk) : 0);
	w.out = malloc(w.out_cap > w.chunk + 8 ? w.out_cap : w.chunk + 8);
	if (!parm || !yarn || !edge || !metr || !w.comp || !w.in || !w.out) {
		rc = loom__fail(diag, parm || strlen(f->db_path) <= FAB_MAX_PATH
		                          ? LOOM_ENOMEM : LOOM_ERANGE,
		                "%s: %s", path, parm || strlen(f->db_path) <= FAB_MAX_PATH
		                                    ? "out of memory"
		                                    : "database path longer than 4096 bytes");
		goto done;
	}
	rc = loom__atomic_open(&w.at, path, diag);
	if (rc)
		goto done;
	memset(head, 0, sizeof head);
	memcpy(head, FAB_MAGIC, 8);
	put32(head + 8, FAB_VERSION);
	put32(head + 12, FAB_HEADER_BYTES);
	put32(head + 16, d->rows);
	put32(head + 20, d->cols);
	put32(head + 24, FAB_N_SECTIONS);
	put32(head + 60, libdeflate_crc32(0, head, 60));
	rc = w_bytes(&w, head, sizeof head);
	ms.p = parm;
	if (!rc)
		rc = write_section(&w, S_PARM, FAB_ENC_RAW, parm_n, produce_mem, &ms);
	ms.p = yarn;
	if (!rc)
		rc = write_section(&w, S_YARN, FAB_ENC_RAW, yarn_n, produce_mem, &ms);
	if (!rc)
		rc = write_section(&w, S_WEAV, FAB_ENC_CHUNKED, (crossings + 7) / 8,
		                   produce_weave, d);
	warp.map = d->warp_type;
	weft.map = d->weft_type;
	warp.rows = weft.rows = d->rows;
	warp.cols = weft.cols = d->cols;
	warp.mode = map_mode(d->warp_type, d->rows, d->cols);
	weft.mode = map_mode(d->weft_type, d->rows, d->cols);
	if (!rc)
		rc = write_section(&w, S_WARP, FAB_ENC_CHUNKED,
		                   8 + map_data_bytes(warp.mode, d->rows, d->cols),
		                   produce_map, &warp);
	if (!rc)
		rc = write_section(&w, S_WEFT, FAB_ENC_CHUNKED,
		                   8 + map_data_bytes(weft.mode, d->rows, d->cols),
		                   produce_map, &weft);
	bs.base = f->base;
	bs.width = f->params.base_width;
	if (!rc)
		rc = write_section(&w, S_BASE, FAB_ENC_CHUNKED, crossings * bs.width,
		                   produce_base, &bs);
	ms.p = edge;
	if (!rc)
		rc = write_section(&w, S_EDGE, FAB_ENC_CHUNKED, edge_n, produce_mem, &ms);
	ms.p = metr;
	if (!rc)
		rc = write_section(&w, S_METR, FAB_ENC_RAW, metr_n, produce_mem, &ms);
	if (!rc) {
		memset(trail, 0, sizeof trail);
		memcpy(trail, FAB_TRAILER_MAGIC, 8);
		put64(trail + 8, w.pos + FAB_TRAILER_BYTES);
		put32(trail + 16, FAB_N_SECTIONS);
		put32(trail + 28, libdeflate_crc32(0, trail, 28));
		rc = w_bytes(&w, trail, sizeof trail);
	}
	if (!rc)
		rc = loom__atomic_commit(&w.at, diag);
	else
		loom__atomic_abort(&w.at);
	if (!rc && bytes)
		*bytes = w.pos;
done:
	libdeflate_free_compressor(w.comp);
	free(w.in);
	free(w.out);
	free(parm);
	free(yarn);
	free(edge);
	free(metr);
	return rc;
}
