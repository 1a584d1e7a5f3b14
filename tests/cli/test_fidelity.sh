# The woven ground truth (loom exemplar generate --design), the identity
# fabric that copies it (loom synth --identity) and loom compare, end to end
# as a user types them (docs/fidelity.md).
SUITE=fidelity
. "$LOOM_TOP/tests/cli/lib.sh"
WIF=$LOOM_TOP/data/herringbone-8.wif

# a design to weave: herringbone 12 x 16 (tiny preset: fast)
expect_ok fid_pattern "$LOOM" pattern make herringbone --size 12x16 -q -o "$T/hb.pbm"
expect_ok gt_generate "$LOOM" exemplar generate --design "$T/hb.pbm" --preset tiny \
	--quiet -o "$T/gt.ldb"
expect_ok gt_info "$LOOM" exemplar info "$T/gt.ldb" --json
cp "$T/out" "$T/gt.json"
expect_ok gt_pattern_info "$LOOM" pattern info "$T/hb.pbm"
if python3 - "$T/gt.json" "$T/hb.pbm" >"$T/py" 2>&1 <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
assert len(j["exemplars"]) == 1, j
e = j["exemplars"][0]
assert e["crossings"] == [12, 16], e["crossings"]
assert e["block"] == [8, 6, 12] and abs(j["voxel_size_um"] - 72) < 1e-3, j
# the weave is the design's: PBM P4, 1 = black = warp over
data = open(sys.argv[2], "rb").read()
parts = data.split(b"\n", 2)
w, h = map(int, parts[1].split())
bits = parts[2]
rows = []
stride = (w + 7) // 8
for r in range(h):
    rows.append("".join(str((bits[r * stride + c // 8] >> (7 - c % 8)) & 1) for c in range(w)))
assert e["weave"] == rows, (e["weave"], rows)
PY
then pass gt_weave_is_design; else fail gt_weave_is_design "$(head -c 600 "$T/py")"; fi

# --like copies the geometry of a database
expect_ok gt_like "$LOOM" exemplar generate --design "$WIF" --like "$T/gt.ldb" --quiet \
	-o "$T/gt8.ldb"
expect_ok gt_like_info "$LOOM" exemplar info "$T/gt8.ldb"
expect_out_contains gt_like_block "block 8x6x12 voxels of 72 um"
# a window of a design
expect_ok gt_window "$LOOM" exemplar generate --design "$T/hb.pbm" --preset tiny \
	--window 2,4:10,16 --json -o "$T/gtw.ldb"
expect_ok gt_window_info "$LOOM" exemplar info "$T/gtw.ldb"
expect_out_contains gt_window_size "8x12"
# bad input
expect_exit gt_too_big 1 "$LOOM" exemplar generate --design "$T/hb.pbm" --preset tiny \
	--block 8x6000x12 -o "$T/x.ldb"
expect_err_contains gt_too_big_msg "at most"
expect_err_contains gt_too_big_hint "--window"
expect_exit gt_window_outside 1 "$LOOM" exemplar generate --design "$T/hb.pbm" \
	--preset tiny --window 0,0:13,16 -o "$T/x.ldb"
expect_err_contains gt_window_outside_msg "outside"
expect_exit gt_window_bad 2 "$LOOM" exemplar generate --design "$T/hb.pbm" --window 3,3:2,5 \
	-o "$T/x.ldb"
expect_exit gt_design_weaves 2 "$LOOM" exemplar generate --design "$T/hb.pbm" \
	--weaves plain -o "$T/x.ldb"
expect_exit gt_like_preset 2 "$LOOM" exemplar generate --design "$T/hb.pbm" \
	--like "$T/gt.ldb" --preset tiny -o "$T/x.ldb"
expect_exit gt_window_alone 2 "$LOOM" exemplar generate --window 0,0:2,2 -o "$T/x.ldb"
expect_exit gt_missing 1 "$LOOM" exemplar generate --design "$T/nope.wif" -o "$T/x.ldb"
expect_err_contains gt_missing_msg "nope.wif"
if [ -e "$T/x.ldb" ]; then fail gt_no_partial "x.ldb exists"; else pass gt_no_partial; fi

# identity fabric: every loom command works on it
expect_ok id_synth "$LOOM" synth "$T/hb.pbm" --db "$T/gt.ldb" --identity --json -o "$T/id.loomf"
expect_out_contains id_algo '"algo": "identity"'
expect_out_contains id_rank '"rank": 0'
expect_ok id_info "$LOOM" info "$T/id.loomf"
expect_ok id_preview "$LOOM" preview "$T/id.loomf" --width 64 -q -o "$T/id.png"
expect_ok id_export "$LOOM" export "$T/id.loomf" --all --format nrrd --channels density \
	--tile 1000,1000 --quiet -o "$T/idx"
expect_ok gt_export "$LOOM" exemplar export "$T/gt.ldb" --exemplar 0 -o "$T/gt.nrrd"
# the identity fabric's voxels are the exemplar's, byte for byte
if python3 - "$T/idx" "$T/gt.nrrd" >"$T/py" 2>&1 <<'PY'
import glob, sys
def nrrd(path):
    b = open(path, "rb").read()
    i = b.index(b"\n\n")
    hdr = b[:i].decode()
    return hdr, b[i + 2:]
tiles = sorted(glob.glob(sys.argv[1] + "/**/*.nrrd", recursive=True))
assert len(tiles) == 1, tiles
h1, d1 = nrrd(tiles[0])
h2, d2 = nrrd(sys.argv[2])
assert "sizes: 128 72 12" in h1 and "sizes: 128 72 12" in h2, (h1, h2)
import struct
n = 128 * 72 * 12
assert "type: float" in h1 and "type: uint8" in h2, (h1, h2)
assert len(d1) == 4 * n and len(d2) == n, (len(d1), len(d2))
f = struct.unpack("<%df" % n, d1)
bad = sum(1 for a, b in zip(f, d2) if abs(a * 255 - b) > 1e-3)
assert bad == 0, bad
assert sum(1 for x in d2 if x) > n // 10
PY
then pass id_equals_gt; else fail id_equals_gt "$(head -c 600 "$T/py")"; fi
expect_exit id_other_design 1 "$LOOM" synth "$WIF" --db "$T/gt.ldb" --identity -o "$T/x.loomf"
expect_err_contains id_other_design_msg "exemplar 0"
expect_exit id_with_rank 2 "$LOOM" synth "$T/hb.pbm" --db "$T/gt.ldb" --identity --rank 5 \
	-o "$T/x.loomf"
