# Memory that grows with the design counts against --budget (issue 14): a
# generated 3000 x 3000 design (9 M crossings, 45 MB of design and base
# assignment held in memory) is refused with a budget too small for it,
# naming the minimum, and runs within --budget + 16 MiB of peak RSS (measured
# from outside by getrusage of the child) with the minimum budget and with
# 64 MiB, through `loom scan` and `loom sample` as a user types them.
SUITE=designmem
. "$LOOM_TOP/tests/cli/lib.sh"
N=3000
P=$T/big.pbm
F=$T/big.loomf
REG=0,0,0:1200,1200,40

# the design: a broken twill (2/2 twill flipping direction in 37 x 53
# patches), N x N crossings, as a PBM; each row repeats every 148 ends
python3 - "$N" "$P" <<'PY'
import sys
n, path = int(sys.argv[1]), sys.argv[2]
out = bytearray(b"P4\n%d %d\n" % (n, n))
for i in range(n):
    per = "".join("1" if ((i + j) % 4 if (j // 37 + i // 53) % 2 else (i - j) % 4) < 2
                  else "0" for j in range(148))
    s = (per * (n // 148 + 1))[:n] + "0" * (-n % 8)
    out += int(s, 2).to_bytes(len(s) // 8, "big")
open(path, "wb").write(out)
PY
expect_ok synth "$LOOM" synth "$P" --quiet -o "$F"

# peak RSS (kB) of a command, from getrusage of the child; its stdout and
# stderr go to $T/out and $T/err, its exit status to $T/rc
rss() {
	python3 - "$@" <<'PY'
import resource, subprocess, sys
r = subprocess.run(sys.argv[1:], stdout=open("%s/out" % __import__("os").environ["T"], "wb"),
                   stderr=open("%s/err" % __import__("os").environ["T"], "wb"))
open("%s/rc" % __import__("os").environ["T"], "w").write("%d\n" % r.returncode)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
PY
}
export T

# too small: usage error naming the smallest --budget (scan) and the
# texture's minimum in MiB (sample: --budget is the texture's budget)
expect_exit scan_small 2 "$LOOM" scan "$F" --region "$REG" --reduce checksum --budget 16
# below the design's own 43 MiB: refused from the file's header, before
# the design is read, naming the design's bound (test_hugedesign.sh)
expect_err_contains scan_small_preload "refused before loading the design"
LB=$(sed -n 's/.*this job needs at least --budget \([0-9]*\) (the design alone.*/\1/p' "$T/err")
if [ "$LB" = 43 ]; then pass scan_small_bound; else fail scan_small_bound "bound '$LB': $(head -c 600 "$T/err")"; fi
# at that bound: the texture's own check, with the exact minimum
expect_exit scan_at_bound 2 "$LOOM" scan "$F" --region "$REG" --reduce checksum --budget "$LB"
expect_err_contains scan_small_fabric "design and base assignment of 9000000 crossings"
MIN=$(sed -n 's/.*this job needs at least --budget \([0-9]*\).*/\1/p' "$T/err")
if [ -n "$MIN" ] && [ "$MIN" -gt 43 ] && [ "$MIN" -lt 64 ]; then pass scan_small_min "$MIN"; else
	fail scan_small_min "no minimum between 43 and 64 MiB named: $(head -c 600 "$T/err")"; fi
expect_exit sample_small 1 "$LOOM" sample "$F" --random 1000 --budget 16 --quiet
expect_err_contains sample_small_min "this fabric needs at least"
expect_err_contains sample_small_why "9000000 crossings"
M=$((MIN - 1))
expect_exit scan_below_min 2 "$LOOM" scan "$F" --region "$REG" --reduce checksum --budget "$M"

# at the minimum and at 64 MiB: the same checksum, peak RSS within budget + 16 MiB
for B in "$MIN" 64; do
	KB=$(rss "$LOOM" scan "$F" --region "$REG" --reduce checksum --json --quiet --budget "$B")
	if [ "$(cat "$T/rc")" = 0 ]; then pass "scan_$B"; else fail "scan_$B" "exit $(cat "$T/rc"): $(head -c 400 "$T/err")"; fi
	sed -n 's/.*"checksum": "\([0-9a-f]*\)".*/\1/p' "$T/out" >"$T/cs_$B"
	echo "peak RSS of loom scan --budget $B over a $N x $N design: $KB kB"
	if [ -n "${LOOM_SAN:-}" ]; then echo "NOTE designmem/scan_rss_$B: not checked under $LOOM_SAN"
	elif [ "$KB" -le $(( (B + 16) * 1024 )) ]; then pass "scan_rss_$B"; else
		fail "scan_rss_$B" "$KB kB > $(( (B + 16) * 1024 )) kB"; fi
	KB=$(rss "$LOOM" sample "$F" --random 100000 --json --quiet --budget "$B")
	if [ "$(cat "$T/rc")" = 0 ]; then pass "sample_$B"; else fail "sample_$B" "exit $(cat "$T/rc"): $(head -c 400 "$T/err")"; fi
	echo "peak RSS of loom sample --budget $B over a $N x $N design: $KB kB"
	if [ -n "${LOOM_SAN:-}" ]; then echo "NOTE designmem/sample_rss_$B: not checked under $LOOM_SAN"
	elif [ "$KB" -le $(( (B + 16) * 1024 )) ]; then pass "sample_rss_$B"; else
		fail "sample_rss_$B" "$KB kB > $(( (B + 16) * 1024 )) kB"; fi
done
if [ -s "$T/cs_$MIN" ] && cmp -s "$T/cs_$MIN" "$T/cs_64"; then pass scan_same_checksum; else
	fail scan_same_checksum "$(cat "$T/cs_$MIN") vs $(cat "$T/cs_64")"; fi
rm -rf "$T"
