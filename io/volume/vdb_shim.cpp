/*
 * io/volume/vdb_shim.cpp - OpenVDB and NanoVDB tile writers behind the C
 * interface of io/volume/vdb.h: the only C++ in libloom.  Built with
 * OpenVDB 10 (Debian libopenvdb-dev) and NanoVDB (libnanovdb-dev) when their
 * headers are there; without them every writer call fails with a message
 * naming the missing package.  No C++ exception crosses the interface.
 */
#include "vdb.h"

#if __has_include(<openvdb/openvdb.h>)
#define LOOM_HAVE_OPENVDB 1
#endif
#if defined(LOOM_HAVE_OPENVDB) && __has_include(<nanovdb/util/OpenToNanoVDB.h>)
#define LOOM_HAVE_NANOVDB 1
#endif
#ifdef LOOM_VDB_PRETEND_MISSING /* tests: the build without the packages */
#undef LOOM_HAVE_OPENVDB
#undef LOOM_HAVE_NANOVDB
#endif

#include <cerrno>
#include <cstdio>
#include <cstring>

#ifdef LOOM_VDB_PLUGIN
#include <cstdarg>
/* The plugin's own loom__fail (libloom's is hidden inside libloom). */
extern "C" int loom__fail(loom_diag *diag, int code, const char *fmt, ...)
{
	if (diag) {
		va_list ap;
		va_start(ap, fmt);
		vsnprintf(diag->message, sizeof diag->message, fmt, ap);
		va_end(ap);
	}
	return code;
}
#endif

extern "C" const char *loom__vdb_missing(int format)
{
#ifndef LOOM_HAVE_OPENVDB
	(void)format;
	return "libopenvdb-dev";
#else
#ifndef LOOM_HAVE_NANOVDB
	if (format == LOOM__VDB_NANOVDB)
		return "libnanovdb-dev";
#endif
	(void)format;
	return nullptr;
#endif
}

#ifndef LOOM_HAVE_OPENVDB

struct loom__vdb {
	int unused;
};

extern "C" int loom__vdb_open(loom__vdb **out, int format, int codec, double voxel_mm,
                              loom_diag *diag)
{
	(void)codec;
	(void)voxel_mm;
	*out = nullptr;
	return loom__fail(diag, LOOM_EUNSUPPORTED, "%s output needs OpenVDB: this loom was "
	                  "built without it (install Debian's %s and rebuild)",
	                  format == LOOM__VDB_NANOVDB ? "NanoVDB" : "OpenVDB",
	                  loom__vdb_missing(format));
}
extern "C" int loom__vdb_grid(loom__vdb *, const char *, int, const int64_t *,
                              const int64_t *, loom_diag *diag)
{
	return loom__fail(diag, LOOM_EUNUSABLE, "no VDB writer");
}
extern "C" int loom__vdb_row(loom__vdb *, int64_t, int64_t, int64_t, size_t, const float *,
                             loom_diag *diag)
{
	return loom__fail(diag, LOOM_EUNUSABLE, "no VDB writer");
}
extern "C" int loom__vdb_write(loom__vdb *, const char *, loom_diag *diag)
{
	return loom__fail(diag, LOOM_EUNUSABLE, "no VDB writer");
}
extern "C" void loom__vdb_free(loom__vdb *) {}

#else /* LOOM_HAVE_OPENVDB */

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>
#ifdef LOOM_HAVE_NANOVDB
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>
#endif

#include <atomic>
#include <climits>
#include <fcntl.h>
#include <fstream>
#include <mutex>
#include <string>
#include <unistd.h>
#include <vector>

struct loom__vdb {
	int format, codec;
	openvdb::math::Transform::Ptr xform;
	openvdb::GridPtrVec grids;
	int kind;                          /* of the current grid */
	openvdb::FloatGrid::Ptr fg;        /* the current grid, one of these */
	openvdb::Vec3SGrid::Ptr vg;
	openvdb::Int32Grid::Ptr ig;
	bool failed;
};

