/*
 * engine/render/preview.c - shaded orthographic top view of a fabric's virtual
 * texture (loom_preview_stream, loom_preview; docs/preview.md).
 *
 * What a pixel is.  Pixel (i, j) covers the voxel columns whose centres fall
 * inside it (its footprint; the column under its centre when it is smaller
 * than a column), and shows the mean of their shaded colours: an area
 * average, so a whole repeat at any width shows the motif instead of moire.
 * Row 0 is the smallest y (pick 0) and column 0 the smallest x (end 0), as
 * a drawdown is drawn.  A column is shaded from its top surface voxel and
 * the heights of its four neighbouring columns (central differences), so
 * the shading does not depend on the zoom.
 *
 * Two ways to get there (opt->filter):
 *
 *   EXACT  reads every column.  The picture is made in bands of output rows;
 *          the voxel rows a band needs (plus one above and below for the
 *          normals) live in a ring of `ring` rows of (height, info) per
 *          column, filled by worker threads from tasks (one per crossing
 *          segment of the new rows) sorted by source block, so the texture's
 *          working set is the bricks of one exemplar block at a time.  Then
 *          workers shade the band's output rows, each pixel from its own
 *          columns.  Memory: ring x (nx + 2) x 8 bytes, plus one band.
 *
 *   BLOCKS reads each source block the box uses once.  Along each axis a
 *          pixel's footprint is cut by crossing borders into at most 4
 *          pieces (crossing, local voxel range, weight; a footprint over
 *          more than 4 crossings samples 4 evenly spaced whole ones).
 *          Step 1: every crossing used (the product of the crossing rows
 *          and columns of all pieces) gives its source block; the first in
 *          row-major order (an atomic minimum, so the choice does not depend
 *          on the threads) is that block's representative.  Step 2: each
 *          representative crossing is read with a one-column margin and its
 *          columns shaded; per texel of g x g voxels the table keeps seven
 *          sums - shade and highlight of warp-topped columns, their count,
 *          the same for weft, and the sum of heights - as a summed-area
 *          table.  Step 3: a pixel integrates, over its pieces, the table of
 *          each piece's source block across the piece's local rectangle
 *          (bilinear in the summed-area table: exact for texels that are
 *          constant inside), coloured by that crossing's own warp and weft
 *          yarn types.  Colour = sum over yarns of albedo x shade +
 *          0.25 (1 - alignment) x highlight + background x empty columns,
 *          divided by the footprint's area.  What it leaves out: the
 *          edge-fix offsets and neighbours of every crossing but the
 *          representative one (a few voxels of height: a small change of
 *          the occlusion term).  Memory: the tables (g chosen so that they
 *          fit the cap), W + H pieces, per-thread caches of source rows.
 *
 * Both are deterministic: each pixel is computed from its own inputs in a
 * fixed order, whatever the thread count.
 */
#include "core/internal.h"
#include "loom/paint.h"
#include "loom/preview.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define RUN_MAX 64u          /* columns per region read */
#define SIDE_MAX ((int64_t)1 << 46)
#define DEFAULT_MEMORY ((size_t)16 << 20)
#define EXACT_MAX_COLS 16.0  /* AUTO: EXACT up to this many columns per pixel */
#define PIECES 4             /* crossings per pixel per axis in BLOCKS */
#define NCH 7                /* table channels: Gw Sw Nw Gf Sf Nf Hs */
#define ROW_CACHE 8          /* BLOCKS: source rows cached per thread */
#define BYTES_PER_PIXEL (3 * 4 + 4 + 3 * 4 + 1) /* one band pixel */

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

LOOM_API int loom_preview_size(const loom_preview_options *opt, uint32_t *w,
                               uint32_t *h)
{
	int64_t nx, ny;
	double hh;

	if (!opt || !w || !h || opt->size < offsetof(loom_preview_options, filter) ||
	    opt->width == 0)
		return LOOM_EINVAL;
	if (opt->hi[0] <= opt->lo[0] || opt->hi[1] <= opt->lo[1])
		return LOOM_EINVAL;
	if (opt->lo[0] < -SIDE_MAX || opt->lo[1] < -SIDE_MAX ||
	    opt->hi[0] > SIDE_MAX || opt->hi[1] > SIDE_MAX)
		return LOOM_ERANGE;
	nx = opt->hi[0] - opt->lo[0];
	ny = opt->hi[1] - opt->lo[1];
	if (opt->width > LOOM_PREVIEW_MAX_SIDE || opt->height > LOOM_PREVIEW_MAX_SIDE)
		return LOOM_ERANGE;
	*w = opt->width;
	if (opt->height) {
		*h = opt->height;
	} else {
		hh = floor((double)opt->width * (double)ny / (double)nx + 0.5);
		if (hh < 1)
			hh = 1;
		if (hh > LOOM_PREVIEW_MAX_SIDE)
			return LOOM_ERANGE;
		*h = (uint32_t)hh;
	}
	if ((uint64_t)*w * *h > ((uint64_t)1 << 31))
		return LOOM_ERANGE;
	return LOOM_OK;
}

/* ---- footprints ------------------------------------------------------------ */

/* ceil(a / b) and floor(a / b) for b > 0, in 128 bits. */
static __int128 ceil128(__int128 a, __int128 b)
{
	return a >= 0 ? (a + b - 1) / b : -((-a) / b);
}

/* Columns [a[k], b[k]) of pixel k of P across [lo, lo + n): those whose
   centre falls in the pixel, else the one under its centre. */
static void footprints(int64_t lo, int64_t n, uint32_t P, int64_t *a, int64_t *b)
{
	for (uint32_t k = 0; k < P; k++) {
		__int128 s = ceil128((__int128)2 * k * n - P, (__int128)2 * P);
		__int128 e = ceil128((__int128)2 * (k + 1) * n - P, (__int128)2 * P);
		if (e <= s) {
			s = ((__int128)(2 * (__int128)k + 1) * n) / (2 * (__int128)P);
			e = s + 1;
		}
		a[k] = lo + (int64_t)s;
		b[k] = lo + (int64_t)e;
	}
}

/* ---- shared state ------------------------------------------------------------ */

typedef struct pv_ctx {
	loom_texture *t;
	const loom_fabric *f;
	const loom_preview_options *opt;
	uint32_t b1, b2, n_blocks;   /* block size, global source blocks */
	int64_t X0, X1, Y0, Y1;      /* the box in x, y */
	int64_t z0, z1;              /* z range read */
	int64_t nx, ny;
	uint32_t W, H, nthreads;
	int64_t *xa, *xb, *ya, *yb;  /* footprints per pixel column / row */
	uint8_t thr;                 /* density byte of the surface */
	double L[3], Hv[3], span;
	float bg[3];
	float alb[256][3];           /* yarn albedo by type */
	float spk[256];              /* 0.25 (1 - alignment) by type */
	uint8_t valid[256];          /* type in the yarn table */
	const loom_paint *paint;     /* the paint layer when it reaches the box */
	size_t cap;                  /* memory cap */
	size_t mem;                  /* working memory in use (peak) */
	pthread_mutex_t lock;        /* progress, first error */
	uint64_t done, total;
	int rc;
	char msg[LOOM_DIAG_MSG_MAX];
	atomic_uint_fast64_t columns, reads;
	uint64_t empty;
	/* the current band of output */
	uint32_t band0, band_rows, band_cap;
	float *o_rgb, *o_h, *o_al;
	uint8_t *o_kind;
} pv_ctx;

