# Temporary outputs: a command killed with SIGKILL while writing leaves its
# temporary "OUT.tmp.PID.N"; the next run of the same command removes it
# (its writer is gone) and nothing else: not a live writer's temporary,
# not other files that merely look alike.  Also the output checks before
# work: -o naming a directory or a missing directory fails at once.
SUITE=leftovers
. "$LOOM_TOP/tests/cli/lib.sh"
cd "$T" || exit 1

# tmps OUT: the temporaries of OUT present now (empty when none)
tmps() {
	for f in "$1".tmp.*; do
		[ -e "$f" ] && printf '%s\n' "$f"
	done
}
# has_tmp OUT: whether OUT has a temporary now (no subprocess: fast polling)
has_tmp() {
	for f in "$1".tmp.*; do
		[ -e "$f" ] && return 0
	done
	return 1
}

# kill_run NAME OUT CMD...: start CMD, SIGKILL it once a temporary of OUT
# exists, then run CMD again to completion: it must succeed, write OUT and
# leave no temporary of OUT.  A command whose temporary lives only while
# it writes (synth: milliseconds at its end) can end between two polls of
# a loaded machine: such a run is started again, up to 20 times.
kill_run() {
	n=$1; out=$2; shift 2
	attempt=0
	left=
	while [ -z "$left" ] && [ $attempt -lt 20 ]; do
		attempt=$((attempt + 1))
		rm -f "$out" "$out".tmp.*
		"$@" >/dev/null 2>&1 &
		pid=$!
		# poll until the temporary appears or the command ends; a deadline
		# in seconds, not in polls (a sanitizer build may work for a long
		# time before it opens its output: synth under TSan)
		i=0
		end=$(($(date +%s) + 300))
		while ! has_tmp "$out" && kill -0 $pid 2>/dev/null; do
			i=$((i + 1))
			if [ $((i % 2000)) -eq 0 ] && [ "$(date +%s)" -ge $end ]; then
				break
			fi
		done
		kill -9 $pid 2>/dev/null
		wait $pid 2>/dev/null
		left=$(tmps "$out")
		[ -n "$left" ] || [ "$(date +%s)" -lt $end ] || break
	done
	if [ -z "$left" ]; then
		fail "$n" "no temporary of $out seen before the command ended ($attempt runs, or 300 s)"
		return
	fi
	if [ -e "$out" ]; then
		fail "$n" "$out exists after the kill"
		return
	fi
	if ! "$@" >"$T/out" 2>"$T/err"; then
		fail "$n" "the second run failed: $(head -c 300 "$T/err")"
		return
	fi
	if [ ! -s "$out" ]; then
		fail "$n" "the second run did not write $out"
		return
	fi
	left=$(tmps "$out")
	if [ -n "$left" ]; then
		fail "$n" "temporaries left after the second run: $left"
		return
	fi
	pass "$n"
}

"$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o db.ldb ||
	{ fail setup "cannot make a database"; exit 0; }
kill_run exemplar_generate big.ldb "$LOOM" exemplar generate --preset small --seed 2 --quiet -o big.ldb
kill_run pattern_make big.pbm "$LOOM" pattern make twill --over 2 --under 3 --size 4000x4000 -o big.pbm
"$LOOM" pattern make twill --over 2 --under 3 --size 1000x1000 -o design.pbm
kill_run synth big.loomf "$LOOM" synth design.pbm --db db.ldb --quiet -o big.loomf

# what the sweep keeps: a live writer's temporary (this shell's pid), names
# that only look alike, other outputs' temporaries; a dead writer's goes
sh -c 'exit 0' &
dead=$!
wait $dead
: >x.pbm.tmp.$$.0
: >x.pbm.tmp.$dead.0
: >x.pbm.tmp.$dead
: >x.pbm.tmp.notes
: >x.pbm.tmp.${dead}x
: >y.pbm.tmp.$dead.0
mkdir x.pbm.tmp.$dead.1
expect_ok sweep_run "$LOOM" pattern make plain --size 8x8 -o x.pbm
if [ -e x.pbm.tmp.$$.0 ] && [ -e x.pbm.tmp.notes ] && [ -e x.pbm.tmp.${dead}x ] &&
   [ -e y.pbm.tmp.$dead.0 ] && [ -d x.pbm.tmp.$dead.1 ]; then pass sweep_keeps_others; else
	fail sweep_keeps_others "removed a file it should keep: $(ls x.pbm.* y.pbm.* | tr '\n' ' ')"; fi
if [ ! -e x.pbm.tmp.$dead.0 ] && [ ! -e x.pbm.tmp.$dead ]; then pass sweep_removes_dead; else
	fail sweep_removes_dead "a dead writer's temporary is still there: $(ls x.pbm.* | tr '\n' ' ')"; fi
# a temporary locked by a live writer is kept whatever its pid says (a
# writer on another host sharing the directory)
: >z.pbm.tmp.$dead.0
if command -v flock >/dev/null 2>&1; then
	flock z.pbm.tmp.$dead.0 sleep 30 &
	holder=$!
	i=0
	while [ $i -lt 500 ] && flock -n z.pbm.tmp.$dead.0 true 2>/dev/null; do
		sleep 0.01; i=$((i + 1)); done
	expect_ok sweep_locked_run "$LOOM" pattern make plain --size 8x8 -o z.pbm
	if [ -e z.pbm.tmp.$dead.0 ]; then pass sweep_keeps_locked; else
		fail sweep_keeps_locked "a locked temporary was removed"; fi
	kill $holder 2>/dev/null
	wait $holder 2>/dev/null
fi

# outputs checked before any work
mkdir -p adir adir.png
for c in "synth design.pbm --db db.ldb -o adir" \
         "exemplar generate --preset tiny -o adir" \
         "render big.loomf --width 8 --height 8 -o adir.png" \
         "exemplar export db.ldb --exemplar 0 -o adir" \
         "synth design.pbm --db db.ldb -o nodir/x.loomf" \
         "exemplar generate --preset tiny -o nodir/x.ldb"; do
	name=$(echo "$c" | tr -c 'a-z0-9\n' _)
	# shellcheck disable=SC2086
	expect_exit "outcheck_$name" 1 "$LOOM" $c
	case $c in
	*adir|*adir.png) expect_err_contains "outcheck_msg_$name" "is a directory" ;;
	*) expect_err_contains "outcheck_msg_$name" "nodir" ;;
	esac
done

# a budget below 1 MiB is reported in bytes, not as "0.0 MiB"
expect_exit budget_bytes 2 "$LOOM" scan big.loomf --all --reduce checksum --budget 0.01
expect_err_contains budget_bytes_msg "more than --budget 10486 bytes"
