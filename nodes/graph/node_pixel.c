/*
 * node_pixel.c — small per-pixel nodes written here because the library has
 * no public method for them: albedo demodulation and remodulation (firefly
 * suppression is the library's filter "outlier", node_library.c), and the arithmetic that wires passes together (add,
 * multiply, mix, channel shuffle).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "graph.h"

/* b's channel k for a's channel k: a one-channel b applies to every
 * channel; channels b lacks (alpha) are left alone (returns 0). */
static int b_value(const ew_image *b, const float *bp, int k, float *out) {
    if (b->channels == 1) {
        if (k >= 3) return 0;
        *out = bp[0];
        return 1;
    }
    if (k >= b->channels) return 0;
    *out = bp[k];
    return 1;
}

/* ---- albedo demodulation ------------------------------------------------- */

static const ew_port_desc modulate_in[] = {
    {"color", EW_PASS_COLOR, 3, 1, "colour (RGB or RGBA; alpha is passed through)"},
    {"albedo", EW_PASS_ALBEDO, 3, 1, "albedo (Cycles: Denoising Albedo)"},
};
/* As the denoisers demodulate (EW_ALBEDO_EPSILON): colour / (albedo +
 * epsilon), a damaged or negative albedo counting as black, so that a graph
 * that demodulates around a filter feeds it what the library's methods see. */
static const ew_port_desc demodulate_out[] = {{"output", EW_PASS_COLOR, 3, 0, "colour / (albedo + epsilon)"}};
static const ew_port_desc remodulate_out[] = {{"output", EW_PASS_COLOR, 3, 0, "colour * (albedo + epsilon)"}};
static const ew_nparam_desc modulate_params[] = {
    {"epsilon", EW_NODE_PARAM_FLOAT, EW_ALBEDO_EPSILON, 1e-6, 1.0, "", {0, 0, 0, 0}, NULL, 0, 0, "Epsilon",
     "added to the albedo before dividing, so black albedo amplifies noise at most 1/epsilon times; the "
     "denoisers' value by default; use the same value to remodulate"},
};

static ew_result modulate(ew_gnode *n, ew_run *r, int divide) {
    const ew_image *col = ew_node_in(n, "color"), *alb = ew_node_in(n, "albedo");
    const float eps = (float)ew_node_num(n, "epsilon");
    ew_image out;
    ew_result res = ew_run_output(r, n, 0, col->width, col->height, col->channels, &out);
    if (res != EW_OK) return res;
    for (int y = 0; y < col->height; y++)
        for (int x = 0; x < col->width; x++) {
            const float *p = ew_px(col, x, y), *a = ew_px(alb, x, y);
            float *o = ew_px(&out, x, y);
            for (int ch = 0; ch < col->channels; ch++) {
                if (ch >= 3) {
                    o[ch] = p[ch];
                    continue;
                }
                const float d = (isfinite(a[ch]) && a[ch] > 0.0f ? a[ch] : 0.0f) + eps;
                o[ch] = divide ? p[ch] / d : p[ch] * d;
            }
        }
    return EW_OK;
}

static ew_result demodulate_execute(ew_gnode *n, ew_run *r) { return modulate(n, r, 1); }
static ew_result remodulate_execute(ew_gnode *n, ew_run *r) { return modulate(n, r, 0); }

const ew_node_type ew_node_demodulate = {
    .name = "demodulate", .version = 1, .category = "denoise",
    .summary = "divide the colour by the albedo (filter the lighting, not the textures)",
    .inputs = modulate_in, .num_inputs = 2, .outputs = demodulate_out, .num_outputs = 1,
    .params = modulate_params, .num_params = 1, .inplace_input = 0, .execute = demodulate_execute,
};

const ew_node_type ew_node_remodulate = {
    .name = "remodulate", .version = 1, .category = "denoise",
    .summary = "multiply the colour by the albedo again (the inverse of demodulate)",
    .inputs = modulate_in, .num_inputs = 2, .outputs = remodulate_out, .num_outputs = 1,
    .params = modulate_params, .num_params = 1, .inplace_input = 0, .execute = remodulate_execute,
};

/* ---- add, multiply, mix ------------------------------------------------- */

static const ew_port_desc ab_in[] = {
    {"a", EW_PASS_ANY, 1, 1, "first image; the result has its channels"},
    {"b", EW_PASS_ANY, 1, 0, "second image (1 channel applies to R,G,B); absent: 'value'"},
};
static const ew_port_desc math_out[] = {{"output", EW_PASS_ANY, 1, 0, "the result"}};
static const ew_nparam_desc add_params[] = {
    {"value", EW_NODE_PARAM_COLOR, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Value", "added when 'b' is not connected"},
};
static const ew_nparam_desc multiply_params[] = {
    {"value", EW_NODE_PARAM_COLOR, 0, 0, 0, "", {1, 1, 1, 1}, NULL, 0, 0, "Value",
     "multiplied by when 'b' is not connected"},
};

static ew_result arith(ew_gnode *n, ew_run *r, int mul) {
    const ew_image *a = ew_node_in(n, "a"), *b = ew_node_in(n, "b");
    const ew_pvalue *val = ew_node_value(n, "value");
    ew_image out;
    ew_result res = ew_run_output(r, n, 0, a->width, a->height, a->channels, &out);
    if (res != EW_OK) return res;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *pa = ew_px(a, x, y);
            const float *pb = b ? ew_px(b, x, y) : NULL;
            float *o = ew_px(&out, x, y);
            for (int k = 0; k < a->channels; k++) {
                float v;
                if (pb) {
                    if (!b_value(b, pb, k, &v)) {
                        o[k] = pa[k];
                        continue;
                    }
                } else {
                    v = val->color[k];
                }
                o[k] = mul ? pa[k] * v : pa[k] + v;
            }
        }
    return EW_OK;
}

