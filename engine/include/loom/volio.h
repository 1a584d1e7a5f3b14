/*
 * loom/volio.h - volume and image file formats (io/): Mitsuba grid volumes
 * (.vol), NRRD (reader), raw volumes, and OpenEXR z-slices.
 * Include <loom.h>, not this file.  Format details: docs/volumes.md.
 *
 * Every interface here is data only: callers pass buffers of values, the
 * library never reaches into the engine.  Conventions shared by all:
 *  - Voxel order is x fastest, then y, then z, channels interleaved:
 *    value (x, y, z, c) is at ((z*ny + y)*nx + x)*channels + c.
 *  - Readers return float values (see each reader for scaling).  Readers
 *    from memory (`*_parse`) take a `name` used in messages; readers from a
 *    path use the path.  Messages name the byte offset (binary formats) or
 *    line (NRRD headers) and what was expected.
 *  - Whole-volume reads take `max_bytes`, a cap on the float output
 *    (0 = no cap beyond the checks against the file's real size); a volume
 *    over the cap fails with LOOM_EBUDGET before anything is allocated.
 *  - Writers are streaming and atomic: data go to "<path>.tmp.<pid>.<n>"
 *    and are renamed over `path` only by a successful *_finish; *_abort (or
 *    a failed *_finish) removes the temporary file; *_finish frees the
 *    writer whatever it returns.  A streaming handle (loom_vol_reader,
 *    loom_raw_reader, loom_vol_writer, loom_exr_writer) becomes unusable
 *    after a failed read or write (I/O error, file ending early) or, for
 *    a writer, after values sent past the declared size (or, .vol,
 *    put_slices after a partial slice): every later call returns
 *    LOOM_EUNUSABLE, and a writer's *_finish then removes the temporary
 *    file.  Argument errors (NULL pointers, a read box outside the volume)
 *    are returned without changing the handle.
 *  - Handles are not thread-safe; distinct handles may be used from
 *    distinct threads.  Close/free/abort functions accept NULL.
 */
#ifndef LOOM_VOLIO_H
#define LOOM_VOLIO_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Scalar types and the in-memory float volume ---------------------- */

/* Types of stored values (file side).  Values are stable. */
enum loom_scalar_type {
	LOOM_SCALAR_U8 = 1,
	LOOM_SCALAR_I8 = 2,
	LOOM_SCALAR_U16 = 3,
	LOOM_SCALAR_I16 = 4,
	LOOM_SCALAR_U32 = 5,
	LOOM_SCALAR_I32 = 6,
	LOOM_SCALAR_F16 = 7,   /* IEEE 754 binary16 */
	LOOM_SCALAR_F32 = 8,
	LOOM_SCALAR_F64 = 9
};

/* Bytes per value of a loom_scalar_type; 0 for an unknown type. */
LOOM_API size_t loom_scalar_size(int type);
/* Short name ("u8", "u16", "f32", ...); "unknown" for an unknown type. */
LOOM_API const char *loom_scalar_name(int type);
/* Parse a type name: u8 uint8 uchar, i8 int8, u16 uint16 ushort, i16 int16
   short, u32 uint32 uint, i32 int32 int, f16 half float16, f32 float
   float32, f64 double float64 (case-insensitive).  LOOM_EINVAL if unknown. */
LOOM_API int loom_scalar_parse(const char *name, int *type);

/* IEEE binary16 conversions (round to nearest even; NaN stays NaN,
   overflow gives infinity).  Exact for every half value. */
LOOM_API float loom_half_to_float(uint16_t h);
LOOM_API uint16_t loom_half_from_float(float f);

/*
 * A volume of float values read from a file, with its geometry.  Owned by
 * the caller; free with loom_volbuf_free.
 */
typedef struct loom_volbuf {
	uint32_t nx, ny, nz;   /* voxels along x, y, z */
	uint32_t channels;     /* float values per voxel */
	double spacing[3];     /* distance between voxel centres along x, y, z
	                          (the file's unit; 1 when the file has none) */
	double origin[3];      /* position of voxel (0,0,0) (0 when none) */
	int source_type;       /* loom_scalar_type of the stored values */
	float *data;           /* nx*ny*nz*channels values, order above */
} loom_volbuf;

