/*
 * tools/loom/cmd_scan.c - `loom scan FABRIC`: stream every voxel of a region
 * (or of a whole bolt) through a reducer, tile by tile on a pool of threads,
 * in a fixed memory budget; `loom scan --combine` adds up the results of
 * shards.  docs/batch.md describes the reducers and their JSON.
 *
 * Checksum.  Voxel (x, y, z) with 0 <= z < b3 (voxels outside are empty
 * and not read), a = density | orientation << 8 | kind << 24, t = type:
 *   h = ((a ^ K1[z]) * M1) ^ ((t ^ K2[z]) * M2);  h ^= h >> 15;
 *   h *= M3;  h ^= h >> 13                                  (32-bit words)
 * with K1[z], K2[z] the low and high halves of mix(z ^ SEED_Z); per voxel
 * column S(x, y) = the 64-bit sum of h over its z; the checksum is the sum
 * over columns of S(x, y) * (mix(mix(x) ^ y) | 1), mod 2^64.  The sums
 * are order-free and split at any z, so threads, tiles, budgets and shards
 * give the same value, and the checksums of disjoint parts add.  32-bit
 * words let the column loop run 8 voxels at a time (AVX2 when the CPU has
 * it, the same arithmetic in plain C otherwise).
 */
#include "cli.h"
#include "commands.h"
#include "export.h"
#include "tiles.h"

#include "io/core/file.h" /* io/: atomic output files (-o) */

#include <errno.h>
#include <immintrin.h>
#include <libdeflate.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"loom scan FABRIC (--region X0,Y0,Z0:X1,Y1,Z1 | --all [--bolt LxW])\n"
	"          --reduce checksum|histogram|coverage [--bins B]\n"
	"          [--tile TX,TY[,TZ]] [--shard I/N] [--budget MB]\n"
	"          [--threads N] [--db DB] [-o RESULT] [--quiet] [--json]\n"
	"loom scan --combine PART.json... [-o RESULT] [--quiet] [--json]\n";

static const char about[] =
	"Stream every voxel of a region of the fabric's virtual texture through a\n"
	"reducer, in tiles, on N threads, within a fixed memory budget, and print\n"
	"the result with voxels per second and the peak resident memory\n"
	"(docs/batch.md).\n";

enum { R_CHECKSUM, R_HISTOGRAM, R_COVERAGE };
static const char *const reduce_names[] = {"checksum", "histogram", "coverage"};
static const opt_choice reduce_choices[] = {
	{"checksum", R_CHECKSUM}, {"histogram", R_HISTOGRAM}, {"coverage", R_COVERAGE},
	{NULL, 0}};

#define SEED_Z 0x6c6f6f6d7363616eull /* "loomscan" */
#define M1 0x9e3779b1u
#define M2 0x85ebca77u
#define M3 0xc2b2ae3du

static inline uint32_t vhash(uint32_t a, uint32_t t, uint32_t k1, uint32_t k2)
{
	uint32_t h = ((a ^ k1) * M1) ^ ((t ^ k2) * M2);
	h ^= h >> 15;
	h *= M3;
	return h ^ (h >> 13);
}

/* Sum of vhash over one column of nz voxels. */
static uint64_t col_sum_c(const uint8_t *d, const uint16_t *o, const uint8_t *k,
                          const uint8_t *t, const uint32_t *k1, const uint32_t *k2,
                          size_t nz)
{
	uint64_t s = 0;

	for (size_t z = 0; z < nz; z++)
		s += vhash((uint32_t)d[z] | (uint32_t)o[z] << 8 | (uint32_t)k[z] << 24, t[z],
		           k1[z], k2[z]);
	return s;
}

#if defined(__x86_64__) && defined(__GNUC__)
#define HAVE_AVX2_PATH 1
__attribute__((target("avx2"))) static uint64_t
col_sum_avx2(const uint8_t *d, const uint16_t *o, const uint8_t *k, const uint8_t *t,
             const uint32_t *k1, const uint32_t *k2, size_t nz)
{
	const __m256i m1 = _mm256_set1_epi32((int)M1), m2 = _mm256_set1_epi32((int)M2);
	const __m256i m3 = _mm256_set1_epi32((int)M3);
	__m256i acc = _mm256_setzero_si256();
	uint64_t lanes[4], s;
	size_t z = 0;

	for (; z + 8 <= nz; z += 8) {
		__m256i vd = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(d + z)));
		__m256i vo = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(o + z)));
		__m256i vk = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(k + z)));
		__m256i vt = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(t + z)));
		__m256i a = _mm256_or_si256(vd, _mm256_or_si256(_mm256_slli_epi32(vo, 8),
		                                                _mm256_slli_epi32(vk, 24)));
		__m256i h = _mm256_mullo_epi32(
		        _mm256_xor_si256(a, _mm256_loadu_si256((const __m256i *)(k1 + z))), m1);
		h = _mm256_xor_si256(h, _mm256_mullo_epi32(_mm256_xor_si256(
		        vt, _mm256_loadu_si256((const __m256i *)(k2 + z))), m2));
		h = _mm256_xor_si256(h, _mm256_srli_epi32(h, 15));
		h = _mm256_mullo_epi32(h, m3);
		h = _mm256_xor_si256(h, _mm256_srli_epi32(h, 13));
		acc = _mm256_add_epi64(acc, _mm256_cvtepu32_epi64(_mm256_castsi256_si128(h)));
		acc = _mm256_add_epi64(acc, _mm256_cvtepu32_epi64(_mm256_extracti128_si256(h, 1)));
	}
	_mm256_storeu_si256((__m256i *)lanes, acc);
	s = lanes[0] + lanes[1] + lanes[2] + lanes[3];
	return s + col_sum_c(d + z, o + z, k + z, t + z, k1 + z, k2 + z, nz - z);
}
#endif

