/* The "nbg" denoiser through the public API: weights from set_data and
 * built in, properties that hold for any weights (a constant image stays
 * constant, outputs are finite whatever the input), thread-count
 * independence, and its error messages. */
#include "ew_test.h"

#include <stdlib.h>
#include <string.h>

#include "algorithms/guidenet.h"
#include "algorithms/nbg.h"
#include "edgewise/edgewise.h"

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

/* Weights-file bytes of a random net (guides spread over the range). */
static void *random_weights(const char *arch, uint64_t seed, size_t *size) {
    ew_guidenet net;
    char err[128];
    if (ew_guidenet_init(&net, arch, err, sizeof err)) return NULL;
    float *p = malloc(sizeof(float) * net.nparams);
    ew_guidenet_random(&net, seed, p);
    const ew_gn_layer *L = &net.layers[net.nlayers - 1];
    for (size_t i = 0; i < (size_t)L->cin * L->cout * 25; i++) p[L->w_off + i] *= 10.0f;
    void *bytes = NULL;
    ew_guidenet_save(&net, p, &bytes, size);
    free(p);
    return bytes;
}

typedef struct {
    int w, h;
    float *color, *albedo, *normal, *depth, *out;
} images;

static void images_make(images *im, int w, int h, unsigned seed) {
    const long n = (long)w * h;
    im->w = w; im->h = h;
    im->color = malloc(sizeof(float) * n * 3); im->albedo = malloc(sizeof(float) * n * 3);
    im->normal = malloc(sizeof(float) * n * 3); im->depth = malloc(sizeof(float) * n);
    im->out = malloc(sizeof(float) * n * 3);
    for (long i = 0; i < n * 3; i++) {
        im->color[i] = 2.0f * urand(&seed);
        im->albedo[i] = urand(&seed);
        im->normal[i] = 2.0f * urand(&seed) - 1.0f;
    }
    for (long i = 0; i < n; i++) im->depth[i] = 1.0f + 9.0f * urand(&seed);
}

static void images_free(images *im) {
    free(im->color); free(im->albedo); free(im->normal); free(im->depth); free(im->out);
}

/* Run nbg; weights NULL: the built-in model `model`. */
static ew_result run(ew_device *dev, images *im, const void *weights, size_t size, int model) {
    ew_denoiser *d = NULL;
    ew_image c = ew_image_packed(im->color, im->w, im->h, 3), a = ew_image_packed(im->albedo, im->w, im->h, 3);
    ew_image n = ew_image_packed(im->normal, im->w, im->h, 3), z = ew_image_packed(im->depth, im->w, im->h, 1);
    ew_image o = ew_image_packed(im->out, im->w, im->h, 3);
    ew_result r = ew_denoiser_create(dev, "nbg", &d);
    if (r == EW_OK && weights) r = ew_denoiser_set_data(d, "weights", weights, size);
    if (r == EW_OK && !weights) r = ew_denoiser_set_int(d, "model", model);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "color", &c);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "albedo", &a);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "normal", &n);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "depth", &z);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "output", &o);
    if (r == EW_OK) r = ew_denoiser_commit(d);
    if (r == EW_OK) r = ew_denoiser_execute(d);
    ew_denoiser_destroy(d);
    return r;
}

/* For any weights: blend weights sum to 1 and the grids average, so a
 * constant colour over a constant albedo comes back unchanged. */
static int constant_stays(const char *arch) {
    size_t size;
    void *w = random_weights(arch, 3, &size);
    images im;
    images_make(&im, 37, 29, 4);
    for (long j = 0; j < 37 * 29; j++)
        for (int k = 0; k < 3; k++) {
            im.color[j * 3 + k] = 0.3f + 0.2f * k;
            im.albedo[j * 3 + k] = 0.6f;
        }
    ew_device *dev = make_device(2);
    ew_result r = run(dev, &im, w, size, 0);
    double worst = 0;
    for (long j = 0; j < 37 * 29; j++)
        for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(im.out[j * 3 + k] - (0.3 + 0.2 * k)));
    ew_device_destroy(dev);
    images_free(&im);
    free(w);
    if (r != EW_OK || worst > 1e-5) fprintf(stderr, "  %s: result %d, worst %g\n", arch, r, worst);
    return r == EW_OK && worst <= 1e-5;
}

