/*
 * image_file.c — image files for callers of libedgewise_nodes (Python's
 * edgewise.read/write): a whole file in memory through the OpenImageIO
 * shim, its layers, passes and header as JSON, passes copied to and from
 * caller views, written atomically. A thin face of ewio.
 */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cycles_passes.h"
#include "edgewise/nodes.h"
#include "ewio.h"
#include "graph.h"

struct ew_image_file {
    ewio_file *f;
    char *json;
};

static ew_result fail(char *err, size_t errlen, ew_result code, const char *msg) {
    if (err && errlen) snprintf(err, errlen, "%s", msg);
    return code;
}

ew_result ew_image_file_read(const char *path, ew_image_file **out, char *err, size_t errlen) {
    if (!out) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "out is NULL");
    *out = NULL;
    if (!path) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "path is NULL");
    ew_image_file *h = (ew_image_file *)calloc(1, sizeof *h);
    if (!h) return fail(err, errlen, EW_ERR_OUT_OF_MEMORY, "out of memory");
    char e[1024];
    if (ewio_read(path, &h->f, e, sizeof e) != 0) {
        free(h);
        return fail(err, errlen, EW_ERR_IO, e);
    }
    *out = h;
    return EW_OK;
}

ew_result ew_image_file_create(int32_t width, int32_t height, ew_image_file **out, char *err, size_t errlen) {
    if (!out) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "out is NULL");
    *out = NULL;
    ew_image_file *h = (ew_image_file *)calloc(1, sizeof *h);
    if (!h) return fail(err, errlen, EW_ERR_OUT_OF_MEMORY, "out of memory");
    char e[1024];
    if (ewio_create(width, height, &h->f, e, sizeof e) != 0) {
        free(h);
        return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, e);
    }
    *out = h;
    return EW_OK;
}

void ew_image_file_destroy(ew_image_file *h) {
    if (!h) return;
    ewio_free(h->f);
    free(h->json);
    free(h);
}

/* Split a channel name as ewio does: component after the last '.', pass
 * the token before it, layer the rest. */
static void split_channel(const char *name, char *layer, char *pass, char *comp, size_t len) {
    const char *last = strrchr(name, '.');
    if (!last) {
        snprintf(layer, len, "%s", "");
        snprintf(pass, len, "%s", "");
        snprintf(comp, len, "%s", name);
        return;
    }
    snprintf(comp, len, "%s", last + 1);
    const char *prev = last;
    while (prev > name && prev[-1] != '.') prev--;
    snprintf(pass, len, "%.*s", (int)(last - prev), prev);
    if (prev > name) snprintf(layer, len, "%.*s", (int)(prev - 1 - name), name);
    else snprintf(layer, len, "%s", "");
}

