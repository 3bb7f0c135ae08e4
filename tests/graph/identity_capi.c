/*
 * identity_capi.c — builds examples/denoise_dof_display.json through the C
 * API (same nodes, parameters and connections) and writes the displayed
 * image as a float EXR: tests/python/test_identity.py checks the pixels are
 * identical to the graph file's and the Python script's.
 *   graph_identity_capi SAMPLE_DIR OUT.exr
 */
#include <stdio.h>

#include "edgewise/nodes.h"

#define TRY(call)                                                                   \
    do {                                                                            \
        if ((call) != EW_OK) {                                                      \
            fprintf(stderr, "graph_identity_capi: %s\n", ew_graph_last_error(g));   \
            ew_graph_destroy(g);                                                    \
            return 1;                                                               \
        }                                                                           \
    } while (0)

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: graph_identity_capi SAMPLE_DIR OUT.exr\n");
        return 2;
    }
    char render[4096], reference[4096];
    snprintf(render, sizeof render, "%s/cornell/f0001_spp0004.exr", argv[1]);
    snprintf(reference, sizeof reference, "%s/cornell/f0001_ref1024.exr", argv[1]);
    ew_graph *g = NULL;
    if (ew_graph_create(NULL, &g) != EW_OK) return 1;
    TRY(ew_graph_add_node(g, "render", "read"));
    TRY(ew_graph_set_string(g, "render", "path", render));
    TRY(ew_graph_add_node(g, "reference", "read"));
    TRY(ew_graph_set_string(g, "reference", "path", reference));
    TRY(ew_graph_add_node(g, "denoised", "denoise"));
    TRY(ew_graph_set_string(g, "denoised", "method", "bgrid"));
    TRY(ew_graph_set_float(g, "denoised", "spatial_rate", 8));
    TRY(ew_graph_set_float(g, "denoised", "range_rate", 8));
    TRY(ew_graph_connect(g, "render", "color", "denoised", "color"));
    TRY(ew_graph_connect(g, "render", "albedo", "denoised", "albedo"));
    TRY(ew_graph_connect(g, "render", "normal", "denoised", "normal"));
    TRY(ew_graph_connect(g, "render", "depth", "denoised", "depth"));
    TRY(ew_graph_add_node(g, "quality", "metrics"));
    TRY(ew_graph_connect(g, "denoised", NULL, "quality", "image"));
    TRY(ew_graph_connect(g, "reference", "color", "quality", "reference"));
    TRY(ew_graph_add_node(g, "lens", "dof"));
    TRY(ew_graph_set_float(g, "lens", "focal_length", 50));
    TRY(ew_graph_set_float(g, "lens", "fstop", 2.0));
    TRY(ew_graph_set_float(g, "lens", "focus_distance", 4.0));
    TRY(ew_graph_set_int(g, "lens", "weights", 0));
    TRY(ew_graph_connect(g, "denoised", NULL, "lens", "color"));
    TRY(ew_graph_connect(g, "render", "z", "lens", "depth"));
    TRY(ew_graph_add_node(g, "view", "display"));
    TRY(ew_graph_set_string(g, "view", "display", "sRGB"));
    TRY(ew_graph_set_string(g, "view", "view", "Standard"));
    TRY(ew_graph_connect(g, "lens", "output", "view", "color"));
    TRY(ew_graph_add_node(g, "pixels", "write"));
    TRY(ew_graph_set_string(g, "pixels", "path", argv[2]));
    TRY(ew_graph_set_string(g, "pixels", "pixel_type", "float"));
    TRY(ew_graph_connect(g, "view", NULL, "pixels", "image"));
    TRY(ew_graph_run(g));
    printf("%s\n", ew_graph_report(g));
    ew_graph_destroy(g);
    return 0;
}
