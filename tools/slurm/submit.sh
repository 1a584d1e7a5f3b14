#!/usr/bin/env bash
# tools/slurm/submit.sh - run a loom export or scan as a Slurm job array
# plus the step that merges (export) or combines (scan) its shards.
#
#   tools/slurm/submit.sh export FABRIC --shards N [loom export options] -o DIR
#   tools/slurm/submit.sh scan   FABRIC --shards N [loom scan options] -o RESULT.json
#
# Submits an array of N tasks (shard I of N each: loom's --shard auto, with
# LOOM_SHARD_COUNT=N so that a resubmitted part of the array keeps N), then
# the merge/combine job with --dependency=afterany on the array and
# --kill-on-invalid-dep=yes, and prints the array's job id, then the merge
# job's, one per line (sbatch --parsable).  The merge runs whatever the
# tasks' outcome; it checks that every shard is complete and, when some
# are not, fails naming them and printing the command that resubmits only
# those (this script with --only LIST), which resume where they stopped.
#
# Options of this script (the others go to loom unchanged):
#   --shards N      tasks of the array (1 .. 100000)
#   --only LIST     submit only these shards ("3,5-7", Slurm's --array
#                   syntax) of the N, and a new merge (the recovery step)
#   -o PATH         export: the output directory; scan: the result file
#                   (shard parts go to PATH.parts/)
# Each task asks for --cpus-per-task = loom's --threads (default 1) and
# --mem = --budget (default 64) + 32 MiB (the program and its libraries,
# LOOM_SLURM_MEM_EXTRA to change) + 16 bytes per crossing of the design
# (the fabric's design-sized tables; docs/batch.md, "Memory").  Environment:
#   LOOM              the loom command (default: loom on PATH)
#   LOOM_SBATCH_ARGS  more sbatch options for every job (e.g. --partition=p)
#   LOOM_SLURM_LOGS   directory of the jobs' logs (default: Slurm's, the
#                     directory sbatch runs in)
#   LOOM_SLURM_MERGE_MEM  --mem of the merge job, MiB (default: a task's;
#                     an export's merge holds every shard manifest: about
#                     2 x their bytes)
# docs/batch.md describes the whole procedure.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
prog="tools/slurm/submit.sh"
usage() {
	sed -n '4,5p' "${BASH_SOURCE[0]}" | sed 's/^# *//' >&2
	[ $# -gt 0 ] && echo "$prog: $*" >&2
	exit 2
}

[ $# -ge 2 ] || usage "give export or scan, and a FABRIC"
kind=$1
fabric=$2
shift 2
case $kind in
export | scan) ;;
*) usage "unknown kind '$kind' (export or scan)" ;;
esac
case $fabric in
-*) usage "give the FABRIC before the options" ;;
esac

shards="" only="" out="" threads=1 budget=64
pass=()
while [ $# -gt 0 ]; do
	a=$1
	case $a in
	--shards) [ $# -ge 2 ] || usage "--shards needs N"; shards=$2; shift 2; continue ;;
	--shards=*) shards=${a#*=} ;;
	--only) [ $# -ge 2 ] || usage "--only needs LIST"; only=$2; shift 2; continue ;;
	--only=*) only=${a#*=} ;;
	-o | --output) [ $# -ge 2 ] || usage "$a needs a path"; out=$2; shift 2; continue ;;
	-o=* | --output=*) out=${a#*=} ;;
	--shard | --shard=*) usage "the tasks choose their shard (--shard auto): give --shards N" ;;
	--merge | --merge=* | --status | --status=* | --combine) usage "$a is the merge job's" ;;
	--threads) [ $# -ge 2 ] || usage "--threads needs N"; threads=$2; pass+=("$a" "$2"); shift 2; continue ;;
	--threads=*) threads=${a#*=}; pass+=("$a") ;;
	--budget) [ $# -ge 2 ] || usage "--budget needs MB"; budget=$2; pass+=("$a" "$2"); shift 2; continue ;;
	--budget=*) budget=${a#*=}; pass+=("$a") ;;
	*) pass+=("$a") ;;
	esac
	shift
