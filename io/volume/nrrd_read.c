/*
 * io/volume/nrrd_read.c - NRRD reader (NRRD0001 .. NRRD0005), attached or
 * detached, raw / gzip / ascii encodings, returning float volumes.
 *
 * The header is text: a magic line, then "field: description" lines,
 * "key:=value" lines and "#" comments, ended by an empty line when the data
 * follow in the same file (attached) or by the end of the file when a
 * "data file" field names where the data are (detached).  Axis 0 is the
 * fastest-varying.  loom maps the axes onto its x, y, z (and a leading
 * value axis) as described in loom/volio.h; everything else the format can
 * say (kinds, centerings, measurement frames, ...) is accepted and ignored
 * so that files from unu, ParaView and 3D Slicer read.
 *
 * Raw data are read by io/volume/raw_read.c (same size checks); gzip data are
 * inflated with libdeflate into a buffer of exactly the declared size
 * (bounded by the 1032:1 limit of deflate, so a small file cannot ask for
 * a huge buffer); ascii data are parsed number by number.
 */
#include "core/internal.h"
#include "io/core/file.h"

#include <errno.h>
#include <libdeflate.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define HEADER_MAX (1u << 20)  /* longest header loom reads */
#define FIELD_LINE_MAX 4096    /* longest field line loom parses */
#define DEFLATE_MAX_RATIO 1032u

/* ---- small text helpers ---------------------------------------------------- */

static const char *skip_ws(const char *s)
{
	while (*s == ' ' || *s == '\t')
		s++;
	return s;
}

/* Split s into whitespace-separated tokens, up to max; returns count
   (max + 1 when there are more).  Modifies s. */
static unsigned split_ws(char *s, char **tok, unsigned max)
{
	unsigned n = 0;
	for (;;) {
		while (*s == ' ' || *s == '\t')
			s++;
		if (!*s)
			return n;
		if (n == max)
			return max + 1;
		tok[n++] = s;
		while (*s && *s != ' ' && *s != '\t')
			s++;
		if (*s)
			*s++ = 0;
	}
}

static int parse_double(const char *s, double *out)
{
	char *end;
	errno = 0;
	*out = strtod(s, &end);
	if (end == s || *end)
		return 0;
	return 1;
}

static int parse_i64(const char *s, int64_t *out)
{
	char *end;
	long long v;
	errno = 0;
	v = strtoll(s, &end, 10);
	if (end == s || *end || errno)
		return 0;
	*out = v;
	return 1;
}

/* Parse "(a,b,c)" with n components (spaces tolerated). */
static int parse_vector(const char *s, double *v, unsigned n)
{
	s = skip_ws(s);
	if (*s++ != '(')
		return 0;
	for (unsigned i = 0; i < n; i++) {
		char *end;
		s = skip_ws(s);
		v[i] = strtod(s, &end);
		if (end == s)
			return 0;
		s = skip_ws(end);
		if (i + 1 < n && *s++ != ',')
			return 0;
	}
	if (*s++ != ')')
		return 0;
	return *skip_ws(s) == 0;
}

/* ---- header parsing --------------------------------------------------------- */

typedef struct hp {
	const char *name;
	unsigned line;
	loom_diag *diag;
	loom_nrrd_info *info;
	int have_type, have_dim, have_sizes, have_encoding;
	int kinds_nonspatial0; /* kinds given and axis 0 is a value axis */
} hp;

static int type_from_nrrd(const char *s, int *type)
{
	static const struct {
		const char *name;
		int type;
	} tab[] = {
		{"signed char", LOOM_SCALAR_I8}, {"int8", LOOM_SCALAR_I8},
		{"int8_t", LOOM_SCALAR_I8}, {"char", LOOM_SCALAR_I8},
		{"uchar", LOOM_SCALAR_U8}, {"unsigned char", LOOM_SCALAR_U8},
		{"uint8", LOOM_SCALAR_U8}, {"uint8_t", LOOM_SCALAR_U8},
		{"short", LOOM_SCALAR_I16}, {"short int", LOOM_SCALAR_I16},
		{"signed short", LOOM_SCALAR_I16}, {"signed short int", LOOM_SCALAR_I16},
		{"int16", LOOM_SCALAR_I16}, {"int16_t", LOOM_SCALAR_I16},
		{"ushort", LOOM_SCALAR_U16}, {"unsigned short", LOOM_SCALAR_U16},
		{"unsigned short int", LOOM_SCALAR_U16}, {"uint16", LOOM_SCALAR_U16},
		{"uint16_t", LOOM_SCALAR_U16}, {"int", LOOM_SCALAR_I32},
		{"signed int", LOOM_SCALAR_I32}, {"int32", LOOM_SCALAR_I32},
		{"int32_t", LOOM_SCALAR_I32}, {"uint", LOOM_SCALAR_U32},
		{"unsigned int", LOOM_SCALAR_U32}, {"uint32", LOOM_SCALAR_U32},
		{"uint32_t", LOOM_SCALAR_U32}, {"float", LOOM_SCALAR_F32},
		{"double", LOOM_SCALAR_F64},
	};
	static const char *const unsupported[] = {
		"longlong", "long long", "long long int", "signed long long",
		"signed long long int", "int64", "int64_t", "ulonglong",
		"unsigned long long", "unsigned long long int", "uint64", "uint64_t",
		"block"};
	for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
		if (loom__strieq(s, tab[i].name)) {
			*type = tab[i].type;
			return LOOM_OK;
		}
	for (size_t i = 0; i < sizeof unsupported / sizeof unsupported[0]; i++)
		if (loom__strieq(s, unsupported[i]))
			return LOOM_EUNSUPPORTED;
	return LOOM_EFORMAT;
}

