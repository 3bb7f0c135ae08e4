/*
 * outlier.h — firefly suppression: a pixel whose luminance lies more than
 * k standard deviations above the mean of its (2r+1)^2 neighbourhood (itself
 * excluded, so one firefly cannot hide itself) is scaled down to that bound.
 * Low-sample path tracing has heavy-tailed noise; a few such samples would
 * otherwise be spread by any smoothing filter into visible blotches.
 * Non-finite neighbours are ignored; a non-finite pixel is left as it is
 * (later stages treat it as missing).
 */
#ifndef EW_KERNELS_OUTLIER_H
#define EW_KERNELS_OUTLIER_H

#include "kernels/color.h"

/* in/out: width*height*3 floats (out must not alias in). */
EW_HD void ew_outlier_clamp_px(int x, int y, int width, int height, int radius, float k,
                               const float *EW_RESTRICT in, float *EW_RESTRICT out) {
    const long j = (long)y * width + x;
    const float *p = in + j * 3;
    float *o = out + j * 3;
    o[0] = p[0];
    o[1] = p[1];
    o[2] = p[2];
    float lum = ew_luminance(p);
    if (!ew_finitef(lum) || lum <= 0.0f) return;
    float sum = 0.0f, sum2 = 0.0f;
    int n = 0;
    for (int yy = ew_maxi(y - radius, 0); yy <= ew_mini(y + radius, height - 1); yy++)
        for (int xx = ew_maxi(x - radius, 0); xx <= ew_mini(x + radius, width - 1); xx++) {
            if (xx == x && yy == y) continue;
            float l = ew_luminance(in + ((long)yy * width + xx) * 3);
            if (!ew_finitef(l)) continue;
            sum += l;
            sum2 += l * l;
            n++;
        }
    if (n < 3) return;
    float mean = sum / (float)n;
    float var = ew_maxf(sum2 / (float)n - mean * mean, 0.0f);
    float bound = mean + k * sqrtf(var);
    if (lum > bound) {
        float s = ew_maxf(bound, 0.0f) / lum;
        o[0] = p[0] * s;
        o[1] = p[1] * s;
        o[2] = p[2] * s;
    }
}

/*
 * Feature-aware outlier suppression (filter "outlier"). The same
 * test as above, but the neighbourhood statistics only count neighbours
 * that look like the same surface: albedo within albedo_tol (every channel,
 * absolute) and normal within normal_cos (cosine) of the pixel's own. A
 * bright pixel at the border of a bright material, or a small bright object
 * of its own albedo, is then compared with its own kind and kept; a firefly
 * inside a surface is compared with that surface and clamped.
 *   - the standard deviation is at least sigma_floor * |mean|, so plain
 *     noise within k * sigma_floor of a smooth surface's mean is never
 *     touched (a few neighbours can otherwise look much tighter than the
 *     noise is);
 *   - the statistics are of luminance differences to the first similar
 *     neighbour's (shifted data: no cancellation next to a 6e4 firefly, and a
 *     constant image stays exactly constant);
 *   - a pixel with fewer than EW_OUTLIER_MIN_SIMILAR similar finite
 *     neighbours is not judged (kept as it is);
 *   - a non-finite pixel (NaN/Inf in any channel) becomes the mean colour of
 *     its similar finite neighbours, else of all finite neighbours, else 0;
 *   - k <= 0 only repairs non-finite pixels;
 *   - a feature pass that is NULL, or non-finite at the pixel, is not used.
 */
#define EW_OUTLIER_MIN_SIMILAR 3

typedef struct ew_outlier_params {
    int width, height;
    int radius;       /* window (2r+1)^2 */
    float k;          /* bound = mean + k * standard deviation of the similar neighbours' luminance */
    float albedo_tol; /* neighbours whose albedo differs by more in any channel are not counted */
    float normal_cos; /* neighbours whose normal has a smaller cosine to the pixel's are not counted */
    float sigma_floor; /* smallest standard deviation, relative to the mean */
} ew_outlier_params;

typedef struct ew_outlier_buffers {
    const float *color;  /* channels per pixel, RGB first */
    const float *albedo; /* 3 per pixel or NULL */
    const float *normal; /* 3 per pixel or NULL */
    float *out;          /* channels per pixel; must not alias color */
    int channels;        /* floats per pixel of color and out, >= 3: the ones past RGB (alpha) are copied */
} ew_outlier_buffers;

