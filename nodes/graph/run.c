/*
 * run.c — running a validated graph: frames one after the other, nodes in
 * plan order, image buffers from a pool (a buffer returns to the pool after
 * its last consumer, and a node may write over an input it is the last
 * consumer of), progress and cancellation, and the run's report.
 */
#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "graph.h"

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

ew_result ew_node_fail(ew_gnode *n, ew_result code, const char *fmt, ...) {
    char msg[1280];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return ew_graph_fail(n->g, code, "node '%s': %s", n->id, msg);
}

const ew_image *ew_node_in(const ew_gnode *n, const char *port) {
    int i = ew_sig_find_input(&n->sig, port);
    return i >= 0 && n->has_in[i] ? &n->in[i] : NULL;
}

int ew_node_output_wanted(const ew_gnode *n, int port) { return port >= 0 && n->num_consumers[port] > 0; }

/* A free buffer of at least `floats`: the smallest that fits, else grow the
 * largest free one, else a new one. Sizes repeat from frame to frame, so
 * after the first frame nothing is allocated. */
static int pool_get(ew_graph *g, size_t floats) {
    int best = -1, largest = -1;
    for (int i = 0; i < g->num_bufs; i++) {
        if (g->bufs[i].refs) continue;
        if (g->bufs[i].cap >= floats && (best < 0 || g->bufs[i].cap < g->bufs[best].cap)) best = i;
        if (largest < 0 || g->bufs[i].cap > g->bufs[largest].cap) largest = i;
    }
    if (best >= 0) return best;
    if (largest >= 0) {
        float *p = (float *)realloc(g->bufs[largest].data, floats * sizeof(float));
        if (!p) return -1;
        g->bufs[largest].data = p;
        g->bufs[largest].cap = floats;
        return largest;
    }
    if (g->num_bufs == g->cap_bufs) {
        int cap = g->cap_bufs ? g->cap_bufs * 2 : 8;
        ew_buffer *nb = (ew_buffer *)realloc(g->bufs, (size_t)cap * sizeof *nb);
        if (!nb) return -1;
        g->bufs = nb;
        g->cap_bufs = cap;
    }
    float *p = (float *)malloc(floats * sizeof(float));
    if (!p) return -1;
    g->bufs[g->num_bufs].data = p;
    g->bufs[g->num_bufs].cap = floats;
    g->bufs[g->num_bufs].refs = 0;
    return g->num_bufs++;
}

ew_result ew_run_output(ew_run *r, ew_gnode *n, int port, int w, int h, int c, ew_image *out) {
    ew_graph *g = r->g;
    if (port < 0 || port >= n->sig.num_outputs) return ew_node_fail(n, EW_ERR_INVALID_STATE, "no output %d", port);
    if (w <= 0 || h <= 0 || c < 1 || c > 4)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "output '%s' would be %dx%d with %d channels",
                            n->sig.outputs[port].name, w, h, c);
    const size_t floats = (size_t)w * (size_t)h * (size_t)c;
    int b = -1;
    int ip = n->sig.inplace_input;
    if (port == 0 && ip >= 0 && n->src_node[ip] >= 0 && n->has_in[ip]) {
        const ew_gnode *src = g->nodes[n->src_node[ip]];
        int sb = src->out_buf[n->src_port[ip]];
        const ew_image *in = &n->in[ip];
        if (sb >= 0 && g->bufs[sb].refs == 1 && in->width == w && in->height == h && in->channels == c) {
            b = sb;
            n->taken_input = ip;
        }
    }
    if (b < 0) {
        b = pool_get(g, floats);
        if (b < 0)
            return ew_node_fail(n, EW_ERR_OUT_OF_MEMORY, "out of memory for a %dx%d image with %d channels", w, h, c);
    }
    g->bufs[b].refs = n->num_consumers[port] > 0 ? n->num_consumers[port] : 1;
    n->out_buf[port] = b;
    n->has_out[port] = 1;
    n->out[port] = ew_image_packed(g->bufs[b].data, w, h, c);
    if (out) *out = n->out[port];
    return EW_OK;
}

