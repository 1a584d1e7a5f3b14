/*
 * loom/db.h - the exemplar database (paper sections 4, 5.3, 6): volumetric
 * exemplars of simple weaves, stored as independently compressed voxel
 * bricks plus the per-source-block tables synthesis needs.  File format:
 * docs/formats.md, "Exemplar database (.ldb)"; generator: docs/exemplars.md.
 *
 * Geometry.  Exemplar u has a weave S_u of `rows` picks (along y) by `cols`
 * ends (along x); S_u(r, c) = 1 when the warp is over.  Block (r, c) is the
 * voxel box x in [c*b1, (c+1)*b1), y in [r*b2, (r+1)*b2), z in [0, b3).
 * b1, b2, b3 and the voxel size are the same for every exemplar of a
 * database.  S_u is periodic with the window: neighbours wrap.
 *
 * Memory.  loom_db_open reads the header, the exemplar table, the tables
 * and the brick index (a few hundred KB for the paper preset) and nothing
 * else; bricks are read with pread when asked for.  An open database is
 * immutable: every const function below may be called from any number of
 * threads at once.
 */
#ifndef LOOM_DB_H
#define LOOM_DB_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct loom_db loom_db;

/* Yarn kinds (voxel label -> yarn table -> kind). */
enum loom_yarn_kind {
	LOOM_YARN_NONE = 0,
	LOOM_YARN_WARP = 1,
	LOOM_YARN_WEFT = 2
};

/* Yarn-table flags. */
#define LOOM_DB_YARN_FLYAWAY 1u /* voxels of a flyaway fibre of this yarn */
#define LOOM_DB_YARN_OUTSIDE 2u /* a yarn of the sheet whose centre line lies
                                   outside the window (cut at the border) */

/* One row of an exemplar's yarn table; row L describes voxel label L
   (row 0 is the empty label). */
typedef struct loom_db_yarn {
	uint8_t kind;   /* enum loom_yarn_kind */
	uint8_t flags;  /* LOOM_DB_YARN_* */
	int16_t index;  /* warp: end (column) index, weft: pick (row) index,
	                   relative to the window; -1 or rows/cols for cut
	                   yarns outside it */
} loom_db_yarn;

/* Whole-database facts. */
typedef struct loom_db_info {
	uint32_t version;         /* format version (1, 2 or 3) */
	uint32_t n_exemplars;
	uint32_t block[3];        /* b1 (x, ends), b2 (y, picks), b3 (z) voxels */
	uint32_t brick[3];        /* brick shape in voxels (x, y, z) */
	float voxel_size_um;      /* edge of a voxel in micrometres */
	uint32_t top_threshold;   /* density (0..255) of the top-surface rule */
	uint64_t seed;            /* generator seed (0 if not generated) */
	uint64_t content_hash;    /* 64-bit identity (docs/formats.md) */
	uint64_t file_bytes;
	uint64_t n_bricks;        /* all bricks, empty ones included */
	uint64_t n_empty_bricks;  /* stored as nothing */
	uint64_t n_raw_bricks;    /* stored uncompressed */
	uint64_t raw_bytes;       /* voxels * 4 over all exemplars */
	uint64_t stored_bytes;    /* brick bytes in the file */
	uint64_t metadata_bytes;  /* tables + index read at open */
	uint32_t voxel_layout;    /* 1: one stream a brick (version 1); 2: each
	                             plane a unit of its own (version 2); 3: as
	                             2, the density unit in eight segments
	                             (version 3) */
	uint64_t n_raw_density;   /* versions 2, 3: stored bricks whose density
	                             plane is stored uncompressed (all of them
	                             in a database written with density_raw) */
} loom_db_info;

/* One exemplar.  Pointers are owned by the database and valid until
   loom_db_close. */
