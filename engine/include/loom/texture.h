/*
 * loom/texture.h - the virtual 3D texture of a fabric: every voxel of the
 * unbounded bolt computed when it is looked up, from exemplar bricks paged
 * through a fixed-size cache.  Include <loom.h>, not this file.
 * docs/engine.md explains a lookup step by step and the memory budget;
 * docs/api-texture.md has one entry per function.
 *
 * Coordinates.  Voxel (x, y, z), int64_t: x across the ends, y along the
 * warps, z up through the cloth.  Crossing (I, J) = (floor(y / b2),
 * floor(x / b1)) is the block x in [J*b1, (J+1)*b1), y in [I*b2, (I+1)*b2);
 * the design repeat tiles the bolt without end in x and y (any sign).
 * Voxels with z outside [0, b3) are empty.  Real-valued positions (the
 * filtered lookups) are in voxel units: voxel (i, j, k) is the unit cube
 * [i, i+1) x [j, j+1) x [k, k+1) and its value sits at its centre
 * (i + 0.5, j + 0.5, k + 0.5).
 *
 * Memory.  Everything the texture allocates after loom_texture_open (brick
 * frames, cache bookkeeping, per-thread state and decompressors, the
 * per-thread caches of edge-fix offset maps) is counted against the budget
 * given at open and never exceeds it, and so is the memory the fabric holds
 * while the texture reads it (design and base assignment, 5 bytes a
 * crossing, and edge-fix tables: a larger design leaves a smaller cache); a
 * budget that cannot hold the fixed part plus one brick is LOOM_EBUDGET at
 * open.
 *
 * Threads.  Any number of threads may call the lookup functions on one
 * texture at once.  Each thread gets private state on its first call (up to
 * max_threads threads at a time; later threads share one extra state under
 * a lock, correct but serialised); it is returned when the thread exits or
 * calls loom_texture_thread_done.  loom_texture_close must not run while
 * another call on the texture is in flight.
 *
 * Determinism.  Every result depends only on the fabric, the database and
 * the position: never on the budget, the thread count or the access order.
 */
#ifndef LOOM_TEXTURE_H
#define LOOM_TEXTURE_H

#include "common.h"
#include "db.h"
#include "fabric.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct loom_texture loom_texture;

#define LOOM_TEXTURE_DEFAULT_BUDGET ((size_t)64 << 20) /* 64 MiB */
#define LOOM_TEXTURE_DEFAULT_THREADS 16u
#define LOOM_TEXTURE_MAX_THREADS 4096u

/* Options of loom_texture_open.  Initialise with LOOM_TEXTURE_OPTIONS_INIT. */
typedef struct loom_texture_options {
	size_t size;          /* sizeof(loom_texture_options) */
	size_t budget_bytes;  /* everything the texture may allocate, bytes
	                         (0 = LOOM_TEXTURE_DEFAULT_BUDGET) */
	unsigned max_threads; /* threads with private state at once
	                         (0 = LOOM_TEXTURE_DEFAULT_THREADS, at most
	                         LOOM_TEXTURE_MAX_THREADS) */
	int lod;              /* 1: coarse levels for loom_texture_sample_lod
	                         (built on demand through the brick cache; each
	                         thread's loader scratch grows by one brick);
	                         0: none (docs/rendering.md, "Level of detail") */
} loom_texture_options;

#define LOOM_TEXTURE_OPTIONS_INIT                                           \
	{sizeof(loom_texture_options), LOOM_TEXTURE_DEFAULT_BUDGET,             \
	 LOOM_TEXTURE_DEFAULT_THREADS, 0}

/* Filters of the real-valued lookups. */
enum loom_texture_filter {
	LOOM_FILTER_NEAREST = 0,   /* the voxel containing the position */
	LOOM_FILTER_TRILINEAR = 1  /* the 8 voxels whose centres surround it */
};

/* Channel masks of loom_texture_voxel_ch and loom_texture_sample_ch: a
   lookup reads only the byte planes of the channels asked for (density is
   one plane, orientation two, the material one: the label, from which kind,
   type, albedo and alignment follow).  Fields outside the mask are zero. */
