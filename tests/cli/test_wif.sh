# End-to-end: `loom pattern convert X.wif -o X.pbm` gives the drawdown in
# tests/data/wif/X.expected.pbm (first row = pick 1, black = warp over);
# invalid WIF files fail with exit 1 and their file:line message.
#
# The expected files are P1 (text) and loom writes P4 (binary), so each
# output is checked twice: against the expected file converted by loom
# itself, and bit by bit with a small od+awk P4 decoder that does not depend
# on loom's image reader.
SUITE=wif_cli
. "$LOOM_TOP/tests/cli/lib.sh"
W=$DATA/wif

if ! "$LOOM" pattern convert --help >/dev/null 2>&1; then
	fail pattern_convert_exists "'loom pattern convert --help' failed; nothing else tested"
	exit 0
fi

# p1_bits FILE: the pixels of a P1 file as one line of 0/1 per row
p1_bits() {
	awk '
	{ sub(/#.*/, ""); for (i = 1; i <= NF; i++) tok[n++] = $i }
	END {
		# tok[0] = P1, tok[1] = width, tok[2] = height, then pixels; pixels
		# may also be written without spaces ("0110"), so split them
		w = tok[1]; h = tok[2]; s = ""
		for (k = 3; k < n; k++) s = s tok[k]
		for (r = 0; r < h; r++) print substr(s, r * w + 1, w)
	}' "$1"
}

# p4_bits FILE: the pixels of a P4 file, same layout as p1_bits
p4_bits() {
	od -An -v -tu1 "$1" | awk '
	{ for (i = 1; i <= NF; i++) b[n++] = $i }
	END {
		k = 2; st = 0; w = 0; h = 0                  # skip "P4"
		while (st < 2) {                            # width, height
			c = b[k]
			if (c == 35) { while (b[k] != 10 && k < n) k++; continue }
			if (c >= 48 && c <= 57) {
				v = 0
				while (b[k] >= 48 && b[k] <= 57) { v = v * 10 + b[k] - 48; k++ }
				if (st == 0) w = v; else h = v
				st++
				continue
			}
			k++
		}
		k++                                         # one whitespace byte
		rb = int((w + 7) / 8)
		for (r = 0; r < h; r++) {
			line = ""
			for (x = 0; x < w; x++) {
				byte = b[k + r * rb + int(x / 8)]
				bit = int(byte / 2 ^ (7 - x % 8)) % 2
				line = line bit
			}
			print line
		}
	}'
}

for f in basic-twill sinking-shed sinking-no liftplan liftplan-wins \
         multi-shaft multi-treadle zero-unused empty-values gaps crlf cr-only \
         comments preamble private-sections mixed-case \
         dialect-fiberworks dialect-weavepoint dialect-weaveit \
         dialect-pixeloom dialect-proweave dialect-arahweave; do
	expect_ok "convert_$f" "$LOOM" pattern convert "$W/$f.wif" -o "$T/$f.pbm"
	if [ -f "$T/$f.pbm" ]; then
		p4_bits "$T/$f.pbm" >"$T/$f.got"
		p1_bits "$W/$f.expected.pbm" >"$T/$f.want"
		expect_same "bits_$f" "$T/$f.got" "$T/$f.want"
		"$LOOM" pattern convert "$W/$f.expected.pbm" -o "$T/$f.e.pbm" 2>/dev/null
		expect_same "same_as_expected_$f" "$T/$f.pbm" "$T/$f.e.pbm"
	fi
done

# warnings reach stderr as "loom: warning: ..." and do not fail the command
expect_ok warn_no_rising_shed "$LOOM" pattern convert "$W/no-rising-shed.wif" -o "$T/w.pbm"
expect_err_contains warn_no_rising_shed_text "loom: warning: "
expect_err_contains warn_no_rising_shed_where "no-rising-shed.wif:6: no Rising Shed in [WEAVING]"

# invalid files: exit 1, message with file:line, no output file
for f in bad-treadling-no-tieup bad-color-index bad-no-threading bad-no-picks \
         bad-huge-design bad-number bad-section; do
	rm -f "$T/bad.pbm"
	expect_exit "reject_$f" 1 "$LOOM" pattern convert "$W/$f.wif" -o "$T/bad.pbm"
	msg=$(sed -n 's/^; expect-error: LOOM_[A-Z]* //p' "$W/$f.wif")
	expect_err_contains "reject_${f}_message" "$msg"
	if [ -e "$T/bad.pbm" ]; then fail "reject_${f}_no_output" "output written"
	else pass "reject_${f}_no_output"; fi
done

# the shipped drafts convert, and info lists their yarn types
for f in "$LOOM_TOP"/data/*.wif; do
	n=$(basename "$f" .wif)
	expect_ok "data_$n" "$LOOM" pattern convert "$f" -o "$T/$n.pbm"
	if [ -s "$T/err" ]; then fail "data_${n}_quiet" "warnings: $(head -c 300 "$T/err")"
	else pass "data_${n}_quiet"; fi
done
expect_ok info_overshot "$LOOM" pattern info "$LOOM_TOP/data/overshot-sampler.wif"
expect_out_contains info_overshot_type "weft #801c2e"

# forgiving reads (issue 16): a line without '=' inside a table, an untied
# treadle and a draft numbered from 0 are read with a warning naming the line
for f in table-no-equals untied-treadle zero-based; do
	expect_ok "forgive_$f" "$LOOM" pattern convert "$W/$f.wif" -o "$T/$f.pbm"
	want=$(sed -n 's/^; expect-warning: //p' "$W/$f.wif" | head -1)
	expect_err_contains "forgive_${f}_warning" "/$want"
	p4_bits "$T/$f.pbm" >"$T/$f.got"
	p1_bits "$W/$f.expected.pbm" >"$T/$f.want"
	expect_same "forgive_${f}_bits" "$T/$f.got" "$T/$f.want"
done
expect_ok zero_based_colours "$LOOM" pattern info "$W/zero-based.wif"
expect_out_contains zero_based_warp "warp #ffffff"
expect_out_contains zero_based_weft "weft #c80000"

# misnamed input (issue 16): a picture, a volume or random bytes named .wif
# is recognised before parsing and named, never parsed into line errors
cp "$LOOM_TOP/docs/images/demo.png" "$T/png.wif"
printf 'NRRD0004\ntype: uchar\n' >"$T/nrrd.wif"
printf 'P4\n8 8\n\377\377\377\377\377\377\377\377' >"$T/pbm.wif"
printf '[WIF]\nVersion=1.1\n\000\001\002' >"$T/nul.wif"
for k in png:"a PNG image" nrrd:"an NRRD volume" pbm:"a PBM/PGM/PPM image" \
	nul:"binary data"; do
	f=${k%%:*}; what=${k#*:}
	expect_exit "misnamed_$f" 1 "$LOOM" pattern convert "$T/$f.wif" -o "$T/mis.pbm"
	expect_err_contains "misnamed_${f}_message" "$f.wif: not a WIF draft (looks like $what)"
done
if [ -e "$T/mis.pbm" ]; then fail misnamed_no_output "output written"
else pass misnamed_no_output; fi
