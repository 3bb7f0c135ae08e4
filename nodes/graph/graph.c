/*
 * graph.c — building a graph: nodes, parameters as given, connections,
 * caller images, errors. Everything is checked later by validation so that a
 * graph can be built in any order.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

ew_result ew_graph_fail(ew_graph *g, ew_result code, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(g->err, sizeof g->err, fmt, ap);
    va_end(ap);
    return code;
}

static char *dup_str(const char *s) {
    if (!s) return NULL;
    size_t n = strlen(s) + 1;
    char *d = (char *)malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}

ew_result ew_graph_create(ew_device *dev, ew_graph **out) {
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    *out = NULL;
    ew_graph *g = (ew_graph *)calloc(1, sizeof *g);
    if (!g) return EW_ERR_OUT_OF_MEMORY;
    if (!dev) {
        ew_device_desc desc = EW_DEVICE_DESC_INIT;
        ew_result r = ew_device_create(&desc, &g->dev);
        if (r != EW_OK) {
            free(g);
            return r;
        }
        g->own_dev = 1;
    } else {
        g->dev = dev;
        ew_device_retain(dev); /* the caller may destroy its device first */
    }
    *out = g;
    return EW_OK;
}

static void free_node(ew_gnode *n) {
    if (!n) return;
    if (n->state && n->type->release) n->type->release(n);
    for (int i = 0; i < n->num_raw; i++) {
        free(n->raw[i].name);
        free(n->raw[i].str);
    }
    free(n->raw);
    for (int i = 0; i < n->num_conns; i++) {
        free(n->conns[i].dst_port);
        free(n->conns[i].src_node);
        free(n->conns[i].src_port);
    }
    free(n->conns);
    free(n);
}

void ew_graph_destroy(ew_graph *g) {
    if (!g) return;
    for (int i = 0; i < g->num_nodes; i++) free_node(g->nodes[i]);
    free(g->nodes);
    free(g->id_index);
    free(g->order);
    free(g->frames);
    for (int i = 0; i < g->num_bufs; i++) free(g->bufs[i].data);
    free(g->bufs);
    free(g->report);
    ew_device_destroy(g->dev); /* our device, or our reference to the caller's */
    free(g);
}

const char *ew_graph_last_error(const ew_graph *g) { return g ? g->err : "no graph"; }

void ew_graph_invalidate(ew_graph *g) { g->validated = 0; }

ew_gnode *ew_graph_find(const ew_graph *g, const char *id) {
    int i = ew_graph_index(g, id);
    return i >= 0 ? g->nodes[i] : NULL;
}

static unsigned long id_hash(const char *s) {
    unsigned long h = 14695981039346656037UL; /* FNV-1a */
    for (; *s; s++) h = (h ^ (unsigned char)*s) * 1099511628211UL;
    return h;
}

int ew_graph_index(const ew_graph *g, const char *id) {
    if (!id || !g->id_index) return -1;
    const unsigned long mask = (unsigned long)g->id_index_cap - 1;
    for (unsigned long k = id_hash(id) & mask;; k = (k + 1) & mask) {
        int v = g->id_index[k];
        if (v == 0) return -1;
        if (!strcmp(g->nodes[v - 1]->id, id)) return v - 1;
    }
}

/* Room for one more id in the index (rebuilt twice as large when half full). */
static int index_reserve(ew_graph *g) {
    if ((g->num_nodes + 1) * 2 <= g->id_index_cap) return 0;
    int cap = g->id_index_cap ? g->id_index_cap * 2 : 64;
    int *t = (int *)calloc((size_t)cap, sizeof *t);
    if (!t) return -1;
    for (int i = 0; i < g->num_nodes; i++) {
        unsigned long k = id_hash(g->nodes[i]->id) & (unsigned long)(cap - 1);
        while (t[k]) k = (k + 1) & (unsigned long)(cap - 1);
        t[k] = i + 1;
    }
    free(g->id_index);
    g->id_index = t;
    g->id_index_cap = cap;
    return 0;
}

