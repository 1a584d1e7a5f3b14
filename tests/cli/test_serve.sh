# `loom serve` end to end: a real server on 127.0.0.1 (a free port), the
# page and its files, tiles (valid PNGs of the right size, cached, made
# again in new colours), a table of bad requests (out-of-range tiles, path
# traversal, huge levels, malformed numbers, wrong methods) that must get
# 4xx and leave the server running, many concurrent requests (200 or 429,
# never a crash, peak RSS within the budget), the on-disk cache bound, and
# the page in Debian's chromium (tests/web/browser.mjs) when it is there.
SUITE=serve
. "$LOOM_TOP/tests/cli/lib.sh"
export PYTHONPATH="$LOOM_TOP/tests/cli"
HB=$LOOM_TOP/data/herringbone-8.wif
SERVER=""
stop_server() { [ -n "$SERVER" ] && kill "$SERVER" 2>/dev/null && wait "$SERVER" 2>/dev/null; SERVER=""; }
trap 'stop_server; cleanup_tmp' EXIT

# start_server NAME ARGS...: run loom serve, wait for its URL line
start_server() {
	n=$1; shift
	"$LOOM" serve "$@" --port 0 >"$T/$n.out" 2>"$T/$n.err" &
	SERVER=$!
	for _ in $(seq 1 100); do
		URL=$(sed -n 's|^loom serve: \(http://[^ ]*\)/ .*|\1|p' "$T/$n.out")
		[ -n "$URL" ] && break
		kill -0 "$SERVER" 2>/dev/null || break
		sleep 0.2
	done
	if [ -n "$URL" ]; then pass "start_$n"; else fail "start_$n" "no URL: $(cat "$T/$n.err")"; fi
}
# code PATH [CURL ARGS]: the HTTP status of a request
# (OUT=FILE keeps the body there instead of $T/body)
code() { p=$1; shift; curl -s --path-as-is -o "${OUT:-$T/body}" -w '%{http_code}' "$@" "$URL$p"; }
expect_code() { # NAME WANT PATH [CURL ARGS]
	n=$1; want=$2; shift 2
	got=$(code "$@")
	if [ "$got" = "$want" ]; then pass "$n"; else fail "$n" "HTTP $got, expected $want for $1: $(head -c 200 "$T/body")"; fi
}
png_size() { python3 -B -c 'import sys, pngread; w, h, ch, px = pngread.read(sys.argv[1]); print(w, h, ch)' "$1" 2>/dev/null; }

expect_ok help "$LOOM" serve --help
expect_out_contains help_budget "--budget"
expect_exit no_args 2 "$LOOM" serve
expect_exit small_budget 2 "$LOOM" serve "$HB" --budget 8
expect_exit bad_bind 2 "$LOOM" serve "$HB" --bind nowhere
expect_exit missing 1 "$LOOM" serve "$T/nope.loomf"
expect_err_contains missing_msg "nope.loomf"

"$LOOM" synth "$HB" --quiet -o "$T/hb.loomf"
start_server main "$T/hb.loomf" --budget 64 --cache "$T/cache" --cache-mb 64
if [ -n "$URL" ]; then
	case $URL in http://127.0.0.1:*) pass bound_localhost ;; *) fail bound_localhost "$URL" ;; esac
	expect_code page 200 /
	expect_code page_js 200 /viewer.js
	expect_code osd 200 /openseadragon.min.js
	expect_code osd_image 200 /images/home_rest.png
	expect_code info 200 /api/info
	python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); assert j["tile_size"]==256 and j["max_level"]>=10 and len(j["yarns"])==3' "$T/body" 2>"$T/pyerr" &&
		pass info_json || fail info_json "$(cat "$T/pyerr")"
	top=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["max_level"])' "$T/body")
	OUT="$T/deep.png" expect_code tile_top 200 "/tile/$top/3/2.png"
	[ "$(png_size "$T/deep.png")" = "256 256 3" ] && pass tile_png || fail tile_png "$(png_size "$T/deep.png")"
	OUT="$T/root.png" expect_code tile_root 200 /tile/0/0/0.png
	[ "$(png_size "$T/root.png")" = "1 1 3" ] && pass tile_root_png || fail tile_root_png "$(png_size "$T/root.png")"
	OUT="$T/mid.png" expect_code tile_mid 200 /tile/8/0/0.png
	OUT="$T/deep2.png" expect_code tile_again 200 "/tile/$top/3/2.png"
	expect_same tile_cached "$T/deep.png" "$T/deep2.png"
	OUT="$T/dd.png" expect_code drawdown 200 /drawdown.png
	[ "$(png_size "$T/dd.png")" = "192 192 3" ] && pass drawdown_png || fail drawdown_png "$(png_size "$T/dd.png")"

	# the bad-request table: every one a 4xx, nothing from outside the page
	while read -r name want path; do
		expect_code "bad_$name" "$want" "$path"
		if grep -q 'root:' "$T/body"; then fail "bad_${name}_leak" "a system file was served"; fi
	done <<'TABLE'
