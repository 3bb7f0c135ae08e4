/*
 * harm_stage.c — the do-no-harm stage the op layer runs around every
 * denoiser (and every filter a caller uses as one), so that a method never
 * hands back a frame clearly worse than the one it was given, and a new
 * method gets it without a line of its own:
 *
 *   1. extreme-outlier rejection before the method (parameter outlier_k):
 *      in albedo-demodulated radiance, a sample far above the median of the
 *      neighbours of its own surface (median + k x 1.4826 MAD, kernels/
 *      outlier.h) is scaled down to that bound. The spread has two floors:
 *      a share of the median (ordinary noise of a smooth surface is never
 *      touched) and a share of the frame's mean radiance (a dark, flat
 *      region at 1-2 spp gets most of its light as sparse bright samples:
 *      they carry its energy and stay). What is left to clamp is the rare
 *      sample hundreds of times brighter than everything around it, whose
 *      energy the frame would otherwise over-represent by orders of
 *      magnitude (one such sample at 4 spp lifted a frame's mean to 1.7x).
 *      A pixel that alone saw a light smaller than itself, whose albedo the
 *      hit lifted with its colour, is judged in colour (kernels/outlier.h).
 *      A filter used as a denoiser then gets the denoisers' own firefly
 *      clamp too (mean + 3 sigma, kernels/outlier.h), which it lacks: its
 *      colour edge-stopping keeps a bright sample where it is.
 *   2. the do-no-harm blend after it (parameter do_no_harm): output = input
 *      + alpha (output - input), alpha = 1 - C / R from the residual's
 *      energy R and its neighbour correlation C over a window
 *      (kernels/harm.h says why that estimates the blend of least error).
 *      The input blended toward is the input after step 1, so a rejected
 *      firefly does not come back. On a frame of low noise (most of
 *      16-64 spp, where a method's harm is what is left of its error)
 *      with albedo, normal and depth, a second estimate from a pilot: kpcn
 *      run on the same input, with a stage of its own (kernels/harm.h, "The
 *      pilot"); not for kpcn itself.
 *   3. energy return: the light the method's own firefly_k clamp took
 *      (recorded through ew_harm_clamp_removed, or the stage's firefly
 *      clamp for a filter) is given back over a 49x49 window in proportion
 *      to the output there; what step 1 took (at most twice what it left)
 *      to the whole frame in proportion to the output, as one gain
 *      (kernels/harm.h says why). The method still reads the clamped colour
 *      it was trained on (kpcn's input preparation is unchanged).
 *
 * All run on the op's device through the backend's `harm` and
 * `outlier_guided` entries, in buffers allocated at commit. With both
 * parameters at 0 the op runs exactly as it would without the stage.
 * With the output written over the colour, a method that can runs the
 * stage inside its tiles instead (fusable, below): the same bits, and no
 * frame of RGB of the stage's own.
 */
#include <string.h>

#include "kernels/half.h"
#include "kernels/harm.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "src/backend.h"
#include "src/op.h"

/* Chosen on the training scenes of BENCHMARKS.md (never the test scenes). */
#include <stdlib.h>
#define HARM_OUTLIER_K 8.0f       /* the parameter's default */
#define HARM_OUTLIER_RADIUS 2     /* 5x5, as the denoisers' own clamp */
#define HARM_SIGMA_FLOOR 0.5f     /* spread >= this x the neighbours' median */
#define HARM_MEAN_FLOOR 2.0f      /* spread >= this x the frame's mean radiance */
#define HARM_ALBEDO_TOL 0.1f      /* as the "outlier" filter */
#define HARM_NORMAL_COS 0.9f
#define HARM_EMITTER_ALBEDO 16.0f /* an albedo no surface has (1 spp through glass: up to 20, judged too) */
#define HARM_BLEND_RADIUS 4       /* 9x9 window of residual statistics */
#define HARM_BLEND_STRENGTH 2.0f  /* C under-counts D (kernels/harm.h) */
#define HARM_BLEND_Z 1.0f         /* C counts above 1 standard deviation of its own */
#define HARM_BLEND_THETA 0.4f     /* no blend while D is below 0.4 of N + D */
#define HARM_BLEND_KAPPA 1.0f     /* the residual's Haar detail is all noise */
#define HARM_BLEND_THETA_N 0.2f   /* ... no blend from it while D is below 0.2 of R (1 spp: random) */
#define HARM_QUIET_NOISE 0.007    /* a frame of noise level (EW_REDUCE_NOISE) up to this: theta_n 0 ... */
#define HARM_NOISY_NOISE 0.011    /* ... from this: theta_n as above, in between a ramp */
#define HARM_QUIET_KAPPA 0.85f    /* on a quiet frame a share of H is the method's own error */
#define HARM_FADE_NOISE 0.025     /* from this noise level the blend fades ... */
#define HARM_OFF_NOISE 0.04       /* ... to none at this one */
#define HARM_PILOT_NOISE 0.016    /* the pilot's share from 0 at this noise level to 1 at HARM_NOISY_NOISE */
#define HARM_REJECT_KEEP 0.75     /* a rejection that took more of the frame's mean runs again */
#define HARM_GIVE_RADIUS 24       /* the method's clamp's light comes back over 49x49 pixels */
#define HARM_GIVE_LIMIT 30.0      /* a pixel gives back at most 30x the output frame's mean luminance */
#define HARM_GIVE_GAIN 0.5f       /* and no pixel grows by more than half */
#define HARM_GIVE_CAP 2.0f        /* of the rejection's share: at most 2x the luminance it left */
#define HARM_TAKE_LIMIT 50.0      /* ... and 50x the output frame's mean luminance, to the whole frame */
#define HARM_TAKE_GAIN 0.5        /* which grows by at most half */
#define HARM_FIREFLY_K 3.0f       /* the denoisers' firefly_k default, for a method without that clamp */
#define HARM_PILOT_METHOD "kpcn"  /* the pilot: kpcn's default model (16 channels) */
#define HARM_PILOT_MEMORY_MB 256  /* its max_memory_mb: tiles beyond that (the same output) */
#define HARM_BAND_ROWS 64         /* fused: the rows the passes before the method take at a time */
#define HARM_BAND_MARGIN 2        /* ... and above and below them, what the rejection's 5x5 window reads */

static const ew_param_desc stage_on[] = {
    {"do_no_harm", EW_PARAM_BOOL, 1.0f, 0.0f, 1.0f,
     "blend the result toward the input where it differs from the input by more than the input's noise "
     "explains (detail a converged frame already had). With albedo, normal and depth, on a frame of low noise "
     "(most frames of 16 samples or more), a method other than kpcn is also compared with kpcn run on the same "
     "input, which tells noise from detail for about kpcn's time; 0: the method's output as it is"},
    {"outlier_k", EW_PARAM_FLOAT, HARM_OUTLIER_K, 0.0f, 1000.0f,
     "before the method, scale isolated extreme samples (fireflies) down to the median + k spreads of the "
     "neighbours of their own surface, in albedo-demodulated radiance; 0 turns it off"},
};
/* Filters smooth on purpose (depth of field, a base layer): the stage is
 * there for a caller that uses one as a denoiser, off by default. */
