/* Training: the whole pipeline's gradient (L1 on tone-mapped colour ->
 * remodulation -> blend -> slice -> splat -> sigmoid -> convolutions)
 * against central finite differences w.r.t. a few GuideNet weights; the
 * training forward pass against the "nbg" op; augmentation; determinism
 * across thread counts; Adam; clipping. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/bgrid.h"
#include "algorithms/train.h"
#include "src/internal.h"

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

static ew_device *make_device(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

/* A small synthetic render: two regions of different albedo and normal, a
 * light gradient, noise, a zero-albedo corner, and its noise-free reference. */
typedef struct {
    int w, h;
    float *color, *albedo, *normal, *depth, *ref;
} scene;

static void scene_make(scene *s, int w, int h, unsigned seed) {
    const long n = (long)w * h;
    s->w = w; s->h = h;
    s->color = malloc(sizeof(float) * n * 3); s->albedo = malloc(sizeof(float) * n * 3);
    s->normal = malloc(sizeof(float) * n * 3); s->depth = malloc(sizeof(float) * n); s->ref = malloc(sizeof(float) * n * 3);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            long j = (long)y * w + x;
            int right = x * 3 > w + y;
            float light = 0.2f + 0.8f * (float)y / h;
            for (int k = 0; k < 3; k++) {
                float a = right ? 0.7f - 0.2f * k : 0.2f + 0.1f * k;
                if (x < 4 && y < 4) a = 0.0f; /* an emitter-like black albedo corner */
                s->albedo[j * 3 + k] = a;
                s->ref[j * 3 + k] = (a + 0.05f) * light;
                s->color[j * 3 + k] = s->ref[j * 3 + k] * (0.2f + 1.6f * urand(&seed));
            }
            s->normal[j * 3] = right ? 0.6f : -0.3f;
            s->normal[j * 3 + 1] = right ? 0.0f : 0.5f;
            s->normal[j * 3 + 2] = 0.8f;
            s->depth[j] = right ? 3.0f : 5.0f + 0.01f * x;
        }
}

static void scene_free(scene *s) {
    free(s->color); free(s->albedo); free(s->normal); free(s->depth); free(s->ref);
}

static int frame_zero(void *user, double u) {
    (void)user;
    (void)u;
    return 0;
}

/* A random net whose output layer is scaled up so the guides spread over
 * the range (the trainer's init keeps them near the middle on purpose),
 * but not so far that the sigmoids saturate: s (1 - s) of a saturated float
 * sigmoid has few correct digits. The 7-layer net's output layer sums 45
 * planes, not 20, hence a smaller factor. */
static float *make_params(const ew_guidenet *net, uint64_t seed) {
    float *p = malloc(sizeof(float) * net->nparams);
    ew_guidenet_random(net, seed, p);
    const ew_gn_layer *L = &net->layers[net->nlayers - 1];
    const float k = net->nlayers > 2 ? 4.0f : 12.0f;
    for (size_t i = 0; i < (size_t)L->cin * L->cout * 25; i++) p[L->w_off + i] *= k;
    return p;
}

/* ---- the whole pipeline in double, for finite differences ------------------
 * Straight from the paper: convolutions with zero padding, sigmoid, guides
 * x255, splat (Eq. 10), slice over non-empty cells (Eq. 13), stick-breaking
 * blend, remodulation, the loss's tone curve and L1. Patch at (x0, y0) of
 * frame f without symmetry. */
static double tent_d(double a) {
    double v = 1.0 - sqrt(a * a + 1e-7);
    return v > 0 ? v : 0;
}

static double act_d(double v, int act) {
    if (act == EW_ACT_LEAKY) return v > 0 ? v : 0.2 * v;
    if (act == EW_ACT_SIGMOID) return 1.0 / (1.0 + exp(-v));
    return v;
}

static double tm_d(double x) {
    const double g = 1 / 2.2, e0 = pow(1e-3, g);
    return x > 1 ? pow(1.001, g) - e0 + 0.1 * log(x) : pow(fmax(x, 0) + 1e-3, g) - e0;
}

