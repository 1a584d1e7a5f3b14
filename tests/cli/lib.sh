# tests/cli/lib.sh - helpers for end-to-end tests of the loom command.
# Source it; each check prints "PASS name" or "FAIL name: why".
# $LOOM is the binary, $LOOM_TEST_TMP a scratch directory (set by run.sh).
: "${LOOM:?run through tests/run.sh}"
# without a scratch directory a suite would write into the working one
: "${LOOM_TEST_TMP:?set LOOM_TEST_TMP to a scratch directory}"
mkdir -p "$LOOM_TEST_TMP" || exit 1
T=$(mktemp -d "$LOOM_TEST_TMP/$(basename "$0" .sh).XXXXXX") || exit 1
[ -d "$T" ] || exit 1
DATA=$LOOM_TOP/tests/data

pass() { echo "PASS $SUITE/$1"; }
fail() { echo "FAIL $SUITE/$1: $2"; : >"$T/.failed" 2>/dev/null; }

# cleanup_tmp: at exit, $T goes unless a check failed (its files are then
# kept, and named, for a look).  A suite with its own EXIT trap calls it
# from there.
cleanup_tmp() {
	if [ -e "$T/.failed" ]; then echo "  files kept in $T"; else rm -rf "$T"; fi
}
trap cleanup_tmp EXIT

# expect_ok NAME CMD...: command exits 0
expect_ok() {
	n=$1; shift
	if "$@" >"$T/out" 2>"$T/err"; then pass "$n"; else
		fail "$n" "exit $? from: $* ; stderr: $(head -c 400 "$T/err")"; fi
}
# expect_exit NAME CODE CMD...: command exits with CODE
expect_exit() {
	n=$1; code=$2; shift 2
	"$@" >"$T/out" 2>"$T/err"
	rc=$?
	if [ "$rc" -eq "$code" ]; then pass "$n"; else
		fail "$n" "exit $rc, expected $code from: $* ; stderr: $(head -c 400 "$T/err")"; fi
}
# expect_err_contains NAME TEXT: last command's stderr contains TEXT
expect_err_contains() {
	if grep -qF -- "$2" "$T/err"; then pass "$1"; else
		fail "$1" "stderr lacks '$2': $(head -c 400 "$T/err")"; fi
}
# expect_out_contains NAME TEXT: last command's stdout contains TEXT
expect_out_contains() {
	if grep -qF -- "$2" "$T/out"; then pass "$1"; else
		fail "$1" "stdout lacks '$2': $(head -c 400 "$T/out")"; fi
}
# expect_same NAME FILE1 FILE2: files identical
expect_same() {
	if cmp -s "$2" "$3"; then pass "$1"; else fail "$1" "$2 and $3 differ"; fi
}
