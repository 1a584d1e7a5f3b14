/*
 * tests/fuzz/fuzz_obj.c - fuzz target of the Wavefront OBJ reader
 * (io/mesh/obj.c) and, for small meshes with texture coordinates, of shell
 * construction and queries (engine/render/shell.c) on whatever it accepted,
 * and of field-aligned UVs (engine/render/surface_field.c) with their
 * measures.
 *
 *   make fuzz && build/fuzz/fuzz_obj -max_total_time=60 tests/fuzz/corpus/obj
 *
 * On success every index must be in range and the counts consistent; on
 * failure there is no mesh, the code is a loom_result and the message
 * names the input ("fuzz.obj:LINE: ...").  Replayed over
 * tests/fuzz/corpus/obj by `make test`.
 */
#include "loom.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_mesh(const loom_mesh *m)
{
	for (size_t c = 0; c < 3 * (size_t)m->n_triangles; c++) {
		if (m->tri_v[c] >= m->n_positions)
			abort();
		if (m->tri_vt && m->tri_vt[c] != LOOM_MESH_NONE &&
		    m->tri_vt[c] >= m->n_texcoords)
			abort();
		if (m->tri_vn && m->tri_vn[c] != LOOM_MESH_NONE &&
		    m->tri_vn[c] >= m->n_normals)
			abort();
	}
	if ((m->n_positions && !m->positions) || (m->n_texcoords && !m->texcoords) ||
	    (m->n_normals && !m->normals) || (m->n_triangles && !m->tri_v))
		abort();
}

static void try_shell(const loom_mesh *m)
{
	loom_shell_params p = LOOM_SHELL_PARAMS_INIT;
	loom_shell *s = NULL;
	loom_diag d;
	int rc;

	if (!m->tri_vt || m->n_triangles == 0 || m->n_triangles > 64)
		return;
	memset(&d, 0, sizeof d);
	p.thickness = 0.5;
	p.voxels_per_uv = 16;
	p.nz = 4;
	rc = loom_shell_new(m, &p, &s, &d);
	if (rc != LOOM_OK) {
		if (s || rc == LOOM_OK || rc >= LOOM_RESULT_COUNT_)
			abort();
		return;
	}
	for (uint32_t k = 0; k < m->n_triangles && k < 8; k++) {
		/* the centroid of a face, lifted half way up the shell */
		const uint32_t *tv = m->tri_v + 3 * (size_t)k;
		double w[3], v[3];
		for (int j = 0; j < 3; j++)
			w[j] = (m->positions[3 * (size_t)tv[0] + j] +
			        m->positions[3 * (size_t)tv[1] + j] +
			        m->positions[3 * (size_t)tv[2] + j]) / 3.0;
		rc = loom_shell_world_to_voxel(s, w, v, NULL);
		if (rc != LOOM_OK && rc != LOOM_ENOTFOUND && rc != LOOM_EUNUSABLE)
			abort();
		v[0] = v[1] = 1.0;
		v[2] = 2.0;
		rc = loom_shell_voxel_to_world(s, v, w, NULL);
		if (rc != LOOM_OK && rc != LOOM_ENOTFOUND && rc != LOOM_EUNUSABLE)
			abort();
	}
	loom_shell_free(s);
}

/* Field UVs of small meshes: every triangle gets three in-range texture
   coordinates, finite; the measure accepts the result. */
static void try_field(const loom_mesh *m)
{
	loom_field_uv_params p = LOOM_FIELD_UV_PARAMS_INIT;
	loom_mesh *o = NULL;
	loom_mesh_uv_stats st;
	double per[2] = {0.5, 0.25};
	int rc;

	if (m->n_triangles == 0 || m->n_triangles > 256)
		return;
	p.period[0] = per[0];
	p.period[1] = per[1];
	rc = loom_mesh_field_uv(m, &p, &o, NULL);
	if (rc != LOOM_OK) {
		if (o || rc >= LOOM_RESULT_COUNT_)
			abort();
		return;
	}
	if (!o || o->n_triangles != m->n_triangles || o->n_texcoords != 3 * m->n_triangles)
		abort();
	check_mesh(o);
	for (size_t i = 0; i < 2 * (size_t)o->n_texcoords; i++)
		if (!(o->texcoords[i] == o->texcoords[i]))
			abort();
	rc = loom_mesh_measure_uv(o, per, 1e-3, &st);
	if (rc != LOOM_OK && rc != LOOM_EINVAL)
		abort();
	loom_mesh_free(o);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	loom_mesh *m = NULL;
	loom_diag diag;
	int rc;

	memset(&diag, 0, sizeof diag);
	rc = loom_obj_parse((const char *)data, size, "fuzz.obj", &m, &diag);
	if (rc == LOOM_OK) {
		if (!m)
			abort();
		check_mesh(m);
		try_shell(m);
		try_field(m);
		loom_mesh_free(m);
	} else if (m || rc < 0 || rc >= LOOM_RESULT_COUNT_ ||
	           memchr(diag.message, 0, sizeof diag.message) == NULL ||
	           strncmp(diag.message, "fuzz.obj:", 9) != 0) {
		abort();
	}
	return 0;
}