static std::mutex vdb_init_lock;
static bool vdb_initialized;
static std::atomic<unsigned> vdb_tmp_counter{0};

static int vdb_exception(loom__vdb *v, loom_diag *diag, const char *what, const char *e)
{
	if (v)
		v->failed = true;
	return loom__fail(diag, LOOM_EIO, "%s: %s", what, e);
}

static void vdb_prune_current(loom__vdb *v)
{
	/* serial: the export's workers write tiles in parallel already, and no
	   TBB thread of OpenVDB's runs under loom's thread budget */
	if (v->fg)
		openvdb::tools::prune(v->fg->tree(), 0.0f, false);
	if (v->vg)
		openvdb::tools::prune(v->vg->tree(), openvdb::Vec3s(0.0f), false);
	if (v->ig)
		openvdb::tools::prune(v->ig->tree(), 0, false);
	v->fg.reset();
	v->vg.reset();
	v->ig.reset();
}

extern "C" int loom__vdb_open(loom__vdb **out, int format, int codec, double voxel_mm,
                              loom_diag *diag)
{
	*out = nullptr;
	if (loom__vdb_missing(format))
		return loom__fail(diag, LOOM_EUNSUPPORTED, "NanoVDB output needs NanoVDB: this "
		                  "loom was built without it (install Debian's %s and rebuild)",
		                  loom__vdb_missing(format));
	if (!(voxel_mm > 0) || (codec != LOOM__VDB_NONE && codec != LOOM__VDB_ZIP &&
	                        codec != LOOM__VDB_BLOSC))
		return loom__fail(diag, LOOM_EINVAL, "VDB writer: bad voxel size or codec");
	if (format == LOOM__VDB_NANOVDB && codec != LOOM__VDB_NONE)
		return loom__fail(diag, LOOM_EUNSUPPORTED, "NanoVDB files are written "
		                  "uncompressed (renderers read them without a codec)");
	try {
		{
			/* openvdb::initialize is itself idempotent and locked; this
			   only skips its lock after the first writer */
			std::lock_guard<std::mutex> g(vdb_init_lock);
			if (!vdb_initialized)
				openvdb::initialize();
			vdb_initialized = true;
		}
		loom__vdb *v = new loom__vdb();
		v->format = format;
		v->codec = codec;
		v->failed = false;
		v->kind = -1;
		/* index (i,j,k) -> world ((i,j,k) + 0.5) * voxel_mm: voxel centres */
		v->xform = openvdb::math::Transform::createLinearTransform(voxel_mm);
		v->xform->postTranslate(openvdb::Vec3d(0.5 * voxel_mm));
		*out = v;
	} catch (const std::exception &e) {
		return vdb_exception(nullptr, diag, "OpenVDB", e.what());
	}
	return LOOM_OK;
}

extern "C" int loom__vdb_grid(loom__vdb *v, const char *name, int kind, const int64_t lo[3],
                              const int64_t hi[3], loom_diag *diag)
{
	if (!v || v->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "VDB writer: unusable after an error");
	for (int a = 0; a < 3; a++)
		if (lo[a] < INT32_MIN || hi[a] > INT32_MAX || lo[a] >= hi[a])
			return loom__fail(diag, LOOM_ERANGE, "VDB writer: the tile box must be "
			                  "within the 32-bit coordinates of OpenVDB");
	try {
		openvdb::GridBase::Ptr g;
		vdb_prune_current(v);
		switch (kind) {
		case LOOM__VDB_FLOAT:
			v->fg = openvdb::FloatGrid::create(0.0f);
			v->fg->setGridClass(openvdb::GRID_FOG_VOLUME);
			g = v->fg;
			break;
		case LOOM__VDB_VEC3:
			v->vg = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
			v->vg->setVectorType(openvdb::VEC_INVARIANT);
			g = v->vg;
			break;
		case LOOM__VDB_INT32:
			v->ig = openvdb::Int32Grid::create(0);
			g = v->ig;
			break;
		default:
			return loom__fail(diag, LOOM_EINVAL, "VDB writer: bad grid kind %d", kind);
		}
		v->kind = kind;
		g->setName(name);
		g->setTransform(v->xform->copy());
		g->insertMeta("loom_tile_lo", openvdb::Vec3IMetadata(openvdb::Vec3i(
			(int)lo[0], (int)lo[1], (int)lo[2])));
		g->insertMeta("loom_tile_hi", openvdb::Vec3IMetadata(openvdb::Vec3i(
			(int)hi[0], (int)hi[1], (int)hi[2])));
		g->insertMeta("loom_voxel_mm", openvdb::DoubleMetadata(v->xform->voxelSize()[0]));
		v->grids.push_back(g);
	} catch (const std::exception &e) {
		return vdb_exception(v, diag, "OpenVDB grid", e.what());
	}
	return LOOM_OK;
}

