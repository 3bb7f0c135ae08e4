/*
 * filter "gain": the example of docs/adding-a-method.md, built only into
 * the test library of tests/gain (libedgewise with one method more). Its
 * descriptor is the whole interface: the fronts (CLI, nodes, Python, OFX)
 * list it, its parameters and its choice names without an edit.
 */
#include <stdlib.h>

#include "gain_px.h"
#include "src/op.h"

static const ew_image_desc images[] = {
    {"color", 1, 1, "image to scale (1 to 4 channels)"},
    {"output", 1, 1, "scaled image, as many channels as the colour; may be the colour view itself"},
};

static const ew_param_desc params[] = {
    {"gain", EW_PARAM_FLOAT, 1.0f, 0.0f, 100.0f, "factor every channel is multiplied by"},
    {"alpha", EW_PARAM_INT, 0.0f, 0.0f, 1.0f, "scale: the 4th channel too, or keep it"},
};

typedef struct {
    int w, h, c;
    float *in, *out;
} state;

static void release(ew_op *op) {
    free(op->state);
    op->state = NULL;
}

static ew_result commit(ew_op *op) {
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    if (output->channels < color->channels)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image 'output' has %d channels but 'color' has %d",
                        output->channels, color->channels);
    const size_t n = (size_t)color->width * (size_t)color->height * (size_t)color->channels;
    release(op);
    state *s = (state *)malloc(sizeof *s + 2 * n * sizeof(float));
    if (!s) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
    s->w = color->width;
    s->h = color->height;
    s->c = color->channels;
    s->in = (float *)(void *)(s + 1);
    s->out = s->in + n;
    op->state = s;
    return EW_OK;
}

/* The colour is packed whole before the output is written, so the output
 * may be the colour view (inplace_inputs). */
static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_view_pack(ew_op_image(op, "color"), s->c, s->in);
    const float gain = ew_op_param(op, "gain");
    const int keep_alpha = ew_op_param(op, "alpha") == 1.0f;
    for (long i = 0; i < (long)s->w * s->h; i++) ew_gain_px(i, s->c, gain, keep_alpha, s->in, s->out);
    ew_view_unpack(s->out, s->c, ew_op_image(op, "output"));
    return EW_OK;
}

const ew_op_type ew_filter_gain = {
    .kind = "filter",
    .name = "gain",
    .summary = "multiplies the colour by a factor (the example of docs/adding-a-method.md)",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .choices = (const ew_param_choices[]){{"alpha", (const char *const[]){"scale", "keep", NULL}}, {NULL, NULL}},
    .inplace_inputs = (const char *const[]){"color", NULL},
    .noop_at_zero = NULL,
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_filter_gain, 120);