typedef struct loom_db_exemplar_info {
	char name[32];            /* e.g. "twill-2-3" */
	char weave_name[32];      /* generator weave, e.g. "twill:2/3" ("" if
	                             unknown) */
	uint32_t rows, cols;      /* crossings: picks (y) x ends (x) */
	uint32_t size[3];         /* voxels: cols*b1, rows*b2, b3 */
	uint32_t block[3];        /* b1, b2, b3 (as the database) */
	float voxel_size_um;
	const uint8_t *weave;     /* rows*cols, row-major, 1 = warp over */
	uint32_t n_yarns;         /* labels 0..n_yarns are valid */
	const loom_db_yarn *yarns;/* n_yarns + 1 rows, row 0 = empty */
	uint32_t n_symmetries;    /* translations (dx, dy), (0,0) included */
	const uint16_t *symmetries; /* 2*n_symmetries: dx (cols), dy (rows) with
	                             S(r+dy, c+dx) = S(r, c) for all r, c */
	uint32_t bricks[3];       /* bricks along x, y, z */
	uint32_t first_brick;     /* global id of brick (0,0,0) */
	uint64_t raw_bytes;       /* size[0]*size[1]*size[2]*4 */
	uint64_t stored_bytes;    /* bytes of its bricks in the file */
	uint8_t fibre[2];         /* material pair (warp, weft; enum loom_fibre
	                             of loom/design.h) the exemplar was woven
	                             with, in a database of several pairs; 0 0 =
	                             not recorded (one pair, scans) */
} loom_db_exemplar_info;

/*
 * Neighbourhood code of a block: bit 0 = S(r,c), bit 1 = N = S(r-1,c),
 * bit 2 = S (south) = S(r+1,c), bit 3 = W = S(r,c-1), bit 4 = E = S(r,c+1),
 * indices wrapping (the weave is periodic).
 */
#define LOOM_DB_CODE_SELF 1u
#define LOOM_DB_CODE_N 2u
#define LOOM_DB_CODE_S 4u
#define LOOM_DB_CODE_W 8u
#define LOOM_DB_CODE_E 16u

/*
 * Per-source-block table (edge fixing, paper 5.5; seam metric baseline).
 * Heights are in voxels above the exemplar's z = 0 of the top surface:
 * the top face (z + 1) of the highest voxel of the column whose label is a
 * yarn without LOOM_DB_YARN_FLYAWAY and whose density is >= top_threshold.
 * Columns with no such voxel are gaps; profile gaps are filled by linear
 * interpolation along the edge (constant past the ends), or with the
 * block's mean height if the whole edge is a gap (docs/formats.md).
 */
typedef struct loom_db_block_info {
	uint8_t code;             /* LOOM_DB_CODE_* bits */
	uint8_t centre_kind;      /* kind of the top voxel of the centre column
	                             (x = c*b1 + b1/2, y = r*b2 + b2/2) */
	uint16_t gap_columns;     /* columns of the block without a surface */
	float mean_dh_x;          /* mean |h(x+1,y) - h(x,y)| inside the block */
	float mean_dh_y;          /* mean |h(x,y+1) - h(x,y)| inside the block */
	float mean_height;        /* mean h over the block's surface columns */
	const float *north;       /* b1 samples, x = c*b1 .. , y = r*b2 */
	const float *south;       /* b1 samples, y = (r+1)*b2 - 1 */
	const float *west;        /* b2 samples, y = r*b2 .. , x = c*b1 */
	const float *east;        /* b2 samples, x = (c+1)*b1 - 1 */
} loom_db_block_info;

/*
 * Open a database.  Reads and checks the header, trailer, tables and brick
 * index (sizes, offsets, CRCs); bricks are not read.  Returns LOOM_OK,
 * LOOM_EIO, LOOM_EFORMAT (bad magic or field), LOOM_EVERSION,
 * LOOM_ETRUNCATED, LOOM_ECORRUPT (CRC), LOOM_ERANGE (offset or size out of
 * range), LOOM_ENOMEM; the message names the file and the place.  *out is
 * NULL on failure.
 */
LOOM_API int loom_db_open(const char *path, loom_db **out, loom_diag *diag);

/* Close; NULL is a no-op. */
LOOM_API void loom_db_close(loom_db *db);

/* Whole-database facts.  LOOM_EINVAL for NULL. */
LOOM_API int loom_db_get_info(const loom_db *db, loom_db_info *info);

