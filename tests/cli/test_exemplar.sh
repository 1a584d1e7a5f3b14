# `loom exemplar generate|info|verify|export` end to end, with teem's unu
# as the independent NRRD reader.
SUITE=exemplar
. "$LOOM_TOP/tests/cli/lib.sh"
UNU=teem-unu
# run on its own (not through make test, which installs the test packages
# first), the suite installs its independent reader itself
if ! command -v $UNU >/dev/null 2>&1; then
	sh "$LOOM_TOP/tools/deps.sh" test >"$T/deps.log" 2>&1 ||
		echo "test_exemplar: tools/deps.sh test failed (see $T/deps.log)" >&2
fi
if command -v $UNU >/dev/null 2>&1; then pass unu_installed; else
	fail unu_installed "teem-unu is not installed and tools/deps.sh test could not install it"; fi
DB=$T/two.ldb

for c in "" generate info verify export; do
	expect_ok "help_${c:-main}" "$LOOM" exemplar $c --help
done
expect_exit no_subcommand 2 "$LOOM" exemplar
expect_exit unknown_subcommand 2 "$LOOM" exemplar frob
expect_exit generate_no_output 2 "$LOOM" exemplar generate
expect_exit generate_bad_preset 2 "$LOOM" exemplar generate --preset huge -o "$T/x.ldb"
expect_exit generate_bad_weave 1 "$LOOM" exemplar generate --weaves twill:0/2 -o "$T/x.ldb"
expect_err_contains generate_bad_weave_msg "twill:0/2"
if [ -e "$T/x.ldb" ]; then fail no_partial_output "x.ldb exists"; else pass no_partial_output; fi

# fibre-level yarns: the same bytes for 1 and 2 threads; a bad fibre is a
# usage error naming it
expect_ok fibre_1 "$LOOM" exemplar generate --preset tiny --weaves twill:2/3 \
	--fibre cotton,silk --threads 1 -q -o "$T/f1.ldb"
expect_ok fibre_2 "$LOOM" exemplar generate --preset tiny --weaves twill:2/3 \
	--fibre cotton,silk --threads 2 -q -o "$T/f2.ldb"
if cmp -s "$T/f1.ldb" "$T/f2.ldb"; then pass fibre_threads_same; else
	fail fibre_threads_same "1 and 2 threads differ"; fi
expect_ok fibre_none "$LOOM" exemplar generate --preset tiny --weaves twill:2/3 \
	-q -o "$T/f0.ldb"
if cmp -s "$T/f0.ldb" "$T/f1.ldb"; then fail fibre_differs "same bytes as smooth yarns"
else pass fibre_differs; fi
expect_exit fibre_bad 2 "$LOOM" exemplar generate --fibre hemp -o "$T/x.ldb"
expect_err_contains fibre_bad_msg "hemp"

# generate: two weaves, small preset; no progress when stderr is not a terminal
expect_ok generate "$LOOM" exemplar generate --preset small --weaves twill:2/3,satin:1/4 \
	--seed 5 -o "$DB"
if [ -s "$T/err" ]; then fail generate_quiet_stderr "$(head -c 200 "$T/err")"; else pass generate_quiet_stderr; fi
expect_out_contains generate_summary "2 exemplars"
expect_ok generate_again "$LOOM" exemplar generate --preset small --weaves twill:2/3,satin:1/4 \
	--seed 5 --threads 1 --quiet -o "$T/again.ldb"
expect_same deterministic "$DB" "$T/again.ldb"

# info --json: valid JSON with the documented keys
expect_ok info_json "$LOOM" exemplar info "$DB" --json
cp "$T/out" "$T/info.json"
if python3 - "$T/info.json" >"$T/py" 2>&1 <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
ex = j["exemplars"]
assert len(ex) == 2, ex
for e in ex:
    for k in ("name", "weave", "crossings", "block", "raw_bytes", "compressed_bytes"):
        assert k in e, k
    assert e["crossings"] == [5, 5], e["crossings"]
    assert e["block"] == [24, 16, 48], e["block"]
    assert len(e["weave"]) == 5 and all(len(r) == 5 and set(r) <= {"0", "1"} for r in e["weave"])
    assert e["raw_bytes"] == 120 * 80 * 48 * 4
    assert 0 < e["compressed_bytes"] < e["raw_bytes"]
