/*
 * parity_body.h — every backend entry, and every op ported to device
 * memory, run on a device under test and on the CPU backend, compared.
 * Included by test_launch_grid.c (the device under test is the CPU harness
 * walking the CUDA launch grids: results must be bit for bit the CPU's) and
 * by tests/gpu/test_gpu_parity.c (a real GPU: to rounding). Sizes are not
 * multiples of the block size, inputs hold NaN/Inf, buffers are allocated,
 * filled and read through the device's own memory entries.
 *
 * The includer defines, before including:
 *   static ew_device *dut_create(int device_images);  a fresh device under test
 *   static const int dut_exact;                        1: bit for bit
 *   static int dut_live_blocks(void);                  device blocks alive (or 0)
 *   static const char *dut_skip_reason(void);          why dut_create gave NULL
 *   CHECK_NO_MISUSE()                                  fails the test on misuse seen
 * and includes ew_test.h; tests that cannot get a device SKIP.
 */
#ifndef EW_TESTS_PARITY_BODY_H
#define EW_TESTS_PARITY_BODY_H

#include <stdint.h>

#include "algorithms/bgrid.h"
#include "algorithms/guidenet.h"
#include "algorithms/pyramid.h"
#include "kernels/denoise_px.h"
#include "kernels/dof.h"
#include "kernels/harm.h"
#include "kernels/kernel_list.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "kernels/temporal.h"
#include "kernels/view.h"
#include "src/backend.h"
#include "src/internal.h"
#include "src/op.h"

#define W 37 /* 2 blocks and a bit across (16), */
#define H 29 /* 3 blocks and a bit down (8) */
#define N ((size_t)W * H)

/* ---- small helpers ------------------------------------------------------- */
static uint32_t rng = 2463534242u;
static float rnd(void) {
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return (float)(rng >> 8) / 16777216.0f;
}
static float rnd_in(float lo, float hi) { return lo + (hi - lo) * rnd(); }

/* Everything a test allocates, freed by release_all. */
static void *host_bufs[128];
static float *dev_bufs[128];
static int n_host, n_dev;

static float *keep_host(float *p) {
    if (n_host < 128) host_bufs[n_host++] = p;
    return p;
}
static float *keep_dev(float *p) {
    if (n_dev < 128) dev_bufs[n_dev++] = p;
    return p;
}
/* Random host floats in [lo, hi), with every `holes`-th a NaN/Inf when
 * holes > 0 (missing samples: every kernel must treat them alike). */
static float *hrand(size_t n, float lo, float hi, int holes) {
    float *p = keep_host((float *)malloc(n * sizeof(float) + 1));
    for (size_t i = 0; i < n; i++) {
        p[i] = rnd_in(lo, hi);
        if (holes > 0 && i % (size_t)holes == 7) p[i] = (i / (size_t)holes) % 2 ? NAN : INFINITY;
    }
    return p;
}
/* Pixels of c channels in [lo, hi) with every `holes`-th pixel missing:
 * NaN in every channel, as the bilateral family's packers make them (those
 * kernels test the first channel only). */
static float *hrand_px(size_t pixels, int c, float lo, float hi, int holes) {
    float *p = hrand(pixels * (size_t)c, lo, hi, 0);
    for (size_t i = 7; holes > 0 && i < pixels; i += (size_t)holes)
        for (int k = 0; k < c; k++) p[i * (size_t)c + (size_t)k] = NAN;
    return p;
}
/* Host floats with NaN bits, as the harness fills device blocks: outputs
 * that a kernel leaves alone then compare equal. */
static float *hnan(size_t n) {
    float *p = keep_host((float *)malloc(n * sizeof(float) + 1));
    memset(p, 0xff, n * sizeof(float));
    return p;
}
static float *hcopy(const float *src, size_t n) {
    float *p = keep_host((float *)malloc(n * sizeof(float) + 1));
    memcpy(p, src, n * sizeof(float));
    return p;
}
/* Device buffers through the backend's own entries (any backend). */
static float *dup_to(ew_device *dev, const float *h, size_t n) {
    float *d = keep_dev((float *)dev->backend->mem_alloc(dev, n * sizeof(float)));
    if (d) dev->backend->mem_upload(dev, d, h, n * sizeof(float));
    return d;
}
static float *hnan(size_t n);
/* NaN bits, as the harness fills its blocks: outputs a kernel leaves alone
 * then compare equal with the CPU's */
static float *dnan(ew_device *dev, size_t n) { return dup_to(dev, hnan(n), n); }
static float *back(ew_device *dev, const float *d, size_t n) {
    float *h = keep_host((float *)malloc(n * sizeof(float) + 1));
    dev->backend->mem_download(dev, h, d, n * sizeof(float));
    return h;
}

static void release_all(ew_device *dev) {
    for (int i = 0; i < n_dev; i++) dev->backend->mem_free(dev, dev_bufs[i]);
    for (int i = 0; i < n_host; i++) free(host_bufs[i]);
    n_dev = n_host = 0;
}

/* Bit-for-bit equality (NaN payloads included). */
static int same(const void *grid, const void *cpu, size_t floats, const char *what) {
    const float *a = (const float *)grid, *b = (const float *)cpu;
    for (size_t i = 0; i < floats; i++)
        if (memcmp(a + i, b + i, sizeof(float)) != 0) {
            fprintf(stderr, "  %s differs at %zu: %.9g (device under test) vs %.9g (cpu backend)\n", what, i, (double)a[i],
                    (double)b[i]);
            return 0;
        }
    return 1;
}
/* Both NaN, both the same infinity, or within rel of each other. */
static int close_to(float a, float b, float rel) {
    if (isnan(a) || isnan(b)) return isnan(a) && isnan(b);
    if (isinf(a) || isinf(b)) return a == b;
    return fabsf(a - b) <= rel * (1.0f + fabsf(b));
}
/* A GPU contracts a*b+c into FMAs and its powf/expf differ in the last
 * bits, so a coordinate can land on the other side of a floor() in rare
 * pixels: allow one element in a thousand beyond rel, and report the worst. */
static int close_enough(const float *dut, const float *cpu, size_t n, float rel, const char *what) {
    size_t bad = 0, worst = 0;
    float worst_err = 0.0f;
    for (size_t i = 0; i < n; i++)
        if (!close_to(dut[i], cpu[i], rel)) {
            bad++;
            const float e = fabsf(dut[i] - cpu[i]);
            if (!(e <= worst_err)) {
                worst_err = e;
                worst = i;
            }
        }
    if (bad * 1000 > n || (bad && isnan(worst_err))) {
        fprintf(stderr, "  %s: %zu of %zu differ beyond %g; worst at %zu: %.9g vs %.9g (cpu backend)\n", what, bad, n,
                (double)rel, worst, (double)dut[worst], (double)cpu[worst]);
        return 0;
    }
    return 1;
}
static int same(const void *grid, const void *cpu, size_t floats, const char *what);
static int near(const float *a, const float *b, size_t n, float rel, const char *what);
/* Exact for a device that runs the CPU's code (the harness), to rounding
 * for a GPU. */
static int match(const void *dut, const void *cpu, size_t floats, const char *what) {
    return dut_exact ? same(dut, cpu, floats, what)
                     : close_enough((const float *)dut, (const float *)cpu, floats, 1e-3f, what);
}
static int match_tol(const float *dut, const float *cpu, size_t n, float rel, const char *what) {
    return dut_exact ? near(dut, cpu, n, rel, what) : close_enough(dut, cpu, n, rel > 1e-3f ? rel : 1e-3f, what);
}
static int match_doubles(const void *dut, const double *cpu, size_t n, const char *what) {
    if (dut_exact) return same(dut, cpu, n * 2, what);
    const double *d = (const double *)dut;
    for (size_t i = 0; i < n; i++)
        if (!(fabs(d[i] - cpu[i]) <= 1e-5 * (1.0 + fabs(cpu[i])))) {
            fprintf(stderr, "  %s differs at %zu: %.17g vs %.17g (cpu backend)\n", what, i, d[i], cpu[i]);
            return 0;
        }
    return 1;
}
static int near(const float *a, const float *b, size_t n, float rel, const char *what) {
    for (size_t i = 0; i < n; i++)
        if (!(fabsf(a[i] - b[i]) <= rel * (1.0f + fabsf(b[i])))) {
            fprintf(stderr, "  %s differs at %zu: %.9g (device under test) vs %.9g (cpu backend)\n", what, i, (double)a[i],
                    (double)b[i]);
            return 0;
        }
    return 1;
}

typedef struct {
    ew_device *cpu, *dut;
} pair;
static pair open_pair(int device_images) {
    pair p;
    ew_device_desc d = EW_DEVICE_DESC_INIT;
    d.type = EW_DEVICE_CPU;
    d.num_threads = 3;
    p.cpu = NULL;
    ew_device_create(&d, &p.cpu);
    p.dut = dut_create(device_images);
    return p;
}
/* A CPU device and a device under test, or SKIP the test without one. */
#define OPEN_PAIR(p, device_images)                      \
    pair p = open_pair(device_images);                   \
    if (!p.dut) {                                        \
        ew_device_destroy(p.cpu);                        \
        SKIP(dut_skip_reason());                         \
    }
static void close_pair(pair *p) {
    release_all(p->dut);
    ew_device_destroy(p->cpu);
    ew_device_destroy(p->dut);
}

