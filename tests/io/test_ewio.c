/*
 * test_ewio.c — tests of the image-file layer (nodes/io/ewio.h).
 *
 * Every fixture is made at run time in a fresh mkdtemp() directory. Real
 * Cycles renders are used when present ($EW_SHARED_DATA, $EW_SAMPLE_DIR),
 * otherwise those tests skip.
 */
#define _XOPEN_SOURCE 700
#include "ew_test.h"
#include "ewio.h"
#include "exr_header_scan.h"

#include <dirent.h>
#include <fcntl.h>
#include <errno.h>
#include <signal.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

/* ------------------------------------------------------------- helpers */

static int make_tmpdir(char *buf, size_t n) {
    const char *t = getenv("TMPDIR");
    snprintf(buf, n, "%s/ewio-test-XXXXXX", (t && *t) ? t : "/tmp");
    return mkdtemp(buf) != NULL;
}

static void rm_tree(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char p[4096];
    while ((e = readdir(d)) != NULL) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        struct stat st;
        if (lstat(p, &st) == 0 && S_ISDIR(st.st_mode)) {
            chmod(p, 0700);
            rm_tree(p);
        } else {
            unlink(p);
        }
    }
    closedir(d);
    rmdir(dir);
}

/* Number of entries in dir; those whose name contains `sub` if sub != NULL. */
static int count_entries(const char *dir, const char *sub) {
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        if (!sub || strstr(e->d_name, sub)) n++;
    }
    closedir(d);
    return n;
}

static unsigned char *slurp(const char *path, long *len) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    unsigned char *b = malloc(n > 0 ? (size_t)n : 1);
    if (b && n > 0 && fread(b, 1, (size_t)n, fp) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(fp);
    *len = n;
    return b;
}

static int file_exists(const char *p) {
    struct stat st;
    return stat(p, &st) == 0;
}

static int has_channel(const ewio_file *f, const char *name) {
    for (int i = 0; i < ewio_num_channels(f); i++)
        if (!strcmp(ewio_channel_name(f, i), name)) return 1;
    return 0;
}

/* A deterministic pattern, different per (x, y, component, seed); not exact
 * in half precision (fractions of 1/10), some values above 1 and negative. */
static float pattern(int x, int y, int c, int seed) {
    return (float)((x * 7 + y * 13 + c * 29 + seed * 31) % 97) / 10.0f - 2.35f;
}

static float *pattern_buf(int w, int h, int nc, int seed) {
    float *b = malloc(sizeof(float) * (size_t)w * (size_t)h * (size_t)nc);
    if (!b) return NULL;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < nc; c++) b[((size_t)y * w + x) * nc + c] = pattern(x, y, c, seed);
    return b;
}

/* Sets pass (layer, pass, comps) to pattern(seed); returns 0 on success. */
static int set_pattern(ewio_file *f, const char *layer, const char *pass, const char *comps,
                       int seed) {
    int nc = (int)strlen(comps);
    float *b = pattern_buf(ewio_width(f), ewio_height(f), nc, seed);
    char err[512];
    int rc = b ? ewio_set_pass(f, layer, pass, comps, b, err, sizeof err) : 1;
    if (rc) fprintf(stderr, "  set_pattern: %s\n", err);
    free(b);
    return rc;
}

/* max |got - pattern| over the pass, or -1 if the pass can't be read. */
static double pattern_diff(const ewio_file *f, const char *layer, const char *pass,
                           const char *comps, int seed) {
    int w = ewio_width(f), h = ewio_height(f), nc = (int)strlen(comps);
    float *b = malloc(sizeof(float) * (size_t)w * (size_t)h * (size_t)nc);
    char err[512];
    if (!b || ewio_get_pass(f, layer, pass, comps, b, err, sizeof err)) {
        if (b) fprintf(stderr, "  pattern_diff: %s\n", err);
        free(b);
        return -1;
    }
    double m = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < nc; c++) {
                double d = fabs((double)b[((size_t)y * w + x) * nc + c] - pattern(x, y, c, seed));
                if (!(d <= m)) m = d; /* NaN propagates as a huge difference */
            }
    free(b);
    return m;
}

/* A Blender-like multilayer image. */
static ewio_file *make_blender_like(int w, int h, const char *layer) {
    ewio_file *f = NULL;
    char err[512];
    if (ewio_create(w, h, &f, err, sizeof err)) return NULL;
    if (set_pattern(f, layer, "Combined", "RGBA", 1) ||
        set_pattern(f, layer, "Denoising Albedo", "RGB", 2) ||
        set_pattern(f, layer, "Denoising Normal", "XYZ", 3) ||
        set_pattern(f, layer, "Denoising Depth", "Z", 4) ||
        set_pattern(f, layer, "Vector", "XYZW", 5)) {
        ewio_free(f);
        return NULL;
    }
    ewio_set_attribute(f, "cycles.ViewLayer.samples", "16");
    ewio_set_attribute(f, "Camera", "Cam");
    return f;
}

static int write_text(const char *path, const char *text) {
    FILE *fp = fopen(path, "w");
    if (!fp) return 1;
    fputs(text, fp);
    return fclose(fp) != 0;
}

static const char *shared_file(char *buf, size_t n) {
    const char *d = getenv("EW_SHARED_DATA");
    if (!d) return NULL;
    snprintf(buf, n, "%s/a_cornell_100_256x256/f0001_spp0004.exr", d);
    return file_exists(buf) ? buf : NULL;
}

static const char *sample_file(char *buf, size_t n) {
    const char *d = getenv("EW_SAMPLE_DIR");
    if (!d) return NULL;
    snprintf(buf, n, "%s/cornell/f0001_spp0004.exr", d);
    return file_exists(buf) ? buf : NULL;
}

/* ------------------------------------------------------ in-memory API */

