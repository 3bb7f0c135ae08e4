/*
 * plan.c — execution order (topological, cycles reported with their path),
 * which nodes run (those that feed a sink), how many consumers each output
 * has (a buffer goes back to the pool after its last one) and how many
 * images are alive at most.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

/* Follow inputs from a node left over by the sort until a node repeats:
 * that is a cycle. Print it in data-flow order. */
static ew_result report_cycle(ew_graph *g, const int *indeg) {
    int start = -1;
    for (int i = 0; i < g->num_nodes && start < 0; i++)
        if (indeg[i] > 0) start = i;
    int *seen = (int *)calloc((size_t)g->num_nodes, sizeof(int));
    int *path = (int *)malloc((size_t)(g->num_nodes + 1) * sizeof(int));
    if (!seen || !path) {
        free(seen);
        free(path);
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "the graph has a cycle");
    }
    int len = 0, cur = start;
    while (cur >= 0 && !seen[cur]) {
        seen[cur] = len + 1;
        path[len++] = cur;
        const ew_gnode *n = g->nodes[cur];
        int next = -1;
        for (int p = 0; p < n->sig.num_inputs && next < 0; p++)
            if (n->src_node[p] >= 0 && indeg[n->src_node[p]] > 0) next = n->src_node[p];
        cur = next;
    }
    char msg[1024];
    size_t used = 0;
    msg[0] = '\0';
    if (cur >= 0) {
        /* path[seen[cur]-1 .. len) is the cycle, walked against the flow */
        int from = seen[cur] - 1;
        for (int k = len - 1; k >= from && used < sizeof msg; k--) {
            int w = snprintf(msg + used, sizeof msg - used, "%s -> ", g->nodes[path[k]]->id);
            if (w < 0) break;
            used += (size_t)w;
        }
        if (used < sizeof msg) snprintf(msg + used, sizeof msg - used, "%s", g->nodes[path[len - 1]]->id);
    }
    ew_result r = ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT, "node '%s': the graph has a cycle: %s",
                                cur >= 0 ? g->nodes[cur]->id : g->nodes[start]->id, msg[0] ? msg : "(not found)");
    free(seen);
    free(path);
    return r;
}

/* A binary min-heap of node indices. */
static void heap_push(int *h, int *n, int v) {
    int k = (*n)++;
    while (k > 0 && h[(k - 1) / 2] > v) {
        h[k] = h[(k - 1) / 2];
        k = (k - 1) / 2;
    }
    h[k] = v;
}

static int heap_pop(int *h, int *n) {
    const int top = h[0], last = h[--*n];
    int k = 0;
    for (;;) {
        int c = 2 * k + 1;
        if (c >= *n) break;
        if (c + 1 < *n && h[c + 1] < h[c]) c++;
        if (h[c] >= last) break;
        h[k] = h[c];
        k = c;
    }
    if (*n > 0) h[k] = last;
    return top;
}

