#include "algorithms/train.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/bgrid.h"
#include "backends/cpu/cpu_conv.h"
#include "kernels/bgrid_backward.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "src/internal.h"

/* ---- frames ------------------------------------------------------------- */
void ew_train_frame_free(ew_train_frame *f) {
    if (!f) return;
    free(f->input);
    free(f->radiance);
    free(f->albedo_f);
    free(f->ref_tm);
    memset(f, 0, sizeof *f);
}

int ew_train_frame_init(ew_train_frame *f, int width, int height, const float *color, const float *albedo,
                        const float *normal, const float *depth, const float *reference, float firefly_k) {
    memset(f, 0, sizeof *f);
    const long n = (long)width * height;
    f->width = width;
    f->height = height;
    f->input = (float *)malloc(sizeof(float) * n * EW_GN_INPUTS);
    f->radiance = (float *)malloc(sizeof(float) * n * 3);
    f->albedo_f = (float *)malloc(sizeof(float) * n * 3);
    f->ref_tm = (float *)malloc(sizeof(float) * n * 3);
    float *raw = (float *)malloc(sizeof(float) * n * 4); /* demodulated radiance + the unused hand-made guide */
    if (!f->input || !f->radiance || !f->albedo_f || !f->ref_tm || !raw) {
        free(raw);
        ew_train_frame_free(f);
        return 1;
    }
    /* the op's steps, in its order: depth normalisation (reduce.h),
     * demodulation (denoise_px.h), firefly clamp (outlier.h), inputs */
    double mx = 0.0;
    double *rows = (double *)(void *)raw; /* 2 doubles a row fit in the 4 floats a pixel of raw */
    for (int y = 0; y < height; y++) ew_reduce_row(EW_REDUCE_DEPTH_MAX, y, width, depth, rows);
    for (int y = 0; y < height; y++)
        if (rows[2 * y] > mx) mx = rows[2 * y];
    ew_denoise_buffers b;
    memset(&b, 0, sizeof b);
    b.width = width;
    b.height = height;
    b.color = color;
    b.albedo = albedo;
    b.normal = normal;
    b.depth = depth;
    b.depth_scale = mx > 0.0 ? (float)(1.0 / mx) : 1.0f;
    b.radiance = raw;
    b.guide = raw + n * 3;
    for (long j = 0; j < n; j++) ew_denoise_prepare_px(j, j, &b);
    const ew_outlier_params fp = ew_outlier_plain_params(width, height, 2, firefly_k);
    const ew_outlier_buffers fb = {raw, NULL, NULL, f->radiance, 3, NULL};
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            if (firefly_k > 0.0f)
                ew_outlier_guided_px(x, y, &fp, &fb);
            else
                memcpy(f->radiance + ((long)y * width + x) * 3, raw + ((long)y * width + x) * 3, 3 * sizeof(float));
        }
    for (long j = 0; j < n; j++) {
        ew_gn_input_px(j, color, albedo, normal, depth, b.depth_scale, f->input + j, n);
        for (int k = 0; k < 3; k++) {
            f->albedo_f[j * 3 + k] = ew_albedo_factor(albedo[j * 3 + k]);
            f->ref_tm[j * 3 + k] = ew_nbg_tm(ew_feature_or_zero(reference[j * 3 + k]));
        }
    }
    free(raw);
    return 0;
}

/* ---- scratch -------------------------------------------------------------- */
struct ew_train_scratch {
    int size;
    ew_bgrid_params gp[EW_GN_MAX_GRIDS];
    ew_gn_planes feat, dfeat, dfinal;
    float *out;                    /* nout planes of size^2: sigmoid outputs */
    float *guide[EW_GN_MAX_GRIDS];  /* size^2 each, 0..255 */
    float *dguide[EW_GN_MAX_GRIDS];
    float *grid[EW_GN_MAX_GRIDS], *dgrid;
    float *sliced[EW_GN_MAX_GRIDS]; /* size^2 * 3 each */
    float *inv_eta, *rgb, *drgb, *dsl, *dw;
    float *radiance, *albedo_f, *ref_tm;
    /* the fast path's tables: per grid, per column / row the first cell and
     * the two tent weights; per pixel the first depth cell, its two tent
     * weights and their derivatives */
    int *u0[EW_GN_MAX_GRIDS], *v0[EW_GN_MAX_GRIDS], *z0;
    float *wx[EW_GN_MAX_GRIDS], *wy[EW_GN_MAX_GRIDS], *tz, *dtz;
    unsigned char *ok;
    int use_kernels; /* 1: the per-column/per-pixel kernels (the reference) */
    void *mem[5];
};

