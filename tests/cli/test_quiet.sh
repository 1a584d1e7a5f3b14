# --quiet prints nothing on success, for every command that has it (no
# progress, summary, report or warning; --json still prints its JSON, -o
# still writes its file), and a failure still says why.
SUITE=quiet
. "$LOOM_TOP/tests/cli/lib.sh"
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf

silent() { # NAME CMD...: exit 0, nothing on stdout nor stderr
	n=$1; shift
	if "$@" >"$T/out" 2>"$T/err"; then
		if [ -s "$T/out" ] || [ -s "$T/err" ]; then
			fail "$n" "printed: $(head -c 300 "$T/out") $(head -c 300 "$T/err")"
		else pass "$n"; fi
	else
		fail "$n" "exit $? from: $*; $(head -c 300 "$T/err")"
	fi
}

silent synth "$LOOM" synth "$WIF" --quiet -o "$F"
silent sample_at "$LOOM" sample "$F" --at 5,7,20 --quiet
silent sample_random "$LOOM" sample "$F" --random 2000 --quiet
silent preview "$LOOM" preview "$F" --region 0,0:64,64 --quiet -o "$T/p.png"
silent render "$LOOM" render "$F" --width 24 --height 16 --spp 1 --quiet -o "$T/r.png"
silent pattern_make "$LOOM" pattern make twill --quiet -o "$T/tw.pbm"
silent pattern_convert "$LOOM" pattern convert "$WIF" --quiet -o "$T/h.png"
silent pattern_info "$LOOM" pattern info "$T/tw.pbm" --quiet
silent exemplar_generate "$LOOM" exemplar generate --preset tiny --quiet -o "$T/tiny.ldb"
silent exemplar_verify "$LOOM" exemplar verify "$T/tiny.ldb" --quiet
silent scan "$LOOM" scan "$F" --region 0,0,0:64,64,48 --reduce checksum --quiet
silent scan_part0 "$LOOM" scan "$F" --region 0,0,0:64,64,48 --reduce checksum --shard 0/2 \
	--quiet --json -o "$T/s0.json"
silent scan_part1 "$LOOM" scan "$F" --region 0,0,0:64,64,48 --reduce checksum --shard 1/2 \
	--quiet --json -o "$T/s1.json"
silent scan_combine "$LOOM" scan --combine "$T/s0.json" "$T/s1.json" --quiet
silent export "$LOOM" export "$F" --region 0,0,0:64,64,48 --tile 32,32 --format vol --quiet \
	-o "$T/e"
silent export_resume "$LOOM" export "$F" --region 0,0,0:64,64,48 --tile 32,32 --format vol \
	--quiet -o "$T/e"
silent export_shard "$LOOM" export "$F" --region 0,0,0:64,64,48 --tile 32,32 --format vol \
	--shard 0/2 --quiet -o "$T/es"
silent export_shard1 "$LOOM" export "$F" --region 0,0,0:64,64,48 --tile 32,32 --format vol \
	--shard 1/2 --quiet -o "$T/es"
silent export_merge "$LOOM" export --merge "$T/es" --quiet
silent export_status "$LOOM" export --status "$T/es" --quiet

# --json still prints; -o still writes
expect_ok scan_json "$LOOM" scan "$F" --region 0,0,0:64,64,48 --reduce checksum --quiet --json
expect_out_contains scan_json_out '"checksum": "'
expect_ok sample_json "$LOOM" sample "$F" --at 5,7,20 --quiet --json
expect_out_contains sample_json_out '"density"'
if grep -q '"checksum"' "$T/s0.json" 2>/dev/null; then pass scan_o_written
else fail scan_o_written "-o wrote no result"; fi
# and a failure still says why
expect_exit fail_says 1 "$LOOM" export --status "$T/nothing-here" --quiet
expect_err_contains fail_says_msg "nothing-here: No such file or directory"
