/*
 * tests/unit/test_image.c - image and design-file I/O: PBM/PGM/PPM and PNG
 * readers and writers, every malformed case with its exact error code and
 * message, weave images and yarn-type maps.
 *
 * PNG inputs that loom's writer never produces (palette, 16-bit, alpha,
 * interlaced, low bit depth) are written here with libpng directly.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"

#include <png.h>
#include <stdlib.h>
#include <unistd.h>

#define S(lit) (const uint8_t *)(lit), sizeof(lit) - 1

static size_t read_all(const char *path, uint8_t *buf, size_t cap)
{
	FILE *fp = fopen(path, "rb");
	size_t n;
	if (!fp)
		return 0;
	n = fread(buf, 1, cap, fp);
	fclose(fp);
	return n;
}

static int pixels_are(const loom_image *img, const uint8_t *want, size_t n)
{
	size_t have = (size_t)img->width * img->height * img->channels;
	if (have != n)
		return 0;
	return memcmp(img->pixels, want, n) == 0;
}

/* ---- PBM --------------------------------------------------------------- */

static void pbm_plain(void)
{
	static const uint8_t want[] = {0, 255, 0, 255, 0, 255};
	loom_image *img = NULL;
	loom_diag d = {0};

	CHECK_EQ_INT(loom_image_parse(S("P1\n# a comment\n3 2\n1 0 1\n0 1 0\n"),
	                              "a.pbm", &img, &d), LOOM_OK);
	CHECK(img && img->width == 3 && img->height == 2 && img->channels == 1);
	CHECK(img && img->bilevel == 1);
	CHECK(img && pixels_are(img, want, 6));
	loom_image_free(img);
	/* digits need no separators; comments may sit anywhere; CRLF */
	CHECK_EQ_INT(loom_image_parse(S("P1 3#c\r\n2\r\n101#x\r\n010"), "b.pbm",
	                              &img, &d), LOOM_OK);
	CHECK(img && pixels_are(img, want, 6));
	loom_image_free(img);
}

static void pbm_roundtrip(void)
{
	/* 10 wide, so two bytes per row with 6 pad bits that must be 0:
	   row 0 = 1010000000, row 1 = 0101111111 (1 = black) */
	loom_image *img, *back = NULL;
	uint8_t buf[64];
	size_t n;

	CHECK_EQ_INT(loom_image_new(10, 2, 1, &img), LOOM_OK);
	memset(img->pixels, 255, 20);
	img->pixels[0] = img->pixels[2] = img->pixels[11] = 0;
	for (int x = 3; x < 10; x++)
		img->pixels[10 + x] = 0;
	CHECK_EQ_INT(loom_image_write(tpath("r.pbm"), img, NULL), LOOM_OK);
	n = read_all(tpath("r.pbm"), buf, sizeof buf);
	CHECK_EQ_INT(n, 12);
	CHECK(memcmp(buf, "P4\n10 2\n", 8) == 0);
	CHECK_EQ_INT(buf[8], 0xA0);  /* 1010 0000 */
	CHECK_EQ_INT(buf[9], 0x00);  /* 00 + pad */
	CHECK_EQ_INT(buf[10], 0x5F); /* 0101 1111 */
	CHECK_EQ_INT(buf[11], 0xC0); /* 11 + pad */
	CHECK_EQ_INT(loom_image_read(tpath("r.pbm"), &back, NULL), LOOM_OK);
	CHECK(back && back->bilevel && pixels_are(back, img->pixels, 20));
	loom_image_free(back);
	/* set pad bits are ignored on reading */
	CHECK_EQ_INT(loom_image_parse(S("P4\n3 1\n\xBF"), "p.pbm", &back, NULL), LOOM_OK);
	CHECK(back && back->pixels[0] == 0 && back->pixels[1] == 255 &&
	      back->pixels[2] == 0);
	loom_image_free(back);
	loom_image_free(img);
	CHECK_EQ_INT(temp_files_left(), 0);
}

/* ---- PGM / PPM --------------------------------------------------------- */

static void pgm_ppm(void)
{
	static const uint8_t grey[] = {0, 136, 255, 17};
	static const uint8_t wide[] = {0, 1, 128, 127, 255};
	static const uint8_t rgb[] = {255, 0, 0, 0, 255, 0};
	loom_image *img = NULL;

	/* maxval 15: each step is 17 */
	CHECK_EQ_INT(loom_image_parse(S("P2\n2 2\n15\n0 8\n15 1\n"), "g.pgm", &img,
	                              NULL), LOOM_OK);
	CHECK(img && img->channels == 1 && pixels_are(img, grey, 4));
	loom_image_free(img);
	/* maxval 65535, big-endian, rounded: 0x0101 = 1, 0x8080 = 128,
	   0x7fff = 127.498 -> 127 */
	CHECK_EQ_INT(loom_image_parse(S("P5\n5 1\n65535\n\x00\x00\x01\x01\x80\x80"
	                                "\x7f\xff\xff\xff"), "w.pgm", &img, NULL),
	             LOOM_OK);
	CHECK(img && pixels_are(img, wide, 5));
	loom_image_free(img);
	CHECK_EQ_INT(loom_image_parse(S("P3 2 1 255 255 0 0 0 255 0"), "c.ppm", &img,
	                              NULL), LOOM_OK);
	CHECK(img && img->channels == 3 && pixels_are(img, rgb, 6));
	loom_image_free(img);
	CHECK_EQ_INT(loom_image_parse(S("P6\n2 1\n255\n\xff\x00\x00\x00\xff\x00"),
	                              "c.ppm", &img, NULL), LOOM_OK);
	CHECK(img && img->channels == 3 && pixels_are(img, rgb, 6));
	loom_image_free(img);
}

