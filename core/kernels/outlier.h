/*
 * outlier.h — the one per-pixel definition of outlier (firefly) rejection.
 * Every clamp of the library calls ew_outlier_px: the filter "outlier", the
 * denoisers' own firefly_k clamp, and the extreme-outlier rejection that the
 * op layer runs before every denoiser (src/harm_stage.c). They differ only
 * in the parameters below.
 *
 * A pixel whose luminance lies more than k spreads above the centre of its
 * (2r+1)^2 neighbourhood (itself excluded, so one firefly cannot hide
 * itself) is scaled down to that bound. Low-sample path tracing has
 * heavy-tailed noise; a few such samples would otherwise be spread by any
 * smoothing filter into visible blotches.
 *   - centre and spread: the mean and standard deviation of the neighbours'
 *     luminance, or (robust) their median and 1.4826 x median absolute
 *     deviation: a second firefly, or an emitter in the window, moves the
 *     mean and inflates the standard deviation enough to let a 300x sample
 *     through, while the median ignores up to half the window;
 *   - only neighbours that look like the same surface count: albedo within
 *     albedo_tol (every channel, absolute) and normal within normal_cos
 *     (cosine) of the pixel's own. A bright pixel at the border of a bright
 *     material, or a small emitter, is then compared with its own kind and
 *     kept; a firefly inside a surface is compared with that surface;
 *   - the spread is at least sigma_floor * |centre| and abs_floor, so plain
 *     noise of a smooth surface is never touched (a few neighbours can look
 *     much tighter than the noise is; a dark, flat region has a spread of 0,
 *     and at 1-2 spp most of its light arrives as sparse bright samples that
 *     carry the region's energy);
 *   - shift: the mean statistics are of luminance differences to the first
 *     similar neighbour's (no cancellation next to a 6e4 firefly, and a
 *     constant image stays exactly constant); 0 sums plain luminances, as
 *     the clamp the shipped NBG models were trained with did;
 *   - a pixel with fewer than EW_OUTLIER_MIN_SIMILAR similar finite
 *     neighbours is not judged (kept as it is);
 *   - repair: a non-finite pixel (NaN/Inf in any channel) becomes the mean
 *     colour of its similar finite neighbours, else of all finite
 *     neighbours, else 0; without it, it is left as it is (later stages
 *     treat it as missing). k <= 0 only repairs;
 *   - emitter_albedo (robust only; 0: off): b->color is radiance, colour
 *     over ew_albedo_factor(albedo). A pixel whose albedo is above
 *     emitter_albedo in some channel (no surface reflects that much: an
 *     emitter's samples wrote it) while no neighbour of its 3x3 has an
 *     albedo above 1 saw an emitter that no neighbour saw: one or two
 *     samples hit a light smaller than the pixel. Its albedo is then as
 *     noisy as its colour (the hits' share of the pixel), so it names no
 *     surface and demodulating by it divides the firefly out of the
 *     radiance (and the method multiplies it back in). Such a pixel is
 *     judged in colour against all its finite neighbours (their colour:
 *     radiance times their albedo factor; no feature similarity); an
 *     emitter larger than a pixel has neighbours that see it too and is
 *     judged as before;
 *   - a feature pass that is NULL, or non-finite at the pixel, is not used;
 *   - removed (optional): the share of each pixel's RGB the clamp took, one
 *     float a pixel (0 where it took nothing, or rebuilt a non-finite
 *     pixel), so that a caller can give the energy back elsewhere
 *     (src/harm_stage.c returns the denoisers' own clamp's share, spread,
 *     after the method) while the clamped colour itself stays what the
 *     method was trained on. A share, not RGB: the clamp scales a pixel's
 *     RGB as one, so the light it took is that share of the colour it was
 *     given, which the caller holds anyway (a third of the memory).
 */
#ifndef EW_KERNELS_OUTLIER_H
#define EW_KERNELS_OUTLIER_H

#include "kernels/color.h"
#include "kernels/denoise_px.h" /* ew_albedo_factor */

#define EW_OUTLIER_MIN_SIMILAR 3
/* The robust statistics sort the window in a per-thread array: radius 3
 * (48 neighbours) at most; a larger radius is treated as 3. */
#define EW_OUTLIER_ROBUST_RADIUS 3
#define EW_OUTLIER_ROBUST_CAP 48
#define EW_OUTLIER_MAD_SCALE 1.4826f /* MAD -> standard deviation of a normal distribution */

