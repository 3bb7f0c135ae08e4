/*
 * ofx_plugin.h — what the modules of the Edgewise OFX plugin share.
 *
 *   ofx_entry.c     exported entry points, one main entry per plugin, dispatch
 *   ofx_host.c      the host's suites (fetched at load), memory, messages
 *   ofx_nodes.c     which library methods become plugins, and their clips/params
 *   ofx_describe.c  describe / describeInContext, generated from the descriptors
 *   ofx_instance.c  create/destroy instance, RoD, RoI, clip preferences, identity
 *   ofx_images.c    fetching host images and viewing them as ew_image
 *   ofx_bands.c     running row bands on the host's threads, checking abort()
 *   ofx_keep.c      the device and op an instance keeps between renders
 *   ofx_render.c    the render action
 */
#ifndef EW_OFX_PLUGIN_H
#define EW_OFX_PLUGIN_H

#include <pthread.h>

#include "edgewise/edgewise.h"
#include "ofx_abi.h"

#define EW_OFX_MAX_PLUGINS 16
#define EW_OFX_MAX_PARAMS 32
#define EW_OFX_MAX_AUX 6
#define EW_OFX_MAX_IDENTITY 2
#define EW_OFX_GROUPING "Edgewise"
/* The render's samples per pixel (Cycles' EXR attribute
 * "cycles.<layer>.samples"), an int a host may put on the Source clip or on
 * its images. OpenFX has no standard property for it; a method's "samples"
 * parameter left at 0 takes it from here, so "auto" chooses as the CLI and
 * graphs do for the same file. */
#define EW_OFX_PROP_RENDER_SAMPLES "org.edgewise.OfxImageClipPropRenderSamples"
#define EW_OFX_SAMPLES_HINT                                                                                     \
    "samples per pixel of the render. 0: the Source clip's sample count when the host gives it (property "     \
    EW_OFX_PROP_RENDER_SAMPLES "), else estimated from the image's noise"

/* ---- nodes: one OFX plugin per user-facing library method ------------- */

/* An optional (or, for some methods, required) input besides the colour. */
typedef struct ew_ofx_aux {
    const char *image; /* the library's image name, e.g. "albedo" */
    char clip[32];     /* the OFX clip name, e.g. "Albedo" */
    int channels;      /* channels handed to the library */
    int required;      /* the method cannot run without it */
    const char *hint;
} ew_ofx_aux;

typedef struct ew_ofx_node {
    const char *kind;   /* "denoiser" or "filter" */
    const char *method; /* library method name */
    const char *summary;
    char identifier[64]; /* OfxPlugin::pluginIdentifier */
    char label[96];
    /* Channels of the source the method gets: 4 filters RGBA (premultiplied
     * colour and alpha blur alike), 3 denoises RGB and passes alpha through. */
    int channels;
    /* Integer parameters that, all zero, make the method an exact identity
     * (EW_PARAM_NOOP_AT_ZERO). */
    const char *identity_params[EW_OFX_MAX_IDENTITY];
    int num_params;
    ew_param_info params[EW_OFX_MAX_PARAMS];
    /* 1: a length in pixels, multiplied by the render scale (proxies) */
    int param_pixels[EW_OFX_MAX_PARAMS];
    /* > 0: an enum, shown as a choice of that many names */
    int param_choices[EW_OFX_MAX_PARAMS];
    int num_aux;
    ew_ofx_aux aux[EW_OFX_MAX_AUX];
} ew_ofx_node;

/* The plugins this binary offers, built once from the library's
 * introspection; at most EW_OFX_MAX_PLUGINS. */
int ew_ofx_node_count(void);
const ew_ofx_node *ew_ofx_node_get(int index);

/* ---- host ---------------------------------------------------------------- */
typedef struct ew_ofx_suites {
    const OfxHost *host;
    const OfxPropertySuiteV1 *prop;     /* required */
    const OfxImageEffectSuiteV1 *effect; /* required */
    const OfxParameterSuiteV1 *param;   /* required */
    const OfxMemorySuiteV1 *memory;     /* optional: malloc otherwise */
    const OfxMultiThreadSuiteV1 *mt;    /* optional: bands run on the render thread */
    const OfxMessageSuiteV1 *msg1;      /* optional */
    const OfxMessageSuiteV2 *msg2;      /* optional: persistent error messages */
} ew_ofx_suites;

/* Written only by setHost/load/unload, which hosts call from one thread
 * before and after any other action. */
extern ew_ofx_suites ew_ofx;

void ew_ofx_set_host(const OfxHost *host);
OfxStatus ew_ofx_load(void);
OfxStatus ew_ofx_unload(void);
int ew_ofx_loaded(void);

/* Memory from the host's memory suite when offered, else malloc; freed by
 * ew_ofx_free whichever it came from. Zero-filled. */
void *ew_ofx_alloc(size_t size);
void ew_ofx_free(void *p);

/* Tell the user why a render failed (persistent when the host can), and
 * clear it after a good render. */