extern "C" int loom__vdb_row(loom__vdb *v, int64_t x0, int64_t y, int64_t z, size_t n,
                             const float *values, loom_diag *diag)
{
	if (!v || v->failed || v->kind < 0)
		return loom__fail(diag, LOOM_EUNUSABLE, "VDB writer: no grid started");
	try {
		openvdb::Coord c((int)x0, (int)y, (int)z);
		if (v->kind == LOOM__VDB_FLOAT) {
			openvdb::FloatGrid::Accessor acc = v->fg->getAccessor();
			for (size_t i = 0; i < n; i++, c.x()++)
				if (values[i] != 0.0f)
					acc.setValueOn(c, values[i]);
		} else if (v->kind == LOOM__VDB_VEC3) {
			openvdb::Vec3SGrid::Accessor acc = v->vg->getAccessor();
			for (size_t i = 0; i < n; i++, c.x()++) {
				const float *p = values + 3 * i;
				if (p[0] != 0.0f || p[1] != 0.0f || p[2] != 0.0f)
					acc.setValueOn(c, openvdb::Vec3s(p[0], p[1], p[2]));
			}
		} else {
			openvdb::Int32Grid::Accessor acc = v->ig->getAccessor();
			for (size_t i = 0; i < n; i++, c.x()++)
				if (values[i] != 0.0f)
					acc.setValueOn(c, (int32_t)values[i]);
		}
	} catch (const std::exception &e) {
		return vdb_exception(v, diag, "OpenVDB", e.what());
	}
	return LOOM_OK;
}

/*
 * OpenVDB writes a random UUID into every file header (bytes 21..56, after
 * the magic, the file and library versions and the grid-offsets flag).
 * loom's exports are deterministic, so it is replaced by one derived from
 * the rest of the file's bytes (two FNV-1a 64-bit hashes, formatted as a
 * version-4 UUID): the same grids give the same file, and files with other
 * contents other UUIDs, which is what OpenVDB's readers use it for.
 */