static const ew_param_desc stage_off[] = {
    {"do_no_harm", EW_PARAM_BOOL, 0.0f, 0.0f, 1.0f,
     "when the filter is used as a denoiser: blend the result toward the input where it differs from the "
     "input by more than the input's noise explains; 0 (default): the filter's output as it is"},
    {"outlier_k", EW_PARAM_FLOAT, 0.0f, 0.0f, 1000.0f,
     "when the filter is used as a denoiser: before it, scale isolated extreme samples (fireflies) down to "
     "the median + k spreads of their neighbours (8 is the denoisers' default), then clamp what is left as the "
     "denoisers do (above the 5x5 mean + 3 standard deviations), giving the light back after the filter; 0 "
     "(default) turns it off"},
};
#define STAGE_PARAMS ((int)(sizeof stage_on / sizeof stage_on[0]))

static int has_stage(const ew_op_type *t) { return !strcmp(t->kind, "denoiser") || t->denoises; }

int ew_op_type_num_params(const ew_op_type *t) { return t->num_params + (has_stage(t) ? STAGE_PARAMS : 0); }

const ew_param_desc *ew_op_type_param(const ew_op_type *t, int i) {
    if (i < 0) return NULL;
    if (i < t->num_params) return &t->params[i];
    if (!has_stage(t) || i >= t->num_params + STAGE_PARAMS) return NULL;
    return strcmp(t->kind, "denoiser") ? &stage_off[i - t->num_params] : &stage_on[i - t->num_params];
}

void ew_harm_forward(const ew_op *from, ew_op *to) {
    for (int i = 0; i < STAGE_PARAMS; i++)
        ew_op_param_put(to, stage_on[i].name, ew_op_param(from, stage_on[i].name));
}

typedef struct ew_harm_state {
    int w, h, cc, has_a, has_n, pre;
    int own;        /* which of colour (1), albedo (2), normal (4) the stage packs itself (else the view in place) */
    int kept;       /* the rejection's excess is kept (the output overwrites the colour read in place) */
    void *dmem;
    size_t dmem_bytes;
    float *col, *alb, *nrm, *a, *b, *clamped;
    float *excess;  /* kept: the luminance the rejection took, a float a pixel (kernels/harm.h EW_HARM_EXCESS) */
    int can_fuse;   /* the method may run the stage in its tiles (fusable) */
    int fused;      /* ... and does, in this execute */
    int blend;      /* fused: the regions are blended (do_no_harm, a frame not faded out) */
    ew_harm_args region; /* fused: the blend's arguments but a region's buffers */
    const unsigned short *pilot; /* fused, in this execute: the pilot's output in T as halves (host, 3 a
                                    pixel; pilot_tone), or NULL */
    float pilot_share;
    float *pregion;      /* ... a region's copy of it as floats (PILOT_SQ rewrites it), grown as regions ask */
    size_t pregion_floats;
    float *band;    /* can_fuse: two bands of rows of 3 floats a pixel for the passes before the method */
    int half;       /* can_fuse: albedo (2), normal (4) read from half views a band at a time (not own) */
    float *fband[2]; /* ... into these: albedo's, normal's rows fband_y0 .. fband_y1 */
    int fband_y0[2], fband_y1[2];
    float *fed;     /* the colour the method reads: clamped, or (pre 2) that after the firefly clamp too */
    float *removed; /* the share of each pixel the firefly clamp took, a float a pixel (the method's own
                       through ew_harm_clamp_removed, or the stage's for a filter), then what comes back */
    double *row_out;
    float *stage;   /* host staging for views, or NULL */
    float *hclamp;  /* host copy of the clamped colour handed to a method on a device with memory of its own */
    double *rows;   /* host: row sums */
    double host[];  /* rows, stage, hclamp */
} ew_harm_state;

void ew_harm_release(ew_op *op) {
    ew_harm_state *s = (ew_harm_state *)op->harm;
    if (s) {
        ew_dev_free(op->dev, s->dmem);
        free(s->pregion);
    }
    free(s);
    op->harm = NULL;
}

static int slot(const ew_op *op, const char *name) {
    for (int i = 0; i < op->type->num_images; i++)
        if (!strcmp(op->type->images[i].name, name)) return op->has_image[i] ? i : -1;
    return -1;
}

/* Floats a pixel of the rejected colour the method reads: a denoiser reads
 * RGB only, so its copy has no alpha (and a method on the CPU reads it in
 * place, packed as it packs its own); a filter used as a denoiser may
 * filter alpha too (op_alpha.c). */
static int clamped_channels(int cc, int pre) { return pre == 1 ? 3 : cc; }

/* Floats of a band of rows of 3 floats a pixel of a frame w wide (fused) */
static size_t band_floats(int w) { return (size_t)(HARM_BAND_ROWS + 2 * HARM_BAND_MARGIN) * (size_t)w * 3; }

/* The stage's device floats for a colour of cc channels (see the commit);
 * own: which of colour, albedo, normal it packs itself; kept: the
 * rejection's excess plane; fuse: two bands of a frame w wide, and one
 * for each feature read from halves (half). */
static size_t stage_floats(size_t n, int cc, int has_a, int has_n, int pre, int own, int kept, int fuse, int half,
                           int w) {
    return n * ((own & 1 ? (size_t)cc : 0) + 3 * ((size_t)(has_a && (own & 2)) + (size_t)(has_n && (own & 4))) + 3 +
                EW_HARM_STATS_FLOATS + (size_t)pre * (size_t)clamped_channels(cc, pre) + 1 + (size_t)kept) +
           (fuse ? (2 + (size_t)(has_a && (half & 2)) + (size_t)(has_n && (half & 4))) * band_floats(w) : 0);
}

/* Colour, albedo and normal read from the caller's views where they are
 * (ew_dev_view_in_place). After the method the stage reads the colour only
 * for what the rejection took (TAKE); with a rejection (pre) that is kept
 * in a plane of one float a pixel before the method (*kept), so the colour
 * is read in place even where the output overlaps it: a caller writing the
 * result over its colour holds one frame of RGB, not two, and the stage no
 * copy of it. Without one it is read in place only where the output does
 * not overlap it (the blend reads it too). */
static int views_in_place(const ew_op *op, int cc, int pre, const float *in[3], int *kept) {
    const ew_image *o = ew_op_image(op, "output"), *c = ew_op_image(op, "color");
    in[0] = ew_dev_view_in_place(op->dev, c, cc, pre ? NULL : o);
    in[1] = ew_dev_view_in_place(op->dev, ew_op_image(op, "albedo"), 3, o);
    in[2] = ew_dev_view_in_place(op->dev, ew_op_image(op, "normal"), 3, o);
    *kept = in[0] && o && ew_images_overlap(c, o);
    return (in[0] ? 0 : 1) | (in[1] ? 0 : 2) | (in[2] ? 0 : 4);
}

/* Whether the stage may run inside the method's tiles (ew_harm_fused): a
 * method that can (stage_in_tiles) whose output is the very view of its
 * colour, packed RGB on the CPU (a backend that blends in bands), with the
 * rejection on: the clamped colour is written over the caller's (which the
 * output replaces anyway; what the rejection took is kept in the excess
 * plane) and the method blends each region before its core goes out, so
 * that neither the clamped colour nor the radiance is held as a frame. */
static int fusable(const ew_op *op, int cc, int pre, int own, int kept) {
    const ew_image *c = ew_op_image(op, "color"), *o = ew_op_image(op, "output");
    if (!op->type->stage_in_tiles || pre != 1 || own || !kept || cc != 3 || !op->dev->backend->harm_bands) return 0;
    /* a frame whose two bands are about a quarter of its RGB or less: a
     * smaller one saves little by it */
    if (c->height < 4 * HARM_BAND_ROWS) return 0;
    const float *in = ew_dev_view_in_place(op->dev, c, 3, NULL);
    return in && ew_dev_view_in_place(op->dev, o, 3, NULL) == in && o->width == c->width && o->height == c->height;
}

