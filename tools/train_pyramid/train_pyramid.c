/*
 * train_pyramid — train the pyramid filter's per-level weights (Xu et al.
 * 2024 §3.3.2) against the exact joint bilateral filter, and write the
 * weights file the library embeds.
 *
 *   train_pyramid --data DIR [--out models/pyramid] [--c-out FILE.c]
 *                 [--model all|gi] [--iters N] [--iters-large N] [--threads N]
 *                 [--radii 1,2,3,...] [--resume] [--quick]
 *
 * --model: which table. "all" (the default): one table for every kind of
 * target below, OUT/pyramid.ewpw (the library's table for colour, depth
 * and DoF). "gi": GI denoising samples only
 * (Eq. 9, diffuse), starting from and compared with the analytic setting
 * for diffuse GI (gamma = 0), OUT/pyramid_gi.ewpw (the library's table for
 * GI, with or without a roughness image): one table serving all kinds is a
 * compromise that is worse than the analytic weights for GI.
 *
 * --iters-large: iterations for radius >= 24 (whole 256x256 images; most
 * of the gain comes in the first 50 iterations). --resume: keep the nodes
 * of the model's file in OUT and train only the radii it lacks.
 *
 * Unknowns per level l of a radius (sigma = radius / 3): the 8 off-centre
 * fine weights wf, the 9 coarse weights wc (by distance class) and gamma;
 * the centre fine weight follows from Eq. 2g. One set per level per radius
 * node; the library interpolates between nodes in log2(sigma).
 *
 * Data. DIR holds the Cycles renders (../shared/data/cycles-train): one
 * folder per scene, <family>_<name>_<seed>_WxH/. Whole scenes are held out,
 * as tools/train does: per family, scenes sorted by seed, the last is a test
 * scene and, in families of four or more, the one before it a validation
 * scene; test scenes are never read here. Plus procedural images (shapes,
 * gradients, stripes, checkers, noise; their own seeds for training and
 * validation).
 *
 * Samples per radius: the four kinds of targets the filter serves, each
 * with its exact result (the brute force, computed here):
 *   colour  the reference render or a procedural image, guided by itself,
 *           sigma_range in {0.05, 0.1, 0.2} (the paper's training)
 *   GI      the 4-spp render with Denoising Normal and Depth (Eq. 9, diffuse,
 *           sigma_normal 32, sigma_depth 0.5 per m^2)
 *   depth   the depth pass, normalised to [0, 1], filtered by itself (Eq. 10,
 *           sigma_depth 40)
 * Crops of 128x128 up to radius 16, whole 256x256 images above.
 *
 * Loss: mean squared error of the display values clip(x,0,1)^(1/2.2) (what
 * PSNR measures). Optimiser: full-batch Adam on the exact gradient
 * (ew_pyr_backward1), weights projected onto [0, 1] with the Eq. 2g centre
 * kept >= 0, gamma in [0, 4]; a step that raises the loss is undone, the
 * learning rate halved and Adam restarted (the paper's rejection rule);
 * accepted steps grow the rate by 5 % up to 0.02. Starts from the analytic
 * weights.
 *
 * Output: OUT/pyramid.ewpw (the weights file), OUT/training-log.txt (per
 * radius: loss and validation PSNR, analytic vs trained), and with --c-out
 * the C array the library embeds. The table is rewritten after every radius
 * (a checkpoint).
 */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "algorithms/bilateral.h"
#include "algorithms/pyramid.h"
#include "ewio.h"
#include "src/backend.h"

#define MAX_SCENES 64
#define MAX_SAMPLES 40

typedef struct {
    char name[160];
    int family, seed;
    int split; /* 0 train, 1 validation, 2 test */
} scene_info;

/* an image with what each kind of target needs */
typedef struct {
    int w, h;
    float *ref;    /* w*h*4, the reference colour (alpha slot 0) */
    float *noisy;  /* w*h*4, 4 spp colour, or NULL */
    float *normal; /* w*h*3 or NULL */
    float *depth;  /* w*h, metres, or NULL */
    char name[192];
} source;

typedef struct {
    ew_bf_model m;
    int w, h;
    float *image, *attr, *gt, *out, *dout, *scratch, *gscratch;
    ew_pyr_plan plan;
    int downs_done;
    char what[200];
} sample;

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static unsigned rnd_state = 12345;
static float frand(void) {
    rnd_state = rnd_state * 1664525u + 1013904223u;
    return (float)((rnd_state >> 8) & 0xffffff) / 16777216.0f;
}

/* ---- data ---------------------------------------------------------------- */
static int cmp_scene(const void *a, const void *b) {
    const scene_info *x = (const scene_info *)a, *y = (const scene_info *)b;
    if (x->family != y->family) return x->family - y->family;
    return x->seed - y->seed;
}

