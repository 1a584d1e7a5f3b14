/*
 * tests/unit/test_obj.c - the Wavefront OBJ reader (io/mesh/obj.c): valid files
 * of every corner form, triangulation, relative indices, line endings,
 * warnings, and a table of malformed inputs each checked for its code and
 * its "name:line: what" message.
 */
#include "loom.h"
#include "check.h"

#include <stdlib.h>
#include <string.h>

static loom_mesh *parse_ok(const char *text, loom_diag *diag)
{
	loom_mesh *m = NULL;
	int rc = loom_obj_parse(text, strlen(text), "t.obj", &m, diag);
	CHECK_EQ_INT(rc, LOOM_OK);
	if (rc)
		printf("  message: %s\n", diag ? diag->message : "");
	return m;
}

static void test_quad_polygon(void)
{
	loom_diag d;
	loom_mesh *m;
	static const uint32_t tv[6] = {0, 1, 2, 0, 2, 3};

	memset(&d, 0, sizeof d);
	m = parse_ok("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
	             "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
	             "f 1/1/1 2/2/1 3/3/1 4/4/1\n", &d);
	if (!m)
		return;
	CHECK_EQ_INT(m->n_positions, 4);
	CHECK_EQ_INT(m->n_texcoords, 4);
	CHECK_EQ_INT(m->n_normals, 1);
	CHECK_EQ_INT(m->n_triangles, 2);
	CHECK(m->tri_vt && m->tri_vn);
	for (int k = 0; k < 6; k++) {
		CHECK_EQ_INT(m->tri_v[k], tv[k]);
		if (m->tri_vt)
			CHECK_EQ_INT(m->tri_vt[k], tv[k]);
		if (m->tri_vn)
			CHECK_EQ_INT(m->tri_vn[k], 0);
	}
	CHECK(m->positions[3 * 2 + 0] == 1.0f && m->positions[3 * 2 + 1] == 1.0f);
	CHECK(m->texcoords[2 * 3 + 1] == 1.0f);
	CHECK_EQ_INT(d.n_warnings, 0);
	loom_mesh_free(m);
}

static void test_corner_forms(void)
{
	loom_mesh *m;

	/* v only: no texcoord / normal arrays */
	m = parse_ok("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", NULL);
	if (m) {
		CHECK(m->tri_vt == NULL && m->tri_vn == NULL);
		CHECK_EQ_INT(m->n_triangles, 1);
		loom_mesh_free(m);
	}
	/* v//vn */
	m = parse_ok("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 -1\n"
	             "f 1//2 2//2 3//1\n", NULL);
	if (m) {
		CHECK(m->tri_vt == NULL && m->tri_vn != NULL);
		if (m->tri_vn)
			CHECK(m->tri_vn[0] == 1 && m->tri_vn[1] == 1 && m->tri_vn[2] == 0);
		loom_mesh_free(m);
	}
	/* v/vt, vt with one and three values */
	m = parse_ok("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25\nvt 1 0 7\nvt 0 1\n"
	             "f 1/1 2/2 3/3\n", NULL);
	if (m) {
		CHECK(m->tri_vt != NULL && m->tri_vn == NULL);
		CHECK(m->texcoords[0] == 0.25f && m->texcoords[1] == 0.0f);
		CHECK(m->texcoords[2] == 1.0f && m->texcoords[3] == 0.0f);
		loom_mesh_free(m);
	}
	/* faces without vt next to faces with: NONE at those corners */
	m = parse_ok("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 2 3\nf 1/1 2/1 3/1\n",
	             NULL);
	if (m) {
		CHECK(m->tri_vt && m->tri_vt[0] == LOOM_MESH_NONE && m->tri_vt[3] == 0);
		loom_mesh_free(m);
	}
}

