/*
 * bench/bench_vdb.cpp - loom's virtual texture against OpenVDB and NanoVDB,
 * side by side in one process (docs/performance.md, "Peer benchmark").
 * The only C++ file of bench/; built by `make bench` when libopenvdb-dev
 * and libnanovdb-dev are installed (tools/deps.sh openvdb), skipped with a
 * message otherwise.  libloom stays C: this program links it like any
 * other client.
 *
 * The same region (default 16 x 16 crossings of the 900 x 1500 Jacquard of
 * bench_texture over the paper preset database, the whole thickness) is
 * read once through loom_texture_read_region and materialised as
 *   - an OpenVDB FloatGrid of density (active where density > 0, pruned,
 *     background 0) and a second FloatGrid of orientation codes (for the
 *     density + orientation lookups; codes are integers below 2^16, exact
 *     in a float);
 *   - the same two grids as NanoVDB grids (openToNanoVDB);
 *   - a dense array (density byte + orientation code, x fastest).
 * Then, per core (thread CPU seconds), the backends interleaved in every
 * repetition, medians of REPS:
 *   random   density at uniformly random voxels of the region
 *   rays     density along rays: random start and direction, unit steps,
 *            up to 256 steps inside the region (voxel = floor of position)
 *   tri-rnd  trilinear density at random real positions
 *   tri-ray  trilinear density along the rays
 *   do-rnd   density + orientation (decoded to a unit vector) at random
 *            voxels;  do-ray  the same along rays
 * loom answers through its public calls, asking for the channels each
 * measure needs (loom_texture_voxel_ch, loom_texture_sample_ch with
 * LOOM_FILTER_TRILINEAR); OpenVDB through a
 * ValueAccessor per grid (tools::BoxSampler for trilinear), NanoVDB through
 * its accessor (SampleFromVoxels order 1).  Every backend's looked-up
 * values are summed into checksums; the bench checks that loom's equal
 * OpenVDB's (exactly for the voxel lookups: density bytes and decoded
 * orientations; to a relative 1e-5 for trilinear, the two blend in a
 * different order) and exits 1 when they do not.
 *
 * Below the working set: the two FloatGrids are written to a .vdb file and
 * child processes look up random voxels and ray walks of the region from
 * cold: OpenVDB with delayed loading (io::File::open(true); leaves are read
 * on first touch and never evicted) and loom at budgets of 16 and 64 MiB.
 * Their per-core rates, checksums (must agree) and peak RSS (VmHWM),
 * with each child's RSS before it opens anything (its base: libraries,
 * OpenVDB initialised) and loom's against budget + 16 MiB.  loom's child
 * is bench_texture --vdb-child (the same work in C, built next to this
 * binary), so its peak RSS carries no OpenVDB, TBB or libstdc++.
 *
 *   build/bench/bench_vdb              the full run (~2 GB of RAM, minutes)
 *   build/bench/bench_vdb --check      a small run on the default database
 *                                      (a test of the bench: checksums must
 *                                      agree; tests/cli/test_bench_vdb.sh)
 * Environment: BENCH_VDB_CROSSINGS (region side in crossings, default 16),
 * BENCH_VDB_SCALE (multiplies the lookup counts), LOOM_PAPER_DB, BUILD.
 * Output: tables on stdout and one JSON line per figure ("{...}").
 */
#include "loom.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/Prune.h>
#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/OpenToNanoVDB.h>
#include <nanovdb/util/SampleFromVoxels.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_usage.h"

static const char USAGE[] =
	"usage: bench_vdb [--check]\n"
	"loom's texture against OpenVDB and NanoVDB in one process: random points,\n"
	"ray walks, trilinear, density + orientation, and below the working set\n"
	"against OpenVDB delayed loading (budgets 16 and 64 MiB); checksums must\n"
	"agree (exit 1 otherwise).  The full run takes minutes and ~2 GB of RAM.\n"
	"  --check    a small run on the default database (a test of the bench)\n"
	"Environment: BENCH_VDB_CROSSINGS (region side, default 16), BENCH_VDB_SCALE,\n"
	"BENCH_VDB_BRICK=XxYxZ (the paper database's brick shape, default 16x16x64;\n"
	"another shape is generated as $BUILD/bench/paper-XxYxZ.ldb), BENCH_VDB_FORMAT=2|3\n"
	"(the paper database in format version 2 or 3 instead of the default 4,\n"
	"$BUILD/bench/paper[-XxYxZ]-vN.ldb: density deflated, 3 in segments),\n"
	"BENCH_VDB_DENSITY=raw (the density planes stored raw, loom exemplar generate\n"
	"--raw-density: paper[-XxYxZ][-vN]-rawd.ldb), BENCH_VDB_EDGE=full|rank15|default\n"
	"(the fabric with loom synth --edge-fix full, the exact edge fix, or --rank 15,\n"
	"the default before 2026-12-07; default: the library's default, full rank),\n"
	"LOOM_PAPER_DB,\n"
	"BUILD (default build).\n";

