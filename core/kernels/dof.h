/*
 * dof.h — depth of field attributes (Xu et al. 2024 §4.1): the circle of
 * confusion of a thin-lens camera per pixel, and the domain CoC that lets a
 * blurred foreground spread over a sharp background.
 *
 * CoC: a point at depth S (planar camera depth, Blender's Depth pass) images
 * as a disc of diameter
 *     c = (f / N) * f * |S - S_f| / (S * (S_f - f))      (thin lens, on the sensor)
 * with focal length f, f-number N and focus distance S_f; in pixels,
 * c * max(width, height) / sensor_width (Blender's sensor fit AUTO applies
 * the sensor width to the larger side). Signed: negative in front of the
 * focus plane (near field). Missing or non-positive depths count as
 * infinitely far (the sky). Capped at max_coc.
 *
 * Eq. 8's CoC A is not the lens's: with equal domain and range CoC its
 * kernel is a Gaussian of sigma A / (6 sqrt 2), while a thin lens spreads a
 * point over a disc of diameter c, sigma c / 4 per axis. So the attributes
 * use A = scale |c| with scale = 3 sqrt(2) / 2 ~ 2.12 by default, which gives
 * the blur of a real lens (checked against Cycles in bench/); the "coc"
 * output stays the lens's c.
 *
 * Attributes for the DOF model (bilateral.h): C = A (the pixel's own) and
 * D = the domain CoC: max(C, the near-field A whose kernel reaches the
 * pixel, radius A / 2). Eq. 8 gathers over the centre's own CoC, so a sharp background
 * pixel would never receive the blurred foreground in front of it; with D it
 * gathers as far as the foreground's blur reaches, and the range function
 * min(D_p, C_q) still keeps the sharp background neighbours out. Without a
 * near field in reach, D = C and this is Eq. 8.
 *
 * "Covers" is computed on tiles of EW_DOF_TILE pixels with the L-inf metric
 * (conservative: a tile counts as covered when any of its pixels may be),
 * as two 1-D passes: a scatter-max over square reaches is separable. On the
 * 1/16-size tile grid this costs little whatever the CoC.
 */
#ifndef EW_KERNELS_DOF_H
#define EW_KERNELS_DOF_H

#include "kernels/compat.h"

#define EW_DOF_TILE 4

typedef struct ew_dof_camera {
    float focal_mm;       /* focal length */
    float fstop;          /* f-number N */
    float focus_m;        /* focus distance */
    float sensor_mm;      /* sensor width (applied to the larger image side) */
    int width, height;    /* image size in pixels */
    float max_coc;        /* largest CoC diameter in pixels */
    float scale;          /* Eq. 8's A per pixel of CoC diameter (see above) */
} ew_dof_camera;

/* Signed CoC diameter in pixels of a point at planar depth depth_m. */
EW_HD float ew_dof_coc(const ew_dof_camera *c, float depth_m) {
    const float f = c->focal_mm, sf = c->focus_m * 1000.0f;
    const float s = (ew_finitef(depth_m) & (depth_m > 0.0f)) ? depth_m * 1000.0f : 1e30f; /* no branch: vectorises */
    const float aperture = f / c->fstop;
    /* |S - S_f| / S, written to stay finite for S = 1e30 */
    const float rel = s >= 1e29f ? 1.0f : fabsf(s - sf) / s;
    const float on_sensor = aperture * f * rel / ew_maxf(sf - f, 1e-3f);
    const float px = on_sensor * (float)ew_maxi(c->width, c->height) / c->sensor_mm;
    const float mag = ew_minf(px, c->max_coc);
    return s < sf ? -mag : mag;
}