/* Exemplar k (0-based).  LOOM_ERANGE if k >= n_exemplars. */
LOOM_API int loom_db_exemplar(const loom_db *db, uint32_t k,
                              loom_db_exemplar_info *out);

/* Find an exemplar by name or by decimal index.  LOOM_ENOTFOUND. */
LOOM_API int loom_db_find_exemplar(const loom_db *db, const char *name_or_index,
                                   uint32_t *k);

/* Table of block (row, col) of exemplar k.  LOOM_ERANGE out of range. */
LOOM_API int loom_db_block(const loom_db *db, uint32_t k, uint32_t row,
                           uint32_t col, loom_db_block_info *out);

/* The content hash (as in loom_db_info); 0 for NULL. */
LOOM_API uint64_t loom_db_content_hash(const loom_db *db);

/*
 * Read a box of exemplar k into caller arrays laid out x fastest, then y,
 * then z (index (z*size_y + y)*size_x + x).  Any output may be NULL.
 * The box must lie inside the exemplar (LOOM_ERANGE).  Every brick touched
 * is read, checked and decompressed (errors as loom_db_verify).  Allocates
 * one brick of scratch per call; thread-safe.
 */
LOOM_API int loom_db_read_box(const loom_db *db, uint32_t k,
                              const uint32_t origin[3], const uint32_t size[3],
                              uint8_t *density, uint16_t *orientation,
                              uint8_t *label, loom_diag *diag);

/*
 * Check every brick: read, CRC32, decompress to the exact size, every label
 * within the yarn table.  Returns LOOM_OK or the first failure (its code,
 * and a message naming the brick: global id, exemplar and brick x,y,z).
 * `progress`, if set, is called with (bricks done, total).
 */
LOOM_API int loom_db_verify(const loom_db *db,
                            void (*progress)(void *user, uint64_t done,
                                             uint64_t total),
                            void *user, loom_diag *diag);

/*
 * Write database `in` again as `out` in another storage: format version
 * db_version (0: in's; 1..4) and density planes stored raw (density_raw
 * 1), compressed (0: DEFLATE, the zero-run code in version 4) or as in
 * (-1: raw when all of in's are).  The voxels,
 * exemplar records and block tables are the same; the content hash is
 * not (it covers the storage), so a fabric synthesized over `in` needs
 * `loom synth` again over `out`.  Streams: one brick in memory; `out` is
 * written under a temporary name and renamed.  LOOM_EINVAL (arguments,
 * out names in's file, raw density with version 1), the codes of
 * loom_db_open and of a failed brick read (the brick named), LOOM_EIO,
 * LOOM_ENOMEM.  progress (may be NULL) gets (bricks done, total); hash
 * (may be NULL) the output's content hash.
 */
LOOM_API int loom_db_convert(const char *in, const char *out, uint32_t db_version,
                             int density_raw,
                             void (*progress)(void *user, uint64_t done, uint64_t total),
                             void *user, uint64_t *hash, loom_diag *diag);

/* ---- Voxel encodings (docs/formats.md) ---------------------------------- */

/* Decode a 16-bit orientation code to a unit direction with z >= 0. */
LOOM_API void loom_orientation_decode(uint16_t code, float dir[3]);
/* Encode a direction (any length); v and -v give the same code; the angle
   between dir and decode(encode(dir)) is at most 0.56 degrees. */
LOOM_API uint16_t loom_orientation_encode(const float dir[3]);

/* ---- NRRD export ---------------------------------------------------------- */

enum loom_db_channel {
	LOOM_DB_CH_DENSITY = 0,     /* uint8 0..255 */
	LOOM_DB_CH_LABEL,           /* uint8 yarn label */
	LOOM_DB_CH_KIND,            /* uint8 0 empty, 1 warp, 2 weft */
	LOOM_DB_CH_ORIENTATION,     /* 3 x float32 unit vector per voxel */
	LOOM_DB_CH_ORIENT_CODE,     /* uint16 orientation code */
	LOOM_DB_CH_COUNT_
};

