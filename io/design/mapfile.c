/*
 * io/design/mapfile.c - posterized image + mapping file -> design (paper 5.2).
 *
 *     W(y, x) = V_p(I(x, y))(y, x)
 *
 * Each distinct colour c of the image I is mapped by p to an elementary
 * weave V and a warp and weft yarn type; every elementary weave is tiled
 * from the image origin, so the weave of a cell depends only on its own
 * colour and position (row y = pick y, column x = end x).
 *
 * The mapping file (full grammar in docs/designs.md) is line based:
 *
 *     yarn NAME ALBEDO [alignment=A] [thickness=T] [fibre=F]
 *     colour COLOUR WEAVE [warp=NAME] [weft=NAME]
 *
 * ALBEDO is #RRGGBB or r,g,b in [0,1]; COLOUR is #RRGGBB, a grey level
 * 0..255 or index=K (entry K of an indexed PNG's palette); WEAVE is a name
 * for loom_weave_parse.  '#' begins a comment at the start of a line or
 * when followed by a blank or the end of the line.  Yarn lines build the
 * yarn table in order (IDs 0, 1, ...); with none, the table is the default
 * {warp, weft}.  warp= and weft= default to "warp" and "weft".
 *
 * Steps: 1. parse every line (yarn and colour lists, errors file:line);
 * 2. build the yarn table and resolve names; 3. turn colour specs into
 * packed RGB keys (palette lookups need the image); 4. list the image's
 * distinct colours (at most 64); 5. match each to a colour line; 6. fill
 * the design.
 */
#include "image_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAP_MAX_IMAGE_COLOURS 64
#define MAP_MAX_COLOUR_LINES 4096
#define MAP_MAX_TOKENS 16
#define MAP_HASH_SLOTS 256 /* > 2 * MAP_MAX_IMAGE_COLOURS, a power of two */

typedef struct tok {
	const char *s;
	size_t n;
} tok;

enum spec_kind { SPEC_RGB, SPEC_GREY, SPEC_INDEX };

typedef struct map_colour {
	int spec;               /* enum spec_kind: how the colour was written */
	uint32_t value;         /* RGB key, grey level or palette index */
	uint32_t key;           /* packed 0xRRGGBB once resolved */
	loom_weave_params weave;
	char warp[LOOM_YARN_NAME_MAX], weft[LOOM_YARN_NAME_MAX];
	uint8_t warp_id, weft_id;
	unsigned line;
	int used;               /* some pixel has this colour */
} map_colour;

typedef struct map_yarn {
	loom_yarn_type t;
	unsigned line;
} map_yarn;

typedef struct mapfile {
	const char *name;
	loom_diag *diag;
	unsigned line;          /* line being parsed */
	map_yarn *yarns;
	uint32_t n_yarns;
	map_colour *colours;
	uint32_t n_colours, cap_colours;
} mapfile;

/* Distinct image colours. */
typedef struct img_colours {
	uint32_t key[MAP_MAX_IMAGE_COLOURS];
	size_t first[MAP_MAX_IMAGE_COLOURS]; /* first pixel (row-major index) */
	int map[MAP_MAX_IMAGE_COLOURS];      /* index into mapfile.colours */
	uint32_t n;
	int16_t slot[MAP_HASH_SLOTS];        /* -1 empty, else colour index */
} img_colours;

/* ---- step 1: lines and tokens ------------------------------------------ */

static int is_blank(char c)
{
	return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static int tok_is(tok t, const char *word)
{
	return strlen(word) == t.n && loom__strnieq(t.s, word, t.n);
}

/* Copy a token into buf (NUL-terminated); 0 if it does not fit. */
static int tok_copy(tok t, char *buf, size_t n)
{
	if (t.n >= n)
		return 0;
	memcpy(buf, t.s, t.n);
	buf[t.n] = 0;
	return 1;
}

/* Split [s, e) into tokens, stopping at a comment. */
static int tokenize(mapfile *m, const char *s, const char *e, tok *t, int *nt)
{
	*nt = 0;
	while (s < e) {
		if (is_blank(*s)) {
			s++;
			continue;
		}
		if (*s == '#' && (*nt == 0 || s + 1 == e || is_blank(s[1])))
			break; /* a comment: first field, or '#' alone */
		if (*nt == MAP_MAX_TOKENS)
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: more than %d "
			                  "fields on one line", m->name, m->line,
			                  MAP_MAX_TOKENS);
		t[*nt].s = s;
		while (s < e && !is_blank(*s)) {
			if ((unsigned char)*s < 0x20 || *s == 0x7f)
				return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: unexpected "
				                  "control byte 0x%02x", m->name, m->line,
				                  (unsigned char)*s);
			s++;
		}
		t[*nt].n = (size_t)(s - t[*nt].s);
		(*nt)++;
	}
	return LOOM_OK;
}

