/*
 * tools/loom/cmd_render.c - `loom render FABRIC`: path-trace a fabric with
 * the microflake volume renderer (loom_render over loom_texture_volume_source;
 * docs/preview.md, docs/rendering.md): a flat patch of cloth seen from above
 * at an angle, or the cloth mapped onto an OBJ mesh through a shell.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "paintfile.h"
#include "progress.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const char usage[] =
	"loom render FABRIC [--mesh OBJ] [--width W] [--height H] [--spp N]\n"
	"            [--threads N] [--budget MB] [--seed S] [--db DB]\n"
	"            [--region X0,Y0:X1,Y1] [--elevation DEG] [--azimuth DEG]\n"
	"            [--fov DEG] [--density-scale K | --density-per-voxel K]\n"
	"            [--exposure STOPS]\n"
	"            [--filter nearest|trilinear] [--thickness T]\n"
	"            [--uv-repeats R | --uv-mm U[,V]] [--warp-dir X,Y,Z]\n"
	"            [--field-smooth N]\n"
	"            [--sun AZ,EL[,INTENSITY[,ANGLE]]] [--majorant grid|global]\n"
	"            [--json] [--quiet] -o OUT.png|OUT.exr\n";

static const char about[] =
	"Render the fabric with the microflake volume path tracer\n"
	"(docs/rendering.md).  Without --mesh: a flat patch of the unbounded bolt\n"
	"seen through a pinhole camera from above at an angle, framed on --region\n"
	"(default one design repeat).  With --mesh: the cloth is mapped onto the\n"
	"mesh's UV layout as a shell (shell mapping) and seen from above the mesh;\n"
	"a mesh without UVs (or with --warp-dir) is clothed along a smooth\n"
	"warp-direction field, one rigid field-aligned map per triangle continuing\n"
	"its neighbours' (no stretch, seams only where the field turns).\n"
	"FABRIC may be a paint file (loom paint): its regions are applied at\n"
	"lookup time.  Same inputs and seed give the same bytes for any thread\n"
	"count.\n";

static const opt_choice filter_names[] = {
	{"nearest", LOOM_FILTER_NEAREST}, {"trilinear", LOOM_FILTER_TRILINEAR}, {NULL, 0}};

static const opt_choice majorant_names[] = {
	{"grid", 0}, {"global", 1}, {NULL, 0}};

/* --sun AZ,EL[,INTENSITY[,ANGLE]] into double[4]. */
static const char *opt_sun(const char *text, void *dest)
{
	double *v = dest, w[4] = {0, 0, 2.6, 0.53};
	int n = 0;
	const char *p = text;

	for (;;) {
		char *end;
		if (n == 4)
			return "AZ,EL[,INTENSITY[,ANGLE]]: at most 4 numbers";
		w[n] = strtod(p, &end);
		if (end == p || !isfinite(w[n]))
			return "AZ,EL[,INTENSITY[,ANGLE]]: finite numbers separated by commas";
		n++;
		p = end;
		if (*p == '\0')
			break;
		if (*p != ',')
			return "AZ,EL[,INTENSITY[,ANGLE]]: finite numbers separated by commas";
		p++;
	}
	if (n < 2)
		return "AZ,EL[,INTENSITY[,ANGLE]]: at least the azimuth and the elevation";
	if (!(w[1] > 0 && w[1] <= 90))
		return "AZ,EL[,INTENSITY[,ANGLE]] with the elevation EL in (0, 90] degrees";
	if (!(w[2] >= 0))
		return "AZ,EL[,INTENSITY[,ANGLE]] with INTENSITY >= 0";
	if (!(w[3] >= 0 && w[3] <= 90))
		return "AZ,EL[,INTENSITY[,ANGLE]] with the disc's ANGLE in [0, 90] degrees";
	memcpy(v, w, sizeof w);
	return NULL;
}

static int parse_box2(const char *s, int64_t lo[2], int64_t hi[2])
{
	long long v[4];
	char tail;

	if (sscanf(s, "%lld,%lld:%lld,%lld%c", &v[0], &v[1], &v[2], &v[3], &tail) != 4)
		return -1;
	if (v[2] <= v[0] || v[3] <= v[1])
		return -1;
	lo[0] = v[0];
	lo[1] = v[1];
	hi[0] = v[2];
	hi[1] = v[3];
	return 0;
}

