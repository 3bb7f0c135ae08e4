/*
 * temporal.h — temporal accumulation with reprojection (as in SVGF,
 * Schied et al. 2017, and the temporal stage of Meng et al. 2020 §4.6).
 *
 * Each pixel follows its motion vector to the previous frame, takes the
 * bilinear taps of the history there that agree with it in normal and depth
 * (a disoccluded or mismatched tap is dropped), and blends:
 *   out = mix(history, current, alpha),  alpha = max(1 / (n + 1), alpha_min)
 * where n is the number of frames already accumulated at that tap (capped),
 * so a new pixel starts from its own value and a long history decays with
 * alpha_min (0.2 in the paper). Without any valid tap the history restarts.
 */
#ifndef EW_KERNELS_TEMPORAL_H
#define EW_KERNELS_TEMPORAL_H

#include "kernels/compat.h"

typedef struct ew_temporal_params {
    int width, height;
    float alpha_min;      /* 0.2 */
    float normal_cos;     /* taps whose normals differ by more (cosine below) are rejected: 0.9 */
    float depth_rel;      /* taps whose depth differs by more than this fraction are rejected: 0.1 */
    float motion_sign;    /* +1: Blender's Vector pass, rows top first: previous position = (x + X, y - Y)
                           * (its y axis points up); -1: the opposite of both */
    float max_frames;     /* cap of the history length */
    float clamp;          /* history clamp, in the current frame's standard deviations (ew_temporal_clip); <= 0: off */
} ew_temporal_params;

typedef struct ew_temporal_buffers {
    const float *color;   /* 3 per pixel, current frame */
    const float *normal;  /* 3 per pixel or NULL */
    const float *depth;   /* 1 per pixel or NULL */
    const float *motion;  /* 2 per pixel (X, Y) in pixels, Blender's Vector.XY, or NULL (static camera) */
    const float *prev_color, *prev_normal, *prev_depth, *prev_len; /* history (prev_len NULL: none) */
    float *out_color;     /* 3 per pixel */
    float *out_len;       /* 1 per pixel */
} ew_temporal_buffers;

EW_HD int ew_temporal_tap_ok(const ew_temporal_params *p, const ew_temporal_buffers *b, long j, long k) {
    if (b->prev_len[k] <= 0.0f) return 0;
    for (int c = 0; c < 3; c++)
        if (!ew_finitef(b->prev_color[k * 3 + c])) return 0;
    if (b->normal && b->prev_normal) {
        const float *n0 = b->normal + j * 3, *n1 = b->prev_normal + k * 3;
        float d = n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2];
        float l = sqrtf((n0[0] * n0[0] + n0[1] * n0[1] + n0[2] * n0[2]) * (n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2]));
        if (l > 0.0f && d < p->normal_cos * l) return 0;
    }
    if (b->depth && b->prev_depth) {
        float d0 = b->depth[j], d1 = b->prev_depth[k];
        if (!(fabsf(d0 - d1) <= p->depth_rel * ew_maxf(fabsf(d0), fabsf(d1)) + 1e-6f)) return 0;
    }
    return 1;
}

/* Optional history clamp (variance clipping, Salvi 2016, as in TAA and
 * A-SVGF): the reprojected history is clamped, per channel, to the current
 * frame's 3x3 mean +- gamma standard deviations before blending, so history
 * that no longer matches (shading changes, resampling blur, missed
 * disocclusions) cannot linger. Meant for a frame that is already denoised,
 * whose neighbourhood statistics are tight. gamma <= 0: off. */
