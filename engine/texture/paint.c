/*
 * engine/texture/paint.c - painted regions of a fabric (loom/paint.h):
 * the paint layer, its text file format, and a volume source that applies
 * it at lookup time over the texture (public texture API only).
 *
 * Memory is O(regions + mask cells), never O(bolt): a lookup scans the
 * regions (their voxel bounds, widened by the blend band, are checked
 * first), and a mask cell is one byte.
 *
 * Lookup of voxel point q (column centre c = floor(q.xy) + 0.5):
 *   1. tx = the texture's sample at q (the unpainted cloth).
 *   2. Structural effects, in file order, for regions containing c:
 *      broken end: a warp voxel becomes empty; missing pick: a weft voxel;
 *      pull: tx = sample(q - lift z) when that is of the kind, else empty
 *      where tx is of the kind; slub: a voxel not of the kind takes the
 *      first of sample(q +- k across the yarn), sample(q +- k z),
 *      k = 1..radius, that is of the kind (the yarn grows by `radius`
 *      voxels across and up/down).
 *   3. Colour effects, in file order, with weight w = 1 inside and
 *      1 - d / blend at distance d (voxels) outside, 0 beyond: yarn:
 *      albedo = lerp(albedo, rgb, w) for voxels of the kind; stain:
 *      albedo *= lerp(1, rgb, strength w) for voxels with yarn.
 */
#include "core/internal.h"
#include "loom/paint.h"
#include "synth/fabric_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct vreg {           /* a region in voxels, for lookups */
	double x0, y0, x1, y1;      /* the rectangle */
	double band;                /* blend in voxels (colour effects) */
	double cw, ch;              /* mask cell size */
} vreg;

struct loom_paint {
	char *fabric;
	loom_paint_region *r;
	uint32_t n, cap;
	/* binding (loom_paint_volume_source) */
	loom_texture *t;
	int filter;
	uint32_t b3;                /* the texture's z extent (bulk reads) */
	vreg *v;
};

static const char *const effect_names[] = {
	NULL, "yarn", "stain", "slub", "broken-end", "missing-pick", "pull", "weave", "fibre"};

LOOM_API const char *loom_paint_effect_name(int effect)
{
	return effect >= 1 && effect <= LOOM_PAINT_FIBRE ? effect_names[effect] : NULL;
}

LOOM_API int loom_paint_effect_parse(const char *name)
{
	for (int e = 1; e <= LOOM_PAINT_FIBRE; e++)
		if (name && !strcmp(name, effect_names[e]))
			return e;
	return 0;
}

