/* A graph commits its ops again every frame with the same images: the
 * denoisers (and auto's rung, and the do-no-harm stage) then keep the
 * device memory of the last commit instead of allocating it again — a new
 * block is mapped and faulted in afresh every frame — and the second run's
 * output is the first's. Device allocations are counted through a copy of
 * the CPU backend's table whose mem_alloc counts. */
#define _DEFAULT_SOURCE /* MAP_ANONYMOUS */
#include "ew_test.h"

#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"
#include "src/backend.h"
#include "src/internal.h"

static int allocs;
static void *(*real_alloc)(ew_device *dev, size_t bytes);

static void *counting_alloc(ew_device *dev, size_t bytes) {
    allocs++;
    return real_alloc(dev, bytes);
}

static float pattern(int i, int k) { return (float)((i * 37 + k * 11) % 101) / 100.0f; }

static void commit_again_allocates_nothing(const char *method) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = 2;
    ew_device *dev = NULL;
    CHECK(ew_device_create(&desc, &dev) == EW_OK);
    const ew_backend *orig = dev->backend;
    ew_backend counting = *orig;
    real_alloc = orig->mem_alloc;
    counting.mem_alloc = counting_alloc;
    dev->backend = &counting;

    const int w = 96, h = 64, n = w * h;
    float *color = malloc(sizeof(float) * 3 * (size_t)n), *albedo = malloc(sizeof(float) * 3 * (size_t)n);
    float *normal = malloc(sizeof(float) * 3 * (size_t)n), *depth = malloc(sizeof(float) * (size_t)n);
    float *out[2] = {malloc(sizeof(float) * 3 * (size_t)n), malloc(sizeof(float) * 3 * (size_t)n)};
    CHECK(color && albedo && normal && depth && out[0] && out[1]);
    for (int i = 0; i < 3 * n; i++) {
        color[i] = pattern(i, 0);
        albedo[i] = 0.2f + 0.5f * pattern(i / 3, 1);
        normal[i] = i % 3 == 2 ? 1.0f : 0.0f;
    }
    for (int i = 0; i < n; i++) depth[i] = 2.0f + (float)(i % 53) / 5.0f;
    ew_image c = ew_image_packed(color, w, h, 3), a = ew_image_packed(albedo, w, h, 3);
    ew_image nm = ew_image_packed(normal, w, h, 3), d = ew_image_packed(depth, w, h, 1);

    ew_op *op = NULL;
    CHECK(ew_op_create(dev, method, &op) == EW_OK);
    CHECK(ew_op_set_image(op, "color", &c) == EW_OK);
    CHECK(ew_op_set_image(op, "albedo", &a) == EW_OK);
    CHECK(ew_op_set_image(op, "normal", &nm) == EW_OK);
    CHECK(ew_op_set_image(op, "depth", &d) == EW_OK);
    int first = 0;
    for (int k = 0; k < 2; k++) {
        ew_image o = ew_image_packed(out[k], w, h, 3);
        CHECK(ew_op_set_image(op, "output", &o) == EW_OK);
        CHECK(ew_op_commit(op) == EW_OK);
        CHECK(ew_op_execute(op) == EW_OK);
        if (k == 0) {
            first = allocs;
            CHECK(first > 0); /* the counting table is the one in use */
        }
    }
    CHECK_EQ_INT(allocs, first);
    CHECK(memcmp(out[0], out[1], sizeof(float) * 3 * (size_t)n) == 0);

    /* another size: new memory, the same as a fresh op's result */
    const int w2 = 80, n2 = w2 * h;
    ew_image c2 = ew_image_packed(color, w2, h, 3), a2 = ew_image_packed(albedo, w2, h, 3);
    ew_image nm2 = ew_image_packed(normal, w2, h, 3), d2 = ew_image_packed(depth, w2, h, 1);
    ew_image o2 = ew_image_packed(out[0], w2, h, 3);
    CHECK(ew_op_set_image(op, "color", &c2) == EW_OK);
    CHECK(ew_op_set_image(op, "albedo", &a2) == EW_OK);
    CHECK(ew_op_set_image(op, "normal", &nm2) == EW_OK);
    CHECK(ew_op_set_image(op, "depth", &d2) == EW_OK);
    CHECK(ew_op_set_image(op, "output", &o2) == EW_OK);
    CHECK(ew_op_commit(op) == EW_OK);
    CHECK(ew_op_execute(op) == EW_OK);
    CHECK(allocs > first);
    ew_op *fresh = NULL;
    CHECK(ew_op_create(dev, method, &fresh) == EW_OK);
    ew_image of = ew_image_packed(out[1], w2, h, 3);
    CHECK(ew_op_set_image(fresh, "color", &c2) == EW_OK);
    CHECK(ew_op_set_image(fresh, "albedo", &a2) == EW_OK);
    CHECK(ew_op_set_image(fresh, "normal", &nm2) == EW_OK);
    CHECK(ew_op_set_image(fresh, "depth", &d2) == EW_OK);
    CHECK(ew_op_set_image(fresh, "output", &of) == EW_OK);
    CHECK(ew_op_commit(fresh) == EW_OK);
    CHECK(ew_op_execute(fresh) == EW_OK);
    CHECK(memcmp(out[0], out[1], sizeof(float) * 3 * (size_t)n2) == 0);

    ew_op_destroy(fresh);
    ew_op_destroy(op);
    dev->backend = orig;
    ew_device_destroy(dev);
    free(color);
    free(albedo);
    free(normal);
    free(depth);
    free(out[0]);
    free(out[1]);
}

