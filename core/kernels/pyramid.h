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
 * Layout: planes (structure of arrays), so that a loop over consecutive
 * pixels reads consecutive floats and vectorises. A level of w x h pixels
 * is EW_BF_CH value planes and A attribute planes of w*h floats each (plane
 * c at buf + c w h). The coarse inputs of an upsampling pass (Up(l+1), the
 * attributes at l+1, DOF's content CoC) are *duplicated horizontally*:
 * planes of 2cw x ch floats in which columns 2x and 2x+1 both hold coarse
 * pixel x. The coarse sample floor(p/2) + i of a fine pixel p is then at
 * column p_x + 2 i_x for both parities ((p_x + 2 i_x) >> 1 = (p_x >> 1) +
 * i_x), so consecutive fine pixels read consecutive coarse floats. The
 * downsampling writes the duplicated attributes (and, for the coarsest
 * level, values) beside the plain ones; the upsampling of level l >= 1
 * writes its result duplicated, since only level l - 1 reads it. The CPU
 * with level 0 in bands keeps no level's duplicated attributes: each pass
 * expands the three coarse rows a fine row reads into a thread's buffer
 * (ew_pyr_up_args.cbuf), and the kernels read them there (cps, cy0).
 *
 * Interior pixels (every sample inside: all but two columns and rows at each
 * border) take a path without bounds logic or branches (ew_pyr_up_in_k,
 * ew_pyr_down_in_k), which the CPU backend runs over spans of a row with the
 * compiler vectorising across pixels; the others take the general path. Both
 * compute the same terms in the same order.
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

/* Loops over samples and channels unrolled completely, so that a loop over
 * pixels around them is an innermost loop the compiler can vectorise. */
#if defined(__GNUC__) && !defined(__clang__) && !defined(__CUDACC__)
#define EW_PYR_UNROLL _Pragma("GCC unroll 32")
#else
#define EW_PYR_UNROLL
#endif
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

/* c ? a : b, exactly, with integer operations (a float select would be
 * turned into a branch around the loads). */
EW_HD float ew_pyr_select(int c, float a, float b) {
    const int mask = -(c != 0);
    return ew_bits_to_float((ew_float_to_bits(a) & mask) | (ew_float_to_bits(b) & ~mask));
}

/* Host code filling the fine planes of rows [y0, y1) (see the args). */
typedef void (*ew_pyr_fill_fn)(void *user, int y0, int y1, int tid, float *planes, long ps, long row0);

typedef struct ew_pyr_down_args {
    const ew_bf_model *m;
    int w, h;                  /* fine level size */
    int cw, ch;                /* coarse level size */
    const float *down, *attr;  /* fine level: planes of w x h */
    float *cdown, *cattr;      /* coarse level, written: planes of cw x ch */
    float d2_unit;             /* squared fine pixel pitch in full-resolution pixels: 4^l */
    int major_attr;            /* 1: coarse attributes are the major pixel's */
    float *cattr2;             /* the coarse attributes duplicated (planes of 2cw x ch), written when not NULL */
    float *cdown2;             /* the coarse values duplicated, written when not NULL (the coarsest level) */
    /* host code the pass runs on fine rows [y0, y1) just before it reads them
     * (NULL: none): the CPU backend packs each coarse row's two fine rows so,
     * while they are in cache; see ew_backend.pyr_row_hooks. It writes the
     * values' EW_BF_CH planes then the attributes', ps floats apart, row y at
     * row y - row0 of planes. */
    ew_pyr_fill_fn fill;
    void *fill_user;
    /* The fine planes held in part (the CPU's level 0 in bands): fine row y
     * at row y - fy0 of planes fps floats apart (fps 0: the whole level, w h
     * floats apart, fy0 0). */
    long fps, fy0;
    /* Where fill writes (CPU): fbuf_stride 0: the whole level at fbuf (the
     * values' planes with the attributes' after them); else one buffer a
     * thread, fbuf_stride floats apart, each pass over a coarse row filling
     * its two fine rows into the thread's buffer (planes fps apart). */
    float *fbuf;
    long fbuf_stride;
} ew_pyr_down_args;

/* Fine planes fps floats apart: the whole level's w h when fps is 0. */
EW_HD long ew_pyr_down_fps(const ew_pyr_down_args *a) { return a->fps ? a->fps : (long)a->w * a->h; }

/* Store one coarse pixel's values v and attributes at; dup2: write the
 * duplicated attributes (bit 0) and values (bit 1) too. */
EW_HD void ew_pyr_down_store(int x, int y, const ew_pyr_down_args *a, const float *v, const float *at, const int A,
                             const int dup2) {
    const long cn = (long)a->cw * a->ch, j = (long)y * a->cw + x;
    const long cn2 = 2 * cn, j2 = (long)y * 2 * a->cw + 2 * x;
    EW_PYR_UNROLL
    for (int c = 0; c < EW_BF_CH; c++) a->cdown[c * cn + j] = v[c];
    EW_PYR_UNROLL
    for (int k = 0; k < A; k++) a->cattr[k * cn + j] = at[k];
    if (dup2 & 1) {
        EW_PYR_UNROLL
        for (int k = 0; k < A; k++) a->cattr2[k * cn2 + j2] = a->cattr2[k * cn2 + j2 + 1] = at[k];
    }
    if (dup2 & 2) {
        EW_PYR_UNROLL
        for (int c = 0; c < EW_BF_CH; c++) a->cdown2[c * cn2 + j2] = a->cdown2[c * cn2 + j2 + 1] = v[c];
    }
}

/* The flags of ew_pyr_down_store for a pass. */
EW_HD int ew_pyr_down_dup2(const ew_pyr_down_args *a) { return (a->cattr2 ? 1 : 0) | (a->cdown2 ? 2 : 0); }

EW_HD void ew_pyr_down_px_k(int x, int y, const ew_pyr_down_args *a, const int kind) {
    const ew_bf_model *m = a->m;
    const int C = EW_BF_CH, A = ew_bf_attrs(kind);
    const long n = ew_pyr_down_fps(a);
    long idx[4] = {0, 0, 0, 0};
    int cxy[4][2] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
    int cnt = 0;
    for (int cy = 0; cy < 2; cy++)
        for (int cx = 0; cx < 2; cx++) {
            int fx = 2 * x + cx, fy = 2 * y + cy;
            if (fx >= a->w || fy >= a->h) continue;
            idx[cnt] = ((long)fy - a->fy0) * a->w + fx;
            cxy[cnt][0] = cx;
            cxy[cnt][1] = cy;
            cnt++;
        }
    float at[4][EW_BF_MAX_ATTR];
    for (int q = 0; q < 4; q++)
        for (int k = 0; k < EW_BF_MAX_ATTR; k++) at[q][k] = q < cnt && k < A ? a->attr[k * n + idx[q]] : 0.0f;
    float abar[EW_BF_MAX_ATTR] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    for (int k = 0; k < A; k++) {
        float s = 0.0f;
        for (int q = 0; q < cnt; q++) s += at[q][k];
        abar[k] = s / (float)cnt;
    }
    /* major pixel: the child the range function finds closest to the mean
     * (all children are at the same distance from the block centre); the
     * argmax of the range is the argmax of its energy */
    int mj = 0;
    if (cnt > 1 && kind != EW_RANGE_NONE) {
        float best = 2.0f * EW_BF_NEVER;
        for (int q = 0; q < cnt; q++) {
            float e = ew_bf_energy(m, kind, abar, at[q], 0.5f * a->d2_unit);
            if (e > best) {
                best = e;
                mj = q;
            }
        }
    }
    const float *am = at[mj];
    /* children beyond the border: zero values of range 1 */
    float acc[EW_BF_CH + 1], aacc[EW_BF_MAX_ATTR + 1];
    for (int c = 0; c < C; c++) acc[c] = 0.0f;
    acc[C] = (float)(4 - cnt);
    for (int k = 0; k <= A; k++) aacc[k] = 0.0f;
    for (int q = 0; q < cnt; q++) {
        int dx = cxy[q][0] - cxy[mj][0], dy = cxy[q][1] - cxy[mj][1];
        float f = q == mj ? 1.0f : ew_fexp2(ew_bf_energy(m, kind, am, at[q], (float)(dx * dx + dy * dy) * a->d2_unit));
        for (int k = 0; k < A; k++) aacc[k] += f * at[q][k];
        aacc[A] += f;
        for (int c = 0; c < C; c++) acc[c] += f * a->down[c * n + idx[q]];
        acc[C] += f;
    }
    float v[EW_BF_CH], oa[EW_BF_MAX_ATTR] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    for (int c = 0; c < C; c++) v[c] = acc[c] / acc[C];
    for (int k = 0; k < A; k++) oa[k] = a->major_attr ? am[k] : aacc[k] / aacc[A];
    ew_pyr_down_store(x, y, a, v, oa, A, ew_pyr_down_dup2(a));
}

/* The same for a coarse pixel with all four children inside (2x + 1 < w,
 * 2y + 1 < h), without branches: the major pixel by selects. */
EW_HD void ew_pyr_down_in_k(int x, int y, const ew_pyr_down_args *a, const int kind, const int major,
                            const int dup2, const int rough) {
    const ew_bf_model *m = a->m;
    const int C = EW_BF_CH, A = ew_bf_attrs(kind);
    const long n = ew_pyr_down_fps(a), i0 = ((long)(2 * y) - a->fy0) * a->w + 2 * x;
    long idx[4];
    idx[0] = i0;
    idx[1] = i0 + 1;
    idx[2] = i0 + a->w;
    idx[3] = i0 + a->w + 1;
    float at[4][EW_BF_MAX_ATTR];
    EW_PYR_UNROLL
    for (int q = 0; q < 4; q++)
        EW_PYR_UNROLL
        for (int k = 0; k < EW_BF_MAX_ATTR; k++) at[q][k] = k < A ? a->attr[k * n + idx[q]] : 0.0f;
    float abar[EW_BF_MAX_ATTR] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    EW_PYR_UNROLL
    for (int k = 0; k < A; k++) {
        float s = 0.0f;
        EW_PYR_UNROLL
        for (int q = 0; q < 4; q++) s += at[q][k];
        abar[k] = s / 4.0f;
    }
    int mj = 0;
    if (kind != EW_RANGE_NONE) {
        float best = 2.0f * EW_BF_NEVER;
        EW_PYR_UNROLL
        for (int q = 0; q < 4; q++) {
            const float e = ew_bf_energy_v(m, kind, rough, abar, at[q], 0.5f * a->d2_unit);
            const int better = e > best;
            best = better ? e : best;
            mj = better ? q : mj;
        }
    }
    /* the major child's attributes by integer selects: with conditional
     * expressions, GCC may thread the chain into a join of five values,
     * which its if-conversion gives up on, and the loop over pixels around
     * this function is then not vectorised (the colour pyramid's
     * downsampling ran about 4x slower in a span function of its own) */
    float am[EW_BF_MAX_ATTR];
    EW_PYR_UNROLL
    for (int k = 0; k < EW_BF_MAX_ATTR; k++)
        am[k] = ew_pyr_select(mj == 0, at[0][k], ew_pyr_select(mj == 1, at[1][k], ew_pyr_select(mj == 2, at[2][k], at[3][k])));
    float acc[EW_BF_CH + 1], aacc[EW_BF_MAX_ATTR + 1];
    EW_PYR_UNROLL
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;
    EW_PYR_UNROLL
    for (int k = 0; k <= A; k++) aacc[k] = 0.0f;
    EW_PYR_UNROLL
    for (int q = 0; q < 4; q++) {
        const int dx = (q & 1) - (mj & 1), dy = (q >> 1) - (mj >> 1);
        const float e = ew_fexp2(ew_bf_energy_v(m, kind, rough, am, at[q], (float)(dx * dx + dy * dy) * a->d2_unit));
        const float f = q == mj ? 1.0f : e;
        EW_PYR_UNROLL
        for (int k = 0; k < A; k++) aacc[k] += f * at[q][k];
        aacc[A] += f;
        EW_PYR_UNROLL
        for (int c = 0; c < C; c++) acc[c] += f * a->down[c * n + idx[q]];
        acc[C] += f;
    }
    float v[EW_BF_CH], oa[EW_BF_MAX_ATTR] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    EW_PYR_UNROLL
    for (int c = 0; c < C; c++) v[c] = acc[c] / acc[C];
    EW_PYR_UNROLL
    for (int k = 0; k < A; k++) {
        const float mean = aacc[k] / aacc[A];
        oa[k] = major ? am[k] : mean;
    }
    ew_pyr_down_store(x, y, a, v, oa, A, dup2);
}

EW_HD void ew_pyr_down_px(int x, int y, const ew_pyr_down_args *a) {
    if (2 * x + 1 < a->w && 2 * y + 1 < a->h)
        ew_pyr_down_in_k(x, y, a, a->m->kind, a->major_attr, ew_pyr_down_dup2(a), a->m->use_roughness);
    else ew_pyr_down_px_k(x, y, a, a->m->kind);
}

typedef struct ew_pyr_up_args {
    const ew_bf_model *m;
    int w, h;                  /* this level (l) */
    int cw, ch;                /* the coarser level (l + 1) */
    const float *down, *attr;  /* Down(l) and attributes at l: planes of w x h */
    const float *cup, *cattr;  /* Up(l + 1) and attributes at l + 1: duplicated planes of 2cw x ch */
    float *up;                 /* Up(l), written: planes of w x h, or of 2w x h duplicated when dup_out */
    float d2_unit;             /* 4^l: squared pitch of a level-l pixel in full-res pixels */
    float coarse_d2;           /* squared distance substituted for coarse samples (DOF) */
    const ew_pyr_wrow *row;    /* the weights when sigma is uniform, else NULL */
    const ew_pyr_wrow *lut;    /* else: this level's EW_PYR_LUT_N rows over log2(sigma) */
    const float *ccoc;         /* DOF: content CoC of Up(l + 1), duplicated (NULL: the coarse attributes' C;
                                  the coarsest level passes cattr's C plane: the same numbers) */
    float *ucoc;               /* DOF: content CoC of Up(l), written when not NULL (duplicated when dup_out) */
    int dup_out;               /* write Up(l) (and ucoc) duplicated: l >= 1 */
    /* host code run on rows [y0, y1) of Up(l) once the pass has written them
     * (NULL: none): the CPU backend unpacks each row of the result so */
    void (*drain)(void *user, int y0, int y1, int tid);
    void *drain_user;
    /* Up(0) held in a band of rows (not duplicated): row y at y - up_y0,
     * planes up_ps floats apart (0: a whole frame, up_y0 0) */
    int up_y0;
    long up_ps;
    /* CPU (pyr_row_hooks): Up(0) in bands of `band` rows, one per thread,
     * band_stride floats apart from a->up (0: a whole frame); the backend
     * sets up, up_y0 and up_ps for each band it runs */
    int band;
    long band_stride;
    /* Down(l) and its attributes held in part (the CPU's level 0 in bands):
     * row y at row y - dy0 of planes dps floats apart (dps 0: the whole
     * level, w h floats apart, dy0 0). */
    long dps, dy0;
    /* CPU, with band: level 0's input in bands too. Before a band's rows are
     * computed, fill packs them into the thread's buffer (fbuf, fbuf_stride
     * floats apart: the values' then the attributes' planes, fps floats
     * apart, of band + 2 rows), and the rows either side, which other bands
     * own and may already have overwritten (an output in place of the
     * colour), are copied from fedge: for each boundary k * band (k >= 1)
     * the rows k * band - 1 and k * band, saved before the pass, as planes
     * of 2 rows, one boundary after another. */
    ew_pyr_fill_fn fill;
    void *fill_user;
    float *fbuf;
    long fbuf_stride, fps;
    const float *fedge;
    /* The coarse attributes (cattr) and DOF's content CoC (ccoc) held in
     * part: coarse row cy at row cy - cy0 of duplicated planes cps floats
     * apart (cps 0: the whole level, 2 cw ch floats apart, cy0 0). Up(l + 1)
     * (cup) is always the whole level. */
    long cps, cy0;
    /* CPU, with cbuf: no level holds duplicated attributes. Before a fine
     * row is computed, the backend expands the three coarse rows it reads
     * (cy - 1 .. cy + 1 for cy = y / 2) into the thread's buffer (cbuf,
     * cbuf_stride floats apart), from cattr_src (the attributes at l + 1:
     * plain planes of cw x ch) and, for DOF, ccoc_src (the content CoC of
     * Up(l + 1), duplicated; NULL at the coarsest level: the attributes'
     * own C), and points cattr and ccoc there. */
    const float *cattr_src, *ccoc_src;
    float *cbuf;
    long cbuf_stride;
} ew_pyr_up_args;

/* Down(l) planes dps floats apart: the whole level's w h when dps is 0. */
EW_HD long ew_pyr_up_dps(const ew_pyr_up_args *a) { return a->dps ? a->dps : (long)a->w * a->h; }

/* The coarse attribute planes cps floats apart: the whole duplicated
 * level's 2 cw ch when cps is 0. */
EW_HD long ew_pyr_up_cps(const ew_pyr_up_args *a) { return a->cps ? a->cps : 2L * a->cw * a->ch; }

/* log2 of the domain sigma at a centre with attributes ap, for the table
 * (ew_flog2(ew_bf_sigma), written without a square root or branch). */
EW_HD float ew_pyr_log2_sigma(const ew_bf_model *m, const int kind, const float *ap) {
    if (kind == EW_RANGE_GI) return ew_flog2v(ew_maxf((m->sigma_alpha * ap[4] + 1.0f) * (1.0f / 3.0f), 1e-6f));
    if (kind == EW_RANGE_DOF) { /* sigma = 1 / sqrt(36 / D^2 + 1 / sigma^2); D <= 0: sigma 0 */
        const float d = ap[0], s2 = m->sigma * m->sigma;
        const float extra = 1.0f / ew_maxf(s2, 1e-30f);
        const float inv = 36.0f / ew_maxf(d * d, 1e-30f) + (m->sigma > 0.0f ? extra : 0.0f);
        const float l = -0.5f * ew_flog2v(inv);
        return ew_pyr_select(d > 0.0f, l, -100.0f); /* an integer select: see ew_pyr_lookup */
    }
    return ew_flog2v(ew_maxf(m->sigma, 1e-6f));
}

/* The weights for a centre of log2(domain sigma) ls and parity par,
 * interpolated from the table. */
EW_HD void ew_pyr_lookup(const ew_pyr_wrow *lut, float ls, int par, float *wf, float *wdc, float *gamma) {
    /* the clamps as integer selects: with float ones the compiler threads
     * the constant rows at the ends into separate paths, and a loop over
     * pixels is no longer branch-free (it would not vectorise) */
    const float t0 = (ls - (float)EW_PYR_LUT_LOG2_MIN) * (float)EW_PYR_LUT_STEPS, top = (float)(EW_PYR_LUT_N - 1);
    const float tl = ew_pyr_select(t0 > 0.0f, t0, 0.0f); /* NaN: 0 */
    const float t = ew_pyr_select(tl < top, tl, top);
    const int i0 = (int)t, i1 = (int)ew_pyr_select(t + 1.0f < top, t + 1.0f, top); /* floats: see ew_fexp2 */
    float f = t - (float)i0, g = 1.0f - f;
    /* the rows as one float array (indices, not row pointers: a loop over
     * pixels turns these loads into gathers) */
    const float *L = (const float *)(const void *)lut;
    const int RS = (int)(sizeof(ew_pyr_wrow) / sizeof(float));
    const int r0 = i0 * RS, r1 = i1 * RS, wo = 9 + par * 9;
    EW_PYR_UNROLL
    for (int k = 0; k < 9; k++) {
        wf[k] = g * L[r0 + k] + f * L[r1 + k];
        wdc[k] = g * L[r0 + wo + k] + f * L[r1 + wo + k];
    }
    *gamma = g * L[r0 + RS - 1] + f * L[r1 + RS - 1];
}

/* The weights of the 18 samples of Up(p, l): coarse 0..8 are
 * Up(floor(p/2) + i, l+1), fine 9..17 are Down(p + i, l), i by offset
 * (iy + 1) * 3 + (ix + 1). Shared by the general path of the kernel and the
 * training's backward pass (pyramid_train.c), so both see the same numbers. */
typedef struct ew_pyr_terms {
    float V[18][EW_BF_CH]; /* the samples' values (zeros beyond the border) */
    int in[18];            /* inside the image */
    float E[18];           /* log2 of the range value (0 beyond the border) */
    float F[18];           /* range value 2^E */
    float G[9];            /* coarse: f^gamma = 2^(gamma E) */
    float coc[18];         /* DOF: the samples' content CoC */
    float wf[9], wdc[9], gamma; /* the domain weights at this pixel */
} ew_pyr_terms;

/* The domain weights of pixel (x, y) with attributes ap. */
EW_HD void ew_pyr_weights(int x, int y, const ew_pyr_up_args *a, const int kind, const float *ap, float *wf,
                          float *wdc, float *gamma) {
    const int par = (y & 1) * 2 + (x & 1);
    if (a->row) {
        for (int k = 0; k < 9; k++) {
            wf[k] = a->row->wf[k];
            wdc[k] = a->row->wdc[par][k];
        }
        *gamma = a->row->gamma;
    } else {
        ew_pyr_lookup(a->lut, ew_pyr_log2_sigma(a->m, kind, ap), par, wf, wdc, gamma);
    }
}

/* kind is a->m->kind (see ew_bf_energy). */
EW_HD void ew_pyr_up_terms(int x, int y, const ew_pyr_up_args *a, const int kind, ew_pyr_terms *t) {
    const ew_bf_model *m = a->m;
    const int C = EW_BF_CH, A = ew_bf_attrs(kind);
    const long n = ew_pyr_up_dps(a), j = ((long)y - a->dy0) * a->w + x;
    const long cw2 = 2L * a->cw, cn2 = cw2 * a->ch, cps = ew_pyr_up_cps(a);
    float ap[EW_BF_MAX_ATTR];
    for (int k = 0; k < EW_BF_MAX_ATTR; k++) ap[k] = k < A ? a->attr[k * n + j] : 0.0f;
    ew_pyr_weights(x, y, a, kind, ap, t->wf, t->wdc, &t->gamma);
    const int cx = x >> 1, cy = y >> 1;
    for (int k = 0; k < 9; k++) {
        const int ix = k % 3 - 1, iy = k / 3 - 1, qx = cx + ix, qy = cy + iy;
        const int in = qx >= 0 && qx < a->cw && qy >= 0 && qy < a->ch;
        const long i = in ? (long)qy * cw2 + 2 * qx : 0, ia = in ? ((long)qy - a->cy0) * cw2 + 2 * qx : 0;
        float aq[EW_BF_MAX_ATTR];
        for (int kk = 0; kk < EW_BF_MAX_ATTR; kk++) aq[kk] = kk < A ? a->cattr[kk * cps + ia] : 0.0f;
        t->in[k] = in;
        for (int c = 0; c < C; c++) t->V[k][c] = in ? a->cup[c * cn2 + i] : 0.0f;
        t->coc[k] = 0.0f;
        if (kind == EW_RANGE_DOF) { /* the CoC of the content (see the top) */
            t->coc[k] = a->ccoc ? a->ccoc[ia] : aq[1];
            aq[1] = t->coc[k];
        }
        t->E[k] = in ? ew_bf_energy(m, kind, ap, aq, a->coarse_d2) : 0.0f;
    }
    for (int k = 0; k < 9; k++) {
        const int ix = k % 3 - 1, iy = k / 3 - 1, qx = x + ix, qy = y + iy;
        const int in = qx >= 0 && qx < a->w && qy >= 0 && qy < a->h;
        const long i = in ? ((long)qy - a->dy0) * a->w + qx : j;
        float aq[EW_BF_MAX_ATTR];
        for (int kk = 0; kk < EW_BF_MAX_ATTR; kk++) aq[kk] = kk < A ? a->attr[kk * n + i] : 0.0f;
        t->in[9 + k] = in;
        for (int c = 0; c < C; c++) t->V[9 + k][c] = in ? a->down[c * n + i] : 0.0f;
        t->coc[9 + k] = kind == EW_RANGE_DOF ? aq[1] : 0.0f;
        t->E[9 + k] = !in || k == 4 ? 0.0f
                                    : ew_bf_energy(m, kind, ap, aq, (float)(ix * ix + iy * iy) * a->d2_unit);
    }
    for (int k = 0; k < 18; k++) t->F[k] = ew_fexp2(t->E[k]);
    for (int k = 0; k < 9; k++) t->G[k] = t->gamma == 1.0f ? t->F[k] : ew_fexp2(t->gamma * t->E[k]);
}

/* Store Up(p, l) and, when wcoc (DOF only), its content CoC; dup:
 * a->dup_out (see the top). */
EW_HD void ew_pyr_up_store(int x, int y, const ew_pyr_up_args *a, const int kind, const int dup, const int wcoc,
                           const float *o, float coc) {
    const long n = (long)a->w * a->h;
    if (dup) {
        const long j2 = (long)y * 2 * a->w + 2 * x;
        EW_PYR_UNROLL
        for (int c = 0; c < EW_BF_CH; c++) a->up[c * 2 * n + j2] = a->up[c * 2 * n + j2 + 1] = o[c];
        if (kind == EW_RANGE_DOF && wcoc) a->ucoc[j2] = a->ucoc[j2 + 1] = coc;
    } else {
        const long j = (long)y * a->w + x, ju = (long)(y - a->up_y0) * a->w + x, ps = a->up_ps ? a->up_ps : n;
        EW_PYR_UNROLL
        for (int c = 0; c < EW_BF_CH; c++) a->up[c * ps + ju] = o[c];
        if (kind == EW_RANGE_DOF && wcoc) a->ucoc[j] = coc;
    }
}

/* Eq. 2 from the terms: the general path. */
EW_HD void ew_pyr_up_general_k(int x, int y, const ew_pyr_up_args *a, const int kind) {
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
    float o[EW_BF_CH];
    /* every weight 0 (a trained centre weight of 0 and nothing else): the pixel itself */
    const float den = acc[C] > 0.0f ? acc[C] : 1.0f;
    for (int c = 0; c < C; c++) o[c] = acc[C] > 0.0f ? acc[c] / den : t.V[13][c];
    const float cden = cocw > 0.0f ? cocw : 1.0f;
    ew_pyr_up_store(x, y, a, kind, a->dup_out, a->ucoc != 0, o, cocw > 0.0f ? cocn / cden : t.coc[13]);
}

/* The interior columns [x0, x1) and whether row y is interior: every sample
 * of such a pixel is inside (x - 1 >= 0, x + 1 < w, floor(x/2) +- 1 inside
 * the coarse level; the same for y). */
EW_HD int ew_pyr_up_interior(int y, const ew_pyr_up_args *a, int *x0, int *x1) {
    *x0 = 2;
    *x1 = ew_mini(a->w - 1, 2 * a->cw - 2);
    return y >= 2 && y + 1 < a->h && (y >> 1) + 1 < a->ch && *x1 > *x0;
}

/* Eq. 2 for an interior pixel, in the order of the general path but
 * without bounds logic or branches, so that a loop over a row's interior
 * vectorises. The variant is fixed by constants: uniform (weights a->row,
 * else the table a->lut; GI compares roughness exactly when not uniform),
 * g1 (uniform with gamma 1: f^gamma = f), dup (a->dup_out; DOF writes
 * a->ucoc exactly when dup). ew_pyr_up_in_ok says when a pass fits. */
EW_HD int ew_pyr_up_in_ok(const ew_pyr_up_args *a, const int kind) {
    return (kind != EW_RANGE_DOF || ((a->ucoc != 0) == (a->dup_out != 0) && a->ccoc)) &&
           (kind != EW_RANGE_GI || (a->m->use_roughness != 0) == (a->row == 0));
}

/* Whether a loop over ew_pyr_up_in_k of this variant vectorises on the CPU
 * (GCC 12): with uniform weights, and with DOF's table (its lookup as
 * gathers). GI's table (roughness) does not yet ("no vectype" for its
 * attribute loads): there the energies take the branchy form that is
 * cheaper in scalar code, and the CPU backend the general path. */
EW_HD int ew_pyr_up_in_vec(const int kind, const int uniform) { return uniform || kind == EW_RANGE_DOF; }

/* Range functions with E(p, q) == E(q, p) bit for bit (COLOR's sum of
 * squared differences: the differences only change sign). For them a pass
 * can evaluate each pair of neighbouring fine pixels once instead of twice
 * (ew_pyr_fine_fwd_k, ew_pyr_fine_rows). */
EW_HD int ew_pyr_symmetric(const int kind) { return kind == EW_RANGE_COLOR; }

/* The fine range values between the pixels of rows y - 1 (p*) and y and
 * their neighbours right (rt), below-left (dl), below (dn) and below-right
 * (dr), each indexed by i = x - xo; pixel (x, y)'s eight are pdr[i - 1],
 * pdn[i], pdl[i + 1], rt[i - 1], rt[i], dl[i], dn[i], dr[i]. */
typedef struct ew_pyr_fine_rows {
    const float *pdl, *pdn, *pdr;   /* row y - 1 */
    const float *rt, *dl, *dn, *dr; /* row y */
    int xo;
} ew_pyr_fine_rows;

/* The range value between interior pixel (x, y) and its neighbour at
 * (x + dx, y + dy) (dy >= 0): one of the forward values above. */
EW_HD float ew_pyr_fine_fwd_k(int x, int y, int dx, int dy, const ew_pyr_up_args *a, const int kind) {
    const int A = ew_bf_attrs(kind);
    const long n = ew_pyr_up_dps(a), j = ((long)y - a->dy0) * a->w + x, i = j + (long)dy * a->w + dx;
    float ap[EW_BF_MAX_ATTR], aq[EW_BF_MAX_ATTR];
    EW_PYR_UNROLL
    for (int k = 0; k < EW_BF_MAX_ATTR; k++) {
        ap[k] = k < A ? a->attr[k * n + j] : 0.0f;
        aq[k] = k < A ? a->attr[k * n + i] : 0.0f;
    }
    return ew_fexp2(ew_bf_energy_v(a->m, kind, 0, ap, aq, (float)(dx * dx + dy * dy) * a->d2_unit));
}

/* The coarse samples' range values f and f^gamma of a span of pixels
 * whose range function depends on the centre through numbers the span
 * shares (DOF: D, where the weights are one row too): by coarse row offset
 * iy + 1, each indexed by the duplicated column minus xo, so pixel x's
 * sample (ix, iy) is F[iy + 1][x + 2 ix - xo]. */
typedef struct ew_pyr_coarse_rows {
    const float *F[3], *G[3];
    int xo;
} ew_pyr_coarse_rows;

/* The value pair of coarse sample i (an index into the duplicated attribute
 * planes, relative to a->cy0) for a centre with attributes ap: what
 * ew_pyr_up_in_k computes for it (DOF's content CoC in place of the coarse
 * C), for ew_pyr_coarse_rows. */
EW_HD void ew_pyr_coarse_fg_k(long i, const float *ap, const ew_pyr_up_args *a, const int kind, float gamma, float *f,
                              float *g) {
    const int A = ew_bf_attrs(kind);
    const long cps = ew_pyr_up_cps(a);
    float aq[EW_BF_MAX_ATTR];
    EW_PYR_UNROLL
    for (int kk = 0; kk < EW_BF_MAX_ATTR; kk++) aq[kk] = kk < A ? a->cattr[kk * cps + i] : 0.0f;
    if (kind == EW_RANGE_DOF) aq[1] = a->ccoc[i];
    const float e = ew_bf_energy_v(a->m, kind, 0, ap, aq, a->coarse_d2);
    *f = ew_fexp2(e);
    *g = ew_fexp2(gamma * e);
}

/* fr: the fine range values, given (symmetric kinds with uniform weights;
 * NULL: computed here); cr: the coarse ones (uniform weights, DOF; NULL:
 * computed here). */
EW_HD void ew_pyr_up_in_k(int x, int y, const ew_pyr_up_args *a, const int kind, const int uniform, const int g1,
                          const int dup, const ew_pyr_fine_rows *fr, const ew_pyr_coarse_rows *cr) {
    const ew_bf_model *m = a->m;
    const int C = EW_BF_CH, A = ew_bf_attrs(kind), rough = !uniform, vec = ew_pyr_up_in_vec(kind, uniform);
    const long n = ew_pyr_up_dps(a), j = ((long)y - a->dy0) * a->w + x;
    const long cw2 = 2L * a->cw, cn2 = cw2 * a->ch, cj = (long)(y >> 1) * cw2 + x;
    const long cps = ew_pyr_up_cps(a), cja = cj - a->cy0 * cw2; /* the attributes' index (cy0) */
    float ap[EW_BF_MAX_ATTR];
    EW_PYR_UNROLL
    for (int k = 0; k < EW_BF_MAX_ATTR; k++) ap[k] = k < A ? a->attr[k * n + j] : 0.0f;
    float wf[9], wdc[9], gamma;
    if (uniform) {
        const int py = (y & 1) * 2, odd = x & 1;
        EW_PYR_UNROLL
        for (int k = 0; k < 9; k++) {
            const float we = a->row->wdc[py][k], wo = a->row->wdc[py + 1][k];
            wf[k] = a->row->wf[k];
            wdc[k] = ew_pyr_select(odd, wo, we);
        }
        gamma = a->row->gamma;
    } else {
        ew_pyr_lookup(a->lut, ew_pyr_log2_sigma(m, kind, ap), (y & 1) * 2 + (x & 1), wf, wdc, &gamma);
    }
    float E[18], F[18], G[9], coc[18];
    const float *ccoc = kind == EW_RANGE_DOF ? a->ccoc : a->cattr; /* DOF: ew_pyr_up_in_ok */
    EW_PYR_UNROLL
    for (int k = 0; k < 9; k++) {
        const long i = cja + (long)(k / 3 - 1) * cw2 + 2 * (k % 3 - 1);
        float aq[EW_BF_MAX_ATTR];
        EW_PYR_UNROLL
        for (int kk = 0; kk < EW_BF_MAX_ATTR; kk++) aq[kk] = kk < A ? a->cattr[kk * cps + i] : 0.0f;
        coc[k] = 0.0f;
        if (kind == EW_RANGE_DOF) {
            coc[k] = ccoc[i];
            aq[1] = coc[k];
        }
        /* the vectorising form where the loop vectorises, the branchy one
         * where it stays scalar (ew_pyr_up_in_vec) */
        E[k] = cr  ? 0.0f /* given */
               : vec ? ew_bf_energy_v(m, kind, rough, ap, aq, a->coarse_d2)
                     : ew_bf_energy_r(m, kind, rough, ap, aq, a->coarse_d2);
    }
    EW_PYR_UNROLL
    for (int k = 0; k < 9; k++) {
        const int ix = k % 3 - 1, iy = k / 3 - 1;
        const long i = j + (long)iy * a->w + ix;
        float aq[EW_BF_MAX_ATTR];
        EW_PYR_UNROLL
        for (int kk = 0; kk < EW_BF_MAX_ATTR; kk++) aq[kk] = kk < A ? a->attr[kk * n + i] : 0.0f;
        coc[9 + k] = kind == EW_RANGE_DOF ? aq[1] : 0.0f;
        const float d2 = (float)(ix * ix + iy * iy) * a->d2_unit;
        if (!fr)
            E[9 + k] = k == 4 ? 0.0f : vec ? ew_bf_energy_v(m, kind, rough, ap, aq, d2) : ew_bf_energy_r(m, kind, rough, ap, aq, d2);
    }
    EW_PYR_UNROLL
    for (int k = 0; k < 18; k++)
        F[k] = k == 13 ? 1.0f : (k > 8 && fr) || (k < 9 && cr) ? 0.0f : ew_fexp2(E[k]); /* the centre: 2^0 */
    if (fr) { /* by offset: see ew_pyr_fine_rows */
        const int i = x - fr->xo;
        F[9] = fr->pdr[i - 1];
        F[10] = fr->pdn[i];
        F[11] = fr->pdl[i + 1];
        F[12] = fr->rt[i - 1];
        F[14] = fr->rt[i];
        F[15] = fr->dl[i];
        F[16] = fr->dn[i];
        F[17] = fr->dr[i];
    }
    EW_PYR_UNROLL
    for (int k = 0; k < 9; k++) G[k] = g1 ? F[k] : cr ? 0.0f : ew_fexp2(gamma * E[k]);
    if (cr) {
        EW_PYR_UNROLL
        for (int k = 0; k < 9; k++) {
            const int c = x + 2 * (k % 3 - 1) - cr->xo;
            F[k] = cr->F[k / 3][c];
            G[k] = g1 ? F[k] : cr->G[k / 3][c];
        }
    }
    float acc[EW_BF_CH + 1], cocn = 0.0f, cocw = 0.0f;
    EW_PYR_UNROLL
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;
    float comp = 0.0f;
    EW_PYR_UNROLL
    for (int k = 0; k < 9; k++) {
        const long i = cj + (long)(k / 3 - 1) * cw2 + 2 * (k % 3 - 1);
        const float wb = wdc[k] * F[k], w = wb * G[k];
        comp += wb - w;
        EW_PYR_UNROLL
        for (int c = 0; c < C; c++) acc[c] += w * a->cup[c * cn2 + i];
        acc[C] += w;
        if (kind == EW_RANGE_DOF) {
            cocn += w * coc[k];
            cocw += w;
        }
    }
    float sff = 0.0f;
    EW_PYR_UNROLL
    for (int k = 9; k < 18; k++) sff += F[k];
    const float cs = comp / sff;
    EW_PYR_UNROLL
    for (int k = 0; k < 9; k++) {
        const long i = j + (long)(k / 3 - 1) * a->w + (k % 3 - 1);
        const float w = F[9 + k] * (wf[k] + cs);
        EW_PYR_UNROLL
        for (int c = 0; c < C; c++) acc[c] += w * a->down[c * n + i];
        acc[C] += w;
        if (kind == EW_RANGE_DOF) {
            cocn += w * coc[9 + k];
            cocw += w;
        }
    }
    /* every weight 0: the pixel itself (selects by integer operations, so
     * the compiler keeps them branch-free) */
    float o[EW_BF_CH];
    const int pos = acc[C] > 0.0f, cpos = cocw > 0.0f;
    const float den = ew_pyr_select(pos, acc[C], 1.0f), cden = ew_pyr_select(cpos, cocw, 1.0f);
    EW_PYR_UNROLL
    for (int c = 0; c < C; c++) o[c] = ew_pyr_select(pos, acc[c] / den, a->down[c * n + j]);
    ew_pyr_up_store(x, y, a, kind, dup, dup, o, ew_pyr_select(cpos, cocn / cden, coc[13]));
}

EW_HD void ew_pyr_up_px_k(int x, int y, const ew_pyr_up_args *a, const int kind) {
    int x0, x1;
    if (ew_pyr_up_interior(y, a, &x0, &x1) && x >= x0 && x < x1 && ew_pyr_up_in_ok(a, kind)) {
        const int uniform = a->row != 0, g1 = uniform && a->row->gamma == 1.0f;
        ew_pyr_up_in_k(x, y, a, kind, uniform, g1, a->dup_out != 0, 0, 0);
    } else {
        ew_pyr_up_general_k(x, y, a, kind);
    }
}

EW_HD void ew_pyr_up_px(int x, int y, const ew_pyr_up_args *a) { ew_pyr_up_px_k(x, y, a, a->m->kind); }

#endif