assert ex[0]["name"] == "twill-2-3" and ex[1]["name"] == "satin-1-4"
# the default format: version 4, each plane a unit of its own, density
# zero-run coded
assert j["version"] == 4 and j["voxel_layout"] == 4, (j["version"], j["voxel_layout"])
# twill 2/3: every column has two 1s, every row two 1s
assert all(r.count("1") == 2 for r in ex[0]["weave"])
assert all(r.count("1") == 1 for r in ex[1]["weave"])
print(ex[0]["weave"][0])
EOF
then pass info_json_keys; else fail info_json_keys "$(head -c 400 "$T/py")"; fi
row0=$(cat "$T/py")
expect_ok info_text "$LOOM" exemplar info "$DB"
expect_out_contains info_text_name "satin-1-4"
expect_out_contains info_text_version "format version 4 (each plane of a brick stored apart, density zero-run coded)"
expect_out_contains info_text_weave "$row0"

# --format-version 3: the density plane in segments, the same voxels
expect_ok generate_v3 "$LOOM" exemplar generate --preset small --weaves twill:2/3,satin:1/4 \
	--seed 5 --threads 1 --quiet --format-version 3 -o "$T/v3.ldb"
expect_ok info_v3 "$LOOM" exemplar info "$T/v3.ldb"
expect_out_contains info_v3_version "format version 3 (each plane of a brick stored apart, density in 8 segments)"
expect_ok export_v4 "$LOOM" exemplar export "$DB" --exemplar 1 -o "$T/x2.nrrd"
expect_ok export_v3 "$LOOM" exemplar export "$T/v3.ldb" --exemplar 1 -o "$T/x3.nrrd"
expect_same v3_same_voxels "$T/x2.nrrd" "$T/x3.nrrd"
# --format-version 2: every plane deflated, a smaller file, the same voxels
expect_ok generate_v2 "$LOOM" exemplar generate --preset small --weaves twill:2/3,satin:1/4 \
	--seed 5 --threads 1 --quiet --format-version 2 -o "$T/v2.ldb"
expect_ok info_v2 "$LOOM" exemplar info "$T/v2.ldb"
expect_out_contains info_v2_version "format version 2 (each plane of a brick stored apart),"
expect_ok export_v2 "$LOOM" exemplar export "$T/v2.ldb" --exemplar 1 -o "$T/xv2.nrrd"
expect_same v2_same_voxels "$T/x2.nrrd" "$T/xv2.nrrd"
if [ "$(wc -c <"$T/v2.ldb")" -lt "$(wc -c <"$DB")" ]; then pass v2_smaller
else fail v2_smaller "$(wc -c <"$T/v2.ldb") bytes in version 2, $(wc -c <"$DB") in 4"; fi
expect_exit format_version_5 2 "$LOOM" exemplar generate --preset tiny --format-version 5 -o "$T/v5.ldb"
# --raw-density: the density planes stored as they are (a larger file, the
# same voxels, every density plane raw; versions 2 to 4 only)
expect_ok generate_rawd "$LOOM" exemplar generate --preset small --weaves twill:2/3,satin:1/4 \
	--seed 5 --threads 1 --quiet --raw-density -o "$T/rawd.ldb"
