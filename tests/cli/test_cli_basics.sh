# The loom command's top level: help, version, exit codes.
SUITE=cli_basics
. "$LOOM_TOP/tests/cli/lib.sh"
expect_ok help "$LOOM" --help
expect_out_contains help_lists_pattern "pattern"
expect_ok version "$LOOM" --version
expect_out_contains version_text "loom 0.1.0"
expect_exit no_args 2 "$LOOM"
expect_exit unknown_command 2 "$LOOM" frobnicate
expect_err_contains unknown_command_msg "unknown command 'frobnicate'"
# every command listed in --help has its own --help that exits 0
"$LOOM" --help | awk '/^commands:/{f=1;next} f && /^  [a-z]/{print $1} /^$/{if(f)exit}' >"$T/cmds"
count=0
while read -r c; do
	count=$((count+1))
	expect_ok "help_$c" "$LOOM" "$c" --help
done <"$T/cmds"
if [ "$count" -ge 2 ]; then pass commands_found; else fail commands_found "only $count commands in --help"; fi
