/* kpcn: every new op's backward pass against central finite differences
 * (the kernel filter w.r.t. its logits, blend logit and coarse input;
 * pooling and bilinear upsampling as adjoints), the whole patch pipeline's
 * gradient w.r.t. weights of every layer, the energy bound, and the trainer's
 * forward pass against the library's "kpcn" op. */
#include "ew_test.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/kpcn.h"
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

/* A device whose convolutions always run direct (as EW_CPU_CONV=direct in
 * the environment gives): the sums the trainer computes, to the bit. */
static ew_device *make_direct_device(int threads) {
    ew_device *dev = make_device(threads);
    if (dev) dev->conv_direct = 1;
    return dev;
}

static ew_kpcn_tensor flat(float *p, int w, int h) {
    ew_kpcn_tensor t = {p, 1, w, (long)w * h};
    return t;
}

/* L = sum_c,p G[c,p] * out[c,p] for fixed random G: dL/d out = G. */
static double filter_loss(const ew_kpcn_filter_args *a, const float *G) {
    const long n = (long)a->width * a->height;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) ew_kpcn_filter_px(x, y, a);
    double L = 0;
    for (long i = 0; i < 3 * n; i++) L += (double)G[i] * a->out.data[i];
    return L;
}

static void filter_case(int with_coarse) {
    const int W = 7, H = 6, CW = 4, CH = 3;
    const long n = (long)W * H;
    unsigned s = 11u + (unsigned)with_coarse;
    float *logits = malloc(sizeof(float) * 26 * n), *rad = malloc(sizeof(float) * 3 * n);
    float *coarse = malloc(sizeof(float) * 3 * CW * CH), *out = malloc(sizeof(float) * 3 * n);
    float *G = malloc(sizeof(float) * 3 * n), *dl = calloc(26 * (size_t)n, sizeof(float));
    float *dc = calloc(3 * (size_t)CW * CH, sizeof(float)), *dr = calloc(3 * (size_t)n, sizeof(float));
    for (long i = 0; i < 26 * n; i++) logits[i] = 2.0f * urand(&s) - 1.0f;
    for (long i = 0; i < 3 * n; i++) rad[i] = urand(&s) * 2.0f, G[i] = urand(&s) - 0.5f;
    for (int i = 0; i < 3 * CW * CH; i++) coarse[i] = urand(&s);
    ew_kpcn_filter_args a;
    memset(&a, 0, sizeof a);
    a.width = W;
    a.height = H;
    a.logits = flat(logits, W, H);
    a.radiance = flat(rad, W, H);
    if (with_coarse) {
        a.coarse = flat(coarse, CW, CH);
        a.cw = CW;
        a.ch = CH;
    }
    a.out = flat(out, W, H);
    ew_kpcn_tensor tdl = flat(dl, W, H), tdc = flat(dc, CW, CH), tdr = flat(dr, W, H);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            const long q = (long)y * W + x;
            float g[3] = {G[q], G[n + q], G[2 * n + q]};
            ew_kpcn_filter_backward_px(x, y, &a, g, &tdl, &tdr, &tdc);
        }
    double worst = 0;
    const float h = 1e-2f;
    const int nl = with_coarse ? 26 : 25;
    /* logits (every plane at a few pixels), radiance and coarse values */
    for (int k = 0; k < nl; k++)
        for (int q = 0; q < n; q += 5) {
            float *v = &logits[k * n + q], keep = *v;
            *v = keep + h;
            double lp = filter_loss(&a, G);
            *v = keep - h;
            double lm = filter_loss(&a, G);
            *v = keep;
            double fd = (lp - lm) / (2 * h), an = dl[k * n + q];
            double e = fabs(fd - an) / (fabs(fd) + fabs(an) + 1e-3);
            if (e > worst) worst = e;
        }
    for (long i = 0; i < 3 * n; i += 3) {
        float keep = rad[i];
        rad[i] = keep + h;
        double lp = filter_loss(&a, G);
        rad[i] = keep - h;
        double lm = filter_loss(&a, G);
        rad[i] = keep;
        double fd = (lp - lm) / (2 * h), e = fabs(fd - dr[i]) / (fabs(fd) + fabs(dr[i]) + 1e-3);
        if (e > worst) worst = e;
    }
    if (with_coarse)
        for (int i = 0; i < 3 * CW * CH; i++) {
            float keep = coarse[i];
            coarse[i] = keep + h;
            double lp = filter_loss(&a, G);
            coarse[i] = keep - h;
            double lm = filter_loss(&a, G);
            coarse[i] = keep;
            double fd = (lp - lm) / (2 * h), e = fabs(fd - dc[i]) / (fabs(fd) + fabs(dc[i]) + 1e-3);
            if (e > worst) worst = e;
        }
    fprintf(stderr, "  filter (coarse %d): worst relative error %.2e\n", with_coarse, worst);
    free(logits); free(rad); free(coarse); free(out); free(G); free(dl); free(dc); free(dr);
    /* float outputs differenced at h = 1e-2: agreement to ~1e-3 is rounding, a wrong term is O(1) */
    CHECK(worst < 1e-2);
}

TEST(filter_backward_matches_finite_differences) {
    filter_case(0);
    filter_case(1);
}

/* L = sum G . m over the frame (m: the remodulation albedo) */
static double remod_loss(const ew_kpcn_filter_args *a, const float *G) {
    const long n = (long)a->width * a->height;
    double L = 0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            float v[EW_KPCN_TAPS], m[3];
            ew_kpcn_remod_albedo_px(x, y, a, v, m);
            for (int c = 0; c < 3; c++) L += (double)G[c * n + (long)y * a->width + x] * m[c];
        }
    return L;
}

/* The remodulation kernel's logits (planes 26..50 of head0), with an albedo
 * that has negative and non-finite values (ew_albedo_factor's cases). */
TEST(remod_backward_matches_finite_differences) {
    const int W = 7, H = 6;
    const long n = (long)W * H;
    unsigned s = 31u;
    float *logits = malloc(sizeof(float) * EW_KPCN_HEAD_REMOD * n), *alb = malloc(sizeof(float) * 3 * n);
    float *G = malloc(sizeof(float) * 3 * n), *dl = calloc((size_t)EW_KPCN_HEAD_REMOD * n, sizeof(float));
    for (long i = 0; i < EW_KPCN_HEAD_REMOD * n; i++) logits[i] = 4.0f * urand(&s) - 2.0f;
    for (long i = 0; i < 3 * n; i++) alb[i] = urand(&s) * 1.2f - 0.1f, G[i] = urand(&s) - 0.5f;
    alb[5] = NAN;
    ew_kpcn_filter_args a;
    memset(&a, 0, sizeof a);
    a.width = W;
    a.height = H;
    a.logits = flat(logits, W, H);
    a.albedo = flat(alb, W, H);
    ew_kpcn_tensor tdl = flat(dl, W, H);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            const long q = (long)y * W + x;
            const float g[3] = {G[q], G[n + q], G[2 * n + q]};
            ew_kpcn_remod_backward_px(x, y, &a, g, &tdl);
        }
    double worst = 0;
    const float h = 1e-2f;
    for (int k = EW_KPCN_HEAD; k < EW_KPCN_HEAD_REMOD; k++)
        for (int q = 0; q < n; q += 4) {
            float *v = &logits[k * n + q], keep = *v;
            *v = keep + h;
            double lp = remod_loss(&a, G);
            *v = keep - h;
            double lm = remod_loss(&a, G);
            *v = keep;
            double fd = (lp - lm) / (2 * h), an = dl[k * n + q];
            double e = fabs(fd - an) / (fabs(fd) + fabs(an) + 1e-3);
            if (e > worst) worst = e;
        }
    /* the filter with the albedo set multiplies its result by m */
    float *rad = malloc(sizeof(float) * 3 * n), *out = malloc(sizeof(float) * 3 * n);
    for (long i = 0; i < 3 * n; i++) rad[i] = urand(&s) * 2.0f;
    a.radiance = flat(rad, W, H);
    a.out = flat(out, W, H);
    int bad = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float w[EW_KPCN_TAPS], f[3], v[EW_KPCN_TAPS], m[3];
            ew_kpcn_softmax_px(x, y, &a, w);
            ew_kpcn_filtered_px(x, y, &a, w, f);
            ew_kpcn_remod_albedo_px(x, y, &a, v, m);
            ew_kpcn_filter_px(x, y, &a);
            for (int c = 0; c < 3; c++) bad += *ew_kpcn_at(&a.out, c, y, x) != f[c] * m[c];
        }
    fprintf(stderr, "  remodulation kernel: worst relative error %.2e\n", worst);
    free(logits); free(alb); free(G); free(dl); free(rad); free(out);
    CHECK(worst < 1e-2);
    CHECK_EQ_INT(bad, 0);
}

/* Pooling and upsampling are linear: their backward passes must be the
 * adjoints, <A x, y> = <x, A^T y>, for odd and even sizes. */
