/*
 * fuzz_graph.c — fuzz target for graph files: parse with jansson, map onto a
 * graph, and validate everything that needs no file access (types,
 * parameters, connections, cycles, plan). Built as a libFuzzer target with
 * -DEW_FUZZ=ON under clang; fuzz_replay.c runs the corpus as a test.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    char *text = (char *)malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    ew_graph *g = NULL;
    if (ew_graph_create(NULL, &g) == EW_OK) {
        if (ew_graph_load_string(g, text, "/nonexistent") == EW_OK) {
            (void)ew_graph_check_structure(g);
            (void)ew_graph_set_assignment(g, "a.b=1");
            (void)ew_graph_check_structure(g);
        }
        /* every message is a terminated string */
        if (strlen(ew_graph_last_error(g)) >= sizeof g->err) abort();
        ew_graph_destroy(g);
    }
    free(text);
    return 0;
}
