/*
 * test_graph.c — the node layer through its public API (nodes.h): node
 * descriptors against the library's introspection, validation errors (each
 * names the node and the parameter or port), planning and buffer reuse,
 * progress and cancellation, frame sequences, file safety.
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "edgewise/nodes.h"
#include "ew_test.h"
#include "ewio.h"

/* ---- helpers ------------------------------------------------------------ */

static char tmpdir[256];

static void remove_tmpdir(void) {
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "  could not remove %s\n", tmpdir);
}

static const char *tmp(const char *name) {
    static char buf[4][512];
    static int k;
    k = (k + 1) % 4;
    if (!tmpdir[0]) {
        snprintf(tmpdir, sizeof tmpdir, "/tmp/ew_test_graph_XXXXXX");
        if (!mkdtemp(tmpdir)) abort();
        atexit(remove_tmpdir);
    }
    snprintf(buf[k], sizeof buf[k], "%s/%s", tmpdir, name);
    return buf[k];
}

/* A small Cycles-like multilayer EXR: Combined, Denoising Albedo/Normal/Depth, Depth. */
static int write_render(const char *path, int w, int h, float level) {
    char err[512];
    ewio_file *f = NULL;
    if (ewio_create(w, h, &f, err, sizeof err)) return 1;
    float *buf = (float *)malloc((size_t)w * h * 4 * sizeof(float));
    unsigned seed = 12345u + (unsigned)(level * 1000);
    for (int i = 0; i < w * h; i++)
        for (int c = 0; c < 4; c++) {
            seed = seed * 1664525u + 1013904223u;
            buf[i * 4 + c] = c == 3 ? 1.0f : level * ((i % w) < w / 2 ? 1.0f : 0.3f) + 0.2f * ((float)(seed >> 8) / 16777216.0f - 0.5f);
        }
    int rc = ewio_set_pass(f, "ViewLayer", "Combined", "RGBA", buf, err, sizeof err);
    for (int i = 0; i < w * h * 3; i++) buf[i] = 0.8f;
    rc |= ewio_set_pass(f, "ViewLayer", "Denoising Albedo", "RGB", buf, err, sizeof err);
    for (int i = 0; i < w * h; i++) buf[i * 3] = 0.0f, buf[i * 3 + 1] = 0.0f, buf[i * 3 + 2] = 1.0f;
    rc |= ewio_set_pass(f, "ViewLayer", "Denoising Normal", "XYZ", buf, err, sizeof err);
    for (int i = 0; i < w * h; i++) buf[i] = 3.0f + (float)(i % w) * 0.01f;
    rc |= ewio_set_pass(f, "ViewLayer", "Denoising Depth", "Z", buf, err, sizeof err);
    rc |= ewio_set_pass(f, "ViewLayer", "Depth", "Z", buf, err, sizeof err);
    rc |= ewio_write(f, path, EWIO_FLOAT, NULL, NULL, err, sizeof err);
    if (rc) fprintf(stderr, "write_render: %s\n", err);
    free(buf);
    ewio_free(f);
    return rc;
}

static ew_graph *graph_from(const char *json) {
    ew_graph *g = NULL;
    if (ew_graph_create(NULL, &g) != EW_OK) return NULL;
    if (ew_graph_load_string(g, json, NULL) != EW_OK) {
        fprintf(stderr, "  load: %s\n", ew_graph_last_error(g));
        ew_graph_destroy(g);
        return NULL;
    }
    return g;
}

/* Validate a graph text; return the result, the message in msg. */
static ew_result validate_text(const char *json, char *msg, size_t len) {
    ew_graph *g = NULL;
    ew_graph_create(NULL, &g);
    ew_result r = ew_graph_load_string(g, json, NULL);
    if (r == EW_OK) r = ew_graph_validate(g);
    snprintf(msg, len, "%s", ew_graph_last_error(g));
    ew_graph_destroy(g);
    return r;
}

#define HEAD "{\"edgewise_graph\": 1, \"nodes\": {"

/* ---- descriptors ---------------------------------------------------------- */

TEST(every_type_has_a_descriptor) {
    CHECK(ew_node_type_count() >= 20);
    static const char *const want[] = {"read", "write", "denoise", "filter", "dof", "bilateral", "atrous", "outlier",
                                       "demodulate", "remodulate", "display", "colorspace", "metrics", "temporal",
                                       "add", "multiply", "mix", "shuffle", "input", "output", NULL};
    for (int i = 0; want[i]; i++) {
        ew_node_type_info t;
        CHECK_EQ_INT(ew_node_type_get(want[i], NULL, &t), EW_OK);
        CHECK(t.summary && t.summary[0]);
    }
    CHECK(ew_node_type_name(ew_node_type_count()) == NULL);
    ew_node_type_info t;
    CHECK_EQ_INT(ew_node_type_get("nope", NULL, &t), EW_ERR_INVALID_ARGUMENT);
}

