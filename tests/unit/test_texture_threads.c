/*
 * tests/unit/test_texture_threads.c - 2-8 threads hammering one virtual
 * texture (also run under `make tsan`).  The reference is a region read by
 * one thread at a large budget (test_texture.c checks region reads against
 * a brute-force materialisation); every thread compares everything it
 * looks up: random voxels, ray-march walks, small region reads, trilinear
 * samples at voxel centres (short walks of them).  Budgets from the
 * minimum (a few bricks) up;
 * more threads than max_threads (the shared overflow state); threads that
 * come and go (their state returns to the pool when they exit); a texture
 * closed while threads that used it are still alive.
 * LOOM_TEXTURE_TEST_OPS lengthens the hammering.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

static char db_path[4200];
static loom_db *g_db;
static loom_fabric *g_fab;
static int g_ok;
static uint64_t g_seed;
static unsigned g_ops = 2000;

/* the reference window */
static int64_t W0[3], W1[3];
static size_t Wn[3];
static uint8_t *R_d, *R_k, *R_t, *R_l;
static uint16_t *R_o;

static uint64_t mix(uint64_t x)
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

static size_t widx(int64_t x, int64_t y, int64_t z)
{
	return ((size_t)(z - W0[2]) * Wn[1] + (size_t)(y - W0[1])) * Wn[0] + (size_t)(x - W0[0]);
}

static loom_texture *open_tex(size_t budget, unsigned threads)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag d = {0};
	o.budget_bytes = budget;
	o.max_threads = threads;
	if (loom_texture_open(g_fab, g_db, &o, &t, &d))
		printf("  texture open: %s\n", d.message);
	return t;
}

static size_t min_budget(unsigned threads)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag d = {0};
	const char *p;
	o.budget_bytes = 1;
	o.max_threads = threads;
	if (loom_texture_open(g_fab, g_db, &o, &t, &d) != LOOM_EBUDGET)
		return 0;
	p = strstr(d.message, "needs at least ");
	return p ? (size_t)strtoull(p + 15, NULL, 10) : 0;
}

