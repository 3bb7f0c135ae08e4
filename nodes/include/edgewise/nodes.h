/*
 * nodes.h — the public C API of the node layer (libedgewise_nodes).
 *
 * Node types are static descriptors: inputs and outputs (named passes),
 * parameters {name, type, default, min, max, label, hint}. Nodes that run a
 * library method (denoise, filter, dof, bilateral, pyramid, atrous) take
 * their images and parameters from libedgewise's introspection (ew_method_*)
 * at run time, so a method added to the library shows up here unchanged.
 *
 * A graph is a DAG of nodes. Build it from a JSON file (docs/graphs.md) or
 * with the calls below, then validate and run. Parameters and connections
 * are checked at validation, so they may be given in any order; every error
 * names the node and the parameter or port (ew_graph_last_error).
 *
 * Same conventions as edgewise.h: results are ew_result, outputs are the last
 * arguments, destroy(NULL) is a no-op, nothing is printed. A graph is used
 * by one thread at a time.
 */
#ifndef EDGEWISE_NODES_H
#define EDGEWISE_NODES_H

#include "edgewise/edgewise.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32)
#define EW_NODES_API __declspec(dllexport)
#else
#define EW_NODES_API __attribute__((visibility("default")))
#endif

/* ---- node types --------------------------------------------------------- */
typedef enum ew_node_param_type {
    EW_NODE_PARAM_BOOL = 0,
    EW_NODE_PARAM_INT = 1,
    EW_NODE_PARAM_FLOAT = 2,
    EW_NODE_PARAM_ENUM = 3,   /* one of a list of names (ew_node_type_param_choice) */
    EW_NODE_PARAM_STRING = 4,
    EW_NODE_PARAM_COLOR = 5   /* RGBA, 4 floats */
} ew_node_param_type;

typedef struct ew_node_type_info {
    const char *name;
    int32_t version;
    const char *category;       /* "io", "denoise", "filter", "color", "math", "analysis", "time" */
    const char *summary;
    const char *library_kind;   /* "denoiser"/"filter" for library-backed nodes, else NULL */
    const char *library_method; /* the method this node runs (the chosen one for denoise/filter) */
    int32_t available;          /* 0 when this libedgewise lacks the method (the node fails to validate) */
    int32_t num_inputs, num_outputs, num_params;
} ew_node_type_info;

typedef struct ew_node_port_info {
    const char *name;
    const char *pass;         /* "any", "color", "albedo", "normal", "depth", "vector", "variance", "mask" */
    int32_t min_channels;
    int32_t required;         /* inputs: validation fails without a connection */
    const char *hint;
} ew_node_port_info;

typedef struct ew_node_param_info {
    const char *name;
    ew_node_param_type type;
    double default_value, min_value, max_value; /* bool/int/float */
    const char *default_string;                 /* enum/string ("" if none) */
    float default_color[4];                     /* color */
    int32_t num_choices;                        /* enum */
    int32_t required;                           /* string: must be given (e.g. a path) */
    const char *label;
    const char *hint;
} ew_node_param_info;

/* Node types in listing order; name NULL for an index out of range. */
EW_NODES_API int32_t ew_node_type_count(void);
EW_NODES_API const char *ew_node_type_name(int32_t index);
/* `method` picks the library method of "denoise"/"filter" nodes (NULL: the
 * default, the library's first); other types ignore it. Ports and parameters
 * of those two depend on the method. Unknown type or method, index out of
 * range: EW_ERR_INVALID_ARGUMENT. Strings are static. */
EW_NODES_API ew_result ew_node_type_get(const char *type, const char *method, ew_node_type_info *out);
EW_NODES_API ew_result ew_node_type_input(const char *type, const char *method, int32_t index, ew_node_port_info *out);
EW_NODES_API ew_result ew_node_type_output(const char *type, const char *method, int32_t index, ew_node_port_info *out);
EW_NODES_API ew_result ew_node_type_param(const char *type, const char *method, int32_t index, ew_node_param_info *out);
EW_NODES_API ew_result ew_node_type_param_choice(const char *type, const char *method, int32_t param, int32_t choice,
                                                 const char **out);

/* ---- graphs ------------------------------------------------------------- */
typedef struct ew_graph ew_graph;

