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
# a budget too small names what it needs for the threads the preview runs:
# all CPUs by default (the texture reserved 16 threads' state before)
expect_exit budget_small 1 "$LOOM" preview "$F" --budget 0.01 -o "$T/x.png"
expect_err_contains budget_small_threads "with $(nproc) thread"
expect_exit budget_small_t3 1 "$LOOM" preview "$F" --budget 0.01 --threads 3 -o "$T/x.png"
expect_err_contains budget_small_t3_threads "with 3 threads"
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

# ---- orientation and anti-aliasing (read back with tests/cli/pngread.py) ----
export PYTHONPATH="$LOOM_TOP/tests/cli"
# twill 2/3: W(0,0) = 1 (warp over), W(4,0) = 0, W(0,1) = 0; the warp is light
# grey and the weft dark blue, so the centre of crossing (i, j) at 1:1 is
# bright exactly where W(i, j) = 1: pick 1 is the top row, end 1 the left.
expect_ok orient_synth "$LOOM" synth "$T/tw.pbm" --quiet -o "$T/o.loomf"
expect_ok orient_preview "$LOOM" preview "$T/o.loomf" --quiet -o "$T/o.png"
if python3 -B - "$T/o.png" "$T/tw.pbm" <<'PY' 2>"$T/pyerr"; then pass orient_top_left; else fail orient_top_left "$(tail -2 "$T/pyerr")"; fi
import re, sys, pngread
w, h, ch, px = pngread.read(sys.argv[1])
b = open(sys.argv[2], 'rb').read()
m = re.match(rb'P4\s+(\d+)\s+(\d+)\s', b)
cols, rows = int(m.group(1)), int(m.group(2))
data = b[m.end():]
W = lambda i, j: (data[i * ((cols + 7) // 8) + j // 8] >> (7 - j % 8)) & 1
bx, by = w // cols, h // rows          # voxels (= pixels) per crossing
def bright(i, j):  # mean over the crossing's central half (fibre-level
    # yarns: one pixel may fall on a ply seam, a gap or a hair)
    s = [pngread.luma(px[i * by + by // 2 + d], ch, j * bx + bx // 2 + e)
         for d in range(-(by // 4), by // 4 + 1)
         for e in range(-(bx // 4), bx // 4 + 1)]
    return sum(s) / len(s)
assert bright(0, 0) > bright(4, 0) + 30 and bright(0, 0) > bright(0, 1) + 30, \
    (bright(0, 0), bright(4, 0), bright(0, 1))
mean = sum(bright(i, j) for i in range(rows) for j in range(cols)) / (rows * cols)
agree = sum((bright(i, j) > mean) == bool(W(i, j)) for i in range(rows) for j in range(cols))
assert agree >= 0.95 * rows * cols, '%d of %d crossings' % (agree, rows * cols)
PY

# A motif woven in two satins (a red diamond, warp-faced, on a cream
# weft-faced ground, 120 x 120 crossings) previewed whole at 120 px: the
# preview, box-averaged to 12 x 12 cells, correlates with the colour
# drawdown box-averaged the same way (bound 0.9, docs/preview.md).
python3 -B - "$T/motif.ppm" <<'PY'
import sys
n = 120
with open(sys.argv[1], 'wb') as f:
    f.write(b'P6\n%d %d\n255\n' % (n, n))
    for y in range(n):
        for x in range(n):
            inside = abs(x - 60) + abs(y - 60) < 40 or (x < 20 and y < 20)
            f.write(b'\xc0\x00\x00' if inside else b'\xf0\xe8\xd0')
PY
cat >"$T/motif.map" <<'MAP'
yarn wine  #a01010
yarn cream #f0e8d0
colour #c00000 satin:4/1 warp=wine weft=cream
colour #f0e8d0 satin:1/4 warp=wine weft=cream
MAP
expect_ok motif_synth "$LOOM" synth "$T/motif.ppm" --map "$T/motif.map" --quiet -o "$T/m.loomf"
expect_ok motif_drawdown "$LOOM" pattern from-image "$T/motif.ppm" --map "$T/motif.map" -o "$T/m.pbm" -q
expect_ok motif_preview "$LOOM" preview "$T/m.loomf" --width 120 --json -o "$T/mp.png"
json_check motif_blocks "j['filter'] == 'blocks' and j['preview_bytes'] <= 16 * 2**20"
# the colour drawdown of the design: from the mapped design itself
expect_ok motif_color "$LOOM" pattern convert "$T/motif.ppm" --map "$T/motif.map" \
	--color -o "$T/mc.png"
if python3 -B - "$T/mp.png" "$T/mc.png" <<'PY' >"$T/out" 2>"$T/pyerr"; then pass motif_correlation; else fail motif_correlation "$(cat "$T/out") $(tail -2 "$T/pyerr")"; fi
import sys, pngread
a = pngread.boxes(*pngread.read(sys.argv[1]), 12, 12)
b = pngread.boxes(*pngread.read(sys.argv[2]), 12, 12)
r = pngread.correlation(a, b)
print('correlation %.3f' % r)
assert r > 0.9
PY
# the top-left corner square (20 x 20 crossings, warp-faced) is red in the
# preview: pick 1 at the top, end 1 at the left
if python3 -B - "$T/mp.png" <<'PY' 2>"$T/pyerr"; then pass motif_corner; else fail motif_corner "$(tail -2 "$T/pyerr")"; fi
import sys, pngread
w, h, ch, px = pngread.read(sys.argv[1])
def rgb(x0, y0):  # mean colour of the 8 x 6 pixels from (x0, y0)
    v = [px[y][3 * x + c] for y in range(y0, y0 + 6) for x in range(x0, x0 + 8) for c in range(3)]
    return [sum(v[c::3]) / (len(v) / 3) for c in range(3)]
tl, bl, tr = rgb(2, 2), rgb(2, h - 8), rgb(w - 10, 2)
assert tl[0] > tl[2] + 40, tl            # red
assert bl[2] > 120 and tr[2] > 120, (bl, tr)  # cream
PY
expect_ok scale_bar "$LOOM" preview "$T/m.loomf" --width 300 --scale-bar --json -o "$T/sb.png"
json_check scale_bar_json "j['scale_bar_mm'] > 0 and abs(j['size_mm'][0] - 120 * 24 * 0.024) < 1e-6"
mkdir -p "$T/dir.png"
expect_exit out_is_dir 1 "$LOOM" preview "$T/m.loomf" -o "$T/dir.png"
expect_err_contains out_is_dir_msg "is a directory"
expect_exit out_dir_missing 1 "$LOOM" preview "$T/m.loomf" -o "$T/no/such.png"
expect_err_contains out_dir_missing_msg "no/such.png"