typedef struct ew_outlier_params {
    int width, height;
    int radius;        /* window (2r+1)^2 */
    float k;           /* bound = centre + k * spread of the similar neighbours' luminance */
    float albedo_tol;  /* neighbours whose albedo differs by more in any channel are not counted */
    float normal_cos;  /* neighbours whose normal has a smaller cosine to the pixel's are not counted */
    float sigma_floor; /* smallest spread, relative to the centre */
    float abs_floor;   /* smallest spread, in luminance units (0: none) */
    int robust;        /* 1: median and MAD; 0: mean and standard deviation */
    int shift;         /* mean statistics of differences to the first similar neighbour */
    int repair;        /* rebuild non-finite pixels from their neighbours */
    float emitter_albedo; /* robust, color demodulated: an isolated emitter hit is judged in colour (above) */
} ew_outlier_params;

typedef struct ew_outlier_buffers {
    const float *color;  /* channels per pixel, RGB first */
    const float *albedo; /* 3 per pixel or NULL */
    const float *normal; /* 3 per pixel or NULL */
    float *out;          /* channels per pixel; must not alias color */
    int channels;        /* floats per pixel of color and out, >= 3: the ones past RGB (alpha) are copied */
    float *removed;      /* 1 per pixel, or NULL: 1 - out / color in RGB where clamped, else 0 */
} ew_outlier_buffers;

/* The parameters of the denoisers' own firefly_k clamp (bgrid, nbg): mean
 * and standard deviation of the whole 5x5 window, nothing else. */
EW_HD ew_outlier_params ew_outlier_plain_params(int width, int height, int radius, float k) {
    ew_outlier_params p;
    p.width = width;
    p.height = height;
    p.radius = radius;
    p.k = k;
    p.albedo_tol = 0.0f;
    p.normal_cos = -1.0f;
    p.sigma_floor = 0.0f;
    p.abs_floor = 0.0f;
    p.robust = 0;
    p.shift = 0;
    p.repair = 0;
    p.emitter_albedo = 0.0f;
    return p;
}

EW_HD int ew_outlier_finite3(const float *v) { return ew_finitef(v[0]) && ew_finitef(v[1]) && ew_finitef(v[2]); }

/* Do normals of squared lengths l0 (the pixel's, finite) and l1 with dot
 * product d face alike (within normal_cos)? Two without a surface
 * (background) are alike. Written without branches so that a row loop
 * (the CPU backend's) vectorises the same test. */
EW_HD int ew_outlier_normals_alike(float l0, float l1, float d, float normal_cos) {
    const int none0 = l0 < 1e-12f, none1 = l1 < 1e-12f, facing = d >= normal_cos * sqrtf(l0 * l1);
    return ew_finitef(l1) & ((none0 & none1) | (((none0 | none1) ^ 1) & facing));
}

/* Does neighbour k look like the same surface as pixel j? use_a/use_n:
 * whether pixel j's albedo/normal are usable. */
EW_HD int ew_outlier_similar(const ew_outlier_params *p, const ew_outlier_buffers *b, long j, long k, int use_a,
                             int use_n) {
    if (use_a) {
        const float *a0 = b->albedo + j * 3, *a1 = b->albedo + k * 3;
        for (int c = 0; c < 3; c++)
            if (!(fabsf(a0[c] - a1[c]) <= p->albedo_tol)) return 0; /* NaN: not similar */
    }
    if (use_n) {
        const float *n0 = b->normal + j * 3, *n1 = b->normal + k * 3;
        const float l0 = n0[0] * n0[0] + n0[1] * n0[1] + n0[2] * n0[2];
        const float l1 = n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2];
        const float d = n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2];
        return ew_outlier_normals_alike(l0, l1, d, p->normal_cos);
    }
    return 1;
}

/* The k-th smallest of v[0..n) (Hoare's selection; reorders v). The values
 * are finite. */
EW_HD float ew_outlier_select(float *v, int n, int k) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        const float pivot = v[(lo + hi) / 2];
        int i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot) i++;
            while (v[j] > pivot) j--;
            if (i <= j) {
                const float t = v[i];
                v[i] = v[j];
                v[j] = t;
                i++;
                j--;
            }
        }
        if (k <= j)
            hi = j;
        else if (k >= i)
            lo = i;
        else
            break;
    }
    return v[k];
}

