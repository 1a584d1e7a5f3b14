# `loom synth` and `loom info` end to end, as a user types them: a WIF
# from data/, a PBM, an image + mapping file; JSON keys; the pictures are
# valid PNGs (checked by an independent reader in Python: signature, chunk
# CRCs, inflated size); exit codes; a fabric refused by another database.
SUITE=synth
. "$LOOM_TOP/tests/cli/lib.sh"
IMG=$DATA/images
WIF=$LOOM_TOP/data/herringbone-8.wif

expect_ok help_synth "$LOOM" synth --help
expect_out_contains help_synth_text "--assignment-map"
expect_ok help_info "$LOOM" info --help
expect_out_contains help_info_text "--bolt"
expect_exit synth_no_args 2 "$LOOM" synth
expect_exit synth_no_output 2 "$LOOM" synth "$WIF"
expect_exit synth_bad_algo 2 "$LOOM" synth "$WIF" --algo best -o "$T/x.loomf"
expect_exit synth_bad_rank 2 "$LOOM" synth "$WIF" --rank 129 -o "$T/x.loomf"
expect_exit synth_bad_edge_fix 2 "$LOOM" synth "$WIF" --edge-fix maybe -o "$T/x.loomf"
expect_exit synth_bad_group 2 "$LOOM" synth "$WIF" --group -1 -o "$T/x.loomf"
expect_exit synth_bad_seed 2 "$LOOM" synth "$WIF" --seed x -o "$T/x.loomf"
expect_exit synth_bad_map_ext 2 "$LOOM" synth "$WIF" --seam-map "$T/s.gif" -o "$T/x.loomf"
expect_exit synth_unknown_opt 2 "$LOOM" synth "$WIF" --frob -o "$T/x.loomf"
expect_exit synth_two_designs 2 "$LOOM" synth "$WIF" "$WIF" -o "$T/x.loomf"
expect_exit synth_missing_design 1 "$LOOM" synth "$T/nope.wif" -o "$T/x.loomf"
expect_err_contains synth_missing_design_msg "nope.wif"
expect_exit synth_bad_db 1 "$LOOM" synth "$WIF" --db "$T/nope.ldb" -o "$T/x.loomf"
expect_err_contains synth_bad_db_msg "nope.ldb"
if [ -e "$T/x.loomf" ]; then fail no_partial_output "x.loomf exists"; else pass no_partial_output; fi
expect_exit info_no_args 2 "$LOOM" info
expect_exit info_bad_bolt 2 "$LOOM" info "$T/x.loomf" --bolt 3
expect_exit info_missing 1 "$LOOM" info "$T/x.loomf"

# a WIF draft from data/ with the default database (built by make)
expect_ok synth_wif "$LOOM" synth "$WIF" -o "$T/h8.loomf"
expect_out_contains synth_wif_summary "correctness 1.000"
if [ -s "$T/err" ]; then fail synth_quiet_stderr "$(head -c 200 "$T/err")"; else pass synth_quiet_stderr; fi
expect_ok synth_wif_again "$LOOM" synth "$WIF" --quiet -o "$T/h8b.loomf"
if [ -s "$T/out" ]; then fail synth_quiet_stdout "$(head -c 200 "$T/out")"; else pass synth_quiet_stdout; fi
expect_same synth_deterministic "$T/h8.loomf" "$T/h8b.loomf"
# floats longer than any exemplar's: the summary and --json give the
# longest floats of the design and of the database (the database's
# computed here from the weaves `loom exemplar info --json` lists for the
# same default database, runs within each exemplar), and a warning names
# them; the herringbone above had none (synth_quiet_stderr)
expect_ok float_db_info "$LOOM" exemplar info --json
cp "$T/out" "$T/exinfo.json"
expect_ok float_make "$LOOM" pattern make satin:1/9 -q -o "$T/s19.pbm"
expect_ok float_synth "$LOOM" synth "$T/s19.pbm" -o "$T/s19.loomf"
expect_out_contains float_summary "longest floats: warp 1, weft 9 crossings"
expect_err_contains float_warning "warning: the design's longest weft float is 9 crossings"
expect_err_contains float_warning_doc "docs/fidelity.md"
expect_ok float_json "$LOOM" synth "$T/s19.pbm" --json -o "$T/s19.loomf"
if python3 - "$T/out" "$T/exinfo.json" >"$T/py" 2>&1 <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))["longest_float"]
warp = weft = 0
for e in json.load(open(sys.argv[2]))["exemplars"]:
    rows = e["weave"]
    for r in rows:
        n = 0
        for c in r:
            n = 0 if c == "1" else n + 1
            weft = max(weft, n)
    for k in range(len(rows[0])):
        n = 0
        for r in rows:
            n = n + 1 if r[k] == "1" else 0
            warp = max(warp, n)
