/*
 * Which library methods become OFX plugins, built once from the library's
 * introspection (ew_method_*), so clips and parameters are declared in one
 * place: the library's descriptors.
 *
 * Every denoiser is user-facing, so each one the library offers becomes a
 * plugin ("bgrid" now, "nbg" when it lands, with no change here). Filters
 * are a curated list checked against the library: "bilateral" and
 * "separable" are the exact reference and a baseline, not compositing
 * tools. A listed filter the library lacks is skipped.
 */
#include "ofx_plugin.h"

#include <ctype.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    const char *kind, *method, *label;
    const char *identity_params[2];
} node_spec;

static const node_spec denoiser_labels[] = {
    {"denoiser", "bgrid", "Edgewise Denoise (bilateral grid)", {NULL, NULL}},
    {"denoiser", "nbg", "Edgewise Denoise (neural bilateral grid)", {NULL, NULL}},
};

static const node_spec filters[] = {
    /* radius 0: "no filtering at all, whatever the model" */
    {"filter", "pyramid", "Edgewise Edge Filter (pyramid)", {"radius", NULL}},
    {"filter", "dof", "Edgewise Depth of Field", {NULL, NULL}},
    /* radius 0 and iterations 0: zero a-trous iterations */
    {"filter", "atrous", "Edgewise A-Trous Filter", {"radius", "iterations"}},
    /* firefly suppression before any filter of the host's (issue 9) */
    {"filter", "outlier", "Edgewise Firefly Suppression", {NULL, NULL}},
};

/* Library images that are not inputs: the result, and extra outputs a
 * compositing node has no second output clip for. */
static int is_output_image(const char *name) { return !strcmp(name, "output") || !strcmp(name, "coc"); }

/* Channels the plugin hands over for an auxiliary image: what the feature
 * is, not the descriptor's minimum (a guide may use colour). */
static int aux_channels(const char *name, int min_channels) {
    if (!strcmp(name, "albedo") || !strcmp(name, "normal") || !strcmp(name, "guide")) return 3;
    if (!strcmp(name, "depth") || !strcmp(name, "roughness")) return 1;
    return min_channels > 0 && min_channels <= 4 ? min_channels : 1;
}

/* OFX names are ASCII without spaces; the library's are lower-case words. */
static int plain_name(const char *s) {
    if (!s || !*s || strlen(s) > 24) return 0;
    for (; *s; s++)
        if (!(islower((unsigned char)*s) || isdigit((unsigned char)*s) || *s == '_')) return 0;
    return 1;
}

static ew_ofx_node nodes[EW_OFX_MAX_PLUGINS];
static int num_nodes;
static pthread_once_t once = PTHREAD_ONCE_INIT;

/* Fill a node from the library's descriptors; 0 if the library does not
 * offer the method or it does not fit the plugin's limits. */
static int build(ew_ofx_node *n, const char *kind, const char *method, const char *label,
                 const char *const identity[2]) {
    memset(n, 0, sizeof *n);
    int32_t count = ew_method_count(kind);
    const char *name = NULL, *summary = NULL;
    int32_t ni = 0, np = 0, found = 0;
    for (int32_t i = 0; i < count && !found; i++)
        if (ew_method_get(kind, i, &name, &summary, &ni, &np) == EW_OK && name && !strcmp(name, method)) found = 1;
    if (!found || !plain_name(method) || np > EW_OFX_MAX_PARAMS) return 0;

    n->kind = kind;
    n->method = name; /* the library's static string */
    n->summary = summary ? summary : "";
    snprintf(n->identifier, sizeof n->identifier, "org.edgewise.%s.%s", !strcmp(kind, "denoiser") ? "denoise" : "filter",
             method);
    if (label)
        snprintf(n->label, sizeof n->label, "%s", label);
    else
        snprintf(n->label, sizeof n->label, "Edgewise %s (%s)", !strcmp(kind, "denoiser") ? "Denoise" : "Filter",
                 method);
    n->channels = !strcmp(kind, "denoiser") ? 3 : 4;
    n->identity_params[0] = identity ? identity[0] : NULL;
    n->identity_params[1] = identity ? identity[1] : NULL;

    for (int32_t i = 0; i < np; i++) {
        if (ew_method_param(kind, method, i, &n->params[i]) != EW_OK || !plain_name(n->params[i].name)) return 0;
        n->param_pixels[i] = ew_method_param_is_pixels(kind, method, i) == 1;
    }
    n->num_params = (int)np;

    int has_color = 0;
    for (int32_t i = 0; i < ni; i++) {
        ew_image_info im;
        if (ew_method_image(kind, method, i, &im) != EW_OK || !plain_name(im.name)) return 0;
        if (!strcmp(im.name, "color")) {
            has_color = 1;
            continue;
        }
        if (is_output_image(im.name)) continue;
        if (n->num_aux == EW_OFX_MAX_AUX) return 0;
        ew_ofx_aux *a = &n->aux[n->num_aux++];
        a->image = im.name;
        snprintf(a->clip, sizeof a->clip, "%s", im.name);
        a->clip[0] = (char)toupper((unsigned char)a->clip[0]);
        a->channels = aux_channels(im.name, im.min_channels);
        a->required = im.required != 0;
        a->hint = im.hint ? im.hint : "";
    }
    return has_color;
}

static void build_all(void) {
    /* every denoiser the library offers */
    int32_t nd = ew_method_count("denoiser");
    for (int32_t i = 0; i < nd && num_nodes < EW_OFX_MAX_PLUGINS; i++) {
        const char *name = NULL;
        if (ew_method_get("denoiser", i, &name, NULL, NULL, NULL) != EW_OK || !name) continue;
        const node_spec *spec = NULL;
        for (size_t k = 0; k < sizeof denoiser_labels / sizeof denoiser_labels[0]; k++)
            if (!strcmp(denoiser_labels[k].method, name)) spec = &denoiser_labels[k];
        if (build(&nodes[num_nodes], "denoiser", name, spec ? spec->label : NULL,
                  spec ? spec->identity_params : NULL))
            num_nodes++;
    }
    /* the user-facing filters, if this library has them */
    for (size_t k = 0; k < sizeof filters / sizeof filters[0] && num_nodes < EW_OFX_MAX_PLUGINS; k++)
        if (build(&nodes[num_nodes], filters[k].kind, filters[k].method, filters[k].label,
                  filters[k].identity_params))
            num_nodes++;
}

int ew_ofx_node_count(void) {
    pthread_once(&once, build_all);
    return num_nodes;
}

const ew_ofx_node *ew_ofx_node_get(int index) {
    pthread_once(&once, build_all);
    return index >= 0 && index < num_nodes ? &nodes[index] : NULL;
}
