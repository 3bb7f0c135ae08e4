/*
 * cpu_backend.c — the CPU backend: rows (or grid rows) are handed out to
 * the device's thread pool; each item calls the shared per-pixel function.
 */
#include "backends/cpu/cpu_bgrid.h"
#include "kernels/harm.h"
#include "kernels/denoise_px.h"
#include "kernels/guidenet.h"
#include "kernels/outlier.h"
#include "kernels/temporal.h"
#include "src/backend.h"
#include "src/internal.h"
#include "src/cpu_clones.h" /* EW_MULTIVERSION */

#include <stdlib.h>
#include <string.h>

typedef struct {
    const ew_bgrid_params *p;
    const float *a, *guide;
    float *dst;
    const ew_denoise_buffers *b;
} cpu_job;

/* splat and slice: cpu_bgrid.c */

static void prepare_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_denoise_buffers *b = ((const cpu_job *)ctx)->b;
    for (int64_t j = begin * b->width; j < end * b->width; j++) ew_denoise_prepare_px((long)j, b);
}

static void finish_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_denoise_buffers *b = ((const cpu_job *)ctx)->b;
    for (int64_t j = begin * b->width; j < end * b->width; j++) ew_denoise_finish_px((long)j, b);
}

static void cpu_denoise_prepare(ew_device *dev, const ew_denoise_buffers *b) {
    cpu_job j = {NULL, NULL, NULL, NULL, b};
    ew_pool_run(dev->pool, b->height, 0, prepare_rows, &j);
}

static void cpu_denoise_finish(ew_device *dev, const ew_denoise_buffers *b) {
    cpu_job j = {NULL, NULL, NULL, NULL, b};
    ew_pool_run(dev->pool, b->height, 0, finish_rows, &j);
}

typedef struct {
    const ew_denoise_buffers *b;
    float mean_lum, color_weight;
} refine_job;

static void refine_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const refine_job *r = (const refine_job *)ctx;
    for (int64_t j = begin * r->b->width; j < end * r->b->width; j++)
        ew_denoise_refine_guide_px((long)j, r->b, r->mean_lum, r->color_weight);
}

static void cpu_denoise_refine_guide(ew_device *dev, const ew_denoise_buffers *b, float mean_lum, float color_weight) {
    refine_job r = {b, mean_lum, color_weight};
    ew_pool_run(dev->pool, b->height, 0, refine_rows, &r);
}

typedef struct {
    const ew_outlier_params *p;
    const ew_outlier_buffers *b;
} outlier_guided_job;

/* acc[x] += v[x + dx], sq[x] += v2[x + dx], cnt[x] += f[x + dx] for the x in [lo, hi) */
static EW_MULTIVERSION void outlier_add_shifted(float *EW_RESTRICT acc, float *EW_RESTRICT sq, float *EW_RESTRICT cnt,
                                                const float *EW_RESTRICT v, const float *EW_RESTRICT v2,
                                                const float *EW_RESTRICT f, int lo, int hi, int dx) {
    for (int x = lo; x < hi; x++) {
        acc[x] += v[x + dx];
        sq[x] += v2[x + dx];
        cnt[x] += f[x + dx];
    }
}

/* The plain clamp (mean statistics of every finite neighbour, no features,
 * no shift: the denoisers' own firefly_k clamp) a row at a time: each row's
 * luminances once, then for every offset of the window in raster order
 * the whole row's sums, as ew_outlier_guided_px adds them pixel by pixel (a
 * non-finite neighbour adds 0 and counts 0, which leaves the sums as its
 * skipping does: they start at +0). The same bits; non-finite pixels go
 * through the per-pixel function (they are rebuilt from their neighbours). */
