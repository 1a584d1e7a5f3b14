/*
 * tests/fuzz/fuzz_db.c - the exemplar database reader on arbitrary bytes.
 *
 * The bytes go to an anonymous memory file (memfd), opened by path through
 * /proc/self/fd, so the reader runs exactly as on disk.  When the open
 * succeeds every query is exercised: info, exemplars, block tables, brick
 * ids, reads of every brick (bounded), verify.  Nothing may crash, leak or
 * read out of bounds; errors must carry a message.
 *
 *   make fuzz && build/fuzz/fuzz_db tests/fuzz/corpus/db
 */
#include "exemplar/db_internal.h"

#include <libdeflate.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void exercise(loom_db *db)
{
	loom_db_info info;
	loom__db_geom geo;
	loom_diag d = {0};
	struct libdeflate_decompressor *dec;
	uint8_t *brick, *scratch;

	loom_db_get_info(db, &info);
	loom__db_geometry(db, &geo);
	for (uint32_t k = 0; k < info.n_exemplars; k++) {
		loom_db_exemplar_info e;
		uint32_t id, k2, bx, by, bz;
		if (loom_db_exemplar(db, k, &e) != LOOM_OK)
			abort();
		for (uint32_t r = 0; r < e.rows && r < 64; r++)
			for (uint32_t c = 0; c < e.cols && c < 64; c++) {
				loom_db_block_info b;
				volatile float s = 0;
				if (loom_db_block(db, k, r, c, &b) != LOOM_OK)
					abort();
				for (uint32_t i = 0; i < info.block[0]; i++)
					s += b.north[i] + b.south[i];
				for (uint32_t i = 0; i < info.block[1]; i++)
					s += b.west[i] + b.east[i];
			}
		for (uint32_t l = 0; l <= e.n_yarns; l++)
			(void)e.yarns[l].kind;
		for (uint32_t i = 0; i < 2 * e.n_symmetries; i++)
			(void)e.symmetries[i];
		if (loom__db_brick_id(db, k, e.bricks[0] - 1, e.bricks[1] - 1,
		                      e.bricks[2] - 1, &id) != LOOM_OK)
			abort();
		if (loom__db_brick_coords(db, id, &k2, &bx, &by, &bz) != LOOM_OK || k2 != k)
			abort();
	}
	if (geo.brick_bytes > (1u << 20) || geo.n_bricks > 4096)
		return; /* keep each input fast */
	dec = libdeflate_alloc_decompressor();
	brick = malloc(geo.brick_bytes);
	scratch = malloc(loom__db_scratch_bytes(db));
	for (uint32_t id = 0; id < geo.n_bricks; id++) {
		int rc = loom__db_read_brick(db, id, dec, scratch, brick, NULL, &d);
		if (rc != LOOM_OK && d.message[0] == 0)
			abort();
	}
	if (loom__db_dsegs(db)) { /* each unit alone, each density segment alone */
		loom__db_reader *r = loom__db_reader_new(db);
		for (uint32_t id = 0; r && id < geo.n_bricks; id++) {
			for (unsigned u = 0; u < LOOM__DB_UNITS; u++)
				if (loom__db_reader_read_unit(r, id, u, brick, NULL, &d) != LOOM_OK &&
				    d.message[0] == 0)
					abort();
			for (unsigned q = 0; q < loom__db_dsegs(db); q++)
				if (loom__db_reader_read_seg(r, id, q, brick, 0, NULL, &d) != LOOM_OK &&
				    d.message[0] == 0)
					abort();
		}
		loom__db_reader_free(r);
	}
	free(brick);
	free(scratch);
	libdeflate_free_decompressor(dec);
	if (loom_db_verify(db, NULL, NULL, &d) != LOOM_OK && d.message[0] == 0)
		abort();
	if (info.n_exemplars) {
		loom_db_exemplar_info e;
		uint32_t org[3] = {0, 0, 0}, sz[3] = {1, 1, 1};
		uint8_t v;
		loom_db_exemplar(db, 0, &e);
		loom_db_read_box(db, 0, org, sz, &v, NULL, NULL, &d);
	}
}

/* Make the checksums and the content hash of an image consistent, so that
   mutations reach the field checks behind them. */
static void reseal(uint8_t *b, size_t n)
{
	uint8_t *t;
	uint64_t mo, ml, h;

	if (n < LOOM__DB_HEADER_BYTES + LOOM__DB_TRAILER_BYTES)
		return;
	t = b + n - LOOM__DB_TRAILER_BYTES;
	mo = loom__le64(t + 8);
	ml = loom__le64(t + 16);
	loom__put32(b + 124, libdeflate_crc32(0, b, 124));
	if (mo > n || ml > n - mo)
		return;
	loom__put32(t + 24, libdeflate_crc32(0, b + mo, (size_t)ml));
	h = loom__fnv1a64(loom__fnv1a64(LOOM__FNV_OFFSET, b, 128), b + mo, (size_t)ml);
	loom__put64(t + 40, h);
	loom__put32(t + 60, libdeflate_crc32(0, t, 60));
}

static void run_one(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	uint8_t *copy;

	run_one(data, size);
	/* the same bytes with consistent checksums */
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

static void run_one(const uint8_t *data, size_t size)
{
	char path[64];
	loom_db *db = NULL;
	loom_diag d = {0};
	int fd = memfd_create("fuzz_db", 0), rc;
	size_t done = 0;

	if (fd < 0)
		return;
	while (done < size) {
		ssize_t w = write(fd, data + done, size - done);
		if (w <= 0) {
			close(fd);
			return;
		}
		done += (size_t)w;
	}
	snprintf(path, sizeof path, "/proc/self/fd/%d", fd);
	rc = loom_db_open(path, &db, &d);
	if (rc == LOOM_OK) {
		exercise(db);
		loom_db_close(db);
	} else if (d.message[0] == 0 || db != NULL) {
		abort();
	}
	close(fd);
}