static void set_error(pv_ctx *c, int rc, const char *msg)
{
	pthread_mutex_lock(&c->lock);
	if (c->rc == LOOM_OK) {
		c->rc = rc;
		snprintf(c->msg, sizeof c->msg, "%s", msg);
	}
	pthread_mutex_unlock(&c->lock);
}

static void progress_add(pv_ctx *c, uint64_t n)
{
	pthread_mutex_lock(&c->lock);
	c->done += n;
	if (c->opt->progress)
		c->opt->progress(c->opt->progress_user, c->done, c->total);
	pthread_mutex_unlock(&c->lock);
}

/* Run fn(arg) on c->nthreads threads (the caller is one of them). */
static void run_threads(pv_ctx *c, void *(*fn)(void *), void *arg)
{
	pthread_t th[256];
	uint32_t started = 0;

	for (; started + 1 < c->nthreads; started++)
		if (pthread_create(&th[started], NULL, fn, arg) != 0)
			break;
	fn(arg);
	for (uint32_t k = 0; k < started; k++)
		pthread_join(th[k], NULL);
}

static void normalize3(double v[3])
{
	double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	if (l > 0) {
		v[0] /= l;
		v[1] /= l;
		v[2] /= l;
	}
}

/* Column info packed in 32 bits: orientation << 16 | kind << 8 | type. */
#define INFO_KIND(v) ((uint8_t)((v) >> 8))
#define INFO_TYPE(v) ((uint8_t)(v))

/*
 * Read columns [xa, xb) of voxel row y (xb - xa <= RUN_MAX) and put each
 * column's surface height (z + 1; 0 when empty) and info into h[], info[].
 * Buffers: RUN_MAX * nz of each channel.
 */
typedef struct pv_buf {
	uint8_t *dens, *kind, *type;
	uint16_t *ori;
} pv_buf;

static int buf_init(pv_buf *b, size_t nz)
{
	size_t cap = RUN_MAX * nz;
	b->dens = malloc(cap);
	b->kind = malloc(cap);
	b->type = malloc(cap);
	b->ori = malloc(cap * sizeof *b->ori);
	return b->dens && b->kind && b->type && b->ori;
}

static void buf_free(pv_buf *b)
{
	free(b->dens);
	free(b->kind);
	free(b->type);
	free(b->ori);
}

static int read_run(pv_ctx *c, pv_buf *b, int64_t y, int64_t xa, int64_t xb,
                    float *h, uint32_t *info, float *alb)
{
	size_t nz = (size_t)(c->z1 - c->z0);
	int64_t lo[3] = {xa, y, c->z0}, hi[3] = {xb, y + 1, c->z1};
	loom_texture_region reg;
	int rc;

	memset(&reg, 0, sizeof reg);
	reg.density = b->dens;
	reg.orientation = b->ori;
	reg.kind = b->kind;
	reg.type = b->type;
	reg.layout = LOOM_REGION_Z_FASTEST;
	/* the paint hook: painted columns as loom_paint_sample shapes them */
	rc = alb ? loom_paint_read_region(c->paint, lo, hi, &reg)
	         : loom_texture_read_region(c->t, lo, hi, &reg);
	atomic_fetch_add(&c->reads, 1);
	atomic_fetch_add(&c->columns, (uint64_t)(xb - xa));
	if (rc != LOOM_OK) {
		set_error(c, rc, loom_texture_errmsg(c->t));
		return rc;
	}
	for (int64_t x = xa; x < xb; x++) {
		size_t col = (size_t)(x - xa) * nz, k = nz;
		while (k > 0 && b->dens[col + k - 1] < c->thr)
			k--;
		if (k == 0) {
			h[x - xa] = 0.0f;
			info[x - xa] = 0;
		} else {
			size_t v = col + k - 1;
			h[x - xa] = (float)(c->z0 + (int64_t)k);
			info[x - xa] = (uint32_t)b->ori[v] << 16 | (uint32_t)b->kind[v] << 8 |
			               b->type[v];
		}
		if (alb) { /* ... and paint tints them (-1: the yarn table's) */
			float *al = alb + 3 * (x - xa);
			uint8_t kd = INFO_KIND(info[x - xa]), ty = INFO_TYPE(info[x - xa]);
			al[0] = -1.0f;
			if (h[x - xa] > 0 && kd) {
				float base[3] = {0.5f, 0.5f, 0.5f};
				if (c->valid[ty])
					memcpy(base, c->alb[ty], sizeof base);
				memcpy(al, base, sizeof base);
				loom_paint_albedo(c->paint, x, y, kd, al);
				if (!memcmp(al, base, sizeof base))
					al[0] = -1.0f;
			}
		}
	}
	return LOOM_OK;
}

/*
 * Geometric shading terms of a column of height h (> 0) and fibre code
 * `ori`, with neighbour heights (0 = empty, counted as z0): G multiplies
 * the albedo, S the highlight factor 0.25 (1 - alignment).
 */
static void shade_terms(const pv_ctx *c, float h, uint16_t ori, float hl, float hr,
                        float hu, float hd, double *G, double *S)
{
	double fl = (double)c->z0, n[3], t[3], tl, th, ndl, occ;
	float tf[3];

	n[0] = -(((hr > 0) ? hr : fl) - ((hl > 0) ? hl : fl)) * 0.5;
	n[1] = -(((hd > 0) ? hd : fl) - ((hu > 0) ? hu : fl)) * 0.5;
	n[2] = 1.0;
	normalize3(n);
	loom_orientation_decode(ori, tf);
	t[0] = tf[0];
	t[1] = tf[1];
	t[2] = tf[2];
	normalize3(t);
	tl = t[0] * c->L[0] + t[1] * c->L[1] + t[2] * c->L[2];
	th = t[0] * c->Hv[0] + t[1] * c->Hv[1] + t[2] * c->Hv[2];
	ndl = n[0] * c->L[0] + n[1] * c->L[1] + n[2] * c->L[2];
	if (ndl < 0)
		ndl = 0;
	occ = c->span > 0 ? 0.45 + 0.55 * ((double)h - fl) / c->span : 1.0;
	*G = (0.12 + 0.88 * ndl * (0.3 + 0.7 * sqrt(fmax(0.0, 1.0 - tl * tl)))) * occ;
	*S = pow(sqrt(fmax(0.0, 1.0 - th * th)), 24.0) * ndl;
}

/* Per-pixel sums, turned into the band's outputs by put_pixel. */
typedef struct pv_acc {
	double rgb[3], al[3], hs, nw, nf, area;
} pv_acc;

static void put_pixel(pv_ctx *c, uint32_t row, uint32_t i, const pv_acc *a)
{
	size_t p = (size_t)(row - c->band0) * c->W + i;
	double inv = a->area > 0 ? 1.0 / a->area : 0, ne = a->nw + a->nf;

	for (int k = 0; k < 3; k++) {
		c->o_rgb[3 * p + (size_t)k] = (float)(a->rgb[k] * inv);
		c->o_al[3 * p + (size_t)k] = (float)(a->al[k] * inv);
	}
	c->o_h[p] = ne > 0 ? (float)(a->hs / ne) : 0.0f;
	c->o_kind[p] = ne > 0 ? (a->nw >= a->nf ? 1 : 2) : 0;
}

