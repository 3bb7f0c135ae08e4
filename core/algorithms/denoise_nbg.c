/*
 * denoise_nbg.c — denoiser "nbg": the neural bilateral grid of Meng et al.
 * 2020. A small CNN (GuideNet) predicts from the noisy colour and the
 * albedo/normal/depth features one guide per bilateral grid and, with three
 * grids, per-pixel blend weights; the albedo-demodulated HDR radiance is
 * splatted into each grid along its guide, sliced back, blended and
 * remodulated. Demodulation, firefly clamp, splat, slice and remodulation
 * are the "bgrid" method's own steps (kernels/denoise_px.h, outlier.h,
 * bgrid.h); only the guides and the blend are learned.
 *
 * Weights: the "model" parameter picks a model built into the library;
 * ew_denoiser_set_data(d, "weights", bytes, size) loads any weights file
 * instead (it takes precedence over "model" until unset with NULL).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/bgrid.h"
#include "algorithms/nbg.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "src/backend.h"
#include "src/op.h"
#include "src/op_model.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "noisy colour (RGB, linear)"},
    {"albedo", 3, 1, "albedo (Cycles: Denoising Albedo): demodulation and a GuideNet input"},
    {"normal", 3, 1, "normal in [-1, 1] (Cycles: Denoising Normal): a GuideNet input"},
    {"depth", 1, 1, "depth (Cycles: Denoising Depth or Depth): a GuideNet input"},
    {"output", 3, 1, "denoised colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"model", EW_PARAM_INT, 0.0f, 0.0f, (float)(EW_NBG_NUM_MODELS - 1),
     "built-in model: 2layer-3grid (real time, trained on 1-64 spp; the default), 2layer-1grid (fastest), "
     "7layer-3grid (offline), 2layer-3grid-1spp (trained on 1 spp: best for 1-2 spp); ignored while weights "
     "are set with set_data"},
    {"firefly_k", EW_PARAM_FLOAT, 3.0f, 0.0f, 100.0f,
     "clamp pixels brighter than the 5x5 mean + k standard deviations before filtering; 0 turns it off "
     "(the shipped models were trained with 3)"},
};

/* The network's weights (src/op_model.h). */
static int from_weights(void *net, const ew_weights *w, float **out, char *err, size_t errlen) {
    return ew_guidenet_from_weights((ew_guidenet *)net, w, out, err, errlen);
}

static const ew_net_kind kind = {"nbg", sizeof(ew_guidenet), from_weights, ew_nbg_builtin_weights,
                                 ew_nbg_model_name};

static const ew_guidenet *net_of(const ew_net_model *m) { return (const ew_guidenet *)m->net; }

static ew_result set_data(ew_op *op, const char *name, const void *data, size_t size) {
    return ew_net_model_set_data(op, &kind, name, data, size);
}

typedef struct {
    ew_net_model *builtin;          /* host: the built-in model parsed at commit, or NULL */
    const ew_net_model *m;          /* the model in use */
    ew_bgrid_params grids[EW_GN_MAX_GRIDS];
    ew_denoise_buffers buf;  /* device buffers */
    float *params, *clamped, *outputs, *band, *grid;
    int band_rows;
    double *row_out;         /* device: reduce_rows output, 2 x height */
    ew_dev_kept dmem; /* the one device allocation, kept across commits of its size */
    double *rows;            /* host: row_out read back */
    float *stage;            /* host staging, or NULL when views need none */
    char choice[96];         /* ew_denoiser_describe: the model in use */
    double host[];
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) {
        ew_dev_free(op->dev, s->dmem.mem);
        ew_net_model_free(s->builtin);
    }
    free(s);
    op->state = NULL;
}

/* ew_op_type.memory: the commit's allocations (row sums as doubles on the
 * host and the device, host staging when views need it). */
static uint64_t memory(const ew_op *op, int w, int h) {
    ew_net_model *builtin = NULL;
    const ew_net_model *m = NULL;
    if (ew_net_model_of(op, &kind, &m, &builtin) != EW_OK) return 0;
    size_t grid_floats, band_floats;
    const uint64_t bytes =
        (uint64_t)ew_nbg_device_floats(net_of(m), w, h, &grid_floats, &band_floats) * sizeof(float) +
        (uint64_t)h * 4 * sizeof(double) +
        (uint64_t)ew_dev_stage_floats(op->dev, (size_t)w * (size_t)h, 3) * sizeof(float);
    ew_net_model_free(builtin);
    return bytes;
}