void ew_ofx_post_error(OfxImageEffectHandle effect, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void ew_ofx_clear_error(OfxImageEffectHandle effect);
/* A persistent warning (hosts with message suite V2 only): the render
 * worked, but not as asked. */
void ew_ofx_post_warning(OfxImageEffectHandle effect, const char *text);
/* The components a clip's input really has (kOfxImageClipPropUnmappedComponents),
 * 0 when the host does not say: 4 RGBA, 3 RGB, 1 Alpha. */
int ew_ofx_clip_unmapped_components(OfxImageClipHandle clip);

/* ---- actions ------------------------------------------------------------- */
OfxStatus ew_ofx_describe(const ew_ofx_node *node, OfxImageEffectHandle effect);
OfxStatus ew_ofx_describe_in_context(const ew_ofx_node *node, OfxImageEffectHandle effect,
                                     OfxPropertySetHandle in);

/* The device and op of an instance's last good render, for the next one
 * (ofx_keep.c says when they are dropped). Between renders the op holds no
 * image and no progress callback: nothing that points into a render. */
typedef struct ew_ofx_keep {
    pthread_mutex_t lock;
    ew_device *dev;
    ew_op *op;          /* NULL: nothing kept */
    const char *method; /* what op runs (a static string) */
    int threads;        /* what dev was created with */
    unsigned generation; /* bumped by every drop */
} ew_ofx_keep;

void ew_ofx_keep_init(ew_ofx_keep *k);
/* Drop what is kept, then the lock. */
void ew_ofx_keep_fini(ew_ofx_keep *k);
/* Free the kept pair, and make a render that holds it now free it too. */
void ew_ofx_keep_drop(ew_ofx_keep *k);
/* Take the kept pair out if it runs `method` on `threads` (1), else free it
 * (0). *generation is what ew_ofx_keep_put wants back. */
int ew_ofx_keep_take(ew_ofx_keep *k, const char *method, int threads, ew_device **dev, ew_op **op,
                     unsigned *generation);
/* Keep the pair of a good render, or free it if a drop came since the take. */
void ew_ofx_keep_put(ew_ofx_keep *k, const char *method, int threads, ew_device *dev, ew_op *op,
                     unsigned generation);

typedef struct ew_ofx_instance {
    unsigned magic;
    const ew_ofx_node *node;
    OfxImageClipHandle source, output;
    OfxImageClipHandle aux[EW_OFX_MAX_AUX]; /* NULL if the host has no such clip */
    OfxParamHandle params[EW_OFX_MAX_PARAMS];
    ew_ofx_keep keep;
} ew_ofx_instance;

OfxStatus ew_ofx_create_instance(const ew_ofx_node *node, OfxImageEffectHandle effect);
OfxStatus ew_ofx_destroy_instance(const ew_ofx_node *node, OfxImageEffectHandle effect);
/* The instance data of `effect`, checked to belong to `node`; NULL with
 * *status set when the handle or its data is not ours. */
ew_ofx_instance *ew_ofx_instance_get(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxStatus *status);

OfxStatus ew_ofx_region_of_definition(const ew_ofx_node *node, OfxImageEffectHandle effect,
                                      OfxPropertySetHandle in, OfxPropertySetHandle out);
OfxStatus ew_ofx_regions_of_interest(const ew_ofx_node *node, OfxImageEffectHandle effect,
                                     OfxPropertySetHandle in, OfxPropertySetHandle out);
OfxStatus ew_ofx_clip_preferences(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxPropertySetHandle out);
OfxStatus ew_ofx_is_identity(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxPropertySetHandle in,
                             OfxPropertySetHandle out);
OfxStatus ew_ofx_render(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxPropertySetHandle in);
/* kOfxActionPurgeCaches and kOfxImageEffectActionEndSequenceRender: free
 * the instance's kept device and op. */
OfxStatus ew_ofx_drop_kept(const ew_ofx_node *node, OfxImageEffectHandle effect);

/* Read parameter i of the instance at `time` as the library wants it:
 * clamped to the descriptor's range, the default if the host gives a
 * non-finite value. */
OfxStatus ew_ofx_param_value(const ew_ofx_instance *inst, int i, OfxTime time, double *value);

/* ---- images -------------------------------------------------------------- */
/* A fetched host image. `handle` is non-NULL exactly while it must be
 * released. */
typedef struct ew_ofx_image {
    OfxPropertySetHandle handle;
    char *data;     /* pixel (bounds.x1, bounds.y1) */
    OfxRectI bounds;
    int row_bytes;  /* may be negative */
    int comps;      /* 4 RGBA, 3 RGB, 1 alpha */
    /* why the image was refused, for the user ("" if it was not): a host
     * that hands an image the plugin cannot read must be told what is wrong
     * with it, or the node just fails */
    char problem[160];
} ew_ofx_image;

/* Fetch and check (float, known components, sane bounds and row bytes).
 * kOfxStatFailed from the host (no image at this time) is passed on so the
 * caller can treat the input as black. A refused image returns
 * kOfxStatErrImageFormat (kOfxStatErrBadHandle if its properties cannot be
 * read) with `problem` set; it is still held: release it. */
OfxStatus ew_ofx_image_fetch(OfxImageClipHandle clip, OfxTime time, ew_ofx_image *img);
void ew_ofx_image_release(ew_ofx_image *img);
/* Address of pixel (x, y) in pixel coordinates; must be inside bounds. */
float *ew_ofx_image_pixel(const ew_ofx_image *img, int x, int y);
/* A top-down library view of `channels` channels from channel `first`,
 * over the image's whole bounds (row 0 = the top row, bounds.y2 - 1). */
ew_image ew_ofx_image_view(const ew_ofx_image *img, int first, int channels);

/* ---- bands ----------------------------------------------------------------- */
typedef void (*ew_ofx_band_fn)(void *ctx, int y0, int y1);
/* Run fn over the rows [y0, y1) in bands, on the host's threads when the
 * multithread suite is offered (on this thread otherwise, or if the host
 * cannot spawn), asking the host's abort() before each band. Returns 1 if
 * it stopped because of abort(). */
int ew_ofx_run_bands(OfxImageEffectHandle effect, int y0, int y1, ew_ofx_band_fn fn, void *ctx);
/* Worker threads for the library: the host's CPU count, 0 (= library
 * default) without the multithread suite. */
int ew_ofx_thread_count(void);

#endif /* EW_OFX_PLUGIN_H */
