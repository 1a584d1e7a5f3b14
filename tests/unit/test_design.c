/* tests/unit/test_design.c - weave generators against hand-checked patterns. */
#include "check.h"
#include "loom.h"

/* Compare a generated repeat with rows of '1'/'0' (row = pick). */
static int same_as(const char *name, const char *const *rows)
{
	loom_weave_params p;
	loom_diag diag = {0};
	loom_design *d = NULL;
	int ok = 1;
	uint32_t nr = 0, nc = (uint32_t)strlen(rows[0]);

	while (rows[nr])
		nr++;
	if (loom_weave_parse(name, &p, &diag) != LOOM_OK) {
		printf("  parse %s: %s\n", name, diag.message);
		return 0;
	}
	if (loom_design_make(&p, 0, 0, &d, &diag) != LOOM_OK) {
		printf("  make %s: %s\n", name, diag.message);
		return 0;
	}
	if (d->rows != nr || d->cols != nc) {
		printf("  %s: size %ux%u, expected %ux%u\n", name, d->rows, d->cols, nr, nc);
		ok = 0;
	}
	for (uint32_t i = 0; ok && i < nr; i++)
		for (uint32_t j = 0; j < nc; j++)
			if (loom_design_at(d, i, j) != (uint8_t)(rows[i][j] - '0')) {
				printf("  %s: cell (%u,%u) is %u\n", name, i, j,
				       loom_design_at(d, i, j));
				ok = 0;
				break;
			}
	loom_design_free(d);
	return ok;
}

static void plain(void)
{
	static const char *const w[] = {"10", "01", NULL};
	CHECK(same_as("plain", w));
}

static void twill_2_3(void)
{
	/* column j floats over 2 picks starting at row j */
	static const char *const w[] = {
		"10001", "11000", "01100", "00110", "00011", NULL};
	CHECK(same_as("twill:2/3", w));
}

static void twill_2_3_s(void)
{
	/* S direction: start row s(j) = -j mod 5: 0,4,3,2,1; over=2: rows s(j), s(j)+1.  j=0: rows 0,1; j=1: rows 4,0; j=2: 3,4;
	   j=3: 2,3; j=4: 1,2. */
	static const char *const w3[] = {
		"11000", "10001", "00011", "00110", "01100", NULL};
	CHECK(same_as("twill:2/3:s", w3));
}

static void satin_1_4(void)
{
	/* move 2: column j over at row 2j mod 5 */
	static const char *const w[] = {
		"10000", "00010", "01000", "00001", "00100", NULL};
	CHECK(same_as("satin:1/4", w));
	CHECK(same_as("satin:1/4:move=2", w));
}

static void satin_4_1(void)
{
	static const char *const w[] = {
		"11101", "10111", "11110", "11011", "01111", NULL};
	CHECK(same_as("satin:4/1", w));
}

static void satin_rejects(void)
{
	loom_weave_params p;
	loom_diag diag = {0};

	CHECK_EQ_INT(loom_weave_parse("satin:1/5", &p, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "no valid move");
	CHECK_EQ_INT(loom_weave_parse("satin:1/7:move=1", &p, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "gives a twill");
	CHECK_EQ_INT(loom_weave_parse("satin:1/7:move=3", &p, &diag), LOOM_OK);
	CHECK_EQ_INT(loom_weave_parse("satin:2/6:move=2", &p, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "shares the factor 2");
	CHECK_EQ_INT(loom_weave_parse("satin:1/3", &p, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "at least 5");
	CHECK_EQ_INT(loom_weave_parse("twill:0/3", &p, &diag), LOOM_EINVAL);
	CHECK_EQ_INT(loom_weave_parse("cord", &p, &diag), LOOM_EINVAL);
	CHECK_STR_CONTAINS(diag.message, "unknown weave");
}

static void basket(void)
{
	static const char *const w[] = {"1100", "1100", "0011", "0011", NULL};
	CHECK(same_as("basket:2", w));
}

static void broken_twill_crowfoot(void)
{
	/* 2/2 broken twill, period 2: starts 0,1,3,2 */
	static const char *const w[] = {
		"1010", "1100", "0101", "0011", NULL};
	CHECK(same_as("broken-twill:2/2", w));
}

static void herringbone(void)
{
	/* 2/2, period 4: starts 0,1,2,3 then (3-t)+2: 1,0,3,2 */
	static const char *const w[] = {
		"10010110", "11001100", "01101001", "00110011", NULL};
	CHECK(same_as("herringbone:2/2", w));
}

static void wavy(void)
{
	/* 1/3 wavy twill, period 4: starts 0,1,2,3,2,1 */
	static const char *const w[] = {
		"100000", "010001", "001010", "000100", NULL};
	CHECK(same_as("wavy-twill:1/3", w));
}

static void names_roundtrip(void)
{
	const char *names[] = {"plain", "twill:2/3", "twill:1/3:s", "satin:1/7:move=3",
	                       "basket:2/3", "herringbone:2/2:period=6",
	                       "broken-twill:2/2", "wavy-twill:3/3:period=5"};
	for (size_t k = 0; k < sizeof names / sizeof names[0]; k++) {
		loom_weave_params p;
		char buf[64];
		CHECK_EQ_INT(loom_weave_parse(names[k], &p, NULL), LOOM_OK);
		CHECK_EQ_INT(loom_weave_name(&p, buf, sizeof buf), LOOM_OK);
		if (strcmp(buf, names[k]) != 0) {
			printf("  %s -> %s\n", names[k], buf);
			CHECK(0);
		}
	}
}

static void tiling_any_size(void)
{
	loom_weave_params p;
	loom_design *d;
	CHECK_EQ_INT(loom_weave_parse("twill:3/1", &p, NULL), LOOM_OK);
	CHECK_EQ_INT(loom_design_make(&p, 7, 9, &d, NULL), LOOM_OK);
	for (uint32_t i = 0; i < 7; i++)
		for (uint32_t j = 0; j < 9; j++)
			CHECK(loom_design_at(d, i, j) == loom_design_at(d, i % 4, j % 4));
	CHECK_EQ_INT(loom_design_validate(d, NULL), LOOM_OK);
	loom_design_free(d);
	loom_design_free(NULL);
}

static void bad_args(void)
{
	loom_design *d = (loom_design *)1;
	CHECK_EQ_INT(loom_design_new(0, 5, &d), LOOM_EINVAL);
	CHECK(d == NULL);
	CHECK_EQ_INT(loom_design_new(5, 5, NULL), LOOM_EINVAL);
	CHECK_EQ_INT(loom_design_new(LOOM_DESIGN_MAX_SIDE + 1, 5, &d), LOOM_ERANGE);
	CHECK(strcmp(loom_strerror(-1), "unknown error") == 0);
	CHECK(strcmp(loom_strerror(LOOM_OK), "success") == 0);
	CHECK(strcmp(loom_strerror(1 << 30), "unknown error") == 0);
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_design");
	RUN(plain);
	RUN(twill_2_3);
	RUN(twill_2_3_s);
	RUN(satin_1_4);
	RUN(satin_4_1);
	RUN(satin_rejects);
	RUN(basket);
	RUN(broken_twill_crowfoot);
	RUN(herringbone);
	RUN(wavy);
	RUN(names_roundtrip);
	RUN(tiling_any_size);
	RUN(bad_args);
	CHECK_MAIN_END();
}
