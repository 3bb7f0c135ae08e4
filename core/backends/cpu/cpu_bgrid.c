/*
 * cpu_bgrid.c — the CPU's bilateral grid splat and slice.
 *
 * The per-cell gather of kernels/bgrid.h (ew_bgrid_splat_column, what the
 * CUDA backend runs) recomputes the tent weights of every pixel in every
 * column that can see it: each pixel is visited by 4 columns and pays 6
 * square roots and 3 divisions each time. Here the work is reorganised,
 * with the same expressions and the same order of additions, so the grid
 * and the slice are the same bits as the kernels' (tests/unit/test_bgrid.c
 * compares them with memcmp):
 *
 *  - splat: one work item is a whole row v of grid columns. It scatters the
 *    image rows its cells can see (each image row is read by 2 grid rows),
 *    each pixel into its 2 x 2 columns and 2 depth cells, in raster order —
 *    the order in which every cell receives its pixels in the column gather
 *    too — then normalises the row while it is still in the cache. Grid
 *    rows are independent, so there are no atomics and no partial grids, and
 *    the result does not depend on the thread count.
 *  - slice: one work item is an image row; the weights of a run of pixels
 *    are computed first (x and depth tents), then the 8 cells of each pixel
 *    are added in the kernel's order.
 *  - the tent weights of a run of pixels (floor, division, square roots) are
 *    computed 8 pixels at a time with AVX2 when the processor has it (the
 *    same IEEE operations, so the same bits), else by the kernel's scalar
 *    functions.
 *
 * Three channels (the only case the denoisers use) take this path; other
 * channel counts run the kernels' functions.
 */
#include <string.h>

#include "backends/cpu/cpu_bgrid.h"

#include "src/backend.h"
#include "src/internal.h"

#if defined(__GNUC__) && defined(__x86_64__)
#define EW_BGRID_AVX2 1
#include <immintrin.h>
#endif

#define RUN 256 /* pixels whose weights are computed together */

/* Tents of a run of n pixels starting at x0 of one row: x cells u0 and
 * u0 + 1 with weights wx0, wx1; depth cells z0, z0 + 1 with tz0, tz1 (a
 * non-finite guide is read as 0, as the slice does; the splat skips those
 * pixels anyway). */
typedef struct {
    int u0[RUN], z0[RUN];
    float wx0[RUN], wx1[RUN], tz0[RUN], tz1[RUN];
} run_weights;

static void weights_scalar(const ew_bgrid_params *p, int x0, int n, const float *guide, run_weights *r) {
    for (int i = 0; i < n; i++) {
        float px = ew_bgrid_pos_s((float)(x0 + i), p->rate_s);
        int u = (int)floorf(px);
        r->u0[i] = u;
        r->wx0[i] = ew_tent(px - (float)u);
        r->wx1[i] = ew_tent(px - (float)(u + 1));
        float g = guide[i];
        float pz = ew_bgrid_pos_d(ew_finitef(g) ? g : 0.0f, p->rate_d);
        int z = (int)floorf(pz);
        r->z0[i] = z;
        r->tz0[i] = ew_tent(pz - (float)z);
        r->tz1[i] = ew_tent(pz - (float)(z + 1));
    }
}

#ifdef EW_BGRID_AVX2
#pragma GCC push_options
#pragma GCC target("avx2")
/* The scalar expressions lane by lane: (x + 0.5) / rate - 0.5, floor, and
 * max(1 - sqrt(a * a + eps), 0), all correctly rounded IEEE operations (no
 * FMA), so every lane is the scalar result. */
static inline __m256 tent8(__m256 a) {
    const __m256 one = _mm256_set1_ps(1.0f), eps = _mm256_set1_ps(EW_TENT_EPS);
    __m256 t = _mm256_sub_ps(one, _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(a, a), eps)));
    return _mm256_max_ps(t, _mm256_setzero_ps()); /* t > 0 ? t : 0, as ew_maxf */
}

