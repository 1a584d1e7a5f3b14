# The brick shape is a storage choice only (docs/exemplars.md, "Brick
# shape"): the same preset and seed written with bricks of 16x16x64 (the
# default), 4x4x4 (most of them empty air: the reader keeps index entries
# for the stored ones only) and 8x8x16 give the same exemplar voxels
# (NRRD export), pass `exemplar verify`, and a fabric synthesized over
# each exports the same voxels; the info counts the empty bricks.
SUITE=brick_shape
. "$LOOM_TOP/tests/cli/lib.sh"

json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$3" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$3") $(head -c 300 "$T/pyerr")"; fi
}

expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 12x10 -o "$T/tw.pbm"
for b in 16x16x64 4x4x4 8x8x16; do
	expect_ok "gen_$b" "$LOOM" exemplar generate --preset tiny --seed 3 --brick "$b" --quiet \
	    -o "$T/$b.ldb"
	expect_ok "verify_$b" "$LOOM" exemplar verify "$T/$b.ldb"
	expect_ok "info_$b" "$LOOM" exemplar info "$T/$b.ldb" --json
	cp "$T/out" "$T/$b.json"
	for k in 0 3; do
		expect_ok "export_${b}_$k" "$LOOM" exemplar export "$T/$b.ldb" --exemplar "$k" \
		    -o "$T/$b-$k.nrrd"
	done
	expect_ok "synth_$b" "$LOOM" synth "$T/tw.pbm" --db "$T/$b.ldb" --quiet -o "$T/$b.loomf"
	expect_ok "fabric_export_$b" "$LOOM" export "$T/$b.loomf" --db "$T/$b.ldb" \
	    --region 0,0,0:40,30,12 --format nrrd --tile 40,30 --quiet -o "$T/ex-$b"
done
json_check small_bricks_mostly_empty \
    'j["brick"] == [4, 4, 4] and j["empty_bricks"] > 0 and j["bricks"] > 1000' "$T/4x4x4.json"
for b in 4x4x4 8x8x16; do
	for k in 0 3; do
		expect_same "same_exemplar_${b}_$k" "$T/16x16x64-$k.nrrd" "$T/$b-$k.nrrd"
	done
	for f in "$T"/ex-16x16x64/*.nrrd; do
		expect_same "same_fabric_${b}_$(basename "$f" .nrrd)" "$f" "$T/ex-$b/$(basename "$f")"
	done
done
