# `loom export` end to end: usage errors, the three formats read back
# (.vol by a Python reader compared with `loom sample --at` and across tile
# sizes, NRRD by Teem's unu and against the .vol data, EXR by exrheader),
# determinism over threads and budgets, a killed export resumed to the same
# bytes and manifest, shards whose union equals the whole and whose merged
# manifest equals the unsharded one.
SUITE=export
. "$LOOM_TOP/tests/cli/lib.sh"
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf
REG=-70,-40,0:90,60,48

expect_ok help "$LOOM" export --help
expect_out_contains help_text "--shard I/N"
expect_exit no_args 2 "$LOOM" export
expect_ok synth "$LOOM" synth "$WIF" --quiet -o "$F"
expect_exit no_format 2 "$LOOM" export "$F" --region "$REG" -o "$T/x"
expect_exit no_region 2 "$LOOM" export "$F" --format vol -o "$T/x"
expect_exit no_out 2 "$LOOM" export "$F" --region "$REG" --format vol
expect_exit bad_region 2 "$LOOM" export "$F" --region 0,0,0:10,10 --format vol -o "$T/x"
expect_err_contains bad_region_msg "bad --region '0,0,0:10,10' (expected X0,Y0,Z0:X1,Y1,Z1"
expect_exit empty_region 2 "$LOOM" export "$F" --region 5,0,0:5,10,10 --format vol -o "$T/x"
expect_exit bad_format 2 "$LOOM" export "$F" --region "$REG" --format tiff -o "$T/x"
expect_exit bad_channels 2 "$LOOM" export "$F" --region "$REG" --format vol --channels density,colour -o "$T/x"
expect_exit bad_tile 2 "$LOOM" export "$F" --region "$REG" --format vol --tile 0,4 -o "$T/x"
expect_exit bad_shard 2 "$LOOM" export "$F" --region "$REG" --format vol --shard 3/3 -o "$T/x"
expect_exit region_and_all 2 "$LOOM" export "$F" --region "$REG" --all --format vol -o "$T/x"
expect_exit tile_over_budget 2 "$LOOM" export "$F" --all --format vol --tile 2048,2048 --budget 16 -o "$T/x"
expect_err_contains tile_over_budget_msg "more than --budget"
# one large tile: the advice is a smaller tile, not a larger one
expect_err_contains tile_over_budget_advice "use a smaller --tile"
# the manifest (a line per tile) counts against the budget: 16000 tiles of
# one voxel column do not fit in 4 MiB, and nothing is written
expect_exit manifest_over_budget 2 "$LOOM" export "$F" --region "$REG" --format vol \
	--channels density --tile 1,1 --budget 4 -o "$T/manifest_budget"
expect_err_contains manifest_over_budget_msg "16000 tiles need about"
if [ -e "$T/manifest_budget/manifest.json" ]; then fail manifest_over_budget_nothing "a manifest was written"
else pass manifest_over_budget_nothing; fi
: >"$T/afile"
expect_exit out_not_dir 1 "$LOOM" export "$F" --region "$REG" --format vol -o "$T/afile/sub"
expect_exit merge_nothing 1 "$LOOM" export --merge "$T"

ALL=density,orientation,albedo,kind,type
# reference: one tile over the whole region; then 48 x 32 tiles on 2 threads
expect_ok vol_one "$LOOM" export "$F" --region "$REG" --format vol --channels $ALL \
	--tile 160,100 --quiet -o "$T/one"
expect_ok vol_tiles "$LOOM" export "$F" --region "$REG" --format vol --channels $ALL \
	--tile 48,32 --threads 2 --quiet --json -o "$T/vol"
expect_out_contains vol_json '"tiles_written": 16'
# part of the thickness, tiles split in z (x fastest reads with z < b3)
expect_ok vol_z "$LOOM" export "$F" --region -70,-40,5:90,60,30 --format vol --channels $ALL \
	--tile 48,32,10 --quiet -o "$T/volz"

# a few voxels looked up one by one, for the Python check below
for p in "-70,-40,10" "0,0,20" "17,33,25" "89,59,30" "-1,-1,12" "45,-20,40" "60,10,5" "-30,50,22"; do
	"$LOOM" sample "$F" --at "$p" --json >"$T/at_$p.json" 2>/dev/null
done
for x in 0 1 2 3 4 5 6 7 8 9 10 11; do # a run along z through the cloth
	"$LOOM" sample "$F" --at "5,7,$((x * 4))" --json >"$T/at_z$x.json" 2>/dev/null
