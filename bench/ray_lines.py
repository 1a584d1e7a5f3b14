#!/usr/bin/env python3
"""usage: bench/ray_lines.py [--rays N] [--steps N] [--pairs]

bench/ray_lines.py - how many cache lines a trilinear footprint brings in
per unit step along random rays, for several voxel layouts (docs/performance.md,
"Lines per step").  A model, not a timing: for each sample of a ray (random
direction, unit steps, bench_vdb's rays) the set of 64-byte lines holding its
2 x 2 x 2 corners is formed, and the lines not among the previous two samples'
are counted as new.  With --pairs, lines are counted in 128-byte pairs (the
adjacent-line prefetch).  Deterministic (seed 1); about a minute.
"""
import math
import random
import sys


def loom_z_lines(x, y, z, line):
    """loom's bricks: 16 x 16 x 64 bytes, z fastest; a 64-byte line is the
    64 z of one column (a 128-byte pair: two columns along x)."""
    return (x // 16, y // 16, z // 64, (x % 16) * 64 // line, y % 16)


def vdb_leaf(x, y, z, line):
    """OpenVDB FloatGrid leaf: 8^3 floats, offset x*256 + y*32 + z*4."""
    return (x // 8, y // 8, z // 8, ((x % 8) * 256 + (y % 8) * 32 + (z % 8) * 4) // line)


def tiles(tx, ty, tz):
    """Bytes in tx x ty x tz tiles of 64 bytes (a pair: two tiles along z)."""
    def f(x, y, z, line):
        return (x // tx, y // ty, z // (tz * line // 64))
    return f


LAYOUTS = [
    ("loom 16x16x64, z lines", loom_z_lines),
    ("OpenVDB 8^3 float leaf", vdb_leaf),
    ("2x2x16 byte tiles", tiles(2, 2, 16)),
    ("4x4x4 byte tiles", tiles(4, 4, 4)),
]


def new_lines_per_step(layout, rays, steps, line, rng):
    new = samples = 0
    for _ in range(rays):
        th = math.acos(2 * rng.random() - 1)
        ph = 2 * math.pi * rng.random()
        d = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
        p = [rng.uniform(0, 1000), rng.uniform(0, 1000), rng.uniform(100, 200)]
        recent = []
        for _ in range(steps):
            i = [math.floor(p[a] - 0.5) for a in range(3)]
            cur = {layout(i[0] + dx, i[1] + dy, i[2] + dz, line)
                   for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)}
            seen = set().union(*recent) if recent else set()
            new += len(cur - seen)
            samples += 1
            recent = (recent + [cur])[-2:]
            p = [p[a] + d[a] for a in range(3)]
    return new / samples


def main(argv):
    rays, steps, line = 3000, 256, 64
    args = list(argv)
    while args:
        a = args.pop(0)
        if a in ("-h", "--help"):
            print(__doc__.strip())
            return 0
        if a == "--pairs":
            line = 128
        elif a in ("--rays", "--steps") and args and args[0].isdigit() and int(args[0]) > 0:
            if a == "--rays":
                rays = int(args.pop(0))
            else:
                steps = int(args.pop(0))
        else:
            sys.stderr.write("ray_lines.py: unexpected argument '%s'\n%s\n"
                             % (a, __doc__.splitlines()[0]))
            return 2
    print("%d rays of %d unit steps, %d-byte lines" % (rays, steps, line))
    for name, f in LAYOUTS:
        rate = new_lines_per_step(f, rays, steps, line, random.Random(1))
        print("%-26s %.2f new lines per step" % (name, rate))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