/* Add column (h, info) with its shading to a pixel's sums (weight w). */
static void add_column(const pv_ctx *c, pv_acc *a, float h, uint32_t info,
                       const float *pal, float hl, float hr, float hu, float hd,
                       double w)
{
	uint8_t kind = INFO_KIND(info), type = INFO_TYPE(info);

	a->area += w;
	if (h <= 0 || kind == 0) {
		for (int k = 0; k < 3; k++) {
			a->rgb[k] += w * c->bg[k];
			a->al[k] += w * c->bg[k];
		}
		return;
	}
	a->hs += w * h;
	if (kind == 1)
		a->nw += w;
	else
		a->nf += w;
	if (pal && pal[0] >= 0) { /* a painted colour */
		double G, S;
		shade_terms(c, h, (uint16_t)(info >> 16), hl, hr, hu, hd, &G, &S);
		for (int k = 0; k < 3; k++) {
			a->rgb[k] += w * (pal[k] * G + (c->valid[type] ? c->spk[type] : 0) * S);
			a->al[k] += w * pal[k];
		}
		return;
	}
	if (!c->valid[type]) {
		for (int k = 0; k < 3; k++) {
			a->rgb[k] += w * 0.5;
			a->al[k] += w * 0.5;
		}
		return;
	}
	{
		double G, S;
		shade_terms(c, h, (uint16_t)(info >> 16), hl, hr, hu, hd, &G, &S);
		for (int k = 0; k < 3; k++) {
			a->rgb[k] += w * (c->alb[type][k] * G + c->spk[type] * S);
			a->al[k] += w * c->alb[type][k];
		}
	}
}

/* Hand the band to the caller. */
static int emit_band(pv_ctx *c, loom_preview_band_fn fn, void *user)
{
	loom_preview_band b;
	size_t n = (size_t)c->band_rows * c->W;
	int rc;

	for (size_t p = 0; p < n; p++)
		if (c->o_kind[p] == 0)
			c->empty++;
	b.row0 = c->band0;
	b.rows = c->band_rows;
	b.width = c->W;
	b.rgb = c->o_rgb;
	b.height = c->o_h;
	b.albedo = c->o_al;
	b.kind = c->o_kind;
	rc = fn(user, &b);
	progress_add(c, n);
	return rc;
}

/* ---- EXACT ------------------------------------------------------------------- */

typedef struct ex_task {
	uint32_t key;          /* source block (sort key) */
	int64_t y0, y1;        /* voxel rows */
	int64_t x0, x1;        /* columns (within one crossing) */
} ex_task;

typedef struct ex_job {
	pv_ctx *c;
	uint32_t ring;         /* rows in the ring */
	size_t stride;         /* columns per ring row: nx + 2 */
	float *rh;             /* ring heights [ring * stride] */
	uint32_t *ri;          /* ring infos */
	float *ra;             /* ring painted albedos (3 per column), or NULL */
	ex_task *tasks;
	size_t n_tasks;
	atomic_size_t next;
	uint32_t j0, j1;       /* output rows to shade */
	atomic_uint next_row;
} ex_job;

static int cmp_task(const void *a, const void *b)
{
	const ex_task *x = a, *y = b;
	if (x->key != y->key)
		return x->key < y->key ? -1 : 1;
	if (x->y0 != y->y0)
		return x->y0 < y->y0 ? -1 : 1;
	return x->x0 < y->x0 ? -1 : x->x0 > y->x0;
}

static void *ex_fetch_worker(void *arg)
{
	ex_job *j = arg;
	pv_ctx *c = j->c;
	pv_buf b;

	if (!buf_init(&b, (size_t)(c->z1 - c->z0))) {
		set_error(c, LOOM_ENOMEM, "out of memory");
		buf_free(&b);
		return NULL;
	}
	for (;;) {
		size_t k = atomic_fetch_add(&j->next, 1);
		const ex_task *tk;
		if (k >= j->n_tasks || c->rc != LOOM_OK)
			break;
		tk = &j->tasks[k];
		for (int64_t y = tk->y0; y < tk->y1; y++) {
			size_t slot = (size_t)((uint64_t)(y - (c->Y0 - 1)) % j->ring) * j->stride;
			for (int64_t x = tk->x0; x < tk->x1; x += RUN_MAX) {
				int64_t xe = x + RUN_MAX < tk->x1 ? x + RUN_MAX : tk->x1;
				size_t off = slot + (size_t)(x - (c->X0 - 1));
				if (read_run(c, &b, y, x, xe, j->rh + off, j->ri + off,
				             j->ra ? j->ra + 3 * off : NULL) != LOOM_OK)
					goto out;
			}
		}
	}
out:
	loom_texture_thread_done(c->t);
	buf_free(&b);
	return NULL;
}

static void *ex_shade_worker(void *arg)
{
	ex_job *j = arg;
	pv_ctx *c = j->c;

	for (;;) {
		uint32_t row = atomic_fetch_add(&j->next_row, 1) + j->j0;
		if (row >= j->j1)
			break;
		for (uint32_t i = 0; i < c->W; i++) {
			pv_acc a;
			memset(&a, 0, sizeof a);
			for (int64_t y = c->ya[row]; y < c->yb[row]; y++) {
				size_t s = (size_t)((uint64_t)(y - (c->Y0 - 1)) % j->ring) * j->stride;
				size_t su = (size_t)((uint64_t)(y - 1 - (c->Y0 - 1)) % j->ring) * j->stride;
				size_t sd = (size_t)((uint64_t)(y + 1 - (c->Y0 - 1)) % j->ring) * j->stride;
				for (int64_t x = c->xa[i]; x < c->xb[i]; x++) {
					size_t q = (size_t)(x - (c->X0 - 1));
					add_column(c, &a, j->rh[s + q], j->ri[s + q],
					           j->ra ? j->ra + 3 * (s + q) : NULL, j->rh[s + q - 1],
					           j->rh[s + q + 1], j->rh[su + q], j->rh[sd + q], 1.0);
				}
			}
			put_pixel(c, row, i, &a);
		}
	}
	return NULL;
}

/* Fetch voxel rows [f0, f1) (all columns of the box plus margins). */
static int ex_fetch(pv_ctx *c, ex_job *j, int64_t f0, int64_t f1)
{
	int64_t xl = c->X0 - 1, xr = c->X1 + 1;
	int64_t Ja = loom_synth_floordiv(xl, c->b1), Jb = loom_synth_floordiv(xr - 1, c->b1);
	size_t n = 0;

	for (int64_t y = f0; y < f1;) {
		int64_t I = loom_synth_floordiv(y, c->b2);
		int64_t ye = (I + 1) * (int64_t)c->b2 < f1 ? (I + 1) * (int64_t)c->b2 : f1;
		for (int64_t J = Ja; J <= Jb; J++) {
			loom_fabric_source src;
			ex_task *tk = &j->tasks[n++];
			tk->key = c->n_blocks;
			if (loom_fabric_source_at(c->f, I, J, &src) == LOOM_OK &&
			    src.block < c->n_blocks)
				tk->key = src.block;
			tk->y0 = y;
			tk->y1 = ye;
			tk->x0 = J * (int64_t)c->b1 > xl ? J * (int64_t)c->b1 : xl;
			tk->x1 = (J + 1) * (int64_t)c->b1 < xr ? (J + 1) * (int64_t)c->b1 : xr;
		}
		y = ye;
	}
	qsort(j->tasks, n, sizeof *j->tasks, cmp_task);
	j->n_tasks = n;
	atomic_store(&j->next, 0);
	run_threads(c, ex_fetch_worker, j);
	return c->rc;
}

