# `loom paint` end to end: regions as rectangles and as a mask image,
# paint files chained (regions kept), the file read back, loom render of a
# paint file (same bytes twice; differs from the unpainted fabric), a
# painted weave (file, render, errors), paint files in preview, export
# and serve (painted weaves, colours and defects shown, unchanged away
# from them, no warning), and
# bad input: options, hostile paint files (not regular, over the size
# limit, bad magic, bad lines), a missing fabric.
SUITE=paint
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
F=$T/tw.loomf

expect_ok help "$LOOM" paint --help
expect_out_contains help_text "--defect"
expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

expect_ok stain "$LOOM" paint "$F" --rect 1,1:3,2.5 --defect stain -o "$T/p1.loomp"
expect_err_contains stain_summary "1 region over"
if head -1 "$T/p1.loomp" | grep -qx 'loom-paint 1' &&
   grep -q '^fabric /' "$T/p1.loomp" &&
   grep -q '^region stain 1 1 3 2.5 kind=any rgb=0.35,0.22,0.08 strength=0.7 blend=0.2 amount=0$' "$T/p1.loomp"
then pass stain_file; else fail stain_file "$(cat "$T/p1.loomp")"; fi
expect_ok broken "$LOOM" paint "$T/p1.loomp" --rect 0.5,0:1.2,4.32 --defect broken-end -q -o "$T/p2.loomp"
expect_ok yarn "$LOOM" paint "$T/p2.loomp" --rect 3.5,0:5,4.32 --yarn weft --rgb 0.8,0.1,0.1 -q -o "$T/p3.loomp"
expect_ok slub "$LOOM" paint "$T/p3.loomp" --rect 0,3:5.76,3.5 --defect slub --kind weft --radius 2 -q -o "$T/p4.loomp"
expect_ok pull "$LOOM" paint "$T/p4.loomp" --rect 2,0.5:2.6,1.5 --defect pull --kind warp --lift 3 -q -o "$T/p5.loomp"
if [ "$(grep -c '^region ' "$T/p5.loomp")" = 5 ]; then pass chained; else fail chained "$(cat "$T/p5.loomp")"; fi

# a mask: 4 x 3 pixels, white = painted (binary PGM written here)
printf 'P5\n4 3\n255\n' >"$T/m.pgm"
printf '\377\000\000\377\000\377\377\000\377\000\000\377' >>"$T/m.pgm"
expect_ok mask "$LOOM" paint "$F" --mask "$T/m.pgm" --at 0.5,0.5 --yarn any --rgb 0.1,0.7,0.1 -q -o "$T/pm.loomp"
if grep -q '^mask 4 3$' "$T/pm.loomp" && grep -qx '#..#' "$T/pm.loomp" &&
   grep -qx '.##.' "$T/pm.loomp" && grep -qx '#..#' "$T/pm.loomp" &&
   grep -q '^region yarn 0.5 0.5 ' "$T/pm.loomp"
then pass mask_file; else fail mask_file "$(cat "$T/pm.loomp")"; fi

R="--width 48 --height 32 --spp 1 --elevation 89 --quiet"
expect_ok render_plain "$LOOM" render "$F" $R -o "$T/r0.png"
expect_ok render_paint "$LOOM" render "$T/p5.loomp" $R -o "$T/r5.png"
expect_ok render_paint2 "$LOOM" render "$T/p5.loomp" $R --threads 1 -o "$T/r5b.png"
expect_same render_paint_deterministic "$T/r5.png" "$T/r5b.png"
if cmp -s "$T/r0.png" "$T/r5.png"; then fail paint_changes_render "same bytes"; else pass paint_changes_render; fi

