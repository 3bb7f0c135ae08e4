/* The public C API through the shared library only. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

static ew_device *cpu(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.type = EW_DEVICE_CPU;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

TEST(version_matches_header) {
    int a = -1, b = -1, c = -1;
    ew_version(&a, &b, &c);
    CHECK_EQ_INT(a, EW_VERSION_MAJOR);
    CHECK_EQ_INT(b, EW_VERSION_MINOR);
    CHECK_EQ_INT(c, EW_VERSION_PATCH);
    char want[32];
    snprintf(want, sizeof want, "%d.%d.%d", a, b, c);
    CHECK(strcmp(ew_version_string(), want) == 0);
}

TEST(device_create_and_threads) {
    ew_device *dev = cpu(3);
    CHECK(dev);
    CHECK_EQ_INT(ew_device_get_num_threads(dev), 3);
    CHECK_EQ_INT(ew_device_get_type(dev), EW_DEVICE_CPU);
    CHECK(strcmp(ew_device_last_error(dev), "") == 0);
    ew_device_destroy(dev);
    ew_device *def = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &def), EW_OK);
    CHECK(ew_device_get_num_threads(def) >= 1);
    ew_device_destroy(def);
    ew_device_destroy(NULL);
    ew_denoiser_destroy(NULL);
}

TEST(device_bad_arguments) {
    ew_device *dev = (ew_device *)1;
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = -1;
    CHECK_EQ_INT(ew_device_create(&desc, &dev), EW_ERR_INVALID_ARGUMENT);
    CHECK(dev == NULL);
    desc.num_threads = 0;
    desc.size = 3;
    CHECK_EQ_INT(ew_device_create(&desc, &dev), EW_ERR_INVALID_ARGUMENT);
    desc = (ew_device_desc)EW_DEVICE_DESC_INIT;
    desc.type = EW_DEVICE_CUDA;
    CHECK_EQ_INT(ew_device_create(&desc, &dev), EW_ERR_BACKEND_UNAVAILABLE);
    desc.type = (ew_device_type)42;
    CHECK_EQ_INT(ew_device_create(&desc, &dev), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_device_create(NULL, NULL), EW_ERR_INVALID_ARGUMENT);
}

TEST(result_strings_are_never_null) {
    for (int r = 0; r < 20; r++) CHECK(ew_result_string((ew_result)r) != NULL);
    CHECK(strcmp(ew_result_string(EW_OK), "success") == 0);
}

TEST(denoiser_errors_name_the_problem) {
    ew_device *dev = cpu(2);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "magic", &d), EW_ERR_UNSUPPORTED);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "magic");
    CHECK(d == NULL);
    CHECK_EQ_INT(ew_denoiser_create(NULL, "bgrid", &d), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_denoiser_create(dev, "bgrid", &d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_float(d, "spatial_rate", 0.0f), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "spatial_rate");
    CHECK_EQ_INT(ew_denoiser_set_float(d, "spatial_rate", NAN), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_denoiser_set_float(d, "colour", 1.0f), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_ERR_INVALID_STATE);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "color");
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_ERR_INVALID_STATE);

    float px[16 * 8 * 3] = {0}, small[4 * 4 * 3] = {0};
    ew_image v = ew_image_packed(px, 16, 8, 3);
    ew_image bad = v;
    bad.width = 0;
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &bad), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "positive");
    bad = v;
    bad.height = -5;
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &bad), EW_ERR_INVALID_ARGUMENT);
    bad = v;
    bad.width = 100000;
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &bad), EW_ERR_INVALID_ARGUMENT);
    bad = v;
    bad.data = NULL;
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &bad), EW_ERR_INVALID_ARGUMENT);
    bad = v;
    bad.channels = 2;
    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &bad), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "at least 3");
    CHECK_EQ_INT(ew_denoiser_set_image(d, "beauty", &v), EW_ERR_INVALID_ARGUMENT);

    CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &v), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "output", &v), EW_OK);
    ew_image s = ew_image_packed(small, 4, 4, 3);
    CHECK_EQ_INT(ew_denoiser_set_image(d, "albedo", &s), EW_OK);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "albedo");
    CHECK_EQ_INT(ew_denoiser_set_image(d, "albedo", NULL), EW_OK);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    CHECK(strcmp(ew_device_last_error(dev), "") == 0);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
}

static int cancel_at_half(void *user, double f) {
    (*(int *)user)++;
    return f < 0.5;
}

TEST(progress_reports_and_cancels) {
    ew_device *dev = cpu(2);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "bgrid", &d), EW_OK);
    float px[32 * 32 * 3] = {0};
    ew_image v = ew_image_packed(px, 32, 32, 3);
    ew_denoiser_set_image(d, "color", &v);
    ew_denoiser_set_image(d, "output", &v);
    int calls = 0;
    ew_denoiser_set_progress(d, cancel_at_half, &calls);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_ERR_CANCELLED);
    CHECK(calls >= 2);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
}

/* Strided RGBA input, a bottom-up output view with negative row stride,
 * NaN/Inf/negative samples: result is finite and identical to the packed run. */