static double pipeline_d(const ew_guidenet *net, const double *params, const ew_train_frame *f, int x0, int y0, int P,
                         const float *ref_tm) {
    const long n = (long)P * P, fn = (long)f->width * f->height;
    double *feat = calloc((size_t)net->nfeat * n, sizeof(double)), *out = calloc((size_t)net->nout * n, sizeof(double));
    for (int c = 0; c < EW_GN_INPUTS; c++)
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++) feat[c * n + y * P + x] = f->input[c * fn + (long)(y0 + y) * f->width + x0 + x];
    for (int l = 0; l < net->nlayers; l++) {
        const ew_gn_layer *L = &net->layers[l];
        for (int co = 0; co < L->cout; co++)
            for (int y = 0; y < P; y++)
                for (int x = 0; x < P; x++) {
                    double acc = params[L->b_off + co];
                    for (int ci = 0; ci < L->cin; ci++)
                        for (int k = 0; k < 25; k++) {
                            int yy = y + k / 5 - 2, xx = x + k % 5 - 2;
                            if (yy >= 0 && yy < P && xx >= 0 && xx < P)
                                acc += params[L->w_off + ((size_t)co * L->cin + ci) * 25 + k] * feat[(L->in_plane + ci) * n + yy * P + xx];
                        }
                    double v = act_d(acc, L->act);
                    if (L->out_plane < 0) out[co * n + y * P + x] = v;
                    else feat[(L->out_plane + co) * n + y * P + x] = v;
                }
    }
    double *rgb = calloc((size_t)n * 3, sizeof(double));
    for (int g = 0; g < net->ngrids; g++) {
        ew_bgrid_params gp;
        ew_bgrid_params_init(&gp, P, P, net->rate_s[g], net->rate_d[g], 3);
        double *grid = calloc((size_t)gp.gw * gp.gh * gp.gd * 4, sizeof(double));
        /* splat: scatter every pixel into the cells of its support */
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++) {
                double px = (x + 0.5) / gp.rate_s - 0.5, py = (y + 0.5) / gp.rate_s - 0.5;
                double pz = 255.0 * out[g * n + y * P + x] / gp.rate_d - 0.5;
                const float *rad = f->radiance + ((long)(y0 + y) * f->width + x0 + x) * 3;
                for (int v = (int)floor(py); v <= (int)floor(py) + 1; v++)
                    for (int u = (int)floor(px); u <= (int)floor(px) + 1; u++)
                        for (int z = (int)floor(pz); z <= (int)floor(pz) + 1; z++) {
                            if (u < 0 || v < 0 || z < 0 || u >= gp.gw || v >= gp.gh || z >= gp.gd) continue;
                            double w = tent_d(px - u) * tent_d(py - v) * tent_d(pz - z);
                            double *cell = grid + (((long)v * gp.gw + u) * gp.gd + z) * 4;
                            for (int c = 0; c < 3; c++) cell[c] += w * rad[c];
                            cell[3] += w;
                        }
            }
        for (long i = 0; i < (long)gp.gw * gp.gh * gp.gd; i++)
            if (grid[i * 4 + 3] > 0)
                for (int c = 0; c < 3; c++) grid[i * 4 + c] /= grid[i * 4 + 3];
        /* slice and blend */
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++) {
                long j = (long)y * P + x;
                double px = (x + 0.5) / gp.rate_s - 0.5, py = (y + 0.5) / gp.rate_s - 0.5;
                double pz = 255.0 * out[g * n + j] / gp.rate_d - 0.5, acc[4] = {0, 0, 0, 0};
                for (int v = (int)floor(py); v <= (int)floor(py) + 1; v++)
                    for (int u = (int)floor(px); u <= (int)floor(px) + 1; u++)
                        for (int z = (int)floor(pz); z <= (int)floor(pz) + 1; z++) {
                            if (u < 0 || v < 0 || z < 0 || u >= gp.gw || v >= gp.gh || z >= gp.gd) continue;
                            const double *cell = grid + (((long)v * gp.gw + u) * gp.gd + z) * 4;
                            if (cell[3] <= 0) continue;
                            double w = tent_d(px - u) * tent_d(py - v) * tent_d(pz - z);
                            for (int c = 0; c < 3; c++) acc[c] += w * cell[c];
                            acc[3] += w;
                        }
                double wg = 1.0;
                if (net->ngrids == 3) {
                    double s0 = out[3 * n + j], s1 = out[4 * n + j];
                    wg = g == 0 ? s0 : g == 1 ? (1 - s0) * s1 : (1 - s0) * (1 - s1);
                }
                for (int c = 0; c < 3; c++) rgb[j * 3 + c] += wg * acc[c] / acc[3];
            }
        free(grid);
    }
    double L = 0;
    for (long j = 0; j < n; j++)
        for (int c = 0; c < 3; c++) {
            double o = rgb[j * 3 + c] * f->albedo_f[((long)(y0 + j / P) * f->width + x0 + j % P) * 3 + c];
            L += fabs(tm_d(o) - ref_tm[j * 3 + c]);
        }
    free(feat); free(out); free(rgb);
    return L / (double)(n * 3);
}