static void setup(void)
{
	const char *ops = getenv("LOOM_TEXTURE_TEST_OPS");
	loom_exgen_params p;
	loom_design *d = NULL;
	loom_texture *t;
	loom_texture_region reg = {0};
	loom_db_info info;
	size_t n;

	if (ops)
		g_ops = (unsigned)strtoul(ops, NULL, 0);
	if (tmpdir_make())
		return;
	snprintf(db_path, sizeof db_path, "%s/tiny.ldb", tmpdir);
	CHECK_EQ_INT(loom_exgen_preset("tiny", &p), LOOM_OK);
	p.brick[0] = 4, p.brick[1] = 4, p.brick[2] = 8;
	p.threads = 1;
	/* format version 3: density-only lookups fill segments (4 of one
	   row each here), claimed by threads at once (the TSan run) */
	p.db_version = 3;
	CHECK_EQ_INT(loom_exgen_write_db(db_path, &p, NULL, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_db_open(db_path, &g_db, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_design_new(6, 10, &d), LOOM_OK);
	if (!g_db || !d)
		return;
	loom_design_set_types(d, 3);
	for (size_t i = 0; i < 60; i++) {
		uint64_t h = mix(i + 77);
		d->weave[i] = h & 1;
		d->warp_type[i] = (uint8_t)(h >> 8 & 1);
		d->weft_type[i] = (uint8_t)(1 + (h >> 9 & 1));
	}
	CHECK_EQ_INT(loom_fabric_synthesize(d, g_db, db_path, NULL, &g_fab, NULL), LOOM_OK);
	loom_design_free(d);
	if (!g_fab)
		return;
	loom_db_get_info(g_db, &info);
	W0[0] = -45, W0[1] = -31, W0[2] = -2;
	W1[0] = 130, W1[1] = 95, W1[2] = info.block[2] + 2;
	for (int a = 0; a < 3; a++)
		Wn[a] = (size_t)(W1[a] - W0[a]);
	n = Wn[0] * Wn[1] * Wn[2];
	R_d = malloc(n), R_k = malloc(n), R_t = malloc(n), R_l = malloc(n);
	R_o = malloc(2 * n);
	t = open_tex(256u << 20, 1);
	if (!t)
		return;
	reg.density = R_d, reg.orientation = R_o, reg.kind = R_k, reg.type = R_t;
	reg.label = R_l;
	CHECK_EQ_INT(loom_texture_read_region(t, W0, W1, &reg), LOOM_OK);
	loom_texture_close(t);
	g_ok = check_fail_count == 0;
}

/* ---------------------------------------------------------- the workers */

struct job {
	loom_texture *t;
	loom_texture *t2;          /* a second texture to alternate with */
	pthread_barrier_t *start;
	pthread_barrier_t *before_exit; /* wait here before exiting, if set */
	unsigned ops;
	uint64_t seed;
	int done_midway;           /* call loom_texture_thread_done midway */
	atomic_ulong *bad, *errors, *lookups;
};

/* The channel mask of an operation: random, or g_mask when set (set
   before the threads start). */
static unsigned g_mask;

static unsigned op_mask(uint64_t h)
{
	return g_mask ? g_mask : (unsigned)(h >> 8) & 7;
}

/* Voxel (x, y, z) through loom_texture_voxel_ch with mask ch (7: all):
   the channels asked for equal the reference, the others are zero. */
static int check_voxel(loom_texture *t, int64_t x, int64_t y, int64_t z, unsigned ch)
{
	loom_texel a;
	size_t i = widx(x, y, z);
	int md = ch & LOOM_CHANNEL_DENSITY, mo = ch & LOOM_CHANNEL_ORIENTATION,
	    mm = ch & LOOM_CHANNEL_MATERIAL;
	if (loom_texture_voxel_ch(t, x, y, z, ch, &a) != LOOM_OK)
		return -1;
	if (a.kind != (mm ? R_k[i] : 0) || a.type != (mm ? R_t[i] : 0) ||
	    a.label != (mm ? R_l[i] : 0) || a.density != (md ? (float)R_d[i] / 255.0f : 0.0f))
		return 1;
	{
		float v[3] = {0, 0, 0};
		if (R_d[i] && mo)
			loom_orientation_decode(R_o[i], v);
		if (memcmp(v, a.orientation, sizeof v))
			return 1;
	}
	return 0;
}

static void *worker(void *arg)
{
	struct job *j = arg;
	uint64_t s = j->seed, bad = 0, errors = 0, looked = 0;
	loom_texture *t = j->t;

	pthread_barrier_wait(j->start);
	for (unsigned op = 0; op < j->ops; op++) {
		uint64_t h = mix(s++);
		unsigned kind = (unsigned)(h % 16);
		if (j->t2 && (op & 64))
			t = (op & 128) ? j->t2 : j->t;
		if (j->done_midway && op == j->ops / 2)
			loom_texture_thread_done(t);
		if (kind < 7) { /* random voxel */
			int64_t x = W0[0] + (int64_t)(mix(s++) % Wn[0]);
			int64_t y = W0[1] + (int64_t)(mix(s++) % Wn[1]);
			int64_t z = W0[2] + (int64_t)(mix(s++) % Wn[2]);
			int r = check_voxel(t, x, y, z, op_mask(h));
			bad += r > 0;
			errors += r < 0;
			looked++;
		} else if (kind < 13) { /* a ray march of 40 steps of 0.7 voxel */
			double p[3], dir[3], len;
			for (int a = 0; a < 3; a++) {
				p[a] = (double)W0[a] + 3 + (double)(mix(s++) % (Wn[a] * 1000 - 6000)) / 1000.0;
				dir[a] = (double)(mix(s++) % 2001) / 1000.0 - 1.0;
			}
			dir[2] *= 0.3;
			len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]) + 1e-9;
			for (int k = 0; k < 40; k++) {
				int64_t q[3];
				int in = 1;
				for (int a = 0; a < 3; a++) {
					q[a] = (int64_t)floor(p[a] + 0.7 * k * dir[a] / len);
					in &= q[a] >= W0[a] && q[a] < W1[a];
				}
				if (!in)
					break;
				{
					int r = check_voxel(t, q[0], q[1], q[2], op_mask(h));
					bad += r > 0;
					errors += r < 0;
					looked++;
				}
			}
		} else if (kind < 15) { /* a small region */
			int64_t lo[3], hi[3];
			uint8_t d[6 * 5 * 7], kd[6 * 5 * 7];
			uint16_t o[6 * 5 * 7];
			int zf = (int)(h >> 8 & 1);
			loom_texture_region reg = {d, o, kd, NULL, NULL, zf};
			for (int a = 0; a < 3; a++) {
				lo[a] = W0[a] + (int64_t)(mix(s++) % (Wn[a] - 7));
				hi[a] = lo[a] + (a == 0 ? 6 : a == 1 ? 5 : 7);
			}
			if (loom_texture_read_region(t, lo, hi, &reg) != LOOM_OK)
				errors++;
			for (int64_t z = lo[2]; z < hi[2]; z++)
				for (int64_t y = lo[1]; y < hi[1]; y++)
					for (int64_t x = lo[0]; x < hi[0]; x++) {
						size_t w = widx(x, y, z);
						size_t i = zf ? ((size_t)(y - lo[1]) * 6 + (size_t)(x - lo[0])) * 7 +
						                        (size_t)(z - lo[2]) :
						                ((size_t)(z - lo[2]) * 5 + (size_t)(y - lo[1])) * 6 +
						                        (size_t)(x - lo[0]);
						bad += d[i] != R_d[w] || o[i] != R_o[w] || kd[i] != R_k[w];
					}
			looked += 210;
		} else { /* trilinear at voxel centres = the voxels: a walk of up
			    to 6 unit steps (the corner columns kept from step to step) */
			int64_t x = W0[0] + (int64_t)(mix(s++) % Wn[0]);
			int64_t y = W0[1] + (int64_t)(mix(s++) % Wn[1]);
			int64_t z = W0[2] + 1 + (int64_t)(mix(s++) % (Wn[2] - 2));
			int dx = (int)(h >> 12 & 1), dy = (int)(h >> 13 & 1);
			unsigned ch = op_mask(h); /* 0: nothing asked */
			for (int k = 0; k < 6; k++, x += dx, y += dy) {
				double p[3] = {x + 0.5, y + 0.5, z + 0.5};
				loom_texel a;
				if (x >= W1[0] - 1 || y >= W1[1] - 1)
					break;
				if (loom_texture_sample_ch(t, p, LOOM_FILTER_TRILINEAR, ch, &a) != LOOM_OK)
					errors++;
				bad += a.density != ((ch & LOOM_CHANNEL_DENSITY)
				                             ? (float)R_d[widx(x, y, z)] / 255.0f
				                             : 0.0f) ||
				       a.kind != ((ch & LOOM_CHANNEL_MATERIAL) ? R_k[widx(x, y, z)] : 0);
				looked++;
			}
		}
	}
	atomic_fetch_add(j->bad, bad);
	atomic_fetch_add(j->errors, errors);
	atomic_fetch_add(j->lookups, looked);
	if (j->before_exit) {
		pthread_barrier_t *b = j->before_exit; /* j dies with run_threads */
		pthread_barrier_wait(b); /* finished */
		pthread_barrier_wait(b); /* the texture is closed */
	}
	return NULL;
}

