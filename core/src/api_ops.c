/* The older faces of ew_op: ew_denoiser_* and ew_filter_* are the same
 * handle (edgewise.h), so each is one call; only create checks the kind. */
#include "src/op.h"

#include <string.h>

ew_result ew_denoiser_create(ew_device *dev, const char *method, ew_denoiser **out) {
    return ew_op_create_kind(dev, "denoiser", method, out);
}
void ew_denoiser_destroy(ew_denoiser *d) { ew_op_destroy(d); }
ew_result ew_denoiser_set_image(ew_denoiser *d, const char *name, const ew_image *view) {
    return ew_op_set_image(d, name, view);
}
ew_result ew_denoiser_set_int(ew_denoiser *d, const char *name, int32_t value) { return ew_op_set_int(d, name, value); }
ew_result ew_denoiser_set_float(ew_denoiser *d, const char *name, float value) { return ew_op_set_float(d, name, value); }
ew_result ew_denoiser_set_data(ew_denoiser *d, const char *name, const void *data, size_t size) {
    return ew_op_set_data(d, name, data, size);
}
ew_result ew_denoiser_set_progress(ew_denoiser *d, ew_progress_fn fn, void *user) {
    return ew_op_set_progress(d, fn, user);
}
ew_result ew_denoiser_commit(ew_denoiser *d) { return ew_op_commit(d); }
ew_result ew_denoiser_execute(ew_denoiser *d) { return ew_op_execute(d); }
const char *ew_denoiser_describe(const ew_denoiser *d) { return ew_op_describe(d); }

ew_result ew_filter_create(ew_device *dev, const char *type, ew_filter **out) {
    return ew_op_create_kind(dev, "filter", type, out);
}
void ew_filter_destroy(ew_filter *f) { ew_op_destroy(f); }
ew_result ew_filter_set_image(ew_filter *f, const char *name, const ew_image *view) {
    return ew_op_set_image(f, name, view);
}
ew_result ew_filter_set_int(ew_filter *f, const char *name, int32_t value) { return ew_op_set_int(f, name, value); }
ew_result ew_filter_set_float(ew_filter *f, const char *name, float value) { return ew_op_set_float(f, name, value); }
ew_result ew_filter_set_data(ew_filter *f, const char *name, const void *data, size_t size) {
    return ew_op_set_data(f, name, data, size);
}
ew_result ew_filter_set_progress(ew_filter *f, ew_progress_fn fn, void *user) { return ew_op_set_progress(f, fn, user); }
ew_result ew_filter_commit(ew_filter *f) { return ew_op_commit(f); }
ew_result ew_filter_execute(ew_filter *f) { return ew_op_execute(f); }

/* ---- introspection over the registry ---- */
static const ew_op_type *nth(const char *kind, int32_t index) {
    int32_t k = 0;
    for (int i = 0; ew_op_types[i]; i++)
        if ((!kind || !strcmp(ew_op_types[i]->kind, kind)) && k++ == index) return ew_op_types[i];
    return NULL;
}

int32_t ew_method_count(const char *kind) {
    int32_t n = 0;
    while (nth(kind, n)) n++;
    return n;
}

ew_result ew_method_get(const char *kind, int32_t index, const char **name, const char **summary,
                        int32_t *num_images, int32_t *num_params) {
    const ew_op_type *t = nth(kind, index);
    if (!t) return EW_ERR_INVALID_ARGUMENT;
    if (name) *name = t->name;
    if (summary) *summary = t->summary;
    if (num_images) *num_images = t->num_images;
    if (num_params) *num_params = ew_op_type_num_params(t);
    return EW_OK;
}

ew_result ew_method_image(const char *kind, const char *name, int32_t index, ew_image_info *out) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || !out || index < 0 || index >= t->num_images) return EW_ERR_INVALID_ARGUMENT;
    *out = t->images[index];
    return EW_OK;
}

ew_result ew_method_param(const char *kind, const char *name, int32_t index, ew_param_info *out) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || !out || index < 0 || index >= ew_op_type_num_params(t)) return EW_ERR_INVALID_ARGUMENT;
    *out = *ew_op_type_param(t, index);
    return EW_OK;
}