TEST(constant_image_stays_constant_2layer_3grid) { CHECK(constant_stays("2layer-3grid")); }
TEST(constant_image_stays_constant_2layer_1grid) { CHECK(constant_stays("2layer-1grid")); }
TEST(constant_image_stays_constant_7layer_3grid) { CHECK(constant_stays("7layer-3grid")); }

/* NaN / Inf colour samples, NaN features, black albedo under a bright
 * emitter-like block: every output sample is finite. */
TEST(outputs_are_finite) {
    size_t size;
    void *w = random_weights("2layer-3grid", 5, &size);
    images im;
    images_make(&im, 40, 33, 6);
    im.color[3 * 100] = NAN;
    im.color[3 * 101 + 1] = INFINITY;
    im.color[3 * 700 + 2] = -INFINITY;
    im.albedo[3 * 300] = NAN;
    im.normal[3 * 301] = NAN;
    im.depth[302] = NAN;
    im.depth[303] = 1e10f; /* Cycles' Depth pass on the background */
    for (int y = 10; y < 20; y++)
        for (int x = 5; x < 15; x++)
            for (int k = 0; k < 3; k++) {
                im.albedo[((long)y * 40 + x) * 3 + k] = 0.0f;
                im.color[((long)y * 40 + x) * 3 + k] = 50.0f;
            }
    ew_device *dev = make_device(2);
    CHECK_EQ_INT(run(dev, &im, w, size, 0), EW_OK);
    int finite = 1;
    for (long i = 0; i < 40 * 33 * 3; i++) finite &= isfinite(im.out[i]) != 0;
    ew_device_destroy(dev);
    images_free(&im);
    free(w);
    CHECK(finite);
}

/* Bands, rows and pixels are independent work: the same bits with 1 and 2
 * threads, on an image taller than one band. */
TEST(result_independent_of_thread_count) {
    size_t size;
    void *w = random_weights("2layer-3grid", 7, &size);
    images a, b;
    images_make(&a, 45, 150, 8);
    images_make(&b, 45, 150, 8);
    ew_device *d1 = make_device(1), *d2 = make_device(2);
    CHECK_EQ_INT(run(d1, &a, w, size, 0), EW_OK);
    CHECK_EQ_INT(run(d2, &b, w, size, 0), EW_OK);
    int same = memcmp(a.out, b.out, sizeof(float) * 45 * 150 * 3) == 0;
    ew_device_destroy(d1);
    ew_device_destroy(d2);
    images_free(&a);
    images_free(&b);
    free(w);
    CHECK(same);
}

TEST(errors_name_the_problem) {
    ew_device *dev = make_device(1);
    ew_denoiser *d = NULL;
    CHECK_EQ_INT(ew_denoiser_create(dev, "nbg", &d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_set_data(d, "weights", "not weights at all", 18), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "not an Edgewise weights file");
    CHECK_EQ_INT(ew_denoiser_set_data(d, "lut", "x", 1), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "takes data 'weights'");
    CHECK_EQ_INT(ew_denoiser_set_int(d, "model", EW_NBG_NUM_MODELS), EW_ERR_INVALID_ARGUMENT);
    /* weights of another kind of model */
    ew_tensor t;
    memset(&t, 0, sizeof t);
    strcpy(t.name, "x");
    float v = 1.0f;
    t.rank = 1; t.dims[0] = 1; t.count = 1; t.data = &v;
    ew_weights wt;
    memset(&wt, 0, sizeof wt);
    strcpy(wt.arch, "pyramid-v1");
    wt.num_tensors = 1;
    wt.tensors = &t;
    void *bytes;
    size_t size;
    ew_weights_serialize(&wt, &bytes, &size);
    CHECK_EQ_INT(ew_denoiser_set_data(d, "weights", bytes, size), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "not a neural bilateral grid");
    free(bytes);
    /* the features are inputs of the network: all are required */
    images im;
    images_make(&im, 8, 8, 1);
    ew_image c = ew_image_packed(im.color, 8, 8, 3), a = ew_image_packed(im.albedo, 8, 8, 3), o = ew_image_packed(im.out, 8, 8, 3);
    ew_image z = ew_image_packed(im.depth, 8, 8, 1);
    ew_denoiser_set_image(d, "color", &c);
    ew_denoiser_set_image(d, "albedo", &a);
    ew_denoiser_set_image(d, "depth", &z);
    ew_denoiser_set_image(d, "output", &o);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_ERR_INVALID_STATE);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "'normal'");
    ew_denoiser_destroy(d);
    images_free(&im);
    ew_device_destroy(dev);
}