/* Allocate a zero-filled volume (spacing 1, origin 0, source_type F32).
   LOOM_EINVAL for a zero size, LOOM_ERANGE when the size overflows,
   LOOM_EBUDGET when the floats exceed max_bytes (0 = no cap),
   LOOM_ENOMEM. */
LOOM_API int loom_volbuf_new(uint32_t nx, uint32_t ny, uint32_t nz,
                             uint32_t channels, size_t max_bytes,
                             loom_volbuf **out, loom_diag *diag);
/* Free a volume and its data; NULL is fine. */
LOOM_API void loom_volbuf_free(loom_volbuf *v);

/* ---- Mitsuba grid volume (.vol) ----------------------------------------- */

#define LOOM_VOL_HEADER_BYTES 48
#define LOOM_VOL_MAX_CHANNELS 64   /* loom's limit (Mitsuba 0.6 reads 1 or 3) */

/* Encodings of a .vol file (int32 at byte 4).  Values are Mitsuba's. */
enum loom_vol_encoding {
	LOOM_VOL_FLOAT32 = 1,  /* 4 bytes per value */
	LOOM_VOL_FLOAT16 = 2,  /* 2 bytes per value (Mitsuba 0.6 cannot read it) */
	LOOM_VOL_UINT8 = 3,    /* 1 byte per value, read as byte / 255 */
	LOOM_VOL_QDIR = 4      /* 2 bytes per voxel (theta, phi): a unit vector;
	                          channels must be 3 */
};

typedef struct loom_vol_header {
	int32_t encoding;      /* enum loom_vol_encoding */
	uint32_t xres, yres, zres; /* voxels, each 1 .. INT32_MAX */
	uint32_t channels;     /* values per voxel (decoded floats per voxel) */
	float bbox_min[3];     /* xmin ymin zmin */
	float bbox_max[3];     /* xmax ymax zmax */
} loom_vol_header;

/* Parse and validate the 48-byte header at the start of `data`.  Checks
   magic, version 3, encoding, resolutions >= 1, channel count, finite
   bounding box.  Does not look at the voxel data.
   Errors: LOOM_ETRUNCATED (len < 48), LOOM_EFORMAT (bad magic, encoding,
   resolution, channels, bounding box), LOOM_EVERSION, LOOM_ERANGE
   (channels above LOOM_VOL_MAX_CHANNELS). */
LOOM_API int loom_vol_header_parse(const uint8_t *data, size_t len,
                                   const char *name, loom_vol_header *h,
                                   loom_diag *diag);

/* Bytes of voxel data the header declares (after the 48 header bytes),
   overflow-checked: LOOM_ERANGE if it does not fit in 63 bits, LOOM_EINVAL
   for an invalid header. */
LOOM_API int loom_vol_data_bytes(const loom_vol_header *h, uint64_t *bytes);

/* Quantized directions (encoding 4) exactly as Mitsuba 0.5/0.6 decode them:
   theta = t*pi/255, phi = p*2pi/255, v = (cos phi sin theta,
   sin phi sin theta, cos theta); t = 255 is exactly (0,0,-1).  Encoding
   normalises v and rounds to the nearest (t, p); a zero or non-finite
   vector encodes as (0, 0), i.e. (0,0,1) (the format has no zero). */
LOOM_API void loom_vol_qdir_encode(const float v[3], uint8_t tp[2]);
LOOM_API void loom_vol_qdir_decode(const uint8_t tp[2], float v[3]);

/* Whole-volume read from memory / from a file.  Decodes every encoding to
   float (uint8 as byte/255, float16 exactly, directions to 3 floats).
   *out gets nx=xres.. , channels, spacing (bbox extent / (res-1): Mitsuba
   0.6 puts sample i at min + i*extent/(res-1); extent when res is 1) and
   origin = bbox_min.  `h` (may be NULL) receives the header.
   Errors: as loom_vol_header_parse, plus LOOM_ETRUNCATED (data shorter
   than declared; message gives both sizes), LOOM_EBUDGET (over
   max_bytes), LOOM_ENOMEM, LOOM_EIO.  Trailing bytes after the data are
   a warning. */