typedef struct ew_dof_args {
    ew_dof_camera cam;
    int tw, th;            /* tile grid: ceil(width / EW_DOF_TILE) x ceil(height / EW_DOF_TILE) */
    const float *depth;    /* width*height, metres */
    float *coc;            /* width*height signed CoC, written */
    float *tiles, *tiles2; /* tw*th: near-field reach per tile, scratch */
    float *attr;           /* width*height*2: (D, C), written (NULL: steps 1-4 only, ew_dof_attr_rows does step 5) */
    int planes;            /* 0: (D, C) per pixel; 1: a D plane then a C plane (what the pyramid reads) */
} ew_dof_args;

/* Step 1: signed CoC of pixel j. */
EW_HD void ew_dof_coc_px(long j, const ew_dof_args *a) { a->coc[j] = ew_dof_coc(&a->cam, a->depth[j]); }

/* Step 2: the largest near-field A in a tile (0 without near field). */
EW_HD void ew_dof_tile_px(int tx, int ty, const ew_dof_args *a) {
    const int W = a->cam.width, H = a->cam.height;
    float m = 0.0f;
    for (int y = ty * EW_DOF_TILE; y < ew_mini(H, (ty + 1) * EW_DOF_TILE); y++)
        for (int x = tx * EW_DOF_TILE; x < ew_mini(W, (tx + 1) * EW_DOF_TILE); x++) {
            const float c = a->coc[(long)y * W + x];
            m = ew_maxf(m, c < 0.0f ? -c * a->cam.scale : 0.0f); /* m >= 0: the same as a branch, without one */
        }
    a->tiles[(long)ty * a->tw + tx] = m;
}

/* Steps 3-4: 1-D scatter-max along axis (0: reads tiles writes tiles2;
 * 1: reads tiles2 writes tiles). Tile s reaches tile t when some pixel of s
 * can be within reach (A / 2) of some pixel of t: (|s - t| - 1) * TILE <=
 * A / 2. */
EW_HD void ew_dof_scatter_px(int tx, int ty, int axis, const ew_dof_args *a) {
    const float *in = axis ? a->tiles2 : a->tiles;
    float *out = axis ? a->tiles : a->tiles2;
    const int n = axis ? a->th : a->tw, t = axis ? ty : tx;
    const int reach = (int)ceilf(0.5f * a->cam.max_coc * a->cam.scale / (float)EW_DOF_TILE) + 1;
    float m = 0.0f;
    for (int s = ew_maxi(0, t - reach); s <= ew_mini(n - 1, t + reach); s++) {
        const float c = in[axis ? (long)s * a->tw + tx : (long)ty * a->tw + s];
        const int d = s > t ? s - t : t - s;
        if ((float)((d - 1) * EW_DOF_TILE) <= 0.5f * c) m = ew_maxf(m, c);
    }
    out[(long)ty * a->tw + tx] = m;
}

/* Step 5's numbers for pixel (x, y): D and C (what step 5 stores, and
 * what a pass that wants them row by row computes, ew_dof_attr_rows). */
EW_HD void ew_dof_attr_of(int x, int y, const ew_dof_args *a, float *d, float *c) {
    const long j = (long)y * a->cam.width + x;
    const float cc = fabsf(a->coc[j]) * a->cam.scale;
    const float near = a->tiles[(long)(y / EW_DOF_TILE) * a->tw + x / EW_DOF_TILE];
    *d = ew_maxf(cc, near);
    *c = cc;
}

/* Step 5: the attributes (D, C) of pixel (x, y); planes is a->planes (a
 * separate argument, so that a loop specialised on it has unit strides). */
EW_HD void ew_dof_attr_px_k(int x, int y, const ew_dof_args *a, const int planes) {
    const long j = (long)y * a->cam.width + x;
    const long n = (long)a->cam.width * a->cam.height, ks = planes ? n : 1, js = planes ? 1 : 2;
    float d, c;
    ew_dof_attr_of(x, y, a, &d, &c);
    a->attr[j * js] = d;
    a->attr[ks + j * js] = c;
}

EW_HD void ew_dof_attr_px(int x, int y, const ew_dof_args *a) { ew_dof_attr_px_k(x, y, a, a->planes != 0); }

#endif
