/*
 * tools/loom/opts.c - the option parser of the loom command (opts.h).
 *
 * Every command declares its options once, as a table of `opt` entries
 * made by the OPT_* macros (git's parse-options is the model): name, short
 * alias, the value's name and type, its range or choices, the help text
 * and where the value goes.  This file is the only code that reads argv,
 * converts values and prints --help, so the three cannot drift apart:
 *
 *   1. Scan.  Walk argv in order: each argument is an option of the table
 *      (its value the rest after '=' or the next argument, whatever that
 *      looks like, so "--budget -1" is a value), a positional (or "-"), or
 *      "--", after which everything is positional.  --help / -h prints the
 *      help at once, --list-options the table's names; an unknown option,
 *      a missing value, a value given to a flag or one positional too many
 *      is a usage error there and then.  So "--help" anywhere after good
 *      syntax wins, as it did when each command had its own loop.
 *   2. Convert.  Each (option, text) pair, in the order given, goes into
 *      its destination by the entry's kind; a text that does not parse or
 *      is out of range stops with "PROG: --NAME: expected WHAT, got
 *      'TEXT'" and "Try 'PROG --help'." (exit 2).  WHAT comes from the
 *      entry (describe()): "an integer in 1..256", "MiB in (0, 1048576]",
 *      "dp, greedy or naive"; a callback entry returns its own.
 *   3. Count.  Fewer positionals than the command needs is "missing NAME".
 *
 * --help is built from the command's hand-written synopsis and description
 * followed by one row per entry: "  -o, --output OUT  help", the help
 * text wrapped at 79 columns in a column chosen from the table (a wide
 * left part puts its help on the next line), "%r" in the text replaced by
 * the range in the words of the error messages, and "\n" starting a list
 * item whose own continuation lines hang two columns deeper.
 *
 * Memory: none allocated but one array of argc (option, text) pairs
 * during opts_parse; the table is the caller's (opts_parse writes only
 * its `seen` counts).  Errors exit the process, as usage errors always
 * did in loom.
 */
#include "opts.h"

#include "cli.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define HELP_WIDTH 79    /* columns of --help */
#define HELP_COL_MAX 26  /* a help column right of this: the row's help starts
                            on the next line instead */
#define WHAT_MAX 256     /* "expected ..." text */

/* ---- describing a value ------------------------------------------------------ */

/* x as written in messages: integers without exponent, else %g. */
static void fmt_num(char *buf, size_t n, double x)
{
	if (x == floor(x) && fabs(x) < 1e15)
		snprintf(buf, n, "%.0f", x);
	else
		snprintf(buf, n, "%g", x);
}

static uint64_t kind_max(enum opt_kind k)
{
	return k == OPTK_U64 ? UINT64_MAX : UINT32_MAX;
}

/* The range of o alone ("1..128", "(0, 1]", "dp, greedy or naive") into
   buf. */
static void describe_range(const opt_entry *o, char *buf, size_t n)
{
	char a[48], b[48];
	size_t len = 0;

	buf[0] = 0;
	switch (o->kind) {
	case OPTK_U32:
	case OPTK_U64:
	case OPTK_SIZE2:
	case OPTK_SIZE3:
		if (o->umax == kind_max(o->kind))
			snprintf(buf, n, "%llu or more", (unsigned long long)o->umin);
		else
			snprintf(buf, n, "%llu..%llu", (unsigned long long)o->umin,
			         (unsigned long long)o->umax);
		break;
	case OPTK_I64:
		snprintf(buf, n, "%lld..%lld", (long long)o->imin, (long long)o->imax);
		break;
	case OPTK_DOUBLE:
		fmt_num(a, sizeof a, o->dmin);
		fmt_num(b, sizeof b, o->dmax);
		if (isinf(o->dmin) && isinf(o->dmax))
			snprintf(buf, n, "any finite number");
		else if (isinf(o->dmax))
			snprintf(buf, n, "%s %s", o->bounds[0] == '(' ? ">" : ">=", a);
		else if (isinf(o->dmin))
			snprintf(buf, n, "%s %s", o->bounds[1] == ')' ? "<" : "<=", b);
		else
			snprintf(buf, n, "%c%s, %s%c", o->bounds[0], a, b, o->bounds[1]);
		break;
	case OPTK_ENUM:
		for (int k = 0; o->choices[k].name && len < n; k++) {
			const char *sep = k == 0 ? "" : o->choices[k + 1].name ? ", " : " or ";
			len += (size_t)snprintf(buf + len, n - len, "%s%s", sep, o->choices[k].name);
		}
		break;
	default:
		break;
	}
}

