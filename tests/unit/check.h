/*
 * tests/unit/check.h - the tiny test harness of loom's unit tests.
 *
 * Each test program is a list of TEST functions run by RUN().  Every RUN
 * prints "PASS <program>/<test>" or "FAIL <program>/<test>"; CHECK failures
 * print file:line and the expression first.  tests/run.sh counts the lines.
 * Randomised tests print their seed (CHECK_SEED) so a failure replays.
 */
#ifndef LOOM_CHECK_H
#define LOOM_CHECK_H

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int check_fail_count;   /* failed CHECKs in the current test */
static int check_tests_failed; /* failed tests in this program */
static const char *check_prog = "test";

#define CHECK(cond)                                                          \
	do {                                                                     \
		if (!(cond)) {                                                       \
			fprintf(stdout, "  %s:%d: CHECK(%s) failed\n", __FILE__,         \
			        __LINE__, #cond);                                        \
			check_fail_count++;                                              \
		}                                                                    \
	} while (0)

#define CHECK_EQ_INT(a, b)                                                   \
	do {                                                                     \
		long long check_a_ = (long long)(a), check_b_ = (long long)(b);      \
		if (check_a_ != check_b_) {                                          \
			fprintf(stdout, "  %s:%d: %s == %lld, expected %s == %lld\n",    \
			        __FILE__, __LINE__, #a, check_a_, #b, check_b_);         \
			check_fail_count++;                                              \
		}                                                                    \
	} while (0)

#define CHECK_STR_CONTAINS(hay, needle)                                      \
	do {                                                                     \
		const char *check_h_ = (hay);                                        \
		if (!check_h_ || !strstr(check_h_, (needle))) {                      \
			fprintf(stdout, "  %s:%d: \"%s\" does not contain \"%s\"\n",     \
			        __FILE__, __LINE__, check_h_ ? check_h_ : "(null)",      \
			        (needle));                                               \
			check_fail_count++;                                              \
		}                                                                    \
	} while (0)

#define RUN(fn)                                                              \
	do {                                                                     \
		check_fail_count = 0;                                                \
		fn();                                                                \
		printf("%s %s/%s\n", check_fail_count ? "FAIL" : "PASS", check_prog, \
		       #fn);                                                         \
		if (check_fail_count)                                                \
			check_tests_failed++;                                            \
		fflush(stdout);                                                      \
	} while (0)

#define CHECK_MAIN_BEGIN(name) check_prog = (name)
#define CHECK_MAIN_END() return check_tests_failed ? 1 : 0

/* Seed for randomised tests: $LOOM_TEST_SEED or a fixed default. */
static inline uint64_t check_seed(void)
{
	const char *s = getenv("LOOM_TEST_SEED");
	uint64_t seed = s ? strtoull(s, NULL, 0) : 20121126u;
	printf("  seed %" PRIu64 " (set LOOM_TEST_SEED to replay)\n", seed);
	return seed;
}

#endif
