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
