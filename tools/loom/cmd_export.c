/*
 * tools/loom/cmd_export.c - `loom export FABRIC`: write a region of the
 * virtual texture (or a whole bolt) as tiles of Mitsuba .vol, NRRD, OpenVDB, NanoVDB or
 * OpenEXR z-slice files, with a manifest that makes a killed job resumable
 * and shards mergeable (`loom export --merge DIR`).  docs/batch.md
 * describes the options, the files, the manifest and resuming.
 */
#include "cli.h"
#include "commands.h"
#include "export.h"
#include "tiles.h"

#include "io/volume/vdb.h" /* io/: the OpenVDB shim, to name a missing package */

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static const char usage[] =
	"loom export FABRIC (--region X0,Y0,Z0:X1,Y1,Z1 | --all [--bolt LxW])\n"
	"            --format vol|nrrd|exr|vdb|nvdb -o DIR [--channels LIST]\n"
	"            [--compression blosc|zip|none] [--tile TX,TY[,TZ]] [--lod L]\n"
	"            [--shard I/N] [--budget MB]\n"
	"            [--threads N] [--db DB] [--quiet] [--json]\n"
	"loom export --merge DIR [--quiet] [--json]\n"
	"loom export --status DIR [--verify] [--quiet] [--json]\n";

static const char about[] =
	"Write a region of the fabric's virtual texture as tiles of files other\n"
	"tools read, with a manifest (DIR/manifest.json) listing every tile's box,\n"
	"files, sizes and CRC-32s (docs/batch.md).  Re-running the same command\n"
	"skips the tiles already complete and verified, so a killed job resumes.\n"
	"Runs of one shard at once are refused (a lock in DIR); --status reports the\n"
	"complete, missing and damaged tiles and the shards to run again.  FABRIC\n"
	"may be a paint file (loom paint): its painted regions are exported.\n";

static const opt_choice format_names[] = {
	{"vol", F_VOL}, {"nrrd", F_NRRD}, {"exr", F_EXR}, {"vdb", F_VDB}, {"nvdb", F_NVDB},
	{NULL, 0}};
static const opt_choice codec_names[] = {
	{"blosc", LOOM__VDB_BLOSC}, {"zip", LOOM__VDB_ZIP}, {"none", LOOM__VDB_NONE}, {NULL, 0}};

#define LOD_MAX 10 /* --lod: coarse voxels of at most 1024^3 fine ones */

static void stem_of(const tiles_job *j, uint64_t index, char *out, size_t n)
{
	int64_t lo[3], hi[3], t[3];

	tiles_box(j, index, lo, hi, t);
	snprintf(out, n, "tile-%lld-%lld-%lld", (long long)t[0], (long long)t[1],
	         (long long)t[2]);
}

/* ---- tiles -------------------------------------------------------------------- */

