/*
 * harm.h — the per-pixel steps of the do-no-harm stage that the op layer
 * runs around every denoiser (src/harm_stage.c):
 *
 *   before the method   DEMOD: radiance = colour / (albedo + eps), where the
 *                       extreme-outlier rejection (kernels/outlier.h) judges
 *                       samples; REMOD: the colour handed to the method, the
 *                       caller's own pixel wherever nothing was rejected.
 *   after the method    STATS, then BLEND: output = input + alpha (output -
 *                       input), with alpha from the residual r = T(input) -
 *                       T(output) over a (2 radius + 1)^2 window.
 *
 * Why this alpha. Write input = x + n (Monte Carlo noise, independent from
 * pixel to pixel: every sample lands in one pixel) and output = x + e (the
 * method's error). For a blend a output + (1 - a) input the expected error
 * is a^2 E[e^2] + (1 - a)^2 E[n^2], least at a = N / (N + D) with N = E[n^2]
 * and D = E[e^2]. Neither is known, but the residual r = n - e gives both:
 * R = mean r_p^2 ~ N + D, and C = mean r_p r_q over neighbouring pairs ~ D,
 * because the noise of neighbours is uncorrelated while what a method
 * removes wrongly (detail, shading, a blurred edge) is smooth at the scale
 * of one pixel. So a = (R - C) / R = 1 - C / R: 1 where the method removed
 * only noise, towards 0 where what it removed is structure the noise cannot
 * explain — a converged frame's reflections, motion blur, bokeh. No sample
 * count, no noise model. Three corrections, chosen on training scenes:
 * C counts only above z of its own standard deviations (sqrt of the sum of
 * the squared products: at 1-4 spp products of pure noise would pull alpha
 * below 1 at random); `strength` scales C / R up (C under-counts D: part
 * of the method's error is the input's own noise, anti-correlated with the
 * residual); and alpha stays 1 until strength C / R exceeds theta, so the
 * stage only steps in where the method's error is a large share of the
 * residual: at 1-2 spp, where N dwarfs D, mixing noisy input back in cost
 * more than the Wiener weight predicts.
 *
 * A second estimate of D, taken where it is the smaller alpha: the
 * residual's diagonal Haar detail H = sum of ((r_a - r_b - r_c + r_d) / 2)^2
 * over the 2x2 blocks, in linear units. Noise independent from pixel to
 * pixel passes into it whole (E[H] = N), while what the method removed of
 * the image, smooth at the scale of one pixel, cancels in it. So D = R_lin -
 * kappa H and alpha = 1 - D / R_lin, R_lin the mean square of the same
 * blocks' four residuals: a pixel counts in R_lin as often as in H (once
 * per block of the window holding it, fewer on the window's edge), so a
 * lone bright sample gives H = R_lin wherever it lies (with each pixel's
 * own square, one on the window's top or left edge read as 1/2 to 3/4
 * structure). On a converged frame C's z test, needed
 * against chance at 1-4 spp, hides much of a smooth error that this
 * estimate sees (64 spp: bgrid on a motion-blur scene -3.9 dB with C alone,
 * -0.8 dB with both). Linear, because in T the residual of a good method
 * has a mean of its own at 1 spp (T is concave: T(input) averages below
 * T(output)) that H does not see and would read as structure. alpha stays
 * 1 until D / R_lin exceeds theta_n: at 1 spp, H and R_lin of a window are
 * a few bright samples, and their ratio alone scatters. On a quiet frame
 * (16-64 spp) that concern is gone (theta_n 0, src/harm_stage.c) and so is
 * T's bias, small against T's own noise there; so the same estimate is
 * also taken in T (tone_share of it): in linear units the bright pixels
 * of a window outweigh the dark ones, where a viewer sees the method's
 * error as well (a sky over a dark ground, a highlight on a dim floor).
 *
 * T compresses like the display (gamma 1/2.2 below 1, logarithmic above,
 * continuous with slope 1/2.2 at 1), so the window statistics are not
 * swamped by one bright sample and measure what a viewer sees.
 */
#ifndef EW_KERNELS_HARM_H
#define EW_KERNELS_HARM_H

#include "kernels/color.h"
#include "kernels/denoise_px.h" /* EW_ALBEDO_EPSILON */
#include "kernels/fastmath.h"


