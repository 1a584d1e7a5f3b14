/*
 * tests/cli/vdb_check.cpp - an independent reader of loom's .vdb and .nvdb
 * exports for tests/cli/test_vdb.sh, through OpenVDB's and NanoVDB's own
 * headers (not loom's shim):
 *
 *   vdb_check info FILE.vdb     one line per grid: name, type, class,
 *                               active voxels, index bbox, voxel size,
 *                               world position of index (0,0,0), the
 *                               loom_tile_lo / loom_tile_hi metadata
 *   vdb_check values FILE.vdb   for each "i j k" line on stdin: "i j k"
 *                               then each grid's value(s) there
 *   vdb_check nano FILE.nvdb    one line per grid: name, type, class,
 *                               full checksum valid, grid valid, active
 *                               voxels, voxel size, world of (0,0,0)
 *   vdb_check nanovalues FILE.nvdb   as values, from the NanoVDB grids
 */
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/GridChecksum.h>
#include <nanovdb/util/GridValidator.h>
#include <nanovdb/util/IO.h>

#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

static void print_meta_vec(const openvdb::GridBase &g, const char *key)
{
	openvdb::Vec3i v(0);
	if (auto m = g.getMetadata<openvdb::Vec3IMetadata>(key))
		v = m->value();
	std::printf(" %s %d %d %d", key, v[0], v[1], v[2]);
}

static int vdb_info(const char *path)
{
	openvdb::io::File f(path);
	f.open();
	openvdb::GridPtrVecPtr grids = f.getGrids();
	for (const openvdb::GridBase::Ptr &g : *grids) {
		openvdb::CoordBBox bb = g->evalActiveVoxelBoundingBox();
		openvdb::Vec3d w = g->transform().indexToWorld(openvdb::Vec3d(0, 0, 0));
		std::string cls = openvdb::GridBase::gridClassToString(g->getGridClass());
		for (char &ch : cls)
			if (ch == ' ')
				ch = '_';
		std::printf("grid %s type %s class %s active %llu bbox %d %d %d %d %d %d voxel %.9g "
		            "world0 %.9g %.9g %.9g", g->getName().c_str(), g->valueType().c_str(),
		            cls.c_str(),
		            (unsigned long long)g->activeVoxelCount(), bb.min().x(), bb.min().y(),
		            bb.min().z(), bb.max().x(), bb.max().y(), bb.max().z(),
		            g->transform().voxelSize()[0], w[0], w[1], w[2]);
		print_meta_vec(*g, "loom_tile_lo");
		print_meta_vec(*g, "loom_tile_hi");
		std::printf("\n");
	}
	f.close();
	return 0;
}

static int vdb_values(const char *path)
{
	openvdb::io::File f(path);
	f.open();
	openvdb::GridPtrVecPtr grids = f.getGrids();
	f.close();
	int i, j, k;
	while (std::scanf("%d %d %d", &i, &j, &k) == 3) {
		openvdb::Coord c(i, j, k);
		std::printf("%d %d %d", i, j, k);
		for (const openvdb::GridBase::Ptr &g : *grids) {
			if (auto fg = openvdb::GridBase::grid<openvdb::FloatGrid>(g))
				std::printf(" %.9g", fg->getConstAccessor().getValue(c));
			else if (auto vg = openvdb::GridBase::grid<openvdb::Vec3SGrid>(g)) {
				openvdb::Vec3s v = vg->getConstAccessor().getValue(c);
				std::printf(" %.9g %.9g %.9g", v[0], v[1], v[2]);
			} else if (auto ig = openvdb::GridBase::grid<openvdb::Int32Grid>(g))
				std::printf(" %d", ig->getConstAccessor().getValue(c));
			else
				std::printf(" ?");
		}
		std::printf("\n");
	}
	return 0;
}

template <typename T>
static void nano_check(const nanovdb::NanoGrid<T> *g, bool &sum, bool &valid,
                       nanovdb::Vec3d &w0)
{
	sum = nanovdb::validateChecksum(*g, nanovdb::ChecksumMode::Full);
	valid = nanovdb::isValid(*g, true);
	w0 = g->indexToWorld(nanovdb::Vec3d(0, 0, 0));
}

static int nano_info(const char *path)
{
	std::vector<nanovdb::GridHandle<>> hs = nanovdb::io::readGrids(path);
	for (auto &h : hs) {
		const nanovdb::GridMetaData *m = h.gridMetaData();
		bool sum = false, valid = false;
		nanovdb::Vec3d w(0, 0, 0);
		if (auto g = h.grid<float>())
			nano_check(g, sum, valid, w);
		else if (auto v = h.grid<nanovdb::Vec3f>())
			nano_check(v, sum, valid, w);
		else if (auto n = h.grid<int32_t>())
			nano_check(n, sum, valid, w);
		std::printf("grid %s type %s class %s checksum %s valid %s active %llu voxel %.9g "
		            "world0 %.9g %.9g %.9g\n", m->shortGridName(),
		            nanovdb::toStr(m->gridType()), nanovdb::toStr(m->gridClass()),
		            sum ? "ok" : "BAD", valid ? "ok" : "BAD",
		            (unsigned long long)m->activeVoxelCount(), m->voxelSize()[0], w[0], w[1],
		            w[2]);
	}
	return 0;
}

static int nano_values(const char *path)
{
	std::vector<nanovdb::GridHandle<>> hs = nanovdb::io::readGrids(path);
	int i, j, k;
	while (std::scanf("%d %d %d", &i, &j, &k) == 3) {
		nanovdb::Coord c(i, j, k);
		std::printf("%d %d %d", i, j, k);
		for (auto &h : hs) {
			if (auto g = h.grid<float>())
				std::printf(" %.9g", g->tree().getValue(c));
			else if (auto v = h.grid<nanovdb::Vec3f>()) {
				nanovdb::Vec3f x = v->tree().getValue(c);
				std::printf(" %.9g %.9g %.9g", x[0], x[1], x[2]);
			} else if (auto n = h.grid<int32_t>())
				std::printf(" %d", n->tree().getValue(c));
			else
				std::printf(" ?");
		}
		std::printf("\n");
	}
	return 0;
}

int main(int argc, char **argv)
{
	if (argc != 3) {
		std::fprintf(stderr, "usage: vdb_check info|values|nano|nanovalues FILE\n");
		return 2;
	}
	try {
		openvdb::initialize();
		std::string cmd = argv[1];
		if (cmd == "info")
			return vdb_info(argv[2]);
		if (cmd == "values")
			return vdb_values(argv[2]);
		if (cmd == "nano")
			return nano_info(argv[2]);
		if (cmd == "nanovalues")
			return nano_values(argv[2]);
	} catch (const std::exception &e) {
		std::fprintf(stderr, "vdb_check: %s: %s\n", argv[2], e.what());
		return 1;
	}
	std::fprintf(stderr, "vdb_check: unknown command %s\n", argv[1]);
	return 2;
}