static ew_result commit(ew_op *op) {
    ew_device *dev = op->dev;
    const ew_image *color = ew_op_image(op, "color");
    const int w = color->width, h = color->height;

    ew_net_model *builtin = NULL;
    const ew_net_model *m = NULL;
    ew_result mr = ew_net_model_of(op, &kind, &m, &builtin);
    if (mr != EW_OK) return mr;
    const ew_guidenet *net = net_of(m);
    ew_bgrid_params gp[EW_GN_MAX_GRIDS];
    for (int g = 0; g < net->ngrids; g++) {
        if (!ew_bgrid_params_init(&gp[g], w, h, net->rate_s[g], net->rate_d[g], 3)) {
            ew_net_model_free(builtin);
            return ew__fail(dev, EW_ERR_INVALID_DATA, "nbg model '%s': grid %d has invalid rates", net->arch, g);
        }
    }
    const int band_rows = ew_nbg_band_rows(net, h);
    const size_t n = (size_t)w * (size_t)h;
    size_t band_floats, grid_floats;
    /* device: row sums (doubles first, for alignment), then (nbg.h) the
     * parameters, packed colour/albedo/normal (3 each) and depth, radiance,
     * clamped radiance, blend sum (sliced), one grid's slice (out, then the
     * result), GuideNet outputs (the hand-made guide that denoise_prepare
     * also writes lands in the first output plane, overwritten by GuideNet),
     * the band, the grid. */
    const size_t need = ew_nbg_device_floats(net, w, h, &grid_floats, &band_floats);
    const size_t row_bytes = (size_t)h * 2 * sizeof(double);
    const size_t stage_floats = ew_dev_stage_floats(dev, n, 3);
    const ew_dev_kept old = ew_dev_kept_take(op->state ? &((state *)op->state)->dmem : NULL);
    release(op);
    state *s = (state *)calloc(1, sizeof(state) + row_bytes + stage_floats * sizeof(float));
    op->state = s;
    if (!ew_dev_keep(dev, s ? &s->dmem : NULL, old, row_bytes + need * sizeof(float))) {
        ew_net_model_free(builtin);
        if (s) s->builtin = NULL;
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of %s memory: nbg on %dx%d needs %.1f MiB",
                        s ? dev->backend->name : "host", w, h, (double)(need * sizeof(float) + row_bytes) / 1048576.0);
    }
    s->builtin = builtin;
    s->m = m;
    if (builtin)
        snprintf(s->choice, sizeof s->choice, "nbg %s", ew_nbg_model_name((int)ew_op_param(op, "model")));
    else
        snprintf(s->choice, sizeof s->choice, "nbg weights %s", net_of(m)->arch);
    s->rows = s->host;
    s->stage = stage_floats ? (float *)(void *)(s->host + (size_t)h * 2) : NULL;
    s->row_out = (double *)s->dmem.mem;
    float *p = (float *)(void *)((char *)s->dmem.mem + row_bytes);
    s->params = p; p += net->nparams;
    ew_denoise_buffers *b = &s->buf;
    memset(b, 0, sizeof *b);
    b->width = w;
    b->height = h;
    b->color = p; p += n * 3;
    b->albedo = p; p += n * 3;
    b->normal = p; p += n * 3;
    b->depth = p; p += n;
    b->radiance = p; p += n * 3;
    s->clamped = p; p += n * 3;
    b->sliced = p; p += n * 3;
    b->out = p; p += n * 3;
    s->outputs = p; p += n * (size_t)net->nout;
    b->guide = s->outputs;
    s->band = p; p += band_floats;
    s->grid = p;
    s->band_rows = band_rows;
    memcpy(s->grids, gp, sizeof gp);
    ew_result r = dev->backend->mem_upload(dev, s->params, m->params, net->nparams * sizeof(float));
    return r;
}

typedef struct {
    ew_op *op;
    double from, span;
} progress_ctx;

