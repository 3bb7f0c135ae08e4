/*
 * guidenet.h — GuideNet (Meng et al. 2020, §4.1, Fig. 2): its architectures,
 * parameters, weights files and the zero-padded plane buffers its
 * convolutions run on.
 *
 * Architectures ("<depth>-<grids>"):
 *   2layer-*  conv 10->20 + LeakyReLU(0.2), conv 20->nout + sigmoid
 *   7layer-*  conv 10->20 + LeakyReLU, a dense block of five convs of 5
 *             channels each seeing the concatenation of all before it
 *             (20, 25, ..., 40 inputs), conv 45->nout + sigmoid
 *   *-3grid   nout = 5: three guides (x255) and two blend outputs
 *   *-1grid   nout = 1: one guide
 * All convolutions are 5x5, SAME, with biases. The grids' sampling rates
 * (eta_s, eta_d) are part of a model; the defaults are (4,4), (8,8),
 * (16,16) for three grids (the paper's) and (8,8) for one.
 *
 * Weights file (src/weights.h format): arch "nbg-<arch>", tensors
 * "conv<l>.weight" [cout, cin, 5, 5], "conv<l>.bias" [cout] for l = 0..L-1,
 * and "grid.rates" [ngrids, 2] = (eta_s, eta_d) per grid.
 *
 * Feature buffer: planes 0..9 hold the inputs, then each hidden layer's
 * output in order, so a dense layer's input (all hidden planes so far) is
 * one contiguous run of planes. The last layer writes to its own buffer.
 */
#ifndef EW_ALGORITHMS_GUIDENET_H
#define EW_ALGORITHMS_GUIDENET_H

#include <stddef.h>
#include <stdint.h>

#include "kernels/conv.h"
#include "kernels/guidenet.h"
#include "src/weights.h"

#define EW_GN_MAX_LAYERS 7
#define EW_GN_MAX_GRIDS 3
#define EW_GN_ARCH_MAX 32

typedef struct ew_gn_layer {
    int cin, cout;
    int in_plane;   /* first input plane in the feature buffer */
    int out_plane;  /* first output plane in the feature buffer; -1: the output buffer */
    int act;        /* EW_ACT_* */
    size_t w_off, b_off; /* offsets of weight and bias in the parameter vector */
} ew_gn_layer;

typedef struct ew_guidenet {
    char arch[EW_GN_ARCH_MAX]; /* e.g. "2layer-3grid" */
    int nlayers;
    int ngrids, nout;
    int nfeat; /* planes of the feature buffer */
    ew_gn_layer layers[EW_GN_MAX_LAYERS];
    float rate_s[EW_GN_MAX_GRIDS], rate_d[EW_GN_MAX_GRIDS];
    size_t nparams;
} ew_guidenet;

/* Set up an architecture by name with its default rates. Returns 0, or
 * non-zero with a message naming the accepted names. */
int ew_guidenet_init(ew_guidenet *net, const char *arch, char *err, size_t errlen);
/* Weights: Kaiming-uniform for the LeakyReLU layers, a smaller uniform for
 * the output layer (so the first guides are near mid-range, not
 * saturated), zero biases; a pure function of the seed. */
void ew_guidenet_random(const ew_guidenet *net, uint64_t seed, float *params);
/* Read a parsed weights file: sets up *net from its arch and rates and
 * fills *params (malloc'd; the caller frees). 0 or non-zero + message. */
int ew_guidenet_from_weights(ew_guidenet *net, const ew_weights *w, float **params, char *err, size_t errlen);
/* Serialise a net and its parameters to weights-file bytes (*out malloc'd).
 * 0 on success. */
int ew_guidenet_save(const ew_guidenet *net, const float *params, void **out, size_t *size);

/* Number of multiply-adds of the convolutions per pixel. */
double ew_guidenet_macs_per_pixel(const ew_guidenet *net);

/* ---- zero-padded plane buffers --------------------------------------- */
/* `rows` x `width` planes with 2 zero rows above and below, 8 zero columns
 * on the left (2 for the kernel, the rest keep x = 0 aligned to 32 bytes)
 * and at least 26 on the right (whole vectors read past the last pixel). */
typedef struct ew_gn_planes {
    float *data; /* plane 0, row 0, x = 0 */
    long rs, ps; /* row and plane strides */
    int width, rows, nplanes;
} ew_gn_planes;

size_t ew_gn_planes_floats(int width, int rows, int nplanes);
/* Lay out planes in mem (ew_gn_planes_floats floats; 32-byte aligned is
 * fastest). _layout only computes the pointers (device memory is zeroed by
 * the caller through the backend); _init also zeroes host memory. */
void ew_gn_planes_layout(ew_gn_planes *p, float *mem, int width, int rows, int nplanes);
void ew_gn_planes_init(ew_gn_planes *p, float *mem, int width, int rows, int nplanes);
static inline float *ew_gn_plane_row(const ew_gn_planes *p, int plane, int row) {
    return p->data + (long)plane * p->ps + (long)row * p->rs;
}

/* The convolution of layer l for `rows` rows from row r0 of `feat`: hidden
 * layers write their planes of `feat`, the last layer writes planes at
 * final_out (its first row, row and plane strides final_rs, final_ps). */
void ew_guidenet_layer_args(const ew_guidenet *net, int l, const float *params, const ew_gn_planes *feat, int r0,
                            int rows, float *final_out, long final_rs, long final_ps, ew_conv_args *a);

#endif
