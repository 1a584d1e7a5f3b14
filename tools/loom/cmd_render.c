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
	"            [--field-smooth N] [--warp-field SRC]\n"
	"            [--sun AZ,EL[,INTENSITY[,ANGLE]]] [--majorant grid|global]\n"
	"            [--look-from X,Y,Z] [--look-at X,Y,Z] [--up X,Y,Z]\n"
	"            [--ortho WIDTH_MM] [--aperture MM [--focus MM]]\n"
	"            [--envmap FILE.exr [--env-rotate DEG] [--env-intensity K]]\n"
	"            [--sky studio|grey]\n"
	"            [--light X,Y,Z,RADIUS,INTENSITY]...\n"
	"            [--cloth-size W[,H]] [--ground [--ground-z MM]\n"
	"            [--ground-albedo A[,G,B]]] [--tone linear|filmic]\n"
	"            [--sampler sobol|random] [--noise REL] [--progressive S]\n"
	"            [--lod off|auto]\n"
	"            [--json] [--quiet] -o OUT.png|OUT.exr\n";

static const char about[] =
	"Render the fabric with the microflake volume path tracer\n"
	"(docs/rendering.md).  Without --mesh: a flat patch of the unbounded bolt\n"
	"seen through a pinhole camera from above at an angle, framed on --region\n"
	"(default one design repeat).  With --mesh: the cloth is mapped onto the\n"
	"mesh's UV layout as a shell (shell mapping) and seen from above the mesh;\n"
	"a mesh without UVs (or with --warp-dir or --warp-field) is clothed along\n"
	"a smooth warp-direction field (a direction projected, or the principal\n"
	"curvature), one rigid field-aligned map per triangle continuing\n"
	"its neighbours' (no stretch, seams only where the field turns).\n"
	"FABRIC may be a paint file (loom paint): its regions are applied at\n"
	"lookup time.  Same inputs and seed give the same bytes for any thread\n"
	"count.\n";

static const opt_choice filter_names[] = {
	{"nearest", LOOM_FILTER_NEAREST}, {"trilinear", LOOM_FILTER_TRILINEAR}, {NULL, 0}};

static const opt_choice lod_names[] = {{"off", 0}, {"auto", 1}, {NULL, 0}};

static const opt_choice tone_names[] = {
	{"linear", LOOM_TONE_LINEAR}, {"filmic", LOOM_TONE_FILMIC}, {NULL, 0}};

static const opt_choice majorant_names[] = {
	{"grid", 0}, {"global", 1}, {NULL, 0}};

static const opt_choice sky_names[] = {
	{"studio", 0}, {"grey", 1}, {NULL, 0}};

static const opt_choice sampler_names[] = {
	{"sobol", LOOM_SAMPLER_SOBOL}, {"random", LOOM_SAMPLER_RANDOM}, {NULL, 0}};

/* --progressive: the image so far to the output name (the writers go
   through a temporary and a rename, so a reader never sees half a file). */
typedef struct pwrite {
	const char *out;
	uint32_t width, height;
	double exposure, unit;
	int tone, is_exr;
	const loom_render_aov *aov; /* filled by the snapshot as the beauty */
	unsigned writes;
	int failed;
} pwrite;

static int write_png_tone(const char *path, const float *rgb, uint32_t w,
                          uint32_t h, double exposure, int tone, loom_diag *diag);
static int write_exr_aov(const char *path, const float *rgb,
                         const loom_render_aov *a, uint32_t w, uint32_t h,
                         double unit, loom_diag *diag);

static void progressive_cb(void *user, const float *rgb)
{
	pwrite *pw = user;
	loom_diag d = {0};

	if (pw->failed)
		return;
	/* the writers of the final image, so each copy looks like it */
	if ((pw->is_exr ? write_exr_aov(pw->out, rgb, pw->aov, pw->width, pw->height,
	                                pw->unit, &d)
	                : write_png_tone(pw->out, rgb, pw->width, pw->height,
	                                 pw->exposure, pw->tone, &d)) != LOOM_OK) {
		fprintf(stderr, "loom render: warning: --progressive: %s; no more "
		        "intermediate images\n", d.message);
		pw->failed = 1;
		return;
	}
	pw->writes++;
}

#define MAX_CLI_LIGHTS 16 /* --sun and --light, each */

/* Repeatable light options: one row of numbers per occurrence. */
typedef struct light_list {
	int n;
	double v[MAX_CLI_LIGHTS][5];
} light_list;

/* --sun AZ,EL[,INTENSITY[,ANGLE]] appended to a light_list. */
static const char *opt_sun(const char *text, void *dest)
{
	light_list *ll = dest;
	double *v, w[4] = {0, 0, 2.6, 0.53};
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
	if (ll->n >= MAX_CLI_LIGHTS)
		return "AZ,EL[,INTENSITY[,ANGLE]], given at most 16 times";
	v = ll->v[ll->n++];
	memcpy(v, w, sizeof w);
	return NULL;
}

