/*
 * tools/loom/cmd_exemplar.c - `loom exemplar generate|info|verify|export`:
 * build, inspect, check and export exemplar databases (docs/exemplars.md).
 */
#include "cli.h"
#include "commands.h"
#include "progress.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static const char help_main[] =
	"usage: loom exemplar COMMAND [ARGS...]\n"
	"\n"
	"Exemplar databases: volumetric exemplars of simple weaves, stored as\n"
	"compressed voxel bricks (docs/exemplars.md, docs/formats.md).\n"
	"\n"
	"commands:\n"
	"  generate   make procedural CT-like exemplars into a new database\n"
	"             (--scan: a scan-like volume of a woven sheet, for build)\n"
	"  build      turn a scan into an exemplar appended to a database\n"
	"  info       list a database's exemplars\n"
	"  verify     check every brick and checksum of a database\n"
	"  export     write one exemplar volume as NRRD\n"
	"\n"
	"Commands that read a database take it as DB or --db DB; without one they\n"
	"use $LOOM_DB, then default.ldb in the data directory ($LOOM_DATA, the\n"
	"build tree, the installed share/loom).\n";

static const char help_generate[] =
	"usage: loom exemplar generate [--preset small|paper|tiny] [--weaves LIST]\n"
	"                              [--seed N] [OPTIONS] -o DB\n"
	"\n"
	"Generate one procedural exemplar per weave and write the database DB\n"
	"(atomically).  The output is the same for any thread count.  With\n"
	"--scan, write a scan-like volume instead (loom exemplar generate --scan\n"
	"--help).\n"
	"\n"
	"options:\n"
	"  -o, --output DB     database to write (.ldb)\n"
	"  --preset NAME       small (default: block 24x16x48, 24 um voxels),\n"
	"                      paper (115x70x300, 5 um: the paper's scale) or\n"
	"                      tiny (8x6x12, 72 um: test corpora)\n"
	"  --weaves LIST       comma-separated weaves (loom pattern names, e.g.\n"
	"                      twill:2/3,satin:1/4,plain); default: the 2/3, 3/2,\n"
	"                      1/4, 4/1 twills and the same four satins\n"
	"  --seed N            random seed (default 1)\n"
	"  --crossings RxC     crossings per exemplar, multiples of each weave's\n"
	"                      repeat (default: the smallest multiple >= 4, so 5x5\n"
	"                      for the 5-end weaves)\n"
	"  --block B1xB2xB3    block size in voxels (overrides the preset)\n"
	"  --voxel-size UM     voxel edge in micrometres (overrides the preset)\n"
	"  --brick XxYxZ       brick shape (default 16x16x64)\n"
	"  --level L           libdeflate level 1..12 (default 6)\n"
	"  --threads N         worker threads (default 2)\n"
	"  --json              print the result as JSON\n"
	"  --quiet             no progress or summary\n";

static const char help_info[] =
	"usage: loom exemplar info [DB] [--db DB] [--json]\n"
	"\n"
	"List the exemplars of a database: weave, crossings, block size, voxel\n"
	"count, raw and compressed bytes, compression ratio.\n"
	"\n"
	"options:\n"
	"  --db DB    database (or give it as the first argument)\n"
	"  --json     JSON object with an \"exemplars\" array (name, weave: one\n"
	"             string of 0/1 per pick, crossings, block, raw_bytes,\n"
	"             compressed_bytes, ...)\n";

static const char help_verify[] =
	"usage: loom exemplar verify [DB] [--db DB] [--quiet]\n"
	"\n"
	"Read every brick of a database, check its CRC32, decompress it to the\n"
	"exact size and check its labels.  Exit status 0 when all are good, 1\n"
	"naming the first bad brick otherwise.\n";

static const char help_export[] =
	"usage: loom exemplar export [DB] [--db DB] --exemplar K -o FILE\n"
	"                            [--channel C] [--detached]\n"
	"\n"
	"Write one exemplar volume as NRRD (raw data, axes x y z, spacing = voxel\n"
	"size in mm) for viewing in standard tools (unu, ParaView, 3D Slicer).\n"
	"\n"
	"options:\n"
	"  --exemplar K    exemplar name or index (see `loom exemplar info`)\n"
	"  -o, --output F  output file: F.nrrd (attached) or F.nhdr (detached)\n"
	"  --channel C     density (uint8, default), label (uint8), kind (uint8:\n"
	"                  0 empty, 1 warp, 2 weft), orientation (3 x float32)\n"
	"                  or orient-code (uint16)\n"
	"  --detached      header in FILE, data in FILE with the extension .raw\n";

/* ---- generate ----------------------------------------------------------- */

typedef struct progress_state {
	int on;
	double t0;
	int last_pct;
} progress_state;

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void progress_cb(void *user, uint64_t done, uint64_t total)
{
	progress_state *ps = user;
	int pct = total ? (int)(100 * done / total) : 100;

	if (!ps->on || pct == ps->last_pct)
		return;
	ps->last_pct = pct;
	fprintf(stderr, "\rloom exemplar generate: %3d%% (%llu/%llu bricks, %.1f s)",
	        pct, (unsigned long long)done, (unsigned long long)total,
	        now_s() - ps->t0);
	if (done == total)
		fputc('\n', stderr);
	fflush(stderr);
}

static int parse_size3(const char *s, uint32_t v[3])
{
	char buf[96], *a, *b;

	if (!s || strlen(s) >= sizeof buf)
		return -1;
	strcpy(buf, s);
	a = strpbrk(buf, "xX,");
	if (!a)
		return -1;
	*a++ = 0;
	b = strpbrk(a, "xX,");
	if (!b)
		return -1;
	*b++ = 0;
	if (cli_parse_u32(buf, &v[0]) || cli_parse_u32(a, &v[1]) || cli_parse_u32(b, &v[2]))
		return -1;
	return 0;
}

