/*
 * node_color.c — OpenColorIO nodes through the ewcolor shim: a colour-space
 * conversion and Blender's display/view transform (exposure, view, look,
 * gamma), so a preview written by a graph looks as it does in Blender.
 */
#include <stdlib.h>
#include <string.h>

#include "ewcolor.h"
#include "graph.h"

static const ew_port_desc color_in[] = {{"color", EW_PASS_ANY, 3, 1, "RGB or RGBA image (alpha passed through)"}};
static const ew_port_desc color_out[] = {{"output", EW_PASS_COLOR, 3, 0, "the transformed image"}};

static const ew_nparam_desc colorspace_params[] = {
    {"from", EW_NODE_PARAM_STRING, 0, 0, 0, "scene_linear", {0, 0, 0, 0}, NULL, 0, 0, "From",
     "source colour space or role of the OCIO config"},
    {"to", EW_NODE_PARAM_STRING, 0, 0, 0, "sRGB", {0, 0, 0, 0}, NULL, 0, 0, "To", "destination colour space or role"},
};

static const ew_nparam_desc display_params[] = {
    {"display", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Display",
     "OCIO display, e.g. 'sRGB'; empty: the config's default"},
    {"view", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "View",
     "view transform, e.g. 'Standard' or 'Filmic' (Blender's default scene setting); empty: the display's default"},
    {"look", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Look",
     "look, e.g. 'Filmic - High Contrast' in Blender's config; empty: none"},
    {"exposure", EW_NODE_PARAM_FLOAT, 0.0, -32.0, 32.0, "", {0, 0, 0, 0}, NULL, 0, 0, "Exposure",
     "stops, applied in scene linear (Blender: Color Management > Exposure)"},
    {"gamma", EW_NODE_PARAM_FLOAT, 1.0, 0.01, 100.0, "", {0, 0, 0, 0}, NULL, 0, 0, "Gamma",
     "display gamma (Blender: Color Management > Gamma)"},
    {"from", EW_NODE_PARAM_STRING, 0, 0, 0, "scene_linear", {0, 0, 0, 0}, NULL, 0, 0, "From",
     "colour space of the input"},
};

static void color_release(ew_gnode *n) {
    ewcolor_free((ewcolor_proc *)n->state);
    n->state = NULL;
}

static ew_result colorspace_prepare(ew_gnode *n, ew_run *r) {
    (void)r;
    char err[1024];
    color_release(n);
    ewcolor_proc *p = NULL;
    if (ewcolor_transform(ew_node_str(n, "from"), ew_node_str(n, "to"), &p, err, sizeof err) != 0)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "%s", err);
    n->state = p;
    return EW_OK;
}

static ew_result display_prepare(ew_gnode *n, ew_run *r) {
    (void)r;
    char err[1024];
    color_release(n);
    ewcolor_proc *p = NULL;
    if (ewcolor_display(ew_node_str(n, "from"), ew_node_str(n, "display"), ew_node_str(n, "view"),
                        ew_node_str(n, "look"), (float)ew_node_num(n, "exposure"), (float)ew_node_num(n, "gamma"), &p,
                        err, sizeof err) != 0)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "%s", err);
    n->state = p;
    return EW_OK;
}

static ew_result color_execute(ew_gnode *n, ew_run *r) {
    const ew_image *in = ew_node_in(n, "color");
    if (in->channels != 3 && in->channels != 4)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "input 'color' has %d channels: colour transforms take 3 or 4",
                            in->channels);
    ew_image out;
    ew_result res = ew_run_output(r, n, 0, in->width, in->height, in->channels, &out);
    if (res != EW_OK) return res;
    if (out.data != in->data)
        for (int y = 0; y < in->height; y++)
            for (int x = 0; x < in->width; x++) memcpy(ew_px(&out, x, y), ew_px(in, x, y), (size_t)in->channels * 4);
    ewcolor_apply((const ewcolor_proc *)n->state, (float *)out.data, out.width, out.height, out.channels);
    return EW_OK;
}

const ew_node_type ew_node_colorspace = {
    .name = "colorspace", .version = 1, .category = "color",
    .summary = "OpenColorIO colour-space conversion",
    .inputs = color_in, .num_inputs = 1, .outputs = color_out, .num_outputs = 1,
    .params = colorspace_params, .num_params = 2, .inplace_input = 0,
    .prepare = colorspace_prepare, .execute = color_execute, .release = color_release,
};

const ew_node_type ew_node_display = {
    .name = "display", .version = 1, .category = "color",
    .summary = "OpenColorIO display/view transform as Blender applies it (exposure, view, look, gamma)",
    .inputs = color_in, .num_inputs = 1, .outputs = color_out, .num_outputs = 1,
    .params = display_params, .num_params = 6, .inplace_input = 0,
    .prepare = display_prepare, .execute = color_execute, .release = color_release,
};
