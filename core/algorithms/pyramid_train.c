/*
 * pyramid_train.c — what training the pyramid's weights needs from the
 * library: a single-threaded forward pass that keeps every level, and the
 * exact gradient of a loss with respect to the per-level parameters (wf,
 * wc, gamma), by reverse mode through the upsampling passes. The
 * downsampling does not depend on the parameters, so the gradient flows
 * only through Up(l) -> Up(l+1).
 *
 * For one output pixel, Up = sum_k w_k v_k / W with W = sum_k w_k over the
 * 18 samples of ew_pyr_up_terms:
 *   coarse  w_k = wdc_k F_k G_k,   G_k = 2^(gamma E_k)
 *   fine    w_j = F_j (wf_j + comp / sff),  comp = sum_k wdc_k F_k (1 - G_k)
 * With gd_k = g . (v_k - Up) / W (g = dL/dUp):
 *   dL/dwf_j  = gd_j F_j
 *   dL/dcomp  = sum_j gd_j F_j / sff
 *   dL/dwdc_k = gd_k F_k G_k + dL/dcomp F_k (1 - G_k)
 *   dL/dgamma = sum_k (gd_k - dL/dcomp) wdc_k F_k G_k E_k ln 2
 *   dL/dv_k   = g w_k / W          (coarse: on to Up(l+1))
 * wdc_k = w_d(p, k) wc[class(k)], and the centre fine weight is
 * 1 - sum(other wf) - sum(a_c wc_c) (Eq. 2g), folded in at the end.
 */
#include <string.h>

#include "algorithms/pyramid.h"

static void up_args(const ew_pyr_plan *p, int l, ew_pyr_up_args *a) {
    memset(a, 0, sizeof *a);
    a->m = &p->model;
    a->w = p->w[l];
    a->h = p->h[l];
    a->cw = p->w[l + 1];
    a->ch = p->h[l + 1];
    a->down = p->down[l];
    a->attr = p->attr[l];
    a->cup = p->up[l + 1];
    a->cattr = p->attr2[l + 1];
    a->up = l == 0 ? p->out : p->up[l];
    a->dup_out = l > 0;
    a->d2_unit = (float)(1u << (2 * l));
    a->coarse_d2 = ew_pyr_coarse_d2(l);
    a->row = &p->rows[l];
    a->lut = NULL;
    a->ccoc = NULL; /* training is for uniform sigma (not DOF) */
    a->ucoc = NULL;
}

void ew_pyr_forward1(const ew_pyr_plan *p, const float *image, const float *attr, float *out, int downs_done) {
    const ew_bf_model *m = &p->model;
    const size_t n0 = (size_t)p->width * (size_t)p->height;
    if (!downs_done) {
        ew_pyr_to_planes(image, EW_BF_CH, n0, p->down[0]);
        ew_pyr_to_planes(attr, m->attrs, n0, p->attr[0]);
    }
    if (p->levels == 0) {
        memcpy(p->out, p->down[0], n0 * EW_BF_CH * sizeof(float));
        ew_pyr_from_planes(p->out, EW_BF_CH, n0, out);
        return;
    }
    for (int l = 0; l < p->levels && !downs_done; l++) {
        ew_pyr_down_args a;
        memset(&a, 0, sizeof a);
        a.m = m;
        a.w = p->w[l];
        a.h = p->h[l];
        a.cw = p->w[l + 1];
        a.ch = p->h[l + 1];
        a.down = p->down[l];
        a.attr = p->attr[l];
        a.cdown = p->down[l + 1];
        a.cattr = p->attr[l + 1];
        a.cattr2 = p->attr2[l + 1];
        a.cdown2 = l + 1 == p->levels ? p->up[l + 1] : NULL;
        a.d2_unit = (float)(1u << (2 * l));
        a.major_attr = p->major_attr;
        for (int y = 0; y < a.ch; y++)
            for (int x = 0; x < a.cw; x++) ew_pyr_down_px(x, y, &a);
    }
    for (int l = p->levels - 1; l >= 0; l--) {
        ew_pyr_up_args a;
        up_args(p, l, &a);
        for (int y = 0; y < a.h; y++)
            for (int x = 0; x < a.w; x++) ew_pyr_up_px(x, y, &a);
    }
    ew_pyr_from_planes(p->out, EW_BF_CH, n0, out);
}

size_t ew_pyr_grad_scratch_floats(int w, int h) {
    /* dL/dUp at two consecutive levels */
    const size_t n0 = (size_t)w * (size_t)h, n1 = (size_t)((w + 1) / 2) * (size_t)((h + 1) / 2);
    return (n0 + n1) * EW_BF_CH;
}

