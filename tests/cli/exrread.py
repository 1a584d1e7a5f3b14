"""A small independent OpenEXR reader for the tests (no OpenEXR Python
module in Debian): single-part scanline files, NO/ZIPS/ZIP compression,
HALF/FLOAT/UINT channels.  read(path) -> (width, height, {name: [rows of
floats]}, attributes {name: (type, raw bytes)})."""
import struct
import zlib


def _header(b):
    assert b[:4] == b'\x76\x2f\x31\x01', 'not an OpenEXR file'
    flags = struct.unpack('<I', b[4:8])[0] >> 8
    assert not flags & 0x1e, 'tiled, deep or multi-part'
    p, attrs = 8, {}
    while b[p] != 0:
        e = b.index(b'\0', p)
        name = b[p:e].decode()
        e2 = b.index(b'\0', e + 1)
        typ = b[e + 1:e2].decode()
        n = struct.unpack('<i', b[e2 + 1:e2 + 5])[0]
        attrs[name] = (typ, b[e2 + 5:e2 + 5 + n])
        p = e2 + 5 + n
    return attrs, p + 1


def _channels(raw):
    out, p = [], 0
    while raw[p] != 0:
        e = raw.index(b'\0', p)
        ptype = struct.unpack('<i', raw[e + 1:e + 5])[0]
        out.append((raw[p:e].decode(), ptype))
        p = e + 17
    return out


def _unzip(data, n):
    t = bytearray(zlib.decompress(data))
    assert len(t) == n, (len(t), n)
    for i in range(1, n):
        t[i] = (t[i - 1] + t[i] - 128) & 0xff
    h = (n + 1) // 2
    out = bytearray(n)
    out[0::2] = t[:h]
    out[1::2] = t[h:]
    return bytes(out)


def read(path):
    b = open(path, 'rb').read()
    attrs, p = _header(b)
    chans = _channels(attrs['channels'][1])
    comp = attrs['compression'][1][0]
    assert comp in (0, 2, 3), 'compression %d' % comp
    x0, y0, x1, y1 = struct.unpack('<4i', attrs['dataWindow'][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lines = {0: 1, 2: 1, 3: 16}[comp]
    nchunks = (h + lines - 1) // lines
    offs = struct.unpack('<%dQ' % nchunks, b[p:p + 8 * nchunks])
    size = {1: 2, 2: 4, 0: 4}
    fmt = {1: 'e', 2: 'f', 0: 'I'}
    data = {c: [] for c, _ in chans}
    for off in offs:
        y, n = struct.unpack('<ii', b[off:off + 8])
        rows = min(lines, y1 + 1 - y)
        raw_n = rows * w * sum(size[t] for _, t in chans)
        blob = b[off + 8:off + 8 + n]
        blob = blob if n == raw_n else _unzip(blob, raw_n)
        q = 0
        for _ in range(rows):
            for c, t in chans:
                k = size[t] * w
                data[c].append(list(struct.unpack('<%d%s' % (w, fmt[t]), blob[q:q + k])))
                q += k
    return w, h, data, attrs
