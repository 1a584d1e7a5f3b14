#!/bin/sh
# bench/cycles.sh - loom's renderer against Blender Cycles on the same
# volume (issue 15; run by bench/run.sh, so by make bench).  Needs Blender
# (tools/deps.sh blender) and loom's VDB writer (OpenVDB: tools/deps.sh
# build); skipped with a message when either is absent.
#
# A herringbone (data/herringbone-8.wif, the default database) framed on
# the window BENCH_CYCLES_REGION (default 0,0:256,160 voxels) by `loom
# render`'s flat-patch camera (elevation 40, azimuth 0, fov 30, 240 x 150),
# lit by loom's default sun (azimuth 150 from the camera, elevation 35,
# irradiance 2.6, disc 0.53 degrees) and the grey world (--sky grey, 0.18).  The
# region the camera sees (the frustum's footprint on the slab, and a margin
# for light scattered in from outside it) is exported as OpenVDB tiles and
# rendered by tools/blender/render_tile.py with the same camera (computed
# here as cmd_render.c places it, in mm), sun, world, density scale (80
# per mm), path depth (32) and samples, Cycles on the CPU; both at 2
# threads (BENCH_CYCLES_THREADS, below).  Each renderer runs at S1 and S2 samples per pixel; the time per
# pixel-sample is (t(S2) - t(S1)) / ((S2 - S1) * pixels), so neither's
# fixed costs (Cycles' scene sync and VDB load, loom's majorant grid)
# count.  loom runs with both samplers (sobol, the default, and random);
# lookups per path are loom's at S2.  Prints a table and one JSON line; writes the S2 images and
# side-by-side.png (loom left, Cycles right) into $BUILD/bench/cycles.
# LOOM_BASE=/path/to/other/loom also renders every loom case with that
# binary (a baseline build), interleaved with this one in the same run, and
# reports its ratios too (the ratio moves +-30 % with the machine's load,
# so compare builds only within one run).  BENCH_CYCLES_REPS=N (default 1)
# repeats every case N times, interleaved, and takes each one's fastest.
# Wall time and CPU time (user + system, of the process and its
# children) are both reported, each per pixel-sample as above.
# BENCH_CYCLES_THREADS=N (default 2) renders with N threads in both; 1
# keeps each renderer on one core, which a loaded 2-core machine still
# gives it, so the ratio moves less with the load.
set -u
BUILD=${BUILD:-build}
LOOM=$BUILD/loom
LOOM_BASE=${LOOM_BASE:-}
W=$BUILD/bench/cycles
if ! command -v blender >/dev/null 2>&1; then
	echo "cycles: skipped (Blender not installed: tools/deps.sh blender)"
	exit 0
fi
if [ ! -f "$BUILD/libloom-vdb.so.0" ]; then
	echo "cycles: skipped (this loom has no VDB writer: install OpenVDB, tools/deps.sh build, and rebuild)"
	exit 0
fi
REGION=${BENCH_CYCLES_REGION:-0,0:256,160}
NT=${BENCH_CYCLES_THREADS:-2}
case $NT in
''|*[!0-9]*|0) echo "cycles: BENCH_CYCLES_THREADS must be a positive integer, got '$NT'" >&2; exit 2 ;;
esac
WIDTH=240 HEIGHT=150 EL=40 AZ=0 FOV=30 S1=${BENCH_CYCLES_S1:-4} S2=${BENCH_CYCLES_S2:-16}
SUN="150,35,2.6,0.53"
BL="blender -b --factory-startup --python-exit-code 1"
rm -rf "$W"
mkdir -p "$W"
"$LOOM" synth data/herringbone-8.wif --quiet -o "$W/h8.loomf" || exit 1
NZ=$("$LOOM" info "$W/h8.loomf" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["repeat_voxels"][2])')
VMM=$("$LOOM" info "$W/h8.loomf" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["voxel_size_um"] / 1000)')
# the camera of `loom render --region` (tools/loom/cmd_render.c), in mm,
# and the box of voxels its frustum sees through the slab, with a margin
set -- $(python3 - "$REGION" "$NZ" "$VMM" "$WIDTH" "$HEIGHT" "$EL" "$AZ" "$FOV" <<'EOF'
import math, sys
reg, nz, vmm = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
w, h, el, az, fov = [float(v) for v in sys.argv[4:9]]
(x0, y0), (x1, y1) = [[float(v) for v in p.split(",")] for p in reg.split(":")]
el, az = math.radians(el), math.radians(az)
ty = math.tan(math.radians(fov) / 2)
c = [0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * nz]
wspan = (x1 - x0) / (2 * ty * w / h)
dist = (y1 - y0) * math.sin(el) / (2 * ty)
dist = max(wspan, dist) + 0.5 * (y1 - y0) * math.cos(el)
eye = [c[0] - dist * math.sin(az) * math.cos(el), c[1] - dist * math.cos(az) * math.cos(el),
       c[2] + dist * math.sin(el)]
f = [c[k] - eye[k] for k in range(3)]
n = math.sqrt(sum(v * v for v in f)); f = [v / n for v in f]
r = [f[1], -f[0], 0.0]; n = math.hypot(r[0], r[1]); r = [v / n for v in r]
u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]]
tx = ty * w / h
lo, hi = [math.inf] * 2, [-math.inf] * 2
for sx in (-1, 1):
    for sy in (-1, 1):
        d = [f[k] + sx * tx * r[k] + sy * ty * u[k] for k in range(3)]
        for z in (0, nz):
            t = (z - eye[2]) / d[2]
            for k in range(2):
                p = eye[k] + t * d[k]
                lo[k], hi[k] = min(lo[k], p), max(hi[k], p)
