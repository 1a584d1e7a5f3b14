#!/usr/bin/env python3
"""tests/data/meshes/gen_meshes.py - writes the curved test meshes beside it.

    python3 tests/data/meshes/gen_meshes.py

cylinder.obj  a 120-degree patch of a cylinder of radius 32 around the y
              axis, bulging towards +z: positions (32 sin t, y, 32 cos t),
              t in [-60, 60] degrees, y in [0, 48]; outward normals written
              as vn; UVs = arc length / 64 and y / 64 (so 64 voxels per UV
              unit is one voxel per world unit).  16 x 6 quads.
pillow.obj    a height field z = 6 sin(pi x / 48) sin(pi y / 48) over
              [0, 48]^2, UV = (x, y) / 64, no normals (the shell computes
              them).  12 x 12 quads.
The output is committed; the script only documents how it was made.
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def fmt(x):
    s = "%.6g" % x
    return "0" if s == "-0" else s


def write(name, header, verts, uvs, normals, faces):
    with open(os.path.join(HERE, name), "w") as f:
        f.write(header)
        for v in verts:
            f.write("v %s %s %s\n" % tuple(fmt(c) for c in v))
        for t in uvs:
            f.write("vt %s %s\n" % tuple(fmt(c) for c in t))
        for n in normals:
            f.write("vn %s %s %s\n" % tuple(fmt(c) for c in n))
        for face in faces:
            f.write("f " + " ".join(face) + "\n")


def cylinder():
    nt, ny, r, length = 16, 6, 32.0, 48.0
    verts, uvs, normals, faces = [], [], [], []
    for j in range(ny + 1):
        y = length * j / ny
        for i in range(nt + 1):
            t = math.radians(-60 + 120.0 * i / nt)
            verts.append((r * math.sin(t), y, r * math.cos(t)))
            uvs.append(((r * t + r * math.radians(60)) / 64.0, y / 64.0))
            normals.append((math.sin(t), 0.0, math.cos(t)))
    for j in range(ny):
        for i in range(nt):
            a = j * (nt + 1) + i + 1
            b, c, d = a + 1, a + nt + 2, a + nt + 1
            faces.append(["%d/%d/%d" % (k, k, k) for k in (a, b, c, d)])
    write("cylinder.obj",
          "# cylinder patch, radius 32, 120 degrees, made by gen_meshes.py\n",
          verts, uvs, normals, faces)


def pillow():
    n, side, amp = 12, 48.0, 6.0
    verts, uvs, faces = [], [], []
    for j in range(n + 1):
        for i in range(n + 1):
            x, y = side * i / n, side * j / n
            z = amp * math.sin(math.pi * x / side) * math.sin(math.pi * y / side)
            verts.append((x, y, z))
            uvs.append((x / 64.0, y / 64.0))
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i + 1
            b, c, d = a + 1, a + n + 2, a + n + 1
            faces.append(["%d/%d" % (k, k) for k in (a, b, c)])
            faces.append(["%d/%d" % (k, k) for k in (a, c, d)])
    write("pillow.obj", "# pillow height field made by gen_meshes.py\n",
          verts, uvs, [], faces)


if __name__ == "__main__":
    cylinder()
    pillow()
