#!/bin/sh
# tools/gallery.sh - the rendering gallery (`make gallery`): the paper's
# figure 13 subjects (a wavy twill, 1/15-15/1 and 1/7-7/1 satin blocks,
# two two-colour Jacquards) woven from `loom pattern` designs over the
# default database and rendered onto the scene meshes of
# tests/data/meshes (docs/rendering.md, "Gallery", lists every command).
#
#     sh tools/gallery.sh LOOM OUTDIR [WIDTH HEIGHT SPP]
#
# writes OUTDIR/gallery-NAME.png (default 640 x 360, 6 spp) and prints
# each command before it runs it.  Work files go to a temporary directory,
# removed at the end.  Exit status: 0, 1 when a command fails, 2 usage.
set -eu
if [ $# -ne 2 ] && [ $# -ne 5 ]; then
	echo "usage: sh tools/gallery.sh LOOM OUTDIR [WIDTH HEIGHT SPP]" >&2
	exit 2
fi
LOOM=$1
OUT=$2
W=${3:-640}
H=${4:-360}
SPP=${5:-6}
TOP=$(cd "$(dirname "$0")/.." && pwd)
MESH=$TOP/tests/data/meshes
case $LOOM in /*) ;; */*) LOOM=$(pwd)/$LOOM ;; esac
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
WORK=$(mktemp -d "${TMPDIR:-/tmp}/loom-gallery.XXXXXX")
trap 'rm -rf "$WORK"' EXIT INT TERM

run() {
	echo "+ $*"
	"$@"
}

cd "$WORK"
# designs: weave images from the generators; the block and Jacquard
# pictures are themselves generated weaves (a 24-crossing checkerboard, a
# large zigzag and a large herringbone), each colour mapped to a weave
run "$LOOM" pattern make wavy-twill --over 2 --under 2 --period 8 --size 64x64 -q -o wavy.png
run "$LOOM" pattern make basket --over 24 --under 24 -q -o blocks24.pbm
run "$LOOM" pattern make basket --over 16 --under 16 -q -o blocks16.pbm
run "$LOOM" pattern make wavy-twill --over 8 --under 8 --period 16 --size 96x96 -q -o zigzag.pbm
run "$LOOM" pattern make herringbone --over 6 --under 6 --period 12 --size 96x96 -q -o chevron.pbm
cat > satin15.map <<'MAP'
yarn navy #1c2a5a alignment=0.25
yarn gold #d8b048 alignment=0.25
colour 0 satin:15/1:move=7 warp=navy weft=gold
colour 255 satin:1/15:move=7 warp=navy weft=gold
MAP
cat > satin7.map <<'MAP'
yarn wine #7a1424 alignment=0.25
yarn ivory #eee6d2 alignment=0.25
colour 0 satin:7/1:move=3 warp=wine weft=ivory
colour 255 satin:1/7:move=3 warp=wine weft=ivory
MAP
cat > jacq1.map <<'MAP'
yarn teal #16585e alignment=0.25
yarn cream #efe4c8 alignment=0.25
colour 0 satin:7/1:move=3 warp=teal weft=cream
colour 255 twill:1/7 warp=teal weft=cream
MAP
cat > jacq2.map <<'MAP'
yarn plum #4a1d4f alignment=0.25
yarn sand #d9c49a alignment=0.25
colour 0 twill:7/1 warp=plum weft=sand
colour 255 satin:1/7:move=3 warp=plum weft=sand
MAP
# fabrics over the default database
run "$LOOM" synth wavy.png --quiet -o wavy.loomf
for d in satin15:blocks24 satin7:blocks16 jacq1:zigzag jacq2:chevron; do
	run "$LOOM" synth "${d#*:}.pbm" --map "${d%%:*}.map" --quiet -o "${d%%:*}.loomf"
done
# renders: --uv-mm enlarges the cloth so a crossing spans about 3 pixels
# (square crossings of 0.47 mm: the default database states no sett); a
# studio set: each object stands on a grey floor (--ground) that catches
# its shadow, lit by the built-in studio sky (loom render's default) and a sun 60 degrees round from the
# camera and 45 up (a front-side key light) with an 8-degree disc (a
# soft-edged shadow), printed through the filmic curve
R="--ground --ground-albedo 0.45 --tone filmic --width $W --height $H --spp $SPP --quiet"
run "$LOOM" render wavy.loomf --mesh "$MESH/sleeve.obj" --uv-mm 110 --elevation 35 --fov 22 --sun 60,45,2.6,8 $R -o "$OUT/gallery-wavy-twill.png"
run "$LOOM" render satin15.loomf --mesh "$MESH/pillow.obj" --uv-mm 135 --elevation 40 --fov 24 --sun 60,45,2.6,8 $R -o "$OUT/gallery-satin-1-15.png"
run "$LOOM" render satin7.loomf --mesh "$MESH/drape.obj" --uv-mm 120 --elevation 30 --fov 26 --sun 60,45,2.6,8 $R -o "$OUT/gallery-satin-1-7.png"
run "$LOOM" render jacq1.loomf --mesh "$MESH/pillow.obj" --uv-mm 135 --elevation 40 --azimuth 30 --fov 24 --sun 90,45,2.6,8 $R -o "$OUT/gallery-jacquard-zigzag.png"
run "$LOOM" render jacq2.loomf --mesh "$MESH/drape.obj" --uv-mm 120 --elevation 30 --azimuth 20 --fov 26 --sun 80,45,2.6,8 $R -o "$OUT/gallery-jacquard-chevron.png"