void ew_pyr_backward1(const ew_pyr_plan *p, const float *image, const float *attr, const float *out,
                      const float *dout, float *scratch, double *grad) {
    (void)image; /* the forward pass left everything in the plan */
    (void)attr;
    (void)out;
    const int C = EW_BF_CH;
    const double ln2 = 0.69314718055994531;
    const size_t n0 = (size_t)p->width * (size_t)p->height;
    /* g for level l lives in bufs[l & 1]; level 0's is dout */
    float *bufs[2] = {scratch, scratch + n0 * C};
    const float *g_cur = dout;
    for (int l = 0; l < p->levels; l++) {
        ew_pyr_up_args a;
        up_args(p, l, &a);
        float *g_next = bufs[(l + 1) & 1];
        const int last = l + 1 == p->levels; /* dL/dDown(L) is not needed */
        if (!last) memset(g_next, 0, (size_t)a.cw * (size_t)a.ch * C * sizeof(float));
        double *gl = grad + (size_t)l * EW_PYR_NPARAM;
        double g_wf[9] = {0}, g_wc[9] = {0}, g_gamma = 0.0;
        for (int y = 0; y < a.h; y++)
            for (int x = 0; x < a.w; x++) {
                const long j = (long)y * a.w + x;
                const float *g = g_cur + j * C;
                if (g[0] == 0.0f && g[1] == 0.0f && g[2] == 0.0f && g[3] == 0.0f) continue;
                /* Up(l) of this pixel: the plan's result (l = 0) or the duplicated Up(l) */
                float o[EW_BF_CH];
                for (int c = 0; c < C; c++)
                    o[c] = l == 0 ? a.up[(size_t)c * n0 + (size_t)j]
                                  : a.up[(size_t)c * 2 * (size_t)a.w * a.h + (size_t)y * 2 * a.w + 2 * (size_t)x];
                ew_pyr_terms t;
                ew_pyr_up_terms(x, y, &a, p->model.kind, &t);
                double comp = 0.0, sff = 0.0, W = 0.0;
                for (int k = 0; k < 9; k++) {
                    comp += (double)t.wdc[k] * t.F[k] * (1.0 - t.G[k]);
                    W += (double)t.wdc[k] * t.F[k] * t.G[k];
                }
                for (int k = 9; k < 18; k++) sff += t.F[k];
                const double cs = comp / sff;
                for (int k = 0; k < 9; k++) W += (double)t.F[9 + k] * (t.wf[k] + cs);
                if (!(W > 0.0)) continue; /* the kernel's fallback: no parameter in play */
                double gd[18];
                for (int k = 0; k < 18; k++) {
                    gd[k] = 0.0;
                    for (int c = 0; c < C; c++) gd[k] += (double)g[c] * ((double)t.V[k][c] - o[c]);
                    gd[k] /= W;
                }
                double dcomp = 0.0;
                for (int k = 0; k < 9; k++) dcomp += gd[9 + k] * t.F[9 + k];
                dcomp /= sff;
                for (int k = 0; k < 9; k++) g_wf[k] += gd[9 + k] * t.F[9 + k];
                const int px = x & 1, py = y & 1;
                for (int k = 0; k < 9; k++) {
                    const int ix = k % 3 - 1, iy = k / 3 - 1;
                    const int kx = ew_pyr_dclass(ix, px), ky = ew_pyr_dclass(iy, py);
                    const double ad = (double)ew_pyr_alpha_d(2 * kx + 1) * ew_pyr_alpha_d(2 * ky + 1);
                    const double fg = (double)t.F[k] * t.G[k];
                    g_wc[ky * 3 + kx] += ad * (gd[k] * fg + dcomp * t.F[k] * (1.0 - t.G[k]));
                    g_gamma += (gd[k] - dcomp) * t.wdc[k] * fg * t.E[k] * ln2;
                    if (last || !t.in[k]) continue;
                    const double wk = t.wdc[k] * fg / W;
                    float *gn = g_next + ((long)(y / 2 + iy) * a.cw + (x / 2 + ix)) * C;
                    for (int c = 0; c < C; c++) gn[c] += (float)(g[c] * wk);
                }
            }
        /* Eq. 2g: wf[4] = 1 - sum(other wf) - sum(a_c wc_c) */
        for (int k = 0; k < 9; k++) {
            if (k != 4) gl[k] += g_wf[k] - g_wf[4];
            const int kx = k % 3, ky = k / 3;
            gl[9 + k] += g_wc[k] - g_wf[4] * ew_pyr_alpha_d(2 * kx + 1) * ew_pyr_alpha_d(2 * ky + 1);
        }
        gl[18] += g_gamma;
        g_cur = g_next;
    }
}