static int sub_generate(int argc, char **argv)
{
	const char *prog = "loom exemplar generate";
	const char *out = NULL, *preset = "small", *weaves = NULL;
	const char *seed_s = NULL, *cross_s = NULL, *block_s = NULL, *vs_s = NULL;
	const char *brick_s = NULL, *level_s = NULL, *threads_s = NULL;
	char *wbuf = NULL;
	int quiet = 0, json = 0, rc;
	loom_exgen_params p;
	loom_diag diag;
	progress_state ps;
	uint64_t hash = 0;
	cli_args a;
	double t0;

	cli_init(&a, argc, argv, prog, help_generate);
	while (cli_more(&a)) {
		if (cli_value(&a, "-o", &out) || cli_value(&a, "--output", &out) ||
		    cli_value(&a, "--preset", &preset) || cli_value(&a, "--weaves", &weaves) ||
		    cli_value(&a, "--seed", &seed_s) || cli_value(&a, "--crossings", &cross_s) ||
		    cli_value(&a, "--block", &block_s) ||
		    cli_value(&a, "--voxel-size", &vs_s) || cli_value(&a, "--brick", &brick_s) ||
		    cli_value(&a, "--level", &level_s) || cli_value(&a, "--threads", &threads_s))
			continue;
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if (cli_flag(&a, "--json")) {
			json = 1;
			continue;
		}
		cli_unknown(&a);
	}
	if (!out)
		cli_usage(&a, "missing -o DB");
	if (loom_exgen_preset(preset, &p) != LOOM_OK)
		cli_usage(&a, "unknown preset '%s' (expected small, paper or tiny)", preset);
	if (weaves) {
		char *s, *tok, *save = NULL;
		wbuf = strdup(weaves);
		if (!wbuf)
			cli_fail(prog, "out of memory");
		p.n_weaves = 0;
		for (s = wbuf; (tok = strtok_r(s, ",", &save)) != NULL; s = NULL) {
			if (p.n_weaves == LOOM_EXGEN_MAX_WEAVES)
				cli_usage(&a, "more than %d weaves", LOOM_EXGEN_MAX_WEAVES);
			p.weaves[p.n_weaves++] = tok;
		}
		if (p.n_weaves == 0)
			cli_usage(&a, "--weaves needs at least one weave");
	}
	if (seed_s && cli_parse_u64(seed_s, &p.seed))
		cli_usage(&a, "bad --seed '%s'", seed_s);
	if (cross_s && (cli_parse_size2(cross_s, &p.rows, &p.cols) || !p.rows || !p.cols))
		cli_usage(&a, "bad --crossings '%s' (expected RxC)", cross_s);
	if (block_s && parse_size3(block_s, p.block))
		cli_usage(&a, "bad --block '%s' (expected B1xB2xB3)", block_s);
	if (brick_s && parse_size3(brick_s, p.brick))
		cli_usage(&a, "bad --brick '%s' (expected XxYxZ)", brick_s);
	if (vs_s) {
		double d;
		if (cli_parse_double(vs_s, &d) || !(d > 0) || d > 10000)
			cli_usage(&a, "bad --voxel-size '%s'", vs_s);
		p.voxel_size_um = (float)d;
	}
	if (level_s) {
		uint32_t l;
		if (cli_parse_u32(level_s, &l) || l < 1 || l > 12)
			cli_usage(&a, "bad --level '%s' (expected 1..12)", level_s);
		p.level = (int)l;
	}
	if (threads_s && (cli_parse_u32(threads_s, &p.threads) || !p.threads ||
	                  p.threads > 64))
		cli_usage(&a, "bad --threads '%s' (expected 1..64)", threads_s);
	memset(&ps, 0, sizeof ps);
	ps.on = !quiet && isatty(2);
	ps.last_pct = -1;
	ps.t0 = t0 = now_s();
	p.progress = progress_cb;
	p.user = &ps;
	cli_diag_init(&diag, &quiet);
	rc = loom_exgen_write_db(out, &p, &hash, &diag);
	free(wbuf);
	if (rc)
		cli_fail(prog, "%s", diag.message);
	if (json || !quiet) {
		loom_db *db;
		loom_db_info info;
		if (loom_db_open(out, &db, &diag) != LOOM_OK)
			cli_fail(prog, "%s", diag.message);
		loom_db_get_info(db, &info);
		if (json) {
			json_w w;
			jw_begin(&w, stdout);
			jw_str(&w, "path", out);
			jw_uint(&w, "exemplars", info.n_exemplars);
			jw_uint(&w, "bricks", info.n_bricks);
			jw_uint(&w, "raw_bytes", info.raw_bytes);
			jw_uint(&w, "file_bytes", info.file_bytes);
			jw_num(&w, "ratio", (double)info.raw_bytes / (double)info.file_bytes);
			{
				char hs[32];
				snprintf(hs, sizeof hs, "%016llx", (unsigned long long)hash);
				jw_str(&w, "content_hash", hs);
			}
			jw_num(&w, "seconds", now_s() - t0);
			jw_end(&w);
		} else {
			printf("%s: %u exemplars, %llu bricks, %.1f MB raw in %.2f MB (%.1fx), "
			       "hash %016llx, %.2f s\n", out, info.n_exemplars,
			       (unsigned long long)info.n_bricks, (double)info.raw_bytes / 1e6,
			       (double)info.file_bytes / 1e6,
			       (double)info.raw_bytes / (double)info.file_bytes,
			       (unsigned long long)hash, now_s() - t0);
		}
		loom_db_close(db);
	}
	return 0;
}

/* ---- generate --scan ------------------------------------------------------ */

/* Write a float volume (channels 1 or 3) as NRRD0004, raw, little-endian:
   uchar (round(v*255)), or float. */
static int write_nrrd(const char *path, const float *v, uint32_t nx, uint32_t ny,
                      uint32_t nz, uint32_t channels, int as_u8, double sp,
                      loom_diag *diag)
{
	char tmp[4096];
	FILE *fp;
	size_t n = (size_t)nx * ny * nz * channels;
	int ok;

	(void)diag;
	if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp)
		return -1;
	fp = fopen(tmp, "wb");
	if (!fp)
		return -1;
	fprintf(fp, "NRRD0004\n# written by loom exemplar generate --scan\n"
	        "type: %s\ndimension: %u\n", as_u8 ? "uchar" : "float",
	        channels > 1 ? 4u : 3u);
	if (channels > 1)
		fprintf(fp, "sizes: %u %u %u %u\nkinds: 3-vector space space space\n"
		        "spacings: NaN %.9g %.9g %.9g\n", channels, nx, ny, nz, sp, sp, sp);
	else
		fprintf(fp, "sizes: %u %u %u\nspacings: %.9g %.9g %.9g\n", nx, ny, nz, sp,
		        sp, sp);
	fprintf(fp, "encoding: raw\nendian: little\n\n");
	ok = 1;
	for (size_t i = 0; i < n && ok; i += 65536) {
		size_t m = n - i < 65536 ? n - i : 65536;
		if (as_u8) {
			uint8_t b[65536];
			for (size_t k = 0; k < m; k++) {
				float x = v[i + k];
				b[k] = (uint8_t)(!(x > 0) ? 0 : x >= 1 ? 255 : (int)(x * 255 + 0.5f));
			}
			ok = fwrite(b, 1, m, fp) == m;
		} else {
			ok = fwrite(v + i, sizeof(float), m, fp) == m; /* little-endian host */
		}
	}
	if (fclose(fp) != 0 || !ok || rename(tmp, path) != 0) {
		remove(tmp);
		return -1;
	}
	return 0;
}

/* .vol through the library's writer. */
static int write_vol(const char *path, const float *v, uint32_t nx, uint32_t ny,
                     uint32_t nz, uint32_t channels, int encoding, double sp,
                     loom_diag *diag)
{
	loom_vol_header h;
	loom_vol_writer *w;
	int rc;

	memset(&h, 0, sizeof h);
	h.encoding = encoding;
	h.xres = nx;
	h.yres = ny;
	h.zres = nz;
	h.channels = channels;
	h.bbox_max[0] = (float)(sp * (nx - 1));
	h.bbox_max[1] = (float)(sp * (ny - 1));
	h.bbox_max[2] = (float)(sp * (nz - 1));
	rc = loom_vol_writer_open(path, &h, &w, diag);
	if (rc)
		return rc;
	rc = loom_vol_writer_put_slices(w, v, nz, diag);
	if (rc) {
		loom_vol_writer_abort(w);
		return rc;
	}
	return loom_vol_writer_finish(w, diag);
}

static int ends_with(const char *s, const char *suf)
{
	size_t a = strlen(s), b = strlen(suf);
	return a >= b && strcmp(s + a - b, suf) == 0;
}

/* "out.vol" + "-orient" -> "out-orient.vol" */
static char *sibling(const char *path, const char *tag)
{
	const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
	size_t base = dot && (!slash || dot > slash) ? (size_t)(dot - path) : strlen(path);
	char *s = malloc(strlen(path) + strlen(tag) + 8);
	if (!s)
		return NULL;
	memcpy(s, path, base);
	strcpy(s + base, tag);
	strcat(s, dot && (!slash || dot > slash) ? dot : "");
	return s;
}

