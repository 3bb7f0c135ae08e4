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

#include <limits.h>
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
    const long is = b->in_stride ? b->in_stride : b->width;
    for (int64_t y = begin; y < end; y++)
        for (long x = 0; x < b->width; x++) ew_denoise_prepare_px((long)y * b->width + x, (long)y * is + x, b);
}

static void finish_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const ew_denoise_buffers *b = ((const cpu_job *)ctx)->b;
    const long is = b->in_stride ? b->in_stride : b->width;
    for (int64_t y = begin; y < end; y++)
        for (long x = 0; x < b->width; x++) ew_denoise_finish_px((long)y * b->width + x, (long)y * is + x, b);
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
            float *removed = b->removed ? b->removed + j : NULL;
            if (removed) ew_store_sparse(removed, 0.0f);
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
            if (b->removed) ew_store_sparse(b->removed + j, 0.0f);
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

/* acc[x] = ew_harm_box_h's sum over v[x - r .. x + r] (a row of w floats):
 * the row with r zeros on either side, the sums of b consecutive taps from
 * every start once, then the blocks of each window; tmp: 2 (w + 2 r) floats */
static void harm_box_row(float *acc, const float *v, int w, int r, float *tmp) {
    const int b = ew_harm_box_block(r), n = 2 * r + 1;
    const long padded = (long)w + 2 * r, starts = padded - b + 1;
    float *p = tmp, *blk = tmp + padded;
    memset(p, 0, (size_t)r * sizeof(float));
    memcpy(p + r, v, (size_t)w * sizeof(float));
    memset(p + r + w, 0, (size_t)r * sizeof(float));
    memset(blk, 0, (size_t)starts * sizeof(float));
    for (int i = 0; i < b; i++) harm_add_shifted(blk, p, 0, starts, i);
    memset(acc, 0, (size_t)w * sizeof(float));
    for (int k = 0; k < n / b; k++) harm_add_shifted(acc, blk, 0, w, (long)k * b);
}

/* SUM_H's row from pixel j0 into dst: the output's luminance taps (into
 * row, w floats) summed along it over radius r (tmp: harm_box_row's) */
static void harm_sum_row(const ew_harm_args *a, long j0, int r, float *dst, float *row, float *tmp) {
    for (int x = 0; x < a->width; x++) row[x] = ew_harm_lum_tap(a, j0 + x);
    harm_box_row(dst, row, a->width, r, tmp);
}

/* A thread's column sums of blocks of rows (ew_harm_box_v's blocks), each
 * computed once for the run of rows the thread takes: the block starting
 * at row k0 sits in slot k0 mod (2 r + 1), which no other block a window
 * needs at the same time shares. */
typedef struct {
    float *rows; /* (2 r + 1) x w */
    int *held;   /* the first row of each slot's block, or INT_MIN */
} harm_col_ring;

/* acc[x] = ew_harm_box_v's sum over rows y - r .. y + r of column x of v */
static void harm_box_col(float *acc, const float *v, int w, int h, int y, int r, harm_col_ring *ring) {
    const int b = ew_harm_box_block(r), n = 2 * r + 1;
    memset(acc, 0, (size_t)w * sizeof(float));
    for (int k0 = y - r; k0 <= y + r; k0 += b) {
        const int slot = ((k0 % n) + n) % n;
        float *blk = ring->rows + (size_t)slot * (size_t)w;
        if (ring->held[slot] != k0) {
            memset(blk, 0, (size_t)w * sizeof(float));
            for (int yy = ew_maxi(k0, 0); yy <= ew_mini(k0 + b - 1, h - 1); yy++)
                harm_add_shifted(blk, v + (long)yy * w, 0, w, 0);
            ring->held[slot] = k0;
        }
        harm_add_shifted(acc, blk, 0, w, 0);
    }
}

/* DEMOD over contiguous RGB floats: rad[i] = col[i] / the albedo factor
 * (as ew_harm_demod_px; no albedo: / 1) */
static EW_MULTIVERSION void harm_demod_span(float *EW_RESTRICT rad, const float *EW_RESTRICT col,
                                            const float *EW_RESTRICT alb, long n) {
    if (alb)
        for (long i = 0; i < n; i++) rad[i] = col[i] / ew_harm_albedo_factor(alb[i]);
    else
        for (long i = 0; i < n; i++) rad[i] = col[i] / 1.0f;
}

