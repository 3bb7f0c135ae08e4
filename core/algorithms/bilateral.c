/*
 * bilateral.c — packing and the brute-force / separable runs of the joint
 * bilateral filter (kernels/bilateral.h has the math).
 */
#include "algorithms/bilateral.h"

#include <math.h>

#include "src/backend.h"

long ew_bf_pack_image(const ew_image *img, int C, float *dst) {
    const int n = C < EW_BF_COLOR ? C : EW_BF_COLOR;
    long missing = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *p = ew__pixel(img, x, y);
            int ok = 1;
            for (int c = 0; c < C; c++) ok &= isfinite(p[c]) != 0;
            for (int c = 0; c < EW_BF_COLOR; c++) dst[c] = ok && c < n ? p[c] : 0.0f;
            dst[EW_BF_COLOR] = ok ? 1.0f : 0.0f;
            missing += !ok;
            dst += EW_BF_CH;
        }
    return missing;
}

long ew_bf_unpack_image(const float *src, int C, const ew_image *img, const ew_image *alpha_from) {
    const int n = C < EW_BF_COLOR ? C : EW_BF_COLOR;
    long zeroed = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = ew__pixel(img, x, y);
            const float mask = src[EW_BF_COLOR];
            const int ok = mask > 0.0f;
            for (int c = 0; c < n; c++) p[c] = ok ? src[c] / mask : 0.0f;
            if (C > EW_BF_COLOR && alpha_from) p[EW_BF_COLOR] = ew__pixel(alpha_from, x, y)[EW_BF_COLOR];
            zeroed += !ok;
            src += EW_BF_CH;
        }
    return zeroed;
}

static float clean(float v, long *bad) {
    if (isfinite(v)) return v;
    if (bad) (*bad)++;
    return 0.0f;
}

void ew_bf_pack_channels(const ew_image *view, int stride, float *attr, long *bad) {
    const int n = view->channels < stride ? view->channels : stride;
    long j = 0;
    for (int y = 0; y < view->height; y++)
        for (int x = 0; x < view->width; x++, j++) {
            const float *p = ew__pixel(view, x, y);
            for (int k = 0; k < stride; k++) attr[j * stride + k] = k < n ? clean(p[k], bad) : 0.0f;
        }
}

void ew_bf_pack_gi(const ew_image *normal, const ew_image *depth, const ew_image *roughness, float *attr,
                   long *bad) {
    const ew_image *any = normal ? normal : depth ? depth : roughness;
    if (!any) return;
    long j = 0;
    for (int y = 0; y < any->height; y++)
        for (int x = 0; x < any->width; x++, j++) {
            float *a = attr + j * 5;
            a[0] = a[1] = a[2] = 0.0f;
            if (normal) {
                const float *n = ew__pixel(normal, x, y);
                float n0 = clean(n[0], bad), n1 = clean(n[1], bad), n2 = clean(n[2], bad);
                float len = sqrtf(n0 * n0 + n1 * n1 + n2 * n2);
                if (len > 1e-6f) {
                    a[0] = n0 / len;
                    a[1] = n1 / len;
                    a[2] = n2 / len;
                }
            }
            a[3] = depth ? clean(*ew__pixel(depth, x, y), bad) : 0.0f;
            a[4] = roughness ? sqrtf(fminf(fmaxf(clean(*ew__pixel(roughness, x, y), bad), 0.0f), 1.0f)) : 1.0f;
        }
}

void ew_bilateral_brute_rows(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b) {
    dev->backend->bf_brute(dev, m, b);
}

void ew_bilateral_separable(ew_device *dev, const ew_bf_model *m, int w, int h, const float *image,
                            const float *attr, float *tmp, float *out) {
    ew_bf_buffers b = {w, h, image, attr, tmp, 0, h};
    dev->backend->bf_separable(dev, m, 0, &b);
    b.image = tmp;
    b.out = out;
    dev->backend->bf_separable(dev, m, 1, &b);
}