static int cancel_at_half(void *user, double f) {
    (void)user;
    return f < 0.5;
}

TEST(progress_can_cancel) {
    size_t size;
    void *w = random_weights("2layer-1grid", 9, &size);
    images im;
    images_make(&im, 30, 200, 10);
    ew_device *dev = make_device(2);
    ew_denoiser *d = NULL;
    ew_image c = ew_image_packed(im.color, 30, 200, 3), a = ew_image_packed(im.albedo, 30, 200, 3);
    ew_image n = ew_image_packed(im.normal, 30, 200, 3), z = ew_image_packed(im.depth, 30, 200, 1);
    ew_image o = ew_image_packed(im.out, 30, 200, 3);
    ew_denoiser_create(dev, "nbg", &d);
    ew_denoiser_set_data(d, "weights", w, size);
    ew_denoiser_set_image(d, "color", &c);
    ew_denoiser_set_image(d, "albedo", &a);
    ew_denoiser_set_image(d, "normal", &n);
    ew_denoiser_set_image(d, "depth", &z);
    ew_denoiser_set_image(d, "output", &o);
    ew_denoiser_set_progress(d, cancel_at_half, NULL);
    CHECK_EQ_INT(ew_denoiser_commit(d), EW_OK);
    CHECK_EQ_INT(ew_denoiser_execute(d), EW_ERR_CANCELLED);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
    images_free(&im);
    free(w);
}

TEST(listed_with_its_parameters) {
    int found = 0;
    for (int32_t i = 0; i < ew_method_count("denoiser"); i++) {
        const char *name, *summary;
        int32_t ni, np;
        ew_method_get("denoiser", i, &name, &summary, &ni, &np);
        if (strcmp(name, "nbg") != 0) continue;
        found = 1;
        ew_param_info p;
        CHECK_EQ_INT(ew_method_param("denoiser", "nbg", 0, &p), EW_OK);
        CHECK(!strcmp(p.name, "model") && p.type == EW_PARAM_INT && p.max_value == EW_NBG_NUM_MODELS - 1);
        CHECK_STR_CONTAINS(p.hint, "2layer-3grid");
    }
    CHECK(found);
}

/* The models built into the library are byte-for-byte the files in
 * models/nbg/, and they run. */
TEST(built_in_models_are_the_shipped_files) {
    int any = 0;
    for (int m = 0; m < EW_NBG_NUM_MODELS; m++) {
        const unsigned char *bytes;
        size_t size;
        ew_nbg_builtin_weights(m, &bytes, &size);
        char path[1024];
        snprintf(path, sizeof path, "%s/nbg/%s.ewm", EW_MODELS_DIR, ew_nbg_model_name(m));
        FILE *f = fopen(path, "rb");
        if (!f) {
            CHECK_EQ_INT(size, 0); /* nothing built in without a file */
            continue;
        }
        unsigned char *file = malloc(size + 1);
        size_t got = fread(file, 1, size + 1, f);
        fclose(f);
        int same = got == size && memcmp(file, bytes, size) == 0;
        free(file);
        if (!same) fprintf(stderr, "  %s differs from the built-in copy: run train_nbg --emit-c\n", path);
        CHECK(same);
        /* saving the parsed model writes the same file: the format is unchanged */
        ew_weights w;
        char err[256];
        CHECK_EQ_INT(ew_weights_parse(bytes, size, &w, err, sizeof err), 0);
        ew_guidenet net;
        float *params = NULL;
        CHECK_EQ_INT(ew_guidenet_from_weights(&net, &w, &params, err, sizeof err), 0);
        void *again = NULL;
        size_t again_size = 0;
        CHECK_EQ_INT(ew_guidenet_save(&net, params, &again, &again_size), 0);
        CHECK(again_size == size && memcmp(again, bytes, size) == 0);
        free(again);
        free(params);
        ew_weights_free(&w);
        images im;
        images_make(&im, 24, 20, 11);
        ew_device *dev = make_device(2);
        CHECK_EQ_INT(run(dev, &im, NULL, 0, m), EW_OK);
        ew_device_destroy(dev);
        images_free(&im);
        any++;
    }
    if (!any) SKIP("no models/nbg/*.ewm in this tree");
}