/* REMOD's RGB for w pixels of contiguous RGB, as ew_harm_remod_px */
static EW_MULTIVERSION void harm_remod_span(float *EW_RESTRICT out, const float *EW_RESTRICT col,
                                            const float *EW_RESTRICT r0, const float *EW_RESTRICT r1,
                                            const float *EW_RESTRICT alb, long w) {
    /* the choice as a mask on the bits, the two cases in loops of their
     * own: a float select or a test inside keeps the loop scalar */
    if (alb)
        for (long x = 0; x < w; x++) {
            const int keep = -ew_harm_kept(r0 + 3 * x, r1 + 3 * x);
            for (int c = 0; c < 3; c++) {
                const float m = r1[3 * x + c] * ew_harm_albedo_factor(alb[3 * x + c]);
                out[3 * x + c] = ew_bits_to_float((ew_float_to_bits(col[3 * x + c]) & keep) | (ew_float_to_bits(m) & ~keep));
            }
        }
    else
        for (long x = 0; x < w; x++) {
            const int keep = -ew_harm_kept(r0 + 3 * x, r1 + 3 * x);
            for (int c = 0; c < 3; c++) {
                const float m = r1[3 * x + c] * 1.0f;
                out[3 * x + c] = ew_bits_to_float((ew_float_to_bits(col[3 * x + c]) & keep) | (ew_float_to_bits(m) & ~keep));
            }
        }
}

/* DEMOD and REMOD of row y; rgb: 9 w floats (the colour's RGB gathered
 * when it has more channels, REMOD's RGB before the other channels are
 * copied, the rejected row when REMOD writes over it) */
static void harm_modulate_row(const ew_harm_args *a, int step, int y, float *rgb) {
    const long w = a->width, cc = a->channels, j0 = (long)y * w;
    const float *col = a->color + j0 * cc, *alb = a->albedo ? a->albedo + j0 * 3 : NULL;
    if (cc != 3) {
        for (long x = 0; x < w; x++)
            for (int c = 0; c < 3; c++) rgb[3 * x + c] = col[x * cc + c];
        col = rgb;
    }
    if (step == EW_HARM_DEMOD) {
        harm_demod_span(a->radiance + j0 * 3, col, alb, 3 * w);
        return;
    }
    const long ck = ew_harm_cch(a);
    float *out = ck != 3 ? rgb + 3 * w : a->clamped + j0 * 3;
    const float *r1 = a->rejected + j0 * 3;
    if (r1 == out) { /* in place (harm.h): the span's inputs and output must not alias */
        memcpy(rgb + 6 * w, r1, 3 * (size_t)w * sizeof(float));
        r1 = rgb + 6 * w;
    }
    harm_remod_span(out, col, a->radiance + j0 * 3, r1, alb, w);
    if (ck != 3) {
        const float *c0 = a->color + j0 * cc;
        float *o = a->clamped + j0 * ck;
        for (long x = 0; x < w; x++)
            for (long c = 0; c < ck; c++) o[x * ck + c] = c < 3 ? out[3 * x + c] : c0[x * cc + c];
    }
}

/* t[i], l[i] = ew_harm_residual's and ew_harm_lin_residual's values for
 * the input c[i] and the output o[i], over contiguous floats (vectorised) */
static EW_MULTIVERSION void harm_residual_span(float *EW_RESTRICT t, float *EW_RESTRICT l, const float *EW_RESTRICT c,
                                               const float *EW_RESTRICT o, long n) {
    for (long i = 0; i < n; i++) {
        t[i] = ew_harm_tone_diff(c[i], o[i]);
        l[i] = ew_harm_finite_or0(c[i] - o[i]);
    }
}

/* rows t (T residual) and l (linear) of row y, 3 floats a pixel, as
 * ew_harm_residuals; rgb: 3 w floats for the input's RGB when it has more
 * channels */
static void harm_residual_row(const ew_harm_args *a, int y, float *t, float *l, float *rgb) {
    const long w = a->width, cc = ew_harm_cch(a);
    const float *c = a->clamped + (long)y * w * cc;
    if (cc != 3) {
        for (long x = 0; x < w; x++) {
            rgb[3 * x] = c[x * cc];
            rgb[3 * x + 1] = c[x * cc + 1];
            rgb[3 * x + 2] = c[x * cc + 2];
        }
        c = rgb;
    }
    harm_residual_span(t, l, c, a->out + (long)y * w * 3, 3 * w);
}

