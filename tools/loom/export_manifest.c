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

/* Write a manifest atomically: lines[perm[0..n)] (lines[0..n) when perm is
   NULL; NULL entries skipped) in that order. */
static int manifest_write(const char *path, const char *params, uint32_t shard_i,
                          uint32_t shard_n, uint64_t total, char *const *lines,
                          const uint64_t *perm, uint64_t n, int complete, char *msg,
                          size_t msz)
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
		const char *ln = lines[perm ? perm[i] : i];
		if (!ln)
			continue;
		fprintf(fp, "%s\n    %s", done ? "," : "", ln);
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

static int cmp_k_by_index(const void *a, const void *b, void *order)
{
	const uint64_t *o = order;
	uint64_t x = o[*(const uint64_t *)a], y = o[*(const uint64_t *)b];
	return x < y ? -1 : x > y;
}

void export_sort_by_index(struct export_ctx *c)
{
	for (uint64_t k = 0; k < c->n; k++)
		c->byidx[k] = k;
	qsort_r(c->byidx, c->n, sizeof *c->byidx, cmp_k_by_index, c->order); /* glibc */
}

uint64_t export_k_of(const struct export_ctx *c, uint64_t index)
{
	uint64_t a = 0, b = c->n;

	while (a < b) {
		uint64_t m = a + (b - a) / 2;
		if (c->order[c->byidx[m]] < index)
			a = m + 1;
		else
			b = m;
	}
	return a < c->n && c->order[c->byidx[a]] == index ? c->byidx[a] : UINT64_MAX;
}

int export_manifest_flush(struct export_ctx *c, int final)
{
	int rc;
	double t0 = cli_now();

	pthread_mutex_lock(&c->lock);
	rc = manifest_write(c->manifest, c->params, c->j->shard_i, c->j->shard_n,
	                    c->j->total, c->lines, c->byidx, c->n, final && c->ndone == c->n,
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
		uint64_t k = index < c->j->total ? export_k_of(c, index) : UINT64_MAX;
		if (k == UINT64_MAX)
			continue; /* not this shard's (a manifest of the old round-robin
			             split): written again */
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

/* Remove the temporary files of this shard's tiles and manifest.  The
   caller holds the shard's lock (shard_lock.h): no live process writes
   them, so each is a dead run's. */
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
			mine = export_k_of(c, idx) != UINT64_MAX;
		}
		if (!mine)
			continue;
		snprintf(path, sizeof path, "%s/%s", c->dir, de->d_name);
		unlink(path);
	}
	closedir(dp);
}

/* ---- reading manifests (--merge, --status) ------------------------------------ */

struct mline {
	unsigned long long index;
	char *text;            /* the tile's "{...}" inside mfile.text */
	uint32_t shard;        /* the manifest it came from */
};

/* One manifest read whole, its lines cut in place. */
struct mfile {
	char *text;
	char *params;          /* the "params" value */
	unsigned long long total;
	int complete;          /* 1, 0, or -1 when not said */
	uint32_t shard_i, shard_n;  /* from its "shard" line (0, 1 when none) */
};

static int cmp_mline(const void *a, const void *b)
{
	const struct mline *x = a, *y = b;
	return x->index < y->index ? -1 : x->index > y->index;
}

/* Read path into m and append its tiles to *ml (shard: the number to
   record in each).  Exits 1 with a message on a file that is not a
   manifest. */
static void manifest_read(const char *prog, const char *path, struct mfile *m,
                          struct mline **ml, size_t *nml, size_t *cap, uint32_t shard)
{
	char *p, *ln;
	int have_total = 0;

