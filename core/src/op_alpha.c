/*
 * op_alpha.c — premultiplied alpha through the filters. A colour view of 4
 * channels is RGBA with colour premultiplied by alpha; a blur that filtered
 * RGB and copied A would leave colour where alpha is 0 (R > A: no longer
 * valid premultiplied colour). A method with filters_alpha runs a second
 * time, on the alpha alone, with the same images, parameters and data, so
 * alpha is blurred with the weights the colour got, and a non-finite alpha
 * is rebuilt from its neighbours like a non-finite colour sample.
 *
 * The weights are the same in both runs when they come from the guide
 * images (guide, normal, depth: the colour's guide is given explicitly to
 * the alpha's run by the method's alpha_guides) and not from the filtered
 * values themselves; a method whose weights read the filtered values (the
 * a-trous luminance term) blurs alpha with weights of its own.
 *
 * The alpha's run goes first, into a buffer of its own: the method may then
 * filter the colour in place, and the alpha lands in the output after it.
 * Images in device memory (ew_device_desc.device_images) keep alpha as the
 * method leaves it: the copy below is a host loop.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "src/backend.h"
#include "src/op.h"

void ew_op_alpha_release(ew_op *op) {
    if (!op->alpha_op) return;
    op->alpha_op->data_state = NULL; /* the parent's, freed with it */
    ew_op_destroy(op->alpha_op);
    op->alpha_op = NULL;
    free(op->alpha_out);
    op->alpha_out = NULL;
}

static int is_extra_output(const ew_op_type *t, const char *name) {
    for (int i = 0; t->extra_outputs && t->extra_outputs[i]; i++)
        if (!strcmp(t->extra_outputs[i], name)) return 1;
    return 0;
}

ew_result ew_op_alpha_commit(ew_op *op) {
    ew_op_alpha_release(op);
    const ew_op_type *t = op->type;
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    if (!t->filters_alpha || !color || !output || color->channels != 4 || output->channels < 4 ||
        op->dev->device_images)
        return EW_OK;
    const int w = color->width, h = color->height;
    ew_op *a = NULL;
    ew_result r = ew_op_create_kind(op->dev, t->kind, t->name, &a);
    if (r != EW_OK) return r;
    op->alpha_op = a;
    memcpy(a->params, op->params, sizeof a->params);
    a->data_state = op->data_state; /* a weights table given as data */
    for (int i = 0; i < t->num_images; i++) {
        const char *name = t->images[i].name;
        if (!op->has_image[i] || !strcmp(name, "color") || !strcmp(name, "output") || is_extra_output(t, name))
            continue;
        a->images[i] = a->given[i] = op->images[i]; /* a half input: the float copy the op packs */
        a->has_image[i] = 1;
    }
    if (!(op->alpha_out = (float *)malloc((size_t)w * (size_t)h * sizeof(float)))) {
        ew_op_alpha_release(op);
        return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory for the alpha of a %dx%d image", w, h);
    }
    /* the colour's 4th channel as a 1-channel view of the same pixels */
    ew_image alpha = *color;
    alpha.data = (char *)color->data + 3 * sizeof(float);
    alpha.channels = 1;
    alpha.pixel_stride = ew__pixel_stride(color);
    alpha.row_stride = ew__row_stride(color);
    ew_image out = ew_image_packed(op->alpha_out, w, h, 1);
    r = ew_op_set_image(a, "color", &alpha);
    if (r == EW_OK) r = ew_op_set_image(a, "output", &out);
    if (r == EW_OK && t->alpha_guides) t->alpha_guides(op, a);
    if (r == EW_OK) r = ew_op_commit(a);
    if (r != EW_OK) ew_op_alpha_release(op);
    return r;
}

/* Whether the colour's alpha is one finite value everywhere (the same
 * bits), as a render's is without a transparent film. */
static int alpha_is_uniform(const ew_image *color, float *value) {
    const float a = ew__pixel(color, 0, 0)[3];
    uint32_t bits;
    memcpy(&bits, &a, sizeof bits);
    if (!isfinite(a)) return 0;
    for (int y = 0; y < color->height; y++)
        for (int x = 0; x < color->width; x++) {
            uint32_t b;
            memcpy(&b, &ew__pixel(color, x, y)[3], sizeof b);
            if (b != bits) return 0;
        }
    *value = a;
    return 1;
}

/* A uniform alpha is not filtered: a normalised filter of a constant is
 * that constant. The filters give exactly it for 0, 0.5 and 1 and within a
 * few ulp for other values (their weights' sums rounded twice); the value
 * itself is the exact result. The alpha run's frame-sized scratch then is
 * never touched, so it costs no memory beside the colour's. */
ew_result ew_op_alpha_execute(ew_op *op) {
    op->alpha_uniform = 0;
    if (!op->alpha_op) return EW_OK;
    if (alpha_is_uniform(ew_op_image(op, "color"), &op->alpha_value)) {
        op->alpha_uniform = 1;
        return EW_OK;
    }
    return ew_op_execute(op->alpha_op);
}

void ew_op_alpha_store(ew_op *op) {
    if (!op->alpha_op) return;
    const ew_image *output = ew_op_image(op, "output");
    const int w = output->width;
    for (int y = 0; y < output->height; y++)
        for (int x = 0; x < w; x++)
            ew__pixel(output, x, y)[3] =
                op->alpha_uniform ? op->alpha_value : op->alpha_out[(size_t)y * (size_t)w + (size_t)x];
}

/* A denoiser reads RGB: a colour's alpha passes through to an output of
 * four channels (or more) as it is, where the output does not overlap the
 * colour (written in place, the alpha is already there). A caller handing
 * RGBA buffers gets the alpha it gave, not what its output held. */
void ew_op_alpha_pass(ew_op *op) {
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    if (strcmp(op->type->kind, "denoiser") || op->type->filters_alpha || !color || !output || color->channels != 4 ||
        output->channels < 4 || op->dev->device_images || ew_images_overlap(color, output))
        return;
    for (int y = 0; y < output->height; y++)
        for (int x = 0; x < output->width; x++) ew__pixel(output, x, y)[3] = ew__pixel(color, x, y)[3];
}
