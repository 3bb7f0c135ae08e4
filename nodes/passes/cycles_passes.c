#include "cycles_passes.h"

#include <stdio.h>
#include <string.h>

void ew_list_layers(const ewio_file *f, char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; i < ewio_num_layers(f) && used < len; i++) {
        int k = snprintf(buf + used, len - used, "%s'%s'", i ? ", " : "", ewio_layer_name(f, i));
        if (k < 0) break;
        used += (size_t)k;
    }
}

static const char *first_present(const ewio_file *f, const char *layer, const char *comps,
                                 const char *const *names) {
    for (; *names; names++)
        if (ewio_has_pass(f, layer, *names, comps)) return *names;
    return NULL;
}

/* colors: the colour pass names in order of preference. */
static int find_passes(const ewio_file *f, const char *layer, const char *const *colors, ew_layer_passes *out,
                       char *err, size_t errlen) {
    static const char *const albedos[] = {"Denoising Albedo", "DiffCol", NULL};
    static const char *const normals[] = {"Denoising Normal", "Normal", NULL};
    static const char *const depths[] = {"Denoising Depth", "Depth", NULL};
    int found = 0;
    for (int i = 0; i < ewio_num_layers(f); i++) found |= strcmp(ewio_layer_name(f, i), layer) == 0;
    char layers[512];
    ew_list_layers(f, layers, sizeof layers);
    if (strlen(layer) >= sizeof out->layer) {
        snprintf(err, errlen, "layer name '%.64s...' is too long", layer);
        return 1;
    }
    if (!found) {
        snprintf(err, errlen, "no layer '%s' in the file (layers found: %s)", layer, layers);
        return 1;
    }
    memset(out, 0, sizeof *out);
    snprintf(out->layer, sizeof out->layer, "%s", layer);
    out->color = first_present(f, layer, "RGB", colors);
    if (!out->color) {
        snprintf(err, errlen, "layer '%s' has no colour pass (looked for %s and plain R,G,B; layers found: %s)",
                 layer, colors[0][0] == 'N' ? "Noisy Image, Combined" : "Combined, Noisy Image", layers);
        return 1;
    }
    out->color_comps = ewio_has_pass(f, layer, out->color, "RGBA") ? "RGBA" : "RGB";
    out->albedo = first_present(f, layer, "RGB", albedos);
    out->normal = first_present(f, layer, "XYZ", normals);
    out->depth = first_present(f, layer, "Z", depths);
    return 0;
}

int ew_find_layer_passes(const ewio_file *f, const char *layer, ew_layer_passes *out, char *err, size_t errlen) {
    static const char *const colors[] = {"Noisy Image", "Combined", "", NULL};
    return find_passes(f, layer, colors, out, err, errlen);
}

int ew_find_image_passes(const ewio_file *f, const char *layer, ew_layer_passes *out, char *err, size_t errlen) {
    /* "Noisy Image" is only a fallback: a layer that has it always has
     * Combined too (Blender writes both), but a hand-made file may not. */
    static const char *const colors[] = {"Combined", "", "Noisy Image", NULL};
    return find_passes(f, layer, colors, out, err, errlen);
}
