/*
 * half_rows.c — a run of halves to floats (ew__halves_to_floats): what
 * reading EW_FORMAT_HALF views costs per value. On x86 with F16C, 8 at a
 * time in hardware (vcvtph2ps: exact, as kernels/half.h; a signalling NaN
 * comes out quiet, which no reader tells apart); elsewhere value by value.
 */
#include "src/internal.h"

#if defined(__GNUC__) && defined(__x86_64__)
#pragma GCC push_options
#pragma GCC target("f16c,avx")
#include <immintrin.h>
static void halves_f16c(const unsigned short *s, float *d, size_t n) {
    size_t i = 0;
    for (; i + 8 <= n; i += 8) _mm256_storeu_ps(d + i, _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(const void *)(s + i))));
    for (; i < n; i++) d[i] = ew_half_to_float(s[i]);
}
#pragma GCC pop_options
#define EW_HAVE_F16C_PATH 1
#endif

void ew__halves_to_floats(const unsigned short *s, float *d, size_t n) {
#ifdef EW_HAVE_F16C_PATH
    static int f16c = -1; /* the CPU's answer, the same on every call */
    if (f16c < 0) {
        __builtin_cpu_init();
        __atomic_store_n(&f16c, __builtin_cpu_supports("f16c") && __builtin_cpu_supports("avx"), __ATOMIC_RELAXED);
    }
    if (__atomic_load_n(&f16c, __ATOMIC_RELAXED)) {
        halves_f16c(s, d, n);
        return;
    }
#endif
    for (size_t i = 0; i < n; i++) d[i] = ew_half_to_float(s[i]);
}
