# `loom render` outputs and staging: --cloth-size (a bounded piece with
# edges), --ground (a floor that catches shadows; on a mesh under its
# box), the EXR's AOV layers read back by exrheader and by an independent
# reader (exrread.py: the floor's albedo, normal and depth are exact in a
# top view), --tone filmic against linear, determinism for any thread
# count, usage errors.
SUITE=render_out
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
F=$T/tw.loomf
MESHES=$LOOM_TOP/tests/data/meshes

py() { # py NAME SCRIPT ARGS...: pass when the script exits 0
	name=$1
	shift
	if PYTHONPATH="$LOOM_TOP/tests/cli" python3 "$@" 2>"$T/pyerr"; then pass "$name"; else
		fail "$name" "$(tail -c 600 "$T/pyerr")"; fi
}

expect_ok help "$LOOM" render --help
for o in --cloth-size --ground --ground-z --ground-albedo --tone; do
	expect_out_contains "help$o" "$o "
done
expect_exit ground_z_alone 2 "$LOOM" render "$F" --ground-z 1 -o x.png
expect_err_contains ground_z_alone_msg "go with --ground"
expect_exit albedo_range 2 "$LOOM" render "$F" --ground --ground-albedo 1.5 -o x.png
expect_err_contains albedo_range_msg "reflectances in [0, 1]"
expect_exit albedo_two 2 "$LOOM" render "$F" --ground --ground-albedo 0.5,0.5 -o x.png
expect_exit cloth_zero 2 "$LOOM" render "$F" --cloth-size 0 -o x.png
expect_exit cloth_mesh 2 "$LOOM" render "$F" --mesh m.obj --cloth-size 5 -o x.png
expect_err_contains cloth_mesh_msg "--cloth-size cuts a flat patch"
expect_exit tone_exr 2 "$LOOM" render "$F" --tone filmic -o x.exr
expect_exit tone_bad 2 "$LOOM" render "$F" --tone gamma -o x.png

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

# a 3 x 2 mm piece on a floor, framed by default: determinism
R="--width 48 --height 32 --spp 2 --cloth-size 3,2 --ground --quiet"
expect_ok piece "$LOOM" render "$F" $R -o "$T/p2.png"
expect_ok piece_t1 "$LOOM" render "$F" $R --threads 1 -o "$T/p1.png"
expect_ok piece_t3 "$LOOM" render "$F" $R --threads 3 -o "$T/p3.png"
expect_same piece_threads_1 "$T/p2.png" "$T/p1.png"
expect_same piece_threads_3 "$T/p2.png" "$T/p3.png"
# the floor shows round the piece: a white floor and a black one differ
# at the corners, and agree at the centre (cloth)
expect_ok piece_black "$LOOM" render "$F" $R --ground-albedo 0 -o "$T/pb.png"
py floor_visible - "$T/p2.png" "$T/pb.png" <<'PY'
import sys, pngread
w, h, ch, a = pngread.read(sys.argv[1])
_, _, _, b = pngread.read(sys.argv[2])
assert a[1][3:6] != b[1][3:6] and max(b[1][3:6]) < 3, (a[1][3:6], b[1][3:6])
c = (h // 2, w // 2 * ch)
assert max(abs(a[c[0]][c[1] + k] - b[c[0]][c[1] + k]) for k in range(3)) < 40
PY

# EXR: beauty and AOVs; a top view (orthographic, 12 mm wide) of the
# piece on the floor at z = 0 from 20 mm up: in the corners the floor's
# albedo (0.5, 0.25, 0.75), normal (0, 0, 1) and depth 20 mm exactly
E="--width 40 --height 30 --spp 3 --cloth-size 3,2 --ground --ground-albedo 0.5,0.25,0.75 --look-from 1.5,1,20 --look-at 1.5,1,0 --up 0,1,0 --ortho 12 --quiet"
expect_ok exr "$LOOM" render "$F" $E -o "$T/e.exr"
expect_ok exr_t1 "$LOOM" render "$F" $E --threads 1 -o "$T/e1.exr"
expect_same exr_threads "$T/e.exr" "$T/e1.exr"
expect_ok exrheader exrheader "$T/e.exr"
for c in R G B albedo.R albedo.G albedo.B normal.X normal.Y normal.Z Z noise.R noise.G noise.B; do
	expect_out_contains "channel_$c" "    $c, 32-bit floating-point"
done
py aovs - "$T/e.exr" <<'PY'
import sys, exrread
w, h, d, a = exrread.read(sys.argv[1])
assert (w, h) == (40, 30)
for (x, y) in [(0, 0), (39, 0), (0, 29), (39, 29)]:
    got = [d[c][y][x] for c in ('albedo.R', 'albedo.G', 'albedo.B', 'normal.X', 'normal.Y', 'normal.Z')]
    assert got == [0.5, 0.25, 0.75, 0.0, 0.0, 1.0], got
    assert abs(d['Z'][y][x] - 20.0) < 1e-4, d['Z'][y][x]
# the piece in the middle: yarn albedo, depth above the floor's, a normal
# facing up on the whole, and Monte Carlo noise
cx, cy = w // 2, h // 2
assert d['Z'][cy][cx] < 19.9, d['Z'][cy][cx]
assert d['albedo.R'][cy][cx] != 0.5
nz = [d['normal.Z'][y][x] for y in range(h // 2 - 3, h // 2 + 3) for x in range(w // 2 - 5, w // 2 + 5)]
assert sum(nz) / len(nz) > 0.3, sum(nz) / len(nz)
assert max(d['noise.R'][y][x] for y in range(h) for x in range(w)) > 0
assert all(v >= 0 for c in ('noise.R', 'noise.G', 'noise.B') for r in d[c] for v in r)
PY
expect_ok exr_1spp "$LOOM" render "$F" $E --spp 1 -o "$T/e0.exr"
py noise_1spp - "$T/e0.exr" <<'PY'
import sys, exrread
w, h, d, a = exrread.read(sys.argv[1])
assert all(v == 0 for c in ('noise.R', 'noise.G', 'noise.B') for r in d[c] for v in r)
PY

# --tone filmic: highlights roll off instead of clipping
T2="--width 48 --height 32 --spp 2 --quiet --exposure 2"
expect_ok tone_linear "$LOOM" render "$F" $T2 -o "$T/tl.png"
expect_ok tone_filmic "$LOOM" render "$F" $T2 --tone filmic -o "$T/tf.png"
expect_ok tone_default "$LOOM" render "$F" $T2 --tone linear -o "$T/td.png"
expect_same tone_linear_default "$T/tl.png" "$T/td.png"
py filmic_rolls_off - "$T/tl.png" "$T/tf.png" <<'PY'
import sys, pngread
_, _, _, a = pngread.read(sys.argv[1])
_, _, _, b = pngread.read(sys.argv[2])
ca = sum(1 for r in a for v in r if v == 255)
cb = sum(1 for r in b for v in r if v == 255)
assert ca > 50 and cb < ca // 4, (ca, cb)
PY

# a mesh on the floor: under the box by default, --json reports it
expect_ok mesh_ground "$LOOM" render "$F" --mesh "$MESHES/drape.obj" --width 32 --height 24 --spp 1 --ground --json -o "$T/m.png"
if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if j["ground_z"] < -6.6 and j["ground_z"] > -7.5 else 1)' "$T/out"; then
	pass mesh_ground_z; else fail mesh_ground_z "$(cat "$T/out")"; fi
