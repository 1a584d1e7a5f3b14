/*
 * tools/loom/cmd_serve.c - `loom serve FABRIC|DRAFT`: a local deep-zoom
 * viewer of the cloth in the browser (docs/designers.md, docs/preview.md).
 *
 * The picture.  A window of the bolt, REPEATS x REPEATS design repeats
 * (enough for --size-mm of cloth), at 2 pixels per voxel at the deepest
 * level, cut into a zoom pyramid of 256-pixel tiles as OpenSeadragon reads
 * it: level L (0 .. top) is the picture scaled by 2^(L - top), top =
 * ceil(log2(largest side)).  Tile (L, x, y) is loom_preview_stream of the
 * voxel box it covers, 256 pixels wide: at the top level a voxel is 2 x 2
 * pixels (single fibres), at level 0 the whole window is one pixel; every
 * level is the area average of its columns (docs/preview.md), so the motif
 * reads at every zoom.
 *
 * Memory.  --budget is split up front: the texture's brick cache gets what
 * the rest leaves, each of at most SERVE_TILE_WORKERS tiles in the making
 * gets TILE_MEMORY for the preview's buffers, a render of the view gets
 * RENDER_MEMORY (one at a time).  Tiles are written to the on-disk cache
 * (bounded by --cache-mb, least recently used evicted, serve_cache.c) and
 * served from there; a colour change gives new file names (the colour
 * table's hash is in the key), so nothing is re-synthesized.
 *
 * Requests (all GET but the colour change; anything else is 4xx):
 *   /, /NAME.js|css|html, /images/NAME.png  the page (DATA/web)
 *   /api/info                               picture size, levels, yarns
 *   /tile/L/X/Y.png                         a tile (400 malformed, 404 out
 *                                           of range, 429 when too many wait)
 *   /drawdown.png                           colour drawdown of the window
 *   POST /api/color?type=K&rgb=RRGGBB       change a yarn's colour
 *   POST /api/paint?x0=&y0=&x1=&y1=&effect= paint a region (colour, defect
 *                                           or weave; serve_paint)
 *   /painted/K.png                          drawdown of painted weave K
 *   /api/render?x0=&y0=&x1=&y1=&w=&h=       a path-traced picture of a view
 *                                           (fractions of the picture); 429
 *                                           while another one runs
 * Paths are checked character by character against a short whitelist, so
 * "..", "//", "%" escapes and anything outside the page's own files never
 * reach the file system.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "picture.h"
#include "paintfile.h"
#include "progress.h"
#include "serve.h"
#include "views.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define TILE 256u
#define SERVE_TILE_WORKERS 4u        /* tiles made at once */
#define SERVE_MAX_WAITING 16u        /* more waiting tile requests: 429 */
#define TILE_MEMORY ((size_t)3 << 20)
#define RENDER_MEMORY ((size_t)24 << 20)
#define RENDER_MAX_W 640u
#define RENDER_MAX_H 400u
#define PX_PER_VOXEL 2               /* top level: a voxel is 2 x 2 pixels */

static const char usage[] =
	"loom serve FABRIC|DRAFT [--port P] [--bind ADDR] [--budget MB]\n"
	"           [--cache DIR] [--cache-mb MB] [--size-mm MM] [--db DB]\n"
	"           [--threads N] [--paint-file PAINT] [--quiet]\n";

static const char about[] =
	"Serve a deep-zoom viewer of the cloth on http://127.0.0.1:P/: the whole\n"
	"window of the bolt down to single fibres, each tile computed on demand\n"
	"from the virtual texture within --budget and cached on disk; the colour\n"
	"drawdown beside it, synchronised; yarn colours editable (no new\n"
	"synthesis); a button for a render of the view.  A DRAFT (WIF or any\n"
	"design) is synthesized first over the exemplar database.  FABRIC may\n"
	"be a paint file (loom paint): its painted regions are shown.  Stop with\n"
	"Ctrl-C.\n";

typedef struct server {
	loom_fabric *f;
	loom_db *db;
	loom_texture *t;
	loom_paint *paint;            /* a paint file's layer (bound to t), or NULL */
	int64_t (*patch)[4];          /* painted weaves' crossings in the window:
	                                 I0, J0, rows, cols (the drawdown's
	                                 patches over the repeat) */
	uint32_t n_patches;
	pthread_rwlock_t paint_lock;  /* readers: tiles, renders; writer: the
	                                 paint tool swapping s->paint */
	char paint_path[4096];        /* where the paint tool saves ("" = none) */
	char fabric_abs[4096];        /* the fabric's absolute path */
	uint64_t paint_hash;          /* FNV-1a of the paint's text (cache keys) */
	loom_design *d;               /* the fabric's design (a copy: painted
	                                 weaves swap the fabric, not the design) */
	loom_texture_options to;      /* the texture's options (the paint tool
	                                 re-opens it over a re-woven fabric) */
	loom_fabric_db_identity id;
	serve_cache *cache;
	char web[4096];
	int64_t win[2];               /* window size in voxels */
	uint32_t reps[2];             /* repeats across, along */
	uint64_t img[2];              /* picture at the top level, pixels */
	uint32_t top;                 /* deepest level */
	pthread_mutex_t lock;         /* types, version */
	loom_yarn_type *types;        /* the colour table served */
	uint32_t n_types;
	uint32_t version;
	pthread_mutex_t render_lock;  /* one render at a time */
	atomic_uint waiting, working;
	pthread_mutex_t work_lock;
	pthread_cond_t work_cond;
	int quiet;
	atomic_ullong tiles_made, tiles_cached, rejected;
} server;

/* ---- responses ---------------------------------------------------------------- */

static enum MHD_Result reply(struct MHD_Connection *conn, unsigned code,
                             const char *type, const char *body)
{
	struct MHD_Response *r = MHD_create_response_from_buffer(
		strlen(body), (void *)body, MHD_RESPMEM_MUST_COPY);
	enum MHD_Result rc;

	if (!r)
		return MHD_NO;
	MHD_add_response_header(r, "Content-Type", type);
	MHD_add_response_header(r, "Cache-Control", "no-store");
	rc = MHD_queue_response(conn, code, r);
	MHD_destroy_response(r);
	return rc;
}

static enum MHD_Result error(struct MHD_Connection *conn, unsigned code,
                             const char *what)
{
	char buf[512];
	snprintf(buf, sizeof buf, "{\"error\": %u, \"message\": \"%s\"}\n", code, what);
	return reply(conn, code, "application/json", buf);
}

static const char *mime_of(const char *path)
{
	if (cli_ends_with(path, ".html"))
		return "text/html; charset=utf-8";
	if (cli_ends_with(path, ".js"))
		return "text/javascript";
	if (cli_ends_with(path, ".css"))
		return "text/css";
	if (cli_ends_with(path, ".png"))
		return "image/png";
	if (cli_ends_with(path, ".json"))
		return "application/json";
	return "application/octet-stream";
}

static enum MHD_Result send_file(struct MHD_Connection *conn, const char *path,
                                 int cacheable)
{
	struct stat st;
	struct MHD_Response *r;
	enum MHD_Result rc;
	int fd = open(path, O_RDONLY | O_NONBLOCK);

	if (fd < 0)
		return error(conn, MHD_HTTP_NOT_FOUND, "no such file");
	if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
		close(fd);
		return error(conn, MHD_HTTP_NOT_FOUND, "no such file");
	}
	r = MHD_create_response_from_fd((size_t)st.st_size, fd);
	if (!r) {
		close(fd);
		return MHD_NO;
	}
	MHD_add_response_header(r, "Content-Type", mime_of(path));
	MHD_add_response_header(r, "Cache-Control",
	                        cacheable ? "max-age=86400" : "no-store");
	rc = MHD_queue_response(conn, MHD_HTTP_OK, r);
	MHD_destroy_response(r);
	return rc;
}