# bad usage
expect_exit no_region 2 "$LOOM" paint "$F" --defect stain -o "$T/x.loomp"
expect_exit two_regions 2 "$LOOM" paint "$F" --rect 0,0:1,1 --mask "$T/m.pgm" --defect stain -o "$T/x.loomp"
expect_exit no_effect 2 "$LOOM" paint "$F" --rect 0,0:1,1 -o "$T/x.loomp"
expect_exit two_effects 2 "$LOOM" paint "$F" --rect 0,0:1,1 --defect stain --yarn warp --rgb 1,0,0 -o "$T/x.loomp"
expect_exit yarn_no_rgb 2 "$LOOM" paint "$F" --rect 0,0:1,1 --yarn warp -o "$T/x.loomp"
expect_exit bad_rect 2 "$LOOM" paint "$F" --rect 1,0:0,1 --defect stain -o "$T/x.loomp"
expect_exit bad_rgb 2 "$LOOM" paint "$F" --rect 0,0:1,1 --yarn warp --rgb 1,2,0 -o "$T/x.loomp"
expect_exit bad_defect 2 "$LOOM" paint "$F" --rect 0,0:1,1 --defect glitter -o "$T/x.loomp"
expect_exit radius_not_slub 2 "$LOOM" paint "$F" --rect 0,0:1,1 --defect stain --radius 2 -o "$T/x.loomp"
expect_exit at_without_mask 2 "$LOOM" paint "$F" --rect 0,0:1,1 --defect stain --at 1,1 -o "$T/x.loomp"
expect_exit no_output 2 "$LOOM" paint "$F" --rect 0,0:1,1 --defect stain
if [ ! -e "$T/x.loomp" ]; then pass no_partial_output; else fail no_partial_output "x.loomp written"; fi

# hostile paint files
expect_exit missing_fabric 1 "$LOOM" paint "$T/nope.loomf" --rect 0,0:1,1 --defect stain -o "$T/x.loomp"
expect_err_contains missing_fabric_msg "nope.loomf"
printf 'loom-paint 1\nfabric %s\nregion stain 0 0 1 nan\n' "$F" >"$T/bad.loomp"
expect_exit bad_line 1 "$LOOM" render "$T/bad.loomp" $R -o "$T/x.png"
expect_err_contains bad_line_msg "bad.loomp:3: expected a finite number"
printf 'loom-paint 1\nfabric %s\n' "$T/gone.loomf" >"$T/gone.loomp"
expect_exit paint_fabric_missing 1 "$LOOM" render "$T/gone.loomp" $R -o "$T/x.png"
expect_err_contains paint_fabric_missing_msg "gone.loomp: its fabric"
{ printf 'loom-paint 1\nfabric %s\n' "$F"; head -c 17000000 /dev/zero | tr '\0' '#'; } >"$T/big.loomp"
expect_exit too_big 1 "$LOOM" render "$T/big.loomp" $R -o "$T/x.png"
expect_err_contains too_big_msg "more than the 16777216 a paint file may have"
# another weave: the file (version 2), render differs from the fabric,
# deterministic; chained after a stain; bad weave input
expect_ok weave "$LOOM" paint "$F" --rect 1.5,1:4.5,3.3 --weave satin:1/4 --band 2 -q -o "$T/pw.loomp"
if head -1 "$T/pw.loomp" | grep -qx 'loom-paint 2' &&
   grep -q "^region weave 1.5 1 4.5 3.3 kind=any rgb=0,0,0 strength=0 blend=0 amount=0 band=2$" "$T/pw.loomp" &&
   grep -qx 'weave 5 5' "$T/pw.loomp" && grep -qx '#....' "$T/pw.loomp"
