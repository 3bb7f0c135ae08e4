#include "algorithms/kpcn.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/train.h"
#include "backends/cpu/cpu_conv.h"
#include "kernels/guidenet.h"
#include "kernels/outlier.h"
#include "kernels/reduce.h"
#include "src/backend.h"
#include "src/internal.h"

/* ---- architecture ------------------------------------------------------- */
int ew_kpcn_init(ew_kpcn_net *net, const char *arch, char *err, size_t errlen) {
    memset(net, 0, sizeof *net);
    int c = 0, used = 0;
    if (!arch || sscanf(arch, "kpcn-c%d%n", &c, &used) != 1 || c < EW_KPCN_MIN_CH || c > EW_KPCN_MAX_CH ||
        (arch[used] != '\0' && strcmp(arch + used, "-noise") != 0)) {
        snprintf(err, errlen, "unknown kpcn architecture '%s' (expected kpcn-c<C> or kpcn-c<C>-noise, C in %d..%d)",
                 arch ? arch : "", EW_KPCN_MIN_CH, EW_KPCN_MAX_CH);
        return 1;
    }
    net->noise = arch[used] != '\0';
    net->inputs = net->noise ? EW_KPCN_MAX_INPUTS : EW_KPCN_INPUTS;
    snprintf(net->arch, sizeof net->arch, "kpcn-c%d%s", c, net->noise ? "-noise" : "");
    net->ch = c;
    net->h0 = net->inputs;
    net->u0 = net->h0 + c;
    net->d0 = net->u0 + c;
    net->k0 = net->d0 + c;
    net->nplanes[0] = net->k0 + EW_KPCN_HEAD;
    net->p1 = 0;
    net->h1 = c;
    net->u1 = 2 * c;
    net->d1 = 3 * c;
    net->k1 = 4 * c;
    net->nplanes[1] = net->k1 + EW_KPCN_HEAD;
    net->p2 = 0;
    net->h2a = c;
    net->h2b = 2 * c;
    net->k2 = 3 * c;
    net->nplanes[2] = net->k2 + EW_KPCN_TAPS;
    const int L = EW_ACT_LEAKY, N = EW_ACT_NONE;
    const ew_kpcn_layer spec[EW_KPCN_NLAYERS] = {
        {0, 0, net->inputs, net->h0, c, L, 0, 0},
        {1, net->p1, c, net->h1, c, L, 0, 0},
        {2, net->p2, c, net->h2a, c, L, 0, 0},
        {2, net->h2a, c, net->h2b, c, L, 0, 0},
        {2, net->h2b, c, net->k2, EW_KPCN_TAPS, N, 0, 0},
        {1, net->h1, 2 * c, net->d1, c, L, 0, 0},
        {1, net->d1, c, net->k1, EW_KPCN_HEAD, N, 0, 0},
        {0, net->h0, 2 * c, net->d0, c, L, 0, 0},
        {0, net->d0, c, net->k0, EW_KPCN_HEAD, N, 0, 0},
    };
    size_t off = 0;
    for (int l = 0; l < EW_KPCN_NLAYERS; l++) {
        net->layers[l] = spec[l];
        net->layers[l].w_off = off;
        off += (size_t)spec[l].cin * spec[l].cout * 25;
        net->layers[l].b_off = off;
        off += (size_t)spec[l].cout;
    }
    net->nparams = off;
    return 0;
}

