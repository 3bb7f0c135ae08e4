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
#include "src/op.h"

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
 * allocation made at commit (docs/backends.md): the history never leaves
 * the device between frames. */
typedef struct {
    int width, height, valid;
    int has_normal, has_depth;
    float *dmem, *stage; /* stage: host staging in host[], or NULL when views need none */
    float *color, *normal, *depth, *motion;
    float *hist_color[2], *hist_normal[2], *hist_depth[2], *hist_len[2];
    int cur; /* index of the newest history */
    float host[];
} state;

static void release(ew_op *op) {
    state *s = (state *)op->state;
    if (s) ew_dev_free(op->dev, s->dmem);
    free(s);
    op->state = NULL;
}

static ew_result commit(ew_op *op) {
    ew_device *dev = op->dev;
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
    const size_t n = (size_t)w * h;
    const size_t floats = n * (3 + 3 + 1 + 2) + 2 * n * (3 + 3 + 1 + 1);
    const size_t stage = ew_dev_stage_floats(dev, n, 3); /* the widest view moved */
    s = (state *)calloc(1, sizeof(state) + stage * sizeof(float));
    if (s) s->dmem = (float *)ew_dev_alloc(dev, floats * sizeof(float));
    op->state = s;
    if (!s || !s->dmem)
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory for temporal history of %dx%d (%.1f MiB)", w, h,
                        (double)(floats + stage) * sizeof(float) / 1048576.0);
    s->width = w;
    s->height = h;
    s->has_normal = has_n;
    s->has_depth = has_d;
    s->stage = stage ? s->host : NULL;
    float *m = s->dmem;
    s->color = m; m += n * 3;
    s->normal = m; m += n * 3;
    s->depth = m; m += n;
    s->motion = m; m += n * 2;
    for (int g = 0; g < 2; g++) {
        s->hist_color[g] = m; m += n * 3;
        s->hist_normal[g] = m; m += n * 3;
        s->hist_depth[g] = m; m += n;
        s->hist_len[g] = m; m += n;
    }
    return EW_OK;
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    const ew_image *nv = ew_op_image(op, "normal"), *dv = ew_op_image(op, "depth"), *vv = ew_op_image(op, "vector");
    ew_result r = ew_dev_put_view(dev, ew_op_image(op, "color"), 3, s->color, s->stage);
    if (r == EW_OK && nv) r = ew_dev_put_view(dev, nv, 3, s->normal, s->stage);
    if (r == EW_OK && dv) r = ew_dev_put_view(dev, dv, 1, s->depth, s->stage);
    if (r == EW_OK && vv) r = ew_dev_put_view(dev, vv, 2, s->motion, s->stage);
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
    if (r == EW_OK) r = ew_dev_get_view(dev, s->hist_color[next], 3, ew_op_image(op, "output"), s->stage);
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
