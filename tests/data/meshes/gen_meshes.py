#!/usr/bin/env python3
"""tests/data/meshes/gen_meshes.py - writes the curved test meshes beside it.

    python3 tests/data/meshes/gen_meshes.py

cylinder.obj  a 120-degree patch of a cylinder of radius 32 around the y
              axis, bulging towards +z: positions (32 sin t, y, 32 cos t),
              t in [-60, 60] degrees, y in [0, 48]; outward normals written
              as vn; UVs = arc length / 64 and y / 64 (so 64 voxels per UV
              unit is one voxel per world unit).  16 x 6 quads.
bump.obj      a height field z = 6 sin(pi x / 48) sin(pi y / 48) over
              [0, 48]^2, UV = (x, y) / 64, no normals (the shell computes
              them).  12 x 12 quads.

The scene meshes (docs/rendering.md, "Scene meshes"; z is up, one UV unit
is 100 mesh units on every one of them, UVs in [0, 1], no normals):
pillow.obj    a closed pillow of two panels sewn along a seam: a puffed
              square 40 x 40 (sides pinched in 7 %), each panel
              z = +-6 (1 - s^4)(1 - t^4), its own UV chart laid out by arc
              length (front u in [0, 0.5], back u in [0.5, 1], the back
              mirrored so both read the right way from outside); seam
              vertices shared, so the mesh is watertight.  2 x 32 x 32 quads.
drape.obj     a square cloth 40 x 40 dropped centred on a sphere of radius
              14: on the sphere up to 50 degrees from the top (arc length
              kept along meridians), then bending to vertical and hanging,
              with 6 folds whose amplitude takes up the extra width so the
              hem keeps its length (amplitude capped so no fold is sharper
              than radius 1.5).  UV = flat cloth position.  44 x 44 quads.
sleeve.obj    a cylinder closed round (a sleeve, open at its ends) of radius 8 and length 44 along
              x, the seam underneath: u = arc length around, v = along the
              axis (the warp runs down the arm).  48 x 22 quads.
The output is committed; the script only documents how it was made (it is
deterministic: running it again rewrites the same bytes).
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


def bump():
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
    write("bump.obj", "# sine bump height field made by gen_meshes.py\n",
          verts, uvs, [], faces)


UV_PER_UNIT = 1.0 / 100.0   # one UV unit = 100 mesh units


def smooth(x):
    x = min(max(x, 0.0), 1.0)
    return x * x * (3 - 2 * x)


class Builder:
    """Positions deduplicated by their written text (so seams share
    vertices exactly), UVs per chart, faces as v/vt quads."""

    def __init__(self):
        self.verts, self.index, self.uvs, self.faces = [], {}, [], []

    def vert(self, p):
        key = tuple(fmt(c) for c in p)
        if key not in self.index:
            self.verts.append(p)
            self.index[key] = len(self.verts)
        return self.index[key]

    def uv(self, t):
        self.uvs.append(t)
        return len(self.uvs)

    def grid(self, ni, nj, pos, tex):
        """A grid of (ni+1) x (nj+1) points; quads wound so that
        d pos/di x d pos/dj is the outward side."""
        vi = [[self.vert(pos(i, j)) for i in range(ni + 1)] for j in range(nj + 1)]
        ti = [[self.uv(tex(i, j)) for i in range(ni + 1)] for j in range(nj + 1)]
        for j in range(nj):
            for i in range(ni):
                c = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
                self.faces.append(["%d/%d" % (vi[b][a], ti[b][a]) for a, b in c])

    def write(self, name, header):
        write(name, header, self.verts, self.uvs, [], self.faces)


def arc_table(f, a, b, n):
    """Cumulative arc length of the curve f over [a, b], sampled at n+1
    points (trapezoids on 64 sub-steps each)."""
    out, acc, prev = [0.0], 0.0, f(a)
    for k in range(1, n + 1):
        for m in range(1, 65):
            x = a + (b - a) * ((k - 1) + m / 64.0) / n
            p = f(x)
            acc += math.dist(p, prev)
            prev = p
        out.append(acc)
    return out


def pillow():
    n, half, puff, pinch = 32, 20.0, 6.0, 0.07
    b = Builder()

    def surf(s, t, side):
        x = s * half * (1 - pinch * (1 - t * t))
        y = t * half * (1 - pinch * (1 - s * s))
        z = side * puff * (1 - s ** 4) * (1 - t ** 4)
        return (x, y, z)

    def param(i):
        return -1.0 + 2.0 * i / n

    for side, uc in ((1, 0.25), (-1, 0.75)):
        # the back panel runs s from +1 to -1 so it faces -z (outwards)
        def sp(i, side=side):
            return side * param(i)
        # arc length from the panel's centre lines, per row and column
        rows = [arc_table(lambda s, t=param(j), side=side: surf(side * s, t, side),
                          -1.0, 1.0, n) for j in range(n + 1)]
        cols = [arc_table(lambda t, s=sp(i), side=side: surf(s, t, side),
                          -1.0, 1.0, n) for i in range(n + 1)]
        b.grid(n, n,
               lambda i, j, side=side: surf(sp(i, side), param(j), side),
               lambda i, j, rows=rows, cols=cols, uc=uc:
               (uc + (rows[j][i] - rows[j][n // 2]) * UV_PER_UNIT,
                0.5 + (cols[i][j] - cols[i][n // 2]) * UV_PER_UNIT))
    b.write("pillow.obj", "# closed two-panel pillow with a seam, made by "
            "gen_meshes.py\n")


def drape():
    n, half, radius, phi_max = 44, 20.0, 14.0, math.radians(50)
    bend, ease, folds, min_bend_r = 5.0, 6.0, 6, 1.5
    rho0, z0 = radius * math.sin(phi_max), radius * math.cos(phi_max)
    # the meridian beyond the sphere: direction psi below the horizontal
    # turns from the sphere's tangent (phi_max) to vertical over `bend`
    step, table = 0.01, [(0.0, rho0, z0)]
    s_end = half * math.sqrt(2) - radius * phi_max + 1.0
    while table[-1][0] < s_end:
        s, rho, z = table[-1]
        psi = phi_max + (math.pi / 2 - phi_max) * smooth((s + step / 2) / bend)
        table.append((s + step, rho + step * math.cos(psi), z - step * math.sin(psi)))

    def meridian(s):
        k = min(int(s / step), len(table) - 2)
        f = (s - table[k][0]) / step
        return (table[k][1] + f * (table[k + 1][1] - table[k][1]),
                table[k][2] + f * (table[k + 1][2] - table[k][2]))

    def pos(x, y):
        r, th = math.hypot(x, y), math.atan2(y, x)
        if r <= radius * phi_max:
            phi = r / radius
            return (radius * math.sin(phi) * math.cos(th),
                    radius * math.sin(phi) * math.sin(th), radius * math.cos(phi))
        s = r - radius * phi_max
        rho, z = meridian(s)
        # folds: rho + A sin(n th) has about the flat circle's length 2 pi r
        amp = math.sqrt(max(0.0, 2 * (r * r - rho * rho))) / folds
        amp = min(amp, rho * rho / (folds * folds * min_bend_r)) * smooth(s / ease)
        rho += amp * math.sin(folds * th)
        return (rho * math.cos(th), rho * math.sin(th), z)

    b = Builder()
    coord = lambda i: -half + 2 * half * i / n
    b.grid(n, n, lambda i, j: pos(coord(i), coord(j)),
           lambda i, j: (0.5 + coord(i) * UV_PER_UNIT, 0.5 + coord(j) * UV_PER_UNIT))
    b.write("drape.obj", "# square cloth draped over a sphere, made by "
            "gen_meshes.py\n")


def sleeve():
    na, nl, radius, length = 48, 22, 8.0, 44.0
    b = Builder()

    def pos(i, j):
        th = 2 * math.pi * (i % na) / na   # 0 at the bottom: the seam
        return (-length / 2 + length * j / nl, radius * math.sin(th),
                -radius * math.cos(th))

    b.grid(na, nl, pos, lambda i, j: (2 * math.pi * radius * i / na * UV_PER_UNIT,
                                      length * j / nl * UV_PER_UNIT))
    b.write("sleeve.obj", "# cylinder sleeve, seam underneath, made by "
            "gen_meshes.py\n")


if __name__ == "__main__":
    cylinder()
    bump()
    pillow()
    drape()
    sleeve()
