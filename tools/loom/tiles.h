/*
 * tools/loom/tiles.h - what `loom export` and `loom scan` share: the region
 * and tiling options, opening the fabric and its texture inside one memory
 * budget, and a pool of worker threads that pulls tiles from an atomic
 * counter.  docs/batch.md describes the options.
 *
 * Tiles.  The region [lo, hi) is cut into tiles of tsize voxels (the last
 * tile along an axis is shorter); tile (tx, ty, tz) has the index
 * (tz*nt[1] + ty)*nt[0] + tx (x fastest).  Shard I of N holds the tiles
 * whose index mod N is I; its k-th tile is I + k*N.
 *
 * Memory.  --budget MB is everything: the worker buffers (threads x the
 * caller's bytes per worker) are taken off it first and the texture gets
 * the rest; a tile too big for the budget is a usage error.
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
#define TILES_OPT_SHARD(j, h) OPT_CALLBACK(0, "shard", (j), "I/N", tiles_opt_shard, h)
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

/* Check the options that go together (usage errors exit 2) and parse
   --region.  need_region: --region or --all is required. */
void tiles_parse(const opts_cmd *c, tiles_job *j, int need_region);

/* Text parsers (0 ok, -1 bad text). */
int tiles_parse_region(const char *s, int64_t lo[3], int64_t hi[3]);
int tiles_parse_tile(const char *s, int64_t t[3]);
int tiles_parse_shard(const char *s, uint32_t *i, uint32_t *n);
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

/* Tiles of this shard, and the k-th one's index and box. */
uint64_t tiles_in_shard(const tiles_job *j);
uint64_t tiles_index(const tiles_job *j, uint64_t k);
void tiles_box(const tiles_job *j, uint64_t index, int64_t lo[3], int64_t hi[3],
               int64_t tile[3]);
/* The voxels of all tiles of this shard. */
uint64_t tiles_shard_voxels(const tiles_job *j);

/* ---- worker pool ---------------------------------------------------------- */

/* Work on shard-local tile k (index tiles_index(j, k)) as worker w.
   Returns 0, or nonzero after writing a message into msg (stops the pool). */
typedef int (*tiles_fn)(void *ctx, unsigned w, uint64_t k, char *msg,
                        size_t msg_size);

#define TILES_CHUNK_SLOTS 4
#define TILES_CHUNK_TILES 4096 /* tiles per chunk of the source order (about) */

typedef struct tiles_pool {
	tiles_job *job;
	tiles_fn fn;
	void *ctx;
	const uint8_t *skip;       /* skip[k] != 0: tile k is done already */
	void (*tick)(void *ctx);   /* called by the main thread while waiting */
	cli_progress *progress;    /* may be NULL */
	int progress_voxels;       /* 1: report voxels, else tiles */
	int source_order;          /* 1: tiles in chunks of tile rows, each
	                              chunk's tiles sorted by the source block
	                              their centre copies, so that a block's
	                              bricks are decompressed once per chunk
	                              (any shard; a result that does not
	                              depend on the order); 0: index order */
	/* results */
	atomic_ullong done_tiles, done_voxels;
	atomic_int stop;
	char msg[LOOM_DIAG_MSG_MAX + 256];
	pthread_mutex_t lock;
	pthread_cond_t cond;       /* signalled when a worker ends */
	unsigned finished;         /* workers ended (under lock) */
	atomic_ullong next;
	/* source order (under lock): chunks of chunk_rows x chunk_cols tiles,
	   the orders of the last TILES_CHUNK_SLOTS chunks kept (fixed memory:
	   16 bytes per tile of a chunk) */
	uint64_t chunk_rows, chunk_cols;
	struct tiles_chunk {
		uint64_t id;           /* chunk number + 1 (0: empty slot) */
		uint64_t n;
		struct tiles_ord {
			uint64_t index;    /* tile index */
			uint32_t key;      /* source block under the tile's centre */
		} *ord;                /* sorted by (key, index) */
	} chunk[TILES_CHUNK_SLOTS];
	unsigned chunk_next;       /* slot to refill next */
} tiles_pool;

/* Tiles grouped by source block (tiles_pool.source_order) unless
   $LOOM_TILE_ORDER is "index" (for comparisons; results are the same). */
int tiles_source_order_wanted(void);

/* Run fn over the tiles of the shard on job->threads threads.  Returns 0,
   or -1 with pool->msg set. */
int tiles_run(tiles_pool *p);

/* Peak resident set size of the process, bytes (getrusage). */
uint64_t tiles_peak_rss(void);
/* A whole text file (NUL-terminated, at most max bytes); NULL with errno. */
char *tiles_read_text(const char *path, size_t max, size_t *len);
/* User + system CPU seconds of the process so far. */
double tiles_cpu_seconds(void);
/* splitmix64 finaliser. */
uint64_t tiles_mix(uint64_t x);

#endif