static int is_nonspatial_kind(const char *k)
{
	static const char *const spatial[] = {"domain", "space", "time", "none",
	                                      "???"};
	for (size_t i = 0; i < sizeof spatial / sizeof spatial[0]; i++)
		if (loom__strieq(k, spatial[i]))
			return 0;
	return 1;
}

static int space_dim_of(const char *s)
{
	static const char *const three[] = {
		"right-anterior-superior", "RAS", "left-anterior-superior", "LAS",
		"left-posterior-superior", "LPS", "scanner-xyz", "3D-right-handed",
		"3D-left-handed"};
	static const char *const four[] = {
		"right-anterior-superior-time", "RAST", "left-anterior-superior-time",
		"LAST", "left-posterior-superior-time", "LPST", "scanner-xyz-time",
		"3D-right-handed-time", "3D-left-handed-time"};
	for (size_t i = 0; i < sizeof three / sizeof three[0]; i++)
		if (loom__strieq(s, three[i]))
			return 3;
	for (size_t i = 0; i < sizeof four / sizeof four[0]; i++)
		if (loom__strieq(s, four[i]))
			return 4;
	return 0;
}

#define HFAIL(P, CODE, ...) hfail((P), (CODE), __VA_ARGS__)

static int hfail(hp *P, int code, const char *fmt, ...) LOOM_PRINTF(3, 4);
static int hfail(hp *P, int code, const char *fmt, ...)
{
	char msg[LOOM_DIAG_MSG_MAX];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof msg, fmt, ap);
	va_end(ap);
	return loom__fail(P->diag, code, "%s:%u: %s", P->name, P->line, msg);
}

/* Require the dimension before a per-axis field. */
static int need_dim(hp *P, const char *field)
{
	if (!P->have_dim)
		return HFAIL(P, LOOM_EFORMAT, "\"%s\" before \"dimension\"", field);
	return LOOM_OK;
}

static int per_axis_tokens(hp *P, const char *field, char *val, char **tok)
{
	unsigned n;
	int rc = need_dim(P, field);
	if (rc)
		return rc;
	n = split_ws(val, tok, P->info->dimension);
	if (n != P->info->dimension)
		return HFAIL(P, LOOM_EFORMAT, "\"%s\" needs %u values (dimension), got %s%u",
		             field, P->info->dimension,
		             n > P->info->dimension ? "more than " : "",
		             n > P->info->dimension ? P->info->dimension : n);
	return LOOM_OK;
}

/* One "field: value" line.  field is lowercased, val NUL-terminated and
   trimmed. */