/* ---- the page --------------------------------------------------------------- */

/* A file of the page: "/" or "/NAME" or "/images/NAME", NAME of letters,
   digits, '-', '_', '.', not starting with '.'.  0 if url is not one. */
static int page_path(const server *s, const char *url, char *buf, size_t n)
{
	const char *name = url + 1;
	const char *sub = "";

	if (strcmp(url, "/") == 0)
		name = "index.html";
	else if (strncmp(url, "/images/", 8) == 0) {
		name = url + 8;
		sub = "images/";
	}
	if (!*name || name[0] == '.' || strlen(name) > 64)
		return 0;
	for (const char *p = name; *p; p++)
		if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		      (*p >= '0' && *p <= '9') || *p == '-' || *p == '_' || *p == '.'))
			return 0;
	if (strstr(name, ".."))
		return 0;
	snprintf(buf, n, "%s/%s%s", s->web, sub, name);
	return 1;
}

/* ---- tiles ---------------------------------------------------------------------- */

static uint64_t level_size(const server *s, uint32_t L, int axis)
{
	uint64_t scale = (uint64_t)1 << (s->top - L);
	return (s->img[axis] + scale - 1) / scale;
}

/* Strict decimal of at most 9 digits; -1 if not. */
static long long number(const char *p, size_t n)
{
	long long v = 0;
	if (n == 0 || n > 9)
		return -1;
	for (size_t k = 0; k < n; k++) {
		if (p[k] < '0' || p[k] > '9')
			return -1;
		v = v * 10 + (p[k] - '0');
	}
	return v;
}

/* 64-bit FNV-1a of the colour table: part of every tile's name. */
static uint64_t table_hash(const loom_yarn_type *t, uint32_t n)
{
	uint64_t h = 0xcbf29ce484222325ull;
	for (uint32_t k = 0; k < n; k++) {
		const unsigned char *b = (const unsigned char *)t[k].albedo;
		for (size_t q = 0; q < sizeof t[k].albedo; q++)
			h = (h ^ b[q]) * 0x100000001b3ull;
	}
	return h;
}

/* Snapshot of the colour table (caller frees). */
static loom_yarn_type *snapshot(server *s, uint32_t *n, uint64_t *hash)
{
	loom_yarn_type *t;

	pthread_mutex_lock(&s->lock);
	*n = s->n_types;
	t = malloc((size_t)*n * sizeof *t);
	if (t)
		memcpy(t, s->types, (size_t)*n * sizeof *t);
	*hash = s->paint_hash;
	pthread_mutex_unlock(&s->lock);
	if (t)
		*hash ^= table_hash(t, *n);
	return t;
}

/* The texture is gone only when a painted weave's swap failed twice. */
static int no_texture(loom_diag *diag)
{
	snprintf(diag->message, sizeof diag->message, "the texture could not be "
	         "re-opened after painting a weave");
	return LOOM_EUNUSABLE;
}

static int make_tile(server *s, uint32_t L, uint64_t tx, uint64_t ty,
                     const loom_yarn_type *types, uint32_t n_types, const char *path,
                     char *err, size_t n)
{
	uint64_t scale = (uint64_t)1 << (s->top - L);
	uint64_t lw = level_size(s, L, 0), lh = level_size(s, L, 1);
	uint64_t px0 = tx * TILE, py0 = ty * TILE;
	uint64_t px1 = px0 + TILE < lw ? px0 + TILE : lw, py1 = py0 + TILE < lh ? py0 + TILE : lh;
	loom_preview_options po = LOOM_PREVIEW_OPTIONS_INIT;
	loom_diag diag = {0};
	pic_out pic;
	int rc;

	/* picture pixels -> voxels (PX_PER_VOXEL pixels per voxel at the top) */
	po.lo[0] = (int64_t)(px0 * scale / PX_PER_VOXEL);
	po.lo[1] = (int64_t)(py0 * scale / PX_PER_VOXEL);
	po.hi[0] = (int64_t)((px1 * scale + PX_PER_VOXEL - 1) / PX_PER_VOXEL);
	po.hi[1] = (int64_t)((py1 * scale + PX_PER_VOXEL - 1) / PX_PER_VOXEL);
	if (po.hi[0] > s->win[0])
		po.hi[0] = s->win[0];
	if (po.hi[1] > s->win[1])
		po.hi[1] = s->win[1];
	if (po.hi[0] <= po.lo[0])
		po.hi[0] = po.lo[0] + 1;
	if (po.hi[1] <= po.lo[1])
		po.hi[1] = po.lo[1] + 1;
	po.width = (uint32_t)(px1 - px0);
	po.height = (uint32_t)(py1 - py0);
	po.threads = 1;
	po.memory_bytes = TILE_MEMORY;
	po.types = types;
	po.n_types = n_types;
	po.background[0] = po.background[1] = po.background[2] = 0.02f;
	memset(&pic, 0, sizeof pic);
	pic.path = path;
	if ((rc = pic_open(&pic, po.width, po.height, &diag)) == LOOM_OK) {
		pthread_rwlock_rdlock(&s->paint_lock);
		po.paint = s->paint;
		rc = s->t ? loom_preview_stream(s->t, s->f, &po, pic_band, &pic, NULL, &diag)
		          : no_texture(&diag);
		pthread_rwlock_unlock(&s->paint_lock);
		if (rc == LOOM_OK)
			rc = pic_finish(&pic);
		else
			pic_abort(&pic);
	}
	if (rc != LOOM_OK)
		snprintf(err, n, "%s", diag.message);
	return rc;
}

/* Wait for a tile worker slot; 0 = too many waiting already. */
static int enter_work(server *s)
{
	if (atomic_fetch_add(&s->waiting, 1) >= SERVE_MAX_WAITING) {
		atomic_fetch_sub(&s->waiting, 1);
		return 0;
	}
	pthread_mutex_lock(&s->work_lock);
	while (atomic_load(&s->working) >= SERVE_TILE_WORKERS)
		pthread_cond_wait(&s->work_cond, &s->work_lock);
	atomic_fetch_add(&s->working, 1);
	pthread_mutex_unlock(&s->work_lock);
	atomic_fetch_sub(&s->waiting, 1);
	return 1;
}

static void leave_work(server *s)
{
	pthread_mutex_lock(&s->work_lock);
	atomic_fetch_sub(&s->working, 1);
	pthread_cond_signal(&s->work_cond);
	pthread_mutex_unlock(&s->work_lock);
}

static enum MHD_Result serve_tile(server *s, struct MHD_Connection *conn,
                                  const char *url)
{
	/* "/tile/L/X/Y.png" */
	const char *p = url + 6, *q1 = strchr(p, '/'), *q2, *dot;
	long long L, X, Y;
	char key[96], path[4200], err[LOOM_DIAG_MSG_MAX];
	loom_yarn_type *types;
	uint32_t nt;
	uint64_t hash;
	int rc;

	if (!q1 || !(q2 = strchr(q1 + 1, '/')) || !(dot = strchr(q2 + 1, '.')) ||
	    strcmp(dot, ".png") != 0)
		return error(conn, MHD_HTTP_BAD_REQUEST, "expected /tile/LEVEL/X/Y.png");
	L = number(p, (size_t)(q1 - p));
	X = number(q1 + 1, (size_t)(q2 - q1 - 1));
	Y = number(q2 + 1, (size_t)(dot - q2 - 1));
	if (L < 0 || X < 0 || Y < 0)
		return error(conn, MHD_HTTP_BAD_REQUEST, "tile coordinates must be whole "
		             "numbers of at most 9 digits");
	if ((uint64_t)L > s->top)
		return error(conn, MHD_HTTP_NOT_FOUND, "no such zoom level");
	if ((uint64_t)X * TILE >= level_size(s, (uint32_t)L, 0) ||
	    (uint64_t)Y * TILE >= level_size(s, (uint32_t)L, 1))
		return error(conn, MHD_HTTP_NOT_FOUND, "tile outside the picture");
	types = snapshot(s, &nt, &hash);
	if (!types)
		return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "out of memory");
	snprintf(key, sizeof key, "t%016llx-%lld-%lld-%lld.png", (unsigned long long)hash,
	         L, X, Y);
	serve_cache_path(s->cache, key, path, sizeof path);
	if (serve_cache_lookup(s->cache, key)) {
		free(types);
		atomic_fetch_add(&s->tiles_cached, 1);
		return send_file(conn, path, 1);
	}
	if (!enter_work(s)) {
		free(types);
		atomic_fetch_add(&s->rejected, 1);
		return error(conn, MHD_HTTP_TOO_MANY_REQUESTS, "too many tiles waiting; "
		             "try again");
	}
	rc = serve_cache_lookup(s->cache, key) ? LOOM_OK
	     : make_tile(s, (uint32_t)L, (uint64_t)X, (uint64_t)Y, types, nt, path, err,
	                 sizeof err);
	leave_work(s);
	free(types);
	if (rc != LOOM_OK)
		return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR, "tile failed");
	serve_cache_add(s->cache, key);
	atomic_fetch_add(&s->tiles_made, 1);
	return send_file(conn, path, 1);
}

