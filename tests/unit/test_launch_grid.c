/*
 * test_launch_grid.c — the CUDA module's kernels, run on the CPU over the
 * exact launch grids the module uses (lg_harness.c), against the CPU
 * backend: every entry of the backend table on awkward sizes (not multiples
 * of the block), then whole denoisers through the device-memory path, the
 * launch geometry itself, and the module's loading on this machine.
 *
 * Kernels must match the CPU backend bit for bit (same functions, same
 * compiler); conv5 to rounding, because the CPU computes it in SIMD blocks.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdint.h>

#include "ew_test.h"
#include "lg_harness.h"

#include "backends/cuda/kernel_bodies.h"

/* the device under test of parity_body.h: the harness */
static ew_device *dut_create(int device_images) {
    lg_error[0] = '\0';
    return lg_device_create(device_images);
}
static const char *dut_skip_reason(void) { return "could not create the harness device"; }
static const int dut_exact = 1;
static int dut_live_blocks(void) { return lg_live_blocks(); }
#define CHECK_NO_MISUSE() \
    do { if (lg_error[0]) { FAIL_AT("harness: %s", lg_error); return; } } while (0)

#include "parity_body.h"

/* ---- launch geometry ----------------------------------------------------- */
TEST(launch_2d_covers_every_pixel_once) {
    const int ws[] = {1, 15, 16, 17, 100, 1280}, hs[] = {1, 7, 8, 9, 720};
    static unsigned char seen[1280 * 720];
    for (size_t a = 0; a < sizeof ws / sizeof ws[0]; a++)
        for (size_t b = 0; b < sizeof hs / sizeof hs[0]; b++) {
            const int w = ws[a], h = hs[b];
            const ew_launch l = ew_launch_2d(w, h);
            CHECK((long)l.grid.x * l.block.x >= w && (long)(l.grid.x - 1) * l.block.x < w);
            CHECK((long)l.grid.y * l.block.y >= h && (long)(l.grid.y - 1) * l.block.y < h);
            memset(seen, 0, (size_t)w * (size_t)h);
            long inside = 0, threads = 0;
            EW_LAUNCH_WALK(l, t, {
                threads++;
                const int x = ew_tx(&t), y = ew_ty(&t);
                if (x < w && y < h) {
                    seen[y * w + x]++;
                    inside++;
                }
            });
            CHECK_EQ_INT(threads, (long)l.grid.x * l.grid.y * l.block.x * l.block.y);
            CHECK_EQ_INT(inside, (long)w * h);
            for (int i = 0; i < w * h; i++) CHECK_EQ_INT(seen[i], 1);
        }
}

TEST(launch_1d_and_3d_geometry) {
    const long ns[] = {1, 127, 128, 129, 100000};
    for (size_t i = 0; i < sizeof ns / sizeof ns[0]; i++) {
        const ew_launch l = ew_launch_1d(ns[i]);
        CHECK((long)l.grid.x * l.block.x >= ns[i] && (long)(l.grid.x - 1) * l.block.x < ns[i]);
        CHECK(l.grid.y == 1 && l.grid.z == 1 && !ew_launch_empty(&l));
    }
    ew_launch e = ew_launch_1d(0);
    CHECK(ew_launch_empty(&e));
    e = ew_launch_2d(5, 0);
    CHECK(ew_launch_empty(&e));
    const ew_launch l3 = ew_launch_3d(17, 9, 6);
    CHECK(l3.grid.z == 6 && l3.block.z == 1);
    long count = 0;
    EW_LAUNCH_WALK(l3, t, count += ew_tx(&t) < 17 && ew_ty(&t) < 9 && ew_tz(&t) < 6);
    CHECK_EQ_INT(count, 17 * 9 * 6);
    /* blockIdx.x * blockDim.x is widened: a 2^31-thread 1-D grid does not wrap */
    ew_thread t;
    t.block_idx = ew_dim3_make(1u << 24, 0, 0);
    t.block_dim = ew_dim3_make(EW_BLOCK_1D, 1, 1);
    t.thread_idx = ew_dim3_make(5, 0, 0);
    CHECK(ew_t1(&t) == (long)(1u << 24) * EW_BLOCK_1D + 5);
    /* the largest image fits CUDA's grid limits (y and z below 65536) */
    const ew_launch big = ew_launch_2d(EW_MAX_SIDE, EW_MAX_SIDE);
    CHECK(big.grid.y <= 65535);
}

TEST(backend_tables_are_complete) {
    CHECK_EQ_INT(ew_backend_first_missing(&ew_cpu_backend), -1);
    CHECK_EQ_INT(ew_backend_first_missing(&lg_backend), -1);
    ew_backend holed = ew_cpu_backend;
    holed.mem_zero = NULL;
    CHECK(ew_backend_first_missing(&holed) > 0);
}

