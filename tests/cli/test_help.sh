# --help and the option tables agree (issue 11): for every command and
# subcommand, each option --help shows is one the parser takes, and each
# option of the table (the hidden --list-options) has a row in --help.
# Bad values give exit 2 and one wording:
#   loom CMD: --opt: expected WHAT, got 'TEXT'
#   Try 'loom CMD --help'.
SUITE=help
. "$LOOM_TOP/tests/cli/lib.sh"

# The commands of a --help text ("commands:" section), as in test_cli_basics.
cmds_of() {
	awk '/^commands:/{f=1;next} f && /^  [a-z]/{print $1} /^$/{if(f)exit}'
}

# Every command path: the top-level commands, the subcommands of those
# whose help lists commands, and the second form of exemplar generate.
: >"$T/paths"
"$LOOM" --help | cmds_of >"$T/top"
while read -r c; do
	"$LOOM" "$c" --help | cmds_of >"$T/subs"
	if [ -s "$T/subs" ]; then
		while read -r s; do echo "$c $s" >>"$T/paths"; done <"$T/subs"
	else
		echo "$c" >>"$T/paths"
	fi
done <"$T/top"
echo "exemplar generate --scan" >>"$T/paths"
n=$(wc -l <"$T/paths")
if [ "$n" -ge 15 ]; then pass paths_found; else fail paths_found "only $n command paths"; fi

# Option names in a text: -x or --name, not inside a word ("8-bit", "F-orient").
tokens() {
	grep -oE '(^|[^A-Za-z0-9_./-])--?[A-Za-z][A-Za-z0-9-]*' | sed 's/^[^-]*//' | sort -u
}

while read -r p; do
	name=$(echo "$p" | tr ' ' '_')
	# shellcheck disable=SC2086
	if ! "$LOOM" $p --help >"$T/help" 2>"$T/err"; then
		fail "help_$name" "loom $p --help: $(head -c 300 "$T/err")"
		continue
	fi
	# shellcheck disable=SC2086
	if ! "$LOOM" $p --list-options >"$T/list" 2>"$T/err"; then
		fail "list_$name" "loom $p --list-options: $(head -c 300 "$T/err")"
		continue
	fi
	sed 's/=.*//' "$T/list" | sort -u >"$T/table"

	# 1. every option shown anywhere in --help is in the table
	tokens <"$T/help" >"$T/shown"
	extra=$(comm -23 "$T/shown" "$T/table" | tr '\n' ' ')
	if [ -z "$extra" ]; then pass "shown_in_table_$name"; else
		fail "shown_in_table_$name" "loom $p --help shows options the parser lacks: $extra"; fi

	# 2. every option of the table has a row: "  -o, --output OUT  help"
	#    (the left part: up to the first two spaces after the indent)
	grep '^  -' "$T/help" | sed 's/^  //; s/  .*//' | tokens >"$T/rows"
	missing=$(comm -23 "$T/table" "$T/rows" | tr '\n' ' ')
	if [ -z "$missing" ]; then pass "table_in_rows_$name"; else
		fail "table_in_rows_$name" "loom $p --help has no row for: $missing"; fi

	# 3. the parser takes each of them: "OPT --help" (a flag) or
	#    "OPT=x --help" (a value; --help wins before values are checked)
	bad=""
	while read -r o; do
		case $o in
		*=*) arg="${o%%=*}=x" ;;
		*) arg=$o ;;
		esac
		# shellcheck disable=SC2086
		if ! "$LOOM" $p "$arg" --help >"$T/out2" 2>"$T/err2" ||
		   ! grep -q '^usage: ' "$T/out2"; then
			bad="$bad $arg"
		fi
	done <"$T/list"
	if [ -z "$bad" ]; then pass "parser_takes_$name"; else
		fail "parser_takes_$name" "loom $p rejects:$bad"; fi

	# 4. and nothing else
	# shellcheck disable=SC2086
	"$LOOM" $p --no-such-option --help >/dev/null 2>"$T/err"
	rc=$?
	if [ "$rc" -eq 2 ] && grep -qF "unknown option '--no-such-option'" "$T/err"; then
		pass "unknown_$name"; else fail "unknown_$name" "exit $rc: $(head -c 300 "$T/err")"; fi

	# 5. --help fits 79 columns
	wide=$(awk 'length($0) > 79 {print NR": "$0}' "$T/help" | head -n 3)
	if [ -z "$wide" ]; then pass "width_$name"; else fail "width_$name" "$wide"; fi