/* ---- drawdown, info, colours, renders ------------------------------------- */

static enum MHD_Result serve_drawdown(server *s, struct MHD_Connection *conn)
{
	char key[96], path[4200];
	loom_design *d = NULL;
	uint32_t nt;
	uint64_t hash;
	loom_yarn_type *types = snapshot(s, &nt, &hash);
	loom_diag diag = {0};
	int rc;

	if (!types)
		return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "out of memory");
	snprintf(key, sizeof key, "d%016llx.png", (unsigned long long)hash);
	serve_cache_path(s->cache, key, path, sizeof path);
	if (serve_cache_lookup(s->cache, key)) {
		free(types);
		return send_file(conn, path, 1);
	}
	/* one repeat in the served colours; the page tiles it over the window */
	rc = loom_design_clone(s->d, &d);
	if (rc == LOOM_OK) {
		memcpy(d->types, types, (size_t)(nt < d->n_types ? nt : d->n_types) *
		                        sizeof *types);
		rc = loom_color_drawdown_write(path, d, 1, &diag);
	}
	loom_design_free(d);
	free(types);
	if (rc != LOOM_OK)
		return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR, "drawdown failed");
	serve_cache_add(s->cache, key);
	return send_file(conn, path, 1);
}

/* /painted/K.png: the drawdown of painted-weave patch K, its crossings as
   the painted fabric weaves them, in the served colours (the page draws it
   over the repeat's pattern). */
static enum MHD_Result serve_patch(server *s, struct MHD_Connection *conn,
                                   const char *url)
{
	char key[96], path[4200];
	loom_design *d = NULL;
	uint32_t nt;
	uint64_t hash;
	long long k = number(url, strlen(url) - 4);
	loom_yarn_type *types;
	loom_diag diag = {0};
	int rc;

	if (strlen(url) < 5 || strcmp(url + strlen(url) - 4, ".png") || k < 0)
		return error(conn, MHD_HTTP_NOT_FOUND, "no such painted weave");
	if (!(types = snapshot(s, &nt, &hash)))
		return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "out of memory");
	/* the fabric and its patches may be swapped by the paint tool */
	pthread_rwlock_rdlock(&s->paint_lock);
	if (k >= (long long)s->n_patches) {
		pthread_rwlock_unlock(&s->paint_lock);
		free(types);
		return error(conn, MHD_HTTP_NOT_FOUND, "no such painted weave");
	}
	snprintf(key, sizeof key, "p%016llx-%lld.png", (unsigned long long)hash, k);
	serve_cache_path(s->cache, key, path, sizeof path);
	if (serve_cache_lookup(s->cache, key)) {
		pthread_rwlock_unlock(&s->paint_lock);
		free(types);
		return send_file(conn, path, 1);
	}
	{
		const int64_t *p = s->patch[k];
		rc = loom_design_new((uint32_t)p[2], (uint32_t)p[3], &d);
		if (rc == LOOM_OK)
			rc = loom_design_set_types(d, nt);
		for (uint32_t r = 0; rc == LOOM_OK && r < (uint32_t)p[2]; r++)
			for (uint32_t c = 0; c < (uint32_t)p[3]; c++) {
				loom_fabric_source src;
				size_t i = (size_t)r * (size_t)p[3] + c;
				if ((rc = loom_fabric_source_at(s->f, p[0] + r, p[1] + c, &src)))
					break;
				d->weave[i] = src.warp_over;
				d->warp_type[i] = src.warp_type;
				d->weft_type[i] = src.weft_type;
			}
		if (rc == LOOM_OK) {
			memcpy(d->types, types, (size_t)nt * sizeof *types);
			rc = loom_color_drawdown_write(path, d, 1, &diag);
		}
	}
	pthread_rwlock_unlock(&s->paint_lock);
	loom_design_free(d);
	free(types);
	if (rc != LOOM_OK)
		return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR, "drawdown failed");
	serve_cache_add(s->cache, key);
	return send_file(conn, path, 1);
}

static uint8_t to_srgb8(float lin)
{
	double c = lin <= 0 ? 0 : lin >= 1 ? 1 : lin;
	c = c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1 / 2.4) - 0.055;
	return (uint8_t)lrint(c * 255.0);
}

static enum MHD_Result serve_info(server *s, struct MHD_Connection *conn)
{
	char *buf;
	size_t cap, len = 0;
	enum MHD_Result rc;
	uint64_t cb;
	uint32_t cf;

	/* the patches may be swapped by the paint tool: held to the end
	   (the order is paint_lock, then lock, as everywhere) */
	pthread_rwlock_rdlock(&s->paint_lock);
	cap = 4096 + (size_t)s->n_types * 160 + (size_t)s->n_patches * 96;
	buf = malloc(cap);
	if (!buf) {
		pthread_rwlock_unlock(&s->paint_lock);
		return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "out of memory");
	}
	serve_cache_usage(s->cache, &cb, &cf);
	pthread_mutex_lock(&s->lock);
	len += (size_t)snprintf(buf + len, cap - len,
		"{\"width\": %llu, \"height\": %llu, \"tile_size\": %u, \"max_level\": %u,\n"
		" \"pixels_per_voxel\": %d, \"voxel_um\": %g, \"window_voxels\": [%lld, %lld],\n"
		" \"repeats\": [%u, %u], \"design\": [%u, %u], \"block\": [%u, %u, %u],\n"
		" \"version\": %u, \"cache_bytes\": %llu, \"cache_files\": %u,\n"
		" \"tiles_made\": %llu, \"tiles_cached\": %llu, \"rejected\": %llu,\n"
		" \"yarns\": [",
		(unsigned long long)s->img[0], (unsigned long long)s->img[1], TILE, s->top,
		PX_PER_VOXEL, s->id.voxel_size_um, (long long)s->win[0], (long long)s->win[1],
		s->reps[0], s->reps[1], s->d->rows, s->d->cols, s->id.block[0],
		s->id.block[1], s->id.block[2], s->version, (unsigned long long)cb, cf,
		(unsigned long long)atomic_load(&s->tiles_made),
		(unsigned long long)atomic_load(&s->tiles_cached),
		(unsigned long long)atomic_load(&s->rejected));
	for (uint32_t k = 0; k < s->n_types; k++) {
		const loom_yarn_type *y = &s->types[k];
		char name[2 * LOOM_YARN_NAME_MAX];
		size_t m = 0;
		for (const char *c = y->name; *c && m + 2 < sizeof name; c++)
			if (*c != '"' && *c != '\\' && (unsigned char)*c >= 32)
				name[m++] = *c;
		name[m] = 0;
		len += (size_t)snprintf(buf + len, cap - len,
		                        "%s{\"id\": %u, \"name\": \"%s\", \"rgb\": \"#%02x%02x%02x\"}",
		                        k ? ", " : "", k, name, to_srgb8(y->albedo[0]),
		                        to_srgb8(y->albedo[1]), to_srgb8(y->albedo[2]));
	}
	pthread_mutex_unlock(&s->lock);
	len += (size_t)snprintf(buf + len, cap - len, "],\n \"painted_weaves\": [");
	for (uint32_t k = 0; k < s->n_patches; k++)
		len += (size_t)snprintf(buf + len, cap - len, "%s[%lld, %lld, %lld, %lld]",
		                        k ? ", " : "", (long long)s->patch[k][0],
		                        (long long)s->patch[k][1], (long long)s->patch[k][2],
		                        (long long)s->patch[k][3]);
	pthread_rwlock_unlock(&s->paint_lock);
	snprintf(buf + len, cap - len, "]}\n");
	rc = reply(conn, MHD_HTTP_OK, "application/json", buf);
	free(buf);
	return rc;
}

