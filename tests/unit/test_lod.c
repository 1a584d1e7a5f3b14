/*
 * tests/unit/test_lod.c - level of detail (engine/texture/lod.c): every
 * coarse voxel of levels 1..3, read through the brick cache, equals a
 * brute-force box filter of the level-0 exemplar (read with
 * loom_db_read_box, filtered here in double with its own eigen solver; the
 * density fitted to the fine transmittance along 13 directions, ref_density,
 * whose transmittance error beats the old axis-only rule's); coarse lookups of the
 * synthesized fabric agree with that filter of its full-resolution lookups
 * away from block edges; a texture opened without
 * options.lod has no levels and sample_lod at level 0 is sample itself.
 */
#include "check.h"
#include "tmpdir.h"
#include "loom.h"
#include "texture/texture_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char db_path[4200], db4_path[4200];

/* The old axis-only rule (before the direction fit), kept to show what
   the fit buys: the density d whose uniform box transmits as much along
   the axes as b (index (x * n + y) * n + z), exp(-sigma n d) = mean over
   the 3 n^2 axis columns of exp(-sigma (column sum)), rounded, at most
   the rounded mean, at least 1. */
static uint8_t old_density(const uint8_t *b, uint32_t n, uint64_t sum, double sigma)
{
	uint64_t n3 = (uint64_t)n * n * n, mean = (sum + n3 / 2) / n3;
	double t = 0, d;

	for (int a = 0; a < 3; a++)
		for (uint32_t i = 0; i < n; i++)
			for (uint32_t j = 0; j < n; j++) {
				uint64_t c = 0;
				for (uint32_t m = 0; m < n; m++) {
					uint32_t x = a == 0 ? m : i, y = a == 0 ? i : a == 1 ? m : j,
					         z = a == 2 ? m : j;
					c += b[((size_t)x * n + y) * n + z];
				}
				t += exp(-sigma * (double)c);
			}
	t /= 3.0 * n * n;
	if (!(t > 1e-300))
		return (uint8_t)mean;
	d = floor(-log(t) / (sigma * n) + 0.5);
	d = d > (double)mean ? (double)mean : d;
	return (uint8_t)(d < 1 ? 1 : d);
}

/* The 13 directions, written out from docs/rendering.md: axes, face and
   body diagonals, as voxel steps. */
static const int dirs[13][3] = {{1, 0, 0},  {0, 1, 0},  {0, 0, 1},  {1, 1, 0},  {1, -1, 0},
                                {1, 0, 1},  {1, 0, -1}, {0, 1, 1},  {0, 1, -1}, {1, 1, 1},
                                {1, 1, -1}, {1, -1, 1}, {1, -1, -1}};

/* Projected area (docs/rendering.md): sqrt(sin^2 + (pi/2) s^2), s 0.2. */
static double area(const double w[3], const double v[3])
{
	double c = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
	return sqrt(fmax(0, 1 - c * c) + M_PI / 2 * 0.2 * 0.2);
}

/* The fine box b (fibre directions v) along each direction j: its mean
   transmittance tf[j] over the n^2 wrapped paths of n voxel steps, each
   voxel's path found by stepping back to the face its first nonzero step
   axis leaves (x = 0 for (1, -1, 0)); and len[j] = |step|. */
static void fine_paths(const uint8_t *b, const double (*v)[3], uint32_t n, double sigma,
                       double tf[13], double len[13], double eb[13])
{
	for (int j = 0; j < 13; j++) {
		const int *g = dirs[j];
		int a = g[0] ? 0 : g[1] ? 1 : 2;
		double tau[64] = {0}, w[3], t = 0, es = 0;
		len[j] = sqrt((double)(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]));
		for (int r = 0; r < 3; r++)
			w[r] = g[r] / len[j];
		for (uint32_t x = 0; x < n; x++)
			for (uint32_t y = 0; y < n; y++)
				for (uint32_t z = 0; z < n; z++) {
					int64_t p[3] = {x, y, z}, m = p[a], q[3];
					size_t i = ((size_t)x * n + y) * n + z;
					if (!b[i])
						continue;
					for (int r = 0; r < 3; r++)
						q[r] = ((p[r] - m * g[r]) % (int64_t)n + n) % n;
					/* the path is named by its start's other two coordinates */
					tau[(a == 0 ? q[1] * n + q[2] : a == 1 ? q[0] * n + q[2]
					                                      : q[0] * n + q[1])] +=
					        b[i] * area(w, v[i]);
				}
		for (uint32_t k = 0; k < n * n; k++) {
			t += exp(-sigma * len[j] * tau[k]);
			es += tau[k];
		}
		tf[j] = t / (n * n);
		eb[j] = es / ((double)n * n * n);
	}
}

