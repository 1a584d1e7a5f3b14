/*
 * tests/unit/test_volio.c - Mitsuba .vol, raw and NRRD readers/writers,
 * half floats.  Expected values are hand-built byte images of the formats
 * or brute-force references; NRRD files come from Teem's unu.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"

#include <stdarg.h>
#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

/* Any "*.tmp.*" left in the scratch directory? */
static uint64_t rng_state;
static uint64_t rnd(void)
{
	uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static float rndf(void)
{
	return (float)(rnd() >> 40) / (float)(1 << 24);
}

static void put32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}

static void putf(uint8_t *p, float f)
{
	uint32_t b;
	memcpy(&b, &f, 4);
	put32(p, b);
}

/* A .vol header by hand. */
static void vol_header(uint8_t *h, int ver, int32_t enc, int32_t x, int32_t y,
                       int32_t z, int32_t ch, const float bb[6])
{
	memcpy(h, "VOL", 3);
	h[3] = (uint8_t)ver;
	put32(h + 4, (uint32_t)enc);
	put32(h + 8, (uint32_t)x);
	put32(h + 12, (uint32_t)y);
	put32(h + 16, (uint32_t)z);
	put32(h + 20, (uint32_t)ch);
	for (int i = 0; i < 6; i++)
		putf(h + 24 + 4 * i, bb[i]);
}

static const float unit_bb[6] = {0, 0, 0, 1, 1, 1};

/* ---- half floats ------------------------------------------------------ */

static void half_exhaustive(void)
{
	int bad = 0;
	for (uint32_t h = 0; h < 65536; h++) {
		float f = loom_half_to_float((uint16_t)h);
		uint16_t back = loom_half_from_float(f);
		if ((h & 0x7c00) == 0x7c00 && (h & 0x3ff)) {
			if (!isnan(f) || (back & 0x7c00) != 0x7c00 || !(back & 0x3ff))
				bad++;
		} else if (back != h) {
			bad++;
		}
	}
	CHECK_EQ_INT(bad, 0);
	/* hand-checked values */
	CHECK(loom_half_to_float(0x3c00) == 1.0f);
	CHECK(loom_half_to_float(0xc000) == -2.0f);
	CHECK(loom_half_to_float(0x7bff) == 65504.0f);
	CHECK(loom_half_to_float(0x0001) == 0x1p-24f);
	CHECK(loom_half_to_float(0x0400) == 0x1p-14f);
	CHECK(isinf(loom_half_to_float(0x7c00)));
	CHECK_EQ_INT(loom_half_from_float(65519.0f), 0x7bff);
	CHECK_EQ_INT(loom_half_from_float(65520.0f), 0x7c00); /* tie -> even = inf */
	CHECK_EQ_INT(loom_half_from_float(1e10f), 0x7c00);
	CHECK_EQ_INT(loom_half_from_float(-1e10f), 0xfc00);
	CHECK_EQ_INT(loom_half_from_float(0x1p-25f), 0);      /* tie -> even 0 */
	CHECK_EQ_INT(loom_half_from_float(0x1.8p-25f), 1);
	CHECK_EQ_INT(loom_half_from_float(0x1p-26f), 0);
	CHECK_EQ_INT(loom_half_from_float(-0.0f), 0x8000);
}

/* Every midpoint between neighbouring halves rounds to the even one, and
   the floats just beside it round to the nearer one. */
static void half_rounding(void)
{
	int bad = 0;
	for (uint32_t h = 0; h < 0x7bff; h++) {
		float a = loom_half_to_float((uint16_t)h);
		float b = loom_half_to_float((uint16_t)(h + 1));
		float m = (a + b) / 2; /* exact: 12 significant bits */
		uint16_t even = (h & 1) ? (uint16_t)(h + 1) : (uint16_t)h;
		if (loom_half_from_float(m) != even)
			bad++;
		if (loom_half_from_float(nextafterf(m, 1e9f)) != h + 1)
			bad++;
		if (loom_half_from_float(nextafterf(m, -1e9f)) != h)
			bad++;
		if (loom_half_from_float(-m) != (0x8000 | even))
			bad++;
	}
	CHECK_EQ_INT(bad, 0);
}

static void scalar_names(void)
{
	int t = 0;
	CHECK_EQ_INT(loom_scalar_parse("u16", &t), LOOM_OK);
	CHECK_EQ_INT(t, LOOM_SCALAR_U16);
	CHECK_EQ_INT(loom_scalar_parse("FLOAT32", &t), LOOM_OK);
	CHECK_EQ_INT(t, LOOM_SCALAR_F32);
	CHECK_EQ_INT(loom_scalar_parse("u12", &t), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scalar_size(LOOM_SCALAR_F64), 8);
	CHECK_EQ_INT(loom_scalar_size(99), 0);
	CHECK(!strcmp(loom_scalar_name(LOOM_SCALAR_U8), "u8"));
	CHECK(!strcmp(loom_scalar_name(-3), "unknown"));
}

/* ---- .vol ---------------------------------------------------------------- */