/* Images smaller than a band, a kernel or a grid cell; and the output
 * written over the colour view. */
TEST(tiny_images_and_aliased_output) {
    size_t size;
    void *w = random_weights("7layer-3grid", 12, &size);
    const int dims[4][2] = {{1, 1}, {2, 3}, {5, 1}, {3, 17}};
    ew_device *dev = make_device(2);
    for (int k = 0; k < 4; k++) {
        images im;
        images_make(&im, dims[k][0], dims[k][1], 13 + k);
        free(im.out);
        im.out = im.color; /* aliasing: the op packs its inputs first */
        ew_result r = run(dev, &im, w, size, 0);
        int finite = 1;
        for (long i = 0; i < (long)dims[k][0] * dims[k][1] * 3; i++) finite &= isfinite(im.out[i]) != 0;
        im.out = malloc(1);
        images_free(&im);
        CHECK_EQ_INT(r, EW_OK);
        CHECK(finite);
    }
    ew_device_destroy(dev);
    free(w);
}

/* Run nbg with weights (NULL: the built-in default) under a memory budget,
 * the do-no-harm blend on or off, with a progress callback (or NULL); the
 * output goes to out; *what gets ew_denoiser_describe. */
static ew_result run_with(ew_device *dev, images *im, float *out, const void *weights, size_t size, int budget_mb,
                          int harm, ew_progress_fn progress, char *what, size_t len) {
    ew_denoiser *d = NULL;
    ew_image c = ew_image_packed(im->color, im->w, im->h, 3), a = ew_image_packed(im->albedo, im->w, im->h, 3);
    ew_image n = ew_image_packed(im->normal, im->w, im->h, 3), z = ew_image_packed(im->depth, im->w, im->h, 1);
    ew_image o = ew_image_packed(out, im->w, im->h, 3);
    ew_result r = ew_denoiser_create(dev, "nbg", &d);
    if (r == EW_OK && weights) r = ew_denoiser_set_data(d, "weights", weights, size);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "color", &c);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "albedo", &a);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "normal", &n);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "depth", &z);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "output", &o);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "max_memory_mb", budget_mb);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "do_no_harm", harm);
    if (r == EW_OK && progress) r = ew_denoiser_set_progress(d, progress, NULL);
    if (r == EW_OK) r = ew_denoiser_commit(d);
    if (r == EW_OK) r = ew_denoiser_execute(d);
    snprintf(what, len, "%s", r == EW_OK ? ew_denoiser_describe(d) : "");
    ew_denoiser_destroy(d);
    return r;
}

/* ... with the blend on, into im->out */
static ew_result run_budget(ew_device *dev, images *im, const void *weights, size_t size, int budget_mb, char *what,
                            size_t len) {
    return run_with(dev, im, im->out, weights, size, budget_mb, 1, NULL, what, len);
}