static void weights_avx2(const ew_bgrid_params *p, int x0, int n, const float *guide, run_weights *r) {
    const __m256 half = _mm256_set1_ps(0.5f), one = _mm256_set1_ps(1.0f);
    const __m256 rs = _mm256_set1_ps(p->rate_s), rd = _mm256_set1_ps(p->rate_d);
    const __m256 absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 inf = _mm256_set1_ps(__builtin_inff());
    const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        __m256 xs = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x0 + i), iota));
        __m256 px = _mm256_sub_ps(_mm256_div_ps(_mm256_add_ps(xs, half), rs), half);
        __m256 fu = _mm256_floor_ps(px);
        _mm256_storeu_si256((__m256i *)(void *)(r->u0 + i), _mm256_cvttps_epi32(fu));
        _mm256_storeu_ps(r->wx0 + i, tent8(_mm256_sub_ps(px, fu)));
        _mm256_storeu_ps(r->wx1 + i, tent8(_mm256_sub_ps(px, _mm256_add_ps(fu, one))));
        __m256 g = _mm256_loadu_ps(guide + i);
        __m256 fin = _mm256_cmp_ps(_mm256_and_ps(g, absmask), inf, _CMP_LT_OQ);
        g = _mm256_and_ps(g, fin);
        __m256 pz = _mm256_sub_ps(_mm256_div_ps(g, rd), half);
        __m256 fz = _mm256_floor_ps(pz);
        _mm256_storeu_si256((__m256i *)(void *)(r->z0 + i), _mm256_cvttps_epi32(fz));
        _mm256_storeu_ps(r->tz0 + i, tent8(_mm256_sub_ps(pz, fz)));
        _mm256_storeu_ps(r->tz1 + i, tent8(_mm256_sub_ps(pz, _mm256_add_ps(fz, one))));
    }
    if (i < n) {
        run_weights t;
        weights_scalar(p, x0 + i, n - i, guide + i, &t);
        for (int k = 0; k < n - i; k++) {
            r->u0[i + k] = t.u0[k];
            r->z0[i + k] = t.z0[k];
            r->wx0[i + k] = t.wx0[k];
            r->wx1[i + k] = t.wx1[k];
            r->tz0[i + k] = t.tz0[k];
            r->tz1[i + k] = t.tz1[k];
        }
    }
}
#pragma GCC pop_options
#endif

static int have_avx2(void) {
#ifdef EW_BGRID_AVX2
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") ? 1 : 0;
#else
    return 0;
#endif
}

static void run_weights_compute(int simd, const ew_bgrid_params *p, int x0, int n, const float *guide,
                                run_weights *r) {
#ifdef EW_BGRID_AVX2
    if (simd) {
        weights_avx2(p, x0, n, guide, r);
        return;
    }
#endif
    (void)simd;
    weights_scalar(p, x0, n, guide, r);
}

/* ---- splat ----------------------------------------------------------------- */
typedef struct {
    const ew_bgrid_params *p;
    const float *image, *guide;
    float *grid;
    int simd;
} splat_job;

/* A pixel as (I0, I1, I2, 1); cell += w * that: the kernel's
 * cell[c] += w * px[c]; cell[C] += w (w * 1 = w), a multiply then an add
 * per lane, as in the scalar code. SSE2 is part of x86-64. */
#if defined(__SSE2__)
#include <emmintrin.h>
typedef __m128 px4;
#define PX4(b0, b1, b2) _mm_setr_ps((b0), (b1), (b2), 1.0f)
#define SPLAT_ADD(cell, w, b) _mm_storeu_ps((cell), _mm_add_ps(_mm_loadu_ps(cell), _mm_mul_ps(_mm_set1_ps(w), (b))))
#else
typedef struct {
    float v[4];
} px4;
static inline px4 px4_make(float b0, float b1, float b2) {
    px4 r = {{b0, b1, b2, 1.0f}};
    return r;
}
#define PX4(b0, b1, b2) px4_make((b0), (b1), (b2))
#define SPLAT_ADD(cell, w, b)                                                                               \
    do {                                                                                                    \
        for (int c_ = 0; c_ < 4; c_++) (cell)[c_] += (w) * (b).v[c_];                                       \
    } while (0)
