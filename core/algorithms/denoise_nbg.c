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
#include "src/tile_writer.h"
#include "src/op_model.h"
#include "src/tiling.h"

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
    {"max_memory_mb", EW_PARAM_INT, 192.0f, 1.0f, 1048576.0f,
     "memory the op may allocate, in MiB (as OIDN's maxMemoryMB): a frame whose buffers would exceed it runs in "
     "tiles with a halo of what a pixel's grid cells and guides read (96 pixels for the 3-grid models, 24 for "
     "2layer-1grid), giving the same output; the frame's colour (12 bytes a pixel; 40 when the features are not "
     "packed float views it can read in place) and a 256x256 tile come first, so a small budget can be exceeded"},
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
    const float *fcolor, *falbedo, *fnormal, *fdepth; /* device: the frame's packed inputs */
    const float *color;             /* the colour an execute reads: the view in place, else fcolor */
    ew_tiling planned;              /* the commit's tiles, for need floats past the row sums */
    size_t need;
    ew_tiling tiling;               /* this execute's: planned, or smaller (plan_execute) */
    float *regions;                 /* device: where the region's buffers start */
    ew_denoise_buffers buf;  /* device: one region's buffers (the frame's inputs when untiled) */
    float *params, *clamped, *outputs, *removed, *band, *grid;
    /* a colour the output overlaps, read where it is by tiles (inplace):
     * what later tiles read of a core waits before it goes out (tw.strip
     * NULL: the commit could not have that) */
    int inplace;
    ew_tile_writer tw;
    double *row_out;         /* device: reduce_rows output, 2 x height */
    ew_dev_kept dmem; /* the one device allocation, kept across commits of its size */
    double *rows;            /* host: row_out read back */
    float *stage;            /* host staging, or NULL when views need none */
    char choice[96];         /* ew_denoiser_describe: the model in use, then the tiles */
    size_t choice_len;       /* ... the model's part */
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

#define MIN_CORE 256

/* The features the op reads from the caller's views where they are
 * (ew_dev_view_in_place: on the CPU, views already packed as the op packs
 * them), else NULL; the output is written while tiles still read them. */
static void features_in_place(const ew_op *op, const float *in[3]) {
    const ew_image *o = ew_op_image(op, "output");
    in[0] = ew_dev_view_in_place(op->dev, ew_op_image(op, "albedo"), 3, o);
    in[1] = ew_dev_view_in_place(op->dev, ew_op_image(op, "normal"), 3, o);
    in[2] = ew_dev_view_in_place(op->dev, ew_op_image(op, "depth"), 1, o);
}

/* Floats a pixel of the frame's packed inputs the op holds itself: the
 * colour (the do-no-harm stage may hand it another view at execute), and
 * the features not read in place. */
static size_t frame_floats_px(const ew_op *op) {
    const float *in[3];
    features_in_place(op, in);
    return 3 + (in[0] ? 0 : 3) + (in[1] ? 0 : 3) + (in[2] ? 0 : 1);
}

/* Whether tiles may read a colour the output overlaps where it is
 * (execute: inplace), and so the commit holds a tile writer's buffers */
static int colour_in_place_possible(const ew_op *op) {
    const ew_image *c = ew_op_image(op, "color"), *o = ew_op_image(op, "output");
    return ew_images_overlap(c, o) && ew_dev_view_in_place(op->dev, c, 3, NULL) != NULL;
}

static size_t region_cost(const void *net, int rw, int rh) {
    return ew_nbg_region_floats((const ew_guidenet *)net, rw, rh, 1);
}

/* The tiles of a w x h frame under max_memory_mb less `held` floats (the
 * do-no-harm stage's, plan_execute), and the device floats of the commit:
 * parameters, the frame's packed colour, albedo, normal and depth, then
 * one region's buffers (nbg.h), and strip and pend for a colour the output
 * overlaps. A model without an exact tiling runs whole. */