static int field_line(hp *P, const char *field, char *val)
{
	loom_nrrd_info *I = P->info;
	char *tok[LOOM_NRRD_MAX_DIM + 1];
	int rc;

	if (!strcmp(field, "type")) {
		rc = type_from_nrrd(val, &I->type);
		if (rc == LOOM_EUNSUPPORTED)
			return HFAIL(P, rc, "type \"%s\" is not supported (loom reads 8, "
			             "16 and 32-bit integers, float and double)", val);
		if (rc)
			return HFAIL(P, rc, "unknown type \"%s\"", val);
		P->have_type = 1;
	} else if (!strcmp(field, "dimension")) {
		int64_t d;
		if (P->have_dim)
			return HFAIL(P, LOOM_EFORMAT, "\"dimension\" given twice");
		if (!parse_i64(val, &d) || d < 1 || d > 16)
			return HFAIL(P, LOOM_EFORMAT, "dimension must be 1..16, got \"%s\"",
			             val);
		if (d > LOOM_NRRD_MAX_DIM)
			return HFAIL(P, LOOM_EUNSUPPORTED,
			             "dimension %d: loom reads at most %d axes (x, y, z "
			             "and a value axis)", (int)d, LOOM_NRRD_MAX_DIM);
		I->dimension = (uint32_t)d;
		P->have_dim = 1;
	} else if (!strcmp(field, "sizes")) {
		if ((rc = per_axis_tokens(P, field, val, tok)))
			return rc;
		for (unsigned a = 0; a < I->dimension; a++) {
			int64_t v;
			if (!parse_i64(tok[a], &v) || v < 1)
				return HFAIL(P, LOOM_EFORMAT,
				             "size of axis %u must be a positive integer, got "
				             "\"%s\"", a, tok[a]);
			I->sizes[a] = (uint64_t)v;
		}
		P->have_sizes = 1;
	} else if (!strcmp(field, "spacings")) {
		if ((rc = per_axis_tokens(P, field, val, tok)))
			return rc;
		for (unsigned a = 0; a < I->dimension; a++)
			if (!parse_double(tok[a], &I->spacings[a]))
				return HFAIL(P, LOOM_EFORMAT,
				             "spacing of axis %u is not a number: \"%s\"", a,
				             tok[a]);
	} else if (!strcmp(field, "kinds")) {
		if ((rc = per_axis_tokens(P, field, val, tok)))
			return rc;
		P->kinds_nonspatial0 = is_nonspatial_kind(tok[0]);
	} else if (!strcmp(field, "space")) {
		int d = space_dim_of(val);
		if (!d)
			return HFAIL(P, LOOM_EFORMAT, "unknown space \"%s\"", val);
		if (I->space_dim && I->space_dim != (uint32_t)d)
			return HFAIL(P, LOOM_EFORMAT, "space \"%s\" disagrees with the "
			             "space dimension %u", val, I->space_dim);
		I->space_dim = (uint32_t)d;
	} else if (!strcmp(field, "space dimension")) {
		int64_t d;
		if (!parse_i64(val, &d) || d < 1 || d > 4)
			return HFAIL(P, LOOM_EFORMAT, "space dimension must be 1..4, got "
			             "\"%s\"", val);
		if (I->space_dim && I->space_dim != (uint32_t)d)
			return HFAIL(P, LOOM_EFORMAT, "space dimension %d disagrees with "
			             "the space (%u)", (int)d, I->space_dim);
		I->space_dim = (uint32_t)d;
	} else if (!strcmp(field, "space directions")) {
		if ((rc = per_axis_tokens(P, field, val, tok)))
			return rc;
		if (!I->space_dim)
			return HFAIL(P, LOOM_EFORMAT, "\"space directions\" before "
			             "\"space\" or \"space dimension\"");
		for (unsigned a = 0; a < I->dimension; a++) {
			double v[4] = {0, 0, 0, 0};
			if (loom__strieq(tok[a], "none")) {
				for (int c = 0; c < 3; c++)
					I->directions[a][c] = NAN;
				continue;
			}
			if (!parse_vector(tok[a], v, I->space_dim))
				return HFAIL(P, LOOM_EFORMAT,
				             "space direction of axis %u must be \"none\" or a "
				             "vector of %u numbers like (1,0,0), got \"%s\"",
				             a, I->space_dim, tok[a]);
			for (int c = 0; c < 3; c++)
				I->directions[a][c] = v[c];
		}
		I->has_directions = 1;
	} else if (!strcmp(field, "space origin")) {
		double v[4] = {0, 0, 0, 0};
		if (!I->space_dim)
			return HFAIL(P, LOOM_EFORMAT, "\"space origin\" before \"space\" "
			             "or \"space dimension\"");
		if (!parse_vector(val, v, I->space_dim))
			return HFAIL(P, LOOM_EFORMAT,
			             "space origin must be a vector of %u numbers like "
			             "(0,0,0), got \"%s\"", I->space_dim, val);
		for (int c = 0; c < 3; c++)
			I->space_origin[c] = v[c];
		I->has_origin = 1;
	} else if (!strcmp(field, "endian")) {
		if (loom__strieq(val, "little"))
			I->big_endian = 0;
		else if (loom__strieq(val, "big"))
			I->big_endian = 1;
		else
			return HFAIL(P, LOOM_EFORMAT, "endian must be little or big, got "
			             "\"%s\"", val);
	} else if (!strcmp(field, "encoding")) {
		if (loom__strieq(val, "raw"))
			I->encoding = LOOM_NRRD_RAW;
		else if (loom__strieq(val, "gzip") || loom__strieq(val, "gz"))
			I->encoding = LOOM_NRRD_GZIP;
		else if (loom__strieq(val, "ascii") || loom__strieq(val, "text") ||
		         loom__strieq(val, "txt"))
			I->encoding = LOOM_NRRD_ASCII;
		else if (loom__strieq(val, "hex") || loom__strieq(val, "bzip2") ||
		         loom__strieq(val, "bz2"))
			return HFAIL(P, LOOM_EUNSUPPORTED, "encoding \"%s\" is not "
			             "supported (loom reads raw, gzip and ascii)", val);
		else
			return HFAIL(P, LOOM_EFORMAT, "unknown encoding \"%s\"", val);
		P->have_encoding = 1;
	} else if (!strcmp(field, "data file") || !strcmp(field, "datafile")) {
		unsigned n = 0;
		char copy[FIELD_LINE_MAX];
		snprintf(copy, sizeof copy, "%s", val);
		n = split_ws(copy, tok, 3);
		if (n >= 1 && loom__strieq(tok[0], "LIST"))
			return HFAIL(P, LOOM_EUNSUPPORTED, "\"data file: LIST\" (several "
			             "data files) is not supported");
		if (n >= 3 && strchr(tok[0], '%'))
			return HFAIL(P, LOOM_EUNSUPPORTED, "numbered data files (\"%s\") "
			             "are not supported", val);
		if (!*val)
			return HFAIL(P, LOOM_EFORMAT, "empty data file name");
		if (strlen(val) >= sizeof I->data_file)
			return HFAIL(P, LOOM_ERANGE, "data file name longer than %d bytes",
			             LOOM_NRRD_PATH_MAX - 1);
		strcpy(I->data_file, val);
	} else if (!strcmp(field, "line skip") || !strcmp(field, "lineskip")) {
		if (!parse_i64(val, &I->line_skip) || I->line_skip < 0)
			return HFAIL(P, LOOM_EFORMAT, "line skip must be >= 0, got \"%s\"",
			             val);
	} else if (!strcmp(field, "byte skip") || !strcmp(field, "byteskip")) {
		if (!parse_i64(val, &I->byte_skip) || I->byte_skip < -1)
			return HFAIL(P, LOOM_EFORMAT, "byte skip must be >= -1, got \"%s\"",
			             val);
	} else {
		static const char *const ignored[] = {
			"content", "block size", "blocksize", "min", "max", "old min",
			"oldmin", "old max", "oldmax", "number", "centers", "centerings",
			"labels", "units", "axis mins", "axismins", "axis maxs",
			"axismaxs", "thicknesses", "sample units", "sampleunits",
			"space units", "measurement frame"};
		for (size_t i = 0; i < sizeof ignored / sizeof ignored[0]; i++)
			if (!strcmp(field, ignored[i]))
				return LOOM_OK;
		loom__warn(P->diag, "%s:%u: unknown field \"%s\" ignored", P->name,
		           P->line, field);
	}
	return LOOM_OK;
}

