/*
 * kpcn.h — the kernel-predicting denoiser "kpcn": a small U-Net of 5x5
 * convolutions over S scales (3 by default; 4 or 5) predicts, at full
 * resolution and every coarser scale (each half the last), a 5x5 softmax
 * kernel per pixel that filters the albedo-demodulated radiance of that
 * scale, and per pixel of every scale but the coarsest a weight blending in
 * the next coarser scale's (bilinearly upsampled) result (kernels/kpcn.h).
 * The albedo is multiplied back at the end. The coarsest scale's 5x5 kernel
 * spans 5 * 2^(S-1) full-resolution pixels (20 at S = 3, 40 at 4, 80 at 5:
 * the low-frequency noise of a diffuse room at 16-64 spp needs the wide
 * ones), at a cost dominated by the full-resolution layers either way.
 *
 * Layers (all 5x5 SAME convolutions with biases; C = the width), S = 3
 * shown; another S repeats the middle scale's encoder, decoder and head:
 *   0 enc0  scale 0  inputs (10|11)  -> h0 (C)  LeakyReLU
 *   1 enc1  scale 1  pool(h0) (C)    -> h1 (C)  LeakyReLU
 *   2 enc2a scale 2  pool(h1) (C)    -> h2a (C) LeakyReLU
 *   3 enc2b scale 2  h2a             -> h2b (C) LeakyReLU
 *   4 head2 scale 2  h2b             -> 25 kernel logits
 *   5 dec1  scale 1  [h1, up(h2b)]   -> d1 (C)  LeakyReLU
 *   6 head1 scale 1  d1              -> 25 kernel logits + 1 blend logit
 *   7 dec0  scale 0  [h0, up(d1)]    -> d0 (C)  LeakyReLU
 *   8 head0 scale 0  d0              -> 25 + 1 (+ 25: the remodulation kernel, "-ra")
 * In general: enc_k (k < S-1), the coarsest scale's enc_a, enc_b and head,
 * then dec_k, head_k for k = S-2 down to 0: 3S layers.
 *
 * Weights file (src/weights.h): arch "kpcn-c<C>" (10 inputs),
 * "kpcn-c<C>-noise" (11: the frame's noise level too), either followed by
 * "-s<S>" for S != 3, then "-ra" for the remodulation kernel (head0 has 51
 * outputs; kernels/kpcn.h); tensors conv<l>.weight [cout, cin, 5, 5] and
 * conv<l>.bias [cout], l = 0..3S-1 in the order above.
 *
 * Per scale, one zero-padded plane buffer (algorithms/guidenet.h's
 * ew_gn_planes) holds every plane of that scale, laid out so that each
 * convolution's input is one contiguous run of planes (the decoders' skip
 * concatenation costs nothing):
 *   scale 0:          inputs (10|11) | h | up(d or h_b of the next scale) | d | head (26, or 51)
 *   scale 0 < k < S-1: pool(h of k-1) | h | up(...) | d | head (26)
 *   scale S-1:        pool(h of S-2) | h_a | h_b | head (25)
 */
#ifndef EW_ALGORITHMS_KPCN_H
#define EW_ALGORITHMS_KPCN_H

#include <stddef.h>
#include <stdint.h>

#include "algorithms/guidenet.h"
#include "edgewise/edgewise.h"
#include "kernels/kpcn.h"
#include "src/tiling.h"
#include "src/weights.h"

#define EW_KPCN_DEFAULT_SCALES 3
#define EW_KPCN_MAX_SCALES 5
#define EW_KPCN_MAX_LAYERS (3 * EW_KPCN_MAX_SCALES)
#define EW_KPCN_MIN_CH 4
#define EW_KPCN_MAX_CH 64

typedef struct ew_kpcn_layer {
    int scale, in_plane, cin, out_plane, cout, act;
    size_t w_off, b_off;
} ew_kpcn_layer;

