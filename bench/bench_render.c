/* bench/bench_render.c - figures of the volume path tracer and the shell
   mapper (engine/render/render.c, engine/render/shell.c, docs/rendering.md).

   Source: a procedural plain weave of elliptical yarn tubes (period 16
   voxels, tubes 12 x 5 voxels, slab 12 voxels thick) with sinusoidal
   crimp; density 1 inside a tube, fibre direction = the tube's tangent,
   warp and weft albedos differ.  The lookup is a pure function (no cache),
   so the figures are the tracer's own cost; a real engine lookup adds its
   brick-cache time per lookup (see bench_cache).

   Cases (each at 1 and 2 threads):
     top     orthographic preview from above, 128 x 128, 8 spp
     persp   pinhole view at 45 degrees, 128 x 96, 8 spp
     shell   the same cloth mapped onto tests/data/meshes/cylinder.obj,
             pinhole, 96 x 96, 4 spp
   Figures: camera samples (paths) per second, rays per second (camera,
   scattered and shadow rays), lookups per second.
   Closest-point queries: loom_shell_world_to_voxel (one Embree
   rtcPointQuery each, no hint) on random points inside the shell of the
   cylinder (192 triangles) and of a generated 64k-triangle cylinder, and
   the time loom_shell_new takes to build each shell.
   Fabric: the engine's texture of a twill on the default database with
   the majorant grid and with the global majorant (bench_fabric below).
   Output: a table on stdout and one JSON line per figure ("{...}").
   BENCH_RENDER_SCALE=0.25 shortens every run; BENCH_RENDER_PNG=dir writes
   the images as PNG. */
#include "loom.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_render\n"
	"The path tracer and shell mapper: paths, rays and lookups per second on a\n"
	"procedural weave (top, perspective, mapped on a cylinder; 1 and 2\n"
	"threads), closest-point queries, and the engine's texture with the\n"
	"majorant grid against the global majorant.\n"
	"Environment: BENCH_RENDER_SCALE=F (0.25: short), BENCH_RENDER_PNG=DIR\n"
	"(write the pictures), BUILD, LOOM_TOP (the source tree, for the meshes).\n";

static double g_scale = 1.0;

#define PERIOD 16.0
#define NZ 12

/* One family of tubes: centre line at x = (j + 0.5) P, z = zc(y). */
static double tube(double across, double along, int parity, double *dz_dalong,
                   double *zc, long *index)
{
	long j = (long)floor(across / PERIOD);
	double dx = across - (j + 0.5) * PERIOD;
	double ph = M_PI * along / PERIOD + (((j + parity) & 1) ? M_PI : 0.0);
	*zc = 6.0 + 2.0 * sin(ph);
	*dz_dalong = 2.0 * M_PI / PERIOD * cos(ph);
	*index = j;
	return dx / 6.0; /* normalised half-width 6 */
}

static int weave_lookup(void *ctx, const double p[3], loom_medium_sample *o)
{
	double dzw, zw, dzf, zf, ex_w, ex_f, rw, rf;
	long jw, jf;
	(void)ctx;

	/* warps run along y (across = x), wefts along x (across = y) with the
	   opposite crimp, so each passes over and under the other */
	ex_w = tube(p[0], p[1], 0, &dzw, &zw, &jw);
	ex_f = tube(p[1], p[0], 1, &dzf, &zf, &jf);
	rw = ex_w * ex_w + (p[2] - zw) * (p[2] - zw) / 6.25;
	rf = ex_f * ex_f + (p[2] - zf) * (p[2] - zf) / 6.25;
	o->alignment = 0.0f; /* the options' default */
	if (rw < 1.0 && rw <= rf) {
		o->density = 1.0f;
		o->orient[0] = 0.0f;
		o->orient[1] = 1.0f;
		o->orient[2] = (float)dzw;
		o->albedo[0] = 0.85f;
		o->albedo[1] = 0.35f;
		o->albedo[2] = 0.2f;
	} else if (rf < 1.0) {
		o->density = 1.0f;
		o->orient[0] = 1.0f;
		o->orient[1] = 0.0f;
		o->orient[2] = (float)dzf;
		o->albedo[0] = 0.3f;
		o->albedo[1] = 0.55f;
		o->albedo[2] = 0.85f;
	} else {
		o->density = 0.0f;
	}
	return 0;
}

static void write_png(const char *name, const float *rgb, uint32_t w, uint32_t h)
{
	const char *dir = getenv("BENCH_RENDER_PNG");
	loom_image *img = NULL;
	char path[1024];

	if (!dir || loom_image_new(w, h, 3, &img) != LOOM_OK)
		return;
	loom_render_to_srgb8(rgb, (size_t)w * h, 0.0, img->pixels);
	snprintf(path, sizeof path, "%s/%s.png", dir, name);
	if (loom_image_write(path, img, NULL) == LOOM_OK)
		fprintf(stderr, "wrote %s\n", path);
	loom_image_free(img);
}

