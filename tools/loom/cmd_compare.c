/*
 * tools/loom/cmd_compare.c - `loom compare A B`: how close two cloths are,
 * column by column (docs/fidelity.md); `loom compare A`: A's own figures
 * (coverage and seam ratios), read as A against itself.
 *
 *   loom compare A [B] [--region X0,Y0:X1,Y1 | X0,Y0,Z0:X1,Y1,Z1]
 *                [--threshold D] [--json] [--pictures DIR] [--budget MB]
 *
 * A and B are fabrics (.loomf, read through the virtual texture's region
 * reads), exemplars (DB.ldb#K, K an index or a name, read with
 * loom_db_read_box) or density volumes (.vol, NRRD) with the kind volume
 * beside them (NAME.density.EXT and NAME.kind.EXT, as `loom export`
 * writes them; placed by their origin).  Both are streamed one block row at a time, in
 * chunks of whole blocks along x that fit the budget; per column only the
 * top surface (height, kind and top-yarn thickness) is kept, for the
 * current and the previous row.  Definitions: docs/fidelity.md.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

static const char about[] =
	"Compare two cloths voxel column by voxel column: the kind of the top\n"
	"yarn, the height of the top surface (RMSE raw and with the mean\n"
	"difference removed, per-block mean offsets), density histograms per\n"
	"yarn kind, coverage, and each input's seam ratio (mean height jump\n"
	"across block edges over the same inside blocks; also at the block\n"
	"corners alone; and the coverage seam ratio: neighbouring columns with a\n"
	"top surface on one side only, across block edges over inside blocks).\n"
	"A and B are fabrics\n"
	"(.loomf), exemplars (DB.ldb#K, K an index or a name) or volumes\n"
	"(NAME.density.vol or .nrrd, with NAME.kind.vol or .nrrd beside it, as\n"
	"`loom export` writes the density and kind channels, placed by their\n"
	"origin); they must have the same voxel size, block size and extent.\n"
	"With A alone, print A's own figures: coverage and the three seam\n"
	"ratios (an exemplar's tell how rough the seams of a fabric\n"
	"synthesized from it will be).\n"
	"Streamed in bounded memory.  Definitions: docs/fidelity.md.\n";

#define HIST_BINS 16
#define PIC_MAX 1024u

enum { SRC_FABRIC, SRC_EXEMPLAR, SRC_VOLUME };

/* One channel of a volume input: a .vol read box by box, a raw NRRD read
   row by row at its data offset, or a compressed NRRD read whole (within
   the budget). */
typedef struct volfile {
	char *path;
	loom_vol_reader *vr;
	FILE *fp;                /* raw NRRD data */
	uint64_t off;
	int type, big_endian, scale_int;
	loom_volbuf *whole;
	uint32_t n[3];
	double spacing[3], origin[3];
	uint8_t *row;            /* one run of x of raw NRRD values */
} volfile;

typedef struct src {
	int type;
	const char *arg;
	loom_db *db;
	loom_fabric *f;
	loom_texture *t;
	uint32_t ex;
	volfile vd, vk;         /* volume: density, kind */
	int64_t lo[3];          /* volume: position of its voxel (0,0,0) */
	float *vbuf;            /* volume: one chunk of floats */
	uint8_t kind_of[256];   /* exemplar label -> kind */
	uint64_t size[3];       /* extent: repeat or exemplar */
	uint32_t b1, b2, b3;
	float vs;
	/* per chunk */
	uint8_t *dens, *kind;
	/* per column of the current and previous block row: height (NAN = no
	   surface), kind, thickness */
	float *h, *hprev;
	uint8_t *k;
	/* statistics */
	double hist[3][HIST_BINS];
	uint64_t surf, cols;
	double thick_sum;
	uint64_t thick_n;
	double seam_sum, in_sum, corner_sum;
	uint64_t seam_n, in_n, corner_n; /* corner: the seam pairs next to a
	                                   point where four blocks meet */
	uint64_t cov_seam_n, cov_seam_x, cov_in_n, cov_in_x; /* neighbouring
	                       pairs across a block edge / inside a block, and
	                       how many have a top surface on one side only */
} src;

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}


/* ---- volume inputs ------------------------------------------------------------ */

/* Open one channel (1 value per voxel).  max_whole: the most bytes a
   compressed NRRD read whole may take; scale: integers are read as 0..1
   (density; not for kinds). */
