/*
 * tests/fuzz/unhex.c - write the binary seed files of a fuzz corpus from
 * their hex listing (tests/fuzz/seeds/NAME.hex), so that git holds text.
 *
 *   unhex LISTING DIR    one line per file: "NAME HEX" (whitespace inside
 *                        HEX allowed); '#' lines and blank lines skipped
 *
 * Exits 1 naming the line on a bad name or odd/non-hex digits.
 */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int hexval(int c)
{
	if (c >= '0' && c <= '9')
		return c - '0';
	c = tolower(c);
	return c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
}

int main(int argc, char **argv)
{
	char line[8192], path[8192 + 4096];
	FILE *in;
	unsigned ln = 0;

	if (argc != 3) {
		fprintf(stderr, "usage: unhex LISTING DIR\n");
		return 2;
	}
	if (!(in = fopen(argv[1], "r"))) {
		perror(argv[1]);
		return 1;
	}
	while (fgets(line, sizeof line, in)) {
		char *p = line, *name;
		FILE *out;
		int hi = -1;

		ln++;
		while (isspace((unsigned char)*p))
			p++;
		if (*p == '#' || *p == 0)
			continue;
		name = p;
		while (*p && !isspace((unsigned char)*p))
			p++;
		if (*p)
			*p++ = 0;
		if (strchr(name, '/') || name[0] == '.') {
			fprintf(stderr, "%s:%u: bad file name '%s'\n", argv[1], ln, name);
			return 1;
		}
		if (strlen(argv[2]) >= 4096) {
			fprintf(stderr, "unhex: directory name too long\n");
			return 1;
		}
		snprintf(path, sizeof path, "%s/%s", argv[2], name);
		if (!(out = fopen(path, "wb"))) {
			perror(path);
			return 1;
		}
		for (; *p; p++) {
			int v;
			if (isspace((unsigned char)*p))
				continue;
			if ((v = hexval((unsigned char)*p)) < 0) {
				fprintf(stderr, "%s:%u: '%c' is not a hex digit\n", argv[1], ln, *p);
				return 1;
			}
			if (hi < 0) {
				hi = v;
			} else {
				fputc(hi << 4 | v, out);
				hi = -1;
			}
		}
		if (hi >= 0) {
			fprintf(stderr, "%s:%u: odd number of hex digits\n", argv[1], ln);
			return 1;
		}
		if (fclose(out) != 0) {
			perror(path);
			return 1;
		}
	}
	fclose(in);
	return 0;
}