TEST(views_with_strides_and_bad_samples) {
    enum { W = 40, H = 30 };
    static float rgba[H][W][4], packed[H][W][3], out_packed[H][W][3], out_flip[H][W][3];
    unsigned s = 3;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 4; c++) {
                s = s * 1664525u + 1013904223u;
                float v = (float)(s >> 8) / 16777216.0f * (x < 20 ? 0.2f : 2.0f);
                rgba[y][x][c] = v;
                if (c < 3) packed[y][x][c] = v;
            }
    rgba[3][4][0] = packed[3][4][0] = NAN;
    rgba[5][6][1] = packed[5][6][1] = INFINITY;
    rgba[7][8][2] = packed[7][8][2] = -3.0f;
    ew_device *dev = cpu(2);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "bgrid", &d), EW_OK);
    ew_image in = ew_image_packed(&rgba[0][0][0], W, H, 4);
    ew_image outv = ew_image_packed(&out_flip[H - 1][0][0], W, H, 3);
    outv.row_stride = -(int64_t)(W * 3 * sizeof(float));
    ew_denoiser_set_image(d, "color", &in);
    ew_denoiser_set_image(d, "output", &outv);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    ew_image inp = ew_image_packed(&packed[0][0][0], W, H, 3);
    ew_image outp = ew_image_packed(&out_packed[0][0][0], W, H, 3);
    ew_denoiser_set_image(d, "color", &inp);
    ew_denoiser_set_image(d, "output", &outp);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                CHECK(isfinite(out_packed[y][x][c]));
                CHECK(out_flip[H - 1 - y][x][c] == out_packed[y][x][c]);
            }
    /* in place: output aliases colour exactly */
    ew_denoiser_set_image(d, "output", &inp);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
    CHECK(memcmp(packed, out_packed, sizeof packed) == 0);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
}

TEST(psnr_and_ssim) {
    enum { W = 32, H = 24 };
    static float ref[H][W][3], noisy[H][W][3];
    unsigned s = 7;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                s = s * 1664525u + 1013904223u;
                ref[y][x][c] = 0.3f + 0.2f * (x > 15);
                noisy[y][x][c] = ref[y][x][c] + 0.05f * ((float)(s >> 8) / 16777216.0f - 0.5f);
            }
    ew_device *dev = cpu(1);
    ew_image r = ew_image_packed(&ref[0][0][0], W, H, 3), n = ew_image_packed(&noisy[0][0][0], W, H, 3);
    double p = 0, q = 0;
    CHECK_EQ_INT(ew_image_psnr(dev, &r, &r, &p), EW_OK);
    CHECK(isinf(p));
    CHECK_EQ_INT(ew_image_ssim(dev, &r, &r, &q), EW_OK);
    CHECK_NEAR(q, 1.0, 1e-6);
    /* independently: MSE of the tone-mapped difference */
    double se = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                double d = pow(noisy[y][x][c], 1 / 2.2) - pow(ref[y][x][c], 1 / 2.2);
                se += d * d;
            }
    CHECK_EQ_INT(ew_image_psnr(dev, &n, &r, &p), EW_OK);
    CHECK_NEAR(p, 10 * log10(1.0 / (se / (W * H * 3))), 1e-3);
    CHECK_EQ_INT(ew_image_ssim(dev, &n, &r, &q), EW_OK);
    CHECK(q < 0.99 && q > 0.0);
    double rel = -1, sm = -1, want_rel = 0, want_sm = 0;
    CHECK_EQ_INT(ew_image_relmse(dev, &r, &r, &rel), EW_OK);
    CHECK_NEAR(rel, 0.0, 0.0);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                double t = noisy[y][x][c], v = ref[y][x][c];
                want_rel += (t - v) * (t - v) / (v * v + 0.01);
                want_sm += fabs(t - v) / (fabs(t) + fabs(v) + 0.01);
            }
    CHECK_EQ_INT(ew_image_relmse(dev, &n, &r, &rel), EW_OK);
    CHECK_NEAR(rel, want_rel / (W * H * 3), 1e-9);
    CHECK_EQ_INT(ew_image_smape(dev, &n, &r, &sm), EW_OK);
    CHECK_NEAR(sm, want_sm / (W * H * 3), 1e-9);
    ew_image small = ew_image_packed(&ref[0][0][0], 8, 8, 3);
    CHECK_EQ_INT(ew_image_psnr(dev, &small, &r, &p), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "8x8");
    ew_device_destroy(dev);
}

