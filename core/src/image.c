#include "src/internal.h"

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

int64_t ew__pixel_stride(const ew_image *img) {
    return img->pixel_stride ? img->pixel_stride : (int64_t)img->channels * (int64_t)sizeof(float);
}

int64_t ew__row_stride(const ew_image *img) {
    return img->row_stride ? img->row_stride : ew__pixel_stride(img) * img->width;
}

int ew__image_packed_as(const ew_image *img, int floats) {
    return ew__pixel_stride(img) == (int64_t)sizeof(float) * floats &&
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
    else if (img->format != EW_FORMAT_FLOAT) w = "only EW_FORMAT_FLOAT images are supported";
    else {
        int64_t ps = ew__pixel_stride(img), rs = ew__row_stride(img);
        int64_t rs_abs = rs < 0 ? -rs : rs;
        if (ps < (int64_t)img->channels * (int64_t)sizeof(float)) w = "pixel stride smaller than a pixel";
        else if (rs_abs < ps * img->width) w = "row stride smaller than a row";
    }
    if (why) *why = w;
    return w == NULL;
}