static void harm_stats_rows(const ew_harm_args *a, int64_t begin, int64_t end, float *buf) {
    const int w = a->width, h = a->height;
    float *t0 = buf, *l0 = t0 + 3 * (size_t)w, *t1 = l0 + 3 * (size_t)w, *l1 = t1 + 3 * (size_t)w;
    float *rgb = l1 + 3 * (size_t)w;
    for (int64_t yl = begin; yl < end; yl++) {
        const int y = (int)yl;
        /* t0/l0: row y; t1/l1: row y + 1, or y - 1 at the last row (its block) */
        if (yl == begin) {
            harm_residual_row(a, y, t0, l0, rgb);
        } else {
            float *tt = t0, *ll = l0;
            t0 = t1; l0 = l1; t1 = tt; l1 = ll;
        }
        const int last = y + 1 >= h, other = last ? y - 1 : y + 1;
        if (other >= 0) harm_residual_row(a, other, t1, l1, rgb);
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

/* ew_harm_stats_from's statistics for the pixels x in [0, n) of a row with
 * a row below it and a pixel right of each (so every neighbour and the
 * block at (x, y) exist) into s0..s5 (six planes of the row): t0/l0 the
 * row's residuals, t1/l1 the next row's (3 floats a pixel). Each statistic
 * adds the same terms in the same order as ew_harm_stats_from, without its
 * tests for the neighbours, so that the loop vectorises: the same bits. */
static EW_MULTIVERSION void harm_stats_span(float *EW_RESTRICT s0, float *EW_RESTRICT s1, float *EW_RESTRICT s2,
                                            float *EW_RESTRICT s3, float *EW_RESTRICT s4, float *EW_RESTRICT s5,
                                            const float *EW_RESTRICT t0, const float *EW_RESTRICT t1,
                                            const float *EW_RESTRICT l0, const float *EW_RESTRICT l1, long n) {
    for (long x = 0; x < n; x++) {
        float sq = 0.0f, cross = 0.0f, hh2 = 0.0f, lin2 = 0.0f, th2 = 0.0f;
        for (int c = 0; c < 3; c++) {
            const long i = 3 * x + c;
            const float r = t0[i];
            sq += r * r;
            cross += r * t0[i + 3];
            cross += r * t1[i];
            const float hh = 0.5f * (l0[i] - l0[i + 3] - l1[i] + l1[i + 3]);
            hh2 += hh * hh;
            const float th = 0.5f * (t0[i] - t0[i + 3] - t1[i] + t1[i + 3]);
            th2 += th * th;
            lin2 += 0.25f * (l0[i] * l0[i] + l0[i + 3] * l0[i + 3] + l1[i] * l1[i] + l1[i + 3] * l1[i + 3]);
        }
        cross = cross / 2.0f;
        s0[x] = sq;
        s1[x] = cross;
        s2[x] = cross * cross;
        s3[x] = hh2;
        s4[x] = lin2;
        s5[x] = th2;
    }
}

/* alpha[x] = ew_harm_alpha of the window sums for x in [0, w): sums holds
 * them as six planes of w floats */
static EW_MULTIVERSION void harm_alpha_span(float *EW_RESTRICT alpha, const float *EW_RESTRICT sums, long w,
                                            const ew_harm_args *a) {
    /* the parameters as locals: a store to alpha cannot change them */
    const float z = a->z, strength = a->strength, theta = a->theta, kappa = a->kappa, theta_n = a->theta_n,
                tone_share = a->tone_share, fade = a->fade;
    const float *EW_RESTRICT p0 = sums, *EW_RESTRICT p1 = sums + w, *EW_RESTRICT p2 = sums + 2 * w;
    const float *EW_RESTRICT p3 = sums + 3 * w, *EW_RESTRICT p4 = sums + 4 * w, *EW_RESTRICT p5 = sums + 5 * w;
    for (long x = 0; x < w; x++)
        alpha[x] = ew_harm_alpha(p0[x], p1[x], p2[x], p3[x], p4[x], p5[x], z, strength, theta, kappa, theta_n,
                                 tone_share, fade);
}

/* ew_harm_blend_mix for w pixels of RGB (colour of 3 channels, give set):
 * the pixels it leaves alone selected by masks, the others mixed, so that
 * the loop vectorises; the same bits. give is stored as ew_store_sparse
 * does, a span of HARM_MIX_SPAN pixels at a time: not at all where it held
 * zeros and still does */
#define HARM_MIX_SPAN 256
static EW_MULTIVERSION void harm_mix_span(float *EW_RESTRICT out, float *EW_RESTRICT give,
                                          const float *EW_RESTRICT in, const float *EW_RESTRICT alpha, long w) {
    for (long x0 = 0; x0 < w; x0 += HARM_MIX_SPAN) {
        const long n = w - x0 < HARM_MIX_SPAN ? w - x0 : HARM_MIX_SPAN;
        float g[HARM_MIX_SPAN];
        int nonzero = 0;
        for (long k = 0; k < n; k++) {
            const long x = x0 + k;
            const float al = alpha[x];
            const int mix = -((!(al >= 1.0f)) & ew_harm_finite_bits(in[3 * x]) & ew_harm_finite_bits(in[3 * x + 1]) &
                              ew_harm_finite_bits(in[3 * x + 2]));
            g[k] = ew_harm_sel(mix, give[x] * al, give[x]);
            nonzero |= (g[k] != 0.0f) | (give[x] != 0.0f);
            for (int c = 0; c < 3; c++) {
                const long i = 3 * x + c;
                out[i] = ew_harm_sel(mix, in[i] + al * (out[i] - in[i]), out[i]);
            }
        }
        if (nonzero) memcpy(give + x0, g, (size_t)n * sizeof *g);
    }
}

/* ---- STATS and BLEND in bands of rows (EW_HARM_STATS_BLEND) ----------
 * The blend of row y reads the statistics of rows y - r .. y + r, and the
 * statistics of row s read the output's rows s and s + 1 (s - 1 at the last
 * row), which the blend rewrites in place. So each band first computes the
 * statistics of its rows that read another band's output — the r rows above
 * it, its last row and the r below (its edges, 2 r + 1 rows) — every band
 * before any blends; then it goes down its rows, computing its own rows'
 * statistics r rows ahead into a ring of 2 r + 1 rows and blending each row
 * from them. The per-pixel functions and the order of every sum are STATS'
 * and BLEND's (the same bits): the statistics held are a ring and the edges
 * of each band instead of a frame of 6 floats a pixel. */

/* Two rows of residuals (T and linear, 3 w floats each) kept between
 * consecutive rows of statistics, which share one. */
typedef struct {
    float *t[2], *l[2], *rgb;
    int row[2];
} harm_res_rows;

/* the slot holding row y's residuals, computed unless held; never the
 * slot holding row keep */
static int harm_res_get(const ew_harm_args *a, harm_res_rows *c, int y, int keep) {
    for (int i = 0; i < 2; i++)
        if (c->row[i] == y) return i;
    const int i = c->row[0] == keep ? 1 : 0;
    harm_residual_row(a, y, c->t[i], c->l[i], c->rgb);
    c->row[i] = y;
    return i;
}

/* The statistics of row y into dst as EW_HARM_STATS_FLOATS planes of w
 * floats (statistic k of pixel x at dst[k w + x]: the blend's loops read
 * each contiguously), the values harm_stats_rows writes */
static void harm_stats_row_into(const ew_harm_args *a, int y, float *dst, harm_res_rows *c) {
    const int w = a->width, h = a->height;
    const int last = y + 1 >= h, other = last ? y - 1 : y + 1;
    const int i0 = harm_res_get(a, c, y, INT_MIN);
    const float *t0 = c->t[i0], *l0 = c->l[i0], *t1 = NULL, *l1 = NULL;
    if (other >= 0) {
        const int i1 = harm_res_get(a, c, other, y);
        t1 = c->t[i1];
        l1 = c->l[i1];
    }
    const size_t wz = (size_t)w;
    int x = 0;
    if (!last && w > 1) { /* every neighbour there: the vectorised row */
        harm_stats_span(dst, dst + wz, dst + 2 * wz, dst + 3 * wz, dst + 4 * wz, dst + 5 * wz, t0, t1, l0, l1, w - 1);
        x = w - 1;
    }
    /* the last column (the last row: every pixel) through the per-pixel
     * function, one pixel's statistics at a time */
    float px[EW_HARM_STATS_FLOATS];
    ew_harm_args ad = *a;
    ad.stats = px;
    const float *bt0 = last ? t1 : t0, *bt1 = last ? t0 : t1, *bl0 = last ? l1 : l0, *bl1 = last ? l0 : l1;
    for (; x < w; x++) {
        const int bx = x + 1 < w ? x : x - 1, block = bx >= 0 && other >= 0;
        const float *tb[4], *lb[4];
        if (block) {
            tb[0] = bt0 + 3 * bx; tb[1] = bt0 + 3 * (bx + 1); tb[2] = bt1 + 3 * bx; tb[3] = bt1 + 3 * (bx + 1);
            lb[0] = bl0 + 3 * bx; lb[1] = bl0 + 3 * (bx + 1); lb[2] = bl1 + 3 * bx; lb[3] = bl1 + 3 * (bx + 1);
        }
        ew_harm_stats_from(0, &ad, t0 + 3 * x, x + 1 < w ? t0 + 3 * (x + 1) : NULL, last ? NULL : t1 + 3 * x,
                           block ? tb : NULL, block ? lb : NULL, l0 + 3 * x);
        for (int k = 0; k < EW_HARM_STATS_FLOATS; k++) dst[(size_t)k * wz + (size_t)x] = px[k];
    }
}

typedef struct {
    const ew_harm_args *a;
    int rows;     /* rows a band (the last may have fewer) */
    float *edges; /* a band's 2 r + 1 edge rows of statistics, band after band */
    float *work;  /* a band's ring (2 r + 1 rows), column and window sums, residual rows */
} harm_band_job;

static size_t harm_band_work_floats(int w, int r) {
    return ((size_t)(2 * r + 1) + 2) * EW_HARM_STATS_FLOATS * (size_t)w + 15 * (size_t)w;
}

/* band k's rows [y0, y1) */
static void harm_band_rows(const harm_band_job *j, int k, int *y0, int *y1) {
    *y0 = k * j->rows;
    *y1 = ew_mini(*y0 + j->rows, j->a->height);
}

/* band k's edge row of statistics s (above it or from its last row on), or
 * NULL for the rows it computes itself */
static float *harm_band_edge(const harm_band_job *j, int k, int s) {
    const int r = j->a->radius, w = j->a->width;
    int y0, y1;
    harm_band_rows(j, k, &y0, &y1);
    const size_t row = (size_t)EW_HARM_STATS_FLOATS * (size_t)w, base = (size_t)k * (size_t)(2 * r + 1);
    if (s < y0) return j->edges + (base + (size_t)(s - (y0 - r))) * row;
    if (s >= y1 - 1) return j->edges + (base + (size_t)r + (size_t)(s - (y1 - 1))) * row;
    return NULL;
}

static harm_res_rows harm_band_res(const harm_band_job *j, int k) {
    const int r = j->a->radius;
    const size_t w = (size_t)j->a->width;
    float *p = j->work + harm_band_work_floats((int)w, r) * (size_t)k + ((size_t)(2 * r + 1) + 2) * EW_HARM_STATS_FLOATS * w;
    harm_res_rows c = {{p, p + 6 * w}, {p + 3 * w, p + 9 * w}, p + 12 * w, {INT_MIN, INT_MIN}};
    return c;
}

static void harm_band_edges(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const harm_band_job *j = (const harm_band_job *)ctx;
    const int r = j->a->radius, h = j->a->height;
    for (int64_t k = begin; k < end; k++) {
        int y0, y1;
        harm_band_rows(j, (int)k, &y0, &y1);
        harm_res_rows c = harm_band_res(j, (int)k);
        for (int s = ew_maxi(y0 - r, 0); s < y0; s++) harm_stats_row_into(j->a, s, harm_band_edge(j, (int)k, s), &c);
        for (int s = y1 - 1; s <= ew_mini(y1 - 1 + r, h - 1); s++)
            harm_stats_row_into(j->a, s, harm_band_edge(j, (int)k, s), &c);
    }
}

static void harm_band_blend(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const harm_band_job *j = (const harm_band_job *)ctx;
    const ew_harm_args *a = j->a;
    const int r = a->radius, h = a->height, w = a->width, n = 2 * r + 1;
    const size_t k6 = EW_HARM_STATS_FLOATS, row = k6 * (size_t)w;
    for (int64_t k = begin; k < end; k++) {
        int y0, y1;
        harm_band_rows(j, (int)k, &y0, &y1);
        float *ring = j->work + harm_band_work_floats(w, r) * (size_t)k, *col = ring + (size_t)n * row, *acc = col + row;
        harm_res_rows c = harm_band_res(j, (int)k);
        int next = y0; /* the next of the band's own rows of statistics, y0 .. y1 - 2 */
        for (int y = y0; y < y1; y++) {
            for (; next <= ew_mini(y + r, y1 - 2); next++)
                harm_stats_row_into(a, next, ring + (size_t)(next % n) * row, &c);
            /* as BLEND: the window's columns (its rows in order), then along the row */
            memset(col, 0, row * sizeof(float));
            for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, h - 1); yy++) {
                const float *st = harm_band_edge(j, (int)k, yy);
                harm_add_shifted(col, st ? st : ring + (size_t)(yy % n) * row, 0, (long)row, 0);
            }
            for (size_t i = 0; i < k6; i++) harm_row_window(acc + i * (size_t)w, col + i * (size_t)w, w, r, 1);
            /* alpha of the whole row (vectorised) into the column sums' place, then the mix */
            harm_alpha_span(col, acc, w, a);
            const long j0 = (long)y * w;
            if (ew_harm_cch(a) == 3 && a->give)
                harm_mix_span(a->out + j0 * 3, a->give + j0, a->clamped + j0 * 3, col, w);
            else
                for (int x = 0; x < w; x++) ew_harm_blend_mix(j0 + x, a, col[x]);
        }
    }
}

