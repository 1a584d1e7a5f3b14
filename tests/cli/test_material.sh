# Materials per yarn type (docs/exemplars.md, "Materials per yarn type"):
# loom synth --yarn-fibre TYPE=F and mapping-file fibre=F; a design of
# several (warp, weft) material pairs gets a database with one set of
# exemplars per pair, and each crossing copies its own pair's blocks.
SUITE=material
. "$LOOM_TOP/tests/cli/lib.sh"
W=$LOOM_TOP/tests/data/wif
export LOOM_CACHE_DIR="$T/cache"
unset LOOM_DB
db_of() { # FABRIC -> database path it records
	"$LOOM" info "$1" --json | python3 -c \
		'import json,sys; print(json.load(sys.stdin)["database"]["path"])'
}

# single material: naming every type cotton changes nothing (the default
# database, the same fabric bytes as without the option)
expect_ok plain "$LOOM" synth "$W/basic-twill.wif" -o "$T/a.loomf" --quiet
expect_ok all_cotton "$LOOM" synth "$W/basic-twill.wif" --yarn-fibre 0=cotton \
	--yarn-fibre "weft #000080=cotton" -o "$T/b.loomf" --quiet
expect_same single_material_same_bytes "$T/a.loomf" "$T/b.loomf"
if [ ! -e "$T/cache" ]; then pass single_material_no_generation; else
	fail single_material_no_generation "$(ls "$T/cache")"; fi

# a silk warp stripe (ends 5..9 of 20) in a cotton cloth, from a mapping file
python3 - "$T" <<'PY'
import sys
t = sys.argv[1]
with open(t + "/stripe.ppm", "w") as f:
    f.write("P3\n20 20\n255\n")
    for y in range(20):
        f.write(" ".join("200 0 0" if 5 <= x < 10 else "0 200 0" for x in range(20)) + "\n")
with open(t + "/stripe.map", "w") as f:
    f.write("yarn silkwarp #f0f0e0 fibre=silk\nyarn cot #c0c0c0\n"
            "colour #c80000 twill:2/3 warp=silkwarp weft=cot\n"
            "colour #00c800 twill:2/3 warp=cot weft=cot\n")
PY
expect_ok stripe "$LOOM" synth "$T/stripe.ppm" --map "$T/stripe.map" -o "$T/s.loomf" --json
expect_err_contains stripe_generated "yarns cotton/cotton, silk/cotton: generated $T/cache/sett-"
python3 - "$T/out" <<'PY' && pass stripe_usage || fail stripe_usage "$(head -c 600 "$T/out")"
import json, sys
u = json.load(open(sys.argv[1]))["usage"]
silk = sum(e["crossings"] for e in u if e["name"].endswith("@si-co"))
cot = sum(e["crossings"] for e in u if e["name"].endswith("@co-co"))
assert silk == 100 and cot == 300, (silk, cot)   # 5 of 20 ends are silk
PY
p=$(db_of "$T/s.loomf")
"$LOOM" exemplar info "$p" --json >"$T/info.json"
python3 - "$T/info.json" <<'PY' && pass stripe_tags || fail stripe_tags "$(head -c 300 "$T/info.json")"
import json, sys
ex = json.load(open(sys.argv[1]))["exemplars"]
assert len(ex) == 26   # two pairs of the thirteen default weaves
assert all(e["fibre_warp"] == ("cotton" if i < 13 else "silk") and e["fibre_weft"] == "cotton"
           for i, e in enumerate(ex))
PY
expect_ok stripe_verify "$LOOM" exemplar verify "$p"
# the default database records no material
"$LOOM" exemplar info "$LOOM_BUILD/share/loom/default.ldb" --json >"$T/d.json"
if grep -q fibre_warp "$T/d.json"; then fail default_untagged "tagged"; else pass default_untagged; fi
# determinism: again (cached database), the same bytes
expect_ok stripe_again "$LOOM" synth "$T/stripe.ppm" --map "$T/stripe.map" -o "$T/s2.loomf" --quiet
expect_same stripe_same_bytes "$T/s.loomf" "$T/s2.loomf"

