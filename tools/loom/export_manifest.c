/*
 * tools/loom/export_manifest.c - the manifest of `loom export`
 * (docs/batch.md): DIR/manifest.json (DIR/manifest-I-of-N.json for shard I
 * of N) lists the job's parameters and, one line per finished tile, its
 * box and files with their sizes and CRC-32s.
 *
 * The manifest is the job's record of what is done.  Workers build their
 * tile's line (export_line_add, export_record_file) and hand it over under
 * the context's lock; the main thread rewrites the whole manifest
 * atomically (temporary file, fsync, rename) at most once a second and
 * never more than a tenth of the run (export_tick), and at the end.  A
 * re-run of the same job (same "params" line) keeps the tiles whose files
 * still match their sizes and CRC-32s (export_resume) and removes the
 * temporary files a killed run left (export_remove_stale).  --merge checks
 * a complete set of shard manifests and writes their union as
 * DIR/manifest.json (export_merge).
 */
#include "cli.h"
#include "export.h"
#include "tiles.h"

#include <dirent.h>
#include <errno.h>
#include <libdeflate.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MANIFEST_VERSION 1

/* ---- a tile's line ------------------------------------------------------------ */

int export_line_add(struct ewstate *w, const char *fmt, ...)
{
	va_list ap;
	int n;

	for (;;) {
		va_start(ap, fmt);
		n = vsnprintf(w->line + w->line_len, w->line_cap - w->line_len, fmt, ap);
		va_end(ap);
		if (n < 0)
			return -1;
		if ((size_t)n < w->line_cap - w->line_len)
			break;
		char *nl = realloc(w->line, 2 * w->line_cap + (size_t)n);
		if (!nl)
			return -1;
		w->line = nl;
		w->line_cap = 2 * w->line_cap + (size_t)n;
	}
	w->line_len += (size_t)n;
	return 0;
}

/* CRC-32 and size of a file. */
int export_file_crc(const char *path, uint8_t *buf, uint32_t *crc, uint64_t *bytes)
{
	FILE *fp = fopen(path, "rb");
	uint32_t c = 0;
	uint64_t n = 0;
	size_t got;

	if (!fp)
		return -1;
	while ((got = fread(buf, 1, CRC_BUF, fp)) > 0) {
		c = libdeflate_crc32(c, buf, got);
		n += got;
	}
	if (ferror(fp)) {
		fclose(fp);
		return -1;
	}
	fclose(fp);
	*crc = c;
	*bytes = n;
	return 0;
}

/* Record a written file in the tile's line. */
int export_record_file(struct export_ctx *c, struct ewstate *w, const char *name,
                       char *msg, size_t msz)
{
	char path[4096];
	uint32_t crc;
	uint64_t bytes;

	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	if (export_file_crc(path, w->io, &crc, &bytes)) {
		snprintf(msg, msz, "%s: cannot read back: %s", path, strerror(errno));
		return -1;
	}
	atomic_fetch_add(&c->bytes, bytes);
	atomic_fetch_add(&c->files, 1);
	if (export_line_add(w, "%s{\"name\": \"%s\", \"bytes\": %llu, \"crc32\": "
	                    "\"%08x\"}", w->line[w->line_len - 1] == '[' ? "" : ", ", name,
	                    (unsigned long long)bytes, crc)) {
		snprintf(msg, msz, "out of memory");
		return -1;
	}
	return 0;
}

/* ---- manifest ----------------------------------------------------------------- */

