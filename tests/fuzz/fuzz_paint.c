/*
 * tests/fuzz/fuzz_paint.c - fuzz target of the paint-file reader
 * (engine/texture/paint.c, loom_paint_parse).
 *
 *   make fuzz && build/fuzz/fuzz_paint -max_total_time=60 tests/fuzz/corpus/paint
 *
 * On success the regions must pass loom_paint_add's checks again and
 * format -> parse -> format must give the same text; on failure there is
 * no paint, the code is a loom_result and the message names the input
 * ("fuzz.loomp..." ).  Replayed over tests/fuzz/corpus/paint by `make test`.
 */
#include "loom.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	loom_paint *p = NULL, *q = NULL, *c = NULL;
	loom_diag diag;
	char *a = NULL, *b = NULL;
	size_t na = 0, nb = 0;
	int rc;

	memset(&diag, 0, sizeof diag);
	rc = loom_paint_parse((const char *)data, size, "fuzz.loomp", &p, &diag);
	if (rc != LOOM_OK) {
		if (p || rc < 0 || rc >= LOOM_RESULT_COUNT_ ||
		    memchr(diag.message, 0, sizeof diag.message) == NULL ||
		    strncmp(diag.message, "fuzz.loomp", 10) != 0)
			abort();
		return 0;
	}
	if (!p || !loom_paint_fabric(p))
		abort();
	if (loom_paint_new(loom_paint_fabric(p), &c, NULL) != LOOM_OK)
		abort();
	for (uint32_t i = 0; i < loom_paint_count(p); i++)
		if (loom_paint_add(c, loom_paint_get(p, i), NULL) != LOOM_OK)
			abort();
	if (loom_paint_format(p, &a, &na) != LOOM_OK ||
	    loom_paint_parse(a, na, "again", &q, NULL) != LOOM_OK ||
	    loom_paint_format(q, &b, &nb) != LOOM_OK || na != nb || memcmp(a, b, na))
		abort();
	free(a);
	free(b);
	loom_paint_free(p);
	loom_paint_free(q);
	loom_paint_free(c);
	return 0;
}
