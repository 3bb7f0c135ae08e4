/*
 * cpu_kpcn_pool.h — the CPU backend's row loop of the 2x2 average pooling
 * (kernels/kpcn.h, ew_kpcn_pool_px), included by cpu_kernels.c only.
 *
 * ew_kpcn_pool_px averages one coarse pixel's 2x2 block in every plane (a
 * plane stride apart), which no compiler vectorises. Here a coarse row of
 * planar tensors goes plane by plane, over the coarse pixels whose block
 * lies whole inside the fine plane: the same sum from 0 in the same order
 * (row 2y's two pixels, then row 2y + 1's) times the same 1/4, so the bits
 * are ew_kpcn_pool_px's (the launch-grid parity test compares them). Packed
 * tensors (the radiance pyramid's RGB), a last coarse row or column over a
 * single fine one take the per-pixel function.
 */
#ifndef EW_CPU_KPCN_POOL_H
#define EW_CPU_KPCN_POOL_H

#include "kernels/kpcn.h"

static EW_KROWS_ATTR_1 void rows_kpcn_pool(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_kpcn_pool_args *a = (const ew_kpcn_pool_args *)ctx;
    const int whole = ew_mini(a->cw, a->fw / 2); /* coarse x whose columns 2x, 2x + 1 both exist */
    const int planar = a->src.xs == 1 && a->dst.xs == 1 && whole > 0;
    for (int64_t yy = begin; yy < end; yy++) {
        const int y = (int)yy;
        if (!planar || 2 * y + 1 >= a->fh) {
            for (int x = 0; x < a->cw; x++) ew_kpcn_pool_px(x, y, a);
            continue;
        }
        const float inv = 1.0f / 4.0f;
        for (long c = 0; c < a->nplanes; c++) {
            const float *r0 = ew_kpcn_at(&a->src, (int)c, 2 * y, 0), *r1 = ew_kpcn_at(&a->src, (int)c, 2 * y + 1, 0);
            float *d = ew_kpcn_at(&a->dst, (int)c, y, 0);
            for (int x = 0; x < whole; x++) {
                float s = 0.0f;
                s += r0[2 * x];
                s += r0[2 * x + 1];
                s += r1[2 * x];
                s += r1[2 * x + 1];
                d[x] = s * inv;
            }
        }
        for (int x = whole; x < a->cw; x++) ew_kpcn_pool_px(x, y, a);
    }
}

#endif