static const char help_generate_scan[] =
	"usage: loom exemplar generate --scan [--preset small|paper] [--weave NAME]\n"
	"                              [--crossings WxF] [--rotate DEG] [--offset X,Y]\n"
	"                              [--noise S] [--blur S] [--no-orientation]\n"
	"                              [--density u8|f32] [--orient f32|qdir]\n"
	"                              [--seed N] [--threads N] [--quiet]\n"
	"                              -o SCAN.vol|SCAN.nrrd [--truth TRUTH.json]\n"
	"\n"
	"Write what a micro-CT scanner would give for a woven sheet, for testing\n"
	"`loom exemplar build`: yarns cut at the borders, the sheet turned about z\n"
	"and offset from the volume's corner, blurred and noisy density, and\n"
	"(unless --no-orientation) the fibre orientation.  Deterministic.\n"
	"\n"
	"options:\n"
	"  -o, --output F     density: F.vol (Mitsuba grid) or F.nrrd; orientation\n"
	"                     goes to F-orient.vol / F-orient.nrrd\n"
	"  --preset NAME      small (default: 160x160x40 voxels, 7 warps x 9 wefts\n"
	"                     24 x 18 voxels apart, 24 um voxels) or paper (1000 x\n"
	"                     1000 x 300, spacing 115 x 70 voxels of 5 um); paper:N\n"
	"                     scales the paper sheet to N x N x 0.3N\n"
	"  --weave NAME       loom pattern name (default twill:2/3)\n"
	"  --crossings WxF    warps x wefts of the sheet (default: the preset's);\n"
	"                     the volume grows or shrinks to hold them\n"
	"  --rotate DEG       rotation about z, counter-clockwise (default 3)\n"
	"  --offset X,Y       aligned position of warp 0 and weft 0 (voxels;\n"
	"                     default the preset's)\n"
	"  --noise S          Gaussian noise sigma on density (default 0.08)\n"
	"  --blur S           Gaussian blur sigma in voxels (default 0.8)\n"
	"  --no-orientation   write the density only\n"
	"  --density T        u8 (default) or f32 samples\n"
	"  --orient E         f32 (3 floats, default) or qdir (.vol encoding 4)\n"
	"  --seed N           random seed (default 7)\n"
	"  --truth F.json     ground truth for tests: weave of the complete\n"
	"                     crossings (one 0/1 string per pick), rotation_degrees,\n"
	"                     crop [x0, y0, width, height] (aligned frame, voxels),\n"
	"                     warps, wefts, ...; labels (0 empty, 1..W warps by x,\n"
	"                     W+1.. wefts by y) to F-labels.nrrd (uchar)\n"
	"  --pure-noise       uniform noise instead of a sheet (bad-scan tests)\n"
	"  --threads N        worker threads (default 2)\n"
	"  --quiet            no summary\n";