static int end_to_end_fd(const char *arch, unsigned seed) {
    ew_guidenet net;
    char err[128];
    if (ew_guidenet_init(&net, arch, err, sizeof err)) return 0;
    scene sc;
    scene_make(&sc, 40, 36, seed);
    ew_train_frame f;
    ew_train_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f);
    const int P = 24;
    float *params = make_params(&net, seed);
    ew_train_model m;
    ew_train_model_init(&m, &net);
    ew_train_scratch *s = ew_train_scratch_create(&net, P);
    ew_patch_ref r = {0, 5, 3, 0};
    /* keep the L1 away from its kink: the reference sits 0.25 above the
     * output everywhere, so |S(out) - ref| is smooth in the weights */
    float *out = malloc(sizeof(float) * P * P * 3), *tm = malloc(sizeof(float) * P * P * 3);
    ew_train_model_prepare(&m, params);
    ew_train_patch(&m, &f, &r, P, s, NULL, out, NULL);
    for (int i = 0; i < P * P * 3; i++) tm[i] = ew_nbg_tm(out[i]) + 0.25f;
    float *grad = calloc(net.nparams, sizeof(float));
    double loss = ew_train_patch(&m, &f, &r, P, s, grad, NULL, tm);
    double *pd = malloc(sizeof(double) * net.nparams);
    for (size_t i = 0; i < net.nparams; i++) pd[i] = params[i];
    double loss_d = pipeline_d(&net, pd, &f, r.x0, r.y0, P, tm);
    /* central differences in double, a few weights of every layer and a bias */
    double worst = 0, gmax = 0;
    unsigned pick = seed * 7 + 1;
    int checked = 0;
    size_t idx[64];
    double fds[64];
    for (int l = 0; l < net.nlayers; l++)
        for (int t = 0; t < 4; t++) {
            const ew_gn_layer *L = &net.layers[l];
            size_t i = t < 3 ? L->w_off + (size_t)(urand(&pick) * L->cin * L->cout * 25) : L->b_off + (size_t)(urand(&pick) * L->cout);
            const double h = 1e-6;
            double keep = pd[i];
            pd[i] = keep + h;
            double lp = pipeline_d(&net, pd, &f, r.x0, r.y0, P, tm);
            pd[i] = keep - h;
            double lm = pipeline_d(&net, pd, &f, r.x0, r.y0, P, tm);
            pd[i] = keep;
            idx[checked] = i;
            fds[checked] = (lp - lm) / (2 * h);
            gmax = fmax(gmax, fabs(fds[checked]));
            checked++;
        }
    for (int k = 0; k < checked; k++) {
        /* relative, with a floor of 5% of the largest: the float kernels
         * resolve the smallest ones only to that. (The tent's rounded peak,
         * 1 - sqrt(a^2 + 1e-7), turns its slope from +1 to -1 within
         * |a| < 3e-4 of a cell centre; float grid positions are good to
         * ~3e-6 there, i.e. ~1% of such a term.) */
        double e = fabs(grad[idx[k]] - fds[k]) / fmax(fmax(fabs(grad[idx[k]]), fabs(fds[k])), 5e-2 * gmax);
        if (e > 0.01) fprintf(stderr, "  %s param %zu: analytic %.6g, finite differences %.6g\n", arch, idx[k], grad[idx[k]], fds[k]);
        worst = fmax(worst, e);
    }
    fprintf(stderr,
            "  %s end to end: loss %.6f (double pipeline %.6f); max relative error vs finite differences over %d "
            "weights/biases: %.2e\n",
            arch, loss, loss_d, checked, worst);
    free(params); free(out); free(tm); free(grad); free(pd);
    ew_train_scratch_destroy(s);
    ew_train_model_free(&m);
    ew_train_frame_free(&f);
    scene_free(&sc);
    return worst < 0.01 && fabs(loss - loss_d) < 1e-5;
}

