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
#include "progress.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#define TILES_COORD_MAX ((int64_t)1 << 62)
#define TILES_SIDE_MAX 2147483647ll /* a .vol resolution is an int32 */

typedef struct tiles_job {
	/* option text as given (NULL when absent) */
	const char *region_s, *tile_s, *shard_s, *bolt_s, *budget_s, *threads_s;
	const char *db_s;
	int all;
	/* parsed */
	int64_t lo[3], hi[3];      /* the region, half open */
	int64_t tsize[3];          /* tile size (0 = default) */
	uint64_t nt[3], total;     /* tiles per axis, tiles in the region */
	uint32_t shard_i, shard_n; /* 0 / 1 when not sharded */
	unsigned threads;
	double budget_mb;
	double bolt_len, bolt_wid; /* repeats */
	int bolt_len_mm, bolt_wid_mm;
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
/* Consume one of the shared options at the cursor (--region, --all, --bolt,
   --tile, --shard, --budget, --threads, --db): 1 if it was one. */
int tiles_option(cli_args *a, tiles_job *j);
/* Parse the option values (usage errors exit 2).  need_region: --region or
   --all is required. */
void tiles_parse(cli_args *a, tiles_job *j, int need_region);

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
