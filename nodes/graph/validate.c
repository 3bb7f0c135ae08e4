/*
 * validate.c — everything checked before a graph runs. Each message names
 * the node and the parameter or port, so a user can fix a graph file from
 * the message alone.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "graph.h"

static const char *raw_kind_name(const ew_raw *r) {
    switch (r->kind) {
    case EW_RAW_BOOL: return "a boolean";
    case EW_RAW_INT: return "an integer";
    case EW_RAW_NUMBER: return "a number";
    case EW_RAW_STRING: return "a string";
    case EW_RAW_ARRAY: return "an array";
    case EW_RAW_TEXT: return "text";
    default: return "an object or null";
    }
}

static const char *type_name(ew_node_param_type t) {
    switch (t) {
    case EW_NODE_PARAM_BOOL: return "a boolean (true/false)";
    case EW_NODE_PARAM_INT: return "an integer";
    case EW_NODE_PARAM_FLOAT: return "a number";
    case EW_NODE_PARAM_ENUM: return "a name";
    case EW_NODE_PARAM_STRING: return "a string";
    default: return "a colour ([r, g, b] or [r, g, b, a])";
    }
}

static int parse_double(const char *s, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    while (*end == ' ') end++;
    if (end == s || *end != '\0' || errno) return 0;
    *out = v;
    return 1;
}

/* Convert one given value to the parameter's type and check its range. */
static ew_result convert(ew_gnode *n, const ew_nparam_desc *p, const ew_raw *r, ew_pvalue *v) {
    ew_graph *g = n->g;
    const char *bad_type = NULL;
    switch (p->type) {
    case EW_NODE_PARAM_BOOL:
        if (r->kind == EW_RAW_BOOL || (r->kind == EW_RAW_INT && (r->num == 0.0 || r->num == 1.0))) {
            v->num = r->num;
        } else if (r->kind == EW_RAW_TEXT) {
            const char *s = r->str;
            if (!strcmp(s, "true") || !strcmp(s, "1") || !strcmp(s, "yes") || !strcmp(s, "on")) v->num = 1.0;
            else if (!strcmp(s, "false") || !strcmp(s, "0") || !strcmp(s, "no") || !strcmp(s, "off")) v->num = 0.0;
            else bad_type = "text";
        } else {
            bad_type = raw_kind_name(r);
        }
        break;
    case EW_NODE_PARAM_INT:
    case EW_NODE_PARAM_FLOAT: {
        double x = 0.0;
        if (r->kind == EW_RAW_INT || r->kind == EW_RAW_NUMBER) x = r->num;
        else if (r->kind == EW_RAW_TEXT && parse_double(r->str, &x)) {}
        else {
            bad_type = raw_kind_name(r);
            break;
        }
        if (!isfinite(x))
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': %g is not a finite number",
                                 n->id, p->name, x);
        if (p->type == EW_NODE_PARAM_INT && x != floor(x))
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': expected an integer, got %g",
                                 n->id, p->name, x);
        /* Float parameters reach the library as float, whose limits are
         * floats: 0.1 (double) is below 0.1f, yet it is the same parameter
         * value once rounded, so compare what the library will get. */
        const double xc = p->type == EW_NODE_PARAM_FLOAT ? (double)(float)x : x;
        if (!(xc >= p->min && xc <= p->max))
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s' = %g is outside [%g, %g]", n->id,
                                 p->name, x, p->min, p->max);
        v->num = x;
        break;
    }
    case EW_NODE_PARAM_ENUM: {
        int nc = ew_param_num_choices(&n->sig, p);
        /* A library enum was an integer before it had names: graph files
         * that give its index still mean the same choice. */
        const int lib_enum = n->sig.lib_enum[p - n->sig.params] > 0;
        double idx = 0.0;
        if (lib_enum && (r->kind == EW_RAW_INT || r->kind == EW_RAW_NUMBER || (r->kind == EW_RAW_TEXT && parse_double(r->str, &idx)))) {
            if (r->kind != EW_RAW_TEXT) idx = r->num;
            if (idx == floor(idx) && idx >= 0 && idx < nc) {
                v->num = idx;
                v->str = ew_param_choice(&n->sig, p, (int)idx);
                return EW_OK;
            }
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': %g is not a choice index in [0, %d]",
                                 n->id, p->name, idx, nc - 1);
        }
        if (r->kind != EW_RAW_STRING && r->kind != EW_RAW_TEXT) {
            bad_type = raw_kind_name(r);
            break;
        }
        for (int i = 0; i < nc; i++)
            if (!strcmp(ew_param_choice(&n->sig, p, i), r->str)) {
                v->num = i;
                v->str = ew_param_choice(&n->sig, p, i);
                return EW_OK;
            }
        char names[512];
        size_t used = 0;
        names[0] = '\0';
        for (int i = 0; i < nc && used < sizeof names; i++) {
            int k = snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", ew_param_choice(&n->sig, p, i));
            if (k < 0) break;
            used += (size_t)k;
        }
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': unknown value '%.80s' (one of: %s)",
                             n->id, p->name, r->str, nc ? names : "none in this build");
    }
    case EW_NODE_PARAM_STRING:
        if (r->kind == EW_RAW_STRING || r->kind == EW_RAW_TEXT) v->str = r->str;
        else bad_type = raw_kind_name(r);
        break;
    case EW_NODE_PARAM_COLOR: {
        double c[4] = {p->def_color[0], p->def_color[1], p->def_color[2], p->def_color[3]};
        if (r->kind == EW_RAW_INT || r->kind == EW_RAW_NUMBER) {
            c[0] = c[1] = c[2] = r->num;
        } else if (r->kind == EW_RAW_ARRAY && (r->n == 3 || r->n == 4)) {
            for (int i = 0; i < r->n; i++) c[i] = r->arr[i];
        } else if (r->kind == EW_RAW_TEXT) {
            /* "v" or "r,g,b" or "r,g,b,a" */
            char buf[256];
            snprintf(buf, sizeof buf, "%s", r->str);
            int k = 0;
            for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
                if (k >= 4 || !parse_double(tok, &c[k])) {
                    k = -1;
                    break;
                }
                k++;
            }
            if (k == 1) c[1] = c[2] = c[0];
            else if (k != 3 && k != 4) bad_type = "text";
        } else {
            bad_type = r->kind == EW_RAW_ARRAY ? "an array of the wrong length" : raw_kind_name(r);
        }
        if (bad_type) break;
        for (int i = 0; i < 4; i++) {
            if (!isfinite(c[i]))
                return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': component %d is not finite",
                                     n->id, p->name, i);
            v->color[i] = (float)c[i];
        }
        break;
    }
    }
    if (bad_type) {
        if (r->kind == EW_RAW_TEXT)
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': expected %s, got '%.80s'", n->id,
                                 p->name, type_name(p->type), r->str);
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': expected %s, got %s", n->id, p->name,
                             type_name(p->type), bad_type);
    }
    return EW_OK;
}

