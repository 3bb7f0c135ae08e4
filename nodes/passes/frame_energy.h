/*
 * frame_energy.h — the energy figures of a frame against its reference, as
 * the benchmark (edgewise bench) and the stability suite report them for
 * the do-no-harm targets (docs/harm.md). Frames are packed RGB floats.
 */
#ifndef EW_FRAME_ENERGY_H
#define EW_FRAME_ENERGY_H

#include <stddef.h>

/* Mean Rec. 709 luminance of n pixels, non-finite ones counting as 0. */
double ew_frame_mean_lum(const float *rgb, size_t n);
/* The largest ratio of an output pixel's luminance to the reference's
 * largest within r pixels (floored at 1e-3 of the reference's mean): an
 * extreme sample that survived, spread or not, shows as a large ratio. */
double ew_frame_peak_ratio(const float *out, const float *ref, int w, int h, int r);

#endif
