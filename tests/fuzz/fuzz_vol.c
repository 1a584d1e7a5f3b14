/*
 * tests/fuzz/fuzz_vol.c - fuzz target for the Mitsuba .vol reader.
 *
 * Parses the input as a whole .vol file from memory (with a 64 MiB cap on
 * the decoded floats) and checks what a successful parse promises: the
 * sizes match the header and every value of a uint8 or direction volume
 * is in range.
 */
#include "loom.h"

#include <math.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	loom_vol_header h, h2;
	loom_volbuf *v = NULL;
	loom_diag d = {0};
	uint64_t bytes;
	int rc = loom_vol_parse(data, size, "fuzz", (size_t)64 << 20, &h, &v, &d);

	if (loom_vol_header_parse(data, size, "fuzz", &h2, &d) == LOOM_OK &&
	    loom_vol_data_bytes(&h2, &bytes) == LOOM_OK && rc == LOOM_OK &&
	    bytes > size - LOOM_VOL_HEADER_BYTES)
		abort(); /* parsed although the data do not fit */
	if (rc != LOOM_OK) {
		if (v)
			abort();
		return 0;
	}
	if (v->nx != h.xres || v->ny != h.yres || v->nz != h.zres ||
	    v->channels != h.channels)
		abort();
	if (h.encoding == LOOM_VOL_UINT8 || h.encoding == LOOM_VOL_QDIR) {
		size_t n = (size_t)v->nx * v->ny * v->nz * v->channels;
		for (size_t i = 0; i < n; i++)
			if (!(v->data[i] >= -1.0f && v->data[i] <= 1.0f))
				abort();
	}
	loom_volbuf_free(v);
	return 0;
}