static int sub_generate_scan(int argc, char **argv)
{
	const char *prog = "loom exemplar generate --scan";
	const char *out = NULL, *preset = "small", *weave = "twill:2/3", *cross_s = NULL;
	const char *rot_s = NULL, *off_s = NULL, *noise_s = NULL, *blur_s = NULL;
	const char *seed_s = NULL, *truth = NULL, *dens_s = "u8", *or_s = "f32";
	const char *threads_s = NULL;
	int quiet = 0, no_orient = 0, pure = 0, nrrd, rc;
	uint32_t threads = 2;
	loom_scan_sheet s;
	loom_weave_params wp;
	uint32_t rr, rc_;
	uint8_t *wbuf = NULL, *lab = NULL;
	loom_scan_volume v;
	loom_diag diag;
	double vs_mm;
	cli_args a;

	cli_init(&a, argc, argv, prog, help_generate_scan);
	while (cli_more(&a)) {
		if (cli_value(&a, "-o", &out) || cli_value(&a, "--output", &out) ||
		    cli_value(&a, "--preset", &preset) || cli_value(&a, "--weave", &weave) ||
		    cli_value(&a, "--crossings", &cross_s) || cli_value(&a, "--rotate", &rot_s) ||
		    cli_value(&a, "--offset", &off_s) || cli_value(&a, "--noise", &noise_s) ||
		    cli_value(&a, "--blur", &blur_s) || cli_value(&a, "--seed", &seed_s) ||
		    cli_value(&a, "--truth", &truth) || cli_value(&a, "--density", &dens_s) ||
		    cli_value(&a, "--orient", &or_s) || cli_value(&a, "--threads", &threads_s))
			continue;
		if (cli_flag(&a, "--scan"))
			continue;
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if (cli_flag(&a, "--no-orientation")) {
			no_orient = 1;
			continue;
		}
		if (cli_flag(&a, "--pure-noise")) {
			pure = 1;
			continue;
		}
		cli_unknown(&a);
	}
	if (!out)
		cli_usage(&a, "missing -o SCAN.vol|SCAN.nrrd");
	nrrd = ends_with(out, ".nrrd");
	if (!nrrd && !ends_with(out, ".vol"))
		cli_usage(&a, "output '%s' must end in .vol or .nrrd", out);
	if (strcmp(dens_s, "u8") && strcmp(dens_s, "f32"))
		cli_usage(&a, "bad --density '%s' (expected u8 or f32)", dens_s);
	if (strcmp(or_s, "f32") && strcmp(or_s, "qdir"))
		cli_usage(&a, "bad --orient '%s' (expected f32 or qdir)", or_s);
	if (nrrd && strcmp(or_s, "qdir") == 0)
		cli_usage(&a, "--orient qdir needs a .vol output");
	if (loom_scan_sheet_preset(preset, &s) != LOOM_OK)
		cli_usage(&a, "unknown preset '%s' (expected small, paper or paper:N)", preset);
	vs_mm = strcmp(preset, "small") == 0 ? 0.024 : 0.005 * 1000.0 / s.nx;
	cli_diag_init(&diag, &quiet);
	if (loom_weave_parse(weave, &wp, &diag) != LOOM_OK ||
	    loom_weave_repeat(&wp, &rr, &rc_, &diag) != LOOM_OK)
		cli_usage(&a, "bad --weave '%s': %s", weave, diag.message);
	if (threads_s && (cli_parse_u32(threads_s, &threads) || !threads || threads > 64))
		cli_usage(&a, "bad --threads '%s' (expected 1..64)", threads_s);
	if (seed_s && cli_parse_u64(seed_s, &s.seed))
		cli_usage(&a, "bad --seed '%s'", seed_s);
	if (rot_s) {
		double d;
		if (cli_parse_double(rot_s, &d) || fabs(d) > 20)
			cli_usage(&a, "bad --rotate '%s' (expected -20..20 degrees)", rot_s);
		s.angle_deg = (float)d;
	}
	if (noise_s) {
		double d;
		if (cli_parse_double(noise_s, &d) || d < 0 || d > 1)
			cli_usage(&a, "bad --noise '%s' (expected 0..1)", noise_s);
		s.noise = (float)d;
	}
	if (blur_s) {
		double d;
		if (cli_parse_double(blur_s, &d) || d < 0 || d > 8)
			cli_usage(&a, "bad --blur '%s' (expected 0..8 voxels)", blur_s);
		s.blur = (float)d;
	}
	if (off_s) {
		char buf[64], *c;
		double x, y;
		if (strlen(off_s) >= sizeof buf)
			cli_usage(&a, "bad --offset '%s'", off_s);
		strcpy(buf, off_s);
		c = strchr(buf, ',');
		if (!c)
			cli_usage(&a, "bad --offset '%s' (expected X,Y)", off_s);
		*c++ = 0;
		if (cli_parse_double(buf, &x) || cli_parse_double(c, &y) || x < -s.sx ||
		    y < -s.sy || x > 4 * s.sx || y > 4 * s.sy)
			cli_usage(&a, "bad --offset '%s' (expected X,Y within a few yarn "
			          "spacings)", off_s);
		s.x0 = (float)x;
		s.y0 = (float)y;
	}
	if (cross_s) {
		uint32_t w, f;
		if (cli_parse_size2(cross_s, &w, &f) || w < 3 || f < 3 ||
		    w > LOOM_SCAN_MAX_YARNS || f > LOOM_SCAN_MAX_YARNS)
			cli_usage(&a, "bad --crossings '%s' (expected WxF, 3..%d each)", cross_s,
			          LOOM_SCAN_MAX_YARNS);
		s.nw = w;
		s.nf = f;
		s.nx = (uint32_t)ceil(2 * s.x0 + (w - 1) * s.sx) + 4;
		s.ny = (uint32_t)ceil(2 * s.y0 + (f - 1) * s.sy) + 4;
	}
	s.pure_noise = pure;
	s.rep_rows = rr;
	s.rep_cols = rc_;
	wbuf = malloc((size_t)rr * rc_);
	if (!wbuf)
		cli_fail(prog, "out of memory");
	for (uint32_t i = 0; i < rr; i++)
		for (uint32_t j = 0; j < rc_; j++)
			wbuf[(size_t)i * rc_ + j] = (uint8_t)loom_weave_cell(&wp, i, j);
	s.weave = wbuf;
	if (loom_scan_volume_alloc(&v, s.nx, s.ny, s.nz,
	                           LOOM_SCAN_DENSITY | (no_orient ? 0 : LOOM_SCAN_ORIENT)))
		cli_fail(prog, "cannot allocate %ux%ux%u voxels", s.nx, s.ny, s.nz);
	if (truth && !(lab = calloc((size_t)s.nx * s.ny * s.nz, 1)))
		cli_fail(prog, "out of memory");
	rc = loom_scan_sheet_make(&s, &v, lab, threads, &diag);
	if (rc)
		cli_fail(prog, "%s", diag.message);
	/* density */
	rc = nrrd ? write_nrrd(out, v.density, s.nx, s.ny, s.nz, 1, dens_s[0] == 'u',
	                       vs_mm, &diag)
	          : write_vol(out, v.density, s.nx, s.ny, s.nz, 1,
	                      dens_s[0] == 'u' ? LOOM_VOL_UINT8 : LOOM_VOL_FLOAT32, vs_mm,
	                      &diag);
	if (rc)
		cli_fail(prog, "%s: cannot write%s%s", out, nrrd ? "" : ": ",
		         nrrd ? "" : diag.message);
	if (!no_orient) {
		char *op = sibling(out, "-orient");
		if (!op)
			cli_fail(prog, "out of memory");
		rc = nrrd ? write_nrrd(op, v.orient, s.nx, s.ny, s.nz, 3, 0, vs_mm, &diag)
		          : write_vol(op, v.orient, s.nx, s.ny, s.nz, 3,
		                      or_s[0] == 'q' ? LOOM_VOL_QDIR : LOOM_VOL_FLOAT32, vs_mm,
		                      &diag);
		if (rc)
			cli_fail(prog, "%s: cannot write", op);
		free(op);
	}
	if (truth) {
		loom_scan_sheet_grid g;
		char *lp = sibling(truth, "-labels"), *dot, row[LOOM_SCAN_MAX_YARNS + 2];
		FILE *fp;
		json_w w;
		float *lf;
		size_t n = (size_t)s.nx * s.ny * s.nz;
		if (!lp)
			cli_fail(prog, "out of memory");
		dot = strrchr(lp, '.');
		if (dot && strcmp(dot, ".json") == 0)
			strcpy(dot, ".nrrd");
		lf = malloc(n * sizeof *lf);
		if (!lf)
			cli_fail(prog, "out of memory");
		for (size_t i = 0; i < n; i++)
			lf[i] = (float)lab[i] / 255.0f;
		if (write_nrrd(lp, lf, s.nx, s.ny, s.nz, 1, 1, vs_mm, &diag))
			cli_fail(prog, "%s: cannot write", lp);
		free(lf);
		memset(&g, 0, sizeof g);
		if (!pure && loom_scan_sheet_truth(&s, &g) != LOOM_OK)
			cli_fail(prog, "no 2 x 2 window of complete crossings fits in the scan");
		fp = fopen(truth, "w");
		if (!fp)
			cli_fail(prog, "%s: cannot write", truth);
		jw_begin(&w, fp);
		jw_arr(&w, "weave");
		for (uint32_t i = 0; i < g.rows; i++) {
			for (uint32_t j = 0; j < g.cols; j++)
				row[j] = loom_scan_sheet_w(&s, g.first_weft + i, g.first_warp + j) ? '1' : '0';
			row[g.cols] = 0;
			jw_str(&w, NULL, row);
		}
		jw_close(&w);
		jw_num(&w, "rotation_degrees", s.angle_deg);
		jw_arr(&w, "crop");
		for (int k = 0; k < 4; k++)
			jw_num(&w, NULL, g.crop[k]);
		jw_close(&w);
		jw_uint(&w, "warps", s.nw);
		jw_uint(&w, "wefts", s.nf);
		jw_uint(&w, "first_warp", g.first_warp);
		jw_uint(&w, "first_weft", g.first_weft);
		jw_arr(&w, "crossings");
		jw_uint(&w, NULL, g.rows);
		jw_uint(&w, NULL, g.cols);
		jw_close(&w);
		jw_arr(&w, "block");
		jw_uint(&w, NULL, g.b1);
		jw_uint(&w, NULL, g.b2);
		jw_uint(&w, NULL, s.nz);
		jw_close(&w);
		jw_arr(&w, "full_weave");
		for (uint32_t i = 0; i < s.nf; i++) {
			for (uint32_t j = 0; j < s.nw; j++)
				row[j] = loom_scan_sheet_w(&s, i, j) ? '1' : '0';
			row[s.nw] = 0;
			jw_str(&w, NULL, row);
		}
		jw_close(&w);
		jw_arr(&w, "size");
		jw_uint(&w, NULL, s.nx);
		jw_uint(&w, NULL, s.ny);
		jw_uint(&w, NULL, s.nz);
		jw_close(&w);
		jw_num(&w, "voxel_mm", vs_mm);
		jw_str(&w, "weave_name", weave);
		jw_str(&w, "labels", lp);
		jw_end(&w);
		if (fclose(fp) != 0)
			cli_fail(prog, "%s: cannot write", truth);
		free(lp);
	}
	if (!quiet)
		printf("%s: %ux%ux%u voxels of %g mm, %u warps x %u wefts (%s), rotated %g "
		       "degrees, noise %g, blur %g%s\n", out, s.nx, s.ny, s.nz, vs_mm, s.nw,
		       s.nf, weave, (double)s.angle_deg, (double)s.noise, (double)s.blur,
		       no_orient ? ", no orientation" : ", with orientation");
	loom_scan_volume_release(&v);
	free(lab);
	free(wbuf);
	return 0;
}

/* ---- build ------------------------------------------------------------------ */