static int outlier_plain_rows(const ew_outlier_params *p, const ew_outlier_buffers *b, int64_t begin, int64_t end) {
    const int w = p->width, h = p->height, r = p->radius, cc = b->channels;
    float *buf = (float *)malloc((size_t)w * 6 * sizeof(float));
    if (!buf) return 0;
    float *sum = buf, *sum2 = sum + w, *cnt = sum2 + w, *lv = cnt + w, *l2 = lv + w, *fv = l2 + w;
    for (int64_t yl = begin; yl < end; yl++) {
        const int y = (int)yl;
        memset(sum, 0, (size_t)w * 3 * sizeof(float));
        for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, h - 1); yy++) {
            for (int x = 0; x < w; x++) {
                const float *c1 = b->color + ((long)yy * w + x) * cc;
                const int fin = ew_outlier_finite3(c1);
                const float l = fin ? ew_luminance(c1) - 0.0f : 0.0f; /* - shift, as the per-pixel sums */
                lv[x] = l;
                l2[x] = l * l;
                fv[x] = fin ? 1.0f : 0.0f;
            }
            for (int dx = -r; dx <= r; dx++) {
                const int lo = dx < 0 ? -dx : 0, hi = dx > 0 ? w - dx : w;
                if (yy != y || dx != 0) {
                    if (lo < hi) outlier_add_shifted(sum, sum2, cnt, lv, l2, fv, lo, hi, dx);
                }
            }
        }
        for (int x = 0; x < w; x++) {
            const long j = (long)y * w + x;
            const float *c0 = b->color + j * cc;
            if (!ew_outlier_finite3(c0)) {
                ew_outlier_guided_px(x, y, p, b);
                continue;
            }
            float *o = b->out + j * cc;
            float *removed = b->removed ? b->removed + j * 3 : NULL;
            if (removed) removed[0] = removed[1] = removed[2] = 0.0f;
            for (int c = 0; c < cc; c++) o[c] = c0[c];
            const float lum = ew_luminance(c0);
            const int n = (int)cnt[x];
            if (p->k <= 0.0f || lum <= 0.0f || n < EW_OUTLIER_MIN_SIMILAR) continue;
            ew_outlier_mean_clamp(p, c0, lum, n, 0.0f, sum[x], sum2[x], o, removed);
        }
    }
    free(buf);
    return 1;
}

/* One row of the robust rejection's inputs as separate planes: luminance,
 * whether the colour is finite, albedo and normal channels, the normal's
 * squared length. */
typedef struct {
    float *lum, *a0, *a1, *a2, *n0, *n1, *n2, *len2;
    int *finite;
} robust_row;

static void robust_row_fill(const ew_outlier_buffers *b, int w, int y, const robust_row *r) {
    for (int x = 0; x < w; x++) {
        const long k = (long)y * w + x;
        const float *c = b->color + k * b->channels;
        r->finite[x] = ew_outlier_finite3(c);
        r->lum[x] = ew_luminance(c);
        if (b->albedo) {
            const float *a = b->albedo + k * 3;
            r->a0[x] = a[0], r->a1[x] = a[1], r->a2[x] = a[2];
        }
        if (b->normal) {
            const float *n = b->normal + k * 3;
            r->n0[x] = n[0], r->n1[x] = n[1], r->n2[x] = n[2];
            r->len2[x] = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
        }
    }
}

/* For the x in [lo, hi): is neighbour x + dx of row r finite and similar to
 * pixel x of row c (ew_outlier_similar's tests, where c uses them: use_a,
 * use_n)? n[x] counts those, below[x] those under keep[x]. */
