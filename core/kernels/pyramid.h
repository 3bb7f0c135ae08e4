/*
 * pyramid.h — per-pixel downsampling and upsampling of the pyramid
 * edge-preserving filter (Xu et al. 2024, §3, Eq. 2-3). Plain C that nvcc
 * also compiles.
 *
 * Levels: level 0 is the image; level l+1 is ceil(w/2) x ceil(h/2) of level
 * l. Coordinates of a level-l pixel in full-resolution pixels are 2^l times
 * its own, so distances given to the range function (DOF only) are scaled by
 * 2^l.
 *
 * Downsampling (Eq. 3): each coarse pixel filters its (up to) four children
 * with the range function centred on the *major pixel* m, the child whose
 * attributes are closest to the children's mean under the range function.
 * Coarse attributes are m's (denoising: keeps edges crisp, §3.2 and Fig. 4)
 * or the same weighted mean as the values (everything else).
 *
 * Upsampling (Eq. 2): the dual 3x3 pattern. Fine samples are Down(p + i, l),
 * coarse samples Up(floor(p/2) + i, l+1), i in {-1,0,1}^2, with
 *   w_f(i) = wf(i) f_f(i) + w_fR(i)                                  (2b)
 *   w_c(i) = w_b(i) f_c(i)^gamma                                     (2c)
 *   w_fR(i) = sum_j w_b(j) (1 - f_c(j)^gamma) * f_f(i) / sum_j f_f(j)  (2d)
 *   w_b(i) = w_d(p, i) f_c(i) wc(i)                                  (2e)
 *   w_d(p, i) = prod_a (17 - 3 d_a) / 24, d_a = |4 i_a - 2 (p_a mod 2) + 1| (2f)
 * normalised by their sum (2a). (2b)+(2d) give w_f(i) = f_f(i) (wf(i) +
 * comp / sum_j f_f(j)) with comp = sum_j w_b(j) (1 - f_c(j)^gamma), which is
 * what the code computes.
 *
 * The domain weights wf, wc and gamma come in an ew_pyr_wrow: wf by fine
 * offset, and wdc = w_d(p, i) * wc(i) by parity of p and coarse offset. The
 * coarse weights are stored per *distance class* (d_x, d_y) in {1,3,5}^2
 * rather than per offset i, so the same 9 numbers mean the same thing for
 * all four parities (the pattern mirrors with the parity). Eq. 2g, the sum
 * of the domain weights being 1, is then independent of the parity.
 *
 * A row depends on the level and on the centre's domain sigma. With a
 * uniform sigma the caller passes one row per level; otherwise a table over
 * log2(sigma) in steps of 1/EW_PYR_LUT_STEPS octave, interpolated per pixel.
 *
 * Values are premultiplied with the mask last (see bilateral.h). Samples
 * beyond the image border (the 3x3 patterns, odd-sized 2x2 blocks) count as
 * (0, 0, 0, 0) with range value 1, as zero padding does, so the mask tracks
 * how much of every result lies inside the image and the final division
 * reproduces the exact filter's renormalised window at borders.
 *
 * DOF: the coarse samples' range function uses the CoC of their content
 * (a per-level buffer averaged with the same weights as the colour) instead
 * of the coarse level's own (downsampled) C. A coarse pixel of sharp
 * background onto which a blurred foreground has already been spread then
 * carries the foreground's CoC, so the spread goes on at the finer levels;
 * with the downsampled C it would be cut at every level to the 3x3 coarse
 * neighbourhood of the foreground's own tiles.
 */
#ifndef EW_KERNELS_PYRAMID_H
#define EW_KERNELS_PYRAMID_H

#include "kernels/bilateral.h"

#define EW_PYR_MAX_LEVELS 16
/* the table over log2(sigma): from 2^EW_PYR_LUT_LOG2_MIN, EW_PYR_LUT_STEPS per octave */
#define EW_PYR_LUT_LOG2_MIN (-4)
#define EW_PYR_LUT_STEPS 8
#define EW_PYR_LUT_N (13 * EW_PYR_LUT_STEPS + 1) /* up to sigma = 2^9 */

typedef struct ew_pyr_wrow {
    float wf[9];     /* fine domain weight by offset (iy + 1) * 3 + (ix + 1) */
    float wdc[4][9]; /* w_d(p, i) * wc(class(i)), by parity (py * 2 + px) and coarse offset */
    float gamma;
} ew_pyr_wrow;

/* Per-axis interpolation factor of Eq. 4 for distance d in {1, 3, 5}. */
EW_HD float ew_pyr_alpha_d(int d) { return (float)(17 - 3 * d) / 24.0f; }

