/*
 * bench_graph.c — what the node graph costs on top of the work it runs: a
 * bgrid denoise of a synthetic W x H frame (default 1280x720, colour,
 * albedo, normal, depth) through the C API directly and through a graph
 * (input nodes -> denoise -> output node, result read in graph memory).
 *
 *   bench_graph [--width W] [--height H] [--runs N] [--threads T]
 *
 * Prints the median time of each (runs interleaved so machine load hits
 * both alike), their difference, and the graph's own measurement of its
 * overhead (time outside node execution: validation, planning, buffer
 * management), which is not blurred by run-to-run noise.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "edgewise/nodes.h"

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int main(int argc, char **argv) {
    int w = 1280, h = 720, runs = 9, threads = 0;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!strcmp(argv[i], "--width")) w = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--height")) h = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--runs")) runs = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--threads")) threads = atoi(argv[i + 1]);
        else {
            fprintf(stderr, "usage: bench_graph [--width W] [--height H] [--runs N] [--threads T]\n");
            return 2;
        }
    }
    if (w < 8 || h < 8 || runs < 1 || runs > 1000) {
        fprintf(stderr, "bench_graph: bad size or run count\n");
        return 2;
    }
    const size_t n = (size_t)w * h;
    float *color = malloc(n * 3 * sizeof(float)), *albedo = malloc(n * 3 * sizeof(float));
    float *normal = malloc(n * 3 * sizeof(float)), *depth = malloc(n * sizeof(float));
    float *out = malloc(n * 3 * sizeof(float));
    double *t_api = malloc((size_t)runs * sizeof(double)), *t_graph = malloc((size_t)runs * sizeof(double));
    double *t_over = malloc((size_t)runs * sizeof(double));
    if (!color || !albedo || !normal || !depth || !out || !t_api || !t_graph || !t_over) return 1;
    unsigned seed = 1;
    for (size_t i = 0; i < n; i++) {
        int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w);
        float base = ((x / 64 + y / 64) % 2) ? 0.8f : 0.2f;
        for (int c = 0; c < 3; c++) {
            seed = seed * 1664525u + 1013904223u;
            color[i * 3 + c] = base * (0.5f + (float)(seed >> 8) / 16777216.0f);
            albedo[i * 3 + c] = base;
            normal[i * 3 + c] = c == 2 ? 1.0f : 0.0f;
        }
        depth[i] = 2.0f + (float)x / (float)w;
    }
    ew_image vc = ew_image_packed(color, w, h, 3), va = ew_image_packed(albedo, w, h, 3);
    ew_image vn = ew_image_packed(normal, w, h, 3), vd = ew_image_packed(depth, w, h, 1);
    ew_image vo = ew_image_packed(out, w, h, 3);

    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    if (ew_device_create(&desc, &dev) != EW_OK) return 1;

    /* the API path: what a caller does per frame */
    ew_denoiser *d = NULL;
    if (ew_denoiser_create(dev, "bgrid", &d) != EW_OK) return 1;

    /* the graph path */
    ew_graph *g = NULL;
    ew_graph_create(dev, &g);
    static const char *const ins[] = {"color", "albedo", "normal", "depth"};
    const ew_image *views[] = {&vc, &va, &vn, &vd};
    ew_graph_add_node(g, "dn", "denoise");
    ew_graph_set_string(g, "dn", "method", "bgrid");
    for (int i = 0; i < 4; i++) {
        ew_graph_add_node(g, ins[i], "input");
        ew_graph_set_input(g, ins[i], views[i]);
        ew_graph_connect(g, ins[i], NULL, "dn", ins[i]);
    }
    ew_graph_add_node(g, "out", "output");
    ew_graph_connect(g, "dn", NULL, "out", "image");
    double t0 = now_s();
    if (ew_graph_validate(g) != EW_OK) {
        fprintf(stderr, "bench_graph: %s\n", ew_graph_last_error(g));
        return 1;
    }
    double t_validate = now_s() - t0;

    for (int k = -1; k < runs; k++) { /* k = -1: warm-up of both */
        double a = now_s();
        ew_result r = EW_OK;
        for (int i = 0; i < 4 && r == EW_OK; i++) r = ew_denoiser_set_image(d, ins[i], views[i]);
        if (r == EW_OK) r = ew_denoiser_set_image(d, "output", &vo);
        if (r == EW_OK) r = ew_denoiser_commit(d);
        if (r == EW_OK) r = ew_denoiser_execute(d);
        double b = now_s();
        if (r != EW_OK) {
            fprintf(stderr, "bench_graph: %s\n", ew_device_last_error(dev));
            return 1;
        }
        if (ew_graph_run(g) != EW_OK) {
            fprintf(stderr, "bench_graph: %s\n", ew_graph_last_error(g));
            return 1;
        }
        double c = now_s();
        ew_graph_stats st;
        ew_graph_get_stats(g, &st);
        if (k >= 0) {
            t_api[k] = b - a;
            t_graph[k] = c - b;
            t_over[k] = st.overhead_seconds;
        }
    }
    ew_image res;
    ew_graph_get_output(g, "out", &res);
    double max_diff = 0.0;
    for (size_t i = 0; i < n * 3; i++) {
        double dd = (double)((float *)res.data)[i] - (double)out[i];
        if (dd < 0) dd = -dd;
        if (dd > max_diff) max_diff = dd;
    }
    double api = median(t_api, runs), graph = median(t_graph, runs), over = median(t_over, runs);
    printf("bgrid denoise %dx%d, %d runs, %d threads\n", w, h, runs, (int)ew_device_get_num_threads(dev));
    printf("  C API         %8.2f ms (median)\n", api * 1e3);
    printf("  graph         %8.2f ms (median)   difference %+.2f %%\n", graph * 1e3, 100.0 * (graph - api) / api);
    printf("  graph's own overhead (outside nodes) %.3f ms = %.3f %% of the API denoise\n", over * 1e3,
           100.0 * over / api);
    printf("  first validation + plan %.3f ms = %.3f %%\n", t_validate * 1e3, 100.0 * t_validate / api);
    printf("  max |graph - API| = %g\n", max_diff);
    ew_graph_destroy(g);
    ew_denoiser_destroy(d);
    ew_device_destroy(dev);
    free(color), free(albedo), free(normal), free(depth), free(out), free(t_api), free(t_graph), free(t_over);
    return max_diff == 0.0 ? 0 : 1;
}
