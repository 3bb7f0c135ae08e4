/* Writes the small EXR files the CLI tests feed to `edgewise`:
 *   make_fixtures DIR
 * and checks premultiplied colour in one:
 *   make_fixtures --premultiplied FILE LAYER PASS
 * prints "over N soft M nonfinite K": N colour samples above their alpha,
 * M pixels with alpha strictly between 0 and 1, K non-finite samples; and
 * compares two RGBA passes value by value:
 *   make_fixtures --same FILE1 LAYER1 PASS1 FILE2 LAYER2 PASS2
 * prints "same" or "differ N" (N samples whose bits differ). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ewio.h"

#define W 64
#define H 48

static float buf[W * H * 4];

static void fill(int c, float base, float noise, unsigned seed) {
    for (int i = 0; i < W * H; i++)
        for (int k = 0; k < c; k++) {
            seed = seed * 1664525u + 1013904223u;
            buf[i * c + k] = base * ((i % W) < W / 2 ? 1.0f : 0.3f) + noise * ((float)(seed >> 8) / 16777216.0f - 0.5f);
        }
}

static int put(ewio_file *f, const char *layer, const char *pass, const char *comps) {
    char err[512];
    if (ewio_set_pass(f, layer, pass, comps, buf, err, sizeof err) != 0) {
        fprintf(stderr, "make_fixtures: %s\n", err);
        return 1;
    }
    return 0;
}

static int cycles_layer(ewio_file *f, const char *layer, int features) {
    int rc = 0;
    fill(4, 0.5f, 0.4f, 1);
    for (int i = 0; i < W * H; i++) buf[i * 4 + 3] = 1.0f;
    rc |= put(f, layer, "Combined", "RGBA");
    if (!features) return rc;
    fill(3, 0.8f, 0.0f, 2);
    rc |= put(f, layer, "Denoising Albedo", "RGB");
    fill(3, 0.0f, 0.0f, 3);
    for (int i = 0; i < W * H; i++) buf[i * 3 + 2] = 1.0f;
    rc |= put(f, layer, "Denoising Normal", "XYZ");
    fill(1, 5.0f, 0.0f, 4);
    rc |= put(f, layer, "Denoising Depth", "Z");
    return rc;
}

static int save(ewio_file *f, const char *dir, const char *name) {
    char path[4096], err[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    int rc = ewio_write(f, path, EWIO_KEEP, NULL, NULL, err, sizeof err);
    if (rc) fprintf(stderr, "make_fixtures: %s: %s\n", path, err);
    ewio_free(f);
    return rc;
}

/* A checker of opaque and transparent 8-pixel cells, colour premultiplied
 * (<= alpha), and a depth ramp for depth of field. */
static int alpha_checker(ewio_file *f) {
    int rc = 0;
    fill(4, 0.6f, 0.3f, 6);
    for (int i = 0; i < W * H; i++) {
        const int x = i % W, y = i / W;
        const float a = ((x / 8 + y / 8) & 1) ? 1.0f : 0.0f;
        for (int k = 0; k < 3; k++) buf[i * 4 + k] = a * fminf(fmaxf(buf[i * 4 + k], 0.05f), 1.0f);
        buf[i * 4 + 3] = a;
    }
    rc |= put(f, "ViewLayer", "Combined", "RGBA");
    for (int i = 0; i < W * H; i++) buf[i] = 0.5f + 10.0f * (float)(i % W) / W;
    rc |= put(f, "ViewLayer", "Depth", "Z");
    return rc;
}

static int check_premultiplied(const char *path, const char *layer, const char *pass) {
    char err[512];
    ewio_file *f = NULL;
    if (ewio_read(path, &f, err, sizeof err) != 0) {
        fprintf(stderr, "make_fixtures: %s\n", err);
        return 1;
    }
    const size_t n = (size_t)ewio_width(f) * (size_t)ewio_height(f);
    float *p = (float *)malloc(n * 4 * sizeof(float));
    if (!p || ewio_get_pass(f, layer, pass, "RGBA", p, err, sizeof err) != 0) {
        fprintf(stderr, "make_fixtures: %s\n", p ? err : "out of memory");
        free(p);
        ewio_free(f);
        return 1;
    }
    long over = 0, soft = 0, nonfinite = 0;
    for (size_t i = 0; i < n; i++) {
        const float *q = p + i * 4;
        for (int k = 0; k < 4; k++) nonfinite += !isfinite(q[k]);
        for (int k = 0; k < 3; k++) over += q[k] > q[3] + 1e-5f;
        soft += q[3] > 0.01f && q[3] < 0.99f;
    }
    printf("over %ld soft %ld nonfinite %ld\n", over, soft, nonfinite);
    free(p);
    ewio_free(f);
    return 0;
}

