/*
 * loom/fabric.h - a fabric: one design bound to one exemplar database by
 * yarn-level synthesis (paper 5.3-5.5).  Include <loom.h>, not this file.
 * docs/fabric.md describes the `loom synth` and `loom info` commands and
 * the metrics; docs/formats.md ("Fabric file") the file byte by byte.
 *
 * A fabric holds, in O(design) memory:
 *   - the design (weave W, warp/weft yarn-type maps, yarn table);
 *   - the identity of the database it was made with (path as given, content
 *     hash, block size b1 x b2 x b3, voxel size, exemplar and block counts);
 *   - the synthesis parameters (algorithm, seed, rank, group m^, flags);
 *   - the base assignment (one source block per crossing of the repeat),
 *     the randomisation key, and the edge-fix tables (size-independent);
 *   - metrics computed at synthesis.
 * With these, the source block, the yarn types and the edge-fix offsets of
 * any crossing (I, J) of the unbounded bolt are O(1) to evaluate.
 *
 * Lifecycle: loom_fabric_synthesize or loom_fabric_open -> queries ->
 * loom_fabric_free.  A fabric is immutable once made: every function taking
 * a const loom_fabric * may be called from any number of threads at once.
 * A fabric made or opened with a caller's database borrows it: the
 * database must stay open until the fabric is freed.
 */
#ifndef LOOM_FABRIC_H
#define LOOM_FABRIC_H

#include "common.h"
#include "db.h"
#include "design.h"
#include "synth.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct loom_fabric loom_fabric;

/* Where the edge-fix tables go in the fabric file. */
enum loom_fabric_edge_storage {
	LOOM_FABRIC_EDGE_AUTO = 0,    /* store them when they take at most
	                                 LOOM_FABRIC_EDGE_STORE_MAX bytes, else
	                                 store the rank and rebuild at open */
	LOOM_FABRIC_EDGE_STORE = 1,   /* store the tables (unless they exceed
	                                 the format's 256 MiB: rebuild then) */
	LOOM_FABRIC_EDGE_REBUILD = 2  /* store the rank; rebuild at open from
	                                 the database (about 11 ms at the paper's
	                                 block size) */
};
#define LOOM_FABRIC_EDGE_STORE_MAX (1536u * 1024u)

#define LOOM_FABRIC_DEFAULT_WINDOW 64u /* side of the bolt metrics window */
#define LOOM_FABRIC_MAX_WINDOW 4096u

/* Synthesis options.  Initialise with LOOM_FABRIC_OPTIONS_INIT. */
typedef struct loom_fabric_options {
	size_t size;           /* sizeof(loom_fabric_options) */
	int algo;              /* enum loom_synth_algo (default LOOM_SYNTH_DP) */
	uint64_t seed;         /* ties, random choices, randomisation (1) */
	uint32_t group;        /* m^, 0..65536; 0 = no randomisation (3) */
	uint32_t rank;         /* edge-fix rank r, 1..LOOM_EDGEFIX_MAX_RANK (15) */
	uint32_t flags;        /* LOOM_SYNTH_FULL_LISTS | LOOM_SYNTH_NO_HPREF */
	uint32_t edge_storage; /* enum loom_fabric_edge_storage */
	uint32_t window;       /* the bolt metrics (seams, randomised
	                          continuity) are measured over the crossings
	                          [0, window) x [0, window) of the bolt (which
	                          wraps the repeat); 0 = 64, at most 4096 */
	uint8_t fibre[2];      /* materials (enum loom_fibre) of the warp and
	                          weft yarn types whose own is unset; 0 =
	                          cotton.  Used only with a database of several
	                          tagged material pairs: each crossing then
	                          copies only blocks of its pair's exemplars
	                          (docs/exemplars.md, "Materials per yarn
	                          type") */
} loom_fabric_options;

#define LOOM_FABRIC_OPTIONS_INIT                                            \
	{sizeof(loom_fabric_options), LOOM_SYNTH_DP, 1, LOOM_SYNTH_DEFAULT_GROUP, \
	 LOOM_EDGEFIX_DEFAULT_RANK, 0, LOOM_FABRIC_EDGE_AUTO, 0, {0, 0}}

/* The parameters a fabric was made with. */
typedef struct loom_fabric_params {
	int algo;              /* enum loom_synth_algo */
	uint64_t seed;
	uint32_t group;        /* m^ (0 = no randomisation) */
	uint32_t rank;         /* requested edge-fix rank */
	uint32_t rank_h, rank_v; /* effective ranks of the N/S and W/E bases */
	uint32_t flags;        /* LOOM_SYNTH_* flags */
	int edge_stored;       /* 1 if the file holds the edge-fix tables, 0 if
	                          they are rebuilt from the database at open */
	uint32_t base_width;   /* bytes per base entry in the file (1 or 2) */
} loom_fabric_params;

