# `loom export --lod L`: tiles downsampled by 2^L.  The coarse grids of
# NRRD exports at lod 1 and 2 equal a brute-force computation (numpy) from
# one full-resolution region read of the same box: density the mean,
# orientation the principal eigenvector of sum rho w w^T, albedo weighted
# by density, kind and type the density-weighted majority.  The VDB files
# of the same export (OpenVDB's Python module) hold the same density, with
# transforms that put adjacent tiles edge to edge in millimetres; every
# format writes; bad --lod values are usage errors naming the axis.
SUITE=lod
. "$LOOM_TOP/tests/cli/lib.sh"
WIF=$LOOM_TOP/data/herringbone-8.wif
F=$T/h8.loomf
# 2 x 3 tiles of 32 x 24 voxels (the last row 2 voxels: it rounds up to a
# whole coarse voxel); the reference covers the rounded-up box
REG=-20,-12,0:44,38,48
REF=-20,-12,0:44,40,48
ALL=density,orientation,albedo,kind,type

expect_ok synth "$LOOM" synth "$WIF" --quiet -o "$F"
expect_ok ref "$LOOM" export "$F" --region "$REF" --format nrrd --channels $ALL \
	--tile 64,52 --quiet -o "$T/ref"

# bad input: a tile smaller than a coarse voxel vanishes; corners and tile
# sides off the coarse grid would not line up
expect_exit lod_vanish 2 "$LOOM" export "$F" --region "$REG" --format nrrd --tile 2,24 \
	--lod 2 -o "$T/x"
expect_err_contains lod_vanish_msg "--lod 2 makes the tiles vanish: they are 2 voxels along x"
expect_exit lod_vanish_z 2 "$LOOM" export "$F" --region -20,-12,0:44,38,3 --format vdb \
	--lod 2 -o "$T/x"
expect_err_contains lod_vanish_z_msg "3 voxels along z, less than one coarse voxel of 4"
expect_exit lod_corner 2 "$LOOM" export "$F" --region -21,-12,0:44,38,48 --format nrrd \
	--tile 32,24 --lod 1 -o "$T/x"
expect_err_contains lod_corner_msg "--lod 1 needs the region's corner at a multiple of 2 voxels along x"
expect_exit lod_tile_side 2 "$LOOM" export "$F" --region "$REG" --format nrrd \
	--tile 32,25 --lod 1 -o "$T/x"
expect_err_contains lod_tile_side_msg "needs a tile side that is a multiple of 2 voxels along y"
expect_exit lod_too_big 2 "$LOOM" export "$F" --region "$REG" --format nrrd --lod 11 -o "$T/x"
expect_exit lod_with_merge 2 "$LOOM" export --merge "$T/ref" --lod 1
if [ -e "$T/x" ]; then fail lod_errors_write_nothing "$(ls "$T/x")"; else pass lod_errors_write_nothing; fi

for L in 1 2; do
	expect_ok nrrd_lod$L "$LOOM" export "$F" --region "$REG" --format nrrd --channels $ALL \
		--tile 32,24 --lod $L --quiet -o "$T/n$L"
	expect_ok vol_lod$L "$LOOM" export "$F" --region "$REG" --format vol --tile 32,24 \
		--lod $L --quiet -o "$T/v$L"
	expect_ok exr_lod$L "$LOOM" export "$F" --region "$REG" --format exr --tile 32,24 \
		--lod $L --quiet -o "$T/e$L"
	n=$(ls "$T/e$L"/tile-0-0-0.z*.exr | wc -l)
	if [ "$n" -eq $((48 >> L)) ]; then pass exr_lod${L}_slices; else fail exr_lod${L}_slices "$n"; fi
	if grep -q "\"lod\": $L" "$T/n$L/manifest.json"; then pass manifest_lod$L
	else fail manifest_lod$L "$(head -c 400 "$T/n$L/manifest.json")"; fi
done
# a re-run of the same export resumes: every tile verified and skipped
expect_ok lod_resume "$LOOM" export "$F" --region "$REG" --format nrrd --channels $ALL \
	--tile 32,24 --lod 1 --json -o "$T/n1"
expect_out_contains lod_resume_skips '"tiles_skipped": 6'
# another --lod into the same directory is another export: refused
expect_exit lod_resume_other 1 "$LOOM" export "$F" --region "$REG" --format nrrd \
	--channels $ALL --tile 32,24 --lod 2 --quiet -o "$T/n1"

if /usr/bin/python3 - "$T" >"$T/py" 2>&1 <<'EOF'
import json, os, sys
import numpy as np
d = sys.argv[1]

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
    return a.reshape(sp[2], sp[1], sp[0], comps).astype(np.float64), h   # [z][y][x][c]

CH = ("density", "orientation", "albedo", "kind", "type")
ref = {c: nrrd(os.path.join(d, "ref", "tile-0-0-0.%s.nrrd" % c))[0] for c in CH}
m0 = json.load(open(os.path.join(d, "ref", "manifest.json")))
vmm = m0["params"]["voxel_mm"]
rlo = m0["tiles"][0]["lo"]

