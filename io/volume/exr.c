/*
 * io/volume/exr.c - OpenEXR z-slice writer and a small reader, through the
 * OpenEXR Core C API (3.1).
 *
 * Writer.  One single-part scanline image per call sequence: the caller
 * streams rows, we keep only the rows of the current chunk (16 for ZIP),
 * split per channel into planes of the stored type, and encode and write
 * each chunk as soon as it is full.  Output goes through our own write
 * callback into a loom__atomic temporary file, so the file appears under
 * its name only after finish has checked the chunk count and OpenEXR has
 * written its offset table.
 *
 * Two OpenEXR 3.1 pitfalls are handled here (../shared/DEPENDENCIES.md):
 *  1. Corruption: when zlib's output is exactly as long as the raw chunk,
 *     3.1 keeps the compressed bytes, and every reader (which takes
 *     "packed size == unpacked size" to mean "stored raw") then decodes
 *     garbage.  The rule that fixes it: a chunk whose deflate output is
 *     not smaller than the raw chunk is stored raw.  We replace the
 *     pipeline's compress_fn with one of two functions that apply it:
 *       - zip_libdeflate (default): the ZIP transform (byte split + delta
 *         predictor, as OpenEXR defines it) and libdeflate's zlib format,
 *         with one compressor per writer.  OpenEXR 3.1's own path calls
 *         zlib's compress2 per chunk, whose ~300 KB of state is allocated,
 *         zeroed and handed back to the kernel every time: perf showed
 *         brk/page-fault/memset taking ~60% of the time of small slices.
 *       - compress_guard (options.openexr_zip): OpenEXR's own compressor,
 *         wrapped; whenever its result is not smaller than the raw chunk
 *         we copy the raw bytes over it.
 *  2. A missing chunk makes exr_finish delete the file yet report success
 *     (default file mode).  We write through our own stream (nothing is
 *     deleted behind our back) and count chunks: finish refuses to commit
 *     unless every chunk was written.
 *
 * Reader.  Whole image into planar floats, half and uint converted, float
 * copied bit for bit; from memory, so tests and fuzzers need no files.
 */
#include "core/internal.h"
#include "io/core/file.h"

#include <errno.h>
#include <libdeflate.h>
#include <openexr.h>
#include <stdlib.h>
#include <string.h>

#define EXR_NAME_MAX 255
#define LOOM_EXR_DEFAULT_LEVEL 6  /* libdeflate level when zip_level is -1 */

/* ---- writer ---------------------------------------------------------------- */

struct loom_exr_writer {
	loom__atomic file;
	exr_context_t ctx;
	uint32_t width, height, n_ch;
	int32_t lines_per_chunk;   /* scanlines per chunk (16 for ZIP) */
	int32_t chunk_count;       /* chunks the image needs */
	int32_t chunks_written;
	uint32_t rows_done;        /* rows received from the caller */
	uint32_t rows_buffered;    /* rows held for the current chunk */
	char **names;              /* caller's channel order */
	int *pixel;                /* LOOM_EXR_HALF / LOOM_EXR_FLOAT */
	uint8_t **plane;           /* per channel: lines_per_chunk*width values */
	int *map;                  /* pipeline channel i -> caller channel */
	exr_encode_pipeline_t enc;
	int enc_ready;
	exr_result_t (*orig_compress)(exr_encode_pipeline_t *);
	int codec_set;             /* compress_fn replaced */
	int openexr_zip;           /* use OpenEXR's compressor + guard */
	struct libdeflate_compressor *deflater;
	int level;                 /* libdeflate level */
	uint8_t *zscratch;         /* chunk bytes after the ZIP transform */
	uint8_t *zout;             /* deflate output */
	size_t zcap;               /* bytes of zscratch; zout holds the bound */
	loom_exr_stats stats;
	loom_exr_stats *stats_out;
	uint64_t file_end;         /* highest byte written + 1 */
	int io_errno;
	char exr_msg[256];         /* last message from OpenEXR */
	int failed;
};

static void exr_err_cb(exr_const_context_t ctxt, exr_result_t code,
                       const char *msg)
{
	void *ud = NULL;
	char *dst;

	if (!ctxt || exr_get_user_data(ctxt, &ud) != EXR_ERR_SUCCESS || !ud)
		return;
	/* both the writer and the reader state begin with this buffer */
	dst = *(char **)ud;
	snprintf(dst, 256, "%s (%s)", msg ? msg : "", exr_get_error_code_as_string(code));
}

/* The writer's user data: a pointer to its message buffer first, so the
   error callback can find it without knowing which side it serves. */
typedef struct wr_ud {
	char *msg;
	loom_exr_writer *w;
} wr_ud;

