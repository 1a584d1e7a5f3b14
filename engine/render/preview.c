/*
 * engine/render/preview.c - shaded orthographic top view of a fabric's virtual
 * texture (loom_preview; docs/preview.md).
 *
 * Three passes over the output:
 *   1. key: the global source block of the crossing under every pixel
 *      (loom_fabric_source_at, once per crossing change along a row), and
 *      a stable counting sort of the pixels by that key;
 *   2. fetch: worker threads take chunks of the sorted order, group
 *      neighbouring columns of one output row into runs and read each run
 *      with one loom_texture_read_region (z fastest); per column the
 *      top-most voxel at or above the threshold gives height, orientation
 *      code, kind and type (stashed in the rgb buffer);
 *   3. shade: normal from the height map, one light, fibre terms.
 * Ordering by source block keeps the texture's working set at the bricks
 * of one exemplar block at a time, so a sparse preview of a huge fabric
 * decompresses each brick about once instead of thrashing the cache.
 */
#include "core/internal.h"
#include "loom/preview.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define RUN_MAX 64u       /* columns per region read */
#define CHUNK 4096u       /* sorted pixels per work item */
#define SIDE_MAX ((int64_t)1 << 46)

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

LOOM_API int loom_preview_size(const loom_preview_options *opt, uint32_t *w,
                               uint32_t *h)
{
	int64_t nx, ny;
	double hh;

	if (!opt || !w || !h || opt->size < sizeof *opt || opt->width == 0)
		return LOOM_EINVAL;
	if (opt->hi[0] <= opt->lo[0] || opt->hi[1] <= opt->lo[1])
		return LOOM_EINVAL;
	if (opt->lo[0] < -SIDE_MAX || opt->lo[1] < -SIDE_MAX ||
	    opt->hi[0] > SIDE_MAX || opt->hi[1] > SIDE_MAX)
		return LOOM_ERANGE;
	nx = opt->hi[0] - opt->lo[0];
	ny = opt->hi[1] - opt->lo[1];
	if (opt->width > LOOM_PREVIEW_MAX_SIDE || opt->height > LOOM_PREVIEW_MAX_SIDE)
		return LOOM_ERANGE;
	*w = opt->width;
	if (opt->height) {
		*h = opt->height;
	} else {
		hh = floor((double)opt->width * (double)ny / (double)nx + 0.5);
		if (hh < 1)
			hh = 1;
		if (hh > LOOM_PREVIEW_MAX_SIDE)
			return LOOM_ERANGE;
		*h = (uint32_t)hh;
	}
	if ((uint64_t)*w * *h > ((uint64_t)1 << 31))
		return LOOM_ERANGE;
	return LOOM_OK;
}

/* Column under pixel k of n across a span of len voxels from lo. */
static int64_t centre(int64_t lo, int64_t len, uint32_t k, uint32_t n)
{
	/* (2k+1) < 2^17 and len <= 2^47: the product fits */
	return lo + (int64_t)(((uint64_t)(2 * (uint64_t)k + 1) * (uint64_t)len) /
	                      (2 * (uint64_t)n));
}

typedef struct pv_job {
	loom_texture *t;
	uint32_t W, H;
	const int64_t *xs, *ys;    /* column of each pixel column / row */
	int64_t z0, z1;
	uint8_t thr;
	const uint32_t *order;
	uint64_t n;                /* pixels */
	float *hmap;               /* height per pixel */
	float *stash;              /* rgb buffer: packed info in slot 0 */
	atomic_uint_fast64_t next; /* next chunk start */
	pthread_mutex_t lock;      /* progress, first error */
	uint64_t done;
	void (*progress)(void *, uint64_t, uint64_t);
	void *progress_user;
	int rc;
	char msg[LOOM_DIAG_MSG_MAX];
	atomic_uint_fast64_t columns, reads, empty;
} pv_job;

static void put_info(float *slot, uint32_t v)
{
	memcpy(slot, &v, sizeof v);
}

static uint32_t get_info(const float *slot)
{
	uint32_t v;
	memcpy(&v, slot, sizeof v);
	return v;
}