TEST(end_to_end_gradient_2layer_3grid) { CHECK(end_to_end_fd("2layer-3grid", 1)); }
TEST(end_to_end_gradient_2layer_1grid) { CHECK(end_to_end_fd("2layer-1grid", 2)); }
TEST(end_to_end_gradient_7layer_3grid) { CHECK(end_to_end_fd("7layer-3grid", 3)); }

/* The trainer's forward pass is the op's: same image out of a patch that
 * covers the whole frame (no symmetry) as out of ew_denoiser "nbg". */
TEST(training_forward_equals_the_op) {
    ew_guidenet net;
    char err[128];
    ew_guidenet_init(&net, "2layer-3grid", err, sizeof err);
    scene sc;
    scene_make(&sc, 48, 48, 4);
    float *params = make_params(&net, 9);
    ew_train_frame f;
    ew_train_frame_init(&f, 48, 48, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f);
    ew_train_model m;
    ew_train_model_init(&m, &net);
    ew_train_model_prepare(&m, params);
    ew_train_scratch *s = ew_train_scratch_create(&net, 48);
    float *train_out = malloc(sizeof(float) * 48 * 48 * 3), *op_out = malloc(sizeof(float) * 48 * 48 * 3);
    ew_patch_ref r = {0, 0, 0, 0};
    ew_train_patch(&m, &f, &r, 48, s, NULL, train_out, NULL);

    void *bytes;
    size_t size;
    CHECK_EQ_INT(ew_guidenet_save(&net, params, &bytes, &size), 0);
    ew_device *dev = make_device(2);
    ew_denoiser *d = NULL;
    ew_image c = ew_image_packed(sc.color, 48, 48, 3), a = ew_image_packed(sc.albedo, 48, 48, 3);
    ew_image nn = ew_image_packed(sc.normal, 48, 48, 3), dp = ew_image_packed(sc.depth, 48, 48, 1);
    ew_image o = ew_image_packed(op_out, 48, 48, 3);
    CHECK_EQ_INT(ew_denoiser_create(dev, "nbg", &d), EW_OK);
    /* the method itself, as training sees it: without the op layer's do-no-harm stage */
    CHECK_EQ_INT(ew_denoiser_set_int(d, "do_no_harm", 0), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_float(d, "outlier_k", 0.0f), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_data(d, "weights", bytes, size), EW_OK);
    ew_denoiser_set_image(d, "color", &c);
    ew_denoiser_set_image(d, "albedo", &a);
    ew_denoiser_set_image(d, "normal", &nn);
    ew_denoiser_set_image(d, "depth", &dp);
    ew_denoiser_set_image(d, "output", &o);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    double worst = 0;
    for (int i = 0; i < 48 * 48 * 3; i++) worst = fmax(worst, fabs(train_out[i] - op_out[i]) / (1 + fabs(op_out[i])));
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
    free(bytes); free(params); free(train_out); free(op_out);
    ew_train_scratch_destroy(s);
    ew_train_model_free(&m);
    ew_train_frame_free(&f);
    scene_free(&sc);
    CHECK(worst < 1e-5);
}

/* A symmetric patch is the patch of the symmetric frame: flip x of a frame
 * whose inputs are mirrored (normal x negated) gives the mirrored output. */
