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
    int c = 0, used = 0, S = EW_KPCN_DEFAULT_SCALES, noise = 0, remod = 0;
    int ok = arch && sscanf(arch, "kpcn-c%d%n", &c, &used) == 1 && c >= EW_KPCN_MIN_CH && c <= EW_KPCN_MAX_CH;
    const char *rest = ok ? arch + used : "";
    if (ok && strncmp(rest, "-noise", 6) == 0) {
        noise = 1;
        rest += 6;
    }
    if (ok && strncmp(rest, "-s", 2) == 0) {
        int sused = 0;
        ok = sscanf(rest, "-s%d%n", &S, &sused) == 1 && S > EW_KPCN_DEFAULT_SCALES && S <= EW_KPCN_MAX_SCALES;
        rest += sused;
    }
    if (ok && strcmp(rest, "-ra") == 0) {
        remod = 1;
        rest += 3;
    }
    ok = ok && rest[0] == '\0';
    if (!ok) {
        snprintf(err, errlen,
                 "unknown kpcn architecture '%s' (expected kpcn-c<C>[-noise][-s<S>][-ra], C in %d..%d, S in %d..%d)",
                 arch ? arch : "", EW_KPCN_MIN_CH, EW_KPCN_MAX_CH, EW_KPCN_DEFAULT_SCALES + 1, EW_KPCN_MAX_SCALES);
        return 1;
    }
    net->noise = noise;
    net->remod = remod;
    net->inputs = noise ? EW_KPCN_MAX_INPUTS : EW_KPCN_INPUTS;
    net->scales = S;
    net->nlayers = 3 * S;
    char sc[8] = "";
    if (S != EW_KPCN_DEFAULT_SCALES) snprintf(sc, sizeof sc, "-s%d", S);
    snprintf(net->arch, sizeof net->arch, "kpcn-c%d%s%s%s", c, noise ? "-noise" : "", sc, remod ? "-ra" : "");
    net->ch = c;
    /* planes (the layout in kpcn.h) */
    for (int k = 0; k < S - 1; k++) {
        net->in[k] = 0;
        net->h[k] = k == 0 ? net->inputs : c;
        net->u[k] = net->h[k] + c;
        net->d[k] = net->u[k] + c;
        net->head[k] = net->d[k] + c;
        net->nplanes[k] = net->head[k] + (k == 0 ? ew_kpcn_head0_outputs(net) : EW_KPCN_HEAD);
    }
    net->in[S - 1] = 0;
    net->h[S - 1] = c;
    net->hb = 2 * c;
    net->head[S - 1] = 3 * c;
    net->u[S - 1] = net->d[S - 1] = -1;
    net->nplanes[S - 1] = net->head[S - 1] + EW_KPCN_TAPS;
    /* layers, in the order of kpcn.h */
    const int L = EW_ACT_LEAKY, N = EW_ACT_NONE;
    int l = 0;
    ew_kpcn_layer spec[EW_KPCN_MAX_LAYERS];
    memset(spec, 0, sizeof spec);
    for (int k = 0; k < S - 1; k++) {
        net->enc[k] = l;
        spec[l++] = (ew_kpcn_layer){k, net->in[k], k == 0 ? net->inputs : c, net->h[k], c, L, 0, 0};
    }
    net->enc_a = l;
    spec[l++] = (ew_kpcn_layer){S - 1, net->in[S - 1], c, net->h[S - 1], c, L, 0, 0};
    net->enc_b = l;
    spec[l++] = (ew_kpcn_layer){S - 1, net->h[S - 1], c, net->hb, c, L, 0, 0};
    net->lhead[S - 1] = l;
    spec[l++] = (ew_kpcn_layer){S - 1, net->hb, c, net->head[S - 1], EW_KPCN_TAPS, N, 0, 0};
    net->enc[S - 1] = net->dec[S - 1] = -1;
    for (int k = S - 2; k >= 0; k--) {
        net->dec[k] = l;
        spec[l++] = (ew_kpcn_layer){k, net->h[k], 2 * c, net->d[k], c, L, 0, 0};
        net->lhead[k] = l;
        spec[l++] = (ew_kpcn_layer){k, net->d[k], c, net->head[k], k == 0 ? ew_kpcn_head0_outputs(net) : EW_KPCN_HEAD,
                                    N, 0, 0};
    }
    size_t off = 0;
    for (l = 0; l < net->nlayers; l++) {
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

/* the bias of head0's output o in the remodulation kernel (o >= EW_KPCN_HEAD) at the start */
static float remod_bias(int o) { return o == EW_KPCN_HEAD + EW_KPCN_TAPS / 2 ? EW_KPCN_REMOD_CENTRE_BIAS : 0.0f; }

void ew_kpcn_random(const ew_kpcn_net *net, uint64_t seed, float *params) {
    uint64_t s = seed * 0x2545F4914F6CDD1Dull + 7;
    memset(params, 0, net->nparams * sizeof(float));
    for (int l = 0; l < net->nlayers; l++) {
        const ew_kpcn_layer *L = &net->layers[l];
        double bound = sqrt(6.0 / ((1.0 + (double)EW_LEAKY_SLOPE * EW_LEAKY_SLOPE) * L->cin * 25.0));
        if (L->act == EW_ACT_NONE) bound *= 0.1;
        float *w = params + L->w_off;
        for (size_t i = 0; i < (size_t)L->cin * L->cout * 25; i++)
            w[i] = (float)(bound * ((double)(splitmix(&s) >> 11) * (2.0 / 9007199254740992.0) - 1.0));
    }
    if (net->remod)
        for (int o = EW_KPCN_HEAD; o < EW_KPCN_HEAD_REMOD; o++)
            params[net->layers[net->lhead[0]].b_off + o] = remod_bias(o);
}

double ew_kpcn_macs_per_pixel(const ew_kpcn_net *net) {
    double m = 0.0;
    for (int l = 0; l < net->nlayers; l++) {
        const ew_kpcn_layer *L = &net->layers[l];
        m += 25.0 * L->cin * L->cout / (double)(1 << (2 * L->scale));
    }
    return m;
}

int ew_kpcn_from_weights(ew_kpcn_net *net, const ew_weights *w, float **params, char *err, size_t errlen) {
    *params = NULL;
    if (strncmp(w->arch, "kpcn-", 5) != 0) {
        snprintf(err, errlen, "weights are for '%s', not kpcn (expected 'kpcn-c<C>[-noise][-s<S>]')", w->arch);
        return 1;
    }
    if (ew_kpcn_init(net, w->arch, err, errlen) != 0) return 1;
    float *p = (float *)malloc(net->nparams * sizeof(float));
    if (!p) {
        snprintf(err, errlen, "out of memory for %zu kpcn parameters", net->nparams);
        return 1;
    }
    for (int l = 0; l < net->nlayers; l++) {
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
    ew_tensor t[2 * EW_KPCN_MAX_LAYERS];
    memset(t, 0, sizeof t);
    int n = 0;
    for (int l = 0; l < net->nlayers; l++, n += 2) {
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

void ew_kpcn_scale_sizes(const ew_kpcn_net *net, int w, int h, int *sw, int *sh) {
    sw[0] = w;
    sh[0] = h;
    for (int s = 1; s < net->scales; s++) {
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

void ew_kpcn_inference_planes(ew_kpcn_net *net) {
    const int S = net->scales, c = net->ch;
    for (int k = 0; k < S; k++) {
        ew_kpcn_layer *head = &net->layers[net->lhead[k]];
        if (k < S - 1 && net->layers[net->enc[k]].cin <= 2 * c) {
            /* the inputs (scale 0's features, else the pooled planes) are
             * read by the encoder only, before the upsampling and the
             * decoder write u and d: they sit there, the encoder's output
             * (which the decoder reads with u, in one run of planes) below */
            ew_kpcn_layer *enc = &net->layers[net->enc[k]], *dec = &net->layers[net->dec[k]];
            net->h[k] = 0;
            net->u[k] = net->in[k] = c;
            net->d[k] = 2 * c;
            net->head[k] = 3 * c;
            net->nplanes[k] = 3 * c + head->cout;
            enc->in_plane = c;
            enc->out_plane = dec->in_plane = 0;
            dec->out_plane = head->in_plane = 2 * c;
            head->out_plane = 3 * c;
        }
        /* the planes below the head's input are dead once the head runs */
        const int below = k < S - 1 ? net->d[k] : net->hb;
        if (head->cout > below) continue;
        net->nplanes[k] = below + net->ch;
        net->head[k] = 0;
        head->out_plane = 0;
    }
    /* the scales between full resolution and the coarsest run in bands of
     * rows (kpcn.h): their one whole plane group is the encoder's output,
     * which the decoder then writes over; every other of their planes lies
     * in the scale's band (plane 0 there: the inputs, the decoder's [h, u],
     * the head's logits) */
    for (int k = 1; k < S - 1; k++) {
        net->in[k] = net->h[k] = net->u[k] = net->d[k] = net->head[k] = 0;
        net->nplanes[k] = c;
        net->layers[net->enc[k]].in_plane = net->layers[net->enc[k]].out_plane = 0;
        net->layers[net->dec[k]].in_plane = net->layers[net->dec[k]].out_plane = 0;
        net->layers[net->lhead[k]].in_plane = net->layers[net->lhead[k]].out_plane = 0;
    }
}

int ew_kpcn_band_rows(int h) { return (h < EW_KPCN_BAND_ROWS ? h : EW_KPCN_BAND_ROWS) + 2 * EW_KPCN_BAND_MARGIN; }

int ew_kpcn_scale_band_rows(int hk) { return (hk < EW_KPCN_BAND_ROWS ? hk : EW_KPCN_BAND_ROWS) + 2 * EW_CONV_R; }

int ew_kpcn_scale_band_planes(const ew_kpcn_net *net) { return 2 * net->ch > EW_KPCN_HEAD ? 2 * net->ch : EW_KPCN_HEAD; }

size_t ew_kpcn_planes_floats(const ew_kpcn_net *net, int w, int h) {
    int sw[EW_KPCN_MAX_SCALES], sh[EW_KPCN_MAX_SCALES];
    ew_kpcn_scale_sizes(net, w, h, sw, sh);
    size_t f = 0;
    for (int s = 1; s < net->scales; s++) f += ew_gn_planes_floats(sw[s], sh[s], net->nplanes[s]) + 16;
    f += ew_gn_planes_floats(w, ew_kpcn_band_rows(h), net->nplanes[0]) + 16;
    for (int s = 1; s < net->scales - 1; s++)
        f += ew_gn_planes_floats(sw[s], ew_kpcn_scale_band_rows(sh[s]), ew_kpcn_scale_band_planes(net)) + 16;
    return f;
}

size_t ew_kpcn_device_floats(const ew_kpcn_net *net, int w, int h) {
    int sw[EW_KPCN_MAX_SCALES], sh[EW_KPCN_MAX_SCALES];
    ew_kpcn_scale_sizes(net, w, h, sw, sh);
    size_t f = ew_kpcn_planes_floats(net, w, h);
    /* radiance and output of the scales below full resolution, 3 planes each */
    for (int s = 1; s < net->scales; s++) f += 2 * 3 * (size_t)sw[s] * sh[s];
    return f;
}

/* ---- how far an output pixel's inputs reach ---------------------------------
 * Intervals of one axis: which pixels of a plane at scale k a set of pixels
 * [lo, hi] of another plane reads, down to the full-resolution inputs
 * (network features and radiance alike), following kernels/kpcn.h: a 5x5
 * convolution or kernel reads +-2 at its scale, a 2x2 pooling of coarse c
 * reads fine 2c, 2c + 1, the upsampling of fine x reads coarse
 * floor((x - 1) / 2) .. floor((x + 1) / 2). */
typedef struct {
    int lo, hi;
} span;

static span span_union(span a, span b) {
    return (span){a.lo < b.lo ? a.lo : b.lo, a.hi > b.hi ? a.hi : b.hi};
}
static span conv_span(span a) { return (span){a.lo - 2, a.hi + 2}; }
static span up_span(span a) { return (span){(a.lo - 1) >> 1, (a.hi + 1) >> 1}; } /* fine -> the coarse it reads */
static span pool_span(span a) { return (span){2 * a.lo, 2 * a.hi + 1}; }        /* coarse -> the fine it reads */

static span full_res(span a, int k) { /* a pooled plane of scale k: its full-resolution pixels */
    return (span){a.lo << k, (a.hi << k) + (1 << k) - 1};
}

static span reach_encoder(const ew_kpcn_net *net, int k, span a); /* h[k] (and hb via the caller) */
static span reach_in(const ew_kpcn_net *net, int k, span a) {
    return k == 0 ? a : reach_encoder(net, k - 1, pool_span(a));
}
static span reach_encoder(const ew_kpcn_net *net, int k, span a) { return reach_in(net, k, conv_span(a)); }
static span reach_hb(const ew_kpcn_net *net, span a) { return reach_encoder(net, net->scales - 1, conv_span(a)); }
/* the plane scale k's decoder upsamples: hb at the coarsest scale, else d */
static span reach_next(const ew_kpcn_net *net, int k, span a);
static span reach_decoder(const ew_kpcn_net *net, int k, span a) {
    const span in = conv_span(a);
    return span_union(reach_encoder(net, k, in), reach_next(net, k + 1, up_span(in)));
}
static span reach_next(const ew_kpcn_net *net, int k, span a) {
    return k == net->scales - 1 ? reach_hb(net, a) : reach_decoder(net, k, a);
}
static span reach_output(const ew_kpcn_net *net, int k, span a) {
    span r = reach_next(net, k, conv_span(a));              /* the head's input */
    r = span_union(r, full_res(conv_span(a), k));           /* the kernel's taps on the radiance of scale k */
    if (k + 1 < net->scales) r = span_union(r, reach_output(net, k + 1, up_span(a)));
    return r;
}

int ew_kpcn_align(const ew_kpcn_net *net) { return 1 << (net->scales - 1); }

int ew_kpcn_halo(const ew_kpcn_net *net) { return ew_kpcn_halo_around(net, 0); }

int ew_kpcn_halo_around(const ew_kpcn_net *net, int margin) {
    const int align = ew_kpcn_align(net), base = 64 * align; /* far from the frame's edges */
    int halo = 0;
    for (int x = base; x < base + align; x++) {
        const span r = reach_output(net, 0, (span){x, x});
        if (x - r.lo > halo) halo = x - r.lo;
        if (r.hi - x > halo) halo = r.hi - x;
    }
    return (halo + margin + align - 1) / align * align; /* regions start on the pooling grid too */
}

typedef struct {
    const ew_kpcn_net *net;
    size_t extra;
} region_cost;

static size_t region_floats(const void *ctx, int w, int h) {
    const region_cost *c = (const region_cost *)ctx;
    return ew_kpcn_device_floats(c->net, w, h) + c->extra * (size_t)w * (size_t)h;
}

void ew_kpcn_tiling_plan(const ew_kpcn_net *net, int w, int h, size_t budget_floats, size_t region_extra_floats,
                         int margin, ew_tiling *t) {
    const region_cost c = {net, region_extra_floats};
    ew_tiling_plan(w, h, ew_kpcn_halo_around(net, margin), ew_kpcn_align(net), budget_floats, region_floats, &c, t);
}

/* The layer of src that net's layer l continues, or -1 for a new one; *skip:
 * l is the decoder of src's coarsest scale, which continues src's enc_b
 * reading only the skip half of its input. */
static int src_layer(const ew_kpcn_net *net, const ew_kpcn_net *src, int l, int *skip) {
    const int Sd = net->scales, Ss = src->scales;
    *skip = 0;
    if (l == net->enc_a) return Sd == Ss ? src->enc_a : -1;
    if (l == net->enc_b) return Sd == Ss ? src->enc_b : -1;
    for (int k = 0; k < Sd; k++) {
        if (l == net->lhead[k]) return k < Ss ? src->lhead[k] : -1;
        if (k < Sd - 1 && l == net->enc[k]) return k < Ss - 1 ? src->enc[k] : (k == Ss - 1 ? src->enc_a : -1);
        if (k < Sd - 1 && l == net->dec[k]) {
            if (k < Ss - 1) return src->dec[k];
            *skip = k == Ss - 1;
            return *skip ? src->enc_b : -1;
        }
    }
    return -1;
}

/* Which channel of src layer sl's input is input i of net's layer l, or -1
 * for a channel src does not have: a decoder's input is [skip (C),
 * upsampled (C)], so its second half moves when the width changes. */
static int src_input_channel(const ew_kpcn_net *net, const ew_kpcn_net *src, int l, int sl, int skip, int i) {
    const ew_kpcn_layer *D = &net->layers[l], *S = &src->layers[sl];
    if (skip) return i < net->ch && i < src->ch ? i : -1;
    if (D->cin == 2 * net->ch && S->cin == 2 * src->ch) {
        const int half = i >= net->ch, k = half ? i - net->ch : i;
        return k < src->ch ? (half ? src->ch + k : k) : -1;
    }
    return i < S->cin ? i : -1;
}

void ew_kpcn_params_from(const ew_kpcn_net *net, float *params, const ew_kpcn_net *src, const float *src_params) {
    if (src->scales > net->scales) return; /* fewer scales: nothing continues; the trainer refuses it */
    for (int l = 0; l < net->nlayers; l++) {
        int skip;
        const int sl = src_layer(net, src, l, &skip);
        if (sl < 0) continue; /* a new scale's layer: random */
        const ew_kpcn_layer *D = &net->layers[l], *S = &src->layers[sl];
        for (int o = 0; o < D->cout; o++) {
            const int old_out = o < S->cout;
            /* the blend logit of src's coarsest head, now a middle one: weight 0, the bias leaves the blend
             * near 0 */
            const int new_blend = !old_out && S->cout == EW_KPCN_TAPS && o == EW_KPCN_TAPS;
            /* the remodulation kernel src lacks: weight 0, the centre tap's bias alone, so the albedo stays
             * (nearly) the raw one */
            const int new_remod = !old_out && D->cout == EW_KPCN_HEAD_REMOD && o >= EW_KPCN_HEAD;
            for (int i = 0; i < D->cin; i++) {
                float *w = params + D->w_off + ((size_t)o * D->cin + i) * 25;
                const int si = src_input_channel(net, src, l, sl, skip, i);
                if (old_out && si >= 0)
                    memcpy(w, src_params + S->w_off + ((size_t)o * S->cin + si) * 25, 25 * sizeof(float));
                else if (old_out || new_blend || new_remod)
                    memset(w, 0, 25 * sizeof(float));
            }
            params[D->b_off + o] = old_out     ? src_params[S->b_off + o]
                                   : new_blend ? EW_KPCN_NEW_SCALE_BIAS
                                   : new_remod ? remod_bias(o)
                                               : 0.0f;
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
    free(f->albedo);
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
    f->albedo = (float *)malloc(sizeof(float) * n * 3);
    f->ref = (float *)malloc(sizeof(float) * n * 3);
    float *raw = (float *)malloc(sizeof(float) * n * 4);
    double *rows = (double *)malloc(sizeof(double) * 2 * (size_t)height);
    if (!f->input || !f->radiance || !f->albedo || !f->ref || !raw || !rows) {
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
    for (long j = 0; j < n; j++) ew_denoise_prepare_px(j, j, &b);
    const ew_outlier_params fp = ew_kpcn_clamp_params(width, height, firefly_k);
    const ew_outlier_buffers fb = {raw, NULL, NULL, f->radiance, 3, NULL};
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) ew_outlier_guided_px(x, y, &fp, &fb);
    free(raw);
    ew_kpcn_input_args ia = {width, height, f->radiance, albedo, normal, depth, b.depth_scale, f->input, width, n,
                             1, ew_kpcn_frame_noise(width, height, f->radiance), width, 0, 0, 0};
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) ew_kpcn_input_px(x, y, &ia);
    for (long j = 0; j < n; j++)
        for (int k = 0; k < 3; k++) {
            f->albedo[j * 3 + k] = albedo[j * 3 + k];
            f->ref[j * 3 + k] = ew_feature_or_zero(reference[j * 3 + k]);
        }
    return 0;
}

/* ---- scratch -------------------------------------------------------------- */
struct ew_kpcn_scratch {
    int size, inputs, scales;
    ew_gn_planes buf[EW_KPCN_MAX_SCALES], dbuf[EW_KPCN_MAX_SCALES];
    float *rad[EW_KPCN_MAX_SCALES]; /* 3 planes each */
    float *out[EW_KPCN_MAX_SCALES], *dout[EW_KPCN_MAX_SCALES];
    float *albedo, *m, *ref; /* 3 planes each, scale 0: the raw albedo, the remodulation albedo, the reference */
    void *mem[2 * EW_KPCN_MAX_SCALES + 1];
};

ew_kpcn_scratch *ew_kpcn_scratch_create(const ew_kpcn_net *net, int size) {
    ew_kpcn_scratch *s = (ew_kpcn_scratch *)calloc(1, sizeof *s);
    if (!s) return NULL;
    s->size = size;
    s->inputs = net->inputs;
    s->scales = net->scales;
    size_t flat = 0;
    for (int k = 0; k < net->scales; k++) {
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
    flat += 3 * 3 * (size_t)size * size;
    float *p = (float *)calloc(flat, sizeof(float));
    s->mem[2 * EW_KPCN_MAX_SCALES] = p;
    if (!p) {
        ew_kpcn_scratch_destroy(s);
        return NULL;
    }
    for (int k = 0; k < net->scales; k++) {
        const size_t np = (size_t)(size >> k) * (size >> k);
        s->rad[k] = p; p += 3 * np;
        s->out[k] = p; p += 3 * np;
        s->dout[k] = p; p += 3 * np;
    }
    s->albedo = p; p += 3 * (size_t)size * size;
    s->m = p; p += 3 * (size_t)size * size;
    s->ref = p;
    return s;
}

void ew_kpcn_scratch_destroy(ew_kpcn_scratch *s) {
    if (!s) return;
    for (int i = 0; i < 2 * EW_KPCN_MAX_SCALES + 1; i++) free(s->mem[i]);
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
    for (int l = 0; l < net->nlayers; l++) {
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
                s->albedo[k * np + q] = f->albedo[j * 3 + k];
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
                         planes_t(fine, fp), 0};
    for (int y = 0; y < fine->rows; y++)
        for (int x = 0; x < fine->width; x++) ew_kpcn_up_px(x, y, &a);
}

static void up_planes_bwd(const ew_gn_planes *dcoarse, int cp, const ew_gn_planes *dfine, int fp, int n) {
    ew_kpcn_up_args a = {dfine->width, dfine->rows, dcoarse->width, dcoarse->rows, n, planes_t(dcoarse, cp),
                         planes_t(dfine, fp), 0};
    const ew_kpcn_tensor df = planes_t(dfine, fp), dc = planes_t(dcoarse, cp);
    for (int y = 0; y < dfine->rows; y++)
        for (int x = 0; x < dfine->width; x++) ew_kpcn_up_backward_px(x, y, &a, &df, &dc);
}

static ew_kpcn_filter_args filter_args(const ew_kpcn_net *net, ew_kpcn_scratch *s, int k) {
    const int P = s->size >> k;
    ew_kpcn_filter_args a;
    memset(&a, 0, sizeof a);
    a.width = a.height = P;
    a.logits = planes_t(&s->buf[k], net->head[k]);
    a.radiance = flat_t(s->rad[k], P, P);
    if (k + 1 < net->scales) {
        a.coarse = flat_t(s->out[k + 1], P / 2, P / 2);
        a.cw = a.ch = P / 2;
    }
    a.out = flat_t(s->out[k], P, P);
    return a;
}

/* the full-resolution kernel logits and the raw albedo, for the remodulation kernel */
static ew_kpcn_filter_args remod_args(const ew_kpcn_net *net, ew_kpcn_scratch *s) {
    ew_kpcn_filter_args a;
    memset(&a, 0, sizeof a);
    a.width = a.height = s->size;
    a.logits = planes_t(&s->buf[0], net->head[0]);
    a.albedo = flat_t(s->albedo, s->size, s->size);
    return a;
}

/* the curve the loss compares colours on: the metrics' tone curve, or log(1 + x) */
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
    const int S = net->scales;
    /* network (the layer list of kpcn.h) */
    conv_fwd(m, net->enc[0], s->buf);
    for (int k = 1; k < S - 1; k++) {
        pool_planes(&s->buf[k - 1], net->h[k - 1], &s->buf[k], net->in[k], C);
        conv_fwd(m, net->enc[k], s->buf);
    }
    pool_planes(&s->buf[S - 2], net->h[S - 2], &s->buf[S - 1], net->in[S - 1], C);
    conv_fwd(m, net->enc_a, s->buf);
    conv_fwd(m, net->enc_b, s->buf);
    conv_fwd(m, net->lhead[S - 1], s->buf);
    for (int k = S - 2; k >= 0; k--) {
        up_planes(&s->buf[k + 1], k + 1 == S - 1 ? net->hb : net->d[k + 1], &s->buf[k], net->u[k], C);
        conv_fwd(m, net->dec[k], s->buf);
        conv_fwd(m, net->lhead[k], s->buf);
    }
    /* radiance pyramid and the filters, coarse to fine */
    for (int k = 1; k < S; k++) {
        const int Pf = P >> (k - 1), Pc = P >> k;
        ew_kpcn_pool_args a = {Pf, Pf, Pc, Pc, 3, flat_t(s->rad[k - 1], Pf, Pf), flat_t(s->rad[k], Pc, Pc)};
        for (int y = 0; y < Pc; y++)
            for (int x = 0; x < Pc; x++) ew_kpcn_pool_px(x, y, &a);
    }
    for (int k = S - 1; k >= 0; k--) {
        ew_kpcn_filter_args a = filter_args(net, s, k);
        const int Pk = P >> k;
        for (int y = 0; y < Pk; y++)
            for (int x = 0; x < Pk; x++) ew_kpcn_filter_px(x, y, &a);
    }
    /* the remodulation albedo m: the albedo's factor, or its predicted kernel's result */
    const ew_kpcn_filter_args ra = remod_args(net, s);
    for (int y = 0; y < P; y++)
        for (int x = 0; x < P; x++) {
            const long q = (long)y * P + x;
            float v[EW_KPCN_TAPS], mq[3];
            if (net->remod) ew_kpcn_remod_albedo_px(x, y, &ra, v, mq);
            for (int c = 0; c < 3; c++) s->m[c * np + q] = net->remod ? mq[c] : ew_albedo_factor(s->albedo[c * np + q]);
        }
    /* remodulate, loss; dout0 holds dL/d colour until the backward pass */
    double sum = 0.0, sq = 0.0;
    const float scale = 1.0f / (float)(np * 3);
    for (int c = 0; c < 3; c++)
        for (long q = 0; q < np; q++) {
            const long i = c * np + q;
            const float o = s->out[0][i] * s->m[i];
            if (out_rgb) out_rgb[q * 3 + c] = o;
            const float d = loss_curve(o, loss) - loss_curve(s->ref[i], loss);
            sum += fabs((double)d);
            sq += (double)d * d;
            /* the L1's slope; the PSNR loss's needs the patch's MSE first */
            s->dout[0][i] = loss == EW_KPCN_LOSS_PSNR ? d * loss_slope(o, loss)
                                                      : (d > 0.0f ? 1.0f : (d < 0.0f ? -1.0f : 0.0f)) * loss_slope(o, loss) * scale;
        }
    const double mse = sq / (double)(np * 3);
    const double value = loss == EW_KPCN_LOSS_PSNR ? 10.0 * log10(mse + EW_KPCN_PSNR_EPS) : sum / (double)(np * 3);
    if (!grad) return value;
    if (loss == EW_KPCN_LOSS_PSNR) {
        /* d/dd of 10 log10(mean d^2 + eps): 20 d / (ln 10 (mse + eps) n) */
        const float w = (float)(20.0 / (log(10.0) * (mse + EW_KPCN_PSNR_EPS) * (double)(np * 3)));
        for (long i = 0; i < 3 * np; i++) s->dout[0][i] *= w;
    }

    for (int k = 0; k < S; k++) {
        const ew_gn_planes *d = &s->dbuf[k];
        memset(ew_gn_plane_row(d, 0, -EW_CONV_R) - 8, 0, sizeof(float) * (size_t)d->ps * d->nplanes);
        if (k > 0) memset(s->dout[k], 0, sizeof(float) * 3 * (size_t)(P >> k) * (P >> k));
    }
    /* remodulation: dL/dm = dL/d colour x out0 (its kernel's logits), dL/d out0 = dL/d colour x m */
    if (net->remod) {
        const ew_kpcn_tensor dl = planes_t(&s->dbuf[0], net->head[0]);
        for (int y = 0; y < P; y++)
            for (int x = 0; x < P; x++) {
                const long q = (long)y * P + x;
                const float gm[3] = {s->dout[0][q] * s->out[0][q], s->dout[0][np + q] * s->out[0][np + q],
                                     s->dout[0][2 * np + q] * s->out[0][2 * np + q]};
                ew_kpcn_remod_backward_px(x, y, &ra, gm, &dl);
            }
    }
    for (long i = 0; i < 3 * np; i++) s->dout[0][i] *= s->m[i];
    /* filters, fine to coarse */
    for (int k = 0; k < S; k++) {
        ew_kpcn_filter_args a = filter_args(net, s, k);
        const int Pk = P >> k;
        const long nk = (long)Pk * Pk;
        const ew_kpcn_tensor dl = planes_t(&s->dbuf[k], net->head[k]);
        ew_kpcn_tensor dc = {NULL, 1, 0, 0};
        if (k + 1 < S) dc = flat_t(s->dout[k + 1], Pk / 2, Pk / 2);
        for (int y = 0; y < Pk; y++)
            for (int x = 0; x < Pk; x++) {
                const long q = (long)y * Pk + x;
                const float g[3] = {s->dout[k][q], s->dout[k][nk + q], s->dout[k][2 * nk + q]};
                ew_kpcn_filter_backward_px(x, y, &a, g, &dl, NULL, &dc);
            }
    }
    /* network, last layer first */
    for (int k = 0; k < S - 1; k++) {
        conv_bwd(m, net->lhead[k], s->buf, s->dbuf, grad);
        conv_bwd(m, net->dec[k], s->buf, s->dbuf, grad);
        up_planes_bwd(&s->dbuf[k + 1], k + 1 == S - 1 ? net->hb : net->d[k + 1], &s->dbuf[k], net->u[k], C);
    }
    conv_bwd(m, net->lhead[S - 1], s->buf, s->dbuf, grad);
    conv_bwd(m, net->enc_b, s->buf, s->dbuf, grad);
    conv_bwd(m, net->enc_a, s->buf, s->dbuf, grad);
    for (int k = S - 1; k >= 1; k--) {
        pool_planes_bwd(&s->dbuf[k - 1], net->h[k - 1], &s->dbuf[k], net->in[k], C);
        conv_bwd(m, net->enc[k - 1], s->buf, s->dbuf, grad);
    }
    return value;
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
    if (size < 16 || size % ew_kpcn_align(net) != 0) return NULL;
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
