/*
 * cpu_backend.c — the CPU backend: rows (or grid rows) are handed out to
 * the device's thread pool; each item calls the shared per-pixel function.
 */
#include "backends/cpu/cpu_bgrid.h"
#include "kernels/harm.h"
#include "kernels/denoise_px.h"
#include "kernels/guidenet.h"
#include "kernels/outlier.h"
#include "kernels/temporal.h"
#include "src/backend.h"
#include "src/internal.h"

typedef struct {
    const ew_bgrid_params *p;
    const float *a, *guide;
    float *dst;
    const ew_denoise_buffers *b;
} cpu_job;

/* splat and slice: cpu_bgrid.c */

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

typedef struct {
    const ew_denoise_buffers *b;
    float mean_lum, color_weight;
} refine_job;

static void refine_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const refine_job *r = (const refine_job *)ctx;
    for (int64_t j = begin * r->b->width; j < end * r->b->width; j++)
        ew_denoise_refine_guide_px((long)j, r->b, r->mean_lum, r->color_weight);
}

static void cpu_denoise_refine_guide(ew_device *dev, const ew_denoise_buffers *b, float mean_lum, float color_weight) {
    refine_job r = {b, mean_lum, color_weight};
    ew_pool_run(dev->pool, b->height, 0, refine_rows, &r);
}

typedef struct {
    const ew_outlier_params *p;
    const ew_outlier_buffers *b;
} outlier_guided_job;

static void outlier_guided_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const outlier_guided_job *j = (const outlier_guided_job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p->width; x++) ew_outlier_guided_px(x, (int)y, j->p, j->b);
}

static void cpu_outlier_guided(ew_device *dev, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    outlier_guided_job j = {p, b};
    ew_pool_run(dev->pool, p->height, 0, outlier_guided_rows, &j);
}

typedef struct {
    int step;
    const ew_harm_args *a;
} harm_job;

static void harm_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const harm_job *h = (const harm_job *)ctx;
    const ew_harm_args *a = h->a;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < a->width; x++) {
            const long j = (long)y * a->width + x;
            switch (h->step) {
            case EW_HARM_DEMOD: ew_harm_demod_px(j, a); break;
            case EW_HARM_REMOD: ew_harm_remod_px(j, a); break;
            case EW_HARM_STATS: ew_harm_stats_px(x, (int)y, a); break;
            case EW_HARM_SUM_H: ew_harm_sum_h_px(x, (int)y, a); break;
            case EW_HARM_SUM_V: ew_harm_sum_v_px(x, (int)y, a); break;
            case EW_HARM_GIVE: ew_harm_give_px(x, (int)y, a); break;
            case EW_HARM_SPREAD_H: ew_harm_spread_h_px(x, (int)y, a); break;
            case EW_HARM_SPREAD_V: ew_harm_spread_v_px(x, (int)y, a); break;
            default: ew_harm_blend_px(x, (int)y, a); break;
            }
        }
}

static void cpu_harm(ew_device *dev, int step, const ew_harm_args *a) {
    harm_job h = {step, a};
    ew_pool_run(dev->pool, a->height, 0, harm_rows, &h);
}

typedef struct {
    const ew_temporal_params *p;
    const ew_temporal_buffers *b;
} temporal_job;

static void temporal_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const temporal_job *j = (const temporal_job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p->width; x++) ew_temporal_px(x, (int)y, j->p, j->b);
}

static void cpu_temporal(ew_device *dev, const ew_temporal_params *p, const ew_temporal_buffers *b) {
    temporal_job j = {p, b};
    ew_pool_run(dev->pool, p->height, 0, temporal_rows, &j);
}

/* ---- the per-pixel GuideNet entries ------------------------------------ */
static void input_rows_shifted(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_gn_input_args *a = (const ew_gn_input_args *)ctx;
    for (int64_t y = a->y0 + begin; y < a->y0 + end; y++) {
        float *dst = a->dst + (y - a->y0) * a->rs;
        const long j0 = (long)y * a->width;
        for (int x = 0; x < a->width; x++)
            ew_gn_input_px(j0 + x, a->color, a->albedo, a->normal, a->depth, a->depth_scale, dst + x, a->ps);
    }
}

static void cpu_gn_input(ew_device *dev, const ew_gn_input_args *a) {
    /* the pool hands out [0, n): shift to the band's rows */
    ew_pool_run(dev->pool, a->y1 - a->y0, 0, input_rows_shifted, (void *)a);
}

typedef struct {
    long n;
    int ngrids;
    float *outputs;
} guides_job;

static void guides_range(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const guides_job *g = (const guides_job *)ctx;
    for (int64_t j = begin; j < end; j++) ew_nbg_guide_px((long)j, g->n, g->ngrids, g->outputs);
}

static void cpu_nbg_guides(ew_device *dev, long n, int ngrids, float *outputs) {
    guides_job g = {n, ngrids, outputs};
    ew_pool_run(dev->pool, n, 16384, guides_range, &g);
}

static void blend_range(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_nbg_blend_args *a = (const ew_nbg_blend_args *)ctx;
    for (int64_t j = begin; j < end; j++) ew_nbg_blend_px((long)j, a->s, a->ngrids, a->outputs, a->n, a->sliced, a->acc);
}

static void cpu_nbg_blend(ew_device *dev, const ew_nbg_blend_args *a) {
    ew_pool_run(dev->pool, a->n, 16384, blend_range, (void *)a);
}

const ew_backend ew_cpu_backend = {
    .name = "cpu",
    .bgrid_splat = ew_cpu_bgrid_splat,
    .bgrid_slice = ew_cpu_bgrid_slice,
    .denoise_prepare = cpu_denoise_prepare,
    .denoise_finish = cpu_denoise_finish,
    .denoise_refine_guide = cpu_denoise_refine_guide,
    .outlier_guided = cpu_outlier_guided,
    .harm = cpu_harm,
    .temporal = cpu_temporal,
    /* edge-aware filters (cpu_filters.c) */
    .bf_brute = ew_cpu_bf_brute,
    .bf_separable = ew_cpu_bf_separable,
    .pyr_down = ew_cpu_pyr_down,
    .pyr_up = ew_cpu_pyr_up,
    .pyr_row_hooks = 1,
    .dof_attributes = ew_cpu_dof_attributes,
    /* neural bilateral grid (the convolution: cpu_conv.c) */
    .conv5 = ew_cpu_conv5,
    .gn_input = cpu_gn_input,
    .nbg_guides = cpu_nbg_guides,
    .nbg_blend = cpu_nbg_blend,
    /* every kernel of EW_KERNEL_LIST (cpu_kernels.c) */
    .run = ew_cpu_run,
    /* device memory (cpu_memory.c) */
    .mem_alloc = ew_cpu_mem_alloc,
    .mem_free = ew_cpu_mem_free,
    .mem_upload = ew_cpu_mem_upload,
    .mem_download = ew_cpu_mem_download,
    .mem_copy = ew_cpu_mem_copy,
    .mem_zero = ew_cpu_mem_zero,
    .sync = ew_cpu_sync,
    .reduce_rows = ew_cpu_reduce_rows,
    .view_pack = ew_cpu_view_pack,
    .view_unpack = ew_cpu_view_unpack,
    .device_release = ew_cpu_device_release,
};
