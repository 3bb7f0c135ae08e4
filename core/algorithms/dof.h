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

#endif
