# tools/slurm/ without a scheduler: the scripts parse, submit.sh refuses bad
# command lines (exit 2, saying what it expected) before it submits
# anything, and merge.sbatch, run as Slurm would run it after a task died,
# fails naming the missing shards and prints the command that resubmits
# only those.  tests/slurm/run.sh runs them on a real Slurm.
SUITE=slurm_scripts
. "$LOOM_TOP/tests/cli/lib.sh"
S=$LOOM_TOP/tools/slurm
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf

for f in submit.sh merge.sbatch; do
	expect_ok "syntax_$f" bash -n "$S/$f"
done
for f in export.sbatch scan.sbatch; do
	expect_ok "syntax_$f" sh -n "$S/$f"
done
expect_exit submit_nothing 2 "$S/submit.sh"
expect_exit submit_kind 2 "$S/submit.sh" render "$F" --shards 4 -o "$T/x"
expect_err_contains submit_kind_msg "unknown kind 'render'"
expect_exit submit_no_shards 2 "$S/submit.sh" export "$F" --format vol -o "$T/x"
expect_err_contains submit_no_shards_msg "missing --shards N"
expect_exit submit_bad_shards 2 "$S/submit.sh" export "$F" --shards 0 --format vol -o "$T/x"
expect_exit submit_shard 2 "$S/submit.sh" scan "$F" --shards 4 --shard 1/4 -o "$T/x.json"
expect_err_contains submit_shard_msg "give --shards N"
expect_exit submit_no_out 2 "$S/submit.sh" scan "$F" --shards 4 --reduce checksum
expect_exit submit_bad_only 2 "$S/submit.sh" scan "$F" --shards 4 --only 'x' -o "$T/x.json"

expect_ok synth "$LOOM" synth "$WIF" --quiet -o "$F"
R=0,0,0:128,96,48
export LOOM LOOM_SHARD_COUNT=4 LOOM_SLURM_DIR=$S
# scan: parts 1 and 3 missing
mkdir -p "$T/s.json.parts"
for i in 0 2; do
	"$LOOM" scan "$F" --region $R --reduce checksum --shard $i/4 --json --quiet \
		-o "$T/s.json.parts/part-$i-of-4.json"
done
expect_exit merge_scan_missing 1 bash "$S/merge.sbatch" scan "$F" "$T/s.json" --region $R \
	--reduce checksum
expect_err_contains merge_scan_names "shards 1,3 of 4 are not complete"
expect_out_contains merge_scan_cmd "RESUBMIT: LOOM=$LOOM $S/submit.sh scan $F --shards 4 --only 1,3 --region $R --reduce checksum -o $T/s.json"
for i in 1 3; do
	"$LOOM" scan "$F" --region $R --reduce checksum --shard $i/4 --json --quiet \
		-o "$T/s.json.parts/part-$i-of-4.json"
done
expect_ok merge_scan "bash" "$S/merge.sbatch" scan "$F" "$T/s.json" --region $R --reduce checksum
expect_ok ref_scan "$LOOM" scan "$F" --region $R --reduce checksum --json --quiet
cs=$(sed -n 's/.*"checksum": "\([0-9a-f]*\)".*/\1/p' "$T/out")
if grep -q "\"checksum\": \"$cs\"" "$T/s.json" 2>/dev/null; then pass merge_scan_checksum
else fail merge_scan_checksum "the combined result lacks checksum $cs"; fi

# export: shards 1 and 2 never ran, then a path with a space survives
mkdir -p "$T/e x"
for i in 0 3; do
	"$LOOM" export "$F" --region $R --format vol --tile 32,32 --shard $i/4 --quiet -o "$T/e x"
done
expect_exit merge_export_missing 1 bash "$S/merge.sbatch" export "$F" "$T/e x" --region $R \
	--format vol --tile 32,32
expect_err_contains merge_export_names "shards 1-2 of 4 are not complete"
cmd=$(sed -n 's/^RESUBMIT: //p' "$T/out")
# run the printed command with a stand-in sbatch that runs the job at once
mkdir -p "$T/bin"
cat >"$T/bin/sbatch" <<'EOS'
#!/bin/sh
# a stand-in for sbatch: run each array index (or the job) right away
array="" ; while [ $# -gt 0 ]; do case $1 in --array=*) array=${1#*=};; --*) ;; *) break;; esac; shift; done
script=$1; shift
if [ -n "$array" ]; then
	for i in $(echo "$array" | tr ',' ' '); do
		case $i in *-*) s=${i%-*}; e=${i#*-};; *) s=$i; e=$i;; esac
		for k in $(seq "$s" "$e"); do SLURM_ARRAY_TASK_ID=$k SLURM_ARRAY_TASK_COUNT=1 sh "$script" "$@" >/dev/null 2>&1 || exit 1; done
	done
	echo 100
else
	bash "$script" "$@" >/dev/null 2>&1 || exit 1
	echo 101
fi
EOS
chmod +x "$T/bin/sbatch"
expect_ok resubmit_runs env PATH="$T/bin:$PATH" sh -c "$cmd"
expect_ok merged "$LOOM" export --status "$T/e x" --verify
expect_out_contains merged_text "12 complete, 0 missing, 0 damaged"