namespace {

const size_t MIB = (size_t)1 << 20;
const int REPS = 5;

/* ------------------------------------------------------------- helpers */

uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

double unit(uint64_t *s) /* [0, 1) */
{
	*s = mix(*s);
	return (double)(*s >> 11) / 9007199254740992.0;
}

double cpu_s()
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double wall_s()
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

std::string loadavg()
{
	char b[128] = "?";
	FILE *f = fopen("/proc/loadavg", "r");
	if (f) {
		if (!fgets(b, sizeof b, f))
			strcpy(b, "?");
		fclose(f);
	}
	std::string s(b);
	size_t k = s.find(' ');
	k = s.find(' ', k == std::string::npos ? 0 : k + 1);
	k = s.find(' ', k == std::string::npos ? 0 : k + 1);
	return s.substr(0, k);
}

/* A "Vm...:" field of /proc/self/status in KiB (key with its colon), -1
   when absent. */
long vm_kib(const char *key)
{
	char line[256];
	long v = -1;
	size_t n = strlen(key);
	FILE *f = fopen("/proc/self/status", "r");
	if (!f)
		return -1;
	while (fgets(line, sizeof line, f))
		if (strncmp(line, key, n) == 0)
			v = atol(line + n);
	fclose(f);
	return v;
}

long vm_hwm_kib()
{
	return vm_kib("VmHWM:");
}

/* A child's resident set before it opens anything of loom's or OpenVDB's
   (libraries, openvdb::initialize): the process itself. */
long g_base_kib = -1;

/* Orientation code -> unit direction, z >= 0: the arithmetic of libloom's
   decoder (docs/formats.md, "Voxel encodings"), inline for the peers. */
inline void orient_decode(uint16_t code, float out[3])
{
	float s = (float)(code & 0xff) * (1.0f / 127.5f) - 1.0f;
	float t = (float)(code >> 8) * (1.0f / 127.5f) - 1.0f;
	float px = 0.5f * (s + t), py = 0.5f * (s - t);
	float pz = 1.0f - std::fabs(px) - std::fabs(py);
	if (pz < 0.0f)
		pz = 0.0f;
	float inv = 1.0f / std::sqrt(px * px + py * py + pz * pz);
	out[0] = px * inv;
	out[1] = py * inv;
	out[2] = pz * inv;
}

/* Twill 2/3 and satin 4/1 over a blocky random mask (as bench_texture). */
loom_design *jacquard(uint32_t rows, uint32_t cols)
{
	loom_weave_params a, b;
	loom_design *d = NULL;

	loom_weave_parse("twill:2/3", &a, NULL);
	loom_weave_parse("satin:4/1", &b, NULL);
	if (loom_design_make(&a, rows, cols, &d, NULL) != LOOM_OK ||
	    loom_design_set_types(d, 3) != LOOM_OK)
		return NULL;
	for (uint32_t i = 0; i < rows; i++)
		for (uint32_t j = 0; j < cols; j++) {
			uint64_t h = mix(((uint64_t)(i / 48) << 32) | (j / 64));
			size_t c = (size_t)i * cols + j;
			if (h & 1)
				d->weave[c] = (uint8_t)loom_weave_cell(&b, i, j);
			d->warp_type[c] = (uint8_t)(h >> 1 & 1);
			d->weft_type[c] = 2;
		}
	return d;
}

/* ------------------------------------------------------------ the setup */

struct Setup {
	std::string build, dbp, fabp, vdbp;
	bool check = false;
	double scale = 1.0;
	int xings = 16;
	loom_db *db = NULL;
	loom_fabric *fab = NULL;
	int64_t lo[3] = {0, 0, 0};     /* region in bolt voxels */
	int n[3] = {0, 0, 0};          /* its size; local coordinates 0..n-1 */
	unsigned brick[3] = {0, 0, 0}; /* BENCH_VDB_BRICK, 0: the preset's */
	unsigned format = 4;           /* BENCH_VDB_FORMAT: the database's version */
	bool raw_density = false;      /* BENCH_VDB_DENSITY=raw */
	int edge_rank = 0;             /* BENCH_VDB_EDGE: 128 full, 15 rank15,
	                                  0 the library's default */
};

/* Open (making when missing) the database and the fabric. */
bool setup_open(Setup &S)
{
	loom_diag diag;
	memset(&diag, 0, sizeof diag);
	struct stat st;
	const char *paper = getenv("LOOM_PAPER_DB");
	const unsigned *brick = S.brick;
	if (S.check)
		S.dbp = S.build + "/share/loom/default.ldb";
	else if (paper && *paper)
		S.dbp = paper;
	else
		S.dbp = S.build + "/bench/paper" +
		        (brick[0] ? std::string("-") + getenv("BENCH_VDB_BRICK") : std::string()) +
		        (S.format != 4 ? "-v" + std::to_string(S.format) : std::string()) +
		        (S.raw_density ? "-rawd" : "") + ".ldb";
	bool stale = false; /* a generated database of another format version */
	if (!S.check && !(paper && *paper) && stat(S.dbp.c_str(), &st) == 0) {
		loom_db *old = NULL;
		loom_db_info oi;
		if (loom_db_open(S.dbp.c_str(), &old, &diag) == LOOM_OK) {
			loom_db_get_info(old, &oi);
			stale = oi.version != S.format ||
			        (oi.n_raw_density > 0) != S.raw_density;
			loom_db_close(old);
		}
		if (stale)
			printf("%s is of format version %u, density %s: generated again in "
			       "version %u, density %s\n", S.dbp.c_str(), oi.version,
			       oi.n_raw_density ? "raw" : "compressed", S.format,
			       S.raw_density ? "raw" : "compressed");
	}
	if (!S.check && (stale || stat(S.dbp.c_str(), &st) != 0)) {
		loom_exgen_params p;
		printf("generating the paper preset database %s (once, ~10-20 s)\n", S.dbp.c_str());
		fflush(stdout);
		loom_exgen_preset("paper", &p);
		p.db_version = S.format;
		p.density_raw = S.raw_density;
		if (brick[0])
			for (int a = 0; a < 3; a++)
				p.brick[a] = brick[a];
		if (loom_exgen_write_db(S.dbp.c_str(), &p, NULL, &diag) != LOOM_OK) {
			printf("bench_vdb: %s\n", diag.message);
			return false;
		}
	}
	if (loom_db_open(S.dbp.c_str(), &S.db, &diag) != LOOM_OK) {
		printf("bench_vdb: %s\n", diag.message);
		return false;
	}
	loom_db_info info;
	loom_db_get_info(S.db, &info);
	printf("database %s: %.1f MB, %u exemplars, block %ux%ux%u%s\n", S.dbp.c_str(),
	       info.file_bytes / 1e6, info.n_exemplars, info.block[0], info.block[1],
	       info.block[2], S.check ? "" : paper && *paper ? " (LOOM_PAPER_DB)" :
	       " (the library's paper preset, smooth yarns: not the CLI's cotton "
	       "--preset paper, docs/exemplars.md)");
	loom_design *d = S.check ? jacquard(60, 80) : jacquard(900, 1500);
	loom_fabric_options fo = LOOM_FABRIC_OPTIONS_INIT;
	if (S.edge_rank)
		fo.rank = (uint32_t)S.edge_rank; /* loom synth --edge-fix full / --rank 15 */
	if (!d || loom_fabric_synthesize(d, S.db, S.dbp.c_str(), &fo, &S.fab, &diag) != LOOM_OK) {
		printf("bench_vdb: synthesis: %s\n", diag.message);
		return false;
	}
	loom_design_free(d);
	if (loom_fabric_save(S.fab, S.fabp.c_str(), NULL, &diag) != LOOM_OK) {
		printf("bench_vdb: %s\n", diag.message);
		return false;
	}
	/* crossings from (11, 7) on, away from the origin; the whole thickness */
	S.lo[0] = 7 * (int64_t)info.block[0];
	S.lo[1] = 11 * (int64_t)info.block[1];
	S.lo[2] = 0;
	S.n[0] = S.xings * (int)info.block[0];
	S.n[1] = S.xings * (int)info.block[1];
	S.n[2] = (int)info.block[2];
	printf("region: %d x %d crossings of a %s Jacquard over %s, %d x %d x %d = %.0f M "
	       "voxels (blocks %u x %u x %u)\n", S.xings, S.xings, S.check ? "60x80" : "900x1500",
	       S.dbp.c_str(), S.n[0], S.n[1], S.n[2], (double)S.n[0] * S.n[1] * S.n[2] / 1e6,
	       info.block[0], info.block[1], info.block[2]);
	return true;
}

loom_texture *tex_open(Setup &S, size_t budget)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_diag diag;
	memset(&diag, 0, sizeof diag);
	loom_texture *t = NULL;
	o.budget_bytes = budget;
	o.max_threads = 2;
	if (loom_texture_open(S.fab, S.db, &o, &t, &diag) != LOOM_OK) {
		printf("bench_vdb: %s\n", diag.message);
		return NULL;
	}
	return t;
}

