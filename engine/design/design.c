/*
 * engine/design/design.c - the design model (paper 5.1) and elementary weave
 * generators.
 *
 * Every elementary weave is written as "column j is a warp that floats over
 * `over` picks then under `under` picks, its float starting at row s(j)":
 *
 *     W(i, j) = ((i - s(j)) mod R) < over,       R = over + under
 *
 * and the kinds differ only in the start function s(j):
 *
 *     twill        s(j) = dir * j                       (dir = +1 Z, -1 S)
 *     satin        s(j) = move * j,  1 < move < R-1, gcd(move, R) = 1
 *     herringbone  sections of P ends; s = t in even sections and
 *                  (P-1-t) + R/2 in odd ones (mirror with a break)
 *     broken twill as herringbone, but the break is `over` (default P = 2;
 *                  2/2 gives the classic 0,1,3,2 crowfoot order)
 *     wavy twill   s(j) = zigzag(j), period 2(P-1): a pointed twill
 *
 * where t = j mod P.  Plain and basket are checkerboards of 1x1 and a x b
 * cells.  docs/designs.md shows each with a picture.
 */
#include "core/internal.h"

#include <stdlib.h>
#include <string.h>

LOOM_API int loom_design_new(uint32_t rows, uint32_t cols, loom_design **out)
{
	loom_design *d;
	size_t n;

	if (!out)
		return LOOM_EINVAL;
	*out = NULL;
	if (rows == 0 || cols == 0)
		return LOOM_EINVAL;
	if (rows > LOOM_DESIGN_MAX_SIDE || cols > LOOM_DESIGN_MAX_SIDE ||
	    (uint64_t)rows * cols > LOOM_DESIGN_MAX_CELLS)
		return LOOM_ERANGE;
	n = (size_t)rows * cols;
	d = calloc(1, sizeof *d);
	if (!d)
		return LOOM_ENOMEM;
	d->rows = rows;
	d->cols = cols;
	d->weave = calloc(n, 1);
	d->warp_type = calloc(n, 1);
	d->weft_type = malloc(n);
	if (!d->weave || !d->warp_type || !d->weft_type) {
		loom_design_free(d);
		return LOOM_ENOMEM;
	}
	memset(d->weft_type, 1, n);
	if (loom_design_set_types(d, 2) != LOOM_OK) {
		loom_design_free(d);
		return LOOM_ENOMEM;
	}
	strcpy(d->types[0].name, "warp");
	strcpy(d->types[1].name, "weft");
	d->types[0].albedo[0] = 0.85f; /* default warp: light grey */
	d->types[0].albedo[1] = 0.85f;
	d->types[0].albedo[2] = 0.82f;
	d->types[1].albedo[0] = 0.20f; /* default weft: dark blue */
	d->types[1].albedo[1] = 0.28f;
	d->types[1].albedo[2] = 0.55f;
	*out = d;
	return LOOM_OK;
}

LOOM_API void loom_design_free(loom_design *d)
{
	if (!d)
		return;
	free(d->weave);
	free(d->warp_type);
	free(d->weft_type);
	free(d->types);
	free(d);
}

LOOM_API int loom_design_clone(const loom_design *d, loom_design **out)
{
	loom_design *c;
	size_t n;
	int rc;

	if (!d || !out)
		return LOOM_EINVAL;
	rc = loom_design_new(d->rows, d->cols, &c);
	if (rc)
		return rc;
	n = (size_t)d->rows * d->cols;
	memcpy(c->weave, d->weave, n);
	memcpy(c->warp_type, d->warp_type, n);
	memcpy(c->weft_type, d->weft_type, n);
	rc = loom_design_set_types(c, d->n_types);
	if (rc) {
		loom_design_free(c);
		return rc;
	}
	memcpy(c->types, d->types, d->n_types * sizeof *d->types);
	memcpy(c->sett, d->sett, sizeof c->sett);
	memcpy(c->yarn_um, d->yarn_um, sizeof c->yarn_um);
	*out = c;
	return LOOM_OK;
}

