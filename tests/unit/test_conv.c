/* GuideNet's 5x5 convolution: the SIMD CPU blocks and the per-value kernel
 * against a slow double-precision reference with explicit zero padding, and
 * every backward pass (input, weights, bias, activations) against central
 * finite differences of that reference. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/guidenet.h"
#include "backends/cpu/cpu_conv.h"
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

typedef struct {
    int w, h, cin, cout, act;
    ew_gn_planes in, out;
    float *inmem, *outmem, *wgt, *bias;
} conv_case;

static void case_init(conv_case *c, int w, int h, int cin, int cout, int act, unsigned seed) {
    c->w = w; c->h = h; c->cin = cin; c->cout = cout; c->act = act;
    c->inmem = malloc(ew_gn_planes_floats(w, h, cin) * sizeof(float));
    c->outmem = malloc(ew_gn_planes_floats(w, h, cout) * sizeof(float));
    ew_gn_planes_init(&c->in, c->inmem, w, h, cin);
    ew_gn_planes_init(&c->out, c->outmem, w, h, cout);
    c->wgt = malloc(sizeof(float) * cin * cout * 25);
    c->bias = malloc(sizeof(float) * cout);
    for (int i = 0; i < cin * cout * 25; i++) c->wgt[i] = urand(&seed) - 0.5f;
    for (int i = 0; i < cout; i++) c->bias[i] = urand(&seed) - 0.5f;
    for (int ci = 0; ci < cin; ci++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) ew_gn_plane_row(&c->in, ci, y)[x] = 2.0f * urand(&seed) - 1.0f;
}

static void case_free(conv_case *c) {
    free(c->inmem); free(c->outmem); free(c->wgt); free(c->bias);
}

static ew_conv_args case_args(const conv_case *c) {
    ew_conv_args a;
    memset(&a, 0, sizeof a);
    a.width = c->w; a.rows = c->h; a.cin = c->cin; a.cout = c->cout;
    a.in = c->in.data; a.in_rs = c->in.rs; a.in_ps = c->in.ps;
    a.out = c->out.data; a.out_rs = c->out.rs; a.out_ps = c->out.ps;
    a.weight = c->wgt; a.bias = c->bias; a.act = c->act;
    return a;
}

static double in_at(const conv_case *c, const double *in, int ci, int y, int x) {
    if (y < 0 || y >= c->h || x < 0 || x >= c->w) return 0.0; /* SAME zero padding */
    return in[((long)ci * c->h + y) * c->w + x];
}

static double act_ref(double v, int act) {
    if (act == EW_ACT_LEAKY) return v > 0 ? v : 0.2 * v;
    if (act == EW_ACT_SIGMOID) return 1.0 / (1.0 + exp(-v));
    return v;
}

/* out[co][y][x] in double; in/w/b given in double so finite differences can
 * perturb them. */
static void conv_ref(const conv_case *c, const double *in, const double *w, const double *b, double *out) {
    for (int co = 0; co < c->cout; co++)
        for (int y = 0; y < c->h; y++)
            for (int x = 0; x < c->w; x++) {
                double acc = b[co];
                for (int ci = 0; ci < c->cin; ci++)
                    for (int ky = 0; ky < 5; ky++)
                        for (int kx = 0; kx < 5; kx++)
                            acc += w[((co * c->cin + ci) * 5 + ky) * 5 + kx] * in_at(c, in, ci, y + ky - 2, x + kx - 2);
                out[((long)co * c->h + y) * c->w + x] = act_ref(acc, c->act);
            }
}

static void case_to_double(const conv_case *c, double *in, double *w, double *b) {
    for (int ci = 0; ci < c->cin; ci++)
        for (int y = 0; y < c->h; y++)
            for (int x = 0; x < c->w; x++) in[((long)ci * c->h + y) * c->w + x] = ew_gn_plane_row(&c->in, ci, y)[x];
    for (int i = 0; i < c->cin * c->cout * 25; i++) w[i] = c->wgt[i];
    for (int i = 0; i < c->cout; i++) b[i] = c->bias[i];
}