TEST(introspection_lists_methods_and_parameters) {
    CHECK(ew_method_count("denoiser") >= 1);
    CHECK_EQ_INT(ew_method_count("nonsense"), 0);
    const char *name = NULL, *summary = NULL;
    int32_t ni = 0, np = 0;
    int found = 0;
    for (int32_t i = 0; i < ew_method_count("denoiser"); i++) {
        CHECK_EQ_INT(ew_method_get("denoiser", i, &name, &summary, &ni, &np), EW_OK);
        if (strcmp(name, "bgrid") != 0) continue;
        found = 1;
        CHECK(ni >= 2 && np >= 2);
        ew_param_info p;
        CHECK_EQ_INT(ew_method_param("denoiser", "bgrid", 0, &p), EW_OK);
        CHECK(strcmp(p.name, "spatial_rate") == 0);
        CHECK(p.min_value <= p.default_value && p.default_value <= p.max_value);
        ew_image_info im;
        CHECK_EQ_INT(ew_method_image("denoiser", "bgrid", 0, &im), EW_OK);
        CHECK(strcmp(im.name, "color") == 0 && im.required == 1);
        CHECK_EQ_INT(ew_method_image("denoiser", "bgrid", ni, &im), EW_ERR_INVALID_ARGUMENT);
    }
    CHECK(found);
    CHECK_EQ_INT(ew_method_get("denoiser", -1, &name, NULL, NULL, NULL), EW_ERR_INVALID_ARGUMENT);
}

/* ---- the one op handle and its older names ---- */

/* One run of `method` on a fixed noisy 4-channel image through the chosen
 * face; returns the checksum bits of the output. */
static void run_pyramid(ew_device *dev, int via_filter_names, float *out, int w, int h) {
    float *in = (float *)malloc((size_t)w * h * 4 * sizeof(float));
    unsigned s = 7;
    for (int i = 0; i < w * h * 4; i++) {
        s = s * 1664525u + 1013904223u;
        in[i] = (float)(s >> 8) / 16777216.0f;
    }
    ew_image vi = ew_image_packed(in, w, h, 4), vo = ew_image_packed(out, w, h, 4);
    if (via_filter_names) {
        ew_filter *f = NULL;
        CHECK_EQ_INT(ew_filter_create(dev, "pyramid", &f), EW_OK);
        CHECK_EQ_INT(ew_filter_set_image(f, "color", &vi), EW_OK);
        CHECK_EQ_INT(ew_filter_set_image(f, "output", &vo), EW_OK);
        CHECK_EQ_INT(ew_filter_set_int(f, "model", 3), EW_OK);
        CHECK_EQ_INT(ew_filter_set_float(f, "sigma_spatial", 2.5f), EW_OK);
        CHECK_EQ_INT(ew_filter_commit(f), EW_OK);
        CHECK_EQ_INT(ew_filter_execute(f), EW_OK);
        ew_filter_destroy(f);
    } else {
        ew_op *op = NULL;
        CHECK_EQ_INT(ew_op_create(dev, "pyramid", &op), EW_OK);
        CHECK_EQ_INT(ew_op_set_image(op, "color", &vi), EW_OK);
        CHECK_EQ_INT(ew_op_set_image(op, "output", &vo), EW_OK);
        CHECK_EQ_INT(ew_op_set_int(op, "model", 3), EW_OK);
        CHECK_EQ_INT(ew_op_set_float(op, "sigma_spatial", 2.5f), EW_OK);
        CHECK_EQ_INT(ew_op_commit(op), EW_OK);
        CHECK_EQ_INT(ew_op_execute(op), EW_OK);
        ew_op_destroy(op);
    }
    free(in);
}