void ew_train_scratch_use_kernels(ew_train_scratch *s, int on) { s->use_kernels = on; }

ew_train_scratch *ew_train_scratch_create(const ew_guidenet *net, int size) {
    ew_train_scratch *s = (ew_train_scratch *)calloc(1, sizeof *s);
    if (!s) return NULL;
    s->size = size;
    const size_t n = (size_t)size * size;
    size_t grids = 0, largest = 0;
    for (int g = 0; g < net->ngrids; g++) {
        if (!ew_bgrid_params_init(&s->gp[g], size, size, net->rate_s[g], net->rate_d[g], 3)) {
            free(s);
            return NULL;
        }
        grids += ew_bgrid_floats(&s->gp[g]);
        if (ew_bgrid_floats(&s->gp[g]) > largest) largest = ew_bgrid_floats(&s->gp[g]);
    }
    const size_t fe = ew_gn_planes_floats(size, size, net->nfeat), fd = ew_gn_planes_floats(size, size, net->nout);
    const size_t flat = n * ((size_t)net->nout + 2 * (size_t)net->ngrids + 3 * (size_t)net->ngrids + 1 + 3 * 3 + 3 +
                             3 * 3) +
                        grids + largest;
    s->mem[0] = aligned_alloc(64, (fe * sizeof(float) + 63) / 64 * 64);
    s->mem[1] = aligned_alloc(64, (fe * sizeof(float) + 63) / 64 * 64);
    s->mem[2] = aligned_alloc(64, (fd * sizeof(float) + 63) / 64 * 64);
    s->mem[3] = malloc(flat * sizeof(float));
    if (!s->mem[0] || !s->mem[1] || !s->mem[2] || !s->mem[3]) {
        ew_train_scratch_destroy(s);
        return NULL;
    }
    ew_gn_planes_init(&s->feat, (float *)s->mem[0], size, size, net->nfeat);
    ew_gn_planes_init(&s->dfeat, (float *)s->mem[1], size, size, net->nfeat);
    ew_gn_planes_init(&s->dfinal, (float *)s->mem[2], size, size, net->nout);
    float *p = (float *)s->mem[3];
    memset(p, 0, flat * sizeof(float));
    s->out = p; p += n * net->nout;
    for (int g = 0; g < net->ngrids; g++) {
        s->guide[g] = p; p += n;
        s->dguide[g] = p; p += n;
        s->sliced[g] = p; p += n * 3;
        s->grid[g] = p; p += ew_bgrid_floats(&s->gp[g]);
    }
    s->dgrid = p; p += largest;
    s->inv_eta = p; p += n;
    s->rgb = p; p += n * 3;
    s->drgb = p; p += n * 3;
    s->dsl = p; p += n * 3;
    s->dw = p; p += n * 3;
    s->radiance = p; p += n * 3;
    s->albedo_f = p; p += n * 3;
    s->ref_tm = p;
    /* fast-path tables (ints and floats share one block) */
    const size_t tab = (size_t)net->ngrids * (2 * (size_t)size * 3) + n * 5 + n;
    s->mem[4] = calloc(tab, sizeof(float));
    if (!s->mem[4]) {
        ew_train_scratch_destroy(s);
        return NULL;
    }
    float *q = (float *)s->mem[4];
    for (int g = 0; g < net->ngrids; g++) {
        s->u0[g] = (int *)(void *)q; q += size;
        s->v0[g] = (int *)(void *)q; q += size;
        s->wx[g] = q; q += 2 * size;
        s->wy[g] = q; q += 2 * size;
        /* exactly the kernels' expressions (kernels/bgrid.h), so the fast
         * path computes the same weights */
        for (int x = 0; x < size; x++) {
            float px = ew_bgrid_pos_s((float)x, s->gp[g].rate_s);
            int u = (int)floorf(px);
            s->u0[g][x] = s->v0[g][x] = u;
            s->wx[g][2 * x] = s->wy[g][2 * x] = ew_tent(px - (float)u);
            s->wx[g][2 * x + 1] = s->wy[g][2 * x + 1] = ew_tent(px - (float)(u + 1));
        }
    }
    s->z0 = (int *)(void *)q; q += n;
    s->tz = q; q += 2 * n;
    s->dtz = q; q += 2 * n;
    s->ok = (unsigned char *)(void *)q;
    return s;
}

