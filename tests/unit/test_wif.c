/*
 * tests/unit/test_wif.c - the WIF 1.1 reader (io/design/wif.c).
 *
 * 1. Every tests/data/wif/NAME.wif is either
 *      valid:   its drawdown must equal NAME.expected.pbm (a hand-checked
 *               P1 file: first row = pick 1, black = warp over), and it must
 *               give exactly the warnings listed in its own comment lines
 *               "; expect-warning: FRAGMENT" (in order), or
 *      invalid: a comment "; expect-error: LOOM_EXXX FRAGMENT" (or, for a
 *               file that cannot hold a comment, NAME.expected.err) gives
 *               the result code and a fragment of the message, which
 *               includes "NAME:LINE:".
 * 2. Yarn types and colours of the coloured files.
 * 3. Small inline cases: shed words, NULL arguments, limits.
 * 4. A randomised round trip: random threading / tie-up / treadling /
 *    liftplan written as WIF text with random formatting quirks, parsed,
 *    compared with a brute-force drawdown (seed printed).
 */
#include "check.h"
#include "loom.h"
#include "io/design/wif_internal.h"

#include <dirent.h>
#include <math.h>
#include <stdarg.h>

/* ---- helpers ----------------------------------------------------------- */

static char *read_all(const char *path, size_t *len)
{
	FILE *fp = fopen(path, "rb");
	char *buf;
	long n;

	if (!fp)
		return NULL;
	fseek(fp, 0, SEEK_END);
	n = ftell(fp);
	fseek(fp, 0, SEEK_SET);
	buf = malloc((size_t)n + 1);
	if (buf && fread(buf, 1, (size_t)n, fp) != (size_t)n) {
		free(buf);
		buf = NULL;
	}
	fclose(fp);
	if (buf) {
		buf[n] = 0;
		*len = (size_t)n;
	}
	return buf;
}

static const char *data_dir(void)
{
	static char dir[2048];
	const char *top = getenv("LOOM_TOP");
	snprintf(dir, sizeof dir, "%s/tests/data/wif", top ? top : ".");
	return dir;
}

/* Parse a P1 PBM (comments, any whitespace).  Returns malloc'ed w*h bits. */
static uint8_t *parse_p1(const char *t, uint32_t *w, uint32_t *h)
{
	const char *p = t;
	long v[2];
	uint8_t *bits;
	size_t n, k = 0;

	if (p[0] != 'P' || p[1] != '1')
		return NULL;
	p += 2;
	for (int i = 0; i < 2; i++) {
		for (;;) {
			while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
				p++;
			if (*p != '#')
				break;
			while (*p && *p != '\n')
				p++;
		}
		if (*p < '0' || *p > '9')
			return NULL;
		v[i] = strtol(p, (char **)&p, 10);
	}
	if (v[0] <= 0 || v[1] <= 0)
		return NULL;
	*w = (uint32_t)v[0];
	*h = (uint32_t)v[1];
	n = (size_t)v[0] * (size_t)v[1];
	bits = malloc(n);
	while (bits && k < n && *p) {
		if (*p == '#') {
			while (*p && *p != '\n')
				p++;
		} else if (*p == '0' || *p == '1') {
			bits[k++] = (uint8_t)(*p - '0');
			p++;
		} else {
			p++;
		}
	}
	if (k != n) {
		free(bits);
		return NULL;
	}
	return bits;
}

typedef struct warnings {
	int n;
	char msg[64][LOOM_DIAG_MSG_MAX];
} warnings;

static void collect(void *user, const char *msg)
{
	warnings *w = user;
	if (w->n < 64)
		snprintf(w->msg[w->n], sizeof w->msg[0], "%s", msg);
	w->n++;
}

static int code_of(const char *name)
{
	static const struct { const char *n; int c; } codes[] = {
		{"LOOM_EINVAL", LOOM_EINVAL}, {"LOOM_EFORMAT", LOOM_EFORMAT},
		{"LOOM_ERANGE", LOOM_ERANGE}, {"LOOM_EIO", LOOM_EIO},
		{"LOOM_ENOMEM", LOOM_ENOMEM}, {"LOOM_EUNSUPPORTED", LOOM_EUNSUPPORTED},
		{"LOOM_ETRUNCATED", LOOM_ETRUNCATED},
	};
	for (size_t i = 0; i < sizeof codes / sizeof *codes; i++)
		if (!strcmp(name, codes[i].n))
			return codes[i].c;
	return -1;
}

