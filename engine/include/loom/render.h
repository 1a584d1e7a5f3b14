/*
 * loom/render.h - rendering the cloth volume (paper section 7): the
 * microflake phase function (Jakob et al. 2010, fibre distribution of Zhao
 * et al. 2011), a volume path tracer over an abstract voxel source, shell
 * mapping of the flat volume onto a mesh (Porumbescu et al. 2005), and the
 * Wavefront OBJ meshes it maps onto.  Include <loom.h>, not this file.
 * docs/rendering.md explains the model, the estimators and the figures.
 *
 * Conventions.
 *  - Voxel space: x across the ends, y along the warps, z up through the
 *    cloth (DESIGN.md).  Voxel (i, j, k) covers [i, i+1) x [j, j+1) x
 *    [k, k+1); coordinates are continuous doubles.
 *  - Directions are unit double[3] unless said otherwise.  A fibre
 *    orientation is a line direction: v and -v mean the same.
 *  - Images are float RGB, row 0 at the top, linear radiance.
 *  - Nothing here keeps global mutable state; the microflake tables are
 *    built once (pthread_once) and only read afterwards.
 */
#ifndef LOOM_RENDER_H
#define LOOM_RENDER_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ======================================================================
 * Microflake phase function (fibre distribution)
 * ======================================================================
 *
 * Flake normals m are distributed around the plane normal to the fibre
 * direction w:   D(m) = C(s) exp(-(m.w)^2 / (2 s^2)),  integral over the
 * sphere = 1.  s ("sigma", loom_yarn_type.alignment) is the roughness:
 * small s = flakes tightly normal to the fibre = glossy, hair-like fibres.
 *
 * Projected area  sigma(omega) = integral |omega.m| D(m) dm;  the code uses
 * A(omega) = 2 sigma(omega), which is 1 for an isotropic medium, so that
 * extinction is  mu_t(omega) = density * density_scale * A(omega).
 * A depends only on |omega.w| and s; it is smallest along the fibre and
 * largest across it (4/pi as s -> 0).
 *
 * Phase function of specular flakes (both directions point away from the
 * scattering point; wi towards where the path came from, wo the new one):
 *     f(wi -> wo) = D(h) / (2 sigma(wi)),   h = (wi + wo) / |wi + wo|
 * (each flake side reflects D(h) / (4 sigma); flakes are two-sided, D is
 * even), and the integral over wo is 1.
 */
#define LOOM_MF_SIGMA_MIN 0.005 /* s below this is clamped */
#define LOOM_MF_SIGMA_MAX 1.0   /* s above this is clamped */

/* D(m) for cos_theta = m.w; exact (closed-form normalisation).  s is
   clamped to [LOOM_MF_SIGMA_MIN, LOOM_MF_SIGMA_MAX].  Thread-safe. */
LOOM_API double loom_microflake_D(double s, double cos_theta);

/* A(omega) = 2 sigma(omega) for cos_w = omega.w (sign ignored), from the
   tables (bilinear in log s and the angle; relative error below 1e-3).
   Thread-safe. */
LOOM_API double loom_microflake_area(double s, double cos_w);

/* The same by direct quadrature (slow; for tests and tables). */
LOOM_API double loom_microflake_area_exact(double s, double cos_w);

/* Largest A over every s and direction (the majorant factor, about 4/pi). */
LOOM_API double loom_microflake_area_max(void);

/* Phase function value f(wi -> wo) (per steradian) for fibre direction w
   (need not be unit; a zero w means isotropic: 1/(4 pi)).  Thread-safe. */
LOOM_API double loom_microflake_eval(double s, const double w[3],
                                     const double wi[3], const double wo[3]);

/*
 * Sample wo with density f(wi -> wo): a flake normal is drawn with density
 * proportional to |wi.m| D(m) by rejection from a proposal that bounds it
 * (mixture of |m.w| D and |cos phi| D, both sampled exactly), then wi is
 * mirrored about it.  Unbiased; expected proposals per sample <= about 1.5.
 * rng is a 64-bit state advanced by splitmix64 (any value to start).
 * The sample's weight f/pdf is exactly 1.  Thread-safe.
 */
LOOM_API void loom_microflake_sample(double s, const double w[3],
                                     const double wi[3], uint64_t *rng,
                                     double wo[3]);

/* Uniform double in [0, 1) from the splitmix64 stream *rng. */
LOOM_API double loom_rng_uniform(uint64_t *rng);

/* ======================================================================
 * Volume source (what the renderer looks up)
 * ====================================================================== */

