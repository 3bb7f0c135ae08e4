/*
 * Stability suite: every denoiser and filter of the library on the frames
 * where denoisers fail — NaN/Inf/negative samples, zero and black albedo,
 * huge emitters, 1x1 and 2x3 frames — on the committed renders of
 * volumetrics, high-frequency textures and thin geometry
 * (tests/data/stability, made by tools/blender/render_scene.py), and on real
 * renders of the hard families (glass, fireflies, depth of field, motion
 * blur) from the shared dataset when present. Every output must be finite;
 * on the renders the `auto` denoiser must stay above stated PSNR floors and
 * above the input. An 8K frame (7680x4320) runs only when EW_STABILITY_LARGE
 * is set (CTest test test_stability_8k, label "large", see CMakeLists.txt).
 *
 * Image strips: with EW_STABILITY_STRIPS=DIR every case writes
 * DIR/<case>.png (input | each method | reference, tone-mapped; magenta =
 * non-finite, dark grey = method refused the frame) and DIR/<case>.txt
 * naming the tiles in order with their PSNR.
 */
#include "ew_test.h"

#include <math.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "frame_energy.h"
#include "method_run.h"

#ifndef EW_STABILITY_DATA_DIR
#define EW_STABILITY_DATA_DIR "tests/data/stability"
#endif

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
    memset(d, 0, sizeof *d);
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

/* ---- image strips (EW_STABILITY_STRIPS=DIR) ----------------------------- */

typedef struct strip {
    int on, w, h, n;
    float *tiles[40];
    char text[4096];
} strip;

static void strip_begin(strip *st, int w, int h) {
    memset(st, 0, sizeof *st);
    const char *dir = getenv("EW_STABILITY_STRIPS");
    /* strips of frames up to 1024x1024; the 8K case writes none */
    st->on = dir && dir[0] && (size_t)w * h <= 1024u * 1024u;
    st->w = w;
    st->h = h;
}

/* A tile: tone-mapped copy (clip, gamma 1/2.2); non-finite = magenta; NULL
 * data = the method refused the frame (dark grey). */
static void strip_add(strip *st, const char *label, const float *rgb, double psnr) {
    if (!st->on || st->n >= 40) return;
    size_t n = (size_t)st->w * st->h * 3;
    float *t = malloc(n * sizeof(float));
    if (!t) return;
    for (size_t i = 0; i < n; i += 3)
        for (int c = 0; c < 3; c++) {
            float v = rgb ? rgb[i + c] : 0.1f;
            if (rgb && !(isfinite(rgb[i]) && isfinite(rgb[i + 1]) && isfinite(rgb[i + 2])))
                v = c == 1 ? 0.0f : 1.0f;
            else if (rgb)
                v = v > 0.0f ? (v < 1.0f ? powf(v, 1.0f / 2.2f) : 1.0f) : 0.0f;
            t[i + c] = v;
        }
    st->tiles[st->n++] = t;
    size_t len = strlen(st->text);
    if (isnan(psnr))
        snprintf(st->text + len, sizeof st->text - len, "%d %s%s\n", st->n, label, rgb ? "" : " (refused)");
    else
        snprintf(st->text + len, sizeof st->text - len, "%d %s %.2f dB\n", st->n, label, psnr);
}

/* Writes DIR/<name>.png: the tiles side by side, each scaled up (nearest)
 * to about 128 pixels high (64x64 renders: 2x; tiny frames: more), 2-pixel white gaps. */