/* Weights of a random net whose grids have the given spatial rates. */
static void *weights_with_rates(const char *arch, const float *rates, size_t *size) {
    ew_guidenet net;
    char err[128];
    if (ew_guidenet_init(&net, arch, err, sizeof err)) return NULL;
    for (int g = 0; g < net.ngrids; g++) net.rate_s[g] = net.rate_d[g] = rates[g];
    float *p = malloc(sizeof(float) * net.nparams);
    ew_guidenet_random(&net, 21, p);
    const ew_gn_layer *L = &net.layers[net.nlayers - 1];
    for (size_t i = 0; i < (size_t)L->cin * L->cout * 25; i++) p[L->w_off + i] *= 10.0f;
    void *bytes = NULL;
    ew_guidenet_save(&net, p, &bytes, size);
    free(p);
    return bytes;
}

/* A frame larger than its tiles (tiles of three widths and two heights, a
 * firefly on a seam, a far background in one corner: the depth scale and
 * the clamp's removed light come from the whole frame) gives the same bits
 * tiled as in one pass, with the do-no-harm stage around it as a user runs
 * it; also with the output written over the colour view. */
static void tiles_case(const void *weights, size_t size, const char *name, int alias) {
    images im;
    images_make(&im, 613, 587, 31);
    const long n3 = 613L * 587 * 3;
    for (int y = 0; y < 40; y++)
        for (int x = 0; x < 50; x++) im.depth[(long)y * 613 + x] = 1e10f;
    im.color[(250L * 613 + 257) * 3 + 1] = 800.0f;
    im.color[(300L * 613 + 100) * 3] = 300.0f;
    float *color0 = malloc(sizeof(float) * n3), *whole = malloc(sizeof(float) * n3);
    memcpy(color0, im.color, sizeof(float) * n3);
    ew_device *dev = make_device(2);
    char what_whole[128], what_tiled[128];
    if (alias) {
        free(im.out);
        im.out = im.color;
    }
    CHECK_EQ_INT(run_budget(dev, &im, weights, size, 1024, what_whole, sizeof what_whole), EW_OK);
    memcpy(whole, im.out, sizeof(float) * n3);
    memcpy(im.color, color0, sizeof(float) * n3);
    CHECK_EQ_INT(run_budget(dev, &im, weights, size, 1, what_tiled, sizeof what_tiled), EW_OK); /* smallest tiles */
    fprintf(stderr, "  %s%s untiled: %s; tiled: %s\n", name, alias ? " (output over the colour)" : "", what_whole,
            what_tiled);
    CHECK(strstr(what_whole, "tiles") == NULL);
    CHECK_STR_CONTAINS(what_tiled, "x2 tiles"); /* seams across and down; 3x2 at this size */
    long differ = 0, first = 0;
    for (long i = 0; i < n3; i++)
        if (memcmp(&whole[i], &im.out[i], sizeof(float)) != 0 && differ++ == 0) first = i;
    if (differ)
        fprintf(stderr, "  %ld values differ, first at pixel (%ld, %ld): %.9g tiled vs %.9g\n", differ, first / 3 % 613,
                first / 3 / 613, (double)im.out[first], (double)whole[first]);
    CHECK(differ == 0);
    if (alias) im.out = malloc(1);
    images_free(&im);
    free(color0);
    free(whole);
    ew_device_destroy(dev);
}

TEST(tiles_give_the_untiled_output) {
    tiles_case(NULL, 0, "2layer-3grid (built in, rates 8/16/32)", 0);
    size_t size;
    void *w = random_weights("7layer-3grid", 5, &size); /* rates 4/8/16, a 14-pixel GuideNet reach */
    tiles_case(w, size, "7layer-3grid", 0);
    tiles_case(w, size, "7layer-3grid", 1);
    free(w);
    const float one[1] = {8.0f};
    w = weights_with_rates("2layer-1grid", one, &size);
    tiles_case(w, size, "2layer-1grid", 0);
    free(w);
}

/* Rates that are not powers of two have no exact tiling: such a model
 * runs whole whatever the budget. */