/* The bound from the centre and spread of a finite pixel's similar
 * neighbours; a pixel above it is scaled down to it (RGB of o; removed: the
 * pixel's share taken, or NULL, already 0). */
EW_HD void ew_outlier_bound_apply(const ew_outlier_params *p, const float *c0, float lum, float centre, float spread,
                                  float *o, float *removed) {
    spread = ew_maxf(ew_maxf(spread, p->sigma_floor * fabsf(centre)), p->abs_floor);
    const float bound = centre + p->k * spread;
    if (lum > bound) {
        const float s = ew_maxf(bound, 0.0f) / lum;
        o[0] = c0[0] * s;
        o[1] = c0[1] * s;
        o[2] = c0[2] * s;
        if (removed) *removed = 1.0f - s;
    }
}

/* ... with the mean statistics: n (>= EW_OUTLIER_MIN_SIMILAR) neighbours'
 * luminances less shift, summed (sum) and squared and summed (sum2). */
EW_HD void ew_outlier_mean_clamp(const ew_outlier_params *p, const float *c0, float lum, int n, float shift,
                                 float sum, float sum2, float *o, float *removed) {
    const float mean_d = sum / (float)n; /* mean - shift */
    const float spread = sqrtf(ew_maxf(sum2 / (float)n - mean_d * mean_d, 0.0f));
    ew_outlier_bound_apply(p, c0, lum, shift + mean_d, spread, o, removed);
}

/* Is pixel j (finite albedo) an emitter hit that no 3x3 neighbour shares
 * (emitter_albedo, above)? */
EW_HD int ew_outlier_lone_emitter(int x, int y, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    const float *a0 = b->albedo + ((long)y * p->width + x) * 3;
    if (!(ew_maxf(ew_maxf(a0[0], a0[1]), a0[2]) > p->emitter_albedo)) return 0;
    for (int yy = ew_maxi(y - 1, 0); yy <= ew_mini(y + 1, p->height - 1); yy++)
        for (int xx = ew_maxi(x - 1, 0); xx <= ew_mini(x + 1, p->width - 1); xx++) {
            const float *a1 = b->albedo + ((long)yy * p->width + xx) * 3;
            if ((xx != x || yy != y) && ew_maxf(ew_maxf(a1[0], a1[1]), a1[2]) > 1.0f) return 0;
        }
    return 1;
}

/* The luminance of pixel k's colour: its radiance times its albedo factor */
EW_HD float ew_outlier_colour_lum(const ew_outlier_buffers *b, long k) {
    const float *c = b->color + k * b->channels, *a = b->albedo + k * 3;
    float v[3];
    for (int i = 0; i < 3; i++) v[i] = c[i] * ew_albedo_factor(a[i]);
    return ew_luminance(v);
}

/* A lone emitter hit (robust): bound from the median and MAD of all its
 * finite neighbours' colour luminance; o scaled by bound / its own. */
EW_HD void ew_outlier_emitter_px(int x, int y, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    const long j = (long)y * p->width + x;
    const int r = ew_mini(p->radius, EW_OUTLIER_ROBUST_RADIUS);
    float window[EW_OUTLIER_ROBUST_CAP];
    int n = 0;
    for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, p->height - 1); yy++)
        for (int xx = ew_maxi(x - r, 0); xx <= ew_mini(x + r, p->width - 1); xx++) {
            const long k = (long)yy * p->width + xx;
            if (k == j || !ew_outlier_finite3(b->color + k * b->channels) || !ew_outlier_finite3(b->albedo + k * 3))
                continue;
            const float l = ew_outlier_colour_lum(b, k);
            if (ew_finitef(l)) window[n++] = l;
        }
    const float lum = ew_outlier_colour_lum(b, j);
    if (n < EW_OUTLIER_MIN_SIMILAR || !(lum > 0.0f) || !ew_finitef(lum)) return;
    const float centre = ew_outlier_select(window, n, (n - 1) / 2);
    for (int i = 0; i < n; i++) window[i] = fabsf(window[i] - centre);
    const float spread = EW_OUTLIER_MAD_SCALE * ew_outlier_select(window, n, (n - 1) / 2);
    ew_outlier_bound_apply(p, b->color + j * b->channels, lum, centre, spread, b->out + j * b->channels,
                           b->removed ? b->removed + j : 0);
}

/* Robust rejection keeps a pixel of luminance lum when at most (n - 1) / 2
 * of its n similar neighbours lie below this (ew_outlier_guided_px says
 * why). */