static uint64_t splitmix(uint64_t *s) {
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

void ew_kpcn_random(const ew_kpcn_net *net, uint64_t seed, float *params) {
    uint64_t s = seed * 0x2545F4914F6CDD1Dull + 7;
    memset(params, 0, net->nparams * sizeof(float));
    for (int l = 0; l < EW_KPCN_NLAYERS; l++) {
        const ew_kpcn_layer *L = &net->layers[l];
        double bound = sqrt(6.0 / ((1.0 + (double)EW_LEAKY_SLOPE * EW_LEAKY_SLOPE) * L->cin * 25.0));
        if (L->act == EW_ACT_NONE) bound *= 0.1;
        float *w = params + L->w_off;
        for (size_t i = 0; i < (size_t)L->cin * L->cout * 25; i++)
            w[i] = (float)(bound * ((double)(splitmix(&s) >> 11) * (2.0 / 9007199254740992.0) - 1.0));
    }
}

double ew_kpcn_macs_per_pixel(const ew_kpcn_net *net) {
    double m = 0.0;
    for (int l = 0; l < EW_KPCN_NLAYERS; l++) {
        const ew_kpcn_layer *L = &net->layers[l];
        m += 25.0 * L->cin * L->cout / (double)(1 << (2 * L->scale));
    }
    return m;
}

int ew_kpcn_from_weights(ew_kpcn_net *net, const ew_weights *w, float **params, char *err, size_t errlen) {
    *params = NULL;
    if (strncmp(w->arch, "kpcn-", 5) != 0) {
        snprintf(err, errlen, "weights are for '%s', not kpcn (expected 'kpcn-c<C>[-noise]')", w->arch);
        return 1;
    }
    if (ew_kpcn_init(net, w->arch, err, errlen) != 0) return 1;
    float *p = (float *)malloc(net->nparams * sizeof(float));
    if (!p) {
        snprintf(err, errlen, "out of memory for %zu kpcn parameters", net->nparams);
        return 1;
    }
    for (int l = 0; l < EW_KPCN_NLAYERS; l++) {
        const ew_kpcn_layer *L = &net->layers[l];
        if (ew_weights_get_conv(w, l, L->cin, L->cout, p, L->w_off, L->b_off, err, errlen) != 0) {
            free(p);
            return 1;
        }
    }
    *params = p;
    return 0;
}

int ew_kpcn_save(const ew_kpcn_net *net, const float *params, void **out, size_t *size) {
    ew_tensor t[2 * EW_KPCN_NLAYERS];
    memset(t, 0, sizeof t);
    int n = 0;
    for (int l = 0; l < EW_KPCN_NLAYERS; l++, n += 2) {
        const ew_kpcn_layer *L = &net->layers[l];
        ew_weights_put_conv(&t[n], l, L->cin, L->cout, params, L->w_off, L->b_off);
    }
    ew_weights w;
    memset(&w, 0, sizeof w);
    snprintf(w.arch, sizeof w.arch, "%s", net->arch);
    w.num_tensors = (uint32_t)n;
    w.tensors = t;
    return ew_weights_serialize(&w, out, size);
}

void ew_kpcn_scale_sizes(int w, int h, int *sw, int *sh) {
    sw[0] = w;
    sh[0] = h;
    for (int s = 1; s < EW_KPCN_SCALES; s++) {
        sw[s] = ew_kpcn_half(sw[s - 1]);
        sh[s] = ew_kpcn_half(sh[s - 1]);
    }
}

void ew_kpcn_layer_args(const ew_kpcn_net *net, int l, const float *params, const ew_gn_planes *buf,
                        ew_conv_args *a) {
    const ew_kpcn_layer *L = &net->layers[l];
    const ew_gn_planes *b = &buf[L->scale];
    memset(a, 0, sizeof *a);
    a->width = b->width;
    a->rows = b->rows;
    a->cin = L->cin;
    a->cout = L->cout;
    a->in = ew_gn_plane_row(b, L->in_plane, 0);
    a->in_rs = b->rs;
    a->in_ps = b->ps;
    a->out = ew_gn_plane_row(b, L->out_plane, 0);
    a->out_rs = b->rs;
    a->out_ps = b->ps;
    a->weight = params + L->w_off;
    a->bias = params + L->b_off;
    a->act = L->act;
}

size_t ew_kpcn_device_floats(const ew_kpcn_net *net, int w, int h) {
    int sw[EW_KPCN_SCALES], sh[EW_KPCN_SCALES];
    ew_kpcn_scale_sizes(w, h, sw, sh);
    size_t f = 0;
    for (int s = 0; s < EW_KPCN_SCALES; s++) f += ew_gn_planes_floats(sw[s], sh[s], net->nplanes[s]) + 16;
    /* radiance and output of scales 1 and 2, 3 planes each */
    for (int s = 1; s < EW_KPCN_SCALES; s++) f += 2 * 3 * (size_t)sw[s] * sh[s];
    return f;
}

static size_t region_floats(const ew_kpcn_net *net, int w, int h, size_t extra) {
    return ew_kpcn_device_floats(net, w, h) + extra * (size_t)w * (size_t)h;
}

/* Core size n split into tiles of side t (a multiple of 4): the regions'
 * summed length along that axis. */
static long regions_length(int n, int t) {
    long sum = 0;
    for (int c = 0; c < n; c += t) {
        const int r0 = c - EW_KPCN_HALO < 0 ? 0 : c - EW_KPCN_HALO;
        const int r1 = c + t + EW_KPCN_HALO > n ? n : c + t + EW_KPCN_HALO;
        sum += r1 - r0;
    }
    return sum;
}

static int region_side(int n, int t) {
    if (t >= n) return n;
    const int r = t + 2 * EW_KPCN_HALO;
    return r > n ? n : r;
}

void ew_kpcn_tiling_plan(const ew_kpcn_net *net, int w, int h, size_t budget_floats, size_t region_extra_floats,
                         ew_kpcn_tiling *t) {
    memset(t, 0, sizeof *t);
    t->width = w;
    t->height = h;
    t->tw = w;
    t->th = h;
    if (region_floats(net, w, h, region_extra_floats) > budget_floats) {
        /* for each tile width, the tallest tile that fits; keep the plan
         * with the fewest region pixels (the work, halos included) */
        double best = -1.0;
        int last = 0;
        for (int nx = 1; nx <= (w + EW_KPCN_MIN_TILE - 1) / EW_KPCN_MIN_TILE; nx++) {
            const int tw = ((w + nx - 1) / nx + 3) / 4 * 4;
            if (tw == last || tw < EW_KPCN_MIN_TILE) continue;
            last = tw;
            const int rw = region_side(w, tw);
            int lo = 0, hi = (h + 3) / 4; /* th = 4 * k: the largest k whose region fits */
            while (lo < hi) {
                const int mid = (lo + hi + 1) / 2;
                if (region_floats(net, rw, region_side(h, 4 * mid), region_extra_floats) <= budget_floats) lo = mid;
                else hi = mid - 1;
            }
            if (4 * lo < EW_KPCN_MIN_TILE) continue;
            const double cost = (double)regions_length(w, tw) * (double)regions_length(h, 4 * lo);
            if (best < 0.0 || cost < best) {
                best = cost;
                t->tw = tw;
                t->th = 4 * lo;
            }
        }
        if (best < 0.0) t->tw = t->th = EW_KPCN_MIN_TILE;
        if (t->tw > w) t->tw = w;
        if (t->th > h) t->th = h;
    }
    t->nx = (w + t->tw - 1) / t->tw;
    t->ny = (h + t->th - 1) / t->th;
    t->rw = region_side(w, t->tw);
    t->rh = region_side(h, t->th);
}

void ew_kpcn_tile_at(const ew_kpcn_tiling *t, int i, ew_kpcn_tile *tile) {
    const int ix = i % t->nx, iy = i / t->nx;
    tile->cx = ix * t->tw;
    tile->cy = iy * t->th;
    tile->cw = ew_mini(t->tw, t->width - tile->cx);
    tile->ch = ew_mini(t->th, t->height - tile->cy);
    tile->rx = ew_maxi(tile->cx - EW_KPCN_HALO, 0);
    tile->ry = ew_maxi(tile->cy - EW_KPCN_HALO, 0);
    tile->rw = ew_mini(tile->cx + tile->cw + EW_KPCN_HALO, t->width) - tile->rx;
    tile->rh = ew_mini(tile->cy + tile->ch + EW_KPCN_HALO, t->height) - tile->ry;
}

/* Which channel of src's layer input i of net's layer is, or -1 for a channel
 * src does not have: a decoder's input is [skip (C), upsampled (C)], so
 * its second half moves when the width changes. */
static int src_input_channel(const ew_kpcn_net *net, const ew_kpcn_net *src, int l, int i) {
    const ew_kpcn_layer *D = &net->layers[l], *S = &src->layers[l];
    if (D->cin == 2 * net->ch && S->cin == 2 * src->ch) {
        const int half = i >= net->ch, k = half ? i - net->ch : i;
        return k < src->ch ? (half ? src->ch + k : k) : -1;
    }
    return i < S->cin ? i : -1;
}

void ew_kpcn_params_from(const ew_kpcn_net *net, float *params, const ew_kpcn_net *src, const float *src_params) {
    for (int l = 0; l < EW_KPCN_NLAYERS; l++) {
        const ew_kpcn_layer *D = &net->layers[l], *S = &src->layers[l];
        for (int o = 0; o < D->cout; o++) {
            const int old_out = o < S->cout;
            for (int i = 0; i < D->cin; i++) {
                float *w = params + D->w_off + ((size_t)o * D->cin + i) * 25;
                const int si = src_input_channel(net, src, l, i);
                if (old_out && si >= 0)
                    memcpy(w, src_params + S->w_off + ((size_t)o * S->cin + si) * 25, 25 * sizeof(float));
                else if (old_out)
                    memset(w, 0, 25 * sizeof(float));
            }
            params[D->b_off + o] = old_out ? src_params[S->b_off + o] : 0.0f;
        }
    }
}

float ew_kpcn_frame_noise(int width, int height, const float *radiance) {
    double *rows = (double *)malloc(sizeof(double) * 2 * (size_t)height);
    if (!rows) return ew_kpcn_noise_feature(0.0);
    for (int y = 0; y < height; y++) ew_reduce_row(EW_REDUCE_NOISE, y, width, radiance, rows);
    const float noise = ew_kpcn_noise_from_rows(rows, height);
    free(rows);
    return noise;
}

/* ---- frames --------------------------------------------------------------- */
void ew_kpcn_frame_free(ew_kpcn_frame *f) {
    if (!f) return;
    free(f->input);
    free(f->radiance);
    free(f->albedo_f);
    free(f->ref);
    memset(f, 0, sizeof *f);
}

int ew_kpcn_frame_init(ew_kpcn_frame *f, int width, int height, const float *color, const float *albedo,
                       const float *normal, const float *depth, const float *reference, float firefly_k) {
    memset(f, 0, sizeof *f);
    const long n = (long)width * height;
    f->width = width;
    f->height = height;
    f->input = (float *)malloc(sizeof(float) * n * EW_KPCN_MAX_INPUTS);
    f->radiance = (float *)calloc((size_t)n * 3, sizeof(float)); /* the clamp pass writes all of it; GCC cannot tell */
    f->albedo_f = (float *)malloc(sizeof(float) * n * 3);
    f->ref = (float *)malloc(sizeof(float) * n * 3);
    float *raw = (float *)malloc(sizeof(float) * n * 4);
    double *rows = (double *)malloc(sizeof(double) * 2 * (size_t)height);
    if (!f->input || !f->radiance || !f->albedo_f || !f->ref || !raw || !rows) {
        free(raw);
        free(rows);
        ew_kpcn_frame_free(f);
        return 1;
    }
    /* the op's steps in its order: depth normalisation, demodulation,
     * firefly clamp, inputs */
    double mx = 0.0;
    for (int y = 0; y < height; y++) ew_reduce_row(EW_REDUCE_DEPTH_MAX, y, width, depth, rows);
    for (int y = 0; y < height; y++)
        if (rows[2 * y] > mx) mx = rows[2 * y];
    free(rows);
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
    for (long j = 0; j < n; j++) ew_denoise_prepare_px(j, &b);
    const ew_outlier_params fp = ew_kpcn_clamp_params(width, height, firefly_k);
    const ew_outlier_buffers fb = {raw, NULL, NULL, f->radiance, 3};
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) ew_outlier_guided_px(x, y, &fp, &fb);
    free(raw);
    ew_kpcn_input_args ia = {width, height, f->radiance, albedo, normal, depth, b.depth_scale, f->input, width, n,
                             1, ew_kpcn_frame_noise(width, height, f->radiance), width};
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) ew_kpcn_input_px(x, y, &ia);
    for (long j = 0; j < n; j++)
        for (int k = 0; k < 3; k++) {
            f->albedo_f[j * 3 + k] = ew_albedo_factor(albedo[j * 3 + k]);
            f->ref[j * 3 + k] = ew_feature_or_zero(reference[j * 3 + k]);
        }
    return 0;
}

