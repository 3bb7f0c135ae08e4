/*
 * cpu_conv.h — the CPU's 5x5 convolutions of GuideNet and KPCN: SIMD blocks (AVX-512
 * or AVX2 + FMA when the processor has them, chosen at run time; portable vectors
 * otherwise), the backend table's conv5 entry (ew_cpu_conv5, declared in
 * src/backend.h) that runs them on the device's threads, and the single-threaded pieces the trainer calls per
 * patch.
 */
#ifndef EW_BACKENDS_CPU_CPU_CONV_H
#define EW_BACKENDS_CPU_CPU_CONV_H

#include <stddef.h>

#include "kernels/conv.h"

typedef struct ew_device ew_device;

/* Largest cin * cout whose weight copy the backend entry keeps on the stack
 * (a host's worker thread may have a small one); larger layers' copy is
 * allocated, and only if that fails do they take the per-value code. */
#define EW_CONV_CPU_STACK_CHANNEL_PAIRS 512

/* The weight layout the SIMD blocks read: per block of output channels
 * (one block of 5 when cout == 5, else blocks of 4 and the rest),
 * [cin][25][block]. Same number of floats as the [cout][cin][5][5] input. */
void ew_conv_cpu_wt_layout(int cin, int cout, const float *w, float *wt);
/* Output rows [r0, r1) of a convolution on this thread; wt from
 * ew_conv_cpu_wt_layout(a->weight). */
void ew_conv_cpu_rows(const ew_conv_args *a, const float *wt, int r0, int r1);
/* Add dL/dW ([cout][cin][25]) and dL/db (NULL: skip) of a convolution to dw
 * and db, given g = dL/d(pre-activation) with zero padding; this thread. */
void ew_conv_cpu_dweight(const ew_conv_args *a, const float *g, long g_rs, long g_ps, float *dw, float *db);
/* The forward blocks in use: 2 AVX-512 (16-float vectors), 1 AVX2 + FMA,
 * 0 portable vectors (for benchmarks to report). The AVX-512 and AVX2 blocks
 * give the same bits; the weight gradient always uses AVX2 (or portable). */
int ew_conv_cpu_simd_level(void);
const char *ew_conv_cpu_simd_name(int level);
/* ew_conv_cpu_rows with the instruction set capped at `level` (tests). */
void ew_conv_cpu_rows_level(const ew_conv_args *a, const float *wt, int r0, int r1, int level);
/* The machine's fused multiply-add throughput as the benchmark sees it: 12
 * independent FMA chains of the forward blocks' vector width per thread on
 * every thread of dev, in GFLOP/s (0 without AVX2). *seconds: the time it
 * took. */
double ew_conv_cpu_fma_gflops(ew_device *dev, double *seconds);

#endif
