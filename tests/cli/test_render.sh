# `loom render` end to end: a small flat patch and a mesh (64 x 48 pixels,
# low spp), PNG read back (signature, IHDR size), EXR accepted by
# exrheader, determinism (same seed twice and on other thread counts gives
# identical bytes, another seed differs), JSON figures, exit codes.
SUITE=render
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
F=$T/tw.loomf

json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$T/out" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$T/out") $(head -c 300 "$T/pyerr")"; fi
}
png_check() {
	if python3 - "$2" "$3" "$4" <<'PY' 2>"$T/pyerr"; then pass "$1"; else fail "$1" "$(cat "$T/pyerr")"; fi
import struct, sys, zlib
b = open(sys.argv[1], 'rb').read()
assert b[:8] == b'\x89PNG\r\n\x1a\n', 'bad signature'
n, typ = struct.unpack('>I4s', b[8:16])
assert typ == b'IHDR' and n == 13, 'no IHDR'
w, h, depth, ct = struct.unpack('>IIBB', b[16:26])
assert (w, h, depth, ct) == (int(sys.argv[2]), int(sys.argv[3]), 8, 2), (w, h, depth, ct)
assert zlib.crc32(b[12:29]) == struct.unpack('>I', b[29:33])[0], 'IHDR CRC'
assert b[-8:-4] == b'IEND', 'no IEND'
PY
}

expect_ok help "$LOOM" render --help
expect_out_contains help_text "--spp"
expect_exit no_args 2 "$LOOM" render
expect_exit no_output 2 "$LOOM" render "$F"
expect_exit bad_ext 2 "$LOOM" render "$F" -o x.tif
expect_exit bad_spp 2 "$LOOM" render "$F" --spp 0 -o x.png
expect_exit bad_elevation 2 "$LOOM" render "$F" --elevation 95 -o x.png
expect_exit bad_filter 2 "$LOOM" render "$F" --filter cubic -o x.png
expect_exit region_with_mesh 2 "$LOOM" render "$F" --mesh m.obj --region 0,0:5,5 -o x.png
expect_exit thickness_without_mesh 2 "$LOOM" render "$F" --thickness 1 -o x.png
expect_exit unknown_opt 2 "$LOOM" render "$F" --frob -o x.png
expect_exit missing_fabric 1 "$LOOM" render "$T/nope.loomf" -o "$T/x.png"
expect_err_contains missing_fabric_msg "nope.loomf"
# the output is checked before any rendering (a missing directory, -o DIR)
expect_exit missing_out_dir 1 "$LOOM" render "$F" -o "$T/nodir/x.png"
expect_err_contains missing_out_dir_message "nodir"
mkdir -p "$T/adir.png"
expect_exit out_is_dir 1 "$LOOM" render "$F" -o "$T/adir.png"
expect_err_contains out_is_dir_message "is a directory"

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