static EW_MULTIVERSION void robust_count_shifted(const robust_row *c, const robust_row *r, const int *EW_RESTRICT use_a,
                                                 const int *EW_RESTRICT use_n, const float *EW_RESTRICT keep,
                                                 int *EW_RESTRICT n, int *EW_RESTRICT below, int lo, int hi, int dx,
                                                 float tol, float normal_cos) {
    /* the planes as restrict locals, so that the loop vectorises */
    const float *EW_RESTRICT ca0 = c->a0, *EW_RESTRICT ca1 = c->a1, *EW_RESTRICT ca2 = c->a2;
    const float *EW_RESTRICT cn0 = c->n0, *EW_RESTRICT cn1 = c->n1, *EW_RESTRICT cn2 = c->n2;
    const float *EW_RESTRICT cl = c->len2, *EW_RESTRICT rlum = r->lum + dx, *EW_RESTRICT rl = r->len2 + dx;
    const float *EW_RESTRICT ra0 = r->a0 + dx, *EW_RESTRICT ra1 = r->a1 + dx, *EW_RESTRICT ra2 = r->a2 + dx;
    const float *EW_RESTRICT rn0 = r->n0 + dx, *EW_RESTRICT rn1 = r->n1 + dx, *EW_RESTRICT rn2 = r->n2 + dx;
    const int *EW_RESTRICT rf = r->finite + dx;
    /* (the planes of a feature the frame lacks are zeros, and use_a / use_n
     * are 0 for every pixel: the tests run and count for nothing) */
    for (int x = lo; x < hi; x++) {
        int s = rf[x];
        s &= (use_a[x] == 0) |
             ((fabsf(ca0[x] - ra0[x]) <= tol) & (fabsf(ca1[x] - ra1[x]) <= tol) & (fabsf(ca2[x] - ra2[x]) <= tol));
        const float d = cn0[x] * rn0[x] + cn1[x] * rn1[x] + cn2[x] * rn2[x];
        s &= (use_n[x] == 0) | ew_outlier_normals_alike(cl[x], rl[x], d, normal_cos);
        n[x] += s;
        below[x] += s & (rlum[x] < keep[x]);
    }
}

/* The robust rejection a row at a time. ew_outlier_guided_px keeps most
 * pixels by a count (at most (n - 1) / 2 of the n similar finite
 * neighbours below ew_outlier_keep_below), which it takes neighbour by
 * neighbour with a branch per test; here the count runs for the whole row,
 * one window offset at a time over contiguous planes of the neighbours'
 * row. The pixels the count does not keep, and those the per-pixel function
 * treats apart (non-finite ones it repairs, lone emitter hits), go through
 * ew_outlier_guided_px itself: the same tests and decisions, the same bits. */
