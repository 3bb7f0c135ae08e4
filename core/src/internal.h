/*
 * internal.h — what the core's modules share and the public header hides:
 * the device (threads, last error, backend) and small helpers.
 */
#ifndef EW_INTERNAL_H
#define EW_INTERNAL_H

#include "edgewise/edgewise.h"
#include "src/thread_pool.h"

struct ew_backend;

#define EW_ERROR_MAX 512

struct ew_device {
    ew_device_type type;
    int32_t num_threads;
    ew_thread_pool *pool;
    const struct ew_backend *backend;
    char last_error[EW_ERROR_MAX];
    /* backends with memory of their own (docs/backends.md) */
    int device_memory;  /* 1: backend buffers are not host-addressable (CUDA) */
    int device_images;  /* 1: ew_image data pointers are device pointers (ew_device_desc) */
    void *backend_ctx;  /* backend-private state (CUDA: ordinal, stream, first error) */
};

/* Record a formatted message as the device's last error and return `r`. */
ew_result ew__fail(ew_device *dev, ew_result r, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void ew__clear_error(ew_device *dev);

/* Checks a view: non-null data, positive size within limits, float format,
 * strides at least as large as the pixel. Fills *why on failure. */
int ew__image_valid(const ew_image *img, const char **why);
/* Byte strides with packed defaults filled in. */
int64_t ew__pixel_stride(const ew_image *img);
int64_t ew__row_stride(const ew_image *img);
/* Whether the view is packed floats, `floats` a pixel, rows back to back
 * (what the fast packers and in-place reads need). */
int ew__image_packed_as(const ew_image *img, int floats);

static inline float *ew__pixel(const ew_image *img, int x, int y) {
    return (float *)((char *)img->data + (int64_t)y * ew__row_stride(img) +
                     (int64_t)x * ew__pixel_stride(img));
}

/* Largest accepted image side and pixel count. */
#define EW_MAX_SIDE 65536
#define EW_MAX_PIXELS ((int64_t)1 << 28)

#endif