/* Is voxel z of a column empty (every field 0)?  Empty voxels above and
   below the cloth are most of a column; their hashes depend on z alone, so
   the scan skips them and adds their precomputed sums (struct scan_ctx ep). */
static inline int vox_empty(const uint8_t *d, const uint16_t *o, const uint8_t *k,
                            const uint8_t *t, size_t z)
{
	return (d[z] | o[z] | k[z] | t[z]) == 0;
}

/* Are voxels z..z+7 all empty?  (8 bytes of d, k, t, 16 of o.) */
static inline int vox_empty8(const uint8_t *d, const uint16_t *o, const uint8_t *k,
                             const uint8_t *t, size_t z)
{
	uint64_t a, b, c, e, f;
	memcpy(&a, d + z, 8);
	memcpy(&b, k + z, 8);
	memcpy(&c, t + z, 8);
	memcpy(&e, o + z, 8);
	memcpy(&f, o + z + 4, 8);
	return (a | b | c | e | f) == 0;
}

typedef struct scan_result {
	int reduce;
	uint64_t voxels, tiles;
	uint64_t checksum;
	uint32_t bins, n_types;
	uint64_t *hist;        /* n_types * bins */
	uint64_t nonempty;     /* histogram: voxels with a yarn */
	uint64_t cov[3];       /* columns whose top is none, warp, weft */
	char (*names)[LOOM_YARN_NAME_MAX];
	/* where it came from */
	int64_t lo[3], hi[3];
	int64_t tile[3];
	uint32_t shard_i, shard_n;
	uint64_t fabric_bytes;
	char fabric_crc[9];    /* CRC-32 of the fabric file, hex ("" unknown) */
	uint64_t bytes_read;   /* --combine: the parts' sum */
} scan_result;

struct wstate {
	uint8_t *d, *k, *ty;
	uint16_t *o;
	uint64_t sum;
	uint64_t *hist;        /* n_types * 256 */
	uint64_t cov[3];
	uint64_t errors;
	char pad[64];
};

struct scan_ctx {
	tiles_job *j;
	int reduce;
	int64_t zlo, zhi;      /* z range that is read: region z within [0, b3) */
	uint32_t *zk1, *zk2;   /* zhi - zlo keys */
	uint64_t *ep;          /* zhi - zlo + 1 prefix sums of the hash of an
	                          empty voxel: ep[i] = sum over z < zlo + i */
	int avx2;
	unsigned n_types;
	struct wstate *w;
};

/* Free what the scan allocated (after success or a failed run alike). */
static void scan_ctx_free(struct scan_ctx *c, unsigned threads)
{
	for (unsigned w = 0; c->w && w < threads; w++) {
		free(c->w[w].d);
		free(c->w[w].k);
		free(c->w[w].ty);
		free(c->w[w].o);
		free(c->w[w].hist);
	}
	free(c->w);
	free(c->zk1);
	free(c->zk2);
	free(c->ep);
	c->w = NULL;
	c->zk1 = c->zk2 = NULL;
	c->ep = NULL;
}

