/*
 * tools/loom/cmd_sample.c - `loom sample FABRIC`: look voxels of a fabric's
 * virtual texture up (loom/texture.h): one position (--at), or N random
 * lookups on several threads with timing and cache statistics (--random).
 * docs/engine.md describes the lookups and the figures printed.
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char usage[] =
	"loom sample FABRIC [--db DB] --at X,Y,Z [--filter nearest|trilinear]\n"
	"                   [--budget MB] [--json]\n"
	"loom sample FABRIC [--db DB] --random N [--seed S] [--budget MB]\n"
	"                   [--threads N] [--json] [--quiet]\n";

static const char about[] =
	"Look voxels of the fabric's virtual texture up (docs/engine.md).\n";

/* The texture's limits (loom/texture.h): integer voxel coordinates below
   2^62 in magnitude, real positions (and every trilinear lookup) below
   2^61. */
#define AT_HELP \
	"one position in voxels (x across the ends, y along the warps, z up; " \
	"the bolt is unbounded in x and y): prints density, fibre orientation, " \
	"kind (0 empty, 1 warp, 2 weft), yarn type and albedo.  Integers with " \
	"the nearest filter name a voxel and must be below 2^62 in magnitude; " \
	"other positions below 2^61"

static const opt_choice filter_names[] = {
	{"nearest", LOOM_FILTER_NEAREST}, {"trilinear", LOOM_FILTER_TRILINEAR}, {NULL, 0}};

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static uint64_t mix(uint64_t x) /* splitmix64 */
{
	x += 0x9e3779b97f4a7c15ull;
	x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
	x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
	return x ^ (x >> 31);
}

/* Peak resident set of this process (VmHWM), bytes; 0 if unknown. */
static uint64_t peak_rss(void)
{
	FILE *fp = fopen("/proc/self/status", "r");
	char line[256];
	unsigned long long kb = 0;

	if (!fp)
		return 0;
	while (fgets(line, sizeof line, fp))
		if (sscanf(line, "VmHWM: %llu kB", &kb) == 1)
			break;
	fclose(fp);
	return (uint64_t)kb * 1024;
}

/* --at "X,Y,Z": three numbers; ints[a] = 1 where the text is an integer. */
typedef struct at_pos {
	double v[3];
	int64_t iv[3];
	int ints[3];
} at_pos;

static const char *parse_at(const char *s, void *dest)
{
	at_pos *at = dest;
	char buf[256], *p = buf;

	if (strlen(s) >= sizeof buf)
		return "three numbers X,Y,Z";
	strcpy(buf, s);
	for (int a = 0; a < 3; a++) {
		char *comma = strchr(p, ',');
		if ((a < 2) != (comma != NULL))
			return "three numbers X,Y,Z";
		if (comma)
			*comma = 0;
		at->ints[a] = cli_parse_i64(p, &at->iv[a]) == 0;
		if (cli_parse_double(p, &at->v[a]) != 0 || !isfinite(at->v[a]))
			return "three numbers X,Y,Z";
		if (at->ints[a])
			at->v[a] = (double)at->iv[a];
		p = comma ? comma + 1 : p;
	}
	return NULL;
}

static const char *kind_name(int k)
{
	return k == LOOM_YARN_WARP ? "warp" : k == LOOM_YARN_WEFT ? "weft" : "empty";
}

/* ---- --random ------------------------------------------------------------ */

struct rjob {
	loom_texture *t;
	uint64_t first, n;       /* lookups [first, first + n) of the stream */
	uint64_t seed;
	uint64_t size[3];        /* one repeat, voxels */
	atomic_ullong *done;     /* progress */
	uint64_t sum, nonempty;  /* results */
	int rc;
	char msg[LOOM_DIAG_MSG_MAX];
};