ew_result ew_graph_plan(ew_graph *g) {
    const int nn = g->num_nodes;
    int *indeg = (int *)calloc((size_t)nn, sizeof(int));
    int *order = (int *)malloc((size_t)nn * sizeof(int));
    int *live = (int *)calloc((size_t)nn, sizeof(int));
    if (!indeg || !order || !live) {
        free(indeg);
        free(order);
        free(live);
        return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    }
    /* indeg[i]: connected inputs of node i whose source is not yet placed */
    for (int i = 0; i < nn; i++) {
        const ew_gnode *n = g->nodes[i];
        for (int p = 0; p < n->sig.num_inputs; p++)
            if (n->src_node[p] >= 0) indeg[i]++;
    }
    /* Kahn, in sweeps over the file order (a node that becomes ready later
     * in the same sweep joins it; one before the sweep's position waits for
     * the next), so the order is stable and readable. Consumers come from
     * an edge list and the sweeps from two heaps: O((nodes + edges) log
     * nodes), where sweeping the whole graph for every placed node made a
     * long chain cubic. */
    int placed = 0;
    int *first = (int *)calloc((size_t)nn + 1, sizeof(int));
    int ne = 0;
    for (int j = 0; j < nn; j++) ne += g->nodes[j]->sig.num_inputs;
    int *edge = (int *)malloc(((size_t)ne + 1) * sizeof(int));
    int *heap_a = (int *)malloc((size_t)nn * sizeof(int)), *heap_b = (int *)malloc((size_t)nn * sizeof(int));
    if (!first || !edge || !heap_a || !heap_b) {
        free(first);
        free(edge);
        free(heap_a);
        free(heap_b);
        free(indeg);
        free(order);
        free(live);
        return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
    }
    for (int j = 0; j < nn; j++) { /* one edge per connected input port */
        const ew_gnode *m = g->nodes[j];
        for (int p = 0; p < m->sig.num_inputs; p++)
            if (m->src_node[p] >= 0) first[m->src_node[p] + 1]++;
    }
    for (int i = 0; i < nn; i++) first[i + 1] += first[i];
    {
        int *fill = (int *)calloc((size_t)nn, sizeof(int));
        if (!fill) {
            free(first);
            free(edge);
            free(heap_a);
            free(heap_b);
            free(indeg);
            free(order);
            free(live);
            return ew_graph_fail(g, EW_ERR_OUT_OF_MEMORY, "out of memory");
        }
        for (int j = 0; j < nn; j++) {
            const ew_gnode *m = g->nodes[j];
            for (int p = 0; p < m->sig.num_inputs; p++) {
                int i = m->src_node[p];
                if (i >= 0) edge[first[i] + fill[i]++] = j;
            }
        }
        free(fill);
    }
    int na = 0, nb = 0;
    for (int i = 0; i < nn; i++)
        if (indeg[i] == 0) heap_push(heap_a, &na, i);
    while (na > 0) {
        const int i = heap_pop(heap_a, &na);
        indeg[i] = -1;
        order[placed++] = i;
        for (int e = first[i]; e < first[i + 1]; e++) {
            const int j = edge[e];
            if (indeg[j] > 0 && --indeg[j] == 0) {
                if (j > i) heap_push(heap_a, &na, j);
                else heap_push(heap_b, &nb, j);
            }
        }
        if (na == 0) { /* the sweep ends: the next starts from the file's top */
            int *t = heap_a;
            heap_a = heap_b;
            heap_b = t;
            na = nb;
            nb = 0;
        }
    }
    free(first);
    free(edge);
    free(heap_a);
    free(heap_b);
    if (placed < nn) {
        ew_result r = report_cycle(g, indeg);
        free(indeg);
        free(order);
        free(live);
        return r;
    }
    /* Live: sinks, and everything that feeds a live node (reverse order). */
    int sinks = 0;
    for (int k = nn - 1; k >= 0; k--) {
        int i = order[k];
        ew_gnode *n = g->nodes[i];
        if (n->type->is_sink) {
            live[i] = 1;
            sinks++;
        }
        if (!live[i]) continue;
        for (int p = 0; p < n->sig.num_inputs; p++)
            if (n->src_node[p] >= 0) live[n->src_node[p]] = 1;
    }
    if (!sinks) {
        free(indeg);
        free(order);
        free(live);
        return ew_graph_fail(g, EW_ERR_INVALID_ARGUMENT,
                             "the graph has no write, output or metrics node: it would produce nothing");
    }
    for (int i = 0; i < nn; i++) {
        ew_gnode *n = g->nodes[i];
        n->live = live[i];
        memset(n->num_consumers, 0, sizeof n->num_consumers);
    }
    for (int i = 0; i < nn; i++) {
        const ew_gnode *n = g->nodes[i];
        if (!n->live) continue;
        for (int p = 0; p < n->sig.num_inputs; p++)
            if (n->src_node[p] >= 0) g->nodes[n->src_node[p]]->num_consumers[n->src_port[p]]++;
    }
    free(g->order);
    g->order = order;
    g->num_order = 0;
    for (int k = 0; k < nn; k++)
        if (live[order[k]]) order[g->num_order++] = order[k];

    /* Most images alive at once: simulate one frame with unit buffers. */
    int *refs = (int *)calloc((size_t)nn * EW_SIG_MAX_PORTS, sizeof(int));
    int alive = 0, peak = 0;
    for (int k = 0; refs && k < g->num_order; k++) {
        const ew_gnode *n = g->nodes[order[k]];
        int inplace = n->sig.inplace_input;
        int took = 0;
        if (inplace >= 0 && n->src_node[inplace] >= 0 && n->sig.num_outputs > 0 && n->num_consumers[0] > 0 &&
            strcmp(g->nodes[n->src_node[inplace]]->type->name, "input") != 0 &&
            refs[n->src_node[inplace] * EW_SIG_MAX_PORTS + n->src_port[inplace]] == 1)
            took = 1;
        for (int o = 0; o < n->sig.num_outputs; o++)
            if (n->num_consumers[o] > 0) {
                refs[order[k] * EW_SIG_MAX_PORTS + o] = n->num_consumers[o];
                if (!(o == 0 && took) && strcmp(n->type->name, "input") != 0) alive++;
            }
        if (alive > peak) peak = alive;
        if (!strcmp(n->type->name, "output")) continue; /* keeps its input */
        for (int p = 0; p < n->sig.num_inputs; p++) {
            if (n->src_node[p] < 0) continue;
            int *r = &refs[n->src_node[p] * EW_SIG_MAX_PORTS + n->src_port[p]];
            if (--*r == 0 && !(took && p == inplace) && strcmp(g->nodes[n->src_node[p]]->type->name, "input") != 0)
                alive--;
        }
    }
    free(refs);
    g->planned_buffers = peak;
    free(indeg);
    free(live);
    return EW_OK;
}