static int scan_tile(void *vctx, unsigned wi, uint64_t k, uint64_t index, char *msg,
                     size_t msz)
{
	struct scan_ctx *c = vctx;
	struct wstate *w = &c->w[wi];
	int64_t lo[3], hi[3];
	size_t nx, ny, nz, ncol;
	loom_texture_region r;
	int rc;

	(void)k;
	tiles_box(c->j, index, lo, hi, NULL);
	if (lo[2] < c->zlo)
		lo[2] = c->zlo;
	if (hi[2] > c->zhi)
		hi[2] = c->zhi;
	nx = (size_t)(hi[0] - lo[0]);
	ny = (size_t)(hi[1] - lo[1]);
	ncol = nx * ny;
	if (hi[2] <= lo[2]) { /* nothing but empty voxels */
		if (c->reduce == R_COVERAGE)
			w->cov[0] += ncol;
		return 0;
	}
	nz = (size_t)(hi[2] - lo[2]);
	memset(&r, 0, sizeof r);
	r.layout = LOOM_REGION_Z_FASTEST;
	r.density = w->d;
	r.kind = w->k;
	if (c->reduce != R_COVERAGE)
		r.type = w->ty;
	if (c->reduce == R_CHECKSUM)
		r.orientation = w->o;
	rc = loom_texture_read_region(c->j->t, lo, hi, &r);
	if (rc != LOOM_OK) {
		snprintf(msg, msz, "tile %llu: %s", (unsigned long long)index,
		         loom_texture_errmsg(c->j->t));
		return -1;
	}
	if (c->reduce == R_CHECKSUM) {
		const uint32_t *k1 = c->zk1 + (lo[2] - c->zlo), *k2 = c->zk2 + (lo[2] - c->zlo);
		uint64_t total = 0;
		const uint64_t *ep = c->ep + (lo[2] - c->zlo);
		for (size_t col = 0; col < ncol; col++) {
			size_t off = col * nz, a = 0, b = nz;
			const uint8_t *d = w->d + off, *kk = w->k + off, *t = w->ty + off;
			const uint16_t *o = w->o + off;
			uint64_t s, x = (uint64_t)(lo[0] + (int64_t)(col % nx));
			uint64_t y = (uint64_t)(lo[1] + (int64_t)(col / nx));
			/* the empty runs at both ends: their sums from ep */
			while (a + 8 <= b && vox_empty8(d, o, kk, t, a))
				a += 8;
			while (a < b && vox_empty(d, o, kk, t, a))
				a++;
			while (b >= a + 8 && vox_empty8(d, o, kk, t, b - 8))
				b -= 8;
			while (b > a && vox_empty(d, o, kk, t, b - 1))
				b--;
			s = (ep[a] - ep[0]) + (ep[nz] - ep[b]);
#ifdef HAVE_AVX2_PATH
			if (c->avx2)
				s += col_sum_avx2(d + a, o + a, kk + a, t + a, k1 + a, k2 + a, b - a);
			else
#endif
				s += col_sum_c(d + a, o + a, kk + a, t + a, k1 + a, k2 + a, b - a);
			total += s * (tiles_mix(tiles_mix(x) ^ y) | 1);
		}
		w->sum += total;
	} else if (c->reduce == R_HISTOGRAM) {
		size_t n = ncol * nz;
		uint64_t *h = w->hist;
		for (size_t i = 0; i < n; i++)
			if (w->k[i])
				h[(size_t)w->ty[i] * 256 + w->d[i]]++;
	} else {
		for (size_t col = 0; col < ncol; col++) {
			const uint8_t *d = w->d + col * nz;
			size_t z = nz;
			while (z > 0 && d[z - 1] == 0)
				z--;
			if (z == 0)
				w->cov[0]++;
			else
				w->cov[w->k[col * nz + z - 1] == LOOM_YARN_WEFT ? 2 :
				       w->k[col * nz + z - 1] == LOOM_YARN_WARP ? 1 : 0]++;
		}
	}
	return 0;
}

/* The result as text or JSON on fp.  j and st: a scan's job and texture
   statistics; NULL for --combine (r's parts, seconds, cpu). */