void ew_train_scratch_destroy(ew_train_scratch *s) {
    if (!s) return;
    for (int i = 0; i < 5; i++) free(s->mem[i]);
    free(s);
}

/* ---- the shared, re-laid-out weights ------------------------------------ */
int ew_train_model_init(ew_train_model *m, const ew_guidenet *net) {
    memset(m, 0, sizeof *m);
    m->net = net;
    size_t w = 0;
    for (int l = 0; l < net->nlayers; l++) w += (size_t)net->layers[l].cin * net->layers[l].cout * 25;
    m->wt = (float *)malloc(w * sizeof(float));
    m->fwt = (float *)malloc(w * sizeof(float));
    m->flip = (float *)malloc(w * sizeof(float));
    if (!m->wt || !m->fwt || !m->flip) {
        ew_train_model_free(m);
        return 1;
    }
    return 0;
}

void ew_train_model_free(ew_train_model *m) {
    free(m->wt);
    free(m->fwt);
    free(m->flip);
    memset(m, 0, sizeof *m);
}

/* Layer l's weights sit at the same offset in wt, fwt and flip: the sum
 * of the sizes of the layers before it. */
static size_t layer_wofs(const ew_guidenet *net, int l) {
    size_t o = 0;
    for (int k = 0; k < l; k++) o += (size_t)net->layers[k].cin * net->layers[k].cout * 25;
    return o;
}

void ew_train_model_prepare(ew_train_model *m, const float *params) {
    const ew_guidenet *net = m->net;
    m->params = params;
    for (int l = 0; l < net->nlayers; l++) {
        const ew_gn_layer *L = &net->layers[l];
        const size_t o = layer_wofs(net, l);
        ew_conv_cpu_wt_layout(L->cin, L->cout, params + L->w_off, m->wt + o);
        ew_conv5_flip_weights(L->cin, L->cout, params + L->w_off, m->flip + o);
        ew_conv_cpu_wt_layout(L->cout, L->cin, m->flip + o, m->fwt + o);
    }
}

/* ---- one patch ------------------------------------------------------------- */

/* Frame pixel of patch pixel (u, v) under symmetry aug. */
static void patch_src(const ew_patch_ref *r, int size, int u, int v, int *x, int *y) {
    int a = (r->aug & 4) ? v : u, b = (r->aug & 4) ? u : v;
    if (r->aug & 1) a = size - 1 - a;
    if (r->aug & 2) b = size - 1 - b;
    *x = r->x0 + a;
    *y = r->y0 + b;
}

static void load_patch(const ew_train_frame *f, const ew_patch_ref *r, int size, ew_train_scratch *s) {
    const long n = (long)f->width * f->height;
    /* Normals (input planes 6, 7 hold (n + 1) / 2 of x and y) follow the
     * symmetry: n_patch = J^T n_frame for the map's Jacobian J, i.e. a flip
     * negates a component (v -> 1 - v) and the transpose swaps x and y. */
    const int flipx = r->aug & 1, flipy = r->aug & 2, tr = r->aug & 4;
    for (int v = 0; v < size; v++)
        for (int u = 0; u < size; u++) {
            int x, y;
            patch_src(r, size, u, v, &x, &y);
            const long j = (long)y * f->width + x, q = (long)v * size + u;
            for (int c = 0; c < EW_GN_INPUTS; c++) ew_gn_plane_row(&s->feat, c, v)[u] = f->input[c * n + j];
            float nx = f->input[6 * n + j], ny = f->input[7 * n + j];
            if (flipx) nx = 1.0f - nx;
            if (flipy) ny = 1.0f - ny;
            ew_gn_plane_row(&s->feat, 6, v)[u] = tr ? ny : nx;
            ew_gn_plane_row(&s->feat, 7, v)[u] = tr ? nx : ny;
            for (int k = 0; k < 3; k++) {
                s->radiance[q * 3 + k] = f->radiance[j * 3 + k];
                s->albedo_f[q * 3 + k] = f->albedo_f[j * 3 + k];
                s->ref_tm[q * 3 + k] = f->ref_tm[j * 3 + k];
            }
        }
}