#define VDB_UUID_AT 21
#define VDB_UUID_LEN 36
static void vdb_fix_uuid(const std::string &tmp)
{
	int fd = open(tmp.c_str(), O_RDWR | O_CLOEXEC);
	uint64_t h1 = 14695981039346656037ull, h2 = 0x9e3779b97f4a7c15ull;
	unsigned char buf[65536];
	char uuid[VDB_UUID_LEN + 1];
	off_t off = 0;
	ssize_t n;

	if (fd < 0)
		throw std::runtime_error("cannot reopen " + tmp + ": " + std::strerror(errno));
	if (pread(fd, uuid, VDB_UUID_LEN, VDB_UUID_AT) != VDB_UUID_LEN || uuid[8] != '-' ||
	    uuid[13] != '-' || uuid[18] != '-' || uuid[23] != '-') {
		close(fd);
		throw std::runtime_error(tmp + ": no UUID at byte 21 of the OpenVDB header");
	}
	while ((n = pread(fd, buf, sizeof buf, off)) > 0) {
		for (ssize_t i = 0; i < n; i++) {
			off_t at = off + i;
			if (at >= VDB_UUID_AT && at < VDB_UUID_AT + VDB_UUID_LEN)
				continue;
			h1 = (h1 ^ buf[i]) * 1099511628211ull;
			h2 = (h2 ^ buf[i]) * 1099511628211ull;
		}
		off += n;
	}
	h1 = (h1 & ~(0xfull << 12)) | (0x4ull << 12);    /* version 4 */
	h2 = (h2 & ~(0x3ull << 62)) | (0x2ull << 62);    /* RFC 4122 variant */
	std::snprintf(uuid, sizeof uuid, "%08x-%04x-%04x-%04x-%012llx", (unsigned)(h1 >> 32),
	              (unsigned)(h1 >> 16) & 0xffffu, (unsigned)h1 & 0xffffu,
	              (unsigned)(h2 >> 48), (unsigned long long)(h2 & 0xffffffffffffull));
	if (n < 0 || pwrite(fd, uuid, VDB_UUID_LEN, VDB_UUID_AT) != VDB_UUID_LEN) {
		close(fd);
		throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
	}
	if (close(fd) != 0)
		throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
}

/* fsync a file by name (the writers below own their streams). */
static int vdb_sync(const char *path)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	int rc;

	if (fd < 0)
		return -1;
	rc = fsync(fd);
	if (close(fd) != 0)
		rc = -1;
	return rc;
}

extern "C" int loom__vdb_write(loom__vdb *v, const char *path, loom_diag *diag)
{
	std::string tmp;

	if (!v || v->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "VDB writer: unusable after an error");
	tmp = std::string(path) + ".tmp." + std::to_string((long)getpid()) + "." +
	      std::to_string(vdb_tmp_counter.fetch_add(1));
	try {
		vdb_prune_current(v);
		if (v->format == LOOM__VDB_OPENVDB) {
			openvdb::io::File f(tmp);
			uint32_t comp = openvdb::io::COMPRESS_ACTIVE_MASK;
			if (v->codec == LOOM__VDB_BLOSC)
				comp |= openvdb::io::COMPRESS_BLOSC;
			else if (v->codec == LOOM__VDB_ZIP)
				comp |= openvdb::io::COMPRESS_ZIP;
			f.setCompression(comp);
			openvdb::MetaMap meta;
			meta.insertMeta("creator", openvdb::StringMetadata("loom export"));
			f.write(v->grids, meta);
			f.close();
			vdb_fix_uuid(tmp);
		}
#ifdef LOOM_HAVE_NANOVDB
		else {
			std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> handles;
			for (const openvdb::GridBase::Ptr &g : v->grids)
				handles.push_back(nanovdb::openToNanoVDB(g, nanovdb::StatsMode::Default,
				                                         nanovdb::ChecksumMode::Full));
			std::ofstream os(tmp, std::ios::out | std::ios::binary | std::ios::trunc);
			if (!os)
				throw std::runtime_error("cannot create " + tmp + ": " +
				                         std::strerror(errno));
			nanovdb::io::writeGrids(os, handles, nanovdb::io::Codec::NONE);
			os.flush();
			if (!os)
				throw std::runtime_error("cannot write " + tmp);
			os.close();
		}
#endif
		if (vdb_sync(tmp.c_str()) != 0)
			throw std::runtime_error("cannot sync " + tmp + ": " + std::strerror(errno));
		if (std::rename(tmp.c_str(), path) != 0)
			throw std::runtime_error("cannot rename " + tmp + " to " + path + ": " +
			                         std::strerror(errno));
	} catch (const std::exception &e) {
		std::remove(tmp.c_str());
		v->failed = true;
		return loom__fail(diag, LOOM_EIO, "%s: %s", path, e.what());
	}
	return LOOM_OK;
}

extern "C" void loom__vdb_free(loom__vdb *v)
{
	delete v;
}

#endif /* LOOM_HAVE_OPENVDB */
