#include "src/finite.h"
#include "src/op.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const ew_op_type *ew_op_type_find(const char *kind, const char *name) {
    for (int i = 0; name && ew_op_types[i]; i++)
        if ((!kind || !strcmp(ew_op_types[i]->kind, kind)) && !strcmp(ew_op_types[i]->name, name)) return ew_op_types[i];
    return NULL;
}

static void list_names(const char *kind, char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; ew_op_types[i]; i++) {
        if (kind && strcmp(ew_op_types[i]->kind, kind) != 0) continue;
        int k = snprintf(buf + used, len - used, "%s%s", used ? ", " : "", ew_op_types[i]->name);
        if (k < 0 || (size_t)k >= len - used) break;
        used += (size_t)k;
    }
}

ew_result ew_op_create_kind(ew_device *dev, const char *kind, const char *name, ew_op **out) {
    if (!out) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "output handle pointer is NULL");
    *out = NULL;
    if (!dev) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(dev);
    const ew_op_type *t = ew_op_type_find(kind, name);
    if (!t) {
        char names[256];
        list_names(kind, names, sizeof names);
        return ew__fail(dev, name ? EW_ERR_UNSUPPORTED : EW_ERR_INVALID_ARGUMENT, "unknown %s '%s' (available: %s)",
                        kind ? kind : "method", name ? name : "(null)", names);
    }
    /* an op still handing the backend host pointers would crash a GPU */
    if (dev->device_memory && !t->device_memory)
        return ew__fail(dev, EW_ERR_UNSUPPORTED, "%s '%s' does not run on CUDA devices yet: use an EW_DEVICE_CPU device",
                        t->kind, name);
    ew_op *op = (ew_op *)calloc(1, sizeof *op);
    if (!op) return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
    op->type = t;
    op->dev = dev;
    ew__device_retain(dev); /* the device outlives its ops whatever the destroy order */
    for (int i = 0; i < ew_op_type_num_params(t); i++) op->params[i] = ew_op_type_param(t, i)->default_value;
    *out = op;
    return EW_OK;
}

ew_result ew_op_create(ew_device *dev, const char *method, ew_op **out) {
    return ew_op_create_kind(dev, NULL, method, out);
}

static void release(ew_op *op) {
    ew_harm_release(op);
    ew_op_alpha_release(op);
    if (op->state && op->type->release) op->type->release(op);
    op->state = NULL;
    op->state_bytes = 0;
    op->committed = 0;
}

void *ew_op_state_block(ew_op *op, size_t bytes) {
    if (op->state && op->state_bytes == bytes) return op->state;
    if (op->state && op->type->release) op->type->release(op);
    op->state = malloc(bytes);
    op->state_bytes = op->state ? bytes : 0;
    return op->state;
}

static void op_free(ew_op *op) {
    ew_device *dev = op->dev;
    release(op);
    if (op->data_state && op->type->release_data) op->type->release_data(op);
    ew_op_half_release(op);
    free(op);
    ew__device_release(dev);
}

void ew_op_destroy(ew_op *op) {
    if (!op) return;
    /* from inside its own progress callback: freed when the run returns */
    if (__atomic_load_n(&op->busy, __ATOMIC_ACQUIRE)) {
        __atomic_store_n(&op->destroy_pending, 1, __ATOMIC_RELEASE);
        return;
    }
    op_free(op);
}

/* Refuse a call that would change an op while its commit or execute runs
 * (a progress callback calling back into it). */
static ew_result busy_fail(ew_op *op, const char *what) {
    return ew__fail(op->dev, EW_ERR_INVALID_STATE,
                    "%s called while the %s '%s' is running (from its progress callback?): wait for "
                    "commit/execute to return",
                    what, op->type->kind, op->type->name);
}

#define EW_OP_NOT_BUSY(op, what)                                                   \
    do {                                                                           \
        if (__atomic_load_n(&(op)->busy, __ATOMIC_ACQUIRE)) return busy_fail(op, what); \
    } while (0)

/* Enter / leave a run; 0 when the op is already running. */
static int op_enter(ew_op *op) {
    int expected = 0;
    return __atomic_compare_exchange_n(&op->busy, &expected, 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE);
}

/* Returns 1 when the op was destroyed during the run (the caller must not
 * touch it again). */
static int op_leave(ew_op *op) {
    __atomic_store_n(&op->busy, 0, __ATOMIC_RELEASE);
    if (__atomic_load_n(&op->destroy_pending, __ATOMIC_ACQUIRE)) {
        op_free(op);
        return 1;
    }
    return 0;
}