enum loom_texture_channel {
	LOOM_CHANNEL_DENSITY = 1,     /* density */
	LOOM_CHANNEL_ORIENTATION = 2, /* orientation */
	LOOM_CHANNEL_MATERIAL = 4,    /* label, kind, type, albedo, alignment */
	LOOM_CHANNEL_ALL = 7
};

/* One looked-up voxel.  An empty voxel is all zeros. */
typedef struct loom_texel {
	float density;        /* 0..1 */
	float orientation[3]; /* fibre direction, a unit line direction with
	                         z >= 0 (v and -v are the same fibre); zeros
	                         where density is 0 */
	float albedo[3];      /* linear RGB of the yarn type (design table);
	                         zeros when kind is 0 */
	float alignment;      /* fibre alignment of the yarn type; 0 when
	                         kind is 0 */
	uint8_t kind;         /* enum loom_yarn_kind: 0 empty, 1 warp, 2 weft */
	uint8_t type;         /* yarn-type ID (index in the design's table);
	                         0 when kind is 0 */
	uint8_t label;        /* the exemplar's yarn label of the voxel */
	uint8_t pad_;
} loom_texel;

/* Output channels of loom_texture_sample_batch: n entries each (3n for the
   vectors, x y z / r g b per point); a NULL channel is not written. */
typedef struct loom_texture_channels {
	float *density;       /* n */
	float *orientation;   /* 3n */
	uint8_t *kind;        /* n */
	uint8_t *type;        /* n */
	float *albedo;        /* 3n */
} loom_texture_channels;

/* Layouts of loom_texture_read_region's output. */
enum loom_region_layout {
	LOOM_REGION_X_FASTEST = 0, /* index ((z - z0)*ny + (y - y0))*nx + (x - x0) */
	LOOM_REGION_Z_FASTEST = 1  /* index ((y - y0)*nx + (x - x0))*nz + (z - z0):
	                              each voxel column contiguous, as in the
	                              bricks (the fastest) */
};

/* Output channels of loom_texture_read_region, raw encodings
   (docs/formats.md, "Voxel encodings"); nx*ny*nz entries each in the given
   layout; a NULL channel is not written.  Zero-initialise it. */
typedef struct loom_texture_region {
	uint8_t *density;      /* 0..255 (density * 255) */
	uint16_t *orientation; /* orientation code (loom_orientation_decode) */
	uint8_t *kind;         /* 0 empty, 1 warp, 2 weft */
	uint8_t *type;         /* yarn-type ID (0 when kind is 0) */
	uint8_t *label;        /* exemplar yarn label */
	int layout;            /* enum loom_region_layout (0: x fastest) */
} loom_texture_region;

/* Statistics since open (exact when no call is in flight). */
typedef struct loom_texture_stats {
	uint64_t lookups;          /* voxels looked up: one per point lookup
	                              (nearest), 8 per trilinear lookup, one per
	                              voxel of a region read */
	uint64_t brick_requests;   /* brick resolutions: per voxel in point
	                              lookups, per brick of a group of columns
	                              sharing it in region reads */
	uint64_t hits;             /* requests served by the thread's current
	                              brick or the cache (no read) */
	uint64_t misses;           /* requests that read a brick (or joined a
	                              read in flight) */
	uint64_t empty_bricks;     /* requests for bricks stored as nothing
	                              (all empty; never read nor cached), and
	                              point lookups answered as air without
	                              their column's offset (docs/engine.md) */
	uint64_t evictions;        /* cached bricks replaced */
	uint64_t bytes_read;       /* compressed bytes read from the database */
	uint64_t bytes_decompressed; /* brick bytes produced by the reads */
	uint64_t decompress_ns;    /* time reading + checking + decompressing */
	uint64_t errors;           /* failed brick reads (corrupt, I/O) */
	uint64_t crossings;        /* crossing setups (source, types, edge-fix
	                              coefficients) into the per-thread caches */
	uint64_t dz_columns;       /* edge-fix offsets evaluated (one per
	                              voxel column of a crossing setup used) */
	uint64_t bytes_in_use;     /* now: fixed part + cache */
	uint64_t peak_bytes;       /* maximum of bytes_in_use since open */
	uint64_t fixed_bytes;      /* outside the cache: the fabric's own
	                              memory (design, base assignment,
	                              edge-fix tables) and what open
	                              allocates (per-thread state, tables) */
	uint64_t budget_bytes;     /* as opened */
	uint64_t brick_bytes;      /* decompressed bytes of one brick */
	uint32_t cache_frames;     /* bricks the cache can hold */
	uint32_t max_threads;      /* private thread states */
	uint32_t threads;          /* private thread states in use now */
	uint32_t pad_;
} loom_texture_stats;