/* ----------------------------------------------------- the materialised */

struct Mat {
	openvdb::FloatGrid::Ptr dg, og;   /* density, orientation codes */
	nanovdb::GridHandle<nanovdb::HostBuffer> dh, oh;
	std::vector<uint8_t> dd;          /* dense density, x fastest */
	std::vector<uint16_t> doo;        /* dense orientation codes */
	uint64_t active = 0;
};

bool materialise(Setup &S, loom_texture *t, Mat &M)
{
	size_t nx = (size_t)S.n[0], ny = (size_t)S.n[1], nz = (size_t)S.n[2];
	size_t band = 64;
	std::vector<uint8_t> d(nx * band * nz);
	std::vector<uint16_t> o(nx * band * nz);
	double t0 = wall_s();

	M.dd.assign(nx * ny * nz, 0);
	M.doo.assign(nx * ny * nz, 0);
	M.dg = openvdb::FloatGrid::create(0.0f);
	M.og = openvdb::FloatGrid::create(0.0f);
	M.dg->setName("density");
	M.og->setName("orientation");
	auto da = M.dg->getAccessor();
	auto oa = M.og->getAccessor();
	for (size_t y0 = 0; y0 < ny; y0 += band) {
		size_t by = std::min(band, ny - y0);
		int64_t lo[3] = {S.lo[0], S.lo[1] + (int64_t)y0, S.lo[2]};
		int64_t hi[3] = {S.lo[0] + (int64_t)nx, lo[1] + (int64_t)by, S.lo[2] + (int64_t)nz};
		loom_texture_region r;
		memset(&r, 0, sizeof r);
		r.density = d.data();
		r.orientation = o.data();
		r.layout = LOOM_REGION_X_FASTEST;
		if (loom_texture_read_region(t, lo, hi, &r) != LOOM_OK) {
			printf("bench_vdb: region read: %s\n", loom_texture_errmsg(t));
			return false;
		}
		for (size_t z = 0; z < nz; z++)
			for (size_t y = 0; y < by; y++) {
				size_t src = (z * by + y) * nx, dst = (z * ny + y0 + y) * nx;
				memcpy(&M.dd[dst], &d[src], nx);
				memcpy(&M.doo[dst], &o[src], 2 * nx);
				for (size_t x = 0; x < nx; x++) {
					uint8_t v = d[src + x];
					if (!v)
						continue;
					openvdb::Coord c((int)x, (int)(y0 + y), (int)z);
					da.setValueOn(c, (float)v / 255.0f);
					oa.setValueOn(c, (float)o[src + x]);
					M.active++;
				}
			}
	}
	if (getenv("BENCH_VDB_PERTURB")) /* the bench's own test: must DIFFER */
		for (auto it = M.dg->beginValueOn(); it; ++it)
			it.setValue(*it + 1.0f / 255.0f);
	openvdb::tools::prune(M.dg->tree());
	openvdb::tools::prune(M.og->tree());
	M.dh = nanovdb::openToNanoVDB(*M.dg);
	M.oh = nanovdb::openToNanoVDB(*M.og);
	printf("materialised in %.1f s: %llu active voxels (%.1f%%)\n", wall_s() - t0,
	       (unsigned long long)M.active, 100.0 * (double)M.active / ((double)nx * ny * nz));
	return true;
}

/* ------------------------------------------------------------ workloads */

/* Pre-generated positions, local voxel units (voxel centres at i + 0.5). */
struct Work {
	std::vector<int32_t> pi;     /* random voxels: x y z */
	std::vector<double> pr;      /* random real positions inside the
	                                centres' hull: x y z */
	std::vector<double> ray;     /* rays: start x y z, unit dir x y z */
	size_t n_pts = 0, n_rays = 0;
	int steps = 256;
};

