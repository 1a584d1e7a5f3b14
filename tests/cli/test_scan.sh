# `loom scan` end to end: usage errors, JSON keys, the checksum identical
# for any thread count, budget, tile size and shard split (and additive
# over disjoint regions through --combine), histogram and coverage equal to
# a brute force over an exported region read back by Python.
SUITE=scan
. "$LOOM_TOP/tests/cli/lib.sh"
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf
REG=-100,-60,-5:140,90,50

expect_ok help "$LOOM" scan --help
expect_out_contains help_text "--reduce"
expect_exit no_args 2 "$LOOM" scan
expect_ok synth "$LOOM" synth "$WIF" --quiet -o "$F"
expect_exit no_reduce 2 "$LOOM" scan "$F" --region "$REG"
expect_exit bad_reduce 2 "$LOOM" scan "$F" --region "$REG" --reduce sum
expect_exit no_region 2 "$LOOM" scan "$F" --reduce checksum
expect_exit bad_region 2 "$LOOM" scan "$F" --region 0,0,0-10,10,10 --reduce checksum
expect_err_contains bad_region_msg "bad --region '0,0,0-10,10,10'"
expect_exit bad_bolt 2 "$LOOM" scan "$F" --all --bolt 3 --reduce checksum
expect_exit bolt_no_all 2 "$LOOM" scan "$F" --region "$REG" --bolt 1x1 --reduce checksum
expect_exit bins_no_hist 2 "$LOOM" scan "$F" --region "$REG" --reduce checksum --bins 8
expect_exit coverage_tz 2 "$LOOM" scan "$F" --region "$REG" --reduce coverage --tile 32,32,10
expect_exit budget_small 2 "$LOOM" scan "$F" --region "$REG" --reduce checksum --tile 1000,1000 --budget 4
expect_exit missing_fabric 1 "$LOOM" scan "$T/nope.loomf" --region "$REG" --reduce checksum
expect_exit combine_nothing 2 "$LOOM" scan --combine

# checksum: JSON keys, then the same value whatever the threads, budget,
# tile size and shard split
expect_ok cs_json "$LOOM" scan "$F" --region "$REG" --reduce checksum --json --quiet
cp "$T/out" "$T/cs.json"
if python3 - "$T/cs.json" >"$T/py" 2>&1 <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
for k in ("voxels", "seconds", "voxels_per_second", "peak_rss_bytes", "checksum"):
    assert k in j, k
assert j["voxels"] == 240 * 150 * 55, j["voxels"]
assert len(j["checksum"]) == 16 and int(j["checksum"], 16) != 0
assert j["peak_rss_bytes"] > 1 << 20
print(j["checksum"])
EOF
then pass cs_keys; else fail cs_keys "$(tail -3 "$T/py")"; fi
CS=$(sed -n 's/.*"checksum": "\([0-9a-f]*\)".*/\1/p' "$T/cs.json")
check_cs() { # NAME ARGS...: the checksum with these options equals $CS
	n=$1; shift
	"$LOOM" scan "$F" --region "$REG" --reduce checksum --json --quiet "$@" >"$T/out" 2>"$T/err"
	got=$(sed -n 's/.*"checksum": "\([0-9a-f]*\)".*/\1/p' "$T/out")
	if [ -n "$got" ] && [ "$got" = "$CS" ]; then pass "$n"; else
		fail "$n" "checksum '$got' with $*, expected $CS; $(head -c 300 "$T/err")"; fi
}
check_cs cs_threads2 --threads 2
check_cs cs_budget8 --budget 8
check_cs cs_budget8_t2 --budget 8 --threads 2
check_cs cs_tile_small --tile 17,23
check_cs cs_tile_z --tile 40,30,7 --threads 2
check_cs cs_tile_one --tile 240,150,55
check_cs cs_tile_column --tile 1,1 --budget 8
# tiles in index order instead of grouped by source block: the same value
export LOOM_TILE_ORDER=index
check_cs cs_index_order --threads 2 --budget 8
check_cs cs_index_order_tiles --tile 17,23,9
unset LOOM_TILE_ORDER
for s in 0 1 2 3; do
	"$LOOM" scan "$F" --region "$REG" --reduce checksum --tile 24,24,20 --shard $s/4 \
		--json --quiet >"$T/part$s.json" 2>/dev/null
