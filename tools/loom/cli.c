/* tools/loom/cli.c - messages, value parsers, data lookup, JSON, images. */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <limits.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

uint32_t cli_cpus(void)
{
	long n = sysconf(_SC_NPROCESSORS_ONLN);
	return n < 1 ? 1 : n > 256 ? 256 : (uint32_t)n;
}

void cli_error(const char *prog, const char *fmt, ...)
{
	va_list ap;
	fprintf(stderr, "%s: ", prog);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fputc('\n', stderr);
}

void cli_fail(const char *prog, const char *fmt, ...)
{
	va_list ap;
	fprintf(stderr, "%s: ", prog);
	va_start(ap, fmt);
	vfprintf(stderr, fmt, ap);
	va_end(ap);
	fputc('\n', stderr);
	exit(EXIT_BAD_INPUT);
}

int cli_parse_u64(const char *s, uint64_t *v)
{
	char *end;
	unsigned long long x;

	if (!s || !*s || *s == '-' || *s == '+')
		return -1;
	errno = 0;
	x = strtoull(s, &end, 10);
	if (errno || *end)
		return -1;
	*v = x;
	return 0;
}

int cli_parse_u32(const char *s, uint32_t *v)
{
	uint64_t x;
	if (cli_parse_u64(s, &x) || x > UINT32_MAX)
		return -1;
	*v = (uint32_t)x;
	return 0;
}

int cli_parse_i64(const char *s, int64_t *v)
{
	char *end;
	long long x;

	if (!s || !*s)
		return -1;
	errno = 0;
	x = strtoll(s, &end, 10);
	if (errno || *end)
		return -1;
	*v = x;
	return 0;
}

int cli_parse_double(const char *s, double *v)
{
	char *end;
	double x;

	if (!s || !*s)
		return -1;
	errno = 0;
	x = strtod(s, &end);
	if (errno || *end || x != x)
		return -1;
	*v = x;
	return 0;
}

int cli_parse_size2(const char *s, uint32_t *a, uint32_t *b)
{
	char buf[64];
	char *sep;

	if (!s || strlen(s) >= sizeof buf)
		return -1;
	strcpy(buf, s);
	sep = strpbrk(buf, "xX,");
	if (!sep)
		return -1;
	*sep = 0;
	if (cli_parse_u32(buf, a) || cli_parse_u32(sep + 1, b))
		return -1;
	return 0;
}

void cli_warn_sink(void *user, const char *msg)
{
	if (user && *(int *)user)
		return;
	fprintf(stderr, "loom: warning: %s\n", msg);
}

void cli_fabric_fits(const char *prog, const char *path, double budget, const char *what,
                     int code)
{
	uint32_t rows, cols;
	double need;
	loom_diag d;

	cli_diag_init(&d, NULL);
	if (loom_fabric_file_size(path, &rows, &cols, &d) != LOOM_OK)
		return; /* loom_fabric_open reports it */
	need = 5.0 * (double)rows * (double)cols;
	if (need < budget)
		return;
	/* sizes below 1 MiB in bytes, as the texture's messages give them */
	char bt[40];
	if (budget < 1048576.0)
		snprintf(bt, sizeof bt, "%.0f bytes", budget < 0 ? 0 : budget);
	else
		snprintf(bt, sizeof bt, "%.1f MiB", budget / 1048576.0);
	fprintf(stderr, "%s: %s: the design and base assignment of %u x %u = %llu crossings "
	        "need %.1f MiB in memory (5 bytes each), more than --budget %s: "
	        "refused before loading the design\n", prog, path, rows, cols,
	        (unsigned long long)rows * cols, need / 1048576.0, bt);
	/* the smallest whole MiB above the design's bytes: a lower bound */
	fprintf(stderr, "%s: %s at least --budget %.0f (the design alone; the texture's "
	        "cache and buffers come on top)\n", prog, what, floor(need / 1048576.0) + 1);
	exit(code);
}

void cli_diag_init(loom_diag *d, int *quiet)
{
	memset(d, 0, sizeof *d);
	d->warn = cli_warn_sink;
	d->user = quiet;
}