TEST(pool_and_up_backward_are_adjoints) {
    unsigned s = 5;
    for (int fw = 6; fw <= 9; fw++) {
        const int fh = fw - 1, cw = ew_kpcn_half(fw), ch = ew_kpcn_half(fh), C = 2;
        float *f = malloc(sizeof(float) * C * fw * fh), *c = malloc(sizeof(float) * C * cw * ch);
        float *Af = malloc(sizeof(float) * C * cw * ch), *ATc = calloc((size_t)C * fw * fh, sizeof(float));
        float *Uc = malloc(sizeof(float) * C * fw * fh), *UTf = calloc((size_t)C * cw * ch, sizeof(float));
        for (int i = 0; i < C * fw * fh; i++) f[i] = urand(&s) - 0.5f;
        for (int i = 0; i < C * cw * ch; i++) c[i] = urand(&s) - 0.5f;
        ew_kpcn_pool_args pa = {fw, fh, cw, ch, C, flat(f, fw, fh), flat(Af, cw, ch)};
        ew_kpcn_tensor tc = flat(c, cw, ch), tATc = flat(ATc, fw, fh), tf = flat(f, fw, fh), tUTf = flat(UTf, cw, ch);
        for (int y = 0; y < ch; y++)
            for (int x = 0; x < cw; x++) {
                ew_kpcn_pool_px(x, y, &pa);
                ew_kpcn_pool_backward_px(x, y, &pa, &tc, &tATc);
            }
        ew_kpcn_up_args ua = {fw, fh, cw, ch, C, flat(c, cw, ch), flat(Uc, fw, fh), 0};
        for (int y = 0; y < fh; y++)
            for (int x = 0; x < fw; x++) {
                ew_kpcn_up_px(x, y, &ua);
                ew_kpcn_up_backward_px(x, y, &ua, &tf, &tUTf);
            }
        double l1 = 0, r1 = 0, l2 = 0, r2 = 0;
        for (int i = 0; i < C * cw * ch; i++) l1 += (double)Af[i] * c[i], r2 += (double)c[i] * UTf[i];
        for (int i = 0; i < C * fw * fh; i++) r1 += (double)f[i] * ATc[i], l2 += (double)Uc[i] * f[i];
        free(f); free(c); free(Af); free(ATc); free(Uc); free(UTf);
        CHECK_NEAR(l1, r1, 1e-5);
        CHECK_NEAR(l2, r2, 1e-5);
    }
}

/* Upsampling a constant gives the constant; pooling averages. */
TEST(up_and_pool_preserve_constants) {
    float c[12], f[42];
    for (int i = 0; i < 12; i++) c[i] = 0.7f;
    ew_kpcn_up_args ua = {7, 6, 4, 3, 1, flat(c, 4, 3), flat(f, 7, 6), 0};
    for (int y = 0; y < 6; y++)
        for (int x = 0; x < 7; x++) ew_kpcn_up_px(x, y, &ua);
    for (int i = 0; i < 42; i++) CHECK_NEAR(f[i], 0.7, 1e-6);
    ew_kpcn_pool_args pa = {7, 6, 4, 3, 1, flat(f, 7, 6), flat(c, 4, 3)};
    for (int y = 0; y < 3; y++)
        for (int x = 0; x < 4; x++) ew_kpcn_pool_px(x, y, &pa);
    for (int i = 0; i < 12; i++) CHECK_NEAR(c[i], 0.7, 1e-6);
}

/* ---- the whole pipeline ---------------------------------------------------- */
typedef struct {
    int w, h;
    float *color, *albedo, *normal, *depth, *ref;
} scene;

static void scene_make(scene *s, int w, int h, unsigned seed) {
    const long n = (long)w * h;
    s->w = w;
    s->h = h;
    s->color = malloc(sizeof(float) * n * 3);
    s->albedo = malloc(sizeof(float) * n * 3);
    s->normal = malloc(sizeof(float) * n * 3);
    s->depth = malloc(sizeof(float) * n);
    s->ref = malloc(sizeof(float) * n * 3);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const long j = (long)y * w + x;
            const int right = x > w / 2;
            for (int k = 0; k < 3; k++) {
                const float alb = right ? 0.2f + 0.2f * k : 0.8f - 0.1f * k;
                const float light = 0.3f + 0.7f * (float)y / (float)h;
                s->albedo[j * 3 + k] = alb;
                s->ref[j * 3 + k] = alb * light;
                s->color[j * 3 + k] = alb * light * (0.2f + 1.6f * urand(&seed));
            }
            s->normal[j * 3 + 0] = right ? 1.0f : 0.0f;
            s->normal[j * 3 + 1] = 0.0f;
            s->normal[j * 3 + 2] = right ? 0.0f : 1.0f;
            s->depth[j] = 2.0f + (right ? 1.0f : 0.0f);
        }
}

static void scene_free(scene *s) {
    free(s->color); free(s->albedo); free(s->normal); free(s->depth); free(s->ref);
}

static void patch_gradient_case_loss(const char *arch, int loss) {
    ew_kpcn_net net;
    char err[128];
    CHECK(ew_kpcn_init(&net, arch, err, sizeof err) == 0);
    scene sc;
    scene_make(&sc, 24, 20, 3);
    ew_kpcn_frame f;
    CHECK(ew_kpcn_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f) == 0);
    const int P = 16;
    float *params = malloc(sizeof(float) * net.nparams), *grad = calloc(net.nparams, sizeof(float));
    ew_kpcn_random(&net, 9, params);
    /* larger head weights than the initialisation, so kernels and blends
     * are far from uniform and every path carries gradient */
    for (int l = 0; l < net.nlayers; l++)
        if (net.layers[l].act == EW_ACT_NONE)
            for (size_t i = 0; i < (size_t)net.layers[l].cin * net.layers[l].cout * 25; i++)
                if (!(net.remod && l == net.lhead[0] && i >= (size_t)EW_KPCN_HEAD * net.layers[l].cin * 25))
                    params[net.layers[l].w_off + i] *= 10.0f; /* not the remodulation kernel's: see below */
    /* a reference far above every output keeps the L1 away from its kink */
    float *ref = malloc(sizeof(float) * P * P * 3);
    for (int i = 0; i < P * P * 3; i++) ref[i] = 20.0f;
    ew_kpcn_model m;
    CHECK(ew_kpcn_model_init(&m, &net) == 0);
    ew_kpcn_scratch *s = ew_kpcn_scratch_create(&net, P);
    CHECK(s != NULL);
    const ew_kpcn_patch p = {0, 5, 3, 5};
    ew_kpcn_model_prepare(&m, params);
    ew_kpcn_train_patch(&m, &f, &p, P, loss, s, grad, NULL, ref);
    double errs[4 * EW_KPCN_MAX_LAYERS];
    int checked = 0, layers_ok = 0;
    for (int l = 0; l < net.nlayers; l++) {
        int good = 0;
        const ew_kpcn_layer *L = &net.layers[l];
        const size_t nw = (size_t)L->cin * L->cout * 25;
        /* a few weights and a bias of every layer; of head0's remodulation
         * kernel when it has one */
        size_t idx[4] = {L->w_off + 3, L->w_off + nw / 2 + 1, L->w_off + nw - 7, L->b_off};
        if (net.remod && l == net.lhead[0]) {
            const size_t first = (size_t)EW_KPCN_HEAD * L->cin * 25;
            idx[0] = L->w_off + first + 3;
            idx[1] = L->w_off + first + (nw - first) / 2 + 1;
            idx[3] = L->b_off + EW_KPCN_HEAD + 7;
        }
        for (int t = 0; t < 4; t++) {
            const size_t i = idx[t];
            const float keep = params[i], h = 2e-3f * (fabsf(keep) > 0.1f ? fabsf(keep) * 10.0f : 1.0f);
            params[i] = keep + h;
            ew_kpcn_model_prepare(&m, params);
            double lp = ew_kpcn_train_patch(&m, &f, &p, P, loss, s, NULL, NULL, ref);
            params[i] = keep - h;
            ew_kpcn_model_prepare(&m, params);
            double lm = ew_kpcn_train_patch(&m, &f, &p, P, loss, s, NULL, NULL, ref);
            params[i] = keep;
            const double fd = (lp - lm) / (2.0 * h), an = grad[i];
            const double e = fabs(fd - an) / (fabs(fd) + fabs(an) + 1e-6);
            fprintf(stderr, "  layer %d param %zu: analytic %+.4e  finite %+.4e  rel %.1e\n", l, i, an, fd, e);
            errs[checked++] = e;
            good += e < 0.1;
        }
        layers_ok += good >= 3;
    }
    ew_kpcn_scratch_destroy(s);
    ew_kpcn_model_free(&m);
    ew_kpcn_frame_free(&f);
    scene_free(&sc);
    free(params);
    free(grad);
    free(ref);
    /* Float differences of a net with LeakyReLU kinks: a step of h moves
     * some pre-activations across zero, so a tiny gradient can be off by
     * tens of percent. A wrong derivative in a layer spoils all its checks,
     * hence: at least 3 of every layer's 4 within 10 %, and the median of
     * all within 1 %. */
    for (int i = 0; i < checked; i++)
        for (int j = i + 1; j < checked; j++)
            if (errs[j] < errs[i]) {
                double t = errs[i];
                errs[i] = errs[j];
                errs[j] = t;
            }
    fprintf(stderr, "  %s, loss %d: median relative error %.1e, layers with >= 3 of 4 within 10%%: %d of %d\n", arch,
            loss, errs[checked / 2], layers_ok, net.nlayers);
    CHECK_EQ_INT(layers_ok, net.nlayers);
    CHECK(errs[checked / 2] < 0.01);
}

