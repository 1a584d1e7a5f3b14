#!/bin/sh
# bench/fidelity-draws.sh - the fidelity suite (bench/fidelity.sh) over
# several draws of the exemplar set: databases that differ only in their
# seed (loom exemplar generate --preset P --seed S), compared with the same
# woven references.  Synthesis copies a handful of small exemplars (16 x 16
# crossings for the satins of the small preset's default database, 8 x 8 at
# the paper preset) many times over, so their own chance shape
# does not average out as it does in a 32 x 32 woven reference: one draw
# can put a figure far from what the method gives on average
# (docs/fidelity.md, "Exemplar draws").  Prints each draw's table, then per
# design the floor and the synthesized figures' mean and range over draws,
# and each exemplar's own seam ratio per draw.
#   usage: bench/fidelity-draws.sh [LOOM] [WORKDIR] [WINDOW]
#   FIDELITY_DB_SEEDS="1 2 3" (default) the database seeds;
#   FIDELITY_PRESET=small (default) the databases' preset;
#   FIDELITY_DB_OPTS="..." more options of loom exemplar generate (default
#   for the small preset "--min-crossings 10", as the default database,
#   so seed 1 is that database byte for byte, FIDELITY_DB_OPTS= for the
#   generator's own 4; none for the other presets);
#   FIDELITY_DESIGNS, FIDELITY_SIZE, FIDELITY_GEN, FIDELITY_SYNTH, FIDELITY_REUSE as in
#   bench/fidelity.sh (FIDELITY_REUSE=1 also keeps databases already made)
set -eu
case ${1:-} in
-h | --help) sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
-*) echo "fidelity-draws.sh: unknown option '$1' (usage: bench/fidelity-draws.sh [LOOM] [WORKDIR] [WINDOW])" >&2; exit 2 ;;
esac
LOOM=${1:-build/loom}
W=${2:-build/fidelity-draws}
WIN=${3:-96}
TOP=$(cd "$(dirname "$0")/.." && pwd)
SEEDS=${FIDELITY_DB_SEEDS:-1 2 3}
PRESET=${FIDELITY_PRESET:-small}
if [ "$PRESET" = small ]; then
	DB_OPTS=${FIDELITY_DB_OPTS---min-crossings 10}
else
	DB_OPTS=${FIDELITY_DB_OPTS:-}
fi
for s in $SEEDS; do # every seed checked before any work
	case $s in
	'' | *[!0-9]*) echo "fidelity-draws.sh: FIDELITY_DB_SEEDS: '$s' is not a seed (expected numbers)" >&2; exit 2 ;;
	esac