then pass weave_file; else fail weave_file "$(cat "$T/pw.loomp")"; fi
expect_ok weave_design "$LOOM" paint "$T/p1.loomp" --rect 0,0:2,2 --weave "$T/tw.pbm" -q -o "$T/pw2.loomp"
if [ "$(grep -c '^region ' "$T/pw2.loomp")" = 2 ] && grep -qx 'weave 10 10' "$T/pw2.loomp"
then pass weave_chained; else fail weave_chained "$(cat "$T/pw2.loomp")"; fi
expect_ok render_weave "$LOOM" render "$T/pw.loomp" $R -o "$T/rw.png"
expect_ok render_weave2 "$LOOM" render "$T/pw.loomp" $R --threads 1 -o "$T/rwb.png"
expect_same render_weave_deterministic "$T/rw.png" "$T/rwb.png"
if cmp -s "$T/r0.png" "$T/rw.png"; then fail weave_changes_render "same bytes"; else pass weave_changes_render; fi
expect_exit band_without_weave 2 "$LOOM" paint "$F" --rect 0,0:1,1 --defect stain --band 2 -o "$T/x.loomp"
expect_exit band_too_wide 2 "$LOOM" paint "$F" --rect 0,0:1,1 --weave plain --band 9 -o "$T/x.loomp"
expect_exit weave_unknown 1 "$LOOM" paint "$F" --rect 0,0:1,1 --weave glitter -o "$T/x.loomp"
expect_err_contains weave_unknown_msg "--weave glitter: neither a weave name"
expect_exit weave_too_large 1 "$LOOM" paint "$F" --rect 0,0:100000,100000 --weave plain -o "$T/x.loomp"
expect_err_contains weave_too_large_msg "weave region 1 covers"
printf 'loom-paint 2\nfabric %s\nregion weave 0 0 1e8 1e8 band=1\nweave 1 1\n#\n' "$F" >"$T/hugew.loomp"
expect_exit weave_file_too_large 1 "$LOOM" render "$T/hugew.loomp" $R -o "$T/x.png"
expect_err_contains weave_file_too_large_msg "hugew.loomp: paint: weave region 1 covers"
# preview, export and serve of a paint file: the painted weave shows
# (differs from the fabric) where painted, the picture is unchanged away
# from it, and other regions are named in a warning
P="--width 80 --quiet"
expect_ok preview_plain "$LOOM" preview "$F" $P -o "$T/v0.png"
expect_ok preview_weave "$LOOM" preview "$T/pw.loomp" $P -o "$T/vw.png"
if cmp -s "$T/v0.png" "$T/vw.png"; then fail preview_weave_differs "same bytes"; else pass preview_weave_differs; fi
# a weave far from the previewed box (a repeat is 80 x 60 voxels, 5.76 x 4.32 mm)
expect_ok weave_far "$LOOM" paint "$F" --rect 40,40:42,42 --weave plain -q -o "$T/pfar.loomp"
expect_ok preview_far "$LOOM" preview "$T/pfar.loomp" $P -o "$T/vfar.png"
expect_same preview_far_unchanged "$T/v0.png" "$T/vfar.png"
# colours and defects too: a stain (1,1:3,2.5 mm, soft edge 0.2 mm) changes
# the 1:1 preview (0.072 mm a pixel) inside its rectangle and edge only,
# with no warning; all five kinds of region change it and stay the same
# bytes on 1 and 3 threads, exact or by blocks
expect_ok preview_stain "$LOOM" preview "$T/p1.loomp" $P -o "$T/vs.png"
if grep -q warning "$T/err"; then fail preview_stain_no_warning "$(cat "$T/err")"; else pass preview_stain_no_warning; fi
PY="python3 -B"
if PYTHONPATH="$LOOM_TOP/tests/cli" $PY - "$T/v0.png" "$T/vs.png" <<'PYEOF' 2>"$T/pyerr"
import sys, pngread
w, h, ch, a = pngread.read(sys.argv[1])
w2, h2, ch2, b = pngread.read(sys.argv[2])
assert (w, h, ch) == (w2, h2, ch2) == (80, 60, 3), (w, h, ch)
vx = 5.76 / 80
lo, hi = (1 - 0.2) / vx - 1, (3 + 0.2) / vx + 1
loy, hiy = (1 - 0.2) / vx - 1, (2.5 + 0.2) / vx + 1
inside = outside = 0
for y in range(h):
    for x in range(w):
        if a[y][x * 3:x * 3 + 3] != b[y][x * 3:x * 3 + 3]:
            if lo <= x + 0.5 <= hi and loy <= y + 0.5 <= hiy:
                inside += 1
            else:
                outside += 1