expect_ok info_rawd "$LOOM" exemplar info "$T/rawd.ldb" --json
if python3 - "$T/out" "$DB" <<'EOF' 2>"$T/py"
import json, os, sys
j = json.load(open(sys.argv[1]))
stored = j["bricks"] - j["empty_bricks"]
assert j["version"] == 4 and stored > 0, j
assert j["raw_density_planes"] == stored, (j["raw_density_planes"], stored)
assert j["file_bytes"] > os.path.getsize(sys.argv[2]), "not larger than compressed"
EOF
then pass rawd_info; else fail rawd_info "$(head -c 400 "$T/py")"; fi
expect_ok info_v2_json "$LOOM" exemplar info "$DB" --json
expect_out_contains v2_no_raw_density '"raw_density_planes": 0'
expect_ok export_rawd "$LOOM" exemplar export "$T/rawd.ldb" --exemplar 1 -o "$T/xr.nrrd"
expect_same rawd_same_voxels "$T/x2.nrrd" "$T/xr.nrrd"
expect_ok verify_rawd "$LOOM" exemplar verify "$T/rawd.ldb" --quiet
expect_ok generate_rawd_v3 "$LOOM" exemplar generate --preset tiny --weaves twill:2/3 \
	--quiet --raw-density --format-version 3 -o "$T/rawd3.ldb"
expect_ok verify_rawd_v3 "$LOOM" exemplar verify "$T/rawd3.ldb" --quiet
expect_exit rawd_v1 2 "$LOOM" exemplar generate --preset tiny --raw-density --format-version 1 \
	-o "$T/rawd1.ldb"
expect_err_contains rawd_v1_msg "--raw-density needs format version 2, 3 or 4"

# convert: another storage, the same voxels and tables; back again gives
# the original bytes (the writer is deterministic)
expect_ok convert_raw "$LOOM" exemplar convert "$DB" -o "$T/cv-raw.ldb" --raw-density --quiet
expect_ok convert_v3 "$LOOM" exemplar convert "$T/cv-raw.ldb" -o "$T/cv-v3.ldb" --format-version 3 --json
if python3 - "$T/out" <<'EOF' 2>"$T/py"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["version"] == 3 and j["raw_density_planes"] == j["bricks"] > 0, j
assert j["content_hash"] != j["input_content_hash"], j
assert j["file_bytes"] == j["input_bytes"], j  # raw planes: the same bytes, other index
EOF
then pass convert_json; else fail convert_json "$(head -c 400 "$T/py")"; fi
# a file that keeps the voxel rule: nothing cleared, no warning (test_db
# checks the warning on a file that breaks it)
if grep -q "warning" "$T/err"; then fail convert_no_warning "$(head -c 400 "$T/err")"
else pass convert_no_warning; fi
expect_ok convert_back "$LOOM" exemplar convert "$T/cv-v3.ldb" -o "$T/cv-back.ldb" \
	--format-version 4 --deflate-density --quiet
expect_same convert_round_trip "$DB" "$T/cv-back.ldb"
# version 2 to 4 gives what generating version 4 gives
expect_ok convert_v2_v4 "$LOOM" exemplar convert "$T/v2.ldb" -o "$T/cv-v4.ldb" --format-version 4 --quiet
expect_same convert_v2_v4_same "$DB" "$T/cv-v4.ldb"
expect_ok convert_v1 "$LOOM" exemplar convert "$DB" -o "$T/cv-v1.ldb" --format-version 1 --quiet
expect_ok export_v1 "$LOOM" exemplar export "$T/cv-v1.ldb" --exemplar 1 -o "$T/xv1.nrrd"
expect_same convert_v1_same_voxels "$T/x2.nrrd" "$T/xv1.nrrd"
expect_exit convert_no_out 2 "$LOOM" exemplar convert "$DB"
expect_exit convert_both 2 "$LOOM" exemplar convert "$DB" -o "$T/cv-x.ldb" --raw-density --deflate-density
expect_exit convert_raw_v1 2 "$LOOM" exemplar convert "$DB" -o "$T/cv-x.ldb" --raw-density --format-version 1
expect_exit convert_same 1 "$LOOM" exemplar convert "$DB" -o "$DB"
expect_err_contains convert_same_msg "the output is the input"
# a damaged brick: exit 1 naming it, nothing written
cp "$DB" "$T/bad.ldb"
python3 - "$T/bad.ldb" <<'EOF'
import sys
b = bytearray(open(sys.argv[1], "rb").read())
b[4096] ^= 0xff  # inside the first bricks' data
open(sys.argv[1], "wb").write(bytes(b))
EOF
expect_exit convert_damaged 1 "$LOOM" exemplar convert "$T/bad.ldb" -o "$T/cv-bad.ldb" --quiet
expect_err_contains convert_damaged_msg "brick"
if [ -e "$T/cv-bad.ldb" ] || ls "$T"/cv-bad.ldb.* >/dev/null 2>&1; then
	fail convert_damaged_nothing "$(ls "$T" | grep cv-bad)"; else pass convert_damaged_nothing; fi

