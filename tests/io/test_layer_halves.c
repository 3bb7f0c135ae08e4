/* The CLI's layer data holds as halves the features a method reads as
 * halves where they are and the file stores as halves (Blender's albedo),
 * the same values, and runs the method on those views with the output it
 * gives the floats. */
#include "ew_test.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"
#include "ewio.h"
#include "method_run.h"

static const char *sample_file(char *buf, size_t n) {
    const char *d = getenv("EW_SAMPLE_DIR");
    if (!d) return NULL;
    snprintf(buf, n, "%s/cornell/f0001_spp0004.exr", d);
    FILE *f = fopen(buf, "rb");
    if (f) fclose(f);
    return f ? buf : NULL;
}

static int read_layer(ewio_file **f, const char *path, ew_layer_passes *lp, ew_layer_data *d) {
    char err[512];
    return ewio_open(path, f, err, sizeof err) == 0 && ew_find_layer_passes(*f, "ViewLayer", lp, err, sizeof err) == 0 &&
           ew_layer_data_read(*f, lp, d, err, sizeof err) == 0;
}

static int run(ew_device *dev, const char *method, const ew_layer_data *d, float *out) {
    ew_method_spec spec;
    memset(&spec, 0, sizeof spec);
    spec.label = method;
    spec.kind = "denoiser";
    spec.name = method;
    char err[512];
    double ms;
    const int bad = ew_method_run(dev, &spec, d, out, &ms, err, sizeof err);
    if (bad) fprintf(stderr, "  %s: %s\n", method, err);
    return !bad;
}

TEST(stored_halves_held_as_halves_for_methods_that_read_them) {
    char buf[4096];
    const char *p = sample_file(buf, sizeof buf);
    if (!p) SKIP("$EW_SAMPLE_DIR/cornell/f0001_spp0004.exr not found");
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    static const char *const methods[3] = {"auto", "kpcn", "nbg"};
    for (int m = 0; m < 3; m++) {
        ewio_file *f = NULL, *g = NULL;
        ew_layer_passes lp, lq;
        ew_layer_data fl, hl;
        CHECK(read_layer(&f, p, &lp, &fl) && read_layer(&g, p, &lq, &hl));
        const size_t n = (size_t)fl.width * (size_t)fl.height;
        CHECK_EQ_INT(ew_layer_data_keep_halves(&hl, g, &lq, "denoiser", methods[m], EW_LAYER_HALF_ALBEDO | EW_LAYER_HALF_NORMAL | EW_LAYER_HALF_DEPTH), 0);
        /* nbg packs floats: the layer keeps them; normal and depth are float in the file */
        CHECK_EQ_INT((int)hl.halves, m < 2 ? (int)EW_LAYER_HALF_ALBEDO : 0);
        if (hl.halves) {
            const uint16_t *h = (const uint16_t *)(const void *)hl.albedo;
            size_t differ = 0;
            for (size_t i = 0; i < n * 3; i++) {
                _Float16 v;
                memcpy(&v, &h[i], sizeof v);
                const float back = (float)v;
                differ += memcmp(&back, &fl.albedo[i], sizeof back) != 0;
            }
            CHECK(differ == 0);
            /* not allowed: kept as floats */
            ew_layer_data again;
            ewio_file *e = NULL;
            ew_layer_passes le;
            CHECK(read_layer(&e, p, &le, &again));
            CHECK_EQ_INT(ew_layer_data_keep_halves(&again, e, &le, "denoiser", methods[m], EW_LAYER_HALF_NORMAL), 0);
            CHECK_EQ_INT((int)again.halves, 0);
            ew_layer_data_free(&again);
            ewio_free(e);
        }
        float *a = malloc(n * 3 * sizeof(float)), *b = malloc(n * 3 * sizeof(float));
        CHECK(a && b && run(dev, methods[m], &fl, a) && run(dev, methods[m], &hl, b));
        CHECK(memcmp(a, b, n * 3 * sizeof(float)) == 0);
        free(a);
        free(b);
        ew_layer_data_free(&fl);
        ew_layer_data_free(&hl);
        ewio_free(f);
        ewio_free(g);
    }
    ew_device_destroy(dev);
}
