/* noise.h — a quick estimate of how noisy a render is, for choosing how
 * strongly to filter when the sample count is unknown. */
#ifndef EW_ALGORITHMS_NOISE_H
#define EW_ALGORITHMS_NOISE_H

#include "edgewise/edgewise.h"

/* Median over pixels of |L(p) - mean of its 4 neighbours| where L is the
 * albedo-demodulated luminance compressed by L / (1 + L) (so fireflies and
 * emitters do not dominate). albedo may be NULL. Non-finite pixels are
 * skipped. Returns 0 for images smaller than 3x3. */
float ew_estimate_noise(const ew_image *color, const ew_image *albedo);

#endif