# default database lookup: LOOM_DB, then the data directory
expect_ok info_env env LOOM_DB="$DB" "$LOOM" exemplar info
expect_out_contains info_env_path "$DB"
mkdir -p "$T/nodata"
expect_exit info_none 1 env LOOM_DB= LOOM_DATA="$T/nodata" "$LOOM" exemplar info
expect_err_contains info_none_msg "no exemplar database"
expect_ok info_default env LOOM_DB= LOOM_DATA= "$LOOM" exemplar info
expect_out_contains info_default_path "default.ldb"

# the voxel rule (docs/formats.md: orientation code 0 wherever density is
# 0) holds for what generate writes with the default fibre-level yarns;
# until 2026-12-05 a voxel at a fibre's edge whose coverage quantised to 0
# kept its code, and verify names such a voxel
for p in small tiny; do
	expect_ok "rule_gen_$p" "$LOOM" exemplar generate --preset $p -o "$T/rule-$p.ldb" --quiet
	expect_ok "rule_verify_$p" "$LOOM" exemplar verify "$T/rule-$p.ldb" --quiet
done

# verify, then damage one byte of the first stored brick (it starts right
# after the 128-byte header: brick 0 is the bottom brick of column 0,0,
# which holds cloth)
expect_ok verify "$LOOM" exemplar verify "$DB"
expect_out_contains verify_ok "ok"
cp "$DB" "$T/flip.ldb"
b=$(od -An -tu1 -j 140 -N1 "$T/flip.ldb" | tr -d ' ')
nb=$(( b ^ 32 ))
printf "\\$(printf %o "$nb")" | dd of="$T/flip.ldb" bs=1 seek=140 conv=notrunc 2>/dev/null
expect_exit verify_flip 1 "$LOOM" exemplar verify "$T/flip.ldb"
expect_err_contains verify_flip_brick "flip.ldb: brick 0 (exemplar 0 'twill-2-3', brick x=0 y=0 z=0)"
expect_err_contains verify_flip_crc "CRC32 mismatch"
expect_exit export_flip 1 "$LOOM" exemplar export "$T/flip.ldb" --exemplar 0 -o "$T/flip.nrrd"
expect_err_contains export_flip_msg "brick 0"

# truncation
size=$(wc -c <"$DB")
head -c $((size - 1)) "$DB" >"$T/trunc.ldb"
expect_exit verify_trunc 1 "$LOOM" exemplar verify "$T/trunc.ldb"
expect_err_contains verify_trunc_msg "trunc.ldb: no trailer in the last 64 bytes (offset $((size - 65))): the file is truncated"
head -c 100 "$DB" >"$T/trunc2.ldb"
expect_exit info_trunc 1 "$LOOM" exemplar info "$T/trunc2.ldb"
expect_err_contains info_trunc_msg "file of 100 bytes ends inside the 128-byte header"
printf 'not a database at all, just text ................................................................................................................\n' >"$T/text.ldb"
expect_exit info_text_file 1 "$LOOM" exemplar info "$T/text.ldb"
expect_err_contains info_text_file_msg "bad magic"

