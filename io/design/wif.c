/*
 * io/design/wif.c - WIF 1.1 reader (Weaving Information File, the interchange
 * format of hand-weaving software).  docs/wif.md is the user's view.
 *
 * A WIF file is an INI-like text: [SECTION] lines, KEY=VALUE lines, ';'
 * comments.  The drawdown needs four tables:
 *
 *     [THREADING]  end    = shaft[,shaft...]     which shafts carry each end
 *     [TIEUP]      treadle= shaft[,shaft...]     which shafts a treadle lifts
 *     [TREADLING]  pick   = treadle[,treadle...] treadles pressed per pick
 *     [LIFTPLAN]   pick   = shaft[,shaft...]     shafts lifted per pick
 *
 *     lift(pick)   = LIFTPLAN line if a liftplan exists, else the union of
 *                    the TIEUP lines of the pick's TREADLING treadles
 *     W(pick, end) = 1 (warp over) iff THREADING(end) meets lift(pick);
 *                    the complement for a sinking shed.
 *
 * The reader works in two steps:
 *
 *   Step 1 (parse_text): one pass over the lines.  Every numeric table
 *   entry becomes a wif_entry {key, line, values}, its values appended to
 *   one growing pool; scalar keys ([WEAVING] Shafts, [WARP] Color...) are
 *   kept as slices of the text.  Memory is proportional to the input.
 *
 *   Step 2 (build): index entries by key (the last duplicate wins), check
 *   what cannot yield a drawdown, then compute the drawdown row by row.
 *   Shafts are renumbered densely, keeping only the shafts some end is
 *   threaded on (a lifted shaft that carries no end changes nothing), plus
 *   one extra bit that is never set for unthreaded ends.  A lift is a
 *   bitset of `words` 64-bit words, words <= ends/64 + 1, so every table
 *   built here is bounded by the design size, never by the (possibly
 *   absurd) shaft numbers in the file.  Picks whose value list equals an
 *   earlier pick's copy that row.  Cost: O(input + picks x ends).
 *
 * Yarn types: every distinct (warp or weft, colour, thickness) is a type;
 * warp types first in order of first end, then weft types by first pick.
 * Colours are normalised by the [COLOR PALETTE] Range and linearised from
 * sRGB into the type's albedo.
 *
 * Messages are "name:line: what was expected, got what".  Warnings go
 * through loom__warn, once per kind of problem and section.
 */
#include "core/internal.h"
#include "io/core/file.h"
#include "wif_internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#define WIF_MAX_ENDS     LOOM_DESIGN_MAX_SIDE /* largest end number */
#define WIF_MAX_PICKS    LOOM_DESIGN_MAX_SIDE /* largest pick number */
#define WIF_MAX_SHAFTS   65536u   /* largest shaft number (jacquard-size) */
#define WIF_MAX_TREADLES 4096u    /* largest treadle number */
#define WIF_MAX_COLORS   65536u   /* largest colour-table index */
#define WIF_MAX_COMPONENT 16777215u /* largest colour component value */
#define WIF_MAX_THICKNESS 1e6     /* largest thickness value, any unit */
#define WIF_MEMO_SLOTS   4096u    /* pick-row memo (power of two) */

/* ---- parser state ------------------------------------------------------ */

enum { /* numeric tables ("lists") */
	L_THREADING, L_TIEUP, L_TREADLING, L_LIFTPLAN, L_COLOR_TABLE,
	L_WARP_COLORS, L_WEFT_COLORS, L_WARP_THICK, L_WEFT_THICK,
	L_WARP_SPACING, L_WEFT_SPACING, L_COUNT
};

enum { /* sections; lists follow SEC_LIST */
	SEC_NONE, SEC_IGNORED, SEC_WIF, SEC_WEAVING, SEC_WARP, SEC_WEFT,
	SEC_PALETTE, SEC_LIST
};

enum { K_INTS, K_ONE, K_RGB, K_REAL }; /* value kinds of a list */

static const struct list_info {
	const char *section;  /* for messages */
	const char *norm;     /* normalised name: upper case, no blanks */
	uint32_t key_max;
	uint32_t val_max;     /* K_INTS, K_ONE, K_RGB */
	int kind;
	const char *key_what; /* "end", "pick"... */
	const char *val_what; /* "shaft", "treadle"... */
} lists[L_COUNT] = {
	[L_THREADING] = {"[THREADING]", "THREADING", WIF_MAX_ENDS, WIF_MAX_SHAFTS,
	                 K_INTS, "end", "shaft"},
	[L_TIEUP] = {"[TIEUP]", "TIEUP", WIF_MAX_TREADLES, WIF_MAX_SHAFTS, K_INTS,
	             "treadle", "shaft"},
	[L_TREADLING] = {"[TREADLING]", "TREADLING", WIF_MAX_PICKS,
	                 WIF_MAX_TREADLES, K_INTS, "pick", "treadle"},
	[L_LIFTPLAN] = {"[LIFTPLAN]", "LIFTPLAN", WIF_MAX_PICKS, WIF_MAX_SHAFTS,
	                K_INTS, "pick", "shaft"},
	[L_COLOR_TABLE] = {"[COLOR TABLE]", "COLORTABLE", WIF_MAX_COLORS,
	                   WIF_MAX_COMPONENT, K_RGB, "colour", "colour component"},
	[L_WARP_COLORS] = {"[WARP COLORS]", "WARPCOLORS", WIF_MAX_ENDS,
	                   WIF_MAX_COLORS, K_ONE, "end", "colour index"},
	[L_WEFT_COLORS] = {"[WEFT COLORS]", "WEFTCOLORS", WIF_MAX_PICKS,
	                   WIF_MAX_COLORS, K_ONE, "pick", "colour index"},
	[L_WARP_THICK] = {"[WARP THICKNESS]", "WARPTHICKNESS", WIF_MAX_ENDS, 0,
	                  K_REAL, "end", "thickness"},
	[L_WEFT_THICK] = {"[WEFT THICKNESS]", "WEFTTHICKNESS", WIF_MAX_PICKS, 0,
	                  K_REAL, "pick", "thickness"},
	[L_WARP_SPACING] = {"[WARP SPACING]", "WARPSPACING", WIF_MAX_ENDS, 0,
	                    K_REAL, "end", "spacing"},
	[L_WEFT_SPACING] = {"[WEFT SPACING]", "WEFTSPACING", WIF_MAX_PICKS, 0,
	                    K_REAL, "pick", "spacing"},
};

static const struct { const char *norm; int sec; } scalar_sections[] = {
	{"WIF", SEC_WIF}, {"WEAVING", SEC_WEAVING}, {"WARP", SEC_WARP},
	{"WEFT", SEC_WEFT}, {"COLORPALETTE", SEC_PALETTE},
};

typedef struct wif_entry {
	uint32_t key;  /* end, pick, treadle or colour number (1-based) */
	uint32_t line; /* source line, for messages */
	size_t off;    /* first value in pool (fpool for K_REAL) */
	uint32_t n;    /* number of values (zeros of K_INTS/K_ONE dropped) */
} wif_entry;

typedef struct wif_list {
	wif_entry *e;
	size_t n, cap;
	uint32_t max_key, max_key_line;     /* highest key and where */
	uint32_t max_val, max_val_line;     /* highest value and where */
	uint32_t header_line;               /* first [SECTION] line; 0 = absent */
	uint32_t zero_key_line;             /* first entry numbered 0; 0 = none */
	int has_zero_val;                   /* a value 0 was kept (K_INTS, K_ONE) */
} wif_list;

typedef struct wif_val { /* a scalar KEY=VALUE, value trimmed */
	const char *s;       /* NULL: absent */
	size_t n;
	uint32_t line;
} wif_val;

typedef struct wif_parser {
	const char *name;   /* for messages */
	loom_diag *diag;
	uint64_t max_cells;
	uint32_t last_line; /* number of lines */
	uint32_t weaving_line; /* first [WEAVING] line, 0 = none */
	uint32_t *pool;     /* values of K_INTS/K_ONE/K_RGB entries */
	size_t npool, cap_pool;
	double *fpool;      /* values of K_REAL entries */
	size_t nf, cap_f;
	wif_list list[L_COUNT];
	wif_val version, shafts, treadles, rising, range, form;
	wif_val threads[2], color[2], thick[2], units[2], spacing[2]; /* [0] warp,
	                                                                 [1] weft */
	int color_shift;    /* colour indices counted from 0: add one */
} wif_parser;

/* ---- messages ---------------------------------------------------------- */

static int perr(wif_parser *p, uint32_t line, int code, const char *fmt, ...)
	LOOM_PRINTF(4, 5);
static int perr(wif_parser *p, uint32_t line, int code, const char *fmt, ...)
{
	char buf[LOOM_DIAG_MSG_MAX];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(buf, sizeof buf, fmt, ap);
	va_end(ap);
	return loom__fail(p->diag, code, "%s:%u: %s", p->name, line, buf);
}