enum {
    EW_HARM_DEMOD = 0,
    EW_HARM_REMOD = 1,
    EW_HARM_STATS = 2,
    EW_HARM_BLEND = 3,
    EW_HARM_SUM_H = 4,    /* energy return: the output's luminance summed over each window (rows) */
    EW_HARM_SUM_V = 5,    /* ... (columns) */
    EW_HARM_GIVE = 6,     /* what the clamps took at each pixel, over that sum */
    EW_HARM_SPREAD_H = 7, /* ... summed over each window (rows) */
    EW_HARM_SPREAD_V = 8, /* ... (columns), and the output scaled by it */
    EW_HARM_TAKE = 9,     /* what the rejection took that comes back, as a grey of that luminance */
    EW_HARM_SCALE = 10,   /* the output scaled by 1 + the frame's gain */
    EW_HARM_STATS_BLEND = 11, /* STATS and BLEND in bands of rows (a backend with harm_bands only) */
    EW_HARM_EXCESS = 12,  /* after REMOD: what the rejection took, as TAKE reads it, into excess */
    EW_HARM_PILOT_SQ = 13, /* after BLEND: each pixel's squared distances from the pilot, over the pilot */
    EW_HARM_PILOT_H = 14,  /* ... summed along the row into spread's first two planes */
    EW_HARM_PILOT_V = 15,  /* ... and along the column: the output blended toward the input by the pilot's alpha */
    EW_HARM_LIGHT = 16,    /* fused, on a tile's region after its blend: the light the method's clamp took
                              into give (GIVE's numerator), while the region still holds the clamped colour */
    EW_HARM_RETURN = 17,   /* SUM_H .. SPREAD_V in bands of rows, without spread (a backend with harm_bands only) */
    EW_HARM_PILOT_HV = 18  /* PILOT_H and PILOT_V in bands of rows, without spread (harm_bands only) */
};
#define EW_HARM_STATS_FLOATS 6

typedef struct ew_harm_args {
    int width, height;
    int channels;           /* floats per pixel of color (>= 3) */
    int clamped_channels;   /* floats per pixel of clamped: 3 (a method that reads RGB only), or 0: as color
                               (the ones past RGB copied) */
    const float *color;     /* the caller's colour, packed */
    const float *albedo;    /* 3 per pixel, or NULL: no demodulation */
    float *radiance;        /* 3 per pixel: DEMOD writes it */
    const float *rejected;  /* 3 per pixel: radiance after the outlier rejection (REMOD reads it; it may be
                               clamped itself when that is RGB: each pixel is read before it is written) */
    float *clamped;         /* clamped_channels per pixel: REMOD writes it (the method's input, and the blend's) */
    float *out;             /* 3 per pixel: the method's output; BLEND rewrites it in place */
    float *stats;           /* EW_HARM_STATS_FLOATS per pixel: STATS writes r^2, the neighbour product, its
                               square, and in linear units the residual's diagonal Haar detail squared
                               and the mean square of the same block's four residuals */
    int radius;             /* BLEND window */
    float strength;         /* BLEND: alpha = 1 - strength * max(C - z sd(C), 0) / R */
    float z;
    float theta;            /* alpha stays 1 while strength * C / R <= theta */
    float kappa;            /* BLEND, second estimate: D = R_lin - kappa H (H: the residual's diagonal Haar
                               detail); 0: off */
    float theta_n;          /* ... and alpha stays 1 while D / R_lin <= theta_n */
    float tone_share;       /* ... D / R taken this share in T, the rest in linear units */
    float fade;             /* BLEND: alpha + fade (1 - alpha): 0 the blend as estimated, 1 none */
    /* energy return (SUM_H, SUM_V, GIVE, SPREAD_H, SPREAD_V; TAKE, SCALE): */
    float *give;            /* 1 per pixel: in, the share of the pixel's RGB the method's own clamp took
                               (ew_outlier_buffers.removed: of the colour it was given, clamped here);
                               GIVE rewrites it as the pixel's share of its window's light, then TAKE as
                               the luminance of what the rejection took that comes back */
    float *spread;          /* 2 per pixel: the box sums (SUM_H, then SPREAD_H over it; S); not read by
                               RETURN and PILOT_HV, which hold a band's sums themselves */
    int give_radius;        /* each pixel's light goes back over its (2 give_radius + 1)^2 window */
    float give_cap;         /* of what the rejection (color - clamped) took, at most give_cap x the
                               luminance it left comes back; 0: none */
    float give_limit;       /* and of all a pixel gives back, at most this luminance */
    float give_gain;        /* SPREAD_V: no pixel is scaled by more than 1 + give_gain */
    float take_limit;       /* TAKE: of what the rejection took, a pixel gives back at most this luminance */
    float gain;             /* SCALE: every pixel of the output is scaled by 1 + gain */
    int band_rows;          /* STATS_BLEND, RETURN, PILOT_HV: rows a band; 0: the backend's choice */
    float *excess;          /* 1 per pixel, or NULL: EXCESS writes the luminance the rejection took (color -
                               clamped, as TAKE computes it) where it is not 0 (zero it first) and TAKE
                               reads it there instead of from color, which the method's output may have
                               overwritten by then */
    float *pilot;           /* PILOT_*: 3 per pixel, another method's output on the same input in T (ew_harm_tone;
                               src/harm_stage.c); PILOT_SQ overwrites its first two floats a pixel */
    float pilot_share;      /* PILOT_V: the pilot's alpha taken this share (0: none, 1: all) */
    int fused;              /* 1: the stage ran inside the method's tiles (src/harm_stage.c), whose output
                               has overwritten the clamped colour by GIVE and TAKE: give holds what LIGHT
                               wrote, and excess what the rejection took already capped at give_cap x what
                               it left (EXCESS); the same values GIVE and TAKE compute from the colour */
} ew_harm_args;

