/*
 * tools/loom/cli.h - shared pieces of the loom command: argument parsing,
 * exit codes, messages, JSON output, locating the default data.
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

/* Argument cursor over argv[1..]. */
typedef struct cli_args {
	int argc;
	char **argv;
	int i;             /* next argument */
	const char *prog;  /* "loom pattern make", for messages */
	const char *help;  /* full --help text */
} cli_args;

void cli_init(cli_args *a, int argc, char **argv, const char *prog,
              const char *help);
/* 1 while arguments remain. */
int cli_more(const cli_args *a);
/* Current argument is the flag `name` (or --help / -h, which print help and
   exit 0): consume it and return 1. */
int cli_flag(cli_args *a, const char *name);
/* Current argument is `--name VALUE` or `--name=VALUE`: consume it, store the
   value and return 1.  A missing value is a usage error. */
int cli_value(cli_args *a, const char *name, const char **val);
/* Current argument is positional (not starting with '-', or "-" alone):
   consume and return it; NULL otherwise. */
const char *cli_positional(cli_args *a);
/* Usage error about the current argument (unknown option). */
_Noreturn void cli_unknown(const cli_args *a);
/* Usage error: message, then "Try '<prog> --help'."; exit 2. */
_Noreturn void cli_usage(const cli_args *a, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
/* Print "prog: message" to stderr (no exit). */
void cli_error(const char *prog, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
/* Failure of an operation: print "prog: message", exit 1. */
_Noreturn void cli_fail(const char *prog, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

/* Parsers for option values; return 0 on success, -1 on bad text. */
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

#endif
