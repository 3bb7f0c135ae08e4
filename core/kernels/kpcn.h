/*
 * kpcn.h — the per-pixel steps of the kernel-predicting denoiser "kpcn"
 * (Bako et al. 2017; multi-scale as Vogels et al. 2018) around its 5x5
 * convolutions (kernels/conv.h): the network's input features, 2x2 average
 * pooling, 2x bilinear upsampling, and the filter that applies a predicted
 * per-pixel 5x5 softmax kernel to the albedo-demodulated radiance and blends
 * the result with the coarser scale's output. With the backward pass of each
 * (used by the trainer on the host; scatters, one thread per patch). Plain C
 * that nvcc also compiles.
 *
 * Every tensor is addressed through strides in floats: value (c, y, x) at
 * data[c * cs + y * rs + x * xs], so the same functions read the
 * convolutions' zero-padded planes (xs = 1) and packed RGB (xs = 3, cs = 1).
 *
 * Why the output cannot invent energy: a softmax kernel is a convex
 * combination of the radiance around the pixel, the blend with the coarser
 * scale is convex too ((1 - a) f + a up(o), a = sigmoid), pooling and
 * bilinear upsampling are averages; so each output channel lies between
 * the smallest and largest demodulated radiance of the pixels it can see,
 * and the albedo is multiplied back afterwards.
 */
#ifndef EW_KERNELS_KPCN_H
#define EW_KERNELS_KPCN_H

#include "kernels/conv.h"
#include "kernels/denoise_px.h"
#include "kernels/fastmath.h"
#include "kernels/outlier.h"

#define EW_KPCN_INPUTS 10     /* network input planes of the per-pixel features */
#define EW_KPCN_MAX_INPUTS 11 /* and the frame's noise level, in the "-noise" models */
#define EW_KPCN_KR 2      /* predicted kernel radius: 5x5 */
#define EW_KPCN_TAPS 25
#define EW_KPCN_HEAD 26   /* head outputs: 25 kernel logits + the blend logit (unused at the coarsest scale) */
/* the full-resolution head of a net with a remodulation kernel ("-ra"
 * architectures): also the 25 logits of the kernel that filters the albedo
 * the output is multiplied back by */
#define EW_KPCN_HEAD_REMOD (EW_KPCN_HEAD + EW_KPCN_TAPS)

typedef struct ew_kpcn_tensor {
    float *data;
    long xs, rs, cs;
} ew_kpcn_tensor;

EW_HD float *ew_kpcn_at(const ew_kpcn_tensor *t, int c, int y, int x) {
    return t->data + (long)c * t->cs + (long)y * t->rs + (long)x * t->xs;
}

/*
 * Input features of pixel (x, y): log(1 + r) of the demodulated, firefly-
 * clamped radiance r (3; the kernels are applied to r, so the network sees
 * it, compressed), albedo clamped to [0, 1] (3), normal mapped by (n + 1)/2
 * (3), depth times depth_scale clamped to [0, 1] (1). A non-finite value
 * reads as 0. With noise_plane set, an 11th plane holds the frame's noise
 * level (ew_kpcn_noise_feature), the same at every pixel: a 5x5 window of
 * features cannot tell a converged frame's texture from 1-spp noise, which
 * the frame-wide level can.
 */
typedef struct ew_kpcn_input_args {
    int width, height;
    const float *radiance, *albedo, *normal, *depth; /* packed (3, 3, 3, 1 floats a pixel), at pixel (0, 0) */
    float depth_scale;
    float *dst; /* plane 0, row 0, x = 0 */
    long rs, ps;
    int noise_plane; /* 1: write plane 10 = noise */
    float noise;
    long src_rs; /* pixels a row of the packed sources (the frame's width: a tile reads its region of them) */
    /* pixels a row of albedo, normal, depth where not src_rs (a band of
     * them converted from halves, the region's width), else 0 */
    long albedo_rs, normal_rs, depth_rs;
} ew_kpcn_input_args;