/* One looked-up voxel. */
typedef struct loom_medium_sample {
	float density;    /* in [0, source max_density]; 0 = empty */
	float orient[3];  /* fibre direction in voxel axes (a line); need not be
	                     unit; all zero = no fibre (isotropic scattering) */
	float albedo[3];  /* single-scattering albedo, linear RGB in [0, 1] */
	float alignment;  /* microflake s of this voxel (the yarn type's
	                     alignment); <= 0 = the render options' default */
	float spread;     /* extra variance of the flake normals' m.w from
	                     fibres averaged in a coarse voxel (level of detail,
	                     loom_texture_sample_lod); the lobe used is
	                     s' = sqrt(s^2 + spread).  0 = none */
} loom_medium_sample;

/*
 * Lookup callback: fill *out for voxel-space point p (nearest or trilinear,
 * the source's choice).  Called from several render threads at once: it
 * must be thread-safe (ctx is the source's ctx, or the thread's own state
 * when the source has a thread_init hook).  Only called for p inside the slab
 * [0,nx) x [0,ny) x [0,nz) (any x, y when unbounded).  Return 0, or a
 * loom_result code to abort the render with it.
 */
typedef int (*loom_lookup_fn)(void *ctx, const double p[3],
                              loom_medium_sample *out);
/* Lookup with the ray's footprint: the width in voxels of the camera
   pixel's cone where p is (after the first scattering, the width there).
   Same rules as loom_lookup_fn. */
typedef int (*loom_lookup_lod_fn)(void *ctx, const double p[3], double footprint,
                                  loom_medium_sample *out);

typedef struct loom_volume_source {
	size_t size;          /* sizeof(loom_volume_source) */
	int64_t nx, ny;       /* extent along x, y in voxels; 0 = unbounded */
	int64_t nz;           /* thickness along z (b3) in voxels, > 0 */
	double voxel_mm;      /* voxel edge in mm (0.005 at the paper's scale);
	                         informational, docs and callers use it */
	float max_density;    /* upper bound of density anywhere; 0 = 1.0.  A
	                         lookup above it is clamped (and biased) */
	loom_lookup_fn lookup;
	void *ctx;            /* passed to lookup (and the thread hooks) */
	void *(*thread_init)(void *ctx);
	                      /* optional: called once in each render thread
	                         before its first lookup; the pointer it returns
	                         is what that thread's lookups get as ctx (e.g.
	                         a per-thread decompressor or cache handle).
	                         NULL = failure: the render stops, LOOM_ENOMEM */
	void (*thread_done)(void *ctx, void *thread_ctx);
	                      /* optional: called when that thread ends */
	int64_t cell[3];      /* majorant grid: cell size in voxels along x, y,
	                         z (cells [c*cell, (c+1)*cell) per axis);
	                         used only with cell_max */
	int (*cell_max)(void *thread_ctx, const int64_t c[3], float *bound);
	                      /* optional majorant grid: *bound >= the density
	                         of every lookup at a point inside cell c
	                         (0 = the cell is empty).  Called from the
	                         render threads with the thread's ctx, as
	                         lookup; returns 0 or a loom_result code.
	                         Slab scenes only (a shell keeps the global
	                         bound max_density) */
	loom_lookup_lod_fn lookup_lod;
	                      /* optional: used instead of lookup for slab
	                         scenes (a shell keeps lookup), with the ray's
	                         footprint, so the source can choose a level of
	                         detail (docs/rendering.md, "Level of detail") */
	int (*density)(void *thread_ctx, const double p[3], float *density);
	                      /* optional, with cell_max: the density alone of
	                         the lookup at p (exactly lookup's value), for
	                         a cheap first test of a tentative collision;
	                         the full lookup follows only when it may be
	                         real.  Same ctx and rules as lookup.  A
	                         wrapper that replaces lookup must replace or
	                         clear this too.  Not used with lookup_lod */
	int (*cell_zspan)(void *thread_ctx, const int64_t c[3], int64_t *zlo,
	                  int64_t *zhi);
	                      /* optional, with cell_max: z cells [*zlo, *zhi]
	                         of the cell column (c[0], c[1]) outside which
	                         cell_max gives 0 for every z (zlo > zhi: the
	                         whole column is empty), so the tracker passes
	                         the empty layers above and below the cloth
	                         without a cell_max call each.  Same ctx and
	                         rules as cell_max */
	int (*cell_zbox)(void *thread_ctx, const int64_t c[3], int64_t box[4],
	                 int64_t *zlo, int64_t *zhi);
	                      /* optional, with cell_zspan: a box of cell
	                         columns [box[0], box[1]) x [box[2], box[3])
	                         holding column (c[0], c[1]), and z cells
	                         [*zlo, *zhi] outside which cell_max gives 0 in
	                         every column of the box (zlo > zhi: the box is
	                         empty), so the tracker passes a ray above or
	                         below the cloth over the whole box in plain
	                         DDA steps, with no query per column.  Same ctx
	                         and rules as cell_max.  (Added after the rest:
	                         a source whose size ends before it is used
	                         without it.) */
} loom_volume_source;

