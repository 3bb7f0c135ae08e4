/*
 * denoise_auto.c — denoiser "auto": no more model than the frame needs.
 *
 * It reads the frame's noise level — the sample count when the caller knows
 * it (Cycles writes it into the EXR header), else a noise estimate of the
 * colour (algorithms/noise.c) — and which feature passes exist, and runs
 * the cheapest method that measured within a few tenths of a dB of the best
 * at that level:
 *
 *   level (spp)   with albedo + normal + depth   otherwise: bgrid (spatial, range, prepass rate;
 *                                                colour weight)
 *   0 (1-2)       nbg 2layer-3grid-1spp          coarse grid (8, 8, 8; 0.7)
 *   1 (3-8)       nbg 2layer-3grid               medium grid (4, 8, 4; 0.7)
 *   2 (9-32)      bgrid fine grid                fine grid   (2, 8, 4; 0.9)
 *   3 (33-)       bgrid finest grid              finest grid (2, 4, 4; 0.9)
 *
 * The "quality" parameter says how far up the ladder it may climb: fast is
 * the table above; balanced, the default, and high run the kernel-predicting
 * network kpcn-large (32 channels, four scales, a learned remodulation) at
 * every level, where its 24-channel predecessor measured 0.6-2.6 dB better
 * than the fast rungs for about 3x their time (the rows below; the 32
 * channels gain 0.08-0.38 dB more on the test scenes for 1.3x that,
 * BENCHMARKS.md); high runs it on the frame mirrored four ways and
 * averages (HIGH_PASSES).
 * Without albedo, normal and depth every quality is the grid. The choice
 * reads the level, not the frame's content: even an oracle picking between
 * kpcn-large and the fast rung per frame would gain at most 0.09 dB on the
 * held-out scenes, per 32x32 tile 0.1-0.3 dB, for a second rung's run
 * (docs/kpcn.md, "Choosing the rung from the frame itself").
 *
 * Measured on the validation scenes of ../shared/data/cycles-train (the
 * split of models/nbg/README.md; BENCHMARKS.md has the held-out figures):
 * the learned guides win by 1.6 dB over the best grid at 1 spp and 1.0 dB
 * at 4 spp; at 16 spp the fine grid matches nbg (+0.2 dB) at under a third
 * of its time, and at 64 spp the finest grid beats nbg by 2.5 dB: strong
 * smoothing destroys detail a converged frame already has. The grid
 * settings per level were swept on the training scenes (bgrid has no
 * weights, so they are fair for it). The last two rows were swept again
 * on the training and validation scenes (2026-12-01, 15 scenes): a guide
 * leaning more on the first-pass colour (0.9 instead of the op's 0.7)
 * gained +0.36 dB at 16 spp and +0.51 dB at 64 spp with the features
 * (+0.0 / +0.0 without): at these levels the first pass is clean enough to
 * say where the detail the albedo lacks is (reflections, blur). Finer
 * cells at 64 spp (1.5, 4, 3) gained 0.23 dB more for 3.5x the time: not
 * taken, by the rule above. When this build has no NBG weights the grid column
 * is used at every level.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/kpcn.h"
#include "algorithms/nbg.h"
#include "algorithms/noise.h"
#include "src/backend.h"
#include "src/op.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "noisy colour (RGB, linear)"},
    {"albedo", 3, 0, "albedo (Cycles: Denoising Albedo)"},
    {"normal", 3, 0, "normal in [-1, 1] (Cycles: Denoising Normal)"},
    {"depth", 1, 0, "depth (Cycles: Denoising Depth or Depth)"},
    {"output", 3, 1, "denoised colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"samples", EW_PARAM_INT, 0.0f, 0.0f, 16777216.0f, "samples per pixel of the render (0: unknown, estimate the noise)"},
    {"quality", EW_PARAM_INT, 1.0f, 0.0f, 2.0f,
     "how far up the ladder auto may climb: fast (grids and nbg only), balanced (the default: kpcn-large at every "
     "sample count, 0.6-2.6 dB better than fast on the held-out scenes for about 3x the time) and high "
     "(kpcn-large averaged over 4 mirrored passes: about +0.1 dB over balanced for 4x the network's time, but more "
     "frame-to-frame flicker at 4 spp on animated test scenes); kpcn needs albedo, normal and depth"},
    {"max_memory_mb", EW_PARAM_INT, 0.0f, 0.0f, 1048576.0f,
     "memory the method auto picks may allocate, in MiB (that method's max_memory_mb: a frame above it runs in "
     "tiles or bands of rows, with the same output); 0: the method's own default (kpcn 768, nbg 192, bgrid 192)"},
};

static const char *const quality_names[] = {"fast", "balanced", "high", NULL};
#define QUALITY_FAST 0
#define QUALITY_BALANCED 1
#define QUALITY_HIGH 2

#define NBG_1SPP 3 /* nbg's built-in models (algorithms/nbg.h) */
#define NBG_ALL_SPP 0

