/*
 * half.h — IEEE 754 binary16 to float, per value, the same on every
 * backend: views of EW_FORMAT_HALF (an EXR's half passes, numpy float16)
 * are read through it. Exact: every half is a float.
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

#endif