static int run_exact(pv_ctx *c, loom_preview_band_fn fn, void *user)
{
	ex_job j;
	int64_t need = 0, w0, w1, ylast;
	size_t rowbytes, band_bytes, fixed, ntask_cap;
	int64_t Ja, Jb;
	uint32_t row = 0;
	int rc = LOOM_OK;

	memset(&j, 0, sizeof j);
	j.c = c;
	j.stride = (size_t)c->nx + 2;
	rowbytes = j.stride * (sizeof(float) + sizeof(uint32_t) +
	                       (c->paint ? 3 * sizeof(float) : 0));
	for (uint32_t r = 0; r < c->H; r++)
		if (c->yb[r] - c->ya[r] + 2 > need)
			need = c->yb[r] - c->ya[r] + 2;
	band_bytes = (size_t)c->band_cap * c->W * BYTES_PER_PIXEL;
	fixed = band_bytes + (size_t)c->nthreads * RUN_MAX * (size_t)(c->z1 - c->z0) * 5;
	Ja = loom_synth_floordiv(c->X0 - 1, c->b1);
	Jb = loom_synth_floordiv(c->X1, c->b1);
	/* ring: what the cap allows beyond the fixed part, at least `need` */
	{
		size_t per_row = rowbytes + (size_t)(Jb - Ja + 1) * sizeof(ex_task);
		uint64_t fit = c->cap > fixed ? (c->cap - fixed) / per_row : 0;
		uint64_t want = (uint64_t)(c->yb[c->H - 1] - c->ya[0]) + 2;
		if (fit > 1024)
			fit = 1024;
		if (fit > want)
			fit = want;
		if ((int64_t)fit < need) {
			char s1[40], s2[40];
			snprintf(c->msg, sizeof c->msg, "an exact preview of this box needs "
			         "%s of row buffers, more than the %s allowed (use "
			         "the blocks filter or a narrower box)",
			         loom__size_text(s1, sizeof s1,
			                         (double)((size_t)need * per_row + fixed)),
			         loom__size_text(s2, sizeof s2, (double)c->cap));
			return LOOM_EBUDGET;
		}
		j.ring = (uint32_t)fit;
		/* tasks: crossing rows of one fetch (at most ring/b2 + 2) x columns */
		ntask_cap = ((size_t)j.ring / c->b2 + 2) * (size_t)(Jb - Ja + 1);
	}
	j.rh = malloc((size_t)j.ring * j.stride * sizeof *j.rh);
	j.ri = malloc((size_t)j.ring * j.stride * sizeof *j.ri);
	j.tasks = malloc(ntask_cap * sizeof *j.tasks);
	if (c->paint)
		j.ra = malloc((size_t)j.ring * j.stride * 3 * sizeof *j.ra);
	if (!j.rh || !j.ri || !j.tasks || (c->paint && !j.ra)) {
		rc = LOOM_ENOMEM;
		snprintf(c->msg, sizeof c->msg, "out of memory for the row buffers");
		goto done;
	}
	c->mem = fixed + (size_t)j.ring * rowbytes + ntask_cap * sizeof *j.tasks;
	w0 = w1 = c->ya[0] - 1; /* the ring holds rows [w0, w1) */
	ylast = c->yb[c->H - 1] + 1;
	while (row < c->H) {
		uint32_t r2 = row;
		int64_t keep = c->ya[row] - 1, f0, f1;
		/* fetch: drop rows below `keep`, fill the ring */
		if (w1 < keep)
			w1 = keep;
		if (w0 < keep)
			w0 = keep;
		f0 = w1;
		f1 = w0 + (int64_t)j.ring < ylast ? w0 + (int64_t)j.ring : ylast;
		if (f1 > f0) {
			if ((rc = ex_fetch(c, &j, f0, f1)) != LOOM_OK)
				goto done;
			w1 = f1;
		}
		/* shade the output rows whose rows are all in the ring */
		while (r2 < c->H && r2 - row < c->band_cap && c->ya[r2] - 1 >= w0 &&
		       c->yb[r2] + 1 <= w1)
			r2++;
		if (r2 == row) { /* cannot happen: ring >= need */
			rc = LOOM_EBUDGET;
			snprintf(c->msg, sizeof c->msg, "row buffers too small");
			goto done;
		}
		c->band0 = row;
		c->band_rows = r2 - row;
		j.j0 = row;
		j.j1 = r2;
		atomic_store(&j.next_row, 0);
		run_threads(c, ex_shade_worker, &j);
		if ((rc = emit_band(c, fn, user)) != 0)
			goto done;
		row = r2;
	}
done:
	free(j.rh);
	free(j.ri);
	free(j.ra);
	free(j.tasks);
	return rc;
}

/* ---- BLOCKS ------------------------------------------------------------------ */

typedef struct bl_piece {
	int64_t cr;            /* crossing index (J or I) */
	uint32_t la, lb;       /* local voxel range [la, lb) in the block */
	uint32_t idx;          /* index of cr in the sorted list of crossings */
	double w;              /* weight (1, or the span a sample stands for) */
} bl_piece;

typedef struct bl_table {
	uint32_t tx, ty;       /* texels across, along */
	float *sat;            /* (ty + 1) x (tx + 1) x NCH, summed-area */
} bl_table;

typedef struct bl_job {
	pv_ctx *c;
	bl_piece *px, *py;     /* PIECES per pixel column / output row */
	uint8_t *npx, *npy;    /* pieces used */
	int64_t *JL, *IL;      /* sorted distinct crossing columns / rows */
	size_t nJ, nI;
	_Atomic uint64_t *first;/* per key: smallest row-major code of use */
	uint32_t *slot;        /* per key: table index or UINT32_MAX */
	uint32_t *keys;        /* tabulated keys */
	uint32_t n_keys;
	bl_table *tab;
	uint32_t g;            /* voxels per texel side */
	atomic_size_t next;
	uint32_t j0, j1;
	atomic_uint next_row;
} bl_job;

/* Pieces of the footprint [a, b) along an axis of block size bs. */
static uint8_t cut(int64_t a, int64_t b, uint32_t bs, bl_piece *out)
{
	int64_t Ca = loom_synth_floordiv(a, bs), Cb = loom_synth_floordiv(b - 1, bs);
	uint8_t n = 0;

	if (Cb - Ca + 1 <= PIECES) {
		for (int64_t C = Ca; C <= Cb; C++) {
			int64_t s = C * (int64_t)bs, e = s + bs;
			out[n].cr = C;
			out[n].la = (uint32_t)((a > s ? a : s) - s);
			out[n].lb = (uint32_t)((b < e ? b : e) - s);
			out[n].w = 1.0;
			n++;
		}
		return n;
	}
	for (int k = 0; k < PIECES; k++) {
		/* the crossing under the centre of the k-th quarter */
		__int128 m = (__int128)a * 2 * PIECES + (__int128)(2 * k + 1) * (b - a);
		int64_t x = (int64_t)(m / (2 * PIECES));
		out[n].cr = loom_synth_floordiv(x, bs);
		out[n].la = 0;
		out[n].lb = bs;
		out[n].w = (double)(b - a) / ((double)PIECES * bs);
		n++;
	}
	return n;
}

static int cmp_i64(const void *a, const void *b)
{
	int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
	return x < y ? -1 : x > y;
}

/* Sorted distinct crossings of all pieces; each piece gets its index. */
static int64_t *crossing_list(bl_piece *p, const uint8_t *np, uint32_t P, size_t *n)
{
	size_t total = 0, k = 0, m = 0;
	int64_t *L;

	for (uint32_t i = 0; i < P; i++)
		total += np[i];
	L = malloc((total ? total : 1) * sizeof *L);
	if (!L)
		return NULL;
	for (uint32_t i = 0; i < P; i++)
		for (uint8_t q = 0; q < np[i]; q++)
			L[k++] = p[(size_t)i * PIECES + q].cr;
	qsort(L, total, sizeof *L, cmp_i64);
	for (k = 0; k < total; k++)
		if (m == 0 || L[m - 1] != L[k])
			L[m++] = L[k];
	for (uint32_t i = 0; i < P; i++)
		for (uint8_t q = 0; q < np[i]; q++) {
			bl_piece *pc = &p[(size_t)i * PIECES + q];
			int64_t *hit = bsearch(&pc->cr, L, m, sizeof *L, cmp_i64);
			pc->idx = (uint32_t)(hit - L);
		}
	*n = m;
	return L;
}

