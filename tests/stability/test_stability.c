/*
 * Stability suite: every denoiser and filter of the library on the frames
 * where denoisers fail — NaN/Inf/negative samples, zero and black albedo,
 * huge emitters, 1x1 and 2x3 frames — and on real renders of the hard
 * families (glass, fireflies, depth of field, motion blur) from the shared
 * dataset when present. Every output must be finite; on the renders the
 * `auto` denoiser must stay above stated PSNR floors and above the input.
 */
#include "ew_test.h"

#include "method_run.h"

static ew_method_spec all_specs[32];
static int n_specs;

/* Every method the library lists, with default parameters; filters
 * demodulated like a renderer would use them. "temporal" needs a sequence
 * and is covered by its own tests. */
static void collect(void) {
    if (n_specs) return;
    const char *kinds[2] = {"denoiser", "filter"};
    for (int k = 0; k < 2; k++)
        for (int32_t i = 0; i < ew_method_count(kinds[k]) && n_specs < 32; i++) {
            const char *name;
            ew_method_get(kinds[k], i, &name, NULL, NULL, NULL);
            if (!strcmp(name, "temporal")) continue;
            ew_method_spec *s = &all_specs[n_specs++];
            memset(s, 0, sizeof *s);
            s->label = name;
            s->kind = kinds[k];
            s->name = name;
            s->demodulate = k == 1;
        }
}

static unsigned rng = 12345;
static float urand(void) {
    rng = rng * 1664525u + 1013904223u;
    return (float)(rng >> 8) / 16777216.0f;
}

static void fill_layer(ew_layer_data *d, int w, int h) {
    size_t n = (size_t)w * h;
    d->width = w;
    d->height = h;
    d->color = malloc(n * 3 * sizeof(float));
    d->albedo = malloc(n * 3 * sizeof(float));
    d->normal = malloc(n * 3 * sizeof(float));
    d->depth = malloc(n * sizeof(float));
    d->vector = NULL;
    for (size_t i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++) {
            d->color[i * 3 + c] = 0.5f * urand() * urand() * 4.0f;
            d->albedo[i * 3 + c] = 0.2f + 0.6f * (float)((i % (size_t)w) < (size_t)w / 2);
        }
        d->normal[i * 3] = 0.0f;
        d->normal[i * 3 + 1] = 0.0f;
        d->normal[i * 3 + 2] = 1.0f;
        d->depth[i] = 3.0f + (float)(i / (size_t)w) * 0.01f;
    }
}

/* Runs every method; returns the number of (method, pixel) failures. */
static int all_finite(const ew_layer_data *d, const char *what) {
    collect();
    ew_device *dev;
    ew_device_create(NULL, &dev);
    size_t n = (size_t)d->width * d->height;
    float *out = malloc(n * 3 * sizeof(float));
    int bad = 0;
    for (int m = 0; m < n_specs; m++) {
        char err[512] = "";
        double ms;
        if (ew_method_run(dev, &all_specs[m], d, out, &ms, err, sizeof err) != 0) {
            /* refusing cleanly is allowed (e.g. a filter too big for a 1x1 frame) */
            if (!err[0]) { fprintf(stderr, "  %s on %s failed without a message\n", all_specs[m].label, what); bad++; }
            continue;
        }
        size_t nonfinite = 0;
        for (size_t i = 0; i < n * 3; i++) nonfinite += !isfinite(out[i]);
        if (nonfinite) {
            fprintf(stderr, "  %s on %s: %zu non-finite output values\n", all_specs[m].label, what, nonfinite);
            bad++;
        }
    }
    free(out);
    ew_device_destroy(dev);
    return bad;
}

TEST(nan_inf_negative_samples) {
    ew_layer_data d;
    fill_layer(&d, 48, 40);
    d.color[0] = NAN;
    d.color[7] = INFINITY;
    d.color[20] = -INFINITY;
    d.color[33] = -5.0f;
    d.albedo[50] = NAN;
    d.normal[90] = NAN;
    d.depth[100] = INFINITY;
    int bad = all_finite(&d, "nan/inf/negative");
    ew_layer_data_free(&d);
    CHECK_EQ_INT(bad, 0);
}