EW_HD int ew_outlier_finite3(const float *v) { return ew_finitef(v[0]) && ew_finitef(v[1]) && ew_finitef(v[2]); }

/* Does neighbour k look like the same surface as pixel j? use_a/use_n:
 * whether pixel j's albedo/normal are usable. */
EW_HD int ew_outlier_similar(const ew_outlier_params *p, const ew_outlier_buffers *b, long j, long k, int use_a,
                             int use_n) {
    if (use_a) {
        const float *a0 = b->albedo + j * 3, *a1 = b->albedo + k * 3;
        for (int c = 0; c < 3; c++)
            if (!(fabsf(a0[c] - a1[c]) <= p->albedo_tol)) return 0; /* NaN: not similar */
    }
    if (use_n) {
        const float *n0 = b->normal + j * 3, *n1 = b->normal + k * 3;
        float l0 = n0[0] * n0[0] + n0[1] * n0[1] + n0[2] * n0[2];
        float l1 = n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2];
        if (!ew_finitef(l1)) return 0;
        if (l0 < 1e-12f || l1 < 1e-12f) return l0 < 1e-12f && l1 < 1e-12f; /* no surface (background) */
        float d = n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2];
        if (!(d >= p->normal_cos * sqrtf(l0 * l1))) return 0;
    }
    return 1;
}

EW_HD void ew_outlier_guided_px(int x, int y, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    const long j = (long)y * p->width + x, cc = b->channels;
    const float *c0 = b->color + j * cc;
    float *o = b->out + j * cc;
    const int finite = ew_outlier_finite3(c0);
    const float lum = finite ? ew_luminance(c0) : 0.0f;
    for (int c = 0; c < cc; c++) o[c] = c0[c];
    if (finite && (p->k <= 0.0f || lum <= 0.0f)) return; /* nothing to judge */
    const int use_a = b->albedo != 0 && ew_outlier_finite3(b->albedo + j * 3);
    const int use_n = b->normal != 0 && ew_outlier_finite3(b->normal + j * 3);
    float shift = 0.0f, sum = 0.0f, sum2 = 0.0f, rgb[3] = {0.0f, 0.0f, 0.0f}, any_rgb[3] = {0.0f, 0.0f, 0.0f};
    int n = 0, any = 0;
    for (int yy = ew_maxi(y - p->radius, 0); yy <= ew_mini(y + p->radius, p->height - 1); yy++)
        for (int xx = ew_maxi(x - p->radius, 0); xx <= ew_mini(x + p->radius, p->width - 1); xx++) {
            if (xx == x && yy == y) continue;
            const long k = (long)yy * p->width + xx;
            const float *c1 = b->color + k * cc;
            if (!ew_outlier_finite3(c1)) continue;
            if (!finite)
                for (int c = 0; c < 3; c++) any_rgb[c] += c1[c];
            any++;
            if (!ew_outlier_similar(p, b, j, k, use_a, use_n)) continue;
            if (n == 0) shift = ew_luminance(c1);
            const float l = ew_luminance(c1) - shift;
            sum += l;
            sum2 += l * l;
            if (!finite)
                for (int c = 0; c < 3; c++) rgb[c] += c1[c];
            n++;
        }
    if (!finite) { /* a missing sample: rebuilt from its surface, else its window */
        for (int c = 0; c < 3; c++)
            o[c] = n > 0 ? rgb[c] / (float)n : (any > 0 ? any_rgb[c] / (float)any : 0.0f);
        return;
    }
    if (n < EW_OUTLIER_MIN_SIMILAR) return;
    const float mean_d = sum / (float)n; /* mean - shift */
    const float var = ew_maxf(sum2 / (float)n - mean_d * mean_d, 0.0f);
    const float mean = shift + mean_d;
    const float bound = mean + p->k * ew_maxf(sqrtf(var), p->sigma_floor * fabsf(mean));
    if (lum > bound) {
        const float s = ew_maxf(bound, 0.0f) / lum;
        o[0] = c0[0] * s;
        o[1] = c0[1] * s;
        o[2] = c0[2] * s;
    }
}

#endif