/* SIMD (through the backend entry, 1 and 2 threads) and per-value kernel
 * against the reference; the zero padding must stay zero. */
static int forward_matches(int w, int h, int cin, int cout, int act, unsigned seed) {
    conv_case c;
    case_init(&c, w, h, cin, cout, act, seed);
    size_t nin = (size_t)cin * w * h, nout = (size_t)cout * w * h;
    double *in = malloc(nin * sizeof(double)), *wd = malloc(sizeof(double) * cin * cout * 25);
    double *bd = malloc(sizeof(double) * cout), *ref = malloc(nout * sizeof(double));
    case_to_double(&c, in, wd, bd);
    conv_ref(&c, in, wd, bd, ref);
    int ok = 1;
    for (int variant = 0; variant < 3 && ok; variant++) {
        ew_gn_planes_init(&c.out, c.outmem, w, h, cout);
        ew_conv_args a = case_args(&c);
        if (variant < 2) {
            ew_device *dev = make_device(variant + 1);
            dev->backend->conv5(dev, &a);
            ew_device_destroy(dev);
        } else {
            for (int y = 0; y < h; y++)
                for (int co = 0; co < cout; co++)
                    for (int x = 0; x < w; x++) ew_conv5_px(x, y, co, &a);
        }
        double worst = 0;
        for (int co = 0; co < cout; co++)
            for (int y = -2; y < h + 2; y++)
                for (int x = -2; x < w + 26; x++) {
                    float v = ew_gn_plane_row(&c.out, co, y)[x];
                    int inside = y >= 0 && y < h && x >= 0 && x < w;
                    double e = inside ? fabs(v - ref[((long)co * h + y) * w + x]) : fabs(v);
                    if (e > worst) worst = e;
                }
        if (worst > 2e-5 * cin * 25) {
            fprintf(stderr, "  %dx%d %d->%d act %d variant %d: worst error %g\n", w, h, cin, cout, act, variant, worst);
            ok = 0;
        }
    }
    free(in); free(wd); free(bd); free(ref);
    case_free(&c);
    return ok;
}

TEST(forward_10_to_20_leaky) { CHECK(forward_matches(37, 11, 10, 20, EW_ACT_LEAKY, 1)); }
TEST(forward_20_to_5_sigmoid) { CHECK(forward_matches(29, 9, 20, 5, EW_ACT_SIGMOID, 2)); }
TEST(forward_20_to_1_sigmoid) { CHECK(forward_matches(8, 5, 20, 1, EW_ACT_SIGMOID, 3)); }
TEST(forward_45_to_5_dense_width_not_a_multiple_of_8) { CHECK(forward_matches(50, 7, 45, 5, EW_ACT_LEAKY, 4)); }
TEST(forward_odd_channel_blocks) { CHECK(forward_matches(3, 4, 5, 11, EW_ACT_NONE, 5)); }
TEST(forward_one_pixel_wide) { CHECK(forward_matches(1, 6, 3, 7, EW_ACT_LEAKY, 6)); }

/* Accumulate mode adds the sum (no bias, no activation) to the output. */
/* Every instruction set the processor has (AVX-512, AVX2 + FMA) computes
 * each output value by the same chain of operations, so they give the same
 * bits: the trainer's and the op's convolutions agree whichever runs. Also
 * in accumulate mode and on widths that leave partial vectors. */
