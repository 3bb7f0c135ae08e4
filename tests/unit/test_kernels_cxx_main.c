/*
 * test_kernels_cxx_main.c — the probe of kernels_probe.h as C, against the
 * C++ builds of test_kernels_cxx.cpp (nvcc's host and device passes,
 * emulated): all three must compute the same bits.
 */
#include "ew_test.h"
#include "kernels_probe.h"

int ew_probe_host_pass(const float *in, float *scratch, float *out);
int ew_probe_device_pass(const float *in, float *scratch, float *out);

static float in[EW_PROBE_IN], scratch[EW_PROBE_SCRATCH], out_c[EW_PROBE_OUT], out_cxx[EW_PROBE_OUT];

static int probe_c(void) {
    uint32_t s = 12345u;
    for (int i = 0; i < EW_PROBE_IN; i++) {
        s = s * 1664525u + 1013904223u;
        in[i] = (float)(s >> 8) / 16777216.0f;
    }
    return ew_probe_run(in, scratch, out_c);
}

static int compare(int n_c, int n_cxx, const char *pass) {
    if (n_c != n_cxx) {
        fprintf(stderr, "  %s: %d results vs %d in C\n", pass, n_cxx, n_c);
        return 0;
    }
    for (int i = 0; i < n_c; i++)
        if (memcmp(&out_c[i], &out_cxx[i], sizeof(float)) != 0) {
            fprintf(stderr, "  %s: result %d is %.9g, %.9g in C\n", pass, i, (double)out_cxx[i], (double)out_c[i]);
            return 0;
        }
    return 1;
}

TEST(probe_exercises_the_kernels) {
    const int n = probe_c();
    CHECK(n > 1000 && n <= EW_PROBE_OUT);
    int nonzero = 0;
    for (int i = 0; i < n; i++) nonzero += out_c[i] != 0.0f;
    CHECK(nonzero > n / 2);
}

TEST(cxx_host_pass_matches_c) {
    const int n = probe_c();
    CHECK(compare(n, ew_probe_host_pass(in, scratch, out_cxx), "C++ (nvcc host pass)"));
}

TEST(cxx_device_pass_matches_c) {
    const int n = probe_c();
    CHECK(compare(n, ew_probe_device_pass(in, scratch, out_cxx), "C++ (nvcc device pass)"));
}