static void patch_gradient_case(const char *arch) { patch_gradient_case_loss(arch, EW_KPCN_LOSS_TM); }

TEST(patch_gradient_matches_finite_differences) { patch_gradient_case("kpcn-c4"); }

/* Four scales: the middle scales' encoder, decoder and head repeat, and the
 * upsampling/pooling chain gets one more link. */
TEST(patch_gradient_matches_finite_differences_4_scales) { patch_gradient_case("kpcn-c4-noise-s4"); }

/* The remodulation kernel: the colour is the filtered radiance times a
 * predicted kernel's average of the albedo, so head0's last 25 outputs get
 * gradient through the albedo and every other layer through the changed
 * factor. Its weights keep their initial scale: on top of the centre tap's
 * bias, 10x weights saturate its softmax until float differences of the
 * loss lose the signal (remod_backward_matches_finite_differences checks
 * its derivative with wild logits on its own). */
TEST(patch_gradient_matches_finite_differences_remodulation) { patch_gradient_case("kpcn-c4-ra"); }

/* The PSNR loss (minus the patch's PSNR on the tone curve): every pixel's
 * slope is scaled by the patch's own MSE, through the whole net. */
TEST(patch_gradient_matches_finite_differences_psnr_loss) {
    patch_gradient_case_loss("kpcn-c4-ra", EW_KPCN_LOSS_PSNR);
}

/* The output stays within [min, max] of the demodulated radiance times the
 * albedo factor: kernels and blends are convex. */
TEST(output_cannot_invent_energy) {
    ew_kpcn_net net;
    char err[128];
    CHECK(ew_kpcn_init(&net, "kpcn-c4", err, sizeof err) == 0);
    scene sc;
    scene_make(&sc, 32, 32, 8);
    ew_kpcn_frame f;
    CHECK(ew_kpcn_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f) == 0);
    float *params = malloc(sizeof(float) * net.nparams);
    ew_kpcn_random(&net, 4, params);
    for (size_t i = 0; i < net.nparams; i++) params[i] *= 30.0f; /* wild kernels */
    ew_kpcn_model m;
    CHECK(ew_kpcn_model_init(&m, &net) == 0);
    ew_kpcn_model_prepare(&m, params);
    ew_kpcn_scratch *s = ew_kpcn_scratch_create(&net, 32);
    float *out = malloc(sizeof(float) * 32 * 32 * 3);
    const ew_kpcn_patch p = {0, 0, 0, 0};
    ew_kpcn_train_patch(&m, &f, &p, 32, EW_KPCN_LOSS_TM, s, NULL, out, NULL);
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (int j = 0; j < 32 * 32; j++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fminf(lo[k], f.radiance[j * 3 + k]);
            hi[k] = fmaxf(hi[k], f.radiance[j * 3 + k]);
        }
    int bad = 0;
    for (int j = 0; j < 32 * 32; j++)
        for (int k = 0; k < 3; k++) {
            const float r = out[j * 3 + k] / ew_albedo_factor(f.albedo[j * 3 + k]);
            if (!(r >= lo[k] - 1e-4f * (1 + fabsf(lo[k])) && r <= hi[k] + 1e-4f * (1 + hi[k]))) bad++;
        }
    ew_kpcn_scratch_destroy(s);
    ew_kpcn_model_free(&m);
    ew_kpcn_frame_free(&f);
    scene_free(&sc);
    free(params);
    free(out);
    CHECK_EQ_INT(bad, 0);
}

/* The trainer's forward pass (kernels run on the host) and the library's
 * "kpcn" op with the same weights give the same image: the model trained
 * is the model that runs. Also refusal without features. The op's
 * convolutions run direct here, as the trainer's do: with Winograd they
 * differ by rounding, which these random weights (5x Kaiming, logits in
 * the hundreds) amplify through the softmax; real weights on a real frame
 * are compared in tests/python (test_kpcn_winograd). */
static void op_matches_training_forward_for(const char *arch, int P, float gain) {
    ew_kpcn_net net;
    char err[128];
    CHECK(ew_kpcn_init(&net, arch, err, sizeof err) == 0);
    scene sc;
    scene_make(&sc, P, P, 21);
    ew_kpcn_frame f;
    CHECK(ew_kpcn_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f) == 0);
    float *params = malloc(sizeof(float) * net.nparams);
    ew_kpcn_random(&net, 17, params);
    for (size_t i = 0; i < net.nparams; i++) params[i] *= gain;
    ew_kpcn_model m;
    CHECK(ew_kpcn_model_init(&m, &net) == 0);
    ew_kpcn_model_prepare(&m, params);
    ew_kpcn_scratch *s = ew_kpcn_scratch_create(&net, P);
    float *ref_out = malloc(sizeof(float) * P * P * 3), *op_out = malloc(sizeof(float) * P * P * 3);
    const ew_kpcn_patch p = {0, 0, 0, 0};
    ew_kpcn_train_patch(&m, &f, &p, P, EW_KPCN_LOSS_TM, s, NULL, ref_out, NULL);
    void *bytes;
    size_t size;
    CHECK(ew_kpcn_save(&net, params, &bytes, &size) == 0);
    ew_device *dev = make_direct_device(2);
    CHECK(dev != NULL);
    ew_denoiser *d = NULL;
    CHECK(ew_denoiser_create(dev, "kpcn", &d) == EW_OK);
    ew_image c = ew_image_packed(sc.color, P, P, 3), a = ew_image_packed(sc.albedo, P, P, 3);
    ew_image n = ew_image_packed(sc.normal, P, P, 3), z = ew_image_packed(sc.depth, P, P, 1);
    ew_image o = ew_image_packed(op_out, P, P, 3);
    CHECK(ew_denoiser_set_data(d, "weights", bytes, size) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "color", &c) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "output", &o) == EW_OK);
    /* features missing: a clear refusal, never a colour-only guess */
    CHECK(ew_denoiser_commit(d) != EW_OK);
    CHECK(ew_denoiser_set_image(d, "albedo", &a) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "normal", &n) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "depth", &z) == EW_OK);
    /* the method against its trainer: without the do-no-harm blend, which
     * pulls these random weights' output toward the input, nor the stage's
     * clamp of extreme samples before the method */
    CHECK(ew_denoiser_set_int(d, "do_no_harm", 0) == EW_OK);
    CHECK(ew_denoiser_set_float(d, "outlier_k", 0.0f) == EW_OK);
    CHECK(ew_denoiser_commit(d) == EW_OK);
    CHECK(ew_denoiser_execute(d) == EW_OK);
    CHECK_STR_CONTAINS(ew_denoiser_describe(d), "kpcn");
    double worst = 0;
    for (int i = 0; i < P * P * 3; i++) worst = fmax(worst, fabs((double)op_out[i] - ref_out[i]) / (1e-3 + fabs(ref_out[i])));
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
    free(bytes);
    ew_kpcn_scratch_destroy(s);
    ew_kpcn_model_free(&m);
    ew_kpcn_frame_free(&f);
    scene_free(&sc);
    free(params);
    free(ref_out);
    free(op_out);
    fprintf(stderr, "  %s at %dx%d op vs trainer: worst relative difference %.2e\n", arch, P, P, worst);
    CHECK(worst < 1e-5);
}

/* kpcn-c24's decoders have 48 x 24 channel pairs, more than the CPU entry
 * keeps on its stack: the allocated weight copy must give the same image. */
TEST(op_matches_training_forward) {
    op_matches_training_forward_for("kpcn-c8", 32, 5.0f);
    op_matches_training_forward_for("kpcn-c24-noise", 32, 5.0f);
    op_matches_training_forward_for("kpcn-c8-noise-s4", 32, 5.0f);
    op_matches_training_forward_for("kpcn-c4-s5", 32, 5.0f);
    op_matches_training_forward_for("kpcn-c8-noise-s4-ra", 32, 5.0f);
    /* the op writes each head over the planes below its input where they
     * fit (ew_kpcn_inference_planes): at c24 every scale's do, the 51
     * logits of a remodulating head0 included; at c8 only some */
    op_matches_training_forward_for("kpcn-c24-noise-s4-ra", 32, 5.0f);
    /* five of the full-resolution scale's bands (kpcn.h: 32 rows, the
     * last shorter), where the op encodes band by band and computes each
     * band's encoder output again to decode it: the trainer holds every
     * plane of the patch (Kaiming's weights as they are: 5x saturates the
     * softmax, which then hides a wrong row of the decoder's inputs) */
    op_matches_training_forward_for("kpcn-c8-noise-s4-ra", 152, 1.0f);
}

static void patch_forward(const ew_kpcn_net *net, const float *params, const ew_kpcn_frame *f, int P, float *grad,
                          float *out) {
    ew_kpcn_model m;
    CHECK(ew_kpcn_model_init(&m, net) == 0);
    ew_kpcn_model_prepare(&m, params);
    ew_kpcn_scratch *s = ew_kpcn_scratch_create(net, P);
    const ew_kpcn_patch p = {0, 0, 0, 0};
    ew_kpcn_train_patch(&m, f, &p, P, EW_KPCN_LOSS_TM, s, grad, out, NULL);
    ew_kpcn_scratch_destroy(s);
    ew_kpcn_model_free(&m);
}

