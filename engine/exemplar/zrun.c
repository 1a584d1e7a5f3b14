/*
 * engine/exemplar/zrun.c - the zero-run code of layout-4 density units
 * (docs/formats.md, "Zero-run density units").
 *
 * A density plane is mostly air: 58 % of the voxels of the paper
 * database's stored bricks are zero, in runs along z above and below the
 * yarns.  DEFLATE stores such a plane in 36 % of its bytes but inflates at
 * under 1 GB/s; this code stores it in 46 % and decodes at about 7 GB/s
 * (docs/performance.md, "Zero-run density units"), so a density lookup
 * that misses below the working set is paid in copying, not in Huffman
 * decoding.
 *
 * The stream is a sequence of tokens, one byte each:
 *   t in 0..127     t + 1 zero bytes (1..128)
 *   t in 128..255   t - 127 literal bytes (1..128) that follow the token
 * and decodes to exactly the plane's bytes.
 */
#include "db_internal.h"

#include <string.h>

#define ZRUN_MAX 128u /* longest run of either kind */

size_t loom__zrun_encode(const uint8_t *in, size_t n, uint8_t *out, size_t cap)
{
	size_t i = 0, o = 0, j;

	while (i < n) {
		if (in[i] == 0) {
			for (j = i + 1; j < n && j - i < ZRUN_MAX && in[j] == 0; j++)
				;
			if (o + 1 > cap)
				return 0;
			out[o++] = (uint8_t)(j - i - 1);
		} else {
			/* a literal run ends at two zeros in a row (one zero costs
			   a byte either way, so it stays inside the run) */
			for (j = i + 1; j < n && j - i < ZRUN_MAX; j++)
				if (in[j] == 0 && (j + 1 == n || in[j + 1] == 0))
					break;
			if (o + 1 + (j - i) > cap)
				return 0;
			out[o++] = (uint8_t)(127 + (j - i));
			memcpy(out + o, in + i, j - i);
			o += j - i;
		}
		i = j;
	}
	return o;
}

int loom__zrun_decode(const uint8_t *in, size_t m, uint8_t *out, size_t n,
                      size_t *where)
{
	size_t i = 0, o = 0, len, k;

	while (i < m) {
		unsigned t = in[i++];
		if (t < 128) {
			len = t + 1;
			if (len > n - o)
				goto bad;
			if (n - o >= ZRUN_MAX) /* room for whole 16-byte stores */
				for (k = 0; k < len; k += 16)
					memset(out + o + k, 0, 16);
			else
				memset(out + o, 0, len);
		} else {
			len = t - 127;
			if (len > n - o || len > m - i)
				goto bad;
			if (n - o >= ZRUN_MAX && m - i >= ZRUN_MAX)
				for (k = 0; k < len; k += 16)
					memcpy(out + o + k, in + i + k, 16);
			else
				memcpy(out + o, in + i, len);
			i += len;
		}
		o += len;
	}
	if (o == n)
		return 0;
	if (where)
		*where = i;
	return 1;
bad:
	if (where)
		*where = i - 1;
	return 1;
}
