/* The bilateral grid's analytic derivatives (kernels/bgrid_backward.h)
 * against central finite differences of a double-precision splat and slice
 * written straight from Eq. 10 and 13 with the supplement's +0.5 biased
 * coordinates: splat w.r.t. image and guide, slice w.r.t. grid and guide.
 * The maximum relative error of each is printed. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/bgrid.h"
#include "kernels/bgrid_backward.h"
#include "src/internal.h"

static double urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (double)((*s >> 8) & 0xffffff) / 16777216.0;
}

static double tent_d(double a) {
    double v = 1.0 - sqrt(a * a + 1e-7);
    return v > 0 ? v : 0;
}

/* weight of pixel (x, y) with guide g for cell (u, v, z) */
static double wgt(const ew_bgrid_params *p, int x, int y, double g, int u, int v, int z) {
    return tent_d((x + 0.5) / p->rate_s - (u + 0.5)) * tent_d((y + 0.5) / p->rate_s - (v + 0.5)) *
           tent_d(g / p->rate_d - (z + 0.5));
}

/* Eq. 10: grid (C values + weight per cell) in double */
static void splat_d(const ew_bgrid_params *p, const double *img, const double *guide, double *grid) {
    const int C = p->channels, S = C + 1;
    for (int v = 0; v < p->gh; v++)
        for (int u = 0; u < p->gw; u++)
            for (int z = 0; z < p->gd; z++) {
                double acc[5] = {0, 0, 0, 0, 0};
                for (int y = 0; y < p->height; y++)
                    for (int x = 0; x < p->width; x++) {
                        long j = (long)y * p->width + x;
                        double w = wgt(p, x, y, guide[j], u, v, z);
                        for (int c = 0; c < C; c++) acc[c] += w * img[j * C + c];
                        acc[C] += w;
                    }
                double *cell = grid + (((long)v * p->gw + u) * p->gd + z) * S;
                for (int c = 0; c < C; c++) cell[c] = acc[C] > 0 ? acc[c] / acc[C] : 0;
                cell[C] = acc[C];
            }
}

/* Eq. 13 over the non-empty cells, in double */
static void slice_d(const ew_bgrid_params *p, const double *grid, const double *guide, double *out) {
    const int C = p->channels, S = C + 1;
    for (int y = 0; y < p->height; y++)
        for (int x = 0; x < p->width; x++) {
            double acc[5] = {0, 0, 0, 0, 0};
            long j = (long)y * p->width + x;
            for (int v = 0; v < p->gh; v++)
                for (int u = 0; u < p->gw; u++)
                    for (int z = 0; z < p->gd; z++) {
                        const double *cell = grid + (((long)v * p->gw + u) * p->gd + z) * S;
                        if (cell[C] <= 0) continue;
                        double w = wgt(p, x, y, guide[j], u, v, z);
                        for (int c = 0; c < C; c++) acc[c] += w * cell[c];
                        acc[C] += w;
                    }
            for (int c = 0; c < C; c++) out[j * C + c] = acc[c] / acc[C];
        }
}

/* |analytic - numeric| relative to the larger of the two, with a floor of
 * 1% of the gradient's RMS: the float kernels cancel digits where a cell is
 * dominated by one pixel (I - G ~ 0), which says nothing about the formula. */
static double rel_err_floor(double a, double n, double floor_) {
    return fabs(a - n) / fmax(fmax(fabs(a), fabs(n)), floor_);
}

static double rms_f(const float *v, long n) {
    double s = 0;
    for (long i = 0; i < n; i++) s += (double)v[i] * v[i];
    return n ? sqrt(s / n) : 0;
}

typedef struct {
    ew_bgrid_params p;
    long n;
    size_t cells;
    double *img, *guide, *r;
    float *imgf, *guidef, *gridf;
} grid_case;

static void case_init(grid_case *k, int w, int h, float rs, float rd, int C, unsigned seed, int clustered) {
    ew_bgrid_params_init(&k->p, w, h, rs, rd, C);
    k->n = (long)w * h;
    k->cells = ew_bgrid_floats(&k->p);
    k->img = malloc(sizeof(double) * k->n * C);
    k->guide = malloc(sizeof(double) * k->n);
    k->imgf = malloc(sizeof(float) * k->n * C);
    k->guidef = malloc(sizeof(float) * k->n);
    k->gridf = malloc(sizeof(float) * k->cells);
    k->r = malloc(sizeof(double) * (k->cells > (size_t)(k->n * C) ? k->cells : (size_t)(k->n * C)));
    for (long i = 0; i < k->n * C; i++) k->imgf[i] = (float)(3.0 * urand(&seed));
    for (long i = 0; i < k->n; i++)
        /* clustered: two bands of guide values, so many cells stay empty */
        k->guidef[i] = (float)(clustered ? (urand(&seed) < 0.5 ? 40.0 : 180.0) + 30.0 * urand(&seed) : 255.0 * urand(&seed));
    for (long i = 0; i < k->n * C; i++) k->img[i] = k->imgf[i];
    for (long i = 0; i < k->n; i++) k->guide[i] = k->guidef[i];
}

