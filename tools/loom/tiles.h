/*
 * tools/loom/tiles.h - what `loom export` and `loom scan` share: the region
 * and tiling options, opening the fabric and its texture inside one memory
 * budget, the tile order and the shards, and a pool of worker threads.
 * docs/batch.md describes the options.
 *
 * Tiles.  The region [lo, hi) is cut into tiles of tsize voxels (the last
 * tile along an axis is shorter); tile (tx, ty, tz) has the index
 * (tz*nt[1] + ty)*nt[0] + tx (x fastest).  File names and manifests use
 * the index; the work follows the source order below.
 *
 * Source order and shards.  The tiles are grouped in chunks: one z layer,
 * chunk_rows whole tile rows (or chunk_cols tiles of a row wider than
 * TILES_CHUNK_TILES), about TILES_CHUNK_TILES tiles each, chunks in index
 * order.  Inside a chunk the tiles are sorted by the source block that the
 * crossing under the tile's centre copies (then by index):
 *
 *     chunk 0: [blk 0 0 0 | 1 1 | 2 2 2 | ... | 199 199]   chunk 1: [...]
 *               shard 0       shard 1   ...     shard N-1
 *
 * Shard I of N takes the I-th of N equal contiguous parts of every
 * chunk's sorted order (positions [I*n/N, (I+1)*n/N) of a chunk of n
 * tiles).  Every chunk holds about every source block, so a shard's parts
 * cover about the same 1/N of the blocks chunk after chunk: each shard
 * inflates about 1/N of the database instead of all of it (round-robin
 * shards did), and its cache keeps them between chunks.  The parts of the
 * N shards are disjoint and cover every tile once.  A shard's k-th tile is
 * its k-th in this order (chunk by chunk, part by part);
 * LOOM_TILE_ORDER=index processes each part in index order instead
 * (membership is unchanged; results never depend on the order).
 *
 * Memory.  --budget MB is everything: the worker buffers (threads x the
 * caller's bytes per worker) are taken off it first and the texture gets
 * the rest; a tile too big for the budget is a usage error.  The order
 * costs one chunk (16 bytes a tile of it); an export's list of its
 * shard's tiles is counted by the export (job_bytes).
 */
#ifndef LOOM_TILES_H
#define LOOM_TILES_H

#include "cli.h"
#include "opts.h"
#include "progress.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#define TILES_COORD_MAX ((int64_t)1 << 62)
#define TILES_SIDE_MAX 2147483647ll /* a .vol resolution is an int32 */

/* A bolt LENGTHxWIDTH (--bolt of loom info, export and scan). */
typedef struct tiles_bolt {
	double len, wid;           /* repeats, or mm where len_mm / wid_mm */
	int len_mm, wid_mm;
	const char *text;          /* as given; NULL when absent */
} tiles_bolt;

typedef struct tiles_job {
	/* options (TILES_OPT_*) */
	const char *region_s;      /* --region as given, NULL when absent */
	const char *tile_s;        /* --tile, --shard as given (NULL: absent) */
	const char *shard_s;
	int shard_auto;            /* --shard auto: I/N from the environment */
	char shard_from[96];       /* auto: where I and N came from */
	const char *db_s;          /* --db */
	int all;                   /* --all */
	tiles_bolt bolt;           /* --bolt (1x1 when absent) */
	uint32_t threads;          /* --threads (1) */
	double budget_mb;          /* --budget (64) */
	/* parsed */
	int64_t lo[3], hi[3];      /* the region, half open */
	int64_t tsize[3];          /* tile size (0 = default) */
	uint64_t nt[3], total;     /* tiles per axis, tiles in the region */
	uint32_t shard_i, shard_n; /* 0 / 1 when not sharded */
	/* opened */
	loom_db *db;
	loom_fabric *f;
	loom_texture *t;
	loom_paint *paint;         /* a paint file's layer, bound to t, when the
	                              caller set keep_paint (else NULL: its
	                              colours and defects noted as not shown) */
	int keep_paint;            /* set before tiles_open_fabric (export) */
	uint64_t rep[3];           /* voxels of one repeat */
	double voxel_mm;           /* edge of a voxel, mm */
	size_t texture_budget;     /* bytes given to the texture */
	size_t worker_bytes;       /* buffers per worker (the caller's figure) */
	size_t job_bytes;          /* held for the whole job besides the workers
	                              (export: its manifest lines), set by the
	                              caller before tiles_open_texture; 0 */
} tiles_job;

