/*
 * op_model.h — the weights of a network op (nbg, kpcn): the file given with
 * set_data("weights"), else the built-in model its "model" parameter names,
 * parsed on the host into the network's description and its packed
 * parameters. The ops differ only in their network, which they name with
 * an ew_net_kind.
 */
#ifndef EW_OP_MODEL_H
#define EW_OP_MODEL_H

#include "src/op.h"

typedef struct ew_weights ew_weights;

typedef struct ew_net_kind {
    const char *method; /* "nbg": in messages */
    size_t net_size;    /* bytes of its network description */
    /* its ew_*_from_weights, net being that description: non-zero with
     * err filled when the weights do not describe such a network */
    int (*from_weights)(void *net, const ew_weights *w, float **params, char *err, size_t errlen);
    /* the built-in weights of a model (size 0 when this build has none) and its name */
    void (*builtin)(int which, const unsigned char **bytes, size_t *size);
    const char *(*model_name)(int which);
} ew_net_kind;

typedef struct ew_net_model {
    void *net;      /* the kind's network description */
    float *params;  /* host */
} ew_net_model;

void ew_net_model_free(ew_net_model *m);
/* The op's set_data: "weights" parsed into op->data_state (NULL data: back
 * to the built-in models); EW_ERR_INVALID_DATA naming the problem. */
ew_result ew_net_model_set_data(ew_op *op, const ew_net_kind *k, const char *name, const void *data, size_t size);
/* The op's release_data. */
void ew_net_model_release(ew_op *op);
/* The model a commit runs: the weights given as data, else the built-in
 * one the "model" parameter names (parsed into *builtin, the caller's to
 * free with ew_net_model_free). */
ew_result ew_net_model_of(const ew_op *op, const ew_net_kind *k, const ew_net_model **out, ew_net_model **builtin);

#endif