assert outside == 0 and inside > 200, (inside, outside)
PYEOF
then pass preview_stain_only_inside; else fail preview_stain_only_inside "$(tail -2 "$T/pyerr")"; fi
expect_ok preview_all "$LOOM" preview "$T/p5.loomp" $P --threads 1 -o "$T/v5.png"
expect_ok preview_all3 "$LOOM" preview "$T/p5.loomp" $P --threads 3 -o "$T/v5b.png"
expect_same preview_all_deterministic "$T/v5.png" "$T/v5b.png"
if cmp -s "$T/vs.png" "$T/v5.png"; then fail preview_all_differs "same bytes"; else pass preview_all_differs; fi
expect_ok preview_blocks0 "$LOOM" preview "$F" --region 0,0:400,300 --width 40 --filter blocks -q -o "$T/b0.png"
expect_ok preview_blocks "$LOOM" preview "$T/p5.loomp" --region 0,0:400,300 --width 40 --filter blocks -q -o "$T/b5.png"
if cmp -s "$T/b0.png" "$T/b5.png"; then fail preview_blocks_differs "same bytes"; else pass preview_blocks_differs; fi
X="--region 0,0,0:40,30,12 --format vol --quiet"
expect_ok export_plain "$LOOM" export "$F" $X -o "$T/e0"
expect_ok export_weave "$LOOM" export "$T/pw.loomp" $X -o "$T/ew"
expect_ok export_far "$LOOM" export "$T/pfar.loomp" $X -o "$T/efar"
e0=$(find "$T/e0" -name '*.vol' | sort | head -1); ew=$(find "$T/ew" -name '*.vol' | sort | head -1)
efar=$(find "$T/efar" -name '*.vol' | sort | head -1)
if [ -n "$e0" ] && [ -n "$ew" ] && ! cmp -s "$e0" "$ew"; then pass export_weave_differs; else fail export_weave_differs "$e0 $ew"; fi
if [ -n "$efar" ] && cmp -s "$e0" "$efar"; then pass export_far_unchanged; else fail export_far_unchanged "$e0 $efar"; fi
# a stain changes the albedo only, the defects the density too
XA="--region 0,0,0:40,30,12 --format vol --channels density,albedo --quiet"
expect_ok export_a0 "$LOOM" export "$F" $XA -o "$T/ea0"
expect_ok export_stain "$LOOM" export "$T/p1.loomp" $XA -o "$T/ea1"
expect_ok export_all "$LOOM" export "$T/p5.loomp" $XA -o "$T/ea5"
ch() { find "$1" -name "*.$2.vol" | sort | head -1; }
if [ -n "$(ch "$T/ea0" density)" ] && cmp -s "$(ch "$T/ea0" density)" "$(ch "$T/ea1" density)" &&
   ! cmp -s "$(ch "$T/ea0" albedo)" "$(ch "$T/ea1" albedo)"; then pass export_stain_albedo_only