done
if python3 - "$T" >"$T/py" 2>&1 <<'EOF'
import glob, json, os, struct, sys
d = sys.argv[1]
LO, HI = (-70, -40, 0), (90, 60, 48)
N = [HI[a] - LO[a] for a in range(3)]
CH = {"density": 1, "orientation": 3, "albedo": 3, "kind": 1, "type": 1}

def read_vol(path):
    b = open(path, "rb").read()
    assert b[:3] == b"VOL" and b[3] == 3, path
    enc, nx, ny, nz, nc = struct.unpack_from("<5i", b, 4)
    box = struct.unpack_from("<6f", b, 24)
    size = 1 if enc == 3 else 4
    assert enc == (3 if path.endswith(".density.vol") else 1), (path, enc)
    assert len(b) == 48 + nx * ny * nz * nc * size, path
    return (nx, ny, nz, nc, size), box, b[48:]

def manifest(sub):
    m = json.load(open(os.path.join(d, sub, "manifest.json")))
    assert m["complete"] and m["tiles_listed"] == m["tiles_total"], m
    return m

# the one-tile export: the whole region per channel
one = {}
for t in manifest("one")["tiles"]:
    assert t["lo"] == list(LO) and t["hi"] == list(HI), t
    for f in t["files"]:
        ch = f["name"].split(".")[1]
        one[ch] = read_vol(os.path.join(d, "one", f["name"]))
assert sorted(one) == sorted(CH), one.keys()
# every tile of the tiled exports equals the same rows of the whole
def check(sub, nvox):
  m = manifest(sub)
  covered = 0
  for t in m["tiles"]:
      lo, hi = t["lo"], t["hi"]
      covered += (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2])
      for f in t["files"]:
          p = os.path.join(d, sub, f["name"])
          assert os.path.getsize(p) == f["bytes"]
          ch = f["name"].split(".")[1]
          (nx, ny, nz, nc, size), box, data = read_vol(p)
          assert (nx, ny, nz) == tuple(hi[a] - lo[a] for a in range(3)), f
          for a in range(3):  # node-centred box: first to last voxel centre, mm
              assert abs(box[a] - (lo[a] + 0.5) * 0.024) < 1e-4, (f, box)
              if hi[a] - lo[a] > 1:
                  assert abs(box[3 + a] - (hi[a] - 0.5) * 0.024) < 1e-4, (f, box)
          whole = one[ch][2]
          w = nx * nc * size
          for z in range(nz):
              for y in range(ny):
                  gz, gy, gx = lo[2] - LO[2] + z, lo[1] - LO[1] + y, lo[0] - LO[0]
                  off = ((gz * N[1] + gy) * N[0] + gx) * nc * size
                  assert data[(z * ny + y) * w:(z * ny + y + 1) * w] == whole[off:off + w], (f, y, z)
  assert covered == nvox, (sub, covered)
check("vol", N[0] * N[1] * N[2])
check("volz", N[0] * N[1] * 25)
dens = one["density"][2]
nonempty = sum(1 for v in dens if v)
assert 0.05 * len(dens) < nonempty < 0.95 * len(dens), nonempty

def voxel(ch, key):
    (nx, ny, nz, nc, size), _, data = one[ch]
    i = (((key[2] - LO[2]) * ny + key[1] - LO[1]) * nx + key[0] - LO[0]) * nc
    if size == 1:
        return [data[i] / 255.0]
    return list(struct.unpack_from("<%df" % nc, data, 4 * i))

n = 0
for p in glob.glob(os.path.join(d, "at_*.json")):
    s = json.load(open(p))
    key = tuple(s["position"])
    assert abs(voxel("density", key)[0] - s["density"]) < 1e-6, (key, s)
    for a in range(3):
        assert abs(voxel("orientation", key)[a] - s["orientation"][a]) < 1e-6, (key, s)
        assert abs(voxel("albedo", key)[a] - s["albedo"][a]) < 1e-6, (key, s)
    assert voxel("kind", key)[0] == s["kind"] and voxel("type", key)[0] == s["type"], (key, s)
    n += s["density"] > 0
assert n >= 3, n
open(os.path.join(d, "density.bin"), "wb").write(dens)
print("ok", nonempty)
EOF
then pass vol_readback; else fail vol_readback "$(tail -5 "$T/py")"; fi

