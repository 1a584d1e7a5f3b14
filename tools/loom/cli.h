/*
 * tools/loom/cli.h - shared pieces of the loom command: exit codes,
 * messages, value parsers, JSON output, locating the default data (the
 * option parser is opts.h).
 *
 * Exit codes (stable, scripts rely on them): 0 success, 1 bad input or a
 * failed operation, 2 usage error.  Errors and warnings go to stderr as
 * "loom CMD: message"; results go to stdout.
 */
#ifndef LOOM_CLI_H
#define LOOM_CLI_H

#include "loom.h"

#include <stdint.h>
#include <stdio.h>

#define EXIT_BAD_INPUT 1
#define EXIT_USAGE 2

/* A subcommand: argv[0] is the subcommand's own name. */
typedef int (*cli_cmd_fn)(int argc, char **argv);

/* Options and usage errors: opts.h (one table per command). */

/* Print "prog: message" to stderr (no exit). */
void cli_error(const char *prog, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
/* Failure of an operation: print "prog: message", exit 1. */
_Noreturn void cli_fail(const char *prog, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

/* The CPUs online, 1..256: what "--threads 0" (all CPUs) means. */
uint32_t cli_cpus(void);

/* Parsers of values (opts.c and callbacks); 0 on success, -1 on bad text. */
int cli_parse_u32(const char *s, uint32_t *v);
int cli_parse_u64(const char *s, uint64_t *v);
int cli_parse_i64(const char *s, int64_t *v);
int cli_parse_double(const char *s, double *v);
/* "MxN" (or "MXN", "M,N") */
int cli_parse_size2(const char *s, uint32_t *a, uint32_t *b);

/* Warning sink for loom_diag: prints "loom: warning: msg" to stderr unless
   quiet is set (user points to an int quiet flag, may be NULL). */
void cli_warn_sink(void *user, const char *msg);
/* Initialise a diag with the CLI warning sink. */
void cli_diag_init(loom_diag *d, int *quiet);

/* Before loading fabric file path: if its design and base assignment (5
   bytes a crossing, from the file's header) cannot fit in budget bytes,
   print why and "prog: WHAT at least --budget N" (a lower bound: the
   design alone) and exit with code.  Returns otherwise (also when the
   header cannot be read: loom_fabric_open reports that). */
void cli_fabric_fits(const char *prog, const char *path, double budget, const char *what,
                     int code);

/* Directory holding the default data (database, sample drafts), in the
   documented order: $LOOM_DATA, <exe dir>/share/loom (build tree),
   <exe dir>/../share/loom (installed).  Returns a static string or NULL. */
const char *cli_data_dir(void);

/* The exemplar database to use (tools/loom/dbpath.c): opt (a --db value) if
   set, else $LOOM_DB, else cli_data_dir()/default.ldb if it exists; NULL if
   none.  cli_db_require fails (exit 1, message naming where it looked)
   instead of returning NULL. */
const char *cli_db_path(const char *opt);
const char *cli_db_require(const char *opt, const char *prog);

/* Databases for a draft's sett (tools/loom/settdb.c, docs/exemplars.md):
   the cache directory ($LOOM_CACHE_DIR, $XDG_CACHE_HOME/loom,
   $HOME/.cache/loom; NULL if none); the path of the database generated for
   d's sett and yarns (d->sett[0] and [1] > 0; else the small preset's
   geometry) with fibre presets `fibre` ("WARP[,WEFT]"; NULL: cotton), made
   and cached if needed (fails, exit 1, on errors); a warning when db's crossing aspect does not
   match d's sett. */
const char *cli_cache_dir(void);
const char *cli_sett_db(const char *prog, const loom_design *d,
                        const char *fibre, int quiet);
/* The distinct (warp, weft) material pairs of d's crossings, in order of
   first use, types without a material taking def[] (0: cotton); the first
   max go to pairs, the count is returned (docs/exemplars.md, "Materials
   per yarn type"). */
uint32_t cli_design_pairs(const loom_design *d, const uint8_t def[2],
                          uint8_t pairs[][2], uint32_t max);
void cli_sett_check(const loom_design *d, const loom_db *db, const char *db_path,
                    int quiet);
/* The design's longest warp and weft floats (dfl, around the repeat) and
   the database's (xfl, within each exemplar's weave); unless quiet, a
   warning on stderr when the design's are longer (docs/fabric.md, "loom
   synth").  1, or 0 when d cannot be analysed. */
int cli_float_check(const char *prog, const loom_design *d, const loom_db *db, int quiet,
                    uint32_t dfl[2], uint32_t xfl[2]);

/* Before long work (tools/loom/outcheck.c): fail (exit 1) when path is a
   directory or its directory is missing or not writable; for an output
   directory, when it is not a directory or cannot be made or written. */
void cli_check_output(const char *prog, const char *path);
void cli_check_output_dir(const char *prog, const char *dir);

/* 1 if s ends in ext, compared without regard to case (".PNG" is ".png"). */
int cli_ends_with(const char *s, const char *ext);

/* Write an OpenEXR image of h rows of w pixels x n_ch float channels
   (interleaved, row after row) atomically.  LOOM_OK or the writer's code. */
int cli_write_exr(const char *path, uint32_t w, uint32_t h, const loom_exr_channel *ch,
                  uint32_t n_ch, const float *rows, loom_diag *diag);

/* Write w x h linear RGB floats as OpenEXR (float R, G, B) when path ends in
   .exr, else as an sRGB 8-bit image (PNG, PPM: loom_image_write) after
   `exposure` stops.  LOOM_OK or the writer's code, the reason in diag. */
int cli_write_rgb(const char *path, const float *rgb, uint32_t w, uint32_t h,
                  double exposure, loom_diag *diag);

/* ---- JSON output -------------------------------------------------------- */
/* A small streaming writer that produces valid, indented JSON. */
typedef struct json_w {
	FILE *fp;
	int depth;
	int first[32];  /* no element yet at this depth */
	char close[32]; /* closing bracket at this depth */
} json_w;

void jw_begin(json_w *w, FILE *fp);                 /* opens the top object */
void jw_end(json_w *w);                             /* closes it, newline */
void jw_obj(json_w *w, const char *key);            /* key may be NULL in arrays */
void jw_arr(json_w *w, const char *key);
void jw_close(json_w *w);                           /* closes obj or arr */
void jw_str(json_w *w, const char *key, const char *s);
void jw_int(json_w *w, const char *key, long long v);
void jw_uint(json_w *w, const char *key, unsigned long long v);
void jw_num(json_w *w, const char *key, double v);  /* %.9g, NaN -> null */
void jw_bool(json_w *w, const char *key, int v);

/* A texture's brick requests served without a read (1 when none). */
double cli_hit_rate(const loom_texture_stats *st);
/* The brick cache's figures as keys of the open object (loom sample
   --json at the top level, loom render --json in "texture"): hit_rate,
   brick_requests, hits, misses, empty_bricks, evictions, bytes_read,
   bytes_decompressed, decompress_seconds, crossings, dz_columns,
   budget_bytes, peak_cache_bytes, cache_frames. */
void jw_texture_stats(json_w *w, const loom_texture_stats *st);

#endif
