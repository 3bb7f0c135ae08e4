/*
 * finite.h — the filters' finite-output guarantee (image.c).
 */
#ifndef EW_FINITE_H
#define EW_FINITE_H

#include "src/internal.h"

/* Filters promise a finite output for any finite input, as the denoisers
 * do; where a filter's sums overflow (colour near FLT_MAX) a pixel is
 * given back as the input pixel (unless `in` is the output itself) with
 * NaN as 0 and +-Inf as +-FLT_MAX. Returns how many pixels it replaced;
 * finite outputs are left bit for bit. Host views only. */
long ew__finite_fallback(ew_device *dev, const ew_image *out, const ew_image *in);

#endif