# same bytes for any thread count and budget
expect_ok vol_t1_b8 "$LOOM" export "$F" --region "$REG" --format vol --channels $ALL \
	--tile 48,32 --threads 1 --budget 8 --quiet -o "$T/vol_b8"
if (cd "$T/vol" && for f in *; do cmp -s "$f" "$T/vol_b8/$f" || echo "$f"; done) | grep -q .; then
	fail vol_deterministic "files differ between --threads 2 --budget 64 and --threads 1 --budget 8"
else pass vol_deterministic; fi
# and for tiles taken in index order instead of grouped by source block
expect_ok vol_index_order env LOOM_TILE_ORDER=index "$LOOM" export "$F" --region "$REG" \
	--format vol --channels $ALL --tile 48,32 --threads 2 --quiet -o "$T/vol_idx"
if (cd "$T/vol" && for f in *; do cmp -s "$f" "$T/vol_idx/$f" || echo "$f"; done) | grep -q .; then
	fail vol_order_free "files differ between source and index tile order"
else pass vol_order_free; fi

# NRRD: unu reads it; the values equal the .vol ones
expect_ok nrrd "$LOOM" export "$F" --region "$REG" --format nrrd --channels density,orientation,kind \
	--tile 160,100 --quiet -o "$T/nrrd"
if command -v teem-unu >/dev/null 2>&1; then
	expect_ok unu_head teem-unu head "$T/nrrd/tile-0-0-0.density.nrrd"
	expect_out_contains unu_spacing "space directions: (0.024,0,0) (0,0.024,0) (0,0,0.024)"
	expect_out_contains unu_origin "space origin: (-1.668,-0.948,0.012)"
	expect_ok unu_minmax teem-unu minmax "$T/nrrd/tile-0-0-0.kind.nrrd"
	expect_out_contains unu_kind_max "max: 2"
	expect_ok unu_minmax_orient teem-unu minmax "$T/nrrd/tile-0-0-0.orientation.nrrd"
	expect_ok unu_slice teem-unu slice -i "$T/nrrd/tile-0-0-0.density.nrrd" -a 2 -p 20 -o "$T/slice.nrrd"
else
	fail unu "teem-unu is not installed (tools/deps.sh test installs it)"
fi
if python3 - "$T" >"$T/py" 2>&1 <<'EOF'
import os, struct, sys
d = sys.argv[1]
ref = open(os.path.join(d, "density.bin"), "rb").read()
b = open(os.path.join(d, "nrrd", "tile-0-0-0.density.nrrd"), "rb").read()
hdr, data = b.split(b"\n\n", 1)
assert b"type: float" in hdr and b"sizes: 160 100 48" in hdr, hdr
vals = struct.unpack("<%df" % len(ref), data)
exp = [struct.unpack("<f", struct.pack("<f", r / 255.0))[0] for r in range(256)]
assert all(v == exp[r] for v, r in zip(vals, ref))
k = open(os.path.join(d, "nrrd", "tile-0-0-0.kind.nrrd"), "rb").read().split(b"\n\n", 1)[1]
assert len(k) == len(ref) and set(k) <= {0, 1, 2} and len(set(k)) == 3
print("ok")
EOF
then pass nrrd_values; else fail nrrd_values "$(tail -5 "$T/py")"; fi

# EXR: one multi-channel image per z per tile; exrheader reads them
expect_ok exr "$LOOM" export "$F" --region -8,-8,0:24,16,48 --format exr --channels $ALL \
	--tile 16,16 --quiet -o "$T/exr"
n=$(ls "$T/exr" | grep -c '\.exr$')
if [ "$n" -eq $((4 * 48)) ]; then pass exr_count; else fail exr_count "$n files, expected 192"; fi
expect_ok exrheader exrheader "$T/exr/tile-1-0-0.z20.exr"
expect_out_contains exr_zip "zip"
expect_out_contains exr_orient "orientation.x"
expect_out_contains exr_slice "loomSliceZ (type int): 20"

# kill an export midway (a test hook slows each tile down), then re-run it
R2=0,0,0:128,96,48
expect_ok ref_run "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --quiet -o "$T/ref"
LOOM_EXPORT_TILE_DELAY_MS=150 "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 \
	--quiet -o "$T/kill" >/dev/null 2>&1 &
pid=$!
i=0
while [ $i -lt 100 ]; do
	if grep -q '"tiles_listed": [1-9]' "$T/kill/manifest.json" 2>/dev/null; then break; fi
	sleep 0.1
	i=$((i + 1))
