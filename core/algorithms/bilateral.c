/*
 * bilateral.c — packing and the brute-force / separable runs of the joint
 * bilateral filter (kernels/bilateral.h has the math).
 */
#include "algorithms/bilateral.h"

#include <math.h>

#include "src/backend.h"

/* The packers write element k of pixel j at dst[k * ks + j * js]:
 * interleaved (ks 1, js = floats a pixel) or planes (ks = plane size, js 1).
 * Rows are walked with their own pointer (views may have any strides). */
static const float *row_of(const ew_image *img, int y) {
    return (const float *)(const void *)((const char *)img->data + (int64_t)y * ew__row_stride(img));
}

static long pack_image(const ew_image *img, int C, float *dst, size_t ks, size_t js) {
    const int n = C < EW_BF_COLOR ? C : EW_BF_COLOR;
    const int64_t ps = ew__pixel_stride(img);
    long missing = 0;
    size_t j = 0;
    for (int y = 0; y < img->height; y++) {
        const char *row = (const char *)row_of(img, y);
        for (int x = 0; x < img->width; x++, j++) {
            const float *p = (const float *)(const void *)(row + (int64_t)x * ps);
            int ok = 1;
            for (int c = 0; c < C; c++) ok &= isfinite(p[c]) != 0;
            for (int c = 0; c < EW_BF_COLOR; c++) dst[(size_t)c * ks + j * js] = ok && c < n ? p[c] : 0.0f;
            dst[EW_BF_COLOR * ks + j * js] = ok ? 1.0f : 0.0f;
            missing += !ok;
        }
    }
    return missing;
}

long ew_bf_pack_image(const ew_image *img, int C, float *dst) { return pack_image(img, C, dst, 1, EW_BF_CH); }

long ew_bf_pack_image_planes(const ew_image *img, int C, float *dst) {
    return pack_image(img, C, dst, (size_t)img->width * (size_t)img->height, 1);
}

static long unpack_image(const float *src, size_t ks, size_t js, int C, const ew_image *img,
                         const ew_image *alpha_from) {
    const int n = C < EW_BF_COLOR ? C : EW_BF_COLOR;
    const int64_t ps = ew__pixel_stride(img);
    long zeroed = 0;
    size_t j = 0;
    for (int y = 0; y < img->height; y++) {
        char *row = (char *)img->data + (int64_t)y * ew__row_stride(img);
        for (int x = 0; x < img->width; x++, j++) {
            float *p = (float *)(void *)(row + (int64_t)x * ps);
            const float mask = src[EW_BF_COLOR * ks + j * js];
            const int ok = mask > 0.0f;
            for (int c = 0; c < n; c++) p[c] = ok ? src[(size_t)c * ks + j * js] / mask : 0.0f;
            if (C > EW_BF_COLOR && alpha_from) p[EW_BF_COLOR] = ew__pixel(alpha_from, x, y)[EW_BF_COLOR];
            zeroed += !ok;
        }
    }
    return zeroed;
}

long ew_bf_unpack_image(const float *src, int C, const ew_image *img, const ew_image *alpha_from) {
    return unpack_image(src, 1, EW_BF_CH, C, img, alpha_from);
}

long ew_bf_unpack_image_planes(const float *src, int C, const ew_image *img, const ew_image *alpha_from) {
    return unpack_image(src, (size_t)img->width * (size_t)img->height, 1, C, img, alpha_from);
}

static float clean(float v, long *bad) {
    if (isfinite(v)) return v;
    if (bad) (*bad)++;
    return 0.0f;
}

static void pack_channels(const ew_image *view, int stride, float *attr, size_t ks, size_t js, long *bad) {
    const int n = view->channels < stride ? view->channels : stride;
    const int64_t ps = ew__pixel_stride(view);
    size_t j = 0;
    for (int y = 0; y < view->height; y++) {
        const char *row = (const char *)row_of(view, y);
        for (int x = 0; x < view->width; x++, j++) {
            const float *p = (const float *)(const void *)(row + (int64_t)x * ps);
            for (int k = 0; k < stride; k++) attr[(size_t)k * ks + j * js] = k < n ? clean(p[k], bad) : 0.0f;
        }
    }
}

void ew_bf_pack_channels(const ew_image *view, int stride, float *attr, long *bad) {
    pack_channels(view, stride, attr, 1, (size_t)stride, bad);
}

void ew_bf_pack_channels_planes(const ew_image *view, int stride, float *attr, long *bad) {
    pack_channels(view, stride, attr, (size_t)view->width * (size_t)view->height, 1, bad);
}

static void pack_gi(const ew_image *normal, const ew_image *depth, const ew_image *roughness, float *attr, size_t ks,
                    size_t js, long *bad) {
    const ew_image *any = normal ? normal : depth ? depth : roughness;
    if (!any) return;
    size_t j = 0;
    for (int y = 0; y < any->height; y++)
        for (int x = 0; x < any->width; x++, j++) {
            float a[5];
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
            for (int k = 0; k < 5; k++) attr[(size_t)k * ks + j * js] = a[k];
        }
}

void ew_bf_pack_gi(const ew_image *normal, const ew_image *depth, const ew_image *roughness, float *attr,
                   long *bad) {
    pack_gi(normal, depth, roughness, attr, 1, 5, bad);
}

void ew_bf_pack_gi_planes(const ew_image *normal, const ew_image *depth, const ew_image *roughness, float *attr,
                          long *bad) {
    const ew_image *any = normal ? normal : depth ? depth : roughness;
    if (any) pack_gi(normal, depth, roughness, attr, (size_t)any->width * (size_t)any->height, 1, bad);
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