LOOM_API int loom_vol_parse(const uint8_t *data, size_t len, const char *name,
                            size_t max_bytes, loom_vol_header *h,
                            loom_volbuf **out, loom_diag *diag);
LOOM_API int loom_vol_read(const char *path, size_t max_bytes,
                           loom_vol_header *h, loom_volbuf **out,
                           loom_diag *diag);

/* Random access to a .vol file without loading it.  open checks the
   header and that the file holds all declared data. */
typedef struct loom_vol_reader loom_vol_reader;
LOOM_API int loom_vol_open(const char *path, loom_vol_reader **out,
                           loom_diag *diag);
/* The file's header (owned by the reader). */
LOOM_API const loom_vol_header *loom_vol_reader_header(const loom_vol_reader *r);
/* Decode the box [x0, x0+nx) x [y0, y0+ny) x [z0, z0+nz) into out
   (nx*ny*nz*channels floats, x fastest).  LOOM_ERANGE if the box leaves
   the volume, LOOM_EIO / LOOM_ETRUNCATED if the file changed underneath. */
LOOM_API int loom_vol_read_box(loom_vol_reader *r, uint32_t x0, uint32_t y0,
                               uint32_t z0, uint32_t nx, uint32_t ny,
                               uint32_t nz, float *out, loom_diag *diag);
LOOM_API void loom_vol_close(loom_vol_reader *r);

/*
 * Streaming writer.  open writes the header; the caller then appends the
 * voxels in file order (z-slices, or any number of voxels at a time) as
 * floats, `channels` per voxel (3 per voxel for LOOM_VOL_QDIR: a
 * direction).  uint8 stores round(clamp(v, 0, 1) * 255) (NaN as 0).
 * finish fails with LOOM_ETRUNCATED, removing the temporary file, unless
 * exactly xres*yres*zres voxels were written; appending past the end is
 * LOOM_ERANGE.  Memory: a fixed 64 KiB encode buffer.
 */
typedef struct loom_vol_writer loom_vol_writer;
LOOM_API int loom_vol_writer_open(const char *path, const loom_vol_header *h,
                                  loom_vol_writer **out, loom_diag *diag);
/* Append n_slices whole z-slices (n_slices*xres*yres*channels floats). */
LOOM_API int loom_vol_writer_put_slices(loom_vol_writer *w, const float *values,
                                        uint32_t n_slices, loom_diag *diag);
/* Append n_voxels voxels (n_voxels*channels floats), e.g. one row. */
LOOM_API int loom_vol_writer_put_voxels(loom_vol_writer *w, const float *values,
                                        uint64_t n_voxels, loom_diag *diag);
/* Check the count, flush, fsync and rename.  Frees w in every case. */
LOOM_API int loom_vol_writer_finish(loom_vol_writer *w, loom_diag *diag);
/* Remove the temporary file and free w.  NULL is fine. */
LOOM_API void loom_vol_writer_abort(loom_vol_writer *w);

/* ---- Raw volumes --------------------------------------------------------- */

/* Flags of loom_raw_params. */
#define LOOM_RAW_ALLOW_TRAILING 1u  /* bytes after the data are not an error */
#define LOOM_RAW_DATA_AT_END    2u  /* data are the last bytes of the file
                                       (offset ignored; NRRD byte skip -1) */
#define LOOM_RAW_NORMALIZE      4u  /* integers scaled to 0..1 (u8 / 255,
                                       u16 / 65535, ...; signed to -1..1) */

/* What the caller knows about a raw volume.  Initialise with
   LOOM_RAW_PARAMS_INIT, then set nx, ny, nz and type at least. */
