# `loom paint` end to end: regions as rectangles and as a mask image,
# paint files chained (regions kept), the file read back, loom render of a
# paint file (same bytes twice; differs from the unpainted fabric), and
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
mkdir -p "$T/dir.loomp"
expect_exit paint_dir 1 "$LOOM" paint "$T/dir.loomp" --rect 0,0:1,1 --defect stain -o "$T/x.loomp"
rm -rf "$T"
