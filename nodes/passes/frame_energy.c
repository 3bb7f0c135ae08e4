#include "frame_energy.h"

#include <math.h>

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

double ew_frame_mean_lum(const float *rgb, size_t n) {
    double s = 0.0;
    for (size_t i = 0; i < n; i++) {
        const double l = lum(rgb + i * 3);
        if (isfinite(l)) s += l;
    }
    return s / (double)n;
}

double ew_frame_peak_ratio(const float *out, const float *ref, int w, int h, int r) {
    const double floor_l = 1e-3 * ew_frame_mean_lum(ref, (size_t)w * h);
    double worst = 0.0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const double l = lum(out + ((size_t)y * w + x) * 3);
            double mx = floor_l;
            for (int yy = y - r < 0 ? 0 : y - r; yy <= (y + r < h ? y + r : h - 1); yy++)
                for (int xx = x - r < 0 ? 0 : x - r; xx <= (x + r < w ? x + r : w - 1); xx++) {
                    const double lq = lum(ref + ((size_t)yy * w + xx) * 3);
                    if (lq > mx) mx = lq;
                }
            if (l / mx > worst) worst = l / mx;
        }
    return worst;
}