static int is_dir(const char *p)
{
	struct stat st;
	return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

const char *cli_data_dir(void)
{
	static char buf[PATH_MAX + 64];
	char exe[PATH_MAX];
	const char *env = getenv("LOOM_DATA");
	ssize_t n;
	char *slash;

	if (env && *env)
		return env;
	n = readlink("/proc/self/exe", exe, sizeof exe - 1);
	if (n <= 0)
		return NULL;
	exe[n] = 0;
	slash = strrchr(exe, '/');
	if (!slash)
		return NULL;
	*slash = 0;
	snprintf(buf, sizeof buf, "%s/share/loom", exe);
	if (is_dir(buf))
		return buf;
	snprintf(buf, sizeof buf, "%s/../share/loom", exe);
	if (is_dir(buf))
		return buf;
	return NULL;
}

/* ---- JSON ---------------------------------------------------------------- */

static void jw_indent(json_w *w)
{
	fputc('\n', w->fp);
	for (int k = 0; k < w->depth; k++)
		fputs("  ", w->fp);
}

static void jw_escape(FILE *fp, const char *s)
{
	fputc('"', fp);
	for (; *s; s++) {
		unsigned char c = (unsigned char)*s;
		if (c == '"' || c == '\\')
			fprintf(fp, "\\%c", c);
		else if (c == '\n')
			fputs("\\n", fp);
		else if (c == '\t')
			fputs("\\t", fp);
		else if (c < 0x20)
			fprintf(fp, "\\u%04x", c);
		else
			fputc(c, fp);
	}
	fputc('"', fp);
}

static void jw_key(json_w *w, const char *key)
{
	if (!w->first[w->depth])
		fputc(',', w->fp);
	w->first[w->depth] = 0;
	jw_indent(w);
	if (key) {
		jw_escape(w->fp, key);
		fputs(": ", w->fp);
	}
}

void jw_begin(json_w *w, FILE *fp)
{
	memset(w, 0, sizeof *w);
	w->fp = fp;
	fputc('{', fp);
	w->depth = 1;
	w->first[1] = 1;
}

void jw_end(json_w *w)
{
	while (w->depth > 1)
		jw_close(w);
	fputs("\n}\n", w->fp);
	w->depth = 0;
}

static void jw_open(json_w *w, const char *key, char c)
{
	jw_key(w, key);
	fputc(c, w->fp);
	if (w->depth < 31)
		w->depth++;
	w->first[w->depth] = 1;
	w->close[w->depth] = c == '{' ? '}' : ']';
}

void jw_obj(json_w *w, const char *key)
{
	jw_open(w, key, '{');
}

void jw_arr(json_w *w, const char *key)
{
	jw_open(w, key, '[');
}

void jw_close(json_w *w)
{
	int empty = w->first[w->depth];
	char c = w->close[w->depth];
	w->depth--;
	if (!empty)
		jw_indent(w);
	fputc(c, w->fp);
}

void jw_str(json_w *w, const char *key, const char *s)
{
	jw_key(w, key);
	if (s)
		jw_escape(w->fp, s);
	else
		fputs("null", w->fp);
}

void jw_int(json_w *w, const char *key, long long v)
{
	jw_key(w, key);
	fprintf(w->fp, "%lld", v);
}

void jw_uint(json_w *w, const char *key, unsigned long long v)
{
	jw_key(w, key);
	fprintf(w->fp, "%llu", v);
}

void jw_num(json_w *w, const char *key, double v)
{
	jw_key(w, key);
	if (v != v || v > 1e308 || v < -1e308)
		fputs("null", w->fp);
	else
		fprintf(w->fp, "%.9g", v);
}

void jw_bool(json_w *w, const char *key, int v)
{
	jw_key(w, key);
	fputs(v ? "true" : "false", w->fp);
}

double cli_hit_rate(const loom_texture_stats *st)
{
	return st->hits + st->misses ? (double)st->hits / (double)(st->hits + st->misses) : 1.0;
}

void jw_texture_stats(json_w *w, const loom_texture_stats *st)
{
	jw_num(w, "hit_rate", cli_hit_rate(st));
	jw_uint(w, "brick_requests", st->brick_requests);
	jw_uint(w, "hits", st->hits);
	jw_uint(w, "misses", st->misses);
	jw_uint(w, "empty_bricks", st->empty_bricks);
	jw_uint(w, "evictions", st->evictions);
	jw_uint(w, "bytes_read", st->bytes_read);
	jw_uint(w, "bytes_decompressed", st->bytes_decompressed);
	jw_num(w, "decompress_seconds", (double)st->decompress_ns * 1e-9);
	jw_uint(w, "crossings", st->crossings);
	jw_uint(w, "dz_columns", st->dz_columns);
	jw_uint(w, "budget_bytes", st->budget_bytes);
	jw_uint(w, "peak_cache_bytes", st->peak_bytes);
	jw_uint(w, "cache_frames", st->cache_frames);
}

int cli_ends_with(const char *s, const char *ext)
{
	size_t n = strlen(s), e = strlen(ext);
	return n >= e && strcasecmp(s + n - e, ext) == 0;
}

int cli_write_exr(const char *path, uint32_t w, uint32_t h, const loom_exr_channel *ch,
                  uint32_t n_ch, const float *rows, loom_diag *diag)
{
	loom_exr_options eo = LOOM_EXR_OPTIONS_INIT;
	loom_exr_writer *wr = NULL;
	int rc = loom_exr_writer_open(path, w, h, ch, n_ch, &eo, &wr, diag);

	if (rc != LOOM_OK)
		return rc;
	rc = loom_exr_writer_put_rows(wr, rows, h, diag);
	if (rc != LOOM_OK) {
		loom_exr_writer_abort(wr);
		return rc;
	}
	return loom_exr_writer_finish(wr, diag);
}

int cli_write_rgb(const char *path, const float *rgb, uint32_t w, uint32_t h,
                  double exposure, loom_diag *diag)
{
	static const loom_exr_channel ch[3] = {
		{"R", LOOM_EXR_FLOAT}, {"G", LOOM_EXR_FLOAT}, {"B", LOOM_EXR_FLOAT}};
	loom_image *img = NULL;
	int rc;

	if (cli_ends_with(path, ".exr"))
		return cli_write_exr(path, w, h, ch, 3, rgb, diag);
	if ((rc = loom_image_new(w, h, 3, &img)) != LOOM_OK)
		return rc;
	loom_render_to_srgb8(rgb, (size_t)w * h, exposure, img->pixels);
	rc = loom_image_write(path, img, diag);
	loom_image_free(img);
	return rc;
}
