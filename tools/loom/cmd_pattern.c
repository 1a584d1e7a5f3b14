/* placeholder: replaced by the real subcommand */
#include "cli.h"
#include "commands.h"
int cmd_pattern(int argc, char **argv)
{
	(void)argc; (void)argv;
	fprintf(stderr, "loom pattern: not implemented yet\n");
	return 1;
}
