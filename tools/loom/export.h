/*
 * tools/loom/export.h - the parts of `loom export`, one file per job:
 *   cmd_export.c       the command: options, the job's memory, the tiles
 *   export_manifest.c  the manifest: each tile's line of files, sizes and
 *                      CRC-32s, its atomic rewrites, resuming a killed job,
 *                      merging the manifests of shards (--merge)
 *   export_formats.c   the tile writers, one per format (vol, nrrd, exr,
 *                      vdb, nvdb)
 *   export_lod.c       --lod: a tile downsampled before it is written
 * A writer puts a tile's files into the output directory and records each
 * with export_record_file, which adds it to the tile's manifest line.
 */
#ifndef LOOM_EXPORT_H
#define LOOM_EXPORT_H

#include "cli.h"
#include "shard_lock.h"
#include "tiles.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

enum { CH_DENSITY, CH_ORIENT, CH_ALBEDO, CH_KIND, CH_TYPE, N_CH };
static const char *const ch_names[N_CH] = {"density", "orientation", "albedo", "kind",
                                           "type"};
static const unsigned ch_comps[N_CH] = {1, 3, 3, 1, 1};
enum { F_VOL, F_NRRD, F_EXR, F_VDB, F_NVDB };
static const char *const fmt_names[] = {"vol", "nrrd", "exr", "vdb", "nvdb"};
/* OpenVDB grid names: albedo is "color", the Principled Volume's colour
   attribute in Blender (docs/interop.md) */
static const char *const vdb_grid_names[N_CH] = {"density", "orientation", "color", "kind",
                                                 "type"};

#define CRC_BUF (256u << 10)

struct ewstate {
	uint8_t *d, *k, *ty;
	uint16_t *o;
	float *row;            /* one row: up to 9 floats per voxel */
	float *lv;             /* --lod: the coarse tile, LOD_FLOATS per voxel */
	double *tw;            /* --lod: summed density per yarn type (256) */
	uint8_t *io;           /* CRC read buffer */
	char *line;            /* the tile's manifest line being built */
	size_t line_cap, line_len;
	/* the tile in the buffers: its first voxel and size read; tint: a
	   paint colour reaches it (albedo through loom_paint_albedo) */
	int64_t lo[3], n[3];
	int tint;
};


struct export_ctx {
	tiles_job *j;
	int format;
	int codec;             /* vdb: LOOM__VDB_BLOSC, _ZIP or _NONE */
	unsigned chmask;
	int lod;               /* --lod L: voxels downsampled by 2^L (0: none) */
	double vmm;            /* edge of an exported voxel, mm (voxel_mm * 2^L) */
	const char *dir;
	char *params;          /* the manifest's "params" value (one line) */
	char manifest[4096];   /* its path */
	char **lines;          /* per shard tile k: manifest line, NULL if not done */
	uint8_t *skip;         /* tiles found complete at start */
	uint64_t n;            /* tiles in the shard */
	uint64_t *order;       /* order[k]: index of the shard's k-th tile */
	uint64_t *byidx;       /* the k of the shard's tiles, by increasing index */
	shard_lock lock_dir;   /* this shard of DIR, held for the run */
	uint64_t ndone, nlisted_written;
	double last_write;
	double write_cost;     /* seconds the last manifest write took */
	pthread_mutex_t lock;
	struct ewstate *w;
	float albedo[256][3];
	atomic_ullong bytes, files, written_tiles;
	int manifest_error;
	char manifest_msg[LOOM_DIAG_MSG_MAX];
};

/* ---- export_lod.c ---------------------------------------------------------- */
/* Albedo of voxel (kind kd, type ty) of column (x, y) of the tile in w's
   buffers: the yarn table's, tinted by the paint's colours (export_lod.c). */
void export_albedo(const struct export_ctx *c, const struct ewstate *w, int64_t x,
                   int64_t y, uint8_t kd, uint8_t ty, float out[3]);

/* Floats per coarse voxel in ewstate.lv: density, orientation (3), albedo
   (3), kind, type. */
#define LOD_FLOATS 9
/* Downsample the tile in w's buffers (n voxels per axis, each a multiple
   of 2^c->lod, x fastest) into w->lv; the coarse kind and type bytes go
   to the start of w->k and w->ty. */
void export_lod_tile(const struct export_ctx *c, struct ewstate *w, const int64_t n[3]);

/* ---- export_formats.c ------------------------------------------------------ */

/* Write the tile [lo, hi) (its voxels in w's buffers) as the files of
   c->format, named after stem, and record each in w's line.  0, or -1
   with a message. */
int export_write_tile(struct export_ctx *c, struct ewstate *w, const char *stem,
                      const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz);

/* ---- export_manifest.c ----------------------------------------------------- */

/* Append printf text to the tile's line being built; 0, or -1 (no memory). */
int export_line_add(struct ewstate *w, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
/* CRC-32 and size of a file (buf: CRC_BUF bytes); 0, or -1 with errno. */
int export_file_crc(const char *path, uint8_t *buf, uint32_t *crc, uint64_t *bytes);
/* Record the written file DIR/name (its size and CRC-32) in the tile's line. */
int export_record_file(struct export_ctx *c, struct ewstate *w, const char *name,
                       char *msg, size_t msz);
/* Fill c->byidx from c->order (c->n entries). */
void export_sort_by_index(struct export_ctx *c);
/* The k of the shard's tile `index`, or UINT64_MAX when not in the shard. */
uint64_t export_k_of(const struct export_ctx *c, uint64_t index);
/* Rewrite the manifest (final: say complete when every tile is done). */
int export_manifest_flush(struct export_ctx *c, int final);
/* The pool's tick: rewrite the manifest when due. */
void export_tick(void *vctx);
/* Keep the tiles of an earlier manifest of this shard whose files verify;
   returns their count.  A manifest of another export: exit 1. */
uint64_t export_resume(struct export_ctx *c, const char *prog);
/* Remove the temporary files of this shard's tiles and manifest (a dead
   run's: the caller holds the shard's lock, shard_lock.h). */
void export_remove_stale(struct export_ctx *c);
/* loom export --merge DIR. */
int export_merge(const char *prog, const char *dir, int json, int quiet);
/* loom export --status DIR: 0 complete, 1 not (or bad input). */
int export_status(const char *prog, const char *dir, int json, int quiet, int verify);

#endif