#endif

static void splat_row3(const splat_job *j, int v, run_weights *r) {
    const ew_bgrid_params *p = j->p;
    const int W = p->width, gw = p->gw, gd = p->gd;
    const long colf = (long)gd * 4;
    float *row = j->grid + (long)v * gw * colf;
    memset(row, 0, sizeof(float) * (size_t)gw * (size_t)colf);
    int y0, y1;
    ew_bgrid_band_rows(v, p, &y0, &y1); /* in the band's rows; positions in the frame's (kernels/bgrid.h) */
    for (int y = y0; y <= y1; y++) {
        const float wy = ew_tent(ew_bgrid_pos_s((float)(y + p->band_y), p->rate_s) - (float)(v + p->band_v));
        if (wy <= 0.0f) continue;
        const float *grow = j->guide + (long)y * W;
        const float *irow = j->image + (long)y * W * 3;
        for (int x0 = 0; x0 < W; x0 += RUN) {
            const int n = W - x0 < RUN ? W - x0 : RUN;
            run_weights_compute(j->simd, p, x0, n, grow + x0, r);
            for (int i = 0; i < n; i++) {
                const float *px = irow + (long)(x0 + i) * 3;
                const float b0 = px[0], b1 = px[1], b2 = px[2];
                if (!(ew_finitef(grow[x0 + i]) & ew_finitef(b0) & ew_finitef(b1) & ew_finitef(b2))) continue;
                const px4 b = PX4(b0, b1, b2);
                const int z0 = r->z0[i], u0 = r->u0[i];
                const float t0 = r->tz0[i], t1 = r->tz1[i];
                if (u0 >= 0 && u0 + 1 < gw && z0 >= 0 && z0 + 1 < gd) {
                    /* inside the grid (most pixels): all 4 cells, no tests.
                     * A zero weight adds +-0, which leaves a cell as it is
                     * (a sum that starts at +0 is never -0), so skipping
                     * those as the kernel does gives the same bits. */
                    const float wxy0 = r->wx0[i] * wy, wxy1 = r->wx1[i] * wy;
                    float *c0 = row + (long)u0 * colf + (long)z0 * 4, *c1 = c0 + colf;
                    SPLAT_ADD(c0, wxy0 * t0, b);
                    SPLAT_ADD(c0 + 4, wxy0 * t1, b);
                    SPLAT_ADD(c1, wxy1 * t0, b);
                    SPLAT_ADD(c1 + 4, wxy1 * t1, b);
                    continue;
                }
                const int has0 = z0 >= 0 && z0 < gd, has1 = z0 + 1 >= 0 && z0 + 1 < gd;
                for (int du = 0; du < 2; du++) {
                    const int u = u0 + du;
                    if (u < 0 || u >= gw) continue;
                    const float wx = du ? r->wx1[i] : r->wx0[i];
                    if (wx <= 0.0f) continue;
                    const float wxy = wx * wy;
                    const long k = (long)u * colf + (long)z0 * 4; /* cell z0 (may be -1: then unused) */
                    if (has0) {
                        const float w = wxy * t0;
                        if (w > 0.0f) SPLAT_ADD(row + k, w, b);
                    }
                    if (has1) {
                        const float w = wxy * t1;
                        if (w > 0.0f) SPLAT_ADD(row + k + 4, w, b);
                    }
                }
            }
        }
    }
    const long cells = (long)gw * gd;
    for (long c = 0; c < cells; c++) {
        float *cell = row + c * 4;
        if (cell[3] > 0.0f) {
            cell[0] /= cell[3];
            cell[1] /= cell[3];
            cell[2] /= cell[3];
        }
    }
}

static void splat_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const splat_job *j = (const splat_job *)ctx;
    if (j->p->channels != 3) {
        for (int64_t v = begin; v < end; v++)
            for (int u = 0; u < j->p->gw; u++) ew_bgrid_splat_column(u, (int)v, j->p, j->image, j->guide, j->grid);
        return;
    }
    run_weights r;
    for (int64_t v = begin; v < end; v++) splat_row3(j, (int)v, &r);
}