/* What runs before the method: 0 nothing, 1 the rejection, 2 the rejection
 * and then the denoisers' own firefly clamp (a method without one of its
 * own: a filter used as a denoiser). */
static int pre_steps(const ew_op *op) {
    if (!(ew_op_param(op, "outlier_k") > 0.0f)) return 0;
    return strcmp(op->type->kind, "denoiser") ? 2 : 1;
}

/* The pilot needs the features kpcn reads; kpcn is its own pilot (the
 * estimate would compare the method with a smaller copy of itself). */
static int pilot_possible(const ew_op *op) {
    return strcmp(op->type->name, HARM_PILOT_METHOD) != 0 && slot(op, "albedo") >= 0 && slot(op, "normal") >= 0 &&
           slot(op, "depth") >= 0;
}

/* The views' sources and where the stage runs: own (views_in_place's
 * without the halves it reads in bands), *fuse (fusable) and *half, which
 * of albedo (2) and normal (4) it reads from half views a band of rows at
 * a time. Only fused: around the method the passes read frames. */
static int plan_views(const ew_op *op, int cc, int pre, const float *in[3], int *kept, int *fuse, int *half) {
    const int own = views_in_place(op, cc, pre, in, kept);
    int h = 0;
    if (ew_dev_view_half_rows(op->dev, ew_op_image(op, "albedo"), 3)) h |= 2;
    if (ew_dev_view_half_rows(op->dev, ew_op_image(op, "normal"), 3)) h |= 4;
    if (h && fusable(op, cc, pre, own & ~h, *kept)) {
        *fuse = 1;
        *half = h;
        return own & ~h;
    }
    *fuse = fusable(op, cc, pre, own, *kept);
    *half = 0;
    return own;
}

uint64_t ew_harm_memory(const ew_op *op, int w, int h) {
    const int pre = pre_steps(op), post = ew_op_param(op, "do_no_harm") != 0.0f;
    if (!has_stage(op->type) || op->type->stage_in_inner || (!pre && !post)) return 0;
    const size_t n = (size_t)w * (size_t)h, stage = ew_dev_stage_floats(op->dev, n, 4);
    /* an RGBA colour with albedo and normal: the most the commit takes;
     * with the views of that size set, what they make it take */
    const ew_image *c = ew_op_image(op, "color");
    int own = 7, cc = 4, kept = 0, fuse = 0, half = 0;
    if (c && c->width == w && c->height == h) {
        const float *in[3];
        cc = c->channels;
        own = plan_views(op, cc, pre, in, &kept, &fuse, &half);
    }
    return (uint64_t)stage_floats(n, cc, 1, 1, pre, own, kept, fuse, half, w) * sizeof(float) + (uint64_t)h * 4 * sizeof(double) +
           (uint64_t)(stage + (pre ? stage : 0)) * sizeof(float);
}

ew_result ew_harm_commit(ew_op *op) {
    ew_device *dev = op->dev;
    const int ci = slot(op, "color"), oi = slot(op, "output");
    const int pre = pre_steps(op), post = ew_op_param(op, "do_no_harm") != 0.0f;
    if (!has_stage(op->type) || op->type->stage_in_inner || ci < 0 || oi < 0 || (!pre && !post) ||
        op->images[ci].channels < 3 || op->images[oi].channels < 3) {
        ew_harm_release(op);
        return EW_OK;
    }
    const ew_image *c = &op->images[ci];
    const int w = c->width, h = c->height, cc = c->channels;
    const int has_a = slot(op, "albedo") >= 0 && op->images[slot(op, "albedo")].channels >= 3;
    const int has_n = slot(op, "normal") >= 0 && op->images[slot(op, "normal")].channels >= 3;
    const float *in[3];
    int kept;
    int fuse, half;
    const int own = plan_views(op, cc, pre, in, &kept, &fuse, &half);
    ew_harm_state *s = (ew_harm_state *)op->harm;
    if (s && s->w == w && s->h == h && s->cc == cc && s->has_a == has_a && s->has_n == has_n && s->pre == pre &&
        s->own == own && s->kept == kept && s->can_fuse == fuse && s->half == half) {
        if (!(own & 1)) s->col = (float *)in[0];
        if (has_a && !(own & 2) && !(half & 2)) s->alb = (float *)in[1];
        if (has_n && !(own & 4) && !(half & 4)) s->nrm = (float *)in[2];
        return EW_OK;
    }
    ew_harm_release(op);
    const size_t n = (size_t)w * (size_t)h;
    /* col (cc), albedo, normal (those not read in place), a (radiance, then
     * the method's output), b (a filter's rejected radiance, then the
     * residual statistics), clamped (clamped_channels; a denoiser's
     * rejected radiance first), removed (1), the rejection's excess (1, kept) */
    const size_t floats = stage_floats(n, cc, has_a, has_n, pre, own, kept, fuse, half, w);
    const size_t row_bytes = (size_t)h * 2 * sizeof(double);
    const size_t stage = ew_dev_stage_floats(dev, n, cc);
    const size_t hclamp = pre ? ew_dev_stage_floats(dev, n, clamped_channels(cc, pre)) : 0; /* the colour the method reads */
    s = (ew_harm_state *)calloc(1, sizeof *s + row_bytes + (stage + hclamp) * sizeof(float));
    if (s) s->dmem = ew_dev_alloc(dev, row_bytes + floats * sizeof(float));
    if (s) s->dmem_bytes = row_bytes + floats * sizeof(float);
    op->harm = s;
    if (!s || !s->dmem)
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory: the do-no-harm stage of %dx%d needs %.1f MiB", w,
                        h, (double)(floats * sizeof(float) + row_bytes) / 1048576.0);
    s->w = w;
    s->h = h;
    s->cc = cc;
    s->has_a = has_a;
    s->has_n = has_n;
    s->pre = pre;
    s->own = own;
    s->kept = kept;
    s->can_fuse = fuse;
    s->half = half;
    s->rows = s->host;
    s->stage = stage ? (float *)(void *)(s->host + (size_t)h * 2) : NULL;
    s->hclamp = hclamp ? s->stage + stage : NULL;
    s->row_out = (double *)s->dmem;
    float *m = (float *)(void *)((char *)s->dmem + row_bytes);
    s->col = own & 1 ? m : (float *)in[0]; m += own & 1 ? n * (size_t)cc : 0;
    /* (a feature read from halves in bands has no frame: NULL) */
    s->alb = !has_a || (half & 2) ? NULL : own & 2 ? m : (float *)in[1]; m += has_a && (own & 2) ? n * 3 : 0;
    s->nrm = !has_n || (half & 4) ? NULL : own & 4 ? m : (float *)in[2]; m += has_n && (own & 4) ? n * 3 : 0;
    s->a = m; m += n * 3;
    s->b = m; m += n * EW_HARM_STATS_FLOATS;
    s->clamped = pre ? m : NULL; m += pre ? n * (size_t)clamped_channels(cc, pre) : 0;
    s->fed = pre == 2 ? m : s->clamped; m += pre == 2 ? n * (size_t)cc : 0;
    s->removed = m; m += n;
    s->excess = kept ? m : NULL; /* past b: not among the pages released while the method runs */
    m += kept ? n : 0;
    /* both hold a few pixels of a quiet frame (what the clamps took) */
    ew_dev_sparse_pages(dev, s->removed, m);
    s->band = fuse ? m : NULL;
    m += fuse ? 2 * band_floats(w) : 0;
    for (int f = 0; f < 2; f++) {
        s->fband[f] = (f ? has_n && (half & 4) : has_a && (half & 2)) ? m : NULL;
        m += s->fband[f] ? band_floats(w) : 0;
    }
    return EW_OK;
}