/* Run n threads on t (and t2); returns mismatches + errors. */
static uint64_t run_threads(loom_texture *t, loom_texture *t2, unsigned n,
                            int done_midway, pthread_barrier_t *before_exit,
                            pthread_t *th_out)
{
	pthread_t th[16];
	struct job jobs[16];
	pthread_barrier_t start;
	atomic_ulong bad = 0, errors = 0, lookups = 0;

	pthread_barrier_init(&start, NULL, n);
	for (unsigned k = 0; k < n; k++) {
		jobs[k].t = t;
		jobs[k].t2 = t2;
		jobs[k].start = &start;
		jobs[k].before_exit = before_exit;
		jobs[k].ops = g_ops;
		jobs[k].seed = mix(g_seed + k * 7919 + n);
		jobs[k].done_midway = done_midway;
		jobs[k].bad = &bad;
		jobs[k].errors = &errors;
		jobs[k].lookups = &lookups;
		pthread_create(&th[k], NULL, worker, &jobs[k]);
	}
	if (th_out) { /* wait until they finished; the caller joins */
		pthread_barrier_wait(before_exit);
		memcpy(th_out, th, n * sizeof th[0]);
	} else {
		for (unsigned k = 0; k < n; k++)
			pthread_join(th[k], NULL);
	}
	pthread_barrier_destroy(&start);
	if (bad || errors)
		printf("  %u threads: %lu wrong, %lu errors\n", n, (unsigned long)bad,
		       (unsigned long)errors);
	return bad + errors;
}