static void print_result(FILE *fp, const scan_result *r, int json, double secs, double cpu,
                         uint64_t rss,
                         const tiles_job *j, const loom_texture_stats *st,
                         uint32_t n_parts)
{
	char cs[32];
	double rate = secs > 0 ? (double)r->voxels / secs : 0;
	uint64_t cols = r->cov[0] + r->cov[1] + r->cov[2];

	snprintf(cs, sizeof cs, "%016llx", (unsigned long long)r->checksum);
	if (json) {
		json_w w;
		jw_begin(&w, fp);
		jw_str(&w, "reduce", reduce_names[r->reduce]);
		jw_uint(&w, "voxels", r->voxels);
		jw_num(&w, "seconds", secs);
		jw_num(&w, "voxels_per_second", rate);
		jw_uint(&w, "peak_rss_bytes", rss);
		jw_num(&w, "cpu_seconds", cpu);
		jw_num(&w, "voxels_per_cpu_second", cpu > 0 ? (double)r->voxels / cpu : 0);
		if (r->fabric_crc[0]) {
			jw_uint(&w, "fabric_bytes", r->fabric_bytes);
			jw_str(&w, "fabric_crc32", r->fabric_crc);
		}
		if (j) {
			jw_arr(&w, "region_lo");
			for (int a = 0; a < 3; a++)
				jw_int(&w, NULL, r->lo[a]);
			jw_close(&w);
			jw_arr(&w, "region_hi");
			for (int a = 0; a < 3; a++)
				jw_int(&w, NULL, r->hi[a]);
			jw_close(&w);
			jw_arr(&w, "shard");
			jw_uint(&w, NULL, r->shard_i);
			jw_uint(&w, NULL, r->shard_n);
			jw_close(&w);
			jw_arr(&w, "tile");
			for (int a = 0; a < 3; a++)
				jw_int(&w, NULL, j->tsize[a]);
			jw_close(&w);
			jw_uint(&w, "tiles", r->tiles);
			jw_uint(&w, "threads", j->threads);
			jw_num(&w, "budget_mb", j->budget_mb);
			jw_uint(&w, "texture_budget_bytes", j->texture_budget);
			jw_uint(&w, "tile_buffer_bytes", (uint64_t)j->worker_bytes * j->threads);
			jw_num(&w, "hit_rate", cli_hit_rate(st));
			jw_uint(&w, "bytes_read", st->bytes_read);
			jw_uint(&w, "peak_cache_bytes", st->peak_bytes);
			jw_uint(&w, "errors", st->errors);
		} else {
			/* --combine: seconds and cpu_seconds are the parts' sums (the
			   work, not the wall time of a parallel run) */
			jw_uint(&w, "parts", n_parts);
			jw_uint(&w, "bytes_read", r->bytes_read);
			if (r->shard_n > 1) {
				jw_uint(&w, "shards", r->shard_n);
				jw_bool(&w, "complete", 1);
				jw_arr(&w, "region_lo");
				for (int a = 0; a < 3; a++)
					jw_int(&w, NULL, r->lo[a]);
				jw_close(&w);
				jw_arr(&w, "region_hi");
				for (int a = 0; a < 3; a++)
					jw_int(&w, NULL, r->hi[a]);
				jw_close(&w);
			}
		}
		if (r->reduce == R_CHECKSUM) {
			jw_str(&w, "checksum", cs);
		} else if (r->reduce == R_HISTOGRAM) {
			jw_obj(&w, "histogram");
			jw_uint(&w, "bins", r->bins);
			jw_uint(&w, "nonempty", r->nonempty);
			jw_uint(&w, "empty", r->voxels - r->nonempty);
			jw_arr(&w, "types");
			for (uint32_t t = 0; t < r->n_types; t++) {
				uint64_t n = 0;
				for (uint32_t b = 0; b < r->bins; b++)
					n += r->hist[(size_t)t * r->bins + b];
				jw_obj(&w, NULL);
				jw_uint(&w, "type", t);
				jw_str(&w, "name", r->names[t]);
				jw_uint(&w, "count", n);
				jw_arr(&w, "counts");
				for (uint32_t b = 0; b < r->bins; b++)
					jw_uint(&w, NULL, r->hist[(size_t)t * r->bins + b]);
				jw_close(&w);
				jw_close(&w);
			}
			jw_close(&w);
			jw_close(&w);
		} else {
			jw_obj(&w, "coverage");
			jw_uint(&w, "columns", cols);
			jw_uint(&w, "warp", r->cov[1]);
			jw_uint(&w, "weft", r->cov[2]);
			jw_uint(&w, "none", r->cov[0]);
			jw_num(&w, "warp_fraction", cols ? (double)r->cov[1] / (double)cols : 0);
			jw_num(&w, "weft_fraction", cols ? (double)r->cov[2] / (double)cols : 0);
			jw_num(&w, "warp_share", r->cov[1] + r->cov[2]
			                                 ? (double)r->cov[1] / (double)(r->cov[1] + r->cov[2])
			                                 : 0);
			jw_close(&w);
		}
		jw_end(&w);
		return;
	}
	if (j)
		fprintf(fp, "%llu voxels in %llu tiles on %u thread%s in %.3f s (%.3f s CPU): %.4g "
		       "voxels/s, peak RSS %.1f MiB (budget %.1f MiB)\n",
		       (unsigned long long)r->voxels, (unsigned long long)r->tiles, j->threads,
		       j->threads == 1 ? "" : "s", secs, cpu, rate, (double)rss / 1048576.0,
		       j->budget_mb);
	else
		fprintf(fp, "%u parts%s, %llu voxels in %.3f s of work (%.3f s CPU)\n", n_parts,
		        r->shard_n > 1 ? " (every shard)" : "", (unsigned long long)r->voxels, secs,
		        cpu);
	if (r->reduce == R_CHECKSUM) {
		fprintf(fp, "checksum %s\n", cs);
	} else if (r->reduce == R_HISTOGRAM) {
		fprintf(fp, "density histogram (%u bins over 0..1) of %llu voxels with a yarn "
		       "(%llu empty):\n", r->bins, (unsigned long long)r->nonempty,
		       (unsigned long long)(r->voxels - r->nonempty));
		for (uint32_t t = 0; t < r->n_types; t++) {
			fprintf(fp, "  type %u %-12s", t, r->names[t]);
			for (uint32_t b = 0; b < r->bins; b++)
				fprintf(fp, " %llu", (unsigned long long)r->hist[(size_t)t * r->bins + b]);
			fprintf(fp, "\n");
		}
	} else {
		fprintf(fp, "coverage from above, %llu columns: warp %.6f, weft %.6f, none %.6f "
		       "(warp share of covered %.6f)\n", (unsigned long long)cols,
		       cols ? (double)r->cov[1] / (double)cols : 0,
		       cols ? (double)r->cov[2] / (double)cols : 0,
		       cols ? (double)r->cov[0] / (double)cols : 0,
		       r->cov[1] + r->cov[2] ? (double)r->cov[1] / (double)(r->cov[1] + r->cov[2]) : 0);
	}
}

/* ---- --combine ------------------------------------------------------------ */

/* Pointer to the value of the first "key": in text, or NULL. */
static const char *find_key(const char *text, const char *key)
{
	char pat[64];
	const char *p;

	snprintf(pat, sizeof pat, "\"%s\":", key);
	p = strstr(text, pat);
	if (!p)
		return NULL;
	p += strlen(pat);
	while (*p == ' ' || *p == '\n' || *p == '\t' || *p == '\r')
		p++;
	return p;
}

static int get_u64(const char *text, const char *key, uint64_t *v)
{
	const char *p = find_key(text, key);
	char *end;

	if (!p)
		return -1;
	errno = 0;
	*v = strtoull(p, &end, 10);
	return end == p || errno ? -1 : 0;
}

