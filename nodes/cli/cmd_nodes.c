/*
 * edgewise nodes — every node type with its ports and parameters, generated
 * from the node descriptors (and, for library nodes, the library's own
 * introspection): never a hand-written list.
 */
#include <jansson.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "edgewise/nodes.h"

static const char help[] =
    "usage: edgewise nodes [TYPE] [--json]\n"
    "\n"
    "List every node type a graph file can use (or one), with its inputs, outputs\n"
    "and parameters: type, default, range and what it does. Nodes that run a\n"
    "library method list the method's own parameters; 'denoise' and 'filter' list\n"
    "them for every method. --json prints the same as JSON.\n";

static const char *type_word(ew_node_param_type t) {
    static const char *const w[] = {"bool", "int", "float", "enum", "string", "color"};
    return (unsigned)t < 6 ? w[t] : "?";
}

static void print_ports(const char *type, const char *method, int outputs, int n) {
    if (!n) return;
    printf("    %s:\n", outputs ? "outputs" : "inputs");
    for (int i = 0; i < n; i++) {
        ew_node_port_info p;
        if ((outputs ? ew_node_type_output : ew_node_type_input)(type, method, i, &p) != EW_OK) continue;
        char what[64];
        snprintf(what, sizeof what, "%s, %d+ ch%s", p.pass, p.min_channels, p.required ? ", required" : "");
        printf("      %-18s %-26s %s\n", p.name, what, p.hint);
    }
}

static void print_params(const char *type, const char *method, int first, int n) {
    if (first >= n) return;
    printf("    parameters:\n");
    for (int i = first; i < n; i++) {
        ew_node_param_info p;
        if (ew_node_type_param(type, method, i, &p) != EW_OK) continue;
        char what[160];
        switch (p.type) {
        case EW_NODE_PARAM_BOOL: snprintf(what, sizeof what, "bool = %s", p.default_value ? "true" : "false"); break;
        case EW_NODE_PARAM_INT:
        case EW_NODE_PARAM_FLOAT:
            snprintf(what, sizeof what, "%s = %g [%g, %g]", type_word(p.type), p.default_value, p.min_value, p.max_value);
            break;
        case EW_NODE_PARAM_ENUM: {
            size_t used = (size_t)snprintf(what, sizeof what, "enum = %s {", p.default_string);
            for (int c = 0; c < p.num_choices && used < sizeof what; c++) {
                const char *name = NULL;
                ew_node_type_param_choice(type, method, i, c, &name);
                used += (size_t)snprintf(what + used, sizeof what - used, "%s%s", c ? ", " : "", name ? name : "?");
            }
            if (used < sizeof what) snprintf(what + used, sizeof what - used, "}");
            break;
        }
        case EW_NODE_PARAM_STRING:
            if (p.required) snprintf(what, sizeof what, "string, required");
            else snprintf(what, sizeof what, "string = \"%s\"", p.default_string);
            break;
        default:
            snprintf(what, sizeof what, "color = [%g, %g, %g, %g]", (double)p.default_color[0],
                     (double)p.default_color[1], (double)p.default_color[2], (double)p.default_color[3]);
        }
        printf("      %-18s %-26s %s\n", p.name, what, p.hint);
    }
}

static void print_type(const char *type) {
    ew_node_type_info t;
    if (ew_node_type_get(type, NULL, &t) != EW_OK) return;
    printf("%s (v%d, %s): %s\n", t.name, (int)t.version, t.category, t.summary);
    if (t.library_kind && !t.available) {
        printf("    unavailable: this libedgewise has no %s '%s'\n", t.library_kind,
               t.library_method ? t.library_method : "?");
    }
    int per_method = t.library_kind && !strcmp(t.name, t.library_kind[0] == 'd' ? "denoise" : "filter");
    if (!per_method) {
        print_ports(type, NULL, 0, t.num_inputs);
        print_ports(type, NULL, 1, t.num_outputs);
        print_params(type, NULL, 0, t.num_params);
        return;
    }
    /* the selector, then every method with its own ports and parameters */
    print_params(type, NULL, 0, 1);
    ew_node_param_info sel;
    ew_node_type_param(type, NULL, 0, &sel);
    for (int c = 0; c < sel.num_choices; c++) {
        const char *m = NULL;
        if (ew_node_type_param_choice(type, NULL, 0, c, &m) != EW_OK) continue;
        ew_node_type_info mt;
        if (ew_node_type_get(type, m, &mt) != EW_OK) continue;
        printf("  with %s = %s:\n", sel.name, m);
        print_ports(type, m, 0, mt.num_inputs);
        print_ports(type, m, 1, mt.num_outputs);
        print_params(type, m, 1, mt.num_params);
    }
}

