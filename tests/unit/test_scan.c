/* tests/unit/test_scan.c - exemplar creation from scans (paper section 6):
 * each step against references (brute force, closed forms) and the whole
 * pipeline against synthetic scans with known ground truth
 * (test_scan_synth.h). */
#include "check.h"
#include "loom.h"
#include "test_scan_synth.h"

#include <math.h>

static const char *const W_PLAIN[] = {"10", "01", NULL};
static const char *const W_TWILL23[] = {"10001", "11000", "01100", "00110",
                                        "00011", NULL};
static const char *const W_SATIN14[] = {"10000", "00100", "00001", "01000",
                                        "00010", NULL};

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

/* ---- parameters and arguments ------------------------------------------ */

static void params_and_bad_args(void)
{
	loom_scan_params p;
	loom_scan_volume v;
	loom_scan_result *r = (loom_scan_result *)&p;
	loom_diag d = {0};

	loom_scan_params_init(&p);
	CHECK_EQ_INT(p.size, sizeof p);
	CHECK(p.step == 15 && p.c0 == 0.7f && p.radius_warp == 20 &&
	      p.radius_weft == 30);
	CHECK_EQ_INT(p.threads, 2);
	CHECK_EQ_INT(p.n_warps, 0);

	CHECK_EQ_INT(loom_scan_volume_alloc(NULL, 4, 4, 4, LOOM_SCAN_DENSITY), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_volume_alloc(&v, 0, 4, 4, LOOM_SCAN_DENSITY), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_volume_alloc(&v, 4, 4, 4, 0), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_volume_alloc(&v, 1u << 20, 1u << 20, 2, LOOM_SCAN_DENSITY),
	             LOOM_ERANGE);
	CHECK_EQ_INT(loom_scan_volume_alloc(&v, 32, 32, 8, LOOM_SCAN_DENSITY), LOOM_OK);
	CHECK(v.density && !v.orient && !v.label && v.nx == 32);

	CHECK_EQ_INT(loom_scan_build(NULL, &p, &r, &d), LOOM_EINVAL);
	CHECK(r == NULL);
	CHECK_EQ_INT(loom_scan_build(&v, NULL, &r, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_build(&v, &p, NULL, &d), LOOM_EINVAL);
	/* counts missing */
	CHECK_EQ_INT(loom_scan_build(&v, &p, &r, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "warps");
	p.n_warps = 3;
	p.n_wefts = LOOM_SCAN_MAX_YARNS + 1;
	CHECK_EQ_INT(loom_scan_build(&v, &p, &r, &d), LOOM_EINVAL);
	p.n_wefts = 3;
	p.size = 8;
	CHECK_EQ_INT(loom_scan_build(&v, &p, &r, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "loom_scan_params_init");
	p.size = sizeof p;
	p.c0 = 1.5f;
	CHECK_EQ_INT(loom_scan_build(&v, &p, &r, &d), LOOM_EINVAL);
	p.c0 = 0.7f;
	p.threads = 0;
	CHECK_EQ_INT(loom_scan_build(&v, &p, &r, &d), LOOM_EINVAL);
	p.threads = 2;
	/* too small a volume */
	{
		loom_scan_volume t;
		CHECK_EQ_INT(loom_scan_volume_alloc(&t, 8, 32, 8, LOOM_SCAN_DENSITY), LOOM_OK);
		CHECK_EQ_INT(loom_scan_build(&t, &p, &r, &d), LOOM_EINVAL);
		CHECK_STR_CONTAINS(d.message, "too small");
		loom_scan_volume_release(&t);
	}
	/* step functions */
	CHECK_EQ_INT(loom_scan_denoise(&v, -1, 1, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_denoise(NULL, 1, 1, &d), LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_orient(&v, 0.5f, 1.5f, 1, NULL, &d), LOOM_EINVAL);
	CHECK_STR_CONTAINS(d.message, "orientation");
	{
		loom_scan_endpoints e;
		CHECK_EQ_INT(loom_scan_endpoints_find(&v, LOOM_SCAN_WARP, 3, 0.5f, &p, &e, &d),
		             LOOM_EINVAL); /* no orientation */
		CHECK_EQ_INT(loom_scan_endpoints_find(&v, 7, 3, 0.5f, &p, &e, &d), LOOM_EINVAL);
	}
	CHECK_EQ_INT(loom_scan_segment(&v, 0.5f, NULL, 0, NULL, 4, 1, NULL, NULL, NULL, &d),
	             LOOM_EINVAL);
	CHECK_EQ_INT(loom_scan_weave(NULL, 1, NULL, 1, 8, 8, 8, NULL, NULL, &d), LOOM_EINVAL);
	{
		double rot;
		CHECK_EQ_INT(loom_scan_align(NULL, NULL, 0, &rot, NULL, &d), LOOM_EINVAL);
	}
	/* a constant volume has no threshold */
	{
		float thr;
		CHECK_EQ_INT(loom_scan_threshold(&v, &thr, &d), LOOM_EUNSUPPORTED);
		CHECK_STR_CONTAINS(d.message, "constant");
	}
	CHECK(strcmp(loom_scan_step_name(LOOM_SCAN_STEP_ORIENT), "orientation") == 0);
	CHECK(strcmp(loom_scan_step_name(99), "unknown step") == 0);
	loom_scan_volume_release(&v);
	loom_scan_volume_release(NULL);
	loom_scan_result_free(NULL);
	loom_scan_curve_release(NULL);
}

/* ---- step 1: denoise, noise level, threshold ----------------------------- */

static void denoise_matches_reference(void)
{
	enum { NX = 13, NY = 11, NZ = 9 };
	uint64_t seed = check_seed();
	loom_scan_volume a, b;
	loom_diag d = {0};
	float *ref = malloc(NX * NY * NZ * sizeof *ref);
	double w[7], sum = 0, maxdiff = 0;

	CHECK_EQ_INT(loom_scan_volume_alloc(&a, NX, NY, NZ, LOOM_SCAN_DENSITY), LOOM_OK);
	CHECK_EQ_INT(loom_scan_volume_alloc(&b, NX, NY, NZ, LOOM_SCAN_DENSITY), LOOM_OK);
	for (int i = 0; i < NX * NY * NZ; i++)
		a.density[i] = b.density[i] = (float)synth_unit(synth_mix(seed + i));
	/* brute-force 3D convolution with the separable kernel, sigma 0.8,
	   radius ceil(2.4) = 3, borders clamped */
	for (int k = -3; k <= 3; k++)
		sum += w[k + 3] = exp(-0.5 * k * k / 0.64);
	for (int k = 0; k < 7; k++)
		w[k] /= sum;
	for (int z = 0; z < NZ; z++)
		for (int y = 0; y < NY; y++)
			for (int x = 0; x < NX; x++) {
				double acc = 0;
				for (int c = -3; c <= 3; c++)
					for (int bb = -3; bb <= 3; bb++)
						for (int aa = -3; aa <= 3; aa++) {
							int xx = x + aa, yy = y + bb, zz = z + c;
							xx = xx < 0 ? 0 : xx >= NX ? NX - 1 : xx;
							yy = yy < 0 ? 0 : yy >= NY ? NY - 1 : yy;
							zz = zz < 0 ? 0 : zz >= NZ ? NZ - 1 : zz;
							acc += w[aa + 3] * w[bb + 3] * w[c + 3] *
							       a.density[(zz * NY + yy) * NX + xx];
						}
				ref[(z * NY + y) * NX + x] = (float)acc;
			}
	CHECK_EQ_INT(loom_scan_denoise(&a, 0.8f, 1, &d), LOOM_OK);
	CHECK_EQ_INT(loom_scan_denoise(&b, 0.8f, 2, &d), LOOM_OK);
	for (int i = 0; i < NX * NY * NZ; i++) {
		double e = fabs(a.density[i] - ref[i]);
		if (e > maxdiff)
			maxdiff = e;
	}
	printf("  max |denoise - reference| = %.2g\n", maxdiff);
	CHECK(maxdiff < 1e-5);
	CHECK(memcmp(a.density, b.density, NX * NY * NZ * sizeof(float)) == 0);
	/* sigma 0 is a no-op */
	memcpy(ref, a.density, NX * NY * NZ * sizeof(float));
	CHECK_EQ_INT(loom_scan_denoise(&a, 0, 2, &d), LOOM_OK);
	CHECK(memcmp(a.density, ref, NX * NY * NZ * sizeof(float)) == 0);
	free(ref);
	loom_scan_volume_release(&a);
	loom_scan_volume_release(&b);
}

static void noise_and_threshold(void)
{
	loom_scan_volume v;
	loom_diag d = {0};
	float thr, sig;
	size_t n = 64 * 64 * 16;

	CHECK_EQ_INT(loom_scan_volume_alloc(&v, 64, 64, 16, LOOM_SCAN_DENSITY), LOOM_OK);
	/* two levels 0.1 and 0.8 in slabs of z (the estimate differentiates
	   along x, so it sees only the noise), plus Gaussian noise 0.05 */
	for (size_t i = 0; i < n; i++) {
		double u1 = synth_unit(synth_mix(2 * i + 1)), u2 = synth_unit(synth_mix(2 * i + 2));
		double g = sqrt(-2 * log(u1 + 1e-300)) * cos(2 * M_PI * u2);
		v.density[i] = (float)((i / (64 * 64) % 4 < 2 ? 0.8 : 0.1) + 0.05 * g);
	}
	sig = loom_scan_noise(&v);
	printf("  noise estimate %.4f (true 0.05)\n", sig);
	CHECK(fabsf(sig - 0.05f) < 0.003f);
	CHECK_EQ_INT(loom_scan_threshold(&v, &thr, &d), LOOM_OK);
	printf("  Otsu threshold %.3f\n", thr);
	CHECK(thr > 0.3f && thr < 0.6f);
	loom_scan_volume_release(&v);
}

/* ---- step 2: eigen solver and orientation --------------------------------- */

/* cyclic Jacobi reference: eigenvalues of a symmetric 3x3 */
static void jacobi3(const double m[6], double ev[3], double vec[3][3])
{
	double a[3][3] = {{m[0], m[1], m[2]}, {m[1], m[3], m[4]}, {m[2], m[4], m[5]}};
	double v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
	for (int sweep = 0; sweep < 60; sweep++)
		for (int p = 0; p < 2; p++)
			for (int q = p + 1; q < 3; q++) {
				double th, t, c, s;
				if (fabs(a[p][q]) < 1e-300)
					continue;
				th = (a[q][q] - a[p][p]) / (2 * a[p][q]);
				t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1));
				c = 1 / sqrt(t * t + 1);
				s = t * c;
				for (int k = 0; k < 3; k++) {
					double akp = a[k][p], akq = a[k][q];
					a[k][p] = c * akp - s * akq;
					a[k][q] = s * akp + c * akq;
				}
				for (int k = 0; k < 3; k++) {
					double apk = a[p][k], aqk = a[q][k];
					a[p][k] = c * apk - s * aqk;
					a[q][k] = s * apk + c * aqk;
				}
				for (int k = 0; k < 3; k++) {
					double vkp = v[k][p], vkq = v[k][q];
					v[k][p] = c * vkp - s * vkq;
					v[k][q] = s * vkp + c * vkq;
				}
			}
	for (int i = 0; i < 3; i++) {
		ev[i] = a[i][i];
		for (int k = 0; k < 3; k++)
			vec[i][k] = v[k][i];
	}
}

static void eigen_matches_jacobi(void)
{
	uint64_t seed = check_seed();
	double worst_val = 0, worst_vec = 0;

	for (int t = 0; t < 2000; t++) {
		double m[6], dir[3], ev[3], rev[3], rvec[3][3], scale;
		int imin = 0;
		for (int k = 0; k < 6; k++)
			m[k] = synth_unit(synth_mix(seed + 6 * t + k)) * 2 - 1;
		if (t % 3 == 0) { /* positive semi-definite, like structure tensors */
			double g[3][3];
			for (int k = 0; k < 9; k++)
				g[k / 3][k % 3] = synth_unit(synth_mix(seed * 7 + 9 * t + k)) - 0.5;
			m[0] = g[0][0] * g[0][0] + g[1][0] * g[1][0] + g[2][0] * g[2][0];
			m[1] = g[0][0] * g[0][1] + g[1][0] * g[1][1] + g[2][0] * g[2][1];
			m[2] = g[0][0] * g[0][2] + g[1][0] * g[1][2] + g[2][0] * g[2][2];
			m[3] = g[0][1] * g[0][1] + g[1][1] * g[1][1] + g[2][1] * g[2][1];
			m[4] = g[0][1] * g[0][2] + g[1][1] * g[1][2] + g[2][1] * g[2][2];
			m[5] = g[0][2] * g[0][2] + g[1][2] * g[1][2] + g[2][2] * g[2][2];
		}
		CHECK_EQ_INT(loom_scan_eigen_min(m, dir, ev), 1);
		jacobi3(m, rev, rvec);
		for (int k = 1; k < 3; k++)
			if (rev[k] < rev[imin])
				imin = k;
		scale = fabs(rev[0]) + fabs(rev[1]) + fabs(rev[2]);
		{
			/* sorted reference values, descending */
			double s[3] = {rev[0], rev[1], rev[2]}, tmp;
			for (int a = 0; a < 3; a++)
				for (int b = a + 1; b < 3; b++)
					if (s[b] > s[a]) {
						tmp = s[a];
						s[a] = s[b];
						s[b] = tmp;
					}
			for (int k = 0; k < 3; k++)
				if (fabs(s[k] - ev[k]) / scale > worst_val)
					worst_val = fabs(s[k] - ev[k]) / scale;
			/* eigenvector check only when the smallest is well separated */
			if ((s[1] - s[2]) / scale > 1e-3) {
				double dot = fabs(dir[0] * rvec[imin][0] + dir[1] * rvec[imin][1] +
				                  dir[2] * rvec[imin][2]);
				if (1 - dot > worst_vec)
					worst_vec = 1 - dot;
			}
		}
	}
	printf("  worst eigenvalue error %.2g, worst 1-|cos| %.2g\n", worst_val, worst_vec);
	CHECK(worst_val < 1e-9);
	CHECK(worst_vec < 1e-6);
	/* degenerate inputs */
	{
		double iso[6] = {2, 0, 0, 2, 0, 2}, dir[3], ev[3];
		double diag[6] = {3, 0, 0, 1, 0, 2};
		double plane[6] = {1, 0, 0, 1, 0, 0}; /* l2 = l3 = 0 in y? no: x,y */
		CHECK_EQ_INT(loom_scan_eigen_min(iso, dir, ev), 0);
		CHECK(dir[0] == 0 && dir[1] == 0 && dir[2] == 0);
		CHECK_EQ_INT(loom_scan_eigen_min(diag, dir, ev), 1);
		CHECK(fabs(fabs(dir[1]) - 1) < 1e-9 && fabs(ev[2] - 1) < 1e-12);
		/* x and y equal, z zero: the fibre is along z, well defined */
		CHECK_EQ_INT(loom_scan_eigen_min(plane, dir, ev), 1);
		CHECK(fabs(fabs(dir[2]) - 1) < 1e-9);
	}
}

/* core voxels of a yarn: no other yarn within 3 voxels */
static int core_voxel(const synth_out *o, const synth_spec *s, uint32_t x,
                      uint32_t y, uint32_t z)
{
	size_t i = ((size_t)z * s->ny + y) * s->nx + x;
	int L = o->truth[i];
	if (!L || x < 3 || y < 3 || z < 3 || x + 3 >= s->nx || y + 3 >= s->ny ||
	    z + 3 >= s->nz)
		return 0;
	for (int dz = -3; dz <= 3; dz++)
		for (int dy = -3; dy <= 3; dy++)
			for (int dx = -3; dx <= 3; dx++) {
				int q = o->truth[i + ((long)dz * s->ny + dy) * (long)s->nx + dx];
				if (q && q != L)
					return 0;
			}
	return 1;
}

static void orientation_accuracy(void)
{
	synth_spec s = synth_default(W_TWILL23);
	synth_out o;
	loom_diag d = {0};
	loom_scan_orient_info info;
	float thr, *err, *orient2;
	size_t n, m = 0;

	CHECK(synth_make(&s, &o) == 0);
	n = (size_t)s.nx * s.ny * s.nz;
	CHECK_EQ_INT(loom_scan_denoise(&o.vol, 1.0f, 2, &d), LOOM_OK);
	CHECK_EQ_INT(loom_scan_threshold(&o.vol, &thr, &d), LOOM_OK);
	o.vol.orient = malloc(3 * n * sizeof(float));
	orient2 = malloc(3 * n * sizeof(float));
	err = malloc(n * sizeof *err);
	CHECK_EQ_INT(loom_scan_orient(&o.vol, thr, 1.5f, 2, &info, &d), LOOM_OK);
	printf("  %llu voxels oriented, mean coherence %.3f\n",
	       (unsigned long long)info.voxels, info.coherence);
	CHECK(info.voxels > n / 10);
	for (uint32_t z = 0; z < s.nz; z++)
		for (uint32_t y = 0; y < s.ny; y++)
			for (uint32_t x = 0; x < s.nx; x++) {
				size_t i = ((size_t)z * s.ny + y) * s.nx + x;
				const float *a = o.vol.orient + 3 * i, *b = o.tangent + 3 * i;
				float c;
				if (!core_voxel(&o, &s, x, y, z))
					continue;
				c = fabsf(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
				err[m++] = acosf(c > 1 ? 1 : c) * 57.29578f;
			}
	qsort(err, m, sizeof *err, cmp_float);
	printf("  %zu core voxels: angle error median %.2f, p75 %.2f, p90 %.2f deg\n", m,
	       err[m / 2], err[3 * m / 4], err[9 * m / 10]);
	CHECK(m > 20000);
	CHECK(err[m / 2] < 4.0f);
	CHECK(err[9 * m / 10] < 12.0f);
	/* empty voxels get no direction */
	for (size_t i = 0; i < n; i += 97)
		if (!(o.vol.density[i] > thr))
			CHECK(o.vol.orient[3 * i] == 0 && o.vol.orient[3 * i + 1] == 0 &&
			      o.vol.orient[3 * i + 2] == 0);
	/* same bytes with one thread */
	{
		float *keep = o.vol.orient;
		o.vol.orient = orient2;
		CHECK_EQ_INT(loom_scan_orient(&o.vol, thr, 1.5f, 1, NULL, &d), LOOM_OK);
		CHECK(memcmp(keep, orient2, 3 * n * sizeof(float)) == 0);
		o.vol.orient = keep;
	}
	free(orient2);
	free(err);
	synth_free(&o);
}

/* ---- step 5: linking integral ------------------------------------------- */

/* midpoint-rule quadrature of the paper's integral for two segments */
static double linking_quadrature(const double a0[3], const double a1[3],
                                 const double b0[3], const double b1[3], int N)
{
	double da[3], db[3], cr[3], sum = 0;
	for (int k = 0; k < 3; k++) {
		da[k] = a1[k] - a0[k];
		db[k] = b1[k] - b0[k];
	}
	cr[0] = da[1] * db[2] - da[2] * db[1];
	cr[1] = da[2] * db[0] - da[0] * db[2];
	cr[2] = da[0] * db[1] - da[1] * db[0];
	for (int i = 0; i < N; i++)
		for (int j = 0; j < N; j++) {
			double s = (i + 0.5) / N, t = (j + 0.5) / N, r[3], n2;
			for (int k = 0; k < 3; k++)
				r[k] = a0[k] + s * da[k] - b0[k] - t * db[k];
			n2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
			sum += (r[0] * cr[0] + r[1] * cr[1] + r[2] * cr[2]) / (n2 * sqrt(n2));
		}
	return sum / ((double)N * N) / (4 * M_PI);
}

static void linking_closed_form_vs_quadrature(void)
{
	uint64_t seed = check_seed();
	double worst = 0;
	int tested = 0;

	for (int t = 0; t < 40 && tested < 16; t++) {
		double a0[3], a1[3], b0[3], b1[3], ref, got;
		float fa[6], fb[6];
		for (int k = 0; k < 3; k++) {
			a0[k] = synth_unit(synth_mix(seed + 12 * t + k)) * 4 - 2;
			a1[k] = synth_unit(synth_mix(seed + 12 * t + 3 + k)) * 4 - 2;
			b0[k] = synth_unit(synth_mix(seed + 12 * t + 6 + k)) * 4 - 2;
			b1[k] = synth_unit(synth_mix(seed + 12 * t + 9 + k)) * 4 - 2;
			/* keep the segments apart so the quadrature is accurate */
			b0[k] += k == 2 ? 3 : 0;
			b1[k] += k == 2 ? 3 : 0;
			fa[k] = (float)a0[k];
			fa[3 + k] = (float)a1[k];
			fb[k] = (float)b0[k];
			fb[3 + k] = (float)b1[k];
			a0[k] = fa[k];
			a1[k] = fa[3 + k];
			b0[k] = fb[k];
			b1[k] = fb[3 + k];
		}
		ref = linking_quadrature(a0, a1, b0, b1, 600);
		got = loom_scan_linking(fa, 2, fb, 2);
		if (fabs(ref) < 1e-4)
			continue;
		tested++;
		if (fabs(got - ref) > worst)
			worst = fabs(got - ref);
	}
	printf("  %d segment pairs, worst |closed form - quadrature| %.2g\n", tested, worst);
	CHECK(tested >= 10);
	CHECK(worst < 2e-5);
	/* two straight lines crossing at height difference h, long polylines:
	   L -> +1/2 for (warp along +y above, weft along -x) */
	{
		float warp[3 * 41], weft[3 * 41];
		double L;
		for (int i = 0; i <= 40; i++) {
			double u = (i - 20) * 1000.0;
			warp[3 * i] = 0;
			warp[3 * i + 1] = (float)u;
			warp[3 * i + 2] = 1;
			weft[3 * i] = (float)-u; /* decreasing x */
			weft[3 * i + 1] = 0;
			weft[3 * i + 2] = 0;
		}
		L = loom_scan_linking(warp, 41, weft, 41);
		printf("  straight lines, warp above: L = %.5f\n", L);
		CHECK(fabs(L - 0.5) < 1e-3);
		for (int i = 0; i <= 40; i++)
			warp[3 * i + 2] = -1;
		L = loom_scan_linking(warp, 41, weft, 41);
		CHECK(fabs(L + 0.5) < 1e-3);
	}
	CHECK(loom_scan_linking(NULL, 2, NULL, 2) == 0);
}

/* The weave of a 3 x 4 grid of crimped yarns built from a known pattern:
   warp j at x = 10 + 20 j rises to +A where W(i,j) = 1 (warp over). */
static void weave_from_linking_sign(void)
{
	static const char *const pat[] = {"1010", "0111", "1001", NULL};
	enum { NW = 4, NF = 3, NP = 61 };
	loom_scan_curve warps[NW], wefts[NF];
	uint8_t weave[NW * NF];
	float L[NW * NF];
	loom_diag d = {0};
	int ok = 1;

	for (int j = 0; j < NW; j++) {
		warps[j].kind = LOOM_SCAN_WARP;
		warps[j].n = NP;
		warps[j].pts = malloc(3 * NP * sizeof(float));
		for (int k = 0; k < NP; k++) {
			double y = k, f = (y - 10) / 20, h;
			long i0 = (long)floor(f);
			double t = f - i0;
			int a = (i0 >= 0 && i0 < NF) ? (pat[i0][j] == '1' ? 1 : -1) : 0;
			int b = (i0 + 1 >= 0 && i0 + 1 < NF) ? (pat[i0 + 1][j] == '1' ? 1 : -1) : 0;
			h = a * 0.5 * (1 + cos(M_PI * t)) + b * 0.5 * (1 - cos(M_PI * t));
			warps[j].pts[3 * k] = (float)(10 + 20 * j + 0.3 * sin(0.2 * k));
			warps[j].pts[3 * k + 1] = (float)y;
			warps[j].pts[3 * k + 2] = (float)(20 + 4 * h);
		}
	}
	for (int i = 0; i < NF; i++) {
		wefts[i].kind = LOOM_SCAN_WEFT;
		wefts[i].n = 81;
		wefts[i].pts = malloc(3 * 81 * sizeof(float));
		for (int k = 0; k < 81; k++) {
			double x = k, f = (x - 10) / 20, h;
			long j0 = (long)floor(f);
			double t = f - j0;
			int a = (j0 >= 0 && j0 < NW) ? (pat[i][j0] == '1' ? -1 : 1) : 0;
			int b = (j0 + 1 >= 0 && j0 + 1 < NW) ? (pat[i][j0 + 1] == '1' ? -1 : 1) : 0;
			h = a * 0.5 * (1 + cos(M_PI * t)) + b * 0.5 * (1 - cos(M_PI * t));
			wefts[i].pts[3 * k] = (float)x;
			wefts[i].pts[3 * k + 1] = (float)(10 + 20 * i);
			wefts[i].pts[3 * k + 2] = (float)(20 + 4 * h);
		}
	}
	CHECK_EQ_INT(loom_scan_weave(warps, NW, wefts, NF, 80, 60, 40, weave, L, &d), LOOM_OK);
	for (int i = 0; i < NF; i++)
		for (int j = 0; j < NW; j++) {
			if (weave[i * NW + j] != (pat[i][j] == '1'))
				ok = 0;
			if (fabsf(fabsf(L[i * NW + j]) - 0.5f) > 0.01f)
				ok = 0;
		}
	printf("  L(0,0) = %.4f (warp over), L(1,0) = %.4f (weft over)\n", L[0], L[NW]);
	CHECK(ok);
	CHECK(L[0] > 0.49f && L[NW] < -0.49f);
	for (int j = 0; j < NW; j++)
		loom_scan_curve_release(&warps[j]);
	for (int i = 0; i < NF; i++)
		loom_scan_curve_release(&wefts[i]);
}

/* ---- steps 7, 8: alignment and registration ------------------------------ */

/* moments of a rasterised band of width w along direction (dx, dy) */
static loom_scan_moments band_moments(double cx, double cy, double dx, double dy,
                                      double len, double w)
{
	loom_scan_moments m = {0, 0, 0, 0, 0, 0};
	for (long y = 0; y < 400; y++)
		for (long x = 0; x < 400; x++) {
			double rx = x - cx, ry = y - cy;
			double along = rx * dx + ry * dy, across = -rx * dy + ry * dx;
			if (fabs(along) <= len / 2 && fabs(across) <= w / 2) {
				m.n++;
				m.sx += x;
				m.sy += y;
				m.sxx += (int64_t)x * x;
				m.sxy += (int64_t)x * y;
				m.syy += (int64_t)y * y;
			}
		}
	return m;
}

static void align_known_rotation(void)
{
	double th = 4.0 * M_PI / 180, rot;
	loom_scan_moments m[8];
	int kinds[8];
	float dirs[16];
	loom_diag d = {0};

	for (int j = 0; j < 4; j++) {
		m[j] = band_moments(100 + 50 * j, 200, -sin(th), cos(th), 300, 30);
		kinds[j] = LOOM_SCAN_WARP;
		m[4 + j] = band_moments(200, 100 + 50 * j, cos(th), sin(th), 300, 20);
		kinds[4 + j] = LOOM_SCAN_WEFT;
	}
	CHECK_EQ_INT(loom_scan_align(m, kinds, 8, &rot, dirs, &d), LOOM_OK);
	printf("  rotation %.4f (true 4)\n", rot);
	CHECK(fabs(rot - 4.0) < 0.05);
	CHECK(dirs[1] > 0.99f && dirs[8] > 0.99f); /* warps to +y, wefts to +x */
	/* aligned_to_scan is a rotation about the centre */
	{
		double sx, sy;
		loom_scan_aligned_to_scan(101, 51, 90, 50, 25, &sx, &sy);
		CHECK(fabs(sx - 50) < 1e-9 && fabs(sy - 25) < 1e-9);
		loom_scan_aligned_to_scan(101, 51, 90, 60, 25, &sx, &sy);
		CHECK(fabs(sx - 50) < 1e-9 && fabs(sy - 35) < 1e-9);
	}
	/* no weft voxels */
	for (int j = 4; j < 8; j++)
		m[j].n = 0;
	CHECK_EQ_INT(loom_scan_align(m, kinds, 8, &rot, NULL, &d), LOOM_EUNSUPPORTED);
}

/* Registration on an ideal top map: 6 warps at x = 14 + 20 j (14 wide), 6
   wefts at y = 12 + 16 i (12 wide), twill; rotation 0; curves offset by
   (+4, +3) from the truth.  The crop must come back within 2 voxels, and
   the SAT scoring must equal brute-force counting. */
static void register_against_brute_force(void)
{
	enum { NX = 140, NY = 110, NW = 6, NF = 6 };
	uint8_t *top = calloc(NX * NY, 1), weave[NW * NF];
	loom_scan_curve c[NW + NF];
	loom_scan_grid g;
	loom_diag d = {0};
	uint64_t seed = check_seed();

	for (int i = 0; i < NF; i++)
		for (int j = 0; j < NW; j++)
			weave[i * NW + j] = W_TWILL23[i % 5][j % 5] == '1';
	for (int y = 0; y < NY; y++)
		for (int x = 0; x < NX; x++) {
			int jw = -1, iw = -1;
			for (int j = 0; j < NW; j++)
				if (fabs(x - (14 + 20.0 * j)) <= 7)
					jw = j;
			for (int i = 0; i < NF; i++)
				if (fabs(y - (12 + 16.0 * i)) <= 6)
					iw = i;
			if (jw >= 0 && iw >= 0)
				top[y * NX + x] = weave[iw * NW + jw] ? 1 + jw : 1 + NW + iw;
			else if (jw >= 0)
				top[y * NX + x] = 1 + jw;
			else if (iw >= 0)
				top[y * NX + x] = 1 + NW + iw;
			/* 10% label noise */
			if (synth_unit(synth_mix(seed + y * NX + x)) < 0.1)
				top[y * NX + x] = (uint8_t)(synth_mix(seed ^ (y * NX + x)) % (NW + NF + 1));
		}
	for (int k = 0; k < NW + NF; k++) {
		c[k].kind = k < NW ? LOOM_SCAN_WARP : LOOM_SCAN_WEFT;
		c[k].n = 2;
		c[k].pts = malloc(6 * sizeof(float));
		if (k < NW) {
			float x = 14 + 20.0f * k + 4;
			float p[6] = {x, 0, 10, x, NY - 1, 10};
			memcpy(c[k].pts, p, sizeof p);
		} else {
			float y = 12 + 16.0f * (k - NW) + 3;
			float p[6] = {0, y, 10, NX - 1, y, 10};
			memcpy(c[k].pts, p, sizeof p);
		}
	}
	CHECK_EQ_INT(loom_scan_register(NX, NY, top, c, NW, NF, weave, 0.0, 0, 0, &g, &d),
	             LOOM_OK);
	printf("  crop %d %d %d %d (truth %d %d), shift %d %d, first %u,%u, %ux%u, score %.3f\n",
	       g.crop[0], g.crop[1], g.crop[2], g.crop[3], 4 + 20 * (int)g.first_warp,
	       4 + 16 * (int)g.first_weft, g.shift[0], g.shift[1], g.first_warp,
	       g.first_weft, g.cols, g.rows, g.score);
	CHECK_EQ_INT(g.b1, 20);
	CHECK_EQ_INT(g.b2, 16);
	CHECK(abs(g.crop[0] - (4 + 20 * (int)g.first_warp)) <= 2);
	CHECK(abs(g.crop[1] - (4 + 16 * (int)g.first_weft)) <= 2);
	CHECK_EQ_INT(g.crop[2], (int)g.cols * 20);
	CHECK_EQ_INT(g.crop[3], (int)g.rows * 16);
	/* brute force: recompute the score of every candidate by counting the
	   central half of each cell directly: the chosen one must score what the
	   summed-area tables said, within the plateau tolerance of the best */
	{
		double best = -1, chosen = -1;
		int x0e = g.crop[0] - g.shift[0], y0e = g.crop[1] - g.shift[1];
		for (int dy = -8; dy <= 8; dy++)
			for (int dx = -10; dx <= 10; dx++) {
				int x0 = x0e + dx, y0 = y0e + dy;
				double sc = 0;
				if (x0 < 0 || y0 < 0 || x0 + g.crop[2] > NX || y0 + g.crop[3] > NY)
					continue;
				for (uint32_t i = 0; i < g.rows; i++)
					for (uint32_t j = 0; j < g.cols; j++) {
						int wv = weave[(g.first_weft + i) * NW + g.first_warp + j], agree = 0, tot = 0;
						for (int y = y0 + (int)i * 16 + 4; y < y0 + (int)i * 16 + 12; y++)
							for (int x = x0 + (int)j * 20 + 5; x < x0 + (int)j * 20 + 15; x++) {
								int lab = top[y * NX + x];
								int b = lab >= 1 && lab <= NW ? 1 : lab > NW ? 0 : 2;
								agree += b == wv;
								tot++;
							}
						sc += (double)agree / tot;
					}
				if (sc > best)
					best = sc;
				if (dx == g.shift[0] && dy == g.shift[1])
					chosen = sc;
			}
		printf("  brute force: best %.4f, chosen %.4f, tables %.4f (x %u cells)\n", best,
		       chosen, g.score * g.rows * g.cols, g.rows * g.cols);
		CHECK(fabs(chosen - g.score * g.rows * g.cols) < 1e-9);
		CHECK(chosen >= best - 0.005 * g.rows * g.cols - 1e-9);
	}
	/* too few yarns */
	CHECK_EQ_INT(loom_scan_register(NX, NY, top, c, 1, NF, weave, 0.0, 0, 0, &g, &d),
	             LOOM_EINVAL);
	for (int k = 0; k < NW + NF; k++)
		loom_scan_curve_release(&c[k]);
	free(top);
}

/* ---- the whole pipeline -------------------------------------------------- */

/* Expected complete yarns: the largest run of cells [c - s/2, c + s/2)
   around the true centres inside the footprint, ties by distance of the
   window centre to the volume centre (the rule loom_scan_register uses). */
static void expected_grid(const synth_spec *s, uint32_t *ja_o, uint32_t *cols,
                          uint32_t *ia_o, uint32_t *rows)
{
	loom_scan_sheet sh;
	loom_scan_sheet_grid g;
	uint8_t wbuf[1024];
	synth_sheet(s, &sh, wbuf);
	CHECK_EQ_INT(loom_scan_sheet_truth(&sh, &g), LOOM_OK);
	*ja_o = g.first_warp;
	*cols = g.cols;
	*ia_o = g.first_weft;
	*rows = g.rows;
}

/* Scan-frame segmentation with the result's centre curves (moved back to
   the scan frame) against the truth labels.  acc[0]: fraction of all truth
   yarn voxels labelled with the right yarn (voxels the blur pushed below the
   threshold count as wrong); acc[1]: the same over the truth yarn voxels
   that are material in the scan (density above the threshold), i.e. the
   labelling alone. */
static void scan_frame_accuracy(const synth_spec *s, const synth_out *o,
                                const loom_scan_result *r, double acc[2])
{
	CHECK_EQ_INT(synth_scan_accuracy(&o->vol, o->truth, s->nw, r, acc, 1), LOOM_OK);
}

/* Check a result against the sheet's truth; returns 1 if all good. */
static int check_result(const synth_spec *s, const synth_out *o,
                        const loom_scan_result *r)
{
	uint32_t ja = 0, cols = 0, ia = 0, rows = 0, bad = 0;
	double tx, ty, acc[2];
	int fails0 = check_fail_count;

	expected_grid(s, &ja, &cols, &ia, &rows);
	printf("  rotation %.3f (true %.3f); crop %d %d %d %d; grid %ux%u from %u,%u "
	       "(expected %ux%u from %u,%u); score %.3f\n",
	       r->rotation_degrees, s->angle_deg, r->grid.crop[0], r->grid.crop[1],
	       r->grid.crop[2], r->grid.crop[3], r->cols, r->rows, r->grid.first_warp,
	       r->grid.first_weft, cols, rows, ja, ia, r->grid.score);
	CHECK(fabs(r->rotation_degrees - s->angle_deg) <= 0.5);
	CHECK_EQ_INT(r->grid.first_warp, ja);
	CHECK_EQ_INT(r->grid.first_weft, ia);
	CHECK_EQ_INT(r->cols, cols);
	CHECK_EQ_INT(r->rows, rows);
	CHECK_EQ_INT(r->b1, (uint32_t)s->sx);
	CHECK_EQ_INT(r->b2, (uint32_t)s->sy);
	CHECK_EQ_INT(r->b3, s->nz);
	tx = s->x0 + (r->grid.first_warp - 0.5) * s->sx;
	ty = s->y0 + (r->grid.first_weft - 0.5) * s->sy;
	CHECK(fabs(r->grid.crop[0] - tx) <= 2);
	CHECK(fabs(r->grid.crop[1] - ty) <= 2);
	CHECK_EQ_INT(r->grid.crop[2], (int)(r->cols * r->b1));
	CHECK_EQ_INT(r->grid.crop[3], (int)(r->rows * r->b2));
	/* the weave, exactly */
	for (uint32_t i = 0; i < r->rows; i++)
		for (uint32_t j = 0; j < r->cols; j++)
			bad += r->weave[i * r->cols + j] !=
			       synth_w(s, r->grid.first_weft + i, r->grid.first_warp + j);
	CHECK_EQ_INT(bad, 0);
	/* the full pattern of all tracked yarns too */
	bad = 0;
	CHECK_EQ_INT(r->full_rows, s->nf);
	CHECK_EQ_INT(r->full_cols, s->nw);
	for (uint32_t i = 0; i < r->full_rows; i++)
		for (uint32_t j = 0; j < r->full_cols; j++)
			bad += r->full_weave[i * r->full_cols + j] != synth_w(s, i, j);
	CHECK_EQ_INT(bad, 0);
	/* the output volume */
	CHECK_EQ_INT(r->volume.nx, r->cols * r->b1);
	CHECK_EQ_INT(r->volume.ny, r->rows * r->b2);
	CHECK(r->volume.density && r->volume.ocode && !r->volume.orient && r->volume.label);
	CHECK_EQ_INT(r->n_yarns, s->nw + s->nf);
	for (uint32_t i = 0; i < r->n_yarns; i++) {
		const loom_scan_yarn *y = &r->yarns[i];
		int warp = i < s->nw;
		CHECK_EQ_INT(y->kind, warp ? LOOM_SCAN_WARP : LOOM_SCAN_WEFT);
		CHECK_EQ_INT(y->tracked, warp ? i : i - s->nw);
		CHECK_EQ_INT(y->index, (int)y->tracked - (int)(warp ? r->grid.first_warp
		                                                    : r->grid.first_weft));
		if (y->index >= 0 && y->index < (int)(warp ? r->cols : r->rows))
			CHECK(y->voxels > 1000); /* every yarn of the crop is in it */
	}
	/* labels of the cropped volume against the truth at the same place */
	{
		size_t tot = 0, right = 0;
		for (uint32_t z = 0; z < r->volume.nz; z++)
			for (uint32_t y = 0; y < r->volume.ny; y++)
				for (uint32_t x = 0; x < r->volume.nx; x++) {
					double sx, sy;
					long ix, iy;
					int t, L, want;
					loom_scan_aligned_to_scan(s->nx, s->ny, r->rotation_degrees,
					                          x + r->grid.crop[0], y + r->grid.crop[1], &sx, &sy);
					ix = lround(sx);
					iy = lround(sy);
					t = o->truth[((size_t)z * s->ny + iy) * s->nx + ix];
					if (!t)
						continue;
					tot++;
					L = r->volume.label[((size_t)z * r->volume.ny + y) * r->volume.nx + x];
					if (!L)
						continue;
					want = r->yarns[L - 1].kind == LOOM_SCAN_WARP
					           ? (int)r->yarns[L - 1].tracked + 1
					           : (int)(s->nw + r->yarns[L - 1].tracked + 1);
					right += want == t;
				}
		printf("  cropped volume: %.2f%% of %zu yarn voxels labelled right\n",
		       100.0 * right / tot, tot);
		CHECK((double)right / tot >= 0.95);
	}
	scan_frame_accuracy(s, o, r, acc);
	CHECK(acc[0] >= 0.96);
	CHECK(acc[1] >= 0.97);
	return check_fail_count == fails0;
}

static loom_scan_result *run_pipeline(synth_spec *s, synth_out *o,
                                      uint32_t threads, loom_diag *d)
{
	loom_scan_params p;
	loom_scan_result *r = NULL;
	int rc;

	loom_scan_params_init(&p);
	p.n_warps = s->nw;
	p.n_wefts = s->nf;
	p.threads = threads;
	rc = loom_scan_build(&o->vol, &p, &r, d);
	if (rc)
		printf("  build failed: %s\n", d->message);
	CHECK_EQ_INT(rc, LOOM_OK);
	if (r) {
		printf("  noise %.3f -> %.3f, threshold %.3f, scale %.3f, endpoint slices "
		       "y=%u x=%u; times:",
		       r->noise_before, r->noise_after, r->threshold, r->scale,
		       r->warp_ends.slice, r->weft_ends.slice);
		for (int k = 0; k < LOOM_SCAN_STEP_COUNT_; k++)
			printf(" %s %.2f", loom_scan_step_name(k), r->seconds[k]);
		printf("\n");
	}
	return r;
}

static void pipeline_weave(const char *const *w, float angle, float x0, float y0,
                           uint64_t seed)
{
	synth_spec s = synth_default(w);
	synth_out o;
	loom_diag d = {0};
	loom_scan_result *r;

	s.angle_deg = angle;
	s.x0 = x0;
	s.y0 = y0;
	s.seed = seed;
	CHECK(synth_make(&s, &o) == 0);
	r = run_pipeline(&s, &o, 2, &d);
	if (r)
		check_result(&s, &o, r);
	/* the estimated field went into the result; the scan has none */
	CHECK(o.vol.orient == NULL);
	if (r)
		CHECK_EQ_INT(r->orientation_estimated, 1);
	loom_scan_result_free(r);
	synth_free(&o);
}

static void pipeline_twill(void)
{
	pipeline_weave(W_TWILL23, 3.0f, 6, 7, 11);
}

static void pipeline_plain(void)
{
	pipeline_weave(W_PLAIN, -2.4f, 4.5f, 8.5f, 12);
}

static void pipeline_satin(void)
{
	pipeline_weave(W_SATIN14, 4.2f, 7.5f, 4.0f, 13);
}

/* Orientation given with the scan (as from a Mitsuba .vol): no estimation. */
static void pipeline_given_orientation(void)
{
	synth_spec s = synth_default(W_TWILL23);
	synth_out o;
	loom_diag d = {0};
	loom_scan_result *r;

	s.with_orient = 1;
	s.angle_deg = -3.5f;
	s.seed = 14;
	CHECK(synth_make(&s, &o) == 0);
	r = run_pipeline(&s, &o, 2, &d);
	if (r) {
		CHECK_EQ_INT(r->orientation_estimated, 0);
		check_result(&s, &o, r);
	}
	loom_scan_result_free(r);
	synth_free(&o);
}

/* block_z: the output shows scan planes z0 .. z0+b3-1 around the cloth,
   zero padded outside the scan; in place (b3 inside) or not (padding). */
static void pipeline_block_z(void)
{
	synth_spec s = synth_default(W_TWILL23);
	synth_out o;
	float *orig;
	size_t n;
	loom_scan_result *r[3] = {NULL, NULL, NULL};
	static const uint32_t bz[3] = {0, 30, 60};

	s.seed = 16;
	s.angle_deg = 2.0f;
	CHECK(synth_make(&s, &o) == 0);
	n = (size_t)s.nx * s.ny * s.nz;
	orig = malloc(n * sizeof *orig);
	memcpy(orig, o.vol.density, n * sizeof *orig);
	for (int k = 0; k < 3; k++) {
		loom_scan_params p;
		loom_diag d = {0};
		memcpy(o.vol.density, orig, n * sizeof *orig);
		loom_scan_params_init(&p);
		p.n_warps = s.nw;
		p.n_wefts = s.nf;
		p.block_z = bz[k];
		CHECK_EQ_INT(loom_scan_build(&o.vol, &p, &r[k], &d), LOOM_OK);
		CHECK(o.vol.orient == NULL);
	}
	if (r[0] && r[1] && r[2]) {
		size_t ncol = (size_t)r[0]->volume.nx * r[0]->volume.ny, lab_same = 0, lab_n = 0;
		printf("  b3 %u: z0 %d; b3 %u: z0 %d; b3 %u: z0 %d\n", r[0]->b3, r[0]->z0,
		       r[1]->b3, r[1]->z0, r[2]->b3, r[2]->z0);
		CHECK_EQ_INT(r[0]->b3, 40);
		CHECK_EQ_INT(r[0]->z0, 0);
		CHECK_EQ_INT(r[1]->b3, 30);
		CHECK_EQ_INT(r[1]->volume.nz, 30);
		CHECK(r[1]->z0 >= 4 && r[1]->z0 <= 7); /* cloth centred at z = 20 */
		CHECK_EQ_INT(r[2]->volume.nz, 60);
		CHECK(r[2]->z0 < 0);
		for (int k = 1; k < 3; k++)
			for (uint32_t z = 0; z < r[k]->b3; z++) {
				long zs = (long)r[k]->z0 + z;
				const float *a = r[k]->volume.density + z * ncol;
				const uint16_t *oa = r[k]->volume.ocode + z * ncol;
				if (zs < 0 || zs >= 40) {
					int zero = 1;
					for (size_t q = 0; q < ncol; q++)
						zero &= a[q] == 0 && oa[q] == 0 && r[k]->volume.label[z * ncol + q] == 0;
					CHECK(zero);
					continue;
				}
				CHECK(memcmp(a, r[0]->volume.density + zs * ncol, ncol * sizeof(float)) == 0);
				CHECK(memcmp(oa, r[0]->volume.ocode + zs * ncol,
				             ncol * sizeof(uint16_t)) == 0);
				for (size_t q = 0; q < ncol; q++) {
					lab_same += r[k]->volume.label[z * ncol + q] ==
					            r[0]->volume.label[zs * ncol + q];
					lab_n++;
				}
			}
		printf("  labels equal on %.4f%% of the shared voxels\n", 100.0 * lab_same / lab_n);
		CHECK(lab_same >= lab_n - lab_n / 1000);
	}
	for (int k = 0; k < 3; k++)
		loom_scan_result_free(r[k]);
	free(orig);
	synth_free(&o);
}

/* Same input, 1 or 2 threads: the same bytes. */
static void pipeline_deterministic(void)
{
	synth_spec s = synth_default(W_SATIN14);
	synth_out a, b;
	loom_diag d = {0};
	loom_scan_result *ra, *rb;
	size_t n;

	s.angle_deg = 1.5f;
	s.seed = 15;
	CHECK(synth_make(&s, &a) == 0);
	CHECK(synth_make(&s, &b) == 0);
	ra = run_pipeline(&s, &a, 1, &d);
	rb = run_pipeline(&s, &b, 2, &d);
	if (ra && rb) {
		n = (size_t)ra->volume.nx * ra->volume.ny * ra->volume.nz;
		CHECK(ra->volume.nx == rb->volume.nx && ra->volume.ny == rb->volume.ny);
		CHECK(memcmp(ra->volume.density, rb->volume.density, n * sizeof(float)) == 0);
		CHECK(memcmp(ra->volume.ocode, rb->volume.ocode, n * sizeof(uint16_t)) == 0);
		CHECK(memcmp(ra->volume.label, rb->volume.label, n) == 0);
		CHECK(ra->rotation_degrees == rb->rotation_degrees);
		CHECK(memcmp(ra->grid.crop, rb->grid.crop, sizeof ra->grid.crop) == 0);
		CHECK(memcmp(ra->linking, rb->linking,
		             ra->full_rows * ra->full_cols * sizeof(float)) == 0);
		for (uint32_t i = 0; i < ra->n_yarns; i++)
			CHECK(ra->yarns[i].n_points == rb->yarns[i].n_points &&
			      memcmp(ra->yarns[i].points, rb->yarns[i].points,
			             3 * ra->yarns[i].n_points * sizeof(float)) == 0);
	}
	loom_scan_result_free(ra);
	loom_scan_result_free(rb);
	synth_free(&a);
	synth_free(&b);
}

/* Wrong yarn counts are errors that say so, not garbage exemplars.  The
   scan is denoised and oriented once; reruns skip denoising. */
static void wrong_yarn_counts(void)
{
	static const char *const *weaves[3] = {W_PLAIN, W_TWILL23, W_SATIN14};
	static const int dw[4] = {-1, 1, 0, 0}, df[4] = {0, 0, -1, 1};

	for (int w = 0; w < 3; w++) {
		synth_spec s = synth_default(weaves[w]);
		synth_out o;
		loom_scan_params p;
		loom_diag d = {0};
		loom_scan_result *r = NULL;

		s.seed = 20 + w;
		CHECK(synth_make(&s, &o) == 0);
		loom_scan_params_init(&p);
		p.n_warps = s.nw;
		p.n_wefts = s.nf;
		/* denoise and orient once, so every build below skips both */
		{
			float thr;
			size_t nv = (size_t)s.nx * s.ny * s.nz;
			CHECK_EQ_INT(loom_scan_denoise(&o.vol, p.denoise_sigma, 2, &d), LOOM_OK);
			CHECK_EQ_INT(loom_scan_threshold(&o.vol, &thr, &d), LOOM_OK);
			o.vol.orient = malloc(3 * nv * sizeof(float));
			CHECK_EQ_INT(loom_scan_orient(&o.vol, thr, p.tensor_sigma, 2, NULL, &d),
			             LOOM_OK);
		}
		p.denoise_sigma = 0;
		CHECK_EQ_INT(loom_scan_build(&o.vol, &p, &r, &d), LOOM_OK);
		CHECK(r && r->orientation_estimated == 0);
		loom_scan_result_free(r);
		for (int k = 0; k < 4; k++) {
			int rc;
			p.n_warps = s.nw + dw[k];
			p.n_wefts = s.nf + df[k];
			r = NULL;
			rc = loom_scan_build(&o.vol, &p, &r, &d);
			printf("  weave %d, %u warps x %u wefts (true %u x %u): %s\n", w,
			       p.n_warps, p.n_wefts, s.nw, s.nf, rc ? d.message : "accepted");
			CHECK_EQ_INT(rc, LOOM_EMISMATCH);
			CHECK(r == NULL);
			CHECK_STR_CONTAINS(d.message, "scan: ");
		}
		synth_free(&o);
	}
}

/* Pure noise and an empty volume give errors. */
static void bad_scans(void)
{
	synth_spec s = synth_default(W_TWILL23);
	synth_out o;
	loom_scan_params p;
	loom_diag d = {0};
	loom_scan_result *r = NULL;
	int rc;

	s.pure_noise = 1;
	s.seed = 99;
	CHECK(synth_make(&s, &o) == 0);
	loom_scan_params_init(&p);
	p.n_warps = s.nw;
	p.n_wefts = s.nf;
	rc = loom_scan_build(&o.vol, &p, &r, &d);
	printf("  pure noise: %s (%s)\n", loom_strerror(rc), rc ? d.message : "");
	CHECK(rc == LOOM_EUNSUPPORTED || rc == LOOM_EMISMATCH);
	CHECK(r == NULL);
	synth_free(&o);

	/* empty (all zero) volume */
	{
		loom_scan_volume v;
		CHECK_EQ_INT(loom_scan_volume_alloc(&v, 64, 64, 16, LOOM_SCAN_DENSITY), LOOM_OK);
		p.n_warps = 3;
		p.n_wefts = 3;
		rc = loom_scan_build(&v, &p, &r, &d);
		printf("  empty volume: %s (%s)\n", loom_strerror(rc), d.message);
		CHECK_EQ_INT(rc, LOOM_EUNSUPPORTED);
		CHECK(r == NULL);
		loom_scan_volume_release(&v);
	}
	/* very noisy sheet: either right or an error, never a wrong weave */
	{
		synth_spec n = synth_default(W_TWILL23);
		n.noise = 0.4f;
		n.seed = 98;
		CHECK(synth_make(&n, &o) == 0);
		p.n_warps = n.nw;
		p.n_wefts = n.nf;
		rc = loom_scan_build(&o.vol, &p, &r, &d);
		printf("  noise 0.4: %s (%s)\n", loom_strerror(rc), rc ? d.message : "");
		if (rc == LOOM_OK) {
			uint32_t bad = 0;
			for (uint32_t i = 0; i < r->rows; i++)
				for (uint32_t j = 0; j < r->cols; j++)
					bad += r->weave[i * r->cols + j] !=
					       synth_w(&n, r->grid.first_weft + i, r->grid.first_warp + j);
			CHECK_EQ_INT(bad, 0);
		}
		loom_scan_result_free(r);
		synth_free(&o);
	}
}

int main(void)
{
	CHECK_MAIN_BEGIN("test_scan");
	RUN(params_and_bad_args);
	RUN(denoise_matches_reference);
	RUN(noise_and_threshold);
	RUN(eigen_matches_jacobi);
	RUN(orientation_accuracy);
	RUN(linking_closed_form_vs_quadrature);
	RUN(weave_from_linking_sign);
	RUN(align_known_rotation);
	RUN(register_against_brute_force);
	RUN(pipeline_twill);
	RUN(pipeline_plain);
	RUN(pipeline_satin);
	RUN(pipeline_given_orientation);
	RUN(pipeline_block_z);
	RUN(pipeline_deterministic);
	RUN(wrong_yarn_counts);
	RUN(bad_scans);
	CHECK_MAIN_END();
}
