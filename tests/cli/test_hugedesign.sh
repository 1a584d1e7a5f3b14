# A design too large for --budget is refused before it is read (issue 14):
# a fabric file whose header records 20,000 x 20,000 crossings (2 GB of
# design and base assignment once loaded; the file is the 64-byte header
# and a sparse tail, nothing else) is refused by `loom scan` (exit 2) and
# `loom sample` (exit 1), naming the size and a lower bound for --budget,
# with a peak RSS far below what loading the design would take (measured
# from outside by getrusage of the child).  With a budget that holds the
# design, the header check lets it through to the full reader, which
# rejects the file (no trailer) without allocating the design either.
SUITE=hugedesign
. "$LOOM_TOP/tests/cli/lib.sh"
F=$T/huge.loomf
python3 - "$F" <<'PY'
import struct, sys, zlib
h = b"\x89LFB\r\n\x1a\n" + struct.pack("<IIIIII", 1, 64, 20000, 20000, 8, 0) + bytes(28)
h += struct.pack("<I", zlib.crc32(h) & 0xffffffff)
assert len(h) == 64
with open(sys.argv[1], "wb") as f:
    f.write(h)
    f.truncate(1 << 30)  # sparse: a 1 GiB file that takes no space
PY
export T
rss() {
	python3 - "$@" <<'PY'
import os, resource, subprocess, sys
t = os.environ["T"]
r = subprocess.run(sys.argv[1:], stdout=open(t + "/out", "wb"), stderr=open(t + "/err", "wb"))
open(t + "/rc", "w").write("%d\n" % r.returncode)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
PY
}
# 5 * 20000^2 bytes = 1907.35 MiB: the bound named is the next whole MiB
NEED=1908
check() { # name, expected exit, command...
	name=$1 code=$2
	shift 2
	KB=$(rss "$@")
	if [ "$(cat "$T/rc")" = "$code" ]; then pass "$name"; else
		fail "$name" "exit $(cat "$T/rc"), expected $code: $(head -c 400 "$T/err")"; fi
	if grep -q "20000 x 20000 = 400000000 crossings" "$T/err" &&
	   grep -q "refused before loading the design" "$T/err" &&
	   grep -q "at least --budget $NEED " "$T/err"; then pass "${name}_message"; else
		fail "${name}_message" "$(head -c 600 "$T/err")"; fi
	echo "peak RSS of the refused $name: $KB kB"
	if [ -n "${LOOM_SAN:-}" ]; then echo "NOTE $SUITE/${name}_rss: not checked under $LOOM_SAN"
	elif [ "$KB" -le 65536 ]; then pass "${name}_rss"; else
		fail "${name}_rss" "$KB kB > 64 MiB"; fi
}
check scan 2 "$LOOM" scan "$F" --region 0,0,0:64,64,8 --reduce checksum --budget 64
check sample 1 "$LOOM" sample "$F" --random 100 --budget 64 --quiet
check scan_budget_16 2 "$LOOM" scan "$F" --region 0,0,0:64,64,8 --reduce checksum --budget 16

# a budget that holds the design: past the header check, the reader
# refuses the file (no trailer), still without reading the design
KB=$(rss "$LOOM" scan "$F" --region 0,0,0:64,64,8 --reduce checksum --budget 4000)
if [ "$(cat "$T/rc")" = 1 ] && ! grep -q "refused before loading" "$T/err" &&
   grep -q "huge.loomf" "$T/err"; then pass big_budget_reader; else
	fail big_budget_reader "exit $(cat "$T/rc"): $(head -c 400 "$T/err")"; fi
echo "peak RSS with --budget 4000: $KB kB"
if [ -n "${LOOM_SAN:-}" ] || [ "$KB" -le 65536 ]; then pass big_budget_rss; else
	fail big_budget_rss "$KB kB"; fi
rm -rf "$T"