else fail export_stain_albedo_only "density changed or albedo did not"; fi
if [ -n "$(ch "$T/ea5" density)" ] && ! cmp -s "$(ch "$T/ea0" density)" "$(ch "$T/ea5" density)"
then pass export_defects_density; else fail export_defects_density "density unchanged"; fi
# serve: a deep tile over the painted weave differs from the fabric's, one
# far from it is the same
SERVER=""
stop_server() { [ -n "$SERVER" ] && kill "$SERVER" 2>/dev/null && wait "$SERVER" 2>/dev/null; SERVER=""; }
trap 'stop_server; cleanup_tmp' EXIT
serve_tiles() { # NAME FABRIC [drawdown]: tiles near and far into $T/NAME-near.png, -far.png
	"$LOOM" serve "$2" --port 0 --budget 64 --cache "$T/cache-$1" >"$T/$1.out" 2>"$T/$1.err" &
	SERVER=$!
	URL=""
	for _ in $(seq 1 100); do
		URL=$(sed -n 's|^loom serve: \(http://[^ ]*\)/ .*|\1|p' "$T/$1.out")
		[ -n "$URL" ] && break
		kill -0 "$SERVER" 2>/dev/null || break
		sleep 0.2
	done
	if [ -n "$URL" ]; then
		top=$(curl -s "$URL/api/info" | sed -n 's/.*"max_level": *\([0-9]*\).*/\1/p')
		c1=$(curl -s -o "$T/$1-near.png" -w '%{http_code}' "$URL/tile/$top/0/0.png")
		c2=$(curl -s -o "$T/$1-far.png" -w '%{http_code}' "$URL/tile/$top/3/2.png")
		if [ "$c1 $c2" = "200 200" ]; then pass "serve_$1"; else fail "serve_$1" "HTTP $c1 $c2"; fi
		if [ "$3" = drawdown ]; then
			# the drawdown of the painted weave: /api/info names its
			# crossings, /painted/0.png draws them as the painted fabric
			# weaves them (inside: the paint file's weave; around: the
			# repeat's drawdown)
			curl -s "$URL/api/info" >"$T/$1-info.json"
			curl -s -o "$T/$1-dd.png" "$URL/drawdown.png"
			c3=$(curl -s -o "$T/$1-patch.png" -w '%{http_code}' "$URL/painted/0.png")
			c4=$(curl -s -o /dev/null -w '%{http_code}' "$URL/painted/1.png")
			if [ "$c3 $c4" = "200 404" ] && PYTHONPATH="$LOOM_TOP/tests/cli" $PY - "$T/$1-info.json" \
				"$2" "$T/$1-patch.png" "$T/$1-dd.png" <<'PYEOF' 2>"$T/pyerr"
import json, sys, pngread
info = json.load(open(sys.argv[1]))
I0, J0, R, C = info['painted_weaves'][0]
b1, b2 = info['block'][0], info['block'][1]
vmm = info['voxel_um'] / 1000
lines = open(sys.argv[2]).read().split('\n')
reg = [l for l in lines if l.startswith('region weave')][0].split()
x0, y0, x1, y1 = (float(v) / vmm for v in reg[2:6])
k = lines.index([l for l in lines if l.startswith('weave ')][0])
W, H = map(int, lines[k].split()[1:3])
weave = lines[k + 1:k + 1 + H]
w, h, ch, px = pngread.read(sys.argv[3])
dw, dh, dch, dd = pngread.read(sys.argv[4])
assert (w, h) == (C, R), (w, h, C, R)
col = lambda img, c, x, y: tuple(img[y][x * c:x * c + 3])
seen = {0: set(), 1: set()}
inside = around = 0
for r in range(R):
    for c in range(C):
        I, J = I0 + r, J0 + c
        cx, cy = (J + 0.5) * b1, (I + 0.5) * b2
        if x0 <= cx < x1 and y0 <= cy < y1:
            seen[weave[I % H][J % W] == '#'].add(col(px, ch, c, r))
            inside += 1
        elif col(px, ch, c, r) == col(dd, dch, J % dw, I % dh):
            around += 1
        else:
            raise SystemExit('crossing %d,%d outside the region differs from the repeat' % (I, J))
assert inside > 20 and len(seen[0]) == 1 and len(seen[1]) == 1 and seen[0] != seen[1], (inside, seen)
PYEOF
			then pass serve_drawdown_painted; else fail serve_drawdown_painted "HTTP $c3 $c4: $(tail -2 "$T/pyerr")"; fi
		fi
	else
		fail "serve_$1" "no URL: $(cat "$T/$1.err")"
	fi
	stop_server
}
serve_tiles s0 "$F"
serve_tiles sw "$T/pw.loomp" drawdown
if [ -s "$T/s0-near.png" ] && [ -s "$T/sw-near.png" ] && ! cmp -s "$T/s0-near.png" "$T/sw-near.png"
then pass serve_weave_differs; else fail serve_weave_differs "same or missing tiles"; fi
expect_same serve_far_unchanged "$T/s0-far.png" "$T/sw-far.png"
serve_tiles s5 "$T/p5.loomp"
if [ -s "$T/s5-near.png" ] && ! cmp -s "$T/s0-near.png" "$T/s5-near.png"
then pass serve_paint_differs; else fail serve_paint_differs "same or missing tiles"; fi
if grep -q warning "$T/s5.err"; then fail serve_paint_no_warning "$(cat "$T/s5.err")"; else pass serve_paint_no_warning; fi

# the viewer's paint tool end to end in chromium: a stain dragged on the
# cloth is saved by the server in FABRIC.loomp (the region the page sent),
# and a tile of the whole cloth changes inside the region (and its soft
# edge) only (not under ThreadSanitizer: tiles are too slow for the page;
# the requests below exercise the same endpoint)
case "${LOOM_SAN:-}" in *thread*)
	echo "NOTE paint/viewer: not run under ThreadSanitizer" ;;
*) false ;; esac ||
if command -v chromium >/dev/null 2>&1 && [ -d "$LOOM_BUILD/web/node_modules/playwright-core" ]; then
	"$LOOM" serve "$F" --port 0 --budget 64 --size-mm 10 --cache "$T/cache-pt" >"$T/pt.out" 2>"$T/pt.err" &
	SERVER=$!
	URL=""
	for _ in $(seq 1 100); do
		URL=$(sed -n 's|^loom serve: \(http://[^ ]*\)/ .*|\1|p' "$T/pt.out")
		[ -n "$URL" ] && break
		kill -0 "$SERVER" 2>/dev/null || break
		sleep 0.2
	done
	curl -s "$URL/api/info" >"$T/pt-info.json"
	top=$(sed -n 's/.*"max_level": *\([0-9]*\).*/\1/p' "$T/pt-info.json")
	L=$((top - 1))
	curl -s -o "$T/pt-before.png" "$URL/tile/$L/0/0.png"
	if [ -n "$URL" ] && LOOM_BUILD="$LOOM_BUILD" LOOM_SAN="${LOOM_SAN:-}" \
		timeout $([ -n "${LOOM_SAN:-}" ] && echo 1500 || echo 300) \
		node "$LOOM_TOP/tests/web/paint.mjs" "$URL/" "$T" >"$T/pt.json" 2>"$T/pt-node.err"
	then pass viewer_paint_run; else fail viewer_paint_run "$(cat "$T/pt.json" "$T/pt-node.err" | head -c 600)"; fi
	curl -s -o "$T/pt-after.png" "$URL/tile/$L/0/0.png"
	stop_server
	if PYTHONPATH="$LOOM_TOP/tests/cli" $PY - "$T/pt.json" "$T/tw.loomp" "$T/pt-info.json" \
		"$T/pt-before.png" "$T/pt-after.png" "$top" "$L" <<'PYEOF' 2>"$T/pyerr"