/* One row per level of the table above. */
typedef struct {
    int kpcn_balanced; /* kpcn's built-in model at quality balanced with all features, or -1: the row below */
    int kpcn_high;     /* the same at quality high */
    int nbg_model;    /* nbg's built-in model with all features, or -1 for the grid */
    const char *grid; /* the bgrid settings otherwise */
    float spatial, range, prepass, color_weight;
} level_choice;

#define KPCN_24 2 /* kpcn's built-in model kpcn-large (algorithms/kpcn.h) */
/* At quality high kpcn runs on the frame mirrored four ways and averages
 * (its "passes"): on the 12 training scenes of ../shared/data/cycles-train
 * +0.15 / +0.15 / +0.17 dB at 1 / 4 / 16 spp over one pass, every scene at
 * or above it at 4 spp, for 4x the network's time (models/kpcn/README.md,
 * "A self-ensemble"). Balanced stays one pass. */
#define HIGH_PASSES 4
static int kpcn_passes(int quality) { return quality == QUALITY_HIGH ? HIGH_PASSES : 1; }

/* Where kpcn takes over, by quality (docs/kpcn.md, models/kpcn/README.md).
 * kpcn-large with its learned remodulation, on the 42 held-out scenes below
 * (edgewise bench, do-no-harm stage on), against quality fast at 1 / 4 / 16 /
 * 64 spp: +2.55 / +2.33 / +1.35 / +0.61 dB (below fast on 7 / 0 / 1 / 7
 * scenes, by up to 1.3 dB) for 2.7-3.2x the time: balanced climbs at every
 * level now, 1-2 spp included. Before it, the four-scale kpcn-large on 42 held-out scenes (render cache val split
 * and held-out training scenes; edgewise bench, do-no-harm stage on),
 * against quality fast: +0.21 dB at 1 spp (below it on 15 scenes, by up to
 * 3.0 dB) for 2.7x the time, +0.70 dB at 64 spp (below on 7, by up to 1.3 dB;
 * its worst scene 0.41 dB under the noisy input against fast's 2.79) for 2.8x.
 * So balanced climbs at 64 spp too, not at 1-2 spp. Before it, the
 * three-scale model on 28 held-out scenes (the render cache's val split and held-out training
 * scenes), against the fast rungs, at 1 / 4 / 16 / 64 spp: kpcn (16
 * channels) -0.4 / +0.3 / +0.4 / +0.0 dB, kpcn-large +0.0 / +0.6 / +0.9 /
 * +0.5 dB. Balanced climbs where kpcn-large wins clearly, high wherever it
 * is at least level. kpcn (16 channels) is not used: kpcn-large is 0.3-0.5
 * dB better at every level for 1.9x the multiply-adds, and kpcn alone fell
 * below the noisy input on a depth-of-field frame at 4 spp (the stability
 * suite) and below the fast rungs on glass; kpcn-small did not beat the fast
 * rungs at all. */