TEST(augmentation_is_a_symmetry) {
    ew_guidenet net;
    char err[128];
    ew_guidenet_init(&net, "2layer-3grid", err, sizeof err);
    scene a;
    scene_make(&a, 32, 32, 5);
    scene b;
    scene_make(&b, 32, 32, 5);
    /* b = a transposed (x <-> y), normals swapped */
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 32; x++) {
            long ja = (long)y * 32 + x, jb = (long)x * 32 + y;
            for (int k = 0; k < 3; k++) {
                b.color[jb * 3 + k] = a.color[ja * 3 + k];
                b.albedo[jb * 3 + k] = a.albedo[ja * 3 + k];
                b.ref[jb * 3 + k] = a.ref[ja * 3 + k];
            }
            b.normal[jb * 3] = a.normal[ja * 3 + 1];
            b.normal[jb * 3 + 1] = a.normal[ja * 3];
            b.normal[jb * 3 + 2] = a.normal[ja * 3 + 2];
            b.depth[jb] = a.depth[ja];
        }
    ew_train_frame f[2];
    ew_train_frame_init(&f[0], 32, 32, a.color, a.albedo, a.normal, a.depth, a.ref, 3.0f);
    ew_train_frame_init(&f[1], 32, 32, b.color, b.albedo, b.normal, b.depth, b.ref, 3.0f);
    float *params = make_params(&net, 10);
    ew_train_model m;
    ew_train_model_init(&m, &net);
    ew_train_model_prepare(&m, params);
    ew_train_scratch *s = ew_train_scratch_create(&net, 32);
    float *oa = malloc(sizeof(float) * 32 * 32 * 3), *ob = malloc(sizeof(float) * 32 * 32 * 3);
    ew_patch_ref ra = {0, 0, 0, 4}, rb = {1, 0, 0, 0}; /* a transposed by the augmentation; b as it is */
    double la = ew_train_patch(&m, f, &ra, 32, s, NULL, oa, NULL);
    double lb = ew_train_patch(&m, f, &rb, 32, s, NULL, ob, NULL);
    double worst = 0;
    for (int i = 0; i < 32 * 32 * 3; i++) worst = fmax(worst, fabs(oa[i] - ob[i]));
    free(params); free(oa); free(ob);
    ew_train_scratch_destroy(s);
    ew_train_model_free(&m);
    ew_train_frame_free(&f[0]);
    ew_train_frame_free(&f[1]);
    scene_free(&a);
    scene_free(&b);
    CHECK_NEAR(la, lb, 1e-6);
    CHECK(worst < 1e-5);
}

static int train_steps(int threads, int steps, float **params_out, double *first, double *last) {
    ew_guidenet net;
    char err[128];
    ew_guidenet_init(&net, "2layer-3grid", err, sizeof err);
    scene sc;
    scene_make(&sc, 40, 40, 6);
    ew_train_frame f;
    ew_train_frame_init(&f, 40, 40, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f);
    float *params = malloc(sizeof(float) * net.nparams);
    ew_guidenet_random(&net, 11, params);
    ew_device *dev = make_device(threads);
    ew_trainer *t = ew_trainer_create(dev, &net, 4, 24);
    ew_adam adam = {1e-2, 0.9, 0.999, 1e-8, 0, calloc(net.nparams, sizeof(float)), calloc(net.nparams, sizeof(float))};
    for (int k = 0; k < steps; k++) {
        ew_patch_ref refs[4];
        for (int b = 0; b < 4; b++) refs[b] = ew_train_pick(5, (uint64_t)k, b, &f, frame_zero, NULL, 24);
        ew_train_step_stats st;
        ew_trainer_step(t, params, &adam, &f, refs, 1.0, &st);
        if (k == 0) *first = st.loss;
        *last = st.loss;
    }
    free(adam.m); free(adam.v);
    ew_trainer_destroy(t);
    ew_device_destroy(dev);
    ew_train_frame_free(&f);
    scene_free(&sc);
    *params_out = params;
    return (int)net.nparams;
}

/* Same bits with 1 and 2 threads: each patch has its own gradient buffer and
 * the sum runs in patch order. Also: the loss goes down. */
TEST(steps_are_deterministic_and_learn) {
    float *p1, *p2;
    double f1, l1, f2, l2;
    int n = train_steps(1, 12, &p1, &f1, &l1);
    train_steps(2, 12, &p2, &f2, &l2);
    int same = memcmp(p1, p2, sizeof(float) * (size_t)n) == 0;
    free(p1);
    free(p2);
    fprintf(stderr, "  12 Adam steps: loss %.4f -> %.4f\n", f1, l1);
    CHECK(same);
    CHECK(l1 < f1);
}

