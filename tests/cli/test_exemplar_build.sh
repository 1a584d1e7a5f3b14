# `loom exemplar generate --scan` and `loom exemplar build` end to end: a
# scan-like sheet with ground truth -> build (JSON compared with the truth)
# -> a database -> loom synth / sample / exemplar verify; bad scans fail
# with exit 1 and a clear message.
SUITE=exemplar_build
. "$LOOM_TOP/tests/cli/lib.sh"

expect_ok help_build "$LOOM" exemplar build --help
expect_ok help_generate_scan "$LOOM" exemplar generate --scan --help
expect_exit build_no_args 2 "$LOOM" exemplar build
expect_exit build_no_db 2 "$LOOM" exemplar build "$T/x.vol" --warps 7 --wefts 9
expect_exit build_no_counts 2 "$LOOM" exemplar build "$T/x.vol" --db "$T/x.ldb"
expect_exit build_bad_block 2 "$LOOM" exemplar build "$T/x.vol" --warps 7 --wefts 9 \
	--block 0x3 --db "$T/x.ldb"
expect_exit build_missing_scan 1 "$LOOM" exemplar build "$T/nope.vol" --warps 7 \
	--wefts 9 --db "$T/x.ldb"
expect_exit gen_scan_bad_ext 2 "$LOOM" exemplar generate --scan -o "$T/x.raw"
expect_exit gen_scan_bad_weave 2 "$LOOM" exemplar generate --scan --weave frob -o "$T/x.vol"

# compare a build's JSON ($1) with a ground truth ($2)
check_truth() {
	python3 - "$1" "$2" <<'PY'
import json, sys
b = json.load(open(sys.argv[1])); t = json.load(open(sys.argv[2]))
for k in ("weave", "rotation_degrees", "crop", "warps", "wefts"):
    assert k in b, k
assert b["weave"] == t["weave"], (b["weave"], t["weave"])
assert abs(b["rotation_degrees"] - t["rotation_degrees"]) <= 0.5, b["rotation_degrees"]
assert all(abs(x - y) <= 2 for x, y in zip(b["crop"], t["crop"])), (b["crop"], t["crop"])
assert b["warps"] == t["warps"] and b["wefts"] == t["wefts"]
assert b["full_weave"] == t["full_weave"]
print("rotation %.3f vs %.3f, crop %s vs %s" % (b["rotation_degrees"],
      t["rotation_degrees"], b["crop"], t["crop"]))
PY
}

# 1. .vol with a given orientation (float32 x3), twill 2/3, into a new DB
expect_ok gen_scan_vol "$LOOM" exemplar generate --scan --seed 3 --rotate 2.5 \
	--offset 8,6 -o "$T/a.vol" --truth "$T/a.json"
expect_out_contains gen_scan_vol_summary "160x160x40 voxels"
if [ -s "$T/a-orient.vol" ] && [ -s "$T/a-labels.nrrd" ]; then pass gen_scan_files
else fail gen_scan_files "missing a-orient.vol or a-labels.nrrd"; fi
expect_ok build_given "$LOOM" exemplar build "$T/a.vol" --orientation "$T/a-orient.vol" \
	--warps 7 --wefts 9 --name twill-given --weave-name twill:2/3 --json --db "$T/s.ldb"
cp "$T/out" "$T/a.build.json"
if check_truth "$T/a.build.json" "$T/a.json" >"$T/py" 2>&1; then pass build_given_truth
else fail build_given_truth "$(head -c 600 "$T/py")"; fi

# 2. NRRD density only (orientation estimated), rotated the other way,
#    appended; the first exemplar's bricks stay byte-identical
"$LOOM" exemplar export "$T/s.ldb" --exemplar 0 -o "$T/e0.nrrd" 2>/dev/null
expect_ok gen_scan_nrrd "$LOOM" exemplar generate --scan --seed 4 --rotate -3 \
	--no-orientation --density f32 -o "$T/b.nrrd" --truth "$T/b.json"
expect_ok build_estimated "$LOOM" exemplar build "$T/b.nrrd" --warps 7 --wefts 9 \
	--name twill-est --json --db "$T/s.ldb"
