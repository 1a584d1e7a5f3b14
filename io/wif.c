/* io/wif.c - WIF 1.1 reader.  PLACEHOLDER until the WIF reader lands. */
#include "internal.h"

LOOM_API int loom_wif_parse(const char *text, size_t len, const char *name,
                            loom_design **out, loom_diag *diag)
{
	(void)text; (void)len;
	if (out)
		*out = NULL;
	return loom__fail(diag, LOOM_EUNSUPPORTED, "%s: WIF reader not built yet", name);
}

LOOM_API int loom_wif_read(const char *path, loom_design **out, loom_diag *diag)
{
	return loom_wif_parse(NULL, 0, path, out, diag);
}
