/*
 * denoise_bgrid.c — denoiser "bgrid": albedo demodulation, a hand-made guide
 * (mean of normalised features, the baseline of Meng et al. 2020 Fig. 7, or
 * the colour's luminance without features), one bilateral grid, splat,
 * slice, remodulation.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/bgrid.h"
#include "kernels/denoise_px.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "src/backend.h"
#include "src/op.h"
#include "src/tile_writer.h"

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
    {"max_memory_mb", EW_PARAM_INT, 192.0f, 1.0f, 1048576.0f,
     "memory the op may allocate, in MiB (as OIDN's maxMemoryMB): a frame whose buffers and grid would exceed it "
     "runs in bands of rows with a halo of what a pixel's grid cells read (2 x rate rows for each grid, the "
     "first pass's and the second's, 2 for the firefly clamp, and the do-no-harm stage's blend margin where it runs "
     "in the bands), giving the same output; the first pass then runs twice (once for the frame's mean luminance). "
     "Inputs that overlap the output are copied whole first (12 bytes a pixel for the colour; not the colour "
     "the stage clamps in place on the CPU, read where it is), and a band of 16 rows comes first, so a small "
     "budget can be exceeded. 192: under 5x the float RGB frame at 3840x2160 for the same time as 256"},
};

/*
 * Bands: above max_memory_mb the frame runs in bands of whole rows, each
 * computed on a region of halo more rows either side (ew_bgrid_reach of
 * each grid and the clamp's radius); the grids of a band hold the cells its
 * rows read, with positions in the frame's coordinates (kernels/bgrid.h),
 * so a core row is the same bits as in one pass. What needs the whole
 * frame comes from rows: the depth scale is the largest of the core rows'
 * maxima, the first pass's mean luminance the sum of their row sums in the
 * frame's order (a first sweep over the bands); whole rows keep every row
 * sum the frame's own.
 *
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
    /* bands (1: the whole frame, the buffers above frame-sized) */
    ew_tiling bands;            /* this execute's (plan_execute): one column of tiles, ny bands */
    int planned_bands;          /* the commit's */
    const float *frame_in[4];   /* colour, albedo, normal, depth read from a frame: the view in place or frame_own */
    float *frame_own[4];        /* a frame copy the op packs at execute (an input the output overlaps) */
    float *band_in[4];          /* a region's packed input, for those not read from a frame */
    float *removed;             /* a region's light removed by the clamp */
    /* the do-no-harm stage in the bands (ew_harm_fused): the colour the
     * output overlaps read where it is (inplace), what the next band reads
     * of a core going out after it (tw.pend NULL: the commit could not
     * have that, and the colour is copied whole) */
    int inplace;
    ew_tile_writer tw;
    char choice[64];
    double host[];          /* rows, then stage */
} state;

static const char *const input_names[4] = {"color", "albedo", "normal", "depth"};
static const int input_channels[4] = {3, 3, 3, 1};

#define MIN_BAND_CORE 16 /* rows: below it the halos would be nearly all the work */

/* What a core row reads around it: the grids' reach and the clamp's, and
 * where the do-no-harm stage may run in the bands, the rows its blend of
 * the core reads beyond it (whose output must be exact too) */
static int band_halo(const ew_op *op) {
    return ew_bgrid_reach(ew_op_param(op, "spatial_rate")) +
           (ew_op_param(op, "color_weight") > 0.0f ? ew_bgrid_reach(ew_op_param(op, "prepass_rate")) : 0) +
           (ew_op_param(op, "firefly_k") > 0.0f ? 2 : 0) + (ew_harm_may_fuse(op) ? ew_harm_region_margin_most(op) : 0);
}

/* A w x h frame in bands of `core` rows (the last the rest), each read
 * over a region `halo` rows beyond its core: tiles of the frame's width
 * (ew_tile_at gives band i's core cy, ch and region ry, rh) */
static ew_tiling bands_tiling(int w, int h, int core, int halo) {
    ew_tiling t;
    memset(&t, 0, sizeof t);
    t.width = t.tw = t.rw = w;
    t.height = h;
    t.th = core;
    t.halo = halo;
    t.align = 1;
    t.nx = 1;
    t.ny = (h + core - 1) / core;
    t.rh = core + 2 * halo < h ? core + 2 * halo : h;
    return t;
}

