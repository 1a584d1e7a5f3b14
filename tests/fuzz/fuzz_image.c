/*
 * tests/fuzz/fuzz_image.c - fuzz target of the image readers (PBM, PGM,
 * PPM, PNG), the two-level weave conversion and the raw (type-map) mode.
 *
 *   make fuzz && build/fuzz/fuzz_image -max_total_time=60 tests/fuzz/corpus/image
 *
 * Checks what the readers promise: on success an image of sane size and
 * channel count (and a palette only with its entries); on failure no image
 * and a NUL-terminated message that names the input.  Replayed over
 * tests/fuzz/corpus/image by `make test`.
 */
#include "loom.h"
#include "io/design/image_internal.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_failure(int rc, const loom_image *img, const loom_diag *d)
{
	if (img || rc <= 0 || rc >= LOOM_RESULT_COUNT_ ||
	    memchr(d->message, 0, sizeof d->message) == NULL ||
	    strncmp(d->message, "fuzz", 4) != 0)
		abort();
}

static void check_image(const loom_image *img, unsigned flags)
{
	size_t n;

	if (!img || img->width == 0 || img->height == 0 || !img->pixels ||
	    (img->channels != 1 && img->channels != 3) ||
	    (uint64_t)img->width * img->height > LOOM__IMAGE_MAX_PIXELS ||
	    (img->n_palette && (!img->palette || img->n_palette > 256)) ||
	    ((flags & LOOM__IMG_RAW) && img->palette))
		abort();
	n = (size_t)img->width * img->height * img->channels;
	if (img->bilevel && img->channels == 1 && !(flags & LOOM__IMG_RAW))
		for (size_t k = 0; k < n; k++)
			if (img->pixels[k] != 0 && img->pixels[k] != 255)
				abort();
}

static void as_weave(const loom_image *img)
{
	size_t n = (size_t)img->width * img->height;
	uint8_t *w = malloc(n);
	loom_diag d;

	memset(&d, 0, sizeof d);
	if (!w)
		return;
	if (loom__weave_from_image(img, "fuzz", w, &d) == LOOM_OK) {
		for (size_t k = 0; k < n; k++)
			if (w[k] > 1)
				abort();
	} else if (strncmp(d.message, "fuzz", 4) != 0) {
		abort();
	}
	free(w);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static const unsigned modes[2] = {0, LOOM__IMG_RAW};

	for (int m = 0; m < 2; m++) {
		loom_image *img = NULL;
		loom_diag d;
		int rc;

		memset(&d, 0, sizeof d);
		rc = loom__image_parse_ex(data, size, "fuzz", modes[m], &img, &d);
		if (rc != LOOM_OK) {
			check_failure(rc, img, &d);
			continue;
		}
		check_image(img, modes[m]);
		if (m == 0)
			as_weave(img);
		loom_image_free(img);
	}
	return 0;
}
