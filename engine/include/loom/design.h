/*
 * loom/design.h - fabric designs (paper sections 5.1, 5.2).
 *
 * A design is one repeat of a cloth that tiles an unbounded bolt:
 *   - the weave pattern W: rows x cols cells; row i = pick (weft) i, column j
 *     = end (warp) j, both 0-based; W(i,j) = 1 when the warp is over;
 *   - a warp-type map and a weft-type map: rows x cols yarn-type IDs (a yarn
 *     may change type along its length, paper 5.1);
 *   - a yarn table indexed by type ID: name, albedo, fibre alignment.
 *
 * The struct is transparent (it is plain data); create and free it with the
 * functions below so that its arrays come from one allocator.
 */
#ifndef LOOM_DESIGN_H
#define LOOM_DESIGN_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define LOOM_MAX_YARN_TYPES 256   /* type IDs are uint8_t */
#define LOOM_DESIGN_MAX_SIDE 1000000u /* largest rows or cols accepted */
#define LOOM_DESIGN_MAX_CELLS (1ull << 32) /* largest rows*cols accepted */
#define LOOM_YARN_NAME_MAX 32

typedef struct loom_yarn_type {
	char name[LOOM_YARN_NAME_MAX]; /* NUL-terminated, e.g. "warp0" */
	float albedo[3];   /* single-scattering albedo, linear RGB in [0,1] */
	float alignment;   /* fibre alignment / gloss: microflake roughness
	                      sigma in (0,1]; smaller = glossier */
	float thickness;   /* relative yarn thickness; 0 = unspecified */
	uint8_t fibre;     /* material: enum loom_fibre; LOOM_FIBRE_DEFAULT =
	                      the side's default (cotton unless chosen) */
} loom_yarn_type;

/* Materials of yarn types (docs/exemplars.md, "Materials per yarn type"):
   the fibre presets of the exemplar generator, or smooth yarns. */
enum loom_fibre {
	LOOM_FIBRE_DEFAULT = 0,   /* unset: the default of the side */
	LOOM_FIBRE_NONE,          /* smooth yarns with fibre-like noise */
	LOOM_FIBRE_COTTON,
	LOOM_FIBRE_RAYON,
	LOOM_FIBRE_SILK,
	LOOM_FIBRE_POLYESTER,
	LOOM_FIBRE_WOOL,
	LOOM_FIBRE_LINEN,
	LOOM_FIBRE_MONOFILAMENT,
	LOOM_FIBRE_COUNT_
};

/* "none", "cotton", "rayon", "silk", "polyester", "wool", "linen",
   "monofilament" -> enum loom_fibre.  LOOM_OK or LOOM_EINVAL (NULL or
   another name; *code untouched). */
LOOM_API int loom_fibre_parse(const char *name, int *code);
/* Name of a material code (as loom_fibre_parse takes; "default" for
   LOOM_FIBRE_DEFAULT), or NULL for a code out of range. */
LOOM_API const char *loom_fibre_name(int code);
/* Two-letter short name ("co", "cv", "si", "pe", "wo", "li", "mf", "sm";
   "--" for the default), NULL out of range (exemplar name suffixes). */
LOOM_API const char *loom_fibre_short(int code);

typedef struct loom_design {
	uint32_t rows;        /* M: picks */
	uint32_t cols;        /* N: ends */
	uint8_t *weave;       /* rows*cols, row-major; 1 = warp over */
	uint8_t *warp_type;   /* rows*cols yarn-type IDs of the warp */
	uint8_t *weft_type;   /* rows*cols yarn-type IDs of the weft */
	uint32_t n_types;     /* entries in types[] (>= 1) */
	loom_yarn_type *types;
	float sett[2];        /* ends and picks per cm the draft states (WIF
	                         Spacing); 0 = not stated */
	float yarn_um[2];     /* mean warp and weft yarn diameter in um the
	                         draft states (WIF Thickness); 0 = not stated */
} loom_design;

/* Cell access; no bounds check. */
static inline uint8_t loom_design_at(const loom_design *d, uint32_t i, uint32_t j)
{
	return d->weave[(size_t)i * d->cols + j];
}