/* ---- scratch -------------------------------------------------------------- */
struct ew_kpcn_scratch {
    int size, inputs;
    ew_gn_planes buf[EW_KPCN_SCALES], dbuf[EW_KPCN_SCALES];
    float *rad[EW_KPCN_SCALES]; /* 3 planes each */
    float *out[EW_KPCN_SCALES], *dout[EW_KPCN_SCALES];
    float *albedo_f, *ref; /* 3 planes each, scale 0 */
    void *mem[2 * EW_KPCN_SCALES + 1];
};

ew_kpcn_scratch *ew_kpcn_scratch_create(const ew_kpcn_net *net, int size) {
    ew_kpcn_scratch *s = (ew_kpcn_scratch *)calloc(1, sizeof *s);
    if (!s) return NULL;
    s->size = size;
    s->inputs = net->inputs;
    size_t flat = 0;
    for (int k = 0; k < EW_KPCN_SCALES; k++) {
        const int P = size >> k;
        const size_t fl = ew_gn_planes_floats(P, P, net->nplanes[k]);
        s->mem[2 * k] = aligned_alloc(64, (fl * sizeof(float) + 63) / 64 * 64);
        s->mem[2 * k + 1] = aligned_alloc(64, (fl * sizeof(float) + 63) / 64 * 64);
        if (!s->mem[2 * k] || !s->mem[2 * k + 1]) {
            ew_kpcn_scratch_destroy(s);
            return NULL;
        }
        ew_gn_planes_init(&s->buf[k], (float *)s->mem[2 * k], P, P, net->nplanes[k]);
        ew_gn_planes_init(&s->dbuf[k], (float *)s->mem[2 * k + 1], P, P, net->nplanes[k]);
        flat += 3 * 3 * (size_t)P * P;
    }
    flat += 2 * 3 * (size_t)size * size;
    float *p = (float *)calloc(flat, sizeof(float));
    s->mem[2 * EW_KPCN_SCALES] = p;
    if (!p) {
        ew_kpcn_scratch_destroy(s);
        return NULL;
    }
    for (int k = 0; k < EW_KPCN_SCALES; k++) {
        const size_t np = (size_t)(size >> k) * (size >> k);
        s->rad[k] = p; p += 3 * np;
        s->out[k] = p; p += 3 * np;
        s->dout[k] = p; p += 3 * np;
    }
    s->albedo_f = p; p += 3 * (size_t)size * size;
    s->ref = p;
    return s;
}

