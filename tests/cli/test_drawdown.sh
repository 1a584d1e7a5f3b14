# `loom pattern convert --color` and `--draft` end to end, read back with an
# independent PNG reader (tests/cli/pngread.py): every cell of the colour
# drawdown has the colour of the yarn on top (the WIF's own colours), and
# the draft diagram, decoded mark by mark (threading, tie-up, treadling or
# liftplan), weaves the same drawdown as `convert -o X.pbm`.
SUITE=drawdown
. "$LOOM_TOP/tests/cli/lib.sh"
W=$DATA/wif
PY="python3 -B"
export PYTHONPATH="$LOOM_TOP/tests/cli"

expect_ok help "$LOOM" pattern convert --help
expect_out_contains help_color "--color"
expect_out_contains help_draft "--draft"
expect_exit both 2 "$LOOM" pattern convert "$W/colors.wif" --color --draft -o "$T/x.png"
expect_exit color_pbm 2 "$LOOM" pattern convert "$W/colors.wif" --color -o "$T/x.pbm"
expect_exit cell_alone 2 "$LOOM" pattern convert "$W/colors.wif" --cell 3 -o "$T/x.pbm"
expect_exit cell_range 2 "$LOOM" pattern convert "$W/colors.wif" --color --cell 0 -o "$T/x.png"
expect_exit out_is_dir 1 "$LOOM" pattern convert "$W/colors.wif" --color -o "$T"
expect_err_contains out_is_dir_msg "is a directory"
expect_exit out_no_dir 1 "$LOOM" pattern convert "$W/colors.wif" --color -o "$T/nodir/x.png"
expect_err_contains out_no_dir_msg "nodir"

# colour drawdown: cell by cell against the PBM drawdown and the yarn table
check_color() { # NAME WIF CELL
	"$LOOM" pattern convert "$2" -o "$T/$1.pbm" -q &&
	"$LOOM" pattern info "$2" --json -q >"$T/$1.json" &&
	"$LOOM" pattern convert "$2" --color --cell "$3" -o "$T/$1.png" -q || {
		fail "color_$1" "loom failed"; return; }
	if $PY - "$T/$1.pbm" "$T/$1.json" "$T/$1.png" "$3" "$2" <<'PY' 2>"$T/pyerr"; then pass "color_$1"; else fail "color_$1" "$(tail -3 "$T/pyerr")"; fi
import json, re, sys, pngread
pbm, js, png, cell, wif = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5]
b = open(pbm, 'rb').read()
m = re.match(rb'P4\s+(\d+)\s+(\d+)\s', b)
cols, rows = int(m.group(1)), int(m.group(2))
data, rb = b[m.end():], (cols + 7) // 8
W = [[(data[i * rb + j // 8] >> (7 - j % 8)) & 1 for j in range(cols)] for i in range(rows)]
# the WIF's own colours, by thread, straight from its text
txt = open(wif).read().replace('\r', '\n')
sec, tab = None, {}
for line in txt.split('\n'):
    line = line.split(';')[0].strip()
    if line.startswith('['):
        sec = line.strip('[]').upper(); tab.setdefault(sec, {}); continue
    if '=' in line and sec:
        k, v = line.split('=', 1); tab[sec][k.strip().upper()] = v.strip()
ct = {int(k): [int(x) for x in v.split(',')] for k, v in tab['COLOR TABLE'].items()}
def color(side, n):
    c = tab.get(side + ' COLORS', {}).get(str(n)) or tab[side]['COLOR']
    return ct[int(c.split(',')[0])]
w, h, ch, px = pngread.read(png)
assert (w, h, ch) == (cols * cell, rows * cell, 3), (w, h, ch)
bad = 0
for i in range(rows):
    for j in range(cols):
        want = color('WARP', j + 1) if W[i][j] else color('WEFT', i + 1)
        for dy in range(cell):
            for dx in range(cell):
                got = list(px[i * cell + dy][3 * (j * cell + dx):3 * (j * cell + dx) + 3])
                if got != want:
                    bad += 1
assert bad == 0, '%d pixels differ' % bad
PY
}
check_color colors "$W/colors.wif" 1
check_color colors3 "$W/colors.wif" 3
check_color overshot "$LOOM_TOP/data/overshot-sampler.wif" 1
check_color herringbone "$LOOM_TOP/data/herringbone-8.wif" 2

# draft diagram: decode the marks and weave them
check_draft() { # NAME DESIGN CELL
	"$LOOM" pattern convert "$2" -o "$T/$1.pbm" -q &&
	"$LOOM" pattern convert "$2" --draft --cell "$3" -o "$T/$1.png" 2>"$T/err" || {
		fail "draft_$1" "loom failed: $(cat "$T/err")"; return; }
	if $PY - "$T/$1.pbm" "$T/$1.png" "$3" <<'PY' 2>"$T/pyerr"; then pass "draft_$1"; else fail "draft_$1" "$(tail -3 "$T/pyerr")"; fi
import re, sys, pngread
pbm, png, c = sys.argv[1], sys.argv[2], int(sys.argv[3])
b = open(pbm, 'rb').read()
m = re.match(rb'P4\s+(\d+)\s+(\d+)\s', b)
cols, rows = int(m.group(1)), int(m.group(2))
data, rb = b[m.end():], (cols + 7) // 8
W = [[(data[i * rb + j // 8] >> (7 - j % 8)) & 1 for j in range(cols)] for i in range(rows)]
w, h, ch, px = pngread.read(png)
def dark(x, y):  # the cell whose top-left pixel is (x, y): mark = dark centre
    cx, cy = x + c // 2, y + c // 2
    return sum(px[cy][3 * cx:3 * cx + 3]) < 200
S = h // c - 3 - rows            # layout in docs/designs.md
T = (w // c) - cols - 3
assert S > 0 and T > 0, (S, T)
thr = [[dark(j * c, (2 + S - 1 - s) * c) for s in range(S)] for j in range(cols)]
tie = [[dark((cols + 1 + t) * c, (2 + S - 1 - s) * c) for t in range(T)] for s in range(S)]
trd = [[dark((cols + 1 + t) * c, (3 + S + i) * c) for t in range(T)] for i in range(rows)]
assert all(sum(r) == 1 for r in thr), 'an end on no shaft or on two'
bad = 0
for i in range(rows):
    lifted = [any(trd[i][t] and tie[s][t] for t in range(T)) for s in range(S)]
    for j in range(cols):
        s = thr[j].index(True)
        bad += int(lifted[s]) != W[i][j]
assert bad == 0, '%d cells of the woven draft differ from the drawdown' % bad
PY
}
check_draft herringbone "$LOOM_TOP/data/herringbone-8.wif" 4
check_draft colors "$W/colors.wif" 6
check_draft liftplan "$W/liftplan.wif" 5
"$LOOM" pattern make satin:1/7:move=3 --size 16x24 -o "$T/satin.pbm"
check_draft satin "$T/satin.pbm" 4
expect_err_contains draft_summary "8 shafts"
# a design with more than 24 distinct picks: a liftplan beside a direct tie-up
"$LOOM" pattern make twill:1/29 --size 30x30 -o "$T/t29.pbm"
check_draft liftplan30 "$T/t29.pbm" 3
expect_err_contains draft_liftplan_summary "liftplan of 30 picks"