TEST(op_handle_runs_what_the_filter_names_run) {
    ew_device *dev = cpu(2);
    enum { W = 37, H = 21 };
    static float a[W * H * 4], b[W * H * 4];
    run_pyramid(dev, 1, a, W, H);
    run_pyramid(dev, 0, b, W, H);
    CHECK(memcmp(a, b, sizeof a) == 0);
    ew_device_destroy(dev);
}

TEST(op_handle_creates_every_kind_and_names_it) {
    ew_device *dev = cpu(1);
    ew_op *op = (ew_op *)1;
    CHECK_EQ_INT(ew_op_create(dev, "magic", &op), EW_ERR_UNSUPPORTED);
    CHECK(op == NULL);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "magic");
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "pyramid"); /* the available names, of every kind */
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "bgrid");
    CHECK_EQ_INT(ew_op_create(dev, "bgrid", &op), EW_OK);
    CHECK(strcmp(ew_op_kind(op), "denoiser") == 0 && strcmp(ew_op_method(op), "bgrid") == 0);
    CHECK(ew_op_describe(op) == NULL); /* not committed */
    /* the older names take the same handle */
    float px[8 * 8 * 3] = {0};
    ew_image v = ew_image_packed(px, 8, 8, 3);
    CHECK_EQ_INT(ew_denoiser_set_image(op, "color", &v), EW_OK);
    CHECK_EQ_INT(ew_op_set_image(op, "output", &v), EW_OK);
    CHECK_EQ_INT(ew_denoiser_commit(op), EW_OK);
    CHECK(strcmp(ew_op_describe(op), "bgrid") == 0);
    CHECK(ew_denoiser_describe(op) == ew_op_describe(op));
    CHECK_EQ_INT(ew_op_execute(op), EW_OK);
    ew_op_destroy(op);
    CHECK_EQ_INT(ew_op_create(dev, "dof", &op), EW_OK);
    CHECK(strcmp(ew_op_kind(op), "filter") == 0);
    ew_op_destroy(op);
    /* the kind-bound older create still refuses the other kind */
    ew_filter *f = NULL;
    CHECK_EQ_INT(ew_filter_create(dev, "bgrid", &f), EW_ERR_UNSUPPORTED);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "unknown filter 'bgrid'");
    ew_op_destroy(NULL);
    CHECK(ew_op_kind(NULL) == NULL && ew_op_method(NULL) == NULL && ew_op_describe(NULL) == NULL);
    ew_device_destroy(dev);
}

