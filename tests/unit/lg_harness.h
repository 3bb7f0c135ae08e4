/*
 * lg_harness.h — a backend that runs the CUDA module's kernel bodies on the
 * CPU over the exact launch grids the module uses (backends/launch_grid.h),
 * with "device memory" that the host cannot touch:
 *
 *  - every mem_alloc block is mmap'd PROT_NONE outside backend entries, so an
 *    algorithm reading or writing a device buffer from the host crashes here
 *    as it would fault (or silently read garbage) on a GPU;
 *  - each block ends on a PROT_NONE guard page, so a thread missing its
 *    bounds check writes past the end and crashes;
 *  - blocks start filled with NaN bits, so a kernel that leaves an element
 *    unwritten shows up in the comparison with the CPU backend;
 *  - every buffer pointer an entry receives must lie in a block (a host
 *    pointer handed to the GPU is recorded in lg_error), and the host
 *    parameter structs the CUDA wrappers pass by value are replaced by an
 *    unreadable address, so a body that forgets to rebind them crashes.
 */
#ifndef EW_TESTS_LG_HARNESS_H
#define EW_TESTS_LG_HARNESS_H

#include <stddef.h>

#include "src/backend.h"

extern const ew_backend lg_backend;
/* The first misuse seen ("" if none): a host pointer given as a buffer, or
 * a device pointer given as a host one. */
extern char lg_error[256];

/* A device (on a CPU device's pool, unused) whose backend is the harness;
 * device_images: view pointers are harness device memory. */
ew_device *lg_device_create(int device_images);
/* Device buffers for tests: a copy of host data, or filled with NaN bits. */
float *lg_upload(ew_device *dev, const float *host, size_t n);
float *lg_alloc_floats(ew_device *dev, size_t n);
/* A malloc'd host copy of a device buffer. */
float *lg_download(ew_device *dev, const float *d, size_t n);
/* Live blocks (to check ops free what they allocate). */
int lg_live_blocks(void);

#endif