/* A warm start into a wider net with the noise plane computes the narrow
 * net's image, and the new channels are not dead: the weights that read
 * them get gradients (both sides zero would keep them zero forever). */
TEST(warm_start_keeps_output_and_trains_new_channels) {
    ew_kpcn_net small, wide;
    char err[128];
    CHECK(ew_kpcn_init(&small, "kpcn-c8", err, sizeof err) == 0);
    CHECK(ew_kpcn_init(&wide, "kpcn-c12-noise", err, sizeof err) == 0);
    const int P = 32;
    scene sc;
    scene_make(&sc, P, P, 5);
    ew_kpcn_frame f;
    CHECK(ew_kpcn_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f) == 0);
    float *ps = malloc(sizeof(float) * small.nparams), *pw = malloc(sizeof(float) * wide.nparams);
    float *gw = calloc(wide.nparams, sizeof(float));
    ew_kpcn_random(&small, 3, ps);
    for (size_t i = 0; i < small.nparams; i++) ps[i] *= 5.0f;
    ew_kpcn_random(&wide, 4, pw);
    ew_kpcn_params_from(&wide, pw, &small, ps);
    float *os = malloc(sizeof(float) * P * P * 3), *ow = malloc(sizeof(float) * P * P * 3);
    patch_forward(&small, ps, &f, P, NULL, os);
    patch_forward(&wide, pw, &f, P, gw, ow);
    double worst = 0;
    for (int i = 0; i < P * P * 3; i++) worst = fmax(worst, fabs((double)ow[i] - os[i]) / (1e-3 + fabs(os[i])));
    fprintf(stderr, "  c8 -> c12-noise warm start: worst relative difference %.2e\n", worst);
    CHECK(worst < 1e-5);
    /* dec0 (layer 7) reading new channel 10 of h0 and head0 (layer 8)
     * reading new channel 10 of d0, over their old outputs */
    const ew_kpcn_layer *L7 = &wide.layers[7], *L8 = &wide.layers[8];
    double g7 = 0, g8 = 0;
    for (int o = 0; o < small.layers[7].cout; o++)
        for (int t = 0; t < 25; t++) g7 += fabs(gw[L7->w_off + (o * (size_t)L7->cin + 10) * 25 + t]);
    for (int o = 0; o < L8->cout; o++)
        for (int t = 0; t < 25; t++) g8 += fabs(gw[L8->w_off + (o * (size_t)L8->cin + 10) * 25 + t]);
    CHECK(g7 > 0);
    CHECK(g8 > 0);
    ew_kpcn_frame_free(&f);
    scene_free(&sc);
    free(ps);
    free(pw);
    free(gw);
    free(os);
    free(ow);
}

/* A warm start into more scales: the old coarsest scale becomes a middle
 * one whose blend starts at sigmoid(EW_KPCN_NEW_SCALE_BIAS), so the image
 * moves by at most that share of the radiance's range, and the new scale
 * trains from the first step: its head and the decoder's weights reading
 * its upsampled output get gradients. */
TEST(warm_start_into_more_scales_stays_close_and_trains_them) {
    ew_kpcn_net three, four;
    char err[128];
    CHECK(ew_kpcn_init(&three, "kpcn-c8-noise", err, sizeof err) == 0);
    CHECK(ew_kpcn_init(&four, "kpcn-c8-noise-s4", err, sizeof err) == 0);
    CHECK_EQ_INT(four.nlayers, 12);
    const int P = 32;
    scene sc;
    scene_make(&sc, P, P, 6);
    ew_kpcn_frame f;
    CHECK(ew_kpcn_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f) == 0);
    float *p3 = malloc(sizeof(float) * three.nparams), *p4 = malloc(sizeof(float) * four.nparams);
    float *g4 = calloc(four.nparams, sizeof(float));
    ew_kpcn_random(&three, 3, p3);
    for (size_t i = 0; i < three.nparams; i++) p3[i] *= 5.0f;
    ew_kpcn_random(&four, 4, p4);
    ew_kpcn_params_from(&four, p4, &three, p3);
    float *o3 = malloc(sizeof(float) * P * P * 3), *o4 = malloc(sizeof(float) * P * P * 3);
    patch_forward(&three, p3, &f, P, NULL, o3);
    patch_forward(&four, p4, &f, P, g4, o4);
    double worst = 0, mx = 0;
    for (int i = 0; i < P * P * 3; i++) {
        worst = fmax(worst, fabs((double)o4[i] - o3[i]));
        mx = fmax(mx, fabs((double)o3[i]));
    }
    const double share = 1.0 / (1.0 + exp(-(double)EW_KPCN_NEW_SCALE_BIAS));
    fprintf(stderr, "  c8-noise -> c8-noise-s4: worst difference %.3g of an output range %.3g (blend %.3f)\n", worst, mx,
            share);
    CHECK(worst > 0);
    CHECK(worst <= 2.0 * share * mx);
    const ew_kpcn_layer *H = &four.layers[four.lhead[3]], *D = &four.layers[four.dec[2]];
    double gh = 0, gd = 0;
    for (size_t i = 0; i < (size_t)H->cin * H->cout * 25; i++) gh += fabs(g4[H->w_off + i]);
    for (int o = 0; o < D->cout; o++)
        for (int i = four.ch; i < D->cin; i++) /* the upsampled half: the new scale's output */
            for (int t = 0; t < 25; t++) gd += fabs(g4[D->w_off + (o * (size_t)D->cin + i) * 25 + t]);
    CHECK(gh > 0);
    CHECK(gd > 0);
    ew_kpcn_frame_free(&f);
    scene_free(&sc);
    free(p3);
    free(p4);
    free(g4);
    free(o3);
    free(o4);
}

/* A warm start that adds the remodulation kernel: it starts as its centre
 * tap's share v_c (EW_KPCN_REMOD_CENTRE_BIAS), so the remodulation albedo
 * moves from the raw one by at most (1 - v_c) of the albedo's range around
 * the pixel, and the colour with it; the new kernel trains from the first
 * step. */
TEST(warm_start_into_the_remodulation_kernel_stays_close_and_trains_it) {
    ew_kpcn_net plain, ra;
    char err[128];
    CHECK(ew_kpcn_init(&plain, "kpcn-c8-noise-s4", err, sizeof err) == 0);
    CHECK(ew_kpcn_init(&ra, "kpcn-c8-noise-s4-ra", err, sizeof err) == 0);
    CHECK(ra.remod && !plain.remod);
    CHECK_EQ_INT(ra.layers[ra.lhead[0]].cout, EW_KPCN_HEAD_REMOD);
    const int P = 32;
    scene sc;
    scene_make(&sc, P, P, 7);
    ew_kpcn_frame f;
    CHECK(ew_kpcn_frame_init(&f, sc.w, sc.h, sc.color, sc.albedo, sc.normal, sc.depth, sc.ref, 3.0f) == 0);
    float *pp = malloc(sizeof(float) * plain.nparams), *pr = malloc(sizeof(float) * ra.nparams);
    float *gr = calloc(ra.nparams, sizeof(float));
    ew_kpcn_random(&plain, 3, pp);
    for (size_t i = 0; i < plain.nparams; i++) pp[i] *= 5.0f;
    ew_kpcn_random(&ra, 4, pr);
    ew_kpcn_params_from(&ra, pr, &plain, pp);
    float *op = malloc(sizeof(float) * P * P * 3), *orr = malloc(sizeof(float) * P * P * 3);
    patch_forward(&plain, pp, &f, P, NULL, op);
    patch_forward(&ra, pr, &f, P, gr, orr);
    const double e6 = exp((double)EW_KPCN_REMOD_CENTRE_BIAS), off = 1.0 - e6 / (e6 + 24.0);
    double amin = 1e30, amax = 0, worst = 0, worst_bound = 0;
    for (int i = 0; i < P * P * 3; i++) {
        amin = fmin(amin, ew_albedo_factor(f.albedo[i]));
        amax = fmax(amax, ew_albedo_factor(f.albedo[i]));
    }
    int over = 0;
    for (int i = 0; i < P * P * 3; i++) {
        const double fr = op[i] / ew_albedo_factor(f.albedo[i]); /* the filtered radiance */
        const double d = fabs((double)orr[i] - op[i]), bound = off * (amax - amin) * fabs(fr) * (1 + 1e-5) + 1e-7;
        worst = fmax(worst, d);
        worst_bound = fmax(worst_bound, bound);
        over += d > bound;
    }
    fprintf(stderr, "  -> -ra: worst difference %.3g (bound up to %.3g; centre share %.3f)\n", worst, worst_bound,
            1.0 - off);
    CHECK(worst > 0);
    CHECK_EQ_INT(over, 0);
    const ew_kpcn_layer *H = &ra.layers[ra.lhead[0]];
    double gw = 0;
    for (size_t i = (size_t)EW_KPCN_HEAD * H->cin * 25; i < (size_t)H->cout * H->cin * 25; i++) gw += fabs(gr[H->w_off + i]);
    CHECK(gw > 0);
    ew_kpcn_frame_free(&f);
    scene_free(&sc);
    free(pp);
    free(pr);
    free(gr);
    free(op);
    free(orr);
}