TEST(op_get_reads_parameters_back) {
    ew_device *dev = cpu(1);
    ew_op *op = NULL;
    CHECK_EQ_INT(ew_op_create(dev, "pyramid", &op), EW_OK);
    int32_t i = -1;
    float f = -1.0f;
    /* defaults from the descriptor */
    CHECK_EQ_INT(ew_op_get_int(op, "radius", &i), EW_OK);
    ew_param_info p;
    CHECK_EQ_INT(ew_method_param("filter", "pyramid", 1, &p), EW_OK);
    CHECK(strcmp(p.name, "radius") == 0 && i == (int32_t)p.default_value);
    CHECK_EQ_INT(ew_op_get_float(op, "sigma_range", &f), EW_OK);
    CHECK(f == 0.1f);
    /* what was set */
    CHECK_EQ_INT(ew_op_set_int(op, "radius", 17), EW_OK);
    CHECK_EQ_INT(ew_op_get_int(op, "radius", &i), EW_OK);
    CHECK_EQ_INT(i, 17);
    CHECK_EQ_INT(ew_op_get_float(op, "radius", &f), EW_OK); /* any parameter reads as a float */
    CHECK(f == 17.0f);
    CHECK_EQ_INT(ew_op_set_float(op, "sigma_range", 0.25f), EW_OK);
    CHECK_EQ_INT(ew_op_get_float(op, "sigma_range", &f), EW_OK);
    CHECK(f == 0.25f);
    /* a refused value leaves the old one */
    CHECK_EQ_INT(ew_op_set_int(op, "radius", 100000), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_get_int(op, "radius", &i), EW_OK);
    CHECK_EQ_INT(i, 17);
    /* errors name the problem */
    CHECK_EQ_INT(ew_op_get_int(op, "sigma_range", &i), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "get_float");
    CHECK_EQ_INT(ew_op_get_float(op, "colour", &f), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "sigma_range");
    CHECK_EQ_INT(ew_op_get_float(op, "radius", NULL), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_get_float(NULL, "radius", &f), EW_ERR_INVALID_ARGUMENT);
    ew_op_destroy(op);

    /* what the method writes back: temporal's one-shot reset reads 0 after
     * the commit that used it */
    CHECK_EQ_INT(ew_op_create(dev, "temporal", &op), EW_OK);
    float px[8 * 8 * 3] = {0};
    ew_image v = ew_image_packed(px, 8, 8, 3);
    ew_op_set_image(op, "color", &v);
    ew_op_set_image(op, "output", &v);
    CHECK_EQ_INT(ew_op_set_int(op, "reset", 1), EW_OK);
    CHECK_EQ_INT(ew_op_get_int(op, "reset", &i), EW_OK);
    CHECK_EQ_INT(i, 1);
    CHECK_EQ_INT(ew_op_commit(op), EW_OK);
    CHECK_EQ_INT(ew_op_get_int(op, "reset", &i), EW_OK);
    CHECK_EQ_INT(i, 0);
    ew_op_destroy(op);
    ew_device_destroy(dev);
}

/* ---- descriptors: direction, in-place, enum names, method flags ---- */

static int32_t image_index(const char *method, const char *image) {
    ew_image_info im;
    for (int32_t i = 0; ew_method_image(NULL, method, i, &im) == EW_OK; i++)
        if (!strcmp(im.name, image)) return i;
    return -1;
}

static int32_t param_index(const char *method, const char *param) {
    ew_param_info p;
    for (int32_t i = 0; ew_method_param(NULL, method, i, &p) == EW_OK; i++)
        if (!strcmp(p.name, param)) return i;
    return -1;
}

TEST(descriptors_state_image_direction_and_inplace) {
    uint32_t fl = 99;
    /* every method: "output" is written, "color" read and may be the output */
    for (int32_t m = 0; m < ew_method_count(NULL); m++) {
        const char *name = NULL;
        int32_t ni = 0;
        CHECK_EQ_INT(ew_method_get(NULL, m, &name, NULL, &ni, NULL), EW_OK);
        CHECK(ew_method_kind(name) != NULL);
        int outputs = 0;
        for (int32_t i = 0; i < ni; i++) {
            ew_image_info im;
            CHECK_EQ_INT(ew_method_image(NULL, name, i, &im), EW_OK);
            CHECK_EQ_INT(ew_method_image_flags(NULL, name, i, &fl), EW_OK);
            if (!strcmp(im.name, "output")) CHECK_EQ_INT((int)fl, (int)EW_IMAGE_OUTPUT);
            if (!strcmp(im.name, "color")) CHECK_EQ_INT((int)fl, (int)EW_IMAGE_INPLACE);
            /* an output is never also an in-place input */
            CHECK(!((fl & EW_IMAGE_OUTPUT) && (fl & EW_IMAGE_INPLACE)));
            outputs += (fl & EW_IMAGE_OUTPUT) != 0;
        }
        CHECK(outputs >= 1);
    }
    CHECK_EQ_INT(ew_method_count(NULL), ew_method_count("denoiser") + ew_method_count("filter"));
    /* the DoF's circle of confusion is a second output; its depth is read */
    CHECK_EQ_INT(ew_method_image_flags("filter", "dof", image_index("dof", "coc"), &fl), EW_OK);
    CHECK_EQ_INT((int)fl, (int)EW_IMAGE_OUTPUT);
    CHECK_EQ_INT(ew_method_image_flags(NULL, "dof", image_index("dof", "depth"), &fl), EW_OK);
    CHECK_EQ_INT((int)fl, 0);
    CHECK_EQ_INT(ew_method_image_flags("denoiser", "dof", 0, &fl), EW_ERR_INVALID_ARGUMENT); /* wrong kind */
    CHECK_EQ_INT(ew_method_image_flags(NULL, "dof", 99, &fl), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_method_image_flags(NULL, "dof", 0, NULL), EW_ERR_INVALID_ARGUMENT);
    CHECK(strcmp(ew_method_kind("nbg"), "denoiser") == 0 && strcmp(ew_method_kind("atrous"), "filter") == 0);
    CHECK(ew_method_kind("magic") == NULL && ew_method_kind(NULL) == NULL);
}