static void pwarn(wif_parser *p, uint32_t line, const char *fmt, ...)
	LOOM_PRINTF(3, 4);
static void pwarn(wif_parser *p, uint32_t line, const char *fmt, ...)
{
	char buf[LOOM_DIAG_MSG_MAX];
	va_list ap;

	if (!p->diag)
		return;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof buf, fmt, ap);
	va_end(ap);
	loom__warn(p->diag, "%s:%u: %s", p->name, line, buf);
}

/* Printable copy of s[0..n) (at most 40 chars) for messages. */
static const char *show(char *buf, size_t cap, const char *s, size_t n)
{
	size_t k = 0;

	for (size_t i = 0; i < n && k + 4 < cap && i < 40; i++) {
		unsigned char c = (unsigned char)s[i];
		buf[k++] = (c >= 32 && c < 127) ? (char)c : '?';
	}
	if (n > 40 && k + 4 < cap) {
		memcpy(buf + k, "...", 3);
		k += 3;
	}
	buf[k] = 0;
	return buf;
}

/* ---- small helpers ----------------------------------------------------- */

static int grow(void **ptr, size_t *cap, size_t need, size_t elem)
{
	size_t nc;
	void *q;

	if (need <= *cap)
		return 1;
	nc = *cap ? *cap : 64;
	while (nc < need) {
		if (nc > ((size_t)-1 / 2) / elem)
			return 0;
		nc *= 2;
	}
	q = realloc(*ptr, nc * elem);
	if (!q)
		return 0;
	*ptr = q;
	*cap = nc;
	return 1;
}

static int is_blank(char c)
{
	return c == ' ' || c == '\t' || c == '\f' || c == '\v';
}

static int is_digit(char c)
{
	return c >= '0' && c <= '9';
}

static char upper(char c)
{
	return (c >= 'a' && c <= 'z') ? (char)(c - 'a' + 'A') : c;
}

static void trim(const char **s, size_t *n)
{
	while (*n && is_blank(**s)) {
		(*s)++;
		(*n)--;
	}
	while (*n && is_blank((*s)[*n - 1]))
		(*n)--;
}

/*
 * Normalise a section or key name: upper case, blanks and '_' dropped,
 * "COLOUR" spelled "COLOR".  Returns 0 if it does not fit in out.
 */
static int normalise(const char *s, size_t n, char *out, size_t cap)
{
	size_t k = 0;

	for (size_t i = 0; i < n; i++) {
		char c = upper(s[i]);
		if (is_blank(c) || c == '_')
			continue;
		if (k + 1 >= cap)
			return 0;
		out[k++] = c;
		if (k >= 6 && memcmp(out + k - 6, "COLOUR", 6) == 0) {
			out[k - 2] = 'R';
			k--;
		}
	}
	out[k] = 0;
	return 1;
}

static int val_is(const wif_val *v, const char *word)
{
	return v->n == strlen(word) && loom__strnieq(v->s, word, v->n);
}

/* Parse a whole number scalar (empty = absent).  *present says which. */
static int scalar_u32(wif_parser *p, const wif_val *v, const char *what,
                      uint32_t max, uint32_t *out, int *present)
{
	uint64_t x = 0;
	char b[64];

	*present = 0;
	if (!v->s || v->n == 0)
		return LOOM_OK;
	for (size_t i = 0; i < v->n; i++) {
		if (!is_digit(v->s[i]))
			return perr(p, v->line, LOOM_EFORMAT,
			            "expected a whole number for %s, got '%s'", what,
			            show(b, sizeof b, v->s, v->n));
		x = x * 10 + (uint64_t)(v->s[i] - '0');
		if (x > max)
			return perr(p, v->line, LOOM_ERANGE,
			            "%s %s too large (at most %u)", what,
			            show(b, sizeof b, v->s, v->n), max);
	}
	*out = (uint32_t)x;
	*present = 1;
	return LOOM_OK;
}

/*
 * Parse a decimal "12", "0.5", ".5" (no sign, no exponent) in s[0..n).
 * Returns 1 and *out on success.
 */
static int parse_real(const char *s, size_t n, double *out)
{
	double x = 0, scale = 1;
	size_t i = 0, digits = 0;

	while (i < n && is_digit(s[i])) {
		x = x * 10 + (s[i] - '0');
		i++;
		digits++;
	}
	if (i < n && s[i] == '.') {
		i++;
		while (i < n && is_digit(s[i])) {
			scale /= 10;
			x += (s[i] - '0') * scale;
			i++;
			digits++;
		}
	}
	if (i != n || digits == 0)
		return 0;
	*out = x;
	return 1;
}

/* ---- Step 1: lines ----------------------------------------------------- */

static int push_value(wif_parser *p, uint32_t v)
{
	if (!grow((void **)&p->pool, &p->cap_pool, p->npool + 1, sizeof *p->pool))
		return perr(p, 0, LOOM_ENOMEM, "out of memory");
	p->pool[p->npool++] = v;
	return LOOM_OK;
}

/*
 * Parse the whole numbers of a list value (separated by ',' or blanks) into
 * the pool.  Zeros are dropped unless keep_zero.  *count gets how many
 * values were kept.
 */
static int parse_ints(wif_parser *p, wif_list *l, const struct list_info *li,
                      const char *v, size_t n, uint32_t line, int keep_zero,
                      uint32_t *count)
{
	size_t i = 0;
	uint32_t kept = 0;
	char b[64];

	(void)keep_zero;
	while (i < n) {
		size_t start;
		uint64_t x = 0;
		int rc;

		while (i < n && (is_blank(v[i]) || v[i] == ','))
			i++;
		if (i == n)
			break;
		start = i;
		while (i < n && !is_blank(v[i]) && v[i] != ',')
			i++;
		for (size_t k = start; k < i; k++) {
			if (!is_digit(v[k]))
				return perr(p, line, LOOM_EFORMAT,
				            "%s: expected %s numbers separated by commas, "
				            "got '%s'", li->section, li->val_what,
				            show(b, sizeof b, v + start, i - start));
			x = x * 10 + (uint64_t)(v[k] - '0');
			if (x > li->val_max)
				return perr(p, line, LOOM_ERANGE,
				            "%s: %s number %s too large (at most %u)",
				            li->section, li->val_what,
				            show(b, sizeof b, v + start, i - start),
				            li->val_max);
		}
		/* 0 means "unused" in a 1-based draft and is dropped in Step 2
		   (normalise_numbers); in a draft numbered from 0 it is a number */
		if (x == 0 && !keep_zero)
			l->has_zero_val = 1;
		if ((rc = push_value(p, (uint32_t)x)) != LOOM_OK)
			return rc;
		kept++;
		if (x > l->max_val) {
			l->max_val = (uint32_t)x;
			l->max_val_line = line;
		}
	}
	*count = kept;
	return LOOM_OK;
}

static uint32_t nonzero(const uint32_t *v, uint32_t n)
{
	uint32_t k = 0;
	for (uint32_t i = 0; i < n; i++)
		k += v[i] != 0;
	return k;
}

