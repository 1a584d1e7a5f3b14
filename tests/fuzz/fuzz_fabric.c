/*
 * tests/fuzz/fuzz_fabric.c - the fabric file reader on arbitrary bytes.
 *
 * Each input is parsed from memory into a detached fabric; when that
 * succeeds it is bound (without the hash check, so that mutated files
 * reach the binding checks) to a tiny generated database made once per
 * process (the "tiny" preset, seed 1: the one the seed corpus was made
 * with), and then every query runs: sources and offsets anywhere on the
 * bolt, seam blocks, save and re-read.  Nothing may crash, leak or read
 * out of bounds; every error must carry a message and leave no fabric.
 * Each input is also tried with its checksums made consistent (reseal),
 * so mutations get past the CRCs to the field checks behind them.
 *
 *   make fuzz && build/fuzz/fuzz_fabric tests/fuzz/corpus/fabric
 */
#include "synth/fabric_internal.h"
#include "io/store/fabric_format.h"

#include <libdeflate.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char dir[256];
static loom_db *db;
static int setup_done;

static void cleanup(void)
{
	char p[300];
	loom_db_close(db);
	snprintf(p, sizeof p, "%s/tiny.ldb", dir);
	unlink(p);
	snprintf(p, sizeof p, "%s/out.loomf", dir);
	unlink(p);
	rmdir(dir);
}

static void setup(void)
{
	loom_exgen_params p;
	char path[300];

	setup_done = 1;
	snprintf(dir, sizeof dir, "%s/fuzz_fabric.XXXXXX",
	         getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
	if (!mkdtemp(dir))
		return;
	snprintf(path, sizeof path, "%s/tiny.ldb", dir);
	if (loom_exgen_preset("tiny", &p) != LOOM_OK ||
	    loom_exgen_write_db(path, &p, NULL, NULL) != LOOM_OK ||
	    loom_db_open(path, &db, NULL) != LOOM_OK)
		db = NULL;
	atexit(cleanup);
}

/* get32 / put32: io/store/fabric_format.h */

/* Make header, section and trailer checksums and the trailer's file size
   consistent with the bytes (docs/formats.md). */
static void reseal(uint8_t *b, size_t n)
{
	size_t pos = 64;
	if (n < 96)
		return;
	put32(b + 60, libdeflate_crc32(0, b, 60));
	for (int k = 0; k < 8 && pos + 32 <= n - 32; k++) {
		uint64_t stored = (uint64_t)get32(b + pos + 16) | (uint64_t)get32(b + pos + 20) << 32;
		if (stored > n - 32 - pos - 32)
			break;
		put32(b + pos + 24, libdeflate_crc32(0, b + pos + 32, (size_t)stored));
		put32(b + pos + 28, libdeflate_crc32(0, b + pos, 28));
		pos += 32 + (size_t)stored;
	}
	for (int k = 0; k < 8; k++)
		b[n - 24 + k] = (uint8_t)((uint64_t)n >> (8 * k));
	put32(b + n - 4, libdeflate_crc32(0, b + n - 32, 28));
}

static void exercise(loom_fabric *f)
{
	const loom_design *d = loom_fabric_design(f);
	loom_fabric_params p;
	loom_fabric_db_identity id;
	loom_fabric_metrics m;
	uint64_t rep[3], bolt[3];
	double total;
	volatile uint64_t sink = 0;

	loom_fabric_get_params(f, &p);
	loom_fabric_get_db_identity(f, &id);
	loom_fabric_get_metrics(f, &m);
	loom_fabric_repeat_voxels(f, rep);
	loom_fabric_bolt_voxels(f, 3.5, 2, bolt, &total);
	for (uint32_t u = 0; u < m.n_exemplars; u++)
		sink += m.usage[u];
	sink += strlen(id.path) + d->n_types + d->weave[(size_t)d->rows * d->cols - 1];
	if (!db || (uint64_t)d->rows * d->cols > 65536)
		return;
	if (loom__fabric_bind(f, db, 0, "fuzz", NULL) == LOOM_OK) {
		float *dz = malloc(sizeof(float) * (size_t)f->b1 * f->b2);
		char path[300];
		loom_fabric *g = NULL;
		for (int64_t I = -5; I < 12; I += 4)
			for (int64_t J = -7; J < 12; J += 3) {
				loom_fabric_source s;
				double seam[4];
				if (loom_fabric_source_at(f, I, J, &s) != LOOM_OK)
					abort();
				sink += s.block + s.exemplar;
				if (dz)
					loom_fabric_dz(f, I, J, dz);
				loom_fabric_seam_block(f, I, J, seam);
			}
		free(dz);
		/* what was read can be written and read back identically */
		snprintf(path, sizeof path, "%s/out.loomf", dir);
		if (loom_fabric_save(f, path, NULL, NULL) == LOOM_OK) {
			if (loom__fabric_read(path, NULL, 0, &g, NULL) != LOOM_OK)
				abort();
			if (memcmp(g->base, f->base, 2 * (size_t)d->rows * d->cols) != 0 ||
			    memcmp(g->design->weave, d->weave, (size_t)d->rows * d->cols) != 0)
				abort();
			loom_fabric_free(g);
		}
	}
	(void)sink;
}

static void run_one(const uint8_t *data, size_t size)
{
	loom_fabric *f = (loom_fabric *)1;
	loom_diag d = {0};
	int rc = loom__fabric_read("fuzz", data ? data : (const uint8_t *)"", size, &f, &d);

	if (rc == LOOM_OK) {
		exercise(f);
		loom_fabric_free(f);
	} else if (d.message[0] == 0 || f != NULL) {
		abort();
	}
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	uint8_t *copy;

	if (!setup_done)
		setup();
	run_one(data, size);
	copy = malloc(size ? size : 1);
	if (!copy)
		return 0;
	memcpy(copy, data, size);
	reseal(copy, size);
	if (memcmp(copy, data, size) != 0)
		run_one(copy, size);
	free(copy);
	return 0;
}