# export: attached density, read back with unu
expect_ok export "$LOOM" exemplar export "$DB" --exemplar twill-2-3 -o "$T/d.nrrd"
if $UNU head "$T/d.nrrd" >"$T/head" 2>&1; then pass unu_head; else fail unu_head "$(cat "$T/head")"; fi
if grep -q "^sizes: 120 80 48" "$T/head" && grep -q "^type: uint8" "$T/head" &&
   grep -q "^space directions: (0.024,0,0) (0,0.024,0) (0,0,0.024)" "$T/head"; then
	pass unu_sizes; else fail unu_sizes "$(cat "$T/head")"; fi
# the top slice is empty, the middle one is not
$UNU slice -i "$T/d.nrrd" -a 2 -p 47 | $UNU save -f text -o "$T/top.txt"
if [ "$(tr ' ' '\n' <"$T/top.txt" | grep -c '[1-9]')" = 0 ] && [ -s "$T/top.txt" ]; then
	pass top_slice_empty; else fail top_slice_empty "non-zero voxels in the top slice"; fi
$UNU slice -i "$T/d.nrrd" -a 2 -p 24 | $UNU save -f text -o "$T/mid.txt"
n=$(tr ' ' '\n' <"$T/mid.txt" | grep -c '[1-9]')
if [ "$n" -gt 1000 ]; then pass mid_slice_full; else fail mid_slice_full "$n non-zero voxels"; fi
# kind channel: at every crossing centre the top-most yarn (density >= 64,
# so that faint flyaway fibres do not count) is the warp (1) exactly where
# the weave says 1
expect_ok export_kind "$LOOM" exemplar export "$DB" --exemplar 0 --channel kind -o "$T/k.nrrd"
bad=0
r=0
python3 -c "import json;print('\n'.join(json.load(open('$T/info.json'))['exemplars'][0]['weave']))" >"$T/weave.txt"
while read -r wrow; do
	c=0
	while [ $c -lt 5 ]; do
		x=$((c * 24 + 12)); y=$((r * 16 + 8))
		$UNU slice -i "$T/k.nrrd" -a 0 -p $x | $UNU slice -a 0 -p $y | $UNU save -f text |
			tr ' ' '\n' | grep -v '^$' >"$T/kcol"
		$UNU slice -i "$T/d.nrrd" -a 0 -p $x | $UNU slice -a 0 -p $y | $UNU save -f text |
			tr ' ' '\n' | grep -v '^$' >"$T/dcol"
		# the surface rule: highest voxel with a yarn and density >= 64
		top=$(paste "$T/kcol" "$T/dcol" | awk '$1 != 0 && $2 >= 64 {k = $1} END {print k}')
		want=$(echo "$wrow" | cut -c$((c + 1)))
		[ "$want" = 1 ] && want=1 || want=2
		[ "$top" = "$want" ] || bad=$((bad + 1))
		c=$((c + 1))
	done
	r=$((r + 1))
done <"$T/weave.txt"
if [ "$bad" = 0 ] && [ "$r" = 5 ]; then pass kind_over_under; else fail kind_over_under "$bad crossings wrong"; fi
# detached header + orientation vectors
expect_ok export_detached "$LOOM" exemplar export "$DB" --exemplar 1 --channel orientation \
	--detached -o "$T/o.nhdr"
if [ -f "$T/o.raw" ] && [ "$(wc -c <"$T/o.raw")" = $((3 * 120 * 80 * 48 * 4)) ]; then
	pass detached_raw; else fail detached_raw "o.raw missing or wrong size"; fi
if $UNU head "$T/o.nhdr" >"$T/head2" 2>&1 && grep -q "^sizes: 3 120 80 48" "$T/head2" &&
   grep -q "^kinds: 3-vector domain domain domain" "$T/head2"; then
	pass unu_vector; else fail unu_vector "$(cat "$T/head2")"; fi
# unit vectors: the largest component magnitude is <= 1 (unu reads the data)
$UNU project -i "$T/o.nhdr" -a 3 -m max | $UNU project -a 2 -m max | $UNU project -a 1 -m max |
	$UNU save -f text -o "$T/omax.txt"
