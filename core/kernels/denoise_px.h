/*
 * denoise_px.h — per-pixel steps around the bilateral grid: albedo
 * demodulation and remodulation, and the hand-made guide.
 *
 * Demodulation divides by ew_albedo_factor (albedo + EW_ALBEDO_EPSILON, the
 * public header's value) and remodulation multiplies by the same value, so a
 * pixel that is not filtered comes back exactly, black albedo (emitters,
 * background, black paint) amplifies noise at most 1/EPSILON times instead
 * of blowing up, and there is no threshold to make seams.
 */
#ifndef EW_KERNELS_DENOISE_PX_H
#define EW_KERNELS_DENOISE_PX_H

#include "edgewise/edgewise.h" /* EW_ALBEDO_EPSILON */
#include "kernels/color.h"

/* Packed per-pixel buffers of one denoise. albedo, normal and depth may be
 * NULL (feature absent). color/albedo/normal/out/sliced: 3 floats a pixel.
 * The inputs (color, albedo, normal, depth) may be a region of a wider
 * frame read where it lies (a tile of it): in_stride pixels a row; 0 when
 * they are packed width x height like the rest. */
typedef struct ew_denoise_buffers {
    int width, height;
    int in_stride;
    const float *color;
    const float *albedo;
    const float *normal;   /* in [-1, 1] */
    const float *depth;
    float depth_scale;     /* 1 / (largest finite foreground depth) */
    float *radiance;       /* demodulated colour */
    float *guide;          /* in [0, 255] */
    float *sliced;         /* filtered radiance */
    float *out;
} ew_denoise_buffers;

EW_HD float ew_feature_or_zero(float v) { return ew_finitef(v) ? v : 0.0f; }

/* What one albedo channel divides and multiplies by: a damaged or negative
 * albedo counts as black, so it cannot turn a pixel into NaN. */
EW_HD float ew_albedo_factor(float albedo) { return (ew_finitef(albedo) && albedo > 0.0f ? albedo : 0.0f) + EW_ALBEDO_EPSILON; }

/* The inputs' index of pixel j of the buffers. */
EW_HD long ew_denoise_in_px(const ew_denoise_buffers *b, long j) {
    return b->in_stride ? j / b->width * b->in_stride + j % b->width : j;
}

/* Pixel j (of the buffers; i = ew_denoise_in_px of it) */
EW_HD void ew_denoise_prepare_px(long j, long i, const ew_denoise_buffers *b) {
    const float *c = b->color + i * 3;
    float *r = b->radiance + j * 3;
    for (int k = 0; k < 3; k++) {
        float den = b->albedo ? ew_albedo_factor(b->albedo[i * 3 + k]) : 1.0f;
        /* Negative radiance is not light (a compositing or reconstruction
         * artefact): splatted, one such sample darkens the whole cell
         * around it, so it counts as black. NaN and +-Inf stay non-finite
         * and the splat skips them as missing. */
        r[k] = (c[k] < 0.0f && ew_finitef(c[k]) ? 0.0f : c[k]) / den;
    }
    /* Guide: the mean of the normalised features (Meng et al. Fig. 7
     * baseline); without features, the gamma-encoded luminance. */
    float sum = 0.0f;
    int n = 0;
    if (b->albedo) {
        for (int k = 0; k < 3; k++) sum += ew_clampf(ew_feature_or_zero(b->albedo[i * 3 + k]), 0.0f, 1.0f);
        n += 3;
    }
    if (b->normal) {
        for (int k = 0; k < 3; k++)
            sum += ew_clampf(0.5f * (ew_feature_or_zero(b->normal[i * 3 + k]) + 1.0f), 0.0f, 1.0f);
        n += 3;
    }
    if (b->depth) {
        sum += ew_clampf(ew_feature_or_zero(b->depth[i]) * b->depth_scale, 0.0f, 1.0f);
        n += 1;
    }
    float g;
    if (n > 0) {
        g = sum / (float)n;
    } else {
        float lum = ew_luminance(c);
        if (!ew_finitef(lum)) lum = 0.0f;
        g = powf(ew_clampf(lum, 0.0f, 1.0f), 1.0f / 2.2f);
    }
    b->guide[j] = 255.0f * g;
}

/*
 * Refined guide for a second pass: the feature guide mixed with the
 * luminance of a first, lightly filtered estimate of the radiance, mapped by
 * l / (l + mean) so the image's mean lands at the middle of the range.
 * Features alone cannot see shading (soft shadows, light fall-off); the
 * first-pass estimate can, without the noise of the raw colour.
 */
EW_HD void ew_denoise_refine_guide_px(long j, const ew_denoise_buffers *b, float mean_lum, float color_weight) {
    float l = ew_maxf(ew_luminance(b->sliced + j * 3), 0.0f);
    float t = ew_finitef(l) ? l / (l + mean_lum) : 1.0f;
    b->guide[j] = (1.0f - color_weight) * b->guide[j] + color_weight * 255.0f * t;
}

EW_HD void ew_denoise_finish_px(long j, long i, const ew_denoise_buffers *b) {
    for (int k = 0; k < 3; k++) {
        float a = b->albedo ? ew_albedo_factor(b->albedo[i * 3 + k]) : 1.0f;
        float v = b->sliced[j * 3 + k] * a;
        b->out[j * 3 + k] = ew_finitef(v) ? v : 0.0f;
    }
}

#endif