#define LOOM_VOLUME_SOURCE_INIT \
	{sizeof(loom_volume_source), 0, 0, 0, 0.0, 0.0f, NULL, NULL, NULL, NULL, \
	 {0, 0, 0}, NULL, NULL, NULL, NULL, NULL}

/* ======================================================================
 * Meshes (Wavefront OBJ)
 * ====================================================================== */

#define LOOM_MESH_NONE 0xFFFFFFFFu /* no texcoord / normal at a corner */
#define LOOM_OBJ_MAX_ELEMENTS 50000000u /* largest count of v, vt, vn or
                                           triangles accepted */

/*
 * A triangle mesh with per-corner indices (OBJ style).  Transparent plain
 * data; free with loom_mesh_free.  tri_vt / tri_vn are NULL when no face
 * has texture coordinates / normals; otherwise a corner without one holds
 * LOOM_MESH_NONE.  Every index is in range (the reader checks).
 */
typedef struct loom_mesh {
	uint32_t n_positions;  /* v lines */
	uint32_t n_texcoords;  /* vt lines */
	uint32_t n_normals;    /* vn lines */
	uint32_t n_triangles;  /* after fan triangulation of polygons */
	float *positions;      /* 3 * n_positions */
	float *texcoords;      /* 2 * n_texcoords (u, v; a third vt value is
	                          dropped) */
	float *normals;        /* 3 * n_normals, as written (not normalised) */
	uint32_t *tri_v;       /* 3 * n_triangles, 0-based position indices */
	uint32_t *tri_vt;      /* 3 * n_triangles or NULL */
	uint32_t *tri_vn;      /* 3 * n_triangles or NULL */
} loom_mesh;

/*
 * Parse OBJ text (len bytes, need not be NUL-terminated; `name` is used in
 * messages as "name:line: ...").  Understood: v (x y z, optional w and
 * vertex colours ignored), vt (u [v [w]]), vn, f with v, v/vt, v//vn and
 * v/vt/vn corners (1-based or negative = relative), polygons fan-
 * triangulated.  Ignored: comments, o, g, s, usemtl, mtllib, l, p; other
 * statements are ignored with one warning for the file (count and first
 * line).  Indices must refer to elements defined earlier.  Errors
 * (LOOM_EFORMAT):
 * bad or non-finite numbers, too few values, index 0 or out of range, a
 * face with < 3 corners or mixing corner forms; LOOM_ERANGE past
 * LOOM_OBJ_MAX_ELEMENTS; LOOM_ENOMEM.  *out is NULL on failure.
 */
LOOM_API int loom_obj_parse(const char *text, size_t len, const char *name,
                            loom_mesh **out, loom_diag *diag);
/* Read and parse an OBJ file (at most 1 GiB). */
LOOM_API int loom_obj_read(const char *path, loom_mesh **out, loom_diag *diag);
/* Free a mesh; NULL is a no-op. */
LOOM_API void loom_mesh_free(loom_mesh *m);

/* ======================================================================
 * Shell mapping (Porumbescu et al. 2005, as Zhao et al. 2011 use it)
 * ======================================================================
 *
 * The flat volume is mapped into a thin shell over a mesh with UVs:
 *   voxel x = (u - uv_origin[0]) * voxels_per_uv
 *   voxel y = (v - uv_origin[1]) * voxels_per_uv
 *   voxel z = (h - offset) / thickness * nz
 * where h is the height along the interpolated vertex normal.  Each
 * triangle (P_i, N_i, uv_i) becomes a prism; its point at barycentrics b
 * and height h is  X(b, h) = sum_i b_i (P_i + h N_i).  Slices of constant
 * h are flat triangles, so the inner (h = offset) and outer (h = offset +
 * thickness) surfaces are triangle meshes; side walls at mesh borders are
 * approximated by two triangles each.  world -> voxel inverts X by Newton
 * (a few steps) in the prism found by an Embree closest-triangle query.
 */
typedef struct loom_shell loom_shell;

#define LOOM_SHELL_COMPUTE_NORMALS 1u /* ignore file normals; use area-
                                         weighted vertex normals */

typedef struct loom_shell_params {
	size_t size;            /* sizeof(loom_shell_params) */
	double thickness;       /* world length of the shell along normals, > 0 */
	double offset;          /* height of the inner surface (0: on the mesh;
	                           -thickness/2: cloth centred on the mesh) */
	double voxels_per_uv;   /* voxels along x per UV unit (u), > 0; also
	                           along y unless voxels_per_uv_v is set */
	double uv_origin[2];    /* UV that maps to voxel x = y = 0 */
	int64_t nz;             /* voxels across the thickness (the source's nz) */
	uint32_t flags;         /* LOOM_SHELL_* */
	double voxels_per_uv_v; /* voxels along y per UV unit (v); 0 = the same
	                           as voxels_per_uv (loom_uv_mm_scale sets both
	                           from millimetres per UV unit) */
} loom_shell_params;

