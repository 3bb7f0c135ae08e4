#include "kernels/compat.h"
#include "src/finite.h"
#include "src/internal.h"

#include <float.h>
#include <math.h>
#include <stdint.h>

ew_image ew_image_packed(float *data, int32_t width, int32_t height, int32_t channels) {
    ew_image v;
    v.data = data;
    v.width = width;
    v.height = height;
    v.channels = channels;
    v.pixel_stride = (int64_t)channels * (int64_t)sizeof(float);
    v.row_stride = v.pixel_stride * width;
    v.format = EW_FORMAT_FLOAT;
    return v;
}

int64_t ew__channel_bytes(const ew_image *img) { return img->format == EW_FORMAT_HALF ? 2 : (int64_t)sizeof(float); }

int64_t ew__pixel_stride(const ew_image *img) {
    return img->pixel_stride ? img->pixel_stride : (int64_t)img->channels * ew__channel_bytes(img);
}

int64_t ew__row_stride(const ew_image *img) {
    return img->row_stride ? img->row_stride : ew__pixel_stride(img) * img->width;
}

ew_image ew__image_crop(const ew_image *img, int x, int y, int w, int h) {
    ew_image v = *img;
    v.pixel_stride = ew__pixel_stride(img);
    v.row_stride = ew__row_stride(img);
    v.data = (char *)img->data + (int64_t)y * v.row_stride + (int64_t)x * v.pixel_stride;
    v.width = w;
    v.height = h;
    return v;
}

int ew__image_packed_as(const ew_image *img, int floats) {
    return img->format == EW_FORMAT_FLOAT && ew__pixel_stride(img) == (int64_t)sizeof(float) * floats &&
           ew__row_stride(img) == (int64_t)sizeof(float) * floats * img->width;
}

int ew__image_valid(const ew_image *img, const char **why) {
    const char *w = NULL;
    if (!img) w = "no image view";
    else if (!img->data) w = "image data is NULL";
    else if (img->width <= 0 || img->height <= 0) w = "image width and height must be positive";
    else if (img->width > EW_MAX_SIDE || img->height > EW_MAX_SIDE ||
             (int64_t)img->width * img->height > EW_MAX_PIXELS)
        w = "image is larger than 65536 pixels per side or 2^28 pixels";
    else if (img->channels <= 0 || img->channels > 64) w = "channel count must be 1..64";
    else if (img->format != EW_FORMAT_FLOAT && img->format != EW_FORMAT_HALF)
        w = "unknown image format (EW_FORMAT_FLOAT or EW_FORMAT_HALF)";
    else if ((uintptr_t)img->data % (uintptr_t)ew__channel_bytes(img) != 0)
        w = img->format == EW_FORMAT_HALF ? "image data is not aligned to a half (2 bytes)"
                                          : "image data is not aligned to a float (4 bytes)";
    else if (img->pixel_stride % ew__channel_bytes(img) != 0 || img->row_stride % ew__channel_bytes(img) != 0)
        w = img->format == EW_FORMAT_HALF ? "image strides must be multiples of 2 bytes (half alignment)"
                                          : "image strides must be multiples of 4 bytes (float alignment)";
    else {
        /* Bounds first, so that nothing below overflows: a stride may be any
         * int64 the caller writes (INT64_MIN has no absolute value). */
        const int64_t lim = INT64_MAX / 2;
        int64_t ps = ew__pixel_stride(img);
        int64_t rs = img->row_stride;
        if (ps < (int64_t)img->channels * ew__channel_bytes(img)) w = "pixel stride smaller than a pixel";
        else if (ps > lim / img->width) w = "pixel stride too large (the row would overflow)";
        else if (rs < -lim || rs > lim) w = "row stride too large (the image would overflow)";
        else {
            rs = ew__row_stride(img);
            int64_t rs_abs = rs < 0 ? -rs : rs;
            if (rs_abs < ps * img->width) w = "row stride smaller than a row";
            else if (rs_abs > lim / img->height) w = "row stride too large (the image would overflow)";
        }
    }
    if (why) *why = w;
    return w == NULL;
}

typedef struct {
    const ew_image *out, *in;
    int channels, in_channels;
    long replaced;
} finite_job;

static void finite_rows(void *ctx, int64_t y0, int64_t y1, int tid) {
    finite_job *j = (finite_job *)ctx;
    (void)tid;
    long replaced = 0;
    for (int64_t y = y0; y < y1; y++)
        for (int x = 0; x < j->out->width; x++) {
            float *o = ew__pixel(j->out, x, (int)y);
            int bad = 0;
            for (int c = 0; c < j->channels; c++) bad |= !isfinite(o[c]);
            if (!bad) continue;
            replaced++;
            const float *i = j->in ? ew__pixel(j->in, x, (int)y) : NULL;
            for (int c = 0; c < j->channels; c++)
                o[c] = ew_finite_orf(i && c < j->in_channels ? i[c] : o[c]);
        }
    __atomic_fetch_add(&j->replaced, replaced, __ATOMIC_RELAXED);
}

long ew__finite_fallback(ew_device *dev, const ew_image *out, const ew_image *in) {
    if (!out || dev->device_images) return 0;
    finite_job j = {out, in && in->data != out->data ? in : NULL, out->channels, in ? in->channels : 0, 0};
    ew_pool_run(dev->pool, out->height, 0, finite_rows, &j);
    return j.replaced;
}

int ew__float_image_valid(const ew_image *img, const char **why) {
    if (!ew__image_valid(img, why)) return 0;
    if (img->format == EW_FORMAT_FLOAT) return 1;
    if (why) *why = "this call reads EW_FORMAT_FLOAT images only";
    return 0;
}
