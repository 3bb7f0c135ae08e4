/*
 * cpu_filters.c — CPU loops for the edge-aware filters: rows go to the
 * device's thread pool, each pixel calls the shared function of
 * kernels/{bilateral,pyramid,atrous,dof}.h. Every pass writes a buffer the
 * same pass does not read, so rows are independent and the result does not
 * depend on the thread count.
 *
 * The per-pixel functions take the model kind as an argument; the row loops
 * below are instantiated once per kind with a constant and `flatten`, so the
 * compiler inlines everything and drops the other kinds' code from the inner
 * loops (what a template would do). The brute force, the separable filter
 * and the pyramid all get the same treatment, so their speed ratios compare
 * the algorithms, not the effort spent on each.
 */
#include "src/backend.h"
#include "src/internal.h"

#if defined(__GNUC__)
#define EW_FLATTEN __attribute__((flatten))
#else
#define EW_FLATTEN
#endif

/* One row function per kind: NAME_<kind>(ctx, begin, end, tid) runs
 * BODY(kind) for rows [begin, end); NAME picks one by kind. */
#define EW_ROWS_PER_KIND(NAME, CTX_T, BODY)                                                                    \
    static EW_FLATTEN void NAME##_k(const CTX_T *j, int64_t begin, int64_t end, const int kind) { BODY }        \
    static EW_FLATTEN void NAME##_color(void *c, int64_t b, int64_t e, int t) { (void)t; NAME##_k((const CTX_T *)c, b, e, EW_RANGE_COLOR); } \
    static EW_FLATTEN void NAME##_gi(void *c, int64_t b, int64_t e, int t) { (void)t; NAME##_k((const CTX_T *)c, b, e, EW_RANGE_GI); } \
    static EW_FLATTEN void NAME##_depth(void *c, int64_t b, int64_t e, int t) { (void)t; NAME##_k((const CTX_T *)c, b, e, EW_RANGE_DEPTH); } \
    static EW_FLATTEN void NAME##_dof(void *c, int64_t b, int64_t e, int t) { (void)t; NAME##_k((const CTX_T *)c, b, e, EW_RANGE_DOF); } \
    static EW_FLATTEN void NAME##_none(void *c, int64_t b, int64_t e, int t) { (void)t; NAME##_k((const CTX_T *)c, b, e, EW_RANGE_NONE); } \
    static ew_range_fn NAME(int kind) {                                                                         \
        switch (kind) {                                                                                         \
        case EW_RANGE_COLOR: return NAME##_color;                                                               \
        case EW_RANGE_GI: return NAME##_gi;                                                                     \
        case EW_RANGE_DEPTH: return NAME##_depth;                                                               \
        case EW_RANGE_DOF: return NAME##_dof;                                                                   \
        default: return NAME##_none;                                                                            \
        }                                                                                                       \
    }

typedef struct {
    const ew_bf_model *m;
    const ew_bf_buffers *b;
    int axis;
} bf_job;

EW_ROWS_PER_KIND(brute_rows, bf_job,
                 for (int64_t y = j->b->y0 + begin; y < j->b->y0 + end; y++)
                     for (int x = 0; x < j->b->width; x++) ew_bf_brute_px_k(x, (int)y, j->m, j->b, kind);)

void ew_cpu_bf_brute(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b) {
    bf_job j = {m, b, 0};
    ew_pool_run(dev->pool, b->y1 - b->y0, 1, brute_rows(m->kind), &j);
}

EW_ROWS_PER_KIND(sep_rows, bf_job,
                 for (int64_t y = begin; y < end; y++)
                     for (int x = 0; x < j->b->width; x++) ew_bf_sep_px_k(x, (int)y, j->axis, j->m, j->b, kind);)

void ew_cpu_bf_separable(ew_device *dev, const ew_bf_model *m, int axis, const ew_bf_buffers *b) {
    bf_job j = {m, b, axis};
    ew_pool_run(dev->pool, b->height, 0, sep_rows(m->kind), &j);
}

EW_ROWS_PER_KIND(down_rows, ew_pyr_down_args,
                 for (int64_t y = begin; y < end; y++)
                     for (int x = 0; x < j->cw; x++) ew_pyr_down_px_k(x, (int)y, j, kind);)

void ew_cpu_pyr_down(ew_device *dev, const ew_pyr_down_args *a) {
    ew_pool_run(dev->pool, a->ch, 0, down_rows(a->m->kind), (void *)a);
}

EW_ROWS_PER_KIND(up_rows, ew_pyr_up_args,
                 for (int64_t y = begin; y < end; y++)
                     for (int x = 0; x < j->w; x++) ew_pyr_up_px_k(x, (int)y, j, kind);)

void ew_cpu_pyr_up(ew_device *dev, const ew_pyr_up_args *a) {
    ew_pool_run(dev->pool, a->h, 0, up_rows(a->m->kind), (void *)a);
}

static void atrous_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_atrous_args *a = (const ew_atrous_args *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < a->w; x++) ew_atrous_px(x, (int)y, a);
}

void ew_cpu_atrous_pass(ew_device *dev, const ew_atrous_args *a) {
    ew_pool_run(dev->pool, a->h, 0, atrous_rows, (void *)a);
}

typedef struct {
    const ew_dof_args *a;
    int step;
} dof_job;

static void dof_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const dof_job *j = (const dof_job *)ctx;
    const ew_dof_args *a = j->a;
    const int W = a->cam.width;
    for (int64_t y = begin; y < end; y++) {
        switch (j->step) {
        case 0:
            for (int x = 0; x < W; x++) ew_dof_coc_px((long)y * W + x, a);
            break;
        case 1:
            for (int x = 0; x < a->tw; x++) ew_dof_tile_px(x, (int)y, a);
            break;
        case 2:
        case 3:
            for (int x = 0; x < a->tw; x++) ew_dof_scatter_px(x, (int)y, j->step - 2, a);
            break;
        default:
            for (int x = 0; x < W; x++) ew_dof_attr_px(x, (int)y, a);
            break;
        }
    }
}

void ew_cpu_dof_attributes(ew_device *dev, const ew_dof_args *a) {
    for (int step = 0; step < 5; step++) {
        dof_job j = {a, step};
        int64_t rows = step == 0 || step == 4 ? a->cam.height : a->th;
        ew_pool_run(dev->pool, rows, 0, dof_rows, &j);
    }
}