assert (j["design_warp"], j["design_weft"]) == (1, 9), j
assert (j["database_warp"], j["database_weft"]) == (warp, weft), (j, warp, weft)
assert weft < 9, weft
EOF
then pass float_json_keys; else fail float_json_keys "$(head -c 600 "$T/py")"; fi
expect_ok float_quiet "$LOOM" synth "$T/s19.pbm" --quiet -o "$T/s19.loomf"
if [ -s "$T/err" ]; then fail float_quiet_silent "$(head -c 200 "$T/err")"; else pass float_quiet_silent; fi

# --rank 0 and --edge-fix off: no edge fix (seams unchanged), the same bytes
# as each other, a fabric every command opens; the default rank moves seams
expect_ok synth_rank0 "$LOOM" synth "$WIF" --rank 0 --json -o "$T/r0.loomf"
cp "$T/out" "$T/r0.json"
expect_ok synth_edge_off "$LOOM" synth "$WIF" --edge-fix off --quiet -o "$T/off.loomf"
expect_same synth_edge_off_is_rank0 "$T/r0.loomf" "$T/off.loomf"
if python3 - "$T/r0.json" >"$T/py" 2>&1 <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
assert j["rank"] == 0 and j["rank_h"] == 0 and j["rank_v"] == 0, j
assert j["seam_before"] > 0 and j["seam_after"] == j["seam_before"], j
EOF
then pass synth_rank0_no_fix; else fail synth_rank0_no_fix "$(head -c 600 "$T/py")"; fi
expect_ok synth_rank0_info "$LOOM" info "$T/r0.loomf"
expect_out_contains synth_rank0_info_rank "rank 0"
expect_ok synth_rank0_preview "$LOOM" preview "$T/r0.loomf" --width 64 -q -o "$T/r0.png"
# --edge-fix full: the exact fix (each side at its whole rank: the default
# database's 24 x 16 blocks give 24 and 14), the same bytes as --rank 128,
# its seams closer than without a fix (it keeps the woven cloth's own jumps,
# 1.2 times the step inside blocks, so it takes off about a third: 0.62
# against 0.89 on this draft); not with --rank
expect_ok synth_edge_full "$LOOM" synth "$WIF" --edge-fix full --json -o "$T/full.loomf"
cp "$T/out" "$T/full.json"
expect_ok synth_rank128 "$LOOM" synth "$WIF" --rank 128 --quiet -o "$T/r128.loomf"
expect_same synth_edge_full_is_rank128 "$T/full.loomf" "$T/r128.loomf"
if python3 - "$T/full.json" "$T/r0.json" >"$T/py" 2>&1 <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
r0 = json.load(open(sys.argv[2]))
assert j["rank"] == 128 and j["rank_h"] == 24 and j["rank_v"] == 14, j
assert j["seam_after"] < 0.75 * r0["seam_after"], (j["seam_after"], r0["seam_after"])
EOF
then pass synth_edge_full_ranks; else fail synth_edge_full_ranks "$(head -c 600 "$T/py")"; fi
expect_exit synth_edge_full_rank 2 "$LOOM" synth "$WIF" --edge-fix full --rank 5 -o "$T/x.loomf"
expect_err_contains synth_edge_full_rank_msg "no --rank"
expect_ok synth_edge_full_preview "$LOOM" preview "$T/full.loomf" --width 64 -q -o "$T/full.png"
expect_ok synth_other_seed "$LOOM" synth "$WIF" --seed 2 --quiet -o "$T/h8s2.loomf"
if cmp -s "$T/h8.loomf" "$T/h8s2.loomf"; then fail seed_changes_bytes "same bytes"; else pass seed_changes_bytes; fi

