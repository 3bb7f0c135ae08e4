/*
 * cpu_conv.c — the CPU's 5x5 convolutions of GuideNet and KPCN (see
 * cpu_conv.h and the SIMD body in cpu_conv_block.h).
 *
 * The body is compiled three times: with AVX-512 and with AVX2 + FMA
 * intrinsics for x86-64 processors that have them (picked at run time, so
 * the library still runs on any x86-64; both give the same bits), and with
 * GCC's portable vector extension otherwise. The
 * build uses ISO C (-std=c11), where GCC does not contract a * b + c into
 * an FMA by itself, hence the explicit intrinsics.
 */
#include "backends/cpu/cpu_conv.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "src/backend.h"
#include "src/internal.h"

/* ---- portable vectors ------------------------------------------------ */
/* Macros, not functions: a function taking or returning a 32-byte vector
 * would change the ABI between the two instruction sets (-Wpsabi). */
typedef float ew_v8 __attribute__((vector_size(32)));
typedef float ew_v8u __attribute__((vector_size(32), aligned(4), may_alias));

#define EW_V ew_v8
#define EW_VLOAD(p) (*(const ew_v8u *)(const void *)(p))
#define EW_VSTORE(p, v) (*(ew_v8u *)(void *)(p) = (v))
#define EW_VSET1(f) ((ew_v8){0, 0, 0, 0, 0, 0, 0, 0} + (f))
#define EW_VZERO() ((ew_v8){0, 0, 0, 0, 0, 0, 0, 0})
#define EW_VFMA(a, b, c) ((a) * (b) + (c))
#define EW_SUFFIX(name) name##_generic
#define EW_VW 8
#define EW_XB4 3
#define EW_XB5 2
#include "backends/cpu/cpu_conv_block.h"
#include "backends/cpu/cpu_simd_end.h"

/* ---- AVX2 + FMA ------------------------------------------------------- */
#if defined(__GNUC__) && defined(__x86_64__)
#define EW_HAVE_AVX2_PATH 1
#pragma GCC push_options
#pragma GCC target("avx2,fma")
#include <immintrin.h>
#define EW_V __m256
#define EW_MM(op) _mm256_##op
#define EW_SUFFIX(name) name##_avx2
#define EW_VW 8
#define EW_XB4 3
#define EW_XB5 2
/* 16 registers: 4 channels x 3 vectors of 8 tiles accumulate */
#define EW_WXB 3
#define EW_WCB 4
#include "backends/cpu/cpu_simd_x86.h"
#include "backends/cpu/cpu_conv_block.h"
#include "backends/cpu/cpu_conv_wino.h"
#include "backends/cpu/cpu_simd_end.h"
#pragma GCC pop_options

/* ---- AVX-512 (forward blocks only) ----------------------------------- */
/* 32 vector registers of 16 floats: blocks of 4 channels x 4 vectors (64
 * pixels; 16 accumulators) and 5 x 4 for the 5-channel layer, so a tap
 * costs 4 loads and 4-5 broadcasts for 16-20 multiply-adds. */
#pragma GCC push_options
#pragma GCC target("avx512f,avx2,fma")
#define EW_V __m512
#define EW_MM(op) _mm512_##op
#define EW_SUFFIX(name) name##_avx512
#define EW_VW 16
#define EW_XB4 4
#define EW_XB5 4
#define EW_NO_DWEIGHT 1
/* 32 registers: 8 channels x 2 vectors of 16 tiles accumulate */
#define EW_WXB 2
#define EW_WCB 8
#include "backends/cpu/cpu_simd_x86.h"
#include "backends/cpu/cpu_conv_block.h"
#include "backends/cpu/cpu_conv_wino.h"
#include "backends/cpu/cpu_simd_end.h"
#pragma GCC pop_options
#endif

typedef struct {
    long iters;
    double flops[256];
} peak_job;

static void peak_items(void *ctx, int64_t begin, int64_t end, int tid) {
    peak_job *j = (peak_job *)ctx;
    for (int64_t i = begin; i < end; i++) {
#ifdef EW_HAVE_AVX2_PATH
        const int level = ew_conv_cpu_simd_level();
        if (level == 2) j->flops[tid & 255] += fma_burn_avx512(j->iters / 2, (float)i);
        else if (level == 1) j->flops[tid & 255] += fma_burn_avx2(j->iters, (float)i);
#else
        (void)j;
#endif
    }
}