static void pnm_write_roundtrip(void)
{
	loom_image *img, *back = NULL;
	uint8_t buf[64];

	CHECK_EQ_INT(loom_image_new(2, 2, 1, &img), LOOM_OK);
	memcpy(img->pixels, "\x00\x40\x80\xff", 4);
	CHECK_EQ_INT(loom_image_write(tpath("g.pgm"), img, NULL), LOOM_OK);
	CHECK_EQ_INT(read_all(tpath("g.pgm"), buf, sizeof buf), 15);
	CHECK(memcmp(buf, "P5\n2 2\n255\n\x00\x40\x80\xff", 15) == 0);
	/* a grey image written as .ppm is expanded */
	CHECK_EQ_INT(loom_image_write(tpath("g.ppm"), img, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_image_read(tpath("g.ppm"), &back, NULL), LOOM_OK);
	CHECK(back && back->channels == 3 && back->pixels[3] == 0x40 &&
	      back->pixels[5] == 0x40 && back->pixels[11] == 0xff);
	loom_image_free(back);
	/* .pnm picks P5 or P6 */
	CHECK_EQ_INT(loom_image_write(tpath("g.pnm"), img, NULL), LOOM_OK);
	CHECK_EQ_INT(read_all(tpath("g.pnm"), buf, 2), 2);
	CHECK(memcmp(buf, "P5", 2) == 0);
	loom_image_free(img);
	CHECK_EQ_INT(loom_image_new(2, 1, 3, &img), LOOM_OK);
	memcpy(img->pixels, "\x01\x02\x03\x04\x05\x06", 6);
	CHECK_EQ_INT(loom_image_write(tpath("c.pnm"), img, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_image_read(tpath("c.pnm"), &back, NULL), LOOM_OK);
	CHECK(back && back->channels == 3 && pixels_are(back, img->pixels, 6));
	loom_image_free(back);
	loom_image_free(img);
}

/* ---- malformed inputs: code and message -------------------------------- */

struct bad {
	const uint8_t *data;
	size_t len;
	int code;
	const char *frag;
};

static void pnm_malformed(void)
{
	static const struct bad cases[] = {
		{S(""), LOOM_ETRUNCATED, "x.img: empty file"},
		{S("GIF89a"), LOOM_EFORMAT, "not a PBM, PGM, PPM or PNG image (starts with bytes 0x47 0x49"},
		{S("P7\n"), LOOM_EFORMAT, "not a PBM, PGM, PPM or PNG"},
		{S("P1"), LOOM_ETRUNCATED, "x.img:1: expected width (a decimal number), got end of file"},
		{S("P1x 1 1\n1"), LOOM_EFORMAT, "x.img:1: expected whitespace after the magic 'P1', got 'x'"},
		{S("P1\n2 x\n"), LOOM_EFORMAT, "x.img:2: expected height (a decimal number), got 'x'"},
		{S("P1\n2 3x\n"), LOOM_EFORMAT, "x.img:2: expected whitespace after height 3, got 'x'"},
		{S("P1\n0 3\n"), LOOM_EFORMAT, "x.img:2: image size 0x3: width and height must be at least 1"},
		{S("P1\n99999999999 1\n"), LOOM_ERANGE, "x.img:2: width is too large"},
		{S("P1\n100000 100000\n"), LOOM_ERANGE, "x.img:2: image size 100000x100000 is larger than 1073741824 pixels"},
		{S("P1\n2 2\n1 0\n1\n"), LOOM_ETRUNCATED, "x.img:4: data ends after 3 of 4 pixels"},
		{S("P1\n2 1\n# c\n1 2\n"), LOOM_EFORMAT, "x.img:4: expected '0' or '1' for pixel x=1, y=0, got '2'"},
		{S("P1\n1 1\n1 1\n"), LOOM_EFORMAT, "x.img:3: expected end of data after the last of 1x1 pixels, got '1'"},
		{S("P2\n2 1\n0\n1 0\n"), LOOM_EFORMAT, "x.img:3: maxval 0 out of range: expected 1..65535"},
		{S("P2\n2 1\n70000\n"), LOOM_EFORMAT, "x.img:3: maxval 70000 out of range"},
		{S("P2\n2 1\n15\n3\n16\n"), LOOM_EFORMAT, "x.img:5: sample 16 of pixel x=1, y=0 exceeds maxval 15"},
		{S("P2\n2 1\n15\n3 -1\n"), LOOM_EFORMAT, "x.img:4: expected a sample (a decimal number), got '-'"},
		{S("P3\n1 1\n255\n1 2\n"), LOOM_ETRUNCATED, "x.img:4: data ends after 2 of 3 samples"},
		{S("P1\n100 100\n1 2"), LOOM_ETRUNCATED, "x.img:2: data ends early: 10000 pixels need at least 10000 bytes, 4 remain"},
		{S("P2\n100 100\n255\n1 2"), LOOM_ETRUNCATED, "x.img:3: data ends early: 10000 samples need at least 19999 bytes, 4 remain"},
		{S("P5 2 1 255"), LOOM_ETRUNCATED, "x.img:1: header ends without a raster"},
		{S("P5 2 1 255#\n"), LOOM_EFORMAT, "x.img:1: expected one whitespace byte between the header and the raster, got '#'"},
		{S("P5 2 1 255\n\x07"), LOOM_ETRUNCATED, "x.img: byte 12: raster ends after 1 of 2 bytes (2x1 image)"},
		{S("P5\n1 1\n10\n\x0b"), LOOM_EFORMAT, "x.img: byte 10: sample 11 exceeds maxval 10"},
		{S("P5\n1 1\n1000\n\x03\xe9"), LOOM_EFORMAT, "x.img: byte 12: sample 1001 exceeds maxval 1000"},
		{S("P5\n2 1\n1000\n\x03\xe8\x00"), LOOM_ETRUNCATED, "raster ends after 3 of 4 bytes"},
		{S("P4\n9 1\n\xff"), LOOM_ETRUNCATED, "x.img: byte 8: raster ends after 1 of 2 bytes (9x1 image)"},
		{S("P6\n1 1\n255\n\x01\x02"), LOOM_ETRUNCATED, "raster ends after 2 of 3 bytes"},
	};

	for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
		loom_image *img = (loom_image *)1;
		loom_diag d = {0};
		int rc = loom_image_parse(cases[k].data, cases[k].len, "x.img", &img, &d);
		if (rc != cases[k].code || !strstr(d.message, cases[k].frag)) {
			printf("  case %zu: code %d (%s), message \"%s\"; expected %d and \"%s\"\n",
			       k, rc, loom_strerror(rc), d.message, cases[k].code,
			       cases[k].frag);
			CHECK(0);
		}
		CHECK(img == NULL);
	}
}

static int n_warned;
static char last_warning[512];
static void grab_warning(void *user, const char *msg)
{
	(void)user;
	n_warned++;
	snprintf(last_warning, sizeof last_warning, "%s", msg);
}

static void pnm_trailing_data(void)
{
	loom_diag d = {0};
	loom_image *img = NULL;

	d.warn = grab_warning;
	n_warned = 0;
	CHECK_EQ_INT(loom_image_parse(S("P5 1 1 255\n\x07P5 1"), "t.pgm", &img, &d),
	             LOOM_OK);
	CHECK(img && img->pixels[0] == 7);
	CHECK_EQ_INT(n_warned, 1);
	CHECK_EQ_INT(d.n_warnings, 1);
	CHECK_STR_CONTAINS(last_warning, "t.pgm: byte 12: ignored 4 bytes after the image");
	loom_image_free(img);
}

/* ---- PNG written by libpng directly ------------------------------------ */

typedef struct png_spec {
	int width, height, depth, type, interlace;
	const uint8_t *rows;    /* packed rows as libpng wants them */
	const png_color *pal;
	int n_pal;
	const uint8_t *trns;
	int n_trns;
} png_spec;

static int write_png_raw(const char *path, const png_spec *s)
{
	FILE *fp = fopen(path, "wb");
	png_structp png;
	png_infop info;
	size_t stride;

	if (!fp)
		return 0;
	png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	info = png_create_info_struct(png);
	if (setjmp(png_jmpbuf(png))) {
		png_destroy_write_struct(&png, &info);
		fclose(fp);
		return 0;
	}
	png_init_io(png, fp);
	png_set_IHDR(png, info, (png_uint_32)s->width, (png_uint_32)s->height,
	             s->depth, s->type, s->interlace, PNG_COMPRESSION_TYPE_DEFAULT,
	             PNG_FILTER_TYPE_DEFAULT);
	if (s->pal)
		png_set_PLTE(png, info, s->pal, s->n_pal);
	if (s->trns)
		png_set_tRNS(png, info, s->trns, s->n_trns, NULL);
	png_write_info(png, info);
	stride = png_get_rowbytes(png, info);
	{
		int passes = png_set_interlace_handling(png);
		for (int p = 0; p < passes; p++)
			for (int y = 0; y < s->height; y++)
				png_write_row(png, (png_bytep)(s->rows + (size_t)y * stride));
	}
	png_write_end(png, info);
	png_destroy_write_struct(&png, &info);
	return fclose(fp) == 0;
}

static void png_palette(void)
{
	static const png_color pal[3] = {{255, 0, 0}, {0, 0, 255}, {10, 20, 30}};
	static const uint8_t trns[] = {0, 255};
	static const uint8_t want[] = {255, 0, 0, 0, 0, 255, 10, 20, 30, 255, 0, 0,
	                               255, 0, 0, 255, 0, 0, 0, 0, 255, 255, 0, 0};
	png_spec s = {4, 2, 4, PNG_COLOR_TYPE_PALETTE, PNG_INTERLACE_NONE, NULL,
	              pal, 3, trns, 2};
	uint8_t packed[4];
	loom_image *img = NULL;
	loom_diag d = {0};

	/* rows of 4 pixels at 4 bits = 2 bytes: 0,1,2,0 / 0,0,1,0 */
	packed[0] = 0x01;
	packed[1] = 0x20;
	packed[2] = 0x00;
	packed[3] = 0x10;
	s.rows = packed;
	CHECK(write_png_raw(tpath("pal.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("pal.png"), &img, &d), LOOM_OK);
	CHECK(img && img->channels == 3 && pixels_are(img, want, sizeof want));
	CHECK(img && img->n_palette == 3 && img->palette &&
	      memcmp(img->palette, "\xff\x00\x00\x00\x00\xff\x0a\x14\x1e", 9) == 0);
	loom_image_free(img);
}

static void png_sixteen_bit(void)
{
	/* grey 16: 0x0101 -> 1, 0x8080 -> 128, 0xffff -> 255 */
	static const uint8_t grey[] = {0x01, 0x01, 0x80, 0x80, 0xff, 0xff};
	static const uint8_t rgb[] = {0x01, 0x01, 0x02, 0x02, 0x03, 0x03};
	png_spec s = {3, 1, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, grey,
	              NULL, 0, NULL, 0};
	loom_image *img = NULL;

	CHECK(write_png_raw(tpath("g16.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("g16.png"), &img, NULL), LOOM_OK);
	CHECK(img && img->channels == 1 && pixels_are(img, (const uint8_t *)"\x01\x80\xff", 3));
	loom_image_free(img);
	s.width = 1;
	s.type = PNG_COLOR_TYPE_RGB;
	s.rows = rgb;
	CHECK(write_png_raw(tpath("c16.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("c16.png"), &img, NULL), LOOM_OK);
	CHECK(img && img->channels == 3 && pixels_are(img, (const uint8_t *)"\x01\x02\x03", 3));
	loom_image_free(img);
}

static void png_alpha_lowbit_interlaced(void)
{
	static const uint8_t ga[] = {10, 0, 20, 255};            /* grey+alpha */
	static const uint8_t rgba[] = {1, 2, 3, 0, 4, 5, 6, 9};  /* RGBA */
	static const uint8_t two_bit[] = {0x1b};                 /* 0 1 2 3 */
	uint8_t big[9 * 9 * 3];
	png_spec s = {2, 1, 8, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_INTERLACE_NONE, ga,
	              NULL, 0, NULL, 0};
	loom_image *img = NULL;

	CHECK(write_png_raw(tpath("ga.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("ga.png"), &img, NULL), LOOM_OK);
	CHECK(img && img->channels == 1 && pixels_are(img, (const uint8_t *)"\x0a\x14", 2));
	loom_image_free(img);
	s.type = PNG_COLOR_TYPE_RGB_ALPHA;
	s.rows = rgba;
	CHECK(write_png_raw(tpath("rgba.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("rgba.png"), &img, NULL), LOOM_OK);
	CHECK(img && img->channels == 3 &&
	      pixels_are(img, (const uint8_t *)"\x01\x02\x03\x04\x05\x06", 6));
	loom_image_free(img);
	s.width = 4;
	s.depth = 2;
	s.type = PNG_COLOR_TYPE_GRAY;
	s.rows = two_bit;
	CHECK(write_png_raw(tpath("g2.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("g2.png"), &img, NULL), LOOM_OK);
	CHECK(img && pixels_are(img, (const uint8_t *)"\x00\x55\xaa\xff", 4));
	CHECK(img && img->bilevel == 0);
	loom_image_free(img);
	for (size_t k = 0; k < sizeof big; k++)
		big[k] = (uint8_t)(k * 7 + 3);
	s = (png_spec){9, 9, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_ADAM7, big, NULL,
	               0, NULL, 0};
	CHECK(write_png_raw(tpath("adam7.png"), &s));
	CHECK_EQ_INT(loom_image_read(tpath("adam7.png"), &img, NULL), LOOM_OK);
	CHECK(img && pixels_are(img, big, sizeof big));
	loom_image_free(img);
}

static void png_roundtrip(void)
{
	loom_image *img, *back = NULL;
	uint8_t buf[256];

	/* 8-bit grey */
	CHECK_EQ_INT(loom_image_new(5, 3, 1, &img), LOOM_OK);
	for (int k = 0; k < 15; k++)
		img->pixels[k] = (uint8_t)(k * 17);
	CHECK_EQ_INT(loom_image_write(tpath("g8.png"), img, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_image_read(tpath("g8.png"), &back, NULL), LOOM_OK);
	CHECK(back && back->channels == 1 && !back->bilevel &&
	      pixels_are(back, img->pixels, 15));
	loom_image_free(back);
	/* bilevel -> 1-bit grey PNG (IHDR bit depth byte 24) -> bilevel again */
	img->bilevel = 1;
	CHECK_EQ_INT(loom_image_write(tpath("g1.png"), img, NULL), LOOM_OK);
	CHECK(read_all(tpath("g1.png"), buf, sizeof buf) > 26);
	CHECK_EQ_INT(buf[24], 1);
	CHECK_EQ_INT(buf[25], 0);
	CHECK_EQ_INT(loom_image_read(tpath("g1.png"), &back, NULL), LOOM_OK);
	CHECK(back && back->bilevel == 1);
	for (int k = 0; back && k < 15; k++)
		CHECK_EQ_INT(back->pixels[k], img->pixels[k] < 128 ? 0 : 255);
	loom_image_free(back);
	loom_image_free(img);
	/* RGB */
	CHECK_EQ_INT(loom_image_new(3, 2, 3, &img), LOOM_OK);
	for (int k = 0; k < 18; k++)
		img->pixels[k] = (uint8_t)(250 - k * 13);
	CHECK_EQ_INT(loom_image_write(tpath("c8.PNG"), img, NULL), LOOM_OK);
	CHECK_EQ_INT(read_all(tpath("c8.PNG"), buf, sizeof buf) > 26, 1);
	CHECK_EQ_INT(buf[24], 8);
	CHECK_EQ_INT(buf[25], 2);
	CHECK_EQ_INT(loom_image_read(tpath("c8.PNG"), &back, NULL), LOOM_OK);
	CHECK(back && back->channels == 3 && pixels_are(back, img->pixels, 18));
	loom_image_free(back);
	loom_image_free(img);
	CHECK_EQ_INT(temp_files_left(), 0);
}

static uint32_t crc32_of(const uint8_t *p, size_t n)
{
	uint32_t c = 0xffffffffu;
	for (size_t k = 0; k < n; k++) {
		c ^= p[k];
		for (int b = 0; b < 8; b++)
			c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1)));
	}
	return ~c;
}

static void put32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)(v >> 24);
	p[1] = (uint8_t)(v >> 16);
	p[2] = (uint8_t)(v >> 8);
	p[3] = (uint8_t)v;
}

/* Signature, IHDR with the given fields and a correct CRC, and the header
   of an IDAT chunk (png_read_info stops there). */
static size_t ihdr_only(uint8_t *buf, uint32_t w, uint32_t h, int depth, int type,
                        int interlace)
{
	static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
	memcpy(buf, sig, 8);
	put32(buf + 8, 13);
	memcpy(buf + 12, "IHDR", 4);
	put32(buf + 16, w);
	put32(buf + 20, h);
	buf[24] = (uint8_t)depth;
	buf[25] = (uint8_t)type;
	buf[26] = buf[27] = 0;
	buf[28] = (uint8_t)interlace;
	put32(buf + 29, crc32_of(buf + 12, 17));
	put32(buf + 33, 100); /* the start of an IDAT chunk, without its data */
	memcpy(buf + 37, "IDAT", 4);
	return 41;
}

static void png_malformed(void)
{
	uint8_t good[512], bad[512];
	size_t n;
	loom_image *img, *out = (loom_image *)1;
	loom_diag d = {0};

	CHECK_EQ_INT(loom_image_new(16, 16, 3, &img), LOOM_OK);
	for (int k = 0; k < 16 * 16 * 3; k++)
		img->pixels[k] = (uint8_t)(k * 31);
	CHECK_EQ_INT(loom_image_write(tpath("m.png"), img, NULL), LOOM_OK);
	loom_image_free(img);
	n = read_all(tpath("m.png"), good, sizeof good);
	CHECK(n > 100 && n < sizeof good);
	/* signature only */
	CHECK_EQ_INT(loom_image_parse(good, 8, "m.png", &out, &d), LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(d.message, "m.png: byte 8: truncated PNG: file ends early");
	CHECK(out == NULL);
	/* cut inside the image data */
	CHECK_EQ_INT(loom_image_parse(good, n - 30, "m.png", &out, &d), LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(d.message, "truncated PNG");
	/* IHDR CRC damaged */
	memcpy(bad, good, n);
	bad[30] ^= 0x55;
	CHECK_EQ_INT(loom_image_parse(bad, n, "m.png", &out, &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "m.png: byte 33: malformed PNG: IHDR: CRC error");
	/* a damaged byte inside IDAT also fails its CRC */
	memcpy(bad, good, n);
	bad[n - 20] ^= 0xff;
	CHECK_EQ_INT(loom_image_parse(bad, n, "m.png", &out, &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "malformed PNG");
	/* zero width */
	n = ihdr_only(bad, 0, 5, 8, 0, 0);
	CHECK_EQ_INT(loom_image_parse(bad, n, "z.png", &out, &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "z.png: byte 33: malformed PNG: Invalid IHDR data");
	/* bad bit depth for the colour type */
	n = ihdr_only(bad, 4, 4, 3, 2, 0);
	CHECK_EQ_INT(loom_image_parse(bad, n, "z.png", &out, &d), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(d.message, "Invalid IHDR data");
	/* huge claimed size, no data: refused before any allocation */
	n = ihdr_only(bad, 40000, 30000, 8, 0, 0);
	CHECK_EQ_INT(loom_image_parse(bad, n, "h.png", &out, &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, "h.png: image size 40000x30000 is larger than 1073741824 pixels");
	/* large but allowed size, no data: truncated, not out of memory */
	n = ihdr_only(bad, 30000, 30000, 8, 2, 0);
	CHECK_EQ_INT(loom_image_parse(bad, n, "h.png", &out, &d), LOOM_ETRUNCATED);
	/* interlaced images need the whole image in memory: limited */
	n = ihdr_only(bad, 20000, 20000, 8, 2, 1);
	CHECK_EQ_INT(loom_image_parse(bad, n, "i.png", &out, &d), LOOM_EUNSUPPORTED);
	CHECK_STR_CONTAINS(d.message, "i.png: interlaced PNG of 20000x20000 is too large to decode (limit 256 MiB)");
	CHECK(out == NULL);
}

/* ---- API edges ---------------------------------------------------------- */

static void api_edges(void)
{
	loom_image *img = (loom_image *)1;
	loom_diag d = {0};

	CHECK_EQ_INT(loom_image_new(0, 1, 1, &img), LOOM_EINVAL);
	CHECK(img == NULL);
	CHECK_EQ_INT(loom_image_new(1, 1, 2, &img), LOOM_EINVAL);
	CHECK_EQ_INT(loom_image_new(1, 1, 1, NULL), LOOM_EINVAL);
	loom_image_free(NULL);
	CHECK_EQ_INT(loom_image_parse(NULL, 3, "n", &img, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_image_parse(S("P1 1 1 1"), "n", NULL, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_image_read(tpath("does-not-exist.png"), &img, &d), LOOM_EIO);
	CHECK_STR_CONTAINS(d.message, "does-not-exist.png: cannot open");
	CHECK_EQ_INT(loom_image_new(2, 2, 3, &img), LOOM_OK);
	CHECK_EQ_INT(loom_image_write(tpath("x.gif"), img, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "unknown image extension '.gif' (expected .png, .pbm, .pgm, .ppm or .pnm)");
	CHECK_EQ_INT(loom_image_write(tpath("noext"), img, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "unknown image extension ''");
	CHECK_EQ_INT(loom_image_write(tpath("x.pgm"), img, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "cannot write an RGB image as PGM");
	CHECK_EQ_INT(loom_image_write(tpath("no/such/dir/x.png"), img, &d), LOOM_EIO);
	CHECK_STR_CONTAINS(d.message, "x.png: cannot create");
	CHECK_EQ_INT(loom_image_write(NULL, img, &d), LOOM_EINVAL);
	loom_image_free(img);
	CHECK_EQ_INT(temp_files_left(), 0);
}

/* ---- designs as files ---------------------------------------------------- */

static loom_design *twill23(uint32_t rows, uint32_t cols)
{
	loom_weave_params p;
	loom_design *d = NULL;
	if (loom_weave_parse("twill:2/3", &p, NULL) ||
	    loom_design_make(&p, rows, cols, &d, NULL))
		return NULL;
	return d;
}

static void weave_write_pbm_png(void)
{
	/* twill 2/3: rows 10001 11000 01100 00110 00011 -> 88 c0 60 30 18 */
	static const uint8_t want[] = "P4\n5 5\n\x88\xc0\x60\x30\x18";
	loom_design *d = twill23(5, 5), *back = NULL;
	uint8_t buf[256];
	loom_diag dg = {0};

	CHECK(d != NULL);
	CHECK_EQ_INT(loom_weave_write(tpath("t.pbm"), d, NULL), LOOM_OK);
	CHECK_EQ_INT(read_all(tpath("t.pbm"), buf, sizeof buf), sizeof want - 1);
	CHECK(memcmp(buf, want, sizeof want - 1) == 0);
	CHECK_EQ_INT(loom_design_read(tpath("t.pbm"), &back, NULL), LOOM_OK);
	CHECK(back && back->rows == 5 && back->cols == 5 &&
	      memcmp(back->weave, d->weave, 25) == 0);
	loom_design_free(back);
	CHECK_EQ_INT(loom_weave_write(tpath("t.png"), d, NULL), LOOM_OK);
	CHECK(read_all(tpath("t.png"), buf, sizeof buf) > 26);
	CHECK_EQ_INT(buf[24], 1); /* 1-bit */
	CHECK_EQ_INT(buf[25], 0); /* grey */
	CHECK_EQ_INT(loom_design_read(tpath("t.png"), &back, NULL), LOOM_OK);
	CHECK(back && memcmp(back->weave, d->weave, 25) == 0);
	loom_design_free(back);
	CHECK_EQ_INT(loom_weave_write(tpath("t.jpg"), d, &dg), LOOM_EINVAL);
	CHECK_STR_CONTAINS(dg.message, "cannot write a weave as '.jpg': expected .pbm or .png");
	loom_design_free(d);
	CHECK_EQ_INT(temp_files_left(), 0);
}

static void weave_from_grey_images(void)
{
	loom_design *d = NULL;
	loom_diag dg = {0};

	/* two levels: the darker (100) is warp over, whatever the threshold */
	CHECK(spit(tpath("two.pgm"), "P2 3 1 255 100 200 100", 22));
	CHECK_EQ_INT(loom_design_read(tpath("two.pgm"), &d, &dg), LOOM_OK);
	CHECK(d && d->rows == 1 && d->cols == 3 && d->weave[0] == 1 &&
	      d->weave[1] == 0 && d->weave[2] == 1);
	loom_design_free(d);
	/* one level: dark means all over */
	CHECK(spit(tpath("one.pgm"), "P2 2 1 255 20 20", 16));
	CHECK_EQ_INT(loom_design_read(tpath("one.pgm"), &d, &dg), LOOM_OK);
	CHECK(d && d->weave[0] == 1 && d->weave[1] == 1);
	loom_design_free(d);
	CHECK(spit(tpath("three.pgm"), "P2 2 2 255 0 255 255 57", 23));
	CHECK_EQ_INT(loom_design_read(tpath("three.pgm"), &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "three.pgm: pixel x=1, y=1 has a third level "
	                   "(grey level 57; the others are grey level 0 and grey "
	                   "level 255): a weave image must be two-level");
	CHECK(d == NULL);
	/* two colours of equal darkness */
	CHECK(spit(tpath("eq.ppm"), "P3 2 1 255 255 0 0 255 0 0", 26));
	CHECK_EQ_INT(loom_design_read(tpath("eq.ppm"), &d, &dg), LOOM_OK); /* one colour */
	loom_design_free(d);
	CHECK(spit(tpath("eq2.ppm"), "P3 2 1 255 4 0 41 0 10 0", 24));
	CHECK_EQ_INT(loom_design_read(tpath("eq2.ppm"), &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "equally dark");
	/* an image extension with other content */
	CHECK(spit(tpath("fake.png"), "hello", 5));
	CHECK_EQ_INT(loom_design_read(tpath("fake.png"), &d, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "fake.png: not a PBM, PGM, PPM or PNG image");
	/* .wif goes to the WIF reader */
	CHECK(spit(tpath("x.wif"), "[WIF]\n", 6));
	dg.message[0] = 0;
	CHECK(loom_design_read(tpath("x.wif"), &d, &dg) != LOOM_OK || d != NULL);
	loom_design_free(d);
	d = NULL;
	CHECK_EQ_INT(loom_design_read(NULL, &d, &dg), LOOM_EINVAL);
	CHECK_EQ_INT(loom_design_read(tpath("x.pbm"), NULL, &dg), LOOM_EINVAL);
}

static void type_maps(void)
{
	loom_design *d = twill23(2, 3);
	loom_diag dg = {0};
	uint8_t buf[64];

	CHECK(d != NULL);
	if (!d)
		return;
	memcpy(d->warp_type, "\x00\x01\x00\x01\x00\x01", 6);
	CHECK_EQ_INT(loom_type_map_write(tpath("warp.pgm"), d, LOOM_MAP_WARP, NULL), LOOM_OK);
	CHECK_EQ_INT(read_all(tpath("warp.pgm"), buf, sizeof buf), 17);
	CHECK(memcmp(buf, "P5\n3 2\n255\n\x00\x01\x00\x01\x00\x01", 17) == 0);
	CHECK_EQ_INT(loom_type_map_write(tpath("weft.png"), d, LOOM_MAP_WEFT, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_type_map_write(tpath("weft.pbm"), d, LOOM_MAP_WEFT, &dg), LOOM_EINVAL);
	CHECK_STR_CONTAINS(dg.message, "cannot write a type map as '.pbm': expected .pgm or .png");
	CHECK_EQ_INT(loom_type_map_write(tpath("w.png"), d, 7, &dg), LOOM_EINVAL);
	/* read back: the weft map PNG into the warp map */
	CHECK_EQ_INT(loom_type_map_read(tpath("weft.png"), d, LOOM_MAP_WARP, &dg), LOOM_OK);
	CHECK(memcmp(d->warp_type, d->weft_type, 6) == 0);
	/* raw values: maxval 7 is not rescaled; IDs past the table extend it */
	CHECK(spit(tpath("ids.pgm"), "P2 3 2 7 0 1 2 3 4 5", 20));
	dg.warn = grab_warning;
	n_warned = 0;
	CHECK_EQ_INT(loom_type_map_read(tpath("ids.pgm"), d, LOOM_MAP_WEFT, &dg), LOOM_OK);
	CHECK(memcmp(d->weft_type, "\x00\x01\x02\x03\x04\x05", 6) == 0);
	CHECK_EQ_INT(d->n_types, 6);
	CHECK_EQ_INT(n_warned, 1);
	CHECK_STR_CONTAINS(last_warning, "ids.pgm: type IDs up to 5 but the yarn table had 2 entries; added default types 2..5");
	CHECK_STR_CONTAINS(d->types[5].name, "type5");
	CHECK_EQ_INT(loom_design_validate(d, NULL), LOOM_OK);
	/* errors leave the design unchanged */
	CHECK(spit(tpath("small.pgm"), "P2 2 2 7 0 1 2 3", 16));
	CHECK_EQ_INT(loom_type_map_read(tpath("small.pgm"), d, LOOM_MAP_WEFT, &dg), LOOM_EMISMATCH);
	CHECK_STR_CONTAINS(dg.message, "small.pgm: weft-type map is 2x2 (width x height) but the weave has 3 ends x 2 picks");
	CHECK(spit(tpath("col.ppm"), "P3 3 2 7 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0", 44));
	CHECK_EQ_INT(loom_type_map_read(tpath("col.ppm"), d, LOOM_MAP_WEFT, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "a weft-type map must be a grey image");
	CHECK(spit(tpath("big.pgm"), "P2 3 2 1000 0 1 2 3 4 300", 25));
	CHECK_EQ_INT(loom_type_map_read(tpath("big.pgm"), d, LOOM_MAP_WEFT, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "big.pgm: line 1: sample 300 is above 255 and cannot be a type ID");
	CHECK(memcmp(d->weft_type, "\x00\x01\x02\x03\x04\x05", 6) == 0);
	loom_design_free(d);
}

static void type_map_png_raw(void)
{
	/* an indexed PNG gives its indices, a 4-bit grey PNG its raw values,
	   16-bit grey must fit in 8 bits */
	static const png_color pal[4] = {{0, 0, 0}, {9, 9, 9}, {1, 2, 3}, {4, 5, 6}};
	static const uint8_t idx[] = {0x1b}; /* 2-bit: 0 1 2 3 */
	static const uint8_t g4[] = {0x0f, 0x37};
	static const uint8_t g16[] = {0x00, 0x05, 0x01, 0x00, 0x00, 0x00, 0x00, 0x01};
	png_spec s = {4, 1, 2, PNG_COLOR_TYPE_PALETTE, PNG_INTERLACE_NONE, idx,
	              pal, 4, NULL, 0};
	loom_design *d;
	loom_diag dg = {0};

	CHECK_EQ_INT(loom_design_new(1, 4, &d), LOOM_OK);
	CHECK(write_png_raw(tpath("idx.png"), &s));
	CHECK_EQ_INT(loom_type_map_read(tpath("idx.png"), d, LOOM_MAP_WARP, &dg), LOOM_OK);
	CHECK(memcmp(d->warp_type, "\x00\x01\x02\x03", 4) == 0);
	s = (png_spec){4, 1, 4, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, g4, NULL,
	               0, NULL, 0};
	CHECK(write_png_raw(tpath("g4.png"), &s));
	CHECK_EQ_INT(loom_type_map_read(tpath("g4.png"), d, LOOM_MAP_WARP, &dg), LOOM_OK);
	CHECK(memcmp(d->warp_type, "\x00\x0f\x03\x07", 4) == 0);
	CHECK_EQ_INT(d->n_types, 16);
	s = (png_spec){4, 1, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, g16, NULL,
	               0, NULL, 0};
	CHECK(write_png_raw(tpath("g16m.png"), &s));
	CHECK_EQ_INT(loom_type_map_read(tpath("g16m.png"), d, LOOM_MAP_WARP, &dg), LOOM_EFORMAT);
	CHECK_STR_CONTAINS(dg.message, "g16m.png: pixel x=1, y=0: sample 256 is above 255 and cannot be a type ID");
	loom_design_free(d);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_image");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(pbm_plain);
	RUN(pbm_roundtrip);
	RUN(pgm_ppm);
	RUN(pnm_write_roundtrip);
	RUN(pnm_malformed);
	RUN(pnm_trailing_data);
	RUN(png_palette);
	RUN(png_sixteen_bit);
	RUN(png_alpha_lowbit_interlaced);
	RUN(png_roundtrip);
	RUN(png_malformed);
	RUN(api_edges);
	RUN(weave_write_pbm_png);
	RUN(weave_from_grey_images);
	RUN(type_maps);
	RUN(type_map_png_raw);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
