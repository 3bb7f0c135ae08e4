/*
 * filter_temporal.c — filter "temporal": accumulates a sequence frame by
 * frame with reprojection (kernels/temporal.h). The history lives in the
 * filter between executes: set the frame's images, commit, execute, once
 * per frame in order. A new size, or the "reset" trigger, starts over.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/backend.h"
#include "kernels/temporal.h"
#include "src/op_mem.h"

static const ew_image_desc images[] = {
    {"color", 3, 1, "the frame's colour (demodulated radiance works best)"},
    {"normal", 3, 0, "normals, for rejecting history across edges"},
    {"depth", 1, 0, "depth, for rejecting disoccluded history"},
    {"vector", 2, 0, "motion in pixels per frame towards the previous frame, as Cycles writes Vector.XY: previous "
                     "position = (x + X, y - Y) with rows top first (its y axis points up)"},
    {"output", 3, 1, "accumulated colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"alpha_min", EW_PARAM_FLOAT, 0.2f, 0.01f, 1.0f, "smallest weight of the current frame (1 = no accumulation)"},
    {"normal_cos", EW_PARAM_FLOAT, 0.9f, -1.0f, 1.0f, "history whose normal has a smaller cosine to the current one is rejected"},
    {"depth_rel", EW_PARAM_FLOAT, 0.1f, 0.0f, 10.0f, "history whose depth differs by more than this fraction is rejected"},
    {"motion_sign", EW_PARAM_INT, 1.0f, -1.0f, 1.0f, "+1: Cycles' Vector pass, previous position = (x + X, y - Y) with rows top first; -1: both negated"},
    {"max_frames", EW_PARAM_INT, 32.0f, 1.0f, 100000.0f, "cap of the history length"},
    {"clamp", EW_PARAM_FLOAT, 0.0f, 0.0f, 100.0f,
     "clamp the history to the frame's 3x3 mean +- this many standard deviations per channel (variance clipping "
     "against ghosting, for an already denoised frame; 0: off)"},
    {"reset", EW_PARAM_BOOL, 0.0f, 0.0f, 1.0f, "1: drop the history at the next commit (then reads 0 again)"},
};

/* The current frame's copies and two history generations, in one device
 * allocation made at commit (src/op_mem.h): the history never leaves the
 * device between frames. */
typedef struct {
    int width, height, valid;
    int has_normal, has_depth;
    ew_op_mem mem;
    float *color, *normal, *depth, *motion;
    float *hist_color[2], *hist_normal[2], *hist_depth[2], *hist_len[2];
    int cur; /* index of the newest history */
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) ew_op_mem_free(op, &s->mem);
    free(s);
    op->state = NULL;
}

static ew_result commit(ew_op *op) {
    const ew_image *c = ew_op_image(op, "color");
    const int w = c->width, h = c->height;
    const int has_n = ew_op_image(op, "normal") != NULL, has_d = ew_op_image(op, "depth") != NULL;
    state *s = (state *)op->state;
    const int reset = ew_op_param(op, "reset") != 0.0f;
    ew_op_param_put(op, "reset", 0.0f); /* the trigger fires once */
    if (s && s->width == w && s->height == h && s->has_normal == has_n && s->has_depth == has_d) {
        if (reset) s->valid = 0;
        return EW_OK;
    }
    release(op);
    s = (state *)calloc(1, sizeof(state));
    op->state = s;
    if (!s) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
    const size_t n = (size_t)w * h;
    const ew_op_buf bufs[] = {
        {&s->color, n * 3},          {&s->normal, n * 3},         {&s->depth, n},
        {&s->motion, n * 2},         {&s->hist_color[0], n * 3},  {&s->hist_normal[0], n * 3},
        {&s->hist_depth[0], n},      {&s->hist_len[0], n},        {&s->hist_color[1], n * 3},
        {&s->hist_normal[1], n * 3}, {&s->hist_depth[1], n},      {&s->hist_len[1], n},
    };
    const ew_result r = ew_op_mem_alloc(op, &s->mem, bufs, (int)(sizeof bufs / sizeof bufs[0]), 3);
    if (r != EW_OK) return r;
    s->width = w;
    s->height = h;
    s->has_normal = has_n;
    s->has_depth = has_d;
    return EW_OK;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    const ew_image *nv = ew_op_image(op, "normal"), *dv = ew_op_image(op, "depth"), *vv = ew_op_image(op, "vector");
    ew_result r = ew_op_put(op, &s->mem, "color", 3, s->color);
    if (r == EW_OK) r = ew_op_put(op, &s->mem, "normal", 3, s->normal);
    if (r == EW_OK) r = ew_op_put(op, &s->mem, "depth", 1, s->depth);
    if (r == EW_OK) r = ew_op_put(op, &s->mem, "vector", 2, s->motion);
    if (r != EW_OK) return r;
    const int prev = s->cur, next = 1 - s->cur;
    ew_temporal_params p;
    p.width = s->width;
    p.height = s->height;
    p.alpha_min = ew_op_param(op, "alpha_min");
    p.normal_cos = ew_op_param(op, "normal_cos");
    p.depth_rel = ew_op_param(op, "depth_rel");
    p.motion_sign = ew_op_param(op, "motion_sign") < 0.0f ? -1.0f : 1.0f;
    p.max_frames = ew_op_param(op, "max_frames");
    p.clamp = ew_op_param(op, "clamp");
    ew_temporal_buffers b;
    b.color = s->color;
    b.normal = nv ? s->normal : NULL;
    b.depth = dv ? s->depth : NULL;
    b.motion = vv ? s->motion : NULL;
    b.prev_color = s->hist_color[prev];
    b.prev_normal = nv ? s->hist_normal[prev] : NULL;
    b.prev_depth = dv ? s->hist_depth[prev] : NULL;
    b.prev_len = s->valid ? s->hist_len[prev] : NULL;
    b.out_color = s->hist_color[next];
    b.out_len = s->hist_len[next];
    dev->backend->temporal(dev, &p, &b);
    const size_t n = (size_t)s->width * s->height;
    if (nv) r = dev->backend->mem_copy(dev, s->hist_normal[next], s->normal, n * 3 * sizeof(float));
    if (r == EW_OK && dv) r = dev->backend->mem_copy(dev, s->hist_depth[next], s->depth, n * sizeof(float));
    if (r == EW_OK) r = ew_op_get(op, &s->mem, s->hist_color[next], 3, "output");
    /* a failed frame leaves the history as it was */
    if (r != EW_OK) return r;
    s->cur = next;
    s->valid = 1;
    return EW_OK;
}

const ew_op_type ew_filter_temporal = {
    .kind = "filter",
    .name = "temporal",
    .summary = "temporal accumulation with reprojection along motion vectors and normal/depth rejection; keeps its "
    "history between executes",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .device_memory = 1,
    .inplace_inputs = (const char *const[]){"color", NULL},
};
EW_REGISTER_OP(ew_filter_temporal, 100);
