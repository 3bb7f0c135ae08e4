#include "algorithms/guidenet.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void add_layer(ew_guidenet *net, int cin, int cout, int in_plane, int out_plane, int act) {
    ew_gn_layer *L = &net->layers[net->nlayers++];
    L->cin = cin;
    L->cout = cout;
    L->in_plane = in_plane;
    L->out_plane = out_plane;
    L->act = act;
    L->w_off = net->nparams;
    net->nparams += (size_t)cin * cout * 25;
    L->b_off = net->nparams;
    net->nparams += (size_t)cout;
}

int ew_guidenet_init(ew_guidenet *net, const char *arch, char *err, size_t errlen) {
    memset(net, 0, sizeof *net);
    int depth = 0, grids = 0;
    if (arch && !strcmp(arch, "2layer-1grid")) depth = 2, grids = 1;
    else if (arch && !strcmp(arch, "2layer-3grid")) depth = 2, grids = 3;
    else if (arch && !strcmp(arch, "7layer-1grid")) depth = 7, grids = 1;
    else if (arch && !strcmp(arch, "7layer-3grid")) depth = 7, grids = 3;
    else {
        snprintf(err, errlen, "unknown GuideNet architecture '%s' (2layer-1grid, 2layer-3grid, 7layer-1grid, 7layer-3grid)",
                 arch ? arch : "(null)");
        return 1;
    }
    snprintf(net->arch, sizeof net->arch, "%s", arch);
    net->ngrids = grids;
    net->nout = grids == 3 ? 5 : 1;
    if (grids == 3) {
        for (int s = 0; s < 3; s++) net->rate_s[s] = net->rate_d[s] = (float)(4 << s);
    } else {
        net->rate_s[0] = net->rate_d[0] = 8.0f;
    }
    add_layer(net, EW_GN_INPUTS, 20, 0, EW_GN_INPUTS, EW_ACT_LEAKY);
    int planes = EW_GN_INPUTS + 20;
    if (depth == 7)
        for (int k = 0; k < 5; k++) {
            add_layer(net, planes - EW_GN_INPUTS, 5, EW_GN_INPUTS, planes, EW_ACT_LEAKY);
            planes += 5;
        }
    add_layer(net, planes - EW_GN_INPUTS, net->nout, EW_GN_INPUTS, -1, EW_ACT_SIGMOID);
    net->nfeat = planes;
    return 0;
}

/* splitmix64: a tiny, well-mixed generator; the weights are a pure
 * function of the seed on every platform. */
