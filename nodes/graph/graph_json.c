/*
 * graph_json.c — graph files (docs/graphs.md), parsed with jansson. The
 * loader only maps JSON onto the graph-building calls; types, parameters and
 * connections are checked by validation like any API-built graph.
 */
#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <jansson.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

#define EW_GRAPH_FILE_MAX (16 << 20)

static const char *json_kind(const json_t *v) {
    switch (json_typeof(v)) {
    case JSON_OBJECT: return "an object";
    case JSON_ARRAY: return "an array";
    case JSON_STRING: return "a string";
    case JSON_INTEGER: return "an integer";
    case JSON_REAL: return "a number";
    case JSON_TRUE:
    case JSON_FALSE: return "a boolean";
    default: return "null";
    }
}

/* Is `name` a path parameter of the node's own (static) parameters? */
static int is_path_param(const ew_node_type *t, const char *name) {
    for (int i = 0; i < t->num_params; i++)
        if (!strcmp(t->params[i].name, name)) return t->params[i].is_path;
    return 0;
}

static ew_result load_param(ew_graph *g, ew_gnode *n, const char *name, json_t *v) {
    ew_raw r;
    memset(&r, 0, sizeof r);
    r.name = (char *)name;
    char joined[4096];
    switch (json_typeof(v)) {
    case JSON_TRUE: r.kind = EW_RAW_BOOL; r.num = 1.0; break;
    case JSON_FALSE: r.kind = EW_RAW_BOOL; r.num = 0.0; break;
    case JSON_INTEGER: r.kind = EW_RAW_INT; r.num = (double)json_integer_value(v); break;
    case JSON_REAL: r.kind = EW_RAW_NUMBER; r.num = json_real_value(v); break;
    case JSON_STRING:
        r.kind = EW_RAW_STRING;
        r.str = (char *)json_string_value(v);
        if (strlen(r.str) != json_string_length(v))
            return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%s' parameter '%s': the string contains a NUL byte",
                                 n->id, name);
        if (is_path_param(n->type, name) && r.str[0] && g->base_dir[0]) {
            ew_path_join(g->base_dir, r.str, joined, sizeof joined);
            r.str = joined;
        }
        break;
    case JSON_ARRAY: {
        size_t len = json_array_size(v);
        if (len < 1 || len > 4)
            return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%s' parameter '%s': an array must hold 1 to 4 numbers",
                                 n->id, name);
        r.kind = EW_RAW_ARRAY;
        r.n = (int)len;
        for (size_t i = 0; i < len; i++) {
            json_t *e = json_array_get(v, i);
            if (!json_is_number(e))
                return ew_graph_fail(g, EW_ERR_INVALID_DATA,
                                     "node '%s' parameter '%s': array element %zu is %s, not a number", n->id, name, i,
                                     json_kind(e));
            r.arr[i] = json_number_value(e);
        }
        break;
    }
    default: r.kind = EW_RAW_OTHER; break; /* reported with the parameter's expected type */
    }
    return ew_graph_put_raw(g, n->id, &r);
}