m = 64
blo = [int(math.floor((lo[k] - m) / 64) * 64) for k in range(2)]
bhi = [int(math.ceil((hi[k] + m) / 64) * 64) for k in range(2)]
print("%.9g,%.9g,%.9g" % tuple(v * vmm for v in eye), "%.9g,%.9g,%.9g" % tuple(v * vmm for v in c),
      "%d,%d,0:%d,%d,%d" % (blo[0], blo[1], bhi[0], bhi[1], nz))
EOF
)
EYE=$1 TARGET=$2 BOX=$3
load0=$(cut -d' ' -f1-3 /proc/loadavg)
"$LOOM" export "$W/h8.loomf" --region "$BOX" --format vdb --channels density,albedo \
	--tile 256,256 --threads 2 --budget 400 --quiet --json -o "$W/vdb" >"$W/export.json" || exit 1
# cpu FILE CMD...: run CMD (its exit status kept) and write the CPU seconds
# (user + system) it and its children used to FILE
cpu() {
	python3 -c 'import resource, subprocess, sys
rc = subprocess.call(sys.argv[2:])
r = resource.getrusage(resource.RUSAGE_CHILDREN)
open(sys.argv[1], "w").write("%.4f\n" % (r.ru_utime + r.ru_stime))
sys.exit(rc)' "$@"
}
REPS=${BENCH_CYCLES_REPS:-1}
R=0
while [ $R -lt "$REPS" ]; do
R=$((R + 1))
X=""
[ $R -gt 1 ] && X=".r$R"
for S in $S1 $S2; do
	for SMP in sobol random; do
		for WHO in loom base; do
			BIN=$LOOM
			if [ "$WHO" = base ]; then
				[ -n "$LOOM_BASE" ] || continue
				BIN=$LOOM_BASE
			fi
			cpu "$W/$WHO-$SMP-$S$X.cpu" "$BIN" render "$W/h8.loomf" --region "$REGION" --elevation $EL --azimuth $AZ --fov $FOV \
				--width $WIDTH --height $HEIGHT --spp "$S" --threads "$NT" --sun "$SUN" --sky grey --quiet --json \
				--sampler $SMP -o "$W/$WHO-$SMP-$S.png" >"$W/$WHO-$SMP-$S$X.json" || exit 1
		done
	done
	cp "$W/loom-sobol-$S.png" "$W/loom-$S.png"
	# shellcheck disable=SC2086
	cpu "$W/cycles-$S$X.cpu" $BL -P tools/blender/render_tile.py -- "$W"/vdb/tile-*.vdb -o "$W/cycles-$S.png" \
		--camera persp --eye "$EYE" --target "$TARGET" --fov $FOV --size $WIDTH,$HEIGHT \
		--samples "$S" --threads "$NT" --sun "$SUN" --density 80 --background 0.18 --bounces 32 \
		--json "$W/cycles-$S$X.json" >"$W/cycles-$S.log" 2>&1 || { tail -20 "$W/cycles-$S.log"; exit 1; }
done
done
load1=$(cut -d' ' -f1-3 /proc/loadavg)
$BL -P bench/side_by_side.py -- "$W/loom-$S2.png" "$W/cycles-$S2.png" "$W/side-by-side.png" \
	>"$W/side.log" 2>&1 || tail -5 "$W/side.log"
python3 - "$W" "$S1" "$S2" "$WIDTH" "$HEIGHT" "$BOX" "$load0" "$load1" "$LOOM_BASE" "$NT" <<'EOF'
import glob, json, sys
d, s1, s2, w, h, box, l0, l1 = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), \
    int(sys.argv[5]), sys.argv[6], sys.argv[7], sys.argv[8]
