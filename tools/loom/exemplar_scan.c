/*
 * tools/loom/exemplar_scan.c - `loom exemplar generate --scan`: what a
 * micro-CT scanner would give for a woven sheet (loom_scan_sheet_make),
 * written as .vol or NRRD, for testing `loom exemplar build`
 * (docs/scan.md).
 */
#include "cli.h"
#include "exemplar.h"

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

int exemplar_generate_scan(int argc, char **argv)
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
	nrrd = exemplar_ends_with(out, ".nrrd");
	if (!nrrd && !exemplar_ends_with(out, ".vol"))
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