/* Step 1 worker: the first use of every key. */
static void *bl_discover_worker(void *arg)
{
	bl_job *j = arg;
	pv_ctx *c = j->c;

	for (;;) {
		size_t r = atomic_fetch_add(&j->next, 1);
		if (r >= j->nI)
			break;
		for (size_t q = 0; q < j->nJ; q++) {
			loom_fabric_source src;
			uint32_t key = c->n_blocks;
			uint64_t code = (uint64_t)r * j->nJ + q, cur;
			if (loom_fabric_source_at(c->f, j->IL[r], j->JL[q], &src) == LOOM_OK &&
			    src.block < c->n_blocks)
				key = src.block;
			cur = atomic_load(&j->first[key]);
			while (code < cur &&
			       !atomic_compare_exchange_weak(&j->first[key], &cur, code))
				;
		}
	}
	return NULL;
}

/* Texel coordinate of local voxel position x (0..bs) at texel size g. */
static double texel_coord(uint32_t x, uint32_t bs, uint32_t g, uint32_t nt)
{
	uint32_t k = x / g;
	if (k >= nt - 1) {
		uint32_t s = (nt - 1) * g;
		return (double)(nt - 1) + (double)(x - s) / (double)(bs - s);
	}
	return (double)k + (double)(x % g) / (double)g;
}

/* Step 2 worker: read, shade and tabulate representative crossings. */
static void *bl_table_worker(void *arg)
{
	bl_job *j = arg;
	pv_ctx *c = j->c;
	uint32_t sw = c->b1 + 2, sh = c->b2 + 2;
	float *h = malloc((size_t)sw * sh * sizeof *h);
	uint32_t *info = malloc((size_t)sw * sh * sizeof *info);
	pv_buf b;
	int ok = buf_init(&b, (size_t)(c->z1 - c->z0));

	if (!h || !info || !ok) {
		set_error(c, LOOM_ENOMEM, "out of memory");
		goto out;
	}
	for (;;) {
		size_t k = atomic_fetch_add(&j->next, 1);
		uint32_t key;
		uint64_t code;
		int64_t I, J, x0, y0;
		bl_table *T;
		if (k >= j->n_keys || c->rc != LOOM_OK)
			break;
		key = j->keys[k];
		T = &j->tab[k];
		code = atomic_load(&j->first[key]);
		I = j->IL[code / j->nJ];
		J = j->JL[code % j->nJ];
		x0 = J * (int64_t)c->b1 - 1;
		y0 = I * (int64_t)c->b2 - 1;
		for (uint32_t r = 0; r < sh; r++)
			for (uint32_t x = 0; x < sw; x += RUN_MAX) {
				uint32_t xe = x + RUN_MAX < sw ? x + RUN_MAX : sw;
				size_t off = (size_t)r * sw + x;
				if (read_run(c, &b, y0 + r, x0 + x, x0 + xe, h + off, info + off,
				             NULL))
					goto out;
			}
		memset(T->sat, 0, (size_t)(T->tx + 1) * (T->ty + 1) * NCH * sizeof(float));
		/* texel sums into the interior of sat (offset by one row and column) */
		for (uint32_t ly = 0; ly < c->b2; ly++)
			for (uint32_t lx = 0; lx < c->b1; lx++) {
				size_t p = (size_t)(ly + 1) * sw + lx + 1;
				uint32_t v = info[p];
				uint8_t kd = INFO_KIND(v);
				float *cell = T->sat + ((size_t)(ly / j->g + 1) * (T->tx + 1) +
				                        lx / j->g + 1) * NCH;
				double G, S;
				if (h[p] <= 0 || kd == 0)
					continue;
				shade_terms(c, h[p], (uint16_t)(v >> 16), h[p - 1], h[p + 1],
				            h[p - sw], h[p + sw], &G, &S);
				cell[kd == 1 ? 0 : 3] += (float)G;
				cell[kd == 1 ? 1 : 4] += (float)S;
				cell[kd == 1 ? 2 : 5] += 1.0f;
				cell[6] += h[p];
			}
		/* prefix sums in both directions */
		for (uint32_t v = 1; v <= T->ty; v++)
			for (uint32_t u = 1; u <= T->tx; u++)
				for (int ch = 0; ch < NCH; ch++) {
					float *s = T->sat;
					size_t W1 = T->tx + 1;
					s[((size_t)v * W1 + u) * NCH + ch] +=
						s[((size_t)(v - 1) * W1 + u) * NCH + ch] +
						s[((size_t)v * W1 + u - 1) * NCH + ch] -
						s[((size_t)(v - 1) * W1 + u - 1) * NCH + ch];
				}
	}
out:
	loom_texture_thread_done(c->t);
	buf_free(&b);
	free(h);
	free(info);
	return NULL;
}

/* Sum of the table over texel coordinates [0, u) x [0, v) (bilinear). */
static void sat_at(const bl_table *T, double u, double v, double out[NCH])
{
	uint32_t ku = (uint32_t)u, kv = (uint32_t)v;
	double fu, fv;
	size_t W1 = T->tx + 1;
	const float *s00, *s01, *s10, *s11;

	if (ku >= T->tx)
		ku = T->tx - 1;
	if (kv >= T->ty)
		kv = T->ty - 1;
	fu = u - ku;
	fv = v - kv;
	s00 = T->sat + ((size_t)kv * W1 + ku) * NCH;
	s01 = s00 + NCH;
	s10 = s00 + W1 * NCH;
	s11 = s10 + NCH;
	for (int ch = 0; ch < NCH; ch++)
		out[ch] = (1 - fv) * ((1 - fu) * s00[ch] + fu * s01[ch]) +
		          fv * ((1 - fu) * s10[ch] + fu * s11[ch]);
}

/* A cached row of sources: keys and yarn types along JL for crossing row I. */
typedef struct bl_row {
	int64_t I;
	int valid;
	uint32_t *key;
	uint8_t *wt, *ft;
} bl_row;

static const bl_row *row_sources(bl_job *j, bl_row *cache, int *clock, int64_t I)
{
	pv_ctx *c = j->c;
	bl_row *r;

	for (int k = 0; k < ROW_CACHE; k++)
		if (cache[k].valid && cache[k].I == I)
			return &cache[k];
	r = &cache[*clock];
	*clock = (*clock + 1) % ROW_CACHE;
	r->I = I;
	r->valid = 1;
	for (size_t q = 0; q < j->nJ; q++) {
		loom_fabric_source src;
		r->key[q] = c->n_blocks;
		r->wt[q] = r->ft[q] = 0;
		if (loom_fabric_source_at(c->f, I, j->JL[q], &src) == LOOM_OK) {
			if (src.block < c->n_blocks)
				r->key[q] = src.block;
			r->wt[q] = src.warp_type;
			r->ft[q] = src.weft_type;
		}
	}
	return r;
}

/*
 * A piece the paint reaches, column by column as EXACT does: columns
 * [x0, x1) of rows [y0, y1) (at most a block wide) read painted, each
 * shaded from its neighbours, added with weight w.  Rows pass through a
 * ring of 3 rows of sw = b1 + 2 columns.
 */
typedef struct bl_exact {
	pv_buf b;
	float *h, *alb;
	uint32_t *info;
	size_t sw;
} bl_exact;

