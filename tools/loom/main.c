/*
 * tools/loom/main.c - the loom command: dispatch to subcommands.
 *
 * Exit status: 0 success, 1 bad input or failed operation, 2 usage error.
 */
#include "cli.h"
#include "commands.h"

#include <string.h>

static const struct command {
	const char *name;
	cli_cmd_fn fn;
	const char *summary;
} commands[] = {
	{"pattern", cmd_pattern, "make, convert, inspect weave patterns (WIF, PBM, PNG)"},
	{"exemplar", cmd_exemplar, "generate, inspect, verify, export exemplar databases"},
	{"synth", cmd_synth, "design + exemplar database -> fabric (assignment, edge fix)"},
	{"info", cmd_info, "describe a fabric file: sizes, parameters, metrics, database"},
	{"sample", cmd_sample, "look voxels of a fabric up: one position, or random lookups timed"},
	{"export", cmd_export, "stream a region or the whole bolt to tiles (.vol, NRRD, EXR)"},
	{"scan", cmd_scan, "stream voxels through a reducer (checksum, histogram, coverage)"},
	{"preview", cmd_preview, "picture of a fabric from above (PNG or EXR)"},
	{"render", cmd_render, "path-trace a fabric, flat or mapped onto a mesh"},
	{"look", cmd_look, "one draft -> drawdown, draft, previews, progressive render"},
	{"serve", cmd_serve, "deep-zoom viewer of a fabric or draft in the browser"},
	{"paint", cmd_paint, "paint a region: yarn colour, stain or defect (paint file)"},
	{"compare", cmd_compare, "compare two cloths (fabrics, exemplars): top yarn, heights, seams"},
	{"demo", cmd_demo, "run the main job on the built-in default data"},
};

static void usage(FILE *fp)
{
	fprintf(fp,
	        "usage: loom COMMAND [ARGS...]\n"
	        "\n"
	        "loom builds volumetric models of woven cloth from a fabric design\n"
	        "and a database of volumetric exemplars (Zhao et al. 2012).\n"
	        "\n"
	        "commands:\n");
	for (size_t k = 0; k < sizeof commands / sizeof commands[0]; k++)
		fprintf(fp, "  %-10s %s\n", commands[k].name, commands[k].summary);
	fprintf(fp,
	        "\n"
	        "  loom COMMAND --help   options of one command\n"
	        "  loom --version        print the version\n"
	        "\n"
	        "Exit status: 0 success, 1 bad input or failed operation, 2 usage error.\n"
	        "Documentation: docs/ (README.md lists the pages).\n");
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		usage(stderr);
		return EXIT_USAGE;
	}
	if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
	    strcmp(argv[1], "help") == 0) {
		usage(stdout);
		return 0;
	}
	if (strcmp(argv[1], "--version") == 0 || strcmp(argv[1], "version") == 0) {
		printf("loom %s\n", loom_version());
		return 0;
	}
	for (size_t k = 0; k < sizeof commands / sizeof commands[0]; k++)
		if (strcmp(argv[1], commands[k].name) == 0)
			return commands[k].fn(argc - 1, argv + 1);
	fprintf(stderr, "loom: unknown command '%s'\nTry 'loom --help'.\n", argv[1]);
	return EXIT_USAGE;
}
