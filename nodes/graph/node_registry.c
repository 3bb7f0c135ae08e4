/*
 * node_registry.c — every node type, and the signature of a node: its own
 * ports/parameters plus, for library-backed nodes, the images and parameters
 * libedgewise reports for the method (never re-declared here).
 */
#include <stdio.h>
#include <string.h>

#include "node_type.h"

extern const ew_node_type ew_node_read, ew_node_write, ew_node_input, ew_node_output;
extern const ew_node_type ew_node_denoise, ew_node_filter, ew_node_pyramid, ew_node_bilateral, ew_node_atrous,
    ew_node_dof;
extern const ew_node_type ew_node_outlier, ew_node_demodulate, ew_node_remodulate;
extern const ew_node_type ew_node_colorspace, ew_node_display;
extern const ew_node_type ew_node_metrics, ew_node_temporal;
extern const ew_node_type ew_node_add, ew_node_multiply, ew_node_mix, ew_node_shuffle;

const ew_node_type *const ew_node_types[] = {
    &ew_node_read,     &ew_node_write,      &ew_node_input,      &ew_node_output,   &ew_node_denoise,
    &ew_node_filter,   &ew_node_pyramid,    &ew_node_bilateral,  &ew_node_atrous,   &ew_node_dof,
    &ew_node_outlier,  &ew_node_demodulate, &ew_node_remodulate, &ew_node_temporal, &ew_node_colorspace,
    &ew_node_display,  &ew_node_metrics,    &ew_node_add,        &ew_node_multiply, &ew_node_mix,
    &ew_node_shuffle,  NULL,
};

const ew_node_type *ew_node_type_find(const char *name) {
    for (int i = 0; name && ew_node_types[i]; i++)
        if (!strcmp(ew_node_types[i]->name, name)) return ew_node_types[i];
    return NULL;
}

int ew_node_type_total(void) {
    int n = 0;
    while (ew_node_types[n]) n++;
    return n;
}

static void append(char *buf, size_t len, size_t *used, const char *s) {
    if (*used >= len) return;
    int k = snprintf(buf + *used, len - *used, "%s%s", *used ? ", " : "", s);
    if (k > 0) *used += (size_t)k;
}

void ew_node_type_list(char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; ew_node_types[i]; i++) append(buf, len, &used, ew_node_types[i]->name);
}

void ew_lib_list_methods(const char *kind, char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    for (int32_t i = 0; i < ew_method_count(kind); i++) {
        const char *m = NULL;
        if (ew_method_get(kind, i, &m, NULL, NULL, NULL) == EW_OK && m) append(buf, len, &used, m);
    }
    if (!used) snprintf(buf, len, "none");
}

static const char *const pass_names[] = {"any", "color", "albedo", "normal", "depth", "vector", "variance", "mask"};

const char *ew_pass_name(ew_pass p) {
    return (unsigned)p < sizeof pass_names / sizeof pass_names[0] ? pass_names[p] : "any";
}

/* Colour-like passes mix freely (an albedo may be filtered like a colour);
 * geometric data (normal, depth, vector) only goes where that data is
 * expected, which catches the usual wiring mistakes. */
int ew_pass_compatible(ew_pass src, ew_pass dst) {
    if (src == EW_PASS_ANY || dst == EW_PASS_ANY || src == dst) return 1;
    int src_geo = src == EW_PASS_NORMAL || src == EW_PASS_DEPTH || src == EW_PASS_VECTOR;
    int dst_geo = dst == EW_PASS_NORMAL || dst == EW_PASS_DEPTH || dst == EW_PASS_VECTOR;
    if (src_geo || dst_geo) return 0;
    return 1;
}

