/*
 * ewio.h — C interface to the OpenImageIO shim (ewio.cpp), the only place
 * that reads or writes image files.
 *
 * A file is loaded whole into memory: every channel as float32, plus the
 * header metadata, so it can be written back with some passes replaced or
 * added while all other layers, channels and metadata are kept.
 *
 * Channel naming follows Blender's multilayer EXR:
 *   "<layer>.<pass>.<component>", e.g. "ViewLayer.Denoising Albedo.R".
 * A plain file (PNG/TIFF/flat EXR with R,G,B[,A]) has one layer named ""
 * with one pass named "" whose components are R,G,B[,A].
 *
 * Every function returning int returns 0 on success and non-zero on failure,
 * with a one-line message (no trailing newline) in err (if err != NULL).
 */
#ifndef EDGEWISE_EWIO_H
#define EDGEWISE_EWIO_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ewio_file ewio_file;

/* Read a whole image file (EXR, multilayer EXR, PNG, TIFF, anything OIIO
 * reads). Fails cleanly on missing, unreadable, truncated or non-image files,
 * on zero/negative dimensions and on images above 65536 px per side or 2^28
 * pixels. Multi-part EXRs: all parts of the same size are merged. */
int ewio_read(const char *path, ewio_file **out, char *err, size_t errlen);
void ewio_free(ewio_file *f); /* NULL is a no-op */

int ewio_width(const ewio_file *f);
int ewio_height(const ewio_file *f);
int ewio_num_channels(const ewio_file *f);
const char *ewio_channel_name(const ewio_file *f, int i);

/* Layers in order of first appearance. A plain RGB(A) file has one layer "". */
int ewio_num_layers(const ewio_file *f);
const char *ewio_layer_name(const ewio_file *f, int i);

/* Copy pass `pass` of `layer` into `dst` as interleaved float32,
 * width*height*strlen(comps) floats, components in the order of `comps`
 * (one letter each: "RGB", "XYZ", "Z", "RGBA"...). Returns non-zero with a
 * message naming what is missing if any component is absent. */
int ewio_get_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps,
                  float *dst, char *err, size_t errlen);
/* 1 if all components of the pass exist. */
int ewio_has_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps);

/* Replace the pass's channels (or add them, after the layer's other channels)
 * from interleaved float32 data of the file's size. */
int ewio_set_pass(ewio_file *f, const char *layer, const char *pass, const char *comps,
                  const float *src, char *err, size_t errlen);

/* Header metadata as text ("" if absent), e.g. "cycles.ViewLayer.samples". */
const char *ewio_get_attribute(const ewio_file *f, const char *name);
int ewio_set_attribute(ewio_file *f, const char *name, const char *value);

typedef enum ewio_pixel_type {
    EWIO_KEEP = 0,  /* each channel keeps the type it was read with (new ones: half) */
    EWIO_HALF = 1,
    EWIO_FLOAT = 2
} ewio_pixel_type;

/* Write atomically: to a temporary file in the destination directory, then
 * rename over `path`. On failure nothing at `path` is touched and the
 * temporary is removed. The format follows the extension; EXR keeps the
 * input's compression and all channels and metadata; PNG/TIFF/JPEG write
 * only the given layer's pass `pass` (e.g. "Combined" or "") as RGB(A).
 * Refuses to write over the file the data was read from (same inode). */
int ewio_write(const ewio_file *f, const char *path, ewio_pixel_type type,
               const char *layer, const char *pass, char *err, size_t errlen);

/* Create an empty in-memory file of the given size (for tests and for
 * writing library outputs that did not come from a file). */
int ewio_create(int width, int height, ewio_file **out, char *err, size_t errlen);

#ifdef __cplusplus
}
#endif

#endif /* EDGEWISE_EWIO_H */