/* floats per pixel of clamped */
EW_HD int ew_harm_cch(const ew_harm_args *a) { return a->clamped_channels ? a->clamped_channels : a->channels; }

EW_HD int ew_harm_finite3(const float *v) { return ew_finitef(v[0]) && ew_finitef(v[1]) && ew_finitef(v[2]); }

/* ew_albedo_factor's value (a damaged or negative albedo counts as black),
 * by an integer mask on the bits: 0 < bits < those of +inf is a positive,
 * finite albedo. Branch-free, so that a row of them vectorises. */
EW_HD float ew_harm_albedo_factor(float albedo) {
    const int b = ew_float_to_bits(albedo);
    return ew_bits_to_float(b & -((b > 0) & (b < 0x7f800000))) + EW_ALBEDO_EPSILON;
}

EW_HD float ew_harm_albedo(const ew_harm_args *a, long j, int c) {
    return a->albedo ? ew_harm_albedo_factor(a->albedo[j * 3 + c]) : 1.0f;
}

/* the finite test of ew_finitef on the bits (vectorises): not all exponent bits set */
EW_HD int ew_harm_finite_bits(float v) { return (ew_float_to_bits(v) & 0x7f800000) != 0x7f800000; }

/* REMOD's choice for a pixel: the caller's colour where the rejection kept
 * the radiance r0 as r1 (or r1 is not finite) */
EW_HD int ew_harm_kept(const float *r0, const float *r1) {
    return ((r0[0] == r1[0]) & (r0[1] == r1[1]) & (r0[2] == r1[2])) |
           !(ew_harm_finite_bits(r1[0]) & ew_harm_finite_bits(r1[1]) & ew_harm_finite_bits(r1[2]));
}

/* display-like compression (see above): v^(1/2.2) below 1, 1 + ln(v) / 2.2
 * above; non-finite and negative: 0. Through log2 and exp2 in plain
 * arithmetic (kernels/fastmath.h, a few 1e-7 relative, as libm's powf and
 * logf round), both branches computed and one taken by integer masks on
 * the bits (positive floats order as ints), so that a row of them
 * vectorises: the stage takes six a pixel. (Below 1e-37 the value is that
 * of 1e-37, 1e-17: a residual's scale is 1e-3 and up.) */
EW_HD float ew_harm_log2(float v) { /* ew_flog2's value, in integer selects (vectorises) */
    int b = ew_float_to_bits(v);
    b = b < 0x02081cea ? 0x02081cea : b; /* 1e-37 (and v <= 0, as ints) */
    const int big = (b & 0x007fffff) > 0x003504f3; /* mantissa > sqrt(2): halved */
    const float m = ew_bits_to_float(((b & 0x007fffff) | 0x3f800000) - (big << 23));
    return (float)((b >> 23) - 127 + big) + ew_flog2_mantissa(m);
}

EW_HD float ew_harm_tone(float v) {
    const int b = ew_float_to_bits(v);
    const float l = ew_harm_log2(v);
    const float below = ew_fexp2(l * (1.0f / 2.2f)), above = 1.0f + l * (0.693147181f / 2.2f);
    const int lo = -(b < 0x3f800000), ok = -((b > 0) & (b < 0x7f800000)); /* v < 1; 0 < v < inf */
    return ew_bits_to_float(((ew_float_to_bits(below) & lo) | (ew_float_to_bits(above) & ~lo)) & ok);
}

/* v where it is finite, else 0 (integer masks: vectorises) */
EW_HD float ew_harm_finite_or0(float v) {
    const int b = ew_float_to_bits(v);
    return ew_bits_to_float(b & -((b & 0x7f800000) != 0x7f800000));
}

/* T(c) - T(o): finite (T is) */
EW_HD float ew_harm_tone_diff(float c, float o) { return ew_harm_tone(c) - ew_harm_tone(o); }

EW_HD float ew_harm_residual(const ew_harm_args *a, long j, int c) {
    return ew_harm_tone_diff(a->clamped[j * ew_harm_cch(a) + c], a->out[j * 3 + c]);
}

EW_HD void ew_harm_demod_px(long j, const ew_harm_args *a) {
    for (int c = 0; c < 3; c++) a->radiance[j * 3 + c] = a->color[j * a->channels + c] / ew_harm_albedo(a, j, c);
}

/* The caller's own pixel where the rejection kept the radiance (no
 * rounding through / and *), else the rejected radiance remodulated. */
EW_HD void ew_harm_remod_px(long j, const ew_harm_args *a) {
    const long cc = a->channels, ck = ew_harm_cch(a);
    const float *r1 = a->rejected + j * 3;
    const int same = ew_harm_kept(a->radiance + j * 3, r1);
    for (long c = 0; c < ck; c++)
        a->clamped[j * ck + c] = same || c >= 3 ? a->color[j * cc + c] : r1[c] * ew_harm_albedo(a, j, (int)c);
}