TEST(rates_without_an_exact_tiling_run_whole) {
    const float rates[3] = {6.0f, 12.0f, 24.0f};
    size_t size;
    void *w = weights_with_rates("2layer-3grid", rates, &size);
    images im;
    images_make(&im, 400, 300, 8);
    ew_device *dev = make_device(2);
    char what[128];
    CHECK_EQ_INT(run_budget(dev, &im, w, size, 1, what, sizeof what), EW_OK);
    CHECK(strstr(what, "tiles") == NULL);
    ew_device_destroy(dev);
    images_free(&im);
    free(w);
}

/* The op and its do-no-harm stage read packed float views in place
 * (colour, albedo, normal, depth) and copy any other layout: both give the
 * same bits, tiled and whole. */
/* nbg with the default model on these views under budget_mb; what it ran into what */
static ew_result run_views(ew_device *dev, const ew_image *c, const ew_image *a, const ew_image *nv, const ew_image *z,
                           const ew_image *o, int budget_mb, char *what, size_t what_size) {
    ew_denoiser *d = NULL;
    ew_result r = ew_denoiser_create(dev, "nbg", &d);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "color", c);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "albedo", a);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "normal", nv);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "depth", z);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "output", o);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "max_memory_mb", budget_mb);
    if (r == EW_OK) r = ew_denoiser_commit(d);
    if (r == EW_OK) r = ew_denoiser_execute(d);
    if (r == EW_OK) snprintf(what, what_size, "%s", ew_denoiser_describe(d));
    ew_denoiser_destroy(d);
    return r;
}

TEST(views_read_in_place_give_the_copies_output) {
    images im;
    enum { W = 613, H = 500 };
    images_make(&im, W, H, 17);
    const long n = (long)W * H;
    im.color[(100L * W + 258) * 3] = 400.0f;
    float *c4 = malloc(sizeof(float) * n * 4), *a4 = malloc(sizeof(float) * n * 4), *n4 = malloc(sizeof(float) * n * 4);
    float *z2 = malloc(sizeof(float) * n * 2), *ref = malloc(sizeof(float) * n * 3);
    for (long j = 0; j < n; j++) {
        for (int k = 0; k < 3; k++) {
            c4[j * 4 + k] = im.color[j * 3 + k];
            a4[j * 4 + k] = im.albedo[j * 3 + k];
            n4[j * 4 + k] = im.normal[j * 3 + k];
        }
        c4[j * 4 + 3] = a4[j * 4 + 3] = n4[j * 4 + 3] = -7.0f;
        z2[j * 2] = im.depth[j];
        z2[j * 2 + 1] = -7.0f;
    }
    ew_device *dev = make_device(2);
    for (int budget = 1024; budget >= 1; budget /= 1024) {
        char what[2][128];
        CHECK_EQ_INT(run_budget(dev, &im, NULL, 0, budget, what[0], sizeof what[0]), EW_OK);
        memcpy(ref, im.out, sizeof(float) * n * 3);
        /* the same pixels, 4 floats apart (2 for the depth): copied */
        ew_image c = ew_image_packed(c4, W, H, 3), a = ew_image_packed(a4, W, H, 3);
        ew_image nv = ew_image_packed(n4, W, H, 3), z = ew_image_packed(z2, W, H, 1);
        c.pixel_stride = a.pixel_stride = nv.pixel_stride = 16;
        z.pixel_stride = 8;
        c.row_stride = a.row_stride = nv.row_stride = 16 * W;
        z.row_stride = 8 * W;
        ew_image o = ew_image_packed(im.out, W, H, 3);
        memset(im.out, 0, sizeof(float) * n * 3);
        CHECK_EQ_INT(run_views(dev, &c, &a, &nv, &z, &o, budget, what[1], sizeof what[1]), EW_OK);
        fprintf(stderr, "  budget %d MiB: %s / %s\n", budget, what[0], what[1]);
        CHECK(strcmp(what[0], what[1]) == 0);
        if (budget == 1) CHECK_STR_CONTAINS(what[1], "tiles");
        CHECK(memcmp(ref, im.out, sizeof(float) * n * 3) == 0);
        /* an RGBA colour (alpha past RGB) into an RGBA output: the same RGB
         * (the do-no-harm stage hands the method its rejected colour as RGB)
         * and the colour's alpha */
        for (long j = 0; j < n; j++) c4[j * 4 + 3] = 0.5f;
        float *o4 = calloc((size_t)n * 4, sizeof(float));
        c = ew_image_packed(c4, W, H, 4);
        o = ew_image_packed(o4, W, H, 4);
        a = ew_image_packed(im.albedo, W, H, 3);
        nv = ew_image_packed(im.normal, W, H, 3);
        z = ew_image_packed(im.depth, W, H, 1);
        CHECK_EQ_INT(run_views(dev, &c, &a, &nv, &z, &o, budget, what[1], sizeof what[1]), EW_OK);
        long same = 0, alpha = 0;
        for (long j = 0; j < n; j++) {
            same += !memcmp(o4 + j * 4, ref + j * 3, 3 * sizeof(float));
            alpha += o4[j * 4 + 3] == 0.5f;
        }
        CHECK_EQ_INT((int)same, (int)n);
        CHECK_EQ_INT((int)alpha, (int)n); /* the colour's alpha, passed through */
        free(o4);
    }
    ew_device_destroy(dev);
    images_free(&im);
    free(c4); free(a4); free(n4); free(z2); free(ref);
}