void ew_cpu_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image, const float *guide,
                        float *grid) {
    splat_job j = {p, image, guide, grid, have_avx2()};
    ew_pool_run(dev->pool, p->gh, 1, splat_rows, &j);
}

/* ---- slice ----------------------------------------------------------------- */
#define PREFETCH 16 /* pixels ahead */
#if defined(__GNUC__)
#define prefetch(p) __builtin_prefetch((p), 0, 3)
#else
#define prefetch(p) ((void)(p))
#endif

typedef struct {
    const ew_bgrid_params *p;
    const float *grid, *guide;
    float *out;
    int simd;
} slice_job;

static void slice_row3(const slice_job *j, int y, run_weights *r) {
    const ew_bgrid_params *p = j->p;
    const int W = p->width, gw = p->gw, gh = p->gh, gd = p->gd;
    const long colf = (long)gd * 4;
    /* the frame's row and cells (kernels/bgrid.h, bands); v0 in the band's grid */
    const float py = ew_bgrid_pos_s((float)(y + p->band_y), p->rate_s);
    const int fv0 = (int)floorf(py), v0 = fv0 - p->band_v;
    const float wy[2] = {ew_tent(py - (float)fv0), ew_tent(py - (float)(fv0 + 1))};
    const int hv[2] = {v0 >= 0 && v0 < gh, v0 + 1 >= 0 && v0 + 1 < gh};
    const long rows[2] = {(long)v0 * gw * colf, (long)(v0 + 1) * gw * colf}; /* offsets of grid rows v0, v0 + 1 */
    const float *grow = j->guide + (long)y * W;
    float *orow = j->out + (long)y * W * 3;
    for (int x0 = 0; x0 < W; x0 += RUN) {
        const int n = W - x0 < RUN ? W - x0 : RUN;
        run_weights_compute(j->simd, p, x0, n, grow + x0, r);
        for (int i = 0; i < n; i++) {
            if (i + PREFETCH < n) {
                /* the first cells of a pixel ahead (the grid was written by
                 * the whole splat pass before, so its rows are rarely still
                 * in the cache) */
                const int pu = r->u0[i + PREFETCH], pz = r->z0[i + PREFETCH];
                const long pk = (long)(pu < 0 ? 0 : (pu >= gw ? gw - 1 : pu)) * colf +
                                (long)(pz < 0 ? 0 : (pz >= gd ? gd - 1 : pz)) * 4;
                if (hv[0]) prefetch(j->grid + rows[0] + pk);
                if (hv[1]) prefetch(j->grid + rows[1] + pk);
                if (pu + 1 < gw) {
                    if (hv[0]) prefetch(j->grid + rows[0] + pk + colf);
                    if (hv[1]) prefetch(j->grid + rows[1] + pk + colf);
                }
            }
            const int u0 = r->u0[i], z0 = r->z0[i];
            const int hu[2] = {u0 >= 0 && u0 < gw, u0 + 1 >= 0 && u0 + 1 < gw};
            const int hz[2] = {z0 >= 0 && z0 < gd, z0 + 1 >= 0 && z0 + 1 < gd};
            const float wx[2] = {r->wx0[i], r->wx1[i]}, tz[2] = {r->tz0[i], r->tz1[i]};
#if defined(__SSE2__)
            /* acc += w * (G0, G1, G2, 1) for the non-empty cells, in the
             * kernel's order; an empty cell adds +0 (masked), which leaves
             * the sums as they are */
            const __m128 one3 = _mm_setr_ps(0.0f, 0.0f, 0.0f, 1.0f);
            const __m128 keep3 = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
            __m128 acc = _mm_setzero_ps();
#define SLICE_ADD(off, w)                                                                                   \
    do {                                                                                                    \
        const __m128 cell_ = _mm_loadu_ps(j->grid + (off));                                                 \
        const __m128 full_ = _mm_cmpgt_ps(_mm_shuffle_ps(cell_, cell_, 0xff), _mm_setzero_ps());            \
        acc = _mm_add_ps(acc, _mm_mul_ps(_mm_set1_ps(w), _mm_and_ps(_mm_or_ps(_mm_and_ps(cell_, keep3), one3), full_))); \
    } while (0)
            if (hv[0] & hv[1] & hu[0] & hu[1] & hz[0] & hz[1]) {
                /* inside the grid (most pixels): the 8 cells in the kernel's order */
                const long k0 = rows[0] + (long)u0 * colf + (long)z0 * 4, k1 = rows[1] + (long)u0 * colf + (long)z0 * 4;
                const float w00 = wx[0] * wy[0], w01 = wx[1] * wy[0], w10 = wx[0] * wy[1], w11 = wx[1] * wy[1];
                SLICE_ADD(k0, w00 * tz[0]);
                SLICE_ADD(k0 + 4, w00 * tz[1]);
                SLICE_ADD(k0 + colf, w01 * tz[0]);
                SLICE_ADD(k0 + colf + 4, w01 * tz[1]);
                SLICE_ADD(k1, w10 * tz[0]);
                SLICE_ADD(k1 + 4, w10 * tz[1]);
                SLICE_ADD(k1 + colf, w11 * tz[0]);
                SLICE_ADD(k1 + colf + 4, w11 * tz[1]);
            } else
            for (int dv = 0; dv < 2; dv++) {
                if (!hv[dv]) continue;
                for (int du = 0; du < 2; du++) {
                    if (!hu[du]) continue;
                    const float wxy = wx[du] * wy[dv];
                    const long k = rows[dv] + (long)(u0 + du) * colf + (long)z0 * 4;
                    for (int dz = 0; dz < 2; dz++)
                        if (hz[dz]) SLICE_ADD(k + 4 * dz, wxy * tz[dz]);
                }
            }
#undef SLICE_ADD
            float av[4];
            _mm_storeu_ps(av, acc);
            const float a0 = av[0], a1 = av[1], a2 = av[2], a3 = av[3];
#else
            float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f;
            for (int dv = 0; dv < 2; dv++) {
                if (!hv[dv]) continue;
                for (int du = 0; du < 2; du++) {
                    if (!hu[du]) continue;
                    const float wxy = wx[du] * wy[dv];
                    const long k = rows[dv] + (long)(u0 + du) * colf + (long)z0 * 4;
                    for (int dz = 0; dz < 2; dz++) {
                        if (!hz[dz]) continue;
                        const float *cell = j->grid + k + 4 * dz;
                        if (cell[3] <= 0.0f) continue;
                        const float w = wxy * tz[dz];
                        a0 += w * cell[0];
                        a1 += w * cell[1];
                        a2 += w * cell[2];
                        a3 += w;
                    }
                }
            }
#endif
            float *o = orow + (long)(x0 + i) * 3;
            if (a3 > 0.0f) {
                const float inv = 1.0f / a3;
                o[0] = a0 * inv;
                o[1] = a1 * inv;
                o[2] = a2 * inv;
            } else {
                ew_bgrid_slice_px(x0 + i, y, p, j->grid, j->guide, o); /* the kernel's fallback */
            }
        }
    }
}

static void slice_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const slice_job *j = (const slice_job *)ctx;
    const int C = j->p->channels;
    if (C != 3) {
        for (int64_t y = begin; y < end; y++)
            for (int x = 0; x < j->p->width; x++)
                ew_bgrid_slice_px(x, (int)y, j->p, j->grid, j->guide, j->out + ((int64_t)y * j->p->width + x) * C);
        return;
    }
    run_weights r;
    /* bottom row first: the splat wrote the grid top to bottom, so its last
     * rows are the ones most likely still in the cache */
    for (int64_t i = begin; i < end; i++) slice_row3(j, j->p->height - 1 - (int)i, &r);
}

void ew_cpu_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid, const float *guide,
                        float *out) {
    slice_job j = {p, grid, guide, out, have_avx2()};
    ew_pool_run(dev->pool, p->height, 0, slice_rows, &j);
}