/* The noise plane's value from the mean |HH| of the frame's compressed
 * demodulated radiance (kernels/reduce.h EW_REDUCE_NOISE): log-scaled into
 * [0, 1], 1e-4 (converged) -> 0, 1 -> 1; each 4x the samples lowers it by
 * about 0.075. */
EW_HD float ew_kpcn_noise_feature(double mean_abs_hh) {
    return ew_clampf(1.0f + 0.25f * log10f((float)mean_abs_hh + 1e-4f), 0.0f, 1.0f);
}

/* The feature from the 2 x height doubles of EW_REDUCE_NOISE, summed in row
 * order on the host, so the op and the trainer get the same bits. */
EW_HD float ew_kpcn_noise_from_rows(const double *rows, int height) {
    double sum = 0.0, count = 0.0;
    for (int y = 0; y < height; y++) {
        sum += rows[2 * y];
        count += rows[2 * y + 1];
    }
    return ew_kpcn_noise_feature(count > 0.0 ? sum / count : 0.0);
}

/* The radiance kpcn filters: firefly-clamped at k (0: no clamp) with the
 * shared outlier definition, and NaN/Inf samples rebuilt from their
 * neighbours: the op and the trainer's frames use these. */
EW_HD ew_outlier_params ew_kpcn_clamp_params(int width, int height, float k) {
    ew_outlier_params p = ew_outlier_plain_params(width, height, 2, k > 0.0f ? k : 0.0f);
    p.repair = 1;
    return p;
}

EW_HD void ew_kpcn_input_px(int x, int y, const ew_kpcn_input_args *a) {
    const long j = (long)y * a->src_rs + x;
    const long ja = (long)y * (a->albedo_rs ? a->albedo_rs : a->src_rs) + x;
    const long jn = (long)y * (a->normal_rs ? a->normal_rs : a->src_rs) + x;
    const long jd = (long)y * (a->depth_rs ? a->depth_rs : a->src_rs) + x;
    float *d = a->dst + (long)y * a->rs + x;
    for (int k = 0; k < 3; k++) {
        float r = ew_feature_or_zero(a->radiance[j * 3 + k]);
        d[k * a->ps] = logf(1.0f + ew_maxf(r, 0.0f));
        d[(3 + k) * a->ps] = ew_clampf(ew_feature_or_zero(a->albedo[ja * 3 + k]), 0.0f, 1.0f);
        d[(6 + k) * a->ps] = ew_clampf(0.5f * (ew_feature_or_zero(a->normal[jn * 3 + k]) + 1.0f), 0.0f, 1.0f);
    }
    d[9 * a->ps] = ew_clampf(ew_feature_or_zero(a->depth[jd]) * a->depth_scale, 0.0f, 1.0f);
    if (a->noise_plane) d[10 * a->ps] = a->noise;
}

/* ---- 2x2 average pooling ------------------------------------------------
 * Coarse (x, y) is the mean of the fine pixels (2x + i, 2y + j), i, j in
 * {0, 1}, that exist: a fine size w gives a coarse size (w + 1) / 2. */
typedef struct ew_kpcn_pool_args {
    int fw, fh, cw, ch;
    long nplanes; /* a long, so that the struct has no padding: a device copies it as bytes, and the
                   * launch-grid check reads every word of it as a possible pointer */
    ew_kpcn_tensor src, dst; /* fine, coarse */
} ew_kpcn_pool_args;

EW_HD int ew_kpcn_half(int n) { return (n + 1) / 2; }

EW_HD void ew_kpcn_pool_px(int x, int y, const ew_kpcn_pool_args *a) {
    const int x1 = ew_mini(2 * x + 1, a->fw - 1), y1 = ew_mini(2 * y + 1, a->fh - 1);
    const float inv = 1.0f / (float)((x1 - 2 * x + 1) * (y1 - 2 * y + 1));
    for (int c = 0; c < a->nplanes; c++) {
        float s = 0.0f;
        for (int yy = 2 * y; yy <= y1; yy++)
            for (int xx = 2 * x; xx <= x1; xx++) s += *ew_kpcn_at(&a->src, c, yy, xx);
        *ew_kpcn_at(&a->dst, c, y, x) = s * inv;
    }
}

