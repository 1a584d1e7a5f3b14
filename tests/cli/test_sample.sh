# `loom sample` end to end: one position (--at, nearest and trilinear,
# text and JSON), random lookups (--random) with timing and cache
# statistics, the checksum identical for any budget and thread count,
# exit codes, a budget too small, a database that is not the fabric's, a
# corrupted brick.  JSON is checked by Python's parser.
SUITE=sample
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf

expect_ok help "$LOOM" sample --help
expect_out_contains help_text "--random"
expect_exit no_args 2 "$LOOM" sample
expect_exit no_mode 2 "$LOOM" sample "$F"
expect_exit both_modes 2 "$LOOM" sample "$F" --at 1,2,3 --random 5
expect_exit bad_at 2 "$LOOM" sample "$F" --at 1,2
expect_exit bad_at_text 2 "$LOOM" sample "$F" --at 1,x,3
expect_exit bad_filter 2 "$LOOM" sample "$F" --at 1,2,3 --filter cubic
expect_exit filter_random 2 "$LOOM" sample "$F" --random 5 --filter trilinear
expect_exit bad_threads 2 "$LOOM" sample "$F" --random 5 --threads 0
expect_exit bad_budget 2 "$LOOM" sample "$F" --random 5 --budget -3
expect_exit unknown_opt 2 "$LOOM" sample "$F" --at 1,2,3 --frob
expect_exit missing_fabric 1 "$LOOM" sample "$T/nope.loomf" --at 1,2,3
expect_err_contains missing_fabric_msg "nope.loomf"

# a small database (tiny preset, 4x4x8 bricks: several bricks per block)
# and a fabric of a WIF draft from data/
expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok make_db2 "$LOOM" exemplar generate --preset tiny --seed 4 --quiet -o "$T/other.ldb"
expect_ok synth "$LOOM" synth "$WIF" --db "$DB" --quiet -o "$F"

# --at: text and JSON
expect_ok at_text "$LOOM" sample "$F" --at 10,20,5
expect_out_contains at_text_density "density"
expect_out_contains at_text_kind "kind"
expect_ok at_json "$LOOM" sample "$F" --at 10,20,5 --json
cp "$T/out" "$T/at.json"
expect_ok at_json_centre "$LOOM" sample "$F" --at 10.5,20.5,5.5 --filter trilinear --json
cp "$T/out" "$T/centre.json"
expect_ok at_json_tri "$LOOM" sample "$F" --at 10.3,20.9,5.2 --filter trilinear --json
cp "$T/out" "$T/tri.json"
expect_ok at_json_below "$LOOM" sample "$F" --at 10,20,-1 --json
cp "$T/out" "$T/below.json"
expect_ok at_json_far "$LOOM" sample "$F" --at 123456789012,-98765432109,5 --json
cp "$T/out" "$T/far.json"
if python3 - "$T" >"$T/py" 2>&1 <<'EOF'
import json, math, sys
d = sys.argv[1]
def load(n):
    j = json.load(open(d + "/" + n))
    for k in ("density", "orientation", "kind", "type", "albedo"):
        assert k in j, (n, k)
    assert 0 <= j["density"] <= 1, j
    assert len(j["orientation"]) == 3 and len(j["albedo"]) == 3, j
    assert j["kind"] in (0, 1, 2), j
    if j["density"] > 0:
        n2 = sum(v * v for v in j["orientation"])
        assert abs(n2 - 1) < 1e-5 and j["orientation"][2] >= 0, j
    if j["kind"] == 0:
        assert j["albedo"] == [0, 0, 0] and j["type"] == 0, j
    else:
        assert any(a > 0 for a in j["albedo"]), j
    return j