static int hexval(char c)
{
	if (c >= '0' && c <= '9')
		return c - '0';
	if (c >= 'a' && c <= 'f')
		return c - 'a' + 10;
	if (c >= 'A' && c <= 'F')
		return c - 'A' + 10;
	return -1;
}

/* "#RRGGBB" -> 0xRRGGBB; 0 if t is not one. */
static int parse_hex(tok t, uint32_t *key)
{
	uint32_t v = 0;

	if (t.n != 7 || t.s[0] != '#')
		return 0;
	for (int k = 1; k < 7; k++) {
		int h = hexval(t.s[k]);
		if (h < 0)
			return 0;
		v = v << 4 | (uint32_t)h;
	}
	*key = v;
	return 1;
}

/* Decimal 0..max; 0 if t is not one. */
static int parse_dec(tok t, uint32_t max, uint32_t *v)
{
	uint32_t x = 0;

	if (t.n == 0 || t.n > 10)
		return 0;
	for (size_t k = 0; k < t.n; k++) {
		if (t.s[k] < '0' || t.s[k] > '9')
			return 0;
		x = x * 10 + (uint32_t)(t.s[k] - '0');
		if (x > max)
			return 0;
	}
	*v = x;
	return 1;
}

/* A finite float; 0 if t is not one. */
static int parse_float(tok t, double *v)
{
	char buf[64];
	char *end;

	if (!tok_copy(t, buf, sizeof buf) || t.n == 0)
		return 0;
	*v = strtod(buf, &end);
	return *end == 0 && isfinite(*v);
}

/* Print at most 40 bytes of a token. */
#define TOKF "'%.*s%s'"
#define TOKA(t) (int)((t).n > 40 ? 40 : (t).n), (t).s, (t).n > 40 ? "..." : ""

static int parse_albedo(mapfile *m, tok t, float rgb[3])
{
	uint32_t key;
	double v[3];
	tok part = t;

	if (parse_hex(t, &key)) {
		for (int k = 0; k < 3; k++)
			rgb[k] = loom__srgb_to_linear(((key >> (16 - 8 * k)) & 255) / 255.0);
		return LOOM_OK;
	}
	for (int k = 0; k < 3; k++) {
		const char *comma = memchr(part.s, ',', part.n);
		tok f = {part.s, comma && k < 2 ? (size_t)(comma - part.s) : part.n};
		if ((k < 2 && !comma) || !parse_float(f, &v[k]) || v[k] < 0 || v[k] > 1)
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected an albedo "
			                  "#RRGGBB or r,g,b with each in 0..1, got " TOKF,
			                  m->name, m->line, TOKA(t));
		if (comma && k < 2) {
			part.n -= (size_t)(comma + 1 - part.s);
			part.s = comma + 1;
		}
	}
	for (int k = 0; k < 3; k++)
		rgb[k] = (float)v[k];
	return LOOM_OK;
}

