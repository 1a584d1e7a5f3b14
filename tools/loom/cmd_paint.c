/*
 * tools/loom/cmd_paint.c - `loom paint`: add a painted region (yarn
 * colour, stain or defect; a rectangle in cloth millimetres or a mask
 * image) to a fabric, writing a paint file (docs/fabric.md "Painted
 * regions", docs/formats.md "Paint file").  Also the paint-file reader
 * the commands share (paintfile.h).
 */
#include "cli.h"
#include "commands.h"
#include "opts.h"
#include "paintfile.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int cli_is_paint(const char *path)
{
	static const char magic[] = "loom-paint ";
	char buf[sizeof magic];
	struct stat st;
	int fd = open(path, O_RDONLY | O_NONBLOCK), ok;

	if (fd < 0)
		return 0;
	ok = fstat(fd, &st) == 0 && S_ISREG(st.st_mode) &&
	     read(fd, buf, sizeof buf) == (ssize_t)sizeof buf &&
	     !memcmp(buf, magic, sizeof magic - 1) &&
	     buf[sizeof magic - 1] >= '1' && buf[sizeof magic - 1] <= '3';
	close(fd);
	return ok;
}

int cli_paint_read(const char *path, loom_paint **out, loom_diag *diag)
{
	struct stat st;
	char *buf;
	size_t n = 0;
	int fd, rc;

	*out = NULL;
	fd = open(path, O_RDONLY | O_NONBLOCK);
	if (fd < 0) {
		snprintf(diag->message, sizeof diag->message, "%s: %s", path, strerror(errno));
		return LOOM_EIO;
	}
	if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
		close(fd);
		snprintf(diag->message, sizeof diag->message, "%s: not a regular file", path);
		return LOOM_EIO;
	}
	if (st.st_size > (off_t)LOOM_PAINT_MAX_FILE) {
		close(fd);
		snprintf(diag->message, sizeof diag->message, "%s: %lld bytes, more than "
		         "the %u a paint file may have", path, (long long)st.st_size,
		         LOOM_PAINT_MAX_FILE);
		return LOOM_ERANGE;
	}
	buf = malloc((size_t)st.st_size + 1);
	if (!buf) {
		close(fd);
		snprintf(diag->message, sizeof diag->message, "%s: out of memory", path);
		return LOOM_ENOMEM;
	}
	while (n < (size_t)st.st_size) {
		ssize_t k = read(fd, buf + n, (size_t)st.st_size - n);
		if (k < 0 && errno == EINTR)
			continue;
		if (k <= 0)
			break;
		n += (size_t)k;
	}
	close(fd);
	if (n != (size_t)st.st_size) {
		free(buf);
		snprintf(diag->message, sizeof diag->message, "%s: read error", path);
		return LOOM_EIO;
	}
	rc = loom_paint_parse(buf, n, path, out, diag);
	free(buf);
	return rc;
}

int cli_open_painted(const char *path, loom_db *db, loom_fabric **f,
                     loom_paint **paint, loom_diag *diag)
{
	int rc;

	*paint = NULL;
	if (!cli_is_paint(path))
		return loom_fabric_open(path, db, 0, f, diag);
	if ((rc = cli_paint_read(path, paint, diag)) != LOOM_OK)
		return rc;
	if ((rc = loom_fabric_open(loom_paint_fabric(*paint), db, 0, f, diag)) != LOOM_OK) {
		char msg[sizeof diag->message];
		memcpy(msg, diag->message, sizeof msg);
		snprintf(diag->message, sizeof diag->message, "%.200s: its fabric: %.280s", path, msg);
		loom_paint_free(*paint);
		*paint = NULL;
		return rc;
	}
	/* painted weaves re-synthesise crossings: the fabric carries them */
	if ((rc = loom_paint_apply_weaves(*paint, f, diag)) != LOOM_OK) {
		char msg[sizeof diag->message];
		memcpy(msg, diag->message, sizeof msg);
		snprintf(diag->message, sizeof diag->message, "%.200s: %.280s", path, msg);
		loom_fabric_free(*f);
		*f = NULL;
		loom_paint_free(*paint);
		*paint = NULL;
	}
	return rc;
}

