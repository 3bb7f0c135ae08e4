/* cpu_bgrid.h — the CPU backend's bilateral grid splat and slice (cpu_bgrid.c). */
#ifndef EW_CPU_BGRID_H
#define EW_CPU_BGRID_H

#include "kernels/bgrid.h"

typedef struct ew_device ew_device;

void ew_cpu_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image, const float *guide,
                        float *grid);
void ew_cpu_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid, const float *guide,
                        float *out);

#endif