/* Copy the rest of the line after `key` into out (trailing CR/LF cut). */
static int meta(const char *text, const char *key, int nth, char *out,
                size_t cap)
{
	const char *p = text;
	int seen = 0;

	while ((p = strstr(p, key))) {
		size_t k = 0;
		p += strlen(key);
		if (seen++ != nth)
			continue;
		while (*p == ' ')
			p++;
		while (p[k] && p[k] != '\n' && p[k] != '\r' && k + 1 < cap) {
			out[k] = p[k];
			k++;
		}
		out[k] = 0;
		return 1;
	}
	return 0;
}

static int parse_text(const char *text, const char *name, loom_design **d,
                      loom_diag *diag, warnings *w)
{
	memset(diag, 0, sizeof *diag);
	memset(w, 0, sizeof *w);
	diag->warn = collect;
	diag->user = w;
	return loom_wif_parse(text, strlen(text), name, d, diag);
}

/* ---- 1. the data files ------------------------------------------------- */

static int n_valid, n_invalid;

static void check_file(const char *name)
{
	char path[8192], base[1024], line[1024];
	char *text, *pbm;
	size_t len, plen;
	loom_design *d = (loom_design *)1;
	loom_diag diag = {0};
	warnings w = {0};
	int rc, have_err;

	snprintf(path, sizeof path, "%s/%s", data_dir(), name);
	snprintf(base, sizeof base, "%.*s", (int)(strlen(name) - 4), name);
	text = read_all(path, &len);
	CHECK(text != NULL);
	if (!text)
		return;
	diag.warn = collect;
	diag.user = &w;
	rc = loom_wif_parse(text, len, name, &d, &diag);

	have_err = meta(text, "; expect-error:", 0, line, sizeof line);
	if (!have_err) { /* sidecar for files that cannot hold a comment */
		char epath[8192];
		char *e;
		size_t elen;
		snprintf(epath, sizeof epath, "%s/%s.expected.err", data_dir(), base);
		e = read_all(epath, &elen);
		if (e) {
			have_err = meta(e, "expect-error:", 0, line, sizeof line);
			free(e);
		}
	}
	if (have_err) {
		char *sp = strchr(line, ' ');
		n_invalid++;
		CHECK(sp != NULL);
		if (sp) {
			*sp = 0;
			CHECK(code_of(line) > 0);
			CHECK_EQ_INT(rc, code_of(line));
			CHECK_STR_CONTAINS(diag.message, sp + 1);
		}
		CHECK(d == NULL);
		/* every message names the file and a line */
		CHECK(strncmp(diag.message, name, strlen(name)) == 0);
		free(text);
		loom_design_free(rc == LOOM_OK ? d : NULL);
		return;
	}

	n_valid++;
	CHECK_EQ_INT(rc, LOOM_OK);
	if (rc != LOOM_OK)
		printf("  %s: %s\n", name, diag.message);
	snprintf(path, sizeof path, "%s/%s.expected.pbm", data_dir(), base);
	pbm = read_all(path, &plen);
	CHECK(pbm != NULL); /* every valid file has its expected drawdown */
	if (rc == LOOM_OK && pbm) {
		uint32_t pw = 0, ph = 0;
		uint8_t *bits = parse_p1(pbm, &pw, &ph);
		CHECK(bits != NULL);
		CHECK_EQ_INT(d->cols, pw);
		CHECK_EQ_INT(d->rows, ph);
		if (bits && d->cols == pw && d->rows == ph) {
			size_t bad = 0;
			for (size_t k = 0; k < (size_t)pw * ph; k++)
				bad += d->weave[k] != bits[k];
			CHECK_EQ_INT(bad, 0);
			if (bad)
				for (uint32_t i = 0; i < d->rows; i++) {
					printf("  got  ");
					for (uint32_t j = 0; j < d->cols; j++)
						printf("%d", d->weave[(size_t)i * d->cols + j]);
					printf("   expected ");
					for (uint32_t j = 0; j < d->cols; j++)
						printf("%d", bits[(size_t)i * d->cols + j]);
					printf("\n");
				}
		}
		free(bits);
		CHECK_EQ_INT(loom_design_validate(d, NULL), LOOM_OK);
	}
	/* warnings: exactly the expected ones, in order */
	{
		int nexp = 0;
		while (meta(text, "; expect-warning:", nexp, line, sizeof line)) {
			if (nexp < w.n)
				CHECK_STR_CONTAINS(w.msg[nexp], line);
			nexp++;
		}
		CHECK_EQ_INT(w.n, nexp);
		CHECK_EQ_INT(diag.n_warnings, nexp);
		for (int k = 0; k < w.n && k < 64; k++) {
			if (k >= nexp)
				printf("  unexpected warning: %s\n", w.msg[k]);
			CHECK(strncmp(w.msg[k], name, strlen(name)) == 0);
		}
	}
	free(pbm);
	free(text);
	loom_design_free(d);
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

static void test_files(void)
{
	DIR *dir = opendir(data_dir());
	struct dirent *e;
	char *names[512];
	size_t n = 0;

	CHECK(dir != NULL);
	if (!dir)
		return;
	while ((e = readdir(dir)) && n < 512) {
		size_t l = strlen(e->d_name);
		if (l > 4 && !strcmp(e->d_name + l - 4, ".wif"))
			names[n++] = strdup(e->d_name);
	}
	closedir(dir);
	qsort(names, n, sizeof *names, cmp_str);
	for (size_t k = 0; k < n; k++) {
		check_fail_count = 0;
		check_file(names[k]);
		printf("%s test_wif/file:%s\n", check_fail_count ? "FAIL" : "PASS",
		       names[k]);
		if (check_fail_count)
			check_tests_failed++;
		free(names[k]);
	}
	check_fail_count = 0;
	/* the suite must not silently shrink */
	CHECK(n_valid >= 30);
	CHECK(n_invalid >= 20);
}

/* ---- 2. yarn types ----------------------------------------------------- */

static loom_design *load(const char *name)
{
	char path[4096];
	loom_design *d = NULL;
	loom_diag diag = {0};
	int rc;

	snprintf(path, sizeof path, "%s/%s", data_dir(), name);
	rc = loom_wif_read(path, &d, &diag);
	CHECK_EQ_INT(rc, LOOM_OK);
	if (rc)
		printf("  %s\n", diag.message);
	return d;
}

#define CHECK_NEAR(a, b) CHECK(fabs((double)(a) - (double)(b)) < 1e-4)

static void test_colors(void)
{
	loom_design *d = load("colors.wif");
	/* type of end j and of pick i, from the file's comment */
	static const uint8_t end_t[6] = {0, 0, 1, 1, 0, 0};
	static const uint8_t pick_t[4] = {2, 3, 2, 4};

	if (!d)
		return;
	CHECK_EQ_INT(d->n_types, 5);
	if (d->n_types != 5) {
		loom_design_free(d);
		return;
	}
	CHECK(!strcmp(d->types[0].name, "warp #ffffff 0.5mm"));
	CHECK(!strcmp(d->types[1].name, "warp #c80000 0.5mm"));
	CHECK(!strcmp(d->types[2].name, "weft #1a2b3c 0.353mm"));
	CHECK(!strcmp(d->types[3].name, "weft #c80000 0.353mm"));
	CHECK(!strcmp(d->types[4].name, "weft #1a2b3c 0.706mm"));
	for (int t = 0; t < 5; t++)
		printf("  type %d: %s\n", t, d->types[t].name);
	/* albedo = sRGB 8-bit linearised (values computed by hand) */
	CHECK_NEAR(d->types[0].albedo[0], 1.0);
	CHECK_NEAR(d->types[0].albedo[2], 1.0);
	CHECK_NEAR(d->types[1].albedo[0], 0.577580); /* 200 */
	CHECK_NEAR(d->types[1].albedo[1], 0.0);
	CHECK_NEAR(d->types[2].albedo[0], 0.010330); /* 26 */
	CHECK_NEAR(d->types[2].albedo[1], 0.024158); /* 43 */
	CHECK_NEAR(d->types[2].albedo[2], 0.045186); /* 60 */
	/* thickness relative to the thickest (20 decipoints = 0.70556 mm) */
	CHECK_NEAR(d->types[4].thickness, 1.0);
	CHECK_NEAR(d->types[2].thickness, 0.5);
	CHECK_NEAR(d->types[0].thickness, 0.5 / (20 * 25.4 / 720));
	for (uint32_t i = 0; i < d->rows; i++)
		for (uint32_t j = 0; j < d->cols; j++) {
			size_t k = (size_t)i * d->cols + j;
			CHECK_EQ_INT(d->warp_type[k], end_t[j]);
			CHECK_EQ_INT(d->weft_type[k], pick_t[i]);
		}
	loom_design_free(d);
}

static void check_names(const char *file, int n, const char *const *names)
{
	loom_design *d = load(file);
	if (!d)
		return;
	CHECK_EQ_INT(d->n_types, n);
	for (int k = 0; k < n && k < (int)d->n_types; k++)
		if (strcmp(d->types[k].name, names[k])) {
			printf("  %s type %d: '%s', expected '%s'\n", file, k,
			       d->types[k].name, names[k]);
			CHECK(0);
		}
	loom_design_free(d);
}

/* Sett and yarn size: per-thread tables averaged with the section's
   default, converted by Units (centimetres; decipoints by default). */
static void test_sett(void)
{
	loom_design *d = load("sett-square.wif"), *c = NULL;

	if (d) {
		/* ends: 0.0175, 0.0195 and four at 0.0185 cm; mean 0.0185 cm */
		CHECK(fabs(d->sett[0] - 10.0 / 0.185) < 1e-3);
		CHECK(fabs(d->sett[1] - 10.0 / 0.185) < 1e-3);
		/* yarns: 0.019, 0.021 and four at 0.02 cm; mean 200 um */
		CHECK(fabs(d->yarn_um[0] - 200.0) < 1e-3);
		CHECK(fabs(d->yarn_um[1] - 200.0) < 1e-3);
		CHECK_EQ_INT(loom_design_clone(d, &c), LOOM_OK);
		if (c)
			CHECK(c->sett[0] == d->sett[0] && c->yarn_um[1] == d->yarn_um[1]);
		loom_design_free(c);
		loom_design_free(d);
	}
	d = load("sett-two-one.wif");
	if (d) {
		/* 5.25 and 10.5 decipoints of 25.4/720 mm */
		CHECK(fabs(d->sett[0] - 10.0 / (5.25 * 25.4 / 720)) < 1e-3);
		CHECK(fabs(d->sett[1] - 10.0 / (10.5 * 25.4 / 720)) < 1e-3);
		CHECK(d->yarn_um[0] == 0 && d->yarn_um[1] == 0);
		loom_design_free(d);
	}
	d = load("basic-twill.wif");
	if (d) {
		CHECK(d->sett[0] == 0 && d->sett[1] == 0);
		loom_design_free(d);
	}
}

static void test_palettes(void)
{
	static const char *const p999[] = {"warp #ffffff", "weft #800000"};
	static const char *const poff[] = {"warp #ff8000", "weft #000000"};
	static const char *const pguess[] = {"warp #ffffff", "weft #0000ff"};
	static const char *const arah[] = {"warp #ffffff 0.3mm", "warp #ff0000 0.3mm",
	                                   "warp #ff0000 0.6mm", "weft #000000 0.4mm"};
	static const char *const plain[] = {"warp", "weft"};
	loom_design *d;

	check_names("palette-999.wif", 2, p999);
	check_names("palette-offset.wif", 2, poff);
	check_names("palette-guess.wif", 2, pguess);
	check_names("dialect-arahweave.wif", 4, arah);
	check_names("liftplan.wif", 2, plain); /* no colours: default types */
	d = load("palette-999.wif");
	if (d) {
		CHECK_NEAR(d->types[1].albedo[0], 0.214505); /* 500/999 linearised */
		CHECK_NEAR(d->types[0].thickness, 0.0);      /* not given */
		loom_design_free(d);
	}
	d = load("liftplan.wif");
	if (d) { /* default types keep the design defaults */
		CHECK_NEAR(d->types[0].albedo[0], 0.85);
		CHECK_NEAR(d->types[1].albedo[2], 0.55);
		CHECK_EQ_INT(d->warp_type[0], 0);
		CHECK_EQ_INT(d->weft_type[0], 1);
		loom_design_free(d);
	}
	d = load("dialect-arahweave.wif");
	if (d) { /* ends 1,3 white; 2 red; 4 red and thicker */
		CHECK_EQ_INT(d->warp_type[0], 0);
		CHECK_EQ_INT(d->warp_type[1], 1);
		CHECK_EQ_INT(d->warp_type[2], 0);
		CHECK_EQ_INT(d->warp_type[3], 2);
		CHECK_EQ_INT(d->weft_type[4], 3);
		CHECK_NEAR(d->types[2].thickness, 1.0);
		CHECK_NEAR(d->types[0].thickness, 0.5);
		loom_design_free(d);
	}
}

/* The drafts shipped in data/ (used by `loom demo`): clean and sized. */
static void test_shipped_data(void)
{
	static const struct { const char *name; uint32_t rows, cols, types; } f[] = {
		{"herringbone-8.wif", 192, 192, 3},
		{"overshot-sampler.wif", 340, 244, 3},
	};
	const char *top = getenv("LOOM_TOP");

	for (size_t k = 0; k < sizeof f / sizeof *f; k++) {
		char path[4096];
		loom_design *d = NULL;
		loom_diag diag = {0};
		loom_design_stats st;
		snprintf(path, sizeof path, "%s/data/%s", top ? top : ".", f[k].name);
		CHECK_EQ_INT(loom_wif_read(path, &d, &diag), LOOM_OK);
		if (!d) {
			printf("  %s\n", diag.message);
			continue;
		}
		CHECK_EQ_INT(diag.n_warnings, 0);
		CHECK_EQ_INT(d->rows, f[k].rows);
		CHECK_EQ_INT(d->cols, f[k].cols);
		CHECK_EQ_INT(d->n_types, f[k].types);
		CHECK_EQ_INT(loom_design_analyze(d, &st), LOOM_OK);
		CHECK(st.interlaced); /* real cloth: every yarn goes over and under */
		loom_design_free(d);
	}
}

/* ---- 3. inline cases --------------------------------------------------- */

static const char *const twill_tables =
	"[THREADING]\n1=1\n2=2\n3=3\n4=4\n[TIEUP]\n1=1,2\n2=2,3\n3=3,4\n4=4,1\n"
	"[TREADLING]\n1=1\n2=2\n3=3\n4=4\n";

static void test_shed_words(void)
{
	static const char *const sinking[] = {"false", "FALSE", "no", "No", "0",
	                                      "off", "Off"};
	static const char *const rising[] = {"true", "True", "yes", "YES", "1",
	                                     "on"};
	char text[1024];
	loom_design *d;
	loom_diag diag;
	warnings w;

	for (size_t k = 0; k < sizeof sinking / sizeof *sinking; k++) {
		snprintf(text, sizeof text, "[WEAVING]\nRising Shed=%s\n%s",
		         sinking[k], twill_tables);
		CHECK_EQ_INT(parse_text(text, "s.wif", &d, &diag, &w), LOOM_OK);
		if (!d)
			continue;
		/* pick 1 lifts shafts 1,2 -> with a sinking shed ends 1,2 are under */
		CHECK_EQ_INT(d->weave[0], 0);
		CHECK_EQ_INT(d->weave[2], 1);
		CHECK_EQ_INT(w.n, 0);
		loom_design_free(d);
	}
	for (size_t k = 0; k < sizeof rising / sizeof *rising; k++) {
		snprintf(text, sizeof text, "[WEAVING]\nRising Shed=%s\n%s", rising[k],
		         twill_tables);
		CHECK_EQ_INT(parse_text(text, "r.wif", &d, &diag, &w), LOOM_OK);
		if (!d)
			continue;
		CHECK_EQ_INT(d->weave[0], 1);
		CHECK_EQ_INT(d->weave[2], 0);
		CHECK_EQ_INT(w.n, 0);
		loom_design_free(d);
	}
	snprintf(text, sizeof text, "[WEAVING]\nRising Shed=maybe\n%s", twill_tables);
	CHECK_EQ_INT(parse_text(text, "m.wif", &d, &diag, &w), LOOM_OK);
	CHECK_EQ_INT(w.n, 1);
	CHECK_STR_CONTAINS(w.msg[0], "m.wif:2: [WEAVING] Rising Shed=maybe is not "
	                   "true or false; assuming a rising shed");
	if (d)
		CHECK_EQ_INT(d->weave[0], 1);
	loom_design_free(d);
}

static void test_misc_warnings(void)
{
	loom_design *d;
	loom_diag diag;
	warnings w;
	char text[2048];

	/* unknown version, palette form, clamped colour, unknown unit, extra
	   colour entries beyond the last end */
	snprintf(text, sizeof text,
	         "[WIF]\nVersion=2.0\n[COLOR PALETTE]\nForm=HSV\nRange=0,255\n"
	         "[COLOR TABLE]\n1=300,0,0\n[WEAVING]\nRising Shed=1\n"
	         "[WARP]\nColor=1\nUnits=furlongs\nThickness=2\n"
	         "[WARP COLORS]\n9=1\n%s", twill_tables);
	CHECK_EQ_INT(parse_text(text, "w.wif", &d, &diag, &w), LOOM_OK);
	CHECK_EQ_INT(w.n, 5);
	CHECK_STR_CONTAINS(w.msg[0], "w.wif:2: WIF Version=2.0; reading it as WIF 1.1");
	CHECK_STR_CONTAINS(w.msg[1], "w.wif:4: [COLOR PALETTE] Form=HSV not understood");
	CHECK_STR_CONTAINS(w.msg[2], "w.wif:7: colour value 300 outside [COLOR "
	                   "PALETTE] Range 0..255; clamped");
	CHECK_STR_CONTAINS(w.msg[3], "w.wif:15: [WARP COLORS] has entries beyond the "
	                   "last end (4); ignored");
	CHECK_STR_CONTAINS(w.msg[4], "w.wif:12: [WARP] Units=furlongs not understood");
	if (d) {
		CHECK(!strcmp(d->types[0].name, "warp #ff0000 2mm"));
		CHECK_NEAR(d->types[0].albedo[0], 1.0);
	}
	loom_design_free(d);

	/* thickness without Units: decipoints (10 dp = 0.3528 mm); colourless
	   types keep their plain names */
	snprintf(text, sizeof text, "[WEAVING]\nRising Shed=1\n[WARP]\n"
	         "Thickness=10\n[WEFT]\nThickness=5\n%s", twill_tables);
	CHECK_EQ_INT(parse_text(text, "u.wif", &d, &diag, &w), LOOM_OK);
	CHECK_EQ_INT(w.n, 0);
	if (d) {
		CHECK_EQ_INT(d->n_types, 2);
		CHECK(!strcmp(d->types[0].name, "warp 0.353mm"));
		CHECK(!strcmp(d->types[1].name, "weft 0.176mm"));
		CHECK_NEAR(d->types[1].thickness, 0.5);
	}
	loom_design_free(d);

	/* without a diag, warnings are dropped and parsing still works */
	d = NULL;
	CHECK_EQ_INT(loom_wif_parse(twill_tables, strlen(twill_tables), "x", &d,
	                            NULL), LOOM_OK);
	CHECK(d && d->rows == 4 && d->cols == 4);
	loom_design_free(d);
}

static void test_args_and_limits(void)
{
	loom_design *d = (loom_design *)1;
	loom_diag diag = {0};
	char path[4096];
	char *big;
	size_t n = 0, cap = 1 << 16;

	CHECK_EQ_INT(loom_wif_parse(NULL, 3, "x", &d, &diag), LOOM_EINVAL);
	CHECK(d == NULL);
	CHECK_EQ_INT(loom_wif_parse("abc", 3, "x", NULL, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_wif_parse(NULL, 0, NULL, &d, &diag), LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(diag.message, "(wif): empty file, expected a WIF draft");
	CHECK_EQ_INT(loom_wif_parse(" \n", 2, NULL, &d, &diag), LOOM_ETRUNCATED);
	CHECK_EQ_INT(loom_wif_parse("; c\n", 4, "c.wif", &d, &diag), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(diag.message, "c.wif:1: no threading");
	CHECK_EQ_INT(loom_wif_read(NULL, &d, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_wif_read("/nonexistent/x.wif", &d, &diag), LOOM_EIO);
	CHECK_STR_CONTAINS(diag.message, "/nonexistent/x.wif");
	CHECK(d == NULL);
	/* the path names the file in messages */
	snprintf(path, sizeof path, "%s/bad-number.wif", data_dir());
	CHECK_EQ_INT(loom_wif_read(path, &d, &diag), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(diag.message, "tests/data/wif/bad-number.wif:7: ");
	/* not NUL-terminated: the parser reads exactly len bytes (the copy has
	   no NUL, so an overread shows under ASan); "\n2=1" is past len */
	{
		const char t[] = "[THREADING]\n1=1\n[LIFTPLAN]\n1=1\n2=1";
		char *copy = malloc(30);
		memcpy(copy, t, 30);
		d = NULL;
		CHECK_EQ_INT(loom_wif_parse(copy, 30, "n", &d, &diag), LOOM_OK);
		CHECK(d && d->rows == 1 && d->cols == 1 && d->weave[0] == 1);
		loom_design_free(d);
		free(copy);
	}
	/* the cell cap of the limited entry point */
	d = (loom_design *)1;
	CHECK_EQ_INT(loom__wif_parse_limited("[THREADING]\n100=1\n[LIFTPLAN]\n100=1\n",
	                                     34, "c", 9999, &d, &diag), LOOM_ERANGE);
	CHECK_STR_CONTAINS(diag.message, "c:4: design of 100 picks x 100 ends has "
	                   "10000 cells, more than the 9999 allowed");
	CHECK(d == NULL);
	/* 300 distinct warp colours: more than the yarn table holds */
	big = malloc(cap);
	n += (size_t)snprintf(big + n, cap - n, "[COLOR TABLE]\n");
	for (int k = 1; k <= 300; k++)
		n += (size_t)snprintf(big + n, cap - n, "%d=%d,%d,0\n", k, k % 256, k / 256);
	n += (size_t)snprintf(big + n, cap - n, "[WARP COLORS]\n");
	for (int k = 1; k <= 300; k++)
		n += (size_t)snprintf(big + n, cap - n, "%d=%d\n", k, k);
	n += (size_t)snprintf(big + n, cap - n, "[THREADING]\n300=1\n[LIFTPLAN]\n1=1\n");
	CHECK_EQ_INT(loom_wif_parse(big, n, "t", &d, &diag), LOOM_ERANGE);
	CHECK_STR_CONTAINS(diag.message, "more than 256 distinct yarns");
	CHECK_STR_CONTAINS(diag.message, "t:559: "); /* end 257, line 302 + 257 */
	free(big);
}

/* ---- 4. randomised round trip ------------------------------------------ */

typedef struct { uint64_t w[4]; } set256; /* shafts 1..255 */

static uint64_t sm64(uint64_t *s)
{
	uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static uint32_t rnd(uint64_t *s, uint32_t n) { return (uint32_t)(sm64(s) % n); }
static void set_add(set256 *s, uint32_t k) { s->w[k / 64] |= 1ull << (k % 64); }
static int set_has(const set256 *s, uint32_t k) { return (s->w[k / 64] >> (k % 64)) & 1; }
static int set_meets(const set256 *a, const set256 *b)
{
	return ((a->w[0] & b->w[0]) | (a->w[1] & b->w[1]) | (a->w[2] & b->w[2]) |
	        (a->w[3] & b->w[3])) != 0;
}

typedef struct { char *s; size_t n, cap; } sbuf;

static void put(sbuf *b, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
static void put(sbuf *b, const char *fmt, ...)
{
	va_list ap;
	int k;
	if (!b->s) {
		b->cap = 256;
		b->s = malloc(b->cap);
	}
	for (;;) {
		va_start(ap, fmt);
		k = vsnprintf(b->s + b->n, b->cap - b->n, fmt, ap);
		va_end(ap);
		if ((size_t)k < b->cap - b->n)
			break;
		b->cap = b->cap * 2 + (size_t)k + 64;
		b->s = realloc(b->s, b->cap);
	}
	b->n += (size_t)k;
}

/* Section header in a random case. */
static void put_section(sbuf *b, uint64_t *s, const char *name)
{
	put(b, "[");
	for (const char *p = name; *p; p++) {
		int c = (unsigned char)*p;
		if (rnd(s, 2) && c >= 'A' && c <= 'Z')
			c += 'a' - 'A';
		put(b, "%c", c);
	}
	put(b, "]\n");
}

/* "key=v1,v2,..." of a set, with zeros, spaces and comments thrown in. */
static void put_set(sbuf *b, uint64_t *s, uint32_t key, const set256 *v,
                    uint32_t maxv)
{
	int first = 1;
	put(b, "%u=", key);
	if (rnd(s, 8) == 0)
		put(b, "0,");
	for (uint32_t k = 1; k <= maxv; k++) {
		if (!set_has(v, k))
			continue;
		put(b, "%s%u", first ? "" : (rnd(s, 4) ? "," : ", "), k);
		first = 0;
	}
	if (rnd(s, 10) == 0)
		put(b, " ; comment");
	put(b, "\n");
}

static void test_round_trip(void)
{
	uint64_t seed = check_seed(), s = seed;
	int failures = 0;

	for (int iter = 0; iter < 300 && failures < 3; iter++) {
		uint32_t S = 1 + rnd(&s, iter % 5 == 0 ? 250 : 12);
		uint32_t T = 1 + rnd(&s, 10);
		uint32_t N = 1 + rnd(&s, iter % 5 == 0 ? 300 : 40);
		uint32_t M = 1 + rnd(&s, 50);
		int use_lift = rnd(&s, 2), both = rnd(&s, 4) == 0;
		int rising = rnd(&s, 3) != 0, crlf = rnd(&s, 2);
		set256 *thr = calloc(N + 1, sizeof *thr), *tie = calloc(T + 1, sizeof *tie);
		set256 *lift = calloc(M + 1, sizeof *lift), *trd = calloc(M + 1, sizeof *trd);
		sbuf b = {0};
		loom_design *d = NULL;
		loom_diag diag = {0};
		size_t bad = 0;
		int rc;

		for (uint32_t j = 1; j <= N; j++) {
			uint32_t r = rnd(&s, 10);
			if (r == 0)
				continue; /* unthreaded */
			set_add(&thr[j], 1 + rnd(&s, S));
			if (r == 1)
				set_add(&thr[j], 1 + rnd(&s, S));
		}
		for (uint32_t t = 1; t <= T; t++)
			for (uint32_t k = 0; k < 1 + rnd(&s, 4); k++)
				set_add(&tie[t], 1 + rnd(&s, S));
		for (uint32_t i = 1; i <= M; i++) {
			uint32_t nt = rnd(&s, 4); /* 0..3 treadles */
			for (uint32_t k = 0; k < nt; k++)
				set_add(&trd[i], 1 + rnd(&s, T));
			for (uint32_t k = 0; k < rnd(&s, 1 + S); k++)
				set_add(&lift[i], 1 + rnd(&s, S));
		}
		/* write it */
		put(&b, "; random draft %d\n", iter);
		if (rnd(&s, 2))
			put(&b, "[WIF]\nVersion=1.1\nSource Program=test_wif\n");
		put_section(&b, &s, "WEAVING");
		put(&b, "Shafts=%u\nTreadles=%u\n", S, T);
		put(&b, "%s=%s\n", rnd(&s, 2) ? "Rising Shed" : "RISING SHED",
		    rising ? (rnd(&s, 2) ? "true" : "yes") : (rnd(&s, 2) ? "false" : "0"));
		put_section(&b, &s, "THREADING");
		for (uint32_t j = 1; j <= N; j++) {
			if (j < N && !(thr[j].w[0] | thr[j].w[1] | thr[j].w[2] | thr[j].w[3]) &&
			    rnd(&s, 2))
				continue; /* a gap instead of "j=" */
			put_set(&b, &s, j, &thr[j], S);
		}
		if (!use_lift || both) {
			put_section(&b, &s, "TIEUP");
			for (uint32_t t = 1; t <= T; t++)
				put_set(&b, &s, t, &tie[t], S);
			put_section(&b, &s, "TREADLING");
			for (uint32_t i = 1; i <= M; i++)
				put_set(&b, &s, i, &trd[i], T);
		}
		if (use_lift) {
			put_section(&b, &s, "LIFTPLAN");
			for (uint32_t i = 1; i <= M; i++)
				put_set(&b, &s, i, &lift[i], S);
		}
		if (crlf) { /* CR LF line ends */
			sbuf c = {0};
			for (size_t k = 0; k < b.n; k++) {
				if (b.s[k] == '\n')
					put(&c, "\r\n");
				else
					put(&c, "%c", b.s[k]);
			}
			free(b.s);
			b = c;
		}
		rc = loom_wif_parse(b.s, b.n, "random.wif", &d, &diag);
		CHECK_EQ_INT(rc, LOOM_OK);
		if (rc == LOOM_OK) {
			CHECK_EQ_INT(d->rows, M);
			CHECK_EQ_INT(d->cols, N);
			for (uint32_t i = 1; i <= M && d->rows == M && d->cols == N; i++) {
				set256 l = {{0}};
				if (use_lift) {
					l = lift[i];
				} else {
					for (uint32_t t = 1; t <= T; t++)
						if (set_has(&trd[i], t))
							for (int w = 0; w < 4; w++)
								l.w[w] |= tie[t].w[w];
				}
				for (uint32_t j = 1; j <= N; j++) {
					int over = set_meets(&thr[j], &l);
					if (!rising)
						over = !over;
					bad += d->weave[(size_t)(i - 1) * N + (j - 1)] != over;
				}
			}
			CHECK_EQ_INT(bad, 0);
			CHECK_EQ_INT(diag.n_warnings, 0);
		} else {
			printf("  %s\n", diag.message);
		}
		if (rc != LOOM_OK || bad || diag.n_warnings) {
			failures++;
			printf("  iteration %d failed (S=%u T=%u N=%u M=%u lift=%d rising=%d)\n",
			       iter, S, T, N, M, use_lift, rising);
		}
		loom_design_free(d);
		free(b.s);
		free(thr);
		free(tie);
		free(lift);
		free(trd);
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_wif");
	test_files();
	RUN(test_colors);
	RUN(test_sett);
	RUN(test_palettes);
	RUN(test_shipped_data);
	RUN(test_shed_words);
	RUN(test_misc_warnings);
	RUN(test_args_and_limits);
	RUN(test_round_trip);
	CHECK_MAIN_END();
}