static int outlier_robust_rows(const ew_outlier_params *p, const ew_outlier_buffers *b, int64_t begin, int64_t end) {
    const int w = p->width, h = p->height, r = ew_mini(p->radius, EW_OUTLIER_ROBUST_RADIUS), cc = b->channels;
    /* a ring of the 2 r + 1 rows of the window, each filled once for this
     * range of rows (slot yy mod ring holds row yy) */
    enum { RING = 2 * EW_OUTLIER_ROBUST_RADIUS + 1 };
    const int ring = 2 * r + 1;
    float *fbuf = (float *)calloc((size_t)w * (8 * (size_t)ring + 1), sizeof(float));
    int *ibuf = (int *)malloc((size_t)w * (5 + (size_t)ring) * sizeof(int));
    if (!fbuf || !ibuf) {
        free(fbuf);
        free(ibuf);
        return 0;
    }
    robust_row rows[RING];
    int held[RING];
    for (int i = 0; i < ring; i++) {
        float *f = fbuf + (size_t)8 * (size_t)w * (size_t)i;
        const robust_row row = {f, f + w, f + 2 * w, f + 3 * w, f + 4 * w, f + 5 * w, f + 6 * w, f + 7 * w,
                                ibuf + (size_t)(5 + i) * (size_t)w};
        rows[i] = row;
        held[i] = -1;
    }
    float *keep = fbuf + (size_t)8 * (size_t)w * (size_t)ring;
    int *use_a = ibuf, *use_n = ibuf + w, *n = ibuf + 2 * w, *below = ibuf + 3 * w, *judge = ibuf + 4 * w;
    for (int64_t yl = begin; yl < end; yl++) {
        const int y = (int)yl, y0 = ew_maxi(y - r, 0), y1 = ew_mini(y + r, h - 1);
        for (int yy = y0; yy <= y1; yy++)
            if (held[yy % ring] != yy) {
                robust_row_fill(b, w, yy, &rows[yy % ring]);
                held[yy % ring] = yy;
            }
        const robust_row *centre = &rows[y % ring];
        for (int x = 0; x < w; x++) {
            const long j = (long)y * w + x;
            const float *c0 = b->color + j * cc;
            float *o = b->out + j * cc;
            for (int c = 0; c < cc; c++) o[c] = c0[c];
            if (b->removed) b->removed[j * 3] = b->removed[j * 3 + 1] = b->removed[j * 3 + 2] = 0.0f;
            n[x] = below[x] = 0;
            keep[x] = 0.0f;
            use_a[x] = b->albedo != 0 && ew_outlier_finite3(b->albedo + j * 3);
            use_n[x] = b->normal != 0 && ew_outlier_finite3(b->normal + j * 3);
            /* 0: kept as it is; 1: by the count; 2: by the per-pixel function */
            if (!centre->finite[x]) {
                judge[x] = p->repair ? 2 : 0;
            } else if (p->k <= 0.0f || !(centre->lum[x] > 0.0f)) {
                judge[x] = 0;
            } else if (use_a[x] && p->emitter_albedo > 0.0f && ew_outlier_lone_emitter(x, y, p, b)) {
                judge[x] = 2;
            } else {
                judge[x] = 1;
                keep[x] = ew_outlier_keep_below(p, centre->lum[x]);
            }
        }
        for (int yy = y0; yy <= y1; yy++) {
            for (int dx = -r; dx <= r; dx++) {
                const int lo = dx < 0 ? -dx : 0, hi = dx > 0 ? w - dx : w;
                if ((yy != y || dx != 0) && lo < hi)
                    robust_count_shifted(centre, &rows[yy % ring], use_a, use_n, keep, n, below, lo, hi, dx,
                                         p->albedo_tol, p->normal_cos);
            }
        }
        for (int x = 0; x < w; x++)
            if (judge[x] == 2 || (judge[x] == 1 && n[x] >= EW_OUTLIER_MIN_SIMILAR && below[x] > (n[x] - 1) / 2))
                ew_outlier_guided_px(x, y, p, b);
    }
    free(fbuf);
    free(ibuf);
    return 1;
}

static void outlier_guided_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const outlier_guided_job *j = (const outlier_guided_job *)ctx;
    if (!j->p->robust && !j->p->shift && !j->b->albedo && !j->b->normal && outlier_plain_rows(j->p, j->b, begin, end))
        return;
    if (j->p->robust && outlier_robust_rows(j->p, j->b, begin, end)) return;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p->width; x++) ew_outlier_guided_px(x, (int)y, j->p, j->b);
}

static void cpu_outlier_guided(ew_device *dev, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    outlier_guided_job j = {p, b};
    ew_pool_run(dev->pool, p->height, 0, outlier_guided_rows, &j);
}

typedef struct {
    int step;
    const ew_harm_args *a;
} harm_job;

/* The steps with windows, a row at a time: the per-pixel functions of
 * kernels/harm.h add each pixel's window in raster order; these add whole
 * rows shifted by each offset, in the same order for every pixel (so the
 * same bits, as the launch-grid test checks against the CUDA bodies), with
 * what several pixels read (residuals, luminances) computed once a row. */

/* acc[i] += src[i + shift] for the i in [lo, hi) */
static EW_MULTIVERSION void harm_add_shifted(float *EW_RESTRICT acc, const float *EW_RESTRICT src, long lo, long hi,
                                              long shift) {
    for (long i = lo; i < hi; i++) acc[i] += src[i + shift];
}

/* acc[x * k ..] = the sum over dx = -r..r (ascending) of v[(x + dx) * k ..],
 * the offsets inside the row; k floats a pixel */
static void harm_row_window(float *acc, const float *v, int w, int r, int k) {
    memset(acc, 0, (size_t)w * (size_t)k * sizeof(float));
    for (int dx = -r; dx <= r; dx++) {
        const long lo = dx < 0 ? -dx : 0, hi = dx > 0 ? w - dx : w;
        if (lo < hi) harm_add_shifted(acc, v, lo * k, hi * k, (long)dx * k);
    }
}