/* One KEY=VALUE line of a numeric table. */
static int list_line(wif_parser *p, int li_idx, const char *key, size_t kn,
                     const char *val, size_t vn, uint32_t line)
{
	const struct list_info *li = &lists[li_idx];
	wif_list *l = &p->list[li_idx];
	wif_entry e;
	uint64_t k = 0;
	char b[64];
	int rc;

	if (kn == 0)
		return perr(p, line, LOOM_EFORMAT, "%s: expected a %s number before "
		            "'='", li->section, li->key_what);
	for (size_t i = 0; i < kn; i++) {
		if (!is_digit(key[i]))
			return perr(p, line, LOOM_EFORMAT,
			            "%s: expected a %s number before '=', got '%s'",
			            li->section, li->key_what, show(b, sizeof b, key, kn));
		k = k * 10 + (uint64_t)(key[i] - '0');
		if (k > li->key_max)
			return perr(p, line, LOOM_ERANGE,
			            "%s: %s number %s too large (at most %u)", li->section,
			            li->key_what, show(b, sizeof b, key, kn), li->key_max);
	}
	if (k == 0 && !l->zero_key_line)
		l->zero_key_line = line; /* decided in Step 2 (normalise_numbers) */
	e.key = (uint32_t)k;
	e.line = line;
	e.n = 0;
	switch (li->kind) {
	case K_INTS:
		e.off = p->npool;
		rc = parse_ints(p, l, li, val, vn, line, 0, &e.n);
		if (rc)
			return rc;
		break;
	case K_ONE:
		e.off = p->npool;
		rc = parse_ints(p, l, li, val, vn, line, 0, &e.n);
		if (rc)
			return rc;
		if (e.n > 1 && nonzero(p->pool + e.off, e.n) > 1)
			return perr(p, line, LOOM_EFORMAT, "%s: expected one colour "
			            "index, got '%s'", li->section, show(b, sizeof b, val, vn));
		break;
	case K_RGB:
		e.off = p->npool;
		rc = parse_ints(p, l, li, val, vn, line, 1, &e.n);
		if (rc)
			return rc;
		if (e.n != 3)
			return perr(p, line, LOOM_EFORMAT, "%s: expected R,G,B (three "
			            "numbers), got '%s'", li->section,
			            show(b, sizeof b, val, vn));
		break;
	case K_REAL: {
		double x;
		e.off = p->nf;
		if (vn == 0)
			break; /* empty: no thickness given */
		if (!parse_real(val, vn, &x))
			return perr(p, line, LOOM_EFORMAT, "%s: expected a %s "
			            "(a number such as 0.5), got '%s'", li->section,
			            li->val_what, show(b, sizeof b, val, vn));
		if (x > WIF_MAX_THICKNESS)
			return perr(p, line, LOOM_ERANGE, "%s: %s %s too large (at most "
			            "%g)", li->section, li->val_what,
			            show(b, sizeof b, val, vn), WIF_MAX_THICKNESS);
		if (x == 0 && (li == &lists[L_WARP_SPACING] ||
		               li == &lists[L_WEFT_SPACING]))
			return perr(p, line, LOOM_ERANGE, "%s: spacing 0 (expected a "
			            "positive number)", li->section);
		if (x > 0) {
			if (!grow((void **)&p->fpool, &p->cap_f, p->nf + 1,
			          sizeof *p->fpool))
				return perr(p, line, LOOM_ENOMEM, "out of memory");
			p->fpool[p->nf++] = x;
			e.n = 1;
		}
		break;
	}
	}
	if (!grow((void **)&l->e, &l->cap, l->n + 1, sizeof *l->e))
		return perr(p, line, LOOM_ENOMEM, "out of memory");
	l->e[l->n++] = e;
	if (e.key > l->max_key) {
		l->max_key = e.key;
		l->max_key_line = line;
	}
	return LOOM_OK;
}

/* One KEY=VALUE line of a scalar section: remember the keys we use. */
static void scalar_line(wif_parser *p, int sec, const char *key, size_t kn,
                        const char *val, size_t vn, uint32_t line)
{
	char k[32];
	wif_val v = {val, vn, line}, *dst = NULL;
	int side = sec == SEC_WEFT;

	if (!normalise(key, kn, k, sizeof k))
		return;
	switch (sec) {
	case SEC_WIF:
		if (!strcmp(k, "VERSION"))
			dst = &p->version;
		break;
	case SEC_WEAVING:
		if (!strcmp(k, "SHAFTS"))
			dst = &p->shafts;
		else if (!strcmp(k, "TREADLES"))
			dst = &p->treadles;
		else if (!strcmp(k, "RISINGSHED"))
			dst = &p->rising;
		break;
	case SEC_WARP:
	case SEC_WEFT:
		if (!strcmp(k, "THREADS"))
			dst = &p->threads[side];
		else if (!strcmp(k, "COLOR"))
			dst = &p->color[side];
		else if (!strcmp(k, "THICKNESS"))
			dst = &p->thick[side];
		else if (!strcmp(k, "UNITS"))
			dst = &p->units[side];
		else if (!strcmp(k, "SPACING"))
			dst = &p->spacing[side];
		break;
	case SEC_PALETTE:
		if (!strcmp(k, "RANGE"))
			dst = &p->range;
		else if (!strcmp(k, "FORM"))
			dst = &p->form;
		break;
	default:
		break;
	}
	if (dst)
		*dst = v;
}

/* A "[...]" line: the new section (or SEC_IGNORED), or an error. */
static int section_line(wif_parser *p, const char *s, size_t n, uint32_t line,
                        int *sec)
{
	const char *close = memchr(s, ']', n);
	char norm[40], b[64];
	size_t nn;
	int all_digits = 1;

	if (!close) {
		if (*sec == SEC_NONE)
			return LOOM_OK; /* text before the first section */
		return perr(p, line, LOOM_EFORMAT,
		            "expected ']' closing the section name, got '%s'",
		            show(b, sizeof b, s, n));
	}
	nn = (size_t)(close - s) - 1;
	for (size_t i = 1; i <= nn; i++)
		if (!is_digit(s[i]) && !is_blank(s[i]))
			all_digits = 0;
	if (all_digits) {
		/* "[8]Border" section labels some programs leave in a table */
		pwarn(p, line, "'%s' is not a section name; line ignored",
		      show(b, sizeof b, s, n));
		return LOOM_OK;
	}
	*sec = SEC_IGNORED;
	if (!normalise(s + 1, nn, norm, sizeof norm))
		return LOOM_OK;
	for (size_t i = 0; i < sizeof scalar_sections / sizeof *scalar_sections; i++)
		if (!strcmp(norm, scalar_sections[i].norm))
			*sec = scalar_sections[i].sec;
	if (*sec == SEC_WEAVING && !p->weaving_line)
		p->weaving_line = line;
	for (int i = 0; i < L_COUNT; i++) {
		if (!strcmp(norm, lists[i].norm)) {
			*sec = SEC_LIST + i;
			if (!p->list[i].header_line)
				p->list[i].header_line = line;
		}
	}
	return LOOM_OK;
}

static int parse_line(wif_parser *p, const char *s, size_t n, uint32_t line,
                      int *sec)
{
	const char *eq, *key, *val;
	size_t kn, vn;
	char b[64];

	trim(&s, &n);
	if (n == 0 || s[0] == ';')
		return LOOM_OK;
	if (s[0] == '[')
		return section_line(p, s, n, line, sec);
	if (*sec == SEC_NONE || *sec == SEC_IGNORED)
		return LOOM_OK;
	eq = memchr(s, '=', n);
	if (!eq) {
		if (*sec >= SEC_LIST) {
			pwarn(p, line, "%s: expected NUMBER=VALUES, got '%s'; line ignored",
			      lists[*sec - SEC_LIST].section, show(b, sizeof b, s, n));
			return LOOM_OK;
		}
		pwarn(p, line, "expected KEY=VALUE, got '%s'; line ignored",
		      show(b, sizeof b, s, n));
		return LOOM_OK;
	}
	key = s;
	kn = (size_t)(eq - s);
	val = eq + 1;
	vn = n - kn - 1;
	{ /* inline comment */
		const char *semi = memchr(val, ';', vn);
		if (semi)
			vn = (size_t)(semi - val);
	}
	trim(&key, &kn);
	trim(&val, &vn);
	if (*sec >= SEC_LIST)
		return list_line(p, *sec - SEC_LIST, key, kn, val, vn, line);
	scalar_line(p, *sec, key, kn, val, vn, line);
	return LOOM_OK;
}

/* Step 1: split into lines (LF, CRLF or CR) and parse each. */
static int parse_text(wif_parser *p, const char *t, size_t len)
{
	size_t i = 0;
	uint32_t line = 0;
	int sec = SEC_NONE, rc;

	if (len >= 3 && memcmp(t, "\xEF\xBB\xBF", 3) == 0)
		i = 3; /* UTF-8 byte order mark */
	while (i < len) {
		size_t b = i;
		while (i < len && t[i] != '\n' && t[i] != '\r')
			i++;
		if (line == UINT32_MAX - 1)
			return perr(p, line, LOOM_ERANGE, "too many lines");
		line++;
		rc = parse_line(p, t + b, i - b, line, &sec);
		if (rc)
			return rc;
		if (i < len) {
			if (t[i] == '\r' && i + 1 < len && t[i + 1] == '\n')
				i++;
			i++;
		}
	}
	p->last_line = line ? line : 1;
	return LOOM_OK;
}

/* ---- Step 2: the drawdown ---------------------------------------------- */

/*
 * Index the entries of a list by key, keys 1..size (larger keys are left
 * out); the last duplicate wins, with one warning.  idx[k-1] = entry index
 * or -1.  Returns LOOM_OK or LOOM_ENOMEM.
 */
static int index_list(wif_parser *p, int li_idx, uint32_t size, int32_t **out)
{
	wif_list *l = &p->list[li_idx];
	int32_t *idx;
	int warned = 0;

	*out = NULL;
	idx = malloc((size ? size : 1) * sizeof *idx);
	if (!idx)
		return perr(p, l->header_line, LOOM_ENOMEM, "out of memory");
	memset(idx, 0xff, (size ? size : 1) * sizeof *idx);
	for (size_t k = 0; k < l->n; k++) {
		uint32_t key = l->e[k].key;
		if (key > size)
			continue;
		if (idx[key - 1] >= 0 && !warned) {
			pwarn(p, l->e[k].line, "%s: %s %u given again; the last entry "
			      "wins", lists[li_idx].section, lists[li_idx].key_what, key);
			warned = 1;
		}
		idx[key - 1] = (int32_t)k;
	}
	*out = idx;
	return LOOM_OK;
}