/* What a good value of o looks like, for "expected ...". */
static void describe(const opt_entry *o, char *buf, size_t n)
{
	char r[WHAT_MAX / 2];
	int full;

	describe_range(o, r, sizeof r);
	switch (o->kind) {
	case OPTK_U32:
	case OPTK_U64:
		full = o->umax == kind_max(o->kind);
		if (o->what)
			snprintf(buf, n, "%s%s%s", o->what, full ? "" : " in ", full ? "" : r);
		else if (full && o->umin <= 1)
			snprintf(buf, n, "a %s integer", o->umin ? "positive" : "non-negative");
		else if (full)
			snprintf(buf, n, "an integer >= %llu", (unsigned long long)o->umin);
		else
			snprintf(buf, n, "an integer in %s", r);
		break;
	case OPTK_I64:
		snprintf(buf, n, "%s in %s", o->what ? o->what : "an integer", r);
		break;
	case OPTK_DOUBLE:
		if (isinf(o->dmin) && isinf(o->dmax))
			snprintf(buf, n, "%s", o->what ? o->what : "a finite number");
		else
			snprintf(buf, n, "%s %s%s", o->what ? o->what : "a number",
			         isinf(o->dmin) || isinf(o->dmax) ? "" : "in ", r);
		break;
	case OPTK_ENUM:
		snprintf(buf, n, "%s", r);
		break;
	case OPTK_SIZE2:
	case OPTK_SIZE3:
		full = o->umax == UINT32_MAX;
		if (full && o->umin <= 1)
			snprintf(buf, n, "%s (%s %s integers)", o->metavar,
			         o->kind == OPTK_SIZE2 ? "two" : "three",
			         o->umin ? "positive" : "non-negative");
		else
			snprintf(buf, n, "%s with each in %s", o->metavar, r);
		break;
	default:
		snprintf(buf, n, "a value");
		break;
	}
}

/* ---- errors ------------------------------------------------------------------- */

void opts_usage(const opts_cmd *c, const char *fmt, ...)
{
	va_list ap;

	fprintf(stderr, "%s: ", c->prog);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fprintf(stderr, "\nTry '%s --help'.\n", c->prog);
	exit(EXIT_USAGE);
}

static _Noreturn void bad_value(const opts_cmd *c, const opt_entry *o, const char *text,
                                const char *what)
{
	opts_usage(c, "--%s: expected %s, got '%s'", o->long_name, what, text);
}

/* ---- converting values ---------------------------------------------------------- */

/* "AxB" or "AxBxC" (separators x, X or ','): n numbers into v. */
static int parse_sizes(const char *s, uint32_t *v, int n)
{
	char buf[96], *p = buf;

	if (strlen(s) >= sizeof buf)
		return -1;
	strcpy(buf, s);
	for (int k = 0; k < n; k++) {
		char *sep = k + 1 < n ? strpbrk(p, "xX,") : NULL;
		if (k + 1 < n && !sep)
			return -1;
		if (sep)
			*sep = 0;
		if (cli_parse_u32(p, &v[k]))
			return -1;
		p = sep ? sep + 1 : p;
	}
	return 0;
}

static int in_bounds(const opt_entry *o, double x)
{
	int lo = o->bounds[0] == '(' ? x > o->dmin : x >= o->dmin;
	int hi = o->bounds[1] == ')' ? x < o->dmax : x <= o->dmax;
	return lo && hi && isfinite(x);
}