/* acc[x] = the sum over the rows yy of the window around y (ascending) of
 * v[yy * w + x] */
static void harm_col_window(float *acc, const float *v, int w, int h, int y, int r) {
    memset(acc, 0, (size_t)w * sizeof(float));
    for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, h - 1); yy++)
        harm_add_shifted(acc, v + (long)yy * w, 0, w, 0);
}

/* rows t (T residual) and l (linear) of row y, 3 floats a pixel */
static void harm_residual_row(const ew_harm_args *a, int y, float *t, float *l) {
    for (int x = 0; x < a->width; x++) ew_harm_residuals(a, (long)y * a->width + x, t + 3 * x, l + 3 * x);
}

static void harm_stats_rows(const ew_harm_args *a, int64_t begin, int64_t end, float *buf) {
    const int w = a->width, h = a->height;
    float *t0 = buf, *l0 = t0 + 3 * (size_t)w, *t1 = l0 + 3 * (size_t)w, *l1 = t1 + 3 * (size_t)w;
    for (int64_t yl = begin; yl < end; yl++) {
        const int y = (int)yl;
        /* t0/l0: row y; t1/l1: row y + 1, or y - 1 at the last row (its block) */
        if (yl == begin) {
            harm_residual_row(a, y, t0, l0);
        } else {
            float *tt = t0, *ll = l0;
            t0 = t1; l0 = l1; t1 = tt; l1 = ll;
        }
        const int last = y + 1 >= h, other = last ? y - 1 : y + 1;
        if (other >= 0) harm_residual_row(a, other, t1, l1);
        /* blocks on rows (by, by + 1) */
        const float *bt0 = last ? t1 : t0, *bt1 = last ? t0 : t1, *bl0 = last ? l1 : l0, *bl1 = last ? l0 : l1;
        for (int x = 0; x < w; x++) {
            const int bx = x + 1 < w ? x : x - 1, block = bx >= 0 && other >= 0;
            const float *tb[4], *lb[4];
            if (block) {
                tb[0] = bt0 + 3 * bx; tb[1] = bt0 + 3 * (bx + 1); tb[2] = bt1 + 3 * bx; tb[3] = bt1 + 3 * (bx + 1);
                lb[0] = bl0 + 3 * bx; lb[1] = bl0 + 3 * (bx + 1); lb[2] = bl1 + 3 * bx; lb[3] = bl1 + 3 * (bx + 1);
            }
            ew_harm_stats_from((long)y * w + x, a, t0 + 3 * x, x + 1 < w ? t0 + 3 * (x + 1) : NULL,
                               last ? NULL : t1 + 3 * x, block ? tb : NULL, block ? lb : NULL, l0 + 3 * x);
        }
    }
}

