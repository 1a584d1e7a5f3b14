/*
 * io/mesh/obj.c - Wavefront OBJ reader: the triangle meshes that shell mapping
 * (engine/render/shell.c) drapes the cloth volume over.  docs/rendering.md has the
 * user's view.
 *
 * One pass over the lines; each statement is a keyword and whitespace-
 * separated tokens.  '#' starts a comment anywhere on a line.
 *
 *     v  x y z [w] [r g b]     position (w and colours ignored)
 *     vt u [v [w]]             texture coordinate (w dropped; v = 0 if absent)
 *     vn x y z                 normal (kept as written)
 *     f  c1 c2 c3 [c4 ...]     polygon, corners "v", "v/vt", "v//vn" or
 *                              "v/vt/vn"; 1-based, negative = relative to
 *                              the last element defined so far
 *     o g s usemtl mtllib l p  ignored silently
 *     anything else            ignored, one warning for the file
 *
 * A polygon c1..cn becomes the fan (c1, ck, ck+1).  Indices must refer to
 * elements defined earlier in the file (the usual practice); every corner
 * of one face uses the same form.  Every problem is an error naming
 * "name:line" and what was expected; nothing is guessed.
 */
#include "core/internal.h"
#include "io/core/file.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define OBJ_MAX_FILE ((size_t)1 << 30)
#define OBJ_NUM_MAX 128 /* longest numeric token */

typedef struct obj_array {
	void *data;
	size_t n, cap, elem; /* elements used, allocated, bytes per element */
} obj_array;

typedef struct obj_parser {
	const char *name;
	loom_diag *diag;
	unsigned line;
	obj_array pos, tex, nrm;      /* float triples / pairs */
	obj_array tv, tt, tn;         /* uint32 per corner */
	int any_vt, any_vn;
	unsigned long unknown;        /* unknown statements */
	unsigned unknown_line;        /* first one */
	char unknown_kw[16];
	obj_array face;               /* corner scratch: 3 uint32 per corner */
} obj_parser;

static int perr(obj_parser *p, int code, const char *fmt, ...) LOOM_PRINTF(3, 4);

static int perr(obj_parser *p, int code, const char *fmt, ...)
{
	char buf[LOOM_DIAG_MSG_MAX];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(buf, sizeof buf, fmt, ap);
	va_end(ap);
	return loom__fail(p->diag, code, "%s:%u: %s", p->name, p->line, buf);
}

/* Append n elements (copied from src) to a; LOOM_ENOMEM on failure. */
static int push(obj_parser *p, obj_array *a, const void *src, size_t n)
{
	if (a->n + n > a->cap) {
		size_t cap = a->cap ? a->cap : 64, bytes;
		void *nd;
		while (cap < a->n + n)
			cap *= 2;
		if (!loom__mul_ok(cap, a->elem, &bytes))
			return perr(p, LOOM_ENOMEM, "out of memory");
		nd = realloc(a->data, bytes);
		if (!nd)
			return perr(p, LOOM_ENOMEM, "out of memory");
		a->data = nd;
		a->cap = cap;
	}
	memcpy((char *)a->data + a->n * a->elem, src, n * a->elem);
	a->n += n;
	return LOOM_OK;
}

/* ---- tokens ------------------------------------------------------------ */

typedef struct tok {
	const char *s;
	size_t n;
} tok;

static int is_space(char c)
{
	return c == ' ' || c == '\t' || c == '\v' || c == '\f';
}

/* Next token of [*cur, end); returns 0 at the end. */
static int next_tok(const char **cur, const char *end, tok *t)
{
	const char *c = *cur;
	while (c < end && is_space(*c))
		c++;
	if (c == end) {
		*cur = c;
		return 0;
	}
	t->s = c;
	while (c < end && !is_space(*c))
		c++;
	t->n = (size_t)(c - t->s);
	*cur = c;
	return 1;
}

static int tok_is(const tok *t, const char *kw)
{
	return t->n == strlen(kw) && memcmp(t->s, kw, t->n) == 0;
}

/* Quote a token for messages (truncated). */
static const char *shown(const tok *t, char buf[48])
{
	size_t n = t->n < 40 ? t->n : 40;
	size_t k;
	for (k = 0; k < n; k++) {
		unsigned char c = (unsigned char)t->s[k];
		buf[k] = (c >= 32 && c < 127) ? (char)c : '?';
	}
	if (t->n > n) {
		memcpy(buf + n, "...", 3);
		n += 3;
	}
	buf[n] = 0;
	return buf;
}

