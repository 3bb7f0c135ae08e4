/*
 * backend.h — the table of device operations the algorithms call. Each entry
 * loops the per-pixel functions of core/kernels/ over a grid of work; the CPU
 * backend runs them on the device's threads, a CUDA backend would launch the
 * same functions as kernels. All buffers are packed float arrays in the
 * device's memory.
 */
#ifndef EW_BACKEND_H
#define EW_BACKEND_H

#include "kernels/bgrid.h"
#include "kernels/denoise_px.h"
#include "kernels/outlier.h"
#include "kernels/temporal.h"

typedef struct ew_device ew_device;

typedef struct ew_backend {
    const char *name;
    void (*bgrid_splat)(ew_device *dev, const ew_bgrid_params *p, const float *image,
                        const float *guide, float *grid);
    void (*bgrid_slice)(ew_device *dev, const ew_bgrid_params *p, const float *grid,
                        const float *guide, float *out);
    /* demodulate + hand-made guide for every pixel */
    void (*denoise_prepare)(ew_device *dev, const ew_denoise_buffers *b);
    /* remodulate: b->out = b->sliced * (albedo + eps) */
    void (*denoise_finish)(ew_device *dev, const ew_denoise_buffers *b);
    /* second-pass guide from the first pass's b->sliced */
    void (*denoise_refine_guide)(ew_device *dev, const ew_denoise_buffers *b, float mean_lum, float color_weight);
    /* firefly suppression of an RGB image (out must not alias in) */
    void (*outlier_clamp)(ew_device *dev, int width, int height, int radius, float k, const float *in, float *out);
    /* temporal accumulation of one frame into b->out_* */
    void (*temporal)(ew_device *dev, const ew_temporal_params *p, const ew_temporal_buffers *b);

} ew_backend;

extern const ew_backend ew_cpu_backend;

#endif