static void *random_worker(void *arg)
{
	struct rjob *j = arg;

	for (uint64_t i = j->first; i < j->first + j->n; i++) {
		uint64_t h = mix(j->seed ^ mix(i));
		int64_t x = (int64_t)(h % j->size[0]);
		int64_t y = (int64_t)(mix(h) % j->size[1]);
		int64_t z = (int64_t)(mix(h + 1) % j->size[2]);
		loom_texel tx;
		int rc = loom_texture_voxel(j->t, x, y, z, &tx);
		if (rc != LOOM_OK && j->rc == LOOM_OK) {
			j->rc = rc;
			snprintf(j->msg, sizeof j->msg, "%s", loom_texture_errmsg(j->t));
		}
		/* order-independent checksum of what was looked up */
		j->sum += mix(i ^ ((uint64_t)(tx.density * 255.0f + 0.5f) |
		                   (uint64_t)tx.kind << 8 | (uint64_t)tx.type << 16 |
		                   (uint64_t)tx.label << 24) << 32);
		j->nonempty += tx.density > 0;
		if ((i & 1023) == 1023)
			atomic_fetch_add_explicit(j->done, 1024, memory_order_relaxed);
	}
	loom_texture_thread_done(j->t);
	return NULL;
}

static int run_random(const char *prog, loom_texture *t, const loom_fabric *f,
                      uint64_t n, uint64_t seed, unsigned threads, int json,
                      int quiet, double budget_mb)
{
	struct rjob *jobs = calloc(threads, sizeof *jobs);
	pthread_t *th = calloc(threads, sizeof *th);
	atomic_ullong done = 0;
	uint64_t size[3], sum = 0, nonempty = 0;
	loom_texture_stats st;
	double t0, secs, rate, hit_rate;
	int progress = !quiet && isatty(2), rc = LOOM_OK;
	const char *msg = "";

	if (!jobs || !th)
		cli_fail(prog, "out of memory");
	loom_fabric_repeat_voxels(f, size);
	t0 = now_s();
	for (unsigned k = 0; k < threads; k++) {
		jobs[k].t = t;
		jobs[k].first = n * k / threads;
		jobs[k].n = n * (k + 1) / threads - jobs[k].first;
		jobs[k].seed = seed;
		memcpy(jobs[k].size, size, sizeof size);
		jobs[k].done = &done;
		if (pthread_create(&th[k], NULL, random_worker, &jobs[k]) != 0)
			cli_fail(prog, "cannot start thread %u", k);
	}
	if (progress) {
		for (;;) {
			struct timespec ts = {0, 200000000};
			unsigned long long d = atomic_load(&done);
			fprintf(stderr, "\r%s: %llu / %llu lookups", prog, d,
			        (unsigned long long)n);
			if (d + 1024ull * threads > n)
				break;
			nanosleep(&ts, NULL);
		}
		fprintf(stderr, "\n");
	}
	for (unsigned k = 0; k < threads; k++) {
		pthread_join(th[k], NULL);
		sum += jobs[k].sum;
		nonempty += jobs[k].nonempty;
		if (jobs[k].rc != LOOM_OK && rc == LOOM_OK) {
			rc = jobs[k].rc;
			msg = jobs[k].msg;
		}
	}
	secs = now_s() - t0;
	loom_texture_get_stats(t, &st);
	rate = secs > 0 ? (double)n / secs : 0;
	hit_rate = cli_hit_rate(&st);
	if (json) {
		json_w w;
		char cs[32];
		snprintf(cs, sizeof cs, "%016llx", (unsigned long long)sum);
		jw_begin(&w, stdout);
		jw_uint(&w, "lookups", n);
		jw_uint(&w, "threads", threads);
		jw_uint(&w, "seed", seed);
		jw_num(&w, "seconds", secs);
		jw_num(&w, "lookups_per_second", rate);
		jw_texture_stats(&w, &st);
		jw_uint(&w, "peak_rss_bytes", peak_rss());
		jw_uint(&w, "nonempty", nonempty);
		jw_str(&w, "checksum", cs);
		jw_uint(&w, "errors", st.errors);
		jw_end(&w);
	} else if (!quiet) {
		printf("%llu random lookups on %u thread%s in %.3f s: %.0f lookups/s\n",
		       (unsigned long long)n, threads, threads == 1 ? "" : "s", secs, rate);
		printf("  budget %.1f MiB: %u brick frames of %llu bytes, peak %.2f MiB "
		       "(fixed part %.2f MiB)\n", budget_mb, st.cache_frames,
		       (unsigned long long)st.brick_bytes, (double)st.peak_bytes / 1048576.0,
		       (double)st.fixed_bytes / 1048576.0);
		printf("  bricks: %llu requests, hit rate %.4f, %llu misses, %llu empty, "
		       "%llu evictions\n", (unsigned long long)st.brick_requests, hit_rate,
		       (unsigned long long)st.misses, (unsigned long long)st.empty_bricks,
		       (unsigned long long)st.evictions);
		printf("  read %.2f MiB, decompressed %.2f MiB in %.3f s\n",
		       (double)st.bytes_read / 1048576.0,
		       (double)st.bytes_decompressed / 1048576.0,
		       (double)st.decompress_ns * 1e-9);
		printf("  peak RSS %.2f MiB\n", (double)peak_rss() / 1048576.0);
		printf("  %llu non-empty voxels, checksum %016llx\n",
		       (unsigned long long)nonempty, (unsigned long long)sum);
	}
	if (rc != LOOM_OK)
		cli_error(prog, "%s", msg);
	free(jobs);
	free(th);
	return rc != LOOM_OK ? EXIT_BAD_INPUT : 0;
}