static void harm_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const harm_job *h = (const harm_job *)ctx;
    const ew_harm_args *a = h->a;
    const int w = a->width, H = a->height;
    const long n = (long)w * H;
    float *buf = NULL;
    switch (h->step) {
    case EW_HARM_STATS: buf = (float *)malloc(12 * (size_t)w * sizeof(float)); break;
    case EW_HARM_BLEND: buf = (float *)malloc((size_t)EW_HARM_STATS_FLOATS * (size_t)w * sizeof(float)); break;
    case EW_HARM_SUM_H:
    case EW_HARM_SPREAD_H: buf = (float *)malloc(2 * (size_t)w * sizeof(float)); break;
    case EW_HARM_SUM_V:
    case EW_HARM_SPREAD_V: buf = (float *)malloc((size_t)w * sizeof(float)); break;
    default: break;
    }
    const int rows = buf != NULL;
    if (rows && h->step == EW_HARM_STATS) {
        harm_stats_rows(a, begin, end, buf);
    } else if (rows) {
        for (int64_t yl = begin; yl < end; yl++) {
            const int y = (int)yl;
            const long j0 = (long)y * w;
            switch (h->step) {
            case EW_HARM_BLEND: {
                /* the window's rows in order, each added over its offsets in order */
                const int r = a->radius;
                memset(buf, 0, (size_t)EW_HARM_STATS_FLOATS * (size_t)w * sizeof(float));
                for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, H - 1); yy++) {
                    const float *st = a->stats + (long)yy * w * EW_HARM_STATS_FLOATS;
                    for (int dx = -r; dx <= r; dx++) {
                        const long lo = dx < 0 ? -dx : 0, hi = dx > 0 ? w - dx : w;
                        if (lo < hi)
                            harm_add_shifted(buf, st, lo * EW_HARM_STATS_FLOATS, hi * EW_HARM_STATS_FLOATS,
                                             (long)dx * EW_HARM_STATS_FLOATS);
                    }
                }
                for (int x = 0; x < w; x++) ew_harm_blend_apply(j0 + x, a, buf + (size_t)x * EW_HARM_STATS_FLOATS);
                break;
            }
            case EW_HARM_SUM_H: { /* as ew_harm_sum_h_px: a luminance that is not finite and positive adds 0 */
                float *v = buf + w;
                for (int x = 0; x < w; x++) {
                    const float l = ew_luminance(a->out + (j0 + x) * 3);
                    v[x] = ew_finitef(l) && l > 0.0f ? l : 0.0f;
                }
                harm_row_window(a->spread + j0, v, w, a->give_radius, 1);
                break;
            }
            case EW_HARM_SUM_V: /* as ew_harm_sum_v_px */
                harm_col_window(a->spread + n + j0, a->spread, w, H, y, a->give_radius);
                break;
            case EW_HARM_SPREAD_H: { /* as ew_harm_spread_h_px */
                float *v = buf + w;
                for (int x = 0; x < w; x++) v[x] = a->give[(j0 + x) * 3];
                harm_row_window(a->spread + 2 * n + j0, v, w, a->give_radius, 1);
                break;
            }
            default: { /* EW_HARM_SPREAD_V, as ew_harm_spread_v_px */
                harm_col_window(buf, a->spread + 2 * n, w, H, y, a->give_radius);
                for (int x = 0; x < w; x++) {
                    const float t = ew_minf(buf[x], a->give_gain);
                    float *o = a->out + (j0 + x) * 3;
                    if (!ew_harm_finite3(o) || !(t > 0.0f)) continue;
                    for (int c = 0; c < 3; c++) o[c] *= 1.0f + t;
                }
                break;
            }
            }
        }
    } else {
        for (int64_t y = begin; y < end; y++)
            for (int x = 0; x < w; x++) {
                const long j = (long)y * w + x;
                switch (h->step) {
                case EW_HARM_DEMOD: ew_harm_demod_px(j, a); break;
                case EW_HARM_REMOD: ew_harm_remod_px(j, a); break;
                case EW_HARM_STATS: ew_harm_stats_px(x, (int)y, a); break;
                case EW_HARM_SUM_H: ew_harm_sum_h_px(x, (int)y, a); break;
                case EW_HARM_SUM_V: ew_harm_sum_v_px(x, (int)y, a); break;
                case EW_HARM_GIVE: ew_harm_give_px(x, (int)y, a); break;
                case EW_HARM_SPREAD_H: ew_harm_spread_h_px(x, (int)y, a); break;
                case EW_HARM_SPREAD_V: ew_harm_spread_v_px(x, (int)y, a); break;
                case EW_HARM_TAKE: ew_harm_take_px(j, a); break;
                case EW_HARM_SCALE: ew_harm_scale_px(j, a); break;
                default: ew_harm_blend_px(x, (int)y, a); break;
                }
            }
    }
    free(buf);
}

static void cpu_harm(ew_device *dev, int step, const ew_harm_args *a) {
    harm_job h = {step, a};
    ew_pool_run(dev->pool, a->height, 0, harm_rows, &h);
}

typedef struct {
    const ew_temporal_params *p;
    const ew_temporal_buffers *b;
} temporal_job;

static void temporal_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const temporal_job *j = (const temporal_job *)ctx;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < j->p->width; x++) ew_temporal_px(x, (int)y, j->p, j->b);
}