static const level_choice levels[] = {
    {KPCN_24, KPCN_24, NBG_1SPP, "coarse", 8.0f, 8.0f, 8.0f, 0.7f},
    {KPCN_24, KPCN_24, NBG_ALL_SPP, "medium", 4.0f, 8.0f, 4.0f, 0.7f},
    {KPCN_24, KPCN_24, -1, "fine", 2.0f, 8.0f, 4.0f, 0.9f},
    {KPCN_24, KPCN_24, -1, "finest", 2.0f, 4.0f, 4.0f, 0.9f},
};

/* Noise-estimate thresholds between the levels: the geometric means of the
 * estimate's medians per sample count over the training scenes, 0.048
 * (1 spp), 0.020 (4), 0.0117 (16) and 0.0065 (64). Scenes overlap a lot
 * (64-spp glossy frames read like 4-spp diffuse ones: the estimate sees
 * detail the albedo lacks as noise), so a known sample count is always
 * preferred. */
static int level_of(int samples, float noise) {
    if (samples > 0) return samples <= 2 ? 0 : samples <= 8 ? 1 : samples <= 32 ? 2 : 3;
    return noise > 0.031f ? 0 : noise > 0.0153f ? 1 : noise > 0.0087f ? 2 : 3;
}

/* The noise estimate of the frame's colour (and albedo). It reads pixels on
 * the host: views that are device pointers (ew_device_desc.device_images)
 * are packed on the device and downloaded first; this happens at commit,
 * where an op may allocate. Returns a negative value when that fails. */
static float frame_noise(ew_op *op) {
    const ew_image *c = ew_op_image(op, "color"), *a = ew_op_image(op, "albedo");
    ew_device *dev = op->dev;
    if (!dev->device_images) return ew_estimate_noise(c, a);
    const size_t n = (size_t)c->width * (size_t)c->height, planes = a ? 2 : 1;
    float *d = (float *)ew_dev_alloc(dev, n * 3 * planes * sizeof(float));
    float *h = (float *)malloc(n * 3 * planes * sizeof(float));
    ew_result r = d && h ? EW_OK : EW_ERR_OUT_OF_MEMORY;
    if (r == EW_OK) r = ew_dev_put_view(dev, c, 3, d, NULL);
    if (r == EW_OK && a) r = ew_dev_put_view(dev, a, 3, d + n * 3, NULL);
    if (r == EW_OK) r = dev->backend->mem_download(dev, h, d, n * 3 * planes * sizeof(float));
    float noise = -1.0f;
    if (r == EW_OK) {
        ew_image hc = ew_image_packed(h, c->width, c->height, 3), ha = ew_image_packed(h + n * 3, c->width, c->height, 3);
        noise = ew_estimate_noise(&hc, a ? &ha : NULL);
    }
    ew_dev_free(dev, d);
    free(h);
    return noise;
}

typedef struct {
    ew_op *inner;
    char choice[160];
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) ew_op_destroy(s->inner);
    free(s);
    op->state = NULL;
}

/* The rung's memory budget: auto's own when set, else the rung's default
 * (put back, since a reused inner op keeps what the last frame set). A
 * rung without the parameter ignores it. */
static void forward_budget(const ew_op *op, ew_op *inner) {
    const float mb = ew_op_param(op, "max_memory_mb");
    for (int i = 0; i < ew_op_type_num_params(inner->type); i++) {
        const ew_param_desc *p = ew_op_type_param(inner->type, i);
        if (!strcmp(p->name, "max_memory_mb")) ew_op_param_put(inner, p->name, mb > 0.0f ? mb : p->default_value);
    }
}

/* Make s->inner an op of method `name` with the frame's images: the last
 * commit's when it is that method (a graph commits every frame, and the op
 * keeps its buffers when the size is the same; its parameters are set again
 * by every caller), else a fresh one. */
static ew_result bind(ew_op *op, state *s, const char *name) {
    ew_result r = EW_OK;
    if (!s->inner || strcmp(s->inner->type->name, name) != 0) {
        ew_op_destroy(s->inner);
        s->inner = NULL;
        r = ew_op_create_kind(op->dev, "denoiser", name, &s->inner);
    }
    if (r == EW_OK) {
        ew_harm_forward(op, s->inner); /* the method runs the do-no-harm stage */
        forward_budget(op, s->inner);
    }
    for (int i = 0; r == EW_OK && i < op->type->num_images; i++)
        r = ew_op_set_image(s->inner, images[i].name, ew_op_image(op, images[i].name));
    return r;
}