void ew_kpcn_scratch_destroy(ew_kpcn_scratch *s) {
    if (!s) return;
    for (int i = 0; i < 2 * EW_KPCN_SCALES + 1; i++) free(s->mem[i]);
    free(s);
}

/* ---- weights re-laid out for the SIMD convolutions ------------------------ */
int ew_kpcn_model_init(ew_kpcn_model *m, const ew_kpcn_net *net) {
    memset(m, 0, sizeof *m);
    m->net = net;
    m->wt = (float *)malloc(net->nparams * sizeof(float));
    m->fwt = (float *)malloc(net->nparams * sizeof(float));
    m->flip = (float *)malloc(net->nparams * sizeof(float));
    if (!m->wt || !m->fwt || !m->flip) {
        ew_kpcn_model_free(m);
        return 1;
    }
    return 0;
}

void ew_kpcn_model_free(ew_kpcn_model *m) {
    free(m->wt);
    free(m->fwt);
    free(m->flip);
    memset(m, 0, sizeof *m);
}

/* layer l's re-laid-out weights sit at its w_off in wt, fwt and flip */
void ew_kpcn_model_prepare(ew_kpcn_model *m, const float *params) {
    const ew_kpcn_net *net = m->net;
    m->params = params;
    for (int l = 0; l < EW_KPCN_NLAYERS; l++) {
        const ew_kpcn_layer *L = &net->layers[l];
        ew_conv_cpu_wt_layout(L->cin, L->cout, params + L->w_off, m->wt + L->w_off);
        ew_conv5_flip_weights(L->cin, L->cout, params + L->w_off, m->flip + L->w_off);
        ew_conv_cpu_wt_layout(L->cout, L->cin, m->flip + L->w_off, m->fwt + L->w_off);
    }
}

