#!/bin/sh
# tests/cli/test_bench_vdb.sh - the peer benchmark checks itself: loom's
# looked-up values (point, ray, trilinear, density + orientation, and from
# cold below the working set) must sum to OpenVDB's, NanoVDB's and the
# dense array's, and a perturbed OpenVDB grid must be reported.  Runs when
# make built build/bench/bench_vdb (OpenVDB and NanoVDB installed:
# tools/deps.sh openvdb); otherwise says so and runs nothing.
SUITE=bench_vdb
. "$LOOM_TOP/tests/cli/lib.sh"

B=$LOOM_BUILD/bench/bench_vdb
if [ ! -x "$B" ]; then
	echo "SKIP $SUITE: $B not built (OpenVDB/NanoVDB not installed: tools/deps.sh openvdb)"
	exit 0
fi
export BUILD="$T/build"
mkdir -p "$BUILD/share/loom"
cp "$LOOM_BUILD/share/loom/default.ldb" "$BUILD/share/loom/"

expect_ok check_runs "$B" --check
expect_out_contains all_equal "bench_vdb: all checksums equal"
for m in "random points" "ray walks" "trilinear random" "trilinear rays" \
	"dens+orient random" "dens+orient rays" "budget  16 MiB" "budget  64 MiB"; do
	if grep -F -- "$m" "$T/out" | grep -q ' equal$'; then pass "equal:$m"; else
		fail "equal:$m" "no 'equal' row: $(grep -F -- "$m" "$T/out")"; fi
done
n=$(grep -c '^{"bench":"vdb_' "$T/out")
if [ "$n" -eq 9 ]; then pass json_lines; else fail json_lines "$n JSON lines, expected 9"; fi

BENCH_VDB_PERTURB=1 expect_exit perturbed_fails 1 "$B" --check
expect_out_contains perturbed_differs "CHECKSUMS DIFFER"
rm -rf "$T"