TEST(bgrid_commit_again_allocates_nothing) { commit_again_allocates_nothing("bgrid"); }
TEST(nbg_commit_again_allocates_nothing) { commit_again_allocates_nothing("nbg"); }
TEST(kpcn_commit_again_allocates_nothing) { commit_again_allocates_nothing("kpcn"); }
TEST(auto_commit_again_allocates_nothing) { commit_again_allocates_nothing("auto"); }

/* dev[0] keeps its scratch, dev[1] hands it back between phases; 0 when
 * either cannot be made */
static int make_release_pair(ew_device *dev[2]) {
    for (int k = 0; k < 2; k++) {
        ew_device_desc desc = EW_DEVICE_DESC_INIT;
        desc.num_threads = 2;
        desc.release_scratch = k;
        dev[k] = NULL;
        if (ew_device_create(&desc, &dev[k]) != EW_OK) return 0;
    }
    return 1;
}

/* Commits op and runs it: once into ref on the device that keeps its
 * scratch (k 0), three times into out on the one that releases it (k 1);
 * 0 when a call fails or a run differs from ref in any bit. Destroys op. */
static int run_against_reference(ew_op *op, int k, float *out, const float *ref, size_t bytes) {
    int ok = ew_op_commit(op) == EW_OK;
    for (int run = 0; ok && run < (k ? 3 : 1); run++) {
        if (k) memset(out, 0, bytes);
        ok = ew_op_execute(op) == EW_OK && (!k || memcmp(out, ref, bytes) == 0);
    }
    ew_op_destroy(op);
    return ok;
}

/* A device with release_scratch hands the pages of the do-no-harm stage's
 * statistics back while the method runs, and the method's buffers once it
 * has run (they come back as zeros): every execute, the first and the ones
 * after a release, gives the output of a device that keeps them. The frame
 * spans many pages, holds fireflies (the stage's rejection and the
 * methods' clamps take light that must come back) and, for nbg at a 1 MiB
 * budget, several tiles (bgrid: bands). */
