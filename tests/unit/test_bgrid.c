/* Splat and slice against a slow, obviously-correct reference: every cell
 * against every pixel, straight from Eq. 10-13 with the supplement's +0.5
 * biased coordinates. */
#include "ew_test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/bgrid.h"
#include "src/internal.h"

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

static double tent_ref(double a) {
    double v = 1.0 - sqrt(a * a + 1e-7);
    return v > 0 ? v : 0;
}

/* Eq. 10 with biased coordinates, for all cells; empty cells get weight 0. */
static void splat_ref(const ew_bgrid_params *p, const float *img, const float *guide, double *grid) {
    const int C = p->channels, S = C + 1;
    for (int v = 0; v < p->gh; v++)
        for (int u = 0; u < p->gw; u++)
            for (int z = 0; z < p->gd; z++) {
                double acc[5] = {0, 0, 0, 0, 0};
                for (int y = 0; y < p->height; y++)
                    for (int x = 0; x < p->width; x++) {
                        long j = (long)y * p->width + x;
                        int ok = isfinite(guide[j]);
                        for (int c = 0; c < C; c++) ok &= isfinite(img[j * C + c]) != 0;
                        if (!ok) continue;
                        double w = tent_ref((x + 0.5) / p->rate_s - (u + 0.5)) *
                                   tent_ref((y + 0.5) / p->rate_s - (v + 0.5)) *
                                   tent_ref(guide[j] / p->rate_d - (z + 0.5));
                        for (int c = 0; c < C; c++) acc[c] += w * img[j * C + c];
                        acc[C] += w;
                    }
                double *cell = grid + (((long)v * p->gw + u) * p->gd + z) * S;
                for (int c = 0; c < C; c++) cell[c] = acc[C] > 0 ? acc[c] / acc[C] : 0;
                cell[C] = acc[C];
            }
}

/* Eq. 13 over all non-empty cells. */
static void slice_ref(const ew_bgrid_params *p, const float *grid, const float *guide, double *out) {
    const int C = p->channels, S = C + 1;
    for (int y = 0; y < p->height; y++)
        for (int x = 0; x < p->width; x++) {
            double acc[5] = {0, 0, 0, 0, 0};
            double g = guide[(long)y * p->width + x];
            for (int v = 0; v < p->gh; v++)
                for (int u = 0; u < p->gw; u++)
                    for (int z = 0; z < p->gd; z++) {
                        const float *cell = grid + (((long)v * p->gw + u) * p->gd + z) * S;
                        if (cell[C] <= 0) continue;
                        double w = tent_ref((x + 0.5) / p->rate_s - (u + 0.5)) *
                                   tent_ref((y + 0.5) / p->rate_s - (v + 0.5)) *
                                   tent_ref(g / p->rate_d - (z + 0.5));
                        for (int c = 0; c < C; c++) acc[c] += w * cell[c];
                        acc[C] += w;
                    }
            for (int c = 0; c < C; c++) out[((long)y * p->width + x) * C + c] = acc[c] / acc[C];
        }
}