/* --light X,Y,Z,RADIUS,INTENSITY appended to a light_list. */
static const char *opt_light(const char *text, void *dest)
{
	light_list *ll = dest;
	double w[5];
	const char *q = text;
	char *end;

	for (int k = 0; k < 5; k++) {
		w[k] = strtod(q, &end);
		if (end == q || !isfinite(w[k]) || (k < 4 && *end != ',') ||
		    (k == 4 && *end))
			return "X,Y,Z,RADIUS,INTENSITY: five finite numbers separated by "
			       "commas";
		q = end + 1;
	}
	if (!(w[3] > 0) || !(w[4] >= 0))
		return "X,Y,Z,RADIUS,INTENSITY with RADIUS > 0 and INTENSITY >= 0";
	if (ll->n >= MAX_CLI_LIGHTS)
		return "X,Y,Z,RADIUS,INTENSITY, given at most 16 times";
	memcpy(ll->v[ll->n++], w, sizeof w);
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

/* --look-from / --look-at / --up X,Y,Z into double[3] (any finite). */
static const char *opt_point3(const char *text, void *dest)
{
	double *d = dest;
	char *end;
	const char *q = text;

	for (int k = 0; k < 3; k++) {
		d[k] = strtod(q, &end);
		if (end == q || !isfinite(d[k]) || (k < 2 && *end != ',') ||
		    (k == 2 && *end))
			return "X,Y,Z: three finite numbers separated by commas";
		q = end + 1;
	}
	return NULL;
}

static const opt_choice field_names[] = {
	{"direction", LOOM_FIELD_DIRECTION}, {"curvature-max", LOOM_FIELD_CURVATURE_MAX},
	{"curvature-min", LOOM_FIELD_CURVATURE_MIN}, {NULL, 0}};

/* --warp-dir X,Y,Z into double[3], not all zero. */
static const char *opt_dir3(const char *text, void *dest)
{
	const double *d = dest;

	if (opt_point3(text, dest) || (d[0] == 0 && d[1] == 0 && d[2] == 0))
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

/* --cloth-size W[,H] into double[2]: millimetres, finite and > 0. */
static const char *opt_size_mm(const char *text, void *dest)
{
	double *d = dest;
	char *end;
	const char *q = text;

	for (int k = 0; k < 2; k++) {
		d[k] = strtod(q, &end);
		if (end == q || !(d[k] > 0) || !isfinite(d[k]))
			return "W[,H]: millimetres, finite and > 0";
		if (k == 0 && *end != ',') {
			d[1] = d[0];
			break;
		}
		q = end + 1;
	}
	if (*end)
		return "W[,H]: millimetres, finite and > 0";
	return NULL;
}

/* --ground-albedo A or R,G,B into double[3], each in [0, 1]. */
static const char *opt_albedo(const char *text, void *dest)
{
	double *d = dest;
	char *end;
	const char *q = text;
	int k;

	for (k = 0; k < 3; k++) {
		d[k] = strtod(q, &end);
		if (end == q || !(d[k] >= 0 && d[k] <= 1))
			return "A or R,G,B: reflectances in [0, 1]";
		if (*end != ',')
			break;
		q = end + 1;
	}
	if (*end || k == 1)
		return "A or R,G,B: reflectances in [0, 1]";
	if (k == 0)
		d[1] = d[2] = d[0];
	return NULL;
}

/* The PNG through the tone curve. */
static int write_png_tone(const char *path, const float *rgb, uint32_t w,
                          uint32_t h, double exposure, int tone, loom_diag *diag)
{
	loom_image *img = NULL;
	int rc;

	if ((rc = loom_image_new(w, h, 3, &img)) != LOOM_OK)
		return rc;
	loom_render_to_srgb8_tone(rgb, (size_t)w * h, exposure, tone, img->pixels);
	rc = loom_image_write(path, img, diag);
	loom_image_free(img);
	return rc;
}

/* The EXR: linear RGB and the AOV layers (docs/rendering.md, "EXR
   output"), float; depth from scene units to the user's (x unit). */
static int write_exr_aov(const char *path, const float *rgb,
                         const loom_render_aov *a, uint32_t w, uint32_t h,
                         double unit, loom_diag *diag)
{
	static const loom_exr_channel ch[13] = {
		{"R", LOOM_EXR_FLOAT}, {"G", LOOM_EXR_FLOAT}, {"B", LOOM_EXR_FLOAT},
		{"albedo.R", LOOM_EXR_FLOAT}, {"albedo.G", LOOM_EXR_FLOAT},
		{"albedo.B", LOOM_EXR_FLOAT}, {"normal.X", LOOM_EXR_FLOAT},
		{"normal.Y", LOOM_EXR_FLOAT}, {"normal.Z", LOOM_EXR_FLOAT},
		{"Z", LOOM_EXR_FLOAT}, {"noise.R", LOOM_EXR_FLOAT},
		{"noise.G", LOOM_EXR_FLOAT}, {"noise.B", LOOM_EXR_FLOAT}};
	size_t npx = (size_t)w * h;
	float *rows = malloc(npx * 13 * sizeof *rows);
	int rc;

	if (!rows) {
		snprintf(diag->message, sizeof diag->message, "%s: out of memory", path);
		return LOOM_ENOMEM;
	}
	for (size_t i = 0; i < npx; i++) {
		float *r = rows + 13 * i;
		for (int k = 0; k < 3; k++) {
			r[k] = rgb[3 * i + (size_t)k];
			r[3 + k] = a->albedo[3 * i + (size_t)k];
			r[6 + k] = a->normal[3 * i + (size_t)k];
			r[10 + k] = a->noise[3 * i + (size_t)k];
		}
		r[9] = (float)(a->depth[i] * unit);
	}
	rc = cli_write_exr(path, w, h, ch, 13, rows, diag);
	free(rows);
	return rc;
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
	int quiet = 0, json = 0, filter = LOOM_FILTER_NEAREST, rc, global_mj = 0, lod = 0;
	uint32_t width = 480, height = 320, spp = 16, threads = 0;
	uint64_t seed = 1;
	double budget_mb = 128, el = 40, az = 0, fov = 30, dscale = 80, exposure = 0;
	double dvoxel = 0;
	double thickness = 0, uv_repeats = 1, warp_dir[3] = {0, 0, 1};
	double uv_mm[2] = {0, 0}, vpu[2] = {0, 0}, pitch_mm[2] = {0, 0};
	light_list suns = {0, {{0}}}, spheres = {0, {{0}}};
	loom_light extra[2 * MAX_CLI_LIGHTS];
	double look_from[3] = {0, 0, 0}, look_at[3] = {0, 0, 0}, cam_up[3] = {0, 0, 1};
	double ortho_w = 0, aperture = 0, focus = 0, unit = 1;
	const char *env_path = NULL;
	double env_rot = 0, env_k = 1;
	loom_envmap *envmap = NULL;
	size_t env_bytes = 0;
	int sky_grey = 0;
	uint32_t field_smooth = 32;
	int field_source = LOOM_FIELD_DIRECTION;
	int ground = 0, tone = LOOM_TONE_LINEAR, is_exr;
	double ground_z = 0, ground_alb[3] = {0.6, 0.6, 0.6}, cloth_mm[2] = {0, 0};
	double floor_scene = 0; /* default floor height, scene units */
	float *aovbuf = NULL;
	loom_render_aov aov;
	int have_uv_stats = 0, field = 0;
	loom_mesh_uv_stats uvst;
	int64_t box[4] = {0, 0, 0, 0}, *lo = box, *hi = box + 2;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_render_options ro = LOOM_RENDER_OPTIONS_INIT;
	loom_render_stats st;
	loom_texture_stats ts;
	loom_volume_source src;
	int sampler = LOOM_SAMPLER_SOBOL;
	double noise = 0, prog_s = 0;
	pwrite pw = {NULL, 0, 0, 0, 0, 0, 0, NULL, 0, 0};
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
		OPT_ENUM(0, "warp-field", &field_source, "SRC", field_names, "mesh without "
		         "UVs: the warps follow --warp-dir projected (direction, the "
		         "default), the direction of strongest curvature (curvature-max: "
		         "round a cylinder) or of weakest (curvature-min: along it); "
		         "--warp-dir where the surface is umbilic"),
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
		OPT_CALLBACK(0, "sun", &suns, "AZ,EL[,I[,A]]", opt_sun, "a sun (repeatable, "
		             "up to 16): azimuth "
		             "and elevation in degrees (measured as the camera's: a sun at "
		             "the camera's angles lights from behind it), irradiance "
		             "(default 2.6) and disc diameter in degrees (default 0.53); "
		             "default: 150 degrees round from the camera, 35 up"),
		OPT_CALLBACK(0, "look-from", look_from, "X,Y,Z", opt_point3, "camera "
		             "position in millimetres of the cloth's frame (docs/"
		             "rendering.md; with --mesh: mesh units); default: from "
		             "--elevation, --azimuth and a distance that frames the view"),
		OPT_CALLBACK(0, "look-at", look_at, "X,Y,Z", opt_point3, "point looked "
		             "at, same units (default: the region's centre at mid-"
		             "thickness, or the mesh's box centre); without --look-from "
		             "the camera keeps its --elevation/--azimuth offset from it"),
		OPT_CALLBACK(0, "up", cam_up, "X,Y,Z", opt_point3, "camera up hint, not "
		             "along the view (default 0,0,1: the cloth's normal)"),
		OPT_DOUBLE(0, "ortho", &ortho_w, "WIDTH_MM", "()", 0, INFINITY, NULL,
		           "orthographic camera whose view is WIDTH_MM wide (mesh units "
		           "with --mesh); --fov is then unused"),
		OPT_DOUBLE(0, "aperture", &aperture, "MM", "[)", 0, INFINITY, NULL,
		           "thin-lens diameter in mm for depth of field (default 0: a "
		           "pinhole, everything sharp)"),
		OPT_DOUBLE(0, "focus", &focus, "MM", "()", 0, INFINITY, NULL,
		           "distance in mm along the view direction of the plane in "
		           "focus (default: from the camera to --look-at)"),
		OPT_STRING(0, "envmap", &env_path, "FILE.exr", "light the cloth with "
		           "this HDR environment map (latitude-longitude, R, G, B half or "
		           "float; row 0 straight up along +z; at most 4 Mi pixels, counted "
		           "in --budget); it replaces the grey studio sky and, unless "
		           "--sun is given, the sun"),
		OPT_DOUBLE(0, "env-rotate", &env_rot, "DEG", "()", -INFINITY, INFINITY,
		           "a finite number of degrees", "turn the map about the "
		           "vertical (default 0: column 0 towards +x, columns running "
		           "counter-clockwise towards +y)"),
		OPT_DOUBLE(0, "env-intensity", &env_k, "K", "[]", 0, 1e9, NULL,
		           "scale the map's radiance, %r (default 1)"),
		OPT_ENUM(0, "sky", &sky_grey, "SKY", sky_names, "without --envmap: "
		         "studio (default: a soft sky brighter at the zenith than at the "
		         "horizon over a dark floor, with a glow round the first sun; "
		         "importance-sampled like a map) or grey (a constant grey of "
		         "radiance 0.18, the sky before)"),
		OPT_CALLBACK(0, "light", &spheres, "X,Y,Z,R,I", opt_light, "a spherical "
		             "lamp (repeatable, up to 16): centre and radius in mm of the "
		             "cloth's frame (mesh units with --mesh) and intensity I, the "
		             "irradiance I / d^2 it gives at distance d mm; lamps light "
		             "the cloth but are not seen in the picture"),
		OPT_CALLBACK(0, "cloth-size", cloth_mm, "W[,H]", opt_size_mm, "flat "
		             "patch: a piece of cloth W x H mm (H = W when not given) "
		             "cut from the bolt at its origin instead of the endless "
		             "bolt, so its edges show; the camera frames the whole piece "
		             "with a margin unless --region is given"),
		OPT_FLAG(0, "ground", &ground, "a diffuse floor under the cloth that "
		         "catches its shadows (flat patch: at the slab's underside; "
		         "mesh: under its bounding box)"),
		OPT_DOUBLE(0, "ground-z", &ground_z, "MM", "()", -INFINITY, INFINITY,
		           "a finite number", "the floor's height in mm of the cloth's "
		           "frame (mesh units with --mesh) instead of the default"),
		OPT_CALLBACK(0, "ground-albedo", ground_alb, "A[,G,B]", opt_albedo,
		             "the floor's diffuse reflectance, grey or per channel, "
		             "each in [0, 1] (default 0.6)"),
		OPT_ENUM(0, "tone", &tone, "T", tone_names, "PNG: linear (default: "
		         "clip at 1) or filmic (an ACES-like curve with a soft "
		         "shoulder: highlights roll off instead of clipping; docs/"
		         "rendering.md)"),
		OPT_ENUM(0, "lod", &lod, "L", lod_names, "flat patch: level of detail: "
		         "off (default: full resolution everywhere) or auto (where a "
		         "pixel's footprint covers 2, 4 or 8 voxels, look up the 2x, "
		         "4x or 8x filtered exemplar: less noise at few samples, not fewer "
		         "lookups; the mean colour matches full resolution at grazing "
		         "views, steeper views render darker; docs/rendering.md)"),
		OPT_ENUM(0, "majorant", &global_mj, "M", majorant_names,
		         "flat patch: track through the per-crossing majorant grid "
		         "(default) or against one global bound (slower; for "
		         "comparison)"),
		OPT_ENUM(0, "sampler", &sampler, "S", sampler_names, "sobol (default: "
		         "Owen-scrambled Sobol points per pixel, less noise at the same "
		         "spp) or random (independent numbers per sample, the sampler "
		         "before)"),
		OPT_DOUBLE(0, "noise", &noise, "REL", "()", 0, 1, NULL, "adaptive "
		           "sampling: a pixel stops once the standard error of its "
		           "luminance is at most REL times its value, %r (e.g. 0.02; "
		           "tested from 16 samples on, every 8; --spp is the maximum)"),
		OPT_DOUBLE(0, "progressive", &prog_s, "SECONDS", "()", 0, 1e9, NULL,
		           "write the image so far to -o about every SECONDS while "
		           "rendering (the final image is the same)"),
		OPT_OUTPUT(&out, "OUT", ".png (8-bit sRGB) or .exr (linear float RGB "
		           "plus the AOV layers albedo, normal, Z and noise; docs/"
		           "rendering.md)"),
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
	                   opt_given(&cmd, warp_dir) || opt_given(&cmd, &field_smooth) ||
	                   opt_given(&cmd, &field_source)))
		opts_usage(&cmd, "--thickness, --uv-repeats, --uv-mm, --warp-dir, "
		           "--field-smooth and --warp-field go with --mesh");
	if (opt_given(&cmd, &uv_repeats) && opt_given(&cmd, uv_mm))
		opts_usage(&cmd, "--uv-repeats and --uv-mm both set the cloth's scale "
		           "on the UVs; give one");
	if (opt_given(&cmd, &ortho_w) && opt_given(&cmd, &aperture))
		opts_usage(&cmd, "--aperture is a lens of the perspective camera; it "
		           "does not go with --ortho");
	if (opt_given(&cmd, &focus) && !opt_given(&cmd, &aperture))
		opts_usage(&cmd, "--focus goes with --aperture");
	if (env_path && opt_given(&cmd, &sky_grey))
		opts_usage(&cmd, "--sky is the sky without --envmap; the map replaces it");
	if (!env_path && (opt_given(&cmd, &env_rot) || opt_given(&cmd, &env_k)))
		opts_usage(&cmd, "--env-rotate and --env-intensity go with --envmap");
	is_exr = cli_ends_with(out, ".exr");
	if (mesh_path && opt_given(&cmd, cloth_mm))
		opts_usage(&cmd, "--cloth-size cuts a flat patch; a mesh's UV layout "
		           "bounds its cloth");
	if (!ground && (opt_given(&cmd, &ground_z) || opt_given(&cmd, ground_alb)))
		opts_usage(&cmd, "--ground-z and --ground-albedo go with --ground");
	if (is_exr && opt_given(&cmd, &tone))
		opts_usage(&cmd, "--tone shapes a PNG; an .exr keeps linear radiance");
	cli_check_output(prog, out); /* before minutes of rendering */
	cli_diag_init(&diag, &quiet);
	budget = (size_t)(budget_mb * 1048576.0);
	if (env_path) {
		/* read before the texture: its bytes come out of --budget */
		loom_exr_image *ei = NULL;
		int ch[3];
		float *px = NULL;
		size_t n;
		if (loom_exr_read_max(env_path, LOOM_ENVMAP_MAX_PIXELS,
		                      (size_t)LOOM_ENVMAP_MAX_PIXELS * 16 + (1u << 20),
		                      &ei, &diag) != LOOM_OK)
			cli_fail(prog, "--envmap: %s", diag.message);
		ch[0] = loom_exr_image_channel(ei, "R");
		ch[1] = loom_exr_image_channel(ei, "G");
		ch[2] = loom_exr_image_channel(ei, "B");
		if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0) {
			char names[256] = "";
			for (uint32_t c = 0; c < ei->n_channels && strlen(names) < 200; c++)
				snprintf(names + strlen(names), sizeof names - strlen(names),
				         "%s%s", c ? "," : "", ei->names[c]);
			loom_exr_image_free(ei);
			cli_fail(prog, "%s: channels %s; an environment map needs R, G "
			         "and B (A and others are ignored)", env_path, names);
		}
		n = (size_t)ei->width * ei->height;
		env_bytes = loom_envmap_bytes(ei->width, ei->height);
		if (env_bytes >= budget) {
			loom_exr_image_free(ei);
			cli_error(prog, "--budget %g MiB cannot hold the environment map "
			          "%s (%zu bytes) and the texture", budget_mb, env_path,
			          env_bytes);
			return EXIT_BAD_INPUT;
		}
		px = malloc(3 * n * sizeof *px);
		if (!px) {
			loom_exr_image_free(ei);
			cli_fail(prog, "%s: out of memory", env_path);
		}
		for (size_t i = 0; i < n; i++)
			for (int c = 0; c < 3; c++)
				px[3 * i + c] = ei->data[(size_t)ch[c] * n + i];
		rc = loom_envmap_new(px, ei->width, ei->height, env_rot, env_k, &envmap,
		                     &diag);
		free(px);
		loom_exr_image_free(ei);
		if (rc != LOOM_OK)
			cli_fail(prog, "%s: %s", env_path, diag.message);
	} else if (!sky_grey) {
		/* the studio sky, built once the sun is known (below) */
		env_bytes = loom_envmap_bytes(LOOM_SKY_MAP_W, LOOM_SKY_MAP_H);
	}

	if (db_opt && loom_db_open(db_opt, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	if (cli_open_painted(path, db, &f, &paint, &diag) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	loom_fabric_get_db_identity(f, &id);
	loom_fabric_repeat_voxels(f, rep);
	if (!threads) /* all CPUs, resolved here so that the budget counts the
	                 majorant caches of the threads that run, not 64 */
		threads = cli_cpus();
	to.max_threads = threads;
	/* The majorant grid (flat patches) is counted in --budget: the texture
	   gets what it leaves. */
	if (!mesh_path && !global_mj && !paint) {
		/* refused before the build reads every block of the database */
		if (loom_majorant_size(f, to.max_threads, &mj_bytes, &diag) != LOOM_OK) {
			loom_fabric_free(f);
			loom_db_close(db);
			cli_fail(prog, "%s", diag.message);
		}
		if (mj_bytes + env_bytes >= budget) {
			cli_error(prog, "--budget %g MiB cannot hold the majorant grid (%zu "
			          "bytes) and the texture (or --majorant global)", budget_mb,
			          mj_bytes);
			loom_fabric_free(f);
			loom_db_close(db);
			return EXIT_BAD_INPUT;
		}
		if (loom_majorant_build(f, &mj, &diag) != LOOM_OK) {
			loom_fabric_free(f);
			loom_db_close(db);
			cli_fail(prog, "%s", diag.message);
		}
		mj_bytes = loom_majorant_bytes(mj, to.max_threads);
		if (mj_bytes + env_bytes >= budget) {
			cli_error(prog, "--budget %g MiB cannot hold the majorant grid (%zu "
			          "bytes) and the texture", budget_mb, mj_bytes);
			loom_majorant_free(mj);
			loom_fabric_free(f);
			loom_db_close(db);
			return EXIT_BAD_INPUT;
		}
	}
	to.budget_bytes = budget - mj_bytes - env_bytes;
	to.lod = lod && !paint && !mesh_path; /* flat, unpainted patches only */
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

	if (opt_given(&cmd, cloth_mm)) {
		/* a piece [0, W) x [0, H) mm of the bolt: the slab bounded */
		double vmm = src.voxel_mm > 0 ? src.voxel_mm : 0.024;
		for (int k = 0; k < 2; k++) {
			double n = floor(cloth_mm[k] / vmm + 0.5);
			if (n > 1e9) {
				cli_error(prog, "--cloth-size %g mm: at most 1e9 voxels of %g "
				          "mm across", cloth_mm[k], vmm);
				goto fail;
			}
			(k ? &src.ny : &src.nx)[0] = n > 1 ? (int64_t)n : 1;
		}
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
	if (mesh_path) {
		loom_shell_params sp = LOOM_SHELL_PARAMS_INIT;
		double blo[3], bhi[3], c[3], diag_len = 0, dist;
		if (loom_obj_read(mesh_path, &mesh, &diag) != LOOM_OK) {
			cli_error(prog, "%s", diag.message);
			goto fail;
		}
		if (mesh->n_triangles == 0) { /* also an empty file */
			cli_error(prog, "%s: no faces: expected 'f' lines (a mesh of "
			          "triangles or polygons; %u vertices read)", mesh_path,
			          mesh->n_positions);
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
		if (!(diag_len > 0)) { /* finite: faces need vertices */
			cli_error(prog, "%s: the mesh has no extent (all its vertices at "
			          "one point)", mesh_path);
			goto fail;
		}
		sp.thickness = thickness > 0 ? thickness : 0.015 * diag_len;
		sp.offset = -sp.thickness / 2;
		floor_scene = blo[2] - sp.thickness / 2; /* under the shell */
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
			field = !mesh->tri_vt || opt_given(&cmd, warp_dir) ||
			        opt_given(&cmd, &field_source);
			if (field) {
				loom_field_uv_params fp = LOOM_FIELD_UV_PARAMS_INIT;
				loom_mesh *fm = NULL;
				memcpy(fp.warp_dir, warp_dir, sizeof warp_dir);
				fp.uv_per_world = 1.0 / diag_len;
				fp.period[0] = per[0];
				fp.period[1] = per[1];
				fp.smooth_iters = field_smooth;
				fp.source = field_source;
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
		if (!opt_given(&cmd, box) && src.nx > 0) {
			/* the whole piece and a fifth of its size round it */
			int64_t m = (src.nx > src.ny ? src.nx : src.ny) / 5;
			lo[0] = lo[1] = -m;
			hi[0] = src.nx + m;
			hi[1] = src.ny + m;
		} else if (!opt_given(&cmd, box)) {
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
	/* The camera in the user's units (mm of the cloth's frame; mesh units
	   with a mesh): the --elevation/--azimuth camera is converted to them
	   and every camera goes back to scene units the same way, so a
	   --look-from/--look-at equal to it gives the same bytes. */
	unit = !mesh_path && src.voxel_mm > 0 ? src.voxel_mm : 1.0;
	{
		loom_camera *cam = &ro.camera;
		double e[3], a[3], fw[3], r[3], len = 0, rl = 0;
		for (int k = 0; k < 3; k++) {
			e[k] = cam->eye[k] * unit;
			a[k] = cam->target[k] * unit;
		}
		if (opt_given(&cmd, look_at)) {
			for (int k = 0; k < 3; k++) {
				e[k] += look_at[k] - a[k];
				a[k] = look_at[k];
			}
		}
		if (opt_given(&cmd, look_from)) {
			memcpy(e, look_from, sizeof e);
			if (e[0] != a[0] || e[1] != a[1])
				az = atan2(a[0] - e[0], a[1] - e[1]) * 180.0 / M_PI;
		}
		memcpy(look_from, e, sizeof e);
		memcpy(look_at, a, sizeof a);
		for (int k = 0; k < 3; k++) {
			fw[k] = a[k] - e[k];
			len += fw[k] * fw[k];
		}
		r[0] = fw[1] * cam_up[2] - fw[2] * cam_up[1];
		r[1] = fw[2] * cam_up[0] - fw[0] * cam_up[2];
		r[2] = fw[0] * cam_up[1] - fw[1] * cam_up[0];
		rl = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
		if (!(len > 0)) {
			cli_error(prog, "--look-from and --look-at are the same point");
			goto fail;
		}
		if (!(rl > 1e-18 * len * (cam_up[0] * cam_up[0] + cam_up[1] * cam_up[1] +
		                          cam_up[2] * cam_up[2]))) {
			cli_error(prog, "--up (%g,%g,%g) is zero or along the view direction",
			          cam_up[0], cam_up[1], cam_up[2]);
			goto fail;
		}
		for (int k = 0; k < 3; k++) {
			cam->eye[k] = e[k] / unit;
			cam->target[k] = a[k] / unit;
			cam->up[k] = cam_up[k];
		}
		if (ortho_w > 0) {
			cam->kind = LOOM_CAMERA_ORTHO;
			cam->ortho_size[0] = ortho_w / unit;
			cam->ortho_size[1] = ortho_w / unit * height / width;
		}
		cam->aperture = aperture / unit;
		cam->focus_dist = focus / unit;
	}
	/* Suns: towards the light = where a camera at (AZ, EL) would stand
	   (see place_camera).  The studio default (no --sun, --light or
	   --envmap) stands 150 degrees round from the camera, so the cloth is
	   lit from the far side at a raking angle (yarn relief and sheen),
	   never flat from behind the viewer; with --look-from, round from that
	   camera's azimuth.  The first sun is ro.light, the others and the
	   lamps ro.lights. */
	if (suns.n == 0 && spheres.n == 0 && !env_path) {
		suns.v[0][0] = az + 150.0;
		suns.v[0][1] = 35.0;
		suns.v[0][2] = 2.6;
		suns.v[0][3] = 0.53;
		suns.n = 1;
	}
	ro.light.kind = LOOM_LIGHT_NONE;
	for (int k = 0; k < suns.n + spheres.n; k++) {
		loom_light *l = k == 0 ? &ro.light : &extra[k - 1];
		memset(l, 0, sizeof *l);
		if (k < suns.n) {
			const double *v = suns.v[k];
			l->kind = LOOM_LIGHT_DISTANT;
			l->dir[0] = -sin(v[0] * M_PI / 180.0) * cos(v[1] * M_PI / 180.0);
			l->dir[1] = -cos(v[0] * M_PI / 180.0) * cos(v[1] * M_PI / 180.0);
			l->dir[2] = sin(v[1] * M_PI / 180.0);
			l->rgb[0] = l->rgb[1] = l->rgb[2] = (float)v[2];
			l->angle_deg = v[3];
		} else {
			const double *v = spheres.v[k - suns.n];
			l->kind = LOOM_LIGHT_SPHERE;
			for (int j = 0; j < 3; j++)
				l->pos[j] = v[j] / unit;
			l->radius = v[3] / unit;
			l->rgb[0] = l->rgb[1] = l->rgb[2] = (float)(v[4] / (unit * unit));
		}
	}
	if (suns.n + spheres.n > 1) {
		ro.lights = extra;
		ro.n_lights = (uint32_t)(suns.n + spheres.n - 1);
	}
	ro.env[0] = ro.env[1] = ro.env[2] = 0.18f;
	if (!env_path && !sky_grey) {
		/* the studio sky, its glow round the first sun (or where the
		   studio sun would stand when only lamps are given) */
		double sd[3], sa = suns.n ? suns.v[0][0] : az + 150.0;
		double se = suns.n ? suns.v[0][1] : 35.0;
		float *px = malloc((size_t)3 * LOOM_SKY_MAP_W * LOOM_SKY_MAP_H * sizeof *px);
		sd[0] = -sin(sa * M_PI / 180.0) * cos(se * M_PI / 180.0);
		sd[1] = -cos(sa * M_PI / 180.0) * cos(se * M_PI / 180.0);
		sd[2] = sin(se * M_PI / 180.0);
		rc = px ? loom_sky_studio_map(sd, LOOM_SKY_MAP_W, LOOM_SKY_MAP_H, px)
		        : LOOM_ENOMEM;
		if (rc == LOOM_OK)
			rc = loom_envmap_new(px, LOOM_SKY_MAP_W, LOOM_SKY_MAP_H, 0.0, 1.0,
			                     &envmap, &diag);
		free(px);
		if (rc != LOOM_OK) {
			cli_error(prog, "studio sky: %s", loom_strerror(rc));
			goto fail;
		}
	}
	ro.envmap = envmap;
	if (ground) {
		ro.ground.enabled = 1;
		ro.ground.height = opt_given(&cmd, &ground_z) ? ground_z / unit : floor_scene;
		for (int k = 0; k < 3; k++)
			ro.ground.albedo[k] = (float)ground_alb[k];
	}
	if (is_exr) {
		/* AOVs: albedo 3, normal 3, depth 1, noise 3 */
		size_t npx = (size_t)width * height;
		aovbuf = malloc(npx * 10 * sizeof *aovbuf);
		if (!aovbuf) {
			cli_error(prog, "out of memory for the AOVs of a %ux%u image",
			          width, height);
			goto fail;
		}
		aov.albedo = aovbuf;
		aov.normal = aovbuf + 3 * npx;
		aov.depth = aovbuf + 6 * npx;
		aov.noise = aovbuf + 7 * npx;
		ro.aov = &aov;
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
	ro.sampler = (uint32_t)sampler;
	ro.noise = noise;
	if (prog_s > 0) {
		pw.out = out;
		pw.width = width;
		pw.height = height;
		pw.exposure = exposure;
		pw.unit = unit;
		pw.tone = tone;
		pw.is_exr = is_exr;
		pw.aov = &aov;
		ro.progressive_seconds = prog_s;
		ro.progressive = progressive_cb;
		ro.progressive_user = &pw;
	}
	rc = loom_render(&src, &ro, rgb, &st, &diag);
	cli_progress_end(&pr.p);
	pthread_mutex_destroy(&pr.lock);
	if (rc != LOOM_OK) {
		cli_error(prog, "%s", diag.message[0] ? diag.message : loom_strerror(rc));
		goto fail;
	}
	if ((is_exr ? write_exr_aov(out, rgb, &aov, width, height, unit, &diag)
	            : write_png_tone(out, rgb, width, height, exposure, tone,
	                             &diag)) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto fail;
	}
	loom_texture_get_stats(t, &ts);
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_str(&w, "output", out);
		jw_uint(&w, "width", width);
		jw_uint(&w, "height", height);
		jw_uint(&w, "spp", spp);
		jw_str(&w, "sampler", sampler == LOOM_SAMPLER_SOBOL ? "sobol" : "random");
		jw_num(&w, "noise", noise);
		jw_num(&w, "mean_spp", (double)st.paths / ((double)width * height));
		jw_uint(&w, "progressive_writes", pw.writes);
		jw_uint(&w, "seed", seed);
		jw_str(&w, "scene", mesh_path ? "mesh" : "flat");
		jw_num(&w, "voxel_mm", src.voxel_mm);
		jw_num(&w, "density_per_voxel", ro.density_scale);
		jw_uint(&w, "paths", st.paths);
		jw_uint(&w, "rays", st.rays);
		jw_uint(&w, "lookups", st.lookups);
		jw_uint(&w, "lod_levels", loom_texture_lod_levels(t));
		jw_uint(&w, "scatterings", st.scatterings);
		jw_uint(&w, "shell_queries", st.shell_queries);
		if (have_uv_stats) {
			jw_obj(&w, "uv");
			jw_str(&w, "source", !field ? "mesh" :
			       field_source == LOOM_FIELD_CURVATURE_MAX ? "field curvature-max" :
			       field_source == LOOM_FIELD_CURVATURE_MIN ? "field curvature-min" :
			       "field");
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
		{
			char buf[3][96];
			const double *v[3] = {look_from, look_at, cam_up};
			for (int k = 0; k < 3; k++)
				snprintf(buf[k], sizeof buf[k], "%.17g,%.17g,%.17g", v[k][0],
				         v[k][1], v[k][2]);
			jw_obj(&w, "camera");
			jw_str(&w, "kind", ortho_w > 0 ? "ortho" : "perspective");
			jw_str(&w, "units", mesh_path ? "mesh" : "mm");
			jw_str(&w, "look_from", buf[0]);
			jw_str(&w, "look_at", buf[1]);
			jw_str(&w, "up", buf[2]);
			jw_close(&w);
		}
		jw_uint(&w, "cells", st.cells);
		jw_str(&w, "majorant", mj ? "grid" : "global");
		jw_uint(&w, "majorant_bytes", mj_bytes);
		jw_uint(&w, "envmap_bytes", env_bytes);
		jw_str(&w, "sky", env_path ? "envmap" : sky_grey ? "grey" : "studio");
		jw_str(&w, "tone", is_exr ? "none" : tone == LOOM_TONE_FILMIC ? "filmic"
		                                                           : "linear");
		if (ground)
			jw_num(&w, "ground_z", ro.ground.height * unit);
		if (src.nx > 0) {
			jw_num(&w, "cloth_w_mm", (double)src.nx * unit);
			jw_num(&w, "cloth_h_mm", (double)src.ny * unit);
		}
		jw_num(&w, "seconds", st.seconds);
		/* the brick cache since the texture was opened (the majorant's
		   build included): whether --budget held what the picture read */
		jw_obj(&w, "texture");
		jw_texture_stats(&w, &ts);
		jw_close(&w);
		jw_end(&w);
	} else if (!quiet) {
		fprintf(stderr, "loom render: %s: %ux%u, %u spp in %.2f s (%.0f paths/s, "
		        "%llu lookups)\n", out, width, height, spp, st.seconds,
		        st.seconds > 0 ? (double)st.paths / st.seconds : 0.0,
		        (unsigned long long)st.lookups);
		fprintf(stderr, "  bricks: hit rate %.4f, %llu misses, %llu evictions, %.1f MiB "
		        "read, %.2f s decompressing (budget %.0f MiB)\n", cli_hit_rate(&ts),
		        (unsigned long long)ts.misses, (unsigned long long)ts.evictions,
		        (double)ts.bytes_read / 1048576.0, (double)ts.decompress_ns * 1e-9,
		        (double)ts.budget_bytes / 1048576.0);
	}
	free(rgb);
	free(aovbuf);
	loom_shell_free(shell);
	loom_mesh_free(mesh);
	loom_texture_close(t);
	loom_paint_free(paint);
	loom_majorant_free(mj);
	loom_fabric_free(f);
	loom_db_close(db);
	loom_envmap_free(envmap);
	return 0;
fail:
	free(rgb);
	free(aovbuf);
	loom_shell_free(shell);
	loom_mesh_free(mesh);
	loom_texture_close(t);
	loom_paint_free(paint);
	loom_majorant_free(mj);
	loom_fabric_free(f);
	loom_db_close(db);
	loom_envmap_free(envmap);
	return EXIT_BAD_INPUT;
}