/* Work out nx, ny, nz, channels, spacing and origin. */
static int derive_layout(hp *P)
{
	loom_nrrd_info *I = P->info;
	uint32_t first = 0, n_spatial;
	uint32_t res[3] = {1, 1, 1};
	int nonaligned = 0;

	if (I->dimension == 4)
		first = 1;
	else if (I->dimension == 3 &&
	         (P->kinds_nonspatial0 ||
	          (I->has_directions && isnan(I->directions[0][0]))))
		first = 1;
	I->channel_axis = first;
	n_spatial = I->dimension - first;
	for (uint32_t a = 0; a < I->dimension; a++)
		if (I->sizes[a] > INT32_MAX)
			return HFAIL(P, LOOM_ERANGE, "size %llu of axis %u is over loom's "
			             "limit of 2147483647", (unsigned long long)I->sizes[a],
			             a);
	I->channels = first ? (uint32_t)I->sizes[0] : 1;
	for (uint32_t s = 0; s < 3; s++) {
		uint32_t a = first + s;
		double sp = NAN;
		I->spacing[s] = 1.0;
		I->origin[s] = I->has_origin ? I->space_origin[s] : 0.0;
		if (s >= n_spatial)
			continue;
		res[s] = (uint32_t)I->sizes[a];
		if (isfinite(I->spacings[a]) && I->spacings[a] != 0.0)
			sp = fabs(I->spacings[a]);
		else if (I->has_directions && !isnan(I->directions[a][0])) {
			const double *d = I->directions[a];
			sp = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
			for (uint32_t c = 0; c < 3; c++)
				if (c != s && d[c] != 0.0)
					nonaligned = 1;
			if (!(sp > 0.0) || !isfinite(sp))
				sp = NAN;
		}
		if (!isnan(sp))
			I->spacing[s] = sp;
	}
	if (nonaligned)
		loom__warn(P->diag, "%s: space directions are not axis-aligned; loom "
		           "uses their lengths as voxel sizes", P->name);
	I->nx = res[0];
	I->ny = res[1];
	I->nz = res[2];
	return LOOM_OK;
}

LOOM_API int loom_nrrd_parse_header(const char *text, size_t len,
                                    const char *name, loom_nrrd_info *info,
                                    loom_diag *diag)
{
	hp P;
	size_t pos = 0;
	int ended = 0, rc;
	char buf[FIELD_LINE_MAX];

	if (!name)
		name = "nrrd";
	memset(&P, 0, sizeof P);
	P.name = name;
	P.diag = diag;
	P.info = info;
	P.line = 1;
	if (!info || (!text && len))
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL argument", name);
	memset(info, 0, sizeof *info);
	info->big_endian = -1;
	for (int a = 0; a < LOOM_NRRD_MAX_DIM; a++) {
		info->spacings[a] = NAN;
		for (int c = 0; c < 3; c++)
			info->directions[a][c] = NAN;
	}
	/* magic */
	if (len < 4 || memcmp(text, "NRRD", 4) != 0)
		return HFAIL(&P, LOOM_EFORMAT, "expected magic \"NRRD000N\"");
	if (len < 9 || memcmp(text + 4, "000", 3) != 0 || text[7] < '1' ||
	    text[7] > '9' || (text[8] != '\n' && text[8] != '\r'))
		return HFAIL(&P, LOOM_EFORMAT, "expected magic \"NRRD0001\" .. "
		             "\"NRRD0005\" on a line of its own");
	if (text[7] > '5')
		return HFAIL(&P, LOOM_EVERSION, "NRRD000%c is newer than loom reads "
		             "(NRRD0001 .. NRRD0005)", text[7]);
	info->version = text[7] - '0';
	pos = text[8] == '\r' && len > 9 && text[9] == '\n' ? 10 : 9;

	while (pos < len) {
		const char *line = text + pos;
		const char *nl = memchr(line, '\n', len - pos);
		size_t n = nl ? (size_t)(nl - line) : len - pos;
		const char *colon;
		size_t next = pos + n + (nl ? 1 : 0);

		P.line++;
		if (n && line[n - 1] == '\r')
			n--;
		if (n == 0) {
			if (!nl && next == len)
				break; /* stray "\r" at the very end */
			info->header_bytes = next;
			ended = 1;
			break;
		}
		pos = next;
		if (line[0] == '#')
			continue;
		colon = memchr(line, ':', n);
		if (!colon)
			return HFAIL(&P, LOOM_EFORMAT, "expected \"field: value\" or "
			             "\"key:=value\", found no ':'");
		if ((size_t)(colon - line) + 1 < n && colon[1] == '=')
			continue; /* key:=value */
		if ((size_t)(colon - line) + 1 >= n || colon[1] != ' ') {
			if ((size_t)(colon - line) + 1 >= n)
				return HFAIL(&P, LOOM_EFORMAT, "field \"%.*s\" has no value",
				             (int)(colon - line), line);
			return HFAIL(&P, LOOM_EFORMAT, "expected \": \" or \":=\" after "
			             "\"%.*s\"", (int)(colon - line), line);
		}
		if (n >= sizeof buf)
			return HFAIL(&P, LOOM_ERANGE, "field line longer than %d bytes",
			             FIELD_LINE_MAX - 1);
		{
			size_t flen = (size_t)(colon - line);
			char *field = buf, *val;
			char *end;
			memcpy(buf, line, n);
			buf[n] = 0;
			if (memchr(buf, 0, n))
				return HFAIL(&P, LOOM_EFORMAT, "NUL byte in header line");
			buf[flen] = 0;
			for (size_t i = 0; i < flen; i++)
				if (field[i] >= 'A' && field[i] <= 'Z')
					field[i] = (char)(field[i] - 'A' + 'a');
			val = (char *)skip_ws(buf + flen + 1);
			end = val + strlen(val);
			while (end > val && (end[-1] == ' ' || end[-1] == '\t'))
				*--end = 0;
			rc = field_line(&P, field, val);
			if (rc)
				return rc;
		}
	}
	if (!ended)
		info->header_bytes = len;
	P.line++;
	if (!P.have_type)
		return HFAIL(&P, LOOM_EFORMAT, "header has no \"type\" field");
	if (!P.have_dim)
		return HFAIL(&P, LOOM_EFORMAT, "header has no \"dimension\" field");
	if (!P.have_sizes)
		return HFAIL(&P, LOOM_EFORMAT, "header has no \"sizes\" field");
	if (!P.have_encoding)
		return HFAIL(&P, LOOM_EFORMAT, "header has no \"encoding\" field");
	if (info->big_endian < 0 && loom_scalar_size(info->type) > 1 &&
	    info->encoding != LOOM_NRRD_ASCII)
		return HFAIL(&P, LOOM_EFORMAT, "header has no \"endian\" field, "
		             "needed for %s %s data", loom_scalar_name(info->type),
		             info->encoding == LOOM_NRRD_GZIP ? "gzip" : "raw");
	if (!ended && !info->data_file[0])
		return HFAIL(&P, LOOM_ETRUNCATED, "no empty line ends the header and "
		             "no \"data file\" is named: where are the data?");
	if (info->byte_skip == -1 && info->encoding != LOOM_NRRD_RAW)
		return HFAIL(&P, LOOM_EFORMAT, "byte skip -1 is only allowed with raw "
		             "encoding");
	return derive_layout(&P);
}