typedef struct loom_raw_params {
	size_t size;           /* sizeof (loom_raw_params) */
	uint32_t nx, ny, nz;   /* voxels along x, y, z */
	uint32_t channels;     /* values per voxel, interleaved (>= 1) */
	int type;              /* loom_scalar_type (U8, U16, F32, or any other) */
	int big_endian;        /* 1: most significant byte first */
	uint64_t offset;       /* bytes to skip before the data */
	uint32_t flags;        /* LOOM_RAW_* */
	double spacing[3];     /* voxel size along x, y, z, copied to the volbuf */
	double origin[3];      /* copied to the volbuf */
} loom_raw_params;

#define LOOM_RAW_PARAMS_INIT                                                  \
	{ sizeof(loom_raw_params), 0, 0, 0, 1, LOOM_SCALAR_U8, 0, 0, 0,           \
	  {1.0, 1.0, 1.0}, {0.0, 0.0, 0.0} }

/* Whole-volume read.  The data size must equal offset + nx*ny*nz*channels*
   size(type) bytes (unless the flags allow more): LOOM_ETRUNCATED when
   shorter, LOOM_ECORRUPT when longer; both messages give the expected and
   actual sizes and what the dimensions imply.  LOOM_EINVAL for zero
   dimensions, an unknown type or a bad params size. */
LOOM_API int loom_raw_parse(const uint8_t *data, size_t len, const char *name,
                            const loom_raw_params *p, size_t max_bytes,
                            loom_volbuf **out, loom_diag *diag);
LOOM_API int loom_raw_read(const char *path, const loom_raw_params *p,
                           size_t max_bytes, loom_volbuf **out,
                           loom_diag *diag);

/* Streaming access: slices z0 .. z0+nz-1 into out (nx*ny*nz*channels
   floats).  open performs the same size checks as loom_raw_read. */
typedef struct loom_raw_reader loom_raw_reader;
LOOM_API int loom_raw_open(const char *path, const loom_raw_params *p,
                           loom_raw_reader **out, loom_diag *diag);
LOOM_API int loom_raw_read_slices(loom_raw_reader *r, uint32_t z0, uint32_t nz,
                                  float *out, loom_diag *diag);
LOOM_API void loom_raw_close(loom_raw_reader *r);

/* ---- NRRD (reader) ------------------------------------------------------ */

#define LOOM_NRRD_MAX_DIM 4
#define LOOM_NRRD_PATH_MAX 1024

enum loom_nrrd_encoding {
	LOOM_NRRD_RAW = 1,
	LOOM_NRRD_GZIP = 2,
	LOOM_NRRD_ASCII = 3
};

/*
 * What a NRRD header says, plus the volume layout loom derives from it.
 * Axis 0 is the fastest.  Dimension 1..4: 1 is a row (ny = nz = 1), 2 a
 * slice (nz = 1), 3 a scalar volume, 4 a volume with a value axis first
 * (channels = sizes[0]).  A dimension-3 file whose axis 0 has a non-spatial
 * kind (vector, 3-vector, RGB-color, ...) or "none" space direction is a
 * multi-channel slice.
 */
typedef struct loom_nrrd_info {
	int version;           /* N of the "NRRD000N" magic (1..5) */
	int type;              /* loom_scalar_type */
	uint32_t dimension;    /* 1 .. LOOM_NRRD_MAX_DIM */
	uint64_t sizes[LOOM_NRRD_MAX_DIM];
	int encoding;          /* enum loom_nrrd_encoding */
	int big_endian;        /* 1 big, 0 little, -1 not given */
	double spacings[LOOM_NRRD_MAX_DIM]; /* per axis; NaN when not known */
	int has_directions;    /* "space directions" given */
	double directions[LOOM_NRRD_MAX_DIM][3]; /* NaN vector for "none" */
	int has_origin;        /* "space origin" given */
	double space_origin[3];
	uint32_t space_dim;    /* from "space" / "space dimension"; 0 if none */
	int64_t line_skip;     /* "line skip" (0 if none) */
	int64_t byte_skip;     /* "byte skip" (0 if none; -1 = data at end) */
	char data_file[LOOM_NRRD_PATH_MAX]; /* "" = attached data */
	size_t header_bytes;   /* bytes up to and including the blank line */
	/* derived layout */
	uint32_t channel_axis; /* 1 if axis 0 holds channels, else 0 */
	uint32_t nx, ny, nz, channels;
	double spacing[3];     /* per spatial axis: spacings, else the length
	                          of the space direction, else 1 */
	double origin[3];      /* space origin, else 0 */
} loom_nrrd_info;