static int levels_agree(int w, int h, int cin, int cout, int act, int accumulate, unsigned seed) {
    conv_case c;
    case_init(&c, w, h, cin, cout, act, seed);
    float *wt = malloc(sizeof(float) * cin * cout * 25);
    ew_conv_cpu_wt_layout(cin, cout, c.wgt, wt);
    const size_t nf = ew_gn_planes_floats(w, h, cout);
    float *res[3];
    for (int level = 1; level <= 2; level++) {
        ew_gn_planes_init(&c.out, c.outmem, w, h, cout);
        for (int co = 0; co < cout; co++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) ew_gn_plane_row(&c.out, co, y)[x] = 0.25f * (float)((x + 3 * y + co) % 7);
        ew_conv_args a = case_args(&c);
        a.accumulate = accumulate;
        ew_conv_cpu_rows_level(&a, wt, 0, h, level);
        res[level] = malloc(nf * sizeof(float));
        memcpy(res[level], c.outmem, nf * sizeof(float));
    }
    int same = memcmp(res[1], res[2], nf * sizeof(float)) == 0;
    if (!same) fprintf(stderr, "  %dx%d %d->%d: AVX-512 and AVX2 differ\n", w, h, cin, cout);
    free(res[1]); free(res[2]); free(wt);
    case_free(&c);
    return same;
}

TEST(instruction_sets_give_the_same_bits) {
    if (ew_conv_cpu_simd_level() < 2) fprintf(stderr, "  (no AVX-512 on this processor: both runs use AVX2)\n");
    CHECK(levels_agree(131, 5, 10, 20, EW_ACT_LEAKY, 0, 31));
    CHECK(levels_agree(77, 4, 20, 5, EW_ACT_SIGMOID, 0, 32));
    CHECK(levels_agree(45, 3, 20, 1, EW_ACT_SIGMOID, 0, 33));
    CHECK(levels_agree(23, 6, 45, 5, EW_ACT_NONE, 1, 34));
    CHECK(levels_agree(9, 3, 5, 11, EW_ACT_NONE, 0, 35));
    CHECK(levels_agree(1, 2, 3, 7, EW_ACT_LEAKY, 0, 36));
}

TEST(accumulate_adds) {
    conv_case c;
    case_init(&c, 27, 6, 5, 20, EW_ACT_LEAKY, 7);
    ew_conv_args a = case_args(&c);
    a.act = EW_ACT_NONE;
    a.bias = NULL;
    ew_device *dev = make_device(2);
    /* both sums direct (accumulate always is): Winograd's rounding differs */
    ew_cpu_conv5_path(dev, &a, EW_CONV_CPU_DIRECT, 2);
    float first = ew_gn_plane_row(&c.out, 13, 3)[17];
    a.accumulate = 1;
    dev->backend->conv5(dev, &a);
    float twice = ew_gn_plane_row(&c.out, 13, 3)[17];
    ew_device_destroy(dev);
    case_free(&c);
    CHECK_NEAR(twice, 2.0 * first, 1e-5 * (1 + fabs(first)));
}

/* ---- backward -------------------------------------------------------- */

/* L = sum r * act(conv(in)) in double, for finite differences. */
static double loss_ref(const conv_case *c, const double *in, const double *w, const double *b, const double *r,
                       double *scratch) {
    conv_ref(c, in, w, b, scratch);
    double L = 0;
    for (long i = 0; i < (long)c->cout * c->w * c->h; i++) L += r[i] * scratch[i];
    return L;
}

static double rel_err(double a, double n) {
    double d = fabs(a - n), s = fmax(fmax(fabs(a), fabs(n)), 1e-3);
    return d / s;
}