cp "$T/out" "$T/b.build.json"
if check_truth "$T/b.build.json" "$T/b.json" >"$T/py" 2>&1; then pass build_estimated_truth
else fail build_estimated_truth "$(head -c 600 "$T/py")"; fi
if python3 -c "import json,sys; assert json.load(open(sys.argv[1]))['appended'] is True" \
	"$T/b.build.json"; then pass build_appended; else fail build_appended "not appended"; fi
"$LOOM" exemplar export "$T/s.ldb" --exemplar 0 -o "$T/e0b.nrrd" 2>/dev/null
expect_same append_keeps_exemplar0 "$T/e0.nrrd" "$T/e0b.nrrd"
expect_exit build_same_name 1 "$LOOM" exemplar build "$T/b.nrrd" --warps 7 --wefts 9 \
	--name twill-est --db "$T/s.ldb"
expect_err_contains build_same_name_msg "already named"

# 3. the plain report names every step
expect_ok gen_scan_plain "$LOOM" exemplar generate --scan --weave satin:1/4 --seed 5 \
	--rotate 1.5 --orient qdir -o "$T/c.vol" --truth "$T/c.json"
expect_ok build_report "$LOOM" exemplar build "$T/c.vol" --orientation "$T/c-orient.vol" \
	--warps 7 --wefts 9 --name satin --db "$T/s.ldb"
for w in "denoise:" "orientation:" "endpoints:" "tracking:" "weave:" "alignment:" \
	"registration:" "pattern:" "appended exemplar 'satin'"; do
	expect_out_contains "build_report_${w%%:*}" "$w"
done
expect_ok build_quiet "$LOOM" exemplar build "$T/c.vol" --warps 7 --wefts 9 --quiet \
	--name satin-q --db "$T/s.ldb"
if [ -s "$T/out" ]; then fail build_quiet_stdout "$(head -c 200 "$T/out")"; else pass build_quiet_stdout; fi

# 4. the database works like a generated one
expect_ok verify_db "$LOOM" exemplar verify "$T/s.ldb"
expect_ok info_db "$LOOM" exemplar info "$T/s.ldb" --json
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); \
assert [e['name'] for e in j['exemplars']] == ['twill-given','twill-est','satin','satin-q'], j" \
	"$T/out"; then pass info_db_names; else fail info_db_names "$(head -c 300 "$T/out")"; fi
expect_ok pattern_design "$LOOM" pattern make twill:2/3 --size 15x15 -o "$T/d.pbm"
expect_ok synth_from_scan "$LOOM" synth "$T/d.pbm" --db "$T/s.ldb" --json -o "$T/f.loomf"
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); \
assert j['correctness'] == 1 and j['consistency'] > 0.9, j" "$T/out"; then
	pass synth_from_scan_checks; else fail synth_from_scan_checks "$(head -c 300 "$T/out")"; fi
expect_ok sample_from_scan "$LOOM" sample "$T/f.loomf" --random 20000 --json --quiet
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); \
assert j['errors'] == 0 and j['nonempty'] > 5000, j" "$T/out"; then
	pass sample_from_scan_checks; else fail sample_from_scan_checks "$(head -c 300 "$T/out")"; fi

# 5. bad scans: exit 1 and the step's message, no database change
cp "$T/s.ldb" "$T/s0.ldb"
expect_exit build_wrong_warps 1 "$LOOM" exemplar build "$T/a.vol" --warps 8 --wefts 9 \
	--db "$T/s.ldb"
expect_err_contains build_wrong_warps_msg "8 warps requested, but"
expect_exit build_wrong_wefts 1 "$LOOM" exemplar build "$T/a.vol" --warps 7 --wefts 7 \
	--db "$T/s.ldb"
expect_err_contains build_wrong_wefts_msg "7 wefts requested, but"
expect_ok gen_noise "$LOOM" exemplar generate --scan --pure-noise --no-orientation \
	-o "$T/n.vol"