import json, sys, pngread
sent = json.load(open(sys.argv[1]))['mm']
lines = open(sys.argv[2]).read().split('\n')
assert lines[0] == 'loom-paint 1', lines[0]
reg = [l.split() for l in lines if l.startswith('region ')]
assert len(reg) == 1 and reg[0][1] == 'stain', reg
x0, y0, x1, y1 = (float(v) for v in reg[0][2:6])
assert all(abs(a - b) < 1e-3 for a, b in zip((x0, y0, x1, y1), sent)), (reg, sent)
info = json.load(open(sys.argv[3]))
top, L = int(sys.argv[6]), int(sys.argv[7])
px_mm = info['pixels_per_voxel'] / 2 ** (top - L) / (info['voxel_um'] / 1000)
w, h, ch, a = pngread.read(sys.argv[4])
w2, h2, ch2, b = pngread.read(sys.argv[5])
assert (w, h) == (w2, h2)
m = 0.2 * px_mm + 2
inside = outside = 0
for y in range(h):
    for x in range(w):
        if a[y][x * ch:x * ch + 3] != b[y][x * ch:x * ch + 3]:
            if x0 * px_mm - m <= x + 0.5 <= x1 * px_mm + m and y0 * px_mm - m <= y + 0.5 <= y1 * px_mm + m:
                inside += 1
            else:
                outside += 1
assert outside == 0 and inside > 100, (inside, outside, w, h, x0 * px_mm, x1 * px_mm)
PYEOF
	then pass viewer_paint_saved_and_shown; else fail viewer_paint_saved_and_shown "$(tail -3 "$T/pyerr")"; fi
else
	echo "NOTE paint/viewer: chromium or playwright-core missing: the paint tool's browser test did not run"
fi
# start_server NAME ARGS...: loom serve ARGS in the background, $URL set
# (empty if it did not start)
start_server() {
	n=$1
	shift
	"$LOOM" serve "$@" --port 0 --budget 64 --size-mm 10 --cache "$T/cache-$n" >"$T/$n.out" 2>"$T/$n.err" &
	SERVER=$!
	URL=""
	for _ in $(seq 1 100); do
		URL=$(sed -n 's|^loom serve: \(http://[^ ]*\)/ .*|\1|p' "$T/$n.out")
		[ -n "$URL" ] && break
		kill -0 "$SERVER" 2>/dev/null || break
		sleep 0.2
	done
}
# a weave painted with the viewer's paint tool in chromium: the paint
# file is the one loom paint --weave writes for the rectangle the page
# sent; the live server's tile over it and its drawdown patch are the
# bytes a fresh server over the saved file serves (the swap re-weaves the
# fabric as every reader of the file does); the tile changed
case "${LOOM_SAN:-}" in *thread*)
	echo "NOTE paint/viewer weave: not run under ThreadSanitizer" ;;