LOOM_API int loom_design_set_types(loom_design *d, uint32_t n)
{
	loom_yarn_type *t;

	if (!d || n == 0 || n > LOOM_MAX_YARN_TYPES)
		return LOOM_EINVAL;
	t = realloc(d->types, n * sizeof *t);
	if (!t)
		return LOOM_ENOMEM;
	for (uint32_t k = d->n_types; k < n; k++) {
		memset(&t[k], 0, sizeof t[k]);
		snprintf(t[k].name, sizeof t[k].name, "type%u", k);
		t[k].albedo[0] = t[k].albedo[1] = t[k].albedo[2] = 0.5f;
		t[k].alignment = 0.3f;
	}
	if (d->n_types == 0) { /* fresh table: give the defaults an alignment */
		for (uint32_t k = 0; k < n; k++)
			t[k].alignment = 0.3f;
	}
	d->types = t;
	d->n_types = n;
	return LOOM_OK;
}

LOOM_API int loom_design_validate(const loom_design *d, loom_diag *diag)
{
	size_t n;

	if (!d)
		return loom__fail(diag, LOOM_EINVAL, "design is NULL");
	if (d->rows == 0 || d->cols == 0 || d->rows > LOOM_DESIGN_MAX_SIDE ||
	    d->cols > LOOM_DESIGN_MAX_SIDE)
		return loom__fail(diag, LOOM_EFORMAT, "design size %ux%u out of range",
		                  d->rows, d->cols);
	if (d->n_types == 0 || d->n_types > LOOM_MAX_YARN_TYPES || !d->types)
		return loom__fail(diag, LOOM_EFORMAT, "yarn table has %u entries",
		                  d->n_types);
	for (uint32_t t = 0; t < d->n_types; t++)
		if (d->types[t].fibre >= LOOM_FIBRE_COUNT_)
			return loom__fail(diag, LOOM_EFORMAT, "yarn type %u ('%s') has "
			                  "material code %u, expected 0..%d", t,
			                  d->types[t].name, d->types[t].fibre,
			                  LOOM_FIBRE_COUNT_ - 1);
	n = (size_t)d->rows * d->cols;
	for (size_t k = 0; k < n; k++) {
		if (d->weave[k] > 1)
			return loom__fail(diag, LOOM_EFORMAT,
			                  "weave cell (%zu,%zu) is %u, expected 0 or 1",
			                  k / d->cols, k % d->cols, d->weave[k]);
		if (d->warp_type[k] >= d->n_types || d->weft_type[k] >= d->n_types)
			return loom__fail(diag, LOOM_EFORMAT,
			                  "cell (%zu,%zu) uses yarn type %u, table has %u",
			                  k / d->cols, k % d->cols,
			                  d->warp_type[k] >= d->n_types ? d->warp_type[k]
			                                                : d->weft_type[k],
			                  d->n_types);
	}
	return LOOM_OK;
}

/* ---- materials --------------------------------------------------------- */

static const char *const fibre_names[LOOM_FIBRE_COUNT_][2] = {
	{"default", "--"}, {"none", "sm"}, {"cotton", "co"}, {"rayon", "cv"},
	{"silk", "si"}, {"polyester", "pe"}, {"wool", "wo"}, {"linen", "li"},
	{"monofilament", "mf"}};

LOOM_API int loom_fibre_parse(const char *name, int *code)
{
	if (!name || !code)
		return LOOM_EINVAL;
	for (int k = LOOM_FIBRE_NONE; k < LOOM_FIBRE_COUNT_; k++)
		if (!strcmp(name, fibre_names[k][0])) {
			*code = k;
			return LOOM_OK;
		}
	return LOOM_EINVAL;
}

LOOM_API const char *loom_fibre_name(int code)
{
	return code >= 0 && code < LOOM_FIBRE_COUNT_ ? fibre_names[code][0] : NULL;
}

LOOM_API const char *loom_fibre_short(int code)
{
	return code >= 0 && code < LOOM_FIBRE_COUNT_ ? fibre_names[code][1] : NULL;
}

/* ---- elementary weaves ------------------------------------------------- */