level_word 400 /tile/abc/0/0.png
level_negative 400 /tile/-1/0/0.png
level_huge 400 /tile/99999999999/0/0.png
level_beyond 404 /tile/99/0/0.png
x_beyond 404 /tile/0/1/0.png
y_beyond 404 /tile/12/0/999999.png
x_huge 400 /tile/12/1234567890123/0.png
not_png 400 /tile/3/0/0.jpg
short 400 /tile/3/0.png
trailing 400 /tile/3/0/0.png/x
traversal 400 /../../../../etc/passwd
traversal_encoded 400 /%2e%2e/%2e%2e/etc/passwd
traversal_images 400 /images/../../../etc/passwd
traversal_tile 400 /tile/../../etc/passwd
double_slash 400 //etc/passwd
dot_file 404 /.hidden
backslash 400 /..\..\etc\passwd
unknown 404 /nothing-here.html
TABLE
	expect_code long_url 400 "/$(printf 'a%.0s' $(seq 1 300))"
	expect_code put 405 / -X PUT
	expect_code color_get 405 "/api/color?type=0&rgb=00ff00"
	expect_code color_no_args 400 /api/color -X POST
	expect_code color_bad_hex 400 "/api/color?type=0&rgb=zzzzzz" -X POST
	expect_code color_bad_type 404 "/api/color?type=99&rgb=00ff00" -X POST
	expect_code render_bad_box 400 "/api/render?x0=0.5&y0=0&x1=0.4&y1=1"
	expect_code render_huge 400 "/api/render?x0=0&y0=0&x1=1&y1=1&w=100000"
	expect_code alive_after_bad 200 /api/info

	# colours: the same tile, made again in the new colours
	expect_code color_change 200 "/api/color?type=2&rgb=00ff00" -X POST
	OUT="$T/deep3.png" expect_code tile_recoloured 200 "/tile/$top/3/2.png"
	if cmp -s "$T/deep.png" "$T/deep3.png"; then fail recoloured_differs "same bytes"; else pass recoloured_differs; fi
	if python3 -B - "$T/deep.png" "$T/deep3.png" <<'PY' 2>"$T/pyerr"; then pass recoloured_green; else fail recoloured_green "$(tail -1 "$T/pyerr")"; fi
import sys, pngread
def mean(p):
    w, h, ch, px = pngread.read(p)
    s = [0, 0, 0]
    for r in px:
        for x in range(w):
            for c in range(3): s[c] += r[3 * x + c]
    return [v / (w * h) for v in s]