TEST(descriptors_name_enum_choices) {
    const int32_t model = param_index("pyramid", "model");
    CHECK_EQ_INT(ew_method_param_num_choices("filter", "pyramid", model), 4);
    const char *want[] = {"color", "gi", "depth", "none"};
    for (int32_t c = 0; c < 4; c++) {
        CHECK(strcmp(ew_method_param_choice("filter", "pyramid", model, c), want[c]) == 0);
        CHECK_EQ_INT(ew_method_param_choice_index(NULL, "pyramid", model, want[c]), c);
    }
    CHECK(ew_method_param_choice("filter", "pyramid", model, 4) == NULL);
    CHECK(ew_method_param_choice("filter", "pyramid", model, -1) == NULL);
    CHECK_EQ_INT(ew_method_param_choice_index(NULL, "pyramid", model, "fancy"), -1);
    CHECK_EQ_INT(ew_method_param_num_choices(NULL, "pyramid", param_index("pyramid", "radius")), 0);
    CHECK_EQ_INT(ew_method_param_num_choices(NULL, "pyramid", 99), -1);
    CHECK_EQ_INT(ew_method_param_num_choices(NULL, "magic", 0), -1);
    /* DoF's method and nbg's models */
    const int32_t dm = param_index("dof", "method");
    CHECK_EQ_INT(ew_method_param_num_choices(NULL, "dof", dm), 3);
    CHECK(strcmp(ew_method_param_choice(NULL, "dof", dm, 1), "bilateral") == 0);
    const int32_t nm = param_index("nbg", "model");
    CHECK(strcmp(ew_method_param_choice(NULL, "nbg", nm, 3), "2layer-3grid-1spp") == 0);
    /* every enum's range is exactly its choices, and its default one of them */
    for (int32_t m = 0; m < ew_method_count(NULL); m++) {
        const char *name = NULL;
        int32_t np = 0;
        ew_method_get(NULL, m, &name, NULL, NULL, &np);
        for (int32_t k = 0; k < np; k++) {
            ew_param_info p;
            ew_method_param(NULL, name, k, &p);
            int32_t n = ew_method_param_num_choices(NULL, name, k);
            CHECK(n >= 0);
            if (n == 0) continue;
            CHECK_EQ_INT(p.type, EW_PARAM_INT);
            CHECK(p.min_value == 0.0f && p.max_value == (float)(n - 1));
            CHECK(ew_method_param_choice(NULL, name, k, (int32_t)p.default_value) != NULL);
        }
    }
}