/* Set the defaults (threads 1, budget 64 MiB, no shard). */
void tiles_init(tiles_job *j);

/* The options of export and scan, one entry each for a command's table. */
#define TILES_OPT_REGION(j) \
	OPT_STRING(0, "region", &(j)->region_s, "BOX", "voxels X0<=x<X1, Y0<=y<Y1, " \
	           "Z0<=z<Z1 (integers below 2^62 in magnitude; x and y of any sign: " \
	           "the bolt is unbounded)")
#define TILES_OPT_ALL(j) \
	OPT_FLAG(0, "all", &(j)->all, "one design repeat, the cloth's whole thickness")
#define TILES_OPT_BOLT(j) \
	OPT_CALLBACK(0, "bolt", &(j)->bolt, "LxW", tiles_opt_bolt, "with --all: a bolt " \
	             "LENGTH (along the warps, y) by WIDTH (x), in repeats or with mm, cm " \
	             "or m (e.g. 2x1, 1.5mx90cm)")
#define TILES_OPT_TILE(j, h) OPT_CALLBACK(0, "tile", (j), "TX,TY[,TZ]", tiles_opt_tile, h)
#define TILES_OPT_SHARD(j, h) OPT_CALLBACK(0, "shard", (j), "I/N|auto", tiles_opt_shard, h)
/* --help text of --shard auto (both commands) */
#define TILES_SHARD_AUTO_HELP "; auto: I from $SLURM_ARRAY_TASK_ID, N from " \
	"$SLURM_ARRAY_TASK_COUNT (or $LOOM_SHARD_INDEX, $LOOM_SHARD_COUNT, which win)"
#define TILES_OPT_BUDGET(j, h) OPT_BUDGET(&(j)->budget_mb, h)
#define TILES_OPT_THREADS(j) \
	OPT_THREADS(&(j)->threads, TILES_THREADS_MAX, "worker threads (default 1)")
#define TILES_OPT_DB(j) \
	OPT_DB(&(j)->db_s, "the exemplar database (default: the fabric's)")
#define TILES_THREADS_MAX 256

/* Option callbacks (opt_fn): --bolt into a tiles_bolt; --tile and --shard
   into a tiles_job. */
const char *tiles_opt_bolt(const char *text, void *bolt);
const char *tiles_opt_tile(const char *text, void *job);
const char *tiles_opt_shard(const char *text, void *job);

/* Check the options that go together (usage errors exit 2), parse
   --region and resolve --shard auto (tiles_shard_auto).  need_region:
   --region or --all is required. */
void tiles_parse(const opts_cmd *c, tiles_job *j, int need_region);

/* Text parsers (0 ok, -1 bad text). */
int tiles_parse_region(const char *s, int64_t lo[3], int64_t hi[3]);
int tiles_parse_tile(const char *s, int64_t t[3]);
int tiles_parse_shard(const char *s, uint32_t *i, uint32_t *n);
/* --shard auto: I and N from the environment: I from $LOOM_SHARD_INDEX,
   else $SLURM_ARRAY_TASK_ID; N from $LOOM_SHARD_COUNT, else
   $SLURM_ARRAY_TASK_COUNT, which is only taken for an array 0..N-1
   ($SLURM_ARRAY_TASK_MIN 0, $SLURM_ARRAY_TASK_MAX N-1: a resubmitted
   part of an array, --array=3, must say N in $LOOM_SHARD_COUNT).  0, or
   -1 with the reason in msg. */
int tiles_shard_auto(uint32_t *i, uint32_t *n, char *from, size_t from_size,
                     char *msg, size_t msg_size);
int tiles_parse_bolt(const char *s, double *len, int *len_mm, double *wid,
                     int *wid_mm);

/* Open the fabric (and --db), resolve --all, cut the region into tiles
   (default tile side def_xy x def_xy x the region's thickness, or the
   tile's z when def_z > 0).  Failures exit 1. */
void tiles_open_fabric(tiles_job *j, const char *prog, const char *path,
                       int64_t def_xy);
/* Check the budget against threads x worker_bytes + j->job_bytes and open
   the texture with the rest.  Too small: exit 2 with the figures. */
void tiles_open_texture(tiles_job *j, const char *prog, size_t worker_bytes);
void tiles_close(tiles_job *j);

