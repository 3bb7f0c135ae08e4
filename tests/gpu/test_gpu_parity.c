/*
 * test_gpu_parity.c — the CUDA backend on a real GPU against the CPU
 * backend: every backend entry and every op ported to device memory
 * (tests/unit/parity_body.h, the same cases the launch-grid harness runs
 * bit for bit), here to rounding (FMA contraction, the GPU's powf/expf).
 *
 * Without a usable GPU every test skips with the reason the library gives
 * (ew_backend_unavailable_reason), so the executable exits 77 and CTest
 * reports it skipped; the per-pixel math it would run is covered on the
 * CPU by test_launch_grid. Label: gpu (ctest -L gpu).
 */
#include "ew_test.h"

#include "edgewise/edgewise.h"

/* the device under test of parity_body.h: a CUDA device */
static ew_device *dut_create(int device_images) {
    ew_device_desc d = EW_DEVICE_DESC_INIT;
    d.type = EW_DEVICE_CUDA;
    d.device_images = device_images;
    ew_device *dev = NULL;
    return ew_device_create(&d, &dev) == EW_OK ? dev : NULL;
}
static const char *dut_skip_reason(void) {
    static char why[700];
    snprintf(why, sizeof why, "no CUDA device: %s", ew_backend_unavailable_reason(EW_DEVICE_CUDA));
    return why;
}
static const int dut_exact = 0;
static int dut_live_blocks(void) { return 0; }
#define CHECK_NO_MISUSE() do { } while (0)

#include "unit/parity_body.h"

TEST(gpu_device_reports_itself) {
    ew_device *dev = dut_create(0);
    if (!dev) SKIP(dut_skip_reason());
    CHECK_EQ_INT(ew_device_get_type(dev), EW_DEVICE_CUDA);
    CHECK(strcmp(ew_backend_unavailable_reason(EW_DEVICE_CUDA), "") == 0);
    CHECK(strcmp(dev->backend->name, "cuda") == 0);
    /* DEFAULT picks the GPU when there is one */
    ew_device *def = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &def), EW_OK);
    CHECK_EQ_INT(ew_device_get_type(def), EW_DEVICE_CUDA);
    ew_device_destroy(def);
    ew_device_destroy(dev);
}

TEST(gpu_failures_surface_at_the_next_sync) {
    ew_device *dev = dut_create(0);
    if (!dev) SKIP(dut_skip_reason());
    /* an impossible allocation fails cleanly and leaves no error behind */
    void *huge = dev->backend->mem_alloc(dev, (size_t)1 << 50);
    CHECK(huge == NULL);
    CHECK_EQ_INT(dev->backend->sync(dev, 1), EW_OK);
    ew_device_destroy(dev);
}