static int list_scenes(const char *dir, scene_info *out) {
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < MAX_SCENES) {
        char fam;
        char nm[64];
        int seed;
        if (e->d_name[0] == '.' || sscanf(e->d_name, "%c_%63[a-z]_%d", &fam, nm, &seed) != 3) continue;
        snprintf(out[n].name, sizeof out[n].name, "%.150s", e->d_name);
        out[n].family = fam;
        out[n].seed = seed;
        n++;
    }
    closedir(d);
    qsort(out, (size_t)n, sizeof *out, cmp_scene);
    for (int i = 0; i < n; i++) {
        int last = i + 1 == n || out[i + 1].family != out[i].family;
        int count = 0, pos = 0;
        for (int k = 0; k < n; k++)
            if (out[k].family == out[i].family) {
                if (k < i) pos++;
                count++;
            }
        out[i].split = last ? 2 : (count >= 4 && pos == count - 2) ? 1 : 0;
    }
    return n;
}

static float *read_pass(ewio_file *f, const char *pass, const char *comps, int stride) {
    const int n = ewio_width(f) * ewio_height(f), c = (int)strlen(comps);
    float *tmp = (float *)malloc(sizeof(float) * (size_t)n * (size_t)c);
    float *dst = (float *)calloc((size_t)n * (size_t)stride, sizeof(float));
    char err[512];
    const char *layer = ewio_layer_name(f, 0);
    if (ewio_get_pass(f, layer, pass, comps, tmp, err, sizeof err) != 0) {
        free(tmp);
        free(dst);
        return NULL;
    }
    for (int i = 0; i < n; i++)
        for (int k = 0; k < c; k++) dst[(size_t)i * stride + k] = isfinite(tmp[i * c + k]) ? tmp[i * c + k] : 0.0f;
    free(tmp);
    return dst;
}

static int load_scene(const char *dir, const scene_info *s, source *out) {
    char path[4096];
    memset(out, 0, sizeof *out);
    ewio_file *f = NULL;
    char err[512];
    snprintf(path, sizeof path, "%.3000s/%.150s/f0001_ref1024.exr", dir, s->name);
    if (ewio_read(path, &f, err, sizeof err) != 0) {
        fprintf(stderr, "train_pyramid: %s: %s\n", path, err);
        return -1;
    }
    out->w = ewio_width(f);
    out->h = ewio_height(f);
    out->ref = read_pass(f, "Combined", "RGB", 4);
    ewio_free(f);
    snprintf(path, sizeof path, "%.3000s/%.150s/f0001_spp0004.exr", dir, s->name);
    if (ewio_read(path, &f, err, sizeof err) == 0) {
        out->noisy = read_pass(f, "Combined", "RGB", 4);
        out->normal = read_pass(f, "Denoising Normal", "XYZ", 3);
        out->depth = read_pass(f, "Depth", "Z", 1);
        ewio_free(f);
    }
    snprintf(out->name, sizeof out->name, "%.150s", s->name);
    return out->ref ? 0 : -1;
}

/* Shapes with gradients over a gradient background, stripes and checkers
 * inside some, mild noise; a depth per shape (front to back). */
static void make_procedural(int w, int h, unsigned seed, source *out) {
    memset(out, 0, sizeof *out);
    out->w = w;
    out->h = h;
    out->ref = (float *)calloc((size_t)w * h * 4, sizeof(float));
    out->depth = (float *)calloc((size_t)w * h, sizeof(float));
    unsigned keep = rnd_state;
    rnd_state = seed;
    float b0[3], b1[3];
    for (int c = 0; c < 3; c++) {
        b0[c] = 0.05f + 0.5f * frand();
        b1[c] = 0.05f + 0.5f * frand();
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float t = (float)y / (float)h;
            for (int c = 0; c < 3; c++) out->ref[((size_t)y * w + x) * 4 + c] = b0[c] * (1 - t) + b1[c] * t;
            out->depth[(size_t)y * w + x] = 50.0f;
        }
    const int shapes = 10 + (int)(frand() * 15);
    for (int s = 0; s < shapes; s++) {
        const float cx = frand() * w, cy = frand() * h, r = 6.0f + frand() * 0.3f * (float)w;
        const int disc = frand() < 0.5f, pattern = (int)(frand() * 4);
        const float period = 2.0f + frand() * 10.0f, z = 1.0f + 40.0f * frand();
        float c0[3], c1[3];
        for (int c = 0; c < 3; c++) {
            c0[c] = frand() * frand() * 1.2f;
            c1[c] = frand() * 0.8f;
        }
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                float dx = (float)x - cx, dy = (float)y - cy;
                int in = disc ? dx * dx + dy * dy < r * r : fabsf(dx) < r && fabsf(dy) < 0.6f * r;
                if (!in || z > out->depth[(size_t)y * w + x]) continue;
                float t = 0.5f + 0.5f * dx / r;
                if (pattern == 1) t = fmodf(fabsf(dx), period) < period / 2 ? 0.0f : 1.0f;
                if (pattern == 2) t = (((int)(fabsf(dx) / period) + (int)(fabsf(dy) / period)) & 1) ? 0.0f : 1.0f;
                for (int c = 0; c < 3; c++)
                    out->ref[((size_t)y * w + x) * 4 + c] = c0[c] * (1 - t) + c1[c] * t;
                out->depth[(size_t)y * w + x] = z;
            }
    }
    for (size_t i = 0; i < (size_t)w * h; i++)
        for (int c = 0; c < 3; c++) out->ref[i * 4 + c] = fmaxf(0.0f, out->ref[i * 4 + c] + 0.01f * (frand() - 0.5f));
    snprintf(out->name, sizeof out->name, "procedural-%u", seed);
    rnd_state = keep;
}