/* the residual input - output in linear units, non-finite as 0 */
EW_HD float ew_harm_lin_residual(const ew_harm_args *a, long j, int c) {
    return ew_harm_finite_or0(a->clamped[j * ew_harm_cch(a) + c] - a->out[j * 3 + c]);
}

/* The statistics of (x, y) from its residuals (3 floats each, T then
 * linear): t at the pixel, tr and td at its right and lower neighbours
 * (NULL past the frame), tb and lb at the 2x2 block of the diagonal Haar
 * detail (the one at (x, y), moved inward at the last row and column; NULL
 * when the frame has none), l at the pixel. The CPU backend passes rows of
 * residuals it computed once (each pixel's are read by up to seven
 * pixels); ew_harm_stats_px computes them here: the same bits either way. */
EW_HD void ew_harm_stats_from(long j, const ew_harm_args *a, const float *t, const float *tr, const float *td,
                              const float *const *tb, const float *const *lb, const float *l) {
    float sq = 0.0f, cross = 0.0f, hh2 = 0.0f, lin2 = 0.0f, th2 = 0.0f;
    for (int c = 0; c < 3; c++) {
        const float r = t[c];
        sq += r * r;
        if (tr) cross += r * tr[c];
        if (td) cross += r * td[c];
        if (tb) {
            const float hh = 0.5f * (lb[0][c] - lb[1][c] - lb[2][c] + lb[3][c]);
            hh2 += hh * hh;
            const float th = 0.5f * (tb[0][c] - tb[1][c] - tb[2][c] + tb[3][c]);
            th2 += th * th;
            lin2 += 0.25f * (lb[0][c] * lb[0][c] + lb[1][c] * lb[1][c] + lb[2][c] * lb[2][c] + lb[3][c] * lb[3][c]);
        } else {
            const float d = l[c];
            lin2 += d * d;
        }
    }
    const int pairs = (tr != 0) + (td != 0);
    cross = pairs ? cross / (float)pairs : 0.0f;
    float *st = a->stats + j * EW_HARM_STATS_FLOATS;
    st[0] = sq;
    st[1] = cross;
    st[2] = cross * cross;
    st[3] = hh2;
    st[4] = lin2;
    st[5] = th2;
}

/* The T and linear residuals of pixel j into t[3], l[3]. */
EW_HD void ew_harm_residuals(const ew_harm_args *a, long j, float *t, float *l) {
    for (int c = 0; c < 3; c++) {
        t[c] = ew_harm_residual(a, j, c);
        l[c] = ew_harm_lin_residual(a, j, c);
    }
}

EW_HD void ew_harm_stats_px(int x, int y, const ew_harm_args *a) {
    const long j = (long)y * a->width + x;
    /* the 2x2 block of the diagonal Haar detail: the one at (x, y), moved
     * inward at the last row and column (a 1-pixel frame has none) */
    const int bx = x + 1 < a->width ? x : x - 1, by = y + 1 < a->height ? y : y - 1;
    const long b0 = (long)by * a->width + bx;
    float t[3], l[3], tr[3], td[3], lr[3], ld[3], tbv[4][3], lbv[4][3];
    ew_harm_residuals(a, j, t, l);
    if (x + 1 < a->width) ew_harm_residuals(a, j + 1, tr, lr);
    if (y + 1 < a->height) ew_harm_residuals(a, j + a->width, td, ld);
    const float *tb[4], *lb[4];
    const int block = bx >= 0 && by >= 0;
    if (block) {
        const long at[4] = {b0, b0 + 1, b0 + a->width, b0 + a->width + 1};
        for (int i = 0; i < 4; i++) {
            ew_harm_residuals(a, at[i], tbv[i], lbv[i]);
            tb[i] = tbv[i];
            lb[i] = lbv[i];
        }
    }
    ew_harm_stats_from(j, a, t, x + 1 < a->width ? tr : 0, y + 1 < a->height ? td : 0, block ? tb : 0,
                       block ? lb : 0, l);
}

/* a where m is all ones, b where it is 0: a select on the bits, which a
 * row loop vectorises (a float select keeps it scalar) */
EW_HD float ew_harm_sel(int m, float a, float b) {
    return ew_bits_to_float((ew_float_to_bits(a) & m) | (ew_float_to_bits(b) & ~m));
}
/* ew_maxf's, ew_minf's and ew_clampf(v, 0, 1)'s values (NaN included) as selects */
EW_HD float ew_harm_max(float a, float b) { return ew_harm_sel(-(a > b), a, b); }
EW_HD float ew_harm_min(float a, float b) { return ew_harm_sel(-(a < b), a, b); }
EW_HD float ew_harm_clamp01(float v) { return ew_harm_sel(-(v < 0.0f), 0.0f, ew_harm_sel(-(v > 1.0f), 1.0f, v)); }

/* BLEND's alpha from the window sums of the statistics (sq, cross, cross2,
 * hh2, lin2, th2: ew_harm_args.stats' six), the other arguments those of
 * ew_harm_args. Written as selects between values computed for every
 * pixel (a division by 0 in the value not taken is harmless), so that a
 * row of them vectorises; the value is that of the tests it stands for. */
