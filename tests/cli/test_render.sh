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
# the brick cache's figures: every request a hit, a miss or an empty brick;
# the tiny database fits the default budget (nothing evicted)
json_check json_texture "(lambda t: t['hits'] + t['misses'] + t['empty_bricks'] == t['brick_requests'] and t['misses'] > 0 and t['bytes_read'] > 0 and t['bytes_decompressed'] > t['bytes_read'] and t['evictions'] == 0 and 0 < t['hit_rate'] <= 1 and t['peak_cache_bytes'] <= t['budget_bytes'])(j['texture'])"
# at 1 MB the cache evicts, stays within its budget, and the picture is the
# same bytes (a texture value does not depend on what is cached)
expect_ok small_budget "$LOOM" render "$F" $R --seed 7 --threads 2 --budget 1 --json -o "$T/sb.png"
json_check small_budget_evicts "(lambda t: t['evictions'] > 0 and t['misses'] > t['evictions'] and t['peak_cache_bytes'] <= t['budget_bytes'] < 1048576 and t['hit_rate'] < 1)(j['texture'])"
expect_same small_budget_same_bytes "$T/a.png" "$T/sb.png"
expect_ok stats_line "$LOOM" render "$F" $R --seed 7 -o "$T/sl.png"
expect_err_contains stats_line_text "bricks: hit rate"
# a budget below the grid is refused before it is built (nothing written)
expect_exit grid_budget 1 "$LOOM" render "$F" $R --threads 2 --budget 0.1 -o "$T/nogrid.png"
expect_err_contains grid_budget_msg "cannot hold the majorant grid"
if [ -e "$T/nogrid.png" ]; then fail grid_budget_nothing "$T/nogrid.png written"; else
	pass grid_budget_nothing; fi
# the majorant grid (default) against one global bound: same picture (EXR
# means within Monte Carlo error), fewer lookups.  Measured 2026-12-02 on
# this scene: cotton fibre-level exemplars (the default) 5.28 M lookups
# against 9.93 M (0.53), smooth yarns (--fibre none) 0.30; fibres cover a
# crossing's whole footprint at near full density in every layer of the
# cloth, so a per-crossing cell saves the air and the layer profile only:
# the bound is 0.6, which a grid no tighter than the old 2-voxel cells
# (0.63) fails.
expect_ok global "$LOOM" render "$F" --width 32 --height 24 --spp 64 --majorant global --json -o "$T/g.exr"
cp "$T/out" "$T/g.json"
expect_ok grid "$LOOM" render "$F" --width 32 --height 24 --spp 64 --seed 9 --json -o "$T/h.exr"
if python3 - "$T/g.json" "$T/out" <<'PY' 2>"$T/pyerr"; then pass grid_fewer_lookups; else fail grid_fewer_lookups "$(cat "$T/pyerr")"; fi
import json, sys
g, h = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
assert g['majorant'] == 'global' and g['cells'] == 0, g
assert h['lookups'] < 0.6 * g['lookups'], (h['lookups'], g['lookups'])
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
# camera by --look-from/--look-at in mm of the cloth's frame: the
# --elevation/--azimuth camera (printed in the JSON) typed back in gives the
# same bytes; --up, --ortho and --aperture change the picture
expect_ok cam_short "$LOOM" render "$F" $R --elevation 30 --azimuth 20 --json -o "$T/cs.png"
LF=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["camera"]["look_from"])' "$T/out")
LA=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["camera"]["look_at"])' "$T/out")
json_check cam_json "j['camera']['units'] == 'mm' and j['camera']['kind'] == 'perspective'"
expect_ok cam_short_sun "$LOOM" render "$F" $R --elevation 30 --azimuth 20 --sun 170,35 --quiet -o "$T/css.png"
expect_ok cam_look "$LOOM" render "$F" $R --look-from "$LF" --look-at "$LA" --sun 170,35 --quiet -o "$T/cl.png"
expect_same look_from_equals_shorthand "$T/css.png" "$T/cl.png"
# the default sun follows the camera's azimuth (20 + 150 degrees)
expect_ok cam_look_sun "$LOOM" render "$F" $R --look-from "$LF" --look-at "$LA" --quiet -o "$T/cl2.png"
if python3 - "$T/cs.png" "$T/cl2.png" "$T/a.png" <<'PY' 2>"$T/pyerr"; then pass default_sun_follows_camera; else fail default_sun_follows_camera "$(cat "$T/pyerr")"; fi
import sys, zlib, struct
def mean(p):
    b = open(p, 'rb').read(); i = 8; data = b''
    while i < len(b):
        n, t = struct.unpack('>I4s', b[i:i+8]); c = b[i+8:i+8+n]; i += 12 + n
        if t == b'IHDR': w, h = struct.unpack('>II', c[:8])
        if t == b'IDAT': data += c
    raw = zlib.decompress(data); s = 0
    for y in range(h):
        s += sum(raw[y*(3*w+1)+1:(y+1)*(3*w+1)])
    return s / (3*w*h)