/* The halo is counted through the layer list: 36 pixels for the three-scale
 * models (the tiles test below fails with 32), more with each scale. */
TEST(halo_grows_with_the_scales) {
    ew_kpcn_net net;
    char err[128];
    int last = 0;
    const char *arch[] = {"kpcn-c8", "kpcn-c8-s4", "kpcn-c8-s5"};
    for (int i = 0; i < 3; i++) {
        CHECK(ew_kpcn_init(&net, arch[i], err, sizeof err) == 0);
        const int halo = ew_kpcn_halo(&net);
        fprintf(stderr, "  %s: halo %d, alignment %d\n", arch[i], halo, ew_kpcn_align(&net));
        if (i == 0) CHECK_EQ_INT(halo, 36);
        CHECK(halo > last);
        CHECK_EQ_INT(halo % ew_kpcn_align(&net), 0);
        last = halo;
    }
    CHECK(ew_kpcn_init(&net, "kpcn-c8-s3", err, sizeof err) != 0); /* the default is written without -s */
    CHECK(ew_kpcn_init(&net, "kpcn-c8-s6", err, sizeof err) != 0);
    CHECK(ew_kpcn_init(&net, "kpcn-c8-noise-s", err, sizeof err) != 0);
}

/* The weights compiled into the library are the files in models/kpcn. */
TEST(builtin_weights_match_model_files) {
    static const int channels[EW_KPCN_NUM_MODELS] = {16, 8, 32};
    for (int k = 0; k < EW_KPCN_NUM_MODELS; k++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/kpcn/%s.ewm", EW_MODELS_DIR, ew_kpcn_model_name(k));
        FILE *f = fopen(path, "rb");
        const unsigned char *bytes;
        size_t size;
        ew_kpcn_builtin_weights(k, &bytes, &size);
        if (!f) {
            CHECK_EQ_INT(size, 0); /* no file, no built-in model */
            continue;
        }
        fseek(f, 0, SEEK_END);
        long n = ftell(f);
        fseek(f, 0, SEEK_SET);
        unsigned char *b = malloc((size_t)n);
        CHECK(fread(b, 1, (size_t)n, f) == (size_t)n);
        fclose(f);
        const int same = (size_t)n == size && memcmp(b, bytes, size) == 0;
        free(b);
        if (!same) fprintf(stderr, "  %s differs from the built-in model %d: run train_kpcn --emit-c\n", path, k);
        CHECK(same);
        ew_weights w;
        char err[128];
        CHECK(ew_weights_parse(bytes, size, &w, err, sizeof err) == 0);
        ew_kpcn_net net;
        float *p = NULL;
        CHECK(ew_kpcn_from_weights(&net, &w, &p, err, sizeof err) == 0);
        CHECK_EQ_INT(net.ch, channels[k]);
        /* and saving it writes the same file: the format is unchanged */
        void *again = NULL;
        size_t again_size = 0;
        CHECK(ew_kpcn_save(&net, p, &again, &again_size) == 0);
        CHECK(again_size == size && memcmp(again, bytes, size) == 0);
        free(again);
        free(p);
        ew_weights_free(&w);
    }
}

/* ---- tiles ------------------------------------------------------------------ */
/* The plan's tiles cover the frame once, start on multiples of 4, and each
 * region holds its core plus the halo (clipped to the frame) within the
 * budget, unless the budget is below the smallest tile. */
static void tiling_plan_case(const char *arch) {
    ew_kpcn_net net;
    char err[128];
    CHECK(ew_kpcn_init(&net, arch, err, sizeof err) == 0);
    const int A = ew_kpcn_align(&net), HALO = ew_kpcn_halo(&net);
    const int sizes[][2] = {{1, 1}, {7, 5}, {97, 203}, {640, 360}, {1283, 721}, {3840, 2160}};
    const size_t budgets[] = {1, 200000, 3000000, 50000000, (size_t)1 << 40};
    for (size_t si = 0; si < sizeof sizes / sizeof sizes[0]; si++)
        for (size_t bi = 0; bi < sizeof budgets / sizeof budgets[0]; bi++) {
            const int w = sizes[si][0], h = sizes[si][1];
            ew_tiling t;
            ew_kpcn_tiling_plan(&net, w, h, budgets[bi], 3, 0, &t);
            unsigned char *cover = calloc((size_t)w * h, 1);
            int ok = 1;
            for (int i = 0; i < t.nx * t.ny; i++) {
                ew_tile c;
                ew_tile_at(&t, i, &c);
                ok &= c.cx % A == 0 && c.cy % A == 0 && c.rx % A == 0 && c.ry % A == 0 && c.cw > 0 && c.ch > 0;
                ok &= c.rx == (c.cx > HALO ? c.cx - HALO : 0);
                ok &= c.ry == (c.cy > HALO ? c.cy - HALO : 0);
                ok &= c.rx + c.rw == (c.cx + c.cw + HALO < w ? c.cx + c.cw + HALO : w);
                ok &= c.ry + c.rh == (c.cy + c.ch + HALO < h ? c.cy + c.ch + HALO : h);
                ok &= c.rw <= t.rw && c.rh <= t.rh;
                for (int y = c.cy; ok && y < c.cy + c.ch; y++)
                    for (int x = c.cx; x < c.cx + c.cw; x++) cover[(long)y * w + x]++;
            }
            for (long j = 0; ok && j < (long)w * h; j++) ok = cover[j] == 1;
            free(cover);
            const size_t need = ew_kpcn_device_floats(&net, t.rw, t.rh) + 3 * (size_t)t.rw * t.rh;
            const int smallest = t.tw <= EW_TILE_MIN || t.th <= EW_TILE_MIN;
            if (!ok || (need > budgets[bi] && !smallest))
                fprintf(stderr, "  %dx%d budget %zu: %dx%d tiles of %dx%d, region %dx%d (%zu floats)\n", w, h,
                        budgets[bi], t.nx, t.ny, t.tw, t.th, t.rw, t.rh, need);
            CHECK(ok);
            CHECK(need <= budgets[bi] || smallest || t.nx * t.ny == 1);
            if (budgets[bi] == (size_t)1 << 40) CHECK_EQ_INT(t.nx * t.ny, 1);
        }
}

TEST(tiling_plan_covers_frame_within_budget) {
    tiling_plan_case("kpcn-c12-noise");
    tiling_plan_case("kpcn-c12-noise-s4");
}

/* Denoise a w x h scene with weights `bytes` and a memory budget; the
 * description in *what. */
/* The colour, its three features and the output, w x h packed planes, on d. */
static void set_frame(ew_denoiser *d, float *color, float *albedo, float *normal, float *depth, float *out, int w,
                      int h) {
    ew_image c = ew_image_packed(color, w, h, 3), a = ew_image_packed(albedo, w, h, 3);
    ew_image n = ew_image_packed(normal, w, h, 3), z = ew_image_packed(depth, w, h, 1);
    ew_image o = ew_image_packed(out, w, h, 3);
    CHECK(ew_denoiser_set_image(d, "color", &c) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "albedo", &a) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "normal", &n) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "depth", &z) == EW_OK);
    CHECK(ew_denoiser_set_image(d, "output", &o) == EW_OK);
}

/* How the views are given: packed RGB, the output apart (the do-no-harm
 * stage on); the output over a copy of the colour (the stage off, so the
 * op reads that view itself); colour and output as RGBA views, which the
 * op cannot read or write in place. */
enum { VIEWS_APART, VIEWS_OUTPUT_OVER_COLOR, VIEWS_RGBA };

static void denoise_budget_views(const scene *sc, const void *bytes, size_t size, int budget_mb, int direct,
                                 int views, float *out, char *what, size_t len) {
    ew_device *dev = direct ? make_direct_device(2) : make_device(2);
    CHECK(dev != NULL);
    ew_denoiser *d = NULL;
    CHECK(ew_denoiser_create(dev, "kpcn", &d) == EW_OK);
    CHECK(ew_denoiser_set_data(d, "weights", bytes, size) == EW_OK);
    const size_t n = (size_t)sc->w * sc->h;
    float *rgba = NULL, *rgba_out = NULL;
    if (views == VIEWS_APART) {
        set_frame(d, sc->color, sc->albedo, sc->normal, sc->depth, out, sc->w, sc->h);
    } else if (views == VIEWS_OUTPUT_OVER_COLOR) {
        memcpy(out, sc->color, n * 3 * sizeof(float));
        set_frame(d, out, sc->albedo, sc->normal, sc->depth, out, sc->w, sc->h);
        CHECK(ew_denoiser_set_int(d, "do_no_harm", 0) == EW_OK);
        CHECK(ew_denoiser_set_float(d, "outlier_k", 0.0f) == EW_OK);
    } else {
        rgba = malloc(n * 4 * sizeof(float));
        rgba_out = malloc(n * 4 * sizeof(float));
        for (size_t i = 0; i < n; i++) {
            memcpy(rgba + i * 4, sc->color + i * 3, 3 * sizeof(float));
            rgba[i * 4 + 3] = 1.0f;
        }
        set_frame(d, sc->color, sc->albedo, sc->normal, sc->depth, out, sc->w, sc->h);
        const ew_image c = ew_image_packed(rgba, sc->w, sc->h, 4), o = ew_image_packed(rgba_out, sc->w, sc->h, 4);
        CHECK(ew_denoiser_set_image(d, "color", &c) == EW_OK);
        CHECK(ew_denoiser_set_image(d, "output", &o) == EW_OK);
    }
    CHECK(ew_denoiser_set_int(d, "max_memory_mb", budget_mb) == EW_OK);
    CHECK(ew_denoiser_commit(d) == EW_OK);
    CHECK(ew_denoiser_execute(d) == EW_OK);
    if (rgba_out)
        for (size_t i = 0; i < n; i++) memcpy(out + i * 3, rgba_out + i * 4, 3 * sizeof(float));
    free(rgba);
    free(rgba_out);
    snprintf(what, len, "%s", ew_denoiser_describe(d));
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
}