def blocks(a, s):
    """[z][y][x][c] -> [cz][cy][cx][s^3][c]"""
    nz, ny, nx, c = a.shape
    b = a.reshape(nz // s, s, ny // s, s, nx // s, s, c)
    return b.transpose(0, 2, 4, 1, 3, 5, 6).reshape(nz // s, ny // s, nx // s, s ** 3, c)

def majority(w, vals, cand):
    """value in cand with the largest summed w (first = smallest on ties)"""
    sums = np.stack([np.where(vals == v, w, 0.0).sum(-1) for v in cand], -1)
    return np.asarray(cand)[np.argmax(sums, -1)]

checked = 0
for L in (1, 2):
    s = 1 << L
    rho = blocks(ref["density"], s)[..., 0]
    W = blocks(ref["orientation"], s)
    A = blocks(ref["albedo"], s)
    K = blocks(ref["kind"], s)[..., 0]
    Y = blocks(ref["type"], s)[..., 0]
    dens = rho.mean(-1)
    T = np.einsum("...n,...ni,...nj->...ij", rho, W, W)
    ev, evec = np.linalg.eigh(T)
    yarn = np.where(K > 0, rho, 0.0)
    wy = yarn.sum(-1)
    alb = np.einsum("...n,...nc->...c", yarn, A) / np.maximum(wy, 1e-300)[..., None]
    kind = np.where(wy > 0, majority(yarn, K, [1, 2]), 0)
    types = sorted(set(np.unique(Y[K > 0]).astype(int)))
    typ = np.where(wy > 0, majority(yarn, Y, types), 0)
    m = json.load(open(os.path.join(d, "n%d" % L, "manifest.json")))
    assert m["complete"] and m["params"]["lod"] == L
    for t in m["tiles"]:
        stem = "tile-%d-%d-%d" % tuple(t["tile"])
        got = {c: nrrd(os.path.join(d, "n%d" % L, "%s.%s.nrrd" % (stem, c))) for c in CH}
        h = got["density"][1]
        org = [float(v) for v in h["space origin"].strip("()").split(",")]
        sp = float(h["space directions"].split(")")[0].strip("( ").split(",")[0])
        assert abs(sp - vmm * s) < 1e-12, (sp, vmm, s)
        clo = [round(org[a] / (vmm * s) - 0.5) for a in range(3)]
        # the coarse box starts where the fine tile starts, in mm
        assert all(abs((clo[a] + 0.5) * s * vmm - org[a]) < 1e-9 and clo[a] * s == t["lo"][a]
                   for a in range(3)), (clo, org, t["lo"])
        g = got["density"][0]
        nz, ny, nx = g.shape[:3]
        ox, oy, oz = [(t["lo"][a] - rlo[a]) // s for a in range(3)]
        sl = (slice(oz, oz + nz), slice(oy, oy + ny), slice(ox, ox + nx))
        assert (nx, ny, nz) == tuple(-(-(t["hi"][a] - t["lo"][a]) // s) for a in range(3)), (stem, nx, ny, nz)
        assert np.allclose(g[..., 0], dens[sl], atol=1e-6, rtol=0), (stem, "density")
        assert np.allclose(got["albedo"][0], alb[sl], atol=1e-5, rtol=0), (stem, "albedo")
        assert np.array_equal(got["kind"][0][..., 0], kind[sl]), (stem, "kind")
        assert np.array_equal(got["type"][0][..., 0], typ[sl]), (stem, "type")
        # orientation: unit, z >= 0, and the principal axis: its Rayleigh
        # quotient is the largest eigenvalue (robust where two are close)
        o = got["orientation"][0]
        full = dens[sl] > 0
        n = np.linalg.norm(o, axis=-1)
        assert np.allclose(n[full], 1, atol=1e-5) and np.all(n[~full] == 0), (stem, "unit")
        assert np.all(o[..., 2][full] >= 0), (stem, "z >= 0")
        Ts, es, vs = T[sl][full], ev[sl][full], evec[sl][full][..., :, 2]
        ray = np.einsum("ni,nij,nj->n", o[full], Ts, o[full])
        assert np.all(ray >= es[:, 2] - 1e-5 * np.maximum(es[:, 2], 1e-12)), (stem, "not principal")
        sep = es[:, 2] - es[:, 1] > 1e-3 * es[:, 2]
        dots = np.abs(np.einsum("ni,ni->n", o[full], vs))
        assert np.all(dots[sep] > 1 - 1e-5), (stem, dots[sep].min())
        assert full.sum() > 20, (stem, full.sum())
        checked += int(full.sum())
print("ok", checked)
EOF
then pass lod_brute_force; else fail lod_brute_force "$(tail -c 900 "$T/py")"; fi

# VDB and NanoVDB at lod 1 and 2: grids read back, the same densities as
# the NRRD export, transforms edge to edge, same bytes for any thread count
if [ ! -x "$LOOM_BUILD/tests/vdb_check" ] || ! /usr/bin/python3 -c 'import pyopenvdb' 2>/dev/null; then
	echo "test_lod: OpenVDB or python3-openvdb not installed (tools/deps.sh test): VDB checks skipped" >&2
	exit 0
fi
case "${LOOM_SAN:-}" in *thread*)
	echo "test_lod: VDB writes not run under ThreadSanitizer (OpenVDB and TBB are not instrumented)" >&2
	exit 0 ;;
esac
for L in 1 2; do
	expect_ok vdb_lod$L "$LOOM" export "$F" --region "$REG" --format vdb --channels $ALL \
		--tile 32,24 --lod $L --quiet -o "$T/d$L"
	expect_ok vdb_lod${L}_threads "$LOOM" export "$F" --region "$REG" --format vdb \
		--channels $ALL --tile 32,24 --lod $L --threads 2 --quiet -o "$T/dt$L"
	same=1
	for f in "$T/d$L"/tile-*.vdb; do cmp -s "$f" "$T/dt$L/$(basename "$f")" || same=0; done
	if [ $same = 1 ]; then pass vdb_lod${L}_deterministic; else fail vdb_lod${L}_deterministic "differ"; fi
	expect_ok nvdb_lod$L "$LOOM" export "$F" --region "$REG" --format nvdb --tile 32,24 \
		--lod $L --quiet -o "$T/nv$L"
	if "$LOOM_BUILD/tests/vdb_check" nano "$T/nv$L/tile-1-2-0.nvdb" | awk '{print $2, $4, $8, $10}' |
		sort | tr '\n' ';' | grep -q '^density float ok ok;orientation Vec3f ok ok;$'
	then pass nvdb_lod${L}_valid; else fail nvdb_lod${L}_valid "$("$LOOM_BUILD/tests/vdb_check" nano "$T/nv$L/tile-1-2-0.nvdb" 2>&1)"; fi
done
if /usr/bin/python3 - "$T" >"$T/pyv" 2>&1 <<'EOF'
import json, os, sys
import numpy as np
import pyopenvdb as vdb
d = sys.argv[1]
edges = 0
for L in (1, 2):
    s = 1 << L
    m = json.load(open(os.path.join(d, "d%d" % L, "manifest.json")))
    vmm = m["params"]["voxel_mm"]
    tiles = {}
    for t in m["tiles"]:
        stem = "tile-%d-%d-%d" % tuple(t["tile"])
        g = vdb.read(os.path.join(d, "d%d" % L, stem + ".vdb"), "density")
        clo = [t["lo"][a] // s for a in range(3)]
        chi = [-(-t["hi"][a] // s) for a in range(3)]
        assert tuple(g.metadata["loom_tile_lo"]) == tuple(clo), (g.metadata["loom_tile_lo"], clo)
        assert tuple(g.metadata["loom_tile_hi"]) == tuple(chi)
        assert abs(g.transform.voxelSize()[0] - vmm * s) < 1e-12
        # the coarse tile's near corner is the fine tile's, in mm
        w = g.transform.indexToWorld(tuple(c - 0.5 for c in clo))
        assert all(abs(w[a] - t["lo"][a] * vmm) < 1e-9 for a in range(3)), (w, t["lo"])
        # its active voxels lie inside it, and hold the NRRD export's densities
        bb = g.evalActiveVoxelBoundingBox()
        assert all(clo[a] <= bb[0][a] and bb[1][a] < chi[a] for a in range(3)), (bb, clo, chi)
        b = open(os.path.join(d, "n%d" % L, stem + ".density.nrrd"), "rb").read().split(b"\n\n", 1)[1]
        ref = np.frombuffer(b, dtype="<f4").reshape(chi[2] - clo[2], chi[1] - clo[1], chi[0] - clo[0])
        a = np.zeros((chi[0] - clo[0], chi[1] - clo[1], chi[2] - clo[2]), np.float32)
        g.copyToArray(a, ijk=tuple(clo))
        assert np.array_equal(a.transpose(2, 1, 0), ref), stem
        assert g.activeVoxelCount() == np.count_nonzero(ref) > 20
        tiles[tuple(t["tile"])] = (clo, chi, g.transform)
    for (tx, ty, tz), (clo, chi, xf) in tiles.items():
        for a, nb in ((0, (tx + 1, ty, tz)), (1, (tx, ty + 1, tz))):
            if nb not in tiles:
                continue
            clo2, chi2, xf2 = tiles[nb]
            face = [c - 0.5 for c in clo]; face[a] = chi[a] - 0.5
            w1 = xf.indexToWorld(tuple(face))
            w2 = xf2.indexToWorld(tuple(c - 0.5 for c in clo2))
            assert abs(w1[a] - w2[a]) < 1e-9, (L, tx, ty, w1, w2)
            edges += 1
assert edges == 2 * 7, edges
print("ok", edges)
EOF
then pass vdb_lod_transforms_values; else fail vdb_lod_transforms_values "$(tail -c 900 "$T/pyv")"; fi
