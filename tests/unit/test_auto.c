/* The "auto" denoiser: which method it runs for a sample count, a noise
 * level and a set of passes (ew_denoiser_describe), that its output is
 * exactly what the method it names gives, and the demodulation epsilon
 * the public header states. */
#include "ew_test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

static ew_device *make_device(void) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = 2;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

#define W 48
#define H 40
#define N (W * H)

/* A smooth two-region scene with noise of the given strength. */
typedef struct {
    float color[N * 3], albedo[N * 3], normal[N * 3], depth[N], out[N * 3], out2[N * 3];
} frame;

static void make_frame(frame *f, float noise, unsigned seed) {
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int j = y * W + x, left = x < W / 2;
            for (int c = 0; c < 3; c++) {
                f->albedo[j * 3 + c] = left ? 0.7f : 0.3f;
                float light = 0.2f + 0.3f * (float)y / H;
                /* multiplicative noise of mean 1, like a few samples' worth */
                float n = 1.0f + noise * (2.0f * urand(&seed) - 1.0f) * 1.7f;
                f->color[j * 3 + c] = f->albedo[j * 3 + c] * light * n;
                f->normal[j * 3 + c] = c == 2 ? 1.0f : 0.0f;
            }
            f->depth[j] = left ? 2.0f : 5.0f;
        }
}

/* A method parameter by name; lists end with {NULL}. */
typedef struct { const char *name; float value; } param;

/* Run `method` on f (features when `features`), with `samples` when the
 * method takes it (>= 0) and the parameters `ps` (may be NULL); returns
 * what it says it ran (copied into `what`). */
static ew_result run(ew_device *dev, const char *method, frame *f, int features, int samples, const param *ps,
                     float *out, char *what, size_t len) {
    ew_denoiser *d = NULL;
    ew_result r = ew_denoiser_create(dev, method, &d);
    ew_image c = ew_image_packed(f->color, W, H, 3), a = ew_image_packed(f->albedo, W, H, 3),
             n = ew_image_packed(f->normal, W, H, 3), z = ew_image_packed(f->depth, W, H, 1),
             o = ew_image_packed(out, W, H, 3);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "color", &c);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "output", &o);
    if (r == EW_OK && features) r = ew_denoiser_set_image(d, "albedo", &a);
    if (r == EW_OK && features) r = ew_denoiser_set_image(d, "normal", &n);
    if (r == EW_OK && features) r = ew_denoiser_set_image(d, "depth", &z);
    if (r == EW_OK && samples >= 0) r = ew_denoiser_set_int(d, "samples", samples);
    for (; r == EW_OK && ps && ps->name; ps++) /* "model", "quality", "max_memory_mb", "passes": integers */
        r = strcmp(ps->name, "model") && strcmp(ps->name, "quality") && strcmp(ps->name, "max_memory_mb") &&
                    strcmp(ps->name, "passes")
                ? ew_denoiser_set_float(d, ps->name, ps->value)
                : ew_denoiser_set_int(d, ps->name, (int32_t)ps->value);
    if (r == EW_OK) r = ew_denoiser_commit(d);
    if (r == EW_OK && what) snprintf(what, len, "%s", ew_denoiser_describe(d));
    if (r == EW_OK) r = ew_denoiser_execute(d);
    ew_denoiser_destroy(d);
    return r;
}

/* the three qualities as auto's parameter */
static const param fast[] = {{"quality", 0}, {NULL, 0}}, balanced[] = {{"quality", 1}, {NULL, 0}},
                   high[] = {{"quality", 2}, {NULL, 0}};

static int same(const float *a, const float *b) { return memcmp(a, b, sizeof(float) * N * 3) == 0; }