static void strip_end(strip *st, const char *name) {
    if (st->on && st->n) {
        int s = 1;
        while (st->h * (s + 1) <= 128 && st->w * (s + 1) <= 256) s++;
        int tw = st->w * s, th = st->h * s, gap = 2, W = st->n * (tw + gap) - gap;
        float *img = malloc(sizeof(float) * (size_t)W * th * 3);
        char err[512], path[4096];
        ewio_file *f = NULL;
        if (img && ewio_create(W, th, &f, err, sizeof err) == 0) {
            for (int y = 0; y < th; y++)
                for (int x = 0; x < W; x++) {
                    int k = x / (tw + gap), xi = x % (tw + gap);
                    float *o = img + ((size_t)y * W + x) * 3;
                    if (xi >= tw) { o[0] = o[1] = o[2] = 1.0f; continue; }
                    const float *p = st->tiles[k] + ((size_t)(y / s) * st->w + xi / s) * 3;
                    o[0] = p[0], o[1] = p[1], o[2] = p[2];
                }
            const char *dir = getenv("EW_STABILITY_STRIPS");
            snprintf(path, sizeof path, "%s/%s.png", dir, name);
            if (ewio_set_pass(f, "", "", "RGB", img, err, sizeof err) != 0 ||
                ewio_write(f, path, EWIO_KEEP, "", "", err, sizeof err) != 0)
                fprintf(stderr, "  strip %s: %s\n", path, err);
            snprintf(path, sizeof path, "%s/%s.txt", dir, name);
            FILE *tf = fopen(path, "w");
            if (tf) {
                fputs(st->text, tf);
                fclose(tf);
            }
        }
        ewio_free(f);
        free(img);
    }
    for (int i = 0; i < st->n; i++) free(st->tiles[i]);
    st->n = 0;
}

/* ---- runner ------------------------------------------------------------- */

static double psnr_of(ew_device *dev, float *a, const float *ref, int w, int h) {
    if (!ref) return NAN;
    ew_image va = ew_image_packed(a, w, h, 3), vr = ew_image_packed((float *)ref, w, h, 3);
    double p = NAN;
    if (ew_image_psnr(dev, &va, &vr, &p) != EW_OK) return NAN;
    return p;
}

/* Runs every method on d; returns the number of failures (non-finite
 * output, or a refusal without a message). With a reference, prints every
 * method's PSNR and returns the input's and auto's in *p_in / *p_auto. */
static int run_all(const ew_layer_data *d, const char *what, const float *ref, double *p_in, double *p_auto) {
    collect();
    ew_device *dev;
    ew_device_create(NULL, &dev);
    int w = d->width, h = d->height;
    size_t n = (size_t)w * h;
    float *out = malloc(n * 3 * sizeof(float));
    int bad = 0;
    strip st;
    strip_begin(&st, w, h);
    double pin = psnr_of(dev, d->color, ref, w, h);
    if (p_in) *p_in = pin;
    if (p_auto) *p_auto = NAN;
    strip_add(&st, "input", d->color, pin);
    if (ref) fprintf(stderr, "  %s: input %.2f dB", what, pin);
    for (int m = 0; m < n_specs; m++) {
        char err[512] = "", chosen[160] = "";
        double ms;
        ew_method_spec sp = all_specs[m];
        sp.chosen = chosen; /* what auto picked, for the log */
        sp.chosen_len = sizeof chosen;
        if (ew_method_run(dev, &sp, d, out, &ms, err, sizeof err) != 0) {
            /* refusing cleanly is allowed (e.g. a filter too big for a 1x1 frame) */
            if (!err[0]) { fprintf(stderr, "  %s on %s failed without a message\n", all_specs[m].label, what); bad++; }
            strip_add(&st, all_specs[m].label, NULL, NAN);
            if (ref) fprintf(stderr, ", %s refused", all_specs[m].label);
            continue;
        }
        size_t nonfinite = 0;
        for (size_t i = 0; i < n * 3; i++) nonfinite += !isfinite(out[i]);
        if (nonfinite) {
            fprintf(stderr, "  %s on %s: %zu non-finite output values\n", all_specs[m].label, what, nonfinite);
            bad++;
        }
        double p = psnr_of(dev, out, ref, w, h);
        if (ref && !strcmp(all_specs[m].name, "auto") && chosen[0])
            fprintf(stderr, ", %s [%s] %.2f", all_specs[m].label, chosen, p);
        else if (ref)
            fprintf(stderr, ", %s %.2f", all_specs[m].label, p);
        if (p_auto && !strcmp(all_specs[m].name, "auto")) *p_auto = p;
        strip_add(&st, all_specs[m].label, out, p);
    }
    if (ref) fprintf(stderr, "\n");
    if (ref) strip_add(&st, "reference", ref, NAN);
    strip_end(&st, what);
    free(out);
    ew_device_destroy(dev);
    return bad;
}

