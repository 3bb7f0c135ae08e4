/*
 * dof.h — depth of field from a depth pass and thin-lens camera values
 * (Xu et al. 2024 §4.1): CoC attributes, then the pyramid filter (or the
 * exact or separable filter) with the DoF functions of Eq. 8.
 */
#ifndef EW_ALGORITHMS_DOF_H
#define EW_ALGORITHMS_DOF_H

#include <stddef.h>

#include "kernels/dof.h"
#include "src/internal.h"

/* Floats of scratch for the attributes of a w x h image: signed CoC, two
 * tile grids, (D, C) per pixel. */
size_t ew_dof_scratch_floats(int w, int h);

/* CoC and (D, C) attributes (w*h*2 floats at attr, interleaved or, with
 * planes, as a D plane and a C plane) from depth. coc receives the signed
 * CoC in pixels (negative in front of the focus plane). */
void ew_dof_compute_attributes(ew_device *dev, const ew_dof_camera *cam, const float *depth, float *coc,
                               float *tiles, float *attr, int planes);
/* The same with attr NULL computes the CoC and the tiles only; then
 * ew_dof_attr_rows gives (D, C) of rows [y0, y1) from them, as planes: D at
 * planes, C ps floats after it, pixel (x, y) at (y - row0) * width + x (the
 * pyramid's fill, so that DoF holds no frame of attributes). args: what
 * ew_dof_args_init makes of the same values. */
void ew_dof_args_init(ew_dof_args *a, const ew_dof_camera *cam, const float *depth, float *coc, float *tiles,
                      float *attr, int planes);
void ew_dof_attr_rows(const ew_dof_args *a, int y0, int y1, float *planes, long ps, long row0);

#endif
