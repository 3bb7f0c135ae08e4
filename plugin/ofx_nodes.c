/*
 * Which library methods become OFX plugins, built once from the library's
 * introspection (ew_method_*), so clips and parameters are declared in one
 * place: the library's descriptors.
 *
 * Every method the library marks EW_METHOD_HOST becomes a plugin (every
 * denoiser, and the filters meant as compositing tools; "bilateral" and
 * "separable" are the exact reference and a baseline), with no change here
 * when one is added. Its inputs are the images the descriptor marks as
 * read, its identity test the parameters marked EW_PARAM_NOOP_AT_ZERO.
 */
#include "ofx_plugin.h"

#include <ctype.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

/* Display names hosts show in their menus, where the generated
 * "Edgewise Filter (name)" reads worse; a method missing here keeps that. */
static const struct {
    const char *method, *label;
} labels[] = {
    {"bgrid", "Edgewise Denoise (bilateral grid)"},
    {"nbg", "Edgewise Denoise (neural bilateral grid)"},
    {"pyramid", "Edgewise Edge Filter (pyramid)"},
    {"dof", "Edgewise Depth of Field"},
    {"atrous", "Edgewise A-Trous Filter"},
    {"outlier", "Edgewise Firefly Suppression"},
};

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
static int build(ew_ofx_node *n, const char *kind, const char *method) {
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
    snprintf(n->label, sizeof n->label, "Edgewise %s (%s)", !strcmp(kind, "denoiser") ? "Denoise" : "Filter", method);
    for (size_t k = 0; k < sizeof labels / sizeof labels[0]; k++)
        if (!strcmp(labels[k].method, method)) snprintf(n->label, sizeof n->label, "%s", labels[k].label);
    n->channels = !strcmp(kind, "denoiser") ? 3 : 4;

    int num_identity = 0;
    for (int32_t i = 0; i < np; i++) {
        uint32_t flags = 0;
        if (ew_method_param(kind, method, i, &n->params[i]) != EW_OK || !plain_name(n->params[i].name) ||
            ew_method_param_flags(kind, method, i, &flags) != EW_OK)
            return 0;
        n->param_pixels[i] = (flags & EW_PARAM_PIXELS) != 0;
        n->param_choices[i] = ew_method_param_num_choices(kind, method, i);
        if (flags & EW_PARAM_NOOP_AT_ZERO) {
            /* more than the plugin can test: never claim identity */
            if (num_identity == EW_OFX_MAX_IDENTITY) return 0;
            n->identity_params[num_identity++] = n->params[i].name;
        }
    }
    n->num_params = (int)np;

    int has_color = 0;
    for (int32_t i = 0; i < ni; i++) {
        ew_image_info im;
        uint32_t flags = 0;
        if (ew_method_image(kind, method, i, &im) != EW_OK || !plain_name(im.name) ||
            ew_method_image_flags(kind, method, i, &flags) != EW_OK)
            return 0;
        if (!strcmp(im.name, "color")) {
            has_color = 1;
            continue;
        }
        /* the result, and extra outputs a compositing node has no second
         * output clip for */
        if (flags & EW_IMAGE_OUTPUT) continue;
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
    /* every method the library offers to hosts, denoisers first */
    static const char *const kinds[] = {"denoiser", "filter"};
    for (int k = 0; k < 2; k++) {
        int32_t count = ew_method_count(kinds[k]);
        for (int32_t i = 0; i < count && num_nodes < EW_OFX_MAX_PLUGINS; i++) {
            const char *name = NULL;
            uint32_t flags = 0;
            if (ew_method_get(kinds[k], i, &name, NULL, NULL, NULL) != EW_OK || !name ||
                ew_method_flags(kinds[k], name, &flags) != EW_OK || !(flags & EW_METHOD_HOST))
                continue;
            if (build(&nodes[num_nodes], kinds[k], name)) num_nodes++;
        }
    }
}

int ew_ofx_node_count(void) {
    pthread_once(&once, build_all);
    return num_nodes;
}

const ew_ofx_node *ew_ofx_node_get(int index) {
    pthread_once(&once, build_all);
    return index >= 0 && index < num_nodes ? &nodes[index] : NULL;
}