static void list_slots(const ew_op_type *t, char *buf, size_t len, int images) {
    size_t used = 0;
    buf[0] = '\0';
    int n = images ? t->num_images : ew_op_type_num_params(t);
    for (int i = 0; i < n; i++) {
        const char *nm = images ? t->images[i].name : ew_op_type_param(t, i)->name;
        int k = snprintf(buf + used, len - used, "%s%s", i ? ", " : "", nm);
        if (k < 0 || (size_t)k >= len - used) break;
        used += (size_t)k;
    }
}

ew_result ew_op_set_image(ew_op *op, const char *name, const ew_image *view) {
    if (!op) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    EW_OP_NOT_BUSY(op, "set_image");
    const ew_op_type *t = op->type;
    for (int i = 0; name && i < t->num_images; i++) {
        if (strcmp(name, t->images[i].name) != 0) continue;
        if (view) {
            const char *why;
            if (!ew__image_valid(view, &why))
                return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image '%s': %s", name, why);
            if (view->channels < t->images[i].min_channels)
                return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image '%s' needs at least %d channels, got %d",
                                name, t->images[i].min_channels, view->channels);
            uint32_t flags = 0;
            ew_method_image_flags(t->kind, t->name, i, &flags);
            if (view->format == EW_FORMAT_HALF && (flags & EW_IMAGE_OUTPUT))
                return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT,
                                "image '%s' is written: it must be EW_FORMAT_FLOAT (halves are for inputs)", name);
            op->images[i] = op->given[i] = *view;
        }
        op->has_image[i] = view != NULL;
        op->committed = 0;
        return EW_OK;
    }
    char names[256];
    list_slots(t, names, sizeof names, 1);
    return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "unknown image '%s' for %s '%s' (%s)", name ? name : "(null)",
                    t->kind, t->name, names);
}

ew_result ew_op_set_param(ew_op *op, const char *name, float value, int is_int) {
    if (!op) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    EW_OP_NOT_BUSY(op, "set_param");
    const ew_op_type *t = op->type;
    for (int i = 0; name && i < ew_op_type_num_params(t); i++) {
        const ew_param_desc *p = ew_op_type_param(t, i);
        if (strcmp(name, p->name) != 0) continue;
        if (p->type != EW_PARAM_FLOAT && !is_int)
            return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "parameter '%s' of %s '%s' is an integer: use set_int",
                            name, t->kind, t->name);
        if (!(value >= p->min_value && value <= p->max_value))
            return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "parameter '%s' = %g is outside [%g, %g]", name,
                            (double)value, (double)p->min_value, (double)p->max_value);
        op->params[i] = value;
        op->committed = 0;
        return EW_OK;
    }
    char names[256];
    list_slots(t, names, sizeof names, 0);
    return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "unknown parameter '%s' for %s '%s' (%s)",
                    name ? name : "(null)", t->kind, t->name, names);
}

ew_result ew_op_set_int(ew_op *op, const char *name, int32_t value) { return ew_op_set_param(op, name, (float)value, 1); }
ew_result ew_op_set_float(ew_op *op, const char *name, float value) { return ew_op_set_param(op, name, value, 0); }

/* The slot of a parameter for the get calls, failing with the known names. */
static int param_slot(const ew_op *op, const char *name) {
    const ew_op_type *t = op->type;
    for (int i = 0; name && i < ew_op_type_num_params(t); i++)
        if (!strcmp(name, ew_op_type_param(t, i)->name)) return i;
    char names[256];
    list_slots(t, names, sizeof names, 0);
    ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "unknown parameter '%s' for %s '%s' (%s)", name ? name : "(null)",
             t->kind, t->name, names);
    return -1;
}

ew_result ew_op_get_float(const ew_op *op, const char *name, float *out) {
    if (!op || !out) return op ? ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "output pointer is NULL") : EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    int i = param_slot(op, name);
    if (i < 0) return EW_ERR_INVALID_ARGUMENT;
    *out = op->params[i];
    return EW_OK;
}

ew_result ew_op_get_int(const ew_op *op, const char *name, int32_t *out) {
    if (!op || !out) return op ? ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "output pointer is NULL") : EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    int i = param_slot(op, name);
    if (i < 0) return EW_ERR_INVALID_ARGUMENT;
    if (ew_op_type_param(op->type, i)->type == EW_PARAM_FLOAT)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "parameter '%s' of %s '%s' is a float: use get_float", name,
                        op->type->kind, op->type->name);
    *out = (int32_t)op->params[i];
    return EW_OK;
}