void work_make(const Setup &S, Work &W, size_t n_pts, size_t n_rays, uint64_t seed)
{
	uint64_t s = seed;
	W.n_pts = n_pts;
	W.n_rays = n_rays;
	W.pi.resize(3 * n_pts);
	W.pr.resize(3 * n_pts);
	W.ray.resize(6 * n_rays);
	for (size_t i = 0; i < n_pts; i++)
		for (int a = 0; a < 3; a++) {
			W.pi[3 * i + a] = (int32_t)(unit(&s) * S.n[a]);
			W.pr[3 * i + a] = 0.5 + unit(&s) * (S.n[a] - 1);
		}
	for (size_t i = 0; i < n_rays; i++) {
		double dir[3], len = 0;
		for (int a = 0; a < 3; a++) {
			W.ray[6 * i + a] = 0.5 + unit(&s) * (S.n[a] - 1);
			dir[a] = 2 * unit(&s) - 1;
			len += dir[a] * dir[a];
		}
		len = std::sqrt(len);
		for (int a = 0; a < 3; a++)
			W.ray[6 * i + 3 + a] = len > 0 ? dir[a] / len : (a == 2);
	}
}

/* Walk ray i: calls f(p) for each position inside the hull of the voxel
   centres (so that trilinear corners stay in the region), unit steps. */
template <class F> inline size_t walk(const Setup &S, const Work &W, size_t i, F f)
{
	const double *r = &W.ray[6 * i];
	double p[3] = {r[0], r[1], r[2]};
	size_t k = 0;
	for (; k < (size_t)W.steps; k++) {
		if (!(p[0] >= 0.5 && p[0] <= S.n[0] - 0.5 && p[1] >= 0.5 && p[1] <= S.n[1] - 0.5 &&
		      p[2] >= 0.5 && p[2] <= S.n[2] - 0.5))
			break;
		f(p);
		p[0] += r[3], p[1] += r[4], p[2] += r[5];
	}
	return k;
}

enum Measure { M_RANDOM, M_RAYS, M_TRI_RND, M_TRI_RAY, M_DO_RND, M_DO_RAY, N_MEASURES };
const char *const measure_name[N_MEASURES] = {"random points", "ray walks", "trilinear random",
                                              "trilinear rays", "dens+orient random",
                                              "dens+orient rays"};
const char *const measure_key[N_MEASURES] = {"random", "rays", "tri_random", "tri_rays",
                                             "do_random", "do_rays"};
enum Backend { B_LOOM, B_VDB, B_NANO, B_DENSE, N_BACKENDS };
const char *const backend_name[N_BACKENDS] = {"loom", "openvdb", "nanovdb", "dense"};

/* Checksums: ck_i exact (density bytes, orientation bits summed as
   integers), ck_f the sum of trilinear densities. */
struct Sum {
	uint64_t ck_i = 0;
	double ck_f = 0;
	uint64_t n = 0;
	int errors = 0;
};

inline uint64_t dbyte(float v)
{
	return (uint64_t)std::lround(v * 255.0f);
}

inline uint64_t obits(const float v[3])
{
	uint32_t b[3];
	memcpy(b, v, sizeof b);
	return (uint64_t)b[0] + b[1] + b[2];
}

/* One backend's run of one measure. */
struct Ctx {
	const Setup *S;
	const Work *W;
	loom_texture *t;
	const Mat *M;
};

template <class Dens, class DensOri, class Tri>
Sum run_generic(const Ctx &c, Measure m, Dens dens, DensOri dori, Tri tri)
{
	const Setup &S = *c.S;
	const Work &W = *c.W;
	Sum s;
	switch (m) {
	case M_RANDOM:
		for (size_t i = 0; i < W.n_pts; i++) {
			const int32_t *q = &W.pi[3 * i];
			s.ck_i += dbyte(dens(q[0], q[1], q[2]));
		}
		s.n = W.n_pts;
		break;
	case M_DO_RND:
		for (size_t i = 0; i < W.n_pts; i++) {
			const int32_t *q = &W.pi[3 * i];
			float v[3];
			s.ck_i += dbyte(dori(q[0], q[1], q[2], v));
			s.ck_i += obits(v);
		}
		s.n = W.n_pts;
		break;
	case M_TRI_RND:
		for (size_t i = 0; i < W.n_pts; i++)
			s.ck_f += tri(&W.pr[3 * i]);
		s.n = W.n_pts;
		break;
	case M_RAYS:
	case M_DO_RAY:
	case M_TRI_RAY:
		for (size_t i = 0; i < W.n_rays; i++)
			s.n += walk(S, W, i, [&](const double *p) {
				int32_t q[3] = {(int32_t)p[0], (int32_t)p[1], (int32_t)p[2]};
				if (m == M_RAYS) {
					s.ck_i += dbyte(dens(q[0], q[1], q[2]));
				} else if (m == M_DO_RAY) {
					float v[3];
					s.ck_i += dbyte(dori(q[0], q[1], q[2], v));
					s.ck_i += obits(v);
				} else {
					s.ck_f += tri(p);
				}
			});
		break;
	default:
		break;
	}
	return s;
}

Sum run_loom(const Ctx &c, Measure m)
{
	loom_texture *t = c.t;
	const int64_t *lo = c.S->lo;
	int errors = 0;
	/* the channel-masked calls: only the planes asked for */
	const unsigned D = LOOM_CHANNEL_DENSITY, DO = D | LOOM_CHANNEL_ORIENTATION;
	auto dens = [&](int32_t x, int32_t y, int32_t z) {
		loom_texel tx;
		errors += loom_texture_voxel_ch(t, lo[0] + x, lo[1] + y, lo[2] + z, D, &tx) != LOOM_OK;
		return tx.density;
	};
	auto dori = [&](int32_t x, int32_t y, int32_t z, float v[3]) {
		loom_texel tx;
		errors += loom_texture_voxel_ch(t, lo[0] + x, lo[1] + y, lo[2] + z, DO, &tx) != LOOM_OK;
		memcpy(v, tx.orientation, 3 * sizeof(float));
		return tx.density;
	};
	auto tri = [&](const double *p) {
		loom_texel tx;
		double q[3] = {(double)lo[0] + p[0], (double)lo[1] + p[1], (double)lo[2] + p[2]};
		errors += loom_texture_sample_ch(t, q, LOOM_FILTER_TRILINEAR, D, &tx) != LOOM_OK;
		return (double)tx.density;
	};
	Sum s = run_generic(c, m, dens, dori, tri);
	s.errors = errors;
	return s;
}

