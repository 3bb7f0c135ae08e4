/*
 * denoise_kpcn.c — denoiser "kpcn": a kernel-predicting network
 * (algorithms/kpcn.h). A U-Net of 5x5 convolutions over three scales (four
 * for kpcn-large) predicts per-pixel 5x5 softmax kernels at full, half,
 * quarter (and eighth) resolution that filter the albedo-demodulated, firefly-clamped radiance, and blends the
 * scales coarse to fine; the albedo is multiplied back. Demodulation,
 * firefly clamp and remodulation are the "bgrid" method's own steps
 * (kernels/denoise_px.h, outlier.h), so the output cannot hold more energy
 * than the radiance around each pixel.
 *
 * Weights: "model" picks a model built into the library (0 = kpcn, 16
 * channels; 1 = kpcn-small, 8; 2 = kpcn-large, 24); ew_denoiser_set_data(d,
 * "weights", ...) loads a weights file written by train_kpcn instead.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/kpcn.h"
#include "kernels/mirror.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "src/backend.h"
#include "src/op.h"
#include "src/tile_writer.h"
#include "src/op_model.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "noisy colour (RGB, linear)"},
    {"albedo", 3, 1, "albedo (Cycles: Denoising Albedo): demodulation and a network input"},
    {"normal", 3, 1, "normal in [-1, 1] (Cycles: Denoising Normal): a network input"},
    {"depth", 1, 1, "depth (Cycles: Denoising Depth or Depth): a network input"},
    {"output", 3, 1, "denoised colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"model", EW_PARAM_INT, 0.0f, 0.0f, (float)(EW_KPCN_NUM_MODELS - 1),
     "built-in model: kpcn (16 channels; the default), kpcn-small (8 channels, 2.7x fewer multiply-adds), "
     "kpcn-large (32 channels, a fourth, coarser scale and a learned 5x5 remodulation over the albedo, 3.6x the "
     "multiply-adds, the best); ignored while weights "
     "are set with set_data"},
    {"firefly_k", EW_PARAM_FLOAT, 3.0f, 0.0f, 100.0f,
     "clamp pixels brighter than the 5x5 mean + k standard deviations before filtering; 0 turns it off (the "
     "shipped models were trained with 3)"},
    /* 768, not more: regions of up to ~0.7 Mpx run faster per pixel than larger ones on the CPU (fewer
     * first-touched pages, planes nearer the caches), which outweighs their halos down to ~0.2 Mpx; at
     * 1920x1080 and 3840x2160 this budget's tiles ran kpcn-large faster than 1024's and took 200-260 MB less
     * (docs/kpcn.md, "Tiles for memory") */
    {"max_memory_mb", EW_PARAM_INT, 768.0f, 1.0f, 1048576.0f,
     "memory the op may allocate, in MiB (as OIDN's maxMemoryMB): a frame whose network planes would exceed it "
     "runs in tiles with a halo of the network's reach (36 pixels at three scales, 80 for kpcn-large's four), giving "
     "the same output (on the CPU, frames above ~0.75 Mpx run in tiles whatever the budget: faster there); "
     "the frame-sized buffers (68 bytes a pixel, 40 when the features are packed float views "
     "read in place; tiled on the CPU 12, the rest streamed in bands of rows) and "
     "a 256x256 tile come first, so a small budget can be exceeded"},
    {"passes", EW_PARAM_INT, 1.0f, 1.0f, 4.0f,
     "runs of the network, each on the frame mirrored another way (left-right, both, up-down, none), averaged: "
     "the runs' errors differ and their mean keeps what they share (4 passes: about +0.15 dB for 4x the "
     "network's time and 3 more floats a pixel; the features are then copied, not read in place)"},
};

/* The network's weights (src/op_model.h). */
static int from_weights(void *net, const ew_weights *w, float **out, char *err, size_t errlen) {
    return ew_kpcn_from_weights((ew_kpcn_net *)net, w, out, err, errlen);
}

static const ew_net_kind kind = {"kpcn", sizeof(ew_kpcn_net), from_weights, ew_kpcn_builtin_weights,
                                 ew_kpcn_model_name};

static const ew_kpcn_net *net_of(const ew_net_model *m) { return (const ew_kpcn_net *)m->net; }

/* The network as the op lays out its planes (ew_kpcn_inference_planes). */
static void op_net(const ew_net_model *m, ew_kpcn_net *net) {
    *net = *net_of(m);
    ew_kpcn_inference_planes(net);
}

static ew_result set_data(ew_op *op, const char *name, const void *data, size_t size) {
    return ew_net_model_set_data(op, &kind, name, data, size);
}