/* ---- one patch -------------------------------------------------------------- */
static ew_kpcn_tensor planes_t(const ew_gn_planes *b, int plane) {
    ew_kpcn_tensor t = {ew_gn_plane_row(b, plane, 0), 1, b->rs, b->ps};
    return t;
}

static ew_kpcn_tensor flat_t(float *p, int w, int h) {
    ew_kpcn_tensor t = {p, 1, w, (long)w * h};
    return t;
}

static void load_patch(const ew_kpcn_frame *f, const ew_kpcn_patch *r, int size, ew_kpcn_scratch *s,
                       const float *ref_override) {
    const long n = (long)f->width * f->height, np = (long)size * size;
    const int flipx = r->aug & 1, flipy = r->aug & 2, tr = r->aug & 4;
    for (int v = 0; v < size; v++)
        for (int u = 0; u < size; u++) {
            int a = tr ? v : u, b = tr ? u : v;
            if (flipx) a = size - 1 - a;
            if (flipy) b = size - 1 - b;
            const long j = (long)(r->y0 + b) * f->width + (r->x0 + a), q = (long)v * size + u;
            for (int c = 0; c < s->inputs; c++) ew_gn_plane_row(&s->buf[0], c, v)[u] = f->input[c * n + j];
            /* normals follow the symmetry (as algorithms/train.c) */
            float nx = f->input[6 * n + j], ny = f->input[7 * n + j];
            if (flipx) nx = 1.0f - nx;
            if (flipy) ny = 1.0f - ny;
            ew_gn_plane_row(&s->buf[0], 6, v)[u] = tr ? ny : nx;
            ew_gn_plane_row(&s->buf[0], 7, v)[u] = tr ? nx : ny;
            for (int k = 0; k < 3; k++) {
                s->rad[0][k * np + q] = f->radiance[j * 3 + k];
                s->albedo_f[k * np + q] = f->albedo_f[j * 3 + k];
                s->ref[k * np + q] = ref_override ? ref_override[q * 3 + k] : f->ref[j * 3 + k];
            }
        }
}

static void conv_fwd(const ew_kpcn_model *m, int l, const ew_gn_planes *buf) {
    ew_conv_args a;
    ew_kpcn_layer_args(m->net, l, m->params, buf, &a);
    ew_conv_cpu_rows(&a, m->wt + m->net->layers[l].w_off, 0, a.rows);
}

/* Backward of layer l: dbuf holds dL/d(its output) in the output planes;
 * applies the activation's derivative there, adds dL/dW, dL/db to grad and,
 * unless l == 0, dL/d input into dbuf's input planes. */
