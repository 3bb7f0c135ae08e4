#include "algorithms/noise.h"

#include <math.h>
#include <stdlib.h>

#include "kernels/color.h"
#include "src/internal.h"

static float compressed_lum(const ew_image *c, const ew_image *a, int x, int y) {
    const float *p = ew__pixel(c, x, y);
    float rgb[3];
    for (int k = 0; k < 3; k++) {
        float al = a ? ew__channel(a, x, y, k) : 1.0f; /* a half albedo too */
        rgb[k] = p[k] / ((isfinite(al) && al > 0.0f ? al : 0.0f) + (a ? 0.01f : 0.0f));
    }
    float l = ew_luminance(rgb);
    if (!isfinite(l)) return NAN;
    l = l > 0.0f ? l : 0.0f;
    return l / (1.0f + l);
}

static int cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

float ew_estimate_noise(const ew_image *c, const ew_image *a) {
    const int w = c->width, h = c->height;
    if (w < 3 || h < 3) return 0.0f;
    /* every second pixel of every second row is plenty and keeps it cheap */
    size_t cap = (size_t)((w - 1) / 2) * (size_t)((h - 1) / 2), n = 0;
    float *d = (float *)malloc(cap * sizeof(float));
    if (!d) return 0.0f;
    for (int y = 1; y < h - 1; y += 2)
        for (int x = 1; x < w - 1; x += 2) {
            float l = compressed_lum(c, a, x, y);
            float m = 0.25f * (compressed_lum(c, a, x - 1, y) + compressed_lum(c, a, x + 1, y) +
                               compressed_lum(c, a, x, y - 1) + compressed_lum(c, a, x, y + 1));
            if (isfinite(l) && isfinite(m) && n < cap) d[n++] = fabsf(l - m);
        }
    float med = 0.0f;
    if (n) {
        qsort(d, n, sizeof(float), cmp_float);
        med = d[(n * 3) / 4];
    }
    free(d);
    return med;
}