/* The frame's mean of buf: luminance (LUM_SUM, 3 floats a pixel) or value
 * (SUM, 1), finite and positive (kernels/reduce.h). */
static ew_result frame_mean_of(ew_harm_state *s, ew_device *dev, int op, const float *buf, double *mean) {
    dev->backend->reduce_rows(dev, op, s->w, s->h, buf, s->row_out);
    ew_result r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)s->h * 2 * sizeof(double));
    double sum = 0.0;
    for (int y = 0; r == EW_OK && y < s->h; y++) sum += s->rows[2 * y];
    *mean = sum / ((double)s->w * (double)s->h);
    return r;
}

/* The frame's mean luminance of buf (3 per pixel). */
static ew_result frame_mean(ew_harm_state *s, ew_device *dev, const float *buf, double *mean) {
    return frame_mean_of(s, dev, EW_REDUCE_LUM_SUM, buf, mean);
}

/* The frame's noise level (kernels/reduce.h EW_REDUCE_NOISE: the mean
 * diagonal Haar detail of compressed luminance) of buf (3 per pixel). */
static ew_result frame_noise(ew_harm_state *s, ew_device *dev, const float *buf, double *noise) {
    dev->backend->reduce_rows(dev, EW_REDUCE_NOISE, s->w, s->h, buf, s->row_out);
    ew_result r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)s->h * 2 * sizeof(double));
    double sum = 0.0, count = 0.0;
    for (int y = 0; r == EW_OK && y < s->h; y++) {
        sum += s->rows[2 * y];
        count += s->rows[2 * y + 1];
    }
    *noise = count > 0.0 ? sum / count : 0.0;
    return r;
}

/* 0 at a noise level of `from`, 1 at `to`, a straight line between and
 * clamped beyond (to < from: a ramp down) */
static float noise_ramp(double noise, double from, double to) {
    const double t = (noise - from) / (to - from);
    return (float)(t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t);
}

/* How quiet a frame of this noise level is: 1 up to HARM_QUIET_NOISE, 0
 * from HARM_NOISY_NOISE, a ramp between. The blend's second estimate has
 * the threshold theta_n x (1 - quiet) and takes a share quiet of its ratio
 * in T (kernels/harm.h). theta_n is there for 1-4 spp, where a window's
 * Haar detail and residual are a few bright samples and their ratio
 * scatters; on a quiet frame (16-64 spp) the ratio is steady and every bit
 * of the method's error it reads is worth blending away. On the 11 training
 * scenes, theta_n 0 on every frame gained 0.1-0.6 dB on the frames below
 * 0.009 and lost 0.1-1.8 dB on those above 0.010 (1 spp is 0.011-0.11).
 * On a quiet frame the residual's Haar detail H is not all noise: a grid
 * method's error at the scale of one pixel (an edge it moved) passes into
 * it too, so D is R - kappa H with kappa 0.85 there (0.7 cost kpcn 0.24 dB
 * at 64 spp; 0.85 lifts bgrid's worst training scene 0.5 dB for 0.05). */
static float quietness(double noise) { return noise_ramp(noise, HARM_NOISY_NOISE, HARM_QUIET_NOISE); }

/* How far the blend fades on a frame of this noise level: 0 up to
 * HARM_FADE_NOISE, 1 (no blend) from HARM_OFF_NOISE, a ramp between. On a
 * frame that noisy (most 1-spp frames, 4-spp frames of dark or caustic
 * scenes) a 9x9 window's residual is a few bright samples, and both of the
 * blend's estimates of the method's error read them as structure: a
 * firefly the method removed leaves a residual whose neighbour products
 * and Haar detail no longer average out. There the blend puts noise back.
 * Render cache training scenes (44 scenes at 1/4/16/64 spp), blend on
 * against off, frames above 0.025 (67): kpcn-large -0.70 dB on average
 * (Cornell rooms and firefly scenes at 1 spp: -1.4 to -4.6), bgrid +0.08,
 * nbg -0.02; and none of the three within 1.7 dB of its input there
 * without the blend: nothing converged to keep. Below 0.025 (106 frames)
 * the blend is what keeps the grids above their input (bgrid +3.8, nbg
 * +2.7 on average; up to 15 dB below the input without it). */
static float fade_of(double noise) { return noise_ramp(noise, HARM_FADE_NOISE, HARM_OFF_NOISE); }

/* The share of the pilot's estimate (kernels/harm.h): 0 from
 * HARM_PILOT_NOISE, 1 on a frame no noisier than HARM_NOISY_NOISE, a ramp
 * between. As a quiet frame's share (0.011 -> 0.007) it left a 64-spp
 * glossy frame of noise 0.0115 without it and bgrid and nbg 1.3-1.6 dB
 * below their input, and took only a third of it on frames of 0.0092 and
 * 0.0098 where bgrid stayed 0.6-0.8 dB below. On 306 render-cache training
 * scenes at 16 and 64 spp this ramp (with the pilot's own stage, below)
 * took the frames below input - 0.2 dB at 64 spp from 6 to 1 for bgrid and
 * from 2 to 1 for nbg, and bgrid's worst at 16 spp from -0.25 to +0.14 dB,
 * the means +0.02 to +0.06 dB. A ramp from the fade's 0.025 did the same
 * there and +0.13 against +0.06 dB for bgrid at 4 spp (40 of the scenes),
 * but ran the pilot on most 4-spp frames: the median 4-spp frame's bgrid
 * 22 -> 81 ms against 22 -> 25. */
static float pilot_share_of(double noise) { return noise_ramp(noise, HARM_PILOT_NOISE, HARM_NOISY_NOISE); }

/* Step 1 into s->clamped (s->a holds the demodulated radiance). The floor of the spread is the frame's mean
 * radiance; when the rejection itself took more than a quarter of it, that
 * mean was the outliers' own (one 6e4 sample in a 64x64 frame lifts it 16
 * units), so the rejection runs again with the mean of what it left, at
 * most twice more. */
static ew_outlier_params rejection_params(const ew_op *op, const ew_harm_state *s) {
    ew_outlier_params p = ew_outlier_plain_params(s->w, s->h, HARM_OUTLIER_RADIUS, ew_op_param(op, "outlier_k"));
    p.robust = 1;
    p.albedo_tol = HARM_ALBEDO_TOL;
    p.normal_cos = HARM_NORMAL_COS;
    p.sigma_floor = HARM_SIGMA_FLOOR;
    /* a pixel that alone saw a light smaller than itself: judged in colour
     * (kernels/outlier.h), its albedo being the hits' own noise */
    p.emitter_albedo = HARM_EMITTER_ALBEDO;
    return p;
}