static ew_device *make_device(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

static int check_against_reference(int w, int h, float rs, float rd, int C, int threads, unsigned seed) {
    ew_bgrid_params p;
    if (!ew_bgrid_params_init(&p, w, h, rs, rd, C)) return 0;
    long n = (long)w * h;
    float *img = malloc(sizeof(float) * n * C), *guide = malloc(sizeof(float) * n);
    float *grid = malloc(sizeof(float) * ew_bgrid_floats(&p));
    double *grid_ref = malloc(sizeof(double) * ew_bgrid_floats(&p));
    float *out = malloc(sizeof(float) * n * C);
    double *out_ref = malloc(sizeof(double) * n * C);
    for (long i = 0; i < n * C; i++) img[i] = 4.0f * urand(&seed);
    for (long i = 0; i < n; i++) guide[i] = 255.0f * urand(&seed);
    guide[0] = 0.0f;   /* the range ends */
    guide[n - 1] = 255.0f;
    ew_device *dev = make_device(threads);
    ew_bgrid_splat(dev, &p, img, guide, grid);
    splat_ref(&p, img, guide, grid_ref);
    int ok = 1;
    double worst = 0;
    for (size_t i = 0; i < ew_bgrid_floats(&p); i++) {
        double tol = 1e-4 * (1.0 + fabs(grid_ref[i]));
        double e = fabs(grid[i] - grid_ref[i]);
        if (e > worst) worst = e;
        if (e > tol) ok = 0;
    }
    if (!ok) fprintf(stderr, "  splat differs: worst %g\n", worst);
    ew_bgrid_slice(dev, &p, grid, guide, out);
    slice_ref(&p, grid, guide, out_ref);
    worst = 0;
    for (long i = 0; i < n * C; i++) {
        double e = fabs(out[i] - out_ref[i]);
        if (e > worst) worst = e;
        if (e > 1e-4 * (1.0 + fabs(out_ref[i]))) ok = 0;
    }
    if (!ok) fprintf(stderr, "  slice differs: worst %g\n", worst);
    ew_device_destroy(dev);
    free(img); free(guide); free(grid); free(grid_ref); free(out); free(out_ref);
    return ok;
}

TEST(splat_slice_match_reference_rates_4_4) { CHECK(check_against_reference(23, 17, 4, 4, 3, 2, 1)); }
TEST(splat_slice_match_reference_rates_8_16) { CHECK(check_against_reference(40, 33, 8, 16, 3, 3, 2)); }
TEST(splat_slice_match_reference_fractional_rates) { CHECK(check_against_reference(19, 26, 2.5f, 5.5f, 2, 1, 3)); }
TEST(splat_slice_match_reference_one_channel_16) { CHECK(check_against_reference(50, 9, 16, 16, 1, 2, 4)); }
TEST(splat_slice_match_reference_rate_1) { CHECK(check_against_reference(7, 6, 1, 32, 4, 2, 5)); }

TEST(grid_size_follows_eq8) {
    ew_bgrid_params p;
    CHECK(ew_bgrid_params_init(&p, 256, 250, 8, 4, 3));
    CHECK_EQ_INT(p.gw, 32);
    CHECK_EQ_INT(p.gh, 32);
    CHECK_EQ_INT(p.gd, 64);
    CHECK(!ew_bgrid_params_init(&p, 0, 10, 8, 4, 3));
    CHECK(!ew_bgrid_params_init(&p, 10, 10, 0.5f, 4, 3));
    CHECK(!ew_bgrid_params_init(&p, 10, 10, 8, 4, 5));
}

/* Same result whatever the thread count: every splat work item fills its own
 * grid row (CPU) or column (kernels), so there are no races. */
TEST(result_independent_of_thread_count) {
    ew_bgrid_params p;
    CHECK(ew_bgrid_params_init(&p, 64, 48, 4, 8, 3));
    long n = 64 * 48;
    unsigned seed = 9;
    float *img = malloc(sizeof(float) * n * 3), *guide = malloc(sizeof(float) * n);
    float *g1 = malloc(sizeof(float) * ew_bgrid_floats(&p)), *g4 = malloc(sizeof(float) * ew_bgrid_floats(&p));
    for (long i = 0; i < n * 3; i++) img[i] = urand(&seed);
    for (long i = 0; i < n; i++) guide[i] = 255.0f * urand(&seed);
    ew_device *d1 = make_device(1), *d4 = make_device(4);
    ew_bgrid_splat(d1, &p, img, guide, g1);
    ew_bgrid_splat(d4, &p, img, guide, g4);
    int same = memcmp(g1, g4, sizeof(float) * ew_bgrid_floats(&p)) == 0;
    ew_device_destroy(d1); ew_device_destroy(d4);
    free(img); free(guide); free(g1); free(g4);
    CHECK(same);
}

TEST(constant_image_stays_constant) {
    ew_bgrid_params p;
    CHECK(ew_bgrid_params_init(&p, 37, 29, 8, 8, 3));
    long n = 37 * 29;
    unsigned seed = 11;
    float *img = malloc(sizeof(float) * n * 3), *guide = malloc(sizeof(float) * n), *out = malloc(sizeof(float) * n * 3);
    float *grid = malloc(sizeof(float) * ew_bgrid_floats(&p));
    for (long i = 0; i < n; i++) { img[i * 3] = 0.25f; img[i * 3 + 1] = 0.5f; img[i * 3 + 2] = 2.0f; }
    for (long i = 0; i < n; i++) guide[i] = 255.0f * urand(&seed);
    ew_device *dev = make_device(2);
    ew_bgrid_splat(dev, &p, img, guide, grid);
    ew_bgrid_slice(dev, &p, grid, guide, out);
    double worst = 0;
    for (long i = 0; i < n; i++) {
        worst = fmax(worst, fabs(out[i * 3] - 0.25));
        worst = fmax(worst, fabs(out[i * 3 + 1] - 0.5));
        worst = fmax(worst, fabs(out[i * 3 + 2] - 2.0));
    }
    ew_device_destroy(dev);
    free(img); free(guide); free(out); free(grid);
    CHECK_NEAR(worst, 0.0, 1e-5);
}

/* Two regions with guides far apart: values must not bleed across the edge,
 * even though the spatial kernel is 16 pixels wide. */
TEST(guide_keeps_edge_sharp) {
    const int w = 48, h = 32;
    ew_bgrid_params p;
    CHECK(ew_bgrid_params_init(&p, w, h, 8, 8, 1));
    float img[48 * 32], guide[48 * 32], out[48 * 32], *grid = malloc(sizeof(float) * ew_bgrid_floats(&p));
    unsigned seed = 5;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int left = x < 21;
            img[y * w + x] = (left ? 0.1f : 5.0f) + 0.02f * (urand(&seed) - 0.5f);
            guide[y * w + x] = left ? 40.0f : 200.0f;
        }
    ew_device *dev = make_device(2);
    ew_bgrid_splat(dev, &p, img, guide, grid);
    ew_bgrid_slice(dev, &p, grid, guide, out);
    ew_device_destroy(dev);
    free(grid);
    for (int y = 0; y < h; y++) {
        CHECK_NEAR(out[y * w + 20], 0.1, 0.011);
        CHECK_NEAR(out[y * w + 21], 5.0, 0.011);
    }
}