/* ---- samples ------------------------------------------------------------- */
enum { K_COLOR_REF, K_COLOR_PROC, K_GI, K_DEPTH };

static void crop(const float *src, int sw, int stride, int x0, int y0, int w, int h, float *dst) {
    for (int y = 0; y < h; y++) memcpy(dst + (size_t)y * w * stride, src + ((size_t)(y0 + y) * sw + x0) * stride, sizeof(float) * (size_t)w * stride);
}

/* Build a sample of a kind from a source (NULL if the source lacks what the
 * kind needs). */
static sample *make_sample(int kind, const source *s, int radius, int size, float variant) {
    if ((kind == K_GI && (!s->noisy || !s->normal || !s->depth)) || (kind == K_DEPTH && !s->depth)) return NULL;
    sample *sm = (sample *)calloc(1, sizeof *sm);
    const int w = size < s->w ? size : s->w, h = size < s->h ? size : s->h;
    const int x0 = (int)(frand() * (float)(s->w - w + 1)), y0 = (int)(frand() * (float)(s->h - h + 1));
    const size_t n = (size_t)w * h;
    ew_bf_model *m = &sm->m;
    m->radius = radius;
    m->sigma = (float)radius / 3.0f;
    m->channels = 3;
    sm->w = w;
    sm->h = h;
    sm->image = (float *)calloc(n * EW_BF_CH, sizeof(float));
    /* the library's layout: (r, g, b, mask 1) */
    if (kind == K_COLOR_REF || kind == K_COLOR_PROC) {
        const float sr = variant < 0.33f ? 0.05f : variant < 0.66f ? 0.1f : 0.2f;
        m->kind = EW_RANGE_COLOR;
        m->inv_2sr2 = 1.0f / (2.0f * sr * sr);
        crop(s->ref, s->w, 4, x0, y0, w, h, sm->image);
        for (size_t i = 0; i < n; i++) sm->image[i * 4 + 3] = 1.0f;
        sm->attr = (float *)malloc(n * 4 * sizeof(float));
        memcpy(sm->attr, sm->image, n * 4 * sizeof(float));
        snprintf(sm->what, sizeof sm->what, "colour sr=%.2f %.150s", (double)sr, s->name);
    } else if (kind == K_GI) {
        m->kind = EW_RANGE_GI;
        m->sigma_alpha = (float)(radius - 1);
        m->sigma_n = 32.0f;
        m->sigma_z = 0.5f;
        crop(s->noisy, s->w, 4, x0, y0, w, h, sm->image);
        for (size_t i = 0; i < n; i++) sm->image[i * 4 + 3] = 1.0f;
        sm->attr = (float *)calloc(n * 5, sizeof(float));
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const size_t i = (size_t)(y0 + y) * s->w + (x0 + x), j = (size_t)y * w + x;
                const float *nv = s->normal + i * 3;
                float l = sqrtf(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
                for (int k = 0; k < 3; k++) sm->attr[j * 5 + k] = l > 1e-6f ? nv[k] / l : 0.0f;
                sm->attr[j * 5 + 3] = s->depth[i] < 1e9f ? s->depth[i] : 1e4f;
                sm->attr[j * 5 + 4] = 1.0f; /* diffuse */
            }
        snprintf(sm->what, sizeof sm->what, "GI %.150s", s->name);
    } else {
        m->kind = EW_RANGE_DEPTH;
        m->channels = 1;
        m->sigma_z = 40.0f;
        float zmax = 0.0f;
        for (size_t i = 0; i < (size_t)s->w * s->h; i++)
            if (s->depth[i] < 1e9f) zmax = fmaxf(zmax, s->depth[i]);
        sm->attr = (float *)malloc(n * sizeof(float));
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const float z = s->depth[(size_t)(y0 + y) * s->w + (x0 + x)];
                const float zn = z < 1e9f && zmax > 0.0f ? z / zmax : 1.0f;
                sm->attr[(size_t)y * w + x] = zn;
                sm->image[((size_t)y * w + x) * 4] = zn;
                sm->image[((size_t)y * w + x) * 4 + 3] = 1.0f;
            }
        snprintf(sm->what, sizeof sm->what, "depth %.150s", s->name);
    }
    m->attrs = ew_bf_attrs(m->kind);
    return sm;
}