static int backward_matches_fd(int w, int h, int cin, int cout, int act, unsigned seed) {
    conv_case c;
    case_init(&c, w, h, cin, cout, act, seed);
    const long nin = (long)cin * w * h, nout = (long)cout * w * h;
    double *in = malloc(nin * sizeof(double)), *wd = malloc(sizeof(double) * cin * cout * 25);
    double *bd = malloc(sizeof(double) * cout), *r = malloc(nout * sizeof(double));
    double *scratch = malloc(nout * sizeof(double));
    case_to_double(&c, in, wd, bd);
    for (long i = 0; i < nout; i++) r[i] = 2.0 * urand(&seed) - 1.0;

    /* analytic: forward, g = r * act'(out) in padded planes, then dW, db via
     * the SIMD reduction and dIn as a convolution with flipped weights */
    ew_conv_args a = case_args(&c);
    float *wt = malloc(sizeof(float) * cin * cout * 25);
    ew_conv_cpu_wt_layout(cin, cout, c.wgt, wt);
    ew_conv_cpu_rows(&a, wt, 0, h);
    float *gmem = malloc(ew_gn_planes_floats(w, h, cout) * sizeof(float));
    ew_gn_planes g;
    ew_gn_planes_init(&g, gmem, w, h, cout);
    for (int co = 0; co < cout; co++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                ew_gn_plane_row(&g, co, y)[x] =
                    (float)r[((long)co * h + y) * w + x] * ew_act_grad(ew_gn_plane_row(&c.out, co, y)[x], act);
    float *dw = calloc((size_t)cin * cout * 25, sizeof(float)), *db = calloc(cout, sizeof(float));
    ew_conv_cpu_dweight(&a, g.data, g.rs, g.ps, dw, db);
    float *flip = malloc(sizeof(float) * cin * cout * 25), *fwt = malloc(sizeof(float) * cin * cout * 25);
    ew_conv5_flip_weights(cin, cout, c.wgt, flip);
    ew_conv_cpu_wt_layout(cout, cin, flip, fwt);
    float *dimem = malloc(ew_gn_planes_floats(w, h, cin) * sizeof(float));
    ew_gn_planes din;
    ew_gn_planes_init(&din, dimem, w, h, cin);
    ew_conv_args b = {w, h, cout, cin, g.data, g.rs, g.ps, din.data, din.rs, din.ps, flip, NULL, EW_ACT_NONE, 1, 0, 0, 0, 0};
    ew_conv_cpu_rows(&b, fwt, 0, h);

    /* the per-element formulas agree with the fast ones */
    int ok = 1;
    for (int co = 0; co < cout && ok; co++)
        for (int ci = 0; ci < cin && ok; ci++)
            for (int k = 0; k < 25; k++) {
                float e = ew_conv5_dweight_elem(co, ci, k / 5, k % 5, &a, g.data, g.rs, g.ps);
                if (fabs(dw[(co * cin + ci) * 25 + k] - e) > 1e-4 * (1 + fabs(e))) {
                    fprintf(stderr, "  dW[%d][%d][%d]: %g vs per-element %g\n", co, ci, k, dw[(co * cin + ci) * 25 + k], e);
                    ok = 0;
                    break;
                }
            }
    for (int ci = 0; ci < cin && ok; ci++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                float e = ew_conv5_dinput_px(x, y, ci, &a, g.data, g.rs, g.ps);
                if (fabs(ew_gn_plane_row(&din, ci, y)[x] - e) > 1e-5 * (1 + fabs(e))) {
                    fprintf(stderr, "  dIn[%d][%d][%d]: %g vs per-element %g\n", ci, y, x, ew_gn_plane_row(&din, ci, y)[x], e);
                    ok = 0;
                    break;
                }
            }
    if (!ok) fprintf(stderr, "  per-element backward disagrees with the SIMD one\n");

    /* central differences in double */
    const double step = 1e-5;
    double worst_in = 0, worst_w = 0, worst_b = 0;
    for (int t = 0; t < 40; t++) {
        long i = (long)(urand(&seed) * nin) % nin;
        double keep = in[i];
        in[i] = keep + step; double lp = loss_ref(&c, in, wd, bd, r, scratch);
        in[i] = keep - step; double lm = loss_ref(&c, in, wd, bd, r, scratch);
        in[i] = keep;
        int ci = (int)(i / ((long)w * h)), y = (int)(i / w % h), x = (int)(i % w);
        worst_in = fmax(worst_in, rel_err(ew_gn_plane_row(&din, ci, y)[x], (lp - lm) / (2 * step)));
    }
    for (int t = 0; t < 40; t++) {
        long i = (long)(urand(&seed) * cin * cout * 25) % (cin * cout * 25);
        double keep = wd[i];
        wd[i] = keep + step; double lp = loss_ref(&c, in, wd, bd, r, scratch);
        wd[i] = keep - step; double lm = loss_ref(&c, in, wd, bd, r, scratch);
        wd[i] = keep;
        worst_w = fmax(worst_w, rel_err(dw[i], (lp - lm) / (2 * step)));
    }
    for (int i = 0; i < cout; i++) {
        double keep = bd[i];
        bd[i] = keep + step; double lp = loss_ref(&c, in, wd, bd, r, scratch);
        bd[i] = keep - step; double lm = loss_ref(&c, in, wd, bd, r, scratch);
        bd[i] = keep;
        worst_b = fmax(worst_b, rel_err(db[i], (lp - lm) / (2 * step)));
    }
    fprintf(stderr, "  conv %d->%d act %d: max relative error vs finite differences: input %.2e, weights %.2e, bias %.2e\n",
            cin, cout, act, worst_in, worst_w, worst_b);
    ok = ok && worst_in < 2e-3 && worst_w < 2e-3 && worst_b < 2e-3;
    free(in); free(wd); free(bd); free(r); free(scratch); free(wt); free(gmem); free(dw); free(db);
    free(flip); free(fwt); free(dimem);
    case_free(&c);
    return ok;
}

TEST(backward_leaky_matches_finite_differences) { CHECK(backward_matches_fd(13, 9, 4, 6, EW_ACT_LEAKY, 11)); }
TEST(backward_sigmoid_matches_finite_differences) { CHECK(backward_matches_fd(10, 7, 6, 5, EW_ACT_SIGMOID, 12)); }
TEST(backward_linear_matches_finite_differences) { CHECK(backward_matches_fd(9, 12, 3, 1, EW_ACT_NONE, 13)); }

/* The activations' derivatives from their outputs, against differences. */
TEST(activation_gradients) {
    const float xs[] = {-3.0f, -0.7f, -0.01f, 0.02f, 0.5f, 4.0f};
    for (int act = 0; act < 3; act++)
        for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++) {
            double h = 1e-3;
            double fd = (act_ref(xs[i] + h, act) - act_ref(xs[i] - h, act)) / (2 * h);
            double an = ew_act_grad(ew_act(xs[i], act), act);
            CHECK_NEAR(an, fd, 1e-4);
            CHECK_NEAR(ew_act(xs[i], act), act_ref(xs[i], act), 1e-6);
        }
}