static int exact_piece(pv_ctx *c, bl_exact *e, int64_t x0, int64_t x1, int64_t y0,
                       int64_t y1, double w, pv_acc *a)
{
	size_t n = (size_t)(x1 - x0) + 2;

	for (int64_t y = y0 - 1; y <= y1; y++) {
		size_t slot = (size_t)((y - (y0 - 1)) % 3) * e->sw;
		for (size_t x = 0; x < n; x += RUN_MAX) {
			size_t xe = x + RUN_MAX < n ? x + RUN_MAX : n;
			if (read_run(c, &e->b, y, x0 - 1 + (int64_t)x, x0 - 1 + (int64_t)xe,
			             e->h + slot + x, e->info + slot + x,
			             e->alb + 3 * (slot + x)) != LOOM_OK)
				return -1;
		}
		if (y - 1 >= y0) { /* row y - 1 and both its neighbours are in */
			int64_t r = y - 1 - (y0 - 1);
			size_t sm = (size_t)(r % 3) * e->sw, su = (size_t)((r + 2) % 3) * e->sw;
			for (size_t q = 1; q + 1 < n; q++)
				add_column(c, a, e->h[sm + q], e->info[sm + q], e->alb + 3 * (sm + q),
				           e->h[sm + q - 1], e->h[sm + q + 1], e->h[su + q],
				           e->h[slot + q], w);
		}
	}
	return 0;
}

/* Step 3 worker: pixels of output rows [j0, j1). */
static void *bl_pixel_worker(void *arg)
{
	bl_job *j = arg;
	pv_ctx *c = j->c;
	bl_row cache[ROW_CACHE];
	int clock = 0, ok = 1;
	bl_exact px;

	memset(cache, 0, sizeof cache);
	memset(&px, 0, sizeof px);
	if (c->paint) {
		px.sw = (size_t)c->b1 + 2;
		px.h = malloc(3 * px.sw * sizeof *px.h);
		px.info = malloc(3 * px.sw * sizeof *px.info);
		px.alb = malloc(3 * 3 * px.sw * sizeof *px.alb);
		if (!buf_init(&px.b, (size_t)(c->z1 - c->z0)) || !px.h || !px.info || !px.alb)
			ok = 0;
	}
	for (int k = 0; k < ROW_CACHE; k++) {
		cache[k].key = malloc(j->nJ * sizeof *cache[k].key);
		cache[k].wt = malloc(j->nJ);
		cache[k].ft = malloc(j->nJ);
		if (!cache[k].key || !cache[k].wt || !cache[k].ft)
			ok = 0;
	}
	if (!ok) {
		set_error(c, LOOM_ENOMEM, "out of memory");
		goto out;
	}
	for (;;) {
		uint32_t row = atomic_fetch_add(&j->next_row, 1) + j->j0;
		const bl_piece *pr;
		const bl_row *rs[PIECES];
		if (row >= j->j1)
			break;
		pr = &j->py[(size_t)row * PIECES];
		for (uint8_t qy = 0; qy < j->npy[row]; qy++)
			rs[qy] = row_sources(j, cache, &clock, pr[qy].cr);
		for (uint32_t i = 0; i < c->W; i++) {
			const bl_piece *pc = &j->px[(size_t)i * PIECES];
			pv_acc a;
			memset(&a, 0, sizeof a);
			for (uint8_t qy = 0; qy < j->npy[row]; qy++)
				for (uint8_t qx = 0; qx < j->npx[i]; qx++) {
					const bl_piece *ex = &pc[qx], *ey = &pr[qy];
					uint32_t key = rs[qy]->key[ex->idx];
					uint8_t wt = rs[qy]->wt[ex->idx], ft = rs[qy]->ft[ex->idx];
					double w = ex->w * ey->w;
					double area = (double)(ex->lb - ex->la) * (ey->lb - ey->la);
					double s[NCH], ne;
					if (c->paint) {
						int64_t x0 = ex->cr * (int64_t)c->b1 + ex->la;
						int64_t y0 = ey->cr * (int64_t)c->b2 + ey->la;
						int64_t x1 = x0 + (ex->lb - ex->la), y1 = y0 + (ey->lb - ey->la);
						int64_t plo[2] = {x0 - 1, y0 - 1}, phi[2] = {x1 + 1, y1 + 1};
						if (loom_paint_touches(c->paint, plo, phi)) {
							if (exact_piece(c, &px, x0, x1, y0, y1, w, &a))
								goto out;
							continue;
						}
					}
					if (key >= c->n_blocks || j->slot[key] == UINT32_MAX) {
						for (int ch = 0; ch < NCH; ch++)
							s[ch] = 0;
					} else {
						const bl_table *T = &j->tab[j->slot[key]];
						double u0 = texel_coord(ex->la, c->b1, j->g, T->tx);
						double u1 = texel_coord(ex->lb, c->b1, j->g, T->tx);
						double v0 = texel_coord(ey->la, c->b2, j->g, T->ty);
						double v1 = texel_coord(ey->lb, c->b2, j->g, T->ty);
						double s11[NCH], s10[NCH], s01[NCH], s00[NCH];
						sat_at(T, u1, v1, s11);
						sat_at(T, u0, v1, s10);
						sat_at(T, u1, v0, s01);
						sat_at(T, u0, v0, s00);
						for (int ch = 0; ch < NCH; ch++)
							s[ch] = s11[ch] - s10[ch] - s01[ch] + s00[ch];
					}
					ne = area - s[2] - s[5];
					if (ne < 0)
						ne = 0;
					a.area += w * area;
					a.hs += w * s[6];
					a.nw += w * s[2];
					a.nf += w * s[5];
					for (int k = 0; k < 3; k++) {
						double col = c->bg[k] * ne, al = c->bg[k] * ne;
						if (c->valid[wt]) {
							col += c->alb[wt][k] * s[0] + c->spk[wt] * s[1];
							al += c->alb[wt][k] * s[2];
						} else {
							col += 0.5 * s[2];
							al += 0.5 * s[2];
						}
						if (c->valid[ft]) {
							col += c->alb[ft][k] * s[3] + c->spk[ft] * s[4];
							al += c->alb[ft][k] * s[5];
						} else {
							col += 0.5 * s[5];
							al += 0.5 * s[5];
						}
						a.rgb[k] += w * col;
						a.al[k] += w * al;
					}
				}
			put_pixel(c, row, i, &a);
		}
	}
out:
	for (int k = 0; k < ROW_CACHE; k++) {
		free(cache[k].key);
		free(cache[k].wt);
		free(cache[k].ft);
	}
	if (c->paint) {
		loom_texture_thread_done(c->t);
		buf_free(&px.b);
		free(px.h);
		free(px.info);
		free(px.alb);
	}
	return NULL;
}

