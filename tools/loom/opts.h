/*
 * tools/loom/opts.h - the option parser of the loom command: each command
 * declares its options once, as a table, and one routine parses argv
 * against it, checks every value's type and range, and prints --help from
 * the same table (opts.c explains how).
 *
 *	opt o[] = {
 *		OPT_OUTPUT(&out, "FABRIC", "fabric file to write (.loomf)"),
 *		OPT_U32(0, "rank", &rank, "R", 1, 128, "edge-fix rank, %r (default 15)"),
 *		OPT_QUIET(&quiet, "no progress or summary"),
 *		OPT_END()
 *	};
 *	opts_cmd c = {.prog = "loom synth", .usage = "...", .about = "...",
 *	              .opts = o, .pos_name = "DESIGN", .pos_min = 1, .pos_max = 1,
 *	              .pos = &design};
 *	opts_parse(&c, argc, argv);
 *
 * A value that does not parse or is out of range is a usage error, in one
 * wording for every command: "loom CMD: --opt: expected WHAT, got 'TEXT'",
 * then "Try 'loom CMD --help'.", exit 2.  Destinations keep their initial
 * value when the option is absent; opt_given() says whether it was given.
 */
#ifndef LOOM_OPTS_H
#define LOOM_OPTS_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

enum opt_kind {
	OPTK_END = 0,  /* ends a table */
	OPTK_GROUP,    /* a heading of --help ("pipeline:"), no option */
	OPTK_TEXT,     /* a row of --help that is not an option: long_name is
	                  its left column (e.g. "SCAN.vol") */
	OPTK_FLAG,     /* int: set to 1; takes no value */
	OPTK_STRING,   /* const char *: the text as given */
	OPTK_U32,      /* uint32_t in [umin, umax] */
	OPTK_U64,      /* uint64_t in [umin, umax] */
	OPTK_I64,      /* int64_t in [imin, imax] */
	OPTK_DOUBLE,   /* double, finite, in the interval `bounds` of dmin, dmax */
	OPTK_ENUM,     /* int: the value of the choice named */
	OPTK_SIZE2,    /* uint32_t[2]: "MxN" (or "MXN", "M,N"), each in [umin, umax] */
	OPTK_SIZE3,    /* uint32_t[3]: "AxBxC" (or "A,B,C"), each in [umin, umax] */
	OPTK_CALLBACK  /* fn(text, dest) parses and checks the value itself */
};

/* One name of an OPTK_ENUM option and the int it stores. */
typedef struct opt_choice {
	const char *name;
	int value;
} opt_choice;

/* Parse text into dest.  Returns NULL when it is good, else what was
   expected ("three numbers X,Y,Z"), for the message; dest may then be
   partly written. */
typedef const char *(*opt_fn)(const char *text, void *dest);

#define OPTF_ICASE 1u   /* enum: names compared without regard to case */
#define OPTF_HIDDEN 2u  /* not in --help nor --list-options */

typedef struct opt_entry {
	enum opt_kind kind;
	char short_name;          /* 'o' for -o, or 0 */
	const char *long_name;    /* "output" for --output (no dashes) */
	const char *metavar;      /* the value in --help ("OUT"); NULL for flags */
	const char *help;         /* --help text, wrapped to fit; "\n" starts a
	                             list item; "%r" is replaced by the range */
	void *dest;               /* where the value goes (type by kind) */
	uint64_t umin, umax;      /* U32, U64, SIZE2, SIZE3 */
	int64_t imin, imax;       /* I64 */
	double dmin, dmax;        /* DOUBLE (+-INFINITY: unbounded) */
	const char *bounds;       /* DOUBLE: "[]", "(]", "[)" or "()" */
	const char *what;         /* noun of the expected value ("degrees",
	                             "MiB"); NULL: by kind ("a number") */
	const opt_choice *choices;/* ENUM: terminated by a NULL name */
	opt_fn fn;                /* CALLBACK */
	unsigned flags;           /* OPTF_* */
	unsigned seen;            /* times given (opts_parse counts) */
} opt_entry;

/* Compile-time check that v points to T (a mismatch is a warning, and the
   build uses -Werror). */
#define OPT_DEST_(T, v) ((void *)(1 ? (v) : (T *)0))

#define OPT_END() {.kind = OPTK_END}
#define OPT_GROUP(heading) {.kind = OPTK_GROUP, .help = (heading)}
#define OPT_TEXT(left, h) {.kind = OPTK_TEXT, .long_name = (left), .help = (h)}
#define OPT_FLAG(s, l, v, h) \
	{.kind = OPTK_FLAG, .short_name = (s), .long_name = (l), \
	 .dest = OPT_DEST_(int, v), .help = (h)}
#define OPT_STRING(s, l, v, meta, h) \
	{.kind = OPTK_STRING, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(const char *, v), .help = (h)}
#define OPT_U32(s, l, v, meta, lo, hi, h) \
	{.kind = OPTK_U32, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(uint32_t, v), .umin = (lo), .umax = (hi), .help = (h)}
#define OPT_U64(s, l, v, meta, lo, hi, h) \
	{.kind = OPTK_U64, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(uint64_t, v), .umin = (lo), .umax = (hi), .help = (h)}
#define OPT_I64(s, l, v, meta, lo, hi, h) \
	{.kind = OPTK_I64, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(int64_t, v), .imin = (lo), .imax = (hi), .help = (h)}