static int hexval(char c)
{
	return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10
	       : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

static float srgb_to_lin(int v)
{
	double c = v / 255.0;
	return (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
}

static enum MHD_Result serve_color(server *s, struct MHD_Connection *conn)
{
	const char *ts = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "type");
	const char *rgb = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "rgb");
	long long k = ts ? number(ts, strlen(ts)) : -1;
	int v[6];
	char buf[64];
	uint32_t ver;

	if (!rgb || strlen(rgb) != 6 || k < 0)
		return error(conn, MHD_HTTP_BAD_REQUEST, "expected ?type=ID&rgb=RRGGBB");
	for (int q = 0; q < 6; q++)
		if ((v[q] = hexval(rgb[q])) < 0)
			return error(conn, MHD_HTTP_BAD_REQUEST, "expected rgb=RRGGBB (hex)");
	pthread_mutex_lock(&s->lock);
	if ((uint64_t)k >= s->n_types) {
		pthread_mutex_unlock(&s->lock);
		return error(conn, MHD_HTTP_NOT_FOUND, "no such yarn type");
	}
	for (int c = 0; c < 3; c++)
		s->types[k].albedo[c] = srgb_to_lin(v[2 * c] * 16 + v[2 * c + 1]);
	ver = ++s->version;
	pthread_mutex_unlock(&s->lock);
	snprintf(buf, sizeof buf, "{\"version\": %u}\n", ver);
	return reply(conn, MHD_HTTP_OK, "application/json", buf);
}

/* A finite number argument; *bad set when absent or not a number. */
static double num_arg(struct MHD_Connection *conn, const char *name, double def,
                      int *bad)
{
	const char *v = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, name);
	char *end;
	double x;

	if (!v)
		return def;
	x = strtod(v, &end);
	if (!*v || *end || !isfinite(x)) {
		*bad = 1;
		return def;
	}
	return x;
}

/* The painted weaves' crossings inside the window (crossings whose centre
   may lie in a weave region, as loom_paint_apply_weaves picks them): a
   malloc'ed array of *n entries I0, J0, rows, cols, or NULL (no memory). */
static int64_t (*painted_patches(const server *s, const loom_paint *p, uint32_t *n))[4]
{
	uint32_t m = loom_paint_count(p);
	double vmm = s->id.voxel_size_um * 1e-3, b1 = s->id.block[0], b2 = s->id.block[1];
	double cols = (double)s->win[0] / b1, rows = (double)s->win[1] / b2;
	int64_t (*patch)[4] = malloc((m ? m : 1) * sizeof *patch);

	*n = 0;
	if (!patch)
		return NULL;
	for (uint32_t i = 0; i < m; i++) {
		const loom_paint_region *r = loom_paint_get(p, i);
		double J0, J1, I0, I1;
		if (r->effect != LOOM_PAINT_WEAVE)
			continue;
		J0 = fmax(0, floor(r->x0 / vmm / b1 - 0.5));
		J1 = fmin(cols - 1, ceil(r->x1 / vmm / b1 - 0.5));
		I0 = fmax(0, floor(r->y0 / vmm / b2 - 0.5));
		I1 = fmin(rows - 1, ceil(r->y1 / vmm / b2 - 0.5));
		if (J1 < J0 || I1 < I0)
			continue;
		patch[*n][0] = (int64_t)I0;
		patch[*n][1] = (int64_t)J0;
		patch[*n][2] = (int64_t)(I1 - I0 + 1);
		patch[*n][3] = (int64_t)(J1 - J0 + 1);
		(*n)++;
	}
	return patch;
}

/* "what: why" for a JSON error: quotes and backslashes made plain. */
static const char *paint_msg(char *out, size_t n, const char *what, const char *why)
{
	snprintf(out, n, "%s: %.300s", what, why);
	for (char *c = out; *c; c++)
		if (*c == '"' || *c == '\\' || (unsigned char)*c < 32)
			*c = '\'';
	return out;
}

/* A weave for the paint tool: weave=NAME (loom_weave_parse: plain,
   twill:2/2, satin:1/4, ...) or draft=ROWS (rows of 0 and 1 separated by
   '/', pick 1 first, end 1 leftmost, 1 = warp over, at most
   SERVE_MAX_DRAFT a side).  LOOM_OK, or LOOM_EINVAL with the reason in
   msg (a 400 answer). */
#define SERVE_MAX_DRAFT 64u
static int paint_weave(const char *name, const char *draft, loom_design **out,
                       char *msg, size_t n)
{
	loom_diag d = {0};
	uint32_t rows = 0, cols = 0, c = 0;

	*out = NULL;
	if ((name != NULL) == (draft != NULL)) {
		snprintf(msg, n, "effect=weave needs exactly one of weave=NAME (plain, "
		         "twill:2/2, satin:1/4, ...) and draft=ROWS (e.g. 1100/0110/0011/1001)");
		return LOOM_EINVAL;
	}
	if (name) {
		loom_weave_params wp;
		if (loom_weave_parse(name, &wp, &d) != LOOM_OK ||
		    loom_design_make(&wp, 0, 0, out, &d) != LOOM_OK) {
			paint_msg(msg, n, "weave", d.message);
			return LOOM_EINVAL;
		}
		if ((*out)->rows > SERVE_MAX_DRAFT || (*out)->cols > SERVE_MAX_DRAFT) {
			snprintf(msg, n, "weave: a %ux%u repeat; the paint tool takes at most "
			         "%ux%u", (*out)->rows, (*out)->cols, SERVE_MAX_DRAFT, SERVE_MAX_DRAFT);
			loom_design_free(*out);
			*out = NULL;
			return LOOM_EINVAL;
		}
		return LOOM_OK;
	}
	/* the draft's size: every row as long as the first */
	for (const char *p = draft;; p++) {
		if (*p == '0' || *p == '1') {
			c++;
		} else if (*p == '/' || !*p) {
			if (c == 0 || (rows && c != cols)) {
				snprintf(msg, n, "draft: row %u has %u cells (row 1: %u); rows of "
				         "0 and 1 separated by '/', all of one length", rows + 1, c,
				         rows ? cols : c);
				return LOOM_EINVAL;
			}
			cols = c;
			c = 0;
			if (++rows > SERVE_MAX_DRAFT || cols > SERVE_MAX_DRAFT) {
				snprintf(msg, n, "draft: at most %ux%u", SERVE_MAX_DRAFT, SERVE_MAX_DRAFT);
				return LOOM_EINVAL;
			}
			if (!*p)
				break;
		} else {
			snprintf(msg, n, "draft: character %d is '%c'; rows of 0 and 1 "
			         "separated by '/'", (int)(p - draft) + 1,
			         (unsigned char)*p >= 32 && *p != '"' && *p != '\\' ? *p : '?');
			return LOOM_EINVAL;
		}
	}
	if (loom_design_new(rows, cols, out) != LOOM_OK) {
		snprintf(msg, n, "draft: out of memory");
		return LOOM_ENOMEM;
	}
	for (size_t i = 0, k = 0; draft[k]; k++)
		if (draft[k] != '/')
			(*out)->weave[i++] = (uint8_t)(draft[k] == '1');
	return LOOM_OK;
}