/* Write a manifest atomically: lines[0..n) (NULL entries skipped) in order. */
static int manifest_write(const char *path, const char *params, uint32_t shard_i,
                          uint32_t shard_n, uint64_t total, char *const *lines,
                          uint64_t n, int complete, char *msg, size_t msz)
{
	char tmp[4200];
	FILE *fp;
	uint64_t listed = 0, done = 0;

	for (uint64_t i = 0; i < n; i++)
		listed += lines[i] != NULL;
	snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
	fp = fopen(tmp, "wb");
	if (!fp) {
		snprintf(msg, msz, "%.400s: cannot create: %s", tmp, strerror(errno));
		return -1;
	}
	fprintf(fp, "{\n  \"loom_export_manifest\": %d,\n  \"params\": %s,\n",
	        MANIFEST_VERSION, params);
	if (shard_n > 1)
		fprintf(fp, "  \"shard\": [%u, %u],\n", shard_i, shard_n);
	fprintf(fp, "  \"tiles_total\": %llu,\n  \"tiles_listed\": %llu,\n"
	        "  \"complete\": %s,\n  \"tiles\": [", (unsigned long long)total,
	        (unsigned long long)listed, complete ? "true" : "false");
	for (uint64_t i = 0; i < n; i++) {
		if (!lines[i])
			continue;
		fprintf(fp, "%s\n    %s", done ? "," : "", lines[i]);
		done++;
	}
	fprintf(fp, "%s]\n}\n", done ? "\n  " : "");
	if (fflush(fp) != 0 || fsync(fileno(fp)) != 0 || ferror(fp)) {
		snprintf(msg, msz, "%.400s: write failed: %s", tmp, strerror(errno));
		fclose(fp);
		unlink(tmp);
		return -1;
	}
	fclose(fp);
	if (rename(tmp, path) != 0) {
		snprintf(msg, msz, "%.200s: cannot rename to %.200s: %s", tmp, path, strerror(errno));
		unlink(tmp);
		return -1;
	}
	return 0;
}

int export_manifest_flush(struct export_ctx *c, int final)
{
	int rc;
	double t0 = cli_now();

	pthread_mutex_lock(&c->lock);
	rc = manifest_write(c->manifest, c->params, c->j->shard_i, c->j->shard_n,
	                    c->j->total, c->lines, c->n, final && c->ndone == c->n,
	                    c->manifest_msg, sizeof c->manifest_msg);
	c->nlisted_written = c->ndone;
	pthread_mutex_unlock(&c->lock);
	c->last_write = cli_now();
	c->write_cost = c->last_write - t0;
	if (rc)
		c->manifest_error = 1;
	return rc;
}

void export_tick(void *vctx)
{
	struct export_ctx *c = vctx;
	uint64_t nd;

	pthread_mutex_lock(&c->lock);
	nd = c->ndone;
	pthread_mutex_unlock(&c->lock);
	/* the whole manifest is rewritten (atomically): at most once a second,
	   and never more than a tenth of the time, however many tiles it lists */
	if (nd != c->nlisted_written && !c->manifest_error &&
	    cli_now() - c->last_write >= (c->write_cost * 10 > 1.0 ? c->write_cost * 10 : 1.0))
		export_manifest_flush(c, 0);
}

/* The text after `key` in a manifest line, or NULL. */
static const char *after(const char *s, const char *key)
{
	const char *p = strstr(s, key);
	return p ? p + strlen(key) : NULL;
}

/* Check a tile line's files (exist, size and CRC-32 as listed). */
static int verify_line(const char *dir, const char *line, uint8_t *buf, int check_crc)
{
	const char *p = after(line, "\"files\": [");

	if (!p)
		return -1;
	while ((p = after(p, "{\"name\": \"")) != NULL) {
		char name[512], path[4096];
		const char *q = strchr(p, '"');
		unsigned long long bytes;
		unsigned crc;
		uint32_t fcrc;
		uint64_t fbytes;
		struct stat st;

		if (!q || (size_t)(q - p) >= sizeof name)
			return -1;
		memcpy(name, p, (size_t)(q - p));
		name[q - p] = 0;
		if (strchr(name, '/'))
			return -1;
		if (sscanf(q, "\", \"bytes\": %llu, \"crc32\": \"%8x\"}", &bytes, &crc) != 2)
			return -1;
		snprintf(path, sizeof path, "%s/%s", dir, name);
		if (check_crc) {
			if (export_file_crc(path, buf, &fcrc, &fbytes) || fbytes != bytes ||
			    fcrc != crc)
				return -1;
		} else if (stat(path, &st) != 0 || (uint64_t)st.st_size != bytes) {
			return -1;
		}
		p = q;
	}
	return 0;
}

/* One line of text (without the newline) starting at *p; advances *p. */
static char *next_line(char **p)
{
	char *s = *p, *e;

	if (!*s)
		return NULL;
	e = strchr(s, '\n');
	if (e) {
		*e = 0;
		*p = e + 1;
	} else {
		*p = s + strlen(s);
	}
	return s;
}