/* dL/d fine += dL/d coarse / count, for coarse pixel (x, y) (a gather-free
 * scatter into its own 2x2 block: blocks do not overlap). */
EW_HD void ew_kpcn_pool_backward_px(int x, int y, const ew_kpcn_pool_args *a, const ew_kpcn_tensor *dcoarse,
                                    const ew_kpcn_tensor *dfine) {
    const int x1 = ew_mini(2 * x + 1, a->fw - 1), y1 = ew_mini(2 * y + 1, a->fh - 1);
    const float inv = 1.0f / (float)((x1 - 2 * x + 1) * (y1 - 2 * y + 1));
    for (int c = 0; c < a->nplanes; c++) {
        const float g = *ew_kpcn_at(dcoarse, c, y, x) * inv;
        for (int yy = 2 * y; yy <= y1; yy++)
            for (int xx = 2 * x; xx <= x1; xx++) *ew_kpcn_at(dfine, c, yy, xx) += g;
    }
}

/* ---- 2x bilinear upsampling ---------------------------------------------
 * Pixel centres: fine x sits at coarse coordinate x / 2 - 1/4, so each fine
 * pixel blends its two nearest coarse pixels 3:1 per axis; indices clamp at
 * the border (the weights of a clamped pair land on the same pixel). */
EW_HD void ew_kpcn_up_taps(int x, int cw, int *i0, int *i1, float *w0, float *w1) {
    const int i = (x - 1) >> 1; /* floor(x/2 - 1/4) */
    const float t = (x & 1) ? 0.25f : 0.75f;
    *i0 = ew_maxi(i, 0);
    *i1 = ew_mini(i + 1, cw - 1);
    *w0 = 1.0f - t;
    *w1 = t;
}

typedef struct ew_kpcn_up_args {
    int fw, fh, cw, ch;
    long nplanes; /* a long, so that the struct has no padding: a device copies it as bytes, and the
                   * launch-grid check reads every word of it as a possible pointer */
    ew_kpcn_tensor src, dst; /* coarse, fine */
    long y0;      /* dst's row 0 is fine row y0 (a band of fh rows of a taller plane), else 0 */
} ew_kpcn_up_args;

EW_HD float ew_kpcn_bilerp(const ew_kpcn_tensor *t, int c, int x0, int x1, int y0, int y1, float wx0, float wx1,
                           float wy0, float wy1) {
    return wy0 * (wx0 * *ew_kpcn_at(t, c, y0, x0) + wx1 * *ew_kpcn_at(t, c, y0, x1)) +
           wy1 * (wx0 * *ew_kpcn_at(t, c, y1, x0) + wx1 * *ew_kpcn_at(t, c, y1, x1));
}

EW_HD void ew_kpcn_up_px(int x, int y, const ew_kpcn_up_args *a) {
    int x0, x1, y0, y1;
    float wx0, wx1, wy0, wy1;
    ew_kpcn_up_taps(x, a->cw, &x0, &x1, &wx0, &wx1);
    ew_kpcn_up_taps(y + (int)a->y0, a->ch, &y0, &y1, &wy0, &wy1);
    for (int c = 0; c < a->nplanes; c++)
        *ew_kpcn_at(&a->dst, c, y, x) = ew_kpcn_bilerp(&a->src, c, x0, x1, y0, y1, wx0, wx1, wy0, wy1);
}

/* Scatter dL/d fine (x, y) into dL/d coarse (add). */
EW_HD void ew_kpcn_up_backward_px(int x, int y, const ew_kpcn_up_args *a, const ew_kpcn_tensor *dfine,
                                  const ew_kpcn_tensor *dcoarse) {
    int x0, x1, y0, y1;
    float wx0, wx1, wy0, wy1;
    ew_kpcn_up_taps(x, a->cw, &x0, &x1, &wx0, &wx1);
    ew_kpcn_up_taps(y, a->ch, &y0, &y1, &wy0, &wy1);
    for (int c = 0; c < a->nplanes; c++) {
        const float g = *ew_kpcn_at(dfine, c, y, x);
        *ew_kpcn_at(dcoarse, c, y0, x0) += wy0 * wx0 * g;
        *ew_kpcn_at(dcoarse, c, y0, x1) += wy0 * wx1 * g;
        *ew_kpcn_at(dcoarse, c, y1, x0) += wy1 * wx0 * g;
        *ew_kpcn_at(dcoarse, c, y1, x1) += wy1 * wx1 * g;
    }
}