static const char help_build[] =
	"usage: loom exemplar build SCAN [--orientation ORIENT] --warps N --wefts N\n"
	"                           [--raw-dims X,Y,Z --raw-type u8|u16|f32]\n"
	"                           [--voxel-mm S] [--block B1xB2] [--depth B3]\n"
	"                           [--name NAME] [--weave-name S] [--threads N]\n"
	"                           [--json] [--quiet] --db DB\n"
	"\n"
	"Turn a scan of a simple weave into one exemplar (paper section 6) and\n"
	"append it to the database DB, creating DB if it does not exist.  Steps:\n"
	"denoise, orientation (estimated from the density when no ORIENT is\n"
	"given), endpoints, tracking, weave by linking integrals, segmentation,\n"
	"alignment, registration, crop (docs/scan.md).  Prints what each step\n"
	"found; fails (exit 1) with the step's message when the data do not\n"
	"support it (too noisy, another number of yarns than given).\n"
	"\n"
	"input (by extension):\n"
	"  SCAN.vol            Mitsuba grid, 1 channel (uint8, float16 or float32)\n"
	"  SCAN.nrrd / .nhdr   NRRD, 1 channel (integers scaled to 0..1)\n"
	"  anything else       raw: needs --raw-dims and --raw-type\n"
	"  --orientation F     fibre directions: .vol with 3 float channels or the\n"
	"                      quantized encoding 4, or a 3-vector NRRD\n"
	"  --raw-dims X,Y,Z    voxels of a raw scan (x fastest)\n"
	"  --raw-type T        u8 (/255), u16 (/65535) or f32 (as is)\n"
	"  --voxel-mm S        voxel edge in mm (default: the file's spacing for\n"
	"                      NRRD and .vol, else 0.005); float densities outside\n"
	"                      [0,1] are rescaled by their range (a warning)\n"
	"\n"
	"pipeline:\n"
	"  --warps N, --wefts N  yarns in the scan, cut border yarns included\n"
	"                      (required)\n"
	"  --block B1xB2       crossing size in voxels (default: DB's when it\n"
	"                      exists, else the measured yarn spacing)\n"
	"  --depth B3          output depth, centred on the cloth (default: DB's,\n"
	"                      else the scan's nz)\n"
	"  --threads N         worker threads (default 2)\n"
	"\n"
	"output:\n"
	"  --db DB             database to append to (created if absent)\n"
	"  --name NAME         exemplar name (default: the scan's file name)\n"
	"  --weave-name S      weave recorded with it (default \"\")\n"
	"  --json              JSON: weave (one 0/1 string per pick of the crop),\n"
	"                      rotation_degrees, crop [x0, y0, w, h] (aligned frame),\n"
	"                      warps, wefts (tracked), crossings, block, ...\n"
	"  --quiet             no report, no progress\n";