static void cpu_temporal(ew_device *dev, const ew_temporal_params *p, const ew_temporal_buffers *b) {
    temporal_job j = {p, b};
    ew_pool_run(dev->pool, p->height, 0, temporal_rows, &j);
}

/* ---- the per-pixel GuideNet entries ------------------------------------ */
static void input_rows_shifted(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_gn_input_args *a = (const ew_gn_input_args *)ctx;
    for (int64_t y = a->y0 + begin; y < a->y0 + end; y++) {
        float *dst = a->dst + (y - a->y0) * a->rs;
        const long j0 = (long)y * a->width;
        for (int x = 0; x < a->width; x++)
            ew_gn_input_px(j0 + x, a->color, a->albedo, a->normal, a->depth, a->depth_scale, dst + x, a->ps);
    }
}

static void cpu_gn_input(ew_device *dev, const ew_gn_input_args *a) {
    /* the pool hands out [0, n): shift to the band's rows */
    ew_pool_run(dev->pool, a->y1 - a->y0, 0, input_rows_shifted, (void *)a);
}

typedef struct {
    long n;
    int ngrids;
    float *outputs;
} guides_job;

static void guides_range(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const guides_job *g = (const guides_job *)ctx;
    for (int64_t j = begin; j < end; j++) ew_nbg_guide_px((long)j, g->n, g->ngrids, g->outputs);
}

static void cpu_nbg_guides(ew_device *dev, long n, int ngrids, float *outputs) {
    guides_job g = {n, ngrids, outputs};
    ew_pool_run(dev->pool, n, 16384, guides_range, &g);
}

static void blend_range(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_nbg_blend_args *a = (const ew_nbg_blend_args *)ctx;
    for (int64_t j = begin; j < end; j++) ew_nbg_blend_px((long)j, a->s, a->ngrids, a->outputs, a->n, a->sliced, a->acc);
}

static void cpu_nbg_blend(ew_device *dev, const ew_nbg_blend_args *a) {
    ew_pool_run(dev->pool, a->n, 16384, blend_range, (void *)a);
}

const ew_backend ew_cpu_backend = {
    .name = "cpu",
    .bgrid_splat = ew_cpu_bgrid_splat,
    .bgrid_slice = ew_cpu_bgrid_slice,
    .denoise_prepare = cpu_denoise_prepare,
    .denoise_finish = cpu_denoise_finish,
    .denoise_refine_guide = cpu_denoise_refine_guide,
    .outlier_guided = cpu_outlier_guided,
    .harm = cpu_harm,
    .temporal = cpu_temporal,
    /* edge-aware filters (cpu_filters.c) */
    .bf_brute = ew_cpu_bf_brute,
    .bf_separable = ew_cpu_bf_separable,
    .pyr_down = ew_cpu_pyr_down,
    .pyr_up = ew_cpu_pyr_up,
    .pyr_row_hooks = 1,
    .dof_attributes = ew_cpu_dof_attributes,
    /* neural bilateral grid (the convolution: cpu_conv.c) */
    .conv5 = ew_cpu_conv5,
    .gn_input = cpu_gn_input,
    .nbg_guides = cpu_nbg_guides,
    .nbg_blend = cpu_nbg_blend,
    /* every kernel of EW_KERNEL_LIST (cpu_kernels.c) */
    .run = ew_cpu_run,
    /* device memory (cpu_memory.c) */
    .mem_alloc = ew_cpu_mem_alloc,
    .mem_free = ew_cpu_mem_free,
    .mem_upload = ew_cpu_mem_upload,
    .mem_download = ew_cpu_mem_download,
    .mem_copy = ew_cpu_mem_copy,
    .mem_zero = ew_cpu_mem_zero,
    .sync = ew_cpu_sync,
    .reduce_rows = ew_cpu_reduce_rows,
    .view_pack = ew_cpu_view_pack,
    .view_unpack = ew_cpu_view_unpack,
    .device_release = ew_cpu_device_release,
};
