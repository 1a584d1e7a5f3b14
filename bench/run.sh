#!/bin/sh
# bench/run.sh - run every benchmark program; figures, never pass/fail.
# Each program prints a human table and JSON lines (prefixed "{").  All
# JSON lines are collected into $BUILD/bench/results.jsonl with the date
# and machine, for docs/performance.md.
set -u
BUILD=${BUILD:-build}
out=$BUILD/bench/results.jsonl
mkdir -p "$BUILD/bench"
{
	printf '{"bench":"machine","date":"%s","cpu":"%s","cores":%s,"kernel":"%s"}\n' \
		"$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
		"$(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //')" \
		"$(nproc)" "$(uname -r)"
} >"$out"
for b in "$BUILD"/bench/bench_*; do
	[ -x "$b" ] || continue
	echo "== $(basename "$b")"
	"$b" | tee "$BUILD/bench/$(basename "$b").log" | grep -v '^{'
	grep '^{' "$BUILD/bench/$(basename "$b").log" >>"$out"
done
# loom's renderer against Blender Cycles on an exported region (skipped,
# with a message, without Blender or OpenVDB)
echo "== cycles"
BUILD=$BUILD sh bench/cycles.sh | tee "$BUILD/bench/cycles.log" | grep -v '^{'
grep '^{' "$BUILD/bench/cycles.log" >>"$out"
echo "results: $out"
