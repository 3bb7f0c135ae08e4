/*
 * cpu_clones.h — EW_MULTIVERSION: a CPU loop built for AVX-512F, AVX2 and
 * the baseline, one picked when the library loads.
 */
#ifndef EW_SRC_CPU_CLONES_H
#define EW_SRC_CPU_CLONES_H

/* The filters' loops over pixels (the exact and separable filters' rows,
 * the pyramid's spans, a-trous, the DoF attributes: cpu_filters.c,
 * cpu_kernels.c) and the packers' loops (bilateral.c) are also compiled
 * for AVX-512F and AVX2 and the CPU picks one at load time (an ifunc), so the speed ratios compare algorithms on the
 * machine's vector width, not one filter's build against another's (and
 * SSE2 alone lacks the blends, gathers and integer ops the branch-free
 * kernels need). No FMA is requested and the C11 build contracts nothing
 * (-ffp-contract=off in ISO mode), so every variant computes the same IEEE
 * operations and results do not depend on the CPU. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && !defined(EW_NO_MULTIVERSION)
#define EW_MULTIVERSION __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define EW_MULTIVERSION
#endif

#endif
