# `loom demo` with an exemplar database (the tiny preset, so it is quick):
# the demo cloth's fabric, preview PNG/EXR and render exist and are valid,
# the files table lists them; the export stage's tiles when `loom export`
# is available.  (tests/cli/test_pattern.sh covers the design stages and a
# data directory without a database.)
SUITE=demo
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
D=$T/demo

png_check() {
	if python3 - "$2" <<'PY' 2>"$T/pyerr"; then pass "$1"; else fail "$1" "$(cat "$T/pyerr")"; fi
import struct, sys, zlib
b = open(sys.argv[1], 'rb').read()
assert b[:8] == b'\x89PNG\r\n\x1a\n', 'bad signature'
n, typ = struct.unpack('>I4s', b[8:16])
assert typ == b'IHDR' and n == 13, 'no IHDR'
w, h, depth, ct = struct.unpack('>IIBB', b[16:26])
assert w > 0 and h > 0 and depth == 8 and ct == 2, (w, h, depth, ct)
assert zlib.crc32(b[12:29]) == struct.unpack('>I', b[29:33])[0], 'IHDR CRC'
assert b[-8:-4] == b'IEND', 'no IEND'
PY
}

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
mkdir -p "$T/data"
LOOM_DATA="$T/data" "$LOOM" demo -o "$D" --db "$DB" >"$T/out" 2>"$T/err"
rc=$?
if [ $rc -eq 0 ]; then pass demo_runs; else fail demo_runs "exit $rc: $(head -c 400 "$T/err")"; fi
cp "$T/out" "$T/demo.out"
for f in cloth.loomf cloth-picture.png cloth-weave.png cloth-preview.png cloth-preview.exr cloth-render.png; do
	if [ -s "$D/$f" ]; then pass "exists_$f"; else fail "exists_$f" "no $D/$f"; fi
	if grep -qF "$D/$f" "$T/demo.out"; then pass "listed_$f"; else fail "listed_$f" "not in the files table"; fi
done
png_check preview_png "$D/cloth-preview.png"
png_check render_png "$D/cloth-render.png"
if command -v exrheader >/dev/null 2>&1; then
	expect_ok preview_exr exrheader "$D/cloth-preview.exr"
	expect_out_contains preview_exr_float "R, 32-bit floating-point"
else
	fail preview_exr "exrheader is not installed (tools/deps.sh test installs it)"
fi
expect_ok fabric_info "$LOOM" info "$D/cloth.loomf" --db "$DB"
expect_out_contains fabric_size "144 x 96 crossings"
if grep -q "files, .* bytes, in" "$T/demo.out"; then pass files_total; else fail files_total "no total line"; fi
for fmt in vol nrrd exr; do
	n=$(find "$D/export-$fmt" -type f 2>/dev/null | wc -l)
	if [ "$n" -gt 0 ]; then pass "export_$fmt"; else fail "export_$fmt" "no files in $D/export-$fmt"; fi
	if grep -qF "$D/export-$fmt/" "$T/demo.out"; then pass "listed_export_$fmt"; else fail "listed_export_$fmt" "not in the table"; fi
done
# a second run over the first with another cloth (another database, as
# after a new default): the exports start over instead of refusing the
# earlier run's manifests
expect_ok make_db2 "$LOOM" exemplar generate --preset tiny --seed 4 --quiet -o "$T/tiny4.ldb"
cp "$D/export-vol/manifest.json" "$T/manifest1.json"
LOOM_DATA="$T/data" "$LOOM" demo -o "$D" --db "$T/tiny4.ldb" >"$T/out2" 2>"$T/err2"
rc=$?
if [ $rc -eq 0 ]; then pass demo_rerun; else fail demo_rerun "exit $rc: $(head -c 400 "$T/err2")"; fi
if cmp -s "$D/export-vol/manifest.json" "$T/manifest1.json"; then
	fail demo_rerun_new_export "export-vol/manifest.json unchanged"
else
	pass demo_rerun_new_export
fi
