/* bench/bench_usage.h - the bench programs' --help and argument checks.

   Every bench program names its usage in one string and calls
   bench_help() first: "-h" or "--help" anywhere prints the usage on
   stdout and exits 0, before any work (some benches generate a
   paper-scale database before their first figure).  An argument a bench
   does not take goes to bench_reject(): the argument and the usage on
   stderr, exit status 2.  C and C++ (bench_vdb.cpp) both include it. */
#ifndef LOOM_BENCH_USAGE_H
#define LOOM_BENCH_USAGE_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static inline void bench_help(int argc, char **argv, const char *usage)
{
	for (int i = 1; i < argc; i++)
		if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
			fputs(usage, stdout);
			exit(0);
		}
}

static inline void bench_reject(const char *prog, const char *arg, const char *usage)
{
	fprintf(stderr, "%s: unexpected argument '%s'\n%s", prog, arg, usage);
	exit(2);
}

/* 1 when s is a non-empty run of the digits in set (a PARTS argument). */
static inline int bench_digits_in(const char *s, const char *set)
{
	if (!*s)
		return 0;
	for (; *s; s++)
		if (!strchr(set, *s))
			return 0;
	return 1;
}

/* 1 when s is a decimal integer in [lo, hi]. */
static inline int bench_int_in(const char *s, long lo, long hi)
{
	char *end;
	long v = strtol(s, &end, 10);
	return *s && !*end && v >= lo && v <= hi;
}

#endif
