# `loom export --format vdb|nvdb` read back by independent readers:
# OpenVDB's Python module (Debian's /usr/bin/python3 + python3-openvdb) for
# the float and vector grids, and build/tests/vdb_check (OpenVDB's and
# NanoVDB's own C++ headers) for every grid, the NanoVDB checksums and grid
# types.  Values at thousands of random voxels equal the NRRD export of the
# same tiles (a region read written verbatim, itself checked against
# `loom sample` in test_export.sh); empty voxels are inactive; adjacent
# tiles' transforms put them edge to edge; same bytes for any thread count,
# resumed and sharded runs; a failed write leaves no file behind.
SUITE=vdb
. "$LOOM_TOP/tests/cli/lib.sh"
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf
REG=-20,-10,0:44,40,48
ALL=density,orientation,albedo,kind,type
CHECK=$LOOM_BUILD/tests/vdb_check

expect_ok synth "$LOOM" synth "$WIF" --quiet -o "$F"
# a loom without the VDB plugin (as built without OpenVDB: the plugin path
# does not exist) says which package is missing, writes nothing
NOPLUG="env LOOM_VDB_LIBRARY=$T/none/libloom-vdb.so.0"
expect_exit vdb_missing 1 $NOPLUG "$LOOM" export "$F" --region "$REG" \
	--format vdb -o "$T/novdb"
expect_err_contains vdb_missing_msg "--format vdb: this loom was built without OpenVDB (install Debian's libopenvdb-dev and rebuild loom)"
expect_exit nvdb_missing 1 $NOPLUG "$LOOM" export "$F" --region "$REG" \
	--format nvdb -o "$T/novdb"
expect_err_contains nvdb_missing_msg "install Debian's libopenvdb-dev"
if [ -e "$T/novdb" ]; then fail vdb_missing_nothing_written "$(ls "$T/novdb")"; else pass vdb_missing_nothing_written; fi
# a plugin that is not one (another library) is named, nothing written
: >"$T/notaplugin.so"
expect_exit vdb_bad_plugin 1 env LOOM_VDB_LIBRARY="$T/notaplugin.so" "$LOOM" export "$F" \
	--region "$REG" --format vdb -o "$T/novdb"
expect_err_contains vdb_bad_plugin_msg "cannot load the VDB writer"
if [ -e "$T/novdb" ]; then fail vdb_bad_plugin_nothing_written "$(ls "$T/novdb")"; else pass vdb_bad_plugin_nothing_written; fi
# only a VDB export maps OpenVDB: the loom command does not link it (nor
# libstdc++, except that the sanitizer runtimes bring it in)
NOT_LINKED="-e openvdb -e libtbb"
[ -z "${LOOM_SAN:-}" ] && NOT_LINKED="$NOT_LINKED -e libstdc++"
# shellcheck disable=SC2086
if ldd "$LOOM" | grep -q $NOT_LINKED; then
	fail no_openvdb_linked "$(ldd "$LOOM" | grep $NOT_LINKED)"
else pass no_openvdb_linked; fi
case "${LOOM_SAN:-}" in *thread*)
	# Debian's OpenVDB and TBB are not built with ThreadSanitizer, so it
	# cannot see their synchronisation and reports races inside TBB's
	# scheduler; the VDB writes run under ASan/UBSan and in the plain suite
	echo "test_vdb: VDB writes not run under ThreadSanitizer (OpenVDB and TBB are not instrumented)" >&2
	exit 0 ;;
esac
if [ ! -x "$CHECK" ]; then
	echo "test_vdb: OpenVDB not installed (tools/deps.sh installs it): only the missing-package message checked" >&2
	exit 0
fi

expect_exit compression_with_nvdb 2 "$LOOM" export "$F" --region "$REG" --format nvdb \
	--compression zip -o "$T/x"
expect_err_contains compression_with_nvdb_msg "--compression goes with --format vdb"
expect_exit bad_compression 2 "$LOOM" export "$F" --region "$REG" --format vdb \
	--compression lz4 -o "$T/x"
expect_exit region_beyond_int32 2 "$LOOM" export "$F" --region 2147483000,0,0:2147484000,10,3 \
	--format vdb -o "$T/x"
expect_err_contains region_beyond_int32_msg "OpenVDB coordinates are 32-bit"

# 2 x 2 tiles of 32 x 25 voxels and the whole thickness
TILE=32,25
expect_ok nrrd_ref "$LOOM" export "$F" --region "$REG" --format nrrd --channels $ALL \
	--tile $TILE --quiet -o "$T/nrrd"
