/*
 * cpu_kpcn_filter.h — the CPU backend's row loop of the kernel filter
 * (kernels/kpcn.h, ew_kpcn_filter_px), included by cpu_kernels.c only.
 *
 * Per pixel the filter takes 25 softmax weights over logit planes and 25
 * taps of 3 channels: ew_kpcn_filter_px does that one pixel at a time, tap
 * by tap, which no compiler vectorises (each tap reads a different plane).
 * Here a span of pixels of one row goes step by step instead: the maximum
 * over the logit planes, the exponentials, the sum, the weights, then each
 * tap's product for the whole span — every step a loop over contiguous
 * floats. Each pixel still sees the same IEEE operations in the same order
 * as ew_kpcn_filter_px (the same maximum, exponential, sum over taps 0..24, one
 * reciprocal, products accumulated tap by tap), so the bits are the same:
 * the launch-grid parity test compares them exactly. Pixels within two of
 * the left or right border (clamped taps) and tensors whose logits are not
 * contiguous along x take the per-pixel function.
 */
#ifndef EW_CPU_KPCN_FILTER_H
#define EW_CPU_KPCN_FILTER_H

#include "kernels/kpcn.h"

enum { EW_KPCN_SPAN = 64 };

/* w[k][i] = softmax over taps of planes first..first+24 at (x0 + i, y). */
static inline void kpcn_softmax_span(const ew_kpcn_tensor *t, int first, int y, int x0, int n,
                                     float w[EW_KPCN_TAPS][EW_KPCN_SPAN]) {
    float mx[EW_KPCN_SPAN], s[EW_KPCN_SPAN];
    const float *l0 = ew_kpcn_at(t, first, y, x0);
    for (int i = 0; i < n; i++) mx[i] = l0[i];
    for (int k = 1; k < EW_KPCN_TAPS; k++) {
        const float *l = ew_kpcn_at(t, first + k, y, x0);
        for (int i = 0; i < n; i++) mx[i] = ew_maxf(mx[i], l[i]);
    }
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        const float *l = ew_kpcn_at(t, first + k, y, x0);
        for (int i = 0; i < n; i++) w[k][i] = l[i] - mx[i];
    }
    for (int k = 0; k < EW_KPCN_TAPS; k++)
        for (int i = 0; i < n; i++) w[k][i] = ew_fexp(w[k][i]);
    for (int i = 0; i < n; i++) s[i] = 0.0f;
    for (int k = 0; k < EW_KPCN_TAPS; k++)
        for (int i = 0; i < n; i++) s[i] += w[k][i];
    for (int i = 0; i < n; i++) s[i] = 1.0f / s[i];
    for (int k = 0; k < EW_KPCN_TAPS; k++)
        for (int i = 0; i < n; i++) w[k][i] *= s[i];
}

/* acc[c][i] = sum_k w[k][i] v_c(x0 + i + k % 5 - 2, rows[k / 5]), with
 * v the 5 rows of a 3-channel tensor around y (clamped to the plane's
 * height rows; the tensor's row 0 the plane's row0), each channel's
 * values first passed through `factor` when it is set. */
static inline void kpcn_taps_span(const ew_kpcn_tensor *t, int y, int height, int row0, int x0, int n,
                                  float w[EW_KPCN_TAPS][EW_KPCN_SPAN], int albedo_factor,
                                  float acc[3][EW_KPCN_SPAN]) {
    float r[3][5][EW_KPCN_SPAN + 2 * EW_KPCN_KR];
    for (int dy = 0; dy < 5; dy++) {
        const int ty = ew_mini(ew_maxi(y + dy - EW_KPCN_KR, 0), height - 1);
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < n + 2 * EW_KPCN_KR; i++) {
                const float v = *ew_kpcn_at(t, c, ty - row0, x0 - EW_KPCN_KR + i);
                r[c][dy][i] = albedo_factor ? ew_albedo_factor(v) : v;
            }
    }
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < n; i++) acc[c][i] = 0.0f;
    for (int k = 0; k < EW_KPCN_TAPS; k++) {
        const int dx = k % 5, dy = k / 5;
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < n; i++) acc[c][i] += w[k][i] * r[c][dy][i + dx];
    }
}

/* Pixels x0 .. x0 + n - 1 (n <= EW_KPCN_SPAN) of the plane's row y (the
 * logits' row y - y0), all at least EW_KPCN_KR from the left and right
 * borders. */
static inline void kpcn_filter_span(const ew_kpcn_filter_args *a, int y, int x0, int n) {
    float w[EW_KPCN_TAPS][EW_KPCN_SPAN], f[3][EW_KPCN_SPAN];
    kpcn_softmax_span(&a->logits, 0, y - a->y0, x0, n, w);
    kpcn_taps_span(&a->radiance, y, ew_kpcn_filter_rows(a), 0, x0, n, w, 0, f);
    if (a->coarse.data)
        for (int i = 0; i < n; i++) {
            float v[3] = {f[0][i], f[1][i], f[2][i]};
            ew_kpcn_blend_coarse_px(x0 + i, y, a, v);
            for (int c = 0; c < 3; c++) f[c][i] = v[c];
        }
    if (a->albedo.data) {
        float m[3][EW_KPCN_SPAN];
        kpcn_softmax_span(&a->logits, EW_KPCN_HEAD, y - a->y0, x0, n, w);
        kpcn_taps_span(&a->albedo, y, ew_kpcn_filter_rows(a), a->albedo_y0, x0, n, w, 1, m);
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < n; i++) {
                const float o = f[c][i] * m[c][i];
                f[c][i] = ew_finitef(o) ? o : 0.0f;
            }
    }
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) *ew_kpcn_at(&a->out, c, y, x0 + i) = f[c][i];
}

static EW_KROWS_ATTR_1 void rows_kpcn_filter(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_kpcn_filter_args *a = (const ew_kpcn_filter_args *)ctx;
    const int W = a->width, lo = EW_KPCN_KR, hi = W - EW_KPCN_KR;
    const int spans = a->logits.xs == 1 && hi > lo;
    for (int64_t yy = begin; yy < end; yy++) {
        const int yb = (int)yy, y = yb + a->y0; /* the yb-th row filtered, the plane's row y */
        if (!spans) {
            for (int x = 0; x < W; x++) ew_kpcn_filter_px(x, yb, a);
            continue;
        }
        for (int x = 0; x < lo; x++) ew_kpcn_filter_px(x, yb, a);
        for (int x = lo; x < hi; x += EW_KPCN_SPAN) kpcn_filter_span(a, y, x, ew_mini(EW_KPCN_SPAN, hi - x));
        for (int x = hi; x < W; x++) ew_kpcn_filter_px(x, yb, a);
    }
}

#endif
