# `make gallery` (tools/gallery.sh) on a tiny size: every design, fabric
# and render command runs, each picture is written at the size asked
# (pngread.py), the render commands are the ones docs/rendering.md lists,
# and a wrong argument count is a usage error.
SUITE=gallery
. "$LOOM_TOP/tests/cli/lib.sh"

expect_exit usage 2 sh "$LOOM_TOP/tools/gallery.sh" "$LOOM"
expect_ok tiny sh "$LOOM_TOP/tools/gallery.sh" "$LOOM" "$T/g" 48 27 1
cp "$T/out" "$T/log"
for n in wavy-twill satin-1-15 satin-1-7 jacquard-zigzag jacquard-chevron; do
	if PYTHONPATH="$LOOM_TOP/tests/cli" python3 - "$T/g/gallery-$n.png" <<'PY' 2>"$T/pyerr"; then pass "png_$n"; else fail "png_$n" "$(cat "$T/pyerr")"; fi
import sys, pngread
w, h, ch, px = pngread.read(sys.argv[1])
assert (w, h) == (48, 27), (w, h)
PY
done
# the documented commands: each render line as the script ran it, with
# the paths as the docs write them and without the size options
grep '^+ .* render ' "$T/log" | sed -e 's|^+ [^ ]*/loom |loom |' \
	-e "s|$LOOM_TOP/||g" -e 's| --width .*||' >"$T/cmds"
if [ "$(wc -l <"$T/cmds")" -eq 5 ]; then pass five_renders; else
	fail five_renders "$(cat "$T/cmds")"; fi
while read -r c; do
	if grep -qF -- "$c" "$LOOM_TOP/docs/rendering.md"; then pass "documented ${c%% --mesh*}"; else
		fail documented "docs/rendering.md lacks: $c"; fi
done <"$T/cmds"