/* ---- every entry against the CPU backend --------------------------------- */
TEST(bgrid_splat_and_slice) {
    OPEN_PAIR(p, 0);
    ew_bgrid_params g;
    CHECK(ew_bgrid_params_init(&g, W, H, 4.0f, 16.0f, 3));
    const size_t gf = ew_bgrid_floats(&g);
    float *image = hrand(N * 3, 0.0f, 2.0f, 41), *guide = hrand(N, 0.0f, 255.0f, 53);
    float *grid = hnan(gf);
    ew_cpu_backend.bgrid_splat(p.cpu, &g, image, guide, grid);
    float *dgrid = dnan(p.dut, gf);
    p.dut->backend->bgrid_splat(p.dut, &g, dup_to(p.dut, image, N * 3), dup_to(p.dut, guide, N), dgrid);
    int ok = match(back(p.dut, dgrid, gf), grid, gf, "splat grid");
    float *out = hnan(N * 3), *dout = dnan(p.dut, N * 3);
    ew_cpu_backend.bgrid_slice(p.cpu, &g, grid, guide, out);
    p.dut->backend->bgrid_slice(p.dut, &g, dup_to(p.dut, grid, gf), dup_to(p.dut, guide, N), dout);
    ok = ok && match(back(p.dut, dout, N * 3), out, N * 3, "sliced");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

/* A band of rows (kernels/bgrid.h: rows 7..22 of the frame, the grid rows
 * they read): the kernels' bodies take the band's origin as the CPU does,
 * and the band's middle rows slice what the whole frame's do. */
TEST(bgrid_splat_and_slice_in_a_band) {
    OPEN_PAIR(p, 0);
    ew_bgrid_params f, g;
    CHECK(ew_bgrid_params_init(&f, W, H, 2.5f, 16.0f, 3));
    const int y0 = 7, rows = 16;
    ew_bgrid_params_band(&f, y0, rows, &g);
    CHECK(g.band_y == y0 && g.band_v > 0 && g.gh < f.gh);
    const size_t gf = ew_bgrid_floats(&g), ff = ew_bgrid_floats(&f), bn = (size_t)W * rows;
    float *image = hrand(N * 3, 0.0f, 2.0f, 43), *guide = hrand(N, 0.0f, 255.0f, 57);
    const float *bimage = image + (size_t)y0 * W * 3, *bguide = guide + (size_t)y0 * W;
    float *grid = hnan(gf), *out = hnan(bn * 3), *fgrid = hnan(ff), *fout = hnan(N * 3);
    ew_cpu_backend.bgrid_splat(p.cpu, &g, bimage, bguide, grid);
    float *dgrid = dnan(p.dut, gf);
    p.dut->backend->bgrid_splat(p.dut, &g, dup_to(p.dut, bimage, bn * 3), dup_to(p.dut, bguide, bn), dgrid);
    int ok = match(back(p.dut, dgrid, gf), grid, gf, "band's grid");
    ew_cpu_backend.bgrid_slice(p.cpu, &g, grid, bguide, out);
    float *dout = dnan(p.dut, bn * 3);
    p.dut->backend->bgrid_slice(p.dut, &g, dup_to(p.dut, grid, gf), dup_to(p.dut, bguide, bn), dout);
    ok = ok && match(back(p.dut, dout, bn * 3), out, bn * 3, "band's slice");
    ew_cpu_backend.bgrid_splat(p.cpu, &f, image, guide, fgrid);
    ew_cpu_backend.bgrid_slice(p.cpu, &f, fgrid, guide, fout);
    const int reach = ew_bgrid_reach(f.rate_s); /* rows 12..17 have every row they read in the band */
    ok = ok && same(out + (size_t)reach * W * 3, fout + (size_t)(y0 + reach) * W * 3,
                    (size_t)(rows - 2 * reach) * W * 3, "band's middle rows against the frame's");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

static ew_denoise_buffers denoise_host(int features) {
    ew_denoise_buffers b;
    memset(&b, 0, sizeof b);
    b.width = W;
    b.height = H;
    b.color = hrand(N * 3, 0.0f, 3.0f, 37);
    if (features) {
        b.albedo = hrand(N * 3, -0.1f, 1.1f, 61);
        b.normal = hrand(N * 3, -1.0f, 1.0f, 0);
        b.depth = hrand(N, 0.5f, 20.0f, 71);
        b.depth_scale = 0.05f;
    }
    b.radiance = hnan(N * 3);
    b.guide = hrand(N, 0.0f, 255.0f, 0);
    b.sliced = hrand(N * 3, 0.0f, 2.0f, 43);
    b.out = hnan(N * 3);
    return b;
}
static ew_denoise_buffers denoise_dev(ew_device *lg, const ew_denoise_buffers *h) {
    ew_denoise_buffers d = *h;
    d.color = dup_to(lg, h->color, N * 3);
    d.albedo = h->albedo ? dup_to(lg, h->albedo, N * 3) : NULL;
    d.normal = h->normal ? dup_to(lg, h->normal, N * 3) : NULL;
    d.depth = h->depth ? dup_to(lg, h->depth, N) : NULL;
    d.radiance = dup_to(lg, h->radiance, N * 3);
    d.guide = dup_to(lg, h->guide, N);
    d.sliced = dup_to(lg, h->sliced, N * 3);
    d.out = dup_to(lg, h->out, N * 3);
    return d;
}

TEST(denoise_prepare_refine_finish) {
    for (int features = 0; features <= 1; features++) {
        OPEN_PAIR(p, 0);
        ew_denoise_buffers h = denoise_host(features);
        ew_denoise_buffers d = denoise_dev(p.dut, &h);
        ew_cpu_backend.denoise_prepare(p.cpu, &h);
        p.dut->backend->denoise_prepare(p.dut, &d);
        int ok = match(back(p.dut, d.radiance, N * 3), h.radiance, N * 3, "radiance") &&
                 match(back(p.dut, d.guide, N), h.guide, N, "guide");
        ew_cpu_backend.denoise_refine_guide(p.cpu, &h, 0.37f, 0.7f);
        p.dut->backend->denoise_refine_guide(p.dut, &d, 0.37f, 0.7f);
        ok = ok && match(back(p.dut, d.guide, N), h.guide, N, "refined guide");
        ew_cpu_backend.denoise_finish(p.cpu, &h);
        p.dut->backend->denoise_finish(p.dut, &d);
        ok = ok && match(back(p.dut, d.out, N * 3), h.out, N * 3, "remodulated");
        close_pair(&p);
        CHECK(ok);
        CHECK_NO_MISUSE();
    }
}

/* A tile's region read where it lies in the frame's inputs (in_stride):
 * the same bits as the region packed first, on both devices. */
TEST(denoise_on_a_region_of_the_frame) {
    OPEN_PAIR(p, 0);
    ew_denoise_buffers f = denoise_host(1);
    const int x0 = 4, y0 = 3, rw = W - 9, rh = H - 7;
    const size_t rn = (size_t)rw * rh;
    /* the reference: the region packed */
    ew_denoise_buffers k;
    memset(&k, 0, sizeof k);
    k.width = rw;
    k.height = rh;
    k.depth_scale = f.depth_scale;
    float *kc = hnan(rn * 3), *ka = hnan(rn * 3), *kn = hnan(rn * 3), *kd = hnan(rn);
    for (int y = 0; y < rh; y++) {
        const size_t from = (size_t)(y0 + y) * W + x0, to = (size_t)y * rw;
        memcpy(kc + to * 3, f.color + from * 3, (size_t)rw * 3 * sizeof(float));
        memcpy(ka + to * 3, f.albedo + from * 3, (size_t)rw * 3 * sizeof(float));
        memcpy(kn + to * 3, f.normal + from * 3, (size_t)rw * 3 * sizeof(float));
        memcpy(kd + to, f.depth + from, (size_t)rw * sizeof(float));
    }
    k.color = kc, k.albedo = ka, k.normal = kn, k.depth = kd;
    k.radiance = hnan(rn * 3);
    k.guide = hnan(rn);
    k.sliced = hrand(rn * 3, 0.0f, 2.0f, 43);
    k.out = hnan(rn * 3);
    /* the region where it lies */
    ew_denoise_buffers h = k;
    const size_t at = (size_t)y0 * W + x0;
    h.in_stride = W;
    h.color = f.color + at * 3, h.albedo = f.albedo + at * 3, h.normal = f.normal + at * 3, h.depth = f.depth + at;
    h.radiance = hnan(rn * 3);
    h.guide = hnan(rn);
    h.out = hnan(rn * 3);
    ew_denoise_buffers d = denoise_dev(p.dut, &f);
    d.width = rw;
    d.height = rh;
    d.in_stride = W;
    d.color += at * 3, d.albedo += at * 3, d.normal += at * 3, d.depth += at;
    d.sliced = dup_to(p.dut, k.sliced, rn * 3);
    ew_cpu_backend.denoise_prepare(p.cpu, &k);
    ew_cpu_backend.denoise_prepare(p.cpu, &h);
    p.dut->backend->denoise_prepare(p.dut, &d);
    int ok = same(h.radiance, k.radiance, rn * 3, "radiance against the packed region's") &&
             same(h.guide, k.guide, rn, "guide against the packed region's") &&
             match(back(p.dut, d.radiance, rn * 3), h.radiance, rn * 3, "radiance") &&
             match(back(p.dut, d.guide, rn), h.guide, rn, "guide");
    ew_cpu_backend.denoise_finish(p.cpu, &k);
    ew_cpu_backend.denoise_finish(p.cpu, &h);
    p.dut->backend->denoise_finish(p.dut, &d);
    ok = ok && same(h.out, k.out, rn * 3, "remodulated against the packed region's") &&
         match(back(p.dut, d.out, rn * 3), h.out, rn * 3, "remodulated");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(outlier_clamp) {
    /* the denoisers' firefly clamp (plain statistics) and the op layer's
     * rejection (robust, with features and floors): one kernel, two uses */
    OPEN_PAIR(p, 0);
    float *in = hrand(N * 3, 0.0f, 1.0f, 29);
    for (size_t i = 5; i < N * 3; i += 97) in[i] = 500.0f; /* fireflies */
    float *albedo = hrand(N * 3, 0.0f, 1.0f, 0), *normal = hrand(N * 3, -1.0f, 1.0f, 0);
    for (size_t i = 0; i < N * 3; i++) albedo[i] = albedo[i] < 0.5f ? 0.2f : 0.8f;
    float *out = hnan(N * 3), *dout = dnan(p.dut, N * 3);
    ew_outlier_params op = ew_outlier_plain_params(W, H, 2, 3.0f);
    ew_outlier_buffers h = {in, NULL, NULL, out, 3, NULL}, d = {dup_to(p.dut, in, N * 3), NULL, NULL, dout, 3, NULL};
    ew_cpu_backend.outlier_guided(p.cpu, &op, &h);
    p.dut->backend->outlier_guided(p.dut, &op, &d);
    int ok = match(back(p.dut, dout, N * 3), out, N * 3, "clamped");
    op.robust = 1;
    op.radius = 5; /* beyond EW_OUTLIER_ROBUST_RADIUS: treated as 3 */
    op.k = 4.0f;
    op.albedo_tol = 0.1f;
    op.normal_cos = 0.5f;
    op.sigma_floor = 0.5f;
    op.abs_floor = 0.05f;
    h.albedo = albedo;
    h.normal = normal;
    d.albedo = dup_to(p.dut, albedo, N * 3);
    d.normal = dup_to(p.dut, normal, N * 3);
    ew_cpu_backend.outlier_guided(p.cpu, &op, &h);
    p.dut->backend->outlier_guided(p.dut, &op, &d);
    ok = ok && match(back(p.dut, dout, N * 3), out, N * 3, "rejected (robust)");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(outlier_robust_surfaces) {
    /* the rejection the op layer runs before every method: smooth surfaces
     * (most neighbours similar, so most pixels are kept by the count and a
     * few judged by their median), normals facing apart and background,
     * lone emitter hits, fireflies, holes in colour and features, both
     * window radii, with and without the removed light */
    OPEN_PAIR(p, 0);
    float *color = hrand(N * 3, 0.2f, 0.6f, 0), *albedo = hnan(N * 3), *normal = hnan(N * 3);
    for (size_t i = 0; i < N; i++) {
        const int x = (int)(i % W), y = (int)(i / W);
        const float tone = x < W / 2 ? 0.3f : 0.7f;
        for (int c = 0; c < 3; c++) albedo[i * 3 + c] = tone;
        /* below the top quarter (no surface), stripes facing apart, dark and bright */
        const int facing = (x / 3 + y / 2) % 2;
        normal[i * 3] = y < H / 4 ? 0.0f : (facing ? 0.8f : -0.8f);
        normal[i * 3 + 1] = 0.0f;
        normal[i * 3 + 2] = y < H / 4 ? 0.0f : 0.6f;
        if (y >= H / 4 && facing)
            for (int c = 0; c < 3; c++) color[i * 3 + c] *= 6.0f;
        if (i % 11 == 4) for (int c = 0; c < 3; c++) color[i * 3 + c] *= 40.0f; /* fireflies */
        if (i % 53 == 9) color[i * 3 + 1] = i % 2 ? NAN : INFINITY;
        if (i % 59 == 3) albedo[i * 3 + 2] = NAN;
        if (i % 61 == 5) normal[i * 3] = INFINITY;
        if (i % 97 == 40) { /* a lone emitter hit */
            for (int c = 0; c < 3; c++) albedo[i * 3 + c] = 50.0f;
            color[i * 3] = 9.0f;
        }
        if (i % 89 == 17) for (int c = 0; c < 3; c++) color[i * 3 + c] = 0.0f;
    }
    float *removed = hnan(N), *dremoved = dnan(p.dut, N);
    ew_outlier_buffers h = {color, albedo, normal, hnan(N * 3), 3, removed}, d = h;
    d.color = dup_to(p.dut, color, N * 3);
    d.albedo = dup_to(p.dut, albedo, N * 3);
    d.normal = dup_to(p.dut, normal, N * 3);
    d.out = dnan(p.dut, N * 3);
    d.removed = dremoved;
    int ok = 1;
    for (int r = 2; r <= 3; r++) {
        ew_outlier_params op = ew_outlier_plain_params(W, H, r, 3.0f);
        op.robust = 1;
        op.albedo_tol = 0.1f;
        op.normal_cos = 0.5f;
        op.sigma_floor = 0.3f;
        op.abs_floor = 0.01f;
        op.repair = r == 2;
        op.emitter_albedo = 16.0f;
        ew_cpu_backend.outlier_guided(p.cpu, &op, &h);
        p.dut->backend->outlier_guided(p.dut, &op, &d);
        int changed = 0;
        for (size_t i = 0; i < N * 3; i++) changed += h.out[i] != color[i] && isfinite(color[i]);
        ok = ok && changed > 20; /* the case judges pixels, not only keeps them */
        ok = ok && match(back(p.dut, d.out, N * 3), h.out, N * 3, "rejected");
        ok = ok && match(back(p.dut, d.removed, N), h.removed, N, "removed light");
        /* the share a pixel lost: out = colour (1 - share) in RGB, 0 where kept */
        int shares = 0;
        for (size_t i = 0; i < N; i++) {
            const float q = h.removed[i];
            shares += q != 0.0f;
            const int finite = isfinite(color[i * 3]) && isfinite(color[i * 3 + 1]) && isfinite(color[i * 3 + 2]);
            for (int c = 0; c < 3 && finite; c++)
                ok = ok && (q == 0.0f ? h.out[i * 3 + c] == color[i * 3 + c]
                                      : q > 0.0f && q < 1.0f &&
                                            fabsf(color[i * 3 + c] * (1.0f - q) - h.out[i * 3 + c]) <=
                                                1e-5f * fabsf(color[i * 3 + c]));
        }
        ok = ok && shares > 20;
        /* and with the albedo alone, the normal alone */
        ew_outlier_buffers ha = h, da = d;
        ha.normal = da.normal = NULL;
        ew_cpu_backend.outlier_guided(p.cpu, &op, &ha);
        p.dut->backend->outlier_guided(p.dut, &op, &da);
        ok = ok && match(back(p.dut, da.out, N * 3), ha.out, N * 3, "rejected by albedo");
        ha = h, da = d;
        ha.albedo = da.albedo = NULL;
        ew_cpu_backend.outlier_guided(p.cpu, &op, &ha);
        p.dut->backend->outlier_guided(p.dut, &op, &da);
        ok = ok && match(back(p.dut, da.out, N * 3), ha.out, N * 3, "rejected by normal");
    }
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(harm_stage_steps) {
    /* every step of the do-no-harm stage, with alpha, NaN/Inf and a firefly */
    OPEN_PAIR(p, 0);
    float *color = hrand(N * 4, 0.0f, 2.0f, 31), *albedo = hrand(N * 3, 0.0f, 1.0f, 37);
    float *rejected = hrand(N * 3, 0.0f, 2.0f, 0), *out = hrand(N * 3, 0.0f, 2.0f, 0);
    color[4 * 11] = 3e4f;
    ew_harm_args h;
    memset(&h, 0, sizeof h);
    h.width = W;
    h.height = H;
    h.channels = 4;
    h.radius = 3;
    h.strength = 1.0f;
    h.color = color;
    h.albedo = albedo;
    h.radiance = hnan(N * 3);
    h.rejected = rejected;
    h.clamped = hnan(N * 4);
    h.out = out;
    h.stats = hnan(N * EW_HARM_STATS_FLOATS);
    h.z = 1.0f;
    h.theta = 0.4f;
    h.kappa = 1.0f;
    h.theta_n = 0.2f;
    h.fade = 0.25f; /* the blend a quarter faded, as on a noisy frame */
    h.give = hrand(N, 0.0f, 1.0f, 41); /* the share a method's clamp took */
    h.spread = hnan(N * 2);
    h.give_radius = 7; /* 15 taps: 5 blocks of 3 (kernels/harm.h), windows past every edge */
    h.give_cap = 2.0f;
    h.give_limit = 5.0f;
    h.take_limit = 4.0f;
    h.give_gain = 0.5f;
    h.gain = 0.3f;
    ew_harm_args d = h;
    d.color = dup_to(p.dut, color, N * 4);
    d.albedo = dup_to(p.dut, albedo, N * 3);
    d.radiance = dnan(p.dut, N * 3);
    d.rejected = dup_to(p.dut, rejected, N * 3);
    d.clamped = dnan(p.dut, N * 4);
    d.out = dup_to(p.dut, out, N * 3);
    d.stats = dnan(p.dut, N * EW_HARM_STATS_FLOATS);
    d.give = dup_to(p.dut, h.give, N);
    d.spread = dnan(p.dut, N * 2);
    /* the rejection keeps most pixels: the radiance itself, then a few
     * changed; then the blend and the energy return */
    for (int step = EW_HARM_DEMOD; step <= EW_HARM_SCALE; step++) {
        if (step == EW_HARM_REMOD) {
            for (size_t i = 0; i < N * 3; i++) rejected[i] = h.radiance[i] * (i % 17 == 3 ? 0.5f : 1.0f);
            h.rejected = rejected;
            d.rejected = dup_to(p.dut, rejected, N * 3);
        }
        ew_cpu_backend.harm(p.cpu, step, &h);
        p.dut->backend->harm(p.dut, step, &d);
    }
    int ok = match(back(p.dut, d.radiance, N * 3), h.radiance, N * 3, "demodulated");
    ok = ok && match(back(p.dut, d.clamped, N * 4), h.clamped, N * 4, "remodulated");
    ok = ok && match(back(p.dut, d.stats, N * EW_HARM_STATS_FLOATS), h.stats, N * EW_HARM_STATS_FLOATS, "residual statistics");
    ok = ok && match(back(p.dut, d.give, N), h.give, N, "shares given back");
    ok = ok && match(back(p.dut, d.spread, N * 2), h.spread, N * 2, "box sums of the energy return");
    ok = ok && match(back(p.dut, d.out, N * 3), h.out, N * 3, "blended, light given back");
    /* what the rejection took, kept for TAKE (a caller's output over its colour) */
    h.excess = hrand(N, 0.0f, 0.0f, 0); /* zero first: written where the rejection took something */
    d.excess = dup_to(p.dut, h.excess, N);
    ew_cpu_backend.harm(p.cpu, EW_HARM_EXCESS, &h);
    p.dut->backend->harm(p.dut, EW_HARM_EXCESS, &d);
    ok = ok && match(back(p.dut, d.excess, N), h.excess, N, "the rejection's excess");
    h.excess = d.excess = NULL;
    /* RGB colour (no channels to copy), with and without albedo: the CPU
     * backend's rows take other paths there */
    for (int with_albedo = 0; with_albedo < 2; with_albedo++) {
        h.channels = d.channels = 3;
        h.albedo = with_albedo ? albedo : NULL;
        d.albedo = with_albedo ? dup_to(p.dut, albedo, N * 3) : NULL;
        d.color = dup_to(p.dut, color, N * 3);
        for (int step = EW_HARM_DEMOD; step <= EW_HARM_BLEND; step++) {
            ew_cpu_backend.harm(p.cpu, step, &h);
            p.dut->backend->harm(p.dut, step, &d);
        }
        ok = ok && match(back(p.dut, d.radiance, N * 3), h.radiance, N * 3, "demodulated RGB");
        ok = ok && match(back(p.dut, d.clamped, N * 3), h.clamped, N * 3, "remodulated RGB");
        ok = ok && match(back(p.dut, d.out, N * 3), h.out, N * 3, "blended RGB");
        /* REMOD over the rejected radiance itself (the stage's denoiser
         * path: the rejection writes where the clamped colour goes) */
        float *const hkept = h.clamped, *const dkept = d.clamped;
        h.rejected = h.clamped = hcopy(rejected, N * 3);
        d.rejected = d.clamped = dup_to(p.dut, rejected, N * 3);
        ew_cpu_backend.harm(p.cpu, EW_HARM_REMOD, &h);
        p.dut->backend->harm(p.dut, EW_HARM_REMOD, &d);
        ok = ok && match(back(p.dut, d.clamped, N * 3), h.clamped, N * 3, "remodulated RGB in place");
        h.rejected = rejected;
        d.rejected = dup_to(p.dut, rejected, N * 3);
        h.clamped = hkept;
        d.clamped = dkept;
    }
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(outlier_guided_with_alpha_and_holes) {
    OPEN_PAIR(p, 0);
    /* 4 channels (alpha copied), fireflies, NaN/Inf in colour and features;
     * albedo in two tones so that similarity splits the windows */
    float *color = hrand(N * 4, 0.0f, 1.0f, 31), *albedo = hrand(N * 3, 0.0f, 1.0f, 43);
    float *normal = hrand(N * 3, -1.0f, 1.0f, 53);
    for (size_t i = 0; i < N; i += 13) color[i * 4 + 1] = 800.0f;
    for (size_t i = 0; i < N * 3; i++)
        if (isfinite(albedo[i])) albedo[i] = albedo[i] < 0.5f ? 0.2f : 0.8f;
    const ew_outlier_params op = {W, H, 2, 3.0f, 0.1f, 0.5f, 0.1f, 0.0f, 0, 1, 1, 0.0f};
    ew_outlier_buffers h = {color, albedo, normal, hnan(N * 4), 4, NULL}, d = h;
    d.color = dup_to(p.dut, color, N * 4);
    d.albedo = dup_to(p.dut, albedo, N * 3);
    d.normal = dup_to(p.dut, normal, N * 3);
    d.out = dnan(p.dut, N * 4);
    ew_cpu_backend.outlier_guided(p.cpu, &op, &h);
    p.dut->backend->outlier_guided(p.dut, &op, &d);
    int ok = match(back(p.dut, d.out, N * 4), h.out, N * 4, "outlier-filtered");
    /* and without the features */
    h.albedo = h.normal = d.albedo = d.normal = NULL;
    ew_cpu_backend.outlier_guided(p.cpu, &op, &h);
    p.dut->backend->outlier_guided(p.dut, &op, &d);
    ok = ok && match(back(p.dut, d.out, N * 4), h.out, N * 4, "outlier-filtered, no features");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(temporal_accumulation) {
    OPEN_PAIR(p, 0);
    ew_temporal_params tp = {W, H, 0.2f, 0.9f, 0.1f, 1.0f, 32.0f, 0.0f};
    ew_temporal_buffers h, d;
    h.color = hrand(N * 3, 0.0f, 2.0f, 59);
    h.normal = hrand(N * 3, -1.0f, 1.0f, 0);
    h.depth = hrand(N, 1.0f, 3.0f, 0);
    h.motion = hrand(N * 2, -3.0f, 3.0f, 83);
    h.prev_color = hrand(N * 3, 0.0f, 2.0f, 67);
    h.prev_normal = hcopy(h.normal, N * 3);
    h.prev_depth = hrand(N, 1.0f, 3.3f, 0);
    h.prev_len = hrand(N, -1.0f, 10.0f, 0);
    h.out_color = hnan(N * 3);
    h.out_len = hnan(N);
    d.color = dup_to(p.dut, h.color, N * 3);
    d.normal = dup_to(p.dut, h.normal, N * 3);
    d.depth = dup_to(p.dut, h.depth, N);
    d.motion = dup_to(p.dut, h.motion, N * 2);
    d.prev_color = dup_to(p.dut, h.prev_color, N * 3);
    d.prev_normal = dup_to(p.dut, h.prev_normal, N * 3);
    d.prev_depth = dup_to(p.dut, h.prev_depth, N);
    d.prev_len = dup_to(p.dut, h.prev_len, N);
    d.out_color = dnan(p.dut, N * 3);
    d.out_len = dnan(p.dut, N);
    ew_cpu_backend.temporal(p.cpu, &tp, &h);
    p.dut->backend->temporal(p.dut, &tp, &d);
    int ok = match(back(p.dut, d.out_color, N * 3), h.out_color, N * 3, "accumulated") &&
             match(back(p.dut, d.out_len, N), h.out_len, N, "history length");
    tp.clamp = 1.0f; /* with the history clamp (variance clipping) */
    ew_cpu_backend.temporal(p.cpu, &tp, &h);
    p.dut->backend->temporal(p.dut, &tp, &d);
    ok = ok && match(back(p.dut, d.out_color, N * 3), h.out_color, N * 3, "accumulated, clamped") &&
         match(back(p.dut, d.out_len, N), h.out_len, N, "history length, clamped");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

/* One frame of the temporal filter on dev; views of this frame's inputs
 * (device copies when the device takes device pointers), output to out. */
static ew_result temporal_frame(ew_device *dev, ew_op *op, float *const in[4], float *out) {
    static const char *names[4] = {"color", "normal", "depth", "vector"};
    static const int chans[4] = {3, 3, 1, 2};
    ew_result r = EW_OK;
    for (int i = 0; i < 4 && r == EW_OK; i++) {
        float *data = dev->device_images ? dup_to(dev, in[i], N * (size_t)chans[i]) : in[i];
        ew_image v = ew_image_packed(data, W, H, chans[i]);
        r = ew_op_set_image(op, names[i], &v);
    }
    float *o = dev->device_images ? dnan(dev, N * 3) : out;
    ew_image ov = ew_image_packed(o, W, H, 3);
    if (r == EW_OK) r = ew_op_set_image(op, "output", &ov);
    if (r == EW_OK) r = ew_op_commit(op);
    if (r == EW_OK) r = ew_op_execute(op);
    if (r == EW_OK && dev->device_images) memcpy(out, back(dev, o, N * 3), N * 3 * sizeof(float));
    return r;
}

/* The temporal filter's history stays in device memory across frames:
 * four frames with motion, rejection and the history clamp agree with the
 * CPU device, with host and with device views. */
TEST(temporal_filter_sequence_on_device_memory) {
    for (int device_images = 0; device_images <= 1; device_images++) {
        OPEN_PAIR(p, device_images);
        ew_op *a = NULL, *b = NULL;
        CHECK_EQ_INT(ew_op_create_kind(p.cpu, "filter", "temporal", &a), EW_OK);
        CHECK_EQ_INT(ew_op_create_kind(p.dut, "filter", "temporal", &b), EW_OK);
        ew_op_set_param(a, "clamp", 1.5f, 0);
        ew_op_set_param(b, "clamp", 1.5f, 0);
        int ok = 1;
        /* one surface (normals, depth within the tolerance) seen in every
         * frame, so most history is kept; the colour and motion change */
        float *normal = hrand(N * 3, 0.5f, 1.0f, 0), *depth = hrand(N, 1.0f, 1.05f, 0);
        for (int f = 0; f < 4 && ok; f++) {
            float *in[4] = {hrand(N * 3, 0.0f, 2.0f, 59), normal, depth, hrand(N * 2, -1.5f, 1.5f, 83)};
            float *oa = hnan(N * 3), *ob = hnan(N * 3);
            const ew_result ra = temporal_frame(p.cpu, a, in, oa), rb = temporal_frame(p.dut, b, in, ob);
            if (ra != EW_OK || rb != EW_OK)
                fprintf(stderr, "  frame %d: cpu %s, device under test %s (%s)\n", f, ew_result_string(ra),
                        ew_result_string(rb), ew_device_last_error(p.dut));
            ok = ra == EW_OK && rb == EW_OK && match(ob, oa, N * 3, "temporal frame");
        }
        ew_op_destroy(a);
        ew_op_destroy(b);
        close_pair(&p);
        if (!ok) fprintf(stderr, "  (device images %d)\n", device_images);
        CHECK(ok);
        CHECK_NO_MISUSE();
    }
}

/* A model of each range kind, with attributes to match. */
static ew_bf_model bf_model(int kind, float **attr) {
    ew_bf_model m;
    memset(&m, 0, sizeof m);
    m.kind = kind;
    m.channels = 3; /* meaningful channels; buffers hold EW_BF_CH */
    m.radius = 6;
    m.sigma = 2.0f;
    switch (kind) {
    case EW_RANGE_COLOR:
        m.inv_2sr2 = 1.0f / (2.0f * 0.2f * 0.2f);
        *attr = hrand(N * (size_t)ew_bf_attrs(kind), 0.0f, 1.0f, 0);
        break;
    case EW_RANGE_GI: {
        m.sigma_alpha = 6.0f;
        m.sigma_n = 32.0f;
        m.sigma_z = 1.0f;
        m.use_roughness = 1;
        float *a = hrand(N * (size_t)ew_bf_attrs(kind), 0.0f, 1.0f, 0);
        for (size_t i = 0; i < N; i++) {
            float *v = a + i * (size_t)ew_bf_attrs(kind);
            float nx = rnd_in(-1, 1), ny = rnd_in(-1, 1), nz = rnd_in(0.1f, 1), l = sqrtf(nx * nx + ny * ny + nz * nz);
            const int sky = i % 23 == 0;
            v[0] = sky ? 0.0f : nx / l;
            v[1] = sky ? 0.0f : ny / l;
            v[2] = sky ? 0.0f : nz / l;
            v[3] = rnd_in(1.0f, 5.0f);
        }
        *attr = a;
        break;
    }
    case EW_RANGE_DEPTH:
        m.sigma_z = 1.0f;
        *attr = hrand(N, 1.0f, 5.0f, 0);
        break;
    case EW_RANGE_DOF: {
        m.sigma = 0.0f;
        m.radius = 8;
        float *a = hrand(N * 2, 0.0f, 10.0f, 0);
        for (size_t i = 0; i < N; i++) a[i * 2] = a[i * 2 + 1] + rnd_in(0.0f, 3.0f);
        *attr = a;
        break;
    }
    default:
        m.sigma = 1.5f;
        *attr = hrand(1, 0.0f, 1.0f, 0);
        break;
    }
    m.attrs = ew_bf_attrs(kind);
    return m;
}

TEST(bilateral_brute_and_separable_every_model) {
    for (int kind = EW_RANGE_COLOR; kind <= EW_RANGE_NONE; kind++) {
        OPEN_PAIR(p, 0);
        float *attr = NULL;
        const ew_bf_model m = bf_model(kind, &attr);
        const size_t na = m.attrs ? N * (size_t)m.attrs : 1;
        float *image = hrand_px(N, EW_BF_CH, 0.0f, 1.0f, 31);
        ew_bf_buffers h = {W, H, image, attr, hnan(N * EW_BF_CH), 3, H - 2}; /* a band, as the algorithm does */
        ew_bf_buffers d = {W, H, dup_to(p.dut, image, N * EW_BF_CH), dup_to(p.dut, attr, na), dnan(p.dut, N * EW_BF_CH), 3, H - 2};
        ew_cpu_backend.bf_brute(p.cpu, &m, &h);
        p.dut->backend->bf_brute(p.dut, &m, &d);
        int ok = match(back(p.dut, d.out, N * EW_BF_CH), h.out, N * EW_BF_CH, "brute force");
        for (int axis = 0; axis <= 1 && ok; axis++) {
            ew_cpu_backend.bf_separable(p.cpu, &m, axis, &h);
            p.dut->backend->bf_separable(p.dut, &m, axis, &d);
            ok = match(back(p.dut, d.out, N * EW_BF_CH), h.out, N * EW_BF_CH, axis ? "separable y" : "separable x");
        }
        close_pair(&p);
        if (!ok) fprintf(stderr, "  (range kind %d)\n", kind);
        CHECK(ok);
        CHECK_NO_MISUSE();
    }
}

TEST(pyramid_down_and_up_rows_and_table) {
    const int kinds[] = {EW_RANGE_COLOR, EW_RANGE_GI, EW_RANGE_DOF};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        OPEN_PAIR(p, 0);
        float *attr = NULL;
        const ew_bf_model m = bf_model(kinds[k], &attr);
        const int A = m.attrs, cw = (W + 1) / 2, ch = (H + 1) / 2;
        const size_t nc = (size_t)cw * ch;
        float *down = hrand_px(N, EW_BF_CH, 0.0f, 1.0f, 47);
        /* planes; the coarse attributes also duplicated (kernels/pyramid.h) */
        ew_pyr_down_args hd = {&m, W, H, cw, ch, down, attr, hnan(nc * EW_BF_CH), hnan(nc * (size_t)A), 4.0f,
                               kinds[k] == EW_RANGE_GI, hnan(2 * nc * (size_t)A), NULL, NULL, NULL, 0, 0, NULL, 0};
        ew_pyr_down_args dd = hd;
        dd.down = dup_to(p.dut, down, N * EW_BF_CH);
        dd.attr = dup_to(p.dut, attr, N * (size_t)A);
        dd.cdown = dnan(p.dut, nc * EW_BF_CH);
        dd.cattr = dnan(p.dut, nc * (size_t)A);
        dd.cattr2 = dnan(p.dut, 2 * nc * (size_t)A);
        ew_cpu_backend.pyr_down(p.cpu, &hd);
        p.dut->backend->pyr_down(p.dut, &dd);
        int ok = match(back(p.dut, dd.cdown, nc * EW_BF_CH), hd.cdown, nc * EW_BF_CH, "coarse values") &&
                 match(back(p.dut, dd.cattr, nc * (size_t)A), hd.cattr, nc * (size_t)A, "coarse attributes") &&
                 match(back(p.dut, dd.cattr2, 2 * nc * (size_t)A), hd.cattr2, 2 * nc * (size_t)A,
                       "duplicated coarse attributes");

        /* up: one row of weights (uniform sigma), then the table over sigma */
        ew_pyr_params prm;
        ew_pyr_analytic(2.0f, 0, 1.0f, &prm);
        ew_pyr_wrow row;
        ew_pyr_expand(&prm, &row);
        const size_t row_floats = sizeof(ew_pyr_wrow) / sizeof(float);
        ew_pyr_wrow *lut = (ew_pyr_wrow *)(void *)hnan((size_t)EW_PYR_LUT_N * row_floats);
        for (int i = 0; i < EW_PYR_LUT_N; i++) {
            ew_pyr_analytic(exp2f((float)EW_PYR_LUT_LOG2_MIN + (float)i / EW_PYR_LUT_STEPS), 0, 0.5f, &prm);
            ew_pyr_expand(&prm, &lut[i]);
        }
        float *cup = hrand_px(2 * nc, EW_BF_CH, 0.0f, 1.0f, 89); /* duplicated coarse planes: */
        for (size_t i = 0; i + 1 < 2 * nc * EW_BF_CH; i += 2) cup[i + 1] = cup[i]; /* columns 2x, 2x+1 equal */
        ew_pyr_up_args hu = {&m, W, H, cw, ch, down, attr, cup, hd.cattr2, hnan(N * EW_BF_CH), 1.0f, 0.75f, &row, NULL, NULL, NULL, 0,
                             NULL, NULL, 0, 0, 0, 0, 0, 0, NULL, NULL, NULL, 0, 0, NULL,
                             0, 0, NULL, NULL, NULL, 0};
        ew_pyr_up_args du = hu;
        du.down = dd.down;
        du.attr = dd.attr;
        du.cup = dup_to(p.dut, cup, 2 * nc * EW_BF_CH);
        du.cattr = dup_to(p.dut, hd.cattr2, 2 * nc * (size_t)A);
        du.up = dnan(p.dut, N * EW_BF_CH);
        for (int table = 0; table <= 1 && ok; table++) {
            if (table) {
                hu.row = du.row = NULL;
                hu.lut = lut;
                du.lut = (const ew_pyr_wrow *)(const void *)dup_to(p.dut, (const float *)(const void *)lut,
                                                                   (size_t)EW_PYR_LUT_N * row_floats);
            }
            ew_cpu_backend.pyr_up(p.cpu, &hu);
            p.dut->backend->pyr_up(p.dut, &du);
            ok = match(back(p.dut, du.up, N * EW_BF_CH), hu.up, N * EW_BF_CH, table ? "up (table)" : "up (row)");
        }
        close_pair(&p);
        if (!ok) fprintf(stderr, "  (range kind %d)\n", kinds[k]);
        CHECK(ok);
        CHECK_NO_MISUSE();
    }
}

TEST(atrous_pass) {
    OPEN_PAIR(p, 0);
    ew_atrous_args h, d;
    h.w = W;
    h.h = H;
    h.channels = 3;
    h.step = 2;
    h.in = hrand_px(N, EW_BF_CH, 0.0f, 1.0f, 33);
    h.out = hnan(N * EW_BF_CH);
    h.normal = hrand(N * EW_BF_CH, -1.0f, 1.0f, 0);
    h.depth = hrand(N, 1.0f, 2.0f, 0);
    h.sigma_l = 0.5f;
    h.sigma_n = 0.3f;
    h.sigma_z = 0.2f;
    d = h;
    d.in = dup_to(p.dut, h.in, N * EW_BF_CH);
    d.out = dnan(p.dut, N * EW_BF_CH);
    d.normal = dup_to(p.dut, h.normal, N * EW_BF_CH);
    d.depth = dup_to(p.dut, h.depth, N);
    (void)EW_RUN(p.cpu, atrous, &h);
    (void)EW_RUN(p.dut, atrous, &d);
    const int ok = match(back(p.dut, d.out, N * EW_BF_CH), h.out, N * EW_BF_CH, "a-trous");
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(dof_attributes) {
    OPEN_PAIR(p, 0);
    ew_dof_args h, d;
    memset(&h, 0, sizeof h);
    h.cam.focal_mm = 50.0f;
    h.cam.fstop = 1.4f;
    h.cam.focus_m = 3.0f;
    h.cam.sensor_mm = 36.0f;
    h.cam.width = W;
    h.cam.height = H;
    h.cam.max_coc = 24.0f;
    h.tw = (W + EW_DOF_TILE - 1) / EW_DOF_TILE;
    h.th = (H + EW_DOF_TILE - 1) / EW_DOF_TILE;
    const size_t nt = (size_t)h.tw * h.th;
    float *depth = hrand(N, 0.3f, 12.0f, 19);
    depth[3] = 0.0f;
    depth[4] = 1e10f;
    h.depth = depth;
    h.coc = hnan(N);
    h.tiles = hnan(nt);
    h.tiles2 = hnan(nt);
    h.attr = hnan(N * 2);
    d = h;
    d.depth = dup_to(p.dut, depth, N);
    d.coc = dnan(p.dut, N);
    d.tiles = dnan(p.dut, nt);
    d.tiles2 = dnan(p.dut, nt);
    d.attr = dnan(p.dut, N * 2);
    ew_cpu_backend.dof_attributes(p.cpu, &h);
    p.dut->backend->dof_attributes(p.dut, &d);
    const int ok = match(back(p.dut, d.coc, N), h.coc, N, "CoC") && match(back(p.dut, d.tiles, nt), h.tiles, nt, "tiles") &&
                   match(back(p.dut, d.attr, N * 2), h.attr, N * 2, "(D, C)");
    /* and as planes */
    h.planes = d.planes = 1;
    ew_cpu_backend.dof_attributes(p.cpu, &h);
    p.dut->backend->dof_attributes(p.dut, &d);
    const int okp = match(back(p.dut, d.attr, N * 2), h.attr, N * 2, "(D, C) planes");
    close_pair(&p);
    CHECK(okp);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(guidenet_conv5) {
    /* small channel counts (the CPU's SIMD weights on its stack) and large
     * ones (allocated); with and without accumulation. Planes laid out as
     * GuideNet lays them out (zero borders, room for whole-vector reads). */
    const int shapes[][2] = {{4, 3}, {10, 16}, {24, 24}};
    for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; s++)
        for (int accumulate = 0; accumulate <= 1; accumulate++) {
            OPEN_PAIR(p, 0);
            const int cin = shapes[s][0], cout = shapes[s][1], rows = 11;
            const size_t nin = ew_gn_planes_floats(W, rows, cin), nout = ew_gn_planes_floats(W, rows, cout);
            float *in_mem = hrand(nin, 0.0f, 1.0f, 0), *out_mem = hrand(nout, 0.0f, 1.0f, 0);
            ew_gn_planes in, out;
            ew_gn_planes_init(&in, in_mem, W, rows, cin);
            ew_gn_planes_init(&out, out_mem, W, rows, cout);
            for (int c = 0; c < cin; c++)
                for (int r = 0; r < rows; r++)
                    for (int x = 0; x < W; x++) ew_gn_plane_row(&in, c, r)[x] = rnd_in(-1.0f, 1.0f);
            for (int c = 0; c < cout; c++)
                for (int r = 0; r < rows; r++)
                    for (int x = 0; x < W; x++) ew_gn_plane_row(&out, c, r)[x] = rnd_in(-1.0f, 1.0f);
            ew_conv_args h;
            memset(&h, 0, sizeof h);
            h.width = W;
            h.rows = rows;
            h.cin = cin;
            h.cout = cout;
            h.in = in.data;
            h.in_rs = in.rs;
            h.in_ps = in.ps;
            h.out = out.data;
            h.out_rs = out.rs;
            h.out_ps = out.ps;
            h.weight = hrand((size_t)cout * cin * 25, -0.2f, 0.2f, 0);
            h.bias = accumulate ? NULL : hrand((size_t)cout, -0.5f, 0.5f, 0);
            h.act = EW_ACT_LEAKY;
            h.accumulate = accumulate;
            ew_conv_args d = h;
            float *din = dup_to(p.dut, in_mem, nin), *dout = dup_to(p.dut, out_mem, nout);
            d.in = din + (in.data - in_mem);
            d.out = dout + (out.data - out_mem);
            d.weight = dup_to(p.dut, h.weight, (size_t)cout * cin * 25);
            d.bias = h.bias ? dup_to(p.dut, h.bias, (size_t)cout) : NULL;
            ew_cpu_backend.conv5(p.cpu, &h);
            p.dut->backend->conv5(p.dut, &d);
            const float *got = back(p.dut, dout, nout);
            int ok = 1;
            for (int c = 0; c < cout && ok; c++)
                for (int r = 0; r < rows && ok; r++) {
                    const size_t off = (size_t)(ew_gn_plane_row(&out, c, r) - out_mem);
                    /* the CPU sums the 25 * cin products in another order:
                     * the rounding difference grows with their count */
                    ok = match_tol(got + off, out_mem + off, W, 1e-8f * 25.0f * (float)cin, "conv5");
                }
            close_pair(&p);
            if (!ok) fprintf(stderr, "  (cin %d, cout %d, accumulate %d)\n", cin, cout, accumulate);
            CHECK(ok);
            CHECK_NO_MISUSE();
        }
}

TEST(guidenet_input_guides_blend) {
    OPEN_PAIR(p, 0);
    const int y0 = 2, y1 = H - 3;
    const long rs = W, ps = (long)(y1 - y0) * W;
    ew_gn_input_args h;
    h.width = W;
    h.y0 = y0;
    h.y1 = y1;
    h.color = hrand(N * 3, 0.0f, 2.0f, 23);
    h.albedo = hrand(N * 3, 0.0f, 1.0f, 79);
    h.normal = hrand(N * 3, -1.0f, 1.0f, 0);
    h.depth = hrand(N, 0.0f, 10.0f, 0);
    h.depth_scale = 0.1f;
    h.in_stride = 0;
    h.dst = hnan((size_t)(ps * EW_GN_INPUTS));
    h.rs = rs;
    h.ps = ps;
    ew_gn_input_args d = h;
    d.color = dup_to(p.dut, h.color, N * 3);
    d.albedo = dup_to(p.dut, h.albedo, N * 3);
    d.normal = dup_to(p.dut, h.normal, N * 3);
    d.depth = dup_to(p.dut, h.depth, N);
    d.dst = dnan(p.dut, (size_t)(ps * EW_GN_INPUTS));
    ew_cpu_backend.gn_input(p.cpu, &h);
    p.dut->backend->gn_input(p.dut, &d);
    int ok = match(back(p.dut, d.dst, (size_t)(ps * EW_GN_INPUTS)), h.dst, (size_t)(ps * EW_GN_INPUTS), "inputs");

    /* a region of the frame, columns [3, W - 2), read where it lies: as
     * from the whole frame's planes, on both devices */
    ew_gn_input_args hr = h, dr = d;
    const int x0 = 3, rw = W - 5;
    hr.width = dr.width = rw;
    hr.in_stride = dr.in_stride = W;
    hr.color += x0 * 3, hr.albedo += x0 * 3, hr.normal += x0 * 3, hr.depth += x0;
    dr.color += x0 * 3, dr.albedo += x0 * 3, dr.normal += x0 * 3, dr.depth += x0;
    hr.dst = hnan((size_t)(ps * EW_GN_INPUTS));
    dr.dst = dnan(p.dut, (size_t)(ps * EW_GN_INPUTS));
    ew_cpu_backend.gn_input(p.cpu, &hr);
    p.dut->backend->gn_input(p.dut, &dr);
    ok = ok && match(back(p.dut, dr.dst, (size_t)(ps * EW_GN_INPUTS)), hr.dst, (size_t)(ps * EW_GN_INPUTS),
                     "a region's inputs");
    for (long c = 0; ok && c < EW_GN_INPUTS; c++)
        for (int y = 0; ok && y < y1 - y0; y++)
            ok = same(hr.dst + c * ps + (long)y * rs, h.dst + c * ps + (long)y * rs + x0, (size_t)rw,
                      "a region's inputs against the frame's");

    float *outputs = hrand(N * 5, 0.0f, 1.0f, 0), *doutputs = dup_to(p.dut, outputs, N * 5);
    ew_cpu_backend.nbg_guides(p.cpu, (long)N, 3, outputs);
    p.dut->backend->nbg_guides(p.dut, (long)N, 3, doutputs);
    ok = ok && match(back(p.dut, doutputs, N * 5), outputs, N * 5, "guides");

    float *acc = hnan(N * 3), *dacc = dnan(p.dut, N * 3);
    for (int s = 0; s < 3 && ok; s++) {
        float *sliced = hrand(N * 3, 0.0f, 2.0f, 0);
        ew_nbg_blend_args hb = {(long)N, s, 3, outputs, sliced, acc};
        ew_nbg_blend_args db = {(long)N, s, 3, doutputs, dup_to(p.dut, sliced, N * 3), dacc};
        ew_cpu_backend.nbg_blend(p.cpu, &hb);
        p.dut->backend->nbg_blend(p.dut, &db);
        ok = match(back(p.dut, dacc, N * 3), acc, N * 3, "blend");
    }
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(kpcn_input_pool_up_filter) {
    OPEN_PAIR(p, 0);
    const int cw = ew_kpcn_half(W), ch = ew_kpcn_half(H);
    const size_t NC = (size_t)cw * ch;
    ew_kpcn_input_args h;
    memset(&h, 0, sizeof h);
    h.noise_plane = 1; /* the "-noise" models' 11th plane too */
    h.noise = 0.375f;
    h.width = W;
    h.height = H;
    h.src_rs = W;
    h.radiance = hrand(N * 3, 0.0f, 4.0f, 23);
    h.albedo = hrand(N * 3, 0.0f, 1.0f, 79);
    h.normal = hrand(N * 3, -1.0f, 1.0f, 0);
    h.depth = hrand(N, 0.0f, 10.0f, 0);
    h.depth_scale = 0.1f;
    h.dst = hnan(N * EW_KPCN_MAX_INPUTS);
    h.rs = W;
    h.ps = (long)N;
    ew_kpcn_input_args d = h;
    d.radiance = dup_to(p.dut, h.radiance, N * 3);
    d.albedo = dup_to(p.dut, h.albedo, N * 3);
    d.normal = dup_to(p.dut, h.normal, N * 3);
    d.depth = dup_to(p.dut, h.depth, N);
    d.dst = dnan(p.dut, N * EW_KPCN_MAX_INPUTS);
    (void)EW_RUN(p.cpu, kpcn_input, &h);
    (void)EW_RUN(p.dut, kpcn_input, &d);
    int ok = match(back(p.dut, d.dst, N * EW_KPCN_MAX_INPUTS), h.dst, N * EW_KPCN_MAX_INPUTS, "kpcn inputs");

    /* pooling packed RGB (odd sizes: partial blocks) into planes */
    float *rad = hrand(N * 3, 0.0f, 3.0f, 0), *drad = dup_to(p.dut, rad, N * 3);
    float *pooled = hnan(NC * 3), *dpooled = dnan(p.dut, NC * 3);
    ew_kpcn_pool_args hp = {W, H, cw, ch, 3, {rad, 3, 3L * W, 1}, {pooled, 1, cw, (long)NC}};
    ew_kpcn_pool_args dp = {W, H, cw, ch, 3, {drad, 3, 3L * W, 1}, {dpooled, 1, cw, (long)NC}};
    (void)EW_RUN(p.cpu, kpcn_pool, &hp);
    (void)EW_RUN(p.dut, kpcn_pool, &dp);
    ok = ok && match(back(p.dut, dpooled, NC * 3), pooled, NC * 3, "kpcn pool");

    float *upd = hnan(N * 3), *dupd = dnan(p.dut, N * 3);
    ew_kpcn_up_args hu = {W, H, cw, ch, 3, {pooled, 1, cw, (long)NC}, {upd, 1, W, (long)N}, 0};
    ew_kpcn_up_args du = {W, H, cw, ch, 3, {dpooled, 1, cw, (long)NC}, {dupd, 1, W, (long)N}, 0};
    (void)EW_RUN(p.cpu, kpcn_up, &hu);
    (void)EW_RUN(p.dut, kpcn_up, &du);
    ok = ok && match(back(p.dut, dupd, N * 3), upd, N * 3, "kpcn up");
    /* ... and pooled back from those planes (the network's planar layout) */
    float *pp = hnan(NC * 3), *dpp = dnan(p.dut, NC * 3);
    ew_kpcn_pool_args hq = {W, H, cw, ch, 3, {upd, 1, W, (long)N}, {pp, 1, cw, (long)NC}};
    ew_kpcn_pool_args dq = {W, H, cw, ch, 3, {dupd, 1, W, (long)N}, {dpp, 1, cw, (long)NC}};
    (void)EW_RUN(p.cpu, kpcn_pool, &hq);
    (void)EW_RUN(p.dut, kpcn_pool, &dq);
    ok = ok && match(back(p.dut, dpp, NC * 3), pp, NC * 3, "kpcn pool of planes");

    /* the filter with and without a coarser scale, into packed RGB; then
     * remodulating by its albedo kernel (variant 2) */
    for (int variant = 0; variant <= 2 && ok; variant++) {
        const int with_coarse = variant >= 1, nl = variant == 2 ? EW_KPCN_HEAD_REMOD : EW_KPCN_HEAD;
        float *logits = hrand(N * nl, -3.0f, 3.0f, 0), *dlogits = dup_to(p.dut, logits, N * nl);
        float *out = hnan(N * 3), *dout = dnan(p.dut, N * 3);
        ew_kpcn_filter_args hf, df;
        memset(&hf, 0, sizeof hf);
        hf.width = W;
        hf.height = H;
        hf.logits.data = logits;
        hf.logits.xs = 1;
        hf.logits.rs = W;
        hf.logits.cs = (long)N;
        hf.radiance.data = rad;
        hf.radiance.xs = 3;
        hf.radiance.rs = 3L * W;
        hf.radiance.cs = 1;
        if (with_coarse) {
            hf.coarse.data = pooled;
            hf.coarse.xs = 1;
            hf.coarse.rs = cw;
            hf.coarse.cs = (long)NC;
            hf.cw = cw;
            hf.ch = ch;
        }
        hf.out.data = out;
        hf.out.xs = 3;
        hf.out.rs = 3L * W;
        hf.out.cs = 1;
        if (variant == 2) {
            hf.albedo.data = rad; /* any positive 3-channel image */
            hf.albedo.xs = 3;
            hf.albedo.rs = 3L * W;
            hf.albedo.cs = 1;
        }
        df = hf;
        df.logits.data = dlogits;
        df.albedo.data = variant == 2 ? drad : NULL;
        df.radiance.data = drad;
        df.coarse.data = with_coarse ? dpooled : NULL;
        df.out.data = dout;
        (void)EW_RUN(p.cpu, kpcn_filter, &hf);
        (void)EW_RUN(p.dut, kpcn_filter, &df);
        ok = match(back(p.dut, dout, N * 3), out, N * 3, "kpcn filter");
        /* a band of rows (the op's full-resolution scale runs so): the
         * logits of the band only, taps reaching past it into the plane,
         * the same pixels as the whole plane's */
        const int y0 = 3, rows = H - 5;
        float *bout = hnan(N * 3), *dbout = dnan(p.dut, N * 3);
        ew_kpcn_filter_args hb = hf, db = df;
        hb.height = db.height = rows;
        hb.y0 = db.y0 = y0;
        hb.frame_h = db.frame_h = H;
        hb.logits.data = logits + (long)y0 * W;
        db.logits.data = dlogits + (long)y0 * W;
        hb.out.data = bout;
        db.out.data = dbout;
        (void)EW_RUN(p.cpu, kpcn_filter, &hb);
        (void)EW_RUN(p.dut, kpcn_filter, &db);
        ok = ok && match(back(p.dut, dbout, N * 3), bout, N * 3, "kpcn filter, a band");
        ok = ok && same(bout + (size_t)y0 * W * 3, out + (size_t)y0 * W * 3, (size_t)rows * W * 3,
                        "kpcn filter, a band against the whole plane");
    }
    /* the upsampling of a band of fine rows (from an even and an odd row) */
    for (int y0 = 2; y0 <= 3 && ok; y0++) {
        const int rows = H - y0 - 1;
        float *bup = hnan(N * 3), *dbup = dnan(p.dut, N * 3);
        ew_kpcn_up_args hb = hu, db = du;
        hb.fh = db.fh = rows;
        hb.y0 = db.y0 = y0;
        hb.dst.data = bup;
        db.dst.data = dbup;
        (void)EW_RUN(p.cpu, kpcn_up, &hb);
        (void)EW_RUN(p.dut, kpcn_up, &db);
        ok = ok && match(back(p.dut, dbup, N * 3), bup, N * 3, "kpcn up, a band");
        for (int c = 0; c < 3 && ok; c++)
            ok = same(bup + (size_t)c * N, upd + (size_t)c * N + (size_t)y0 * W, (size_t)rows * W,
                      "kpcn up, a band against the whole plane");
    }
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

/* kpcn's passes: in-place mirrors along each axis (odd sizes: a middle
 * column and row that stay), then the gathers back in every mode. */
TEST(mirror_swap_and_add) {
    OPEN_PAIR(p, 0);
    int ok = 1;
    for (int axis = 0; axis < 2 && ok; axis++) {
        float *h = hrand(N * 3, 0.0f, 2.0f, 31 + axis), *d = dup_to(p.dut, h, N * 3);
        ew_mirror_swap_args hs;
        memset(&hs, 0, sizeof hs);
        hs.p = h;
        hs.channels = 3;
        hs.width = W;
        hs.height = H;
        hs.axis = axis;
        hs.dw = axis == 0 ? W / 2 : W;
        hs.dh = axis == 0 ? H : H / 2;
        ew_mirror_swap_args ds = hs;
        ds.p = d;
        (void)EW_RUN(p.cpu, mirror_swap, &hs);
        (void)EW_RUN(p.dut, mirror_swap, &ds);
        ok = match(back(p.dut, d, N * 3), h, N * 3, "mirror swap");
    }
    float *out = hrand(N * 3, 0.0f, 2.0f, 5), *dout = dup_to(p.dut, out, N * 3);
    float *acc = hnan(N * 3), *dacc = dnan(p.dut, N * 3);
    static const int modes[3][3] = {{1, 0, EW_MIRROR_FIRST}, {1, 1, EW_MIRROR_MORE}, {0, 0, EW_MIRROR_LAST}};
    for (int i = 0; i < 3 && ok; i++) {
        ew_mirror_add_args ha;
        memset(&ha, 0, sizeof ha);
        ha.out = out;
        ha.acc = acc;
        ha.width = W;
        ha.height = H;
        ha.mx = modes[i][0];
        ha.my = modes[i][1];
        ha.mode = modes[i][2];
        ha.scale = 1.0f / 3.0f;
        ew_mirror_add_args da = ha;
        da.out = dout;
        da.acc = dacc;
        (void)EW_RUN(p.cpu, mirror_add, &ha);
        (void)EW_RUN(p.dut, mirror_add, &da);
        ok = match(back(p.dut, dacc, N * 3), acc, N * 3, "mirror add (sum)") &&
             match(back(p.dut, dout, N * 3), out, N * 3, "mirror add (output)");
    }
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

TEST(reduce_rows_both_kinds) {
    OPEN_PAIR(p, 0);
    float *rgb = hrand(N * 3, -0.5f, 3.0f, 13), *depth = hrand(N, 0.0f, 50.0f, 17);
    depth[40] = 1e10f;
    const size_t nd = (size_t)H * 2;
    double *h = (double *)(void *)hnan(nd * 2);
    double *d = (double *)(void *)dnan(p.dut, nd * 2);
    ew_cpu_backend.reduce_rows(p.cpu, EW_REDUCE_LUM_SUM, W, H, rgb, h);
    p.dut->backend->reduce_rows(p.dut, EW_REDUCE_LUM_SUM, W, H, dup_to(p.dut, rgb, N * 3), d);
    int ok = match_doubles(back(p.dut, (float *)(void *)d, nd * 2), h, nd, "luminance row sums");
    ew_cpu_backend.reduce_rows(p.cpu, EW_REDUCE_DEPTH_MAX, W, H, depth, h);
    p.dut->backend->reduce_rows(p.dut, EW_REDUCE_DEPTH_MAX, W, H, dup_to(p.dut, depth, N), d);
    ok = ok && match_doubles(back(p.dut, (float *)(void *)d, nd * 2), h, nd, "depth row maxima");
    double mx = 0.0;
    for (int y = 0; y < H; y++) mx = h[2 * y] > mx ? h[2 * y] : mx;
    ew_cpu_backend.reduce_rows(p.cpu, EW_REDUCE_NOISE, W, H, rgb, h);
    p.dut->backend->reduce_rows(p.dut, EW_REDUCE_NOISE, W, H, dup_to(p.dut, rgb, N * 3), d);
    ok = ok && match_doubles(back(p.dut, (float *)(void *)d, nd * 2), h, nd, "noise row sums");
    const int noise_row_zero_empty = h[0] == 0.0 && h[1] == 0.0 && h[3] > 0.0 && h[3] <= (double)(W - 1);
    close_pair(&p);
    CHECK(ok);
    CHECK(mx < 1e9 && mx > 40.0); /* the background depth is left out */
    CHECK(noise_row_zero_empty);  /* HH of rows y - 1, y: row 0 has none, row 1 up to W - 1 blocks */
    CHECK_NO_MISUSE();
}

TEST(view_pack_unpack_strided_bottom_up) {
    OPEN_PAIR(p, 1);
    /* 5 floats a pixel, 3 spare floats a row, rows stored bottom-up */
    const long row_floats = W * 5 + 3;
    const size_t total = (size_t)(row_floats * H);
    float *buf = hrand(total, 0.0f, 1.0f, 0), *dbuf = dup_to(p.dut, buf, total);
    ew_view_desc hv = {(char *)(buf + row_floats * (H - 1)), W, H, 5 * 4, -row_floats * 4, 0};
    ew_view_desc dv = hv;
    dv.data = (char *)(dbuf + row_floats * (H - 1));
    float *packed = hnan(N * 3), *dpacked = dnan(p.dut, N * 3);
    ew_cpu_backend.view_pack(p.cpu, &hv, 3, packed);
    p.dut->backend->view_pack(p.dut, &dv, 3, dpacked);
    int ok = match(back(p.dut, dpacked, N * 3), packed, N * 3, "packed");
    CHECK(packed[0] == buf[row_floats * (H - 1)]); /* pixel (0, 0) is the last stored row */
    float *src = hrand(N * 3, 0.0f, 1.0f, 0);
    ew_cpu_backend.view_unpack(p.cpu, src, 3, &hv);
    p.dut->backend->view_unpack(p.dut, dup_to(p.dut, src, N * 3), 3, &dv);
    ok = ok && match(back(p.dut, dbuf, total), buf, total, "unpacked view (spare floats untouched)");
    /* the same bytes as halves, 10 a pixel: every finite half there is */
    unsigned short *hb = (unsigned short *)(void *)buf;
    for (size_t i = 0; i < total * 2; i++) hb[i] = (unsigned short)((i * 7919u) % 0x7c00u | (i & 1u) << 15);
    ew_view_desc hh = {(char *)(buf + row_floats * (H - 1)), W, H, 5 * 4, -row_floats * 4, 1};
    ew_view_desc dh = hh;
    dh.data = (char *)(dup_to(p.dut, buf, total) + row_floats * (H - 1));
    ew_cpu_backend.view_pack(p.cpu, &hh, 3, packed);
    p.dut->backend->view_pack(p.dut, &dh, 3, dpacked);
    ok = ok && match(back(p.dut, dpacked, N * 3), packed, N * 3, "packed halves");
    CHECK(packed[0] == ew_half_to_float(hb[(row_floats * (H - 1)) * 2]));
    close_pair(&p);
    CHECK(ok);
    CHECK_NO_MISUSE();
}

/* ---- whole denoisers through the device-memory path ---------------------- */
typedef struct {
    float *color, *albedo4, *normal, *depth; /* albedo with 4 floats a pixel: a strided view */
} scene;

static scene make_scene(void) {
    scene s;
    s.color = hrand(N * 3, 0.0f, 1.0f, 0);
    for (size_t i = 11; i < N * 3; i += 131) s.color[i] = 80.0f; /* fireflies */
    s.color[20] = NAN;
    s.color[50] = INFINITY;
    s.albedo4 = hrand(N * 4, 0.1f, 0.9f, 0);
    s.normal = hrand(N * 3, -1.0f, 1.0f, 0);
    s.depth = hrand(N, 1.0f, 4.0f, 0);
    for (size_t i = 0; i < N; i += 17) s.depth[i] = 1e10f; /* background */
    return s;
}

/* Run "bgrid" with the scene's views on dev; out: N*3 floats. For a
 * device_images device the views point at device copies. */
static ew_result run_bgrid(ew_device *dev, const scene *s, int features, float color_weight, float *out) {
    const int on_dev = dev->device_images;
    float *color = on_dev ? dup_to(dev, s->color, N * 3) : hcopy(s->color, N * 3);
    float *alb = on_dev ? dup_to(dev, s->albedo4, N * 4) : s->albedo4;
    float *nrm = on_dev ? dup_to(dev, s->normal, N * 3) : s->normal;
    float *dep = on_dev ? dup_to(dev, s->depth, N) : s->depth;
    ew_image vc = ew_image_packed(color, W, H, 3), va = ew_image_packed(alb, W, H, 3);
    va.pixel_stride = 4 * sizeof(float);
    va.row_stride = 4 * sizeof(float) * W;
    ew_image vn = ew_image_packed(nrm, W, H, 3), vd = ew_image_packed(dep, W, H, 1);
    ew_denoiser *d = NULL;
    ew_result r = ew_denoiser_create(dev, "bgrid", &d);
    if (r != EW_OK) return r;
    ew_denoiser_set_image(d, "color", &vc);
    ew_denoiser_set_image(d, "output", &vc); /* in place */
    if (features) {
        ew_denoiser_set_image(d, "albedo", &va);
        ew_denoiser_set_image(d, "normal", &vn);
        ew_denoiser_set_image(d, "depth", &vd);
    }
    ew_denoiser_set_float(d, "spatial_rate", 5.0f);
    ew_denoiser_set_float(d, "color_weight", color_weight);
    r = ew_denoiser_commit(d);
    /* twice: buffers are reused across frames */
    for (int frame = 0; frame < 2 && r == EW_OK; frame++) {
        r = ew_denoiser_execute(d);
        /* read the output, then put the input back for the next frame */
        if (r == EW_OK && on_dev) {
            float *h = back(dev, color, N * 3);
            memcpy(out, h, N * 3 * sizeof(float));
            dev->backend->mem_upload(dev, color, s->color, N * 3 * sizeof(float));
        } else if (r == EW_OK) {
            memcpy(out, color, N * 3 * sizeof(float));
            memcpy(color, s->color, N * 3 * sizeof(float));
        }
    }
    ew_denoiser_destroy(d);
    return r;
}

TEST(bgrid_denoiser_matches_cpu_through_device_memory) {
    const float weights[] = {0.0f, 0.7f};
    for (int features = 0; features <= 1; features++)
        for (int w = 0; w < 2; w++)
            for (int device_images = 0; device_images <= 1; device_images++) {
                OPEN_PAIR(p, device_images);
                const int blocks_before = dut_live_blocks();
                scene s = make_scene();
                float *a = hnan(N * 3), *b = hnan(N * 3);
                ew_result ra = run_bgrid(p.cpu, &s, features, weights[w], a);
                ew_result rb = run_bgrid(p.dut, &s, features, weights[w], b);
                CHECK_EQ_INT(ra, EW_OK);
                CHECK_EQ_INT(rb, EW_OK);
                int ok = match(b, a, N * 3, "denoised");
                for (size_t i = 0; i < N * 3 && ok; i++) ok = isfinite(a[i]);
                release_all(p.dut);
                /* the denoiser gave back every block it allocated */
                CHECK_EQ_INT(dut_live_blocks(), blocks_before);
                ew_device_destroy(p.cpu);
                ew_device_destroy(p.dut);
                if (!ok) fprintf(stderr, "  (features %d, color_weight %g, device images %d)\n", features,
                                 (double)weights[w], device_images);
                CHECK(ok);
                CHECK_NO_MISUSE();
            }
}

/* Run op type t on dev with generic inputs (every image, random; every
 * parameter at its default); the output, N*C floats, into out. */
static ew_result run_op_generic(ew_device *dev, const ew_op_type *t, float *out, int *out_channels) {
    ew_op *op = NULL;
    ew_result r = ew_op_create_kind(dev, t->kind, t->name, &op);
    if (r != EW_OK) return r;
    float *out_buf = NULL;
    int oc = 0;
    uint32_t saved = rng;
    rng = 99991u; /* the same inputs on every device */
    for (int i = 0; i < t->num_images && r == EW_OK; i++) {
        const ew_image_desc *d = &t->images[i];
        const int c = d->min_channels;
        const int is_out = !strcmp(d->name, "output");
        const int is_normal = strstr(d->name, "normal") != NULL;
        float *h = hrand(N * (size_t)c, is_normal ? -1.0f : 0.05f, 1.0f, 0);
        float *data = dev->device_images ? dup_to(dev, h, N * (size_t)c) : h;
        if (is_out) {
            out_buf = data;
            oc = c;
        }
        ew_image v = ew_image_packed(data, W, H, c);
        r = ew_op_set_image(op, d->name, &v);
    }
    rng = saved;
    if (r == EW_OK) r = ew_op_commit(op);
    if (r == EW_OK) r = ew_op_execute(op);
    if (r == EW_OK && out_buf) {
        const float *h = dev->device_images ? back(dev, out_buf, N * (size_t)oc) : out_buf;
        memcpy(out, h, N * (size_t)oc * sizeof(float));
    }
    *out_channels = oc;
    ew_op_destroy(op);
    return r;
}

/* Every op type that declares device_memory runs on the harness — host
 * views and device views — and agrees with the CPU backend (to rounding:
 * GuideNet's convolutions sum in another order on the CPU). An op enrols
 * itself by setting the flag. */
TEST(every_op_on_device_memory_matches_cpu) {
    int ran = 0;
    for (int i = 0; ew_op_types[i]; i++) {
        const ew_op_type *t = ew_op_types[i];
        if (!t->device_memory) continue;
        for (int device_images = 0; device_images <= 1; device_images++) {
            OPEN_PAIR(p, device_images);
            const int blocks_before = dut_live_blocks();
            float *a = hnan(N * 4), *b = hnan(N * 4);
            int ca = 0, cb = 0;
            const ew_result ra = run_op_generic(p.cpu, t, a, &ca);
            if (ra != EW_OK) {
                /* e.g. needs data these generic inputs do not give: nothing
                 * to compare against, and nothing about device memory */
                fprintf(stderr, "  %s %s: not compared, fails on the CPU too: %s\n", t->kind, t->name,
                        ew_device_last_error(p.cpu));
                close_pair(&p);
                continue;
            }
            const ew_result rb = run_op_generic(p.dut, t, b, &cb);
            if (rb != EW_OK)
                fprintf(stderr, "  %s %s: cpu %s (%s), launch grid %s (%s)\n", t->kind, t->name,
                        ew_result_string(ra), ew_device_last_error(p.cpu), ew_result_string(rb),
                        ew_device_last_error(p.dut));
            const int ok = ra == EW_OK && rb == EW_OK && ca == cb && match_tol(b, a, N * (size_t)ca, 1e-4f, t->name);
            release_all(p.dut);
            const int leaked = dut_live_blocks() - blocks_before;
            ew_device_destroy(p.cpu);
            ew_device_destroy(p.dut);
            if (!ok) fprintf(stderr, "  (%s %s, device images %d)\n", t->kind, t->name, device_images);
            CHECK(ok);
            CHECK_EQ_INT(leaked, 0);
            CHECK_NO_MISUSE();
        }
        ran++;
    }
    fprintf(stderr, "  %d op types run on device memory\n", ran);
    CHECK(ran >= 1);
}


#endif