static int valid_id(const char *id) {
    size_t n = strlen(id);
    if (n == 0 || n > 63) return 0;
    for (size_t i = 0; i < n; i++)
        if (!isalnum((unsigned char)id[i]) && id[i] != '_' && id[i] != '-') return 0;
    return 1;
}

ew_result ew_graph_add_node(ew_graph *g, const char *id, const char *type) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    g->err[0] = '\0';
    if (!id || !valid_id(id))
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                             "node id '%.80s' is not valid: use 1 to 63 letters, digits, '_' or '-'", id ? id : "(null)");
    if (ew_graph_find(g, id)) return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' is defined twice", id);
    const ew_node_type *t = ew_node_type_find(type);
    if (!t) {
        char names[1024];
        ew_node_type_list(names, sizeof names);
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': unknown node type '%.80s' (types: %s)", id,
                             type ? type : "(null)", names);
    }
    if (index_reserve(g) != 0) return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    if (g->num_nodes == g->cap_nodes) {
        int cap = g->cap_nodes ? g->cap_nodes * 2 : 8;
        ew_gnode **nn = (ew_gnode **)realloc(g->nodes, (size_t)cap * sizeof *nn);
        if (!nn) return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
        g->nodes = nn;
        g->cap_nodes = cap;
    }
    ew_gnode *n = (ew_gnode *)calloc(1, sizeof *n);
    if (!n) return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    n->g = g;
    snprintf(n->id, sizeof n->id, "%s", id);
    n->type = t;
    n->taken_input = -1;
    g->nodes[g->num_nodes] = n;
    {
        const unsigned long mask = (unsigned long)g->id_index_cap - 1;
        unsigned long k = id_hash(n->id) & mask;
        while (g->id_index[k]) k = (k + 1) & mask;
        g->id_index[k] = g->num_nodes + 1;
    }
    g->num_nodes++;
    ew_graph_invalidate(g);
    return EW_OK;
}

static ew_gnode *need_node(ew_graph *g, const char *node) {
    ew_gnode *n = ew_graph_find(g, node);
    if (!n) ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "no node '%.80s' in the graph", node ? node : "(null)");
    return n;
}

ew_result ew_graph_put_raw(ew_graph *g, const char *node, const ew_raw *v) {
    g->err[0] = '\0';
    ew_gnode *n = need_node(g, node);
    if (!n) return EW_ERR_INVALID_ARGUMENT;
    if (!v->name || !*v->name) return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': empty parameter name", n->id);
    ew_raw copy = *v;
    copy.name = dup_str(v->name);
    copy.str = dup_str(v->str);
    if (!copy.name || (v->str && !copy.str)) {
        free(copy.name);
        free(copy.str);
        return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    }
    for (int i = 0; i < n->num_raw; i++)
        if (!strcmp(n->raw[i].name, v->name)) {
            free(n->raw[i].name);
            free(n->raw[i].str);
            n->raw[i] = copy;
            ew_graph_invalidate(g);
            return EW_OK;
        }
    if (n->num_raw == n->cap_raw) {
        int cap = n->cap_raw ? n->cap_raw * 2 : 8;
        ew_raw *nr = (ew_raw *)realloc(n->raw, (size_t)cap * sizeof *nr);
        if (!nr) {
            free(copy.name);
            free(copy.str);
            return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
        }
        n->raw = nr;
        n->cap_raw = cap;
    }
    n->raw[n->num_raw++] = copy;
    ew_graph_invalidate(g);
    return EW_OK;
}

ew_result ew_graph_set_param(ew_graph *g, const char *node, const char *param, const char *text) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    if (!text) return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': no value", node ? node : "",
                                    param ? param : "");
    ew_raw v = {(char *)param, EW_RAW_TEXT, 0.0, (char *)text, {0, 0, 0, 0}, 0};
    return ew_graph_put_raw(g, node, &v);
}