static int64_t write_cb(exr_const_context_t ctxt, void *userdata,
                        const void *buffer, uint64_t sz, uint64_t offset,
                        exr_stream_error_func_ptr_t error_cb)
{
	loom_exr_writer *w = ((wr_ud *)userdata)->w;
	FILE *fp = w->file.fp;

	(void)ctxt;
	(void)error_cb;
	if (!fp)
		return -1;
	if (ftello(fp) != (off_t)offset && fseeko(fp, (off_t)offset, SEEK_SET) != 0) {
		w->io_errno = errno ? errno : EIO;
		return -1;
	}
	if (sz && fwrite(buffer, 1, (size_t)sz, fp) != sz) {
		w->io_errno = errno ? errno : EIO;
		return -1;
	}
	if (offset + sz > w->file_end)
		w->file_end = offset + sz;
	return (int64_t)sz;
}

/* Workaround 1, default path (file comment): ZIP as OpenEXR defines it.
   Bytes are split into even and odd positions (two halves), then each byte
   after the first becomes (b[i] - b[i-1] + 128) mod 256 of the split
   sequence, then zlib format (RFC 1950). */
static exr_result_t zip_libdeflate(exr_encode_pipeline_t *e)
{
	loom_exr_writer *w = e->encoding_user_data;
	const uint8_t *src = e->packed_buffer;
	size_t n = (size_t)e->packed_bytes, half = (n + 1) / 2, out;
	uint8_t *t = w->zscratch, prev;

	if (n > w->zcap)
		return EXR_ERR_OUT_OF_MEMORY;
	for (size_t i = 0; i < n / 2; i++) {
		t[i] = src[2 * i];
		t[half + i] = src[2 * i + 1];
	}
	if (n & 1)
		t[half - 1] = src[n - 1];
	prev = t[0];
	for (size_t i = 1; i < n; i++) {
		uint8_t cur = t[i];
		t[i] = (uint8_t)(cur - prev + 128);
		prev = cur;
	}
	out = libdeflate_zlib_compress(w->deflater, t, n, w->zout,
	                               libdeflate_zlib_compress_bound(w->deflater, w->zcap));
	if (out == 0 || out >= n) {
		if (out == n)
			w->stats.chunks_equal++; /* what OpenEXR 3.1 would corrupt */
		w->stats.chunks_raw++;
		e->compressed_buffer = e->packed_buffer;
		e->compressed_bytes = e->packed_bytes;
	} else {
		e->compressed_buffer = w->zout;
		e->compressed_bytes = out;
	}
	e->compressed_alloc_size = 0; /* not the pipeline's to free */
	return EXR_ERR_SUCCESS;
}

/* Workaround 1, OpenEXR's compressor (file comment). */
static exr_result_t compress_guard(exr_encode_pipeline_t *e)
{
	loom_exr_writer *w = e->encoding_user_data;
	exr_result_t rv = w->orig_compress(e);

	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (e->compressed_bytes >= e->packed_bytes) {
		if (e->compressed_alloc_size < e->packed_bytes)
			return EXR_ERR_OUT_OF_MEMORY;
		if (e->compressed_buffer != e->packed_buffer) {
			if (e->compressed_bytes == e->packed_bytes &&
			    memcmp(e->compressed_buffer, e->packed_buffer,
			           e->packed_bytes) != 0)
				w->stats.chunks_equal++; /* zlib data of the raw size */
			memcpy(e->compressed_buffer, e->packed_buffer, e->packed_bytes);
		}
		e->compressed_bytes = e->packed_bytes;
		w->stats.chunks_raw++;
	}
	return EXR_ERR_SUCCESS;
}

/* Free the encode pipeline; our codec's buffers are not the pipeline's. */
static void enc_destroy(loom_exr_writer *w)
{
	if (!w->enc_ready)
		return;
	if (!w->openexr_zip) {
		w->enc.compressed_buffer = NULL;
		w->enc.compressed_alloc_size = 0;
	}
	exr_encoding_destroy(w->ctx, &w->enc);
	w->enc_ready = 0;
}

static int exr_fail(loom_exr_writer *w, loom_diag *diag, exr_result_t rv,
                    const char *what)
{
	w->failed = 1;
	if (w->io_errno)
		return loom__fail(diag, LOOM_EIO, "%s: %s: write failed: %s",
		                  w->file.path, what, strerror(w->io_errno));
	return loom__fail(diag, rv == EXR_ERR_OUT_OF_MEMORY ? LOOM_ENOMEM
	                                                    : LOOM_EUNSUPPORTED,
	                  "%s: %s: OpenEXR: %s", w->file.path, what,
	                  w->exr_msg[0] ? w->exr_msg
	                                : exr_get_default_error_message(rv));
}

static void writer_free(loom_exr_writer *w)
{
	if (!w)
		return;
	enc_destroy(w);
	if (w->ctx)
		exr_finish(&w->ctx);
	if (w->deflater)
		libdeflate_free_compressor(w->deflater);
	free(w->zscratch);
	free(w->zout);
	free(w->map);
	for (uint32_t c = 0; c < w->n_ch; c++) {
		if (w->names)
			free(w->names[c]);
		if (w->plane)
			free(w->plane[c]);
	}
	free(w->names);
	free(w->plane);
	free(w->pixel);
	free(w);
}

