/*
 * tools/loom/cmd_export.c - `loom export FABRIC`: write a region of the
 * virtual texture (or a whole bolt) as tiles of Mitsuba .vol, NRRD or
 * OpenEXR z-slice files, with a manifest that makes a killed job resumable
 * and shards mergeable (`loom export --merge DIR`).  docs/batch.md
 * describes the options, the files, the manifest and resuming.
 */
#include "cli.h"
#include "commands.h"
#include "tiles.h"

#include "io/volume/nrrd.h" /* io/: the NRRD writer (internal to libloom) */

#include <dirent.h>
#include <errno.h>
#include <libdeflate.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char help[] =
	"usage: loom export FABRIC (--region X0,Y0,Z0:X1,Y1,Z1 | --all [--bolt LxW])\n"
	"                   --format vol|nrrd|exr -o DIR [--channels LIST]\n"
	"                   [--tile TX,TY[,TZ]] [--shard I/N] [--budget MB]\n"
	"                   [--threads N] [--db DB] [--quiet] [--json]\n"
	"       loom export --merge DIR [--json]\n"
	"\n"
	"Write a region of the fabric's virtual texture as tiles of files other\n"
	"tools read, with a manifest (DIR/manifest.json) listing every tile's box,\n"
	"files, sizes and CRC-32s (docs/batch.md).  Re-running the same command\n"
	"skips the tiles already complete and verified, so a killed job resumes.\n"
	"\n"
	"  --region BOX     voxels X0<=x<X1, Y0<=y<Y1, Z0<=z<Z1 (integers; x and y\n"
	"                   of any sign: the bolt is unbounded)\n"
	"  --all            one design repeat, the cloth's whole thickness\n"
	"  --bolt LxW       with --all: a bolt LENGTH (along y) by WIDTH (x), in\n"
	"                   repeats or with mm, cm or m\n"
	"  --format F       vol: Mitsuba grid volumes, one file per channel per tile\n"
	"                   nrrd: NRRD (attached header), one per channel per tile\n"
	"                   exr: OpenEXR, one multi-channel image per z per tile\n"
	"  --channels LIST  comma-separated: density, orientation, albedo, kind,\n"
	"                   type (default density,orientation)\n"
	"  --tile TX,TY[,TZ] tile size in voxels (default 64,64 and the region's\n"
	"                   whole thickness)\n"
	"  --shard I/N      only the tiles whose index mod N is I; writes\n"
	"                   DIR/manifest-I-of-N.json\n"
	"  --merge DIR      merge DIR's shard manifests into DIR/manifest.json\n"
	"  --budget MB      all memory for tile buffers and bricks, MiB (default 64)\n"
	"  --threads N      worker threads (default 1)\n"
	"  --db DB          the exemplar database (default: the fabric's)\n"
	"  -o DIR           output directory (made if missing)\n"
	"  --json           print a summary as JSON\n"
	"  --quiet          no progress on stderr\n"
	"\n"
	"Exit status: 0 success, 1 bad input or failed write, 2 usage error.\n";

enum { CH_DENSITY, CH_ORIENT, CH_ALBEDO, CH_KIND, CH_TYPE, N_CH };
static const char *const ch_names[N_CH] = {"density", "orientation", "albedo", "kind",
                                           "type"};
static const unsigned ch_comps[N_CH] = {1, 3, 3, 1, 1};
enum { F_VOL, F_NRRD, F_EXR };
static const char *const fmt_names[] = {"vol", "nrrd", "exr"};

#define CRC_BUF (256u << 10)
#define MANIFEST_VERSION 1

struct ewstate {
	uint8_t *d, *k, *ty;
	uint16_t *o;
	float *row;            /* one row: up to 9 floats per voxel */
	uint8_t *io;           /* CRC read buffer */
	char *line;            /* the tile's manifest line being built */
	size_t line_cap, line_len;
};

struct export_ctx {
	tiles_job *j;
	int format;
	unsigned chmask;
	const char *dir;
	char *params;          /* the manifest's "params" value (one line) */
	char manifest[4096];   /* its path */
	char **lines;          /* per shard tile: manifest line, NULL if not done */
	uint8_t *skip;         /* tiles found complete at start */
	uint64_t n;            /* tiles in the shard */
	uint64_t ndone, nlisted_written;
	double last_write;
	double write_cost;     /* seconds the last manifest write took */
	pthread_mutex_t lock;
	struct ewstate *w;
	float albedo[256][3];
	atomic_ullong bytes, files, written_tiles;
	int manifest_error;
	char manifest_msg[LOOM_DIAG_MSG_MAX];
};