done
kill -KILL $pid 2>/dev/null
wait $pid 2>/dev/null
if grep -q '"complete": false' "$T/kill/manifest.json" 2>/dev/null; then pass killed_midway
else fail killed_midway "the export was not caught midway"; fi
expect_ok resume "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 -o "$T/kill"
expect_err_contains resume_skips "already complete and verified"
expect_same resume_manifest "$T/ref/manifest.json" "$T/kill/manifest.json"
if [ "$(ls "$T/ref")" = "$(ls "$T/kill")" ] &&
   ! (cd "$T/ref" && for f in *; do cmp -s "$f" "$T/kill/$f" || echo "$f"; done) | grep -q .; then
	pass resume_bytes; else fail resume_bytes "files differ after resuming"; fi
# a corrupted tile file is rewritten by the next run
printf 'x' | dd of="$T/kill/tile-2-1-0.density.vol" bs=1 seek=100 conv=notrunc 2>/dev/null
expect_ok rerun "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --json -o "$T/kill"
expect_out_contains rerun_json '"tiles_skipped": 11' 
expect_out_contains rerun_one '"tiles_written": 1'
expect_same rerun_fixed "$T/ref/tile-2-1-0.density.vol" "$T/kill/tile-2-1-0.density.vol"
# another export into the same directory is refused
expect_exit other_params 1 "$LOOM" export "$F" --region $R2 --format vol --tile 16,16 --quiet -o "$T/kill"
expect_err_contains other_params_msg "belongs to another export"

# shards: union = whole, merged manifest = unsharded manifest
for s in 0 1 2; do
	expect_ok shard_$s "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 \
		--shard $s/3 --quiet -o "$T/sh"
done
expect_ok merge "$LOOM" export --merge "$T/sh"
expect_same merge_manifest "$T/ref/manifest.json" "$T/sh/manifest.json"
if [ "$(ls "$T/ref" | grep -v manifest)" = "$(ls "$T/sh" | grep -v manifest)" ] &&
   ! (cd "$T/ref" && for f in tile-*; do cmp -s "$f" "$T/sh/$f" || echo "$f"; done) | grep -q .; then
	pass shard_union; else fail shard_union "shards' files differ from the whole"; fi
expect_ok shard_partial "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 \
	--shard 0/2 --quiet -o "$T/sh2"
: >"$T/sh2/manifest-1-of-2.json.tmp.999999" # a dead run's temporary is no manifest
expect_exit merge_missing 1 "$LOOM" export --merge "$T/sh2"
expect_err_contains merge_missing_msg "1 of 2 shards not complete: 1 (no manifest: 1)"