int ew_run_progress(ew_run *r, double node_fraction) {
    ew_graph *g = r->g;
    if (!g->progress) return 1;
    if (node_fraction < 0.0) node_fraction = 0.0;
    if (node_fraction > 1.0) node_fraction = 1.0;
    double per_frame = ((double)r->node_index + node_fraction) / (double)(g->num_order ? g->num_order : 1);
    double f = ((double)r->frame_index + per_frame) / (double)(g->num_frames ? g->num_frames : 1);
    if (!g->progress(g->progress_user, f)) {
        r->cancelled = 1;
        return 0;
    }
    return 1;
}

/* The object under `key` of `parent`, made empty when it is not there yet. */
static json_t *child_object(json_t *parent, const char *key) {
    json_t *o = json_object_get(parent, key);
    if (!o) {
        o = json_object();
        json_object_set_new(parent, key, o);
    }
    return o;
}

void ew_run_report_number(ew_run *r, const ew_gnode *n, const char *key, double value) {
    json_t *frame = (json_t *)r->report_frame;
    if (!frame) return;
    json_t *node = child_object(child_object(frame, "metrics"), n->id);
    /* JSON has no infinity: an identical image's PSNR is null */
    json_object_set_new(node, key, isfinite(value) ? json_real(value) : json_null());
}

void ew_run_report_method(ew_run *r, const ew_gnode *n, const char *what) {
    json_t *frame = (json_t *)r->report_frame;
    if (!frame || !what) return;
    json_object_set_new(child_object(frame, "methods"), n->id, json_string(what));
}

void ew_run_report_written(ew_run *r, const char *path) {
    json_t *frame = (json_t *)r->report_frame;
    if (!frame) return;
    json_t *w = json_object_get(frame, "written");
    if (!w) {
        w = json_array();
        json_object_set_new(frame, "written", w);
    }
    json_array_append_new(w, json_string(path));
}

/* Inputs of a node from its sources' outputs, with the checks every node
 * needs: same size everywhere, enough channels. */
static ew_result gather(ew_graph *g, ew_gnode *n) {
    const ew_image *first = NULL;
    int first_port = -1;
    for (int p = 0; p < n->sig.num_inputs; p++) {
        n->has_in[p] = 0;
        if (n->src_node[p] < 0) continue;
        const ew_gnode *src = g->nodes[n->src_node[p]];
        int sp = n->src_port[p];
        if (!src->has_out[sp])
            return ew_node_fail(n, EW_ERR_INVALID_STATE, "input '%s': '%s.%s' produced nothing",
                                n->sig.inputs[p].name, src->id, src->sig.outputs[sp].name);
        n->in[p] = src->out[sp];
        n->has_in[p] = 1;
        n->in_samples[p] = src->out_samples[sp];
        if (n->in[p].channels < n->sig.inputs[p].min_channels)
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "input '%s' needs at least %d channels but '%s.%s' has %d",
                                n->sig.inputs[p].name, n->sig.inputs[p].min_channels, src->id,
                                src->sig.outputs[sp].name, n->in[p].channels);
        if (!first) {
            first = &n->in[p];
            first_port = p;
        } else if (n->in[p].width != first->width || n->in[p].height != first->height) {
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "input '%s' is %dx%d but input '%s' is %dx%d",
                                n->sig.inputs[p].name, n->in[p].width, n->in[p].height,
                                n->sig.inputs[first_port].name, first->width, first->height);
        }
    }
    return EW_OK;
}

/* Metadata a node did not set on its outputs flows through from its inputs. */
static void inherit_samples(ew_gnode *n) {
    int s = 0;
    for (int p = 0; p < n->sig.num_inputs; p++)
        if (n->has_in[p] && n->in_samples[p] > s) s = n->in_samples[p];
    for (int o = 0; o < n->sig.num_outputs; o++)
        if (n->has_out[o] && n->out_samples[o] == 0) n->out_samples[o] = s;
}

/* After a node: its inputs lose a consumer (an "output" node keeps its
 * input for ew_graph_get_output); outputs nobody consumes go back. */
static void release_after(ew_graph *g, ew_gnode *n) {
    int taken = n->taken_input;
    int is_output = !strcmp(n->type->name, "output");
    for (int p = 0; p < n->sig.num_inputs; p++) {
        if (!n->has_in[p] || n->src_node[p] < 0 || is_output) continue;
        if (p == taken) continue;
        int b = g->nodes[n->src_node[p]]->out_buf[n->src_port[p]];
        if (b >= 0 && g->bufs[b].refs > 0) g->bufs[b].refs--;
    }
    for (int o = 0; o < n->sig.num_outputs; o++)
        if (n->has_out[o] && n->num_consumers[o] == 0 && n->out_buf[o] >= 0) g->bufs[n->out_buf[o]].refs = 0;
}

