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
#include "kernels/denoise_px.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
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

/*
 * Memory (docs/backends.md): every buffer the backend touches is
 * device memory from one ew_dev_alloc at commit, reused by every execute;
 * execute moves only the input views in and the output view out. The two
 * scalars the host needs (the depth normalisation and the first pass's mean
 * luminance) come back as per-row sums, 2 doubles a row. Host memory: the
 * state, the row sums read back and, when the device has memory of its own,
 * one staging buffer of n x 3 floats that every view is packed through.
 */
typedef struct {
    ew_bgrid_params grid_params, prepass_params;
    ew_denoise_buffers buf; /* device buffers */
    float *grid;            /* device */
    float *clamped;         /* device: radiance after firefly suppression */
    double *row_out;        /* device: reduce_rows output, 2 x height */
    ew_dev_kept dmem; /* the one device allocation, kept across commits of its size */
    double *rows;           /* host: row_out read back */
    float *stage;           /* host staging, or NULL when views need none */
    double host[];          /* rows, then stage */
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) ew_dev_free(op->dev, s->dmem.mem);
    free(s);
    op->state = NULL;
}

/* Device floats of a commit at w x h with these inputs (0: invalid grid
 * parameters): the packed inputs (views may have any stride and the output
 * may alias the colour), radiance, guide, sliced, output, clamped, grid. */
static size_t device_floats(const ew_op *op, int w, int h, int has_a, int has_n, int has_d, ew_bgrid_params *gp,
                            ew_bgrid_params *pre) {
    if (!ew_bgrid_params_init(gp, w, h, ew_op_param(op, "spatial_rate"), ew_op_param(op, "range_rate"), 3) ||
        !ew_bgrid_params_init(pre, w, h, ew_op_param(op, "prepass_rate"), ew_op_param(op, "range_rate"), 3))
        return 0;
    size_t grid_floats = ew_bgrid_floats(gp);
    if (ew_bgrid_floats(pre) > grid_floats) grid_floats = ew_bgrid_floats(pre);
    const size_t n = (size_t)w * (size_t)h;
    return n * 3 * 5 + n + (has_a ? n * 3 : 0) + (has_n ? n * 3 : 0) + (has_d ? n : 0) + grid_floats;
}

/* ew_op_type.memory: the commit's allocations with every feature given
 * (the row sums are doubles, first, for alignment). */
static uint64_t memory(const ew_op *op, int w, int h) {
    ew_bgrid_params gp, pre;
    const size_t n = (size_t)w * (size_t)h, need = device_floats(op, w, h, 1, 1, 1, &gp, &pre);
    if (!need) return 0;
    return (uint64_t)need * sizeof(float) + (uint64_t)h * 4 * sizeof(double) +
           (uint64_t)ew_dev_stage_floats(op->dev, n, 3) * sizeof(float);
}

static ew_result commit(ew_op *op) {
    ew_device *dev = op->dev;
    const ew_image *color = ew_op_image(op, "color");
    const int w = color->width, h = color->height;
    const int has_a = ew_op_image(op, "albedo") != NULL, has_n = ew_op_image(op, "normal") != NULL,
              has_d = ew_op_image(op, "depth") != NULL;
    ew_bgrid_params gp, pre;
    const size_t need = device_floats(op, w, h, has_a, has_n, has_d, &gp, &pre);
    if (!need) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "invalid grid parameters");
    const size_t n = (size_t)w * (size_t)h;
    const size_t row_bytes = (size_t)h * 2 * sizeof(double);
    const size_t stage_floats = ew_dev_stage_floats(dev, n, 3);
    const ew_dev_kept old = ew_dev_kept_take(op->state ? &((state *)op->state)->dmem : NULL);
    release(op);
    state *s = (state *)calloc(1, sizeof(state) + row_bytes + stage_floats * sizeof(float));
    op->state = s;
    if (!ew_dev_keep(dev, s ? &s->dmem : NULL, old, row_bytes + need * sizeof(float)))
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of %s memory: denoising %dx%d needs %.1f MiB",
                        s ? dev->backend->name : "host", w, h, (double)need * sizeof(float) / 1048576.0);
    s->rows = s->host;
    s->stage = stage_floats ? (float *)(void *)(s->host + (size_t)h * 2) : NULL;
    s->row_out = (double *)s->dmem.mem;
    float *m = (float *)(void *)((char *)s->dmem.mem + row_bytes);
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

