/* The public faces of ew_op: ew_denoiser_* (and ew_filter_*). */
#include "src/op.h"

#include <string.h>

struct ew_denoiser { ew_op op; };

ew_result ew_denoiser_create(ew_device *dev, const char *method, ew_denoiser **out) {
    return ew_op_create(dev, "denoiser", method, (ew_op **)out);
}
void ew_denoiser_destroy(ew_denoiser *d) { ew_op_destroy((ew_op *)d); }
ew_result ew_denoiser_set_image(ew_denoiser *d, const char *name, const ew_image *view) {
    return ew_op_set_image((ew_op *)d, name, view);
}
ew_result ew_denoiser_set_int(ew_denoiser *d, const char *name, int32_t value) {
    return ew_op_set_param((ew_op *)d, name, (float)value, 1);
}
ew_result ew_denoiser_set_float(ew_denoiser *d, const char *name, float value) {
    return ew_op_set_param((ew_op *)d, name, value, 0);
}
ew_result ew_denoiser_set_data(ew_denoiser *d, const char *name, const void *data, size_t size) {
    return ew_op_set_data((ew_op *)d, name, data, size);
}
ew_result ew_denoiser_set_progress(ew_denoiser *d, ew_progress_fn fn, void *user) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    d->op.progress = fn;
    d->op.progress_user = user;
    return EW_OK;
}
ew_result ew_denoiser_commit(ew_denoiser *d) { return ew_op_commit((ew_op *)d); }
ew_result ew_denoiser_execute(ew_denoiser *d) { return ew_op_execute((ew_op *)d); }
const char *ew_denoiser_describe(const ew_denoiser *d) {
    const ew_op *op = (const ew_op *)d;
    if (!op || !op->committed) return NULL;
    const char *s = op->type->describe ? op->type->describe(op) : NULL;
    return s ? s : op->type->name;
}

struct ew_filter { ew_op op; };

ew_result ew_filter_create(ew_device *dev, const char *type, ew_filter **out) {
    return ew_op_create(dev, "filter", type, (ew_op **)out);
}
void ew_filter_destroy(ew_filter *f) { ew_op_destroy((ew_op *)f); }
ew_result ew_filter_set_image(ew_filter *f, const char *name, const ew_image *view) {
    return ew_op_set_image((ew_op *)f, name, view);
}
ew_result ew_filter_set_int(ew_filter *f, const char *name, int32_t value) {
    return ew_op_set_param((ew_op *)f, name, (float)value, 1);
}
ew_result ew_filter_set_float(ew_filter *f, const char *name, float value) {
    return ew_op_set_param((ew_op *)f, name, value, 0);
}
ew_result ew_filter_set_data(ew_filter *f, const char *name, const void *data, size_t size) {
    return ew_op_set_data((ew_op *)f, name, data, size);
}
ew_result ew_filter_set_progress(ew_filter *f, ew_progress_fn fn, void *user) {
    if (!f) return EW_ERR_INVALID_ARGUMENT;
    f->op.progress = fn;
    f->op.progress_user = user;
    return EW_OK;
}
ew_result ew_filter_commit(ew_filter *f) { return ew_op_commit((ew_op *)f); }
ew_result ew_filter_execute(ew_filter *f) { return ew_op_execute((ew_op *)f); }

/* ---- introspection over the registry ---- */
static const ew_op_type *nth(const char *kind, int32_t index) {
    int32_t k = 0;
    for (int i = 0; kind && ew_op_types[i]; i++)
        if (!strcmp(ew_op_types[i]->kind, kind) && k++ == index) return ew_op_types[i];
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
    if (num_params) *num_params = t->num_params;
    return EW_OK;
}

ew_result ew_method_image(const char *kind, const char *name, int32_t index, ew_image_info *out) {
    const ew_op_type *t = kind && name ? ew_op_type_find(kind, name) : NULL;
    if (!t || !out || index < 0 || index >= t->num_images) return EW_ERR_INVALID_ARGUMENT;
    *out = t->images[index];
    return EW_OK;
}

ew_result ew_method_param(const char *kind, const char *name, int32_t index, ew_param_info *out) {
    const ew_op_type *t = kind && name ? ew_op_type_find(kind, name) : NULL;
    if (!t || !out || index < 0 || index >= t->num_params) return EW_ERR_INVALID_ARGUMENT;
    *out = t->params[index];
    return EW_OK;
}

int32_t ew_method_param_is_pixels(const char *kind, const char *name, int32_t index) {
    const ew_op_type *t = kind && name ? ew_op_type_find(kind, name) : NULL;
    if (!t || index < 0 || index >= t->num_params) return -1;
    for (const char *const *p = t->pixel_params; p && *p; p++)
        if (!strcmp(*p, t->params[index].name)) return 1;
    return 0;
}
