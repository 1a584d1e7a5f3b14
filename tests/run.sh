#!/bin/sh
# tests/run.sh - run every loom test and print "N passed, N failed".
# `sh tests/run.sh units`: the unit test programs only.
#
# Test programs and scripts print one line per test: "PASS name" or
# "FAIL name".  A program that exits non-zero without printing a FAIL line
# (a crash, a sanitizer report) counts as one failure.  Output of each
# program goes to $BUILD/test-logs/<name>.log; failures are shown in full.
set -u
BUILD=${BUILD:-build}
TOP=$(pwd)
LOGS=$BUILD/test-logs
rm -rf "$LOGS"
mkdir -p "$LOGS"
export LOOM="$TOP/$BUILD/loom"
export LOOM_BUILD="$TOP/$BUILD"
export LOOM_TOP="$TOP"
export LOOM_TEST_TMP="$TOP/$BUILD/test-tmp"
rm -rf "$LOOM_TEST_TMP"
mkdir -p "$LOOM_TEST_TMP"
# databases generated for a draft's sett go here, never to ~/.cache
export LOOM_CACHE_DIR="$LOOM_TEST_TMP/cache"

passed=0
failed=0

# a program that hangs fails after LOOM_TEST_TIMEOUT seconds (default 30
# minutes, far above any program's time under ThreadSanitizer) instead of
# holding the run until CI's own limit
TIMEOUT=${LOOM_TEST_TIMEOUT:-1800}
case $TIMEOUT in '' | *[!0-9]*) echo "run.sh: LOOM_TEST_TIMEOUT=$TIMEOUT: expected seconds" >&2; exit 2 ;; esac

run_one() { # run_one NAME COMMAND...
	name=$1; shift
	log=$LOGS/$name.log
	timeout -k 10 "$TIMEOUT" "$@" >"$log" 2>&1
	rc=$?
	p=$(grep -c '^PASS ' "$log")
	f=$(grep -c '^FAIL ' "$log")
	if [ "$rc" -eq 124 ]; then
		echo "FAIL $name (no end after $TIMEOUT s: stopped; LOOM_TEST_TIMEOUT)" >>"$log"
		f=$((f + 1))
	elif [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then
		echo "FAIL $name (exit status $rc)" >>"$log"
		f=1
	fi
	passed=$((passed + p))
	failed=$((failed + f))
	if [ "$f" -ne 0 ]; then
		echo "---- $name: $f failed ----"
		tail -n 60 "$log"
	else
		echo "  ok   $name ($p)"
	fi
}

for t in "$BUILD"/tests/test_*; do
	[ -x "$t" ] || continue
	run_one "$(basename "$t")" "$t"
done
if [ "${1:-}" = units ]; then # the unit programs only (make test-portable)
	echo "$passed passed, $failed failed"
	[ "$failed" -eq 0 ]
	exit
fi
for t in "$BUILD"/tests/replay_*; do
	[ -x "$t" ] || continue
	n=$(basename "$t" | sed 's/^replay_//')
	# seeds in git (tests/fuzz/corpus/NAME) and those written from hex text
	# by make (tests/fuzz/seeds/NAME.hex -> $BUILD/fuzz-corpus/NAME)
	dirs=""
	for d in "tests/fuzz/corpus/$n" "$BUILD/fuzz-corpus/$n"; do
		[ -d "$d" ] && dirs="$dirs $d"
	done
	# shellcheck disable=SC2086
	run_one "replay_$n" "$t" $dirs
done
for t in tests/cli/test_*.sh; do
	[ -f "$t" ] || continue
	run_one "cli_$(basename "$t" .sh)" sh "$t"
done
# checks against other programs that are installed only on request
# (tests/extra/blender.sh: tools/deps.sh blender); a SKIP line says why not
for t in tests/extra/*.sh; do
	[ -f "$t" ] || continue
	run_one "extra_$(basename "$t" .sh)" sh "$t"
	grep '^SKIP ' "$LOGS/extra_$(basename "$t" .sh).log"
done

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