/* The sigmoid never overflows for large inputs. */
TEST(sigmoid_is_stable) {
    CHECK(ew_sigmoidf(-1000.0f) == 0.0f);
    CHECK(ew_sigmoidf(1000.0f) == 1.0f);
    CHECK_NEAR(ew_sigmoidf(0.0f), 0.5, 1e-7);
}

/* ---- Winograd F(4x4, 5x5) ------------------------------------------------
 * The backend's Winograd path against its direct path on random weights and
 * inputs: region sizes that are not multiples of the 4x4 output tiles or of
 * the 16- and 32-tile items, the channel counts of the kpcn models (10/11
 * inputs, 24 and 48 hidden, 25/26/51 logits), every activation, both
 * instruction sets. A wrong transform coefficient gives errors of the order
 * of the output itself; rounding stays near 1e-5 of its magnitude. With
 * `band`, the region is a band of a taller buffer (NBG computes bands): the
 * rows next to it are data the taps read, not padding. Nothing outside the
 * region may be written. */
static int wino_matches_at(int w, int h, int cin, int cout, int act, int band, int gx, int gy, unsigned seed) {
    conv_case c;
    const int off = band ? 3 : 0, H = h + 2 * off;
    case_init(&c, w, H, cin, cout, act, seed);
    const size_t nf = ew_gn_planes_floats(w, H, cout);
    float *direct = malloc(nf * sizeof(float));
    ew_device *dev = make_device(2);
    int ok = dev != NULL;
    for (int level = 1; level <= 2 && ok; level++) {
        for (int pass = 0; pass < 2; pass++) {
            ew_gn_planes_init(&c.out, c.outmem, w, H, cout);
            ew_conv_args a = case_args(&c);
            a.rows = h;
            a.in += off * a.in_rs;
            a.out += off * a.out_rs;
            a.grid_x = gx;
            a.grid_y = gy;
            const int want = pass == 0 ? EW_CONV_CPU_DIRECT : EW_CONV_CPU_WINOGRAD;
            const int got = ew_cpu_conv5_path(dev, &a, want, level);
            if (got != want && ew_conv_cpu_simd_level() >= level) {
                fprintf(stderr, "  %dx%d %d->%d level %d: path %d ran, not %d\n", w, h, cin, cout, level, got, want);
                ok = 0;
            }
            if (pass == 0) memcpy(direct, c.outmem, nf * sizeof(float));
        }
        double worst = 0, sq = 0;
        long n = 0, outside = 0;
        for (int co = 0; co < cout; co++)
            for (int y = -2; y < H + 2; y++)
                for (int x = -2; x < w + 26; x++) {
                    const float *pw = ew_gn_plane_row(&c.out, co, y) + x;
                    const float *pd = direct + (pw - c.outmem);
                    const int inside = y >= off && y < off + h && x >= 0 && x < w;
                    if (!inside) {
                        outside += *pw != 0.0f || *pd != 0.0f;
                        continue;
                    }
                    worst = fmax(worst, fabs((double)*pw - *pd));
                    sq += (double)*pd * *pd;
                    n++;
                }
        const double rms = sqrt(sq / (double)(n > 0 ? n : 1));
        if (level == 2)
            fprintf(stderr, "  %dx%d %d->%d: worst |winograd - direct| = %.2e of the output's rms\n", w, h, cin, cout,
                    worst / rms);
        if (outside || !(worst <= 1e-4 * rms)) {
            fprintf(stderr, "  %dx%d %d->%d act %d band %d level %d: worst |winograd - direct| %.3g = %.2e of the rms %.3g, %ld values written outside\n",
                    w, h, cin, cout, act, band, level, worst, worst / rms, rms, outside);
            ok = 0;
        }
    }
    ew_device_destroy(dev);
    free(direct);
    case_free(&c);
    return ok;
}

