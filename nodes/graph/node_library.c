/*
 * node_library.c — nodes that run a libedgewise method: "denoise" and
 * "filter" (method chosen by a parameter) and nodes bound to one filter
 * ("pyramid", "bilateral", "atrous", "dof", "outlier"). Their images and parameters
 * come from the library's introspection (node_registry.c); here they are
 * handed to the library's ew_op_* unchanged.
 */
#include <stdlib.h>
#include <string.h>

#include "graph.h"

typedef struct {
    ew_op *op;
    ew_run *run; /* the run in progress, for the progress trampoline */
} lib_state;

static int is_denoiser(const ew_gnode *n) { return !strcmp(n->type->lib_kind, "denoiser"); }

static void lib_release(ew_gnode *n) {
    lib_state *s = (lib_state *)n->state;
    if (s) ew_op_destroy(s->op);
    free(s);
    n->state = NULL;
}

static int lib_progress(void *user, double fraction) {
    lib_state *s = (lib_state *)user;
    return s->run ? ew_run_progress(s->run, fraction) : 1;
}

static ew_result lib_error(ew_gnode *n, ew_result r, const char *what) {
    const char *msg = ew_device_last_error(n->g->dev)[0] ? ew_device_last_error(n->g->dev) : ew_result_string(r);
    if (what[0]) return ew_node_fail(n, r, "%s %s '%s': %s", what, n->type->lib_kind, n->sig.method, msg);
    return ew_node_fail(n, r, "%s '%s': %s", n->type->lib_kind, n->sig.method, msg);
}

/* Create the method once per validated graph and give it the parameters. */
static ew_result lib_prepare(ew_gnode *n, ew_run *r) {
    (void)r;
    ew_device *dev = n->g->dev;
    if (n->state) lib_release(n);
    lib_state *s = (lib_state *)calloc(1, sizeof *s);
    if (!s) return ew_node_fail(n, EW_ERR_OUT_OF_MEMORY, "out of memory");
    n->state = s;
    ew_result res = ew_op_create(dev, n->sig.method, &s->op);
    if (res != EW_OK) return lib_error(n, res, "cannot create");
    for (int i = n->sig.num_static_params; i < n->sig.num_params && res == EW_OK; i++) {
        const ew_nparam_desc *p = &n->sig.params[i];
        double v = n->values[i].num;
        if (p->type == EW_NODE_PARAM_FLOAT)
            res = ew_op_set_float(s->op, p->name, (float)v);
        else /* int, bool, and an enum's choice index */
            res = ew_op_set_int(s->op, p->name, (int32_t)v);
        if (res != EW_OK)
            return ew_node_fail(n, res, "parameter '%s': %s", p->name, ew_device_last_error(dev));
    }
    res = ew_op_set_progress(s->op, lib_progress, s);
    return res == EW_OK ? EW_OK : lib_error(n, res, "");
}

static ew_result set_image(lib_state *s, const char *name, const ew_image *v) { return ew_op_set_image(s->op, name, v); }

