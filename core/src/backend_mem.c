/*
 * backend_mem.c — what algorithms call to allocate device buffers and to
 * move caller views in and out of them (docs/backends.md), so that
 * one code path serves the CPU (device memory is host memory: views are
 * packed straight into the buffers, no extra copy) and CUDA (views are
 * packed into a host staging buffer and uploaded, or, for device-pointer
 * views, packed on the GPU).
 */
#if defined(__linux__) && !defined(_DEFAULT_SOURCE)
#define _DEFAULT_SOURCE /* madvise */
#endif
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#include "kernels/view.h"
#include "src/backend.h"
#include "src/internal.h"
#include "src/op.h"
#include "src/thread_pool.h"

void *ew_dev_alloc(ew_device *dev, size_t bytes) { return dev->backend->mem_alloc(dev, bytes); }

void ew_dev_free(ew_device *dev, void *ptr) {
    if (ptr) dev->backend->mem_free(dev, ptr);
}

#if defined(__linux__)
/* [*a, *b): the whole units (aligned to unit) inside [from, to); 0 when there
 * is none. */
static int inner_units(uintptr_t from, uintptr_t to, uintptr_t unit, uintptr_t *a, uintptr_t *b) {
    *a = (from + unit - 1) / unit * unit;
    *b = to / unit * unit;
    return *b > *a;
}

/* [*a, *b): the whole pages inside [from, to) — a page the range shares with
 * live data (the block's parameters, the allocator's header) is left out.
 * 0 when there is none (or no page size). */
static int inner_pages(uintptr_t from, uintptr_t to, uintptr_t *a, uintptr_t *b) {
    const long ps = sysconf(_SC_PAGESIZE);
    return ps > 0 && inner_units(from, to, (uintptr_t)ps, a, b);
}
#endif

void ew_dev_release_pages(ew_device *dev, void *from, void *to) {
#if defined(__linux__)
    if (!dev->release_scratch || dev->device_memory || !from || !to) return;
    uintptr_t a, b;
    /* MADV_DONTNEED on private anonymous memory: the pages are dropped at
     * once and come back zero-filled on the next touch */
    if (inner_pages((uintptr_t)from, (uintptr_t)to, &a, &b)) (void)madvise((void *)a, (size_t)(b - a), MADV_DONTNEED);
#else
    (void)dev;
    (void)from;
    (void)to;
#endif
}

#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
/* the pages are made resident in chunks of a transparent huge page's size
 * (2 MiB with 4 KiB pages), aligned to it, one chunk a call on a thread */
#define PREFAULT_CHUNK ((uintptr_t)2 << 20)
typedef struct {
    uintptr_t a, b, base;
} prefault_job;

static void prefault_chunks(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const prefault_job *j = (const prefault_job *)ctx;
    uintptr_t a = j->base + (uintptr_t)begin * PREFAULT_CHUNK, b = j->base + (uintptr_t)end * PREFAULT_CHUNK;
    if (a < j->a) a = j->a;
    if (b > j->b) b = j->b;
    /* a failure (an older kernel) leaves the pages to fault in as they are written */
    if (b > a) (void)madvise((void *)a, (size_t)(b - a), MADV_POPULATE_WRITE);
}

#if defined(MADV_HUGEPAGE)
/* Bytes the kernel holds free in blocks of 2 MiB and more (/proc/buddyinfo,
 * every zone: order 9 and above), 0 when unknown or when pages are not
 * 4 KiB (where a huge page is another size). */
static size_t free_huge_bytes(void) {
    const long ps = sysconf(_SC_PAGESIZE);
    FILE *f = ps == 4096 ? fopen("/proc/buddyinfo", "r") : NULL;
    if (!f) return 0;
    size_t total = 0;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        char *p = strstr(line, "zone");
        if (!p) continue;
        p += 4;
        while (*p == ' ') p++;
        while (*p && *p != ' ') p++; /* the zone's name */
        for (int order = 0;; order++) {
            char *e;
            const unsigned long n = strtoul(p, &e, 10);
            if (e == p) break;
            p = e;
            if (((size_t)ps << order) >= PREFAULT_CHUNK) total += n * ((size_t)ps << order);
        }
    }
    fclose(f);
    return total;
}

