/*
 * docs/examples/read_region.c - a box of voxels into your own buffers.
 *
 * loom_texture_read_region fills caller-owned arrays (raw encodings:
 * density as a byte 0..255, orientation as a 16-bit code) for any box of
 * the unbounded bolt, the fastest way to bulk-copy voxels into a
 * renderer's or simulator's own grid.  This program reads a 100 x 80 x 48
 * box at negative and positive coordinates, counts warp and weft voxels,
 * and checks a sample of them against single-voxel lookups.
 *
 *   cc read_region.c $(pkg-config --cflags --libs loom)
 *   ./a.out /usr/local/share/loom/default.ldb
 */
#include "common.h"

#include <math.h>
#include <string.h>

int main(int argc, char **argv)
{
	const int64_t lo[3] = {-40, -30, 0}, hi[3] = {60, 50, 48};
	size_t nx = 100, ny = 80, nz = 48, n = nx * ny * nz;
	uint8_t *dens = malloc(n), *kind = malloc(n);
	uint16_t *orie = malloc(2 * n);
	loom_texture_region r;
	size_t count[3] = {0, 0, 0}, checked = 0, mismatches = 0;
	example e;

	if (argc < 2) {
		fprintf(stderr, "usage: %s DATABASE.ldb\n", argv[0]);
		return 2;
	}
	if (!dens || !kind || !orie)
		return 1;
	example_open(&e, argv[1], "satin:4/1", 10, 10, 32, 1);
	memset(&r, 0, sizeof r); /* NULL channels are not written */
	r.density = dens;
	r.orientation = orie;
	r.kind = kind;
	r.layout = LOOM_REGION_X_FASTEST; /* index ((z*ny + y)*nx + x) */
	if (loom_texture_read_region(e.tex, lo, hi, &r) != LOOM_OK) {
		fprintf(stderr, "read: %s\n", loom_texture_errmsg(e.tex));
		return 1;
	}
	for (size_t i = 0; i < n; i++)
		count[kind[i] < 3 ? kind[i] : 0]++;
	/* every 97th voxel against loom_texture_voxel */
	for (size_t i = 0; i < n; i += 97) {
		int64_t x = lo[0] + (int64_t)(i % nx), y = lo[1] + (int64_t)(i / nx % ny);
		int64_t z = lo[2] + (int64_t)(i / nx / ny);
		loom_texel v;
		float o[3];
		loom_texture_voxel(e.tex, x, y, z, &v);
		loom_orientation_decode(orie[i], o);
		checked++;
		if (fabsf(v.density - dens[i] / 255.0f) > 1e-6f || v.kind != kind[i] ||
		    (dens[i] && (o[0] != v.orientation[0] || o[1] != v.orientation[1] ||
		                 o[2] != v.orientation[2])))
			mismatches++;
	}
	printf("voxels %zu empty %zu warp %zu weft %zu checked %zu mismatches %zu\n", n,
	       count[0], count[1], count[2], checked, mismatches);
	example_close(&e);
	free(dens);
	free(kind);
	free(orie);
	return mismatches != 0;
}
