#!/usr/bin/env python3
# bench/fidelity_place.py - where along the design's floats two cloths'
# per-block mean heights differ (docs/fidelity.md, "Float runs").  Reads
# the density NRRD volumes `loom export --channels density --format nrrd`
# writes (one tile each: give --tile as large as the region, which must
# start at voxel 0, 0 of the design), takes each column's top (the highest
# voxel of density >= THRESHOLD, as `loom compare` does), and for every
# block the mean top-height difference B - A over the columns with a top
# in both.  Blocks are grouped by the design crossing's place along its
# float: "row" and the left run for a float of 6 or more crossings along
# the row, "col" and the up run along the column, "short" otherwise (the
# float-run rule's threshold, engine/synth/assign_impl.h).  Prints each
# B's block-offset SD (as `loom compare` reports it), the same with each
# place's mean removed (what a height model along the float could reach
# at best), and per place the count, the mean offset (after the global
# mean) and the SD.  Pure Python (no numpy): about 30 s per 20 M voxels.
#   usage: bench/fidelity_place.py DESIGN.pbm B1 B2 A_DIR B_DIR... [--threshold D]
#   (DESIGN.pbm: the design as `loom pattern make` writes it, P1 or P4;
#   B1 x B2 the block size in voxels; A_DIR, B_DIR: export directories
#   holding tile-0-0-0.density.nrrd)
import array
import sys


def nrrd(path):
	b = open(path, 'rb').read()
	i = b.index(b'\n\n') + 2
	head = b[:i].decode()
	if 'encoding: raw' not in head or 'type: float' not in head:
		sys.exit('%s: only raw float NRRD is read' % path)
	sizes = [int(v) for v in head.split('sizes:')[1].split('\n')[0].split()]
	a = array.array('f')
	a.frombytes(b[i:])
	return a, sizes


def tops(d, thr):
	den, (nx, ny, nz) = nrrd(d + '/tile-0-0-0.density.nrrd')
	plane = nx * ny
	h = [None] * plane
	for c in range(plane):
		for z in range(nz - 1, -1, -1):
			if den[z * plane + c] >= thr:
				h[c] = z
				break
	return h, nx, ny


def pbm(path):
	b = open(path, 'rb').read()
	toks, i = [], 0
	while len(toks) < 3:
		while b[i:i + 1].isspace():
			i += 1
		if b[i:i + 1] == b'#':
			i = b.index(b'\n', i)
			continue
		j = i
		while not b[j:j + 1].isspace():
			j += 1
		toks.append(b[i:j])
		i = j
	magic, w, h = toks[0], int(toks[1]), int(toks[2])
	if magic == b'P4':
		data, rowb = b[i + 1:], (w + 7) // 8
		return [[(data[r * rowb + c // 8] >> (7 - c % 8)) & 1 for c in range(w)]
		        for r in range(h)], h, w
	if magic == b'P1':
		bits = [int(ch) for ch in b[i:].decode() if ch in '01']
		return [bits[r * w:(r + 1) * w] for r in range(h)], h, w
	sys.exit('%s: not a PBM (P1 or P4)' % path)


def main():
	args = sys.argv[1:]
	thr = 0.2
	if '--threshold' in args:
		k = args.index('--threshold')
		thr = float(args[k + 1])
		del args[k:k + 2]
	usage = 'usage: bench/fidelity_place.py DESIGN.pbm B1 B2 A_DIR B_DIR... [--threshold D]'
	if '-h' in args or '--help' in args:
		print(usage)
		return
	if len(args) < 5:
		print(usage, file=sys.stderr)
		sys.exit(2)
	W, R, C = pbm(args[0])
	b1, b2 = int(args[1]), int(args[2])

	def run(r, c, dr, dc):
		k, v = 0, W[r][c]
		for s in range(1, 16):
			if W[(r + dr * s) % R][(c + dc * s) % C] != v:
				break
			k += 1
		return k

	A, nx, ny = tops(args[3], thr)
	if nx < C * b1 or ny < R * b2:
		sys.exit('%s: %d x %d columns, fewer than the design\'s %d x %d blocks of %d x %d'
		         % (args[3], nx, ny, C, R, b1, b2))
	for bdir in args[4:]:
		B, bx, by = tops(bdir, thr)
		if (bx, by) != (nx, ny):
			sys.exit('%s: %d x %d columns, %s has %d x %d' % (bdir, bx, by, args[3], nx, ny))
		off = {}
		for r in range(R):
			for c in range(C):
				s = n = 0
				for y in range(r * b2, r * b2 + b2):
					for x in range(c * b1, c * b1 + b1):
						i = y * nx + x
						if A[i] is not None and B[i] is not None:
							s += B[i] - A[i]
							n += 1
				if n:
					off[(r, c)] = s / n
		mean = sum(off.values()) / len(off)
		groups = {}
		for (r, c), v in off.items():
			lh = run(r, c, 0, -1), run(r, c, 0, 1)
			lv = run(r, c, -1, 0), run(r, c, 1, 0)
			if lh[0] + lh[1] + 1 >= 6:
				key = ('row', W[r][c], lh[0])
			elif lv[0] + lv[1] + 1 >= 6:
				key = ('col', W[r][c], lv[0])
			else:
				key = ('short', W[r][c], 0)
			groups.setdefault(key, []).append(v - mean)
		sd = (sum((v - mean) ** 2 for v in off.values()) / len(off)) ** .5
		res = [x - sum(g) / len(g) for g in groups.values() for x in g]
		sdr = (sum(x * x for x in res) / len(res)) ** .5
		print('%s - %s: %d blocks, block-offset SD %.3f, without the place means %.3f'
		      % (bdir, args[3], len(off), sd, sdr))
		for k in sorted(groups):
			g = groups[k]
			m = sum(g) / len(g)
			s2 = (sum((x - m) ** 2 for x in g) / len(g)) ** .5
			print('  %-5s value %d place %2d  n %4d  mean %+.3f  sd %.3f' % (k[0], k[1], k[2], len(g), m, s2))


main()