static ew_result reject(ew_op *op, ew_harm_state *s, ew_harm_args *ha) {
    ew_device *dev = op->dev;
    double mean;
    ew_result r = frame_mean(s, dev, s->a, &mean);
    ew_outlier_params p = rejection_params(op, s);
    /* the rejected radiance: where the clamped colour goes when that is
     * RGB (a denoiser's), remodulated there in place, so that no third
     * frame of RGB is held beside the radiance and the clamped colour */
    float *rejected = s->pre == 1 ? s->clamped : s->b;
    const ew_outlier_buffers ob = {s->a, s->alb, s->nrm, rejected, 3, NULL};
    for (int pass = 0; r == EW_OK; pass++) {
        p.abs_floor = HARM_MEAN_FLOOR * (float)mean;
        dev->backend->outlier_guided(dev, &p, &ob);
        double left;
        if (pass == 2 || (r = frame_mean(s, dev, rejected, &left)) != EW_OK || left >= HARM_REJECT_KEEP * mean) break;
        mean = left;
    }
    if (r != EW_OK) return r;
    ha->rejected = rejected;
    dev->backend->harm(dev, EW_HARM_REMOD, ha);
    if (ha->excess) {
        /* written only where the rejection took something: on the CPU the
         * plane holds those pages only */
        r = ew_dev_zero(dev, ha->excess, (size_t)s->w * s->h * sizeof(float));
        if (r != EW_OK) return r;
        dev->backend->harm(dev, EW_HARM_EXCESS, ha);
    }
    if (s->pre == 2) {
        /* then the denoisers' own firefly clamp (kernels/outlier.h: mean +
         * 3 sigma of the 5x5 window, no features) on the rejected radiance,
         * for a method that has none: a filter keeps an isolated bright
         * sample where it is (its colour edge-stopping sees an edge all
         * around it), so what the rejection left in a dark region at 1-4
         * spp, 16x the frame's mean radiance, came out at 15-26x the
         * reference's local maximum. What it takes comes back after the
         * method as the denoisers' clamp's does (step 3). */
        const ew_outlier_params fp = ew_outlier_plain_params(s->w, s->h, 2, HARM_FIREFLY_K);
        const ew_outlier_buffers fb = {s->b, NULL, NULL, s->a, 3, s->removed};
        dev->backend->outlier_guided(dev, &fp, &fb);
        ew_harm_args hf = *ha;
        hf.color = s->clamped;
        hf.radiance = s->b;
        hf.rejected = s->a;
        hf.clamped = s->fed;
        dev->backend->harm(dev, EW_HARM_REMOD, &hf);
    }
    return r;
}

/* ---- fused (fusable): the passes before the method in bands of rows ---- */

/* Rows [y0, y1) of the albedo (f 0) or the normal (f 1), from row y0:
 * where the frame of it is, or from the half view, those rows converted
 * into the feature's band (until other rows are asked for); NULL without
 * the feature. */
static const float *feature_rows(ew_op *op, ew_harm_state *s, int f, int y0, int y1) {
    const float *frame = f ? s->nrm : s->alb;
    if (frame) return frame + (size_t)y0 * (size_t)s->w * 3;
    if (!s->fband[f]) return NULL;
    if (s->fband_y0[f] != y0 || s->fband_y1[f] != y1) {
        ew_dev_view_rows(op->dev, ew_op_image(op, f ? "normal" : "albedo"), 3, y0, y1, 0, s->w, s->fband[f]);
        s->fband_y0[f] = y0;
        s->fband_y1[f] = y1;
    }
    return s->fband[f];
}

/* Rows [y0, y1) of the caller's colour (packed RGB) demodulated into dst */
static void demod_rows(ew_op *op, ew_harm_state *s, const ew_harm_args *ha, int y0, int y1, float *dst) {
    ew_device *dev = op->dev;
    ew_harm_args d = *ha;
    const size_t at = (size_t)y0 * (size_t)s->w;
    d.height = y1 - y0;
    d.color = s->col + at * 3;
    d.albedo = feature_rows(op, s, 0, y0, y1);
    d.radiance = dst;
    dev->backend->harm(dev, EW_HARM_DEMOD, &d);
}

/* frame_noise's and frame_mean's values over the demodulated colour, from
 * bands of it: the same row sums, added in the same order */
static ew_result noise_and_mean_in_bands(ew_op *op, ew_harm_state *s, const ew_harm_args *ha, double *noise,
                                         double *mean) {
    ew_device *dev = op->dev;
    const size_t w = (size_t)s->w;
    double ns = 0.0, nc = 0.0, sum = 0.0;
    ew_result r = EW_OK;
    for (int y0 = 0; y0 < s->h && r == EW_OK; y0 += HARM_BAND_ROWS) {
        const int y1 = ew_mini(y0 + HARM_BAND_ROWS, s->h), lo = ew_maxi(y0 - 1, 0); /* NOISE reads the row above */
        demod_rows(op, s, ha, lo, y1, s->band);
        dev->backend->reduce_rows(dev, EW_REDUCE_NOISE, s->w, y1 - lo, s->band, s->row_out);
        r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)(y1 - lo) * 2 * sizeof(double));
        for (int y = y0; r == EW_OK && y < y1; y++) {
            ns += s->rows[2 * (y - lo)];
            nc += s->rows[2 * (y - lo) + 1];
        }
        if (r != EW_OK) break;
        dev->backend->reduce_rows(dev, EW_REDUCE_LUM_SUM, s->w, y1 - y0, s->band + (size_t)(y0 - lo) * w * 3,
                                  s->row_out);
        r = dev->backend->mem_download(dev, s->rows, s->row_out, (size_t)(y1 - y0) * 2 * sizeof(double));
        for (int y = 0; r == EW_OK && y < y1 - y0; y++) sum += s->rows[2 * y];
    }
    *noise = nc > 0.0 ? ns / nc : 0.0;
    *mean = sum / ((double)s->w * (double)s->h);
    return r;
}

/* reject()'s passes with the radiance in bands (each band's rejection reads
 * HARM_BAND_MARGIN rows beyond it): the rejected radiance into s->clamped's
 * frame (released before the method); then band by band the clamped colour
 * written over the caller's, and what the rejection took, capped as TAKE
 * caps it, into the excess plane (ha->fused) */