/* ---- the kernel filter of one scale --------------------------------------
 *   w_k = softmax(logits)_k over the 25 taps (offsets (k % 5 - 2, k / 5 - 2),
 *         image borders clamped),
 *   f   = sum_k w_k r(p + d_k),
 *   out = (1 - a) f + a up(coarse)(p),  a = sigmoid(logit 25)
 * or out = f at the coarsest scale (coarse.data == NULL).
 * With an albedo (full resolution, a "-ra" net) the output is the colour,
 * out x m, with the remodulation albedo
 *   m   = sum_k v_k A(p + d_k),  v = softmax(logits 26..50),
 *         A = albedo + eps (ew_albedo_factor),
 * and non-finite values become 0 (as ew_denoise_finish_px). Why: at a few
 * spp Cycles' denoising albedo is itself noisy (glass, glossy paths,
 * anti-aliased edges), and multiplying the filtered radiance back by it
 * brings its noise back; a fixed filter of the albedo blurs the texture it
 * also holds, while a kernel the network predicts can tell the two apart.
 * m is a convex combination of A around the pixel, so it stays between the
 * smallest and largest albedo there. */
typedef struct ew_kpcn_filter_args {
    int width, height;        /* the rows filtered: height of them from row y0 */
    ew_kpcn_tensor logits;    /* 25 or 26 planes, its row 0 the row y0 */
    ew_kpcn_tensor radiance;  /* 3 channels at this scale */
    ew_kpcn_tensor coarse;    /* 3 channels at half this scale, or data NULL */
    int cw, ch;               /* the coarse size */
    int y0, frame_h;          /* a band of a plane of frame_h rows (taps clamp there) from row y0; 0, 0: the
                                 whole plane, height rows */
    ew_kpcn_tensor out;       /* 3 channels */
    ew_kpcn_tensor albedo;    /* 3 channels of raw albedo at full resolution, or data NULL: no remodulation */
    int albedo_y0;            /* the albedo's row 0 is the plane's row albedo_y0 (a band of rows around the
                                 filtered ones, converted from halves), else 0 */
} ew_kpcn_filter_args;

/* the rows of the plane the taps clamp to */
EW_HD int ew_kpcn_filter_rows(const ew_kpcn_filter_args *a) { return a->frame_h ? a->frame_h : a->height; }

/* softmax of the 25 logits from plane first at (x, y) into w; w sums to 1.
 * The exponential is ew_fexp (kernels/fastmath.h), not libm's expf: the CPU
 * row loop then computes it for a span of pixels in vector registers, and
 * every backend, the trainer included, gets the same bits. */
EW_HD void ew_kpcn_softmax_at(int x, int y, const ew_kpcn_tensor *logits, int first, float *w) {
    float mx = *ew_kpcn_at(logits, first, y, x);
    for (int k = 1; k < EW_KPCN_TAPS; k++) mx = ew_maxf(mx, *ew_kpcn_at(logits, first + k, y, x));
    float s = 0.0f;
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        w[k] = ew_fexp(*ew_kpcn_at(logits, first + k, y, x) - mx);
        s += w[k];
    }
    const float inv = 1.0f / s;
    for (int k = 0; k < EW_KPCN_TAPS; k++) w[k] *= inv;
}

/* at row y of the plane (the logits' row y - y0) */
EW_HD void ew_kpcn_softmax_px(int x, int y, const ew_kpcn_filter_args *a, float *w) {
    ew_kpcn_softmax_at(x, y - a->y0, &a->logits, 0, w);
}