/* The coarse density byte (docs/rendering.md): least squares in log over
   the 13 directions of D A(w, vc) against -log tf / (sigma n |w|),
   rounded to [1, 255]. */
static uint8_t ref_density(const uint8_t *b, const double (*v)[3], uint32_t n,
                           const double vc[3], double sigma)
{
	double tf[13], len[13], eb[13], num = 0, den = 0, D;
	fine_paths(b, v, n, sigma, tf, len, eb);
	for (int j = 0; j < 13; j++) {
		double w[3], aw, bw;
		for (int r = 0; r < 3; r++)
			w[r] = dirs[j][r] / len[j];
		aw = area(w, vc);
		bw = tf[j] > 1e-300 ? -log(tf[j]) / (sigma * n * len[j]) : eb[j];
		num += aw * bw;
		den += aw * aw;
	}
	D = floor(num / den + 0.5);
	return (uint8_t)(D < 1 ? 1 : D > 255 ? 255 : D);
}

/* Mean over the 13 directions of |fine mean transmittance - coarse
   transmittance exp(-sigma n |w| D A(w, vc))| of coarse byte D. */
static double trans_err(const uint8_t *b, const double (*v)[3], uint32_t n,
                        const double vc[3], double sigma, uint8_t D)
{
	double tf[13], len[13], eb[13], e = 0;
	fine_paths(b, v, n, sigma, tf, len, eb);
	for (int j = 0; j < 13; j++) {
		double w[3];
		for (int r = 0; r < 3; r++)
			w[r] = dirs[j][r] / len[j];
		e += fabs(tf[j] - exp(-sigma * n * len[j] * D * area(w, vc)));
	}
	return e / 13;
}

/* Mean transmittance error over the 13 directions per coarse voxel that
   the direction fit stays under and the axis-only rule does not. */
#define LOD_TERR_BOUND 0.09

static double db_sigma(loom_db *db)
{
	loom_db_info di;
	if (loom_db_get_info(db, &di) != LOOM_OK)
		return 0;
	return LOOM__LOD_EXTINCTION_MM * di.voxel_size_um * 1e-3 / 255.0;
}

static int make_db(const char *path, const uint32_t brick[3])
{
	loom_exgen_params p;
	loom_diag d = {0};
	int rc = loom_exgen_preset("tiny", &p);
	if (rc)
		return rc;
	p.seed = 7;
	p.threads = 2;
	memcpy(p.brick, brick, sizeof p.brick);
	rc = loom_exgen_write_db(path, &p, NULL, &d);
	if (rc)
		printf("  exgen: %s\n", d.message);
	return rc;
}

static loom_fabric *synth(loom_db *db, const char *path)
{
	loom_design *d = NULL;
	loom_fabric *f = NULL;
	loom_diag dg = {0};

	if (loom_design_new(6, 8, &d) || loom_design_set_types(d, 2))
		return NULL;
	for (size_t i = 0; i < 48; i++) {
		d->weave[i] = (uint8_t)((i / 8 + i % 8) % 3 == 0); /* a twill */
		d->warp_type[i] = 0;
		d->weft_type[i] = 1;
	}
	for (int k = 0; k < 2; k++) {
		d->types[k].albedo[0] = 0.2f + 0.6f * k;
		d->types[k].albedo[1] = 0.5f;
		d->types[k].albedo[2] = 0.8f - 0.6f * k;
		d->types[k].alignment = 0.2f;
	}
	if (loom_fabric_synthesize(d, db, path, NULL, &f, &dg))
		printf("  synthesize: %s\n", dg.message);
	loom_design_free(d);
	return f;
}