base, nt = sys.argv[9], int(sys.argv[10])
t, lk, cpu = {}, {}, {}
whos = ("loom-sobol", "loom-random", "cycles") + (("base-sobol", "base-random") if base else ())
for who in whos:
    # the fastest of the BENCH_CYCLES_REPS runs of each case (a load
    # spike only ever slows a run down)
    ja = json.load(open("%s/%s-%d.json" % (d, who, s1)))
    jb = json.load(open("%s/%s-%d.json" % (d, who, s2)))
    a = min(json.load(open(f))["seconds"] for f in glob.glob("%s/%s-%d.json" % (d, who, s1)) +
            glob.glob("%s/%s-%d.r*.json" % (d, who, s1)))
    b = min(json.load(open(f))["seconds"] for f in glob.glob("%s/%s-%d.json" % (d, who, s2)) +
            glob.glob("%s/%s-%d.r*.json" % (d, who, s2)))
    t[who] = (a, b, (b - a) / ((s2 - s1) * w * h) * 1e6)
    # CPU seconds (user + system) likewise: what a busy machine moves less
    ca = min(float(open(f).read()) for f in glob.glob("%s/%s-%d.cpu" % (d, who, s1)) +
             glob.glob("%s/%s-%d.r*.cpu" % (d, who, s1)))
    cb = min(float(open(f).read()) for f in glob.glob("%s/%s-%d.cpu" % (d, who, s2)) +
             glob.glob("%s/%s-%d.r*.cpu" % (d, who, s2)))
    cpu[who] = (cb - ca) / ((s2 - s1) * w * h) * 1e6
    if who != "cycles":
        lk[who] = jb["lookups"] / jb["paths"]
t["loom"] = t["loom-sobol"]
ex = json.load(open(d + "/export.json"))
ratio = t["loom"][2] / t["cycles"][2]
print("cycles: %dx%d, %d and %d spp, %d thread%s; exported %s (%d tiles, %.1f MiB) in %.2f s" %
      (w, h, s1, s2, nt, "" if nt == 1 else "s", box, ex["tiles"], ex["bytes_written"] / 1048576, ex["seconds"]))
for who in whos:
    print("  %-11s %6.2f s at %d spp, %6.2f s at %d spp: %7.2f us per pixel-sample%s" %
          (who, t[who][0], s1, t[who][1], s2, t[who][2],
           ", %.1f lookups per path" % lk[who] if who in lk else ""))
print("  loom (sobol) / Cycles per pixel-sample: %.2f; random sampler: %.2f (load average %s before, %s after)" %
      (ratio, t["loom-random"][2] / t["cycles"][2], l0, l1))
print("  CPU time (user + system) per pixel-sample: %s; loom (sobol) / Cycles %.2f, random %.2f" %
      (", ".join("%s %.2f us" % (who, cpu[who]) for who in whos),
       cpu["loom-sobol"] / cpu["cycles"], cpu["loom-random"] / cpu["cycles"]))
res = {}
if base:
    print("  baseline %s (same run): sobol / Cycles %.2f; random %.2f; this build / baseline %.3f (sobol), %.3f (random)" %
          (base, t["base-sobol"][2] / t["cycles"][2], t["base-random"][2] / t["cycles"][2],
           t["loom-sobol"][2] / t["base-sobol"][2], t["loom-random"][2] / t["base-random"][2]))
    res = {"base": base, "base_over_cycles": round(t["base-sobol"][2] / t["cycles"][2], 3),
           "base_random_over_cycles": round(t["base-random"][2] / t["cycles"][2], 3),
           "base_lookups_per_path": round(lk["base-sobol"], 2)}
print(json.dumps(dict({"bench": "cycles", "width": w, "height": h, "spp": [s1, s2], "threads": nt,
                  "export_box": box, "export_seconds": ex["seconds"], "export_tiles": ex["tiles"],
                  "export_bytes": ex["bytes_written"],
                  "loom_us_per_pixel_sample": round(t["loom"][2], 3),
                  "cycles_us_per_pixel_sample": round(t["cycles"][2], 3),
                  "loom_over_cycles": round(ratio, 3),
                  "cpu_us_per_pixel_sample": {k: round(v, 3) for k, v in cpu.items()},
                  "cpu_loom_over_cycles": round(cpu["loom-sobol"] / cpu["cycles"], 3),
                  "cpu_loom_random_over_cycles": round(cpu["loom-random"] / cpu["cycles"], 3),
                  "loom_random_us_per_pixel_sample": round(t["loom-random"][2], 3),
                  "loom_random_over_cycles": round(t["loom-random"][2] / t["cycles"][2], 3),
                  "loom_lookups_per_path": round(lk["loom-sobol"], 2),
                  "loom_random_lookups_per_path": round(lk["loom-random"], 2),
                  "load_before": l0, "load_after": l1}, **res),
                 separators=(",", ":")))
EOF