static uint32_t gcd_u32(uint32_t a, uint32_t b)
{
	while (b) {
		uint32_t t = a % b;
		a = b;
		b = t;
	}
	return a;
}

static const char *const kind_names[LOOM_WEAVE_KIND_COUNT_] = {
	"plain", "twill", "satin", "basket", "herringbone", "broken-twill",
	"wavy-twill",
};

/* Period P of the section-based kinds, with its default. */
static uint32_t section_period(const loom_weave_params *p)
{
	uint32_t r = p->over + p->under;
	if (p->period)
		return p->period;
	return p->kind == LOOM_WEAVE_BROKEN_TWILL ? 2 : r;
}

static uint32_t satin_default_move(uint32_t r)
{
	for (uint32_t s = 2; s + 1 < r; s++)
		if (gcd_u32(s, r) == 1)
			return s;
	return 0;
}

LOOM_API int loom_weave_repeat(const loom_weave_params *p, uint32_t *rows,
                               uint32_t *cols, loom_diag *diag)
{
	uint32_t r, per;

	if (!p || !rows || !cols)
		return loom__fail(diag, LOOM_EINVAL, "NULL argument");
	if (p->kind < 0 || p->kind >= LOOM_WEAVE_KIND_COUNT_)
		return loom__fail(diag, LOOM_EINVAL, "unknown weave kind %d", p->kind);
	if (p->kind == LOOM_WEAVE_PLAIN) {
		*rows = *cols = 2;
		return LOOM_OK;
	}
	if (p->over == 0 || p->under == 0 || p->over > 4096 || p->under > 4096)
		return loom__fail(diag, LOOM_EINVAL,
		                  "%s: over and under must be 1..4096 (got %u/%u)",
		                  kind_names[p->kind], p->over, p->under);
	r = p->over + p->under;
	switch (p->kind) {
	case LOOM_WEAVE_BASKET:
		*rows = 2 * p->over;
		*cols = 2 * p->under;
		return LOOM_OK;
	case LOOM_WEAVE_TWILL:
		if (p->direction != 1 && p->direction != -1)
			return loom__fail(diag, LOOM_EINVAL,
			                  "twill direction must be +1 (Z) or -1 (S)");
		*rows = *cols = r;
		return LOOM_OK;
	case LOOM_WEAVE_SATIN: {
		uint32_t s = p->move ? p->move : satin_default_move(r);
		if (r < 5)
			return loom__fail(diag, LOOM_EINVAL,
			                  "satin %u/%u: a satin needs a repeat of at least 5 "
			                  "ends (got %u)", p->over, p->under, r);
		if (s == 0)
			return loom__fail(diag, LOOM_EINVAL,
			                  "satin %u/%u: no valid move exists for a repeat of "
			                  "%u (every 1 < move < %u shares a factor with %u)",
			                  p->over, p->under, r, r - 1, r);
		if (s <= 1 || s >= r - 1)
			return loom__fail(diag, LOOM_EINVAL,
			                  "satin %u/%u: move %u gives a twill; use "
			                  "2..%u", p->over, p->under, s, r - 2);
		if (gcd_u32(s, r) != 1)
			return loom__fail(diag, LOOM_EINVAL,
			                  "satin %u/%u: move %u shares the factor %u with the "
			                  "repeat %u, so some ends would never interlace",
			                  p->over, p->under, s, gcd_u32(s, r), r);
		*rows = *cols = r;
		return LOOM_OK;
	}
	case LOOM_WEAVE_HERRINGBONE:
	case LOOM_WEAVE_BROKEN_TWILL:
		per = section_period(p);
		if (per < 1 || per > 65536)
			return loom__fail(diag, LOOM_EINVAL, "%s: period must be 1..65536",
			                  kind_names[p->kind]);
		*rows = r;
		*cols = 2 * per;
		return LOOM_OK;
	case LOOM_WEAVE_WAVY_TWILL:
		per = section_period(p);
		if (per < 2 || per > 65536)
			return loom__fail(diag, LOOM_EINVAL,
			                  "wavy-twill: period must be 2..65536");
		*rows = r;
		*cols = 2 * (per - 1);
		return LOOM_OK;
	default:
		return loom__fail(diag, LOOM_EINVAL, "unknown weave kind %d", p->kind);
	}
}