# --json with the keys, and both pictures
expect_ok synth_json "$LOOM" synth "$WIF" --algo dp --seed 3 --rank 10 --group 4 --json \
	--assignment-map "$T/assign.png" --seam-map "$T/seam.png" -o "$T/h8j.loomf"
cp "$T/out" "$T/synth.json"
if python3 - "$T/synth.json" "$T/h8j.loomf" >"$T/py" 2>&1 <<'EOF'
import json, os, sys
j = json.load(open(sys.argv[1]))
for k in ("crossings", "correctness", "consistency", "continuity", "seam_before",
          "seam_after", "internal_step", "seam_before_ratio", "seam_after_ratio",
          "seconds", "fabric_bytes", "usage", "database", "bolt_window"):
    assert k in j, k
assert j["crossings"] == j["rows"] * j["cols"] > 0
assert j["correctness"] == 1, j["correctness"]
assert 0 < j["consistency"] <= 1 and 0 <= j["continuity"] <= 1
assert j["seam_after"] < j["seam_before"], (j["seam_before"], j["seam_after"])
assert abs(j["seam_before_ratio"] - j["seam_before"] / j["internal_step"]) < 1e-6
assert j["fabric_bytes"] == os.path.getsize(sys.argv[2])
assert j["algo"] == "dp" and j["seed"] == 3 and j["rank"] == 10 and j["group"] == 4
assert sum(u["crossings"] for u in j["usage"]) == j["crossings"]
assert len(j["usage"]) == j["database"]["exemplars"] == 13
assert j["database"]["block"] == [24, 16, 48]
assert j["assignment_map"]["rows"] == j["rows"] and j["seam_map"]["max_voxels"] > 0
sm = j["seam_map"]
print(j["assignment_map"]["scale"], j["rows"], j["cols"],
      2 * sm["cols"] * sm["scale"] + 8, sm["rows"] * sm["scale"] + 8 + 12)
EOF
then pass synth_json_keys; else fail synth_json_keys "$(head -c 600 "$T/py")"; fi
set -- $(cat "$T/py")
ascale=$1; rows=$2; cols=$3; seam_w=$4; seam_h=$5

# pngcheck NAME FILE WIDTH HEIGHT: a valid 8-bit RGB PNG of that size
pngcheck() {
	if python3 - "$2" "$3" "$4" >"$T/py" 2>&1 <<'EOF'
import struct, sys, zlib
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n", "signature"
pos, idat, ihdr = 8, b"", None
while pos < len(data):
    n, = struct.unpack(">I", data[pos:pos + 4])
    typ, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
    crc, = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])
    assert zlib.crc32(typ + body) & 0xffffffff == crc, typ
    if typ == b"IHDR": ihdr = struct.unpack(">IIBBBBB", body)
    if typ == b"IDAT": idat += body
    pos += 12 + n
    if typ == b"IEND": break
w, h, depth, ctype = ihdr[:4]
if sys.argv[2] != "-": assert w == int(sys.argv[2]), (w, sys.argv[2])
if sys.argv[3] != "-": assert h == int(sys.argv[3]), (h, sys.argv[3])
assert depth == 8 and ctype == 2, (depth, ctype)
assert len(zlib.decompress(idat)) == h * (1 + 3 * w)
EOF
	then pass "$1"; else fail "$1" "$(head -c 400 "$T/py")"; fi
}
pngcheck assignment_png "$T/assign.png" $((cols * ascale)) $((rows * ascale))
pngcheck seam_png "$T/seam.png" "$seam_w" "$seam_h"

# a PBM weave, greedy, and a bad --map use
expect_ok synth_pbm "$LOOM" synth "$IMG/twill23_5x5.pbm" --algo greedy -o "$T/t.loomf"
expect_out_contains synth_pbm_summary "5x5 design (25 crossings), greedy"
expect_ok synth_pbm_maps "$LOOM" synth "$IMG/twill23_plain.pbm" --warp-map "$IMG/ids.pgm" \
	--edge-tables rebuild -o "$T/tp.loomf"
expect_out_contains synth_pbm_rebuild "rebuilt at open"

