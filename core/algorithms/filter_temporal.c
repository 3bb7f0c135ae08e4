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
    {"vector", 2, 0, "motion in pixels per frame towards the previous frame (Cycles Vector.XY)"},
    {"output", 3, 1, "accumulated colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"alpha_min", EW_PARAM_FLOAT, 0.2f, 0.01f, 1.0f, "smallest weight of the current frame (1 = no accumulation)"},
    {"normal_cos", EW_PARAM_FLOAT, 0.9f, -1.0f, 1.0f, "history whose normal has a smaller cosine to the current one is rejected"},
    {"depth_rel", EW_PARAM_FLOAT, 0.1f, 0.0f, 10.0f, "history whose depth differs by more than this fraction is rejected"},
    {"motion_sign", EW_PARAM_INT, 1.0f, -1.0f, 1.0f, "+1: previous position = pixel + vector (Cycles); -1: pixel - vector"},
    {"max_frames", EW_PARAM_INT, 32.0f, 1.0f, 100000.0f, "cap of the history length"},
    {"clamp", EW_PARAM_FLOAT, 0.0f, 0.0f, 100.0f,
     "clamp the history to the frame's 3x3 mean +- this many standard deviations per channel (variance clipping "
     "against ghosting, for an already denoised frame; 0: off)"},
    {"reset", EW_PARAM_BOOL, 0.0f, 0.0f, 1.0f, "1: drop the history at the next commit (then reads 0 again)"},
};

typedef struct {
    int width, height, valid;
    int has_normal, has_depth;
    /* current-frame copies and two history generations */
    float *color, *normal, *depth, *motion;
    float *hist_color[2], *hist_normal[2], *hist_depth[2], *hist_len[2];
    int cur; /* index of the newest history */
    float mem[];
} state;

typedef struct {
    const ew_temporal_params *p;
    const ew_temporal_buffers *b;
    float gamma;
} clip_job;

static void clip_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const clip_job *j = (const clip_job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p->width; x++) ew_temporal_clipped_px(x, (int)y, j->p, j->b, j->gamma);
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
    free(s);
    const size_t n = (size_t)w * h;
    const size_t floats = n * (3 + 3 + 1 + 2) + 2 * n * (3 + 3 + 1 + 1);
    s = (state *)calloc(1, sizeof(state) + floats * sizeof(float));
    op->state = s;
    if (!s) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory for temporal history of %dx%d", w, h);
    s->width = w;
    s->height = h;
    s->has_normal = has_n;
    s->has_depth = has_d;
    float *m = s->mem;
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
    ew_view_pack(ew_op_image(op, "color"), 3, s->color);
    if (nv) ew_view_pack(nv, 3, s->normal);
    if (dv) ew_view_pack(dv, 1, s->depth);
    if (vv) ew_view_pack(vv, 2, s->motion);
    const int prev = s->cur, next = 1 - s->cur;
    ew_temporal_params p;
    p.width = s->width;
    p.height = s->height;
    p.alpha_min = ew_op_param(op, "alpha_min");
    p.normal_cos = ew_op_param(op, "normal_cos");
    p.depth_rel = ew_op_param(op, "depth_rel");
    p.motion_sign = ew_op_param(op, "motion_sign") < 0.0f ? -1.0f : 1.0f;
    p.max_frames = ew_op_param(op, "max_frames");
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
    const float gamma = ew_op_param(op, "clamp");
    if (gamma > 0.0f) { /* CPU only, like the rest of this op (device_memory 0): the backend entry has no clamp */
        clip_job cj = {&p, &b, gamma};
        ew_pool_run(dev->pool, s->height, 0, clip_rows, &cj);
    } else {
        dev->backend->temporal(dev, &p, &b);
    }
    const size_t n = (size_t)s->width * s->height;
    if (nv) memcpy(s->hist_normal[next], s->normal, n * 3 * sizeof(float));
    if (dv) memcpy(s->hist_depth[next], s->depth, n * sizeof(float));
    s->cur = next;
    s->valid = 1;
    ew_view_unpack(s->hist_color[next], 3, ew_op_image(op, "output"));
    return EW_OK;
}

static void release(ew_op *op) { free(op->state); }

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
    .device_memory = 0, /* issue 8: not ported yet, CPU devices only */
};
