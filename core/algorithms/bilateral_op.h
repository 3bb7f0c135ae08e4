/*
 * bilateral_op.h — what the filters "bilateral", "separable" and "pyramid"
 * share: the same images and parameters (declared once here), one model
 * built from them, and one commit/execute parameterised by the method.
 */
#ifndef EW_ALGORITHMS_BILATERAL_OP_H
#define EW_ALGORITHMS_BILATERAL_OP_H

#include "algorithms/bilateral.h"
#include "algorithms/pyramid.h"
#include "src/op.h"

typedef enum { EW_BF_BRUTE = 0, EW_BF_SEPARABLE = 1, EW_BF_PYRAMID = 2 } ew_bf_method;

#define EW_BF_OP_IMAGES                                                                                         \
    {"color", 1, 1, "image to filter (1 to 3 channels, linear; a 4th is premultiplied alpha, filtered with the colour's weights)"},           \
    {"guide", 1, 0, "model color: edge-stopping guide, up to 4 channels (default: the colour itself)"},         \
    {"normal", 3, 0, "model gi: normals, unit or zero for no surface (Cycles: Denoising Normal)"},             \
    {"depth", 1, 0, "models gi and depth: depth (Cycles: Depth); model depth without it filters on the colour's first channel"}, \
    {"roughness", 1, 0, "model gi: roughness alpha in [0, 1]; absent = diffuse (sqrt(alpha) = 1, no roughness test)"}, \
    {"output", 1, 1, "filtered image, as many channels as the colour; may be the colour view itself"}

#define EW_BF_OP_PARAMS                                                                                         \
    {"model", EW_PARAM_INT, 0.0f, 0.0f, 3.0f,                                                                   \
     "edge-stopping functions: color: difference of the guide (sigma_range), gi: GI denoising, Eq. 9 "        \
     "(normal, depth, roughness), depth: Eq. 10, none: a plain Gaussian"},                                     \
    {"radius", EW_PARAM_INT, 8.0f, 0.0f, 256.0f,                                                                \
     "kernel radius in pixels (the exact filter's window; model gi: the radius at roughness 1)"},             \
    {"sigma_spatial", EW_PARAM_FLOAT, 0.0f, 0.0f, 256.0f, "domain Gaussian sigma in pixels; 0 = radius / 3"},  \
    {"sigma_range", EW_PARAM_FLOAT, 0.1f, 1e-4f, 1e4f, "model color: sigma of the guide difference"},         \
    {"sigma_normal", EW_PARAM_FLOAT, 32.0f, 0.0f, 1024.0f, "model gi: exponent s of (n_p . n_q)^s"},           \
    {"sigma_depth", EW_PARAM_FLOAT, 1.0f, 0.0f, 1e6f, "models gi and depth: s in exp(-s z_p |z_p - z_q|)"}

/* The parameters of EW_BF_OP_PARAMS that are lengths in pixels (ew_op_type.pixel_params). */
#define EW_BF_OP_PIXEL_PARAMS ((const char *const[]){"radius", "sigma_spatial", NULL})

/* Choice names of "model" (in the order of bilateral_op.c's kinds[]) and of the
 * pyramid's "weights". */
#define EW_BF_MODEL_CHOICES {"model", (const char *const[]){"color", "gi", "depth", "none", NULL}}
#define EW_PYR_WEIGHTS_CHOICES {"weights", (const char *const[]){"analytic", "trained", NULL}}
/* The filters' one input the output may be: the colour (they read it
 * whole before writing). */
#define EW_BF_OP_INPLACE ((const char *const[]){"color", NULL})

#define EW_PYR_WEIGHTS_PARAM                                                                                    \
    {"weights", EW_PARAM_INT, 1.0f, 0.0f, 1.0f,                                                                 \
     "pyramid domain weights: analytic (the paper's method e), trained (built in, models/pyramid), or a "      \
     "weights file given as data 'weights'"}

ew_result ew_bf_op_commit(ew_op *op, ew_bf_method method);
ew_result ew_bf_op_execute(ew_op *op);
void ew_bf_op_release(ew_op *op);
/* ew_op_type.alpha_guides: the alpha's run gets the colour as its guide
 * (model color) and as its depth (model depth without a depth image). */
void ew_bf_op_alpha_guides(const ew_op *op, ew_op *alpha_op);

/* The pyramid's weights table for a commit: the one given with
 * set_data("weights", file bytes) if any, else the built-in trained table
 * of the model kind when trained != 0 (parsed into *table), else NULL
 * (analytic). Errors are reported on op. The pyramid and DoF filters share
 * this. */
ew_result ew_bf_op_table(ew_op *op, int trained, int kind, ew_pyr_table *table, const ew_pyr_table **out);

/* set_data("weights", bytes of a weights file): validated now, kept in
 * op->data_state until unset (NULL) or the filter is destroyed. */
ew_result ew_pyr_op_set_data(ew_op *op, const char *name, const void *data, size_t size);
void ew_pyr_op_release_data(ew_op *op);

#endif
