/*
 * tools/loom/settdb.c - exemplar databases woven at a draft's own sett
 * (docs/exemplars.md, "Databases for a draft's sett"), and the checks of
 * a design against the database it is synthesized over: the sett's
 * aspect (cli_sett_check) and the longest floats (cli_float_check).
 *
 * A draft that states its sett (WIF Spacing) gets a database generated for
 * that sett and those yarn diameters: the small preset's weaves and seed,
 * exemplars of at least SETT_MIN_CROSSINGS crossings a side (as the default
 * database's),
 * cotton fibre-level yarns (as loom exemplar generate's default) or the
 * yarns of loom synth --fibre (which also makes one for a draft that states
 * no sett: the small preset's geometry with those yarns); a design whose
 * yarn types have materials of several (warp, weft) pairs gets one set of
 * exemplars per pair (loom_exgen_params.pairs, at most 4),
 * the finer of the two spacings 16 voxels long (as in the default
 * database), b1 x b2 from the sett.  Databases are cached in
 *   $LOOM_CACHE_DIR, else $XDG_CACHE_HOME/loom, else $HOME/.cache/loom
 * as sett-KEY.ldb, KEY = FNV-1a of every generator parameter (fibres too) and
 * LOOM_EXGEN_REVISION, so a changed generator never reuses an old file.  The
 * cache is bounded: after a database is added, the least recently used
 * sett-*.ldb files go until the total is under $LOOM_CACHE_MAX_MB (default
 * 256 MB); a cache hit refreshes its file's time.
 */
#include "cli.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <utime.h>

#define SETT_FINE_VOXELS 16.0 /* voxels along the finer spacing */
#define CACHE_MAX_MB_DEFAULT 256.0
#define SETT_FIBRE "cotton"   /* the yarns, as loom exemplar generate's default */
#define SETT_MIN_CROSSINGS 10 /* exemplar sides, as the default database's */

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
	const unsigned char *b = p;
	for (size_t i = 0; i < n; i++)
		h = (h ^ b[i]) * 0x100000001b3ull;
	return h;
}

/* mkdir -p; 0 on success. */
static int make_dirs(const char *path)
{
	char buf[PATH_MAX];
	size_t n = strlen(path);

	if (n >= sizeof buf)
		return -1;
	memcpy(buf, path, n + 1);
	for (size_t i = 1; i <= n; i++)
		if (buf[i] == '/' || buf[i] == '\0') {
			char c = buf[i];
			buf[i] = '\0';
			if (mkdir(buf, 0777) != 0 && errno != EEXIST)
				return -1;
			buf[i] = c;
		}
	return 0;
}

const char *cli_cache_dir(void)
{
	static char buf[PATH_MAX];
	const char *e = getenv("LOOM_CACHE_DIR"), *x = getenv("XDG_CACHE_HOME");
	const char *home = getenv("HOME");

	if (e && *e)
		snprintf(buf, sizeof buf, "%s", e);
	else if (x && *x)
		snprintf(buf, sizeof buf, "%s/loom", x);
	else if (home && *home)
		snprintf(buf, sizeof buf, "%s/.cache/loom", home);
	else
		return NULL;
	return buf;
}

typedef struct cached {
	char name[64];
	off_t size;
	time_t mtime;
} cached;

static int by_age(const void *a, const void *b)
{
	const cached *x = a, *y = b;
	if (x->mtime != y->mtime)
		return x->mtime < y->mtime ? -1 : 1;
	return strcmp(x->name, y->name);
}

/* Remove the oldest sett-*.ldb files of dir, never `keep`, until the total
   is at most max_bytes. */
static void trim_cache(const char *dir, const char *keep, double max_bytes, int quiet)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	cached *list = NULL;
	size_t n = 0, cap = 0;
	double total = 0;

	if (!d)
		return;
	while ((e = readdir(d)) != NULL) {
		char path[PATH_MAX];
		struct stat st;
		size_t l = strlen(e->d_name);
		if (strncmp(e->d_name, "sett-", 5) != 0 || l < 9 || l >= sizeof list->name ||
		    strcmp(e->d_name + l - 4, ".ldb") != 0)
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		if (stat(path, &st) != 0 || !S_ISREG(st.st_mode))
			continue;
		if (n == cap) {
			cached *nl = realloc(list, (cap = cap ? 2 * cap : 16) * sizeof *nl);
			if (!nl)
				break;
			list = nl;
		}
		memcpy(list[n].name, e->d_name, l + 1); /* l < sizeof name */
		list[n].size = st.st_size;
		list[n].mtime = st.st_mtime;
		total += (double)st.st_size;
		n++;
	}
	closedir(d);
	if (n > 1)
		qsort(list, n, sizeof *list, by_age);
	for (size_t i = 0; i < n && total > max_bytes; i++) {
		char path[PATH_MAX];
		if (!strcmp(list[i].name, keep))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, list[i].name);
		if (remove(path) == 0) {
			total -= (double)list[i].size;
			if (!quiet)
				fprintf(stderr, "loom: removed %s from the cache (over %.0f MB)\n",
				        path, max_bytes / 1e6);
		}
	}
	free(list);
}