static size_t plan(const ew_op *op, const ew_guidenet *net, int w, int h, size_t held, ew_tiling *t) {
    const size_t max = (size_t)ew_op_param(op, "max_memory_mb") * (1048576 / sizeof(float));
    const size_t budget = max > held ? max - held : 0;
    size_t frame = net->nparams + (size_t)w * (size_t)h * frame_floats_px(op);
    const int align = ew_nbg_align(net);
    const size_t whole = frame + ew_nbg_region_floats(net, w, h, 0);
    if (!align || whole <= budget) {
        memset(t, 0, sizeof *t);
        t->width = t->tw = t->rw = w;
        t->height = t->th = t->rh = h;
        t->nx = t->ny = 1;
        t->align = 1;
        return whole;
    }
    if (colour_in_place_possible(op)) frame += ew_tile_writer_floats(w, h, ew_nbg_halo(net)); /* tiled */
    /* below a 256-pixel core the halos would more than double the work */
    const int least = MIN_CORE + 2 * ew_nbg_halo(net);
    const size_t floor = ew_nbg_region_floats(net, least, least, 1);
    ew_tiling_plan(w, h, ew_nbg_halo(net), align, budget > frame + floor ? budget - frame : floor, region_cost, net, t);
    if (t->nx * t->ny == 1) return whole;
    return frame + ew_nbg_region_floats(net, t->rw, t->rh, 1);
}

/* ew_op_type.memory: the commit's allocations (row sums as doubles on the
 * host and the device, host staging when views need it). */
static uint64_t memory(const ew_op *op, int w, int h) {
    ew_net_model *builtin = NULL;
    const ew_net_model *m = NULL;
    if (ew_net_model_of(op, &kind, &m, &builtin) != EW_OK) return 0;
    ew_tiling t;
    const uint64_t bytes = (uint64_t)plan(op, net_of(m), w, h, 0, &t) * sizeof(float) + (uint64_t)h * 4 * sizeof(double) +
                           (uint64_t)ew_dev_stage_floats(op->dev, (size_t)w * (size_t)h, 3) * sizeof(float);
    ew_net_model_free(builtin);
    return bytes;
}

static void lay_out(ew_op *op, const ew_tiling *t);

static ew_result commit(ew_op *op) {
    ew_device *dev = op->dev;
    const ew_image *color = ew_op_image(op, "color");
    const int w = color->width, h = color->height;

    ew_net_model *builtin = NULL;
    const ew_net_model *m = NULL;
    ew_result mr = ew_net_model_of(op, &kind, &m, &builtin);
    if (mr != EW_OK) return mr;
    const ew_guidenet *net = net_of(m);
    for (int g = 0; g < net->ngrids; g++) {
        ew_bgrid_params gp;
        if (!ew_bgrid_params_init(&gp, w, h, net->rate_s[g], net->rate_d[g], 3)) {
            ew_net_model_free(builtin);
            return ew__fail(dev, EW_ERR_INVALID_DATA, "nbg model '%s': grid %d has invalid rates", net->arch, g);
        }
    }
    const size_t n = (size_t)w * (size_t)h;
    ew_tiling tiling;
    const size_t need = plan(op, net, w, h, 0, &tiling);
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
    s->planned = tiling;
    s->need = need;
    if (builtin)
        snprintf(s->choice, sizeof s->choice, "nbg %s", ew_nbg_model_name((int)ew_op_param(op, "model")));
    else
        snprintf(s->choice, sizeof s->choice, "nbg weights %s", net_of(m)->arch);
    s->choice_len = strlen(s->choice);
    s->rows = s->host;
    s->stage = stage_floats ? (float *)(void *)(s->host + (size_t)h * 2) : NULL;
    s->row_out = (double *)s->dmem.mem;
    /* device: row sums (doubles first, for alignment), then the
     * parameters, the frame's packed colour/albedo/normal (3 each) and
     * depth, then the region's (lay_out) */
    float *p = (float *)(void *)((char *)s->dmem.mem + row_bytes);
    s->params = p; p += net->nparams;
    const float *in[3];
    features_in_place(op, in);
    const float *fc = p; p += n * 3;
    const float *fa = in[0] ? in[0] : p; p += in[0] ? 0 : n * 3;
    const float *fn = in[1] ? in[1] : p; p += in[1] ? 0 : n * 3;
    const float *fd = in[2] ? in[2] : p; p += in[2] ? 0 : n;
    s->fcolor = fc;
    s->falbedo = fa;
    s->fnormal = fn;
    s->fdepth = fd;
    s->regions = p;
    lay_out(op, &tiling);
    return dev->backend->mem_upload(dev, s->params, m->params, net->nparams * sizeof(float));
}

