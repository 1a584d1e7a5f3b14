# tests/extra/blender.sh - a loom tile in Blender's Cycles (run by make
# test when `blender` is installed: tools/deps.sh blender; skipped with a
# message when not).  Exports a 64 x 40 voxel tile as OpenVDB, renders it
# headless with tools/blender/render_tile.py from straight above (one voxel
# per pixel, the tile off-centre in the frame, a black world), and compares
# the image with `loom preview` of the same region: the cloth masks'
# intersection over union, and the correlation of the luminance inside the
# tile (the herringbone's two yarn colours, from the `color` grid).
SUITE=blender
. "$LOOM_TOP/tests/cli/lib.sh"
if ! command -v blender >/dev/null 2>&1; then
	echo "SKIP blender: not installed (tools/deps.sh blender installs it): the Cycles check is skipped"
	exit 0
fi
if [ ! -f "$LOOM_BUILD/libloom-vdb.so.0" ]; then
	echo "SKIP blender: this loom has no VDB writer (OpenVDB not installed): the Cycles check is skipped"
	exit 0
fi
case "${LOOM_SAN:-}" in *thread*)
	echo "SKIP blender: VDB writes not run under ThreadSanitizer (OpenVDB and TBB are not instrumented)"
	exit 0 ;;
esac
BL="blender -b --factory-startup --python-exit-code 1"
F=$T/h8.loomf
expect_ok synth "$LOOM" synth "$LOOM_TOP/data/herringbone-8.wif" --quiet -o "$F"
expect_ok export "$LOOM" export "$F" --region 0,0,0:64,40,48 --format vdb \
	--channels density,albedo --tile 64,40 --quiet -o "$T/vdb"
expect_ok preview "$LOOM" preview "$F" --region 0,0:64,40 --quiet -o "$T/preview.png"
# the frame: x -10 .. 86, y -30 .. 50 voxels of 0.024 mm (96 x 80 pixels)
VMM=$(sed -n 's/.*"voxel_mm": \([0-9.e-]*\).*/\1/p' "$T/vdb/manifest.json")
ORTHO=$(awk -v v="$VMM" 'BEGIN { printf "%.9g,%.9g,%.9g,%.9g", -10 * v, -30 * v, 86 * v, 50 * v }')
expect_ok render $BL -P "$LOOM_TOP/tools/blender/render_tile.py" -- "$T/vdb/tile-0-0-0.vdb" \
	-o "$T/cycles.png" --size 96,80 --samples 16 --threads 2 --ortho "$ORTHO" \
	--background 0 --sun 0,60,3 --json "$T/render.json"
if [ -s "$T/cycles.png" ] && grep -q '"color_grid": true' "$T/render.json"
then pass render_written; else fail render_written "$(cat "$T/render.json" 2>&1)"; fi
# bad arguments: exit 2 with the reason
expect_exit render_bad_option 2 $BL -P "$LOOM_TOP/tools/blender/render_tile.py" -- \
	"$T/vdb/tile-0-0-0.vdb" -o "$T/x.png" --camera fisheye
expect_err_contains render_bad_option_msg "--camera: top or persp, got 'fisheye'"

# placed where it is, and (a check that can fail) 20 voxels off
$BL -P "$LOOM_TOP/tests/extra/blender_compare.py" -- "$T/cycles.png" "$T/preview.png" \
	10 30 30 10 >"$T/cmp" 2>&1
line=$(grep '^iou .* at 10 30$' "$T/cmp")
# the tile covers 2560 of the 7680 pixels; its pixels hold the preview's
# colours
if echo "$line" | awk '{exit !($2 >= 0.8 && $4 >= 0.6 && $6 > 0.25 && $6 < 0.4)}'
then pass silhouette_matches_preview
else fail silhouette_matches_preview "${line:-$(tail -c 600 "$T/cmp")}"; fi
if grep '^iou .* at 30 10$' "$T/cmp" | awk '{exit !($2 < 0.6)}'
then pass misplaced_tile_fails; else fail misplaced_tile_fails "$(grep '^iou' "$T/cmp")"; fi