static void report(const char *what, loom_texture *t)
{
	loom_texture_stats st;
	loom_texture_get_stats(t, &st);
	printf("  %s: budget %llu, %u frames, lookups %llu, hit rate %.4f, "
	       "evictions %llu, peak %llu\n", what, (unsigned long long)st.budget_bytes,
	       st.cache_frames, (unsigned long long)st.lookups,
	       st.hits + st.misses ? (double)st.hits / (double)(st.hits + st.misses) : 0,
	       (unsigned long long)st.evictions, (unsigned long long)st.peak_bytes);
	CHECK(st.peak_bytes <= st.budget_bytes);
	CHECK_EQ_INT(st.errors, 0);
	CHECK_EQ_INT(st.hits + st.misses + st.empty_bricks, st.brick_requests);
	CHECK_EQ_INT(st.threads, 0); /* every thread exited: states returned */
}

static void hammer_budgets(void)
{
	static const unsigned threads[] = {2, 4, 8};
	if (!g_ok)
		return;
	for (int k = 0; k < 3; k++) {
		unsigned n = threads[k];
		size_t budgets[2] = {min_budget(n), min_budget(n) + (64u << 10)};
		for (int b = 0; b < 2; b++) {
			loom_texture *t = open_tex(budgets[b], n);
			char what[64];
			if (!t)
				continue;
			CHECK_EQ_INT(run_threads(t, NULL, n, b, NULL, NULL), 0);
			snprintf(what, sizeof what, "%u threads, budget %s", n,
			         b ? "min + 64 KiB" : "minimum");
			report(what, t);
			loom_texture_close(t);
		}
	}
}

/* Every point lookup density-only: the threads share density units
   (database version 2) and race to fill the same planes at the smallest
   budget (units evicted while others fill theirs); values equal the
   reference and planes were filled (misses that read). */
static void density_only_fills(void)
{
	static const unsigned threads[] = {2, 4, 8};
	if (!g_ok)
		return;
	g_mask = LOOM_CHANNEL_DENSITY;
	for (int k = 0; k < 3; k++) {
		unsigned n = threads[k];
		loom_texture *t = open_tex(min_budget(n), n);
		loom_texture_stats st;
		if (!t)
			continue;
		CHECK_EQ_INT(run_threads(t, NULL, n, 0, NULL, NULL), 0);
		loom_texture_get_stats(t, &st);
		CHECK(st.misses > 0 && st.bytes_decompressed > 0);
		report("density only", t);
		loom_texture_close(t);
	}
	g_mask = 0;
}

/* More threads than private states: the rest share the overflow state. */
static void overflow_threads(void)
{
	loom_texture *t;
	if (!g_ok)
		return;
	t = open_tex(min_budget(2) + 4096, 2);
	if (!t)
		return;
	CHECK_EQ_INT(run_threads(t, NULL, 8, 0, NULL, NULL), 0);
	report("8 threads on 2 states", t);
	loom_texture_close(t);
}

/* Waves of threads: states return to the pool at thread exit, so every
   wave finds them free; a thread alternating two textures. */
static void threads_come_and_go(void)
{
	loom_texture *t, *t2;
	if (!g_ok)
		return;
	t = open_tex(1u << 20, 4);
	t2 = open_tex(min_budget(4), 4);
	if (!t || !t2)
		goto done;
	for (int wave = 0; wave < 3; wave++) {
		loom_texture_stats st;
		CHECK_EQ_INT(run_threads(t, wave == 2 ? t2 : NULL, 4, wave == 1, NULL, NULL), 0);
		loom_texture_get_stats(t, &st);
		CHECK_EQ_INT(st.threads, 0);
	}
	report("3 waves of 4 threads", t);
	report("second texture", t2);
done:
	loom_texture_close(t);
	loom_texture_close(t2);
}