#define LOOM_SHELL_PARAMS_INIT \
	{sizeof(loom_shell_params), 0.0, 0.0, 0.0, {0.0, 0.0}, 0, 0u, 0.0}

/*
 * Voxels per UV unit in u and v for a cloth laid at uv_mm[0] x uv_mm[1]
 * millimetres per UV unit, so that crossings keep the cloth's sett and
 * square motifs stay square whatever the exemplar crossing's aspect:
 *
 *     pitch_u = 10 / sett[0] mm (ends per cm), pitch_v = 10 / sett[1]
 *     voxels_per_uv[0] = uv_mm[0] * block[0] / pitch_u   (likewise v)
 *
 * A sett of 0 (not stated by the draft) stands for square crossings of the
 * exemplar crossing's area: pitch = sqrt(block[0] block[1]) x voxel_mm in
 * both directions; one side stated, that pitch in both.  A database generated for the draft's sett has
 * block = pitch / voxel_mm, so the voxels keep their size (factor 1).
 * pitch_mm[2] (may be NULL) receives the crossing size in mm used.
 * Returns LOOM_OK; LOOM_EINVAL (NULL, a non-positive or non-finite
 * uv_mm, block, voxel_mm or negative sett).  Thread-safe.
 */
LOOM_API int loom_uv_mm_scale(const double uv_mm[2], const uint32_t block[2],
                              double voxel_mm, const float sett[2],
                              double voxels_per_uv[2], double pitch_mm[2]);

/*
 * Build the shell of mesh m (copied; m may be freed afterwards): vertex
 * normals, prisms, three Embree scenes (base triangles for closest-point
 * queries, shell boundary for rays, UV triangles for voxel -> world).
 * Triangles degenerate in space or UV are skipped (counted in a warning).
 * Returns LOOM_OK; LOOM_EINVAL (NULL, bad params, no texture coordinates,
 * no usable triangle) with the reason in diag; LOOM_ENOMEM; LOOM_EIO when
 * Embree fails (its message in diag).  The shell is immutable: every
 * query below may run from many threads at once.
 */
LOOM_API int loom_shell_new(const loom_mesh *m, const loom_shell_params *p,
                            loom_shell **out, loom_diag *diag);
/* Free a shell; NULL is a no-op. */
LOOM_API void loom_shell_free(loom_shell *s);

/*
 * Map world point w to voxel coordinates v.  tri (may be NULL) receives the
 * prism's triangle index (into the mesh's triangles).  Returns LOOM_OK,
 * LOOM_ENOTFOUND when w is outside the shell (v untouched), LOOM_EUNUSABLE
 * after an Embree error, LOOM_EINVAL for NULL.  Thread-safe.
 */
LOOM_API int loom_shell_world_to_voxel(const loom_shell *s, const double w[3],
                                       double v[3], uint32_t *tri);

/* The inverse: voxel coordinates (z in [0, nz]) to a world point.  The
   triangle is found by UV point location.  LOOM_ENOTFOUND when (x, y) is
   outside the mesh's UV domain.  Thread-safe. */
LOOM_API int loom_shell_voxel_to_world(const loom_shell *s, const double v[3],
                                       double w[3], uint32_t *tri);

/* Axis-aligned bounds of the shell (world).  Thread-safe. */
LOOM_API void loom_shell_bounds(const loom_shell *s, double lo[3], double hi[3]);

/* World length of one voxel across the shell: thickness / nz. */
LOOM_API double loom_shell_voxel_length(const loom_shell *s);

/* Triangles used (degenerate ones skipped). */
LOOM_API uint32_t loom_shell_triangle_count(const loom_shell *s);

/* ======================================================================
 * Meshes without texture coordinates (engine/render/surface_field.c)
 * ======================================================================
 *
 * A smooth warp-direction field over the surface (warp_dir projected onto
 * each triangle, or a principal curvature direction with warp_dir where
 * the surface is umbilic; smoothed over edge neighbours) and one rigid planar map
 * per triangle aligned with it (warps along v), translated breadth-first
 * to continue its placed neighbours (Magda and Kriegman 2003); with a
 * period the continuation is taken modulo whole periods.  The result is a
 * copy of the mesh with three texture coordinates per triangle, ready for
 * loom_shell_new.  Its UV triangles overlap, so loom_shell_voxel_to_world
 * on it returns one of the points with that voxel.
 */