a, b = mean(sys.argv[1]), mean(sys.argv[2])
assert b[1] - b[0] > a[1] - a[0] + 10, (a, b)   # greener
PY
	OUT="$T/render.png" expect_code render_view 200 "/api/render?x0=0.1&y0=0.1&x1=0.12&y1=0.12&w=64"
	[ "$(png_size "$T/render.png")" = "64 40 3" ] && pass render_png || fail render_png "$(png_size "$T/render.png")"

	# many concurrent requests for tiles nobody asked for yet: 200 or 429
	: >"$T/codes"
	for k in $(seq 0 47); do
		curl -s -o /dev/null -w '%{http_code}\n' "$URL/tile/$((top - 1))/$((k % 8))/$((k / 8)).png" >>"$T/codes" &
	done
	wait_curls=0
	while [ "$(wc -l <"$T/codes")" -lt 48 ] && [ $wait_curls -lt 600 ]; do sleep 0.2; wait_curls=$((wait_curls + 1)); done
	bad=$(grep -cv '^\(200\|429\)$' "$T/codes")
	ok=$(grep -c '^200$' "$T/codes")
	if [ "$bad" -eq 0 ] && [ "$ok" -gt 0 ]; then pass concurrent "$(sort "$T/codes" | uniq -c | tr '\n' ' ')"; else
		fail concurrent "$(sort "$T/codes" | uniq -c | tr '\n' ' ')"; fi
	expect_code alive_after_load 200 /api/info
	hwm=$(awk '/VmHWM/ {print $2}' "/proc/$SERVER/status")
	# the budget (64 MiB) plus the process itself (code, libraries, thread stacks)
	# (not under sanitizers: their shadow memory and quarantine are not ours)
	if [ -n "${LOOM_SAN:-}" ]; then echo "NOTE serve/peak_rss: not checked under $LOOM_SAN"
	elif [ "$hwm" -le $(( (64 + 24) * 1024 )) ]; then pass peak_rss "$hwm kB"; else fail peak_rss "$hwm kB"; fi
	echo "peak RSS of loom serve --budget 64: $hwm kB"
	# the page in a real browser
	case "${LOOM_SAN:-}" in *thread*)
		# tiles are 10x slower under ThreadSanitizer and the viewer gives up on
		# them; the concurrent requests above exercise the server's threads
		echo "NOTE serve/browser: not run under ThreadSanitizer" ;;
	*) false ;; esac ||
	if command -v chromium >/dev/null 2>&1 && [ -d "$LOOM_BUILD/web/node_modules/playwright-core" ]; then
		mkdir -p "$T/shots"
		if LOOM_BUILD="$LOOM_BUILD" LOOM_SAN="${LOOM_SAN:-}" timeout $([ -n "${LOOM_SAN:-}" ] && echo 1500 || echo 300) node "$LOOM_TOP/tests/web/browser.mjs" "$URL/" "$T/shots" >"$T/browser.json" 2>"$T/browser.err"
		then pass browser_run; else fail browser_run "$(cat "$T/browser.json" "$T/browser.err" | head -c 600)"; fi
		if python3 -B - "$T/browser.json" "$T/shots" <<'PY' >"$T/bstats" 2>"$T/pyerr"; then pass browser_pixels; else fail browser_pixels "$(cat "$T/bstats") $(tail -2 "$T/pyerr")"; fi
import json, sys, pngread
j = json.load(open(sys.argv[1]))
shots = sys.argv[2]
assert j['ok'] and j['failed_tiles'] == 0 and j['tiles_zoom'] > 0, j
def stats(name, box):
    w, h, ch, px = pngread.read(shots + '/' + name)
    x0, y0 = int(box['x']) + 4, int(box['y']) + 4
    x1, y1 = min(w, int(box['x'] + box['width']) - 4), min(h, int(box['y'] + box['height']) - 4)
    lum, g = [], 0.0
    for y in range(y0, y1, 2):
        for x in range(x0, x1, 2):
            r, gg, b = px[y][ch * x:ch * x + 3]
            lum.append(0.299 * r + 0.587 * gg + 0.114 * b)
            g += gg - (r + b) / 2
    m = sum(lum) / len(lum)
    sd = (sum((v - m) ** 2 for v in lum) / len(lum)) ** 0.5
    return m, sd, g / len(lum)
for name in ('home.png', 'zoom.png'):
    m, sd, _ = stats(name, j['boxes']['cloth'])
    print(name, 'cloth mean %.1f sd %.1f' % (m, sd))
    assert m > 40 and sd > 8, (name, m, sd)     # cloth, not an empty panel
m, sd, _ = stats('home.png', j['boxes']['drawdown'])
print('drawdown mean %.1f sd %.1f' % (m, sd))
assert m > 40 and sd > 8
_, _, green = stats('green.png', j['boxes']['cloth'])
_, _, before = stats('zoom.png', j['boxes']['cloth'])
print('green excess %.1f -> %.1f' % (before, green))
assert green > before + 5
assert j['render_width'] == 160
PY
		cat "$T/bstats"
	else
		echo "NOTE serve/browser: chromium or playwright-core missing (tools/deps.sh test installs chromium; make installs playwright-core): the browser test did not run"
	fi
	stop_server
	if grep -q "tiles made" "$T/main.err"; then pass stopped_log; else fail stopped_log "$(cat "$T/main.err")"; fi
fi

# the on-disk cache stays under --cache-mb
start_server small "$T/hb.loomf" --budget 64 --cache "$T/small" --cache-mb 0.1
if [ -n "$URL" ]; then
	for k in $(seq 0 11); do code "/tile/12/$k/1.png" >/dev/null; done
	bytes=$(du -cb "$T/small"/*.png 2>/dev/null | tail -1 | cut -f1)
	# the limit plus the file just added (never the one evicted)
	if [ "$bytes" -le $((104858 + 60000)) ]; then pass cache_bounded "$bytes bytes"; else fail cache_bounded "$bytes bytes"; fi
	stop_server
fi
# a DRAFT is synthesized first
start_server draft "$HB" --budget 64 --cache "$T/dcache"
if [ -n "$URL" ]; then
	expect_code draft_tile 200 /tile/10/1/1.png
	stop_server
fi
