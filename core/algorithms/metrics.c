/*
 * metrics.c — PSNR and SSIM on tone-mapped images (Wang et al. 2004 SSIM:
 * 11x11 Gaussian window, sigma 1.5, K1 = 0.01, K2 = 0.03, dynamic range 1).
 */
#include <math.h>
#include <stdlib.h>

#include "src/internal.h"

static float tonemap(float v) {
    if (!isfinite(v)) return 0.0f;
    return powf(v < 0.0f ? 0.0f : (v > 1.0f ? 1.0f : v), 1.0f / 2.2f);
}

/* A test sample as displayed: a non-finite one counts as the worst error,
 * the displayable value farthest from the reference's (so a NaN output is
 * never "identical" to a reference, even a NaN or black one). */
static float tonemap_test(float v, float ref_tm) {
    if (!isfinite(v)) return ref_tm < 0.5f ? 1.0f : 0.0f;
    return tonemap(v);
}

static ew_result check_pair(ew_device *dev, const ew_image *a, const ew_image *b, double *out, int *channels) {
    if (!dev) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(dev);
    const char *why;
    if (!out) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "metric output pointer is NULL");
    if (!ew__float_image_valid(a, &why)) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "test image: %s", why);
    if (!ew__float_image_valid(b, &why)) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "reference image: %s", why);
    if (a->width != b->width || a->height != b->height)
        return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "test image is %dx%d but reference is %dx%d", a->width,
                        a->height, b->width, b->height);
    int c = a->channels < b->channels ? a->channels : b->channels;
    *channels = c < 3 ? 1 : 3;
    return EW_OK;
}

ew_result ew_image_psnr(ew_device *dev, const ew_image *a, const ew_image *b, double *out) {
    int C;
    ew_result r = check_pair(dev, a, b, out, &C);
    if (r != EW_OK) return r;
    double se = 0.0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *pa = ew__pixel(a, x, y), *pb = ew__pixel(b, x, y);
            for (int c = 0; c < C; c++) {
                const float rt = tonemap(pb[c]);
                double d = (double)tonemap_test(pa[c], rt) - (double)rt;
                se += d * d;
            }
        }
    double mse = se / ((double)a->width * a->height * C);
    *out = mse > 0.0 ? 10.0 * log10(1.0 / mse) : INFINITY;
    return EW_OK;
}

/* Separable Gaussian blur of a w*h plane with clamped borders. */
static void blur(const float *src, float *tmp, float *dst, int w, int h, const float *k, int r) {
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float s = 0.0f;
            for (int i = -r; i <= r; i++) {
                int xx = x + i < 0 ? 0 : (x + i >= w ? w - 1 : x + i);
                s += k[i + r] * src[(size_t)y * w + xx];
            }
            tmp[(size_t)y * w + x] = s;
        }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float s = 0.0f;
            for (int i = -r; i <= r; i++) {
                int yy = y + i < 0 ? 0 : (y + i >= h ? h - 1 : y + i);
                s += k[i + r] * tmp[(size_t)yy * w + x];
            }
            dst[(size_t)y * w + x] = s;
        }
}

ew_result ew_image_ssim(ew_device *dev, const ew_image *a, const ew_image *b, double *out) {
    int C;
    ew_result r = check_pair(dev, a, b, out, &C);
    if (r != EW_OK) return r;
    const int w = a->width, h = a->height, R = 5;
    const size_t n = (size_t)w * h;
    float k[11], ks = 0.0f;
    for (int i = -R; i <= R; i++) ks += k[i + R] = expf(-(float)(i * i) / (2.0f * 1.5f * 1.5f));
    for (int i = 0; i < 2 * R + 1; i++) k[i] /= ks;
    float *buf = (float *)malloc(sizeof(float) * n * 11);
    if (!buf) return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory computing SSIM of %dx%d", w, h);
    float *X = buf, *Y = X + n, *XX = Y + n, *YY = XX + n, *XY = YY + n, *mx = XY + n, *my = mx + n,
          *sxx = my + n, *syy = sxx + n, *sxy = syy + n, *tmp = sxy + n;
    const double C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;
    double total = 0.0;
    for (int c = 0; c < C; c++) {
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t i = (size_t)y * w + x;
                Y[i] = tonemap(ew__pixel(b, x, y)[c]);
                X[i] = tonemap_test(ew__pixel(a, x, y)[c], Y[i]);
                XX[i] = X[i] * X[i];
                YY[i] = Y[i] * Y[i];
                XY[i] = X[i] * Y[i];
            }
        blur(X, tmp, mx, w, h, k, R);
        blur(Y, tmp, my, w, h, k, R);
        blur(XX, tmp, sxx, w, h, k, R);
        blur(YY, tmp, syy, w, h, k, R);
        blur(XY, tmp, sxy, w, h, k, R);
        double s = 0.0;
        for (size_t i = 0; i < n; i++) {
            double ux = mx[i], uy = my[i];
            double vx = sxx[i] - ux * ux, vy = syy[i] - uy * uy, cxy = sxy[i] - ux * uy;
            s += ((2 * ux * uy + C1) * (2 * cxy + C2)) / ((ux * ux + uy * uy + C1) * (vx + vy + C2));
        }
        total += s / (double)n;
    }
    free(buf);
    *out = total / C;
    return EW_OK;
}