static void release_scratch_keeps_output(const char *method, int max_memory_mb) {
    ew_device *dev[2];
    CHECK(make_release_pair(dev));
    CHECK(!dev[0]->release_scratch && dev[1]->release_scratch);
    const int w = 300, h = 170, n = w * h;
    const size_t b3 = sizeof(float) * 3 * (size_t)n;
    float *color = malloc(b3), *albedo = malloc(b3), *normal = malloc(b3), *depth = malloc(sizeof(float) * (size_t)n);
    float *ref = malloc(b3), *out = malloc(b3);
    CHECK(color && albedo && normal && depth && ref && out);
    for (int i = 0; i < 3 * n; i++) {
        color[i] = pattern(i, 0) * (i / 3 % 997 == 5 ? 400.0f : 1.0f);
        albedo[i] = 0.2f + 0.5f * pattern(i / 3, 1);
        normal[i] = i % 3 == 2 ? 1.0f : 0.0f;
    }
    for (int i = 0; i < n; i++) depth[i] = 2.0f + (float)(i % 53) / 5.0f;
    ew_image c = ew_image_packed(color, w, h, 3), a = ew_image_packed(albedo, w, h, 3);
    ew_image nm = ew_image_packed(normal, w, h, 3), d = ew_image_packed(depth, w, h, 1);
    for (int k = 0; k < 2; k++) {
        ew_op *op = NULL;
        CHECK(ew_op_create(dev[k], method, &op) == EW_OK);
        ew_image o = ew_image_packed(k ? out : ref, w, h, 3);
        CHECK(ew_op_set_image(op, "color", &c) == EW_OK);
        CHECK(ew_op_set_image(op, "albedo", &a) == EW_OK);
        CHECK(ew_op_set_image(op, "normal", &nm) == EW_OK);
        CHECK(ew_op_set_image(op, "depth", &d) == EW_OK);
        CHECK(ew_op_set_image(op, "output", &o) == EW_OK);
        if (max_memory_mb) CHECK(ew_op_set_int(op, "max_memory_mb", max_memory_mb) == EW_OK);
        CHECK(run_against_reference(op, k, out, ref, b3));
    }
    ew_device_destroy(dev[0]);
    ew_device_destroy(dev[1]);
    free(color);
    free(albedo);
    free(normal);
    free(depth);
    free(ref);
    free(out);
}

TEST(nbg_release_scratch_keeps_output) { release_scratch_keeps_output("nbg", 0); }
TEST(nbg_tiled_release_scratch_keeps_output) { release_scratch_keeps_output("nbg", 1); }
TEST(kpcn_release_scratch_keeps_output) { release_scratch_keeps_output("kpcn", 0); }
TEST(kpcn_tiled_release_scratch_keeps_output) { release_scratch_keeps_output("kpcn", 16); }
TEST(auto_release_scratch_keeps_output) { release_scratch_keeps_output("auto", 0); }
TEST(bgrid_release_scratch_keeps_output) { release_scratch_keeps_output("bgrid", 0); }
TEST(bgrid_bands_release_scratch_keeps_output) { release_scratch_keeps_output("bgrid", 1); }

/* The pyramid's filters with release_scratch hand back the coarse levels'
 * pages that the upsampling of a finer level no longer reads: every execute
 * gives the output of a device that keeps them. Large enough for the
 * coarse levels to span whole pages; model gi with a roughness image keeps
 * its weight table after the levels; dof has the content CoC planes. */