/* The region's buffers (nbg.h) for tiles t, from s->regions: radiance,
 * clamped radiance, blend sum (sliced), one grid's slice (out, then the
 * result), the clamp's removed light when tiled, GuideNet outputs (the
 * hand-made guide that denoise_prepare also writes lands in the first
 * output plane, overwritten by GuideNet), the band, strip and pend for a
 * colour the output overlaps, the grid. Smaller tiles take less of the
 * commit's memory, from its start: the pages past that are not touched. */
static void lay_out(ew_op *op, const ew_tiling *t) {
    state *s = (state *)op->state;
    const ew_guidenet *net = net_of(s->m);
    const ew_tiling tiling = *t;
    const int w = tiling.width, h = tiling.height, tiled = tiling.nx * tiling.ny > 1;
    s->tiling = tiling;
    s->choice[s->choice_len] = '\0';
    if (tiled) snprintf(s->choice + s->choice_len, sizeof s->choice - s->choice_len, ", %dx%d tiles", tiling.nx, tiling.ny);
    float *p = s->regions;
    const size_t rn = (size_t)tiling.rw * (size_t)tiling.rh;
    ew_denoise_buffers *b = &s->buf;
    memset(b, 0, sizeof *b);
    b->width = w;
    b->height = h;
    b->color = s->fcolor; /* a tile reads its region of the frame's inputs where it lies (run_tile) */
    b->albedo = s->falbedo;
    b->normal = s->fnormal;
    b->depth = s->fdepth;
    b->radiance = p; p += rn * 3;
    s->clamped = p; p += rn * 3;
    b->sliced = p; p += rn * 3;
    b->out = p; p += rn * 3;
    s->removed = NULL;
    if (tiled) {
        s->removed = p;
        p += rn;
    }
    s->outputs = p; p += rn * (size_t)net->nout;
    b->guide = s->outputs;
    s->band = p; p += ew_nbg_band_floats(net, tiling.rw, ew_nbg_band_rows(net, tiling.rh));
    s->tw.strip = s->tw.pend = NULL;
    if (tiled && colour_in_place_possible(op) && ew_tile_writer_fits(&tiling, tiling.halo)) {
        s->tw.keep = tiling.halo; /* what a region reads of its neighbours' cores */
        s->tw.strip = p; p += (size_t)h * tiling.halo * 3;
        s->tw.pend = p; p += 2 * (size_t)w * tiling.halo * 3;
    }
    s->grid = p;
}

/* This execute's tiles: the commit's, or smaller ones while the do-no-harm
 * stage holds a frame of its own through the method (the pilot's estimate,
 * on the host), so that the two stay within max_memory_mb together where
 * the commit's memory has room for that plan. The same bits in any tiles
 * (tiling.h). */
static void plan_execute(ew_op *op) {
    state *s = (state *)op->state;
    const size_t held = ew_harm_held_bytes(op) / sizeof(float);
    ew_tiling t = s->planned;
    if (held) {
        ew_tiling u;
        if (plan(op, net_of(s->m), t.width, t.height, held, &u) <= s->need) t = u;
    }
    if (memcmp(&t, &s->tiling, sizeof t) != 0) lay_out(op, &t);
}

typedef struct {
    ew_op *op;
    double from, span;
} progress_ctx;

static int band_progress(void *user, double f) {
    progress_ctx *c = (progress_ctx *)user;
    return ew_op_report(c->op, c->from + c->span * f);
}

/* The output view's pixels [x, x + w) x [y, y + h) */
static ew_image out_crop(const ew_op *op, int x, int y, int w, int h) {
    return ew__image_crop(ew_op_image(op, "output"), x, y, w, h);
}

/* The frame's pixels [x, x + w) x [y, y + h) from tile t's output into the
 * output view, packed first where the radiance was (read by nothing now) */
static ew_result out_rect(ew_op *op, const ew_tile *t, int x, int y, int w, int h) {
    state *s = (state *)op->state;
    if (w <= 0 || h <= 0) return EW_OK;
    ew_result r = ew_dev_copy_rect(op->dev, s->buf.radiance, w, 0, 0, s->buf.out, t->rw, x - t->rx, y - t->ry, w, h, 3);
    const ew_image v = out_crop(op, x, y, w, h);
    return r == EW_OK ? ew_dev_get_view(op->dev, s->buf.radiance, 3, &v, s->stage) : r;
}

/* The whole method on one tile's region (the frame when untiled): its
 * inputs are in s->buf; the core goes to the output view. Progress from p0
 * over the span dp. */
