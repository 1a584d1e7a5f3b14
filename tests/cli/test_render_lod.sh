# `loom render --lod off|auto` end to end (docs/rendering.md, "Level of
# detail"): a grazing view of far cloth renders with coarse levels with
# --lod auto (JSON lod_levels 3), identical bytes on 1 and 2 threads, and
# differently from --lod off (the default: lod_levels 0, the same bytes as
# no option), whose bytes are also thread-independent;
# a database whose brick shape allows no level (3 x 5 x 7 bricks) still
# renders, with lod_levels 0 and the same bytes as --lod off; bad values
# are usage errors.
SUITE=render_lod
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
DB2=$T/odd.ldb
F=$T/tw.loomf
F2=$T/tw2.loomf

json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$3" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$3") $(head -c 300 "$T/pyerr")"; fi
}

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

expect_exit bad_lod 2 "$LOOM" render "$F" --lod on -o "$T/x.png"
expect_err_contains bad_lod_msg "--lod"

# far cloth at 12 degrees: pixels cover up to tens of voxels
R="--width 48 --height 24 --spp 2 --seed 5 --elevation 12 --region 0,0:1200,800 --quiet"
expect_ok auto_2 "$LOOM" render "$F" $R --threads 2 --lod auto --json -o "$T/a2.png"
json_check auto_json 'j["lod_levels"] == 3 and j["paths"] == 48 * 24 * 2' "$T/out"
expect_ok auto_1 "$LOOM" render "$F" $R --threads 1 --lod auto -o "$T/a1.png"
expect_same auto_threads "$T/a1.png" "$T/a2.png"
expect_ok off_2 "$LOOM" render "$F" $R --threads 2 --lod off --json -o "$T/o2.png"
json_check off_json 'j["lod_levels"] == 0' "$T/out"
expect_ok off_1 "$LOOM" render "$F" $R --threads 1 --lod off -o "$T/o1.png"
expect_same off_threads "$T/o1.png" "$T/o2.png"
expect_ok default "$LOOM" render "$F" $R --threads 2 --json -o "$T/n2.png"
json_check default_json 'j["lod_levels"] == 0' "$T/out"
expect_same default_is_off "$T/n2.png" "$T/o2.png"
if cmp -s "$T/a2.png" "$T/o2.png"; then fail lod_differs "--lod auto and off gave the same bytes"; else
	pass lod_differs; fi

# a brick shape without levels: LOD quietly off, as --lod off
expect_ok make_odd "$LOOM" exemplar generate --preset tiny --seed 3 --brick 3x5x7 --quiet -o "$DB2"
expect_ok synth_odd "$LOOM" synth "$T/tw.pbm" --db "$DB2" --quiet -o "$F2"
expect_ok odd_auto "$LOOM" render "$F2" $R --db "$DB2" --lod auto --json -o "$T/d1.png"
json_check odd_json 'j["lod_levels"] == 0' "$T/out"
expect_ok odd_off "$LOOM" render "$F2" $R --db "$DB2" --lod off -o "$T/d2.png"
expect_same odd_same "$T/d1.png" "$T/d2.png"