static int valid_name(tok t)
{
	if (t.n == 0 || t.n >= LOOM_YARN_NAME_MAX)
		return 0;
	for (size_t k = 0; k < t.n; k++) {
		char c = t.s[k];
		if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
		      (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.'))
			return 0;
	}
	return 1;
}

static int bad_name(mapfile *m, const char *what, tok t)
{
	return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected %s (letters, "
	                  "digits, '_', '-', '.'; at most %d characters), got " TOKF,
	                  m->name, m->line, what, LOOM_YARN_NAME_MAX - 1, TOKA(t));
}

/* "key=value" with key matched case-insensitively; value token out. */
static int keyval(tok t, const char *key, tok *val)
{
	size_t k = strlen(key);
	if (t.n <= k || t.s[k] != '=' || !loom__strnieq(t.s, key, k))
		return 0;
	val->s = t.s + k + 1;
	val->n = t.n - k - 1;
	return 1;
}

static int yarn_option(mapfile *m, tok t, loom_yarn_type *y)
{
	tok v;
	double x;

	if (keyval(t, "alignment", &v)) {
		if (!parse_float(v, &x) || x <= 0 || x > 1)
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: alignment must be "
			                  "a number in (0,1], got " TOKF, m->name, m->line,
			                  TOKA(v));
		y->alignment = (float)x;
		return LOOM_OK;
	}
	if (keyval(t, "thickness", &v)) {
		if (!parse_float(v, &x) || x < 0 || x > 1e6)
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: thickness must be "
			                  "a number >= 0, got " TOKF, m->name, m->line,
			                  TOKA(v));
		y->thickness = (float)x;
		return LOOM_OK;
	}
	if (keyval(t, "fibre", &v)) {
		char name[16];
		int code;
		if (!tok_copy(v, name, sizeof name) || loom_fibre_parse(name, &code) != LOOM_OK)
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: fibre must be cotton, "
			                  "rayon, silk, polyester, wool, linen, monofilament "
			                  "or none, got " TOKF, m->name, m->line, TOKA(v));
		y->fibre = (uint8_t)code;
		return LOOM_OK;
	}
	return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected alignment=A, "
	                  "thickness=T or fibre=F, got " TOKF, m->name, m->line, TOKA(t));
}

static int parse_yarn(mapfile *m, const tok *t, int nt)
{
	loom_yarn_type y;
	int rc;

	if (nt < 3)
		return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected 'yarn NAME "
		                  "ALBEDO [alignment=A] [thickness=T] [fibre=F]'", m->name, m->line);
	if (!valid_name(t[1]))
		return bad_name(m, "a yarn name", t[1]);
	for (uint32_t k = 0; k < m->n_yarns; k++)
		if (tok_is(t[1], m->yarns[k].t.name))
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: yarn '%s' is "
			                  "already defined on line %u", m->name, m->line,
			                  m->yarns[k].t.name, m->yarns[k].line);
	if (m->n_yarns == LOOM_MAX_YARN_TYPES)
		return loom__fail(m->diag, LOOM_ERANGE, "%s:%u: more than %d yarns",
		                  m->name, m->line, LOOM_MAX_YARN_TYPES);
	memset(&y, 0, sizeof y);
	tok_copy(t[1], y.name, sizeof y.name);
	y.alignment = 0.3f;
	if ((rc = parse_albedo(m, t[2], y.albedo)))
		return rc;
	for (int k = 3; k < nt; k++)
		if ((rc = yarn_option(m, t[k], &y)))
			return rc;
	m->yarns[m->n_yarns].t = y;
	m->yarns[m->n_yarns++].line = m->line;
	return LOOM_OK;
}

static int parse_spec(mapfile *m, tok t, map_colour *c)
{
	tok v;

	if (parse_hex(t, &c->value)) {
		c->spec = SPEC_RGB;
		return LOOM_OK;
	}
	if (parse_dec(t, 255, &c->value)) {
		c->spec = SPEC_GREY;
		return LOOM_OK;
	}
	if (keyval(t, "index", &v) && parse_dec(v, 255, &c->value)) {
		c->spec = SPEC_INDEX;
		return LOOM_OK;
	}
	return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected an image colour: "
	                  "#RRGGBB, a grey level 0..255 or index=K (K = 0..255), "
	                  "got " TOKF, m->name, m->line, TOKA(t));
}

static int parse_weave(mapfile *m, tok t, loom_weave_params *p)
{
	char buf[128];
	loom_diag d = {0};
	int rc;

	if (!tok_copy(t, buf, sizeof buf))
		return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: weave name too long",
		                  m->name, m->line);
	rc = loom_weave_parse(buf, p, &d);
	if (rc)
		return loom__fail(m->diag, rc, "%s:%u: %s", m->name, m->line, d.message);
	return LOOM_OK;
}

static int colour_option(mapfile *m, tok t, map_colour *c, int *seen)
{
	tok v;
	int which;
	char *dst;

	if (keyval(t, "warp", &v))
		which = 0;
	else if (keyval(t, "weft", &v))
		which = 1;
	else
		return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected warp=YARN or "
		                  "weft=YARN, got " TOKF, m->name, m->line, TOKA(t));
	if (seen[which]++)
		return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: %s= given twice",
		                  m->name, m->line, which ? "weft" : "warp");
	if (!valid_name(v))
		return bad_name(m, "a yarn name", v);
	dst = which ? c->weft : c->warp;
	tok_copy(v, dst, LOOM_YARN_NAME_MAX);
	return LOOM_OK;
}