/* A library image name -> pass. A filter's "color" is whatever is filtered. */
static ew_pass lib_pass(const char *kind, const char *name) {
    if (!strcmp(name, "color") || !strcmp(name, "output")) return !strcmp(kind, "denoiser") ? EW_PASS_COLOR : EW_PASS_ANY;
    if (!strcmp(name, "albedo")) return EW_PASS_ALBEDO;
    if (!strcmp(name, "normal")) return EW_PASS_NORMAL;
    if (!strcmp(name, "depth")) return EW_PASS_DEPTH;
    if (!strcmp(name, "vector") || !strcmp(name, "motion")) return EW_PASS_VECTOR;
    if (!strcmp(name, "variance")) return EW_PASS_VARIANCE;
    if (!strcmp(name, "roughness") || !strcmp(name, "coc") || !strcmp(name, "mask")) return EW_PASS_MASK;
    return EW_PASS_ANY;
}

static const char *find_method(const char *kind, const char *name, int32_t *num_images, int32_t *num_params) {
    for (int32_t i = 0; i < ew_method_count(kind); i++) {
        const char *m = NULL;
        if (ew_method_get(kind, i, &m, NULL, num_images, num_params) != EW_OK || !m) continue;
        if (!name || !strcmp(m, name)) return m;
    }
    return NULL;
}

int ew_node_sig_build(const ew_node_type *t, const char *method, ew_node_sig *s) {
    memset(s, 0, sizeof *s);
    s->type = t;
    s->available = 1;
    s->inplace_input = t->inplace_input;
    for (int i = 0; i < t->num_inputs && s->num_inputs < EW_SIG_MAX_PORTS; i++) s->inputs[s->num_inputs++] = t->inputs[i];
    for (int i = 0; i < t->num_outputs && s->num_outputs < EW_SIG_MAX_PORTS; i++)
        s->outputs[s->num_outputs++] = t->outputs[i];
    for (int i = 0; i < t->num_params && s->num_params < EW_SIG_MAX_PARAMS; i++) s->params[s->num_params++] = t->params[i];
    s->num_static_params = s->num_params;
    if (!t->lib_kind) return 1;

    const char *kind = t->lib_kind;
    const char *want = t->lib_method ? t->lib_method : method;
    int32_t ni = 0, np = 0;
    const char *m = find_method(kind, want, &ni, &np);
    /* The selector's default is the library's first method. */
    if (!t->lib_method && s->num_params > 0 && s->params[0].type == EW_NODE_PARAM_ENUM) {
        const char *first = find_method(kind, NULL, NULL, NULL);
        s->params[0].def_string = first ? first : "";
    }
    if (!m) {
        s->available = 0;
        s->method = NULL;
        return 0;
    }
    s->method = m;
    int inplace_in = -1, out_port = -1;
    for (int32_t i = 0; i < ni; i++) {
        ew_image_info im;
        uint32_t flags = 0;
        if (ew_method_image(kind, m, i, &im) != EW_OK || ew_method_image_flags(kind, m, i, &flags) != EW_OK) continue;
        ew_port_desc d = {im.name, lib_pass(kind, im.name), im.min_channels, im.required, im.hint};
        if (flags & EW_IMAGE_OUTPUT) {
            if (s->num_outputs >= EW_SIG_MAX_PORTS) continue;
            if (!strcmp(im.name, "output")) out_port = s->num_outputs;
            d.required = 0; /* outputs are wanted only when connected */
            s->outputs[s->num_outputs++] = d;
        } else {
            if (s->num_inputs >= EW_SIG_MAX_PORTS) continue;
            if ((flags & EW_IMAGE_INPLACE) && inplace_in < 0) inplace_in = s->num_inputs;
            s->inputs[s->num_inputs++] = d;
        }
    }
    /* The library's "output" first: a node's main output is its port 0. */
    if (out_port > 0) {
        ew_port_desc tmp = s->outputs[0];
        s->outputs[0] = s->outputs[out_port];
        s->outputs[out_port] = tmp;
    }
    s->inplace_input = out_port >= 0 ? inplace_in : -1;
    for (int32_t i = 0; i < np && s->num_params < EW_SIG_MAX_PARAMS; i++) {
        ew_param_info p;
        if (ew_method_param(kind, m, i, &p) != EW_OK) continue;
        /* A library parameter named like one of the node's own would be
         * ambiguous in a graph file; the node's own wins (docs/graphs.md). */
        int clash = 0;
        for (int k = 0; k < s->num_static_params; k++) clash |= !strcmp(s->params[k].name, p.name);
        if (clash) continue;
        ew_nparam_desc d;
        memset(&d, 0, sizeof d);
        d.name = p.name;
        d.type = p.type == EW_PARAM_INT ? EW_NODE_PARAM_INT : p.type == EW_PARAM_BOOL ? EW_NODE_PARAM_BOOL
                                                                                       : EW_NODE_PARAM_FLOAT;
        d.def = p.default_value;
        d.min = p.min_value;
        d.max = p.max_value;
        d.def_string = "";
        d.label = p.name;
        d.hint = p.hint ? p.hint : "";
        if (ew_method_param_num_choices(kind, m, i) > 0) { /* shown and given by choice name */
            const char *def = ew_method_param_choice(kind, m, i, (int32_t)p.default_value);
            d.type = EW_NODE_PARAM_ENUM;
            d.def_string = def ? def : "";
            s->lib_enum[s->num_params] = (int)i + 1;
        }
        s->params[s->num_params++] = d;
    }
    return 1;
}

