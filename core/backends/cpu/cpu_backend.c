/*
 * cpu_backend.c — the CPU backend: rows (or grid columns) are handed out to
 * the device's thread pool; each item calls the shared per-pixel function.
 */
#include "src/backend.h"
#include "src/internal.h"

typedef struct {
    const ew_bgrid_params *p;
    const float *a, *guide;
    float *dst;
    const ew_denoise_buffers *b;
} cpu_job;

static void splat_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const cpu_job *j = (const cpu_job *)ctx;
    for (int64_t v = begin; v < end; v++)
        for (int u = 0; u < j->p->gw; u++) ew_bgrid_splat_column(u, (int)v, j->p, j->a, j->guide, j->dst);
}

static void cpu_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image,
                            const float *guide, float *grid) {
    cpu_job j = {p, image, guide, grid, NULL};
    ew_pool_run(dev->pool, p->gh, 1, splat_rows, &j);
}

static void slice_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const cpu_job *j = (const cpu_job *)ctx;
    const int C = j->p->channels;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p->width; x++)
            ew_bgrid_slice_px(x, (int)y, j->p, j->a, j->guide,
                              j->dst + ((int64_t)y * j->p->width + x) * C);
}

static void cpu_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid,
                            const float *guide, float *out) {
    cpu_job j = {p, grid, guide, out, NULL};
    ew_pool_run(dev->pool, p->height, 0, slice_rows, &j);
}

static void prepare_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_denoise_buffers *b = ((const cpu_job *)ctx)->b;
    for (int64_t j = begin * b->width; j < end * b->width; j++) ew_denoise_prepare_px((long)j, b);
}

static void finish_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_denoise_buffers *b = ((const cpu_job *)ctx)->b;
    for (int64_t j = begin * b->width; j < end * b->width; j++) ew_denoise_finish_px((long)j, b);
}

static void cpu_denoise_prepare(ew_device *dev, const ew_denoise_buffers *b) {
    cpu_job j = {NULL, NULL, NULL, NULL, b};
    ew_pool_run(dev->pool, b->height, 0, prepare_rows, &j);
}

static void cpu_denoise_finish(ew_device *dev, const ew_denoise_buffers *b) {
    cpu_job j = {NULL, NULL, NULL, NULL, b};
    ew_pool_run(dev->pool, b->height, 0, finish_rows, &j);
}

const ew_backend ew_cpu_backend = {
    "cpu", cpu_bgrid_splat, cpu_bgrid_slice, cpu_denoise_prepare, cpu_denoise_finish,
};