/* Library-backed nodes take their parameters from ew_method_param: same
 * names, types, defaults and ranges, for every method the library has. */
TEST(library_params_come_from_introspection) {
    static const char *const kinds[] = {"denoiser", "filter"};
    for (int k = 0; k < 2; k++) {
        const char *node = k ? "filter" : "denoise";
        for (int32_t m = 0; m < ew_method_count(kinds[k]); m++) {
            const char *name;
            int32_t ni, np;
            CHECK_EQ_INT(ew_method_get(kinds[k], m, &name, NULL, &ni, &np), EW_OK);
            ew_node_type_info t;
            CHECK_EQ_INT(ew_node_type_get(node, name, &t), EW_OK);
            CHECK(t.available);
            CHECK_EQ_INT(t.num_params, np + 1); /* + the method selector */
            for (int32_t i = 0; i < np; i++) {
                ew_param_info lp;
                ew_node_param_info p;
                CHECK_EQ_INT(ew_method_param(kinds[k], name, i, &lp), EW_OK);
                CHECK_EQ_INT(ew_node_type_param(node, name, i + 1, &p), EW_OK);
                CHECK(!strcmp(p.name, lp.name));
                CHECK_NEAR(p.default_value, lp.default_value, 0);
                CHECK_NEAR(p.min_value, lp.min_value, 0);
                CHECK_NEAR(p.max_value, lp.max_value, 0);
                /* an enum of the library is shown and given by its choice names */
                const int32_t nc = ew_method_param_num_choices(kinds[k], name, i);
                CHECK_EQ_INT(p.type, nc > 0                      ? EW_NODE_PARAM_ENUM
                                     : lp.type == EW_PARAM_FLOAT ? EW_NODE_PARAM_FLOAT
                                     : lp.type == EW_PARAM_INT   ? EW_NODE_PARAM_INT
                                                                 : EW_NODE_PARAM_BOOL);
                CHECK_EQ_INT(p.num_choices, nc);
                for (int32_t c = 0; c < nc; c++) {
                    const char *choice = NULL;
                    CHECK_EQ_INT(ew_node_type_param_choice(node, name, i + 1, c, &choice), EW_OK);
                    CHECK(!strcmp(choice, ew_method_param_choice(kinds[k], name, i, c)));
                }
                if (nc > 0) CHECK(!strcmp(p.default_string, ew_method_param_choice(kinds[k], name, i, (int32_t)lp.default_value)));
            }
            CHECK_EQ_INT(t.num_inputs + t.num_outputs, ni);
        }
    }
    /* a bound node: "dof" has exactly the dof filter's parameters */
    ew_node_type_info t;
    CHECK_EQ_INT(ew_node_type_get("dof", NULL, &t), EW_OK);
    if (!t.available) SKIP("this libedgewise has no dof filter");
    int32_t np = 0;
    for (int32_t m = 0; m < ew_method_count("filter"); m++) {
        const char *name;
        int32_t n;
        ew_method_get("filter", m, &name, NULL, NULL, &n);
        if (!strcmp(name, "dof")) np = n;
    }
    CHECK_EQ_INT(t.num_params, np);
}

TEST(denoise_method_choices_are_the_library_denoisers) {
    ew_node_param_info p;
    CHECK_EQ_INT(ew_node_type_param("denoise", NULL, 0, &p), EW_OK);
    CHECK(!strcmp(p.name, "method"));
    CHECK_EQ_INT(p.type, EW_NODE_PARAM_ENUM);
    CHECK_EQ_INT(p.num_choices, ew_method_count("denoiser"));
    const char *c0, *m0;
    CHECK_EQ_INT(ew_node_type_param_choice("denoise", NULL, 0, 0, &c0), EW_OK);
    ew_method_get("denoiser", 0, &m0, NULL, NULL, NULL);
    CHECK(!strcmp(c0, m0));
    CHECK(!strcmp(p.default_string, m0));
    ew_node_type_info t;
    CHECK_EQ_INT(ew_node_type_get("denoise", "no-such-method", &t), EW_ERR_INVALID_ARGUMENT);
}