/* --region into int64_t[4]: lo x, lo y, hi x, hi y. */
static const char *opt_region(const char *text, void *dest)
{
	int64_t *b = dest;

	if (parse_box2(text, b, b + 2))
		return "X0,Y0:X1,Y1 with X0 < X1, Y0 < Y1";
	return NULL;
}

typedef struct rprog {
	cli_progress p;
	pthread_mutex_t lock;
} rprog;

static void progress_cb(void *user, uint64_t done, uint64_t total)
{
	rprog *r = user;
	(void)total;
	pthread_mutex_lock(&r->lock);
	cli_progress_update(&r->p, done);
	pthread_mutex_unlock(&r->lock);
}

/* --warp-dir X,Y,Z into double[3], not all zero. */
static const char *opt_dir3(const char *text, void *dest)
{
	double *d = dest;
	char *end;
	const char *q = text;

	for (int k = 0; k < 3; k++) {
		d[k] = strtod(q, &end);
		if (end == q || !isfinite(d[k]) || (k < 2 && *end != ',') ||
		    (k == 2 && *end))
			return "X,Y,Z: three finite numbers, not all zero";
		q = end + 1;
	}
	if (d[0] == 0 && d[1] == 0 && d[2] == 0)
		return "X,Y,Z: three finite numbers, not all zero";
	return NULL;
}

/* --uv-mm U[,V] into double[2]: millimetres of cloth per UV unit. */
static const char *opt_uv_mm(const char *text, void *dest)
{
	double *d = dest;
	char *end;

	d[0] = strtod(text, &end);
	if (end == text || !(d[0] > 0) || !isfinite(d[0]))
		return "U[,V]: millimetres per UV unit, finite and > 0";
	d[1] = d[0];
	if (*end == ',') {
		const char *q = end + 1;
		d[1] = strtod(q, &end);
		if (end == q || !(d[1] > 0) || !isfinite(d[1]))
			return "U[,V]: millimetres per UV unit, finite and > 0";
	}
	if (*end)
		return "U[,V]: millimetres per UV unit, finite and > 0";
	return NULL;
}

/* Pinhole camera at elevation el, azimuth az (radians) looking at target
   from distance dist. */
static void place_camera(loom_camera *c, const double target[3], double dist,
                         double el, double az, double fov)
{
	c->kind = LOOM_CAMERA_PINHOLE;
	memcpy(c->target, target, 3 * sizeof(double));
	c->eye[0] = target[0] - dist * sin(az) * cos(el);
	c->eye[1] = target[1] - dist * cos(az) * cos(el);
	c->eye[2] = target[2] + dist * sin(el);
	c->up[0] = 0;
	c->up[1] = 0;
	c->up[2] = 1;
	c->fov_y_deg = fov;
}