typedef struct {
    ew_net_model *builtin;
    const ew_net_model *m;
    ew_kpcn_net net; /* m's network with the op's plane layout */
    ew_denoise_buffers buf;
    float *params, *clamped; /* the clamped radiance: the frame's, or streamed a region's (packed) */
    ew_tiling tiling;
    float *scale_mem;       /* the scale buffers of one region */
    size_t scale_floats;
    int lw, lh;             /* the region size sb is laid out for (0: none yet) */
    ew_gn_planes sb[EW_KPCN_MAX_SCALES]; /* the scales below full resolution (sb[0] unused) */
    ew_gn_planes band;                   /* every plane of scale 0 on a band of rows (kpcn.h) */
    ew_gn_planes sband[EW_KPCN_MAX_SCALES]; /* the bands of scales 1 .. S - 2 (kpcn.h: ew_kpcn_scale_band_rows) */
    float *rad[EW_KPCN_MAX_SCALES], *out[EW_KPCN_MAX_SCALES]; /* scales below full resolution: 3 planes each */
    float *tile_out;        /* scale 0's output on a region when there are several tiles */
    float *acc;             /* with several passes: the sum of the runs so far, 3 floats a pixel */
    int streamed;           /* tiles without the frame's radiance (execute_streamed) */
    int held;               /* streamed: the cores go out through the tile writer (output_over_color) */
    float *fcolor;          /* streamed: the colour when its view is not read in place (else untouched) */
    float *target;          /* streamed: the result when the output view is not written in place (else untouched) */
    float *band_rad, *band_guide, *band_clamped, *band_removed; /* streamed: one band of rows and its margins */
    float *band_above;      /* streamed: the clamped row above the band (exact: the band above's) */
    /* streamed: albedo, normal, depth held by the caller as halves
     * (ew_dev_view_half_rows), each read a band of rows at a time into
     * its buffer (feature_rows), else NULL */
    float *frows[3];
    ew_tile_writer tw;      /* streamed with the output over the colour: the cores out (writer_keep) */
    int sw[EW_KPCN_MAX_SCALES], sh[EW_KPCN_MAX_SCALES];
    double *row_out;
    ew_dev_kept dmem; /* the one device allocation, kept across commits of its size */
    double *rows;
    float *stage;
    char choice[96];
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

/* Device floats of a commit at w x h: parameters and the frame-sized
 * buffers (FRAME_FLOATS a pixel: packed colour, albedo, normal, depth,
 * radiance, clamped radiance, the hand-made guide denoise_prepare writes;
 * the output takes the colour's place, the filtered radiance the unused
 * one of radiance and clamped radiance), then one region's scale buffers,
 * the scales' radiance and outputs, and with several tiles scale 0's
 * output of a region. */
#define FRAME_FLOATS 17
#define FEATURE_FLOATS 7 /* of them albedo, normal, depth */
#define TILE_EXTRA_FLOATS 3
#define MIN_CORE 256
/* On the CPU a region above ~0.75 Mpx costs more a pixel than smaller
 * ones (more pages touched for the first time, planes farther from the
 * caches), more than the halos of smaller regions cost down to ~0.2 Mpx:
 * frames above a FAST_REGION-sided square run in tiles whatever the budget
 * (docs/kpcn.md, "Tiles for memory", has the sweep) */
#define FAST_REGION 864

/* Several passes (the "passes" parameter): the features are the op's own
 * copies, mirrored in place between runs, and a sum plane holds the runs. */
static int passes_of(const ew_op *op) { return (int)ew_op_param(op, "passes"); }

/* Streamed tiles. A tiled single run on the CPU holds no frame of colour,
 * radiance or guide: the firefly clamp (a 5x5 window) runs over bands of
 * BAND_ROWS rows with its window's rows above and below, each band's own
 * rows kept (the same bits as over the frame: a window inside the band's
 * rows is the frame's window). One sweep over the frame gives the noise
 * level's row sums and the light the clamp took; then each tile clamps its
 * region's radiance (a frame of it would be 95 MiB at 3840x2160). The
 * result goes straight into the output view when that is packed RGB
 * float (through the tile writer when it is the colour's). Not with several
 * passes (they mirror frames of inputs), nor on a device with memory of
 * its own (the views are copied to it whole anyway). Bands of 8 rows: the
 * sweep's bands are the frame's width (3 MiB less than 32 rows at 4K;
 * the clamp is a small part of the work, margins and all). */
#define BAND_ROWS 8
#define BAND_FLOATS_PX 8 /* radiance 3, guide 1, clamped 3, removed 1 */
static int can_stream(const ew_op *op) { return !op->dev->device_memory && passes_of(op) == 1; }
/* the clamp's window's rows above and below a band */
static int band_margin(void) { return ew_kpcn_clamp_params(1, 1, 0.0f).radius; }
/* a band and its margins, and the clamped row above it (the noise level's sums read it) */
static size_t band_floats(int w) {
    return (size_t)(BAND_ROWS + 2 * band_margin()) * (size_t)w * BAND_FLOATS_PX + 3 * (size_t)w;
}

/* albedo, normal, depth and their floats a pixel */
static const char *const feature_names[3] = {"albedo", "normal", "depth"};
static const int feature_channels[3] = {3, 3, 1};

/* The pixels of a band of a half feature's view read at once
 * (feature_rows), on a frame w wide in regions up to rw wide: the clamp's
 * bands of the frame's width, the network's (kpcn.h) and the
 * remodulation's of a region's, each with its margins */
static size_t feature_band_px(int w, int rw) {
    const size_t frame = (size_t)(BAND_ROWS + 2 * band_margin()) * (size_t)w;
    const size_t region = (size_t)(EW_KPCN_BAND_ROWS + 2 * EW_KPCN_BAND_MARGIN) * (size_t)rw;
    return frame > region ? frame : region;
}

/* Which features a streamed op reads from the caller's half views in
 * bands (no float copy of the frame) */
static void features_half(const ew_op *op, int half[3]) {
    for (int i = 0; i < 3; i++)
        half[i] = can_stream(op) && ew_dev_view_half_rows(op->dev, ew_op_image(op, feature_names[i]), feature_channels[i]);
}

/* The features the op reads from the caller's views where they are
 * (ew_dev_view_in_place: on the CPU, views already packed as the op packs
 * them), else NULL; the output is written while they are still read.
 * Several passes mirror the features in place: then always the op's copies. */
static void features_in_place(const ew_op *op, const float *in[3]) {
    if (passes_of(op) > 1) {
        in[0] = in[1] = in[2] = NULL;
        return;
    }
    const ew_image *o = ew_op_image(op, "output");
    in[0] = ew_dev_view_in_place(op->dev, ew_op_image(op, "albedo"), 3, o);
    in[1] = ew_dev_view_in_place(op->dev, ew_op_image(op, "normal"), 3, o);
    in[2] = ew_dev_view_in_place(op->dev, ew_op_image(op, "depth"), 1, o);
}

/* The parameters (rounded up to 16 floats), px floats a pixel and `more`. */
static size_t params_and_frame(const ew_kpcn_net *net, int w, int h, size_t px, size_t more) {
    return ((size_t)net->nparams + 15) / 16 * 16 + (size_t)w * (size_t)h * px + more + 64;
}

/* Floats a pixel of the features the op copies (those not read in place,
 * nor, streamed, read from halves in bands). */
static size_t feature_copies_px(const ew_op *op, int streamed) {
    const float *in[3];
    int half[3];
    features_in_place(op, in);
    features_half(op, half);
    size_t px = 0;
    for (int i = 0; i < 3; i++) px += in[i] || (streamed && half[i]) ? 0 : (size_t)feature_channels[i];
    return px;
}

/* Streamed: the band buffers of the features read from halves (regions
 * up to rw wide) */
static size_t feature_band_floats(const ew_op *op, int w, int rw) {
    int half[3];
    features_half(op, half);
    size_t px = 0;
    for (int i = 0; i < 3; i++) px += half[i] ? (size_t)feature_channels[i] : 0;
    return px * feature_band_px(w, rw);
}

static size_t frame_floats(const ew_op *op, const ew_kpcn_net *net, int w, int h) {
    const size_t px = FRAME_FLOATS - FEATURE_FLOATS + feature_copies_px(op, 0) + (passes_of(op) > 1 ? 3 : 0); /* the passes' sum */
    return params_and_frame(net, w, h, px, 0);
}

/* The pixels around a core whose output must be exact too: the
 * do-no-harm stage's blend's, when it may run in the tiles (fused_core) */
static int fused_margin(const ew_op *op) { return ew_harm_may_fuse(op) ? ew_harm_region_margin(op) : 0; }

/* Streamed: are the cores written over the colour the tiles read where it
 * lies (both views read and written in place, overlapping)? */
static int output_over_color(const ew_op *op) {
    const ew_image *c = ew_op_image(op, "color"), *o = ew_op_image(op, "output");
    return c && o && ew_dev_view_in_place(op->dev, c, 3, NULL) && ew_dev_view_in_place(op->dev, o, 3, NULL) &&
           ew_images_overlap(c, o);
}

/* Streamed, what the tile writer holds back of each core (0: no writer):
 * with the output over the colour, all a later region clamps its radiance
 * from (its halo and the clamp's window past it), so the colour is still
 * there when it does; else the stage's blend margin when it may run in
 * the tiles (with the views it runs on then, which the commit's include). */
static int writer_keep(const ew_op *op, const ew_kpcn_net *net) {
    const int m = fused_margin(op);
    return output_over_color(op) ? ew_kpcn_halo_around(net, m) + band_margin() : m;
}

/* Streamed (above): the parameters, the colour when it is not read in
 * place and the result when the output is not written in place (reserved;
 * their pages untouched otherwise), the features not read in place (a
 * band of those read from halves, regions up to rw wide), one band, the
 * clamped radiance of a rw x rh region, and what the tile writer holds
 * back of the cores (writer_keep). */
static size_t streamed_frame_floats(const ew_op *op, const ew_kpcn_net *net, int w, int h, int rw, int rh) {
    const int keep = writer_keep(op, net);
    return params_and_frame(net, w, h, 3 + 3 + feature_copies_px(op, 1),
                            band_floats(w) + feature_band_floats(op, w, rw) + (size_t)rw * (size_t)rh * 3 +
                                (keep ? ew_tile_writer_floats(w, h, keep) : 0));
}

/* The device floats of a tiled side x side region. */
static size_t square_region_floats(const ew_kpcn_net *net, int side) {
    return ew_kpcn_device_floats(net, side, side) + (size_t)TILE_EXTRA_FLOATS * side * side;
}

/* The tiles of a w x h frame whose frame-sized buffers take `frame`
 * floats under max_memory_mb. */
static void plan_tiles(const ew_op *op, const ew_kpcn_net *net, int w, int h, size_t frame, ew_tiling *t) {
    const size_t budget = (size_t)ew_op_param(op, "max_memory_mb") * (1048576 / sizeof(float));
    /* below a 256-pixel core the halos would more than double the work:
     * such a tile's region is the least the tiles get */
    const int margin = fused_margin(op);
    const size_t floor = square_region_floats(net, MIN_CORE + 2 * ew_kpcn_halo_around(net, margin));
    size_t tiles = budget > frame + floor ? budget - frame : floor;
    const size_t fast = square_region_floats(net, FAST_REGION);
    if (!op->dev->device_memory && tiles > fast) tiles = fast;
    ew_kpcn_tiling_plan(net, w, h, tiles, TILE_EXTRA_FLOATS, margin, t);
}

/* The tiles of a w x h frame under max_memory_mb, whether they are
 * streamed, and the device floats of the commit. */
static size_t plan(const ew_op *op, const ew_kpcn_net *net, int w, int h, ew_tiling *t, int *streamed) {
    size_t frame = frame_floats(op, net, w, h);
    plan_tiles(op, net, w, h, frame, t);
    *streamed = 0;
    if (t->nx * t->ny > 1 && can_stream(op)) {
        /* with the smaller frame buffers the tiles may get more room:
         * planned with a frame's clamped radiance, then holding a region's
         * (the tile writer needs cores at least as wide as what it keeps) */
        ew_tiling ts;
        plan_tiles(op, net, w, h, streamed_frame_floats(op, net, w, h, w, h), &ts);
        if (ts.nx * ts.ny > 1 && ew_tile_writer_fits(&ts, writer_keep(op, net))) {
            *t = ts;
            *streamed = 1;
            frame = streamed_frame_floats(op, net, w, h, ts.rw, ts.rh);
        }
    }
    const int tiled = t->nx * t->ny > 1;
    return frame + ew_kpcn_device_floats(net, t->rw, t->rh) +
           (tiled ? (size_t)TILE_EXTRA_FLOATS * (size_t)t->rw * (size_t)t->rh : 0);
}

/* ew_op_type.memory: the commit's allocations (row sums as doubles on the
 * host and the device, host staging when views need it). */
static uint64_t memory(const ew_op *op, int w, int h) {
    ew_net_model *builtin = NULL;
    const ew_net_model *m = NULL;
    if (ew_net_model_of(op, &kind, &m, &builtin) != EW_OK) return 0;
    ew_tiling t;
    ew_kpcn_net net;
    op_net(m, &net);
    int streamed;
    const uint64_t bytes = (uint64_t)plan(op, &net, w, h, &t, &streamed) * sizeof(float) + (uint64_t)h * 4 * sizeof(double) +
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
    ew_kpcn_net run;
    op_net(m, &run);
    const ew_kpcn_net *net = &run;
    const size_t n = (size_t)w * (size_t)h;
    /* device: row sums (doubles first), then as plan() counts */
    ew_tiling tiling;
    int streamed;
    const size_t need = plan(op, net, w, h, &tiling, &streamed);
    const size_t row_bytes = (size_t)h * 2 * sizeof(double);
    const size_t stage_floats = ew_dev_stage_floats(dev, n, 3);
    const ew_dev_kept old = ew_dev_kept_take(op->state ? &((state *)op->state)->dmem : NULL);
    release(op);
    state *s = (state *)calloc(1, sizeof(state) + row_bytes + stage_floats * sizeof(float));
    op->state = s;
    if (!ew_dev_keep(dev, s ? &s->dmem : NULL, old, row_bytes + need * sizeof(float))) {
        ew_net_model_free(builtin);
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of %s memory: kpcn on %dx%d needs %.1f MiB",
                        s ? dev->backend->name : "host", w, h, (double)(need * sizeof(float) + row_bytes) / 1048576.0);
    }
    s->builtin = builtin;
    s->m = m;
    s->net = run;
    s->tiling = tiling;
    s->streamed = streamed;
    if (builtin)
        snprintf(s->choice, sizeof s->choice, "kpcn %s", ew_kpcn_model_name((int)ew_op_param(op, "model")));
    else
        snprintf(s->choice, sizeof s->choice, "kpcn weights %s", net_of(m)->arch);
    if (tiling.nx * tiling.ny > 1) {
        const size_t len = strlen(s->choice);
        snprintf(s->choice + len, sizeof s->choice - len, ", %dx%d tiles", tiling.nx, tiling.ny);
    }
    if (passes_of(op) > 1) {
        const size_t len = strlen(s->choice);
        snprintf(s->choice + len, sizeof s->choice - len, ", %d mirrored passes", passes_of(op));
    }
    s->rows = s->host;
    s->stage = stage_floats ? (float *)(void *)(s->host + (size_t)h * 2) : NULL;
    s->row_out = (double *)s->dmem.mem;
    float *p = (float *)(void *)((char *)s->dmem.mem + row_bytes);
    s->params = p; p += (net->nparams + 15) / 16 * 16;
    ew_denoise_buffers *b = &s->buf;
    memset(b, 0, sizeof *b);
    b->width = w;
    b->height = h;
    const float *in[3];
    int half[3];
    features_in_place(op, in);
    features_half(op, half);
    if (streamed) {
        s->fcolor = p; p += n * 3;
        s->target = p; p += n * 3;
    } else {
        b->out = p; /* the colour is read by denoise_prepare only: the output takes its place */
        b->color = p; p += n * 3;
    }
    const float **fp[3] = {&b->albedo, &b->normal, &b->depth};
    for (int i = 0; i < 3; i++) {
        const size_t c = (size_t)feature_channels[i];
        if (in[i]) {
            *fp[i] = in[i];
        } else if (streamed && half[i]) { /* no plane: feature_rows reads bands into frows */
            *fp[i] = NULL;
            s->frows[i] = p; p += feature_band_px(w, tiling.rw) * c;
        } else {
            *fp[i] = p; p += n * c;
        }
    }
    if (streamed) {
        s->clamped = p; p += (size_t)tiling.rw * (size_t)tiling.rh * 3; /* a region */
        const size_t bn = (band_floats(w) - 3 * (size_t)w) / BAND_FLOATS_PX;
        s->band_rad = p; p += bn * 3;
        s->band_guide = p; p += bn;
        s->band_clamped = p; p += bn * 3;
        s->band_removed = p; p += bn;
        s->band_above = p; p += 3 * (size_t)w;
        s->tw.keep = writer_keep(op, net);
        if (s->tw.keep) {
            s->tw.strip = p; p += (size_t)h * (size_t)s->tw.keep * 3;
            s->tw.pend = p; p += 2 * (size_t)w * (size_t)s->tw.keep * 3;
        }
    } else {
        b->radiance = p; p += n * 3;
        s->clamped = p; p += n * 3;
        b->guide = p; p += n;
    }
    s->acc = passes_of(op) > 1 ? p : NULL; p += s->acc ? n * 3 : 0;
    /* the region's buffers */
    int rsw[EW_KPCN_MAX_SCALES], rsh[EW_KPCN_MAX_SCALES];
    ew_kpcn_scale_sizes(net, tiling.rw, tiling.rh, rsw, rsh);
    s->scale_mem = p;
    p += ew_kpcn_planes_floats(net, tiling.rw, tiling.rh);
    s->scale_floats = (size_t)(p - s->scale_mem);
    for (int k = 1; k < net->scales; k++) {
        s->rad[k] = p; p += 3 * (size_t)rsw[k] * rsh[k];
        s->out[k] = p; p += 3 * (size_t)rsw[k] * rsh[k];
    }
    s->tile_out = tiling.nx * tiling.ny > 1 ? p : NULL;
    return dev->backend->mem_upload(dev, s->params, m->params, net->nparams * sizeof(float));
}