static ew_result load_node(ew_graph *g, const char *id, json_t *obj) {
    if (!json_is_object(obj))
        return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%.80s': expected an object, got %s", id, json_kind(obj));
    json_t *type = json_object_get(obj, "type");
    if (!type) return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%.80s': no \"type\"", id);
    if (!json_is_string(type))
        return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%.80s': \"type\" must be a string, got %s", id,
                             json_kind(type));
    const char *key;
    json_t *v;
    json_object_foreach(obj, key, v) {
        if (strcmp(key, "type") && strcmp(key, "params") && strcmp(key, "inputs") && strcmp(key, "comment"))
            return ew_graph_fail(g, EW_ERR_INVALID_DATA,
                                 "node '%.80s': unknown key '%.80s' (keys: type, params, inputs, comment)", id, key);
    }
    ew_result r = ew_graph_add_node(g, id, json_string_value(type));
    if (r != EW_OK) return r;
    ew_gnode *n = ew_graph_find(g, id);
    json_t *params = json_object_get(obj, "params");
    if (params) {
        if (!json_is_object(params))
            return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%s': \"params\" must be an object, got %s", id,
                                 json_kind(params));
        json_object_foreach(params, key, v) {
            if ((r = load_param(g, n, key, v)) != EW_OK) return r;
        }
    }
    json_t *inputs = json_object_get(obj, "inputs");
    if (inputs) {
        if (!json_is_object(inputs))
            return ew_graph_fail(g, EW_ERR_INVALID_DATA, "node '%s': \"inputs\" must be an object, got %s", id,
                                 json_kind(inputs));
        json_object_foreach(inputs, key, v) {
            if (!json_is_string(v))
                return ew_graph_fail(g, EW_ERR_INVALID_DATA,
                                     "node '%s' input '%.80s': expected \"node.output\", got %s", id, key, json_kind(v));
            const char *src = json_string_value(v);
            const char *dot = strchr(src, '.');
            char node[128];
            if ((dot ? (size_t)(dot - src) : strlen(src)) >= sizeof node || !src[0] || dot == src)
                return ew_graph_fail(g, EW_ERR_INVALID_DATA,
                                     "node '%s' input '%.80s': '%.80s' is not \"node\" or \"node.output\"", id, key, src);
            snprintf(node, sizeof node, "%.*s", dot ? (int)(dot - src) : (int)strlen(src), src);
            if ((r = ew_graph_connect(g, node, dot ? dot + 1 : NULL, id, key)) != EW_OK) return r;
        }
    }
    return EW_OK;
}

static ew_result load_frames(ew_graph *g, json_t *v) {
    long a, b;
    if (json_is_integer(v)) {
        a = b = (long)json_integer_value(v);
    } else if (json_is_array(v) && json_array_size(v) == 2 && json_is_integer(json_array_get(v, 0)) &&
               json_is_integer(json_array_get(v, 1))) {
        a = (long)json_integer_value(json_array_get(v, 0));
        b = (long)json_integer_value(json_array_get(v, 1));
    } else if (json_is_string(v)) {
        char *end;
        const char *s = json_string_value(v);
        errno = 0;
        a = strtol(s, &end, 10);
        b = a;
        if (*end == '-') b = strtol(end + 1, &end, 10);
        if (end == s || *end != '\0' || errno)
            return ew_graph_fail(g, EW_ERR_INVALID_DATA, "\"frames\": '%.80s' is not \"A-B\" or \"A\"", s);
    } else {
        return ew_graph_fail(g, EW_ERR_INVALID_DATA, "\"frames\": expected \"A-B\", [A, B] or A, got %s", json_kind(v));
    }
    if (a < 0 || b < a || a > INT_MAX || b > INT_MAX)
        return ew_graph_fail(g, EW_ERR_INVALID_DATA, "\"frames\": %ld-%ld is not a valid range (0 <= first <= last)",
                             a, b);
    return ew_graph_set_frames(g, (int32_t)a, (int32_t)b);
}