/*
 * Step 2a: what the numbers count from.  WIF numbers ends, picks,
 * treadles, shafts and colours from 1, and a value 0 means "unused".  A
 * file whose threading and picks both have an entry numbered 0 was
 * written counting from 0 (generated files do): then every end and pick
 * number, and the treadle, shaft and colour numbers of the tables that
 * use 0, is read one higher, with one warning saying so.  Otherwise an
 * entry numbered 0 is ignored (a warning per table) and values 0 are
 * dropped.  Highest keys and values are counted afresh.
 */
static void shift_keys(wif_list *l)
{
	for (size_t k = 0; k < l->n; k++)
		l->e[k].key++;
	l->zero_key_line = 0;
}

static void shift_vals(wif_parser *p, wif_list *l)
{
	for (size_t k = 0; k < l->n; k++)
		for (uint32_t v = 0; v < l->e[k].n; v++)
			p->pool[l->e[k].off + v]++;
	l->has_zero_val = 0;
}

static int normalise_numbers(wif_parser *p)
{
	wif_list *L = p->list;
	int picks = L[L_LIFTPLAN].n > 0 ? L_LIFTPLAN : L_TREADLING;
	char what[96] = "ends, picks";
	uint32_t end0 = L[L_THREADING].zero_key_line, pick0 = L[picks].zero_key_line;

	if (end0 && pick0) {
		static const int ends_picks[] = {L_THREADING, L_TREADLING, L_LIFTPLAN,
		                                 L_WARP_COLORS, L_WEFT_COLORS, L_WARP_THICK,
		                                 L_WEFT_THICK};
		for (size_t k = 0; k < sizeof ends_picks / sizeof *ends_picks; k++)
			shift_keys(&L[ends_picks[k]]);
		if (L[L_TIEUP].zero_key_line) {
			shift_keys(&L[L_TIEUP]);
			shift_vals(p, &L[L_TREADLING]);
			strcat(what, ", treadles");
		}
		if (L[L_THREADING].has_zero_val) {
			shift_vals(p, &L[L_THREADING]);
			shift_vals(p, &L[L_TIEUP]);
			shift_vals(p, &L[L_LIFTPLAN]);
			strcat(what, ", shafts");
		}
		if (L[L_COLOR_TABLE].zero_key_line) {
			shift_keys(&L[L_COLOR_TABLE]);
			shift_vals(p, &L[L_WARP_COLORS]);
			shift_vals(p, &L[L_WEFT_COLORS]);
			p->color_shift = 1;
			strcat(what, ", colours");
		}
		pwarn(p, end0, "the draft numbers from 0 (end 0 here, pick 0 on line %u), "
		      "WIF from 1: reading every number one higher (%s)", pick0, what);
	}
	for (int li = 0; li < L_COUNT; li++) {
		wif_list *l = &L[li];
		size_t m = 0;
		if (l->zero_key_line)
			pwarn(p, l->zero_key_line, "%s: %s 0 ignored (WIF numbers %ss from 1)",
			      lists[li].section, lists[li].key_what, lists[li].key_what);
		l->max_key = l->max_val = 0;
		l->max_key_line = l->max_val_line = 0;
		for (size_t k = 0; k < l->n; k++) {
			wif_entry e = l->e[k];
			if (e.key == 0)
				continue;
			if (lists[li].kind == K_INTS || lists[li].kind == K_ONE) {
				uint32_t *v = p->pool + e.off, kept = 0;
				for (uint32_t q = 0; q < e.n; q++)
					if (v[q] != 0)
						v[kept++] = v[q];
				e.n = kept;
			}
			if (lists[li].kind != K_REAL)
				for (uint32_t q = 0; q < e.n; q++)
					if (p->pool[e.off + q] > l->max_val) {
						l->max_val = p->pool[e.off + q];
						l->max_val_line = e.line;
					}
			if (e.key > l->max_key) {
				l->max_key = e.key;
				l->max_key_line = e.line;
			}
			l->e[m++] = e;
		}
		l->n = m;
	}
	/* Every number was checked against its limit as written, so only a
	   draft read one higher gets here: its largest allowed number, written,
	   is one above the limit now. */
	for (int li = 0; li < L_COUNT; li++) {
		const wif_list *l = &L[li];
		int vals = lists[li].kind == K_INTS || lists[li].kind == K_ONE;
		if (l->max_key > lists[li].key_max)
			return perr(p, l->max_key_line, LOOM_ERANGE, "%s: %s number %u (%u "
			            "as written, the draft counting from 0) too large (at "
			            "most %u)", lists[li].section, lists[li].key_what,
			            l->max_key, l->max_key - 1, lists[li].key_max);
		if (vals && l->max_val > lists[li].val_max)
			return perr(p, l->max_val_line, LOOM_ERANGE, "%s: %s %u (%u as "
			            "written, the draft counting from 0) too large (at most "
			            "%u)", lists[li].section, lists[li].val_what, l->max_val,
			            l->max_val - 1, lists[li].val_max);
	}
	return LOOM_OK;
}

/* WIF booleans: true/yes/on/1 and false/no/off/0 (any case). */
static int parse_bool(const wif_val *v, int *out)
{
	static const char *const yes[] = {"true", "yes", "on", "1", "y", "t"};
	static const char *const no[] = {"false", "no", "off", "0", "n", "f"};

	for (size_t i = 0; i < sizeof yes / sizeof *yes; i++) {
		if (val_is(v, yes[i])) {
			*out = 1;
			return 1;
		}
		if (val_is(v, no[i])) {
			*out = 0;
			return 1;
		}
	}
	return 0;
}

typedef struct wif_build { /* everything Step 2 allocates */
	int32_t *end_e;       /* [cols] THREADING entry per end, -1 none */
	int32_t *pick_e;      /* [rows] LIFTPLAN or TREADLING entry per pick */
	int32_t *tie_e;       /* [treadles] TIEUP entry per treadle */
	uint32_t *cidx;       /* [max shaft + 1] dense shaft index, or NONE */
	uint32_t *end_bit;    /* [cols] dense index of the end's first shaft */
	uint32_t *extra;      /* pairs (end, dense index) of further shafts */
	size_t n_extra, cap_extra;
	uint64_t *tie;        /* [treadles x words] tieup bitsets */
	uint64_t *lift;       /* [words] */
	uint32_t *memo;       /* [WIF_MEMO_SLOTS x 2] (entry + 1, row) */
	int32_t *thr_e[2], *col_e[2]; /* thickness and colour entries */
	int32_t *ct_e;        /* COLOR TABLE entry per index */
	uint8_t *type_of[2];  /* [cols] / [rows] yarn type per end / pick */
} wif_build;

static void build_free(wif_build *b)
{
	free(b->end_e);
	free(b->pick_e);
	free(b->tie_e);
	free(b->cidx);
	free(b->end_bit);
	free(b->extra);
	free(b->tie);
	free(b->lift);
	free(b->memo);
	for (int s = 0; s < 2; s++) {
		free(b->thr_e[s]);
		free(b->col_e[s]);
		free(b->type_of[s]);
	}
	free(b->ct_e);
}

#define NONE32 0xffffffffu

/* Warn once if a list's values (or keys) exceed a declared count. */
static void check_declared(wif_parser *p, int li_idx, int keys,
                           uint32_t declared, const char *decl_name)
{
	const wif_list *l = &p->list[li_idx];
	uint32_t m = keys ? l->max_key : l->max_val;
	uint32_t line = keys ? l->max_key_line : l->max_val_line;

	if (m > declared)
		pwarn(p, line, "%s: %s %u is above [WEAVING] %s=%u", lists[li_idx].section,
		      keys ? lists[li_idx].key_what : lists[li_idx].val_what, m,
		      decl_name, declared);
}

static uint64_t hash_values(const uint32_t *v, uint32_t n)
{
	uint64_t h = 0x9e3779b97f4a7c15ull ^ n;
	for (uint32_t i = 0; i < n; i++) {
		h ^= v[i];
		h *= 0xbf58476d1ce4e5b9ull;
		h ^= h >> 31;
	}
	return h;
}

/* A treadle pressed on some pick but with no [TIEUP] line lifts no shaft:
   say so, once per treadle (the first few), with the first pick using it. */