static int all_finite(const ew_layer_data *d, const char *what) { return run_all(d, what, NULL, NULL, NULL); }

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
    int bad = all_finite(&d, "nan_inf_negative");
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
    int bad = all_finite(&d, "zero_albedo_emitters");
    ew_layer_data_free(&d);
    CHECK_EQ_INT(bad, 0);
}

TEST(tiny_frames) {
    int sizes[][2] = {{1, 1}, {2, 3}, {3, 7}, {17, 1}};
    int bad = 0;
    for (int k = 0; k < 4; k++) {
        ew_layer_data d;
        char what[64];
        fill_layer(&d, sizes[k][0], sizes[k][1]);
        snprintf(what, sizeof what, "tiny_%dx%d", sizes[k][0], sizes[k][1]);
        bad += all_finite(&d, what);
        ew_layer_data_free(&d);
    }
    CHECK_EQ_INT(bad, 0);
}

/* ---- renders ------------------------------------------------------------ */

/* Reads <dir>/<scene>/f0001_spp<spp>.exr and the reference. 0 on success. */
static int read_render(const char *dir, const char *scene, int spp, const char *ref_name, ew_layer_data *d,
                       float **refc, char *err, size_t errlen) {
    char in[2048], ref[2048];
    snprintf(in, sizeof in, "%s/%s/f0001_spp%04d.exr", dir, scene, spp);
    snprintf(ref, sizeof ref, "%s/%s/%s", dir, scene, ref_name);
    ewio_file *f = NULL, *r = NULL;
    ew_layer_passes lp;
    int rc = 1;
    *refc = NULL;
    memset(d, 0, sizeof *d);
    if (ewio_read(in, &f, err, errlen) == 0 && ewio_read(ref, &r, err, errlen) == 0 &&
        ew_find_layer_passes(f, "ViewLayer", &lp, err, errlen) == 0 && ew_layer_data_read(f, &lp, d, err, errlen) == 0) {
        if (ewio_width(r) != d->width || ewio_height(r) != d->height) {
            snprintf(err, errlen, "%s: size differs from the input", ref_name);
        } else {
            *refc = malloc(sizeof(float) * (size_t)d->width * d->height * 3);
            if (*refc && ewio_get_pass(r, "ViewLayer", "Combined", "RGB", *refc, err, errlen) == 0) rc = 0;
        }
    }
    if (rc) {
        free(*refc);
        *refc = NULL;
        ew_layer_data_free(d);
    }
    ewio_free(f);
    ewio_free(r);
    return rc;
}

/* Real hard renders: auto must beat the input and stay above a floor
 * (floors are the measured values minus a margin; see BENCHMARKS.md). */
static void hard_scene(const char *scene, int spp, double floor_db, int must_beat_input) {
    const char *root = getenv("EW_SHARED_DATA");
    char err[512], what[256];
    ew_layer_data d;
    float *refc;
    if (!root || read_render(root, scene, spp, "f0001_ref1024.exr", &d, &refc, err, sizeof err) != 0)
        SKIP("shared dataset not found");
    double p_in, p_out;
    snprintf(what, sizeof what, "%s_spp%d", scene, spp);
    int bad = run_all(&d, what, refc, &p_in, &p_out);
    fprintf(stderr, "  %s %d spp: input %.2f dB -> auto %.2f dB (floor %.1f)\n", scene, spp, p_in, p_out, floor_db);
    ew_layer_data_free(&d);
    free(refc);
    CHECK_EQ_INT(bad, 0);
    if (must_beat_input) CHECK(p_out > p_in);
    CHECK(p_out >= floor_db);
}