/*
 * The grid steps of one patch on one thread, as scatters over the pixels
 * with the tent weights computed once: ~5x less work than the kernels'
 * per-column gathers, which pay for recomputing every weight in every
 * column that can see a pixel (the price of running in parallel without
 * atomics). The weights are the kernels' own expressions, and every cell
 * still receives its pixels in raster order, so the forward values are the
 * same bits as the kernels' (tests/unit/test_train.c compares both paths).
 */
static void fast_prepare(ew_train_scratch *s, int g, const float *guide) {
    const ew_bgrid_params *p = &s->gp[g];
    const long n = (long)p->width * p->height;
    for (long j = 0; j < n; j++) {
        float gv = guide[j];
        int ok = ew_finitef(gv);
        for (int c = 0; c < 3; c++) ok &= ew_finitef(s->radiance[j * 3 + c]);
        s->ok[j] = (unsigned char)ok;
        float pz = ew_bgrid_pos_d(ew_finitef(gv) ? gv : 0.0f, p->rate_d);
        int z = (int)floorf(pz);
        s->z0[j] = z;
        s->tz[2 * j] = ew_tent(pz - (float)z);
        s->tz[2 * j + 1] = ew_tent(pz - (float)(z + 1));
        s->dtz[2 * j] = ew_finitef(gv) ? ew_tent_grad(pz - (float)z) / p->rate_d : 0.0f;
        s->dtz[2 * j + 1] = ew_finitef(gv) ? ew_tent_grad(pz - (float)(z + 1)) / p->rate_d : 0.0f;
    }
}

/* The 8 cells of pixel (x, y): loop body gets cell pointer offset `k`
 * (float index of the cell), weight w and its guide derivative dw. */
#define EW_FOR_CELLS(s, g, p, x, y, j, BODY)                                                            \
    do {                                                                                                \
        const int u0_ = (s)->u0[g][x], v0_ = (s)->v0[g][y], z0_ = (s)->z0[j];                            \
        for (int dv_ = 0; dv_ < 2; dv_++) {                                                              \
            const int v_ = v0_ + dv_;                                                                    \
            if (v_ < 0 || v_ >= (p)->gh) continue;                                                       \
            const float wy_ = (s)->wy[g][2 * (y) + dv_];                                                 \
            for (int du_ = 0; du_ < 2; du_++) {                                                          \
                const int u_ = u0_ + du_;                                                                \
                if (u_ < 0 || u_ >= (p)->gw) continue;                                                   \
                const float wxy_ = (s)->wx[g][2 * (x) + du_] * wy_;                                      \
                for (int dz_ = 0; dz_ < 2; dz_++) {                                                      \
                    const int z_ = z0_ + dz_;                                                            \
                    if (z_ < 0 || z_ >= (p)->gd) continue;                                               \
                    const long k = (((long)v_ * (p)->gw + u_) * (p)->gd + z_) * 4;                       \
                    const float w = wxy_ * (s)->tz[2 * (j) + dz_];                                       \
                    const float dw = wxy_ * (s)->dtz[2 * (j) + dz_];                                     \
                    (void)dw;                                                                            \
                    BODY                                                                                 \
                }                                                                                        \
            }                                                                                            \
        }                                                                                                \
    } while (0)

static void fast_splat_slice(ew_train_scratch *s, int g) {
    const ew_bgrid_params *p = &s->gp[g];
    const int P = p->width;
    float *grid = s->grid[g];
    memset(grid, 0, ew_bgrid_floats(p) * sizeof(float));
    for (int y = 0; y < P; y++)
        for (int x = 0; x < P; x++) {
            const long j = (long)y * P + x;
            if (!s->ok[j]) continue;
            const float *I = s->radiance + j * 3;
            EW_FOR_CELLS(s, g, p, x, y, j, {
                if (w > 0.0f) {
                    grid[k] += w * I[0];
                    grid[k + 1] += w * I[1];
                    grid[k + 2] += w * I[2];
                    grid[k + 3] += w;
                }
            });
        }
    const long cells = (long)p->gw * p->gh * p->gd;
    for (long c = 0; c < cells; c++)
        if (grid[c * 4 + 3] > 0.0f)
            for (int k = 0; k < 3; k++) grid[c * 4 + k] /= grid[c * 4 + 3];
    for (int y = 0; y < P; y++)
        for (int x = 0; x < P; x++) {
            const long j = (long)y * P + x;
            float acc[4] = {0, 0, 0, 0};
            EW_FOR_CELLS(s, g, p, x, y, j, {
                if (grid[k + 3] > 0.0f) {
                    acc[0] += w * grid[k];
                    acc[1] += w * grid[k + 1];
                    acc[2] += w * grid[k + 2];
                    acc[3] += w;
                }
            });
            float *o = s->sliced[g] + j * 3;
            if (acc[3] > 0.0f) {
                float inv = 1.0f / acc[3];
                o[0] = acc[0] * inv;
                o[1] = acc[1] * inv;
                o[2] = acc[2] * inv;
            } else {
                ew_bgrid_slice_px(x, y, p, grid, s->guide[g], o); /* the kernel's fallback */
            }
        }
}