EW_HD float ew_harm_alpha(float sq, float cross, float cross2, float hh2, float lin2, float th2, float z,
                          float strength, float theta, float kappa, float theta_n, float tone_share, float fade) {
    /* C is a sum of products of noisy residuals: only what stands z of its
     * own standard deviations above 0 counts as structure (at 1-4 spp the
     * products of pure noise would otherwise pull alpha below 1 at random) */
    const float excess = ew_harm_max(cross - z * sqrtf(cross2), 0.0f);
    const float q = ew_harm_sel(-(sq > 0.0f), strength * excess / sq, 0.0f);
    const float alpha = ew_harm_clamp01(1.0f - ew_harm_max(q - theta, 0.0f) / (1.0f - theta));
    /* Second estimate, in linear units: the residual's diagonal Haar detail
     * H (see above) keeps its noise and drops what is smooth at the scale
     * of one pixel, so R_lin - kappa H is what the method removed of the
     * image. Unlike C it needs no threshold against chance, so it also
     * catches a converged frame's error where C's z test hides it. Taken
     * where kappa > 0 and lin2 > 0; its share in T where tone_share > 0
     * and sq > 0. */
    const float ql = ew_harm_max(lin2 - kappa * hh2, 0.0f) / lin2;
    const float qt = ql + tone_share * (ew_harm_max(sq - kappa * th2, 0.0f) / sq - ql);
    const float qn = ew_harm_sel(-((tone_share > 0.0f) & (sq > 0.0f)), qt, ql);
    const float an = ew_harm_min(alpha, ew_harm_clamp01(1.0f - ew_harm_max(qn - theta_n, 0.0f) / (1.0f - theta_n)));
    const float est = ew_harm_sel(-((kappa > 0.0f) & (lin2 > 0.0f)), an, alpha);
    return est + fade * (1.0f - est);
}

/* BLEND's mix at pixel j for its alpha: alpha 1, the method's output
 * exactly; a missing sample, the method's reconstruction */
EW_HD void ew_harm_blend_mix(long j, const ew_harm_args *a, float alpha) {
    const float *in = a->clamped + j * ew_harm_cch(a);
    float *o = a->out + j * 3;
    if (alpha >= 1.0f || !ew_harm_finite3(in)) return;
    /* the blend gives the pixel 1 - alpha of the input back, and with it
     * that share of what the method's own clamp took there */
    if (a->give) ew_store_sparse(a->give + j, a->give[j] * alpha);
    for (int c = 0; c < 3; c++) o[c] = in[c] + alpha * (o[c] - in[c]);
}

/* BLEND at pixel j from the window sums of its statistics (sums[k]: the
 * sum of stats[k] over the window, in raster order). */
EW_HD void ew_harm_blend_apply(long j, const ew_harm_args *a, const float *sums) {
    ew_harm_blend_mix(j, a, ew_harm_alpha(sums[0], sums[1], sums[2], sums[3], sums[4], sums[5], a->z, a->strength,
                                          a->theta, a->kappa, a->theta_n, a->tone_share, a->fade));
}

/* The window sums in a separable order: each column of the window summed
 * over its rows (ascending), then those column sums along the row
 * (ascending). A backend that sums the columns of a whole row once, then
 * the row (the CPU backend), gets the same bits as this pixel-at-a-time
 * body: 2 (2 radius + 1) adds a statistic where the window has
 * (2 radius + 1)^2. */
EW_HD void ew_harm_blend_px(int x, int y, const ew_harm_args *a) {
    float sums[EW_HARM_STATS_FLOATS] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    const int y0 = ew_maxi(y - a->radius, 0), y1 = ew_mini(y + a->radius, a->height - 1);
    for (int xx = ew_maxi(x - a->radius, 0); xx <= ew_mini(x + a->radius, a->width - 1); xx++) {
        float col[EW_HARM_STATS_FLOATS] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
        for (int yy = y0; yy <= y1; yy++) {
            const float *st = a->stats + ((long)yy * a->width + xx) * EW_HARM_STATS_FLOATS;
            for (int k = 0; k < EW_HARM_STATS_FLOATS; k++) col[k] += st[k];
        }
        for (int k = 0; k < EW_HARM_STATS_FLOATS; k++) sums[k] += col[k];
    }
    ew_harm_blend_apply((long)y * a->width + x, a, sums);
}

