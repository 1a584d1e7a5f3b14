/*
 * tools/loom/exemplar_scan.c - `loom exemplar generate --scan`: what a
 * micro-CT scanner would give for a woven sheet (loom_scan_sheet_make),
 * written as .vol or NRRD, for testing `loom exemplar build`
 * (docs/scan.md).
 */
#include "cli.h"
#include "exemplar.h"
#include "opts.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

static const char usage_scan[] =
	"loom exemplar generate --scan [--preset small|paper] [--weave NAME]\n"
	"                       [--crossings WxF] [--rotate DEG] [--offset X,Y]\n"
	"                       [--noise S] [--blur S] [--no-orientation]\n"
	"                       [--density u8|f32] [--orient f32|qdir]\n"
	"                       [--seed N] [--threads N] [--quiet]\n"
	"                       -o SCAN.vol|SCAN.nrrd [--truth TRUTH.json]\n";

static const char about_scan[] =
	"Write what a micro-CT scanner would give for a woven sheet, for testing\n"
	"`loom exemplar build`: yarns cut at the borders, the sheet turned about z\n"
	"and offset from the volume's corner, blurred and noisy density, and\n"
	"(unless --no-orientation) the fibre orientation.  Deterministic.\n";

static const opt_choice density_types[] = {{"u8", 1}, {"f32", 0}, {NULL, 0}};
static const opt_choice orient_types[] = {{"f32", 0}, {"qdir", 1}, {NULL, 0}};

/* --preset: a sheet loom_scan_sheet_preset knows. */
static const char *opt_preset(const char *text, void *dest)
{
	loom_scan_sheet s;

	*(const char **)dest = text;
	return loom_scan_sheet_preset(text, &s) == LOOM_OK ? NULL : "small, paper or paper:N";
}

/* --weave: a weave name with a repeat (the reason in the message). */
static const char *opt_weave(const char *text, void *dest)
{
	static char what[LOOM_DIAG_MSG_MAX + 32];
	loom_weave_params wp;
	loom_diag diag = {0};
	uint32_t r, c;

	*(const char **)dest = text;
	if (loom_weave_parse(text, &wp, &diag) != LOOM_OK ||
	    loom_weave_repeat(&wp, &r, &c, &diag) != LOOM_OK) {
		snprintf(what, sizeof what, "a weave name (%s)", diag.message);
		return what;
	}
	return NULL;
}

/* --offset X,Y: two numbers (their range depends on the preset). */
struct offset {
	double xy[2];
	const char *text;
};

static const char *opt_offset(const char *text, void *dest)
{
	struct offset *o = dest;
	double *xy = o->xy;
	char buf[64], *c;

	o->text = text;
	if (strlen(text) >= sizeof buf)
		return "X,Y";
	strcpy(buf, text);
	c = strchr(buf, ',');
	if (!c)
		return "X,Y";
	*c++ = 0;
	if (cli_parse_double(buf, &xy[0]) || cli_parse_double(c, &xy[1]))
		return "X,Y (two numbers)";
	return NULL;
}