/* STATS then BLEND in bands; 0 when out of memory (nothing done) */
static int harm_stats_blend_bands(ew_device *dev, const ew_harm_args *a) {
    const int threads = ew_pool_threads(dev->pool), r = a->radius, w = a->width, h = a->height;
    /* two bands a thread, of at least 8 windows' rows: a band holds about
     * 22 rows' worth of statistics (ring, edges, sums), so with many threads
     * the bands stay under a third of the frame's, and the edges' rows
     * computed twice under an eighth of the statistics */
    int rows = a->band_rows > 0 ? a->band_rows : ew_maxi((h + 2 * threads - 1) / (2 * threads), 8 * (2 * r + 1));
    rows = ew_maxi(ew_mini(rows, h), 1);
    const int bands = (h + rows - 1) / rows;
    const size_t edges = (size_t)bands * (size_t)(2 * r + 1) * EW_HARM_STATS_FLOATS * (size_t)w;
    /* mapped by itself, as the sweeps' scratch: a program that keeps freed
     * heap blocks for reuse (the CLI) would hold its 8 MB at 4K through the
     * energy return that follows */
    const size_t bytes = (edges + (size_t)bands * harm_band_work_floats(w, r)) * sizeof(float);
    float *mem = (float *)ew__scratch_alloc(bytes);
    if (!mem) return 0;
    harm_band_job j = {a, rows, mem, mem + edges};
    ew_pool_run(dev->pool, bands, 1, harm_band_edges, &j);
    ew_pool_run(dev->pool, bands, 1, harm_band_blend, &j);
    ew__scratch_free(mem, bytes);
    return 1;
}