/*
 * Open the virtual texture of fabric over database db.  db may be NULL:
 * the database the fabric is bound to (loom_fabric_db).  Both are borrowed
 * and must outlive the texture.  The database's identity must be the
 * fabric's (content hash and block size, LOOM_EMISMATCH naming both);
 * the fabric must be attached (not opened LOOM_FABRIC_OPEN_DETACHED:
 * LOOM_EUNUSABLE).  opts may be NULL (defaults).
 * Returns LOOM_OK; LOOM_EINVAL (NULL fabric or out, options.size below
 * sizeof(loom_texture_options), max_threads above
 * LOOM_TEXTURE_MAX_THREADS, an unreadable fabric or database identity,
 * edge-fix tables that do not match the block size); LOOM_EUNUSABLE
 * (detached fabric); LOOM_EMISMATCH (another database); LOOM_EBUDGET
 * (budget too small: the message says how many bytes this fabric needs at
 * least, "needs at least N bytes (M MiB)", and how they split); LOOM_ENOMEM; an error of loom_db_exemplar for an unreadable
 * exemplar.  *out is NULL on failure.  Thread-safe (the fabric and the
 * database are only read).
 */
LOOM_API int loom_texture_open(const loom_fabric *fabric, const loom_db *db,
                               const loom_texture_options *opts,
                               loom_texture **out, loom_diag *diag);

/* Free everything.  NULL is a no-op.  No other call on t may be in flight;
   threads that used t need not have exited. */
LOOM_API void loom_texture_close(loom_texture *t);

/*
 * The calling thread's last error message on t ("" if none), e.g.
 * "db.ldb: brick 17 (exemplar 0 'twill-2-3', brick x=1 y=0 z=5): CRC32
 * mismatch ...".  The pointer is to thread-local storage, valid until the
 * thread's next loom_texture_errmsg call.  NULL t: a message saying so.
 */
LOOM_API const char *loom_texture_errmsg(const loom_texture *t);

/*
 * Voxel (x, y, z) of the bolt into *out (all zeros when empty).
 * Returns LOOM_OK; LOOM_EINVAL (NULL); LOOM_ERANGE (|x|, |y| or |z| >=
 * 2^62); a brick read error (LOOM_ECORRUPT,
 * LOOM_EIO, LOOM_ETRUNCATED, or LOOM_ENOMEM when the thread's decompressor
 * cannot be allocated; *out is then empty and loom_texture_errmsg names
 * the brick; the texture stays usable and a later lookup retries the
 * read).  Thread-safe.
 */
LOOM_API int loom_texture_voxel(loom_texture *t, int64_t x, int64_t y,
                                int64_t z, loom_texel *out);

/*
 * loom_texture_voxel reading only the channels of mask `channels` (enum
 * loom_texture_channel, OR-ed; LOOM_CHANNEL_ALL is loom_texture_voxel):
 * the fields of the other channels are zero, those asked for are equal to
 * loom_texture_voxel's.  LOOM_EINVAL also for bits outside
 * LOOM_CHANNEL_ALL.  Thread-safe.
 */
LOOM_API int loom_texture_voxel_ch(loom_texture *t, int64_t x, int64_t y,
                                   int64_t z, unsigned channels,
                                   loom_texel *out);

/*
 * Filtered lookup at the real position p (voxel units, see the top of this
 * file).  LOOM_FILTER_NEAREST: the voxel containing p.
 * LOOM_FILTER_TRILINEAR: density is the trilinear blend of the 8 voxels
 * whose centres surround p; orientation the sign-aligned blend of their
 * fibre directions weighted by weight * density (docs/engine.md: no
 * cancellation of v and -v), unit length, z >= 0; kind, type, label,
 * albedo and alignment those of the voxel containing p.
 * Returns LOOM_OK; LOOM_EINVAL (NULL, bad filter, p not finite);
 * LOOM_ERANGE (|p| >= 2^61 on an axis); brick read errors as
 * loom_texture_voxel (the failed voxels count as empty).  Thread-safe.
 */