static ew_result add_execute(ew_gnode *n, ew_run *r) { return arith(n, r, 0); }
static ew_result multiply_execute(ew_gnode *n, ew_run *r) { return arith(n, r, 1); }

const ew_node_type ew_node_add = {
    .name = "add", .version = 1, .category = "math", .summary = "a + b (or a + value)",
    .inputs = ab_in, .num_inputs = 2, .outputs = math_out, .num_outputs = 1,
    .params = add_params, .num_params = 1, .inplace_input = 0, .execute = add_execute,
};

const ew_node_type ew_node_multiply = {
    .name = "multiply", .version = 1, .category = "math", .summary = "a * b (or a * value)",
    .inputs = ab_in, .num_inputs = 2, .outputs = math_out, .num_outputs = 1,
    .params = multiply_params, .num_params = 1, .inplace_input = 0, .execute = multiply_execute,
};

static const ew_port_desc mix_in[] = {
    {"a", EW_PASS_ANY, 1, 1, "image at factor 0; the result has its channels"},
    {"b", EW_PASS_ANY, 1, 1, "image at factor 1"},
    {"mask", EW_PASS_ANY, 1, 0, "optional per-pixel factor (first channel), multiplied by 'factor'"},
};
static const ew_nparam_desc mix_params[] = {
    {"factor", EW_NODE_PARAM_FLOAT, 0.5, 0.0, 1.0, "", {0, 0, 0, 0}, NULL, 0, 0, "Factor", "0: a, 1: b"},
};

static ew_result mix_execute(ew_gnode *n, ew_run *r) {
    const ew_image *a = ew_node_in(n, "a"), *b = ew_node_in(n, "b"), *m = ew_node_in(n, "mask");
    const float f = (float)ew_node_num(n, "factor");
    ew_image out;
    ew_result res = ew_run_output(r, n, 0, a->width, a->height, a->channels, &out);
    if (res != EW_OK) return res;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *pa = ew_px(a, x, y), *pb = ew_px(b, x, y);
            float t = m ? f * ew_px(m, x, y)[0] : f;
            float *o = ew_px(&out, x, y);
            for (int k = 0; k < a->channels; k++) {
                float v;
                o[k] = b_value(b, pb, k, &v) ? pa[k] + (v - pa[k]) * t : pa[k];
            }
        }
    return EW_OK;
}

const ew_node_type ew_node_mix = {
    .name = "mix", .version = 1, .category = "math", .summary = "a + (b - a) * factor (* mask)",
    .inputs = mix_in, .num_inputs = 3, .outputs = math_out, .num_outputs = 1,
    .params = mix_params, .num_params = 1, .inplace_input = 0, .execute = mix_execute,
};

/* ---- shuffle -------------------------------------------------------------- */

static const ew_port_desc shuffle_in[] = {{"image", EW_PASS_ANY, 1, 1, "source image"}};
static const ew_nparam_desc shuffle_params[] = {
    {"channels", EW_NODE_PARAM_STRING, 0, 0, 0, "RGB", {0, 0, 0, 0}, NULL, 0, 0, "Channels",
     "one letter per output channel: R/X first, G/Y second, B/Z third, A/W fourth source channel, 0 or 1 a "
     "constant; e.g. 'BGR', 'RGB1', 'ZZZ', 'A'"},
};

static int shuffle_source(char c) {
    switch (c) {
    case 'R': case 'X': case 'r': case 'x': return 0;
    case 'G': case 'Y': case 'g': case 'y': return 1;
    case 'B': case 'Z': case 'b': case 'z': return 2;
    case 'A': case 'W': case 'a': case 'w': return 3;
    case '0': return -1;
    case '1': return -2;
    default: return -3;
    }
}

static ew_result shuffle_check(ew_gnode *n) {
    const char *s = ew_node_str(n, "channels");
    size_t len = strlen(s);
    if (len < 1 || len > 4)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'channels': '%s' must have 1 to 4 letters", s);
    for (size_t i = 0; i < len; i++)
        if (shuffle_source(s[i]) == -3)
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT,
                                "parameter 'channels': '%c' is not one of R G B A, X Y Z W, 0 1", s[i]);
    return EW_OK;
}

static ew_result shuffle_execute(ew_gnode *n, ew_run *r) {
    const ew_image *in = ew_node_in(n, "image");
    const char *s = ew_node_str(n, "channels");
    const int c = (int)strlen(s);
    int src[4];
    for (int i = 0; i < c; i++) {
        src[i] = shuffle_source(s[i]);
        if (src[i] >= in->channels)
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'channels': '%c' needs channel %d but the image "
                                "has %d", s[i], src[i] + 1, in->channels);
    }
    ew_image out;
    ew_result res = ew_run_output(r, n, 0, in->width, in->height, c, &out);
    if (res != EW_OK) return res;
    for (int y = 0; y < in->height; y++)
        for (int x = 0; x < in->width; x++) {
            const float *p = ew_px(in, x, y);
            float *o = ew_px(&out, x, y);
            float tmp[4];
            for (int i = 0; i < c; i++) tmp[i] = src[i] >= 0 ? p[src[i]] : src[i] == -1 ? 0.0f : 1.0f;
            memcpy(o, tmp, (size_t)c * sizeof(float)); /* safe in place */
        }
    return EW_OK;
}

const ew_node_type ew_node_shuffle = {
    .name = "shuffle", .version = 1, .category = "math", .summary = "reorder, pick or add channels",
    .inputs = shuffle_in, .num_inputs = 1, .outputs = math_out, .num_outputs = 1,
    .params = shuffle_params, .num_params = 1, .inplace_input = 0,
    .check = shuffle_check, .execute = shuffle_execute,
};