static uint64_t splitmix64(uint64_t *s) {
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static float uniform_pm1(uint64_t *s) { return (float)((double)(splitmix64(s) >> 11) * (2.0 / 9007199254740992.0) - 1.0); }

void ew_guidenet_random(const ew_guidenet *net, uint64_t seed, float *params) {
    uint64_t s = seed * 0x2545F4914F6CDD1Dull + 1;
    memset(params, 0, net->nparams * sizeof(float));
    for (int l = 0; l < net->nlayers; l++) {
        const ew_gn_layer *L = &net->layers[l];
        double fan_in = (double)L->cin * 25.0;
        /* Kaiming-uniform for LeakyReLU(0.2): bound = sqrt(6 / ((1 + a^2) fan_in)).
         * The sigmoid layer starts 10x smaller so the guides begin near the
         * middle of the range with room to move both ways. */
        double bound = sqrt(6.0 / ((1.0 + (double)EW_LEAKY_SLOPE * EW_LEAKY_SLOPE) * fan_in));
        if (L->act == EW_ACT_SIGMOID) bound *= 0.1;
        float *w = params + L->w_off;
        for (size_t i = 0; i < (size_t)L->cin * L->cout * 25; i++) w[i] = (float)(bound * uniform_pm1(&s));
    }
}

double ew_guidenet_macs_per_pixel(const ew_guidenet *net) {
    double m = 0;
    for (int l = 0; l < net->nlayers; l++) m += 25.0 * net->layers[l].cin * net->layers[l].cout;
    return m;
}

int ew_guidenet_from_weights(ew_guidenet *net, const ew_weights *w, float **params, char *err, size_t errlen) {
    *params = NULL;
    if (strncmp(w->arch, "nbg-", 4) != 0) {
        snprintf(err, errlen, "weights are for '%s', not a neural bilateral grid (expected 'nbg-<arch>')", w->arch);
        return 1;
    }
    if (ew_guidenet_init(net, w->arch + 4, err, errlen) != 0) return 1;
    float *p = (float *)malloc(net->nparams * sizeof(float));
    if (!p) {
        snprintf(err, errlen, "out of memory for %zu GuideNet parameters", net->nparams);
        return 1;
    }
    for (int l = 0; l < net->nlayers; l++) {
        const ew_gn_layer *L = &net->layers[l];
        if (ew_weights_get_conv(w, l, L->cin, L->cout, p, L->w_off, L->b_off, err, errlen) != 0) goto fail;
    }
    uint32_t rd[2] = {(uint32_t)net->ngrids, 2};
    const ew_tensor *rates = ew_weights_find(w, "grid.rates", 2, rd, err, errlen);
    if (!rates) goto fail;
    for (int s = 0; s < net->ngrids; s++) {
        float rs = rates->data[2 * s], rdv = rates->data[2 * s + 1];
        if (!(rs >= 1.0f && rs <= 256.0f && rdv >= 1.0f && rdv <= 256.0f)) {
            snprintf(err, errlen, "weights '%s': grid %d has rates (%g, %g) outside [1, 256]", w->arch, s, (double)rs,
                     (double)rdv);
            goto fail;
        }
        net->rate_s[s] = rs;
        net->rate_d[s] = rdv;
    }
    *params = p;
    return 0;
fail:
    free(p);
    return 1;
}

int ew_guidenet_save(const ew_guidenet *net, const float *params, void **out, size_t *size) {
    ew_tensor t[2 * EW_GN_MAX_LAYERS + 1];
    float rates[2 * EW_GN_MAX_GRIDS];
    memset(t, 0, sizeof t);
    int n = 0;
    for (int l = 0; l < net->nlayers; l++, n += 2) {
        const ew_gn_layer *L = &net->layers[l];
        ew_weights_put_conv(&t[n], l, L->cin, L->cout, params, L->w_off, L->b_off);
    }
    for (int s = 0; s < net->ngrids; s++) {
        rates[2 * s] = net->rate_s[s];
        rates[2 * s + 1] = net->rate_d[s];
    }
    snprintf(t[n].name, sizeof t[n].name, "grid.rates");
    t[n].rank = 2;
    t[n].dims[0] = (uint32_t)net->ngrids;
    t[n].dims[1] = 2;
    t[n].count = (size_t)net->ngrids * 2;
    t[n].data = rates;
    n++;
    ew_weights w;
    memset(&w, 0, sizeof w);
    snprintf(w.arch, sizeof w.arch, "nbg-%s", net->arch);
    w.num_tensors = (uint32_t)n;
    w.tensors = t;
    return ew_weights_serialize(&w, out, size);
}

/* ---- plane buffers ---------------------------------------------------- */
static long planes_rs(int width) { return ((long)width + 8 + 26 + 7) / 8 * 8; }

size_t ew_gn_planes_floats(int width, int rows, int nplanes) {
    return (size_t)nplanes * (size_t)(rows + 2 * EW_CONV_R) * (size_t)planes_rs(width) + 8;
}

void ew_gn_planes_init(ew_gn_planes *p, float *mem, int width, int rows, int nplanes) {
    memset(mem, 0, ew_gn_planes_floats(width, rows, nplanes) * sizeof(float));
    ew_gn_planes_layout(p, mem, width, rows, nplanes);
}

void ew_gn_planes_layout(ew_gn_planes *p, float *mem, int width, int rows, int nplanes) {
    p->width = width;
    p->rows = rows;
    p->nplanes = nplanes;
    p->rs = planes_rs(width);
    p->ps = (long)(rows + 2 * EW_CONV_R) * p->rs;
    /* align x = 0 to 32 bytes when mem is 4-byte aligned: skip up to 7 floats */
    float *base = mem;
    while (((uintptr_t)(base + 8) & 31u) != 0 && base < mem + 7) base++;
    p->data = base + 2L * p->rs + 8;
}

void ew_guidenet_layer_args(const ew_guidenet *net, int l, const float *params, const ew_gn_planes *feat, int r0,
                            int rows, float *final_out, long final_rs, long final_ps, ew_conv_args *a) {
    const ew_gn_layer *L = &net->layers[l];
    memset(a, 0, sizeof *a);
    a->width = feat->width;
    a->rows = rows;
    a->cin = L->cin;
    a->cout = L->cout;
    a->in = ew_gn_plane_row(feat, L->in_plane, r0);
    a->in_rs = feat->rs;
    a->in_ps = feat->ps;
    if (L->out_plane < 0) {
        a->out = final_out;
        a->out_rs = final_rs;
        a->out_ps = final_ps;
    } else {
        a->out = ew_gn_plane_row(feat, L->out_plane, r0);
        a->out_rs = feat->rs;
        a->out_ps = feat->ps;
    }
    a->weight = params + L->w_off;
    a->bias = params + L->b_off;
    a->act = L->act;
    a->accumulate = 0;
}