/*
 * Re-open the texture over fabric f (the write lock held; the old
 * texture is closed first, so the budget holds one texture at a time).
 * On failure s->t is NULL.
 */
static int reopen_texture(server *s, const loom_fabric *f, loom_diag *diag)
{
	loom_texture_close(s->t);
	s->t = NULL;
	return loom_texture_open(f, s->db, &s->to, &s->t, diag);
}

/*
 * POST /api/paint?x0=&y0=&x1=&y1=&effect=E[&kind=K][&rgb=RRGGBB]
 * [&strength=S][&blend=MM][&amount=V][&weave=NAME|&draft=ROWS][&band=N]:
 * the viewer's paint tool.  One region (cloth mm; the defaults of loom
 * paint), checked by loom_paint_add as loom paint checks it, added to the
 * paint layer, the paint file written (temporary name, then rename) and
 * the layer swapped in while no tile or render reads it.  A weave
 * (effect=weave) re-weaves the fabric as loom paint --weave and every
 * command reading the paint file do: the fabric re-opened and the
 * layer's weaves applied to it (loom_paint_apply_weaves), then, under the
 * write lock, the texture re-opened over it and the painted weaves'
 * drawdown patches re-made.
 */
static pthread_mutex_t paint_mu = PTHREAD_MUTEX_INITIALIZER; /* serve_paint */

static enum MHD_Result serve_paint(server *s, struct MHD_Connection *conn)
{
	const char *es = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "effect");
	const char *ks = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "kind");
	const char *rgb = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "rgb");
	const char *wn = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "weave");
	const char *ds = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "draft");
	loom_paint_region r;
	loom_paint *np = NULL, *old;
	loom_fabric *g = NULL, *old_f = NULL;
	loom_design *weave = NULL;
	int64_t (*patch)[4] = NULL, (*old_patch)[4] = NULL;
	uint32_t n_patch = 0, n_regions;
	loom_diag diag = {0};
	char *text = NULL, buf[96], msg[400];
	size_t len = 0;
	int bad = 0, rc;
	uint64_t h = 0xcbf29ce484222325ull;
	uint32_t ver;

	if (!s->paint_path[0])
		return error(conn, MHD_HTTP_CONFLICT, "painting needs a fabric file (serve a "
		             ".loomf or a paint file)");
	memset(&r, 0, sizeof r);
	r.effect = es ? loom_paint_effect_parse(es) : 0;
	if (!r.effect)
		return error(conn, MHD_HTTP_BAD_REQUEST, "effect must be yarn, stain, slub, "
		             "broken-end, missing-pick, pull or weave");
	if (r.effect != LOOM_PAINT_WEAVE && (wn || ds || MHD_lookup_connection_value(
	                                     conn, MHD_GET_ARGUMENT_KIND, "band")))
		return error(conn, MHD_HTTP_BAD_REQUEST, "weave, draft and band go with "
		             "effect=weave");
	if (r.effect == LOOM_PAINT_WEAVE && (ks || rgb))
		return error(conn, MHD_HTTP_BAD_REQUEST, "kind and rgb do not go with "
		             "effect=weave");
	r.x0 = num_arg(conn, "x0", NAN, &bad);
	r.y0 = num_arg(conn, "y0", NAN, &bad);
	r.x1 = num_arg(conn, "x1", NAN, &bad);
	r.y1 = num_arg(conn, "y1", NAN, &bad);
	r.kind = r.effect == LOOM_PAINT_SLUB || r.effect == LOOM_PAINT_PULL ? LOOM_YARN_WARP : 0;
	if (ks && !strcmp(ks, "warp"))
		r.kind = LOOM_YARN_WARP;
	else if (ks && !strcmp(ks, "weft"))
		r.kind = LOOM_YARN_WEFT;
	else if (ks && !strcmp(ks, "any"))
		r.kind = 0;
	else if (ks)
		bad = 1;
	if (r.effect != LOOM_PAINT_WEAVE) {
		r.rgb[0] = 0.35f;
		r.rgb[1] = 0.22f;
		r.rgb[2] = 0.08f;
	}
	if (rgb) {
		int v[6];
		if (strlen(rgb) != 6)
			bad = 1;
		for (int q = 0; !bad && q < 6; q++)
			if ((v[q] = hexval(rgb[q])) < 0)
				bad = 1;
		for (int c = 0; !bad && c < 3; c++)
			r.rgb[c] = srgb_to_lin(v[2 * c] * 16 + v[2 * c + 1]);
	}
	r.strength = r.effect == LOOM_PAINT_STAIN ? (float)num_arg(conn, "strength", 0.7, &bad)
	                                          : 0.0f;
	r.blend_mm = r.effect == LOOM_PAINT_YARN || r.effect == LOOM_PAINT_STAIN
	           ? num_arg(conn, "blend", 0.2, &bad) : 0;
	{
		double a = num_arg(conn, "amount", r.effect == LOOM_PAINT_SLUB ? 2 : 4, &bad);
		if (a < 0 || a > 1e6 || a != floor(a))
			bad = 1;
		else if (r.effect == LOOM_PAINT_SLUB || r.effect == LOOM_PAINT_PULL)
			r.amount = (uint32_t)a;
	}
	if (bad)
		return error(conn, MHD_HTTP_BAD_REQUEST, "expected x0, y0, x1, y1 (mm), "
		             "kind=any|warp|weft, rgb=RRGGBB, numbers for strength, blend, "
		             "amount");
	if (r.effect == LOOM_PAINT_WEAVE) {
		double band = num_arg(conn, "band", 1, &bad);
		if (bad || band != floor(band) || band < 0 || band > LOOM_PAINT_MAX_BAND) {
			snprintf(msg, sizeof msg, "band: a whole number of crossings, 0 to %u",
			         LOOM_PAINT_MAX_BAND);
			return error(conn, MHD_HTTP_BAD_REQUEST, msg);
		}
		r.band = (uint32_t)band;
		if ((rc = paint_weave(wn, ds, &weave, msg, sizeof msg)) != LOOM_OK)
			return error(conn, rc == LOOM_ENOMEM ? MHD_HTTP_SERVICE_UNAVAILABLE
			                                     : MHD_HTTP_BAD_REQUEST, msg);
		r.weave_w = weave->cols;
		r.weave_h = weave->rows;
		r.weave = weave->weave;
	}
	/* the new layer: the current one's regions and this one; one POST at a
	   time from here to the swap, so two at once cannot both start from the
	   same layer and lose one of the regions */
	pthread_mutex_lock(&paint_mu);
	pthread_rwlock_rdlock(&s->paint_lock);
	rc = s->paint ? loom_paint_format(s->paint, &text, &len) : LOOM_OK;
	pthread_rwlock_unlock(&s->paint_lock);
	if (rc == LOOM_OK)
		rc = text ? loom_paint_parse(text, len, s->paint_path, &np, &diag)
		          : loom_paint_new(s->fabric_abs, &np, &diag);
	free(text);
	text = NULL;
	if (rc != LOOM_OK) {
		loom_paint_free(np);
		pthread_mutex_unlock(&paint_mu);
		loom_design_free(weave);
		return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR, "paint: out of memory");
	}
	rc = loom_paint_add(np, &r, &diag);
	loom_design_free(weave);
	if (rc != LOOM_OK) {
		loom_paint_free(np);
		pthread_mutex_unlock(&paint_mu);
		return error(conn, MHD_HTTP_BAD_REQUEST, paint_msg(msg, sizeof msg, "paint refused",
		                                                   diag.message));
	}
	if (r.effect == LOOM_PAINT_WEAVE) {
		/* the fabric re-woven as a reader of the paint file weaves it */
		if ((rc = loom_fabric_open(s->fabric_abs, s->db, 0, &g, &diag)) != LOOM_OK) {
			loom_paint_free(np);
			pthread_mutex_unlock(&paint_mu);
			return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR,
			             paint_msg(msg, sizeof msg, "paint: the fabric", diag.message));
		}
		if ((rc = loom_paint_apply_weaves(np, &g, &diag)) != LOOM_OK ||
		    !(patch = painted_patches(s, np, &n_patch))) {
			loom_fabric_free(g);
			loom_paint_free(np);
			pthread_mutex_unlock(&paint_mu);
			if (rc == LOOM_OK || rc == LOOM_ENOMEM)
				return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "paint: out of memory");
			return error(conn, MHD_HTTP_BAD_REQUEST, paint_msg(msg, sizeof msg,
			             "paint refused", diag.message));
		}
	}
	if (loom_paint_format(np, &text, &len) != LOOM_OK ||
	    cli_write_atomic(s->paint_path, text, len, &diag) != LOOM_OK ||
	    (!g && loom_paint_bind(np, s->t, s->f) != LOOM_OK)) {
		free(text);
		free(patch);
		loom_fabric_free(g);
		loom_paint_free(np);
		pthread_mutex_unlock(&paint_mu);
		return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR,
		             paint_msg(msg, sizeof msg, "paint not saved", diag.message));
	}
	for (size_t k = 0; k < len; k++)
		h = (h ^ (unsigned char)text[k]) * 0x100000001b3ull;
	free(text);
	pthread_rwlock_wrlock(&s->paint_lock);
	if (g) {
		/* the new fabric in: its texture, the layer bound to both; if that
		   fails, the old fabric's texture back (the file holds the region:
		   a restart shows it) */
		if (reopen_texture(s, g, &diag) != LOOM_OK || loom_paint_bind(np, s->t, g) != LOOM_OK) {
			loom_diag d2 = {0};
			if (!diag.message[0])
				snprintf(diag.message, sizeof diag.message, "out of memory");
			if (reopen_texture(s, s->f, &d2) != LOOM_OK && !s->quiet)
				fprintf(stderr, "loom serve: %s\n", d2.message);
			pthread_rwlock_unlock(&s->paint_lock);
			pthread_mutex_unlock(&paint_mu);
			free(patch);
			loom_fabric_free(g);
			loom_paint_free(np);
			return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR,
			             paint_msg(msg, sizeof msg, "paint saved but not shown", diag.message));
		}
		old_f = s->f;
		s->f = g;
		old_patch = s->patch;
		s->patch = patch;
		s->n_patches = n_patch;
	}
	old = s->paint;
	s->paint = np;
	/* the new cache keys with the table lock, before the write lock goes:
	   no tile of the new layer is cached under the old key */
	pthread_mutex_lock(&s->lock);
	s->paint_hash = h;
	ver = ++s->version;
	pthread_mutex_unlock(&s->lock);
	n_regions = loom_paint_count(np);  /* np is the next POST's to free */
	n_patch = s->n_patches;
	pthread_rwlock_unlock(&s->paint_lock);
	pthread_mutex_unlock(&paint_mu);
	loom_paint_free(old);
	loom_fabric_free(old_f);
	free(old_patch);
	if (!s->quiet)
		fprintf(stderr, "loom serve: painted %s %g,%g:%g,%g mm; %u regions in %s\n",
		        es, r.x0, r.y0, r.x1, r.y1, n_regions, s->paint_path);
	snprintf(buf, sizeof buf, "{\"version\": %u, \"regions\": %u, \"painted_weaves\": %u}\n",
	         ver, n_regions, n_patch);
	return reply(conn, MHD_HTTP_OK, "application/json", buf);
}

