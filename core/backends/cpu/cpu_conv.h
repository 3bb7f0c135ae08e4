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

/* ---- Winograd F(4x4, 5x5) --------------------------------------------
 * The backend entry's fast path for inference (cpu_conv_wino.h): 64
 * products per 4x4 output tile and channel pair instead of 400, equal to
 * the direct convolution up to rounding (about 1e-5 of the output's
 * magnitude; tests/unit/test_conv.c), not to the bit. The trainer calls
 * ew_conv_cpu_rows, which stays direct: its gradients are checked against
 * the bits of the forward pass. AVX2 + FMA or AVX-512 only. */
#define EW_CONV_CPU_AUTO 0     /* Winograd where ew_conv_cpu_wino_pays, unless the device forces direct */
#define EW_CONV_CPU_DIRECT 1
#define EW_CONV_CPU_WINOGRAD 2 /* falls back to direct without AVX2 + FMA or with accumulate */
/* The automatic choice takes Winograd where the caller allows it
 * (a->winograd), not in accumulate mode, and from this many channel pairs
 * cin * cout (its transforms cost per input and per output channel, the
 * products per pair): measured with train_kpcn --bench. */
#define EW_CONV_CPU_WINO_MIN_PAIRS 64
int ew_conv_cpu_wino_pays(const ew_conv_args *a);
/* The backend's conv5 by path (EW_CONV_CPU_*) with the instruction set
 * capped at level (ew_conv_cpu_simd_level's numbers); returns the path
 * that ran. ew_cpu_conv5 is (dev, a, EW_CONV_CPU_AUTO, 2). */
int ew_cpu_conv5_path(ew_device *dev, const ew_conv_args *a, int path, int level);

#endif