expect_exit build_noise 1 "$LOOM" exemplar build "$T/n.vol" --warps 7 --wefts 9 \
	--db "$T/s.ldb"
expect_err_contains build_noise_msg "scan: endpoints:"
expect_same bad_scans_leave_db "$T/s.ldb" "$T/s0.ldb"

# 6. raw input (u8) with --raw-dims, into a fresh database
python3 - "$T/a.vol" "$T/a.raw" <<'PY'
import sys
d = open(sys.argv[1], "rb").read()
open(sys.argv[2], "wb").write(d[48:])
PY
expect_ok build_raw "$LOOM" exemplar build "$T/a.raw" --raw-dims 160,160,40 --raw-type u8 \
	--voxel-mm 0.024 --warps 7 --wefts 9 --json --db "$T/r.ldb"
cp "$T/out" "$T/r.build.json"
if check_truth "$T/r.build.json" "$T/a.json" >"$T/py" 2>&1; then pass build_raw_truth
else fail build_raw_truth "$(head -c 600 "$T/py")"; fi
expect_exit build_raw_no_dims 1 "$LOOM" exemplar build "$T/a.raw" --warps 7 --wefts 9 \
	--db "$T/r2.ldb"
expect_err_contains build_raw_no_dims_msg "--raw-dims"

# 7. storage of a new database: --format-version 3 --raw-density gives the
#    same voxels as the default storage (exemplar 0 of s.ldb, built from the
#    same scan), every stored density plane raw; appending keeps a
#    database's storage and refuses to change it (exit 1, file unchanged)
expect_exit build_raw_v1 2 "$LOOM" exemplar build "$T/a.vol" --warps 7 --wefts 9 \
	--raw-density --format-version 1 --db "$T/v.ldb"
expect_err_contains build_raw_v1_msg "--raw-density needs format version 2, 3 or 4"
expect_ok build_raw_density "$LOOM" exemplar build "$T/a.vol" --orientation "$T/a-orient.vol" \
	--warps 7 --wefts 9 --name twill-given --weave-name twill:2/3 --format-version 3 \
	--raw-density --quiet --db "$T/v.ldb"
expect_ok info_raw_density "$LOOM" exemplar info "$T/v.ldb" --json
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); \
assert j['version'] == 3, j['format_version']; \
n = j['bricks'] - j['empty_bricks']; assert n > 0 and j['raw_density_planes'] == n, j" \
	"$T/out"; then pass info_raw_density_all; else fail info_raw_density_all "$(head -c 300 "$T/out")"; fi
"$LOOM" exemplar export "$T/v.ldb" --exemplar 0 -o "$T/v0.nrrd" 2>/dev/null
expect_same raw_density_same_voxels "$T/e0.nrrd" "$T/v0.nrrd"
expect_ok verify_raw_density "$LOOM" exemplar verify "$T/v.ldb"
expect_ok build_append_raw "$LOOM" exemplar build "$T/c.vol" --warps 7 --wefts 9 --quiet \
	--name satin --db "$T/v.ldb"
expect_ok info_append_raw "$LOOM" exemplar info "$T/v.ldb" --json
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); \
assert j['version'] == 3 and len(j['exemplars']) == 2, j; \
assert j['raw_density_planes'] == j['bricks'] - j['empty_bricks'], j" \
	"$T/out"; then pass append_keeps_raw; else fail append_keeps_raw "$(head -c 300 "$T/out")"; fi
cp "$T/s.ldb" "$T/s0.ldb"
expect_exit build_append_not_raw 1 "$LOOM" exemplar build "$T/c.vol" --warps 7 --wefts 9 \
	--raw-density --name satin-r --db "$T/s.ldb"
expect_err_contains build_append_not_raw_msg "convert --raw-density"
expect_exit build_append_other_version 1 "$LOOM" exemplar build "$T/c.vol" --warps 7 \
	--wefts 9 --format-version 3 --name satin-3 --db "$T/s.ldb"
expect_err_contains build_append_other_version_msg "format version 4"
expect_same refused_appends_leave_db "$T/s.ldb" "$T/s0.ldb"
