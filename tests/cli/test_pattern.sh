# `loom pattern` and `loom demo` end to end, as a user types them.
SUITE=pattern
. "$LOOM_TOP/tests/cli/lib.sh"
IMG=$DATA/images
cd "$T" || exit 1

# json_check NAME PYTHON-EXPR: stdout of the last command is valid JSON and
# the expression (over j = the parsed object) is true.
json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$T/out" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$T/out") $(head -c 300 "$T/pyerr")"; fi
}

# png_bits FILE: the pixels of a 1-bit grey PNG as rows of 0/1 (1 = black),
# decoded here with zlib, independently of libpng.
png_bits() {
	python3 - "$1" <<'EOF'
import struct, sys, zlib
data = open(sys.argv[1], 'rb').read()
assert data[:8] == b'\x89PNG\r\n\x1a\n'
pos, idat, w, h = 8, b'', 0, 0
while pos < len(data):
    n, kind = struct.unpack('>I4s', data[pos:pos + 8])
    body = data[pos + 8:pos + 8 + n]
    if kind == b'IHDR':
        w, h, depth, ctype = struct.unpack('>IIBB', body[:10])
        assert depth == 1 and ctype == 0, (depth, ctype)
    elif kind == b'IDAT':
        idat += body
    pos += 12 + n
raw, stride, prev = zlib.decompress(idat), (w + 7) // 8, None
for y in range(h):
    f, row = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
    prev = prev or bytearray(stride)
    for i in range(stride):
        a = row[i - 1] if i else 0
        b, c = prev[i], (prev[i - 1] if i else 0)
        p = a + b - c
        pred = [0, a, b, (a + b) // 2, a if abs(p - a) <= abs(p - b) and abs(p - a) <= abs(p - c) else (b if abs(p - b) <= abs(p - c) else c)][f]
        row[i] = (row[i] + pred) & 255
    prev = row
    print(''.join('0' if row[x >> 3] & (0x80 >> (x & 7)) else '1' for x in range(w)))
EOF
}

# pnm_values FILE: the samples of a binary P5, space-separated, one row a line.
pnm_values() {
	python3 - "$1" <<'EOF'
import sys
d = open(sys.argv[1], 'rb').read()
assert d[:2] == b'P5', d[:2]
head = d.split(b'\n', 3)
w, h = map(int, head[1].split())
pix = head[3]
for y in range(h):
    print(' '.join(str(v) for v in pix[y * w:(y + 1) * w]))
EOF
}

# ---- help and usage -----------------------------------------------------------
expect_ok help "$LOOM" pattern --help
expect_out_contains help_lists "from-image"
for c in make convert from-image info; do
	expect_ok "help_$c" "$LOOM" pattern "$c" --help
	expect_out_contains "help_${c}_usage" "usage: loom pattern $c"
	expect_exit "help_${c}_late" 0 "$LOOM" pattern "$c" x --help
done
expect_ok help_demo "$LOOM" demo --help
expect_exit no_subcommand 2 "$LOOM" pattern
expect_exit unknown_subcommand 2 "$LOOM" pattern frobnicate
expect_err_contains unknown_subcommand_msg "unknown command 'frobnicate'"

# ---- make -----------------------------------------------------------------------
expect_ok make_twill "$LOOM" pattern make twill:2/3 --size 5x5 -o t.pbm
expect_same make_twill_bytes t.pbm "$IMG/twill23_5x5.pbm"
expect_ok make_kind_options "$LOOM" pattern make twill --over 2 --under 3 --size=5x5 --output t2.pbm
expect_same make_kind_options_bytes t2.pbm "$IMG/twill23_5x5.pbm"
expect_ok make_default_size "$LOOM" pattern make twill:2/3 -o t3.pbm
expect_same make_default_size_bytes t3.pbm "$IMG/twill23_5x5.pbm"
expect_ok make_png "$LOOM" pattern make twill:2/3 --size 5x5 -o t.png
if [ "$(png_bits t.png | tr '\n' ' ')" = "10001 11000 01100 00110 00011 " ]; then
	pass make_png_pixels; else fail make_png_pixels "$(png_bits t.png 2>&1 | tr '\n' ' ')"; fi
expect_ok make_s_twill "$LOOM" pattern make twill:2/3 --direction s -o s.png
if [ "$(png_bits s.png | tr '\n' ' ')" = "11000 10001 00011 00110 01100 " ]; then
	pass make_s_twill_pixels; else fail make_s_twill_pixels "$(png_bits s.png 2>&1 | tr '\n' ' ')"; fi
expect_ok make_satin_move "$LOOM" pattern make satin --over 1 --under 4 --move 3 -o sat.pbm
expect_ok make_large "$LOOM" pattern make herringbone:2/2:period=4 --size 300x200 -o h.png
expect_exit make_no_output 2 "$LOOM" pattern make twill
expect_err_contains make_no_output_msg "missing -o OUT"
expect_exit make_no_kind 2 "$LOOM" pattern make -o x.pbm
expect_exit make_bad_kind 2 "$LOOM" pattern make twirl -o x.pbm
expect_err_contains make_bad_kind_msg "unknown weave 'twirl'"
expect_exit make_bad_satin 2 "$LOOM" pattern make satin:1/5 -o x.pbm
expect_err_contains make_bad_satin_msg "no valid move exists for a repeat of 6"
expect_exit make_bad_move 2 "$LOOM" pattern make satin:1/4 --move 1 -o x.pbm
expect_err_contains make_bad_move_msg "move 1 gives a twill"
expect_exit make_option_not_for_kind 2 "$LOOM" pattern make plain --over 2 -o x.pbm
expect_err_contains make_option_not_for_kind_msg "--over does not apply to plain"
expect_exit make_bad_size 2 "$LOOM" pattern make plain --size 0x5 -o x.pbm
expect_exit make_bad_size2 2 "$LOOM" pattern make plain --size abc -o x.pbm
expect_err_contains make_bad_size_msg "--size: expected MxN"
expect_exit make_bad_direction 2 "$LOOM" pattern make twill --direction x -o x.pbm
expect_exit make_bad_number 2 "$LOOM" pattern make twill --over two -o x.pbm
expect_exit make_bad_ext 2 "$LOOM" pattern make twill -o x.jpg
expect_err_contains make_bad_ext_msg "expected a .pbm or .png file name"
expect_exit make_unknown_option 2 "$LOOM" pattern make twill --frob -o x.pbm
expect_err_contains make_unknown_option_msg "unknown option '--frob'"
expect_exit make_extra_arg 2 "$LOOM" pattern make twill extra -o x.pbm
expect_exit make_missing_value 2 "$LOOM" pattern make twill -o
expect_exit make_unwritable 1 "$LOOM" pattern make twill -o no/such/dir/x.pbm
expect_err_contains make_unwritable_msg "cannot create"
if [ ! -e x.pbm ] && [ -z "$(ls | grep '\.tmp\.')" ]; then pass no_stray_files; else
	fail no_stray_files "$(ls)"; fi

# ---- convert -------------------------------------------------------------------
expect_ok convert_p1 "$LOOM" pattern convert "$IMG/twill23_plain.pbm" -o c.pbm
expect_same convert_p1_bytes c.pbm "$IMG/twill23_5x5.pbm"
expect_ok convert_to_png "$LOOM" pattern convert c.pbm -o c.png
expect_ok convert_back "$LOOM" pattern convert c.png -o c2.pbm
expect_same convert_roundtrip c2.pbm "$IMG/twill23_5x5.pbm"
expect_ok convert_wif "$LOOM" pattern convert "$IMG/tiny.wif" -o w.pbm
expect_ok convert_wif_expected "$LOOM" pattern convert "$IMG/tiny_expected.pbm" -o w_exp.pbm
expect_same convert_wif_drawdown w.pbm w_exp.pbm
expect_ok convert_maps "$LOOM" pattern convert "$IMG/twill23_plain.pbm" --warp-map "$IMG/ids.pgm" \
	-o m.png --write-warp-map warp.pgm --write-weft-map weft.pgm
if [ "$(pnm_values warp.pgm | tr '\n' '|')" = "0 0 0 0 2|0 0 0 0 2|0 0 0 0 2|0 0 0 0 2|0 0 0 0 2|" ] &&
   [ "$(pnm_values weft.pgm | tr '\n' '|')" = "1 1 1 1 1|1 1 1 1 1|1 1 1 1 1|1 1 1 1 1|1 1 1 1 1|" ]; then
	pass convert_maps_values; else fail convert_maps_values "$(pnm_values warp.pgm 2>&1 | tr '\n' '|')"; fi
expect_exit convert_missing 1 "$LOOM" pattern convert nothere.pbm -o x.pbm
expect_err_contains convert_missing_msg "nothere.pbm: cannot open"
expect_exit convert_three_levels 1 "$LOOM" pattern convert "$IMG/three_levels.pgm" -o x.pbm
expect_err_contains convert_three_levels_msg "has a third level (grey level 57"
printf 'P1\n2 2\n1 0\n' >short.pbm
expect_exit convert_truncated 1 "$LOOM" pattern convert short.pbm -o x.pbm
expect_err_contains convert_truncated_msg "short.pbm:3: data ends after 2 of 4 pixels"
expect_exit convert_map_size 1 "$LOOM" pattern convert t.pbm --warp-map "$IMG/three_levels.pgm" -o x.pbm
expect_err_contains convert_map_size_msg "warp-type map is 2x2 (width x height) but the weave has 5 ends x 5 picks"
expect_exit convert_no_output 2 "$LOOM" pattern convert t.pbm
expect_exit convert_no_input 2 "$LOOM" pattern convert -o x.pbm
expect_exit convert_bad_map_ext 2 "$LOOM" pattern convert t.pbm -o x.pbm --write-warp-map w.pbm
expect_err_contains convert_bad_map_ext_msg "type maps are written as .pgm or .png files"
expect_exit convert_two_inputs 2 "$LOOM" pattern convert t.pbm t2.pbm -o x.pbm

# ---- from-image ------------------------------------------------------------------
expect_ok from_image "$LOOM" pattern from-image "$IMG/motif.ppm" --map "$IMG/motif.map" -o f.pbm \
	--write-warp-map fw.pgm --write-weft-map ff.png
expect_ok from_image_expected "$LOOM" pattern convert "$IMG/motif_expected.pbm" -o f_exp.pbm
expect_same from_image_weave f.pbm f_exp.pbm
if [ "$(pnm_values fw.pgm | tr '\n' '|')" = "0 0 0 1 1 1|0 0 1 1 1 1|0 1 1 1 1 0|1 1 1 1 0 0|" ]; then
	pass from_image_warp_map; else fail from_image_warp_map "$(pnm_values fw.pgm 2>&1 | tr '\n' '|')"; fi
expect_ok from_image_info "$LOOM" pattern info "$IMG/motif.ppm" --map "$IMG/motif.map" --json
json_check from_image_info_types "[t['name'] for t in j['types']] == ['wine', 'leaf', 'cream'] and j['types'][1]['alignment'] == 0.2 and j['types'][1]['albedo'] == [0, 0.75, 0] and j['types_used'] == 3"
expect_exit from_image_no_map 2 "$LOOM" pattern from-image "$IMG/motif.ppm" -o x.pbm
expect_err_contains from_image_no_map_msg "missing --map MAPFILE"
expect_exit from_image_bad_map 1 "$LOOM" pattern from-image "$IMG/motif.ppm" --map "$IMG/motif_bad.map" -o x.pbm
expect_err_contains from_image_bad_map_msg "motif_bad.map:3: unknown yarn 'cream' for weft= (defined: wine, leaf)"
printf 'colour #c00000 plain\n' >partial.map
expect_exit from_image_unmapped 1 "$LOOM" pattern from-image "$IMG/motif.ppm" --map partial.map -o x.pbm
expect_err_contains from_image_unmapped_msg "partial.map: image colour #00c000 (first at pixel x=3, y=0) has no 'colour' line"
python3 -c 'import sys; sys.stdout.buffer.write(b"P6 10 10 255\n" + bytes(v for k in range(100) for v in (k, 0, 0)))' >many.ppm
expect_exit from_image_many_colours 1 "$LOOM" pattern from-image many.ppm --map partial.map -o x.pbm
expect_err_contains from_image_many_colours_msg "more than 64 colours"
expect_err_contains from_image_many_colours_hint "posterize"
expect_exit from_image_missing_map 1 "$LOOM" pattern from-image "$IMG/motif.ppm" --map nothere.map -o x.pbm
expect_err_contains from_image_missing_map_msg "nothere.map: cannot open"
printf 'colour #c00000 plain\ncolour #00c000 plain\ncolour #123456 plain\n' >extra.map
expect_ok from_image_warning "$LOOM" pattern from-image "$IMG/motif.ppm" --map extra.map -o x.pbm
expect_err_contains from_image_warning_msg "loom: warning: extra.map:3: colour #123456 does not occur in the image"
expect_ok from_image_quiet "$LOOM" pattern from-image "$IMG/motif.ppm" --map extra.map -o x.pbm --quiet
if [ ! -s "$T/err" ]; then pass from_image_quiet_silent; else fail from_image_quiet_silent "$(cat "$T/err")"; fi

# ---- info --------------------------------------------------------------------------
expect_ok info_text "$LOOM" pattern info t.pbm
expect_out_contains info_text_repeat "repeat       5 x 5"
expect_out_contains info_text_floats "weft floats  max 3, mean 3.00"
expect_ok info_json "$LOOM" pattern info t.pbm --json
if python3 -c 'import json,sys; json.load(sys.stdin)' <"$T/out" 2>/dev/null; then
	pass info_json_valid; else fail info_json_valid "$(head -c 300 "$T/out")"; fi
json_check info_json_values "j['rows'] == 5 and j['cols'] == 5 and j['repeat'] == [5, 5] and j['warp_floats'] == {'max': 2, 'mean': 2} and j['weft_floats'] == {'max': 3, 'mean': 3} and j['interlaced'] is True and j['warp_over'] == 10"
json_check info_json_types "[(t['id'], t['name']) for t in j['types']] == [(0, 'warp'), (1, 'weft')] and len(j['types'][0]['albedo']) == 3 and all(t['used'] for t in j['types'])"
expect_ok info_png_same "$LOOM" pattern info t.png --json
json_check info_png_values "j['repeat'] == [5, 5] and j['warp_over'] == 10"
expect_ok info_large "$LOOM" pattern info h.png --json
json_check info_large_repeat "j['rows'] == 300 and j['cols'] == 200 and j['repeat'] == [4, 8]"
expect_ok info_wif "$LOOM" pattern info "$IMG/tiny.wif" --json
json_check info_wif_values "j['rows'] == 4 and j['cols'] == 4 and j['repeat'] == [4, 4] and j['warp_floats']['max'] == 2"
expect_ok info_maps "$LOOM" pattern info t.pbm --warp-map "$IMG/ids.pgm" --json
json_check info_maps_types "len(j['types']) == 3 and j['types'][2]['name'] == 'type2' and j['types_used'] == 3"
expect_err_contains info_maps_warning "ids.pgm: type IDs up to 2 but the yarn table had 2 entries"
expect_exit info_missing 1 "$LOOM" pattern info nothere.png
expect_exit info_no_input 2 "$LOOM" pattern info --json
expect_exit info_no_output_option 2 "$LOOM" pattern info t.pbm -o x.pbm
printf 'not an image' >junk.png
expect_exit info_junk 1 "$LOOM" pattern info junk.png
expect_err_contains info_junk_msg "junk.png: not a PBM, PGM, PPM or PNG image"

# ---- demo ---------------------------------------------------------------------------
mkdir -p data_ok data_bad
cp "$IMG/tiny.wif" data_ok/
expect_ok demo_runs env LOOM_DATA="$T/data_ok" "$LOOM" demo -o demo_out
expect_out_contains demo_table_twill "twill-2-3"
expect_out_contains demo_table_jacquard "jacquard"
expect_out_contains demo_table_wif "tiny.wif"
missing=""
for f in twill-2-3 satin-1-4 herringbone-2-2 jacquard jacquard-picture tiny; do
	[ -s "demo_out/$f.png" ] || missing="$missing $f"
done
if [ -z "$missing" ]; then pass demo_files; else fail demo_files "missing:$missing"; fi
expect_ok demo_png_readable "$LOOM" pattern info demo_out/tiny.png --json
json_check demo_png_is_drawdown "j['rows'] == 4 and j['repeat'] == [4, 4]"
expect_ok demo_rerun env LOOM_DATA="$T/data_ok" "$LOOM" demo -o demo_out --quiet
if [ ! -s "$T/err" ]; then pass demo_quiet; else fail demo_quiet "$(cat "$T/err")"; fi
printf '[WIF]\nnonsense\n' >data_bad/broken.wif
expect_exit demo_bad_wif 1 env LOOM_DATA="$T/data_bad" "$LOOM" demo -o demo_bad
expect_err_contains demo_bad_wif_msg "broken.wif"
if [ -s demo_bad/twill-2-3.png ]; then pass demo_bad_wif_continues; else fail demo_bad_wif_continues "no twill-2-3.png"; fi
: >afile
expect_exit demo_dir_is_file 1 "$LOOM" demo -o afile
expect_exit demo_unknown_option 2 "$LOOM" demo --frob