static ew_kpcn_tensor planes_t(const ew_gn_planes *b, int plane) {
    ew_kpcn_tensor t = {ew_gn_plane_row(b, plane, 0), 1, b->rs, b->ps};
    return t;
}

static ew_kpcn_tensor flat_t(float *p, int w, int h) {
    ew_kpcn_tensor t = {p, 1, w, (long)w * h};
    return t;
}

/* Scale k's kernel filter on `rows` of its rows from y0, with the logits
 * `logits` (their row 0 the row y0): the scale's radiance and output (scale
 * 0's are the caller's to set), toward the next scale's output (none at the
 * coarsest) */
static ew_kpcn_filter_args filter_args(const state *s, int k, int y0, int rows, ew_kpcn_tensor logits) {
    ew_kpcn_filter_args fa;
    memset(&fa, 0, sizeof fa);
    fa.width = s->sw[k];
    fa.height = rows;
    fa.y0 = y0;
    fa.frame_h = s->sh[k];
    fa.logits = logits;
    if (k > 0) {
        fa.radiance = flat_t(s->rad[k], s->sw[k], s->sh[k]);
        fa.out = flat_t(s->out[k], s->sw[k], s->sh[k]);
    }
    if (k + 1 < s->net.scales) {
        fa.coarse = flat_t(s->out[k + 1], s->sw[k + 1], s->sh[k + 1]);
        fa.cw = s->sw[k + 1];
        fa.ch = s->sh[k + 1];
    }
    return fa;
}

/* Layer l of scale k on `rows` rows: its input from plane ip of `in` at
 * row ir, its output into plane opl of `out` at row orow, on the scale's
 * rows y .. y + rows of the region. Winograd where the backend has it, its
 * tiles anchored at the frame's origin (the region's at this scale is
 * tile->rx / 2^scale, exact: regions start on multiples of 2^(S-1)), so
 * inside a region, and in a band whose rows start on the grid (kpcn.h),
 * they are the whole frame's tiles; the tiled output is the untiled one to
 * rounding (docs/kpcn.md, "tiles"). */
