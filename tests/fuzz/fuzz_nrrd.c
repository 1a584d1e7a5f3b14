/*
 * tests/fuzz/fuzz_nrrd.c - fuzz target for the NRRD reader.
 *
 * Parses the input as an attached NRRD from memory (64 MiB cap on the
 * float output) and checks that a successful parse returns the layout the
 * header promised.
 */
#include "loom.h"

#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	loom_nrrd_info info;
	loom_volbuf *v = NULL;
	loom_diag d = {0};
	int rc = loom_nrrd_parse(data, size, "fuzz", (size_t)64 << 20, &info, &v, &d);

	if (rc != LOOM_OK) {
		if (v)
			abort();
		return 0;
	}
	if (v->nx != info.nx || v->ny != info.ny || v->nz != info.nz ||
	    v->channels != info.channels || info.header_bytes > size)
		abort();
	loom_volbuf_free(v);
	return 0;
}
