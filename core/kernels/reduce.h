/*
 * reduce.h — per-row reductions whose results the host needs (a mean
 * luminance, a largest depth) when the buffers live in device memory and the
 * host cannot read them. One work item per row writes two doubles; the host
 * downloads the 2 x height doubles (a few KiB) and finishes the sum. The same
 * row order is used on every backend, so the result does not depend on the
 * backend or the thread count. Doubles because a row of a 8K image summed in
 * float would lose the small values.
 */
#ifndef EW_KERNELS_REDUCE_H
#define EW_KERNELS_REDUCE_H

#include "kernels/color.h"

enum {
    EW_REDUCE_LUM_SUM = 0,  /* out: sum of the finite, positive luminances of the row; their count */
    EW_REDUCE_DEPTH_MAX = 1, /* out: largest finite depth below 1e9 of the row (0 if none); 0 */
    EW_REDUCE_NOISE = 2,     /* out: sum of |HH| over rows y - 1, y (see below); their count */
    EW_REDUCE_SUM = 3        /* out: sum of the finite, positive values of the row; their count */
};

/* Compressed luminance l / (1 + l) of an RGB pixel (negative as 0). */
EW_HD float ew_reduce_clum(const float *rgb) {
    float l = ew_maxf(ew_luminance(rgb), 0.0f);
    return l / (1.0f + l);
}

/* Row y of a width-pixel image: src holds 3 floats a pixel for LUM_SUM and
 * NOISE, 1 for DEPTH_MAX and SUM. Writes out[2 * y] and out[2 * y + 1].
 * NOISE is the frame's noise level the way wavelet denoisers measure it:
 * the diagonal (HH) Haar detail (a - b - c + d) / 2 of each 2x2 block of
 * compressed luminance in rows y - 1 and y (row 0 gives nothing). Pixel
 * noise independent between pixels passes into HH unchanged, while edges
 * along rows or columns cancel in it; the mean |HH| over the frame falls
 * as 1/sqrt(samples). */
EW_HD void ew_reduce_row(int op, int y, int width, const float *EW_RESTRICT src, double *EW_RESTRICT out) {
    double a = 0.0, b = 0.0;
    if (op == EW_REDUCE_LUM_SUM) {
        const float *row = src + (long)y * width * 3;
        for (int x = 0; x < width; x++) {
            float l = ew_luminance(row + x * 3);
            if (ew_finitef(l) && l > 0.0f) {
                a += (double)l;
                b += 1.0;
            }
        }
    } else if (op == EW_REDUCE_NOISE) {
        if (y > 0) {
            const float *r0 = src + (long)(y - 1) * width * 3, *r1 = src + (long)y * width * 3;
            for (int x = 0; x + 1 < width; x++) {
                float hh = 0.5f * (ew_reduce_clum(r0 + x * 3) - ew_reduce_clum(r0 + x * 3 + 3) -
                                   ew_reduce_clum(r1 + x * 3) + ew_reduce_clum(r1 + x * 3 + 3));
                if (ew_finitef(hh)) {
                    a += (double)(hh < 0.0f ? -hh : hh);
                    b += 1.0;
                }
            }
        }
    } else if (op == EW_REDUCE_SUM) {
        const float *row = src + (long)y * width;
        for (int x = 0; x < width; x++)
            if (ew_finitef(row[x]) && row[x] > 0.0f) {
                a += (double)row[x];
                b += 1.0;
            }
    } else {
        const float *row = src + (long)y * width;
        float mx = 0.0f;
        /* Background pixels have Depth 1e10 (Depth pass): they would swamp
         * the scene's range, so they are left out. */
        for (int x = 0; x < width; x++)
            if (ew_finitef(row[x]) && row[x] < 1e9f && row[x] > mx) mx = row[x];
        a = (double)mx;
    }
    out[2 * y] = a;
    out[2 * y + 1] = b;
}

#endif