static int get_str(const char *text, const char *key, char *out, size_t n)
{
	const char *p = find_key(text, key);
	size_t i = 0;

	if (!p || *p != '"')
		return -1;
	for (p++; *p && *p != '"' && i + 1 < n; p++)
		out[i++] = *p;
	out[i] = 0;
	return *p == '"' ? 0 : -1;
}

/* Up to n unsigned (or signed, if sign) integers of the array at key. */
static int get_arr(const char *p, uint64_t *v, size_t n, size_t *got)
{
	char *end;

	*got = 0;
	if (!p || *p != '[')
		return -1;
	p++;
	for (;;) {
		while (*p == ' ' || *p == '\n' || *p == '\t' || *p == ',' || *p == '\r')
			p++;
		if (*p == ']')
			return 0;
		if (*got >= n)
			return -1;
		errno = 0;
		if (*p == '-')
			v[*got] = (uint64_t)strtoll(p, &end, 10);
		else
			v[*got] = strtoull(p, &end, 10);
		if (end == p || errno)
			return -1;
		(*got)++;
		p = end;
	}
}

static int get_num(const char *text, const char *key, double *v)
{
	const char *p = find_key(text, key);
	char *end;

	if (!p)
		return -1;
	*v = strtod(p, &end);
	return end == p ? -1 : 0;
}

/* Print the result to stdout, or to out (atomically: a temporary file
   renamed when complete).  0, or exit 1. */