/* Parse "density", "label", "kind", "orientation", "orient-code". */
LOOM_API int loom_db_channel_parse(const char *s, int *channel);

/*
 * Write exemplar k, one channel, as NRRD (raw encoding, little-endian,
 * axes x, y, z; spacing = voxel size in mm; space origin = half a voxel on
 * each axis, the centre of voxel (0,0,0), so the volume's corner is at 0).
 * detached = 0: one file with the header attached; 1: header at `path`
 * (.nhdr) and data in the same name with its extension replaced by ".raw".
 * Atomic; memory bounded by one z-layer of bricks.  Returns LOOM_OK;
 * LOOM_EINVAL (NULL db or path, unknown channel, a detached path that
 * would name its own .raw file); LOOM_ERANGE (k out of range); LOOM_ENOMEM;
 * the errors of loom_db_read_box; LOOM_EIO.
 */
LOOM_API int loom_db_export_nrrd(const loom_db *db, uint32_t k, int channel,
                                 const char *path, int detached,
                                 loom_diag *diag);

/* ---- Procedural exemplars (docs/exemplars.md) --------------------------- */

#define LOOM_EXGEN_MAX_WEAVES 64
#define LOOM_EXGEN_MAX_PAIRS 4  /* material pairs of one generated database */
/* Revision of the generator's output: bumped whenever the same parameters
   give different bytes (caches of generated databases key on it). */
#define LOOM_EXGEN_REVISION 6

/* Generator parameters.  Initialise with loom_exgen_preset(). */
typedef struct loom_exgen_params {
	size_t size;              /* sizeof(loom_exgen_params); must be exactly
	                             that (LOOM_EINVAL otherwise) */
	uint32_t block[3];        /* b1, b2, b3 voxels */
	float voxel_size_um;
	uint32_t rows, cols;      /* crossings per exemplar; 0 = per weave: the
	                             smallest multiple of its repeat >=
	                             min_crossings */
	uint32_t n_weaves;        /* <= LOOM_EXGEN_MAX_WEAVES */
	const char *weaves[LOOM_EXGEN_MAX_WEAVES]; /* loom_weave_parse names */
	uint64_t seed;
	uint32_t brick[3];        /* brick shape */
	int level;                /* libdeflate level 1..12 */
	unsigned threads;         /* worker threads; 0 = 2 */
	void (*progress)(void *user, uint64_t done, uint64_t total);
	void *user;               /* passed to progress */
	float yarn_diameter_um[2];/* free (round) diameter of the warp and weft
	                             yarns, 0 < d <= 4 x their spacing; 0 = in
	                             proportion to the spacing (the presets) */
	const char *fibre[2];     /* fibre-level yarns of the warp and weft:
	                             "cotton", "rayon", "silk", "polyester",
	                             "wool", "linen", "monofilament" (plies of
	                             twisted fibres, docs/exemplars.md), or NULL /
	                             "none": smooth yarns with fibre-like noise */
	uint32_t n_pairs;         /* 0 or 1: one pair, fibre[] (exemplars not
	                             tagged); 2..LOOM_EXGEN_MAX_PAIRS: one set of
	                             exemplars (every weave) per pair, tagged with
	                             it, fibre[] not used (docs/exemplars.md,
	                             "Materials per yarn type") */
	const char *pairs[LOOM_EXGEN_MAX_PAIRS][2]; /* warp, weft fibre names
	                             (as fibre[]; NULL = the other one), distinct
	                             pairs */
	uint32_t db_version;      /* 0 or 4: the default format (each plane of
	                             a brick stored apart, the density plane
	                             zero-run coded: decoded several times
	                             faster than DEFLATE); 2: every plane
	                             deflated (a file 10-15 % smaller); 3:
	                             as 2, the density plane in eight segments
	                             (docs/formats.md); 1: version 1 (one
	                             stream a brick), for older readers */
	uint32_t density_raw;     /* 0: density planes compressed (the
	                             default); 1: stored raw (versions 2 to 4),
	                             a larger file whose density misses copy
	                             16 KiB rather than decode it
	                             (docs/exemplars.md, "Raw density"); any
	                             reader of the version reads it */
	uint32_t min_crossings;   /* where rows or cols is 0: each side the
	                             smallest multiple of the weave's repeat >=
	                             this, at most 64; 0 = 4 (the presets).
	                             Larger exemplars vary less from one seed
	                             to the next (docs/fidelity.md, "Exemplar
	                             draws") but make a larger file */
} loom_exgen_params;

