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

# ---- loom compare ----
expect_exit cmp_no_args 2 "$LOOM" compare
expect_exit cmp_one_arg_pictures 2 "$LOOM" compare "$T/id.loomf" --pictures "$T/pp"
expect_err_contains cmp_one_arg_pictures_msg "give B"
expect_exit cmp_three_args 2 "$LOOM" compare "$T/id.loomf" "$T/id.loomf" "$T/id.loomf"
expect_exit cmp_bad_region 2 "$LOOM" compare "$T/id.loomf" "$T/id.loomf" --region 5,5:1,1
expect_exit cmp_missing 1 "$LOOM" compare "$T/nope.loomf" "$T/id.loomf"
expect_err_contains cmp_missing_msg "nope.loomf"
expect_exit cmp_bad_exemplar 1 "$LOOM" compare "$T/gt.ldb#7" "$T/id.loomf"
expect_err_contains cmp_bad_exemplar_msg "no exemplar '7'"
# another geometry: a clear error naming both
expect_exit cmp_geometry 1 "$LOOM" compare "$T/id.loomf" "$LOOM_BUILD/share/loom/default.ldb#0" \
	--region 0,0:8,6
expect_err_contains cmp_geometry_msg "default.ldb#0 24x16x48"
expect_err_contains cmp_geometry_msg_a "id.loomf has blocks of 8x6x12"
expect_exit cmp_extent 1 "$LOOM" compare "$T/id.loomf" "$T/gtw.ldb#0"
expect_err_contains cmp_extent_msg "128x72x12"
expect_err_contains cmp_extent_msg_b "96x48x12"

# a fabric against itself and against its ground truth: perfect agreement
check_perfect() { # name json
	if python3 - "$2" >"$T/py" 2>&1 <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
keys = ["top_agreement_centres", "top_agreement_columns", "height_rmse",
        "height_rmse_debiased", "height_rmse_diameters", "block_offset_sd",
        "histogram_l1", "coverage_a", "coverage_b", "seam_ratio_a", "seam_ratio_b",
        "corner_seam_ratio_a", "corner_seam_ratio_b", "corner_pairs_a", "corner_pairs_b",
        "coverage_seam_ratio_a", "coverage_seam_ratio_b", "voxels", "seconds"]
assert sorted(j) == sorted(keys), sorted(j)
assert j["top_agreement_centres"] == 1 and j["top_agreement_columns"] == 1, j
assert j["height_rmse"] == 0 and j["block_offset_sd"] == 0 and j["histogram_l1"] == 0, j
assert j["coverage_a"] == j["coverage_b"] > 0.5 and j["seam_ratio_a"] == j["seam_ratio_b"] > 0, j
assert j["corner_seam_ratio_a"] == j["corner_seam_ratio_b"] > 0, j
assert j["corner_pairs_a"] == j["corner_pairs_b"] > 0, j
assert j["coverage_seam_ratio_a"] == j["coverage_seam_ratio_b"] > 0, j
assert j["voxels"] == 128 * 72 * 12, j
PY
	then pass "$1"; else fail "$1" "$(head -c 600 "$T/py")"; fi
}
expect_ok cmp_self "$LOOM" compare "$T/id.loomf" "$T/id.loomf" --json
cp "$T/out" "$T/self.json"
check_perfect cmp_self_perfect "$T/self.json"
expect_ok cmp_gt "$LOOM" compare "$T/id.loomf" "$T/gt.ldb#0" --json
cp "$T/out" "$T/gt.json"
check_perfect cmp_identity_is_gt "$T/gt.json"

# synthesized (the tiny default weaves) against the ground truth: every
# figure against a brute-force computation from exported volumes
expect_ok cmp_tiny_db "$LOOM" exemplar generate --preset tiny --quiet -o "$T/tiny.ldb"
expect_ok cmp_synth "$LOOM" synth "$T/hb.pbm" --db "$T/tiny.ldb" --quiet -o "$T/syn.loomf"
expect_ok cmp_synth_gt "$LOOM" compare "$T/syn.loomf" "$T/id.loomf" --json \
	--pictures "$T/pics"