static int emit(const char *prog, const char *out, const scan_result *r, int json,
                int quiet, double secs, double cpu, const tiles_job *j,
                const loom_texture_stats *st, uint32_t n_parts)
{
	loom__atomic a;
	loom_diag diag;

	if (!out) {
		if (json || !quiet)
			print_result(stdout, r, json, secs, cpu, tiles_peak_rss(), j, st, n_parts);
		return 0;
	}
	cli_diag_init(&diag, NULL);
	if (loom__atomic_open(&a, out, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	print_result(a.fp, r, json, secs, cpu, tiles_peak_rss(), j, st, n_parts);
	if (loom__atomic_commit(&a, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	return 0;
}

static int combine(const char *prog, int nfiles, const char **files, int json, int quiet,
                   const char *out)
{
	scan_result r;
	uint8_t *seen = NULL;
	uint64_t tile_lo[3] = {0}, tile_hi[3] = {0}, tile_sz[3] = {0};
	int sharded = -1, have_tile = 0;
	double secs = 0, cpu = 0;

	memset(&r, 0, sizeof r);
	r.reduce = -1;
	r.shard_n = 1;
	for (int f = 0; f < nfiles; f++) {
		char *text;
		char red[32], cs[32], fc[16];
		uint64_t v, sh[2], lo[3], hi[3], tl[3];
		size_t got, got_t = 0;
		double x;
		int ri = -1, is_shard;

		text = tiles_read_text(files[f], 64u << 20, NULL);
		if (!text)
			cli_fail(prog, "%s: %s", files[f], strerror(errno));
		if (get_str(text, "reduce", red, sizeof red))
			cli_fail(prog, "%s: not a `loom scan --json` result (no \"reduce\")", files[f]);
		for (int k = 0; k < 3; k++)
			if (strcmp(red, reduce_names[k]) == 0)
				ri = k;
		if (ri < 0)
			cli_fail(prog, "%s: unknown reducer '%s'", files[f], red);
		if (r.reduce >= 0 && ri != r.reduce)
			cli_fail(prog, "%s: reducer %s, the first part's is %s", files[f], red,
			         reduce_names[r.reduce]);
		r.reduce = ri;
		if (get_u64(text, "voxels", &v))
			cli_fail(prog, "%s: no \"voxels\"", files[f]);
		r.voxels += v;
		if (get_num(text, "seconds", &x) == 0)
			secs += x;
		if (get_num(text, "cpu_seconds", &x) == 0)
			cpu += x;
		if (get_u64(text, "bytes_read", &v) == 0)
			r.bytes_read += v;
		if (get_str(text, "fabric_crc32", fc, sizeof fc) == 0) {
			uint64_t fb = 0;
			get_u64(text, "fabric_bytes", &fb);
			if (!r.fabric_crc[0]) {
				snprintf(r.fabric_crc, sizeof r.fabric_crc, "%.8s", fc);
				r.fabric_bytes = fb;
			} else if (strcmp(fc, r.fabric_crc) != 0 || fb != r.fabric_bytes)
				cli_fail(prog, "%s: a scan of another fabric (CRC-32 %s, the first "
				         "part's %s)", files[f], fc, r.fabric_crc);
		}
		is_shard = get_arr(find_key(text, "shard"), sh, 2, &got) == 0 && got == 2 &&
		           get_arr(find_key(text, "region_lo"), lo, 3, &got) == 0 && got == 3 &&
		           get_arr(find_key(text, "region_hi"), hi, 3, &got) == 0 && got == 3 &&
		           sh[1] > 1;
		if (get_arr(find_key(text, "tile"), tl, 3, &got_t) != 0 || got_t != 3)
			got_t = 0;
		if (sharded >= 0 && is_shard != sharded)
			cli_fail(prog, "%s: %s, the first part %s: give the shards of one split, or "
			         "results of disjoint regions", files[f], is_shard ? "a shard" :
			         "not a shard", sharded ? "is a shard" : "is not");
		sharded = is_shard;
		if (is_shard) {
			if (!seen) {
				if (sh[1] > UINT32_MAX)
					cli_fail(prog, "%s: a split into %llu shards", files[f],
					         (unsigned long long)sh[1]);
				r.shard_n = (uint32_t)sh[1];
				memcpy(tile_lo, lo, sizeof lo);
				memcpy(tile_hi, hi, sizeof hi);
				seen = calloc(r.shard_n, 1);
				if (!seen)
					cli_fail(prog, "out of memory");
			}
			if (sh[1] != r.shard_n || sh[0] >= sh[1] || memcmp(lo, tile_lo, sizeof lo) ||
			    memcmp(hi, tile_hi, sizeof hi))
				cli_fail(prog, "%s: shard %llu/%llu of another region or split than "
				         "the first shard's", files[f], (unsigned long long)sh[0],
				         (unsigned long long)sh[1]);
			/* shards hold the tiles of one tiling: another --tile splits
			   otherwise */
			if (got_t == 3 && have_tile && memcmp(tl, tile_sz, sizeof tl))
				cli_fail(prog, "%s: shard %llu/%llu of tiles %llux%llux%llu, the first "
				         "shard's are %llux%llux%llu (shards must use the same --tile)",
				         files[f], (unsigned long long)sh[0], (unsigned long long)sh[1],
				         (unsigned long long)tl[0], (unsigned long long)tl[1],
				         (unsigned long long)tl[2], (unsigned long long)tile_sz[0],
				         (unsigned long long)tile_sz[1], (unsigned long long)tile_sz[2]);
			if (got_t == 3 && !have_tile) {
				memcpy(tile_sz, tl, sizeof tl);
				have_tile = 1;
			}
			if (seen[sh[0]]++)
				cli_fail(prog, "%s: shard %llu/%llu given twice", files[f],
				         (unsigned long long)sh[0], (unsigned long long)sh[1]);
		}
		if (ri == R_CHECKSUM) {
			char *end;
			if (get_str(text, "checksum", cs, sizeof cs))
				cli_fail(prog, "%s: no \"checksum\"", files[f]);
			errno = 0;
			v = strtoull(cs, &end, 16);
			if (*end || errno || strlen(cs) != 16)
				cli_fail(prog, "%s: bad checksum '%s'", files[f], cs);
			r.checksum += v;
		} else if (ri == R_COVERAGE) {
			uint64_t c[3];
			if (get_u64(text, "none", &c[0]) || get_u64(text, "warp", &c[1]) ||
			    get_u64(text, "weft", &c[2]))
				cli_fail(prog, "%s: no coverage counts", files[f]);
			for (int k = 0; k < 3; k++)
				r.cov[k] += c[k];
		} else {
			uint64_t bins, ne;
			const char *p;
			uint32_t t = 0;
			if (get_u64(text, "bins", &bins) || bins < 1 || bins > 256 ||
			    get_u64(text, "nonempty", &ne))
				cli_fail(prog, "%s: no histogram", files[f]);
			if (f == 0)
				r.bins = (uint32_t)bins;
			else if (bins != r.bins)
				cli_fail(prog, "%s: %llu bins, the first part has %u", files[f],
				         (unsigned long long)bins, r.bins);
			r.nonempty += ne;
			p = find_key(text, "types");
			while (p && (p = strstr(p, "\"type\":")) != NULL) {
				uint64_t cnt[256];
				char name[LOOM_YARN_NAME_MAX];
				if (t >= r.n_types) {
					uint64_t *h = realloc(r.hist, (size_t)(t + 1) * r.bins * sizeof *h);
					char (*nm)[LOOM_YARN_NAME_MAX] = realloc(r.names, (t + 1) * sizeof *nm);
					if (!h || !nm)
						cli_fail(prog, "out of memory");
					r.hist = h;
					r.names = nm;
					memset(h + (size_t)t * r.bins, 0, r.bins * sizeof *h);
					r.names[t][0] = 0;
					r.n_types = t + 1;
				}
				if (get_str(p, "name", name, sizeof name) == 0 && !r.names[t][0])
					snprintf(r.names[t], sizeof r.names[t], "%s", name);
				if (get_arr(find_key(p, "counts"), cnt, 256, &got) || got != r.bins)
					cli_fail(prog, "%s: bad histogram counts of type %u", files[f], t);
				for (uint32_t b = 0; b < r.bins; b++)
					r.hist[(size_t)t * r.bins + b] += cnt[b];
				p = find_key(p, "counts");
				t++;
			}
		}
		free(text);
	}
	if (sharded == 1) {
		uint32_t missing = 0;
		for (uint32_t i = 0; i < r.shard_n; i++) {
			missing += !seen[i];
			seen[i] = !seen[i];
		}
		if (missing) {
			char *list = tiles_list_text(seen, r.shard_n);
			cli_fail(prog, "%u of %u shards missing: %s (run them again, e.g. sbatch "
			         "--array=%s with LOOM_SHARD_COUNT=%u, or --shard I/%u; then combine "
			         "all %u parts)", missing, r.shard_n, list ? list : "?",
			         list ? list : "?", r.shard_n, r.shard_n, r.shard_n);
		}
		for (int a = 0; a < 3; a++) {
			r.lo[a] = (int64_t)tile_lo[a];
			r.hi[a] = (int64_t)tile_hi[a];
		}
	}
	emit(prog, out, &r, json, quiet, secs, cpu, NULL, NULL, (uint32_t)nfiles);
	free(seen);
	free(r.hist);
	free(r.names);
	return 0;
}

int cmd_scan(int argc, char **argv)
{
	const char *prog = "loom scan";
	const char *path, *out = NULL;
	int json = 0, quiet = 0, combine_mode = 0, nfiles;
	const char **files = calloc((size_t)argc + 1, sizeof *files);
	uint32_t bins = 16;
	tiles_job j;
	struct scan_ctx c;
	scan_result r;
	tiles_pool pool;
	cli_progress prog_bar;
	loom_texture_stats st;
	const loom_design *d;
	size_t ncol, nz, per;
	double t0, secs, cpu0, cpu;
	opt_entry opts[] = {
		TILES_OPT_REGION(&j),
		TILES_OPT_ALL(&j),
		TILES_OPT_BOLT(&j),
		OPT_ENUM(0, "reduce", &c.reduce, "R", reduce_choices, "checksum: a 64-bit hash "
		         "of every voxel (density, orientation, kind, type), the same for any "
		         "threads, budget, tile size and shard split; shards' values add\n"
		         "histogram: density per yarn type (voxels with a yarn)\ncoverage: per "
		         "voxel column, the kind of the top-most voxel with density > 0: warp, "
		         "weft or none"),
		OPT_U32(0, "bins", &bins, "B", 1, 256,
		        "histogram bins over density 0..1 (default 16, %r)"),
		TILES_OPT_TILE(&j, "tile size in voxels (default 32,32 and the whole region's "
		               "thickness; coverage needs whole columns)"),
		TILES_OPT_SHARD(&j, "only shard I of N (0-based; docs/batch.md: each shard "
		                "reads about 1/N of the database)" TILES_SHARD_AUTO_HELP),
		TILES_OPT_BUDGET(&j, "all memory for tiles and bricks, MiB (default 64)"),
		TILES_OPT_THREADS(&j),
		TILES_OPT_DB(&j),
		OPT_FLAG(0, "combine", &combine_mode, "add up the --json results of shards (or "
		         "of disjoint regions) of one reducer, given as PART.json...; every shard "
		         "of the split must be there once (else exit 1 naming the missing)"),
		OPT_OUTPUT(&out, "RESULT", "write the result (text, or JSON with --json) to "
		           "RESULT, atomically, instead of stdout"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_QUIET(&quiet, "nothing on success (no progress, and no result on stdout "
		          "unless --json)"),
		OPT_END()
	};
	opts_cmd cmd = {.prog = prog, .usage = usage, .about = about,
	                .exit1 = "bad input or failed read", .opts = opts,
	                .pos_name = "FABRIC", .pos_max = argc, .pos = files};

	if (!files)
		cli_fail(prog, "out of memory");
	tiles_init(&j);
	c.reduce = -1;
	opts_parse(&cmd, argc, argv);
	nfiles = cmd.n_pos;
	if (combine_mode) {
		int rc;
		if (nfiles == 0)
			opts_usage(&cmd, "--combine needs the JSON results to add up");
		if (j.region_s || j.all || c.reduce >= 0 || j.tile_s || j.shard_s)
			opts_usage(&cmd, "--combine takes only JSON files (and --json)");
		rc = combine(prog, nfiles, files, json, quiet, out);
		free(files);
		return rc;
	}
	if (nfiles == 0)
		opts_usage(&cmd, "missing FABRIC");
	if (nfiles > 1)
		opts_usage(&cmd, "more than one FABRIC ('%s' and '%s')", files[0], files[1]);
	path = files[0];
	tiles_parse(&cmd, &j, 1);
	if (c.reduce < 0)
		opts_usage(&cmd, "missing --reduce checksum|histogram|coverage");
	if (opt_given(&cmd, &bins) && c.reduce != R_HISTOGRAM)
		opts_usage(&cmd, "--bins goes with --reduce histogram");
	if (out)
		cli_check_output(prog, out);

	tiles_open_fabric(&j, prog, path, 32);
	if (c.reduce == R_COVERAGE && j.tsize[2] < j.hi[2] - j.lo[2]) {
		tiles_close(&j);
		opts_usage(&cmd, "--reduce coverage needs whole columns: no TZ in --tile");
	}
	d = loom_fabric_design(j.f);
	c.j = &j;
	c.n_types = d->n_types;
	c.zlo = j.lo[2] > 0 ? j.lo[2] : 0;
	c.zhi = j.hi[2] < (int64_t)j.rep[2] ? j.hi[2] : (int64_t)j.rep[2];
	if (c.zhi < c.zlo)
		c.zhi = c.zlo;
	/* per worker: the tile's readable columns, 5 bytes per voxel */
	ncol = (size_t)j.tsize[0] * (size_t)j.tsize[1];
	nz = (size_t)(c.zhi - c.zlo);
	if ((int64_t)nz > j.tsize[2])
		nz = (size_t)j.tsize[2];
	if (nz == 0)
		nz = 1;
	per = ncol * nz * 5 + (c.reduce == R_HISTOGRAM ? (size_t)256 * 8 * 256 : 0) +
	      sizeof(struct wstate);
	tiles_open_texture(&j, prog, per);

	c.zk1 = calloc((size_t)(c.zhi - c.zlo) + 1, sizeof *c.zk1);
	c.zk2 = calloc((size_t)(c.zhi - c.zlo) + 1, sizeof *c.zk2);
	c.ep = calloc((size_t)(c.zhi - c.zlo) + 1, sizeof *c.ep);
	c.w = calloc(j.threads, sizeof *c.w);
	if (!c.zk1 || !c.zk2 || !c.ep || !c.w)
		cli_fail(prog, "out of memory");
	for (int64_t z = c.zlo; z < c.zhi; z++) {
		uint64_t key = tiles_mix((uint64_t)z ^ SEED_Z);
		size_t i = (size_t)(z - c.zlo);
		c.zk1[i] = (uint32_t)key;
		c.zk2[i] = (uint32_t)(key >> 32);
		c.ep[i + 1] = c.ep[i] + vhash(0, 0, c.zk1[i], c.zk2[i]);
	}
	c.avx2 = 0;
#ifdef HAVE_AVX2_PATH
	c.avx2 = __builtin_cpu_supports("avx2") && !getenv("LOOM_SCAN_NO_AVX2");
#endif
	for (unsigned w = 0; w < j.threads; w++) {
		struct wstate *ws = &c.w[w];
		ws->d = malloc(ncol * nz);
		ws->k = malloc(ncol * nz);
		ws->ty = malloc(ncol * nz);
		ws->o = malloc(ncol * nz * 2);
		ws->hist = calloc(256 * 256, sizeof *ws->hist);
		if (!ws->d || !ws->k || !ws->ty || !ws->o || !ws->hist)
			cli_fail(prog, "out of memory");
	}

	memset(&pool, 0, sizeof pool);
	pool.job = &j;
	pool.fn = scan_tile;
	pool.ctx = &c;
	pool.progress = &prog_bar;
	pool.progress_voxels = 1;
	pool.index_order = tiles_index_order_wanted();
	/* the total walks the shard's order once more: only when it is shown */
	cli_progress_begin(&prog_bar, prog, "voxels", quiet ? 0 : tiles_shard_voxels(&j),
	                   quiet);
	t0 = cli_now();
	cpu0 = tiles_cpu_seconds();
	if (tiles_run(&pool) != 0) {
		cli_error(prog, "%s", pool.msg);
		scan_ctx_free(&c, j.threads);
		free(files);
		tiles_close(&j);
		return EXIT_BAD_INPUT;
	}
	secs = cli_now() - t0;
	cpu = tiles_cpu_seconds() - cpu0;
	loom_texture_get_stats(j.t, &st);

	memset(&r, 0, sizeof r);
	r.reduce = c.reduce;
	r.voxels = atomic_load(&pool.done_voxels);
	r.tiles = atomic_load(&pool.done_tiles);
	memcpy(r.lo, j.lo, sizeof r.lo);
	memcpy(r.hi, j.hi, sizeof r.hi);
	r.shard_i = j.shard_i;
	r.shard_n = j.shard_n;
	r.bins = bins;
	r.n_types = c.n_types;
	r.hist = calloc((size_t)c.n_types * bins, sizeof *r.hist);
	r.names = calloc(c.n_types, sizeof *r.names);
	if (!r.hist || !r.names)
		cli_fail(prog, "out of memory");
	for (uint32_t t = 0; t < c.n_types; t++)
		snprintf(r.names[t], sizeof r.names[t], "%s", d->types[t].name);
	for (unsigned w = 0; w < j.threads; w++) {
		r.checksum += c.w[w].sum;
		for (int k = 0; k < 3; k++)
			r.cov[k] += c.w[w].cov[k];
		for (uint32_t t = 0; t < c.n_types; t++)
			for (uint32_t v = 0; v < 256; v++) {
				uint64_t n = c.w[w].hist[(size_t)t * 256 + v];
				r.hist[(size_t)t * bins + v * bins / 256] += n;
				r.nonempty += n;
			}
	}
	memcpy(r.tile, j.tsize, sizeof r.tile);
	{ /* the fabric's identity, for --combine (streamed, not loaded) */
		uint8_t *fbuf = malloc(CRC_BUF);
		uint32_t fcrc;
		uint64_t flen;
		if (fbuf && export_file_crc(path, fbuf, &fcrc, &flen) == 0) {
			r.fabric_bytes = flen;
			snprintf(r.fabric_crc, sizeof r.fabric_crc, "%08x", fcrc);
		}
		free(fbuf);
	}
	emit(prog, out, &r, json, quiet, secs, cpu, &j, &st, 1);
	scan_ctx_free(&c, j.threads);
	free(r.hist);
	free(r.names);
	free(files);
	tiles_close(&j);
	return 0;
}