done
[ -n "$SEEDS" ] || { echo "fidelity-draws.sh: FIDELITY_DB_SEEDS is empty" >&2; exit 2; }
mkdir -p "$W"
first=""
for s in $SEEDS; do
	db=$W/db-$s.ldb
	if [ "${FIDELITY_REUSE:-0}" != 1 ] || [ ! -s "$db" ]; then
		# shellcheck disable=SC2086
		"$LOOM" exemplar generate --preset "$PRESET" --seed "$s" $DB_OPTS --quiet -o "$db"
	fi
	mkdir -p "$W/seed-$s"
	# each exemplar's own seam ratio (loom compare DB#K, one input):
	# synthesis copies an exemplar's seams with its blocks, so the
	# synthesized seam ratio follows the draw's (docs/fidelity.md, "The
	# satins' seams follow their exemplar")
	"$LOOM" exemplar info "$db" --json >"$W/seed-$s/exemplars.json"
	n=$(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['exemplars']))" "$W/seed-$s/exemplars.json")
	k=0
	while [ "$k" -lt "$n" ]; do
		"$LOOM" compare "$db#$k" --json >"$W/seed-$s/exemplar-$k.json"
		k=$((k + 1))
	done
	reuse=${FIDELITY_REUSE:-0}
	if [ -n "$first" ]; then
		# the same woven references for every draw (they depend on the
		# database's geometry only, which the seed does not change)
		for g in "$W/seed-$first"/*-gt[12].ldb; do
			[ -e "$g" ] || continue # no reference made (the glob unmatched)
			ln -f "$g" "$W/seed-$s/" 2>/dev/null || cp "$g" "$W/seed-$s/"
		done
		reuse=1
	fi
	echo "database seed $s ($db)"
	FIDELITY_REUSE=$reuse sh "$TOP/bench/fidelity.sh" "$LOOM" "$db" "$W/seed-$s" "$WIN"
	echo
	[ -n "$first" ] || first=$s
done
# shellcheck disable=SC2086
python3 - "$W" $SEEDS <<'EOF'
import json, os, sys
w, seeds = sys.argv[1], sys.argv[2:]
keys = [("top_agreement_columns", "top agreement"), ("height_rmse_debiased", "height RMSE debiased"),
        ("block_offset_sd", "block-offset SD"), ("histogram_l1", "histogram L1"),
        ("seam", "seam ratio / reference's"), ("corner", "corners / reference's"),
        ("cover", "coverage seams / reference's")]
RATIOS = {"seam": "seam_ratio", "corner": "corner_seam_ratio", "cover": "coverage_seam_ratio"}
def val(j, k):
    if k not in RATIOS:
        return j[k]
    a, b = j.get(RATIOS[k] + "_a"), j.get(RATIOS[k] + "_b")  # None: an older loom compare
    return b / a if a and b is not None else float("nan")
d0 = os.path.join(w, "seed-" + seeds[0])
designs = (os.environ.get("FIDELITY_DESIGNS") or "herringbone wavy-twill broken-twill basket "
           "satin-1-7 satin-1-9 herringbone-8 overshot-sampler").split()
print("Over %d database draws (seeds %s): floor (seed-2 reference vs seed 1) and the synthesized fabric's mean [min - max]"
      % (len(seeds), " ".join(seeds)))
print()
print("| design | pair | " + " | ".join(n for _, n in keys) + " |")
print("|---|---|" + "---|" * len(keys))
for d in designs:
    floor = json.load(open(os.path.join(d0, d + "-floor.json")))
    print("| %s | floor | " % d + " | ".join("%.3f" % val(floor, k) for k, _ in keys) + " |")
    for pair, label in (("synth", os.environ.get("FIDELITY_SYNTH") or "full rank (default)"),
                        ("rank0", "no edge fix")):
        vs = []
        for s in seeds:
            p = os.path.join(w, "seed-" + s, "%s-%s.json" % (d, pair))
            if os.path.exists(p):
                vs.append(json.load(open(p)))
        cells = []
        for k, _ in keys:
            xs = [val(j, k) for j in vs]
            cells.append("%.3f [%.3f - %.3f]" % (sum(xs) / len(xs), min(xs), max(xs)) if xs else "-")
        print("| %s | %s | " % (d, label) + " | ".join(cells) + " |")
print()
print("Each exemplar's own seam ratio (loom compare DB#K), per draw (seeds %s), and the mean:" % " ".join(seeds))
print()
print("| exemplar | crossings | " + " | ".join("seed " + s for s in seeds) + " | mean |")
print("|---|---|" + "---|" * (len(seeds) + 1))
ex = json.load(open(os.path.join(d0, "exemplars.json")))["exemplars"]
for e in ex:
    xs = []
    for s in seeds:
        p = os.path.join(w, "seed-" + s, "exemplar-%d.json" % e["index"])
        xs.append(json.load(open(p))["seam_ratio"] if os.path.exists(p) else float("nan"))
    print("| %s | %dx%d | " % (e["name"], e["crossings"][0], e["crossings"][1])
          + " | ".join("%.3f" % x for x in xs) + " | %.3f |" % (sum(xs) / len(xs)))
EOF
