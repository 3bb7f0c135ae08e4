/*
 * graph.h — the graph, its nodes, and what node implementations use while a
 * graph runs (inputs, parameters, output buffers, errors, progress).
 */
#ifndef EW_GRAPH_H
#define EW_GRAPH_H

#include <stddef.h>
#include <stdint.h>

#include "node_type.h"

/* A parameter as given (file, API or --set), checked at validation. */
typedef enum { EW_RAW_BOOL, EW_RAW_INT, EW_RAW_NUMBER, EW_RAW_STRING, EW_RAW_ARRAY, EW_RAW_TEXT, EW_RAW_OTHER } ew_raw_kind;

typedef struct ew_raw {
    char *name;
    ew_raw_kind kind;
    double num;       /* bool, int, number */
    char *str;        /* string, text */
    double arr[4];    /* array */
    int n;            /* array length (up to 4 kept; more is an error) */
} ew_raw;

/* A resolved parameter value. */
typedef struct ew_pvalue {
    double num;        /* bool (0/1), int, float, enum index */
    float color[4];
    const char *str;   /* enum choice, string (points into the raw or a static default) */
} ew_pvalue;

typedef struct ew_conn {
    char *dst_port;
    char *src_node;
    char *src_port; /* NULL: the source's only output */
} ew_conn;

typedef struct ew_gnode {
    struct ew_graph *g;
    char id[64];
    const ew_node_type *type;
    ew_raw *raw;
    int num_raw, cap_raw;
    ew_conn *conns;
    int num_conns, cap_conns;
    /* resolved by validation */
    ew_node_sig sig;
    ew_pvalue values[EW_SIG_MAX_PARAMS];
    int src_node[EW_SIG_MAX_PORTS], src_port[EW_SIG_MAX_PORTS]; /* per input; -1 = unconnected */
    int num_consumers[EW_SIG_MAX_PORTS];                        /* per output */
    int live;                                                   /* feeds a sink */
    /* caller memory of "input" / "output" nodes */
    ew_image ext;
    int has_ext;
    /* per frame */
    ew_image in[EW_SIG_MAX_PORTS];
    int has_in[EW_SIG_MAX_PORTS];
    ew_image out[EW_SIG_MAX_PORTS];
    int out_buf[EW_SIG_MAX_PORTS]; /* pool index, -1 = none/external */
    int has_out[EW_SIG_MAX_PORTS];
    int taken_input; /* the input whose buffer output 0 took over this frame, -1 none */
    /* Image metadata travelling with the pixels: the render's samples per
     * pixel (Cycles' "cycles.<layer>.samples"), 0 unknown. A read node sets
     * it on its outputs; any other node's outputs inherit the largest of
     * its inputs' unless the node set one; a denoiser whose "samples"
     * parameter is left at 0 takes it from its colour input. */
    int in_samples[EW_SIG_MAX_PORTS];
    int out_samples[EW_SIG_MAX_PORTS];
    void *state;  /* node implementation's, freed by type->release */
} ew_gnode;

typedef struct ew_buffer {
    float *data;
    size_t cap; /* floats */
    int refs;   /* consumers still to run (0 = free) */
} ew_buffer;

typedef struct ew_graph {
    ew_device *dev;
    int own_dev;
    char err[1536];
    char base_dir[4096]; /* relative paths of a loaded file are relative to this */
    ew_gnode **nodes;
    int num_nodes, cap_nodes;
    /* Open-addressing index of node ids (node index + 1, 0 empty), at most
     * half full: finding a node is O(1), so loading and checking a graph
     * stays linear in its nodes. */
    int *id_index;
    int id_index_cap;
    int frames_set, first_frame, last_frame;
    ew_progress_fn progress;
    void *progress_user;
    int validated; /* 0 after any change */
    /* plan */
    int *order;
    int num_order;
    int planned_buffers;
    int *frames;
    int num_frames;
    /* run */
    ew_buffer *bufs;
    int num_bufs, cap_bufs;
    char *report;
    ew_graph_stats stats;
} ew_graph;

/* What a running node sees of the run. */
typedef struct ew_run {
    ew_graph *g;
    int frame;       /* frame number */
    int frame_index; /* 0-based position in the run */
    int node_index;  /* position in the order, for progress */
    void *report_frame; /* json_t object of this frame */
    int cancelled;
} ew_run;

/* graph.c */
ew_result ew_graph_fail(ew_graph *g, ew_result code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
ew_gnode *ew_graph_find(const ew_graph *g, const char *id);
int ew_graph_index(const ew_graph *g, const char *id);
ew_result ew_graph_put_raw(ew_graph *g, const char *node, const ew_raw *value); /* copies; replaces same name */
void ew_graph_invalidate(ew_graph *g);
/* The node's value of parameter `name`: the resolved value after
 * validation (NULL if no such parameter). */
const ew_pvalue *ew_node_value(const ew_gnode *n, const char *name);
double ew_node_num(const ew_gnode *n, const char *name);
const char *ew_node_str(const ew_gnode *n, const char *name);
/* Join a relative path onto base_dir (copied when absolute or base empty). */
void ew_path_join(const char *base, const char *path, char *out, size_t len);

/* validate.c */
ew_result ew_graph_check_structure(ew_graph *g); /* no file access: what the fuzz target runs */
ew_result ew_graph_check_files(ew_graph *g);

/* plan.c: order, liveness, consumer counts, planned peak. */
ew_result ew_graph_plan(ew_graph *g);

/* frames.c */
int ew_path_has_pattern(const char *path);
/* Replace the frame pattern of the file name (a run of '#', or "%0Nd" /
 * "%d") with the frame number, zero-padded to the run's length or N.
 * Returns 0 when it does not fit. */
int ew_frame_path(const char *pattern, int frame, char *out, size_t len);
/* Frame numbers of files matching the pattern, sorted; *out malloc'ed. */
int ew_frames_on_disk(const char *pattern, int **out, int *count);

/* run.c, for node implementations */
ew_result ew_node_fail(ew_gnode *n, ew_result code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
const ew_image *ew_node_in(const ew_gnode *n, const char *port);
int ew_node_output_wanted(const ew_gnode *n, int port);
/* A packed w x h x c output buffer for output `port` (in place over the
 * type's inplace_input when this node is its last consumer). */
ew_result ew_run_output(ew_run *r, ew_gnode *n, int port, int w, int h, int c, ew_image *out);
/* Progress of the current node in [0,1]; returns 0 when cancelled. */
int ew_run_progress(ew_run *r, double node_fraction);
void ew_run_report_number(ew_run *r, const ew_gnode *n, const char *key, double value);
void ew_run_report_written(ew_run *r, const char *path);
/* What node n ran this frame, in words (a denoiser's ew_denoiser_describe), under "methods". */
void ew_run_report_method(ew_run *r, const ew_gnode *n, const char *what);

static inline float *ew_px(const ew_image *im, int x, int y) {
    int64_t ps = im->pixel_stride ? im->pixel_stride : (int64_t)im->channels * (int64_t)sizeof(float);
    int64_t rs = im->row_stride ? im->row_stride : ps * im->width;
    return (float *)((char *)im->data + (int64_t)y * rs + (int64_t)x * ps);
}

#endif