Sum run_vdb(const Ctx &c, Measure m)
{
	auto da = c.M->dg->getConstAccessor();
	auto oa = c.M->og->getConstAccessor();
	auto dens = [&](int32_t x, int32_t y, int32_t z) {
		return da.getValue(openvdb::Coord(x, y, z));
	};
	auto dori = [&](int32_t x, int32_t y, int32_t z, float v[3]) {
		openvdb::Coord q(x, y, z);
		float d = da.getValue(q);
		if (d > 0)
			orient_decode((uint16_t)oa.getValue(q), v);
		else
			v[0] = v[1] = v[2] = 0;
		return d;
	};
	auto tri = [&](const double *p) {
		openvdb::Vec3R q(p[0] - 0.5, p[1] - 0.5, p[2] - 0.5);
		return (double)openvdb::tools::BoxSampler::sample(da, q);
	};
	return run_generic(c, m, dens, dori, tri);
}

Sum run_nano(const Ctx &c, Measure m)
{
	const nanovdb::FloatGrid *dg = c.M->dh.grid<float>();
	const nanovdb::FloatGrid *og = c.M->oh.grid<float>();
	auto da = dg->getAccessor();
	auto oa = og->getAccessor();
	auto smp = nanovdb::createSampler<1>(da);
	auto dens = [&](int32_t x, int32_t y, int32_t z) {
		return da.getValue(nanovdb::Coord(x, y, z));
	};
	auto dori = [&](int32_t x, int32_t y, int32_t z, float v[3]) {
		nanovdb::Coord q(x, y, z);
		float d = da.getValue(q);
		if (d > 0)
			orient_decode((uint16_t)oa.getValue(q), v);
		else
			v[0] = v[1] = v[2] = 0;
		return d;
	};
	auto tri = [&](const double *p) {
		nanovdb::Vec3d q(p[0] - 0.5, p[1] - 0.5, p[2] - 0.5);
		return (double)smp(q);
	};
	return run_generic(c, m, dens, dori, tri);
}

Sum run_dense(const Ctx &c, Measure m)
{
	const uint8_t *dd = c.M->dd.data();
	const uint16_t *oo = c.M->doo.data();
	size_t nx = (size_t)c.S->n[0], nxy = nx * (size_t)c.S->n[1];
	int nz = c.S->n[2];
	const int *n = c.S->n;
	auto at = [&](int32_t x, int32_t y, int32_t z) -> float {
		if ((uint32_t)x >= (uint32_t)n[0] || (uint32_t)y >= (uint32_t)n[1] ||
		    (uint32_t)z >= (uint32_t)nz)
			return 0.0f;
		return (float)dd[(size_t)z * nxy + (size_t)y * nx + (size_t)x] / 255.0f;
	};
	auto dens = [&](int32_t x, int32_t y, int32_t z) { return at(x, y, z); };
	auto dori = [&](int32_t x, int32_t y, int32_t z, float v[3]) {
		size_t i = (size_t)z * nxy + (size_t)y * nx + (size_t)x;
		float d = (float)dd[i] / 255.0f;
		if (d > 0)
			orient_decode(oo[i], v);
		else
			v[0] = v[1] = v[2] = 0;
		return d;
	};
	auto tri = [&](const double *p) {
		double u[3] = {p[0] - 0.5, p[1] - 0.5, p[2] - 0.5};
		int32_t i0[3];
		double f[3];
		for (int a = 0; a < 3; a++) {
			i0[a] = (int32_t)std::floor(u[a]);
			f[a] = u[a] - i0[a];
		}
		double v = 0;
		for (int k = 0; k < 8; k++) {
			int dx = k & 1, dy = k >> 1 & 1, dz = k >> 2 & 1;
			double w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) *
			           (dz ? f[2] : 1 - f[2]);
			v += w * at(i0[0] + dx, i0[1] + dy, i0[2] + dz);
		}
		return v;
	};
	return run_generic(c, m, dens, dori, tri);
}

Sum run_backend(const Ctx &c, Backend b, Measure m, double *cpu)
{
	double c0 = cpu_s();
	Sum s;
	switch (b) {
	case B_LOOM: s = run_loom(c, m); break;
	case B_VDB: s = run_vdb(c, m); break;
	case B_NANO: s = run_nano(c, m); break;
	default: s = run_dense(c, m); break;
	}
	*cpu = cpu_s() - c0;
	return s;
}

double median(std::vector<double> v)
{
	std::sort(v.begin(), v.end());
	return v.empty() ? 0 : v[v.size() / 2];
}

bool same(const Sum &a, const Sum &b)
{
	if (a.n != b.n || a.ck_i != b.ck_i)
		return false;
	double m = std::max(std::fabs(a.ck_f), std::fabs(b.ck_f));
	return std::fabs(a.ck_f - b.ck_f) <= 1e-5 * m + 1e-9;
}

