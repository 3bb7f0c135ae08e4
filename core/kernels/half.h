/*
 * half.h — IEEE 754 binary16 to float, per value, the same on every
 * backend: views of EW_FORMAT_HALF (an EXR's half passes, numpy float16)
 * are read through it. Exact: every half is a float. And float to half,
 * rounded to nearest even as the compiler's _Float16 rounds (what the
 * do-no-harm stage keeps of a pilot's output, src/harm_stage.c).
 */
#ifndef EW_KERNELS_HALF_H
#define EW_KERNELS_HALF_H

#include "kernels/compat.h"

EW_HD float ew_half_to_float(unsigned short h) {
    const unsigned int sign = (unsigned int)(h & 0x8000u) << 16, e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
    union {
        unsigned int u;
        float f;
    } v;
    if (e == 0x1fu) v.u = sign | 0x7f800000u | (m << 13); /* infinity, NaN (payload kept) */
    else if (e) v.u = sign | ((e + 112u) << 23) | (m << 13);
    else { /* zero and subnormals: m * 2^-24, exact in a float */
        v.f = (float)m * 5.9604644775390625e-8f;
        v.u |= sign;
    }
    return v.f;
}

/* Round to nearest, ties to even; past 65504 (from 65520) infinity; a NaN
 * stays a NaN (quiet, its top payload bits kept). */
EW_HD unsigned short ew_float_to_half(float f) {
    union {
        unsigned int u;
        float f;
    } v, magic;
    v.f = f;
    const unsigned int sign = (v.u >> 16) & 0x8000u, a = v.u & 0x7fffffffu;
    if (a >= 0x7f800000u) return (unsigned short)(sign | 0x7c00u | (a > 0x7f800000u ? 0x200u | ((a >> 13) & 0x3ffu) : 0u));
    if (a >= 0x477ff000u) return (unsigned short)(sign | 0x7c00u);
    if (a < 0x38800000u) { /* below 2^-14: a subnormal half, rounded by the float addition itself */
        magic.u = 126u << 23; /* 0.5: its last mantissa bit is 2^-24, the half's smallest step */
        v.u = a;
        v.f += magic.f;
        return (unsigned short)(sign | (v.u - magic.u));
    }
    const unsigned int odd = (a >> 13) & 1u; /* the even of a tie */
    return (unsigned short)(sign | ((a - (112u << 23) + 0xfffu + odd) >> 13));
}

#endif