static ew_tile band_at(const ew_tiling *t, int i) {
    ew_tile b;
    ew_tile_at(t, i, &b);
    return b;
}

/* Where each input comes from when the frame runs in bands: read in place
 * (frame_in), copied whole (own: an input the output overlaps, which the
 * cores written would change under later regions), or packed a region at a
 * time (neither). The colour is decided again at execute: the do-no-harm
 * stage may hand its clamped colour then (src/harm_stage.c), so a region's
 * buffer is kept for it whatever the caller's view. */
static void band_inputs(const ew_op *op, const float *in[4], int own[4]) {
    const ew_image *o = ew_op_image(op, "output");
    for (int i = 0; i < 4; i++) {
        const ew_image *v = ew_op_image(op, input_names[i]);
        in[i] = v ? ew_dev_view_in_place(op->dev, v, input_channels[i], o) : NULL;
        own[i] = v && !in[i] && ew_images_overlap(v, o);
    }
}

/* Device floats of `bands` bands of a w x h frame (bands > 1): the frame
 * copies, a region's buffers (the inputs packed per region, radiance,
 * guide, sliced, out, clamped, the removed light), the tile writer's where
 * the stage may run in the bands, and the largest band grid of the two
 * passes. */
static size_t band_floats(const ew_op *op, int w, int h, int bands, int halo, const ew_bgrid_params *gp,
                          const ew_bgrid_params *pre) {
    const float *in[4];
    int own[4];
    band_inputs(op, in, own);
    const int core = (h + bands - 1) / bands;
    size_t frame = 0, px = 14; /* radiance, guide, sliced, out, clamped, removed: 3 + 1 + 3 + 3 + 3 + 1 */
    for (int i = 0; i < 4; i++) {
        if (!ew_op_image(op, input_names[i])) continue;
        if (own[i]) frame += (size_t)w * (size_t)h * (size_t)input_channels[i];
        else if (!in[i] || i == 0) px += (size_t)input_channels[i];
    }
    if (ew_harm_may_fuse(op)) frame += ew_tile_writer_floats(w, h, halo);
    size_t grid = 0;
    int rows = 0;
    const ew_tiling t = bands_tiling(w, h, core, halo);
    for (int i = 0; i < t.ny; i++) {
        const ew_tile b = band_at(&t, i);
        ew_bgrid_params g;
        ew_bgrid_params_band(gp, b.ry, b.rh, &g);
        if (ew_bgrid_floats(&g) > grid) grid = ew_bgrid_floats(&g);
        ew_bgrid_params_band(pre, b.ry, b.rh, &g);
        if (ew_bgrid_floats(&g) > grid) grid = ew_bgrid_floats(&g);
        if (b.rh > rows) rows = b.rh;
    }
    return frame + px * (size_t)w * (size_t)rows + grid;
}

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

/* The bands of a w x h frame under max_memory_mb less `held` floats (the
 * do-no-harm stage's, plan_execute) and the device floats of the commit
 * (0: invalid grid parameters): one band when the whole frame's buffers
 * fit, else the fewest bands that fit (bands of MIN_BAND_CORE rows when
 * none do). */
static size_t plan(const ew_op *op, int w, int h, int has_a, int has_n, int has_d, size_t held, ew_bgrid_params *gp,
                   ew_bgrid_params *pre, int *bands, int *halo) {
    const size_t whole = device_floats(op, w, h, has_a, has_n, has_d, gp, pre);
    const size_t max = (size_t)ew_op_param(op, "max_memory_mb") * (1048576 / sizeof(float));
    const size_t budget = max > held ? max - held : 0;
    *bands = 1;
    *halo = band_halo(op);
    if (!whole || whole <= budget || h <= MIN_BAND_CORE) return whole;
    const int most = (h + MIN_BAND_CORE - 1) / MIN_BAND_CORE;
    int best = most;
    for (int nb = 2; nb < most; nb++) {
        /* bands of equal cores, the last the rest: skip counts whose last band would be empty */
        const int core = (h + nb - 1) / nb;
        if ((nb - 1) * core >= h) continue;
        if (band_floats(op, w, h, nb, *halo, gp, pre) <= budget) {
            best = nb;
            break;
        }
    }
    const int core = (h + best - 1) / best;
    *bands = (h + core - 1) / core;
    const size_t need = band_floats(op, w, h, *bands, *halo, gp, pre);
    if (need >= whole) *bands = 1;
    return *bands == 1 ? whole : need;
}

