/* color.h — colour helpers shared by kernels (Rec. 709 luminance). */
#ifndef EW_KERNELS_COLOR_H
#define EW_KERNELS_COLOR_H

#include "kernels/compat.h"

EW_HD float ew_luminance(const float *rgb) { return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]; }

#endif
