#!/usr/bin/env python3
# bench/fidelity_hist.py - where two cloths' density histograms differ
# (docs/fidelity.md, "Cotton densities and paper-scale seams").  Reads the
# density and kind NRRD volumes `loom export --channels density,kind
# --format nrrd` writes (one tile each: give --tile as large as the region)
# and prints, per yarn kind, the 16-bin histograms as `loom compare` bins
# them (density byte d >= 1 in bin (d - 1) * 16 / 255), the L1 distance,
# and B - A in thousandths of each kind's voxels, split by band (columns
# within BAND voxels of a block edge, where the edge fix acts) against
# interior and by depth below the column's top voxel (0, 1, 2, 3+).
# Pure Python (no numpy): about 10 s per 5 M voxels.
#   usage: bench/fidelity_hist.py A_DIR B_DIR B1 B2 [BAND]
#   (A_DIR, B_DIR: export directories holding tile-0-0-0.density.nrrd and
#   tile-0-0-0.kind.nrrd; B1 x B2 the block size in voxels; BAND default 2)
import array
import sys


def nrrd(path, typ):
	b = open(path, 'rb').read()
	i = b.index(b'\n\n') + 2
	head = b[:i].decode()
	sizes = [int(v) for v in head.split('sizes:')[1].split('\n')[0].split()]
	if 'encoding: raw' not in head:
		sys.exit('%s: only raw NRRD is read' % path)
	a = array.array(typ)
	a.frombytes(b[i:])
	return a, sizes


def histograms(d, b1, b2, band):
	den, (nx, ny, nz) = nrrd(d + '/tile-0-0-0.density.nrrd', 'f')
	kind, _ = nrrd(d + '/tile-0-0-0.kind.nrrd', 'B')
	h = {}
	for y in range(ny):
		yb = y % b2 < band or y % b2 >= b2 - band
		for x in range(nx):
			inb = yb or x % b1 < band or x % b1 >= b1 - band
			depth = 0
			for z in range(nz - 1, -1, -1):
				i = (z * ny + y) * nx + x
				k = kind[i]
				v = int(den[i] * 255 + 0.5)
				if k == 0 or v == 0:
					continue
				key = (k, inb, min(depth, 3))
				h.setdefault(key, [0] * 16)[(v - 1) * 16 // 255] += 1
				depth += 1
	return h


def main():
	if len(sys.argv) < 5:
		sys.exit('usage: bench/fidelity_hist.py A_DIR B_DIR B1 B2 [BAND]')
	b1, b2 = int(sys.argv[3]), int(sys.argv[4])
	band = int(sys.argv[5]) if len(sys.argv) > 5 else 2
	A = histograms(sys.argv[1], b1, b2, band)
	B = histograms(sys.argv[2], b1, b2, band)
	for k, name in ((1, 'warp'), (2, 'weft')):
		na = sum(sum(v) for key, v in A.items() if key[0] == k) or 1
		nb = sum(sum(v) for key, v in B.items() if key[0] == k) or 1

		def agg(h, n, sel):
			out = [0.0] * 16
			for key, v in h.items():
				if key[0] == k and sel(key):
					out = [o + c / n for o, c in zip(out, v)]
			return out

		def row(sel):
			a, b = agg(A, na, sel), agg(B, nb, sel)
			return ' '.join('%+4.0f' % (1000 * (y - x)) for x, y in zip(a, b))

		ha, hb = agg(A, na, lambda key: True), agg(B, nb, lambda key: True)
		print('%s: voxels %d -> %d (%+.1f %%), L1 %.4f' %
		      (name, na, nb, 100.0 * (nb / na - 1), sum(abs(x - y) for x, y in zip(ha, hb))))
		print('  A bins        ' + ' '.join('%.3f' % x for x in ha))
		print('  B - A (1e-3)  ' + row(lambda key: True))
		for inb in (True, False):
			for dep in range(4):
				print('  %-8s d %-2s  %s' % ('band' if inb else 'interior',
				                             str(dep) if dep < 3 else '3+',
				                             row(lambda key: key[1] == inb and key[2] == dep)))


main()
