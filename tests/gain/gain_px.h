/*
 * gain_px.h — the per-pixel function of the guide's example method "gain"
 * (docs/adding-a-method.md): what a method's core/kernels/<name>.h holds.
 * Plain C that nvcc also compiles (kernels/compat.h).
 */
#ifndef EW_TEST_GAIN_PX_H
#define EW_TEST_GAIN_PX_H

#include "kernels/compat.h"

/* Pixel i of c channels: every channel times gain, or all but a 4th
 * (alpha) when keep_alpha. */
EW_HD void ew_gain_px(long i, int c, float gain, int keep_alpha, const float *EW_RESTRICT in, float *EW_RESTRICT out) {
    for (int k = 0; k < c; k++) out[i * c + k] = (keep_alpha && k == 3) ? in[i * c + k] : in[i * c + k] * gain;
}

#endif