/* Floors: the measured auto PSNR (BENCHMARKS.md) minus about 1.5 dB. */
TEST(glass_caustics) { hard_scene("c_glass_120_256x256", 4, 34.2, 1); }
TEST(fireflies) { hard_scene("d_firefly_115_256x256", 4, 28.2, 1); }
/* The weakest gain: on a defocused frame the feature passes are themselves
 * blurred and a feature-driven guide cannot separate the bokeh. auto (nbg)
 * gains 0.4 dB at 4 spp (27.93 -> 28.30; bgrid loses 0.8 dB) and 1.4 dB at
 * 1 spp (21.47 -> 22.90). BENCHMARKS.md lists it. */
TEST(depth_of_field) { hard_scene("e_dof_116_256x256", 4, 27.5, 1); }
TEST(depth_of_field_1spp) { hard_scene("e_dof_116_256x256", 1, 22.2, 1); }
TEST(motion_blur) { hard_scene("f_motionblur_117_256x256", 4, 36.9, 1); }

/* The committed stability renders (tests/data/stability, 64x64, 1 and 4 spp,
 * 1024-spp reference; see tools/blender/README.md). They are part of the
 * repository, so a missing file is a failure, not a skip. Every method must
 * give finite output; auto must beat the input and its floor (measured
 * value minus about 1 dB; BENCHMARKS.md "Where methods fail"). With
 * `inject`, NaN, +-Inf and negative samples are written into the render
 * first: outputs must stay finite and auto must lose at most 0.3 dB
 * (measured: < 0.05 dB. Before negative radiance counted as black in the
 * denoisers' demodulation, nbg spread the -3 samples into dark blotches and
 * lost 0.2-1.0 dB here.) */
static void stability_scene(const char *scene, int spp, double floor_db, int inject) {
    const char *root = getenv("EW_STABILITY_DATA");
    if (!root || !root[0]) root = EW_STABILITY_DATA_DIR;
    char err[512], what[256];
    ew_layer_data d;
    float *refc;
    if (read_render(root, scene, spp, "f0001_ref1024.exr", &d, &refc, err, sizeof err) != 0) {
        FAIL_AT("%s/%s: %s", root, scene, err);
        return;
    }
    double p_in, p_out;
    snprintf(what, sizeof what, "%s_spp%d", scene, spp);
    int bad = run_all(&d, what, refc, &p_in, &p_out);
    fprintf(stderr, "  %s %d spp: input %.2f dB -> auto %.2f dB (floor %.1f)\n", scene, spp, p_in, p_out, floor_db);
    double p_bad = p_out;
    if (inject) {
        int w = d.width, n = d.width * d.height;
        /* scattered damaged samples: about one pixel in 200 */
        for (int i = 7; i < n; i += 211) {
            int k = (i / 211) % 4;
            d.color[i * 3 + k % 3] = k == 0 ? NAN : k == 1 ? INFINITY : k == 2 ? -INFINITY : -3.0f;
        }
        d.color[(w + 1) * 3] = 6.5e4f;
        snprintf(what, sizeof what, "%s_spp%d_nan_inf", scene, spp);
        double p_in_bad;
        bad += run_all(&d, what, refc, &p_in_bad, &p_bad);
        fprintf(stderr, "  %s %d spp with NaN/Inf/negative samples: auto %.2f dB\n", scene, spp, p_bad);
    }
    ew_layer_data_free(&d);
    free(refc);
    CHECK_EQ_INT(bad, 0);
    CHECK(p_out > p_in);
    CHECK(p_out >= floor_db);
    /* The damaged samples (one pixel in 200) may add at most 5 % of the noisy
     * input's squared error to the output's. In dB the same damage costs more
     * the cleaner the output is: k_thin at 4 spp lost 0.22 dB at 28.95 and
     * 0.37 dB at 30.99, both 3 % of the input's error. */
    if (inject) CHECK(pow(10.0, -p_bad / 10.0) - pow(10.0, -p_out / 10.0) <= 0.05 * pow(10.0, -p_in / 10.0));
}