EW_HD void ew_kpcn_tap_xy(int k, int x, int y, int width, int height, int *tx, int *ty) {
    *tx = ew_mini(ew_maxi(x + k % 5 - EW_KPCN_KR, 0), width - 1);
    *ty = ew_mini(ew_maxi(y + k / 5 - EW_KPCN_KR, 0), height - 1);
}

EW_HD void ew_kpcn_filtered_px(int x, int y, const ew_kpcn_filter_args *a, const float *w, float *f) {
    f[0] = f[1] = f[2] = 0.0f;
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        int tx, ty;
        ew_kpcn_tap_xy(k, x, y, a->width, ew_kpcn_filter_rows(a), &tx, &ty);
        for (int c = 0; c < 3; c++) f[c] += w[k] * *ew_kpcn_at(&a->radiance, c, ty, tx);
    }
}

/* The remodulation albedo m at (x, y) (a->albedo set) and its kernel v. */
EW_HD void ew_kpcn_remod_albedo_px(int x, int y, const ew_kpcn_filter_args *a, float *v, float *m) {
    ew_kpcn_softmax_at(x, y - a->y0, &a->logits, EW_KPCN_HEAD, v);
    m[0] = m[1] = m[2] = 0.0f;
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        int tx, ty;
        ew_kpcn_tap_xy(k, x, y, a->width, ew_kpcn_filter_rows(a), &tx, &ty);
        for (int c = 0; c < 3; c++) m[c] += v[k] * ew_albedo_factor(*ew_kpcn_at(&a->albedo, c, ty - a->albedo_y0, tx));
    }
}

/* Backward of m at (x, y) given gm = dL/dm (3): dL/d logit (planes 26..50)
 * into dlogits, v_k (dL/dv_k - sum_j v_j dL/dv_j) with dL/dv_k = gm . A_k. */
EW_HD void ew_kpcn_remod_backward_px(int x, int y, const ew_kpcn_filter_args *a, const float *gm,
                                     const ew_kpcn_tensor *dlogits) {
    float v[EW_KPCN_TAPS], m[3], dv[EW_KPCN_TAPS], dot = 0.0f;
    ew_kpcn_remod_albedo_px(x, y, a, v, m);
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        int tx, ty;
        ew_kpcn_tap_xy(k, x, y, a->width, a->height, &tx, &ty);
        float s = 0.0f;
        for (int c = 0; c < 3; c++) s += gm[c] * ew_albedo_factor(*ew_kpcn_at(&a->albedo, c, ty - a->albedo_y0, tx));
        dv[k] = s;
        dot += v[k] * s;
    }
    for (int k = 0; k < EW_KPCN_TAPS; k++) *ew_kpcn_at(dlogits, EW_KPCN_HEAD + k, y, x) = v[k] * (dv[k] - dot);
}

/* f = (1 - a) f + a up(coarse)(x, y), a = sigmoid(logit 25): the filtered
 * radiance f at (x, y) blended with the coarser scale's result */
EW_HD void ew_kpcn_blend_coarse_px(int x, int y, const ew_kpcn_filter_args *a, float *f) {
    const float al = ew_sigmoidf(*ew_kpcn_at(&a->logits, EW_KPCN_TAPS, y - a->y0, x));
    int x0, x1, y0, y1;
    float wx0, wx1, wy0, wy1;
    ew_kpcn_up_taps(x, a->cw, &x0, &x1, &wx0, &wx1);
    ew_kpcn_up_taps(y, a->ch, &y0, &y1, &wy0, &wy1);
    for (int c = 0; c < 3; c++) {
        const float u = ew_kpcn_bilerp(&a->coarse, c, x0, x1, y0, y1, wx0, wx1, wy0, wy1);
        f[c] = (1.0f - al) * f[c] + al * u;
    }
}

