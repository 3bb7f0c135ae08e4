/*
 * internal.h — what the core's modules share and the public header hides:
 * the device (threads, last error, backend) and small helpers.
 */
#ifndef EW_INTERNAL_H
#define EW_INTERNAL_H

#include "edgewise/edgewise.h"
#include "kernels/half.h"
#include "src/thread_pool.h"

#include <pthread.h>

struct ew_backend;

#define EW_ERROR_MAX 512

/* One thread's last error on a device (ew_device_last_error). */
typedef struct ew_error_slot {
    pthread_t thread;
    int used;
    unsigned long stamp; /* last use, to recycle the oldest slot */
    char msg[EW_ERROR_MAX];
} ew_error_slot;

#define EW_ERROR_SLOTS 64

struct ew_device {
    ew_device_type type;
    int32_t num_threads;
    ew_thread_pool *pool;
    const struct ew_backend *backend;
    /* Backends write a message here only while the device is being created
     * (one thread, before the handle is returned); afterwards every message
     * goes through ew__fail / ew__set_error into the calling thread's slot. */
    char last_error[EW_ERROR_MAX];
    /* How a loaded backend module records a message as the calling thread's
     * last error (ew__set_error; the module cannot link the core's hidden
     * symbols). */
    void (*set_error)(ew_device *dev, const char *msg);
    /* The last error is kept per calling thread, as OIDN does: two threads
     * using one device each read their own failure, and neither reads a
     * message while the other writes it. The lock guards the slot table
     * (and the refcount's final release); a slot's text is written only by
     * its own thread. */
    pthread_mutex_t error_lock;
    ew_error_slot *errors; /* EW_ERROR_SLOTS of them, allocated with the device */
    unsigned long error_clock;
    /* Every op made on the device holds a reference, as does the caller
     * until ew_device_destroy: the device is freed when the last goes, so
     * destroying it before its ops is safe. Changed with __atomic builtins
     * (this header is also compiled as CUDA C++, where <stdatomic.h> is not). */
    int refs;
    /* backends with memory of their own (docs/backends.md) */
    int device_memory;  /* 1: backend buffers are not host-addressable (CUDA) */
    int device_images;  /* 1: ew_image data pointers are device pointers (ew_device_desc) */
    void *backend_ctx;  /* backend-private state (CUDA: ordinal, stream, first error) */
    int release_scratch; /* ew_device_desc.release_scratch (ew_dev_release_pages) */
    /* 1: the CPU's 5x5 convolutions always run direct, never Winograd
     * (environment EW_CPU_CONV=direct when the device is created;
     * backends/cpu/cpu_conv.h, docs/backends.md) */
    int conv_direct;
};

/* Record a formatted message as the device's last error and return `r`. */
ew_result ew__fail(ew_device *dev, ew_result r, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void ew__clear_error(ew_device *dev);
/* Record a ready message (e.g. a backend's) as the calling thread's last error. */
void ew__set_error(ew_device *dev, const char *msg);
/* Device reference counting for the ops made on it: ew__device_release
 * frees the device with its last reference. */
void ew__device_retain(ew_device *dev);
void ew__device_release(ew_device *dev);
/* Set up / tear down what every device has whatever its backend (the error
 * slots, the refcount). 0 on success. */
int ew__device_init_common(ew_device *dev);
void ew__device_free_common(ew_device *dev);

/* Checks a view: non-null data, positive size within limits, a known format,
 * strides at least as large as the pixel. Fills *why on failure. */
int ew__image_valid(const ew_image *img, const char **why);
/* ew__image_valid and EW_FORMAT_FLOAT (calls that read views themselves). */
int ew__float_image_valid(const ew_image *img, const char **why);
/* Bytes of a channel: 4 (EW_FORMAT_FLOAT) or 2 (EW_FORMAT_HALF). */
int64_t ew__channel_bytes(const ew_image *img);
/* Byte strides with packed defaults filled in. */
int64_t ew__pixel_stride(const ew_image *img);
int64_t ew__row_stride(const ew_image *img);
/* Whether the view is packed floats, `floats` a pixel, rows back to back
 * (what the fast packers and in-place reads need). */
int ew__image_packed_as(const ew_image *img, int floats);
/* The view's pixels [x, x + w) x [y, y + h), with its strides filled in:
 * a packed view's 0 strides would mean another row stride at the crop's
 * width (and offsets of 0). */
ew_image ew__image_crop(const ew_image *img, int x, int y, int w, int h);

static inline float *ew__pixel(const ew_image *img, int x, int y) {
    return (float *)((char *)img->data + (int64_t)y * ew__row_stride(img) +
                     (int64_t)x * ew__pixel_stride(img));
}

/* n halves to floats, exactly (half_rows.c: in hardware where the CPU can). */
void ew__halves_to_floats(const unsigned short *s, float *d, size_t n);
/* Host scratch mapped by itself and unmapped by ew__scratch_free (given
 * the same size), whatever its size: a heap keeps what is freed below its
 * mmap threshold (the CLI's is 32 MiB, never trimmed by itself), where
 * scratch of one step would still count at a later step's peak. */
void *ew__scratch_alloc(size_t bytes);
void ew__scratch_free(void *p, size_t bytes);

/* Channel k of pixel (x, y) of a float or half view, as a float. */
static inline float ew__channel(const ew_image *img, int x, int y, int k) {
    const void *p = ew__pixel(img, x, y);
    return img->format == EW_FORMAT_HALF ? ew_half_to_float(((const unsigned short *)p)[k]) : ((const float *)p)[k];
}

/* Largest accepted image side and pixel count. */
#define EW_MAX_SIDE 65536
#define EW_MAX_PIXELS ((int64_t)1 << 28)

#endif
