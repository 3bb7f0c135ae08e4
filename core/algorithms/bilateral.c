/*
 * bilateral.c — packing and the brute-force / separable runs of the joint
 * bilateral filter (kernels/bilateral.h has the math).
 */
#include "algorithms/bilateral.h"

#include <math.h>
#include <string.h>

#include "src/backend.h"
#include "src/cpu_clones.h"

/* The packers write element k of pixel j at dst[k * ks + (j - jsub) * js]:
 * interleaved (ks 1, js = floats a pixel) or planes (ks = plane size, js 1);
 * jsub: the first pixel of dst (a band of rows), 0 for a whole frame.
 * Rows are walked with their own pointer (views may have any strides). Each
 * does the rows [y0, y1), so that ew_bf_io can run them in bands of rows on
 * the device's threads (rows are independent): every filter's execute packs
 * and unpacks this way alike. */
static const float *row_of(const ew_image *img, int y) {
    return (const float *)(const void *)((const char *)img->data + (int64_t)y * ew__row_stride(img));
}

/* The common layouts (views of packed floats, 1, 3 or 4 a pixel, to and
 * from planes) as row loops without branches, which the compiler
 * vectorises (built for each vector width, as the filters' loops: the
 * stride-3 loads need AVX2's shuffles): the general loops below, with their
 * per-channel loops and strides known only at run time, stay scalar and
 * were most of the time the filters spend outside their passes. Same
 * values, same counts. */
static int is_finite_bits(float v) { return (ew_float_to_bits(v) & 0x7f800000) != 0x7f800000; }

/* C = 3 or 4 floats a pixel into the 4 planes (r, g, b, mask) */
static EW_MULTIVERSION long pack_image_fast(const float *EW_RESTRICT src, const int C, float *EW_RESTRICT dst, size_t ks,
                                   size_t j0, long count) {
    float *EW_RESTRICT d0 = dst + j0, *EW_RESTRICT d1 = d0 + ks, *EW_RESTRICT d2 = d1 + ks, *EW_RESTRICT d3 = d2 + ks;
    long missing = 0;
    for (long x = 0; x < count; x++) {
        const float *p = src + x * C;
        const int ok = is_finite_bits(p[0]) & is_finite_bits(p[1]) & is_finite_bits(p[2]) &
                       (C > 3 ? is_finite_bits(p[3]) : 1);
        d0[x] = ok ? p[0] : 0.0f;
        d1[x] = ok ? p[1] : 0.0f;
        d2[x] = ok ? p[2] : 0.0f;
        d3[x] = ok ? 1.0f : 0.0f;
        missing += !ok;
    }
    return missing;
}