EW_HD float ew_outlier_keep_below(const ew_outlier_params *p, float lum) {
    const float sf = ew_maxf(p->sigma_floor, 0.0f), af = ew_maxf(p->abs_floor, 0.0f);
    return ew_minf(lum / (1.0f + p->k * sf), lum - p->k * af) + 1e-4f * lum;
}

EW_HD void ew_outlier_guided_px(int x, int y, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    const long j = (long)y * p->width + x, cc = b->channels;
    const float *c0 = b->color + j * cc;
    float *o = b->out + j * cc;
    const int finite = ew_outlier_finite3(c0);
    if (b->removed) ew_store_sparse(b->removed + j, 0.0f);
    const float lum = finite ? ew_luminance(c0) : 0.0f;
    for (int c = 0; c < cc; c++) o[c] = c0[c];
    if (finite && (p->k <= 0.0f || lum <= 0.0f)) return; /* nothing to judge */
    if (!finite && !p->repair) return;
    const int use_a = b->albedo != 0 && ew_outlier_finite3(b->albedo + j * 3);
    const int use_n = b->normal != 0 && ew_outlier_finite3(b->normal + j * 3);
    const int robust = p->robust && finite;
    if (robust && use_a && p->emitter_albedo > 0.0f && ew_outlier_lone_emitter(x, y, p, b)) {
        ew_outlier_emitter_px(x, y, p, b);
        return;
    }
    const int r = robust ? ew_mini(p->radius, EW_OUTLIER_ROBUST_RADIUS) : p->radius;
    float shift = 0.0f, sum = 0.0f, sum2 = 0.0f, rgb[3] = {0.0f, 0.0f, 0.0f}, any_rgb[3] = {0.0f, 0.0f, 0.0f};
    float window[EW_OUTLIER_ROBUST_CAP];
    int n = 0, any = 0;
    for (int yy = ew_maxi(y - r, 0); yy <= ew_mini(y + r, p->height - 1); yy++)
        for (int xx = ew_maxi(x - r, 0); xx <= ew_mini(x + r, p->width - 1); xx++) {
            if (xx == x && yy == y) continue;
            const long k = (long)yy * p->width + xx;
            const float *c1 = b->color + k * cc;
            if (!ew_outlier_finite3(c1)) continue;
            if (!finite)
                for (int c = 0; c < 3; c++) any_rgb[c] += c1[c];
            any++;
            if (!ew_outlier_similar(p, b, j, k, use_a, use_n)) continue;
            if (robust) {
                window[n++] = ew_luminance(c1);
                continue;
            }
            if (n == 0 && p->shift) shift = ew_luminance(c1);
            const float l = ew_luminance(c1) - shift;
            sum += l;
            sum2 += l * l;
            if (!finite)
                for (int c = 0; c < 3; c++) rgb[c] += c1[c];
            n++;
        }
    if (!finite) { /* a missing sample: rebuilt from its surface, else its window */
        for (int c = 0; c < 3; c++)
            o[c] = n > 0 ? rgb[c] / (float)n : (any > 0 ? any_rgb[c] / (float)any : 0.0f);
        return;
    }
    if (n < EW_OUTLIER_MIN_SIMILAR) return;
    if (!robust) {
        ew_outlier_mean_clamp(p, c0, lum, n, shift, sum, sum2, o, b->removed ? b->removed + j : 0);
        return;
    }
    float centre, spread;
    {
        /* Most pixels lie far below their bound, and the bound grows with the
         * median (the spread is at least sigma_floor * centre and abs_floor):
         * a median of t or more already puts the bound above lum, and the
         * median is at least t exactly when at most (n - 1) / 2 neighbours lie
         * below t. That count decides those pixels without the two
         * selections. t is raised by 1e-4 lum above the smallest such median
         * so that the rounding of the exact test cannot disagree with it. */
        const float t = ew_outlier_keep_below(p, lum);
        int below = 0;
        for (int i = 0; i < n; i++) below += window[i] < t;
        if (below <= (n - 1) / 2) return;
        centre = ew_outlier_select(window, n, (n - 1) / 2);
        for (int i = 0; i < n; i++) window[i] = fabsf(window[i] - centre);
        spread = EW_OUTLIER_MAD_SCALE * ew_outlier_select(window, n, (n - 1) / 2);
    }
    ew_outlier_bound_apply(p, c0, lum, centre, spread, o, b->removed ? b->removed + j : 0);
}

#endif