static void harm_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const harm_job *h = (const harm_job *)ctx;
    const ew_harm_args *a = h->a;
    const int w = a->width, H = a->height;
    const long n = (long)w * H;
    float *buf = NULL;
    const int gr = a->give_radius, gn = 2 * gr + 1;
    harm_col_ring ring = {NULL, NULL};
    switch (h->step) {
    case EW_HARM_DEMOD:
    case EW_HARM_REMOD: buf = (float *)malloc(9 * (size_t)w * sizeof(float)); break;
    case EW_HARM_STATS: buf = (float *)malloc(15 * (size_t)w * sizeof(float)); break;
    case EW_HARM_BLEND: buf = (float *)malloc(2 * (size_t)EW_HARM_STATS_FLOATS * (size_t)w * sizeof(float)); break;
    case EW_HARM_SUM_H:
    case EW_HARM_SPREAD_H: buf = (float *)malloc((3 * (size_t)w + 4 * (size_t)gr) * sizeof(float)); break;
    case EW_HARM_SUM_V:
    case EW_HARM_SPREAD_V:
        buf = (float *)malloc((size_t)w * (1 + (size_t)gn) * sizeof(float));
        ring.held = (int *)malloc((size_t)gn * sizeof(int));
        if (!ring.held) {
            free(buf);
            buf = NULL;
        } else {
            ring.rows = buf + w;
            for (int i = 0; i < gn; i++) ring.held[i] = INT_MIN;
        }
        break;
    default: break;
    }
    const int rows = buf != NULL;
    if (rows && h->step == EW_HARM_STATS) {
        harm_stats_rows(a, begin, end, buf);
    } else if (rows && (h->step == EW_HARM_DEMOD || h->step == EW_HARM_REMOD)) {
        for (int64_t y = begin; y < end; y++) harm_modulate_row(a, h->step, (int)y, buf);
    } else if (rows) {
        for (int64_t yl = begin; yl < end; yl++) {
            const int y = (int)yl;
            const long j0 = (long)y * w;
            switch (h->step) {
            case EW_HARM_BLEND: {
                /* as ew_harm_blend_px: the window's columns of the whole row
                 * (its rows in order), then those along the row (offsets in order) */
                const int r = a->radius;
                const size_t k = EW_HARM_STATS_FLOATS;
                float *col = buf + k * (size_t)w;
                memset(col, 0, k * (size_t)w * sizeof(float));
                for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, H - 1); yy++)
                    harm_add_shifted(col, a->stats + (long)yy * w * (long)k, 0, (long)(k * (size_t)w), 0);
                harm_row_window(buf, col, w, r, (int)k);
                for (int x = 0; x < w; x++) ew_harm_blend_apply(j0 + x, a, buf + (size_t)x * k);
                break;
            }
            case EW_HARM_SUM_H: /* as ew_harm_sum_h_px */
                harm_sum_row(a, j0, gr, a->spread + j0, buf, buf + w);
                break;
            case EW_HARM_SUM_V: /* as ew_harm_sum_v_px */
                harm_box_col(a->spread + n + j0, a->spread, w, H, y, gr, &ring);
                break;
            case EW_HARM_SPREAD_H: /* as ew_harm_spread_h_px */
                harm_box_row(a->spread + j0, a->give + j0, w, gr, buf + w);
                break;
            default: /* EW_HARM_SPREAD_V, as ew_harm_spread_v_px */
                harm_box_col(buf, a->spread, w, H, y, gr, &ring);
                for (int x = 0; x < w; x++) ew_harm_spread_at(j0 + x, a, buf[x]);
                break;
            }
        }
    } else {
        for (int64_t y = begin; y < end; y++)
            for (int x = 0; x < w; x++) ew_harm_px(h->step, x, (int)y, a);
    }
    free(buf);
    free(ring.held);
}