static const ew_raw *find_raw(const ew_gnode *n, const char *name) {
    for (int i = 0; i < n->num_raw; i++)
        if (!strcmp(n->raw[i].name, name)) return &n->raw[i];
    return NULL;
}

/* Signature (with the chosen library method) and parameter values. */
static ew_result resolve_node(ew_gnode *n) {
    ew_graph *g = n->g;
    const ew_node_type *t = n->type;
    const char *method = NULL;
    const ew_raw *sel = NULL;
    if (t->lib_kind && !t->lib_method && t->num_params > 0) {
        sel = find_raw(n, t->params[0].name);
        if (sel && sel->kind != EW_RAW_STRING && sel->kind != EW_RAW_TEXT)
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' parameter '%s': expected a name, got %s", n->id,
                                 t->params[0].name, raw_kind_name(sel));
        if (sel) method = sel->str;
    }
    if (!ew_node_sig_build(t, method, &n->sig)) {
        char names[512];
        ew_lib_list_methods(t->lib_kind, names, sizeof names);
        if (t->lib_method)
            return ew_graph_fail(g, EW_ERR_UNSUPPORTED,
                                 "node '%s': node type '%s' needs the library %s '%s', which this libedgewise does not "
                                 "have (%ss: %s)",
                                 n->id, t->name, t->lib_kind, t->lib_method, t->lib_kind, names);
        if (sel)
            return ew_graph_fail(g, EW_ERR_UNSUPPORTED,
                                 "node '%s' parameter '%s': this libedgewise has no %s '%.80s' (%ss: %s)", n->id,
                                 t->params[0].name, t->lib_kind, method, t->lib_kind, names);
        return ew_graph_fail(g, EW_ERR_UNSUPPORTED, "node '%s': this libedgewise has no %s at all", n->id, t->lib_kind);
    }
    const ew_node_sig *s = &n->sig;
    for (int i = 0; i < s->num_params; i++) {
        const ew_nparam_desc *p = &s->params[i];
        ew_pvalue *v = &n->values[i];
        memset(v, 0, sizeof *v);
        v->num = p->def;
        memcpy(v->color, p->def_color, sizeof v->color);
        v->str = p->def_string ? p->def_string : "";
        if (p->type == EW_NODE_PARAM_ENUM) {
            int nc = ew_param_num_choices(s, p);
            for (int k = 0; k < nc; k++)
                if (!strcmp(ew_param_choice(s, p, k), v->str)) v->num = k;
            if (i == 0 && s->method && t->lib_kind && !t->lib_method) v->str = s->method;
        }
    }
    for (int i = 0; i < n->num_raw; i++) {
        const ew_raw *r = &n->raw[i];
        int k = ew_sig_find_param(s, r->name);
        if (k < 0) {
            char names[1024];
            ew_sig_list_params(s, names, sizeof names);
            if (s->method && !t->lib_method)
                return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                     "node '%s': unknown parameter '%.80s' (%s '%s' with %s '%s' has: %s)", n->id,
                                     r->name, t->name, n->id, t->params[0].name, s->method, names);
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': unknown parameter '%.80s' (%s has: %s)", n->id,
                                 r->name, t->name, names);
        }
        ew_result res = convert(n, &s->params[k], r, &n->values[k]);
        if (res != EW_OK) return res;
    }
    for (int i = 0; i < s->num_params; i++)
        if (s->params[i].required && !find_raw(n, s->params[i].name))
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': parameter '%s' is required (%s)", n->id,
                                 s->params[i].name, s->params[i].hint);
    if (t->check) return t->check(n);
    return EW_OK;
}