cp "$T/out" "$T/syn.json"
expect_ok cmp_table "$LOOM" compare "$T/syn.loomf" "$T/gt.ldb#design"
expect_out_contains cmp_table_text "block offset SD"
# one input: its own figures, the same as its _a figures against another
# (which the brute-force check below verifies)
expect_ok cmp_alone "$LOOM" compare "$T/syn.loomf" --json
cp "$T/out" "$T/alone.json"
if python3 - "$T/alone.json" "$T/syn.json" >"$T/py" 2>&1 <<'PY'
import json, sys
a, j = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
assert sorted(a) == sorted(["coverage", "seam_ratio", "corner_seam_ratio", "corner_pairs",
                            "coverage_seam_ratio", "voxels", "seconds"]), sorted(a)
for k in ("coverage", "seam_ratio", "corner_seam_ratio", "corner_pairs", "coverage_seam_ratio"):
    assert a[k] == j[k + "_a"], (k, a[k], j[k + "_a"])
assert a["seam_ratio"] > 0 and a["voxels"] == j["voxels"], a
PY
then pass cmp_alone_equals_a; else fail cmp_alone_equals_a "$(head -c 600 "$T/py")"; fi
expect_ok cmp_alone_table "$LOOM" compare "$T/gt.ldb#design"
expect_out_contains cmp_alone_table_text "seam ratio"
for f in syn id; do
	expect_ok "cmp_export_$f" "$LOOM" export "$T/$f.loomf" --all --format nrrd \
		--channels density,kind --tile 1000,1000 --quiet -o "$T/x_$f"
done
if python3 - "$T/syn.json" "$T/x_syn" "$T/x_id" "$LOOM_TOP/tests/cli/pngread.py" \
	"$T/pics" >"$T/py" 2>&1 <<'PY'