/* The render's volume source: the texture, coloured by the served table. */
typedef struct render_src {
	loom_texture *t;
	const loom_paint *paint;      /* or NULL */
	const loom_yarn_type *types;
	uint32_t n_types;
} render_src;

static int render_lookup(void *ctx, const double p[3], loom_medium_sample *out)
{
	render_src *r = ctx;
	loom_texel tx;
	int rc = r->paint ? loom_paint_sample(r->paint, p, &tx)
	                  : loom_texture_sample(r->t, p, LOOM_FILTER_NEAREST, &tx);

	out->density = tx.density;
	memcpy(out->orient, tx.orientation, sizeof out->orient);
	if (tx.kind && tx.type < r->n_types) {
		/* the served colour, then the paint's tint of it */
		memcpy(out->albedo, r->types[tx.type].albedo, sizeof out->albedo);
		out->alignment = r->types[tx.type].alignment;
		if (r->paint)
			loom_paint_albedo(r->paint, (int64_t)floor(p[0]), (int64_t)floor(p[1]),
			                  tx.kind, out->albedo);
	} else {
		memcpy(out->albedo, tx.albedo, sizeof out->albedo);
		out->alignment = tx.alignment;
	}
	return rc == LOOM_OK ? 0 : 1;
}

static void render_thread_done(void *ctx, void *tctx)
{
	render_src *r = ctx;
	(void)tctx;
	loom_texture_thread_done(r->t);
}

static double frac_arg(struct MHD_Connection *conn, const char *name, int *bad)
{
	const char *v = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, name);
	char *end;
	double x;

	if (!v) {
		*bad = 1;
		return 0;
	}
	x = strtod(v, &end);
	if (*end || !isfinite(x) || x < -1 || x > 2)
		*bad = 1;
	return x;
}

static enum MHD_Result serve_render(server *s, struct MHD_Connection *conn)
{
	int bad = 0;
	double x0 = frac_arg(conn, "x0", &bad), y0 = frac_arg(conn, "y0", &bad);
	double x1 = frac_arg(conn, "x1", &bad), y1 = frac_arg(conn, "y1", &bad);
	const char *ws = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "w");
	long long w = ws ? number(ws, strlen(ws)) : 320, h;
	loom_volume_source src = LOOM_VOLUME_SOURCE_INIT, tsrc;
	loom_render_options ro = LOOM_RENDER_OPTIONS_INIT;
	render_src rs;
	view_prog vp;
	int64_t lo[2], hi[2];
	char key[96], path[4200];
	loom_diag diag = {0};
	uint64_t hash;
	int rc;

	if (bad || !(x1 > x0) || !(y1 > y0) || w < 16 || w > RENDER_MAX_W)
		return error(conn, MHD_HTTP_BAD_REQUEST, "expected x0<x1, y0<y1 (fractions of "
		             "the picture) and w in 16..640");
	h = w * 5 / 8;
	if (h > RENDER_MAX_H)
		h = RENDER_MAX_H;
	lo[0] = (int64_t)floor(x0 * (double)s->win[0]);
	hi[0] = (int64_t)ceil(x1 * (double)s->win[0]);
	/* y fractions are of the picture's height, as OpenSeadragon's viewport */
	lo[1] = (int64_t)floor(y0 * (double)s->win[1]);
	hi[1] = (int64_t)ceil(y1 * (double)s->win[1]);
	if (hi[0] <= lo[0] + 4 || hi[1] <= lo[1] + 4)
		return error(conn, MHD_HTTP_BAD_REQUEST, "the view is too small to render");
	if (pthread_mutex_trylock(&s->render_lock) != 0)
		return error(conn, MHD_HTTP_TOO_MANY_REQUESTS, "a render is running; try again");
	rs.types = snapshot(s, &rs.n_types, &hash);
	if (!rs.types || view_prog_init(&vp, (uint32_t)w, (uint32_t)h) != LOOM_OK) {
		free((void *)rs.types);
		pthread_mutex_unlock(&s->render_lock);
		return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "out of memory");
	}
	/* the texture, fabric and paint stay as they are until the end of the
	   pass (the paint tool swaps them under the write lock) */
	pthread_rwlock_rdlock(&s->paint_lock);
	if (!s->t) {
		pthread_rwlock_unlock(&s->paint_lock);
		view_prog_free(&vp);
		free((void *)rs.types);
		pthread_mutex_unlock(&s->render_lock);
		return error(conn, MHD_HTTP_SERVICE_UNAVAILABLE, "no texture");
	}
	rs.t = s->t;
	loom_texture_volume_source(s->t, s->f, LOOM_FILTER_NEAREST, &tsrc);
	src = tsrc;
	src.lookup = render_lookup;
	src.ctx = &rs;
	src.thread_init = NULL;
	src.thread_done = render_thread_done;
	view_render_setup(&src, lo, hi, (uint32_t)w, (uint32_t)h, &ro);
	ro.seed = 1;
	rs.paint = s->paint;
	rc = view_prog_pass(&vp, &src, &ro, 2, &diag);
	pthread_rwlock_unlock(&s->paint_lock);
	snprintf(key, sizeof key, "r%016llx-%lld-%lld-%lld-%lld-%lld.png",
	         (unsigned long long)hash, (long long)lo[0], (long long)lo[1],
	         (long long)hi[0], (long long)hi[1], w);
	serve_cache_path(s->cache, key, path, sizeof path);
	if (rc == LOOM_OK)
		rc = cli_write_rgb(path, vp.mean, (uint32_t)w, (uint32_t)h, 0, &diag);
	view_prog_free(&vp);
	free((void *)rs.types);
	pthread_mutex_unlock(&s->render_lock);
	if (rc != LOOM_OK)
		return error(conn, MHD_HTTP_INTERNAL_SERVER_ERROR, "render failed");
	serve_cache_add(s->cache, key);
	return send_file(conn, path, 0);
}