/* A tile line "    {...}," -> its "{...}" (modifies the text). */
static char *tile_entry(char *ln, unsigned long long *index)
{
	size_t n;

	while (*ln == ' ')
		ln++;
	if (sscanf(ln, "{\"index\": %llu,", index) != 1)
		return NULL;
	n = strlen(ln);
	if (n && ln[n - 1] == ',')
		ln[--n] = 0;
	return n && ln[n - 1] == '}' ? ln : NULL;
}

/* Read this shard's earlier manifest: keep the tiles whose files verify. */
uint64_t export_resume(struct export_ctx *c, const char *prog)
{
	char *text = tiles_read_text(c->manifest, (size_t)1 << 40, NULL), *p, *ln;
	uint64_t kept = 0;
	char expect[256];

	if (!text) {
		if (errno != ENOENT)
			cli_fail(prog, "%s: %s", c->manifest, strerror(errno));
		return 0;
	}
	p = text;
	snprintf(expect, sizeof expect, "  \"shard\": [%u, %u],", c->j->shard_i,
	         c->j->shard_n);
	while ((ln = next_line(&p)) != NULL) {
		unsigned long long index;
		char *e;
		if (strncmp(ln, "  \"params\": ", 12) == 0) {
			size_t n = strlen(ln);
			if (n < 13 || strncmp(ln + 12, c->params, n - 13) != 0 ||
			    strlen(c->params) != n - 13)
				cli_fail(prog, "%s belongs to another export (different fabric, "
				         "format, channels, region or tile): use another -o DIR or "
				         "remove it", c->manifest);
			continue;
		}
		if (strncmp(ln, "  \"shard\": ", 11) == 0 && strcmp(ln, expect) != 0)
			cli_fail(prog, "%s belongs to another shard", c->manifest);
		if ((e = tile_entry(ln, &index)) == NULL)
			continue;
		if (index >= c->j->total || index % c->j->shard_n != c->j->shard_i)
			continue;
		uint64_t k = (index - c->j->shard_i) / c->j->shard_n;
		if (c->lines[k] || verify_line(c->dir, e, c->w[0].io, 1) != 0)
			continue;
		if (!(c->lines[k] = strdup(e)))
			cli_fail(prog, "out of memory");
		c->skip[k] = 1;
		kept++;
	}
	free(text);
	c->ndone = kept;
	return kept;
}

/* Remove temporary files a killed run of this shard left behind. */
void export_remove_stale(struct export_ctx *c)
{
	DIR *dp = opendir(c->dir);
	struct dirent *de;
	const char *mbase = strrchr(c->manifest, '/') + 1;

	if (!dp)
		return;
	while ((de = readdir(dp)) != NULL) {
		unsigned long long t[3];
		char path[4096];
		int mine = 0;
		if (!strstr(de->d_name, ".tmp."))
			continue;
		if (strncmp(de->d_name, mbase, strlen(mbase)) == 0 &&
		    strncmp(de->d_name + strlen(mbase), ".tmp.", 5) == 0)
			mine = 1;
		else if (sscanf(de->d_name, "tile-%llu-%llu-%llu.", &t[0], &t[1], &t[2]) == 3 &&
		         t[0] < c->j->nt[0] && t[1] < c->j->nt[1] && t[2] < c->j->nt[2]) {
			uint64_t idx = (t[2] * c->j->nt[1] + t[1]) * c->j->nt[0] + t[0];
			mine = idx % c->j->shard_n == c->j->shard_i;
		}
		if (!mine)
			continue;
		snprintf(path, sizeof path, "%s/%s", c->dir, de->d_name);
		unlink(path);
	}
	closedir(dp);
}

/* ---- --merge ------------------------------------------------------------------ */

struct mline {
	unsigned long long index;
	char *text;
};

static int cmp_mline(const void *a, const void *b)
{
	const struct mline *x = a, *y = b;
	return x->index < y->index ? -1 : x->index > y->index;
}

