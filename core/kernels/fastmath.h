/*
 * fastmath.h — exp, exp2 and log2 in plain float and integer arithmetic,
 * for the kernels' weights: no libm call, so that loops over pixels
 * vectorise (a call to expf takes one lane at a time) and every backend
 * computes the same bits; accurate to a few 1e-7 relative.
 */
#ifndef EW_KERNELS_FASTMATH_H
#define EW_KERNELS_FASTMATH_H

#include "kernels/compat.h"

/* ---- fast, accurate exp / log2 ----------------------------------------- */
/* Bit casts. __CUDA_ARCH__, not __CUDACC__: the intrinsics exist only in
 * nvcc's device pass; its host pass compiles these functions too.
 * Elsewhere a union (defined in C; GCC and nvcc's host compilers support it
 * in C++ too). */
#ifdef __CUDA_ARCH__
EW_HD float ew_bits_to_float(int i) { return __int_as_float(i); }
EW_HD int ew_float_to_bits(float f) { return __float_as_int(f); }
#else
EW_HD float ew_bits_to_float(int i) {
    union { int i; float f; } u;
    u.i = i;
    return u.f;
}
EW_HD int ew_float_to_bits(float f) {
    union { int i; float f; } u;
    u.f = f;
    return u.i;
}
#endif

/* 2^x for finite x <= 127: x = n + f with n = round(x) by the 1.5 * 2^23
 * trick (no libm call; needs round-to-nearest, the default) and |f| <= 1/2
 * exact, then a degree-7 Taylor polynomial of e^(f ln 2): relative error
 * < 2e-7. Below -126 returns 0 (denormal weights are not needed). No float
 * selects (compilers will not if-convert those under trapping math), so loops
 * of it vectorise. */
/* max(x, lo) for a negative lo given as its bits (a signed int), with integer
 * operations only: negative floats order backwards as ints. NaN gives lo. */
EW_HD float ew_clamp_below(float x, int lo_bits) {
    int b = ew_float_to_bits(x);
    int below = -((b < 0) & (b > lo_bits)); /* all ones when below */
    return ew_bits_to_float((lo_bits & below) | (b & ~below));
}

EW_HD float ew_fexp2(float x) {
    const float xc = ew_clamp_below(x, -1023541248); /* -127.0f */
    float n = (xc + 12582912.0f) - 12582912.0f;
    float f = xc - n;
    float p = 1.5252734e-5f;
    p = p * f + 1.5403530e-4f;
    p = p * f + 1.3333558e-3f;
    p = p * f + 9.6181291e-3f;
    p = p * f + 5.5504109e-2f;
    p = p * f + 2.4022651e-1f;
    p = p * f + 6.9314718e-1f;
    p = p * f + 1.0f;
    /* the exponent clamped as a float (an integral value: exact; integer
     * min/max would keep SSE2 loops from vectorising) */
    const int i = (int)(n < -126.0f ? -126.0f : (n > 127.0f ? 127.0f : n));
    const int bx = ew_float_to_bits(x), zero = -((bx < 0) & (bx > -1023672320)); /* x < -126.0f */
    return ew_bits_to_float(ew_float_to_bits(p * ew_bits_to_float((i + 127) << 23)) & ~zero);
}

/* e^x for finite x <= 88 with Cody-Waite reduction, x = n ln2 + r,
 * |r| <= ln2/2, and a degree-7 Taylor polynomial for e^r: relative error
 * < 3e-7; below -87 returns 0. */
EW_HD float ew_fexp(float x) {
    const float xc = ew_clamp_below(x, -1028653056); /* -88.0f */
    float n = (xc * 1.44269504f + 12582912.0f) - 12582912.0f;
    float r = xc - n * 0.693145751953125f - n * 1.428606765330187e-6f;
    float p = 1.0f / 5040.0f;
    p = p * r + 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    const int i = (int)(n < -126.0f ? -126.0f : (n > 127.0f ? 127.0f : n));
    const int bx = ew_float_to_bits(x), zero = -((bx < 0) & (bx > -1028784128)); /* x < -87.0f */
    return ew_bits_to_float(ew_float_to_bits(p * ew_bits_to_float((i + 127) << 23)) & ~zero);
}

/* log2(m) for a mantissa m in [sqrt(.5), sqrt(2)): the atanh series,
 * 2/ln 2 * atanh((m - 1) / (m + 1)). Shared by ew_flog2 and ew_flog2v. */
EW_HD float ew_flog2_mantissa(float m) {
    float t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
    float s = 1.0f / 9.0f;
    s = s * t2 + 1.0f / 7.0f;
    s = s * t2 + 1.0f / 5.0f;
    s = s * t2 + 1.0f / 3.0f;
    s = s * t2 + 1.0f;
    return 2.88539008f * t * s; /* 2/ln 2 */
}

/* log2(x) for finite x > 0 (x <= 0 gives about -123, which ew_fexp2 turns
 * into 0). Mantissa in [sqrt(.5), sqrt(2)), atanh series. */
EW_HD float ew_flog2(float x) {
    int b = ew_float_to_bits(x);
    b = b < 0x02081cea ? 0x02081cea : b; /* 1e-37 (and x <= 0, as ints) */
    int e = ((b >> 23) & 255) - 127;
    float m = ew_bits_to_float((b & 0x007fffff) | 0x3f800000); /* [1, 2) */
    int big = ew_float_to_bits(m) > 0x3fb504f3; /* m > sqrt(2), compared as ints */
    m = m * (1.0f - 0.5f * (float)big);
    e += big;
    return (float)e + ew_flog2_mantissa(m);
}

/* The same value for every finite x > 0 (and x <= 0), written for loops
 * vectorised across pixels: the clamp as a float select, the exponent as a
 * float, so that the compiler keeps one lane width (ew_flog2 is faster in
 * scalar code). */
EW_HD float ew_flog2v(float x) {
    const int b = ew_float_to_bits(x > 1e-37f ? x : 1e-37f); /* x <= 0 and NaN too */
    /* the exponent as a float (small integers: exact), which keeps the
     * compiler from narrowing the integer arithmetic in vectorised loops */
    const float big = ew_float_to_bits(ew_bits_to_float((b & 0x007fffff) | 0x3f800000)) > 0x3fb504f3 ? 1.0f : 0.0f;
    float m = ew_bits_to_float((b & 0x007fffff) | 0x3f800000); /* [1, 2) */
    m = m * (1.0f - 0.5f * big);                                /* m > sqrt(2): halved */
    const float e = (float)(b >> 23) - 127.0f + big;           /* b > 0 here: the sign bit is clear */
    return e + ew_flog2_mantissa(m);
}

#endif
