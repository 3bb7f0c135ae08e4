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
    EW_REDUCE_DEPTH_MAX = 1 /* out: largest finite depth below 1e9 of the row (0 if none); 0 */
};

/* Row y of a width-pixel image: src holds 3 floats a pixel for LUM_SUM, 1
 * for DEPTH_MAX. Writes out[2 * y] and out[2 * y + 1]. */
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