static int check_channels(const char *path, const loom_exr_channel *ch,
                          uint32_t n, loom_diag *diag)
{
	if (!ch || n == 0)
		return loom__fail(diag, LOOM_EINVAL, "%s: no channels", path);
	if (n > 1024)
		return loom__fail(diag, LOOM_EINVAL, "%s: %u channels, at most 1024",
		                  path, n);
	for (uint32_t c = 0; c < n; c++) {
		size_t len = ch[c].name ? strlen(ch[c].name) : 0;
		if (len == 0 || len > EXR_NAME_MAX)
			return loom__fail(diag, LOOM_EINVAL,
			                  "%s: channel %u: name must have 1..%d bytes", path,
			                  c, EXR_NAME_MAX);
		if (ch[c].pixel != LOOM_EXR_HALF && ch[c].pixel != LOOM_EXR_FLOAT)
			return loom__fail(diag, LOOM_EINVAL,
			                  "%s: channel \"%s\": pixel type must be half or "
			                  "float", path, ch[c].name);
		for (uint32_t d = 0; d < c; d++)
			if (!strcmp(ch[c].name, ch[d].name))
				return loom__fail(diag, LOOM_EINVAL,
				                  "%s: channel \"%s\" named twice", path,
				                  ch[c].name);
	}
	return LOOM_OK;
}