/* ---- validation errors ---------------------------------------------------- */

#define EXPECT_INVALID(json, code, substr)                                         \
    do {                                                                           \
        char msg_[2048];                                                           \
        CHECK_EQ_INT(validate_text(json, msg_, sizeof msg_), code);                \
        CHECK_STR_CONTAINS(msg_, substr);                                          \
    } while (0)

static const char in_out[] = "\"in\": {\"type\": \"input\"}, \"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"x\"}}, ";

TEST(unknown_node_type) {
    EXPECT_INVALID(HEAD "\"x\": {\"type\": \"blur\"}}}", EW_ERR_INVALID_ARGUMENT, "node 'x': unknown node type 'blur' (types: read,");
}

TEST(unknown_parameter_names_node_and_parameter) {
    char j[1024];
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"bilateral\", \"params\": {\"radius\": 3, \"radus\": 2}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x': unknown parameter 'radus' (bilateral has: model, radius,");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"denoise\", \"params\": {\"method\": \"bgrid\", \"radius\": 2}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x': unknown parameter 'radius' (denoise 'x' with method 'bgrid' has: method, spatial_rate");
}

TEST(missing_required_input) {
    char j[1024];
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"demodulate\", \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x': required input 'albedo' is not connected");
}

TEST(cycle_is_reported_with_its_path) {
    EXPECT_INVALID(HEAD "\"in\": {\"type\": \"input\"},"
                   "\"a\": {\"type\": \"add\", \"inputs\": {\"a\": \"in\", \"b\": \"c\"}},"
                   "\"b\": {\"type\": \"multiply\", \"inputs\": {\"a\": \"a\"}},"
                   "\"c\": {\"type\": \"mix\", \"inputs\": {\"a\": \"b\", \"b\": \"in\"}},"
                   "\"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"c\"}}}}",
                   EW_ERR_INVALID_ARGUMENT, "the graph has a cycle: ");
    char msg[2048];
    validate_text(HEAD "\"in\": {\"type\": \"input\"},"
                  "\"a\": {\"type\": \"add\", \"inputs\": {\"a\": \"in\", \"b\": \"c\"}},"
                  "\"b\": {\"type\": \"multiply\", \"inputs\": {\"a\": \"a\"}},"
                  "\"c\": {\"type\": \"mix\", \"inputs\": {\"a\": \"b\", \"b\": \"in\"}},"
                  "\"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"c\"}}}}", msg, sizeof msg);
    CHECK(strstr(msg, "a -> b -> c -> a") || strstr(msg, "b -> c -> a -> b") || strstr(msg, "c -> a -> b -> c"));
    EXPECT_INVALID(HEAD "\"a\": {\"type\": \"add\", \"inputs\": {\"a\": \"a\"}}, \"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"a\"}}}}",
                   EW_ERR_INVALID_ARGUMENT, "cycle: a -> a");
}

TEST(wrong_parameter_type_and_range) {
    char j[1024];
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"bilateral\", \"params\": {\"radius\": \"big\"}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'radius': expected an integer, got a string");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"bilateral\", \"params\": {\"radius\": 2.5}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'radius': expected an integer, got 2.5");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"bilateral\", \"params\": {\"radius\": 9999}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'radius' = 9999 is outside [0, 256]");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"outlier\", \"params\": {\"k\": true}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'k': expected a number, got a boolean");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"denoise\", \"params\": {\"method\": \"oidn\"}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_UNSUPPORTED, "node 'x' parameter 'method': this libedgewise has no denoiser 'oidn' (denoisers: ");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"write\", \"params\": {\"path\": \"a.exr\", \"pixel_type\": \"double\"}, \"inputs\": {\"image\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'pixel_type': unknown value 'double' (one of: half, float)");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"add\", \"params\": {\"value\": [1, 2]}, \"inputs\": {\"a\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'value': expected a colour");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"shuffle\", \"params\": {\"channels\": \"RQB\"}, \"inputs\": {\"image\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x': parameter 'channels': 'Q' is not one of");
    EXPECT_INVALID(HEAD "\"r\": {\"type\": \"read\"}, \"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"r.color\"}}}}",
                   EW_ERR_INVALID_ARGUMENT, "node 'r': parameter 'path' is required");
}

/* A library enum by name; the index older graph files give means the same
 * choice; an unknown name lists the names. */