# a PNG weave (as `loom pattern make` writes it) gives the same fabric as
# the same weave as PBM
expect_ok make_png "$LOOM" pattern make twill:2/3 --size 5x5 -o "$T/t23.png"
expect_ok synth_png "$LOOM" synth "$T/t23.png" --algo greedy --quiet -o "$T/tpng.loomf"
expect_ok synth_pbm_again "$LOOM" synth "$IMG/twill23_5x5.pbm" --algo greedy --quiet -o "$T/tpbm.loomf"
expect_same synth_png_equals_pbm "$T/tpng.loomf" "$T/tpbm.loomf"

# an image + mapping file (Jacquard)
expect_ok synth_image "$LOOM" synth "$IMG/motif.ppm" --map "$IMG/motif.map" --json -o "$T/m.loomf"
if python3 -c "import json,sys; j=json.load(open(sys.argv[1])); assert j['correctness']==1 and j['crossings']==24" "$T/out" 2>"$T/py"
then pass synth_image_json; else fail synth_image_json "$(head -c 300 "$T/py")"; fi
expect_exit synth_image_three_levels 1 "$LOOM" synth "$IMG/three_levels.pgm" -o "$T/m2.loomf"
expect_exit synth_image_bad_map 1 "$LOOM" synth "$IMG/motif.ppm" --map "$IMG/motif_bad.map" -o "$T/m2.loomf"

# loom info: text, JSON, bolts in repeats and in metres
expect_ok info_text "$LOOM" info "$T/h8.loomf"
expect_out_contains info_design "192 x 192 crossings"
expect_out_contains info_repeat "4608 x 3072 x 48 voxels"
expect_out_contains info_matches "matches"
expect_ok info_bolt "$LOOM" info "$T/h8.loomf" --bolt 10x2 --json
if python3 - "$T/out" >"$T/py" 2>&1 <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
assert j["repeat_voxels"] == [192 * 24, 192 * 16, 48]
b = j["bolt"]
assert b["voxels"] == [2 * 4608, 10 * 3072, 48], b
assert b["total_voxels"] == 2 * 4608 * 10 * 3072 * 48
assert j["database"]["matches"] is True and j["database"]["found"] is True
assert j["params"]["algo"] == "dp" and j["metrics"]["correctness"] == 1
EOF
then pass info_bolt_json; else fail info_bolt_json "$(head -c 400 "$T/py")"; fi
# 1 m long, 22.1184 cm wide: voxels of 24 um -> 41667 x 9216 columns
expect_ok info_bolt_units "$LOOM" info "$T/h8.loomf" --bolt 1mx22.1184cm --json
if python3 -c "
import json,sys; b=json.load(open(sys.argv[1]))['bolt']
assert b['voxels'] == [9216, 41667, 48], b['voxels']" "$T/out" 2>"$T/py"
then pass info_bolt_units_json; else fail info_bolt_units_json "$(head -c 300 "$T/py")"; fi

# a fabric made with one database is refused with another
expect_ok db_a "$LOOM" exemplar generate --preset tiny --seed 1 --quiet -o "$T/a.ldb"
expect_ok db_b "$LOOM" exemplar generate --preset tiny --seed 2 --quiet -o "$T/b.ldb"
expect_ok synth_tiny "$LOOM" synth "$WIF" --db "$T/a.ldb" --quiet -o "$T/ta.loomf"
expect_ok info_same_db "$LOOM" info "$T/ta.loomf" --db "$T/a.ldb"
expect_exit info_other_db 1 "$LOOM" info "$T/ta.loomf" --db "$T/b.ldb"
expect_err_contains info_other_db_msg "content hash"
# the recorded database changed under the fabric: reported, not fatal
cp "$T/b.ldb" "$T/a.ldb"
expect_ok info_changed_db "$LOOM" info "$T/ta.loomf"
expect_out_contains info_changed_db_text "DIFFERS"
expect_err_contains info_changed_db_warn "warning"
# a corrupt fabric
head -c 500 "$T/h8.loomf" >"$T/cut.loomf"
expect_exit info_truncated 1 "$LOOM" info "$T/cut.loomf"
expect_err_contains info_truncated_msg "truncated"
