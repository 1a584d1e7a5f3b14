# Exemplar coverage of the default database (docs/fidelity.md, "Exemplar
# coverage"): `loom synth` over the default database reaches a consistency
# of at least 0.95 on a suite of real drafts and generated weaves, and the
# figure it reports is the one a brute-force count of the neighbourhood
# codes (Python, from the design and `exemplar info --json`) gives.
SUITE=coverage
. "$LOOM_TOP/tests/cli/lib.sh"
# drafts that state a sett would otherwise get a cached sett database
LOOM_CACHE_DIR=$T/cache
export LOOM_CACHE_DIR

for k in herringbone wavy-twill broken-twill basket plain; do
	expect_ok "make_$k" "$LOOM" pattern make "$k" --size 32x32 -q -o "$T/$k.pbm"
done
expect_ok make_hb8 "$LOOM" pattern convert "$LOOM_TOP/data/herringbone-8.wif" -q \
	-o "$T/herringbone-8.pbm"
expect_ok make_overshot "$LOOM" pattern convert "$LOOM_TOP/data/overshot-sampler.wif" -q \
	-o "$T/overshot-sampler.pbm"
# a two-colour Jacquard: a diamond of 1/7 twill on 7/1 satin (paper Fig. 13c)
python3 - "$T/jq.ppm" <<'PY'
import sys
n = 48
with open(sys.argv[1], "w") as f:
    f.write("P3\n%d %d\n255\n" % (n, n))
    for y in range(n):
        f.write(" ".join("200 0 0" if abs(x - 23.5) + abs(y - 23.5) < 16 else "240 232 208"
                         for x in range(n)) + "\n")
PY
cat >"$T/jq.map" <<'EOF'
yarn red  #b01818
yarn gold #e0b030
colour #c80000 twill:1/7 warp=red weft=gold
colour #f0e8d0 satin:7/1 warp=red weft=gold
EOF
expect_ok make_jacquard "$LOOM" pattern from-image "$T/jq.ppm" --map "$T/jq.map" -q \
	-o "$T/jacquard.pbm"

expect_ok default_info "$LOOM" exemplar info --json
cp "$T/out" "$T/db.json"
suite="herringbone wavy-twill broken-twill basket plain jacquard"
for d in $suite; do
	expect_ok "synth_$d" "$LOOM" synth "$T/$d.pbm" --json -o "$T/$d.loomf"
	cp "$T/out" "$T/$d.json"
done
# the drafts as users give them (WIF), and their weave images
for d in herringbone-8 overshot-sampler; do
	expect_ok "synth_$d" "$LOOM" synth "$LOOM_TOP/data/$d.wif" --json -o "$T/$d.loomf"
	cp "$T/out" "$T/$d.json"
done
if python3 - "$T" "$T/db.json" $suite herringbone-8 overshot-sampler >"$T/py" 2>&1 <<'PY'
import json, sys
top, db = sys.argv[1], json.load(open(sys.argv[2]))

def pbm(path):
    data = open(path, "rb").read()
    toks, i = [], 0
    while len(toks) < 3:
        while data[i:i + 1].isspace():
            i += 1
        if data[i:i + 1] == b"#":
            i = data.index(b"\n", i)
            continue
        s = i
        while not data[i:i + 1].isspace():
            i += 1
        toks.append(data[s:i])
    i += 1
    w, h = int(toks[1]), int(toks[2])
    stride = (w + 7) // 8
    return [[(data[i + r * stride + c // 8] >> (7 - c % 8)) & 1 for c in range(w)]
            for r in range(h)]

def codes(W):
    # loom_synth_code: self | up << 1 | down << 2 | left << 3 | right << 4, wrapping
    R, C = len(W), len(W[0])
    return [W[i][j] | W[(i - 1) % R][j] << 1 | W[(i + 1) % R][j] << 2 |
            W[i][(j - 1) % C] << 3 | W[i][(j + 1) % C] << 4
            for i in range(R) for j in range(C)]

have = set()
for e in db["exemplars"]:
    have |= set(codes([[int(ch) for ch in row] for row in e["weave"]]))
bad = []
for d in sys.argv[3:]:
    got = json.load(open("%s/%s.json" % (top, d)))["consistency"]
    cs = codes(pbm("%s/%s.pbm" % (top, d)))
    want = sum(c in have for c in cs) / len(cs)
    print("%s %.4f (brute force %.4f)" % (d, got, want))
    if abs(got - want) > 1e-6:
        bad.append("%s: loom says %.6f, the code count %.6f" % (d, got, want))
    if got < 0.95:
        bad.append("%s: consistency %.4f < 0.95" % (d, got))
assert not bad, bad
PY
then pass suite_consistency; else fail suite_consistency "$(head -c 900 "$T/py")"; fi

rm -rf "$T"