TEST(library_enums_by_name) {
    enum { W = 16, H = 12 };
    static float in[W * H * 3], out_name[W * H * 3], out_index[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) in[i] = (float)((i * 7919) % 97) / 97.0f;
    float *outs[2] = {out_name, out_index};
    const char *model[2] = {"\"none\"", "3"};
    for (int k = 0; k < 2; k++) {
        char j[1024];
        snprintf(j, sizeof j,
                 HEAD "\"in\": {\"type\": \"input\"}, \"x\": {\"type\": \"pyramid\", \"params\": {\"model\": %s, "
                      "\"radius\": 4}, \"inputs\": {\"color\": \"in\"}}, \"out\": {\"type\": \"output\", \"inputs\": "
                      "{\"image\": \"x\"}}}}",
                 model[k]);
        ew_graph *g = graph_from(j);
        CHECK(g);
        ew_image vi = ew_image_packed(in, W, H, 3), vo = ew_image_packed(outs[k], W, H, 3);
        CHECK_EQ_INT(ew_graph_set_input(g, "in", &vi), EW_OK);
        CHECK_EQ_INT(ew_graph_set_output(g, "out", &vo), EW_OK);
        CHECK_EQ_INT(ew_graph_run(g), EW_OK);
        ew_graph_destroy(g);
    }
    CHECK(memcmp(out_name, out_index, sizeof out_name) == 0);
    CHECK(memcmp(out_name, in, sizeof in) != 0); /* it filtered */
    char j[1024];
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"pyramid\", \"params\": {\"model\": \"fancy\"}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'model': unknown value 'fancy' (one of: color, gi, depth, none)");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"pyramid\", \"params\": {\"model\": 4}, \"inputs\": {\"color\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' parameter 'model': 4 is not a choice index in [0, 3]");
}

TEST(connection_errors_name_both_ends) {
    char j[1024];
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"outlier\", \"inputs\": {\"colour\": \"in\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x': unknown input 'colour' (inputs: color, albedo, normal)");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"outlier\", \"inputs\": {\"color\": \"nowhere\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' input 'color': no node 'nowhere' in the graph");
    snprintf(j, sizeof j, HEAD "%s\"x\": {\"type\": \"outlier\", \"inputs\": {\"color\": \"in.rgb\"}}}}", in_out);
    EXPECT_INVALID(j, EW_ERR_INVALID_ARGUMENT, "node 'x' input 'color': node 'in' has no output 'rgb' (outputs: image)");
    EXPECT_INVALID(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"a.exr\"}},"
                   "\"x\": {\"type\": \"outlier\", \"inputs\": {\"color\": \"r\"}}, \"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"x\"}}}}",
                   EW_ERR_INVALID_ARGUMENT, "node 'r' has several outputs (color, albedo,");
}

TEST(type_errors_between_passes) {
    EXPECT_INVALID(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"a.exr\"}},"
                   "\"d\": {\"type\": \"denoise\", \"inputs\": {\"color\": \"r.color\", \"albedo\": \"r.normal\"}},"
                   "\"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"d\"}}}}",
                   EW_ERR_INVALID_ARGUMENT,
                   "node 'd' input 'albedo': type error: 'r.normal' is a normal pass but the input takes albedo");
    EXPECT_INVALID(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"a.exr\"}},"
                   "\"d\": {\"type\": \"demodulate\", \"inputs\": {\"color\": \"r.depth\", \"albedo\": \"r.albedo\"}},"
                   "\"out\": {\"type\": \"output\", \"inputs\": {\"image\": \"d\"}}}}",
                   EW_ERR_INVALID_ARGUMENT, "type error: 'r.depth' is a depth pass but the input takes color");
}

TEST(graph_file_errors) {
    EXPECT_INVALID("{\"edgewise_graph\": 1, \"nodes\": {\n  \"a\": {\"type\": \"add\",}\n}}", EW_ERR_INVALID_DATA, "graph:2:");
    EXPECT_INVALID("[1, 2]", EW_ERR_INVALID_DATA, "a graph file is a JSON object, got an array");
    EXPECT_INVALID("{\"nodes\": {}}", EW_ERR_INVALID_DATA, "not an edgewise graph");
    EXPECT_INVALID("{\"edgewise_graph\": 2, \"nodes\": {}}", EW_ERR_UNSUPPORTED, "graph format version 2");
    EXPECT_INVALID(HEAD "\"a\": {\"type\": \"add\", \"param\": {}}}}", EW_ERR_INVALID_DATA, "node 'a': unknown key 'param'");
    EXPECT_INVALID(HEAD "\"a\": {\"type\": \"add\", \"inputs\": {\"a\": 3}}}}", EW_ERR_INVALID_DATA, "node 'a' input 'a': expected \"node.output\", got an integer");
    EXPECT_INVALID(HEAD "\"a\": {\"type\": \"add\"}, \"a\": {\"type\": \"add\"}}}", EW_ERR_INVALID_DATA, "duplicate");
    EXPECT_INVALID(HEAD "\"a b\": {\"type\": \"add\"}}}", EW_ERR_INVALID_ARGUMENT, "node id 'a b' is not valid");
    EXPECT_INVALID("{\"edgewise_graph\": 1, \"frames\": \"3-1\", \"nodes\": {}}", EW_ERR_INVALID_DATA, "\"frames\": 3-1 is not a valid range");
    EXPECT_INVALID(HEAD "\"in\": {\"type\": \"input\"}, \"a\": {\"type\": \"add\", \"inputs\": {\"a\": \"in\"}}}}",
                   EW_ERR_INVALID_ARGUMENT, "no write, output or metrics node");
}