typedef struct ew_kpcn_net {
    char arch[40]; /* "kpcn-c<C>[-noise][-s<S>][-ra]" */
    int ch;
    int noise;  /* 1: the network also sees the frame's noise level (kernels/kpcn.h) */
    int remod;  /* 1: head0 also predicts the kernel of the remodulation albedo (kernels/kpcn.h) */
    int inputs; /* input planes: EW_KPCN_INPUTS, + 1 with noise */
    int scales, nlayers;
    int nplanes[EW_KPCN_MAX_SCALES];
    /* plane indices per scale k: in (scale 0: the inputs; else the pooled
     * encoder output of k-1), h (the encoder's output; the coarsest scale's
     * first encoder), u (the next scale's output upsampled; k < S-1), d (the
     * decoder's; k < S-1), head (the kernel logits); hb: the coarsest
     * scale's second encoder */
    int in[EW_KPCN_MAX_SCALES], h[EW_KPCN_MAX_SCALES], u[EW_KPCN_MAX_SCALES], d[EW_KPCN_MAX_SCALES],
        head[EW_KPCN_MAX_SCALES], hb;
    /* layer indices: enc[k] (k < S-1), enc_a, enc_b (the coarsest scale),
     * dec[k] (k < S-1), lhead[k] (every scale) */
    int enc[EW_KPCN_MAX_SCALES], enc_a, enc_b, dec[EW_KPCN_MAX_SCALES], lhead[EW_KPCN_MAX_SCALES];
    ew_kpcn_layer layers[EW_KPCN_MAX_LAYERS];
    size_t nparams;
} ew_kpcn_net;

/* "kpcn-c<C>[-noise][-s<S>][-ra]" with C in [EW_KPCN_MIN_CH, EW_KPCN_MAX_CH],
 * S in [3, EW_KPCN_MAX_SCALES]. 0 or non-zero + message. */
int ew_kpcn_init(ew_kpcn_net *net, const char *arch, char *err, size_t errlen);
/* head0's outputs: EW_KPCN_HEAD, or EW_KPCN_HEAD_REMOD with the remodulation kernel */
static inline int ew_kpcn_head0_outputs(const ew_kpcn_net *net) { return net->remod ? EW_KPCN_HEAD_REMOD : EW_KPCN_HEAD; }
/* Kaiming-uniform for the LeakyReLU layers, heads 10x smaller (kernels start
 * near a box filter, blends near one half), zero biases; a pure function of
 * the seed. */
void ew_kpcn_random(const ew_kpcn_net *net, uint64_t seed, float *params);
int ew_kpcn_from_weights(ew_kpcn_net *net, const ew_weights *w, float **params, char *err, size_t errlen);
int ew_kpcn_save(const ew_kpcn_net *net, const float *params, void **out, size_t *size);
/* Parameters of net from those of another architecture src (a warm start),
 * over params already holding ew_kpcn_random's: src's channels are copied,
 * an old channel's weights from a new input (a wider net's extra channels,
 * the noise plane) are zero, and a new channel keeps its random weights. So
 * the net computes src's output until trained, and the new channels still
 * get gradients (their consumers' weights start at zero, not their own).
 * More scales than src (S > src's): src's coarsest scale becomes a middle
 * one (its enc_a the encoder, its enc_b the decoder reading the skip half,
 * its head the head, with a blend logit of weight 0 and bias
 * EW_KPCN_NEW_SCALE_BIAS), the new coarser scales keep random weights: the
 * output moves by that blend's sigmoid (1.8 %) toward the new scales', and
 * they are trained from the first step. A remodulation kernel src lacks
 * ("-ra" from a net without) starts with weight 0 and the centre tap's bias
 * (EW_KPCN_REMOD_CENTRE_BIAS). */
#define EW_KPCN_NEW_SCALE_BIAS (-4.0f)
/* A remodulation kernel starts as its centre tap: logit 6 against 0 for the
 * other 24 taps gives it e^6 / (e^6 + 24) = 94 % of the weight (random
 * initialisation and warm start alike); the network learns where to widen
 * it. */
