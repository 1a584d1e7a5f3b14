/*
 * engine/render/embree_dl.c - load Embree 3 on first use (see embree_dl.h).
 */
#include "embree_dl.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

loom__embree_api loom__rtc;

static pthread_once_t g_once = PTHREAD_ONCE_INIT;
static int g_rc;
static char g_msg[384];

static const struct {
	const char *name;
	size_t offset;
} g_syms[] = {
#define SYM(f) {"rtc" #f, offsetof(loom__embree_api, f)}
	SYM(NewDevice),
	SYM(ReleaseDevice),
	SYM(GetDeviceError),
	SYM(SetDeviceErrorFunction),
	SYM(NewScene),
	SYM(ReleaseScene),
	SYM(SetSceneFlags),
	SYM(CommitScene),
	SYM(NewGeometry),
	SYM(ReleaseGeometry),
	SYM(SetNewGeometryBuffer),
	SYM(CommitGeometry),
	SYM(AttachGeometry),
	SYM(Intersect1),
	SYM(PointQuery),
#undef SYM
};

static void load_once(void)
{
	loom__embree_api api;
	const char *lib = getenv("LOOM_EMBREE_LIBRARY");
	void *h;

	if (!lib || !*lib)
		lib = LOOM_EMBREE_SONAME;
	h = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
	if (!h) {
		const char *e = dlerror();
		snprintf(g_msg, sizeof g_msg,
		         "cannot load Embree 3 (%s): %s; install the Debian package "
		         "libembree3-3 (or set LOOM_EMBREE_LIBRARY)", lib,
		         e ? e : "not found");
		g_rc = LOOM_EIO;
		return;
	}
	memset(&api, 0, sizeof api);
	for (size_t k = 0; k < sizeof g_syms / sizeof g_syms[0]; k++) {
		void *p = dlsym(h, g_syms[k].name);
		if (!p) {
			snprintf(g_msg, sizeof g_msg, "%s has no symbol %s: not Embree 3.x",
			         lib, g_syms[k].name);
			g_rc = LOOM_EIO;
			dlclose(h);
			return;
		}
		/* POSIX: a function's address as returned by dlsym */
		memcpy((char *)&api + g_syms[k].offset, &p, sizeof p);
	}
	loom__rtc = api; /* the handle stays open for the process */
	g_rc = LOOM_OK;
}

int loom__embree_load(loom_diag *diag)
{
	pthread_once(&g_once, load_once);
	if (g_rc)
		return loom__fail(diag, g_rc, "%s", g_msg);
	return LOOM_OK;
}