static void untied_treadles(wif_parser *p, const wif_build *b, uint32_t rows,
                            uint32_t ntr)
{
	const wif_list *tr = &p->list[L_TREADLING];
	uint8_t seen[WIF_MAX_TREADLES + 1]; /* normalise_numbers keeps t in range */
	uint32_t warned = 0;

	memset(seen, 0, sizeof seen);
	for (uint32_t i = 0; i < rows && warned < 8; i++) {
		const wif_entry *e = b->pick_e[i] >= 0 ? &tr->e[b->pick_e[i]] : NULL;
		for (uint32_t k = 0; e && k < e->n && warned < 8; k++) {
			uint32_t t = p->pool[e->off + k];
			if ((t <= ntr && b->tie_e[t - 1] >= 0) || seen[t])
				continue;
			seen[t] = 1;
			pwarn(p, e->line, "[TREADLING]: treadle %u (first pressed on pick %u) "
			      "has no [TIEUP] line, so it lifts no shaft: on its picks only the "
			      "other treadles' shafts rise%s", t, i + 1,
			      ++warned == 8 ? " (further untied treadles not listed)" : "");
		}
	}
}

/* Drawdown rows into d->weave.  b->end_e and b->pick_e are indexed. */
static int drawdown(wif_parser *p, wif_build *b, loom_design *d, int use_lift,
                    int rising)
{
	const wif_list *th = &p->list[L_THREADING];
	const wif_list *pk = &p->list[use_lift ? L_LIFTPLAN : L_TREADLING];
	const wif_list *tu = &p->list[L_TIEUP];
	uint32_t rows = d->rows, cols = d->cols, max_sh = th->max_val;
	uint32_t nb = 0, zero_bit, words, ntr = 0;

	/* dense shaft numbers: only shafts that carry an end */
	b->cidx = malloc(((size_t)max_sh + 1) * sizeof *b->cidx);
	b->end_bit = malloc((size_t)cols * sizeof *b->end_bit);
	if (!b->cidx || !b->end_bit)
		return perr(p, 0, LOOM_ENOMEM, "out of memory");
	memset(b->cidx, 0xff, ((size_t)max_sh + 1) * sizeof *b->cidx);
	for (uint32_t j = 0; j < cols; j++) {
		const wif_entry *e;
		if (b->end_e[j] < 0)
			continue;
		e = &th->e[b->end_e[j]];
		for (uint32_t k = 0; k < e->n; k++) {
			uint32_t s = p->pool[e->off + k];
			if (b->cidx[s] == NONE32)
				b->cidx[s] = nb++;
		}
	}
	zero_bit = nb; /* never set: unthreaded ends */
	words = nb / 64 + 1;
	for (uint32_t j = 0; j < cols; j++) {
		const wif_entry *e;
		b->end_bit[j] = zero_bit;
		if (b->end_e[j] < 0)
			continue;
		e = &th->e[b->end_e[j]];
		for (uint32_t k = 0; k < e->n; k++) {
			uint32_t c = b->cidx[p->pool[e->off + k]];
			if (k == 0) {
				b->end_bit[j] = c;
				continue;
			}
			if (!grow((void **)&b->extra, &b->cap_extra, b->n_extra + 2,
			          sizeof *b->extra))
				return perr(p, 0, LOOM_ENOMEM, "out of memory");
			b->extra[b->n_extra++] = j;
			b->extra[b->n_extra++] = c;
		}
	}
	b->lift = malloc((size_t)words * sizeof *b->lift);
	b->memo = calloc((size_t)WIF_MEMO_SLOTS * 2, sizeof *b->memo);
	if (!b->lift || !b->memo)
		return perr(p, 0, LOOM_ENOMEM, "out of memory");

	/* tieup bitsets, one per treadle */
	if (!use_lift) {
		ntr = tu->max_key;
		b->tie = calloc((size_t)ntr * words, sizeof *b->tie);
		if (!b->tie || index_list(p, L_TIEUP, ntr, &b->tie_e))
			return perr(p, 0, LOOM_ENOMEM, "out of memory");
		for (uint32_t t = 0; t < ntr; t++) {
			const wif_entry *e;
			if (b->tie_e[t] < 0)
				continue;
			e = &tu->e[b->tie_e[t]];
			for (uint32_t k = 0; k < e->n; k++) {
				uint32_t s = p->pool[e->off + k];
				uint32_t c = s <= max_sh ? b->cidx[s] : NONE32;
				if (c != NONE32)
					b->tie[(size_t)t * words + c / 64] |= 1ull << (c % 64);
			}
		}
		untied_treadles(p, b, rows, ntr);
	}

	for (uint32_t i = 0; i < rows; i++) {
		uint8_t *row = d->weave + (size_t)i * cols;
		const wif_entry *e = b->pick_e[i] >= 0 ? &pk->e[b->pick_e[i]] : NULL;
		const uint32_t *v = e ? p->pool + e->off : NULL;
		uint32_t n = e ? e->n : 0;

		/* Picks with the same value list have the same row. */
		if (e) {
			uint32_t slot = (uint32_t)(hash_values(v, n) & (WIF_MEMO_SLOTS - 1));
			uint32_t m = b->memo[2 * slot];
			if (m) {
				const wif_entry *o = &pk->e[m - 1];
				if (o->n == n && !memcmp(p->pool + o->off, v, n * sizeof *v)) {
					memcpy(row, d->weave + (size_t)b->memo[2 * slot + 1] * cols,
					       cols);
					continue;
				}
			}
			b->memo[2 * slot] = (uint32_t)b->pick_e[i] + 1;
			b->memo[2 * slot + 1] = i;
		}
		memset(b->lift, 0, (size_t)words * sizeof *b->lift);
		for (uint32_t k = 0; k < n; k++) {
			if (use_lift) {
				uint32_t c = v[k] <= max_sh ? b->cidx[v[k]] : NONE32;
				if (c != NONE32)
					b->lift[c / 64] |= 1ull << (c % 64);
			} else if (v[k] <= ntr) {
				const uint64_t *t = b->tie + (size_t)(v[k] - 1) * words;
				for (uint32_t w = 0; w < words; w++)
					b->lift[w] |= t[w];
			}
		}
		for (uint32_t j = 0; j < cols; j++) {
			uint32_t c = b->end_bit[j];
			row[j] = (uint8_t)((b->lift[c >> 6] >> (c & 63)) & 1);
		}
		for (size_t k = 0; k < b->n_extra; k += 2) {
			uint32_t c = b->extra[k + 1];
			row[b->extra[k]] |= (uint8_t)((b->lift[c >> 6] >> (c & 63)) & 1);
		}
		if (!rising)
			for (uint32_t j = 0; j < cols; j++)
				row[j] ^= 1;
	}
	return LOOM_OK;
}

/* ---- yarn types -------------------------------------------------------- */

typedef struct wif_ykey {
	int side;          /* 0 warp, 1 weft */
	int has_color;
	uint16_t rgb[3];   /* normalised colour, 0..65535 */
	double mm;         /* thickness in millimetres; 0 = not given */
} wif_ykey;

typedef struct wif_types {
	wif_ykey key[LOOM_MAX_YARN_TYPES];
	uint32_t n;
	int16_t slot[1024]; /* hash table of type ids, -1 empty */
} wif_types;

static uint32_t ykey_hash(const wif_ykey *k)
{
	uint64_t h = (uint64_t)k->side * 3 + (uint64_t)k->has_color;
	uint64_t t;
	memcpy(&t, &k->mm, sizeof t);
	h = h * 0x100000001b3ull ^ k->rgb[0];
	h = h * 0x100000001b3ull ^ k->rgb[1];
	h = h * 0x100000001b3ull ^ k->rgb[2];
	h = (h ^ t) * 0xbf58476d1ce4e5b9ull;
	return (uint32_t)(h >> 40) & 1023u;
}

static int ykey_eq(const wif_ykey *a, const wif_ykey *b)
{
	return a->side == b->side && a->has_color == b->has_color &&
	       a->rgb[0] == b->rgb[0] && a->rgb[1] == b->rgb[1] &&
	       a->rgb[2] == b->rgb[2] && a->mm == b->mm;
}

/* Type id of a key, adding it if new; -1 when the table is full. */
static int type_id(wif_types *t, const wif_ykey *k)
{
	uint32_t s = ykey_hash(k);

	for (;;) {
		int16_t id = t->slot[s];
		if (id < 0)
			break;
		if (ykey_eq(&t->key[id], k))
			return id;
		s = (s + 1) & 1023u;
	}
	if (t->n >= LOOM_MAX_YARN_TYPES)
		return -1;
	t->key[t->n] = *k;
	t->slot[s] = (int16_t)t->n;
	return (int)t->n++;
}

typedef struct wif_palette {
	double lo, hi;
	int clamp_warned;
} wif_palette;