*) false ;; esac ||
if command -v chromium >/dev/null 2>&1 && [ -d "$LOOM_BUILD/web/node_modules/playwright-core" ]; then
	start_server vw "$F" --paint-file "$T/vw.loomp"
	top=$(curl -s "$URL/api/info" | sed -n 's/.*"max_level": *\([0-9]*\).*/\1/p')
	L=$((top - 1))
	curl -s -o "$T/vw-before.png" "$URL/tile/$L/0/0.png"
	if [ -n "$URL" ] && LOOM_BUILD="$LOOM_BUILD" LOOM_SAN="${LOOM_SAN:-}" \
		timeout $([ -n "${LOOM_SAN:-}" ] && echo 1500 || echo 300) \
		node "$LOOM_TOP/tests/web/paint_weave.mjs" "$URL/" "$T" satin:1/4 >"$T/vw.json" 2>"$T/vw-node.err"
	then pass viewer_weave_run; else fail viewer_weave_run "$(cat "$T/vw.json" "$T/vw-node.err" | head -c 600)"; fi
	curl -s -o "$T/vw-after.png" "$URL/tile/$L/0/0.png"
	curl -s -o "$T/vw-patch.png" "$URL/painted/0.png"
	curl -s "$URL/api/info" | sed -n 's/.*"painted_weaves": *\(\[.*\]\)}.*/\1/p' >"$T/vw-pw"
	stop_server
	mm=$($PY -c 'import json,sys; m=json.load(open(sys.argv[1]))["mm"]; print("%.4f,%.4f:%.4f,%.4f" % tuple(m))' "$T/vw.json" 2>/dev/null)
	"$LOOM" paint "$F" --rect "$mm" --weave satin:1/4 -q -o "$T/vw-ref.loomp"
	expect_same viewer_weave_file "$T/vw.loomp" "$T/vw-ref.loomp"
	start_server vf "$T/vw.loomp"
	curl -s -o "$T/vf-tile.png" "$URL/tile/$L/0/0.png"
	curl -s -o "$T/vf-patch.png" "$URL/painted/0.png"
	stop_server
	expect_same viewer_weave_tile_as_fresh "$T/vw-after.png" "$T/vf-tile.png"
	expect_same viewer_weave_drawdown_as_fresh "$T/vw-patch.png" "$T/vf-patch.png"
	if [ -s "$T/vw-after.png" ] && ! cmp -s "$T/vw-before.png" "$T/vw-after.png" && grep -q '\[\[' "$T/vw-pw"
	then pass viewer_weave_shown; else fail viewer_weave_shown "tile unchanged or no patch: $(cat "$T/vw-pw")"; fi
else
	echo "NOTE paint/viewer weave: chromium or playwright-core missing: the weave paint tool's browser test did not run"
fi
# weaves through the API: bad input refused with a 400 naming it, the
# file untouched; a draft and a name accepted
start_server wb "$F" --paint-file "$T/wb.loomp"
post() { curl -s -o "$T/wb-body" -w '%{http_code}' -X POST "$URL/api/paint?$1"; }
bad_weave() { # NAME QUERY MESSAGE
	c=$(post "$2")
	if [ "$c" = 400 ] && grep -q "$3" "$T/wb-body"; then pass "serve_weave_$1"
	else fail "serve_weave_$1" "HTTP $c: $(cat "$T/wb-body")"; fi
}
R0="x0=1&y0=1&x1=2&y1=2"
bad_weave none "$R0&effect=weave" "exactly one of weave=NAME"
bad_weave both "$R0&effect=weave&weave=plain&draft=10/01" "exactly one of weave=NAME"
bad_weave unknown "$R0&effect=weave&weave=glitter" "weave: "
bad_weave satin_move "$R0&effect=weave&weave=satin:1/5:move=1" "weave: "
bad_weave draft_char "$R0&effect=weave&draft=102/010" "draft: character 3"
bad_weave draft_ragged "$R0&effect=weave&draft=10/1" "draft: row 2 has 1 cells"
bad_weave draft_empty "$R0&effect=weave&draft=10//01" "draft: row 2 has 0 cells"
bad_weave band "$R0&effect=weave&weave=plain&band=9" "band: a whole number"
bad_weave rgb "$R0&effect=weave&weave=plain&rgb=ff0000" "do not go with effect=weave"
bad_weave on_stain "$R0&effect=stain&weave=plain" "go with effect=weave"
bad_weave too_large "x0=0&y0=0&x1=100000&y1=100000&effect=weave&weave=plain" "weave region 1 covers"
bad_weave rect "x0=2&y0=1&x1=1&y1=2&effect=weave&weave=plain" "paint refused"
if [ ! -e "$T/wb.loomp" ]; then pass serve_weave_bad_no_file; else fail serve_weave_bad_no_file "$(cat "$T/wb.loomp")"; fi
c1=$(post "x0=0.5&y0=0.5&x1=2&y1=2&effect=weave&draft=1100/0110/0011/1001&band=2")
c2=$(post "x0=3&y0=0.5&x1=4.5&y1=2&effect=weave&weave=twill:1/3")
pw=$(curl -s "$URL/api/info" | sed -n 's/.*"painted_weaves": *\(\[.*\]\)}.*/\1/p')
stop_server
if [ "$c1 $c2" = "200 200" ] && grep -qx 'weave 4 4' "$T/wb.loomp" && grep -qx '##..' "$T/wb.loomp" &&
   grep -qx '.##.' "$T/wb.loomp" && grep -q 'band=2$' "$T/wb.loomp" &&
   [ "$(grep -c '^region weave' "$T/wb.loomp")" = 2 ] && [ "$(echo "$pw" | grep -o '\[[0-9]' | wc -l)" = 2 ]
