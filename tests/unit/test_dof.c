/* Depth of field: the thin-lens CoC against hand-computed values, the
 * near-field dilation against its 2-D definition, and both blur directions
 * of §4.1 on a synthetic scene, with the pyramid and the exact filter. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/dof.h"
#include "src/backend.h"

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

TEST(coc_is_the_thin_lens_formula) {
    ew_dof_camera c = {50.0f, 2.0f, 5.0f, 36.0f, 1920, 1080, 1000.0f, 1.0f};
    /* c = (f/N) f |S - Sf| / (S (Sf - f)) mm on the sensor, * 1920 / 36 px */
    CHECK_NEAR(ew_dof_coc(&c, 10.0f), 25.0 * 50 * 5000 / (10000.0 * 4950) * 1920 / 36, 1e-3);
    CHECK_NEAR(ew_dof_coc(&c, 2.5f), -25.0 * 50 * 2500 / (2500.0 * 4950) * 1920 / 36, 1e-3);
    CHECK_NEAR(ew_dof_coc(&c, 5.0f), 0.0, 1e-6);
    /* the sky: Depth 1e10, Denoising Depth 0, missing */
    double inf = 25.0 * 50 / 4950 * 1920 / 36;
    CHECK_NEAR(ew_dof_coc(&c, 1e10f), inf, 1e-3);
    CHECK_NEAR(ew_dof_coc(&c, 0.0f), inf, 1e-3);
    CHECK_NEAR(ew_dof_coc(&c, NAN), inf, 1e-3);
    CHECK_NEAR(ew_dof_coc(&c, INFINITY), inf, 1e-3);
    /* portrait images: the sensor spans the larger side */
    c.width = 1080;
    c.height = 1920;
    CHECK_NEAR(ew_dof_coc(&c, 10.0f), 25.0 * 50 * 5000 / (10000.0 * 4950) * 1920 / 36, 1e-3);
    c.max_coc = 4.0f;
    CHECK_NEAR(ew_dof_coc(&c, 0.3f), -4.0, 1e-6);
}

/* With A = scale |c|: C(p) = A(p), D(p) = max(A(p), max over near q whose
 * tile is within reach of p's tile: (max axis tile distance - 1) * TILE <=
 * A(q) / 2) */
TEST(near_field_dilation_matches_its_definition) {
    const int w = 61, h = 47;
    unsigned s = 9;
    float *depth = malloc(sizeof(float) * w * h), *coc = malloc(sizeof(float) * w * h);
    float *attr = malloc(sizeof(float) * w * h * 2), *tiles = malloc(sizeof(float) * 2 * 16 * 12);
    for (int i = 0; i < w * h; i++) depth[i] = urand(&s) < 0.05f ? 0.6f + urand(&s) : 3.0f + 10.0f * urand(&s);
    const float S = 2.1213203f;
    ew_dof_camera cam = {50.0f, 1.4f, 3.0f, 36.0f, w, h, 40.0f, S};
    ew_device *dev = make_device(2);
    ew_dof_compute_attributes(dev, &cam, depth, coc, tiles, attr, 0);
    const int T = EW_DOF_TILE;
    int ok = 1;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float want = fabsf(coc[y * w + x]) * S;
            for (int qy = 0; qy < h; qy++)
                for (int qx = 0; qx < w; qx++) {
                    float c = coc[qy * w + qx];
                    if (c >= 0) continue;
                    int dx = abs(qx / T - x / T), dy = abs(qy / T - y / T), d = dx > dy ? dx : dy;
                    if ((float)((d - 1) * T) <= -0.5f * c * S && -c * S > want) want = -c * S;
                }
            if (attr[(y * w + x) * 2] != want || attr[(y * w + x) * 2 + 1] != fabsf(coc[y * w + x]) * S) ok = 0;
        }
    CHECK(ok);
    /* the planes the pyramid reads: the same numbers, D plane then C plane */
    float *planes = malloc(sizeof(float) * w * h * 2);
    ew_dof_compute_attributes(dev, &cam, depth, coc, tiles, planes, 1);
    int same = 1;
    for (int j = 0; j < w * h; j++) same &= planes[j] == attr[2 * j] && planes[w * h + j] == attr[2 * j + 1];
    CHECK(same);
    ew_device_destroy(dev);
    free(depth); free(coc); free(attr); free(tiles); free(planes);
}