/* Close a texture while threads that used it are alive; they exit after
   (their exit must not touch it: ASan/TSan would say so). */
static void close_before_thread_exit(void)
{
	pthread_t th[4];
	pthread_barrier_t before_exit;
	loom_texture *t;

	if (!g_ok)
		return;
	t = open_tex(1u << 20, 2);
	if (!t)
		return;
	pthread_barrier_init(&before_exit, NULL, 5);
	run_threads(t, NULL, 4, 0, &before_exit, th);
	/* the workers have finished and wait, bound to t (2 private states +
	   the overflow one): close t, then let them exit */
	{
		loom_texture_stats st;
		loom_texture_get_stats(t, &st);
		CHECK_EQ_INT(st.threads, 2);
		loom_texture_close(t);
		printf("  closed with %u thread states bound, %llu lookups\n", st.threads,
		       (unsigned long long)st.lookups);
	}
	pthread_barrier_wait(&before_exit);
	for (int k = 0; k < 4; k++)
		pthread_join(th[k], NULL);
	pthread_barrier_destroy(&before_exit);
	/* a new texture works as usual afterwards */
	t = open_tex(1u << 20, 2);
	if (t) {
		CHECK_EQ_INT(run_threads(t, NULL, 2, 0, NULL, NULL), 0);
		loom_texture_close(t);
	}
}

/* One voxel of every column of the window, checked against the
   reference; the number wrong in *arg's first word. */
struct sweep {
	loom_texture *t;
	unsigned bad;
};

static void *sweep_columns(void *arg)
{
	struct sweep *w = arg;
	for (int64_t y = W0[1]; y < W1[1]; y++)
		for (int64_t x = W0[0]; x < W1[0]; x++)
			w->bad += check_voxel(w->t, x, y, (W0[2] + W1[2]) / 2 + (x + y) % 3,
			                      LOOM_CHANNEL_ALL) != 0;
	return NULL;
}

/* The column offsets are shared between threads: a second thread that
   looks up the columns a first one did computes none of them (the maps
   hold every crossing of the window at this budget), and both read the
   reference's values. */
static void offset_maps_shared(void)
{
	loom_texture *t;
	loom_texture_stats s1, s2;
	struct sweep w = {0};
	pthread_t th;

	if (!g_ok)
		return;
	t = open_tex(64u << 20, 2);
	if (!t)
		return;
	w.t = t;
	pthread_create(&th, NULL, sweep_columns, &w);
	pthread_join(th, NULL);
	loom_texture_get_stats(t, &s1);
	pthread_create(&th, NULL, sweep_columns, &w);
	pthread_join(th, NULL);
	loom_texture_get_stats(t, &s2);
	printf("  offsets computed: %llu by the first thread, %llu by the second "
	       "(%llu columns)\n", (unsigned long long)s1.dz_columns,
	       (unsigned long long)(s2.dz_columns - s1.dz_columns),
	       (unsigned long long)(Wn[0] * Wn[1]));
	CHECK_EQ_INT(w.bad, 0);
	CHECK(s1.dz_columns > 0 && s1.dz_columns <= Wn[0] * Wn[1]);
	CHECK_EQ_INT(s2.dz_columns, s1.dz_columns);
	CHECK(s2.crossings > s1.crossings); /* the second set up its own entries */
	loom_texture_close(t);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_texture_threads");
	g_seed = check_seed();
	RUN(setup);
	RUN(hammer_budgets);
	RUN(density_only_fills);
	RUN(overflow_threads);
	RUN(threads_come_and_go);
	RUN(close_before_thread_exit);
	RUN(offset_maps_shared);
	free(R_d), free(R_k), free(R_t), free(R_l), free(R_o);
	loom_fabric_free(g_fab);
	loom_db_close(g_db);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
