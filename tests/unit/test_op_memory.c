/* ew_op_memory against what commit really allocates (glibc's mallinfo2:
 * heap and mmap bytes in use), for every denoiser: an estimate that said
 * less than the commit takes would let a front start work that cannot fit,
 * one far above it would refuse frames that fit. */
#include "ew_test.h"

#include <malloc.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"

#define W 320
#define H 200

static size_t in_use(void) {
    struct mallinfo2 mi = mallinfo2();
    return mi.uordblks + mi.hblkhd;
}

static ew_device *dev_cpu(void) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = 1;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

/* Whether mallinfo2 sees this process's allocations: a sanitizer's
 * allocator (the ASan build) serves malloc itself and glibc reports 0. */
static int mallinfo_counts(void) {
    const size_t before = in_use();
    volatile char *p = (volatile char *)malloc(1 << 20);
    if (!p) return 0;
    p[0] = 1;
    const size_t grew = in_use() - before;
    free((void *)p);
    return grew >= (1u << 20);
}

/* Estimate and commit growth of `method` with every feature image. */
static void measure(ew_device *dev, const char *method, const char *param, int value, int samples, uint64_t *est,
                    size_t *grew) {
    static float color[W * H * 3], albedo[W * H * 3], normal[W * H * 3], depth[W * H], out[W * H * 3];
    for (size_t i = 0; i < (size_t)W * H * 3; i++) {
        color[i] = (float)((i * 2654435761u) % 1000) / 1000.0f;
        albedo[i] = 0.5f;
        normal[i] = i % 3 == 2 ? 1.0f : 0.0f;
    }
    for (size_t i = 0; i < (size_t)W * H; i++) depth[i] = 3.0f;
    ew_op *op = NULL;
    CHECK_EQ_INT(ew_op_create(dev, method, &op), EW_OK);
    if (param) CHECK_EQ_INT(ew_op_set_int(op, param, value), EW_OK);
    if (samples) CHECK_EQ_INT(ew_op_set_int(op, "samples", samples), EW_OK);
    ew_image c = ew_image_packed(color, W, H, 3), a = ew_image_packed(albedo, W, H, 3);
    ew_image n = ew_image_packed(normal, W, H, 3), d = ew_image_packed(depth, W, H, 1);
    ew_image o = ew_image_packed(out, W, H, 3);
    CHECK_EQ_INT(ew_op_set_image(op, "color", &c), EW_OK);
    CHECK_EQ_INT(ew_op_set_image(op, "albedo", &a), EW_OK);
    CHECK_EQ_INT(ew_op_set_image(op, "normal", &n), EW_OK);
    CHECK_EQ_INT(ew_op_set_image(op, "depth", &d), EW_OK);
    CHECK_EQ_INT(ew_op_set_image(op, "output", &o), EW_OK);
    CHECK_EQ_INT(ew_op_memory(op, W, H, est), EW_OK);
    const size_t before = in_use();
    CHECK_EQ_INT(ew_op_commit(op), EW_OK);
    *grew = in_use() - before;
    ew_op_destroy(op);
}

TEST(estimate_matches_the_commit) {
    if (!mallinfo_counts()) SKIP("mallinfo2 does not see this allocator's blocks (a sanitizer build)");
    ew_device *dev = dev_cpu();
    CHECK(dev);
    static const struct {
        const char *method, *param;
        int value;
    } cases[] = {{"bgrid", NULL, 0}, {"nbg", "model", 0}, {"nbg", "model", 2}, {"kpcn", "model", 0}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        uint64_t est = 0;
        size_t grew = 0;
        measure(dev, cases[i].method, cases[i].param, cases[i].value, 0, &est, &grew);
        fprintf(stderr, "  %s %s=%d: estimate %.2f MiB, commit allocated %.2f MiB\n", cases[i].method,
                cases[i].param ? cases[i].param : "-", cases[i].value, (double)est / 1048576.0,
                (double)grew / 1048576.0);
        /* the commit's scratch, within its small allocations (state,
         * parsed built-in weights) */
        CHECK((double)est >= 0.9 * (double)grew);
        CHECK((double)est <= 1.1 * (double)grew + 65536.0);
    }
    ew_device_destroy(dev);
}

/* auto: at least what the rung it picks allocates, for a known sample
 * count and for none (the noise estimate's pick) */
TEST(auto_estimate_covers_its_pick) {
    if (!mallinfo_counts()) SKIP("mallinfo2 does not see this allocator's blocks (a sanitizer build)");
    ew_device *dev = dev_cpu();
    CHECK(dev);
    const int samples[] = {1, 4, 16, 64, 0};
    for (int q = 0; q < 3; q++)
        for (size_t i = 0; i < sizeof samples / sizeof samples[0]; i++) {
            uint64_t est = 0;
            size_t grew = 0;
            measure(dev, "auto", "quality", q, samples[i], &est, &grew);
            fprintf(stderr, "  auto quality %d, %d spp: estimate %.2f MiB, commit allocated %.2f MiB\n", q, samples[i],
                    (double)est / 1048576.0, (double)grew / 1048576.0);
            CHECK((double)est >= 0.9 * (double)grew);
        }
    ew_device_destroy(dev);
}

/* ew_host_alloc: 64-byte aligned, and a block of 2 MiB or more starts on a
 * huge page's boundary (so all of it can be huge pages); every byte is the
 * caller's; freed by ew_host_free, NULL freed as a no-op. */
TEST(host_alloc) {
    const size_t sizes[] = {0, 1, 100, (size_t)2 << 20, ((size_t)5 << 20) + 12};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        unsigned char *p = (unsigned char *)ew_host_alloc(sizes[k]);
        CHECK(p != NULL);
        CHECK((uintptr_t)p % 64 == 0);
#if defined(__linux__)
        if (sizes[k] >= ((size_t)2 << 20)) CHECK((uintptr_t)p % ((uintptr_t)2 << 20) == 0);
#endif
        memset(p, 0x5a, sizes[k]);
        CHECK(sizes[k] == 0 || (p[0] == 0x5a && p[sizes[k] - 1] == 0x5a));
        ew_host_free(p);
    }
    ew_host_free(NULL);
}

TEST(bad_calls) {
    ew_device *dev = dev_cpu();
    CHECK(dev);
    ew_op *op = NULL;
    uint64_t b = 1;
    CHECK_EQ_INT(ew_op_memory(NULL, 8, 8, &b), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_create(dev, "bgrid", &op), EW_OK);
    CHECK_EQ_INT(ew_op_memory(op, 8, 8, NULL), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_memory(op, 0, 8, &b), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_memory(op, 8, -1, &b), EW_ERR_INVALID_ARGUMENT);
    ew_op_destroy(op);
    CHECK_EQ_INT(ew_op_create(dev, "pyramid", &op), EW_OK);
    CHECK_EQ_INT(ew_op_memory(op, 8, 8, &b), EW_ERR_UNSUPPORTED);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "no memory estimate");
    ew_op_destroy(op);
    ew_device_destroy(dev);
}
