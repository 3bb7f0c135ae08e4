/*
 * API misuse that must not corrupt memory (run under ASan/UBSan in CI):
 * destroy order, calls from inside the progress callback, views whose
 * strides overflow or whose floats are misaligned, and the packed (0)
 * stride.
 */
#include "ew_test.h"

#include <float.h>
#include <stdint.h>

#include "edgewise/edgewise.h"

static ew_device *cpu(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.type = EW_DEVICE_CPU;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

enum { W = 32, H = 24 };

static void fill(float *px, int n) {
    for (int i = 0; i < n; i++) px[i] = (float)((i * 7919) % 101) / 100.0f;
}

static int all_finite(const float *px, int n) {
    for (int i = 0; i < n; i++)
        if (!isfinite(px[i])) return 0;
    return 1;
}

TEST(device_destroyed_before_its_denoiser) {
    static float in[W * H * 3], out[W * H * 3];
    fill(in, W * H * 3);
    ew_device *dev = cpu(2);
    CHECK(dev);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "bgrid", &d), EW_OK);
    ew_image vi = ew_image_packed(in, W, H, 3), vo = ew_image_packed(out, W, H, 3);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &vi), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "output", &vo), EW_OK);
    /* the caller's reference goes first; the denoiser keeps the device */
    ew_device_destroy(dev);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    CHECK(all_finite(out, W * H * 3));
    ew_denoiser_destroy(d); /* frees the device too (LeakSanitizer checks) */
}

TEST(device_destroyed_between_filters) {
    static float in[W * H * 3], out[W * H * 3];
    fill(in, W * H * 3);
    ew_device *dev = cpu(1);
    ew_filter *a = NULL, *b = NULL;
    CHECK_EQ_INT(ew_filter_create(dev, "bilateral", &a), EW_OK);
    CHECK_EQ_INT(ew_filter_create(dev, "bilateral", &b), EW_OK);
    ew_device_destroy(dev);
    ew_filter_destroy(a);
    ew_image vi = ew_image_packed(in, W, H, 3), vo = ew_image_packed(out, W, H, 3);
    CHECK_EQ_INT(ew_filter_set_image(b, "color", &vi), EW_OK);
    CHECK_EQ_INT(ew_filter_set_image(b, "output", &vo), EW_OK);
    CHECK_EQ_INT(ew_filter_commit(b), EW_OK);
    CHECK_EQ_INT(ew_filter_execute(b), EW_OK);
    ew_filter_destroy(b);
}

TEST(retain_keeps_the_device) {
    ew_device *dev = cpu(1);
    ew_device_retain(dev);
    ew_device_destroy(dev);
    CHECK_EQ_INT(ew_device_get_num_threads(dev), 1); /* still alive: one reference left */
    ew_device_destroy(dev);
}

typedef struct {
    ew_denoiser *d;
    ew_result commit_r, execute_r, set_r;
    int calls, destroy;
    const char *msg;
    ew_device *dev;
} reenter;

static int reenter_cb(void *user, double fraction) {
    reenter *r = (reenter *)user;
    (void)fraction;
    if (r->calls++ == 0) {
        if (r->destroy) {
            ew_denoiser_destroy(r->d); /* deferred until execute returns */
            return 1;
        }
        r->commit_r = ew_denoiser_commit(r->d);
        r->msg = ew_device_last_error(r->dev);
        r->execute_r = ew_denoiser_execute(r->d);
        r->set_r = ew_denoiser_set_float(r->d, "spatial_rate", 8.0f);
    }
    return 1;
}