double ew_conv_cpu_fma_gflops(ew_device *dev, double *seconds) {
    peak_job j;
    memset(&j, 0, sizeof j);
    j.iters = 20000000;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    ew_pool_run(dev->pool, dev->num_threads, 1, peak_items, &j);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double dt = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec), f = 0;
    for (int k = 0; k < 256; k++) f += j.flops[k];
    if (seconds) *seconds = dt;
    return dt > 0 ? f / dt * 1e-9 : 0.0;
}

int ew_conv_cpu_simd_level(void) {
#ifdef EW_HAVE_AVX2_PATH
    __builtin_cpu_init();
    if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return 0;
    return __builtin_cpu_supports("avx512f") ? 2 : 1;
#else
    return 0;
#endif
}

const char *ew_conv_cpu_simd_name(int level) {
    return level == 2 ? "AVX-512" : (level == 1 ? "AVX2 + FMA" : "portable");
}

void ew_conv_cpu_rows_level(const ew_conv_args *a, const float *wt, int r0, int r1, int level) {
#ifdef EW_HAVE_AVX2_PATH
    if (level > ew_conv_cpu_simd_level()) level = ew_conv_cpu_simd_level();
    if (level == 2) {
        conv_rows_avx512(a, wt, r0, r1);
        return;
    }
    if (level == 1) {
        conv_rows_avx2(a, wt, r0, r1);
        return;
    }
#endif
    (void)level;
    conv_rows_generic(a, wt, r0, r1);
}

void ew_conv_cpu_wt_layout(int cin, int cout, const float *w, float *wt) {
    int co = 0;
    while (co < cout) {
        int cb = cout == 5 ? 5 : (cout - co >= 4 ? 4 : cout - co);
        float *blk = wt + (long)co * cin * 25;
        for (int ci = 0; ci < cin; ci++)
            for (int t = 0; t < 25; t++)
                for (int k = 0; k < cb; k++) blk[((long)ci * 25 + t) * cb + k] = w[((long)(co + k) * cin + ci) * 25 + t];
        co += cb;
    }
}

void ew_conv_cpu_rows(const ew_conv_args *a, const float *wt, int r0, int r1) {
    ew_conv_cpu_rows_level(a, wt, r0, r1, 2);
}

void ew_conv_cpu_dweight(const ew_conv_args *a, const float *g, long g_rs, long g_ps, float *dw, float *db) {
#ifdef EW_HAVE_AVX2_PATH
    if (ew_conv_cpu_simd_level()) {
        conv_dweight_avx2(a, g, g_rs, g_ps, dw, db);
        return;
    }
#endif
    conv_dweight_generic(a, g, g_rs, g_ps, dw, db);
}

typedef struct {
    const ew_conv_args *a;
    const float *wt;
    int simd;
} conv_job;

static void conv_job_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const conv_job *j = (const conv_job *)ctx;
    if (j->simd) {
        ew_conv_cpu_rows(j->a, j->wt, (int)begin, (int)end);
        return;
    }
    for (int64_t r = begin; r < end; r++)
        for (int co = 0; co < j->a->cout; co++)
            for (int x = 0; x < j->a->width; x++) ew_conv5_px(x, (int)r, co, j->a);
}

static void conv5_direct(ew_device *dev, const ew_conv_args *a) {
    float stack_wt[EW_CONV_CPU_STACK_CHANNEL_PAIRS * 25];
    const int pairs = a->cin * a->cout;
    float *wt = pairs <= EW_CONV_CPU_STACK_CHANNEL_PAIRS ? stack_wt : (float *)malloc(sizeof(float) * 25 * (size_t)pairs);
    conv_job j = {a, wt, wt != NULL};
    if (j.simd) ew_conv_cpu_wt_layout(a->cin, a->cout, a->weight, wt);
    ew_pool_run(dev->pool, a->rows, 1, conv_job_rows, &j);
    if (wt != stack_wt) free(wt);
}

