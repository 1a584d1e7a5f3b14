/*
 * io/volume/vdb_dl.c - the VDB writers of io/volume/vdb.h, loaded on first
 * use from the plugin libloom-vdb.so.0 (io/volume/vdb_shim.cpp built with
 * -DLOOM_VDB_PLUGIN against Debian's OpenVDB and NanoVDB).
 *
 * Why a plugin: OpenVDB, TBB and libstdc++ cost every process that links
 * them about 30 MiB of resident memory before main (measured: `loom
 * --version` 36 MiB linked, 5 MiB without), and loom's promise is a
 * process that stays within --budget plus a small constant.  So, as for
 * Embree (engine/render/embree_dl.c), only a VDB export pays for OpenVDB.
 *
 * Where the plugin is looked for, first found wins:
 *   1. $LOOM_VDB_LIBRARY (a path; only it is tried when set, and a path
 *      that does not exist means "no plugin");
 *   2. beside the object holding this code (libloom.so, or the program a
 *      static libloom is linked into): DIR/libloom-vdb.so.0;
 *   3. DIR/../lib/libloom-vdb.so.0 (a program in PREFIX/bin);
 *   4. DIR/../libloom-vdb.so.0 (a test program in build/tests).
 * A loom built without OpenVDB has no plugin: loom__vdb_missing names the
 * package to install.
 */
#include "vdb.h"

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PLUGIN "libloom-vdb.so.0"

typedef struct vdb_api {
	const char *(*missing)(int format);
	int (*open)(loom__vdb **out, int format, int codec, double voxel_mm,
	            loom_diag *diag);
	int (*grid)(loom__vdb *v, const char *name, int kind, const int64_t lo[3],
	            const int64_t hi[3], loom_diag *diag);
	int (*row)(loom__vdb *v, int64_t x0, int64_t y, int64_t z, size_t n,
	           const float *values, loom_diag *diag);
	int (*write)(loom__vdb *v, const char *path, loom_diag *diag);
	void (*free)(loom__vdb *v);
} vdb_api;

static pthread_once_t g_once = PTHREAD_ONCE_INIT;
static vdb_api g_api;
static int g_loaded;
static char g_why[512];

/* directory of the object this function is in, or "" */
static void self_dir(char *dir, size_t cap)
{
	Dl_info info;
	char path[PATH_MAX];
	ssize_t n = -1;

	dir[0] = 0;
	if (dladdr((void *)self_dir, &info) && info.dli_fname &&
	    strchr(info.dli_fname, '/') && realpath(info.dli_fname, path))
		n = (ssize_t)strlen(path);
	else if ((n = readlink("/proc/self/exe", path, sizeof path - 1)) > 0)
		path[n] = 0;
	if (n <= 0)
		return;
	char *slash = strrchr(path, '/');
	if (!slash)
		return;
	*slash = 0;
	snprintf(dir, cap, "%s", path);
}

static void *try_open(const char *path)
{
	void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
	if (!h) {
		const char *e = dlerror();
		/* keep the first reason that is not "no such file" */
		if (e && !g_why[0] && !strstr(e, "No such file"))
			snprintf(g_why, sizeof g_why, "%s", e);
	}
	return h;
}

static void load_once(void)
{
	char dir[PATH_MAX], path[PATH_MAX + 64];
	const char *env = getenv("LOOM_VDB_LIBRARY");
	void *h = NULL;
	vdb_api api;

	if (env && *env) {
		/* a path that does not exist is "no plugin" (as a loom built
		   without OpenVDB); one that exists and fails to load is named */
		if (access(env, F_OK) == 0) {
			h = try_open(env);
			if (!h && !g_why[0])
				snprintf(g_why, sizeof g_why, "%s: cannot load it", env);
		}
	} else {
		self_dir(dir, sizeof dir);
		if (dir[0]) {
			snprintf(path, sizeof path, "%s/" PLUGIN, dir);
			h = try_open(path);
			if (!h) {
				snprintf(path, sizeof path, "%s/../lib/" PLUGIN, dir);
				h = try_open(path);
			}
		}
		if (!h && dir[0]) {
			snprintf(path, sizeof path, "%s/../" PLUGIN, dir);
			h = try_open(path);
		}
	}
	if (!h)
		return;
#define SYM(f)                                                               \
	do {                                                                     \
		void *p = dlsym(h, "loom_vdb_plugin_" #f);                         \
		if (!p) {                                                            \
			snprintf(g_why, sizeof g_why, "%s has no symbol "                \
			         "loom_vdb_plugin_" #f, env && *env ? env : PLUGIN);   \
			dlclose(h);                                                      \
			return;                                                          \
		}                                                                    \
		memcpy(&api.f, &p, sizeof p);                                        \
	} while (0)
	SYM(missing);
	SYM(open);
	SYM(grid);
	SYM(row);
	SYM(write);
	SYM(free);
#undef SYM
	g_api = api; /* the handle stays open for the process */
	g_loaded = 1;
}

static int load(void)
{
	pthread_once(&g_once, load_once);
	return g_loaded;
}

const char *loom__vdb_missing(int format)
{
	if (!load())
		return "libopenvdb-dev";
	return g_api.missing(format);
}

const char *loom__vdb_load_error(void)
{
	return load() || !g_why[0] ? NULL : g_why;
}

int loom__vdb_open(loom__vdb **out, int format, int codec, double voxel_mm,
                   loom_diag *diag)
{
	if (out)
		*out = NULL;
	if (!load())
		return loom__fail(diag, LOOM_EUNSUPPORTED, "the VDB writer (" PLUGIN
		                  ") is not available: %s",
		                  g_why[0] ? g_why : "install libopenvdb-dev and rebuild loom");
	return g_api.open(out, format, codec, voxel_mm, diag);
}

int loom__vdb_grid(loom__vdb *v, const char *name, int kind, const int64_t lo[3],
                   const int64_t hi[3], loom_diag *diag)
{
	return g_loaded ? g_api.grid(v, name, kind, lo, hi, diag)
	                : loom__fail(diag, LOOM_EINVAL, "VDB writer not open");
}

int loom__vdb_row(loom__vdb *v, int64_t x0, int64_t y, int64_t z, size_t n,
                  const float *values, loom_diag *diag)
{
	return g_loaded ? g_api.row(v, x0, y, z, n, values, diag)
	                : loom__fail(diag, LOOM_EINVAL, "VDB writer not open");
}

int loom__vdb_write(loom__vdb *v, const char *path, loom_diag *diag)
{
	return g_loaded ? g_api.write(v, path, diag)
	                : loom__fail(diag, LOOM_EINVAL, "VDB writer not open");
}

void loom__vdb_free(loom__vdb *v)
{
	if (g_loaded && v)
		g_api.free(v);
}