/* ---- small helpers --------------------------------------------------------- */

static int line_add(struct ewstate *w, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

static int line_add(struct ewstate *w, const char *fmt, ...)
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
static int file_crc(const char *path, uint8_t *buf, uint32_t *crc, uint64_t *bytes)
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

static void stem_of(const tiles_job *j, uint64_t index, char *out, size_t n)
{
	int64_t lo[3], hi[3], t[3];

	tiles_box(j, index, lo, hi, t);
	snprintf(out, n, "tile-%lld-%lld-%lld", (long long)t[0], (long long)t[1],
	         (long long)t[2]);
}

/* One row (x0..x1 at y, z of the tile buffers, nx x ny) of channel ch as
   floats, comps per voxel. */
static void fill_row(const struct export_ctx *c, const struct ewstate *w, int ch,
                     size_t off, size_t nx, float *out)
{
	const uint8_t *d = w->d + off, *k = w->k + off, *ty = w->ty + off;
	const uint16_t *o = w->o + off;

	switch (ch) {
	case CH_DENSITY:
		for (size_t i = 0; i < nx; i++)
			out[i] = (float)d[i] / 255.0f;
		break;
	case CH_ORIENT:
		for (size_t i = 0; i < nx; i++) {
			if (d[i])
				loom_orientation_decode(o[i], out + 3 * i);
			else
				out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = 0.0f;
		}
		break;
	case CH_ALBEDO:
		for (size_t i = 0; i < nx; i++) {
			if (k[i])
				memcpy(out + 3 * i, c->albedo[ty[i]], 3 * sizeof(float));
			else
				out[3 * i] = out[3 * i + 1] = out[3 * i + 2] = 0.0f;
		}
		break;
	case CH_KIND:
		for (size_t i = 0; i < nx; i++)
			out[i] = (float)k[i];
		break;
	default:
		for (size_t i = 0; i < nx; i++)
			out[i] = (float)ty[i];
		break;
	}
}

/* Record a written file in the tile's line. */
static int record_file(struct export_ctx *c, struct ewstate *w, const char *name,
                       char *msg, size_t msz)
{
	char path[4096];
	uint32_t crc;
	uint64_t bytes;

	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	if (file_crc(path, w->io, &crc, &bytes)) {
		snprintf(msg, msz, "%s: cannot read back: %s", path, strerror(errno));
		return -1;
	}
	atomic_fetch_add(&c->bytes, bytes);
	atomic_fetch_add(&c->files, 1);
	if (line_add(w, "%s{\"name\": \"%s\", \"bytes\": %llu, \"crc32\": \"%08x\"}",
	             w->line[w->line_len - 1] == '[' ? "" : ", ", name,
	             (unsigned long long)bytes, crc)) {
		snprintf(msg, msz, "out of memory");
		return -1;
	}
	return 0;
}

/* ---- writers ----------------------------------------------------------------- */

static int write_vol(struct export_ctx *c, struct ewstate *w, const char *stem, int ch,
                     const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	loom_vol_header h;
	loom_vol_writer *vw = NULL;
	loom_diag diag;
	char name[512], path[4096];
	double vmm = c->j->voxel_mm;

	snprintf(name, sizeof name, "%s.%s.vol", stem, ch_names[ch]);
	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	memset(&h, 0, sizeof h);
	h.encoding = ch == CH_DENSITY ? LOOM_VOL_UINT8 : LOOM_VOL_FLOAT32;
	h.xres = (uint32_t)nx;
	h.yres = (uint32_t)ny;
	h.zres = (uint32_t)nz;
	h.channels = ch_comps[ch];
	for (int a = 0; a < 3; a++) {
		/* node-centred: first to last voxel centre (one voxel when res 1) */
		h.bbox_min[a] = (float)(((double)lo[a] + 0.5) * vmm);
		h.bbox_max[a] = hi[a] - lo[a] > 1 ? (float)(((double)hi[a] - 0.5) * vmm)
		                                  : (float)(((double)lo[a] + 1.5) * vmm);
	}
	cli_diag_init(&diag, NULL);
	if (loom_vol_writer_open(path, &h, &vw, &diag) != LOOM_OK)
		goto fail;
	for (size_t z = 0; z < nz; z++)
		for (size_t y = 0; y < ny; y++) {
			fill_row(c, w, ch, (z * ny + y) * nx, nx, w->row);
			if (loom_vol_writer_put_voxels(vw, w->row, nx, &diag) != LOOM_OK)
				goto fail;
		}
	if (loom_vol_writer_finish(vw, &diag) != LOOM_OK) {
		vw = NULL;
		goto fail;
	}
	return record_file(c, w, name, msg, msz);
fail:
	loom_vol_writer_abort(vw);
	snprintf(msg, msz, "%s", diag.message);
	return -1;
}

static int write_nrrd(struct export_ctx *c, struct ewstate *w, const char *stem, int ch,
                      const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	loom__nrrd_desc d;
	loom__nrrd_w nw;
	loom_diag diag;
	char name[512], path[4096], content[64];
	int rc = LOOM_OK;

	snprintf(name, sizeof name, "%s.%s.nrrd", stem, ch_names[ch]);
	snprintf(path, sizeof path, "%s/%s", c->dir, name);
	snprintf(content, sizeof content, "loom %s", ch_names[ch]);
	memset(&d, 0, sizeof d);
	d.type = ch == CH_KIND || ch == CH_TYPE ? LOOM__NRRD_UINT8 : LOOM__NRRD_FLOAT;
	d.components = ch_comps[ch];
	d.sizes[0] = nx;
	d.sizes[1] = ny;
	d.sizes[2] = nz;
	for (int a = 0; a < 3; a++) {
		d.spacing[a] = c->j->voxel_mm;
		d.origin[a] = ((double)lo[a] + 0.5) * c->j->voxel_mm;
	}
	d.units = "mm";
	d.content = content;
	cli_diag_init(&diag, NULL);
	if (loom__nrrd_begin(&nw, path, 0, &d, &diag) != LOOM_OK) {
		snprintf(msg, msz, "%s", diag.message);
		return -1;
	}
	if (ch == CH_KIND || ch == CH_TYPE) {
		rc = loom__nrrd_write(&nw, ch == CH_KIND ? w->k : w->ty, nx * ny * nz, &diag);
	} else {
		for (size_t r = 0; r < ny * nz && rc == LOOM_OK; r++) {
			fill_row(c, w, ch, r * nx, nx, w->row);
			rc = loom__nrrd_write(&nw, w->row, nx * ch_comps[ch], &diag);
		}
	}
	if (rc == LOOM_OK)
		rc = loom__nrrd_finish(&nw, &diag);
	else
		loom__nrrd_abort(&nw);
	if (rc != LOOM_OK) {
		snprintf(msg, msz, "%s", diag.message);
		return -1;
	}
	return record_file(c, w, name, msg, msz);
}

static int write_exr(struct export_ctx *c, struct ewstate *w, const char *stem,
                     const int64_t lo[3], const int64_t hi[3], char *msg, size_t msz)
{
	static const char *const names[N_CH][3] = {
		{"density"}, {"orientation.x", "orientation.y", "orientation.z"},
		{"R", "G", "B"}, {"kind"}, {"type"}};
	size_t nx = (size_t)(hi[0] - lo[0]), ny = (size_t)(hi[1] - lo[1]);
	size_t nz = (size_t)(hi[2] - lo[2]);
	loom_exr_channel chans[9];
	uint32_t nch = 0;
	float tmp[3 * 4096];
	loom_diag diag;

	for (int ch = 0; ch < N_CH; ch++)
		if (c->chmask & 1u << ch)
			for (unsigned q = 0; q < ch_comps[ch]; q++) {
				chans[nch].name = names[ch][q];
				chans[nch].pixel = LOOM_EXR_FLOAT;
				nch++;
			}
	cli_diag_init(&diag, NULL);
	for (size_t z = 0; z < nz; z++) {
		loom_exr_options o = LOOM_EXR_OPTIONS_INIT;
		loom_exr_writer *ew = NULL;
		char name[512], path[4096];
		int64_t az = lo[2] + (int64_t)z;

		snprintf(name, sizeof name, "%s.z%lld.exr", stem, (long long)az);
		snprintf(path, sizeof path, "%s/%s", c->dir, name);
		o.has_slice = 1;
		o.slice_z = (int32_t)az;
		for (int a = 0; a < 3; a++)
			o.voxel_mm[a] = c->j->voxel_mm;
		o.origin_mm[0] = ((double)lo[0] + 0.5) * c->j->voxel_mm;
		o.origin_mm[1] = ((double)lo[1] + 0.5) * c->j->voxel_mm;
		o.origin_mm[2] = ((double)az + 0.5) * c->j->voxel_mm;
		if (loom_exr_writer_open(path, (uint32_t)nx, (uint32_t)ny, chans, nch, &o, &ew,
		                         &diag) != LOOM_OK)
			goto fail;
		for (size_t y = 0; y < ny; y++) {
			size_t off = (z * ny + y) * nx;
			/* interleave the channels of the row, 4096 voxels at a time */
			for (size_t x0 = 0; x0 < nx; x0 += 4096) {
				size_t m = nx - x0 < 4096 ? nx - x0 : 4096;
				uint32_t base = 0;
				for (int ch = 0; ch < N_CH; ch++) {
					if (!(c->chmask & 1u << ch))
						continue;
					fill_row(c, w, ch, off + x0, m, tmp);
					for (size_t i = 0; i < m; i++)
						for (unsigned q = 0; q < ch_comps[ch]; q++)
							w->row[(x0 + i) * nch + base + q] = tmp[i * ch_comps[ch] + q];
					base += ch_comps[ch];
				}
			}
			if (loom_exr_writer_put_rows(ew, w->row, 1, &diag) != LOOM_OK)
				goto fail;
		}
		if (loom_exr_writer_finish(ew, &diag) != LOOM_OK)
			goto fail_done;
		if (record_file(c, w, name, msg, msz))
			return -1;
		continue;
	fail:
		loom_exr_writer_abort(ew);
	fail_done:
		snprintf(msg, msz, "%s", diag.message);
		return -1;
	}
	return 0;
}

/* ---- tiles -------------------------------------------------------------------- */

static int export_tile(void *vctx, unsigned wi, uint64_t k, char *msg, size_t msz)
{
	struct export_ctx *c = vctx;
	struct ewstate *w = &c->w[wi];
	uint64_t index = tiles_index(c->j, k);
	int64_t lo[3], hi[3], t[3];
	loom_texture_region r;
	char stem[128], *line;
	const char *delay = getenv("LOOM_EXPORT_TILE_DELAY_MS");

	tiles_box(c->j, index, lo, hi, t);
	stem_of(c->j, index, stem, sizeof stem);
	memset(&r, 0, sizeof r);
	r.layout = LOOM_REGION_X_FASTEST;
	r.density = w->d;
	if (c->chmask & 1u << CH_ORIENT)
		r.orientation = w->o;
	if (c->chmask & (1u << CH_ALBEDO | 1u << CH_KIND | 1u << CH_TYPE)) {
		r.kind = w->k;
		r.type = w->ty;
	}
	if (loom_texture_read_region(c->j->t, lo, hi, &r) != LOOM_OK) {
		snprintf(msg, msz, "tile %s: %s", stem, loom_texture_errmsg(c->j->t));
		return -1;
	}
	w->line_len = 0;
	w->line[0] = 0;
	if (line_add(w, "{\"index\": %llu, \"tile\": [%lld, %lld, %lld], \"lo\": [%lld, %lld, "
	             "%lld], \"hi\": [%lld, %lld, %lld], \"files\": [",
	             (unsigned long long)index, (long long)t[0], (long long)t[1],
	             (long long)t[2], (long long)lo[0], (long long)lo[1], (long long)lo[2],
	             (long long)hi[0], (long long)hi[1], (long long)hi[2])) {
		snprintf(msg, msz, "out of memory");
		return -1;
	}
	if (c->format == F_EXR) {
		if (write_exr(c, w, stem, lo, hi, msg, msz))
			return -1;
	} else {
		for (int ch = 0; ch < N_CH; ch++) {
			if (!(c->chmask & 1u << ch))
				continue;
			if ((c->format == F_VOL ? write_vol : write_nrrd)(c, w, stem, ch, lo, hi,
			                                                  msg, msz))
				return -1;
		}
	}
	if (line_add(w, "]}") || !(line = strdup(w->line))) {
		snprintf(msg, msz, "out of memory");
		return -1;
	}
	if (delay && *delay) { /* test hook: make a job slow enough to kill */
		struct timespec ts;
		long ms = atol(delay);
		ts.tv_sec = ms / 1000;
		ts.tv_nsec = (ms % 1000) * 1000000L;
		nanosleep(&ts, NULL);
	}
	pthread_mutex_lock(&c->lock);
	c->lines[k] = line;
	c->ndone++;
	pthread_mutex_unlock(&c->lock);
	atomic_fetch_add(&c->written_tiles, 1);
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

static int manifest_flush(struct export_ctx *c, int final)
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

static void export_tick(void *vctx)
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
		manifest_flush(c, 0);
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
			if (file_crc(path, buf, &fcrc, &fbytes) || fbytes != bytes || fcrc != crc)
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
static uint64_t resume(struct export_ctx *c, const char *prog)
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
static void remove_stale(struct export_ctx *c)
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

static int parse_channels(const char *s, unsigned *mask)
{
	char buf[256], *save = NULL, *tok;

	if (strlen(s) >= sizeof buf)
		return -1;
	strcpy(buf, s);
	*mask = 0;
	for (tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
		int found = -1;
		for (int ch = 0; ch < N_CH; ch++)
			if (strcmp(tok, ch_names[ch]) == 0)
				found = ch;
		if (found < 0)
			return -1;
		*mask |= 1u << found;
	}
	return *mask ? 0 : -1;
}

static void make_dir(const char *prog, const char *dir)
{
	struct stat st;

	if (mkdir(dir, 0777) != 0 && errno != EEXIST)
		cli_fail(prog, "cannot create the output directory %s: %s", dir, strerror(errno));
	if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
		cli_fail(prog, "%s is not a directory", dir);
	if (access(dir, W_OK | X_OK) != 0)
		cli_fail(prog, "cannot write to the output directory %s: %s", dir,
		         strerror(errno));
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

static int merge(const char *prog, const char *dir, int json)
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

/* ---- the command -------------------------------------------------------------- */

int cmd_export(int argc, char **argv)
{
	const char *prog = "loom export";
	const char *path = NULL, *format_s = NULL, *channels_s = NULL, *out = NULL;
	const char *merge_dir = NULL;
	int json = 0, quiet = 0;
	tiles_job j;
	struct export_ctx c;
	tiles_pool pool;
	cli_progress bar;
	const loom_design *d;
	size_t voxels, per, rowf;
	uint64_t kept;
	uint32_t fcrc;
	uint64_t fbytes;
	double t0, secs;
	char params[2048], cl[160] = "";
	uint8_t *fbuf;
	cli_args a;

	tiles_init(&j);
	memset(&c, 0, sizeof c);
	cli_init(&a, argc, argv, prog, help);
	while (cli_more(&a)) {
		const char *s;
		if (tiles_option(&a, &j) || cli_value(&a, "--format", &format_s) ||
		    cli_value(&a, "--channels", &channels_s) || cli_value(&a, "-o", &out) ||
		    cli_value(&a, "--merge", &merge_dir))
			continue;
		if (cli_flag(&a, "--json")) {
			json = 1;
			continue;
		}
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if ((s = cli_positional(&a)) != NULL) {
			if (path)
				cli_usage(&a, "more than one FABRIC");
			path = s;
			continue;
		}
		cli_unknown(&a);
	}
	if (merge_dir) {
		if (path || format_s || channels_s || out || j.region_s || j.all || j.shard_s ||
		    j.tile_s)
			cli_usage(&a, "--merge DIR takes no FABRIC nor export options");
		return merge(prog, merge_dir, json);
	}
	if (!path)
		cli_usage(&a, "missing FABRIC");
	tiles_parse(&a, &j, 1);
	if (!format_s)
		cli_usage(&a, "missing --format vol|nrrd|exr");
	c.format = -1;
	for (int f = 0; f < 3; f++)
		if (strcmp(format_s, fmt_names[f]) == 0)
			c.format = f;
	if (c.format < 0)
		cli_usage(&a, "bad --format '%s' (expected vol, nrrd or exr)", format_s);
	if (parse_channels(channels_s ? channels_s : "density,orientation", &c.chmask))
		cli_usage(&a, "bad --channels '%s' (expected a comma-separated list of density, "
		          "orientation, albedo, kind, type)", channels_s);
	if (!out)
		cli_usage(&a, "missing -o DIR");

	tiles_open_fabric(&j, prog, path, 64);
	if (c.format == F_EXR && (j.tsize[0] > 65536 || j.tsize[1] > 65536)) {
		tiles_close(&j);
		cli_usage(&a, "EXR tiles are at most 65536 x 65536 pixels: give a smaller --tile");
	}
	if (c.format == F_EXR && (j.lo[2] < INT32_MIN || j.hi[2] > INT32_MAX)) {
		tiles_close(&j);
		cli_usage(&a, "EXR slices need z within the 32-bit range");
	}
	make_dir(prog, out);
	c.j = &j;
	c.dir = out;
	c.n = tiles_in_shard(&j);
	d = loom_fabric_design(j.f);
	for (uint32_t t = 0; t < d->n_types && t < 256; t++)
		memcpy(c.albedo[t], d->types[t].albedo, sizeof c.albedo[t]);

	/* the parameters that determine the bytes (not threads nor budget) */
	fbuf = malloc(CRC_BUF);
	if (!fbuf || file_crc(path, fbuf, &fcrc, &fbytes))
		cli_fail(prog, "%s: cannot read", path);
	free(fbuf);
	for (int ch = 0; ch < N_CH; ch++)
		if (c.chmask & 1u << ch)
			snprintf(cl + strlen(cl), sizeof cl - strlen(cl), "%s\"%s\"", cl[0] ? ", " : "",
			         ch_names[ch]);
	snprintf(params, sizeof params,
	         "{\"fabric_bytes\": %llu, \"fabric_crc32\": \"%08x\", \"format\": \"%s\", "
	         "\"channels\": [%s], \"region_lo\": [%lld, %lld, %lld], \"region_hi\": "
	         "[%lld, %lld, %lld], \"tile\": [%lld, %lld, %lld], \"voxel_mm\": %.9g}",
	         (unsigned long long)fbytes, fcrc, fmt_names[c.format], cl, (long long)j.lo[0],
	         (long long)j.lo[1], (long long)j.lo[2], (long long)j.hi[0], (long long)j.hi[1],
	         (long long)j.hi[2], (long long)j.tsize[0], (long long)j.tsize[1],
	         (long long)j.tsize[2], j.voxel_mm);
	c.params = params;
	if (j.shard_n > 1)
		snprintf(c.manifest, sizeof c.manifest, "%s/manifest-%u-of-%u.json", out, j.shard_i,
		         j.shard_n);
	else
		snprintf(c.manifest, sizeof c.manifest, "%s/manifest.json", out);

	/* per worker: the tile's raw channels, a row of up to 9 floats per voxel,
	   the CRC buffer and the writers' own buffers (a .vol writer 64 KiB; an
	   EXR writer one 16-row chunk, its planes and a compressor) */
	voxels = (size_t)j.tsize[0] * (size_t)j.tsize[1] * (size_t)j.tsize[2];
	rowf = (size_t)j.tsize[0] * 9;
	per = voxels * 5 + rowf * sizeof(float) + CRC_BUF + (1u << 20) +
	      (c.format == F_EXR ? (size_t)j.tsize[0] * 16 * 9 * 4 * 3 : 0);
	/* the manifest lines, held until the end: per tile of the shard about
	   256 bytes of index and box and 128 per file (an upper estimate), its
	   pointer, skip flag and allocation header */
	{
		size_t files = 0;
		for (int ch = 0; ch < N_CH; ch++)
			files += (c.chmask >> ch) & 1u;
		if (c.format == F_EXR)
			files = (size_t)j.tsize[2];
		j.job_bytes = (size_t)c.n * (256 + 128 * files + 8 + 1 + 16);
	}
	tiles_open_texture(&j, prog, per);

	c.lines = calloc(c.n ? c.n : 1, sizeof *c.lines);
	c.skip = calloc(c.n ? c.n : 1, 1);
	c.w = calloc(j.threads, sizeof *c.w);
	if (!c.lines || !c.skip || !c.w)
		cli_fail(prog, "out of memory");
	for (unsigned w = 0; w < j.threads; w++) {
		struct ewstate *ws = &c.w[w];
		ws->d = malloc(voxels);
		ws->k = malloc(voxels);
		ws->ty = malloc(voxels);
		ws->o = malloc(voxels * 2);
		ws->row = malloc(rowf * sizeof(float));
		ws->io = malloc(CRC_BUF);
		ws->line_cap = 4096;
		ws->line = malloc(ws->line_cap);
		if (!ws->d || !ws->k || !ws->ty || !ws->o || !ws->row || !ws->io || !ws->line)
			cli_fail(prog, "out of memory");
	}
	pthread_mutex_init(&c.lock, NULL);
	remove_stale(&c);
	kept = resume(&c, prog);
	if (kept && !quiet)
		fprintf(stderr, "%s: %llu of %llu tiles already complete and verified "
		        "(%s): skipping them\n", prog, (unsigned long long)kept,
		        (unsigned long long)c.n, c.manifest);

	memset(&pool, 0, sizeof pool);
	pool.job = &j;
	pool.fn = export_tile;
	pool.ctx = &c;
	pool.skip = c.skip;
	pool.tick = export_tick;
	pool.progress = &bar;
	pool.source_order = tiles_source_order_wanted();
	c.last_write = cli_now();
	cli_progress_begin(&bar, prog, "tiles", c.n, quiet);
	t0 = cli_now();
	if (tiles_run(&pool) != 0) {
		manifest_flush(&c, 0);
		cli_error(prog, "%s", pool.msg);
		tiles_close(&j);
		return EXIT_BAD_INPUT;
	}
	secs = cli_now() - t0;
	if (manifest_flush(&c, 1) != 0) {
		cli_error(prog, "%s", c.manifest_msg);
		tiles_close(&j);
		return EXIT_BAD_INPUT;
	}
	{
		uint64_t wt = atomic_load(&c.written_tiles), bytes = atomic_load(&c.bytes);
		uint64_t vox = 0;
		for (uint64_t k = 0; k < c.n; k++) {
			int64_t lo[3], hi[3];
			if (c.skip[k])
				continue;
			tiles_box(&j, tiles_index(&j, k), lo, hi, NULL);
			vox += (uint64_t)(hi[0] - lo[0]) * (uint64_t)(hi[1] - lo[1]) *
			       (uint64_t)(hi[2] - lo[2]);
		}
		if (json) {
			json_w w;
			jw_begin(&w, stdout);
			jw_str(&w, "manifest", c.manifest);
			jw_str(&w, "format", fmt_names[c.format]);
			jw_uint(&w, "tiles", c.n);
			jw_uint(&w, "tiles_written", wt);
			jw_uint(&w, "tiles_skipped", kept);
			jw_uint(&w, "files_written", atomic_load(&c.files));
			jw_uint(&w, "bytes_written", bytes);
			jw_uint(&w, "voxels", vox);
			jw_num(&w, "seconds", secs);
			jw_num(&w, "voxels_per_second", secs > 0 ? (double)vox / secs : 0);
			jw_num(&w, "bytes_per_second", secs > 0 ? (double)bytes / secs : 0);
			jw_uint(&w, "threads", j.threads);
			jw_num(&w, "budget_mb", j.budget_mb);
			jw_uint(&w, "peak_rss_bytes", tiles_peak_rss());
			jw_end(&w);
		} else {
			printf("%s: %llu tiles (%llu written, %llu already complete), %llu files, "
			       "%.1f MiB in %.3f s; manifest %s\n", out, (unsigned long long)c.n,
			       (unsigned long long)wt, (unsigned long long)kept,
			       (unsigned long long)atomic_load(&c.files), (double)bytes / 1048576.0,
			       secs, c.manifest);
		}
	}
	for (unsigned w = 0; w < j.threads; w++) {
		free(c.w[w].d);
		free(c.w[w].k);
		free(c.w[w].ty);
		free(c.w[w].o);
		free(c.w[w].row);
		free(c.w[w].io);
		free(c.w[w].line);
	}
	for (uint64_t k = 0; k < c.n; k++)
		free(c.lines[k]);
	free(c.lines);
	free(c.skip);
	free(c.w);
	pthread_mutex_destroy(&c.lock);
	tiles_close(&j);
	return 0;
}