/* A smooth frame (features of broad surfaces) with noise of relative
 * amplitude amp and fireflies the do-no-harm stage's rejection takes. */
static void smooth_images(images *im, int w, int h, float amp, unsigned seed) {
    images_make(im, w, h, seed);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const long j = (long)y * w + x;
            const int surface = (x / 97 + y / 89) % 3;
            for (int c = 0; c < 3; c++) {
                const float base = 0.3f + 0.2f * (float)surface + 0.1f * (float)c + 0.2f * (float)x / (float)w;
                im->color[j * 3 + c] = base * (1.0f + amp * (2.0f * urand(&seed) - 1.0f));
                im->albedo[j * 3 + c] = 0.4f + 0.15f * (float)surface;
                im->normal[j * 3 + c] = c == 2 ? 1.0f : 0.0f;
            }
            im->depth[j] = 2.0f + (float)surface;
        }
    for (int k = 0; k < 40; k++) {
        const long j = (long)(urand(&seed) * (float)(h - 1)) * w + (long)(urand(&seed) * (float)(w - 1));
        im->color[j * 3 + 1] = 900.0f;
    }
}

static char opts_what[128];

static ew_result run_opts(ew_device *dev, images *im, float *out, int budget_mb, int harm, ew_progress_fn progress) {
    return run_with(dev, im, out, NULL, 0, budget_mb, harm, progress, opts_what, sizeof opts_what);
}

/* With the output written over the colour (the CLI's denoise), the
 * do-no-harm stage runs inside nbg's tiles: it clamps the caller's colour
 * in place, nbg reads it where it is (what later tiles read of a core goes
 * out after them) and blends each core before it goes out. The same bits
 * as with the output apart (the stage around the method), tiled and whole,
 * on frames noisy enough that the blend fades out, quiet enough that the
 * pilot runs (before the method, on the clamped colour; each region takes
 * its estimate after the blend, over a margin grown by the estimate's
 * window: without that, 38822 values differ at the seams), and between.
 * That it ran in the tiles shows in a run cancelled half way: the colour
 * the tiles had not reached holds the clamped colour (around the method,
 * the caller's colour is read only). */