TEST(create_limits) {
    ewio_file *f = (ewio_file *)1;
    char err[256];
    CHECK(ewio_create(0, 5, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "invalid image dimensions");
    CHECK(ewio_create(5, -3, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "invalid image dimensions");
    CHECK(ewio_create(65537, 1, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "too large");
    CHECK(ewio_create(20000, 20000, &f, err, sizeof err) != 0); /* > 2^28 pixels */
    CHECK_STR_CONTAINS(err, "too large");
    CHECK(ewio_create(4, 3, &f, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_width(f), 4);
    CHECK_EQ_INT(ewio_height(f), 3);
    CHECK_EQ_INT(ewio_num_channels(f), 0);
    CHECK_EQ_INT(ewio_num_layers(f), 0);
    CHECK(ewio_channel_name(f, 0) == NULL);
    CHECK_STR_CONTAINS(ewio_get_attribute(f, "nothing"), "");
    ewio_free(f);
    ewio_free(NULL);
}

TEST(set_pass_order_and_replace) {
    ewio_file *f = NULL;
    char err[512];
    CHECK(ewio_create(3, 2, &f, err, sizeof err) == 0);
    CHECK(set_pattern(f, "A", "Combined", "RGB", 1) == 0);
    CHECK(set_pattern(f, "B", "Combined", "RGB", 2) == 0);
    /* A new pass goes after its layer's last channel, not at the end. */
    CHECK(set_pattern(f, "A", "Denoised", "RGB", 3) == 0);
    CHECK_EQ_INT(ewio_num_channels(f), 9);
    CHECK(!strcmp(ewio_channel_name(f, 3), "A.Denoised.R"));
    CHECK(!strcmp(ewio_channel_name(f, 5), "A.Denoised.B"));
    CHECK(!strcmp(ewio_channel_name(f, 6), "B.Combined.R"));
    /* A missing component goes right after its pass. */
    CHECK(set_pattern(f, "A", "Combined", "A", 4) == 0);
    CHECK(!strcmp(ewio_channel_name(f, 3), "A.Combined.A"));
    /* Replacing in place keeps the count and position. */
    CHECK(set_pattern(f, "B", "Combined", "BGR", 5) == 0);
    CHECK_EQ_INT(ewio_num_channels(f), 10);
    CHECK(!strcmp(ewio_channel_name(f, 7), "B.Combined.R"));
    CHECK(pattern_diff(f, "B", "Combined", "BGR", 5) == 0.0);
    CHECK_EQ_INT(ewio_num_layers(f), 2);
    CHECK(!strcmp(ewio_layer_name(f, 0), "A"));
    CHECK(!strcmp(ewio_layer_name(f, 1), "B"));
    CHECK_EQ_INT(ewio_has_pass(f, "A", "Combined", "RGBA"), 1);
    CHECK_EQ_INT(ewio_has_pass(f, "B", "Combined", "RGBA"), 0);
    /* Names that would not read back as the same layer/pass are refused. */
    float px[3 * 2 * 3] = {0};
    CHECK(ewio_set_pass(f, "A", "", "RGB", px, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "pass name is required");
    CHECK(ewio_set_pass(f, "A", "Bad.Pass", "RGB", px, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "ambiguous");
    CHECK(ewio_set_pass(f, "A", "P", "RR", px, err, sizeof err) != 0);
    CHECK_EQ_INT(ewio_num_channels(f), 10);
    ewio_free(f);
}

/* A released pass is refused until it is set again; setting it brings its
 * channels back where they were, and the rest of the file is untouched. */
TEST(release_pass_then_set) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(9, 5, "ViewLayer");
    CHECK(f != NULL);
    const int nch = ewio_num_channels(f);
    CHECK(ewio_release_pass(f, "ViewLayer", "No Such Pass", "RGB") != 0);
    CHECK(ewio_release_pass(f, "ViewLayer", "Combined", "RGBW") != 0); /* no W: nothing freed */
    CHECK(pattern_diff(f, "ViewLayer", "Combined", "RGBA", 1) == 0.0);
    CHECK(ewio_release_pass(f, "ViewLayer", "Combined", "RGBA") == 0);
    CHECK_EQ_INT(ewio_num_channels(f), nch);
    CHECK_EQ_INT(ewio_has_pass(f, "ViewLayer", "Combined", "RGBA"), 1);
    float px[9 * 5 * 4];
    CHECK(ewio_get_pass(f, "ViewLayer", "Combined", "RGB", px, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "released");
    snprintf(p, sizeof p, "%s/released.exr", dir);
    CHECK(ewio_write(f, p, EWIO_FLOAT, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "released");
    CHECK(!file_exists(p));
    CHECK(count_entries(dir, ".tmp-") == 0);
    /* other passes still read */
    CHECK(pattern_diff(f, "ViewLayer", "Vector", "XYZW", 5) == 0.0);
    CHECK(set_pattern(f, "ViewLayer", "Combined", "RGBA", 7) == 0);
    CHECK_EQ_INT(ewio_num_channels(f), nch);
    CHECK(!strcmp(ewio_channel_name(f, 0), "ViewLayer.Combined.R"));
    CHECK(ewio_write(f, p, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK(pattern_diff(g, "ViewLayer", "Combined", "RGBA", 7) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Denoising Albedo", "RGB", 2) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Vector", "XYZW", 5) == 0.0);
    ewio_free(g);
    ewio_free(f);
    rm_tree(dir);
}

/* --------------------------------------------------------- round trips */

TEST(roundtrip_multilayer_float_and_half) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(13, 7, "ViewLayer");
    CHECK(f != NULL);
    CHECK(ewio_set_attribute(f, "compression", "piz") == 0);
    CHECK(ewio_set_attribute(f, "Note", "multi word value") == 0);
    float nf[13 * 7];
    for (int i = 0; i < 13 * 7; i++) nf[i] = (float)i;
    nf[0] = NAN;
    nf[1] = INFINITY;
    nf[2] = -INFINITY;
    nf[3] = 1.0e6f; /* above the half range */
    CHECK(ewio_set_pass(f, "ViewLayer", "Depth", "Z", nf, err, sizeof err) == 0);

    /* float */
    snprintf(p, sizeof p, "%s/float.exr", dir);
    CHECK(ewio_write(f, p, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_width(g), 13);
    CHECK_EQ_INT(ewio_height(g), 7);
    CHECK_EQ_INT(ewio_num_channels(g), ewio_num_channels(f));
    for (int i = 0; i < ewio_num_channels(f); i++) CHECK(has_channel(g, ewio_channel_name(f, i)));
    CHECK(has_channel(g, "ViewLayer.Denoising Albedo.G"));
    CHECK_EQ_INT(ewio_num_layers(g), 1);
    CHECK(!strcmp(ewio_layer_name(g, 0), "ViewLayer"));
    CHECK(pattern_diff(g, "ViewLayer", "Combined", "RGBA", 1) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Denoising Albedo", "RGB", 2) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Denoising Normal", "XYZ", 3) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Denoising Depth", "Z", 4) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Vector", "XYZW", 5) == 0.0);
    CHECK(!strcmp(ewio_get_attribute(g, "cycles.ViewLayer.samples"), "16"));
    CHECK(!strcmp(ewio_get_attribute(g, "Camera"), "Cam"));
    CHECK(!strcmp(ewio_get_attribute(g, "Note"), "multi word value"));
    CHECK(!strcmp(ewio_get_attribute(g, "compression"), "piz"));
    float z[13 * 7];
    CHECK(ewio_get_pass(g, "ViewLayer", "Depth", "Z", z, err, sizeof err) == 0);
    CHECK(isnan(z[0])); /* non-finite values are kept as read */
    CHECK(isinf(z[1]) && z[1] > 0);
    CHECK(isinf(z[2]) && z[2] < 0);
    CHECK(z[3] == 1.0e6f);
    CHECK(z[50] == 50.0f);

    /* half: values quantised to half precision, compression still kept */
    snprintf(p, sizeof p, "%s/half.exr", dir);
    CHECK(ewio_write(g, p, EWIO_HALF, NULL, NULL, err, sizeof err) == 0);
    ewio_file *hf = NULL;
    CHECK(ewio_read(p, &hf, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(hf), ewio_num_channels(f));
    double d = pattern_diff(hf, "ViewLayer", "Combined", "RGBA", 1);
    CHECK(d > 0.0 && d < 4e-3); /* half: 11-bit mantissa, values up to ~7.3 */
    CHECK(!strcmp(ewio_get_attribute(hf, "compression"), "piz"));
    CHECK(!strcmp(ewio_get_attribute(hf, "cycles.ViewLayer.samples"), "16"));
    CHECK(ewio_get_pass(hf, "ViewLayer", "Depth", "Z", z, err, sizeof err) == 0);
    CHECK(isnan(z[0]));
    CHECK(isinf(z[3])); /* 1e6 overflows half */

    /* EWIO_KEEP: float channels stay float, the added one is half. */
    CHECK(set_pattern(g, "ViewLayer", "Denoised", "RGB", 6) == 0);
    snprintf(p, sizeof p, "%s/keep.exr", dir);
    CHECK(ewio_write(g, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_file *k = NULL;
    CHECK(ewio_read(p, &k, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(k), ewio_num_channels(f) + 3);
    CHECK(pattern_diff(k, "ViewLayer", "Combined", "RGBA", 1) == 0.0);
    d = pattern_diff(k, "ViewLayer", "Denoised", "RGB", 6);
    CHECK(d > 0.0 && d < 4e-3);
    CHECK(!strcmp(ewio_get_attribute(k, "compression"), "piz"));
    /* ...and a half file written with KEEP stays half (bit-identical values). */
    snprintf(p, sizeof p, "%s/keep_half.exr", dir);
    CHECK(ewio_write(hf, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_file *k2 = NULL;
    CHECK(ewio_read(p, &k2, err, sizeof err) == 0);
    CHECK(pattern_diff(k2, "ViewLayer", "Combined", "RGBA", 1) ==
          pattern_diff(hf, "ViewLayer", "Combined", "RGBA", 1));

    /* A created file defaults to zip. */
    snprintf(p, sizeof p, "%s/default.exr", dir);
    ewio_file *c = NULL;
    CHECK(ewio_create(2, 2, &c, err, sizeof err) == 0);
    CHECK(set_pattern(c, "", "", "RGB", 1) == 0);
    CHECK(ewio_write(c, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_file *c2 = NULL;
    CHECK(ewio_read(p, &c2, err, sizeof err) == 0);
    CHECK(!strcmp(ewio_get_attribute(c2, "compression"), "zip"));
    CHECK_EQ_INT(ewio_num_layers(c2), 1);
    CHECK(!strcmp(ewio_layer_name(c2, 0), ""));
    CHECK(ewio_has_pass(c2, "", "", "RGB"));
    CHECK(count_entries(dir, ".tmp-") == 0);
    ewio_free(c2);
    ewio_free(c);
    ewio_free(k2);
    ewio_free(k);
    ewio_free(hf);
    ewio_free(g);
    ewio_free(f);
    rm_tree(dir);
}

TEST(two_view_layers) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(8, 5, "ViewLayer");
    CHECK(f != NULL);
    /* Blender names a second view layer "ViewLayer.001"; names may have spaces. */
    CHECK(set_pattern(f, "ViewLayer.001", "Combined", "RGBA", 11) == 0);
    CHECK(set_pattern(f, "ViewLayer.001", "Denoising Albedo", "RGB", 12) == 0);
    CHECK(set_pattern(f, "My Layer", "Combined", "RGBA", 21) == 0);
    snprintf(p, sizeof p, "%s/two.exr", dir);
    CHECK(ewio_write(f, p, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_layers(g), 3);
    int seen = 0;
    for (int i = 0; i < 3; i++) {
        const char *l = ewio_layer_name(g, i);
        seen |= !strcmp(l, "ViewLayer") ? 1 : !strcmp(l, "ViewLayer.001") ? 2
              : !strcmp(l, "My Layer")  ? 4 : 0;
    }
    CHECK_EQ_INT(seen, 7);
    CHECK(has_channel(g, "ViewLayer.001.Combined.A"));
    CHECK(has_channel(g, "My Layer.Combined.R"));
    CHECK(pattern_diff(g, "ViewLayer", "Combined", "RGBA", 1) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer.001", "Combined", "RGBA", 11) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer.001", "Denoising Albedo", "RGB", 12) == 0.0);
    CHECK(pattern_diff(g, "My Layer", "Combined", "RGBA", 21) == 0.0);
    CHECK(!ewio_has_pass(g, "My Layer", "Denoising Albedo", "RGB"));
    /* PNG of one layer's pass */
    snprintf(p, sizeof p, "%s/second.png", dir);
    CHECK(ewio_write(g, p, EWIO_KEEP, "My Layer", "Combined", err, sizeof err) == 0);
    ewio_free(g);
    ewio_free(f);
    rm_tree(dir);
}

TEST(png_and_tiff_colour_only) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    const int w = 9, h = 4;
    ewio_file *f = NULL;
    CHECK(ewio_create(w, h, &f, err, sizeof err) == 0);
    float rgb[9 * 4 * 3];
    for (int i = 0; i < w * h * 3; i++) rgb[i] = (float)(i * 7 % 256) / 255.0f;
    rgb[0] = 3.0f;   /* clamped to 1 in 8-bit */
    rgb[1] = -1.0f;  /* clamped to 0 */
    rgb[2] = NAN;    /* written as 0 */
    CHECK(ewio_set_pass(f, "", "", "RGB", rgb, err, sizeof err) == 0);

    /* 8-bit PNG */
    snprintf(p, sizeof p, "%s/c.png", dir);
    CHECK(ewio_write(f, p, EWIO_KEEP, "", "", err, sizeof err) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(g), 3);
    CHECK(!strcmp(ewio_channel_name(g, 0), "R"));
    CHECK(!strcmp(ewio_channel_name(g, 2), "B"));
    CHECK_EQ_INT(ewio_num_layers(g), 1);
    CHECK(!strcmp(ewio_layer_name(g, 0), ""));
    float back[9 * 4 * 3];
    CHECK(ewio_get_pass(g, "", "", "RGB", back, err, sizeof err) == 0);
    CHECK_NEAR(back[0], 1.0, 1e-6);
    CHECK_NEAR(back[1], 0.0, 1e-6);
    CHECK_NEAR(back[2], 0.0, 1e-6);
    for (int i = 3; i < w * h * 3; i++) CHECK_NEAR(back[i], rgb[i], 0.5 / 255 + 1e-6);
    CHECK(!ewio_has_pass(g, "", "", "RGBA"));

    /* PNG with alpha */
    float a[9 * 4];
    for (int i = 0; i < w * h; i++) a[i] = 1.0f;
    CHECK(ewio_set_pass(f, "", "", "A", a, err, sizeof err) == 0);
    snprintf(p, sizeof p, "%s/ca.png", dir);
    CHECK(ewio_write(f, p, EWIO_KEEP, "", "", err, sizeof err) == 0);
    ewio_file *ga = NULL;
    CHECK(ewio_read(p, &ga, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(ga), 4);
    CHECK(ewio_has_pass(ga, "", "", "RGBA"));

    /* Float TIFF: exact; 8-bit TIFF from the 8-bit PNG (KEEP keeps uint8). */
    snprintf(p, sizeof p, "%s/c.tif", dir);
    CHECK(ewio_write(f, p, EWIO_FLOAT, "", "", err, sizeof err) == 0);
    ewio_file *t = NULL;
    CHECK(ewio_read(p, &t, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(t), 4);
    CHECK_EQ_INT(ewio_num_layers(t), 1);
    CHECK(ewio_get_pass(t, "", "", "RGB", back, err, sizeof err) == 0);
    CHECK(back[0] == 3.0f && back[1] == -1.0f && isnan(back[2]));
    for (int i = 3; i < w * h * 3; i++) CHECK(back[i] == rgb[i]);
    snprintf(p, sizeof p, "%s/c8.tiff", dir);
    CHECK(ewio_write(g, p, EWIO_KEEP, "", "", err, sizeof err) == 0);
    ewio_file *t8 = NULL;
    CHECK(ewio_read(p, &t8, err, sizeof err) == 0);
    float back8[9 * 4 * 3];
    CHECK(ewio_get_pass(t8, "", "", "RGB", back8, err, sizeof err) == 0);
    CHECK(ewio_get_pass(g, "", "", "RGB", back, err, sizeof err) == 0);
    for (int i = 0; i < w * h * 3; i++) CHECK(back8[i] == back[i]);

    /* An 8-bit file written as EXR with KEEP becomes half, metadata-less is fine. */
    snprintf(p, sizeof p, "%s/from_png.exr", dir);
    CHECK(ewio_write(g, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_file *e = NULL;
    CHECK(ewio_read(p, &e, err, sizeof err) == 0);
    CHECK(!strcmp(ewio_get_attribute(e, "compression"), "zip"));
    CHECK_EQ_INT(ewio_num_channels(e), 3);

    /* A pass that is not there can't be written to PNG; no file appears. */
    snprintf(p, sizeof p, "%s/none.png", dir);
    CHECK(ewio_write(f, p, EWIO_KEEP, "ViewLayer", "Combined", err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "missing");
    CHECK_STR_CONTAINS(err, "layers found: ''");
    CHECK(!file_exists(p));
    /* Unknown extension */
    snprintf(p, sizeof p, "%s/c.xyz", dir);
    CHECK(ewio_write(f, p, EWIO_KEEP, "", "", err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "unsupported extension");
    CHECK(count_entries(dir, ".tmp-") == 0);
    ewio_free(e);
    ewio_free(t8);
    ewio_free(t);
    ewio_free(ga);
    ewio_free(g);
    ewio_free(f);
    rm_tree(dir);
}

/* Multi-part EXR: made with oiiotool (ewio itself writes single-part files). */
/* A make_blender_like file of w x h written as dir/src.exr (its path in
 * src): the source the ewio_open tests read. 0 on success. */
static int write_blender_source(const char *dir, int w, int h, char *src, size_t srclen) {
    char err[512];
    ewio_file *f = make_blender_like(w, h, "ViewLayer");
    if (!f) return 1;
    snprintf(src, srclen, "%s/src.exr", dir);
    const int rc = ewio_write(f, src, EWIO_KEEP, NULL, NULL, err, sizeof err);
    if (rc) fprintf(stderr, "  write_blender_source: %s\n", err);
    ewio_free(f);
    return rc;
}

/* 1 when g written to a and d written to b are the same bytes; 0 when they
 * differ or either write fails. */
static int written_alike(const ewio_file *g, const char *a, const ewio_file *d, const char *b) {
    char err[512];
    if (ewio_write(g, a, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0 ||
        ewio_write(d, b, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0) {
        fprintf(stderr, "  written_alike: %s\n", err);
        return 0;
    }
    long la = 0, lb = 0;
    unsigned char *ba = slurp(a, &la), *bb = slurp(b, &lb);
    const int same = ba && bb && la == lb && memcmp(ba, bb, (size_t)la) == 0;
    free(ba);
    free(bb);
    return same;
}

/* ewio_open leaves a scanline EXR's pixels in the file: each pass reads
 * as ewio_read reads it (decoded on demand, or loaded by
 * ewio_load_passes), a pass set from the source is the values read, and
 * the written file is the same bytes as from a whole read; a source that
 * changed since is refused with a message and the destination left alone.
 * 4096 x 300 so the decodes run in several bands. */
TEST(open_leaves_passes_in_the_file) {
    char dir[4096], src[4200], a[4200], b[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    const int w = 4096, h = 300;
    CHECK(write_blender_source(dir, w, h, src, sizeof src) == 0);
    ewio_file *g = NULL, *d = NULL;
    CHECK(ewio_read(src, &g, err, sizeof err) == 0);
    CHECK(ewio_open(src, &d, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(d), ewio_num_channels(g));
    const char *passes[][2] = {{"Combined", "RGBA"}, {"Denoising Albedo", "RGB"}, {"Denoising Normal", "XYZ"},
                               {"Denoising Depth", "Z"}, {"Vector", "XYZW"}, {"Vector", "WX"}};
    const size_t n = (size_t)w * h;
    float *pg = malloc(sizeof(float) * n * 4), *pd = malloc(sizeof(float) * n * 4);
    CHECK(pg && pd);
    for (int round = 0; round < 2; round++) { /* on demand, then loaded */
        for (int k = 0; k < 6; k++) {
            const size_t c = strlen(passes[k][1]);
            CHECK(ewio_get_pass(g, "ViewLayer", passes[k][0], passes[k][1], pg, err, sizeof err) == 0);
            CHECK(ewio_get_pass(d, "ViewLayer", passes[k][0], passes[k][1], pd, err, sizeof err) == 0);
            CHECK(memcmp(pg, pd, sizeof(float) * n * c) == 0);
        }
        const ewio_pass_ref refs[] = {{"ViewLayer", "Combined", NULL, NULL}, {"ViewLayer", "Vector", "XY", NULL},
                                      {"ViewLayer", "Missing", NULL, NULL}};
        CHECK(ewio_load_passes(d, refs, 3, err, sizeof err) == 0);
    }
    /* the same edits on both: a pass replaced, one released and set, one set from the source */
    CHECK(ewio_pass_in_source(d, "ViewLayer", "Combined", "RGBA"));
    CHECK(!ewio_pass_in_source(d, "ViewLayer", "Combined", "RGBAQ"));
    CHECK(ewio_get_pass(g, "ViewLayer", "Combined", "RGBA", pg, err, sizeof err) == 0);
    CHECK(ewio_set_pass(g, "ViewLayer", "Noisy Image", "RGBA", pg, err, sizeof err) == 0);
    CHECK(ewio_set_pass_from_source(d, "ViewLayer", "Noisy Image", "RGBA", "Combined", err, sizeof err) == 0);
    CHECK(ewio_set_pass_from_source(d, "ViewLayer", "New", "RGB", "Absent", err, sizeof err) != 0);
    CHECK(strstr(err, "not in the file") != NULL);
    ewio_file *both[2] = {g, d};
    for (int i = 0; i < 2; i++) {
        CHECK(set_pattern(both[i], "ViewLayer", "Combined", "RGB", 9) == 0);
        CHECK(ewio_release_pass(both[i], "ViewLayer", "Denoising Depth", "Z") == 0);
        CHECK(set_pattern(both[i], "ViewLayer", "Denoising Depth", "Z", 8) == 0);
    }
    CHECK(ewio_get_pass(d, "ViewLayer", "Noisy Image", "RGBA", pd, err, sizeof err) == 0);
    CHECK(memcmp(pg, pd, sizeof(float) * n * 4) == 0); /* the values read, not the pattern set since */
    snprintf(a, sizeof a, "%s/a.exr", dir);
    snprintf(b, sizeof b, "%s/b.exr", dir);
    CHECK(written_alike(g, a, d, b) == 1);
    /* the source changes under the file: refused, destination untouched */
    struct timespec ts[2] = {{1000000000, 0}, {1000000000, 0}};
    CHECK(utimensat(AT_FDCWD, src, ts, 0) == 0);
    CHECK(ewio_write(d, b, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK(strstr(err, "changed") != NULL);
    CHECK(ewio_get_pass(d, "ViewLayer", "Denoising Normal", "XYZ", pd, err, sizeof err) != 0);
    CHECK(strstr(err, "changed") != NULL);
    long la = 0, lb = 0;
    unsigned char *ba = slurp(a, &la), *bb2 = slurp(b, &lb);
    CHECK(ba && bb2 && lb == la && memcmp(ba, bb2, (size_t)la) == 0);
    free(ba);
    free(bb2);
    CHECK_EQ_INT(count_entries(dir, ".tmp-"), 0);
    free(pg);
    free(pd);
    ewio_free(g);
    ewio_free(d);
    rm_tree(dir);
}

/* A pass decoded into the caller's buffer by ewio_load_passes is what
 * ewio_get_pass gives (from the file, and from memory for a file read
 * whole) and stays in the file; a pass lent with ewio_lend_pass is written
 * as ewio_set_pass's copy would be (the same bytes), follows later changes
 * to the buffer until it is set or released again, and a new pass can be
 * lent. 4096 x 300: several bands. */
TEST(load_into_dst_and_lend) {
    char dir[4096], src[4200], a[4200], b[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    const int w = 4096, h = 300;
    CHECK(write_blender_source(dir, w, h, src, sizeof src) == 0);
    const size_t n = (size_t)w * h;
    float *want = malloc(sizeof(float) * n * 4), *got = malloc(sizeof(float) * n * 4),
          *nrm = malloc(sizeof(float) * n * 3);
    CHECK(want && got && nrm);
    ewio_file *g = NULL, *d = NULL;
    CHECK(ewio_read(src, &g, err, sizeof err) == 0);
    CHECK(ewio_get_pass(g, "ViewLayer", "Combined", "BGRA", want, err, sizeof err) == 0);
    for (int whole = 0; whole < 2; whole++) {
        CHECK((whole ? ewio_read : ewio_open)(src, &d, err, sizeof err) == 0);
        memset(got, 0xff, sizeof(float) * n * 4);
        const ewio_pass_ref refs[] = {{"ViewLayer", "Combined", "BGRA", got},
                                      {"ViewLayer", "Denoising Normal", NULL, NULL}};
        CHECK(ewio_load_passes(d, refs, 2, err, sizeof err) == 0);
        CHECK(memcmp(want, got, sizeof(float) * n * 4) == 0);
        /* the kept pass is in memory now, the decoded one still reads */
        CHECK(ewio_get_pass(g, "ViewLayer", "Denoising Normal", "XYZ", nrm, err, sizeof err) == 0);
        CHECK(ewio_get_pass(d, "ViewLayer", "Denoising Normal", "XYZ", got, err, sizeof err) == 0);
        CHECK(memcmp(nrm, got, sizeof(float) * n * 3) == 0);
        CHECK(ewio_get_pass(d, "ViewLayer", "Combined", "BGRA", got, err, sizeof err) == 0);
        CHECK(memcmp(want, got, sizeof(float) * n * 4) == 0);
        const ewio_pass_ref bad[] = {{"ViewLayer", "Combined", "RGBQ", got}};
        CHECK(ewio_load_passes(d, bad, 1, err, sizeof err) != 0);
        CHECK_STR_CONTAINS(err, "Q");
        ewio_free(d);
        d = NULL;
    }
    /* a channel asked for twice in one load (a pass and its alpha) reaches
     * both buffers, however the decoder holds its destinations */
    CHECK(ewio_open(src, &d, err, sizeof err) == 0);
    memset(got, 0xff, sizeof(float) * n * 4);
    memset(nrm, 0xff, sizeof(float) * n);
    const ewio_pass_ref twice[] = {{"ViewLayer", "Combined", "BGRA", got}, {"ViewLayer", "Combined", "A", nrm}};
    CHECK(ewio_load_passes(d, twice, 2, err, sizeof err) == 0);
    CHECK(memcmp(want, got, sizeof(float) * n * 4) == 0);
    size_t alpha_wrong = 0;
    for (size_t i = 0; i < n; i++) alpha_wrong += memcmp(&nrm[i], &want[4 * i + 3], sizeof(float)) != 0;
    CHECK(alpha_wrong == 0);
    ewio_free(d);
    d = NULL;
    /* lend: the same bytes as a copy, a new pass too */
    CHECK(ewio_open(src, &d, err, sizeof err) == 0);
    for (size_t i = 0; i < n * 3; i++) got[i] = (float)(i % 977) * 0.25f;
    CHECK(ewio_set_pass(g, "ViewLayer", "Combined", "RGB", got, err, sizeof err) == 0);
    CHECK(ewio_set_pass(g, "ViewLayer", "Extra", "RGB", got, err, sizeof err) == 0);
    CHECK(ewio_lend_pass(d, "ViewLayer", "Combined", "RGB", nrm, err, sizeof err) == 0);
    CHECK(ewio_lend_pass(d, "ViewLayer", "Extra", "RGB", nrm, err, sizeof err) == 0);
    memcpy(nrm, got, sizeof(float) * n * 3); /* lent, not copied: the write sees this */
    CHECK(ewio_get_pass(d, "ViewLayer", "Extra", "BR", want, err, sizeof err) == 0);
    CHECK(want[0] == got[2] && want[1] == got[0] && want[2 * (n - 1)] == got[3 * (n - 1) + 2]);
    snprintf(a, sizeof a, "%s/a.exr", dir);
    snprintf(b, sizeof b, "%s/b.exr", dir);
    CHECK(written_alike(g, a, d, b) == 1);
    /* set again: a copy of its own, the buffer no longer read; released: refused */
    CHECK(ewio_set_pass(d, "ViewLayer", "Extra", "RGB", got, err, sizeof err) == 0);
    memset(nrm, 0, sizeof(float) * n * 3);
    CHECK(ewio_get_pass(d, "ViewLayer", "Extra", "RGB", want, err, sizeof err) == 0);
    CHECK(memcmp(want, got, sizeof(float) * n * 3) == 0);
    CHECK(ewio_release_pass(d, "ViewLayer", "Combined", "RGB") == 0);
    CHECK(ewio_write(d, b, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "released");
    CHECK(ewio_lend_pass(d, "ViewLayer", "Bad.Name", "RGB", nrm, err, sizeof err) != 0);
    CHECK(ewio_lend_pass(d, "ViewLayer", "Combined", "RGB", NULL, err, sizeof err) != 0);
    CHECK_EQ_INT(count_entries(dir, ".tmp-"), 0);
    free(want);
    free(got);
    free(nrm);
    ewio_free(g);
    ewio_free(d);
    rm_tree(dir);
}

TEST(multipart_exr) {
    if (system("oiiotool --version >/dev/null 2>&1") != 0) SKIP("oiiotool not found");
    char dir[4096], a[4200], b[4200], mp[4200], out[4200], cmd[16384], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = NULL;
    CHECK(ewio_create(6, 5, &f, err, sizeof err) == 0);
    CHECK(set_pattern(f, "ViewLayer", "Combined", "RGBA", 1) == 0);
    snprintf(a, sizeof a, "%s/a.exr", dir);
    CHECK(ewio_write(f, a, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_free(f);
    CHECK(ewio_create(6, 5, &f, err, sizeof err) == 0);
    CHECK(set_pattern(f, "ViewLayer", "Denoising Albedo", "RGB", 2) == 0);
    snprintf(b, sizeof b, "%s/b.exr", dir);
    CHECK(ewio_write(f, b, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_free(f);
    snprintf(mp, sizeof mp, "%s/mp.exr", dir);
    snprintf(cmd, sizeof cmd,
             "oiiotool '%s' --attrib oiio:subimagename combined '%s' --attrib "
             "oiio:subimagename albedo --siappend -o '%s' >/dev/null 2>&1",
             a, b, mp);
    CHECK(system(cmd) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(mp, &g, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(g), 7);
    CHECK_EQ_INT(ewio_num_layers(g), 1);
    CHECK(pattern_diff(g, "ViewLayer", "Combined", "RGBA", 1) == 0.0);
    CHECK(pattern_diff(g, "ViewLayer", "Denoising Albedo", "RGB", 2) == 0.0);
    CHECK(!strcmp(ewio_get_attribute(g, "name"), "")); /* part names are dropped */
    snprintf(out, sizeof out, "%s/single.exr", dir);
    CHECK(ewio_write(g, out, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_file *h = NULL;
    CHECK(ewio_read(out, &h, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(h), 7);
    CHECK(pattern_diff(h, "ViewLayer", "Denoising Albedo", "RGB", 2) == 0.0);
    ewio_free(h);
    /* the parts' passes left in the file: the same values, the same output */
    ewio_file *o = NULL;
    CHECK(ewio_open(mp, &o, err, sizeof err) == 0);
    CHECK(pattern_diff(o, "ViewLayer", "Combined", "RGBA", 1) == 0.0);
    CHECK(pattern_diff(o, "ViewLayer", "Denoising Albedo", "RGB", 2) == 0.0);
    char out2[4300];
    snprintf(out2, sizeof out2, "%s/single2.exr", dir);
    CHECK(ewio_write(o, out2, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_free(o);
    long l1 = 0, l2 = 0;
    unsigned char *b1 = slurp(out, &l1), *b2 = slurp(out2, &l2);
    CHECK(b1 && b2 && l1 == l2 && memcmp(b1, b2, (size_t)l1) == 0);
    free(b1);
    free(b2);
    ewio_free(g);
    rm_tree(dir);
}

/* ------------------------------------------------------ real renders */

static const char *const cycles_channels[] = {
    "ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
    "ViewLayer.Combined.A", "ViewLayer.Denoising Albedo.R", "ViewLayer.Denoising Albedo.G",
    "ViewLayer.Denoising Albedo.B", "ViewLayer.Denoising Depth.Z",
    "ViewLayer.Denoising Normal.X", "ViewLayer.Denoising Normal.Y",
    "ViewLayer.Denoising Normal.Z", "ViewLayer.Depth.Z", "ViewLayer.Normal.X",
    "ViewLayer.Normal.Y", "ViewLayer.Normal.Z", "ViewLayer.Vector.X", "ViewLayer.Vector.Y",
    "ViewLayer.Vector.Z", "ViewLayer.Vector.W"};

/* Checks common to any Debian-Blender 4-spp render with denoising data.
 * A failed CHECK returns early and marks the calling test failed. */
static void check_cycles_file(const char *path, int exact_list) {
    char err[512];
    ewio_file *f = NULL;
    int rc = ewio_read(path, &f, err, sizeof err);
    if (rc) fprintf(stderr, "  %s\n", err);
    CHECK(rc == 0);
    int w = ewio_width(f), h = ewio_height(f);
    CHECK(w > 0 && h > 0);
    if (exact_list) {
        CHECK_EQ_INT(w, 256);
        CHECK_EQ_INT(h, 256);
        CHECK_EQ_INT(ewio_num_channels(f), 19);
        for (int i = 0; i < 19; i++) CHECK(!strcmp(ewio_channel_name(f, i), cycles_channels[i]));
    } else {
        for (int i = 0; i < 15; i++) CHECK(has_channel(f, cycles_channels[i]));
    }
    CHECK(ewio_num_layers(f) >= 1);
    CHECK(!strcmp(ewio_layer_name(f, 0), "ViewLayer"));
    CHECK(ewio_has_pass(f, "ViewLayer", "Combined", "RGBA"));
    CHECK(ewio_has_pass(f, "ViewLayer", "Denoising Albedo", "RGB"));
    CHECK(ewio_has_pass(f, "ViewLayer", "Denoising Normal", "XYZ"));
    CHECK(ewio_has_pass(f, "ViewLayer", "Denoising Depth", "Z"));
    CHECK(!strcmp(ewio_get_attribute(f, "cycles.ViewLayer.samples"), "4"));
    CHECK(!strcmp(ewio_get_attribute(f, "compression"), "zip"));

    size_t n = (size_t)w * (size_t)h;
    float *c = malloc(n * 4 * sizeof(float));
    float *alb = malloc(n * 3 * sizeof(float));
    CHECK(c && alb);
    CHECK(ewio_get_pass(f, "ViewLayer", "Combined", "RGBA", c, err, sizeof err) == 0);
    CHECK(ewio_get_pass(f, "ViewLayer", "Denoising Albedo", "RGB", alb, err, sizeof err) == 0);
    double sum = 0, amin = 1e30, amax = -1e30;
    for (size_t i = 0; i < n; i++) {
        if (isfinite(c[i * 4])) sum += c[i * 4];
        if (alb[i * 3] < amin) amin = alb[i * 3];
        if (alb[i * 3] > amax) amax = alb[i * 3];
    }
    CHECK(sum > 0.0);               /* a lit scene */
    CHECK(amin >= 0.0 && isfinite(amax)); /* (lights make albedo exceed 1) */
    CHECK(amax > 0.05);

    /* Rewrite with an added pass; everything else survives bit-exactly. */
    char dir[4096], p[4200];
    CHECK(make_tmpdir(dir, sizeof dir));
    for (size_t i = 0; i < n * 3; i++) alb[i] *= 0.5f;
    CHECK(ewio_set_pass(f, "ViewLayer", "Denoised", "RGB", alb, err, sizeof err) == 0);
    snprintf(p, sizeof p, "%s/out.exr", dir);
    CHECK(ewio_write(f, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_num_channels(g), ewio_num_channels(f));
    CHECK(has_channel(g, "ViewLayer.Denoised.G"));
    CHECK(!strcmp(ewio_get_attribute(g, "cycles.ViewLayer.samples"), "4"));
    CHECK(!strcmp(ewio_get_attribute(g, "compression"), "zip"));
    CHECK(!strcmp(ewio_get_attribute(g, "Camera"), ewio_get_attribute(f, "Camera")));
    float *c2 = malloc(n * 4 * sizeof(float));
    CHECK(c2);
    CHECK(ewio_get_pass(g, "ViewLayer", "Combined", "RGBA", c2, err, sizeof err) == 0);
    CHECK(memcmp(c, c2, n * 4 * sizeof(float)) == 0);
    float *d1 = malloc(n * sizeof(float)), *d2 = malloc(n * sizeof(float));
    CHECK(d1 && d2);
    CHECK(ewio_get_pass(f, "ViewLayer", "Denoising Depth", "Z", d1, err, sizeof err) == 0);
    CHECK(ewio_get_pass(g, "ViewLayer", "Denoising Depth", "Z", d2, err, sizeof err) == 0);
    CHECK(memcmp(d1, d2, n * sizeof(float)) == 0); /* float pass stays float */
    free(d1);
    free(d2);
    free(c2);
    free(c);
    free(alb);
    ewio_free(g);
    ewio_free(f);
    rm_tree(dir);
}

TEST(real_cycles_exr_shared_data) {
    char buf[4096];
    const char *p = shared_file(buf, sizeof buf);
    if (!p) SKIP("$EW_SHARED_DATA/a_cornell_100_256x256/f0001_spp0004.exr not found");
    check_cycles_file(p, 1);
}

TEST(real_cycles_exr_bundled_sample) {
    char buf[4096];
    const char *p = sample_file(buf, sizeof buf);
    if (!p) SKIP("$EW_SAMPLE_DIR/cornell/f0001_spp0004.exr not found");
    check_cycles_file(p, 0);
}

/* Blender stores the denoising albedo as half, its normal and depth as
 * float: ewio says which, and the albedo's floats go back to the very
 * halves stored (a caller may hold them so at no loss). */
TEST(pass_stored_half_gives_back_its_halves) {
    char buf[4096], err[512];
    const char *p = sample_file(buf, sizeof buf);
    if (!p) SKIP("$EW_SAMPLE_DIR/cornell/f0001_spp0004.exr not found");
    for (int open = 0; open < 2; open++) {
        ewio_file *f = NULL;
        CHECK((open ? ewio_open(p, &f, err, sizeof err) : ewio_read(p, &f, err, sizeof err)) == 0);
        CHECK_EQ_INT(ewio_pass_stored_half(f, "ViewLayer", "Denoising Albedo", "RGB"), 1);
        CHECK_EQ_INT(ewio_pass_stored_half(f, "ViewLayer", "Denoising Normal", "XYZ"), 0);
        CHECK_EQ_INT(ewio_pass_stored_half(f, "ViewLayer", "Denoising Depth", "Z"), 0);
        CHECK_EQ_INT(ewio_pass_stored_half(f, "ViewLayer", "Denoising Albedo", "RGBA"), 0); /* no A */
        CHECK_EQ_INT(ewio_pass_stored_half(f, "ViewLayer", "Nothing", "RGB"), 0);
        CHECK_EQ_INT(ewio_pass_stored_half(NULL, "ViewLayer", "Denoising Albedo", "RGB"), 0);
        const size_t n = (size_t)ewio_width(f) * (size_t)ewio_height(f) * 3;
        float *a = malloc(n * sizeof(float));
        uint16_t *h = malloc(n * sizeof(uint16_t));
        CHECK(a && h);
        CHECK(ewio_get_pass(f, "ViewLayer", "Denoising Albedo", "RGB", a, err, sizeof err) == 0);
        ewio_floats_to_half(a, h, n);
        size_t differ = 0;
        for (size_t i = 0; i < n; i++) {
            _Float16 v;
            memcpy(&v, &h[i], sizeof v);
            const float back = (float)v;
            differ += memcmp(&back, &a[i], sizeof back) != 0;
        }
        CHECK(differ == 0);
        /* a float the halves cannot hold rounds to the nearest, ties to even */
        const float odd[3] = {1.0f + 2.0f / 4096.0f, 1.0f + 6.0f / 4096.0f, 70000.0f};
        uint16_t ho[3];
        ewio_floats_to_half(odd, ho, 3);
        CHECK_EQ_INT(ho[0], 0x3c00); /* halfway between 1.0 and the next half: the even one */
        CHECK_EQ_INT(ho[1], 0x3c02); /* halfway between 0x3c01 and 0x3c02: the even one */
        CHECK_EQ_INT(ho[2], 0x7c00); /* beyond 65504: infinity */
        free(a);
        free(h);
        ewio_free(f);
    }
}

/* --------------------------------------------------------- bad inputs */

TEST(bad_missing_file) {
    ewio_file *f = (ewio_file *)1;
    char err[512];
    CHECK(ewio_read("/nonexistent-dir-ewio/none.exr", &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "no such file");
    CHECK_STR_CONTAINS(err, "none.exr");
    CHECK(strchr(err, '\n') == NULL);
    /* a directory */
    CHECK(ewio_read("/", &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "is a directory");
    /* a tiny error buffer is filled but never overrun */
    char small[8];
    memset(small, 'x', sizeof small);
    CHECK(ewio_read("/nonexistent-dir-ewio/none.exr", &f, small, 6) != 0);
    CHECK_EQ_INT(strlen(small), 5);
    CHECK(small[7] == 'x');
    CHECK(ewio_read(NULL, &f, err, sizeof err) != 0);
    CHECK(ewio_read("/x.exr", &f, NULL, 0) != 0);
}

TEST(bad_text_file_named_exr) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    snprintf(p, sizeof p, "%s/notes.exr", dir);
    CHECK(write_text(p, "this is not an image, just some text\n") == 0);
    ewio_file *f = (ewio_file *)1;
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "not an image");
    CHECK_STR_CONTAINS(err, "notes.exr");
    /* refused before OpenImageIO tries its other readers on it */
    CHECK_STR_CONTAINS(err, "named .exr, but it does not start with EXR's magic number");
    CHECK(strchr(err, '\n') == NULL);
    /* empty file */
    snprintf(p, sizeof p, "%s/empty.png", dir);
    CHECK(write_text(p, "") == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "not an image");
    rm_tree(dir);
}

TEST(bad_truncated_exr) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(64, 64, "ViewLayer");
    CHECK(f != NULL);
    snprintf(p, sizeof p, "%s/cut.exr", dir);
    CHECK(ewio_write(f, p, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_free(f);
    struct stat st;
    CHECK(stat(p, &st) == 0);
    CHECK(st.st_size > 4096);
    CHECK(truncate(p, st.st_size / 2) == 0);
    ewio_file *g = (ewio_file *)1;
    CHECK(ewio_read(p, &g, err, sizeof err) != 0);
    CHECK(g == NULL); /* no partial data */
    CHECK_STR_CONTAINS(err, "corrupt or truncated");
    CHECK_STR_CONTAINS(err, "cut.exr");
    CHECK(strchr(err, '\n') == NULL);
    rm_tree(dir);
}

static void put_u32(FILE *fp, uint32_t v) {
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 24)};
    fwrite(b, 1, 4, fp);
}

static void put_attr(FILE *fp, const char *name, const char *type, uint32_t size) {
    fwrite(name, 1, strlen(name) + 1, fp);
    fwrite(type, 1, strlen(type) + 1, fp);
    put_u32(fp, size);
}

/* A new EXR file at path with its magic number and version 2 (single
 * part, scanline, short names) written; NULL when it cannot be made. */
static FILE *exr_start(const char *path) {
    FILE *fp = fopen(path, "wb");
    if (fp) {
        put_u32(fp, 20000630u);
        put_u32(fp, 2u);
    }
    return fp;
}

/* A scanline EXR header claiming w x h pixels, one half channel "R", no
 * compression, followed by a line offset table of zeros and no pixel data. */
static int write_exr_header_typed(const char *path, int w, int h, uint32_t pixel_type) {
    FILE *fp = exr_start(path);
    if (!fp) return 1;
    put_attr(fp, "channels", "chlist", 18 + 1);
    fwrite("R", 1, 2, fp);
    put_u32(fp, pixel_type); /* 1: HALF */
    put_u32(fp, 0); /* pLinear + reserved */
    put_u32(fp, 1);
    put_u32(fp, 1);
    fputc(0, fp);
    put_attr(fp, "compression", "compression", 1);
    fputc(0, fp);
    for (int k = 0; k < 2; k++) {
        put_attr(fp, k ? "displayWindow" : "dataWindow", "box2i", 16);
        put_u32(fp, 0);
        put_u32(fp, 0);
        put_u32(fp, (uint32_t)(w - 1));
        put_u32(fp, (uint32_t)(h - 1));
    }
    put_attr(fp, "lineOrder", "lineOrder", 1);
    fputc(0, fp);
    float one = 1.0f, zero = 0.0f;
    put_attr(fp, "pixelAspectRatio", "float", 4);
    fwrite(&one, 4, 1, fp);
    put_attr(fp, "screenWindowCenter", "v2f", 8);
    fwrite(&zero, 4, 1, fp);
    fwrite(&zero, 4, 1, fp);
    put_attr(fp, "screenWindowWidth", "float", 4);
    fwrite(&one, 4, 1, fp);
    fputc(0, fp); /* end of header */
    for (int i = 0; i < 2 * h; i++) put_u32(fp, 0);
    return fclose(fp) != 0;
}

static int write_exr_header(const char *path, int w, int h) { return write_exr_header_typed(path, w, h, 1); }

TEST(bad_huge_dimensions) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    /* 100000 x 100000 would be 40 GB as float: must be refused before allocating. */
    snprintf(p, sizeof p, "%s/huge.exr", dir);
    CHECK(write_exr_header(p, 100000, 100000) == 0);
    ewio_file *f = (ewio_file *)1;
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "too large");
    /* 60000 x 60000: each side fine, but more than 2^28 pixels */
    snprintf(p, sizeof p, "%s/many.exr", dir);
    CHECK(write_exr_header(p, 60000, 60000) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "too large");
    /* The same header at a small size reads as far as the pixels. */
    snprintf(p, sizeof p, "%s/small.exr", dir);
    CHECK(write_exr_header(p, 4, 4) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "corrupt or truncated");
    rm_tree(dir);
}

/* Headers that declare more than the file holds are refused before
 * OpenImageIO opens the file: OpenEXR would first allocate what they
 * declare (a 302-byte file asked for 1.9 GB through one string length). */
TEST(bad_header_sizes_beyond_the_file) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    snprintf(p, sizeof p, "%s/long_string.exr", dir);
    FILE *fp = exr_start(p);
    CHECK(fp != NULL);
    put_attr(fp, "comments", "string", 1952540018u);
    fwrite("only a few bytes follow", 1, 23, fp);
    CHECK(fclose(fp) == 0);
    ewio_file *f = (ewio_file *)1;
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "long_string.exr");
    CHECK_STR_CONTAINS(err, "'comments' declares 1952540018 bytes, but the file has 23 left");
    ewio_header h;
    CHECK(ewio_read_header(p, &h, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "declares 1952540018 bytes");

    /* 4 x 60000 is within every limit, but its 60000 line offsets are not in the file */
    snprintf(p, sizeof p, "%s/short_table.exr", dir);
    CHECK(write_exr_header(p, 4, 60000) == 0);
    CHECK(truncate(p, 400) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "at least 60000 chunks");
    CHECK_STR_CONTAINS(err, "offset table");

    /* an empty data window */
    snprintf(p, sizeof p, "%s/empty.exr", dir);
    CHECK(write_exr_header(p, 0, 4) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "data window is empty (0 x 4 pixels)");

    /* no data window at all: OpenEXR would take a default one and rebuild
     * its offset table from what follows (the fuzz corpus's
     * oom_tiled_part_without_data_window.exr asked for over 512 MB so) */
    snprintf(p, sizeof p, "%s/no_window.exr", dir);
    fp = exr_start(p);
    CHECK(fp != NULL);
    put_attr(fp, "comments", "string", 4);
    fwrite("abcd", 1, 4, fp);
    fputc(0, fp);
    for (int k = 0; k < 8; k++) put_u32(fp, 0);
    CHECK(fclose(fp) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "has no data window");

    /* A channel list shorter than its entries: OpenEXR reads entries up to the
     * empty name, then the rest of the header out of step; here the
     * "comments" string's text becomes the next size it reads. It reads any
     * attribute of type chlist that way, whatever its name. */
    static const char *const list_names[] = {"channels", "2channels"};
    for (int k = 0; k < 2; k++) {
        char want[128];
        snprintf(p, sizeof p, "%s/short_chlist_%d.exr", dir, k);
        fp = exr_start(p);
        CHECK(fp != NULL);
        put_attr(fp, list_names[k], "chlist", 10);
        fwrite("R", 1, 2, fp);
        put_u32(fp, 1);
        put_u32(fp, 0);
        put_u32(fp, 1);
        put_u32(fp, 1);
        fputc(0, fp);
        put_attr(fp, "comments", "string", 4);
        fwrite("abcd", 1, 4, fp);
        fputc(0, fp);
        CHECK(fclose(fp) == 0);
        CHECK(ewio_read(p, &f, err, sizeof err) != 0);
        CHECK(f == NULL);
        snprintf(want, sizeof want, "channel list '%s' declares 10 bytes, but its entries take 19", list_names[k]);
        CHECK_STR_CONTAINS(err, want);
    }

    /* a fixed-size type with another size: OpenEXR reads its 16 bytes and
     * takes the declared rest as the next attribute */
    snprintf(p, sizeof p, "%s/long_box.exr", dir);
    fp = exr_start(p);
    CHECK(fp != NULL);
    put_attr(fp, "dataWindow", "box2i", 20);
    for (int k = 0; k < 5; k++) put_u32(fp, 3);
    fputc(0, fp);
    CHECK(fclose(fp) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "'dataWindow' of type box2i declares 20 bytes, but that type has 16");

    /* a pixel type EXR does not have: OpenImageIO aborts the process on it */
    snprintf(p, sizeof p, "%s/type3.exr", dir);
    CHECK(write_exr_header_typed(p, 4, 4, 3) == 0);
    CHECK(ewio_read(p, &f, err, sizeof err) != 0);
    CHECK(f == NULL);
    CHECK_STR_CONTAINS(err, "channel 'R' has pixel type 3");
    rm_tree(dir);
}

TEST(bad_missing_pass) {
    char err[1024];
    ewio_file *f = make_blender_like(4, 4, "ViewLayer");
    CHECK(f != NULL);
    CHECK(set_pattern(f, "Second Layer", "Combined", "RGB", 9) == 0);
    float buf[4 * 4 * 4];
    /* absent pass */
    CHECK(ewio_get_pass(f, "ViewLayer", "Denoising Shadow", "RGB", buf, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "missing");
    CHECK_STR_CONTAINS(err, "'Denoising Shadow'");
    CHECK_STR_CONTAINS(err, "'RGB'");
    CHECK_STR_CONTAINS(err, "'Denoising Albedo'"); /* the passes that are there */
    CHECK_STR_CONTAINS(err, "layers found: 'ViewLayer', 'Second Layer'");
    /* absent layer */
    CHECK(ewio_get_pass(f, "RenderLayer", "Combined", "RGBA", buf, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "no layer 'RenderLayer'");
    CHECK_STR_CONTAINS(err, "layers found: 'ViewLayer', 'Second Layer'");
    /* absent component */
    CHECK(ewio_get_pass(f, "Second Layer", "Combined", "RGBA", buf, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "missing components 'A'");
    CHECK_STR_CONTAINS(err, "'Second Layer'");
    CHECK_STR_CONTAINS(err, "layers found:");
    CHECK(strchr(err, '\n') == NULL);
    CHECK_EQ_INT(ewio_has_pass(f, "Second Layer", "Combined", "RGBA"), 0);
    CHECK_EQ_INT(ewio_has_pass(f, "Second Layer", "Combined", "BGR"), 1);
    ewio_free(f);
}

TEST(bad_output_is_input) {
    char dir[4096], p[4200], alias[4300], lk[4300], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(16, 16, "ViewLayer");
    CHECK(f != NULL);
    snprintf(p, sizeof p, "%s/in.exr", dir);
    CHECK(ewio_write(f, p, EWIO_HALF, NULL, NULL, err, sizeof err) == 0);
    ewio_free(f);
    long n0 = 0, n1 = 0;
    unsigned char *before = slurp(p, &n0);
    CHECK(before != NULL);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK(set_pattern(g, "ViewLayer", "Denoised", "RGB", 7) == 0);
    CHECK(ewio_write(g, p, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "refusing to overwrite the input");
    /* another spelling of the same path, a symlink and a hard link */
    snprintf(alias, sizeof alias, "%s/./../%s/in.exr", dir, strrchr(dir, '/') + 1);
    CHECK(ewio_write(g, alias, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "refusing to overwrite the input");
    snprintf(lk, sizeof lk, "%s/sym.exr", dir);
    CHECK(symlink(p, lk) == 0);
    CHECK(ewio_write(g, lk, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "refusing to overwrite the input");
    snprintf(lk, sizeof lk, "%s/hard.exr", dir);
    CHECK(link(p, lk) == 0);
    CHECK(ewio_write(g, lk, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "refusing to overwrite the input");
    unsigned char *after = slurp(p, &n1);
    CHECK(after != NULL);
    CHECK_EQ_INT(n1, n0);
    CHECK(memcmp(before, after, (size_t)n0) == 0);
    CHECK(count_entries(dir, ".tmp-") == 0);
    /* writing elsewhere is fine */
    snprintf(lk, sizeof lk, "%s/out.exr", dir);
    CHECK(ewio_write(g, lk, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    free(before);
    free(after);
    ewio_free(g);
    rm_tree(dir);
}

TEST(bad_unwritable_directory) {
    char dir[4096], sub[4200], p[4300], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(4, 4, "ViewLayer");
    CHECK(f != NULL);
    /* a directory that does not exist */
    snprintf(p, sizeof p, "%s/missing/out.exr", dir);
    CHECK(ewio_write(f, p, EWIO_KEEP, NULL, NULL, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "does not exist");
    /* a read-only directory; root ignores modes, so drop to "nobody" meanwhile */
    snprintf(sub, sizeof sub, "%s/ro", dir);
    CHECK(mkdir(sub, 0755) == 0);
    CHECK(chmod(dir, 0755) == 0);
    CHECK(chmod(sub, 0555) == 0);
    snprintf(p, sizeof p, "%s/out.exr", sub);
    int dropped = 0;
    if (geteuid() == 0) {
        if (seteuid(65534) != 0) {
            ewio_free(f);
            rm_tree(dir);
            SKIP("running as root and cannot drop privileges to test permissions");
        }
        dropped = 1;
    }
    int rc = ewio_write(f, p, EWIO_KEEP, NULL, NULL, err, sizeof err);
    int rc_png = 0;
    char err_png[512];
    if (rc) {
        snprintf(p, sizeof p, "%s/out.png", sub);
        rc_png = ewio_write(f, p, EWIO_KEEP, "ViewLayer", "Combined", err_png, sizeof err_png);
    }
    if (dropped && seteuid(0) != 0) {
        FAIL_AT("cannot restore root privileges");
        return;
    }
    CHECK(rc != 0);
    CHECK_STR_CONTAINS(err, "not writable");
    CHECK_STR_CONTAINS(err, "/ro");
    CHECK(rc_png != 0);
    CHECK_STR_CONTAINS(err_png, "not writable");
    CHECK_EQ_INT(count_entries(sub, NULL), 0);
    ewio_free(f);
    rm_tree(dir);
}

TEST(bad_failed_write_keeps_destination) {
    char dir[4096], p[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    snprintf(p, sizeof p, "%s/dest.exr", dir);
    ewio_file *small = make_blender_like(4, 4, "ViewLayer");
    CHECK(small != NULL);
    CHECK(ewio_write(small, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    ewio_free(small);
    long n0 = 0, n1 = 0;
    unsigned char *before = slurp(p, &n0);
    CHECK(before != NULL && n0 > 0);

    /* A big, incompressible image, written with the file size limit set
     * below its size: the write fails half-way (EFBIG). */
    ewio_file *big = NULL;
    CHECK(ewio_create(256, 256, &big, err, sizeof err) == 0);
    float *noise = malloc(sizeof(float) * 256 * 256 * 3);
    CHECK(noise != NULL);
    uint32_t s = 12345;
    for (int i = 0; i < 256 * 256 * 3; i++) {
        s = s * 1664525u + 1013904223u;
        noise[i] = (float)(s >> 8) / 16777216.0f;
    }
    CHECK(ewio_set_pass(big, "ViewLayer", "Combined", "RGB", noise, err, sizeof err) == 0);
    free(noise);

    struct rlimit old, lim;
    CHECK(getrlimit(RLIMIT_FSIZE, &old) == 0);
    lim = old;
    lim.rlim_cur = 8192;
    void (*oldsig)(int) = signal(SIGXFSZ, SIG_IGN);
    CHECK(setrlimit(RLIMIT_FSIZE, &lim) == 0);
    int rc = ewio_write(big, p, EWIO_FLOAT, NULL, NULL, err, sizeof err);
    int rc_png;
    char err_png[512];
    char p_png[4300];
    snprintf(p_png, sizeof p_png, "%s/dest.png", dir);
    rc_png = ewio_write(big, p_png, EWIO_KEEP, "ViewLayer", "Combined", err_png, sizeof err_png);
    int restored = setrlimit(RLIMIT_FSIZE, &old) == 0;
    signal(SIGXFSZ, oldsig);
    CHECK(restored);

    CHECK(rc != 0);
    CHECK_STR_CONTAINS(err, "cannot write");
    CHECK_STR_CONTAINS(err, "dest.exr");
    CHECK(strchr(err, '\n') == NULL);
    unsigned char *after = slurp(p, &n1);
    CHECK(after != NULL);
    CHECK_EQ_INT(n1, n0);
    CHECK(memcmp(before, after, (size_t)n0) == 0);
    /* PNG: OIIO reports this one without failing the call; still caught. */
    CHECK(rc_png != 0);
    CHECK_STR_CONTAINS(err_png, "cannot write");
    CHECK(!file_exists(p_png));
    CHECK_EQ_INT(count_entries(dir, ".tmp-"), 0);
    CHECK_EQ_INT(count_entries(dir, NULL), 1);
    /* and the same write succeeds without the limit */
    CHECK(ewio_write(big, p, EWIO_FLOAT, NULL, NULL, err, sizeof err) == 0);
    ewio_file *g = NULL;
    CHECK(ewio_read(p, &g, err, sizeof err) == 0);
    CHECK_EQ_INT(ewio_width(g), 256);
    free(before);
    free(after);
    ewio_free(g);
    ewio_free(big);
    rm_tree(dir);
}

static int mode_of(const char *p) {
    struct stat st;
    return stat(p, &st) == 0 ? (int)(st.st_mode & 07777) : -1;
}

/* A new file gets what open(0666) under the umask gives, an overwritten one
 * keeps its mode: what the user's other tools would leave (the temporary
 * itself is created private). */
TEST(written_files_keep_the_usual_modes) {
    char dir[4096], p[4200], t[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    ewio_file *f = make_blender_like(4, 3, "ViewLayer");
    CHECK(f != NULL);
    snprintf(p, sizeof p, "%s/new.exr", dir);
    snprintf(t, sizeof t, "%s/new.json", dir);
    const mode_t masks[] = {022, 027, 077};
    for (int i = 0; i < 3; i++) {
        const mode_t old = umask(masks[i]);
        unlink(p);
        unlink(t);
        CHECK(ewio_write(f, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
        CHECK(ewio_write_text(t, "{}\n", 3, err, sizeof err) == 0);
        umask(old);
        CHECK_EQ_INT(mode_of(p), (int)(0666 & ~masks[i]));
        CHECK_EQ_INT(mode_of(t), (int)(0666 & ~masks[i]));
    }
    CHECK(chmod(p, 0640) == 0 && chmod(t, 0604) == 0);
    CHECK(ewio_write(f, p, EWIO_KEEP, NULL, NULL, err, sizeof err) == 0);
    CHECK(ewio_write_text(t, "[]\n", 3, err, sizeof err) == 0);
    CHECK_EQ_INT(mode_of(p), 0640);
    CHECK_EQ_INT(mode_of(t), 0604);
    CHECK_EQ_INT(count_entries(dir, ".tmp-"), 0);
    ewio_free(f);
    rm_tree(dir);
}

/* The check a written EXR passes before it replaces anything
 * (ewio_exr_chunks_check): what a write that failed unnoticed leaves — the
 * file cut short anywhere, the chunk table still the zeros OpenEXR writes
 * first, a chunk out of its place — is refused; the file as written passes. */
/* The little-endian 8-byte value at b (an EXR chunk offset). */
static uint64_t le64_at(const unsigned char *b) {
    uint64_t v = 0;
    for (int k = 7; k >= 0; k--) v = v << 8 | b[k];
    return v;
}

static int chunks_check_of(const unsigned char *b, long n, const char *p, ewio_exr_layout *lay) {
    FILE *fp = fopen(p, "wb");
    if (!fp) return 99;
    if (n > 0 && fwrite(b, 1, (size_t)n, fp) != (size_t)n) n = -1;
    fclose(fp);
    if (n < 0) return 99;
    fp = fopen(p, "rb");
    char why[256] = "";
    const int r = ewio_exr_chunks_check(fp, n, lay, why, sizeof why);
    fclose(fp);
    if (r == 1 && !why[0]) return 98; /* a refusal says why */
    return r;
}

TEST(written_exr_chunks_checked) {
    char dir[4096], p[4200], q[4200], err[512];
    CHECK(make_tmpdir(dir, sizeof dir));
    snprintf(p, sizeof p, "%s/w.exr", dir);
    snprintf(q, sizeof q, "%s/damaged.exr", dir);
    const int w = 37, h = 100, chunks = 7; /* zip: 16 lines a chunk */
    ewio_file *f = NULL;
    CHECK(ewio_create(w, h, &f, err, sizeof err) == 0);
    float *px = malloc(sizeof(float) * w * h * 3);
    CHECK(px != NULL);
    uint32_t s = 777;
    for (int i = 0; i < w * h * 3; i++) {
        s = s * 1664525u + 1013904223u;
        px[i] = (float)(s >> 8) / 16777216.0f;
    }
    CHECK(ewio_set_pass(f, "ViewLayer", "Combined", "RGB", px, err, sizeof err) == 0);
    CHECK(ewio_write(f, p, EWIO_HALF, NULL, NULL, err, sizeof err) == 0);
    long n = 0;
    unsigned char *b = slurp(p, &n);
    CHECK(b != NULL && n > 100);
    ewio_exr_layout lay;
    CHECK_EQ_INT(chunks_check_of(b, n, q, &lay), 0);
    CHECK_EQ_INT((int)lay.width, w);
    CHECK_EQ_INT((int)lay.height, h);
    CHECK_EQ_INT((int)lay.channels, 3);
    /* the table: 7 offsets, the first pointing just past it */
    long table = -1;
    for (long i = 8; i + 8 <= n && table < 0; i++)
        if (le64_at(b + i) == (uint64_t)(i + 8 * chunks)) table = i;
    CHECK(table > 0);
    /* cut short anywhere past the magic number: never passes; past the
     * table, refused with a reason */
    int passed = 0, refused_past_table = 1;
    for (long len = 8; len < n; len += len < table + 8 * chunks ? 7 : 13) {
        const int r = chunks_check_of(b, len, q, &lay);
        passed += r == 0;
        if (len >= table + 8 * chunks) refused_past_table = refused_past_table && r == 1;
    }
    CHECK_EQ_INT(chunks_check_of(b, n - 1, q, &lay), 1);
    CHECK_EQ_INT(passed, 0);
    CHECK(refused_past_table);
    /* the table as OpenEXR leaves it until close: zeros */
    unsigned char *d = malloc((size_t)n);
    CHECK(d != NULL);
    memcpy(d, b, (size_t)n);
    memset(d + table, 0, 8 * chunks);
    CHECK_EQ_INT(chunks_check_of(d, n, q, &lay), 1);
    /* one entry pointing at another chunk */
    memcpy(d, b, (size_t)n);
    memcpy(d + table + 8 * 3, b + table + 8 * 4, 8);
    CHECK_EQ_INT(chunks_check_of(d, n, q, &lay), 1);
    /* the last chunk declaring more bytes than the file holds */
    memcpy(d, b, (size_t)n);
    const uint64_t last = le64_at(b + table + 8 * (chunks - 1));
    CHECK(last + 8 <= (uint64_t)n);
    const uint32_t more = (uint32_t)(n - (long)last - 8 + 1);
    for (int k = 0; k < 4; k++) d[last + 4 + (uint64_t)k] = (unsigned char)(more >> (8 * k));
    CHECK_EQ_INT(chunks_check_of(d, n, q, &lay), 1);
    /* not an EXR at all */
    CHECK_EQ_INT(chunks_check_of((const unsigned char *)"hello, world", 12, q, &lay), 1);
    /* every codec's chunks of lines are checked in place, none left to the
     * whole decode (-1) */
    static const char *const codecs[] = {"none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"};
    for (size_t k = 0; k < sizeof codecs / sizeof codecs[0]; k++) {
        CHECK(ewio_set_attribute(f, "compression", codecs[k]) == 0);
        CHECK(ewio_write(f, p, EWIO_HALF, NULL, NULL, err, sizeof err) == 0);
        long m = 0;
        unsigned char *c = slurp(p, &m);
        CHECK(c != NULL);
        const int r = chunks_check_of(c, m, q, &lay);
        if (r != 0) fprintf(stderr, "  compression %s: check %d\n", codecs[k], r);
        CHECK_EQ_INT(r, 0);
        CHECK_EQ_INT(chunks_check_of(c, m - 1, q, &lay), 1);
        free(c);
    }
    free(d);
    free(b);
    free(px);
    ewio_free(f);
    rm_tree(dir);
}