/* Read a 1- or 3-channel volume into floats (malloc'ed, nx*ny*nz*ch). */
static float *read_volume(const char *prog, const char *path, uint32_t want_ch,
                          const uint32_t *raw_dims, int raw_type, uint32_t dims[3],
                          double *spacing, loom_diag *diag)
{
	float *buf = NULL;
	size_t n;

	*spacing = 0;
	if (ends_with(path, ".vol")) {
		loom_vol_reader *r;
		const loom_vol_header *h;
		if (loom_vol_open(path, &r, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		h = loom_vol_reader_header(r);
		if (h->channels != want_ch) {
			loom_vol_close(r);
			cli_fail(prog, "%s: %u channels per voxel, expected %u (%s)", path,
			         h->channels, want_ch, want_ch == 1 ? "density" : "orientation");
		}
		dims[0] = h->xres;
		dims[1] = h->yres;
		dims[2] = h->zres;
		if (h->xres > 1)
			*spacing = (h->bbox_max[0] - h->bbox_min[0]) / (h->xres - 1);
		n = (size_t)dims[0] * dims[1] * dims[2] * want_ch;
		buf = malloc(n * sizeof *buf);
		if (!buf || loom_vol_read_box(r, 0, 0, 0, dims[0], dims[1], dims[2], buf, diag)) {
			loom_vol_close(r);
			cli_fail(prog, "%s", buf ? diag->message : "out of memory");
		}
		loom_vol_close(r);
		return buf;
	}
	if (ends_with(path, ".nrrd") || ends_with(path, ".nhdr")) {
		loom_nrrd_info info;
		loom_raw_reader *rr;
		loom_volbuf *vb = NULL;
		int rc = loom_nrrd_open(path, &info, &rr, diag);
		if (rc == LOOM_EUNSUPPORTED) { /* gzip or ascii: read whole */
			rc = loom_nrrd_read(path, SIZE_MAX, &info, &vb, diag);
			rr = NULL;
		}
		if (rc)
			cli_fail(prog, "%s", diag->message);
		if (info.channels != want_ch) {
			loom_raw_close(rr);
			loom_volbuf_free(vb);
			cli_fail(prog, "%s: %u channels per voxel, expected %u", path,
			         info.channels, want_ch);
		}
		dims[0] = info.nx;
		dims[1] = info.ny;
		dims[2] = info.nz;
		*spacing = info.spacing[0];
		n = (size_t)dims[0] * dims[1] * dims[2] * want_ch;
		if (vb) {
			buf = vb->data;
			vb->data = NULL;
			loom_volbuf_free(vb);
		} else {
			buf = malloc(n * sizeof *buf);
			if (!buf || loom_raw_read_slices(rr, 0, dims[2], buf, diag)) {
				loom_raw_close(rr);
				cli_fail(prog, "%s", buf ? diag->message : "out of memory");
			}
			loom_raw_close(rr);
		}
		if (info.type == LOOM_SCALAR_U8 || info.type == LOOM_SCALAR_U16) {
			float k = info.type == LOOM_SCALAR_U8 ? 1.0f / 255 : 1.0f / 65535;
			for (size_t i = 0; i < n; i++)
				buf[i] *= k;
		}
		return buf;
	}
	if (!raw_dims)
		cli_fail(prog, "%s: not .vol or .nrrd; give --raw-dims X,Y,Z and --raw-type "
		         "for a raw volume", path);
	{
		loom_raw_params p = LOOM_RAW_PARAMS_INIT;
		loom_raw_reader *rr;
		p.nx = raw_dims[0];
		p.ny = raw_dims[1];
		p.nz = raw_dims[2];
		p.channels = want_ch;
		p.type = raw_type;
		p.flags = LOOM_RAW_NORMALIZE;
		if (loom_raw_open(path, &p, &rr, diag))
			cli_fail(prog, "%s", diag->message);
		memcpy(dims, raw_dims, 3 * sizeof *dims);
		n = (size_t)dims[0] * dims[1] * dims[2] * want_ch;
		buf = malloc(n * sizeof *buf);
		if (!buf || loom_raw_read_slices(rr, 0, dims[2], buf, diag)) {
			loom_raw_close(rr);
			cli_fail(prog, "%s", buf ? diag->message : "out of memory");
		}
		loom_raw_close(rr);
	}
	return buf;
}

typedef struct build_progress {
	int quiet;
	double t0;
} build_progress;

static void build_progress_cb(void *user, int step, double fraction)
{
	build_progress *bp = user;
	if (bp->quiet || fraction < 1)
		return;
	if (isatty(2))
		fprintf(stderr, "\rloom exemplar build: %-13s done (%.1f s)\n",
		        loom_scan_step_name(step), cli_now() - bp->t0);
}

static void weave_rows(json_w *w, const char *key, const uint8_t *W, uint32_t rows,
                       uint32_t cols)
{
	char row[LOOM_SCAN_MAX_YARNS + 2];
	jw_arr(w, key);
	for (uint32_t i = 0; i < rows; i++) {
		for (uint32_t j = 0; j < cols; j++)
			row[j] = W[(size_t)i * cols + j] ? '1' : '0';
		row[cols] = 0;
		jw_str(w, NULL, row);
	}
	jw_close(w);
}

static int sub_build(int argc, char **argv)
{
	const char *prog = "loom exemplar build";
	const char *scan = NULL, *orient_p = NULL, *dims_s = NULL, *type_s = NULL;
	const char *vs_s = NULL, *warps_s = NULL, *wefts_s = NULL, *block_s = NULL;
	const char *depth_s = NULL, *name = NULL, *wname = "", *db = NULL, *threads_s = NULL;
	int json = 0, quiet = 0, raw_type = LOOM_SCALAR_U8, rc, appended = 0;
	uint32_t raw_dims[3], dims[3], odims[3];
	double sp = 0, osp, voxel_mm;
	char namebuf[32];
	loom_scan_params p;
	loom_scan_db_params dp;
	loom_scan_volume v;
	loom_scan_result *r = NULL;
	loom_diag diag;
	build_progress bp;
	struct stat st;
	cli_args a;
	size_t n;

	cli_init(&a, argc, argv, prog, help_build);
	while (cli_more(&a)) {
		const char *s;
		if (cli_value(&a, "--orientation", &orient_p) ||
		    cli_value(&a, "--raw-dims", &dims_s) || cli_value(&a, "--raw-type", &type_s) ||
		    cli_value(&a, "--voxel-mm", &vs_s) || cli_value(&a, "--warps", &warps_s) ||
		    cli_value(&a, "--wefts", &wefts_s) || cli_value(&a, "--block", &block_s) ||
		    cli_value(&a, "--depth", &depth_s) || cli_value(&a, "--name", &name) ||
		    cli_value(&a, "--weave-name", &wname) || cli_value(&a, "--db", &db) ||
		    cli_value(&a, "--threads", &threads_s))
			continue;
		if (cli_flag(&a, "--json")) {
			json = 1;
			continue;
		}
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if (!scan && (s = cli_positional(&a)) != NULL) {
			scan = s;
			continue;
		}
		cli_unknown(&a);
	}
	if (!scan)
		cli_usage(&a, "missing SCAN");
	if (!db)
		cli_usage(&a, "missing --db DB");
	loom_scan_params_init(&p);
	if (!warps_s || !wefts_s)
		cli_usage(&a, "--warps N and --wefts N are required (yarns in the scan)");
	if (cli_parse_u32(warps_s, &p.n_warps) || p.n_warps < 2 ||
	    p.n_warps > LOOM_SCAN_MAX_YARNS)
		cli_usage(&a, "bad --warps '%s' (expected 2..%d)", warps_s, LOOM_SCAN_MAX_YARNS);
	if (cli_parse_u32(wefts_s, &p.n_wefts) || p.n_wefts < 2 ||
	    p.n_wefts > LOOM_SCAN_MAX_YARNS)
		cli_usage(&a, "bad --wefts '%s' (expected 2..%d)", wefts_s, LOOM_SCAN_MAX_YARNS);
	if (block_s && (cli_parse_size2(block_s, &p.block_x, &p.block_y) || !p.block_x ||
	                !p.block_y || p.block_x > 4096 || p.block_y > 4096))
		cli_usage(&a, "bad --block '%s' (expected B1xB2)", block_s);
	if (depth_s && (cli_parse_u32(depth_s, &p.block_z) || !p.block_z ||
	                p.block_z > 4096))
		cli_usage(&a, "bad --depth '%s' (expected 1..4096)", depth_s);
	if (threads_s && (cli_parse_u32(threads_s, &p.threads) || !p.threads ||
	                  p.threads > 64))
		cli_usage(&a, "bad --threads '%s' (expected 1..64)", threads_s);
	if (dims_s) {
		char buf[96];
		snprintf(buf, sizeof buf, "%s", dims_s);
		if (parse_size3(buf, raw_dims) || !raw_dims[0] || !raw_dims[1] || !raw_dims[2])
			cli_usage(&a, "bad --raw-dims '%s' (expected X,Y,Z)", dims_s);
	}
	if (type_s) {
		if (strcmp(type_s, "u8") == 0)
			raw_type = LOOM_SCALAR_U8;
		else if (strcmp(type_s, "u16") == 0)
			raw_type = LOOM_SCALAR_U16;
		else if (strcmp(type_s, "f32") == 0)
			raw_type = LOOM_SCALAR_F32;
		else
			cli_usage(&a, "bad --raw-type '%s' (expected u8, u16 or f32)", type_s);
	}
	voxel_mm = 0;
	if (vs_s && (cli_parse_double(vs_s, &voxel_mm) || !(voxel_mm > 0) || voxel_mm > 100))
		cli_usage(&a, "bad --voxel-mm '%s'", vs_s);
	if (!name) {
		const char *b = strrchr(scan, '/'), *dot;
		size_t len;
		b = b ? b + 1 : scan;
		dot = strchr(b, '.');
		len = dot ? (size_t)(dot - b) : strlen(b);
		if (len > 31)
			len = 31;
		memcpy(namebuf, b, len);
		namebuf[len] = 0;
		name = namebuf[0] ? namebuf : "scan";
	}
	if (!name[0] || strlen(name) > 31)
		cli_usage(&a, "bad --name '%s' (1..31 bytes)", name);
	cli_diag_init(&diag, &quiet);
	/* the database's block, when it exists */
	if (stat(db, &st) == 0) {
		loom_db *d;
		loom_db_info info;
		uint32_t k;
		if (loom_db_open(db, &d, &diag) != LOOM_OK)
			cli_fail(prog, "%s", diag.message);
		loom_db_get_info(d, &info);
		if (loom_db_find_exemplar(d, name, &k) == LOOM_OK) {
			loom_db_close(d);
			cli_fail(prog, "%s: exemplar %u is already named '%s'; choose another "
			         "--name", db, k, name);
		}
		loom_db_close(d);
		if (!block_s) {
			p.block_x = info.block[0];
			p.block_y = info.block[1];
		}
		if (!depth_s)
			p.block_z = info.block[2];
	}
	memset(&v, 0, sizeof v);
	v.density = read_volume(prog, scan, 1, dims_s ? raw_dims : NULL, raw_type, dims,
	                        &sp, &diag);
	v.nx = dims[0];
	v.ny = dims[1];
	v.nz = dims[2];
	n = (size_t)v.nx * v.ny * v.nz;
	{
		float lo = v.density[0], hi = v.density[0];
		for (size_t i = 1; i < n; i++) {
			lo = v.density[i] < lo ? v.density[i] : lo;
			hi = v.density[i] > hi ? v.density[i] : hi;
		}
		if (lo < 0 || hi > 1) {
			float k = hi > lo ? 1.0f / (hi - lo) : 0;
			for (size_t i = 0; i < n; i++)
				v.density[i] = (v.density[i] - lo) * k;
			if (!quiet)
				fprintf(stderr, "loom: warning: %s: density range [%g, %g] rescaled to "
				        "[0, 1]\n", scan, (double)lo, (double)hi);
		}
	}
	if (orient_p) {
		v.orient = read_volume(prog, orient_p, 3, dims_s ? raw_dims : NULL,
		                       LOOM_SCALAR_F32, odims, &osp, &diag);
		if (odims[0] != v.nx || odims[1] != v.ny || odims[2] != v.nz)
			cli_fail(prog, "%s is %ux%ux%u, the scan %ux%ux%u", orient_p, odims[0],
			         odims[1], odims[2], v.nx, v.ny, v.nz);
	}
	if (!(voxel_mm > 0))
		voxel_mm = sp > 0 && sp != 1 && sp < 100 ? sp : 0.005;
	bp.quiet = quiet;
	bp.t0 = cli_now();
	p.progress = build_progress_cb;
	p.progress_user = &bp;
	rc = loom_scan_build(&v, &p, &r, &diag);
	if (rc) {
		loom_scan_volume_release(&v);
		cli_fail(prog, "%s: %s", scan, diag.message);
	}
	loom_scan_volume_release(&v);
	loom_scan_db_params_init(&dp);
	dp.name = name;
	dp.weave_name = wname;
	dp.voxel_size_um = (float)(voxel_mm * 1000);
	rc = loom_scan_write_db(r, db, &dp, &appended, &diag);
	if (rc) {
		loom_scan_result_free(r);
		cli_fail(prog, "%s", diag.message);
	}
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "scan", scan);
		jw_str(&w, "db", db);
		jw_str(&w, "name", name);
		jw_bool(&w, "appended", appended);
		weave_rows(&w, "weave", r->weave, r->rows, r->cols);
		jw_num(&w, "rotation_degrees", r->rotation_degrees);
		jw_arr(&w, "crop");
		for (int k = 0; k < 4; k++)
			jw_int(&w, NULL, r->grid.crop[k]);
		jw_close(&w);
		jw_uint(&w, "warps", r->warps_tracked);
		jw_uint(&w, "wefts", r->wefts_tracked);
		jw_uint(&w, "first_warp", r->grid.first_warp);
		jw_uint(&w, "first_weft", r->grid.first_weft);
		jw_arr(&w, "crossings");
		jw_uint(&w, NULL, r->rows);
		jw_uint(&w, NULL, r->cols);
		jw_close(&w);
		jw_arr(&w, "block");
		jw_uint(&w, NULL, r->b1);
		jw_uint(&w, NULL, r->b2);
		jw_uint(&w, NULL, r->b3);
		jw_close(&w);
		jw_int(&w, "z0", r->z0);
		weave_rows(&w, "full_weave", r->full_weave, r->full_rows, r->full_cols);
		jw_num(&w, "voxel_mm", voxel_mm);
		jw_num(&w, "noise_before", r->noise_before);
		jw_num(&w, "noise_after", r->noise_after);
		jw_num(&w, "threshold", r->threshold);
		jw_bool(&w, "orientation_estimated", r->orientation_estimated);
		jw_num(&w, "registration_score", r->grid.score);
		jw_obj(&w, "seconds");
		for (int k = 0; k < LOOM_SCAN_STEP_COUNT_; k++)
			jw_num(&w, loom_scan_step_name(k), r->seconds[k]);
		jw_close(&w);
		jw_end(&w);
	} else if (!quiet) {
		double tot = 0;
		for (int k = 0; k < LOOM_SCAN_STEP_COUNT_; k++)
			tot += r->seconds[k];
		printf("scan %s: %ux%ux%u voxels of %g mm\n", scan, dims[0], dims[1], dims[2],
		       voxel_mm);
		printf("  denoise:      noise %.4f -> %.4f, threshold %.3f\n",
		       (double)r->noise_before, (double)r->noise_after, (double)r->threshold);
		if (r->orientation_estimated)
			printf("  orientation:  estimated for %llu voxels, mean coherence %.3f\n",
			       (unsigned long long)r->orient.voxels, (double)r->orient.coherence);
		else
			printf("  orientation:  given (%s)\n", orient_p);
		printf("  endpoints:    %u warps on slice y = %u (spacing %.1f), %u wefts on "
		       "slice x = %u (spacing %.1f)\n", r->warp_ends.k, r->warp_ends.slice,
		       (double)r->warp_ends.spacing, r->weft_ends.k, r->weft_ends.slice,
		       (double)r->weft_ends.spacing);
		printf("  tracking:     %u warps, %u wefts tracked (scale %.3f)\n",
		       r->warps_tracked, r->wefts_tracked, (double)r->scale);
		printf("  weave:        %ux%u crossings of all tracked yarns:", r->full_rows,
		       r->full_cols);
		for (uint32_t i = 0; i < r->full_rows; i++) {
			printf(" ");
			for (uint32_t j = 0; j < r->full_cols; j++)
				putchar(r->full_weave[(size_t)i * r->full_cols + j] ? '1' : '0');
		}
		printf("\n  alignment:    rotation %.3f degrees\n", r->rotation_degrees);
		printf("  registration: crop %d %d %d %d (aligned frame), %ux%u complete "
		       "crossings from warp %u, weft %u, block %ux%ux%u, score %.3f\n",
		       r->grid.crop[0], r->grid.crop[1], r->grid.crop[2], r->grid.crop[3],
		       r->rows, r->cols, r->grid.first_warp, r->grid.first_weft, r->b1, r->b2,
		       r->b3, r->grid.score);
		printf("  pattern:     ");
		for (uint32_t i = 0; i < r->rows; i++) {
			printf(" ");
			for (uint32_t j = 0; j < r->cols; j++)
				putchar(r->weave[(size_t)i * r->cols + j] ? '1' : '0');
		}
		printf("\n%s exemplar '%s' (%ux%ux%u voxels) %s %s in %.2f s\n",
		       appended ? "appended" : "wrote", name, r->volume.nx, r->volume.ny,
		       r->volume.nz, appended ? "to" : "into new database", db, tot);
	}
	loom_scan_result_free(r);
	return 0;
}

