# `loom look DRAFT` end to end: every picture written and readable, the
# list printed, JSON, the render refined in passes, output directory
# problems caught before any work, bad drafts rejected.
SUITE=look
. "$LOOM_TOP/tests/cli/lib.sh"
export PYTHONPATH="$LOOM_TOP/tests/cli"
HB=$LOOM_TOP/data/herringbone-8.wif

expect_ok help "$LOOM" look --help
expect_out_contains help_open "--open"
expect_exit no_args 2 "$LOOM" look
expect_exit bad_time 2 "$LOOM" look "$HB" --time 0
expect_exit unknown 2 "$LOOM" look "$HB" --frob
: >"$T/afile"
expect_exit out_is_file 1 "$LOOM" look "$HB" -o "$T/afile"
expect_err_contains out_is_file_msg "not a directory"
expect_exit out_parent_missing 1 "$LOOM" look "$HB" -o "$T/no/such/dir"
expect_err_contains out_parent_missing_msg "does not exist"
if [ -e "$T/no" ]; then fail out_parent_missing_nothing "created $T/no"; else pass out_parent_missing_nothing; fi
expect_exit missing_draft 1 "$LOOM" look "$T/nope.wif" -o "$T/x"
expect_err_contains missing_draft_msg "nope.wif"
printf '[WIF]\n[THREADING]\n' >"$T/broken.wif"
expect_exit broken_draft 1 "$LOOM" look "$T/broken.wif" -o "$T/x"
expect_err_contains broken_draft_msg "broken.wif"

expect_ok look_runs "$LOOM" look "$HB" -o "$T/hb" --time 4 --width 96 --json
json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$T/out" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$T/out") $(head -c 300 "$T/pyerr")"; fi
}
json_check json_files "len(j['files']) == 7 and j['files'][-1]['path'].endswith('index.html') and j['rows'] == 192 and j['render_passes'] >= 1"
# the render is written after its first pass and before the page (its time
# is a benchmark figure, bench/bench_preview, not a test)
json_check json_render_before_page "[f['path'][-11:] for f in j['files']].index('-render.png') < len(j['files']) - 1"
for f in drawdown draft preview closeup render; do
	p="$T/hb/herringbone-8-$f.png"
	if python3 -B -c 'import sys, pngread; w, h, ch, px = pngread.read(sys.argv[1]); assert w > 8 and h > 8 and ch == 3' "$p" 2>"$T/pyerr"
	then pass "png_$f"; else fail "png_$f" "$(tail -1 "$T/pyerr")"; fi
done
if [ -s "$T/hb/herringbone-8.loomf" ] && [ -s "$T/hb/index.html" ]; then pass fabric_and_page; else fail fabric_and_page "missing"; fi
expect_ok fabric_reads "$LOOM" info "$T/hb/herringbone-8.loomf"
# the preview's top-left shows pick 1 / end 1: same colour family as the
# drawdown's top-left 8 x 8 crossings, and it matches the drawdown clearly
# better than the same preview mirrored in x or in y does
if python3 -B - "$T/hb/herringbone-8-preview.png" "$T/hb/herringbone-8-drawdown.png" <<'PY' 2>"$T/pyerr"; then pass preview_matches_drawdown; else fail preview_matches_drawdown "$(tail -2 "$T/pyerr")"; fi
import sys, pngread
w, h, ch, rows = pngread.read(sys.argv[1])
b = pngread.boxes(*pngread.read(sys.argv[2]), 48, 4)
def corr(rr):   # the bottom row of boxes has the scale bar
    return pngread.correlation(pngread.boxes(w, h, ch, rr, 48, 4)[:3], b[:3])
def mirror(r):
    return type(r)(r[(w - 1 - x) * ch + c] for x in range(w) for c in range(ch))
r, rx, ry = corr(rows), corr([mirror(r) for r in rows]), corr(rows[::-1])
assert r > 0.7 and r > max(rx, ry) + 0.25, (r, rx, ry)
PY
# the text listing
expect_ok look_text "$LOOM" look "$LOOM_TOP/tests/data/wif/colors.wif" -o "$T/c" --time 2 --width 48
expect_out_contains list_drawdown "colors-drawdown.png"
expect_out_contains list_render "colors-render.png"
expect_err_contains progress_render "render"
if grep -qF "longest" "$T/err"; then fail short_floats_no_warning "$(grep -F longest "$T/err")"; else pass short_floats_no_warning; fi
# a design with floats longer than any exemplar's: the warning names its
# longest weft float, as `loom pattern info` counts it
expect_ok long_float_make "$LOOM" pattern make satin:1/9 -q -o "$T/s19.pbm"
expect_ok long_float_info "$LOOM" pattern info "$T/s19.pbm" --json
weft=$(python3 -c 'import json,sys; print(json.load(sys.stdin)["weft_floats"]["max"])' <"$T/out")
expect_ok long_float_look "$LOOM" look "$T/s19.pbm" -o "$T/s19" --time 1 --width 48
expect_err_contains long_float_warning "warning: the design's longest weft float is $weft crossings"