static int parse_colour(mapfile *m, const tok *t, int nt)
{
	map_colour c;
	int seen[2] = {0, 0};
	int rc;

	if (nt < 3)
		return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected 'colour "
		                  "COLOUR WEAVE [warp=YARN] [weft=YARN]'", m->name,
		                  m->line);
	if (m->n_colours == MAP_MAX_COLOUR_LINES)
		return loom__fail(m->diag, LOOM_ERANGE, "%s:%u: more than %d colour "
		                  "lines", m->name, m->line, MAP_MAX_COLOUR_LINES);
	memset(&c, 0, sizeof c);
	strcpy(c.warp, "warp");
	strcpy(c.weft, "weft");
	c.line = m->line;
	if ((rc = parse_spec(m, t[1], &c)) || (rc = parse_weave(m, t[2], &c.weave)))
		return rc;
	for (int k = 3; k < nt; k++)
		if ((rc = colour_option(m, t[k], &c, seen)))
			return rc;
	if (m->n_colours == m->cap_colours) {
		uint32_t cap = m->cap_colours ? 2 * m->cap_colours : 16;
		map_colour *nc = realloc(m->colours, cap * sizeof *nc);
		if (!nc)
			return loom__fail(m->diag, LOOM_ENOMEM, "%s: out of memory", m->name);
		m->colours = nc;
		m->cap_colours = cap;
	}
	m->colours[m->n_colours++] = c;
	return LOOM_OK;
}

static int parse_line(mapfile *m, const char *s, const char *e)
{
	tok t[MAP_MAX_TOKENS];
	int nt, rc;

	if ((rc = tokenize(m, s, e, t, &nt)) || nt == 0)
		return rc;
	if (tok_is(t[0], "yarn"))
		return parse_yarn(m, t, nt);
	if (tok_is(t[0], "colour") || tok_is(t[0], "color"))
		return parse_colour(m, t, nt);
	return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: expected 'yarn' or "
	                  "'colour', got " TOKF, m->name, m->line, TOKA(t[0]));
}

static int parse_text(mapfile *m, const char *text, size_t len)
{
	const char *s = text, *end = text + len;
	int rc;

	m->yarns = calloc(LOOM_MAX_YARN_TYPES, sizeof *m->yarns);
	if (!m->yarns)
		return loom__fail(m->diag, LOOM_ENOMEM, "%s: out of memory", m->name);
	for (m->line = 1; s < end; m->line++) {
		const char *nl = memchr(s, '\n', (size_t)(end - s));
		const char *e = nl ? nl : end;
		if ((rc = parse_line(m, s, e)))
			return rc;
		s = nl ? nl + 1 : end;
	}
	if (m->n_colours == 0)
		return loom__fail(m->diag, LOOM_EFORMAT, "%s: no 'colour' lines: "
		                  "nothing maps the image's colours to weaves", m->name);
	return LOOM_OK;
}

/* ---- step 2: yarn table and names --------------------------------------- */

static int find_yarn(const loom_design *d, const char *name)
{
	for (uint32_t k = 0; k < d->n_types; k++)
		if (strcmp(d->types[k].name, name) == 0)
			return (int)k;
	return -1;
}

static void yarn_list(const loom_design *d, char *buf, size_t n)
{
	size_t w = 0;

	buf[0] = 0;
	for (uint32_t k = 0; k < d->n_types && w + 1 < n; k++) {
		int r = snprintf(buf + w, n - w, "%s%s", k ? ", " : "", d->types[k].name);
		if (r < 0 || (size_t)r >= n - w) {
			snprintf(buf + (n > 4 ? n - 4 : 0), n > 4 ? 4 : n, "...");
			return;
		}
		w += (size_t)r;
	}
}

static int resolve_yarn(mapfile *m, const loom_design *d, const map_colour *c,
                        int which, uint8_t *id)
{
	const char *name = which ? c->weft : c->warp;
	int k = find_yarn(d, name);
	char list[200];

	if (k < 0) {
		yarn_list(d, list, sizeof list);
		return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: unknown yarn '%s' for "
		                  "%s= (defined: %s)", m->name, c->line, name,
		                  which ? "weft" : "warp", list);
	}
	*id = (uint8_t)k;
	return LOOM_OK;
}

