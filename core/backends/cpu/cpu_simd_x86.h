/*
 * cpu_simd_x86.h — the vector macros the CPU's SIMD bodies (cpu_conv_block.h,
 * cpu_conv_wino.h) are written in, for one x86 instruction set: the includer
 * defines EW_V (the vector type, __m256 or __m512) and EW_MM(op) (its
 * intrinsics' prefix: _mm256_##op, _mm512_##op) under the matching
 * `#pragma GCC target`, includes this, then the bodies, then
 * cpu_simd_end.h. One definition of each operation for both widths, so the
 * AVX2 and AVX-512 paths cannot drift apart (both must give the same bits).
 */
#define EW_VLOAD(p) EW_MM(loadu_ps)(p)
#define EW_VSTORE(p, v) EW_MM(storeu_ps)((p), (v))
#define EW_VSET1(f) EW_MM(set1_ps)(f)
#define EW_VZERO() EW_MM(setzero_ps)()
#define EW_VFMA(a, b, c) EW_MM(fmadd_ps)((a), (b), (c))
#define EW_VADD(a, b) EW_MM(add_ps)((a), (b))
#define EW_VSUB(a, b) EW_MM(sub_ps)((a), (b))
#define EW_VMUL(a, b) EW_MM(mul_ps)((a), (b))
#define EW_VMAX(a, b) EW_MM(max_ps)((a), (b))
/* Transpose the 4x4 blocks of four vectors (each 128-bit lane on its own). */
#define EW_VTRANS4(a, b, c, d)                                                                                       \
    do {                                                                                                             \
        const EW_V t0_ = EW_MM(unpacklo_ps)((a), (b)), t1_ = EW_MM(unpackhi_ps)((a), (b));                           \
        const EW_V t2_ = EW_MM(unpacklo_ps)((c), (d)), t3_ = EW_MM(unpackhi_ps)((c), (d));                           \
        (a) = EW_MM(shuffle_ps)(t0_, t2_, 0x44);                                                                     \
        (b) = EW_MM(shuffle_ps)(t0_, t2_, 0xEE);                                                                     \
        (c) = EW_MM(shuffle_ps)(t1_, t3_, 0x44);                                                                     \
        (d) = EW_MM(shuffle_ps)(t1_, t3_, 0xEE);                                                                     \
    } while (0)

/* 12 independent FMA chains of one vector each: enough in flight to fill two
 * FMA pipes with a 4-cycle latency (the FMA peak the convolutions are
 * measured against). Returns the flops done. */
static double EW_SUFFIX(fma_burn)(long iters, float seed) {
    EW_V a[12], m = EW_VSET1(0.999999f), c = EW_VSET1(1e-7f);
    for (int k = 0; k < 12; k++) a[k] = EW_VSET1(seed + (float)k);
    for (long i = 0; i < iters; i++)
        for (int k = 0; k < 12; k++) a[k] = EW_VFMA(a[k], m, c);
    float t[EW_VW];
    EW_V s = a[0];
    for (int k = 1; k < 12; k++) s = EW_VADD(s, a[k]);
    EW_VSTORE(t, s);
    return t[0] > -1.0f ? (double)iters * 12 * EW_VW * 2 : 0.0; /* (use the result) */
}