TEST(commit_and_execute_from_the_progress_callback_are_refused) {
    static float in[W * H * 3], out[W * H * 3];
    fill(in, W * H * 3);
    ew_device *dev = cpu(2);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "bgrid", &d), EW_OK);
    ew_image vi = ew_image_packed(in, W, H, 3), vo = ew_image_packed(out, W, H, 3);
    ew_denoiser_set_image(d, "color", &vi);
    ew_denoiser_set_image(d, "output", &vo);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    reenter r = {d, EW_OK, EW_OK, EW_OK, 0, 0, NULL, dev};
    ew_denoiser_set_progress(d, reenter_cb, &r);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    CHECK_EQ_INT(r.commit_r, EW_ERR_INVALID_STATE);
    CHECK_STR_CONTAINS(r.msg, "progress callback");
    CHECK_EQ_INT(r.execute_r, EW_ERR_INVALID_STATE);
    CHECK_EQ_INT(r.set_r, EW_ERR_INVALID_STATE);
    CHECK(all_finite(out, W * H * 3));
    /* after the run the op is usable again */
    ew_denoiser_set_progress(d, NULL, NULL);
    CHECK_EQ_INT(ew_denoiser_set_float(d, "spatial_rate", 8.0f), EW_OK);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
}

TEST(destroy_from_the_progress_callback_is_deferred) {
    static float in[W * H * 3], out[W * H * 3];
    fill(in, W * H * 3);
    ew_device *dev = cpu(2);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "bgrid", &d), EW_OK);
    ew_image vi = ew_image_packed(in, W, H, 3), vo = ew_image_packed(out, W, H, 3);
    ew_denoiser_set_image(d, "color", &vi);
    ew_denoiser_set_image(d, "output", &vo);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    reenter r = {d, EW_OK, EW_OK, EW_OK, 0, 1, NULL, dev};
    ew_denoiser_set_progress(d, reenter_cb, &r);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK); /* d is gone now (ASan checks) */
    ew_device_destroy(dev);
}

static ew_result set_view(ew_device *dev, ew_image v, const char **msg) {
    ew_filter *f = NULL;
    ew_filter_create(dev, "bilateral", &f);
    ew_result r = ew_filter_set_image(f, "color", &v);
    *msg = ew_device_last_error(dev);
    static char keep[512];
    snprintf(keep, sizeof keep, "%s", *msg);
    *msg = keep;
    ew_filter_destroy(f);
    return r;
}

TEST(overflowing_strides_are_refused) {
    static float px[W * H * 3];
    ew_device *dev = cpu(1);
    const char *msg;
    ew_image v = ew_image_packed(px, W, H, 3);
    v.row_stride = INT64_MIN;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "row stride");
    v = ew_image_packed(px, W, H, 3);
    v.pixel_stride = INT64_MAX / 2 / 4 * 4;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "pixel stride");
    v = ew_image_packed(px, W, H, 3);
    v.row_stride = INT64_MAX / 4 * 4;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    v.row_stride = -(INT64_MAX / 4 * 4);
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    /* height * |row stride| past int64 */
    v = ew_image_packed(px, W, H, 3);
    v.row_stride = (INT64_MAX / H) / 4 * 4;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    /* still fine: a negative (bottom-up) row stride */
    v = ew_image_packed(px + (H - 1) * W * 3, W, H, 3);
    v.row_stride = -(int64_t)W * 12;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_OK);
    ew_device_destroy(dev);
}

TEST(misaligned_views_are_refused) {
    static float px[W * H * 4 + 4];
    ew_device *dev = cpu(1);
    const char *msg;
    ew_image v = ew_image_packed(px, W, H, 3);
    v.data = (char *)px + 1;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "aligned");
    v = ew_image_packed(px, W, H, 3);
    v.pixel_stride = 13;
    v.row_stride = 13 * W;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "multiples of 4");
    v = ew_image_packed(px, W, H, 3);
    v.row_stride = 12 * W + 2;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_ERR_INVALID_ARGUMENT);
    v = ew_image_packed(px, W, H, 3);
    v.pixel_stride = 16; /* RGBA memory viewed as RGB: fine */
    v.row_stride = 16 * W;
    CHECK_EQ_INT(set_view(dev, v, &msg), EW_OK);
    ew_device_destroy(dev);
}