static ew_result load_json(ew_graph *g, const char *text, size_t len, const char *name) {
    if (g->num_nodes) return ew_graph_fail(g, EW_ERR_INVALID_STATE, "load into an empty graph");
    if (len > EW_GRAPH_FILE_MAX)
        return ew_graph_fail(g, EW_ERR_INVALID_DATA, "%s: larger than %d MiB: not a graph file", name,
                             EW_GRAPH_FILE_MAX >> 20);
    json_error_t je;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (!root)
        return ew_graph_fail(g, EW_ERR_INVALID_DATA, "%s:%d:%d: %s", name, je.line, je.column, je.text);
    ew_result r = EW_OK;
    const char *key;
    json_t *v;
    if (!json_is_object(root)) {
        r = ew_graph_fail(g, EW_ERR_INVALID_DATA, "%s: a graph file is a JSON object, got %s", name, json_kind(root));
        goto done;
    }
    json_object_foreach(root, key, v) {
        if (strcmp(key, "edgewise_graph") && strcmp(key, "frames") && strcmp(key, "nodes") && strcmp(key, "description")) {
            r = ew_graph_fail(g, EW_ERR_INVALID_DATA,
                              "%s: unknown key '%.80s' (keys: edgewise_graph, description, frames, nodes)", name, key);
            goto done;
        }
    }
    v = json_object_get(root, "edgewise_graph");
    if (!v || !json_is_integer(v)) {
        r = ew_graph_fail(g, EW_ERR_INVALID_DATA, "%s: not an edgewise graph (no \"edgewise_graph\": 1)", name);
        goto done;
    }
    if (json_integer_value(v) != 1) {
        r = ew_graph_fail(g, EW_ERR_UNSUPPORTED, "%s: graph format version %lld; this edgewise reads version 1", name,
                          (long long)json_integer_value(v));
        goto done;
    }
    json_t *nodes = json_object_get(root, "nodes");
    if (!nodes || !json_is_object(nodes)) {
        r = ew_graph_fail(g, EW_ERR_INVALID_DATA, "%s: \"nodes\" must be an object of nodes by id, got %s", name,
                          nodes ? json_kind(nodes) : "nothing");
        goto done;
    }
    /* Connections are resolved at validation: a node may name a source
     * defined later in the file. */
    json_object_foreach(nodes, key, v) {
        if ((r = load_node(g, key, v)) != EW_OK) goto done;
    }
    if ((v = json_object_get(root, "frames")) != NULL && (r = load_frames(g, v)) != EW_OK) goto done;
done:
    json_decref(root);
    return r;
}

ew_result ew_graph_load_string(ew_graph *g, const char *json, const char *base_dir) {
    if (!g || !json) return EW_ERR_INVALID_ARGUMENT;
    g->err[0] = '\0';
    snprintf(g->base_dir, sizeof g->base_dir, "%s", base_dir ? base_dir : "");
    return load_json(g, json, strlen(json), "graph");
}

ew_result ew_graph_load_file(ew_graph *g, const char *path) {
    if (!g || !path) return EW_ERR_INVALID_ARGUMENT;
    g->err[0] = '\0';
    /* a regular file only: a FIFO would block the open (O_NONBLOCK) and a
     * device could be read forever */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return ew_graph_fail(g, EW_ERR_IO, "cannot read graph '%s': %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        close(fd);
        return ew_graph_fail(g, EW_ERR_IO, "cannot read graph '%s': %s", path,
                             S_ISDIR(st.st_mode) ? "is a directory" : "not a regular file");
    }
    FILE *f = fdopen(fd, "rb");
    if (!f) {
        close(fd);
        return ew_graph_fail(g, EW_ERR_IO, "cannot read graph '%s': %s", path, strerror(errno));
    }
    char *buf = NULL;
    size_t len = 0, cap = 0;
    for (;;) {
        if (len == cap) {
            cap = cap ? cap * 2 : 65536;
            if (cap > (size_t)EW_GRAPH_FILE_MAX + 65536) {
                fclose(f);
                free(buf);
                return ew_graph_fail(g, EW_ERR_INVALID_DATA, "%s: larger than %d MiB: not a graph file", path,
                                     EW_GRAPH_FILE_MAX >> 20);
            }
            char *nb = (char *)realloc(buf, cap);
            if (!nb) {
                fclose(f);
                free(buf);
                return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
            }
            buf = nb;
        }
        size_t k = fread(buf + len, 1, cap - len, f);
        len += k;
        if (k == 0) break;
    }
    int rd_err = ferror(f);
    fclose(f);
    if (rd_err) {
        free(buf);
        return ew_graph_fail(g, EW_ERR_IO, "cannot read graph '%s'", path);
    }
    /* relative paths in the file are relative to the file */
    const char *slash = strrchr(path, '/');
    if (slash == path) snprintf(g->base_dir, sizeof g->base_dir, "/");
    else if (slash) snprintf(g->base_dir, sizeof g->base_dir, "%.*s", (int)(slash - path), path);
    else g->base_dir[0] = '\0';
    ew_result r = load_json(g, buf, len, path);
    free(buf);
    return r;
}