static void vol_open(const char *prog, volfile *v, const char *path, size_t max_whole,
                     int scale, loom_diag *diag)
{
	memset(v, 0, sizeof *v);
	v->path = strdup(path);
	if (!v->path)
		cli_fail(prog, "out of memory");
	if (cli_ends_with(path, ".vol")) {
		const loom_vol_header *h;
		if (loom_vol_open(path, &v->vr, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		h = loom_vol_reader_header(v->vr);
		if (h->channels != 1)
			cli_fail(prog, "%s: %u values per voxel, expected 1 (density or kind)",
			         path, h->channels);
		v->n[0] = h->xres;
		v->n[1] = h->yres;
		v->n[2] = h->zres;
		for (int a = 0; a < 3; a++) {
			double ext = (double)h->bbox_max[a] - h->bbox_min[a];
			/* Mitsuba 0.6: sample i at min + i * extent / (res - 1) */
			v->spacing[a] = v->n[a] > 1 ? ext / (v->n[a] - 1) : ext;
			v->origin[a] = h->bbox_min[a];
		}
		return;
	}
	{
		loom_nrrd_info I;
		loom_raw_reader *rr = NULL;
		int rc = loom_nrrd_open(path, &I, &rr, diag);
		loom_raw_close(rr);
		if (rc == LOOM_OK && I.line_skip == 0 && I.byte_skip >= -1) {
			/* raw: read rows at the data offset ourselves */
			const char *slash = strrchr(path, '/');
			char dpath[4096];
			struct stat st;
			uint64_t need;
			if (!I.data_file[0])
				snprintf(dpath, sizeof dpath, "%s", path);
			else if (I.data_file[0] == '/' || !slash)
				snprintf(dpath, sizeof dpath, "%s", I.data_file);
			else
				snprintf(dpath, sizeof dpath, "%.*s%s", (int)(slash - path + 1), path,
				         I.data_file);
			v->fp = fopen(dpath, "rb");
			if (!v->fp || fstat(fileno(v->fp), &st) != 0)
				cli_fail(prog, "%s: %s", dpath, strerror(errno));
			need = (uint64_t)I.nx * I.ny * I.nz * I.channels * loom_scalar_size(I.type);
			if (I.byte_skip == -1)
				v->off = (uint64_t)st.st_size - need;
			else
				v->off = (I.data_file[0] ? 0 : I.header_bytes) + (uint64_t)I.byte_skip;
			v->type = I.type;
			v->big_endian = I.big_endian == 1;
		} else if (rc == LOOM_OK || rc == LOOM_EUNSUPPORTED) {
			/* gzip, ascii or a line skip: whole, within the budget */
			int rr2 = loom_nrrd_read(path, max_whole, &I, &v->whole, diag);
			if (rr2 != LOOM_OK)
				cli_fail(prog, "%s%s", diag->message, rr2 == LOOM_EBUDGET ?
				         " (a compressed NRRD is read whole: raise --budget, or "
				         "store it raw)" : "");
			v->type = I.type;
		} else {
			cli_fail(prog, "%s", diag->message);
		}
		if (I.channels != 1)
			cli_fail(prog, "%s: %u values per voxel, expected 1 (density or kind)",
			         path, I.channels);
		v->n[0] = I.nx;
		v->n[1] = I.ny;
		v->n[2] = I.nz;
		for (int a = 0; a < 3; a++) {
			v->spacing[a] = I.spacing[a];
			v->origin[a] = I.origin[a];
		}
		v->scale_int = scale && I.type != LOOM_SCALAR_F16 && I.type != LOOM_SCALAR_F32 &&
		               I.type != LOOM_SCALAR_F64;
		v->row = malloc((size_t)v->n[0] * 8);
		if (!v->row)
			cli_fail(prog, "out of memory");
	}
}

static void vol_close(volfile *v)
{
	loom_vol_close(v->vr);
	if (v->fp)
		fclose(v->fp);
	loom_volbuf_free(v->whole);
	free(v->row);
	free(v->path);
}

/* One stored value of a raw NRRD as a float (integers unscaled). */
static float raw_value(const uint8_t *p, int type, int big)
{
	size_t n = loom_scalar_size(type);
	uint8_t b[8];
	for (size_t i = 0; i < n; i++)
		b[i] = big ? p[n - 1 - i] : p[i];
	switch (type) {
	case LOOM_SCALAR_U8: return b[0];
	case LOOM_SCALAR_I8: return (int8_t)b[0];
	case LOOM_SCALAR_U16: return (uint16_t)(b[0] | b[1] << 8);
	case LOOM_SCALAR_I16: return (int16_t)(b[0] | b[1] << 8);
	case LOOM_SCALAR_F16: return loom_half_to_float((uint16_t)(b[0] | b[1] << 8));
	case LOOM_SCALAR_U32: case LOOM_SCALAR_I32: case LOOM_SCALAR_F32: {
		uint32_t u = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 |
		             (uint32_t)b[3] << 24;
		float f;
		if (type == LOOM_SCALAR_U32)
			return (float)u;
		if (type == LOOM_SCALAR_I32)
			return (float)(int32_t)u;
		memcpy(&f, &u, 4);
		return f;
	}
	case LOOM_SCALAR_F64: {
		uint64_t u = 0;
		double d;
		for (int i = 7; i >= 0; i--)
			u = u << 8 | b[i];
		memcpy(&d, &u, 8);
		return (float)d;
	}
	}
	return 0;
}

/* Box of the file (its own coordinates, inside it) into out, x fastest. */
static void vol_read(const char *prog, volfile *v, uint32_t x0, uint32_t y0, uint32_t z0,
                     uint32_t nx, uint32_t ny, uint32_t nz, float *out, loom_diag *diag)
{
	if (v->vr) {
		if (loom_vol_read_box(v->vr, x0, y0, z0, nx, ny, nz, out, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		return;
	}
	for (uint32_t z = 0; z < nz; z++)
		for (uint32_t y = 0; y < ny; y++) {
			float *o = out + ((size_t)z * ny + y) * nx;
			uint64_t i = ((uint64_t)(z0 + z) * v->n[1] + y0 + y) * v->n[0] + x0;
			if (v->whole) {
				memcpy(o, v->whole->data + i, nx * sizeof *o);
			} else {
				size_t sz = loom_scalar_size(v->type);
				if (fseeko(v->fp, (off_t)(v->off + i * sz), SEEK_SET) != 0 ||
				    fread(v->row, sz, nx, v->fp) != nx)
					cli_fail(prog, "%s: cannot read %u values at byte %llu (file "
					         "changed or too short?)", v->path, nx,
					         (unsigned long long)(v->off + i * sz));
				for (uint32_t x = 0; x < nx; x++)
					o[x] = raw_value(v->row + x * sz, v->type, v->big_endian);
			}
			if (v->scale_int)
				for (uint32_t x = 0; x < nx; x++)
					o[x] *= v->type == LOOM_SCALAR_U16 ? 1.0f / 65535 : 1.0f / 255;
		}
}

/* NAME.density.EXT -> NAME.kind.EXT (NULL when the name has no ".density."). */
static char *kind_path(const char *path)
{
	const char *d = strstr(path, ".density.");
	char *k;
	if (!d)
		return NULL;
	k = malloc(strlen(path) + 1);
	if (k)
		sprintf(k, "%.*s.kind.%s", (int)(d - path), path, d + 9);
	return k;
}

static int is_volume(const char *arg)
{
	return cli_ends_with(arg, ".vol") || cli_ends_with(arg, ".nrrd") ||
	       cli_ends_with(arg, ".nhdr");
}

static void open_volume(const char *prog, src *s, const char *arg, size_t budget,
                        loom_diag *diag)
{
	char *kp = kind_path(arg);
	struct stat st;

	s->type = SRC_VOLUME;
	if (!kp || stat(kp, &st) != 0)
		cli_fail(prog, "%s: a volume is compared with its kind volume beside it "
		         "(%s; NAME.density.EXT and NAME.kind.EXT, as `loom export "
		         "--channels density,kind` writes them)", arg,
		         kp ? kp : "the name must contain .density.");
	vol_open(prog, &s->vd, arg, budget / 2, 1, diag);
	vol_open(prog, &s->vk, kp, budget / 2, 0, diag);
	for (int a = 0; a < 3; a++)
		if (s->vd.n[a] != s->vk.n[a] ||
		    fabs(s->vd.origin[a] - s->vk.origin[a]) > 1e-3 * s->vd.spacing[0])
			cli_fail(prog, "%s is %ux%ux%u voxels at (%g, %g, %g), its kind volume %s "
			         "%ux%ux%u at (%g, %g, %g): they must match", arg, s->vd.n[0],
			         s->vd.n[1], s->vd.n[2], s->vd.origin[0], s->vd.origin[1],
			         s->vd.origin[2], kp, s->vk.n[0], s->vk.n[1], s->vk.n[2],
			         s->vk.origin[0], s->vk.origin[1], s->vk.origin[2]);
	free(kp);
	for (int a = 1; a < 3; a++)
		if (s->vd.n[a] > 1 && fabs(s->vd.spacing[a] - s->vd.spacing[0]) >
		                      1e-4 * s->vd.spacing[0])
			cli_fail(prog, "%s: voxels of %g x %g x %g (file units): compare needs "
			         "cubic voxels", arg, s->vd.spacing[0], s->vd.spacing[1],
			         s->vd.spacing[2]);
	if (!(s->vd.spacing[0] > 0))
		cli_fail(prog, "%s: no voxel size (spacing %g)", arg, s->vd.spacing[0]);
	/* loom writes millimetres; the origin is the centre of voxel (0,0,0) */
	s->vs = (float)(s->vd.spacing[0] * 1000.0);
	for (int a = 0; a < 3; a++) {
		s->lo[a] = (int64_t)floor(s->vd.origin[a] / s->vd.spacing[0] + 1e-3);
		s->size[a] = s->vd.n[a];
	}
}

static void open_src(const char *prog, src *s, const char *arg, size_t budget,
                     loom_diag *diag)
{
	const char *hash = strrchr(arg, '#');

	memset(s, 0, sizeof *s);
	s->arg = arg;
	if (is_volume(arg)) {
		open_volume(prog, s, arg, budget, diag);
		return;
	}
	if (hash && hash > arg) {
		char *path = strndup(arg, (size_t)(hash - arg));
		loom_db_info info;
		loom_db_exemplar_info e;
		if (!path)
			cli_fail(prog, "out of memory");
		s->type = SRC_EXEMPLAR;
		if (loom_db_open(path, &s->db, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		if (loom_db_find_exemplar(s->db, hash + 1, &s->ex) != LOOM_OK)
			cli_fail(prog, "%s: no exemplar '%s' in %s", arg, hash + 1, path);
		free(path);
		loom_db_get_info(s->db, &info);
		loom_db_exemplar(s->db, s->ex, &e);
		for (int a = 0; a < 3; a++)
			s->size[a] = e.size[a];
		for (uint32_t l = 1; l <= e.n_yarns && l < 256; l++)
			s->kind_of[l] = (e.yarns[l].kind == LOOM_YARN_WARP ||
			                 e.yarns[l].kind == LOOM_YARN_WEFT) ? e.yarns[l].kind : 0;
		s->b1 = info.block[0];
		s->b2 = info.block[1];
		s->b3 = info.block[2];
		s->vs = info.voxel_size_um;
		return;
	}
	if (!cli_ends_with(arg, ".loomf"))
		cli_fail(prog, "%s: expected a fabric (.loomf), an exemplar DB.ldb#K or a "
		         "volume (.vol, .nrrd, .nhdr)", arg);
	s->type = SRC_FABRIC;
	{
		loom_fabric_db_identity id;
		loom_texture_options to = LOOM_TEXTURE_OPTIONS_INIT;
		if (loom_fabric_open(arg, NULL, 0, &s->f, diag) != LOOM_OK)
			cli_fail(prog, "%s", diag->message);
		loom_fabric_get_db_identity(s->f, &id);
		loom_fabric_repeat_voxels(s->f, s->size);
		s->b1 = id.block[0];
		s->b2 = id.block[1];
		s->b3 = id.block[2];
		s->vs = id.voxel_size_um;
		to.budget_bytes = budget;
		to.max_threads = 1;
		if (loom_texture_open(s->f, NULL, &to, &s->t, diag) != LOOM_OK)
			cli_fail(prog, "%s: %s", arg, diag->message);
	}
}

static void close_src(src *s)
{
	loom_texture_close(s->t);
	loom_fabric_free(s->f);
	loom_db_close(s->db);
	if (s->type == SRC_VOLUME) {
		vol_close(&s->vd);
		vol_close(&s->vk);
	}
	free(s->vbuf);
	free(s->dens);
	free(s->kind);
	free(s->h);
	free(s->hprev);
	free(s->k);
}

/* Read box [x0,x0+nx) x [y0,y0+ny) x [z0,z0+nz) (x fastest) into dens and
   kind. */
static void read_box(const char *prog, src *s, int64_t x0, int64_t y0, int64_t z0,
                     uint32_t nx, uint32_t ny, uint32_t nz, loom_diag *diag)
{
	size_t n = (size_t)nx * ny * nz;

	if (s->type == SRC_FABRIC) {
		int64_t lo[3] = {x0, y0, z0}, hi[3] = {x0 + nx, y0 + ny, z0 + nz};
		loom_texture_region r = {0};
		r.density = s->dens;
		r.kind = s->kind;
		r.layout = LOOM_REGION_X_FASTEST;
		if (loom_texture_read_region(s->t, lo, hi, &r) != LOOM_OK)
			cli_fail(prog, "%s: %s", s->arg, loom_texture_errmsg(s->t));
	} else if (s->type == SRC_VOLUME) {
		uint32_t o[3] = {(uint32_t)(x0 - s->lo[0]), (uint32_t)(y0 - s->lo[1]),
		                 (uint32_t)(z0 - s->lo[2])};
		vol_read(prog, &s->vd, o[0], o[1], o[2], nx, ny, nz, s->vbuf, diag);
		for (size_t i = 0; i < n; i++) {
			float v = s->vbuf[i];
			s->dens[i] = (uint8_t)(v > 0 ? (v < 1 ? lroundf(v * 255.0f) : 255) : 0);
		}
		vol_read(prog, &s->vk, o[0], o[1], o[2], nx, ny, nz, s->vbuf, diag);
		for (size_t i = 0; i < n; i++)
			s->kind[i] = s->vbuf[i] == 1.0f ? LOOM_YARN_WARP :
			             s->vbuf[i] == 2.0f ? LOOM_YARN_WEFT : 0;
	} else {
		uint32_t org[3] = {(uint32_t)x0, (uint32_t)y0, (uint32_t)z0};
		uint32_t sz[3] = {nx, ny, nz};
		if (loom_db_read_box(s->db, s->ex, org, sz, s->dens, NULL, s->kind, diag) !=
		    LOOM_OK)
			cli_fail(prog, "%s: %s", s->arg, diag->message);
		for (size_t i = 0; i < n; i++)
			s->kind[i] = s->kind_of[s->kind[i]];
	}
}

/* --region: X0,Y0:X1,Y1 or X0,Y0,Z0:X1,Y1,Z1. */
typedef struct box {
	int64_t lo[3], hi[3];
	int has_z;
} box;

static const char *opt_region(const char *text, void *dest)
{
	box *b = dest;
	long long v[6];
	char tail;

	if (sscanf(text, "%lld,%lld,%lld:%lld,%lld,%lld%c", &v[0], &v[1], &v[2], &v[3],
	           &v[4], &v[5], &tail) == 6) {
		b->lo[0] = v[0], b->lo[1] = v[1], b->lo[2] = v[2];
		b->hi[0] = v[3], b->hi[1] = v[4], b->hi[2] = v[5];
		b->has_z = 1;
	} else if (sscanf(text, "%lld,%lld:%lld,%lld%c", &v[0], &v[1], &v[3], &v[4],
	                  &tail) == 4) {
		b->lo[0] = v[0], b->lo[1] = v[1];
		b->hi[0] = v[3], b->hi[1] = v[4];
		b->has_z = 0;
	} else {
		return "X0,Y0:X1,Y1 or X0,Y0,Z0:X1,Y1,Z1 (voxels, half-open)";
	}
	for (int a = 0; a < (b->has_z ? 3 : 2); a++)
		if (b->lo[a] < 0 || b->hi[a] <= b->lo[a] || b->hi[a] > ((int64_t)1 << 40))
			return "0 <= X0 < X1, 0 <= Y0 < Y1 (and Z) below 2^40";
	return NULL;
}

/* --block B1xB2xB3 (volume inputs). */
static const char *opt_block(const char *text, void *dest)
{
	uint32_t *b = dest;
	unsigned v[3];
	char tail;

	if (sscanf(text, "%ux%ux%u%c", &v[0], &v[1], &v[2], &tail) != 3 || !v[0] || !v[1] ||
	    !v[2] || v[0] > 65536 || v[1] > 65536 || v[2] > 65536)
		return "B1xB2xB3, each 1..65536 voxels";
	for (int a = 0; a < 3; a++)
		b[a] = v[a];
	return NULL;
}

/* ---- the comparison -------------------------------------------------------- */

typedef struct acc {
	uint64_t both, agree, centres, centres_agree;
	double d_sum, d2_sum;
	/* per block of the current block row: sum and count of dh */
	double *blk_sum;
	uint64_t *blk_n;
	double bo_sum, bo2_sum;
	uint64_t bo_n;
	uint64_t voxels;
} acc;

/* Top surface of every column of the chunk into s->h/k (index x - xr0 +
   (y - y0)*W where W is the region width). */
static void tops(src *s, uint32_t nx, uint32_t ny, uint32_t nz, uint8_t thr,
                 size_t off, size_t W, int64_t z0)
{
	for (uint32_t y = 0; y < ny; y++)
		for (uint32_t x = 0; x < nx; x++) {
			size_t col = off + (size_t)y * W + x;
			int top = -1;
			for (int z = (int)nz - 1; z >= 0; z--) {
				size_t i = ((size_t)z * ny + y) * nx + x;
				uint8_t d = s->dens[i];
				if (d) {
					uint8_t kk = s->kind[i] <= 2 ? s->kind[i] : 0;
					int bin = (d - 1) * HIST_BINS / 255;
					s->hist[kk][bin] += 1;
				}
				if (top < 0 && d >= thr && s->kind[i])
					top = z;
			}
			s->cols++;
			if (top < 0) {
				s->h[col] = NAN;
				s->k[col] = 0;
				continue;
			}
			s->surf++;
			s->h[col] = (float)(z0 + top + 1);
			s->k[col] = s->kind[((size_t)top * ny + y) * nx + x];
			{
				int z = top;
				while (z >= 0 && s->kind[((size_t)z * ny + y) * nx + x] == s->k[col] &&
				       s->dens[((size_t)z * ny + y) * nx + x] >= thr)
					z--;
				s->thick_sum += top - z;
				s->thick_n++;
			}
		}
}

static int is_edge(int64_t v, uint32_t b) /* v and v+1 in different blocks */
{
	return (v + 1) % b == 0;
}

static int is_rim(int64_t v, uint32_t b) /* v is a block's first or last */
{
	int64_t m = v % (int64_t)b;
	m = m < 0 ? m + b : m;
	return m == 0 || m == (int64_t)b - 1;
}

/* Seam statistics of one input over a finished band of rows [0, ny) (and the
   pair with the previous band's last row when have_prev): height jumps
   where both columns have a top, coverage mismatches over every pair. */
static void seam_pair(src *s, float h0, float h1, int edge, int rim)
{
	int c0 = !isnan(h0), c1 = !isnan(h1);
	if (edge)
		s->cov_seam_n++, s->cov_seam_x += c0 != c1;
	else
		s->cov_in_n++, s->cov_in_x += c0 != c1;
	if (!c0 || !c1)
		return;
	if (edge) {
		s->seam_sum += fabsf(h1 - h0), s->seam_n++;
		if (rim)
			s->corner_sum += fabsf(h1 - h0), s->corner_n++;
	} else
		s->in_sum += fabsf(h1 - h0), s->in_n++;
}

static void seams(src *s, const box *r, int64_t y0, uint32_t ny, size_t W,
                  int have_prev)
{
	for (uint32_t y = 0; y < ny; y++)
		for (size_t x = 0; x < W; x++) {
			float h0 = s->h[(size_t)y * W + x];
			int64_t gx = r->lo[0] + (int64_t)x, gy = y0 + y;
			if (x + 1 < W)
				seam_pair(s, h0, s->h[(size_t)y * W + x + 1], is_edge(gx, s->b1),
				          is_rim(gy, s->b2));
			if (y == 0 && !have_prev)
				continue;
			seam_pair(s, h0, y ? s->h[(size_t)(y - 1) * W + x] : s->hprev[x],
			          is_edge(gy - 1, s->b2), is_rim(gx, s->b1));
		}
	memcpy(s->hprev, s->h + (size_t)(ny - 1) * W, W * sizeof *s->h);
}

/* Mean jump of n seam pairs summing to sum over the mean jump inside
   blocks (0 when either is undefined). */
static double seam_ratio(const src *s, double sum, uint64_t n)
{
	return n && s->in_n && s->in_sum > 0 ? (sum / n) / (s->in_sum / s->in_n) : 0;
}

/* Fraction of block-edge pairs with a top on one side only over the same
   fraction inside blocks (0 when either is undefined). */
static double coverage_seam_ratio(const src *s)
{
	return s->cov_seam_n && s->cov_in_n && s->cov_in_x ?
	       ((double)s->cov_seam_x / (double)s->cov_seam_n) /
	       ((double)s->cov_in_x / (double)s->cov_in_n) : 0;
}

/* ---- pictures ---------------------------------------------------------------- */

typedef struct pics {
	uint32_t w, h, scale;
	double *ha, *hb, *n, *ka, *kb; /* per pixel sums */
} pics;

static void pic_add(pics *p, const box *r, int64_t y0, uint32_t ny, size_t W,
                    const src *a, const src *b)
{
	for (uint32_t y = 0; y < ny; y++)
		for (size_t x = 0; x < W; x++) {
			size_t c = (size_t)y * W + x;
			uint32_t px = (uint32_t)(x / p->scale);
			uint32_t py = (uint32_t)((uint64_t)(y0 + y - r->lo[1]) / p->scale);
			size_t i;
			if (px >= p->w || py >= p->h || isnan(a->h[c]) || isnan(b->h[c]))
				continue;
			i = (size_t)py * p->w + px;
			p->ha[i] += a->h[c];
			p->hb[i] += b->h[c];
			p->ka[i] += a->k[c] == LOOM_YARN_WARP;
			p->kb[i] += b->k[c] == LOOM_YARN_WARP;
			p->n[i] += 1;
		}
}

/* Height-shaded kind colours: warp light grey, weft blue (as the preview's
   default yarn types); brightness from the height. */
static void shade(double kfrac, double h, double lo, double hi, uint8_t *rgb)
{
	static const double warp[3] = {225, 225, 218}, weft[3] = {92, 112, 176};
	double t = hi > lo ? (h - lo) / (hi - lo) : 0.5, v = 0.35 + 0.65 * t;
	for (int c = 0; c < 3; c++) {
		double x = (kfrac * warp[c] + (1 - kfrac) * weft[c]) * v;
		rgb[c] = (uint8_t)(x < 0 ? 0 : x > 255 ? 255 : lround(x));
	}
}

static void pic_write(const char *prog, const pics *p, const char *dir, double bias,
                      double deb, double *range, loom_diag *diag)
{
	loom_image *img = NULL, *dimg = NULL;
	char path[4096];
	double lo = INFINITY, hi = -INFINITY, dmax = 3 * deb;
	uint32_t gap = 8;

	for (size_t i = 0; i < (size_t)p->w * p->h; i++) {
		double a, b;
		if (!p->n[i])
			continue;
		a = p->ha[i] / p->n[i];
		b = p->hb[i] / p->n[i];
		lo = fmin(lo, fmin(a, b));
		hi = fmax(hi, fmax(a, b));
	}
	if (dmax < 1)
		dmax = 1;
	*range = dmax;
	if (loom_image_new(2 * p->w + gap, p->h, 3, &img) != LOOM_OK ||
	    loom_image_new(p->w, p->h, 3, &dimg) != LOOM_OK)
		cli_fail(prog, "out of memory for the pictures");
	memset(img->pixels, 255, (size_t)img->width * img->height * 3);
	for (uint32_t y = 0; y < p->h; y++)
		for (uint32_t x = 0; x < p->w; x++) {
			size_t i = (size_t)y * p->w + x;
			uint8_t *pa = img->pixels + 3 * ((size_t)y * img->width + x);
			uint8_t *pb = img->pixels + 3 * ((size_t)y * img->width + x + p->w + gap);
			uint8_t *pd = dimg->pixels + 3 * i;
			double d;
			if (!p->n[i]) {
				memset(pa, 0, 3);
				memset(pb, 0, 3);
				memset(pd, 0, 3);
				continue;
			}
			shade(p->ka[i] / p->n[i], p->ha[i] / p->n[i], lo, hi, pa);
			shade(p->kb[i] / p->n[i], p->hb[i] / p->n[i], lo, hi, pb);
			/* diverging: B higher (after the mean) red, lower blue */
			d = ((p->hb[i] - p->ha[i]) / p->n[i] + bias) / dmax;
			d = d > 1 ? 1 : d < -1 ? -1 : d;
			pd[0] = (uint8_t)lround(d > 0 ? 255 : 255 * (1 + d));
			pd[1] = (uint8_t)lround(255 * (1 - fabs(d)));
			pd[2] = (uint8_t)lround(d < 0 ? 255 : 255 * (1 - d));
		}
	snprintf(path, sizeof path, "%s/side-by-side.png", dir);
	if (loom_image_write(path, img, diag) != LOOM_OK)
		cli_fail(prog, "%s", diag->message);
	snprintf(path, sizeof path, "%s/height-difference.png", dir);
	if (loom_image_write(path, dimg, diag) != LOOM_OK)
		cli_fail(prog, "%s", diag->message);
	loom_image_free(img);
	loom_image_free(dimg);
}

/* ---- the command ----------------------------------------------------------------- */

static double hist_l1(const src *a, const src *b, int kind)
{
	double na = 0, nb = 0, l1 = 0;
	for (int i = 0; i < HIST_BINS; i++) {
		na += a->hist[kind][i];
		nb += b->hist[kind][i];
	}
	if (!(na > 0) || !(nb > 0))
		return na > 0 || nb > 0 ? 2.0 : 0.0;
	for (int i = 0; i < HIST_BINS; i++)
		l1 += fabs(a->hist[kind][i] / na - b->hist[kind][i] / nb);
	return l1;
}

/* The table's region line and column heads. */
static void table_head(const box *r, uint64_t voxels, const src *a, double thr)
{
	printf("  region %lld,%lld,%lld:%lld,%lld,%lld (%llu voxels), blocks %ux%ux%u of "
	       "%g um, threshold %.3f\n", (long long)r->lo[0], (long long)r->lo[1],
	       (long long)r->lo[2], (long long)r->hi[0], (long long)r->hi[1],
	       (long long)r->hi[2], (unsigned long long)voxels, a->b1, a->b2, a->b3,
	       (double)a->vs, thr);
	printf("  %-28s %10s\n", "measure", "value");
}

static int same_geometry(const src *a, const src *b)
{
	return a->b1 == b->b1 && a->b2 == b->b2 && a->b3 == b->b3 &&
	       fabsf(a->vs - b->vs) <= 1e-4f * a->vs;
}

int cmd_compare(int argc, char **argv)
{
	const char *prog = "loom compare";
	const char *pos[2] = {NULL, NULL}, *picdir = NULL;
	double budget_mb = 64, thr = 0.2, t0 = now_s();
	int json = 0, quiet = 0, single, nin;
	box r;
	uint32_t blk[3] = {0, 0, 0};
	src A, B;
	acc ac;
	pics pic;
	loom_diag diag;
	size_t budget, W, chunk_cols, per_col;
	uint32_t nz, band;
	uint8_t thr8;
	opt_entry opts[] = {
		OPT_CALLBACK(0, "region", &r, "BOX", opt_region, "voxels, half-open: "
		             "X0,Y0:X1,Y1 or X0,Y0,Z0:X1,Y1,Z1 (default: the whole extent, "
		             "which must be the same for A and B)"),
		OPT_CALLBACK(0, "block", blk, "B1xB2xB3", opt_block, "block size of volume "
		             "inputs (default: the other input's; required when both are volumes)"),
		OPT_DOUBLE(0, "threshold", &thr, "D", "(]", 0, 1, "",
		           "density of the top surface, %r (default 0.2)"),
		OPT_STRING(0, "pictures", &picdir, "DIR", "write DIR/side-by-side.png (A "
		           "left, B right, shaded top surfaces) and DIR/height-difference.png "
		           "(B - A after the mean: red higher, blue lower, full colour at 3 debiased RMSE)"),
		OPT_BUDGET(&budget_mb, "memory budget in MiB (default 64): texture caches "
		           "and the chunks read"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_QUIET(&quiet, "no table"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = "loom compare A [B] [OPTIONS]", .about = about,
	              .opts = opts, .pos_name = "A [B]", .pos_min = 1, .pos_max = 2,
	              .pos = pos};

	memset(&r, 0, sizeof r);
	opts_parse(&c, argc, argv);
	cli_diag_init(&diag, &quiet);
	budget = (size_t)(budget_mb * 1048576.0);
	if (budget < ((size_t)8 << 20))
		opts_usage(&c, "--budget: at least 8 MiB");
	/* one input: A read once and compared with itself (B a copy of its
	   geometry, its column state A's), reporting only A's own figures */
	single = !pos[1];
	nin = single ? 1 : 2;
	if (single && picdir)
		opts_usage(&c, "--pictures compares two inputs: give B");
	open_src(prog, &A, pos[0], budget / 4, &diag);
	if (single)
		B = A;
	else
		open_src(prog, &B, pos[1], budget / 4, &diag);
	for (int k = 0; k < 2; k++) {
		src *s = k ? &B : &A, *o = k ? &A : &B;
		if (s->type != SRC_VOLUME)
			continue;
		if (opt_given(&c, blk)) {
			s->b1 = blk[0], s->b2 = blk[1], s->b3 = blk[2];
		} else if (o->type != SRC_VOLUME) {
			s->b1 = o->b1, s->b2 = o->b2, s->b3 = o->b3;
		} else {
			opts_usage(&c, single ? "a volume alone: give its block size with --block "
			           "B1xB2xB3" : "two volumes: give their block size with --block "
			           "B1xB2xB3");
		}
		for (int a = 0; a < 3; a++)
			if (s->lo[a] < 0)
				cli_fail(prog, "%s starts at voxel %lld along %c (its origin): compare "
				         "reads boxes at non-negative coordinates", s->arg,
				         (long long)s->lo[a], "xyz"[a]);
	}
	if (!same_geometry(&A, &B))
		cli_fail(prog, "%s has blocks of %ux%ux%u voxels of %g um, %s %ux%ux%u of %g "
		         "um: compare cloths of the same geometry (loom exemplar generate "
		         "--like DB)", A.arg, A.b1, A.b2, A.b3, (double)A.vs, B.arg, B.b1,
		         B.b2, B.b3, (double)B.vs);
	if (!opt_given(&c, &r) && (A.type == SRC_VOLUME || B.type == SRC_VOLUME)) {
		/* the volume's box (both: the same box) */
		const src *v = A.type == SRC_VOLUME ? &A : &B;
		if (A.type == SRC_VOLUME && B.type == SRC_VOLUME)
			for (int a = 0; a < 3; a++)
				if (A.lo[a] != B.lo[a] || A.size[a] != B.size[a])
					cli_fail(prog, "%s is voxels %lld,%lld,%lld:%lld,%lld,%lld, %s "
					         "%lld,%lld,%lld:%lld,%lld,%lld: compare the same box or "
					         "give --region", A.arg, (long long)A.lo[0],
					         (long long)A.lo[1], (long long)A.lo[2],
					         (long long)(A.lo[0] + (int64_t)A.size[0]),
					         (long long)(A.lo[1] + (int64_t)A.size[1]),
					         (long long)(A.lo[2] + (int64_t)A.size[2]), B.arg,
					         (long long)B.lo[0], (long long)B.lo[1], (long long)B.lo[2],
					         (long long)(B.lo[0] + (int64_t)B.size[0]),
					         (long long)(B.lo[1] + (int64_t)B.size[1]),
					         (long long)(B.lo[2] + (int64_t)B.size[2]));
		for (int a = 0; a < 3; a++) {
			r.lo[a] = v->lo[a];
			r.hi[a] = v->lo[a] + (int64_t)v->size[a];
		}
		r.has_z = 1;
	} else if (!opt_given(&c, &r)) {
		if (memcmp(A.size, B.size, sizeof A.size) != 0)
			cli_fail(prog, "%s is %llux%llux%llu voxels, %s %llux%llux%llu: compare "
			         "the same extent or give --region", A.arg,
			         (unsigned long long)A.size[0], (unsigned long long)A.size[1],
			         (unsigned long long)A.size[2], B.arg,
			         (unsigned long long)B.size[0], (unsigned long long)B.size[1],
			         (unsigned long long)B.size[2]);
		for (int a = 0; a < 3; a++) {
			r.lo[a] = 0;
			r.hi[a] = (int64_t)A.size[a];
		}
	} else if (!r.has_z) {
		r.lo[2] = 0;
		r.hi[2] = (int64_t)A.b3;
	}
	for (int k = 0; k < 2; k++) {
		const src *s = k ? &B : &A;
		if (s->type == SRC_EXEMPLAR)
			for (int a = 0; a < 3; a++)
				if ((uint64_t)r.hi[a] > s->size[a])
					cli_fail(prog, "--region: %s is %llux%llux%llu voxels; the region "
					         "ends at %lld,%lld,%lld", s->arg,
					         (unsigned long long)s->size[0],
					         (unsigned long long)s->size[1],
					         (unsigned long long)s->size[2], (long long)r.hi[0],
					         (long long)r.hi[1], (long long)r.hi[2]);
		if (s->type == SRC_VOLUME)
			for (int a = 0; a < 3; a++)
				if (r.lo[a] < s->lo[a] || r.hi[a] > s->lo[a] + (int64_t)s->size[a])
					cli_fail(prog, "%s holds voxels %lld,%lld,%lld:%lld,%lld,%lld; the "
					         "region %lld,%lld,%lld:%lld,%lld,%lld is not inside it",
					         s->arg, (long long)s->lo[0], (long long)s->lo[1],
					         (long long)s->lo[2],
					         (long long)(s->lo[0] + (int64_t)s->size[0]),
					         (long long)(s->lo[1] + (int64_t)s->size[1]),
					         (long long)(s->lo[2] + (int64_t)s->size[2]),
					         (long long)r.lo[0], (long long)r.lo[1], (long long)r.lo[2],
					         (long long)r.hi[0], (long long)r.hi[1], (long long)r.hi[2]);
	}
	if (r.hi[2] > (int64_t)A.b3)
		cli_fail(prog, "--region: z ends at %lld, the cloth is %u voxels thick",
		         (long long)r.hi[2], A.b3);
	W = (size_t)(r.hi[0] - r.lo[0]);
	nz = (uint32_t)(r.hi[2] - r.lo[2]);
	band = A.b2;
	/* chunk: whole blocks along x; 2 bytes per voxel per input, 4 more for
	   a volume input's floats */
	per_col = (size_t)band * nz *
	          (4 + 4 * (size_t)(A.type == SRC_VOLUME) + 4 * (size_t)(B.type == SRC_VOLUME));
	chunk_cols = (budget / 2) / per_col;
	chunk_cols -= chunk_cols % A.b1;
	if (chunk_cols < A.b1)
		cli_fail(prog, "--budget %.0f MiB cannot hold one block (%zu bytes)", budget_mb,
		         per_col * A.b1 * 2);
	if (chunk_cols > W)
		chunk_cols = W;
	/* per-row state: 2 inputs x 3 rows of floats + kinds, the block sums */
	if ((double)W * band * 24 > (double)budget / 4)
		cli_fail(prog, "--region %zu voxels wide needs %.0f MiB of row state; raise "
		         "--budget or narrow the region", W, (double)W * band * 24 * 4 / 1048576.0);
	memset(&ac, 0, sizeof ac);
	for (int k = 0; k < nin; k++) {
		src *s = k ? &B : &A;
		s->dens = malloc(chunk_cols * band * nz);
		s->kind = malloc(chunk_cols * band * nz);
		s->h = malloc(W * band * sizeof *s->h);
		s->hprev = malloc(W * sizeof *s->hprev);
		s->k = malloc(W * band);
		if (s->type == SRC_VOLUME &&
		    !(s->vbuf = malloc(chunk_cols * band * nz * sizeof *s->vbuf)))
			cli_fail(prog, "out of memory");
		if (!s->dens || !s->kind || !s->h || !s->hprev || !s->k)
			cli_fail(prog, "out of memory");
	}
	if (single) {
		B.h = A.h;
		B.k = A.k;
	}
	ac.blk_sum = calloc(W / A.b1 + 2, sizeof *ac.blk_sum);
	ac.blk_n = calloc(W / A.b1 + 2, sizeof *ac.blk_n);
	memset(&pic, 0, sizeof pic);
	if (picdir) {
		uint64_t H = (uint64_t)(r.hi[1] - r.lo[1]), M = W > H ? W : H;
		if (mkdir(picdir, 0777) != 0 && errno != EEXIST)
			cli_fail(prog, "--pictures %s: %s", picdir, strerror(errno));
		pic.scale = (uint32_t)((M + PIC_MAX - 1) / PIC_MAX);
		pic.w = (uint32_t)((W + pic.scale - 1) / pic.scale);
		pic.h = (uint32_t)((H + pic.scale - 1) / pic.scale);
		pic.ha = calloc((size_t)pic.w * pic.h, sizeof(double));
		pic.hb = calloc((size_t)pic.w * pic.h, sizeof(double));
		pic.ka = calloc((size_t)pic.w * pic.h, sizeof(double));
		pic.kb = calloc((size_t)pic.w * pic.h, sizeof(double));
		pic.n = calloc((size_t)pic.w * pic.h, sizeof(double));
		if (!pic.ha || !pic.hb || !pic.ka || !pic.kb || !pic.n)
			cli_fail(prog, "out of memory for the pictures");
	}
	if (!ac.blk_sum || !ac.blk_n)
		cli_fail(prog, "out of memory");
	thr8 = (uint8_t)lround(thr * 255.0);
	if (thr8 < 1)
		thr8 = 1;

	/* bands: block rows (the first and last may be partial) */
	for (int64_t y0 = r.lo[1]; y0 < r.hi[1];) {
		int64_t yb = (y0 / A.b2 + 1) * A.b2;
		uint32_t ny = (uint32_t)((yb < r.hi[1] ? yb : r.hi[1]) - y0);
		for (size_t x = 0; x < W;) {
			int64_t gx = r.lo[0] + (int64_t)x;
			int64_t xb = (gx / A.b1) * A.b1 + (int64_t)chunk_cols;
			size_t nx = (size_t)((xb < r.hi[0] ? xb : r.hi[0]) - gx);
			if (nx > chunk_cols)
				nx = chunk_cols;
			for (int k = 0; k < nin; k++) {
				src *s = k ? &B : &A;
				read_box(prog, s, gx, y0, r.lo[2], (uint32_t)nx, ny, nz, &diag);
				tops(s, (uint32_t)nx, ny, nz, thr8, x, W, r.lo[2]);
			}
			x += nx;
		}
		/* column pairs of this band */
		for (size_t i = 0; i < W / A.b1 + 2; i++) {
			ac.blk_sum[i] = 0;
			ac.blk_n[i] = 0;
		}
		for (uint32_t y = 0; y < ny; y++)
			for (size_t x = 0; x < W; x++) {
				size_t cidx = (size_t)y * W + x;
				int64_t gx = r.lo[0] + (int64_t)x, gy = y0 + y;
				float ha = A.h[cidx], hb = B.h[cidx];
				int centre = gx % A.b1 == A.b1 / 2 && gy % A.b2 == A.b2 / 2;
				size_t bi = (size_t)(gx / A.b1 - r.lo[0] / A.b1);
				double d;
				if (isnan(ha) || isnan(hb))
					continue;
				d = (double)hb - ha;
				ac.both++;
				ac.agree += A.k[cidx] == B.k[cidx];
				if (centre) {
					ac.centres++;
					ac.centres_agree += A.k[cidx] == B.k[cidx];
				}
				ac.d_sum += d;
				ac.d2_sum += d * d;
				ac.blk_sum[bi] += d;
				ac.blk_n[bi]++;
			}
		/* a block counts once its rows are complete: blocks are b2 rows, the
		   band is one block row, so each band closes its blocks (partial
		   blocks at the region's border count with their columns) */
		for (size_t i = 0; i < W / A.b1 + 2; i++)
			if (ac.blk_n[i]) {
				double m = ac.blk_sum[i] / (double)ac.blk_n[i];
				ac.bo_sum += m;
				ac.bo2_sum += m * m;
				ac.bo_n++;
			}
		seams(&A, &r, y0, ny, W, y0 > r.lo[1]);
		if (!single)
			seams(&B, &r, y0, ny, W, y0 > r.lo[1]);
		if (picdir)
			pic_add(&pic, &r, y0, ny, W, &A, &B);
		ac.voxels += (uint64_t)W * ny * nz;
		y0 += ny;
	}

	{
		double n = (double)ac.both, mean = n > 0 ? ac.d_sum / n : 0;
		double rmse = n > 0 ? sqrt(ac.d2_sum / n) : 0;
		double var = n > 0 ? ac.d2_sum / n - mean * mean : 0;
		double deb = sqrt(var > 0 ? var : 0);
		double thick = A.thick_n ? A.thick_sum / (double)A.thick_n : 0;
		double bom = ac.bo_n ? ac.bo_sum / (double)ac.bo_n : 0;
		double bov = ac.bo_n ? ac.bo2_sum / (double)ac.bo_n - bom * bom : 0;
		double bosd = sqrt(bov > 0 ? bov : 0);
		double hw = hist_l1(&A, &B, LOOM_YARN_WARP), hf = hist_l1(&A, &B, LOOM_YARN_WEFT);
		double hl1 = 0.5 * (hw + hf);
		double agc = ac.centres ? (double)ac.centres_agree / (double)ac.centres : 0;
		double aga = n > 0 ? (double)ac.agree / n : 0;
		double cova = A.cols ? (double)A.surf / (double)A.cols : 0;
		double covb = B.cols ? (double)B.surf / (double)B.cols : 0;
		double sra = seam_ratio(&A, A.seam_sum, A.seam_n);
		double srb = seam_ratio(&B, B.seam_sum, B.seam_n);
		double cra = seam_ratio(&A, A.corner_sum, A.corner_n);
		double crb = seam_ratio(&B, B.corner_sum, B.corner_n);
		double csa = coverage_seam_ratio(&A), csb = coverage_seam_ratio(&B);
		double range = 0, secs;
		if (picdir)
			pic_write(prog, &pic, picdir, -mean, deb, &range, &diag);
		secs = now_s() - t0;
		if (json && single) {
			json_w w;
			jw_begin(&w, stdout);
			jw_num(&w, "coverage", cova);
			jw_num(&w, "seam_ratio", sra);
			jw_num(&w, "corner_seam_ratio", cra);
			jw_uint(&w, "corner_pairs", A.corner_n);
			jw_num(&w, "coverage_seam_ratio", csa);
			jw_uint(&w, "voxels", ac.voxels);
			jw_num(&w, "seconds", secs);
			jw_end(&w);
		} else if (json) {
			json_w w;
			jw_begin(&w, stdout);
			jw_num(&w, "top_agreement_centres", agc);
			jw_num(&w, "top_agreement_columns", aga);
			jw_num(&w, "height_rmse", rmse);
			jw_num(&w, "height_rmse_debiased", deb);
			jw_num(&w, "height_rmse_diameters", thick > 0 ? deb / thick : 0);
			jw_num(&w, "block_offset_sd", bosd);
			jw_num(&w, "histogram_l1", hl1);
			jw_num(&w, "coverage_a", cova);
			jw_num(&w, "coverage_b", covb);
			jw_num(&w, "seam_ratio_a", sra);
			jw_num(&w, "seam_ratio_b", srb);
			jw_num(&w, "corner_seam_ratio_a", cra);
			jw_num(&w, "corner_seam_ratio_b", crb);
			jw_uint(&w, "corner_pairs_a", A.corner_n);
			jw_uint(&w, "corner_pairs_b", B.corner_n);
			jw_num(&w, "coverage_seam_ratio_a", csa);
			jw_num(&w, "coverage_seam_ratio_b", csb);
			jw_uint(&w, "voxels", ac.voxels);
			jw_num(&w, "seconds", secs);
			jw_end(&w);
		} else if (!quiet && single) {
			printf("%s\n", A.arg);
			table_head(&r, ac.voxels, &A, thr);
			printf("  %-28s %10.4f\n", "coverage", cova);
			printf("  %-28s %10.4f\n", "seam ratio", sra);
			printf("  %-28s %10.4f  (%llu pairs)\n", "  at block corners", cra,
			       (unsigned long long)A.corner_n);
			printf("  %-28s %10.4f\n", "coverage seam ratio", csa);
			printf("  %.2f s\n", secs);
		} else if (!quiet) {
			printf("A %s\nB %s\n", A.arg, B.arg);
			table_head(&r, ac.voxels, &A, thr);
			printf("  %-28s %10.4f\n", "top agreement, centres", agc);
			printf("  %-28s %10.4f\n", "top agreement, columns", aga);
			printf("  %-28s %10.4f\n", "height RMSE (voxels)", rmse);
			printf("  %-28s %10.4f  (mean B - A %+.3f)\n", "  debiased", deb, mean);
			printf("  %-28s %10.4f  (top-yarn thickness %.2f voxels)\n",
			       "  debiased, diameters", thick > 0 ? deb / thick : 0, thick);
			printf("  %-28s %10.4f  (%llu blocks)\n", "block offset SD (voxels)", bosd,
			       (unsigned long long)ac.bo_n);
			printf("  %-28s %10.4f  (warp %.4f, weft %.4f)\n", "histogram L1", hl1, hw,
			       hf);
			printf("  %-28s %10.4f / %.4f\n", "coverage A / B", cova, covb);
			printf("  %-28s %10.4f / %.4f\n", "seam ratio A / B", sra, srb);
			printf("  %-28s %10.4f / %.4f  (%llu / %llu pairs)\n",
			       "  at block corners A / B", cra, crb,
			       (unsigned long long)A.corner_n, (unsigned long long)B.corner_n);
			printf("  %-28s %10.4f / %.4f\n", "coverage seam ratio A / B", csa, csb);
			printf("  %.2f s\n", secs);
			if (picdir)
				printf("  pictures %s/side-by-side.png, %s/height-difference.png "
				       "(%u voxel columns per pixel, difference ramp +-%.2f voxels)\n",
				       picdir, picdir, pic.scale, range);
		}
	}
	close_src(&A);
	if (!single)
		close_src(&B);
	free(ac.blk_sum);
	free(ac.blk_n);
	free(pic.ha);
	free(pic.hb);
	free(pic.ka);
	free(pic.kb);
	free(pic.n);
	return 0;
}
