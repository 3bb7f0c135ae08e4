/*
 * outlier.h — firefly suppression: a pixel whose luminance lies more than
 * k standard deviations above the mean of its (2r+1)^2 neighbourhood (itself
 * excluded, so one firefly cannot hide itself) is scaled down to that bound.
 * Low-sample path tracing has heavy-tailed noise; a few such samples would
 * otherwise be spread by any smoothing filter into visible blotches.
 * Non-finite neighbours are ignored; a non-finite pixel is left as it is
 * (later stages treat it as missing).
 */
#ifndef EW_KERNELS_OUTLIER_H
#define EW_KERNELS_OUTLIER_H

#include "kernels/color.h"

/* in/out: width*height*3 floats (out must not alias in). */
EW_HD void ew_outlier_clamp_px(int x, int y, int width, int height, int radius, float k,
                               const float *EW_RESTRICT in, float *EW_RESTRICT out) {
    const long j = (long)y * width + x;
    const float *p = in + j * 3;
    float *o = out + j * 3;
    o[0] = p[0];
    o[1] = p[1];
    o[2] = p[2];
    float lum = ew_luminance(p);
    if (!ew_finitef(lum) || lum <= 0.0f) return;
    float sum = 0.0f, sum2 = 0.0f;
    int n = 0;
    for (int yy = ew_maxi(y - radius, 0); yy <= ew_mini(y + radius, height - 1); yy++)
        for (int xx = ew_maxi(x - radius, 0); xx <= ew_mini(x + radius, width - 1); xx++) {
            if (xx == x && yy == y) continue;
            float l = ew_luminance(in + ((long)yy * width + xx) * 3);
            if (!ew_finitef(l)) continue;
            sum += l;
            sum2 += l * l;
            n++;
        }
    if (n < 3) return;
    float mean = sum / (float)n;
    float var = ew_maxf(sum2 / (float)n - mean * mean, 0.0f);
    float bound = mean + k * sqrtf(var);
    if (lum > bound) {
        float s = ew_maxf(bound, 0.0f) / lum;
        o[0] = p[0] * s;
        o[1] = p[1] * s;
        o[2] = p[2] * s;
    }
}

#endif
