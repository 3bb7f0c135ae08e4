/*
 * node_type.h — node type descriptors and the signature of a node (its
 * ports and parameters once the library method is known).
 *
 * A descriptor declares its own ports and parameters statically. A node that
 * runs a library method gets the method's images and parameters appended
 * from libedgewise's introspection when the signature is built, so a
 * parameter of a library method is declared once, in the library.
 */
#ifndef EW_NODE_TYPE_H
#define EW_NODE_TYPE_H

#include "edgewise/nodes.h"

/* Pass types carried by ports; connections are checked against them. */
typedef enum ew_pass {
    EW_PASS_ANY = 0,
    EW_PASS_COLOR,
    EW_PASS_ALBEDO,
    EW_PASS_NORMAL,
    EW_PASS_DEPTH,
    EW_PASS_VECTOR,
    EW_PASS_VARIANCE,
    EW_PASS_MASK
} ew_pass;

const char *ew_pass_name(ew_pass p);
/* 1 when an output of pass `src` may feed an input of pass `dst`. */
int ew_pass_compatible(ew_pass src, ew_pass dst);

typedef struct ew_port_desc {
    const char *name;
    ew_pass pass;
    int min_channels;
    int required;
    const char *hint;
} ew_port_desc;

typedef struct ew_nparam_desc {
    const char *name;
    ew_node_param_type type;
    double def, min, max;
    const char *def_string;      /* enum / string */
    float def_color[4];
    const char *const *choices;  /* enum: NULL-terminated; NULL = the library's methods of lib_kind */
    int required;
    int is_path; /* a file path: relative ones in a graph file are relative to the file */
    const char *label;
    const char *hint;
} ew_nparam_desc;

struct ew_gnode;
struct ew_run;

typedef struct ew_node_type {
    const char *name;
    int version;
    const char *category;
    const char *summary;
    /* Library-backed nodes: kind ("denoiser"/"filter") and a fixed method,
     * or NULL method = chosen by the "method" enum parameter. */
    const char *lib_kind;
    const char *lib_method;
    const ew_port_desc *inputs;
    int num_inputs;
    const ew_port_desc *outputs;
    int num_outputs;
    const ew_nparam_desc *params;
    int num_params;
    /* Input whose buffer output 0 may take over when this node is its last
     * consumer (same size and channels), -1 if none. */
    int inplace_input;
    int is_sink; /* runs even with no consumer: write, output, metrics */
    /* Validation hooks, parameters resolved: without file access (value
     * checks the descriptor cannot express), and with it (inputs exist). */
    ew_result (*check)(struct ew_gnode *n);
    ew_result (*check_files)(struct ew_gnode *n);
    /* Once per run, after validation (open files, build processors...). */
    ew_result (*prepare)(struct ew_gnode *n, struct ew_run *r);
    /* Once per frame, inputs ready; allocate outputs with ew_run_output. */
    ew_result (*execute)(struct ew_gnode *n, struct ew_run *r);
    void (*release)(struct ew_gnode *n); /* free n->state */
} ew_node_type;

/* Registry (node_registry.c), in listing order, NULL-terminated. */
extern const ew_node_type *const ew_node_types[];
const ew_node_type *ew_node_type_find(const char *name);
int ew_node_type_total(void);
/* "a, b, c" of every node type name. */
void ew_node_type_list(char *buf, size_t len);

#define EW_SIG_MAX_PORTS 16
#define EW_SIG_MAX_PARAMS 48

/* The ports and parameters of a node of `type` running `method`. */
typedef struct ew_node_sig {
    const ew_node_type *type;
    const char *method; /* library method name (static library string) or NULL */
    int available;      /* 0: the library lacks the method */
    ew_port_desc inputs[EW_SIG_MAX_PORTS];
    int num_inputs;
    ew_port_desc outputs[EW_SIG_MAX_PORTS];
    int num_outputs;
    ew_nparam_desc params[EW_SIG_MAX_PARAMS];
    int num_params;
    int num_static_params; /* params[0..num_static_params) are the type's own */
    /* For each parameter: 1 + its index among the library method's
     * parameters when it is one of the library's enums (choices come from
     * ew_method_param_choice), else 0. */
    int lib_enum[EW_SIG_MAX_PARAMS];
    int inplace_input;
} ew_node_sig;

/* Build the signature; method NULL = the default (the library's first of
 * lib_kind). Returns 0 when `method` names no method of lib_kind (sig is then
 * the type's own ports and parameters only). */
int ew_node_sig_build(const ew_node_type *type, const char *method, ew_node_sig *sig);
int ew_sig_find_input(const ew_node_sig *s, const char *name);
int ew_sig_find_output(const ew_node_sig *s, const char *name);
int ew_sig_find_param(const ew_node_sig *s, const char *name);
/* Enum choices: count and the i-th name (the library's methods when
 * choices == NULL, a library enum's names when sig->lib_enum says so). */
int ew_param_num_choices(const ew_node_sig *s, const ew_nparam_desc *p);
const char *ew_param_choice(const ew_node_sig *s, const ew_nparam_desc *p, int i);
/* "a, b, c" lists for messages. */
void ew_sig_list_params(const ew_node_sig *s, char *buf, size_t len);
void ew_sig_list_ports(const ew_node_sig *s, int outputs, char *buf, size_t len);
void ew_lib_list_methods(const char *kind, char *buf, size_t len);

#endif