/* ---- data ------------------------------------------------------------------ */

static void params_from_info(const loom_nrrd_info *I, loom_raw_params *p)
{
	loom_raw_params init = LOOM_RAW_PARAMS_INIT;
	*p = init;
	p->nx = I->nx;
	p->ny = I->ny;
	p->nz = I->nz;
	p->channels = I->channels;
	p->type = I->type;
	p->big_endian = I->big_endian == 1;
	for (int a = 0; a < 3; a++) {
		p->spacing[a] = I->spacing[a];
		p->origin[a] = I->origin[a];
	}
	if (I->byte_skip == -1)
		p->flags |= LOOM_RAW_DATA_AT_END;
}

static uint64_t data_bytes_of(const loom_nrrd_info *I)
{
	/* each size <= 2^31 and dimension <= 4 with the value axis counted
	   once: the product can exceed 64 bits, so saturate */
	uint64_t n = loom_scalar_size(I->type);
	uint64_t dims[4] = {I->nx, I->ny, I->nz, I->channels};
	for (int i = 0; i < 4; i++) {
		if (n > (UINT64_MAX >> 2) / dims[i])
			return UINT64_MAX;
		n *= dims[i];
	}
	return n;
}

/* Skip line_skip lines in buf from *pos. */
static int skip_lines(const uint8_t *buf, size_t len, size_t *pos,
                      int64_t lines, const char *name, loom_diag *diag)
{
	for (int64_t i = 0; i < lines; i++) {
		const uint8_t *nl = *pos < len ? memchr(buf + *pos, '\n', len - *pos)
		                               : NULL;
		if (!nl)
			return loom__fail(diag, LOOM_ETRUNCATED,
			                  "%s: byte %zu: end of data while skipping line "
			                  "%lld of %lld (line skip)",
			                  name, len, (long long)i + 1, (long long)lines);
		*pos = (size_t)(nl - buf) + 1;
	}
	return LOOM_OK;
}