/* The database a fabric belongs to. */
typedef struct loom_fabric_db_identity {
	const char *path;      /* as given at synthesis; owned by the fabric */
	uint64_t content_hash; /* loom_db_content_hash of that database */
	uint32_t block[3];     /* b1, b2, b3 voxels */
	float voxel_size_um;
	uint32_t n_exemplars;
	uint32_t n_blocks;     /* source blocks K */
} loom_fabric_db_identity;

/* Metrics, computed at synthesis and stored in the file. */
typedef struct loom_fabric_metrics {
	loom_synth_metrics repeat; /* base assignment over the repeat, with
	                              wrap-around neighbours */
	loom_synth_metrics bolt;   /* window of the bolt after randomisation */
	loom_seam_metrics seam;    /* seams over the same window, before and
	                              after the offsets lookups apply (edge
	                              fix and corner term), with the
	                              database's internal step as baseline */
	uint64_t window_rows, window_cols; /* that window: [0,h) x [0,w) */
	uint32_t n_exemplars;
	const uint64_t *usage;     /* n_exemplars: crossings of the repeat whose
	                              base block comes from each exemplar; owned
	                              by the fabric */
} loom_fabric_metrics;

/*
 * Synthesize a fabric: build the exemplar set from the database's exemplar
 * weaves, assign a source block to every crossing of d (o->algo), set up
 * the randomisation (o->seed, o->group), build the edge-fix tables from the
 * database's edge profiles (o->rank), and measure the metrics.  d is
 * copied; db is borrowed (keep it open while the fabric lives); db_path is
 * recorded as given (NULL: "") for loom_fabric_open to find the database.
 * o may be NULL (defaults).  Time O(rows * cols * L) + O(K) tables; memory
 * the design (3 bytes per crossing), the base (2) and O(K + b1 b2 r).
 * Returns LOOM_OK; LOOM_EINVAL (NULL, bad option: message says which);
 * LOOM_EFORMAT (invalid design); LOOM_EUNSUPPORTED (the database cannot
 * give the right yarn on top); LOOM_ERANGE; LOOM_ENOMEM.  *out is NULL on
 * failure.
 */
LOOM_API int loom_fabric_synthesize(const loom_design *d, const loom_db *db,
                                    const char *db_path,
                                    const loom_fabric_options *o,
                                    loom_fabric **out, loom_diag *diag);

/*
 * Write the fabric file (docs/formats.md) atomically.  *bytes (may be NULL)
 * receives its size.  Same fabric => same bytes.  Memory: a few MiB of
 * buffers, whatever the design size.  Returns LOOM_OK, LOOM_EINVAL,
 * LOOM_EIO (message names the path), LOOM_ENOMEM.
 */
LOOM_API int loom_fabric_save(const loom_fabric *f, const char *path,
                              uint64_t *bytes, loom_diag *diag);

/* Flags of loom_fabric_open. */
#define LOOM_FABRIC_OPEN_DETACHED 1u /* read the file only: no database is
                                        opened or checked; the design,
                                        parameters, metrics and identity are
                                        available, lookups are not */

/*
 * Open a fabric file.  Every length, count, index and CRC is checked
 * before use (LOOM_EFORMAT, LOOM_EVERSION, LOOM_ETRUNCATED, LOOM_ECORRUPT,
 * LOOM_ERANGE; the message names the file, the section and the offset).
 * db: the database to bind to (borrowed); NULL opens the path stored in
 * the file (tried as stored, then, if relative, next to the fabric file)
 * and the fabric owns it.  The database's content hash must equal the
 * stored one: otherwise LOOM_EMISMATCH with a message naming both hashes;
 * its geometry must match too (LOOM_EMISMATCH).  Edge-fix tables are
 * read from the file or rebuilt from the database.  flags:
 * LOOM_FABRIC_OPEN_DETACHED (db is then ignored).  Other codes: LOOM_EINVAL
 * (NULL path or out, unknown flags); LOOM_EIO (the file cannot be read);
 * LOOM_ENOTFOUND (db NULL and the file records no database path); the
 * error of loom_db_open when the recorded database cannot be opened;
 * LOOM_ENOMEM.  *out is NULL on failure.
 */
LOOM_API int loom_fabric_open(const char *path, const loom_db *db,
                              unsigned flags, loom_fabric **out,
                              loom_diag *diag);

/*
 * The design size (rows x cols crossings) recorded in a fabric file's
 * header, reading its first 64 bytes only (magic, version, header CRC and
 * the size limits checked; nothing else): to refuse a job whose --budget
 * cannot hold the design before loading it (the design and base
 * assignment take 5 bytes a crossing once opened).  LOOM_OK; LOOM_EINVAL
 * (NULL); the header errors of loom_fabric_open (LOOM_EIO, LOOM_EFORMAT,
 * LOOM_ETRUNCATED, LOOM_EVERSION, LOOM_ECORRUPT, LOOM_ERANGE).
 */