TEST(sample_count_picks_the_model) {
    ew_device *dev = make_device();
    static frame f;
    make_frame(&f, 0.5f, 1);
    char what[200];
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 1, fast, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "nbg 2layer-3grid-1spp");
    CHECK_STR_CONTAINS(what, "1 spp");
    CHECK_EQ_INT(run(dev, "nbg", &f, 1, -1, (const param[]){{"model", 3}, {NULL, 0}}, f.out2, what, sizeof what), EW_OK);
    CHECK(same(f.out, f.out2));
    CHECK_STR_CONTAINS(what, "nbg 2layer-3grid-1spp"); /* nbg names its model too */

    CHECK_EQ_INT(run(dev, "auto", &f, 1, 4, fast, f.out, what, sizeof what), EW_OK);
    CHECK(strstr(what, "nbg 2layer-3grid (") != NULL);
    CHECK_EQ_INT(run(dev, "nbg", &f, 1, -1, (const param[]){{"model", 0}, {NULL, 0}}, f.out2, NULL, 0), EW_OK);
    CHECK(same(f.out, f.out2));

    /* quality fast stays on the grids and nbg; balanced (the default)
     * and high climb to kpcn-large at every count, high with four
     * mirrored passes; the output is that model's own */
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 16, fast, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "bgrid fine grid 2/8");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 16, NULL, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "kpcn kpcn-large (16 spp, quality balanced)");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 16, balanced, f.out2, what, sizeof what), EW_OK);
    CHECK(same(f.out, f.out2));
    CHECK_EQ_INT(run(dev, "kpcn", &f, 1, -1, (const param[]){{"model", 2}, {NULL, 0}}, f.out2, NULL, 0), EW_OK);
    CHECK(same(f.out, f.out2));
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 1, balanced, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "kpcn kpcn-large (1 spp, quality balanced)");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 1, fast, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "nbg 2layer-3grid-1spp");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 4, high, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "kpcn kpcn-large (4 spp, quality high), 4 mirrored passes");
    CHECK_EQ_INT(run(dev, "kpcn", &f, 1, -1, (const param[]){{"model", 2}, {NULL, 0}}, f.out2, NULL, 0), EW_OK);
    CHECK(!same(f.out, f.out2));
    CHECK_EQ_INT(run(dev, "kpcn", &f, 1, -1, (const param[]){{"model", 2}, {"passes", 4}, {NULL, 0}}, f.out2, NULL, 0),
                 EW_OK);
    CHECK(same(f.out, f.out2));
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 1, high, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "kpcn kpcn-large (1 spp, quality high)");
    /* without the features kpcn cannot run: the grid, whatever the quality */
    CHECK_EQ_INT(run(dev, "auto", &f, 0, 16, high, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "bgrid fine grid");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 1024, NULL, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "kpcn kpcn-large (1024 spp, quality balanced)");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 1024, fast, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "bgrid finest grid 2/4");
    /* the finest grid is bgrid with those rates */
    static const param finest[] = {
        {"spatial_rate", 2.0f}, {"range_rate", 4.0f}, {"prepass_rate", 4.0f}, {"color_weight", 0.9f}, {NULL, 0}};
    CHECK_EQ_INT(run(dev, "bgrid", &f, 1, -1, finest, f.out2, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "bgrid");
    CHECK(same(f.out, f.out2));
    ew_device_destroy(dev);
}

TEST(without_features_it_uses_the_grid) {
    ew_device *dev = make_device();
    static frame f;
    make_frame(&f, 0.5f, 2);
    char what[200];
    CHECK_EQ_INT(run(dev, "auto", &f, 0, 1, NULL, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "bgrid coarse grid 8/8");
    CHECK_EQ_INT(run(dev, "auto", &f, 0, 4, NULL, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "bgrid medium grid 4/8");
    for (int i = 0; i < N * 3; i++) CHECK(isfinite(f.out[i]));
    ew_device_destroy(dev);
}

TEST(noise_estimate_when_the_count_is_unknown) {
    ew_device *dev = make_device();
    static frame f;
    char what[200];
    make_frame(&f, 0.9f, 3); /* very noisy: the 1-spp level (nbg's 1-spp model at quality fast) */
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 0, fast, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "1spp");
    CHECK_STR_CONTAINS(what, "noise estimate");
    make_frame(&f, 0.0f, 3); /* clean: the finest grid at quality fast, kpcn-large at balanced */
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 0, fast, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "finest");
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 0, NULL, f.out, what, sizeof what), EW_OK);
    CHECK_STR_CONTAINS(what, "kpcn kpcn-large (noise estimate");
    ew_device_destroy(dev);
}

/* auto's max_memory_mb is its rung's: a smaller budget gives a smaller
 * estimate at 4K and the same pixels (the rung tiles), and 0 puts the
 * rung's own default back on a reused op */
TEST(memory_budget_reaches_the_rung) {
    ew_device *dev = make_device();
    static frame f;
    make_frame(&f, 0.5f, 5);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "auto", &d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_int(d, "samples", 4), EW_OK);
    uint64_t own = 0, small = 0, back = 0;
    CHECK_EQ_INT(ew_op_memory(d, 3840, 2160, &own), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_int(d, "max_memory_mb", 256), EW_OK);
    CHECK_EQ_INT(ew_op_memory(d, 3840, 2160, &small), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_int(d, "max_memory_mb", 0), EW_OK);
    CHECK_EQ_INT(ew_op_memory(d, 3840, 2160, &back), EW_OK);
    CHECK(small < own);
    CHECK(back == own);
    ew_denoiser_destroy(d);

    CHECK_EQ_INT(run(dev, "auto", &f, 1, 4, NULL, f.out, NULL, 0), EW_OK);
    CHECK_EQ_INT(run(dev, "auto", &f, 1, 4, (const param[]){{"max_memory_mb", 1}, {NULL, 0}}, f.out2, NULL, 0), EW_OK);
    CHECK(same(f.out, f.out2));
    ew_device_destroy(dev);
}

TEST(describe_needs_a_commit) {
    ew_device *dev = make_device();
    static frame f;
    make_frame(&f, 0.5f, 4);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "auto", &d), EW_OK);
    CHECK(ew_denoiser_describe(d) == NULL);
    ew_image c = ew_image_packed(f.color, W, H, 3), o = ew_image_packed(f.out, W, H, 3);
    ew_denoiser_set_image(d, "color", &c);
    ew_denoiser_set_image(d, "output", &o);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK(ew_denoiser_describe(d) != NULL);
    ew_denoiser_set_int(d, "samples", 64); /* a change undoes the commit */
    CHECK(ew_denoiser_describe(d) == NULL);
    ew_denoiser_destroy(d);
    CHECK(ew_denoiser_describe(NULL) == NULL);
    ew_device_destroy(dev);
}