/* Host staging floats: a region's (or the frame's when inputs are copied
 * whole or the frame runs in one band). */
static size_t stage_floats(const ew_op *op, int w, int h, int bands, int halo) {
    const float *in[4];
    int own[4];
    band_inputs(op, in, own);
    int rows = h;
    if (bands > 1 && !own[0] && !own[1] && !own[2] && !own[3])
        rows = bands_tiling(w, h, (h + bands - 1) / bands, halo).rh;
    return ew_dev_stage_floats(op->dev, (size_t)w * (size_t)rows, 3);
}

/* ew_op_type.memory: the commit's allocations with every feature given
 * (the row sums are doubles, first, for alignment). */
static uint64_t memory(const ew_op *op, int w, int h) {
    ew_bgrid_params gp, pre;
    int bands, halo;
    const size_t need = plan(op, w, h, 1, 1, 1, 0, &gp, &pre, &bands, &halo);
    if (!need) return 0;
    return (uint64_t)need * sizeof(float) + (uint64_t)h * 4 * sizeof(double) +
           (uint64_t)stage_floats(op, w, h, bands, halo) * sizeof(float);
}

static ew_result commit(ew_op *op) {
    ew_device *dev = op->dev;
    const ew_image *color = ew_op_image(op, "color");
    const int w = color->width, h = color->height;
    const int has_a = ew_op_image(op, "albedo") != NULL, has_n = ew_op_image(op, "normal") != NULL,
              has_d = ew_op_image(op, "depth") != NULL;
    ew_bgrid_params gp, pre;
    int bands, halo;
    const size_t need = plan(op, w, h, has_a, has_n, has_d, 0, &gp, &pre, &bands, &halo);
    if (!need) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "invalid grid parameters");
    const size_t n = (size_t)w * (size_t)h;
    const size_t row_bytes = (size_t)h * 2 * sizeof(double);
    const size_t stage = stage_floats(op, w, h, bands, halo);
    const ew_dev_kept old = ew_dev_kept_take(op->state ? &((state *)op->state)->dmem : NULL);
    release(op);
    state *s = (state *)calloc(1, sizeof(state) + row_bytes + stage * sizeof(float));
    op->state = s;
    if (!ew_dev_keep(dev, s ? &s->dmem : NULL, old, row_bytes + need * sizeof(float)))
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of %s memory: denoising %dx%d needs %.1f MiB",
                        s ? dev->backend->name : "host", w, h, (double)need * sizeof(float) / 1048576.0);
    s->rows = s->host;
    s->stage = stage ? (float *)(void *)(s->host + (size_t)h * 2) : NULL;
    s->row_out = (double *)s->dmem.mem;
    float *m = (float *)(void *)((char *)s->dmem.mem + row_bytes);
    ew_denoise_buffers *b = &s->buf;
    memset(b, 0, sizeof *b);
    b->width = w;
    b->height = h;
    s->grid_params = gp;
    s->prepass_params = pre;
    s->planned_bands = bands;
    s->bands = bands_tiling(w, h, (h + bands - 1) / bands, halo);
    if (bands > 1) {
        snprintf(s->choice, sizeof s->choice, "bgrid, %d bands", bands);
        const float *in[4];
        int own[4];
        band_inputs(op, in, own);
        int rows = 0;
        for (int i = 0; i < s->bands.ny; i++) {
            const ew_tile bb = band_at(&s->bands, i);
            if (bb.rh > rows) rows = bb.rh;
        }
        const size_t rn = (size_t)w * (size_t)rows;
        for (int i = 0; i < 4; i++) {
            if (!ew_op_image(op, input_names[i])) continue;
            if (own[i]) {
                s->frame_own[i] = m;
                s->frame_in[i] = m;
                m += n * (size_t)input_channels[i];
            } else {
                s->frame_in[i] = in[i];
            }
        }
        for (int i = 0; i < 4; i++)
            if (ew_op_image(op, input_names[i]) && !s->frame_own[i] && (!s->frame_in[i] || i == 0)) {
                s->band_in[i] = m;
                m += rn * (size_t)input_channels[i];
            }
        b->radiance = m; m += rn * 3;
        b->guide = m; m += rn;
        b->sliced = m; m += rn * 3;
        b->out = m; m += rn * 3;
        s->clamped = m; m += rn * 3;
        s->removed = m; m += rn;
        if (ew_harm_may_fuse(op) && ew_tile_writer_fits(&s->bands, halo)) {
            s->tw.keep = halo; /* what a band reads of the core before it */
            s->tw.strip = m; m += (size_t)h * halo * 3; /* (bands span the width: never written) */
            s->tw.pend = m; m += 2 * (size_t)w * halo * 3;
        }
        s->grid = m;
        return EW_OK;
    }
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