/* The [COLOR PALETTE] Range, or a guess from the table's values. */
static int palette_range(wif_parser *p, wif_palette *pal)
{
	const wif_list *ct = &p->list[L_COLOR_TABLE];
	char b[64];

	pal->lo = 0;
	pal->hi = 255;
	pal->clamp_warned = 0;
	if (p->form.s && p->form.n && !val_is(&p->form, "RGB"))
		pwarn(p, p->form.line, "[COLOR PALETTE] Form=%s not understood; "
		      "reading colours as RGB", show(b, sizeof b, p->form.s, p->form.n));
	if (p->range.s && p->range.n) {
		uint32_t v[2] = {0, 0}, nv = 0;
		size_t i = 0, n = p->range.n;
		const char *s = p->range.s;
		while (i < n) {
			uint64_t x = 0;
			size_t start;
			while (i < n && (is_blank(s[i]) || s[i] == ','))
				i++;
			if (i == n)
				break;
			start = i;
			while (i < n && is_digit(s[i]) && x <= WIF_MAX_COMPONENT)
				x = x * 10 + (uint64_t)(s[i++] - '0');
			if (i == start || x > WIF_MAX_COMPONENT || nv == 2 ||
			    (i < n && !is_blank(s[i]) && s[i] != ','))
				return perr(p, p->range.line, LOOM_EFORMAT,
				            "[COLOR PALETTE]: expected Range=LOW,HIGH (whole "
				            "numbers up to %u), got '%s'", WIF_MAX_COMPONENT,
				            show(b, sizeof b, s, n));
			v[nv++] = (uint32_t)x;
		}
		if (nv == 1) { /* "Range=255" */
			v[1] = v[0];
			v[0] = 0;
		}
		if (nv == 0 || v[1] <= v[0])
			return perr(p, p->range.line, LOOM_EFORMAT,
			            "[COLOR PALETTE]: expected Range=LOW,HIGH with LOW < "
			            "HIGH, got '%s'", show(b, sizeof b, s, n));
		pal->lo = v[0];
		pal->hi = v[1];
		return LOOM_OK;
	}
	if (ct->n && ct->max_val > 255) {
		pal->hi = ct->max_val <= 999 ? 999 : ct->max_val <= 65535 ? 65535
		                                                          : ct->max_val;
		pwarn(p, ct->max_val_line, "[COLOR TABLE] has values up to %u but no "
		      "[COLOR PALETTE] Range; assuming Range=0,%.0f", ct->max_val,
		      pal->hi);
	}
	return LOOM_OK;
}

static uint16_t norm16(wif_parser *p, wif_palette *pal, uint32_t v,
                       uint32_t line)
{
	double x = ((double)v - pal->lo) / (pal->hi - pal->lo);

	if (x < 0 || x > 1) {
		if (!pal->clamp_warned)
			pwarn(p, line, "colour value %u outside [COLOR PALETTE] Range "
			      "%.0f..%.0f; clamped", v, pal->lo, pal->hi);
		pal->clamp_warned = 1;
		x = x < 0 ? 0 : 1;
	}
	return (uint16_t)lrint(x * 65535.0);
}

/* Colour of table index c into k (returns 0 if the table lacks it). */
static int table_color(wif_parser *p, wif_build *b, wif_palette *pal,
                       uint32_t c, wif_ykey *k)
{
	const wif_list *ct = &p->list[L_COLOR_TABLE];
	const wif_entry *e;

	if (c == 0 || c > ct->max_key || b->ct_e[c - 1] < 0)
		return 0;
	e = &ct->e[b->ct_e[c - 1]];
	for (int q = 0; q < 3; q++)
		k->rgb[q] = norm16(p, pal, p->pool[e->off + q], e->line);
	k->has_color = 1;
	return 1;
}

static int bad_color(wif_parser *p, uint32_t line, uint32_t c)
{
	const wif_list *ct = &p->list[L_COLOR_TABLE];

	if (ct->n == 0)
		return perr(p, line, LOOM_EFORMAT, "colour index %u is beyond the "
		            "colour table: there is no [COLOR TABLE]", c);
	return perr(p, line, LOOM_EFORMAT, "colour index %u is beyond the colour "
	            "table: [COLOR TABLE] defines no colour %u (highest %u)", c, c,
	            ct->max_key);
}

/* Millimetres per unit of [WARP]/[WEFT] Units; 0 = unknown unit. */
static double unit_mm(const wif_val *u)
{
	static const struct { const char *name; double mm; } units[] = {
		{"decipoints", 25.4 / 720}, {"decipoint", 25.4 / 720},
		{"inches", 25.4}, {"inch", 25.4}, {"in", 25.4},
		{"centimeters", 10}, {"centimetres", 10}, {"centimeter", 10},
		{"centimetre", 10}, {"cm", 10},
		{"millimeters", 1}, {"millimetres", 1}, {"millimeter", 1},
		{"millimetre", 1}, {"mm", 1},
	};

	if (!u->s || u->n == 0)
		return 25.4 / 720; /* WIF's default unit */
	for (size_t i = 0; i < sizeof units / sizeof *units; i++)
		if (val_is(u, units[i].name))
			return units[i].mm;
	return 0;
}

/* Yarn types of the ends (side 0) or picks (side 1) into b->type_of[side]. */
static int side_types(wif_parser *p, wif_build *b, wif_palette *pal,
                      wif_types *t, int side, uint32_t count)
{
	static const char *const what[2] = {"[WARP]", "[WEFT]"};
	const int col_l = side ? L_WEFT_COLORS : L_WARP_COLORS;
	const int thr_l = side ? L_WEFT_THICK : L_WARP_THICK;
	const wif_list *cl = &p->list[col_l], *tl = &p->list[thr_l];
	wif_ykey def = {0};
	double umm = unit_mm(&p->units[side]), fac = umm > 0 ? umm : 1;
	int rc, used_thick = 0;
	char bb[64];

	def.side = side;
	/* default colour: "index" or "index,r,g,b" */
	if (p->color[side].s && p->color[side].n) {
		const wif_val *v = &p->color[side];
		uint32_t c[4] = {0}, nc = 0;
		size_t i = 0;
		while (i < v->n) {
			uint64_t x = 0;
			size_t start;
			while (i < v->n && (is_blank(v->s[i]) || v->s[i] == ','))
				i++;
			if (i == v->n)
				break;
			start = i;
			while (i < v->n && is_digit(v->s[i]) && x <= WIF_MAX_COMPONENT)
				x = x * 10 + (uint64_t)(v->s[i++] - '0');
			if (i == start || x > WIF_MAX_COMPONENT || nc == 4 ||
			    (i < v->n && !is_blank(v->s[i]) && v->s[i] != ','))
				return perr(p, v->line, LOOM_EFORMAT, "%s: expected Color=INDEX "
				            "or Color=INDEX,R,G,B, got '%s'", what[side],
				            show(bb, sizeof bb, v->s, v->n));
			c[nc++] = (uint32_t)x;
		}
		if (nc != 1 && nc != 4)
			return perr(p, v->line, LOOM_EFORMAT, "%s: expected Color=INDEX or "
			            "Color=INDEX,R,G,B, got '%s'", what[side],
			            show(bb, sizeof bb, v->s, v->n));
		if (p->color_shift)
			c[0]++;
		if (c[0] != 0 && !table_color(p, b, pal, c[0], &def)) {
			if (nc != 4)
				return bad_color(p, v->line, c[0]);
			for (int q = 0; q < 3; q++)
				def.rgb[q] = norm16(p, pal, c[q + 1], v->line);
			def.has_color = 1;
		}
	}
	/* default thickness */
	if (p->thick[side].s && p->thick[side].n) {
		const wif_val *v = &p->thick[side];
		double x;
		if (!parse_real(v->s, v->n, &x) || x > WIF_MAX_THICKNESS)
			return perr(p, v->line, LOOM_EFORMAT, "%s: expected Thickness=NUMBER "
			            "such as 0.5, got '%s'", what[side],
			            show(bb, sizeof bb, v->s, v->n));
		def.mm = x * fac;
	}
	if ((rc = index_list(p, col_l, count, &b->col_e[side])) ||
	    (rc = index_list(p, thr_l, count, &b->thr_e[side])))
		return rc;
	if (cl->max_key > count)
		pwarn(p, cl->max_key_line, "%s has entries beyond the last %s (%u); "
		      "ignored", lists[col_l].section, lists[col_l].key_what, count);
	if (tl->max_key > count)
		pwarn(p, tl->max_key_line, "%s has entries beyond the last %s (%u); "
		      "ignored", lists[thr_l].section, lists[thr_l].key_what, count);
	b->type_of[side] = malloc(count);
	if (!b->type_of[side])
		return perr(p, 0, LOOM_ENOMEM, "out of memory");
	for (uint32_t j = 0; j < count; j++) {
		wif_ykey k = def;
		uint32_t line = 0;
		int id;
		if (b->col_e[side][j] >= 0) {
			const wif_entry *e = &cl->e[b->col_e[side][j]];
			line = e->line;
			if (e->n == 1 && !table_color(p, b, pal, p->pool[e->off], &k))
				return bad_color(p, e->line, p->pool[e->off]);
		}
		if (b->thr_e[side][j] >= 0) {
			const wif_entry *e = &tl->e[b->thr_e[side][j]];
			if (e->n == 1)
				k.mm = p->fpool[e->off] * fac;
			if (!line)
				line = e->line;
		}
		if (k.mm > 0)
			used_thick = 1;
		id = type_id(t, &k);
		if (id < 0)
			return perr(p, line ? line : p->last_line, LOOM_ERANGE,
			            "more than %d distinct yarns (warp and weft colour x "
			            "thickness); loom's yarn table holds %d",
			            LOOM_MAX_YARN_TYPES, LOOM_MAX_YARN_TYPES);
		b->type_of[side][j] = (uint8_t)id;
	}
	if (used_thick && umm == 0)
		pwarn(p, p->units[side].line, "%s Units=%s not understood; reading "
		      "thicknesses as millimetres", what[side],
		      show(bb, sizeof bb, p->units[side].s, p->units[side].n));
	return LOOM_OK;
}