static int build_table(mapfile *m, loom_design *d)
{
	int rc;

	if (m->n_yarns) {
		if ((rc = loom_design_set_types(d, m->n_yarns)))
			return loom__fail(m->diag, rc, "%s: out of memory", m->name);
		for (uint32_t k = 0; k < m->n_yarns; k++)
			d->types[k] = m->yarns[k].t;
	}
	for (uint32_t k = 0; k < m->n_colours; k++) {
		map_colour *c = &m->colours[k];
		if ((rc = resolve_yarn(m, d, c, 0, &c->warp_id)) ||
		    (rc = resolve_yarn(m, d, c, 1, &c->weft_id)))
			return rc;
	}
	return LOOM_OK;
}

/* ---- step 3: colour keys ------------------------------------------------ */

static void spec_text(const map_colour *c, char *buf, size_t n)
{
	if (c->spec == SPEC_GREY)
		snprintf(buf, n, "grey level %u", c->value);
	else if (c->spec == SPEC_INDEX)
		snprintf(buf, n, "index=%u (#%06x)", c->value, c->key);
	else
		snprintf(buf, n, "#%06x", c->value);
}

static int resolve_keys(mapfile *m, const loom_image *img)
{
	for (uint32_t k = 0; k < m->n_colours; k++) {
		map_colour *c = &m->colours[k];
		char a[48];
		if (c->spec == SPEC_RGB) {
			c->key = c->value;
		} else if (c->spec == SPEC_GREY) {
			c->key = c->value * 0x010101u;
		} else if (c->value >= img->n_palette) {
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: index=%u but the "
			                  "image %s", m->name, c->line, c->value,
			                  img->n_palette ? "palette is shorter" :
			                  "has no palette (index=K needs an indexed PNG)");
		} else {
			const uint8_t *p = img->palette + 3 * c->value;
			c->key = (uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2];
		}
		for (uint32_t j = 0; j < k; j++) {
			if (m->colours[j].key != c->key)
				continue;
			spec_text(c, a, sizeof a);
			return loom__fail(m->diag, LOOM_EFORMAT, "%s:%u: colour %s is "
			                  "already mapped on line %u", m->name, c->line, a,
			                  m->colours[j].line);
		}
	}
	return LOOM_OK;
}

/* ---- step 4: the image's colours ---------------------------------------- */

static uint32_t px_key(const loom_image *img, size_t k)
{
	const uint8_t *p = img->pixels + k * img->channels;
	if (img->channels == 1)
		return p[0] * 0x010101u;
	return (uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2];
}

/* Slot of key in the hash table (its colour's, or the empty one to use). */
static uint32_t find_slot(const img_colours *ic, uint32_t key)
{
	uint32_t s = (key * 2654435761u) >> 24;
	while (ic->slot[s] >= 0 && ic->key[ic->slot[s]] != key)
		s = (s + 1) & (MAP_HASH_SLOTS - 1);
	return s;
}

static void describe(const loom_image *img, uint32_t key, char *buf, size_t n)
{
	int w = img->channels == 1 ? snprintf(buf, n, "grey level %u", key & 255)
	                           : snprintf(buf, n, "#%06x", key);
	for (uint32_t k = 0; k < img->n_palette && w > 0 && (size_t)w < n; k++) {
		const uint8_t *p = img->palette + 3 * k;
		if (((uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2]) == key) {
			snprintf(buf + w, n - (size_t)w, " (palette index %u)", k);
			return;
		}
	}
}

static int scan_colours(mapfile *m, const loom_image *img, img_colours *ic)
{
	size_t n = (size_t)img->width * img->height;
	uint32_t last = 0xffffffffu;

	memset(ic->slot, 0xff, sizeof ic->slot);
	ic->n = 0;
	for (size_t k = 0; k < n; k++) {
		uint32_t key = px_key(img, k), s;
		if (key == last)
			continue;
		last = key;
		s = find_slot(ic, key);
		if (ic->slot[s] >= 0)
			continue;
		if (ic->n == MAP_MAX_IMAGE_COLOURS)
			return loom__fail(m->diag, LOOM_ERANGE, "%s: the image has more "
			                  "than %d colours (the %dth new one is at pixel "
			                  "x=%zu, y=%zu); posterize it to a few colours "
			                  "first, without dithering", m->name,
			                  MAP_MAX_IMAGE_COLOURS, MAP_MAX_IMAGE_COLOURS + 1,
			                  k % img->width, k / img->width);
		ic->slot[s] = (int16_t)ic->n;
		ic->key[ic->n] = key;
		ic->first[ic->n++] = k;
	}
	return LOOM_OK;
}