done
expect_ok cs_combine "$LOOM" scan --combine "$T/part0.json" "$T/part1.json" "$T/part2.json" "$T/part3.json"
cp "$T/out" "$T/comb.txt"
expect_out_contains cs_combine_value "checksum $CS"
# other splits, tilings with several chunks of the source order (2 x 2
# tiles: 9000 a layer, 3 chunks) and 40 shards of few tiles: every tile
# once (the parts add up to the whole)
check_split() { # NAME N TILE
	n=$2
	parts=""
	for s in $(seq 0 $((n - 1))); do
		"$LOOM" scan "$F" --region "$REG" --reduce checksum --tile "$3" --shard $s/$n --json \
			--quiet -o "$T/sp$s.json" 2>"$T/err" || fail "$1" "shard $s/$n: $(cat "$T/err")"
		parts="$parts $T/sp$s.json"
	done
	# shellcheck disable=SC2086
	"$LOOM" scan --combine $parts --json >"$T/out" 2>"$T/err"
	got=$(sed -n 's/.*"checksum": "\([0-9a-f]*\)".*/\1/p' "$T/out")
	if [ "$got" = "$CS" ]; then pass "$1"; else fail "$1" "checksum '$got' over $n shards of $3, expected $CS"; fi
	rm -f "$T"/sp*.json
}
check_split cs_split7 7 17,23,20
check_split cs_split5_chunks 5 2,2,55
check_split cs_split40 40 60,50
export LOOM_TILE_ORDER=index
check_split cs_split3_index 3 2,2,55
unset LOOM_TILE_ORDER

# every shard must be there, once; time and voxels add up over the parts
expect_exit cs_combine_missing 1 "$LOOM" scan --combine "$T/part0.json" "$T/part2.json"
expect_err_contains cs_combine_missing_msg "2 of 4 shards missing: 1,3"
if [ -s "$T/out" ]; then fail cs_combine_missing_silent "a result was printed"
else pass cs_combine_missing_silent; fi
expect_exit cs_combine_twice 1 "$LOOM" scan --combine "$T/part0.json" "$T/part0.json" \
	"$T/part1.json" "$T/part2.json" "$T/part3.json"
expect_err_contains cs_combine_twice_msg "shard 0/4 given twice"
expect_ok cs_combine_json "$LOOM" scan --combine "$T/part0.json" "$T/part1.json" "$T/part2.json" \
	"$T/part3.json" --json -o "$T/comb.json"
if [ -s "$T/out" ]; then fail cs_combine_o_stdout "printed with -o"; else pass cs_combine_o_stdout; fi
if python3 - "$T" "$CS" >"$T/py" 2>&1 <<'EOF2'
import json, os, sys
d, cs = sys.argv[1], sys.argv[2]
parts = [json.load(open(os.path.join(d, "part%d.json" % i))) for i in range(4)]
c = json.load(open(os.path.join(d, "comb.json")))
assert c["checksum"] == cs and c["complete"] and c["shards"] == 4 and c["parts"] == 4, c
assert c["voxels"] == sum(p["voxels"] for p in parts) == 240 * 150 * 55, c
s = sum(p["seconds"] for p in parts)
assert s > 0 and abs(c["seconds"] - s) < 1e-6 * s + 1e-9, (c["seconds"], s)
assert abs(c["voxels_per_second"] - c["voxels"] / c["seconds"]) < 1e-3 * c["voxels_per_second"]
assert abs(c["cpu_seconds"] - sum(p["cpu_seconds"] for p in parts)) < 1e-6
assert c["bytes_read"] == sum(p["bytes_read"] for p in parts) > 0
assert c["fabric_crc32"] == parts[0]["fabric_crc32"] and len(c["fabric_crc32"]) == 8
# a shard reads less of the database than the whole region does
whole = json.load(open(os.path.join(d, "cs.json")))
assert max(p["bytes_read"] for p in parts) < whole["bytes_read"], ([p["bytes_read"] for p in parts], whole["bytes_read"])
print("ok")
EOF2
then pass cs_combine_sums; else fail cs_combine_sums "$(tail -5 "$T/py")"; fi
# shards of another tiling hold other tiles: refused
"$LOOM" scan "$F" --region "$REG" --reduce checksum --tile 30,24,20 --shard 1/4 --json --quiet \
	>"$T/part1t.json" 2>/dev/null
expect_exit cs_combine_tiles 1 "$LOOM" scan --combine "$T/part0.json" "$T/part1t.json" \
	"$T/part2.json" "$T/part3.json"
expect_err_contains cs_combine_tiles_msg "shards must use the same --tile"
expect_exit cs_combine_mixed 1 "$LOOM" scan --combine "$T/part0.json" "$T/cs.json"
# parts of another fabric are refused
"$LOOM" synth "$WIF" --seed 7 --quiet -o "$T/other.loomf"
"$LOOM" scan "$T/other.loomf" --region "$REG" --reduce checksum --tile 24,24,20 --shard 3/4 \
	--json --quiet >"$T/part3o.json" 2>/dev/null
expect_exit cs_combine_fabric 1 "$LOOM" scan --combine "$T/part0.json" "$T/part1.json" \
	"$T/part2.json" "$T/part3o.json"