static void set_value(const opts_cmd *c, const opt_entry *o, const char *text)
{
	char what[WHAT_MAX];
	const char *msg;
	uint64_t u;
	int64_t i;
	double d;
	uint32_t v[3];
	int n;

	switch (o->kind) {
	case OPTK_FLAG:
		*(int *)o->dest = 1;
		return;
	case OPTK_STRING:
		*(const char **)o->dest = text;
		return;
	case OPTK_U32:
	case OPTK_U64:
		if (cli_parse_u64(text, &u) || u < o->umin || u > o->umax)
			break;
		if (o->kind == OPTK_U32)
			*(uint32_t *)o->dest = (uint32_t)u;
		else
			*(uint64_t *)o->dest = u;
		return;
	case OPTK_I64:
		if (cli_parse_i64(text, &i) || i < o->imin || i > o->imax)
			break;
		*(int64_t *)o->dest = i;
		return;
	case OPTK_DOUBLE:
		if (cli_parse_double(text, &d) || !in_bounds(o, d))
			break;
		*(double *)o->dest = d;
		return;
	case OPTK_ENUM:
		for (int k = 0; o->choices[k].name; k++)
			if ((o->flags & OPTF_ICASE) ? strcasecmp(text, o->choices[k].name) == 0
			                            : strcmp(text, o->choices[k].name) == 0) {
				*(int *)o->dest = o->choices[k].value;
				return;
			}
		break;
	case OPTK_SIZE2:
	case OPTK_SIZE3:
		n = o->kind == OPTK_SIZE2 ? 2 : 3;
		if (parse_sizes(text, v, n))
			break;
		for (int k = 0; k < n; k++)
			if (v[k] < o->umin || v[k] > o->umax)
				goto bad;
		memcpy(o->dest, v, (size_t)n * sizeof *v);
		return;
	case OPTK_CALLBACK:
		msg = o->fn(text, o->dest);
		if (!msg)
			return;
		bad_value(c, o, text, msg);
	default:
		return;
	}
bad:
	describe(o, what, sizeof what);
	bad_value(c, o, text, what);
}

/* ---- --help -------------------------------------------------------------------- */

static int is_option(const opt_entry *o)
{
	return o->kind != OPTK_END && o->kind != OPTK_GROUP && o->kind != OPTK_TEXT &&
	       !(o->flags & OPTF_HIDDEN);
}

/* -h, --help: in every table without being written. */
static const opt_entry help_opt = {.kind = OPTK_FLAG, .short_name = 'h',
                                   .long_name = "help", .help = "this text"};

/* The left column of a row: "  -o, --output OUT". */
static void row_left(const opt_entry *o, char *buf, size_t n)
{
	int k;

	if (o->kind == OPTK_TEXT) {
		snprintf(buf, n, "  %s", o->long_name);
		return;
	}
	k = o->short_name ? snprintf(buf, n, "  -%c, ", o->short_name) : snprintf(buf, n, "  ");
	snprintf(buf + k, n - (size_t)k, "--%s%s%s", o->long_name, o->metavar ? " " : "",
	         o->metavar ? o->metavar : "");
}

/* Help text of o with "%r" replaced by its range. */
static void expand_help(const opt_entry *o, char *buf, size_t n)
{
	const char *s = o->help ? o->help : "";
	char r[WHAT_MAX];
	size_t len = 0;

	describe_range(o, r, sizeof r);
	for (; *s && len + 1 < n; s++) {
		if (s[0] == '%' && s[1] == 'r') {
			len += (size_t)snprintf(buf + len, n - len, "%s", r);
			if (len >= n)
				len = n - 1;
			s++;
		} else {
			buf[len++] = *s;
		}
	}
	buf[len] = 0;
}

static void pad(FILE *fp, int n)
{
	while (n-- > 0)
		fputc(' ', fp);
}

/* Print text from column `at` (the cursor is there), each line starting at
   col (continuation lines of a list item at col + 2), wrapped at
   HELP_WIDTH, keeping two spaces after a full stop; ends with a newline. */
static void put_wrapped(FILE *fp, const char *text, int at, int col)
{
	int list = strchr(text, '\n') != NULL;
	const char *s = text;

	if (at > col - 2 && *text) { /* the left part is too wide */
		fputc('\n', fp);
		at = 0;
	}
	while (*s) {
		const char *end = strchr(s, '\n');
		const char *p = s, *stop = end ? end : s + strlen(s);
		int lead = 0, words = 0, gap = 0;

		while (p < stop && *p == ' ') { /* an item's own indent */
			p++;
			lead++;
		}
		pad(fp, col + lead - at);
		at = col + lead;
		while (p < stop) {
			const char *w = p;
			int wl;
			while (w < stop && *w != ' ')
				w++;
			wl = (int)(w - p);
			if (words > 0 && at + gap + wl > HELP_WIDTH) {
				fputc('\n', fp);
				at = col + lead + (list ? 2 : 0);
				pad(fp, at);
				words = 0;
			}
			if (words > 0) {
				pad(fp, gap);
				at += gap;
			}
			fwrite(p, 1, (size_t)wl, fp);
			at += wl;
			words++;
			for (p = w; p < stop && *p == ' '; p++)
				;
			gap = p - w > 2 ? 2 : (int)(p - w);
		}
		fputc('\n', fp);
		at = 0;
		s = end ? end + 1 : stop;
	}
	if (!*text)
		fputc('\n', fp);
}