void cli_paint_note(const char *prog, const char *path, const loom_paint *p)
{
	uint32_t other = 0;

	for (uint32_t i = 0; i < loom_paint_count(p); i++)
		other += loom_paint_get(p, i)->effect != LOOM_PAINT_WEAVE &&
		         loom_paint_get(p, i)->effect != LOOM_PAINT_FIBRE;
	if (other)
		fprintf(stderr, "%s: warning: %s: %u region%s of colour or defect "
		        "(applied at lookup time) not shown by this command (loom render, "
		        "preview, export and serve show them); painted weaves and "
		        "fibres are shown\n", prog, path, other, other == 1 ? "" : "s");
}

/* ---- loom paint ------------------------------------------------------------ */

static const char usage[] =
	"loom paint FABRIC (--rect X0,Y0:X1,Y1 | --mask PNG [--at X,Y]\n"
	"           [--cell W,H]) (--yarn warp|weft|any [--rgb R,G,B]\n"
	"           [--fibre F [--band N]] |\n"
	"            --weave WEAVE|DESIGN [--band N] |\n"
	"            --defect stain|slub|broken-end|missing-pick|pull)\n"
	"           [--rgb R,G,B] [--strength S] [--blend MM] [--radius V]\n"
	"           [--lift V] [--kind warp|weft] [--db DB] [--quiet] -o PAINT\n";

static const char about[] =
	"Paint a region of the cloth: recolour a yarn kind or change its fibre\n"
	"material, stain it, weave it in another weave (a new fibre or weave:\n"
	"its crossings and a band around them re-synthesised),\n"
	"or add a defect (slub, broken end, missing pick, pulled thread).  FABRIC is a\n"
	"fabric or a paint file (its regions are kept and the new one added);\n"
	"PAINT is a paint file naming the fabric, which loom render opens like a\n"
	"fabric and evaluates at lookup time (docs/fabric.md).  Coordinates are\n"
	"cloth millimetres: x across (ends), y along the warps.\n";

static const opt_choice kind_names[] = {
	{"any", 0}, {"warp", LOOM_YARN_WARP}, {"weft", LOOM_YARN_WEFT}, {NULL, 0}};
static const opt_choice defect_names[] = {
	{"stain", LOOM_PAINT_STAIN}, {"slub", LOOM_PAINT_SLUB},
	{"broken-end", LOOM_PAINT_BROKEN_END}, {"missing-pick", LOOM_PAINT_MISSING_PICK},
	{"pull", LOOM_PAINT_PULL}, {NULL, 0}};
static const opt_choice fibre_names[] = {
	{"cotton", LOOM_FIBRE_COTTON}, {"rayon", LOOM_FIBRE_RAYON},
	{"silk", LOOM_FIBRE_SILK}, {"polyester", LOOM_FIBRE_POLYESTER},
	{"wool", LOOM_FIBRE_WOOL}, {"linen", LOOM_FIBRE_LINEN},
	{"monofilament", LOOM_FIBRE_MONOFILAMENT}, {"none", LOOM_FIBRE_NONE}, {NULL, 0}};

static const char *opt_rect(const char *text, void *dest)
{
	double *r = dest;
	char *e;
	const char *s = text;
	const char *msg = "X0,Y0:X1,Y1 (mm) with X0 < X1 and Y0 < Y1";
	const char seps[4] = {',', ':', ',', 0};

	for (int k = 0; k < 4; k++) {
		r[k] = strtod(s, &e);
		if (e == s || !isfinite(r[k]) || *e != seps[k])
			return msg;
		s = e + 1;
	}
	return r[0] < r[2] && r[1] < r[3] ? NULL : msg;
}