static void case_free(grid_case *k) {
    free(k->img); free(k->guide); free(k->imgf); free(k->guidef); free(k->gridf); free(k->r);
}

/* L = sum over cell values of r * G */
static double splat_loss(const grid_case *k, double *grid) {
    splat_d(&k->p, k->img, k->guide, grid);
    const int C = k->p.channels, S = C + 1;
    double L = 0;
    for (size_t i = 0; i < k->cells; i++)
        if (i % S != (size_t)C) L += k->r[i] * grid[i];
    return L;
}

static int splat_backward_ok(int w, int h, float rs, float rd, int C, unsigned seed, int clustered) {
    grid_case k;
    case_init(&k, w, h, rs, rd, C, seed, clustered);
    const ew_bgrid_params *p = &k.p;
    const int S = C + 1;
    double *grid = malloc(sizeof(double) * k.cells);
    float *dgrid = malloc(sizeof(float) * k.cells), *dimg = malloc(sizeof(float) * k.n * C);
    float *dguide = calloc(k.n, sizeof(float));
    for (size_t i = 0; i < k.cells; i++) k.r[i] = i % S == (size_t)C ? 0.0 : 2.0 * urand(&seed) - 1.0;
    for (size_t i = 0; i < k.cells; i++) dgrid[i] = (float)k.r[i];
    for (int v = 0; v < p->gh; v++)
        for (int u = 0; u < p->gw; u++) ew_bgrid_splat_column(u, v, p, k.imgf, k.guidef, k.gridf);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) ew_bgrid_splat_backward_px(x, y, p, k.imgf, k.guidef, k.gridf, dgrid, &dguide[(long)y * w + x], dimg);
    double worst_i = 0, worst_g = 0;
    const double fi = 1e-2 * rms_f(dimg, k.n * C), fg = 1e-2 * rms_f(dguide, k.n);
    for (long j = 0; j < k.n; j++) {
        const double hs = 1e-4;
        for (int c = 0; c < C; c++) {
            double keep = k.img[j * C + c];
            k.img[j * C + c] = keep + hs; double lp = splat_loss(&k, grid);
            k.img[j * C + c] = keep - hs; double lm = splat_loss(&k, grid);
            k.img[j * C + c] = keep;
            worst_i = fmax(worst_i, rel_err_floor(dimg[j * C + c], (lp - lm) / (2 * hs), fi));
        }
        double keep = k.guide[j];
        k.guide[j] = keep + hs; double lp = splat_loss(&k, grid);
        k.guide[j] = keep - hs; double lm = splat_loss(&k, grid);
        k.guide[j] = keep;
        worst_g = fmax(worst_g, rel_err_floor(dguide[j], (lp - lm) / (2 * hs), fg));
    }
    fprintf(stderr, "  splat %dx%d rates (%g, %g)%s: max relative error vs finite differences: image %.2e, guide %.2e\n", w, h,
            (double)rs, (double)rd, clustered ? " clustered" : "", worst_i, worst_g);
    free(grid); free(dgrid); free(dimg); free(dguide);
    case_free(&k);
    return worst_i < 1e-3 && worst_g < 2e-3;
}

TEST(splat_backward_image_and_guide) { CHECK(splat_backward_ok(11, 9, 4, 16, 3, 1, 0)); }
TEST(splat_backward_fractional_rates) { CHECK(splat_backward_ok(9, 10, 2.5f, 5.5f, 3, 2, 0)); }
TEST(splat_backward_clustered_guides) { CHECK(splat_backward_ok(10, 8, 4, 8, 3, 3, 1)); }

/* L = sum r * R over pixels */
static double slice_loss(const grid_case *k, const double *grid, double *out) {
    slice_d(&k->p, grid, k->guide, out);
    double L = 0;
    for (long i = 0; i < k->n * k->p.channels; i++) L += k->r[i] * out[i];
    return L;
}