/* ---- running on caller memory -------------------------------------------- */

TEST(arithmetic_on_caller_memory) {
    enum { W = 7, H = 5 };
    float a[W * H * 3], b[W * H], out[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) a[i] = (float)i;
    for (int i = 0; i < W * H; i++) b[i] = 2.0f;
    ew_graph *g = graph_from(HEAD "\"a\": {\"type\": \"input\"}, \"b\": {\"type\": \"input\"},"
                             "\"m\": {\"type\": \"multiply\", \"inputs\": {\"a\": \"a\", \"b\": \"b\"}},"
                             "\"p\": {\"type\": \"add\", \"params\": {\"value\": [1, 1, 1]}, \"inputs\": {\"a\": \"m\"}},"
                             "\"s\": {\"type\": \"shuffle\", \"params\": {\"channels\": \"BGR\"}, \"inputs\": {\"image\": \"p\"}},"
                             "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"s\"}}}}");
    CHECK(g);
    ew_image va = ew_image_packed(a, W, H, 3), vb = ew_image_packed(b, W, H, 1), vo = ew_image_packed(out, W, H, 3);
    CHECK_EQ_INT(ew_graph_set_input(g, "a", &va), EW_OK);
    CHECK_EQ_INT(ew_graph_set_input(g, "b", &vb), EW_OK);
    CHECK_EQ_INT(ew_graph_set_output(g, "o", &vo), EW_OK);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    for (int i = 0; i < W * H; i++)
        for (int c = 0; c < 3; c++) CHECK_NEAR(out[i * 3 + c], a[i * 3 + (2 - c)] * 2.0f + 1.0f, 0);
    /* the chain multiply -> add -> shuffle reuses one buffer in place */
    ew_graph_stats st;
    ew_graph_get_stats(g, &st);
    CHECK_EQ_INT(st.planned_buffers, 1);
    CHECK_EQ_INT(st.num_buffers, 1);
    ew_image got;
    CHECK_EQ_INT(ew_graph_get_output(g, "o", &got), EW_OK);
    CHECK_EQ_INT(got.channels, 3);
    CHECK_NEAR(((float *)got.data)[0], out[0], 0);
    /* inputs are never written */
    CHECK_NEAR(a[5], 5.0f, 0);
    ew_graph_destroy(g);
}

TEST(sizes_and_channels_are_checked_per_frame) {
    float a[4 * 4 * 3] = {0}, b[3 * 3 * 3] = {0};
    ew_graph *g = graph_from(HEAD "\"a\": {\"type\": \"input\"}, \"b\": {\"type\": \"input\"},"
                             "\"m\": {\"type\": \"mix\", \"inputs\": {\"a\": \"a\", \"b\": \"b\"}},"
                             "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"m\"}}}}");
    CHECK(g);
    ew_image va = ew_image_packed(a, 4, 4, 3), vb = ew_image_packed(b, 3, 3, 3);
    ew_graph_set_input(g, "a", &va);
    CHECK_EQ_INT(ew_graph_run(g), EW_ERR_INVALID_STATE);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "node 'b': no image given");
    ew_graph_set_input(g, "b", &vb);
    CHECK_EQ_INT(ew_graph_run(g), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "node 'm': input 'b' is 3x3 but input 'a' is 4x4");
    ew_graph_destroy(g);
}

typedef struct {
    int calls, cancel_at;
    double last;
    int monotonic;
} progress_log;

static int on_progress(void *user, double f) {
    progress_log *p = (progress_log *)user;
    if (f < p->last) p->monotonic = 0;
    p->last = f;
    return ++p->calls != p->cancel_at;
}