static void run_case(const char *name, const loom_volume_source *src,
                     loom_render_options *o)
{
	float *rgb = malloc((size_t)o->width * o->height * 3 * sizeof *rgb);
	loom_diag d;

	memset(&d, 0, sizeof d);
	for (uint32_t th = 1; th <= 2; th++) {
		loom_render_stats st;
		o->threads = th;
		if (loom_render(src, o, rgb, &st, &d) != LOOM_OK) {
			fprintf(stderr, "bench_render: %s\n", d.message);
			break;
		}
		printf("%-6s %4ux%-4u %4u %7u %10.3f %10.3f %10.3f %10.3f %8.2f\n", name,
		       o->width, o->height, o->spp, th, st.paths / st.seconds * 1e-3,
		       st.rays / st.seconds * 1e-6, st.lookups / st.seconds * 1e-6,
		       (double)st.lookups / st.paths, st.seconds);
		printf("{\"bench\":\"render\",\"case\":\"%s\",\"width\":%u,\"height\":%u,"
		       "\"spp\":%u,\"threads\":%u,\"paths_per_s\":%.1f,\"rays_per_s\":%.1f,"
		       "\"lookups_per_s\":%.1f,\"shell_queries\":%llu,\"seconds\":%.4f}\n",
		       name, o->width, o->height, o->spp, th, st.paths / st.seconds,
		       st.rays / st.seconds, st.lookups / st.seconds,
		       (unsigned long long)st.shell_queries, st.seconds);
		if (th == 2)
			write_png(name, rgb, o->width, o->height);
	}
	free(rgb);
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A cylinder patch of nt x ny quads (radius 32, 120 degrees, length 48). */
static loom_mesh *grid_cylinder(uint32_t nt, uint32_t ny)
{
	size_t nv = (size_t)(nt + 1) * (ny + 1), len = 0, cap = 64 * nv + 64 * nt * ny;
	char *txt = malloc(cap);
	loom_mesh *m = NULL;

	for (uint32_t j = 0; j <= ny; j++)
		for (uint32_t i = 0; i <= nt; i++) {
			double t = (-60.0 + 120.0 * i / nt) * M_PI / 180.0, y = 48.0 * j / ny;
			len += (size_t)snprintf(txt + len, cap - len, "v %.9g %.9g %.9g\nvt %.9g %.9g\n",
			                        32 * sin(t), y, 32 * cos(t),
			                        32 * (t + M_PI / 3) / 64, y / 64);
		}
	for (uint32_t j = 0; j < ny; j++)
		for (uint32_t i = 0; i < nt; i++) {
			size_t a = (size_t)j * (nt + 1) + i + 1, b = a + 1, c = a + nt + 2,
			       d = a + nt + 1;
			len += (size_t)snprintf(txt + len, cap - len,
			                        "f %zu/%zu %zu/%zu %zu/%zu %zu/%zu\n", a, a, b,
			                        b, c, c, d, d);
		}
	if (loom_obj_parse(txt, len, "grid", &m, NULL) != LOOM_OK)
		m = NULL;
	free(txt);
	return m;
}

static void bench_queries(const char *name, const loom_mesh *m)
{
	loom_shell_params p = LOOM_SHELL_PARAMS_INIT;
	loom_shell *s = NULL;
	size_t n = (size_t)(400000 * g_scale) + 1000, found = 0;
	double *pts, t0, dt, sum = 0, build;
	uint64_t rng = 11;

	p.thickness = 2.0;
	p.voxels_per_uv = 64;
	p.nz = NZ;
	t0 = now_s();
	if (loom_shell_new(m, &p, &s, NULL) != LOOM_OK)
		return;
	build = now_s() - t0;
	pts = malloc(n * 3 * sizeof *pts);
	for (size_t k = 0; k < n; k++) { /* inside the shell's outer cylinder */
		double t = (-58.0 + 116.0 * loom_rng_uniform(&rng)) * M_PI / 180.0;
		double r = 32.0 + 2.0 * loom_rng_uniform(&rng);
		pts[3 * k] = r * sin(t);
		pts[3 * k + 1] = 1.0 + 46.0 * loom_rng_uniform(&rng);
		pts[3 * k + 2] = r * cos(t);
	}
	t0 = now_s();
	for (size_t k = 0; k < n; k++) {
		double v[3];
		if (loom_shell_world_to_voxel(s, pts + 3 * k, v, NULL) == LOOM_OK) {
			found++;
			sum += v[2];
		}
	}
	dt = now_s() - t0;
	printf("%-22s %9u %9.1f %9zu %7.4f %10.3f\n", name,
	       loom_shell_triangle_count(s), build * 1e3, n, (double)found / n,
	       n / dt * 1e-6);
	printf("{\"bench\":\"render\",\"case\":\"closest_point\",\"mesh\":\"%s\","
	       "\"triangles\":%u,\"build_s\":%.5f,\"queries\":%zu,\"inside\":%zu,"
	       "\"queries_per_s\":%.1f,\"check\":%.6g}\n", name,
	       loom_shell_triangle_count(s), build, n, found, n / dt, sum);
	free(pts);
	loom_shell_free(s);
}

/*
 * The engine's own fabric: a 2/3 twill of 10 x 10 crossings synthesized on
 * the default database ($BUILD/share/loom/default.ldb, 24 x 16 x 48 voxel
 * blocks), the same view at 35 and 12 degrees elevation, rendered with the
 * majorant grid and with the single global majorant, 2 threads.  Figures:
 * lookups per path, microseconds per pixel-sample (wall time / paths, both
 * threads busy) and the ratio global / grid.
 */
static void bench_fabric(void)
{
	const char *build = getenv("BUILD");
	char path[1024];
	loom_db *db = NULL;
	loom_design *d = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_majorant *m = NULL;
	loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
	loom_volume_source grid, glob;
	loom_render_options o = LOOM_RENDER_OPTIONS_INIT;
	const double els[2] = {35.0, 12.0};
	float *rgb;

	snprintf(path, sizeof path, "%s/share/loom/default.ldb", build ? build : "build");
	if (loom_db_open(path, &db, NULL) != LOOM_OK) {
		printf("\n(fabric case skipped: cannot open %s)\n", path);
		return;
	}
	if (loom_design_new(10, 10, &d) != LOOM_OK)
		goto done;
	for (uint32_t i = 0; i < 10; i++)
		for (uint32_t j = 0; j < 10; j++)
			d->weave[i * 10 + j] = (uint8_t)((j + 10 - i) % 5 < 2);
	to.budget_bytes = (size_t)64 << 20;
	if (loom_fabric_synthesize(d, db, path, NULL, &f, NULL) != LOOM_OK ||
	    loom_texture_open(f, db, &to, &t, NULL) != LOOM_OK ||
	    loom_majorant_build(f, &m, NULL) != LOOM_OK)
		goto done;
	loom_texture_volume_source_grid(t, f, LOOM_FILTER_NEAREST, m, &grid);
	loom_texture_volume_source(t, f, LOOM_FILTER_NEAREST, &glob);
	o.width = 160;
	o.height = 100;
	o.spp = (uint32_t)(4 * g_scale) + 1;
	o.threads = 2;
	o.density_scale = 2.0;
	o.max_depth = 32;
	o.light.dir[0] = -0.35;
	o.light.dir[1] = -0.45;
	o.light.dir[2] = 1.0;
	o.env[0] = o.env[1] = o.env[2] = 0.18f;
	rgb = malloc((size_t)o.width * o.height * 3 * sizeof *rgb);
	printf("\nfabric: twill 2/3 on the default database, %ux%u, %u spp, 2 threads "
	       "(majorant grid %zu bytes)\n", o.width, o.height, o.spp,
	       loom_majorant_bytes(m, 2));
	printf("%-6s %-8s %10s %10s %10s %8s\n", "elev", "majorant", "lookup/pth",
	       "cells/pth", "us/sample", "seconds");
	for (int e = 0; rgb && e < 2; e++) {
		double el = els[e] * M_PI / 180.0, us[2] = {0, 0}, lk[2] = {0, 0};
		o.camera.kind = LOOM_CAMERA_PINHOLE;
		o.camera.target[0] = 120;
		o.camera.target[1] = 80;
		o.camera.target[2] = 24;
		o.camera.eye[0] = 120;
		o.camera.eye[1] = 80 - 420 * cos(el);
		o.camera.eye[2] = 24 + 420 * sin(el);
		o.camera.up[0] = o.camera.up[1] = 0;
		o.camera.up[2] = 1;
		o.camera.fov_y_deg = 30;
		for (int v = 0; v < 2; v++) {
			loom_render_stats st;
			o.flags = v ? LOOM_RENDER_GLOBAL_MAJORANT : 0;
			if (loom_render(v ? &glob : &grid, &o, rgb, &st, NULL) != LOOM_OK)
				break;
			us[v] = st.seconds / (double)st.paths * 1e6;
			lk[v] = (double)st.lookups / (double)st.paths;
			printf("%-6.0f %-8s %10.1f %10.1f %10.2f %8.2f\n", els[e],
			       v ? "global" : "grid", lk[v], (double)st.cells / (double)st.paths,
			       us[v], st.seconds);
			printf("{\"bench\":\"render\",\"case\":\"fabric\",\"elevation\":%.0f,"
			       "\"majorant\":\"%s\",\"lookups_per_path\":%.2f,\"cells_per_path\":"
			       "%.2f,\"us_per_sample\":%.3f,\"seconds\":%.4f}\n", els[e],
			       v ? "global" : "grid", lk[v], (double)st.cells / (double)st.paths,
			       us[v], st.seconds);
			if (v == 0 && e == 0)
				write_png("fabric35", rgb, o.width, o.height);
		}
		if (us[0] > 0 && lk[0] > 0)
			printf("       global/grid: lookups %.2fx, time %.2fx\n", lk[1] / lk[0],
			       us[1] / us[0]);
	}
	free(rgb);
done:
	loom_majorant_free(m);
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_design_free(d);
	loom_db_close(db);
}

int main(int argc, char **argv)
{
	loom_volume_source src = LOOM_VOLUME_SOURCE_INIT;
	loom_render_options o = LOOM_RENDER_OPTIONS_INIT;
	const char *sc = getenv("BENCH_RENDER_SCALE");
	const char *top = getenv("LOOM_TOP");
	char path[1024];
	loom_mesh *cyl = NULL, *fine;

	bench_help(argc, argv, USAGE);
	if (argc > 1)
		bench_reject("bench_render", argv[1], USAGE);
	if (sc && atof(sc) > 0)
		g_scale = atof(sc);
	src.nz = NZ;
	src.voxel_mm = 0.005;
	src.lookup = weave_lookup;

	o.density_scale = 4.0;
	o.alignment = 0.2;
	o.max_depth = 32;
	o.light.kind = LOOM_LIGHT_DISTANT;
	o.light.dir[0] = -0.4;
	o.light.dir[1] = 0.3;
	o.light.dir[2] = 1.0;
	o.env[0] = o.env[1] = o.env[2] = 0.15f;

	printf("volume path tracer, procedural plain weave (lookup = pure function)\n");
	printf("%-6s %9s %4s %7s %10s %10s %10s %10s %8s\n", "case", "image", "spp",
	       "threads", "kpaths/s", "Mrays/s", "Mlookup/s", "lookup/pth", "seconds");

	o.width = 128;
	o.height = 128;
	o.spp = (uint32_t)(8 * g_scale) + 1;
	loom_camera_top(&src, 0, 0, 128, 128, &o.camera);
	run_case("top", &src, &o);

	o.width = 128;
	o.height = 96;
	o.camera.kind = LOOM_CAMERA_PINHOLE;
	o.camera.eye[0] = 64;
	o.camera.eye[1] = -40;
	o.camera.eye[2] = 110;
	o.camera.target[0] = 64;
	o.camera.target[1] = 64;
	o.camera.target[2] = 6;
	o.camera.up[0] = 0;
	o.camera.up[1] = 0;
	o.camera.up[2] = 1;
	o.camera.fov_y_deg = 50;
	run_case("persp", &src, &o);

	snprintf(path, sizeof path, "%s/tests/data/meshes/cylinder.obj", top ? top : ".");
	if (loom_obj_read(path, &cyl, NULL) == LOOM_OK) {
		loom_shell_params p = LOOM_SHELL_PARAMS_INIT;
		loom_shell *s = NULL;
		p.thickness = 2.0; /* 12 voxels over 2 world units */
		p.voxels_per_uv = 6.0 * 64.0;
		p.nz = NZ;
		if (loom_shell_new(cyl, &p, &s, NULL) == LOOM_OK) {
			o.shell = s;
			o.width = 96;
			o.height = 96;
			o.spp = (uint32_t)(4 * g_scale) + 1;
			o.camera.eye[0] = 0;
			o.camera.eye[1] = -40;
			o.camera.eye[2] = 80;
			o.camera.target[0] = 0;
			o.camera.target[1] = 24;
			o.camera.target[2] = 28;
			o.camera.fov_y_deg = 45;
			o.light.dir[0] = 0.3;
			o.light.dir[1] = -0.5;
			o.light.dir[2] = 1.0;
			run_case("shell", &src, &o);
			loom_shell_free(s);
			o.shell = NULL;
		}
	} else {
		printf("(shell case skipped: cannot read %s)\n", path);
	}

	printf("\nclosest-point queries (loom_shell_world_to_voxel, no hint), 1 thread\n");
	printf("%-22s %9s %9s %9s %7s %10s\n", "mesh", "triangles", "build ms",
	       "queries", "inside", "Mquery/s");
	if (cyl)
		bench_queries("cylinder.obj", cyl);
	fine = grid_cylinder(256, 128);
	if (fine)
		bench_queries("cylinder 256x128 quads", fine);
	loom_mesh_free(fine);
	loom_mesh_free(cyl);
	bench_fabric();
	return 0;
}