/* Floors: measured auto PSNR minus about 1 dB (values in BENCHMARKS.md). */
TEST(volume_1spp) { stability_scene("i_volume_1_64x64", 1, 16.0, 0); }
TEST(volume_4spp) { stability_scene("i_volume_1_64x64", 4, 20.7, 1); }
TEST(texture_1spp) { stability_scene("j_texture_1_64x64", 1, 18.0, 0); }
TEST(texture_4spp) { stability_scene("j_texture_1_64x64", 4, 24.0, 1); }
TEST(thin_1spp) { stability_scene("k_thin_1_64x64", 1, 19.0, 0); }
TEST(thin_4spp) { stability_scene("k_thin_1_64x64", 4, 27.6, 1); }

/* ---- 8K ----------------------------------------------------------------- */

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A synthetic 7680x4320 frame (noise, two albedo halves, an emitter band,
 * NaN/Inf samples) through the cheapest methods: each must finish with
 * finite output. Measured: 11-23 s per grid method, 52 s for auto on 2
 * cores, peak RSS 4.8 GB (7.1 GB with auto), so it runs only with
 * EW_STABILITY_LARGE=1 (ctest -L large after configuring with
 * -DEW_LARGE_TESTS=ON). */
TEST(frame_8k) {
    if (!getenv("EW_STABILITY_LARGE")) SKIP("8K frame: set EW_STABILITY_LARGE=1 (CTest: -DEW_LARGE_TESTS=ON, ctest -L large)");
    const int w = 7680, h = 4320;
    ew_layer_data d;
    double t0 = now_s();
    fill_layer(&d, w, h);
    CHECK(d.color && d.albedo && d.normal && d.depth);
    for (int i = 0; i < w * 200; i++)
        for (int c = 0; c < 3; c++) d.color[i * 3 + c] = 1e4f, d.albedo[i * 3 + c] = 0.0f;
    d.color[3 * (size_t)(w * 1000 + 17)] = NAN;
    d.color[3 * (size_t)(w * 2000 + 4000) + 1] = INFINITY;
    d.color[3 * (size_t)(w * 4000 + 7000) + 2] = -INFINITY;
    d.samples = 4;
    fprintf(stderr, "  8K frame filled in %.1f s\n", now_s() - t0);
    const char *names[][2] = {{"denoiser", "bgrid"}, {"filter", "pyramid"}, {"denoiser", "auto"}};
    ew_device *dev;
    ew_device_create(NULL, &dev);
    size_t n = (size_t)w * h;
    float *out = malloc(n * 3 * sizeof(float));
    CHECK(out);
    int bad = 0;
    for (int m = 0; m < 3; m++) {
        ew_method_spec s;
        memset(&s, 0, sizeof s);
        s.label = names[m][1];
        s.kind = names[m][0];
        s.name = names[m][1];
        s.demodulate = !strcmp(s.kind, "filter");
        char err[512] = "";
        double ms = 0;
        t0 = now_s();
        int rc = ew_method_run(dev, &s, &d, out, &ms, err, sizeof err);
        size_t nonfinite = 0;
        for (size_t i = 0; rc == 0 && i < n * 3; i++) nonfinite += !isfinite(out[i]);
        struct rusage ru;
        getrusage(RUSAGE_SELF, &ru);
        fprintf(stderr, "  8K %s: %s, %.1f s (commit+execute %.1f s), %zu non-finite, max RSS so far %.2f GB\n",
                s.label, rc ? err : "ok", now_s() - t0, ms / 1e3, nonfinite, (double)ru.ru_maxrss / (1024.0 * 1024.0));
        bad += rc != 0 || nonfinite != 0;
    }
    free(out);
    ew_device_destroy(dev);
    ew_layer_data_free(&d);
    CHECK_EQ_INT(bad, 0);
}

