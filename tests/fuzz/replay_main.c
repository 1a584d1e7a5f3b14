/*
 * tests/fuzz/replay_main.c - replays a fuzz target's corpus as a plain test.
 *
 *   replay_NAME DIR...   runs LLVMFuzzerTestOneInput on every file in DIR
 *
 * Prints "PASS replay_NAME/<file>" per input (a crash or sanitizer report
 * ends the run, which tests/run.sh counts as a failure).
 */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int cmp(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

static int replay_file(const char *prog, const char *path, const char *name)
{
	FILE *fp = fopen(path, "rb");
	uint8_t *buf;
	long n;

	if (!fp) {
		printf("FAIL %s/%s (cannot open)\n", prog, name);
		return 1;
	}
	fseek(fp, 0, SEEK_END);
	n = ftell(fp);
	fseek(fp, 0, SEEK_SET);
	buf = malloc(n > 0 ? (size_t)n : 1);
	if (!buf || (n > 0 && fread(buf, 1, (size_t)n, fp) != (size_t)n)) {
		printf("FAIL %s/%s (cannot read)\n", prog, name);
		free(buf);
		fclose(fp);
		return 1;
	}
	fclose(fp);
	LLVMFuzzerTestOneInput(buf, (size_t)n);
	free(buf);
	printf("PASS %s/%s\n", prog, name);
	fflush(stdout);
	return 0;
}

int main(int argc, char **argv)
{
	const char *prog = strrchr(argv[0], '/') ? strrchr(argv[0], '/') + 1 : argv[0];
	int bad = 0;

	for (int a = 1; a < argc; a++) {
		DIR *d = opendir(argv[a]);
		struct dirent *e;
		char **names = NULL;
		size_t n = 0, cap = 0;

		if (!d) {
			printf("FAIL %s (no corpus directory %s)\n", prog, argv[a]);
			bad = 1;
			continue;
		}
		while ((e = readdir(d))) {
			if (e->d_name[0] == '.')
				continue;
			if (n == cap) {
				cap = cap ? cap * 2 : 64;
				names = realloc(names, cap * sizeof *names);
			}
			names[n++] = strdup(e->d_name);
		}
		closedir(d);
		qsort(names, n, sizeof *names, cmp);
		for (size_t k = 0; k < n; k++) {
			char path[4096];
			snprintf(path, sizeof path, "%s/%s", argv[a], names[k]);
			bad |= replay_file(prog, path, names[k]);
			free(names[k]);
		}
		free(names);
	}
	return bad;
}