a, b = mean(sys.argv[1]), mean(sys.argv[2])
assert abs(a - b) < 0.03 * a + 1, (a, b)
PY
expect_ok cam_look_at_only "$LOOM" render "$F" $R --elevation 30 --azimuth 20 --look-at "$LA" --quiet -o "$T/ca.png"
expect_same look_at_keeps_offset "$T/cs.png" "$T/ca.png"
expect_ok cam_ap0 "$LOOM" render "$F" $R --elevation 30 --azimuth 20 --aperture 0 --focus 3 --quiet -o "$T/c0.png"
expect_same aperture0_is_pinhole "$T/cs.png" "$T/c0.png"
expect_ok cam_lens "$LOOM" render "$F" $R --elevation 30 --azimuth 20 --aperture 2 --focus 20 --quiet -o "$T/cd.png"
if cmp -s "$T/cs.png" "$T/cd.png"; then fail lens_matters "--aperture 2 gave the pinhole picture"; else pass lens_matters; fi
expect_ok cam_ortho "$LOOM" render "$F" $R --look-from 2.88,2.16,10 --look-at 2.88,2.16,0 --up 0,1,0 --ortho 2 --json -o "$T/co.exr"
json_check ortho_json "j['camera']['kind'] == 'ortho' and j['camera']['up'] == '0,1,0'"
expect_ok cam_ortho_threads "$LOOM" render "$F" $R --look-from 2.88,2.16,10 --look-at 2.88,2.16,0 --up 0,1,0 --ortho 2 --threads 1 --quiet -o "$T/co1.exr"
expect_same ortho_threads_same_bytes "$T/co.exr" "$T/co1.exr"
expect_exit cam_same_point 1 "$LOOM" render "$F" $R --look-from 1,1,1 --look-at 1,1,1 -o "$T/x.png"
expect_err_contains cam_same_point_msg "same point"
expect_exit cam_up_parallel 1 "$LOOM" render "$F" $R --look-from 1,1,5 --look-at 1,1,0 -o "$T/x.png"
expect_err_contains cam_up_parallel_msg "--up"
expect_exit cam_bad_point 2 "$LOOM" render "$F" --look-from 1,2 -o x.png
expect_err_contains cam_bad_point_msg "--look-from"
expect_exit cam_ortho_lens 2 "$LOOM" render "$F" --ortho 3 --aperture 1 -o x.png
expect_exit cam_focus_alone 2 "$LOOM" render "$F" --focus 3 -o x.png
expect_exit cam_aperture_neg 2 "$LOOM" render "$F" --aperture -1 -o x.png
# --envmap: a small latitude-longitude EXR written by an independent writer
ENVPY="python3 $LOOM_TOP/tests/cli/exr_envmap.py"
$ENVPY "$T/sky.exr" 64 32 sky
$ENVPY "$T/skyf.exr" 32 16 sky R,G,B float
$ENVPY "$T/lum.exr" 8 4 const:1 Y
$ENVPY "$T/huge.exr" 4097 1025 header
expect_ok env "$LOOM" render "$F" $R --envmap "$T/sky.exr" --json -o "$T/env.png"
json_check env_json "j['envmap_bytes'] > 64 * 32 * 12"
expect_ok env_threads "$LOOM" render "$F" $R --envmap "$T/sky.exr" --threads 1 --quiet -o "$T/env1.png"
expect_same env_threads_same_bytes "$T/env.png" "$T/env1.png"
if cmp -s "$T/env.png" "$T/a.png"; then fail env_matters "--envmap gave the studio picture"; else pass env_matters; fi
expect_ok env_rotate "$LOOM" render "$F" $R --envmap "$T/sky.exr" --env-rotate 90 --quiet -o "$T/envr.png"
if cmp -s "$T/env.png" "$T/envr.png"; then fail env_rotate_matters "--env-rotate 90 changed nothing"; else pass env_rotate_matters; fi
expect_ok env_float "$LOOM" render "$F" $R --envmap "$T/skyf.exr" --env-intensity 2 --sun 30,40 --quiet -o "$T/envf.png"
expect_exit env_not_exr 1 "$LOOM" render "$F" $R --envmap "$T/a.png" -o "$T/x.png"
expect_err_contains env_not_exr_msg "a.png: not an OpenEXR file"
expect_exit env_channels 1 "$LOOM" render "$F" $R --envmap "$T/lum.exr" -o "$T/x.png"
expect_err_contains env_channels_msg "lum.exr: channels Y; an environment map needs R, G and B"
expect_exit env_huge 1 "$LOOM" render "$F" $R --envmap "$T/huge.exr" -o "$T/x.png"
expect_err_contains env_huge_msg "huge.exr: 4097x1025 image is larger than 4194304 pixels"
expect_exit env_missing 1 "$LOOM" render "$F" $R --envmap "$T/nope.exr" -o "$T/x.png"
expect_err_contains env_missing_msg "nope.exr"
expect_exit env_budget 1 "$LOOM" render "$F" $R --envmap "$T/sky.exr" --budget 0.01 -o "$T/x.png"
expect_err_contains env_budget_msg "cannot hold the environment map"
# the built-in studio sky (the default) and the grey one before it
expect_ok sky_json "$LOOM" render "$F" $R --json -o "$T/sky1.png"
json_check sky_json_studio "j['sky'] == 'studio' and j['envmap_bytes'] > 128 * 64 * 12"
expect_ok sky_grey "$LOOM" render "$F" $R --sky grey --json -o "$T/skyg.png"
json_check sky_grey_json "j['sky'] == 'grey' and j['envmap_bytes'] == 0"
if cmp -s "$T/sky1.png" "$T/skyg.png"; then fail sky_matters "--sky grey gave the studio picture"; else pass sky_matters; fi
expect_ok sky_threads "$LOOM" render "$F" $R --threads 1 --quiet -o "$T/sky2.png"
expect_same sky_threads_same_bytes "$T/sky1.png" "$T/sky2.png"
expect_exit sky_with_envmap 2 "$LOOM" render "$F" --envmap "$T/sky.exr" --sky grey -o x.png
expect_err_contains sky_with_envmap_msg "--sky"
expect_exit sky_bad 2 "$LOOM" render "$F" --sky blue -o x.png
expect_err_contains sky_bad_msg "--sky"
expect_exit env_rotate_alone 2 "$LOOM" render "$F" --env-rotate 10 -o x.png
expect_exit env_intensity_neg 2 "$LOOM" render "$F" --envmap x.exr --env-intensity -1 -o x.png
# --light (spherical lamps, mm) and repeatable --sun
expect_ok lamps "$LOOM" render "$F" $R --light 1,0,3,0.3,40 --light 5,5,3,0.3,20 --sun 30,40,1 --sun 200,20,1 --quiet -o "$T/lamp.png"
expect_ok lamps_threads "$LOOM" render "$F" $R --light 1,0,3,0.3,40 --light 5,5,3,0.3,20 --sun 30,40,1 --sun 200,20,1 --threads 1 --quiet -o "$T/lamp1.png"
expect_same lamps_threads_same_bytes "$T/lamp.png" "$T/lamp1.png"
expect_ok one_sun "$LOOM" render "$F" $R --sun 30,40,1 --quiet -o "$T/sun1.png"
if cmp -s "$T/lamp.png" "$T/sun1.png"; then fail lamps_matter "lamps and a second sun changed nothing"; else pass lamps_matter; fi
expect_exit lamp_radius 2 "$LOOM" render "$F" --light 1,2,3,0,4 -o x.png
expect_err_contains lamp_radius_msg "RADIUS > 0"
expect_exit lamp_four 2 "$LOOM" render "$F" --light 1,2,3,4 -o x.png
expect_exit suns_17 2 "$LOOM" render "$F" $(for i in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17; do printf -- '--sun %d,30 ' "$i"; done) -o x.png
expect_err_contains suns_17_msg "at most 16 times"
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
# meshes with nothing to map onto: no faces (an empty file, a comment, only
# vertices) or no extent; each named, nothing written
: > "$T/empty.obj"
printf '# nothing\n' > "$T/comment.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\n' > "$T/nofaces.obj"
printf 'v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n' > "$T/point.obj"
for m in empty comment nofaces; do
	expect_exit mesh_$m 1 "$LOOM" render "$F" --mesh "$T/$m.obj" $R -o "$T/x.png"
	expect_err_contains mesh_${m}_msg "$m.obj: no faces: expected 'f' lines"
done
expect_err_contains mesh_nofaces_count "3 vertices read"
expect_exit mesh_point 1 "$LOOM" render "$F" --mesh "$T/point.obj" $R -o "$T/x.png"
expect_err_contains mesh_point_msg "point.obj: the mesh has no extent"
if [ -e "$T/x.png" ]; then fail mesh_bad_no_output "an image was written"
else pass mesh_bad_no_output; fi
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