static ew_result resolve_links(ew_gnode *n) {
    ew_graph *g = n->g;
    const ew_node_sig *s = &n->sig;
    for (int i = 0; i < EW_SIG_MAX_PORTS; i++) {
        n->src_node[i] = -1;
        n->src_port[i] = -1;
    }
    for (int c = 0; c < n->num_conns; c++) {
        const ew_conn *cn = &n->conns[c];
        int in = ew_sig_find_input(s, cn->dst_port);
        if (in < 0) {
            char names[512];
            ew_sig_list_ports(s, 0, names, sizeof names);
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': unknown input '%.80s' (inputs: %s)", n->id,
                                 cn->dst_port, names);
        }
        int si = ew_graph_index(g, cn->src_node);
        if (si < 0)
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s' input '%s': no node '%.80s' in the graph", n->id,
                                 cn->dst_port, cn->src_node);
        const ew_gnode *src = g->nodes[si];
        const ew_node_sig *ss = &src->sig;
        int out;
        char outs[512];
        ew_sig_list_ports(ss, 1, outs, sizeof outs);
        if (cn->src_port) {
            out = ew_sig_find_output(ss, cn->src_port);
            if (out < 0)
                return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                     "node '%s' input '%s': node '%s' has no output '%.80s' (outputs: %s)", n->id,
                                     cn->dst_port, src->id, cn->src_port, outs);
        } else {
            /* "node" alone: its only output, or its main one named "output" */
            if (ss->num_outputs != 1 && !(ss->num_outputs > 1 && !strcmp(ss->outputs[0].name, "output")))
                return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                     "node '%s' input '%s': node '%s' has %s outputs (%s): name one, as '%s.%s'", n->id,
                                     cn->dst_port, src->id, ss->num_outputs ? "several" : "no", outs, src->id,
                                     ss->num_outputs ? ss->outputs[0].name : "port");
            out = 0;
        }
        ew_pass sp = ss->outputs[out].pass, dp = s->inputs[in].pass;
        if (!ew_pass_compatible(sp, dp))
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                 "node '%s' input '%s': type error: '%s.%s' is a %s pass but the input takes %s", n->id,
                                 cn->dst_port, src->id, ss->outputs[out].name, ew_pass_name(sp), ew_pass_name(dp));
        n->src_node[in] = si;
        n->src_port[in] = out;
    }
    for (int i = 0; i < s->num_inputs; i++)
        if (s->inputs[i].required && n->src_node[i] < 0)
            return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': required input '%s' is not connected (%s)",
                                 n->id, s->inputs[i].name, s->inputs[i].hint);
    return EW_OK;
}