LOOM_API int loom_exr_writer_open(const char *path, uint32_t width,
                                  uint32_t height,
                                  const loom_exr_channel *channels,
                                  uint32_t n_channels,
                                  const loom_exr_options *opt,
                                  loom_exr_writer **out, loom_diag *diag)
{
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	loom_exr_options defaults = LOOM_EXR_OPTIONS_INIT;
	loom_exr_writer *w;
	wr_ud *ud;
	exr_result_t rv;
	int part = 0, rc, longnames = 0;
	size_t plane_bytes;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_exr_writer_open: NULL argument");
	*out = NULL;
	if (!opt)
		opt = &defaults;
	if (opt->size < sizeof(loom_exr_options))
		return loom__fail(diag, LOOM_EINVAL, "%s: options not initialised with "
		                  "LOOM_EXR_OPTIONS_INIT", path);
	if (width == 0 || height == 0 || width > INT32_MAX / 2 ||
	    height > INT32_MAX / 2)
		return loom__fail(diag, LOOM_EINVAL, "%s: image size %ux%u out of range",
		                  path, width, height);
	if (opt->zip_level < -1 || opt->zip_level > 9)
		return loom__fail(diag, LOOM_EINVAL, "%s: zip level %d, expected -1..9",
		                  path, opt->zip_level);
	rc = check_channels(path, channels, n_channels, diag);
	if (rc)
		return rc;

	w = calloc(1, sizeof *w + sizeof(wr_ud));
	if (!w)
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	ud = (wr_ud *)(w + 1);
	ud->msg = w->exr_msg;
	ud->w = w;
	w->width = width;
	w->height = height;
	w->stats_out = opt->stats;
	w->names = calloc(n_channels, sizeof *w->names);
	w->plane = calloc(n_channels, sizeof *w->plane);
	w->pixel = calloc(n_channels, sizeof *w->pixel);
	w->map = calloc(n_channels, sizeof *w->map);
	if (!w->names || !w->plane || !w->pixel || !w->map) {
		writer_free(w);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
	}
	w->n_ch = n_channels;
	for (uint32_t c = 0; c < n_channels; c++) {
		w->names[c] = strdup(channels[c].name);
		w->pixel[c] = channels[c].pixel;
		if (!w->names[c]) {
			writer_free(w);
			return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
		}
		if (strlen(channels[c].name) > 31)
			longnames = 1;
	}

	rc = loom__atomic_open(&w->file, path, diag);
	if (rc) {
		writer_free(w);
		return rc;
	}
	init.user_data = ud;
	init.write_fn = write_cb;
	init.error_handler_fn = exr_err_cb;
	if (opt->zip_level >= 0)
		init.zip_level = opt->zip_level;
	rv = exr_start_write(&w->ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
	if (rv != EXR_ERR_SUCCESS) {
		w->ctx = NULL;
		goto exr_error;
	}
	if (longnames && (rv = exr_set_longname_support(w->ctx, 1)))
		goto exr_error;
	if ((rv = exr_add_part(w->ctx, "slice", EXR_STORAGE_SCANLINE, &part)))
		goto exr_error;
	if ((rv = exr_initialize_required_attr_simple(w->ctx, part, (int32_t)width,
	                                              (int32_t)height,
	                                              EXR_COMPRESSION_ZIP)))
		goto exr_error;
	for (uint32_t c = 0; c < n_channels; c++) {
		rv = exr_add_channel(w->ctx, part, w->names[c],
		                     w->pixel[c] == LOOM_EXR_HALF ? EXR_PIXEL_HALF
		                                                  : EXR_PIXEL_FLOAT,
		                     EXR_PERCEPTUALLY_LINEAR, 1, 1);
		if (rv)
			goto exr_error;
	}
	if (opt->zip_level >= 0 &&
	    (rv = exr_set_zip_compression_level(w->ctx, part, opt->zip_level)))
		goto exr_error;
	if (opt->has_slice) {
		exr_attr_v3d_t vs, org;
		for (int a = 0; a < 3; a++) {
			vs.arr[a] = opt->voxel_mm[a];
			org.arr[a] = opt->origin_mm[a];
		}
		if ((rv = exr_attr_set_int(w->ctx, part, "loomSliceZ", opt->slice_z)) ||
		    (rv = exr_attr_set_v3d(w->ctx, part, "loomVoxelSize", &vs)) ||
		    (rv = exr_attr_set_v3d(w->ctx, part, "loomOrigin", &org)))
			goto exr_error;
	}
	if ((rv = exr_write_header(w->ctx)))
		goto exr_error;
	if ((rv = exr_get_scanlines_per_chunk(w->ctx, part, &w->lines_per_chunk)) ||
	    (rv = exr_get_chunk_count(w->ctx, part, &w->chunk_count)))
		goto exr_error;
	if (w->lines_per_chunk < 1 || w->lines_per_chunk > 256) {
		rc = loom__fail(diag, LOOM_EUNSUPPORTED, "%s: unexpected %d scanlines "
		                "per chunk", path, w->lines_per_chunk);
		goto fail;
	}
	for (uint32_t c = 0; c < n_channels; c++) {
		size_t elem = w->pixel[c] == LOOM_EXR_HALF ? 2 : 4;
		plane_bytes = (size_t)w->lines_per_chunk * width * elem;
		w->plane[c] = malloc(plane_bytes);
		if (!w->plane[c]) {
			rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
			goto fail;
		}
		w->zcap += plane_bytes;
	}
	w->openexr_zip = opt->openexr_zip != 0;
	if (!w->openexr_zip) {
		w->level = opt->zip_level >= 0 ? opt->zip_level : LOOM_EXR_DEFAULT_LEVEL;
		w->deflater = libdeflate_alloc_compressor(w->level);
		w->zscratch = malloc(w->zcap);
		w->zout = w->deflater ? malloc(libdeflate_zlib_compress_bound(w->deflater,
		                                                              w->zcap))
		                      : NULL;
		if (!w->deflater || !w->zscratch || !w->zout) {
			rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", path);
			goto fail;
		}
	}
	*out = w;
	return LOOM_OK;

exr_error:
	rc = exr_fail(w, diag, rv, "cannot start the image");
fail:
	if (w->ctx)
		exr_finish(&w->ctx);
	loom__atomic_abort(&w->file);
	writer_free(w);
	return rc;
}

/* Encode and write the buffered rows as one chunk. */
static int flush_chunk(loom_exr_writer *w, loom_diag *diag)
{
	exr_chunk_info_t ci;
	exr_result_t rv;
	int32_t y = (int32_t)(w->rows_done - w->rows_buffered);

	if ((rv = exr_write_scanline_chunk_info(w->ctx, 0, y, &ci)))
		return exr_fail(w, diag, rv, "chunk info");
	if (ci.height != (int32_t)w->rows_buffered || ci.width != (int32_t)w->width) {
		w->failed = 1;
		return loom__fail(diag, LOOM_EUNSUPPORTED, "%s: chunk at row %d is "
		                  "%dx%d, expected %ux%u", w->file.path, y, ci.width,
		                  ci.height, w->width, w->rows_buffered);
	}
	if (!w->enc_ready) {
		if ((rv = exr_encoding_initialize(w->ctx, 0, &ci, &w->enc)))
			return exr_fail(w, diag, rv, "encoder");
		w->enc_ready = 1;
		if (w->enc.channel_count != (int16_t)w->n_ch) {
			w->failed = 1;
			return loom__fail(diag, LOOM_EUNSUPPORTED, "%s: encoder has %d "
			                  "channels, expected %u", w->file.path,
			                  w->enc.channel_count, w->n_ch);
		}
		for (int i = 0; i < w->enc.channel_count; i++) {
			w->map[i] = -1;
			for (uint32_t c = 0; c < w->n_ch; c++)
				if (!strcmp(w->enc.channels[i].channel_name, w->names[c]))
					w->map[i] = (int)c;
			if (w->map[i] < 0) {
				w->failed = 1;
				return loom__fail(diag, LOOM_EUNSUPPORTED, "%s: encoder channel "
				                  "\"%s\" unknown", w->file.path,
				                  w->enc.channels[i].channel_name);
			}
		}
	} else if ((rv = exr_encoding_update(w->ctx, 0, &ci, &w->enc))) {
		return exr_fail(w, diag, rv, "encoder");
	}
	for (int i = 0; i < w->enc.channel_count; i++) {
		exr_coding_channel_info_t *ch = &w->enc.channels[i];
		int c = w->map[i];
		int half = w->pixel[c] == LOOM_EXR_HALF;
		ch->encode_from_ptr = w->plane[c];
		ch->user_bytes_per_element = half ? 2 : 4;
		ch->user_data_type = (uint16_t)(half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT);
		ch->user_pixel_stride = half ? 2 : 4;
		ch->user_line_stride = (int32_t)w->width * (half ? 2 : 4);
	}
	if (!w->codec_set) {
		if ((rv = exr_encoding_choose_default_routines(w->ctx, 0, &w->enc)))
			return exr_fail(w, diag, rv, "encoder");
		if (!w->enc.compress_fn) {
			w->failed = 1;
			return loom__fail(diag, LOOM_EUNSUPPORTED, "%s: OpenEXR chose no "
			                  "compressor for ZIP", w->file.path);
		}
		w->orig_compress = w->enc.compress_fn;
		w->enc.compress_fn = w->openexr_zip ? compress_guard : zip_libdeflate;
		w->codec_set = 1;
	}
	w->enc.encoding_user_data = w;
	if ((rv = exr_encoding_run(w->ctx, 0, &w->enc)))
		return exr_fail(w, diag, rv, "writing a chunk");
	if (w->io_errno)
		return exr_fail(w, diag, EXR_ERR_WRITE_IO, "writing a chunk");
	w->chunks_written++;
	w->stats.chunks++;
	w->rows_buffered = 0;
	return LOOM_OK;
}

LOOM_API int loom_exr_writer_put_rows(loom_exr_writer *w, const float *pixels,
                                      uint32_t n_rows, loom_diag *diag)
{
	if (!w)
		return loom__fail(diag, LOOM_EINVAL, "loom_exr_writer_put_rows: NULL writer");
	if (w->failed)
		return loom__fail(diag, LOOM_EUNUSABLE, "%s: writer failed earlier",
		                  w->file.path);
	if (n_rows > w->height - w->rows_done) {
		w->failed = 1;
		return loom__fail(diag, LOOM_ERANGE, "%s: %u rows sent after %u, the "
		                  "image has %u", w->file.path, n_rows, w->rows_done,
		                  w->height);
	}
	if (n_rows && !pixels)
		return loom__fail(diag, LOOM_EINVAL, "loom_exr_writer_put_rows: pixels is NULL");
	for (uint32_t r = 0; r < n_rows; r++) {
		const float *row = pixels + (size_t)r * w->width * w->n_ch;
		size_t base = (size_t)w->rows_buffered * w->width;
		for (uint32_t c = 0; c < w->n_ch; c++) {
			if (w->pixel[c] == LOOM_EXR_HALF) {
				uint16_t *dst = (uint16_t *)(void *)w->plane[c] + base;
				for (uint32_t x = 0; x < w->width; x++)
					dst[x] = loom_half_from_float(row[(size_t)x * w->n_ch + c]);
			} else {
				float *dst = (float *)(void *)w->plane[c] + base;
				for (uint32_t x = 0; x < w->width; x++)
					dst[x] = row[(size_t)x * w->n_ch + c];
			}
		}
		w->rows_buffered++;
		w->rows_done++;
		if (w->rows_buffered == (uint32_t)w->lines_per_chunk ||
		    w->rows_done == w->height) {
			int rc = flush_chunk(w, diag);
			if (rc)
				return rc;
		}
	}
	return LOOM_OK;
}

LOOM_API int loom_exr_writer_finish(loom_exr_writer *w, loom_diag *diag)
{
	exr_result_t rv;
	int rc;

	if (!w)
		return loom__fail(diag, LOOM_EINVAL, "loom_exr_writer_finish: NULL writer");
	if (w->failed) {
		rc = loom__fail(diag, LOOM_EUNUSABLE, "%s: writer failed earlier; "
		                "nothing written", w->file.path);
		loom_exr_writer_abort(w);
		return rc;
	}
	if (w->rows_done != w->height || w->chunks_written != w->chunk_count) {
		/* workaround 2: never let an incomplete image reach exr_finish's
		   delete-and-succeed path, nor its name */
		rc = loom__fail(diag, LOOM_ETRUNCATED,
		                "%s: only %u of %u rows (%d of %d chunks) written; "
		                "file not created", w->file.path, w->rows_done,
		                w->height, w->chunks_written, w->chunk_count);
		loom_exr_writer_abort(w);
		return rc;
	}
	enc_destroy(w);
	rv = exr_finish(&w->ctx);
	w->ctx = NULL;
	if (rv != EXR_ERR_SUCCESS || w->io_errno) {
		rc = exr_fail(w, diag, rv ? rv : EXR_ERR_WRITE_IO, "finishing");
		loom__atomic_abort(&w->file);
		writer_free(w);
		return rc;
	}
	w->stats.file_bytes = w->file_end;
	if (w->stats_out)
		*w->stats_out = w->stats;
	rc = loom__atomic_commit(&w->file, diag);
	writer_free(w);
	return rc;
}

LOOM_API void loom_exr_writer_abort(loom_exr_writer *w)
{
	if (!w)
		return;
	enc_destroy(w);
	if (w->ctx) {
		/* exr_finish would try to complete the file through write_cb: close
		   our stream first so it cannot, then drop the context */
		if (w->file.fp) {
			fclose(w->file.fp);
			w->file.fp = NULL;
		}
		exr_finish(&w->ctx);
		w->ctx = NULL;
	}
	loom__atomic_abort(&w->file);
	writer_free(w);
}

/* ---- reader ----------------------------------------------------------------- */

typedef struct rd_state {
	char *msg;             /* first: see exr_err_cb */
	const uint8_t *data;
	size_t len;
	char msgbuf[256];
} rd_state;

static int64_t read_cb(exr_const_context_t ctxt, void *userdata, void *buffer,
                       uint64_t sz, uint64_t offset,
                       exr_stream_error_func_ptr_t error_cb)
{
	rd_state *s = userdata;
	(void)ctxt;
	(void)error_cb;
	if (offset >= s->len)
		return 0;
	if (sz > s->len - offset)
		sz = s->len - offset;
	memcpy(buffer, s->data + offset, (size_t)sz);
	return (int64_t)sz;
}

static int64_t size_cb(exr_const_context_t ctxt, void *userdata)
{
	(void)ctxt;
	return (int64_t)((rd_state *)userdata)->len;
}

LOOM_API void loom_exr_image_free(loom_exr_image *img)
{
	if (!img)
		return;
	if (img->names)
		for (uint32_t c = 0; c < img->n_channels; c++)
			free(img->names[c]);
	free(img->names);
	free(img->pixel);
	free(img->data);
	free(img);
}

LOOM_API int loom_exr_image_channel(const loom_exr_image *img, const char *name)
{
	if (!img || !name)
		return -1;
	for (uint32_t c = 0; c < img->n_channels; c++)
		if (!strcmp(img->names[c], name))
			return (int)c;
	return -1;
}

static int rd_fail(rd_state *s, const char *name, loom_diag *diag,
                   exr_result_t rv, const char *what)
{
	return loom__fail(diag, rv == EXR_ERR_OUT_OF_MEMORY ? LOOM_ENOMEM
	                                                    : LOOM_EFORMAT,
	                  "%s: %s: OpenEXR: %s", name, what,
	                  s->msgbuf[0] ? s->msgbuf
	                               : exr_get_default_error_message(rv));
}

static int read_pixels(exr_context_t ctx, rd_state *s, const char *name,
                       loom_exr_image *img, const exr_attr_box2i_t *dw,
                       loom_diag *diag)
{
	exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
	int dec_ready = 0, rc = LOOM_OK;
	int32_t lines;
	exr_result_t rv;
	uint8_t *tmp = NULL;
	int *map = NULL;

	if ((rv = exr_get_scanlines_per_chunk(ctx, 0, &lines)) || lines < 1 ||
	    lines > 256)
		return rd_fail(s, name, diag, rv ? rv : EXR_ERR_INVALID_ATTR,
		               "scanlines per chunk");
	tmp = malloc((size_t)lines * img->width * 4 * img->n_channels);
	map = calloc(img->n_channels, sizeof *map);
	if (!tmp || !map) {
		free(tmp);
		free(map);
		return loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
	}
	for (int64_t y = dw->min.y; y <= dw->max.y; y += lines) {
		exr_chunk_info_t ci;
		int32_t row0;
		if ((rv = exr_read_scanline_chunk_info(ctx, 0, (int)y, &ci))) {
			rc = rd_fail(s, name, diag, rv, "chunk table");
			break;
		}
		row0 = ci.start_y - dw->min.y;
		if (ci.height < 1 || ci.height > lines || row0 < 0 ||
		    (uint32_t)row0 + (uint32_t)ci.height > img->height ||
		    ci.width != (int32_t)img->width) {
			rc = loom__fail(diag, LOOM_EFORMAT, "%s: chunk at row %lld has an "
			                "unexpected shape", name, (long long)y);
			break;
		}
		if (!dec_ready) {
			if ((rv = exr_decoding_initialize(ctx, 0, &ci, &dec))) {
				rc = rd_fail(s, name, diag, rv, "decoder");
				break;
			}
			dec_ready = 1;
			if ((uint32_t)dec.channel_count != img->n_channels) {
				rc = loom__fail(diag, LOOM_EFORMAT, "%s: decoder channel count",
				                name);
				break;
			}
			for (int i = 0; i < dec.channel_count; i++) {
				map[i] = loom_exr_image_channel(img, dec.channels[i].channel_name);
				if (map[i] < 0) {
					rc = loom__fail(diag, LOOM_EFORMAT, "%s: decoder channel "
					                "\"%s\" unknown", name,
					                dec.channels[i].channel_name);
					break;
				}
			}
			if (rc)
				break;
		} else if ((rv = exr_decoding_update(ctx, 0, &ci, &dec))) {
			rc = rd_fail(s, name, diag, rv, "decoder");
			break;
		}
		for (int i = 0; i < dec.channel_count; i++) {
			exr_coding_channel_info_t *ch = &dec.channels[i];
			int bpe = ch->bytes_per_element;
			ch->decode_to_ptr = tmp + (size_t)i * lines * img->width * 4;
			ch->user_bytes_per_element = (int16_t)bpe;
			ch->user_data_type = ch->data_type;
			ch->user_pixel_stride = bpe;
			ch->user_line_stride = (int32_t)img->width * bpe;
		}
		if (y == dw->min.y &&
		    (rv = exr_decoding_choose_default_routines(ctx, 0, &dec))) {
			rc = rd_fail(s, name, diag, rv, "decoder");
			break;
		}
		if ((rv = exr_decoding_run(ctx, 0, &dec))) {
			rc = rd_fail(s, name, diag, rv, "decoding a chunk");
			break;
		}
		for (int i = 0; i < dec.channel_count; i++) {
			const uint8_t *src = tmp + (size_t)i * lines * img->width * 4;
			size_t n = (size_t)ci.height * img->width;
			float *dst = img->data +
			             ((size_t)map[i] * img->height + (size_t)row0) * img->width;
			switch (dec.channels[i].data_type) {
			case EXR_PIXEL_HALF:
				for (size_t k = 0; k < n; k++) {
					uint16_t h;
					memcpy(&h, src + 2 * k, 2);
					dst[k] = loom_half_to_float(h);
				}
				break;
			case EXR_PIXEL_UINT:
				for (size_t k = 0; k < n; k++) {
					uint32_t u;
					memcpy(&u, src + 4 * k, 4);
					dst[k] = (float)u;
				}
				break;
			default:
				memcpy(dst, src, n * 4);
				break;
			}
		}
	}
	if (dec_ready)
		exr_decoding_destroy(ctx, &dec);
	free(tmp);
	free(map);
	return rc;
}

static int exr_parse_max(const uint8_t *data, size_t len, const char *name,
                         uint64_t max_pixels, loom_exr_image **out,
                         loom_diag *diag)
{
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	exr_context_t ctx = NULL;
	const exr_attr_chlist_t *chl;
	exr_attr_box2i_t dw;
	exr_storage_t storage;
	exr_compression_t comp;
	loom_exr_image *img = NULL;
	rd_state s;
	exr_result_t rv;
	int parts, rc = LOOM_OK;
	uint64_t w64, h64, values;

	if (!name)
		name = "exr";
	if (!out || (!data && len))
		return loom__fail(diag, LOOM_EINVAL, "%s: NULL argument", name);
	*out = NULL;
	memset(&s, 0, sizeof s);
	s.msg = s.msgbuf;
	s.data = data;
	s.len = len;
	init.user_data = &s;
	init.read_fn = read_cb;
	init.size_fn = size_cb;
	init.error_handler_fn = exr_err_cb;
	init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
	if ((rv = exr_start_read(&ctx, name, &init)))
		return rd_fail(&s, name, diag, rv, "cannot read the header");
	if ((rv = exr_get_count(ctx, &parts)) || parts != 1) {
		rc = rv ? rd_fail(&s, name, diag, rv, "parts")
		        : loom__fail(diag, LOOM_EUNSUPPORTED, "%s: %d parts; loom reads "
		                     "single-part images", name, parts);
		goto done;
	}
	if ((rv = exr_get_storage(ctx, 0, &storage)) ||
	    storage != EXR_STORAGE_SCANLINE) {
		rc = rv ? rd_fail(&s, name, diag, rv, "storage")
		        : loom__fail(diag, LOOM_EUNSUPPORTED, "%s: tiled or deep image; "
		                     "loom reads scanline images", name);
		goto done;
	}
	if ((rv = exr_get_data_window(ctx, 0, &dw)) ||
	    (rv = exr_get_channels(ctx, 0, &chl)) ||
	    (rv = exr_get_compression(ctx, 0, &comp))) {
		rc = rd_fail(&s, name, diag, rv, "header");
		goto done;
	}
	w64 = (uint64_t)((int64_t)dw.max.x - dw.min.x + 1);
	h64 = (uint64_t)((int64_t)dw.max.y - dw.min.y + 1);
	if (dw.max.x < dw.min.x || dw.max.y < dw.min.y || chl->num_channels < 1) {
		rc = loom__fail(diag, LOOM_EFORMAT, "%s: empty image", name);
		goto done;
	}
	/* a ZIP chunk expands at most ~1032x: refuse sizes no file this long
	   can hold, before allocating */
	values = 0;
	if (w64 <= INT32_MAX && h64 <= INT32_MAX && /* then w64*h64 < 2^62 */
	    w64 * h64 <= (UINT64_MAX >> 2) / (uint64_t)chl->num_channels)
		values = w64 * h64 * (uint64_t)chl->num_channels;
	if (w64 > max_pixels || h64 > max_pixels / w64) {
		rc = loom__fail(diag, LOOM_ERANGE, "%s: %llux%llu image is larger than "
		                "%llu pixels", name, (unsigned long long)w64,
		                (unsigned long long)h64, (unsigned long long)max_pixels);
		goto done;
	}
	if (values == 0 || values / 1032 / 2 > len + 4096 ||
	    values > (SIZE_MAX / 8)) {
		rc = loom__fail(diag, LOOM_ERANGE, "%s: %llux%llu image with %d "
		                "channels cannot be held in %zu bytes", name,
		                (unsigned long long)w64, (unsigned long long)h64,
		                chl->num_channels, len);
		goto done;
	}
	img = calloc(1, sizeof *img);
	if (!img) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
		goto done;
	}
	img->width = (uint32_t)w64;
	img->height = (uint32_t)h64;
	img->compression = (int)comp;
	img->names = calloc((size_t)chl->num_channels, sizeof *img->names);
	img->pixel = calloc((size_t)chl->num_channels, sizeof *img->pixel);
	img->data = calloc((size_t)values, sizeof(float));
	if (!img->names || !img->pixel || !img->data) {
		rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
		goto done;
	}
	img->n_channels = (uint32_t)chl->num_channels;
	for (int c = 0; c < chl->num_channels; c++) {
		const exr_attr_chlist_entry_t *e = &chl->entries[c];
		img->names[c] = malloc((size_t)e->name.length + 1);
		if (!img->names[c]) {
			rc = loom__fail(diag, LOOM_ENOMEM, "%s: out of memory", name);
			goto done;
		}
		memcpy(img->names[c], e->name.str, (size_t)e->name.length);
		img->names[c][e->name.length] = 0;
		img->pixel[c] = e->pixel_type == EXR_PIXEL_HALF ? LOOM_EXR_HALF
		                : e->pixel_type == EXR_PIXEL_UINT ? LOOM_EXR_UINT
		                                                  : LOOM_EXR_FLOAT;
		if (e->x_sampling != 1 || e->y_sampling != 1) {
			rc = loom__fail(diag, LOOM_EUNSUPPORTED, "%s: channel \"%s\" is "
			                "subsampled", name, img->names[c]);
			goto done;
		}
	}
	{
		exr_attr_v3d_t v;
		int32_t z;
		if (exr_attr_get_int(ctx, 0, "loomSliceZ", &z) == EXR_ERR_SUCCESS) {
			img->has_slice = 1;
			img->slice_z = z;
			if (exr_attr_get_v3d(ctx, 0, "loomVoxelSize", &v) == EXR_ERR_SUCCESS)
				for (int a = 0; a < 3; a++)
					img->voxel_mm[a] = v.arr[a];
			if (exr_attr_get_v3d(ctx, 0, "loomOrigin", &v) == EXR_ERR_SUCCESS)
				for (int a = 0; a < 3; a++)
					img->origin_mm[a] = v.arr[a];
		}
		s.msgbuf[0] = 0; /* missing optional attributes are not errors */
	}
	rc = read_pixels(ctx, &s, name, img, &dw, diag);
done:
	if (ctx)
		exr_finish(&ctx);
	if (rc) {
		loom_exr_image_free(img);
		return rc;
	}
	*out = img;
	return LOOM_OK;
}