/* NaN/Inf pixels are skipped and refilled from their neighbourhood. */
TEST(non_finite_pixels_are_reconstructed) {
    const int w = 20, h = 20;
    ew_bgrid_params p;
    CHECK(ew_bgrid_params_init(&p, w, h, 4, 16, 3));
    float img[20 * 20 * 3], guide[20 * 20], out[20 * 20 * 3], *grid = malloc(sizeof(float) * ew_bgrid_floats(&p));
    for (int i = 0; i < w * h * 3; i++) img[i] = 1.0f;
    for (int i = 0; i < w * h; i++) guide[i] = 100.0f;
    img[3 * 50] = NAN;
    img[3 * 51 + 1] = INFINITY;
    img[3 * 52 + 2] = -INFINITY;
    guide[53] = NAN;
    ew_device *dev = make_device(2);
    ew_bgrid_splat(dev, &p, img, guide, grid);
    ew_bgrid_slice(dev, &p, grid, guide, out);
    ew_device_destroy(dev);
    free(grid);
    for (int i = 0; i < w * h * 3; i++) CHECK_NEAR(out[i], 1.0, 1e-5);
}

/* The CPU backend's row splat and slice (backends/cpu/cpu_bgrid.c) against
 * the kernels' per-column gather and per-pixel slice (what CUDA runs and the
 * trainer's reference): the same expressions added in the same order, so
 * the same bits — on widths that are not multiples of the SIMD width or of
 * the weights' run, fractional rates, guides at and beyond the range ends,
 * non-finite pixels and empty neighbourhoods (the slice's fallback). */