static int wino_matches(int w, int h, int cin, int cout, int act, int band, unsigned seed) {
    return wino_matches_at(w, h, cin, cout, act, band, 0, 0, seed);
}

TEST(winograd_matches_direct) {
    CHECK(wino_matches(37, 11, 10, 24, EW_ACT_LEAKY, 0, 41));
    CHECK(wino_matches(131, 13, 11, 24, EW_ACT_LEAKY, 0, 42));
    CHECK(wino_matches(70, 9, 48, 24, EW_ACT_LEAKY, 0, 43));
    CHECK(wino_matches(129, 7, 24, 51, EW_ACT_NONE, 0, 44));
    CHECK(wino_matches(3, 5, 24, 26, EW_ACT_NONE, 0, 45));
    CHECK(wino_matches(1, 1, 24, 25, EW_ACT_NONE, 0, 46));
    CHECK(wino_matches(67, 6, 20, 5, EW_ACT_SIGMOID, 0, 47));
    CHECK(wino_matches(45, 10, 24, 24, EW_ACT_LEAKY, 1, 48));
    CHECK(wino_matches(200, 4, 48, 24, EW_ACT_LEAKY, 1, 49));
}

/* A region whose tiles are anchored off its origin (a kpcn tile's region at
 * a coarse scale): partial tiles on the left and top too. */
TEST(winograd_matches_direct_off_grid) {
    CHECK(wino_matches_at(37, 11, 10, 24, EW_ACT_LEAKY, 0, 1, 2, 51));
    CHECK(wino_matches_at(70, 9, 48, 24, EW_ACT_LEAKY, 1, 3, 3, 52));
    CHECK(wino_matches_at(129, 7, 24, 51, EW_ACT_NONE, 0, 6, 5, 53));
    CHECK(wino_matches_at(2, 3, 24, 25, EW_ACT_SIGMOID, 0, 3, 1, 54));
}

