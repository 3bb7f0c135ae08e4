#include "src/op_model.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/weights.h"

void ew_net_model_free(ew_net_model *m) {
    if (m) {
        free(m->params);
        free(m->net);
    }
    free(m);
}

static ew_result parse(ew_device *dev, const ew_net_kind *k, const void *bytes, size_t size, const char *what,
                       ew_net_model **out) {
    *out = NULL;
    ew_weights w;
    char err[256];
    if (ew_weights_parse(bytes, size, &w, err, sizeof err) != 0)
        return ew__fail(dev, EW_ERR_INVALID_DATA, "%s: %s", what, err);
    ew_net_model *m = (ew_net_model *)calloc(1, sizeof *m);
    if (m) m->net = calloc(1, k->net_size);
    if (!m || !m->net) {
        ew_net_model_free(m);
        ew_weights_free(&w);
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory loading %s", what);
    }
    int bad = k->from_weights(m->net, &w, &m->params, err, sizeof err);
    ew_weights_free(&w);
    if (bad) {
        ew_net_model_free(m);
        return ew__fail(dev, EW_ERR_INVALID_DATA, "%s: %s", what, err);
    }
    *out = m;
    return EW_OK;
}

ew_result ew_net_model_set_data(ew_op *op, const ew_net_kind *k, const char *name, const void *data, size_t size) {
    if (strcmp(name, "weights") != 0)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "denoiser '%s' takes data 'weights', not '%s'", k->method,
                        name);
    ew_net_model *m = NULL;
    if (data) {
        ew_result r = parse(op->dev, k, data, size, "weights", &m);
        if (r != EW_OK) return r;
    }
    ew_net_model_free((ew_net_model *)op->data_state);
    op->data_state = m;
    return EW_OK;
}

void ew_net_model_release(ew_op *op) {
    ew_net_model_free((ew_net_model *)op->data_state);
    op->data_state = NULL;
}

ew_result ew_net_model_of(const ew_op *op, const ew_net_kind *k, const ew_net_model **out, ew_net_model **builtin) {
    *builtin = NULL;
    *out = (const ew_net_model *)op->data_state;
    if (*out) return EW_OK;
    const int which = (int)ew_op_param(op, "model");
    const unsigned char *bytes;
    size_t size;
    k->builtin(which, &bytes, &size);
    if (size == 0)
        return ew__fail(op->dev, EW_ERR_UNSUPPORTED,
                        "this build has no built-in weights for %s model %d (%s): load a weights file with "
                        "ew_denoiser_set_data(\"weights\") (CLI: --model PATH)",
                        k->method, which, k->model_name(which));
    char what[64];
    snprintf(what, sizeof what, "built-in %s model '%s'", k->method, k->model_name(which));
    ew_result r = parse(op->dev, k, bytes, size, what, builtin);
    if (r != EW_OK) return r;
    *out = *builtin;
    return EW_OK;
}