	memset(m, 0, sizeof *m);
	m->complete = -1;
	m->shard_n = 1;
	m->text = tiles_read_text(path, (size_t)1 << 40, NULL);
	if (!m->text)
		cli_fail(prog, "%s: %s", path, strerror(errno));
	p = m->text;
	while ((ln = next_line(&p)) != NULL) {
		unsigned long long index, t;
		unsigned si, sn;
		char *e;
		if (strncmp(ln, "  \"params\": ", 12) == 0) {
			size_t len = strlen(ln);
			if (len > 13)
				ln[len - 1] = 0; /* the comma */
			m->params = ln + 12;
		} else if (sscanf(ln, "  \"shard\": [%u, %u],", &si, &sn) == 2) {
			m->shard_i = si;
			m->shard_n = sn;
		} else if (sscanf(ln, "  \"tiles_total\": %llu,", &t) == 1) {
			m->total = t;
			have_total = 1;
		} else if (strcmp(ln, "  \"complete\": true,") == 0) {
			m->complete = 1;
		} else if (strcmp(ln, "  \"complete\": false,") == 0) {
			m->complete = 0;
		} else if ((e = tile_entry(ln, &index)) != NULL) {
			if (index >= m->total && have_total)
				cli_fail(prog, "%s: tile %llu is outside the region's %llu tiles", path,
				         index, m->total);
			if (*nml == *cap) {
				*cap = *cap ? 2 * *cap : 1024;
				*ml = realloc(*ml, *cap * sizeof **ml);
				if (!*ml)
					cli_fail(prog, "out of memory");
			}
			(*ml)[*nml].index = index;
			(*ml)[*nml].text = e;
			(*ml)[*nml].shard = shard;
			(*nml)++;
		}
	}
	if (!have_total || !m->params)
		cli_fail(prog, "%s: not a loom export manifest", path);
}

/* The shard manifests of dir: n (0 when none) and, per shard, whether its
   manifest is there (seen).  Mixed splits: exit 1. */
static uint32_t shard_files(const char *prog, const char *dir, uint8_t **seen)
{
	DIR *dp = opendir(dir);
	struct dirent *de;
	uint32_t n = 0;

	*seen = NULL;
	if (!dp)
		cli_fail(prog, "cannot open %s: %s", dir, strerror(errno));
	while ((de = readdir(dp)) != NULL) {
		unsigned si, sn;
		char tail[8], exact[64];
		if (sscanf(de->d_name, "manifest-%u-of-%u.jso%1s", &si, &sn, tail) != 3 ||
		    strcmp(tail, "n") != 0 || sn < 2 || si >= sn)
			continue;
		/* exactly the name (not a temporary "....json.tmp.PID") */
		snprintf(exact, sizeof exact, "manifest-%u-of-%u.json", si, sn);
		if (strcmp(de->d_name, exact) != 0)
			continue;
		if (n == 0) {
			n = sn;
			*seen = calloc(n, 1);
			if (!*seen)
				cli_fail(prog, "out of memory");
		} else if (sn != n) {
			cli_fail(prog, "%s: shards of a %u-way split and of a %u-way split in %s",
			         de->d_name, sn, n, dir);
		}
		(*seen)[si] = 1;
	}
	closedir(dp);
	return n;
}

/* ---- --merge ------------------------------------------------------------------ */