TEST(zero_albedo_black_and_emitters) {
    ew_layer_data d;
    fill_layer(&d, 48, 40);
    for (int i = 0; i < 48 * 10; i++) { /* top rows: emitter with zero albedo, then black paint */
        for (int c = 0; c < 3; c++) d.albedo[i * 3 + c] = 0.0f;
        for (int c = 0; c < 3; c++) d.color[i * 3 + c] = i < 48 * 5 ? 1e4f : 0.0f;
    }
    d.color[3 * 1000] = 6e4f; /* half-float-sized firefly */
    int bad = all_finite(&d, "zero albedo");
    ew_layer_data_free(&d);
    CHECK_EQ_INT(bad, 0);
}

TEST(tiny_frames) {
    int sizes[][2] = {{1, 1}, {2, 3}, {3, 7}, {17, 1}};
    int bad = 0;
    for (int k = 0; k < 4; k++) {
        ew_layer_data d;
        fill_layer(&d, sizes[k][0], sizes[k][1]);
        bad += all_finite(&d, "tiny frame");
        ew_layer_data_free(&d);
    }
    CHECK_EQ_INT(bad, 0);
}

/* Real hard renders: auto must beat the input and stay above a floor
 * (floors are the measured values minus a margin; see BENCHMARKS.md). */
static void hard_scene(const char *scene, int spp, double floor_db, int must_beat_input) {
    const char *root = getenv("EW_SHARED_DATA");
    char in[2048], ref[2048], err[512];
    snprintf(in, sizeof in, "%s/%s/f0001_spp%04d.exr", root ? root : "", scene, spp);
    snprintf(ref, sizeof ref, "%s/%s/f0001_ref1024.exr", root ? root : "", scene);
    ewio_file *f = NULL, *r = NULL;
    if (!root || ewio_read(in, &f, err, sizeof err) != 0) SKIP("shared dataset not found");
    CHECK(ewio_read(ref, &r, err, sizeof err) == 0);
    ew_layer_passes lp;
    ew_layer_data d;
    CHECK(ew_find_layer_passes(f, "ViewLayer", &lp, err, sizeof err) == 0);
    CHECK(ew_layer_data_read(f, &lp, &d, err, sizeof err) == 0);
    int w = d.width, h = d.height;
    float *refc = malloc(sizeof(float) * w * h * 3), *out = malloc(sizeof(float) * w * h * 3);
    CHECK(ewio_get_pass(r, "ViewLayer", "Combined", "RGB", refc, err, sizeof err) == 0);
    ew_device *dev;
    ew_device_create(NULL, &dev);
    ew_method_spec s;
    memset(&s, 0, sizeof s);
    s.label = "auto";
    s.kind = "denoiser";
    s.name = "auto";
    double ms, p_in, p_out;
    CHECK(ew_method_run(dev, &s, &d, out, &ms, err, sizeof err) == 0);
    ew_image vi = ew_image_packed(d.color, w, h, 3), vo = ew_image_packed(out, w, h, 3),
             vr = ew_image_packed(refc, w, h, 3);
    ew_image_psnr(dev, &vi, &vr, &p_in);
    ew_image_psnr(dev, &vo, &vr, &p_out);
    fprintf(stderr, "  %s %d spp: input %.2f dB -> auto %.2f dB (floor %.1f)\n", scene, spp, p_in, p_out, floor_db);
    for (int i = 0; i < w * h * 3; i++) CHECK(isfinite(out[i]));
    ew_device_destroy(dev);
    ew_layer_data_free(&d);
    free(refc);
    free(out);
    ewio_free(f);
    ewio_free(r);
    if (must_beat_input) CHECK(p_out > p_in);
    CHECK(p_out >= floor_db);
}

TEST(glass_caustics) { hard_scene("c_glass_120_256x256", 4, 32.0, 1); }
TEST(fireflies) { hard_scene("d_firefly_115_256x256", 4, 27.0, 1); }
/* A known failure: on a defocused frame the feature passes are themselves
 * blurred and the hand-made guide cannot separate the bokeh, so auto at 4 spp
 * is 0.2 dB below the input (measured 27.73 vs 27.93), and at 1 spp it gains
 * only 1.2 dB (21.47 -> 22.67). The floors guard against it getting worse;
 * BENCHMARKS.md lists it. */
TEST(depth_of_field) { hard_scene("e_dof_116_256x256", 4, 27.2, 0); }
TEST(depth_of_field_1spp) { hard_scene("e_dof_116_256x256", 1, 22.0, 1); }
TEST(motion_blur) { hard_scene("f_motionblur_117_256x256", 4, 34.5, 1); }
