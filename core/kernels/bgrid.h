/*
 * bgrid.h — per-cell splat and per-pixel slice of a bilateral grid
 * (Meng et al. 2020, Eq. 10-13; supplement §5 for the +0.5 biased
 * coordinates). Plain C that nvcc also compiles.
 *
 * Coordinates: pixel x sits at (x + 0.5) / rate_s on the grid's axis, cell u
 * at u + 0.5 (both biased by +0.5 as in the supplement); a guide value g in
 * [0, 255] sits at g / rate_d, cell w at w + 0.5. We store them shifted by
 * -0.5 so cell u is at integer u.
 *
 * The tent is max(1 - |a|*, 0) with |a|* = sqrt(a^2 + 1e-7): the paper's
 * differentiable version, used in the forward pass too so that inference and
 * training see the same function.
 *
 * Layout: cell (u, v, w) holds `channels` normalised values followed by its
 * weight sum: grid[((v * gw + u) * gd + w) * (channels + 1) + c].
 * A cell is empty when its weight sum is 0. The paper tests "value != 0"
 * instead, which would also drop cells of genuinely black radiance; testing
 * the weight is what the paper means and stays correct for black regions.
 *
 * Bands: the image may be rows band_y .. band_y + height - 1 of a taller
 * frame and the grid rows band_v .. band_v + gh - 1 of the frame's grid.
 * Positions and tents are computed in the frame's rows and cells (the same
 * float operations on the same values as for the whole frame), a column
 * gathers the rows of its support that the band holds, and a pixel reads
 * the cells the band's grid holds. A cell whose support lies inside the
 * band, and a pixel whose cells the band's grid holds, are therefore the
 * same bits as in one whole-frame pass. Both are 0 for a whole frame.
 */
#ifndef EW_KERNELS_BGRID_H
#define EW_KERNELS_BGRID_H

#include "kernels/compat.h"

#define EW_BGRID_MAX_CHANNELS 4
#define EW_TENT_EPS 1e-7f

typedef struct ew_bgrid_params {
    int width, height;   /* image size */
    int gw, gh, gd;      /* grid size: ceil(w / rate_s), ceil(h / rate_s), ceil(255 / rate_d) */
    float rate_s;        /* spatial sampling rate (eta_h = eta_w) in pixels per cell */
    float rate_d;        /* range sampling rate in guide units per cell */
    int channels;        /* value channels, 1..EW_BGRID_MAX_CHANNELS */
    int band_y;          /* the image's first row in the frame (0: the whole frame) */
    int band_v;          /* the grid's first row of cells in the frame's grid (0: the whole grid) */
} ew_bgrid_params;

EW_HD float ew_tent(float a) { return ew_maxf(1.0f - sqrtf(a * a + EW_TENT_EPS), 0.0f); }

/* Continuous grid coordinates of a pixel and of a guide value. */
EW_HD float ew_bgrid_pos_s(float x, float rate_s) { return (x + 0.5f) / rate_s - 0.5f; }
EW_HD float ew_bgrid_pos_d(float g, float rate_d) { return g / rate_d - 0.5f; }

/* Pixels that can touch cell u along one axis: |pos(x) - u| < 1. */
EW_HD void ew_bgrid_pixel_span(int u, float rate_s, int n, int *x0, int *x1) {
    int a = (int)floorf((float)u * rate_s - 0.5f * rate_s - 0.5f);
    int b = (int)ceilf((float)u * rate_s + 1.5f * rate_s - 0.5f);
    *x0 = ew_maxi(a, 0);
    *x1 = ew_mini(b, n - 1);
}

/* Frame rows that can touch grid row v (the band's, 0-based) and that the
 * band holds, as the band's rows; *y0 > *y1 when there are none. */
EW_HD void ew_bgrid_band_rows(int v, const ew_bgrid_params *p, int *y0, int *y1) {
    ew_bgrid_pixel_span(v + p->band_v, p->rate_s, p->band_y + p->height, y0, y1);
    *y0 = ew_maxi(*y0, p->band_y) - p->band_y;
    *y1 -= p->band_y;
}

/*
 * Splat as a gather: fill the whole column (u, v) — all gd cells — from the
 * pixels in its spatial support. Columns are independent, so they run in
 * parallel without atomics and the result does not depend on thread count.
 * Pixels with any non-finite value are skipped (treated as missing).
 * image: width*height*channels floats; guide: width*height floats.
 */