static ew_result lib_execute(ew_gnode *n, ew_run *r) {
    lib_state *s = (lib_state *)n->state;
    s->run = r;
    const ew_image *first = NULL;
    ew_result res = EW_OK;
    for (int p = 0; p < n->sig.num_inputs && res == EW_OK; p++) {
        const ew_image *v = n->has_in[p] ? &n->in[p] : NULL;
        if (v && !first) first = v;
        res = set_image(s, n->sig.inputs[p].name, v); /* NULL unsets what an earlier frame set */
        if (res != EW_OK) return ew_node_fail(n, res, "input '%s': %s", n->sig.inputs[p].name, ew_device_last_error(n->g->dev));
    }
    if (!first) return ew_node_fail(n, EW_ERR_INVALID_STATE, "no input connected");
    const ew_image *color = ew_node_in(n, "color");
    for (int o = 0; o < n->sig.num_outputs; o++) {
        const ew_port_desc *d = &n->sig.outputs[o];
        int is_main = !strcmp(d->name, "output");
        if (!is_main && !ew_node_output_wanted(n, o)) {
            set_image(s, d->name, NULL);
            continue;
        }
        /* A denoiser's output has its documented channels; a filter's as
         * many as the image it filters. */
        int c = d->min_channels;
        if (is_main && !is_denoiser(n) && color) c = color->channels;
        if (c < 1) c = 1;
        ew_image v;
        res = ew_run_output(r, n, o, first->width, first->height, c, &v);
        if (res == EW_OK) res = set_image(s, d->name, &v);
        if (res != EW_OK) return ew_node_fail(n, res, "output '%s': %s", d->name, ew_device_last_error(n->g->dev));
    }
    /* The render's sample count from the colour's metadata when the
     * parameter is left at 0 (unknown), so "auto" chooses as the CLI does
     * for the same file; set every frame, as frames may differ. */
    const int sp = ew_sig_find_param(&n->sig, "samples");
    const int ci = ew_sig_find_input(&n->sig, "color");
    if (sp >= n->sig.num_static_params && n->values[sp].num == 0.0 && ci >= 0) {
        const int spp = n->has_in[ci] ? n->in_samples[ci] : 0;
        res = ew_op_set_int(s->op, "samples", spp);
        if (res != EW_OK) return ew_node_fail(n, res, "parameter 'samples': %s", ew_device_last_error(n->g->dev));
    }
    res = ew_op_commit(s->op);
    if (res == EW_OK) res = ew_op_execute(s->op);
    s->run = NULL;
    if (res == EW_ERR_CANCELLED || r->cancelled) return ew_node_fail(n, EW_ERR_CANCELLED, "cancelled (frame %d)", r->frame);
    if (res != EW_OK) return lib_error(n, res, "");
    if (is_denoiser(n)) ew_run_report_method(r, n, ew_op_describe(s->op)); /* e.g. what "auto" picked */
    return EW_OK;
}

static const ew_nparam_desc denoise_params[] = {
    {"method", EW_NODE_PARAM_ENUM, 0, 0, 0, NULL, {0, 0, 0, 0}, NULL, 0, 0, "Method",
     "the library denoiser; its parameters follow (edgewise nodes denoise)"},
};

static const ew_nparam_desc filter_params[] = {
    {"filter", EW_NODE_PARAM_ENUM, 0, 0, 0, NULL, {0, 0, 0, 0}, NULL, 0, 0, "Filter",
     "the library filter; its parameters follow (edgewise nodes filter)"},
};

#define LIB_NODE(var, nm, cat, sum, kind, method, plist, nparams)                                          \
    const ew_node_type var = {                                                                             \
        .name = nm, .version = 1, .category = cat, .summary = sum, .lib_kind = kind, .lib_method = method, \
        .params = plist, .num_params = nparams, .inplace_input = -1,                                       \
        .prepare = lib_prepare, .execute = lib_execute, .release = lib_release,                            \
    }

LIB_NODE(ew_node_denoise, "denoise", "denoise", "any libedgewise denoiser, chosen by 'method'", "denoiser", NULL,
         denoise_params, 1);
LIB_NODE(ew_node_filter, "filter", "filter", "any libedgewise edge-aware filter, chosen by 'filter'", "filter", NULL,
         filter_params, 1);
LIB_NODE(ew_node_pyramid, "pyramid", "filter", "pyramid edge-preserving filter (libedgewise filter 'pyramid')",
         "filter", "pyramid", NULL, 0);
LIB_NODE(ew_node_bilateral, "bilateral", "filter", "exact joint bilateral filter (libedgewise filter 'bilateral')",
         "filter", "bilateral", NULL, 0);
LIB_NODE(ew_node_atrous, "atrous", "filter", "edge-avoiding à-trous wavelet filter (libedgewise filter 'atrous')",
         "filter", "atrous", NULL, 0);
LIB_NODE(ew_node_dof, "dof", "filter", "depth of field from depth and camera values (libedgewise filter 'dof')",
         "filter", "dof", NULL, 0);
LIB_NODE(ew_node_outlier, "outlier", "filter",
         "firefly suppression among neighbours of similar albedo and normal, NaN/Inf rebuilt (libedgewise filter "
         "'outlier')",
         "filter", "outlier", NULL, 0);
/* The history lives in the library filter between executes; prepare creates
 * the filter once per run, so every run starts from an empty history and
 * frames are accumulated in run order. */
LIB_NODE(ew_node_temporal, "temporal", "time",
         "temporal accumulation with reprojection across the frames of a run (libedgewise filter 'temporal')",
         "filter", "temporal", NULL, 0);