LOOM_API int loom_texture_sample(loom_texture *t, const double p[3],
                                 int filter, loom_texel *out);

/*
 * Level of detail (docs/rendering.md, "Level of detail"): coarse levels
 * available on t: 0 when it was opened without options.lod or its brick
 * shape allows none, else 1..3 (level k is the 2^k box filter).
 */
LOOM_API unsigned loom_texture_lod_levels(const loom_texture *t);

/*
 * loom_texture_sample at coarse level `level` (0: loom_texture_sample
 * itself; above loom_texture_lod_levels: the coarsest there is).  The
 * crossing and edge-fix offset are level 0's at floor(p); the source
 * position, divided by 2^level, is looked up in the exemplar's level
 * (nearest: the coarse voxel containing it; trilinear: the 8 around it,
 * clamped at the exemplar's x, y edges).  density: the box-filtered
 * density; orientation: the principal axis of the fibres' averaged
 * tensor; label and material: the coarse voxel's (majority kind).
 * *spread (may be NULL) is the extra variance of the microflake's
 * m.w that the fibres' spread adds: (1 - a) / 3 for anisotropy a in
 * [0, 1] (0 at level 0).  Errors as loom_texture_sample.
 */
LOOM_API int loom_texture_sample_lod(loom_texture *t, const double p[3], int filter,
                                     unsigned level, loom_texel *out, float *spread);

/*
 * loom_texture_sample reading only the channels of mask `channels` (as
 * loom_texture_voxel_ch): trilinear density and orientation read just
 * their planes of the 8 corners (each column's two corners resolved
 * together), the material just the label of the voxel containing p.  The
 * fields asked for equal loom_texture_sample's; the others are zero.
 * LOOM_EINVAL also for bits outside LOOM_CHANNEL_ALL.  Thread-safe.
 */
LOOM_API int loom_texture_sample_ch(loom_texture *t, const double p[3],
                                    int filter, unsigned channels,
                                    loom_texel *out);

/*
 * loom_texture_sample for n points given as three arrays x, y, z; results
 * into the non-NULL channels of *out, reading only the planes those
 * channels need (density; orientation; kind, type or albedo: the label).
 * Every point is looked up; a point
 * that fails gets empty values and the first failure's code is returned
 * (loom_texture_errmsg has its message).  n = 0 is LOOM_OK.  Thread-safe.
 */
LOOM_API int loom_texture_sample_batch(loom_texture *t, size_t n,
                                       const double *x, const double *y,
                                       const double *z, int filter,
                                       const loom_texture_channels *out);

/*
 * Read the box [lo[0], hi[0]) x [lo[1], hi[1]) x [lo[2], hi[2]) into the
 * non-NULL channels of *out (raw encodings; x fastest by default, or z
 * fastest: see loom_texture_region).  Voxel for voxel equal to
 * loom_texture_voxel.  Per output voxel column the source column and
 * edge-fix offset are computed once and whole z-runs are copied from the
 * bricks (x fastest: through a small per-thread buffer, transposed).
 * Every voxel is written; voxels whose brick fails to read are empty and
 * the first failure's code is returned.  Returns LOOM_OK (also for an
 * empty box, hi == lo); LOOM_EINVAL (NULL, hi < lo, unknown layout);
 * LOOM_ERANGE (a bound with |lo| or |hi| >= 2^62, or nx*ny*nz above
 * SIZE_MAX);
 * read errors.  Thread-safe.
 */
LOOM_API int loom_texture_read_region(loom_texture *t, const int64_t lo[3],
                                      const int64_t hi[3],
                                      const loom_texture_region *out);

/* Statistics.  LOOM_OK or LOOM_EINVAL (NULL).  Thread-safe. */
LOOM_API int loom_texture_get_stats(const loom_texture *t,
                                    loom_texture_stats *st);

/*
 * Give the calling thread's private state on t back to t (its current brick
 * is unpinned); the next call from this thread makes a new one.  For thread
 * pools that stop using a texture; a thread's state is also returned when
 * it exits.  NULL or a thread without state: no-op.  Thread-safe.
 */
LOOM_API void loom_texture_thread_done(loom_texture *t);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_TEXTURE_H */