at, centre, tri = load("at.json"), load("centre.json"), load("tri.json")
below, far = load("below.json"), load("far.json")
assert at["position"] == [10, 20, 5], at["position"]
# trilinear at a voxel centre is the voxel itself
assert abs(centre["density"] - at["density"]) < 1e-7, (centre, at)
assert centre["kind"] == at["kind"] and centre["type"] == at["type"]
assert below["density"] == 0 and below["kind"] == 0
print("ok")
EOF
then pass at_json_keys; else fail at_json_keys "$(head -c 600 "$T/py")"; fi
expect_exit at_out_of_range 1 "$LOOM" sample "$F" --at 9223372036854775807,0,0
expect_err_contains at_out_of_range_msg "out of range"

# --random: JSON keys; the checksum is the same for any budget and thread
# count (tiny budgets: a few bricks beside the 230 KB the fabric holds)
expect_ok random_json "$LOOM" sample "$F" --random 20000 --seed 5 --json
cp "$T/out" "$T/r1.json"
expect_ok random_small_budget "$LOOM" sample "$F" --random 20000 --seed 5 --budget 0.6 --json
cp "$T/out" "$T/r2.json"
expect_ok random_threads "$LOOM" sample "$F" --random 20000 --seed 5 --threads 3 --budget 1 --json
cp "$T/out" "$T/r3.json"
expect_ok random_other_seed "$LOOM" sample "$F" --random 20000 --seed 6 --json
cp "$T/out" "$T/r4.json"
if python3 - "$T" >"$T/py" 2>&1 <<'EOF'
import json, sys
d = sys.argv[1]
r = [json.load(open("%s/r%d.json" % (d, k))) for k in (1, 2, 3, 4)]
for j in r:
    for k in ("lookups", "lookups_per_second", "hit_rate", "peak_rss_bytes",
              "misses", "evictions", "bytes_read", "bytes_decompressed",
              "peak_cache_bytes", "budget_bytes", "checksum"):
        assert k in j, k
    assert j["lookups"] == 20000 and j["lookups_per_second"] > 0
    assert 0 <= j["hit_rate"] <= 1 and j["peak_rss_bytes"] > 0
    assert j["peak_cache_bytes"] <= j["budget_bytes"], j
    assert j["errors"] == 0
assert r[0]["checksum"] == r[1]["checksum"] == r[2]["checksum"], [x["checksum"] for x in r]
assert r[0]["checksum"] != r[3]["checksum"]
assert r[0]["nonempty"] == r[1]["nonempty"] == r[2]["nonempty"] > 0
assert r[1]["evictions"] > 0 and r[1]["hit_rate"] < r[0]["hit_rate"]
assert r[2]["threads"] == 3
print("ok")
EOF
then pass random_json_keys; else fail random_json_keys "$(head -c 600 "$T/py")"; fi
expect_ok random_text "$LOOM" sample "$F" --random 1000
expect_out_contains random_text_rate "lookups/s"
expect_out_contains random_text_rss "peak RSS"

# budget too small: exit 1, the bytes needed in the message
expect_exit budget_too_small 1 "$LOOM" sample "$F" --random 10 --budget 0.001
expect_err_contains budget_too_small_msg "needs at least"

# another database: refused (the fabric's content hash)
expect_exit wrong_db 1 "$LOOM" sample "$F" --db "$T/other.ldb" --at 1,2,3
expect_err_contains wrong_db_msg "content hash"

# a corrupted brick (a flipped byte in a copy): an error naming the brick,
# exit 1, no crash
cp "$DB" "$T/bad.ldb"
"$LOOM" exemplar info "$DB" --json >"$T/info.json"
python3 - "$T/bad.ldb" "$T/info.json" <<'EOF'
import json, sys
p = sys.argv[1]
stored = sum(e["compressed_bytes"] for e in json.load(open(sys.argv[2]))["exemplars"])
b = bytearray(open(p, "rb").read())
for off in range(128 + 500, 128 + stored, 1500):  # bricks: [128, 128 + stored)
    b[off] ^= 0x5A
open(p, "wb").write(b)
EOF
expect_exit corrupt 1 "$LOOM" sample "$F" --db "$T/bad.ldb" --random 30000 --seed 1
expect_err_contains corrupt_msg "brick"
expect_err_contains corrupt_crc "CRC32"
