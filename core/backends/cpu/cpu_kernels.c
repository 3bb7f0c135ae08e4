/*
 * cpu_kernels.c — the CPU backend's run: for every kernel of EW_KERNEL_LIST
 * (kernels/kernel_ids.h), a row loop that calls its per-pixel function over
 * the rows the device's thread pool hands out. Each work item writes only
 * its own outputs, so the result does not depend on the thread count.
 */
/* No trapping math, as in cpu_filters.c: the compiler may if-convert and
 * vectorise across pixels; IEEE results are unchanged. Before the includes,
 * so the kernels' inline functions get it too. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("no-trapping-math")
#endif
#include "kernels/kernel_list.h"
#include "src/backend.h"
#include "src/cpu_clones.h" /* EW_MULTIVERSION */
#include "src/internal.h"

#if defined(__GNUC__)
#define EW_KROWS_ATTR_1 EW_MULTIVERSION __attribute__((flatten))
#else
#define EW_KROWS_ATTR_1
#endif
#define EW_KROWS_ATTR_0

#define EW_KROWS_LOOP_(NAME, ARGS, PX, W, ATTR)                                     \
    static ATTR void rows_##NAME(void *ctx, int64_t begin, int64_t end, int tid) {  \
        (void)tid;                                                                  \
        const ARGS *a = (const ARGS *)ctx;                                          \
        for (int64_t y = begin; y < end; y++)                                       \
            for (int x = 0; x < a->W; x++) PX(x, (int)y, a);                        \
    }
#define EW_KROWS_0(NAME, ARGS, PX, W) EW_KROWS_LOOP_(NAME, ARGS, PX, W, EW_KROWS_ATTR_0)
#define EW_KROWS_1(NAME, ARGS, PX, W) EW_KROWS_LOOP_(NAME, ARGS, PX, W, EW_KROWS_ATTR_1)
#define EW_KROWS_2(NAME, ARGS, PX, W) /* rows_NAME: its own row loop, included below */
#define EW_KROWS_(NAME, ARGS, PX, W, H, VEC) EW_KROWS_##VEC(NAME, ARGS, PX, W)
EW_KERNEL_LIST(EW_KROWS_)
#undef EW_KROWS_

/* the kernels of VEC 2 */
#include "cpu_kpcn_filter.h"
#include "cpu_kpcn_pool.h"
#include "cpu_kpcn_up.h"

ew_result ew_cpu_run(ew_device *dev, int id, const void *args, size_t args_size) {
    switch (id) {
#define EW_KCASE_(NAME, ARGS, PX, W, H, VEC)                                                   \
    case EW_K_##NAME:                                                                          \
        if (args_size != sizeof(ARGS)) break;                                                  \
        ew_pool_run(dev->pool, ((const ARGS *)args)->H, 0, rows_##NAME, (void *)(uintptr_t)args); \
        return EW_OK;
        EW_KERNEL_LIST(EW_KCASE_)
#undef EW_KCASE_
    default: break;
    }
    return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "CPU backend: no kernel %d taking %zu bytes of arguments", id,
                    args_size);
}