TEST(zero_strides_mean_packed) {
    /* EW_STRIDE_PACKED: 0 is the packed stride, not a repeated pixel */
    static float in[W * H * 3], out_a[W * H * 3], out_b[W * H * 3];
    fill(in, W * H * 3);
    CHECK_EQ_INT(EW_STRIDE_PACKED, 0);
    ew_device *dev = cpu(1);
    for (int k = 0; k < 2; k++) {
        ew_filter *f = NULL;
        CHECK_EQ_INT(ew_filter_create(dev, "bilateral", &f), EW_OK);
        ew_image vi = ew_image_packed(in, W, H, 3), vo = ew_image_packed(k ? out_b : out_a, W, H, 3);
        if (k) vi.pixel_stride = vi.row_stride = EW_STRIDE_PACKED;
        ew_filter_set_image(f, "color", &vi);
        ew_filter_set_image(f, "output", &vo);
        CHECK_EQ_INT(ew_filter_commit(f), EW_OK);
        CHECK_EQ_INT(ew_filter_execute(f), EW_OK);
        ew_filter_destroy(f);
    }
    CHECK(memcmp(out_a, out_b, sizeof out_a) == 0);
    ew_device_destroy(dev);
}

/* A denoiser on frame-sized views, each packed with explicit strides or
 * with EW_STRIDE_PACKED, under a budget that makes it tile or band; the
 * output apart or over the colour (the CLI's way). What went out. */
static void denoise_strided(ew_device *dev, const char *method, int zero, int over, const float *color,
                            const float *feat, int w, int h, float *out, char *what, size_t len) {
    float *col = malloc(sizeof(float) * 3 * (size_t)w * h);
    CHECK(col != NULL);
    memcpy(col, color, sizeof(float) * 3 * (size_t)w * h);
    ew_image c = ew_image_packed(col, w, h, 3), a = ew_image_packed((float *)feat, w, h, 3);
    ew_image n = ew_image_packed((float *)feat, w, h, 3), z = ew_image_packed((float *)feat, w, h, 1);
    ew_image o = ew_image_packed(over ? col : out, w, h, 3);
    if (zero) {
        ew_image *v[5] = {&c, &a, &n, &z, &o};
        for (int i = 0; i < 5; i++) v[i]->pixel_stride = v[i]->row_stride = EW_STRIDE_PACKED;
    }
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, method, &d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &c), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "albedo", &a), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "normal", &n), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "depth", &z), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "output", &o), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_int(d, "max_memory_mb", 1), EW_OK);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    snprintf(what, len, "%s", ew_denoiser_describe(d));
    ew_denoiser_destroy(d);
    if (over) memcpy(out, col, sizeof(float) * 3 * (size_t)w * h);
    free(col);
}

TEST(zero_strides_mean_packed_in_tiles_and_bands) {
    /* the cores and bands that go out into a cropped view: a crop of a
     * packed (0-stride) view is not packed at its own width */
    enum { FW = 520, FH = 720 };
    float *color = malloc(sizeof(float) * 3 * FW * FH), *feat = malloc(sizeof(float) * 3 * FW * FH);
    float *a = malloc(sizeof(float) * 3 * FW * FH), *b = malloc(sizeof(float) * 3 * FW * FH);
    CHECK(color && feat && a && b);
    /* fill()'s i * 7919 would overflow an int at this size */
    for (unsigned i = 0; i < 3u * FW * FH; i++) {
        color[i] = (float)((i * 7919u) % 101u) / 100.0f;
        feat[i] = 0.25f + 0.5f * (float)((i * 13u) % 97u) / 97.0f;
    }
    ew_device *dev = cpu(2);
    static const char *const methods[3] = {"nbg", "kpcn", "bgrid"};
    for (int m = 0; m < 3; m++)
        for (int over = 0; over < 2; over++) {
            char wa[128], wb[128];
            denoise_strided(dev, methods[m], 0, over, color, feat, FW, FH, a, wa, sizeof wa);
            denoise_strided(dev, methods[m], 1, over, color, feat, FW, FH, b, wb, sizeof wb);
            size_t differ = 0;
            for (size_t i = 0; i < (size_t)3 * FW * FH; i++) differ += memcmp(a + i, b + i, sizeof(float)) != 0;
            fprintf(stderr, "  %s%s: %s / %s: %zu values differ\n", methods[m], over ? ", over the colour" : "", wa,
                    wb, differ);
            CHECK(strstr(wa, "tiles") || strstr(wa, "bands"));
            CHECK(differ == 0);
        }
    ew_device_destroy(dev);
    free(color);
    free(feat);
    free(a);
    free(b);
}