/* A region of a larger image, passed with its origin, is tiled as the
 * image is: where a tile's inputs are the same, so are its bits. */
TEST(winograd_region_of_an_image_gives_its_bits) {
    const int W = 83, H = 29, cin = 24, cout = 24, rx = 10, ry = 6, rw = 41, rh = 17;
    conv_case c;
    case_init(&c, W, H, cin, cout, EW_ACT_LEAKY, 61);
    ew_device *dev = make_device(2);
    CHECK(dev != NULL);
    for (int level = 1; level <= ew_conv_cpu_simd_level(); level++) {
        ew_gn_planes_init(&c.out, c.outmem, W, H, cout);
        ew_conv_args a = case_args(&c);
        CHECK_EQ_INT(ew_cpu_conv5_path(dev, &a, EW_CONV_CPU_WINOGRAD, level), EW_CONV_CPU_WINOGRAD);
        float *whole = malloc(sizeof(float) * cout * rw * rh);
        for (int co = 0; co < cout; co++)
            for (int y = 0; y < rh; y++)
                memcpy(whole + ((long)co * rh + y) * rw, ew_gn_plane_row(&c.out, co, ry + y) + rx, sizeof(float) * rw);
        /* the region as a buffer of its own: its inputs, zero padding around */
        conv_case r;
        case_init(&r, rw, rh, cin, cout, EW_ACT_LEAKY, 62);
        memcpy(r.wgt, c.wgt, sizeof(float) * cin * cout * 25);
        memcpy(r.bias, c.bias, sizeof(float) * cout);
        for (int ci = 0; ci < cin; ci++)
            for (int y = 0; y < rh; y++)
                memcpy(ew_gn_plane_row(&r.in, ci, y), ew_gn_plane_row(&c.in, ci, ry + y) + rx, sizeof(float) * rw);
        ew_conv_args b = case_args(&r);
        b.grid_x = rx;
        b.grid_y = ry;
        CHECK_EQ_INT(ew_cpu_conv5_path(dev, &b, EW_CONV_CPU_WINOGRAD, level), EW_CONV_CPU_WINOGRAD);
        /* the pixels of the tiles whose 8x8 inputs lie inside the region
         * (a tile's every output depends on all 64 of them through
         * rounding, not only on its 5x5 taps: near the region's edge its
         * zero padding replaces the image's neighbours) */
        long differ = 0, compared = 0;
        for (int co = 0; co < cout; co++)
            for (int y = 0; y < rh; y++)
                for (int x = 0; x < rw; x++) {
                    const int tx = x - (x + rx) % 4, ty = y - (y + ry) % 4;
                    if (tx - 2 < 0 || tx + 5 >= rw || ty - 2 < 0 || ty + 5 >= rh) continue;
                    compared++;
                    differ += memcmp(&whole[((long)co * rh + y) * rw + x], ew_gn_plane_row(&r.out, co, y) + x, sizeof(float)) != 0;
                }
        if (differ || !compared) fprintf(stderr, "  level %d: %ld values differ\n", level, differ);
        CHECK(differ == 0);
        free(whole);
        case_free(&r);
    }
    ew_device_destroy(dev);
    case_free(&c);
}

/* The automatic choice: Winograd where the caller allows it, from
 * EW_CONV_CPU_WINO_MIN_PAIRS channel pairs, direct in accumulate mode. */
TEST(winograd_where_it_pays) {
    ew_conv_args a;
    memset(&a, 0, sizeof a);
    a.cin = 24;
    a.cout = 24;
    CHECK(!ew_conv_cpu_wino_pays(&a)); /* the caller did not allow it */
    a.winograd = 1;
    CHECK(ew_conv_cpu_wino_pays(&a));
    a.accumulate = 1;
    CHECK(!ew_conv_cpu_wino_pays(&a));
    a.accumulate = 0;
    a.cin = 1;
    a.cout = EW_CONV_CPU_WINO_MIN_PAIRS - 1;
    CHECK(!ew_conv_cpu_wino_pays(&a));
}
