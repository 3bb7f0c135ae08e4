#include "algorithms/bgrid.h"

#include <math.h>

#include "src/backend.h"
#include "src/internal.h"

int ew_bgrid_params_init(ew_bgrid_params *p, int width, int height, float rate_s, float rate_d,
                         int channels) {
    if (!p || width <= 0 || height <= 0 || !(rate_s >= 1.0f && rate_s <= 256.0f) ||
        !(rate_d >= 1.0f && rate_d <= 256.0f) || channels < 1 || channels > EW_BGRID_MAX_CHANNELS)
        return 0;
    p->width = width;
    p->height = height;
    p->rate_s = rate_s;
    p->rate_d = rate_d;
    p->channels = channels;
    p->gw = (int)ceilf((float)width / rate_s);
    p->gh = (int)ceilf((float)height / rate_s);
    p->gd = (int)ceilf(255.0f / rate_d);
    p->band_y = 0;
    p->band_v = 0;
    return 1;
}

void ew_bgrid_params_band(const ew_bgrid_params *frame, int y0, int rows, ew_bgrid_params *band) {
    *band = *frame;
    band->height = rows;
    band->band_y = y0;
    /* the cells the band's rows read (kernels/bgrid.h: floor(py) and the
     * next), within the frame's grid */
    int v0 = (int)floorf(ew_bgrid_pos_s((float)y0, frame->rate_s));
    int v1 = (int)floorf(ew_bgrid_pos_s((float)(y0 + rows - 1), frame->rate_s)) + 1;
    v0 = v0 < 0 ? 0 : v0;
    v1 = v1 > frame->gh - 1 ? frame->gh - 1 : v1;
    band->band_v = v0;
    band->gh = v1 - v0 + 1;
}

int ew_bgrid_reach(float rate_s) { return (int)ceilf(2.0f * rate_s); }

size_t ew_bgrid_floats(const ew_bgrid_params *p) {
    return (size_t)p->gw * (size_t)p->gh * (size_t)p->gd * (size_t)(p->channels + 1);
}

void ew_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image,
                    const float *guide, float *grid) {
    dev->backend->bgrid_splat(dev, p, image, guide, grid);
}

void ew_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid,
                    const float *guide, float *out) {
    dev->backend->bgrid_slice(dev, p, grid, guide, out);
}