if awk '{for (i = 1; i <= NF; i++) if ($i > 1.0001 || $i < -1.0001) bad = 1} END {exit bad}' "$T/omax.txt" &&
   [ -s "$T/omax.txt" ]; then pass orientation_values; else fail orientation_values "$(cat "$T/omax.txt")"; fi
expect_exit export_bad_exemplar 1 "$LOOM" exemplar export "$DB" --exemplar nope -o "$T/n.nrrd"
expect_exit export_bad_channel 2 "$LOOM" exemplar export "$DB" --exemplar 0 --channel rgb -o "$T/n.nrrd"

# sett and yarn size from a draft (WIF Spacing/Thickness/Units) or options:
# a square sett gives square crossings, 2:1 gives 2:1 (b1 = 10000 / (ends
# per cm x voxel um): 54 per cm at 5 um = 37.04 voxels)
W=$LOOM_TOP/tests/data/wif
block_of() { # DB -> "b1 b2 b3"
	"$LOOM" exemplar info "$1" --json | python3 -c \
		'import json,sys; print(*json.load(sys.stdin)["block"])'
}
expect_ok sett_square "$LOOM" exemplar generate --sett-from "$W/sett-square.wif" \
	--voxel-size 5 --weaves plain --quiet -o "$T/sq.ldb"
b=$(block_of "$T/sq.ldb")
case "$b" in "37 37 "*) pass sett_square_block ;; *) fail sett_square_block "$b" ;; esac
expect_ok sett_two_one "$LOOM" exemplar generate --sett-from "$W/sett-two-one.wif" \
	--voxel-size 5 --weaves plain --quiet -o "$T/s21.ldb"
b=$(block_of "$T/s21.ldb")
case "$b" in "37 74 "*) pass sett_two_one_block ;; *) fail sett_two_one_block "$b" ;; esac
expect_ok sett_option "$LOOM" exemplar generate --sett 20x10 --yarn-diameter 250,300 \
	--weaves plain --quiet -o "$T/so.ldb"
b=$(block_of "$T/so.ldb")
case "$b" in "21 42 "*) pass sett_option_block ;; *) fail sett_option_block "$b" ;; esac
# the sett option overrides the draft; a draft without a sett keeps the preset
expect_ok sett_override "$LOOM" exemplar generate --sett-from "$W/sett-square.wif" \
	--sett 27x54 --voxel-size 5 --weaves plain --quiet -o "$T/sov.ldb"
b=$(block_of "$T/sov.ldb")
case "$b" in "74 37 "*) pass sett_override_block ;; *) fail sett_override_block "$b" ;; esac
expect_ok sett_none "$LOOM" exemplar generate --sett-from "$W/basic-twill.wif" \
	--weaves plain -o "$T/sn.ldb"
