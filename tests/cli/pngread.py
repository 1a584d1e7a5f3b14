"""tests/cli/pngread.py - a small PNG reader for the CLI tests, written from
the PNG specification (zlib + the five row filters), independent of loom's
own image code.  8-bit grey, grey+alpha, RGB and RGBA, non-interlaced.

    import pngread
    w, h, ch, px = pngread.read(path)   # px[y][x*ch + c]
    grid = pngread.boxes(w, h, ch, px, gw, gh)  # mean luma per cell
"""
import struct
import zlib


def read(path):
    b = open(path, 'rb').read()
    assert b[:8] == b'\x89PNG\r\n\x1a\n', path + ': not a PNG'
    i, idat, w, h, depth, ct, inter = 8, b'', 0, 0, 0, 0, 0
    while i < len(b):
        n, typ = struct.unpack('>I4s', b[i:i + 8])
        data = b[i + 8:i + 8 + n]
        if typ == b'IHDR':
            w, h, depth, ct, _, _, inter = struct.unpack('>IIBBBBB', data)
        elif typ == b'IDAT':
            idat += data
        elif typ == b'IEND':
            break
        i += 12 + n
    assert depth == 8 and inter == 0, 'only 8-bit non-interlaced PNGs'
    ch = {0: 1, 2: 3, 4: 2, 6: 4}[ct]
    raw = zlib.decompress(idat)
    stride = w * ch
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - ch] if x >= ch else 0
            up = prev[x]
            c = prev[x - ch] if x >= ch else 0
            if f == 1:
                line[x] = (line[x] + a) & 255
            elif f == 2:
                line[x] = (line[x] + up) & 255
            elif f == 3:
                line[x] = (line[x] + (a + up) // 2) & 255
            elif f == 4:
                p = a + up - c
                pa, pb, pc = abs(p - a), abs(p - up), abs(p - c)
                pr = a if pa <= pb and pa <= pc else (up if pb <= pc else c)
                line[x] = (line[x] + pr) & 255
        rows.append(line)
        prev = line
    return w, h, ch, rows


def luma(px, ch, x):
    if ch < 3:
        return float(px[x * ch])
    r, g, b = px[x * ch], px[x * ch + 1], px[x * ch + 2]
    return 0.299 * r + 0.587 * g + 0.114 * b


def boxes(w, h, ch, rows, gw, gh):
    """Mean luma of each of gw x gh equal cells (pixel centres decide)."""
    s = [[0.0] * gw for _ in range(gh)]
    n = [[0] * gw for _ in range(gh)]
    for y in range(h):
        cy = min(gh - 1, (2 * y + 1) * gh // (2 * h))
        r = rows[y]
        for x in range(w):
            cx = min(gw - 1, (2 * x + 1) * gw // (2 * w))
            s[cy][cx] += luma(r, ch, x)
            n[cy][cx] += 1
    return [[s[y][x] / max(1, n[y][x]) for x in range(gw)] for y in range(gh)]


def correlation(a, b):
    xs = [v for row in a for v in row]
    ys = [v for row in b for v in row]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    sxx = sum((x - mx) ** 2 for x in xs)
    syy = sum((y - my) ** 2 for y in ys)
    return sxy / (sxx * syy) ** 0.5 if sxx > 0 and syy > 0 else 0.0