static int run_blocks(pv_ctx *c, loom_preview_band_fn fn, void *user,
                      loom_preview_stats *st)
{
	bl_job j;
	size_t mem = (size_t)c->band_cap * c->W * BYTES_PER_PIXEL, table_cap;
	uint32_t row = 0;
	int rc = LOOM_OK;

	memset(&j, 0, sizeof j);
	j.c = c;
	j.px = malloc((size_t)c->W * PIECES * sizeof *j.px);
	j.py = malloc((size_t)c->H * PIECES * sizeof *j.py);
	j.npx = malloc(c->W);
	j.npy = malloc(c->H);
	j.first = malloc(((size_t)c->n_blocks + 1) * sizeof *j.first);
	j.slot = malloc(((size_t)c->n_blocks + 1) * sizeof *j.slot);
	j.keys = malloc(((size_t)c->n_blocks + 1) * sizeof *j.keys);
	if (!j.px || !j.py || !j.npx || !j.npy || !j.first || !j.slot || !j.keys)
		goto nomem;
	for (uint32_t i = 0; i < c->W; i++)
		j.npx[i] = cut(c->xa[i], c->xb[i], c->b1, &j.px[(size_t)i * PIECES]);
	for (uint32_t r = 0; r < c->H; r++)
		j.npy[r] = cut(c->ya[r], c->yb[r], c->b2, &j.py[(size_t)r * PIECES]);
	j.JL = crossing_list(j.px, j.npx, c->W, &j.nJ);
	j.IL = crossing_list(j.py, j.npy, c->H, &j.nI);
	if (!j.JL || !j.IL)
		goto nomem;
	mem += ((size_t)c->W + c->H) * PIECES * sizeof(bl_piece) +
	       (j.nJ + j.nI) * sizeof(int64_t) +
	       (size_t)c->nthreads * ROW_CACHE * j.nJ * 6;

	/* step 1: first use of every source block */
	for (uint32_t k = 0; k <= c->n_blocks; k++)
		atomic_init(&j.first[k], UINT64_MAX);
	atomic_store(&j.next, 0);
	run_threads(c, bl_discover_worker, &j);
	for (uint32_t k = 0; k < c->n_blocks; k++) {
		j.slot[k] = UINT32_MAX;
		if (atomic_load(&j.first[k]) != UINT64_MAX) {
			j.slot[k] = j.n_keys;
			j.keys[j.n_keys++] = k;
		}
	}
	j.slot[c->n_blocks] = UINT32_MAX;

	/* step 2: tables, texels as fine as the cap allows */
	table_cap = c->cap > mem ? c->cap - mem : 0;
	for (j.g = 1;; j.g++) {
		uint64_t tx = (c->b1 + j.g - 1) / j.g, ty = (c->b2 + j.g - 1) / j.g;
		uint64_t bytes = (uint64_t)j.n_keys * (tx + 1) * (ty + 1) * NCH * sizeof(float);
		if (bytes <= table_cap || (tx == 1 && ty == 1))
			break;
	}
	j.tab = calloc(j.n_keys ? j.n_keys : 1, sizeof *j.tab);
	if (!j.tab)
		goto nomem;
	for (uint32_t k = 0; k < j.n_keys; k++) {
		j.tab[k].tx = (c->b1 + j.g - 1) / j.g;
		j.tab[k].ty = (c->b2 + j.g - 1) / j.g;
		j.tab[k].sat = malloc((size_t)(j.tab[k].tx + 1) * (j.tab[k].ty + 1) * NCH *
		                      sizeof(float));
		if (!j.tab[k].sat)
			goto nomem;
		mem += (size_t)(j.tab[k].tx + 1) * (j.tab[k].ty + 1) * NCH * sizeof(float);
	}
	mem += (size_t)c->nthreads * ((size_t)(c->b1 + 2) * (c->b2 + 2) * 8 +
	                              RUN_MAX * (size_t)(c->z1 - c->z0) * 5);
	if (c->paint) /* the painted pieces' buffers */
		mem += (size_t)c->nthreads * (3 * ((size_t)c->b1 + 2) * 20 +
		                              RUN_MAX * (size_t)(c->z1 - c->z0) * 5);
	c->mem = mem;
	if (mem > c->cap) {
		char s1[40], s2[40];
		rc = LOOM_EBUDGET;
		snprintf(c->msg, sizeof c->msg, "a block-filtered preview of this box needs "
		         "%s, more than the %s allowed",
		         loom__size_text(s1, sizeof s1, (double)mem),
		         loom__size_text(s2, sizeof s2, (double)c->cap));
		goto done;
	}
	atomic_store(&j.next, 0);
	run_threads(c, bl_table_worker, &j);
	if ((rc = c->rc) != LOOM_OK)
		goto done;
	if (st) {
		st->blocks = j.n_keys;
		st->texel = j.g;
	}

	/* step 3: pixels, band by band */
	while (row < c->H) {
		uint32_t r2 = row + c->band_cap < c->H ? row + c->band_cap : c->H;
		c->band0 = row;
		c->band_rows = r2 - row;
		j.j0 = row;
		j.j1 = r2;
		atomic_store(&j.next_row, 0);
		run_threads(c, bl_pixel_worker, &j);
		if ((rc = c->rc) != LOOM_OK)
			goto done;
		if ((rc = emit_band(c, fn, user)) != 0)
			goto done;
		row = r2;
	}
	goto done;
nomem:
	rc = LOOM_ENOMEM;
	snprintf(c->msg, sizeof c->msg, "out of memory for the block tables");
done:
	if (j.tab)
		for (uint32_t k = 0; k < j.n_keys; k++)
			free(j.tab[k].sat);
	free(j.tab);
	free(j.px);
	free(j.py);
	free(j.npx);
	free(j.npy);
	free(j.JL);
	free(j.IL);
	free((void *)j.first);
	free(j.slot);
	free(j.keys);
	return rc;
}

/* ---- entry points --------------------------------------------------------------- */

static int run_empty(pv_ctx *c, loom_preview_band_fn fn, void *user)
{
	int rc = 0;
	for (uint32_t row = 0; row < c->H && rc == 0;) {
		uint32_t r2 = row + c->band_cap < c->H ? row + c->band_cap : c->H;
		c->band0 = row;
		c->band_rows = r2 - row;
		for (uint32_t r = row; r < r2; r++)
			for (uint32_t i = 0; i < c->W; i++) {
				pv_acc a;
				memset(&a, 0, sizeof a);
				add_column(c, &a, 0, 0, NULL, 0, 0, 0, 0, 1.0);
				put_pixel(c, r, i, &a);
			}
		rc = emit_band(c, fn, user);
		row = r2;
	}
	return rc;
}