/* Energy return. Every clamp before the method (the rejection above, the
 * method's own firefly clamp) takes light the frame had; the method cannot
 * put it back, so a frame lit by sparse bright samples (a caustic, a small
 * light at 1-16 spp) came out at 0.6-0.8 of its mean. The light is given
 * back after the method, each clamp's where its kind of light belongs.
 *
 * What the method's own clamp took (mean + 3 sigma of a 5x5 window: it cuts
 * legitimate light, the sparse samples of a dark region at 1-4 spp) comes
 * back over a window around where it was taken, in proportion to the
 * method's output there: the light goes where the method says light is (a
 * lamp's rim clamped next to the lamp goes back into the lamp, not into a
 * halo on the dark wall; a sparse-lit region gets brighter as it is
 * shaped), never the spike again. Pixel i gives g_i; pixel j gets out_j x
 * the sum over the windows holding it of g_i / S_i, S_i the output's
 * luminance summed over i's window (box sums, two passes each). It comes
 * back whole, times the blend's alpha (the blend already gave 1 - alpha of
 * the input back); a pixel gives at most give_limit; and no pixel grows by
 * more than give_gain of itself (in a dark window with one bright remnant,
 * the remnant would take it all).
 *
 * What the rejection took (a sample orders of magnitude above the median
 * of its surface) is a rare path whose expected light is spread over a
 * region of unknown size: given back over its own window it lit that
 * window (raising the caps to return more of it that way cost a firefly
 * training scene up to 4.6 dB), while over the whole frame, in proportion
 * to the output (one gain for every pixel), the same light changes each
 * pixel by the same small ratio (0.8 dB there with the caps off). TAKE
 * adds it up, at most give_cap times the luminance the rejection left (a
 * sample hundreds of times brighter than its surface carries far more than
 * its pixel's share of the frame) and take_limit a pixel (a damaged sample
 * would otherwise brighten the frame); SCALE applies the gain. */
/* The energy return's box sums: the 2 r + 1 taps of a window in blocks of
 * ew_harm_box_block(r) consecutive taps (7 blocks of 7 for the 49 of r 24),
 * each block's taps added in order, then the blocks in order; taps past the
 * frame add nothing. A backend that sums the blocks of a whole row (or of a
 * run of rows) once reuses each block for that many pixels — 2 sqrt(49)
 * adds a pixel instead of 49, as the CPU backend does — and gets the same
 * bits as these pixel-at-a-time bodies. */
EW_HD int ew_harm_box_block(int r) {
    const int n = 2 * r + 1;
    int b = 1;
    for (int d = 2; d * d <= n; d++)
        if (n % d == 0) b = d;
    return b;
}

/* the output's luminance at j where it is finite and positive, else 0 */
EW_HD float ew_harm_lum_tap(const ew_harm_args *a, long j) {
    const float l = ew_luminance(a->out + j * 3);
    return ew_finitef(l) && l > 0.0f ? l : 0.0f;
}

/* The box sum over x - r .. x + r of row y of v (lum: the output's
 * luminance taps instead, v unused). */
EW_HD float ew_harm_box_h(const ew_harm_args *a, const float *v, int lum, int x, int y, int r) {
    const int b = ew_harm_box_block(r);
    const long row = (long)y * a->width;
    float s = 0.0f;
    for (int k0 = x - r; k0 <= x + r; k0 += b) {
        float blk = 0.0f;
        for (int xx = ew_maxi(k0, 0); xx <= ew_mini(k0 + b - 1, a->width - 1); xx++)
            blk += lum ? ew_harm_lum_tap(a, row + xx) : v[row + xx];
        s += blk;
    }
    return s;
}

/* The box sum over y - r .. y + r of column x of v. */
EW_HD float ew_harm_box_v(const ew_harm_args *a, const float *v, int x, int y, int r) {
    const int b = ew_harm_box_block(r);
    float s = 0.0f;
    for (int k0 = y - r; k0 <= y + r; k0 += b) {
        float blk = 0.0f;
        for (int yy = ew_maxi(k0, 0); yy <= ew_mini(k0 + b - 1, a->height - 1); yy++) blk += v[(long)yy * a->width + x];
        s += blk;
    }
    return s;
}

/* SUM_H: the output's luminance (finite, positive) summed along the row */
EW_HD void ew_harm_sum_h_px(int x, int y, const ew_harm_args *a) {
    a->spread[(long)y * a->width + x] = ew_harm_box_h(a, NULL, 1, x, y, a->give_radius);
}

/* SUM_V: ... and along the column: S */
EW_HD void ew_harm_sum_v_px(int x, int y, const ew_harm_args *a) {
    const long n = (long)a->width * a->height;
    a->spread[n + (long)y * a->width + x] = ew_harm_box_v(a, a->spread, x, y, a->give_radius);
}

/* the luminance of what the method's clamp took at pixel j: its share
 * give[j] of the colour it was given (negative channels are no light) */
EW_HD float ew_harm_clamp_light(long j, const ew_harm_args *a) {
    const float *c1 = a->clamped + j * ew_harm_cch(a);
    const float rgb[3] = {ew_maxf(c1[0], 0.0f), ew_maxf(c1[1], 0.0f), ew_maxf(c1[2], 0.0f)};
    return a->give[j] * ew_luminance(rgb);
}

/* LIGHT (fused): that luminance into give[j] */
EW_HD void ew_harm_light_px(long j, const ew_harm_args *a) { ew_store_sparse(a->give + j, ew_harm_clamp_light(j, a)); }