static int export_tile(void *vctx, unsigned wi, uint64_t k, uint64_t index, char *msg,
                       size_t msz)
{
	struct export_ctx *c = vctx;
	struct ewstate *w = &c->w[wi];
	int64_t lo[3], hi[3], t[3], rhi[3], clo[3], chi[3], n[3];
	loom_texture_region r;
	char stem[128], *line;
	const char *delay = getenv("LOOM_EXPORT_TILE_DELAY_MS");

	tiles_box(c->j, index, lo, hi, t);
	stem_of(c->j, index, stem, sizeof stem);
	/* --lod L: read whole coarse voxels of s = 2^L (lo is a multiple of s;
	   the far end of the region rounds up), then downsample */
	for (int a = 0; a < 3; a++) {
		int64_t s = (int64_t)1 << c->lod;
		n[a] = (hi[a] - lo[a] + s - 1) / s * s;
		rhi[a] = lo[a] + n[a];
		clo[a] = lo[a] / s;
		chi[a] = rhi[a] / s;
	}
	memset(&r, 0, sizeof r);
	r.layout = LOOM_REGION_X_FASTEST;
	r.density = w->d;
	if (c->chmask & 1u << CH_ORIENT)
		r.orientation = w->o;
	if (c->chmask & (1u << CH_ALBEDO | 1u << CH_KIND | 1u << CH_TYPE)) {
		r.kind = w->k;
		r.type = w->ty;
	}
	/* a paint file: its slubs, broken ends, missing picks and pulls in the
	   voxels read, its colours in the albedo (export_albedo) */
	if ((c->j->paint ? loom_paint_read_region(c->j->paint, lo, rhi, &r)
	                 : loom_texture_read_region(c->j->t, lo, rhi, &r)) != LOOM_OK) {
		snprintf(msg, msz, "tile %s: %s", stem, loom_texture_errmsg(c->j->t));
		return -1;
	}
	memcpy(w->lo, lo, sizeof w->lo);
	memcpy(w->n, n, sizeof w->n);
	w->tint = c->j->paint && (c->chmask & 1u << CH_ALBEDO) &&
	          (loom_paint_touches(c->j->paint, lo, rhi) & LOOM_PAINT_TOUCH_COLOUR);
	if (c->lod)
		export_lod_tile(c, w, n);
	w->line_len = 0;
	w->line[0] = 0;
	if (export_line_add(w, "{\"index\": %llu, \"tile\": [%lld, %lld, %lld], \"lo\": "
	                    "[%lld, %lld, %lld], \"hi\": [%lld, %lld, %lld], \"files\": [",
	                    (unsigned long long)index, (long long)t[0], (long long)t[1],
	                    (long long)t[2], (long long)lo[0], (long long)lo[1],
	                    (long long)lo[2], (long long)hi[0], (long long)hi[1],
	                    (long long)hi[2])) {
		snprintf(msg, msz, "out of memory");
		return -1;
	}
	if (export_write_tile(c, w, stem, clo, chi, msg, msz))
		return -1;
	if (export_line_add(w, "]}") || !(line = strdup(w->line))) {
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

static const char *opt_channels(const char *text, void *mask)
{
	if (parse_channels(text, mask))
		return "a comma-separated list of density, orientation, albedo, kind, type";
	return NULL;
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

/* ---- the command -------------------------------------------------------------- */

/* Free what the export allocated, release the shard lock (after success
   or a failed run alike). */
static void export_ctx_free(struct export_ctx *c, unsigned threads)
{
	for (unsigned w = 0; c->w && w < threads; w++) {
		free(c->w[w].d);
		free(c->w[w].k);
		free(c->w[w].ty);
		free(c->w[w].o);
		free(c->w[w].row);
		free(c->w[w].lv);
		free(c->w[w].tw);
		free(c->w[w].io);
		free(c->w[w].line);
	}
	for (uint64_t k = 0; c->lines && k < c->n; k++)
		free(c->lines[k]);
	free(c->lines);
	free(c->skip);
	free(c->order);
	free(c->byidx);
	free(c->w);
	c->w = NULL;
	c->lines = NULL;
	shard_lock_release(&c->lock_dir);
	pthread_mutex_destroy(&c->lock);
}

int cmd_export(int argc, char **argv)
{
	const char *prog = "loom export";
	const char *path = NULL, *out = NULL, *merge_dir = NULL, *status_dir = NULL;
	int json = 0, quiet = 0, verify = 0;
	uint32_t lod_u = 0;
	tiles_job j;
	struct export_ctx c;
	tiles_pool pool;
	cli_progress bar;
	const loom_design *d;
	size_t voxels, per, rowf, cvox, cx;
	uint64_t kept;
	uint32_t fcrc;
	uint64_t fbytes;
	double t0, secs;
	char params[2048], cl[160] = "", lod_text[32] = "";
	uint8_t *fbuf;
	opt_entry opts[] = {
		TILES_OPT_REGION(&j),
		TILES_OPT_ALL(&j),
		TILES_OPT_BOLT(&j),
		OPT_ENUM(0, "format", &c.format, "F", format_names, "vol: Mitsuba grid volumes, "
		         "one file per channel per tile\nnrrd: NRRD (attached header), one per "
		         "channel per tile\nexr: OpenEXR, one multi-channel image per z per tile\n"
		         "vdb: OpenVDB, one file per tile with a grid per channel\nnvdb: NanoVDB, "
		         "the same grids"),
		OPT_ENUM(0, "compression", &c.codec, "C", codec_names, "with --format vdb: "
		         "blosc (default), zip or none (NanoVDB files are uncompressed)"),
		OPT_CALLBACK(0, "channels", &c.chmask, "LIST", opt_channels, "comma-separated: "
		             "density, orientation, albedo, kind, type (default "
		             "density,orientation)"),
		TILES_OPT_TILE(&j, "tile size in voxels (default 64,64 and the region's whole "
		               "thickness)"),
		OPT_U32(0, "lod", &lod_u, "L", 0, LOD_MAX, "level of detail: voxels "
		        "downsampled by 2^L (density averaged, orientation by the averaged "
		        "structure tensor, albedo density-weighted, kind and type by density-"
		        "weighted majority); the region's corner and the tile sides must be "
		        "multiples of 2^L (default 0)"),
		TILES_OPT_SHARD(&j, "only shard I of N (0-based; each shard reads about 1/N of "
		                "the database); writes DIR/manifest-I-of-N.json"
		                TILES_SHARD_AUTO_HELP),
		OPT_STRING(0, "merge", &merge_dir, "DIR",
		           "merge DIR's shard manifests into DIR/manifest.json (all shards "
		           "complete, else exit 1 naming those to run again)"),
		OPT_STRING(0, "status", &status_dir, "DIR", "report DIR's complete, missing and "
		           "damaged tiles and the shards to run again; exit 0 when complete, 1 "
		           "when not"),
		OPT_FLAG(0, "verify", &verify, "with --status: read every file back and check "
		         "its CRC-32 (else its size)"),
		TILES_OPT_BUDGET(&j, "all memory for tile buffers and bricks, MiB (default 64)"),
		TILES_OPT_THREADS(&j),
		TILES_OPT_DB(&j),
		OPT_OUTPUT(&out, "DIR", "output directory (made if missing)"),
		OPT_JSON(&json, "print a summary as JSON"),
		OPT_QUIET(&quiet, "nothing on success (no progress, no summary)"),
		OPT_END()
	};
	opts_cmd cmd = {.prog = prog, .usage = usage, .about = about,
	                .exit1 = "bad input, failed write or incomplete",
	                .opts = opts,
	                .pos_name = "FABRIC", .pos_max = 1, .pos = &path};

	tiles_init(&j);
	memset(&c, 0, sizeof c);
	c.format = -1;
	c.codec = -1;
	c.chmask = 1u << CH_DENSITY | 1u << CH_ORIENT;
	opts_parse(&cmd, argc, argv);
	if (merge_dir || status_dir) {
		const char *what = merge_dir ? "--merge" : "--status";
		if (merge_dir && status_dir)
			opts_usage(&cmd, "give --merge DIR or --status DIR, not both");
		if (path || c.format >= 0 || c.codec >= 0 || opt_given(&cmd, &c.chmask) || out || j.region_s ||
		    j.all || j.shard_s || j.tile_s || opt_given(&cmd, &j.bolt) ||
		    opt_given(&cmd, &j.threads) || opt_given(&cmd, &j.budget_mb) || j.db_s ||
		    opt_given(&cmd, &lod_u))
			opts_usage(&cmd, "%s DIR takes no FABRIC nor export options", what);
		if (verify && merge_dir)
			opts_usage(&cmd, "--verify goes with --status");
		if (merge_dir)
			return export_merge(prog, merge_dir, json, quiet);
		return export_status(prog, status_dir, json, quiet, verify);
	}
	if (verify)
		opts_usage(&cmd, "--verify goes with --status");
	if (!path)
		opts_usage(&cmd, "missing FABRIC");
	tiles_parse(&cmd, &j, 1);
	if (c.format < 0)
		opts_usage(&cmd, "missing --format vol|nrrd|exr|vdb|nvdb");
	if (c.codec >= 0 && c.format != F_VDB)
		opts_usage(&cmd, "--compression goes with --format vdb (NanoVDB files are "
		           "uncompressed)");
	if (c.format == F_VDB || c.format == F_NVDB) {
		const char *miss = loom__vdb_missing(c.format == F_NVDB ? LOOM__VDB_NANOVDB
		                                                        : LOOM__VDB_OPENVDB);
		const char *why = miss ? loom__vdb_load_error() : NULL;
		if (why)
			cli_fail(prog, "--format %s: cannot load the VDB writer: %s",
			         fmt_names[c.format], why);
		if (miss)
			cli_fail(prog, "--format %s: this loom was built without %s (install "
			         "Debian's %s and rebuild loom)", fmt_names[c.format],
			         c.format == F_NVDB ? "NanoVDB" : "OpenVDB", miss);
		if (c.codec < 0)
			c.codec = c.format == F_VDB ? LOOM__VDB_BLOSC : LOOM__VDB_NONE;
	}
	if (!out)
		opts_usage(&cmd, "missing -o DIR");

	j.keep_paint = 1; /* a paint file's regions applied to every tile */
	tiles_open_fabric(&j, prog, path, 64);
	if (c.format == F_EXR && (j.tsize[0] > 65536 || j.tsize[1] > 65536)) {
		tiles_close(&j);
		opts_usage(&cmd, "EXR tiles are at most 65536 x 65536 pixels: give a smaller "
		           "--tile");
	}
	if (c.format == F_EXR && (j.lo[2] < INT32_MIN || j.hi[2] > INT32_MAX)) {
		tiles_close(&j);
		opts_usage(&cmd, "EXR slices need z within the 32-bit range");
	}
	if ((c.format == F_VDB || c.format == F_NVDB) &&
	    (j.lo[0] < INT32_MIN || j.lo[1] < INT32_MIN || j.lo[2] < INT32_MIN ||
	     j.hi[0] > INT32_MAX || j.hi[1] > INT32_MAX || j.hi[2] > INT32_MAX)) {
		tiles_close(&j);
		opts_usage(&cmd, "OpenVDB coordinates are 32-bit: the region must be within "
		           "-2^31 .. 2^31-1 voxels");
	}
	c.lod = (int)lod_u;
	c.vmm = j.voxel_mm * (double)((int64_t)1 << c.lod);
	for (int a = 0; a < 3 && c.lod; a++) {
		int64_t s = (int64_t)1 << c.lod;
		const char *why = NULL;
		if (j.tsize[a] < s)
			why = "makes the tiles vanish";
		else if (j.lo[a] % s != 0)
			why = "needs the region's corner at a multiple of";
		else if (j.nt[a] > 1 && j.tsize[a] % s != 0)
			why = "needs a tile side that is a multiple of";
		if (!why)
			continue;
		tiles_close(&j);
		if (j.tsize[a] < s)
			opts_usage(&cmd, "--lod %d %s: they are %lld voxels along %c, less than "
			           "one coarse voxel of %lld (give a --tile of at least %lld, or a "
			           "smaller --lod)", c.lod, why, (long long)j.tsize[a], "xyz"[a],
			           (long long)s, (long long)s);
		opts_usage(&cmd, "--lod %d %s %lld voxels along %c (the region starts at %lld, "
		           "the tiles are %lld voxels), so that coarse tiles line up edge to edge",
		           c.lod, why, (long long)s, "xyz"[a], (long long)j.lo[a],
		           (long long)j.tsize[a]);
	}
	make_dir(prog, out);
	c.j = &j;
	c.dir = out;
	c.n = tiles_in_shard(&j);
	c.lock_dir.fd = -1;
	d = loom_fabric_design(j.f);
	for (uint32_t t = 0; t < d->n_types && t < 256; t++)
		memcpy(c.albedo[t], d->types[t].albedo, sizeof c.albedo[t]);

	/* the parameters that determine the bytes (not threads nor budget) */
	fbuf = malloc(CRC_BUF);
	if (!fbuf || export_file_crc(path, fbuf, &fcrc, &fbytes))
		cli_fail(prog, "%s: cannot read", path);
	free(fbuf);
	for (int ch = 0; ch < N_CH; ch++)
		if (c.chmask & 1u << ch)
			snprintf(cl + strlen(cl), sizeof cl - strlen(cl), "%s\"%s\"", cl[0] ? ", " : "",
			         ch_names[ch]);
	if (c.lod) /* absent at 0: manifests of earlier exports stay valid */
		snprintf(lod_text, sizeof lod_text, ", \"lod\": %d", c.lod);
	snprintf(params, sizeof params,
	         "{\"fabric_bytes\": %llu, \"fabric_crc32\": \"%08x\", \"format\": \"%s\", "
	         "\"channels\": [%s], \"region_lo\": [%lld, %lld, %lld], \"region_hi\": "
	         "[%lld, %lld, %lld], \"tile\": [%lld, %lld, %lld], \"voxel_mm\": %.9g%s%s}",
	         (unsigned long long)fbytes, fcrc, fmt_names[c.format], cl, (long long)j.lo[0],
	         (long long)j.lo[1], (long long)j.lo[2], (long long)j.hi[0], (long long)j.hi[1],
	         (long long)j.hi[2], (long long)j.tsize[0], (long long)j.tsize[1],
	         (long long)j.tsize[2], j.voxel_mm,
	         c.format != F_VDB ? "" : c.codec == LOOM__VDB_BLOSC ? ", \"compression\": \"blosc\""
	         : c.codec == LOOM__VDB_ZIP ? ", \"compression\": \"zip\""
	                                    : ", \"compression\": \"none\"", lod_text);
	c.params = params;
	if (j.shard_n > 1)
		snprintf(c.manifest, sizeof c.manifest, "%s/manifest-%u-of-%u.json", out, j.shard_i,
		         j.shard_n);
	else
		snprintf(c.manifest, sizeof c.manifest, "%s/manifest.json", out);

	/* per worker: the tile's raw channels, a row of up to 9 floats per voxel,
	   the CRC buffer and the writers' own buffers (a .vol writer 64 KiB; an
	   EXR writer one 16-row chunk, its planes and a compressor) */
	{
		/* with --lod the tile read rounds up to whole coarse voxels; the
		   writers see the coarse tile (cvox voxels, cx a row) */
		int64_t s = (int64_t)1 << c.lod, rt[3];
		for (int a = 0; a < 3; a++)
			rt[a] = (j.tsize[a] + s - 1) / s * s;
		voxels = (size_t)rt[0] * (size_t)rt[1] * (size_t)rt[2];
		cvox = voxels >> (3 * c.lod);
		cx = (size_t)(rt[0] / s);
	}
	rowf = cx * 9;
	per = voxels * 5 + rowf * sizeof(float) + CRC_BUF + (1u << 20) +
	      (c.format == F_EXR ? cx * 16 * 9 * 4 * 3 : 0) +
	      (c.lod ? cvox * LOD_FLOATS * sizeof(float) + 256 * sizeof(double) : 0);
	/* a VDB writer holds the tile's grids (all voxels active at worst), and
	   for NanoVDB the converted grids too */
	if (c.format == F_VDB || c.format == F_NVDB)
		for (int ch = 0; ch < N_CH; ch++)
			if (c.chmask & 1u << ch)
				per += cvox * (c.format == F_NVDB ? 2u : 1u) *
				       (ch_comps[ch] == 3 ? LOOM__VDB_BYTES_VEC3 : LOOM__VDB_BYTES_SCALAR);
	/* the manifest lines, held until the end: per tile of the shard about
	   256 bytes of index and box and 128 per file (an upper estimate), its
	   pointer, skip flag and allocation header, and its place in the
	   shard's order and by index (16 bytes) */
	{
		size_t files = 0;
		for (int ch = 0; ch < N_CH; ch++)
			files += (c.chmask >> ch) & 1u;
		if (c.format == F_EXR)
			files = (size_t)((j.tsize[2] + ((int64_t)1 << c.lod) - 1) >> c.lod);
		if (c.format == F_VDB || c.format == F_NVDB)
			files = 1;
		j.job_bytes = (size_t)c.n * (256 + 128 * files + 8 + 1 + 16 + 16);
	}
	tiles_open_texture(&j, prog, per);

	c.lines = calloc(c.n ? c.n : 1, sizeof *c.lines);
	c.skip = calloc(c.n ? c.n : 1, 1);
	c.order = malloc((c.n ? c.n : 1) * sizeof *c.order);
	c.byidx = malloc((c.n ? c.n : 1) * sizeof *c.byidx);
	c.w = calloc(j.threads, sizeof *c.w);
	if (!c.lines || !c.skip || !c.order || !c.byidx || !c.w)
		cli_fail(prog, "out of memory");
	if (tiles_shard_list(&j, tiles_index_order_wanted(), c.order) != 0)
		cli_fail(prog, "cannot order the tiles (out of memory)");
	export_sort_by_index(&c);
	for (unsigned w = 0; w < j.threads; w++) {
		struct ewstate *ws = &c.w[w];
		ws->d = malloc(voxels);
		ws->k = malloc(voxels);
		ws->ty = malloc(voxels);
		ws->o = malloc(voxels * 2);
		ws->row = malloc(rowf * sizeof(float));
		if (c.lod && (!(ws->lv = malloc(cvox * LOD_FLOATS * sizeof(float))) ||
		              !(ws->tw = calloc(256, sizeof(double)))))
			cli_fail(prog, "out of memory");
		ws->io = malloc(CRC_BUF);
		ws->line_cap = 4096;
		ws->line = malloc(ws->line_cap);
		if (!ws->d || !ws->k || !ws->ty || !ws->o || !ws->row || !ws->io || !ws->line)
			cli_fail(prog, "out of memory");
	}
	pthread_mutex_init(&c.lock, NULL);
	{
		char msg[LOOM_DIAG_MSG_MAX + 4096];
		if (shard_lock_shard(&c.lock_dir, out, j.shard_i, j.shard_n, msg, sizeof msg))
			cli_fail(prog, "%s", msg);
	}
	export_remove_stale(&c);
	kept = export_resume(&c, prog);
	if (kept && !quiet)
		fprintf(stderr, "%s: %llu of %llu tiles already complete and verified "
		        "(%s): skipping them\n", prog, (unsigned long long)kept,
		        (unsigned long long)c.n, c.manifest);

	memset(&pool, 0, sizeof pool);
	pool.job = &j;
	pool.fn = export_tile;
	pool.ctx = &c;
	pool.list = c.order;
	pool.skip = c.skip;
	pool.tick = export_tick;
	pool.progress = &bar;
	pool.index_order = tiles_index_order_wanted();
	c.last_write = cli_now();
	cli_progress_begin(&bar, prog, "tiles", c.n, quiet);
	t0 = cli_now();
	if (tiles_run(&pool) != 0) {
		export_manifest_flush(&c, 0);
		cli_error(prog, "%s", pool.msg);
		export_ctx_free(&c, j.threads);
		tiles_close(&j);
		return EXIT_BAD_INPUT;
	}
	secs = cli_now() - t0;
	if (export_manifest_flush(&c, 1) != 0) {
		cli_error(prog, "%s", c.manifest_msg);
		export_ctx_free(&c, j.threads);
		tiles_close(&j);
		return EXIT_BAD_INPUT;
	}
	{
		uint64_t wt = atomic_load(&c.written_tiles), bytes = atomic_load(&c.bytes);
		uint64_t vox = 0;
		for (uint64_t k = 0; k < c.n; k++) {
			if (c.skip[k])
				continue;
			vox += tiles_voxels(&j, c.order[k]);
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
		} else if (!quiet) {
			printf("%s: %llu tiles (%llu written, %llu already complete), %llu files, "
			       "%.1f MiB in %.3f s; manifest %s\n", out, (unsigned long long)c.n,
			       (unsigned long long)wt, (unsigned long long)kept,
			       (unsigned long long)atomic_load(&c.files), (double)bytes / 1048576.0,
			       secs, c.manifest);
		}
	}
	export_ctx_free(&c, j.threads);
	tiles_close(&j);
	return 0;
}
