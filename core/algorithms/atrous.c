/* atrous.c — iterations of the edge-avoiding à-trous filter. */
#include "algorithms/atrous.h"

#include <string.h>

#include "kernels/atrous.h"
#include "src/backend.h"

int ew_atrous_iterations_for(int radius) {
    int n = 0;
    while (2 * ((1 << n) - 1) < radius && n < 16) n++;
    return n;
}

void ew_atrous_run(ew_device *dev, int w, int h, int C, int iterations, const float *in, float *tmp, float *out,
                   const float *normal, const float *depth, float sigma_l, float sigma_n, float sigma_z) {
    if (iterations <= 0) {
        memcpy(out, in, (size_t)w * (size_t)h * EW_BF_CH * sizeof(float));
        return;
    }
    /* the last iteration must land in out */
    float *dst = iterations % 2 ? out : tmp;
    const float *src = in;
    for (int i = 0; i < iterations; i++) {
        ew_atrous_args a;
        a.w = w;
        a.h = h;
        a.channels = C;
        a.step = 1 << i;
        a.in = src;
        a.out = dst;
        a.normal = normal;
        a.depth = depth;
        a.sigma_l = sigma_l / (float)(1 << i);
        a.sigma_n = sigma_n;
        a.sigma_z = sigma_z;
        (void)EW_RUN(dev, atrous, &a);
        src = dst;
        dst = dst == out ? tmp : out;
    }
}
