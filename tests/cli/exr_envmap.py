#!/usr/bin/env python3
"""Write a small latitude-longitude environment map as an uncompressed
scanline OpenEXR file, by hand (an independent writer for the tests of
`loom render --envmap`; tests/cli/test_render.sh).

exr_envmap.py OUT.exr W H KIND [CHANNELS] [TYPE]
  KIND      header: the header and offset table only (for size checks);
            sky: a blue-grey sky, a dark ground and a bright sun blob at
            azimuth 200 degrees (from +x towards +y), 35 degrees up;
            const:V: every pixel V
  CHANNELS  comma-separated channel names (default A,B,G,R)
  TYPE      half or float (default half)
"""
import math
import struct
import sys


def half_bytes(v):
    return struct.pack('<e', v)


def main():
    out, w, h, kind = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    chans = sorted((sys.argv[5] if len(sys.argv) > 5 else 'A,B,G,R').split(','))
    typ = sys.argv[6] if len(sys.argv) > 6 else 'half'
    ptype, size = (1, 2) if typ == 'half' else (2, 4)
    pack = half_bytes if typ == 'half' else (lambda v: struct.pack('<f', v))

    def radiance(x, y):
        if kind.startswith('const:'):
            v = float(kind[6:])
            return (v, v, v)
        th = math.pi * (y + 0.5) / h
        ph = 2 * math.pi * (x + 0.5) / w
        d = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
        sa, se = math.radians(200), math.radians(35)
        s = (math.cos(se) * math.cos(sa), math.cos(se) * math.sin(sa), math.sin(se))
        c = sum(a * b for a, b in zip(d, s))
        if d[2] < 0:
            base = (0.08, 0.07, 0.06)
        else:
            base = (0.35 - 0.15 * d[2], 0.42 - 0.1 * d[2], 0.55)
        sun = 400.0 if c > math.cos(math.radians(3)) else 0.0
        return tuple(b + sun for b in base)

    def attr(name, typ_name, data):
        return name.encode() + b'\0' + typ_name.encode() + b'\0' + \
            struct.pack('<i', len(data)) + data

    chl = b''.join(c.encode() + b'\0' + struct.pack('<iB3xii', ptype, 0, 1, 1)
                   for c in chans) + b'\0'
    box = struct.pack('<iiii', 0, 0, w - 1, h - 1)
    head = b'\x76\x2f\x31\x01' + struct.pack('<i', 2)
    head += attr('channels', 'chlist', chl)
    head += attr('compression', 'compression', b'\0')
    head += attr('dataWindow', 'box2i', box)
    head += attr('displayWindow', 'box2i', box)
    head += attr('lineOrder', 'lineOrder', b'\0')
    head += attr('pixelAspectRatio', 'float', struct.pack('<f', 1.0))
    head += attr('screenWindowCenter', 'v2f', struct.pack('<ff', 0, 0))
    head += attr('screenWindowWidth', 'float', struct.pack('<f', 1.0))
    head += b'\0'
    chunks = []
    if kind == 'header':
        with open(out, 'wb') as f:
            f.write(head + struct.pack('<Q', 0) * h)
        return
    for y in range(h):
        px = [radiance(x, y) for x in range(w)]
        data = b''
        for c in chans:
            k = {'R': 0, 'G': 1, 'B': 2}.get(c)
            data += b''.join(pack(1.0 if k is None else p[k]) for p in px)
        chunks.append(struct.pack('<ii', y, len(data)) + data)
    pos = len(head) + 8 * h
    table = b''
    for ch in chunks:
        table += struct.pack('<Q', pos)
        pos += len(ch)
    with open(out, 'wb') as f:
        f.write(head + table + b''.join(chunks))


main()
