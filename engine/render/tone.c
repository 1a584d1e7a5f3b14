/*
 * engine/render/tone.c - tone curves from the renderer's linear radiance to
 * 8-bit sRGB (loom/render.h, enum loom_tone; docs/rendering.md "Tone").
 */
#include "render_internal.h"

LOOM_API double loom_tone_filmic(double x)
{
	double y;
	if (!(x > 0))
		return 0.0;
	if (x > 1e6) /* the curve's limit 2.51 / 2.43 is above 1 */
		return 1.0;
	y = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14);
	return y < 1.0 ? y : 1.0;
}

LOOM_API void loom_render_to_srgb8_tone(const float *rgb, size_t n_pixels,
                                        double exposure, int tone, uint8_t *out)
{
	double k = pow(2.0, exposure);
	if (!rgb || !out)
		return;
	if (tone != LOOM_TONE_FILMIC) {
		loom_render_to_srgb8(rgb, n_pixels, exposure, out);
		return;
	}
	for (size_t i = 0; i < n_pixels; i++) {
		float v[3]; /* the curve's output is display-linear: encode it */
		for (int j = 0; j < 3; j++)
			v[j] = (float)loom_tone_filmic(rgb[3 * i + (size_t)j] * k);
		loom_render_to_srgb8(v, 1, 0.0, out + 3 * i);
	}
}