LOOM_API int loom_paint_new(const char *fabric, loom_paint **out, loom_diag *diag)
{
	loom_paint *p;

	if (out)
		*out = NULL;
	if (!fabric || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_paint_new: NULL argument");
	if (!fabric[0] || strchr(fabric, '\n') || strchr(fabric, '\r'))
		return loom__fail(diag, LOOM_EINVAL, "paint: the fabric path must be "
		                  "non-empty and on one line");
	p = calloc(1, sizeof *p);
	if (!p || !(p->fabric = strdup(fabric))) {
		free(p);
		return loom__fail(diag, LOOM_ENOMEM, "paint: out of memory");
	}
	*out = p;
	return LOOM_OK;
}

LOOM_API void loom_paint_free(loom_paint *p)
{
	if (!p)
		return;
	for (uint32_t i = 0; i < p->n; i++) {
		free((void *)p->r[i].mask);
		free((void *)p->r[i].weave);
	}
	free(p->r);
	free(p->v);
	free(p->fabric);
	free(p);
}

LOOM_API uint32_t loom_paint_count(const loom_paint *p)
{
	return p ? p->n : 0;
}

LOOM_API const loom_paint_region *loom_paint_get(const loom_paint *p, uint32_t i)
{
	return p && i < p->n ? &p->r[i] : NULL;
}

LOOM_API const char *loom_paint_fabric(const loom_paint *p)
{
	return p ? p->fabric : NULL;
}

static int fin(double x)
{
	return isfinite(x) && fabs(x) < 1e9;
}

LOOM_API int loom_paint_add(loom_paint *p, const loom_paint_region *r, loom_diag *diag)
{
	loom_paint_region c;
	size_t cells;

	if (!p || !r)
		return loom__fail(diag, LOOM_EINVAL, "loom_paint_add: NULL argument");
	if (!loom_paint_effect_name(r->effect))
		return loom__fail(diag, LOOM_EINVAL, "paint: unknown effect %d", r->effect);
	if (!fin(r->x0) || !fin(r->y0) || !fin(r->x1) || !fin(r->y1) ||
	    !(r->x0 < r->x1) || !(r->y0 < r->y1))
		return loom__fail(diag, LOOM_EINVAL, "paint: the rectangle needs finite "
		                  "x0 < x1 and y0 < y1 (mm, |value| < 1e9)");
	if ((r->mask_w == 0) != (r->mask_h == 0) || r->mask_w > LOOM_PAINT_MAX_MASK ||
	    r->mask_h > LOOM_PAINT_MAX_MASK || (r->mask_w && !r->mask))
		return loom__fail(diag, LOOM_EINVAL, "paint: a mask needs 1..%u x 1..%u "
		                  "cells and its data", LOOM_PAINT_MAX_MASK,
		                  LOOM_PAINT_MAX_MASK);
	if (r->kind < 0 || r->kind > LOOM_YARN_WEFT)
		return loom__fail(diag, LOOM_EINVAL, "paint: kind must be any, warp or weft");
	if ((r->effect == LOOM_PAINT_SLUB || r->effect == LOOM_PAINT_PULL) && !r->kind)
		return loom__fail(diag, LOOM_EINVAL, "paint: %s needs kind warp or weft",
		                  loom_paint_effect_name(r->effect));
	for (int k = 0; k < 3; k++)
		if (!(r->rgb[k] >= 0 && r->rgb[k] <= 1))
			return loom__fail(diag, LOOM_EINVAL, "paint: rgb values must be in "
			                  "[0, 1]");
	if (!(r->strength >= 0 && r->strength <= 1))
		return loom__fail(diag, LOOM_EINVAL, "paint: strength must be in [0, 1]");
	if (!(r->blend_mm >= 0 && r->blend_mm <= 1e3))
		return loom__fail(diag, LOOM_EINVAL, "paint: blend must be in [0, 1000] mm");
	if (r->effect == LOOM_PAINT_SLUB && (r->amount < 1 || r->amount > 16))
		return loom__fail(diag, LOOM_EINVAL, "paint: slub radius must be 1..16 voxels");
	if (r->effect == LOOM_PAINT_PULL && (r->amount < 1 || r->amount > 64))
		return loom__fail(diag, LOOM_EINVAL, "paint: pull lift must be 1..64 voxels");
	if (r->effect == LOOM_PAINT_WEAVE &&
	    (r->weave_w < 1 || r->weave_h < 1 || r->weave_w > LOOM_PAINT_MAX_MASK ||
	     r->weave_h > LOOM_PAINT_MAX_MASK || !r->weave))
		return loom__fail(diag, LOOM_EINVAL, "paint: a weave region needs its "
		                  "weave, 1..%u x 1..%u crossings", LOOM_PAINT_MAX_MASK,
		                  LOOM_PAINT_MAX_MASK);
	if ((r->effect == LOOM_PAINT_WEAVE || r->effect == LOOM_PAINT_FIBRE) &&
	    r->band > LOOM_PAINT_MAX_BAND)
		return loom__fail(diag, LOOM_EINVAL, "paint: %s band must be 0..%u "
		                  "crossings", loom_paint_effect_name(r->effect),
		                  LOOM_PAINT_MAX_BAND);
	if (r->effect == LOOM_PAINT_FIBRE &&
	    (r->fibre <= LOOM_FIBRE_DEFAULT || r->fibre >= LOOM_FIBRE_COUNT_))
		return loom__fail(diag, LOOM_EINVAL, "paint: a fibre region needs a "
		                  "material (cotton, silk, ...), got code %d", r->fibre);
	if (p->n >= LOOM_PAINT_MAX_REGIONS)
		return loom__fail(diag, LOOM_ERANGE, "paint: more than %u regions",
		                  LOOM_PAINT_MAX_REGIONS);
	if (p->n == p->cap) {
		uint32_t nc = p->cap ? 2 * p->cap : 8;
		loom_paint_region *nr = realloc(p->r, nc * sizeof *nr);
		if (!nr)
			return loom__fail(diag, LOOM_ENOMEM, "paint: out of memory");
		p->r = nr;
		p->cap = nc;
	}
	c = *r;
	c.mask = NULL;
	c.weave = NULL;
	if (r->effect != LOOM_PAINT_FIBRE)
		c.fibre = 0;
	if (r->effect != LOOM_PAINT_WEAVE) {
		c.weave_w = c.weave_h = 0;
		if (r->effect != LOOM_PAINT_FIBRE)
			c.band = 0;
	} else {
		size_t nw = (size_t)r->weave_w * r->weave_h;
		uint8_t *w = malloc(nw);
		if (!w)
			return loom__fail(diag, LOOM_ENOMEM, "paint: out of memory");
		for (size_t i = 0; i < nw; i++)
			w[i] = r->weave[i] ? 1 : 0;
		c.weave = w;
	}
	if (r->mask_w) {
		uint8_t *m;
		cells = (size_t)r->mask_w * r->mask_h;
		m = malloc(cells);
		if (!m) {
			free((void *)c.weave);
			return loom__fail(diag, LOOM_ENOMEM, "paint: out of memory");
		}
		for (size_t i = 0; i < cells; i++)
			m[i] = r->mask[i] ? 1 : 0;
		c.mask = m;
	}
	p->r[p->n++] = c;
	return LOOM_OK;
}

/* ---- the text format ---------------------------------------------------- */

#define MAGIC "loom-paint 1"  /* version 2 (MAGIC2): weave regions */
#define MAGIC2 "loom-paint 2"
#define MAGIC3 "loom-paint 3" /* version 3: fibre regions */

typedef struct growbuf {
	char *s;
	size_t n, cap;
	int oom;
} growbuf;

static void put(growbuf *b, const char *fmt, ...) LOOM_PRINTF(2, 3);
static void put(growbuf *b, const char *fmt, ...)
{
	va_list ap;
	int k;

	if (b->oom)
		return;
	for (;;) {
		size_t room = b->cap - b->n;
		va_start(ap, fmt);
		k = vsnprintf(b->s ? b->s + b->n : NULL, room, fmt, ap);
		va_end(ap);
		if (k < 0) {
			b->oom = 1;
			return;
		}
		if ((size_t)k < room) {
			b->n += (size_t)k;
			return;
		}
		{
			size_t nc = (b->cap + (size_t)k + 1) * 2;
			char *ns = realloc(b->s, nc);
			if (!ns) {
				b->oom = 1;
				return;
			}
			b->s = ns;
			b->cap = nc;
		}
	}
}

LOOM_API int loom_paint_format(const loom_paint *p, char **text, size_t *len)
{
	growbuf b = {NULL, 0, 0, 0};
	static const char *const kinds[] = {"any", "warp", "weft"};

	if (!p || !text)
		return LOOM_EINVAL;
	int v2 = 0, v3 = 0;

	for (uint32_t i = 0; i < p->n; i++) {
		v2 |= p->r[i].effect == LOOM_PAINT_WEAVE;
		v3 |= p->r[i].effect == LOOM_PAINT_FIBRE;
	}
	put(&b, "%s\nfabric %s\n", v3 ? MAGIC3 : v2 ? MAGIC2 : MAGIC, p->fabric);
	for (uint32_t i = 0; i < p->n; i++) {
		const loom_paint_region *r = &p->r[i];
		put(&b, "region %s %.15g %.15g %.15g %.15g kind=%s rgb=%.6g,%.6g,%.6g "
		    "strength=%.6g blend=%.15g amount=%u",
		    loom_paint_effect_name(r->effect), r->x0, r->y0, r->x1, r->y1,
		    kinds[r->kind], (double)r->rgb[0], (double)r->rgb[1],
		    (double)r->rgb[2], (double)r->strength, r->blend_mm, r->amount);
		if (r->effect == LOOM_PAINT_WEAVE || r->effect == LOOM_PAINT_FIBRE)
			put(&b, " band=%u", r->band);
		if (r->effect == LOOM_PAINT_FIBRE)
			put(&b, " fibre=%s", loom_fibre_name(r->fibre));
		put(&b, "\n");
		if (r->mask_w) {
			put(&b, "mask %u %u\n", r->mask_w, r->mask_h);
			for (uint32_t y = 0; y < r->mask_h; y++) {
				for (uint32_t x = 0; x < r->mask_w && !b.oom; x++)
					put(&b, "%c", r->mask[(size_t)y * r->mask_w + x] ? '#' : '.');
				put(&b, "\n");
			}
		}
		if (r->effect == LOOM_PAINT_WEAVE) {
			put(&b, "weave %u %u\n", r->weave_w, r->weave_h);
			for (uint32_t y = 0; y < r->weave_h; y++) {
				for (uint32_t x = 0; x < r->weave_w && !b.oom; x++)
					put(&b, "%c", r->weave[(size_t)y * r->weave_w + x] ? '#' : '.');
				put(&b, "\n");
			}
		}
	}
	if (b.oom) {
		free(b.s);
		return LOOM_ENOMEM;
	}
	*text = b.s;
	if (len)
		*len = b.n;
	return LOOM_OK;
}

typedef struct lines {
	const char *s, *end;
	const char *name;
	unsigned line;
	loom_diag *diag;
} lines;

/* Next line into buf (without the newline); 0 at the end, -1 too long or
   a NUL byte. */
static int next_line(lines *L, char *buf, size_t cap)
{
	size_t n = 0;

	if (L->s >= L->end)
		return 0;
	L->line++;
	while (L->s < L->end && *L->s != '\n') {
		if (*L->s == 0 || n + 1 >= cap)
			return -1;
		buf[n++] = *L->s++;
	}
	if (L->s < L->end)
		L->s++;
	if (n && buf[n - 1] == '\r')
		n--;
	buf[n] = 0;
	return 1;
}

static int bad(lines *L, int code, const char *what, const char *got)
{
	return loom__fail(L->diag, code, "%s:%u: %s%s%.60s%s", L->name, L->line, what,
	                  got ? ", got '" : "", got ? got : "", got ? "'" : "");
}

static int num(const char *s, double *out)
{
	char *e;
	double v;
	if (!s || !*s)
		return 0;
	v = strtod(s, &e);
	if (*e || !isfinite(v))
		return 0;
	*out = v;
	return 1;
}

/* A region (or fabric line) rejected by loom_paint_add (loom_paint_new):
   its message again with the line. */
static int bad_region(lines *L, int rc)
{
	char msg[sizeof L->diag->message];
	if (!L->diag)
		return bad(L, rc, "bad region", NULL);
	memcpy(msg, L->diag->message, sizeof msg);
	msg[sizeof msg - 1] = 0;
	return bad(L, rc, msg, NULL);
}

/* key=value options of a region line */
static int region_opts(lines *L, char *rest, loom_paint_region *r)
{
	char *save = NULL, *tok;

	for (tok = strtok_r(rest, " \t", &save); tok; tok = strtok_r(NULL, " \t", &save)) {
		char *eq = strchr(tok, '=');
		double v;
		if (!eq)
			return bad(L, LOOM_EFORMAT, "expected key=value", tok);
		*eq++ = 0;
		if (!strcmp(tok, "kind")) {
			if (!strcmp(eq, "any"))
				r->kind = 0;
			else if (!strcmp(eq, "warp"))
				r->kind = LOOM_YARN_WARP;
			else if (!strcmp(eq, "weft"))
				r->kind = LOOM_YARN_WEFT;
			else
				return bad(L, LOOM_EFORMAT, "kind must be any, warp or weft", eq);
		} else if (!strcmp(tok, "rgb")) {
			char *a = eq, *c1 = strchr(a, ','), *c2 = c1 ? strchr(c1 + 1, ',') : NULL;
			double x[3];
			if (!c1 || !c2)
				return bad(L, LOOM_EFORMAT, "rgb needs R,G,B", eq);
			*c1 = *c2 = 0;
			if (!num(a, &x[0]) || !num(c1 + 1, &x[1]) || !num(c2 + 1, &x[2]))
				return bad(L, LOOM_EFORMAT, "rgb needs three numbers", NULL);
			for (int k = 0; k < 3; k++)
				r->rgb[k] = (float)x[k];
		} else if (!strcmp(tok, "band")) {
			if (r->effect != LOOM_PAINT_WEAVE && r->effect != LOOM_PAINT_FIBRE)
				return bad(L, LOOM_EFORMAT, "band goes with 'region weave' or "
				           "'region fibre'", NULL);
			if (!num(eq, &v) || v < 0 || v > LOOM_PAINT_MAX_BAND || v != floor(v))
				return bad(L, LOOM_EFORMAT, "band must be a whole number 0..8", eq);
			r->band = (uint32_t)v;
		} else if (!strcmp(tok, "fibre")) {
			int code;
			if (r->effect != LOOM_PAINT_FIBRE)
				return bad(L, LOOM_EFORMAT, "fibre goes with 'region fibre'", NULL);
			if (loom_fibre_parse(eq, &code) != LOOM_OK || code == LOOM_FIBRE_DEFAULT)
				return bad(L, LOOM_EFORMAT, "fibre must be cotton, rayon, silk, "
				           "polyester, wool, linen, monofilament or none", eq);
			r->fibre = code;
		} else if (!strcmp(tok, "strength") || !strcmp(tok, "blend") ||
		           !strcmp(tok, "amount")) {
			if (!num(eq, &v))
				return bad(L, LOOM_EFORMAT, "expected a finite number", eq);
			if (tok[0] == 's')
				r->strength = (float)v;
			else if (tok[0] == 'b')
				r->blend_mm = v;
			else if (v >= 0 && v <= 1e6 && v == floor(v))
				r->amount = (uint32_t)v;
			else
				return bad(L, LOOM_EFORMAT, "amount must be a whole number", eq);
		} else {
			return bad(L, LOOM_EFORMAT, "unknown key (kind, rgb, strength, "
			           "blend, amount, band, fibre)", tok);
		}
	}
	return LOOM_OK;
}

/* "W H" then H rows of W characters '.' or '#' (a mask or a weave). */
static int read_grid(lines *L, char *buf, size_t cap, char *wh, uint32_t *ow,
                     uint32_t *oh, uint8_t **out, const char *what)
{
	double w, h;
	char *sp = strchr(wh, ' ');
	uint8_t *m;

	if (!sp)
		return bad(L, LOOM_EFORMAT, what, NULL);
	*sp = 0;
	if (!num(wh, &w) || !num(sp + 1, &h) || w != floor(w) || h != floor(h) ||
	    w < 1 || h < 1 || w > LOOM_PAINT_MAX_MASK || h > LOOM_PAINT_MAX_MASK)
		return bad(L, LOOM_EFORMAT, "grid size must be 1..4096 x 1..4096", NULL);
	m = malloc((size_t)w * (size_t)h);
	if (!m)
		return loom__fail(L->diag, LOOM_ENOMEM, "paint: out of memory");
	for (uint32_t y = 0; y < (uint32_t)h; y++) {
		size_t n;
		if (next_line(L, buf, cap) != 1 || (n = strlen(buf)) != (size_t)w ||
		    strspn(buf, ".#") != n) {
			free(m);
			return bad(L, LOOM_EFORMAT, "expected a row of W characters '.' or '#'",
			           NULL);
		}
		for (uint32_t x = 0; x < (uint32_t)w; x++)
			m[(size_t)y * (size_t)w + x] = buf[x] == '#';
	}
	*ow = (uint32_t)w;
	*oh = (uint32_t)h;
	*out = m;
	return LOOM_OK;
}

LOOM_API int loom_paint_parse(const char *text, size_t len, const char *name,
                              loom_paint **out, loom_diag *diag)
{
	lines L = {text, text + len, name ? name : "paint", 0, diag};
	char *buf;
	loom_paint *p = NULL;
	int rc, k, version;
	const size_t cap = LOOM_PAINT_MAX_MASK + 4096;
	loom_paint_region pend;
	uint8_t *pmask = NULL, *pweave = NULL;
	int have_pend = 0;
	unsigned pend_line = 0;
	const size_t ml = sizeof MAGIC - 1;

	if (out)
		*out = NULL;
	if (!out || (!text && len))
		return loom__fail(diag, LOOM_EINVAL, "loom_paint_parse: NULL argument");
	if (len > LOOM_PAINT_MAX_FILE)
		return loom__fail(diag, LOOM_ERANGE, "%s: %zu bytes, more than the %u a "
		                  "paint file may have", L.name, len, LOOM_PAINT_MAX_FILE);
	if (len < ml || (memcmp(text, MAGIC, ml) && memcmp(text, MAGIC2, ml) &&
	                 memcmp(text, MAGIC3, ml)) ||
	    (len > ml && text[ml] != '\n' && text[ml] != '\r'))
		return loom__fail(diag, LOOM_EFORMAT, "%s: not a loom paint file (the "
		                  "first line must be '%s', '%s' or '%s')", L.name, MAGIC,
		                  MAGIC2, MAGIC3);
	version = text[ml - 1] - '0';
	buf = malloc(cap);
	if (!buf)
		return loom__fail(diag, LOOM_ENOMEM, "paint: out of memory");
	memset(&pend, 0, sizeof pend);
	next_line(&L, buf, cap); /* the magic */
	while ((k = next_line(&L, buf, cap)) != 0) {
		char *s = buf;
		if (k < 0) {
			rc = bad(&L, LOOM_EFORMAT, "line too long or holds a NUL byte", NULL);
			goto fail;
		}
		while (*s == ' ' || *s == '\t')
			s++;
		if (!*s || *s == '#')
			continue;
		if (!strncmp(s, "fabric ", 7)) {
			if (p) {
				rc = bad(&L, LOOM_EFORMAT, "a second 'fabric' line", NULL);
				goto fail;
			}
			if ((rc = loom_paint_new(s + 7, &p, diag))) {
				bad_region(&L, rc);
				goto fail;
			}
			continue;
		}
		if (!p) {
			rc = bad(&L, LOOM_EFORMAT, "expected 'fabric PATH' first", s);
			goto fail;
		}
		if (have_pend) {
			/* a region line may be followed by its mask and its weave */
			if (!strncmp(s, "mask ", 5)) {
				if (pmask) {
					rc = bad(&L, LOOM_EFORMAT, "a second 'mask' for one region", NULL);
					goto fail;
				}
				if ((rc = read_grid(&L, buf, cap, s + 5, &pend.mask_w, &pend.mask_h,
				                    &pmask, "expected 'mask W H'")) != LOOM_OK)
					goto fail;
				pend.mask = pmask;
				continue;
			}
			if (!strncmp(s, "weave ", 6)) {
				if (pend.effect != LOOM_PAINT_WEAVE || pweave) {
					rc = bad(&L, LOOM_EFORMAT, "'weave W H' goes once after a "
					         "'region weave' line", NULL);
					goto fail;
				}
				if ((rc = read_grid(&L, buf, cap, s + 6, &pend.weave_w, &pend.weave_h,
				                    &pweave, "expected 'weave W H'")) != LOOM_OK)
					goto fail;
				pend.weave = pweave;
				continue;
			}
			rc = loom_paint_add(p, &pend, diag);
			free(pmask);
			free(pweave);
			pmask = pweave = NULL;
			have_pend = 0;
			if (rc) {
				L.line = pend_line;
				bad_region(&L, rc);
				goto fail;
			}
		}
		if (!strncmp(s, "region ", 7)) {
			char *save = NULL, *tok[5];
			double v[4];
			memset(&pend, 0, sizeof pend);
			pend.strength = 1;
			for (int i = 0; i < 5; i++)
				tok[i] = strtok_r(i ? NULL : s + 7, " \t", &save);
			if (!tok[4] || !(pend.effect = loom_paint_effect_parse(tok[0]))) {
				rc = bad(&L, LOOM_EFORMAT, "expected 'region EFFECT X0 Y0 X1 Y1 "
				         "[key=value...]' with EFFECT yarn, stain, slub, "
				         "broken-end, missing-pick, pull, weave or fibre", tok[0]);
				goto fail;
			}
			if (pend.effect == LOOM_PAINT_WEAVE && version < 2) {
				rc = bad(&L, LOOM_EFORMAT, "a weave region needs version 2 "
				         "(first line '" MAGIC2 "')", NULL);
				goto fail;
			}
			if (pend.effect == LOOM_PAINT_FIBRE && version < 3) {
				rc = bad(&L, LOOM_EFORMAT, "a fibre region needs version 3 "
				         "(first line '" MAGIC3 "')", NULL);
				goto fail;
			}
			for (int i = 0; i < 4; i++)
				if (!num(tok[i + 1], &v[i])) {
					rc = bad(&L, LOOM_EFORMAT, "expected a finite number (mm)",
					         tok[i + 1]);
					goto fail;
				}
			pend.x0 = v[0];
			pend.y0 = v[1];
			pend.x1 = v[2];
			pend.y1 = v[3];
			if ((rc = region_opts(&L, save ? save : (char *)"", &pend)))
				goto fail;
			have_pend = 1;
			pend_line = L.line;
			continue;
		}
		rc = bad(&L, LOOM_EFORMAT, "expected 'region', 'mask' or 'weave'", s);
		goto fail;
	}
	if (!p) {
		rc = bad(&L, LOOM_EFORMAT, "no 'fabric PATH' line", NULL);
		goto fail;
	}
	if (have_pend && (rc = loom_paint_add(p, &pend, diag))) {
		L.line = pend_line;
		bad_region(&L, rc);
		goto fail;
	}
	free(pmask);
	free(pweave);
	free(buf);
	*out = p;
	return LOOM_OK;
fail:
	free(pmask);
	free(pweave);
	free(buf);
	loom_paint_free(p);
	return rc;
}

/* ---- lookups ------------------------------------------------------------ */

/* Distance (voxels) from column centre (cx, cy) to region i's painted
   area: 0 inside. */
static double region_dist_rv(const loom_paint_region *r, const vreg *v, double cx,
                             double cy, double limit)
{
	double dx = fmax(fmax(v->x0 - cx, cx - v->x1), 0.0);
	double dy = fmax(fmax(v->y0 - cy, cy - v->y1), 0.0);
	double best = INFINITY;

	if (dx > limit || dy > limit)
		return INFINITY;
	if (!r->mask_w) {
		if (cx >= v->x0 && cx < v->x1 && cy >= v->y0 && cy < v->y1)
			return 0;
		return sqrt(dx * dx + dy * dy);
	}
	{
		/* the cell of c and the cells within limit, clamped to the mask
		   in floating point before any conversion */
		double fi = floor((cx - v->x0) / v->cw), fj = floor((cy - v->y0) / v->ch);
		double ri = ceil(limit / v->cw) + 1, rj = ceil(limit / v->ch) + 1;
		double mw = (double)r->mask_w, mh = (double)r->mask_h;
		int64_t i0, i1, j0, j1;
		if (fi >= 0 && fj >= 0 && fi < mw && fj < mh &&
		    r->mask[(size_t)fj * r->mask_w + (size_t)fi])
			return 0;
		if (!(limit > 0))
			return INFINITY;
		i0 = (int64_t)fmax(0.0, fmin(mw, fi - ri));
		i1 = (int64_t)fmax(-1.0, fmin(mw - 1, fi + ri));
		j0 = (int64_t)fmax(0.0, fmin(mh, fj - rj));
		j1 = (int64_t)fmax(-1.0, fmin(mh - 1, fj + rj));
		for (int64_t j = j0; j <= j1; j++)
			for (int64_t k = i0; k <= i1; k++) {
				double ax, ay, ex, ey;
				if (!r->mask[(size_t)j * r->mask_w + (size_t)k])
					continue;
				ax = v->x0 + (double)k * v->cw;
				ay = v->y0 + (double)j * v->ch;
				ex = fmax(fmax(ax - cx, cx - (ax + v->cw)), 0.0);
				ey = fmax(fmax(ay - cy, cy - (ay + v->ch)), 0.0);
				best = fmin(best, sqrt(ex * ex + ey * ey));
			}
	}
	return best;
}

static double region_dist(const loom_paint *p, uint32_t i, double cx, double cy,
                          double limit)
{
	return region_dist_rv(&p->r[i], &p->v[i], cx, cy, limit);
}

static void to_voxels(const loom_paint_region *r, double vmm, vreg *v)
{
	v->x0 = r->x0 / vmm;
	v->y0 = r->y0 / vmm;
	v->x1 = r->x1 / vmm;
	v->y1 = r->y1 / vmm;
	v->band = r->blend_mm / vmm;
	v->cw = r->mask_w ? (v->x1 - v->x0) / r->mask_w : 0;
	v->ch = r->mask_h ? (v->y1 - v->y0) / r->mask_h : 0;
}

static int base(const loom_paint *p, const double q[3], loom_texel *o)
{
	return loom_texture_sample(p->t, q, p->filter, o);
}

static void empty(loom_texel *o)
{
	memset(o, 0, sizeof *o);
}

/* The colour effects, in file order, on the albedo of a voxel of `kind`
   (non-zero) in the column with centre (cx, cy). */
static void colour(const loom_paint *p, double cx, double cy, int kind, float albedo[3])
{
	for (uint32_t i = 0; i < p->n; i++) {
		const loom_paint_region *r = &p->r[i];
		double d, w;
		if (r->effect != LOOM_PAINT_YARN && r->effect != LOOM_PAINT_STAIN)
			continue;
		d = region_dist(p, i, cx, cy, p->v[i].band);
		if (d == 0)
			w = 1;
		else if (d < p->v[i].band)
			w = 1 - d / p->v[i].band;
		else
			continue;
		if (r->effect == LOOM_PAINT_YARN) {
			if (r->kind && kind != r->kind)
				continue;
			for (int k = 0; k < 3; k++)
				albedo[k] = (float)((1 - w) * albedo[k] + w * r->rgb[k]);
		} else {
			double sw = w * r->strength;
			for (int k = 0; k < 3; k++)
				albedo[k] = (float)(albedo[k] * (1 - sw + sw * r->rgb[k]));
		}
	}
}

LOOM_API int loom_paint_sample(const loom_paint *p, const double q[3], loom_texel *out)
{
	loom_texel tx;
	double cx, cy;
	int rc;

	if (!p || !q || !out || !p->t)
		return LOOM_EINVAL;
	if ((rc = base(p, q, &tx)) != LOOM_OK) {
		*out = tx;
		return rc;
	}
	cx = floor(q[0]) + 0.5;
	cy = floor(q[1]) + 0.5;
	/* structural effects: inside only, seeing the unpainted cloth */
	for (uint32_t i = 0; i < p->n; i++) {
		const loom_paint_region *r = &p->r[i];
		loom_texel nb;
		if (r->effect == LOOM_PAINT_YARN || r->effect == LOOM_PAINT_STAIN ||
		    r->effect == LOOM_PAINT_WEAVE || r->effect == LOOM_PAINT_FIBRE)
			/* weaves and fibres: in the fabric */
			continue;
		if (region_dist(p, i, cx, cy, 0.0) != 0)
			continue;
		switch (r->effect) {
		case LOOM_PAINT_BROKEN_END:
			if (tx.kind == LOOM_YARN_WARP)
				empty(&tx);
			break;
		case LOOM_PAINT_MISSING_PICK:
			if (tx.kind == LOOM_YARN_WEFT)
				empty(&tx);
			break;
		case LOOM_PAINT_PULL: {
			double s[3] = {q[0], q[1], q[2] - (double)r->amount};
			if ((rc = base(p, s, &nb)) != LOOM_OK)
				return rc;
			if (nb.kind == r->kind)
				tx = nb;
			else if (tx.kind == r->kind)
				empty(&tx);
			break;
		}
		case LOOM_PAINT_SLUB:
			if (tx.kind == r->kind)
				break;
			/* across the yarn: x for warps (they run along y), y for wefts */
			for (uint32_t k = 1; k <= r->amount; k++) {
				int a = r->kind == LOOM_YARN_WARP ? 0 : 1, found = 0;
				for (int d = 0; d < 4 && !found; d++) {
					double s[3] = {q[0], q[1], q[2]};
					if (d < 2)
						s[a] += d ? -(double)k : (double)k;
					else
						s[2] += d == 3 ? -(double)k : (double)k;
					if ((rc = base(p, s, &nb)) != LOOM_OK)
						return rc;
					if (nb.kind == r->kind) {
						tx = nb;
						found = 1;
					}
				}
				if (found)
					break;
			}
			break;
		default:
			break;
		}
	}
	/* colour effects, soft-edged */
	if (tx.kind)
		colour(p, cx, cy, tx.kind, tx.albedo);
	*out = tx;
	return LOOM_OK;
}

static int src_lookup(void *ctx, const double q[3], loom_medium_sample *out)
{
	loom_texel tx;
	int rc = loom_paint_sample(ctx, q, &tx);

	if (rc != LOOM_OK)
		return rc;
	out->density = tx.density;
	memcpy(out->orient, tx.orientation, sizeof out->orient);
	memcpy(out->albedo, tx.albedo, sizeof out->albedo);
	out->alignment = tx.alignment;
	return LOOM_OK;
}

static void *src_thread_init(void *ctx)
{
	return ctx;
}

static void src_thread_done(void *ctx, void *thread_ctx)
{
	(void)thread_ctx;
	loom_texture_thread_done(((loom_paint *)ctx)->t);
}

LOOM_API int loom_paint_bind(loom_paint *p, loom_texture *t, const loom_fabric *f)
{
	loom_fabric_db_identity id;
	double vmm;
	vreg *v;

	if (!p || !t || !f)
		return LOOM_EINVAL;
	if (loom_fabric_get_db_identity(f, &id) != LOOM_OK || !(id.voxel_size_um > 0))
		return LOOM_EINVAL;
	vmm = (double)id.voxel_size_um * 1e-3;
	v = malloc((p->n ? p->n : 1) * sizeof *v);
	if (!v)
		return LOOM_ENOMEM;
	for (uint32_t i = 0; i < p->n; i++)
		to_voxels(&p->r[i], vmm, &v[i]);
	free(p->v);
	p->v = v;
	p->t = t;
	p->b3 = id.block[2];
	p->filter = LOOM_FILTER_NEAREST;
	return LOOM_OK;
}

LOOM_API int loom_paint_volume_source(loom_paint *p, loom_texture *t,
                                      const loom_fabric *f, int filter,
                                      loom_volume_source *src)
{
	int rc;

	if (!p || !t || !f || !src ||
	    (filter != LOOM_FILTER_NEAREST && filter != LOOM_FILTER_TRILINEAR))
		return LOOM_EINVAL;
	if (loom_texture_volume_source(t, f, filter, src) != LOOM_OK)
		return LOOM_EINVAL;
	if ((rc = loom_paint_bind(p, t, f)) != LOOM_OK)
		return rc;
	p->filter = filter;
	src->lookup = src_lookup;
	src->ctx = p;
	src->thread_init = src_thread_init;
	src->thread_done = src_thread_done;
	return LOOM_OK;
}

/* ---- bulk reads ---------------------------------------------------------- */

static int structural(int effect)
{
	return effect == LOOM_PAINT_SLUB || effect == LOOM_PAINT_BROKEN_END ||
	       effect == LOOM_PAINT_MISSING_PICK || effect == LOOM_PAINT_PULL;
}

/* Region i's voxel bounds (widened by its blend band for colours) meet the
   columns [x0, x1) x [y0, y1)? */
static int meets(const loom_paint *p, uint32_t i, double x0, double y0, double x1,
                 double y1)
{
	const vreg *v = &p->v[i];
	double b = structural(p->r[i].effect) ? 0 : v->band;
	/* a column belongs when its centre does: compare centres */
	return x0 + 0.5 < v->x1 + b && x1 - 0.5 >= v->x0 - b &&
	       y0 + 0.5 < v->y1 + b && y1 - 0.5 >= v->y0 - b;
}

LOOM_API unsigned loom_paint_touches(const loom_paint *p, const int64_t lo[2],
                                     const int64_t hi[2])
{
	unsigned m = 0;

	if (!p || !p->v || !lo || !hi)
		return 0;
	for (uint32_t i = 0; i < p->n; i++) {
		int e = p->r[i].effect;
		unsigned bit = structural(e) ? LOOM_PAINT_TOUCH_SHAPE
		             : e == LOOM_PAINT_YARN || e == LOOM_PAINT_STAIN
		             ? LOOM_PAINT_TOUCH_COLOUR : 0;
		if (bit && !(m & bit) &&
		    meets(p, i, (double)lo[0], (double)lo[1], (double)hi[0], (double)hi[1]))
			m |= bit;
	}
	return m;
}

LOOM_API void loom_paint_albedo(const loom_paint *p, int64_t x, int64_t y, int kind,
                                float albedo[3])
{
	if (p && p->v && albedo && kind)
		colour(p, (double)x + 0.5, (double)y + 0.5, kind, albedo);
}

/* One raw voxel (the encodings of loom_texture_region). */
typedef struct rawvox {
	uint8_t d, k, ty, lb;
	uint16_t o;
} rawvox;

/* A voxel column [0, b3) of the unpainted texture, read on demand. */
typedef struct rawcol {
	int64_t x, y;
	int valid;
	uint8_t *d, *k, *ty, *lb;
	uint16_t *o;
} rawcol;

typedef struct bulk {
	const loom_paint *p;
	uint32_t b3;
	rawcol col[1 + 2 * 16];  /* own column, then slub side columns */
	int rc;                  /* the first read error */
} bulk;

static int col_read(bulk *B, rawcol *c, int64_t x, int64_t y)
{
	int64_t lo[3] = {x, y, 0}, hi[3] = {x + 1, y + 1, (int64_t)B->b3};
	loom_texture_region r;
	int rc;

	if (c->valid && c->x == x && c->y == y)
		return LOOM_OK;
	memset(&r, 0, sizeof r);
	r.density = c->d;
	r.orientation = c->o;
	r.kind = c->k;
	r.type = c->ty;
	r.label = c->lb;
	r.layout = LOOM_REGION_Z_FASTEST;
	rc = loom_texture_read_region(B->p->t, lo, hi, &r);
	if (rc != LOOM_OK && B->rc == LOOM_OK)
		B->rc = rc;
	c->x = x;
	c->y = y;
	c->valid = 1;
	return rc;
}

static rawvox col_at(const bulk *B, const rawcol *c, int64_t z)
{
	rawvox v = {0, 0, 0, 0, 0};
	if (z >= 0 && z < (int64_t)B->b3) {
		v.d = c->d[z];
		v.k = c->k[z];
		v.ty = c->ty[z];
		v.lb = c->lb[z];
		v.o = c->o[z];
	}
	return v;
}

/* Voxel (x, y, z) of column c (own, read) with the structural regions
   `idx` (those containing the column) applied, as loom_paint_sample does
   with the nearest filter. */
static rawvox shape_voxel(bulk *B, const uint32_t *idx, uint32_t n, int64_t x,
                          int64_t y, int64_t z)
{
	const loom_paint *p = B->p;
	rawvox tx = col_at(B, &B->col[0], z), none = {0, 0, 0, 0, 0};

	for (uint32_t q = 0; q < n; q++) {
		const loom_paint_region *r = &p->r[idx[q]];
		switch (r->effect) {
		case LOOM_PAINT_BROKEN_END:
			if (tx.k == LOOM_YARN_WARP)
				tx = none;
			break;
		case LOOM_PAINT_MISSING_PICK:
			if (tx.k == LOOM_YARN_WEFT)
				tx = none;
			break;
		case LOOM_PAINT_PULL: {
			rawvox nb = col_at(B, &B->col[0], z - (int64_t)r->amount);
			if (nb.k == r->kind)
				tx = nb;
			else if (tx.k == r->kind)
				tx = none;
			break;
		}
		case LOOM_PAINT_SLUB:
			if (tx.k == r->kind)
				break;
			for (uint32_t k = 1; k <= r->amount; k++) {
				int found = 0;
				for (int d = 0; d < 4 && !found; d++) {
					rawvox nb;
					if (d < 2) {
						/* across the yarn: x for warps, y for wefts */
						int64_t s = d ? -(int64_t)k : (int64_t)k;
						rawcol *c = &B->col[1 + 2 * (k - 1) + (uint32_t)d];
						if (r->kind == LOOM_YARN_WARP)
							col_read(B, c, x + s, y);
						else
							col_read(B, c, x, y + s);
						nb = col_at(B, c, z);
					} else {
						nb = col_at(B, &B->col[0], d == 3 ? z - (int64_t)k
						                                  : z + (int64_t)k);
					}
					if (nb.k == r->kind) {
						tx = nb;
						found = 1;
					}
				}
				if (found)
					break;
			}
			break;
		default:
			break;
		}
	}
	return tx;
}

LOOM_API int loom_paint_read_region(const loom_paint *p, const int64_t lo[3],
                                    const int64_t hi[3], const loom_texture_region *out)
{
	bulk *B = NULL;
	uint32_t *idx = NULL, *here = NULL, n = 0;
	int64_t nx, ny, nz;
	int rc;
	uint8_t *mem = NULL;

	if (!p || !p->t || !p->v || !lo || !hi || !out)
		return LOOM_EINVAL;
	rc = loom_texture_read_region(p->t, lo, hi, out);
	if (rc == LOOM_EINVAL || rc == LOOM_ERANGE)
		return rc;
	nx = hi[0] - lo[0];
	ny = hi[1] - lo[1];
	nz = hi[2] - lo[2];
	if (nx == 0 || ny == 0 || nz == 0)
		return rc;
	/* the structural regions over the box's columns, in file order */
	for (uint32_t i = 0; i < p->n; i++)
		if (structural(p->r[i].effect) &&
		    meets(p, i, (double)lo[0], (double)lo[1], (double)hi[0], (double)hi[1]))
			n++;
	if (n == 0)
		return rc;
	idx = malloc(2 * (size_t)n * sizeof *idx);
	B = calloc(1, sizeof *B);
	mem = malloc((size_t)p->b3 * 6 * (sizeof B->col / sizeof B->col[0]));
	if (!idx || !B || !mem) {
		free(idx);
		free(B);
		free(mem);
		return LOOM_ENOMEM;
	}
	here = idx + n;
	n = 0;
	for (uint32_t i = 0; i < p->n; i++)
		if (structural(p->r[i].effect) &&
		    meets(p, i, (double)lo[0], (double)lo[1], (double)hi[0], (double)hi[1]))
			idx[n++] = i;
	B->p = p;
	B->b3 = p->b3;
	B->rc = rc;
	for (size_t c = 0; c < sizeof B->col / sizeof B->col[0]; c++) {
		uint8_t *m = mem + c * (size_t)p->b3 * 6;
		B->col[c].o = (uint16_t *)(void *)m; /* 6 b3 bytes apart: aligned */
		B->col[c].d = m + 2 * (size_t)p->b3;
		B->col[c].k = m + 3 * (size_t)p->b3;
		B->col[c].ty = m + 4 * (size_t)p->b3;
		B->col[c].lb = m + 5 * (size_t)p->b3;
	}
	for (int64_t y = lo[1]; y < hi[1]; y++)
		for (int64_t x = lo[0]; x < hi[0]; x++) {
			double cx = (double)x + 0.5, cy = (double)y + 0.5;
			uint32_t m = 0;
			for (uint32_t q = 0; q < n; q++)
				if (region_dist(p, idx[q], cx, cy, 0.0) == 0)
					here[m++] = idx[q];
			if (m == 0)
				continue;
			for (size_t c = 0; c < sizeof B->col / sizeof B->col[0]; c++)
				B->col[c].valid = 0;
			col_read(B, &B->col[0], x, y);
			for (int64_t z = lo[2]; z < hi[2]; z++) {
				rawvox v = shape_voxel(B, here, m, x, y, z);
				size_t o = out->layout == LOOM_REGION_Z_FASTEST
				         ? ((size_t)(y - lo[1]) * (size_t)nx + (size_t)(x - lo[0])) *
				           (size_t)nz + (size_t)(z - lo[2])
				         : ((size_t)(z - lo[2]) * (size_t)ny + (size_t)(y - lo[1])) *
				           (size_t)nx + (size_t)(x - lo[0]);
				if (out->density)
					out->density[o] = v.d;
				if (out->orientation)
					out->orientation[o] = v.o;
				if (out->kind)
					out->kind[o] = v.k;
				if (out->type)
					out->type[o] = v.ty;
				if (out->label)
					out->label[o] = v.lb;
			}
		}
	rc = B->rc;
	free(mem);
	free(idx);
	free(B);
	return rc;
}

/* ---- painted weaves ----------------------------------------------------- */

LOOM_API int loom_paint_apply_weaves(const loom_paint *p, loom_fabric **f,
                                     loom_diag *diag)
{
	loom_fabric *cur;
	double vmm;
	int rc;

	if (!p || !f || !*f)
		return loom__fail(diag, LOOM_EINVAL, "loom_paint_apply_weaves: NULL argument");
	cur = *f;
	if (!cur->attached)
		return loom__fail(diag, LOOM_EUNUSABLE, "paint: the fabric is detached");
	vmm = (double)cur->voxel_size_um * 1e-3;
	for (uint32_t i = 0; i < p->n; i++) {
		const loom_paint_region *r = &p->r[i];
		double b1 = cur->b1, b2 = cur->b2, fJ0, fJ1, fI0, fI1;
		int64_t I0, J0;
		uint32_t rows, cols;
		uint8_t *want;
		vreg v;
		loom_fabric *next;

		if (r->effect != LOOM_PAINT_WEAVE && r->effect != LOOM_PAINT_FIBRE)
			continue;
		to_voxels(r, vmm, &v);
		/* crossings whose centre may lie in the rectangle */
		fJ0 = floor(v.x0 / b1 - 0.5);
		fJ1 = ceil(v.x1 / b1 - 0.5);
		fI0 = floor(v.y0 / b2 - 0.5);
		fI1 = ceil(v.y1 / b2 - 0.5);
		if (!(fJ1 - fJ0 + 1 <= LOOM__FABRIC_PATCH_MAX) ||
		    !(fI1 - fI0 + 1 <= LOOM__FABRIC_PATCH_MAX) ||
		    !((fJ1 - fJ0 + 1) * (fI1 - fI0 + 1) <= LOOM__FABRIC_PATCH_MAX) ||
		    fabs(fJ0) > 1e15 || fabs(fI0) > 1e15) {
			rc = loom__fail(diag, LOOM_ERANGE, "paint: %s region %u covers "
			                "%.0f x %.0f crossings; at most %u",
			                loom_paint_effect_name(r->effect), i + 1, fI1 - fI0 + 1,
			                fJ1 - fJ0 + 1, LOOM__FABRIC_PATCH_MAX);
			goto fail;
		}
		I0 = (int64_t)fI0;
		J0 = (int64_t)fJ0;
		rows = (uint32_t)(fI1 - fI0 + 1);
		cols = (uint32_t)(fJ1 - fJ0 + 1);
		want = malloc((size_t)rows * cols);
		if (!want) {
			rc = loom__fail(diag, LOOM_ENOMEM, "paint: out of memory");
			goto fail;
		}
		for (uint32_t a = 0; a < rows; a++)
			for (uint32_t c = 0; c < cols; c++) {
				int64_t I = I0 + a, J = J0 + c;
				double cx = ((double)J + 0.5) * b1, cy = ((double)I + 0.5) * b2;
				uint8_t w = 0;
				int in = region_dist_rv(r, &v, cx, cy, 0.0) == 0;
				if (in && r->effect == LOOM_PAINT_FIBRE) {
					loom__fabric_xing x; /* the weave kept */
					loom__fabric_crossing(cur, I, J, &x);
					w = (uint8_t)(1 + x.warp_over);
				} else if (in) {
					uint64_t wi = (uint64_t)loom_synth_floormod(I, r->weave_h);
					uint64_t wj = (uint64_t)loom_synth_floormod(J, r->weave_w);
					w = (uint8_t)(1 + r->weave[wi * r->weave_w + wj]);
				}
				want[(size_t)a * cols + c] = w;
			}
		next = cur;
		rc = loom__fabric_reweave(&next, I0, J0, rows, cols, want, r->band,
		                          r->kind, r->effect == LOOM_PAINT_FIBRE ? r->fibre : 0,
		                          diag);
		free(want);
		if (rc != LOOM_OK)
			goto fail;
		cur = next;
	}
	*f = cur;
	return LOOM_OK;
fail:
	/* undo the patches made here: free down to the caller's fabric */
	while (cur != *f) {
		loom_fabric *parent = cur->parent;
		cur->parent = NULL;
		{
			loom__fabric_patch *q = (loom__fabric_patch *)cur->patch;
			free(q->src);
			free(q->weave);
			free(q);
		}
		free(cur);
		cur = parent;
	}
	return rc;
}