# --status: complete, missing and damaged tiles, the shards to run again
expect_exit status_partial 1 "$LOOM" export --status "$T/sh2" --json
cp "$T/out" "$T/st_partial.json"
expect_ok status_whole "$LOOM" export --status "$T/sh" --verify
expect_out_contains status_whole_text "12 tiles: 12 complete, 0 missing, 0 damaged"
expect_ok status_quiet "$LOOM" export --status "$T/sh" --quiet
if [ -s "$T/out" ] || [ -s "$T/err" ]; then fail status_quiet_silent "output with --quiet"
else pass status_quiet_silent; fi
cp -r "$T/sh" "$T/shd"
rm "$T/shd/manifest.json"
rm -f "$T/shd/tile-1-1-0.orientation.vol"
printf 'x' | dd of="$T/shd/tile-3-2-0.density.vol" bs=1 seek=77 conv=notrunc 2>/dev/null
expect_exit status_size_ok 1 "$LOOM" export --status "$T/shd" --json
cp "$T/out" "$T/st_size.json"
expect_exit status_crc 1 "$LOOM" export --status "$T/shd" --verify --json
cp "$T/out" "$T/st_crc.json"
expect_exit merge_damaged 1 "$LOOM" export --merge "$T/shd"
expect_err_contains merge_damaged_msg "the files of tile 5 are missing or have another size: run shard"
expect_exit status_nothing 1 "$LOOM" export --status "$T/afile_dir_none"
expect_exit status_and_merge 2 "$LOOM" export --status "$T/sh" --merge "$T/sh"
expect_exit verify_alone 2 "$LOOM" export "$F" --region $R2 --format vol --verify -o "$T/v"
if python3 - "$T" >"$T/py" 2>&1 <<'EOF2'
import json, os, sys
d = sys.argv[1]
p = json.load(open(os.path.join(d, "st_partial.json")))
assert not p["complete"] and p["shards"] == 2 and p["tiles_total"] == 12, p
assert p["shards_to_run"] == "1" and p["shards_complete"] == "0", p
assert p["tiles_complete"] == 6 and p["tiles_missing"] == 6 and p["tiles_damaged"] == 0, p
assert len(p["missing"]) == 6 and not p["lists_truncated"], p
sm = p["shard_manifests"]
assert [s["manifest"] for s in sm] == [True, False] and not any(s["running"] for s in sm), sm
s = json.load(open(os.path.join(d, "st_size.json")))
# tile-1-1-0 (index 5) lost a file: damaged by size; the flipped byte is
# seen only with --verify
assert s["tiles_damaged"] == 1 and s["damaged"][0]["index"] == 5, s
assert "tile-1-1-0.orientation.vol is missing" in s["damaged"][0]["why"], s
c = json.load(open(os.path.join(d, "st_crc.json")))
assert c["tiles_damaged"] == 2 and c["verified_crc32"], c
assert sorted(x["index"] for x in c["damaged"]) == [5, 11], c
assert "CRC-32" in [x for x in c["damaged"] if x["index"] == 11][0]["why"], c
assert c["tiles_complete"] == 10 and c["tiles_missing"] == 0 and not c["merged"], c
# the shards to run again hold the damaged tiles (and are runnable lists)
assert c["shards_to_run"] and all(ch.isdigit() or ch in ",-" for ch in c["shards_to_run"]), c
print("ok")
EOF2
then pass status_json; else fail status_json "$(tail -5 "$T/py")"; fi
# running the shards named again repairs the export
for s in $(sed -n 's/.*"shards_to_run": "\([0-9,-]*\)".*/\1/p' "$T/st_crc.json" | tr ',' ' '); do
	"$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --shard $s/3 --quiet -o "$T/shd" ||
		fail status_rerun "shard $s failed"
done
expect_ok status_repaired "$LOOM" export --status "$T/shd" --verify
expect_ok merge_repaired "$LOOM" export --merge "$T/shd" --quiet
expect_same merge_repaired_manifest "$T/ref/manifest.json" "$T/shd/manifest.json"

# --shard auto: I and N from a Slurm array task's or the generic variables
expect_ok auto_slurm env SLURM_ARRAY_TASK_ID=1 SLURM_ARRAY_TASK_COUNT=3 SLURM_ARRAY_TASK_MIN=0 \
	SLURM_ARRAY_TASK_MAX=2 "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 \
	--shard auto --quiet -o "$T/auto"
if [ -f "$T/auto/manifest-1-of-3.json" ] && cmp -s "$T/auto/manifest-1-of-3.json" "$T/sh/manifest-1-of-3.json"
then pass auto_slurm_manifest; else fail auto_slurm_manifest "not shard 1/3's manifest"; fi
expect_ok auto_generic env LOOM_SHARD_INDEX=2 LOOM_SHARD_COUNT=3 "$LOOM" export "$F" --region $R2 \
	--format vol --tile 32,32 --shard auto --quiet -o "$T/auto"
# a resubmitted task (--array=0 alone) takes N from LOOM_SHARD_COUNT
expect_ok auto_resubmit env SLURM_ARRAY_TASK_ID=0 SLURM_ARRAY_TASK_COUNT=1 SLURM_ARRAY_TASK_MIN=0 \
	SLURM_ARRAY_TASK_MAX=0 LOOM_SHARD_COUNT=3 "$LOOM" export "$F" --region $R2 --format vol \
	--tile 32,32 --shard auto --quiet -o "$T/auto"
expect_ok auto_merge "$LOOM" export --merge "$T/auto" --quiet
expect_same auto_merge_manifest "$T/ref/manifest.json" "$T/auto/manifest.json"
expect_exit auto_resubmit_no_count 2 env SLURM_ARRAY_TASK_ID=3 SLURM_ARRAY_TASK_COUNT=1 \
	SLURM_ARRAY_TASK_MIN=3 SLURM_ARRAY_TASK_MAX=3 "$LOOM" export "$F" --region $R2 --format vol \
	--shard auto -o "$T/auto2"