typedef struct loom_field_uv_params {
	size_t size;            /* sizeof(loom_field_uv_params) */
	double warp_dir[3];     /* world direction the warps follow, != 0 */
	double uv_per_world;    /* UV units per world length, > 0 */
	double period[2];       /* UV period of the cloth (one design repeat)
	                           along u and v; 0 = none */
	uint32_t smooth_iters;  /* field smoothing rounds (<= 100000) */
	int source;             /* enum loom_field_source */
} loom_field_uv_params;

/* Where the warp field comes from (loom_field_uv_params.source). */
enum loom_field_source {
	LOOM_FIELD_DIRECTION = 0,     /* warp_dir projected onto the surface */
	LOOM_FIELD_CURVATURE_MAX = 1, /* the principal direction of larger
	                                 |curvature| (round a cylinder, round a
	                                 torus's tube); warp_dir near umbilics */
	LOOM_FIELD_CURVATURE_MIN = 2  /* the other principal direction (along a
	                                 cylinder's axis, round a torus's hole) */
};

#define LOOM_FIELD_UV_PARAMS_INIT \
	{sizeof(loom_field_uv_params), {0.0, 1.0, 0.0}, 1.0, {0.0, 0.0}, 32u, \
	 LOOM_FIELD_DIRECTION}

/* Returns LOOM_OK with *out a new mesh (free with loom_mesh_free);
   LOOM_EINVAL (bad params, no triangles) with the reason in diag;
   LOOM_ENOMEM; LOOM_ERANGE. */
LOOM_API int loom_mesh_field_uv(const loom_mesh *m,
                                const loom_field_uv_params *p,
                                loom_mesh **out, loom_diag *diag);

/* Distortion and seams of a mesh's texture coordinates. */
typedef struct loom_mesh_uv_stats {
	double uv_per_world;    /* sqrt(UV area / surface area): the scale */
	double stretch_max;     /* max over triangles of max(s1, 1/s2), s1 >= s2
	                           the singular values of d(uv)/d(surface) over
	                           the scale: 1 = crossings keep their size */
	double stretch_mean;    /* the same, area-weighted mean */
	uint32_t interior_edges;/* edges shared by exactly two triangles */
	uint32_t seam_edges;    /* of those, UV mismatch > seam_tol */
	double seam_mean;       /* UV mismatch at the edge ends, modulo the
	                           period: mean and max over interior edges */
	double seam_max;
} loom_mesh_uv_stats;

/* Measure m (which must have texture coordinates): LOOM_OK, LOOM_EINVAL
   (no UVs or zero area), LOOM_ENOMEM.  period may be NULL. */
LOOM_API int loom_mesh_measure_uv(const loom_mesh *m, const double period[2],
                                 double seam_tol, loom_mesh_uv_stats *st);

/* ======================================================================
 * Volume path tracer
 * ====================================================================== */

enum loom_camera_kind {
	LOOM_CAMERA_ORTHO = 0,   /* parallel rays along eye -> target */
	LOOM_CAMERA_PINHOLE = 1  /* perspective from eye */
};

typedef struct loom_camera {
	int kind;               /* enum loom_camera_kind */
	double eye[3];          /* pinhole: centre of projection; ortho: centre
	                           of the image plane (rays start there) */
	double target[3];       /* point looked at */
	double up[3];           /* up hint (not parallel to target - eye) */
	double fov_y_deg;       /* pinhole: vertical field of view, (0, 180) */
	double ortho_size[2];   /* ortho: width and height of the view (world) */
	double aperture;        /* pinhole: thin-lens diameter (world); 0 = a
	                           pinhole (everything sharp) */
	double focus_dist;      /* thin lens: distance of the plane in focus
	                           along the view direction (world); 0 = the
	                           distance from eye to target */
} loom_camera;

/*
 * An orthographic camera looking straight down (-z) on the window
 * [x0, x1] x [y0, y1] of the slab of src (voxel space; image right = +x,
 * image up = +y), from above the slab.  Returns LOOM_EINVAL for an empty
 * window or NULL.
 */
LOOM_API int loom_camera_top(const loom_volume_source *src, double x0,
                             double y0, double x1, double y1, loom_camera *cam);

enum loom_light_kind {
	LOOM_LIGHT_NONE = 0,
	LOOM_LIGHT_DISTANT = 1,  /* parallel light from direction `dir` */
	LOOM_LIGHT_POINT = 2,    /* isotropic point at `pos` */
	LOOM_LIGHT_SPHERE = 3    /* sphere of uniform radiance, centre `pos`,
	                            `radius`; lights the scene but is not seen
	                            by camera or scattered rays */
};