int32_t ew_method_param_is_pixels(const char *kind, const char *name, int32_t index) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || index < 0 || index >= ew_op_type_num_params(t)) return -1;
    for (const char *const *p = t->pixel_params; p && *p; p++)
        if (!strcmp(*p, ew_op_type_param(t, index)->name)) return 1;
    return 0;
}

const char *ew_method_kind(const char *name) {
    const ew_op_type *t = ew_op_type_find(NULL, name);
    return t ? t->kind : NULL;
}

static int listed(const char *const *list, const char *name) {
    for (; list && *list; list++)
        if (!strcmp(*list, name)) return 1;
    return 0;
}

ew_result ew_method_image_flags(const char *kind, const char *name, int32_t index, uint32_t *flags) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || !flags || index < 0 || index >= t->num_images) return EW_ERR_INVALID_ARGUMENT;
    const char *im = t->images[index].name;
    *flags = 0;
    if (!strcmp(im, "output") || listed(t->extra_outputs, im)) *flags |= EW_IMAGE_OUTPUT;
    if (listed(t->inplace_inputs, im)) *flags |= EW_IMAGE_INPLACE;
    if (listed(t->half_inputs, im)) *flags |= EW_IMAGE_HALF_IN_PLACE;
    return EW_OK;
}

static const char *const *choices_of(const ew_op_type *t, int32_t index) {
    for (const ew_param_choices *c = t->choices; c && c->param; c++)
        if (!strcmp(c->param, ew_op_type_param(t, index)->name)) return c->names;
    return NULL;
}

int32_t ew_method_param_num_choices(const char *kind, const char *name, int32_t index) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || index < 0 || index >= ew_op_type_num_params(t)) return -1;
    int32_t n = 0;
    for (const char *const *c = choices_of(t, index); c && c[n];) n++;
    return n;
}

const char *ew_method_param_choice(const char *kind, const char *name, int32_t index, int32_t choice) {
    int32_t n = ew_method_param_num_choices(kind, name, index);
    if (choice < 0 || choice >= n) return NULL;
    return choices_of(ew_op_type_find(kind, name), index)[choice];
}

int32_t ew_method_param_choice_index(const char *kind, const char *name, int32_t index, const char *choice) {
    int32_t n = ew_method_param_num_choices(kind, name, index);
    for (int32_t i = 0; choice && i < n; i++)
        if (!strcmp(ew_method_param_choice(kind, name, index, i), choice)) return i;
    return -1;
}

ew_result ew_method_param_flags(const char *kind, const char *name, int32_t index, uint32_t *flags) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || !flags || index < 0 || index >= ew_op_type_num_params(t)) return EW_ERR_INVALID_ARGUMENT;
    *flags = 0;
    if (listed(t->pixel_params, ew_op_type_param(t, index)->name)) *flags |= EW_PARAM_PIXELS;
    if (listed(t->noop_at_zero, ew_op_type_param(t, index)->name)) *flags |= EW_PARAM_NOOP_AT_ZERO;
    return EW_OK;
}

const char *ew_method_param_data(const char *kind, const char *name, int32_t index) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || index < 0 || index >= ew_op_type_num_params(t)) return NULL;
    for (const char *const *p = t->data_params; p && p[0] && p[1]; p += 2)
        if (!strcmp(p[0], ew_op_type_param(t, index)->name)) return p[1];
    return NULL;
}

ew_result ew_method_flags(const char *kind, const char *name, uint32_t *flags) {
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t || !flags) return EW_ERR_INVALID_ARGUMENT;
    *flags = t->flags;
    return EW_OK;
}

ew_result ew_op_image_flags(const ew_op *op, const char *image, uint32_t *flags) {
    if (!op || !flags) return op ? ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "flags pointer is NULL") : EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    const ew_op_type *t = op->type;
    int32_t i = 0;
    while (i < t->num_images && (!image || strcmp(t->images[i].name, image) != 0)) i++;
    if (i == t->num_images)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "%s '%s' has no image '%s'", t->kind, t->name,
                        image ? image : "(null)");
    if (!op->committed)
        return ew__fail(op->dev, EW_ERR_INVALID_STATE, "image flags asked before a successful commit");
    ew_method_image_flags(t->kind, t->name, i, flags);
    if ((*flags & EW_IMAGE_HALF_IN_PLACE) && t->reads_half && !t->reads_half(op, image)) *flags &= ~EW_IMAGE_HALF_IN_PLACE;
    return EW_OK;
}