done <"$T/paths"

# ---- bad values: exit 2, one wording ------------------------------------------
# expect_bad NAME 'EXPECTED FIRST LINE' CMD...: exit 2, stderr is exactly that
# line and "Try 'PROG --help'." (PROG: the first line up to ': --').
expect_bad() {
	n=$1; want=$2; shift 2
	"$@" >"$T/out" 2>"$T/err"
	rc=$?
	prog=${want%%: --*}
	printf '%s\nTry %s --help%s.\n' "$want" "'$prog" "'" >"$T/want"
	if [ "$rc" -eq 2 ] && cmp -s "$T/err" "$T/want"; then pass "$n"; else
		fail "$n" "exit $rc, stderr: $(head -c 300 "$T/err") ; expected: $(cat "$T/want")"; fi
}
expect_bad threads_zero "loom sample: --threads: expected an integer in 1..1024, got '0'" \
	"$LOOM" sample f.loomf --random 5 --threads 0
expect_bad threads_range "loom scan: --threads: expected an integer in 1..256, got '257'" \
	"$LOOM" scan --threads=257
expect_bad threads_text "loom exemplar generate: --threads: expected an integer in 1..64, got 'two'" \
	"$LOOM" exemplar generate --threads two -o "$T/x.ldb"
expect_bad budget_negative "loom export: --budget: expected MiB in (0, 1048576], got '-1'" \
	"$LOOM" export f.loomf --budget -1
expect_bad budget_zero "loom sample: --budget: expected MiB in (0, 1048576], got '0'" \
	"$LOOM" sample --budget=0
expect_bad width_text "loom preview: --width: expected an integer in 1..65536, got 'abc'" \
	"$LOOM" preview f.loomf --width abc -o x.png
expect_bad width_render "loom render: --width: expected an integer in 1..65536, got '0'" \
	"$LOOM" render f.loomf --width 0 -o x.png
expect_bad seed_negative "loom synth: --seed: expected a non-negative integer, got '-1'" \
	"$LOOM" synth d.wif --seed=-1 -o x.loomf
expect_bad rank_range "loom synth: --rank: expected an integer in 0..128, got '129'" \
	"$LOOM" synth d.wif --rank 129 -o x.loomf
expect_bad enum_filter "loom render: --filter: expected nearest or trilinear, got 'cubic'" \
	"$LOOM" render f.loomf --filter cubic -o x.png
expect_bad enum_algo "loom synth: --algo: expected dp, greedy or naive, got 'best'" \
	"$LOOM" synth d.wif --algo best
expect_bad double_open "loom render: --elevation: expected degrees in (0, 90], got '0'" \
	"$LOOM" render f.loomf --elevation 0
expect_bad double_text "loom preview: --threshold: expected a density in (0, 1], got 'half'" \
	"$LOOM" preview f.loomf --threshold half
expect_bad size2 "loom exemplar build: --block: expected B1xB2 with each in 1..4096, got '0x4'" \
	"$LOOM" exemplar build s.vol --block 0x4
expect_bad size3 "loom exemplar build: --raw-dims: expected X,Y,Z (three positive integers), got '4,4'" \
	"$LOOM" exemplar build s.raw --raw-dims 4,4
expect_bad callback_at "loom sample: --at: expected three numbers X,Y,Z, got '1,2'" \
	"$LOOM" sample f.loomf --at 1,2
expect_bad callback_bolt "loom info: --bolt: expected LENGTHxWIDTH (repeats, or lengths with mm, cm or m: 10x2, 50mx1.5m), got '3'" \
	"$LOOM" info f.loomf --bolt 3
expect_bad callback_channel "loom exemplar export: --channel: expected density, label, kind, orientation or orient-code, got 'rgb'" \
	"$LOOM" exemplar export --channel rgb
# the first bad value on the command line is the one reported
expect_bad first_bad "loom render: --spp: expected an integer in 1..1000000, got '0'" \
	"$LOOM" render --spp 0 --width 0
