/*
 * denoise_bgrid.c — denoiser "bgrid": albedo demodulation, a hand-made guide
 * (mean of normalised features, the baseline of Meng et al. 2020 Fig. 7, or
 * the colour's luminance without features), one bilateral grid, splat,
 * slice, remodulation.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/bgrid.h"
#include "src/backend.h"
#include "src/op.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "noisy colour (RGB, linear)"},
    {"albedo", 3, 0, "albedo for demodulation and guidance (Cycles: Denoising Albedo)"},
    {"normal", 3, 0, "normal in [-1, 1] (Cycles: Denoising Normal)"},
    {"depth", 1, 0, "depth (Cycles: Denoising Depth or Depth)"},
    {"output", 3, 1, "denoised colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"spatial_rate", EW_PARAM_FLOAT, 8.0f, 1.0f, 256.0f, "pixels per grid cell (eta_s); larger blurs more"},
    {"range_rate", EW_PARAM_FLOAT, 8.0f, 1.0f, 256.0f, "guide units per grid cell on the 0..255 guide (eta_d); larger blurs across more edges"},
    {"color_weight", EW_PARAM_FLOAT, 0.7f, 0.0f, 1.0f, "share of a first-pass radiance estimate in the guide (0: features only, one pass)"},
    {"prepass_rate", EW_PARAM_FLOAT, 8.0f, 1.0f, 256.0f, "spatial rate of the first pass that feeds color_weight"},
    {"firefly_k", EW_PARAM_FLOAT, 3.0f, 0.0f, 100.0f, "clamp pixels brighter than the 5x5 mean + k standard deviations before filtering; 0 turns it off"},
};

typedef struct {
    ew_bgrid_params grid_params, prepass_params;
    ew_denoise_buffers buf;
    float *grid;
    float *clamped; /* radiance after firefly suppression */
    float mem[]; /* every buffer, one allocation */
} state;

static ew_result commit(ew_op *op) {
    const ew_image *color = ew_op_image(op, "color");
    const int w = color->width, h = color->height;
    ew_bgrid_params gp, pre;
    if (!ew_bgrid_params_init(&gp, w, h, ew_op_param(op, "spatial_rate"), ew_op_param(op, "range_rate"), 3) ||
        !ew_bgrid_params_init(&pre, w, h, ew_op_param(op, "prepass_rate"), ew_op_param(op, "range_rate"), 3))
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "invalid grid parameters");
    size_t grid_floats = ew_bgrid_floats(&gp);
    if (ew_bgrid_floats(&pre) > grid_floats) grid_floats = ew_bgrid_floats(&pre);
    const int has_a = ew_op_image(op, "albedo") != NULL, has_n = ew_op_image(op, "normal") != NULL,
              has_d = ew_op_image(op, "depth") != NULL;
    /* packed inputs (views may have any stride and the output may alias the
     * colour), radiance, guide, sliced, output, grid */
    const size_t n = (size_t)w * (size_t)h;
    size_t need = n * 3 * 5 + n + (has_a ? n * 3 : 0) + (has_n ? n * 3 : 0) + (has_d ? n : 0) + grid_floats;
    if (op->state) op->type->release(op);
    state *s = (state *)malloc(sizeof(state) + need * sizeof(float));
    op->state = s;
    if (!s)
        return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory: denoising %dx%d needs %.1f MiB", w, h,
                        (double)need * sizeof(float) / 1048576.0);
    float *m = s->mem;
    ew_denoise_buffers *b = &s->buf;
    memset(b, 0, sizeof *b);
    b->width = w;
    b->height = h;
    b->color = m; m += n * 3;
    b->radiance = m; m += n * 3;
    b->guide = m; m += n;
    b->sliced = m; m += n * 3;
    b->out = m; m += n * 3;
    s->clamped = m; m += n * 3;
    if (has_a) { b->albedo = m; m += n * 3; }
    if (has_n) { b->normal = m; m += n * 3; }
    if (has_d) { b->depth = m; m += n; }
    s->grid = m;
    s->grid_params = gp;
    s->prepass_params = pre;
    return EW_OK;
}

/* Background pixels have Depth 1e10 (Depth pass) or 0 (Denoising Depth):
 * normalise by the largest depth below 1e9 so the scene uses the range. */
static float depth_scale(const float *depth, size_t n) {
    float mx = 0.0f;
    for (size_t i = 0; i < n; i++)
        if (isfinite(depth[i]) && depth[i] < 1e9f && depth[i] > mx) mx = depth[i];
    return mx > 0.0f ? 1.0f / mx : 1.0f;
}

static float mean_luminance(const float *rgb, size_t n) {
    double sum = 0.0;
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        float l = ew_luminance(rgb + i * 3);
        if (isfinite(l) && l > 0.0f) { sum += l; k++; }
    }
    return k && sum > 0.0 ? (float)(sum / (double)k) : 1.0f;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    ew_view_pack(ew_op_image(op, "color"), 3, (float *)b->color);
    if (b->albedo) ew_view_pack(ew_op_image(op, "albedo"), 3, (float *)b->albedo);
    if (b->normal) ew_view_pack(ew_op_image(op, "normal"), 3, (float *)b->normal);
    if (b->depth) {
        ew_view_pack(ew_op_image(op, "depth"), 1, (float *)b->depth);
        b->depth_scale = depth_scale(b->depth, (size_t)b->width * b->height);
    }
    dev->backend->denoise_prepare(dev, b);
    if (!ew_op_report(op, 0.2)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    const float k = ew_op_param(op, "firefly_k");
    const float *radiance = b->radiance;
    if (k > 0.0f) {
        dev->backend->outlier_clamp(dev, b->width, b->height, 2, k, b->radiance, s->clamped);
        radiance = s->clamped;
    }
    const float cw = ew_op_param(op, "color_weight");
    if (cw > 0.0f) {
        ew_bgrid_splat(dev, &s->prepass_params, radiance, b->guide, s->grid);
        ew_bgrid_slice(dev, &s->prepass_params, s->grid, b->guide, b->sliced);
        dev->backend->denoise_refine_guide(dev, b, mean_luminance(b->sliced, (size_t)b->width * b->height), cw);
        if (!ew_op_report(op, 0.4)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    ew_bgrid_splat(dev, &s->grid_params, radiance, b->guide, s->grid);
    if (!ew_op_report(op, 0.6)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    ew_bgrid_slice(dev, &s->grid_params, s->grid, b->guide, b->sliced);
    dev->backend->denoise_finish(dev, b);
    ew_view_unpack(b->out, 3, ew_op_image(op, "output"));
    return EW_OK;
}

static void release(ew_op *op) { free(op->state); }

const ew_op_type ew_denoise_bgrid = {
    "denoiser", "bgrid",
    "bilateral grid guided by a hand-made guide: the mean of the normalised albedo, normal and depth "
    "(the colour's luminance when no features are given)",
    images, (int)(sizeof images / sizeof images[0]), params, (int)(sizeof params / sizeof params[0]),
    commit, execute, release, NULL, NULL,
};