static void pyramid_release_scratch_keeps_output(const char *method, int model) {
    ew_device *dev[2];
    CHECK(make_release_pair(dev));
    const int w = 640, h = 360, n = w * h;
    const size_t b3 = sizeof(float) * 3 * (size_t)n;
    float *color = malloc(b3), *normal = malloc(b3), *depth = malloc(sizeof(float) * (size_t)n);
    float *rough = malloc(sizeof(float) * (size_t)n), *ref = malloc(b3), *out = malloc(b3);
    CHECK(color && normal && depth && rough && ref && out);
    for (int i = 0; i < 3 * n; i++) {
        color[i] = pattern(i, 0) * (i / 3 % 997 == 5 ? 40.0f : 1.0f);
        normal[i] = i % 3 == 2 ? 1.0f : i % 3 == 0 ? 0.3f * pattern(i / 3 / w, 2) : 0.0f;
    }
    for (int i = 0; i < n; i++) {
        depth[i] = 2.0f + (float)(i % 53) / 5.0f + (float)(i / w % 40);
        rough[i] = pattern(i, 3);
    }
    ew_image c = ew_image_packed(color, w, h, 3), nm = ew_image_packed(normal, w, h, 3);
    ew_image d = ew_image_packed(depth, w, h, 1), r = ew_image_packed(rough, w, h, 1);
    for (int k = 0; k < 2; k++) {
        ew_op *op = NULL;
        CHECK(ew_op_create(dev[k], method, &op) == EW_OK);
        ew_image o = ew_image_packed(k ? out : ref, w, h, 3);
        CHECK(ew_op_set_image(op, "color", &c) == EW_OK);
        CHECK(ew_op_set_image(op, "depth", &d) == EW_OK);
        CHECK(ew_op_set_image(op, "output", &o) == EW_OK);
        if (model >= 0) {
            CHECK(ew_op_set_int(op, "model", model) == EW_OK);
            CHECK(ew_op_set_int(op, "radius", 24) == EW_OK);
            if (model == 1) {
                CHECK(ew_op_set_image(op, "normal", &nm) == EW_OK);
                CHECK(ew_op_set_image(op, "roughness", &r) == EW_OK);
            }
        } else {
            CHECK(ew_op_set_float(op, "fstop", 1.4f) == EW_OK);
            CHECK(ew_op_set_float(op, "focus_distance", 6.0f) == EW_OK);
        }
        CHECK(run_against_reference(op, k, out, ref, b3));
    }
    ew_device_destroy(dev[0]);
    ew_device_destroy(dev[1]);
    free(color);
    free(normal);
    free(depth);
    free(rough);
    free(ref);
    free(out);
}

TEST(pyramid_release_scratch_keeps_output) { pyramid_release_scratch_keeps_output("pyramid", 0); }
TEST(pyramid_gi_release_scratch_keeps_output) { pyramid_release_scratch_keeps_output("pyramid", 1); }
TEST(dof_release_scratch_keeps_output) { pyramid_release_scratch_keeps_output("dof", -1); }

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>

#include "kernels/compat.h"

/* A sparse plane (what a clamp took) is copied without writing a page of
 * zeros over a page of zeros: pages 0 and 2 of the destination are made
 * read-only, so a write there would fault; the nonzeros and the stale
 * values of page 1 are copied exactly. ew_store_sparse the same, value by
 * value. */
TEST(sparse_copies_leave_pages_of_zeros_unwritten) {
    const long ps = sysconf(_SC_PAGESIZE);
    CHECK(ps >= 4096);
    const size_t per = (size_t)ps / sizeof(float), n = 3 * per;
    float *dst = (float *)mmap(NULL, 3 * (size_t)ps, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    CHECK(dst != MAP_FAILED);
    float *src = (float *)calloc(n, sizeof(float));
    CHECK(src != NULL);
    src[per + 3] = 2.5f;     /* a value the clamp took */
    dst[per + 10] = 7.0f;    /* a stale value, to be overwritten by 0 */
    src[per + per - 1] = -1.0f;
    CHECK(mprotect(dst, (size_t)ps, PROT_READ) == 0);
    CHECK(mprotect(dst + 2 * per, (size_t)ps, PROT_READ) == 0);
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = 1;
    ew_device *dev = NULL;
    CHECK(ew_device_create(&desc, &dev) == EW_OK);
    CHECK_EQ_INT(ew_dev_copy_sparse(dev, dst, src, n), EW_OK);
    CHECK(memcmp(dst, src, n * sizeof(float)) == 0);
    /* as rows of a rect: a 2-row rect whose rows are the first and last pages */
    CHECK_EQ_INT(ew_dev_copy_rect_sparse(dev, dst, (int)per, 0, 0, src, (int)per, 0, 0, (int)per, 3), EW_OK);
    CHECK(memcmp(dst, src, n * sizeof(float)) == 0);
    /* value by value: zero over zero unwritten (page 0 is read-only), a zero over a value written */
    for (size_t i = 0; i < per; i++) ew_store_sparse(dst + i, 0.0f);
    ew_store_sparse(dst + per + 3, 0.0f);
    CHECK(dst[per + 3] == 0.0f);
    ew_store_sparse(dst + per + 4, 1.5f);
    CHECK(dst[per + 4] == 1.5f);
    ew_device_destroy(dev);
    free(src);
    munmap(dst, 3 * (size_t)ps);
}
#endif