/* A frame larger than its tiles (odd sizes: partial pooling blocks at the
 * right and bottom, tiles of three widths and heights) gives the same bits
 * tiled as in one pass: the halo covers everything a core pixel sees, and
 * the noise level and the firefly clamp come from the whole frame (on the
 * CPU tiles are streamed: the clamp runs in bands of 8 rows, so fireflies
 * and missing samples sit on and beside band seams too), whichever views
 * the op reads and writes in place or copies (direct convolutions). With
 * direct convolutions. With Winograd's (the default on CPUs with AVX2), an
 * output also depends, through rounding only, on the rest of its 4x4
 * tile's 8x8 inputs (up to 5 pixels away, not 2): the halo, counted from
 * the 5x5 taps, leaves a core pixel's rounding to see a region edge's
 * zero padding where the whole frame has pixels, so the tiled output is
 * the untiled one to rounding (the tiles are anchored at the frame's
 * origin at every scale, so inside a region they are the frame's tiles). */
/* Measured: 2.5e-3 at worst (kpcn-c24-noise-s4-ra; a few thousand of 1.1M
 * values differ at all). These random weights are 5x Kaiming, so logits
 * reach the hundreds and the softmax amplifies rounding; a halo that missed
 * a real dependency changes core pixels by the order of the output. */
#define EW_TILES_WINOGRAD_TOLERANCE 1e-2
static void tiles_case(const char *arch, int direct, int views) {
    ew_kpcn_net net;
    char err[128];
    CHECK(ew_kpcn_init(&net, arch, err, sizeof err) == 0);
    float *params = malloc(sizeof(float) * net.nparams);
    ew_kpcn_random(&net, 29, params);
    for (size_t i = 0; i < net.nparams; i++) params[i] *= 5.0f;
    void *bytes;
    size_t size;
    CHECK(ew_kpcn_save(&net, params, &bytes, &size) == 0);
    scene sc;
    scene_make(&sc, 613, 587, 5);
    sc.color[(100L * sc.w + 150) * 3] = 500.0f; /* a firefly near a tile seam */
    for (int y = 30; y <= 34; y++) sc.color[((long)y * sc.w + 40 + 7 * y) * 3 + 1] = 300.0f; /* by a band seam */
    sc.color[(64L * sc.w + 90) * 3 + 2] = NAN;
    sc.color[(63L * sc.w + 200) * 3] = INFINITY;
    const size_t n3 = (size_t)sc.w * sc.h * 3;
    float *whole = malloc(sizeof(float) * n3), *tiled = malloc(sizeof(float) * n3);
    char what_whole[128], what_tiled[128];
    denoise_budget_views(&sc, bytes, size, 1024, direct, views, whole, what_whole, sizeof what_whole);
    /* the smallest tiles */
    denoise_budget_views(&sc, bytes, size, 1, direct, views, tiled, what_tiled, sizeof what_tiled);
    fprintf(stderr, "  %s, views %d: untiled: %s; tiled: %s\n", arch, views, what_whole, what_tiled);
    CHECK(strstr(what_whole, "tiles") == NULL);
    CHECK_STR_CONTAINS(what_tiled, "tiles");
    size_t differ = 0, first = n3;
    double worst = 0;
    for (size_t i = 0; i < n3; i++) {
        if (memcmp(&whole[i], &tiled[i], sizeof(float)) != 0 && differ++ == 0) first = i;
        worst = fmax(worst, fabs((double)tiled[i] - whole[i]) / (1e-3 + fabs((double)whole[i])));
    }
    if (differ)
        fprintf(stderr, "  %s: %zu values differ (worst relative difference %.2e), first at pixel (%ld, %ld): %.9g tiled vs %.9g\n",
                direct ? "direct" : "winograd", differ, worst, (long)(first / 3 % sc.w), (long)(first / 3 / sc.w),
                (double)tiled[first], (double)whole[first]);
    if (direct) CHECK(differ == 0);
    else CHECK(worst < EW_TILES_WINOGRAD_TOLERANCE);
    free(whole);
    free(tiled);
    free(bytes);
    free(params);
    scene_free(&sc);
}

TEST(tiles_give_the_untiled_output) {
    tiles_case("kpcn-c8-noise", 1, VIEWS_APART);
    tiles_case("kpcn-c8-noise-s4", 1, VIEWS_APART); /* a 76-pixel halo and regions on multiples of 8 */
    tiles_case("kpcn-c4-ra", 1, VIEWS_APART);       /* the filter writes the colour, tile by tile */
    /* the colour read from the view the output overwrites, the filtered
     * radiance finished in the output; copies of RGBA views, the colour
     * written tile by tile into the op's plane */
    tiles_case("kpcn-c8-noise", 1, VIEWS_OUTPUT_OVER_COLOR);
    tiles_case("kpcn-c4-ra", 1, VIEWS_RGBA);
}

TEST(tiles_with_winograd_give_the_untiled_output_to_rounding) {
    tiles_case("kpcn-c8-noise", 0, VIEWS_APART);
    tiles_case("kpcn-c8-noise-s4", 0, VIEWS_APART);
    tiles_case("kpcn-c24-noise-s4-ra", 0, VIEWS_APART); /* the shipped large model's layers */
}

/* The CPU runs frames above FAST_REGION's ~0.75 Mpx in tiles however large
 * the budget (smaller regions are cheaper a pixel there); a frame under it
 * runs whole. The commit decides; the built-in model, no execute. */
static void tiles_at(int w, int h, char *what, size_t len) {
    ew_device *dev = make_device(1);
    CHECK(dev != NULL);
    ew_denoiser *d = NULL;
    CHECK(ew_denoiser_create(dev, "kpcn", &d) == EW_OK);
    scene sc;
    scene_make(&sc, w, h, 3);
    float *out = malloc(sizeof(float) * 3 * (size_t)w * h);
    CHECK(out != NULL);
    set_frame(d, sc.color, sc.albedo, sc.normal, sc.depth, out, w, h);
    CHECK(ew_denoiser_set_int(d, "max_memory_mb", 65536) == EW_OK);
    const ew_result r = ew_denoiser_commit(d);
    CHECK(r == EW_OK);
    snprintf(what, len, "%s", r == EW_OK ? ew_denoiser_describe(d) : "(commit failed)");
    ew_denoiser_destroy(d);
    free(out);
    scene_free(&sc);
    ew_device_destroy(dev);
}

TEST(large_frames_run_in_tiles_on_the_cpu_whatever_the_budget) {
    char what[160];
    tiles_at(800, 800, what, sizeof what); /* 0.64 Mpx */
    fprintf(stderr, "  800x800: %s\n", what);
    CHECK(strstr(what, "tiles") == NULL);
    tiles_at(1280, 720, what, sizeof what); /* 0.92 Mpx */
    fprintf(stderr, "  1280x720: %s\n", what);
    CHECK_STR_CONTAINS(what, "2x1 tiles");
}

/* ---- passes: the network on mirrored frames, averaged ------------------- */
/* A w x h x c frame mirrored along x and/or y into dst. */
static void mirror_frame(const float *src, float *dst, int w, int h, int c, int mx, int my) {
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int k = 0; k < c; k++)
                dst[((long)y * w + x) * c + k] = src[((long)(my ? h - 1 - y : y) * w + (mx ? w - 1 - x : x)) * c + k];
}

/* kpcn-small (the method alone: no do-no-harm stage) with `passes` on a
 * scene mirrored along (mx, my), its output mirrored back into out. */