static void reset_frame(ew_graph *g) {
    for (int i = 0; i < g->num_bufs; i++) g->bufs[i].refs = 0;
    for (int i = 0; i < g->num_nodes; i++) {
        ew_gnode *n = g->nodes[i];
        for (int p = 0; p < EW_SIG_MAX_PORTS; p++) {
            n->has_out[p] = 0;
            n->has_in[p] = 0;
            n->in_samples[p] = 0;
            n->out_samples[p] = 0;
            n->out_buf[p] = -1;
        }
    }
}

ew_result ew_graph_run(ew_graph *g) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    double t_start = now_s(), t_validate = 0.0;
    if (!g->validated) {
        ew_result v = ew_graph_validate(g);
        if (v != EW_OK) return v;
        t_validate = g->stats.validate_seconds;
    }
    g->err[0] = '\0';
    json_t *report = json_object();
    json_t *frames = json_array();
    json_object_set_new(report, "frames", frames);
    ew_run run;
    memset(&run, 0, sizeof run);
    run.g = g;
    ew_result res = EW_OK;
    double t_nodes = 0.0;
    g->stats.frames_done = 0;
    for (int k = 0; k < g->num_order && res == EW_OK; k++) {
        ew_gnode *n = g->nodes[g->order[k]];
        if (n->type->prepare) {
            double t0 = now_s();
            res = n->type->prepare(n, &run);
            t_nodes += now_s() - t0;
        }
    }
    for (int f = 0; f < g->num_frames && res == EW_OK; f++) {
        double tf = now_s();
        reset_frame(g);
        run.frame = g->frames[f];
        run.frame_index = f;
        json_t *fr = json_object();
        json_object_set_new(fr, "frame", json_integer(run.frame));
        json_array_append_new(frames, fr);
        run.report_frame = fr;
        for (int k = 0; k < g->num_order && res == EW_OK; k++) {
            ew_gnode *n = g->nodes[g->order[k]];
            run.node_index = k;
            if (!ew_run_progress(&run, 0.0)) {
                res = ew_graph_fail(g, EW_ERR_CANCELLED, "cancelled before node '%s' (frame %d)", n->id, run.frame);
                break;
            }
            res = gather(g, n);
            if (res != EW_OK) break;
            n->taken_input = -1;
            double t0 = now_s();
            res = n->type->execute(n, &run);
            t_nodes += now_s() - t0;
            if (res != EW_OK) {
                if (run.cancelled && res != EW_ERR_CANCELLED) res = EW_ERR_CANCELLED;
                if (res == EW_ERR_CANCELLED && !strstr(g->err, "cancel"))
                    ew_graph_fail(g, EW_ERR_CANCELLED, "cancelled in node '%s' (frame %d)", n->id, run.frame);
                break;
            }
            inherit_samples(n);
            release_after(g, n);
        }
        json_object_set_new(fr, "seconds", json_real(now_s() - tf));
        if (res == EW_OK) g->stats.frames_done++;
    }
    if (res == EW_OK && g->progress) g->progress(g->progress_user, 1.0);

    json_object_set_new(report, "frames_done", json_integer(g->stats.frames_done));
    json_object_set_new(report, "ok", json_boolean(res == EW_OK));
    if (res != EW_OK) json_object_set_new(report, "error", json_string(g->err));
    free(g->report);
    g->report = json_dumps(report, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(10));
    json_decref(report);

    int64_t bytes = 0;
    for (int i = 0; i < g->num_bufs; i++) bytes += (int64_t)g->bufs[i].cap * (int64_t)sizeof(float);
    g->stats.num_nodes = g->num_order;
    g->stats.planned_buffers = g->planned_buffers;
    g->stats.num_buffers = g->num_bufs;
    g->stats.buffer_bytes = bytes;
    double total = now_s() - t_start;
    g->stats.run_seconds = total - t_validate;
    g->stats.overhead_seconds = total - t_nodes;
    return res;
}