static void free_sample(sample *s) {
    if (!s) return;
    free(s->image);
    free(s->attr);
    free(s->gt);
    free(s->out);
    free(s->dout);
    free(s->scratch);
    free(s->gscratch);
    free(s);
}

static void prepare(ew_device *dev, sample *s) {
    const size_t n = (size_t)s->w * s->h;
    s->gt = (float *)malloc(n * EW_BF_CH * sizeof(float));
    s->out = (float *)malloc(n * EW_BF_CH * sizeof(float));
    s->dout = (float *)calloc(n * EW_BF_CH, sizeof(float));
    ew_bf_buffers b = {s->w, s->h, s->image, s->attr, s->gt, 0, s->h};
    dev->backend->bf_brute(dev, &s->m, &b);
    const int levels = ew_pyr_levels(s->m.sigma, s->w, s->h);
    s->scratch = (float *)malloc(ew_pyr_scratch_floats(&s->m, s->w, s->h, levels, 1) * sizeof(float));
    s->gscratch = (float *)malloc(ew_pyr_grad_scratch_floats(s->w, s->h) * sizeof(float));
    ew_pyr_plan_init(&s->plan, &s->m, s->w, s->h, levels, 1, NULL, 1.0f, s->scratch);
    s->downs_done = 0;
}

/* ---- loss ---------------------------------------------------------------- */
static float tone(float x) { return x <= 0.0f ? 0.0f : x >= 1.0f ? 1.0f : powf(x, 1.0f / 2.2f); }
static float dtone(float x) { return x <= 0.0f || x >= 1.0f ? 0.0f : (1.0f / 2.2f) * powf(fmaxf(x, 1e-3f), 1.0f / 2.2f - 1.0f); }

/* forward; loss = mean squared display error; fills dout when grad */
static double forward_loss(sample *s, const ew_pyr_params *prm, int grad) {
    for (int l = 0; l < s->plan.levels; l++) ew_pyr_expand(&prm[l], &s->plan.rows[l]);
    ew_pyr_forward1(&s->plan, s->image, s->attr, s->out, s->downs_done);
    s->downs_done = 1;
    const size_t n = (size_t)s->w * s->h;
    const int C = s->m.channels;
    double se = 0.0;
    const double norm = 1.0 / ((double)n * C);
    /* results are (colour x mask, mask): the colour is out / mask, so
     * dL/dout_c = dL/dcol_c / M and dL/dM = -sum_c dL/dcol_c col_c / M */
    for (size_t i = 0; i < n; i++) {
        const float *o = s->out + i * 4, *g = s->gt + i * 4;
        const float M = o[3], GM = g[3];
        double dm = 0.0;
        for (int c = 0; c < C; c++) {
            const float col = M > 0.0f ? o[c] / M : 0.0f, ref = GM > 0.0f ? g[c] / GM : 0.0f;
            const float d = tone(col) - tone(ref);
            se += (double)d * d;
            if (grad && M > 0.0f) {
                const float dcol = (float)(2.0 * norm) * d * dtone(col);
                s->dout[i * 4 + c] = dcol / M;
                dm -= (double)dcol * col / M;
            }
        }
        if (grad) s->dout[i * 4 + 3] = (float)dm;
    }
    return se * norm;
}

static double psnr_of(double mse) { return mse > 0 ? 10.0 * log10(1.0 / mse) : 99.0; }

/* ---- optimisation ------------------------------------------------------- */
typedef struct {
    sample **s;
    int n;
    const ew_pyr_params *prm;
    int levels, grad;
    double loss[MAX_SAMPLES];
    double *g; /* threads x levels x NPARAM */
} batch_job;

static void batch_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    batch_job *j = (batch_job *)ctx;
    for (int64_t i = begin; i < end; i++) {
        sample *s = j->s[i];
        j->loss[i] = forward_loss(s, j->prm, j->grad);
        if (j->grad)
            ew_pyr_backward1(&s->plan, s->image, s->attr, s->out, s->dout, s->gscratch,
                             j->g + (size_t)tid * j->levels * EW_PYR_NPARAM);
    }
}