then pass serve_weave_requests; else fail serve_weave_requests "HTTP $c1 $c2; $pw: $(cat "$T/wb.loomp" 2>&1 | head -8)"; fi
expect_ok serve_weave_file_renders "$LOOM" render "$T/wb.loomp" $R -o "$T/wb.png"
# bad paint requests: refused with 4xx, the file untouched
"$LOOM" serve "$F" --port 0 --budget 64 --size-mm 10 --cache "$T/cache-pb" --paint-file "$T/pb.loomp" >"$T/pb.out" 2>"$T/pb.err" &
SERVER=$!
URL=""
for _ in $(seq 1 100); do
	URL=$(sed -n 's|^loom serve: \(http://[^ ]*\)/ .*|\1|p' "$T/pb.out")
	[ -n "$URL" ] && break
	kill -0 "$SERVER" 2>/dev/null || break
	sleep 0.2
done
b1=$(curl -s -o /dev/null -w '%{http_code}' -X POST "$URL/api/paint?x0=1&y0=1&x1=0&y1=2&effect=stain")
b2=$(curl -s -o /dev/null -w '%{http_code}' -X POST "$URL/api/paint?x0=0&y0=0&x1=1&y1=1&effect=glitter")
b3=$(curl -s -o /dev/null -w '%{http_code}' -X POST "$URL/api/paint?x0=0&y0=0&x1=1&y1=1&effect=slub&kind=any")
b4=$(curl -s -o /dev/null -w '%{http_code}' "$URL/api/paint?x0=0&y0=0&x1=1&y1=1&effect=stain")
b5=$(curl -s -o /dev/null -w '%{http_code}' -X POST "$URL/api/paint?x0=0&y0=0&x1=nan&y1=1&effect=stain")
ok1=$(curl -s -o /dev/null -w '%{http_code}' -X POST "$URL/api/paint?x0=0.5&y0=0.5&x1=2&y1=1&effect=slub&kind=weft&amount=3")
# eight stains posted at once: each one's region is kept (one POST at a
# time from reading the layer to the swap; none starts from a stale layer)
pids=""
for k in 1 2 3 4 5 6 7 8; do
	curl -s -o "$T/par$k" -X POST "$URL/api/paint?x0=$k&y0=3&x1=$k.5&y1=4&effect=stain" &
	pids="$pids $!"
done
wait $pids # (not the server)
stop_server
n_par=0
for k in 1 2 3 4 5 6 7 8; do
	grep -q "^region stain $k 3 $k.5 4" "$T/pb.loomp" && n_par=$((n_par + 1))
done
if [ "$n_par" = 8 ]; then pass serve_paint_concurrent; else fail serve_paint_concurrent "$n_par of 8 regions kept: $(grep -c '^region' "$T/pb.loomp") regions"; fi
if [ "$b1 $b2 $b3 $b4 $b5 $ok1" = "400 400 400 405 400 200" ] && grep -q '^region slub 0.5 0.5 2 1 kind=weft' "$T/pb.loomp" &&
   [ "$(grep -c '^region' "$T/pb.loomp")" = 9 ] && ! ls "$T"/pb.loomp.tmp.* >/dev/null 2>&1
then pass serve_paint_requests; else fail serve_paint_requests "HTTP $b1 $b2 $b3 $b4 $b5 $ok1: $(cat "$T/pb.loomp" 2>&1 | head -3)"; fi

mkdir -p "$T/dir.loomp"
expect_exit paint_dir 1 "$LOOM" paint "$T/dir.loomp" --rect 0,0:1,1 --defect stain -o "$T/x.loomp"
rm -rf "$T"
