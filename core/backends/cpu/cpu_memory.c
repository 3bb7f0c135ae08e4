/*
 * cpu_memory.c — the memory entries of the CPU backend. Device
 * memory is host memory here, so these are malloc/memcpy; they exist so that
 * algorithms have one code path for the CPU and for backends with memory of
 * their own (docs/backends.md). Work runs synchronously on the device's
 * threads, so there is never a queued failure to report.
 */
#include <stdlib.h>
#include <string.h>

#include "kernels/fastmath.h" /* ew_bits_to_float */
#include "kernels/reduce.h"
#include "kernels/view.h"
#include "src/backend.h"
#include "src/internal.h"
#include "src/cpu_clones.h" /* EW_MULTIVERSION */

/* From this size up a block is made as the host's frames are (ew_host_alloc:
 * aligned to 2 MiB, in huge pages where the kernel has them free), since a
 * VM pays every 4 KiB page's first touch in the hypervisor; the alignment
 * adds up to 2 MiB of address space to the block, under 1/16 of it here. */
#define HUGE_BLOCK ((size_t)32 << 20)

void *ew_cpu_mem_alloc(ew_device *dev, size_t bytes) {
    (void)dev;
    /* 64-byte aligned like cudaMalloc's 256: rows of floats start on a cache line */
    void *p = NULL;
    size_t n = (bytes + 63) & ~(size_t)63;
    if (n >= HUGE_BLOCK) return ew_host_alloc(n);
    if (posix_memalign(&p, 64, n ? n : 64) != 0) return NULL;
    return p;
}

void ew_cpu_mem_free(ew_device *dev, void *ptr) {
    (void)dev;
    free(ptr);
}

ew_result ew_cpu_mem_upload(ew_device *dev, void *dst, const void *src, size_t bytes) {
    (void)dev;
    if (bytes && dst != src) memcpy(dst, src, bytes);
    return EW_OK;
}

ew_result ew_cpu_mem_download(ew_device *dev, void *dst, const void *src, size_t bytes) {
    (void)dev;
    if (bytes && dst != src) memcpy(dst, src, bytes);
    return EW_OK;
}

ew_result ew_cpu_mem_copy(ew_device *dev, void *dst, const void *src, size_t bytes) {
    (void)dev;
    if (bytes && dst != src) memmove(dst, src, bytes);
    return EW_OK;
}

ew_result ew_cpu_mem_zero(ew_device *dev, void *ptr, size_t bytes) {
    (void)dev;
    if (bytes) memset(ptr, 0, bytes);
    return EW_OK;
}

ew_result ew_cpu_sync(ew_device *dev, int wait) {
    (void)dev;
    (void)wait;
    return EW_OK;
}

typedef struct {
    int op, width;
    const float *src;
    double *out;
    const ew_view_desc *v;
    int c;
    float *dst;
    const float *packed;
} mem_job;

/* cl[x] = ew_reduce_clum of pixel x of a row of RGB (vectorised: the
 * clamp at 0 as a select on the bits) */
static EW_MULTIVERSION void clum_span(float *EW_RESTRICT cl, const float *EW_RESTRICT rgb, long w) {
    for (long x = 0; x < w; x++) {
        const float l = ew_luminance(rgb + 3 * x);
        const int pos = -(l > 0.0f);
        const float m = ew_bits_to_float(ew_float_to_bits(l) & pos); /* ew_maxf(l, 0.0f) */
        cl[x] = m / (1.0f + m);
    }
}

/* EW_REDUCE_NOISE of rows [begin, end) as ew_reduce_row, with each row's
 * compressed luminance computed once (ew_reduce_row takes four a pixel)
 * and the same sums in the same order: the same bits. 0: no memory. */
static int noise_rows(const mem_job *j, int64_t begin, int64_t end) {
    const long w = j->width;
    float *buf = (float *)malloc(2 * (size_t)(w > 0 ? w : 1) * sizeof(float));
    if (!buf) return 0;
    float *prev = buf, *cur = buf + w;
    for (int64_t y = begin; y < end; y++) {
        double a = 0.0, b = 0.0;
        if (y > 0) {
            if (y == begin) clum_span(prev, j->src + (y - 1) * w * 3, w);
            clum_span(cur, j->src + y * w * 3, w);
            for (long x = 0; x + 1 < w; x++) {
                const float hh = 0.5f * (prev[x] - prev[x + 1] - cur[x] + cur[x + 1]);
                if (ew_finitef(hh)) {
                    a += (double)(hh < 0.0f ? -hh : hh);
                    b += 1.0;
                }
            }
        } else {
            clum_span(cur, j->src, w);
        }
        j->out[2 * y] = a;
        j->out[2 * y + 1] = b;
        float *t = prev;
        prev = cur;
        cur = t;
    }
    free(buf);
    return 1;
}

static void reduce_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const mem_job *j = (const mem_job *)ctx;
    if (j->op == EW_REDUCE_NOISE && noise_rows(j, begin, end)) return;
    for (int64_t y = begin; y < end; y++) ew_reduce_row(j->op, (int)y, j->width, j->src, j->out);
}

void ew_cpu_reduce_rows(ew_device *dev, int op, int width, int height, const float *src, double *out) {
    mem_job j = {op, width, src, out, NULL, 0, NULL, NULL};
    ew_pool_run(dev->pool, height, 0, reduce_rows, &j);
}

static void pack_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const mem_job *j = (const mem_job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->v->width; x++) ew_view_pack_px(x, (int)y, j->v, j->c, j->dst);
}

void ew_cpu_view_pack(ew_device *dev, const ew_view_desc *v, int c, float *dst) {
    mem_job j = {0, 0, NULL, NULL, v, c, dst, NULL};
    ew_pool_run(dev->pool, v->height, 0, pack_rows, &j);
}

static void unpack_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const mem_job *j = (const mem_job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->v->width; x++) ew_view_unpack_px(x, (int)y, j->v, j->c, j->packed);
}

void ew_cpu_view_unpack(ew_device *dev, const float *src, int c, const ew_view_desc *v) {
    mem_job j = {0, 0, NULL, NULL, v, c, NULL, src};
    ew_pool_run(dev->pool, v->height, 0, unpack_rows, &j);
}

void ew_cpu_device_release(ew_device *dev) { (void)dev; }
