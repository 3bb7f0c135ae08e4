/* Temporal accumulation: noise falls on a static sequence, motion vectors
 * carry history along, depth disagreement rejects it, NaN stays contained. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

enum { W = 32, H = 24 };

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)(*s >> 8) / 16777216.0f;
}

static ew_filter *make(ew_device **dev) {
    ew_device_create(NULL, dev);
    ew_filter *f = NULL;
    if (ew_filter_create(*dev, "temporal", &f) != EW_OK) return NULL;
    return f;
}

static int run(ew_filter *f, float *color, float *vec, float *depth, float *out) {
    ew_image c = ew_image_packed(color, W, H, 3), o = ew_image_packed(out, W, H, 3);
    ew_image v = ew_image_packed(vec, W, H, 2), d = ew_image_packed(depth, W, H, 1);
    ew_filter_set_image(f, "color", &c);
    ew_filter_set_image(f, "output", &o);
    ew_filter_set_image(f, "vector", vec ? &v : NULL);
    ew_filter_set_image(f, "depth", depth ? &d : NULL);
    return ew_filter_commit(f) == EW_OK && ew_filter_execute(f) == EW_OK;
}

TEST(static_noise_averages_out) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3];
    unsigned s = 1;
    double err_first = 0, err_last = 0;
    for (int fr = 0; fr < 30; fr++) {
        for (int i = 0; i < W * H * 3; i++) color[i] = 0.5f + (urand(&s) - 0.5f);
        CHECK(run(f, color, NULL, NULL, out));
        double e = 0;
        for (int i = 0; i < W * H * 3; i++) e += (out[i] - 0.5) * (out[i] - 0.5);
        if (fr == 0) err_first = e;
        err_last = e;
    }
    /* alpha_min 0.2: steady-state variance 0.2/1.8 of one frame's */
    CHECK(err_last < 0.2 * err_first);
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}

/* A pattern moving 2 px right per frame; Cycles' vector points to the
 * previous position: -2 px. With it, history lands on the same content. */
TEST(motion_vectors_carry_history) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3], vec[W * H * 2];
    for (int i = 0; i < W * H; i++) { vec[2 * i] = -2.0f; vec[2 * i + 1] = 0.0f; }
    double worst = 0;
    for (int fr = 0; fr < 6; fr++) {
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int c = 0; c < 3; c++) color[(y * W + x) * 3 + c] = (float)(((x - 2 * fr) / 4 + 100) % 2);
        CHECK(run(f, color, vec, NULL, out));
        for (int y = 0; y < H; y++)
            for (int x = 2; x < W; x++) worst = fmax(worst, fabs(out[(y * W + x) * 3] - color[(y * W + x) * 3]));
    }
    CHECK_NEAR(worst, 0.0, 1e-5);
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}

/* The same pattern moving 2 px down (rows top first) and 1 px left per
 * frame. Cycles' Vector.Y is measured with its y axis pointing up (Blender's
 * rows go bottom-up): content that moved down came from above, Y = +2, and
 * X = previous minus current column = +1. Measured on a rendered rising
 * camera: reprojection error 0.0024 with (x + X, y - Y), 0.051 with y + Y. */
TEST(vertical_motion_follows_cycles_y_axis) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3], vec[W * H * 2];
    for (int i = 0; i < W * H; i++) { vec[2 * i] = 1.0f; vec[2 * i + 1] = 2.0f; }
    double worst = 0;
    for (int fr = 0; fr < 6; fr++) {
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int c = 0; c < 3; c++)
                    color[(y * W + x) * 3 + c] = (float)(((x + fr) / 4 + (y - 2 * fr + 100) / 4) % 2);
        CHECK(run(f, color, vec, NULL, out));
        for (int y = 2; y < H; y++)
            for (int x = 0; x < W - 1; x++) worst = fmax(worst, fabs(out[(y * W + x) * 3] - color[(y * W + x) * 3]));
    }
    CHECK_NEAR(worst, 0.0, 1e-5);
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}

TEST(depth_disagreement_rejects_history) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3], depth[W * H];
    for (int i = 0; i < W * H * 3; i++) color[i] = 1.0f;
    for (int i = 0; i < W * H; i++) depth[i] = 10.0f;
    CHECK(run(f, color, NULL, depth, out));
    for (int i = 0; i < W * H * 3; i++) color[i] = 3.0f;
    for (int i = 0; i < W * H; i++) depth[i] = (i % W) < W / 2 ? 10.0f : 2.0f; /* right half: new surface */
    CHECK(run(f, color, NULL, depth, out));
    CHECK_NEAR(out[(5 * W + 2) * 3], 2.0, 1e-5);      /* left: mix(1, 3, 0.5) */
    CHECK_NEAR(out[(5 * W + W - 3) * 3], 3.0, 1e-5);  /* right: history rejected */
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}

TEST(non_finite_is_contained_and_reset_works) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) color[i] = 1.0f;
    CHECK(run(f, color, NULL, NULL, out));
    color[0] = NAN;
    color[4] = INFINITY;
    CHECK(run(f, color, NULL, NULL, out));
    for (int i = 0; i < W * H * 3; i++) CHECK(isfinite(out[i]));
    CHECK_NEAR(out[0], 1.0, 1e-6);
    for (int i = 0; i < W * H * 3; i++) color[i] = 5.0f;
    CHECK_EQ_INT(ew_filter_set_int(f, "reset", 1), EW_OK);
    CHECK(run(f, color, NULL, NULL, out));
    CHECK_NEAR(out[100], 5.0, 1e-6);
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}