TEST(filters_keep_finite_input_finite) {
    /* FLT_MAX (and -FLT_MAX) colour in 30 % of the pixels: sums inside a
     * filter overflow, yet every output sample must stay finite */
    enum { FW = 40, FH = 28 };
    static float in[FW * FH * 3], out[FW * FH * 3];
    for (int i = 0; i < FW * FH; i++)
        for (int c = 0; c < 3; c++) {
            unsigned h = (unsigned)(i * 2654435761u) >> 8;
            in[i * 3 + c] = h % 10 < 3 ? (h % 2 ? FLT_MAX : -FLT_MAX) : (float)(h % 97) / 97.0f;
        }
    ew_device *dev = cpu(2);
    int tried = 0;
    for (int k = 0; k < ew_method_count("filter"); k++) {
        const char *name;
        int32_t ni = 0;
        CHECK_EQ_INT(ew_method_get("filter", k, &name, NULL, &ni, NULL), EW_OK);
        int simple = 1; /* only colour and output required */
        for (int i = 0; i < ni; i++) {
            ew_image_info info;
            ew_method_image("filter", name, i, &info);
            if (info.required && strcmp(info.name, "color") && strcmp(info.name, "output")) simple = 0;
        }
        if (!simple) continue;
        ew_filter *f = NULL;
        CHECK_EQ_INT(ew_filter_create(dev, name, &f), EW_OK);
        ew_image vi = ew_image_packed(in, FW, FH, 3), vo = ew_image_packed(out, FW, FH, 3);
        ew_filter_set_image(f, "color", &vi);
        ew_filter_set_image(f, "output", &vo);
        if (ew_filter_commit(f) != EW_OK) {
            ew_filter_destroy(f);
            continue;
        }
        CHECK_EQ_INT(ew_filter_execute(f), EW_OK);
        ew_filter_destroy(f);
        long bad = 0;
        for (int i = 0; i < FW * FH * 3; i++) bad += !isfinite(out[i]);
        if (bad) FAIL_AT("filter '%s': %ld of %d output samples are not finite", name, bad, FW * FH * 3);
        tried++;
    }
    CHECK(tried >= 4); /* pyramid, separable, bilateral, atrous at least */
    ew_device_destroy(dev);
}

TEST(nan_against_nan_is_not_a_perfect_score) {
    static float a[W * H * 3], b[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) a[i] = b[i] = NAN;
    ew_device *dev = cpu(1);
    ew_image va = ew_image_packed(a, W, H, 3), vb = ew_image_packed(b, W, H, 3);
    double psnr = 0, ssim = 0;
    CHECK_EQ_INT(ew_image_psnr(dev, &va, &vb, &psnr), EW_OK);
    CHECK_EQ_INT(ew_image_ssim(dev, &va, &vb, &ssim), EW_OK);
    CHECK(isfinite(psnr) && psnr < 1.0);
    CHECK(ssim < 0.5);
    /* finite identical images still score +inf and 1 */
    for (int i = 0; i < W * H * 3; i++) a[i] = b[i] = 0.25f;
    CHECK_EQ_INT(ew_image_psnr(dev, &va, &vb, &psnr), EW_OK);
    CHECK(isinf(psnr));
    ew_device_destroy(dev);
}