TEST(patch_picks_are_a_function_of_seed_step_index) {
    ew_train_frame f;
    memset(&f, 0, sizeof f);
    f.width = 100;
    f.height = 80;
    int augs[8] = {0};
    for (int k = 0; k < 200; k++) {
        ew_patch_ref a = ew_train_pick(3, 17, k, &f, frame_zero, NULL, 32), b = ew_train_pick(3, 17, k, &f, frame_zero, NULL, 32);
        CHECK(a.x0 == b.x0 && a.y0 == b.y0 && a.aug == b.aug);
        CHECK(a.x0 >= 0 && a.x0 <= 68 && a.y0 >= 0 && a.y0 <= 48);
        augs[a.aug]++;
    }
    for (int k = 0; k < 8; k++) CHECK(augs[k] > 5); /* every symmetry is used */
}

TEST(clipping_rescales_and_reports) {
    float g[4] = {3, 4, 0, 0};
    int clipped;
    double norm = ew_clip_global_norm(g, 4, 1.0, &clipped);
    CHECK_NEAR(norm, 5.0, 1e-9);
    CHECK(clipped);
    CHECK_NEAR(g[0], 0.6, 1e-6);
    CHECK_NEAR(g[1], 0.8, 1e-6);
    norm = ew_clip_global_norm(g, 4, 2.0, &clipped);
    CHECK(!clipped);
    CHECK_NEAR(g[0], 0.6, 1e-6);
}

TEST(adam_first_step_moves_by_lr) {
    /* bias-corrected Adam's first step is lr * sign(g) */
    float p[3] = {1, 1, 1}, g[3] = {0.5f, -2.0f, 1e-3f}, m[3] = {0}, v[3] = {0};
    ew_adam a = {0.1, 0.9, 0.999, 1e-12, 0, m, v};
    ew_adam_update(&a, p, g, 3);
    CHECK_NEAR(p[0], 0.9, 1e-6);
    CHECK_NEAR(p[1], 1.1, 1e-6);
    CHECK_NEAR(p[2], 0.9, 1e-5);
    CHECK_EQ_INT(a.step, 1);
}

/* The trainer's single-thread scatters against the per-column / per-pixel
 * kernels the devices run: the same forward bits, the same gradient up to
 * float rounding. */
TEST(fast_grid_path_matches_the_kernels) {
    ew_guidenet net;
    char err[128];
    ew_guidenet_init(&net, "2layer-3grid", err, sizeof err);
    scene sc;
    scene_make(&sc, 48, 40, 12);
    ew_train_frame f;
    ew_train_frame_init(&f, 48, 40, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f);
    float *params = make_params(&net, 13);
    ew_train_model m;
    ew_train_model_init(&m, &net);
    ew_train_model_prepare(&m, params);
    ew_train_scratch *s = ew_train_scratch_create(&net, 32);
    float *g0 = calloc(net.nparams, sizeof(float)), *g1 = calloc(net.nparams, sizeof(float));
    float *o0 = malloc(sizeof(float) * 32 * 32 * 3), *o1 = malloc(sizeof(float) * 32 * 32 * 3);
    ew_patch_ref r = {0, 9, 4, 5};
    double l0 = ew_train_patch(&m, &f, &r, 32, s, g0, o0, NULL);
    ew_train_scratch_use_kernels(s, 1);
    double l1 = ew_train_patch(&m, &f, &r, 32, s, g1, o1, NULL);
    double gmax = 0, worst = 0;
    for (size_t i = 0; i < net.nparams; i++) gmax = fmax(gmax, fabs(g1[i]));
    for (size_t i = 0; i < net.nparams; i++) worst = fmax(worst, fabs(g0[i] - g1[i]));
    int same = memcmp(o0, o1, sizeof(float) * 32 * 32 * 3) == 0;
    fprintf(stderr, "  fast path vs kernels: loss %.8f / %.8f, worst gradient difference %.2e of max %.2e\n", l0, l1,
            worst, gmax);
    free(params); free(g0); free(g1); free(o0); free(o1);
    ew_train_scratch_destroy(s);
    ew_train_model_free(&m);
    ew_train_frame_free(&f);
    scene_free(&sc);
    CHECK(same);
    CHECK(l0 == l1);
    CHECK(worst < 1e-4 * gmax);
}