/* The warm table; returns false when a checksum differs. */
bool warm(const Setup &S, loom_texture *t, const Mat &M, const Work &W)
{
	Ctx c = {&S, &W, t, &M};
	bool ok = true;
	int reps = S.check ? 1 : REPS;
	printf("\nwarm lookups, 1 thread, M lookups/s per core (median of %d interleaved "
	       "repetitions); load average %s\n", reps, loadavg().c_str());
	printf("%-19s %9s %9s %9s %9s | %8s %8s %8s | %s\n", "measure", "loom", "openvdb",
	       "nanovdb", "dense", "l/vdb", "l/nano", "l/dense", "checksums");
	for (int m = 0; m < N_MEASURES; m++) {
		std::vector<double> rate[N_BACKENDS];
		Sum sum[N_BACKENDS];
		/* one untimed warm-up pass of loom (the bricks and crossings) */
		double cpu;
		run_backend(c, B_LOOM, (Measure)m, &cpu);
		for (int r = 0; r < reps; r++)
			for (int b = 0; b < N_BACKENDS; b++) {
				sum[b] = run_backend(c, (Backend)b, (Measure)m, &cpu);
				rate[b].push_back((double)sum[b].n / std::max(cpu, 1e-9));
			}
		double med[N_BACKENDS];
		for (int b = 0; b < N_BACKENDS; b++)
			med[b] = median(rate[b]);
		bool eq = same(sum[B_LOOM], sum[B_VDB]) && sum[B_LOOM].errors == 0;
		bool eqn = same(sum[B_LOOM], sum[B_NANO]) && same(sum[B_LOOM], sum[B_DENSE]);
		ok = ok && eq && eqn;
		printf("%-19s %9.2f %9.2f %9.2f %9.2f | %8.3f %8.3f %8.3f | %s\n", measure_name[m],
		       med[B_LOOM] / 1e6, med[B_VDB] / 1e6, med[B_NANO] / 1e6, med[B_DENSE] / 1e6,
		       med[B_LOOM] / med[B_VDB], med[B_LOOM] / med[B_NANO], med[B_LOOM] / med[B_DENSE],
		       eq && eqn ? "equal" : "DIFFER");
		if (!(eq && eqn))
			printf("  loom n=%llu i=%llu f=%.9g errors=%d; openvdb n=%llu i=%llu f=%.9g; "
			       "nanovdb i=%llu f=%.9g; dense i=%llu f=%.9g\n",
			       (unsigned long long)sum[0].n, (unsigned long long)sum[0].ck_i,
			       sum[0].ck_f, sum[0].errors, (unsigned long long)sum[1].n,
			       (unsigned long long)sum[1].ck_i, sum[1].ck_f,
			       (unsigned long long)sum[2].ck_i, sum[2].ck_f,
			       (unsigned long long)sum[3].ck_i, sum[3].ck_f);
		printf("{\"bench\":\"vdb_warm\",\"measure\":\"%s\",\"lookups\":%llu,"
		       "\"loom_per_core\":%.0f,\"openvdb_per_core\":%.0f,\"nanovdb_per_core\":%.0f,"
		       "\"dense_per_core\":%.0f,\"loom_vs_openvdb\":%.4f,\"loom_vs_nanovdb\":%.4f,"
		       "\"checksums_equal\":%s,\"load\":\"%s\"}\n", measure_key[m],
		       (unsigned long long)sum[B_LOOM].n, med[0], med[1], med[2], med[3],
		       med[0] / med[1], med[0] / med[2], eq && eqn ? "true" : "false",
		       loadavg().c_str());
	}
	return ok;
}

/* ---------------------------------------------- below the working set */

/* OpenVDB's child (loom's is bench_texture --vdb-child, the same work in
   C): from cold, random voxels then ray walks, density; prints
   "RESULT rnd_rate ray_rate ck_rnd ck_ray hwm_kib base_kib". */
int child(Setup &S, const char *what, const char *arg)
{
	Work W;
	size_t n_pts = (size_t)(S.scale * (S.check ? 2e4 : 3e5));
	size_t n_rays = (size_t)(S.scale * (S.check ? 200 : 4000));
	work_make(S, W, n_pts, n_rays, 99);
	Sum s[2];
	double rate[2];
	if (strcmp(what, "vdb") != 0)
		return 1;
	{
		openvdb::io::File file(arg);
		file.open(true); /* delayed loading */
		openvdb::FloatGrid::Ptr g =
		        openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("density"));
		if (!g)
			return 1;
		Mat M;
		M.dg = g;
		auto da = g->getConstAccessor();
		for (int k = 0; k < 2; k++) {
			double c0 = cpu_s();
			auto dens = [&](int32_t x, int32_t y, int32_t z) {
				return da.getValue(openvdb::Coord(x, y, z));
			};
			auto none = [&](int32_t, int32_t, int32_t, float *) { return 0.0f; };
			auto tri0 = [&](const double *) { return 0.0; };
			Ctx c = {&S, &W, NULL, &M};
			s[k] = run_generic(c, k ? M_RAYS : M_RANDOM, dens, none, tri0);
			rate[k] = (double)s[k].n / std::max(cpu_s() - c0, 1e-9);
		}
		file.close();
	}
	printf("RESULT %.0f %.0f %llu %llu %ld %ld\n", rate[0], rate[1],
	       (unsigned long long)s[0].ck_i, (unsigned long long)s[1].ck_i, vm_hwm_kib(),
	       g_base_kib);
	return 0;
}

struct ChildOut {
	double rnd = 0, ray = 0;
	unsigned long long ck_rnd = 0, ck_ray = 0;
	long hwm = 0, base = 0;
	bool ok = false;
};

/* loom's child is bench_texture --vdb-child (next to this binary): a C
   process, so its peak RSS is loom's own, without OpenVDB's libraries. */
std::string loom_child_cmd(const char *self, const Setup &S, const char *budget)
{
	std::string dir(self);
	size_t k = dir.rfind('/');
	dir = k == std::string::npos ? "." : dir.substr(0, k);
	size_t n_pts = (size_t)(S.scale * (S.check ? 2e4 : 3e5));
	size_t n_rays = (size_t)(S.scale * (S.check ? 200 : 4000));
	char num[256];
	snprintf(num, sizeof num, " %lld %lld %d %d %d %zu %zu %s", (long long)S.lo[0],
	         (long long)S.lo[1], S.n[0], S.n[1], S.n[2], n_pts, n_rays, budget);
	return "'" + dir + "/bench_texture' --vdb-child '" + S.dbp + "' '" + S.fabp + "'" + num;
}

/* The region for OpenVDB's child ("X0 Y0 NX NY NZ"): it needs nothing else
   of loom's, so it opens neither the database nor the fabric. */
std::string region_args(const Setup &S)
{
	char num[160];
	snprintf(num, sizeof num, " %lld %lld %d %d %d", (long long)S.lo[0], (long long)S.lo[1],
	         S.n[0], S.n[1], S.n[2]);
	return num;
}