static void fast_backward(ew_train_scratch *s, int g) {
    const ew_bgrid_params *p = &s->gp[g];
    const int P = p->width;
    const float *grid = s->grid[g];
    float *dgrid = s->dgrid, *dguide = s->dguide[g];
    memset(dgrid, 0, ew_bgrid_floats(p) * sizeof(float));
    /* slice: dL/dg and the scatter of dL/dG */
    for (int y = 0; y < P; y++)
        for (int x = 0; x < P; x++) {
            const long j = (long)y * P + x;
            float mu[3] = {0, 0, 0}, dmu[3] = {0, 0, 0}, eta = 0.0f, deta = 0.0f;
            EW_FOR_CELLS(s, g, p, x, y, j, {
                if (grid[k + 3] > 0.0f) {
                    for (int c = 0; c < 3; c++) {
                        mu[c] += w * grid[k + c];
                        dmu[c] += dw * grid[k + c];
                    }
                    eta += w;
                    deta += dw;
                }
            });
            if (!(eta > 0.0f)) {
                dguide[j] = 0.0f;
                continue;
            }
            const float inv = 1.0f / eta, *o = s->dsl + j * 3;
            float acc = 0.0f;
            for (int c = 0; c < 3; c++) acc += o[c] * (dmu[c] - mu[c] * inv * deta) * inv;
            dguide[j] = acc;
            EW_FOR_CELLS(s, g, p, x, y, j, {
                if (grid[k + 3] > 0.0f && w > 0.0f) {
                    const float wi = w * inv;
                    dgrid[k] += wi * o[0];
                    dgrid[k + 1] += wi * o[1];
                    dgrid[k + 2] += wi * o[2];
                }
            });
        }
    /* splat: dL/dg */
    for (int y = 0; y < P; y++)
        for (int x = 0; x < P; x++) {
            const long j = (long)y * P + x;
            if (!s->ok[j]) continue;
            const float *I = s->radiance + j * 3;
            float dg = 0.0f;
            EW_FOR_CELLS(s, g, p, x, y, j, {
                if (w > 0.0f && grid[k + 3] > 0.0f) {
                    const float dot = dgrid[k] * (I[0] - grid[k]) + dgrid[k + 1] * (I[1] - grid[k + 1]) +
                                      dgrid[k + 2] * (I[2] - grid[k + 2]);
                    dg += dw / grid[k + 3] * dot;
                }
            });
            dguide[j] += dg;
        }
}