/* bounds: "[]" lo <= x <= hi, "(]" lo < x <= hi, "[)", "()"; what: the
   noun of messages ("degrees"), NULL for "a number". */
#define OPT_DOUBLE(s, l, v, meta, bnd, lo, hi, wh, h) \
	{.kind = OPTK_DOUBLE, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(double, v), .bounds = (bnd), .dmin = (lo), .dmax = (hi), \
	 .what = (wh), .help = (h)}
#define OPT_ENUM(s, l, v, meta, ch, h) \
	{.kind = OPTK_ENUM, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(int, v), .choices = (ch), .help = (h)}
#define OPT_ENUM_ICASE(s, l, v, meta, ch, h) \
	{.kind = OPTK_ENUM, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(int, v), .choices = (ch), .flags = OPTF_ICASE, .help = (h)}
#define OPT_SIZE2(s, l, v, meta, lo, hi, h) \
	{.kind = OPTK_SIZE2, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(uint32_t, v), .umin = (lo), .umax = (hi), .help = (h)}
#define OPT_SIZE3(s, l, v, meta, lo, hi, h) \
	{.kind = OPTK_SIZE3, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = OPT_DEST_(uint32_t, v), .umin = (lo), .umax = (hi), .help = (h)}
#define OPT_CALLBACK(s, l, v, meta, f, h) \
	{.kind = OPTK_CALLBACK, .short_name = (s), .long_name = (l), .metavar = (meta), \
	 .dest = (v), .fn = (f), .help = (h)}

/* ---- the options most commands share, defined once ------------------------ */

#define OPTS_BUDGET_MAX_MB 1048576.0 /* --budget: at most 1 TiB */

#define OPT_QUIET(v, h) OPT_FLAG('q', "quiet", v, h)
#define OPT_JSON(v, h) OPT_FLAG(0, "json", v, h)
#define OPT_DB(v, h) OPT_STRING(0, "db", v, "DB", h)
#define OPT_OUTPUT(v, meta, h) OPT_STRING('o', "output", v, meta, h)
#define OPT_SEED(v, meta, h) OPT_U64(0, "seed", v, meta, 0, UINT64_MAX, h)
#define OPT_THREADS(v, max, h) OPT_U32(0, "threads", v, "N", 1, max, h)
#define OPT_BUDGET(v, h) \
	OPT_DOUBLE(0, "budget", v, "MB", "(]", 0, OPTS_BUDGET_MAX_MB, "MiB", h)
/* -h, --help is in every table without being written: opts_parse adds it. */

/* ---- a command -------------------------------------------------------------- */

typedef struct opts_cmd {
	const char *prog;        /* "loom synth": messages and --help */
	const char *usage;       /* synopsis lines; --help prints "usage: " before
	                            the first and 7 spaces before the others */
	const char *about;       /* what the command does (verbatim), or NULL */
	const char *exit1;       /* what exit status 1 means (NULL: "bad input
	                            or failed operation"; "": no exit line) */
	const char *footer;      /* verbatim after the exit line, or NULL */
	opt_entry *opts;               /* the table, ended by OPT_END() */
	const char *pos_name;    /* positional arguments' name ("FABRIC") */
	const char *pos_missing; /* message when fewer than pos_min (NULL:
	                            "missing FABRIC") */
	int pos_min, pos_max;    /* how many positionals are accepted */
	const char **pos;        /* pos_max slots for them */
	int n_pos;               /* how many were given (opts_parse sets it) */
} opts_cmd;

/*
 * Parse argv[1..argc) (argv[0] is the command's own name) against c->opts:
 * "--name VALUE", "--name=VALUE", "-s VALUE", "-s=VALUE", flags, and
 * positionals into c->pos ("-" alone is positional; after "--" everything
 * is).  --help or -h anywhere prints the help (stdout) and exits 0;
 * --list-options prints the option names of the table, one a line
 * ("--db=DB" for one that takes a value, "--json" for a flag), and exits 0
 * (tests/cli/test_help.sh compares them with --help).  Any error
 * is a usage error: message on stderr, exit 2.  Given twice, an option's
 * last value wins.
 */
void opts_parse(opts_cmd *c, int argc, char **argv);

/* Times the option whose destination is dest was given (0: absent). */
unsigned opt_given(const opts_cmd *c, const void *dest);

/* A usage error found after parsing (options that do not go together, a
   missing -o): "PROG: message", "Try 'PROG --help'.", exit 2. */
_Noreturn void opts_usage(const opts_cmd *c, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

/* ---- commands of commands (loom pattern make, loom exemplar build) -------- */

typedef struct opts_sub {
	const char *name;      /* "make" */
	const char *args;      /* shown after it in the list ("KIND"), or NULL */
	int (*fn)(int argc, char **argv);
	const char *summary;   /* one line ("\n" continues it) */
} opts_sub;

typedef struct opts_dispatch {
	const char *prog;      /* "loom pattern" */
	const char *about;     /* before the list of commands (verbatim) */
	const char *footer;    /* after it (verbatim), or NULL */
	const opts_sub *subs;  /* ended by a NULL name */
} opts_dispatch;

/* Run the subcommand argv[1] with argv + 1.  No subcommand: the help on
   stderr, exit 2; --help, -h or help: the help on stdout, 0; an unknown
   one: exit 2 with "unknown command 'X'".  Returns the subcommand's
   status. */
int opts_run_sub(const opts_dispatch *d, int argc, char **argv);

#endif