typedef struct loom_light {
	int kind;          /* enum loom_light_kind */
	double dir[3];     /* distant: direction TOWARDS the light (any length) */
	double pos[3];     /* point: position (world) */
	float rgb[3];      /* distant: irradiance on a plane facing the light;
	                      point: intensity (irradiance at distance 1) */
	double angle_deg;  /* distant: angular diameter of the light's disc,
	                      [0, 90]; 0 = a point (sharp shadows), the sun
	                      is about 0.53 */
	double radius;     /* sphere: radius (world), > 0; rgb is then the
	                      intensity, irradiance I / d^2 at distance d from
	                      the centre (radiance I / (pi radius^2)) */
} loom_light;

/* ======================================================================
 * HDR environment maps (engine/render/envmap.c)
 * ======================================================================
 *
 * A latitude-longitude map of linear RGB radiance: pixel (x, y) of a W x H
 * map covers azimuth [360 x / W, 360 (x+1) / W) degrees, counter-clockwise
 * from +x towards +y, plus the rotation, and polar angle
 * [180 y / H, 180 (y+1) / H) from +z (row 0 = straight up; in the slab
 * scene +z is the cloth's normal).  Radiance is constant over a pixel.
 * Sampling picks a pixel with probability proportional to its luminance
 * times its solid angle (marginal CDF over rows, conditional per row) and
 * a direction uniform in solid angle inside it.
 */
typedef struct loom_envmap loom_envmap;

#define LOOM_ENVMAP_MAX_PIXELS (1ull << 22) /* 4 Mi pixels (e.g. 2896 x
                                               1448): 64 MiB */

/* Bytes a W x H map takes (count it in a memory budget). */
LOOM_API size_t loom_envmap_bytes(uint32_t width, uint32_t height);

/* Build a map from rgb (3 floats per pixel, row 0 = zenith, copied),
   rotated about +z by rotate_deg and scaled by intensity.  LOOM_ERANGE
   for an empty map or more than LOOM_ENVMAP_MAX_PIXELS; LOOM_EINVAL for a
   negative or non-finite value (the pixel is named) or bad parameters;
   LOOM_ENOMEM.  The map is immutable; every query is thread-safe. */
LOOM_API int loom_envmap_new(const float *rgb, uint32_t width, uint32_t height,
                             double rotate_deg, double intensity,
                             loom_envmap **out, loom_diag *diag);
LOOM_API void loom_envmap_free(loom_envmap *m);

/* Radiance arriving from unit direction d (d points away from the
   scene, towards the sky). */
LOOM_API void loom_envmap_eval(const loom_envmap *m, const double d[3],
                               double rgb[3]);

/* Sample a direction from (u1, u2) in [0, 1)^2; returns its pdf per
   steradian (0 for an all-black map: d is then not set). */
LOOM_API double loom_envmap_sample(const loom_envmap *m, double u1, double u2,
                                   double d[3]);

/* The pdf per steradian with which loom_envmap_sample returns d. */
LOOM_API double loom_envmap_pdf(const loom_envmap *m, const double d[3]);

/*
 * The built-in studio sky (docs/rendering.md, "The studio sky"): a soft
 * overcast-like dome, brightest at the zenith (0.32, 0.34, 0.37) and
 * falling to (0.13, 0.13, 0.14) at the horizon, a dark floor (0.05) below
 * it with a short blend under the horizon, and a warm glow round the sun
 * (unit direction `sun`, towards it; about 15 degrees wide, 0.9 at its
 * centre, not below the horizon).  The sun's own disc is not in it (the
 * renderer's sun light is).  Linear RGB radiance arriving from unit
 * direction d (+z up).
 */
LOOM_API void loom_sky_studio(const double sun[3], const double d[3], double rgb[3]);

/*
 * The studio sky as a width x height latitude-longitude map in
 * loom_envmap_new's layout (rotation 0), each pixel the mean of 4 x 4
 * directions uniform in its solid angle (so the map's integral matches the
 * sky's).  rgb holds 3 width height floats.  LOOM_EINVAL (NULL, a zero
 * size, a sun that is not a finite non-zero vector), LOOM_ERANGE (more
 * than LOOM_ENVMAP_MAX_PIXELS).
 */
#define LOOM_SKY_MAP_W 128u /* the size `loom render` uses (about 2.8
                               degrees a pixel; 0.25 MiB with its CDFs) */
#define LOOM_SKY_MAP_H 64u
LOOM_API int loom_sky_studio_map(const double sun[3], uint32_t width, uint32_t height,
                                 float *rgb);

/* Power heuristic (exponent 2) weight of a sample drawn with pdf_a when
   the other strategy has pdf_b: a^2 / (a^2 + b^2); 0 when pdf_a is 0. */