/* GIVE: g / S into give[j], g the luminance of what the method's clamp
 * took: its share of the colour it was given (the clamped colour; negative
 * channels are no light, as the methods demodulate them). The rejection's
 * share goes to the whole frame, TAKE. At pixel j with S = sum (a backend's
 * banded RETURN has S where spread's plane would) */
EW_HD void ew_harm_give_at(long j, const ew_harm_args *a, float sum) {
    const float m = a->fused ? a->give[j] : ew_harm_clamp_light(j, a);
    const float lg = ew_minf(ew_finitef(m) && m > 0.0f ? m : 0.0f, a->give_limit);
    ew_store_sparse(a->give + j, sum > 0.0f ? lg / sum : 0.0f);
}

/* ... S from spread's second plane (SUM_V) */
EW_HD void ew_harm_give_px(int x, int y, const ew_harm_args *a) {
    const long j = (long)y * a->width + x, n = (long)a->width * a->height;
    ew_harm_give_at(j, a, a->spread[n + j]);
}

/* The luminance of what the rejection took from a pixel (color - clamped,
 * each channel's positive part) */
EW_HD float ew_harm_excess_lum(long j, const ew_harm_args *a) {
    const float *c0 = a->color + j * a->channels, *c1 = a->clamped + j * ew_harm_cch(a);
    float ex[3];
    for (int c = 0; c < 3; c++) {
        const float e = c0[c] - c1[c];
        ex[c] = ew_finitef(e) && e > 0.0f ? e : 0.0f;
    }
    return ew_luminance(ex);
}

/* the luminance the rejection left at pixel j (of the clamped colour, negative as 0) */
EW_HD float ew_harm_left_lum(long j, const ew_harm_args *a) {
    return ew_maxf(ew_luminance(a->clamped + j * ew_harm_cch(a)), 0.0f);
}

/* EXCESS: that luminance kept for TAKE, the colour not needed after it.
 * Only where the rejection took something (excess is zero before): the
 * pixels it judges extreme are few, and a page not written is not held */
EW_HD void ew_harm_excess_px(long j, const ew_harm_args *a) {
    const float le = ew_harm_excess_lum(j, a);
    if (le != 0.0f) a->excess[j] = a->fused ? ew_minf(le, a->give_cap * ew_harm_left_lum(j, a)) : le;
}

/* TAKE: the luminance of what the rejection took that comes back, at most
 * give_cap x the luminance it left and take_limit, into give[j] (the
 * frame's sum adds it up) */
EW_HD void ew_harm_take_px(long j, const ew_harm_args *a) {
    float lr;
    if (a->fused) {
        lr = ew_minf(a->excess[j], a->take_limit);
    } else {
        const float le = a->excess ? a->excess[j] : ew_harm_excess_lum(j, a);
        lr = ew_minf(ew_minf(le, a->give_cap * ew_harm_left_lum(j, a)), a->take_limit);
    }
    ew_store_sparse(a->give + j, lr > 0.0f ? lr : 0.0f);
}

/* SCALE: the output scaled by 1 + the frame's gain (finite pixels) */
EW_HD void ew_harm_scale_px(long j, const ew_harm_args *a) {
    float *o = a->out + j * 3;
    if (!ew_harm_finite3(o) || !(a->gain > 0.0f)) return;
    for (int c = 0; c < 3; c++) o[c] *= 1.0f + a->gain;
}

/* SPREAD_H: the shares g / S summed along the row, where SUM_H's sums
 * were (SUM_V has read them) */
EW_HD void ew_harm_spread_h_px(int x, int y, const ew_harm_args *a) {
    /* as ew_harm_box_h, over give */
    const int b = ew_harm_box_block(a->give_radius), r = a->give_radius;
    float s = 0.0f;
    for (int k0 = x - r; k0 <= x + r; k0 += b) {
        float blk = 0.0f;
        for (int xx = ew_maxi(k0, 0); xx <= ew_mini(k0 + b - 1, a->width - 1); xx++)
            blk += a->give[(long)y * a->width + xx];
        s += blk;
    }
    a->spread[(long)y * a->width + x] = s;
}

/* SPREAD_V: ... and along the column; the output scaled by 1 + that
 * (at pixel j, the column's sum `sum`) */
EW_HD void ew_harm_spread_at(long j, const ew_harm_args *a, float sum) {
    const float t = ew_minf(sum, a->give_gain);
    float *o = a->out + j * 3;
    if (!ew_harm_finite3(o) || !(t > 0.0f)) return;
    for (int c = 0; c < 3; c++) o[c] *= 1.0f + t;
}

/* ... the column's sum over spread's first plane (SPREAD_H) */
EW_HD void ew_harm_spread_v_px(int x, int y, const ew_harm_args *a) {
    ew_harm_spread_at((long)y * a->width + x, a, ew_harm_box_v(a, a->spread, x, y, a->give_radius));
}