LOOM_API int loom_exr_parse(const uint8_t *data, size_t len, const char *name,
                            loom_exr_image **out, loom_diag *diag)
{
	return exr_parse_max(data, len, name, UINT64_MAX, out, diag);
}

/* an OpenEXR file starts with the magic number 20000630 (76 2f 31 01) */
static int exr_head(const uint8_t *head, size_t n, const char *path,
                    loom_diag *diag)
{
	if (n >= 4 && memcmp(head, "\x76\x2f\x31\x01", 4) == 0)
		return LOOM_OK;
	return loom__fail(diag, n < 4 ? LOOM_ETRUNCATED : LOOM_EFORMAT,
	                  "%s: not an OpenEXR file (%s)", path,
	                  n < 4 ? "shorter than the 4-byte magic number"
	                        : "no magic number 76 2f 31 01 at byte 0");
}

LOOM_API int loom_exr_read(const char *path, loom_exr_image **out,
                           loom_diag *diag)
{
	uint8_t *data;
	size_t len;
	int rc;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_exr_read: NULL argument");
	*out = NULL;
	rc = loom__read_file_checked(path, (size_t)1 << 36, "OpenEXR", exr_head,
	                             &data, &len, diag);
	if (rc)
		return rc;
	rc = loom_exr_parse(data, len, path, out, diag);
	free(data);
	return rc;
}

LOOM_API int loom_exr_read_max(const char *path, uint64_t max_pixels,
                               size_t max_bytes, loom_exr_image **out,
                               loom_diag *diag)
{
	uint8_t *data;
	size_t len;
	int rc;

	if (!path || !out)
		return loom__fail(diag, LOOM_EINVAL, "loom_exr_read_max: NULL argument");
	*out = NULL;
	rc = loom__read_file_checked(path, max_bytes, "OpenEXR", exr_head, &data,
	                             &len, diag);
	if (rc)
		return rc;
	rc = exr_parse_max(data, len, path, max_pixels, out, diag);
	free(data);
	return rc;
}