static ew_result commit_grid(ew_op *op, state *s, const level_choice *g) {
    ew_result r = bind(op, s, "bgrid");
    if (r == EW_OK) r = ew_op_set_param(s->inner, "spatial_rate", g->spatial, 0);
    if (r == EW_OK) r = ew_op_set_param(s->inner, "range_rate", g->range, 0);
    if (r == EW_OK) r = ew_op_set_param(s->inner, "prepass_rate", g->prepass, 0);
    if (r == EW_OK) r = ew_op_set_param(s->inner, "color_weight", g->color_weight, 0);
    if (r == EW_OK) r = ew_op_commit(s->inner);
    return r;
}

/* The estimate of one rung: method `name` with one int parameter set
 * (NULL: the grid of level g), and kpcn's passes when `passes` > 0. */
static uint64_t rung_memory(const ew_op *op, const char *name, const char *param, int value, int passes,
                            const level_choice *g, int w, int h) {
    ew_op *in = NULL;
    if (ew_op_create_kind(op->dev, "denoiser", name, &in) != EW_OK) return 0;
    if (param) ew_op_set_param(in, param, (float)value, 1);
    if (passes > 0) ew_op_set_param(in, "passes", (float)passes, 1);
    if (g) {
        ew_op_set_param(in, "spatial_rate", g->spatial, 0);
        ew_op_set_param(in, "range_rate", g->range, 0);
        ew_op_set_param(in, "prepass_rate", g->prepass, 0);
        ew_op_set_param(in, "color_weight", g->color_weight, 0);
    }
    ew_harm_forward(op, in); /* the stage runs in the rung, with auto's settings */
    forward_budget(op, in);
    uint64_t bytes = 0;
    if (ew_op_memory(in, w, h, &bytes) != EW_OK) bytes = 0;
    ew_op_destroy(in);
    return bytes;
}

/* ew_op_type.memory: the most that any rung auto may pick for such a frame
 * needs (the sample count's level when one is set, else every level; kpcn,
 * nbg and the grid alike, since which runs depends on the features and the
 * weights a build has), each by its own estimate. */
static uint64_t memory(const ew_op *op, int w, int h) {
    const int samples = (int)ew_op_param(op, "samples"), quality = (int)ew_op_param(op, "quality");
    const int lo = samples > 0 ? level_of(samples, 0.0f) : 0, hi = samples > 0 ? lo : 3;
    uint64_t most = 0, b;
    for (int l = lo; l <= hi; l++) {
        const level_choice *lv = &levels[l];
        const int kmodel = quality == QUALITY_HIGH ? lv->kpcn_high : quality == QUALITY_BALANCED ? lv->kpcn_balanced : -1;
        if (kmodel >= 0 && (b = rung_memory(op, "kpcn", "model", kmodel, kpcn_passes(quality), NULL, w, h)) > most)
            most = b;
        if (lv->nbg_model >= 0 && (b = rung_memory(op, "nbg", "model", lv->nbg_model, 0, NULL, w, h)) > most)
            most = b;
        if ((b = rung_memory(op, "bgrid", NULL, 0, 0, lv, w, h)) > most) most = b;
    }
    return most;
}