/* A textured background and a flat red square in front of it. */
typedef struct {
    int w, h;
    float *rgb, *depth, *out;
} scene;

static scene make_scene(float fg_depth, float bg_depth) {
    scene sc = {160, 120, NULL, NULL, NULL};
    const int n = sc.w * sc.h;
    sc.rgb = malloc(sizeof(float) * n * 3);
    sc.depth = malloc(sizeof(float) * n);
    sc.out = malloc(sizeof(float) * n * 3);
    for (int y = 0; y < sc.h; y++)
        for (int x = 0; x < sc.w; x++) {
            int i = y * sc.w + x, fg = x >= 60 && x < 100 && y >= 40 && y < 80;
            float stripe = ((x / 2) % 2) ? 0.9f : 0.1f; /* 2-px stripes: blur flattens them */
            sc.rgb[i * 3 + 0] = fg ? 1.0f : 0.0f;
            sc.rgb[i * 3 + 1] = fg ? 0.0f : stripe;
            sc.rgb[i * 3 + 2] = fg ? 0.0f : 0.5f;
            sc.depth[i] = fg ? fg_depth : bg_depth;
        }
    return sc;
}

static ew_result run_dof(ew_device *dev, scene *sc, float focus, int method) {
    const float focal = 100.0f; /* CoCs of 15 px and more on this small image */
    ew_filter *f = NULL;
    ew_result r = ew_filter_create(dev, "dof", &f);
    ew_image vi = ew_image_packed(sc->rgb, sc->w, sc->h, 3), vo = ew_image_packed(sc->out, sc->w, sc->h, 3);
    ew_image vd = ew_image_packed(sc->depth, sc->w, sc->h, 1);
    if (r == EW_OK) r = ew_filter_set_image(f, "color", &vi);
    if (r == EW_OK) r = ew_filter_set_image(f, "depth", &vd);
    if (r == EW_OK) r = ew_filter_set_image(f, "output", &vo);
    if (r == EW_OK) r = ew_filter_set_float(f, "focus_distance", focus);
    if (r == EW_OK) r = ew_filter_set_float(f, "fstop", 1.4f);
    if (r == EW_OK) r = ew_filter_set_float(f, "focal_length", focal);
    if (r == EW_OK) r = ew_filter_set_int(f, "radius", 16);
    if (r == EW_OK) r = ew_filter_set_int(f, "method", method);
    if (r == EW_OK) r = ew_filter_set_int(f, "weights", 0);
    if (r == EW_OK) r = ew_filter_commit(f);
    if (r == EW_OK) r = ew_filter_execute(f);
    ew_filter_destroy(f);
    return r;
}

static void free_scene(scene *sc) {
    free(sc->rgb);
    free(sc->depth);
    free(sc->out);
}

/* stripe contrast of the background along row y over [x0, x1) */
static double contrast(const scene *sc, int y, int x0, int x1) {
    double lo = 1, hi = 0;
    for (int x = x0; x < x1; x++) {
        double g = sc->out[(y * sc->w + x) * 3 + 1];
        lo = fmin(lo, g);
        hi = fmax(hi, g);
    }
    return hi - lo;
}

