/*
 * tools/loom/serve_cache.c - the bounded on-disk tile cache of loom serve
 * (serve.h).
 *
 * Index: an array of entries (key, bytes, last use), searched linearly: a
 * cache of a few hundred MiB holds some thousands of tiles, and a search
 * costs microseconds beside the milliseconds of making a tile.  The
 * clock is a counter bumped on every lookup or add, so "least recently
 * used" does not depend on the wall clock.  Eviction deletes the entry
 * with the smallest last use until the total is under the limit (the file
 * just added is never the one deleted).
 */
#include "serve.h"

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define KEY_MAX 96

typedef struct entry {
	char key[KEY_MAX];
	uint64_t bytes;
	uint64_t used;
} entry;

struct serve_cache {
	char dir[4096];
	uint64_t max_bytes, bytes, clock;
	entry *e;
	uint32_t n, cap;
	pthread_mutex_t lock;
};

void serve_cache_path(const serve_cache *c, const char *key, char *buf, size_t n)
{
	snprintf(buf, n, "%s/%s", c->dir, key);
}

static entry *find(serve_cache *c, const char *key)
{
	for (uint32_t k = 0; k < c->n; k++)
		if (!strcmp(c->e[k].key, key))
			return &c->e[k];
	return NULL;
}

static void drop(serve_cache *c, uint32_t k)
{
	char path[4200];

	serve_cache_path(c, c->e[k].key, path, sizeof path);
	unlink(path);
	c->bytes -= c->e[k].bytes;
	c->e[k] = c->e[--c->n];
}

static void evict(serve_cache *c, const char *keep)
{
	while (c->bytes > c->max_bytes && c->n > 1) {
		uint32_t old = UINT32_MAX;
		for (uint32_t k = 0; k < c->n; k++)
			if (strcmp(c->e[k].key, keep) &&
			    (old == UINT32_MAX || c->e[k].used < c->e[old].used))
				old = k;
		if (old == UINT32_MAX)
			break;
		drop(c, old);
	}
}

static int put(serve_cache *c, const char *key, uint64_t bytes, uint64_t used)
{
	entry *e = find(c, key);

	if (!e) {
		if (c->n == c->cap) {
			uint32_t nc = c->cap ? 2 * c->cap : 256;
			entry *g = realloc(c->e, (size_t)nc * sizeof *g);
			if (!g)
				return -1;
			c->e = g;
			c->cap = nc;
		}
		e = &c->e[c->n++];
		strncpy(e->key, key, sizeof e->key - 1);
		e->key[sizeof e->key - 1] = 0;
		e->bytes = 0;
	}
	c->bytes += bytes - e->bytes;
	e->bytes = bytes;
	e->used = used;
	return 0;
}

typedef struct found {
	char key[KEY_MAX];
	uint64_t bytes;
	time_t mtime;
} found;

static int by_mtime(const void *a, const void *b)
{
	const found *x = a, *y = b;
	return x->mtime < y->mtime ? -1 : x->mtime > y->mtime;
}

serve_cache *serve_cache_open(const char *dir, uint64_t max_bytes, char *err, size_t n)
{
	serve_cache *c = calloc(1, sizeof *c);
	DIR *dp;
	struct dirent *de;
	found *f = NULL;
	size_t nf = 0, cf = 0;

	if (!c) {
		snprintf(err, n, "out of memory");
		return NULL;
	}
	snprintf(c->dir, sizeof c->dir, "%s", dir);
	c->max_bytes = max_bytes;
	pthread_mutex_init(&c->lock, NULL);
	if (mkdir(dir, 0700) != 0 && errno != EEXIST) {
		snprintf(err, n, "%s: cannot create the tile cache: %s", dir, strerror(errno));
		serve_cache_close(c);
		return NULL;
	}
	dp = opendir(dir);
	if (!dp) {
		snprintf(err, n, "%s: cannot open the tile cache: %s", dir, strerror(errno));
		serve_cache_close(c);
		return NULL;
	}
	while ((de = readdir(dp)) != NULL) {
		char path[4400];
		struct stat st;
		size_t len = strlen(de->d_name);
		if (de->d_name[0] == '.' || len >= KEY_MAX || len < 5 ||
		    strcmp(de->d_name + len - 4, ".png"))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
		if (stat(path, &st) != 0 || !S_ISREG(st.st_mode))
			continue;
		if (nf == cf) {
			size_t nc = cf ? 2 * cf : 256;
			found *g = realloc(f, nc * sizeof *g);
			if (!g)
				break;
			f = g;
			cf = nc;
		}
		memcpy(f[nf].key, de->d_name, len + 1); /* len < KEY_MAX */
		f[nf].bytes = (uint64_t)st.st_size;
		f[nf].mtime = st.st_mtime;
		nf++;
	}
	closedir(dp);
	if (nf)
		qsort(f, nf, sizeof *f, by_mtime);
	for (size_t k = 0; k < nf; k++)
		put(c, f[k].key, f[k].bytes, ++c->clock);
	free(f);
	evict(c, "");
	return c;
}

void serve_cache_close(serve_cache *c)
{
	if (!c)
		return;
	pthread_mutex_destroy(&c->lock);
	free(c->e);
	free(c);
}

int serve_cache_lookup(serve_cache *c, const char *key)
{
	char path[4200];
	entry *e;
	int hit = 0;

	pthread_mutex_lock(&c->lock);
	e = find(c, key);
	if (e) {
		serve_cache_path(c, key, path, sizeof path);
		if (access(path, R_OK) == 0) {
			e->used = ++c->clock;
			hit = 1;
		} else {
			c->bytes -= e->bytes;
			*e = c->e[--c->n];
		}
	}
	pthread_mutex_unlock(&c->lock);
	return hit;
}

void serve_cache_add(serve_cache *c, const char *key)
{
	char path[4200];
	struct stat st;

	serve_cache_path(c, key, path, sizeof path);
	if (stat(path, &st) != 0)
		return;
	pthread_mutex_lock(&c->lock);
	if (put(c, key, (uint64_t)st.st_size, ++c->clock) == 0)
		evict(c, key);
	pthread_mutex_unlock(&c->lock);
}

void serve_cache_usage(serve_cache *c, uint64_t *bytes, uint32_t *files)
{
	pthread_mutex_lock(&c->lock);
	*bytes = c->bytes;
	*files = c->n;
	pthread_mutex_unlock(&c->lock);
}