TEST(progress_and_cancel) {
    enum { W = 64, H = 48 };
    static float a[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) a[i] = (float)(i % 17) / 17.0f;
    ew_graph *g = graph_from(HEAD "\"a\": {\"type\": \"input\"},"
                             "\"d\": {\"type\": \"denoise\", \"inputs\": {\"color\": \"a\"}},"
                             "\"f\": {\"type\": \"outlier\", \"inputs\": {\"color\": \"d\"}},"
                             "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"f\"}}}}");
    CHECK(g);
    ew_image va = ew_image_packed(a, W, H, 3);
    ew_graph_set_input(g, "a", &va);
    progress_log p = {0, -1, 0.0, 1};
    ew_graph_set_progress(g, on_progress, &p);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    CHECK(p.calls > 3);
    CHECK(p.monotonic);
    CHECK_NEAR(p.last, 1.0, 1e-12);
    /* cancel inside the denoiser (its own progress calls) */
    progress_log q = {0, 3, 0.0, 1};
    ew_graph_set_progress(g, on_progress, &q);
    CHECK_EQ_INT(ew_graph_run(g), EW_ERR_CANCELLED);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "cancelled");
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "node 'd'");
    /* and it runs again afterwards */
    ew_graph_set_progress(g, NULL, NULL);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    ew_graph_destroy(g);
}

TEST(set_assignment_overrides) {
    float a[2 * 2 * 3] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1}, out[2 * 2 * 3];
    ew_graph *g = graph_from(HEAD "\"a\": {\"type\": \"input\"},"
                             "\"p\": {\"type\": \"add\", \"params\": {\"value\": 1}, \"inputs\": {\"a\": \"a\"}},"
                             "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"p\"}}}}");
    CHECK(g);
    ew_image va = ew_image_packed(a, 2, 2, 3), vo = ew_image_packed(out, 2, 2, 3);
    ew_graph_set_input(g, "a", &va);
    ew_graph_set_output(g, "o", &vo);
    CHECK_EQ_INT(ew_graph_set_assignment(g, "p.value=0.5,0.25,2"), EW_OK);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    CHECK_NEAR(out[0], 1.5, 1e-6);
    CHECK_NEAR(out[1], 1.25, 1e-6);
    CHECK_NEAR(out[2], 3.0, 1e-6);
    CHECK_EQ_INT(ew_graph_set_assignment(g, "p.value=abc"), EW_OK);
    CHECK_EQ_INT(ew_graph_run(g), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "node 'p' parameter 'value': expected a colour");
    CHECK_EQ_INT(ew_graph_set_assignment(g, "nope.value=1"), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "no node 'nope'");
    CHECK_EQ_INT(ew_graph_set_assignment(g, "p=1"), EW_ERR_INVALID_ARGUMENT);
    ew_graph_destroy(g);
}

/* ---- files and sequences ------------------------------------------------- */