static void *pv_worker(void *arg)
{
	pv_job *j = arg;
	size_t nz = (size_t)(j->z1 - j->z0), cap = RUN_MAX * nz;
	uint8_t *dens = malloc(cap), *kind = malloc(cap), *type = malloc(cap);
	uint16_t *ori = malloc(cap * sizeof *ori);
	uint64_t columns = 0, reads = 0, empty = 0;

	if (!dens || !kind || !type || !ori) {
		pthread_mutex_lock(&j->lock);
		if (j->rc == LOOM_OK) {
			j->rc = LOOM_ENOMEM;
			snprintf(j->msg, sizeof j->msg, "preview: out of memory");
		}
		pthread_mutex_unlock(&j->lock);
		goto out;
	}
	for (;;) {
		uint64_t a = atomic_fetch_add(&j->next, CHUNK), b;
		if (a >= j->n)
			break;
		b = a + CHUNK < j->n ? a + CHUNK : j->n;
		for (uint64_t q = a; q < b;) {
			uint32_t p0 = j->order[q];
			uint32_t row = p0 / j->W, i0 = p0 % j->W;
			int64_t xa = j->xs[i0], xb = xa;
			uint64_t r = q + 1;
			loom_texture_region reg;
			int64_t lo[3], hi[3];
			int rc;

			/* extend the run along the row while columns are adjacent */
			while (r < b && r - q < RUN_MAX) {
				uint32_t p = j->order[r];
				int64_t x;
				if (p != j->order[r - 1] + 1 || p / j->W != row)
					break;
				x = j->xs[p % j->W];
				if (x != xb && x != xb + 1)
					break;
				if (x - xa >= (int64_t)RUN_MAX)
					break;
				xb = x;
				r++;
			}
			lo[0] = xa;
			lo[1] = j->ys[row];
			lo[2] = j->z0;
			hi[0] = xb + 1;
			hi[1] = lo[1] + 1;
			hi[2] = j->z1;
			memset(&reg, 0, sizeof reg);
			reg.density = dens;
			reg.orientation = ori;
			reg.kind = kind;
			reg.type = type;
			reg.layout = LOOM_REGION_Z_FASTEST;
			rc = loom_texture_read_region(j->t, lo, hi, &reg);
			reads++;
			columns += (uint64_t)(xb - xa + 1);
			if (rc != LOOM_OK) {
				pthread_mutex_lock(&j->lock);
				if (j->rc == LOOM_OK) {
					j->rc = rc;
					snprintf(j->msg, sizeof j->msg, "%s",
					         loom_texture_errmsg(j->t));
				}
				pthread_mutex_unlock(&j->lock);
			}
			for (uint64_t s = q; s < r; s++) {
				uint32_t p = j->order[s];
				size_t c = (size_t)(j->xs[p % j->W] - xa) * nz;
				size_t k = nz;
				while (k > 0 && dens[c + k - 1] < j->thr)
					k--;
				if (k == 0) {
					j->hmap[p] = 0.0f;
					put_info(&j->stash[3 * (size_t)p], 0);
					empty++;
				} else {
					size_t v = c + k - 1;
					j->hmap[p] = (float)(j->z0 + (int64_t)k);
					put_info(&j->stash[3 * (size_t)p],
					         (uint32_t)ori[v] << 16 | (uint32_t)kind[v] << 8 |
					         type[v]);
				}
			}
			q = r;
		}
		pthread_mutex_lock(&j->lock);
		j->done += b - a;
		if (j->progress)
			j->progress(j->progress_user, j->done, j->n);
		pthread_mutex_unlock(&j->lock);
	}
out:
	atomic_fetch_add(&j->columns, columns);
	atomic_fetch_add(&j->reads, reads);
	atomic_fetch_add(&j->empty, empty);
	loom_texture_thread_done(j->t);
	free(dens);
	free(kind);
	free(type);
	free(ori);
	return NULL;
}

static void normalize3(double v[3])
{
	double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	if (l > 0) {
		v[0] /= l;
		v[1] /= l;
		v[2] /= l;
	}
}

/* Height used for gradients: empty columns count as the floor. */
static double hval(const float *hm, size_t p, double floor_h)
{
	return hm[p] > 0 ? (double)hm[p] : floor_h;
}

