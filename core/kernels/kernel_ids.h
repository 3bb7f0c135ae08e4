/*
 * kernel_ids.h — every per-pixel kernel that backends launch by id, each
 * declared once. From this one list the CPU backend builds its row loop
 * (backends/cpu/cpu_kernels.c), the CUDA module its __global__ wrapper and
 * launcher (backends/cuda/cuda_backend.cu), and the launch-grid harness its
 * mirror (tests/unit/lg_harness.c); an op launches one with
 * EW_RUN(dev, NAME, &args) (src/backend.h).
 *
 * X(NAME, ARGS, PX, W, H, VEC):
 *   ARGS  the kernel's argument struct (its tag must be its typedef name);
 *         every pointer in it is a device buffer, since CUDA gets the struct
 *         by value;
 *   PX    the EW_HD per-pixel function, PX(int x, int y, const ARGS *a);
 *   W, H  the members of ARGS giving the domain: one work item per (x, y)
 *         with x < a->W, y < a->H, each writing only its own outputs;
 *   VEC   1: the CPU row loop is also built for wider vector units
 *         (src/cpu_clones.h), for kernels that vectorise across pixels;
 *         2: the CPU backend has its own row loop, rows_NAME
 *         (backends/cpu/cpu_kernels.c includes it), giving PX's bits for
 *         every pixel (the launch-grid parity test compares them exactly).
 * The kernel's header goes in kernels/kernel_list.h.
 *
 * This header holds no types: an op includes only its own kernel's header.
 */
#ifndef EW_KERNELS_KERNEL_IDS_H
#define EW_KERNELS_KERNEL_IDS_H

#define EW_KERNEL_LIST(X)                                                              \
    X(atrous, ew_atrous_args, ew_atrous_px, w, h, 1)                                   \
    X(kpcn_input, ew_kpcn_input_args, ew_kpcn_input_px, width, height, 0)              \
    X(kpcn_pool, ew_kpcn_pool_args, ew_kpcn_pool_px, cw, ch, 2)                        \
    X(kpcn_up, ew_kpcn_up_args, ew_kpcn_up_px, fw, fh, 2)                              \
    X(kpcn_filter, ew_kpcn_filter_args, ew_kpcn_filter_px, width, height, 2)          \
    X(mirror_swap, ew_mirror_swap_args, ew_mirror_swap_px, dw, dh, 0)                  \
    X(mirror_add, ew_mirror_add_args, ew_mirror_add_px, width, height, 0)

#define EW_KERNEL_ID_(NAME, ARGS, PX, W, H, VEC) EW_K_##NAME,
enum ew_kernel_id { EW_KERNEL_LIST(EW_KERNEL_ID_) EW_KERNEL_COUNT };
#undef EW_KERNEL_ID_

/* The list as one string: the CUDA module reports the list it was built
 * with, and the loader refuses a module whose ids mean other kernels. */
#define EW_KERNEL_NAME_(NAME, ARGS, PX, W, H, VEC) #NAME "(" #ARGS ") "
#define EW_KERNEL_NAMES EW_KERNEL_LIST(EW_KERNEL_NAME_)

/* ew_kargs_NAME(a): a itself, so that EW_RUN refuses at compile time an
 * argument struct of another kernel. */
#define EW_KERNEL_ARGS_CHECK_(NAME, ARGS, PX, W, H, VEC) \
    struct ARGS;                                          \
    static inline const void *ew_kargs_##NAME(const struct ARGS *a) { return a; }
EW_KERNEL_LIST(EW_KERNEL_ARGS_CHECK_)
#undef EW_KERNEL_ARGS_CHECK_

#endif