int cmd_render(int argc, char **argv)
{
	const char *prog = "loom render";
	const char *path = NULL, *out = NULL, *db_opt = NULL, *mesh_path = NULL;
	int quiet = 0, json = 0, filter = LOOM_FILTER_NEAREST, rc, global_mj = 0;
	uint32_t width = 480, height = 320, spp = 16, threads = 0;
	uint64_t seed = 1;
	double budget_mb = 128, el = 40, az = 0, fov = 30, dscale = 80, exposure = 0;
	double dvoxel = 0;
	double thickness = 0, uv_repeats = 1, warp_dir[3] = {0, 0, 1};
	double uv_mm[2] = {0, 0}, vpu[2] = {0, 0}, pitch_mm[2] = {0, 0};
	double sun[4] = {0, 35, 2.6, 0.53};
	uint32_t field_smooth = 32;
	int have_uv_stats = 0, field = 0;
	loom_mesh_uv_stats uvst;
	int64_t box[4] = {0, 0, 0, 0}, *lo = box, *hi = box + 2;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_render_options ro = LOOM_RENDER_OPTIONS_INIT;
	loom_render_stats st;
	loom_volume_source src;
	loom_fabric_db_identity id;
	uint64_t rep[3];
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_paint *paint = NULL;
	loom_texture *t = NULL;
	loom_mesh *mesh = NULL;
	loom_shell *shell = NULL;
	loom_majorant *mj = NULL;
	size_t mj_bytes = 0, budget;
	float *rgb = NULL;
	rprog pr;
	loom_diag diag;
	opt_entry opts[] = {
		OPT_U32(0, "width", &width, "W", 1, 65536, "image width, %r (default 480)"),
		OPT_U32(0, "height", &height, "H", 1, 65536, "image height, %r (default 320)"),
		OPT_U32(0, "spp", &spp, "N", 1, 1000000, "samples per pixel, %r (default 16)"),
		OPT_THREADS(&threads, 256, "render threads (default: all CPUs)"),
		OPT_BUDGET(&budget_mb, "texture cache budget in MiB (default 128)"),
		OPT_SEED(&seed, "S", "random seed (default 1)"),
		OPT_DB(&db_opt, "exemplar database (default: the one the fabric names)"),
		OPT_CALLBACK(0, "region", box, "BOX", opt_region, "flat patch: the window "
		             "framed, voxels (default one repeat)"),
		OPT_DOUBLE(0, "elevation", &el, "DEG", "(]", 0, 90, "degrees", "camera angle "
		           "above the cloth plane, %r (default 40)"),
		OPT_DOUBLE(0, "azimuth", &az, "DEG", "()", -INFINITY, INFINITY,
		           "a finite number of degrees",
		           "camera direction around the vertical (default 0: looking along "
		           "+y, the warps)"),
		OPT_DOUBLE(0, "fov", &fov, "DEG", "()", 0, 180, "degrees",
		           "vertical field of view, %r (default 30)"),
		OPT_DOUBLE(0, "density-scale", &dscale, "K", "(]", 0, 1e6, NULL, "extinction "
		           "per millimetre of a density-1 voxel (default 80: opaque yarns; "
		           "databases of any voxel size look alike)"),
		OPT_DOUBLE(0, "density-per-voxel", &dvoxel, "K", "(]", 0, 1e6, NULL,
		           "extinction per voxel length instead (the old meaning of "
		           "--density-scale)"),
		OPT_DOUBLE(0, "exposure", &exposure, "STOPS", "[]", -64, 64, "stops", "PNG: "
		           "scale by 2^STOPS before the sRGB curve (default 0)"),
		OPT_ENUM(0, "filter", &filter, "F", filter_names,
		         "texture lookups: nearest (default) or trilinear"),
		OPT_STRING(0, "mesh", &mesh_path, "OBJ",
		           "map the cloth onto this mesh (its UVs; without UVs along a "
		           "warp-direction field, see --warp-dir)"),
		OPT_CALLBACK(0, "warp-dir", warp_dir, "X,Y,Z", opt_dir3, "mesh: lay the "
		             "warps along this world direction projected onto the surface "
		             "(a smooth field; default 0,0,1); also ignores the mesh's UVs"),
		OPT_U32(0, "field-smooth", &field_smooth, "N", 0, 100000, "mesh without "
		        "UVs: rounds of warp-field smoothing, %r (default 32)"),
		OPT_DOUBLE(0, "thickness", &thickness, "T", "()", 0, INFINITY, NULL, "shell "
		           "thickness in mesh units (default 1.5% of the mesh's bounding-box "
		           "diagonal)"),
		OPT_DOUBLE(0, "uv-repeats", &uv_repeats, "R", "()", 0, INFINITY, NULL,
		           "design repeats per UV unit along u, the same voxel scale "
		           "along v (default 1; without UVs a UV unit is the mesh's "
		           "bounding-box diagonal)"),
		OPT_CALLBACK(0, "uv-mm", uv_mm, "U[,V]", opt_uv_mm, "instead of "
		             "--uv-repeats: millimetres of cloth per UV unit along u "
		             "and v, crossings at the draft's sett (square when it "
		             "states none), so square motifs stay square"),
		OPT_CALLBACK(0, "sun", sun, "AZ,EL[,I[,A]]", opt_sun, "the sun: azimuth "
		             "and elevation in degrees (measured as the camera's: a sun at "
		             "the camera's angles lights from behind it), irradiance "
		             "(default 2.6) and disc diameter in degrees (default 0.53); "
		             "default: 150 degrees round from the camera, 35 up"),
		OPT_ENUM(0, "majorant", &global_mj, "M", majorant_names,
		         "flat patch: track through the per-crossing majorant grid "
		         "(default) or against one global bound (slower; for "
		         "comparison)"),
		OPT_OUTPUT(&out, "OUT", ".png (8-bit sRGB) or .exr (linear float RGB)"),
		OPT_JSON(&json, "print figures as JSON on stdout"),
		OPT_QUIET(&quiet, "no progress or summary"),
		OPT_END()
	};
	opts_cmd cmd = {.prog = prog, .usage = usage, .about = about, .opts = opts,
	                .pos_name = "FABRIC", .pos_min = 1, .pos_max = 1, .pos = &path};

	opts_parse(&cmd, argc, argv);
	if (!out)
		opts_usage(&cmd, "missing -o OUT.png|OUT.exr");
	if (!cli_ends_with(out, ".png") && !cli_ends_with(out, ".exr"))
		opts_usage(&cmd, "output '%s' must end in .png or .exr", out);
	if (mesh_path && opt_given(&cmd, box))
		opts_usage(&cmd, "--region frames a flat patch; it does not go with --mesh");
	if (opt_given(&cmd, &dscale) && opt_given(&cmd, &dvoxel))
		opts_usage(&cmd, "--density-scale (per mm) and --density-per-voxel are "
		           "the same setting in two units; give one");
	if (mesh_path && opt_given(&cmd, &global_mj))
		opts_usage(&cmd, "--majorant applies to a flat patch; a mesh is tracked "
		           "against one global bound");
	if (!mesh_path && (opt_given(&cmd, &thickness) || opt_given(&cmd, &uv_repeats) ||
	                   opt_given(&cmd, uv_mm) ||
	                   opt_given(&cmd, warp_dir) || opt_given(&cmd, &field_smooth)))
		opts_usage(&cmd, "--thickness, --uv-repeats, --uv-mm, --warp-dir and "
		           "--field-smooth go with --mesh");
	if (opt_given(&cmd, &uv_repeats) && opt_given(&cmd, uv_mm))
		opts_usage(&cmd, "--uv-repeats and --uv-mm both set the cloth's scale "
		           "on the UVs; give one");
	cli_check_output(prog, out); /* before minutes of rendering */
	cli_diag_init(&diag, &quiet);

	if (db_opt && loom_db_open(db_opt, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (cli_open_painted(path, db, &f, &paint, &diag) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	loom_fabric_get_db_identity(f, &id);
	loom_fabric_repeat_voxels(f, rep);
	to.max_threads = threads ? threads : 64;
	budget = (size_t)(budget_mb * 1048576.0);
	/* The majorant grid (flat patches) is counted in --budget: the texture
	   gets what it leaves. */
	if (!mesh_path && !global_mj && !paint) {
		if (loom_majorant_build(f, &mj, &diag) != LOOM_OK) {
			loom_fabric_free(f);
			loom_db_close(db);
			cli_fail(prog, "%s", diag.message);
		}
		mj_bytes = loom_majorant_bytes(mj, to.max_threads);
		if (mj_bytes >= budget) {
			cli_error(prog, "--budget %g MiB cannot hold the majorant grid (%zu "
			          "bytes) and the texture", budget_mb, mj_bytes);
			loom_majorant_free(mj);
			loom_fabric_free(f);
			loom_db_close(db);
			return EXIT_BAD_INPUT;
		}
	}
	to.budget_bytes = budget - mj_bytes;
	if (loom_texture_open(f, db, &to, &t, &diag) != LOOM_OK) {
		loom_majorant_free(mj);
		loom_fabric_free(f);
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	/* painted regions may add density where the grid saw none (a slub, a
	   pull): a painted fabric is tracked against the global bound */
	if (paint ? loom_paint_volume_source(paint, t, f, filter, &src) != LOOM_OK
	          : (mj ? loom_texture_volume_source_grid(t, f, filter, mj, &src)
	                : loom_texture_volume_source(t, f, filter, &src)) != LOOM_OK) {
		cli_error(prog, "%s: cannot make the volume source", path);
		goto fail;
	}

	ro.width = width;
	ro.height = height;
	ro.spp = spp;
	ro.threads = threads;
	ro.seed = seed;
	/* loom_render wants extinction per voxel length */
	ro.density_scale = opt_given(&cmd, &dvoxel) ? dvoxel
	                   : dscale * (src.voxel_mm > 0 ? src.voxel_mm : 0.024);
	ro.max_depth = 32;
	/* The sun: towards the light = where a camera at (AZ, EL) would stand
	   (see place_camera).  The studio default stands 150 degrees round from
	   the camera, so the cloth is lit from the far side at a raking angle
	   (yarn relief and sheen), never flat from behind the viewer. */
	if (!opt_given(&cmd, sun))
		sun[0] = az + 150.0;
	ro.light.kind = LOOM_LIGHT_DISTANT;
	ro.light.dir[0] = -sin(sun[0] * M_PI / 180.0) * cos(sun[1] * M_PI / 180.0);
	ro.light.dir[1] = -cos(sun[0] * M_PI / 180.0) * cos(sun[1] * M_PI / 180.0);
	ro.light.dir[2] = sin(sun[1] * M_PI / 180.0);
	ro.light.rgb[0] = ro.light.rgb[1] = ro.light.rgb[2] = (float)sun[2];
	ro.light.angle_deg = sun[3];
	ro.env[0] = ro.env[1] = ro.env[2] = 0.18f;
	if (mesh_path) {
		loom_shell_params sp = LOOM_SHELL_PARAMS_INIT;
		double blo[3], bhi[3], c[3], diag_len = 0, dist;
		if (loom_obj_read(mesh_path, &mesh, &diag) != LOOM_OK) {
			cli_error(prog, "%s", diag.message);
			goto fail;
		}
		for (int k = 0; k < 3; k++) {
			blo[k] = INFINITY;
			bhi[k] = -INFINITY;
		}
		for (uint32_t v = 0; v < mesh->n_positions; v++)
			for (int k = 0; k < 3; k++) {
				double x = mesh->positions[3 * v + (uint32_t)k];
				blo[k] = x < blo[k] ? x : blo[k];
				bhi[k] = x > bhi[k] ? x : bhi[k];
			}
		for (int k = 0; k < 3; k++)
			diag_len += (bhi[k] - blo[k]) * (bhi[k] - blo[k]);
		diag_len = sqrt(diag_len);
		if (!(diag_len > 0)) {
			cli_error(prog, "%s: the mesh has no extent", mesh_path);
			goto fail;
		}
		sp.thickness = thickness > 0 ? thickness : 0.015 * diag_len;
		sp.offset = -sp.thickness / 2;
		vpu[0] = vpu[1] = (double)rep[0] * uv_repeats;
		if (opt_given(&cmd, uv_mm) &&
		    loom_uv_mm_scale(uv_mm, id.block, src.voxel_mm > 0 ? src.voxel_mm
		                     : 0.024, loom_fabric_design(f)->sett, vpu,
		                     pitch_mm) != LOOM_OK) {
			cli_error(prog, "--uv-mm %g,%g: no scale for crossings of %ux%u "
			          "voxels of %g mm", uv_mm[0], uv_mm[1], id.block[0],
			          id.block[1], src.voxel_mm);
			goto fail;
		}
		sp.voxels_per_uv = vpu[0];
		sp.voxels_per_uv_v = vpu[1];
		sp.nz = src.nz;
		{
			/* the UVs' distortion and seams, modulo one design repeat;
			   a seam: a mismatch over half a voxel */
			double per[2] = {(double)rep[0] / vpu[0], (double)rep[1] / vpu[1]};
			field = !mesh->tri_vt || opt_given(&cmd, warp_dir);
			if (field) {
				loom_field_uv_params fp = LOOM_FIELD_UV_PARAMS_INIT;
				loom_mesh *fm = NULL;
				memcpy(fp.warp_dir, warp_dir, sizeof warp_dir);
				fp.uv_per_world = 1.0 / diag_len;
				fp.period[0] = per[0];
				fp.period[1] = per[1];
				fp.smooth_iters = field_smooth;
				if (loom_mesh_field_uv(mesh, &fp, &fm, &diag) != LOOM_OK) {
					cli_error(prog, "%s: %s", mesh_path, diag.message);
					goto fail;
				}
				loom_mesh_free(mesh);
				mesh = fm;
			}
			have_uv_stats = loom_mesh_measure_uv(mesh, per,
			                                     0.5 / (vpu[0] > vpu[1] ? vpu[0]
			                                            : vpu[1]),
			                                     &uvst) == LOOM_OK;
		}
		if (loom_shell_new(mesh, &sp, &shell, &diag) != LOOM_OK) {
			cli_error(prog, "%s", diag.message);
			goto fail;
		}
		ro.shell = shell;
		for (int k = 0; k < 3; k++)
			c[k] = 0.5 * (blo[k] + bhi[k]);
		dist = 0.42 * diag_len / tan(0.5 * fov * M_PI / 180.0);
		place_camera(&ro.camera, c, dist, el * M_PI / 180.0, az * M_PI / 180.0, fov);
	} else {
		double c[3], wspan, dist, aspect = (double)width / height;
		double tanh_y = tan(0.5 * fov * M_PI / 180.0);
		if (!opt_given(&cmd, box)) {
			hi[0] = (int64_t)rep[0];
			hi[1] = (int64_t)rep[1];
		}
		c[0] = 0.5 * (double)(lo[0] + hi[0]);
		c[1] = 0.5 * (double)(lo[1] + hi[1]);
		c[2] = 0.5 * (double)src.nz;
		/* fit the region's width (and its foreshortened depth) */
		wspan = (double)(hi[0] - lo[0]) / (2.0 * tanh_y * aspect);
		dist = (double)(hi[1] - lo[1]) * sin(el * M_PI / 180.0) / (2.0 * tanh_y);
		dist = (wspan > dist ? wspan : dist) + 0.5 * (double)(hi[1] - lo[1]) *
		       cos(el * M_PI / 180.0);
		place_camera(&ro.camera, c, dist, el * M_PI / 180.0, az * M_PI / 180.0, fov);
	}
	rgb = malloc((size_t)width * height * 3 * sizeof *rgb);
	if (!rgb) {
		cli_error(prog, "out of memory for a %ux%u image", width, height);
		goto fail;
	}
	pthread_mutex_init(&pr.lock, NULL);
	{
		uint32_t tile = ro.tile ? ro.tile : 16;
		uint64_t tiles = (uint64_t)((width + tile - 1) / tile) *
		                 ((height + tile - 1) / tile);
		cli_progress_begin(&pr.p, prog, "tiles", tiles, quiet);
	}
	ro.progress = progress_cb;
	ro.progress_user = &pr;
	rc = loom_render(&src, &ro, rgb, &st, &diag);
	cli_progress_end(&pr.p);
	pthread_mutex_destroy(&pr.lock);
	if (rc != LOOM_OK) {
		cli_error(prog, "%s", diag.message[0] ? diag.message : loom_strerror(rc));
		goto fail;
	}
	if (cli_write_rgb(out, rgb, width, height, exposure, &diag) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto fail;
	}
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "output", out);
		jw_uint(&w, "width", width);
		jw_uint(&w, "height", height);
		jw_uint(&w, "spp", spp);
		jw_uint(&w, "seed", seed);
		jw_str(&w, "scene", mesh_path ? "mesh" : "flat");
		jw_num(&w, "voxel_mm", src.voxel_mm);
		jw_num(&w, "density_per_voxel", ro.density_scale);
		jw_uint(&w, "paths", st.paths);
		jw_uint(&w, "rays", st.rays);
		jw_uint(&w, "lookups", st.lookups);
		jw_uint(&w, "scatterings", st.scatterings);
		jw_uint(&w, "shell_queries", st.shell_queries);
		if (have_uv_stats) {
			jw_obj(&w, "uv");
			jw_str(&w, "source", field ? "field" : "mesh");
			jw_num(&w, "stretch_max", uvst.stretch_max);
			jw_num(&w, "stretch_mean", uvst.stretch_mean);
			jw_uint(&w, "interior_edges", uvst.interior_edges);
			jw_uint(&w, "seam_edges", uvst.seam_edges);
			jw_num(&w, "seam_mean_voxels", uvst.seam_mean * vpu[0]);
			jw_num(&w, "seam_max_voxels", uvst.seam_max * vpu[0]);
			jw_num(&w, "voxels_per_uv_u", vpu[0]);
			jw_num(&w, "voxels_per_uv_v", vpu[1]);
			if (pitch_mm[0] > 0) {
				jw_num(&w, "crossing_mm_u", pitch_mm[0]);
				jw_num(&w, "crossing_mm_v", pitch_mm[1]);
			}
			jw_close(&w);
		}
		jw_uint(&w, "cells", st.cells);
		jw_str(&w, "majorant", mj ? "grid" : "global");
		jw_uint(&w, "majorant_bytes", mj_bytes);
		jw_num(&w, "seconds", st.seconds);
		jw_end(&w);
	} else if (!quiet) {
		fprintf(stderr, "loom render: %s: %ux%u, %u spp in %.2f s (%.0f paths/s, "
		        "%llu lookups)\n", out, width, height, spp, st.seconds,
		        st.seconds > 0 ? (double)st.paths / st.seconds : 0.0,
		        (unsigned long long)st.lookups);
	}
	free(rgb);
	loom_shell_free(shell);
	loom_mesh_free(mesh);
	loom_texture_close(t);
	loom_paint_free(paint);
	loom_majorant_free(mj);
	loom_fabric_free(f);
	loom_db_close(db);
	return 0;
fail:
	free(rgb);
	loom_shell_free(shell);
	loom_mesh_free(mesh);
	loom_texture_close(t);
	loom_paint_free(paint);
	loom_majorant_free(mj);
	loom_fabric_free(f);
	loom_db_close(db);
	return EXIT_BAD_INPUT;
}
