/* The temporal-stability metric (ew_image_temporal_diff) against a direct
 * computation, the static-pixel mask (reference change, motion), argument
 * errors and non-finite samples. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

enum { W = 20, H = 14, N = W * H };

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)(*s >> 8) / 16777216.0f;
}

static double tm(double v) { return isfinite(v) ? pow(v < 0 ? 0 : (v > 1 ? 1 : v), 1 / 2.2) : 0.0; }

/* The definition, written out: mean |tm(a1) - tm(a0)| over pixels (mask:
 * only where mask[i]) and 3 channels. */
static double mean_diff(const float *a0, const float *a1, const int *mask) {
    double s = 0;
    int n = 0;
    for (int i = 0; i < N; i++) {
        if (mask && !mask[i]) continue;
        for (int c = 0; c < 3; c++) s += fabs(tm(a1[i * 3 + c]) - tm(a0[i * 3 + c]));
        n++;
    }
    return n ? s / (3.0 * n) : 0.0;
}

static float t0[N * 3], t1[N * 3], r0[N * 3], r1[N * 3], vec[N * 2];

static void fill(unsigned seed) {
    unsigned s = seed;
    for (int i = 0; i < N * 3; i++) {
        r0[i] = 0.3f + 0.4f * (float)((i / 3) % W) / W; /* a ramp */
        r1[i] = r0[i];
        t0[i] = r0[i] + 0.2f * (urand(&s) - 0.5f);
        t1[i] = r0[i] + 0.2f * (urand(&s) - 0.5f);
    }
    for (int i = 0; i < N * 2; i++) vec[i] = 0.0f;
}

TEST(matches_the_definition_on_a_static_scene) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    fill(3);
    ew_image a = ew_image_packed(t0, W, H, 3), b = ew_image_packed(t1, W, H, 3);
    ew_image ra = ew_image_packed(r0, W, H, 3), rb = ew_image_packed(r1, W, H, 3);
    ew_temporal_diff d;
    memset(&d, 0xff, sizeof d);
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, NULL, 0.02f, &d), EW_OK);
    double want = mean_diff(t0, t1, NULL);
    CHECK(want > 0.01);
    CHECK_NEAR(d.test, want, 1e-6);
    CHECK_NEAR(d.reference, 0.0, 0.0);
    CHECK_NEAR(d.excess, want, 1e-6);
    CHECK_EQ_INT(d.static_pixels, N);
    CHECK_NEAR(d.static_flicker, want, 1e-6);
    /* a method as stable as the reference adds nothing */
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &ra, &rb, &ra, &rb, NULL, 0.02f, &d), EW_OK);
    CHECK_NEAR(d.excess, 0.0, 0.0);
    CHECK_NEAR(d.static_flicker, 0.0, 0.0);
    ew_device_destroy(dev);
}

TEST(reference_change_and_motion_leave_the_static_set) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    fill(5);
    int mask[N];
    for (int i = 0; i < N; i++) {
        int x = i % W, y = i / W;
        int lit = y < H / 2 && x < W / 2;    /* the reference brightens here */
        int moving = y >= H / 2 && x < W / 4; /* the camera says this moves */
        if (lit)
            for (int c = 0; c < 3; c++) r1[i * 3 + c] = r0[i * 3 + c] + 0.2f;
        if (moving) vec[i * 2 + (i & 1)] = (i & 2) ? 0.6f : -0.6f;
        if (!moving && !lit && x == W - 1) vec[i * 2] = 0.4f; /* under half a pixel: still static */
        mask[i] = !lit && !moving;
    }
    ew_image a = ew_image_packed(t0, W, H, 3), b = ew_image_packed(t1, W, H, 3);
    ew_image ra = ew_image_packed(r0, W, H, 3), rb = ew_image_packed(r1, W, H, 3);
    ew_image v = ew_image_packed(vec, W, H, 2);
    ew_temporal_diff d;
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, &v, 0.02f, &d), EW_OK);
    int want_n = 0;
    for (int i = 0; i < N; i++) want_n += mask[i];
    CHECK_EQ_INT(d.static_pixels, want_n);
    CHECK_NEAR(d.static_flicker, mean_diff(t0, t1, mask), 1e-6);
    CHECK_NEAR(d.reference, mean_diff(r0, r1, NULL), 1e-6);
    CHECK(d.reference > 0.01);
    CHECK_NEAR(d.excess, mean_diff(t0, t1, NULL) - mean_diff(r0, r1, NULL), 1e-6);
    /* without vectors the moving pixels count as static */
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, NULL, 0.02f, &d), EW_OK);
    CHECK_EQ_INT(d.static_pixels, N - (H / 2) * (W / 2));
    /* a tolerance above the reference change takes the lit block back */
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, NULL, 1.0f, &d), EW_OK);
    CHECK_EQ_INT(d.static_pixels, N);
    ew_device_destroy(dev);
}

TEST(non_finite_samples_count_as_zero) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    fill(7);
    t1[0] = NAN;
    t1[4] = INFINITY;
    vec[2 * 7] = NAN; /* unknown motion: not static */
    ew_image a = ew_image_packed(t0, W, H, 3), b = ew_image_packed(t1, W, H, 3);
    ew_image ra = ew_image_packed(r0, W, H, 3), rb = ew_image_packed(r1, W, H, 3);
    ew_image v = ew_image_packed(vec, W, H, 2);
    ew_temporal_diff d;
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, &v, 0.02f, &d), EW_OK);
    CHECK(isfinite(d.test) && isfinite(d.static_flicker));
    CHECK_NEAR(d.test, mean_diff(t0, t1, NULL), 1e-6);
    CHECK_EQ_INT(d.static_pixels, N - 1);
    ew_device_destroy(dev);
}

TEST(argument_errors) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    fill(9);
    ew_image a = ew_image_packed(t0, W, H, 3), b = ew_image_packed(t1, W, H, 3);
    ew_image ra = ew_image_packed(r0, W, H, 3), rb = ew_image_packed(r1, W, H, 3);
    ew_image small = ew_image_packed(t0, W - 1, H, 3), v1 = ew_image_packed(vec, W, H, 1);
    ew_temporal_diff d;
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, NULL, 0.02f, NULL), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &small, &b, &ra, &rb, NULL, 0.02f, &d), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "19x14");
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &small, &rb, NULL, 0.02f, &d), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, &v1, 0.02f, &d), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "vector");
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, NULL, -1.0f, &d), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_image_temporal_diff(dev, &a, &b, &ra, &rb, NULL, NAN, &d), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_image_temporal_diff(NULL, &a, &b, &ra, &rb, NULL, 0.02f, &d), EW_ERR_INVALID_ARGUMENT);
    ew_device_destroy(dev);
}