double ew_train_patch(const ew_train_model *m, const ew_train_frame *frames, const ew_patch_ref *ref, int size,
                      ew_train_scratch *s, float *grad, float *out_rgb, const float *ref_tm_override) {
    const ew_guidenet *net = m->net;
    const int P = size, G = net->ngrids, L = net->nlayers;
    const long n = (long)P * P;
    load_patch(&frames[ref->frame], ref, P, s);
    const float *ref_tm = ref_tm_override ? ref_tm_override : s->ref_tm;

    /* GuideNet */
    for (int l = 0; l < L; l++) {
        ew_conv_args a;
        ew_guidenet_layer_args(net, l, m->params, &s->feat, 0, P, s->out, P, n, &a);
        ew_conv_cpu_rows(&a, m->wt + layer_wofs(net, l), 0, P);
    }
    /* grids: guide = 255 * sigmoid, splat, slice */
    for (int g = 0; g < G; g++) {
        const ew_bgrid_params *gp = &s->gp[g];
        for (long j = 0; j < n; j++) s->guide[g][j] = 255.0f * s->out[g * n + j];
        if (!s->use_kernels) {
            fast_prepare(s, g, s->guide[g]);
            fast_splat_slice(s, g);
            continue;
        }
        for (int v = 0; v < gp->gh; v++)
            for (int u = 0; u < gp->gw; u++) ew_bgrid_splat_column(u, v, gp, s->radiance, s->guide[g], s->grid[g]);
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++)
                ew_bgrid_slice_px(x, y, gp, s->grid[g], s->guide[g], s->sliced[g] + ((long)y * P + x) * 3);
    }
    /* blend (the op's kernel), remodulate, loss */
    for (int g = 0; g < G; g++)
        for (long j = 0; j < n; j++) ew_nbg_blend_px(j, g, G, s->out, n, s->sliced[g], s->rgb);
    double loss = 0.0;
    const float scale = 1.0f / (float)(n * 3);
    for (long i = 0; i < n * 3; i++) {
        float o = s->rgb[i] * s->albedo_f[i];
        if (out_rgb) out_rgb[i] = o;
        float d = ew_nbg_tm(o) - ref_tm[i];
        loss += fabs((double)d);
        /* dL/d blend = sign * S'(out) * (albedo + eps) / (3 n) */
        s->drgb[i] = (d > 0.0f ? 1.0f : (d < 0.0f ? -1.0f : 0.0f)) * ew_nbg_tm_grad(o) * s->albedo_f[i] * scale;
    }
    loss /= (double)(n * 3);
    if (!grad) return loss;

    /* blend backward: dL/d sliced_g = w_g dL/dR; dL/dw_g = sliced_g . dL/dR */
    for (int g = 0; g < G; g++) {
        for (long j = 0; j < n; j++) {
            float w[3] = {1.0f, 0.0f, 0.0f};
            if (G == 3) ew_nbg_weights(s->out[3 * n + j], s->out[4 * n + j], w);
            float dot = 0.0f;
            for (int k = 0; k < 3; k++) {
                s->dsl[j * 3 + k] = w[g] * s->drgb[j * 3 + k];
                dot += s->sliced[g][j * 3 + k] * s->drgb[j * 3 + k];
            }
            s->dw[j * 3 + g] = dot;
        }
        /* slice (guide, grid) then splat (guide) backward */
        const ew_bgrid_params *gp = &s->gp[g];
        if (!s->use_kernels) {
            fast_prepare(s, g, s->guide[g]); /* (the tables of grid g: another grid's may be there) */
            fast_backward(s, g);
            continue;
        }
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++)
                ew_bgrid_slice_backward_px(x, y, gp, s->grid[g], s->guide[g], s->dsl, &s->dguide[g][(long)y * P + x],
                                           &s->inv_eta[(long)y * P + x]);
        for (int v = 0; v < gp->gh; v++)
            for (int u = 0; u < gp->gw; u++)
                ew_bgrid_slice_backward_column(u, v, gp, s->grid[g], s->guide[g], s->dsl, s->inv_eta, s->dgrid);
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++)
                ew_bgrid_splat_backward_px(x, y, gp, s->radiance, s->guide[g], s->grid[g], s->dgrid,
                                           &s->dguide[g][(long)y * P + x], NULL);
    }
    /* dL/d (sigmoid output), then through the sigmoid: the last layer's g */
    for (int y = 0; y < P; y++)
        for (int x = 0; x < P; x++) {
            const long j = (long)y * P + x;
            float d[5];
            for (int g = 0; g < G; g++) d[g] = 255.0f * s->dguide[g][j];
            if (G == 3) ew_nbg_weights_backward(s->out[3 * n + j], s->out[4 * n + j], s->dw + j * 3, &d[3], &d[4]);
            for (int o = 0; o < net->nout; o++)
                ew_gn_plane_row(&s->dfinal, o, y)[x] = d[o] * ew_act_grad(s->out[o * n + j], EW_ACT_SIGMOID);
        }
    /* convolutions, last to first; dfeat collects dL/d(hidden planes) */
    for (int c = EW_GN_INPUTS; c < net->nfeat; c++)
        for (int y = 0; y < P; y++) memset(ew_gn_plane_row(&s->dfeat, c, y), 0, sizeof(float) * (size_t)P);
    for (int l = L - 1; l >= 0; l--) {
        const ew_gn_layer *Ly = &net->layers[l];
        ew_conv_args a;
        ew_guidenet_layer_args(net, l, m->params, &s->feat, 0, P, s->out, P, n, &a);
        const ew_gn_planes *gpl = &s->dfinal;
        int gplane = 0;
        if (Ly->out_plane >= 0) {
            /* through the activation, in place: g = dL/d out * act'(out) */
            gpl = &s->dfeat;
            gplane = Ly->out_plane;
            for (int c = 0; c < Ly->cout; c++)
                for (int y = 0; y < P; y++) {
                    float *gr = ew_gn_plane_row(&s->dfeat, gplane + c, y);
                    const float *o = ew_gn_plane_row(&s->feat, gplane + c, y);
                    for (int x = 0; x < P; x++) gr[x] *= ew_act_grad(o[x], Ly->act);
                }
        }
        const float *gdata = ew_gn_plane_row(gpl, gplane, 0);
        ew_conv_cpu_dweight(&a, gdata, gpl->rs, gpl->ps, grad + Ly->w_off, grad + Ly->b_off);
        if (l > 0) {
            ew_conv_args b;
            memset(&b, 0, sizeof b);
            b.width = P;
            b.rows = P;
            b.cin = Ly->cout;
            b.cout = Ly->cin;
            b.in = gdata;
            b.in_rs = gpl->rs;
            b.in_ps = gpl->ps;
            b.out = ew_gn_plane_row(&s->dfeat, Ly->in_plane, 0);
            b.out_rs = s->dfeat.rs;
            b.out_ps = s->dfeat.ps;
            b.weight = m->flip + layer_wofs(net, l);
            b.accumulate = 1;
            ew_conv_cpu_rows(&b, m->fwt + layer_wofs(net, l), 0, P);
        }
    }
    return loss;
}