#define EW_KPCN_REMOD_CENTRE_BIAS 6.0f
void ew_kpcn_params_from(const ew_kpcn_net *net, float *params, const ew_kpcn_net *src, const float *src_params);
/* The noise plane's value of a frame: EW_REDUCE_NOISE over its (clamped,
 * demodulated) radiance, 3 floats a pixel. */
float ew_kpcn_frame_noise(int width, int height, const float *radiance);
/* Multiply-adds of the convolutions per full-resolution pixel. */
double ew_kpcn_macs_per_pixel(const ew_kpcn_net *net);
/* The convolution of layer l on the scale buffers buf[scale]. */
void ew_kpcn_layer_args(const ew_kpcn_net *net, int l, const float *params, const ew_gn_planes *buf,
                        ew_conv_args *a);
/* Sizes of the net's scales of a w x h frame. */
void ew_kpcn_scale_sizes(const ew_kpcn_net *net, int w, int h, int *sw, int *sh);

/* ---- built-in models ------------------------------------------------- */
#define EW_KPCN_NUM_MODELS 3
/* 0 = "kpcn" (the default), 1 = "kpcn-small", 2 = "kpcn-large": the files
 * models/kpcn/<name>.ewm, compiled in as kpcn_weights_data.c. */
const char *ew_kpcn_model_name(int which);
extern const char *const ew_kpcn_model_names[EW_KPCN_NUM_MODELS + 1]; /* NULL-terminated (enum choices) */
/* The built-in model's weights file; size 0 when this build has none. */
void ew_kpcn_builtin_weights(int which, const unsigned char **bytes, size_t *size);
/* kpcn_weights_data.c (train_kpcn --emit-c) */
extern const unsigned char *const ew_kpcn_builtin_bytes[EW_KPCN_NUM_MODELS];
extern const size_t ew_kpcn_builtin_sizes[EW_KPCN_NUM_MODELS];

/* ---- inference on a device -------------------------------------------- */
/* The op's plane layout of net (inference only: the trainer keeps every
 * plane for the backward pass): a scale's inputs (the features, or the
 * pooled planes) lie where the upsampled and decoder planes go later, as
 * only the encoder reads them (where they fit there), and each scale's
 * head writes its logits over the planes below its input (the encoder's
 * output, the upsampled planes; the coarsest scale's pooled planes and
 * first encoder), which nothing reads once the decoder has run, where they
 * fit. kpcn-large (32 channels, a remodulation kernel) would hold 96
 * planes at full resolution and at the two finer half scales (the
 * trainer's layout: 158 and 154; with the heads alone over dead planes:
 * 107 and 128): the memory the op touches, the page faults of a first run
 * and the tiles it needs shrink with it. The arithmetic is the same. Full
 * resolution and scale 1 then run in bands (below): scale 1 keeps the 32
 * planes of its encoder's output, the decoder's output written over them. */
void ew_kpcn_inference_planes(ew_kpcn_net *net);

/* The full-resolution scale in bands of rows: a region holds no plane of
 * it, only a band of EW_KPCN_BAND_ROWS rows of every plane with margins.
 * Encoding, band after band: the inputs, the encoder on the band's rows
 * (the inputs 2 rows beyond them) and its 2x2 pooling into the next
 * scale's inputs. Decoding, once the coarser scales are done: each band
 * computes its inputs and the encoder's output again, upsamples the next
 * scale's output, runs the decoder, the head and the kernel filter. A
 * band's head reads its decoder 2 rows beyond it, which reads the encoder's
 * output and the upsampled planes 2 rows further; on the CPU every
 * convolution's Winograd tiles (4 rows, anchored at the frame's origin)
 * must be whole and the frame's own, so the decoder runs on
 * EW_KPCN_DEC_MARGIN rows beyond the band, the encoder on
 * EW_KPCN_ENC_MARGIN (6 rounded up to the tiles), and the inputs reach
 * EW_KPCN_BAND_MARGIN rows either side. The same bits as the planes of the
 * whole region. The encoder's second run and the margins cost about 21 %
 * more multiply-adds of kpcn-large (15 % with bands of 64 rows, yet those
 * ran no faster: 32-row bands keep their planes nearer the caches, and a
 * 4K tile's band takes 16 MiB instead of 26); holding the encoder's inputs
 * and output for the decoder would take 43 planes of the region. */
