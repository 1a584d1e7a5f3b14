#!/bin/sh
# bench/fidelity.sh - predictive fidelity of synthesis against the woven
# ground truth (docs/fidelity.md).  For each design of the suite: weave the
# whole design as one exemplar (loom exemplar generate --design, the
# database's geometry, seed 1), the same with seed 2 (the floor: how far
# two weavings of the same design differ), synthesize the design from the
# default database with the edge fix (the default rank, full) and without (rank 0), and
# compare each with the seed-1 reference.  The sample WIFs of data/ are
# woven as their first WINDOW x WINDOW crossings (--window; default 96) and
# compared over that corner of the synthesized whole design.  Prints a
# markdown table.
#   usage: bench/fidelity.sh [LOOM] [DB] [WORKDIR] [WINDOW]
#   (FIDELITY_DESIGNS="herringbone-8 ..." runs a part of the suite;
#   FIDELITY_SIZE=N weaves the generated designs at N x N crossings, default
#   32; at the paper preset use 24 or more: 12 x 12 is within the noise of
#   two weavings, docs/fidelity.md "Paper preset"; FIDELITY_GEN="--fibre cotton" adds options to the ground truth's
#   generation: give the fibre the database DB was made with;
#   FIDELITY_REUSE=1 keeps the references already in WORKDIR, to compare
#   another database against the same ones; FIDELITY_SYNTH="--rank 15"
#   adds options to the synthesis, e.g. the smaller rank of the former default)
# Leaves in WORKDIR, per design D: D-synthesis.json (loom synth --json),
# D-floor.json, D-synth.json and D-rank0.json (loom compare --json against
# the seed-1 reference; bench/fidelity-draws.sh reads them) and
# D-pictures/ (loom compare --pictures of the synthesized fabric).
set -eu
LOOM=${1:-build/loom}
DB=${2:-build/share/loom/default.ldb}
W=${3:-build/fidelity}
WIN=${4:-96}
TOP=$(cd "$(dirname "$0")/.." && pwd)
S=${FIDELITY_SIZE:-32}
mkdir -p "$W"
"$LOOM" pattern make herringbone --size ${S}x$S -q -o "$W/herringbone.pbm"
"$LOOM" pattern make wavy-twill --size ${S}x$S -q -o "$W/wavy-twill.pbm"
"$LOOM" pattern make broken-twill --size ${S}x$S -q -o "$W/broken-twill.pbm"
"$LOOM" pattern make basket --size ${S}x$S -q -o "$W/basket.pbm"
"$LOOM" pattern make satin:1/7 --size ${S}x$S -q -o "$W/satin-1-7.pbm"
"$LOOM" pattern make satin:1/9 --size ${S}x$S -q -o "$W/satin-1-9.pbm"
cp "$TOP/data/herringbone-8.wif" "$TOP/data/overshot-sampler.wif" "$W/"
get() { python3 -c "import json,sys; print('%.3f' % json.load(open(sys.argv[1]))[sys.argv[2]])" "$1" "$2"; }
# block size of DB (b1 b2)
set -- $("$LOOM" exemplar info "$DB" --json | python3 -c "import json,sys; b=json.load(sys.stdin)['block']; print(b[0], b[1])")
B1=$1; B2=$2
printf '| design | crossings | consistency | pair | top agreement (columns) | height RMSE debiased | block-offset SD | histogram L1 | seam ratio (ref %s) | at block corners (ref %s) | coverage seams (ref %s) |\n' "->" "->" "->"
printf '|---|---|---|---|---|---|---|---|---|---|---|\n'
for d in ${FIDELITY_DESIGNS:-herringbone wavy-twill broken-twill basket satin-1-7 satin-1-9 herringbone-8 overshot-sampler}; do
	f=$W/$d.pbm
	win=""
	region=""
	if [ ! -e "$f" ]; then
		f=$W/$d.wif
		win="--window 0,0:$WIN,$WIN"
		region="--region 0,0:$((WIN * B1)),$((WIN * B2))"
	fi
	for seed in 1 2; do
		[ "${FIDELITY_REUSE:-0}" = 1 ] && [ -s "$W/$d-gt$seed.ldb" ] && continue
		# shellcheck disable=SC2086
		"$LOOM" exemplar generate --design "$f" --like "$DB" --seed $seed $win ${FIDELITY_GEN:-} --quiet -o "$W/$d-gt$seed.ldb"
	done
	# shellcheck disable=SC2086
	"$LOOM" synth "$f" --db "$DB" ${FIDELITY_SYNTH:-} --json -o "$W/$d.loomf" >"$W/$d-synthesis.json"
	"$LOOM" synth "$f" --db "$DB" --rank 0 --quiet -o "$W/$d-r0.loomf"
	rows=$(python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print('%dx%d' % (j['rows'], j['cols']))" "$W/$d-synthesis.json")
	[ -n "$win" ] && rows="$rows ($WIN x $WIN compared)"
	cons=$(get "$W/$d-synthesis.json" consistency)
	for pair in floor synth rank0; do
		case $pair in
		floor) b="$W/$d-gt2.ldb#0"; label="seed 2 vs seed 1 (floor)" ;;
		synth) b="$W/$d.loomf"; label="synthesized, ${FIDELITY_SYNTH:-full rank (default)}" ;;
		rank0) b="$W/$d-r0.loomf"; label="synthesized, no edge fix" ;;
		esac
		pics=""
		[ "$pair" = synth ] && pics="--pictures $W/$d-pictures"
		# shellcheck disable=SC2086
		"$LOOM" compare "$W/$d-gt1.ldb#0" "$b" --json $pics $region >"$W/$d-$pair.json"
		j=$W/$d-$pair.json
		printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s -> %s | %s -> %s | %s -> %s |\n' "$d" "$rows" "$cons" \
			"$label" "$(get "$j" top_agreement_columns)" "$(get "$j" height_rmse_debiased)" \
			"$(get "$j" block_offset_sd)" "$(get "$j" histogram_l1)" \
			"$(get "$j" seam_ratio_a)" "$(get "$j" seam_ratio_b)" \
			"$(get "$j" corner_seam_ratio_a)" "$(get "$j" corner_seam_ratio_b)" \
			"$(get "$j" coverage_seam_ratio_a)" "$(get "$j" coverage_seam_ratio_b)"
	done
done