static void test_relative_and_extras(void)
{
	loom_diag d;
	loom_mesh *m;

	memset(&d, 0, sizeof d);
	/* negative indices, v with w and with colours, comments, CRLF, a
	   pentagon (3 triangles), ignored statements */
	m = parse_ok("# header\r\nmtllib x.mtl\r\no thing\r\ng group\r\ns 1\r\n"
	             "v 0 0 0 1\r\nv 1 0 0 0.5 0.5 0.5\r\nv 1 1 0 1 0.2 0.2 0.2\r\n"
	             "v 0 1 0\r\nv -1 0.5 0 # trailing comment\r\n"
	             "usemtl red\r\nf -5 -4 -3 -2 -1\r\n", &d);
	if (m) {
		CHECK_EQ_INT(m->n_positions, 5);
		CHECK_EQ_INT(m->n_triangles, 3);
		CHECK(m->tri_v[6] == 0 && m->tri_v[7] == 3 && m->tri_v[8] == 4);
		CHECK(m->positions[12] == -1.0f);
		loom_mesh_free(m);
	}
	CHECK_EQ_INT(d.n_warnings, 0);

	/* unknown statements: one warning for the file */
	memset(&d, 0, sizeof d);
	m = parse_ok("v 0 0 0\nvp 1 2\ncstype bezier\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", &d);
	loom_mesh_free(m);
	CHECK_EQ_INT(d.n_warnings, 1);

	/* empty input: an empty mesh */
	m = parse_ok("", NULL);
	if (m) {
		CHECK_EQ_INT(m->n_triangles, 0);
		CHECK(m->positions == NULL);
		loom_mesh_free(m);
	}
}

typedef struct bad_case {
	const char *text;
	int code;
	const char *msg;
} bad_case;

static void test_malformed(void)
{
	static const bad_case cases[] = {
		{"v 1 2\n", LOOM_EFORMAT, "t.obj:1: 'v' needs at least 3 numbers, got 2"},
		{"v 1 2 x\n", LOOM_EFORMAT, "t.obj:1: expected a number for the 3rd value of 'v', got 'x'"},
		{"v 1 2 nan\n", LOOM_EFORMAT, "t.obj:1: expected a finite number"},
		{"v 1e999 0 0\n", LOOM_EFORMAT, "t.obj:1: expected a finite number for the 1st"},
		{"v 1 2 3 4 5\n", LOOM_EFORMAT, "t.obj:1: 'v' takes x y z [w] or x y z [w] r g b, got 5"},
		{"v 1 2 3 4 5 6 7 8\n", LOOM_EFORMAT, "t.obj:1: 'v' takes at most 7 numbers"},
		{"vt\n", LOOM_EFORMAT, "t.obj:1: 'vt' needs at least 1 numbers, got 0"},
		{"vt 1 2 3 4\n", LOOM_EFORMAT, "t.obj:1: 'vt' takes at most 3 numbers, got more ('4')"},
		{"vn 1 2\n", LOOM_EFORMAT, "t.obj:1: 'vn' needs at least 3 numbers"},
		{"vn 0 0 1 0\n", LOOM_EFORMAT, "t.obj:1: 'vn' takes at most 3 numbers"},
		{"v 1 2 3\nv 1 2 3\nf 1 2\n", LOOM_EFORMAT, "t.obj:3: a face needs at least 3 corners, got 2"},
		{"f\n", LOOM_EFORMAT, "t.obj:1: a face needs at least 3 corners, got 0"},
		{"v 0 0 0\nf 1 2 3\n", LOOM_EFORMAT,
		 "t.obj:2: v index in face corner '2' out of range: 1 positions defined so far"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nf 0 1 2\n", LOOM_EFORMAT,
		 "t.obj:4: v index 0 in face corner '0' (indices start at 1)"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nf -4 1 2\n", LOOM_EFORMAT,
		 "t.obj:4: v index in face corner '-4' out of range"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nvt 0 0\nf 1/1 2 3\n", LOOM_EFORMAT,
		 "t.obj:5: face corners must all have the same form: first is v/vt, '2' is v"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nvt 0 0\nvn 0 0 1\nf 1//1 2//1 3/1/1\n", LOOM_EFORMAT,
		 "first is v//vn, '3/1/1' is v/vt/vn"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1/1/1/1 2 3\n", LOOM_EFORMAT,
		 "t.obj:4: expected a face corner v, v/vt, v//vn or v/vt/vn, got '1/1/1/1'"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nvt 0 0\nf 1/x 2/1 3/1\n", LOOM_EFORMAT,
		 "t.obj:5: expected a vt index (integer) in face corner '1/x'"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nvt 0 0\nf 1/2 2/1 3/1\n", LOOM_EFORMAT,
		 "t.obj:5: vt index in face corner '1/2' out of range: 1 texture coordinates defined so far"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1//1 2//1 3//1\n", LOOM_EFORMAT,
		 "t.obj:4: vn index in face corner '1//1' out of range: 0 normals defined so far"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nf a b c\n", LOOM_EFORMAT,
		 "t.obj:4: expected a v index (integer) in face corner 'a'"},
		{"v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1/ 2/ 3/\n", LOOM_EFORMAT,
		 "t.obj:4: expected a vt index (integer) in face corner '1/'"},
		{"v 0 0 0\r\nv 1 0 0\r\nfoo bar\r\nf 1 2 9\r\n", LOOM_EFORMAT,
		 "t.obj:4: v index in face corner '9' out of range"},
		{"v 0 0 0\rv 1 0 0\rf 1 2 99999999999999999999\r", LOOM_EFORMAT,
		 "t.obj:3: expected a v index (integer) in face corner '999999999999"},
		{"v 0 0 00000000000000000000000000000000000000000000000000000000000000000000"
		 "000000000000000000000000000000000000000000000000000000000000000000000001\n",
		 LOOM_EFORMAT, "t.obj:1: expected a number for the 3rd value of 'v', got '0000"},
	};
	for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
		loom_diag d;
		loom_mesh *m = (loom_mesh *)&d; /* must be reset to NULL */
		int rc;
		memset(&d, 0, sizeof d);
		rc = loom_obj_parse(cases[k].text, strlen(cases[k].text), "t.obj", &m, &d);
		if (rc != cases[k].code || !strstr(d.message, cases[k].msg) || m != NULL)
			printf("  case %zu: rc %d message \"%s\"\n", k, rc, d.message);
		CHECK_EQ_INT(rc, cases[k].code);
		CHECK_STR_CONTAINS(d.message, cases[k].msg);
		CHECK(m == NULL);
	}
}

