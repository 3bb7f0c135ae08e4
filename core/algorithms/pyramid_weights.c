/*
 * pyramid_weights.c — the pyramid filter's trained table in the weights
 * container (src/weights.h): parse + validate, write, and the table built
 * into the library.
 *
 * Architecture string EW_PYR_ARCH, two tensors:
 *   "log2_sigma"  [nodes]                  ascending, within the table range
 *   "params"      [nodes, levels, 19]      wf[9], wc[9], gamma (pyramid.h)
 * Validation also checks that the domain weights are in [0, 1], gamma in
 * [0, 8], and Eq. 2g: wf[4] = 1 - the other domain weights (within 1e-4).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/pyramid.h"
#include "src/weights.h"

static ew_result bad(char *why, size_t len, const char *msg) {
    if (why && len) snprintf(why, len, "%s", msg);
    return EW_ERR_INVALID_DATA;
}

/* the values of the container w into out, checked */
static ew_result table_from_weights(const ew_weights *w, ew_pyr_table *out, char *why, size_t whylen) {
    char msg[160];
    if (strcmp(w->arch, EW_PYR_ARCH) != 0)
        return bad(why, whylen, "architecture string differs from this library's (weights for another model)");
    if (w->num_tensors != 2) return bad(why, whylen, "expected 2 tensors");
    const ew_tensor *ls = ew_weights_tensor(w, "log2_sigma"), *pt = ew_weights_tensor(w, "params");
    if (!ls || ls->rank != 1) return bad(why, whylen, "bad tensor 'log2_sigma'");
    const uint32_t nodes = ls->dims[0];
    if (nodes < 1 || nodes > EW_PYR_MAX_NODES) return bad(why, whylen, "bad number of sigma nodes");
    if (!pt || pt->rank != 3 || pt->dims[0] != nodes || pt->dims[2] != EW_PYR_NPARAM)
        return bad(why, whylen, "bad tensor 'params' (expected [nodes, levels, 19])");
    const uint32_t levels = pt->dims[1];
    if (levels < 1 || levels > EW_PYR_MAX_LEVELS) return bad(why, whylen, "bad number of levels");
    memset(out, 0, sizeof *out);
    out->nodes = (int)nodes;
    out->levels = (int)levels;
    memcpy(out->log2_sigma, ls->data, sizeof(float) * nodes);
    for (uint32_t i = 0; i < nodes; i++)
        for (uint32_t l = 0; l < levels; l++)
            memcpy(&out->p[i][l], pt->data + ((size_t)i * levels + l) * EW_PYR_NPARAM, sizeof(float) * EW_PYR_NPARAM);
    for (int i = 0; i < out->nodes; i++) {
        float s = out->log2_sigma[i];
        if (s <= (float)EW_PYR_LUT_LOG2_MIN || s > 9.0f || (i > 0 && !(s > out->log2_sigma[i - 1])))
            return bad(why, whylen, "sigma nodes not ascending within the table's range");
        for (int l = 0; l < out->levels; l++) {
            const ew_pyr_params *q = &out->p[i][l];
            for (int k = 0; k < 9; k++)
                if (q->wf[k] < 0.0f || q->wf[k] > 1.0f || q->wc[k] < 0.0f || q->wc[k] > 1.0f) {
                    snprintf(msg, sizeof msg, "node %d level %d: a domain weight is outside [0, 1]", i, l);
                    return bad(why, whylen, msg);
                }
            if (q->gamma < 0.0f || q->gamma > 8.0f) {
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

ew_result ew_pyr_table_parse(const void *data, size_t size, ew_pyr_table *out, char *why, size_t whylen) {
    if (!data || !out) return bad(why, whylen, "no data");
    char err[200], msg[240];
    ew_weights w;
    /* finite values, sizes, checksum: the container's checks */
    if (ew_weights_parse(data, size, &w, err, sizeof err) != 0) {
        snprintf(msg, sizeof msg, "not a pyramid weights file: %s", err);
        return bad(why, whylen, msg);
    }
    const ew_result r = table_from_weights(&w, out, why, whylen);
    ew_weights_free(&w);
    return r;
}

size_t ew_pyr_table_write(const ew_pyr_table *t, void *buf, size_t cap) {
    const size_t np = (size_t)t->nodes * (size_t)t->levels * EW_PYR_NPARAM;
    float *params = (float *)malloc(sizeof(float) * (np + (size_t)t->nodes + 1)), *log2_sigma = params + np;
    if (!params) return 0;
    memcpy(log2_sigma, t->log2_sigma, sizeof(float) * (size_t)t->nodes);
    for (int i = 0; i < t->nodes; i++)
        for (int l = 0; l < t->levels; l++) {
            ew_pyr_params q = t->p[i][l];
            q.wf[4] = ew_pyr_centre_weight(&q); /* Eq. 2g, exactly as read back */
            memcpy(params + ((size_t)i * (size_t)t->levels + (size_t)l) * EW_PYR_NPARAM, &q, sizeof(float) * EW_PYR_NPARAM);
        }
    ew_tensor tensors[2];
    memset(tensors, 0, sizeof tensors);
    snprintf(tensors[0].name, sizeof tensors[0].name, "log2_sigma");
    tensors[0].rank = 1;
    tensors[0].dims[0] = (uint32_t)t->nodes;
    tensors[0].count = (size_t)t->nodes;
    tensors[0].data = log2_sigma;
    snprintf(tensors[1].name, sizeof tensors[1].name, "params");
    tensors[1].rank = 3;
    tensors[1].dims[0] = (uint32_t)t->nodes;
    tensors[1].dims[1] = (uint32_t)t->levels;
    tensors[1].dims[2] = EW_PYR_NPARAM;
    tensors[1].count = np;
    tensors[1].data = params;
    ew_weights w;
    memset(&w, 0, sizeof w);
    snprintf(w.arch, sizeof w.arch, "%s", EW_PYR_ARCH);
    w.num_tensors = 2;
    w.tensors = tensors;
    const size_t n = ew_weights_write(&w, buf, buf ? cap : 0);
    free(params);
    return n;
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