/* Transparent huge pages (MADV_HUGEPAGE) for the whole 2 MiB pages of
 * [a, b): in a virtual machine the first touch of every 4 KiB page costs
 * ~5 us in the hypervisor even after it is populated, and a huge page one
 * such touch (BENCHMARKS.md, "Huge pages for the pyramid's prefaulted
 * planes"). Only when free blocks of that size cover twice the range: the
 * kernel then takes them from its free lists instead of compacting memory
 * for them, which costs more than it saves. As with glibc's malloc.hugetlb
 * tunable, the advice stays on the heap pages a block leaves behind when it
 * is freed. */
static void advise_huge_pages(uintptr_t a, uintptr_t b) {
    uintptr_t ha, hb;
    if (inner_units(a, b, PREFAULT_CHUNK, &ha, &hb) && free_huge_bytes() >= 2 * (size_t)(hb - ha))
        (void)madvise((void *)ha, (size_t)(hb - ha), MADV_HUGEPAGE);
}
#endif
#endif

void ew_dev_prefault(ew_device *dev, void *from, void *to) {
#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
    prefault_job j;
    if (dev->device_memory || !from || !to || !inner_pages((uintptr_t)from, (uintptr_t)to, &j.a, &j.b)) return;
    j.base = j.a / PREFAULT_CHUNK * PREFAULT_CHUNK;
#if defined(MADV_HUGEPAGE)
    advise_huge_pages(j.a, j.b);
#endif
    ew_pool_run(dev->pool, (int64_t)((j.b - j.base + PREFAULT_CHUNK - 1) / PREFAULT_CHUNK), 1, prefault_chunks,
                (void *)&j);
#else
    (void)dev;
    (void)from;
    (void)to;
#endif
}

void ew_dev_sparse_pages(ew_device *dev, void *from, void *to) {
#if defined(__linux__) && defined(MADV_NOHUGEPAGE)
    uintptr_t a, b;
    if (!dev->device_memory && from && to && inner_pages((uintptr_t)from, (uintptr_t)to, &a, &b))
        (void)madvise((void *)a, (size_t)(b - a), MADV_NOHUGEPAGE); /* a failure leaves huge pages: more held */
#else
    (void)dev;
    (void)from;
    (void)to;
#endif
}

void *ew_host_alloc(size_t bytes) {
    void *p = NULL;
#if defined(__linux__) && defined(MADV_POPULATE_WRITE) && defined(MADV_HUGEPAGE)
    /* from 2 MiB up the block starts on a huge page, so all of it can be
     * made of them (glibc maps such a block by itself and unmaps it on free)
     * but the first: an op's block begins with its small parts (row sums,
     * parameters, a band's buffers), written long before the planes after
     * them or without them, which in a huge page hold 2 MiB each */
    if (bytes >= PREFAULT_CHUNK) {
        if (posix_memalign(&p, PREFAULT_CHUNK, bytes) != 0) return NULL;
        advise_huge_pages((uintptr_t)p + PREFAULT_CHUNK, (uintptr_t)p + bytes);
        return p;
    }
#endif
    return posix_memalign(&p, 64, bytes ? bytes : 64) == 0 ? p : NULL;
}

void ew_host_free(void *ptr) { free(ptr); }