static loom_texture *open_tex(const loom_fabric *f, const loom_db *db, int lod)
{
	loom_texture_options o = LOOM_TEXTURE_OPTIONS_INIT;
	loom_texture *t = NULL;
	loom_diag d = {0};

	o.budget_bytes = 16u << 20;
	o.max_threads = 2;
	o.lod = lod;
	if (loom_texture_open(f, db, &o, &t, &d))
		printf("  texture: %s\n", d.message);
	return t;
}

static void decode(uint16_t code, double v[3])
{
	double s = (code & 0xff) / 127.5 - 1, t = (code >> 8) / 127.5 - 1;
	double px = (s + t) / 2, py = (s - t) / 2, pz = 1 - fabs(px) - fabs(py), n;
	if (pz < 0)
		pz = 0;
	n = sqrt(px * px + py * py + pz * pz);
	v[0] = px / n;
	v[1] = py / n;
	v[2] = pz / n;
}

/* Largest eigenvalue and its vector of symmetric m by power iteration on
   m + tr I (positive definite), from each axis; the best Rayleigh
   quotient.  Also the second eigenvalue (trace - l1 - l3 via deflation). */
static double power_max(const double m[9], double v[3], double *l2)
{
	double best = -1, tr = m[0] + m[4] + m[8];
	for (int s = 0; s < 3; s++) {
		double x[3] = {s == 0, s == 1, s == 2}, q;
		for (int it = 0; it < 2000; it++) {
			double y[3], n;
			for (int r = 0; r < 3; r++)
				y[r] = m[3 * r] * x[0] + m[3 * r + 1] * x[1] + m[3 * r + 2] * x[2] +
				       tr * x[r];
			n = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
			if (!(n > 0))
				break;
			for (int r = 0; r < 3; r++)
				x[r] = y[r] / n;
		}
		q = 0;
		for (int r = 0; r < 3; r++)
			for (int c = 0; c < 3; c++)
				q += x[r] * m[3 * r + c] * x[c];
		if (q > best) {
			best = q;
			memcpy(v, x, sizeof x);
		}
	}
	{ /* deflate and iterate again for the second */
		double d[9], w[3];
		for (int r = 0; r < 3; r++)
			for (int c = 0; c < 3; c++)
				d[3 * r + c] = m[3 * r + c] - best * v[r] * v[c];
		double x[3] = {0.577, 0.5, 0.646}, q = 0;
		for (int it = 0; it < 2000; it++) {
			double y[3], n;
			for (int r = 0; r < 3; r++)
				y[r] = d[3 * r] * x[0] + d[3 * r + 1] * x[1] + d[3 * r + 2] * x[2] +
				       tr * x[r];
			n = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
			for (int r = 0; r < 3; r++)
				x[r] = y[r] / n;
		}
		memcpy(w, x, sizeof w);
		for (int r = 0; r < 3; r++)
			for (int c = 0; c < 3; c++)
				q += w[r] * d[3 * r + c] * w[c];
		*l2 = q;
	}
	return best;
}