ChildOut run_child(const char *self, const Setup &S, const char *what, const char *arg)
{
	ChildOut o;
	std::string cmd = strcmp(what, "loom") == 0
	                          ? loom_child_cmd(self, S, arg)
	                          : std::string("'") + self + "' " + (S.check ? "--check " : "") +
	                                    "--child " + what + " '" + arg + "'" + region_args(S);
	FILE *p = popen(cmd.c_str(), "r");
	char line[512];
	if (!p)
		return o;
	while (fgets(line, sizeof line, p))
		if (sscanf(line, "RESULT %lf %lf %llu %llu %ld %ld", &o.rnd, &o.ray, &o.ck_rnd,
		           &o.ck_ray, &o.hwm, &o.base) == 6)
			o.ok = true;
		else
			fputs(line, stdout);
	o.ok = pclose(p) == 0 && o.ok;
	return o;
}

bool below(const char *self, const Setup &S, const Mat &M)
{
	bool ok = true;
	{
		openvdb::io::File f(S.vdbp);
		openvdb::GridPtrVec grids;
		grids.push_back(M.dg);
		grids.push_back(M.og);
		f.write(grids);
		f.close();
	}
	struct stat st;
	stat(S.vdbp.c_str(), &st);
	printf("\nbelow the working set: from cold, 1 thread, density; OpenVDB delayed loading "
	       "of a %.1f MiB .vdb file\nagainst loom at a fixed budget (one process each, "
	       "peak RSS = VmHWM); load average %s\n", (double)st.st_size / MIB, loadavg().c_str());
	printf("base = the child's RSS before it opens anything (OpenVDB's: libraries, OpenVDB "
	       "initialised;\nloom's child is bench_texture --vdb-child, a C process without them);"
	       "\nloom's target: peak RSS <= budget + 16 MiB (\"limit\"; \"within\" also shown "
	       "for peak - base)\n");
	printf("%-22s %12s %12s %10s %8s | %8s %8s | %s\n", "backend", "random M/s", "rays M/s",
	       "peak RSS", "base", "rnd l/v", "ray l/v", "checksums");
	int reps = S.check ? 1 : 3;
	std::vector<double> vr, vy;
	ChildOut v;
	for (int r = 0; r < reps; r++) { /* interleaving below: vdb first each time */
		v = run_child(self, S, "vdb", S.vdbp.c_str());
		vr.push_back(v.rnd), vy.push_back(v.ray);
	}
	if (!v.ok) {
		printf("bench_vdb: the OpenVDB child failed\n");
		return false;
	}
	double vrm = median(vr), vym = median(vy);
	printf("%-22s %12.3f %12.3f %6.0f MiB %4.0f MiB | %8s %8s |\n", "openvdb delayed",
	       vrm / 1e6, vym / 1e6, v.hwm / 1024.0, v.base / 1024.0, "", "");
	const char *budgets[] = {"16", "64"};
	for (const char *b : budgets) {
		std::vector<double> lr, ly;
		ChildOut l;
		for (int r = 0; r < reps; r++) {
			l = run_child(self, S, "loom", b);
			lr.push_back(l.rnd), ly.push_back(l.ray);
		}
		bool eq = l.ok && l.ck_rnd == v.ck_rnd && l.ck_ray == v.ck_ray;
		ok = ok && eq;
		double lrm = median(lr), lym = median(ly);
		long limit = (atol(b) + 16) * 1024; /* budget + 16 MiB, KiB */
		printf("loom, budget %3s MiB   %12.3f %12.3f %6.0f MiB %4.0f MiB | %8.3f %8.3f | %s\n",
		       b, lrm / 1e6, lym / 1e6, l.hwm / 1024.0, l.base / 1024.0, lrm / vrm,
		       lym / vym, eq ? "equal" : "DIFFER");
		printf("  limit %ld MiB: peak %s, peak - base %.0f MiB %s\n", limit / 1024,
		       l.hwm <= limit ? "within" : "ABOVE", (l.hwm - l.base) / 1024.0,
		       l.hwm - l.base <= limit ? "within" : "ABOVE");
		printf("{\"bench\":\"vdb_below\",\"budget_mib\":%s,\"loom_random_per_core\":%.0f,"
		       "\"loom_rays_per_core\":%.0f,\"openvdb_random_per_core\":%.0f,"
		       "\"openvdb_rays_per_core\":%.0f,\"loom_peak_rss_kib\":%ld,"
		       "\"loom_base_rss_kib\":%ld,\"loom_rss_limit_kib\":%ld,"
		       "\"openvdb_peak_rss_kib\":%ld,\"openvdb_base_rss_kib\":%ld,"
		       "\"vdb_file_bytes\":%lld,\"checksums_equal\":%s,"
		       "\"load\":\"%s\"}\n", b, lrm, lym, vrm, vym, l.hwm, l.base, limit, v.hwm,
		       v.base, (long long)st.st_size, eq ? "true" : "false", loadavg().c_str());
	}
	unlink(S.vdbp.c_str());
	return ok;
}

} /* namespace */

