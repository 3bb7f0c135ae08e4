/*
 * conv.h — the 5x5 "SAME" convolution of GuideNet (Meng et al. 2020, §4.1)
 * and its activations, per output value, with the per-element backward
 * passes. Plain C that nvcc also compiles.
 *
 * Tensors are planar: value (c, r, x) of a stack of planes sits at
 * data[c * plane_stride + r * row_stride + x]. Every plane a convolution
 * reads must be readable, and zero, for 2 rows and columns around the region
 * computed (the zero padding of a SAME convolution lives in memory, so the
 * inner loops have no bounds checks and one band of rows can be computed on
 * its own: see algorithms/guidenet.h for the buffer layout).
 *
 * Weights are [cout][cin][5][5] (PyTorch's order), biases [cout]:
 *   out[co][r][x] = act(b[co] + sum_{ci,ky,kx} W[co][ci][ky][kx] * in[ci][r+ky-2][x+kx-2]).
 * The CPU backend computes the same sums with SIMD blocks
 * (backends/cpu/cpu_conv.c); the functions here are the per-value
 * formulation a CUDA kernel would call and the reference the tests use.
 */
#ifndef EW_KERNELS_CONV_H
#define EW_KERNELS_CONV_H

#include "kernels/compat.h"

#define EW_CONV_K 5 /* kernel side */
#define EW_CONV_R 2 /* kernel radius = padding of every plane */

/* Activations. LeakyReLU slope 0.2 as in the authors' code (the paper says
 * ReLU; a leak keeps units from dying with our small data set). */
#define EW_ACT_NONE 0
#define EW_ACT_LEAKY 1
#define EW_ACT_SIGMOID 2
#define EW_LEAKY_SLOPE 0.2f

EW_HD float ew_sigmoidf(float v) {
    /* never overflows: exp of a non-positive number only */
    if (v >= 0.0f) return 1.0f / (1.0f + expf(-v));
    float e = expf(v);
    return e / (1.0f + e);
}

EW_HD float ew_act(float v, int act) {
    if (act == EW_ACT_LEAKY) return v > 0.0f ? v : EW_LEAKY_SLOPE * v;
    if (act == EW_ACT_SIGMOID) return ew_sigmoidf(v);
    return v;
}

/* d act / d pre-activation, from the activation's *output* (so backward
 * passes need only the stored outputs): LeakyReLU keeps the sign, and
 * sigmoid' = s (1 - s). */
EW_HD float ew_act_grad(float out, int act) {
    if (act == EW_ACT_LEAKY) return out > 0.0f ? 1.0f : EW_LEAKY_SLOPE;
    if (act == EW_ACT_SIGMOID) return out * (1.0f - out);
    return 1.0f;
}

typedef struct ew_conv_args {
    int width, rows;     /* output region: x in [0, width), r in [0, rows) */
    int cin, cout;
    const float *in;     /* input plane 0 at the first output row, x = 0 */
    long in_rs, in_ps;   /* row and plane strides of the input, in floats */
    float *out;          /* output plane 0 at the first output row, x = 0 */
    long out_rs, out_ps;
    const float *weight; /* [cout][cin][5][5] */
    const float *bias;   /* [cout], NULL for none */
    int act;             /* EW_ACT_* applied to the sum */
    int accumulate;      /* 1: add the sum to what `out` holds (no bias, no activation) */
    /* 1: the CPU backend may compute the sums with Winograd's F(4x4, 5x5)
     * (backends/cpu/cpu_conv.h): fewer multiplies, equal to the sums above
     * up to rounding, not to the bit; 0: always these sums (callers whose
     * bits must not depend on how the work is cut, e.g. NBG's bands). Its
     * 4x4 output tiles are anchored at (-grid_x, -grid_y) mod 4: a region
     * of a larger image passes its origin there, so it is tiled as the
     * whole image is (the same bits where a tile's 8x8 inputs are the
     * same). Other backends ignore them. */
    int winograd, grid_x, grid_y;
    int reserved; /* 0; keeps the struct free of padding (docs/backends.md) */
} ew_conv_args;

/* One output value (x, r, co). */
EW_HD void ew_conv5_px(int x, int r, int co, const ew_conv_args *a) {
    float acc = 0.0f;
    for (int ci = 0; ci < a->cin; ci++) {
        const float *w = a->weight + ((long)co * a->cin + ci) * 25;
        const float *p = a->in + ci * a->in_ps + (long)(r - EW_CONV_R) * a->in_rs + (x - EW_CONV_R);
        for (int ky = 0; ky < EW_CONV_K; ky++)
            for (int kx = 0; kx < EW_CONV_K; kx++) acc += w[ky * 5 + kx] * p[ky * a->in_rs + kx];
    }
    float *o = a->out + co * a->out_ps + (long)r * a->out_rs + x;
    if (a->accumulate) {
        *o += acc;
    } else {
        if (a->bias) acc += a->bias[co];
        *o = ew_act(acc, a->act);
    }
}

/*
 * Backward of one convolution given g = dL/d(pre-activation) as planes of
 * the output's shape (zero-padded like any input):
 *   dL/d in[ci][r][x]      = sum_{co,ky,kx} W[co][ci][ky][kx] g[co][r-ky+2][x-kx+2]
 *                          = a convolution of g with the flipped, transposed
 *                            kernel (ew_conv5_flip_weights), which is how the
 *                            CPU computes it;
 *   dL/d W[co][ci][ky][kx] = sum_{r,x} g[co][r][x] in[ci][r+ky-2][x+kx-2];
 *   dL/d b[co]             = sum_{r,x} g[co][r][x].
 */
EW_HD float ew_conv5_dinput_px(int x, int r, int ci, const ew_conv_args *a, const float *g, long g_rs, long g_ps) {
    float acc = 0.0f;
    for (int co = 0; co < a->cout; co++) {
        const float *w = a->weight + ((long)co * a->cin + ci) * 25;
        for (int ky = 0; ky < EW_CONV_K; ky++)
            for (int kx = 0; kx < EW_CONV_K; kx++)
                acc += w[ky * 5 + kx] * g[co * g_ps + (long)(r - ky + EW_CONV_R) * g_rs + (x - kx + EW_CONV_R)];
    }
    return acc;
}

EW_HD float ew_conv5_dweight_elem(int co, int ci, int ky, int kx, const ew_conv_args *a, const float *g, long g_rs,
                                  long g_ps) {
    float acc = 0.0f;
    for (int r = 0; r < a->rows; r++)
        for (int x = 0; x < a->width; x++)
            acc += g[co * g_ps + (long)r * g_rs + x] *
                   a->in[ci * a->in_ps + (long)(r + ky - EW_CONV_R) * a->in_rs + (x + kx - EW_CONV_R)];
    return acc;
}

/* W'[ci][co][ky][kx] = W[co][ci][4-ky][4-kx]: the kernel whose forward
 * convolution of g is dL/d in. */
EW_HD void ew_conv5_flip_weights(int cin, int cout, const float *EW_RESTRICT w, float *EW_RESTRICT flipped) {
    for (int co = 0; co < cout; co++)
        for (int ci = 0; ci < cin; ci++)
            for (int k = 0; k < 25; k++)
                flipped[((long)ci * cout + co) * 25 + (24 - k)] = w[((long)co * cin + ci) * 25 + k];
}

#endif