/* Rows y .. y + n - 1 of a view. */
static ew_image view_rows(const ew_image *v, int y, int n) { return ew__image_crop(v, 0, y, v->width, n); }

/* Input i's rows of region bb, packed: in the frame it is read from, or
 * packed into the region's buffer. */
static ew_result band_input(ew_op *op, int i, const ew_tile *bb, const float **dst) {
    state *s = (state *)op->state;
    const int w = s->buf.width, c = input_channels[i];
    if (s->frame_in[i]) {
        *dst = s->frame_in[i] + (size_t)bb->ry * (size_t)w * (size_t)c;
        return EW_OK;
    }
    const ew_image v = view_rows(ew_op_image(op, input_names[i]), bb->ry, bb->rh);
    *dst = s->band_in[i];
    return ew_dev_put_view(op->dev, &v, c, s->band_in[i], s->stage);
}

/* The band's core rows of the light the clamp took into the stage's frame
 * plane `removed` (sparse: a quiet frame's clamp takes a few pixels) */
static ew_result core_removed_out(ew_op *op, const ew_tile *bb, float *removed) {
    const state *s = (const state *)op->state;
    const size_t w = (size_t)s->buf.width;
    return ew_dev_copy_sparse(op->dev, removed + (size_t)bb->cy * w, s->removed + (size_t)(bb->cy - bb->ry) * w,
                              (size_t)bb->ch * w);
}

/* The region of band bb up to the grids: its inputs, radiance and guide,
 * and the firefly clamp (the removed light of its core into the stage's
 * frame when `removed`, but in the band's buffer only while the stage runs
 * in the bands, which rewrites it first); *radiance is what the grids
 * splat. */
static ew_result band_prepare(ew_op *op, const ew_tile *bb, float *removed, const float **radiance) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const float **in[4] = {&b->color, &b->albedo, &b->normal, &b->depth};
    ew_result r = EW_OK;
    for (int i = 0; i < 4 && r == EW_OK; i++)
        if (ew_op_image(op, input_names[i])) r = band_input(op, i, bb, in[i]);
    if (r != EW_OK) return r;
    b->height = bb->rh;
    dev->backend->denoise_prepare(dev, b);
    *radiance = b->radiance;
    const float k = ew_op_param(op, "firefly_k");
    if (k > 0.0f) {
        const ew_outlier_params fp = ew_outlier_plain_params(b->width, bb->rh, 2, k);
        const ew_outlier_buffers fb = {b->radiance, NULL, NULL, s->clamped, 3, removed ? s->removed : NULL};
        dev->backend->outlier_guided(dev, &fp, &fb);
        *radiance = s->clamped;
        if (removed && !ew_harm_fused(op)) r = core_removed_out(op, bb, removed);
    }
    return r;
}

/* The first pass on band bb's region, into b->sliced. */
static void band_first_pass(ew_op *op, const ew_tile *bb, const float *radiance) {
    state *s = (state *)op->state;
    ew_bgrid_params g;
    ew_bgrid_params_band(&s->prepass_params, bb->ry, bb->rh, &g);
    ew_bgrid_splat(op->dev, &g, radiance, s->buf.guide, s->grid);
    ew_bgrid_slice(op->dev, &g, s->grid, s->buf.guide, s->buf.sliced);
}

/* This execute's bands: the commit's, or more while the do-no-harm stage
 * holds a frame of its own through the method (the pilot's estimate, on
 * the host), so that the two stay within max_memory_mb together. A smaller
 * region takes less of each buffer, from its start (the pages past that
 * are not touched); more bands keep the colour in place where the commit's
 * did (cores no shorter than the halo). The same bits in any bands. */