static void test_bad_args_and_files(void)
{
	loom_diag d;
	loom_mesh *m = NULL;
	char path[1024];
	const char *top = getenv("LOOM_TOP");

	memset(&d, 0, sizeof d);
	CHECK_EQ_INT(loom_obj_parse("v 0 0 0\n", 8, "t.obj", NULL, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_obj_parse(NULL, 3, "t.obj", &m, &d), LOOM_EINVAL);
	CHECK(m == NULL);
	CHECK_EQ_INT(loom_obj_parse(NULL, 0, "t.obj", &m, &d), LOOM_OK);
	loom_mesh_free(m);
	m = NULL;
	CHECK_EQ_INT(loom_obj_read(NULL, &m, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_obj_read("/nonexistent/dir/x.obj", &m, &d), LOOM_EIO);
	CHECK_STR_CONTAINS(d.message, "/nonexistent/dir/x.obj");
	loom_mesh_free(NULL);

	/* the committed test meshes */
	snprintf(path, sizeof path, "%s/tests/data/meshes/quad.obj", top ? top : ".");
	CHECK_EQ_INT(loom_obj_read(path, &m, &d), LOOM_OK);
	if (m) {
		CHECK_EQ_INT(m->n_triangles, 2);
		CHECK(m->positions[3 * 2] == 64.0f);
		loom_mesh_free(m);
		m = NULL;
	}
	snprintf(path, sizeof path, "%s/tests/data/meshes/cylinder.obj", top ? top : ".");
	CHECK_EQ_INT(loom_obj_read(path, &m, &d), LOOM_OK);
	if (m) {
		CHECK_EQ_INT(m->n_positions, 17 * 7);
		CHECK_EQ_INT(m->n_triangles, 2 * 16 * 6);
		CHECK(m->tri_vt && m->tri_vn);
		loom_mesh_free(m);
		m = NULL;
	}
	snprintf(path, sizeof path, "%s/tests/data/meshes/bump.obj", top ? top : ".");
	CHECK_EQ_INT(loom_obj_read(path, &m, &d), LOOM_OK);
	if (m) {
		CHECK_EQ_INT(m->n_triangles, 2 * 12 * 12);
		CHECK(m->tri_vt && !m->tri_vn);
		loom_mesh_free(m);
	}
}

/* Undirected edges by position index: how many triangles use each, and
   whether each directed edge occurs once (consistent winding). */
typedef struct { uint64_t key; int dir; } dedge;

static int dedge_cmp(const void *a, const void *b)
{
	const dedge *x = a, *y = b;
	return x->key < y->key ? -1 : x->key > y->key;
}

static void edge_census(const loom_mesh *m, uint32_t *border, uint32_t *twice,
                        uint32_t *other, uint32_t *misoriented)
{
	size_t n = 3 * (size_t)m->n_triangles;
	dedge *e = malloc(n * sizeof *e);

	*border = *twice = *other = *misoriented = 0;
	if (!e)
		return;
	for (size_t t = 0; t < m->n_triangles; t++)
		for (int i = 0; i < 3; i++) {
			uint64_t a = m->tri_v[3 * t + i], b = m->tri_v[3 * t + (i + 1) % 3];
			e[3 * t + i].key = a < b ? (a << 32) | b : (b << 32) | a;
			e[3 * t + i].dir = a < b;
		}
	qsort(e, n, sizeof *e, dedge_cmp);
	for (size_t i = 0; i < n;) {
		size_t j = i + 1;
		while (j < n && e[j].key == e[i].key)
			j++;
		if (j - i == 1)
			(*border)++;
		else if (j - i == 2) {
			(*twice)++;
			if (e[i].dir == e[i + 1].dir)
				(*misoriented)++;
		} else
			(*other)++;
		i = j;
	}
	free(e);
}

/* Signed volume (divergence theorem): > 0 when the normals face out. */
static double signed_volume(const loom_mesh *m)
{
	double vol = 0;
	for (size_t t = 0; t < m->n_triangles; t++) {
		const float *a = m->positions + 3 * (size_t)m->tri_v[3 * t];
		const float *b = m->positions + 3 * (size_t)m->tri_v[3 * t + 1];
		const float *c = m->positions + 3 * (size_t)m->tri_v[3 * t + 2];
		vol += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
		        a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
		        a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
	}
	return vol;
}

/* The scene meshes of tests/data/meshes/gen_meshes.py: read, counts, UVs in
   [0, 1], the pillow closed (every edge shared by exactly two triangles,
   wound consistently, normals outwards, two UV charts meeting at a seam),
   the drape and the sleeve open along their hems only. */
static void test_scene_meshes(void)
{
	static const struct {
		const char *name;
		uint32_t positions, triangles, border;
	} tab[] = {
		{"pillow.obj", 2 * 33 * 33 - 4 * 32, 2 * 2 * 32 * 32, 0},
		{"drape.obj", 45 * 45, 2 * 44 * 44, 4 * 44},
		{"sleeve.obj", 48 * 23, 2 * 48 * 22, 2 * 48},
	};
	const char *top = getenv("LOOM_TOP");
	char path[4096];
	loom_diag d;

	memset(&d, 0, sizeof d);
	for (size_t k = 0; k < sizeof tab / sizeof tab[0]; k++) {
		loom_mesh *m = NULL;
		uint32_t border, twice, other, mis, uv_out = 0;
		snprintf(path, sizeof path, "%s/tests/data/meshes/%s", top ? top : ".",
		         tab[k].name);
		CHECK_EQ_INT(loom_obj_read(path, &m, &d), LOOM_OK);
		if (!m)
			continue;
		CHECK_EQ_INT(m->n_positions, tab[k].positions);
		CHECK_EQ_INT(m->n_triangles, tab[k].triangles);
		CHECK(m->tri_vt != NULL);
		for (size_t i = 0; i < 2 * (size_t)m->n_texcoords; i++)
			uv_out += !(m->texcoords[i] >= 0.0f && m->texcoords[i] <= 1.0f);
		CHECK_EQ_INT(uv_out, 0);
		edge_census(m, &border, &twice, &other, &mis);
		printf("  %s: %u triangles, %u border edges, %u shared, %u "
		       "non-manifold, %u misoriented\n", tab[k].name, m->n_triangles,
		       border, twice, other, mis);
		CHECK_EQ_INT(border, tab[k].border);
		CHECK_EQ_INT(other, 0);
		CHECK_EQ_INT(mis, 0);
		if (tab[k].border == 0) {
			/* closed: Euler characteristic 2, outward normals, and the
			   seam: shared edges whose two triangles use different vt */
			uint32_t seam = 0;
			CHECK_EQ_INT((int64_t)m->n_positions - (int64_t)(border + twice) +
			             (int64_t)m->n_triangles, 2);
			CHECK(signed_volume(m) > 0);
			for (size_t t = 0; t < m->n_triangles; t++)
				for (int i = 0; i < 3; i++) {
					/* a corner whose position is on z = 0 (the seam
					   plane) with u on the back chart's side */
					uint32_t v = m->tri_v[3 * t + i], vt = m->tri_vt[3 * t + i];
					if (m->positions[3 * (size_t)v + 2] == 0.0f &&
					    m->texcoords[2 * (size_t)vt] > 0.5f)
						seam++;
				}
			CHECK(seam > 0);
			CHECK_EQ_INT(m->n_texcoords, 2 * 33 * 33);
		}
		loom_mesh_free(m);
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_obj");
	RUN(test_quad_polygon);
	RUN(test_corner_forms);
	RUN(test_relative_and_extras);
	RUN(test_malformed);
	RUN(test_bad_args_and_files);
	RUN(test_scene_meshes);
	CHECK_MAIN_END();
}