static float *read_rgba(const char *path, const char *layer, const char *pass, size_t *n) {
    char err[512];
    ewio_file *f = NULL;
    if (ewio_read(path, &f, err, sizeof err) != 0) {
        fprintf(stderr, "make_fixtures: %s\n", err);
        return NULL;
    }
    *n = (size_t)ewio_width(f) * (size_t)ewio_height(f);
    float *p = (float *)malloc(*n * 4 * sizeof(float));
    if (!p || ewio_get_pass(f, layer, pass, "RGBA", p, err, sizeof err) != 0) {
        fprintf(stderr, "make_fixtures: %s\n", p ? err : "out of memory");
        free(p);
        p = NULL;
    }
    ewio_free(f);
    return p;
}

static int check_same(char **a) {
    size_t na = 0, nb = 0;
    float *p = read_rgba(a[0], a[1], a[2], &na), *q = read_rgba(a[3], a[4], a[5], &nb);
    int rc = 1;
    if (p && q && na == nb) {
        long differ = 0;
        for (size_t i = 0; i < 4 * na; i++) differ += memcmp(p + i, q + i, sizeof(float)) != 0;
        if (differ) printf("differ %ld\n", differ);
        else printf("same\n");
        rc = 0;
    } else if (p && q) {
        fprintf(stderr, "make_fixtures: the images differ in size\n");
    }
    free(p);
    free(q);
    return rc;
}

int main(int argc, char **argv) {
    if (argc == 5 && !strcmp(argv[1], "--premultiplied")) return check_premultiplied(argv[2], argv[3], argv[4]);
    if (argc == 8 && !strcmp(argv[1], "--same")) return check_same(argv + 2);
    if (argc != 2) { fprintf(stderr, "usage: make_fixtures DIR\n"); return 2; }
    const char *dir = argv[1];
    char err[512];
    ewio_file *f;
    int rc = 0;

    /* features present; NaN, +-Inf and negative colour samples */
    ewio_create(W, H, &f, err, sizeof err);
    rc |= cycles_layer(f, "ViewLayer", 1);
    fill(4, 0.5f, 0.4f, 1);
    for (int i = 0; i < W * H; i++) buf[i * 4 + 3] = 1.0f;
    buf[4 * 10] = NAN; buf[4 * 20 + 1] = INFINITY; buf[4 * 30 + 2] = -INFINITY; buf[4 * 40] = -2.0f;
    rc |= put(f, "ViewLayer", "Combined", "RGBA");
    ewio_set_attribute(f, "cycles.ViewLayer.samples", "4");
    rc |= save(f, dir, "bad_samples.exr");

    /* two view layers, one without features */
    ewio_create(W, H, &f, err, sizeof err);
    rc |= cycles_layer(f, "ViewLayer", 1);
    rc |= cycles_layer(f, "Back Plate", 0);
    rc |= save(f, dir, "two_layers.exr");

    /* colour only */
    ewio_create(W, H, &f, err, sizeof err);
    rc |= cycles_layer(f, "Main", 0);
    rc |= save(f, dir, "no_albedo.exr");

    /* no colour at all: only a depth pass */
    ewio_create(W, H, &f, err, sizeof err);
    fill(1, 3.0f, 0.0f, 5);
    rc |= put(f, "ViewLayer", "Depth", "Z");
    rc |= save(f, dir, "depth_only.exr");

    /* premultiplied RGBA with transparent cells, and depth */
    ewio_create(W, H, &f, err, sizeof err);
    rc |= alpha_checker(f);
    rc |= save(f, dir, "alpha_checker.exr");
    return rc ? 1 : 0;
}