/* ---- the energy return and the pilot's blend in bands of rows -------
 * (EW_HARM_RETURN, EW_HARM_PILOT_HV). Their box sums along the row of the
 * rows a band's windows reach (r above and below it) go into a thread's
 * scratch instead of a frame's plane, and the column sums read them there:
 * the same sums in the same order (harm_box_row and harm_box_col; the
 * pilot's through its per-pixel functions over the band as a frame of its
 * own, whose top and bottom are the frame's wherever a window is clipped),
 * so the same bits as the steps over the frame. Each sweep over the bands
 * finishes before the next starts: GIVE reads the output before
 * SPREAD_V scales it. */
typedef struct {
    const ew_harm_args *a;
    int step; /* EW_HARM_SUM_H (sums, GIVE), EW_HARM_SPREAD_H (sums, SPREAD_V), EW_HARM_PILOT_H */
    int rows, r;
    size_t per_thread; /* floats of scratch a thread */
    float *mem;
} harm_sweep_job;

/* a thread's scratch: 2 planes of a band's rows with their margins, a row
 * of column sums, harm_box_row's 2 (w + 2 r), a ring of 2 r + 1 rows and
 * its 2 r + 1 first rows (ints, a float's size) */
_Static_assert(sizeof(int) == sizeof(float), "the ring's first rows take a float's place each");
static size_t harm_sweep_floats(int w, int rows, int r) {
    return 2 * (size_t)(rows + 2 * r) * (size_t)w + (size_t)w + 2 * ((size_t)w + 2 * (size_t)r) +
           (size_t)(2 * r + 1) * ((size_t)w + 1);
}