static int decode_gzip(const uint8_t *src, size_t len, const char *name,
                       const loom_nrrd_info *I, size_t max_bytes,
                       loom_volbuf **out, loom_diag *diag)
{
	uint64_t need = data_bytes_of(I), total;
	uint64_t skip = I->byte_skip > 0 ? (uint64_t)I->byte_skip : 0;
	struct libdeflate_decompressor *d;
	enum libdeflate_result res;
	size_t in_used = 0, out_got = 0;
	uint8_t *raw;
	loom_raw_params p;
	int rc;

	if (need == UINT64_MAX || skip > UINT64_MAX / 2 - need)
		return loom__fail(diag, LOOM_ERANGE, "%s: declared data size overflows",
		                  name);
	total = need + skip;
	if (total / DEFLATE_MAX_RATIO > len + 64)
		return loom__fail(diag, LOOM_ETRUNCATED,
		                  "%s: %llu bytes of gzip data cannot hold the %llu "
		                  "bytes the header declares (%ux%ux%u x %u %s)",
		                  name, (unsigned long long)len,
		                  (unsigned long long)total, I->nx, I->ny, I->nz,
		                  I->channels, loom_scalar_name(I->type));
	if (max_bytes && need / loom_scalar_size(I->type) > max_bytes / 4)
		return loom__fail(diag, LOOM_EBUDGET,
		                  "%s: %ux%ux%u x %u values as floats exceed the "
		                  "%zu-byte limit",
		                  name, I->nx, I->ny, I->nz, I->channels, max_bytes);
	if (total > SIZE_MAX / 2)
		return loom__fail(diag, LOOM_ERANGE, "%s: data too large", name);
	raw = malloc(total ? (size_t)total : 1);
	if (!raw)
		return loom__fail(diag, LOOM_ENOMEM, "%s: cannot allocate %llu bytes "
		                  "for the inflated data", name,
		                  (unsigned long long)total);
	d = libdeflate_alloc_decompressor();
	if (!d) {
		free(raw);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	}
	res = libdeflate_gzip_decompress_ex(d, src, len, raw, (size_t)total,
	                                    &in_used, &out_got);
	libdeflate_free_decompressor(d);
	if (res == LIBDEFLATE_INSUFFICIENT_SPACE) {
		free(raw);
		return loom__fail(diag, LOOM_ECORRUPT,
		                  "%s: gzip data inflate to more than the %llu bytes "
		                  "the header declares", name, (unsigned long long)total);
	}
	if (res != LIBDEFLATE_SUCCESS) {
		free(raw);
		return loom__fail(diag, LOOM_ECORRUPT,
		                  "%s: gzip data are corrupt or truncated (libdeflate "
		                  "error %d)", name, (int)res);
	}
	if (out_got != total) {
		free(raw);
		return loom__fail(diag, LOOM_ETRUNCATED,
		                  "%s: gzip data inflate to %zu bytes, the header "
		                  "declares %llu (%ux%ux%u x %u %s)",
		                  name, out_got, (unsigned long long)total, I->nx, I->ny,
		                  I->nz, I->channels, loom_scalar_name(I->type));
	}
	if (in_used < len)
		loom__warn(diag, "%s: %zu bytes after the gzip stream ignored", name,
		           len - in_used);
	params_from_info(I, &p);
	p.flags = 0;
	rc = loom_raw_parse(raw + skip, (size_t)need, name, &p, max_bytes, out,
	                    diag);
	free(raw);
	return rc;
}

static int decode_ascii(const uint8_t *src, size_t len, const char *name,
                        const loom_nrrd_info *I, size_t max_bytes,
                        loom_volbuf **out, loom_diag *diag)
{
	uint64_t n_values = data_bytes_of(I) / loom_scalar_size(I->type);
	size_t pos = 0, i;
	int rc;

	if (data_bytes_of(I) == UINT64_MAX)
		return loom__fail(diag, LOOM_ERANGE, "%s: declared size overflows", name);
	/* each value takes at least two bytes of text (digit + separator) */
	if (n_values > len / 2 + 1)
		return loom__fail(diag, LOOM_ETRUNCATED,
		                  "%s: %zu bytes of text cannot hold the %llu values the "
		                  "header declares", name, len,
		                  (unsigned long long)n_values);
	rc = loom_volbuf_new(I->nx, I->ny, I->nz, I->channels, max_bytes, out, diag);
	if (rc)
		return rc;
	for (i = 0; i < n_values; i++) {
		char tok[80];
		size_t k = 0, start;
		char *end;
		while (pos < len && (src[pos] == ' ' || src[pos] == '\t' ||
		                     src[pos] == ',' || src[pos] == '\n' ||
		                     src[pos] == '\r'))
			pos++;
		start = pos;
		while (pos < len && !(src[pos] == ' ' || src[pos] == '\t' ||
		                      src[pos] == ',' || src[pos] == '\n' ||
		                      src[pos] == '\r')) {
			if (k + 1 < sizeof tok)
				tok[k++] = (char)src[pos];
			pos++;
		}
		tok[k] = 0;
		if (pos == start) {
			rc = loom__fail(diag, LOOM_ETRUNCATED,
			                "%s: ascii data end after %zu of %llu values", name,
			                i, (unsigned long long)n_values);
			break;
		}
		(*out)->data[i] = strtof(tok, &end);
		if (end == tok || *end || pos - start >= sizeof tok) {
			rc = loom__fail(diag, LOOM_EFORMAT,
			                "%s: byte %zu: ascii value %zu is not a number: "
			                "\"%s\"", name, start, i, tok);
			break;
		}
	}
	if (rc) {
		loom_volbuf_free(*out);
		*out = NULL;
		return rc;
	}
	for (int a = 0; a < 3; a++) {
		(*out)->spacing[a] = I->spacing[a];
		(*out)->origin[a] = I->origin[a];
	}
	(*out)->source_type = I->type;
	return LOOM_OK;
}

