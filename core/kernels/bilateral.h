/*
 * bilateral.h — the joint bilateral filter of Xu et al. 2024, Eq. 1, with the
 * domain and range functions of its three targets, as per-pixel functions
 * that the brute-force ground truth, the separable approximation, the
 * pyramid filter and a CUDA build all share.
 *
 *   I(p) = sum_q I(q) f_dom(p, q) f_rng(A(p), A(q)) / sum_q f_dom f_rng
 *
 * Every domain function of the paper is a Gaussian whose sigma may depend on
 * the centre's attributes (Eq. 8: the CoC, Eq. 9: the roughness), so a model
 * is "a per-pixel sigma" plus "a range function":
 *
 *   kind   attributes A (per pixel)            domain sigma        range
 *   COLOR  guide colour (1..4 ch)              sigma               exp(-|g_p - g_q|^2 / 2 sigma_r^2)
 *   GI     normal xyz, depth z, sqrt(rough)    (s_a sqrt(a_p)+1)/3 (n_p.n_q)^s_n exp(-s_z z_p|z_p-z_q|) (1-smoothstep(0,.5,|da|))
 *   DEPTH  depth z                             sigma               exp(-s_z z_p |z_p - z_q|)              (Eq. 10)
 *   DOF    D (domain CoC), C (own CoC), px     1/s^2 = 36/D^2 + 1/sigma^2    exp(-18 |p-q|^2 / min(D_p, C_q)^2)  (Eq. 8)
 *   NONE   -                                   sigma               1  (plain Gaussian: the convolution model)
 *
 * Notes on our reading of the paper:
 *  - Eq. 9 writes the roughness factor as smoothstep(0, .5, |..|), which is
 *    0 for equal roughness; the edge-stopping factor meant is one minus it.
 *  - Eq. 8 uses min(A(p), A(q)) with A the CoC diameter. For the foreground
 *    to blur over a sharp background (§4.1) the centre's value is its
 *    *domain* CoC D (its own CoC dilated by the near-field CoCs that cover
 *    it, see dof.h), so attributes carry D and C separately; without a near
 *    field D == C and this is Eq. 8 exactly.
 *  - Normals are unit vectors or zero (no surface: background); two zero
 *    normals match, a zero and a non-zero one do not.
 *
 * Buffers: EW_BF_CH = 4 floats a pixel, up to 3 colour channels premultiplied
 * by a mask M and M itself last: (r M, g M, b M, M). M is 1, or 0 for a
 * missing sample (any channel non-finite in the input). Every filter
 * computes the normalised sum of these 4-vectors and the caller divides by
 * the last one at the end (ew_bf_unpack_image): normalized convolution. For
 * the exact filter this is Eq. 1 over the valid samples; for the pyramid,
 * samples beyond the image border count as (0, 0, 0, 0) with range 1, so it
 * reproduces the exact filter's truncated, renormalised window at borders
 * instead of skewing towards the inside (and missing samples need no
 * branch anywhere).
 *
 * Exponentials and logarithms are ew_fexp2 / ew_fexp / ew_flog2 below
 * (polynomials, about 2e-7 relative error, branch-free so that loops over
 * samples vectorise), used by every method alike, the ground truth included.
 */
#ifndef EW_KERNELS_BILATERAL_H
#define EW_KERNELS_BILATERAL_H

#include "kernels/compat.h"
#include "kernels/fastmath.h"

#define EW_BF_MAX_CH 4  /* channels a filter takes (a 4th, alpha, is passed through) */
#define EW_BF_COLOR 3   /* colour channels filtered */
#define EW_BF_CH 4      /* floats a pixel in the kernels' buffers: 3 colour (times M), M */
#define EW_BF_MAX_ATTR 5

enum { EW_RANGE_COLOR = 0, EW_RANGE_GI = 1, EW_RANGE_DEPTH = 2, EW_RANGE_DOF = 3, EW_RANGE_NONE = 4 };