static long pack_image(const ew_image *img, int C, float *dst, size_t ks, size_t js, size_t jsub, int y0, int y1) {
    if (js == 1 && (C == 3 || C == 4) && ew__image_packed_as(img, C)) {
        const size_t w = (size_t)img->width;
        const float *src = (const float *)img->data + (size_t)y0 * w * (size_t)C;
        const long count = (long)((size_t)(y1 - y0) * w);
        return C == 3 ? pack_image_fast(src, 3, dst, ks, (size_t)y0 * w - jsub, count)
                      : pack_image_fast(src, 4, dst, ks, (size_t)y0 * w - jsub, count);
    }
    const int n = C < EW_BF_COLOR ? C : EW_BF_COLOR;
    const int64_t ps = ew__pixel_stride(img);
    long missing = 0;
    size_t j = (size_t)y0 * (size_t)img->width - jsub;
    for (int y = y0; y < y1; y++) {
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

/* 4 planes into C = 3 or 4 floats a pixel (alpha: from a packed view, or
 * left as it is when it is the output itself) */
static EW_MULTIVERSION long unpack_image_fast(const float *EW_RESTRICT src, size_t ks, size_t j0, const int C,
                                     float *EW_RESTRICT out, const float *alpha, long count) {
    const float *EW_RESTRICT s0 = src + j0, *EW_RESTRICT s1 = s0 + ks, *EW_RESTRICT s2 = s1 + ks, *EW_RESTRICT s3 = s2 + ks;
    long zeroed = 0;
    for (long x = 0; x < count; x++) {
        const float mask = s3[x];
        const int ok = mask > 0.0f;
        const float den = ok ? mask : 1.0f;
        float *p = out + x * C;
        p[0] = ok ? s0[x] / den : 0.0f;
        p[1] = ok ? s1[x] / den : 0.0f;
        p[2] = ok ? s2[x] / den : 0.0f;
        if (C > 3 && alpha) p[3] = alpha[x * 4 + 3];
        zeroed += !ok;
    }
    return zeroed;
}

/* src's pixel j is at j - jsub (a band of rows starting at pixel jsub) */
static long unpack_image(const float *src, size_t ks, size_t js, size_t jsub, int C, const ew_image *img,
                         const ew_image *alpha_from, int y0, int y1) {
    if (js == 1 && (C == 3 || C == 4) && ew__image_packed_as(img, C) &&
        (C == 3 || !alpha_from || ew__image_packed_as(alpha_from, 4))) {
        const size_t w = (size_t)img->width, j0 = (size_t)y0 * w;
        float *out = (float *)img->data + j0 * (size_t)C;
        const long count = (long)((size_t)(y1 - y0) * w);
        if (C == 3) return unpack_image_fast(src, ks, j0 - jsub, 3, out, NULL, count);
        /* alpha copied from another view; onto itself it stays */
        const float *alpha = alpha_from && alpha_from->data != img->data ? (const float *)alpha_from->data + j0 * 4 : NULL;
        return unpack_image_fast(src, ks, j0 - jsub, 4, out, alpha, count);
    }
    const int n = C < EW_BF_COLOR ? C : EW_BF_COLOR;
    const int64_t ps = ew__pixel_stride(img);
    long zeroed = 0;
    size_t j = (size_t)y0 * (size_t)img->width;
    for (int y = y0; y < y1; y++) {
        char *row = (char *)img->data + (int64_t)y * ew__row_stride(img);
        for (int x = 0; x < img->width; x++, j++) {
            float *p = (float *)(void *)(row + (int64_t)x * ps);
            const float mask = src[EW_BF_COLOR * ks + (j - jsub) * js];
            const int ok = mask > 0.0f;
            for (int c = 0; c < n; c++) p[c] = ok ? src[(size_t)c * ks + (j - jsub) * js] / mask : 0.0f;
            if (C > EW_BF_COLOR && alpha_from) p[EW_BF_COLOR] = ew__pixel(alpha_from, x, y)[EW_BF_COLOR];
            zeroed += !ok;
        }
    }
    return zeroed;
}

static float clean(float v, long *bad) {
    if (isfinite(v)) return v;
    (*bad)++;
    return 0.0f;
}

/* nv = 1, 3 or 4 floats a pixel into `stride` planes (zeros after nv) */
static EW_MULTIVERSION long pack_channels_fast(const float *EW_RESTRICT src, const int nv, const int stride,
                                      float *EW_RESTRICT dst, size_t ks, size_t j0, long count) {
    long bad = 0;
    for (int k = 0; k < stride; k++) {
        float *EW_RESTRICT d = dst + (size_t)k * ks + j0;
        if (k >= nv) {
            for (long x = 0; x < count; x++) d[x] = 0.0f;
            continue;
        }
        for (long x = 0; x < count; x++) {
            const float v = src[x * nv + k];
            const int ok = is_finite_bits(v);
            d[x] = ok ? v : 0.0f;
            bad += !ok;
        }
    }
    return bad;
}

static long pack_channels(const ew_image *view, int stride, float *attr, size_t ks, size_t js, size_t jsub, int y0,
                          int y1) {
    const int n = view->channels < stride ? view->channels : stride;
    if (js == 1 && n == view->channels && (n == 1 || n == 3 || n == 4) && (stride == 1 || stride == 4) &&
        ew__image_packed_as(view, n)) {
        const size_t w = (size_t)view->width, j0 = (size_t)y0 * w;
        const float *src = (const float *)view->data + j0 * (size_t)n;
        const long count = (long)((size_t)(y1 - y0) * w);
        if (stride == 1) return pack_channels_fast(src, 1, 1, attr, ks, j0 - jsub, count);
        return n == 1   ? pack_channels_fast(src, 1, 4, attr, ks, j0 - jsub, count)
               : n == 3 ? pack_channels_fast(src, 3, 4, attr, ks, j0 - jsub, count)
                        : pack_channels_fast(src, 4, 4, attr, ks, j0 - jsub, count);
    }
    const int64_t ps = ew__pixel_stride(view);
    long bad = 0;
    size_t j = (size_t)y0 * (size_t)view->width - jsub;
    for (int y = y0; y < y1; y++) {
        const char *row = (const char *)row_of(view, y);
        for (int x = 0; x < view->width; x++, j++) {
            const float *p = (const float *)(const void *)(row + (int64_t)x * ps);
            for (int k = 0; k < stride; k++) attr[(size_t)k * ks + j * js] = k < n ? clean(p[k], &bad) : 0.0f;
        }
    }
    return bad;
}

static long pack_gi(const ew_image *normal, const ew_image *depth, const ew_image *roughness, float *attr, size_t ks,
                    size_t js, size_t jsub, int y0, int y1) {
    const ew_image *any = normal ? normal : depth ? depth : roughness;
    long bad = 0;
    size_t j = (size_t)y0 * (size_t)any->width - jsub;
    for (int y = y0; y < y1; y++)
        for (int x = 0; x < any->width; x++, j++) {
            float a[5];
            a[0] = a[1] = a[2] = 0.0f;
            if (normal) {
                const float *n = ew__pixel(normal, x, y);
                float n0 = clean(n[0], &bad), n1 = clean(n[1], &bad), n2 = clean(n[2], &bad);
                float len = sqrtf(n0 * n0 + n1 * n1 + n2 * n2);
                if (len > 1e-6f) {
                    a[0] = n0 / len;
                    a[1] = n1 / len;
                    a[2] = n2 / len;
                }
            }
            a[3] = depth ? clean(*ew__pixel(depth, x, y), &bad) : 0.0f;
            a[4] = roughness ? sqrtf(fminf(fmaxf(clean(*ew__pixel(roughness, x, y), &bad), 0.0f), 1.0f)) : 1.0f;
            for (int k = 0; k < 5; k++) attr[(size_t)k * ks + j * js] = a[k];
        }
    return bad;
}

/* ---- the packers over bands of rows on the device's threads ---- */
#define EW_IO_MAX_THREADS 256
enum { IO_IMAGE, IO_UNPACK, IO_CHANNELS, IO_GI };

typedef struct {
    ew_bf_io_job j;
    long counts[EW_IO_MAX_THREADS]; /* per thread, summed at the end (no atomics, no allocation) */
} io_job;

static long job_rows(const ew_bf_io_job *j, int y0, int y1, int tid) {
    switch (j->what) {
    case IO_IMAGE: return pack_image(j->v, j->C, j->dst, j->ks, j->js, 0, y0, y1);
    case IO_UNPACK:
        if (j->band) /* rows [y0, y1) lie in one band: thread tid's buffer */
            return unpack_image(j->src + (size_t)tid * j->band_stride, j->ks, 1,
                                (size_t)(y0 - y0 % j->band) * (size_t)j->v->width, j->C, j->v, j->v2, y0, y1);
        return unpack_image(j->src, j->ks, j->js, 0, j->C, j->v, j->v2, y0, y1);
    case IO_CHANNELS: return pack_channels(j->v, j->C, j->dst, j->ks, j->js, 0, y0, y1);
    default: return pack_gi(j->v, j->v2, j->v3, j->dst, j->ks, j->js, 0, y0, y1);
    }
}

static void io_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    io_job *j = (io_job *)ctx;
    j->counts[tid] += job_rows(&j->j, (int)begin, (int)end, tid); /* tid < threads <= EW_IO_MAX_THREADS (run_io) */
}

/* Run a job over the rows of `any` (the views' common size), laid out as
 * interleaved pixels of per_pixel floats or as planes; the sum of its
 * counts. Devices with more threads than there are count slots pack on one
 * thread. */
static void set_layout(ew_bf_io_job *j, const ew_image *any, size_t per_pixel, int planes) {
    j->ks = planes ? (size_t)any->width * (size_t)any->height : 1;
    j->js = planes ? 1 : per_pixel;
}

static long run_io(ew_device *dev, io_job *j, const ew_image *any, size_t per_pixel, int planes) {
    set_layout(&j->j, any, per_pixel, planes);
    memset(j->counts, 0, sizeof j->counts);
    if (dev && dev->pool && ew_device_get_num_threads(dev) <= EW_IO_MAX_THREADS)
        ew_pool_run(dev->pool, any->height, 16, io_rows, j);
    else
        io_rows(j, 0, any->height, 0);
    long n = 0;
    for (int t = 0; t < EW_IO_MAX_THREADS; t++) n += j->counts[t];
    return n;
}

static long image_io(ew_device *dev, int what, const ew_image *img, int C, const float *src, float *dst,
                     const ew_image *alpha_from, int planes) {
    io_job j = {.j = {.what = what, .C = C, .v = img, .v2 = alpha_from, .src = src, .dst = dst}};
    return run_io(dev, &j, img, EW_BF_CH, planes);
}

long ew_bf_pack_image(ew_device *dev, const ew_image *img, int C, float *dst) {
    return image_io(dev, IO_IMAGE, img, C, NULL, dst, NULL, 0);
}

long ew_bf_pack_image_planes(ew_device *dev, const ew_image *img, int C, float *dst) {
    return image_io(dev, IO_IMAGE, img, C, NULL, dst, NULL, 1);
}

long ew_bf_unpack_image(ew_device *dev, const float *src, int C, const ew_image *img, const ew_image *alpha_from) {
    return image_io(dev, IO_UNPACK, img, C, src, NULL, alpha_from, 0);
}

long ew_bf_unpack_image_planes(ew_device *dev, const float *src, int C, const ew_image *img,
                               const ew_image *alpha_from) {
    return image_io(dev, IO_UNPACK, img, C, src, NULL, alpha_from, 1);
}

static void channels_io(ew_device *dev, const ew_image *view, int stride, float *attr, long *bad, int planes) {
    io_job j = {.j = {.what = IO_CHANNELS, .C = stride, .v = view, .dst = attr}};
    const long n = run_io(dev, &j, view, (size_t)stride, planes);
    if (bad) *bad += n;
}

void ew_bf_pack_channels(ew_device *dev, const ew_image *view, int stride, float *attr, long *bad) {
    channels_io(dev, view, stride, attr, bad, 0);
}

void ew_bf_pack_channels_planes(ew_device *dev, const ew_image *view, int stride, float *attr, long *bad) {
    channels_io(dev, view, stride, attr, bad, 1);
}

static void gi_io(ew_device *dev, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                  float *attr, long *bad, int planes) {
    const ew_image *any = normal ? normal : depth ? depth : roughness;
    if (!any) return;
    io_job j = {.j = {.what = IO_GI, .v = normal, .v2 = depth, .v3 = roughness, .dst = attr}};
    const long n = run_io(dev, &j, any, 5, planes);
    if (bad) *bad += n;
}

void ew_bf_pack_gi(ew_device *dev, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                   float *attr, long *bad) {
    gi_io(dev, normal, depth, roughness, attr, bad, 0);
}

void ew_bf_pack_gi_planes(ew_device *dev, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                          float *attr, long *bad) {
    gi_io(dev, normal, depth, roughness, attr, bad, 1);
}

/* ---- the same jobs on rows given by another pass ---- */
static void add_job(ew_bf_io_set *s, ew_bf_io_job j, const ew_image *any, size_t per_pixel, int planes) {
    if (s->n >= EW_BF_IO_JOBS || !any) return; /* callers add at most EW_BF_IO_JOBS */
    set_layout(&j, any, per_pixel, planes);
    s->job[s->n++] = j;
}

void ew_bf_io_pack_image(ew_bf_io_set *s, const ew_image *img, int C, float *dst, int planes) {
    add_job(s, (ew_bf_io_job){.what = IO_IMAGE, .C = C, .v = img, .dst = dst}, img, EW_BF_CH, planes);
}

void ew_bf_io_pack_channels(ew_bf_io_set *s, const ew_image *view, int stride, float *attr, int planes) {
    add_job(s, (ew_bf_io_job){.what = IO_CHANNELS, .C = stride, .v = view, .dst = attr}, view, (size_t)stride,
            planes);
}

void ew_bf_io_pack_gi(ew_bf_io_set *s, const ew_image *normal, const ew_image *depth, const ew_image *roughness,
                      float *attr, int planes) {
    add_job(s, (ew_bf_io_job){.what = IO_GI, .v = normal, .v2 = depth, .v3 = roughness, .dst = attr},
            normal ? normal : depth ? depth : roughness, 5, planes);
}

void ew_bf_io_unpack_image(ew_bf_io_set *s, const float *src, int C, const ew_image *img,
                           const ew_image *alpha_from, int planes) {
    add_job(s, (ew_bf_io_job){.what = IO_UNPACK, .C = C, .v = img, .v2 = alpha_from, .src = src}, img, EW_BF_CH,
            planes);
}

void ew_bf_io_unpack_band(ew_bf_io_set *s, const float *src, int band, long band_stride, int C, const ew_image *img,
                          const ew_image *alpha_from) {
    if (!band) {
        ew_bf_io_unpack_image(s, src, C, img, alpha_from, 1);
        return;
    }
    if (s->n >= EW_BF_IO_JOBS || !img) return;
    s->job[s->n++] = (ew_bf_io_job){.what = IO_UNPACK, .C = C, .v = img, .v2 = alpha_from, .src = src,
                                    .ks = (size_t)band * (size_t)img->width, .js = 1, .band = band,
                                    .band_stride = (size_t)band_stride};
}

void ew_bf_io_rows(void *set, int y0, int y1, int tid) {
    const ew_bf_io_set *s = (const ew_bf_io_set *)set;
    for (int k = 0; k < s->n; k++) (void)job_rows(&s->job[k], y0, y1, tid);
}

void ew_bf_io_fill(void *set, int y0, int y1, int tid, float *planes, long ps, long row0) {
    (void)tid;
    const ew_bf_io_set *s = (const ew_bf_io_set *)set;
    const size_t ks = (size_t)ps;
    for (int k = 0; k < s->n; k++) {
        const ew_bf_io_job *j = &s->job[k];
        const ew_image *any = j->v ? j->v : j->v2 ? j->v2 : j->v3; /* GI: any of its views */
        const size_t w = (size_t)any->width, jsub = (size_t)row0 * w;
        float *attr = planes + EW_BF_CH * ks;
        switch (j->what) {
        case IO_IMAGE: (void)pack_image(j->v, j->C, planes, ks, 1, jsub, y0, y1); break;
        case IO_CHANNELS: (void)pack_channels(j->v, j->C, attr, ks, 1, jsub, y0, y1); break;
        case IO_GI: (void)pack_gi(j->v, j->v2, j->v3, attr, ks, 1, jsub, y0, y1); break;
        default: break; /* unpacking: a drain's job */
        }
    }
}

static void set_rows(void *set, int64_t begin, int64_t end, int tid) { ew_bf_io_rows(set, (int)begin, (int)end, tid); }

void ew_bf_io_run(ew_device *dev, ew_bf_io_set *s, const ew_image *any) {
    if (dev && dev->pool) ew_pool_run(dev->pool, any->height, 16, set_rows, s);
    else set_rows(s, 0, any->height, 0);
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