static ew_result reject_in_bands(ew_op *op, ew_harm_state *s, ew_harm_args *ha, double mean) {
    ew_device *dev = op->dev;
    const size_t w = (size_t)s->w;
    float *rad = s->band, *out = s->band + (size_t)(HARM_BAND_ROWS + 2 * HARM_BAND_MARGIN) * w * 3;
    float *rejected = s->clamped;
    ew_outlier_params p = rejection_params(op, s);
    ew_result r = EW_OK;
    for (int pass = 0; r == EW_OK; pass++) {
        p.abs_floor = HARM_MEAN_FLOOR * (float)mean;
        for (int y0 = 0; y0 < s->h && r == EW_OK; y0 += HARM_BAND_ROWS) {
            const int y1 = ew_mini(y0 + HARM_BAND_ROWS, s->h);
            const int lo = ew_maxi(y0 - HARM_BAND_MARGIN, 0), hi = ew_mini(y1 + HARM_BAND_MARGIN, s->h);
            demod_rows(op, s, ha, lo, hi, rad);
            ew_outlier_params pb = p;
            pb.height = hi - lo;
            const ew_outlier_buffers ob = {rad, feature_rows(op, s, 0, lo, hi), feature_rows(op, s, 1, lo, hi), out, 3,
                                           NULL};
            dev->backend->outlier_guided(dev, &pb, &ob);
            r = dev->backend->mem_copy(dev, rejected + (size_t)y0 * w * 3, out + (size_t)(y0 - lo) * w * 3,
                                       (size_t)(y1 - y0) * w * 3 * sizeof(float));
        }
        double left;
        if (r != EW_OK || pass == 2 || (r = frame_mean(s, dev, rejected, &left)) != EW_OK ||
            left >= HARM_REJECT_KEEP * mean)
            break;
        mean = left;
    }
    if (r == EW_OK) r = ew_dev_zero(dev, s->excess, (size_t)s->w * s->h * sizeof(float));
    ha->fused = 1;
    for (int y0 = 0; y0 < s->h && r == EW_OK; y0 += HARM_BAND_ROWS) {
        const int y1 = ew_mini(y0 + HARM_BAND_ROWS, s->h);
        const size_t at = (size_t)y0 * w;
        demod_rows(op, s, ha, y0, y1, rad);
        ew_harm_args d = *ha;
        d.height = y1 - y0;
        d.color = s->col + at * 3;
        d.albedo = feature_rows(op, s, 0, y0, y1);
        d.radiance = rad;
        d.rejected = rejected + at * 3;
        d.clamped = out;
        d.excess = s->excess + at;
        dev->backend->harm(dev, EW_HARM_REMOD, &d);
        dev->backend->harm(dev, EW_HARM_EXCESS, &d);
        /* the caller's colour is the output's view (fusable): it is given
         * up to the result, and holds the method's input until then */
        r = dev->backend->mem_copy(dev, (float *)s->col + at * 3, out, (size_t)(y1 - y0) * w * 3 * sizeof(float));
    }
    return r;
}

int ew_harm_may_fuse(const ew_op *op) {
    const ew_image *c = ew_op_image(op, "color"), *o = ew_op_image(op, "output");
    const int pre = pre_steps(op);
    if (!has_stage(op->type) || op->type->stage_in_inner || !c || !o || c->channels < 3) return 0;
    const float *in[3];
    int kept, fuse, half;
    plan_views(op, c->channels, pre, in, &kept, &fuse, &half);
    return fuse;
}

int ew_harm_fused(const ew_op *op) {
    const ew_harm_state *s = (const ew_harm_state *)op->harm;
    return s && s->fused;
}

ew_result ew_harm_region_done(ew_op *op, int x, int y, int rw, int rh, const float *in, float *out, float *give) {
    ew_harm_state *s = (ew_harm_state *)op->harm;
    ew_device *dev = op->dev;
    ew_harm_args ha = s->region;
    ha.width = rw;
    ha.height = rh;
    ha.channels = 3;
    ha.clamped_channels = 3;
    ha.clamped = (float *)in;
    ha.out = out;
    ha.give = give;
    ha.stats = s->b; /* a frame's statistics, for a backend out of memory for its bands (not touched else) */
    if (s->blend) dev->backend->harm(dev, EW_HARM_STATS_BLEND, &ha);
    if (s->blend && s->pilot) {
        /* the pilot's estimate over the blended region, as apply_pilot's
         * over the frame (fused: a backend that sums in bands) */
        const size_t need = (size_t)rw * (size_t)rh * 3;
        if (need > s->pregion_floats) {
            free(s->pregion);
            s->pregion = (float *)malloc(need * sizeof(float));
            s->pregion_floats = s->pregion ? need : 0;
            if (!s->pregion) return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory: the pilot's region of %dx%d", rw, rh);
        }
        for (int row = 0; row < rh; row++)
            ew__halves_to_floats(s->pilot + ((size_t)(y + row) * s->w + x) * 3, s->pregion + (size_t)row * rw * 3,
                                 (size_t)rw * 3);
        ha.pilot = s->pregion;
        ha.pilot_share = s->pilot_share;
        dev->backend->harm(dev, EW_HARM_PILOT_SQ, &ha);
        dev->backend->harm(dev, EW_HARM_PILOT_HV, &ha);
    }
    if (give) dev->backend->harm(dev, EW_HARM_LIGHT, &ha);
    return dev->backend->sync(dev, 0);
}

/* the blend's window, and the row and column of residuals a pixel's
 * statistics read beyond it (kernels/harm.h); with a pilot in this
 * execute, its estimate's window beyond that (it reads the blended output
 * over its own) */
int ew_harm_region_margin(const ew_op *op) {
    const ew_harm_state *s = (const ew_harm_state *)op->harm;
    return HARM_BLEND_RADIUS + 1 + (s && s->pilot ? HARM_BLEND_RADIUS : 0);
}

int ew_harm_region_margin_most(const ew_op *op) {
    return HARM_BLEND_RADIUS + 1 + (pilot_possible(op) ? HARM_BLEND_RADIUS : 0);
}

size_t ew_harm_held_bytes(const ew_op *op) {
    const ew_harm_state *s = (const ew_harm_state *)op->harm;
    return s && s->pilot && !op->dev->device_memory ? (size_t)s->w * (size_t)s->h * 3 * sizeof *s->pilot : 0;
}

float *ew_harm_clamp_removed(const ew_op *op) {
    const ew_harm_state *s = (const ew_harm_state *)op->harm;
    return s ? s->removed : NULL;
}

/* A share [from, from + span) of a progress callback's range */
typedef struct {
    ew_progress_fn fn;
    void *user;
    double from, span;
} progress_span;

static int span_report(void *user, double f) {
    const progress_span *ps = (const progress_span *)user;
    return ps->fn(ps->user, ps->from + ps->span * f);
}

/* The share of the op's progress the pilot takes (kpcn takes about as long
 * as nbg and bgrid together at 4K) */
#define HARM_PILOT_PROGRESS 0.5

/* What the stage keeps of the pilot's output p: T(p) (kernels/harm.h),
 * all its estimate reads of p, rounded to halves. Their 11 bits are far
 * below what the estimate measures in T (on a frame quiet enough for a
 * pilot the input's distance from p is ~1e-2, a half's step at most 5e-4),
 * and T is below 41 for every float, so no value overflows. The floats in
 * place become those halves, packed at the front (halves 1: a frame held
 * through the method, at 6 bytes a pixel), or the floats they hold
 * (halves 0: the same values wherever the estimate runs). One pass front
 * to back: a half's two bytes never reach a float not yet read. */
static void pilot_tone(float *p, size_t values, int halves) {
    for (size_t i = 0; i < values; i++) {
        const unsigned short t = ew_float_to_half(ew_harm_tone(p[i]));
        if (halves)
            memcpy((char *)p + i * sizeof t, &t, sizeof t);
        else
            p[i] = ew_half_to_float(t);
    }
}

/* The pilot's output in T (pilot_tone; 3 floats a pixel, or 3 halves
 * with `halves`, in a buffer of its own then; host memory: `into` when
 * given, else a buffer of its own, *owned 1) on the colour the method reads and
 * the op's features: kpcn's default model, built for this frame and freed
 * after it, so that its tiles are not held while the method runs. Its
 * stage blends (kpcn blurs detail of a converged frame too, and the
 * pilot's distance from the input is the noise figure: a pilot that kept
 * that detail tells it from noise) but does not reject (the colour is the
 * stage's, rejected already). On the training scenes the pilot's own blend
 * took the frames of bgrid below input - 0.2 dB at 64 spp from 4 to 1
 * against the pilot without it. Its progress is the op's span `ps` (fn
 * NULL: none). NULL in *out when it could not run (the stage then blends
 * as without it). */
