/*
 * guidenet.h — the per-pixel steps of the neural bilateral grid around the
 * GuideNet convolutions (Meng et al. 2020, §4-§5): the network's input
 * features, the blend of the sliced grids, the loss's tone curve, and their
 * derivatives. Plain C that nvcc also compiles.
 */
#ifndef EW_KERNELS_GUIDENET_H
#define EW_KERNELS_GUIDENET_H

#include "kernels/denoise_px.h"

#define EW_GN_INPUTS 10 /* GuideNet input channels */

/*
 * Input features of pixel j into planes dst[c * ps] (c = 0..9), all in [0, 1]
 * as in the authors' code: tone-mapped colour clip(c, 0, 1)^(1/2.2) (3),
 * albedo (3), normal mapped by (n + 1) / 2 (3), depth times depth_scale (1).
 * Non-finite samples: +Inf colour (half overflow) reads as 1, NaN as 0; a
 * non-finite feature reads as 0 (as in the hand-made guide). color, albedo,
 * normal: 3 floats a pixel; depth: 1.
 */
EW_HD void ew_gn_input_px(long j, const float *EW_RESTRICT color, const float *EW_RESTRICT albedo,
                          const float *EW_RESTRICT normal, const float *EW_RESTRICT depth, float depth_scale,
                          float *EW_RESTRICT dst, long ps) {
    for (int k = 0; k < 3; k++) {
        float c = color[j * 3 + k];
        c = c != c ? 0.0f : ew_clampf(c, 0.0f, 1.0f); /* NaN -> 0, +-Inf clamp */
        dst[k * ps] = powf(c, 1.0f / 2.2f);
        dst[(3 + k) * ps] = ew_clampf(ew_feature_or_zero(albedo[j * 3 + k]), 0.0f, 1.0f);
        dst[(6 + k) * ps] = ew_clampf(0.5f * (ew_feature_or_zero(normal[j * 3 + k]) + 1.0f), 0.0f, 1.0f);
    }
    dst[9 * ps] = ew_clampf(ew_feature_or_zero(depth[j]) * depth_scale, 0.0f, 1.0f);
}

/*
 * Blend weights of the three grids from the network's two blend outputs
 * s0, s1 in (0, 1) by stick breaking:
 *   w0 = s0,  w1 = (1 - s0) s1,  w2 = (1 - s0)(1 - s1).
 * All three lie in [0, 1] and sum to exactly 1 — a partition of unity. (The
 * paper's w2 = 1 - w0 - w1 goes negative whenever s0 + s1 > 1, which makes
 * the blend extrapolate.)
 */
EW_HD void ew_nbg_weights(float s0, float s1, float *w) {
    w[0] = s0;
    w[1] = (1.0f - s0) * s1;
    w[2] = (1.0f - s0) * (1.0f - s1);
}

/* Given dL/dw, dL/ds0 and dL/ds1. */
EW_HD void ew_nbg_weights_backward(float s0, float s1, const float *dw, float *ds0, float *ds1) {
    *ds0 = dw[0] - s1 * dw[1] - (1.0f - s1) * dw[2];
    *ds1 = (1.0f - s0) * (dw[1] - dw[2]);
}

/*
 * Tone curve of the loss (Eq. 14's S): the display transform
 * clip(x, 0, 1)^(1/2.2) that the PSNR/SSIM metrics use, with two changes
 * for the gradient: an epsilon inside the power, so the slope at black is
 * finite ((1/2.2) eps^(-0.55) ~ 20 rather than infinite), and a gentle
 * log shoulder above 1 instead of the clip, so an output overshooting a
 * reference (a spread firefly) still gets a gradient.
 *   x <= 1: (max(x, 0) + eps)^(1/2.2) - eps^(1/2.2)
 *   x >  1: S(1) + 0.1 ln x
 */
#define EW_NBG_TM_EPS 1e-3f
#define EW_NBG_TM_SHOULDER 0.1f

EW_HD float ew_nbg_tm(float x) {
    const float g = 1.0f / 2.2f, e0 = powf(EW_NBG_TM_EPS, g);
    if (x > 1.0f) return powf(1.0f + EW_NBG_TM_EPS, g) - e0 + EW_NBG_TM_SHOULDER * logf(x);
    return powf(ew_maxf(x, 0.0f) + EW_NBG_TM_EPS, g) - e0;
}

EW_HD float ew_nbg_tm_grad(float x) {
    const float g = 1.0f / 2.2f;
    if (x > 1.0f) return EW_NBG_TM_SHOULDER / x;
    if (x <= 0.0f) return 0.0f;
    return g * powf(x + EW_NBG_TM_EPS, g - 1.0f);
}

/*
 * Blend pixel j of grid s into the running sum: acc += w_s * sliced.
 * outputs: the network's planes (plane stride ps), grids 0..ngrids-1 first,
 * then the two blend outputs when ngrids == 3. With one grid w0 = 1.
 * s == 0 overwrites acc instead of adding.
 */
EW_HD void ew_nbg_blend_px(long j, int s, int ngrids, const float *EW_RESTRICT outputs, long ps,
                           const float *EW_RESTRICT sliced, float *EW_RESTRICT acc) {
    float w[3] = {1.0f, 0.0f, 0.0f};
    if (ngrids == 3) ew_nbg_weights(outputs[3 * ps + j], outputs[4 * ps + j], w);
    for (int k = 0; k < 3; k++) {
        float v = w[s] * sliced[j * 3 + k];
        acc[j * 3 + k] = s == 0 ? v : acc[j * 3 + k] + v;
    }
}

/* Work descriptions of the backend table's GuideNet entries. */
typedef struct ew_gn_input_args {
    int width, y0, y1;   /* image rows [y0, y1) */
    const float *color, *albedo, *normal, *depth; /* whole image, in_stride pixels a row (0: width) */
    long in_stride;
    float depth_scale;
    float *dst;          /* plane 0 at image row y0, x = 0 */
    long rs, ps;
} ew_gn_input_args;

typedef struct ew_nbg_blend_args {
    long n;              /* pixels */
    int s, ngrids;       /* blend grid s (s == 0 starts the sum) */
    const float *outputs; /* GuideNet outputs, n floats a plane */
    const float *sliced; /* grid s sliced, 3 floats a pixel */
    float *acc;          /* 3 floats a pixel */
} ew_nbg_blend_args;

/* Guides on the grid's 0..255 range from the network's sigmoid outputs. */
EW_HD void ew_nbg_guide_px(long j, long n, int ngrids, float *outputs) {
    for (int s = 0; s < ngrids; s++) outputs[s * n + j] *= 255.0f;
}

#endif