/* alpha = max(1 / (n + 1), alpha_min), n = frames already accumulated: a
 * static pixel is the running mean of the first 1 / alpha_min frames, then
 * an exponential average with weight alpha_min. */
static double alpha_sequence_error(float alpha_min) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    if (!f) return 1e9;
    static float color[W * H * 3], out[W * H * 3];
    const float v[8] = {1.0f, 5.0f, 2.0f, 7.0f, 3.0f, 11.0f, 0.0f, 4.0f};
    double want = 0.0, worst = 0.0;
    ew_filter_set_float(f, "alpha_min", alpha_min);
    for (int t = 0; t < 8; t++) {
        for (int i = 0; i < W * H * 3; i++) color[i] = v[t];
        if (!run(f, color, NULL, NULL, out)) worst = 1e9;
        double a = fmax(1.0 / (t + 1), (double)alpha_min);
        want = t == 0 ? v[0] : want + a * (v[t] - want);
        for (int i = 0; i < W * H * 3; i++) worst = fmax(worst, fabs(out[i] - want));
    }
    ew_filter_destroy(f);
    ew_device_destroy(dev);
    return worst;
}

TEST(alpha_is_one_over_n_plus_one_then_alpha_min) {
    CHECK_NEAR(alpha_sequence_error(0.2f), 0.0, 1e-5);
    CHECK_NEAR(alpha_sequence_error(0.5f), 0.0, 1e-5);
    /* the default is 0.2 */
    ew_param_info p;
    CHECK_EQ_INT(ew_method_param("filter", "temporal", 0, &p), EW_OK);
    CHECK(!strcmp(p.name, "alpha_min"));
    CHECK_NEAR(p.default_value, 0.2, 1e-7);
}

TEST(normal_disagreement_rejects_history) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3], normal[W * H * 3];
    ew_image c = ew_image_packed(color, W, H, 3), o = ew_image_packed(out, W, H, 3), n = ew_image_packed(normal, W, H, 3);
    CHECK_EQ_INT(ew_filter_set_image(f, "color", &c), EW_OK);
    CHECK_EQ_INT(ew_filter_set_image(f, "output", &o), EW_OK);
    CHECK_EQ_INT(ew_filter_set_image(f, "normal", &n), EW_OK);
    for (int i = 0; i < W * H; i++) {
        color[i * 3] = color[i * 3 + 1] = color[i * 3 + 2] = 1.0f;
        normal[i * 3] = 0.0f, normal[i * 3 + 1] = 0.0f, normal[i * 3 + 2] = 1.0f;
    }
    CHECK(ew_filter_commit(f) == EW_OK && ew_filter_execute(f) == EW_OK);
    for (int i = 0; i < W * H; i++) {
        color[i * 3] = color[i * 3 + 1] = color[i * 3 + 2] = 3.0f;
        if (i % W >= W / 2) { /* right half turns 60 degrees: cos 0.5 < 0.9 */
            normal[i * 3] = 0.866f;
            normal[i * 3 + 2] = 0.5f;
        } else if (i / W == 0) { /* top row of the left half: 20 degrees, cos 0.94 > 0.9, unnormalised */
            normal[i * 3] = 2.0f * 0.342f;
            normal[i * 3 + 2] = 2.0f * 0.940f;
        }
    }
    CHECK(ew_filter_commit(f) == EW_OK && ew_filter_execute(f) == EW_OK);
    CHECK_NEAR(out[(5 * W + 2) * 3], 2.0, 1e-5);     /* kept: mix(1, 3, 1/2) */
    CHECK_NEAR(out[(0 * W + 2) * 3], 2.0, 1e-5);     /* within the cosine: kept */
    CHECK_NEAR(out[(5 * W + W - 3) * 3], 3.0, 1e-5); /* rejected: restarts from the frame */
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}

/* clamp > 0: history outside the frame's 3x3 mean +- clamp sigma is pulled
 * in (no ghost of a changed surface); history inside is left alone. */
TEST(history_clamp_limits_ghosting_only) {
    ew_device *dev;
    ew_filter *f = make(&dev);
    CHECK(f);
    static float color[W * H * 3], out[W * H * 3];
    CHECK_EQ_INT(ew_filter_set_float(f, "clamp", 1.0f), EW_OK);
    for (int i = 0; i < W * H * 3; i++) color[i] = 1.0f;
    CHECK(run(f, color, NULL, NULL, out));
    /* left half: the surface changed to 3 (flat: sigma 0, history clamped to
     * 3); right half: a stripe pattern 0.5 / 1.5 that keeps history 1 inside */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) color[(y * W + x) * 3 + c] = x < W / 2 ? 3.0f : (x % 2 ? 1.5f : 0.5f);
    CHECK(run(f, color, NULL, NULL, out));
    CHECK_NEAR(out[(5 * W + 3) * 3], 3.0, 1e-5);                     /* without the clamp: 2 */
    CHECK_NEAR(out[(5 * W + W - 4) * 3], 0.5 * (1.0 + 0.5), 1e-5);   /* x even: mix(1, 0.5, 1/2) */
    CHECK_NEAR(out[(5 * W + W - 3) * 3 + 1], 0.5 * (1.0 + 1.5), 1e-5); /* x odd */
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}