static int same_bits_as_kernels(int w, int h, float rs, float rd, int threads, unsigned seed) {
    ew_bgrid_params p;
    if (!ew_bgrid_params_init(&p, w, h, rs, rd, 3)) return 0;
    const long n = (long)w * h;
    const size_t gf = ew_bgrid_floats(&p);
    float *img = malloc(sizeof(float) * n * 3), *guide = malloc(sizeof(float) * n);
    float *grid = malloc(sizeof(float) * gf), *grid_k = malloc(sizeof(float) * gf);
    float *out = malloc(sizeof(float) * n * 3), *out_k = malloc(sizeof(float) * n * 3);
    for (long i = 0; i < n * 3; i++) img[i] = 8.0f * urand(&seed) - 0.5f;
    for (long i = 0; i < n; i++) {
        /* clustered guides, so some cells are empty next to full ones */
        float r = urand(&seed);
        guide[i] = r < 0.45f ? 30.0f + 10.0f * urand(&seed) : (r < 0.9f ? 200.0f + 20.0f * urand(&seed) : 255.0f * urand(&seed));
    }
    guide[0] = 0.0f;
    guide[n - 1] = 255.0f;
    guide[n / 2] = NAN;
    guide[n / 3] = -3.0f;
    img[3 * (n / 4)] = INFINITY;
    img[3 * (n / 5) + 2] = NAN;
    ew_device *dev = make_device(threads);
    ew_bgrid_splat(dev, &p, img, guide, grid);
    for (int v = 0; v < p.gh; v++)
        for (int u = 0; u < p.gw; u++) ew_bgrid_splat_column(u, v, &p, img, guide, grid_k);
    int ok = memcmp(grid, grid_k, sizeof(float) * gf) == 0;
    if (!ok) fprintf(stderr, "  %dx%d rates %g/%g: splat differs from the kernel\n", w, h, rs, rd);
    ew_bgrid_slice(dev, &p, grid_k, guide, out);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) ew_bgrid_slice_px(x, y, &p, grid_k, guide, out_k + ((long)y * w + x) * 3);
    if (memcmp(out, out_k, sizeof(float) * n * 3) != 0) {
        fprintf(stderr, "  %dx%d rates %g/%g: slice differs from the kernel\n", w, h, rs, rd);
        ok = 0;
    }
    ew_device_destroy(dev);
    free(img); free(guide); free(grid); free(grid_k); free(out); free(out_k);
    return ok;
}

TEST(cpu_rows_are_the_kernels_bits) {
    CHECK(same_bits_as_kernels(301, 37, 4, 4, 2, 21));
    CHECK(same_bits_as_kernels(517, 23, 8, 8, 1, 22));
    CHECK(same_bits_as_kernels(70, 71, 16, 16, 3, 23));
    CHECK(same_bits_as_kernels(45, 19, 2.5f, 5.5f, 2, 24));
    CHECK(same_bits_as_kernels(33, 40, 3, 255, 2, 25)); /* one depth cell */
    CHECK(same_bits_as_kernels(9, 7, 1, 32, 2, 26));
    CHECK(same_bits_as_kernels(260, 12, 32, 32, 2, 27));
}

/* ---- the denoiser in bands of rows ----------------------------------------- */
typedef struct {
    int w, h, stride; /* stride: floats a pixel of the colour, albedo and normal views (3: packed) */
    float *color, *albedo, *normal, *depth, *out;
} frame;

/* An odd-sized frame with edges across the bands (a lit region whose
 * albedo and normal change at x = w / 2 and at y = h / 3), noise of
 * relative amplitude amp, a far background (depth 1e10) in one corner,
 * fireflies near band seams and a NaN sample. */
static void frame_make_amp(frame *f, int w, int h, int stride, unsigned seed, float amp) {
    const long n = (long)w * h;
    f->w = w;
    f->h = h;
    f->stride = stride;
    f->color = calloc((size_t)n * stride, sizeof(float));
    f->albedo = calloc((size_t)n * stride, sizeof(float));
    f->normal = calloc((size_t)n * stride, sizeof(float));
    f->depth = calloc((size_t)n * (stride > 3 ? 2 : 1), sizeof(float));
    f->out = calloc((size_t)n * 3, sizeof(float));
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const long j = (long)y * w + x;
            const int right = x > w / 2, low = y > h / 3;
            for (int k = 0; k < 3; k++) {
                const float alb = right ? 0.2f + 0.2f * k : 0.8f - 0.1f * k;
                const float light = (low ? 0.3f : 1.5f) + 0.7f * (float)y / (float)h;
                f->albedo[j * stride + k] = alb;
                f->color[j * stride + k] = alb * light * (1.0f + amp * (2.0f * urand(&seed) - 1.0f));
            }
            f->normal[j * stride + 0] = right ? 1.0f : 0.0f;
            f->normal[j * stride + 1] = low ? 0.3f : 0.0f;
            f->normal[j * stride + 2] = right ? 0.0f : 1.0f;
            f->depth[j * (stride > 3 ? 2 : 1)] = x < 60 && y < 50 ? 1e10f : 2.0f + (right ? 1.0f : 0.0f) + 0.001f * y;
        }
    f->color[(100L * w + 150) * stride + 1] = 800.0f;
    f->color[(257L * w + 40) * stride] = 300.0f;
    f->color[(33L * w + 300) * stride + 2] = NAN;
}

