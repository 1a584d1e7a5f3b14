# tests/extra/blender_compare.py - run by tests/extra/blender.sh inside
# Blender's Python (it reads the PNGs; Debian's python3 has no image
# module here):
#   blender -b --factory-startup --python-exit-code 1 -P blender_compare.py -- \
#       CYCLES.png PREVIEW.png X0 Y0 [X0 Y0 ...]
# CYCLES.png: a top view with one voxel per pixel and a black world;
# PREVIEW.png: `loom preview` of the tile (one voxel per pixel, row 0 at
# the tile's lowest y), whose lowest-y, lowest-x voxel is Cycles' pixel
# column X0, row Y0 counted from the bottom.  Prints, per placement X0 Y0,
# the IoU of the cloth masks and the correlation of the luminance inside
# the tile.
import sys

import bpy

a = sys.argv[sys.argv.index("--") + 1:]
cy, pv = a[0], a[1]


def load(path):
    im = bpy.data.images.load(path)
    w, h = im.size
    px = list(im.pixels)   # RGBA floats, rows from the bottom
    lum = [[0.2126 * px[4 * (r * w + c)] + 0.7152 * px[4 * (r * w + c) + 1] +
            0.0722 * px[4 * (r * w + c) + 2] for c in range(w)] for r in range(h)]
    return w, h, lum


cw, ch, cl = load(cy)
pw, ph, pl = load(pv)
def compare(x0, y0):
    # Blender's rows count from the bottom; the preview's rows from its top
    # are y = 0, 1, ...: its bottom row in Blender's order is the tile's
    # highest y, so preview row from the bottom rb is y = ph - 1 - rb
    inter = union = 0
    xs, ys = [], []
    for r in range(ch):
        for c in range(cw):
            y, x = r - y0, c - x0
            inside = 0 <= x < pw and 0 <= y < ph
            p = pl[ph - 1 - y][x] if inside else 0.0
            m_cy = cl[r][c] > 0.03
            m_pv = inside and p > 0.03
            inter += m_cy and m_pv
            union += m_cy or m_pv
            if inside:
                xs.append(cl[r][c])
                ys.append(p)
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxy = sum((u - mx) * (v - my) for u, v in zip(xs, ys))
    sxx = sum((u - mx) ** 2 for u in xs)
    syy = sum((v - my) ** 2 for v in ys)
    corr = sxy / (sxx * syy) ** 0.5 if sxx > 0 and syy > 0 else 0.0
    cover = sum(1 for r in range(ch) for c in range(cw) if cl[r][c] > 0.03) / (cw * ch)
    print("iou %.4f corr %.4f cover %.4f at %d %d" % (inter / union if union else 0.0, corr, cover, x0, y0))


for q in range(2, len(a), 2):
    compare(int(a[q]), int(a[q + 1]))
