/*
 * launch_grid.h — the CUDA launch geometry, written once for both sides:
 * the CUDA module computes grids with these functions and launches them;
 * the CPU harness (tests/unit/test_launch_grid.c) walks the very same grids,
 * block by block and thread by thread, through the same kernel bodies
 * (backends/cuda/kernel_bodies.h). So index arithmetic, bounds checks and
 * argument fix-ups are tested on every machine, with or without a GPU.
 */
#ifndef EW_BACKENDS_LAUNCH_GRID_H
#define EW_BACKENDS_LAUNCH_GRID_H

#include "kernels/compat.h"

typedef struct ew_dim3 {
    unsigned x, y, z;
} ew_dim3;

/* <<<grid, block>>> */
typedef struct ew_launch {
    ew_dim3 grid, block;
} ew_launch;

/* What a thread knows about itself: blockIdx, blockDim, threadIdx. */
typedef struct ew_thread {
    ew_dim3 block_idx, block_dim, thread_idx;
} ew_thread;

/* 2-D blocks of 16 x 8: a warp covers 16 consecutive pixels of two rows, so
 * loads along a row coalesce; 128 threads leave room for the register-heavy
 * kernels (bilateral windows) on every architecture from sm_75. */
#define EW_BLOCK_X 16
#define EW_BLOCK_Y 8
#define EW_BLOCK_1D 128

EW_HD unsigned ew_div_up(long long n, unsigned b) { return n <= 0 ? 0u : (unsigned)((n + (long long)b - 1) / (long long)b); }

EW_HD ew_dim3 ew_dim3_make(unsigned x, unsigned y, unsigned z) {
    ew_dim3 d;
    d.x = x;
    d.y = y;
    d.z = z;
    return d;
}

/* One thread per (x, y) of a w x h domain. Grid y stays below CUDA's 65535
 * limit: EW_MAX_SIDE / EW_BLOCK_Y = 8192. */
EW_HD ew_launch ew_launch_2d(int w, int h) {
    ew_launch l;
    l.block = ew_dim3_make(EW_BLOCK_X, EW_BLOCK_Y, 1);
    l.grid = ew_dim3_make(ew_div_up(w, EW_BLOCK_X), ew_div_up(h, EW_BLOCK_Y), 1);
    return l;
}

/* One thread per (x, y, z) of a w x h x d domain: z runs over grid z (d
 * stays below 65535: channel counts). */
EW_HD ew_launch ew_launch_3d(int w, int h, int d) {
    ew_launch l = ew_launch_2d(w, h);
    l.grid.z = ew_div_up(d, 1);
    return l;
}

/* One thread per item of [0, n): grid x allows 2^31 - 1 blocks. */
EW_HD ew_launch ew_launch_1d(long long n) {
    ew_launch l;
    l.block = ew_dim3_make(EW_BLOCK_1D, 1, 1);
    l.grid = ew_dim3_make(ew_div_up(n, EW_BLOCK_1D), 1, 1);
    return l;
}

/* A launch with no blocks is an error on CUDA: callers skip it. */
EW_HD int ew_launch_empty(const ew_launch *l) { return l->grid.x == 0 || l->grid.y == 0 || l->grid.z == 0; }

/* Global indices. Widened before multiplying: blockIdx.x * blockDim.x of
 * a large 1-D launch would wrap in 32 bits. */
EW_HD int ew_tx(const ew_thread *t) { return (int)((long long)t->block_idx.x * t->block_dim.x + t->thread_idx.x); }
EW_HD int ew_ty(const ew_thread *t) { return (int)((long long)t->block_idx.y * t->block_dim.y + t->thread_idx.y); }
EW_HD int ew_tz(const ew_thread *t) { return (int)((long long)t->block_idx.z * t->block_dim.z + t->thread_idx.z); }
EW_HD long ew_t1(const ew_thread *t) { return (long)((long long)t->block_idx.x * t->block_dim.x + t->thread_idx.x); }

#ifdef __CUDACC__
/* Device side: the thread's own coordinates from the CUDA built-ins. */
__device__ inline ew_thread ew_thread_self(void) {
    ew_thread t;
    t.block_idx = ew_dim3_make(blockIdx.x, blockIdx.y, blockIdx.z);
    t.block_dim = ew_dim3_make(blockDim.x, blockDim.y, blockDim.z);
    t.thread_idx = ew_dim3_make(threadIdx.x, threadIdx.y, threadIdx.z);
    return t;
}
#else
/*
 * CPU side: run the statement (the variadic part, so it may hold commas)
 * once for every thread of launch `l`, with `t` (an ew_thread) describing it. Blocks and the threads in them go in reverse
 * order: a GPU promises no order at all, and a kernel whose result depends
 * on it then differs from the CPU backend's forward loops.
 */
#define EW_LAUNCH_WALK(l, t, ...)                                                                    \
    do {                                                                                             \
        const ew_launch ew_l_ = (l);                                                                 \
        ew_thread t;                                                                                 \
        t.block_dim = ew_l_.block;                                                                   \
        for (long long ew_b_ = (long long)ew_l_.grid.x * ew_l_.grid.y * ew_l_.grid.z - 1; ew_b_ >= 0; \
             ew_b_--) {                                                                              \
            t.block_idx.x = (unsigned)(ew_b_ % ew_l_.grid.x);                                        \
            t.block_idx.y = (unsigned)(ew_b_ / ew_l_.grid.x % ew_l_.grid.y);                         \
            t.block_idx.z = (unsigned)(ew_b_ / ((long long)ew_l_.grid.x * ew_l_.grid.y));            \
            for (long long ew_i_ = (long long)ew_l_.block.x * ew_l_.block.y * ew_l_.block.z - 1;     \
                 ew_i_ >= 0; ew_i_--) {                                                              \
                t.thread_idx.x = (unsigned)(ew_i_ % ew_l_.block.x);                                  \
                t.thread_idx.y = (unsigned)(ew_i_ / ew_l_.block.x % ew_l_.block.y);                  \
                t.thread_idx.z = (unsigned)(ew_i_ / ((long long)ew_l_.block.x * ew_l_.block.y));     \
                __VA_ARGS__;                                                                         \
            }                                                                                        \
        }                                                                                            \
    } while (0)
#endif

#endif
