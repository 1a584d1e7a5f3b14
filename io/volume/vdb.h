/*
 * io/volume/vdb.h - OpenVDB (.vdb) and NanoVDB (.nvdb) tile writers: the C
 * interface of io/volume/vdb_shim.cpp, the only C++ in libloom.  Internal
 * (loom__); loom.h and the C ABI do not change with or without it.
 *
 * The shim is built as a plugin, libloom-vdb.so.0 (-DLOOM_VDB_PLUGIN),
 * when Debian's libopenvdb-dev (and, for NanoVDB, libnanovdb-dev) are
 * present; libloom reaches it through io/volume/vdb_dl.c, which loads it on
 * first use, so no other loom process maps OpenVDB.  Without the plugin
 * loom__vdb_missing names the package to install.
 *
 * A writer collects one tile's grids in memory (OpenVDB trees: about 4.3
 * bytes per active voxel of a float or int grid, 12.6 of a vector grid,
 * LOOM__VDB_BYTES_* below), then writes them all into one file:
 *
 *     loom__vdb_open(&v, LOOM__VDB_OPENVDB, LOOM__VDB_BLOSC, voxel_mm, ...)
 *     loom__vdb_grid(v, "density", LOOM__VDB_FLOAT, lo, hi, ...)
 *     loom__vdb_row(v, x0, y, z, n, values, ...)   (every row of the tile)
 *     loom__vdb_grid(v, "color", LOOM__VDB_VEC3, ...) ... rows ...
 *     loom__vdb_write(v, path, ...)                (temporary name, fsync,
 *                                                   rename; then free)
 *     loom__vdb_free(v)
 *
 * Index space is loom's voxel grid: voxel (i, j, k) of the virtual texture
 * is OpenVDB coordinate (i, j, k) in every tile; the transform scales by
 * voxel_mm and shifts by half a voxel, so voxel centres sit at
 * (i + 0.5) * voxel_mm in millimetres (as the .vol and NRRD exports) and
 * tiles line up in any VDB tool.  Zero values are the background and stay
 * inactive; trees are pruned.  Coordinates must fit in 32 bits.
 */
#ifndef LOOM_IO_VDB_H
#define LOOM_IO_VDB_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "core/internal.h" /* loom_diag, loom__fail (C declarations) */

enum { LOOM__VDB_OPENVDB, LOOM__VDB_NANOVDB };
enum { LOOM__VDB_FLOAT, LOOM__VDB_VEC3, LOOM__VDB_INT32 };
enum { LOOM__VDB_NONE, LOOM__VDB_ZIP, LOOM__VDB_BLOSC };

/* Upper estimates of a writer's memory per voxel of a tile (all active),
   for the export's budget: the OpenVDB trees, and for NanoVDB the
   converted buffer besides them. */
#define LOOM__VDB_BYTES_SCALAR 6u
#define LOOM__VDB_BYTES_VEC3 16u

typedef struct loom__vdb loom__vdb;

/* Internal to libloom, hidden as the C files are (the shim itself is built
   without -fvisibility=hidden: OpenVDB's template statics must be the ones
   of libopenvdb.so, not private copies). */
#ifdef LOOM_VDB_PLUGIN
/* the plugin (vdb_shim.cpp built into libloom-vdb.so.0) exports the
   writers under loom_vdb_plugin_*, which io/volume/vdb_dl.c looks up */
#define LOOM__VDB_FN __attribute__((visibility("default")))
#define loom__vdb_missing loom_vdb_plugin_missing
#define loom__vdb_open loom_vdb_plugin_open
#define loom__vdb_grid loom_vdb_plugin_grid
#define loom__vdb_row loom_vdb_plugin_row
#define loom__vdb_write loom_vdb_plugin_write
#define loom__vdb_free loom_vdb_plugin_free
#else
#define LOOM__VDB_FN __attribute__((visibility("hidden")))
#endif

/* NULL when this libloom can write `format`, else the Debian package that
   was missing when it was built (e.g. "libopenvdb-dev"). */
LOOM__VDB_FN const char *loom__vdb_missing(int format);

/* A writer of `format` with `codec` (NanoVDB: LOOM__VDB_NONE only, other
   codecs are LOOM_EUNSUPPORTED); voxel_mm > 0. */
LOOM__VDB_FN int loom__vdb_open(loom__vdb **out, int format, int codec, double voxel_mm,
                   loom_diag *diag);
/* Start grid `name` of `kind` for the tile box [lo, hi) (recorded as the
   grid metadata loom_tile_lo, loom_tile_hi); the grid before it is pruned. */
LOOM__VDB_FN int loom__vdb_grid(loom__vdb *v, const char *name, int kind, const int64_t lo[3],
                   const int64_t hi[3], loom_diag *diag);
/* n voxels (x0 .. x0+n-1, y, z) of the current grid: n floats, or 3n for
   LOOM__VDB_VEC3 (int grids take the floats' integer values).  Voxels whose
   value is 0 (all components) stay inactive. */
LOOM__VDB_FN int loom__vdb_row(loom__vdb *v, int64_t x0, int64_t y, int64_t z, size_t n,
                  const float *values, loom_diag *diag);
/* Write every grid to path (a temporary name in its directory, fsync'ed and
   renamed when complete; removed on any error). */
LOOM__VDB_FN int loom__vdb_write(loom__vdb *v, const char *path, loom_diag *diag);
LOOM__VDB_FN void loom__vdb_free(loom__vdb *v);

#ifndef LOOM_VDB_PLUGIN
/* Why the plugin was found but could not be loaded (a dlopen or symbol
   error), or NULL when it loaded or was not found at all (then
   loom__vdb_missing names the package).  io/volume/vdb_dl.c. */
LOOM__VDB_FN const char *loom__vdb_load_error(void);
#endif

#ifdef __cplusplus
}
#endif

#endif /* LOOM_IO_VDB_H */