/* Every coarse voxel of every level against the brute-force filter. */
static void levels_equal_box_filter(const char *path, unsigned want_levels)
{
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL;
	loom_db_exemplar_info ei;
	uint8_t *den = NULL, *lab = NULL;
	uint16_t *ori = NULL;
	long checked = 0, dens_bad = 0, lab_bad = 0, an_bad = 0, dir_bad = 0, dir_n = 0,
	     nonempty = 0, lowered = 0, off1 = 0;
	double worst = 0, err_new = 0, err_old = 0;

	CHECK_EQ_INT(loom_db_open(path, &db, NULL), LOOM_OK);
	if (!db)
		return;
	f = synth(db, path);
	CHECK(f != NULL);
	t = f ? open_tex(f, db, 1) : NULL;
	CHECK(t != NULL);
	if (!t)
		goto out;
	CHECK_EQ_INT((int)loom_texture_lod_levels(t), (int)want_levels);
	for (uint32_t u = 0; u < 2; u++) {
		uint32_t org[3] = {0, 0, 0}, sz[3];
		size_t nv;
		CHECK_EQ_INT(loom_db_exemplar(db, u, &ei), LOOM_OK);
		memcpy(sz, ei.size, sizeof sz);
		nv = (size_t)sz[0] * sz[1] * sz[2];
		den = malloc(nv);
		lab = malloc(nv);
		ori = malloc(2 * nv);
		CHECK_EQ_INT(loom_db_read_box(db, u, org, sz, den, ori, lab, NULL), LOOM_OK);
		for (unsigned k = 1; k <= want_levels; k++) {
			uint32_t n = 1u << k, ls[3];
			for (int a = 0; a < 3; a++)
				ls[a] = (sz[a] + n - 1) / n;
			for (uint32_t Z = 0; Z < ls[2]; Z++)
				for (uint32_t Y = 0; Y < ls[1]; Y++)
					for (uint32_t X = 0; X < ls[0]; X++) {
						uint64_t sum = 0;
						uint8_t bx[8 * 8 * 8] = {0};
						double fv[8 * 8 * 8][3], T[9] = {0}, kw[3] = {0, 0, 0};
						uint8_t best[3] = {0, 0, 0}, bestd[3] = {0, 0, 0}, got[5],
						        want_d, want_l;
						/* brick order: y, x, then z fastest */
						for (uint32_t y = Y * n; y < Y * n + n; y++)
							for (uint32_t x = X * n; x < X * n + n; x++)
								for (uint32_t z = Z * n; z < Z * n + n; z++) {
									size_t i;
									double v[3];
									uint8_t d, l, kd;
									if (x >= sz[0] || y >= sz[1] || z >= sz[2])
										continue;
									i = ((size_t)z * sz[1] + y) * sz[0] + x;
									d = den[i];
									if (!d)
										continue;
									l = lab[i];
									sum += d;
									decode(ori[i], v);
									{
										size_t q = ((x - X * n) * n + (y - Y * n)) * n +
										           (z - Z * n);
										bx[q] = d;
										memcpy(fv[q], v, sizeof v);
									}
									for (int r = 0; r < 3; r++)
										for (int c = 0; c < 3; c++)
											T[3 * r + c] += d * v[r] * v[c];
									kd = l <= ei.n_yarns && ei.yarns[l].kind <= 2
									             ? ei.yarns[l].kind
									             : 0;
									kw[kd] += d;
									if (d > bestd[kd]) {
										bestd[kd] = d;
										best[kd] = l;
									}
								}
						CHECK_EQ_INT(loom__lod_voxel(t, u, k, X, Y, Z, got), LOOM_OK);
						checked++;
						if (!sum) {
							if (got[0] || got[1] || got[2] || got[3] || got[4])
								dens_bad++;
							continue;
						}
						nonempty++;
						{ /* the coarse axis as the renderer decodes it */
							double vc[3], sg = db_sigma(db);
							uint8_t od = old_density(bx, n, sum, sg);
							decode((uint16_t)(got[1] | got[2] << 8), vc);
							want_d = ref_density(bx, (const double(*)[3])fv, n, vc, sg);
							/* float decoding in lod.c against double here */
							dens_bad += abs((int)got[0] - (int)want_d) > 1;
							off1 += got[0] != want_d;
							err_new += trans_err(bx, (const double(*)[3])fv, n, vc, sg,
							                     want_d);
							err_old += trans_err(bx, (const double(*)[3])fv, n, vc, sg, od);
						}
						/* below the box mean: gaps kept open */
						lowered += want_d < (sum + (uint64_t)n * n * n / 2) / ((uint64_t)n * n * n);
						{
							int kd = kw[2] > kw[1] ? 2 : kw[1] > 0 ? 1 : 0;
							want_l = best[kd];
							lab_bad += got[3] != want_l;
						}
						{
							double v[3], w[3], l2, tr = T[0] + T[4] + T[8];
							double l1 = power_max(T, v, &l2);
							double a = (3 * l1 / tr - 1) / 2, ang;
							a = a < 0 ? 0 : a > 1 ? 1 : a;
							an_bad += abs((int)got[4] - (int)lround(a * 255)) > 1;
							/* the direction is defined where l1 stands out */
							if (l1 - l2 > 0.05 * tr) {
								decode((uint16_t)(got[1] | got[2] << 8), w);
								ang = acos(fmin(1, fabs(v[0] * w[0] + v[1] * w[1] +
								                        v[2] * w[2]))) *
								      180 / M_PI;
								dir_n++;
								if (ang > worst)
									worst = ang;
								dir_bad += ang > 0.6;
							}
						}
					}
		}
		free(den);
		free(lab);
		free(ori);
		den = lab = NULL;
		ori = NULL;
	}
	printf("  %s: %ld coarse voxels (%ld with density, %ld below the box mean), %ld "
	       "directions, worst %.3f deg\n",
	       path + strlen(tmpdir) + 1, checked, nonempty, lowered, dir_n, worst);
	printf("  density: %ld off by one (float decoding); mean transmittance error over "
	       "13 directions %.4f (axis-only rule %.4f)\n",
	       off1, err_new / (double)(nonempty ? nonempty : 1),
	       err_old / (double)(nonempty ? nonempty : 1));
	CHECK(nonempty > 100);
	CHECK(lowered > nonempty / 4);
	CHECK(off1 <= nonempty / 1000);
	CHECK(err_new < LOD_TERR_BOUND * (double)nonempty);
	CHECK(err_old > LOD_TERR_BOUND * (double)nonempty);
	CHECK(dir_n > 50);
	CHECK_EQ_INT((int)dens_bad, 0);
	CHECK_EQ_INT((int)lab_bad, 0);
	CHECK_EQ_INT((int)an_bad, 0);
	CHECK_EQ_INT((int)dir_bad, 0);
	CHECK_EQ_INT(loom__lod_voxel(t, 0, want_levels + 1, 0, 0, 0, (uint8_t[5]){0}),
	             LOOM_EINVAL);
out:
	loom_texture_close(t);
	loom_fabric_free(f);
	loom_db_close(db);
}

