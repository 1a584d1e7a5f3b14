# The scene meshes (tests/data/meshes/gen_meshes.py: a closed two-panel
# pillow, a cloth draped over a sphere, a sleeve) rendered end to end
# through `loom render --mesh`: each shows cloth over a good part of the
# frame (pixels read back by pngread.py and compared with the background).
SUITE=render_scenes
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
F=$T/tw.loomf
MESHES=$LOOM_TOP/tests/data/meshes

json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$T/out" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 400 "$T/out") $(head -c 300 "$T/pyerr")"; fi
}
# cloth_check NAME PNG FRACTION: more than FRACTION of the pixels differ
# from the background grey (the corner pixel); an empty render differs in
# none.
cloth_check() {
	if PYTHONPATH="$LOOM_TOP/tests/cli" python3 - "$2" "$3" <<'PY' 2>"$T/pyerr"; then pass "$1"; else fail "$1" "$(cat "$T/pyerr")"; fi
import sys, pngread
w, h, ch, px = pngread.read(sys.argv[1])
bg = px[0][0:3]
n = sum(1 for y in range(h) for x in range(w)
        if max(abs(px[y][x * ch + c] - bg[c]) for c in range(3)) > 12)
assert n > w * h * float(sys.argv[2]), '%d of %d pixels differ from the background' % (n, w * h)
PY
}

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

R="--width 64 --height 36 --spp 1"
# coverage: the pillow and the sleeve differ from the background in about
# 23 % of the pixels, the drape 18 % (the rest is the grey or shaded cloth
# close to it); an empty or failed render in none
for m in pillow:0.15 drape:0.1 sleeve:0.15; do
	name=${m%%:*}
	expect_ok "$name" "$LOOM" render "$F" --mesh "$MESHES/$name.obj" $R --uv-repeats 4 --json -o "$T/$name.png"
	json_check "${name}_uv" "j['scene'] == 'mesh' and j['uv']['source'] == 'mesh' and j['uv']['stretch_mean'] < 1.25"
	cloth_check "${name}_cloth" "$T/$name.png" "${m#*:}"
done

# --uv-mm U,V: millimetres of cloth per UV unit.  The tiny database states
# no sett: crossings become square at the exemplar crossing's area, so the
# voxel scales differ by the crossing's aspect b1 / b2 (and U / V)
expect_ok uv_mm "$LOOM" render "$F" --mesh "$MESHES/quad.obj" $R --uv-mm 12,6 --json -o "$T/uvmm.png"
json_check uv_mm_scales "abs(j['uv']['crossing_mm_u'] - j['uv']['crossing_mm_v']) < 1e-12 and abs(j['uv']['voxels_per_uv_u'] / 12 * j['uv']['crossing_mm_u'] - 8) < 1e-6 and abs(j['uv']['voxels_per_uv_v'] / 6 * j['uv']['crossing_mm_v'] - 6) < 1e-6"
cloth_check uv_mm_cloth "$T/uvmm.png" 0.15
expect_ok uv_mm_pillow "$LOOM" render "$F" --mesh "$MESHES/pillow.obj" $R --uv-mm 40 --json -o "$T/uvmmp.png"
json_check uv_mm_one_value "abs(j['uv']['voxels_per_uv_u'] / j['uv']['voxels_per_uv_v'] - 8 / 6) < 1e-9"
cloth_check uv_mm_pillow_cloth "$T/uvmmp.png" 0.15
expect_exit uv_mm_and_repeats 2 "$LOOM" render "$F" --mesh "$MESHES/quad.obj" --uv-mm 12 --uv-repeats 2 -o "$T/x.png"
expect_err_contains uv_mm_and_repeats_msg "give one"
expect_exit uv_mm_zero 2 "$LOOM" render "$F" --mesh "$MESHES/quad.obj" --uv-mm 0 -o "$T/x.png"
expect_err_contains uv_mm_zero_msg "--uv-mm"
expect_exit uv_mm_bad_v 2 "$LOOM" render "$F" --mesh "$MESHES/quad.obj" --uv-mm 12,x -o "$T/x.png"
expect_exit uv_mm_flat 2 "$LOOM" render "$F" --uv-mm 12 -o "$T/x.png"