/* Distance d_a = |4 i - 2 parity + 1| of a coarse sample at offset i. */
EW_HD int ew_pyr_dist(int i, int parity) {
    int d = 4 * i - 2 * parity + 1;
    return d < 0 ? -d : d;
}

/* The distance class 0, 1, 2 of d = 1, 3, 5. */
EW_HD int ew_pyr_dclass(int i, int parity) { return ew_pyr_dist(i, parity) / 2; }

typedef struct ew_pyr_down_args {
    const ew_bf_model *m;
    int w, h;                  /* fine level size */
    int cw, ch;                /* coarse level size */
    const float *down, *attr;  /* fine level */
    float *cdown, *cattr;      /* coarse level, written */
    float d2_unit;             /* squared fine pixel pitch in full-resolution pixels: 4^l */
    int major_attr;            /* 1: coarse attributes are the major pixel's */
} ew_pyr_down_args;

EW_HD void ew_pyr_down_px_k(int x, int y, const ew_pyr_down_args *a, const int kind) {
    const ew_bf_model *m = a->m;
    const int C = EW_BF_CH, A = ew_bf_attrs(kind);
    long idx[4] = {0, 0, 0, 0};
    int cxy[4][2] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
    int n = 0;
    for (int cy = 0; cy < 2; cy++)
        for (int cx = 0; cx < 2; cx++) {
            int fx = 2 * x + cx, fy = 2 * y + cy;
            if (fx >= a->w || fy >= a->h) continue;
            idx[n] = (long)fy * a->w + fx;
            cxy[n][0] = cx;
            cxy[n][1] = cy;
            n++;
        }
    float abar[EW_BF_MAX_ATTR] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    for (int k = 0; k < A; k++) {
        float s = 0.0f;
        for (int q = 0; q < n; q++) s += a->attr[idx[q] * A + k];
        abar[k] = s / (float)n;
    }
    /* major pixel: the child the range function finds closest to the mean
     * (all children are at the same distance from the block centre); the
     * argmax of the range is the argmax of its energy */
    int mj = 0;
    if (n > 1 && kind != EW_RANGE_NONE) {
        float best = 2.0f * EW_BF_NEVER;
        for (int q = 0; q < n; q++) {
            float e = ew_bf_energy(m, kind, abar, a->attr + idx[q] * A, 0.5f * a->d2_unit);
            if (e > best) {
                best = e;
                mj = q;
            }
        }
    }
    const float *am = a->attr + idx[mj] * A;
    /* children beyond the border: zero values of range 1 */
    float acc[EW_BF_CH + 1], aacc[EW_BF_MAX_ATTR + 1];
    for (int c = 0; c < C; c++) acc[c] = 0.0f;
    acc[C] = (float)(4 - n);
    for (int k = 0; k <= A; k++) aacc[k] = 0.0f;
    for (int q = 0; q < n; q++) {
        int dx = cxy[q][0] - cxy[mj][0], dy = cxy[q][1] - cxy[mj][1];
        const float *aq = a->attr + idx[q] * A;
        float f = q == mj ? 1.0f : ew_fexp2(ew_bf_energy(m, kind, am, aq, (float)(dx * dx + dy * dy) * a->d2_unit));
        for (int k = 0; k < A; k++) aacc[k] += f * aq[k];
        aacc[A] += f;
        const float *v = a->down + idx[q] * C;
        for (int c = 0; c < C; c++) acc[c] += f * v[c];
        acc[C] += f;
    }
    const long j = (long)y * a->cw + x;
    float *o = a->cdown + j * C;
    for (int c = 0; c < C; c++) o[c] = acc[c] / acc[C];
    float *oa = a->cattr + j * A;
    for (int k = 0; k < A; k++) oa[k] = a->major_attr ? am[k] : aacc[k] / aacc[A];
}

EW_HD void ew_pyr_down_px(int x, int y, const ew_pyr_down_args *a) { ew_pyr_down_px_k(x, y, a, a->m->kind); }

typedef struct ew_pyr_up_args {
    const ew_bf_model *m;
    int w, h;                  /* this level (l) */
    int cw, ch;                /* the coarser level (l + 1) */
    const float *down, *attr;  /* Down(l) and attributes at l */
    const float *cup, *cattr;  /* Up(l + 1) and attributes at l + 1 */
    float *up;                 /* Up(l), written */
    float d2_unit;             /* 4^l: squared pitch of a level-l pixel in full-res pixels */
    float coarse_d2;           /* squared distance substituted for coarse samples (DOF) */
    const ew_pyr_wrow *row;    /* the weights when sigma is uniform, else NULL */
    const ew_pyr_wrow *lut;    /* else: this level's EW_PYR_LUT_N rows over log2(sigma) */
    const float *ccoc;         /* DOF: content CoC of Up(l + 1) (NULL: the coarse attributes' C) */
    float *ucoc;               /* DOF: content CoC of Up(l), written when not NULL */
} ew_pyr_up_args;