expect_err_contains auto_resubmit_msg "set LOOM_SHARD_COUNT"
expect_exit auto_absent 2 env -u SLURM_ARRAY_TASK_ID -u SLURM_ARRAY_TASK_COUNT -u LOOM_SHARD_INDEX \
	-u LOOM_SHARD_COUNT "$LOOM" scan "$F" --region $R2 --reduce checksum --shard auto
expect_err_contains auto_absent_msg "--shard auto: \$SLURM_ARRAY_TASK_ID and \$SLURM_ARRAY_TASK_COUNT"
expect_exit auto_range 2 env LOOM_SHARD_INDEX=3 LOOM_SHARD_COUNT=3 "$LOOM" scan "$F" --region $R2 \
	--reduce checksum --shard auto
expect_exit auto_bad 2 env LOOM_SHARD_INDEX=x LOOM_SHARD_COUNT=3 "$LOOM" scan "$F" --region $R2 \
	--reduce checksum --shard auto

# two runs of one shard at once: the second is refused and nothing is damaged
# (the first run takes 4 tiles x 1.5 s; it holds its lock from the start)
LOOM_EXPORT_TILE_DELAY_MS=1500 "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 \
	--shard 1/3 --quiet -o "$T/conc" >"$T/conc1.out" 2>&1 &
pid=$!
i=0
while [ $i -lt 100 ] && ! [ -f "$T/conc/.loom-export.lock" ]; do sleep 0.05; i=$((i + 1)); done
sleep 0.3
expect_exit conc_second 1 "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --shard 1/3 \
	--quiet -o "$T/conc"
expect_err_contains conc_second_msg "shard 1/3 of $T/conc is being written by another run (process $pid)"
expect_exit conc_other_split 1 "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 \
	--shard 0/2 --quiet -o "$T/conc"
expect_err_contains conc_other_split_msg "is being written by a differently sharded export (process $pid)"
expect_ok conc_other_shard "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --shard 0/3 \
	--quiet -o "$T/conc"
expect_exit conc_merge_running 1 "$LOOM" export --merge "$T/conc"
expect_exit conc_status_running 1 "$LOOM" export --status "$T/conc" --json
expect_out_contains conc_status_running_shard '"shards_running": "1"'
if wait $pid; then pass conc_first; else fail conc_first "the first run failed: $(cat "$T/conc1.out")"; fi
expect_ok conc_last "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --shard 2/3 \
	--quiet -o "$T/conc"
expect_ok conc_merge "$LOOM" export --merge "$T/conc" --quiet
expect_same conc_manifest "$T/ref/manifest.json" "$T/conc/manifest.json"
if ! (cd "$T/ref" && for f in tile-*; do cmp -s "$f" "$T/conc/$f" || echo "$f"; done) | grep -q .; then
	pass conc_bytes; else fail conc_bytes "files differ after concurrent runs"; fi
# a dead writer's temporary files of the shard are removed by its next run,
# another shard's are left alone
: >"$T/conc/manifest-0-of-3.json.tmp.999999"
idx_other=$(python3 -c "import json;print(json.load(open('$T/conc/manifest-1-of-3.json'))['tiles'][0]['tile'])" |
	tr -d '[] ' | tr ',' '-')
: >"$T/conc/tile-$idx_other.density.vol.tmp.999999.0"
own=$(python3 -c "import json;t=[x['tile'] for x in json.load(open('$T/conc/manifest-0-of-3.json'))['tiles']];print('-'.join(map(str,t[0])))")
: >"$T/conc/tile-$own.kind.vol.tmp.999999.3"
expect_ok conc_sweep "$LOOM" export "$F" --region $R2 --format vol --tile 32,32 --shard 0/3 \
	--quiet -o "$T/conc"
if [ -e "$T/conc/tile-$own.kind.vol.tmp.999999.3" ] || [ -e "$T/conc/manifest-0-of-3.json.tmp.999999" ]
then fail conc_sweep_own "shard 0's temporaries are still there"; else pass conc_sweep_own; fi
if [ -e "$T/conc/tile-$idx_other.density.vol.tmp.999999.0" ]; then pass conc_sweep_other
else fail conc_sweep_other "another shard's temporary was removed"; fi

# --all exports the repeat (a few big tiles, density only, shard 5 of 40)
expect_ok all_shard "$LOOM" export "$F" --all --format vol --channels density --tile 512,512 \
	--shard 5/40 --quiet --json -o "$T/all"
expect_out_contains all_shard_tiles '"tiles": 2'