static int parse_float(obj_parser *p, const tok *t, const char *what, float *out)
{
	char buf[OBJ_NUM_MAX + 1], show[48];
	char *endp;
	double v;

	if (t->n > OBJ_NUM_MAX)
		return perr(p, LOOM_EFORMAT, "expected a number for %s, got '%s'",
		            what, shown(t, show));
	memcpy(buf, t->s, t->n);
	buf[t->n] = 0;
	errno = 0;
	v = strtod(buf, &endp);
	if (endp == buf || *endp != 0)
		return perr(p, LOOM_EFORMAT, "expected a number for %s, got '%s'",
		            what, shown(t, show));
	if (!isfinite(v) || fabs(v) > 3.0e38)
		return perr(p, LOOM_EFORMAT, "expected a finite number for %s, got '%s'",
		            what, shown(t, show));
	*out = (float)v;
	return LOOM_OK;
}

/* Read exactly the numbers a statement needs: min..max values. */
static int parse_floats(obj_parser *p, const char **cur, const char *end,
                        const char *kw, int min, int max, float *out, int *count)
{
	static const char *const axis[] = {"1st", "2nd", "3rd", "4th", "5th",
	                                   "6th", "7th"};
	tok t;
	int n = 0, rc;
	char what[32], show[48];

	while (next_tok(cur, end, &t)) {
		if (n == max)
			return perr(p, LOOM_EFORMAT,
			            "'%s' takes at most %d numbers, got more ('%s')", kw,
			            max, shown(&t, show));
		snprintf(what, sizeof what, "the %s value of '%s'", axis[n], kw);
		if ((rc = parse_float(p, &t, what, &out[n])))
			return rc;
		n++;
	}
	if (n < min)
		return perr(p, LOOM_EFORMAT, "'%s' needs at least %d numbers, got %d",
		            kw, min, n);
	*count = n;
	return LOOM_OK;
}

/* Parse a signed decimal index [s, s+n); returns 0 on success. */
static int parse_int(const char *s, size_t n, long long *out)
{
	long long v = 0;
	size_t k = 0;
	int neg = 0;

	if (n > 0 && (s[0] == '-' || s[0] == '+')) {
		neg = s[0] == '-';
		k = 1;
	}
	if (k == n)
		return -1;
	for (; k < n; k++) {
		if (s[k] < '0' || s[k] > '9')
			return -1;
		if (v > 1000000000000LL)
			return -1; /* absurd: reported as out of range by caller */
		v = v * 10 + (s[k] - '0');
	}
	*out = neg ? -v : v;
	return 0;
}

/* Resolve one index of a corner against `count` elements of kind what. */
static int resolve(obj_parser *p, const char *s, size_t n, size_t count,
                   const char *what, const tok *corner, uint32_t *out)
{
	long long v;
	char show[48];

	if (n == 0 || parse_int(s, n, &v) != 0)
		return perr(p, LOOM_EFORMAT,
		            "expected a %s index (integer) in face corner '%s'", what,
		            shown(corner, show));
	if (v == 0)
		return perr(p, LOOM_EFORMAT,
		            "%s index 0 in face corner '%s' (indices start at 1)", what,
		            shown(corner, show));
	if (v < 0)
		v = (long long)count + v + 1;
	if (v < 1 || v > (long long)count)
		return perr(p, LOOM_EFORMAT,
		            "%s index in face corner '%s' out of range: %zu %s defined so far",
		            what, shown(corner, show), count,
		            what[1] == 't' ? "texture coordinates" :
		            what[1] == 'n' ? "normals" : "positions");
	*out = (uint32_t)(v - 1);
	return LOOM_OK;
}

/* Corner forms. */
enum { FORM_V = 0, FORM_VT = 1, FORM_VN = 2, FORM_VTN = 3 };
static const char *const form_name[] = {"v", "v/vt", "v//vn", "v/vt/vn"};