/* The weights for a centre of domain sigma s and parity par, interpolated
 * from the table. */
EW_HD void ew_pyr_lookup(const ew_pyr_wrow *lut, float s, int par, float *wf, float *wdc, float *gamma) {
    float t = (ew_flog2(ew_maxf(s, 1e-6f)) - (float)EW_PYR_LUT_LOG2_MIN) * (float)EW_PYR_LUT_STEPS;
    t = ew_clampf(t, 0.0f, (float)(EW_PYR_LUT_N - 1));
    int i0 = (int)t;
    int i1 = ew_mini(i0 + 1, EW_PYR_LUT_N - 1);
    float f = t - (float)i0, g = 1.0f - f;
    const ew_pyr_wrow *r0 = lut + i0, *r1 = lut + i1;
    for (int k = 0; k < 9; k++) {
        wf[k] = g * r0->wf[k] + f * r1->wf[k];
        wdc[k] = g * r0->wdc[par][k] + f * r1->wdc[par][k];
    }
    *gamma = g * r0->gamma + f * r1->gamma;
}

/* The weights of the 18 samples of Up(p, l): coarse 0..8 are
 * Up(floor(p/2) + i, l+1), fine 9..17 are Down(p + i, l), i by offset
 * (iy + 1) * 3 + (ix + 1). Shared by the kernel and the training's backward
 * pass (pyramid_train.c), so both see the same numbers. */
typedef struct ew_pyr_terms {
    const float *V[18]; /* the samples' values (EW_BF_CH floats; zeros beyond the border) */
    int in[18];         /* inside the image */
    float E[18];        /* log2 of the range value (0 beyond the border) */
    float F[18];        /* range value 2^E */
    float G[9];         /* coarse: f^gamma = 2^(gamma E) */
    float coc[18];      /* DOF: the samples' content CoC */
    float wf[9], wdc[9], gamma; /* the domain weights at this pixel */
    float zero[EW_BF_CH];
} ew_pyr_terms;

/* kind is a->m->kind (see ew_bf_energy). The range values are computed as
 * energies first and exponentiated in one branch-free loop, so the compiler
 * can vectorise it; f^gamma is 2^(gamma E). */