/* ---- do no harm ----------------------------------------------------------
 * Every method that denoises (the denoisers, and the filters used as
 * denoisers: demodulated, with the stage method_run gives them) on the
 * committed renders of tests/data/stability:
 *   - d_firefly_1_64x64 (a tiny, very bright light, sample clamping off) at
 *     1, 4, 16 and 64 spp: the frame's mean luminance within 0.85-1.10 of
 *     the reference's, and no output pixel above 10x the reference's
 *     largest luminance in the 11x11 window around it (an isolated extreme
 *     sample must not survive, spread or not);
 *   - b_glossy_1 and f_motionblur_1 at 16 and 64 spp (reflections and blur
 *     that the albedo does not explain): output >= input - 0.2 dB at 64 spp
 *     and >= input at 16 spp.
 * Each case also runs with the stage off (do_no_harm 0, outlier_k 0: the
 * methods as they were) and prints both, with "target missed" where the
 * issue's targets above are not met (BENCHMARKS.md lists them). Checked:
 * the stage never makes a method worse — output - input at least the
 * stage-off figure - 0.1 dB; on the firefly render no peak above the
 * input's own nor above 10x the reference's local maximum (15x at 4 spp,
 * below), and at 64 spp the mean within 0.85-1.10; and at 16 spp every
 * method at least as good as its input. The filters used as denoisers came
 * out at 26x at 4 spp and 16x at 64 spp before the stage gave them the
 * denoisers' firefly clamp (now <= 5.2x at 1, 16 and 64 spp); at 4 spp two
 * adjacent bright samples, each inside the other's mean + 3 sigma, still
 * come out at 14.1-14.4x through pyramid, bilateral and separable (atrous
 * 8.1x, the denoisers <= 7.1x): printed as "target missed". */

static int is_denoising(const ew_method_spec *s) {
    return s->kind && (!strcmp(s->kind, "denoiser") || (strcmp(s->name, "dof") && strcmp(s->name, "outlier")));
}

/* One committed render at one sample count, every denoising method with
 * and without the stage. firefly: check the peaks against `margin` (x the
 * reference's local maximum) and the energy; else check output - input
 * against `margin` dB; must_meet: check the target (the energy, or the
 * margin) too. Returns the failures. */