EW_HD void ew_bgrid_splat_column(int u, int v, const ew_bgrid_params *p,
                                 const float *EW_RESTRICT image,
                                 const float *EW_RESTRICT guide,
                                 float *EW_RESTRICT grid) {
    const int C = p->channels, S = C + 1;
    float *col = grid + ((long)v * p->gw + u) * p->gd * S;
    for (int i = 0; i < p->gd * S; i++) col[i] = 0.0f;

    int x0, x1, y0, y1;
    ew_bgrid_pixel_span(u, p->rate_s, p->width, &x0, &x1);
    ew_bgrid_band_rows(v, p, &y0, &y1);
    for (int y = y0; y <= y1; y++) {
        float wy = ew_tent(ew_bgrid_pos_s((float)(y + p->band_y), p->rate_s) - (float)(v + p->band_v));
        if (wy <= 0.0f) continue;
        for (int x = x0; x <= x1; x++) {
            float wx = ew_tent(ew_bgrid_pos_s((float)x, p->rate_s) - (float)u);
            if (wx <= 0.0f) continue;
            long j = (long)y * p->width + x;
            const float *px = image + j * C;
            int ok = ew_finitef(guide[j]);
            for (int c = 0; c < C; c++) ok &= ew_finitef(px[c]);
            if (!ok) continue;
            float pz = ew_bgrid_pos_d(guide[j], p->rate_d);
            int z0 = (int)floorf(pz);
            for (int z = z0; z <= z0 + 1; z++) {
                if (z < 0 || z >= p->gd) continue;
                float w = wx * wy * ew_tent(pz - (float)z);
                if (w <= 0.0f) continue;
                float *cell = col + (long)z * S;
                for (int c = 0; c < C; c++) cell[c] += w * px[c];
                cell[C] += w;
            }
        }
    }
    for (int z = 0; z < p->gd; z++) {
        float *cell = col + (long)z * S;
        if (cell[C] > 0.0f)
            for (int c = 0; c < C; c++) cell[c] /= cell[C];
    }
}

/*
 * Slice pixel (x, y): trilinear interpolation of the non-empty cells around
 * its grid position, renormalised by the weights of the cells used (Eq. 13).
 * When all eight neighbours are empty (possible only for a pixel that was
 * itself skipped, e.g. NaN, with no valid neighbours at its guide value) the
 * pixel falls back to the spatially interpolated column averages over all
 * depths; if even those are empty it is 0.
 */
EW_HD void ew_bgrid_slice_px(int x, int y, const ew_bgrid_params *p,
                             const float *EW_RESTRICT grid,
                             const float *EW_RESTRICT guide,
                             float *EW_RESTRICT out) {
    const int C = p->channels, S = C + 1;
    float px = ew_bgrid_pos_s((float)x, p->rate_s);
    float py = ew_bgrid_pos_s((float)(y + p->band_y), p->rate_s);
    float g = guide[(long)y * p->width + x];
    float pz = ew_bgrid_pos_d(ew_finitef(g) ? g : 0.0f, p->rate_d);
    /* v0: the band grid's row of the frame's cell row floor(py) */
    int u0 = (int)floorf(px), v0 = (int)floorf(py) - p->band_v, z0 = (int)floorf(pz);
    float acc[EW_BGRID_MAX_CHANNELS + 1];
    for (int c = 0; c <= C; c++) acc[c] = 0.0f;

    for (int v = v0; v <= v0 + 1; v++) {
        if (v < 0 || v >= p->gh) continue;
        float wy = ew_tent(py - (float)(v + p->band_v));
        for (int u = u0; u <= u0 + 1; u++) {
            if (u < 0 || u >= p->gw) continue;
            float wxy = ew_tent(px - (float)u) * wy;
            const float *col = grid + ((long)v * p->gw + u) * p->gd * S;
            for (int z = z0; z <= z0 + 1; z++) {
                if (z < 0 || z >= p->gd) continue;
                const float *cell = col + (long)z * S;
                if (cell[C] <= 0.0f) continue;
                float w = wxy * ew_tent(pz - (float)z);
                for (int c = 0; c < C; c++) acc[c] += w * cell[c];
                acc[C] += w;
            }
        }
    }
    if (!(acc[C] > 0.0f)) {
        for (int c = 0; c <= C; c++) acc[c] = 0.0f;
        for (int v = v0; v <= v0 + 1; v++) {
            if (v < 0 || v >= p->gh) continue;
            for (int u = u0; u <= u0 + 1; u++) {
                if (u < 0 || u >= p->gw) continue;
                float wxy = ew_maxf(ew_tent(px - (float)u) * ew_tent(py - (float)(v + p->band_v)), 1e-6f);
                const float *col = grid + ((long)v * p->gw + u) * p->gd * S;
                for (int z = 0; z < p->gd; z++) {
                    const float *cell = col + (long)z * S;
                    float w = wxy * cell[C];
                    for (int c = 0; c < C; c++) acc[c] += w * cell[c];
                    acc[C] += w;
                }
            }
        }
    }
    float inv = acc[C] > 0.0f ? 1.0f / acc[C] : 0.0f;
    for (int c = 0; c < C; c++) out[c] = acc[c] * inv;
}

#endif
