/*
 * bgrid_backward.h — analytic derivatives of the bilateral grid's splat and
 * slice (kernels/bgrid.h), after the supplement of Meng et al. 2020, §5.1-5.2.
 * Plain C that nvcc also compiles; every function is a gather (one pixel or
 * one grid column writes only its own outputs), so the CPU runs them in
 * parallel without atomics and the sums do not depend on the thread count.
 *
 * Notation for one grid: pixel j with value I_j (C channels) and guide g_j;
 * cell k with weight sum beta_k and value G_k; w_kj the trilinear tent
 * weight (exactly the products kernels/bgrid.h computes) and
 * w'_kj = d w_kj / d g_j = T(x) T(y) T'(z) / rate_d, with
 * T'(a) = -a / sqrt(a^2 + eps) inside the support and 0 outside.
 *
 * Splat (Eq. 10): G_k = alpha_k / beta_k, alpha_k = sum_j w_kj I_j,
 *   beta_k = sum_j w_kj. With Gamma_k = dL/dG_k:
 *   dL/dI_j = sum_k Gamma_k w_kj / beta_k
 *   dL/dg_j = sum_k (w'_kj / beta_k) sum_c Gamma_kc (I_jc - G_kc)
 *   (the quotient rule of supplement Eq. 16 with alpha_k = G_k beta_k).
 * Slice (Eq. 13): R_j = mu_j / eta_j over the non-empty cells (m_k = 1 when
 *   beta_k > 0), mu_j = sum_k m_k w_kj G_k, eta_j = sum_k m_k w_kj. With
 *   o_j = dL/dR_j:
 *   dL/dG_kc = sum_j o_jc m_k w_kj / eta_j
 *   dL/dg_j  = sum_c o_jc (mu'_jc - R_jc eta'_j) / eta_j,
 *   mu' and eta' being mu and eta with w' in place of w.
 *   (Supplement Eq. 28 divides by eta^2; the quotient rule with
 *   d eta / dG = 0 leaves eta — the finite-difference tests settle it.)
 * The emptiness mask m_k and the fallback of a pixel with no non-empty
 * neighbour (only a skipped, non-finite pixel can have one) are piecewise
 * constant: they pass no gradient.
 */
#ifndef EW_KERNELS_BGRID_BACKWARD_H
#define EW_KERNELS_BGRID_BACKWARD_H

#include "kernels/bgrid.h"

/* d tent(a) / da for the differentiable tent of kernels/bgrid.h. */
EW_HD float ew_tent_grad(float a) {
    float r = sqrtf(a * a + EW_TENT_EPS);
    return 1.0f - r > 0.0f ? -a / r : 0.0f;
}

/*
 * Slice, pixel (x, y): dL/dg_j into *dguide (overwritten) and 1 / eta_j
 * into *inv_eta (0 when the pixel took the fallback) for the grid pass.
 * dout: dL/dR, width*height*C floats.
 */
EW_HD void ew_bgrid_slice_backward_px(int x, int y, const ew_bgrid_params *p, const float *EW_RESTRICT grid,
                                      const float *EW_RESTRICT guide, const float *EW_RESTRICT dout,
                                      float *EW_RESTRICT dguide, float *EW_RESTRICT inv_eta) {
    const int C = p->channels, S = C + 1;
    const long j = (long)y * p->width + x;
    float px = ew_bgrid_pos_s((float)x, p->rate_s);
    float py = ew_bgrid_pos_s((float)y, p->rate_s);
    float g = guide[j];
    int finite = ew_finitef(g);
    float pz = ew_bgrid_pos_d(finite ? g : 0.0f, p->rate_d);
    int u0 = (int)floorf(px), v0 = (int)floorf(py), z0 = (int)floorf(pz);
    float mu[EW_BGRID_MAX_CHANNELS], dmu[EW_BGRID_MAX_CHANNELS], eta = 0.0f, deta = 0.0f;
    for (int c = 0; c < C; c++) mu[c] = dmu[c] = 0.0f;
    for (int v = v0; v <= v0 + 1; v++) {
        if (v < 0 || v >= p->gh) continue;
        float wy = ew_tent(py - (float)v);
        for (int u = u0; u <= u0 + 1; u++) {
            if (u < 0 || u >= p->gw) continue;
            float wxy = ew_tent(px - (float)u) * wy;
            const float *col = grid + ((long)v * p->gw + u) * p->gd * S;
            for (int z = z0; z <= z0 + 1; z++) {
                if (z < 0 || z >= p->gd) continue;
                const float *cell = col + (long)z * S;
                if (cell[C] <= 0.0f) continue;
                float w = wxy * ew_tent(pz - (float)z);
                float dw = wxy * ew_tent_grad(pz - (float)z) / p->rate_d;
                for (int c = 0; c < C; c++) {
                    mu[c] += w * cell[c];
                    dmu[c] += dw * cell[c];
                }
                eta += w;
                deta += dw;
            }
        }
    }
    if (!(eta > 0.0f)) {
        *dguide = 0.0f;
        *inv_eta = 0.0f;
        return;
    }
    float inv = 1.0f / eta, acc = 0.0f;
    for (int c = 0; c < C; c++) acc += dout[j * C + c] * (dmu[c] - mu[c] * inv * deta) * inv;
    *dguide = finite ? acc : 0.0f;
    *inv_eta = inv;
}