/* Sum the per-row pairs of a reduction (computed on the device, read back). */
static ew_result reduce(ew_device *dev, state *s, int kind, const float *src, double *a, double *b) {
    const int h = s->buf.height;
    dev->backend->reduce_rows(dev, kind, s->buf.width, h, src, s->row_out);
    ew_result r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)h * 2 * sizeof(double));
    if (r != EW_OK) return r;
    double sa = 0.0, sb = 0.0;
    for (int y = 0; y < h; y++) {
        if (kind == EW_REDUCE_DEPTH_MAX) {
            if (s->rows[2 * y] > sa) sa = s->rows[2 * y];
        } else {
            sa += s->rows[2 * y];
        }
        sb += s->rows[2 * y + 1];
    }
    *a = sa;
    *b = sb;
    return EW_OK;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    ew_result r = ew_dev_put_view(dev, ew_op_image(op, "color"), 3, (float *)b->color, s->stage);
    if (r == EW_OK && b->albedo) r = ew_dev_put_view(dev, ew_op_image(op, "albedo"), 3, (float *)b->albedo, s->stage);
    if (r == EW_OK && b->normal) r = ew_dev_put_view(dev, ew_op_image(op, "normal"), 3, (float *)b->normal, s->stage);
    if (r == EW_OK && b->depth) {
        r = ew_dev_put_view(dev, ew_op_image(op, "depth"), 1, (float *)b->depth, s->stage);
        /* Background pixels have Depth 1e10 (Depth pass) or 0 (Denoising
         * Depth): normalise by the largest depth below 1e9 (reduce.h) so the
         * scene uses the range. */
        double mx = 0.0, unused;
        if (r == EW_OK) r = reduce(dev, s, EW_REDUCE_DEPTH_MAX, b->depth, &mx, &unused);
        b->depth_scale = mx > 0.0 ? (float)(1.0 / mx) : 1.0f;
    }
    if (r != EW_OK) return r;
    dev->backend->denoise_prepare(dev, b);
    if (!ew_op_report(op, 0.2)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    const float k = ew_op_param(op, "firefly_k");
    const float *radiance = b->radiance;
    if (k > 0.0f) {
        /* the shared outlier definition (kernels/outlier.h) with the
         * statistics this clamp always had: mean and standard deviation */
        const ew_outlier_params fp = ew_outlier_plain_params(b->width, b->height, 2, k);
        const ew_outlier_buffers fb = {b->radiance, NULL, NULL, s->clamped, 3, ew_harm_clamp_removed(op)};
        dev->backend->outlier_guided(dev, &fp, &fb);
        radiance = s->clamped;
    }
    const float cw = ew_op_param(op, "color_weight");
    if (cw > 0.0f) {
        ew_bgrid_splat(dev, &s->prepass_params, radiance, b->guide, s->grid);
        ew_bgrid_slice(dev, &s->prepass_params, s->grid, b->guide, b->sliced);
        /* mean of the finite, positive luminances (1 when there are none) */
        double sum = 0.0, count = 0.0;
        r = reduce(dev, s, EW_REDUCE_LUM_SUM, b->sliced, &sum, &count);
        if (r != EW_OK) return r;
        const float mean = count > 0.0 && sum > 0.0 ? (float)(sum / count) : 1.0f;
        dev->backend->denoise_refine_guide(dev, b, mean, cw);
        if (!ew_op_report(op, 0.4)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    ew_bgrid_splat(dev, &s->grid_params, radiance, b->guide, s->grid);
    if (!ew_op_report(op, 0.6)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    ew_bgrid_slice(dev, &s->grid_params, s->grid, b->guide, b->sliced);
    dev->backend->denoise_finish(dev, b);
    /* every buffer is written again before it is read at the next execute
     * (the grid comes back as zeros, as a fresh block): with the device's
     * release_scratch, all but the output go before it is copied out, and
     * it after, so neither sits under the do-no-harm stage's statistics nor
     * the caller's output view (untouched until now when fresh) under them */
    const size_t n3 = (size_t)b->width * (size_t)b->height * 3;
    ew_dev_release_pages(dev, (void *)b->color, b->out);
    ew_dev_release_pages(dev, b->out + n3, (char *)s->dmem.mem + s->dmem.bytes);
    r = ew_dev_get_view(dev, b->out, 3, ew_op_image(op, "output"), s->stage);
    ew_dev_release_pages(dev, b->out, b->out + n3);
    return r;
}

const ew_op_type ew_denoise_bgrid = {
    .kind = "denoiser",
    .name = "bgrid",
    .summary = "bilateral grid guided by a hand-made guide: the mean of the normalised albedo, normal and depth "
               "(the colour's luminance when no features are given)",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .memory = memory,
    .device_memory = 1, /* runs on CUDA */
    .pixel_params = (const char *const[]){"spatial_rate", "prepass_rate", NULL},
    .inplace_inputs = (const char *const[]){"color", NULL},
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_denoise_bgrid, 20);
