/* GuideNet: architectures, weights files, the banded forward pass against a
 * naive whole-image double-precision network, the input features, and the
 * per-pixel pieces around it (blend weights, the loss's tone curve) against
 * finite differences. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/guidenet.h"
#include "algorithms/nbg.h"
#include "src/backend.h"
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

TEST(architectures_have_the_papers_shapes) {
    ew_guidenet net;
    char err[256];
    CHECK_EQ_INT(ew_guidenet_init(&net, "2layer-3grid", err, sizeof err), 0);
    CHECK_EQ_INT(net.nlayers, 2);
    CHECK_EQ_INT(net.nout, 5);
    CHECK_EQ_INT(net.nparams, 10 * 20 * 25 + 20 + 20 * 5 * 25 + 5);
    CHECK_NEAR(ew_guidenet_macs_per_pixel(&net), 7500, 0); /* the figure */
    CHECK_NEAR(net.rate_s[0], 4, 0);
    CHECK_NEAR(net.rate_d[2], 16, 0);
    CHECK_EQ_INT(ew_guidenet_init(&net, "7layer-3grid", err, sizeof err), 0);
    CHECK_EQ_INT(net.nlayers, 7);
    CHECK_EQ_INT(net.layers[1].cin, 20);
    CHECK_EQ_INT(net.layers[5].cin, 40);
    CHECK_EQ_INT(net.layers[6].cin, 45);
    CHECK_EQ_INT(net.nfeat, 10 + 20 + 25);
    CHECK_EQ_INT(ew_guidenet_init(&net, "2layer-1grid", err, sizeof err), 0);
    CHECK_EQ_INT(net.nout, 1);
    CHECK(ew_guidenet_init(&net, "3layer-2grid", err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "unknown GuideNet architecture '3layer-2grid'");
}