/*
 * Slice, grid column (u, v): dL/dG for its gd cells, gathered from the
 * pixels in its support (the same pixels and weights as the splat gather).
 * dgrid has the grid's layout; the weight slot of each cell is set to 0.
 */
EW_HD void ew_bgrid_slice_backward_column(int u, int v, const ew_bgrid_params *p, const float *EW_RESTRICT grid,
                                          const float *EW_RESTRICT guide, const float *EW_RESTRICT dout,
                                          const float *EW_RESTRICT inv_eta, float *EW_RESTRICT dgrid) {
    const int C = p->channels, S = C + 1;
    const long base = ((long)v * p->gw + u) * p->gd * S;
    const float *col = grid + base;
    float *dcol = dgrid + base;
    for (int i = 0; i < p->gd * S; i++) dcol[i] = 0.0f;
    int x0, x1, y0, y1;
    ew_bgrid_pixel_span(u, p->rate_s, p->width, &x0, &x1);
    ew_bgrid_pixel_span(v, p->rate_s, p->height, &y0, &y1);
    for (int y = y0; y <= y1; y++) {
        /* the slice's spatial weights, computed exactly as it does */
        float wy = ew_tent(ew_bgrid_pos_s((float)y, p->rate_s) - (float)v);
        if (wy <= 0.0f) continue;
        for (int x = x0; x <= x1; x++) {
            float wxy = ew_tent(ew_bgrid_pos_s((float)x, p->rate_s) - (float)u) * wy;
            if (wxy <= 0.0f) continue;
            long j = (long)y * p->width + x;
            if (inv_eta[j] == 0.0f) continue;
            float g = guide[j];
            float pz = ew_bgrid_pos_d(ew_finitef(g) ? g : 0.0f, p->rate_d);
            int z0 = (int)floorf(pz);
            for (int z = z0; z <= z0 + 1; z++) {
                if (z < 0 || z >= p->gd) continue;
                if (col[(long)z * S + C] <= 0.0f) continue;
                float w = wxy * ew_tent(pz - (float)z) * inv_eta[j];
                for (int c = 0; c < C; c++) dcol[(long)z * S + c] += w * dout[j * C + c];
            }
        }
    }
}

/*
 * Splat, pixel (x, y): adds dL/dg_j to *dguide and, if dimage is not NULL,
 * writes dL/dI_j (C floats). dgrid: dL/dG (the grid's layout). A pixel the
 * splat skipped (any non-finite value) gets zeros.
 */
EW_HD void ew_bgrid_splat_backward_px(int x, int y, const ew_bgrid_params *p, const float *EW_RESTRICT image,
                                      const float *EW_RESTRICT guide, const float *EW_RESTRICT grid,
                                      const float *EW_RESTRICT dgrid, float *EW_RESTRICT dguide,
                                      float *EW_RESTRICT dimage) {
    const int C = p->channels, S = C + 1;
    const long j = (long)y * p->width + x;
    const float *px_val = image + j * C;
    float dI[EW_BGRID_MAX_CHANNELS];
    for (int c = 0; c < C; c++) dI[c] = 0.0f;
    int ok = ew_finitef(guide[j]);
    for (int c = 0; c < C; c++) ok &= ew_finitef(px_val[c]);
    float dg = 0.0f;
    if (ok) {
        float fx = ew_bgrid_pos_s((float)x, p->rate_s);
        float fy = ew_bgrid_pos_s((float)y, p->rate_s);
        float pz = ew_bgrid_pos_d(guide[j], p->rate_d);
        int u0 = (int)floorf(fx), v0 = (int)floorf(fy), z0 = (int)floorf(pz);
        for (int v = v0; v <= v0 + 1; v++) {
            if (v < 0 || v >= p->gh) continue;
            float wy = ew_tent(fy - (float)v);
            if (wy <= 0.0f) continue;
            for (int u = u0; u <= u0 + 1; u++) {
                if (u < 0 || u >= p->gw) continue;
                float wx = ew_tent(fx - (float)u);
                if (wx <= 0.0f) continue;
                long cbase = ((long)v * p->gw + u) * p->gd * S;
                for (int z = z0; z <= z0 + 1; z++) {
                    if (z < 0 || z >= p->gd) continue;
                    const float *cell = grid + cbase + (long)z * S;
                    const float *dcell = dgrid + cbase + (long)z * S;
                    float w = wx * wy * ew_tent(pz - (float)z);
                    if (w <= 0.0f || !(cell[C] > 0.0f)) continue;
                    float inv_beta = 1.0f / cell[C];
                    float dw = wx * wy * ew_tent_grad(pz - (float)z) / p->rate_d;
                    float dot = 0.0f;
                    for (int c = 0; c < C; c++) {
                        dI[c] += dcell[c] * w * inv_beta;
                        dot += dcell[c] * (px_val[c] - cell[c]);
                    }
                    dg += dw * inv_beta * dot;
                }
            }
        }
    }
    *dguide += dg;
    if (dimage)
        for (int c = 0; c < C; c++) dimage[j * C + c] = dI[c];
}

#endif
