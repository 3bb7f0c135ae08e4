/*
 * atrous.h — the edge-avoiding à-trous wavelet filter on packed buffers
 * (per-pixel math in kernels/atrous.h).
 */
#ifndef EW_ALGORITHMS_ATROUS_H
#define EW_ALGORITHMS_ATROUS_H

#include "kernels/atrous.h"
#include "src/internal.h"

/* Iterations whose combined support 2 (2^n - 1) reaches the radius. */
int ew_atrous_iterations_for(int radius);

/* n iterations from `in` into `out`, ping-ponging through tmp (neither may
 * alias in). sigma_l is the first iteration's; it halves at each one. */
void ew_atrous_run(ew_device *dev, int w, int h, int C, int iterations, const float *in, float *tmp, float *out,
                   const float *normal, const float *depth, float sigma_l, float sigma_n, float sigma_z);

#endif
