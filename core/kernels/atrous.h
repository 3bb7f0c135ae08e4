/*
 * atrous.h — one iteration of the edge-avoiding à-trous wavelet filter
 * (Dammertz, Sewtz, Hanika, Lensch 2010), the spatial filter of SVGF.
 *
 * Iteration i convolves with the 5x5 B3-spline kernel h = (1, 4, 6, 4, 1)/16
 * dilated by 2^i (holes between taps), each tap weighted by edge-stopping
 * functions of the centre and the tap, as in Dammertz et al. Eq. 3-5:
 *   w = exp(-(L_p - L_q)^2 / s_l^2) exp(-|n_p - n_q|^2 / s_n^2) exp(-(z_p - z_q)^2 / s_z^2)
 * with the luminance L of the *current* iteration's colour (the paper's
 * colour term on luminance, as SVGF does) and s_l halved at every iteration
 * (the paper's 2^-i s_rt), so later, wider passes stop more readily.
 * A sigma <= 0 switches its term off; a NULL normal/depth likewise.
 * Pixels are premultiplied with a mask (see bilateral.h): missing samples
 * carry zero colour and mask, and the caller divides by the mask at the end.
 */
#ifndef EW_KERNELS_ATROUS_H
#define EW_KERNELS_ATROUS_H

#include "kernels/bilateral.h"

typedef struct ew_atrous_args {
    int w, h, channels;        /* meaningful channels 1..EW_BF_MAX_CH; buffers hold EW_BF_CH */
    int step;                  /* 2^i */
    const float *in;           /* w*h*channels */
    float *out;
    const float *normal;       /* w*h*3 or NULL */
    const float *depth;        /* w*h or NULL */
    float sigma_l, sigma_n, sigma_z; /* sigma_l already scaled for this iteration */
} ew_atrous_args;

/* Luminance of a premultiplied pixel (r M, g M, b M, M); 1 channel: r. */
EW_HD float ew_atrous_lum(const float *v, int C) {
    const float l = C >= 3 ? 0.2126f * v[0] + 0.7152f * v[1] + 0.0722f * v[2] : v[0];
    return v[EW_BF_COLOR] > 0.0f ? l / v[EW_BF_COLOR] : 0.0f;
}

EW_HD void ew_atrous_px(int x, int y, const ew_atrous_args *a) {
    const int C = EW_BF_CH, CL = a->channels;
    const long j = (long)y * a->w + x;
    const float hk[5] = {1.0f / 16.0f, 1.0f / 4.0f, 3.0f / 8.0f, 1.0f / 4.0f, 1.0f / 16.0f};
    const float *vp = a->in + j * C;
    const float lp = ew_atrous_lum(vp, CL);
    /* a missing centre (mask 0) has no luminance to compare */
    const float kl = a->sigma_l > 0.0f && vp[EW_BF_COLOR] > 0.0f ? -1.0f / (a->sigma_l * a->sigma_l) : 0.0f;
    const float kn = a->normal && a->sigma_n > 0.0f ? -1.0f / (a->sigma_n * a->sigma_n) : 0.0f;
    const float kz = a->depth && a->sigma_z > 0.0f ? -1.0f / (a->sigma_z * a->sigma_z) : 0.0f;
    float acc[EW_BF_CH + 1];
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;
    for (int ty = -2; ty <= 2; ty++) {
        const int qy = y + ty * a->step;
        if (qy < 0 || qy >= a->h) continue;
        for (int tx = -2; tx <= 2; tx++) {
            const int qx = x + tx * a->step;
            if (qx < 0 || qx >= a->w) continue;
            const long i = (long)qy * a->w + qx;
            const float *v = a->in + i * C;
            float e = 0.0f;
            if (kl != 0.0f && v[EW_BF_COLOR] > 0.0f) {
                float d = ew_atrous_lum(v, CL) - lp;
                e += kl * d * d;
            }
            if (kn != 0.0f) {
                const float *np = a->normal + j * 3, *nq = a->normal + i * 3;
                float d0 = np[0] - nq[0], d1 = np[1] - nq[1], d2 = np[2] - nq[2];
                e += kn * (d0 * d0 + d1 * d1 + d2 * d2);
            }
            if (kz != 0.0f) {
                float d = a->depth[j] - a->depth[i];
                e += kz * d * d;
            }
            const float w = hk[tx + 2] * hk[ty + 2] * ew_fexp(e);
            for (int c = 0; c < C; c++) acc[c] += w * v[c];
            acc[C] += w;
        }
    }
    float *o = a->out + j * C;
    for (int c = 0; c < C; c++) o[c] = acc[c] / acc[C]; /* the centre's weight is > 0 */
}

#endif