int ew_sig_find_input(const ew_node_sig *s, const char *name) {
    for (int i = 0; name && i < s->num_inputs; i++)
        if (!strcmp(s->inputs[i].name, name)) return i;
    return -1;
}

int ew_sig_find_output(const ew_node_sig *s, const char *name) {
    for (int i = 0; name && i < s->num_outputs; i++)
        if (!strcmp(s->outputs[i].name, name)) return i;
    return -1;
}

int ew_sig_find_param(const ew_node_sig *s, const char *name) {
    for (int i = 0; name && i < s->num_params; i++)
        if (!strcmp(s->params[i].name, name)) return i;
    return -1;
}

/* The library parameter index of a library enum of s, or -1. */
static int32_t lib_enum_of(const ew_node_sig *s, const ew_nparam_desc *p) {
    long k = p - s->params;
    return k >= 0 && k < s->num_params && s->lib_enum[k] > 0 ? (int32_t)s->lib_enum[k] - 1 : -1;
}

int ew_param_num_choices(const ew_node_sig *s, const ew_nparam_desc *p) {
    if (p->type != EW_NODE_PARAM_ENUM) return 0;
    int32_t li = lib_enum_of(s, p);
    if (li >= 0) {
        int32_t n = ew_method_param_num_choices(s->type->lib_kind, s->method, li);
        return n > 0 ? (int)n : 0;
    }
    if (!p->choices) return s->type->lib_kind ? (int)ew_method_count(s->type->lib_kind) : 0;
    int n = 0;
    while (p->choices[n]) n++;
    return n;
}

const char *ew_param_choice(const ew_node_sig *s, const ew_nparam_desc *p, int i) {
    if (i < 0 || i >= ew_param_num_choices(s, p)) return NULL;
    int32_t li = lib_enum_of(s, p);
    if (li >= 0) return ew_method_param_choice(s->type->lib_kind, s->method, li, i);
    if (p->choices) return p->choices[i];
    const char *m = NULL;
    ew_method_get(s->type->lib_kind, i, &m, NULL, NULL, NULL);
    return m;
}

void ew_sig_list_params(const ew_node_sig *s, char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; i < s->num_params; i++) append(buf, len, &used, s->params[i].name);
    if (!used) snprintf(buf, len, "none");
}

void ew_sig_list_ports(const ew_node_sig *s, int outputs, char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    int n = outputs ? s->num_outputs : s->num_inputs;
    for (int i = 0; i < n; i++) append(buf, len, &used, outputs ? s->outputs[i].name : s->inputs[i].name);
    if (!used) snprintf(buf, len, "none");
}
