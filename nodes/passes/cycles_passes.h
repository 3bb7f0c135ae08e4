/*
 * cycles_passes.h — which passes of a Cycles render layer a command reads:
 * the colour and the feature passes with their fallbacks. Two colours:
 * - a denoiser's input is the noisy colour: "Noisy Image" when a denoiser
 *   (Blender's, or `edgewise denoise`) already ran and kept the original,
 *   else "Combined" (ew_find_layer_passes);
 * - everything else (compare, info, filters, DoF, the graph's read.color)
 *   works on the image the file shows, "Combined" (ew_find_image_passes):
 *   on a denoised file the noisy original is not the picture.
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
    int skip_vector;         /* 0 as found; a caller whose method takes no motion vectors sets 1, and
                                ew_layer_data_read leaves the Vector pass unread */
} ew_layer_passes;

/* Find the passes of `layer` for a denoiser (colour: "Noisy Image", else
 * "Combined", else a plain R,G,B). Returns 0 when the layer has a colour
 * pass, non-zero with a message otherwise (naming the layers found). */
int ew_find_layer_passes(const ewio_file *f, const char *layer, ew_layer_passes *out, char *err, size_t errlen);
/* The same for the image the file shows (colour: "Combined", else a plain
 * R,G,B, else "Noisy Image"). */
int ew_find_image_passes(const ewio_file *f, const char *layer, ew_layer_passes *out, char *err, size_t errlen);

/* The names of all layers, comma-separated, quoted, for messages. */
void ew_list_layers(const ewio_file *f, char *buf, size_t len);

#endif