ew_result ew_graph_set_assignment(ew_graph *g, const char *a) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    const char *dot = a ? strchr(a, '.') : NULL;
    const char *eq = dot ? strchr(dot, '=') : NULL;
    if (!dot || !eq || dot == a || eq == dot + 1)
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "'%.200s' is not node.param=value", a ? a : "(null)");
    char node[64], param[128];
    if ((size_t)(dot - a) >= sizeof node || (size_t)(eq - dot - 1) >= sizeof param)
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "'%.200s': node or parameter name too long", a);
    memcpy(node, a, (size_t)(dot - a));
    node[dot - a] = '\0';
    memcpy(param, dot + 1, (size_t)(eq - dot - 1));
    param[eq - dot - 1] = '\0';
    return ew_graph_set_param(g, node, param, eq + 1);
}

ew_result ew_graph_set_bool(ew_graph *g, const char *node, const char *param, int32_t value) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    ew_raw v = {(char *)param, EW_RAW_BOOL, value ? 1.0 : 0.0, NULL, {0, 0, 0, 0}, 0};
    return ew_graph_put_raw(g, node, &v);
}

ew_result ew_graph_set_int(ew_graph *g, const char *node, const char *param, int32_t value) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    ew_raw v = {(char *)param, EW_RAW_INT, (double)value, NULL, {0, 0, 0, 0}, 0};
    return ew_graph_put_raw(g, node, &v);
}

ew_result ew_graph_set_float(ew_graph *g, const char *node, const char *param, double value) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    ew_raw v = {(char *)param, EW_RAW_NUMBER, value, NULL, {0, 0, 0, 0}, 0};
    return ew_graph_put_raw(g, node, &v);
}

ew_result ew_graph_set_string(ew_graph *g, const char *node, const char *param, const char *value) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    if (!value) return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': NULL string",
                                     node ? node : "", param ? param : "");
    ew_raw v = {(char *)param, EW_RAW_STRING, 0.0, (char *)value, {0, 0, 0, 0}, 0};
    return ew_graph_put_raw(g, node, &v);
}

ew_result ew_graph_set_color(ew_graph *g, const char *node, const char *param, const float rgba[4]) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    if (!rgba) return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "NULL colour");
    ew_raw v = {(char *)param, EW_RAW_ARRAY, 0.0, NULL, {rgba[0], rgba[1], rgba[2], rgba[3]}, 4};
    return ew_graph_put_raw(g, node, &v);
}

ew_result ew_graph_connect(ew_graph *g, const char *src_node, const char *src_port, const char *dst_node,
                           const char *dst_port) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    g->err[0] = '\0';
    ew_gnode *d = need_node(g, dst_node);
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    if (!dst_port || !*dst_port)
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': connection without an input port name", d->id);
    if (!src_node || !*src_node)
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' input '%s': connection without a source node",
                             d->id, dst_port);
    ew_conn c = {dup_str(dst_port), dup_str(src_node), src_port && *src_port ? dup_str(src_port) : NULL};
    if (!c.dst_port || !c.src_node || (src_port && *src_port && !c.src_port)) {
        free(c.dst_port);
        free(c.src_node);
        free(c.src_port);
        return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    }
    for (int i = 0; i < d->num_conns; i++)
        if (!strcmp(d->conns[i].dst_port, dst_port)) {
            free(d->conns[i].dst_port);
            free(d->conns[i].src_node);
            free(d->conns[i].src_port);
            d->conns[i] = c;
            ew_graph_invalidate(g);
            return EW_OK;
        }
    if (d->num_conns == d->cap_conns) {
        int cap = d->cap_conns ? d->cap_conns * 2 : 4;
        ew_conn *nc = (ew_conn *)realloc(d->conns, (size_t)cap * sizeof *nc);
        if (!nc) {
            free(c.dst_port);
            free(c.src_node);
            free(c.src_port);
            return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
        }
        d->conns = nc;
        d->cap_conns = cap;
    }
    d->conns[d->num_conns++] = c;
    ew_graph_invalidate(g);
    return EW_OK;
}