static int parse_corner(obj_parser *p, const tok *t, uint32_t idx[3], int *form)
{
	const char *s = t->s, *e = t->s + t->n;
	const char *s1 = memchr(s, '/', t->n), *s2;
	char show[48];
	int rc;

	idx[1] = idx[2] = LOOM_MESH_NONE;
	if (!s1) {
		*form = FORM_V;
		return resolve(p, s, t->n, p->pos.n / 3, "v", t, &idx[0]);
	}
	s2 = memchr(s1 + 1, '/', (size_t)(e - s1 - 1));
	if (s2 && memchr(s2 + 1, '/', (size_t)(e - s2 - 1)))
		return perr(p, LOOM_EFORMAT,
		            "expected a face corner v, v/vt, v//vn or v/vt/vn, got '%s'",
		            shown(t, show));
	if ((rc = resolve(p, s, (size_t)(s1 - s), p->pos.n / 3, "v", t, &idx[0])))
		return rc;
	if (!s2) {
		*form = FORM_VT;
		return resolve(p, s1 + 1, (size_t)(e - s1 - 1), p->tex.n / 2, "vt", t,
		               &idx[1]);
	}
	if (s2 == s1 + 1) {
		*form = FORM_VN;
	} else {
		*form = FORM_VTN;
		if ((rc = resolve(p, s1 + 1, (size_t)(s2 - s1 - 1), p->tex.n / 2, "vt",
		                  t, &idx[1])))
			return rc;
	}
	return resolve(p, s2 + 1, (size_t)(e - s2 - 1), p->nrm.n / 3, "vn", t,
	               &idx[2]);
}

static int parse_face(obj_parser *p, const char **cur, const char *end)
{
	tok t;
	int form0 = -1, rc;
	size_t nc;
	char show[48];

	p->face.n = 0;
	while (next_tok(cur, end, &t)) {
		uint32_t idx[3];
		int form = FORM_V;
		if ((rc = parse_corner(p, &t, idx, &form)))
			return rc;
		if (form0 < 0)
			form0 = form;
		else if (form != form0)
			return perr(p, LOOM_EFORMAT,
			            "face corners must all have the same form: first is %s, '%s' is %s",
			            form_name[form0], shown(&t, show), form_name[form]);
		if ((rc = push(p, &p->face, idx, 1)))
			return rc;
	}
	nc = p->face.n;
	if (nc < 3)
		return perr(p, LOOM_EFORMAT, "a face needs at least 3 corners, got %zu", nc);
	if (p->tv.n / 3 + (nc - 2) > LOOM_OBJ_MAX_ELEMENTS)
		return perr(p, LOOM_ERANGE, "more than %u triangles",
		            (unsigned)LOOM_OBJ_MAX_ELEMENTS);
	if (form0 == FORM_VT || form0 == FORM_VTN)
		p->any_vt = 1;
	if (form0 == FORM_VN || form0 == FORM_VTN)
		p->any_vn = 1;
	for (size_t k = 1; k + 1 < nc; k++) {
		const uint32_t *c[3];
		const uint32_t *f = p->face.data;
		c[0] = f;
		c[1] = f + 3 * k;
		c[2] = f + 3 * (k + 1);
		for (int j = 0; j < 3; j++) {
			if ((rc = push(p, &p->tv, &c[j][0], 1)) ||
			    (rc = push(p, &p->tt, &c[j][1], 1)) ||
			    (rc = push(p, &p->tn, &c[j][2], 1)))
				return rc;
		}
	}
	return LOOM_OK;
}

static int parse_line(obj_parser *p, const char *cur, const char *end)
{
	tok kw;
	float v[7];
	int n, rc;

	if (!next_tok(&cur, end, &kw))
		return LOOM_OK;
	if (tok_is(&kw, "v")) {
		if ((rc = parse_floats(p, &cur, end, "v", 3, 7, v, &n)))
			return rc;
		if (n == 5)
			return perr(p, LOOM_EFORMAT,
			            "'v' takes x y z [w] or x y z [w] r g b, got 5 numbers");
		if (p->pos.n / 3 >= LOOM_OBJ_MAX_ELEMENTS)
			return perr(p, LOOM_ERANGE, "more than %u positions",
			            (unsigned)LOOM_OBJ_MAX_ELEMENTS);
		return push(p, &p->pos, v, 3);
	}
	if (tok_is(&kw, "vt")) {
		if ((rc = parse_floats(p, &cur, end, "vt", 1, 3, v, &n)))
			return rc;
		if (n == 1)
			v[1] = 0;
		if (p->tex.n / 2 >= LOOM_OBJ_MAX_ELEMENTS)
			return perr(p, LOOM_ERANGE, "more than %u texture coordinates",
			            (unsigned)LOOM_OBJ_MAX_ELEMENTS);
		return push(p, &p->tex, v, 2);
	}
	if (tok_is(&kw, "vn")) {
		if ((rc = parse_floats(p, &cur, end, "vn", 3, 3, v, &n)))
			return rc;
		if (p->nrm.n / 3 >= LOOM_OBJ_MAX_ELEMENTS)
			return perr(p, LOOM_ERANGE, "more than %u normals",
			            (unsigned)LOOM_OBJ_MAX_ELEMENTS);
		return push(p, &p->nrm, v, 3);
	}
	if (tok_is(&kw, "f"))
		return parse_face(p, &cur, end);
	if (tok_is(&kw, "o") || tok_is(&kw, "g") || tok_is(&kw, "s") ||
	    tok_is(&kw, "usemtl") || tok_is(&kw, "mtllib") || tok_is(&kw, "l") ||
	    tok_is(&kw, "p"))
		return LOOM_OK;
	if (p->unknown++ == 0) {
		char show[48];
		p->unknown_line = p->line;
		snprintf(p->unknown_kw, sizeof p->unknown_kw, "%s", shown(&kw, show));
	}
	return LOOM_OK;
}