/* ---- Winograd F(4x4, 5x5) (cpu_conv_wino.h) ---------------------------- */
#ifdef EW_HAVE_AVX2_PATH
/* G of tools/winograd_f4x5.py: the kernel's transform, applied in double
 * once per call. */
static const double wino_g[8][5] = {
    {1.0, 0.0, 0.0, 0.0, 0.0},
    {-2.0 / 9.0, -2.0 / 9.0, -2.0 / 9.0, -2.0 / 9.0, -2.0 / 9.0},
    {-2.0 / 9.0, 2.0 / 9.0, -2.0 / 9.0, 2.0 / 9.0, -2.0 / 9.0},
    {1.0 / 180.0, 1.0 / 90.0, 1.0 / 45.0, 2.0 / 45.0, 4.0 / 45.0},
    {1.0 / 180.0, -1.0 / 90.0, 1.0 / 45.0, -2.0 / 45.0, 4.0 / 45.0},
    {64.0 / 45.0, 32.0 / 45.0, 16.0 / 45.0, 8.0 / 45.0, 4.0 / 45.0},
    {64.0 / 45.0, -32.0 / 45.0, 16.0 / 45.0, -8.0 / 45.0, 4.0 / 45.0},
    {0.0, 0.0, 0.0, 0.0, 1.0},
};

/* Doubles of one thread's scratch for wino_weights_rows on cout outputs */
static size_t wino_weights_scratch(int cout) { return ((size_t)cout * 66 + 7) / 8 * 8; }

/* The transformed kernels U = G g G^T the Winograd products read
 * ([64][cin][cout] floats from the [cout][cin][5][5] weights) of input
 * channels ci0 .. ci1, each element as its own sum in the same order (any
 * split, any vector width gives the same bits): the output channels side
 * by side in g (wino_weights_scratch), so the sums run across them
 * (vectorised) and each transform position's are written in a row. */
static void wino_weights_rows(int cin, int cout, const float *w, float *u, int ci0, int ci1, double *g) {
    double *t = g + (size_t)25 * cout, *acc = t + (size_t)40 * cout;
    for (int ci = ci0; ci < ci1; ci++) {
        for (int co = 0; co < cout; co++)
            for (int k = 0; k < 25; k++) g[(size_t)k * cout + co] = (double)w[((long)co * cin + ci) * 25 + k];
        for (int i = 0; i < 8; i++)
            for (int kx = 0; kx < 5; kx++) {
                double *tt = t + (size_t)(i * 5 + kx) * cout;
                for (int co = 0; co < cout; co++) tt[co] = 0.0;
                for (int ky = 0; ky < 5; ky++) {
                    const double c = wino_g[i][ky], *gg = g + (size_t)(ky * 5 + kx) * cout;
                    for (int co = 0; co < cout; co++) tt[co] += c * gg[co];
                }
            }
        for (int i = 0; i < 8; i++)
            for (int j = 0; j < 8; j++) {
                for (int co = 0; co < cout; co++) acc[co] = 0.0;
                for (int kx = 0; kx < 5; kx++) {
                    const double c = wino_g[j][kx], *tt = t + (size_t)(i * 5 + kx) * cout;
                    for (int co = 0; co < cout; co++) acc[co] += tt[co] * c;
                }
                float *ur = u + ((long)(i * 8 + j) * cin + ci) * cout;
                for (int co = 0; co < cout; co++) ur[co] = (float)acc[co];
            }
    }
}

typedef struct {
    int cin, cout;
    const float *w;
    float *u;
    double *scratch; /* wino_weights_scratch(cout) doubles a thread */
} wino_weights_job;

static void wino_weights_items(void *ctx, int64_t begin, int64_t end, int tid) {
    const wino_weights_job *j = (const wino_weights_job *)ctx;
    wino_weights_rows(j->cin, j->cout, j->w, j->u, (int)begin, (int)end,
                      j->scratch + (size_t)tid * wino_weights_scratch(j->cout));
}

/* tiles per item and output channels per block of the products (the
 * EW_WXB * EW_VW and EW_WCB of each instruction set in cpu_conv_wino.h) */
static int wino_tiles(int level) { return level == 2 ? 32 : 24; }
static int wino_cb(int level) { return level == 2 ? 8 : 4; }