EW_HD void ew_temporal_clip(int x, int y, const ew_temporal_params *p, const float *color, float gamma, float *hist) {
    float s1[3] = {0.0f, 0.0f, 0.0f}, s2[3] = {0.0f, 0.0f, 0.0f};
    int n = 0;
    for (int yy = ew_maxi(y - 1, 0); yy <= ew_mini(y + 1, p->height - 1); yy++)
        for (int xx = ew_maxi(x - 1, 0); xx <= ew_mini(x + 1, p->width - 1); xx++) {
            const float *c = color + ((long)yy * p->width + xx) * 3;
            if (!ew_finitef(c[0]) || !ew_finitef(c[1]) || !ew_finitef(c[2])) continue;
            for (int k = 0; k < 3; k++) {
                s1[k] += c[k];
                s2[k] += c[k] * c[k];
            }
            n++;
        }
    if (n == 0) return;
    for (int k = 0; k < 3; k++) {
        const float m = s1[k] / (float)n;
        const float sd = sqrtf(ew_maxf(s2[k] / (float)n - m * m, 0.0f));
        hist[k] = ew_clampf(hist[k], m - gamma * sd, m + gamma * sd);
    }
}

/* One pixel, with the history clamp when p->clamp > 0. */
EW_HD void ew_temporal_px(int x, int y, const ew_temporal_params *p, const ew_temporal_buffers *b) {
    const float gamma = p->clamp;
    const long j = (long)y * p->width + x;
    const float *cur = b->color + j * 3;
    float hist[3] = {0.0f, 0.0f, 0.0f}, wsum = 0.0f, len = 0.0f;
    if (b->prev_len) {
        float mx = b->motion ? b->motion[j * 2] : 0.0f, my = b->motion ? b->motion[j * 2 + 1] : 0.0f;
        if (!ew_finitef(mx) || !ew_finitef(my)) mx = my = 1e9f; /* no history */
        /* Cycles' Vector.XY is previous minus current position in a frame
         * whose y axis points up (Blender's rows go bottom-up); our rows go
         * top-down, so the row offset is -Y. Checked on rendered sequences:
         * a camera panning and one rising, the albedo of frame t-1
         * reprojected onto frame t (docs/temporal.md). */
        float px = (float)x + p->motion_sign * mx, py = (float)y - p->motion_sign * my;
        if (px > -1.0f && py > -1.0f && px < (float)p->width && py < (float)p->height) {
            int x0 = (int)floorf(px), y0 = (int)floorf(py);
            float fx = px - (float)x0, fy = py - (float)y0;
            for (int t = 0; t < 4; t++) {
                int xx = x0 + (t & 1), yy = y0 + (t >> 1);
                if (xx < 0 || yy < 0 || xx >= p->width || yy >= p->height) continue;
                float w = ((t & 1) ? fx : 1.0f - fx) * ((t >> 1) ? fy : 1.0f - fy);
                long k = (long)yy * p->width + xx;
                if (w <= 0.0f || !ew_temporal_tap_ok(p, b, j, k)) continue;
                for (int c = 0; c < 3; c++) hist[c] += w * b->prev_color[k * 3 + c];
                len += w * b->prev_len[k];
                wsum += w;
            }
        }
    }
    float *out = b->out_color + j * 3;
    int cur_ok = ew_finitef(cur[0]) && ew_finitef(cur[1]) && ew_finitef(cur[2]);
    if (wsum > 1e-4f) {
        for (int c = 0; c < 3; c++) hist[c] /= wsum;
        len /= wsum;
        if (gamma > 0.0f && cur_ok) ew_temporal_clip(x, y, p, b->color, gamma, hist);
        float alpha = ew_maxf(1.0f / (len + 1.0f), p->alpha_min);
        for (int c = 0; c < 3; c++) out[c] = cur_ok ? hist[c] + alpha * (cur[c] - hist[c]) : hist[c];
        b->out_len[j] = ew_minf(len + (cur_ok ? 1.0f : 0.0f), p->max_frames);
    } else {
        /* no history: the frame itself, finite as every filter's output is
         * (the op's host fallback does not reach device memory) */
        for (int c = 0; c < 3; c++) out[c] = ew_finite_orf(cur[c]);
        b->out_len[j] = cur_ok ? 1.0f : 0.0f;
    }
}

#endif