static int slice_backward_ok(int w, int h, float rs, float rd, int C, unsigned seed, int clustered) {
    grid_case k;
    case_init(&k, w, h, rs, rd, C, seed, clustered);
    const ew_bgrid_params *p = &k.p;
    const int S = C + 1;
    for (int v = 0; v < p->gh; v++)
        for (int u = 0; u < p->gw; u++) ew_bgrid_splat_column(u, v, p, k.imgf, k.guidef, k.gridf);
    /* slice with guides other than the splat's, so the derivative w.r.t.
     * the slice's guide is tested on its own */
    for (long j = 0; j < k.n; j++) {
        float g = k.guidef[j] + (float)(6.0 * urand(&seed) - 3.0);
        k.guidef[j] = g < 0 ? 0 : g;
        k.guide[j] = k.guidef[j];
    }
    double *grid = malloc(sizeof(double) * k.cells), *out = malloc(sizeof(double) * k.n * C);
    for (size_t i = 0; i < k.cells; i++) grid[i] = k.gridf[i];
    for (long i = 0; i < k.n * C; i++) k.r[i] = 2.0 * urand(&seed) - 1.0;
    float *dout = malloc(sizeof(float) * k.n * C), *dguide = malloc(sizeof(float) * k.n), *inv_eta = malloc(sizeof(float) * k.n);
    float *dgrid = malloc(sizeof(float) * k.cells);
    for (long i = 0; i < k.n * C; i++) dout[i] = (float)k.r[i];
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            ew_bgrid_slice_backward_px(x, y, p, k.gridf, k.guidef, dout, &dguide[(long)y * w + x], &inv_eta[(long)y * w + x]);
    for (int v = 0; v < p->gh; v++)
        for (int u = 0; u < p->gw; u++) ew_bgrid_slice_backward_column(u, v, p, k.gridf, k.guidef, dout, inv_eta, dgrid);
    const double hs = 1e-4;
    double worst_m = 0, worst_g = 0;
    const double fm = 1e-2 * rms_f(dgrid, (long)k.cells), fg = 1e-2 * rms_f(dguide, k.n);
    int tested = 0;
    for (size_t i = 0; i < k.cells; i++) {
        if (i % S == (size_t)C || grid[i - i % S + C] <= 0) continue; /* values of non-empty cells */
        double keep = grid[i];
        grid[i] = keep + hs; double lp = slice_loss(&k, grid, out);
        grid[i] = keep - hs; double lm = slice_loss(&k, grid, out);
        grid[i] = keep;
        worst_m = fmax(worst_m, rel_err_floor(dgrid[i], (lp - lm) / (2 * hs), fm));
        tested++;
    }
    for (long j = 0; j < k.n; j++) {
        double keep = k.guide[j];
        k.guide[j] = keep + hs; double lp = slice_loss(&k, grid, out);
        k.guide[j] = keep - hs; double lm = slice_loss(&k, grid, out);
        k.guide[j] = keep;
        worst_g = fmax(worst_g, rel_err_floor(dguide[j], (lp - lm) / (2 * hs), fg));
    }
    fprintf(stderr, "  slice %dx%d rates (%g, %g)%s: max relative error vs finite differences: grid %.2e (%d cells), guide %.2e\n",
            w, h, (double)rs, (double)rd, clustered ? " clustered" : "", worst_m, tested, worst_g);
    free(grid); free(out); free(dout); free(dguide); free(inv_eta); free(dgrid);
    case_free(&k);
    return tested > 0 && worst_m < 1e-3 && worst_g < 2e-3;
}

TEST(slice_backward_grid_and_guide) { CHECK(slice_backward_ok(11, 9, 4, 16, 3, 4, 0)); }
TEST(slice_backward_fractional_rates) { CHECK(slice_backward_ok(9, 10, 2.5f, 5.5f, 2, 5, 0)); }
TEST(slice_backward_clustered_guides) { CHECK(slice_backward_ok(10, 8, 4, 8, 3, 6, 1)); }

/* The tent's derivative, against differences, away from its kinks. */
TEST(tent_gradient) {
    const float as[] = {-0.93f, -0.5f, -0.01f, 0.003f, 0.4f, 0.97f, 1.2f};
    for (size_t i = 0; i < sizeof as / sizeof as[0]; i++) {
        double h = 1e-4;
        double fd = (tent_d(as[i] + h) - tent_d(as[i] - h)) / (2 * h);
        CHECK_NEAR(ew_tent_grad(as[i]), fd, 2e-3);
    }
}