static void run_passes(ew_device *dev, const scene *sc, int passes, int mx, int my, float *out, char *what,
                       size_t len) {
    const long n = (long)sc->w * sc->h;
    float *m = malloc(sizeof(float) * n * 10);
    float *c = m, *a = m + n * 3, *nr = m + n * 6, *z = m + n * 9;
    float *res = malloc(sizeof(float) * n * 3);
    mirror_frame(sc->color, c, sc->w, sc->h, 3, mx, my);
    mirror_frame(sc->albedo, a, sc->w, sc->h, 3, mx, my);
    mirror_frame(sc->normal, nr, sc->w, sc->h, 3, mx, my);
    mirror_frame(sc->depth, z, sc->w, sc->h, 1, mx, my);
    ew_denoiser *d = NULL;
    CHECK(ew_denoiser_create(dev, "kpcn", &d) == EW_OK);
    set_frame(d, c, a, nr, z, res, sc->w, sc->h);
    CHECK(ew_denoiser_set_int(d, "model", 1) == EW_OK);
    CHECK(ew_denoiser_set_int(d, "passes", passes) == EW_OK);
    CHECK(ew_denoiser_set_int(d, "do_no_harm", 0) == EW_OK);
    CHECK(ew_denoiser_set_float(d, "outlier_k", 0.0f) == EW_OK);
    CHECK(ew_denoiser_commit(d) == EW_OK);
    CHECK(ew_denoiser_execute(d) == EW_OK);
    if (what) snprintf(what, len, "%s", ew_denoiser_describe(d));
    if (passes > 1) { /* a second execute: the passes left the op's inputs as they came */
        float *again = malloc(sizeof(float) * n * 3);
        memcpy(again, res, sizeof(float) * n * 3);
        CHECK(ew_denoiser_execute(d) == EW_OK);
        CHECK(memcmp(again, res, sizeof(float) * n * 3) == 0);
        free(again);
    }
    ew_denoiser_destroy(d);
    mirror_frame(res, out, sc->w, sc->h, 3, mx, my);
    free(res);
    free(m);
}

/* Four passes are the mean of the single runs on the frame mirrored
 * left-right, both ways, up-down and not at all, each mirrored back (in
 * that order of summation). Not to the bit: a single run on a mirrored
 * frame sums its firefly statistics and noise level in another order. The
 * runs themselves differ by far more, so a pass read or written unmirrored
 * fails. Odd sizes: a middle column and row that mirror onto themselves,
 * and pooling blocks that fall differently on the mirrored frame. */
TEST(passes_average_the_mirrored_runs) {
    ew_device *dev = make_direct_device(2);
    CHECK(dev != NULL);
    scene sc;
    scene_make(&sc, 97, 83, 11);
    const long n3 = (long)sc.w * sc.h * 3;
    float *runs[4], *four = malloc(sizeof(float) * n3), *mean = malloc(sizeof(float) * n3);
    static const int mirrors[4][2] = {{1, 0}, {1, 1}, {0, 1}, {0, 0}};
    for (int i = 0; i < 4; i++) {
        runs[i] = malloc(sizeof(float) * n3);
        run_passes(dev, &sc, 1, mirrors[i][0], mirrors[i][1], runs[i], NULL, 0);
    }
    char what[128];
    run_passes(dev, &sc, 4, 0, 0, four, what, sizeof what);
    CHECK_STR_CONTAINS(what, "4 mirrored passes");
    double worst = 0.0, apart = 0.0;
    for (long i = 0; i < n3; i++) {
        float acc = runs[0][i];
        acc += runs[1][i];
        acc += runs[2][i];
        mean[i] = (acc + runs[3][i]) * 0.25f;
        worst = fmax(worst, fabs((double)four[i] - mean[i]) / (1e-3 + fabs((double)mean[i])));
        apart = fmax(apart, fabs((double)runs[0][i] - runs[3][i]) / (1e-3 + fabs((double)runs[3][i])));
    }
    fprintf(stderr, "  4 passes against the mean of the mirrored runs: worst relative difference %.2e; "
                    "two runs apart by %.2e\n", worst, apart);
    CHECK(worst < 1e-4);
    CHECK(apart > 1e-2);
    /* the same from a scene mirrored before: the passes are the frame's, whatever its orientation */
    run_passes(dev, &sc, 4, 1, 1, mean, NULL, 0);
    worst = 0.0;
    for (long i = 0; i < n3; i++) worst = fmax(worst, fabs((double)four[i] - mean[i]) / (1e-3 + fabs((double)mean[i])));
    CHECK(worst < 1e-4);
    for (int i = 0; i < 4; i++) free(runs[i]);
    free(four);
    free(mean);
    scene_free(&sc);
    ew_device_destroy(dev);
}

/* At 3840x2160 the default budget keeps the op under 2 GiB (the do-no-harm
 * stage around it included), for the default model and kpcn-large, and auto
 * at quality balanced and high, which run kpcn-large (high: 4 passes), need
 * no more than it or auto's own lower rungs. */
TEST(uhd_frame_fits_the_default_budget) {
    ew_device *dev = make_device(1);
    CHECK(dev != NULL);
    static const char *const what[6] = {"kpcn",          "kpcn-large", "kpcn-large, 4 passes", "auto fast",
                                        "auto balanced", "auto high"};
    uint64_t bytes[6] = {0, 0, 0, 0, 0, 0};
    for (int m = 0; m < 6; m++) {
        ew_op *op = NULL;
        CHECK(ew_op_create(dev, m < 3 ? "kpcn" : "auto", &op) == EW_OK);
        if (m == 1 || m == 2) CHECK(ew_op_set_int(op, "model", 2) == EW_OK);
        if (m == 2) CHECK(ew_op_set_int(op, "passes", 4) == EW_OK);
        if (m >= 3) CHECK(ew_op_set_int(op, "quality", m - 3) == EW_OK);
        CHECK(ew_op_memory(op, 3840, 2160, &bytes[m]) == EW_OK);
        fprintf(stderr, "  %s at 3840x2160: %.0f MiB\n", what[m], (double)bytes[m] / 1048576.0);
        ew_op_destroy(op);
    }
    CHECK(bytes[0] > 0 && bytes[0] < (uint64_t)2 << 30);
    CHECK(bytes[1] > 0 && bytes[1] < (uint64_t)2 << 30);
    CHECK(bytes[4] <= (bytes[3] > bytes[1] ? bytes[3] : bytes[1]));
    CHECK(bytes[5] <= (bytes[3] > bytes[2] ? bytes[3] : bytes[2]));
    ew_device_destroy(dev);
}

/* ---- the do-no-harm stage in kpcn's tiles ---------------------------------- */
static int cancel_at_half(void *user, double f) {
    (void)user;
    return f < 0.5;
}

/* kpcn (the built-in model) on sc with the stage's defaults under a budget,
 * the output into out (which may be sc->color); 0: cancelled half way */
static ew_result denoise_stage_passes(ew_device *dev, const scene *sc, float *out, int budget_mb, int harm,
                                      int cancel, int passes, char *what, size_t len) {
    ew_denoiser *d = NULL;
    ew_result r = ew_denoiser_create(dev, "kpcn", &d);
    if (r != EW_OK) return r;
    set_frame(d, sc->color, sc->albedo, sc->normal, sc->depth, out, sc->w, sc->h);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "max_memory_mb", budget_mb);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "passes", passes);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "do_no_harm", harm);
    if (r == EW_OK && cancel) r = ew_denoiser_set_progress(d, cancel_at_half, NULL);
    if (r == EW_OK) r = ew_denoiser_commit(d);
    if (r == EW_OK) r = ew_denoiser_execute(d);
    snprintf(what, len, "%s", r == EW_OK ? ew_denoiser_describe(d) : "");
    ew_denoiser_destroy(d);
    return r;
}

static ew_result denoise_stage(ew_device *dev, const scene *sc, float *out, int budget_mb, int harm, int cancel,
                               char *what, size_t len) {
    return denoise_stage_passes(dev, sc, out, budget_mb, harm, cancel, 1, what, len);
}

/* With the output written over the colour (the CLI's denoise), the
 * do-no-harm stage runs inside kpcn's tiles: it clamps the caller's colour
 * in place, the tiles' halo reaches the blend's margin past the core, and
 * each core is remodulated and blended before it goes out (what the next
 * tiles' blends read of it after them). With direct convolutions the same
 * bits as the output apart (the stage around the method), whole and in
 * streamed tiles, where the blend runs and where it fades out. That it ran
 * in the tiles shows in a run cancelled half way: the colour the tiles had
 * not reached holds the clamped colour. */
