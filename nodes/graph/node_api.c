/*
 * node_api.c — the public introspection of node types (nodes.h), read from
 * the same descriptors and library introspection the graph validates with.
 */
#include <string.h>

#include "ewcolor.h"
#include "graph.h"

int32_t ew_node_type_count(void) { return (int32_t)ew_node_type_total(); }

const char *ew_node_type_name(int32_t index) {
    return index >= 0 && index < ew_node_type_total() ? ew_node_types[index]->name : NULL;
}

/* A signature for a public query; an unknown method of denoise/filter is an
 * error, a bound node whose method is missing is reported unavailable. */
static ew_result sig_for(const char *type, const char *method, ew_node_sig *s) {
    const ew_node_type *t = ew_node_type_find(type);
    if (!t) return EW_ERR_INVALID_ARGUMENT;
    int ok = ew_node_sig_build(t, method, s);
    if (!ok && t->lib_kind && !t->lib_method && method) return EW_ERR_INVALID_ARGUMENT;
    return EW_OK;
}

ew_result ew_node_type_get(const char *type, const char *method, ew_node_type_info *out) {
    ew_node_sig s;
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    ew_result r = sig_for(type, method, &s);
    if (r != EW_OK) return r;
    const ew_node_type *t = s.type;
    memset(out, 0, sizeof *out);
    out->name = t->name;
    out->version = t->version;
    out->category = t->category;
    out->summary = t->summary;
    out->library_kind = t->lib_kind;
    out->library_method = s.method ? s.method : t->lib_method;
    out->available = s.available;
    out->num_inputs = s.num_inputs;
    out->num_outputs = s.num_outputs;
    out->num_params = s.num_params;
    return EW_OK;
}

static void port_info(const ew_port_desc *d, ew_node_port_info *out) {
    out->name = d->name;
    out->pass = ew_pass_name(d->pass);
    out->min_channels = d->min_channels;
    out->required = d->required;
    out->hint = d->hint ? d->hint : "";
}

ew_result ew_node_type_input(const char *type, const char *method, int32_t index, ew_node_port_info *out) {
    ew_node_sig s;
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    ew_result r = sig_for(type, method, &s);
    if (r != EW_OK) return r;
    if (index < 0 || index >= s.num_inputs) return EW_ERR_INVALID_ARGUMENT;
    port_info(&s.inputs[index], out);
    return EW_OK;
}

ew_result ew_node_type_output(const char *type, const char *method, int32_t index, ew_node_port_info *out) {
    ew_node_sig s;
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    ew_result r = sig_for(type, method, &s);
    if (r != EW_OK) return r;
    if (index < 0 || index >= s.num_outputs) return EW_ERR_INVALID_ARGUMENT;
    port_info(&s.outputs[index], out);
    return EW_OK;
}

ew_result ew_node_type_param(const char *type, const char *method, int32_t index, ew_node_param_info *out) {
    ew_node_sig s;
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    ew_result r = sig_for(type, method, &s);
    if (r != EW_OK) return r;
    if (index < 0 || index >= s.num_params) return EW_ERR_INVALID_ARGUMENT;
    const ew_nparam_desc *p = &s.params[index];
    memset(out, 0, sizeof *out);
    out->name = p->name;
    out->type = p->type;
    out->default_value = p->def;
    out->min_value = p->min;
    out->max_value = p->max;
    out->default_string = p->def_string ? p->def_string : "";
    memcpy(out->default_color, p->def_color, sizeof out->default_color);
    out->num_choices = ew_param_num_choices(&s, p);
    out->required = p->required;
    out->label = p->label ? p->label : p->name;
    out->hint = p->hint ? p->hint : "";
    if (p->type == EW_NODE_PARAM_ENUM) {
        /* the default's index, as a number too */
        for (int i = 0; i < out->num_choices; i++)
            if (!strcmp(ew_param_choice(&s, p, i), out->default_string)) out->default_value = i;
        out->max_value = out->num_choices > 0 ? out->num_choices - 1 : 0;
    }
    return EW_OK;
}

ew_result ew_node_type_param_choice(const char *type, const char *method, int32_t param, int32_t choice,
                                    const char **out) {
    ew_node_sig s;
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    ew_result r = sig_for(type, method, &s);
    if (r != EW_OK) return r;
    if (param < 0 || param >= s.num_params) return EW_ERR_INVALID_ARGUMENT;
    const char *c = ew_param_choice(&s, &s.params[param], choice);
    if (!c) return EW_ERR_INVALID_ARGUMENT;
    *out = c;
    return EW_OK;
}

ew_result ew_nodes_color_config(char *buf, size_t len) {
    if (!buf || !len) return EW_ERR_INVALID_ARGUMENT;
    ewcolor_config_name(buf, len);
    return EW_OK;
}