static void frame_make(frame *f, int w, int h, int stride, unsigned seed) { frame_make_amp(f, w, h, stride, seed, 0.8f); }

static void frame_free(frame *f) {
    if (f->out != f->color) free(f->out);
    free(f->color); free(f->albedo); free(f->normal); free(f->depth);
}

static ew_image view_of(float *data, const frame *f, int channels, int stride) {
    ew_image v = ew_image_packed(data, f->w, f->h, channels);
    v.pixel_stride = (int64_t)stride * (int64_t)sizeof(float);
    v.row_stride = v.pixel_stride * f->w;
    return v;
}

static ew_progress_fn run_progress; /* run_bgrid's progress callback, or NULL */

static int cancel_at_half(void *user, double f) {
    (void)user;
    return f < 0.5;
}

/* One denoise of f under a budget; what it ran (ew_denoiser_describe). */
static ew_result run_bgrid(ew_device *dev, frame *f, int features, const float rates[4], float k, int stage,
                           int budget_mb, char *what, size_t len) {
    ew_denoiser *d = NULL;
    const int s = f->stride;
    ew_image c = view_of(f->color, f, s, s), a = view_of(f->albedo, f, s, s), n = view_of(f->normal, f, s, s);
    ew_image z = view_of(f->depth, f, s > 3 ? 2 : 1, s > 3 ? 2 : 1);
    ew_image o = f->out == f->color ? c : ew_image_packed(f->out, f->w, f->h, 3);
    ew_result r = ew_denoiser_create(dev, "bgrid", &d);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "color", &c);
    if (r == EW_OK && features) r = ew_denoiser_set_image(d, "albedo", &a);
    if (r == EW_OK && features) r = ew_denoiser_set_image(d, "normal", &n);
    if (r == EW_OK && features) r = ew_denoiser_set_image(d, "depth", &z);
    if (r == EW_OK) r = ew_denoiser_set_image(d, "output", &o);
    if (r == EW_OK) r = ew_denoiser_set_float(d, "spatial_rate", rates[0]);
    if (r == EW_OK) r = ew_denoiser_set_float(d, "range_rate", rates[1]);
    if (r == EW_OK) r = ew_denoiser_set_float(d, "prepass_rate", rates[2]);
    if (r == EW_OK) r = ew_denoiser_set_float(d, "color_weight", rates[3]);
    if (r == EW_OK) r = ew_denoiser_set_float(d, "firefly_k", k);
    if (r == EW_OK) r = ew_denoiser_set_int(d, "max_memory_mb", budget_mb);
    if (r == EW_OK && !stage) r = ew_denoiser_set_float(d, "outlier_k", 0.0f); /* the method reads the caller's colour */
    if (r == EW_OK && !stage) r = ew_denoiser_set_int(d, "do_no_harm", 0);
    if (r == EW_OK && run_progress) r = ew_denoiser_set_progress(d, run_progress, NULL);
    if (r == EW_OK) r = ew_denoiser_commit(d);
    if (r == EW_OK) r = ew_denoiser_execute(d);
    const char *dsc = r == EW_OK ? ew_denoiser_describe(d) : NULL;
    snprintf(what, len, "%s", dsc ? dsc : "");
    ew_denoiser_destroy(d);
    return r;
}

/* A frame in bands of rows (the smallest: 16-row cores, so dozens of seams,
 * every one with its halo clipped differently from its neighbours') gives
 * the same bits as in one pass: the halo covers what a core row's two
 * grids and the clamp read, the depth scale and the first pass's mean come
 * from every row, and the stage's removed light from each band's core.
 * Features or none, both passes or one, fractional rates, views packed
 * (read in place) or of 4 floats a pixel (packed band by band), and the
 * output written over the colour view. */