/* The exact bytes of a tiny float32 file written by the writer. */
static void vol_bytes_exact(void)
{
	loom_vol_header h = {LOOM_VOL_FLOAT32, 2, 1, 2, 1, {0, 0, 0}, {2, 1, 2}};
	float v[4] = {0.5f, -1.0f, 2.0f, 3.25f};
	uint8_t want[48 + 16];
	loom_vol_writer *w;
	loom_diag d = {0};
	uint8_t *got;
	size_t n = 0;
	const char *p = tpath("exact.vol");
	float bb[6] = {0, 0, 0, 2, 1, 2};

	vol_header(want, 3, 1, 2, 1, 2, 1, bb);
	for (int i = 0; i < 4; i++)
		putf(want + 48 + 4 * i, v[i]);
	CHECK_EQ_INT(loom_vol_writer_open(p, &h, &w, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_slices(w, v, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_voxels(w, v + 2, 2, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_finish(w, &d), LOOM_OK);
	got = slurp(p, &n);
	CHECK(got != NULL);
	CHECK_EQ_INT(n, sizeof want);
	CHECK(got && n == sizeof want && memcmp(got, want, n) == 0);
	/* header bytes spelled out: "VOL", 3, encoding 1, 2 1 2, 1 channel */
	CHECK(got && got[0] == 'V' && got[1] == 'O' && got[2] == 'L' && got[3] == 3 &&
	      got[4] == 1 && got[8] == 2 && got[12] == 1 && got[16] == 2 &&
	      got[20] == 1);
	free(got);
	CHECK_EQ_INT(temp_files_left(), 0);
}

/* Reading a hand-made file of each encoding. */
static void vol_decode_by_hand(void)
{
	uint8_t buf[48 + 64];
	loom_volbuf *v = NULL;
	loom_vol_header h;
	loom_diag d = {0};
	float bb[6] = {-1, 0, 10, 1, 4, 20};

	/* uint8, 3x1x1, 1 channel: 0, 128, 255 */
	vol_header(buf, 3, 3, 3, 1, 1, 1, bb);
	buf[48] = 0;
	buf[49] = 128;
	buf[50] = 255;
	CHECK_EQ_INT(loom_vol_parse(buf, 51, "u8", 0, &h, &v, &d), LOOM_OK);
	if (v) {
		CHECK(v->data[0] == 0.0f && v->data[1] == 128.0f / 255.0f &&
		      v->data[2] == 1.0f);
		/* Mitsuba 0.6 geometry: spacing extent/(res-1), origin bbox min */
		CHECK(v->spacing[0] == 1.0 && v->origin[0] == -1.0 && v->origin[2] == 10.0);
		CHECK(v->spacing[1] == 4.0); /* res 1: the extent */
		CHECK_EQ_INT(v->source_type, LOOM_SCALAR_U8);
	}
	loom_volbuf_free(v);
	/* float16: 1.0, -2.0 */
	vol_header(buf, 3, 2, 1, 1, 1, 2, bb);
	buf[48] = 0x00; buf[49] = 0x3c; buf[50] = 0x00; buf[51] = 0xc0;
	CHECK_EQ_INT(loom_vol_parse(buf, 52, "f16", 0, &h, &v, &d), LOOM_OK);
	if (v)
		CHECK(v->data[0] == 1.0f && v->data[1] == -2.0f);
	loom_volbuf_free(v);
	/* quantized directions: (0,0) = +z, (255,x) = -z, (128,0), (64,64) */
	vol_header(buf, 3, 4, 4, 1, 1, 3, bb);
	buf[48] = 0; buf[49] = 0;
	buf[50] = 255; buf[51] = 17;
	buf[52] = 128; buf[53] = 0;
	buf[54] = 64; buf[55] = 64;
	CHECK_EQ_INT(loom_vol_parse(buf, 56, "qdir", 0, &h, &v, &d), LOOM_OK);
	if (v) {
		double t = 128 * M_PI / 255, t2 = 64 * M_PI / 255, p2 = 2 * 64 * M_PI / 255;
		CHECK_EQ_INT(v->channels, 3);
		CHECK(v->data[0] == 0.0f && v->data[1] == 0.0f && v->data[2] == 1.0f);
		CHECK(v->data[3] == 0.0f && v->data[4] == 0.0f && v->data[5] == -1.0f);
		CHECK(fabs(v->data[6] - sin(t)) < 1e-6 && v->data[7] == 0.0f &&
		      fabs(v->data[8] - cos(t)) < 1e-6);
		CHECK(fabs(v->data[9] - cos(p2) * sin(t2)) < 1e-6 &&
		      fabs(v->data[10] - sin(p2) * sin(t2)) < 1e-6 &&
		      fabs(v->data[11] - cos(t2)) < 1e-6);
	}
	loom_volbuf_free(v);
}

static void qdir_codes(void)
{
	int bad = 0;
	double worst = 0;
	/* every code decodes to a unit vector that encodes back to itself
	   (phi is irrelevant at the poles, and phi 255 is phi 0) */
	for (int t = 0; t < 256; t++)
		for (int p = 0; p < 256; p++) {
			uint8_t tp[2] = {(uint8_t)t, (uint8_t)p}, back[2];
			float v[3];
			loom_vol_qdir_decode(tp, v);
			if (fabs(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - 1.0) > 1e-6)
				bad++;
			loom_vol_qdir_encode(v, back);
			if (back[0] != t)
				bad++;
			else if (t != 0 && t != 255 && back[1] != (p == 255 ? 0 : p))
				bad++;
		}
	CHECK_EQ_INT(bad, 0);
	/* random unit vectors: the quantisation error stays below a cell */
	rng_state = check_seed();
	for (int i = 0; i < 20000; i++) {
		float v[3], w[3];
		uint8_t tp[2];
		double n, dot;
		do {
			v[0] = 2 * rndf() - 1;
			v[1] = 2 * rndf() - 1;
			v[2] = 2 * rndf() - 1;
			n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
		} while (n < 0.1 || n > 1);
		loom_vol_qdir_encode(v, tp);
		loom_vol_qdir_decode(tp, w);
		dot = (v[0] * w[0] + v[1] * w[1] + v[2] * w[2]) / n;
		if (dot > 1)
			dot = 1;
		if (acos(dot) > worst)
			worst = acos(dot);
	}
	/* half the diagonal of a (pi/255) x (2pi/255) cell on the equator */
	CHECK(worst < 0.5 * sqrt(1 + 4) * M_PI / 255 + 1e-6);
	printf("  worst quantised-direction error %.4f degrees\n", worst * 180 / M_PI);
	{
		float zero[3] = {0, 0, 0}, nanv[3] = {NAN, 0, 0};
		uint8_t tp[2] = {9, 9};
		loom_vol_qdir_encode(zero, tp);
		CHECK(tp[0] == 0 && tp[1] == 0);
		loom_vol_qdir_encode(nanv, tp);
		CHECK(tp[0] == 0 && tp[1] == 0);
	}
}

/* Round trip every encoding through the writer (slices in uneven calls),
   the whole readers and the box reader. */
static void vol_round_trips(void)
{
	const int enc[4] = {LOOM_VOL_FLOAT32, LOOM_VOL_FLOAT16, LOOM_VOL_UINT8,
	                    LOOM_VOL_QDIR};
	rng_state = check_seed() + 1;
	for (int e = 0; e < 4; e++)
		for (uint32_t ch = 1; ch <= 3; ch++) {
			loom_vol_header h = {enc[e], 7, 5, 6, ch, {0, -1, 2}, {3.5f, 1, 4}};
			size_t nvox = 7 * 5 * 6, nval;
			float *in, *want;
			loom_vol_writer *w = NULL;
			loom_volbuf *v = NULL;
			loom_vol_header hr;
			loom_diag d = {0};
			char name[64];
			int bad = 0;

			if (enc[e] == LOOM_VOL_QDIR && ch != 3)
				continue;
			snprintf(name, sizeof name, "rt_%d_%u.vol", enc[e], ch);
			nval = nvox * ch;
			in = malloc(nval * sizeof *in);
			want = malloc(nval * sizeof *want);
			for (size_t i = 0; i < nval; i++) {
				switch (enc[e]) {
				case LOOM_VOL_FLOAT32: /* any bits but NaN */
					in[i] = (rndf() - 0.5f) * 1e6f;
					want[i] = in[i];
					break;
				case LOOM_VOL_FLOAT16: /* representable halves */
					want[i] = in[i] = loom_half_to_float((uint16_t)(rnd() & 0x7bff));
					break;
				case LOOM_VOL_UINT8: {
					int k = (int)(rnd() % 256);
					in[i] = (float)k / 255.0f;
					want[i] = in[i];
					if (i % 17 == 0) { /* clamping */
						in[i] = (i & 1) ? 7.0f : -3.0f;
						want[i] = (i & 1) ? 1.0f : 0.0f;
					}
					break;
				}
				default:
					in[i] = rndf() - 0.5f;
					break;
				}
			}
			if (enc[e] == LOOM_VOL_QDIR)
				for (size_t i = 0; i < nvox; i++) {
					uint8_t tp[2];
					loom_vol_qdir_encode(in + 3 * i, tp);
					loom_vol_qdir_decode(tp, want + 3 * i);
				}
			CHECK_EQ_INT(loom_vol_writer_open(tpath(name), &h, &w, &d), LOOM_OK);
			CHECK_EQ_INT(loom_vol_writer_put_slices(w, in, 2, &d), LOOM_OK);
			CHECK_EQ_INT(loom_vol_writer_put_voxels(w, in + 70 * ch, 3, &d), LOOM_OK);
			CHECK_EQ_INT(loom_vol_writer_put_voxels(w, in + 73 * ch, 32, &d), LOOM_OK);
			CHECK_EQ_INT(loom_vol_writer_put_slices(w, in + 105 * ch, 3, &d), LOOM_OK);
			CHECK(!file_exists(tpath(name))); /* not before finish */
			CHECK_EQ_INT(loom_vol_writer_finish(w, &d), LOOM_OK);
			CHECK_EQ_INT(loom_vol_read(tpath(name), 0, &hr, &v, &d), LOOM_OK);
			if (v) {
				CHECK(v->nx == 7 && v->ny == 5 && v->nz == 6 && v->channels == ch);
				CHECK(hr.encoding == enc[e] && hr.bbox_max[0] == 3.5f);
				CHECK(fabs(v->spacing[0] - 3.5 / 6) < 1e-12 && v->origin[1] == -1.0);
				for (size_t i = 0; i < nval; i++)
					if (memcmp(&v->data[i], &want[i], 4) != 0)
						bad++;
				CHECK_EQ_INT(bad, 0);
				/* memory parse gives the same */
				{
					size_t n = 0;
					uint8_t *b = slurp(tpath(name), &n);
					loom_volbuf *v2 = NULL;
					CHECK_EQ_INT(loom_vol_parse(b, n, name, 0, NULL, &v2, &d), LOOM_OK);
					CHECK(v2 && memcmp(v2->data, v->data, nval * 4) == 0);
					loom_volbuf_free(v2);
					free(b);
				}
				/* random boxes against the whole volume */
				{
					loom_vol_reader *r = NULL;
					CHECK_EQ_INT(loom_vol_open(tpath(name), &r, &d), LOOM_OK);
					for (int k = 0; r && k < 20; k++) {
						uint32_t x0 = (uint32_t)(rnd() % 7), y0 = (uint32_t)(rnd() % 5),
						         z0 = (uint32_t)(rnd() % 6);
						uint32_t bx = 1 + (uint32_t)(rnd() % (7 - x0)),
						         by = 1 + (uint32_t)(rnd() % (5 - y0)),
						         bz = 1 + (uint32_t)(rnd() % (6 - z0));
						float *box = malloc((size_t)bx * by * bz * ch * 4);
						int diff = 0;
						CHECK_EQ_INT(loom_vol_read_box(r, x0, y0, z0, bx, by, bz, box, &d),
						             LOOM_OK);
						for (uint32_t z = 0; z < bz; z++)
							for (uint32_t y = 0; y < by; y++)
								for (uint32_t x = 0; x < bx; x++)
									for (uint32_t c = 0; c < ch; c++) {
										size_t a = (((size_t)z * by + y) * bx + x) * ch + c;
										size_t b = ((((size_t)z0 + z) * 5 + y0 + y) * 7 + x0 + x) * ch + c;
										diff += memcmp(&box[a], &v->data[b], 4) != 0;
									}
						CHECK_EQ_INT(diff, 0);
						free(box);
					}
					if (r) {
						CHECK_EQ_INT(loom_vol_read_box(r, 6, 0, 0, 2, 1, 1, in, &d),
						             LOOM_ERANGE);
						CHECK_STR_CONTAINS(d.message, "leaves the 7x5x6 volume");
						CHECK(loom_vol_reader_header(r)->zres == 6);
					}
					loom_vol_close(r);
				}
			}
			loom_volbuf_free(v);
			free(in);
			free(want);
		}
	CHECK_EQ_INT(temp_files_left(), 0);
}

/* Malformed headers: each with its code and a message fragment. */
static void vol_malformed(void)
{
	static const struct {
		const char *what;
		int ver, enc, x, y, z, ch;
		float bad_bb; /* 0: fine; else put into xmax */
		size_t len;   /* 0: header + exact data */
		int code;
		const char *frag;
	} cases[] = {
		{"short", 3, 1, 1, 1, 1, 1, 0, 17, LOOM_ETRUNCATED, "byte 17: header truncated"},
		{"version", 2, 1, 1, 1, 1, 1, 0, 0, LOOM_EVERSION, "byte 3: unsupported version 2"},
		{"enc0", 3, 0, 1, 1, 1, 1, 0, 0, LOOM_EFORMAT, "byte 4: unknown encoding 0"},
		{"enc5", 3, 5, 1, 1, 1, 1, 0, 0, LOOM_EFORMAT, "unknown encoding 5"},
		{"xres0", 3, 1, 0, 1, 1, 1, 0, 0, LOOM_EFORMAT, "byte 8: xres must be 1..2147483647, got 0"},
		{"yresneg", 3, 1, 1, -4, 1, 1, 0, 0, LOOM_EFORMAT, "byte 12: yres must be 1..2147483647, got -4"},
		{"zres0", 3, 3, 2, 2, 0, 1, 0, 0, LOOM_EFORMAT, "byte 16: zres"},
		{"ch0", 3, 1, 1, 1, 1, 0, 0, 0, LOOM_EFORMAT, "byte 20: channels must be at least 1, got 0"},
		{"chneg", 3, 3, 1, 1, 1, -1, 0, 0, LOOM_EFORMAT, "channels must be at least 1, got -1"},
		{"qdir1", 3, 4, 1, 1, 1, 1, 0, 0, LOOM_EFORMAT, "channels must be 3 for encoding 4"},
		{"ch65", 3, 1, 1, 1, 1, 65, 0, 0, LOOM_ERANGE, "65 channels, loom reads at most 64"},
		{"bbnan", 3, 1, 1, 1, 1, 1, NAN, 0, LOOM_EFORMAT, "byte 36: bounding box xmax is not finite"},
		{"bbinf", 3, 1, 1, 1, 1, 1, INFINITY, 0, LOOM_EFORMAT, "xmax is not finite"},
		{"trunc", 3, 1, 4, 4, 4, 1, 0, 48 + 100, LOOM_ETRUNCATED, "byte 148: truncated: 4x4x4 voxels x 1 float32 channels need 256 data bytes"},
		{"trunc0", 3, 3, 4, 4, 4, 3, 0, 48, LOOM_ETRUNCATED, "need 192 data bytes"},
		{"absurd", 3, 1, 100000, 100000, 100000, 3, 0, 48 + 8, LOOM_ETRUNCATED, "need 12000000000000000 data bytes"},
		{"overflow", 3, 1, 2147483647, 2147483647, 2147483647, 64, 0, 48, LOOM_ERANGE, "overflow"},
	};
	uint8_t *buf = calloc(1, 48 + 4096);
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		float bb[6] = {0, 0, 0, 1, 1, 1};
		loom_diag d = {0};
		loom_volbuf *v = (loom_volbuf *)1;
		loom_vol_header h;
		size_t len = cases[i].len;
		int rc;
		if (cases[i].bad_bb != 0)
			bb[3] = cases[i].bad_bb;
		vol_header(buf, cases[i].ver, cases[i].enc, cases[i].x, cases[i].y,
		           cases[i].z, cases[i].ch, bb);
		if (!len)
			len = 48 + 4;
		rc = loom_vol_parse(buf, len, cases[i].what, 0, &h, &v, &d);
		if (rc != cases[i].code)
			printf("  case %s: code %d (%s)\n", cases[i].what, rc, d.message);
		CHECK_EQ_INT(rc, cases[i].code);
		CHECK_STR_CONTAINS(d.message, cases[i].frag);
		CHECK_STR_CONTAINS(d.message, cases[i].what); /* the name */
		CHECK(v == NULL);
		/* the same through a file */
		spit(tpath("bad.vol"), buf, len);
		v = NULL;
		CHECK_EQ_INT(loom_vol_read(tpath("bad.vol"), 0, NULL, &v, &d), cases[i].code);
		CHECK_STR_CONTAINS(d.message, cases[i].frag);
	}
	/* bad magic */
	{
		loom_diag d = {0};
		loom_volbuf *v;
		vol_header(buf, 3, 1, 1, 1, 1, 1, unit_bb);
		buf[2] = 'X';
		CHECK_EQ_INT(loom_vol_parse(buf, 52, "m", 0, NULL, &v, &d), LOOM_EFORMAT);
		CHECK_STR_CONTAINS(d.message, "byte 0: expected magic \"VOL\", got bytes 0x56 0x4f 0x58");
	}
	/* trailing bytes: a warning, not an error */
	{
		loom_diag d = {0};
		loom_volbuf *v = NULL;
		vol_header(buf, 3, 3, 2, 1, 1, 1, unit_bb);
		CHECK_EQ_INT(loom_vol_parse(buf, 48 + 2 + 5, "t", 0, NULL, &v, &d), LOOM_OK);
		CHECK_EQ_INT(d.n_warnings, 1);
		loom_volbuf_free(v);
	}
	/* budget */
	{
		loom_diag d = {0};
		loom_volbuf *v = NULL;
		vol_header(buf, 3, 3, 16, 16, 16, 1, unit_bb);
		CHECK_EQ_INT(loom_vol_parse(buf, 48 + 4096, "b", 16383, NULL, &v, &d),
		             LOOM_EBUDGET);
		CHECK_STR_CONTAINS(d.message, "16384 bytes as floats, over the 16383-byte limit");
		CHECK_EQ_INT(loom_vol_parse(buf, 48 + 4096, "b", 16384, NULL, &v, &d), LOOM_OK);
		loom_volbuf_free(v);
	}
	/* missing file */
	{
		loom_diag d = {0};
		loom_vol_reader *r;
		CHECK_EQ_INT(loom_vol_open(tpath("none.vol"), &r, &d), LOOM_EIO);
		CHECK_STR_CONTAINS(d.message, "cannot open");
	}
	free(buf);
}

static void vol_writer_errors(void)
{
	loom_vol_header h = {LOOM_VOL_UINT8, 4, 3, 5, 1, {0, 0, 0}, {1, 1, 1}};
	float slice[12] = {0};
	loom_vol_writer *w = NULL;
	loom_diag d = {0};
	const char *p = tpath("werr.vol");

	/* too few slices: no file, no temporary */
	CHECK_EQ_INT(loom_vol_writer_open(p, &h, &w, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_slices(w, slice, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_slices(w, slice, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_voxels(w, slice, 5, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_finish(w, &d), LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(d.message, "only 2 of 5 z-slices written (29 of 60 voxels)");
	CHECK(!file_exists(p));
	CHECK_EQ_INT(temp_files_left(), 0);
	/* an existing file survives a failed rewrite */
	spit(p, "old", 3);
	CHECK_EQ_INT(loom_vol_writer_open(p, &h, &w, &d), LOOM_OK);
	for (int z = 0; z < 5; z++)
		CHECK_EQ_INT(loom_vol_writer_put_slices(w, slice, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_voxels(w, slice, 1, &d), LOOM_ERANGE);
	CHECK_STR_CONTAINS(d.message, "1 voxels appended after 60, the volume has only 60");
	CHECK_EQ_INT(loom_vol_writer_put_voxels(w, slice, 0, &d), LOOM_EUNUSABLE);
	CHECK_EQ_INT(loom_vol_writer_finish(w, &d), LOOM_EUNUSABLE);
	{
		size_t n = 0;
		uint8_t *b = slurp(p, &n);
		CHECK(b && n == 3 && memcmp(b, "old", 3) == 0);
		free(b);
	}
	/* abort */
	CHECK_EQ_INT(loom_vol_writer_open(tpath("ab.vol"), &h, &w, &d), LOOM_OK);
	loom_vol_writer_abort(w);
	loom_vol_writer_abort(NULL);
	CHECK(!file_exists(tpath("ab.vol")));
	CHECK_EQ_INT(temp_files_left(), 0);
	/* slices after a partial slice */
	CHECK_EQ_INT(loom_vol_writer_open(tpath("ps.vol"), &h, &w, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_voxels(w, slice, 3, &d), LOOM_OK);
	CHECK_EQ_INT(loom_vol_writer_put_slices(w, slice, 1, &d), LOOM_EINVAL);
	loom_vol_writer_abort(w);
	/* bad headers */
	h.encoding = 9;
	CHECK_EQ_INT(loom_vol_writer_open(p, &h, &w, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "unknown encoding 9");
	h.encoding = LOOM_VOL_QDIR;
	CHECK_EQ_INT(loom_vol_writer_open(p, &h, &w, &d), LOOM_EINVAL);
	h.encoding = LOOM_VOL_FLOAT32;
	h.bbox_min[1] = NAN;
	CHECK_EQ_INT(loom_vol_writer_open(p, &h, &w, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_vol_writer_open(tpath("nodir/x.vol"), &(loom_vol_header){1, 1, 1, 1, 1, {0, 0, 0}, {1, 1, 1}}, &w, &d),
	             LOOM_EIO);
	CHECK_EQ_INT(temp_files_left(), 0);
}

/* ---- raw ------------------------------------------------------------------ */

static void raw_round_trips(void)
{
	/* 3x2x2 with 2 channels: values by hand in each type and byte order */
	const uint32_t nx = 3, ny = 2, nz = 2, ch = 2, n = 24;
	uint8_t buf[16 + 24 * 8];
	rng_state = check_seed() + 2;
	for (int type = LOOM_SCALAR_U8; type <= LOOM_SCALAR_F64; type++)
		for (int big = 0; big <= 1; big++) {
			size_t es = loom_scalar_size(type), off = 16;
			double want[24];
			loom_raw_params p = LOOM_RAW_PARAMS_INIT;
			loom_volbuf *v = NULL;
			loom_diag d = {0};
			int bad = 0;
			memset(buf, 0xee, sizeof buf);
			for (uint32_t i = 0; i < n; i++) {
				uint64_t bits = 0;
				double val = 0;
				switch (type) {
				case LOOM_SCALAR_U8: val = (double)(rnd() % 256); bits = (uint64_t)val; break;
				case LOOM_SCALAR_I8: val = (double)((int)(rnd() % 256) - 128); bits = (uint8_t)(int8_t)val; break;
				case LOOM_SCALAR_U16: val = (double)(rnd() % 65536); bits = (uint64_t)val; break;
				case LOOM_SCALAR_I16: val = (double)((int)(rnd() % 65536) - 32768); bits = (uint16_t)(int16_t)val; break;
				case LOOM_SCALAR_U32: val = (double)(rnd() % 16777216); bits = (uint64_t)val; break;
				case LOOM_SCALAR_I32: val = (double)((int)(rnd() % 16777216) - 8388608); bits = (uint32_t)(int32_t)val; break;
				case LOOM_SCALAR_F16: bits = rnd() & 0x7bff; val = loom_half_to_float((uint16_t)bits); break;
				case LOOM_SCALAR_F32: { float f = rndf() * 100 - 50; uint32_t b; memcpy(&b, &f, 4); bits = b; val = f; break; }
				default: { double f = (double)(float)(rndf() * 100 - 50); memcpy(&bits, &f, 8); val = f; break; }
				}
				want[i] = val;
				for (size_t b = 0; b < es; b++) {
					uint8_t byte = (uint8_t)(bits >> (8 * b));
					buf[off + i * es + (big ? es - 1 - b : b)] = byte;
				}
			}
			p.nx = nx; p.ny = ny; p.nz = nz; p.channels = ch;
			p.type = type; p.big_endian = big; p.offset = off;
			p.spacing[2] = 0.25;
			CHECK_EQ_INT(loom_raw_parse(buf, off + n * es, "raw", &p, 0, &v, &d), LOOM_OK);
			for (uint32_t i = 0; v && i < n; i++)
				bad += v->data[i] != (float)want[i];
			CHECK_EQ_INT(bad, 0);
			if (v)
				CHECK(v->spacing[2] == 0.25 && v->source_type == type && v->channels == 2);
			loom_volbuf_free(v);
			/* through a file, whole and by slices */
			spit(tpath("r.raw"), buf, off + n * es);
			v = NULL;
			CHECK_EQ_INT(loom_raw_read(tpath("r.raw"), &p, 0, &v, &d), LOOM_OK);
			bad = 0;
			for (uint32_t i = 0; v && i < n; i++)
				bad += v->data[i] != (float)want[i];
			CHECK_EQ_INT(bad, 0);
			{
				loom_raw_reader *r = NULL;
				float sl[12];
				CHECK_EQ_INT(loom_raw_open(tpath("r.raw"), &p, &r, &d), LOOM_OK);
				CHECK_EQ_INT(loom_raw_read_slices(r, 1, 1, sl, &d), LOOM_OK);
				CHECK(v && memcmp(sl, v->data + 12, sizeof sl) == 0);
				CHECK_EQ_INT(loom_raw_read_slices(r, 1, 2, sl, &d), LOOM_ERANGE);
				loom_raw_close(r);
			}
			loom_volbuf_free(v);
		}
}

static void raw_sizes(void)
{
	uint8_t buf[200];
	loom_raw_params p = LOOM_RAW_PARAMS_INIT;
	loom_volbuf *v = NULL;
	loom_diag d = {0};

	for (int i = 0; i < 200; i++)
		buf[i] = (uint8_t)i;
	p.nx = 4; p.ny = 5; p.nz = 3; p.type = LOOM_SCALAR_U16;
	/* 120 bytes needed */
	CHECK_EQ_INT(loom_raw_parse(buf, 119, "s", &p, 0, &v, &d), LOOM_ETRUNCATED);
	CHECK_STR_CONTAINS(d.message, "4x5x3 x 1 u16 values need 120 bytes from byte 0");
	CHECK_STR_CONTAINS(d.message, "the file has 119 bytes");
	CHECK_EQ_INT(loom_raw_parse(buf, 121, "s", &p, 0, &v, &d), LOOM_ECORRUPT);
	CHECK_STR_CONTAINS(d.message, "size mismatch");
	CHECK_STR_CONTAINS(d.message, "1 extra bytes at byte 120");
	p.flags = LOOM_RAW_ALLOW_TRAILING;
	CHECK_EQ_INT(loom_raw_parse(buf, 121, "s", &p, 0, &v, &d), LOOM_OK);
	loom_volbuf_free(v);
	/* data at the end: skip an unknown header */
	p.flags = LOOM_RAW_DATA_AT_END;
	p.type = LOOM_SCALAR_U8;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_OK);
	CHECK(v && v->data[0] == 140.0f && v->data[59] == 199.0f);
	loom_volbuf_free(v);
	/* normalise */
	p.flags = LOOM_RAW_NORMALIZE;
	p.offset = 140;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_OK);
	CHECK(v && v->data[0] == 140.0f / 255.0f);
	loom_volbuf_free(v);
	/* offset beyond the end */
	p.flags = 0;
	p.offset = 300;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_ETRUNCATED);
	/* bad parameters */
	p.offset = 0;
	p.nz = 0;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "4x5x0");
	p.nz = 3;
	p.type = 42;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_EINVAL);
	p.type = LOOM_SCALAR_U8;
	p.size = 8;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "LOOM_RAW_PARAMS_INIT");
	p.size = sizeof p;
	p.nx = p.ny = p.nz = 4000000;
	p.channels = 4000000;
	p.type = LOOM_SCALAR_F64;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 0, &v, &d), LOOM_ERANGE);
	/* budget */
	p.nx = 10; p.ny = 10; p.nz = 2; p.channels = 1; p.type = LOOM_SCALAR_U8;
	CHECK_EQ_INT(loom_raw_parse(buf, 200, "s", &p, 799, &v, &d), LOOM_EBUDGET);
	CHECK_EQ_INT(loom_raw_read(tpath("missing.raw"), &p, 0, &v, &d), LOOM_EIO);
	CHECK(v == NULL);
}

/* ---- NRRD -------------------------------------------------------------- */

static int have_unu(void)
{
	return system("command -v teem-unu >/dev/null 2>&1") == 0;
}

static int sh(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int sh(const char *fmt, ...)
{
	char cmd[sizeof tmpdir + 256];
	va_list ap;
	int rc;
	va_start(ap, fmt);
	vsnprintf(cmd, sizeof cmd, fmt, ap);
	va_end(ap);
	rc = system(cmd);
	if (rc != 0)
		printf("  command failed (%d): %s\n", rc, cmd);
	return rc;
}

static int same_floats(const float *a, const float *b, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (a[i] != b[i]) {
			printf("  value %zu: %g != %g\n", i, a[i], b[i]);
			return 0;
		}
	return 1;
}

/* Files written by unu, read back and compared with the raw values. */
static void nrrd_from_unu(void)
{
	enum { NX = 4, NY = 5, NZ = 6, N = NX * NY * NZ };
	uint8_t u8[N];
	uint16_t u16le[N];
	uint8_t u16be[2 * N];
	float f3[3 * N], ref8[N], ref16[N];
	loom_volbuf *v = NULL;
	loom_nrrd_info info;
	loom_diag d = {0};
	const char *dir = tmpdir;

	if (!have_unu()) {
		printf("  teem-unu not found (install teem-apps: tools/deps.sh test)\n");
		CHECK(0);
		return;
	}
	for (int i = 0; i < N; i++) {
		u8[i] = (uint8_t)(i * 7 + 3);
		u16le[i] = (uint16_t)(i * 523 + 11);
		u16be[2 * i] = (uint8_t)(u16le[i] >> 8);
		u16be[2 * i + 1] = (uint8_t)u16le[i];
		ref8[i] = u8[i];
		ref16[i] = u16le[i];
	}
	for (int i = 0; i < 3 * N; i++)
		f3[i] = (float)i * 0.25f - 7.0f;
	spit(tpath("u8.bin"), u8, N);
	spit(tpath("u16le.bin"), u16le, 2 * N); /* x86: little-endian */
	spit(tpath("u16be.bin"), u16be, 2 * N);
	spit(tpath("f3.bin"), f3, sizeof f3);

	/* the command of the brief: uchar raw, attached */
	CHECK_EQ_INT(sh("cd %s && teem-unu make -i u8.bin -t uchar -s 4 5 6 -e raw -o x.nrrd", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("x.nrrd"), 0, &info, &v, &d), LOOM_OK);
	if (v) {
		CHECK(v->nx == NX && v->ny == NY && v->nz == NZ && v->channels == 1);
		CHECK(same_floats(v->data, ref8, N));
		CHECK_EQ_INT(v->source_type, LOOM_SCALAR_U8);
		CHECK_EQ_INT(info.version, 1);
	}
	loom_volbuf_free(v);
	v = NULL;
	/* ushort, spacings; then gzip */
	CHECK_EQ_INT(sh("cd %s && teem-unu make -i u16le.bin -t ushort -s 4 5 6 -en little -e raw -sp 0.5 0.25 2 -o y.nrrd && teem-unu save -i y.nrrd -f nrrd -e gzip -o yg.nrrd", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("y.nrrd"), 0, &info, &v, &d), LOOM_OK);
	if (v) {
		CHECK(same_floats(v->data, ref16, N));
		CHECK(v->spacing[0] == 0.5 && v->spacing[1] == 0.25 && v->spacing[2] == 2.0);
	}
	loom_volbuf_free(v);
	v = NULL;
	CHECK_EQ_INT(loom_nrrd_read(tpath("yg.nrrd"), 0, &info, &v, &d), LOOM_OK);
	CHECK_EQ_INT(info.encoding, LOOM_NRRD_GZIP);
	if (v)
		CHECK(same_floats(v->data, ref16, N) && v->spacing[2] == 2.0);
	loom_volbuf_free(v);
	v = NULL;
	/* big-endian, detached header */
	CHECK_EQ_INT(sh("cd %s && teem-unu make -h -i u16be.bin -t ushort -s 4 5 6 -en big -e raw -o det.nhdr", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("det.nhdr"), 0, &info, &v, &d), LOOM_OK);
	CHECK_EQ_INT(info.big_endian, 1);
	CHECK(strstr(info.data_file, "u16be.bin") != NULL);
	if (v)
		CHECK(same_floats(v->data, ref16, N));
	loom_volbuf_free(v);
	v = NULL;
	/* streaming a detached raw volume by slices */
	{
		loom_raw_reader *r = NULL;
		float sl[NX * NY * 2];
		CHECK_EQ_INT(loom_nrrd_open(tpath("det.nhdr"), &info, &r, &d), LOOM_OK);
		CHECK_EQ_INT(loom_raw_read_slices(r, 3, 2, sl, &d), LOOM_OK);
		CHECK(same_floats(sl, ref16 + 3 * NX * NY, NX * NY * 2));
		loom_raw_close(r);
		CHECK_EQ_INT(loom_nrrd_open(tpath("yg.nrrd"), &info, &r, &d), LOOM_EUNSUPPORTED);
		CHECK_STR_CONTAINS(d.message, "gzip-encoded data cannot be streamed");
	}
	/* space directions and origin (NRRD0004) */
	CHECK_EQ_INT(sh("cd %s && teem-unu make -i u16le.bin -t ushort -s 4 5 6 -en little -e raw -spc LPS -orig '(1,2,3)' -dirs '(0.5,0,0) (0,0.5,0) (0,0,2)' -o s.nrrd", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("s.nrrd"), 0, &info, &v, &d), LOOM_OK);
	if (v) {
		CHECK(same_floats(v->data, ref16, N));
		CHECK(v->spacing[0] == 0.5 && v->spacing[1] == 0.5 && v->spacing[2] == 2.0);
		CHECK(v->origin[0] == 1.0 && v->origin[1] == 2.0 && v->origin[2] == 3.0);
		CHECK_EQ_INT(info.version, 4);
	}
	loom_volbuf_free(v);
	v = NULL;
	/* 4-D: a 3-vector per voxel; raw then ascii (unu writes "ASCII") */
	CHECK_EQ_INT(sh("cd %s && teem-unu make -i f3.bin -t float -s 3 4 5 6 -en little -e raw -k 3-vector space space space -o v.nrrd && teem-unu save -i v.nrrd -f nrrd -e ascii -o va.nrrd", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("v.nrrd"), 0, &info, &v, &d), LOOM_OK);
	if (v) {
		CHECK(v->channels == 3 && v->nx == NX && v->nz == NZ);
		CHECK(same_floats(v->data, f3, 3 * N));
	}
	loom_volbuf_free(v);
	v = NULL;
	CHECK_EQ_INT(loom_nrrd_read(tpath("va.nrrd"), 0, &info, &v, &d), LOOM_OK);
	CHECK_EQ_INT(info.encoding, LOOM_NRRD_ASCII);
	if (v)
		CHECK(v->channels == 3 && same_floats(v->data, f3, 3 * N));
	loom_volbuf_free(v);
	v = NULL;
	/* 3-D with a value axis first: an RGB slice */
	CHECK_EQ_INT(sh("cd %s && teem-unu make -i f3.bin -t float -s 3 20 6 -en little -e raw -k RGB-color space space -o rgb.nrrd", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("rgb.nrrd"), 0, &info, &v, &d), LOOM_OK);
	if (v)
		CHECK(v->channels == 3 && v->nx == 20 && v->ny == 6 && v->nz == 1 &&
		      same_floats(v->data, f3, 3 * N));
	loom_volbuf_free(v);
	v = NULL;
	/* line skip and byte skip in a detached header: unu agrees with us */
	{
		uint8_t blob[11 + 2 * N];
		memcpy(blob, "skip me\nxy", 10);
		blob[10] = 0x55;
		memcpy(blob + 11, u16le, 2 * N);
		spit(tpath("skip.bin"), blob, sizeof blob);
		CHECK_EQ_INT(sh("cd %s && teem-unu make -h -i skip.bin -t ushort -s 4 5 6 -en little -e raw -ls 1 -bs 3 -o skip.nhdr", dir), 0);
		CHECK_EQ_INT(loom_nrrd_read(tpath("skip.nhdr"), 0, &info, &v, &d), LOOM_OK);
		if (v)
			CHECK(same_floats(v->data, ref16, N));
		loom_volbuf_free(v);
		v = NULL;
		CHECK_EQ_INT(sh("cd %s && teem-unu make -h -i skip.bin -t ushort -s 4 5 6 -en little -e raw -bs -1 -o skipend.nhdr", dir), 0);
		CHECK_EQ_INT(loom_nrrd_read(tpath("skipend.nhdr"), 0, &info, &v, &d), LOOM_OK);
		if (v)
			CHECK(same_floats(v->data, ref16, N));
		loom_volbuf_free(v);
		v = NULL;
	}
}

/* Files we write by hand (NRRD0005, CRLF, comments, key/values, our own
   gzip): unu must read them the same way we do.  unu converts each to raw
   little-endian float, which we then compare with our reading. */
static void nrrd_to_unu(void)
{
	enum { N = 3 * 4 * 2 };
	const char *dir = tmpdir;
	uint8_t file[4096];
	size_t hl;
	short vals[N];
	loom_volbuf *ours = NULL, *theirs = NULL;
	loom_diag d = {0};
	char hdr[1024];

	if (!have_unu()) {
		CHECK(0);
		return;
	}
	for (int i = 0; i < N; i++)
		vals[i] = (short)(i * 1000 - 12000);
	/* big-endian short, CRLF lines, comments, key/value, NRRD0005 */
	hl = (size_t)snprintf(hdr, sizeof hdr,
	                      "NRRD0005\r\n# made by hand\r\ntype: short\r\ndimension: 3\r\n"
	                      "space dimension: 3\r\nsizes: 3 4 2\r\n"
	                      "space directions: (0.1,0,0) (0,0.2,0) (0,0,0.3)\r\n"
	                      "space origin: (-1,-2,-3)\r\nmy key:=my value\r\n"
	                      "endian: big\r\nencoding: raw\r\ncontent: hand\r\n\r\n");
	memcpy(file, hdr, hl);
	for (int i = 0; i < N; i++) {
		file[hl + 2 * i] = (uint8_t)((uint16_t)vals[i] >> 8);
		file[hl + 2 * i + 1] = (uint8_t)vals[i];
	}
	spit(tpath("hand.nrrd"), file, hl + 2 * N);
	CHECK_EQ_INT(loom_nrrd_read(tpath("hand.nrrd"), 0, NULL, &ours, &d), LOOM_OK);
	CHECK_EQ_INT(sh("cd %s && teem-unu convert -i hand.nrrd -t float | teem-unu save -f nrrd -e raw -en little -o hand_unu.nrrd", dir), 0);
	CHECK_EQ_INT(loom_nrrd_read(tpath("hand_unu.nrrd"), 0, NULL, &theirs, &d), LOOM_OK);
	if (ours && theirs) {
		CHECK(same_floats(ours->data, theirs->data, N));
		CHECK(ours->data[0] == -12000.0f && ours->data[N - 1] == 11000.0f);
		CHECK(fabs(ours->spacing[1] - 0.2) < 1e-15 && ours->origin[2] == -3.0);
		CHECK(fabs(theirs->spacing[1] - 0.2) < 1e-15 && theirs->origin[2] == -3.0);
	}
	loom_volbuf_free(ours);
	loom_volbuf_free(theirs);
	ours = theirs = NULL;
	/* the same file through our memory parser */
	CHECK_EQ_INT(loom_nrrd_parse(file, hl + 2 * N, "mem", 0, NULL, &ours, &d), LOOM_OK);
	CHECK(ours && ours->data[1] == -11000.0f);
	loom_volbuf_free(ours);
	ours = NULL;
	/* ascii with commas and uneven lines, dimension 2 */
	{
		const char *t = "NRRD0002\ntype: double\ndimension: 2\nsizes: 3 2\n"
		                "spacings: 1.5 2.5\nencoding: txt\n\n1.5, -2 3e2\n4\n5 6.25\n";
		spit(tpath("a.nrrd"), t, strlen(t));
		CHECK_EQ_INT(loom_nrrd_read(tpath("a.nrrd"), 0, NULL, &ours, &d), LOOM_OK);
		CHECK_EQ_INT(sh("cd %s && teem-unu convert -i a.nrrd -t float | teem-unu save -f nrrd -e raw -en little -o a_unu.nrrd", dir), 0);
		CHECK_EQ_INT(loom_nrrd_read(tpath("a_unu.nrrd"), 0, NULL, &theirs, &d), LOOM_OK);
		if (ours && theirs) {
			CHECK(ours->nx == 3 && ours->ny == 2 && ours->nz == 1);
			CHECK(same_floats(ours->data, theirs->data, 6));
			CHECK(ours->data[2] == 300.0f && ours->data[5] == 6.25f);
			CHECK(ours->spacing[1] == 2.5);
		}
		loom_volbuf_free(ours);
		loom_volbuf_free(theirs);
		ours = theirs = NULL;
	}
	/* gzip made by the gzip tool (not by Teem), the way a user would */
	{
		char cmd[sizeof tmpdir + 256];
		int ok;
		hl = (size_t)snprintf(hdr, sizeof hdr, "NRRD0004\ntype: short\ndimension: 3\n"
		                      "sizes: 3 4 2\nendian: little\nencoding: gzip\n\n");
		spit(tpath("g.raw"), vals, sizeof vals);
		spit(tpath("g.hdr"), hdr, hl);
		snprintf(cmd, sizeof cmd, "cd %s && gzip -c g.raw > g.gz && cat g.hdr g.gz > g.nrrd", dir);
		ok = system(cmd) == 0;
		CHECK(ok);
		CHECK_EQ_INT(loom_nrrd_read(tpath("g.nrrd"), 0, NULL, &ours, &d), LOOM_OK);
		CHECK_EQ_INT(sh("cd %s && teem-unu convert -i g.nrrd -t float | teem-unu save -f nrrd -e raw -en little -o g_unu.nrrd", dir), 0);
		CHECK_EQ_INT(loom_nrrd_read(tpath("g_unu.nrrd"), 0, NULL, &theirs, &d), LOOM_OK);
		if (ours && theirs)
			CHECK(same_floats(ours->data, theirs->data, N) && ours->data[3] == -9000.0f);
		loom_volbuf_free(ours);
		loom_volbuf_free(theirs);
	}
}

static void nrrd_malformed(void)
{
	static const struct {
		const char *what;
		const char *text;
		int code;
		const char *frag;
	} cases[] = {
		{"nomagic", "PNRD0001\n", LOOM_EFORMAT, "nomagic:1: expected magic"},
		{"magic9", "NRRD0009\ntype: uchar\n", LOOM_EVERSION, "NRRD0009 is newer"},
		{"magicx", "NRRD00x1\n", LOOM_EFORMAT, "NRRD0001\" .. \"NRRD0005"},
		{"notype", "NRRD0001\ndimension: 1\nsizes: 2\nencoding: raw\n\nab", LOOM_EFORMAT, "notype:6: header has no \"type\" field"},
		{"badtype", "NRRD0001\ntype: quad\n", LOOM_EFORMAT, "badtype:2: unknown type \"quad\""},
		{"int64", "NRRD0001\ntype: int64\n", LOOM_EUNSUPPORTED, "type \"int64\" is not supported"},
		{"block", "NRRD0001\ntype: block\n", LOOM_EUNSUPPORTED, "not supported"},
		{"dim5", "NRRD0001\ntype: uchar\ndimension: 5\n", LOOM_EUNSUPPORTED, "dim5:3: dimension 5: loom reads at most 4 axes"},
		{"dim0", "NRRD0001\ntype: uchar\ndimension: 0\n", LOOM_EFORMAT, "dimension must be 1..16"},
		{"sizesfirst", "NRRD0001\ntype: uchar\nsizes: 2 2\n", LOOM_EFORMAT, "sizesfirst:3: \"sizes\" before \"dimension\""},
		{"sizescount", "NRRD0001\ntype: uchar\ndimension: 3\nsizes: 2 2\n", LOOM_EFORMAT, "\"sizes\" needs 3 values (dimension), got 2"},
		{"sizesmany", "NRRD0001\ntype: uchar\ndimension: 2\nsizes: 2 2 2\n", LOOM_EFORMAT, "got more than 2"},
		{"size0", "NRRD0001\ntype: uchar\ndimension: 2\nsizes: 2 0\n", LOOM_EFORMAT, "size of axis 1 must be a positive integer, got \"0\""},
		{"sizehuge", "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 3000000000\nencoding: raw\n\n", LOOM_ERANGE, "over loom's limit"},
		{"noendian", "NRRD0001\ntype: ushort\ndimension: 1\nsizes: 2\nencoding: raw\n\nabcd", LOOM_EFORMAT, "no \"endian\" field, needed for u16 raw data"},
		{"badendian", "NRRD0001\ntype: ushort\nendian: middle\n", LOOM_EFORMAT, "endian must be little or big"},
		{"hex", "NRRD0001\ntype: uchar\nencoding: hex\n", LOOM_EUNSUPPORTED, "encoding \"hex\" is not supported"},
		{"bzip2", "NRRD0001\ntype: uchar\nencoding: bzip2\n", LOOM_EUNSUPPORTED, "loom reads raw, gzip and ascii"},
		{"badenc", "NRRD0001\ntype: uchar\nencoding: zip\n", LOOM_EFORMAT, "unknown encoding \"zip\""},
		{"list", "NRRD0004\ntype: uchar\ndata file: LIST\n", LOOM_EUNSUPPORTED, "LIST"},
		{"fmt", "NRRD0004\ntype: uchar\ndata file: slice%03d.raw 1 10 1\n", LOOM_EUNSUPPORTED, "numbered data files"},
		{"noend", "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 4\nencoding: raw\n", LOOM_ETRUNCATED, "no empty line ends the header"},
		{"nocolon", "NRRD0001\ntype uchar\n", LOOM_EFORMAT, "nocolon:2: expected \"field: value\" or \"key:=value\""},
		{"nospace", "NRRD0001\ntype:uchar\n", LOOM_EFORMAT, "expected \": \" or \":=\" after \"type\""},
		{"novalue", "NRRD0001\ntype:\n", LOOM_EFORMAT, "field \"type\" has no value"},
		{"dirnospace", "NRRD0004\ntype: uchar\ndimension: 1\nspace directions: (1,0,0)\n", LOOM_EFORMAT, "before \"space\" or \"space dimension\""},
		{"badvec", "NRRD0004\ntype: uchar\ndimension: 2\nspace: RAS\nspace directions: (1,0) (0,1,0)\n", LOOM_EFORMAT, "space direction of axis 0 must be"},
		{"badorigin", "NRRD0004\nspace: LPS\nspace origin: 1,2,3\n", LOOM_EFORMAT, "space origin must be a vector of 3 numbers"},
		{"badspace", "NRRD0004\nspace: nowhere\n", LOOM_EFORMAT, "unknown space \"nowhere\""},
		{"spacing", "NRRD0001\ndimension: 2\nspacings: 1 x\n", LOOM_EFORMAT, "spacing of axis 1 is not a number: \"x\""},
		{"skipgz", "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 1\nencoding: gzip\nbyte skip: -1\n\n", LOOM_EFORMAT, "byte skip -1 is only allowed with raw"},
		{"lineskip", "NRRD0001\nline skip: -2\n", LOOM_EFORMAT, "line skip must be >= 0"},
		{"dimtwice", "NRRD0001\ndimension: 1\ndimension: 1\n", LOOM_EFORMAT, "given twice"},
		{"short", "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 5\nencoding: raw\n\nabc", LOOM_ETRUNCATED, "truncated"},
		{"long", "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 2\nencoding: raw\n\nabc", LOOM_OK, ""},
		{"gzbad", "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 5\nencoding: gzip\n\nnot gzip at all", LOOM_ECORRUPT, "gzip data are corrupt"},
		{"gzsmall", "NRRD0001\ntype: uchar\ndimension: 3\nsizes: 1000 1000 1000\nencoding: gzip\n\nxx", LOOM_ETRUNCATED, "cannot hold the 1000000000 bytes"},
		{"asciishort", "NRRD0001\ntype: float\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1 2", LOOM_ETRUNCATED, "cannot hold"},
		{"asciibad", "NRRD0001\ntype: float\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1 two 3 4", LOOM_EFORMAT, "ascii value 1 is not a number: \"two\""},
		{"detached", "NRRD0004\ntype: uchar\ndimension: 1\nsizes: 2\nencoding: raw\ndata file: x.raw\n", LOOM_EUNSUPPORTED, "read the header with loom_nrrd_read"},
	};
	for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
		loom_diag d = {0};
		loom_volbuf *v = NULL;
		int rc = loom_nrrd_parse((const uint8_t *)cases[i].text,
		                         strlen(cases[i].text), cases[i].what, 0, NULL,
		                         &v, &d);
		if (rc != cases[i].code)
			printf("  case %s: code %d (%s)\n", cases[i].what, rc, d.message);
		CHECK_EQ_INT(rc, cases[i].code);
		CHECK_STR_CONTAINS(d.message, cases[i].frag);
		CHECK((v != NULL) == (cases[i].code == LOOM_OK));
		loom_volbuf_free(v);
	}
	/* unknown fields warn; trailing data warn */
	{
		const char *t = "NRRD0001\ntype: uchar\ndimension: 1\nsizes: 2\nfrobnicate: yes\n"
		                "encoding: raw\n\nabc";
		loom_diag d = {0};
		loom_volbuf *v = NULL;
		CHECK_EQ_INT(loom_nrrd_parse((const uint8_t *)t, strlen(t), "w", 0, NULL, &v, &d),
		             LOOM_OK);
		CHECK_EQ_INT(d.n_warnings, 2);
		CHECK(v && v->data[0] == 'a' && v->data[1] == 'b');
		loom_volbuf_free(v);
	}
	/* a detached header whose data file is missing */
	{
		const char *t = "NRRD0004\ntype: uchar\ndimension: 1\nsizes: 2\nencoding: raw\n"
		                "data file: nothere.raw\n";
		loom_diag d = {0};
		loom_volbuf *v = NULL;
		spit(tpath("lost.nhdr"), t, strlen(t));
		CHECK_EQ_INT(loom_nrrd_read(tpath("lost.nhdr"), 0, NULL, &v, &d), LOOM_EIO);
		CHECK_STR_CONTAINS(d.message, "nothere.raw: cannot open");
	}
	/* header info */
	{
		const char *t = "NRRD0005\ntype: float\ndimension: 3\nspace: RAS\nsizes: 2 3 4\n"
		                "space directions: (0,1,0) (2,0,0) (0,0,3)\nendian: little\n"
		                "encoding: raw\n\n";
		loom_nrrd_info info;
		loom_diag d = {0};
		CHECK_EQ_INT(loom_nrrd_parse_header(t, strlen(t), "i", &info, &d), LOOM_OK);
		CHECK(info.nx == 2 && info.ny == 3 && info.nz == 4 && info.channels == 1);
		CHECK(info.spacing[0] == 1.0 && info.spacing[1] == 2.0 && info.spacing[2] == 3.0);
		CHECK_EQ_INT(info.header_bytes, strlen(t));
		CHECK_EQ_INT(d.n_warnings, 1); /* not axis-aligned */
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_volio");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	RUN(half_exhaustive);
	RUN(half_rounding);
	RUN(scalar_names);
	RUN(vol_bytes_exact);
	RUN(vol_decode_by_hand);
	RUN(qdir_codes);
	RUN(vol_round_trips);
	RUN(vol_malformed);
	RUN(vol_writer_errors);
	RUN(raw_round_trips);
	RUN(raw_sizes);
	RUN(nrrd_from_unu);
	RUN(nrrd_to_unu);
	RUN(nrrd_malformed);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
