/*
 * test_kernels_cxx.cpp — the kernel headers compiled as C++17 the way nvcc
 * compiles them (__CUDACC__ defined, EW_HD = __host__ __device__ inline), so
 * that C-only constructs (compound literals, designated initializers, VLAs,
 * `restrict`, implicit void* conversions, ...) fail this build on machines
 * without nvcc. Built twice: as nvcc's host pass (this file) and as its
 * device pass (test_kernels_cxx_device.cpp: __CUDA_ARCH__ defined, the
 * device intrinsics the headers use emulated), each in a namespace of its
 * own so the two sets of inline functions never meet. The C side
 * (test_kernels_cxx_main.c) compares both with the C build of the same
 * probe, bit for bit.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* What nvcc provides, after the system headers (which must not see it). */
#define __CUDACC__ 1
#define __host__
#define __device__
#define __global__
struct ew_fake_uint3 {
    unsigned x, y, z;
};
static const ew_fake_uint3 blockIdx = {0, 0, 0}, blockDim = {1, 1, 1}, threadIdx = {0, 0, 0};
#ifdef EW_PROBE_DEVICE_PASS
#define __CUDA_ARCH__ 750
static inline float __int_as_float(int i) {
    float f;
    memcpy(&f, &i, sizeof f);
    return f;
}
static inline int __float_as_int(float f) {
    int i;
    memcpy(&i, &f, sizeof i);
    return i;
}
#define EW_PROBE_NS ew_device_pass
#define EW_PROBE_ENTRY ew_probe_device_pass
#else
#define EW_PROBE_NS ew_host_pass
#define EW_PROBE_ENTRY ew_probe_host_pass
#endif

namespace EW_PROBE_NS {
#include "kernels_probe.h"
/* the device-side thread fetch compiles too */
inline ew_thread probe_thread_self() { return ew_thread_self(); }
} // namespace EW_PROBE_NS

extern "C" int EW_PROBE_ENTRY(const float *in, float *scratch, float *out);
extern "C" int EW_PROBE_ENTRY(const float *in, float *scratch, float *out) {
    const EW_PROBE_NS::ew_thread t = EW_PROBE_NS::probe_thread_self();
    if (t.block_dim.x != 1) return -1;
    return EW_PROBE_NS::ew_probe_run(in, scratch, out);
}