static void harm_sweep_bands(void *ctx, int64_t begin, int64_t end, int tid) {
    const harm_sweep_job *j = (const harm_sweep_job *)ctx;
    const ew_harm_args *a = j->a;
    const int w = a->width, h = a->height, r = j->r, n = 2 * r + 1;
    float *sums = j->mem + j->per_thread * (size_t)tid;
    float *col = sums + 2 * (size_t)(j->rows + 2 * r) * (size_t)w, *tmp = col + w, *ringrows = tmp + 2 * ((size_t)w + 2 * r);
    int *held = (int *)(void *)(ringrows + (size_t)n * (size_t)w);
    for (int64_t k = begin; k < end; k++) {
        const int y0 = (int)k * j->rows, y1 = ew_mini(y0 + j->rows, h);
        const int lo = ew_maxi(y0 - r, 0), hi = ew_mini(y1 + r, h), bh = hi - lo;
        if (j->step == EW_HARM_PILOT_H) {
            /* the band with its margins as a frame: PILOT_H's and PILOT_V's
             * own functions over it */
            ew_harm_args b = *a;
            const long at = (long)lo * w;
            b.height = bh;
            b.pilot = a->pilot + at * 3;
            b.out = a->out + at * 3;
            b.clamped = a->clamped + at * ew_harm_cch(a);
            b.give = a->give ? a->give + at : NULL;
            b.spread = sums;
            for (int y = 0; y < bh; y++)
                for (int x = 0; x < w; x++) ew_harm_pilot_h_px(x, y, &b);
            for (int y = y0 - lo; y < y1 - lo; y++)
                for (int x = 0; x < w; x++) ew_harm_pilot_v_px(x, y, &b);
            continue;
        }
        for (int y = lo; y < hi; y++) {
            const long j0 = (long)y * w;
            float *dst = sums + (size_t)(y - lo) * (size_t)w;
            if (j->step == EW_HARM_SUM_H)
                harm_sum_row(a, j0, r, dst, col, tmp);
            else /* as SPREAD_H */
                harm_box_row(dst, a->give + j0, w, r, tmp);
        }
        harm_col_ring ring = {ringrows, held};
        for (int i = 0; i < n; i++) held[i] = INT_MIN;
        for (int y = y0; y < y1; y++) {
            const long j0 = (long)y * w;
            harm_box_col(col, sums, w, bh, y - lo, r, &ring);
            if (j->step == EW_HARM_SUM_H)
                for (int x = 0; x < w; x++) ew_harm_give_at(j0 + x, a, col[x]); /* as SUM_V, GIVE */
            else
                for (int x = 0; x < w; x++) ew_harm_spread_at(j0 + x, a, col[x]); /* as SPREAD_V */
        }
    }
}