TEST(output_over_the_colour_runs_the_stage_in_the_tiles) {
    ew_device *dev = make_direct_device(2);
    const float amps[2] = {0.2f, 0.9f};
    int blended_in_tiles = 0;
    for (int a = 0; a < 2; a++) {
        scene sc;
        scene_make(&sc, 420, 580, 11 + a);
        unsigned seed = 90 + a;
        const long n3 = (long)sc.w * sc.h * 3;
        for (long i = 0; i < n3; i++) sc.color[i] = sc.ref[i] * (1.0f + amps[a] * (2.0f * urand(&seed) - 1.0f));
        for (int k = 0; k < 30; k++)
            sc.color[((long)(urand(&seed) * (float)(sc.h - 1)) * sc.w + (long)(urand(&seed) * (float)(sc.w - 1))) * 3 + 1] = 900.0f;
        const long fly = ((long)(sc.h - 12) * sc.w + 300) * 3 + 1; /* where a cancelled run does not reach */
        sc.color[fly] = 900.0f;
        float *apart = malloc(sizeof(float) * n3), *off = malloc(sizeof(float) * n3), *keep = malloc(sizeof(float) * n3);
        memcpy(keep, sc.color, sizeof(float) * n3);
        long blended = 0;
        for (int budget = 1024; budget >= 1; budget /= 1024) {
            char what[128], what_over[128], scratch[128];
            CHECK_EQ_INT(denoise_stage(dev, &sc, apart, budget, 1, 0, what, sizeof what), EW_OK);
            if (budget == 1024) { /* whether the blend runs at all (the same bits in tiles) */
                CHECK_EQ_INT(denoise_stage(dev, &sc, off, budget, 0, 0, scratch, sizeof scratch), EW_OK);
                for (long i = 0; i < n3; i++) blended += memcmp(&apart[i], &off[i], sizeof(float)) != 0;
            }
            CHECK_EQ_INT(denoise_stage(dev, &sc, sc.color, budget, 1, 1, scratch, sizeof scratch), EW_ERR_CANCELLED);
            const int in_tiles = sc.color[fly] < 900.0f;
            memcpy(sc.color, keep, sizeof(float) * n3);
            CHECK_EQ_INT(denoise_stage(dev, &sc, sc.color, budget, 1, 0, what_over, sizeof what_over), EW_OK);
            long differ = 0;
            for (long i = 0; i < n3; i++) differ += memcmp(&apart[i], &sc.color[i], sizeof(float)) != 0;
            fprintf(stderr, "  amplitude %.1f, %s / over the colour %s: blend changed %ld values, stage %s; %ld differ\n",
                    (double)amps[a], what, what_over, blended, in_tiles ? "in the tiles" : "around the method", differ);
            CHECK(differ == 0);
            CHECK(in_tiles);
            if (budget == 1) CHECK_STR_CONTAINS(what_over, "x2 tiles"); /* seams across and down */
            blended_in_tiles += blended > 0;
            memcpy(sc.color, keep, sizeof(float) * n3);
        }
        free(apart);
        free(off);
        free(keep);
        scene_free(&sc);
    }
    CHECK(blended_in_tiles >= 2);
    ew_device_destroy(dev);
}

/* Several mirrored passes (auto --quality high) run tiles over the frame's
 * planes, not streamed: with the output over the colour the stage blends
 * their mean once, at the frame's end, as with the output apart (the
 * tiles had tried to blend each region into buffers only streamed tiles
 * have, and crashed). Same bits, direct convolutions. */
TEST(passes_in_tiles_with_the_output_over_the_colour) {
    ew_device *dev = make_direct_device(2);
    scene sc;
    scene_make(&sc, 420, 300, 21);
    unsigned seed = 77;
    const long n3 = (long)sc.w * sc.h * 3;
    for (long i = 0; i < n3; i++) sc.color[i] = sc.ref[i] * (1.0f + 0.5f * (2.0f * urand(&seed) - 1.0f));
    for (int k = 0; k < 30; k++)
        sc.color[((long)(urand(&seed) * (float)(sc.h - 1)) * sc.w + (long)(urand(&seed) * (float)(sc.w - 1))) * 3] = 700.0f;
    float *apart = malloc(sizeof(float) * n3), *over = malloc(sizeof(float) * n3);
    char what[128], what_over[128];
    CHECK_EQ_INT(denoise_stage_passes(dev, &sc, apart, 1, 1, 0, 2, what, sizeof what), EW_OK);
    memcpy(over, sc.color, sizeof(float) * n3);
    scene s2 = sc;
    s2.color = over;
    CHECK_EQ_INT(denoise_stage_passes(dev, &s2, over, 1, 1, 0, 2, what_over, sizeof what_over), EW_OK);
    long differ = 0;
    for (long i = 0; i < n3; i++) differ += memcmp(&apart[i], &over[i], sizeof(float)) != 0;
    fprintf(stderr, "  2 passes: %s / over the colour: %s; %ld values differ\n", what, what_over, differ);
    CHECK_STR_CONTAINS(what_over, "tiles");
    CHECK_STR_CONTAINS(what_over, "2 mirrored passes");
    CHECK(differ == 0);
    free(apart);
    free(over);
    scene_free(&sc);
    ew_device_destroy(dev);
}

/* ---- features held as halves ------------------------------------------------ */
/* v as a half (round to nearest even) and the half's bits */
static uint16_t to_half(float v, float *held) {
    const _Float16 h = (_Float16)v;
    uint16_t bits;
    memcpy(&bits, &h, sizeof bits);
    *held = (float)h;
    return bits;
}

/* One run of net `bytes` on sc with albedo, normal and depth as float
 * views or as the half views of the same values (sc's features hold
 * values halves hold); the output apart or over a copy of the colour. */
static void denoise_features_as(const scene *sc, const void *bytes, size_t size, int budget_mb, int half, int over,
                                float *out, char *what, size_t len) {
    ew_device *dev = make_direct_device(2);
    ew_denoiser *d = NULL;
    CHECK(ew_denoiser_create(dev, "kpcn", &d) == EW_OK);
    CHECK(ew_denoiser_set_data(d, "weights", bytes, size) == EW_OK);
    const size_t n = (size_t)sc->w * sc->h;
    float *color = sc->color;
    if (over) {
        memcpy(out, sc->color, n * 3 * sizeof(float));
        color = out;
    }
    set_frame(d, color, sc->albedo, sc->normal, sc->depth, out, sc->w, sc->h);
    uint16_t *hf[3] = {NULL, NULL, NULL};
    if (half) {
        const char *names[3] = {"albedo", "normal", "depth"};
        const float *src[3] = {sc->albedo, sc->normal, sc->depth};
        const int ch[3] = {3, 3, 1};
        for (int f = 0; f < 3; f++) {
            hf[f] = malloc(sizeof(uint16_t) * n * (size_t)ch[f]);
            for (size_t i = 0; i < n * (size_t)ch[f]; i++) {
                float held;
                hf[f][i] = to_half(src[f][i], &held);
            }
            const ew_image v = {hf[f], sc->w, sc->h, ch[f], EW_STRIDE_PACKED, EW_STRIDE_PACKED, EW_FORMAT_HALF};
            CHECK(ew_denoiser_set_image(d, names[f], &v) == EW_OK);
        }
    }
    CHECK(ew_denoiser_set_int(d, "max_memory_mb", budget_mb) == EW_OK);
    CHECK(ew_denoiser_commit(d) == EW_OK);
    CHECK(ew_denoiser_execute(d) == EW_OK);
    snprintf(what, len, "%s", ew_denoiser_describe(d));
    for (int f = 0; f < 3; f++) free(hf[f]);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
}

/* Albedo, normal and depth held as halves (an EXR's half passes): kpcn
 * reads them a band of rows at a time when its tiles are streamed (no
 * float copy of the frame; the do-no-harm stage's passes before the
 * method too, when it runs in the tiles) and packs them otherwise. The
 * same bits as float views of the values the halves hold, whole and in
 * streamed tiles, the output apart (the stage around the method) and over
 * the colour (in the tiles), with and without the remodulation kernel
 * (which reads the albedo band by band; without it the tiles' cores are
 * multiplied by the albedo). Direct convolutions. */
TEST(half_features_give_the_bits_of_the_floats_they_hold) {
    static const char *const archs[2] = {"kpcn-c8-noise", "kpcn-c4-ra"};
    scene sc;
    scene_make(&sc, 531, 262, 17);
    const size_t n = (size_t)sc.w * sc.h;
    for (size_t i = 0; i < n * 3; i++) {
        to_half(sc.albedo[i], &sc.albedo[i]);
        to_half(sc.normal[i], &sc.normal[i]);
    }
    for (size_t i = 0; i < n; i++) to_half(sc.depth[i], &sc.depth[i]);
    sc.color[(100L * sc.w + 150) * 3] = 500.0f; /* a firefly for the clamp and the stage */
    float *a = malloc(sizeof(float) * n * 3), *b = malloc(sizeof(float) * n * 3);
    for (int k = 0; k < 2; k++) {
        ew_kpcn_net net;
        char err[128];
        CHECK(ew_kpcn_init(&net, archs[k], err, sizeof err) == 0);
        float *params = malloc(sizeof(float) * net.nparams);
        ew_kpcn_random(&net, 31, params);
        void *bytes;
        size_t size;
        CHECK(ew_kpcn_save(&net, params, &bytes, &size) == 0);
        for (int budget = 1024; budget >= 1; budget /= 1024)
            for (int over = 0; over < 2; over++) {
                char wf[128], wh[128];
                denoise_features_as(&sc, bytes, size, budget, 0, over, a, wf, sizeof wf);
                denoise_features_as(&sc, bytes, size, budget, 1, over, b, wh, sizeof wh);
                size_t differ = 0;
                for (size_t i = 0; i < n * 3; i++) differ += memcmp(&a[i], &b[i], sizeof(float)) != 0;
                fprintf(stderr, "  %s, budget %d, output %s: %s; %zu values differ\n", archs[k], budget,
                        over ? "over the colour" : "apart", wh, differ);
                CHECK(strcmp(wf, wh) == 0);
                CHECK(differ == 0);
                if (budget == 1) CHECK_STR_CONTAINS(wh, "tiles");
            }
        free(bytes);
        free(params);
    }
    free(a);
    free(b);
    scene_free(&sc);
}