static json_t *node_json(const char *type, const char *method) {
    ew_node_type_info t;
    if (ew_node_type_get(type, method, &t) != EW_OK) return json_null();
    json_t *o = json_object();
    json_object_set_new(o, "name", json_string(t.name));
    json_object_set_new(o, "version", json_integer(t.version));
    json_object_set_new(o, "category", json_string(t.category));
    json_object_set_new(o, "summary", json_string(t.summary));
    if (t.library_kind) {
        json_object_set_new(o, "library_kind", json_string(t.library_kind));
        json_object_set_new(o, "library_method", t.library_method ? json_string(t.library_method) : json_null());
    }
    json_object_set_new(o, "available", json_boolean(t.available));
    for (int side = 0; side < 2; side++) {
        json_t *ports = json_array();
        for (int i = 0; i < (side ? t.num_outputs : t.num_inputs); i++) {
            ew_node_port_info p;
            if ((side ? ew_node_type_output : ew_node_type_input)(type, method, i, &p) != EW_OK) continue;
            json_array_append_new(ports, json_pack("{s:s, s:s, s:i, s:b, s:s}", "name", p.name, "pass", p.pass,
                                                   "min_channels", (int)p.min_channels, "required", (int)p.required,
                                                   "hint", p.hint));
        }
        json_object_set_new(o, side ? "outputs" : "inputs", ports);
    }
    json_t *params = json_array();
    for (int i = 0; i < t.num_params; i++) {
        ew_node_param_info p;
        if (ew_node_type_param(type, method, i, &p) != EW_OK) continue;
        json_t *jp = json_pack("{s:s, s:s, s:s, s:s}", "name", p.name, "type", type_word(p.type), "label", p.label,
                               "hint", p.hint);
        switch (p.type) {
        case EW_NODE_PARAM_BOOL: json_object_set_new(jp, "default", json_boolean(p.default_value != 0.0)); break;
        case EW_NODE_PARAM_INT:
        case EW_NODE_PARAM_FLOAT:
            json_object_set_new(jp, "default", json_real(p.default_value));
            json_object_set_new(jp, "min", json_real(p.min_value));
            json_object_set_new(jp, "max", json_real(p.max_value));
            break;
        case EW_NODE_PARAM_ENUM: {
            json_t *ch = json_array();
            for (int c = 0; c < p.num_choices; c++) {
                const char *name = NULL;
                if (ew_node_type_param_choice(type, method, i, c, &name) == EW_OK) json_array_append_new(ch, json_string(name));
            }
            json_object_set_new(jp, "choices", ch);
            json_object_set_new(jp, "default", json_string(p.default_string));
            break;
        }
        case EW_NODE_PARAM_STRING:
            json_object_set_new(jp, "default", json_string(p.default_string));
            json_object_set_new(jp, "required", json_boolean(p.required));
            break;
        default:
            json_object_set_new(jp, "default", json_pack("[f, f, f, f]", (double)p.default_color[0],
                                                         (double)p.default_color[1], (double)p.default_color[2],
                                                         (double)p.default_color[3]));
        }
        json_array_append_new(params, jp);
    }
    json_object_set_new(o, "params", params);
    return o;
}

static json_t *node_json_all(const char *type) {
    json_t *o = node_json(type, NULL);
    ew_node_type_info t;
    if (ew_node_type_get(type, NULL, &t) != EW_OK || !t.library_kind || !json_is_object(o)) return o;
    if (strcmp(t.name, "denoise") != 0 && strcmp(t.name, "filter") != 0) return o;
    json_t *methods = json_object();
    ew_node_param_info sel;
    ew_node_type_param(type, NULL, 0, &sel);
    for (int c = 0; c < sel.num_choices; c++) {
        const char *m = NULL;
        if (ew_node_type_param_choice(type, NULL, 0, c, &m) == EW_OK) json_object_set_new(methods, m, node_json(type, m));
    }
    json_object_set_new(o, "methods", methods);
    return o;
}

int cmd_nodes(int argc, char **argv) {
    const char *only = NULL;
    int as_json = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            fputs(help, stdout);
            return 0;
        } else if (!strcmp(argv[i], "--json")) {
            as_json = 1;
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise nodes --help')\n", argv[i]);
            return EW_EXIT_USAGE;
        } else if (!only) {
            only = argv[i];
        } else {
            fprintf(stderr, "edgewise: unexpected argument '%s'\n", argv[i]);
            return EW_EXIT_USAGE;
        }
    }
    ew_node_type_info t;
    if (only && ew_node_type_get(only, NULL, &t) != EW_OK) {
        char names[1024];
        size_t used = 0;
        names[0] = '\0';
        for (int i = 0; i < ew_node_type_count() && used < sizeof names; i++)
            used += (size_t)snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", ew_node_type_name(i));
        fprintf(stderr, "edgewise: unknown node type '%s' (types: %s)\n", only, names);
        return EW_EXIT_USAGE;
    }
    if (as_json) {
        json_t *root = json_object();
        for (int i = 0; i < ew_node_type_count(); i++)
            if (!only || !strcmp(only, ew_node_type_name(i)))
                json_object_set_new(root, ew_node_type_name(i), node_json_all(ew_node_type_name(i)));
        char *s = json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        if (s) puts(s);
        free(s);
        json_decref(root);
        return 0;
    }
    char config[512];
    ew_nodes_color_config(config, sizeof config);
    if (!only) printf("%d node types (colour nodes use the OpenColorIO config %s)\n\n", (int)ew_node_type_count(), config);
    for (int i = 0; i < ew_node_type_count(); i++)
        if (!only || !strcmp(only, ew_node_type_name(i))) {
            print_type(ew_node_type_name(i));
            if (!only) putchar('\n');
        }
    return 0;
}