uint32_t cli_design_pairs(const loom_design *d, const uint8_t def[2],
                          uint8_t pairs[][2], uint32_t max)
{
	enum { NF = LOOM_FIBRE_COUNT_ };
	uint8_t seen[NF * NF];
	uint8_t mat[LOOM_MAX_YARN_TYPES][2];
	size_t n = (size_t)d->rows * d->cols;
	uint32_t np = 0;

	memset(seen, 0, sizeof seen);
	for (uint32_t t = 0; t < d->n_types && t < LOOM_MAX_YARN_TYPES; t++)
		for (int k = 0; k < 2; k++) {
			int m = d->types[t].fibre ? d->types[t].fibre : def[k];
			mat[t][k] = (uint8_t)(m ? m : LOOM_FIBRE_COTTON);
		}
	for (size_t c = 0; c < n; c++) {
		uint8_t w = mat[d->warp_type[c]][0], f = mat[d->weft_type[c]][1];
		if (seen[w * NF + f])
			continue;
		seen[w * NF + f] = 1;
		if (np < max) {
			pairs[np][0] = w;
			pairs[np][1] = f;
		}
		np++;
	}
	return np;
}

const char *cli_sett_db(const char *prog, const loom_design *d,
                        const char *fibre, int quiet)
{
	static char path[PATH_MAX];
	char name[64];
	const char *dir = cli_cache_dir(), *env = getenv("LOOM_CACHE_MAX_MB");
	int has_sett = d->sett[0] > 0 && d->sett[1] > 0;
	double fine = has_sett ? 1e4 / (d->sett[0] > d->sett[1] ? d->sett[0] : d->sett[1]) : 0;
	char fbuf[64], *fcomma, what[160];
	double max_mb = CACHE_MAX_MB_DEFAULT, t0;
	loom_exgen_params p;
	loom_diag diag;
	uint64_t h = 0xcbf29ce484222325ull;
	struct timespec ts;
	struct stat st;
	loom_db *db;
	int rev = LOOM_EXGEN_REVISION;

	if (env && *env) {
		char *end;
		max_mb = strtod(env, &end);
		if (*end || !(max_mb > 0))
			cli_fail(prog, "LOOM_CACHE_MAX_MB=%s: expected a positive number of MB",
			         env);
	}
	if (!dir)
		cli_fail(prog, "no cache directory for the draft's sett database: set "
		         "LOOM_CACHE_DIR, XDG_CACHE_HOME or HOME, or give --db DB");
	cli_diag_init(&diag, &quiet);
	loom_exgen_preset("small", &p);
	p.min_crossings = SETT_MIN_CROSSINGS;
	/* --fibre WARP[,WEFT] (one name: both), checked by the generator */
	snprintf(fbuf, sizeof fbuf, "%s", fibre ? fibre : SETT_FIBRE);
	fcomma = strchr(fbuf, ',');
	if (fcomma)
		*fcomma++ = '\0';
	p.fibre[0] = fbuf;
	p.fibre[1] = fcomma ? fcomma : fbuf;
	{
		/* the design's material pairs: one set of exemplars per pair */
		uint8_t def[2] = {0, 0}, pairs[LOOM_EXGEN_MAX_PAIRS][2];
		int code;
		uint32_t np;
		for (int k = 0; k < 2; k++)
			if (loom_fibre_parse(p.fibre[k], &code) == LOOM_OK)
				def[k] = (uint8_t)code;
		np = cli_design_pairs(d, def, pairs, LOOM_EXGEN_MAX_PAIRS);
		if (np > LOOM_EXGEN_MAX_PAIRS) {
			char list[512];
			uint8_t all[64][2];
			size_t w = 0;
			uint32_t m = cli_design_pairs(d, def, all, 64);
			list[0] = '\0';
			for (uint32_t i = 0; i < m && i < 64 && w < sizeof list; i++)
				w += (size_t)snprintf(list + w, sizeof list - w, "%s%s/%s",
				                      i ? ", " : "", loom_fibre_name(all[i][0]),
				                      loom_fibre_name(all[i][1]));
			cli_fail(prog, "the design uses %u (warp, weft) material pairs (%s); "
			         "a generated database holds at most %d (LOOM_EXGEN_MAX_PAIRS): "
			         "give fewer yarn types their own fibre", np, list,
			         LOOM_EXGEN_MAX_PAIRS);
		}
		if (np == 1) {
			p.fibre[0] = loom_fibre_name(pairs[0][0]);
			p.fibre[1] = loom_fibre_name(pairs[0][1]);
		} else {
			p.n_pairs = np;
			for (uint32_t i = 0; i < np; i++) {
				p.pairs[i][0] = loom_fibre_name(pairs[i][0]);
				p.pairs[i][1] = loom_fibre_name(pairs[i][1]);
			}
		}
	}
	if (!has_sett) {
		/* no sett stated (--fibre only): the small preset's geometry */
		if (loom_exgen_check_params(&p, &diag) != LOOM_OK)
			cli_fail(prog, "--fibre %s: %s", fibre ? fibre : SETT_FIBRE,
			         diag.message);
	} else {
		p.voxel_size_um = (float)(fine / SETT_FINE_VOXELS);
		p.yarn_diameter_um[0] = d->yarn_um[0] > 0 ? d->yarn_um[0] : d->yarn_um[1];
		p.yarn_diameter_um[1] = d->yarn_um[1] > 0 ? d->yarn_um[1] : d->yarn_um[0];
		if (loom_exgen_set_sett(&p, d->sett[0], d->sett[1], &diag) != LOOM_OK)
			cli_fail(prog, "the draft's sett: %s", diag.message);
	}
	/* a yarn the generator refuses (over 4 times its spacing): proportional */
	if (has_sett && loom_exgen_check_params(&p, &diag) != LOOM_OK) {
		if (strstr(diag.message, "fibre"))
			cli_fail(prog, "--fibre %s: %s", fibre, diag.message);
		if (!quiet)
			fprintf(stderr, "loom: warning: the draft's yarn diameters (%g, %g um) "
			        "do not fit its sett (%s); using yarns in proportion to the "
			        "spacing\n", (double)p.yarn_diameter_um[0],
			        (double)p.yarn_diameter_um[1], diag.message);
		p.yarn_diameter_um[0] = p.yarn_diameter_um[1] = 0;
		if (loom_exgen_set_sett(&p, d->sett[0], d->sett[1], &diag) != LOOM_OK)
			cli_fail(prog, "the draft's sett: %s", diag.message);
	}
	h = fnv(h, &rev, sizeof rev);
	h = fnv(h, p.block, sizeof p.block);
	h = fnv(h, &p.voxel_size_um, sizeof p.voxel_size_um);
	h = fnv(h, p.yarn_diameter_um, sizeof p.yarn_diameter_um);
	h = fnv(h, &p.seed, sizeof p.seed);
	h = fnv(h, p.brick, sizeof p.brick);
	h = fnv(h, &p.level, sizeof p.level);
	h = fnv(h, &p.min_crossings, sizeof p.min_crossings);
	for (uint32_t k = 0; k < p.n_weaves; k++)
		h = fnv(h, p.weaves[k], strlen(p.weaves[k]) + 1);
	if (p.n_pairs < 2)
		for (int k = 0; k < 2; k++)
			h = fnv(h, p.fibre[k], strlen(p.fibre[k]) + 1);
	else
		for (uint32_t i = 0; i < p.n_pairs; i++) /* in the design's order */
			for (int k = 0; k < 2; k++)
				h = fnv(h, p.pairs[i][k], strlen(p.pairs[i][k]) + 1);
	if (p.n_pairs < 2)
		snprintf(what, sizeof what, "%s/%s", p.fibre[0], p.fibre[1]);
	else
		for (size_t w = 0, i = 0; i < p.n_pairs && w < sizeof what; i++)
			w += (size_t)snprintf(what + w, sizeof what - w, "%s%s/%s",
			                      i ? ", " : "", p.pairs[i][0], p.pairs[i][1]);
	snprintf(name, sizeof name, "sett-%016llx.ldb", (unsigned long long)h);
	if ((size_t)snprintf(path, sizeof path, "%s/%s", dir, name) >= sizeof path)
		cli_fail(prog, "cache directory path too long: %s", dir);
	if (stat(path, &st) == 0 && loom_db_open(path, &db, NULL) == LOOM_OK) {
		loom_db_close(db);
		utime(path, NULL); /* recently used */
		if (!quiet && has_sett)
			fprintf(stderr, "loom: the draft's sett %.4g x %.4g per cm: database %s "
			        "(cached)\n", (double)d->sett[0], (double)d->sett[1], path);
		else if (!quiet)
			fprintf(stderr, "loom: yarns %s: database %s (cached)\n", what, path);
		return path;
	}
	if (make_dirs(dir) != 0)
		cli_fail(prog, "cannot create the cache directory %s: %s", dir,
		         strerror(errno));
	clock_gettime(CLOCK_MONOTONIC, &ts);
	t0 = (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
	if (loom_exgen_write_db(path, &p, NULL, &diag) != LOOM_OK)
		cli_fail(prog, "generating the database for the draft's sett: %s",
		         diag.message);
	clock_gettime(CLOCK_MONOTONIC, &ts);
	if (!quiet && has_sett)
		fprintf(stderr, "loom: the draft's sett %.4g x %.4g per cm: generated %s "
		        "(block %ux%ux%u of %.3g um, %.1f s)\n", (double)d->sett[0],
		        (double)d->sett[1], path, p.block[0], p.block[1], p.block[2],
		        (double)p.voxel_size_um,
		        (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec - t0);
	else if (!quiet)
		fprintf(stderr, "loom: yarns %s: generated %s (block %ux%ux%u of %.3g "
		        "um, %.1f s)\n", what, path, p.block[0], p.block[1], p.block[2],
		        (double)p.voxel_size_um,
		        (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec - t0);
	trim_cache(dir, name, max_mb * 1e6, quiet);
	return path;
}

void cli_sett_check(const loom_design *d, const loom_db *db, const char *db_path,
                    int quiet)
{
	loom_db_info info;
	double want, have;

	if (quiet || !(d->sett[0] > 0) || !(d->sett[1] > 0) ||
	    loom_db_get_info(db, &info) != LOOM_OK || !info.block[1])
		return;
	want = (double)d->sett[1] / (double)d->sett[0]; /* b1 / b2 of the sett */
	have = (double)info.block[0] / (double)info.block[1];
	if (have > 1.1 * want || want > 1.1 * have)
		fprintf(stderr, "loom: warning: %s has crossings of %ux%u voxels (aspect "
		        "%.3g) but the draft's sett %.4g x %.4g ends x picks per cm needs "
		        "aspect %.3g; the cloth will be %s (omit --db to use a database "
		        "for the draft's sett)\n", db_path, info.block[0], info.block[1],
		        have, (double)d->sett[0], (double)d->sett[1], want,
		        have > want ? "wider than it should" : "narrower than it should");
}

/* The longest warp float (run of 1s down a column) and weft float (run of
   0s along a row) of the exemplars' weaves, as runs of neighbouring
   blocks: within the exemplar, not across its border, since synthesis
   never continues a copy across an exemplar's border. */
static void db_floats(const loom_db *db, uint32_t fl[2])
{
	loom_db_info info;

	fl[0] = fl[1] = 0;
	loom_db_get_info(db, &info);
	for (uint32_t u = 0; u < info.n_exemplars; u++) {
		loom_db_exemplar_info e;
		if (loom_db_exemplar(db, u, &e) != LOOM_OK || !e.weave)
			continue;
		for (uint32_t i = 0; i < e.rows; i++)
			for (uint32_t j = 0, n = 0; j < e.cols; j++) {
				n = e.weave[(size_t)i * e.cols + j] ? 0 : n + 1;
				fl[1] = n > fl[1] ? n : fl[1];
			}
		for (uint32_t j = 0; j < e.cols; j++)
			for (uint32_t i = 0, n = 0; i < e.rows; i++) {
				n = e.weave[(size_t)i * e.cols + j] ? n + 1 : 0;
				fl[0] = n > fl[0] ? n : fl[0];
			}
	}
}

int cli_float_check(const char *prog, const loom_design *d, const loom_db *db, int quiet,
                    uint32_t dfl[2], uint32_t xfl[2])
{
	loom_design_stats st;
	char what[128];
	int n = 0;

	if (loom_design_analyze(d, &st) != LOOM_OK)
		return 0;
	dfl[0] = st.max_warp_float;
	dfl[1] = st.max_weft_float;
	db_floats(db, xfl);
	for (int k = 0; k < 2; k++)
		if (dfl[k] > xfl[k])
			n += snprintf(what + n, sizeof what - (size_t)n,
			              "%s%s float is %u crossings, the database's %u",
			              n ? "; its longest " : "", k ? "weft" : "warp", dfl[k], xfl[k]);
	if (n && !quiet)
		fprintf(stderr, "%s: warning: the design's longest %s: blocks along longer "
		        "floats are copied from shorter ones, so their heights differ from the "
		        "woven cloth's (docs/fidelity.md, \"Float runs\")\n", prog, what);
	return 1;
}
