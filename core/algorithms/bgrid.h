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
/* The grid of rows y0 .. y0 + rows - 1 of the frame `frame` was made for
 * (kernels/bgrid.h, bands): the cells those rows read. A pixel of the band
 * whose rows within ew_bgrid_reach of it are all the band's (or beyond the
 * frame's edge) slices the same bits from the band's grid as from the
 * frame's. */
void ew_bgrid_params_band(const ew_bgrid_params *frame, int y0, int rows, ew_bgrid_params *band);
/* Rows a sliced pixel depends on, either side, at this spatial rate: it
 * reads cells floor(py) and floor(py) + 1, each of which gathers the pixels
 * less than one cell from it (a tent weight > 0), so rows less than two
 * cells, 2 rate rows, from y: ceil(2 rate), which also keeps a row at
 * exactly 2 rate that the rounding of the positions might let in. */
int ew_bgrid_reach(float rate_s);
/* Number of floats of the grid. */
size_t ew_bgrid_floats(const ew_bgrid_params *p);

void ew_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image,
                    const float *guide, float *grid);
void ew_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid,
                    const float *guide, float *out);

#endif