static ew_result run_pilot(ew_op *op, float *into, int halves, progress_span *ps, float **out, int *owned) {
    *out = NULL;
    *owned = 0;
    const ew_image *c = ew_op_image(op, "color");
    const size_t n = (size_t)c->width * (size_t)c->height;
    float *buf = into ? into : (float *)malloc(n * 3 * sizeof(float));
    ew_op *p = NULL;
    ew_result r = buf ? ew_op_create_kind(op->dev, "denoiser", HARM_PILOT_METHOD, &p) : EW_ERR_OUT_OF_MEMORY;
    if (r == EW_OK) r = ew_op_set_param(p, "do_no_harm", 1.0f, 1);
    if (r == EW_OK) r = ew_op_set_param(p, "outlier_k", 0.0f, 0);
    if (r == EW_OK) r = ew_op_set_param(p, "max_memory_mb", (float)HARM_PILOT_MEMORY_MB, 1);
    if (r == EW_OK && ps->fn) r = ew_op_set_progress(p, span_report, ps);
    static const char *const in[] = {"color", "albedo", "normal", "depth"};
    for (int i = 0; r == EW_OK && i < 4; i++) r = ew_op_set_image(p, in[i], ew_op_image(op, in[i]));
    const ew_image o = ew_image_packed(buf, c->width, c->height, 3);
    if (r == EW_OK) r = ew_op_set_image(p, "output", &o);
    if (r == EW_OK) r = ew_op_commit(p);
    if (r == EW_OK) r = ew_op_execute(p);
    ew_op_destroy(p);
    if (r != EW_OK) {
        if (buf != into) free(buf);
        return r == EW_ERR_CANCELLED ? r : EW_OK;
    }
    pilot_tone(buf, n * 3, halves);
    if (halves) { /* the floats' second half goes back (a shrink does not move or fail in glibc) */
        float *shrunk = (float *)realloc(buf, n * 3 * sizeof(unsigned short));
        if (shrunk) buf = shrunk;
    }
    *out = buf;
    *owned = buf != into;
    return EW_OK;
}

/* The pilot's second estimate over the blended output (kernels/harm.h),
 * a share `share` of it. */
static ew_result apply_pilot(ew_op *op, ew_harm_state *s, ew_harm_args *ha, float *host, float share) {
    ew_device *dev = op->dev;
    const ew_image v = ew_image_packed(host, s->w, s->h, 3);
    float *p = (float *)ew_dev_view_in_place(dev, &v, 3, NULL), *mem = NULL;
    if (!p) {
        const size_t stage = ew_dev_stage_floats(dev, (size_t)s->w * s->h, 3);
        float *st = stage ? (float *)malloc(stage * sizeof(float)) : NULL;
        mem = (float *)ew_dev_alloc(dev, (size_t)s->w * s->h * 3 * sizeof(float));
        ew_result r = !mem || (stage && !st) ? EW_ERR_OUT_OF_MEMORY : ew_dev_put_view(dev, &v, 3, mem, st);
        free(st);
        if (r != EW_OK) {
            ew_dev_free(dev, mem);
            return r == EW_ERR_OUT_OF_MEMORY ? EW_OK : r; /* no pilot: the blend as without it */
        }
        p = mem;
    }
    ha->pilot = p;
    ha->pilot_share = share;
    ha->spread = s->b;
    dev->backend->harm(dev, EW_HARM_PILOT_SQ, ha);
    if (dev->backend->harm_bands) { /* the sums along the rows a band at a time: spread is not touched */
        dev->backend->harm(dev, EW_HARM_PILOT_HV, ha);
    } else {
        dev->backend->harm(dev, EW_HARM_PILOT_H, ha);
        dev->backend->harm(dev, EW_HARM_PILOT_V, ha);
    }
    ew_result r = dev->backend->sync(dev, 0);
    ew_dev_free(dev, mem);
    ha->pilot = NULL;
    return r;
}

