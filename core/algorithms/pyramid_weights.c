/*
 * pyramid_weights.c — the trained-weights file of the pyramid filter:
 * parse + validate, write, and the table built into the library.
 *
 * Format (all integers u32 little-endian, floats IEEE-754 f32 little-endian):
 *   "EWPYRWTS"                 8-byte magic
 *   version                    1
 *   arch_len, arch             the architecture string, must equal EW_PYR_ARCH
 *   ntensors                   2
 *   per tensor: name_len, name, ndim, dims[ndim], data (prod(dims) floats)
 *     "log2_sigma"  [nodes]                  ascending, within the table range
 *     "params"      [nodes, levels, 19]      wf[9], wc[9], gamma (pyramid.h)
 *   crc32                      CRC-32 (IEEE, as zlib) of every byte before it
 * Validation also checks that every value is finite, the domain weights are
 * in [0, 1], gamma in [0, 8], and Eq. 2g: wf[4] = 1 - the other domain
 * weights (within 1e-4).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "algorithms/pyramid.h"
#include "src/weights.h"

#define MAGIC "EWPYRWTS"
#define VERSION 1u

typedef struct {
    const unsigned char *p;
    size_t size, at;
    int ok;
} reader;

static uint32_t rd_u32(reader *r) {
    if (!r->ok || r->size - r->at < 4) {
        r->ok = 0;
        return 0;
    }
    const unsigned char *b = r->p + r->at;
    r->at += 4;
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static float rd_f32(reader *r) {
    uint32_t u = rd_u32(r);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static const unsigned char *rd_bytes(reader *r, size_t n) {
    if (!r->ok || r->size - r->at < n) {
        r->ok = 0;
        return NULL;
    }
    const unsigned char *b = r->p + r->at;
    r->at += n;
    return b;
}

static ew_result bad(char *why, size_t len, const char *msg) {
    if (why && len) snprintf(why, len, "%s", msg);
    return EW_ERR_INVALID_DATA;
}

/* Read a tensor header: name must match, ndim and dims are returned. */
static int rd_tensor(reader *r, const char *name, uint32_t *ndim, uint32_t dims[4]) {
    uint32_t nl = rd_u32(r);
    if (nl > 64) return 0;
    const unsigned char *nm = rd_bytes(r, nl);
    if (!nm || nl != strlen(name) || memcmp(nm, name, nl) != 0) return 0;
    *ndim = rd_u32(r);
    if (*ndim < 1 || *ndim > 4) return 0;
    for (uint32_t i = 0; i < *ndim; i++) dims[i] = rd_u32(r);
    return r->ok;
}

ew_result ew_pyr_table_parse(const void *data, size_t size, ew_pyr_table *out, char *why, size_t whylen) {
    char msg[160];
    if (!data || !out) return bad(why, whylen, "no data");
    const unsigned char *p = (const unsigned char *)data;
    if (size < 8 + 4 + 4 || memcmp(p, MAGIC, 8) != 0) return bad(why, whylen, "not a pyramid weights file (bad magic)");
    if (size < 4 + 8 + 4) return bad(why, whylen, "truncated");
    uint32_t stored = (uint32_t)p[size - 4] | (uint32_t)p[size - 3] << 8 | (uint32_t)p[size - 2] << 16 |
                      (uint32_t)p[size - 1] << 24;
    reader r = {p, size - 4, 8, 1};
    uint32_t version = rd_u32(&r);
    if (r.ok && version != VERSION) {
        snprintf(msg, sizeof msg, "unsupported weights version %u (this library reads %u)", version, VERSION);
        return bad(why, whylen, msg);
    }
    if (ew_crc32(p, size - 4) != stored) return bad(why, whylen, "checksum mismatch (corrupted file)");
    uint32_t al = rd_u32(&r);
    const unsigned char *arch = al < 4096 ? rd_bytes(&r, al) : NULL;
    if (!arch) return bad(why, whylen, "truncated architecture string");
    if (al != strlen(EW_PYR_ARCH) || memcmp(arch, EW_PYR_ARCH, al) != 0)
        return bad(why, whylen, "architecture string differs from this library's (weights for another model)");
    if (rd_u32(&r) != 2) return bad(why, whylen, "expected 2 tensors");
    uint32_t nd, dims[4];
    if (!rd_tensor(&r, "log2_sigma", &nd, dims) || nd != 1) return bad(why, whylen, "bad tensor 'log2_sigma'");
    const uint32_t nodes = dims[0];
    if (nodes < 1 || nodes > EW_PYR_MAX_NODES) return bad(why, whylen, "bad number of sigma nodes");
    memset(out, 0, sizeof *out);
    out->nodes = (int)nodes;
    for (uint32_t i = 0; i < nodes; i++) out->log2_sigma[i] = rd_f32(&r);
    if (!rd_tensor(&r, "params", &nd, dims) || nd != 3 || dims[0] != nodes || dims[2] != EW_PYR_NPARAM)
        return bad(why, whylen, "bad tensor 'params' (expected [nodes, levels, 19])");
    if (dims[1] < 1 || dims[1] > EW_PYR_MAX_LEVELS) return bad(why, whylen, "bad number of levels");
    out->levels = (int)dims[1];
    for (uint32_t i = 0; i < nodes; i++)
        for (uint32_t l = 0; l < dims[1]; l++) {
            float *f = (float *)&out->p[i][l];
            for (int k = 0; k < EW_PYR_NPARAM; k++) f[k] = rd_f32(&r);
        }
    if (!r.ok) return bad(why, whylen, "truncated");
    if (r.at != size - 4) return bad(why, whylen, "trailing bytes before the checksum");
    for (int i = 0; i < out->nodes; i++) {
        float ls = out->log2_sigma[i];
        if (!isfinite(ls) || ls <= (float)EW_PYR_LUT_LOG2_MIN || ls > 9.0f ||
            (i > 0 && !(ls > out->log2_sigma[i - 1])))
            return bad(why, whylen, "sigma nodes not ascending within the table's range");
        for (int l = 0; l < out->levels; l++) {
            const ew_pyr_params *q = &out->p[i][l];
            for (int k = 0; k < 9; k++)
                if (!isfinite(q->wf[k]) || !isfinite(q->wc[k]) || q->wf[k] < 0.0f || q->wf[k] > 1.0f ||
                    q->wc[k] < 0.0f || q->wc[k] > 1.0f) {
                    snprintf(msg, sizeof msg, "node %d level %d: a domain weight is outside [0, 1]", i, l);
                    return bad(why, whylen, msg);
                }
            if (!isfinite(q->gamma) || q->gamma < 0.0f || q->gamma > 8.0f) {
                snprintf(msg, sizeof msg, "node %d level %d: gamma outside [0, 8]", i, l);
                return bad(why, whylen, msg);
            }
            if (fabsf(ew_pyr_centre_weight(q) - q->wf[4]) > 1e-4f) {
                snprintf(msg, sizeof msg, "node %d level %d: weights violate Eq. 2g (sum %.6f, not 1)", i, l,
                         (double)(1.0f - ew_pyr_centre_weight(q) + q->wf[4]));
                return bad(why, whylen, msg);
            }
        }
    }
    if (why && whylen) why[0] = '\0';
    return EW_OK;
}