/*
 * Sett and yarn size of the ends (side 0) or picks (side 1): the mean of the
 * per-thread [WARP SPACING] / [WEFT SPACING] and thickness entries, threads
 * without one taking [WARP]/[WEFT] Spacing and Thickness, converted by the
 * side's Units into d->sett[side] (threads per cm) and d->yarn_um[side].
 * Nothing stated leaves them 0.  A spacing in a unit loom cannot convert is
 * an error (the geometry would be wrong by an unknown factor); an odd sett
 * or a yarn much thicker than its spacing is a warning.
 */
static int side_sett(wif_parser *p, wif_build *b, loom_design *d, int side,
                     uint32_t count)
{
	static const char *const what[2] = {"[WARP]", "[WEFT]"};
	static const char *const thread[2] = {"ends", "picks"};
	const int spc_l = side ? L_WEFT_SPACING : L_WARP_SPACING;
	const wif_list *sl = &p->list[spc_l];
	const wif_list *tl = &p->list[side ? L_WEFT_THICK : L_WARP_THICK];
	double umm = unit_mm(&p->units[side]);
	double def_s = 0, def_t = 0, sum_s = 0, sum_t = 0;
	uint32_t n_s = 0, n_t = 0, line_s = sl->header_line;
	int32_t *se = NULL;
	char bb[64];
	int rc;

	if (p->spacing[side].s && p->spacing[side].n) {
		const wif_val *v = &p->spacing[side];
		if (!parse_real(v->s, v->n, &def_s) || def_s > WIF_MAX_THICKNESS)
			return perr(p, v->line, LOOM_EFORMAT, "%s: expected Spacing=NUMBER "
			            "(positive, at most %g), such as 0.05, got '%s'",
			            what[side], WIF_MAX_THICKNESS,
			            show(bb, sizeof bb, v->s, v->n));
		if (def_s <= 0)
			return perr(p, v->line, LOOM_ERANGE, "%s: Spacing=%s (expected a "
			            "positive number)", what[side],
			            show(bb, sizeof bb, v->s, v->n));
		line_s = v->line;
	}
	if (p->thick[side].s && p->thick[side].n)
		parse_real(p->thick[side].s, p->thick[side].n, &def_t); /* checked */
	if ((rc = index_list(p, spc_l, count, &se)))
		return rc;
	for (uint32_t j = 0; j < count; j++) {
		double sp = def_s, th = def_t;
		if (se[j] >= 0 && sl->e[se[j]].n == 1)
			sp = p->fpool[sl->e[se[j]].off];
		if (b->thr_e[side][j] >= 0 && tl->e[b->thr_e[side][j]].n == 1)
			th = p->fpool[tl->e[b->thr_e[side][j]].off];
		if (sp > 0) {
			sum_s += sp;
			n_s++;
		}
		if (th > 0) {
			sum_t += th;
			n_t++;
		}
	}
	free(se);
	if (n_s && umm == 0)
		return perr(p, p->units[side].line ? p->units[side].line : line_s,
		            LOOM_EFORMAT, "%s: Units=%s is not a WIF unit (expected "
		            "Decipoints, Inches or Centimeters; loom also reads "
		            "Millimeters), so the spacing cannot be read", what[side],
		            show(bb, sizeof bb, p->units[side].s, p->units[side].n));
	if (n_s) {
		double mm = sum_s / n_s * umm;
		d->sett[side] = (float)(10.0 / mm);
		if (mm < 0.02 || mm > 20)
			pwarn(p, line_s, "%s: a spacing of %.3g mm (%.3g %s per cm) is not a "
			      "usual sett (0.02..20 mm)", what[side], mm,
			      (double)d->sett[side], thread[side]);
	}
	if (n_t) {
		double mm = sum_t / n_t * (umm > 0 ? umm : 1);
		double sp = n_s ? sum_s / n_s * umm : 0;
		if (sp > 0 && mm > 4 * sp)
			pwarn(p, p->thick[side].line ? p->thick[side].line : tl->header_line,
			      "%s: yarns %.3g mm thick at a spacing of %.3g mm cannot lie "
			      "side by side; the thickness is not used for the geometry",
			      what[side], mm, sp);
		else
			d->yarn_um[side] = (float)(1000.0 * mm);
	}
	return LOOM_OK;
}

/* Fill the design's yarn table and type maps. */
static int yarn_types(wif_parser *p, wif_build *b, loom_design *d)
{
	static const float def_albedo[2][3] = {{0.85f, 0.85f, 0.82f},
	                                       {0.20f, 0.28f, 0.55f}};
	static const char *const side_name[2] = {"warp", "weft"};
	wif_palette pal;
	wif_types *t;
	double max_mm = 0;
	const wif_list *ct = &p->list[L_COLOR_TABLE];
	int rc;

	if ((rc = palette_range(p, &pal)))
		return rc;
	if ((rc = index_list(p, L_COLOR_TABLE, ct->max_key, &b->ct_e)))
		return rc;
	t = malloc(sizeof *t);
	if (!t)
		return perr(p, 0, LOOM_ENOMEM, "out of memory");
	t->n = 0;
	memset(t->slot, 0xff, sizeof t->slot);
	if ((rc = side_types(p, b, &pal, t, 0, d->cols)) ||
	    (rc = side_types(p, b, &pal, t, 1, d->rows))) {
		free(t);
		return rc;
	}
	if (loom_design_set_types(d, t->n) != LOOM_OK) {
		free(t);
		return perr(p, 0, LOOM_ENOMEM, "out of memory");
	}
	for (uint32_t k = 0; k < t->n; k++)
		if (t->key[k].mm > max_mm)
			max_mm = t->key[k].mm;
	for (uint32_t k = 0; k < t->n; k++) {
		const wif_ykey *y = &t->key[k];
		loom_yarn_type *ty = &d->types[k];
		int w;
		memset(ty, 0, sizeof *ty);
		if (y->has_color) {
			for (int q = 0; q < 3; q++)
				ty->albedo[q] = loom__srgb_to_linear(y->rgb[q] / 65535.0);
			w = snprintf(ty->name, sizeof ty->name, "%s #%02x%02x%02x",
			             side_name[y->side], (unsigned)lrint(y->rgb[0] / 257.0),
			             (unsigned)lrint(y->rgb[1] / 257.0),
			             (unsigned)lrint(y->rgb[2] / 257.0));
		} else {
			memcpy(ty->albedo, def_albedo[y->side], sizeof ty->albedo);
			w = snprintf(ty->name, sizeof ty->name, "%s", side_name[y->side]);
		}
		if (y->mm > 0 && w > 0 && (size_t)w < sizeof ty->name)
			snprintf(ty->name + w, sizeof ty->name - (size_t)w, " %.3gmm", y->mm);
		ty->alignment = 0.3f;
		ty->thickness = y->mm > 0 ? (float)(y->mm / max_mm) : 0.0f;
	}
	free(t);
	for (uint32_t i = 0; i < d->rows; i++) {
		memcpy(d->warp_type + (size_t)i * d->cols, b->type_of[0], d->cols);
		memset(d->weft_type + (size_t)i * d->cols, b->type_of[1][i], d->cols);
	}
	return LOOM_OK;
}

