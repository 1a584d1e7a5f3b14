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
assert len(ex) == 22
assert all(e["fibre_warp"] == ("cotton" if i < 11 else "silk") and e["fibre_weft"] == "cotton"
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
rm -rf "$T"