/* ---- sampling ---------------------------------------------------------------- */
static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

ew_patch_ref ew_train_pick(uint64_t seed, uint64_t step, int index, const ew_train_frame *frames,
                           int (*frame_pick)(void *user, double u), void *user, int size) {
    uint64_t h = mix64(seed * 0x9E3779B97F4A7C15ull + mix64(step * 0xD1B54A32D192ED03ull + (uint64_t)index + 1));
    uint64_t h2 = mix64(h + 1), h3 = mix64(h + 2), h4 = mix64(h + 3);
    ew_patch_ref r;
    r.frame = frame_pick(user, (double)(h >> 11) / 9007199254740992.0);
    const ew_train_frame *f = &frames[r.frame];
    r.x0 = (int)(h2 % (uint64_t)(f->width - size + 1));
    r.y0 = (int)(h3 % (uint64_t)(f->height - size + 1));
    r.aug = (int)(h4 & 7u);
    return r;
}

/* ---- Adam, clipping -------------------------------------------------------------- */
void ew_adam_update(ew_adam *a, float *params, const float *grad, size_t n) {
    a->step++;
    const double c1 = 1.0 - pow(a->beta1, (double)a->step), c2 = 1.0 - pow(a->beta2, (double)a->step);
    for (size_t i = 0; i < n; i++) {
        double g = grad[i];
        double m = a->beta1 * a->m[i] + (1.0 - a->beta1) * g;
        double v = a->beta2 * a->v[i] + (1.0 - a->beta2) * g * g;
        a->m[i] = (float)m;
        a->v[i] = (float)v;
        params[i] -= (float)(a->lr * (m / c1) / (sqrt(v / c2) + a->eps));
    }
}

double ew_clip_global_norm(float *grad, size_t n, double max_norm, int *clipped) {
    double ss = 0.0;
    for (size_t i = 0; i < n; i++) ss += (double)grad[i] * grad[i];
    double norm = sqrt(ss);
    *clipped = 0;
    if (max_norm > 0.0 && norm > max_norm) {
        float k = (float)(max_norm / norm);
        for (size_t i = 0; i < n; i++) grad[i] *= k;
        *clipped = 1;
    }
    return norm;
}

double ew_adam_step(ew_adam *a, float *params, float *grad, size_t n, double max_norm, int *clipped) {
    const double norm = ew_clip_global_norm(grad, n, max_norm, clipped);
    ew_adam_update(a, params, grad, n);
    return norm;
}