/* Start row s(j) of the warp float of column j, reduced mod r. */
static uint32_t float_start(const loom_weave_params *p, uint64_t j, uint32_t r)
{
	uint32_t per, t;
	uint64_t k;

	switch (p->kind) {
	case LOOM_WEAVE_TWILL:
		return p->direction < 0 ? (uint32_t)((r - j % r) % r) : (uint32_t)(j % r);
	case LOOM_WEAVE_SATIN: {
		uint32_t s = p->move ? p->move : satin_default_move(r);
		return (uint32_t)(((j % r) * s) % r);
	}
	case LOOM_WEAVE_HERRINGBONE:
	case LOOM_WEAVE_BROKEN_TWILL: {
		uint32_t brk = p->kind == LOOM_WEAVE_HERRINGBONE ? r / 2 : p->over;
		per = section_period(p);
		k = j / per;
		t = (uint32_t)(j % per);
		if ((k & 1) == 0)
			return t % r;
		return (uint32_t)(((uint64_t)(per - 1 - t) + brk) % r);
	}
	case LOOM_WEAVE_WAVY_TWILL: {
		uint32_t w;
		per = section_period(p);
		w = 2 * (per - 1);
		t = (uint32_t)(j % w);
		return (t < per ? t : w - t) % r;
	}
	default:
		return 0;
	}
}

LOOM_API int loom_weave_cell(const loom_weave_params *p, uint64_t i, uint64_t j)
{
	uint32_t r, s;

	switch (p->kind) {
	case LOOM_WEAVE_PLAIN:
		return ((i + j) & 1) == 0;
	case LOOM_WEAVE_BASKET:
		return ((i / p->over + j / p->under) & 1) == 0;
	default:
		r = p->over + p->under;
		s = float_start(p, j, r);
		return (uint32_t)((i % r + r - s) % r) < p->over;
	}
}

LOOM_API int loom_design_make(const loom_weave_params *p, uint32_t rows,
                              uint32_t cols, loom_design **out, loom_diag *diag)
{
	uint32_t rr, rc;
	loom_design *d;
	int rc2;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "NULL output");
	*out = NULL;
	rc2 = loom_weave_repeat(p, &rr, &rc, diag);
	if (rc2)
		return rc2;
	if (rows == 0)
		rows = rr;
	if (cols == 0)
		cols = rc;
	rc2 = loom_design_new(rows, cols, &d);
	if (rc2)
		return loom__fail(diag, rc2, "cannot make a %ux%u design: %s", rows,
		                  cols, loom_strerror(rc2));
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++)
			d->weave[(size_t)i * cols + j] = (uint8_t)loom_weave_cell(p, i, j);
	*out = d;
	return LOOM_OK;
}

/* ---- names ------------------------------------------------------------- */

static int parse_u32(const char **s, uint32_t *v)
{
	uint64_t x = 0;
	const char *q = *s;
	if (*q < '0' || *q > '9')
		return 0;
	while (*q >= '0' && *q <= '9') {
		x = x * 10 + (uint64_t)(*q - '0');
		if (x > 0xffffffffu)
			return 0;
		q++;
	}
	*v = (uint32_t)x;
	*s = q;
	return 1;
}