static char *fmt_graph(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static char *fmt_graph(const char *fmt, ...) {
    static char buf[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return buf;
}

static int exists(const char *p) {
    struct stat st;
    return stat(p, &st) == 0;
}

TEST(sequence_streams_with_bounded_memory) {
    for (int f = 1; f <= 5; f++) {
        char name[64];
        snprintf(name, sizeof name, "seq_%04d.exr", f);
        CHECK_EQ_INT(write_render(tmp(name), 40, 30, 0.2f * f), 0);
    }
    const char *json = fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\"}},"
                                 "\"d\": {\"type\": \"denoise\", \"inputs\": {\"color\": \"r.color\", \"albedo\": \"r.albedo\"}},"
                                 "\"t\": {\"type\": \"temporal\", \"inputs\": {\"color\": \"d\", \"normal\": \"r.normal\"}},"
                                 "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"%s\"}, \"inputs\": {\"image\": \"t\"}}}}",
                                 tmp("seq_####.exr"), tmp("out_####.exr"));
    ew_graph *g = graph_from(json);
    CHECK(g);
    /* one frame, then all five frames found on disk: the same buffers */
    CHECK_EQ_INT(ew_graph_set_frames(g, 1, 1), EW_OK);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    ew_graph_stats one;
    ew_graph_get_stats(g, &one);
    ew_graph_destroy(g);
    g = graph_from(json);
    CHECK(g);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    ew_graph_stats all;
    ew_graph_get_stats(g, &all);
    CHECK_EQ_INT(all.frames_done, 5);
    CHECK_EQ_INT(all.num_buffers, one.num_buffers);
    CHECK_EQ_INT(all.buffer_bytes, one.buffer_bytes);
    CHECK(exists(tmp("out_0001.exr")) && exists(tmp("out_0005.exr")));
    CHECK_STR_CONTAINS(ew_graph_report(g), "out_0005.exr");
    ew_graph_destroy(g);
}

TEST(frame_pattern_matching_nothing) {
    char msg[2048];
    CHECK_EQ_INT(validate_text(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\"}},"
                                         "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"%s\"}, \"inputs\": {\"image\": \"r.color\"}}}}",
                                         tmp("none_####.exr"), tmp("o_####.exr")), msg, sizeof msg),
                 EW_ERR_IO);
    CHECK_STR_CONTAINS(msg, "node 'r' parameter 'path': the frame pattern");
    CHECK_STR_CONTAINS(msg, "none_####.exr' matches no file");
    /* an explicit range with a missing frame names the file */
    CHECK_EQ_INT(write_render(tmp("gap_0001.exr"), 8, 8, 0.5f), 0);
    CHECK_EQ_INT(validate_text(fmt_graph("{\"edgewise_graph\": 1, \"frames\": \"1-2\", \"nodes\": {"
                                         "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\"}},"
                                         "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"%s\"}, \"inputs\": {\"image\": \"r.color\"}}}}",
                                         tmp("gap_####.exr"), tmp("o_####.exr")), msg, sizeof msg),
                 EW_ERR_IO);
    CHECK_STR_CONTAINS(msg, "frame 2 of");
    CHECK_STR_CONTAINS(msg, "gap_0002.exr");
}

TEST(unknown_passes_and_layers) {
    CHECK_EQ_INT(write_render(tmp("one.exr"), 8, 8, 0.5f), 0);
    char msg[2048];
    CHECK_EQ_INT(validate_text(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\", \"pass\": \"Emit\"}},"
                                         "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"r.image\"}}}}", tmp("one.exr")),
                               msg, sizeof msg),
                 EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "node 'r': parameter 'pass': no pass 'Emit' in layer 'ViewLayer'");
    CHECK_STR_CONTAINS(msg, "'Denoising Albedo'");
    CHECK_EQ_INT(validate_text(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\"}},"
                                         "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"r.vector\"}}}}", tmp("one.exr")),
                               msg, sizeof msg),
                 EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "node 'r': output 'vector': layer 'ViewLayer' of");
    CHECK_STR_CONTAINS(msg, "has no vector pass (looked for 'Vector'");
    CHECK_EQ_INT(validate_text(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\", \"layer\": \"Nope\"}},"
                                         "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"r.color\"}}}}", tmp("one.exr")),
                               msg, sizeof msg),
                 EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "parameter 'layer': no layer 'Nope'");
    /* a pass read by name */
    ew_graph *g = graph_from(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\", \"pass\": \"Depth\"}},"
                                       "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"r.image\"}}}}", tmp("one.exr")));
    CHECK(g);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    ew_image v;
    CHECK_EQ_INT(ew_graph_get_output(g, "o", &v), EW_OK);
    CHECK_EQ_INT(v.channels, 1);
    CHECK_NEAR(((float *)v.data)[1], 3.01, 1e-5);
    ew_graph_destroy(g);
}

TEST(refuses_to_overwrite_an_input) {
    CHECK_EQ_INT(write_render(tmp("keep.exr"), 8, 8, 0.5f), 0);
    struct stat before;
    stat(tmp("keep.exr"), &before);
    char msg[2048];
    CHECK_EQ_INT(validate_text(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\"}},"
                                         "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"%s\"}, \"inputs\": {\"image\": \"r.color\"}}}}",
                                         tmp("keep.exr"), tmp("keep.exr")), msg, sizeof msg),
                 EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "node 'w' parameter 'path': refusing to write");
    CHECK_STR_CONTAINS(msg, "it is an input of the graph (node 'r'");
    /* through a symbolic link and another spelling of the path */
    unlink(tmp("link.exr"));
    CHECK_EQ_INT(symlink(tmp("keep.exr"), tmp("link.exr")), 0);
    CHECK_EQ_INT(validate_text(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s/./keep.exr\"}},"
                                         "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"%s\"}, \"inputs\": {\"image\": \"r.color\"}}}}",
                                         tmpdir, tmp("link.exr")), msg, sizeof msg),
                 EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(msg, "refusing to write");
    struct stat after;
    stat(tmp("keep.exr"), &after);
    CHECK(after.st_mtime == before.st_mtime && after.st_size == before.st_size);
}

