#!/bin/sh
# tests/cli/test_bench_help.sh - every bench program answers --help with
# its usage and exit 0 before doing any work, and refuses an argument it
# does not take (exit 2, the argument named, the usage on stderr), so a
# typo never starts a minutes-long run or a paper-scale database build.
# make test builds the C benches; bench_vdb only where OpenVDB is
# installed (checked when built).
SUITE=bench_help
. "$LOOM_TOP/tests/cli/lib.sh"

# Each bench runs with BUILD in the scratch directory: a bench that
# started its work would create files there.
export BUILD="$T/build"
mkdir -p "$BUILD"
count=0
for src in "$LOOM_TOP"/bench/bench_*.c "$LOOM_TOP"/bench/bench_*.cpp; do
	name=$(basename "$src"); name=${name%.*}
	b=$LOOM_BUILD/bench/$name
	if [ ! -x "$b" ]; then
		case $src in
		*.cpp) echo "SKIP $SUITE/$name: not built (OpenVDB not installed)"; continue ;;
		esac
		fail "$name:built" "$b missing: make test should build every C bench"
		continue
	fi
	count=$((count + 1))
	expect_ok "$name:help" timeout 60 "$b" --help
	if [ "$(head -1 "$T/out")" = "$(printf 'usage: %s' "$name")" ] ||
	   head -1 "$T/out" | grep -q "^usage: $name "; then
		pass "$name:usage_line"
	else
		fail "$name:usage_line" "first line: $(head -1 "$T/out")"
	fi
	expect_exit "$name:unknown" 2 timeout 60 "$b" --no-such-option
	expect_err_contains "$name:named" "$name: unexpected argument '--no-such-option'"
	expect_err_contains "$name:usage_on_stderr" "usage: $name"
done
if [ -z "$(ls -A "$BUILD")" ]; then pass nothing_ran; else
	fail nothing_ran "files made under BUILD: $(ls "$BUILD")"; fi
if [ "$count" -ge 11 ]; then pass all_benches; else fail all_benches "$count benches checked, expected 11 or more"; fi
# positional arguments are checked too
expect_exit texture_parts 2 "$LOOM_BUILD/bench/bench_texture" 9
expect_err_contains texture_parts_named "unexpected argument '9'"
expect_exit wif_runs 2 "$LOOM_BUILD/bench/bench_wif" 0
expect_exit volio_size 2 "$LOOM_BUILD/bench/bench_volio" 8
# a malformed brick shape for bench_vdb's database: refused before any work
if [ -x "$LOOM_BUILD/bench/bench_vdb" ]; then
	BENCH_VDB_BRICK=16x16 expect_exit vdb_brick 2 "$LOOM_BUILD/bench/bench_vdb"
	expect_err_contains vdb_brick_named "BENCH_VDB_BRICK='16x16': expected XxYxZ"
	if [ -z "$(ls -A "$BUILD")" ]; then pass vdb_brick_nothing_ran; else
		fail vdb_brick_nothing_ran "files made under BUILD: $(ls "$BUILD")"; fi
fi
rm -rf "$T"
