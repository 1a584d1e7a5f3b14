# `loom preview` end to end: PNG (signature, IHDR size) and EXR (exrheader)
# outputs, height maps, regions, widths, determinism across thread counts,
# JSON figures, exit codes.
SUITE=preview
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
F=$T/tw.loomf

json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$T/out" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$T/out") $(head -c 300 "$T/pyerr")"; fi
}
# png_check NAME FILE W H COLOURTYPE: PNG signature and IHDR width, height,
# bit depth 8 and colour type (2 = RGB, 0 = grey)
png_check() {
	if python3 - "$2" "$3" "$4" "$5" <<'PY' 2>"$T/pyerr"; then pass "$1"; else fail "$1" "$(cat "$T/pyerr")"; fi
import struct, sys, zlib
b = open(sys.argv[1], 'rb').read()
assert b[:8] == b'\x89PNG\r\n\x1a\n', 'bad signature'
n, typ = struct.unpack('>I4s', b[8:16])
assert typ == b'IHDR' and n == 13, 'no IHDR'
w, h, depth, ct = struct.unpack('>IIBB', b[16:26])
assert (w, h, depth, ct) == (int(sys.argv[2]), int(sys.argv[3]), 8, int(sys.argv[4])), (w, h, depth, ct)
assert zlib.crc32(b[12:29]) == struct.unpack('>I', b[29:33])[0], 'IHDR CRC'
assert b[-8:-4] == b'IEND', 'no IEND'
PY
}

expect_ok help "$LOOM" preview --help
expect_out_contains help_text "--height-map"
expect_exit no_args 2 "$LOOM" preview
expect_exit no_output 2 "$LOOM" preview "$F"
expect_exit bad_ext 2 "$LOOM" preview "$F" -o x.jpg
expect_exit bad_region 2 "$LOOM" preview "$F" --region 1,2:0,5 -o x.png
expect_exit bad_region_dims 2 "$LOOM" preview "$F" --region 1,2,3:4,5 -o x.png
expect_exit bad_width 2 "$LOOM" preview "$F" --width 0 -o x.png
expect_exit bad_threshold 2 "$LOOM" preview "$F" --threshold 2 -o x.png
expect_exit unknown_opt 2 "$LOOM" preview "$F" --frob -o x.png
expect_exit missing_fabric 1 "$LOOM" preview "$T/nope.loomf" -o "$T/x.png"
expect_err_contains missing_fabric_msg "nope.loomf"

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

# default: one repeat at its own width (the tiny preset: 8x6 voxel blocks)
expect_ok png_default "$LOOM" preview "$F" -o "$T/a.png" --quiet
png_check png_default_ihdr "$T/a.png" 80 60 2
if [ ! -s "$T/err" ]; then pass quiet_silent; else fail quiet_silent "$(cat "$T/err")"; fi
expect_ok png_threads1 "$LOOM" preview "$F" -o "$T/b.png" --threads 1 --quiet
expect_same deterministic_threads "$T/a.png" "$T/b.png"
expect_ok png_width "$LOOM" preview "$F" --width 40 -o "$T/c.png" --quiet
png_check png_width_ihdr "$T/c.png" 40 30 2
expect_ok png_region "$LOOM" preview "$F" --region -100,-50:300,150 --width 64 \
	--height-map "$T/h.png" -o "$T/d.png" --json
png_check png_region_ihdr "$T/d.png" 64 32 2
png_check height_png_ihdr "$T/h.png" 64 32 0
json_check json_fields "j['width'] == 64 and j['height'] == 32 and j['region'][:2] == [-100, -50] and j['seconds'] >= 0"
expect_ok exr "$LOOM" preview "$F" --width 50 -o "$T/e.exr" --height-map "$T/h.exr" --quiet
if command -v exrheader >/dev/null 2>&1; then
	expect_ok exrheader_rgb exrheader "$T/e.exr"
	expect_out_contains exr_channels "R, 32-bit floating-point"
	expect_out_contains exr_size "(0 0) - (49 37)"
	expect_ok exrheader_height exrheader "$T/h.exr"
	expect_out_contains exr_height_channel "height, 32-bit floating-point"
else
	fail exrheader "exrheader is not installed (tools/deps.sh test installs it)"
fi
# a z range above the cloth: nothing on top (background only)
expect_ok z_range "$LOOM" preview "$F" --region 0,0,100:80,60,120 -o "$T/z.png" --quiet
png_check z_range_ihdr "$T/z.png" 80 60 2
expect_exit wrong_db 1 "$LOOM" preview "$F" --db "$T/nope.ldb" -o "$T/x.png"