/* ---- --at ------------------------------------------------------------------- */

static int run_at(const char *prog, loom_texture *t, const loom_fabric *f,
                  const at_pos *at, int filter, int json, int quiet)
{
	const loom_design *d = loom_fabric_design(f);
	const double *v = at->v;
	const int64_t *iv = at->iv;
	const int *ints = at->ints;
	int voxel = filter == LOOM_FILTER_NEAREST && ints[0] && ints[1] && ints[2];
	loom_texel tx;
	int rc;

	if (voxel)
		rc = loom_texture_voxel(t, iv[0], iv[1], iv[2], &tx);
	else
		rc = loom_texture_sample(t, v, filter, &tx);
	if ((rc == LOOM_EINVAL || rc == LOOM_ERANGE) && voxel)
		cli_fail(prog, "voxel %lld,%lld,%lld out of range (|coordinate| < 2^62)",
		         (long long)iv[0], (long long)iv[1], (long long)iv[2]);
	if (rc == LOOM_EINVAL || rc == LOOM_ERANGE)
		cli_fail(prog, "position %g,%g,%g out of range (|coordinate| < 2^61 for real "
		         "positions and trilinear lookups)", v[0], v[1], v[2]);
	if (rc != LOOM_OK)
		cli_fail(prog, "%s", loom_texture_errmsg(t));
	if (json) {
		json_w w;
		jw_begin(&w, stdout);
		jw_arr(&w, "position");
		for (int a = 0; a < 3; a++) {
			if (ints[a])
				jw_int(&w, NULL, iv[a]);
			else
				jw_num(&w, NULL, v[a]);
		}
		jw_close(&w);
		jw_str(&w, "filter", filter == LOOM_FILTER_NEAREST ? "nearest" : "trilinear");
		jw_num(&w, "density", tx.density);
		jw_arr(&w, "orientation");
		for (int a = 0; a < 3; a++)
			jw_num(&w, NULL, tx.orientation[a]);
		jw_close(&w);
		jw_int(&w, "kind", tx.kind);
		jw_str(&w, "kind_name", kind_name(tx.kind));
		jw_int(&w, "type", tx.type);
		jw_str(&w, "type_name", tx.kind && tx.type < d->n_types ? d->types[tx.type].name : "");
		jw_arr(&w, "albedo");
		for (int a = 0; a < 3; a++)
			jw_num(&w, NULL, tx.albedo[a]);
		jw_close(&w);
		jw_num(&w, "alignment", tx.alignment);
		jw_int(&w, "label", tx.label);
		jw_end(&w);
	} else if (!quiet) {
		printf("voxel at %g,%g,%g (%s)\n", v[0], v[1], v[2],
		       filter == LOOM_FILTER_NEAREST ? "nearest" : "trilinear");
		printf("  density      %.6f\n", tx.density);
		printf("  orientation  %.6f %.6f %.6f\n", tx.orientation[0], tx.orientation[1],
		       tx.orientation[2]);
		printf("  kind         %d (%s)\n", tx.kind, kind_name(tx.kind));
		if (tx.kind)
			printf("  type         %d (%s)\n", tx.type,
			       tx.type < d->n_types ? d->types[tx.type].name : "?");
		else
			printf("  type         0\n");
		printf("  albedo       %.6f %.6f %.6f\n", tx.albedo[0], tx.albedo[1],
		       tx.albedo[2]);
		printf("  alignment    %.6f\n", tx.alignment);
		printf("  label        %d\n", tx.label);
	}
	return 0;
}

