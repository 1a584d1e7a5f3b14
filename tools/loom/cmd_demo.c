/* placeholder: replaced by the real subcommand */
#include "cli.h"
#include "commands.h"
int cmd_demo(int argc, char **argv)
{
	(void)argc; (void)argv;
	fprintf(stderr, "loom demo: not implemented yet\n");
	return 1;
}