ew_result ew_op_set_progress(ew_op *op, ew_progress_fn fn, void *user) {
    if (!op) return EW_ERR_INVALID_ARGUMENT;
    op->progress = fn;
    op->progress_user = user;
    return EW_OK;
}

const char *ew_op_describe(const ew_op *op) {
    if (!op || !op->committed) return NULL;
    const char *s = op->type->describe ? op->type->describe(op) : NULL;
    return s ? s : op->type->name;
}

const char *ew_op_method(const ew_op *op) { return op ? op->type->name : NULL; }
const char *ew_op_kind(const ew_op *op) { return op ? op->type->kind : NULL; }

ew_result ew_op_set_data(ew_op *op, const char *name, const void *data, size_t size) {
    if (!op) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    EW_OP_NOT_BUSY(op, "set_data");
    if (!op->type->set_data)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "%s '%s' takes no data ('%s')", op->type->kind,
                        op->type->name, name ? name : "(null)");
    if (!name) return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "data name is NULL");
    if (!data != !size) return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "data '%s': pointer and size disagree", name);
    ew_result r = op->type->set_data(op, name, data, size);
    if (r == EW_OK) op->committed = 0;
    return r;
}

const ew_image *ew_op_image(const ew_op *op, const char *name) {
    for (int i = 0; i < op->type->num_images; i++)
        if (!strcmp(op->type->images[i].name, name)) return op->has_image[i] ? &op->images[i] : NULL;
    return NULL;
}

float ew_op_param(const ew_op *op, const char *name) {
    for (int i = 0; i < ew_op_type_num_params(op->type); i++)
        if (!strcmp(ew_op_type_param(op->type, i)->name, name)) return op->params[i];
    return 0.0f;
}

void ew_op_param_put(ew_op *op, const char *name, float value) {
    for (int i = 0; i < ew_op_type_num_params(op->type); i++)
        if (!strcmp(ew_op_type_param(op->type, i)->name, name)) op->params[i] = value;
}

int ew_op_report(ew_op *op, double fraction) {
    return op->progress ? op->progress(op->progress_user, fraction) : 1;
}

static ew_result commit_checked(ew_op *op) {
    ew_device *dev = op->dev;
    const ew_op_type *t = op->type;
    const ew_image *first = NULL;
    const char *first_name = NULL;
    for (int i = 0; i < t->num_images; i++) {
        if (!op->has_image[i]) {
            if (t->images[i].required)
                return ew__fail(dev, EW_ERR_INVALID_STATE, "no '%s' image set (%s '%s' needs it)", t->images[i].name,
                                t->kind, t->name);
            continue;
        }
        const ew_image *im = &op->images[i];
        if (!first) {
            first = im;
            first_name = t->images[i].name;
        } else if (im->width != first->width || im->height != first->height) {
            return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "image '%s' is %dx%d but '%s' is %dx%d", t->images[i].name,
                            im->width, im->height, first_name, first->width, first->height);
        }
    }
    op->committed = 0;
    ew_result r = ew_op_half_commit(op);
    if (r == EW_OK) r = t->commit(op);
    if (r == EW_OK) r = ew_harm_commit(op);
    if (r == EW_OK) r = ew_op_alpha_commit(op);
    if (r == EW_OK) op->committed = 1;
    return r;
}

ew_result ew_op_commit(ew_op *op) {
    if (!op) return EW_ERR_INVALID_ARGUMENT;
    ew_device *dev = op->dev;
    ew__clear_error(dev);
    if (!op_enter(op)) return busy_fail(op, "commit");
    ew_result r = commit_checked(op);
    op_leave(op);
    return r;
}

ew_result ew_op_execute(ew_op *op) {
    if (!op) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(op->dev);
    if (!op_enter(op)) return busy_fail(op, "execute");
    ew_result r;
    if (!op->committed)
        r = ew__fail(op->dev, EW_ERR_INVALID_STATE, "execute called before commit (or after a change)");
    else if (!ew_op_report(op, 0.0))
        r = ew__fail(op->dev, EW_ERR_CANCELLED, "cancelled");
    else {
        ew_op_half_execute(op);
        r = ew_op_alpha_execute(op);
        if (r == EW_OK) r = op->harm ? ew_harm_execute(op) : op->type->execute(op);
        if (r == EW_OK && !strcmp(op->type->kind, "filter"))
            ew__finite_fallback(op->dev, ew_op_image(op, "output"), ew_op_image(op, "color"));
        if (r == EW_OK) ew_op_alpha_store(op);
        if (r == EW_OK) ew_op_alpha_pass(op);
        if (r == EW_OK) ew_op_report(op, 1.0);
    }
    op_leave(op);
    return r;
}