static double run_batch(ew_device *dev, sample **s, int n, const ew_pyr_params *prm, int levels, double *grad,
                        double *per_sample) {
    const int T = ew_device_get_num_threads(dev);
    batch_job j;
    memset(&j, 0, sizeof j);
    j.s = s;
    j.n = n;
    j.prm = prm;
    j.levels = levels;
    j.grad = grad != NULL;
    j.g = grad ? (double *)calloc((size_t)T * levels * EW_PYR_NPARAM, sizeof(double)) : NULL;
    ew_pool_run(dev->pool, n, 1, batch_rows, &j);
    double L = 0.0;
    for (int i = 0; i < n; i++) {
        L += j.loss[i] / n;
        if (per_sample) per_sample[i] = j.loss[i];
    }
    if (grad) {
        memset(grad, 0, sizeof(double) * levels * EW_PYR_NPARAM);
        for (int t = 0; t < T; t++)
            for (int k = 0; k < levels * EW_PYR_NPARAM; k++) grad[k] += j.g[(size_t)t * levels * EW_PYR_NPARAM + k] / n;
        free(j.g);
    }
    return L;
}

/* weights onto [0, 1] with the Eq. 2g centre >= 0, gamma onto [0, 4] */
static void project(ew_pyr_params *p) {
    for (int k = 0; k < 9; k++) {
        if (k != 4) p->wf[k] = fminf(fmaxf(p->wf[k], 0.0f), 1.0f);
        p->wc[k] = fminf(fmaxf(p->wc[k], 0.0f), 1.0f);
    }
    p->gamma = fminf(fmaxf(p->gamma, 0.0f), 4.0f);
    float c = ew_pyr_centre_weight(p);
    if (c < 0.0f) {
        const float rest = 1.0f - c, s = 1.0f / rest;
        for (int k = 0; k < 9; k++) {
            if (k != 4) p->wf[k] *= s;
            p->wc[k] *= s;
        }
    }
    p->wf[4] = fmaxf(ew_pyr_centre_weight(p), 0.0f);
}

static void train_node(ew_device *dev, sample **tr, int ntr, int levels, int iters, ew_pyr_params *prm, FILE *log,
                       double *loss0, double *loss1) {
    const int P = levels * EW_PYR_NPARAM;
    double *g = (double *)calloc((size_t)P, sizeof(double)), *mom = (double *)calloc((size_t)P, sizeof(double));
    double *vel = (double *)calloc((size_t)P, sizeof(double));
    ew_pyr_params best[EW_PYR_MAX_LEVELS];
    memcpy(best, prm, sizeof(ew_pyr_params) * levels);
    double lr = 0.004, L = run_batch(dev, tr, ntr, prm, levels, g, NULL);
    *loss0 = L;
    int t = 0;
    for (int it = 0; it < iters && lr > 1e-5; it++) {
        t++;
        for (int l = 0; l < levels; l++) {
            float *f = (float *)&prm[l];
            for (int k = 0; k < EW_PYR_NPARAM; k++) {
                if (k == 4) continue;
                const int i = l * EW_PYR_NPARAM + k;
                mom[i] = 0.9 * mom[i] + 0.1 * g[i];
                vel[i] = 0.999 * vel[i] + 0.001 * g[i] * g[i];
                const double mh = mom[i] / (1.0 - pow(0.9, t)), vh = vel[i] / (1.0 - pow(0.999, t));
                f[k] -= (float)(lr * mh / (sqrt(vh) + 1e-12));
            }
            project(&prm[l]);
        }
        double Ln = run_batch(dev, tr, ntr, prm, levels, g, NULL);
        if (Ln > L) { /* the paper's rule: reject a step that makes it worse; restart Adam smaller */
            memcpy(prm, best, sizeof(ew_pyr_params) * levels);
            lr *= 0.5;
            memset(mom, 0, sizeof(double) * (size_t)P);
            memset(vel, 0, sizeof(double) * (size_t)P);
            t = 0;
            L = run_batch(dev, tr, ntr, prm, levels, g, NULL);
            continue;
        }
        L = Ln;
        lr = fmin(lr * 1.05, 0.02);
        memcpy(best, prm, sizeof(ew_pyr_params) * levels);
        if (log && (it % 25 == 0 || it == iters - 1))
            fprintf(log, "    iter %4d  loss %.4e  (%.2f dB)  lr %.4g\n", it, L, psnr_of(L), lr);
    }
    memcpy(prm, best, sizeof(ew_pyr_params) * levels);
    *loss1 = L;
    free(g);
    free(mom);
    free(vel);
}