# --yarn-fibre by name or index: the same database and fabric
expect_ok by_name "$LOOM" synth "$W/colors.wif" --yarn-fibre "warp #c80000 0.5mm=silk" \
	-o "$T/c1.loomf" --quiet
expect_ok by_index "$LOOM" synth "$W/colors.wif" --yarn-fibre 1=silk -o "$T/c2.loomf" --quiet
expect_same by_name_index_same "$T/c1.loomf" "$T/c2.loomf"
case "$(db_of "$T/c1.loomf")" in "$T/cache/sett-"*) pass by_name_generated ;;
	*) fail by_name_generated "$(db_of "$T/c1.loomf")" ;; esac

# bad input: usage errors naming the option and what was expected
expect_exit bad_type 2 "$LOOM" synth "$W/colors.wif" --yarn-fibre "nylon-warp=silk" -o "$T/x.loomf"
expect_err_contains bad_type_msg "--yarn-fibre nylon-warp=silk: the design has no yarn type 'nylon-warp' (its types: 0 'warp #ffffff 0.5mm', 1 'warp #c80000 0.5mm'"
expect_exit bad_index 2 "$LOOM" synth "$W/colors.wif" --yarn-fibre 7=silk -o "$T/x.loomf"
expect_err_contains bad_index_msg "the design has no yarn type '7'"
expect_exit bad_fibre 2 "$LOOM" synth "$W/colors.wif" --yarn-fibre 1=tweed -o "$T/x.loomf"
expect_err_contains bad_fibre_msg "TYPE=F: a yarn type (name or index) and a fibre: cotton, rayon"
expect_exit no_equals 2 "$LOOM" synth "$W/colors.wif" --yarn-fibre silk -o "$T/x.loomf"
printf 'yarn a #ffffff fibre=tweed\ncolour #c80000 plain warp=a weft=a\n' >"$T/bad.map"
expect_exit bad_map 1 "$LOOM" synth "$T/stripe.ppm" --map "$T/bad.map" -o "$T/x.loomf"
expect_err_contains bad_map_msg "bad.map:1: fibre must be cotton, rayon, silk, polyester, wool, linen, monofilament or none, got 'tweed'"
# more pairs than a database holds: an error naming the limit
python3 - "$T" <<'PY'
import sys
t = sys.argv[1]
cols = ["200 0 0", "0 200 0", "0 0 200", "200 200 0", "0 200 200"]
with open(t + "/five.ppm", "w") as f:
    f.write("P3\n10 4\n255\n")
    for y in range(4):
        f.write(" ".join(cols[x // 2] for x in range(10)) + "\n")
with open(t + "/five.map", "w") as f:
    for n, fb in zip("abcde", ["silk", "wool", "linen", "rayon", "polyester"]):
        f.write("yarn %s #808080 fibre=%s\n" % (n, fb))
    f.write("yarn cot #ffffff\n")
    for c, n in zip(["#c80000", "#00c800", "#0000c8", "#c8c800", "#00c8c8"], "abcde"):
        f.write("colour %s plain warp=%s weft=cot\n" % (c, n))
PY
expect_exit five_pairs 1 "$LOOM" synth "$T/five.ppm" --map "$T/five.map" -o "$T/x.loomf"
expect_err_contains five_pairs_msg "the design uses 5 (warp, weft) material pairs (silk/cotton, wool/cotton, linen/cotton, rayon/cotton, polyester/cotton); a generated database holds at most 4"
# with --db of one pair: a warning, all exemplars used
expect_ok with_db "$LOOM" synth "$W/colors.wif" --yarn-fibre 1=silk \
	--db "$LOOM_BUILD/share/loom/default.ldb" -o "$T/y.loomf"
expect_err_contains with_db_warn "warning: --yarn-fibre:"
# with --db of the stripe's database, a pair it lacks: an error
expect_exit db_lacks_pair 1 "$LOOM" synth "$W/colors.wif" --yarn-fibre 1=wool --db "$p" -o "$T/z.loomf"
expect_err_contains db_lacks_pair_msg "of wool and weft yarn type"
# painting a fibre material (docs/fabric.md "Painted fibres"): a silk warp
# over crossings 4..7 x 12..15 of the cotton part of the stripe fabric
# (crossings 24 x 16 voxels of 24 um: centres (J+0.5)*0.576, (I+0.5)*0.384 mm)
PF="--rect 7.0,1.6:9.1,3.0 --yarn warp --fibre silk"
expect_ok paint_fibre "$LOOM" paint "$T/s.loomf" $PF -q -o "$T/pf.loomp"
if [ "$(head -1 "$T/pf.loomp")" = "loom-paint 3" ] &&
   grep -qx "region fibre 7 1.6 9.1 3 kind=warp rgb=0,0,0 strength=0 blend=0 amount=0 band=1 fibre=silk" "$T/pf.loomp"
then pass paint_fibre_file; else fail paint_fibre_file "$(cat "$T/pf.loomp")"; fi
expect_ok paint_fibre_again "$LOOM" paint "$T/s.loomf" $PF -q -o "$T/pf2.loomp"
expect_same paint_fibre_same_bytes "$T/pf.loomp" "$T/pf2.loomp"
# read back: a colour added to the file keeps the fibre region as written
expect_ok paint_fibre_chain "$LOOM" paint "$T/pf.loomp" --rect 0,0:1,1 --yarn any --rgb 0.5,0.5,0.5 -q -o "$T/pf3.loomp"
if [ "$(sed -n 3p "$T/pf3.loomp")" = "$(sed -n 3p "$T/pf.loomp")" ] && [ "$(grep -c '^region ' "$T/pf3.loomp")" = 2 ]
then pass paint_fibre_read_back; else fail paint_fibre_read_back "$(cat "$T/pf3.loomp")"; fi
# --rgb and --fibre together: a colour region, then a fibre region
expect_ok paint_fibre_rgb "$LOOM" paint "$T/s.loomf" $PF --rgb 0.8,0.8,0.7 -q -o "$T/pf4.loomp"
if grep -q '^region yarn 7 1.6 9.1 3 kind=warp rgb=0.8,0.8,0.7 ' "$T/pf4.loomp" && grep -q '^region fibre ' "$T/pf4.loomp"
then pass paint_fibre_rgb_regions; else fail paint_fibre_rgb_regions "$(cat "$T/pf4.loomp")"; fi
# the voxels: a box around the region exported from the fabric and the
# paint file; density and albedo differ only at the crossings re-assigned
# (painted 4..7 x 12..15 and the band of 1), their four neighbours, and
# the one corner column of a diagonal neighbour of the band's corner that
# faces it (the corner term takes the mean of the four crossings meeting
# at a corner: docs/synthesis.md "Block corners"), and differ at the
# painted ones
XF="--region 192,0,0:480,192,48 --tile 288,192,48 --format vol --channels density,albedo --quiet"
expect_ok export_unpainted "$LOOM" export "$T/s.loomf" $XF -o "$T/e0"
expect_ok export_fibre "$LOOM" export "$T/pf.loomp" $XF -o "$T/e1"
python3 - "$T/e0" "$T/e1" <<'PY' && pass paint_fibre_voxels || fail paint_fibre_voxels "$(cat "$T/pyout" 2>/dev/null)"
import glob, os, struct, sys
def vol(path):
    b = open(path, "rb").read()
    assert b[:4] == b"VOL\x03"
    enc, X, Y, Z, C = struct.unpack("<5i", b[4:24])
    return X, Y, Z, C * {1: 4, 3: 1}[enc], b[48:]
changed = painted = 0
for ch in ("density", "albedo"):
    a = glob.glob(os.path.join(sys.argv[1], "*.%s.vol" % ch)); b = glob.glob(os.path.join(sys.argv[2], "*.%s.vol" % ch))
    assert len(a) == 1 and len(b) == 1, (a, b)
    X, Y, Z, E, va = vol(a[0]); _, _, _, _, vb = vol(b[0])
    assert (X, Y, Z) == (288, 192, 48) and len(va) == len(vb) == X * Y * Z * E
    for z in range(Z):
        for y in range(Y):
            k0 = (z * Y + y) * X * E
            if va[k0:k0 + X * E] == vb[k0:k0 + X * E]:
                continue
            for x in range(X):
                k = k0 + x * E
                if va[k:k + E] == vb[k:k + E]:
                    continue
                J, I = (x + 192) // 24, y // 16
                di = 4 - I if I < 4 else max(I - 7, 0)
                dj = 12 - J if J < 12 else max(J - 15, 0)
                assert max(di, dj) <= 2, (x, y, z, I, J)
                if di == 2 and dj == 2:  # only the corner column facing the band
                    assert y % 16 == (15 if I < 4 else 0) and (x + 192) % 24 == (0 if J > 15 else 23), (x, y, z, I, J)
                changed += 1
                painted += di == 0 and dj == 0
assert painted > 1000, (changed, painted)
PY
# determinism: a render of the paint file, 1 and 2 threads, and it differs
# from the unpainted fabric's
R="--width 64 --height 40 --spp 1 --elevation 89 --quiet"
expect_ok render_unpainted "$LOOM" render "$T/s.loomf" $R -o "$T/r0.png"
expect_ok render_fibre1 "$LOOM" render "$T/pf.loomp" $R --threads 1 -o "$T/r1.png"
expect_ok render_fibre2 "$LOOM" render "$T/pf.loomp" $R --threads 2 -o "$T/r2.png"
expect_same render_fibre_threads "$T/r1.png" "$T/r2.png"
if cmp -s "$T/r0.png" "$T/r1.png"; then fail render_fibre_differs "same bytes"; else pass render_fibre_differs; fi
# bad input
expect_exit paint_bad_fibre 2 "$LOOM" paint "$T/s.loomf" --rect 0,0:1,1 --yarn warp --fibre tweed -o "$T/x.loomp"
expect_err_contains paint_bad_fibre_msg "--fibre: expected cotton, rayon, silk, polyester, wool, linen, monofilament or none, got 'tweed'"
expect_exit paint_fibre_no_yarn 2 "$LOOM" paint "$T/s.loomf" --rect 0,0:1,1 --fibre silk --defect stain -o "$T/x.loomp"
expect_exit paint_missing_pair 1 "$LOOM" paint "$T/s.loomf" --rect 7.0,1.6:9.1,3.0 --yarn weft --fibre wool -o "$T/x.loomp"
expect_err_contains paint_missing_pair_msg "painted fibre: crossing (4, 12) would have the (warp, weft) pair cotton/wool, but the database has exemplars of the pairs cotton/cotton, silk/cotton only; for a database with the pairs needed, synthesize the fabric with the material per yarn type (loom synth DESIGN --yarn-fibre TYPE=wool"
if [ ! -e "$T/x.loomp" ]; then pass paint_missing_pair_no_output; else fail paint_missing_pair_no_output "written"; fi
printf 'loom-paint 2\nfabric %s\nregion fibre 0 0 1 1 kind=warp band=1 fibre=silk\n' "$T/s.loomf" >"$T/v2.loomp"
expect_exit paint_fibre_v2 1 "$LOOM" render "$T/v2.loomp" $R -o "$T/x.png"
expect_err_contains paint_fibre_v2_msg "v2.loomp:3: a fibre region needs version 3"
rm -rf "$T"