static int harm_case_of(const char *scene, int spp, int firefly, double margin, int must_meet, const char *only) {
    collect();
    const char *root = getenv("EW_STABILITY_DATA");
    if (!root || !root[0]) root = EW_STABILITY_DATA_DIR;
    char err[512];
    ew_layer_data d;
    float *refc;
    /* the suite's own renders have 1024-spp references; a crop of a render
     * cache scene its 256-spp one */
    char ref[2048];
    snprintf(ref, sizeof ref, "%s/%s/f0001_ref1024.exr", root, scene);
    const char *ref_name = access(ref, R_OK) == 0 ? "f0001_ref1024.exr" : "f0001_ref0256.exr";
    if (read_render(root, scene, spp, ref_name, &d, &refc, err, sizeof err) != 0) {
        fprintf(stderr, "  %s/%s: %s\n", root, scene, err);
        return 1;
    }
    ew_device *dev;
    ew_device_create(NULL, &dev);
    const int w = d.width, h = d.height;
    const size_t n = (size_t)w * h;
    float *out = malloc(n * 3 * sizeof(float));
    const double p_in = psnr_of(dev, d.color, refc, w, h), l_ref = ew_frame_mean_lum(refc, n);
    int fails = 0;
    const double in_peak = ew_frame_peak_ratio(d.color, refc, w, h, 5);
    if (firefly)
        fprintf(stderr, "  %s %d spp: input lum %.3fx ref, peak %.1fx local max\n", scene, spp,
                ew_frame_mean_lum(d.color, n) / l_ref, ew_frame_peak_ratio(d.color, refc, w, h, 5));
    else
        fprintf(stderr, "  %s %d spp: input %.2f dB\n", scene, spp, p_in);
    for (int m = 0; out && m < n_specs; m++) {
        if (!is_denoising(&all_specs[m])) continue;
        double fig[2][2];
        for (int stage = 0; stage < 2; stage++) {
            ew_method_spec sp = all_specs[m];
            if (!stage) {
                sp.num_params = 2;
                sp.param_names[0] = "do_no_harm";
                sp.param_values[0] = 0.0f;
                sp.param_names[1] = "outlier_k";
                sp.param_values[1] = 0.0f;
            }
            double ms;
            fig[stage][0] = fig[stage][1] = NAN;
            if (ew_method_run(dev, &sp, &d, out, &ms, err, sizeof err) != 0) {
                fprintf(stderr, "    %s: %s\n", sp.label, err);
                continue;
            }
            if (firefly) {
                fig[stage][0] = ew_frame_mean_lum(out, n) / l_ref;
                fig[stage][1] = ew_frame_peak_ratio(out, refc, w, h, 5);
            } else {
                fig[stage][0] = psnr_of(dev, out, refc, w, h) - p_in;
            }
        }
        int ok, target;
        const int check = must_meet && (!only || strstr(only, all_specs[m].label));
        if (firefly) {
            const int energy = fig[1][0] >= 0.85 && fig[1][0] <= 1.10;
            target = energy && fig[1][1] <= 10.0;
            ok = fig[1][1] <= margin && fig[1][1] <= in_peak && (!check || energy);
            fprintf(stderr, "    %-10s lum %.3fx peak %7.2fx   (stage off: lum %.3fx peak %7.2fx)%s%s\n",
                    all_specs[m].label, fig[1][0], fig[1][1], fig[0][0], fig[0][1], target ? "" : "  target missed",
                    ok ? "" : "  FAIL");
        } else {
            target = fig[1][0] >= margin;
            ok = fig[1][0] >= fig[0][0] - 0.1 && (!check || target);
            fprintf(stderr, "    %-10s output - input %+6.2f dB   (stage off: %+6.2f dB)%s%s\n", all_specs[m].label,
                    fig[1][0], fig[0][0], target ? "" : "  target missed", ok ? "" : "  FAIL");
        }
        fails += !ok;
    }
    free(out);
    free(refc);
    ew_layer_data_free(&d);
    ew_device_destroy(dev);
    return fails;
}

static int harm_case(const char *scene, int spp, int firefly, double margin, int must_meet) {
    return harm_case_of(scene, spp, firefly, margin, must_meet, NULL);
}

TEST(firefly_energy_1spp) { CHECK_EQ_INT(harm_case("d_firefly_1_64x64", 1, 1, 10.0, 0), 0); }
TEST(firefly_energy_4spp) { CHECK_EQ_INT(harm_case("d_firefly_1_64x64", 4, 1, 15.0, 0), 0); }
TEST(firefly_energy_16spp) { CHECK_EQ_INT(harm_case("d_firefly_1_64x64", 16, 1, 10.0, 0), 0); }
/* 64 spp: the mean within 0.85-1.10 checked (the clamps' light given back;
 * 0.75-0.84 before). kpcn-large (auto here) was near the line at 0.852
 * while the rejection's light went back over a 49x49 window; with it given
 * to the whole frame, 0.904 (every method 0.90-0.94). Its network alone,
 * without the clamps and the stage, keeps 0.90 of the reference's light
 * against the input's 1.01: the fireflies' excess on the caustic is
 * filtered away as noise, which the clamps' return does not cover. */
