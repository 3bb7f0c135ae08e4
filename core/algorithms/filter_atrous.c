/*
 * filter "atrous": the edge-avoiding à-trous wavelet filter (Dammertz et al.
 * 2010), the spatial filter of SVGF, as the baseline users know.
 */
#include <stdlib.h>
#include <string.h>

#include "algorithms/atrous.h"
#include "algorithms/bilateral.h"
#include "src/op.h"

static const ew_image_desc images[] = {
    {"color", 1, 1, "image to filter (1 to 3 channels, linear; a 4th is premultiplied alpha, filtered too, with weights of its own luminance)"},
    {"normal", 3, 0, "normals for the normal edge-stopping term (Cycles: Denoising Normal)"},
    {"depth", 1, 0, "depth for the depth edge-stopping term (Cycles: Depth)"},
    {"output", 1, 1, "filtered image, as many channels as the colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"radius", EW_PARAM_INT, 8.0f, 0.0f, 256.0f,
     "support radius in pixels: iterations n with 2 (2^n - 1) >= radius (ignored when iterations > 0)"},
    {"iterations", EW_PARAM_INT, 0.0f, 0.0f, 12.0f, "number of à-trous iterations; 0 = from the radius"},
    {"sigma_luminance", EW_PARAM_FLOAT, 0.5f, 0.0f, 1e4f,
     "luminance edge-stopping sigma of the first iteration (halved at each); 0 = off"},
    {"sigma_normal", EW_PARAM_FLOAT, 0.3f, 0.0f, 100.0f, "sigma of |n_p - n_q|; 0 = off"},
    {"sigma_depth", EW_PARAM_FLOAT, 0.5f, 0.0f, 1e6f, "sigma of |z_p - z_q| in depth units; 0 = off"},
};

typedef struct {
    int w, h, C, iterations;
    float *image, *tmp, *out, *normal, *depth;
    float mem[];
} state;

static void release(ew_op *op) {
    free(op->state);
    op->state = NULL;
}

static ew_result commit(ew_op *op) {
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    const int w = color->width, h = color->height, C = color->channels;
    if (C > EW_BF_MAX_CH)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image 'color' has %d channels; at most %d are supported",
                        C, EW_BF_MAX_CH);
    if (output->channels < C)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image 'output' has %d channels but 'color' has %d",
                        output->channels, C);
    const int has_n = ew_op_image(op, "normal") != NULL, has_d = ew_op_image(op, "depth") != NULL;
    const size_t n = (size_t)w * (size_t)h;
    size_t need = n * (size_t)EW_BF_CH * 3 + (has_n ? n * 3 : 0) + (has_d ? n : 0);
    state *s = (state *)ew_op_state_block(op, sizeof(state) + need * sizeof(float));
    if (!s)
        return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory: filtering %dx%d needs %.1f MiB", w, h,
                        (double)need * sizeof(float) / 1048576.0);
    s->w = w;
    s->h = h;
    s->C = C;
    int it = (int)ew_op_param(op, "iterations");
    s->iterations = it > 0 ? it : ew_atrous_iterations_for((int)ew_op_param(op, "radius"));
    float *p = s->mem;
    s->image = p; p += n * (size_t)EW_BF_CH;
    s->tmp = p; p += n * (size_t)EW_BF_CH;
    s->out = p; p += n * (size_t)EW_BF_CH;
    s->normal = has_n ? p : NULL; p += has_n ? n * 3 : 0;
    s->depth = has_d ? p : NULL;
    return EW_OK;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_bf_pack_image(op->dev, ew_op_image(op, "color"), s->C, s->image);
    long bad = 0;
    if (s->normal) ew_bf_pack_channels(op->dev, ew_op_image(op, "normal"), 3, s->normal, &bad);
    if (s->depth) ew_bf_pack_channels(op->dev, ew_op_image(op, "depth"), 1, s->depth, &bad);
    ew_atrous_run(op->dev, s->w, s->h, s->C, s->iterations, s->image, s->tmp, s->out, s->normal, s->depth,
                  ew_op_param(op, "sigma_luminance"), ew_op_param(op, "sigma_normal"), ew_op_param(op, "sigma_depth"));
    ew_bf_unpack_image(op->dev, s->out, s->C, ew_op_image(op, "output"), ew_op_image(op, "color"));
    return EW_OK;
}

const ew_op_type ew_filter_atrous = {
    .kind = "filter",
    .name = "atrous",
    .summary = "edge-avoiding à-trous wavelet filter (Dammertz et al. 2010, the SVGF spatial filter) with luminance, "
    "normal and depth edge-stopping",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .pixel_params = (const char *const[]){"radius", NULL},
    .inplace_inputs = (const char *const[]){"color", NULL},
    .filters_alpha = 1,
    /* zero iterations */
    .noop_at_zero = (const char *const[]){"radius", "iterations", NULL},
    .flags = EW_METHOD_HOST,
    .denoises = 1,
};
EW_REGISTER_OP(ew_filter_atrous, 80);