/*
 * Allocate a rows x cols design: weave all 0, warp type 0, weft type 1, and a
 * two-entry yarn table ("warp", "weft").  Returns LOOM_OK, LOOM_EINVAL (zero
 * size or out), LOOM_ERANGE (larger than LOOM_DESIGN_MAX_*), LOOM_ENOMEM.
 * *out is NULL on failure.  Thread-safe.
 */
LOOM_API int loom_design_new(uint32_t rows, uint32_t cols, loom_design **out);

/* Free a design; NULL is a no-op. */
LOOM_API void loom_design_free(loom_design *d);

/* Deep copy (maps and yarn table).  LOOM_OK; LOOM_EINVAL (NULL d or out,
   zero size, d->n_types 0 or above LOOM_MAX_YARN_TYPES); LOOM_ERANGE (d's
   size beyond LOOM_DESIGN_MAX_*); LOOM_ENOMEM.  *out is untouched on
   failure. */
LOOM_API int loom_design_clone(const loom_design *d, loom_design **out);

/*
 * Resize the yarn table to n entries (1..LOOM_MAX_YARN_TYPES); existing
 * entries keep their values, new entries get a default name "typeK", grey
 * albedo 0.5, alignment 0.3 and thickness 0.  The type maps are not
 * touched.  Returns LOOM_OK; LOOM_EINVAL (NULL d, n = 0 or above
 * LOOM_MAX_YARN_TYPES); LOOM_ENOMEM (the table is unchanged).
 */
LOOM_API int loom_design_set_types(loom_design *d, uint32_t n);

/* Check internal consistency: every type ID < n_types, sizes in range.
   Returns LOOM_OK, LOOM_EINVAL (NULL d) or LOOM_EFORMAT with the reason in
   diag. */
LOOM_API int loom_design_validate(const loom_design *d, loom_diag *diag);

/* ---- Generators: elementary weaves ------------------------------------- */

enum loom_weave_kind {
	LOOM_WEAVE_PLAIN = 0,
	LOOM_WEAVE_TWILL,        /* over/under, shift +-1 per pick */
	LOOM_WEAVE_SATIN,        /* over/under, shift = move per pick */
	LOOM_WEAVE_BASKET,       /* checkerboard of cells `over` picks by
	                            `under` ends (basket:2 = 2x2 groups) */
	LOOM_WEAVE_HERRINGBONE,  /* twill reversing direction every `period` ends */
	LOOM_WEAVE_BROKEN_TWILL, /* twill broken (shifted) every `period` ends */
	LOOM_WEAVE_WAVY_TWILL,   /* twill whose shift follows a zigzag wave */
	LOOM_WEAVE_KIND_COUNT_
};

/* Parameters of an elementary weave.  Fields a kind does not use are ignored.
   Initialise with LOOM_WEAVE_PARAMS_INIT. */
typedef struct loom_weave_params {
	int kind;          /* enum loom_weave_kind */
	uint32_t over;     /* warp-over picks per repeat (twill, satin); picks
	                      per cell (basket) */
	uint32_t under;    /* warp-under picks per repeat; ends per cell
	                      (basket) */
	uint32_t move;     /* satin move number (counter), 0 = choose one */
	int direction;     /* +1: rising to the right (Z twill); -1: S twill */
	uint32_t period;   /* herringbone / broken / wavy: ends per zig (0 =
	                      repeat length) */
} loom_weave_params;

#define LOOM_WEAVE_PARAMS_INIT {LOOM_WEAVE_PLAIN, 1, 1, 0, 1, 0}

/*
 * Natural repeat size (rows, cols) of an elementary weave.  LOOM_EINVAL with
 * the reason in diag for impossible parameters (e.g. a satin move that is not
 * coprime with the repeat, or a move of 1 or repeat-1, which gives a twill).
 */
LOOM_API int loom_weave_repeat(const loom_weave_params *p, uint32_t *rows,
                               uint32_t *cols, loom_diag *diag);

/* Value W(i,j) (0 or 1) of an elementary weave at any (wrapping)
   position, for parameters that loom_weave_repeat accepted (nothing is
   checked; p must not be NULL). */
LOOM_API int loom_weave_cell(const loom_weave_params *p, uint64_t i, uint64_t j);