/* The pilot: a noise estimate from a second method's output. On a
 * converged frame the blend above cannot tell the input's noise from what
 * the method removed at the scale of one pixel (a glossy reflection of
 * texture, an outline the grid moved): both pass into the residual's Haar
 * detail, so alpha stays high exactly where the method did harm. A second
 * denoiser run on the same input, p, gives the two figures apart: the input's
 * distance from p over a window, N = sum (T(in) - T(p))^2, is its noise
 * (plus p's own error, small where p keeps that detail), and the output's,
 * D = sum (T(out) - T(p))^2, what the method changed beyond p. So alpha =
 * N / (N + D), the Wiener weight of those two, applied to the blended
 * output: 1 where the method agrees with p, toward the input where it
 * removed what p kept. p itself is never mixed in: the output stays the
 * method's own, moved toward the input. Sums over the blend's window
 * (radius), RGB averaged, in T (the stage hands p in T already). Where the method is better than p the
 * weight takes p's error for the method's and gives back some noise; a
 * threshold on D's share (no blend below 0.1 of N + D) won that back on
 * average (+0.05 to +0.07 dB on 50 training scenes at 16-64 spp) but left the
 * worst frames below their input (-0.16 against -0.12 dB at 64 spp; the
 * worst 64x64 region of a glossy frame -0.34 against -0.16): not taken. */
EW_HD void ew_harm_pilot_sq_px(long j, const ew_harm_args *a) {
    const float *in = a->clamped + j * ew_harm_cch(a), *o = a->out + j * 3;
    float *p = a->pilot + j * 3;
    float n = 0.0f, d = 0.0f;
    for (int c = 0; c < 3; c++) {
        const float tp = p[c], ti = ew_harm_tone(in[c]) - tp, to = ew_harm_tone(o[c]) - tp;
        n += ti * ti;
        d += to * to;
    }
    p[0] = n;
    p[1] = d;
}

/* PILOT_H: N and D summed along the row (taps past the frame add nothing) */
EW_HD void ew_harm_pilot_h_px(int x, int y, const ew_harm_args *a) {
    const long n = (long)a->width * a->height, row = (long)y * a->width;
    float sn = 0.0f, sd = 0.0f;
    for (int xx = ew_maxi(x - a->radius, 0); xx <= ew_mini(x + a->radius, a->width - 1); xx++) {
        sn += a->pilot[(row + xx) * 3];
        sd += a->pilot[(row + xx) * 3 + 1];
    }
    a->spread[row + x] = sn;
    a->spread[n + row + x] = sd;
}

/* PILOT_V: ... and along the column, then the blend by N / (N + D), taken
 * pilot_share of the way (a ramp with the frame's noise level) */
EW_HD void ew_harm_pilot_v_px(int x, int y, const ew_harm_args *a) {
    const long n = (long)a->width * a->height;
    float sn = 0.0f, sd = 0.0f;
    for (int yy = ew_maxi(y - a->radius, 0); yy <= ew_mini(y + a->radius, a->height - 1); yy++) {
        sn += a->spread[(long)yy * a->width + x];
        sd += a->spread[n + (long)yy * a->width + x];
    }
    const float alpha = sn + sd > 0.0f ? sn / (sn + sd) : 1.0f;
    ew_harm_blend_mix((long)y * a->width + x, a, 1.0f - a->pilot_share * (1.0f - alpha));
}

/* Every step's body at one pixel (x, y): what a backend without faster
 * rows of its own runs for each pixel of the frame (EW_HARM_STATS_BLEND
 * is STATS, then BLEND: two launches, not one body). */
EW_HD void ew_harm_px(int step, int x, int y, const ew_harm_args *a) {
    const long j = (long)y * a->width + x;
    switch (step) {
    case EW_HARM_DEMOD: ew_harm_demod_px(j, a); break;
    case EW_HARM_REMOD: ew_harm_remod_px(j, a); break;
    case EW_HARM_STATS: ew_harm_stats_px(x, y, a); break;
    case EW_HARM_BLEND: ew_harm_blend_px(x, y, a); break;
    case EW_HARM_SUM_H: ew_harm_sum_h_px(x, y, a); break;
    case EW_HARM_SUM_V: ew_harm_sum_v_px(x, y, a); break;
    case EW_HARM_GIVE: ew_harm_give_px(x, y, a); break;
    case EW_HARM_SPREAD_H: ew_harm_spread_h_px(x, y, a); break;
    case EW_HARM_SPREAD_V: ew_harm_spread_v_px(x, y, a); break;
    case EW_HARM_TAKE: ew_harm_take_px(j, a); break;
    case EW_HARM_SCALE: ew_harm_scale_px(j, a); break;
    case EW_HARM_EXCESS: ew_harm_excess_px(j, a); break;
    case EW_HARM_PILOT_SQ: ew_harm_pilot_sq_px(j, a); break;
    case EW_HARM_PILOT_H: ew_harm_pilot_h_px(x, y, a); break;
    case EW_HARM_PILOT_V: ew_harm_pilot_v_px(x, y, a); break;
    case EW_HARM_LIGHT: ew_harm_light_px(j, a); break;
    default: break;
    }
}

#endif