typedef double (*pair_metric)(double t, double r);
static double relmse_term(double t, double r) { return (t - r) * (t - r) / (r * r + 0.01); }
static double smape_term(double t, double r) { return fabs(t - r) / (fabs(t) + fabs(r) + 0.01); }

/* Mean of a per-sample term over the first C channels; a non-finite test
 * sample counts as 0 (as in PSNR). */
static ew_result mean_term(ew_device *dev, const ew_image *a, const ew_image *b, double *out, pair_metric term) {
    int C;
    ew_result r = check_pair(dev, a, b, out, &C);
    if (r != EW_OK) return r;
    double sum = 0.0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *pa = ew__pixel(a, x, y), *pb = ew__pixel(b, x, y);
            for (int c = 0; c < C; c++) {
                double t = isfinite(pa[c]) ? pa[c] : 0.0, ref = isfinite(pb[c]) ? pb[c] : 0.0;
                sum += term(t, ref);
            }
        }
    *out = sum / ((double)a->width * a->height * C);
    return EW_OK;
}

ew_result ew_image_relmse(ew_device *dev, const ew_image *a, const ew_image *b, double *out) {
    return mean_term(dev, a, b, out, relmse_term);
}

ew_result ew_image_smape(ew_device *dev, const ew_image *a, const ew_image *b, double *out) {
    return mean_term(dev, a, b, out, smape_term);
}

/* Temporal stability of one pair of frames (edgewise.h). */
ew_result ew_image_temporal_diff(ew_device *dev, const ew_image *test_prev, const ew_image *test,
                                 const ew_image *reference_prev, const ew_image *reference, const ew_image *vector,
                                 float static_tol, ew_temporal_diff *out) {
    int C, C2, C3;
    ew_result r = check_pair(dev, test, reference, out ? &out->test : NULL, &C);
    if (r != EW_OK) return r;
    if ((r = check_pair(dev, test_prev, test, &out->test, &C2)) != EW_OK) return r;
    if ((r = check_pair(dev, reference_prev, reference, &out->test, &C3)) != EW_OK) return r;
    C = C < C2 ? C : C2;
    C = C < C3 ? C : C3;
    if (vector) {
        const char *why;
        if (!ew__float_image_valid(vector, &why)) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "vector image: %s", why);
        if (vector->channels < 2 || vector->width != test->width || vector->height != test->height)
            return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "vector image is %dx%d with %d channels; %dx%d with 2 needed",
                            vector->width, vector->height, vector->channels, test->width, test->height);
    }
    if (!(static_tol >= 0.0f)) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "static_tol must be >= 0");
    double dt = 0.0, dr = 0.0, ds = 0.0;
    int64_t ns = 0;
    for (int y = 0; y < test->height; y++)
        for (int x = 0; x < test->width; x++) {
            const float *t0 = ew__pixel(test_prev, x, y), *t1 = ew__pixel(test, x, y);
            const float *r0 = ew__pixel(reference_prev, x, y), *r1 = ew__pixel(reference, x, y);
            double pt = 0.0, pr = 0.0;
            int still = 1;
            for (int c = 0; c < C; c++) {
                double et = fabs((double)tonemap(t1[c]) - (double)tonemap(t0[c]));
                double er = fabs((double)tonemap(r1[c]) - (double)tonemap(r0[c]));
                pt += et;
                pr += er;
                still &= er < (double)static_tol;
            }
            if (vector) {
                const float *v = ew__pixel(vector, x, y);
                still &= isfinite(v[0]) && isfinite(v[1]) && v[0] * v[0] + v[1] * v[1] < 0.25f;
            }
            dt += pt;
            dr += pr;
            if (still) {
                ds += pt;
                ns++;
            }
        }
    const double n = (double)test->width * test->height * C;
    out->test = dt / n;
    out->reference = dr / n;
    out->excess = out->test - out->reference;
    out->static_flicker = ns ? ds / ((double)ns * C) : 0.0;
    out->static_pixels = ns;
    return EW_OK;
}
