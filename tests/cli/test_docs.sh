# Docs match the code: every public function has an entry in docs/api.md,
# and every loom subcommand is documented somewhere in docs/ or README.md.
SUITE=docs
. "$LOOM_TOP/tests/cli/lib.sh"
cd "$LOOM_TOP" || exit 1
perl -ne 'print "$1\n" if /LOOM_API.*?\b(loom_[a-z0-9_]+)\s*\(/' engine/include/loom/*.h | sort -u >"$T/api"
missing=""
while read -r f; do
	grep -q "^### \`\?$f\b" docs/api.md 2>/dev/null || missing="$missing $f"
done <"$T/api"
if [ -z "$missing" ]; then pass api_documented; else fail api_documented "docs/api.md lacks:$missing"; fi
"$LOOM" --help | awk '/^commands:/{f=1;next} f && /^  [a-z]/{print $1} /^$/{if(f)exit}' >"$T/cmds"
missing=""
while read -r c; do
	grep -rq "loom $c" README.md docs/ || missing="$missing $c"
done <"$T/cmds"
if [ -z "$missing" ]; then pass commands_documented; else fail commands_documented "undocumented:$missing"; fi
