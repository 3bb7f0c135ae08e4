/*
 * cycles_passes.h — which passes of a Cycles render layer feed a denoiser:
 * the noisy colour ("Noisy Image" when Blender's own denoiser ran, else
 * "Combined"), and the feature passes with their fallbacks.
 */
#ifndef EW_CYCLES_PASSES_H
#define EW_CYCLES_PASSES_H

#include <stddef.h>

#include "ewio.h"

typedef struct ew_layer_passes {
    char layer[256];         /* view layer name ("" for a plain RGB file); a copy,
                                because ewio_set_pass may move the file's strings */
    const char *color;       /* pass name of the noisy colour */
    const char *color_comps; /* "RGB" or "RGBA" */
    const char *albedo;      /* NULL when absent */
    const char *normal;      /* NULL when absent; "Denoising Normal" is camera space */
    const char *depth;       /* NULL when absent */
} ew_layer_passes;

/* Find the passes of `layer`. Returns 0 when the layer has a colour pass,
 * non-zero with a message otherwise (naming the layers found). */
int ew_find_layer_passes(const ewio_file *f, const char *layer, ew_layer_passes *out, char *err, size_t errlen);

/* The names of all layers, comma-separated, quoted, for messages. */
void ew_list_layers(const ewio_file *f, char *buf, size_t len);

#endif