int main(int argc, char **argv)
{
	Setup S;
	const char *b = getenv("BUILD");
	const char *sc = getenv("BENCH_VDB_SCALE");
	const char *xs = getenv("BENCH_VDB_CROSSINGS");
	int ai = 1;

	setvbuf(stdout, NULL, _IOLBF, 0);
	bench_help(argc, argv, USAGE);
	S.build = b && *b ? b : "build";
	if (ai < argc && strcmp(argv[ai], "--check") == 0)
		S.check = true, ai++;
	if (ai < argc && (strcmp(argv[ai], "--child") != 0 || ai + 7 >= argc))
		bench_reject("bench_vdb", argv[ai], USAGE);
	if (sc && atof(sc) > 0)
		S.scale = atof(sc);
	const char *bs = getenv("BENCH_VDB_BRICK");
	if (bs && *bs) {
		char tail;
		if (sscanf(bs, "%ux%ux%u%c", &S.brick[0], &S.brick[1], &S.brick[2], &tail) != 3 ||
		    !S.brick[0] || !S.brick[1] || !S.brick[2]) {
			fprintf(stderr, "bench_vdb: BENCH_VDB_BRICK='%s': expected XxYxZ, e.g. "
			        "16x16x16\n", bs);
			return 2;
		}
	}
	const char *fv = getenv("BENCH_VDB_FORMAT");
	if (fv && *fv) {
		if (strcmp(fv, "2") != 0 && strcmp(fv, "3") != 0 && strcmp(fv, "4") != 0) {
			fprintf(stderr, "bench_vdb: BENCH_VDB_FORMAT='%s': expected 2, 3 or 4\n", fv);
			return 2;
		}
		S.format = (unsigned)atoi(fv);
	}
	const char *dv = getenv("BENCH_VDB_DENSITY");
	if (dv && *dv) {
		if (strcmp(dv, "raw") != 0 && strcmp(dv, "deflate") != 0) {
			fprintf(stderr, "bench_vdb: BENCH_VDB_DENSITY='%s': expected raw or "
			        "deflate\n", dv);
			return 2;
		}
		S.raw_density = strcmp(dv, "raw") == 0;
	}
	const char *ev = getenv("BENCH_VDB_EDGE");
	if (ev && *ev) {
		if (strcmp(ev, "full") != 0 && strcmp(ev, "rank15") != 0 &&
		    strcmp(ev, "default") != 0) {
			fprintf(stderr, "bench_vdb: BENCH_VDB_EDGE='%s': expected full, rank15 or "
			        "default\n", ev);
			return 2;
		}
		S.edge_rank = strcmp(ev, "full") == 0 ? LOOM_EDGEFIX_MAX_RANK :
		              strcmp(ev, "rank15") == 0 ? 15 : 0;
	}
	S.xings = S.check ? 3 : 16;
	if (xs && atoi(xs) > 0)
		S.xings = atoi(xs);
	/* per brick shape, so that runs with another BENCH_VDB_BRICK do not
	   leave the default's fabric naming the other database */
	std::string shape = S.check ? std::string() :
	                    (S.brick[0] ? std::string("-") + bs : std::string()) +
	                    (S.format != 4 ? "-v" + std::to_string(S.format) : std::string()) +
	                    (S.raw_density ? "-rawd" : "") +
	                    (S.edge_rank ? "-r" + std::to_string(S.edge_rank) : std::string());
	S.fabp = S.build + (S.check ? "/bench/vdb-check.loomf" : "/bench/vdb-paper" + shape + ".loomf");
	S.vdbp = S.build + (S.check ? "/bench/vdb-check.vdb" : "/bench/vdb-paper" + shape + ".vdb");
	mkdir((S.build + "/bench").c_str(), 0777);
	openvdb::initialize();
	if (ai + 7 < argc && strcmp(argv[ai], "--child") == 0) {
		/* OpenVDB's child: the .vdb file and the region from the parent;
		   nothing of loom's is opened (its RSS is OpenVDB's alone) */
		g_base_kib = vm_kib("VmRSS:");
		S.lo[0] = atoll(argv[ai + 3]);
		S.lo[1] = atoll(argv[ai + 4]);
		for (int a = 0; a < 3; a++)
			S.n[a] = atoi(argv[ai + 5 + a]);
		return child(S, argv[ai + 1], argv[ai + 2]);
	}
	printf("bench_vdb: loom %s against OpenVDB %s and NanoVDB %d.%d.%d; load average %s\n",
	       loom_version(), openvdb::getLibraryVersionString(),
	       NANOVDB_MAJOR_VERSION_NUMBER, NANOVDB_MINOR_VERSION_NUMBER,
	       NANOVDB_PATCH_VERSION_NUMBER, loadavg().c_str());
	if (!setup_open(S))
		return S.check ? 1 : 0;
	loom_texture *t = tex_open(S, (size_t)512 * MIB);
	if (!t)
		return 1;
	Mat M;
	if (!materialise(S, t, M))
		return 1;

	size_t nvox = (size_t)S.n[0] * S.n[1] * S.n[2];
	loom_texture_stats st;
	Work W;
	work_make(S, W, (size_t)(S.scale * (S.check ? 2e4 : 1e6)),
	          (size_t)(S.scale * (S.check ? 200 : 8000)), 7);
	bool ok = warm(S, t, M, W);
	loom_texture_get_stats(t, &st);
	printf("\nmemory (the region: %.0f M voxels, %llu active)\n", nvox / 1e6,
	       (unsigned long long)M.active);
	printf("  loom texture, all of its bricks cached:  %8.1f MiB (peak counted bytes; the "
	       "whole bolt, any size)\n", st.peak_bytes / (double)MIB);
	printf("  OpenVDB FloatGrid density:               %8.1f MiB (+ orientation grid %.1f)\n",
	       M.dg->memUsage() / (double)MIB, M.og->memUsage() / (double)MIB);
	printf("  NanoVDB float density:                   %8.1f MiB (+ orientation grid %.1f)\n",
	       M.dh.size() / (double)MIB, M.oh.size() / (double)MIB);
	printf("  dense array density u8 (+ orientation u16): %5.1f MiB (+ %.1f)\n",
	       nvox / (double)MIB, 2.0 * nvox / MIB);
	printf("{\"bench\":\"vdb_memory\",\"voxels\":%zu,\"active\":%llu,\"loom_peak_bytes\":%llu,"
	       "\"openvdb_density_bytes\":%llu,\"openvdb_orientation_bytes\":%llu,"
	       "\"nanovdb_density_bytes\":%llu,\"nanovdb_orientation_bytes\":%llu,"
	       "\"dense_density_bytes\":%zu}\n", nvox, (unsigned long long)M.active,
	       (unsigned long long)st.peak_bytes, (unsigned long long)M.dg->memUsage(),
	       (unsigned long long)M.og->memUsage(), (unsigned long long)M.dh.size(),
	       (unsigned long long)M.oh.size(), nvox);
	loom_texture_close(t);
	ok = below(argv[0], S, M) && ok;
	loom_fabric_free(S.fab);
	loom_db_close(S.db);
	printf("\nbench_vdb: %s\n", ok ? "all checksums equal" : "CHECKSUMS DIFFER");
	return ok ? 0 : 1;
}