static void conv_bwd(const ew_kpcn_model *m, int l, const ew_gn_planes *buf, const ew_gn_planes *dbuf, float *grad) {
    const ew_kpcn_layer *L = &m->net->layers[l];
    const ew_gn_planes *b = &buf[L->scale], *d = &dbuf[L->scale];
    if (L->act != EW_ACT_NONE)
        for (int c = 0; c < L->cout; c++)
            for (int y = 0; y < b->rows; y++) {
                float *g = ew_gn_plane_row(d, L->out_plane + c, y);
                const float *o = ew_gn_plane_row(b, L->out_plane + c, y);
                for (int x = 0; x < b->width; x++) g[x] *= ew_act_grad(o[x], L->act);
            }
    ew_conv_args a;
    ew_kpcn_layer_args(m->net, l, m->params, buf, &a);
    const float *g = ew_gn_plane_row(d, L->out_plane, 0);
    ew_conv_cpu_dweight(&a, g, d->rs, d->ps, grad + L->w_off, grad + L->b_off);
    if (l == 0) return;
    ew_conv_args bk;
    memset(&bk, 0, sizeof bk);
    bk.width = b->width;
    bk.rows = b->rows;
    bk.cin = L->cout;
    bk.cout = L->cin;
    bk.in = g;
    bk.in_rs = d->rs;
    bk.in_ps = d->ps;
    bk.out = ew_gn_plane_row(d, L->in_plane, 0);
    bk.out_rs = d->rs;
    bk.out_ps = d->ps;
    bk.weight = m->flip + L->w_off;
    bk.accumulate = 1;
    ew_conv_cpu_rows(&bk, m->fwt + L->w_off, 0, b->rows);
}

static void pool_planes(const ew_gn_planes *fine, int fp, const ew_gn_planes *coarse, int cp, int n) {
    ew_kpcn_pool_args a = {fine->width, fine->rows, coarse->width, coarse->rows, n, planes_t(fine, fp),
                           planes_t(coarse, cp)};
    for (int y = 0; y < coarse->rows; y++)
        for (int x = 0; x < coarse->width; x++) ew_kpcn_pool_px(x, y, &a);
}

static void pool_planes_bwd(const ew_gn_planes *dfine, int fp, const ew_gn_planes *dcoarse, int cp, int n) {
    ew_kpcn_pool_args a = {dfine->width, dfine->rows, dcoarse->width, dcoarse->rows, n, planes_t(dfine, fp),
                           planes_t(dcoarse, cp)};
    const ew_kpcn_tensor dc = planes_t(dcoarse, cp), df = planes_t(dfine, fp);
    for (int y = 0; y < dcoarse->rows; y++)
        for (int x = 0; x < dcoarse->width; x++) ew_kpcn_pool_backward_px(x, y, &a, &dc, &df);
}

static void up_planes(const ew_gn_planes *coarse, int cp, const ew_gn_planes *fine, int fp, int n) {
    ew_kpcn_up_args a = {fine->width, fine->rows, coarse->width, coarse->rows, n, planes_t(coarse, cp),
                         planes_t(fine, fp)};
    for (int y = 0; y < fine->rows; y++)
        for (int x = 0; x < fine->width; x++) ew_kpcn_up_px(x, y, &a);
}

static void up_planes_bwd(const ew_gn_planes *dcoarse, int cp, const ew_gn_planes *dfine, int fp, int n) {
    ew_kpcn_up_args a = {dfine->width, dfine->rows, dcoarse->width, dcoarse->rows, n, planes_t(dcoarse, cp),
                         planes_t(dfine, fp)};
    const ew_kpcn_tensor df = planes_t(dfine, fp), dc = planes_t(dcoarse, cp);
    for (int y = 0; y < dfine->rows; y++)
        for (int x = 0; x < dfine->width; x++) ew_kpcn_up_backward_px(x, y, &a, &df, &dc);
}

static ew_kpcn_filter_args filter_args(const ew_kpcn_net *net, ew_kpcn_scratch *s, int k) {
    const int P = s->size >> k;
    const int kp = k == 0 ? net->k0 : k == 1 ? net->k1 : net->k2;
    ew_kpcn_filter_args a;
    memset(&a, 0, sizeof a);
    a.width = a.height = P;
    a.logits = planes_t(&s->buf[k], kp);
    a.radiance = flat_t(s->rad[k], P, P);
    if (k + 1 < EW_KPCN_SCALES) {
        a.coarse = flat_t(s->out[k + 1], P / 2, P / 2);
        a.cw = a.ch = P / 2;
    }
    a.out = flat_t(s->out[k], P, P);
    return a;
}