expect_ok vdb_export "$LOOM" export "$F" --region "$REG" --format vdb --channels $ALL \
	--tile $TILE --quiet --json -o "$T/vdb"
expect_out_contains vdb_json '"tiles_written": 4'
expect_ok vdb_zip "$LOOM" export "$F" --region "$REG" --format vdb --channels $ALL \
	--tile $TILE --compression zip --quiet -o "$T/vdbzip"
expect_ok vdb_threads "$LOOM" export "$F" --region "$REG" --format vdb --channels $ALL \
	--tile $TILE --threads 2 --budget 48 --quiet -o "$T/vdb2"
expect_ok nvdb_export "$LOOM" export "$F" --region "$REG" --format nvdb --channels $ALL \
	--tile $TILE --quiet -o "$T/nvdb"
expect_ok vdb_density_only "$LOOM" export "$F" --region "$REG" --format vdb \
	--channels density --tile $TILE --quiet -o "$T/vdbd"

n=$(ls "$T/vdb"/tile-*.vdb 2>/dev/null | wc -l)
if [ "$n" -eq 4 ]; then pass vdb_one_file_per_tile; else fail vdb_one_file_per_tile "$n files"; fi
if ls "$T"/vdb*/*.tmp.* "$T"/nvdb/*.tmp.* >/dev/null 2>&1; then fail no_temporaries "left: $(ls "$T"/*/*.tmp.*)"
else pass no_temporaries; fi

# same bytes for any thread count (the file's UUID is derived from its
# name, not random: docs/interop.md)
same=1
for f in "$T"/vdb/tile-*.vdb; do cmp -s "$f" "$T/vdb2/$(basename "$f")" || same=0; done
if [ $same = 1 ]; then pass vdb_deterministic; else fail vdb_deterministic "bytes differ across threads"; fi
expect_same vdb_manifest_deterministic "$T/vdb/manifest.json" "$T/vdb2/manifest.json"
if grep -q '"compression": "blosc"' "$T/vdb/manifest.json" && grep -q '"compression": "zip"' "$T/vdbzip/manifest.json"
then pass manifest_compression; else fail manifest_compression "$(head -c 400 "$T/vdb/manifest.json")"; fi

# grids, types, transforms, values (vdb_check: OpenVDB's C++ reader)
for f in "$T"/vdb/tile-*.vdb; do
	b=$(basename "$f" .vdb)
	"$CHECK" info "$f" >"$T/info.$b" 2>&1
	"$CHECK" nano "$T/nvdb/$b.nvdb" >"$T/nano.$b" 2>&1
	"$CHECK" info "$T/vdbzip/$b.vdb" >"$T/infozip.$b" 2>&1
done
if awk '{print $2, $4, $6}' "$T/info.tile-0-0-0" | sort | tr '\n' ';' |
	grep -q '^color vec3s unknown;density float fog_volume;kind int32 unknown;orientation vec3s unknown;type int32 unknown;$'
then pass vdb_grids_listed; else fail vdb_grids_listed "$(cat "$T/info.tile-0-0-0")"; fi
if [ "$("$CHECK" info "$T/vdbd/tile-1-1-0.vdb" | awk '{print $2}' | tr '\n' ' ')" = "density " ]
then pass vdb_channels_select_grids; else fail vdb_channels_select_grids "$("$CHECK" info "$T/vdbd/tile-1-1-0.vdb")"; fi
if cat "$T"/nano.* | awk '{print $2, $4, $8, $10}' | sort -u | tr '\n' ';' |
	grep -q '^color Vec3f ok ok;density float ok ok;kind int32 ok ok;orientation Vec3f ok ok;type int32 ok ok;$'
then pass nvdb_checksum_and_types; else fail nvdb_checksum_and_types "$(cat "$T"/nano.*)"; fi

# random voxels of each tile: one list, read by vdb_check from the .vdb
# (all five grids) and the .nvdb, and by pyopenvdb; compared with the NRRDs
if /usr/bin/python3 - "$T" "$CHECK" >"$T/py" 2>&1 <<'EOF'
import json, os, random, struct, subprocess, sys
import numpy as np
import pyopenvdb as vdb
d, check = sys.argv[1], sys.argv[2]
m = json.load(open(os.path.join(d, "vdb", "manifest.json")))
vmm = m["params"]["voxel_mm"]
assert m["complete"] and m["params"]["format"] == "vdb", m["params"]