/* EW_HARM_RETURN or EW_HARM_PILOT_HV in bands; 0 when out of memory
 * (nothing done) */
static int harm_sweeps(ew_device *dev, int step, const ew_harm_args *a) {
    const int threads = ew_pool_threads(dev->pool), w = a->width, h = a->height;
    const int r = step == EW_HARM_RETURN ? a->give_radius : a->radius;
    /* bands of 4 windows' rows, at least 64 (the margins' sums are computed
     * twice: an eighth to a quarter more of them), so that a thread's scratch
     * stays a few MiB at 4K: two bands a thread took 36 MiB there, at the
     * peak of a pilot's own stage */
    int rows = a->band_rows > 0 ? a->band_rows : ew_maxi(4 * (2 * r + 1), 64);
    rows = ew_maxi(ew_mini(rows, h), 1);
    const int bands = (h + rows - 1) / rows;
    harm_sweep_job j = {a, 0, rows, r, harm_sweep_floats(w, rows, r), NULL};
    const size_t floats = j.per_thread * (size_t)threads;
    j.mem = (float *)ew__scratch_alloc(floats * sizeof(float));
    if (!j.mem) return 0;
    if (step == EW_HARM_RETURN) {
        j.step = EW_HARM_SUM_H;
        ew_pool_run(dev->pool, bands, 1, harm_sweep_bands, &j);
        j.step = EW_HARM_SPREAD_H;
    } else {
        j.step = EW_HARM_PILOT_H;
    }
    ew_pool_run(dev->pool, bands, 1, harm_sweep_bands, &j);
    ew__scratch_free(j.mem, floats * sizeof(float));
    return 1;
}

static void cpu_harm(ew_device *dev, int step, const ew_harm_args *a) {
    if (step == EW_HARM_RETURN || step == EW_HARM_PILOT_HV) {
        /* out of memory for the bands: the steps over the frame's planes */
        if (!harm_sweeps(dev, step, a)) {
            const int first = step == EW_HARM_RETURN ? EW_HARM_SUM_H : EW_HARM_PILOT_H;
            const int last = step == EW_HARM_RETURN ? EW_HARM_SPREAD_V : EW_HARM_PILOT_V;
            for (int st = first; st <= last; st++) cpu_harm(dev, st, a);
        }
        return;
    }
    if (step == EW_HARM_STATS_BLEND) {
        /* out of memory for the bands: the two steps over the frame's statistics */
        if (!harm_stats_blend_bands(dev, a)) {
            cpu_harm(dev, EW_HARM_STATS, a);
            cpu_harm(dev, EW_HARM_BLEND, a);
        }
        return;
    }
    harm_job h = {step, a};
    /* the column box sums fill their ring of blocks anew at the start of
     * each run of rows: a few long runs, not the pool's many short ones */
    const int threads = ew_pool_threads(dev->pool);
    const int64_t grain = step == EW_HARM_SUM_V || step == EW_HARM_SPREAD_V
                              ? (a->height + 2 * threads - 1) / (2 * threads) : 0;
    ew_pool_run(dev->pool, a->height, grain, harm_rows, &h);
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
        const long j0 = (long)y * (a->in_stride ? a->in_stride : a->width);
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
    .harm_bands = 1,
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
