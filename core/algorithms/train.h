/*
 * train.h — end-to-end training of the neural bilateral grid (Meng et al.
 * 2020, §4.4): one patch's forward pass and its analytic backward pass from
 * the L1 loss on tone-mapped colour back to every GuideNet weight, a batch of
 * patches on the device's threads, global-norm gradient clipping and Adam.
 *
 * Everything runs on the host (CPU) in the same per-pixel kernels as
 * inference (kernels/guidenet.h, bgrid.h, bgrid_backward.h, conv.h), so the
 * model trained is the model the "nbg" op runs. Reading files is the
 * caller's business (tools/train/train_nbg.c): frames come in as arrays.
 *
 * Determinism: a batch's patches are independent; each writes its gradient
 * to its own buffer and the buffers are summed in patch order, so a step's
 * result does not depend on the number of threads or their timing. Patch
 * positions and augmentations are a pure function of (seed, step, index),
 * so a resumed run continues exactly as an uninterrupted one.
 */
#ifndef EW_ALGORITHMS_TRAIN_H
#define EW_ALGORITHMS_TRAIN_H

#include <stddef.h>
#include <stdint.h>

#include "algorithms/guidenet.h"
#include "edgewise/edgewise.h"

/* One frame, preprocessed exactly as the "nbg" op preprocesses it. */
typedef struct ew_train_frame {
    int width, height;
    float *input;     /* EW_GN_INPUTS planes of width*height: GuideNet's input */
    float *radiance;  /* 3 a pixel: albedo-demodulated, firefly-clamped HDR radiance (splatted) */
    float *albedo_f;  /* 3 a pixel: albedo + eps, the remodulation factor */
    float *ref_tm;    /* 3 a pixel: the loss's tone curve of the reference */
} ew_train_frame;

/* Build a frame from packed buffers (3 floats a pixel; depth 1). Returns 0,
 * or non-zero when out of memory. firefly_k as the op's parameter. */
int ew_train_frame_init(ew_train_frame *f, int width, int height, const float *color, const float *albedo,
                        const float *normal, const float *depth, const float *reference, float firefly_k);
void ew_train_frame_free(ew_train_frame *f);

/* Where a patch comes from: a square of side `size` at (x0, y0) of a frame,
 * transformed by one of the 8 symmetries of the square (bit 0: flip x,
 * bit 1: flip y, bit 2: transpose, applied transpose first). The normals
 * are transformed with the image so they keep pointing the way the
 * surface faces in the patch. */
typedef struct ew_patch_ref {
    int frame, x0, y0, aug;
} ew_patch_ref;

/* Scratch of one patch's forward and backward pass (one per thread). */
typedef struct ew_train_scratch ew_train_scratch;
ew_train_scratch *ew_train_scratch_create(const ew_guidenet *net, int size);
void ew_train_scratch_destroy(ew_train_scratch *s);
/* on = 1: run the grids through the per-column / per-pixel kernels the
 * devices use instead of the trainer's single-thread scatters (slower; the
 * tests compare the two). */
void ew_train_scratch_use_kernels(ew_train_scratch *s, int on);

/* What a step shares between its patches: the parameters and their
 * re-laid-out copies for the SIMD convolutions (see ew_train_prepare). */
typedef struct ew_train_model {
    const ew_guidenet *net;
    const float *params;
    float *wt;   /* per layer: ew_conv_cpu_wt_layout of the weights */
    float *fwt;  /* per layer: of the flipped, transposed weights (dL/d input) */
    float *flip; /* per layer: the flipped, transposed weights */
} ew_train_model;

int ew_train_model_init(ew_train_model *m, const ew_guidenet *net);
void ew_train_model_free(ew_train_model *m);
/* Point at params and re-lay them out; call after every update. */
void ew_train_model_prepare(ew_train_model *m, const float *params);

/*
 * Forward and backward of one patch: returns the patch's loss (mean L1 of
 * the tone-mapped colour over its pixels and channels) and adds its
 * gradient to grad (nparams floats). grad may be NULL for a forward pass
 * only. out_rgb (size*size*3, may be NULL) receives the denoised colour.
 * ref_tm_override (size*size*3, may be NULL) replaces the reference's tone-
 * mapped colour (tests use it to keep the loss away from its kinks).
 */
double ew_train_patch(const ew_train_model *m, const ew_train_frame *frames, const ew_patch_ref *ref, int size,
                      ew_train_scratch *s, float *grad, float *out_rgb, const float *ref_tm_override);

/* The patch of a step: frame, position and symmetry from a hash of
 * (seed, step, index). frame_pick maps a uniform number in [0, 1) to a
 * frame index (the caller decides how scenes are weighted). */
ew_patch_ref ew_train_pick(uint64_t seed, uint64_t step, int index, const ew_train_frame *frames,
                           int (*frame_pick)(void *user, double u), void *user, int size);

/* ---- a step ------------------------------------------------------------ */
typedef struct ew_adam {
    double lr, beta1, beta2, eps;
    uint64_t step;  /* updates done */
    float *m, *v;   /* nparams each */
} ew_adam;

typedef struct ew_train_step_stats {
    double loss;         /* mean over the batch */
    double grad_norm;    /* global L2 norm of the mean gradient, before clipping */
    int clipped;         /* 1 when the gradient was scaled down to max_norm */
} ew_train_step_stats;

typedef struct ew_trainer ew_trainer;
/* batch patches of side size; threads from dev. NULL when out of memory. */
ew_trainer *ew_trainer_create(ew_device *dev, const ew_guidenet *net, int batch, int size);
void ew_trainer_destroy(ew_trainer *t);
/* One step of Adam on the mean gradient of the batch given by `refs`, the
 * gradient first clipped to global L2 norm max_norm (<= 0: no clipping).
 * Gradient clipping rescales, never zeroes: the step keeps its direction. */
void ew_trainer_step(ew_trainer *t, float *params, ew_adam *adam, const ew_train_frame *frames,
                     const ew_patch_ref *refs, double max_norm, ew_train_step_stats *stats);
/* Mean gradient of a batch without updating (for tests). grad: nparams. */
double ew_trainer_gradient(ew_trainer *t, const float *params, const ew_train_frame *frames, const ew_patch_ref *refs,
                           float *grad);

/* Adam (Kingma & Ba 2014) with bias correction. */
void ew_adam_update(ew_adam *a, float *params, const float *grad, size_t n);
/* Scale grad to L2 norm max_norm if above it; returns the norm before. */
double ew_clip_global_norm(float *grad, size_t n, double max_norm, int *clipped);
/* The optimiser step of every trainer: grad clipped to global L2 norm
 * max_norm (<= 0: no clipping), then Adam. Returns the norm before. */
double ew_adam_step(ew_adam *a, float *params, float *grad, size_t n, double max_norm, int *clipped);

/* A batch's per-patch gradients and losses (patch b writes its own, from
 * whichever thread runs it) and their mean, summed in patch order so that
 * a step does not depend on the number of threads. Every trainer's. */
typedef struct ew_batch_grads {
    int batch;
    size_t nparams;
    float *grads;   /* batch x nparams */
    double *losses; /* batch */
} ew_batch_grads;
/* 0, or -1 when out of memory (free it either way). */
int ew_batch_grads_init(ew_batch_grads *g, int batch, size_t nparams);
void ew_batch_grads_free(ew_batch_grads *g);
/* Patch b's gradient, zeroed. */
float *ew_batch_grads_patch(ew_batch_grads *g, int b);
/* grad (nparams) = the mean gradient; returns the mean loss. */
double ew_batch_grads_mean(const ew_batch_grads *g, float *grad);

#endif