static void conv_rows(ew_device *dev, const state *s, int l, const ew_tile *tile, const ew_gn_planes *in, int ip,
                      int ir, const ew_gn_planes *out, int opl, int orow, int rows, int y) {
    ew_conv_args a;
    ew_kpcn_layer_args(&s->net, l, s->params, s->sb, &a);
    const int k = s->net.layers[l].scale;
    a.width = in->width;
    a.rows = rows;
    a.in = ew_gn_plane_row(in, ip, ir);
    a.in_rs = in->rs;
    a.in_ps = in->ps;
    a.out = ew_gn_plane_row(out, opl, orow);
    a.out_rs = out->rs;
    a.out_ps = out->ps;
    a.winograd = 1;
    a.grid_x = tile->rx >> k;
    a.grid_y = (tile->ry >> k) + y;
    dev->backend->conv5(dev, &a);
}

/* Layer l on its scale's whole planes of the region */
static void conv(ew_device *dev, const state *s, int l, const ew_tile *tile) {
    const ew_kpcn_layer *L = &s->net.layers[l];
    const ew_gn_planes *b = &s->sb[L->scale];
    conv_rows(dev, s, l, tile, b, L->in_plane, 0, b, L->out_plane, 0, b->rows, 0);
}

/* The 2x2 pooling of rows f0 .. f0 + rows of plane fp of f (and the n - 1
 * after it) into plane cp of c from row c_row */
static void pool_rows(ew_device *dev, const ew_gn_planes *f, int fp, int f0, int rows, const ew_gn_planes *c, int cp,
                      int c_row, int n) {
    ew_kpcn_pool_args a = {f->width, rows, c->width, ew_kpcn_half(rows), n, planes_t(f, fp), planes_t(c, cp)};
    a.src.data = ew_gn_plane_row(f, fp, f0);
    a.dst.data = ew_gn_plane_row(c, cp, c_row);
    (void)EW_RUN(dev, kpcn_pool, &a);
}

static void pool(ew_device *dev, const ew_gn_planes *f, int fp, const ew_gn_planes *c, int cp, int nplanes) {
    pool_rows(dev, f, fp, 0, f->rows, c, cp, 0, nplanes);
}

/* Where the full-resolution filter's output goes: the filtered radiance,
 * which denoise_finish multiplies by the albedo, or with a remodulation
 * kernel the output colour itself (the filter remodulates). */
static float *tile_target(const state *s, const ew_kpcn_net *net) { return net->remod ? s->buf.out : s->buf.sliced; }

/* Lays the scale buffers out for a rw x rh region; zeroes them when the
 * layout changes (the planes' zero padding is written once a layout: the
 * entries only write inside the planes). */
static ew_result layout_region(ew_device *dev, state *s, int rw, int rh) {
    if (s->lw == rw && s->lh == rh) return EW_OK;
    const ew_kpcn_net *net = &s->net;
    ew_kpcn_scale_sizes(net, rw, rh, s->sw, s->sh);
    float *p = s->scale_mem;
    for (int k = 1; k < net->scales; k++) {
        ew_gn_planes_layout(&s->sb[k], p, s->sw[k], s->sh[k], net->nplanes[k]);
        p += ew_gn_planes_floats(s->sw[k], s->sh[k], net->nplanes[k]) + 16;
    }
    ew_gn_planes_layout(&s->band, p, rw, ew_kpcn_band_rows(rh), net->nplanes[0]);
    p += ew_gn_planes_floats(rw, ew_kpcn_band_rows(rh), net->nplanes[0]) + 16;
    for (int k = 1; k < net->scales - 1; k++) {
        const int rows = ew_kpcn_scale_band_rows(s->sh[k]), planes = ew_kpcn_scale_band_planes(net);
        ew_gn_planes_layout(&s->sband[k], p, s->sw[k], rows, planes);
        p += ew_gn_planes_floats(s->sw[k], rows, planes) + 16;
    }
    s->lw = rw;
    s->lh = rh;
    return dev->backend->mem_zero(dev, s->scale_mem, s->scale_floats * sizeof(float));
}

/* Layer l of scale 0 on `rows` rows of its band from band row `row` (the
 * region's row y) */
static void band_conv(ew_device *dev, const state *s, int l, const ew_tile *tile, int row, int rows, int y) {
    const ew_kpcn_layer *L = &s->net.layers[l];
    conv_rows(dev, s, l, tile, &s->band, L->in_plane, row, &s->band, L->out_plane, row, rows, y);
}

/* Rows y0 .. y1, columns x0 .. x1 of feature i (albedo, normal, depth) as
 * floats, at its pixel (x0, y0), and *rs, the pixels a row: the op's plane
 * or the view read in place (the frame's width), or, streamed from a half
 * view, that rectangle converted into its band buffer (x1 - x0; one band
 * at a time: the caller reads it before the next call). */
static const float *feature_rows(ew_op *op, int i, int y0, int y1, int x0, int x1, long *rs) {
    const state *s = (const state *)op->state;
    const ew_denoise_buffers *b = &s->buf;
    const float *plane = i == 0 ? b->albedo : i == 1 ? b->normal : b->depth;
    const size_t c = (size_t)feature_channels[i];
    if (plane) {
        *rs = b->width;
        return plane + ((size_t)y0 * (size_t)b->width + (size_t)x0) * c;
    }
    ew_dev_view_rows(op->dev, ew_op_image(op, feature_names[i]), (int)c, y0, y1, x0, x1, s->frows[i]);
    *rs = x1 - x0;
    return s->frows[i];
}

/* The rows of a band w wide that feature_rows converts at once */
static int feature_band_rows(const state *s, int w) {
    return (int)(feature_band_px(s->buf.width, s->tiling.rw) / (size_t)w);
}

/* out = filtered * (albedo + eps) on the frame's rect x0, y0, w x h, out
 * (packed w wide) holding the filtered radiance: at once, or a band of
 * rows at a time when the albedo is read from halves */
static void finish_rows(ew_op *op, int x0, int y0, int w, int h, float *out) {
    const state *s = (const state *)op->state;
    const int step = s->frows[0] ? feature_band_rows(s, w) : h;
    for (int y = 0; y < h; y += step) {
        const int n = ew_mini(step, h - y);
        ew_denoise_buffers rb = s->buf;
        long rs;
        rb.width = w;
        rb.height = n;
        rb.albedo = feature_rows(op, 0, y0 + y, y0 + y + n, x0, x0 + w, &rs);
        rb.in_stride = (int)rs;
        rb.sliced = rb.out = out + (size_t)y * (size_t)w * 3;
        op->dev->backend->denoise_finish(op->dev, &rb);
    }
}

/* The band's rows: the region's rows t0 .. t1 of the network's inputs from
 * its first row on (`region`: kpcn_input's arguments for the whole region,
 * its sources at the region's first pixel), and when t1 is the region's
 * last row, zeros below it in every plane, as a whole region's padding
 * (a shorter last band would leave the rows of the band before there). */
static ew_result band_inputs(ew_op *op, const ew_tile *tile, const ew_kpcn_input_args *region, int t0, int t1) {
    ew_device *dev = op->dev;
    const state *s = (const state *)op->state;
    const ew_gn_planes *B = &s->band;
    ew_kpcn_input_args a = *region;
    const long at = (long)t0 * a.src_rs;
    a.height = t1 - t0;
    a.radiance += at * 3;
    const float **f[3] = {&a.albedo, &a.normal, &a.depth};
    long *frs[3] = {&a.albedo_rs, &a.normal_rs, &a.depth_rs};
    for (int i = 0; i < 3; i++) /* the region's rows t0 .. t1 of each, at its first column */
        *f[i] = feature_rows(op, i, tile->ry + t0, tile->ry + t1, tile->rx, tile->rx + tile->rw, frs[i]);
    a.dst = ew_gn_plane_row(B, s->net.in[0], 0);
    a.rs = B->rs;
    a.ps = B->ps;
    (void)EW_RUN(dev, kpcn_input, &a);
    ew_result r = EW_OK;
    for (int pl = 0; t1 == s->sh[0] && pl < B->nplanes && r == EW_OK; pl++)
        r = dev->backend->mem_zero(dev, ew_gn_plane_row(B, pl, t1 - t0), (size_t)EW_CONV_R * (size_t)B->rs * sizeof(float));
    return r;
}

/* Zeroes rows r .. r + EW_CONV_R of planes 0 .. n of a band: past the
 * region's last row, as its planes' padding */
static ew_result zero_rows(ew_device *dev, const ew_gn_planes *b, int n, int r) {
    ew_result res = EW_OK;
    for (int pl = 0; pl < n && res == EW_OK; pl++)
        res = dev->backend->mem_zero(dev, ew_gn_plane_row(b, pl, r), (size_t)EW_CONV_R * (size_t)b->rs * sizeof(float));
    return res;
}

