/*
 * tests/unit/test_voxel.c - voxel encodings (engine/exemplar/voxel.h): density
 * round trip, orientation error bound, v/-v identity, brick indexing.
 */
#include "check.h"
#include "exemplar/voxel.h"
#include "loom.h"

#include <math.h>

static uint64_t rng_state;
static double rnd(void)
{
	rng_state += 0x9e3779b97f4a7c15ull;
	uint64_t z = rng_state;
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	z ^= z >> 31;
	return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

/* Angle in degrees between the line through v and the decoded code. */
static double line_err_deg(const float v[3], uint16_t code)
{
	float d[3];
	double n, dot;

	loom__orient_decode(code, d);
	n = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
	dot = fabs((double)d[0] * v[0] + (double)d[1] * v[1] + (double)d[2] * v[2]) / n;
	if (dot > 1)
		dot = 1;
	return acos(dot) * 180.0 / M_PI;
}

static void test_density(void)
{
	for (int v = 0; v < 256; v++)
		CHECK_EQ_INT(loom__density_encode(loom__density_decode((uint8_t)v)), v);
	CHECK_EQ_INT(loom__density_encode(-1.0f), 0);
	CHECK_EQ_INT(loom__density_encode(NAN), 0);
	CHECK_EQ_INT(loom__density_encode(2.0f), 255);
	CHECK_EQ_INT(loom__density_encode(0.5f), 128); /* 127.5 rounds up */
}

static void test_orient_axes(void)
{
	/* hand-checked codes: +z is the centre of the square (s = t = 0 ->
	   q = round(127.5) = 128); +x: s = t = 1 -> 255; +y: s = 1, t = -1 */
	float z[3] = {0, 0, 1}, x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, d[3];

	CHECK_EQ_INT(loom_orientation_encode(z), 128 | 128 << 8);
	CHECK_EQ_INT(loom_orientation_encode(x), 255 | 255 << 8);
	CHECK_EQ_INT(loom_orientation_encode(y), 255 | 0 << 8);
	loom_orientation_decode(255 | 255 << 8, d);
	CHECK(fabsf(d[0] - 1) < 1e-6f && fabsf(d[1]) < 1e-6f && fabsf(d[2]) < 1e-6f);
	/* zero and non-finite vectors give code 0 */
	CHECK_EQ_INT(loom__orient_encode(0, 0, 0), 0);
	CHECK_EQ_INT(loom__orient_encode(NAN, 1, 0), 0);
	CHECK_EQ_INT(loom__orient_encode(INFINITY, 1, 0), 0);
	/* decoded vectors are unit length with z >= 0, for every code */
	for (uint32_t c = 0; c < 65536; c++) {
		float e[3], n;
		loom__orient_decode((uint16_t)c, e);
		n = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
		if (fabsf(n - 1) > 1e-5f || e[2] < 0) {
			CHECK(!"decoded vector not unit or below the equator");
			break;
		}
	}
}

static void test_orient_sign(void)
{
	int bad = 0;

	rng_state = check_seed();
	for (int i = 0; i < 200000 && !bad; i++) {
		float v[3], w[3];
		for (int k = 0; k < 3; k++)
			v[k] = (float)(2 * rnd() - 1);
		if (i % 3 == 0)
			v[2] = 0; /* equator: the fold must still identify v and -v */
		if (i % 7 == 0)
			v[1] = 0;
		for (int k = 0; k < 3; k++)
			w[k] = -v[k];
		if (loom__orient_encode(v[0], v[1], v[2]) != loom__orient_encode(w[0], w[1], w[2]))
			bad = 1;
		/* scale does not matter */
		if (loom__orient_encode(v[0], v[1], v[2]) !=
		    loom__orient_encode(4 * v[0], 4 * v[1], 4 * v[2]))
			bad = 1;
	}
	CHECK(!bad);
}

static void test_orient_error(void)
{
	double worst = 0, sum = 0;
	long n = 0;

	rng_state = check_seed() ^ 0x1234;
	/* uniform directions on the sphere */
	for (int i = 0; i < 1000000; i++) {
		double z = 2 * rnd() - 1, ph = 2 * M_PI * rnd(), r = sqrt(1 - z * z);
		float v[3] = {(float)(r * cos(ph)), (float)(r * sin(ph)), (float)z};
		double e = line_err_deg(v, loom__orient_encode(v[0], v[1], v[2]));
		if (e > worst)
			worst = e;
		sum += e;
		n++;
	}
	/* the worst region: around the octant centres |x| = |y| = |z| */
	for (int i = 0; i < 1000000; i++) {
		float v[3];
		for (int k = 0; k < 3; k++)
			v[k] = (float)(0.5 + 0.2 * rnd()) * ((i >> k) & 1 ? -1.0f : 1.0f);
		double e = line_err_deg(v, loom__orient_encode(v[0], v[1], v[2]));
		if (e > worst)
			worst = e;
	}
	printf("  orientation error: max %.4f deg, mean %.4f deg\n", worst, sum / (double)n);
	CHECK(worst <= LOOM__ORIENT_MAX_ERR_DEG);
	/* the bound is tight: the measured maximum is within 0.05 deg of it,
	   so a broken encoder cannot hide under a loose constant */
	CHECK(worst > LOOM__ORIENT_MAX_ERR_DEG - 0.05);
	CHECK(sum / (double)n < 0.3);
}

static void test_brick_index(void)
{
	/* 3 x 2 x 4 brick: index = (ly*bx + lx)*bz + lz */
	uint8_t b[3 * 2 * 4 * 4];
	size_t nv = 24;

	CHECK_EQ_INT(loom__brick_index(3, 4, 0, 0, 0), 0);
	CHECK_EQ_INT(loom__brick_index(3, 4, 0, 0, 3), 3);
	CHECK_EQ_INT(loom__brick_index(3, 4, 1, 0, 0), 4);
	CHECK_EQ_INT(loom__brick_index(3, 4, 0, 1, 0), 12);
	CHECK_EQ_INT(loom__brick_index(3, 4, 2, 1, 3), 23);
	memset(b, 0, sizeof b);
	b[nv + 5] = 0x34;
	b[2 * nv + 5] = 0x12;
	CHECK_EQ_INT(loom__brick_orient(b, nv, 5), 0x1234);
	CHECK_EQ_INT(loom__brick_plane(nv, LOOM__PLANE_LABEL), 72);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_voxel");
	RUN(test_density);
	RUN(test_orient_axes);
	RUN(test_orient_sign);
	RUN(test_orient_error);
	RUN(test_brick_index);
	CHECK_MAIN_END();
}