TEST(unwritable_output_mid_sequence_keeps_earlier_frames) {
    for (int f = 1; f <= 3; f++) {
        char name[64];
        snprintf(name, sizeof name, "mid_%04d.exr", f);
        CHECK_EQ_INT(write_render(tmp(name), 16, 12, 0.3f * f), 0);
    }
    /* frame 2's output path is taken by a directory: the write fails there */
    mkdir(tmp("res_0002.exr"), 0755);
    ew_graph *g = graph_from(fmt_graph(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"%s\"}},"
                                       "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"%s\"}, \"inputs\": {\"image\": \"r.color\"}}}}",
                                       tmp("mid_####.exr"), tmp("res_####.exr")));
    CHECK(g);
    CHECK_EQ_INT(ew_graph_run(g), EW_ERR_IO);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "node 'w': frame 2:");
    CHECK(exists(tmp("res_0001.exr")));
    CHECK(!exists(tmp("res_0003.exr")));
    ew_graph_stats st;
    ew_graph_get_stats(g, &st);
    CHECK_EQ_INT(st.frames_done, 1);
    CHECK_STR_CONTAINS(ew_graph_report(g), "\"frames_done\": 1");
    ew_graph_destroy(g);
}

TEST(relative_paths_are_relative_to_the_graph_file) {
    CHECK_EQ_INT(write_render(tmp("rel_in.exr"), 8, 8, 0.5f), 0);
    FILE *f = fopen(tmp("rel.json"), "w");
    CHECK(f);
    fputs(HEAD "\"r\": {\"type\": \"read\", \"params\": {\"path\": \"rel_in.exr\"}},"
          "\"w\": {\"type\": \"write\", \"params\": {\"path\": \"rel_out.png\"}, \"inputs\": {\"image\": \"r.color\"}}}}", f);
    fclose(f);
    ew_graph *g = NULL;
    ew_graph_create(NULL, &g);
    CHECK_EQ_INT(ew_graph_load_file(g, tmp("rel.json")), EW_OK);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    CHECK(exists(tmp("rel_out.png")));
    ew_graph_destroy(g);
    ew_graph_create(NULL, &g);
    CHECK_EQ_INT(ew_graph_load_file(g, tmp("no_such.json")), EW_ERR_IO);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "cannot read graph");
    ew_graph_destroy(g);
}

/* ---- colour --------------------------------------------------------------- */

TEST(colour_transforms) {
    float px[3] = {0.18f, 0.18f, 0.18f};
    ew_graph *g = graph_from(HEAD "\"a\": {\"type\": \"input\"},"
                             "\"c\": {\"type\": \"colorspace\", \"params\": {\"from\": \"scene_linear\", \"to\": \"sRGB\"}, \"inputs\": {\"color\": \"a\"}},"
                             "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"c\"}}}}");
    CHECK(g);
    ew_image v = ew_image_packed(px, 1, 1, 3);
    ew_graph_set_input(g, "a", &v);
    CHECK_EQ_INT(ew_graph_run(g), EW_OK);
    ew_image o;
    ew_graph_get_output(g, "o", &o);
    CHECK_NEAR(((float *)o.data)[0], 0.4613, 2e-3); /* the sRGB curve at 18 % grey */
    ew_graph_destroy(g);

    char msg[2048];
    CHECK_EQ_INT(validate_text(HEAD "\"a\": {\"type\": \"input\"},"
                               "\"c\": {\"type\": \"display\", \"params\": {\"view\": \"Nope\"}, \"inputs\": {\"color\": \"a\"}},"
                               "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"c\"}}}}", msg, sizeof msg),
                 EW_OK); /* OCIO names are checked when the run starts */
    g = graph_from(HEAD "\"a\": {\"type\": \"input\"},"
                   "\"c\": {\"type\": \"display\", \"params\": {\"view\": \"Nope\"}, \"inputs\": {\"color\": \"a\"}},"
                   "\"o\": {\"type\": \"output\", \"inputs\": {\"image\": \"c\"}}}}");
    CHECK(g);
    ew_graph_set_input(g, "a", &v);
    CHECK_EQ_INT(ew_graph_run(g), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_graph_last_error(g), "node 'c': unknown view 'Nope' for display");
    ew_graph_destroy(g);
    char config[512];
    ew_nodes_color_config(config, sizeof config);
    fprintf(stderr, "  colour config: %s\n", config);
}