/* Step 2: checks, sizes, drawdown and yarn types. */
static int build(wif_parser *p, loom_design **out)
{
	wif_list *th = &p->list[L_THREADING], *tu = &p->list[L_TIEUP];
	wif_list *tr = &p->list[L_TREADLING], *lp = &p->list[L_LIFTPLAN];
	wif_build b;
	loom_design *d = NULL;
	uint32_t rows, cols, nshafts = 0, ntreadles = 0, nthreads;
	int use_lift, rising = 1, have, rc;
	wif_list *pk;
	char s[64];

	memset(&b, 0, sizeof b);
	if ((rc = normalise_numbers(p)))
		return rc;
	use_lift = lp->n > 0;
	pk = use_lift ? lp : tr;
	if (p->version.s && p->version.n && !(p->version.n >= 2 &&
	    p->version.s[0] == '1' && p->version.s[1] == '.'))
		pwarn(p, p->version.line, "WIF Version=%s; reading it as WIF 1.1",
		      show(s, sizeof s, p->version.s, p->version.n));
	if (th->n == 0)
		return perr(p, th->header_line ? th->header_line : p->last_line,
		            LOOM_EFORMAT, "no threading: expected a [THREADING] section "
		            "with at least one END=SHAFT line");
	if (!use_lift && tr->n == 0)
		return perr(p, tr->header_line ? tr->header_line
		            : lp->header_line ? lp->header_line : p->last_line,
		            LOOM_EFORMAT, "no picks: expected a [TREADLING] or "
		            "[LIFTPLAN] section with at least one PICK=... line");
	if (!use_lift && tu->n == 0)
		return perr(p, tr->header_line, LOOM_EFORMAT, "[TREADLING] without "
		            "[TIEUP]: expected a [TIEUP] section (or a [LIFTPLAN]) "
		            "saying which shafts each treadle lifts");
	cols = th->max_key;
	rows = pk->max_key;
	if ((uint64_t)rows * cols > p->max_cells)
		return perr(p, pk->max_key_line, LOOM_ERANGE, "design of %u picks x %u "
		            "ends has %llu cells, more than the %llu allowed", rows, cols,
		            (unsigned long long)rows * cols,
		            (unsigned long long)p->max_cells);

	/* declared counts: warnings only */
	if ((rc = scalar_u32(p, &p->shafts, "[WEAVING] Shafts", UINT32_MAX,
	                     &nshafts, &have)))
		return rc;
	if (have) {
		check_declared(p, L_THREADING, 0, nshafts, "Shafts");
		check_declared(p, use_lift ? L_LIFTPLAN : L_TIEUP, 0, nshafts, "Shafts");
	}
	if ((rc = scalar_u32(p, &p->treadles, "[WEAVING] Treadles", UINT32_MAX,
	                     &ntreadles, &have)))
		return rc;
	if (have && !use_lift) {
		check_declared(p, L_TIEUP, 1, ntreadles, "Treadles");
		check_declared(p, L_TREADLING, 0, ntreadles, "Treadles");
	}
	for (int side = 0; side < 2; side++) {
		uint32_t real = side ? rows : cols;
		if ((rc = scalar_u32(p, &p->threads[side], side ? "[WEFT] Threads"
		                     : "[WARP] Threads", UINT32_MAX, &nthreads, &have)))
			return rc;
		if (have && nthreads != real)
			pwarn(p, p->threads[side].line, "%s Threads=%u but %s goes up to "
			      "%s %u; using %u", side ? "[WEFT]" : "[WARP]", nthreads,
			      side ? lists[pk == lp ? L_LIFTPLAN : L_TREADLING].section
			           : "[THREADING]", side ? "pick" : "end", real, real);
	}
	if (!p->rising.s || p->rising.n == 0)
		pwarn(p, p->rising.s ? p->rising.line
		      : p->weaving_line ? p->weaving_line : p->last_line,
		      "no Rising Shed in [WEAVING]; assuming a rising shed");
	else if (!parse_bool(&p->rising, &rising))
		pwarn(p, p->rising.line, "[WEAVING] Rising Shed=%s is not true or "
		      "false; assuming a rising shed",
		      show(s, sizeof s, p->rising.s, p->rising.n));

	rc = loom_design_new(rows, cols, &d);
	if (rc) {
		build_free(&b);
		return perr(p, pk->max_key_line, rc, "cannot make a %u x %u design: %s",
		            rows, cols, loom_strerror(rc));
	}
	if ((rc = index_list(p, L_THREADING, cols, &b.end_e)) ||
	    (rc = index_list(p, use_lift ? L_LIFTPLAN : L_TREADLING, rows,
	                     &b.pick_e)) ||
	    (rc = drawdown(p, &b, d, use_lift, rising)) ||
	    (rc = yarn_types(p, &b, d)) ||
	    (rc = side_sett(p, &b, d, 0, d->cols)) ||
	    (rc = side_sett(p, &b, d, 1, d->rows))) {
		build_free(&b);
		loom_design_free(d);
		return rc;
	}
	build_free(&b);
	*out = d;
	return LOOM_OK;
}

/* ---- entry points ------------------------------------------------------ */

/*
 * What a non-WIF input looks like, from its first bytes, or NULL when it
 * may be text.  A WIF draft is an INI-style text file; a picture or an
 * archive given by mistake (a PNG renamed .wif) is named as such instead
 * of being parsed into "no threading" at some line of binary garbage.
 */
static const char *sniff_binary(const unsigned char *t, size_t len)
{
	static const struct {
		const char *magic;
		size_t n;
		const char *what;
	} known[] = {
		{"\x89PNG\r\n\x1a\n", 8, "a PNG image"},
		{"\xff\xd8\xff", 3, "a JPEG image"},
		{"GIF8", 4, "a GIF image"},
		{"v/1\x01", 4, "an OpenEXR image"},
		{"%PDF", 4, "a PDF document"},
		{"PK\x03\x04", 4, "a ZIP archive"},
		{"\x1f\x8b", 2, "gzip data"},
		{"VOL\x03", 4, "a Mitsuba volume"},
		{"NRRD", 4, "an NRRD volume"},
		{"\x7f" "ELF", 4, "a program"},
	};
	size_t head = len < 4096 ? len : 4096;

	for (size_t k = 0; k < sizeof known / sizeof known[0]; k++)
		if (len >= known[k].n && memcmp(t, known[k].magic, known[k].n) == 0)
			return known[k].what;
	if (len >= 2 && t[0] == 'P' && t[1] >= '1' && t[1] <= '6' &&
	    (len == 2 || t[2] == '\n' || t[2] == '\r' || t[2] == ' ' ||
	     t[2] == '\t'))
		return "a PBM/PGM/PPM image";
	for (size_t i = 0; i < head; i++)
		if (t[i] == 0)
			return "binary data";
	return NULL;
}

/* Nothing but white space (an empty or blank file). */
static int blank_text(const char *t, size_t len)
{
	for (size_t i = 0; i < len; i++)
		if (!is_blank(t[i]) && t[i] != '\n' && t[i] != '\r')
			return 0;
	return 1;
}

int loom__wif_parse_limited(const char *text, size_t len, const char *name,
                            uint64_t max_cells, loom_design **out,
                            loom_diag *diag)
{
	wif_parser p;
	int rc;

	if (out)
		*out = NULL;
	if (!name)
		name = "(wif)";
	if (!out || (!text && len))
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL argument", name);
	memset(&p, 0, sizeof p);
	if (blank_text(text, len))
		return loom__fail(diag, LOOM_ETRUNCATED, "%s: empty file, expected a "
		                  "WIF draft ([WIF], [THREADING], [TIEUP] and "
		                  "[TREADLING] or [LIFTPLAN] sections)", name);
	if (text) {
		const char *what = sniff_binary((const unsigned char *)text, len);
		if (what)
			return loom__fail(diag, LOOM_EFORMAT,
			                  "%s: not a WIF draft (looks like %s)", name,
			                  what);
	}
	p.name = name;
	p.diag = diag;
	p.max_cells = max_cells < LOOM_DESIGN_MAX_CELLS ? max_cells
	                                                : LOOM_DESIGN_MAX_CELLS;
	/* the pool is never NULL, even for tables without values */
	if (!grow((void **)&p.pool, &p.cap_pool, 1, sizeof *p.pool))
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	rc = parse_text(&p, text ? text : "", len);
	if (rc == LOOM_OK)
		rc = build(&p, out);
	free(p.pool);
	free(p.fpool);
	for (int i = 0; i < L_COUNT; i++)
		free(p.list[i].e);
	return rc;
}

LOOM_API int loom_wif_parse(const char *text, size_t len, const char *name,
                            loom_design **out, loom_diag *diag)
{
	return loom__wif_parse_limited(text, len, name, LOOM_DESIGN_MAX_CELLS, out,
	                               diag);
}

/* head check of a WIF file: a known binary format is named, then text */
static int wif_head(const uint8_t *head, size_t n, const char *path,
                    loom_diag *diag)
{
	const char *what = sniff_binary(head, n);

	if (what)
		return loom__fail(diag, LOOM_EFORMAT,
		                  "%s: not a WIF draft (looks like %s)", path, what);
	return loom__head_text(head, n, path, diag);
}

LOOM_API int loom_wif_read(const char *path, loom_design **out, loom_diag *diag)
{
	uint8_t *data;
	size_t len;
	int rc;

	if (out)
		*out = NULL;
	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_wif_read: NULL argument");
	rc = loom__read_file_checked(path, LOOM__WIF_MAX_FILE_BYTES, "WIF",
	                             wif_head, &data, &len, diag);
	if (rc)
		return rc;
	rc = loom_wif_parse((const char *)data, len, path, out, diag);
	free(data);
	return rc;
}