/* pixel x of the yb-th row filtered (the plane's row y0 + yb) */
EW_HD void ew_kpcn_filter_px(int x, int yb, const ew_kpcn_filter_args *a) {
    const int y = yb + a->y0;
    float w[EW_KPCN_TAPS], f[3];
    ew_kpcn_softmax_px(x, y, a, w);
    ew_kpcn_filtered_px(x, y, a, w, f);
    if (a->coarse.data) ew_kpcn_blend_coarse_px(x, y, a, f);
    if (a->albedo.data) {
        float v[EW_KPCN_TAPS], m[3];
        ew_kpcn_remod_albedo_px(x, y, a, v, m);
        for (int c = 0; c < 3; c++) {
            const float o = f[c] * m[c];
            f[c] = ew_finitef(o) ? o : 0.0f;
        }
    }
    for (int c = 0; c < 3; c++) *ew_kpcn_at(&a->out, c, y, x) = f[c];
}

/*
 * Backward of the filter at (x, y) given g = dL/d out (3): writes dL/d
 * logits at (x, y) into dlogits (25 or 26 planes) and adds dL/d radiance
 * and dL/d coarse to the pixels they came from (scatters):
 *   dL/df = (1 - a) g,  dL/da = g . (up - f),  dL/d logit_a = dL/da a (1 - a),
 *   dL/dw_k = dL/df . r_k,  dL/d logit_k = w_k (dL/dw_k - sum_j w_j dL/dw_j),
 *   dL/d r_k += w_k dL/df,  dL/d coarse += a g x (its bilinear weight).
 */
EW_HD void ew_kpcn_filter_backward_px(int x, int y, const ew_kpcn_filter_args *a, const float *g,
                                      const ew_kpcn_tensor *dlogits, const ew_kpcn_tensor *dradiance,
                                      const ew_kpcn_tensor *dcoarse) {
    float w[EW_KPCN_TAPS], f[3], df[3] = {g[0], g[1], g[2]};
    ew_kpcn_softmax_px(x, y, a, w);
    ew_kpcn_filtered_px(x, y, a, w, f);
    if (a->coarse.data) {
        const float al = ew_sigmoidf(*ew_kpcn_at(&a->logits, EW_KPCN_TAPS, y, x));
        int x0, x1, y0, y1;
        float wx0, wx1, wy0, wy1;
        ew_kpcn_up_taps(x, a->cw, &x0, &x1, &wx0, &wx1);
        ew_kpcn_up_taps(y, a->ch, &y0, &y1, &wy0, &wy1);
        float dal = 0.0f;
        for (int c = 0; c < 3; c++) {
            const float u = ew_kpcn_bilerp(&a->coarse, c, x0, x1, y0, y1, wx0, wx1, wy0, wy1);
            dal += g[c] * (u - f[c]);
            df[c] = (1.0f - al) * g[c];
            const float ga = al * g[c];
            if (dcoarse && dcoarse->data) {
                *ew_kpcn_at(dcoarse, c, y0, x0) += wy0 * wx0 * ga;
                *ew_kpcn_at(dcoarse, c, y0, x1) += wy0 * wx1 * ga;
                *ew_kpcn_at(dcoarse, c, y1, x0) += wy1 * wx0 * ga;
                *ew_kpcn_at(dcoarse, c, y1, x1) += wy1 * wx1 * ga;
            }
        }
        *ew_kpcn_at(dlogits, EW_KPCN_TAPS, y, x) = dal * al * (1.0f - al);
    }
    float dw[EW_KPCN_TAPS], dot = 0.0f;
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        int tx, ty;
        ew_kpcn_tap_xy(k, x, y, a->width, a->height, &tx, &ty);
        float s = 0.0f;
        for (int c = 0; c < 3; c++) {
            s += df[c] * *ew_kpcn_at(&a->radiance, c, ty, tx);
            if (dradiance && dradiance->data) *ew_kpcn_at(dradiance, c, ty, tx) += w[k] * df[c];
        }
        dw[k] = s;
        dot += w[k] * s;
    }
    for (int k = 0; k < EW_KPCN_TAPS; k++) *ew_kpcn_at(dlogits, k, y, x) = w[k] * (dw[k] - dot);
}

#endif