static ew_result run_tile(ew_op *op, const ew_tile *t, double p0, double dp) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const ew_guidenet *net = net_of(s->m);
    const int W = s->tiling.width, tiled = s->tiling.nx * s->tiling.ny > 1;
    const long n = (long)t->rw * t->rh;
    ew_result r = EW_OK;
    b->width = t->rw;
    b->height = t->rh;
    /* the region's inputs where they lie in the frame's, W pixels a row */
    const long at = (long)t->ry * W + t->rx;
    b->in_stride = tiled ? W : 0;
    b->color = s->color + at * 3;
    b->albedo = s->falbedo + at * 3;
    b->normal = s->fnormal + at * 3;
    b->depth = s->fdepth + at;
    dev->backend->denoise_prepare(dev, b); /* radiance = colour / (albedo + eps) */
    const float k = ew_op_param(op, "firefly_k");
    const float *radiance = b->radiance;
    float *removed = ew_harm_clamp_removed(op);
    if (k > 0.0f) {
        /* the shared outlier definition (kernels/outlier.h) with the
         * statistics this clamp always had: mean and standard deviation */
        const ew_outlier_params fp = ew_outlier_plain_params(t->rw, t->rh, 2, k);
        const ew_outlier_buffers fb = {b->radiance, NULL, NULL, s->clamped, 3, tiled && removed ? s->removed : removed};
        dev->backend->outlier_guided(dev, &fp, &fb);
        radiance = s->clamped;
    }
    if (!ew_op_report(op, p0 + 0.05 * dp)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");

    ew_nbg_forward f;
    f.net = net;
    f.params = s->params;
    f.width = t->rw;
    f.height = t->rh;
    f.color = b->color;
    f.albedo = b->albedo;
    f.normal = b->normal;
    f.depth = b->depth;
    f.in_stride = b->in_stride;
    f.depth_scale = b->depth_scale;
    f.band_mem = s->band;
    f.band_rows = ew_nbg_band_rows(net, t->rh);
    f.outputs = s->outputs;
    progress_ctx pc = {op, p0 + 0.05 * dp, 0.6 * dp};
    r = ew_nbg_guidenet_forward(dev, &f, band_progress, &pc);
    if (r != EW_OK) return r;
    dev->backend->nbg_guides(dev, n, net->ngrids, s->outputs);

    for (int g = 0; g < net->ngrids; g++) {
        ew_bgrid_params gp;
        ew_bgrid_params_init(&gp, t->rw, t->rh, net->rate_s[g], net->rate_d[g], 3); /* checked at commit */
        const float *guide = s->outputs + (long)g * n;
        ew_bgrid_splat(dev, &gp, radiance, guide, s->grid);
        ew_bgrid_slice(dev, &gp, s->grid, guide, b->out);
        ew_nbg_blend_args ba = {n, g, net->ngrids, s->outputs, b->out, b->sliced};
        dev->backend->nbg_blend(dev, &ba);
        if (!ew_op_report(op, p0 + (0.65 + 0.3 * (g + 1) / net->ngrids) * dp))
            return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    dev->backend->denoise_finish(dev, b); /* out = blend * (albedo + eps) */
    /* what the clamp took of the region (a tile's own buffer), where the
     * stage reads it */
    float *give = k > 0.0f && removed ? (tiled ? s->removed : removed) : NULL;
    if (ew_harm_fused(op)) {
        /* the stage's blend of the core and what its window reads around
         * it, packed where the slices, the radiance and the clamped
         * radiance were (read by nothing now): the clamped colour, the
         * output and the clamp's share; then the core back */
        const int m = ew_harm_region_margin(op), ox = t->cx - t->rx, oy = t->cy - t->ry;
        const int x0 = ew_maxi(ox - m, 0), y0 = ew_maxi(oy - m, 0);
        const int x1 = ew_mini(ox + t->cw + m, t->rw), y1 = ew_mini(oy + t->ch + m, t->rh);
        const int sw = x1 - x0, sh = y1 - y0;
        float *in = b->sliced, *out = b->radiance, *share = give ? s->clamped : NULL;
        r = ew_dev_copy_rect(dev, in, sw, 0, 0, s->color, W, t->rx + x0, t->ry + y0, sw, sh, 3);
        if (r == EW_OK) r = ew_dev_copy_rect(dev, out, sw, 0, 0, b->out, t->rw, x0, y0, sw, sh, 3);
        if (r == EW_OK && share) r = ew_dev_copy_rect(dev, share, sw, 0, 0, give, t->rw, x0, y0, sw, sh, 1);
        if (r == EW_OK) r = ew_harm_region_done(op, t->rx + x0, t->ry + y0, sw, sh, in, out, share);
        if (r == EW_OK) r = ew_dev_copy_rect(dev, b->out, t->rw, ox, oy, out, sw, ox - x0, oy - y0, t->cw, t->ch, 3);
        if (r == EW_OK && share) r = ew_dev_copy_rect(dev, give, t->rw, ox, oy, share, sw, ox - x0, oy - y0, t->cw, t->ch, 1);
        if (r != EW_OK) return r;
    }
    if (tiled && give) {
        r = ew_dev_copy_rect_sparse(dev, removed, W, t->cx, t->cy, give, t->rw, t->cx - t->rx, t->cy - t->ry, t->cw, t->ch);
        if (r != EW_OK) return r;
    }
    const ew_image *o = ew_op_image(op, "output");
    if (!tiled) return ew_dev_get_view(dev, b->out, 3, o, s->stage);
    if (s->inplace) return ew_tile_writer_core(&s->tw, &s->tiling, t, b->out, b->radiance);
    /* the core into the output view's core */
    return out_rect(op, t, t->cx, t->cy, t->cw, t->ch);
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    plan_execute(op);
    const int W = s->tiling.width, H = s->tiling.height;
    const ew_image *av = ew_op_image(op, "albedo"), *nv = ew_op_image(op, "normal"), *dv = ew_op_image(op, "depth");
    /* the colour is read where it is when that is packed RGB (on the CPU;
     * the do-no-harm stage hands its clamped colour so, or clamps the
     * caller's in place when it runs in the tiles): fcolor's pages are then
     * never touched */
    const ew_image *cv = ew_op_image(op, "color");
    const int ntiles = s->tiling.nx * s->tiling.ny;
    s->color = ew_dev_view_in_place(dev, cv, 3, ew_op_image(op, "output"));
    s->inplace = 0;
    s->tw.dev = dev;
    s->tw.out = ew_op_image(op, "output");
    s->tw.stage = s->stage;
    s->tw.held.cw = 0;
    if (!s->color && (ntiles == 1 || s->tw.strip)) {
        /* a colour the output overlaps: whole, the output goes out after
         * the last read; in tiles, what later tiles read waits (inplace) */
        s->color = ew_dev_view_in_place(dev, cv, 3, NULL);
        s->inplace = s->color && ntiles > 1;
    }
    ew_result r = EW_OK;
    if (!s->color) {
        s->color = s->fcolor;
        r = ew_dev_put_view(dev, cv, 3, (float *)s->fcolor, s->stage);
    }
    if (r == EW_OK && s->falbedo != av->data) r = ew_dev_put_view(dev, av, 3, (float *)s->falbedo, s->stage);
    if (r == EW_OK && s->fnormal != nv->data) r = ew_dev_put_view(dev, nv, 3, (float *)s->fnormal, s->stage);
    if (r == EW_OK && s->fdepth != dv->data) r = ew_dev_put_view(dev, dv, 1, (float *)s->fdepth, s->stage);
    if (r != EW_OK) return r;
    /* depth normalisation as in "bgrid": the largest depth below 1e9
     * (reduce.h) of the whole frame, computed per row on the device */
    dev->backend->reduce_rows(dev, EW_REDUCE_DEPTH_MAX, W, H, s->fdepth, s->row_out);
    r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)H * 2 * sizeof(double));
    if (r != EW_OK) return r;
    double mx = 0.0;
    for (int y = 0; y < H; y++)
        if (s->rows[2 * y] > mx) mx = s->rows[2 * y];
    b->depth_scale = mx > 0.0 ? (float)(1.0 / mx) : 1.0f;
    for (int i = 0; i < ntiles && r == EW_OK; i++) {
        ew_tile t;
        ew_tile_at(&s->tiling, i, &t);
        r = run_tile(op, &t, (double)i / ntiles, 1.0 / ntiles);
    }
    /* the frame's inputs and the regions' buffers are written again before
     * they are read at the next execute (the parameters before them stay):
     * the do-no-harm stage's statistics need not sit on top of them */
    ew_dev_release_pages(dev, (void *)s->fcolor, (char *)s->dmem.mem + s->dmem.bytes);
    return r;
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
    .stage_in_tiles = 1,
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