done
[ -n "$shards" ] || usage "missing --shards N"
case $shards in
'' | *[!0-9]*) usage "--shards: expected a number 1..100000, got '$shards'" ;;
esac
[ "$shards" -ge 1 ] && [ "$shards" -le 100000 ] ||
	usage "--shards: expected a number 1..100000, got '$shards'"
[ -n "$out" ] || usage "missing -o (export: DIR; scan: RESULT.json)"
case $threads in
'' | *[!0-9]*) usage "--threads: expected a number, got '$threads'" ;;
esac
case $only in
*[!0-9,-]*) usage "--only: expected a list like 3,5-7, got '$only'" ;;
esac
array=${only:-0-$((shards - 1))}

loom=${LOOM:-loom}
if ! command -v "$loom" >/dev/null 2>&1; then
	echo "$prog: the loom command '$loom' is not found (set LOOM)" >&2
	exit 1
fi
loom=$(command -v "$loom")
case $loom in
/*) ;;
*) loom=$(pwd)/$loom ;;
esac
[ -r "$fabric" ] || { echo "$prog: $fabric: cannot read the fabric" >&2; exit 1; }
# absolute paths: the jobs may start in another directory
abs() { case $1 in /*) printf '%s' "$1" ;; *) printf '%s/%s' "$(pwd)" "$1" ;; esac; }
fabric=$(abs "$fabric")
out=$(abs "$out")

# memory of a task: the whole loom budget, the program around it and the
# design-sized tables of the fabric (measured: about 5 bytes a crossing)
extra=${LOOM_SLURM_MEM_EXTRA:-32}
if ! info=$("$loom" info "$fabric" --json 2>&1); then
	echo "$prog: $info" >&2
	exit 1
fi
crossings=$(printf '%s\n' "$info" | sed -n 's/^ *"crossings": \([0-9]*\).*/\1/p' | head -1)
mem=$(awk -v b="$budget" -v e="$extra" -v c="${crossings:-0}" \
	'BEGIN { m = b + e + c * 16 / 1048576; if (m != int(m)) m = int(m) + 1; print m }')

# values for --export=...: no commas (sbatch splits its list on them)
for v in "$loom" "$here"; do
	case $v in
	*,*) echo "$prog: '$v' has a comma, which sbatch --export cannot pass" >&2; exit 1 ;;
	esac
done
envs="ALL,LOOM=$loom,LOOM_SHARD_COUNT=$shards,LOOM_SLURM_DIR=$here"
sb=(sbatch --parsable)
# shellcheck disable=SC2206
[ -n "${LOOM_SBATCH_ARGS:-}" ] && sb+=(${LOOM_SBATCH_ARGS})
logs=()
if [ -n "${LOOM_SLURM_LOGS:-}" ]; then
	mkdir -p "$LOOM_SLURM_LOGS"
	logs=(--output="$(abs "$LOOM_SLURM_LOGS")/%x-%A_%a.out")
fi
mlogs=()
[ -n "${LOOM_SLURM_LOGS:-}" ] && mlogs=(--output="$(abs "$LOOM_SLURM_LOGS")/%x-%j.out")

if [ "$kind" = export ]; then
	mkdir -p "$out"
else
	mkdir -p "$out.parts"
fi
jid=$("${sb[@]}" --array="$array" --job-name="loom-$kind" --cpus-per-task="$threads" \
	--mem="${mem}M" --export="$envs" "${logs[@]}" \
	"$here/$kind.sbatch" "$fabric" "$out" "${pass[@]}")
jid=${jid%%;*}
mid=$("${sb[@]}" --dependency="afterany:$jid" --kill-on-invalid-dep=yes \
	--job-name="loom-$kind-merge" --mem="${LOOM_SLURM_MERGE_MEM:-$mem}M" --export="$envs" \
	"${mlogs[@]}" \
	"$here/merge.sbatch" "$kind" "$fabric" "$out" "${pass[@]}")
mid=${mid%%;*}
echo "$jid"
echo "$mid"