static float loss_curve(float x, int loss) { return loss == EW_KPCN_LOSS_LOG ? logf(1.0f + ew_maxf(x, 0.0f)) : ew_nbg_tm(x); }
static float loss_slope(float x, int loss) {
    return loss == EW_KPCN_LOSS_LOG ? (x > 0.0f ? 1.0f / (1.0f + x) : 0.0f) : ew_nbg_tm_grad(x);
}

double ew_kpcn_train_patch(const ew_kpcn_model *m, const ew_kpcn_frame *frames, const ew_kpcn_patch *p, int size,
                           int loss, ew_kpcn_scratch *s, float *grad, float *out_rgb, const float *ref_override) {
    const ew_kpcn_net *net = m->net;
    const int C = net->ch, P = size;
    const long np = (long)P * P;
    load_patch(&frames[p->frame], p, P, s, ref_override);
    /* network */
    conv_fwd(m, 0, s->buf);
    pool_planes(&s->buf[0], net->h0, &s->buf[1], net->p1, C);
    conv_fwd(m, 1, s->buf);
    pool_planes(&s->buf[1], net->h1, &s->buf[2], net->p2, C);
    conv_fwd(m, 2, s->buf);
    conv_fwd(m, 3, s->buf);
    conv_fwd(m, 4, s->buf);
    up_planes(&s->buf[2], net->h2b, &s->buf[1], net->u1, C);
    conv_fwd(m, 5, s->buf);
    conv_fwd(m, 6, s->buf);
    up_planes(&s->buf[1], net->d1, &s->buf[0], net->u0, C);
    conv_fwd(m, 7, s->buf);
    conv_fwd(m, 8, s->buf);
    /* radiance pyramid and the filters, coarse to fine */
    for (int k = 1; k < EW_KPCN_SCALES; k++) {
        const int Pf = P >> (k - 1), Pc = P >> k;
        ew_kpcn_pool_args a = {Pf, Pf, Pc, Pc, 3, flat_t(s->rad[k - 1], Pf, Pf), flat_t(s->rad[k], Pc, Pc)};
        for (int y = 0; y < Pc; y++)
            for (int x = 0; x < Pc; x++) ew_kpcn_pool_px(x, y, &a);
    }
    for (int k = EW_KPCN_SCALES - 1; k >= 0; k--) {
        ew_kpcn_filter_args a = filter_args(net, s, k);
        const int Pk = P >> k;
        for (int y = 0; y < Pk; y++)
            for (int x = 0; x < Pk; x++) ew_kpcn_filter_px(x, y, &a);
    }
    /* remodulate, loss, dL/d out0 */
    double sum = 0.0;
    const float scale = 1.0f / (float)(np * 3);
    for (int c = 0; c < 3; c++)
        for (long q = 0; q < np; q++) {
            const long i = c * np + q;
            const float o = s->out[0][i] * s->albedo_f[i];
            if (out_rgb) out_rgb[q * 3 + c] = o;
            const float d = loss_curve(o, loss) - loss_curve(s->ref[i], loss);
            sum += fabs((double)d);
            s->dout[0][i] = (d > 0.0f ? 1.0f : (d < 0.0f ? -1.0f : 0.0f)) * loss_slope(o, loss) * s->albedo_f[i] * scale;
        }
    if (!grad) return sum / (double)(np * 3);

    for (int k = 0; k < EW_KPCN_SCALES; k++) {
        const ew_gn_planes *d = &s->dbuf[k];
        memset(ew_gn_plane_row(d, 0, -EW_CONV_R) - 8, 0, sizeof(float) * (size_t)d->ps * d->nplanes);
        if (k > 0) memset(s->dout[k], 0, sizeof(float) * 3 * (size_t)(P >> k) * (P >> k));
    }
    /* filters, fine to coarse */
    for (int k = 0; k < EW_KPCN_SCALES; k++) {
        ew_kpcn_filter_args a = filter_args(net, s, k);
        const int Pk = P >> k;
        const long nk = (long)Pk * Pk;
        const ew_kpcn_tensor dl = planes_t(&s->dbuf[k], k == 0 ? net->k0 : k == 1 ? net->k1 : net->k2);
        ew_kpcn_tensor dc = {NULL, 1, 0, 0};
        if (k + 1 < EW_KPCN_SCALES) dc = flat_t(s->dout[k + 1], Pk / 2, Pk / 2);
        for (int y = 0; y < Pk; y++)
            for (int x = 0; x < Pk; x++) {
                const long q = (long)y * Pk + x;
                const float g[3] = {s->dout[k][q], s->dout[k][nk + q], s->dout[k][2 * nk + q]};
                ew_kpcn_filter_backward_px(x, y, &a, g, &dl, NULL, &dc);
            }
    }
    /* network, last layer first */
    conv_bwd(m, 8, s->buf, s->dbuf, grad);
    conv_bwd(m, 7, s->buf, s->dbuf, grad);
    up_planes_bwd(&s->dbuf[1], net->d1, &s->dbuf[0], net->u0, C);
    conv_bwd(m, 6, s->buf, s->dbuf, grad);
    conv_bwd(m, 5, s->buf, s->dbuf, grad);
    up_planes_bwd(&s->dbuf[2], net->h2b, &s->dbuf[1], net->u1, C);
    conv_bwd(m, 4, s->buf, s->dbuf, grad);
    conv_bwd(m, 3, s->buf, s->dbuf, grad);
    conv_bwd(m, 2, s->buf, s->dbuf, grad);
    pool_planes_bwd(&s->dbuf[1], net->h1, &s->dbuf[2], net->p2, C);
    conv_bwd(m, 1, s->buf, s->dbuf, grad);
    pool_planes_bwd(&s->dbuf[0], net->h0, &s->dbuf[1], net->p1, C);
    conv_bwd(m, 0, s->buf, s->dbuf, grad);
    return sum / (double)(np * 3);
}