static void free_parser(obj_parser *p)
{
	free(p->pos.data);
	free(p->tex.data);
	free(p->nrm.data);
	free(p->tv.data);
	free(p->tt.data);
	free(p->tn.data);
	free(p->face.data);
}

LOOM_API void loom_mesh_free(loom_mesh *m)
{
	if (!m)
		return;
	free(m->positions);
	free(m->texcoords);
	free(m->normals);
	free(m->tri_v);
	free(m->tri_vt);
	free(m->tri_vn);
	free(m);
}

/* Move a parser array into a mesh field (an empty array gives NULL). */
static void *take(obj_array *a)
{
	void *d = a->n ? a->data : NULL;
	if (!a->n)
		free(a->data);
	a->data = NULL;
	a->n = a->cap = 0;
	return d;
}

LOOM_API int loom_obj_parse(const char *text, size_t len, const char *name,
                            loom_mesh **out, loom_diag *diag)
{
	obj_parser p;
	const char *c, *end;
	loom_mesh *m;
	int rc = LOOM_OK;

	if (!name)
		name = "obj";
	if (out)
		*out = NULL;
	if ((!text && len) || !out)
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL argument", name);
	memset(&p, 0, sizeof p);
	p.name = name;
	p.diag = diag;
	p.pos.elem = p.tex.elem = p.nrm.elem = sizeof(float);
	p.tv.elem = p.tt.elem = p.tn.elem = sizeof(uint32_t);
	p.face.elem = 3 * sizeof(uint32_t);

	c = text;
	end = text + len;
	while (rc == LOOM_OK && c < end) {
		const char *eol = c, *stop;
		while (eol < end && *eol != '\n' && *eol != '\r')
			eol++;
		p.line++;
		stop = memchr(c, '#', (size_t)(eol - c));
		rc = parse_line(&p, c, stop ? stop : eol);
		if (eol < end && *eol == '\r' && eol + 1 < end && eol[1] == '\n')
			eol++;
		c = eol + 1;
	}
	if (rc) {
		free_parser(&p);
		return rc;
	}
	if (p.unknown)
		loom__warn(diag, "%s:%u: %lu unknown statement%s ignored (first '%s')",
		           name, p.unknown_line, p.unknown, p.unknown == 1 ? "" : "s",
		           p.unknown_kw);

	m = calloc(1, sizeof *m);
	if (!m) {
		free_parser(&p);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	}
	m->n_positions = (uint32_t)(p.pos.n / 3);
	m->n_texcoords = (uint32_t)(p.tex.n / 2);
	m->n_normals = (uint32_t)(p.nrm.n / 3);
	m->n_triangles = (uint32_t)(p.tv.n / 3);
	m->positions = take(&p.pos);
	m->texcoords = take(&p.tex);
	m->normals = take(&p.nrm);
	m->tri_v = take(&p.tv);
	if (p.any_vt)
		m->tri_vt = take(&p.tt);
	if (p.any_vn)
		m->tri_vn = take(&p.tn);
	free_parser(&p);
	*out = m;
	return LOOM_OK;
}

LOOM_API int loom_obj_read(const char *path, loom_mesh **out, loom_diag *diag)
{
	uint8_t *data;
	size_t len;
	int rc;

	if (out)
		*out = NULL;
	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_obj_read: NULL argument");
	if ((rc = loom__read_file_checked(path, OBJ_MAX_FILE, "OBJ", loom__head_text,
	                                  &data, &len, diag)))
		return rc;
	rc = loom_obj_parse((const char *)data, len, path, out, diag);
	free(data);
	return rc;
}