static void bands_case(const char *name, int stride, int features, const float rates[4], float k, int alias,
                       int stage) {
    frame f;
    frame_make(&f, 613, 587, stride, 31);
    const long n3 = 613L * 587 * 3;
    const size_t cbytes = sizeof(float) * (size_t)613 * 587 * stride;
    float *color0 = malloc(cbytes), *whole = malloc(sizeof(float) * n3);
    memcpy(color0, f.color, cbytes);
    if (alias) {
        CHECK(stride == 3);
        free(f.out);
        f.out = f.color;
    }
    ew_device *dev = make_device(2);
    char what_whole[96], what_bands[96];
    CHECK_EQ_INT(run_bgrid(dev, &f, features, rates, k, stage, 1024, what_whole, sizeof what_whole), EW_OK);
    memcpy(whole, f.out, sizeof(float) * n3);
    memcpy(f.color, color0, cbytes);
    CHECK_EQ_INT(run_bgrid(dev, &f, features, rates, k, stage, 1, what_bands, sizeof what_bands), EW_OK);
    fprintf(stderr, "  %s: whole '%s', in bands '%s'\n", name, what_whole, what_bands);
    CHECK(strstr(what_whole, "bands") == NULL);
    CHECK_STR_CONTAINS(what_bands, "bands");
    long differ = 0, first = 0;
    for (long i = 0; i < n3; i++)
        if (memcmp(&whole[i], &f.out[i], sizeof(float)) != 0 && differ++ == 0) first = i;
    if (differ)
        fprintf(stderr, "  %ld values differ, first at pixel (%ld, %ld): %.9g in bands vs %.9g\n", differ,
                first / 3 % 613, first / 3 / 613, (double)f.out[first], (double)whole[first]);
    CHECK(differ == 0);
    frame_free(&f);
    free(color0);
    free(whole);
    ew_device_destroy(dev);
}

TEST(bands_give_the_whole_frame_output) {
    const float defaults[4] = {8.0f, 8.0f, 8.0f, 0.7f}, finest[4] = {2.0f, 4.0f, 4.0f, 0.9f};
    const float fractional[4] = {2.5f, 5.5f, 3.3f, 0.5f}, one_pass[4] = {4.0f, 16.0f, 8.0f, 0.0f};
    bands_case("defaults, features", 3, 1, defaults, 3.0f, 0, 1);
    bands_case("auto's finest grid, features", 3, 1, finest, 3.0f, 0, 1);
    bands_case("fractional rates, no features, no clamp", 3, 0, fractional, 0.0f, 0, 1);
    bands_case("one pass, 4-float views", 4, 1, one_pass, 3.0f, 0, 1);
    bands_case("auto's finest grid, 4-float views", 4, 1, finest, 3.0f, 0, 1);
    bands_case("defaults, output over the colour", 3, 1, defaults, 3.0f, 1, 1);
    bands_case("no features, output over the colour", 3, 0, finest, 3.0f, 1, 1);
    /* without the stage the method reads the caller's colour itself */
    bands_case("no stage, packed views", 3, 1, finest, 3.0f, 0, 0);
    bands_case("no stage, 4-float views", 4, 1, defaults, 3.0f, 0, 0);
    bands_case("no stage, output over the colour", 3, 1, finest, 3.0f, 1, 0);
}

/* With the output written over the colour (the CLI's denoise), the
 * do-no-harm stage runs in bgrid's bands (or over its whole frame): it
 * clamps the caller's colour in place, the bands read it where it is (what
 * the next band reads of a core goes out after it) and each band is blended
 * before it goes out. The same bits as with the output apart (the stage
 * around the method), whole and in bands (more rows than the halo: the
 * colour read in place; fewer: a copy of it), on a noisy frame and on
 * frames quiet enough for the blend and for the pilot (whose estimate each
 * band takes over a margin the halo holds). That it ran in the bands shows
 * in a run cancelled half way: a firefly in rows the bands had not reached
 * is clamped in the caller's colour (around the method it is read only). */