int exemplar_generate_scan(int argc, char **argv)
{
	const char *prog = "loom exemplar generate --scan";
	const char *out = NULL, *preset = "small", *weave = "twill:2/3", *truth = NULL;
	int quiet = 0, no_orient = 0, pure = 0, scan = 0, dens_u8 = 1, or_qdir = 0, nrrd, rc;
	uint32_t threads = 2, cross[2];
	uint64_t seed = 0;
	double rot = 0, noise = 0, blur = 0;
	struct offset off = {{0, 0}, NULL};
	loom_scan_sheet s;
	loom_weave_params wp;
	uint32_t rr, rc_;
	uint8_t *wbuf = NULL, *lab = NULL;
	loom_scan_volume v;
	loom_diag diag;
	double vs_mm;
	opt_entry opts[] = {
		OPT_FLAG(0, "scan", &scan, "this form of generate: a scan-like volume"),
		OPT_OUTPUT(&out, "F", "density: F.vol (Mitsuba grid) or F.nrrd; orientation "
		           "goes to F-orient.vol / F-orient.nrrd"),
		OPT_CALLBACK(0, "preset", &preset, "NAME", opt_preset, "small (default: "
		             "160x160x40 voxels, 7 warps x 9 wefts 24 x 18 voxels apart, 24 um "
		             "voxels) or paper (1000 x 1000 x 300, spacing 115 x 70 voxels of 5 "
		             "um); paper:N scales the paper sheet to N x N x 0.3N"),
		OPT_CALLBACK(0, "weave", &weave, "NAME", opt_weave,
		             "loom pattern name (default twill:2/3)"),
		OPT_SIZE2(0, "crossings", cross, "WxF", 3, LOOM_SCAN_MAX_YARNS, "warps x wefts "
		          "of the sheet, %r (default: the preset's); the volume grows or "
		          "shrinks to hold them"),
		OPT_DOUBLE(0, "rotate", &rot, "DEG", "[]", -20, 20, "degrees",
		           "rotation about z, counter-clockwise, %r (default 3)"),
		OPT_CALLBACK(0, "offset", &off, "X,Y", opt_offset, "aligned position of warp 0 "
		             "and weft 0 (voxels, -1..4 yarn spacings; default the preset's)"),
		OPT_DOUBLE(0, "noise", &noise, "S", "[]", 0, 1, NULL,
		           "Gaussian noise sigma on density, %r (default 0.08)"),
		OPT_DOUBLE(0, "blur", &blur, "S", "[]", 0, 8, "voxels",
		           "Gaussian blur sigma in voxels, %r (default 0.8)"),
		OPT_FLAG(0, "no-orientation", &no_orient, "write the density only"),
		OPT_ENUM(0, "density", &dens_u8, "T", density_types,
		         "u8 (default) or f32 samples"),
		OPT_ENUM(0, "orient", &or_qdir, "E", orient_types,
		         "f32 (3 floats, default) or qdir (.vol encoding 4)"),
		OPT_SEED(&seed, "N", "random seed (default 7)"),
		OPT_STRING(0, "truth", &truth, "F.json", "ground truth for tests: weave of the "
		           "complete crossings (one 0/1 string per pick), rotation_degrees, crop "
		           "[x0, y0, width, height] (aligned frame, voxels), warps, wefts, ...; "
		           "labels (0 empty, 1..W warps by x, W+1.. wefts by y) to "
		           "F-labels.nrrd (uchar)"),
		OPT_FLAG(0, "pure-noise", &pure,
		         "uniform noise instead of a sheet (bad-scan tests)"),
		OPT_THREADS(&threads, 64, "worker threads (default 2; %r)"),
		OPT_QUIET(&quiet, "no summary"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage_scan, .about = about_scan,
	              .opts = opts};

	opts_parse(&c, argc, argv);
	if (!out)
		opts_usage(&c, "missing -o SCAN.vol|SCAN.nrrd");
	nrrd = exemplar_ends_with(out, ".nrrd");
	if (!nrrd && !exemplar_ends_with(out, ".vol"))
		opts_usage(&c, "output '%s' must end in .vol or .nrrd", out);
	if (nrrd && or_qdir)
		opts_usage(&c, "--orient qdir needs a .vol output");
	cli_check_output(prog, out);
	if (loom_scan_sheet_preset(preset, &s) != LOOM_OK)
		cli_fail(prog, "preset '%s': cannot set up the sheet", preset);
	vs_mm = strcmp(preset, "small") == 0 ? 0.024 : 0.005 * 1000.0 / s.nx;
	cli_diag_init(&diag, &quiet);
	if (loom_weave_parse(weave, &wp, &diag) != LOOM_OK ||
	    loom_weave_repeat(&wp, &rr, &rc_, &diag) != LOOM_OK)
		cli_fail(prog, "--weave '%s': %s", weave, diag.message);
	/* the options override the preset's sheet */
	if (opt_given(&c, &seed))
		s.seed = seed;
	if (opt_given(&c, &rot))
		s.angle_deg = (float)rot;
	if (opt_given(&c, &noise))
		s.noise = (float)noise;
	if (opt_given(&c, &blur))
		s.blur = (float)blur;
	if (opt_given(&c, &off)) {
		const double *xy = off.xy;
		if (xy[0] < -s.sx || xy[1] < -s.sy || xy[0] > 4 * s.sx || xy[1] > 4 * s.sy)
			opts_usage(&c, "--offset: expected X,Y within -1..4 yarn spacings "
			           "(%g..%g, %g..%g), got '%s'", -(double)s.sx, 4 * (double)s.sx,
			           -(double)s.sy, 4 * (double)s.sy, off.text);
		s.x0 = (float)xy[0];
		s.y0 = (float)xy[1];
	}
	if (opt_given(&c, cross)) {
		s.nw = cross[0];
		s.nf = cross[1];
		s.nx = (uint32_t)ceil(2 * s.x0 + (cross[0] - 1) * s.sx) + 4;
		s.ny = (uint32_t)ceil(2 * s.y0 + (cross[1] - 1) * s.sy) + 4;
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
	rc = nrrd ? write_nrrd(out, v.density, s.nx, s.ny, s.nz, 1, dens_u8,
	                       vs_mm, &diag)
	          : write_vol(out, v.density, s.nx, s.ny, s.nz, 1,
	                      dens_u8 ? LOOM_VOL_UINT8 : LOOM_VOL_FLOAT32, vs_mm,
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
		                      or_qdir ? LOOM_VOL_QDIR : LOOM_VOL_FLOAT32, vs_mm,
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