void *ew__scratch_alloc(size_t bytes) {
#if defined(__linux__)
    void *p = mmap(NULL, bytes ? bytes : 1, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    return p == MAP_FAILED ? NULL : p;
#else
    return malloc(bytes);
#endif
}

void ew__scratch_free(void *p, size_t bytes) {
    if (!p) return;
#if defined(__linux__)
    munmap(p, bytes ? bytes : 1);
#else
    (void)bytes;
    free(p);
#endif
}

ew_result ew_dev_copy_rect(ew_device *dev, float *dst, int dw, int dx, int dy, const float *src, int sw, int sx, int sy,
                           int w, int h, int c) {
    ew_result r = EW_OK;
    for (int y = 0; y < h && r == EW_OK; y++)
        r = dev->backend->mem_copy(dev, dst + ((long)(dy + y) * dw + dx) * c, src + ((long)(sy + y) * sw + sx) * c,
                                   (size_t)w * (size_t)c * sizeof(float));
    return r;
}

/* the floats compared (and written) at a time: a page's */
#define SPARSE_SPAN 1024

ew_result ew_dev_copy_sparse(ew_device *dev, float *dst, const float *src, size_t floats) {
    if (dev->device_memory) return dev->backend->mem_copy(dev, dst, src, floats * sizeof(float));
    for (size_t i = 0; i < floats; i += SPARSE_SPAN) {
        const size_t n = floats - i < SPARSE_SPAN ? floats - i : SPARSE_SPAN;
        int nonzero = 0;
        for (size_t k = 0; k < n; k++) nonzero |= (src[i + k] != 0.0f) | (dst[i + k] != 0.0f);
        if (nonzero) memcpy(dst + i, src + i, n * sizeof(float));
    }
    return EW_OK;
}

ew_result ew_dev_copy_rect_sparse(ew_device *dev, float *dst, int dw, int dx, int dy, const float *src, int sw, int sx,
                                  int sy, int w, int h) {
    ew_result r = EW_OK;
    for (int y = 0; y < h && r == EW_OK; y++)
        r = ew_dev_copy_sparse(dev, dst + (long)(dy + y) * dw + dx, src + (long)(sy + y) * sw + sx, (size_t)w);
    return r;
}

ew_result ew_dev_zero(ew_device *dev, void *ptr, size_t bytes) {
#if defined(__linux__)
    const uintptr_t p = (uintptr_t)ptr, e = p + bytes;
    uintptr_t a, b;
    if (!dev->device_memory && ptr && inner_pages(p, e, &a, &b)) {
        /* MADV_DONTNEED on private anonymous memory: zero-filled on the
         * next touch (a failure leaves the pages: they are written) */
        if (madvise((void *)a, (size_t)(b - a), MADV_DONTNEED) == 0) {
            ew_result r = dev->backend->mem_zero(dev, ptr, (size_t)(a - p));
            return r == EW_OK ? dev->backend->mem_zero(dev, (void *)b, (size_t)(e - b)) : r;
        }
    }
#endif
    return dev->backend->mem_zero(dev, ptr, bytes);
}

ew_dev_kept ew_dev_kept_take(ew_dev_kept *k) {
    ew_dev_kept t = {NULL, 0};
    if (k) {
        t = *k;
        k->mem = NULL;
        k->bytes = 0;
    }
    return t;
}

void *ew_dev_keep(ew_device *dev, ew_dev_kept *k, ew_dev_kept old, size_t bytes) {
    if (!k) {
        ew_dev_free(dev, old.mem);
        return NULL;
    }
    if (old.mem && old.bytes == bytes) {
        *k = old;
        return k->mem;
    }
    ew_dev_free(dev, old.mem);
    k->mem = ew_dev_alloc(dev, bytes);
    k->bytes = k->mem ? bytes : 0;
    return k->mem;
}

size_t ew_dev_stage_floats(const ew_device *dev, size_t n, int c) {
    return dev->device_memory && !dev->device_images ? n * (size_t)c : 0;
}

static ew_view_desc view_desc(const ew_image *img) {
    ew_view_desc v;
    v.data = (char *)img->data;
    v.width = img->width;
    v.height = img->height;
    v.pixel_stride = ew__pixel_stride(img);
    v.row_stride = ew__row_stride(img);
    v.half = img->format == EW_FORMAT_HALF;
    return v;
}

/* op.h's host loops: the backends' per-pixel copies (kernels/view.h), row
 * after row */
void ew_view_pack(const ew_image *img, int c, float *dst) {
    const ew_view_desc v = view_desc(img);
    for (int y = 0; y < v.height; y++)
        for (int x = 0; x < v.width; x++) ew_view_pack_px(x, y, &v, c, dst);
}

void ew_view_unpack(const float *src, int c, const ew_image *img) {
    const ew_view_desc v = view_desc(img);
    for (int y = 0; y < v.height; y++)
        for (int x = 0; x < v.width; x++) ew_view_unpack_px(x, y, &v, c, src);
}

ew_result ew_dev_put_view(ew_device *dev, const ew_image *img, int c, float *dst, float *stage) {
    if (!dev->device_memory || dev->device_images) {
        /* the view is where the buffer is: pack in place, in parallel */
        const ew_view_desc v = view_desc(img);
        dev->backend->view_pack(dev, &v, c, dst);
        return EW_OK;
    }
    /* host view, device buffer: pack on the host (any stride, any sign),
     * then one contiguous upload */
    ew_view_pack(img, c, stage);
    return dev->backend->mem_upload(dev, dst, stage, (size_t)img->width * (size_t)img->height * (size_t)c * sizeof(float));
}

/* The bytes a view spans (any signs of its strides). */
static void view_span(const ew_image *img, const char **lo, const char **hi) {
    const int64_t ps = ew__pixel_stride(img), rs = ew__row_stride(img);
    const int64_t dx = (int64_t)(img->width - 1) * ps, dy = (int64_t)(img->height - 1) * rs;
    const int64_t a = (dx < 0 ? dx : 0) + (dy < 0 ? dy : 0), b = (dx > 0 ? dx : 0) + (dy > 0 ? dy : 0);
    *lo = (const char *)img->data + a;
    *hi = (const char *)img->data + b + (int64_t)img->channels * ew__channel_bytes(img);
}

int ew_images_overlap(const ew_image *a, const ew_image *b) {
    if (!a || !b || !a->data || !b->data) return 0;
    const char *a0, *a1, *b0, *b1;
    view_span(a, &a0, &a1);
    view_span(b, &b0, &b1);
    return a0 < b1 && b0 < a1;
}

const float *ew_dev_view_in_place(const ew_device *dev, const ew_image *img, int c, const ew_image *written) {
    if (!img || !img->data || (dev->device_memory && !dev->device_images)) return NULL;
    if (img->format != EW_FORMAT_FLOAT || img->channels != c || !ew__image_packed_as(img, c)) return NULL;
    if (written && written->data) {
        const char *a0, *a1, *b0, *b1;
        view_span(img, &a0, &a1);
        view_span(written, &b0, &b1);
        if (a0 < b1 && b0 < a1) return NULL;
    }
    return (const float *)img->data;
}

int ew_dev_view_half_rows(const ew_device *dev, const ew_image *img, int c) {
    return img && img->data && img->format == EW_FORMAT_HALF && img->channels >= c && !dev->device_memory;
}

typedef struct {
    ew_view_desc v; /* the rectangle */
    int c;
    float *buf;
} rows_job;

static void view_rows(void *ctx, int64_t y0, int64_t y1, int tid) {
    (void)tid;
    const rows_job *j = (const rows_job *)ctx;
    const size_t c = (size_t)j->c;
    for (int64_t y = y0; y < y1; y++) {
        if (j->v.pixel_stride == (long long)(c * 2)) { /* the row's pixels back to back: one run */
            const unsigned short *src = (const unsigned short *)(const void *)ew_view_px(&j->v, 0, (int)y);
            ew__halves_to_floats(src, j->buf + (size_t)y * (size_t)j->v.width * c, (size_t)j->v.width * c);
            continue;
        }
        for (int x = 0; x < j->v.width; x++) ew_view_pack_px(x, (int)y, &j->v, j->c, j->buf);
    }
}

void ew_dev_view_rows(ew_device *dev, const ew_image *img, int c, int y0, int y1, int x0, int x1, float *buf) {
    const ew_image rect = ew__image_crop(img, x0, y0, x1 - x0, y1 - y0);
    rows_job j = {view_desc(&rect), c, buf};
    ew_pool_run(dev->pool, y1 - y0, 0, view_rows, &j);
}

ew_result ew_dev_get_view(ew_device *dev, const float *src, int c, const ew_image *img, float *stage) {
    const ew_view_desc v = view_desc(img);
    if (!dev->device_memory || dev->device_images) {
        dev->backend->view_unpack(dev, src, c, &v);
        /* a device-pointer output stays queued (the caller's stream orders
         * it): report launch failures without waiting */
        return dev->backend->sync(dev, 0);
    }
    ew_result r = dev->backend->mem_download(dev, stage, src,
                                             (size_t)img->width * (size_t)img->height * (size_t)c * sizeof(float));
    if (r != EW_OK) return r;
    ew_view_unpack(stage, c, img);
    return EW_OK;
}

int ew_backend_first_missing(const ew_backend *b) {
    typedef void (*any_fn)(void);
    const size_t first = offsetof(ew_backend, name) + sizeof(b->name);
    const int n = (int)((sizeof(ew_backend) - first) / sizeof(any_fn));
    for (int i = 0; i < n; i++) {
        any_fn f;
        memcpy(&f, (const char *)b + first + (size_t)i * sizeof(any_fn), sizeof f);
        if (!f) return i;
    }
    return -1;
}