/* ---- shared: open the database of info/verify/export ---------------------- */

static loom_db *open_db(const char *prog, const char *pos, const char *opt)
{
	const char *path = pos ? pos : cli_db_require(opt, prog);
	loom_diag diag;
	loom_db *db;

	cli_diag_init(&diag, NULL);
	if (loom_db_open(path, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	return db;
}

/* ---- info ---------------------------------------------------------------- */

static void weave_row(const loom_db_exemplar_info *e, uint32_t r, char *buf)
{
	for (uint32_t c = 0; c < e->cols; c++)
		buf[c] = e->weave[(size_t)r * e->cols + c] ? '1' : '0';
	buf[e->cols] = 0;
}

static int sub_info(int argc, char **argv)
{
	const char *prog = "loom exemplar info", *dbopt = NULL, *pos = NULL, *s;
	int json = 0;
	loom_db *db;
	loom_db_info info;
	char hs[32], row[1100];
	cli_args a;

	cli_init(&a, argc, argv, prog, help_info);
	while (cli_more(&a)) {
		if (cli_value(&a, "--db", &dbopt))
			continue;
		if (cli_flag(&a, "--json")) {
			json = 1;
			continue;
		}
		if (!pos && (s = cli_positional(&a)) != NULL) {
			pos = s;
			continue;
		}
		cli_unknown(&a);
	}
	db = open_db(prog, pos, dbopt);
	loom_db_get_info(db, &info);
	snprintf(hs, sizeof hs, "%016llx", (unsigned long long)info.content_hash);
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "path", pos ? pos : cli_db_path(dbopt));
		jw_uint(&w, "version", info.version);
		jw_str(&w, "content_hash", hs);
		jw_arr(&w, "block");
		for (int k = 0; k < 3; k++)
			jw_uint(&w, NULL, info.block[k]);
		jw_close(&w);
		jw_arr(&w, "brick");
		for (int k = 0; k < 3; k++)
			jw_uint(&w, NULL, info.brick[k]);
		jw_close(&w);
		jw_num(&w, "voxel_size_um", info.voxel_size_um);
		jw_uint(&w, "seed", info.seed);
		jw_uint(&w, "file_bytes", info.file_bytes);
		jw_uint(&w, "raw_bytes", info.raw_bytes);
		jw_uint(&w, "compressed_bytes", info.stored_bytes);
		jw_num(&w, "ratio", info.stored_bytes ?
		               (double)info.raw_bytes / (double)info.stored_bytes : 0.0);
		jw_uint(&w, "bricks", info.n_bricks);
		jw_uint(&w, "empty_bricks", info.n_empty_bricks);
		jw_uint(&w, "raw_bricks", info.n_raw_bricks);
		jw_arr(&w, "exemplars");
		for (uint32_t k = 0; k < info.n_exemplars; k++) {
			loom_db_exemplar_info e;
			loom_db_exemplar(db, k, &e);
			jw_obj(&w, NULL);
			jw_uint(&w, "index", k);
			jw_str(&w, "name", e.name);
			jw_str(&w, "weave_name", e.weave_name);
			jw_arr(&w, "weave");
			for (uint32_t r = 0; r < e.rows; r++) {
				weave_row(&e, r, row);
				jw_str(&w, NULL, row);
			}
			jw_close(&w);
			jw_arr(&w, "crossings");
			jw_uint(&w, NULL, e.rows);
			jw_uint(&w, NULL, e.cols);
			jw_close(&w);
			jw_arr(&w, "block");
			for (int i = 0; i < 3; i++)
				jw_uint(&w, NULL, e.block[i]);
			jw_close(&w);
			jw_arr(&w, "size");
			for (int i = 0; i < 3; i++)
				jw_uint(&w, NULL, e.size[i]);
			jw_close(&w);
			jw_num(&w, "voxel_size_um", e.voxel_size_um);
			jw_uint(&w, "voxels", (unsigned long long)e.size[0] * e.size[1] * e.size[2]);
			jw_uint(&w, "raw_bytes", e.raw_bytes);
			jw_uint(&w, "compressed_bytes", e.stored_bytes);
			jw_num(&w, "ratio", e.stored_bytes ?
			               (double)e.raw_bytes / (double)e.stored_bytes : 0.0);
			jw_uint(&w, "yarn_labels", e.n_yarns);
			jw_arr(&w, "symmetries");
			for (uint32_t i = 0; i < e.n_symmetries; i++) {
				jw_arr(&w, NULL);
				jw_uint(&w, NULL, e.symmetries[2 * i]);
				jw_uint(&w, NULL, e.symmetries[2 * i + 1]);
				jw_close(&w);
			}
			jw_close(&w);
			jw_close(&w);
		}
		jw_close(&w);
		jw_end(&w);
	} else {
		printf("database %s\n", pos ? pos : cli_db_path(dbopt));
		printf("  format version %u, content hash %s, %llu bytes\n", info.version,
		       hs, (unsigned long long)info.file_bytes);
		printf("  block %ux%ux%u voxels of %g um, brick %ux%ux%u, %llu bricks "
		       "(%llu empty, %llu stored raw)\n", info.block[0], info.block[1],
		       info.block[2], (double)info.voxel_size_um, info.brick[0],
		       info.brick[1], info.brick[2], (unsigned long long)info.n_bricks,
		       (unsigned long long)info.n_empty_bricks,
		       (unsigned long long)info.n_raw_bricks);
		printf("\n  %-3s %-16s %-14s %-9s %12s %12s %12s %7s  %s\n", "#", "name",
		       "weave", "crossings", "voxels", "raw bytes", "compressed", "ratio",
		       "weave rows (pick 0 first)");
		for (uint32_t k = 0; k < info.n_exemplars; k++) {
			loom_db_exemplar_info e;
			char cr[24];
			loom_db_exemplar(db, k, &e);
			snprintf(cr, sizeof cr, "%ux%u", e.rows, e.cols);
			printf("  %-3u %-16s %-14s %-9s %12llu %12llu %12llu %6.1fx  ", k, e.name,
			       e.weave_name[0] ? e.weave_name : "-", cr,
			       (unsigned long long)e.size[0] * e.size[1] * e.size[2],
			       (unsigned long long)e.raw_bytes,
			       (unsigned long long)e.stored_bytes,
			       e.stored_bytes ? (double)e.raw_bytes / (double)e.stored_bytes : 0.0);
			for (uint32_t r = 0; r < e.rows; r++) {
				weave_row(&e, r, row);
				printf("%s%s", r ? " " : "", row);
			}
			printf("\n");
		}
		printf("\n  total %llu raw bytes in %llu (%.1fx)\n",
		       (unsigned long long)info.raw_bytes,
		       (unsigned long long)info.stored_bytes,
		       info.stored_bytes ? (double)info.raw_bytes / (double)info.stored_bytes
		                         : 0.0);
	}
	loom_db_close(db);
	return 0;
}