ew_result ew_graph_check_structure(ew_graph *g) {
    g->err[0] = '\0';
    if (g->num_nodes == 0) return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "the graph has no nodes");
    /* Every node first, so links can look at their source's signature. */
    for (int i = 0; i < g->num_nodes; i++) {
        ew_result r = resolve_node(g->nodes[i]);
        if (r != EW_OK) return r;
    }
    for (int i = 0; i < g->num_nodes; i++) {
        ew_result r = resolve_links(g->nodes[i]);
        if (r != EW_OK) return r;
    }
    return ew_graph_plan(g);
}

/* ---- file checks ------------------------------------------------------- */

static ew_result resolve_frames(ew_graph *g) {
    free(g->frames);
    g->frames = NULL;
    g->num_frames = 0;
    if (g->frames_set) {
        int n = g->last_frame - g->first_frame + 1;
        /* A range over a write without a frame pattern would write one file
         * again for every frame (a million times for "0-1000000"). */
        for (int k = 0; n > 1 && k < g->num_order; k++) {
            ew_gnode *w = g->nodes[g->order[k]];
            if (strcmp(w->type->name, "write") != 0) continue;
            const char *path = ew_node_str(w, "path");
            if (path && !ew_path_has_pattern(path))
                return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                     "frames %d-%d: node '%s' parameter 'path' ('%s') has no frame pattern (####), so "
                                     "every frame would overwrite the same file; add one or run a single frame",
                                     g->first_frame, g->last_frame, w->id, path);
        }
        g->frames = (int *)malloc((size_t)n * sizeof(int));
        if (!g->frames) return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
        for (int i = 0; i < n; i++) g->frames[i] = g->first_frame + i;
        g->num_frames = n;
        return EW_OK;
    }
    /* The frames of the first read node with a pattern. */
    for (int k = 0; k < g->num_order; k++) {
        ew_gnode *n = g->nodes[g->order[k]];
        if (strcmp(n->type->name, "read") != 0) continue;
        const char *path = ew_node_str(n, "path");
        if (!ew_path_has_pattern(path)) continue;
        if (ew_frames_on_disk(path, &g->frames, &g->num_frames) != 0)
            return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
        if (g->num_frames == 0)
            return ew_graph_fail(g, EW_ERR_IO, "node '%s' parameter 'path': the frame pattern '%s' matches no file",
                                 n->id, path);
        return EW_OK;
    }
    g->frames = (int *)malloc(sizeof(int));
    if (!g->frames) return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    g->frames[0] = 1;
    g->num_frames = 1;
    return EW_OK;
}

typedef struct {
    dev_t dev;
    ino_t ino;
    int node, frame;
} file_id;

static int cmp_id(const void *a, const void *b) {
    const file_id *x = (const file_id *)a, *y = (const file_id *)b;
    if (x->dev != y->dev) return x->dev < y->dev ? -1 : 1;
    if (x->ino != y->ino) return x->ino < y->ino ? -1 : 1;
    return 0;
}

/* Refuse before running when any frame of any write would replace a file the
 * graph reads (by device and inode, so links and other spellings of the
 * path are caught; inputs exist by now, so a target that does not exist yet
 * cannot be one). */