int export_merge(const char *prog, const char *dir, int json, int quiet)
{
	uint8_t *seen, *bad;
	uint32_t n = shard_files(prog, dir, &seen);
	struct mfile *mf;
	char *params = NULL, path[4096], msg[LOOM_DIAG_MSG_MAX + 4096];
	unsigned long long total = 0;
	struct mline *ml = NULL;
	size_t nml = 0, cap = 0;
	uint32_t nbad = 0;
	char **lines;
	shard_lock lk = {-1};

	if (n == 0)
		cli_fail(prog, "no shard manifests (manifest-I-of-N.json) in %s", dir);
	if (shard_lock_merge(&lk, dir, n, msg, sizeof msg) != 0)
		cli_fail(prog, "%s", msg);
	mf = calloc(n, sizeof *mf);
	bad = calloc(n, 1);
	if (!mf || !bad)
		cli_fail(prog, "out of memory");
	for (uint32_t i = 0; i < n; i++) {
		if (!seen[i]) {
			bad[i] = 1;
			nbad++;
			continue;
		}
		snprintf(path, sizeof path, "%s/manifest-%u-of-%u.json", dir, i, n);
		manifest_read(prog, path, &mf[i], &ml, &nml, &cap, i);
		if (mf[i].shard_n != n || mf[i].shard_i != i)
			cli_fail(prog, "%s: says it is shard %u/%u", path, mf[i].shard_i, mf[i].shard_n);
		if (!params)
			params = mf[i].params;
		else if (strcmp(params, mf[i].params) != 0)
			cli_fail(prog, "%s: parameters differ from the other shards'", path);
		if (total && mf[i].total != total)
			cli_fail(prog, "%s: tiles_total differs from the other shards'", path);
		total = mf[i].total;
		if (mf[i].complete != 1) {
			bad[i] = 1;
			nbad++;
		}
	}
	if (nbad) {
		char *all = tiles_list_text(bad, n), *none;
		for (uint32_t i = 0; i < n; i++)
			bad[i] = !seen[i];
		none = tiles_list_text(bad, n);
		cli_fail(prog, "%s: %u of %u shards not complete: %s (no manifest: %s): run them "
		         "again (they resume; e.g. sbatch --array=%s with LOOM_SHARD_COUNT=%u, or "
		         "--shard I/%u), then merge; `loom export --status %s` lists the tiles",
		         dir, nbad, n, all ? all : "?", none && *none ? none : "none",
		         all ? all : "?", n, n, dir);
	}
	for (size_t t = 0; t < nml; t++)
		if (verify_line(dir, ml[t].text, NULL, 0) != 0)
			cli_fail(prog, "%s/manifest-%u-of-%u.json: the files of tile %llu are missing "
			         "or have another size: run shard %u/%u again (it rewrites them), then "
			         "merge", dir, ml[t].shard, n, ml[t].index, ml[t].shard, n);
	qsort(ml, nml, sizeof *ml, cmp_mline);
	for (size_t i = 1; i < nml; i++)
		if (ml[i].index == ml[i - 1].index)
			cli_fail(prog, "tile %llu is listed twice (shards %u and %u of %u)",
			         ml[i].index, ml[i - 1].shard, ml[i].shard, n);
	if (nml != total)
		cli_fail(prog, "the shards list %zu tiles, the region has %llu", nml, total);
	lines = malloc((nml ? nml : 1) * sizeof *lines);
	if (!lines)
		cli_fail(prog, "out of memory");
	for (size_t i = 0; i < nml; i++)
		lines[i] = ml[i].text;
	snprintf(path, sizeof path, "%s/manifest.json", dir);
	if (manifest_write(path, params, 0, 1, total, lines, NULL, nml, 1, msg, sizeof msg))
		cli_fail(prog, "%s", msg);
	shard_lock_release(&lk);
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "manifest", path);
		jw_uint(&w, "shards", n);
		jw_uint(&w, "tiles", nml);
		jw_end(&w);
	} else if (!quiet) {
		printf("merged %u shard manifests (%zu tiles) into %s\n", n, nml, path);
	}
	for (uint32_t i = 0; i < n; i++)
		free(mf[i].text);
	free(mf);
	free(seen);
	free(bad);
	free(ml);
	free(lines);
	return 0;
}

/* ---- --status ----------------------------------------------------------------- */

#define STATUS_LIST_MAX 1000 /* tiles named in the report, of each kind */

/* Why tile line `line` is damaged (a file missing, of another size or,
   with crc, another CRC-32), into why; 0 when it is whole. */
static int damaged_why(const char *dir, const char *line, uint8_t *buf, int crc,
                       char *why, size_t wsz)
{
	const char *p = after(line, "\"files\": [");

	if (!p) {
		snprintf(why, wsz, "no files listed");
		return -1;
	}
	while ((p = after(p, "{\"name\": \"")) != NULL) {
		char name[512], path[4096];
		const char *q = strchr(p, '"');
		unsigned long long bytes;
		unsigned want;
		uint32_t fcrc;
		uint64_t fbytes;
		struct stat st;

		if (!q || (size_t)(q - p) >= sizeof name ||
		    sscanf(q, "\", \"bytes\": %llu, \"crc32\": \"%8x\"}", &bytes, &want) != 2) {
			snprintf(why, wsz, "a malformed file entry");
			return -1;
		}
		memcpy(name, p, (size_t)(q - p));
		name[q - p] = 0;
		snprintf(path, sizeof path, "%s/%s", dir, name);
		if (strchr(name, '/') || stat(path, &st) != 0) {
			snprintf(why, wsz, "%s is missing", name);
			return -1;
		}
		if ((uint64_t)st.st_size != bytes) {
			snprintf(why, wsz, "%s has %llu bytes, the manifest says %llu", name,
			         (unsigned long long)st.st_size, bytes);
			return -1;
		}
		if (crc && (export_file_crc(path, buf, &fcrc, &fbytes) || fcrc != want)) {
			snprintf(why, wsz, "%s has CRC-32 %08x, the manifest says %08x", name, fcrc,
			         want);
			return -1;
		}
		p = q;
	}
	return 0;
}