int export_merge(const char *prog, const char *dir, int json)
{
	DIR *dp = opendir(dir);
	struct dirent *de;
	uint32_t n = 0;
	uint8_t *seen = NULL;
	char *params = NULL, **texts = NULL, path[4096], msg[LOOM_DIAG_MSG_MAX];
	unsigned long long total = 0;
	struct mline *ml = NULL;
	size_t nml = 0, cap = 0;
	char **lines;
	uint8_t buf[1];

	(void)buf;
	if (!dp)
		cli_fail(prog, "cannot open %s: %s", dir, strerror(errno));
	while ((de = readdir(dp)) != NULL) {
		unsigned si, sn;
		char tail[8], *text, *p, *ln;
		int complete = -1, have_total = 0;
		if (sscanf(de->d_name, "manifest-%u-of-%u.jso%1s", &si, &sn, tail) != 3 ||
		    strcmp(tail, "n") != 0)
			continue;
		if (sn < 2 || si >= sn)
			continue;
		if (n == 0) {
			n = sn;
			seen = calloc(n, 1);
			texts = calloc(n, sizeof *texts);
			if (!seen || !texts)
				cli_fail(prog, "out of memory");
		} else if (sn != n) {
			cli_fail(prog, "%s: shards of a %u-way split and of a %u-way split in %s",
			         de->d_name, sn, n, dir);
		}
		snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
		text = tiles_read_text(path, (size_t)1 << 40, NULL);
		if (!text)
			cli_fail(prog, "%s: %s", path, strerror(errno));
		seen[si] = 1;
		texts[si] = text;
		p = text;
		while ((ln = next_line(&p)) != NULL) {
			unsigned long long index, t;
			char *e;
			if (strncmp(ln, "  \"params\": ", 12) == 0) {
				size_t len = strlen(ln);
				if (len > 13)
					ln[len - 1] = 0; /* the comma */
				if (!params)
					params = ln + 12;
				else if (strcmp(params, ln + 12) != 0)
					cli_fail(prog, "%s: parameters differ from the other shards'", path);
			} else if (sscanf(ln, "  \"tiles_total\": %llu,", &t) == 1) {
				if (total && t != total)
					cli_fail(prog, "%s: tiles_total differs from the other shards'", path);
				total = t;
				have_total = 1;
			} else if (strcmp(ln, "  \"complete\": true,") == 0) {
				complete = 1;
			} else if (strcmp(ln, "  \"complete\": false,") == 0) {
				complete = 0;
			} else if ((e = tile_entry(ln, &index)) != NULL) {
				if (index % n != si)
					cli_fail(prog, "%s: tile %llu is not in shard %u/%u", path, index, si, n);
				if (verify_line(dir, e, NULL, 0) != 0)
					cli_fail(prog, "%s: the files of tile %llu are missing or have "
					         "another size", path, index);
				if (nml == cap) {
					cap = cap ? 2 * cap : 1024;
					ml = realloc(ml, cap * sizeof *ml);
					if (!ml)
						cli_fail(prog, "out of memory");
				}
				ml[nml].index = index;
				ml[nml].text = e;
				nml++;
			}
		}
		if (!have_total || !params)
			cli_fail(prog, "%s: not a loom export manifest", path);
		if (complete != 1)
			cli_fail(prog, "%s: shard %u/%u is not complete: run it again", path, si, n);
	}
	closedir(dp);
	if (n == 0)
		cli_fail(prog, "no shard manifests (manifest-I-of-N.json) in %s", dir);
	for (uint32_t i = 0; i < n; i++)
		if (!seen[i])
			cli_fail(prog, "shard %u/%u has no manifest in %s (run it, then merge)", i, n,
			         dir);
	qsort(ml, nml, sizeof *ml, cmp_mline);
	for (size_t i = 1; i < nml; i++)
		if (ml[i].index == ml[i - 1].index)
			cli_fail(prog, "tile %llu is listed twice", ml[i].index);
	if (nml != total)
		cli_fail(prog, "the shards list %zu tiles, the region has %llu", nml, total);
	lines = malloc((nml ? nml : 1) * sizeof *lines);
	if (!lines)
		cli_fail(prog, "out of memory");
	for (size_t i = 0; i < nml; i++)
		lines[i] = ml[i].text;
	snprintf(path, sizeof path, "%s/manifest.json", dir);
	if (manifest_write(path, params, 0, 1, total, lines, nml, 1, msg, sizeof msg))
		cli_fail(prog, "%s", msg);
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "manifest", path);
		jw_uint(&w, "shards", n);
		jw_uint(&w, "tiles", nml);
		jw_end(&w);
	} else {
		printf("merged %u shard manifests (%zu tiles) into %s\n", n, nml, path);
	}
	for (uint32_t i = 0; i < n; i++)
		free(texts[i]);
	free(texts);
	free(seen);
	free(ml);
	free(lines);
	return 0;
}