/* ---- output -------------------------------------------------------------- */
/* The table a --model writes: its file name (without .ewpw), the log's and
 * the library's array. */
typedef struct {
    const char *name, *file, *log, *array;
    float analytic_gamma; /* the library's analytic setting for these targets */
} model_spec;

static const model_spec models[] = {
    {"all", "pyramid", "training-log.txt", "ew_pyr_builtin_weights", 1.0f},
    {"gi", "pyramid_gi", "training-log-gi.txt", "ew_pyr_builtin_weights_gi", 0.0f},
};

static int write_outputs(const ew_pyr_table *t, const model_spec *ms, const char *out_dir, const char *c_out) {
    size_t n = ew_pyr_table_write(t, NULL, 0);
    unsigned char *buf = n ? (unsigned char *)malloc(n) : NULL;
    if (!buf || ew_pyr_table_write(t, buf, n) != n) {
        fprintf(stderr, "train_pyramid: out of memory writing the table\n");
        free(buf);
        return -1;
    }
    ew_pyr_table check;
    char why[200];
    if (ew_pyr_table_parse(buf, n, &check, why, sizeof why) != EW_OK) {
        fprintf(stderr, "train_pyramid: the table does not validate: %s\n", why);
        free(buf);
        return -1;
    }
    char path[4096], tmp[4200];
    snprintf(path, sizeof path, "%.4000s/%s.ewpw", out_dir, ms->file);
    snprintf(tmp, sizeof tmp, "%.4096s.tmp", path);
    FILE *f = fopen(tmp, "wb");
    if (!f || fwrite(buf, 1, n, f) != n || fclose(f) != 0 || rename(tmp, path) != 0) {
        fprintf(stderr, "train_pyramid: cannot write %s\n", path);
        free(buf);
        return -1;
    }
    if (c_out) {
        snprintf(tmp, sizeof tmp, "%.4000s.tmp", c_out);
        f = fopen(tmp, "w");
        if (!f) {
            free(buf);
            return -1;
        }
        fprintf(f, "/* The trained pyramid weights built into the library: a byte-for-byte copy\n"
                   " * of models/pyramid/%s.ewpw (%zu bytes), written by tools/train_pyramid --model %s\n"
                   " * (models/pyramid/README.md). Validated when a filter commits. */\n"
                   "#include <stddef.h>\n\n"
                   "extern const unsigned char %s[];\n"
                   "extern const size_t %s_size;\n\n"
                   "const unsigned char %s[] = {\n",
                ms->file, n, ms->name, ms->array, ms->array, ms->array);
        for (size_t i = 0; i < n; i++) fprintf(f, "%s0x%02x,%s", i % 16 ? " " : "    ", buf[i], i % 16 == 15 || i + 1 == n ? "\n" : "");
        fprintf(f, "};\nconst size_t %s_size = %zu;\n", ms->array, n);
        if (fclose(f) != 0 || rename(tmp, c_out) != 0) {
            free(buf);
            return -1;
        }
    }
    free(buf);
    return 0;
}