LOOM_API int loom_preview_stream(loom_texture *t, const loom_fabric *f,
                                 const loom_preview_options *opt,
                                 loom_preview_band_fn fn, void *user,
                                 loom_preview_stats *stats, loom_diag *diag)
{
	double t0 = now_s();
	loom_fabric_db_identity id;
	const loom_design *d;
	loom_preview_options o;
	pv_ctx *c;
	int rc, filter;

	if (!t || !f || !opt || !fn)
		return loom__fail(diag, LOOM_EINVAL, "loom_preview: NULL argument");
	rc = loom_preview_size(opt, &(uint32_t){0}, &(uint32_t){0});
	if (rc != LOOM_OK)
		return loom__fail(diag, rc, "loom_preview: bad box or size (width %u, "
		                  "height %u, box x [%lld, %lld) y [%lld, %lld))",
		                  opt->width, opt->height, (long long)opt->lo[0],
		                  (long long)opt->hi[0], (long long)opt->lo[1],
		                  (long long)opt->hi[1]);
	/* options of an older, shorter struct take their defaults */
	memset(&o, 0, sizeof o);
	memcpy(&o, opt, opt->size < sizeof o ? opt->size : sizeof o);
	o.size = sizeof o;
	filter = o.filter;
	if (filter < LOOM_PREVIEW_AUTO || filter > LOOM_PREVIEW_BLOCKS)
		return loom__fail(diag, LOOM_EINVAL, "loom_preview: unknown filter %d", filter);
	if (loom_fabric_get_db_identity(f, &id) != LOOM_OK || !loom_fabric_attached(f))
		return loom__fail(diag, LOOM_EINVAL, "loom_preview: fabric is detached");
	d = loom_fabric_design(f);
	c = calloc(1, sizeof *c);
	if (!c)
		return loom__fail(diag, LOOM_ENOMEM, "loom_preview: out of memory");
	c->t = t;
	c->f = f;
	c->opt = &o;
	loom_preview_size(&o, &c->W, &c->H);
	c->b1 = id.block[0];
	c->b2 = id.block[1];
	c->n_blocks = id.n_blocks;
	c->X0 = o.lo[0];
	c->X1 = o.hi[0];
	c->Y0 = o.lo[1];
	c->Y1 = o.hi[1];
	c->nx = c->X1 - c->X0;
	c->ny = c->Y1 - c->Y0;
	c->z0 = 0;
	c->z1 = (int64_t)id.block[2];
	if (o.hi[2] > o.lo[2]) {
		c->z0 = o.lo[2] > 0 ? o.lo[2] : 0;
		c->z1 = o.hi[2] < c->z1 ? o.hi[2] : c->z1;
	}
	c->span = (double)(c->z1 - c->z0);
	c->cap = o.memory_bytes ? o.memory_bytes : DEFAULT_MEMORY;
	{
		float thf = o.threshold > 0 ? o.threshold : 0.2f;
		double tb = ceil((double)thf * 255.0 - 1e-3);
		c->thr = (uint8_t)(tb < 1 ? 1 : tb > 255 ? 255 : tb);
	}
	if (o.light[0] == 0 && o.light[1] == 0 && o.light[2] == 0) {
		c->L[0] = -0.4;
		c->L[1] = -0.5;
		c->L[2] = 0.77;
	} else {
		memcpy(c->L, o.light, sizeof c->L);
	}
	normalize3(c->L);
	c->Hv[0] = c->L[0];
	c->Hv[1] = c->L[1];
	c->Hv[2] = c->L[2] + 1.0;
	normalize3(c->Hv);
	memcpy(c->bg, o.background, sizeof c->bg);
	{
		const loom_yarn_type *ty = o.types ? o.types : d ? d->types : NULL;
		uint32_t nt = o.types ? o.n_types : d ? d->n_types : 0;
		for (uint32_t k = 0; ty && k < nt && k < 256; k++) {
			float al = ty[k].alignment;
			if (!(al > 0) || al > 1)
				al = 0.3f;
			memcpy(c->alb[k], ty[k].albedo, sizeof c->alb[k]);
			c->spk[k] = 0.25f * (1.0f - al);
			c->valid[k] = 1;
		}
	}
	c->nthreads = o.threads;
	if (c->nthreads == 0) {
		long n = sysconf(_SC_NPROCESSORS_ONLN);
		c->nthreads = n > 0 ? (uint32_t)n : 1;
	}
	if (c->nthreads > 256)
		c->nthreads = 256;
	pthread_mutex_init(&c->lock, NULL);
	atomic_init(&c->columns, 0);
	atomic_init(&c->reads, 0);
	c->total = (uint64_t)c->W * c->H;
	c->xa = malloc(c->W * sizeof *c->xa);
	c->xb = malloc(c->W * sizeof *c->xb);
	c->ya = malloc(c->H * sizeof *c->ya);
	c->yb = malloc(c->H * sizeof *c->yb);
	/* one band of output: a quarter of the cap, at least one row */
	c->band_cap = (uint32_t)(c->cap / 4 / ((size_t)c->W * BYTES_PER_PIXEL));
	if (c->band_cap < 1)
		c->band_cap = 1;
	if (c->band_cap > c->H)
		c->band_cap = c->H;
	c->o_rgb = malloc((size_t)c->band_cap * c->W * 3 * sizeof(float));
	c->o_al = malloc((size_t)c->band_cap * c->W * 3 * sizeof(float));
	c->o_h = malloc((size_t)c->band_cap * c->W * sizeof(float));
	c->o_kind = malloc((size_t)c->band_cap * c->W);
	if (!c->xa || !c->xb || !c->ya || !c->yb || !c->o_rgb || !c->o_al || !c->o_h ||
	    !c->o_kind) {
		rc = LOOM_ENOMEM;
		snprintf(c->msg, sizeof c->msg, "out of memory for %ux%u pixels", c->W, c->H);
		goto done;
	}
	footprints(c->X0, c->nx, c->W, c->xa, c->xb);
	footprints(c->Y0, c->ny, c->H, c->ya, c->yb);
	if (o.paint) { /* the paint, if it reaches the box's columns or their
	                  neighbours */
		int64_t plo[2] = {c->X0 - 1, c->Y0 - 1}, phi[2] = {c->X1 + 1, c->Y1 + 1};
		if (loom_paint_touches(o.paint, plo, phi))
			c->paint = o.paint;
	}
	if (filter == LOOM_PREVIEW_AUTO)
		filter = (double)c->nx * (double)c->ny <=
		         EXACT_MAX_COLS * (double)c->W * (double)c->H
		         ? LOOM_PREVIEW_EXACT : LOOM_PREVIEW_BLOCKS;
	if (stats)
		memset(stats, 0, sizeof *stats);
	if (c->z1 <= c->z0)
		rc = run_empty(c, fn, user);
	else if (filter == LOOM_PREVIEW_EXACT)
		rc = run_exact(c, fn, user);
	else
		rc = run_blocks(c, fn, user, stats);
	if (rc == LOOM_OK && c->rc != LOOM_OK)
		rc = c->rc;
	if (stats) {
		stats->pixels = (uint64_t)c->W * c->H;
		stats->columns = atomic_load(&c->columns);
		stats->region_reads = atomic_load(&c->reads);
		stats->empty = c->empty;
		stats->seconds = now_s() - t0;
		stats->filter = filter;
		stats->memory_bytes = c->mem + ((size_t)c->W + c->H) * 16;
	}
done:
	if (rc != LOOM_OK) {
		if (c->msg[0])
			rc = loom__fail(diag, rc, "loom_preview: %s", c->msg);
		else if (diag && rc > 0 && rc < LOOM_RESULT_COUNT_)
			loom__fail(diag, rc, "loom_preview: stopped by the caller (%d)", rc);
	}
	pthread_mutex_destroy(&c->lock);
	free(c->xa);
	free(c->xb);
	free(c->ya);
	free(c->yb);
	free(c->o_rgb);
	free(c->o_al);
	free(c->o_h);
	free(c->o_kind);
	free(c);
	return rc;
}

/* loom_preview: the bands copied into the caller's arrays. */
typedef struct pv_copy {
	float *rgb;
	const loom_preview_maps *maps;
} pv_copy;

static int copy_band(void *user, const loom_preview_band *b)
{
	pv_copy *cp = user;
	size_t off = (size_t)b->row0 * b->width, n = (size_t)b->rows * b->width;

	memcpy(cp->rgb + 3 * off, b->rgb, 3 * n * sizeof(float));
	if (cp->maps && cp->maps->height)
		memcpy(cp->maps->height + off, b->height, n * sizeof(float));
	if (cp->maps && cp->maps->albedo)
		memcpy(cp->maps->albedo + 3 * off, b->albedo, 3 * n * sizeof(float));
	if (cp->maps && cp->maps->kind)
		memcpy(cp->maps->kind + off, b->kind, n);
	return 0;
}

LOOM_API int loom_preview(loom_texture *t, const loom_fabric *f,
                          const loom_preview_options *opt, float *rgb,
                          const loom_preview_maps *maps,
                          loom_preview_stats *stats, loom_diag *diag)
{
	pv_copy cp = {rgb, maps};

	if (!rgb)
		return loom__fail(diag, LOOM_EINVAL, "loom_preview: NULL argument");
	return loom_preview_stream(t, f, opt, copy_band, &cp, stats, diag);
}