const char *ew_image_file_describe(ew_image_file *h) {
    if (!h) return NULL;
    if (h->json) return h->json;
    const ewio_file *f = h->f;
    json_t *root = json_object(), *layers = json_object(), *attrs = json_object();
    json_object_set_new(root, "width", json_integer(ewio_width(f)));
    json_object_set_new(root, "height", json_integer(ewio_height(f)));
    for (int i = 0; i < ewio_num_layers(f); i++) {
        json_t *l = json_object();
        json_object_set_new(l, "passes", json_object());
        json_object_set_new(layers, ewio_layer_name(f, i), l);
    }
    /* components of every pass, in file order (one letter each: what ewio addresses) */
    for (int c = 0; c < ewio_num_channels(f); c++) {
        char layer[256], pass[256], comp[256];
        split_channel(ewio_channel_name(f, c), layer, pass, comp, sizeof layer);
        json_t *l = json_object_get(layers, layer);
        if (!l || strlen(comp) != 1) continue;
        json_t *passes = json_object_get(l, "passes");
        const char *had = json_string_value(json_object_get(passes, pass));
        /* comp is one letter (checked above); a pass of more than 62
         * components keeps its first 62, which no reader addresses anyway */
        char comps[64];
        snprintf(comps, sizeof comps, "%.*s%c", (int)sizeof comps - 2, had ? had : "", comp[0]);
        json_object_set_new(passes, pass, json_string(comps));
    }
    for (int i = 0; i < ewio_num_layers(f); i++) {
        const char *layer = ewio_layer_name(f, i);
        json_t *l = json_object_get(layers, layer);
        ew_layer_passes lp;
        char e[512];
        if (ew_find_image_passes(f, layer, &lp, e, sizeof e) == 0) json_object_set_new(l, "color", json_string(lp.color));
        if (ew_find_layer_passes(f, layer, &lp, e, sizeof e) == 0) {
            json_object_set_new(l, "noisy", json_string(lp.color));
            if (lp.albedo) json_object_set_new(l, "albedo", json_string(lp.albedo));
            if (lp.normal) json_object_set_new(l, "normal", json_string(lp.normal));
            if (lp.depth) json_object_set_new(l, "depth", json_string(lp.depth));
        }
    }
    json_object_set_new(root, "layers", layers);
    static const char *const keys[] = {"compression", "Software", "BlenderMultiChannel", NULL};
    for (int i = 0; keys[i]; i++) {
        const char *v = ewio_get_attribute(f, keys[i]);
        if (v && v[0]) json_object_set_new(attrs, keys[i], json_string(v));
    }
    for (int i = 0; i < ewio_num_layers(f); i++) {
        char key[320];
        snprintf(key, sizeof key, "cycles.%s.samples", ewio_layer_name(f, i));
        const char *v = ewio_get_attribute(f, key);
        if (v && v[0]) json_object_set_new(attrs, key, json_string(v));
    }
    json_object_set_new(root, "attributes", attrs);
    h->json = json_dumps(root, JSON_PRESERVE_ORDER);
    json_decref(root);
    return h->json;
}

static int packed(const ew_image *v) {
    return v && v->data && (v->pixel_stride == 0 || v->pixel_stride == (int64_t)v->channels * 4) &&
           (v->row_stride == 0 || v->row_stride == (int64_t)v->channels * 4 * v->width);
}

ew_result ew_image_file_get_pass(const ew_image_file *h, const char *layer, const char *pass, const char *comps,
                                 const ew_image *dst, char *err, size_t errlen) {
    if (!h || !comps || !dst || !dst->data) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "NULL argument");
    const int c = (int)strlen(comps);
    if (c < 1 || c > 4 || dst->channels != c || dst->width != ewio_width(h->f) || dst->height != ewio_height(h->f))
        return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "the view does not match the file's size and the components");
    if (!packed(dst)) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "the view must be packed");
    char e[1024];
    if (ewio_get_pass(h->f, layer, pass, comps, (float *)dst->data, e, sizeof e) != 0)
        return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, e);
    return EW_OK;
}

ew_result ew_image_file_set_pass(ew_image_file *h, const char *layer, const char *pass, const char *comps,
                                 const ew_image *src, char *err, size_t errlen) {
    if (!h || !comps || !src || !src->data) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "NULL argument");
    const int c = (int)strlen(comps);
    if (c < 1 || c > 4 || src->channels != c || src->width != ewio_width(h->f) || src->height != ewio_height(h->f))
        return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "the view does not match the file's size and the components");
    if (!packed(src)) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "the view must be packed");
    char e[1024];
    if (ewio_set_pass(h->f, layer, pass, comps, (const float *)src->data, e, sizeof e) != 0)
        return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, e);
    free(h->json);
    h->json = NULL;
    return EW_OK;
}

ew_result ew_image_file_set_attribute(ew_image_file *h, const char *name, const char *value) {
    if (!h || !name) return EW_ERR_INVALID_ARGUMENT;
    ewio_set_attribute(h->f, name, value);
    free(h->json);
    h->json = NULL;
    return EW_OK;
}

ew_result ew_image_file_write(const ew_image_file *h, const char *path, int32_t pixel_type, const char *layer,
                              const char *pass, char *err, size_t errlen) {
    if (!h || !path) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "NULL argument");
    if (pixel_type < 0 || pixel_type > 2) return fail(err, errlen, EW_ERR_INVALID_ARGUMENT, "pixel type 0, 1 or 2");
    char e[1024];
    if (ewio_write(h->f, path, (ewio_pixel_type)pixel_type, layer, pass, e, sizeof e) != 0)
        return fail(err, errlen, EW_ERR_IO, e);
    return EW_OK;
}