/* ---- dispatch ------------------------------------------------------------------- */

static enum MHD_Result handler(void *cls, struct MHD_Connection *conn, const char *url,
                               const char *method, const char *version,
                               const char *upload, size_t *upload_size, void **state)
{
	static int first;
	server *s = cls;
	int get = strcmp(method, "GET") == 0 || strcmp(method, "HEAD") == 0;
	int post = strcmp(method, "POST") == 0;
	char path[4200];

	(void)version;
	(void)upload;
	if (*state == NULL) { /* headers only: answer on the next call */
		*state = &first;
		return MHD_YES;
	}
	if (*upload_size) { /* bodies are not used: drop them */
		*upload_size = 0;
		return MHD_YES;
	}
	if (!get && !post)
		return error(conn, MHD_HTTP_METHOD_NOT_ALLOWED, "GET or POST only");
	if (strlen(url) > 200 || strstr(url, "..") || strstr(url, "//") ||
	    strchr(url, '\\') || strchr(url, '%'))
		return error(conn, MHD_HTTP_BAD_REQUEST, "malformed path");
	if (strcmp(url, "/api/color") == 0)
		return post ? serve_color(s, conn)
		            : error(conn, MHD_HTTP_METHOD_NOT_ALLOWED, "POST a colour change");
	if (strcmp(url, "/api/paint") == 0)
		return post ? serve_paint(s, conn)
		            : error(conn, MHD_HTTP_METHOD_NOT_ALLOWED, "POST a painted region");
	if (post && strcmp(url, "/api/render") != 0)
		return error(conn, MHD_HTTP_METHOD_NOT_ALLOWED, "GET only");
	if (strncmp(url, "/tile/", 6) == 0)
		return serve_tile(s, conn, url);
	if (strcmp(url, "/api/info") == 0)
		return serve_info(s, conn);
	if (strcmp(url, "/api/render") == 0)
		return serve_render(s, conn);
	if (strcmp(url, "/drawdown.png") == 0)
		return serve_drawdown(s, conn);
	if (strncmp(url, "/painted/", 9) == 0)
		return serve_patch(s, conn, url + 9);
	if (page_path(s, url, path, sizeof path))
		return send_file(conn, path, 0);
	return error(conn, MHD_HTTP_NOT_FOUND, "no such page");
}

/* ---- the command ---------------------------------------------------------------- */

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
	(void)sig;
	stop = 1;
}