LOOM_API int loom_weave_parse(const char *name, loom_weave_params *p,
                              loom_diag *diag)
{
	loom_weave_params q = LOOM_WEAVE_PARAMS_INIT;
	const char *s, *colon;
	size_t klen;
	int kind = -1;
	uint32_t a, b, dummy_r, dummy_c;
	int rc;

	if (!name || !p)
		return loom__fail(diag, LOOM_EINVAL, "NULL argument");
	colon = strchr(name, ':');
	klen = colon ? (size_t)(colon - name) : strlen(name);
	for (int k = 0; k < LOOM_WEAVE_KIND_COUNT_; k++)
		if (strlen(kind_names[k]) == klen && loom__strnieq(name, kind_names[k], klen))
			kind = k;
	if (kind < 0)
		return loom__fail(diag, LOOM_EINVAL,
		                  "unknown weave '%s': expected plain, twill:M/N, "
		                  "satin:M/N[:move=K], basket:A[/B], herringbone:M/N, "
		                  "broken-twill:M/N or wavy-twill:M/N", name);
	q.kind = kind;
	s = colon ? colon + 1 : "";
	if (kind == LOOM_WEAVE_PLAIN) {
		if (*s)
			return loom__fail(diag, LOOM_EINVAL, "weave '%s': plain takes no "
			                  "parameters", name);
		*p = q;
		return LOOM_OK;
	}
	if (!parse_u32(&s, &a))
		return loom__fail(diag, LOOM_EINVAL, "weave '%s': expected a number after "
		                  "'%.*s:'", name, (int)klen, name);
	b = a;
	if (*s == '/') {
		s++;
		if (!parse_u32(&s, &b))
			return loom__fail(diag, LOOM_EINVAL, "weave '%s': expected a number "
			                  "after '/'", name);
	} else if (kind != LOOM_WEAVE_BASKET) {
		return loom__fail(diag, LOOM_EINVAL, "weave '%s': expected OVER/UNDER, "
		                  "e.g. %s:2/3", name, kind_names[kind]);
	}
	q.over = a;
	q.under = b;
	while (*s == ':') {
		s++;
		if (loom__strnieq(s, "move=", 5)) {
			s += 5;
			if (!parse_u32(&s, &q.move))
				return loom__fail(diag, LOOM_EINVAL, "weave '%s': bad move", name);
		} else if (loom__strnieq(s, "period=", 7)) {
			s += 7;
			if (!parse_u32(&s, &q.period))
				return loom__fail(diag, LOOM_EINVAL, "weave '%s': bad period", name);
		} else if ((*s == 's' || *s == 'S') && (s[1] == 0 || s[1] == ':')) {
			q.direction = -1;
			s++;
		} else if ((*s == 'z' || *s == 'Z') && (s[1] == 0 || s[1] == ':')) {
			q.direction = 1;
			s++;
		} else {
			return loom__fail(diag, LOOM_EINVAL, "weave '%s': unknown option "
			                  "'%s' (expected move=K, period=P, s or z)", name, s);
		}
	}
	if (*s)
		return loom__fail(diag, LOOM_EINVAL, "weave '%s': unexpected '%s'", name, s);
	rc = loom_weave_repeat(&q, &dummy_r, &dummy_c, diag);
	if (rc)
		return rc;
	*p = q;
	return LOOM_OK;
}

LOOM_API int loom_weave_name(const loom_weave_params *p, char *buf, size_t n)
{
	int w;

	if (!p || !buf || p->kind < 0 || p->kind >= LOOM_WEAVE_KIND_COUNT_)
		return LOOM_EINVAL;
	if (p->kind == LOOM_WEAVE_PLAIN)
		w = snprintf(buf, n, "plain");
	else if (p->kind == LOOM_WEAVE_BASKET)
		w = snprintf(buf, n, "basket:%u/%u", p->over, p->under);
	else
		w = snprintf(buf, n, "%s:%u/%u", kind_names[p->kind], p->over, p->under);
	if (w >= 0 && (size_t)w < n && p->kind == LOOM_WEAVE_SATIN && p->move)
		w += snprintf(buf + w, n - (size_t)w, ":move=%u", p->move);
	if (w >= 0 && (size_t)w < n && p->direction < 0 &&
	    p->kind == LOOM_WEAVE_TWILL)
		w += snprintf(buf + w, n - (size_t)w, ":s");
	if (w >= 0 && (size_t)w < n && p->period &&
	    (p->kind == LOOM_WEAVE_HERRINGBONE || p->kind == LOOM_WEAVE_BROKEN_TWILL ||
	     p->kind == LOOM_WEAVE_WAVY_TWILL))
		w += snprintf(buf + w, n - (size_t)w, ":period=%u", p->period);
	return (w < 0 || (size_t)w >= n) ? LOOM_ERANGE : LOOM_OK;
}