/* Parse a NRRD header (NRRD0001..NRRD0005) from the start of `text`.  The
   header ends at the first empty line (attached data follow) or at the end
   of `text` (a detached header, which must name a data file).  Fields:
   type (all C names and int8..float64 aliases; 64-bit integers and
   "block" are LOOM_EUNSUPPORTED), dimension, sizes, endian, encoding (raw,
   gzip/gz, ascii/text/txt; hex and bzip2 are LOOM_EUNSUPPORTED),
   spacings, space directions, space origin, space, space dimension, kinds,
   data file / datafile (a single file; LIST and formatted lists are
   LOOM_EUNSUPPORTED), line skip, byte skip.  Other standard fields,
   comments and key:=value lines are accepted and ignored; unknown fields
   are warnings.  Errors name the line: LOOM_EFORMAT, LOOM_EVERSION,
   LOOM_EUNSUPPORTED, LOOM_ERANGE, LOOM_ETRUNCATED (no end of header when
   data are attached). */
LOOM_API int loom_nrrd_parse_header(const char *text, size_t len,
                                    const char *name, loom_nrrd_info *info,
                                    loom_diag *diag);

/* Read a whole NRRD (attached or detached) as floats (values unscaled:
   a uchar 200 reads as 200.0f; doubles are rounded to float).
   Detached data files are found relative to the header's directory.
   `info` may be NULL.  Errors as above plus size mismatches
   (LOOM_ETRUNCATED / LOOM_ECORRUPT, with sizes), gzip errors
   (LOOM_ECORRUPT), LOOM_EBUDGET, LOOM_ENOMEM, LOOM_EIO. */
LOOM_API int loom_nrrd_read(const char *path, size_t max_bytes,
                            loom_nrrd_info *info, loom_volbuf **out,
                            loom_diag *diag);
/* The same from memory; detached headers are LOOM_EUNSUPPORTED here. */
LOOM_API int loom_nrrd_parse(const uint8_t *data, size_t len, const char *name,
                             size_t max_bytes, loom_nrrd_info *info,
                             loom_volbuf **out, loom_diag *diag);
/* Stream a raw-encoded NRRD slice by slice: opens a loom_raw_reader on its
   data (attached or detached).  LOOM_EUNSUPPORTED for gzip and ascii
   (read those whole). */
LOOM_API int loom_nrrd_open(const char *path, loom_nrrd_info *info,
                            loom_raw_reader **out, loom_diag *diag);

/* ---- OpenEXR z-slices ----------------------------------------------------- */

enum loom_exr_pixel {
	LOOM_EXR_HALF = 1,
	LOOM_EXR_FLOAT = 2,
	LOOM_EXR_UINT = 3      /* reader only */
};

typedef struct loom_exr_channel {
	const char *name;      /* e.g. "density", "orientation.x", "R" */
	int pixel;             /* LOOM_EXR_HALF or LOOM_EXR_FLOAT */
} loom_exr_channel;

/* Counts filled by loom_exr_writer_finish (through options.stats). */
typedef struct loom_exr_stats {
	uint64_t chunks;       /* chunks written */
	uint64_t chunks_raw;   /* chunks stored uncompressed (zlib no smaller) */
	uint64_t chunks_equal; /* of those, zlib output exactly the raw size:
	                          the OpenEXR 3.1 corruption case, fixed here */
	uint64_t file_bytes;   /* size of the file written */
} loom_exr_stats;