ew_result ew_harm_execute(ew_op *op) {
    ew_harm_state *s = (ew_harm_state *)op->harm;
    ew_device *dev = op->dev;
    const int ci = slot(op, "color");
    ew_result r = s->own & 1 ? ew_dev_put_view(dev, &op->images[ci], s->cc, s->col, s->stage) : EW_OK;
    if (r == EW_OK && s->alb && (s->own & 2)) r = ew_dev_put_view(dev, ew_op_image(op, "albedo"), 3, s->alb, s->stage);
    if (r == EW_OK && s->nrm && (s->own & 4)) r = ew_dev_put_view(dev, ew_op_image(op, "normal"), 3, s->nrm, s->stage);
    if (r != EW_OK) return r;
    s->fband_y0[0] = s->fband_y0[1] = s->fband_y1[0] = s->fband_y1[1] = -1; /* the views' pixels may be new */
    ew_harm_args ha;
    memset(&ha, 0, sizeof ha);
    ha.width = s->w;
    ha.height = s->h;
    ha.channels = s->cc;
    const int ck = clamped_channels(s->cc, s->pre);
    ha.clamped_channels = s->pre ? ck : 0; /* without a rejection the method's input is the colour itself */
    ha.color = s->col;
    ha.albedo = s->alb;
    ha.radiance = s->a;
    ha.clamped = s->pre ? s->clamped : s->col;
    ha.excess = s->excess;
    ha.radius = HARM_BLEND_RADIUS;
    ha.strength = HARM_BLEND_STRENGTH;
    ha.z = HARM_BLEND_Z;
    ha.theta = HARM_BLEND_THETA;
    ha.kappa = HARM_BLEND_KAPPA;
    ha.give_cap = HARM_GIVE_CAP;
    /* the input's noise level, in demodulated radiance as kpcn measures it
     * (fusable: and the mean radiance, from bands of it) */
    double noise, mean = 0.0;
    int fuse = s->can_fuse;
    if (fuse) {
        r = noise_and_mean_in_bands(op, s, &ha, &noise, &mean);
    } else {
        dev->backend->harm(dev, EW_HARM_DEMOD, &ha);
        r = frame_noise(s, dev, s->a, &noise);
    }
    if (r != EW_OK) return r;
    const float quiet = quietness(noise);
    ha.theta_n = HARM_BLEND_THETA_N * (1.0f - quiet);
    ha.tone_share = quiet;
    ha.kappa = HARM_BLEND_KAPPA - (HARM_BLEND_KAPPA - HARM_QUIET_KAPPA) * quiet;
    ha.fade = fade_of(noise);
    const int post = ew_op_param(op, "do_no_harm") != 0.0f && ha.fade < 1.0f;
    const float pilot_share = pilot_share_of(noise);
    const int want_pilot = post && pilot_share > 0.0f && pilot_possible(op);
    const ew_image saved = op->images[ci];
    if (s->pre) {
        r = fuse ? reject_in_bands(op, s, &ha, mean) : reject(op, s, &ha);
        if (r != EW_OK) return r;
        /* the method reads the clamped colour where it reads views from
         * (fused: the caller's colour, which holds it now) */
        if (!fuse && s->hclamp) {
            r = dev->backend->mem_download(dev, s->hclamp, s->fed, (size_t)s->w * s->h * ck * sizeof(float));
            if (r != EW_OK) return r;
            op->images[ci] = ew_image_packed(s->hclamp, s->w, s->h, ck);
        } else if (!fuse) {
            op->images[ci] = ew_image_packed(s->fed, s->w, s->h, ck);
        }
    }
    /* the radiance and the rejected radiance are dead while the method
     * runs (its output and the residual statistics overwrite them after it):
     * their pages go before the clamp's plane is zeroed, so the two are
     * not resident together (fused: the rejected radiance, in the clamped
     * colour's place) */
    if (fuse) {
        ew_dev_release_pages(dev, s->clamped, s->clamped + (size_t)s->w * s->h * 3);
        /* the passes' bands (and the features' converted from halves): the
         * last buffers, rewritten before they are read at the next execute */
        ew_dev_release_pages(dev, s->band, (char *)s->dmem + s->dmem_bytes);
    } else
        ew_dev_release_pages(dev, s->a, s->b + (size_t)s->w * s->h * EW_HARM_STATS_FLOATS);
    /* the pilot reads what the method reads. Where that is the stage's
     * clamped colour (a rejection, around the method), which the method's
     * output cannot overwrite, it runs after the method, so that its output
     * and the method's buffers are not held together; else before, ahead
     * of an output written over the colour (fused: the caller's colour,
     * which holds the clamped colour now; each region then takes the
     * pilot's estimate after its blend) */
    const int pilot_after = want_pilot && s->pre && !fuse;
    float *pilot = NULL;
    int pilot_owned = 0;
    /* with a pilot, the op's progress is the pilot's and the method's in turn */
    const ew_progress_fn fn = op->progress;
    void *const user = op->progress_user;
    progress_span pilot_span = {fn, user, pilot_after ? 1.0 - HARM_PILOT_PROGRESS : 0.0, HARM_PILOT_PROGRESS};
    progress_span method_span = {fn, user, want_pilot && !pilot_after ? HARM_PILOT_PROGRESS : 0.0,
                                 want_pilot ? 1.0 - HARM_PILOT_PROGRESS : 1.0};
    if (want_pilot && !pilot_after) {
        r = run_pilot(op, NULL, fuse, &pilot_span, &pilot, &pilot_owned);
        if (r != EW_OK) {
            op->images[ci] = saved;
            return r;
        }
    }
    /* the method's clamp's plane, zeroed after a pilot that runs first, so
     * that it is not resident beside the pilot's own */
    if (s->pre != 2) { /* pre 2: the stage's firefly clamp wrote it */
        r = ew_dev_zero(dev, s->removed, (size_t)s->w * s->h * sizeof(float));
        if (r != EW_OK) {
            if (pilot_owned) free(pilot);
            op->images[ci] = saved;
            return r;
        }
    }
    s->region = ha;
    s->blend = post;
    s->fused = fuse;
    s->pilot = fuse ? (const unsigned short *)(void *)pilot : NULL;
    s->pilot_share = pilot_share;
    if (want_pilot && fn) {
        op->progress = span_report;
        op->progress_user = &method_span;
    }
    r = op->type->execute(op);
    op->progress = fn;
    op->progress_user = user;
    s->fused = 0;
    s->pilot = NULL;
    free(s->pregion);
    s->pregion = NULL;
    s->pregion_floats = 0;
    if (r == EW_OK && pilot_after) {
        /* into the radiance's plane, dead now, where the output view is
         * the result and the device's memory is the host's */
        const ew_image va = ew_image_packed(s->a, s->w, s->h, 3);
        const int a_free = ew_dev_view_in_place(dev, ew_op_image(op, "output"), 3, NULL) &&
                           ew_dev_view_in_place(dev, &va, 3, NULL) == s->a;
        r = run_pilot(op, a_free ? s->a : NULL, 0, &pilot_span, &pilot, &pilot_owned);
    }
    op->images[ci] = saved;
    if (r != EW_OK) {
        if (pilot_owned) free(pilot);
        return r;
    }
    const ew_image *out = ew_op_image(op, "output");
    /* an output view packed as the stage's RGB is blended and given its
     * light in place: no second frame of the result beside the statistics
     * (nothing the stage reads after the method overlaps it: albedo and
     * normal are read in place only where they do not, and the colour is
     * not read after the method where it does: its excess is kept) */
    float *res = (float *)ew_dev_view_in_place(dev, out, 3, NULL);
    if (!res) {
        res = s->a;
        r = ew_dev_put_view(dev, out, 3, res, s->stage);
        if (r != EW_OK) {
            if (pilot_owned) free(pilot);
            return r;
        }
    }
    ha.out = res;
    ha.stats = s->b;
    ha.give = s->removed;
    /* faded out (a noisy frame), the blend would keep every pixel of the
     * method's output: its statistics are not computed at all; fused, the
     * method's regions were blended */
    if (post && !fuse) {
        /* a backend that blends in bands of rows keeps their statistics
         * itself: only the first 3 floats a pixel of b (the energy return's
         * box sums) are touched after the method */
        if (dev->backend->harm_bands) {
            dev->backend->harm(dev, EW_HARM_STATS_BLEND, &ha);
        } else {
            dev->backend->harm(dev, EW_HARM_STATS, &ha);
            dev->backend->harm(dev, EW_HARM_BLEND, &ha);
        }
    }
    if (pilot && !fuse) r = apply_pilot(op, s, &ha, pilot, pilot_share); /* fused: the regions took it */
    if (pilot_owned)
        free(pilot);
    else if (pilot) /* the radiance's plane: written again before it is read */
        ew_dev_release_pages(dev, pilot, pilot + (size_t)s->w * s->h * 3);
    if (r != EW_OK) return r;
    /* the light the clamps took (kernels/harm.h): the method's clamp's back
     * where it was taken, the rejection's to the whole frame as one gain.
     * Its limit a pixel, 50x the output's mean (30x, with the method's
     * clamp's, over the window before): the damaged 6.5e4 sample of the
     * stability suite's 4-spp renders stays within its bound (at 70x by
     * 0.02 dB, at 100x not). Fused, the clamped colour is gone: the
     * regions left its part of both in give and excess (ha.fused) */
    if (fuse) ha.clamped = NULL;
    ha.spread = s->b;
    ha.give_radius = HARM_GIVE_RADIUS;
    double out_mean, given;
    r = frame_mean(s, dev, res, &out_mean);
    if (r != EW_OK) return r;
    ha.give_limit = (float)(HARM_GIVE_LIMIT * out_mean);
    ha.take_limit = (float)(HARM_TAKE_LIMIT * out_mean);
    ha.give_gain = HARM_GIVE_GAIN;
    if (dev->backend->harm_bands) { /* as the pilot's: spread is not touched */
        dev->backend->harm(dev, EW_HARM_RETURN, &ha);
    } else {
        dev->backend->harm(dev, EW_HARM_SUM_H, &ha);
        dev->backend->harm(dev, EW_HARM_SUM_V, &ha);
        dev->backend->harm(dev, EW_HARM_GIVE, &ha);
        dev->backend->harm(dev, EW_HARM_SPREAD_H, &ha);
        dev->backend->harm(dev, EW_HARM_SPREAD_V, &ha);
    }
    dev->backend->harm(dev, EW_HARM_TAKE, &ha);
    r = frame_mean(s, dev, res, &out_mean);
    if (r == EW_OK) r = frame_mean_of(s, dev, EW_REDUCE_SUM, s->removed, &given);
    if (r != EW_OK) return r;
    ha.gain = out_mean > 0.0 ? (float)(given / out_mean < HARM_TAKE_GAIN ? given / out_mean : HARM_TAKE_GAIN) : 0.0f;
    dev->backend->harm(dev, EW_HARM_SCALE, &ha);
    return res == s->a ? ew_dev_get_view(dev, res, 3, out, s->stage) : dev->backend->sync(dev, 0);
}