TEST(output_over_the_colour_runs_the_stage_in_the_tiles) {
    enum { W = 600, H = 640 };
    const long n3 = (long)W * H * 3;
    const float amps[3] = {0.05f, 0.2f, 0.5f};
    ew_device *dev = make_device(2);
    float *apart = malloc(sizeof(float) * n3), *off = malloc(sizeof(float) * n3), *keep = malloc(sizeof(float) * n3);
    int blended_in_tiles = 0;
    for (int a = 0; a < 3; a++) {
        images im;
        smooth_images(&im, W, H, amps[a], 40 + a);
        /* a firefly in the last rows, which a cancelled run's tiles do not reach */
        const long fly = ((long)(H - 20) * W + 300) * 3 + 1;
        im.color[fly] = 900.0f;
        memcpy(keep, im.color, sizeof(float) * n3);
        long blended = 0;
        for (int budget = 1024; budget >= 1; budget /= 1024) {
            CHECK_EQ_INT(run_opts(dev, &im, apart, budget, 1, NULL), EW_OK);
            if (budget == 1024) { /* whether the blend runs at all (the same bits in tiles) */
                CHECK_EQ_INT(run_opts(dev, &im, off, budget, 0, NULL), EW_OK);
                for (long i = 0; i < n3; i++) blended += memcmp(&apart[i], &off[i], sizeof(float)) != 0;
            }
            CHECK_EQ_INT(run_opts(dev, &im, im.color, budget, 1, cancel_at_half), EW_ERR_CANCELLED);
            const int in_tiles = im.color[fly] < 900.0f;
            memcpy(im.color, keep, sizeof(float) * n3);
            CHECK_EQ_INT(run_opts(dev, &im, im.color, budget, 1, NULL), EW_OK);
            long differ = 0;
            for (long i = 0; i < n3; i++) differ += memcmp(&apart[i], &im.color[i], sizeof(float)) != 0;
            fprintf(stderr, "  amplitude %.2f, %s: blend changed %ld values, stage %s; %ld differ\n", (double)amps[a],
                    opts_what, blended, in_tiles ? "in the tiles" : "around the method", differ);
            CHECK(differ == 0);
            if (budget == 1) CHECK_STR_CONTAINS(opts_what, "3x2 tiles"); /* seams across and down */
            blended_in_tiles += blended > 0 && in_tiles;
            memcpy(im.color, keep, sizeof(float) * n3);
        }
        images_free(&im);
    }
    CHECK(blended_in_tiles >= 4); /* the blend in the tiles, whole and tiled, with the pilot and without */
    free(apart);
    free(off);
    free(keep);
    ew_device_destroy(dev);
}

/* The tiles of a run, from what it ran ("..., 3x2 tiles"; none: 1) */
static int tiles_of(const char *what) {
    const char *t = strrchr(what, ',');
    int nx, ny;
    return t && sscanf(t, ", %dx%d tiles", &nx, &ny) == 2 ? nx * ny : 1;
}

/* While the stage holds the pilot's estimate through the method (the
 * output over the colour, a frame quiet enough for the pilot: halves of
 * T, 6 bytes a pixel), nbg plans its tiles at execute under max_memory_mb
 * less that: at some budget more tiles than with the output apart (where
 * nothing is held through the method), and the same bits. */
TEST(tiles_leave_room_for_the_pilots_estimate) {
    enum { W = 600, H = 640 };
    const long n3 = (long)W * H * 3;
    ew_device *dev = make_device(2);
    float *apart = malloc(sizeof(float) * n3), *keep = malloc(sizeof(float) * n3);
    images im;
    smooth_images(&im, W, H, 0.05f, 40);
    memcpy(keep, im.color, sizeof(float) * n3);
    int more = 0;
    for (int budget = 30; budget <= 64 && !more; budget += 2) { /* 30: 2x2 tiles, 2x3 beside the estimate */
        char what_apart[128];
        CHECK_EQ_INT(run_opts(dev, &im, apart, budget, 1, NULL), EW_OK);
        snprintf(what_apart, sizeof what_apart, "%s", opts_what);
        CHECK_EQ_INT(run_opts(dev, &im, im.color, budget, 1, NULL), EW_OK);
        if (tiles_of(opts_what) > tiles_of(what_apart)) {
            long differ = 0;
            for (long i = 0; i < n3; i++) differ += memcmp(&apart[i], &im.color[i], sizeof(float)) != 0;
            fprintf(stderr, "  %d MiB: output apart %s, over the colour %s; %ld values differ\n", budget, what_apart,
                    opts_what, differ);
            CHECK(differ == 0);
            more = 1;
        }
        memcpy(im.color, keep, sizeof(float) * n3);
    }
    CHECK(more);
    images_free(&im);
    free(apart);
    free(keep);
    ew_device_destroy(dev);
}