static void put_row(FILE *fp, const opt_entry *o, int col)
{
	char left[160], text[2048];

	row_left(o, left, sizeof left);
	expand_help(o, text, sizeof text);
	fputs(left, fp);
	put_wrapped(fp, text, (int)strlen(left), col);
}

/* The help column: two spaces right of the widest left part that fits. */
static int help_column(const opts_cmd *c)
{
	char left[160];
	int col = 0, w;

	row_left(&help_opt, left, sizeof left);
	col = (int)strlen(left) + 2;
	for (const opt_entry *o = c->opts; o->kind != OPTK_END; o++) {
		if (!is_option(o) && o->kind != OPTK_TEXT)
			continue;
		row_left(o, left, sizeof left);
		w = (int)strlen(left) + 2;
		if (w <= HELP_COL_MAX && w > col)
			col = w;
	}
	return col;
}

static void put_lines(FILE *fp, const char *first, const char *rest, const char *text)
{
	const char *s = text;

	fputs(first, fp);
	while (*s) {
		const char *e = strchr(s, '\n');
		size_t n = e ? (size_t)(e - s) : strlen(s);
		fwrite(s, 1, n, fp);
		fputc('\n', fp);
		s += n + (e != NULL);
		if (*s)
			fputs(rest, fp);
	}
}

/* The end of a verbatim block: one newline, whatever the text ends with. */
static void put_block(FILE *fp, const char *text)
{
	size_t n = strlen(text);

	while (n > 0 && text[n - 1] == '\n')
		n--;
	fwrite(text, 1, n, fp);
	fputc('\n', fp);
}

static void print_help(const opts_cmd *c, FILE *fp)
{
	int col = help_column(c), heading = 0;

	put_lines(fp, "usage: ", "       ", c->usage);
	if (c->about) {
		fputc('\n', fp);
		put_block(fp, c->about);
	}
	for (const opt_entry *o = c->opts; o->kind != OPTK_END; o++) {
		if (o->kind == OPTK_GROUP) {
			fprintf(fp, "\n%s\n", o->help);
			heading = 1;
			continue;
		}
		if (!is_option(o) && o->kind != OPTK_TEXT)
			continue;
		if (!heading) {
			fputs("\noptions:\n", fp);
			heading = 1;
		}
		put_row(fp, o, col);
	}
	if (!heading)
		fputs("\noptions:\n", fp);
	put_row(fp, &help_opt, col);
	if (!c->exit1 || c->exit1[0])
		fprintf(fp, "\nExit status: 0 success, 1 %s, 2 usage error.\n",
		        c->exit1 ? c->exit1 : "bad input or failed operation");
	if (c->footer) {
		fputc('\n', fp);
		put_block(fp, c->footer);
	}
}

/* --list-options: each name of each option, one a line, "=METAVAR" after
   those that take a value. */
static void list_options(const opts_cmd *c)
{
	for (const opt_entry *o = c->opts; o->kind != OPTK_END; o++) {
		const char *v = o->kind == OPTK_FLAG ? "" : "=";
		const char *m = o->kind == OPTK_FLAG ? "" : o->metavar ? o->metavar : "VALUE";
		if (!is_option(o))
			continue;
		if (o->short_name)
			printf("-%c%s%s\n", o->short_name, v, m);
		printf("--%s%s%s\n", o->long_name, v, m);
	}
	printf("-h\n--help\n");
}

/* ---- parsing ------------------------------------------------------------------- */

struct given {
	opt_entry *o;
	const char *text;
};

/* The entry for "--name" (len bytes of name) or "-s" (short). */
static opt_entry *find(const opts_cmd *c, const char *name, size_t len, char short_name)
{
	for (opt_entry *o = c->opts; o->kind != OPTK_END; o++) {
		if (o->kind == OPTK_GROUP || o->kind == OPTK_TEXT)
			continue;
		if (short_name ? o->short_name == short_name
		               : strlen(o->long_name) == len && memcmp(o->long_name, name, len) == 0)
			return o;
	}
	return NULL;
}