static ew_result check_overwrite(ew_graph *g) {
    size_t cap = 0, count = 0;
    file_id *ids = NULL;
    char path[4096];
    ew_result res = EW_OK;
    for (int k = 0; k < g->num_order; k++) {
        ew_gnode *n = g->nodes[g->order[k]];
        if (strcmp(n->type->name, "read") != 0) continue;
        for (int f = 0; f < g->num_frames; f++) {
            if (!ew_frame_path(ew_node_str(n, "path"), g->frames[f], path, sizeof path)) continue;
            struct stat st;
            if (stat(path, &st) != 0) continue;
            if (count == cap) {
                cap = cap ? cap * 2 : 64;
                file_id *ni = (file_id *)realloc(ids, cap * sizeof *ni);
                if (!ni) {
                    free(ids);
                    return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
                }
                ids = ni;
            }
            ids[count].dev = st.st_dev;
            ids[count].ino = st.st_ino;
            ids[count].node = g->order[k];
            ids[count].frame = g->frames[f];
            count++;
            if (!ew_path_has_pattern(ew_node_str(n, "path"))) break; /* same file every frame */
        }
    }
    if (count) qsort(ids, count, sizeof *ids, cmp_id);
    for (int k = 0; k < g->num_order && res == EW_OK; k++) {
        ew_gnode *n = g->nodes[g->order[k]];
        if (strcmp(n->type->name, "write") != 0) continue;
        for (int f = 0; f < g->num_frames; f++) {
            if (!ew_frame_path(ew_node_str(n, "path"), g->frames[f], path, sizeof path)) continue;
            struct stat st;
            if (stat(path, &st) != 0) continue;
            file_id key = {st.st_dev, st.st_ino, 0, 0};
            const file_id *hit = count ? (const file_id *)bsearch(&key, ids, count, sizeof *ids, cmp_id) : NULL;
            if (hit) {
                res = ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                    "node '%s' parameter 'path': refusing to write '%s' (frame %d): it is an input of "
                                    "the graph (node '%s', frame %d)",
                                    n->id, path, g->frames[f], g->nodes[hit->node]->id, hit->frame);
                break;
            }
            if (!ew_path_has_pattern(ew_node_str(n, "path"))) break;
        }
    }
    free(ids);
    return res;
}

typedef struct {
    char *path; /* the directory resolved, then the file name */
    int node, frame;
} out_id;

static int cmp_out(const void *a, const void *b) {
    const out_id *x = (const out_id *)a, *y = (const out_id *)b;
    int c = strcmp(x->path, y->path);
    if (c) return c;
    return x->node != y->node ? (x->node < y->node ? -1 : 1) : (x->frame > y->frame) - (x->frame < y->frame);
}

/* The file a write will create, as one spelling: the directory's real path
 * (it exists: write's check_files) and the file name. */
static char *out_key(const char *path) {
    char dir[4096];
    const char *slash = strrchr(path, '/');
    if (!slash) snprintf(dir, sizeof dir, ".");
    else if (slash == path) snprintf(dir, sizeof dir, "/");
    else snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    char *real = realpath(dir, NULL);
    const char *base = slash ? slash + 1 : path;
    size_t n = strlen(real ? real : dir) + strlen(base) + 2;
    char *key = (char *)malloc(n);
    if (key) snprintf(key, n, "%s/%s", real ? real : dir, base);
    free(real);
    return key;
}

/* Refuse before running when two writes, or two frames of one write, would
 * create the same file: the later would silently replace the earlier. */
static ew_result check_collisions(ew_graph *g) {
    size_t cap = 0, count = 0;
    out_id *ids = NULL;
    char path[4096];
    ew_result res = EW_OK;
    for (int k = 0; k < g->num_order && res == EW_OK; k++) {
        ew_gnode *n = g->nodes[g->order[k]];
        if (strcmp(n->type->name, "write") != 0) continue;
        for (int f = 0; f < g->num_frames && res == EW_OK; f++) {
            if (!ew_frame_path(ew_node_str(n, "path"), g->frames[f], path, sizeof path)) continue;
            if (count == cap) {
                cap = cap ? cap * 2 : 64;
                out_id *ni = (out_id *)realloc(ids, cap * sizeof *ni);
                if (!ni) {
                    res = ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
                    break;
                }
                ids = ni;
            }
            ids[count].path = out_key(path);
            ids[count].node = g->order[k];
            ids[count].frame = g->frames[f];
            if (!ids[count].path) res = ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
            count++;
        }
    }
    if (res == EW_OK && count > 1) qsort(ids, count, sizeof *ids, cmp_out);
    for (size_t i = 1; res == EW_OK && i < count; i++) {
        const out_id *a = &ids[i - 1], *b = &ids[i];
        if (strcmp(a->path, b->path) != 0) continue;
        const ew_gnode *na = g->nodes[a->node], *nb = g->nodes[b->node];
        if (a->node == b->node)
            res = ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                "node '%s' parameter 'path': frames %d and %d would both be written to '%s': put the "
                                "frame number in the file name ('####' or '%%04d', e.g. out_####.exr)",
                                na->id, a->frame, b->frame, ew_node_str(na, "path"));
        else
            res = ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                                "nodes '%s' and '%s' would both write '%s' (frame %d): give each write its own path",
                                na->id, nb->id, a->path, a->frame);
    }
    for (size_t i = 0; i < count; i++) free(ids[i].path);
    free(ids);
    return res;
}

