# `loom render` sampling options end to end (docs/rendering.md,
# "Sampling"): --sampler sobol (default) and random, --noise (adaptive),
# --progressive (intermediate images through a temporary and a rename):
# identical bytes on 1 and 2 threads for each, the final progressive image
# byte-equal to the plain one, intermediate files read back as valid PNGs,
# JSON figures, bad values refused with exit 2.
SUITE=render_sampling
. "$LOOM_TOP/tests/cli/lib.sh"
DB=$T/tiny.ldb
F=$T/tw.loomf

json_check() {
	if python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if eval(sys.argv[2]) else 1)' \
	    "$3" "$2" 2>"$T/pyerr"; then pass "$1"; else
		fail "$1" "JSON check failed: $2: $(head -c 300 "$3") $(head -c 300 "$T/pyerr")"; fi
}
# png_ok FILE W H: a whole PNG of that size whose pixels decode (zlib
# stream complete, one filter byte + 3 W bytes per row)
png_ok() {
	python3 - "$1" "$2" "$3" <<'PY'
import struct, sys, zlib
b = open(sys.argv[1], 'rb').read()
assert b[:8] == b'\x89PNG\r\n\x1a\n', 'bad signature'
p, idat, w = 8, b'', None
while p < len(b):
    n, typ = struct.unpack('>I4s', b[p:p + 8])
    body = b[p + 8:p + 8 + n]
    assert zlib.crc32(b[p + 4:p + 8 + n]) == struct.unpack('>I', b[p + 8 + n:p + 12 + n])[0], 'CRC'
    if typ == b'IHDR':
        w, h, depth, ct = struct.unpack('>IIBB', body[:10])
        assert (w, h, depth, ct) == (int(sys.argv[2]), int(sys.argv[3]), 8, 2), (w, h)
    elif typ == b'IDAT':
        idat += body
    p += 12 + n
    if typ == b'IEND':
        break
assert p == len(b), 'trailing bytes'
raw = zlib.decompress(idat)
assert len(raw) == h * (1 + 3 * w), 'pixel data size'
PY
}

expect_exit bad_sampler 2 "$LOOM" render "$F" --sampler halton -o "$T/x.png"
expect_err_contains bad_sampler_msg "--sampler"
expect_exit bad_noise_zero 2 "$LOOM" render "$F" --noise 0 -o "$T/x.png"
expect_err_contains bad_noise_msg "--noise"
expect_exit bad_noise_big 2 "$LOOM" render "$F" --noise 1.5 -o "$T/x.png"
expect_exit bad_progressive 2 "$LOOM" render "$F" --progressive -1 -o "$T/x.png"
expect_err_contains bad_progressive_msg "--progressive"

expect_ok make_db "$LOOM" exemplar generate --preset tiny --seed 3 --quiet -o "$DB"
expect_ok pattern "$LOOM" pattern make twill --over 2 --under 3 --size 10x10 -o "$T/tw.pbm"
expect_ok synth "$LOOM" synth "$T/tw.pbm" --db "$DB" --quiet -o "$F"

R="--width 48 --height 32 --seed 5 --quiet"
expect_ok sobol "$LOOM" render "$F" $R --spp 4 --threads 2 --json -o "$T/s2.exr"
json_check sobol_json 'j["sampler"] == "sobol" and j["paths"] == 48 * 32 * 4' "$T/out"
expect_ok sobol_1 "$LOOM" render "$F" $R --spp 4 --threads 1 -o "$T/s1.exr"
expect_same sobol_threads "$T/s1.exr" "$T/s2.exr"
expect_ok random "$LOOM" render "$F" $R --spp 4 --sampler random --json -o "$T/r.exr"
json_check random_json 'j["sampler"] == "random"' "$T/out"
if cmp -s "$T/r.exr" "$T/s2.exr"; then fail sampler_differs "sobol and random gave the same bytes"; else
	pass sampler_differs; fi

# adaptive: the grey sky above the horizon stops at 16 samples
A="--region 0,0:40,40 --elevation 10 --spp 40"
expect_ok noise_2 "$LOOM" render "$F" $R $A --noise 0.05 --threads 2 --json -o "$T/n2.exr"
json_check noise_json 'j["noise"] == 0.05 and 16 <= j["mean_spp"] < 40 and j["paths"] < 48 * 32 * 40' "$T/out"
expect_ok noise_1 "$LOOM" render "$F" $R $A --noise 0.05 --threads 1 -o "$T/n1.exr"
expect_same noise_threads "$T/n1.exr" "$T/n2.exr"

# progressive: copies of the output taken while it renders are whole PNGs;
# the final bytes equal a plain render's
P="--spp 32 --noise 0.02"
expect_ok plain "$LOOM" render "$F" $R $P --threads 2 -o "$T/plain.png"
"$LOOM" render "$F" $R $P --threads 2 --progressive 0.2 --json -o "$T/prog.png" \
	>"$T/prog.json" 2>"$T/prog.err" &
pid=$!
i=0
while kill -0 "$pid" 2>/dev/null; do
	if [ -f "$T/prog.png" ] && [ "$i" -lt 50 ]; then
		cp "$T/prog.png" "$T/snap$i.png" 2>/dev/null && i=$((i + 1))
	fi
	sleep 0.1
done
if wait "$pid"; then pass progressive_run; else fail progressive_run "exit $?: $(head -c 300 "$T/prog.err")"; fi
expect_same progressive_final "$T/plain.png" "$T/prog.png"
bad=0
for s in "$T"/snap*.png; do
	[ -f "$s" ] || continue
	png_ok "$s" 48 32 2>"$T/pyerr" || { bad=1; fail progressive_snapshot "$s: $(tail -1 "$T/pyerr")"; }
done
[ "$bad" = 0 ] && pass progressive_snapshots_valid
# not a speed check: only a render that outlasted several periods must
# have written intermediate images
json_check progressive_writes '(j["seconds"] < 0.5 or j["progressive_writes"] >= 1) and j["output"].endswith("prog.png")' "$T/prog.json"
if ls "$T" | grep -q 'prog.png.tmp'; then fail progressive_no_temp "$(ls "$T")"; else pass progressive_no_temp; fi
echo "  progressive: $i copies taken, $(python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j["progressive_writes"], "writes in", round(j["seconds"], 2), "s")' "$T/prog.json")"
