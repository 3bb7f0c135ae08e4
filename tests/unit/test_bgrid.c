/* Splat and slice against a slow, obviously-correct reference: every cell
 * against every pixel, straight from Eq. 10-13 with the supplement's +0.5
 * biased coordinates. */
#include "ew_test.h"

#include <stdlib.h>

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