/* dev may be NULL: the graph then creates (and owns) a default device. */
EW_NODES_API ew_result ew_graph_create(ew_device *dev, ew_graph **out);
EW_NODES_API void ew_graph_destroy(ew_graph *g);
/* Message of the last failure on the graph ("" if none); never NULL. */
EW_NODES_API const char *ew_graph_last_error(const ew_graph *g);

/* Add the nodes, parameters, connections and frame range of a graph file
 * (JSON, docs/graphs.md) to an empty graph. Relative paths in the file are
 * relative to the file's directory (load_string: to base_dir, NULL = cwd). */
EW_NODES_API ew_result ew_graph_load_file(ew_graph *g, const char *path);
EW_NODES_API ew_result ew_graph_load_string(ew_graph *g, const char *json, const char *base_dir);

/* id: letters, digits, '_' and '-', at most 63 chars, unique in the graph. */
EW_NODES_API ew_result ew_graph_add_node(ew_graph *g, const char *id, const char *type);
/* Parameters, kept as given and checked against the node's type at
 * validation. set_param takes text converted by the parameter's type ("8",
 * "true", "bgrid", "0.5,0.5,0.5"); the typed setters check the type too.
 * Setting a parameter again replaces the earlier value. */
EW_NODES_API ew_result ew_graph_set_param(ew_graph *g, const char *node, const char *param, const char *text);
/* "node.param=value", as `edgewise graph run --set` takes it. */
EW_NODES_API ew_result ew_graph_set_assignment(ew_graph *g, const char *assignment);
EW_NODES_API ew_result ew_graph_set_bool(ew_graph *g, const char *node, const char *param, int32_t value);
EW_NODES_API ew_result ew_graph_set_int(ew_graph *g, const char *node, const char *param, int32_t value);
EW_NODES_API ew_result ew_graph_set_float(ew_graph *g, const char *node, const char *param, double value);
EW_NODES_API ew_result ew_graph_set_string(ew_graph *g, const char *node, const char *param, const char *value);
EW_NODES_API ew_result ew_graph_set_color(ew_graph *g, const char *node, const char *param, const float rgba[4]);
/* Connect an output port to an input port (an input takes one connection;
 * connecting again replaces it). src_port NULL: the node's only output. */
EW_NODES_API ew_result ew_graph_connect(ew_graph *g, const char *src_node, const char *src_port, const char *dst_node,
                                        const char *dst_port);
/* Frames to run (inclusive). Without a range, a read path with a '#' frame
 * pattern runs every frame found on disk; otherwise one frame, number 1. */
EW_NODES_API ew_result ew_graph_set_frames(ew_graph *g, int32_t first, int32_t last);

/* Pixels of an "input" node: a caller view, read (never written) while the
 * graph runs; the pixels are not copied. NULL unsets. */
EW_NODES_API ew_result ew_graph_set_input(ew_graph *g, const char *node, const ew_image *view);
/* Where an "output" node puts its result: the graph copies each frame's
 * result into this caller view (size and channels must match). NULL: keep
 * it in graph memory only (ew_graph_get_output). */
EW_NODES_API ew_result ew_graph_set_output(ew_graph *g, const char *node, const ew_image *view);
/* After a run: a packed view of an "output" node's result (the last frame)
 * in graph memory, valid until the next run, change or destroy. */
EW_NODES_API ew_result ew_graph_get_output(const ew_graph *g, const char *node, ew_image *out);

/* Called with the fraction of the whole run (all frames); return 0 to
 * cancel (the run then fails with EW_ERR_CANCELLED). */
EW_NODES_API ew_result ew_graph_set_progress(ew_graph *g, ew_progress_fn fn, void *user);

/* Check everything that can be checked before running: node types,
 * parameters (type, range, enum names), connections (pass types), required
 * inputs, cycles, library methods, frame patterns (every frame's file must
 * exist), passes of the first frame's input files, writable output
 * directories and that no write would replace an input of the graph.
 * ew_graph_run validates first when anything changed since. */
EW_NODES_API ew_result ew_graph_validate(ew_graph *g);
/* For a file a caller writes beside the run (the CLI's --report): refuse
 * (EW_ERR_INVALID_ARGUMENT, naming the node and frame) a path that any
 * frame of the validated graph reads or writes, compared by device and
 * inode when both exist, else by resolved path. */