static const char *opt_pair(const char *text, void *dest)
{
	double *r = dest;
	char *e;

	r[0] = strtod(text, &e);
	if (e == text || *e != ',' || !isfinite(r[0]))
		return "X,Y: two finite numbers (mm)";
	text = e + 1;
	r[1] = strtod(text, &e);
	if (e == text || *e || !isfinite(r[1]))
		return "X,Y: two finite numbers (mm)";
	return NULL;
}

static const char *opt_rgb(const char *text, void *dest)
{
	float *c = dest;
	char *e;
	const char *s = text;

	for (int k = 0; k < 3; k++) {
		double v = strtod(s, &e);
		if (e == s || !(v >= 0 && v <= 1) || *e != (k < 2 ? ',' : 0))
			return "R,G,B: three numbers in [0, 1] (linear)";
		c[k] = (float)v;
		s = e + 1;
	}
	return NULL;
}

/* Write text to path atomically (temporary name, then rename). */
int cli_write_atomic(const char *path, const char *text, size_t len, loom_diag *d)
{
	char tmp[PATH_MAX];
	FILE *fp;
	int ok;

	if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp) {
		snprintf(d->message, sizeof d->message, "%s: path too long", path);
		return LOOM_EINVAL;
	}
	fp = fopen(tmp, "wb");
	if (!fp) {
		snprintf(d->message, sizeof d->message, "%.300s: %s", tmp, strerror(errno));
		return LOOM_EIO;
	}
	ok = fwrite(text, 1, len, fp) == len;
	ok = (fflush(fp) == 0) && ok;
	ok = (fsync(fileno(fp)) == 0) && ok;
	ok = (fclose(fp) == 0) && ok;
	if (!ok || rename(tmp, path) != 0) {
		snprintf(d->message, sizeof d->message, "%.300s: %s", path, strerror(errno));
		unlink(tmp);
		return LOOM_EIO;
	}
	return LOOM_OK;
}