typedef struct ew_bf_model {
    int kind;
    int channels;          /* meaningful image channels, 1..EW_BF_MAX_CH (buffers hold EW_BF_CH) */
    int attrs;             /* attribute channels: ew_bf_attrs(kind) */
    int radius;            /* largest support radius in pixels (the brute force's window cap) */
    float sigma;           /* COLOR/DEPTH/NONE: domain sigma; DOF: extra Gaussian, 0 = none */
    float inv_2sr2;        /* COLOR: 1 / (2 sigma_r^2) */
    float sigma_alpha;     /* GI: domain radius per sqrt(roughness) */
    float sigma_n;         /* GI: normal exponent */
    float sigma_z;         /* GI, DEPTH: depth factor */
    int use_roughness;     /* GI: compare roughness (specular) or not (diffuse) */
} ew_bf_model;

/* ew_fexp, ew_fexp2, ew_flog2: kernels/fastmath.h */

EW_HD float ew_smoothstep(float e0, float e1, float x) {
    float t = ew_clampf((x - e0) / (e1 - e0), 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

/* ---- the model's functions --------------------------------------------- */

/* Attribute floats per pixel of a kind (COLOR: the guide padded to 4). A
 * function of the kind only, so loops specialised on a kind know it. */
EW_HD int ew_bf_attrs(int kind) {
    return kind == EW_RANGE_COLOR ? 4 : kind == EW_RANGE_GI ? 5 : kind == EW_RANGE_DEPTH ? 1 : kind == EW_RANGE_DOF ? 2 : 0;
}

/* Domain sigma (pixels) at a centre with attributes ap. */
EW_HD float ew_bf_sigma(const ew_bf_model *m, const float *ap) {
    if (m->kind == EW_RANGE_GI) return (m->sigma_alpha * ap[4] + 1.0f) * (1.0f / 3.0f);
    if (m->kind == EW_RANGE_DOF) {
        float d = ap[0];
        if (!(d > 0.0f)) return 0.0f;
        float inv = 36.0f / (d * d);
        if (m->sigma > 0.0f) inv += 1.0f / (m->sigma * m->sigma);
        return 1.0f / sqrtf(inv);
    }
    return m->sigma;
}

/* Support radius of the ground truth at a centre of domain sigma s: the
 * 3-sigma model of the paper, capped by the model's radius. */
EW_HD int ew_bf_support(const ew_bf_model *m, float s) {
    int r = (int)ceilf(3.0f * s - 1e-3f);
    return ew_maxi(0, ew_mini(r, m->radius));
}

/* log2 of the range function f_R(A(p), A(q)) ("energy": <= 0, and
 * EW_BF_NEVER where f_R is 0); d2 = |p - q|^2 in full-resolution pixels
 * (only DOF uses it). kind is m->kind, passed separately so that CPU loops
 * can specialise on a constant. Working in log2 makes f^gamma = 2^(gamma E)
 * free and lets callers batch the exponentials. */
#define EW_BF_NEVER (-1000.0f)
/* rough: GI compares roughness (m->use_roughness; a separate argument so
 * that loops specialised on it have no branch). Every conditional below
 * selects between values already computed, so loops over samples or
 * pixels if-convert and vectorise. */
EW_HD float ew_bf_energy_r(const ew_bf_model *m, int kind, int rough, const float *EW_RESTRICT ap,
                           const float *EW_RESTRICT aq, float d2) {
    if (kind == EW_RANGE_COLOR) { /* written out: 4 lanes for the compiler's SLP */
        const float d0 = ap[0] - aq[0], d1 = ap[1] - aq[1], d2c = ap[2] - aq[2], d3 = ap[3] - aq[3];
        return -1.44269504f * m->inv_2sr2 * ((d0 * d0 + d1 * d1) + (d2c * d2c + d3 * d3));
    }
    if (kind == EW_RANGE_GI) {
        float pp = ap[0] * ap[0] + ap[1] * ap[1] + ap[2] * ap[2];
        float qq = aq[0] * aq[0] + aq[1] * aq[1] + aq[2] * aq[2];
        float dot = ap[0] * aq[0] + ap[1] * aq[1] + ap[2] * aq[2];
        dot = pp < 0.25f && qq < 0.25f ? 1.0f : dot; /* both without a surface */
        float e = m->sigma_n * ew_flog2(ew_minf(dot, 1.0f)) -
                  1.44269504f * m->sigma_z * fabsf(ap[3]) * fabsf(ap[3] - aq[3]);
        if (rough) e += ew_flog2(1.0f - ew_smoothstep(0.0f, 0.5f, fabsf(aq[4] - ap[4])));
        return dot > 0.0f ? ew_maxf(e, EW_BF_NEVER) : EW_BF_NEVER;
    }
    if (kind == EW_RANGE_DEPTH) return -1.44269504f * m->sigma_z * fabsf(ap[0]) * fabsf(ap[0] - aq[0]);
    if (kind == EW_RANGE_DOF) {
        float mn = ew_minf(ap[0], aq[1]);
        float e = mn > 0.0f ? -1.44269504f * 18.0f * d2 / (mn * mn) : EW_BF_NEVER;
        return d2 <= 0.0f ? 0.0f : ew_maxf(e, EW_BF_NEVER);
    }
    return 0.0f;
}

EW_HD float ew_bf_energy(const ew_bf_model *m, int kind, const float *EW_RESTRICT ap, const float *EW_RESTRICT aq,
                         float d2) {
    return ew_bf_energy_r(m, kind, m->use_roughness, ap, aq, d2);
}

/* The same values, written for loops vectorised across pixels (the
 * pyramid's interior paths): GI's and DOF's selects as integer masks of the
 * floats' width and ew_flog2v, so the compiler keeps one lane width and no
 * branch. (In scalar loops ew_bf_energy_r's branches are cheaper.) */
EW_HD float ew_bf_energy_v(const ew_bf_model *m, int kind, int rough, const float *EW_RESTRICT ap,
                           const float *EW_RESTRICT aq, float d2) {
    if (kind == EW_RANGE_GI) {
        float pp = ap[0] * ap[0] + ap[1] * ap[1] + ap[2] * ap[2];
        float qq = aq[0] * aq[0] + aq[1] * aq[1] + aq[2] * aq[2];
        float dot = ap[0] * aq[0] + ap[1] * aq[1] + ap[2] * aq[2];
        /* both without a surface: a match (the selects as integer masks of
         * the floats' width, so that vectorised loops keep one mask type) */
        const int none = -(int)(pp < 0.25f) & -(int)(qq < 0.25f);
        dot = ew_bits_to_float((ew_float_to_bits(1.0f) & none) | (ew_float_to_bits(dot) & ~none));
        float e = m->sigma_n * ew_flog2v(ew_minf(dot, 1.0f)) -
                  1.44269504f * m->sigma_z * fabsf(ap[3]) * fabsf(ap[3] - aq[3]);
        if (rough) e += ew_flog2v(1.0f - ew_smoothstep(0.0f, 0.5f, fabsf(aq[4] - ap[4])));
        const int facing = -(int)(dot > 0.0f);
        return ew_bits_to_float((ew_float_to_bits(ew_maxf(e, EW_BF_NEVER)) & facing) |
                                (ew_float_to_bits(EW_BF_NEVER) & ~facing));
    }
    if (kind == EW_RANGE_DOF) {
        const float mn = ew_minf(ap[0], aq[1]), mm = mn * mn;
        const int pos = -(int)(mn > 0.0f), far = -(int)(d2 > 0.0f); /* integer masks, as GI's */
        const float q = -1.44269504f * 18.0f * d2 /
                        ew_bits_to_float((ew_float_to_bits(mm) & pos) | (ew_float_to_bits(1.0f) & ~pos));
        const float e = ew_maxf(ew_bits_to_float((ew_float_to_bits(q) & pos) | (ew_float_to_bits(EW_BF_NEVER) & ~pos)),
                                EW_BF_NEVER);
        return ew_bits_to_float(ew_float_to_bits(e) & far); /* d2 <= 0: 0 */
    }
    return ew_bf_energy_r(m, kind, rough, ap, aq, d2);
}

/* The range function itself. */
EW_HD float ew_bf_range(const ew_bf_model *m, const float *EW_RESTRICT ap, const float *EW_RESTRICT aq, float d2) {
    return ew_fexp2(ew_bf_energy(m, m->kind, ap, aq, d2));
}

/* ---- brute force (Eq. 1) ------------------------------------------------ */
typedef struct ew_bf_buffers {
    int width, height;
    const float *image; /* width*height*EW_BF_CH, premultiplied with the mask last */
    const float *attr;  /* width*height*attrs */
    float *out;         /* width*height*EW_BF_CH: the normalised sum (divide by the last) */
    int y0, y1;         /* brute force: the rows [y0, y1) to compute (for progress) */
} ew_bf_buffers;

/* Eq. 1 at (x, y) over the square window of radius ew_bf_support; kind is
 * m->kind (see ew_bf_energy). Domain and range share one exponential. The
 * centre has weight 1, so the sum of weights is >= 1. */
EW_HD void ew_bf_brute_px_k(int x, int y, const ew_bf_model *m, const ew_bf_buffers *b, const int kind) {
    const int C = EW_BF_CH, A = ew_bf_attrs(kind), W = b->width, H = b->height;
    const long j = (long)y * W + x;
    const float *ap = b->attr + j * A;
    const float s = ew_bf_sigma(m, ap);
    const int r = ew_bf_support(m, s);
    const float k = s > 0.0f ? -0.72134752f / (s * s) : 0.0f; /* -log2(e) / (2 s^2) */
    float acc[EW_BF_CH + 1];
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;
    const int y0 = ew_maxi(0, y - r), y1 = ew_mini(H - 1, y + r);
    const int x0 = ew_maxi(0, x - r), x1 = ew_mini(W - 1, x + r);
    for (int qy = y0; qy <= y1; qy++) {
        const float dy2 = (float)((qy - y) * (qy - y));
        for (int qx = x0; qx <= x1; qx++) {
            const long i = (long)qy * W + qx;
            const float *v = b->image + i * C;
            const float d2 = dy2 + (float)((qx - x) * (qx - x));
            const float w = ew_fexp2(k * d2 + ew_bf_energy(m, kind, ap, b->attr + i * A, d2));
            for (int c = 0; c < C; c++) acc[c] += w * v[c];
            acc[C] += w;
        }
    }
    float *o = b->out + j * C;
    const float inv = 1.0f / acc[C];
    for (int c = 0; c < C; c++) o[c] = acc[c] * inv;
}

EW_HD void ew_bf_brute_px(int x, int y, const ew_bf_model *m, const ew_bf_buffers *b) {
    ew_bf_brute_px_k(x, y, m, b, m->kind);
}

/* ---- separable approximation ------------------------------------------- */
/* One 1-D pass of the separable bilateral filter along `axis` (0: x, 1: y):
 * the 1-D restriction of Eq. 1, reading `image` (the input, or the first
 * pass's result: still premultiplied, so the second pass weighs the first's
 * mask too) and the original attributes. What games do; not edge-exact
 * because the range function is not separable. */
EW_HD void ew_bf_sep_px_k(int x, int y, int axis, const ew_bf_model *m, const ew_bf_buffers *b, const int kind) {
    const int C = EW_BF_CH, A = ew_bf_attrs(kind), W = b->width, H = b->height;
    const long j = (long)y * W + x;
    const float *ap = b->attr + j * A;
    const float s = ew_bf_sigma(m, ap);
    const int r = ew_bf_support(m, s);
    const float k = s > 0.0f ? -0.72134752f / (s * s) : 0.0f;
    const int pos = axis ? y : x, n = axis ? H : W;
    const long step = axis ? (long)W : 1L;
    float acc[EW_BF_CH + 1];
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;
    const int t0 = ew_maxi(-r, -pos), t1 = ew_mini(r, n - 1 - pos);
    for (int t = t0; t <= t1; t++) {
        const long i = j + (long)t * step;
        const float *v = b->image + i * C;
        const float d2 = (float)(t * t);
        const float w = ew_fexp2(k * d2 + ew_bf_energy(m, kind, ap, b->attr + i * A, d2));
        for (int c = 0; c < C; c++) acc[c] += w * v[c];
        acc[C] += w;
    }
    float *o = b->out + j * C;
    const float inv = 1.0f / acc[C];
    for (int c = 0; c < C; c++) o[c] = acc[c] * inv;
}

EW_HD void ew_bf_sep_px(int x, int y, int axis, const ew_bf_model *m, const ew_bf_buffers *b) {
    ew_bf_sep_px_k(x, y, axis, m, b, m->kind);
}

#endif