TEST(firefly_energy_64spp) { CHECK_EQ_INT(harm_case("d_firefly_1_64x64", 64, 1, 10.0, 1), 0); }
/* 16 spp: every method at least as good as its input; 64 spp: within 0.2
 * dB of it (checked; before the blend's quiet-frame estimate bgrid and nbg
 * were at -0.82 dB on f_motionblur_1, now -0.04 and +0.07) */
TEST(glossy_no_harm_16spp) { CHECK_EQ_INT(harm_case("b_glossy_1_64x64", 16, 0, 0.0, 1), 0); }
TEST(glossy_no_harm_64spp) { CHECK_EQ_INT(harm_case("b_glossy_1_64x64", 64, 0, -0.2, 1), 0); }
TEST(motionblur_no_harm_16spp) { CHECK_EQ_INT(harm_case("f_motionblur_1_64x64", 16, 0, 0.0, 1), 0); }
TEST(motionblur_no_harm_64spp) { CHECK_EQ_INT(harm_case("f_motionblur_1_64x64", 64, 0, -0.2, 1), 0); }
/* The 64x64 region of a render cache training frame (b_glossy_150001, a
 * reflection of texture on a glossy floor) where bgrid fell furthest below
 * its input. The target is checked for the methods the stage's pilot
 * serves (denoisers with albedo, normal and depth, other than kpcn;
 * src/harm_stage.c): before it bgrid -0.80 / -3.74 dB and nbg -0.47 /
 * -1.89 dB at 16 / 64 spp, with it +0.05 / -0.16 and +0.13 / -0.18 dB.
 * The others miss it here and print "target missed": auto (kpcn-large)
 * -0.21 / -0.72, kpcn -0.03 / +0.11, the filters (run demodulated, no
 * features, so no pilot) -0.8 to -1.1 / -2.5 to -3.5 dB. */
TEST(glossy_floor_no_harm_16spp) { CHECK_EQ_INT(harm_case_of("b_glossy_150001_64x64", 16, 0, 0.0, 1, "bgrid nbg"), 0); }
TEST(glossy_floor_no_harm_64spp) { CHECK_EQ_INT(harm_case_of("b_glossy_150001_64x64", 64, 0, -0.2, 1, "bgrid nbg"), 0); }
/* A 64x64 region of a render cache training frame lit by an HDRI
 * (h_hdri_150263). At 64 spp its noise level, 0.0109, is at the edge of a
 * quiet frame's: with the pilot's share from quietness (0.011 -> 0.007)
 * bgrid was -6.93 dB and nbg -0.35 below the input; with the share from
 * 0.016 and the pilot's own stage (src/harm_stage.c) +0.33 and +0.49. At
 * 16 spp (noise 0.0176, no pilot) bgrid stays -1.85 dB below its input,
 * printed: a ramp from 0.025 reached it (+0.82) but ran the pilot on most
 * 4-spp frames. */
TEST(hdri_no_harm_16spp) { CHECK_EQ_INT(harm_case_of("h_hdri_150263_64x64", 16, 0, 0.0, 1, "nbg"), 0); }
TEST(hdri_no_harm_64spp) { CHECK_EQ_INT(harm_case_of("h_hdri_150263_64x64", 64, 0, -0.2, 1, "bgrid nbg"), 0); }

/* 1 spp: the stage never makes a method worse (the check above) on noise
 * whose windows are a few bright samples. Before the blend faded with the
 * frame's noise level it put noise back there: auto (kpcn-large) came out
 * 2.8 dB below the stage-off figure on this volume (+9.38 against +12.16
 * dB over the input). */
TEST(volume_no_harm_1spp) { CHECK_EQ_INT(harm_case("i_volume_1_64x64", 1, 0, 0.0, 0), 0); }