TEST(output_over_the_colour_runs_the_stage_in_the_bands) {
    const float defaults[4] = {8.0f, 8.0f, 8.0f, 0.7f}, finest[4] = {2.0f, 4.0f, 4.0f, 0.9f};
    const float amps[3] = {0.8f, 0.1f, 0.02f};
    const long n3 = 613L * 587 * 3;
    ew_device *dev = make_device(2);
    float *apart = malloc(sizeof(float) * n3), *color0 = malloc(sizeof(float) * n3);
    /* each frame whole, in bands longer than the halo (12 MiB) and shorter
     * (1 MiB), but for the quiet ones, where the pilot's run is most of the
     * time (several seconds a run under the sanitizers), two of those */
    const int budgets[3][3] = {{1024, 12, 1}, {12, 1, 0}, {1024, 12, 0}};
    for (int a = 0; a < 3; a++)
        for (int bi = 0; bi < 3 && budgets[a][bi]; bi++) {
            const int budget = budgets[a][bi];
            const float *rates = a == 1 ? finest : defaults;
            frame f;
            frame_make_amp(&f, 613, 587, 3, 31 + a, amps[a]);
            const long fly = (570L * 613 + 300) * 3 + 1;
            f.color[fly] = 900.0f;
            memcpy(color0, f.color, sizeof(float) * n3);
            char what_apart[96], what_over[96];
            CHECK_EQ_INT(run_bgrid(dev, &f, 1, rates, 3.0f, 1, budget, what_apart, sizeof what_apart), EW_OK);
            memcpy(apart, f.out, sizeof(float) * n3);
            free(f.out);
            f.out = f.color;
            if (budget == 12) {
                run_progress = cancel_at_half;
                CHECK_EQ_INT(run_bgrid(dev, &f, 1, rates, 3.0f, 1, budget, what_over, sizeof what_over),
                             EW_ERR_CANCELLED);
                run_progress = NULL;
                CHECK(f.color[fly] < 900.0f);
                memcpy(f.color, color0, sizeof(float) * n3);
            }
            CHECK_EQ_INT(run_bgrid(dev, &f, 1, rates, 3.0f, 1, budget, what_over, sizeof what_over), EW_OK);
            long differ = 0, moved = 0;
            for (long i = 0; i < n3; i++) {
                differ += memcmp(&apart[i], &f.out[i], sizeof(float)) != 0;
                moved += memcmp(&color0[i], &f.out[i], sizeof(float)) != 0;
            }
            fprintf(stderr, "  amplitude %.2f, %s (output apart: %s): %ld values differ (%ld changed)\n",
                    (double)amps[a], what_over[0] ? what_over : "whole", what_apart[0] ? what_apart : "whole", differ,
                    moved);
            CHECK(differ == 0);
            CHECK(moved > n3 / 2);
            CHECK(budget < 1024 ? strstr(what_over, "bands") != NULL : strstr(what_over, "bands") == NULL);
            frame_free(&f);
        }
    free(apart);
    free(color0);
    ew_device_destroy(dev);
}

static int bands_of(const char *what) {
    int bands = 1;
    sscanf(what, "bgrid, %d bands", &bands);
    return bands;
}

/* While the stage holds the pilot's estimate through the method (the
 * output over the colour, a frame quiet enough for the pilot: halves of
 * T, 6 bytes a pixel), bgrid plans its bands at execute under
 * max_memory_mb less that: at some budget more bands than on a noisy frame
 * (no pilot) of the same size, with cores as tall as the halo or taller
 * (the colour read in place), and the bits of the output apart. */
TEST(bands_leave_room_for_the_pilots_estimate) {
    const float defaults[4] = {8.0f, 8.0f, 8.0f, 0.7f};
    const int halo = 16 + 16 + 2 + 9; /* the grids' reach, the clamp's, the blend's with the pilot's */
    const long n3 = 613L * 587 * 3;
    ew_device *dev = make_device(2);
    float *apart = malloc(sizeof(float) * n3);
    int more = 0;
    for (int budget = 13; budget <= 64 && !more; budget++) { /* 13: 5 bands, 9 beside the estimate */
        char what[2][96], what_apart[96];
        for (int q = 0; q < 2; q++) {
            frame f;
            frame_make_amp(&f, 613, 587, 3, 33, q ? 0.02f : 0.8f);
            if (q) {
                CHECK_EQ_INT(run_bgrid(dev, &f, 1, defaults, 3.0f, 1, budget, what_apart, sizeof what_apart), EW_OK);
                memcpy(apart, f.out, sizeof(float) * n3);
            }
            free(f.out);
            f.out = f.color;
            CHECK_EQ_INT(run_bgrid(dev, &f, 1, defaults, 3.0f, 1, budget, what[q], sizeof what[q]), EW_OK);
            if (q && bands_of(what[1]) > bands_of(what[0]) && 587 / bands_of(what[1]) >= halo) {
                long differ = 0;
                for (long i = 0; i < n3; i++) differ += memcmp(&apart[i], &f.out[i], sizeof(float)) != 0;
                fprintf(stderr, "  %d MiB: noisy '%s', quiet '%s'; %ld values differ from the output apart\n", budget,
                        what[0], what[1], differ);
                CHECK(differ == 0);
                more = 1;
            }
            frame_free(&f);
        }
    }
    CHECK(more);
    free(apart);
    ew_device_destroy(dev);
}