/* ---- batches ------------------------------------------------------------------ */
struct ew_kpcn_trainer {
    ew_device *dev;
    const ew_kpcn_net *net;
    int batch, size, loss, nscratch;
    ew_kpcn_model model;
    ew_kpcn_scratch **scratch;
    ew_batch_grads g;
};

ew_kpcn_trainer *ew_kpcn_trainer_create(ew_device *dev, const ew_kpcn_net *net, int batch, int size, int loss) {
    if (size < 16 || size % 4 != 0) return NULL;
    ew_kpcn_trainer *t = (ew_kpcn_trainer *)calloc(1, sizeof *t);
    if (!t) return NULL;
    t->dev = dev;
    t->net = net;
    t->batch = batch;
    t->size = size;
    t->loss = loss;
    t->nscratch = ew_device_get_num_threads(dev);
    t->scratch = (ew_kpcn_scratch **)calloc((size_t)t->nscratch, sizeof *t->scratch);
    int bad = ew_batch_grads_init(&t->g, batch, net->nparams) != 0 || !t->scratch ||
              ew_kpcn_model_init(&t->model, net) != 0;
    for (int i = 0; !bad && i < t->nscratch; i++) bad = !(t->scratch[i] = ew_kpcn_scratch_create(net, size));
    if (bad) {
        ew_kpcn_trainer_destroy(t);
        return NULL;
    }
    return t;
}

void ew_kpcn_trainer_destroy(ew_kpcn_trainer *t) {
    if (!t) return;
    for (int i = 0; t->scratch && i < t->nscratch; i++) ew_kpcn_scratch_destroy(t->scratch[i]);
    free(t->scratch);
    ew_batch_grads_free(&t->g);
    ew_kpcn_model_free(&t->model);
    free(t);
}

typedef struct {
    ew_kpcn_trainer *t;
    const ew_kpcn_frame *frames;
    const ew_kpcn_patch *patches;
} kbatch_job;

static void kbatch_items(void *ctx, int64_t begin, int64_t end, int tid) {
    const kbatch_job *j = (const kbatch_job *)ctx;
    ew_kpcn_trainer *t = j->t;
    for (int64_t b = begin; b < end; b++)
        t->g.losses[b] = ew_kpcn_train_patch(&t->model, j->frames, &j->patches[b], t->size, t->loss, t->scratch[tid],
                                             ew_batch_grads_patch(&t->g, (int)b), NULL, NULL);
}

double ew_kpcn_trainer_gradient(ew_kpcn_trainer *t, const float *params, const ew_kpcn_frame *frames,
                                const ew_kpcn_patch *patches, float *grad) {
    ew_kpcn_model_prepare(&t->model, params);
    kbatch_job j = {t, frames, patches};
    ew_pool_run(t->dev->pool, t->batch, 1, kbatch_items, &j);
    return ew_batch_grads_mean(&t->g, grad);
}

/* ---- built-in models (kpcn_weights_data.c) ---------------------------------- */
const char *const ew_kpcn_model_names[EW_KPCN_NUM_MODELS + 1] = {"kpcn", "kpcn-small", "kpcn-large", NULL};

const char *ew_kpcn_model_name(int which) {
    return which >= 0 && which < EW_KPCN_NUM_MODELS ? ew_kpcn_model_names[which] : NULL;
}

void ew_kpcn_builtin_weights(int which, const unsigned char **bytes, size_t *size) {
    const int ok = which >= 0 && which < EW_KPCN_NUM_MODELS;
    *bytes = ok ? ew_kpcn_builtin_bytes[which] : NULL;
    *size = ok ? ew_kpcn_builtin_sizes[which] : 0;
}