/* ---- verify -------------------------------------------------------------- */

static void verify_progress(void *user, uint64_t done, uint64_t total)
{
	(void)user;
	fprintf(stderr, "\rloom exemplar verify: %llu/%llu bricks", (unsigned long long)done,
	        (unsigned long long)total);
	if (done == total)
		fputc('\n', stderr);
}

static int sub_verify(int argc, char **argv)
{
	const char *prog = "loom exemplar verify", *dbopt = NULL, *pos = NULL, *s;
	int quiet = 0, rc;
	loom_db *db;
	loom_db_info info;
	loom_diag diag;
	cli_args a;

	cli_init(&a, argc, argv, prog, help_verify);
	while (cli_more(&a)) {
		if (cli_value(&a, "--db", &dbopt))
			continue;
		if (cli_flag(&a, "--quiet")) {
			quiet = 1;
			continue;
		}
		if (!pos && (s = cli_positional(&a)) != NULL) {
			pos = s;
			continue;
		}
		cli_unknown(&a);
	}
	db = open_db(prog, pos, dbopt);
	cli_diag_init(&diag, &quiet);
	rc = loom_db_verify(db, !quiet && isatty(2) ? verify_progress : NULL, NULL, &diag);
	loom_db_get_info(db, &info);
	loom_db_close(db);
	if (rc)
		cli_fail(prog, "%s", diag.message);
	if (!quiet)
		printf("%s: ok (%llu bricks, %llu empty, content hash %016llx)\n",
		       pos ? pos : cli_db_path(dbopt), (unsigned long long)info.n_bricks,
		       (unsigned long long)info.n_empty_bricks,
		       (unsigned long long)info.content_hash);
	return 0;
}

/* ---- export -------------------------------------------------------------- */

static int sub_export(int argc, char **argv)
{
	const char *prog = "loom exemplar export", *dbopt = NULL, *pos = NULL, *s;
	const char *ex = NULL, *out = NULL, *ch = "density";
	int detached = 0, channel;
	uint32_t k;
	loom_db *db;
	loom_diag diag;
	cli_args a;

	cli_init(&a, argc, argv, prog, help_export);
	while (cli_more(&a)) {
		if (cli_value(&a, "--db", &dbopt) || cli_value(&a, "--exemplar", &ex) ||
		    cli_value(&a, "-o", &out) || cli_value(&a, "--output", &out) ||
		    cli_value(&a, "--channel", &ch))
			continue;
		if (cli_flag(&a, "--detached")) {
			detached = 1;
			continue;
		}
		if (!pos && (s = cli_positional(&a)) != NULL) {
			pos = s;
			continue;
		}
		cli_unknown(&a);
	}
	if (!ex)
		cli_usage(&a, "missing --exemplar K");
	if (!out)
		cli_usage(&a, "missing -o FILE");
	if (loom_db_channel_parse(ch, &channel) != LOOM_OK)
		cli_usage(&a, "unknown channel '%s' (expected density, label, kind, "
		          "orientation or orient-code)", ch);
	db = open_db(prog, pos, dbopt);
	if (loom_db_find_exemplar(db, ex, &k) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "no exemplar '%s' (see loom exemplar info)", ex);
	}
	cli_diag_init(&diag, NULL);
	if (loom_db_export_nrrd(db, k, channel, out, detached, &diag) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	loom_db_close(db);
	return 0;
}

int cmd_exemplar(int argc, char **argv)
{
	const char *sub;

	if (argc < 2) {
		fputs(help_main, stderr);
		return EXIT_USAGE;
	}
	sub = argv[1];
	if (strcmp(sub, "--help") == 0 || strcmp(sub, "-h") == 0 ||
	    strcmp(sub, "help") == 0) {
		fputs(help_main, stdout);
		return 0;
	}
	if (strcmp(sub, "generate") == 0) {
		for (int i = 2; i < argc; i++)
			if (strcmp(argv[i], "--scan") == 0)
				return sub_generate_scan(argc - 1, argv + 1);
		return sub_generate(argc - 1, argv + 1);
	}
	if (strcmp(sub, "build") == 0)
		return sub_build(argc - 1, argv + 1);
	if (strcmp(sub, "info") == 0)
		return sub_info(argc - 1, argv + 1);
	if (strcmp(sub, "verify") == 0)
		return sub_verify(argc - 1, argv + 1);
	if (strcmp(sub, "export") == 0)
		return sub_export(argc - 1, argv + 1);
	fprintf(stderr, "loom exemplar: unknown command '%s'\nTry 'loom exemplar "
	        "--help'.\n", sub);
	return EXIT_USAGE;
}
