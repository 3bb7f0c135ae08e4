/*
 * bgrid.h — bilateral grid construction and slicing on a device (the
 * per-cell math is in kernels/bgrid.h).
 */
#ifndef EW_ALGORITHMS_BGRID_H
#define EW_ALGORITHMS_BGRID_H

#include <stddef.h>

#include "kernels/bgrid.h"

typedef struct ew_device ew_device;

/* Grid size for an image (Eq. 8, guide range d = 255). Returns 0 on bad
 * arguments (non-positive size, rates < 1 or > 256, channels out of range). */
int ew_bgrid_params_init(ew_bgrid_params *p, int width, int height, float rate_s, float rate_d,
                         int channels);
/* Number of floats of the grid. */
size_t ew_bgrid_floats(const ew_bgrid_params *p);

void ew_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image,
                    const float *guide, float *grid);
void ew_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid,
                    const float *guide, float *out);

#endif