/* Copies `rows` rows of n planes from plane sp of src at row from to
 * planes 0 .. n of dst at row to (the same width: the same row stride;
 * whole rows, their zero padding with them) */
static ew_result copy_rows(ew_device *dev, const ew_gn_planes *dst, int to, const ew_gn_planes *src, int sp, int from,
                           int n, int rows) {
    ew_result res = EW_OK;
    for (int pl = 0; pl < n && res == EW_OK; pl++)
        res = dev->backend->mem_copy(dev, ew_gn_plane_row(dst, pl, to), ew_gn_plane_row(src, sp + pl, from),
                                     (size_t)rows * (size_t)dst->rs * sizeof(float));
    return res;
}

/* Scale 0's encoder on the region's rows f0 .. f1 (f0 on the 4-row grid,
 * its inputs 2 rows beyond them) and its 2x2 pooling into scale 1's inputs
 * in plane 0 of `dst` from row dst_row (f0 is even, so the poolings pair
 * the rows the whole region's do). */
static ew_result encode0_rows(ew_op *op, const ew_tile *tile, const ew_kpcn_input_args *in, int f0, int f1,
                              const ew_gn_planes *dst, int dst_row) {
    ew_device *dev = op->dev;
    const state *s = (const state *)op->state;
    const ew_kpcn_net *net = &s->net;
    const ew_gn_planes *B = &s->band;
    const int rh = s->sh[0];
    const int t0 = ew_maxi(f0 - EW_CONV_R, 0), t1 = ew_mini(f1 + EW_CONV_R, rh);
    const ew_result r = band_inputs(op, tile, in, t0, t1);
    if (r != EW_OK) return r;
    band_conv(dev, s, net->enc[0], tile, f0 - t0, f1 - f0, f0);
    pool_rows(dev, B, net->h[0], f0 - t0, f1 - f0, dst, 0, dst_row, net->ch);
    return EW_OK;
}

/* The end of the chunk or band of n rows (a multiple of 4) from row y of
 * a scale h rows tall whose first row is the frame's row g at that scale:
 * on the frame's n-row grid there, so on Winograd's 4-row one (kpcn.h) */
static int band_end(int y, int g, int n, int h) { return ew_mini((y + g) / n * n + n - g, h); }

/* Scale k's inputs from row f0 / 2 into plane 0 of `dst` from row dst_row:
 * scale 0's encoder on the region's rows f0 .. f1 pooled (k 1), or the
 * finer scale's whole encoder output pooled */
static ew_result feed_scale(ew_op *op, const ew_tile *tile, const ew_kpcn_input_args *in, int k, int f0, int f1,
                            const ew_gn_planes *dst, int dst_row) {
    if (k == 1) return encode0_rows(op, tile, in, f0, f1, dst, dst_row);
    const state *s = (const state *)op->state;
    pool_rows(op->dev, &s->sb[k - 1], s->net.h[k - 1], f0, f1 - f0, dst, 0, dst_row, s->net.ch);
    return EW_OK;
}

/* Scale k's encoder (0 < k < S - 1; kpcn.h) in chunks of
 * EW_KPCN_BAND_ROWS / 2 rows into its plane h, each once the finer scale
 * has pooled the rows it reads into the scale's band (band row 0: the
 * scale's row t0; the 2 rows above a chunk carried over from the chunk
 * before). */
static ew_result encode_scale(ew_op *op, const ew_tile *tile, const ew_kpcn_input_args *in, int k) {
    ew_device *dev = op->dev;
    const state *s = (const state *)op->state;
    const ew_kpcn_net *net = &s->net;
    const ew_gn_planes *I = &s->sband[k];
    const int hk = s->sh[k], hf = s->sh[k - 1], C = net->ch, R = EW_CONV_R, A = EW_KPCN_BAND_ROWS / 2;
    const int g = tile->ry >> k;
    int t0 = 0, have = 0; /* the scale's input rows t0 .. have are in the band */
    ew_result r = EW_OK;
    for (int a0 = 0, a1; a0 < hk && r == EW_OK; a0 = a1) {
        a1 = band_end(a0, g, A, hk);
        const int need = ew_mini(a1 + R, hk);
        if (need > have) r = feed_scale(op, tile, in, k, 2 * have, ew_mini(2 * need, hf), I, have - t0);
        have = need;
        if (r == EW_OK && need == hk) r = zero_rows(dev, I, C, hk - t0);
        if (r != EW_OK) break;
        conv_rows(dev, s, net->enc[k], tile, I, 0, a0 - t0, &s->sb[k], net->h[k], a0, a1 - a0, a0);
        if (a1 < hk) {
            r = copy_rows(dev, I, 0, I, 0, a1 - R - t0, C, have - (a1 - R)); /* up to row 0 */
            t0 = a1 - R;
        }
    }
    return r;
}

/* Scale k's end (0 < k < S - 1; kpcn.h): the decoder band by band over its
 * encoder's output h (the 2 rows above each band, overwritten by the band
 * above, carried over in the band), then the head and the kernel filter
 * band by band into the scale's output out[k]. */
static ew_result decode_scale(ew_op *op, const ew_tile *tile, int k) {
    ew_device *dev = op->dev;
    const state *s = (const state *)op->state;
    const ew_kpcn_net *net = &s->net;
    const ew_gn_planes *D = &s->sband[k], *P = &s->sb[k];
    const int hk = s->sh[k], C = net->ch, R = EW_CONV_R, S = net->scales, B = EW_KPCN_BAND_ROWS;
    const int g = tile->ry >> k;
    ew_result r = EW_OK;
    for (int p0 = 0, p1; p0 < hk && r == EW_OK; p0 = p1) {
        p1 = band_end(p0, g, B, hk);
        const int t0 = ew_maxi(p0 - R, 0), t1 = ew_mini(p1 + R, hk);
        /* h's rows p0 .. t1 (rows t0 .. p0 are in the band already) */
        r = copy_rows(dev, D, p0 - t0, P, net->h[k], p0, C, t1 - p0);
        if (r != EW_OK) break;
        ew_kpcn_up_args ua = {D->width, t1 - t0, s->sw[k + 1], s->sh[k + 1], C,
                              planes_t(&s->sb[k + 1], k + 1 == S - 1 ? net->hb : net->d[k + 1]), planes_t(D, C), t0};
        (void)EW_RUN(dev, kpcn_up, &ua);
        if (t1 == hk) r = zero_rows(dev, D, 2 * C, t1 - t0);
        if (r != EW_OK) break;
        conv_rows(dev, s, net->dec[k], tile, D, 0, p0 - t0, P, net->d[k], p0, p1 - p0, p0);
        if (p1 < hk) r = copy_rows(dev, D, 0, D, 0, p1 - R - t0, C, R); /* up to row 0 */
    }
    for (int q0 = 0, q1; q0 < hk && r == EW_OK; q0 = q1) {
        q1 = band_end(q0, g, B, hk);
        conv_rows(dev, s, net->lhead[k], tile, P, net->d[k], q0, D, 0, 0, q1 - q0, q0);
        ew_kpcn_filter_args fa = filter_args(s, k, q0, q1 - q0, planes_t(D, 0));
        (void)EW_RUN(dev, kpcn_filter, &fa);
    }
    return r;
}

/* Scale 0's end on the region's rows b0 .. b0 + EW_KPCN_BAND_ROWS (kpcn.h):
 * the inputs and the encoder's output of the band and its margins again,
 * the next scale's output upsampled, the decoder on the band and 4 rows
 * either side, the head and the kernel filter (rad0, out: the region's
 * tensors; remod: with the remodulation over the albedo) on the band. The band's
 * planes hold its margins from row t0; past the region's last row they
 * read zeros, as the region's planes would. */