expect_err_contains cs_combine_fabric_msg "a scan of another fabric"
# disjoint regions add up to the whole
"$LOOM" scan "$F" --region -100,-60,-5:20,90,50 --reduce checksum --json --quiet >"$T/left.json" 2>/dev/null
"$LOOM" scan "$F" --region 20,-60,-5:140,90,50 --reduce checksum --json --quiet >"$T/right.json" 2>/dev/null
expect_ok cs_halves "$LOOM" scan --combine "$T/left.json" "$T/right.json" --json
expect_out_contains cs_halves_value "\"checksum\": \"$CS\""
# and a different region gives a different checksum
"$LOOM" scan "$F" --region -100,-60,-5:140,90,47 --reduce checksum --json --quiet >"$T/out" 2>&1
if grep -q "\"checksum\": \"$CS\"" "$T/out" || ! grep -q '"checksum"' "$T/out"; then
	fail cs_sensitive "a thinner region has the same checksum (or none)"
else pass cs_sensitive; fi

# --all with --bolt (a quarter repeat each way) on two threads
expect_ok all_bolt "$LOOM" scan "$F" --all --bolt 0.25x0.25 --reduce coverage --threads 2 --json --quiet
expect_out_contains all_bolt_voxels '"voxels": 42467328'

# histogram and coverage against a brute force over an export read back
R=-30,-20,0:50,44,48
expect_ok export "$LOOM" export "$F" --region $R --format vol --channels density,kind,type \
	--tile 80,64 --quiet -o "$T/ex"
expect_ok hist "$LOOM" scan "$F" --region $R --reduce histogram --bins 8 --tile 16,16,12 --threads 2 --json --quiet
cp "$T/out" "$T/hist.json"
expect_ok cov "$LOOM" scan "$F" --region $R --reduce coverage --tile 24,10 --json --quiet
cp "$T/out" "$T/cov.json"
for s in 0 1 2; do
	"$LOOM" scan "$F" --region $R --reduce histogram --bins 8 --shard $s/3 --json --quiet >"$T/h$s.json" 2>/dev/null
	"$LOOM" scan "$F" --region $R --reduce coverage --shard $s/3 --json --quiet >"$T/c$s.json" 2>/dev/null
done
"$LOOM" scan --combine "$T/h0.json" "$T/h1.json" "$T/h2.json" --json >"$T/hcomb.json" 2>/dev/null
"$LOOM" scan --combine "$T/c0.json" "$T/c1.json" "$T/c2.json" --json >"$T/ccomb.json" 2>/dev/null
if python3 - "$T" >"$T/py" 2>&1 <<'EOF'
import json, os, struct, sys
d = sys.argv[1]
nx, ny, nz = 80, 64, 48
def vol(ch):
    b = open(os.path.join(d, "ex", "tile-0-0-0.%s.vol" % ch), "rb").read()
    enc, x, y, z, c = struct.unpack_from("<5i", b, 4)
    assert (x, y, z, c) == (nx, ny, nz, 1)
    if enc == 3:
        return list(b[48:])
    return [int(v) for v in struct.unpack_from("<%df" % (nx * ny * nz), b, 48)]
dens, kind, typ = vol("density"), vol("kind"), vol("type")
bins = 8
hist = {}
for dv, k, t in zip(dens, kind, typ):
    if k:
        hist.setdefault(t, [0] * bins)[dv * bins // 256] += 1
cov = [0, 0, 0]
for y in range(ny):
    for x in range(nx):
        top = 0
        for z in range(nz - 1, -1, -1):
            i = (z * ny + y) * nx + x
            if dens[i]:
                top = kind[i]
                break
        cov[top] += 1
for name in ("hist.json", "hcomb.json"):
    h = json.load(open(os.path.join(d, name)))
    assert h["voxels"] == nx * ny * nz
    hh = h["histogram"]
    assert hh["bins"] == bins
    for t in hh["types"]:
        assert t["counts"] == hist.get(t["type"], [0] * bins), (name, t, hist.get(t["type"]))
    assert hh["nonempty"] == sum(sum(v) for v in hist.values()), name
    assert sum(1 for v in hist.values() if sum(v)) >= 2
for name in ("cov.json", "ccomb.json"):
    c = json.load(open(os.path.join(d, name)))["coverage"]
    assert [c["none"], c["warp"], c["weft"]] == cov, (name, c, cov)
    assert abs(c["warp_fraction"] - cov[1] / (nx * ny)) < 1e-9
assert cov[1] > 0 and cov[2] > 0, cov
print("ok", cov)
EOF
then pass brute_force; else fail brute_force "$(tail -4 "$T/py")"; fi