static void shade(const loom_preview_options *opt, const loom_design *d,
                  uint32_t W, uint32_t H, double sx, double sy, int64_t z0,
                  int64_t z1, const float *hm, float *rgb,
                  const loom_preview_maps *maps)
{
	double L[3], Hv[3], span = (double)(z1 - z0);

	if (opt->light[0] == 0 && opt->light[1] == 0 && opt->light[2] == 0) {
		L[0] = -0.4;
		L[1] = 0.5;
		L[2] = 0.77;
	} else {
		memcpy(L, opt->light, sizeof L);
	}
	normalize3(L);
	Hv[0] = L[0];
	Hv[1] = L[1];
	Hv[2] = L[2] + 1.0;
	normalize3(Hv);
	for (uint32_t row = 0; row < H; row++) {
		for (uint32_t i = 0; i < W; i++) {
			size_t p = (size_t)row * W + i;
			uint32_t info = get_info(&rgb[3 * p]);
			uint8_t kind = (uint8_t)(info >> 8), type = (uint8_t)info;
			float *out = &rgb[3 * p];
			double n[3], t[3], al[3], align, tl, th, ndl, occ, diff, spec;
			float tf[3];

			if (maps && maps->kind)
				maps->kind[p] = hm[p] > 0 ? kind : 0;
			if (hm[p] <= 0 || kind == 0 || !d || type >= d->n_types) {
				/* empty column (or no yarn type to colour it by) */
				for (int c = 0; c < 3; c++) {
					if (hm[p] > 0 && kind != 0) {
						out[c] = 0.5f;
						continue;
					}
					out[c] = opt->background[c];
				}
				if (maps && maps->albedo)
					memcpy(&maps->albedo[3 * p], out, 3 * sizeof(float));
				continue;
			}
			/* normal: central differences (one-sided at the borders);
			   image row index grows towards -y */
			{
				size_t pl = i > 0 ? p - 1 : p, pr = i + 1 < W ? p + 1 : p;
				size_t pu = row > 0 ? p - W : p, pd = row + 1 < H ? p + W : p;
				double dxs = sx * (double)((i + 1 < W) + (i > 0));
				double dys = sy * (double)((row + 1 < H) + (row > 0));
				double fl = (double)z0;
				n[0] = dxs > 0 ? -(hval(hm, pr, fl) - hval(hm, pl, fl)) / dxs : 0;
				n[1] = dys > 0 ? -(hval(hm, pu, fl) - hval(hm, pd, fl)) / dys : 0;
				n[2] = 1.0;
				normalize3(n);
			}
			loom_orientation_decode((uint16_t)(info >> 16), tf);
			t[0] = tf[0];
			t[1] = tf[1];
			t[2] = tf[2];
			normalize3(t);
			for (int c = 0; c < 3; c++)
				al[c] = d->types[type].albedo[c];
			align = d->types[type].alignment;
			if (!(align > 0) || align > 1)
				align = 0.3;
			tl = t[0] * L[0] + t[1] * L[1] + t[2] * L[2];
			th = t[0] * Hv[0] + t[1] * Hv[1] + t[2] * Hv[2];
			ndl = n[0] * L[0] + n[1] * L[1] + n[2] * L[2];
			if (ndl < 0)
				ndl = 0;
			occ = span > 0 ? 0.45 + 0.55 * ((double)hm[p] - (double)z0) / span : 1.0;
			diff = 0.12 + 0.88 * ndl * (0.3 + 0.7 * sqrt(fmax(0.0, 1.0 - tl * tl)));
			spec = 0.25 * (1.0 - align) *
			       pow(sqrt(fmax(0.0, 1.0 - th * th)), 24.0) * ndl;
			for (int c = 0; c < 3; c++)
				out[c] = (float)(al[c] * diff * occ + spec);
			if (maps && maps->albedo)
				for (int c = 0; c < 3; c++)
					maps->albedo[3 * p + (size_t)c] = (float)al[c];
		}
	}
}