static ew_result scale0_band(ew_op *op, const ew_tile *tile, const ew_kpcn_input_args *in, int b0,
                             const ew_kpcn_tensor *rad0, const ew_kpcn_tensor *out, int remod) {
    ew_device *dev = op->dev;
    const state *s = (const state *)op->state;
    const ew_kpcn_net *net = &s->net;
    const ew_gn_planes *B = &s->band;
    const int rh = s->sh[0], C = net->ch, S = net->scales;
    const int b1 = ew_mini(b0 + EW_KPCN_BAND_ROWS, rh);
    const int t0 = ew_maxi(b0 - EW_KPCN_BAND_MARGIN, 0), t1 = ew_mini(b1 + EW_KPCN_BAND_MARGIN, rh);
    const int e0 = ew_maxi(b0 - EW_KPCN_ENC_MARGIN, 0), e1 = ew_mini(b1 + EW_KPCN_ENC_MARGIN, rh);
    const int o0 = ew_maxi(b0 - EW_KPCN_DEC_MARGIN, 0), o1 = ew_mini(b1 + EW_KPCN_DEC_MARGIN, rh);
    /* the decoder reads the encoder's output and the upsampled planes 2 rows beyond its own */
    const int u0 = ew_maxi(o0 - EW_CONV_R, 0), u1 = ew_mini(o1 + EW_CONV_R, rh);
    const ew_result r = band_inputs(op, tile, in, t0, t1);
    if (r != EW_OK) return r;
    band_conv(dev, s, net->enc[0], tile, e0 - t0, e1 - e0, e0);
    /* over the inputs, which only the encoder reads (ew_kpcn_inference_planes) */
    ew_kpcn_up_args ua = {B->width, u1 - u0, s->sw[1], s->sh[1], C,
                          planes_t(&s->sb[1], S - 1 == 1 ? net->hb : net->d[1]), planes_t(B, net->u[0]), u0};
    ua.dst.data = ew_gn_plane_row(B, net->u[0], u0 - t0);
    (void)EW_RUN(dev, kpcn_up, &ua);
    band_conv(dev, s, net->dec[0], tile, o0 - t0, o1 - o0, o0);
    band_conv(dev, s, net->lhead[0], tile, b0 - t0, b1 - b0, b0);
    ew_kpcn_tensor logits = planes_t(B, net->head[0]);
    logits.data = ew_gn_plane_row(B, net->head[0], b0 - t0);
    ew_kpcn_filter_args fa = filter_args(s, 0, b0, b1 - b0, logits);
    fa.radiance = *rad0;
    fa.out = *out;
    if (remod) { /* the filter remodulates: its output is the colour; the albedo band_inputs read, from row t0 */
        long rs;
        const float *al = feature_rows(op, 0, tile->ry + t0, tile->ry + t1, tile->rx, tile->rx + tile->rw, &rs);
        const ew_kpcn_tensor at = {(float *)al, 3, 3L * rs, 1};
        fa.albedo = at;
        fa.albedo_y0 = t0;
    }
    (void)EW_RUN(dev, kpcn_filter, &fa);
    return EW_OK;
}

/* A streamed tile's end with the do-no-harm stage in the tiles
 * (ew_harm_fused: the output is the colour's view, which holds the clamped
 * colour; the halo reaches ew_harm_region_margin past the core): the
 * region's output remodulated, blended on that colour (packed into the
 * region's clamped radiance, read by nothing after the filters) with the
 * share the clamp took (packed where the scales' radiance and outputs
 * were: 1.5 floats a region pixel at least), the core's share back where
 * the stage reads it, and the core out through the tile writer, which
 * holds back what the next tiles read. */
static ew_result fused_core(ew_op *op, const ew_tile *tile) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    const ew_denoise_buffers *b = &s->buf;
    const int W = b->width, rw = tile->rw, rh = tile->rh, ox = tile->cx - tile->rx, oy = tile->cy - tile->ry;
    if (!s->net.remod) finish_rows(op, tile->rx, tile->ry, rw, rh, s->tile_out); /* out = filtered * (albedo + eps), in place */
    const float *color = ew_dev_view_in_place(dev, ew_op_image(op, "color"), 3, NULL);
    float *removed = ew_harm_clamp_removed(op), *share = s->rad[1];
    ew_result r = ew_dev_copy_rect(dev, s->clamped, rw, 0, 0, color, W, tile->rx, tile->ry, rw, rh, 3);
    if (r == EW_OK) r = ew_dev_copy_rect(dev, share, rw, 0, 0, removed, W, tile->rx, tile->ry, rw, rh, 1);
    if (r == EW_OK) r = ew_harm_region_done(op, tile->rx, tile->ry, rw, rh, s->clamped, s->tile_out, share);
    if (r == EW_OK) r = ew_dev_copy_rect_sparse(dev, removed, W, tile->cx, tile->cy, share, rw, ox, oy, tile->cw, tile->ch);
    return r == EW_OK ? ew_tile_writer_core(&s->tw, &s->tiling, tile, s->tile_out, s->clamped) : r;
}

/* The network and the filters on one tile's region, keeping its core in
 * tile_target (the filtered radiance, or the colour), the clamped radiance
 * `radiance` (rs pixels a row, its first pixel the frame's (x0, y0));
 * progress from p0 over the span dp. */
