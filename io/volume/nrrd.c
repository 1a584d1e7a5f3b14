/*
 * io/volume/nrrd.c - NRRD writer (attached or detached header, raw data).
 * Format reference: teem's "NRRD0004" text header; we write the fields
 * type, dimension, space dimension, sizes, space directions, kinds,
 * space units, space origin, endian (multi-byte types), encoding and, when
 * detached, data file.  See io/volume/nrrd.h.
 */
#include "nrrd.h"
#include "io/core/file.h"

#include <stdlib.h>
#include <string.h>

static const char *const type_name[] = {"uint8", "uint16", "float"};
static const size_t type_bytes[] = {1, 2, 4};

static int host_is_le(void)
{
	const uint16_t one = 1;
	return *(const uint8_t *)&one == 1;
}

/* "dir/name.nhdr" -> "dir/name.raw"; *base points at "name.raw". */
static char *data_path(const char *path, const char **base)
{
	const char *slash = strrchr(path, '/');
	const char *name = slash ? slash + 1 : path;
	const char *dot = strrchr(name, '.');
	size_t stem = dot && dot != name ? (size_t)(dot - path) : strlen(path);
	char *p = malloc(stem + 5);

	if (!p)
		return NULL;
	memcpy(p, path, stem);
	memcpy(p + stem, ".raw", 5);
	*base = p + (name - path);
	return p;
}

static void put_vec(FILE *fp, const double *v, int axis)
{
	fputc('(', fp);
	for (int a = 0; a < 3; a++)
		fprintf(fp, "%s%.9g", a ? "," : "", a == axis ? v[axis] : 0.0);
	fputc(')', fp);
}

int loom__nrrd_begin(loom__nrrd_w *w, const char *path, int detached,
                     const loom__nrrd_desc *d, loom_diag *diag)
{
	FILE *fp;
	char *dpath = NULL;
	const char *dbase = NULL;
	uint64_t n = 1;
	int rc;

	memset(w, 0, sizeof *w);
	if (!path || !d || d->type < 0 || d->type > LOOM__NRRD_FLOAT ||
	    (d->components != 1 && d->components != 3))
		return loom__fail(diag, LOOM_EINVAL, "NRRD writer: bad arguments");
	for (int a = 0; a < 3; a++) {
		if (d->sizes[a] == 0)
			return loom__fail(diag, LOOM_EINVAL, "%s: NRRD axis %d has size 0",
			                  path, a);
		n *= d->sizes[a];
	}
	w->elem_bytes = type_bytes[d->type];
	w->expected = n * d->components * w->elem_bytes;
	w->detached = detached;
	if (detached) {
		dpath = data_path(path, &dbase);
		if (!dpath)
			return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
		if (strcmp(dpath, path) == 0) {
			free(dpath);
			return loom__fail(diag, LOOM_EINVAL, "%s: a detached header needs a "
			                  "name other than its .raw data file", path);
		}
	}
	rc = loom__atomic_open(&w->hdr, path, diag);
	if (rc) {
		free(dpath);
		return rc;
	}
	if (detached) {
		rc = loom__atomic_open(&w->data, dpath, diag);
		if (rc) {
			free(dpath);
			loom__atomic_abort(&w->hdr);
			return rc;
		}
	}
	fp = w->hdr.fp;
	fprintf(fp, "NRRD0004\n");
	fprintf(fp, "# Complete NRRD file format specification at:\n");
	fprintf(fp, "# http://teem.sourceforge.net/nrrd/format.html\n");
	if (d->content && *d->content && !strchr(d->content, '\n'))
		fprintf(fp, "content: %s\n", d->content);
	fprintf(fp, "type: %s\n", type_name[d->type]);
	fprintf(fp, "dimension: %d\n", d->components == 3 ? 4 : 3);
	fprintf(fp, "space dimension: 3\n");
	fprintf(fp, "sizes:%s %llu %llu %llu\n", d->components == 3 ? " 3" : "",
	        (unsigned long long)d->sizes[0], (unsigned long long)d->sizes[1],
	        (unsigned long long)d->sizes[2]);
	fprintf(fp, "space directions:%s", d->components == 3 ? " none" : "");
	for (int a = 0; a < 3; a++) {
		fputc(' ', fp);
		put_vec(fp, d->spacing, a);
	}
	fprintf(fp, "\nkinds:%s domain domain domain\n",
	        d->components == 3 ? " 3-vector" : "");
	if (d->units && *d->units && !strchr(d->units, '"') && !strchr(d->units, '\n'))
		fprintf(fp, "space units: \"%s\" \"%s\" \"%s\"\n", d->units, d->units,
		        d->units);
	fprintf(fp, "space origin: (%.9g,%.9g,%.9g)\n", d->origin[0], d->origin[1],
	        d->origin[2]);
	if (w->elem_bytes > 1)
		fprintf(fp, "endian: little\n");
	fprintf(fp, "encoding: raw\n");
	if (detached)
		fprintf(fp, "data file: %s\n", dbase);
	else
		fprintf(fp, "\n");
	free(dpath);
	return LOOM_OK;
}

int loom__nrrd_write(loom__nrrd_w *w, const void *samples, size_t n,
                     loom_diag *diag)
{
	FILE *fp = w->detached ? w->data.fp : w->hdr.fp;
	const char *path = w->detached ? w->data.path : w->hdr.path;
	size_t bytes = n * w->elem_bytes;

	if (w->written + bytes > w->expected)
		return loom__fail(diag, LOOM_EINVAL, "%s: more data than the header "
		                  "announces (%llu bytes)", path,
		                  (unsigned long long)w->expected);
	if (w->elem_bytes > 1 && !host_is_le()) {
		uint8_t tmp[4096];
		const uint8_t *s = samples;
		size_t per = sizeof tmp / w->elem_bytes;
		for (size_t i = 0; i < n; i += per) {
			size_t m = n - i < per ? n - i : per;
			for (size_t j = 0; j < m; j++)
				for (size_t b = 0; b < w->elem_bytes; b++)
					tmp[j * w->elem_bytes + b] =
					        s[(i + j) * w->elem_bytes + w->elem_bytes - 1 - b];
			if (fwrite(tmp, w->elem_bytes, m, fp) != m)
				return loom__fail(diag, LOOM_EIO, "%s: write failed", path);
		}
	} else if (bytes && fwrite(samples, 1, bytes, fp) != bytes) {
		return loom__fail(diag, LOOM_EIO, "%s: write failed", path);
	}
	w->written += bytes;
	return LOOM_OK;
}

int loom__nrrd_finish(loom__nrrd_w *w, loom_diag *diag)
{
	int rc;

	if (w->written != w->expected) {
		rc = loom__fail(diag, LOOM_EINVAL, "%s: %llu bytes of data written, the "
		                "header announces %llu", w->hdr.path,
		                (unsigned long long)w->written,
		                (unsigned long long)w->expected);
		loom__nrrd_abort(w);
		return rc;
	}
	if (w->detached) {
		rc = loom__atomic_commit(&w->data, diag);
		if (rc) {
			loom__atomic_abort(&w->hdr);
			return rc;
		}
	}
	return loom__atomic_commit(&w->hdr, diag);
}

void loom__nrrd_abort(loom__nrrd_w *w)
{
	if (w->hdr.fp || w->hdr.tmp_path)
		loom__atomic_abort(&w->hdr);
	if (w->data.fp || w->data.tmp_path)
		loom__atomic_abort(&w->data);
}