int cmd_sample(int argc, char **argv)
{
	const char *prog = "loom sample";
	const char *path = NULL, *db_opt = NULL;
	int json = 0, quiet = 0, filter = LOOM_FILTER_NEAREST, rc;
	uint64_t n = 0, seed = 1;
	uint32_t threads = 1;
	double budget_mb = 64;
	at_pos at = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_diag diag;
	opt_entry opts[] = {
		OPT_CALLBACK(0, "at", &at, "X,Y,Z", parse_at, AT_HELP),
		OPT_ENUM(0, "filter", &filter, "F", filter_names, "nearest (default: the voxel "
		         "containing the position; integers name voxels) or trilinear (voxel "
		         "centres are at integer + 0.5)"),
		OPT_U64(0, "random", &n, "N", 1, UINT64_MAX, "N nearest lookups at uniformly "
		        "random voxels of one design repeat; prints lookups per second, the "
		        "cache's statistics, the peak resident memory and a checksum of the "
		        "voxels (the same for any budget and thread count)"),
		OPT_SEED(&seed, "S", "seed of the random positions (default 1)"),
		OPT_THREADS(&threads, 1024, "lookup threads for --random (default 1; %r)"),
		OPT_BUDGET(&budget_mb, "memory budget of the texture in MiB (default 64)"),
		OPT_DB(&db_opt, "the exemplar database (default: the path recorded in the "
		       "fabric)"),
		OPT_JSON(&json, "print the result as JSON"),
		OPT_QUIET(&quiet, "nothing on success (no progress, no text result; --json "
		          "still prints)"),
		OPT_END()
	};
	opts_cmd c = {.prog = prog, .usage = usage, .about = about,
	              .exit1 = "bad input or failed lookup", .opts = opts,
	              .pos_name = "FABRIC", .pos_min = 1, .pos_max = 1, .pos = &path};

	opts_parse(&c, argc, argv);
	if (!opt_given(&c, &at) == !opt_given(&c, &n))
		opts_usage(&c, "give one of --at X,Y,Z or --random N");
	if (opt_given(&c, &filter) && opt_given(&c, &n))
		opts_usage(&c, "--filter goes with --at");
	if ((opt_given(&c, &seed) || opt_given(&c, &threads)) && !opt_given(&c, &n))
		opts_usage(&c, "--seed and --threads go with --random");
	cli_diag_init(&diag, &quiet);

	if (db_opt && loom_db_open(db_opt, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	/* a design too large for --budget: refused before it is read */
	cli_fabric_fits(prog, path, budget_mb * 1048576.0, "this fabric needs", EXIT_BAD_INPUT);
	if (loom_fabric_open(path, db, 0, &f, &diag) != LOOM_OK) {
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	o.budget_bytes = (size_t)(budget_mb * 1048576.0);
	o.max_threads = threads;
	if (loom_texture_open(f, db, &o, &t, &diag) != LOOM_OK) {
		loom_fabric_free(f);
		loom_db_close(db);
		cli_fail(prog, "%s", diag.message);
	}
	if (opt_given(&c, &at))
		rc = run_at(prog, t, f, &at, filter, json, quiet);
	else
		rc = run_random(prog, t, f, n, seed, threads, json, quiet, budget_mb);
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
	return rc;
}