import glob, json, math, struct, sys
j = json.load(open(sys.argv[1]))
nx, ny, nz, b1, b2 = 128, 72, 12, 8, 6
def load(d, ch):
    f = [p for p in glob.glob(d + "/**/*.nrrd", recursive=True) if ch in p.split("/")[-1]]
    assert len(f) == 1, (d, ch, f)
    b = open(f[0], "rb").read()
    i = b.index(b"\n\n")
    hdr, data = b[:i].decode(), b[i + 2:]
    if "type: float" in hdr:
        return [round(v * 255) for v in struct.unpack("<%df" % (len(data) // 4), data)]
    return list(data)
def tops(d):
    dens, kind = load(d, "density"), load(d, "kind")
    H, K, T = {}, {}, {}
    hist = {1: [0] * 16, 2: [0] * 16}
    for i, v in enumerate(dens):
        if v and kind[i] in hist:
            hist[kind[i]][(v - 1) * 16 // 255] += 1
    for y in range(ny):
        for x in range(nx):
            for z in range(nz - 1, -1, -1):
                i = (z * ny + y) * nx + x
                if dens[i] >= 51 and kind[i]:
                    H[x, y], K[x, y] = z + 1, kind[i]
                    t = z
                    while t >= 0 and kind[(t * ny + y) * nx + x] == kind[i] and dens[(t * ny + y) * nx + x] >= 51:
                        t -= 1
                    T[x, y] = z - t
                    break
    return H, K, T, hist
Ha, Ka, Ta, hia = tops(sys.argv[2])
Hb, Kb, Tb, hib = tops(sys.argv[3])
both = [c for c in Ha if c in Hb]
d = [Hb[c] - Ha[c] for c in both]
mean = sum(d) / len(d)
rmse = math.sqrt(sum(v * v for v in d) / len(d))
deb = math.sqrt(max(0, sum(v * v for v in d) / len(d) - mean * mean))
agree = sum(Ka[c] == Kb[c] for c in both) / len(both)
cen = [c for c in both if c[0] % b1 == b1 // 2 and c[1] % b2 == b2 // 2]
agc = sum(Ka[c] == Kb[c] for c in cen) / len(cen)
blocks = {}
for c, v in zip(both, d):
    blocks.setdefault((c[0] // b1, c[1] // b2), []).append(v)
bm = [sum(v) / len(v) for v in blocks.values()]
bmean = sum(bm) / len(bm)
bosd = math.sqrt(max(0, sum(m * m for m in bm) / len(bm) - bmean * bmean))
thick = sum(Ta.values()) / len(Ta)
def l1(a, b):
    na, nb = sum(a), sum(b)
    return sum(abs(x / na - y / nb) for x, y in zip(a, b))
hl1 = 0.5 * (l1(hia[1], hib[1]) + l1(hia[2], hib[2]))
def seam(H):
    s = [0, 0, 0, 0]
    for (x, y), h in H.items():
        for (u, v, edge) in ((x + 1, y, (x + 1) % b1 == 0), (x, y + 1, (y + 1) % b2 == 0)):
            if (u, v) in H:
                k = 0 if edge else 2
                s[k] += abs(H[u, v] - h)
                s[k + 1] += 1
    return (s[0] / s[1]) / (s[2] / s[3])
def corner(H):  # the seam pairs next to a point where four blocks meet
    s = [0, 0, 0, 0]
    for (x, y), h in H.items():
        for (u, v, edge, rim) in ((x + 1, y, (x + 1) % b1 == 0, y % b2 in (0, b2 - 1)),
                                  (x, y + 1, (y + 1) % b2 == 0, x % b1 in (0, b1 - 1))):
            if (u, v) in H:
                if edge and rim:
                    s[0] += abs(H[u, v] - h)
                    s[1] += 1
                elif not edge:
                    s[2] += abs(H[u, v] - h)
                    s[3] += 1
    return (s[0] / s[1]) / (s[2] / s[3]), s[1]
def cov_seam(H):  # pairs with a top on one side only: across edges / inside
    s = [0, 0, 0, 0]
    for x in range(nx):
        for y in range(ny):
            for (u, v, edge) in ((x + 1, y, (x + 1) % b1 == 0), (x, y + 1, (y + 1) % b2 == 0)):
                if u < nx and v < ny:
                    k = 0 if edge else 2
                    s[k] += ((x, y) in H) != ((u, v) in H)
                    s[k + 1] += 1
    return (s[0] / s[1]) / (s[2] / s[3])
corner_a, corner_b = corner(Ha), corner(Hb)
want = {"top_agreement_columns": agree, "top_agreement_centres": agc, "height_rmse": rmse,
        "height_rmse_debiased": deb, "height_rmse_diameters": deb / thick,
        "block_offset_sd": bosd, "histogram_l1": hl1, "coverage_a": len(Ha) / (nx * ny),
        "coverage_b": len(Hb) / (nx * ny), "seam_ratio_a": seam(Ha), "seam_ratio_b": seam(Hb),
        "corner_seam_ratio_a": corner_a[0], "corner_seam_ratio_b": corner_b[0],
        "corner_pairs_a": corner_a[1], "corner_pairs_b": corner_b[1],
        "coverage_seam_ratio_a": cov_seam(Ha), "coverage_seam_ratio_b": cov_seam(Hb)}
for k, v in want.items():
    assert abs(j[k] - v) < 1e-6 * max(1, abs(v)), (k, j[k], v)
assert 0 < agree < 1 and rmse > 0 and bosd > 0, want
assert want["corner_seam_ratio_a"] != want["seam_ratio_a"], want
# pictures: PNGs of the right sizes (an independent reader)
sys.path.insert(0, sys.argv[4].rsplit("/", 1)[0])
import pngread
w, h = pngread.read(sys.argv[5] + "/side-by-side.png")[:2]
assert (w, h) == (2 * nx + 8, ny), (w, h)
w, h = pngread.read(sys.argv[5] + "/height-difference.png")[:2]
assert (w, h) == (nx, ny), (w, h)
PY
then pass cmp_brute_force; else fail cmp_brute_force "$(head -c 900 "$T/py")"; fi

# volume inputs: a fabric against its own exported tile (.vol and NRRD,
# density + kind), a shifted copy, another cloth, and bad geometry
expect_ok vol_export "$LOOM" export "$T/syn.loomf" --all --format vol --channels density,kind \
	--tile 1000,1000 --quiet -o "$T/v_syn"
VD=$(find "$T/v_syn" -name '*.density.vol')
ND=$(find "$T/x_syn" -name '*.density.nrrd')
expect_ok vol_self "$LOOM" compare "$T/syn.loomf" "$VD" --json
cp "$T/out" "$T/vself.json"
expect_ok nrrd_self "$LOOM" compare "$T/syn.loomf" "$ND" --json
cp "$T/out" "$T/nself.json"
expect_ok vol_nrrd "$LOOM" compare "$VD" "$ND" --block 8x6x12 --json
cp "$T/out" "$T/vn.json"
# the same comparison with B read from the fabric and from its NRRD export
expect_ok vol_gt_fabric "$LOOM" compare "$T/id.loomf" "$T/syn.loomf" --json
cp "$T/out" "$T/idsyn.json"
expect_ok vol_gt_nrrd "$LOOM" compare "$T/id.loomf" "$ND" --json
cp "$T/out" "$T/idnrrd.json"
# a copy of the tile placed one voxel further along x (its header's origin),
# and one with 50 um voxels
mkdir -p "$T/shift"
python3 - "${ND%.density.nrrd}" "$T/shift" <<'PY'
import sys
src, dst = sys.argv[1], sys.argv[2]
for c in ("density", "kind"):
    b = open("%s.%s.nrrd" % (src, c), "rb").read()
    i = b.index(b"\n\n")
    h = b[:i].decode()
    assert "space origin: (0.036," in h, h
    open("%s/s.%s.nrrd" % (dst, c), "wb").write(
        h.replace("space origin: (0.036,", "space origin: (0.108,").encode() + b[i:])
    assert "(0.072,0,0) (0,0.072,0) (0,0,0.072)" in h, h
    open("%s/v50.%s.nrrd" % (dst, c), "wb").write(
        h.replace("(0.072,0,0) (0,0.072,0) (0,0,0.072)",
                  "(0.05,0,0) (0,0.05,0) (0,0,0.05)").encode() + b[i:])
PY
expect_ok vol_shifted "$LOOM" compare "$T/syn.loomf" "$T/shift/s.density.nrrd" --json
cp "$T/out" "$T/shift.json"
if python3 - "$T" >"$T/py" 2>&1 <<'PY'
import json, sys
t = sys.argv[1]
J = lambda n: json.load(open("%s/%s.json" % (t, n)))
for n in ("vself", "nself", "vn"):
    j = J(n)
    for k in ("top_agreement_centres", "top_agreement_columns"):
        assert j[k] == 1, (n, k, j[k])
    for k in ("height_rmse", "height_rmse_debiased", "block_offset_sd", "histogram_l1"):
        assert j[k] == 0, (n, k, j[k])
    assert j["coverage_a"] == j["coverage_b"] > 0.9, (n, j)
    assert j["seam_ratio_a"] == j["seam_ratio_b"] > 0, (n, j)
    assert j["voxels"] == 128 * 72 * 12, (n, j["voxels"])
a, b = J("idsyn"), J("idnrrd")
for k in a:
    if k != "seconds":
        assert a[k] == b[k], (k, a[k], b[k])
assert a["height_rmse"] > 0 and a["top_agreement_columns"] < 1, a
s = J("shift")
assert s["voxels"] == 128 * 72 * 12, s
assert s["top_agreement_columns"] < 0.99 and s["height_rmse"] > 0.1, s
PY
then pass vol_figures; else fail vol_figures "$(head -c 900 "$T/py")"; fi
# bad input: another voxel size, no kind volume, two volumes without --block,
# a region outside the volume, different boxes
expect_exit vol_voxel_size 1 "$LOOM" compare "$T/syn.loomf" "$T/shift/v50.density.nrrd"
expect_err_contains vol_voxel_size_a "syn.loomf has blocks of 8x6x12 voxels of 72 um"
expect_err_contains vol_voxel_size_b "v50.density.nrrd 8x6x12 of 50 um"
cp "$T/shift/s.density.nrrd" "$T/shift/alone.density.nrrd"
expect_exit vol_no_kind 1 "$LOOM" compare "$T/syn.loomf" "$T/shift/alone.density.nrrd"
expect_err_contains vol_no_kind_msg "alone.kind.nrrd"
expect_exit vol_no_block 2 "$LOOM" compare "$VD" "$ND"
expect_err_contains vol_no_block_msg "--block"
expect_exit vol_region_out 1 "$LOOM" compare "$T/syn.loomf" "$VD" --region 64,0:200,12
expect_err_contains vol_region_out_msg "not inside"
expect_exit vol_boxes 1 "$LOOM" compare "$VD" "$T/shift/s.density.nrrd" --block 8x6x12
expect_err_contains vol_boxes_msg "0,0,0:128,72,12"

# The edge fix is calibrated against the woven cloth (docs/fidelity.md,
# "Calibrating the edge fix"): it keeps the woven seams' own jumps instead
# of closing them, and its correction stays near the edges.  On a 24 x 24
# herringbone (tiny preset, the default set), against the woven reference:
# the synthesized seam ratio is within 0.8-1.2 of the reference's (the fix
# that closed the seams gave 0.70 here), and the block-offset SD and the
# debiased height RMSE stay within 20 % of those without the fix (0.188 and
# 0.535 against 0.128 and 0.398 before the calibration).  The sub-voxel
# blend keeps the woven densities ("Densities at the floor", "Blending the
# top voxel only"): the density histogram L1 stays within 1.1 times that
# without the fix (0.038 against 0.036; the floor, a second weaving, is
# 0.033; blending every surface voxel gave 0.042, the linear blend 0.092,
# blending two yarn voxels 0.059).
expect_ok cal_db "$LOOM" exemplar generate --preset tiny --seed 1 -q -o "$T/cal.ldb"
expect_ok cal_pattern "$LOOM" pattern make herringbone --size 24x24 -q -o "$T/cal.pbm"
expect_ok cal_gt "$LOOM" exemplar generate --design "$T/cal.pbm" --like "$T/cal.ldb" \
	--seed 1 -q -o "$T/calgt.ldb"
expect_ok cal_fix "$LOOM" synth "$T/cal.pbm" --db "$T/cal.ldb" -q -o "$T/calfix.loomf"
expect_ok cal_nofix "$LOOM" synth "$T/cal.pbm" --db "$T/cal.ldb" --rank 0 -q \
	-o "$T/cal0.loomf"
expect_ok cal_cmp_fix "$LOOM" compare "$T/calgt.ldb#0" "$T/calfix.loomf" --json
cp "$T/out" "$T/calfix.json"
expect_ok cal_cmp_nofix "$LOOM" compare "$T/calgt.ldb#0" "$T/cal0.loomf" --json
cp "$T/out" "$T/cal0.json"
if python3 - "$T/calfix.json" "$T/cal0.json" >"$T/py" 2>&1 <<'PY'
import json, sys
f, z = (json.load(open(p)) for p in sys.argv[1:3])
r = f["seam_ratio_b"] / f["seam_ratio_a"]
assert 0.8 <= r <= 1.2, ("seam ratio against the reference's", r, f)
assert f["block_offset_sd"] <= 1.2 * z["block_offset_sd"], (f, z)
assert f["height_rmse_debiased"] <= 1.2 * z["height_rmse_debiased"], (f, z)
assert f["histogram_l1"] <= 1.1 * z["histogram_l1"], ("histogram", f, z)
PY
then pass cal_seams_as_woven; else fail cal_seams_as_woven "$(head -c 900 "$T/py")"; fi