EW_HD void ew_pyr_up_terms(int x, int y, const ew_pyr_up_args *a, const int kind, ew_pyr_terms *t) {
    const ew_bf_model *m = a->m;
    const int C = EW_BF_CH, A = ew_bf_attrs(kind);
    const long j = (long)y * a->w + x;
    const float *ap = a->attr + j * A;
    const int par = (y & 1) * 2 + (x & 1);
    if (a->row) {
        for (int k = 0; k < 9; k++) {
            t->wf[k] = a->row->wf[k];
            t->wdc[k] = a->row->wdc[par][k];
        }
        t->gamma = a->row->gamma;
    } else {
        ew_pyr_lookup(a->lut, ew_bf_sigma(m, ap), par, t->wf, t->wdc, &t->gamma);
    }
    for (int c = 0; c < C; c++) t->zero[c] = 0.0f;
    const int cx = x >> 1, cy = y >> 1;
    if (x >= 2 && y >= 2 && x + 1 < a->w && y + 1 < a->h && cx + 1 < a->cw && cy + 1 < a->ch &&
        kind != EW_RANGE_DOF) {
        /* every sample inside (almost every pixel): no bounds logic */
        const long c0 = (long)(cy - 1) * a->cw + (cx - 1), f0 = j - a->w - 1;
        for (int k = 0; k < 9; k++) {
            const long ci = c0 + (long)(k / 3) * a->cw + k % 3, fi = f0 + (long)(k / 3) * a->w + k % 3;
            const int ix = k % 3 - 1, iy = k / 3 - 1;
            t->in[k] = t->in[9 + k] = 1;
            t->coc[k] = t->coc[9 + k] = 0.0f;
            t->V[k] = a->cup + ci * C;
            t->V[9 + k] = a->down + fi * C;
            t->E[k] = ew_bf_energy(m, kind, ap, a->cattr + ci * A, a->coarse_d2);
            t->E[9 + k] = k == 4 ? 0.0f
                                 : ew_bf_energy(m, kind, ap, a->attr + fi * A, (float)(ix * ix + iy * iy) * a->d2_unit);
        }
    } else {
    for (int k = 0; k < 9; k++) {
        const int ix = k % 3 - 1, iy = k / 3 - 1, qx = cx + ix, qy = cy + iy;
        const int in = qx >= 0 && qx < a->cw && qy >= 0 && qy < a->ch;
        const long i = in ? (long)qy * a->cw + qx : 0;
        t->in[k] = in;
        t->V[k] = in ? a->cup + i * C : t->zero;
        const float *aq = a->cattr + i * A;
        float dof_aq[2] = {0.0f, 0.0f};
        t->coc[k] = 0.0f;
        if (kind == EW_RANGE_DOF) { /* the CoC of the content (see the top) */
            t->coc[k] = a->ccoc ? a->ccoc[i] : aq[1];
            dof_aq[0] = aq[0];
            dof_aq[1] = t->coc[k];
            aq = dof_aq;
        }
        t->E[k] = in ? ew_bf_energy(m, kind, ap, aq, a->coarse_d2) : 0.0f;
    }
    for (int k = 0; k < 9; k++) {
        const int ix = k % 3 - 1, iy = k / 3 - 1, qx = x + ix, qy = y + iy;
        const int in = qx >= 0 && qx < a->w && qy >= 0 && qy < a->h;
        const long i = in ? (long)qy * a->w + qx : j;
        t->in[9 + k] = in;
        t->V[9 + k] = in ? a->down + i * C : t->zero;
        t->coc[9 + k] = kind == EW_RANGE_DOF ? a->attr[i * A + 1] : 0.0f;
        t->E[9 + k] = !in || k == 4 ? 0.0f
                                    : ew_bf_energy(m, kind, ap, a->attr + i * A, (float)(ix * ix + iy * iy) * a->d2_unit);
    }
    }
    for (int k = 0; k < 18; k++) t->F[k] = ew_fexp2(t->E[k]);
    if (t->gamma == 1.0f) { /* the analytic setting */
        for (int k = 0; k < 9; k++) t->G[k] = t->F[k];
    } else {
        for (int k = 0; k < 9; k++) t->G[k] = ew_fexp2(t->gamma * t->E[k]);
    }
}

EW_HD void ew_pyr_up_px_k(int x, int y, const ew_pyr_up_args *a, const int kind) {
    ew_pyr_terms t;
    ew_pyr_up_terms(x, y, a, kind, &t);
    const int C = EW_BF_CH;
    float acc[EW_BF_CH + 1], cocn = 0.0f, cocw = 0.0f;
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;
    /* coarse: w_c = w_b f^gamma, w_b = w_d wc f; the rest of w_b is comp */
    float comp = 0.0f;
    for (int k = 0; k < 9; k++) {
        const float wb = t.wdc[k] * t.F[k], w = wb * t.G[k];
        comp += wb - w;
        for (int c = 0; c < C; c++) acc[c] += w * t.V[k][c];
        acc[C] += w;
        if (kind == EW_RANGE_DOF && t.in[k]) {
            cocn += w * t.coc[k];
            cocw += w;
        }
    }
    /* fine: their own range value times (wf + comp / sum of fine range) */
    float sff = 0.0f;
    for (int k = 9; k < 18; k++) sff += t.F[k];
    const float cs = comp / sff; /* sff >= 1: the centre */
    for (int k = 0; k < 9; k++) {
        const float w = t.F[9 + k] * (t.wf[k] + cs);
        for (int c = 0; c < C; c++) acc[c] += w * t.V[9 + k][c];
        acc[C] += w;
        if (kind == EW_RANGE_DOF && t.in[9 + k]) {
            cocn += w * t.coc[9 + k];
            cocw += w;
        }
    }
    const long j = (long)y * a->w + x;
    float *o = a->up + j * C;
    if (acc[C] > 0.0f) {
        for (int c = 0; c < C; c++) o[c] = acc[c] / acc[C];
    } else { /* every weight 0 (a trained centre weight of 0 and nothing else): the pixel itself */
        for (int c = 0; c < C; c++) o[c] = t.V[13][c];
    }
    if (kind == EW_RANGE_DOF && a->ucoc) a->ucoc[j] = cocw > 0.0f ? cocn / cocw : t.coc[13];
}

EW_HD void ew_pyr_up_px(int x, int y, const ew_pyr_up_args *a) { ew_pyr_up_px_k(x, y, a, a->m->kind); }

#endif