/* ---- step 5: match colours to lines ------------------------------------- */

static int match_colours(mapfile *m, const loom_image *img, img_colours *ic)
{
	for (uint32_t i = 0; i < ic->n; i++) {
		char a[64];
		ic->map[i] = -1;
		for (uint32_t k = 0; k < m->n_colours; k++)
			if (m->colours[k].key == ic->key[i])
				ic->map[i] = (int)k;
		if (ic->map[i] >= 0) {
			m->colours[ic->map[i]].used = 1;
			continue;
		}
		describe(img, ic->key[i], a, sizeof a);
		return loom__fail(m->diag, LOOM_EFORMAT, "%s: image colour %s (first "
		                  "at pixel x=%zu, y=%zu) has no 'colour' line", m->name,
		                  a, ic->first[i] % img->width, ic->first[i] / img->width);
	}
	for (uint32_t k = 0; k < m->n_colours; k++) {
		char a[48];
		if (m->colours[k].used)
			continue;
		spec_text(&m->colours[k], a, sizeof a);
		loom__warn(m->diag, "%s:%u: colour %s does not occur in the image",
		           m->name, m->colours[k].line, a);
	}
	return LOOM_OK;
}

/* ---- step 6: fill the design -------------------------------------------- */

static void fill(const mapfile *m, const loom_image *img, const img_colours *ic,
                 loom_design *d)
{
	uint32_t last = 0xffffffffu;
	const map_colour *c = NULL;

	for (uint32_t y = 0; y < img->height; y++) {
		for (uint32_t x = 0; x < img->width; x++) {
			size_t k = (size_t)y * img->width + x;
			uint32_t key = px_key(img, k);
			if (key != last) {
				last = key;
				c = &m->colours[ic->map[ic->slot[find_slot(ic, key)]]];
			}
			d->weave[k] = (uint8_t)loom_weave_cell(&c->weave, y, x);
			d->warp_type[k] = c->warp_id;
			d->weft_type[k] = c->weft_id;
		}
	}
}

static int from_image(mapfile *m, const loom_image *img, const char *text,
                      size_t len, loom_design **out)
{
	img_colours *ic = NULL;
	loom_design *d = NULL;
	int rc;

	rc = parse_text(m, text, len);
	if (!rc && (rc = loom_design_new(img->height, img->width, &d)))
		loom__fail(m->diag, rc, "%s: cannot make a %ux%u design: %s", m->name,
		           img->height, img->width, loom_strerror(rc));
	if (!rc && !(ic = malloc(sizeof *ic)))
		rc = loom__fail(m->diag, LOOM_ENOMEM, "%s: out of memory", m->name);
	if (!rc && !(rc = build_table(m, d)) && !(rc = resolve_keys(m, img)) &&
	    !(rc = scan_colours(m, img, ic)) && !(rc = match_colours(m, img, ic)))
		fill(m, img, ic, d);
	free(ic);
	if (rc) {
		loom_design_free(d);
		return rc;
	}
	*out = d;
	return LOOM_OK;
}

LOOM_API int loom_design_from_image(const loom_image *img, const char *map_text,
                                    size_t map_len, const char *map_name,
                                    loom_design **out, loom_diag *diag)
{
	mapfile m;
	int rc;

	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "NULL output");
	*out = NULL;
	if (!img || !img->pixels || img->width == 0 || img->height == 0 ||
	    (img->channels != 1 && img->channels != 3) || (!map_text && map_len) ||
	    (img->n_palette && !img->palette))
		return loom__fail(diag, LOOM_EINVAL, "invalid image or mapping text");
	memset(&m, 0, sizeof m);
	m.name = map_name ? map_name : "(map)";
	m.diag = diag;
	rc = from_image(&m, img, map_text ? map_text : "", map_len, out);
	free(m.yarns);
	free(m.colours);
	return rc;
}