int cmd_paint(int argc, char **argv)
{
	const char *prog = "loom paint";
	const char *path = NULL, *out = NULL, *db_opt = NULL, *mask_path = NULL;
	const char *weave_arg = NULL;
	loom_design *weave = NULL;
	double rect[4] = {0, 0, 0, 0}, at[2] = {0, 0}, cell[2] = {0, 0};
	double strength = 0.7, blend = 0.2;
	float rgb[3] = {0.35f, 0.22f, 0.08f};
	int yarn = -1, defect = 0, fibre = 0, kind = LOOM_YARN_WARP, quiet = 0, rc = EXIT_BAD_INPUT;
	uint32_t radius = 2, lift = 4, band = 1;
	loom_paint *p = NULL;
	loom_fabric *f = NULL;
	loom_db *db = NULL;
	loom_image *img = NULL;
	loom_paint_region r;
	loom_diag diag;
	char *text = NULL;
	uint8_t *m = NULL;
	size_t len = 0;
	opt_entry opts[] = {
		OPT_CALLBACK(0, "rect", rect, "X0,Y0:X1,Y1", opt_rect,
		             "the region: a rectangle in cloth mm"),
		OPT_STRING(0, "mask", &mask_path, "PNG", "the region: an image, one pixel "
		           "per cell, white (>= 128) painted, top row at --at"),
		OPT_CALLBACK(0, "at", at, "X,Y", opt_pair, "mask: its corner in cloth mm "
		             "(default 0,0)"),
		OPT_CALLBACK(0, "cell", cell, "W,H", opt_pair, "mask: mm per pixel (default "
		             "one crossing)"),
		OPT_ENUM(0, "yarn", &yarn, "KIND", kind_names, "recolour the yarns of KIND "
		         "(warp, weft or any) to --rgb, or change their material (--fibre)"),
		OPT_ENUM(0, "fibre", &fibre, "F", fibre_names, "yarn: the new fibre "
		         "material (cotton, rayon, silk, polyester, wool, linen, "
		         "monofilament, none); the crossings copy exemplars of their new "
		         "(warp, weft) pair, which the fabric's database must have "
		         "(see loom synth)"),
		OPT_STRING(0, "weave", &weave_arg, "WEAVE", "weave the region in another "
		           "weave: a name (plain, twill:2/2, satin:1/4, ...) or a design "
		           "file (WIF, PBM, PNG), tiled from crossing 0,0"),
		OPT_U32(0, "band", &band, "N", 0, 8, "weave and fibre: crossings "
		        "re-synthesised around the region, %r (default 1)"),
		OPT_ENUM(0, "defect", &defect, "D", defect_names, "add a defect: stain, "
		         "slub, broken-end, missing-pick or pull"),
		OPT_CALLBACK(0, "rgb", rgb, "R,G,B", opt_rgb, "yarn colour or stain tint, "
		             "linear 0..1 (stain default 0.35,0.22,0.08)"),
		OPT_DOUBLE(0, "strength", &strength, "S", "[]", 0, 1, NULL, "stain "
		           "strength, %r (default 0.7)"),
		OPT_DOUBLE(0, "blend", &blend, "MM", "[]", 0, 1000, "mm", "yarn and stain: "
		           "soft edge outside the region, %r (default 0.2)"),
		OPT_U32(0, "radius", &radius, "V", 1, 16, "slub: extra yarn radius in "
		        "voxels, %r (default 2)"),
		OPT_U32(0, "lift", &lift, "V", 1, 64, "pull: lift in voxels, %r (default 4)"),
		OPT_ENUM(0, "kind", &kind, "K", kind_names + 1, "slub and pull: the yarn "
		         "kind, warp (default) or weft"),
		OPT_DB(&db_opt, "exemplar database (default: the one the fabric names)"),
		OPT_OUTPUT(&out, "PAINT", "the paint file to write"),
		OPT_QUIET(&quiet, "no summary"),
		OPT_END()
	};
	opts_cmd cmd = {.prog = prog, .usage = usage, .about = about, .opts = opts,
	                .pos_name = "FABRIC", .pos_min = 1, .pos_max = 1, .pos = &path};

	opts_parse(&cmd, argc, argv);
	if (!out)
		opts_usage(&cmd, "missing -o PAINT");
	if (opt_given(&cmd, rect) == (mask_path != NULL))
		opts_usage(&cmd, "give the region as exactly one of --rect and --mask");
	if (!mask_path && (opt_given(&cmd, at) || opt_given(&cmd, cell)))
		opts_usage(&cmd, "--at and --cell go with --mask");
	if (opt_given(&cmd, cell) && !(cell[0] > 0 && cell[1] > 0))
		opts_usage(&cmd, "--cell: W,H must be > 0");
	if ((yarn >= 0) + (defect != 0) + (weave_arg != NULL) != 1)
		opts_usage(&cmd, "give exactly one of --yarn, --weave and --defect");
	if (opt_given(&cmd, &fibre) && yarn < 0)
		opts_usage(&cmd, "--fibre goes with --yarn KIND");
	if (opt_given(&cmd, &band) && !weave_arg && !opt_given(&cmd, &fibre))
		opts_usage(&cmd, "--band goes with --weave or --yarn --fibre");
	if (weave_arg && opt_given(&cmd, rgb))
		opts_usage(&cmd, "--rgb goes with --yarn or --defect stain");
	if (yarn >= 0 && !opt_given(&cmd, rgb) && !opt_given(&cmd, &fibre))
		opts_usage(&cmd, "--yarn needs --rgb R,G,B or --fibre F (or both)");
	if (opt_given(&cmd, &blend) && yarn >= 0 && !opt_given(&cmd, rgb))
		opts_usage(&cmd, "--blend goes with --rgb (a new fibre blends over --band)");
	if (opt_given(&cmd, &kind) && defect != LOOM_PAINT_SLUB && defect != LOOM_PAINT_PULL)
		opts_usage(&cmd, "--kind goes with --defect slub or pull");
	if (opt_given(&cmd, &radius) && defect != LOOM_PAINT_SLUB)
		opts_usage(&cmd, "--radius goes with --defect slub");
	if (opt_given(&cmd, &lift) && defect != LOOM_PAINT_PULL)
		opts_usage(&cmd, "--lift goes with --defect pull");
	if (opt_given(&cmd, &strength) && defect != LOOM_PAINT_STAIN)
		opts_usage(&cmd, "--strength goes with --defect stain");
	cli_diag_init(&diag, &quiet);

	if (db_opt && loom_db_open(db_opt, &db, &diag) != LOOM_OK)
		cli_fail(prog, "%s", diag.message);
	/* the fabric (checked, and for one crossing's size) */
	if (cli_open_painted(path, db, &f, &p, &diag) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto done;
	}
	if (!p) {
		char full[PATH_MAX];
		if (!realpath(path, full)) {
			cli_error(prog, "%s: %s", path, strerror(errno));
			goto done;
		}
		if (loom_paint_new(full, &p, &diag) != LOOM_OK) {
			cli_error(prog, "%s: %s", path, diag.message);
			goto done;
		}
	}
	memset(&r, 0, sizeof r);
	r.effect = yarn >= 0 ? LOOM_PAINT_YARN : weave_arg ? LOOM_PAINT_WEAVE : defect;
	if (weave_arg) {
		loom_weave_params wp;
		loom_diag wd;
		memset(&wd, 0, sizeof wd);
		if (loom_weave_parse(weave_arg, &wp, &wd) == LOOM_OK) {
			if (loom_design_make(&wp, 0, 0, &weave, &diag) != LOOM_OK) {
				cli_error(prog, "--weave %s: %s", weave_arg, diag.message);
				goto done;
			}
		} else if (loom_design_read(weave_arg, &weave, &diag) != LOOM_OK) {
			cli_error(prog, "--weave %s: neither a weave name (%s) nor a design "
			          "file: %s", weave_arg, wd.message, diag.message);
			goto done;
		}
		if (weave->rows > LOOM_PAINT_MAX_MASK || weave->cols > LOOM_PAINT_MAX_MASK) {
			cli_error(prog, "--weave %s: %ux%u crossings; a painted weave may have "
			          "at most %ux%u", weave_arg, weave->rows, weave->cols,
			          LOOM_PAINT_MAX_MASK, LOOM_PAINT_MAX_MASK);
			goto done;
		}
		r.weave_w = weave->cols;
		r.weave_h = weave->rows;
		r.weave = weave->weave;
		r.band = band;
	}
	r.kind = yarn >= 0 ? yarn : (defect == LOOM_PAINT_SLUB || defect == LOOM_PAINT_PULL)
	                            ? kind : 0;
	if (!weave_arg)
		memcpy(r.rgb, rgb, sizeof rgb);
	r.strength = defect == LOOM_PAINT_STAIN ? (float)strength : 0.0f;
	r.blend_mm = (r.effect == LOOM_PAINT_YARN || r.effect == LOOM_PAINT_STAIN) ? blend : 0;
	r.amount = defect == LOOM_PAINT_SLUB ? radius : defect == LOOM_PAINT_PULL ? lift : 0;
	if (mask_path) {
		loom_fabric_db_identity id;
		size_t np;
		if (loom_image_read(mask_path, &img, &diag) != LOOM_OK) {
			cli_error(prog, "%s", diag.message);
			goto done;
		}
		if (img->width > LOOM_PAINT_MAX_MASK || img->height > LOOM_PAINT_MAX_MASK) {
			cli_error(prog, "%s: %ux%u pixels; a mask may have at most %ux%u", mask_path,
			          img->width, img->height, LOOM_PAINT_MAX_MASK, LOOM_PAINT_MAX_MASK);
			goto done;
		}
		if (!opt_given(&cmd, cell)) {
			loom_fabric_get_db_identity(f, &id);
			cell[0] = id.block[0] * (double)id.voxel_size_um * 1e-3;
			cell[1] = id.block[1] * (double)id.voxel_size_um * 1e-3;
		}
		np = (size_t)img->width * img->height;
		m = malloc(np ? np : 1);
		if (!m) {
			cli_error(prog, "out of memory");
			goto done;
		}
		for (size_t i = 0; i < np; i++) {
			const uint8_t *px = img->pixels + i * img->channels;
			unsigned sum = 0;
			for (unsigned c = 0; c < img->channels && c < 3; c++)
				sum += px[c];
			m[i] = sum >= 128u * (img->channels < 3 ? img->channels : 3);
		}
		r.x0 = at[0];
		r.y0 = at[1];
		r.x1 = at[0] + cell[0] * img->width;
		r.y1 = at[1] + cell[1] * img->height;
		r.mask_w = img->width;
		r.mask_h = img->height;
		r.mask = m;
	} else {
		r.x0 = rect[0];
		r.y0 = rect[1];
		r.x1 = rect[2];
		r.y1 = rect[3];
	}
	/* --yarn: a colour region (--rgb), then a fibre region (--fibre) */
	rc = LOOM_OK;
	if (r.effect != LOOM_PAINT_YARN || opt_given(&cmd, rgb))
		rc = loom_paint_add(p, &r, &diag);
	if (rc == LOOM_OK && fibre) {
		r.effect = LOOM_PAINT_FIBRE;
		r.fibre = fibre;
		r.band = band;
		memset(r.rgb, 0, sizeof r.rgb);
		r.blend_mm = 0;
		rc = loom_paint_add(p, &r, &diag);
	}
	if (rc != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		rc = EXIT_BAD_INPUT;
		goto done;
	}
	if (weave_arg || fibre) {
		/* synthesise the new weave or fibre once now: its errors (a
		   region too large, no exemplar block, a material pair the
		   database lacks) belong to this command */
		loom_paint *one = NULL;
		loom_fabric *g = f;
		int e = LOOM_OK;
		rc = EXIT_BAD_INPUT;
		if (loom_paint_new(loom_paint_fabric(p), &one, &diag) != LOOM_OK ||
		    loom_paint_add(one, &r, &diag) != LOOM_OK ||
		    (e = loom_paint_apply_weaves(one, &g, &diag)) != LOOM_OK) {
			if (e == LOOM_EMISMATCH)
				cli_error(prog, "%s: %s; for a database with the pairs needed, "
				          "synthesize the fabric with the material per yarn "
				          "type (loom synth DESIGN --yarn-fibre TYPE=%s ..., "
				          "docs/exemplars.md) and paint that fabric", path,
				          diag.message, loom_fibre_name(fibre));
			else
				cli_error(prog, "%s", diag.message);
			loom_paint_free(one);
			goto done;
		}
		loom_paint_free(one);
		f = g;
	}
	rc = EXIT_BAD_INPUT;
	if (loom_paint_format(p, &text, &len) != LOOM_OK) {
		cli_error(prog, "out of memory");
		goto done;
	}
	if (cli_write_atomic(out, text, len, &diag) != LOOM_OK) {
		cli_error(prog, "%s", diag.message);
		goto done;
	}
	if (!quiet)
		fprintf(stderr, "loom paint: %s: %u region%s over %s\n", out, loom_paint_count(p),
		        loom_paint_count(p) == 1 ? "" : "s", loom_paint_fabric(p));
	rc = 0;
done:
	free(text);
	free(m);
	loom_image_free(img);
	loom_design_free(weave);
	loom_paint_free(p);
	loom_fabric_free(f);
	loom_db_close(db);
	return rc;
}