#define EW_KPCN_BAND_ROWS 32
#define EW_KPCN_DEC_MARGIN 4
#define EW_KPCN_ENC_MARGIN 8
#define EW_KPCN_BAND_MARGIN (EW_KPCN_ENC_MARGIN + EW_CONV_R)
/* the rows of the band of a region h rows tall: its margins included */
int ew_kpcn_band_rows(int h);

/* The scales between full resolution and the coarsest in bands too,
 * without computing anything twice: the region keeps each one's encoder
 * output h (C planes; before session 36 every plane of the scale, 3C: 75
 * MiB of a 4K tile's region at kpcn-large's half scale). A scale's encoder
 * runs on chunks of EW_KPCN_BAND_ROWS / 2 rows as soon as the finer scale
 * has pooled the rows a chunk reads (2 beyond it, kept in the scale's
 * band): scale 1's from scale 0's encoder band by band, the others' from
 * the finer scale's whole h. Decoding, coarse to fine, band by band of
 * EW_KPCN_BAND_ROWS rows: h and the upsampled coarser output 2 rows beyond
 * the band into the band, the decoder over h's rows of the band (the 2
 * rows above it, which it read and which the band above has overwritten,
 * carried over in the band); then the head on bands of that decoder output
 * into the band and the kernel filter. Chunks and bands end on rows of the
 * frame's Winograd grid (the 4-row tiles anchored at the frame's origin,
 * at the scale), so every window's tiles are whole and the frame's own:
 * the same bits as the whole planes. */
/* the rows and planes of such a scale's band, for a scale hk rows tall */
int ew_kpcn_scale_band_rows(int hk);
int ew_kpcn_scale_band_planes(const ew_kpcn_net *net);
/* Floats of the scale buffers of a w x h region, in the op's order: the
 * planes of the scales below full resolution, scale 0's band, the bands of
 * the scales between (each laid out by ew_gn_planes_layout, 16 floats
 * apart). */
size_t ew_kpcn_planes_floats(const ew_kpcn_net *net, int w, int h);

/* Device floats the op needs for a w x h frame beyond its packed inputs:
 * the scale buffers above, radiance pyramid and outputs of the scales
 * below 0. */
size_t ew_kpcn_device_floats(const ew_kpcn_net *net, int w, int h);

/* ---- tiles -------------------------------------------------------------
 * A frame whose planes exceed a memory budget runs in tiles: each tile's
 * core is computed on a region that adds ew_kpcn_halo pixels on every side
 * inside the frame, and only the core is kept. The halo is how far an
 * output pixel's inputs reach, counted by following every path of the
 * layer list above (convolutions, poolings, upsamplings, the kernels' taps
 * on the radiance pyramid) from each pixel phase: 36 pixels at S = 3 (the
 * longest path runs head0, dec0, up, dec1, up, enc2b, enc2a, pool, enc1,
 * pool, enc0; 32 would not do). A region reads zero padding or clamped taps
 * only at its own edges, so with that halo every core pixel sees what it
 * sees in the whole frame. Core and region origins are multiples of
 * ew_kpcn_align (2^(S-1)), so the 2x2 poolings of a region pair the same
 * pixels as the whole frame's; the output is the same bits as one
 * whole-frame pass (tests/unit/test_kpcn.c). */
int ew_kpcn_halo(const ew_kpcn_net *net);
/* ... for an output exact `margin` pixels around the core too (what a
 * blend's window reads around it: src/harm_stage.c, in the tiles) */
int ew_kpcn_halo_around(const ew_kpcn_net *net, int margin);
int ew_kpcn_align(const ew_kpcn_net *net);

/* Tiles of a w x h frame (src/tiling.h) with kpcn's halo (around margin
 * pixels) and alignment, each region within budget_floats device floats
 * (ew_kpcn_device_floats + region_extra_floats a region pixel). */