expect_err_contains sett_none_warning "states no sett; the block stays 24x16"
# bad input: the option or the file:line, and the accepted range
expect_exit sett_too_fine 2 "$LOOM" exemplar generate --sett 200x20 -o "$T/x.ldb"
expect_err_contains sett_too_fine_msg "--sett: sett: 200 ends per cm at 24 um voxels gives crossings of 2.1 voxels (at least 4"
expect_exit sett_bad 2 "$LOOM" exemplar generate --sett 20x-1 -o "$T/x.ldb"
expect_err_contains sett_bad_msg "--sett: expected ENDS_PER_CMxPICKS_PER_CM"
expect_exit yarn_bad 2 "$LOOM" exemplar generate --yarn-diameter 0 -o "$T/x.ldb"
expect_err_contains yarn_bad_msg "--yarn-diameter: expected UM or WARP_UM,WEFT_UM"
expect_exit yarn_too_thick 1 "$LOOM" exemplar generate --sett 20x20 --yarn-diameter 3000 -o "$T/x.ldb"
expect_err_contains yarn_too_thick_msg "warp yarn diameter 3000 um (expected 0 < d <= 2016 um"
expect_exit sett_block_both 2 "$LOOM" exemplar generate --sett 20x20 --block 8x8x8 -o "$T/x.ldb"
expect_exit sett_bad_units 1 "$LOOM" exemplar generate --sett-from "$W/bad-spacing-units.wif" -o "$T/x.ldb"
expect_err_contains sett_bad_units_msg "bad-spacing-units.wif:40: [WARP]: Units=Furlongs is not a WIF unit"
if [ -e "$T/x.ldb" ]; then fail sett_no_partial_output "x.ldb exists"; else pass sett_no_partial_output; fi
# a negative WIF spacing names the file:line and the range; an odd sett
# (0.019 mm, 526 ends per cm) is a warning, never an error or a crash
sed 's/^Spacing=0.0185$/Spacing=-0.0185/' "$W/sett-square.wif" >"$T/neg.wif"
expect_exit sett_negative 1 "$LOOM" exemplar generate --sett-from "$T/neg.wif" -o "$T/x.ldb"
neg_line=$(grep -n '^Spacing=-' "$T/neg.wif" | head -1 | cut -d: -f1)
expect_err_contains sett_negative_msg "neg.wif:$neg_line: [WARP]: expected Spacing=NUMBER (positive, at most 1e+06), such as 0.05, got '-0.0185'"
sed -e 's/^Spacing=0.0185$/Spacing=0.0019/' -e '/^\[WARP SPACING\]/,/^$/d' \
	"$W/sett-square.wif" >"$T/odd.wif"
expect_ok sett_odd "$LOOM" exemplar generate --sett-from "$T/odd.wif" --voxel-size 2 \
	--weaves plain --fibre none -o "$T/odd.ldb"
expect_err_contains sett_odd_warning "is not a usual sett"
b=$(block_of "$T/odd.ldb")
case "$b" in "9 9 "*) pass sett_odd_block ;; *) fail sett_odd_block "$b" ;; esac
# no fibre named (an empty --fibre or an empty side): the accepted names
expect_exit fibre_empty 2 "$LOOM" exemplar generate --fibre "" -o "$T/x.ldb"
expect_err_contains fibre_empty_msg "--fibre"
expect_exit fibre_empty_side 2 "$LOOM" exemplar generate --fibre cotton, -o "$T/x.ldb"
expect_err_contains fibre_empty_side_msg "cotton, rayon, silk"
# --min-crossings: each side the smallest multiple of the weave's repeat at
# least N (5-end twill 10 x 10, 8-end satin 16 x 16); with --crossings a
# usage error; a multiple above 64 a side: the weave, its repeat, the limit
expect_ok min_crossings "$LOOM" exemplar generate --preset tiny --weaves twill:2/3,satin:1/7 \
	--min-crossings 10 --fibre none --quiet -o "$T/mc.ldb"
expect_ok min_crossings_info "$LOOM" exemplar info "$T/mc.ldb" --json
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); c=[e['crossings'] for e in j['exemplars']]; sys.exit(0 if c == [[10, 10], [16, 16]] else 1)" "$T/out"; then
	pass min_crossings_sizes
else
	fail min_crossings_sizes "$(cat "$T/out")"
fi
expect_exit min_crossings_with_crossings 2 "$LOOM" exemplar generate --preset tiny --min-crossings 10 \
	--crossings 5x5 -o "$T/x.ldb"
expect_err_contains min_crossings_with_crossings_msg "--min-crossings and --crossings exclude each other"
expect_exit min_crossings_too_big 1 "$LOOM" exemplar generate --preset tiny --weaves twill:2/3 \
	--min-crossings 61 -o "$T/x.ldb"
expect_err_contains min_crossings_too_big_msg "weave 'twill:2/3' repeats every 5x5 crossings: its smallest multiple of at least 61 crossings a side is 65x65, above the largest window (64 a side)"
if [ -e "$T/x.ldb" ]; then fail min_crossings_no_output "x.ldb exists"; else pass min_crossings_no_output; fi