void opts_parse(opts_cmd *c, int argc, char **argv)
{
	struct given *g = calloc((size_t)(argc > 0 ? argc : 1), sizeof *g);
	int ng = 0, only_pos = 0;

	if (!g)
		cli_fail(c->prog, "out of memory");
	c->n_pos = 0;
	for (opt_entry *o = c->opts; o->kind != OPTK_END; o++)
		o->seen = 0;
	/* step 1: scan */
	for (int i = 1; i < argc; i++) {
		const char *s = argv[i], *eq, *name;
		size_t len;
		opt_entry *o;

		if (only_pos || s[0] != '-' || s[1] == 0) {
			if (c->n_pos >= c->pos_max) {
				if (c->pos_max == 1)
					opts_usage(c, "more than one %s ('%s' and '%s')", c->pos_name,
					            c->pos[0], s);
				opts_usage(c, "unexpected argument '%s'", s);
			}
			c->pos[c->n_pos++] = s;
			continue;
		}
		if (strcmp(s, "--") == 0) {
			only_pos = 1;
			continue;
		}
		if (strcmp(s, "--help") == 0 || strcmp(s, "-h") == 0) {
			print_help(c, stdout);
			exit(0);
		}
		if (strcmp(s, "--list-options") == 0) {
			list_options(c);
			exit(0);
		}
		name = s + (s[1] == '-' ? 2 : 1);
		eq = strchr(name, '=');
		len = eq ? (size_t)(eq - name) : strlen(name);
		if (s[1] == '-')
			o = find(c, name, len, 0);
		else
			o = len == 1 ? find(c, NULL, 0, name[0]) : NULL;
		if (!o)
			opts_usage(c, "unknown option '%s'", s);
		if (o->kind == OPTK_FLAG) {
			if (eq)
				opts_usage(c, "option %.*s takes no value", (int)(eq - s), s);
			g[ng].text = NULL;
		} else if (eq) {
			g[ng].text = eq + 1;
		} else if (i + 1 < argc) {
			g[ng].text = argv[++i];
		} else {
			opts_usage(c, "option %s needs a value", s);
		}
		g[ng++].o = o;
	}
	/* step 2: convert, in the order given */
	for (int k = 0; k < ng; k++) {
		g[k].o->seen++;
		set_value(c, g[k].o, g[k].text);
	}
	free(g);
	/* step 3: count the positionals */
	if (c->n_pos < c->pos_min) {
		if (c->pos_missing)
			opts_usage(c, "%s", c->pos_missing);
		opts_usage(c, "missing %s", c->pos_name);
	}
}

unsigned opt_given(const opts_cmd *c, const void *dest)
{
	for (const opt_entry *o = c->opts; o->kind != OPTK_END; o++)
		if (o->dest == dest && o->kind != OPTK_GROUP && o->kind != OPTK_TEXT)
			return o->seen;
	return 0;
}

/* ---- subcommands ------------------------------------------------------------------ */

static void dispatch_help(const opts_dispatch *d, FILE *fp)
{
	char left[128];
	int col = 0;

	fprintf(fp, "usage: %s COMMAND [ARGS...]\n", d->prog);
	if (d->about) {
		fputc('\n', fp);
		put_block(fp, d->about);
	}
	for (const opts_sub *s = d->subs; s->name; s++) {
		int w = snprintf(left, sizeof left, "  %s%s%s", s->name, s->args ? " " : "",
		                 s->args ? s->args : "") + 2;
		col = w > col ? w : col;
	}
	fputs("\ncommands:\n", fp);
	for (const opts_sub *s = d->subs; s->name; s++) {
		snprintf(left, sizeof left, "  %s%s%s", s->name, s->args ? " " : "",
		         s->args ? s->args : "");
		fputs(left, fp);
		put_wrapped(fp, s->summary, (int)strlen(left), col);
	}
	fprintf(fp, "\n  %s COMMAND --help   options of one command\n", d->prog);
	fprintf(fp, "\nExit status: 0 success, 1 bad input or failed operation, 2 usage "
	        "error.\n");
	if (d->footer)
		put_block(fp, d->footer);
}

int opts_run_sub(const opts_dispatch *d, int argc, char **argv)
{
	if (argc < 2) {
		dispatch_help(d, stderr);
		return EXIT_USAGE;
	}
	if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
	    strcmp(argv[1], "help") == 0) {
		dispatch_help(d, stdout);
		return 0;
	}
	for (const opts_sub *s = d->subs; s->name; s++)
		if (strcmp(argv[1], s->name) == 0)
			return s->fn(argc - 1, argv + 1);
	fprintf(stderr, "%s: unknown command '%s'\nTry '%s --help'.\n", d->prog, argv[1],
	        d->prog);
	return EXIT_USAGE;
}