R="--width 64 --height 48 --spp 2"
expect_ok flat "$LOOM" render "$F" $R --seed 7 -o "$T/a.png" --quiet
png_check flat_ihdr "$T/a.png" 64 48
if [ ! -s "$T/err" ]; then pass quiet_silent; else fail quiet_silent "$(cat "$T/err")"; fi
expect_ok flat_again "$LOOM" render "$F" $R --seed 7 -o "$T/b.png" --quiet
expect_same same_seed_same_bytes "$T/a.png" "$T/b.png"
expect_ok flat_threads "$LOOM" render "$F" $R --seed 7 --threads 1 -o "$T/c.png" --quiet
expect_same threads_same_bytes "$T/a.png" "$T/c.png"
expect_ok other_seed "$LOOM" render "$F" $R --seed 8 -o "$T/d.png" --quiet
if cmp -s "$T/a.png" "$T/d.png"; then fail seed_matters "seeds 7 and 8 gave the same bytes"; else pass seed_matters; fi
expect_ok json "$LOOM" render "$F" $R --json -o "$T/e.exr"
json_check json_fields "j['width'] == 64 and j['height'] == 48 and j['paths'] == 64*48*2 and j['scene'] == 'flat' and j['lookups'] > 0"
json_check json_grid "j['majorant'] == 'grid' and j['cells'] > 0 and j['majorant_bytes'] > 0"
# the majorant grid (default) against one global bound: same picture (EXR
# means within Monte Carlo error), fewer lookups
expect_ok global "$LOOM" render "$F" --width 32 --height 24 --spp 64 --majorant global --json -o "$T/g.exr"
cp "$T/out" "$T/g.json"
expect_ok grid "$LOOM" render "$F" --width 32 --height 24 --spp 64 --seed 9 --json -o "$T/h.exr"
if python3 - "$T/g.json" "$T/out" <<'PY' 2>"$T/pyerr"; then pass grid_fewer_lookups; else fail grid_fewer_lookups "$(cat "$T/pyerr")"; fi
import json, sys
g, h = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
assert g['majorant'] == 'global' and g['cells'] == 0, g
assert h['lookups'] * 2 < g['lookups'], (h['lookups'], g['lookups'])
PY
expect_exit majorant_with_mesh 2 "$LOOM" render "$F" --mesh m.obj --majorant global -o x.png
expect_exit sun_one_number 2 "$LOOM" render "$F" --sun 30 -o x.png
expect_exit sun_low 2 "$LOOM" render "$F" --sun 30,0 -o x.png
expect_exit sun_five 2 "$LOOM" render "$F" --sun 30,20,1,1,1 -o x.png
expect_exit sun_text 2 "$LOOM" render "$F" --sun 30,high -o x.png
expect_err_contains sun_msg "--sun"
expect_ok sun "$LOOM" render "$F" $R --sun 200,30,3,2 --quiet -o "$T/sun.png"
if cmp -s "$T/a.png" "$T/sun.png"; then fail sun_matters "--sun gave the default picture"; else pass sun_matters; fi
# --density-scale is per millimetre: per voxel = K * voxel_mm (tiny: 72 um)
expect_ok density_mm "$LOOM" render "$F" --width 8 --height 6 --spp 1 --density-scale 50 --json -o "$T/dm.png"
json_check density_per_voxel "abs(j['density_per_voxel'] - 50 * j['voxel_mm']) < 1e-9 and abs(j['voxel_mm'] - 0.072) < 1e-6"
expect_ok density_voxel "$LOOM" render "$F" --width 8 --height 6 --spp 1 --density-per-voxel 3.6 --json -o "$T/dv.png"
json_check density_voxel_json "j['density_per_voxel'] == 3.6"
expect_exit density_both 2 "$LOOM" render "$F" --density-scale 50 --density-per-voxel 3 -o x.png
expect_err_contains density_both_msg "give one"
expect_exit bad_majorant 2 "$LOOM" render "$F" --majorant tight -o x.png
if command -v exrheader >/dev/null 2>&1; then
	expect_ok exrheader exrheader "$T/e.exr"
	expect_out_contains exr_size "(0 0) - (63 47)"
else
	fail exrheader "exrheader is not installed (tools/deps.sh test installs it)"
fi
# onto a mesh through the shell mapping
MESH=$DATA/meshes/quad.obj
if [ -f "$MESH" ]; then
	expect_ok mesh "$LOOM" render "$F" --mesh "$MESH" $R --json -o "$T/m.png"
	json_check mesh_json "j['scene'] == 'mesh' and j['shell_queries'] > 0"
	png_check mesh_ihdr "$T/m.png" 64 48
	expect_ok mesh_again "$LOOM" render "$F" --mesh "$MESH" $R --quiet -o "$T/m2.png"
	expect_same mesh_deterministic "$T/m.png" "$T/m2.png"
fi
expect_exit mesh_missing 1 "$LOOM" render "$F" --mesh "$T/nope.obj" $R -o "$T/x.png"
expect_err_contains mesh_missing_msg "nope.obj"
# Embree is loaded only for meshes: without it a flat render still works and
# a mesh render fails with a message naming the library, writing nothing
if [ -f "$MESH" ]; then
	expect_exit no_embree 1 env LOOM_EMBREE_LIBRARY=/nonexistent/libembree3.so.3 \
		"$LOOM" render "$F" --mesh "$MESH" $R --quiet -o "$T/noembree.png"
	expect_err_contains no_embree_msg "cannot load Embree 3 (/nonexistent/libembree3.so.3)"
	if [ -e "$T/noembree.png" ]; then fail no_embree_no_output "an image was written"
	else pass no_embree_no_output; fi
	expect_ok no_embree_flat env LOOM_EMBREE_LIBRARY=/nonexistent/libembree3.so.3 \
		"$LOOM" render "$F" $R --quiet -o "$T/flat-noembree.png"
fi