/* Tiles of this shard (arithmetic, no order needed). */
uint64_t tiles_in_shard(const tiles_job *j);
/* The box of tile `index`, and its tile coordinates (tile may be NULL). */
void tiles_box(const tiles_job *j, uint64_t index, int64_t lo[3], int64_t hi[3],
               int64_t tile[3]);
/* Voxels of tile `index`. */
uint64_t tiles_voxels(const tiles_job *j, uint64_t index);

/* ---- the source order ------------------------------------------------------ */

#define TILES_CHUNK_TILES 4096 /* tiles per chunk of the source order (about) */

struct tiles_ord {
	uint64_t index;            /* tile index */
	uint32_t key;              /* source block under the tile's centre */
};

/* Walks this shard's tiles in its order (fixed memory: one chunk). */
typedef struct tiles_iter {
	const tiles_job *j;
	int index_order;           /* each part in index order */
	uint64_t chunk_rows, chunk_cols;
	uint64_t cpr, cpl;         /* chunks per band of rows, bands per layer */
	uint64_t chunk, n_chunks;  /* next chunk, chunks in all */
	struct tiles_ord *ord;     /* the current chunk's part */
	uint64_t pos, end;         /* its entries still to hand out */
	uint32_t block[2];         /* source block size (b1, b2) */
} tiles_iter;

/* Start walking j's shard (j's fabric must be attached: after
   tiles_open_texture).  index_order: see tiles_source_order_wanted.
   0, or -1 (out of memory). */
int tiles_iter_init(tiles_iter *it, const tiles_job *j, int index_order);
/* The next tile's index: 1, 0 at the end, -1 on a failure (no memory, a
   detached fabric). */
int tiles_iter_next(tiles_iter *it, uint64_t *index);
void tiles_iter_free(tiles_iter *it);

/* All this shard's tile indices in its order into list[0 .. tiles_in_shard)
   (export keeps them: 8 bytes a tile).  0, or -1. */
int tiles_shard_list(const tiles_job *j, int index_order, uint64_t *list);
/* The voxels of all tiles of this shard (walks the order: O(tiles)). */
uint64_t tiles_shard_voxels(const tiles_job *j);

/* ---- worker pool ---------------------------------------------------------- */

/* Work on the shard's k-th tile (its index: index) as worker w.  Returns
   0, or nonzero after writing a message into msg (stops the pool). */
typedef int (*tiles_fn)(void *ctx, unsigned w, uint64_t k, uint64_t index, char *msg,
                        size_t msg_size);

typedef struct tiles_pool {
	tiles_job *job;
	tiles_fn fn;
	void *ctx;
	const uint64_t *list;      /* the shard's tiles in order (tiles_shard_list),
	                              or NULL: walked by an iterator */
	const uint8_t *skip;       /* skip[k] != 0: the k-th tile is done already */
	void (*tick)(void *ctx);   /* called by the main thread while waiting */
	cli_progress *progress;    /* may be NULL */
	int progress_voxels;       /* 1: report voxels, else tiles */
	int index_order;           /* 1: each part in index order (see above) */
	/* results */
	atomic_ullong done_tiles, done_voxels;
	atomic_int stop;
	char msg[LOOM_DIAG_MSG_MAX + 256];
	pthread_mutex_t lock;
	pthread_cond_t cond;       /* signalled when a worker ends */
	unsigned finished;         /* workers ended (under lock) */
	uint64_t next;             /* tiles handed out (under lock) */
	tiles_iter it;             /* without a list (under lock) */
} tiles_pool;

/* 1 when $LOOM_TILE_ORDER is "index": each shard part in index order (for
   comparisons; results are the same), else 0 (source order). */
int tiles_index_order_wanted(void);

/* Run fn over the tiles of the shard on job->threads threads.  Returns 0,
   or -1 with pool->msg set. */
int tiles_run(tiles_pool *p);

/* Peak resident set size of the process, bytes (getrusage). */
uint64_t tiles_peak_rss(void);
/* A whole text file (NUL-terminated, at most max bytes); NULL with errno. */
char *tiles_read_text(const char *path, size_t max, size_t *len);
/* User + system CPU seconds of the process so far. */
double tiles_cpu_seconds(void);
/* The i < n with flag[i] as a Slurm --array list ("3,5-7"; "" when
   none), malloc'ed; NULL when out of memory. */
char *tiles_list_text(const uint8_t *flag, uint32_t n);
/* splitmix64 finaliser. */
uint64_t tiles_mix(uint64_t x);

#endif