def nrrd(path):
    b = open(path, "rb").read()
    hdr, data = b.split(b"\n\n", 1)
    h = {}
    for line in hdr.decode().splitlines()[1:]:
        if ": " in line:
            k, v = line.split(": ", 1)
            h[k] = v
    sizes = [int(s) for s in h["sizes"].split()]
    dt = np.float32 if h["type"] == "float" else np.uint8
    a = np.frombuffer(data, dtype=np.dtype(dt).newbyteorder("<"))
    comps = sizes[0] if len(sizes) == 4 else 1
    sp = sizes[-3:]
    a = a.reshape(sp[2], sp[1], sp[0], comps)   # [z][y][x][c]
    return a, h

rng = random.Random(17)
total = 0
tiles = {}
for t in m["tiles"]:
    lo, hi = t["lo"], t["hi"]
    stem = "tile-%d-%d-%d" % tuple(t["tile"])
    tiles[tuple(t["tile"])] = (lo, hi, stem)
    ref = {ch: nrrd(os.path.join(d, "nrrd", "%s.%s.nrrd" % (stem, ch)))[0]
           for ch in ("density", "orientation", "albedo", "kind", "type")}
    f = os.path.join(d, "vdb", stem + ".vdb")
    # (pyopenvdb has no Int32Grid: kind and type are read by vdb_check below)
    gd = vdb.read(f, "density")
    go = vdb.read(f, "orientation")
    gc = vdb.read(f, "color")
    assert gd.gridClass == vdb.GridClass.FOG_VOLUME and gd.background == 0.0
    # every non-empty voxel active, every empty one inactive (pruned, background 0)
    nz = int(np.count_nonzero(ref["density"]))
    assert gd.activeVoxelCount() == nz, (stem, gd.activeVoxelCount(), nz)
    assert nz > 1000, (stem, nz)
    ad, ao, ac = gd.getConstAccessor(), go.getConstAccessor(), gc.getConstAccessor()
    pts = []
    for k in range(1500):
        x = rng.randrange(lo[0], hi[0]); y = rng.randrange(lo[1], hi[1]); z = rng.randrange(lo[2], hi[2])
        pts.append((x, y, z))
    # force both empty and filled voxels in: the first filled ones found
    zz, yy, xx = np.nonzero(ref["density"][..., 0])
    for q in range(0, len(xx), max(1, len(xx) // 500)):
        pts.append((lo[0] + int(xx[q]), lo[1] + int(yy[q]), lo[2] + int(zz[q])))
    inp = "".join("%d %d %d\n" % p for p in pts)
    out = subprocess.run([check, "values", f], input=inp, capture_output=True, text=True, check=True).stdout.split("\n")
    nout = subprocess.run([check, "nanovalues", os.path.join(d, "nvdb", stem + ".nvdb")], input=inp,
                          capture_output=True, text=True, check=True).stdout.split("\n")
    # the grids in file order (OpenVDB and NanoVDB list them by name)
    order = [l.split()[1] for l in subprocess.run([check, "info", f], capture_output=True, text=True,
                                                  check=True).stdout.splitlines()]
    norder = [l.split()[1] for l in subprocess.run([check, "nano", os.path.join(d, "nvdb", stem + ".nvdb")],
                                                   capture_output=True, text=True, check=True).stdout.splitlines()]
    assert sorted(order) == sorted(norder) == ["color", "density", "kind", "orientation", "type"], (order, norder)
    def by_name(vals, names):
        r, q = {}, 0
        for n in names:
            c = 3 if n in ("orientation", "color") else 1
            r[n] = vals[q:q + c]
            q += c
        assert q == len(vals)
        return [v for n in ("density", "orientation", "color", "kind", "type") for v in r[n]]
    for p, line, nline in zip(pts, out, nout):
        i, j, k = p[0] - lo[0], p[1] - lo[1], p[2] - lo[2]
        want = [float(ref["density"][k, j, i, 0])] + [float(v) for v in ref["orientation"][k, j, i]] + \
               [float(v) for v in ref["albedo"][k, j, i]] + [int(ref["kind"][k, j, i, 0]), int(ref["type"][k, j, i, 0])]
        got = by_name([float(v) for v in line.split()[3:]], order)
        ngot = by_name([float(v) for v in nline.split()[3:]], norder)
        assert [float(np.float32(v)) for v in got] == [float(np.float32(v)) for v in want], (stem, p, got, want)
        assert [float(np.float32(v)) for v in ngot] == [float(np.float32(v)) for v in want], (stem, p, ngot, want)
        py = [ad.getValue(p)] + list(ao.getValue(p)) + list(ac.getValue(p))
        assert [float(np.float32(v)) for v in py] == [float(np.float32(v)) for v in want[:7]], (stem, p, py, want)
        assert ad.isValueOn(p) == (want[0] != 0), (stem, p)
        total += 1
    # the transform: voxel centre (i + 0.5) * voxel_mm, as the NRRD origin
    h = nrrd(os.path.join(d, "nrrd", stem + ".density.nrrd"))[1]
    org = [float(v) for v in h["space origin"].strip("()").split(",")]
    w = gd.transform.indexToWorld(tuple(lo))
    assert all(abs(w[a] - org[a]) < 1e-9 for a in range(3)), (w, org)
    assert abs(gd.transform.voxelSize()[0] - vmm) < 1e-12
    assert tuple(gd.metadata["loom_tile_lo"]) == tuple(lo) and tuple(gd.metadata["loom_tile_hi"]) == tuple(hi)
    tiles[tuple(t["tile"])] = (lo, hi, stem, gd.transform)
# adjacent tiles edge to edge: the far face of one is the near face of the next
edges = 0
for (tx, ty, tz), (lo, hi, stem, xf) in tiles.items():
    for a, nb in ((0, (tx + 1, ty, tz)), (1, (tx, ty + 1, tz))):
        if nb not in tiles:
            continue
        lo2, hi2, stem2, xf2 = tiles[nb]
        assert hi[a] == lo2[a]
        face = [lo[0] - 0.5, lo[1] - 0.5, lo[2] - 0.5]; face[a] = hi[a] - 0.5
        face2 = [lo2[0] - 0.5, lo2[1] - 0.5, lo2[2] - 0.5]
        w1, w2 = xf.indexToWorld(tuple(face)), xf2.indexToWorld(tuple(face2))
        assert abs(w1[a] - w2[a]) < 1e-9 and abs(w1[a] - hi[a] * vmm) < 1e-9, (stem, stem2, w1, w2)
        edges += 1
assert edges == 4, edges
print("ok", total, "voxels", edges, "edges")
EOF
then pass vdb_values_transforms; else fail vdb_values_transforms "$(tail -c 900 "$T/py")"; fi
grep -q '^ok' "$T/py" && awk '{exit !($2 >= 6000)}' "$T/py" && pass vdb_thousands_checked ||
	fail vdb_thousands_checked "$(tail -c 300 "$T/py")"
# zip-compressed files hold the same grids and active voxels
if [ "$(cut -d' ' -f1-8 "$T/info.tile-1-0-0")" = "$(cut -d' ' -f1-8 "$T/infozip.tile-1-0-0")" ] &&
	! cmp -s "$T/vdb/tile-1-0-0.vdb" "$T/vdbzip/tile-1-0-0.vdb"
then pass vdb_zip_same_grids; else fail vdb_zip_same_grids "$(cat "$T/infozip.tile-1-0-0")"; fi

# resume: a second run skips every verified tile; a damaged file is redone
# to the same bytes
cp "$T/vdb/tile-1-1-0.vdb" "$T/keep.vdb"
printf 'xx' | dd of="$T/vdb/tile-1-1-0.vdb" bs=1 seek=200 conv=notrunc 2>/dev/null
expect_ok vdb_resume "$LOOM" export "$F" --region "$REG" --format vdb --channels $ALL \
	--tile $TILE --json -o "$T/vdb"
expect_out_contains vdb_resume_skips '"tiles_skipped": 3'
expect_same vdb_resume_same_bytes "$T/keep.vdb" "$T/vdb/tile-1-1-0.vdb"
# shards, merged: the same files and manifest as one run
for i in 0 1; do
	"$LOOM" export "$F" --region "$REG" --format vdb --channels $ALL --tile $TILE \
		--shard $i/2 --quiet -o "$T/vsh" || fail "vdb_shard_$i" "exit $?"
done
expect_ok vdb_merge "$LOOM" export --merge "$T/vsh" --quiet
expect_same vdb_merge_manifest "$T/vdb2/manifest.json" "$T/vsh/manifest.json"
same=1
for f in "$T"/vdb2/tile-*.vdb; do cmp -s "$f" "$T/vsh/$(basename "$f")" || same=0; done
if [ $same = 1 ]; then pass vdb_shards_same_bytes; else fail vdb_shards_same_bytes "differ"; fi

# a write that fails (the final name is taken by a directory) leaves no
# file: neither a temporary nor anything under the final name
mkdir -p "$T/vfail/tile-0-0-0.vdb"
expect_exit vdb_write_fails 1 "$LOOM" export "$F" --region "$REG" --format vdb --tile $TILE \
	--quiet -o "$T/vfail"
expect_err_contains vdb_write_fails_msg "tile-0-0-0.vdb"
if ls "$T"/vfail/*.tmp.* >/dev/null 2>&1; then fail vdb_write_fails_clean "$(ls "$T/vfail")"
else pass vdb_write_fails_clean; fi