static size_t wino_scratch_floats(int level, int cin) {
    const int nt = wino_tiles(level), vw = level == 2 ? 16 : 8;
    return ((size_t)64 * cin * nt + (size_t)64 * wino_cb(level) * nt + 9 * (size_t)(4 * vw + 4) + 15) / 16 * 16;
}

typedef struct {
    const ew_conv_args *a;
    const float *u;
    float *scratch;
    size_t per_thread;
    int level, items_x, px, py;
} wino_job;

static void wino_job_items(void *ctx, int64_t begin, int64_t end, int tid) {
    const wino_job *j = (const wino_job *)ctx;
    float *scratch = j->scratch + (size_t)tid * j->per_thread;
    for (int64_t i = begin; i < end; i++) {
        const int ty = (int)(i / j->items_x), tx0 = (int)(i % j->items_x) * wino_tiles(j->level);
        if (j->level == 2) wino_item_avx512(j->a, j->u, ty, tx0, j->px, j->py, scratch);
        else wino_item_avx2(j->a, j->u, ty, tx0, j->px, j->py, scratch);
    }
}
#endif

/* Winograd on dev's threads; 0 when this build or processor has no
 * AVX2 + FMA, or memory is short (the caller then runs the direct path). */
static int conv5_wino(ew_device *dev, const ew_conv_args *a, int level) {
#ifdef EW_HAVE_AVX2_PATH
    if (level > ew_conv_cpu_simd_level()) level = ew_conv_cpu_simd_level();
    if (level < 1 || a->accumulate || a->width <= 0 || a->rows <= 0) return 0;
    const int threads = ew_pool_threads(dev->pool) > 0 ? ew_pool_threads(dev->pool) : 1;
    const size_t per = wino_scratch_floats(level, a->cin), nu = (size_t)64 * a->cin * a->cout;
    const size_t tw = 2 * wino_weights_scratch(a->cout) * (size_t)threads; /* floats of the transform's doubles */
    float *mem = (float *)calloc(nu + per * (size_t)threads + tw + 32, sizeof(float));
    if (!mem) return 0;
    float *scratch = mem + (nu + 15) / 16 * 16;
    /* the layer's weights, on the pool's threads: kpcn's bands make a few
     * thousand calls a 4K frame, each transforming its layer's */
    wino_weights_job wj = {a->cin, a->cout, a->weight, mem,
                           (double *)(void *)(scratch + ((per * (size_t)threads + 15) / 16 * 16))};
    ew_pool_run(dev->pool, a->cin, 1, wino_weights_items, &wj);
    /* the tiles start at x = -px, r = -py: (grid_x, grid_y) mod 4 */
    const int px = ((a->grid_x % 4) + 4) % 4, py = ((a->grid_y % 4) + 4) % 4;
    const int nt = wino_tiles(level), tiles_x = (a->width + px + 3) / 4, tiles_y = (a->rows + py + 3) / 4;
    wino_job j = {a, mem, scratch, per, level, (tiles_x + nt - 1) / nt, px, py};
    ew_pool_run(dev->pool, (int64_t)tiles_y * j.items_x, 1, wino_job_items, &j);
    free(mem);
    return 1;
#else
    (void)dev;
    (void)a;
    (void)level;
    return 0;
#endif
}

int ew_conv_cpu_wino_pays(const ew_conv_args *a) {
    return a->winograd && !a->accumulate && a->cin * a->cout >= EW_CONV_CPU_WINO_MIN_PAIRS;
}

int ew_cpu_conv5_path(ew_device *dev, const ew_conv_args *a, int path, int level) {
    if (path == EW_CONV_CPU_AUTO) path = !dev->conv_direct && ew_conv_cpu_wino_pays(a) ? EW_CONV_CPU_WINOGRAD : EW_CONV_CPU_DIRECT;
    if (path == EW_CONV_CPU_WINOGRAD && conv5_wino(dev, a, level)) return EW_CONV_CPU_WINOGRAD;
    conv5_direct(dev, a);
    return EW_CONV_CPU_DIRECT;
}

void ew_cpu_conv5(ew_device *dev, const ew_conv_args *a) { (void)ew_cpu_conv5_path(dev, a, EW_CONV_CPU_AUTO, 2); }
