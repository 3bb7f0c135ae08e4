/*
 * filter "outlier": firefly / outlier suppression with albedo and normal
 * similarity (kernels/outlier.h, ew_outlier_guided_px: the one definition
 * the denoisers' clamps use too). A pixel far brighter
 * than the neighbours of its own surface is scaled down to their bound;
 * NaN/Inf samples are rebuilt from them. Meant before a spatial denoiser or
 * filter on low-sample renders (measured in docs/temporal.md).
 */
#include <stdlib.h>

#include "kernels/color.h"
#include "kernels/outlier.h"
#include "src/backend.h"
#include "src/op_mem.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "linear colour with fireflies (the first 3 channels are read; RGB written to the output)"},
    {"albedo", 3, 0, "albedo: only neighbours of similar albedo are compared (Cycles: Denoising Albedo)"},
    {"normal", 3, 0, "normals: only neighbours of similar orientation are compared (Cycles: Denoising Normal)"},
    {"output", 3, 1, "colour with outliers clamped and NaN/Inf replaced; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"radius", EW_PARAM_INT, 2.0f, 1.0f, 16.0f, "window radius in pixels (2: 5x5, as the denoisers' own clamp)"},
    {"k", EW_PARAM_FLOAT, 3.0f, 0.0f, 100.0f,
     "clamp luminance above the similar neighbours' mean + k standard deviations; 0 only replaces NaN/Inf"},
    {"albedo_tol", EW_PARAM_FLOAT, 0.1f, 0.0f, 1e4f,
     "neighbours whose albedo differs by more than this in any channel are not compared (large: ignore albedo)"},
    {"normal_cos", EW_PARAM_FLOAT, 0.9f, -1.0f, 1.0f,
     "neighbours whose normal has a smaller cosine to the pixel's are not compared (-1: ignore normals)"},
    {"sigma_floor", EW_PARAM_FLOAT, 0.1f, 0.0f, 10.0f,
     "smallest standard deviation as a fraction of the neighbours' mean: noise within k * this is never clamped"},
    {"robust", EW_PARAM_BOOL, 0.0f, 0.0f, 1.0f,
     "1: median and 1.4826 x median absolute deviation of the similar neighbours instead of mean and standard "
     "deviation (a second firefly or an emitter in the window cannot hide a firefly; radius at most 3), as the "
     "denoisers' outlier_k rejection"},
};

/* Every buffer in one device allocation (commit), reused by each execute
 * (src/op_mem.h), so the filter runs on CUDA devices too. Colour and output
 * carry the channels both views share (alpha passes through the kernel). */
typedef struct {
    int w, h, has_albedo, has_normal, channels;
    ew_op_mem mem;
    ew_outlier_buffers b;
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) ew_op_mem_free(op, &s->mem);
    free(s);
    op->state = NULL;
}

/* channels of colour and output that the filter carries: RGB and what both views have beyond it */
static int carried_channels(ew_op *op) {
    const int cc = ew_op_image(op, "color")->channels, oc = ew_op_image(op, "output")->channels;
    return cc < oc ? cc : oc;
}

static ew_result commit(ew_op *op) {
    const ew_image *c = ew_op_image(op, "color");
    const int w = c->width, h = c->height, ch = carried_channels(op);
    const int has_a = ew_op_image(op, "albedo") != NULL, has_n = ew_op_image(op, "normal") != NULL;
    state *s = (state *)op->state;
    if (s && s->w == w && s->h == h && s->has_albedo == has_a && s->has_normal == has_n && s->channels == ch)
        return EW_OK;
    release(op);
    s = (state *)calloc(1, sizeof(state));
    op->state = s;
    if (!s) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
    const size_t n = (size_t)w * (size_t)h;
    float *color, *out, *albedo, *normal;
    const ew_op_buf bufs[] = {{&color, n * (size_t)ch}, {&out, n * (size_t)ch}, {&albedo, has_a ? n * 3 : 0},
                              {&normal, has_n ? n * 3 : 0}};
    const ew_result r = ew_op_mem_alloc(op, &s->mem, bufs, 4, ch);
    if (r != EW_OK) return r;
    s->w = w;
    s->h = h;
    s->has_albedo = has_a;
    s->has_normal = has_n;
    s->channels = ch;
    s->b.channels = ch;
    s->b.color = color;
    s->b.out = out;
    s->b.albedo = albedo;
    s->b.normal = normal;
    return EW_OK;
}

static ew_result execute(ew_op *op) {
    ew_device *dev = op->dev;
    state *s = (state *)op->state;
    const ew_outlier_buffers *b = &s->b;
    ew_result r = ew_op_put(op, &s->mem, "color", s->channels, (float *)b->color);
    if (r == EW_OK) r = ew_op_put(op, &s->mem, "albedo", 3, (float *)b->albedo);
    if (r == EW_OK) r = ew_op_put(op, &s->mem, "normal", 3, (float *)b->normal);
    if (r != EW_OK) return r;
    ew_outlier_params p = ew_outlier_plain_params(s->w, s->h, (int)ew_op_param(op, "radius"), ew_op_param(op, "k"));
    p.shift = 1;
    p.repair = 1;
    p.robust = ew_op_param(op, "robust") != 0.0f;
    p.albedo_tol = ew_op_param(op, "albedo_tol");
    p.normal_cos = ew_op_param(op, "normal_cos");
    p.sigma_floor = ew_op_param(op, "sigma_floor");
    dev->backend->outlier_guided(dev, &p, b);
    return ew_op_get(op, &s->mem, b->out, s->channels, "output");
}

const ew_op_type ew_filter_outlier = {
    .kind = "filter",
    .name = "outlier",
    .summary = "firefly / outlier suppression: clamp pixels far brighter than the neighbours of similar albedo and "
    "normal, rebuild NaN/Inf",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .device_memory = 1,
    .inplace_inputs = (const char *const[]){"color", NULL},
    .flags = EW_METHOD_HOST, /* before any filter of the host's */
};
EW_REGISTER_OP(ew_filter_outlier, 110);
