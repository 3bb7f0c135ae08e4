/*
 * view.h — copying between a caller's strided image view and a packed
 * buffer, per pixel, so a backend can do it where the pixels are (a CUDA
 * device when the caller passes device pointers, see ew_device_desc's
 * device_images). Strides are in bytes and the row stride may be negative
 * (OFX hosts pass bottom-up images): row y starts at data + y * row_stride.
 */
#ifndef EW_KERNELS_VIEW_H
#define EW_KERNELS_VIEW_H

#include "kernels/compat.h"
#include "kernels/half.h"

typedef struct ew_view_desc {
    char *data;              /* pixel (0, 0) */
    int width, height;
    long long pixel_stride;  /* bytes */
    long long row_stride;    /* bytes, may be negative */
    int half;                /* 1: EW_FORMAT_HALF channels (read only: packed as floats) */
} ew_view_desc;

EW_HD float *ew_view_px(const ew_view_desc *v, int x, int y) {
    return (float *)(void *)(v->data + (long long)y * v->row_stride + (long long)x * v->pixel_stride);
}

/* The first c channels of pixel (x, y) into the packed buffer dst. */
EW_HD void ew_view_pack_px(int x, int y, const ew_view_desc *v, int c, float *EW_RESTRICT dst) {
    float *d = dst + ((long)y * v->width + x) * c;
    if (v->half) {
        const unsigned short *p = (const unsigned short *)(const void *)ew_view_px(v, x, y);
        for (int k = 0; k < c; k++) d[k] = ew_half_to_float(p[k]);
        return;
    }
    const float *p = ew_view_px(v, x, y);
    for (int k = 0; k < c; k++) d[k] = p[k];
}

/* The reverse: pixel (x, y) of the packed src into the view's first c channels. */
EW_HD void ew_view_unpack_px(int x, int y, const ew_view_desc *v, int c, const float *EW_RESTRICT src) {
    float *p = ew_view_px(v, x, y);
    const float *s = src + ((long)y * v->width + x) * c;
    for (int k = 0; k < c; k++) p[k] = s[k];
}

#endif