ew_result ew_graph_set_frames(ew_graph *g, int32_t first, int32_t last) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    if (first < 0 || last < first || last - first > 1000000)
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "frame range %d-%d is not valid (first <= last, both >= 0)",
                             (int)first, (int)last);
    g->frames_set = 1;
    g->first_frame = first;
    g->last_frame = last;
    ew_graph_invalidate(g);
    return EW_OK;
}

static ew_gnode *need_type(ew_graph *g, const char *node, const char *type) {
    ew_gnode *n = need_node(g, node);
    if (n && strcmp(n->type->name, type) != 0) {
        ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' is a '%s' node, not '%s'", n->id, n->type->name, type);
        return NULL;
    }
    return n;
}

static int view_ok(const ew_image *v) {
    return v->data && v->width > 0 && v->height > 0 && v->channels >= 1 && v->channels <= 4 &&
           v->format == EW_FORMAT_FLOAT;
}

ew_result ew_graph_set_input(ew_graph *g, const char *node, const ew_image *view) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    g->err[0] = '\0';
    ew_gnode *n = need_type(g, node, "input");
    if (!n) return EW_ERR_INVALID_ARGUMENT;
    if (view && !view_ok(view))
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                             "node '%s': the image must be float, 1 to 4 channels, with a size and data", n->id);
    n->has_ext = view != NULL;
    if (view) n->ext = *view;
    return EW_OK; /* sizes are checked per frame: no revalidation needed */
}

ew_result ew_graph_set_output(ew_graph *g, const char *node, const ew_image *view) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    g->err[0] = '\0';
    ew_gnode *n = need_type(g, node, "output");
    if (!n) return EW_ERR_INVALID_ARGUMENT;
    if (view && !view_ok(view))
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                             "node '%s': the image must be float, 1 to 4 channels, with a size and data", n->id);
    n->has_ext = view != NULL;
    if (view) n->ext = *view;
    return EW_OK;
}

ew_result ew_graph_get_output(const ew_graph *g, const char *node, ew_image *out) {
    if (!g || !out) return EW_ERR_INVALID_ARGUMENT;
    ew_gnode *n = ew_graph_find(g, node);
    if (!n || strcmp(n->type->name, "output") != 0) return EW_ERR_INVALID_ARGUMENT;
    if (!n->has_in[0]) return EW_ERR_INVALID_STATE;
    *out = n->in[0];
    return EW_OK;
}

ew_result ew_graph_set_progress(ew_graph *g, ew_progress_fn fn, void *user) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    g->progress = fn;
    g->progress_user = user;
    return EW_OK;
}

const char *ew_graph_report(const ew_graph *g) { return g && g->report ? g->report : "{}"; }

ew_result ew_graph_get_stats(const ew_graph *g, ew_graph_stats *out) {
    if (!g || !out) return EW_ERR_INVALID_ARGUMENT;
    *out = g->stats;
    return EW_OK;
}

int32_t ew_graph_frame_count(const ew_graph *g) { return g && g->validated ? g->num_frames : 0; }

const ew_pvalue *ew_node_value(const ew_gnode *n, const char *name) {
    int i = ew_sig_find_param(&n->sig, name);
    return i >= 0 ? &n->values[i] : NULL;
}

double ew_node_num(const ew_gnode *n, const char *name) {
    const ew_pvalue *v = ew_node_value(n, name);
    return v ? v->num : 0.0;
}

const char *ew_node_str(const ew_gnode *n, const char *name) {
    const ew_pvalue *v = ew_node_value(n, name);
    return v && v->str ? v->str : "";
}

void ew_path_join(const char *base, const char *path, char *out, size_t len) {
    if (path[0] == '/' || !base || !base[0]) snprintf(out, len, "%s", path);
    else snprintf(out, len, "%s/%s", base, path);
}
