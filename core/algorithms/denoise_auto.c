/*
 * denoise_auto.c — denoiser "auto": no more filtering than the frame needs.
 * It picks the bgrid settings for the frame's noise level: from the sample
 * count when the caller knows it (Cycles writes it into the EXR header),
 * else from a noise estimate of the colour (algorithms/noise.c). The tiers
 * and their thresholds were measured on the training scenes of
 * ../shared/data/cycles-train (see BENCHMARKS.md): strong smoothing at 1 spp
 * loses 4 dB at 64 spp, where a fine grid still gains 2 dB.
 */
#include <stdlib.h>
#include <string.h>

#include "algorithms/noise.h"
#include "src/op.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "noisy colour (RGB, linear)"},
    {"albedo", 3, 0, "albedo (Cycles: Denoising Albedo)"},
    {"normal", 3, 0, "normal in [-1, 1] (Cycles: Denoising Normal)"},
    {"depth", 1, 0, "depth (Cycles: Denoising Depth or Depth)"},
    {"output", 3, 1, "denoised colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"samples", EW_PARAM_INT, 0.0f, 0.0f, 1e7f, "samples per pixel of the render (0: unknown, estimate the noise)"},
};

typedef struct { float spatial, range, prepass; } tier;

/* Measured best settings per noise level (training scenes, mean PSNR gain). */
static const tier tiers[] = {
    {8.0f, 8.0f, 8.0f}, /* ~1 spp */
    {4.0f, 8.0f, 4.0f}, /* ~4 spp */
    {2.0f, 4.0f, 4.0f}, /* 16 spp and more */
};

static int pick_tier(int samples, const ew_image *color, const ew_image *albedo) {
    if (samples > 0) return samples <= 2 ? 0 : samples <= 8 ? 1 : 2;
    float n = ew_estimate_noise(color, albedo);
    return n > 0.04f ? 0 : n > 0.015f ? 1 : 2;
}

typedef struct {
    ew_op *inner;
    int tier;
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) ew_op_destroy(s->inner);
    free(s);
    op->state = NULL;
}

static ew_result commit(ew_op *op) {
    state *s = (state *)op->state;
    if (!s) {
        s = (state *)calloc(1, sizeof *s);
        if (!s) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
        op->state = s;
        ew_result r = ew_op_create(op->dev, "denoiser", "bgrid", &s->inner);
        if (r != EW_OK) return r;
    }
    s->tier = pick_tier((int)ew_op_param(op, "samples"), ew_op_image(op, "color"), ew_op_image(op, "albedo"));
    const tier *t = &tiers[s->tier];
    ew_result r = EW_OK;
    for (int i = 0; r == EW_OK && i < op->type->num_images; i++)
        r = ew_op_set_image(s->inner, images[i].name, ew_op_image(op, images[i].name));
    if (r == EW_OK) r = ew_op_set_param(s->inner, "spatial_rate", t->spatial, 0);
    if (r == EW_OK) r = ew_op_set_param(s->inner, "range_rate", t->range, 0);
    if (r == EW_OK) r = ew_op_set_param(s->inner, "prepass_rate", t->prepass, 0);
    if (r == EW_OK) r = ew_op_commit(s->inner);
    return r;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    s->inner->progress = op->progress;
    s->inner->progress_user = op->progress_user;
    return ew_op_execute(s->inner);
}

const ew_op_type ew_denoise_auto = {
    .kind = "denoiser",
    .name = "auto",
    .summary = "picks the bilateral-grid settings for the frame's noise level (sample count, or a noise "
               "estimate): no more smoothing than the frame needs",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
};
