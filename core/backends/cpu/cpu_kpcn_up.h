/*
 * cpu_kpcn_up.h — the CPU backend's row loop of the 2x bilinear upsampling
 * (kernels/kpcn.h, ew_kpcn_up_px), included by cpu_kernels.c only.
 *
 * ew_kpcn_up_px computes one fine pixel's taps and then walks every plane
 * (a plane stride apart), which no compiler vectorises; it ran at a tenth
 * of the convolutions' speed a multiply-add and took 8 % of kpcn-large's
 * time. Here a row goes plane by plane, and inside the frame (no tap
 * clamped) fine pixels 2i and 2i + 1 read coarse columns i - 1, i and i,
 * i + 1 with the weights 1/4, 3/4 and 3/4, 1/4 that ew_kpcn_up_taps gives
 * them: contiguous loops over i. Each pixel sees the same IEEE operations
 * in the same order as ew_kpcn_up_px (ew_kpcn_bilerp: the two rows'
 * horizontal blends, then the vertical one), so the bits are the same: the
 * launch-grid parity test compares them exactly. Tensors that are not
 * contiguous along x, and the clamped columns at either end, take the
 * per-pixel function.
 */
#ifndef EW_CPU_KPCN_UP_H
#define EW_CPU_KPCN_UP_H

#include "kernels/kpcn.h"

/* Fine pixels 2i, 2i + 1 of plane c's row y for i in [i0, i1): coarse rows
 * y0, y1 with weights wy0, wy1; the pairs' horizontal weights are
 * ew_kpcn_up_taps' for an even and an odd x. */
static inline void kpcn_up_pairs(const ew_kpcn_up_args *a, int c, int y, int y0, int y1, float wy0, float wy1,
                                 int i0, int i1) {
    int e0, e1, o0, o1;
    float we0, we1, wo0, wo1;
    ew_kpcn_up_taps(2, a->cw, &e0, &e1, &we0, &we1); /* even: columns i - 1, i */
    ew_kpcn_up_taps(1, a->cw, &o0, &o1, &wo0, &wo1); /* odd: columns i, i + 1 */
    const float *r0 = ew_kpcn_at(&a->src, c, y0, 0), *r1 = ew_kpcn_at(&a->src, c, y1, 0);
    float *d = ew_kpcn_at(&a->dst, c, y, 0);
    for (int i = i0; i < i1; i++) {
        const float e = wy0 * (we0 * r0[i - 1] + we1 * r0[i]) + wy1 * (we0 * r1[i - 1] + we1 * r1[i]);
        const float o = wy0 * (wo0 * r0[i] + wo1 * r0[i + 1]) + wy1 * (wo0 * r1[i] + wo1 * r1[i + 1]);
        d[2 * i] = e;
        d[2 * i + 1] = o;
    }
}

static EW_KROWS_ATTR_1 void rows_kpcn_up(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_kpcn_up_args *a = (const ew_kpcn_up_args *)ctx;
    /* pairs (2i, 2i + 1) with no clamped tap: 1 <= i (the even pixel's
     * left column) and i + 1 <= cw - 1 (the odd one's right), inside fw */
    const int i0 = 1, i1 = ew_mini(a->cw - 1, a->fw / 2);
    const int pairs = a->src.xs == 1 && a->dst.xs == 1 && i1 > i0;
    for (int64_t yy = begin; yy < end; yy++) {
        const int y = (int)yy;
        if (!pairs) {
            for (int x = 0; x < a->fw; x++) ew_kpcn_up_px(x, y, a);
            continue;
        }
        int y0, y1;
        float wy0, wy1;
        ew_kpcn_up_taps(y + (int)a->y0, a->ch, &y0, &y1, &wy0, &wy1);
        for (int c = 0; c < a->nplanes; c++) kpcn_up_pairs(a, c, y, y0, y1, wy0, wy1, i0, i1);
        for (int x = 0; x < 2 * i0; x++) ew_kpcn_up_px(x, y, a);
        for (int x = 2 * i1; x < a->fw; x++) ew_kpcn_up_px(x, y, a);
    }
}

#endif
