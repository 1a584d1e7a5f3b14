#!/usr/bin/env python3
"""Write the test meshes for cloth on meshes without texture coordinates.

make_meshes.py DIR writes into DIR:
  sphere.obj     icosphere, radius 1, no vt (subdivision 4: 5120 triangles)
  torus.obj      torus R = 1, r = 0.4 around z, no vt
  figure.obj     a closed, character-like blob (head, body, arms, legs)
                 displaced from an icosphere with scanner-like noise, no vt
  sphere_uv.obj  latitude-longitude sphere with vt (u around z, v pole to
                 pole): the UV-mapped version to compare against
  torus_uv.obj   torus.obj's grid with vt (u around z, v around the tube)
Deterministic: same bytes on every run.
"""
import math
import os
import sys


def icosphere(level):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [norm(p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
         (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
         (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]
    for _ in range(level):
        mid = {}

        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                p, q = v[a], v[b]
                v.append(norm(((p[0] + q[0]) / 2, (p[1] + q[1]) / 2,
                               (p[2] + q[2]) / 2)))
                mid[k] = len(v) - 1
            return mid[k]
        nf = []
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return v, f


def norm(p):
    n = math.sqrt(p[0] ** 2 + p[1] ** 2 + p[2] ** 2)
    return (p[0] / n, p[1] / n, p[2] / n)


def write(path, v, f, vt=None, ft=None, comment=""):
    with open(path + ".tmp", "w") as o:
        o.write("# %s\n" % comment)
        for p in v:
            o.write("v %.6f %.6f %.6f\n" % p)
        for t in vt or []:
            o.write("vt %.6f %.6f\n" % t)
        for i, tri in enumerate(f):
            if ft:
                o.write("f %s\n" % " ".join("%d/%d" % (a + 1, b + 1)
                                            for a, b in zip(tri, ft[i])))
            else:
                o.write("f %d %d %d\n" % (tri[0] + 1, tri[1] + 1, tri[2] + 1))
    os.replace(path + ".tmp", path)


def torus(nu, nv, R=1.0, r=0.4):
    v, vt, f, ft = [], [], [], []
    for i in range(nu):
        a = 2 * math.pi * i / nu
        for j in range(nv):
            b = 2 * math.pi * j / nv
            v.append(((R + r * math.cos(b)) * math.cos(a),
                      (R + r * math.cos(b)) * math.sin(a), r * math.sin(b)))
    for i in range(nu + 1):
        for j in range(nv + 1):
            vt.append((i / nu * 2 * math.pi * R, j / nv * 2 * math.pi * r))
    for i in range(nu):
        for j in range(nv):
            a, b = i * nv + j, ((i + 1) % nu) * nv + j
            c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
            ta, tb = i * (nv + 1) + j, (i + 1) * (nv + 1) + j
            tc, td = (i + 1) * (nv + 1) + j + 1, i * (nv + 1) + j + 1
            f += [(a, b, c), (a, c, d)]
            ft += [(ta, tb, tc), (ta, tc, td)]
    return v, f, vt, ft


def latlong(nu, nv):
    """Sphere with poles on z; vt: u = longitude, v = latitude (radians)."""
    v, vt, f, ft = [], [], [], []
    for j in range(nv + 1):
        th = math.pi * j / nv
        for i in range(nu + 1):
            ph = 2 * math.pi * i / nu
            # the seam column i = nu repeats i = 0 in space
            v.append((math.sin(th) * math.cos(ph % (2 * math.pi)),
                      math.sin(th) * math.sin(ph % (2 * math.pi)), -math.cos(th)))
            vt.append((ph, th))
    # weld duplicated seam and pole positions so the surface is closed
    index, uniq, remap = {}, [], []
    for p in v:
        k = tuple(round(x, 9) + 0.0 for x in p)
        if k not in index:
            index[k] = len(uniq)
            uniq.append(p)
        remap.append(index[k])
    for j in range(nv):
        for i in range(nu):
            a, b = j * (nu + 1) + i, j * (nu + 1) + i + 1
            c, d = (j + 1) * (nu + 1) + i + 1, (j + 1) * (nu + 1) + i
            for tri in ((a, b, c), (a, c, d)):
                g = tuple(remap[x] for x in tri)
                if len(set(g)) == 3:
                    f.append(g)
                    ft.append(tri)
    return uniq, f, vt, ft


def figure(level):
    """A star-shaped closed blob: head, body, arms and legs as bumps of the
    radius over an icosphere, plus small smooth 'scanner' noise."""
    v, f = icosphere(level)
    parts = [((0, 0, 1), 0.55, 10.0), ((0.9, 0, 0.25), 0.9, 16.0),
             ((-0.9, 0, 0.25), 0.9, 16.0), ((0.35, 0, -0.94), 1.0, 14.0),
             ((-0.35, 0, -0.94), 1.0, 14.0), ((0, 0.7, 0.1), 0.15, 6.0)]
    out = []
    for p in v:
        r = 0.8
        for c, amp, sharp in parts:
            c = norm(c)
            r += amp * math.exp(-sharp * (1 - (p[0] * c[0] + p[1] * c[1] +
                                                p[2] * c[2])))
        r += 0.015 * math.sin(13 * p[0] + 2) * math.sin(11 * p[1] + 1) * \
            math.sin(17 * p[2])
        out.append((p[0] * r * 0.8, p[1] * r * 0.55, p[2] * r * 1.1))
    return out, f


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: make_meshes.py DIR")
    d = sys.argv[1]
    os.makedirs(d, exist_ok=True)
    v, f = icosphere(4)
    write(os.path.join(d, "sphere.obj"), v, f, comment="icosphere, no vt")
    v, f, vt, ft = torus(96, 40)
    write(os.path.join(d, "torus.obj"), v, f, comment="torus, no vt")
    write(os.path.join(d, "torus_uv.obj"), v, f, vt, ft,
          comment="torus with arc-length vt")
    v, f = figure(5)
    write(os.path.join(d, "figure.obj"), v, f,
          comment="character-like closed blob, no vt")
    v, f, vt, ft = latlong(96, 48)
    write(os.path.join(d, "sphere_uv.obj"), v, f, vt, ft,
          comment="latitude-longitude sphere with vt")


if __name__ == "__main__":
    main()