static void plan_execute(ew_op *op) {
    state *s = (state *)op->state;
    const int w = s->buf.width, h = s->grid_params.height, halo = s->bands.halo;
    s->bands = bands_tiling(w, h, (h + s->planned_bands - 1) / s->planned_bands, halo);
    const size_t held = ew_harm_held_bytes(op) / sizeof(float);
    if (held) {
        ew_bgrid_params gp, pre;
        int bands, halo_at;
        plan(op, w, h, ew_op_image(op, "albedo") != NULL, ew_op_image(op, "normal") != NULL,
             ew_op_image(op, "depth") != NULL, held, &gp, &pre, &bands, &halo_at);
        const int core = (h + bands - 1) / bands;
        if (bands > s->bands.ny && (!s->tw.pend || core >= halo)) s->bands = bands_tiling(w, h, core, halo);
    }
    snprintf(s->choice, sizeof s->choice, "bgrid, %d bands", s->bands.ny);
}

static ew_result execute_bands(ew_op *op) {
    state *s = (state *)op->state;
    plan_execute(op);
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const int w = b->width, h = s->grid_params.height;
    const size_t w3 = (size_t)w * 3;
    ew_result r = EW_OK;
    /* the colour of this execute (the stage's clamped colour, or the
     * caller's; the stage in the bands: the caller's holds the clamped
     * colour, read where it is while what later bands read of a core waits) */
    const ew_image *cv = ew_op_image(op, "color");
    s->frame_in[0] = ew_dev_view_in_place(dev, cv, 3, ew_op_image(op, "output"));
    s->inplace = 0;
    const ew_tiling *tiling = &s->bands;
    s->tw.dev = dev;
    s->tw.out = ew_op_image(op, "output");
    s->tw.stage = s->stage;
    s->tw.held.cw = 0;
    if (!s->frame_in[0] && ew_harm_fused(op) && s->tw.pend) {
        s->frame_in[0] = ew_dev_view_in_place(dev, cv, 3, NULL);
        s->inplace = s->frame_in[0] != NULL;
    }
    if (!s->frame_in[0] && ew_images_overlap(cv, ew_op_image(op, "output"))) {
        if (!s->frame_own[0]) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "bgrid: the colour overlaps the output");
        s->frame_in[0] = s->frame_own[0];
    }
    for (int i = 0; i < 4 && r == EW_OK; i++)
        if (s->frame_own[i] && s->frame_in[i] == s->frame_own[i])
            r = ew_dev_put_view(dev, ew_op_image(op, input_names[i]), input_channels[i], s->frame_own[i], s->stage);
    if (r != EW_OK) return r;
    b->depth_scale = 1.0f;
    if (ew_op_image(op, "depth")) {
        /* the depth normalisation of one pass: the largest of the rows' maxima */
        if (s->frame_in[3]) {
            dev->backend->reduce_rows(dev, EW_REDUCE_DEPTH_MAX, w, h, s->frame_in[3], s->row_out);
        } else {
            for (int i = 0; i < tiling->ny && r == EW_OK; i++) {
                const ew_tile bb = band_at(tiling, i);
                const ew_image v = view_rows(ew_op_image(op, "depth"), bb.cy, bb.ch);
                r = ew_dev_put_view(dev, &v, 1, s->band_in[3], s->stage);
                dev->backend->reduce_rows(dev, EW_REDUCE_DEPTH_MAX, w, bb.ch, s->band_in[3], s->row_out + 2 * (size_t)bb.cy);
            }
        }
        if (r == EW_OK) r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)h * 2 * sizeof(double));
        if (r != EW_OK) return r;
        double mx = 0.0;
        for (int y = 0; y < h; y++)
            if (s->rows[2 * y] > mx) mx = s->rows[2 * y];
        b->depth_scale = mx > 0.0 ? (float)(1.0 / mx) : 1.0f;
    }
    const float cw = ew_op_param(op, "color_weight");
    float mean = 1.0f;
    const float *radiance;
    if (cw > 0.0f) {
        /* first sweep: the first pass's luminance sums of every core row */
        for (int i = 0; i < tiling->ny; i++) {
            const ew_tile bb = band_at(tiling, i);
            r = band_prepare(op, &bb, NULL, &radiance);
            if (r != EW_OK) return r;
            band_first_pass(op, &bb, radiance);
            dev->backend->reduce_rows(dev, EW_REDUCE_LUM_SUM, w, bb.ch, b->sliced + (size_t)(bb.cy - bb.ry) * w3,
                                      s->row_out + 2 * (size_t)bb.cy);
            if (!ew_op_report(op, 0.4 * (i + 1) / tiling->ny)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
        }
        r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)h * 2 * sizeof(double));
        if (r != EW_OK) return r;
        double sum = 0.0, count = 0.0;
        for (int y = 0; y < h; y++) {
            sum += s->rows[2 * y];
            count += s->rows[2 * y + 1];
        }
        mean = count > 0.0 && sum > 0.0 ? (float)(sum / count) : 1.0f;
    }
    float *removed = ew_harm_clamp_removed(op);
    const ew_image *o = ew_op_image(op, "output");
    for (int i = 0; i < tiling->ny && r == EW_OK; i++) {
        const ew_tile bb = band_at(tiling, i);
        r = band_prepare(op, &bb, removed, &radiance);
        if (r != EW_OK) return r;
        if (cw > 0.0f) {
            band_first_pass(op, &bb, radiance);
            dev->backend->denoise_refine_guide(dev, b, mean, cw);
        }
        ew_bgrid_params g;
        ew_bgrid_params_band(&s->grid_params, bb.ry, bb.rh, &g);
        ew_bgrid_splat(dev, &g, radiance, b->guide, s->grid);
        ew_bgrid_slice(dev, &g, s->grid, b->guide, b->sliced);
        dev->backend->denoise_finish(dev, b);
        if (ew_harm_fused(op)) {
            /* the stage's blend of the core and the rows its window reads
             * around it (exact: the halo holds them), over the clamped
             * colour where it lies; then the core's light the clamp took */
            const int m = ew_harm_region_margin(op);
            const int y0 = ew_maxi(bb.cy - m, 0), y1 = ew_mini(bb.cy + bb.ch + m, h);
            float *give = removed && ew_op_param(op, "firefly_k") > 0.0f ? s->removed + (size_t)(y0 - bb.ry) * w : NULL;
            r = ew_harm_region_done(op, 0, y0, w, y1 - y0, s->frame_in[0] + (size_t)y0 * w3,
                                    b->out + (size_t)(y0 - bb.ry) * w3, give);
            if (r == EW_OK && give) r = core_removed_out(op, &bb, removed);
            if (r != EW_OK) return r;
        }
        if (s->inplace) {
            r = ew_tile_writer_core(&s->tw, tiling, &bb, b->out, b->radiance);
        } else {
            const ew_image core = view_rows(o, bb.cy, bb.ch);
            r = ew_dev_get_view(dev, b->out + (size_t)(bb.cy - bb.ry) * w3, 3, &core, s->stage);
        }
        if (r == EW_OK && !ew_op_report(op, (cw > 0.0f ? 0.4 : 0.0) + (cw > 0.0f ? 0.6 : 1.0) * (i + 1) / tiling->ny))
            r = ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    b->height = h;
    /* every buffer is written again before it is read at the next execute */
    ew_dev_release_pages(dev, (char *)s->dmem.mem + (size_t)h * 2 * sizeof(double), (char *)s->dmem.mem + s->dmem.bytes);
    return r;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    if (s->bands.ny > 1) return execute_bands(op);
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
    /* the stage's blend of the frame, in place (ew_harm_fused: the colour
     * packed is the clamped colour the caller's view holds) */
    if (ew_harm_fused(op)) {
        r = ew_harm_region_done(op, 0, 0, b->width, b->height, b->color, b->out,
                                k > 0.0f ? ew_harm_clamp_removed(op) : NULL);
        if (r != EW_OK) return r;
    }
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

static const char *describe(const ew_op *op) {
    const state *s = (const state *)op->state;
    return s && s->bands.ny > 1 ? s->choice : NULL;
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
    .describe = describe,
    .stage_in_tiles = 1,
    .device_memory = 1, /* runs on CUDA */
    .pixel_params = (const char *const[]){"spatial_rate", "prepass_rate", NULL},
    .inplace_inputs = (const char *const[]){"color", NULL},
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_denoise_bgrid, 20);