typedef struct loom_exr_options {
	size_t size;           /* sizeof (loom_exr_options) */
	int zip_level;         /* 0..9, or -1 for the default (6) */
	int has_slice;         /* 1: write the slice attributes below */
	int32_t slice_z;       /* attribute "loomSliceZ" (int) */
	double voxel_mm[3];    /* attribute "loomVoxelSize" (v3d, mm) */
	double origin_mm[3];   /* attribute "loomOrigin" (v3d, mm): voxel (0,0) */
	loom_exr_stats *stats; /* optional, filled by finish */
	int openexr_zip;       /* 1: compress with OpenEXR's own zlib code (size
	                          guard applied) instead of loom's libdeflate
	                          encoder; both write standard ZIP chunks */
} loom_exr_options;

#define LOOM_EXR_OPTIONS_INIT                                                 \
	{ sizeof(loom_exr_options), -1, 0, 0, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0},   \
	  NULL, 0 }

/*
 * Streaming writer of one ZIP-compressed scanline image (one z-slice).
 * The caller sends rows top to bottom (y = 0 first); each row is width
 * pixels of n_channels floats in the order of `channels` (half channels
 * are rounded to half).  Memory: one 16-row chunk plus the codec's
 * buffers.  finish fails with LOOM_ETRUNCATED (and no file) unless every
 * row was sent.  Channel names: 1..255 bytes, unique.
 * Errors: LOOM_EINVAL (arguments), LOOM_EIO, LOOM_ENOMEM, LOOM_ERANGE
 * (rows past the end), LOOM_EUNSUPPORTED (OpenEXR refused).
 */
typedef struct loom_exr_writer loom_exr_writer;
LOOM_API int loom_exr_writer_open(const char *path, uint32_t width,
                                  uint32_t height,
                                  const loom_exr_channel *channels,
                                  uint32_t n_channels,
                                  const loom_exr_options *opt,
                                  loom_exr_writer **out, loom_diag *diag);
LOOM_API int loom_exr_writer_put_rows(loom_exr_writer *w, const float *pixels,
                                      uint32_t n_rows, loom_diag *diag);
/* Writes the last chunk, checks the chunk count, closes and renames.
   Frees w in every case. */
LOOM_API int loom_exr_writer_finish(loom_exr_writer *w, loom_diag *diag);
LOOM_API void loom_exr_writer_abort(loom_exr_writer *w);

/* A whole single-part scanline EXR image read back as floats. */
typedef struct loom_exr_image {
	uint32_t width, height;
	uint32_t n_channels;
	char **names;          /* channel names in file order (sorted) */
	int *pixel;            /* enum loom_exr_pixel of each channel */
	float *data;           /* planar: channel c, row y, column x at
	                          data[((size_t)c*height + y)*width + x] */
	int compression;       /* OpenEXR compression id (3 = ZIP) */
	int has_slice;         /* loom slice attributes present */
	int32_t slice_z;
	double voxel_mm[3], origin_mm[3];
} loom_exr_image;

/* Read through the OpenEXR Core API (half and uint converted to float,
   float bit-exact).  Tiled, deep and multi-part files: LOOM_EUNSUPPORTED.
   Other errors: LOOM_EFORMAT (OpenEXR's message), LOOM_EIO, LOOM_ENOMEM. */
LOOM_API int loom_exr_read(const char *path, loom_exr_image **out,
                           loom_diag *diag);
LOOM_API int loom_exr_parse(const uint8_t *data, size_t len, const char *name,
                            loom_exr_image **out, loom_diag *diag);
/* The same, refusing files over max_bytes (before reading them) and
   images over max_pixels (from the header, before reading pixels):
   LOOM_ERANGE naming the file. */
LOOM_API int loom_exr_read_max(const char *path, uint64_t max_pixels,
                               size_t max_bytes, loom_exr_image **out,
                               loom_diag *diag);
/* Index of the channel called `name`, or -1. */
LOOM_API int loom_exr_image_channel(const loom_exr_image *img, const char *name);
LOOM_API void loom_exr_image_free(loom_exr_image *img);

#ifdef __cplusplus
}
#endif
#endif /* LOOM_VOLIO_H */