/*
 * Make a rows x cols design filled with the weave (tiled from its repeat).
 * rows/cols 0 = one natural repeat.  Errors as loom_weave_repeat and
 * loom_design_new.
 */
LOOM_API int loom_design_make(const loom_weave_params *p, uint32_t rows,
                              uint32_t cols, loom_design **out, loom_diag *diag);

/*
 * Parse a weave name as used on the command line and in mapping files:
 *   "plain", "twill:2/3", "twill:2/3:s" (S direction), "satin:1/4",
 *   "satin:1/4:move=2", "basket:2", "herringbone:2/2:period=4",
 *   "broken-twill:2/2", "wavy-twill:2/2:period=6".
 * Returns LOOM_OK or LOOM_EINVAL with the reason in diag.
 */
LOOM_API int loom_weave_parse(const char *name, loom_weave_params *p,
                              loom_diag *diag);

/* Canonical name of params (the inverse of loom_weave_parse) into buf.
   Returns LOOM_OK; LOOM_EINVAL (NULL p or buf, unknown kind); LOOM_ERANGE
   (the name needs more than n bytes: buf holds it cut, NUL-terminated if
   n > 0).  64 bytes always suffice. */
LOOM_API int loom_weave_name(const loom_weave_params *p, char *buf, size_t n);

/* ---- Analysis ---------------------------------------------------------- */

typedef struct loom_design_stats {
	uint32_t repeat_rows, repeat_cols; /* smallest period of W (both axes) */
	uint64_t warp_over;        /* cells with W = 1 */
	uint32_t max_warp_float;   /* longest run of 1s along a column (warp
	                              float), counted cyclically */
	uint32_t max_weft_float;   /* longest run of 0s along a row */
	double mean_warp_float, mean_weft_float;
	uint32_t types_used;       /* distinct type IDs used in either map */
	int interlaced;            /* 1 if every end and pick crosses over and
	                              under at least once (the cloth holds) */
} loom_design_stats;

/* Fill *st.  LOOM_OK; LOOM_EINVAL (NULL d or st, missing arrays, zero
   size); LOOM_ENOMEM.  O(rows*cols) time, O(rows + cols) memory. */
LOOM_API int loom_design_analyze(const loom_design *d, loom_design_stats *st);

/* ---- The draft behind a drawdown --------------------------------------- */

#define LOOM_DRAFT_MAX_SHAFTS 4096u /* more distinct ends: no useful draft */

/*
 * A loom draft that weaves a design: threading (the shaft of each end),
 * and either a tie-up and treadling (one treadle per pick) or a liftplan.
 * Shafts and treadles are numbered from 0 here (1 in a printed draft).
 * Recovered from the drawdown: one shaft per distinct end (column of W),
 * in order of first use, and one treadle per distinct pick (row of the
 * liftplan), in order of first use, when at most max_treadles are needed;
 * otherwise no treadles and the liftplan stands alone.  Weaving the draft
 * (rising shed) gives W back exactly.
 */
typedef struct loom_draft {
	uint32_t rows, cols;     /* picks, ends (as the design) */
	uint32_t shafts;         /* distinct ends */
	uint32_t treadles;       /* distinct picks; 0 = liftplan only */
	uint32_t *threading;     /* [cols] shaft of each end */
	uint8_t *liftplan;       /* [rows * shafts] 1 = shaft lifted on the pick */
	uint8_t *tieup;          /* [shafts * treadles] 1 = treadle lifts shaft
	                            (row = shaft); NULL when treadles is 0 */
	uint32_t *treadling;     /* [rows] treadle of each pick; NULL when 0 */
} loom_draft;

/* Recover the draft of d.  LOOM_OK; LOOM_EINVAL (NULL, empty design);
   LOOM_EUNSUPPORTED (more than LOOM_DRAFT_MAX_SHAFTS distinct ends: a
   jacquard design); LOOM_ENOMEM.  O(rows x cols).  Thread-safe. */
LOOM_API int loom_draft_from_design(const loom_design *d, uint32_t max_treadles,
                                    loom_draft **out, loom_diag *diag);
/* Free a draft; NULL is a no-op. */
LOOM_API void loom_draft_free(loom_draft *dr);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_DESIGN_H */