/* Decode data that start at byte `pos` of buf (before line/byte skips). */
static int decode_buffer(const uint8_t *buf, size_t len, size_t pos,
                         const char *name, const loom_nrrd_info *I,
                         size_t max_bytes, loom_volbuf **out, loom_diag *diag)
{
	loom_raw_params p;
	int rc = skip_lines(buf, len, &pos, I->line_skip, name, diag);

	if (rc)
		return rc;
	switch (I->encoding) {
	case LOOM_NRRD_RAW:
		params_from_info(I, &p);
		if (!(p.flags & LOOM_RAW_DATA_AT_END)) {
			uint64_t need = data_bytes_of(I);
			p.offset = pos + (uint64_t)I->byte_skip;
			if (need != UINT64_MAX && p.offset <= len &&
			    len - p.offset > need) {
				loom__warn(diag, "%s: byte %llu: %llu bytes after the data "
				           "ignored", name,
				           (unsigned long long)(p.offset + need),
				           (unsigned long long)(len - p.offset - need));
				p.flags |= LOOM_RAW_ALLOW_TRAILING;
			}
		}
		return loom_raw_parse(buf, len, name, &p, max_bytes, out, diag);
	case LOOM_NRRD_GZIP:
		return decode_gzip(buf + pos, len - pos, name, I, max_bytes, out, diag);
	case LOOM_NRRD_ASCII:
		if (I->byte_skip > 0) {
			if ((uint64_t)I->byte_skip > len - pos)
				return loom__fail(diag, LOOM_ETRUNCATED,
				                  "%s: byte skip %lld passes the end of the data",
				                  name, (long long)I->byte_skip);
			pos += (size_t)I->byte_skip;
		}
		return decode_ascii(buf + pos, len - pos, name, I, max_bytes, out, diag);
	default:
		return loom__fail(diag, LOOM_EINVAL, "%s: no encoding", name);
	}
}

LOOM_API int loom_nrrd_parse(const uint8_t *data, size_t len, const char *name,
                             size_t max_bytes, loom_nrrd_info *info,
                             loom_volbuf **out, loom_diag *diag)
{
	loom_nrrd_info I;
	int rc;

	if (!name)
		name = "nrrd";
	if (!out)
		return loom__fail(diag, LOOM_EINVAL, "%s: out is NULL", name);
	*out = NULL;
	rc = loom_nrrd_parse_header((const char *)data, len, name, &I, diag);
	if (rc)
		return rc;
	if (I.data_file[0])
		return loom__fail(diag, LOOM_EUNSUPPORTED,
		                  "%s: detached data file \"%s\": read the header "
		                  "with loom_nrrd_read", name, I.data_file);
	rc = decode_buffer(data, len, I.header_bytes, name, &I, max_bytes, out, diag);
	if (!rc && info)
		*info = I;
	return rc;
}

/* ---- from files ------------------------------------------------------------ */

