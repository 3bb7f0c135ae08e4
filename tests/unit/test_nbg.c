/* The "nbg" denoiser through the public API: weights from set_data and
 * built in, properties that hold for any weights (a constant image stays
 * constant, outputs are finite whatever the input), thread-count
 * independence, and its error messages. */
#include "ew_test.h"

#include <stdlib.h>

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
