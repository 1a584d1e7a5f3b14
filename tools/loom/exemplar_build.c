/*
 * tools/loom/exemplar_build.c - `loom exemplar build SCAN`: turn a scan of
 * a simple weave into one exemplar appended to a database (paper section
 * 6; docs/scan.md).
 */
#include "cli.h"
#include "exemplar.h"
#include "opts.h"
#include "progress.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char usage_build[] =
	"loom exemplar build SCAN [--orientation ORIENT] --warps N --wefts N\n"
	"                    [--raw-dims X,Y,Z --raw-type u8|u16|f32]\n"
	"                    [--voxel-mm S] [--block B1xB2] [--depth B3]\n"
	"                    [--name NAME] [--weave-name S] [--threads N]\n"
	"                    [--format-version N] [--raw-density]\n"
	"                    [--json] [--quiet] --db DB\n";

static const char about_build[] =
	"Turn a scan of a simple weave into one exemplar (paper section 6) and\n"
	"append it to the database DB, creating DB if it does not exist.  Steps:\n"
	"denoise, orientation (estimated from the density when no ORIENT is\n"
	"given), endpoints, tracking, weave by linking integrals, segmentation,\n"
	"alignment, registration, crop (docs/scan.md).  Prints what each step\n"
	"found; fails (exit 1) with the step's message when the data do not\n"
	"support it (too noisy, another number of yarns than given).\n";

static const opt_choice raw_types[] = {
	{"u8", LOOM_SCALAR_U8}, {"u16", LOOM_SCALAR_U16}, {"f32", LOOM_SCALAR_F32},
	{NULL, 0}};