/* Read at most HEADER_MAX bytes of path and parse the header. */
static int read_header(const char *path, loom_nrrd_info *I, loom_diag *diag)
{
	char *buf;
	size_t n = 0;
	uint64_t size;
	int rc, fd, err = 0;
	FILE *fp;

	rc = loom__open_input(path, &fd, &size, diag);
	if (rc)
		return rc;
	fp = fdopen(fd, "rb");
	buf = fp ? malloc(HEADER_MAX) : NULL;
	if (!buf) {
		if (fp)
			fclose(fp);
		else
			close(fd);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	/* the magic line first: a file that is not NRRD is not read further */
	n = fread(buf, 1, 4, fp);
	if (!ferror(fp) && n == 4 && memcmp(buf, "NRRD", 4) == 0)
		n += fread(buf + 4, 1, HEADER_MAX - 4, fp);
	err = ferror(fp);
	if (err) {
		rc = loom__fail(diag, LOOM_EIO, "%s: read error: %s", path,
		                strerror(errno));
	} else {
		rc = loom_nrrd_parse_header(buf, n, path, I, diag);
		if (!rc && n == HEADER_MAX && I->header_bytes == n)
			rc = loom__fail(diag, LOOM_ERANGE, "%s: header longer than %u "
			                "bytes", path, HEADER_MAX);
	}
	free(buf);
	fclose(fp);
	return rc;
}

/* Path of the data: the header itself, or the data file relative to the
   header's directory.  Returns a malloc'ed string. */
static char *data_path(const char *path, const loom_nrrd_info *I)
{
	const char *slash;
	size_t dir_len;
	char *s;

	if (!I->data_file[0] || I->data_file[0] == '/')
		return strdup(I->data_file[0] ? I->data_file : path);
	slash = strrchr(path, '/');
	dir_len = slash ? (size_t)(slash - path) + 1 : 0;
	s = malloc(dir_len + strlen(I->data_file) + 1);
	if (s) {
		memcpy(s, path, dir_len);
		strcpy(s + dir_len, I->data_file);
	}
	return s;
}

/* Offset of the data in a raw-encoded file after header and line skip
   (byte skip not included). */
static int raw_data_offset(const char *dpath, const loom_nrrd_info *I,
                           uint64_t *offset, loom_diag *diag)
{
	uint64_t pos = I->data_file[0] ? 0 : I->header_bytes;
	FILE *fp;
	int64_t lines = I->line_skip;

	*offset = pos;
	if (lines == 0)
		return LOOM_OK;
	{
		int fd, rc;
		uint64_t size;
		rc = loom__open_input(dpath, &fd, &size, diag);
		if (rc)
			return rc;
		fp = fdopen(fd, "rb");
		if (!fp) {
			close(fd);
			return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", dpath);
		}
	}
	if (fseeko(fp, (off_t)pos, SEEK_SET) != 0) {
		fclose(fp);
		return loom__fail(diag, LOOM_EIO, "%s: cannot seek", dpath);
	}
	while (lines > 0) {
		int c = getc(fp);
		if (c == EOF) {
			fclose(fp);
			return loom__fail(diag, LOOM_ETRUNCATED,
			                  "%s: byte %llu: end of file while skipping lines "
			                  "(line skip %lld)", dpath,
			                  (unsigned long long)pos, (long long)I->line_skip);
		}
		pos++;
		if (c == '\n')
			lines--;
	}
	fclose(fp);
	*offset = pos;
	return LOOM_OK;
}

static int raw_params_for(const char *dpath, const loom_nrrd_info *I,
                          loom_raw_params *p, loom_diag *diag)
{
	uint64_t off;
	int rc = raw_data_offset(dpath, I, &off, diag);
	struct stat st;

	if (rc)
		return rc;
	params_from_info(I, p);
	if (p->flags & LOOM_RAW_DATA_AT_END)
		return LOOM_OK;
	p->offset = off + (uint64_t)I->byte_skip;
	if (stat(dpath, &st) == 0) {
		uint64_t need = data_bytes_of(I), size = (uint64_t)st.st_size;
		if (need != UINT64_MAX && p->offset <= size && size - p->offset > need) {
			loom__warn(diag, "%s: byte %llu: %llu bytes after the data ignored",
			           dpath, (unsigned long long)(p->offset + need),
			           (unsigned long long)(size - p->offset - need));
			p->flags |= LOOM_RAW_ALLOW_TRAILING;
		}
	}
	return LOOM_OK;
}

/*
 * Largest file that can hold the gzip or ASCII data the header declares
 * (docs/volumes.md): gzip never needs more than the data plus 1/64 of it
 * (stored blocks cost 5 bytes per 64 KiB) and 1 MiB of gzip header, ASCII
 * at most 64 bytes of text per value, both after the attached header.  A
 * larger file is refused before it is read.
 */
static uint64_t encoded_limit(const loom_nrrd_info *I)
{
	uint64_t need = data_bytes_of(I), lim;
	uint64_t skip = I->byte_skip > 0 ? (uint64_t)I->byte_skip : 0;

	if (need == UINT64_MAX || need > ((uint64_t)1 << 50) ||
	    skip > ((uint64_t)1 << 50))
		return UINT64_MAX;
	if (I->encoding == LOOM_NRRD_GZIP)
		lim = need + skip + (need + skip) / 64;
	else
		lim = need / loom_scalar_size(I->type) * 64;
	lim += (uint64_t)1 << 20;
	if (!I->data_file[0])
		lim += I->header_bytes;
	if (I->line_skip > 0) /* lines of at most 4 KiB */
		lim += (uint64_t)(I->line_skip < ((int64_t)1 << 20) ? I->line_skip
		                                                    : (int64_t)1 << 20) * 4096;
	return lim;
}

LOOM_API int loom_nrrd_read(const char *path, size_t max_bytes,
                            loom_nrrd_info *info, loom_volbuf **out,
                            loom_diag *diag)
{
	loom_nrrd_info I;
	char *dpath;
	int rc;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_nrrd_read: NULL argument");
	*out = NULL;
	rc = read_header(path, &I, diag);
	if (rc)
		return rc;
	dpath = data_path(path, &I);
	if (!dpath)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	if (I.encoding == LOOM_NRRD_RAW) {
		loom_raw_params p;
		rc = raw_params_for(dpath, &I, &p, diag);
		if (!rc)
			rc = loom_raw_read(dpath, &p, max_bytes, out, diag);
	} else {
		uint8_t *buf;
		size_t len;
		rc = loom__read_file_checked(dpath, encoded_limit(&I),
		                             I.encoding == LOOM_NRRD_GZIP ? "gzip NRRD "
		                             "data" : "ASCII NRRD data", NULL, &buf,
		                             &len, diag);
		if (!rc) {
			size_t start = I.data_file[0] ? 0 : I.header_bytes;
			if (start > len)
				rc = loom__fail(diag, LOOM_ETRUNCATED, "%s: file shrank", dpath);
			else
				rc = decode_buffer(buf, len, start, dpath, &I, max_bytes, out,
				                   diag);
			free(buf);
		}
	}
	free(dpath);
	if (!rc && info)
		*info = I;
	return rc;
}

LOOM_API int loom_nrrd_open(const char *path, loom_nrrd_info *info,
                            loom_raw_reader **out, loom_diag *diag)
{
	loom_nrrd_info I;
	loom_raw_params p;
	char *dpath;
	int rc;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_nrrd_open: NULL argument");
	*out = NULL;
	rc = read_header(path, &I, diag);
	if (rc)
		return rc;
	if (I.encoding != LOOM_NRRD_RAW)
		return loom__fail(diag, LOOM_EUNSUPPORTED,
		                  "%s: %s-encoded data cannot be streamed by slices; "
		                  "read it whole with loom_nrrd_read", path,
		                  I.encoding == LOOM_NRRD_GZIP ? "gzip" : "ascii");
	dpath = data_path(path, &I);
	if (!dpath)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	rc = raw_params_for(dpath, &I, &p, diag);
	if (!rc)
		rc = loom_raw_open(dpath, &p, out, diag);
	free(dpath);
	if (!rc && info)
		*info = I;
	return rc;
}