EW_NODES_API ew_result ew_graph_check_side_file(ew_graph *g, const char *path);
/* Run every frame, streaming: one frame in memory at a time, buffers reused
 * after their last consumer. A failure stops the run; frames already
 * written stay. */
EW_NODES_API ew_result ew_graph_run(ew_graph *g);

/* Remove the temporaries of the image writes this library is doing now
 * (".<name>.tmp-XXXXXX.<ext>" beside an output). Async-signal-safe: for
 * a SIGINT/SIGTERM handler that then ends the process. */
EW_NODES_API void ew_nodes_remove_temporaries(void);

/* JSON text describing the last run: frames, files written, metrics
 * ("{}" before any run). Valid until the next run or destroy. */
EW_NODES_API const char *ew_graph_report(const ew_graph *g);

typedef struct ew_graph_stats {
    int32_t num_nodes;        /* nodes that run (those that feed a sink) */
    int32_t planned_buffers;  /* most images alive at once, as planned */
    int32_t num_buffers;      /* image buffers allocated by the last run */
    int64_t buffer_bytes;     /* their total size */
    int32_t frames_done;
    double validate_seconds;  /* last validation (types, plan, file checks) */
    double run_seconds;       /* last run, validation excluded */
    double overhead_seconds;  /* part of run_seconds spent in the graph itself */
} ew_graph_stats;
EW_NODES_API ew_result ew_graph_get_stats(const ew_graph *g, ew_graph_stats *out);
/* Frames the next run runs, once validated (0 before, or for NULL). */
EW_NODES_API int32_t ew_graph_frame_count(const ew_graph *g);

/* ---- image files (what Python's edgewise.read / write use) -------------- */
/* A whole image file in memory (EXR, multilayer EXR, PNG, TIFF, JPEG) with
 * its layers, passes and header; pixels as float. Channel names follow
 * Blender's multilayer EXR, "<layer>.<pass>.<component>"; a plain RGB(A)
 * file is layer "" with pass "". Failures return a code and a one-line
 * message in err (errlen bytes). */
typedef struct ew_image_file ew_image_file;
EW_NODES_API ew_result ew_image_file_read(const char *path, ew_image_file **out, char *err, size_t errlen);
EW_NODES_API ew_result ew_image_file_create(int32_t width, int32_t height, ew_image_file **out, char *err,
                                            size_t errlen);
EW_NODES_API void ew_image_file_destroy(ew_image_file *f);
/* JSON: {"width", "height", "layers": {layer: {"passes": {pass: "RGBA"},
 * "color": the pass the file shows, "noisy"/"albedo"/"normal"/"depth": what
 * a denoiser reads}}, "attributes": {Cycles' sample counts, compression...}}.
 * Valid until the file changes or is destroyed. */
EW_NODES_API const char *ew_image_file_describe(ew_image_file *f);
/* Copy a pass into / out of a packed view of the file's size with one
 * channel per letter of comps ("RGBA", "XYZ", "Z"...). set_pass replaces the
 * pass's channels or adds them. */
EW_NODES_API ew_result ew_image_file_get_pass(const ew_image_file *f, const char *layer, const char *pass,
                                              const char *comps, const ew_image *dst, char *err, size_t errlen);
EW_NODES_API ew_result ew_image_file_set_pass(ew_image_file *f, const char *layer, const char *pass, const char *comps,
                                              const ew_image *src, char *err, size_t errlen);
EW_NODES_API ew_result ew_image_file_set_attribute(ew_image_file *f, const char *name, const char *value);
/* Write atomically. pixel_type: 0 each pass as read (new ones half), 1
 * half, 2 float. EXR keeps every layer, pass and header entry; PNG/TIFF/JPEG
 * take pass `pass` of `layer` only, values as they are. Never over the file
 * it was read from. */
EW_NODES_API ew_result ew_image_file_write(const ew_image_file *f, const char *path, int32_t pixel_type,
                                           const char *layer, const char *pass, char *err, size_t errlen);

/* Which OpenColorIO config the colour nodes use, e.g. "$OCIO=/path" or
 * "Blender: /usr/share/blender/.../config.ocio" or "built-in fallback (raw,
 * sRGB)". Copied into buf. */
EW_NODES_API ew_result ew_nodes_color_config(char *buf, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* EDGEWISE_NODES_H */