/* Canonical form of a path that may not exist yet: the resolved directory
 * plus the base name ("" when the directory does not resolve). */
static void canonical(const char *path, char *out, size_t len) {
    char dir[4096], res[4096]; /* realpath needs PATH_MAX (4096 on Linux) */
    out[0] = '\0';
    if (realpath(path, res)) {
        snprintf(out, len, "%s", res);
        return;
    }
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    const char *base = slash ? slash + 1 : path;
    if (!slash) snprintf(dir, sizeof dir, ".");
    else if (slash == dir) dir[1] = '\0';
    else *slash = '\0';
    if (!realpath(dir, res)) return;
    int k = snprintf(out, len, "%s/%s", strcmp(res, "/") ? res : "", base);
    if (k < 0 || (size_t)k >= len) out[0] = '\0'; /* too long to compare */
}

ew_result ew_graph_check_side_file(ew_graph *g, const char *side) {
    if (!g || !side) return EW_ERR_INVALID_ARGUMENT;
    ew_result r = resolve_frames(g);
    if (r != EW_OK) return r;
    struct stat ss;
    const int side_exists = stat(side, &ss) == 0;
    char side_c[4096], path[4096], path_c[4096];
    canonical(side, side_c, sizeof side_c);
    for (int k = 0; k < g->num_nodes; k++) {
        ew_gnode *n = g->nodes[k];
        const int is_read = !strcmp(n->type->name, "read"), is_write = !strcmp(n->type->name, "write");
        if (!is_read && !is_write) continue;
        const char *pattern = ew_node_str(n, "path");
        if (!pattern || !*pattern) continue;
        for (int f = 0; f < g->num_frames; f++) {
            if (!ew_frame_path(pattern, g->frames[f], path, sizeof path)) continue;
            struct stat st;
            int same;
            if (side_exists && stat(path, &st) == 0) {
                same = st.st_dev == ss.st_dev && st.st_ino == ss.st_ino;
            } else {
                canonical(path, path_c, sizeof path_c);
                same = side_c[0] && !strcmp(side_c, path_c);
            }
            if (same)
                return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "'%s' is %s of the graph (node '%s', frame %d)", side,
                                     is_read ? "an input" : "an output", n->id, g->frames[f]);
            if (!ew_path_has_pattern(pattern)) break; /* the same file every frame */
        }
    }
    return EW_OK;
}

ew_result ew_graph_check_files(ew_graph *g) {
    ew_result r = resolve_frames(g);
    if (r != EW_OK) return r;
    for (int k = 0; k < g->num_order; k++) {
        ew_gnode *n = g->nodes[g->order[k]];
        if (n->type->check_files && (r = n->type->check_files(n)) != EW_OK) return r;
    }
    if ((r = check_collisions(g)) != EW_OK) return r;
    return check_overwrite(g);
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

ew_result ew_graph_validate(ew_graph *g) {
    if (!g) return EW_ERR_INVALID_ARGUMENT;
    double t0 = now_s();
    g->validated = 0;
    ew_result r = ew_graph_check_structure(g);
    if (r == EW_OK) r = ew_graph_check_files(g);
    g->stats.validate_seconds = now_s() - t0;
    if (r == EW_OK) {
        g->validated = 1;
        g->err[0] = '\0';
    }
    return r;
}