TEST(sharp_foreground_stays_out_of_the_blurred_background) {
    ew_device *dev = make_device(2);
    for (int method = 0; method < 2; method++) {
        scene sc = make_scene(2.0f, 30.0f); /* focus on the square */
        CHECK_EQ_INT(run_dof(dev, &sc, 2.0f, method), EW_OK);
        /* the background is blurred: stripes nearly gone far from the square */
        CHECK(contrast(&sc, 10, 10, 50) < 0.2);
        /* the square is sharp: unchanged inside, up to its edge */
        for (int y = 40; y < 80; y++) {
            CHECK_NEAR(sc.out[(y * sc.w + 60) * 3 + 0], 1.0, 0.02);
            CHECK_NEAR(sc.out[(y * sc.w + 99) * 3 + 1], 0.0, 0.02);
        }
        /* no red halo: the sharp square does not bleed into the background */
        for (int y = 45; y < 75; y++) {
            CHECK(sc.out[(y * sc.w + 58) * 3 + 0] < 0.03);
            CHECK(sc.out[(y * sc.w + 101) * 3 + 0] < 0.03);
        }
        free_scene(&sc);
    }
    ew_device_destroy(dev);
}

TEST(blurred_foreground_spreads_over_the_sharp_background) {
    ew_device *dev = make_device(2);
    ew_dof_camera cam = {100.0f, 1.4f, 30.0f, 36.0f, 160, 120, 32.0f, 1.0f};
    CHECK(ew_dof_coc(&cam, 0.6f) <= -32.0f); /* the square's CoC: capped at 2 radius */
    for (int method = 0; method < 2; method++) {
        scene sc = make_scene(0.6f, 30.0f); /* focus on the background */
        CHECK_EQ_INT(run_dof(dev, &sc, 30.0f, method), EW_OK);
        /* far from the square the background stays sharp */
        CHECK(contrast(&sc, 10, 10, 50) > 0.75);
        /* next to the square, the blurred red spreads over the background */
        double red_out = 0;
        for (int y = 50; y < 70; y++) red_out += sc.out[(y * sc.w + 58) * 3 + 0] / 20;
        CHECK(red_out > 0.1);
        /* falling off with the distance to the square, gone beyond its CoC */
        double red_far = 0, red_gone = 0;
        for (int y = 50; y < 70; y++) {
            red_far += sc.out[(y * sc.w + 52) * 3 + 0] / 20;
            red_gone += sc.out[(y * sc.w + 30) * 3 + 0] / 20;
        }
        CHECK(red_out > red_far && red_far > red_gone);
        CHECK(red_gone < 0.01);
        free_scene(&sc);
    }
    ew_device_destroy(dev);
}

TEST(pyramid_close_to_exact_and_parameters_checked) {
    ew_device *dev = make_device(2);
    /* both directions; the numbers are reported, the thresholds only catch
     * breakage (the benchmark measures quality on renders) */
    const float fg[2] = {2.0f, 0.6f}, focus[2] = {2.0f, 30.0f};
    const double floor_db[2] = {25.0, 15.0};
    for (int k = 0; k < 2; k++) {
        scene a = make_scene(fg[k], 30.0f), b = make_scene(fg[k], 30.0f);
        CHECK_EQ_INT(run_dof(dev, &a, focus[k], 0), EW_OK);
        CHECK_EQ_INT(run_dof(dev, &b, focus[k], 1), EW_OK);
        ew_image va = ew_image_packed(a.out, a.w, a.h, 3), vb = ew_image_packed(b.out, b.w, b.h, 3);
        double p = 0;
        CHECK_EQ_INT(ew_image_psnr(dev, &va, &vb, &p), EW_OK);
        fprintf(stderr, "  pyramid (analytic) vs exact, %s: %.2f dB\n", k ? "blurred foreground" : "blurred background", p);
        CHECK(p > floor_db[k]);
        free_scene(&a);
        free_scene(&b);
    }
    scene a = make_scene(2.0f, 30.0f);
    /* focus inside the lens */
    CHECK_EQ_INT(run_dof(dev, &a, 0.01f, 0), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "'focus_distance'");
    free_scene(&a);
    ew_device_destroy(dev);
}
