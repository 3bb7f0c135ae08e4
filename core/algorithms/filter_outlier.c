/*
 * filter "outlier": firefly / outlier suppression with albedo and normal
 * similarity (kernels/outlier.h, ew_outlier_guided_px). A pixel far brighter
 * than the neighbours of its own surface is scaled down to their bound;
 * NaN/Inf samples are rebuilt from them. Meant before a spatial denoiser or
 * filter on low-sample renders (issue 9; measured in docs/temporal.md).
 */
#include <stdlib.h>

#include "kernels/color.h"
#include "kernels/outlier.h"
#include "src/op.h"

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
};

typedef struct {
    int w, h, has_albedo, has_normal;
    float *color, *albedo, *normal, *out;
    float mem[];
} state;

typedef struct {
    ew_outlier_params p;
    ew_outlier_buffers b;
} job;

static void rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const job *j = (const job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p.width; x++) ew_outlier_guided_px(x, (int)y, &j->p, &j->b);
}

static void release(ew_op *op) {
    free(op->state);
    op->state = NULL;
}

static ew_result commit(ew_op *op) {
    const ew_image *c = ew_op_image(op, "color");
    const int w = c->width, h = c->height;
    const int has_a = ew_op_image(op, "albedo") != NULL, has_n = ew_op_image(op, "normal") != NULL;
    state *s = (state *)op->state;
    if (s && s->w == w && s->h == h && s->has_albedo == has_a && s->has_normal == has_n) return EW_OK;
    release(op);
    const size_t n = (size_t)w * (size_t)h;
    const size_t floats = n * 3 * (2 + (size_t)has_a + (size_t)has_n);
    s = (state *)malloc(sizeof(state) + floats * sizeof(float));
    op->state = s;
    if (!s)
        return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory: outlier filter of %dx%d needs %.1f MiB", w, h,
                        (double)floats * sizeof(float) / 1048576.0);
    s->w = w;
    s->h = h;
    s->has_albedo = has_a;
    s->has_normal = has_n;
    float *m = s->mem;
    s->color = m; m += n * 3;
    s->out = m; m += n * 3;
    s->albedo = has_a ? m : NULL; m += has_a ? n * 3 : 0;
    s->normal = has_n ? m : NULL;
    return EW_OK;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_view_pack(ew_op_image(op, "color"), 3, s->color);
    if (s->albedo) ew_view_pack(ew_op_image(op, "albedo"), 3, s->albedo);
    if (s->normal) ew_view_pack(ew_op_image(op, "normal"), 3, s->normal);
    job j;
    j.p.width = s->w;
    j.p.height = s->h;
    j.p.radius = (int)ew_op_param(op, "radius");
    j.p.k = ew_op_param(op, "k");
    j.p.albedo_tol = ew_op_param(op, "albedo_tol");
    j.p.normal_cos = ew_op_param(op, "normal_cos");
    j.p.sigma_floor = ew_op_param(op, "sigma_floor");
    j.b.color = s->color;
    j.b.albedo = s->albedo;
    j.b.normal = s->normal;
    j.b.out = s->out;
    ew_pool_run(op->dev->pool, s->h, 0, rows, &j);
    const ew_image *cv = ew_op_image(op, "color"), *ov = ew_op_image(op, "output");
    ew_view_unpack(s->out, 3, ov);
    /* channels past RGB (alpha) pass through: a 4-channel output must not
     * keep whatever its memory held */
    const int extra = (ov->channels < cv->channels ? ov->channels : cv->channels) - 3;
    for (int y = 0; extra > 0 && y < s->h; y++)
        for (int x = 0; x < s->w; x++) {
            const float *c = ew__pixel(cv, x, y);
            float *o = ew__pixel(ov, x, y);
            for (int k = 3; k < 3 + extra; k++) o[k] = c[k];
        }
    return EW_OK;
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
    .device_memory = 0, /* CPU devices only: the per-pixel function is ready for a CUDA entry */
};
