/*
 * compat.h — the common subset of C11 and CUDA C++ that per-pixel kernels
 * are written in, so the CPU backend and the CUDA backend compile the same
 * functions (the approach of Cycles' kernel/).
 */
#ifndef EW_KERNELS_COMPAT_H
#define EW_KERNELS_COMPAT_H

#ifdef __CUDACC__
#define EW_HD __host__ __device__ inline
#define EW_RESTRICT __restrict__
#include <math.h>
#else
#include <math.h>
#include <stdint.h>
#define EW_HD static inline
#define EW_RESTRICT restrict
#endif

EW_HD float ew_minf(float a, float b) { return a < b ? a : b; }
EW_HD float ew_maxf(float a, float b) { return a > b ? a : b; }
EW_HD float ew_clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }
EW_HD int ew_mini(int a, int b) { return a < b ? a : b; }
EW_HD int ew_maxi(int a, int b) { return a > b ? a : b; }
EW_HD int ew_finitef(float v) { return isfinite(v) ? 1 : 0; }
/* The filters' finite-output rule for one value: NaN as 0, +-Inf as +-FLT_MAX. */
EW_HD float ew_finite_orf(float v) { return isnan(v) ? 0.0f : isinf(v) ? (v > 0.0f ? 3.40282347e+38f : -3.40282347e+38f) : v; }

/* *p = v, except a zero over a zero, which is not written: a plane zeroed
 * by dropping its pages (ew_dev_zero) keeps unmapped every page where only
 * zeros land, so a sparse plane (what a clamp took: a few pixels of a quiet
 * frame) holds the pages of its non-zeros, not a frame's */
EW_HD void ew_store_sparse(float *p, float v) {
    if (v != 0.0f || *p != 0.0f) *p = v;
}

#endif