TEST(descriptors_flag_params_and_methods) {
    uint32_t fl = 0;
    CHECK_EQ_INT(ew_method_param_flags(NULL, "atrous", param_index("atrous", "radius"), &fl), EW_OK);
    CHECK_EQ_INT((int)fl, (int)(EW_PARAM_PIXELS | EW_PARAM_NOOP_AT_ZERO));
    CHECK_EQ_INT(ew_method_param_flags(NULL, "atrous", param_index("atrous", "iterations"), &fl), EW_OK);
    CHECK_EQ_INT((int)fl, (int)EW_PARAM_NOOP_AT_ZERO);
    CHECK_EQ_INT(ew_method_param_flags(NULL, "dof", param_index("dof", "fstop"), &fl), EW_OK);
    CHECK_EQ_INT((int)fl, 0);
    /* the flag and the older query agree everywhere */
    for (int32_t m = 0; m < ew_method_count(NULL); m++) {
        const char *name = NULL;
        int32_t np = 0;
        ew_method_get(NULL, m, &name, NULL, NULL, &np);
        for (int32_t k = 0; k < np; k++) {
            CHECK_EQ_INT(ew_method_param_flags(NULL, name, k, &fl), EW_OK);
            CHECK_EQ_INT((fl & EW_PARAM_PIXELS) != 0, ew_method_param_is_pixels(ew_method_kind(name), name, k));
        }
    }
    /* host tools vs references */
    CHECK_EQ_INT(ew_method_flags(NULL, "pyramid", &fl), EW_OK);
    CHECK(fl & EW_METHOD_HOST);
    CHECK_EQ_INT(ew_method_flags("filter", "bilateral", &fl), EW_OK);
    CHECK(!(fl & EW_METHOD_HOST));
    CHECK_EQ_INT(ew_method_flags(NULL, "magic", &fl), EW_ERR_INVALID_ARGUMENT);
    /* parameters a file may give instead */
    CHECK(strcmp(ew_method_param_data(NULL, "pyramid", param_index("pyramid", "weights")), "weights") == 0);
    CHECK(strcmp(ew_method_param_data(NULL, "nbg", param_index("nbg", "model")), "weights") == 0);
    CHECK(ew_method_param_data(NULL, "pyramid", param_index("pyramid", "radius")) == NULL);
    CHECK(ew_method_param_data(NULL, "bilateral", 0) == NULL);
    CHECK(ew_method_param_data(NULL, "magic", 0) == NULL);
}

/* Every denoiser reads RGB and passes an RGBA colour's alpha through to an
 * RGBA output of its own; written over the colour, the alpha stays. */
TEST(denoisers_pass_alpha_through) {
    enum { W = 40, H = 24 };
    static float c[H][W][4], o[H][W][4], alb[H][W][3], nrm[H][W][3], dep[H][W];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            for (int k = 0; k < 3; k++) {
                c[y][x][k] = 0.2f + 0.1f * (float)((x + y + k) % 4);
                alb[y][x][k] = 0.6f;
                nrm[y][x][k] = k == 2 ? 1.0f : 0.0f;
            }
            c[y][x][3] = (float)(x % 3) / 2.0f;
            dep[y][x] = 2.0f;
        }
    ew_device *dev = cpu(2);
    static const char *const methods[] = {"bgrid", "nbg", "kpcn", "auto"};
    for (int m = 0; m < 4; m++) {
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) o[y][x][3] = -9.0f;
        ew_denoiser *d = NULL;
        CHECK_EQ_INT(ew_denoiser_create(dev, methods[m], &d), EW_OK);
        ew_image ci = ew_image_packed(&c[0][0][0], W, H, 4), oi = ew_image_packed(&o[0][0][0], W, H, 4);
        ew_image ai = ew_image_packed(&alb[0][0][0], W, H, 3), ni = ew_image_packed(&nrm[0][0][0], W, H, 3);
        ew_image zi = ew_image_packed(&dep[0][0], W, H, 1);
        CHECK_EQ_INT(ew_denoiser_set_image(d, "color", &ci), EW_OK);
        CHECK_EQ_INT(ew_denoiser_set_image(d, "albedo", &ai), EW_OK);
        CHECK_EQ_INT(ew_denoiser_set_image(d, "normal", &ni), EW_OK);
        CHECK_EQ_INT(ew_denoiser_set_image(d, "depth", &zi), EW_OK);
        CHECK_EQ_INT(ew_denoiser_set_image(d, "output", &oi), EW_OK);
        CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
        CHECK_EQ_INT(ew_denoiser_execute(d), EW_OK);
        ew_denoiser_destroy(d);
        int passed = 0;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) passed += o[y][x][3] == c[y][x][3];
        if (passed != W * H) fprintf(stderr, "  %s: %d of %d alphas passed\n", methods[m], passed, W * H);
        CHECK_EQ_INT(passed, W * H);
    }
    ew_device_destroy(dev);
}