void ew_kpcn_tiling_plan(const ew_kpcn_net *net, int w, int h, size_t budget_floats, size_t region_extra_floats,
                         int margin, ew_tiling *t);

/* ---- training (host) ---------------------------------------------------- */
#define EW_KPCN_LOSS_TM 0  /* L1 of the metrics' tone curve (kernels/guidenet.h ew_nbg_tm) */
#define EW_KPCN_LOSS_LOG 1 /* L1 of log(1 + x) */
/* 10 log10(MSE + EW_KPCN_PSNR_EPS) of the tone curve over each patch: minus
 * the patch's PSNR, so that a 64-spp patch's last tenth of a dB weighs as
 * much as a 1-spp patch's, as in the benchmark's mean PSNR per sample
 * count (an L1 or MSE over the batch is ruled by the 1-spp errors) */
#define EW_KPCN_LOSS_PSNR 2
#define EW_KPCN_PSNR_EPS 1e-5 /* 50 dB: flatter patches weigh no more than one there */

/* One frame, preprocessed as the op preprocesses it. */
typedef struct ew_kpcn_frame {
    int width, height;
    float *input;    /* EW_KPCN_MAX_INPUTS planes of width*height (the noise plane last) */
    float *radiance; /* 3 a pixel: demodulated, firefly-clamped */
    float *albedo;   /* 3 a pixel: the albedo as read (the remodulation factor is ew_albedo_factor of it) */
    float *ref;      /* 3 a pixel: the reference colour (linear) */
} ew_kpcn_frame;

int ew_kpcn_frame_init(ew_kpcn_frame *f, int width, int height, const float *color, const float *albedo,
                       const float *normal, const float *depth, const float *reference, float firefly_k);
void ew_kpcn_frame_free(ew_kpcn_frame *f);

typedef struct ew_kpcn_scratch ew_kpcn_scratch;
ew_kpcn_scratch *ew_kpcn_scratch_create(const ew_kpcn_net *net, int size);
void ew_kpcn_scratch_destroy(ew_kpcn_scratch *s);

/* The parameters and their SIMD re-layouts, shared by a step's patches. */
typedef struct ew_kpcn_model {
    const ew_kpcn_net *net;
    const float *params;
    float *wt, *fwt, *flip;
} ew_kpcn_model;
int ew_kpcn_model_init(ew_kpcn_model *m, const ew_kpcn_net *net);
void ew_kpcn_model_free(ew_kpcn_model *m);
void ew_kpcn_model_prepare(ew_kpcn_model *m, const float *params);

/* Patch from a frame: square of side size at (x0, y0), symmetry aug (bit 0
 * flip x, bit 1 flip y, bit 2 transpose; as algorithms/train.h). */
typedef struct ew_kpcn_patch {
    int frame, x0, y0, aug;
} ew_kpcn_patch;

/*
 * Forward and backward of one patch (size a multiple of ew_kpcn_align): returns the
 * loss (the mean L1 over pixels and channels; EW_KPCN_LOSS_PSNR: minus the
 * patch's PSNR in dB) and adds the gradient to grad
 * (NULL: forward only). out_rgb (size^2 * 3, may be NULL): the denoised
 * colour. ref_override (size^2 * 3 linear colour, may be NULL) replaces the
 * reference (tests).
 */
double ew_kpcn_train_patch(const ew_kpcn_model *m, const ew_kpcn_frame *frames, const ew_kpcn_patch *p, int size,
                           int loss, ew_kpcn_scratch *s, float *grad, float *out_rgb, const float *ref_override);

typedef struct ew_kpcn_trainer ew_kpcn_trainer;
ew_kpcn_trainer *ew_kpcn_trainer_create(ew_device *dev, const ew_kpcn_net *net, int batch, int size, int loss);
void ew_kpcn_trainer_destroy(ew_kpcn_trainer *t);
/* Mean gradient of a batch (grad: nparams); returns the mean loss. */
double ew_kpcn_trainer_gradient(ew_kpcn_trainer *t, const float *params, const ew_kpcn_frame *frames,
                                const ew_kpcn_patch *patches, float *grad);

#endif