/* Read a 1- or 3-channel volume into floats (malloc'ed, nx*ny*nz*ch). */
static float *read_volume(const char *prog, const char *path, uint32_t want_ch,
                          const uint32_t *raw_dims, int raw_type, uint32_t dims[3],
                          double *spacing, loom_diag *diag)
{
	float *buf = NULL;
	size_t n;

	*spacing = 0;
	if (exemplar_ends_with(path, ".vol")) {
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
	if (exemplar_ends_with(path, ".nrrd") || exemplar_ends_with(path, ".nhdr")) {
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

int exemplar_build(int argc, char **argv)
{
	const char *prog = "loom exemplar build";
	const char *scan = NULL, *orient_p = NULL, *name = NULL, *wname = "", *db = NULL;
	int json = 0, quiet = 0, raw_type = LOOM_SCALAR_U8, rc, appended = 0;
	int raw_density = 0;
	uint32_t fmt = 0;
	uint32_t raw_dims[3], dims[3], odims[3], block[2];
	double sp = 0, osp, voxel_mm = 0;
	char namebuf[32];
	loom_scan_params p;
	loom_scan_db_params dp;
	loom_scan_volume v;
	loom_scan_result *r = NULL;
	loom_diag diag;
	build_progress bp;
	struct stat st;
	size_t n;
	opt_entry opts[] = {
		OPT_GROUP("input (by extension):"),
		OPT_TEXT("SCAN.vol", "Mitsuba grid, 1 channel (uint8, float16 or float32)"),
		OPT_TEXT("SCAN.nrrd / .nhdr", "NRRD, 1 channel (integers scaled to 0..1)"),
		OPT_TEXT("anything else", "raw: needs --raw-dims and --raw-type"),
		OPT_STRING(0, "orientation", &orient_p, "ORIENT", "fibre directions: .vol with 3 "
		           "float channels or the quantized encoding 4, or a 3-vector NRRD"),
		OPT_SIZE3(0, "raw-dims", raw_dims, "X,Y,Z", 1, UINT32_MAX,
		          "voxels of a raw scan (x fastest)"),
		OPT_ENUM(0, "raw-type", &raw_type, "T", raw_types,
		         "u8 (/255), u16 (/65535) or f32 (as is)"),
		OPT_DOUBLE(0, "voxel-mm", &voxel_mm, "S", "(]", 0, 100, "mm", "voxel edge in "
		           "mm, %r (default: the file's spacing for NRRD and .vol, else 0.005); "
		           "float densities outside [0,1] are rescaled by their range (a "
		           "warning)"),
		OPT_GROUP("pipeline:"),
		OPT_U32(0, "warps", &p.n_warps, "N", 2, LOOM_SCAN_MAX_YARNS, "warps in the "
		        "scan, cut border yarns included, %r (required)"),
		OPT_U32(0, "wefts", &p.n_wefts, "N", 2, LOOM_SCAN_MAX_YARNS, "wefts in the "
		        "scan, likewise (required)"),
		OPT_SIZE2(0, "block", block, "B1xB2", 1, 4096, "crossing size in voxels, "
		          "%r (default: DB's when it exists, else the measured yarn spacing)"),
		OPT_U32(0, "depth", &p.block_z, "B3", 1, 4096, "output depth, centred on the "
		        "cloth, %r (default: DB's, else the scan's nz)"),
		OPT_THREADS(&p.threads, 64, "worker threads (default 2; %r)"),
		OPT_GROUP("output:"),
		OPT_DB(&db, "database to append to (created if absent)"),
		OPT_STRING(0, "name", &name, "NAME", "exemplar name, 1..31 bytes (default: the "
		           "scan's file name)"),
		OPT_STRING(0, "weave-name", &wname, "S", "weave recorded with it (default \"\")"),
		OPT_U32(0, "format-version", &fmt, "N", 1, 4, "format %r of a new database "
		        "(default 4; appending keeps the database's)"),
		OPT_FLAG(0, "raw-density", &raw_density, "a new database with its density "
		         "planes raw (docs/exemplars.md); appending keeps the database's"),
		OPT_JSON(&json, "JSON: weave (one 0/1 string per pick of the crop), "
		         "rotation_degrees, crop [x0, y0, w, h] (aligned frame), warps, wefts "
		         "(tracked), crossings, block, ..."),
		OPT_QUIET(&quiet, "no report, no progress"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage_build, .about = about_build,
	              .opts = opts, .pos_name = "SCAN", .pos_min = 1, .pos_max = 1,
	              .pos = &scan};

	loom_scan_params_init(&p);
	opts_parse(&c, argc, argv);
	if (!db)
		opts_usage(&c, "missing --db DB");
	cli_check_output(prog, db);
	if (!opt_given(&c, &p.n_warps) || !opt_given(&c, &p.n_wefts))
		opts_usage(&c, "--warps N and --wefts N are required (yarns in the scan)");
	if (opt_given(&c, block)) {
		p.block_x = block[0];
		p.block_y = block[1];
	}
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
		opts_usage(&c, "--name: expected 1..31 bytes, got '%s'", name);
	if (raw_density && fmt == 1)
		opts_usage(&c, "--raw-density needs format version 2, 3 or 4 (version 1 "
		           "stores a brick as one stream)");
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
		/* appending keeps the storage: say so before the scan's work */
		if (fmt && fmt != info.voxel_layout)
			cli_fail(prog, "%s is format version %u; appending keeps it (convert it "
			         "first: loom exemplar convert --format-version %u)", db,
			         info.voxel_layout, fmt);
		if (raw_density && (info.n_raw_density == 0 ||
		                    info.n_raw_density != info.n_bricks - info.n_empty_bricks))
			cli_fail(prog, "%s stores its density planes deflated; appending keeps "
			         "that (convert it first: loom exemplar convert --raw-density)",
			         db);
		if (!opt_given(&c, block)) {
			p.block_x = info.block[0];
			p.block_y = info.block[1];
		}
		if (!opt_given(&c, &p.block_z))
			p.block_z = info.block[2];
	}
	memset(&v, 0, sizeof v);
	v.density = read_volume(prog, scan, 1, opt_given(&c, raw_dims) ? raw_dims : NULL, raw_type, dims,
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
		v.orient = read_volume(prog, orient_p, 3, opt_given(&c, raw_dims) ? raw_dims : NULL,
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
	dp.db_version = fmt;
	dp.density_raw = (uint32_t)raw_density;
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
