/*
 * tools/loom/serve.h - pieces of `loom serve` (cmd_serve.c): the bounded
 * on-disk tile cache (serve_cache.c).
 */
#ifndef LOOM_SERVE_H
#define LOOM_SERVE_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

/*
 * A directory of cached files (tiles, drawdowns) whose total size stays
 * under max_bytes: files are named by the caller (a key), registered when
 * written, touched when served, and the least recently used are deleted
 * when the total passes the limit.  Existing files of the directory are
 * adopted at open (oldest first by modification time).  Thread-safe.
 */
typedef struct serve_cache serve_cache;

/* Open (creating dir); NULL with a message in err on failure. */
serve_cache *serve_cache_open(const char *dir, uint64_t max_bytes, char *err,
                              size_t n);
void serve_cache_close(serve_cache *c);
/* The path of key in the cache directory (no check that it exists). */
void serve_cache_path(const serve_cache *c, const char *key, char *buf, size_t n);
/* 1 and touched if key is cached (and its file is still there). */
int serve_cache_lookup(serve_cache *c, const char *key);
/* Register a file just written under key; evicts old files if needed. */
void serve_cache_add(serve_cache *c, const char *key);
/* Bytes and files held. */
void serve_cache_usage(serve_cache *c, uint64_t *bytes, uint32_t *files);

#endif