/*
 * Set the block size b1 x b2 from a sett: ends_per_cm and picks_per_cm at
 * p->voxel_size_um (b1 = 10000 / (ends_per_cm * voxel), rounded), and make
 * b3 deep enough for the cloth (yarn diameters included; set them first).
 * LOOM_EINVAL when a sett is not positive or a crossing would be under 4
 * voxels or over the largest block; the message names the sett, the voxel
 * size and the accepted range.  A warning (diag) for an unusual sett (under
 * 2 or over 200 threads per cm).
 */
LOOM_API int loom_exgen_set_sett(loom_exgen_params *p, double ends_per_cm,
                                 double picks_per_cm, loom_diag *diag);

/* Check the parameters that do not depend on a weave (what
   loom_exgen_write_db refuses before it starts): LOOM_OK or LOOM_EINVAL
   with the reason. */
LOOM_API int loom_exgen_check_params(const loom_exgen_params *p, loom_diag *diag);

/*
 * Fill p for a preset: "paper" (block 115x70x300, 5 um voxels), "small"
 * (24x16x48, 24 um; the built-in default) or "tiny" (8x6x12, 72 um; test
 * corpora), with the thirteen default weaves (2/3, 3/2, 1/4, 4/1 twills and
 * satins, the 2/3 and 3/2 S twills, basket 1/3, the 1/7 and 7/1 satins),
 * seed 1, the default brick
 * shape and level.  LOOM_EINVAL for an unknown name.
 */
LOOM_API int loom_exgen_preset(const char *name, loom_exgen_params *p);

/* Default brick shape (chosen by bench/bench_db.c) and deflate level. */
#define LOOM_DB_DEFAULT_BRICK_X 16
#define LOOM_DB_DEFAULT_BRICK_Y 16
#define LOOM_DB_DEFAULT_BRICK_Z 64
#define LOOM_DB_DEFAULT_LEVEL 6

/*
 * Generate one exemplar per weave and write the database to `path`
 * (atomically, streaming: memory is a few bricks per thread, not the
 * database).  Output is identical for any thread count.  Returns LOOM_OK,
 * LOOM_EINVAL (bad parameters or weave; message says which), LOOM_EIO,
 * LOOM_ENOMEM.  *hash, if not NULL, receives the content hash.
 */
LOOM_API int loom_exgen_write_db(const char *path, const loom_exgen_params *p,
                                 uint64_t *hash, loom_diag *diag);

/*
 * The woven ground truth of a design (docs/fidelity.md): one exemplar named
 * `name` whose weave is the whole design (rows x cols cells, row-major,
 * 1 = warp over), woven by the same generator with p's block, voxel size,
 * seed, brick shape and level (p->weaves, rows, cols are not used).  At
 * most LOOM_EXGEN_MAX_DESIGN crossings a side and 65536 voxels along x and
 * y (LOOM_ERANGE; the message gives the limit for p's block).  Written like
 * loom_exgen_write_db (atomically, brick column by brick column; the
 * writer keeps a height map of 3 bytes per voxel column and the block
 * tables until the end).
 */
#define LOOM_EXGEN_MAX_DESIGN 1024u
LOOM_API int loom_exgen_write_design(const char *path, const loom_exgen_params *p,
                                     const char *name, uint32_t rows,
                                     uint32_t cols, const uint8_t *weave,
                                     uint64_t *hash, loom_diag *diag);
/* Largest design side (crossings) loom_exgen_write_design accepts along an
   axis whose block side is `block` voxels: min(1024, 65536 / block). */
LOOM_API uint32_t loom_exgen_design_limit(uint32_t block);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_DB_H */