static ew_result run_tile(ew_op *op, const float *radiance, long rs, int x0, int y0, float noise, const ew_tile *tile,
                          double p0, double dp) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const ew_kpcn_net *net = &s->net;
    const int W = b->width, C = net->ch, rw = tile->rw, rh = tile->rh;
    ew_result r = layout_region(dev, s, rw, rh);
    if (r != EW_OK) return r;
    const float *rad = radiance + ((long)(tile->ry - y0) * rs + (tile->rx - x0)) * 3; /* ... in the clamped radiance */
    /* zeroed first, then member by member: the padding after depth_scale
     * would otherwise carry stale stack bytes to a device that copies the
     * struct as bytes (and to the launch-grid check, which reads every word
     * of it as a possible pointer) */
    ew_kpcn_input_args ia;
    memset(&ia, 0, sizeof ia);
    ia.width = rw;
    ia.height = rh;
    ia.radiance = rad; /* the features: band_inputs' */
    ia.depth_scale = b->depth_scale;
    ia.noise_plane = net->noise;
    ia.noise = noise;
    ia.src_rs = rs;
    /* the network (algorithms/kpcn.h's layer list): the encoders of the
     * scales but the coarsest in bands, ... */
    const int S = net->scales;
    for (int k = 1; k < S - 1 && r == EW_OK; k++) r = encode_scale(op, tile, &ia, k);
    if (r != EW_OK) return r;
    if (!ew_op_report(op, p0 + 0.05 * dp)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    /* ... the coarsest scale whole ... */
    pool(dev, &s->sb[S - 2], net->h[S - 2], &s->sb[S - 1], net->in[S - 1], C);
    conv(dev, s, net->enc_a, tile);
    conv(dev, s, net->enc_b, tile);
    conv(dev, s, net->lhead[S - 1], tile);
    if (!ew_op_report(op, p0 + 0.3 * dp)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    /* the radiance pyramid, then the filters coarse to fine */
    const ew_kpcn_tensor rad0 = {(float *)rad, 3, 3L * rs, 1};
    ew_kpcn_tensor prev = rad0;
    for (int sc = 1; sc < S; sc++) {
        ew_kpcn_pool_args pa = {s->sw[sc - 1], s->sh[sc - 1], s->sw[sc], s->sh[sc], 3, prev,
                                flat_t(s->rad[sc], s->sw[sc], s->sh[sc])};
        (void)EW_RUN(dev, kpcn_pool, &pa);
        prev = pa.dst;
    }
    /* the coarsest scale's filter */
    ew_kpcn_filter_args fa = filter_args(s, S - 1, 0, s->sh[S - 1], planes_t(&s->sb[S - 1], net->head[S - 1]));
    (void)EW_RUN(dev, kpcn_filter, &fa);
    /* ... the finer scales' ends in bands, coarse to fine ... */
    for (int k = S - 2; k >= 1 && r == EW_OK; k--) r = decode_scale(op, tile, k);
    if (r != EW_OK) return r;
    /* ... and scale 0's end in bands (kpcn.h): one tile writes the frame;
     * several write their region, and keep the core */
    const ew_kpcn_tensor o = {s->tile_out ? s->tile_out : tile_target(s, net), 3, 3L * rw, 1};
    for (int b0 = 0; b0 < rh && r == EW_OK; b0 += EW_KPCN_BAND_ROWS) {
        r = scale0_band(op, tile, &ia, b0, &rad0, &o, net->remod);
        const int done = b0 + EW_KPCN_BAND_ROWS < rh ? b0 + EW_KPCN_BAND_ROWS : rh;
        if (r == EW_OK && !ew_op_report(op, p0 + (0.3 + 0.65 * done / rh) * dp))
            return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    }
    /* the stage in streamed tiles blends each region; tiles over the
     * frame's planes (several passes: their mean is blended) leave it to
     * the frame's end (execute) */
    if (r == EW_OK && s->tile_out && s->streamed && ew_harm_fused(op)) return fused_core(op, tile);
    if (r == EW_OK && s->tile_out && s->held) /* the clamped radiance, read no more: the scratch */
        return ew_tile_writer_core(&s->tw, &s->tiling, tile, s->tile_out, s->clamped);
    if (s->tile_out) {
        const size_t row = (size_t)tile->cw * 3 * sizeof(float);
        for (int y = tile->cy; y < tile->cy + tile->ch && r == EW_OK; y++)
            r = dev->backend->mem_copy(dev, tile_target(s, net) + ((long)y * W + tile->cx) * 3,
                                       s->tile_out + ((long)(y - tile->ry) * rw + (tile->cx - tile->rx)) * 3, row);
    }
    return r;
}

/* Mirrors what the network and the filters read (the clamped radiance and
 * the features, the op's own copies with several passes) along one axis. */
static void mirror_inputs(ew_device *dev, const state *s, const float *radiance, int axis) {
    const ew_denoise_buffers *b = &s->buf;
    float *const planes[4] = {(float *)radiance, (float *)b->albedo, (float *)b->normal, (float *)b->depth};
    static const long channels[4] = {3, 3, 3, 1};
    for (int i = 0; i < 4; i++) {
        ew_mirror_swap_args a;
        memset(&a, 0, sizeof a);
        a.p = planes[i];
        a.channels = channels[i];
        a.width = b->width;
        a.height = b->height;
        a.axis = axis;
        a.dw = axis == 0 ? b->width / 2 : b->width;
        a.dh = axis == 0 ? b->height : b->height / 2;
        (void)EW_RUN(dev, mirror_swap, &a);
    }
}

/* The tiles of one run on the frame's clamped radiance; progress from p0
 * over the span dp. */
static ew_result run_tiles(ew_op *op, const float *radiance, float noise, double p0, double dp) {
    const state *s = (const state *)op->state;
    const ew_tiling *t = &s->tiling;
    const int ntiles = t->nx * t->ny;
    for (int i = 0; i < ntiles; i++) {
        ew_tile tile;
        ew_tile_at(t, i, &tile);
        const ew_result r = run_tile(op, radiance, t->width, 0, 0, noise, &tile, p0 + dp * i / ntiles, dp / ntiles);
        if (r != EW_OK) return r;
    }
    return EW_OK;
}

/* The features not read in place into the op's copies, and the depth
 * scale from the whole frame. */
static ew_result put_features(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const int w = b->width, h = b->height;
    const ew_image *av = ew_op_image(op, "albedo"), *nv = ew_op_image(op, "normal"), *dv = ew_op_image(op, "depth");
    ew_result r = EW_OK;
    /* (a feature read from halves in bands has no plane) */
    if (b->albedo && b->albedo != av->data) r = ew_dev_put_view(dev, av, 3, (float *)b->albedo, s->stage);
    if (r == EW_OK && b->normal && b->normal != nv->data) r = ew_dev_put_view(dev, nv, 3, (float *)b->normal, s->stage);
    if (r == EW_OK && b->depth && b->depth != dv->data) r = ew_dev_put_view(dev, dv, 1, (float *)b->depth, s->stage);
    /* each row's largest depth (row by row: in bands, the same) */
    const int step = b->depth ? h : feature_band_rows(s, w);
    for (int y = 0; y < h && r == EW_OK; y += step) {
        const int n = ew_mini(step, h - y);
        long rs; /* the frame's width: the whole rows */
        dev->backend->reduce_rows(dev, EW_REDUCE_DEPTH_MAX, w, n, feature_rows(op, 2, y, y + n, 0, w, &rs), s->row_out);
        r = dev->backend->mem_download(dev, s->rows + 2 * (size_t)y, s->row_out, (size_t)n * 2 * sizeof(double));
    }
    if (r != EW_OK) return r;
    double mx = 0.0;
    for (int y = 0; y < h; y++)
        if (s->rows[2 * y] > mx) mx = s->rows[2 * y];
    b->depth_scale = mx > 0.0 ? (float)(1.0 / mx) : 1.0f;
    return EW_OK;
}

/* Streamed: the demodulated radiance's firefly clamp of the frame's rows
 * y_begin .. y_end, columns x_begin .. x_end, band by band, each band read
 * with the clamp window's rows and columns around it (inside the frame: so
 * the same windows as over the frame). With dst, the clamped pixels into
 * dst (packed x_end - x_begin wide, its row 0 the frame's row y_begin). A
 * sweep (the whole frame): the light the clamp took into the stage's
 * plane, and the noise level's row sums of the clamped radiance into
 * s->rows (as the frame path's reduce_rows over it: each row's sum reads
 * that row and the one above, the band above's last, kept in band_above). */
static ew_result clamp_rect(ew_op *op, const float *color, int x_begin, int x_end, int y_begin, int y_end, float *dst,
                            int sweep) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    const ew_denoise_buffers *b = &s->buf;
    const int w = b->width, h = b->height, dw = x_end - x_begin;
    const float k = ew_op_param(op, "firefly_k");
    float *removed = sweep ? ew_harm_clamp_removed(op) : NULL;
    const size_t w3 = (size_t)w * 3, row_bytes = w3 * sizeof(float);
    const int margin = band_margin();
    const int c0 = ew_maxi(x_begin - margin, 0), c1 = ew_mini(x_end + margin, w), cw = c1 - c0;
    ew_result r = EW_OK;
    for (int y0 = y_begin; y0 < y_end && r == EW_OK; y0 += BAND_ROWS) {
        const int y1 = y0 + BAND_ROWS < y_end ? y0 + BAND_ROWS : y_end;
        const int e0 = y0 - margin > 0 ? y0 - margin : 0, e1 = y1 + margin < h ? y1 + margin : h;
        ew_denoise_buffers bb = *b;
        bb.width = cw;
        bb.height = e1 - e0;
        bb.color = color + ((size_t)e0 * w + (size_t)c0) * 3;
        bb.in_stride = w;
        long rs;
        bb.albedo = feature_rows(op, 0, e0, e1, c0, c1, &rs);
        if (rs != w) { /* albedo converted into its band, cw wide: the colour packed beside it */
            r = ew_dev_copy_rect(dev, s->band_clamped, cw, 0, 0, color, w, c0, e0, cw, e1 - e0, 3);
            bb.color = s->band_clamped;
            bb.in_stride = 0;
        }
        bb.normal = bb.depth = NULL; /* the guide it writes goes unread: the clamp reads the radiance alone */
        bb.radiance = s->band_rad;
        bb.guide = s->band_guide;
        if (r == EW_OK) dev->backend->denoise_prepare(dev, &bb); /* radiance = colour / (albedo + eps) */
        const ew_outlier_params fp = ew_kpcn_clamp_params(cw, e1 - e0, k);
        const ew_outlier_buffers fb = {s->band_rad, NULL, NULL, s->band_clamped, 3, removed ? s->band_removed : NULL};
        if (r == EW_OK) dev->backend->outlier_guided(dev, &fp, &fb);
        if (r == EW_OK && dst)
            r = ew_dev_copy_rect(dev, dst, dw, 0, y0 - y_begin, s->band_clamped, cw, x_begin - c0, y0 - e0, dw, y1 - y0, 3);
        /* a sweep's bands are the frame's whole rows */
        float *core = s->band_clamped + (size_t)(y0 - e0) * w3;
        if (r == EW_OK && removed)
            r = ew_dev_copy_sparse(dev, removed + (size_t)y0 * w, s->band_removed + (size_t)(y0 - e0) * w,
                                   (size_t)(y1 - y0) * w);
        if (r == EW_OK && sweep && s->net.noise) {
            /* the row above the band's first (which gives nothing itself)
             * is the band above's, exact there and not in this band's
             * margin: it goes where the margin's was */
            const int n0 = y0 > 0 ? y0 - 1 : 0;
            if (y0 > 0) r = dev->backend->mem_copy(dev, core - w3, s->band_above, row_bytes);
            if (r == EW_OK) {
                dev->backend->reduce_rows(dev, EW_REDUCE_NOISE, w, y1 - n0, core - (size_t)(y0 - n0) * w3, s->row_out);
                r = dev->backend->mem_download(dev, s->rows + 2 * (size_t)y0, s->row_out + 2 * (size_t)(y0 - n0),
                                               (size_t)(y1 - y0) * 2 * sizeof(double));
            }
            if (r == EW_OK) r = dev->backend->mem_copy(dev, s->band_above, core + (size_t)(y1 - y0 - 1) * w3, row_bytes);
        }
    }
    return r;
}

