/*
 * method_run.h — run any library denoiser or filter on one layer of a
 * render: the method's image slots are bound to the layer's passes by name
 * (color, albedo, normal, depth, vector), parameters are set by name, and
 * for filters the colour can be albedo-demodulated around the filter (how
 * GI filters such as à-trous or the pyramid filter are used on renders).
 */
#ifndef EW_METHOD_RUN_H
#define EW_METHOD_RUN_H

#include "cycles_passes.h"
#include "edgewise/edgewise.h"

#define EW_RUN_MAX_PARAMS 16

typedef struct ew_method_spec {
    const char *label;        /* for reports, e.g. "pyramid-gi" */
    const char *kind;         /* "denoiser" or "filter"; NULL: identity (the input itself) */
    const char *name;
    int demodulate;           /* filters: divide by albedo + 0.01 before, multiply after */
    int num_params;
    const char *param_names[EW_RUN_MAX_PARAMS];
    float param_values[EW_RUN_MAX_PARAMS];
    /* optional named data (ew_*_set_data), e.g. "weights" and a file's bytes */
    const char *data_name;
    const void *data;
    size_t data_size;
    /* optional output: what the method ran (ew_denoiser_describe), e.g. the
     * model "auto" picked */
    char *chosen;
    size_t chosen_len;
    /* optional: the method's progress (ew_*_set_progress) */
    ew_progress_fn progress;
    void *progress_user;
    /* optional: after the timed run, execute the committed op this many
     * more times (the same inputs give the same output; not when the colour
     * is demodulated in place) and store the fastest in *warm_ms: the
     * in-process time of the same work */
    int warm_runs;
    double *warm_ms;
    /* optional: the layer data run on, as the caller may change it, and the
     * features (EW_LAYER_HALF_* bits, ew_layer_halves_allowed) it may hold
     * as halves: those the committed op reads as halves where they are
     * (ew_op_image_flags) are converted before execute, and the op
     * committed again on them */
    struct ew_layer_data *holds;
    unsigned halves_allowed;
} ew_method_spec;

/* Inputs of one layer, read once, reused across methods. */
typedef struct ew_layer_data {
    int width, height;
    float *color;   /* 3 per pixel */
    float *albedo;  /* 3 per pixel or NULL */
    float *normal;  /* 3 per pixel or NULL */
    float *depth;   /* 1 per pixel or NULL */
    float *vector;  /* 2 per pixel or NULL */
    int samples;    /* samples per pixel from the file's Cycles metadata, 0 if unknown;
                       given to methods with a "samples" parameter the spec leaves unset */
    unsigned halves; /* EW_LAYER_HALF_* bits: that buffer holds halves (uint16_t), not floats */
} ew_layer_data;

#define EW_LAYER_HALF_ALBEDO 1u
#define EW_LAYER_HALF_NORMAL 2u
#define EW_LAYER_HALF_DEPTH 4u

/* The layer's passes, decoded from the file in one pass over it into new
 * buffers (ew_host_alloc); the file itself keeps none of them. */
int ew_layer_data_read(ewio_file *f, const ew_layer_passes *lp, ew_layer_data *out, char *err, size_t errlen);
void ew_layer_data_free(ew_layer_data *d);
/* The features (EW_LAYER_HALF_* bits) the layer may hold as halves at no
 * loss: the file stores their passes as halves (ewio_pass_stored_half) and
 * gives them back itself when written (ewio_pass_in_source: the floats of
 * the layer's copies are not written). */
unsigned ew_layer_halves_allowed(const ewio_file *f, const ew_layer_passes *lp);
/* The features `bits` held as halves from now on (their floats, which
 * halves hold exactly, converted): half the memory. 0, or non-zero when out
 * of memory (a feature not converted keeps its floats). */
int ew_layer_data_to_halves(ew_layer_data *d, unsigned bits);

/* Run `spec` on the layer into out (3 per pixel; it may be in->color, the
 * result written over the colour, and then spec's warm runs are skipped:
 * they would read it). *ms: wall time of commit +
 * execute (the work a user waits for), excluding file I/O. Returns 0, or
 * non-zero with the reason in err (unknown method, missing required pass,
 * library error). */
int ew_method_run(ew_device *dev, const ew_method_spec *spec, const ew_layer_data *in, float *out, double *ms,
                  char *err, size_t errlen);

#endif
