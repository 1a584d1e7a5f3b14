/*
 * engine/render/embree_dl.h - Embree 3, loaded when first needed.
 *
 * Only shell mapping (loom render --mesh) uses Embree, yet linking
 * libembree3 costs every process ~4.5 MiB of resident memory before main()
 * (TBB, libstdc++ and their relocations; measured in docs/performance.md),
 * which a memory-bounded batch job should not pay.  So libloom does not
 * link Embree: loom__embree_load() dlopen()s libembree3.so.3 the first time
 * a shell is built (or the file $LOOM_EMBREE_LIBRARY names, when set) and
 * fills a table of the few entry points loom calls.
 * The header's inline helpers (rtcInitIntersectContext, ...) are used as
 * they are.
 *
 * Include this instead of <embree3/rtcore.h>; the rtc* names below are
 * macros over the table, so the calling code reads like plain Embree.
 * Call loom__embree_load() (thread-safe, once) before any of them.
 */
#ifndef LOOM_EMBREE_DL_H
#define LOOM_EMBREE_DL_H

#include "core/internal.h"

#include <embree3/rtcore.h>

/* The library loaded: the Debian runtime package libembree3-3 ships it. */
#define LOOM_EMBREE_SONAME "libembree3.so.3"

typedef struct loom__embree_api {
	RTCDevice (*NewDevice)(const char *config);
	void (*ReleaseDevice)(RTCDevice device);
	enum RTCError (*GetDeviceError)(RTCDevice device);
	void (*SetDeviceErrorFunction)(RTCDevice device, RTCErrorFunction error,
	                               void *user);
	RTCScene (*NewScene)(RTCDevice device);
	void (*ReleaseScene)(RTCScene scene);
	void (*SetSceneFlags)(RTCScene scene, enum RTCSceneFlags flags);
	void (*CommitScene)(RTCScene scene);
	RTCGeometry (*NewGeometry)(RTCDevice device, enum RTCGeometryType type);
	void (*ReleaseGeometry)(RTCGeometry geometry);
	void *(*SetNewGeometryBuffer)(RTCGeometry geometry, enum RTCBufferType type,
	                              unsigned int slot, enum RTCFormat format,
	                              size_t byteStride, size_t itemCount);
	void (*CommitGeometry)(RTCGeometry geometry);
	unsigned int (*AttachGeometry)(RTCScene scene, RTCGeometry geometry);
	void (*Intersect1)(RTCScene scene, struct RTCIntersectContext *context,
	                   struct RTCRayHit *rayhit);
	bool (*PointQuery)(RTCScene scene, struct RTCPointQuery *query,
	                   struct RTCPointQueryContext *context,
	                   RTCPointQueryFunction queryFunc, void *userPtr);
} loom__embree_api;

extern loom__embree_api loom__rtc;

/*
 * Load Embree once (later calls return the first result).  LOOM_OK, or
 * LOOM_EIO with a message naming the library, what dlopen said and the
 * Debian package to install.  Thread-safe.
 */
int loom__embree_load(loom_diag *diag);

#define rtcNewDevice loom__rtc.NewDevice
#define rtcReleaseDevice loom__rtc.ReleaseDevice
#define rtcGetDeviceError loom__rtc.GetDeviceError
#define rtcSetDeviceErrorFunction loom__rtc.SetDeviceErrorFunction
#define rtcNewScene loom__rtc.NewScene
#define rtcReleaseScene loom__rtc.ReleaseScene
#define rtcSetSceneFlags loom__rtc.SetSceneFlags
#define rtcCommitScene loom__rtc.CommitScene
#define rtcNewGeometry loom__rtc.NewGeometry
#define rtcReleaseGeometry loom__rtc.ReleaseGeometry
#define rtcSetNewGeometryBuffer loom__rtc.SetNewGeometryBuffer
#define rtcCommitGeometry loom__rtc.CommitGeometry
#define rtcAttachGeometry loom__rtc.AttachGeometry
#define rtcIntersect1 loom__rtc.Intersect1
#define rtcPointQuery loom__rtc.PointQuery

#endif