static void levels_8x8x16(void)
{
	levels_equal_box_filter(db_path, 3);
}

static void levels_4x4x8(void)
{
	levels_equal_box_filter(db4_path, 2); /* 2^3 does not divide 4 */
}

/* Coarse lookups of the fabric against a box filter of its full-resolution
   lookups: the density at coarse-voxel centres, away from block edges. */
static void lookups_match_synthesized(void)
{
	loom_db *db = NULL;
	loom_fabric *f = NULL;
	loom_texture *t = NULL, *t0 = NULL;
	uint32_t b[3];
	double sum_err = 0, worst = 0;
	long n = 0, far = 0;

	CHECK_EQ_INT(loom_db_open(db_path, &db, NULL), LOOM_OK);
	f = db ? synth(db, db_path) : NULL;
	CHECK(f != NULL);
	if (!f)
		goto out;
	t = open_tex(f, db, 1);
	t0 = open_tex(f, db, 0);
	CHECK(t && t0);
	if (!t || !t0)
		goto out;
	CHECK_EQ_INT((int)loom_texture_lod_levels(t0), 0);
	{
		loom_fabric_db_identity id;
		CHECK_EQ_INT(loom_fabric_get_db_identity(f, &id), LOOM_OK);
		memcpy(b, id.block, sizeof b);
	}
	for (unsigned k = 1; k <= 2; k++) {
		int64_t s = 1 << k;
		for (int64_t Y = 0; Y < 6 * (int64_t)b[1] / s; Y++)
			for (int64_t X = 0; X < 8 * (int64_t)b[0] / s; X++)
				for (int64_t Z = 0; Z < (int64_t)b[2] / s; Z++) {
					int64_t x0 = X * s, y0 = Y * s, z0 = Z * s;
					int64_t bx = x0 % b[0], by = y0 % b[1];
					double p[3] = {(double)x0 + s / 2.0, (double)y0 + s / 2.0,
					               (double)z0 + s / 2.0},
					       box = 0, e;
					loom_texel tx, ta, tb;
					float spread = -1;
					/* away from block edges: the box and a voxel margin */
					if (bx < 2 || by < 2 || bx + s + 2 > b[0] || by + s + 2 > b[1])
						continue;
					{
						uint8_t bb[8 * 8 * 8];
						double bv[8 * 8 * 8][3];
						uint64_t sum = 0;
						for (int64_t y = y0; y < y0 + s; y++)
							for (int64_t x = x0; x < x0 + s; x++)
								for (int64_t z = z0; z < z0 + s; z++) {
									loom_texel v;
									CHECK_EQ_INT(loom_texture_voxel(t0, x, y, z, &v),
									             LOOM_OK);
									bb[((x - x0) * s + (y - y0)) * s + (z - z0)] =
									        (uint8_t)lround(v.density * 255);
									for (int r = 0; r < 3; r++)
										bv[((x - x0) * s + (y - y0)) * s + (z - z0)][r] =
										        v.orientation[r];
									sum += bb[((x - x0) * s + (y - y0)) * s + (z - z0)];
								}
						CHECK_EQ_INT(loom_texture_sample_lod(t, p, LOOM_FILTER_NEAREST,
						                                     k, &tx, &spread),
						             LOOM_OK);
						{ /* the coarse axis the lookup returns */
							double vc[3] = {tx.orientation[0], tx.orientation[1],
							                tx.orientation[2]};
							box = sum ? ref_density(bb, (const double(*)[3])bv,
							                        (uint32_t)s, vc, db_sigma(db)) /
							                    255.0
							          : 0;
						}
					}
					CHECK(spread == 0); /* the lobe is not widened (lod.c) */
					e = fabs(tx.density - box);
					sum_err += e;
					worst = e > worst ? e : worst;
					far += e > 0.25;
					n++;
					/* level 0 through sample_lod is sample itself */
					if (Z == 1) {
						CHECK_EQ_INT(loom_texture_sample_lod(t, p, LOOM_FILTER_TRILINEAR,
						                                     0, &ta, &spread),
						             LOOM_OK);
						CHECK_EQ_INT(loom_texture_sample(t0, p, LOOM_FILTER_TRILINEAR,
						                                 &tb),
						             LOOM_OK);
						CHECK(memcmp(&ta, &tb, sizeof ta) == 0 && spread == 0);
					}
				}
	}
	printf("  %ld coarse lookups: mean |error| %.4f, worst %.3f, %ld above 0.25\n", n,
	       n ? sum_err / n : 0, worst, far);
	CHECK(n > 100);
	CHECK(sum_err / (double)(n ? n : 1) < 0.01);
	CHECK(worst < 0.05);
	CHECK_EQ_INT((int)far, 0);
out:
	loom_texture_close(t);
	loom_texture_close(t0);
	loom_fabric_free(f);
	loom_db_close(db);
}

int main(void)
{
	const uint32_t brick[3] = {8, 8, 16}, brick4[3] = {4, 4, 8};

	CHECK_MAIN_BEGIN("test_lod");
	RUN(tmpdir_setup);
	if (!tmpdir[0])
		return 1;
	snprintf(db_path, sizeof db_path, "%s/b8.ldb", tmpdir);
	snprintf(db4_path, sizeof db4_path, "%s/b4.ldb", tmpdir);
	CHECK_EQ_INT(make_db(db_path, brick), LOOM_OK);
	CHECK_EQ_INT(make_db(db4_path, brick4), LOOM_OK);
	RUN(levels_8x8x16);
	RUN(levels_4x4x8);
	RUN(lookups_match_synthesized);
	RUN(tmpdir_remove);
	CHECK_MAIN_END();
}