LOOM_API int loom_fabric_file_size(const char *path, uint32_t *rows, uint32_t *cols,
                                   loom_diag *diag);

/* Free (and close the database if the fabric opened it); NULL is a no-op. */
LOOM_API void loom_fabric_free(loom_fabric *f);

/* The design (owned by the fabric); NULL for NULL. */
LOOM_API const loom_design *loom_fabric_design(const loom_fabric *f);

/* The database in use (NULL if detached or f is NULL). */
LOOM_API const loom_db *loom_fabric_db(const loom_fabric *f);

/* 1 if lookups are available (bound to a database), else 0. */
LOOM_API int loom_fabric_attached(const loom_fabric *f);

/* Parameters, database identity, metrics: LOOM_OK or LOOM_EINVAL (NULL).
   Pointers inside the results are owned by the fabric. */
LOOM_API int loom_fabric_get_params(const loom_fabric *f,
                                    loom_fabric_params *out);
LOOM_API int loom_fabric_get_db_identity(const loom_fabric *f,
                                         loom_fabric_db_identity *out);
LOOM_API int loom_fabric_get_metrics(const loom_fabric *f,
                                     loom_fabric_metrics *out);

/* Voxels of one repeat: size[0] = cols*b1 (x), size[1] = rows*b2 (y),
   size[2] = b3 (z).  LOOM_OK or LOOM_EINVAL. */
LOOM_API int loom_fabric_repeat_voxels(const loom_fabric *f, uint64_t size[3]);

/*
 * Voxels of a bolt `length` repeats long (along the warps, y) and `width`
 * repeats wide (x), fractions allowed: size[0] = ceil(width * cols * b1),
 * size[1] = ceil(length * rows * b2), size[2] = b3, *total = their product
 * (a double: exact below 2^53).  LOOM_OK; LOOM_EINVAL (NULL, a length not
 * finite or <= 0); LOOM_ERANGE (a side beyond 2^62 voxels).
 */
LOOM_API int loom_fabric_bolt_voxels(const loom_fabric *f, double length,
                                     double width, uint64_t size[3],
                                     double *total);

/* What absolute crossing (I, J) of the bolt copies. */
typedef struct loom_fabric_source {
	uint32_t block;        /* global source block t (docs/synthesis.md) */
	uint32_t exemplar;     /* u */
	uint32_t row, col;     /* block (row, col) of exemplar u: its voxels are
	                          x in [col*b1, +b1), y in [row*b2, +b2) */
	uint8_t warp_over;     /* W(I mod M, J mod N) */
	uint8_t warp_type;     /* yarn-type IDs at (I mod M, J mod N) */
	uint8_t weft_type;
	loom_synth_nbhd nbhd;  /* sources of the crossing and its 4 neighbours */
} loom_fabric_source;

/* Fill *out for crossing (I, J) (any sign).  LOOM_OK; LOOM_EINVAL (NULL);
   LOOM_EUNUSABLE (detached). */
LOOM_API int loom_fabric_source_at(const loom_fabric *f, int64_t I, int64_t J,
                                   loom_fabric_source *out);

/* Edge-fix offsets of crossing (I, J): dz[y*b1 + x], b1*b2 floats, the
   amount by which the block's content is raised (read source z - dz).
   LOOM_OK, LOOM_EINVAL, LOOM_EUNUSABLE (detached). */
LOOM_API int loom_fabric_dz(const loom_fabric *f, int64_t I, int64_t J,
                            float *dz);

/* The offsets of crossing (I, J)'s four corner columns, dz[0..3] = NW (x 0,
   y 0), NE (b1-1, 0), SW (0, b2-1), SE (b1-1, b2-1): loom_fabric_dz's
   values there.  With the edge fix on they come from the corner term (the
   four crossings meeting at each corner: docs/synthesis.md, "Block
   corners"), not from the N/S edge rows alone.  LOOM_OK, LOOM_EINVAL,
   LOOM_EUNUSABLE (detached). */
LOOM_API int loom_fabric_corner_dz(const loom_fabric *f, int64_t I, int64_t J,
                                   float dz[4]);

/* Mean |seam jump| of crossing (I, J) along its S and E edges (voxels):
   out[0] S before the fix, out[1] S after, out[2] E before, out[3] E after
   (after: the offsets lookups apply, corner term included).  LOOM_OK,
   LOOM_EINVAL, LOOM_EUNUSABLE (detached). */
LOOM_API int loom_fabric_seam_block(const loom_fabric *f, int64_t I,
                                    int64_t J, double out[4]);

/* Name of an algorithm ("naive", "greedy", "dp"; "?" otherwise) and the
   inverse (LOOM_OK or LOOM_EINVAL). */
LOOM_API const char *loom_fabric_algo_name(int algo);
LOOM_API int loom_fabric_algo_parse(const char *name, int *algo);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_FABRIC_H */