/* Streamed (above): the sweep, then each row of tiles on its rows of
 * clamped radiance, each core into the output view (or the op's plane,
 * copied out) */
static ew_result execute_streamed(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const ew_kpcn_net *net = &s->net;
    const ew_image *cv = ew_op_image(op, "color"), *ov = ew_op_image(op, "output");
    /* read before any core is written: in place even under the output */
    const float *color = ew_dev_view_in_place(dev, cv, 3, NULL);
    ew_result r = EW_OK;
    if (!color) {
        color = s->fcolor;
        r = ew_dev_put_view(dev, cv, 3, s->fcolor, s->stage);
    }
    if (r == EW_OK) r = put_features(op);
    /* the sweep gives nothing when neither the noise level nor the clamp's light is wanted */
    if (r == EW_OK && (net->noise || ew_harm_clamp_removed(op)))
        r = clamp_rect(op, color, 0, b->width, 0, b->height, NULL, 1);
    if (r != EW_OK) return r;
    const float noise = net->noise ? ew_kpcn_noise_from_rows(s->rows, b->height) : 0.0f;
    float *target = (float *)ew_dev_view_in_place(dev, ov, 3, NULL);
    if (!target) target = s->target;
    b->out = b->sliced = target; /* tile_target, and finished in place */
    s->tw.dev = dev;
    s->tw.out = ov;
    s->tw.stage = s->stage;
    s->tw.held.cw = 0;
    s->held = output_over_color(op);
    /* each region's clamped radiance from the colour where it lies: with
     * the output over it, the tile writer holds back the cores' pixels a
     * later region reads until it has (writer_keep) */
    const ew_tiling *t = &s->tiling;
    const int ntiles = t->nx * t->ny;
    for (int i = 0; i < ntiles && r == EW_OK; i++) {
        ew_tile tile;
        ew_tile_at(t, i, &tile);
        r = clamp_rect(op, color, tile.rx, tile.rx + tile.rw, tile.ry, tile.ry + tile.rh, s->clamped, 0);
        if (r == EW_OK)
            r = run_tile(op, s->clamped, tile.rw, tile.rx, tile.ry, noise, &tile, (double)i / ntiles, 1.0 / ntiles);
    }
    /* out = filtered * (albedo + eps) (fused: each tile's) */
    if (r == EW_OK && !net->remod && !ew_harm_fused(op)) finish_rows(op, 0, 0, b->width, b->height, target);
    if (r == EW_OK && target == s->target) r = ew_dev_get_view(dev, target, 3, ov, s->stage);
    /* as the frame path's: nothing here is read before it is written again */
    ew_dev_release_pages(dev, s->fcolor, (char *)s->dmem.mem + s->dmem.bytes);
    return r;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    if (s->streamed) return execute_streamed(op);
    ew_device *dev = op->dev;
    ew_denoise_buffers *b = &s->buf;
    const ew_kpcn_net *net = &s->net;
    const int w = b->width, h = b->height;
    ew_result r = ew_dev_put_view(dev, ew_op_image(op, "color"), 3, (float *)b->color, s->stage);
    if (r == EW_OK) r = put_features(op);
    if (r != EW_OK) return r;
    dev->backend->denoise_prepare(dev, b); /* radiance = colour / (albedo + eps) */
    const float k = ew_op_param(op, "firefly_k");
    /* the shared outlier definition (kernels/outlier.h), plain statistics;
     * it also rebuilds NaN/Inf samples from their neighbours even with the
     * clamp off (k 0), since the kernels are convex combinations of the
     * radiance: one non-finite tap would blank its whole neighbourhood */
    const ew_outlier_params fp = ew_kpcn_clamp_params(w, h, k);
    const ew_outlier_buffers fb = {b->radiance, NULL, NULL, s->clamped, 3, ew_harm_clamp_removed(op)};
    dev->backend->outlier_guided(dev, &fp, &fb);
    float *radiance = s->clamped;
    float noise = 0.0f;
    if (net->noise) { /* the frame's noise level, as the trainer's ew_kpcn_frame_noise */
        dev->backend->reduce_rows(dev, EW_REDUCE_NOISE, w, h, radiance, s->row_out);
        r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)h * 2 * sizeof(double));
        if (r != EW_OK) return r;
        noise = ew_kpcn_noise_from_rows(s->rows, h);
    }
    /* the filtered radiance goes where the radiance the filters do not read was */
    b->sliced = radiance == b->radiance ? s->clamped : b->radiance;
    /* The runs' mirrors (x, y), the unmirrored one last: it leaves the
     * inputs as they came, and its output is where the sum goes. */
    static const int mirrors[4][2] = {{1, 0}, {1, 1}, {0, 1}, {0, 0}};
    const int passes = s->acc ? passes_of(op) : 1;
    int at[2] = {0, 0};
    for (int i = 0; i < passes && r == EW_OK; i++) {
        const int *m = mirrors[i == passes - 1 ? 3 : i];
        for (int axis = 0; axis < 2; axis++)
            if (m[axis] != at[axis]) {
                mirror_inputs(dev, s, radiance, axis);
                at[axis] = m[axis];
            }
        r = run_tiles(op, radiance, noise, (double)i / passes, 1.0 / passes);
        if (r == EW_OK && passes > 1) {
            ew_mirror_add_args a;
            memset(&a, 0, sizeof a);
            a.out = tile_target(s, net);
            a.acc = s->acc;
            a.width = w;
            a.height = h;
            a.mx = m[0];
            a.my = m[1];
            a.mode = i == 0 ? EW_MIRROR_FIRST : i == passes - 1 ? EW_MIRROR_LAST : EW_MIRROR_MORE;
            a.scale = 1.0f / (float)passes;
            (void)EW_RUN(dev, mirror_add, &a);
        }
    }
    if (r != EW_OK) return r;
    if (!net->remod) dev->backend->denoise_finish(dev, b); /* out = filtered * (albedo + eps) */
    if (ew_harm_fused(op)) {
        /* the stage in the tiles, here one region: the frame's blend on the
         * clamped colour its view holds (the output goes there only below) */
        const float *color = ew_dev_view_in_place(dev, ew_op_image(op, "color"), 3, NULL);
        r = ew_harm_region_done(op, 0, 0, w, h, color, b->out, ew_harm_clamp_removed(op));
        if (r != EW_OK) return r;
    }
    /* the frame's buffers and the regions' are written again before they
     * are read at the next execute (the parameters before them stay; the
     * planes' zero padding comes back as zeros): the do-no-harm stage's
     * statistics need not sit on top of them. All but the output go before
     * it is copied out, so the caller's output view (untouched until now
     * when it is fresh memory) is not resident under them either. */
    const size_t n3 = (size_t)w * (size_t)h * 3;
    ew_dev_release_pages(dev, b->out + n3, (char *)s->dmem.mem + s->dmem.bytes);
    r = ew_dev_get_view(dev, b->out, 3, ew_op_image(op, "output"), s->stage);
    ew_dev_release_pages(dev, b->out, b->out + n3);
    return r;
}

static const char *describe(const ew_op *op) {
    const state *s = (const state *)op->state;
    return s ? s->choice : NULL;
}

/* ew_op_image_flags: a half feature is read where it is in streamed tiles
 * (whole frames pack it, as they pack float views they cannot read) */
static int reads_half(const ew_op *op, const char *image) {
    (void)image;
    const state *s = (const state *)op->state;
    return s && s->streamed;
}

/* device_memory: every buffer comes from ew_dev_alloc and only the views
 * cross between host and device, so it runs on a CUDA device too. */
const ew_op_type ew_denoise_kpcn = {
    .kind = "denoiser",
    .name = "kpcn",
    .summary = "kernel-predicting network: a U-Net over three scales (four for kpcn-large) predicts per-pixel 5x5 "
               "softmax kernels that filter the albedo-demodulated radiance at each scale, blended coarse to fine",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .memory = memory,
    .stage_in_tiles = 1,
    .set_data = set_data,
    .release_data = ew_net_model_release,
    .device_memory = 1,
    .describe = describe,
    .choices = (const ew_param_choices[]){{"model", ew_kpcn_model_names}, {NULL, NULL}},
    .inplace_inputs = (const char *const[]){"color", NULL},
    /* tiled on the CPU they are read in bands of rows (feature_rows);
     * otherwise put_features packs them as it packs float views */
    .half_inputs = (const char *const[]){"albedo", "normal", "depth", NULL},
    .reads_half = reads_half,
    .data_params = (const char *const[]){"model", "weights", NULL},
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_denoise_kpcn, 40);