static int band_progress(void *user, double f) {
    progress_ctx *c = (progress_ctx *)user;
    return ew_op_report(c->op, c->from + c->span * f);
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const ew_guidenet *net = net_of(s->m);
    const long n = (long)b->width * b->height;
    ew_result r = ew_dev_put_view(dev, ew_op_image(op, "color"), 3, (float *)b->color, s->stage);
    if (r == EW_OK) r = ew_dev_put_view(dev, ew_op_image(op, "albedo"), 3, (float *)b->albedo, s->stage);
    if (r == EW_OK) r = ew_dev_put_view(dev, ew_op_image(op, "normal"), 3, (float *)b->normal, s->stage);
    if (r == EW_OK) r = ew_dev_put_view(dev, ew_op_image(op, "depth"), 1, (float *)b->depth, s->stage);
    if (r != EW_OK) return r;
    /* depth normalisation as in "bgrid": the largest depth below 1e9
     * (reduce.h), computed per row on the device */
    dev->backend->reduce_rows(dev, EW_REDUCE_DEPTH_MAX, b->width, b->height, b->depth, s->row_out);
    r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)b->height * 2 * sizeof(double));
    if (r != EW_OK) return r;
    double mx = 0.0;
    for (int y = 0; y < b->height; y++)
        if (s->rows[2 * y] > mx) mx = s->rows[2 * y];
    b->depth_scale = mx > 0.0 ? (float)(1.0 / mx) : 1.0f;

    dev->backend->denoise_prepare(dev, b); /* radiance = colour / (albedo + eps) */
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
    if (!ew_op_report(op, 0.05)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");

    ew_nbg_forward f;
    f.net = net;
    f.params = s->params;
    f.width = b->width;
    f.height = b->height;
    f.color = b->color;
    f.albedo = b->albedo;
    f.normal = b->normal;
    f.depth = b->depth;
    f.depth_scale = b->depth_scale;
    f.band_mem = s->band;
    f.band_rows = s->band_rows;
    f.outputs = s->outputs;
    progress_ctx pc = {op, 0.05, 0.6};
    r = ew_nbg_guidenet_forward(dev, &f, band_progress, &pc);
    if (r != EW_OK) return r;
    dev->backend->nbg_guides(dev, n, net->ngrids, s->outputs);

    for (int g = 0; g < net->ngrids; g++) {
        const float *guide = s->outputs + (long)g * n;
        ew_bgrid_splat(dev, &s->grids[g], radiance, guide, s->grid);
        ew_bgrid_slice(dev, &s->grids[g], s->grid, guide, b->out);
        ew_nbg_blend_args ba = {n, g, net->ngrids, s->outputs, b->out, b->sliced};
        dev->backend->nbg_blend(dev, &ba);
        if (!ew_op_report(op, 0.65 + 0.3 * (g + 1) / net->ngrids)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    dev->backend->denoise_finish(dev, b); /* out = blend * (albedo + eps) */
    return ew_dev_get_view(dev, b->out, 3, ew_op_image(op, "output"), s->stage);
}

/* Designated: fields added to ew_op_type later start as 0. device_memory:
 * every buffer comes from ew_dev_alloc and only the views cross between
 * host and device, so it may run on a CUDA device, whose table
 * has the conv5 / gn_input / nbg_* kernels. */
static const char *describe(const ew_op *op) {
    const state *s = (const state *)op->state;
    return s ? s->choice : NULL;
}

const ew_op_type ew_denoise_nbg = {
    .kind = "denoiser",
    .name = "nbg",
    .summary = "neural bilateral grid (Meng et al. 2020): a small CNN predicts the guides of 1 or 3 bilateral "
               "grids and their blend from the colour, albedo, normal and depth",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .memory = memory,
    .set_data = set_data,
    .release_data = ew_net_model_release,
    .device_memory = 1,
    .describe = describe,
    .choices = (const ew_param_choices[]){{"model", ew_nbg_model_names}, {NULL, NULL}},
    .inplace_inputs = (const char *const[]){"color", NULL},
    .data_params = (const char *const[]){"model", "weights", NULL},
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_denoise_nbg, 30);
