/*
 * tests/unit/test_exr.c - OpenEXR z-slice writer and reader.
 *
 * Round trips of many small images whose heights leave short edge chunks,
 * with incompressible (random-bit) data so that chunks are stored raw,
 * and a sweep that hits the OpenEXR 3.1 "zlib output exactly the raw size"
 * case the writer must work around.  exrheader (OpenEXR's own tool) must
 * accept the files and list our channels and ZIP compression.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"

#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

static uint64_t rng_state;
static int openexr_zip; /* which compressor the writer uses */
static uint64_t rnd(void)
{
	uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

/* A random non-NaN float bit pattern (incompressible). */
static float rnd_bits(void)
{
	uint32_t b = (uint32_t)rnd();
	float f;
	if ((b & 0x7f800000u) == 0x7f800000u)
		b &= 0xbfffffffu;
	memcpy(&f, &b, 4);
	return f;
}

/* Write an image from interleaved pixels, rows in chunks of `step`. */
static int write_image(const char *path, uint32_t w, uint32_t h,
                       const loom_exr_channel *ch, uint32_t n,
                       const float *px, uint32_t step, loom_exr_stats *st,
                       loom_diag *d)
{
	loom_exr_options o = LOOM_EXR_OPTIONS_INIT;
	loom_exr_writer *wr = NULL;
	int rc;
	o.stats = st;
	o.openexr_zip = openexr_zip;
	rc = loom_exr_writer_open(path, w, h, ch, n, &o, &wr, d);
	if (rc)
		return rc;
	for (uint32_t y = 0; y < h; y += step) {
		uint32_t k = h - y < step ? h - y : step;
		rc = loom_exr_writer_put_rows(wr, px + (size_t)y * w * n, k, d);
		if (rc) {
			loom_exr_writer_abort(wr);
			return rc;
		}
	}
	return loom_exr_writer_finish(wr, d);
}

/* Compare a read-back image with what was written: float channels bit for
   bit, half channels as the rounded half. */
static int same_image(const loom_exr_image *img, uint32_t w, uint32_t h,
                      const loom_exr_channel *ch, uint32_t n, const float *px)
{
	if (!img || img->width != w || img->height != h || img->n_channels != n)
		return 0;
	for (uint32_t c = 0; c < n; c++) {
		int k = loom_exr_image_channel(img, ch[c].name);
		if (k < 0 || img->pixel[k] != ch[c].pixel)
			return 0;
		for (uint32_t y = 0; y < h; y++)
			for (uint32_t x = 0; x < w; x++) {
				float in = px[((size_t)y * w + x) * n + c];
				float want = ch[c].pixel == LOOM_EXR_HALF
				                 ? loom_half_to_float(loom_half_from_float(in))
				                 : in;
				float got = img->data[((size_t)k * h + y) * w + x];
				if (memcmp(&got, &want, 4) != 0 && !(isnan(got) && isnan(want))) {
					printf("  %s (%u,%u): got %a want %a\n", ch[c].name, x, y,
					       got, want);
					return 0;
				}
			}
	}
	return 1;
}

static void round_trips(void)
{
	static const loom_exr_channel chans[] = {
		{"density", LOOM_EXR_FLOAT},      {"orientation.x", LOOM_EXR_HALF},
		{"orientation.y", LOOM_EXR_HALF}, {"orientation.z", LOOM_EXR_HALF},
		{"R", LOOM_EXR_FLOAT},            {"G", LOOM_EXR_FLOAT},
		{"B", LOOM_EXR_FLOAT},
	};
	int images = 0, bad = 0;
	uint64_t raw = 0, chunks = 0;

	rng_state = check_seed();
	for (uint32_t h = 1; h <= 40; h += 3)
		for (uint32_t w = 1; w <= 29; w += 7)
			for (uint32_t n = 1; n <= 7; n += 3) {
				size_t nv = (size_t)w * h * n;
				float *px = malloc(nv * sizeof *px);
				int smooth = (h + w) % 2;
				loom_exr_stats st;
				loom_exr_image *img = NULL;
				loom_diag d = {0};
				/* random channel subset order: rotate the table */
				loom_exr_channel ch[7];
				for (uint32_t c = 0; c < n; c++)
					ch[c] = chans[(c + h) % 7];
				for (size_t i = 0; i < nv; i++)
					px[i] = smooth ? (float)(i % 97) * 0.01f : rnd_bits();
				if (write_image(tpath("rt.exr"), w, h, ch, n, px,
				                1 + (uint32_t)(rnd() % 20), &st, &d) != LOOM_OK) {
					printf("  write %ux%u: %s\n", w, h, d.message);
					bad++;
				} else if (loom_exr_read(tpath("rt.exr"), &img, &d) != LOOM_OK) {
					printf("  read %ux%u: %s\n", w, h, d.message);
					bad++;
				} else {
					if (!same_image(img, w, h, ch, n, px)) {
						printf("  image %ux%u n=%u differs\n", w, h, n);
						bad++;
					}
					if (img->compression != 3 || st.chunks != (h + 15) / 16)
						bad++;
				}
				raw += st.chunks_raw;
				chunks += st.chunks;
				loom_exr_image_free(img);
				free(px);
				images++;
			}
	CHECK_EQ_INT(bad, 0);
	printf("  %d images, %llu chunks, %llu stored raw\n", images,
	       (unsigned long long)chunks, (unsigned long long)raw);
	CHECK(raw > 0); /* random data exercised the raw path */
	CHECK_EQ_INT(temp_files_left(), 0);
}

/* Sweep images of one row with a growing zero prefix before random bits:
   zlib's output shrinks through the raw size, and for some prefixes lands
   exactly on it (the OpenEXR 3.1 corruption case).  All must read back. */
static void zip_equal_size_case(void)
{
	static const loom_exr_channel ch[] = {{"v", LOOM_EXR_FLOAT}};
	uint64_t equal = 0;
	int bad = 0, files = 0;

	for (int seed = 0; seed < 4; seed++)
		for (uint32_t wd = 48; wd <= 80; wd += 16)
			for (uint32_t k = 0; k <= wd / 2; k++) {
				float px[80];
				loom_exr_stats st;
				loom_exr_image *img = NULL;
				loom_diag d = {0};
				rng_state = 1000u * (unsigned)seed + wd;
				for (uint32_t i = 0; i < wd; i++)
					px[i] = i < k ? 0.0f : rnd_bits();
				if (write_image(tpath("eq.exr"), wd, 1, ch, 1, px, 1, &st, &d) ||
				    loom_exr_read(tpath("eq.exr"), &img, &d) ||
				    !same_image(img, wd, 1, ch, 1, px)) {
					printf("  seed %d width %u prefix %u: %s\n", seed, wd, k,
					       d.message);
					bad++;
				}
				equal += st.chunks_equal;
				loom_exr_image_free(img);
				files++;
			}
	printf("  %d files, %llu hit the equal-size case\n", files,
	       (unsigned long long)equal);
	CHECK_EQ_INT(bad, 0);
	CHECK(equal > 0);
}

static void round_trips_libdeflate(void)
{
	openexr_zip = 0;
	round_trips();
}

static void round_trips_openexr_zip(void)
{
	openexr_zip = 1;
	round_trips();
	openexr_zip = 0;
}

static void equal_size_libdeflate(void)
{
	openexr_zip = 0;
	zip_equal_size_case();
}

/* The real workaround: OpenEXR 3.1's compressor, wrapped by the guard. */
static void equal_size_openexr_zip(void)
{
	openexr_zip = 1;
	zip_equal_size_case();
	openexr_zip = 0;
}

static void exrheader_accepts(void)
{
	static const loom_exr_channel ch[] = {
		{"density", LOOM_EXR_FLOAT}, {"orientation.x", LOOM_EXR_HALF},
		{"orientation.y", LOOM_EXR_HALF}, {"orientation.z", LOOM_EXR_HALF},
		{"R", LOOM_EXR_HALF}, {"G", LOOM_EXR_HALF}, {"B", LOOM_EXR_HALF}};
	loom_exr_options o = LOOM_EXR_OPTIONS_INIT;
	loom_exr_writer *w = NULL;
	loom_exr_image *img = NULL;
	loom_diag d = {0};
	float row[33 * 7];
	char cmd[sizeof tmpdir + 256], out[8192];
	size_t n = 0;
	FILE *p;

	for (int i = 0; i < 33 * 7; i++)
		row[i] = (float)i / 10.0f;
	o.has_slice = 1;
	o.slice_z = 42;
	o.voxel_mm[0] = o.voxel_mm[1] = o.voxel_mm[2] = 0.005;
	o.origin_mm[2] = 1.25;
	o.zip_level = 9;
	CHECK_EQ_INT(loom_exr_writer_open(tpath("hdr.exr"), 33, 21, ch, 7, &o, &w, &d),
	             LOOM_OK);
	for (int y = 0; y < 21; y++)
		CHECK_EQ_INT(loom_exr_writer_put_rows(w, row, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_exr_writer_finish(w, &d), LOOM_OK);
	snprintf(cmd, sizeof cmd, "exrheader '%s' 2>&1", tpath("hdr.exr"));
	p = popen(cmd, "r");
	CHECK(p != NULL);
	if (p) {
		n = fread(out, 1, sizeof out - 1, p);
		CHECK_EQ_INT(pclose(p), 0);
	}
	out[n] = 0;
	CHECK_STR_CONTAINS(out, "compression (type compression): zip");
	CHECK_STR_CONTAINS(out, "density, 32-bit floating-point");
	CHECK_STR_CONTAINS(out, "orientation.x, 16-bit floating-point");
	CHECK_STR_CONTAINS(out, "orientation.z, 16-bit floating-point");
	CHECK_STR_CONTAINS(out, "    B, 16-bit floating-point");
	CHECK_STR_CONTAINS(out, "dataWindow (type box2i): (0 0) - (32 20)");
	CHECK_STR_CONTAINS(out, "loomSliceZ (type int): 42");
	/* our reader: attributes and values */
	CHECK_EQ_INT(loom_exr_read(tpath("hdr.exr"), &img, &d), LOOM_OK);
	if (img) {
		int c = loom_exr_image_channel(img, "density");
		CHECK(img->has_slice && img->slice_z == 42 && img->voxel_mm[1] == 0.005 &&
		      img->origin_mm[2] == 1.25);
		/* channels come back sorted by name */
		CHECK(!strcmp(img->names[0], "B") && !strcmp(img->names[3], "density"));
		CHECK(c == 3 && img->data[((size_t)c * 21 + 20) * 33 + 32] == row[32 * 7]);
		CHECK_EQ_INT(loom_exr_image_channel(img, "nope"), -1);
	}
	loom_exr_image_free(img);
}

static void writer_errors(void)
{
	static const loom_exr_channel ch[] = {{"a", LOOM_EXR_FLOAT}, {"b", LOOM_EXR_HALF}};
	loom_exr_writer *w = NULL;
	loom_diag d = {0};
	float row[2 * 40] = {0};
	const char *p = tpath("err.exr");

	/* a missing chunk: never a file (workaround for exr_finish) */
	CHECK_EQ_INT(loom_exr_writer_open(p, 40, 40, ch, 2, NULL, &w, &d), LOOM_OK);
	for (int y = 0; y < 39; y++)
		CHECK_EQ_INT(loom_exr_writer_put_rows(w, row, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_exr_writer_finish(w, &d), LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(d.message, "only 39 of 40 rows (2 of 3 chunks) written");
	CHECK(!file_exists(p));
	CHECK_EQ_INT(temp_files_left(), 0);
	/* too many rows */
	CHECK_EQ_INT(loom_exr_writer_open(p, 40, 2, ch, 2, NULL, &w, &d), LOOM_OK);
	CHECK_EQ_INT(loom_exr_writer_put_rows(w, row, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_exr_writer_put_rows(w, row, 2, &d), LOOM_ERANGE);
	CHECK_EQ_INT(loom_exr_writer_put_rows(w, row, 1, &d), LOOM_EUNUSABLE);
	CHECK_EQ_INT(loom_exr_writer_finish(w, &d), LOOM_EUNUSABLE);
	CHECK(!file_exists(p));
	/* abort mid-way */
	CHECK_EQ_INT(loom_exr_writer_open(p, 40, 40, ch, 2, NULL, &w, &d), LOOM_OK);
	CHECK_EQ_INT(loom_exr_writer_put_rows(w, row, 1, &d), LOOM_OK);
	loom_exr_writer_abort(w);
	loom_exr_writer_abort(NULL);
	CHECK(!file_exists(p));
	CHECK_EQ_INT(temp_files_left(), 0);
	/* bad arguments */
	{
		loom_exr_channel dup[] = {{"a", LOOM_EXR_FLOAT}, {"a", LOOM_EXR_HALF}};
		loom_exr_channel badpx[] = {{"a", LOOM_EXR_UINT}};
		loom_exr_channel noname[] = {{"", LOOM_EXR_FLOAT}};
		loom_exr_options o = LOOM_EXR_OPTIONS_INIT;
		CHECK_EQ_INT(loom_exr_writer_open(p, 4, 4, dup, 2, NULL, &w, &d), LOOM_EINVAL);
		CHECK_STR_CONTAINS(d.message, "channel \"a\" named twice");
		CHECK_EQ_INT(loom_exr_writer_open(p, 4, 4, badpx, 1, NULL, &w, &d), LOOM_EINVAL);
		CHECK_EQ_INT(loom_exr_writer_open(p, 4, 4, noname, 1, NULL, &w, &d), LOOM_EINVAL);
		CHECK_EQ_INT(loom_exr_writer_open(p, 0, 4, ch, 2, NULL, &w, &d), LOOM_EINVAL);
		CHECK_EQ_INT(loom_exr_writer_open(p, 4, 4, ch, 0, NULL, &w, &d), LOOM_EINVAL);
		o.zip_level = 12;
		CHECK_EQ_INT(loom_exr_writer_open(p, 4, 4, ch, 2, &o, &w, &d), LOOM_EINVAL);
		o.zip_level = -1;
		o.size = 4;
		CHECK_EQ_INT(loom_exr_writer_open(p, 4, 4, ch, 2, &o, &w, &d), LOOM_EINVAL);
		CHECK_EQ_INT(loom_exr_writer_open(tpath("no/dir.exr"), 4, 4, ch, 2, NULL, &w, &d),
		             LOOM_EIO);
		CHECK(w == NULL);
	}
	/* long channel names need the long-name flag */
	{
		loom_exr_channel lng[] = {{"a_channel_name_longer_than_31_bytes.x", LOOM_EXR_FLOAT}};
		loom_exr_image *img = NULL;
		float v[4] = {1, 2, 3, 4};
		CHECK_EQ_INT(write_image(tpath("long.exr"), 2, 2, lng, 1, v, 2, NULL, &d), LOOM_OK);
		CHECK_EQ_INT(loom_exr_read(tpath("long.exr"), &img, &d), LOOM_OK);
		CHECK(same_image(img, 2, 2, lng, 1, v));
		loom_exr_image_free(img);
	}
}

static void reader_errors(void)
{
	loom_exr_image *img = NULL;
	loom_diag d = {0};
	uint8_t junk[64] = "this is not an EXR file at all";
	FILE *fp;
	uint8_t *buf;
	long n;

	CHECK_EQ_INT(loom_exr_parse(junk, sizeof junk, "junk", &img, &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "junk: cannot read the header");
	CHECK(img == NULL);
	CHECK_EQ_INT(loom_exr_read(tpath("missing.exr"), &img, &d), LOOM_EIO);
	/* a truncated copy of a good file */
	fp = fopen(tpath("hdr.exr"), "rb");
	CHECK(fp != NULL);
	if (!fp)
		return;
	fseek(fp, 0, SEEK_END);
	n = ftell(fp);
	fseek(fp, 0, SEEK_SET);
	buf = malloc((size_t)n);
	CHECK(fread(buf, 1, (size_t)n, fp) == (size_t)n);
	fclose(fp);
	for (long cut = 8; cut < n; cut += n / 13) {
		int rc = loom_exr_parse(buf, (size_t)cut, "cut", &img, &d);
		CHECK(rc != LOOM_OK);
		CHECK(img == NULL);
	}
	free(buf);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_exr");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(round_trips_libdeflate);
	RUN(round_trips_openexr_zip);
	RUN(equal_size_libdeflate);
	RUN(equal_size_openexr_zip);
	RUN(exrheader_accepts);
	RUN(writer_errors);
	RUN(reader_errors);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