LOOM_API int loom_preview(loom_texture *t, const loom_fabric *f,
                          const loom_preview_options *opt, float *rgb,
                          const loom_preview_maps *maps,
                          loom_preview_stats *stats, loom_diag *diag)
{
	double t0 = now_s();
	loom_fabric_db_identity id;
	const loom_design *d;
	uint32_t W, H, nthreads, *order = NULL, *count = NULL, nblocks;
	int64_t *xs = NULL, *ys = NULL, nx, ny, z0, z1;
	float *hmap = NULL;
	pv_job *job = NULL;
	pthread_t *th = NULL;
	uint64_t n;
	int rc;

	if (!t || !f || !opt || !rgb)
		return loom__fail(diag, LOOM_EINVAL, "loom_preview: NULL argument");
	rc = loom_preview_size(opt, &W, &H);
	if (rc != LOOM_OK)
		return loom__fail(diag, rc, "loom_preview: bad box or size (width %u, "
		                  "height %u, box x [%lld, %lld) y [%lld, %lld))",
		                  opt->width, opt->height, (long long)opt->lo[0],
		                  (long long)opt->hi[0], (long long)opt->lo[1],
		                  (long long)opt->hi[1]);
	if (loom_fabric_get_db_identity(f, &id) != LOOM_OK || !loom_fabric_attached(f))
		return loom__fail(diag, LOOM_EINVAL, "loom_preview: fabric is detached");
	d = loom_fabric_design(f);
	nx = opt->hi[0] - opt->lo[0];
	ny = opt->hi[1] - opt->lo[1];
	z0 = 0;
	z1 = (int64_t)id.block[2];
	if (opt->hi[2] > opt->lo[2]) {
		z0 = opt->lo[2] > 0 ? opt->lo[2] : 0;
		z1 = opt->hi[2] < z1 ? opt->hi[2] : z1;
	}
	n = (uint64_t)W * H;
	nblocks = id.n_blocks + 1; /* + 1: key for an unknown block */
	xs = malloc(W * sizeof *xs);
	ys = malloc(H * sizeof *ys);
	order = malloc(n * sizeof *order);
	count = calloc((size_t)nblocks + 1, sizeof *count);
	hmap = maps && maps->height ? maps->height : malloc(n * sizeof *hmap);
	job = calloc(1, sizeof *job);
	if (!xs || !ys || !order || !count || !hmap || !job) {
		rc = loom__fail(diag, LOOM_ENOMEM, "loom_preview: out of memory for "
		                "%ux%u pixels", W, H);
		goto done;
	}
	for (uint32_t i = 0; i < W; i++)
		xs[i] = centre(opt->lo[0], nx, i, W);
	for (uint32_t j = 0; j < H; j++)
		ys[j] = opt->hi[1] - 1 - (centre(0, ny, j, H));

	/* pass 1: keys (stashed in rgb slot 0), counting sort */
	for (uint32_t j = 0; j < H; j++) {
		int64_t I = loom_synth_floordiv(ys[j], id.block[1]), lastJ = 0;
		uint32_t key = 0;
		int have = 0;
		for (uint32_t i = 0; i < W; i++) {
			int64_t J = loom_synth_floordiv(xs[i], id.block[0]);
			if (!have || J != lastJ) {
				loom_fabric_source src;
				key = nblocks - 1;
				if (z1 > z0 && loom_fabric_source_at(f, I, J, &src) == LOOM_OK &&
				    src.block < id.n_blocks)
					key = src.block;
				lastJ = J;
				have = 1;
			}
			put_info(&rgb[3 * ((size_t)j * W + i)], key);
			count[key + 1]++;
		}
	}
	for (uint32_t k = 0; k < nblocks; k++)
		count[k + 1] += count[k];
	for (uint64_t p = 0; p < n; p++)
		order[count[get_info(&rgb[3 * p])]++] = (uint32_t)p;

	/* pass 2: fetch */
	if (z1 <= z0) {
		for (uint64_t p = 0; p < n; p++) {
			hmap[p] = 0;
			put_info(&rgb[3 * p], 0);
		}
		job->empty = n;
	} else {
		float thf = opt->threshold > 0 ? opt->threshold : 0.2f;
		double tb = ceil((double)thf * 255.0 - 1e-3);
		nthreads = opt->threads;
		if (nthreads == 0) {
			long c = sysconf(_SC_NPROCESSORS_ONLN);
			nthreads = c > 0 ? (uint32_t)c : 1;
		}
		if (nthreads > 256)
			nthreads = 256;
		if ((uint64_t)nthreads > (n + CHUNK - 1) / CHUNK)
			nthreads = (uint32_t)((n + CHUNK - 1) / CHUNK);
		job->t = t;
		job->W = W;
		job->H = H;
		job->xs = xs;
		job->ys = ys;
		job->z0 = z0;
		job->z1 = z1;
		job->thr = (uint8_t)(tb < 1 ? 1 : tb > 255 ? 255 : tb);
		job->order = order;
		job->n = n;
		job->hmap = hmap;
		job->stash = rgb;
		job->progress = opt->progress;
		job->progress_user = opt->progress_user;
		atomic_init(&job->next, 0);
		atomic_init(&job->columns, 0);
		atomic_init(&job->reads, 0);
		atomic_init(&job->empty, 0);
		pthread_mutex_init(&job->lock, NULL);
		th = calloc(nthreads, sizeof *th);
		if (!th) {
			pthread_mutex_destroy(&job->lock);
			rc = loom__fail(diag, LOOM_ENOMEM, "loom_preview: out of memory");
			goto done;
		}
		{
			uint32_t started = 0;
			for (; started + 1 < nthreads; started++)
				if (pthread_create(&th[started], NULL, pv_worker, job) != 0)
					break;
			pv_worker(job); /* the caller works too */
			for (uint32_t k = 0; k < started; k++)
				pthread_join(th[k], NULL);
		}
		pthread_mutex_destroy(&job->lock);
		if (job->rc != LOOM_OK) {
			rc = loom__fail(diag, job->rc, "loom_preview: %s", job->msg);
			goto done;
		}
	}

	/* pass 3: shade */
	shade(opt, d, W, H, (double)nx / W, (double)ny / H, z0, z1, hmap, rgb, maps);
	rc = LOOM_OK;
	if (stats) {
		stats->pixels = n;
		stats->columns = atomic_load(&job->columns);
		stats->region_reads = atomic_load(&job->reads);
		stats->empty = atomic_load(&job->empty);
		stats->seconds = now_s() - t0;
	}
done:
	free(xs);
	free(ys);
	free(order);
	free(count);
	if (!(maps && maps->height))
		free(hmap);
	free(job);
	free(th);
	return rc;
}
