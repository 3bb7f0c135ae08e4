/* test_kernels_cxx.cpp again, as nvcc's device pass sees the headers. */
#define EW_PROBE_DEVICE_PASS 1
#include "test_kernels_cxx.cpp"
