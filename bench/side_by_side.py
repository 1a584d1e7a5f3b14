# bench/side_by_side.py - two PNGs of one size side by side (a 4-pixel
# white gap), in Blender's Python (bench/cycles.sh; Debian's python3 has no
# image module here):
#   blender -b --factory-startup -P bench/side_by_side.py -- LEFT.png RIGHT.png OUT.png
import sys

import bpy

left, right, out = sys.argv[sys.argv.index("--") + 1:][:3]
a, b = bpy.data.images.load(left), bpy.data.images.load(right)
w, h = a.size
if tuple(b.size) != (w, h):
    sys.exit("side_by_side.py: %s is %dx%d, %s is %dx%d" % (left, w, h, right, *b.size))
gap = 4
pa, pb = list(a.pixels), list(b.pixels)
px = [1.0] * (4 * (2 * w + gap) * h)
for r in range(h):
    o = 4 * r * (2 * w + gap)
    px[o:o + 4 * w] = pa[4 * r * w:4 * (r + 1) * w]
    px[o + 4 * (w + gap):o + 4 * (2 * w + gap)] = pb[4 * r * w:4 * (r + 1) * w]
im = bpy.data.images.new("side", 2 * w + gap, h)
# the inputs' stored values, written back unchanged
im.colorspace_settings.name = a.colorspace_settings.name
im.pixels = px
im.filepath_raw = out
im.file_format = "PNG"
im.save()