static ew_result commit(ew_op *op) {
    state *s = (state *)op->state;
    if (!s) {
        s = (state *)calloc(1, sizeof *s);
        if (!s) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
        op->state = s;
    }
    const int samples = (int)ew_op_param(op, "samples");
    const float noise = samples > 0 ? 0.0f : frame_noise(op);
    if (noise < 0.0f)
        return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "auto: cannot read the colour back for its noise estimate");
    const level_choice *lv = &levels[level_of(samples, noise)];
    char why[64];
    if (samples > 0)
        snprintf(why, sizeof why, "%d spp", samples);
    else
        snprintf(why, sizeof why, "noise estimate %.4f", (double)noise);

    const int features = ew_op_image(op, "albedo") && ew_op_image(op, "normal") && ew_op_image(op, "depth");
    const int quality = (int)ew_op_param(op, "quality");
    const int kmodel = !features ? -1 : quality == QUALITY_HIGH ? lv->kpcn_high
                                      : quality == QUALITY_BALANCED ? lv->kpcn_balanced : -1;
    if (kmodel >= 0) {
        ew_result r = bind(op, s, "kpcn");
        const int passes = kpcn_passes(quality);
        if (r == EW_OK) r = ew_op_set_param(s->inner, "model", (float)kmodel, 1);
        if (r == EW_OK) r = ew_op_set_param(s->inner, "passes", (float)passes, 1);
        if (r == EW_OK) r = ew_op_commit(s->inner);
        if (r == EW_OK) {
            const int len = snprintf(s->choice, sizeof s->choice, "kpcn %s (%s, quality %s)",
                                     ew_kpcn_model_name(kmodel), why, quality == QUALITY_HIGH ? "high" : "balanced");
            if (passes > 1 && len > 0 && (size_t)len < sizeof s->choice)
                snprintf(s->choice + len, sizeof s->choice - (size_t)len, ", %d mirrored passes", passes);
            return EW_OK;
        }
        if (r != EW_ERR_UNSUPPORTED) return r;
        /* this build has no weights for that model: the rungs below */
    }
    const int model = features ? lv->nbg_model : -1;
    if (model >= 0) {
        ew_result r = bind(op, s, "nbg");
        if (r == EW_OK) r = ew_op_set_param(s->inner, "model", (float)model, 1);
        if (r == EW_OK) r = ew_op_commit(s->inner);
        if (r == EW_OK) {
            snprintf(s->choice, sizeof s->choice, "nbg %s (%s)", ew_nbg_model_name(model), why);
            return EW_OK;
        }
        if (r != EW_ERR_UNSUPPORTED) return r;
        /* this build has no weights for that model: the hand-made guide */
    }
    ew_result r = commit_grid(op, s, lv);
    if (r == EW_OK)
        snprintf(s->choice, sizeof s->choice, "bgrid %s grid %g/%g (%s)", lv->grid, (double)lv->spatial,
                 (double)lv->range, why);
    return r;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    s->inner->progress = op->progress;
    s->inner->progress_user = op->progress_user;
    return ew_op_execute(s->inner);
}

static const char *describe(const ew_op *op) {
    const state *s = (const state *)op->state;
    return s ? s->choice : NULL;
}

/* ew_op_image_flags: as the method it picked reads the image */
static int reads_half(const ew_op *op, const char *image) {
    const state *s = (const state *)op->state;
    uint32_t fl = 0;
    return s && s->inner && ew_op_image_flags(s->inner, image, &fl) == EW_OK && (fl & EW_IMAGE_HALF_IN_PLACE);
}

const ew_op_type ew_denoise_auto = {
    .kind = "denoiser",
    .name = "auto",
    .summary = "picks the cheapest method that reaches the best quality for the frame's noise level (sample "
               "count, or a noise estimate), its passes and the quality setting: with albedo/normal/depth "
               "kpcn-large (quality balanced, the default, and high; nbg and the grids at quality fast), else a "
               "bilateral grid as fine as the frame allows",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .memory = memory,
    .describe = describe,
    .stage_in_inner = 1,
    /* it runs whatever its inner op runs on (bgrid and nbg are ported),
     * and reads the views only through the device (frame_noise) */
    .device_memory = 1,
    .inplace_inputs = (const char *const[]){"color", NULL},
    /* the noise estimate reads them as they are; the method it runs gets
     * the views (kpcn reads halves in bands, the others pack floats) */
    .half_inputs = (const char *const[]){"albedo", "normal", "depth", NULL},
    .reads_half = reads_half,
    .choices = (const ew_param_choices[]){{"quality", quality_names}, {NULL, NULL}},
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_denoise_auto, 10);