typedef struct {
    unsigned char *p;
    size_t cap, at;
} writer;

static void wr_u32(writer *w, uint32_t v) {
    if (w->at + 4 <= w->cap) {
        w->p[w->at] = (unsigned char)(v & 255);
        w->p[w->at + 1] = (unsigned char)(v >> 8 & 255);
        w->p[w->at + 2] = (unsigned char)(v >> 16 & 255);
        w->p[w->at + 3] = (unsigned char)(v >> 24 & 255);
    }
    w->at += 4;
}

static void wr_f32(writer *w, float f) {
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    wr_u32(w, u);
}

static void wr_bytes(writer *w, const void *b, size_t n) {
    if (w->at + n <= w->cap) memcpy(w->p + w->at, b, n);
    w->at += n;
}

static void wr_str(writer *w, const char *s) {
    wr_u32(w, (uint32_t)strlen(s));
    wr_bytes(w, s, strlen(s));
}

size_t ew_pyr_table_write(const ew_pyr_table *t, void *buf, size_t cap) {
    writer w = {(unsigned char *)buf, buf ? cap : 0, 0};
    wr_bytes(&w, MAGIC, 8);
    wr_u32(&w, VERSION);
    wr_str(&w, EW_PYR_ARCH);
    wr_u32(&w, 2);
    wr_str(&w, "log2_sigma");
    wr_u32(&w, 1);
    wr_u32(&w, (uint32_t)t->nodes);
    for (int i = 0; i < t->nodes; i++) wr_f32(&w, t->log2_sigma[i]);
    wr_str(&w, "params");
    wr_u32(&w, 3);
    wr_u32(&w, (uint32_t)t->nodes);
    wr_u32(&w, (uint32_t)t->levels);
    wr_u32(&w, EW_PYR_NPARAM);
    for (int i = 0; i < t->nodes; i++)
        for (int l = 0; l < t->levels; l++) {
            ew_pyr_params q = t->p[i][l];
            q.wf[4] = ew_pyr_centre_weight(&q); /* Eq. 2g, exactly as read back */
            const float *f = (const float *)&q;
            for (int k = 0; k < EW_PYR_NPARAM; k++) wr_f32(&w, f[k]);
        }
    size_t body = w.at;
    uint32_t crc = w.at + 4 <= w.cap ? ew_crc32(w.p, body) : 0;
    wr_u32(&w, crc);
    return w.at;
}

/* pyramid_weights_data.c and pyramid_weights_gi_data.c, written by
 * tools/train_pyramid (--model all, --model gi) */
extern const unsigned char ew_pyr_builtin_weights[], ew_pyr_builtin_weights_gi[];
extern const size_t ew_pyr_builtin_weights_size, ew_pyr_builtin_weights_gi_size;

ew_result ew_pyr_builtin_table(int kind, ew_pyr_table *out, char *why, size_t whylen) {
    const int gi = kind == EW_RANGE_GI;
    /* parsed into the caller's table (no global state); ~0.3 ms */
    ew_result r = ew_pyr_table_parse(gi ? ew_pyr_builtin_weights_gi : ew_pyr_builtin_weights,
                                     gi ? ew_pyr_builtin_weights_gi_size : ew_pyr_builtin_weights_size, out, why, whylen);
    if (r != EW_OK && why && whylen) {
        char tmp[200];
        snprintf(tmp, sizeof tmp, "built-in pyramid weights: %s", why);
        snprintf(why, whylen, "%s", tmp);
    }
    return r;
}