TEST(unported_ops_are_refused_on_device_memory) {
    ew_device *lg = lg_device_create(0);
    int refused = 0;
    /* every op not marked device_memory must be refused with a message
     * that says what to do, never handed device memory */
    for (int i = 0; ew_op_types[i]; i++) {
        const ew_op_type *t = ew_op_types[i];
        ew_op *op = NULL;
        ew_result r = ew_op_create_kind(lg, t->kind, t->name, &op);
        if (t->device_memory) {
            CHECK_EQ_INT(r, EW_OK);
        } else {
            CHECK_EQ_INT(r, EW_ERR_UNSUPPORTED);
            CHECK_STR_CONTAINS(ew_device_last_error(lg), "EW_DEVICE_CPU");
            CHECK(op == NULL);
            refused++;
        }
        ew_op_destroy(op);
    }
    ew_device_destroy(lg);
    fprintf(stderr, "  %d op types are not ported to device memory yet\n", refused);
}

/* ---- the module and the device API on this machine ----------------------- */
TEST(device_create_fallback_and_reasons) {
    CHECK(strcmp(ew_backend_unavailable_reason(EW_DEVICE_CPU), "") == 0);
    CHECK_STR_CONTAINS(ew_backend_unavailable_reason((ew_device_type)42), "unknown");
    const char *why = ew_backend_unavailable_reason(EW_DEVICE_CUDA);
    CHECK(why != NULL);
    CHECK_STR_CONTAINS(ew_backend_unavailable_reason(EW_DEVICE_DEFAULT), "CPU");
    ew_device_desc d = EW_DEVICE_DESC_INIT;
    ew_device *dev = NULL;
    d.type = EW_DEVICE_CUDA;
    ew_result r = ew_device_create(&d, &dev);
    if (why[0]) {
        CHECK_EQ_INT(r, EW_ERR_BACKEND_UNAVAILABLE);
        CHECK(dev == NULL);
    } else {
        CHECK_EQ_INT(r, EW_OK);
        CHECK_EQ_INT(ew_device_get_type(dev), EW_DEVICE_CUDA);
        ew_device_destroy(dev);
    }
    /* DEFAULT: the CPU while most methods are CPU-only, GPU or not */
    d.type = EW_DEVICE_DEFAULT;
    CHECK_EQ_INT(ew_device_create(&d, &dev), EW_OK);
    CHECK_EQ_INT(ew_device_get_type(dev), EW_DEVICE_CPU);
    ew_device_destroy(dev);
    /* device pointers only with an explicit CUDA device */
    d.device_images = 1;
    CHECK_EQ_INT(ew_device_create(&d, &dev), EW_ERR_INVALID_ARGUMENT);
    d.device_images = 0;
    d.cuda_device = -1;
    CHECK_EQ_INT(ew_device_create(&d, &dev), EW_ERR_INVALID_ARGUMENT);
    /* a desc from before the CUDA fields: the rest takes defaults */
    ew_device_desc old = EW_DEVICE_DESC_INIT;
    old.size = offsetof(ew_device_desc, num_threads) + sizeof(int32_t);
    old.type = EW_DEVICE_CPU;
    old.cuda_device = 99; /* beyond the old size: must be ignored */
    CHECK_EQ_INT(ew_device_create(&old, &dev), EW_OK);
    ew_device_destroy(dev);
}

TEST(cuda_module_loads_and_explains) {
#ifndef EW_TEST_CUDA_MODULE
    SKIP("this build has no CUDA module (configured without nvcc or with EW_CUDA=OFF)");
#else
    void *h = dlopen(EW_TEST_CUDA_MODULE, RTLD_NOW | RTLD_LOCAL);
    if (!h) FAIL_AT("dlopen %s: %s", EW_TEST_CUDA_MODULE, dlerror());
    CHECK(h != NULL);
    void *sym = dlsym(h, EW_CUDA_MODULE_ENTRY);
    CHECK(sym != NULL);
    ew_module_entry_fn entry;
    memcpy(&entry, &sym, sizeof entry);
    const ew_module_api *api = entry();
    CHECK(api != NULL);
    CHECK_EQ_INT(api->abi, EW_MODULE_ABI);
    CHECK_EQ_INT(api->sizeof_backend, sizeof(ew_backend));
    CHECK_EQ_INT(api->sizeof_device, sizeof(struct ew_device));
    CHECK(strcmp(api->version, ew_version_string()) == 0);
    CHECK(strcmp(api->backend->name, "cuda") == 0);
    /* every entry of the table has a CUDA wrapper */
    const int missing = ew_backend_first_missing(api->backend);
    if (missing >= 0) FAIL_AT("the CUDA table lacks backend entry #%d (add its wrapper to cuda_backend.cu)", missing);
    CHECK_EQ_INT(missing, -1);
    char why[512] = "";
    const int n = api->probe(why, sizeof why);
    if (n <= 0) {
        /* no GPU here: the probe and the library say why, the same way */
        CHECK(why[0] != '\0');
        CHECK_STR_CONTAINS(ew_backend_unavailable_reason(EW_DEVICE_CUDA), why);
        fprintf(stderr, "  no GPU: %s\n", ew_backend_unavailable_reason(EW_DEVICE_CUDA));
    }
    dlclose(h);
#endif
}