LOOM_API double loom_mis_power(double pdf_a, double pdf_b);

/*
 * An optional floor: the opaque plane z = height (scene units) with a
 * Lambertian (diffuse) surface of reflectance albedo, seen from either
 * side.  Camera, scattered and shadow rays all hit it, so it catches the
 * cloth's shadows; the environment and the lights light it like the cloth.
 */
typedef struct loom_ground {
	int enabled;            /* 0: no floor (the default) */
	double height;          /* z of the plane, scene units, finite */
	float albedo[3];        /* diffuse reflectance per channel, [0, 1] */
} loom_ground;

/*
 * Optional per-pixel outputs besides the beauty image (arbitrary output
 * variables, for denoisers and compositing).  Each non-NULL buffer holds
 * width * height values of the given count, row 0 at the top, filled in
 * sample order (same bytes for any thread count; asking for them does not
 * change the beauty image).  "First event" is a camera ray's first real
 * collision in the medium or its hit on the ground; samples whose camera
 * ray escapes give 0 to albedo and normal and nothing to depth.
 */
typedef struct loom_render_aov {
	float *albedo;          /* 3: mean single-scattering albedo at the
	                           first event (the ground's albedo there) */
	float *normal;          /* 3: mean unit normal at the first event:
	                           minus the density gradient (central
	                           differences one voxel apart) turned towards
	                           the camera; the plane's normal on the
	                           ground; scene axes */
	float *depth;           /* 1: mean distance (scene units) from the ray's
	                           origin to the first event over the samples
	                           that had one; 0 when none had */
	float *noise;           /* 3: standard error of the pixel's mean,
	                           sqrt(sample variance / spp) (0 at 1 spp) */
} loom_render_aov;

typedef struct loom_render_options {
	size_t size;            /* sizeof(loom_render_options) */
	uint32_t width, height; /* pixels, 1 .. 65536 each */
	uint32_t spp;           /* samples per pixel, >= 1 */
	uint32_t max_depth;     /* scattering events per path, >= 1 */
	uint32_t rr_depth;      /* Russian roulette from this many events */
	uint64_t seed;          /* same seed => same bytes, any thread count */
	uint32_t threads;       /* worker threads; 0 = online CPUs */
	uint32_t tile;          /* tile side in pixels; 0 = 16 */
	double density_scale;   /* extinction per voxel length at density 1
	                           for A = 1 (isotropic) */
	double alignment;       /* default microflake s (voxels whose
	                           alignment <= 0) */
	loom_camera camera;
	loom_light light;
	float env[3];           /* constant environment radiance (every
	                           direction; also the background) */
	const loom_shell *shell;/* NULL: the slab in voxel space is the scene;
	                           else the shell (world = mesh space), whose
	                           nz must equal the source's */
	double world_per_voxel; /* shell: world length of a voxel for
	                           extinction; 0 = loom_shell_voxel_length() */
	void (*progress)(void *user, uint64_t tiles_done, uint64_t tiles_total);
	                        /* optional; called from worker threads, one at
	                           a time */
	void *progress_user;
	uint32_t flags;         /* LOOM_RENDER_* bits */
	const loom_light *lights; /* n_lights more lights, each sampled at
	                           every scattering event as `light` is */
	uint32_t n_lights;      /* <= LOOM_RENDER_MAX_LIGHTS */
	const loom_envmap *envmap; /* NULL: the constant env; else this map is
	                           the environment (and background), sampled
	                           at every scattering event and combined with
	                           phase sampling by multiple importance
	                           sampling; env is then unused */
	loom_ground ground;     /* optional floor (ground.enabled = 0: none) */
	const loom_render_aov *aov; /* NULL: the beauty image only */
	/* Sampling (docs/rendering.md, "Sampling"); zero = the defaults */
	uint32_t sampler;       /* LOOM_SAMPLER_SOBOL (0: Owen-scrambled Sobol
	                           per pixel) or LOOM_SAMPLER_RANDOM (an
	                           independent stream per sample, the sampler
	                           before; its bytes are unchanged) */
	double noise;           /* > 0: adaptive sampling: a pixel stops once
	                           the standard error of its mean luminance is
	                           at most noise x that mean (tested after 16,
	                           24, 32, ... samples; spp is the maximum);
	                           0 = every pixel takes spp */
	uint32_t *samples;      /* optional out: width * height samples taken
	                           per pixel */
	double progressive_seconds; /* > 0: call progressive() with the image
	                           so far about this often (samples run in
	                           passes ending at 1, 2, 4, ... spp; the final
	                           bytes do not change) */
	void (*progressive)(void *user, const float *rgb);
	                        /* called from the thread that called
	                           loom_render, while workers go on; rgb is the
	                           caller's buffer holding each pixel's mean so
	                           far (0 before its first sample) */
	void *progressive_user;
} loom_render_options;

