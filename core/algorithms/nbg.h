/*
 * nbg.h — pieces of the neural bilateral grid denoiser shared by the "nbg"
 * op (denoise_nbg.c), the trainer (train.c) and the tests: GuideNet's
 * forward pass over a whole image in bands of rows, and the models built
 * into the library.
 */
#ifndef EW_ALGORITHMS_NBG_H
#define EW_ALGORITHMS_NBG_H

#include <stddef.h>

#include "algorithms/guidenet.h"
#include "edgewise/edgewise.h"

/*
 * GuideNet over a width x height image, one band of rows at a time, so the
 * hidden activations (20 to 45 planes) never exist for the whole frame:
 * a band of B output rows needs 2 more rows per layer on each side, kept in
 * a buffer of ew_nbg_band_floats floats; rows outside the image are zero
 * (the SAME padding). The outputs (nout planes of width*height floats,
 * sigmoid values) are the only full-frame tensor.
 */
int ew_nbg_band_rows(const ew_guidenet *net, int height);
size_t ew_nbg_band_floats(const ew_guidenet *net, int width, int band_rows);

typedef struct ew_nbg_forward {
    const ew_guidenet *net;
    const float *params;   /* device memory, net->nparams floats */
    int width, height;
    const float *color, *albedo, *normal, *depth; /* device buffers, in_stride pixels a row */
    float depth_scale;
    float *band_mem;       /* ew_nbg_band_floats(net, width, band_rows) floats of device memory */
    int band_rows;
    float *outputs;        /* nout * width * height floats of device memory */
    long in_stride;        /* pixels a row of color, albedo, normal and depth (a tile's region of the
                              frame's, read where they lie); 0: width */
} ew_nbg_forward;

/* Runs on the device. progress (may be NULL) is called after each band with
 * the fraction done; returning 0 stops early with EW_ERR_CANCELLED. */
ew_result ew_nbg_guidenet_forward(ew_device *dev, const ew_nbg_forward *f, int (*progress)(void *, double),
                                  void *user);

/* Device floats the "nbg" op allocates for a width x height frame (one
 * allocation at commit; denoise_nbg.c lays it out): parameters, 3 + 3 + 3
 * + 1 input floats a pixel, radiance, clamped radiance, blend sum and one
 * grid's slice (3 each), nout GuideNet outputs, one band, and the largest
 * grid. */
size_t ew_nbg_device_floats(const ew_guidenet *net, int width, int height, size_t *grid_floats, size_t *band_floats);

/* ---- tiles (src/tiling.h) ------------------------------------------------
 * A frame above the op's max_memory_mb runs in tiles. A core pixel reads
 * the grid cells around it, which gather the pixels within 2 x rate_s + 1
 * of it, whose clamped radiance reads 2 pixels further (the 5x5 firefly
 * clamp) and whose guides read 2 x nlayers further (GuideNet's 5x5
 * layers): that is the halo, rounded up to the alignment. Region origins
 * are multiples of every grid's rate_s, so a region's cells are the
 * frame's cells shifted by whole cells; with rates that are powers of two
 * the tent weights (x + 0.5) / rate_s - 0.5 - u are then the same floats
 * and a tiled frame is the same bits as one pass. A model whose rates are
 * not powers of two has no exact tiling: ew_nbg_align returns 0 and the op
 * runs it whole. */
int ew_nbg_align(const ew_guidenet *net);
int ew_nbg_halo(const ew_guidenet *net);
/* Device floats of one rw x rh region beyond the frame's inputs (which a
 * region reads where they lie): radiance, clamped radiance, blend sum, one
 * grid's slice, the firefly clamp's removed light (when tiled), nout
 * GuideNet outputs, one band, and the largest grid. */
size_t ew_nbg_region_floats(const ew_guidenet *net, int rw, int rh, int tiled);

/* Built-in models, by the op's "model" parameter: 0 = 2layer-3grid (the
 * default, trained on 1-64 spp), 1 = 2layer-1grid, 2 = 7layer-3grid,
 * 3 = 2layer-3grid-1spp (the same net trained on 1-spp renders only). The
 * bytes are a weights file (size 0 when this build has none for that
 * model). */
#define EW_NBG_NUM_MODELS 4
const char *ew_nbg_model_name(int model);
/* The built-in models' names by index, NULL-terminated (the "model" enum). */
extern const char *const ew_nbg_model_names[EW_NBG_NUM_MODELS + 1];
void ew_nbg_builtin_weights(int model, const unsigned char **bytes, size_t *size);

#endif
