/*
 * ofx_fixtures.h — what the OFX tests share besides the host: the bundled
 * Cornell-box render (samples/cornell, read with ewio), the library's own
 * result for the same inputs and parameters, exact comparison, and the
 * set-up of a loaded plugin instance.
 */
#ifndef EW_TESTS_OFX_FIXTURES_H
#define EW_TESTS_OFX_FIXTURES_H

#include <stddef.h>

#include "ofx_host.h"

/* Top-down packed passes of one render. */
typedef struct fx_sample {
    int w, h;
    float *rgba;    /* Combined, 4 */
    float *albedo;  /* Denoising Albedo, 3 */
    float *normal;  /* Denoising Normal, 3 */
    float *ddepth;  /* Denoising Depth, 1 */
    float *depth;   /* Depth (planar camera depth, metres), 1 */
    int samples;    /* the file's cycles.ViewLayer.samples, 0 if absent */
} fx_sample;

/* Loads $EW_SAMPLE_DIR/cornell/f0001_spp0004.exr once per process (the
 * result is shared; do not free). NULL with a message on failure. */
const fx_sample *fx_cornell(char *err, size_t len);
/* A w x h window of a sample at column x0, row y0 (rows from the top). */
void fx_crop(const fx_sample *s, int x0, int y0, int w, int h, fx_sample *out);
void fx_free(fx_sample *s);

typedef struct fx_param {
    const char *name;
    double value;
} fx_param;

typedef struct fx_image {
    const char *name; /* library image name */
    const float *data; /* top-down, packed */
    int channels;
} fx_image;

/* The library's result for the plugin's policy: the method gets `channels`
 * channels of the source (src_comps per pixel); the RGBA result takes
 * alpha from the method (channels == 4), the source (src_comps == 4) or 1.
 * out: w*h*4. threads: device threads (0 = library default). 0 on success. */
int fx_reference(const char *kind, const char *method, int threads, int w, int h, const float *src, int src_comps,
                 int channels, const fx_image *aux, int num_aux, const fx_param *params, int num_params, float *out,
                 char *err, size_t len);

/* Floats that differ (NaN equals NaN); describes the first in msg. */
long fx_compare(const float *got, const float *want, size_t n, int comps, int width, char *msg, size_t len);

/* ---- a loaded plugin ---------------------------------------------------- */
typedef struct fx_plugin {
    host_bundle bundle;
    int index;
    host_effect *desc, *ctx, *inst;
} fx_plugin;

/* Open the bundle, find `identifier`, load, describe, describeInContext
 * (context), create an instance, with the host as host_cfg says (call
 * host_reset first for the defaults). 0 on success; fx_close either way. */
int fx_open(fx_plugin *fx, const char *identifier, const char *context, char *err, size_t len);
/* Destroy the instance, unload, close the bundle (fresh plugin state for
 * the next test). */
void fx_close(fx_plugin *fx);
/* 1 when the bundle declares a plugin with this identifier (a build may
 * lack a method's weights); NEED(id) skips the test otherwise. */
int fx_plugin_exists(const char *identifier);
#define NEED(id)                                                                                               \
    do {                                                                                                       \
        if (!fx_plugin_exists(id)) SKIP("the library has no " id);                                             \
    } while (0)
/* Set a host parameter's value (no keys). 0 if it exists. */
int fx_set_param(fx_plugin *fx, const char *name, double value);

#endif