enum loom_sampler {
	LOOM_SAMPLER_SOBOL = 0,
	LOOM_SAMPLER_RANDOM = 1
};

#define LOOM_RENDER_MAX_LIGHTS 64u /* extra lights (opt.lights) */

#define LOOM_RENDER_GLOBAL_MAJORANT 1u /* ignore the source's majorant grid:
                                          track against max_density
                                          everywhere (the reference the
                                          tests and the bench compare to) */

#define LOOM_RENDER_OPTIONS_INIT                                              \
	{sizeof(loom_render_options), 256, 256, 16, 64, 4, 1, 0, 16, 1.0, 0.3,    \
	 {LOOM_CAMERA_ORTHO, {0, 0, 1}, {0, 0, 0}, {0, 1, 0}, 40.0, {1, 1}, 0.0,  \
	  0.0},                                                                    \
	 {LOOM_LIGHT_DISTANT, {0.3, 0.2, 1.0}, {0, 0, 0}, {3.0f, 3.0f, 3.0f}, 0.0,\
	  0.0},                                                                    \
	 {0.1f, 0.1f, 0.1f}, NULL, 0.0, NULL, NULL, 0u, NULL, 0u, NULL,           \
	 {0, 0.0, {0.5f, 0.5f, 0.5f}}, NULL,                                     \
	 0u, 0.0, NULL, 0.0, NULL, NULL}

typedef struct loom_render_stats {
	uint64_t paths;          /* camera samples (width * height * spp) */
	uint64_t rays;           /* rays traced: camera, scattered and shadow */
	uint64_t lookups;        /* source lookups (tentative collisions) */
	uint64_t scatterings;    /* real collisions */
	uint64_t shell_queries;  /* Embree closest-point queries (shell only) */
	uint64_t cells;          /* majorant grid cells entered (0 without a
	                            grid) */
	double seconds;          /* wall-clock time of loom_render */
} loom_render_stats;

/*
 * Render src into rgb (caller-allocated, width * height * 3 floats, row 0
 * at the top).  Unidirectional volume path tracing: delta (Woodcock)
 * tracking against the majorant max_density * density_scale * A_max, next-
 * event estimation of the light with ratio-tracking transmittance, the
 * environment on escape, Russian roulette after rr_depth events.  Pixels
 * are computed in tiles by `threads` pthreads; each (pixel, sample) has its
 * own random stream, so the bytes depend only on the inputs and the seed.
 * Memory: O(threads), nothing proportional to the volume or image.
 * stats may be NULL.  Returns LOOM_OK; LOOM_EINVAL (NULL, bad options or
 * camera, source without lookup) with the reason in diag; LOOM_EMISMATCH
 * (shell nz != source nz); LOOM_ENOMEM; a lookup's own error code (rgb is
 * then incomplete).  Thread-safe (re-entrant) for distinct rgb buffers.
 */
LOOM_API int loom_render(const loom_volume_source *src,
                         const loom_render_options *opt, float *rgb,
                         loom_render_stats *stats, loom_diag *diag);

/*
 * Tone-map n_pixels linear RGB floats to 8-bit sRGB: value * 2^exposure,
 * clamped to [0, 1], sRGB transfer curve, rounded.  out holds
 * 3 * n_pixels bytes.  NaN becomes 0.  Thread-safe.
 */
LOOM_API void loom_render_to_srgb8(const float *rgb, size_t n_pixels,
                                   double exposure, uint8_t *out);

/* Tone curves for loom_render_to_srgb8_tone (engine/render/tone.c). */
enum loom_tone {
	LOOM_TONE_LINEAR = 0,  /* clamp to [0, 1] (loom_render_to_srgb8) */
	LOOM_TONE_FILMIC = 1   /* f(x) = x (2.51 x + 0.03) / (x (2.43 x + 0.59)
	                          + 0.14), clamped to [0, 1]: a toe, a
	                          straight middle and a soft shoulder that
	                          reaches white at x = 7.24 (K. Narkowicz's
	                          2015 fit of the ACES film curve, applied per
	                          channel) */
};

/* The filmic curve above for one linear value (>= 0; NaN gives 0). */
LOOM_API double loom_tone_filmic(double x);

/* As loom_render_to_srgb8 with a tone curve (enum loom_tone) applied
   to value * 2^exposure before the sRGB transfer curve; LOOM_TONE_LINEAR
   gives loom_render_to_srgb8's bytes.  An unknown tone is treated as
   linear. */
LOOM_API void loom_render_to_srgb8_tone(const float *rgb, size_t n_pixels,
                                        double exposure, int tone, uint8_t *out);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_RENDER_H */