int main(int argc, char **argv) {
    const char *data = NULL, *out_dir = "models/pyramid", *c_out = NULL, *radii_s = "1,2,3,4,6,8,12,16,24,32,48,64";
    int iters = 150, iters_large = -1, threads = 0, quick = 0, resume = 0;
    const model_spec *ms = &models[0];
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--data") && v) { data = v; i++; }
        else if (!strcmp(a, "--out") && v) { out_dir = v; i++; }
        else if (!strcmp(a, "--c-out") && v) { c_out = v; i++; }
        else if (!strcmp(a, "--model") && v && (!strcmp(v, "all") || !strcmp(v, "gi"))) {
            ms = &models[strcmp(v, "gi") == 0];
            i++;
        }
        else if (!strcmp(a, "--iters") && v) { iters = atoi(v); i++; }
        else if (!strcmp(a, "--iters-large") && v) { iters_large = atoi(v); i++; }
        else if (!strcmp(a, "--resume")) resume = 1;
        else if (!strcmp(a, "--threads") && v) { threads = atoi(v); i++; }
        else if (!strcmp(a, "--radii") && v) { radii_s = v; i++; }
        else if (!strcmp(a, "--quick")) quick = 1;
        else {
            fprintf(stderr, "usage: train_pyramid --data DIR [--out DIR] [--c-out FILE.c] [--model all|gi] [--iters N] "
                            "[--iters-large N] [--threads N] [--radii 1,2,...] [--resume] [--quick]\n");
            return 2;
        }
    }
    if (!data) {
        fprintf(stderr, "train_pyramid: --data DIR is required (../shared/data/cycles-train)\n");
        return 2;
    }
    int radii[32], nr = 0;
    for (const char *p = radii_s; *p && nr < 32;) {
        radii[nr++] = atoi(p);
        while (*p && *p != ',') p++;
        if (*p == ',') p++;
    }
    scene_info scenes[MAX_SCENES];
    const int ns = list_scenes(data, scenes);
    if (ns <= 0) {
        fprintf(stderr, "train_pyramid: no scenes in '%s'\n", data);
        return 1;
    }
    source train_src[MAX_SCENES], val_src[MAX_SCENES];
    int ntrain = 0, nval = 0;
    for (int i = 0; i < ns; i++) {
        if (scenes[i].split == 2) continue; /* test scenes are never read */
        source *dst = scenes[i].split == 0 ? &train_src[ntrain] : &val_src[nval];
        if (load_scene(data, &scenes[i], dst) != 0) continue;
        if (scenes[i].split == 0) ntrain++;
        else nval++;
    }
    const int gi_only = ms != &models[0]; /* procedural images have no GI passes */
    const int nproc_train = gi_only ? 0 : quick ? 2 : 8, nproc_val = gi_only ? 0 : quick ? 1 : 3;
    for (int i = 0; i < nproc_train; i++) make_procedural(256, 256, 1000u + (unsigned)i, &train_src[ntrain++]);
    for (int i = 0; i < nproc_val; i++) make_procedural(256, 256, 9000u + (unsigned)i, &val_src[nval++]);
    char logpath[4096];
    snprintf(logpath, sizeof logpath, "%.4000s/%s", out_dir, ms->log);
    ew_pyr_table table;
    memset(&table, 0, sizeof table);
    if (resume) { /* the nodes trained so far */
        char wpath[4096];
        snprintf(wpath, sizeof wpath, "%.4000s/%s.ewpw", out_dir, ms->file);
        FILE *wf = fopen(wpath, "rb");
        static unsigned char wbuf[1 << 20];
        size_t wn = wf ? fread(wbuf, 1, sizeof wbuf, wf) : 0;
        if (wf) fclose(wf);
        char why[200];
        if (wn && ew_pyr_table_parse(wbuf, wn, &table, why, sizeof why) != EW_OK) {
            fprintf(stderr, "train_pyramid: --resume: %s: %s\n", wpath, why);
            return 1;
        }
    }
    FILE *log = fopen(logpath, resume ? "a" : "w");
    if (!log) {
        fprintf(stderr, "train_pyramid: cannot write %s\n", logpath);
        return 1;
    }
    fprintf(log, "train_pyramid: %d training sources (%d procedural), %d validation sources (%d procedural); "
                 "test scenes held out:",
            ntrain, nproc_train, nval, nproc_val);
    for (int i = 0; i < ns; i++)
        if (scenes[i].split == 2) fprintf(log, " %s", scenes[i].name);
    fprintf(log, "\nvalidation scenes:");
    for (int i = 0; i < ns; i++)
        if (scenes[i].split == 1) fprintf(log, " %s", scenes[i].name);
    fprintf(log, "\nmodel %s, iterations %d, radii %s\n\n", ms->name, iters, radii_s);
    fflush(log);

    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    if (ew_device_create(&desc, &dev) != EW_OK) return 1;
    double t_start = now_s();
    for (int r = 0; r < nr; r++) {
        const int R = radii[r], size = R <= 16 ? 128 : 256;
        const float sigma = (float)R / 3.0f;
        int have = 0;
        for (int k = 0; k < table.nodes; k++) have |= fabsf(table.log2_sigma[k] - log2f(sigma)) < 1e-4f;
        if (have) continue; /* --resume: already trained */
        const int node_iters = R >= 24 && iters_large >= 0 ? iters_large : iters;
        double t0 = now_s();
        rnd_state = 777u + (unsigned)R;
        sample *tr[MAX_SAMPLES], *va[MAX_SAMPLES];
        int ntr = 0, nva = 0;
        /* training: per source a colour sample; GI and depth where the
         * source has them (renders). GI only: a GI sample of every render. */
        for (int i = 0; i < ntrain && ntr < MAX_SAMPLES - 3 && gi_only; i++) {
            sample *s = make_sample(K_GI, &train_src[i], R, size, 0);
            if (s) tr[ntr++] = s;
            if (quick && ntr >= 3) break;
        }
        for (int i = 0; i < nval && nva < MAX_SAMPLES - 3 && gi_only; i++) {
            sample *s = make_sample(K_GI, &val_src[i], R, size, 0);
            if (s) va[nva++] = s;
        }
        for (int i = 0; i < ntrain && ntr < MAX_SAMPLES - 3 && !gi_only; i++) {
            int proc = train_src[i].noisy == NULL;
            sample *s = make_sample(proc ? K_COLOR_PROC : K_COLOR_REF, &train_src[i], R, size, frand());
            if (s) tr[ntr++] = s;
            if (!proc && (i % 2 == 0) && (s = make_sample(K_GI, &train_src[i], R, size, 0))) tr[ntr++] = s;
            if ((i % 3 == 1) && (s = make_sample(K_DEPTH, &train_src[i], R, size, 0))) tr[ntr++] = s;
            if (quick && ntr >= 6) break;
        }
        for (int i = 0; i < nval && nva < MAX_SAMPLES - 3 && !gi_only; i++) {
            int proc = val_src[i].noisy == NULL;
            sample *s = make_sample(proc ? K_COLOR_PROC : K_COLOR_REF, &val_src[i], R, size, frand());
            if (s) va[nva++] = s;
            if (!proc && (s = make_sample(K_GI, &val_src[i], R, size, 0))) va[nva++] = s;
            if (!proc && (s = make_sample(K_DEPTH, &val_src[i], R, size, 0))) va[nva++] = s;
            if (quick && nva >= 3) break;
        }
        for (int i = 0; i < ntr; i++) prepare(dev, tr[i]);
        for (int i = 0; i < nva; i++) prepare(dev, va[i]);
        const double t_gt = now_s() - t0;
        const int levels = tr[0]->plan.levels;
        ew_pyr_params prm[EW_PYR_MAX_LEVELS], ana[EW_PYR_MAX_LEVELS];
        for (int l = 0; l < levels; l++) {
            ew_pyr_analytic(sigma, l, ms->analytic_gamma, &prm[l]);
            ana[l] = prm[l];
        }
        double vl_ana[MAX_SAMPLES], vl_tr[MAX_SAMPLES];
        const double va0 = run_batch(dev, va, nva, ana, levels, NULL, vl_ana);
        fprintf(log, "radius %d (sigma %.3f, %d levels, %d iterations): %d training samples, %d validation samples, "
                     "exact filter in %.1f s\n",
                R, (double)sigma, levels, node_iters, ntr, nva, t_gt);
        double l0, l1;
        train_node(dev, tr, ntr, levels, node_iters, prm, log, &l0, &l1);
        const double va1 = run_batch(dev, va, nva, prm, levels, NULL, vl_tr);
        fprintf(log, "  training loss %.4e -> %.4e (%.2f -> %.2f dB)\n", l0, l1, psnr_of(l0), psnr_of(l1));
        fprintf(log, "  validation mean MSE: analytic %.4e (%.2f dB), trained %.4e (%.2f dB)\n", va0, psnr_of(va0),
                va1, psnr_of(va1));
        for (int i = 0; i < nva; i++)
            fprintf(log, "    %-48s analytic %6.2f dB  trained %6.2f dB\n", va[i]->what, psnr_of(vl_ana[i]),
                    psnr_of(vl_tr[i]));
        for (int l = 0; l < levels; l++) {
            const ew_pyr_params *q = &prm[l];
            fprintf(log, "  level %d: wf", l);
            for (int k = 0; k < 9; k++) fprintf(log, " %.4f", (double)q->wf[k]);
            fprintf(log, " | wc");
            for (int k = 0; k < 9; k++) fprintf(log, " %.4f", (double)q->wc[k]);
            fprintf(log, " | gamma %.3f\n", (double)q->gamma);
        }
        fprintf(log, "  (%.1f s)\n\n", now_s() - t0);
        fflush(log);
        /* add the node, keeping nodes sorted by sigma */
        int at = table.nodes;
        while (at > 0 && table.log2_sigma[at - 1] > log2f(sigma)) {
            table.log2_sigma[at] = table.log2_sigma[at - 1];
            memcpy(table.p[at], table.p[at - 1], sizeof table.p[at]);
            at--;
        }
        table.log2_sigma[at] = log2f(sigma);
        for (int l = 0; l < EW_PYR_MAX_LEVELS; l++) ew_pyr_identity(&table.p[at][l]);
        for (int l = 0; l < levels; l++) table.p[at][l] = prm[l];
        table.nodes++;
        if (levels > table.levels) table.levels = levels;
        if (write_outputs(&table, ms, out_dir, c_out) != 0) return 1;
        printf("radius %2d: validation %.2f dB analytic -> %.2f dB trained (%.0f s)\n", R, psnr_of(va0), psnr_of(va1),
               now_s() - t0);
        fflush(stdout);
        for (int i = 0; i < ntr; i++) free_sample(tr[i]);
        for (int i = 0; i < nva; i++) free_sample(va[i]);
    }
    fprintf(log, "total %.0f s\n", now_s() - t_start);
    fclose(log);
    ew_device_destroy(dev);
    return 0;
}
