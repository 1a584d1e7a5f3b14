/*
 * tests/fuzz/fuzz_wif.c - fuzz target of the WIF reader.
 *
 *   make fuzz && build/fuzz/fuzz_wif -max_total_time=120 tests/fuzz/corpus/wif
 *
 * Feeds arbitrary bytes to the reader (through loom__wif_parse_limited, so
 * that a few bytes cannot ask for gigabytes) and checks what it returns:
 * on success a design that validates, with the sizes the reader promises;
 * on failure no design and a message naming the input.  Replayed over
 * tests/fuzz/corpus/wif by `make test`.
 */
#include "loom.h"
#include "io/design/wif_internal.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	loom_design *d = NULL;
	loom_diag diag;
	int rc;

	memset(&diag, 0, sizeof diag);
	rc = loom__wif_parse_limited((const char *)data, size, "fuzz.wif",
	                             (uint64_t)1 << 22, &d, &diag);
	if (rc == LOOM_OK) {
		if (!d || loom_design_validate(d, NULL) != LOOM_OK ||
		    (uint64_t)d->rows * d->cols > ((uint64_t)1 << 22) ||
		    d->n_types < 2)
			abort();
		for (size_t k = 0; k < (size_t)d->rows * d->cols; k++)
			if (d->weave[k] > 1)
				abort();
		loom_design_free(d);
	} else {
		if (d || rc < 0 || rc >= LOOM_RESULT_COUNT_ ||
		    strncmp(diag.message, "fuzz.wif:", 9) != 0 ||
		    memchr(diag.message, 0, sizeof diag.message) == NULL)
			abort();
	}
	return 0;
}