/* Open FABRIC, or synthesize a DRAFT (any design loom reads). */
static void load(const char *prog, const char *in, const char *db_opt, server *s,
                 uint64_t *paint_hash, loom_diag *diag)
{
	*paint_hash = 0;
	if (cli_ends_with(in, ".loomf") || cli_is_paint(in)) {
		loom_paint *paint = NULL;
		if (db_opt && loom_db_open(db_opt, &s->db, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		if (cli_open_painted(in, s->db, &s->f, &paint, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		if (paint) {
			/* painted weaves are in the fabric now; the tile cache is
			   keyed by the paint's text too */
			char *text = NULL;
			size_t len = 0;
			if (loom_paint_format(paint, &text, &len) != LOOM_OK)
				cli_fail(prog, "out of memory");
			*paint_hash = 0xcbf29ce484222325ull;
			for (size_t k = 0; k < len; k++)
				*paint_hash = (*paint_hash ^ (unsigned char)text[k]) * 0x100000001b3ull;
			free(text);
			s->paint = paint; /* bound when the texture opens */
			snprintf(s->paint_path, sizeof s->paint_path, "%s", in);
			snprintf(s->fabric_abs, sizeof s->fabric_abs, "%s",
			         loom_paint_fabric(paint));
		} else if (!realpath(in, s->fabric_abs)) {
			cli_fail(prog, "%s: %s", in, strerror(errno));
		} else {
			/* the paint tool's file: FABRIC.loomp beside the fabric */
			size_t n = strlen(in) - strlen(".loomf");
			snprintf(s->paint_path, sizeof s->paint_path, "%.*s.loomp", (int)n, in);
		}
	} else {
		const char *db_path = cli_db_require(db_opt, prog);
		loom_design *d = NULL;
		loom_fabric_options fo = LOOM_FABRIC_OPTIONS_INIT;
		if (loom_design_read(in, &d, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		if (loom_db_open(db_path, &s->db, diag) != LOOM_OK ||
		    loom_fabric_synthesize(d, s->db, db_path, &fo, &s->f, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		loom_design_free(d);
	}
}

int cmd_serve(int argc, char **argv)
{
	const char *prog = "loom serve";
	const char *in = NULL, *db_opt = NULL, *cache_opt = NULL, *bind_opt = "127.0.0.1";
	const char *paint_out = NULL;
	uint32_t port = 8080, threads = 0;
	double budget_mb = 128, cache_mb = 256, size_mm = 200;
	int quiet = 0;
	server s;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	struct MHD_Daemon *daemon;
	struct sockaddr_in addr;
	const union MHD_DaemonInfo *info;
	char cache_dir[4300], err[600];
	uint64_t paint_hash = 0;
	uint64_t rep[3];
	size_t reserve;
	loom_diag diag;
	opt_entry opts[] = {
		OPT_U32(0, "port", &port, "P", 0, 65535, "TCP port, %r (default 8080; 0 = any "
		        "free port, printed)"),
		OPT_STRING(0, "bind", &bind_opt, "ADDR", "IPv4 address to listen on (default "
		           "127.0.0.1: this machine only)"),
		OPT_BUDGET(&budget_mb, "memory budget in MiB (default 128, at least 64): brick "
		           "cache, tiles being made, one render"),
		OPT_STRING(0, "cache", &cache_opt, "DIR", "tile cache directory (default "
		           "$TMPDIR/loom-serve-UID/HASH, HASH the fabric's)"),
		OPT_DOUBLE(0, "cache-mb", &cache_mb, "MB", "(]", 0, 1048576, "MiB",
		           "largest size of the tile cache on disk, %r (default 256)"),
		OPT_DOUBLE(0, "size-mm", &size_mm, "MM", "(]", 0, 100000, "millimetres",
		           "cloth shown: whole repeats covering at least MM across (default "
		           "200)"),
		OPT_DB(&db_opt, "exemplar database (default: the fabric's; for a DRAFT "
		       "$LOOM_DB, then default.ldb)"),
		OPT_THREADS(&threads, 256, "threads of one render (default: all CPUs)"),
		OPT_STRING(0, "paint-file", &paint_out, "PAINT", "where the page's paint tool "
		           "saves the regions drawn (default: the paint file served, or "
		           "FABRIC.loomp beside a fabric)"),
		OPT_QUIET(&quiet, "no log of requests"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage, .about = about, .opts = opts,
	              .pos_name = "FABRIC|DRAFT", .pos_min = 1, .pos_max = 1, .pos = &in};

	opts_parse(&c, argc, argv);
	if (budget_mb < 64)
		opts_usage(&c, "--budget: at least 64 MiB (%g given)", budget_mb);
	memset(&addr, 0, sizeof addr);
	addr.sin_family = AF_INET;
	addr.sin_port = htons((uint16_t)port);
	if (inet_pton(AF_INET, bind_opt, &addr.sin_addr) != 1)
		opts_usage(&c, "--bind: expected an IPv4 address such as 127.0.0.1, got '%s'",
		           bind_opt);
	memset(&s, 0, sizeof s);
	s.quiet = quiet;
	if (!cli_data_dir())
		cli_fail(prog, "no data directory (set LOOM_DATA): the viewer page lives in "
		         "its web/ folder");
	snprintf(s.web, sizeof s.web, "%s/web", cli_data_dir());
	{
		char idx[4200];
		snprintf(idx, sizeof idx, "%s/index.html", s.web);
		if (access(idx, R_OK) != 0 ||
		    (snprintf(idx, sizeof idx, "%s/openseadragon.min.js", s.web),
		     access(idx, R_OK) != 0))
			cli_fail(prog, "the viewer page is not installed in %s (make installs it "
			         "with npm: tools/web/package.json)", s.web);
	}
	cli_diag_init(&diag, &quiet);
	load(prog, in, db_opt, &s, &paint_hash, &diag);
	s.paint_hash = paint_hash;
	if (paint_out)
		snprintf(s.paint_path, sizeof s.paint_path, "%s", paint_out);
	if (paint_out && !s.fabric_abs[0])
		opts_usage(&c, "--paint-file: serve a fabric (.loomf) or a paint file to paint "
		           "on it");
	if (loom_design_clone(loom_fabric_design(s.f), &s.d) != LOOM_OK)
		cli_fail(prog, "out of memory");
	loom_fabric_get_db_identity(s.f, &s.id);
	loom_fabric_repeat_voxels(s.f, rep);
	for (int a = 0; a < 2; a++) {
		double rep_mm = (double)rep[a] * s.id.voxel_size_um * 1e-3;
		double r = ceil(size_mm / rep_mm);
		s.reps[a] = r < 1 ? 1 : r > 4096 ? 4096 : (uint32_t)r;
		s.win[a] = (int64_t)rep[a] * s.reps[a];
		s.img[a] = (uint64_t)s.win[a] * PX_PER_VOXEL;
	}
	while (((uint64_t)1 << s.top) < (s.img[0] > s.img[1] ? s.img[0] : s.img[1]))
		s.top++;
	if (s.paint && !(s.patch = painted_patches(&s, s.paint, &s.n_patches)))
		cli_fail(prog, "out of memory");
	s.n_types = s.d->n_types;
	s.types = malloc((size_t)s.n_types * sizeof *s.types);
	if (!s.types)
		cli_fail(prog, "out of memory");
	memcpy(s.types, s.d->types, (size_t)s.n_types * sizeof *s.types);
	/* the budget, split up front */
	reserve = SERVE_TILE_WORKERS * TILE_MEMORY + RENDER_MEMORY + ((size_t)8 << 20);
	to.budget_bytes = (size_t)(budget_mb * 1048576.0) - reserve;
	to.max_threads = 64 + SERVE_TILE_WORKERS;
	s.to = to;
	if (loom_texture_open(s.f, s.db, &to, &s.t, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (s.paint && loom_paint_bind(s.paint, s.t, s.f) != LOOM_OK)
		cli_fail(prog, "out of memory binding the paint layer");
	if (cache_opt) {
		snprintf(cache_dir, sizeof cache_dir, "%s", cache_opt);
	} else {
		const char *tmp = getenv("TMPDIR");
		char base[4096];
		snprintf(base, sizeof base, "%s/loom-serve-%d", tmp && *tmp ? tmp : "/tmp",
		         (int)getuid());
		if (mkdir(base, 0700) != 0 && errno != EEXIST)
			cli_fail(prog, "%s: %s", base, strerror(errno));
		snprintf(cache_dir, sizeof cache_dir, "%s/%016llx-%u-%u", base,
		         (unsigned long long)s.id.content_hash ^
		         table_hash(s.d->types, s.d->n_types) ^ ((uint64_t)s.d->rows << 32 | s.d->cols) ^
		         paint_hash,
		         s.reps[0], s.reps[1]);
	}
	s.cache = serve_cache_open(cache_dir, (uint64_t)(cache_mb * 1048576.0), err,
	                           sizeof err);
	if (!s.cache)
		cli_fail(prog, "%s", err);
	pthread_mutex_init(&s.lock, NULL);
	pthread_mutex_init(&s.render_lock, NULL);
	pthread_rwlock_init(&s.paint_lock, NULL);
	pthread_mutex_init(&s.work_lock, NULL);
	pthread_cond_init(&s.work_cond, NULL);
	(void)threads;
	daemon = MHD_start_daemon(MHD_USE_THREAD_PER_CONNECTION |
	                          MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_ERROR_LOG,
	                          (uint16_t)port, NULL, NULL, handler, &s,
	                          MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&addr,
	                          MHD_OPTION_CONNECTION_LIMIT, (unsigned)96,
	                          MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)60,
	                          MHD_OPTION_THREAD_STACK_SIZE, (size_t)1 << 20,
	                          MHD_OPTION_END);
	if (!daemon)
		cli_fail(prog, "cannot listen on %s:%u: %s", bind_opt, port,
		         errno ? strerror(errno) : "the port may be in use");
	info = MHD_get_daemon_info(daemon, MHD_DAEMON_INFO_BIND_PORT);
	printf("loom serve: http://%s:%u/  (%s: %ux%u repeats, %llux%llu pixels, %u "
	       "levels; tile cache %s)\n", bind_opt, info ? info->port : port, in,
	       s.reps[0], s.reps[1], (unsigned long long)s.img[0],
	       (unsigned long long)s.img[1], s.top + 1, cache_dir);
	fflush(stdout);
	signal(SIGINT, on_signal);
	signal(SIGTERM, on_signal);
	signal(SIGPIPE, SIG_IGN);
	while (!stop)
		pause();
	MHD_stop_daemon(daemon);
	if (!quiet)
		fprintf(stderr, "loom serve: stopped; %llu tiles made, %llu from the cache, "
		        "%llu refused (429)\n", (unsigned long long)atomic_load(&s.tiles_made),
		        (unsigned long long)atomic_load(&s.tiles_cached),
		        (unsigned long long)atomic_load(&s.rejected));
	serve_cache_close(s.cache);
	loom_texture_close(s.t);
	loom_paint_free(s.paint);
	free(s.patch);
	loom_fabric_free(s.f);
	loom_db_close(s.db);
	loom_design_free(s.d);
	free(s.types);
	return 0;
}
