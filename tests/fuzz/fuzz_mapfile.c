/*
 * tests/fuzz/fuzz_mapfile.c - fuzz target of the mapping-file parser and
 * the posterized-image-to-design builder (paper 5.2).
 *
 *   make fuzz && build/fuzz/fuzz_mapfile -max_total_time=60 tests/fuzz/corpus/mapfile
 *
 * The input is the mapping file's text; it is applied to three small
 * images built here (grey levels, RGB colours, an indexed image with a
 * palette).  On success the design must validate and have the image's size;
 * on failure there is no design and the message names the mapping file.
 * Replayed over tests/fuzz/corpus/mapfile by `make test`.
 */
#include "loom.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static loom_image *grey_image(void)
{
	loom_image *img = NULL;
	if (loom_image_new(7, 5, 1, &img))
		abort();
	for (uint32_t k = 0; k < 35; k++)
		img->pixels[k] = (uint8_t)(k % 3 == 0 ? 0 : k % 3 == 1 ? 128 : 255);
	return img;
}

static loom_image *rgb_image(int with_palette)
{
	static const uint8_t pal[4][3] = {
		{0xc0, 0, 0}, {0, 0xc0, 0}, {0xff, 0xff, 0xff}, {0x12, 0x34, 0x56}};
	loom_image *img = NULL;

	if (loom_image_new(8, 6, 3, &img))
		abort();
	for (uint32_t k = 0; k < 48; k++)
		memcpy(img->pixels + 3 * k, pal[(k * 7 + k / 8) % 3], 3);
	if (with_palette) {
		img->palette = malloc(sizeof pal);
		if (!img->palette)
			abort();
		memcpy(img->palette, pal, sizeof pal);
		img->n_palette = 4;
	}
	return img;
}

static void run(const loom_image *img, const uint8_t *data, size_t size)
{
	loom_design *d = NULL;
	loom_diag diag;
	int rc;

	memset(&diag, 0, sizeof diag);
	rc = loom_design_from_image(img, (const char *)data, size, "fuzz.map", &d,
	                            &diag);
	if (rc == LOOM_OK) {
		if (!d || d->rows != img->height || d->cols != img->width ||
		    loom_design_validate(d, NULL) != LOOM_OK)
			abort();
		loom_design_free(d);
	} else if (d || rc < 0 || rc >= LOOM_RESULT_COUNT_ ||
	           memchr(diag.message, 0, sizeof diag.message) == NULL ||
	           strncmp(diag.message, "fuzz.map", 8) != 0) {
		abort();
	}
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	loom_image *img[3] = {grey_image(), rgb_image(0), rgb_image(1)};

	for (int k = 0; k < 3; k++) {
		run(img[k], data, size);
		loom_image_free(img[k]);
	}
	return 0;
}