int ew_batch_grads_init(ew_batch_grads *g, int batch, size_t nparams) {
    g->batch = batch;
    g->nparams = nparams;
    g->grads = (float *)malloc(sizeof(float) * nparams * (size_t)batch);
    g->losses = (double *)malloc(sizeof(double) * (size_t)batch);
    return g->grads && g->losses ? 0 : -1;
}

void ew_batch_grads_free(ew_batch_grads *g) {
    free(g->grads);
    free(g->losses);
    g->grads = NULL;
    g->losses = NULL;
}

float *ew_batch_grads_patch(ew_batch_grads *g, int b) {
    float *p = g->grads + (size_t)b * g->nparams;
    memset(p, 0, sizeof(float) * g->nparams);
    return p;
}

double ew_batch_grads_mean(const ew_batch_grads *g, float *grad) {
    const size_t np = g->nparams;
    for (size_t i = 0; i < np; i++) {
        float s = 0.0f;
        for (int b = 0; b < g->batch; b++) s += g->grads[(size_t)b * np + i];
        grad[i] = s / (float)g->batch;
    }
    double loss = 0.0;
    for (int b = 0; b < g->batch; b++) loss += g->losses[b];
    return loss / g->batch;
}

/* ---- batches ----------------------------------------------------------------------- */
struct ew_trainer {
    ew_device *dev;
    const ew_guidenet *net;
    int batch, size, nscratch;
    ew_train_model model;
    ew_train_scratch **scratch; /* one per thread */
    ew_batch_grads g;
    float *mean;                /* nparams */
};

ew_trainer *ew_trainer_create(ew_device *dev, const ew_guidenet *net, int batch, int size) {
    ew_trainer *t = (ew_trainer *)calloc(1, sizeof *t);
    if (!t) return NULL;
    t->dev = dev;
    t->net = net;
    t->batch = batch;
    t->size = size;
    t->nscratch = ew_device_get_num_threads(dev);
    t->scratch = (ew_train_scratch **)calloc((size_t)t->nscratch, sizeof *t->scratch);
    t->mean = (float *)malloc(sizeof(float) * net->nparams);
    int bad = ew_batch_grads_init(&t->g, batch, net->nparams) != 0 || !t->scratch || !t->mean ||
              ew_train_model_init(&t->model, net) != 0;
    for (int i = 0; !bad && i < t->nscratch; i++) bad = !(t->scratch[i] = ew_train_scratch_create(net, size));
    if (bad) {
        ew_trainer_destroy(t);
        return NULL;
    }
    return t;
}

void ew_trainer_destroy(ew_trainer *t) {
    if (!t) return;
    for (int i = 0; t->scratch && i < t->nscratch; i++) ew_train_scratch_destroy(t->scratch[i]);
    free(t->scratch);
    ew_batch_grads_free(&t->g);
    free(t->mean);
    ew_train_model_free(&t->model);
    free(t);
}

typedef struct {
    ew_trainer *t;
    const ew_train_frame *frames;
    const ew_patch_ref *refs;
} batch_job;

static void batch_items(void *ctx, int64_t begin, int64_t end, int tid) {
    const batch_job *j = (const batch_job *)ctx;
    ew_trainer *t = j->t;
    for (int64_t b = begin; b < end; b++)
        t->g.losses[b] = ew_train_patch(&t->model, j->frames, &j->refs[b], t->size, t->scratch[tid],
                                        ew_batch_grads_patch(&t->g, (int)b), NULL, NULL);
}

double ew_trainer_gradient(ew_trainer *t, const float *params, const ew_train_frame *frames, const ew_patch_ref *refs,
                           float *grad) {
    ew_train_model_prepare(&t->model, params);
    batch_job j = {t, frames, refs};
    ew_pool_run(t->dev->pool, t->batch, 1, batch_items, &j);
    return ew_batch_grads_mean(&t->g, grad);
}

void ew_trainer_step(ew_trainer *t, float *params, ew_adam *adam, const ew_train_frame *frames,
                     const ew_patch_ref *refs, double max_norm, ew_train_step_stats *stats) {
    stats->loss = ew_trainer_gradient(t, params, frames, refs, t->mean);
    stats->grad_norm = ew_adam_step(adam, params, t->mean, t->net->nparams, max_norm, &stats->clipped);
}
