/* The CLI's layer data holds as halves the features the file stores as
 * halves (and gives back itself when written) when the method's run reads
 * halves where they are (ew_op_image_flags after commit): kpcn in streamed
 * tiles, auto when it runs kpcn so. The same output as from the floats;
 * a method that would pack them into floats leaves the layer's floats. */
#include "ew_test.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "edgewise/edgewise.h"
#include "ewio.h"
#include "method_run.h"

#define W 600
#define H 560

static uint32_t rng = 99u;
static float frand(float lo, float hi) {
    rng = rng * 1664525u + 1013904223u;
    return lo + (hi - lo) * (float)(rng >> 8) / 16777216.0f;
}

/* A Cycles-like layer whose every pass ewio stores as half (new channels
 * under EWIO_KEEP), written to path. */
static int write_frame(const char *path) {
    char err[512];
    ewio_file *f = NULL;
    if (ewio_create(W, H, &f, err, sizeof err) != 0) return 0;
    const size_t n = (size_t)W * H;
    float *c = malloc(n * 3 * sizeof(float)), *a = malloc(n * 3 * sizeof(float)), *nm = malloc(n * 3 * sizeof(float));
    float *z = malloc(n * sizeof(float));
    for (size_t i = 0; i < n; i++) {
        const int x = (int)(i % W), y = (int)(i / W);
        const float base = (x / 40 + y / 40) % 2 ? 0.7f : 0.2f;
        for (int k = 0; k < 3; k++) {
            a[i * 3 + k] = base + 0.1f * (float)k;
            c[i * 3 + k] = a[i * 3 + k] * frand(0.2f, 1.8f) + (i % 997 == 0 ? 30.0f : 0.0f);
            nm[i * 3 + k] = k == 2 ? 1.0f : 0.0f;
        }
        z[i] = 3.0f + 0.01f * (float)y;
    }
    int ok = ewio_set_pass(f, "ViewLayer", "Combined", "RGB", c, err, sizeof err) == 0 &&
             ewio_set_pass(f, "ViewLayer", "Denoising Albedo", "RGB", a, err, sizeof err) == 0 &&
             ewio_set_pass(f, "ViewLayer", "Denoising Normal", "XYZ", nm, err, sizeof err) == 0 &&
             ewio_set_pass(f, "ViewLayer", "Denoising Depth", "Z", z, err, sizeof err) == 0 &&
             ewio_write(f, path, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0;
    if (!ok) fprintf(stderr, "  writing %s: %s\n", path, err);
    free(c);
    free(a);
    free(nm);
    free(z);
    ewio_free(f);
    return ok;
}

static int read_layer(ewio_file **f, const char *path, ew_layer_passes *lp, ew_layer_data *d) {
    char err[512];
    return ewio_open(path, f, err, sizeof err) == 0 && ew_find_layer_passes(*f, "ViewLayer", lp, err, sizeof err) == 0 &&
           ew_layer_data_read(*f, lp, d, err, sizeof err) == 0;
}

/* method (kpcn: the small model, 1 MiB of budget: streamed tiles) on d;
 * holds: let it hold halves */
static int run(ew_device *dev, const char *method, ew_layer_data *d, unsigned allowed, int holds, float *out) {
    ew_method_spec spec;
    memset(&spec, 0, sizeof spec);
    spec.label = method;
    spec.kind = "denoiser";
    spec.name = method;
    if (!strcmp(method, "kpcn")) {
        spec.num_params = 2;
        spec.param_names[0] = "model";
        spec.param_values[0] = 1.0f;
        spec.param_names[1] = "max_memory_mb";
        spec.param_values[1] = 1.0f;
    }
    if (holds) {
        spec.holds = d;
        spec.halves_allowed = allowed;
    }
    char err[512];
    double ms;
    const int bad = ew_method_run(dev, &spec, d, out, &ms, err, sizeof err);
    if (bad) fprintf(stderr, "  %s: %s\n", method, err);
    return !bad;
}

TEST(stored_halves_held_as_halves_where_the_run_reads_them) {
    char path[] = "/tmp/ew_layer_halves_XXXXXX.exr";
    const int fd = mkstemps(path, 4);
    CHECK(fd >= 0);
    close(fd);
    CHECK(write_frame(path));
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    const size_t n = (size_t)W * H;
    /* kpcn in streamed tiles reads them; nbg packs floats */
    static const char *const methods[2] = {"kpcn", "nbg"};
    for (int m = 0; m < 2; m++) {
        ewio_file *f = NULL, *g = NULL;
        ew_layer_passes lp, lq;
        ew_layer_data fl, hl;
        CHECK(read_layer(&f, path, &lp, &fl) && read_layer(&g, path, &lq, &hl));
        const unsigned all = EW_LAYER_HALF_ALBEDO | EW_LAYER_HALF_NORMAL | EW_LAYER_HALF_DEPTH;
        CHECK_EQ_INT((int)ew_layer_halves_allowed(g, &lq), (int)all);
        float *albedo = malloc(n * 3 * sizeof(float));
        memcpy(albedo, fl.albedo, n * 3 * sizeof(float));
        float *a = malloc(n * 3 * sizeof(float)), *b = malloc(n * 3 * sizeof(float));
        CHECK(a && b && run(dev, methods[m], &fl, all, 0, a) && run(dev, methods[m], &hl, all, 1, b));
        CHECK_EQ_INT((int)fl.halves, 0);
        CHECK_EQ_INT((int)hl.halves, m == 0 ? (int)all : 0);
        if (hl.halves) { /* the values the floats held */
            const uint16_t *h = (const uint16_t *)(const void *)hl.albedo;
            size_t differ = 0;
            for (size_t i = 0; i < n * 3; i++) {
                _Float16 v;
                memcpy(&v, &h[i], sizeof v);
                const float back = (float)v;
                differ += memcmp(&back, &albedo[i], sizeof back) != 0;
            }
            CHECK(differ == 0);
        }
        size_t differ = 0;
        for (size_t i = 0; i < n * 3; i++) differ += memcmp(&a[i], &b[i], sizeof(float)) != 0;
        if (differ) fprintf(stderr, "  %s: %zu values differ\n", methods[m], differ);
        CHECK(differ == 0);
        free(albedo);
        free(a);
        free(b);
        ew_layer_data_free(&fl);
        ew_layer_data_free(&hl);
        ewio_free(f);
        ewio_free(g);
    }
    ew_device_destroy(dev);
    unlink(path);
}

/* Blender stores the denoising albedo as half, normal and depth as float */
TEST(only_what_the_file_stores_as_halves) {
    const char *d = getenv("EW_SAMPLE_DIR");
    if (!d) SKIP("$EW_SAMPLE_DIR not set");
    char path[4096], err[512];
    snprintf(path, sizeof path, "%s/cornell/f0001_spp0004.exr", d);
    ewio_file *f = NULL;
    ew_layer_passes lp;
    CHECK(ewio_open(path, &f, err, sizeof err) == 0);
    CHECK(ew_find_layer_passes(f, "ViewLayer", &lp, err, sizeof err) == 0);
    CHECK_EQ_INT((int)ew_layer_halves_allowed(f, &lp), (int)EW_LAYER_HALF_ALBEDO);
    ewio_free(f);
}