TEST(weights_round_trip_and_validation) {
    ew_guidenet net, back;
    char err[256];
    CHECK_EQ_INT(ew_guidenet_init(&net, "7layer-1grid", err, sizeof err), 0);
    net.rate_s[0] = 6;
    net.rate_d[0] = 12;
    float *p = malloc(sizeof(float) * net.nparams), *q = NULL;
    ew_guidenet_random(&net, 42, p);
    void *bytes;
    size_t size;
    CHECK_EQ_INT(ew_guidenet_save(&net, p, &bytes, &size), 0);
    ew_weights w;
    CHECK_EQ_INT(ew_weights_parse(bytes, size, &w, err, sizeof err), 0);
    CHECK(strcmp(w.arch, "nbg-7layer-1grid") == 0);
    CHECK_EQ_INT(ew_guidenet_from_weights(&back, &w, &q, err, sizeof err), 0);
    CHECK(memcmp(p, q, sizeof(float) * net.nparams) == 0);
    CHECK_NEAR(back.rate_s[0], 6, 0);
    CHECK_NEAR(back.rate_d[0], 12, 0);
    free(q);
    /* a foreign architecture string and an unusable rate are refused */
    strcpy(w.arch, "pyramid-v1");
    CHECK(ew_guidenet_from_weights(&back, &w, &q, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "not a neural bilateral grid");
    strcpy(w.arch, "nbg-7layer-1grid");
    ew_tensor *rates = NULL;
    for (uint32_t i = 0; i < w.num_tensors; i++)
        if (!strcmp(w.tensors[i].name, "grid.rates")) rates = &w.tensors[i];
    CHECK(rates);
    rates->data[0] = 0.5f;
    CHECK(ew_guidenet_from_weights(&back, &w, &q, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "outside [1, 256]");
    /* a tensor of the wrong shape */
    strcpy(w.arch, "nbg-2layer-1grid");
    CHECK(ew_guidenet_from_weights(&back, &w, &q, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "wrong shape");
    ew_weights_free(&w);
    free(bytes);
    free(p);
}

TEST(random_init_is_a_function_of_the_seed) {
    ew_guidenet net;
    char err[64];
    ew_guidenet_init(&net, "2layer-3grid", err, sizeof err);
    float *a = malloc(sizeof(float) * net.nparams), *b = malloc(sizeof(float) * net.nparams);
    ew_guidenet_random(&net, 7, a);
    ew_guidenet_random(&net, 7, b);
    int same = memcmp(a, b, sizeof(float) * net.nparams) == 0;
    ew_guidenet_random(&net, 8, b);
    int differ = memcmp(a, b, sizeof(float) * net.nparams) != 0;
    free(a);
    free(b);
    CHECK(same && differ);
}

/* ---- the input features ------------------------------------------------ */
TEST(input_features) {
    float color[6] = {0.25f, 2.0f, -1.0f, NAN, INFINITY, 0.0f};
    float albedo[6] = {0.5f, 1.5f, NAN, 0, 0, 0};
    float normal[6] = {-1.0f, 0.0f, 1.0f, 0, 0, 0};
    float depth[2] = {5.0f, NAN};
    float dst[10 * 2];
    ew_gn_input_px(0, color, albedo, normal, depth, 0.1f, dst, 2);
    ew_gn_input_px(1, color, albedo, normal, depth, 0.1f, dst + 1, 2);
    CHECK_NEAR(dst[0], pow(0.25, 1 / 2.2), 1e-6);
    CHECK_NEAR(dst[2], 1.0, 0);      /* clipped */
    CHECK_NEAR(dst[4], 0.0, 0);      /* negative -> 0 */
    CHECK_NEAR(dst[1], 0.0, 0);      /* NaN -> 0 */
    CHECK_NEAR(dst[3], 1.0, 0);      /* +Inf (half overflow) -> 1 */
    CHECK_NEAR(dst[6], 0.5, 0);
    CHECK_NEAR(dst[8], 1.0, 0);      /* albedo clipped */
    CHECK_NEAR(dst[10], 0.0, 0);     /* NaN albedo -> 0 */
    CHECK_NEAR(dst[12], 0.0, 0);     /* normal -1 -> 0 */
    CHECK_NEAR(dst[14], 0.5, 0);
    CHECK_NEAR(dst[16], 1.0, 0);
    CHECK_NEAR(dst[18], 0.5, 1e-7);  /* depth * scale */
    CHECK_NEAR(dst[19], 0.0, 0);     /* NaN depth */
}

/* ---- banded forward vs a naive network ----------------------------------- */
static double act_ref(double v, int act) {
    if (act == EW_ACT_LEAKY) return v > 0 ? v : 0.2 * v;
    if (act == EW_ACT_SIGMOID) return 1.0 / (1.0 + exp(-v));
    return v;
}

/* The whole net on the whole image, planes in double: feat[c][y][x]. */
static void net_ref(const ew_guidenet *net, const float *params, int w, int h, double *feat, double *out) {
    for (int l = 0; l < net->nlayers; l++) {
        const ew_gn_layer *L = &net->layers[l];
        for (int co = 0; co < L->cout; co++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    double acc = params[L->b_off + co];
                    for (int ci = 0; ci < L->cin; ci++)
                        for (int ky = 0; ky < 5; ky++)
                            for (int kx = 0; kx < 5; kx++) {
                                int yy = y + ky - 2, xx = x + kx - 2;
                                if (yy < 0 || yy >= h || xx < 0 || xx >= w) continue;
                                acc += params[L->w_off + ((size_t)co * L->cin + ci) * 25 + ky * 5 + kx] *
                                       feat[((size_t)(L->in_plane + ci) * h + yy) * w + xx];
                            }
                    double v = act_ref(acc, L->act);
                    if (L->out_plane < 0) out[((size_t)co * h + y) * w + x] = v;
                    else feat[((size_t)(L->out_plane + co) * h + y) * w + x] = v;
                }
    }
}

static int forward_matches(const char *arch, int w, int h, int band, unsigned seed) {
    ew_guidenet net;
    char err[128];
    if (ew_guidenet_init(&net, arch, err, sizeof err)) return 0;
    const long n = (long)w * h;
    float *params = malloc(sizeof(float) * net.nparams);
    ew_guidenet_random(&net, seed, params);
    for (int l = 0; l < net.nlayers; l++) /* non-zero biases too */
        for (int c = 0; c < net.layers[l].cout; c++) params[net.layers[l].b_off + c] = 0.2f * (urand(&seed) - 0.5f);
    float *color = malloc(sizeof(float) * n * 3), *albedo = malloc(sizeof(float) * n * 3);
    float *normal = malloc(sizeof(float) * n * 3), *depth = malloc(sizeof(float) * n);
    for (long i = 0; i < n * 3; i++) {
        color[i] = 2.0f * urand(&seed);
        albedo[i] = urand(&seed);
        normal[i] = 2.0f * urand(&seed) - 1.0f;
    }
    for (long i = 0; i < n; i++) depth[i] = 10.0f * urand(&seed);
    const float depth_scale = 0.1f;
    /* reference */
    double *feat = calloc((size_t)net.nfeat * n, sizeof(double)), *ref = malloc(sizeof(double) * net.nout * n);
    float tmp[10];
    for (long j = 0; j < n; j++) {
        ew_gn_input_px(0, color + j * 3, albedo + j * 3, normal + j * 3, depth + j, depth_scale, tmp, 1);
        for (int c = 0; c < 10; c++) feat[(size_t)c * n + j] = tmp[c];
    }
    net_ref(&net, params, w, h, feat, ref);
    int ok = 1;
    float *first = NULL;
    for (int threads = 1; threads <= 2 && ok; threads++) {
        ew_device *dev = make_device(threads);
        float *band_mem = malloc(sizeof(float) * ew_nbg_band_floats(&net, w, band));
        float *outputs = malloc(sizeof(float) * net.nout * n);
        ew_nbg_forward f = {&net, params, w, h, color, albedo, normal, depth, depth_scale, band_mem, band, outputs, 0};
        ok = ew_nbg_guidenet_forward(dev, &f, NULL, NULL) == EW_OK;
        double worst = 0;
        for (long i = 0; ok && i < net.nout * n; i++) worst = fmax(worst, fabs(outputs[i] - ref[i]));
        if (worst > 1e-5) {
            fprintf(stderr, "  %s %dx%d band %d, %d threads: worst error %g\n", arch, w, h, band, threads, worst);
            ok = 0;
        }
        /* the same bits whatever the thread count */
        if (ok && first && memcmp(first, outputs, sizeof(float) * net.nout * n) != 0) {
            fprintf(stderr, "  %s: 1 and 2 threads differ\n", arch);
            ok = 0;
        }
        free(first);
        first = outputs;
        free(band_mem);
        ew_device_destroy(dev);
    }
    free(first);
    free(params); free(color); free(albedo); free(normal); free(depth); free(feat); free(ref);
    return ok;
}

TEST(forward_2layer_3grid_in_bands) { CHECK(forward_matches("2layer-3grid", 29, 23, 5, 1)); }
TEST(forward_2layer_1grid_one_band) { CHECK(forward_matches("2layer-1grid", 17, 9, 9, 2)); }
TEST(forward_7layer_3grid_in_bands) { CHECK(forward_matches("7layer-3grid", 21, 30, 4, 3)); }
TEST(forward_7layer_band_taller_than_halo) { CHECK(forward_matches("7layer-3grid", 9, 40, 16, 4)); }
TEST(forward_one_row_bands) { CHECK(forward_matches("2layer-3grid", 12, 7, 1, 5)); }

/* ---- blend weights, tone curve ------------------------------------------ */
TEST(blend_weights_are_a_partition_of_unity) {
    unsigned seed = 3;
    for (int i = 0; i < 1000; i++) {
        float s0 = urand(&seed), s1 = urand(&seed), w[3];
        if (i == 0) s0 = s1 = 1.0f; /* the paper's 1 - w0 - w1 would be -1 here */
        if (i == 1) s0 = s1 = 0.0f;
        ew_nbg_weights(s0, s1, w);
        for (int k = 0; k < 3; k++) CHECK(w[k] >= 0.0f && w[k] <= 1.0f);
        CHECK_NEAR(w[0] + w[1] + w[2], 1.0, 1e-6);
    }
}

TEST(blend_weights_gradient_matches_finite_differences) {
    unsigned seed = 4;
    double worst = 0;
    for (int i = 0; i < 50; i++) {
        float s0 = urand(&seed), s1 = urand(&seed), dw[3] = {urand(&seed) - 0.5f, urand(&seed) - 0.5f, urand(&seed) - 0.5f};
        float ds0, ds1;
        ew_nbg_weights_backward(s0, s1, dw, &ds0, &ds1);
        /* L = dw . w(s0, s1) in double */
        const double h = 1e-4;
#define LW(a, b) (dw[0] * (a) + dw[1] * (1 - (a)) * (b) + dw[2] * (1 - (a)) * (1 - (b)))
        double n0 = (LW(s0 + h, s1) - LW(s0 - h, s1)) / (2 * h), n1 = (LW(s0, s1 + h) - LW(s0, s1 - h)) / (2 * h);
#undef LW
        worst = fmax(worst, fmax(fabs(ds0 - n0), fabs(ds1 - n1)));
    }
    fprintf(stderr, "  blend weights: max abs error vs finite differences %.2e\n", worst);
    CHECK(worst < 1e-5);
}

TEST(loss_tone_curve_and_gradient) {
    /* matches the display transform on [0, 1] up to the epsilon, is
     * continuous at 1 and keeps a slope above it */
    CHECK_NEAR(ew_nbg_tm(0.0f), 0.0, 1e-7);
    CHECK_NEAR(ew_nbg_tm(0.5f), pow(0.501, 1 / 2.2) - pow(0.001, 1 / 2.2), 1e-6);
    CHECK_NEAR(ew_nbg_tm(1.0f + 1e-6f), ew_nbg_tm(1.0f), 1e-5);
    CHECK(ew_nbg_tm(4.0f) > ew_nbg_tm(2.0f));
    const float xs[] = {-0.5f, 0.0005f, 0.01f, 0.3f, 0.99f, 1.01f, 7.0f};
    double worst = 0;
    for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++) {
        double h = 1e-4 * fmax(fabs(xs[i]), 1e-2);
        double g = 1 / 2.2, e0 = pow(1e-3, g);
#define TM(x) ((x) > 1 ? pow(1.001, g) - e0 + 0.1 * log(x) : pow(fmax((x), 0) + 1e-3, g) - e0)
        double fd = (TM(xs[i] + h) - TM(xs[i] - h)) / (2 * h);
#undef TM
        double an = ew_nbg_tm_grad(xs[i]);
        worst = fmax(worst, fabs(an - fd) / fmax(fabs(fd), 1e-3));
    }
    fprintf(stderr, "  tone curve: max relative error vs finite differences %.2e\n", worst);
    CHECK(worst < 1e-3);
}