int export_status(const char *prog, const char *dir, int json, int quiet, int verify)
{
	uint8_t *seen, *rerun = NULL, *running = NULL, *listed, *buf = NULL;
	uint32_t n = shard_files(prog, dir, &seen), nm = n ? n : 1;
	struct mfile *mf = calloc(nm, sizeof *mf);
	struct mline *ml = NULL;
	size_t nml = 0, cap = 0;
	unsigned long long total = 0, ncomplete = 0, nmissing, ndamaged = 0;
	uint64_t *damaged = NULL, *missing = NULL;
	char (*why)[600] = NULL;
	size_t nd = 0, nmi = 0;
	char path[4096];
	const char *params = NULL;
	int merged = 0, complete;
	struct stat st;

	if (!mf)
		cli_fail(prog, "out of memory");
	snprintf(path, sizeof path, "%s/manifest.json", dir);
	merged = n > 0 && stat(path, &st) == 0;
	if (n == 0) {
		if (stat(path, &st) != 0)
			cli_fail(prog, "no manifest (manifest.json or manifest-I-of-N.json) in %s",
			         dir);
		manifest_read(prog, path, &mf[0], &ml, &nml, &cap, 0);
		params = mf[0].params;
		total = mf[0].total;
	}
	for (uint32_t i = 0; i < n; i++) {
		if (!seen[i])
			continue;
		snprintf(path, sizeof path, "%s/manifest-%u-of-%u.json", dir, i, n);
		manifest_read(prog, path, &mf[i], &ml, &nml, &cap, i);
		if (params && strcmp(params, mf[i].params) != 0)
			cli_fail(prog, "%s: parameters differ from the other shards' (another "
			         "export in the same directory)", path);
		if (total && mf[i].total != total)
			cli_fail(prog, "%s: tiles_total differs from the other shards'", path);
		params = mf[i].params;
		total = mf[i].total;
	}
	listed = calloc(total / 8 + 1, 1);
	rerun = calloc(nm, 1);
	running = calloc(nm, 1);
	buf = malloc(CRC_BUF);
	damaged = malloc(STATUS_LIST_MAX * sizeof *damaged);
	missing = malloc(STATUS_LIST_MAX * sizeof *missing);
	why = malloc(STATUS_LIST_MAX * sizeof *why);
	if (!listed || !rerun || !running || !buf || !damaged || !missing || !why)
		cli_fail(prog, "out of memory");
	/* each listed tile: once, with its files whole */
	for (size_t t = 0; t < nml; t++) {
		unsigned long long idx = ml[t].index;
		char w[600];
		int bad = 0;
		if (idx >= total)
			cli_fail(prog, "%s: tile %llu is outside the region's %llu tiles", dir, idx,
			         total);
		if (listed[idx / 8] & (1u << (idx % 8))) {
			snprintf(w, sizeof w, "listed twice");
			bad = 1;
		} else {
			listed[idx / 8] |= (uint8_t)(1u << (idx % 8));
			bad = damaged_why(dir, ml[t].text, buf, verify, w, sizeof w) != 0;
		}
		if (!bad) {
			ncomplete++;
			continue;
		}
		ndamaged++;
		rerun[ml[t].shard] = 1;
		if (nd < STATUS_LIST_MAX) {
			damaged[nd] = idx;
			snprintf(why[nd++], sizeof *why, "%s", w);
		}
	}
	nmissing = 0;
	for (unsigned long long idx = 0; idx < total; idx++)
		if (!(listed[idx / 8] & (1u << (idx % 8)))) {
			if (nmi < STATUS_LIST_MAX)
				missing[nmi++] = idx;
			nmissing++;
		}
	/* shards to run again: no manifest, not complete, or a damaged tile */
	for (uint32_t i = 0; i < n; i++)
		if (!seen[i] || mf[i].complete != 1)
			rerun[i] = 1;
	if (n == 0 && (mf[0].complete != 1 || nmissing || ndamaged))
		rerun[0] = 1;
	if (n)
		shard_lock_running(dir, n, running);
	else
		shard_lock_running(dir, 1, running);
	complete = nmissing == 0 && ndamaged == 0;
	{
		char *rr = tiles_list_text(rerun, nm), *run = tiles_list_text(running, nm);
		uint8_t *ok = calloc(nm, 1);
		char *okl;
		if (!rr || !run || !ok)
			cli_fail(prog, "out of memory");
		for (uint32_t i = 0; i < nm; i++)
			ok[i] = !rerun[i];
		okl = tiles_list_text(ok, nm);
		if (!okl)
			cli_fail(prog, "out of memory");
		if (json) {
			json_w w;
			jw_begin(&w, stdout);
			jw_str(&w, "dir", dir);
			jw_bool(&w, "complete", complete);
			jw_bool(&w, "merged", merged);
			jw_bool(&w, "verified_crc32", verify);
			jw_uint(&w, "tiles_total", total);
			jw_uint(&w, "tiles_complete", ncomplete);
			jw_uint(&w, "tiles_missing", nmissing);
			jw_uint(&w, "tiles_damaged", ndamaged);
			jw_uint(&w, "shards", n);
			jw_str(&w, "shards_complete", n ? okl : "");
			jw_str(&w, "shards_to_run", n ? rr : "");
			jw_str(&w, "shards_running", n ? run : "");
			if (n) {
				jw_arr(&w, "shard_manifests");
				for (uint32_t i = 0; i < n; i++) {
					jw_obj(&w, NULL);
					jw_uint(&w, "shard", i);
					jw_bool(&w, "manifest", seen[i]);
					jw_bool(&w, "complete", seen[i] && mf[i].complete == 1);
					jw_bool(&w, "running", running[i]);
					jw_close(&w);
				}
				jw_close(&w);
			}
			jw_arr(&w, "missing");
			for (size_t i = 0; i < nmi; i++)
				jw_uint(&w, NULL, missing[i]);
			jw_close(&w);
			jw_arr(&w, "damaged");
			for (size_t i = 0; i < nd; i++) {
				jw_obj(&w, NULL);
				jw_uint(&w, "index", damaged[i]);
				jw_str(&w, "why", why[i]);
				jw_close(&w);
			}
			jw_close(&w);
			jw_bool(&w, "lists_truncated", nmi < nmissing || nd < ndamaged);
			jw_end(&w);
		} else if (!quiet) {
			printf("%s: %llu tiles%s: %llu complete, %llu missing, %llu damaged%s\n", dir,
			       total, n ? "" : " (unsharded)", ncomplete, nmissing, ndamaged,
			       complete ? (n && !merged ? " (not merged yet)" : "") : "");
			if (n) {
				printf("  shards: %u; complete: %s; to run again: %s", n, *okl ? okl : "none",
				       *rr ? rr : "none");
				if (*run)
					printf("; running now: %s", run);
				printf("\n");
			}
			if (nmi) {
				printf("  missing tiles:");
				for (size_t i = 0; i < nmi; i++)
					printf(" %llu", (unsigned long long)missing[i]);
				printf("%s\n", nmi < nmissing ? " ..." : "");
			}
			for (size_t i = 0; i < nd; i++)
				printf("  damaged tile %llu: %s\n", (unsigned long long)damaged[i], why[i]);
			if (nd < ndamaged)
				printf("  ... and %llu more damaged tiles\n", ndamaged - nd);
		}
		free(rr);
		free(run);
		free(ok);
		free(okl);
	}
	for (uint32_t i = 0; i < nm; i++)
		free(mf[i].text);
	free(mf);
	free(ml);
	free(seen);
	free(listed);
	free(rerun);
	free(running);
	free(buf);
	free(damaged);
	free(missing);
	free(why);
	return complete ? 0 : EXIT_BAD_INPUT;
}
