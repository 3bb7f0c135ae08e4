/*
 * ofx_host.h — a small, strict OpenFX 1.4 host for testing the Edgewise
 * bundle: it dlopens the bundle, offers the property, image effect,
 * parameter, memory, multithread and message suites, and drives the
 * actions on real images.
 *
 * Strict means it behaves like a careful real host: every property set
 * knows which properties its object has (names, types, dimensions, and
 * which the plugin may write, typed from the OFX 1.4 reference as string
 * literals, independently of plugin/ofx_abi.h), every handle is checked,
 * and whatever a plugin gets wrong (an unknown property, a wrong type, a
 * bad handle, an image released twice) returns the proper error *and* is
 * counted in host_st.violations, so tests can require none.
 *
 * The host objects are the OFX opaque structs themselves (struct
 * OfxImageEffectStruct ...), each starting with a magic number.
 */
#ifndef EW_TESTS_OFX_HOST_H
#define EW_TESTS_OFX_HOST_H

#include <stdint.h>

#include "ofx_abi.h"

/* ---- configuration and statistics ------------------------------------- */
typedef struct host_config {
    int offer_multithread, offer_memory, offer_message_v1, offer_message_v2;
    int offer_property, offer_image_effect, offer_parameter;
    int mt_fail;             /* multiThread fails without running anything */
    unsigned int num_cpus;   /* what multiThreadNumCPUs answers */
    int abort_after;         /* abort() answers 1 from this call on (-1: never) */
    int abort_in_spawned;    /* abort() answers 1 on threads multiThread spawned */
    int image_memory_fail;   /* imageMemoryAlloc fails */
    double render_scale[2];  /* the actions' kOfxImageEffectPropRenderScale (0: 1, full size) */
} host_config;

typedef struct host_stats {
    int violations;
    char last_violation[256];
    int images_fetched, images_out;  /* clipGetImage calls; images not yet released */
    int image_memory_out, memory_out; /* outstanding blocks */
    int abort_calls;
    int mt_calls, mt_threads;
    int messages, persistent_messages, persistent_cleared;
    char last_message[512];
    int param_get_value_calls;        /* paramGetValue (without time) */
} host_stats;

extern host_config host_cfg;
extern host_stats host_st;
/* Default configuration (every suite offered, 3 CPUs, no abort), zero stats. */
void host_reset(void);
void host_violation(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* ---- property sets ------------------------------------------------------ */
typedef struct hp_schema {
    const char *name;
    char type;          /* 'i' int, 'd' double, 's' string, 'p' pointer */
    int dim;            /* 0: any number of values */
    int plugin_writes;  /* the plugin may set it */
} hp_schema;

/* kind names the object for messages. schema: NULL-name-terminated list
 * (NULL: empty; the host declares what it sets). */
OfxPropertySetHandle hp_new(const char *kind, const hp_schema *schema);
void hp_free(OfxPropertySetHandle ps);
void hp_declare(OfxPropertySetHandle ps, const char *name, char type, int dim, int plugin_writes);
/* Host-side access: bypasses the plugin's write rules, declares as needed. */
void hp_set_i(OfxPropertySetHandle ps, const char *name, int index, int v);
void hp_set_d(OfxPropertySetHandle ps, const char *name, int index, double v);
void hp_set_s(OfxPropertySetHandle ps, const char *name, int index, const char *v);
void hp_set_p(OfxPropertySetHandle ps, const char *name, int index, void *v);
int hp_i(OfxPropertySetHandle ps, const char *name, int index);       /* 0 if absent */
double hp_d(OfxPropertySetHandle ps, const char *name, int index);    /* 0 if absent */
const char *hp_s(OfxPropertySetHandle ps, const char *name, int index); /* "" if absent */
void *hp_p(OfxPropertySetHandle ps, const char *name, int index);
int hp_count(OfxPropertySetHandle ps, const char *name); /* values set; -1 if undeclared */
int hp_has_string(OfxPropertySetHandle ps, const char *name, const char *value);
/* The set behind a handle, or NULL if it is not a live property set. */
OfxPropertySetHandle hp_check(OfxPropertySetHandle ps);
void *hp_owner(OfxPropertySetHandle ps);
void hp_set_owner(OfxPropertySetHandle ps, void *owner);

extern const OfxPropertySuiteV1 host_property_suite;

/* Schemas (host_schema.c). */
extern const hp_schema hs_host[], hs_effect_descriptor[], hs_context_descriptor[], hs_instance[];
extern const hp_schema hs_clip_descriptor[], hs_clip_instance[], hs_image[];
extern const hp_schema hs_param_double[], hs_param_int[], hs_param_bool[], hs_param_choice[];
extern const hp_schema hs_describe_in_context_in[], hs_rod_in[], hs_rod_out[], hs_roi_in[];
extern const hp_schema hs_identity_in[], hs_identity_out[], hs_render_in[], hs_clip_prefs_out[];
extern const hp_schema hs_sequence_render_in[];

/* ---- objects ---------------------------------------------------------------- */
enum { HE_DESCRIPTOR = 1, HE_CONTEXT = 2, HE_INSTANCE = 3 };

struct OfxParamSetStruct {
    uint32_t magic;
    struct OfxImageEffectStruct *owner;
};

struct OfxParamStruct {
    uint32_t magic;
    char name[64];
    char type[40];
    OfxPropertySetHandle props;
    double value;      /* value without keys */
    int num_keys;      /* linear interpolation between keys */
    double key_time[4], key_value[4];
    int at_time_calls;
    double last_time;
};

struct OfxImageClipStruct {
    uint32_t magic;
    char name[64];
    OfxPropertySetHandle props;
    struct OfxImageEffectStruct *owner;
    /* instance clips: the pixels clipGetImage hands out */
    char *buf;          /* host allocation */
    size_t buf_bytes, guard; /* guard bytes before and after the rows */
    char *data;         /* pixel (bounds.x1, bounds.y1) */
    OfxRectI bounds;
    int row_bytes, comps, pad;
    char depth[32];
    OfxRectD rod;
    OfxStatus fetch_status; /* what clipGetImage returns (OK by default) */
};

struct OfxImageEffectStruct {
    uint32_t magic;
    int kind;
    int plugin;                /* index in the bundle */
    OfxPropertySetHandle props;
    struct OfxParamSetStruct set;
    struct OfxParamStruct *params[48];
    int num_params;
    struct OfxImageClipStruct *clips[16];
    int num_clips;
};

typedef struct OfxImageEffectStruct host_effect;
typedef struct OfxImageClipStruct host_clip;
typedef struct OfxParamStruct host_param;

extern const OfxImageEffectSuiteV1 host_image_effect_suite;
extern const OfxParameterSuiteV1 host_parameter_suite;
extern const OfxMemorySuiteV1 host_memory_suite;
extern const OfxMultiThreadSuiteV1 host_multithread_suite;
extern const OfxMessageSuiteV2 host_message_suite;
/* The OfxHost handed to plugins: fetchSuite answers as host_cfg says. */
extern OfxHost host_ofx;
void host_init(void); /* builds the host descriptor; host_reset calls it */

host_effect *he_new(int kind, int plugin);
host_clip *he_add_clip(host_effect *e, const char *name);
host_param *he_add_param(host_effect *e, const char *type, const char *name);
void he_free(host_effect *e);
host_clip *he_clip(host_effect *e, const char *name);
host_param *he_param(host_effect *e, const char *name);

/* ---- the bundle and the actions (host_driver.c) ------------------------ */
typedef struct host_bundle {
    void *dl;
    int (*get_count)(void);
    OfxPlugin *(*get_plugin)(int);
    OfxStatus (*set_host)(const OfxHost *);
    char binary[1024];
} host_bundle;

/* Opens $EW_OFX_BUNDLE/Contents/<arch>/Edgewise.ofx. 0 on success. */
int hb_open(host_bundle *b, char *err, size_t len);
void hb_close(host_bundle *b);
int hb_find(const host_bundle *b, const char *identifier); /* -1 if absent */

OfxStatus hx_action(const host_bundle *b, int plugin, const char *action, const void *handle,
                    OfxPropertySetHandle in, OfxPropertySetHandle out);
/* setHost + load */
OfxStatus hx_load(const host_bundle *b, int plugin);
OfxStatus hx_unload(const host_bundle *b, int plugin);
OfxStatus hx_describe(const host_bundle *b, int plugin, host_effect **desc);
OfxStatus hx_describe_in_context(const host_bundle *b, int plugin, const char *context, host_effect **ctx);
/* An instance built from a context descriptor the way a host does it
 * (clips and parameters with their defaults), then kOfxActionCreateInstance. */
OfxStatus hx_create_instance(const host_bundle *b, int plugin, const host_effect *ctx, const char *context,
                             host_effect **inst);
OfxStatus hx_destroy_instance(const host_bundle *b, int plugin, host_effect *inst);

OfxStatus hx_rod(const host_bundle *b, int plugin, host_effect *inst, double time, double rod[4]);
OfxStatus hx_roi(const host_bundle *b, int plugin, host_effect *inst, double time, const double region[4],
                 OfxPropertySetHandle *out);
OfxStatus hx_clip_prefs(const host_bundle *b, int plugin, host_effect *inst, OfxPropertySetHandle *out);
OfxStatus hx_is_identity(const host_bundle *b, int plugin, host_effect *inst, double time, OfxRectI window,
                         char *clip, size_t clip_len, double *clip_time);
OfxStatus hx_render(const host_bundle *b, int plugin, host_effect *inst, double time, OfxRectI window);
/* kOfxImageEffectActionBeginSequenceRender / EndSequenceRender over the
 * frames [first, last], step 1, not interactive. */
OfxStatus hx_begin_sequence(const host_bundle *b, int plugin, host_effect *inst, double first, double last);
OfxStatus hx_end_sequence(const host_bundle *b, int plugin, host_effect *inst, double first, double last);
/* kOfxActionPurgeCaches: no arguments. */
OfxStatus hx_purge_caches(const host_bundle *b, int plugin, host_effect *inst);

/* Pixels. `top_down` holds w*h*comps floats, row 0 at the top (y1+h-1). */
enum { HX_NEG_ROW_BYTES = 1, HX_PAD_ROWS = 2 };
void hx_clip_set_image(host_clip *c, const float *top_down, int w, int h, int comps, int x1, int y1, int layout);
void hx_clip_connect(host_clip *c, int connected);
/* The output's image: bounds, components, layout; filled with a canary. */
void hx_output_prepare(host_clip *out, OfxRectI bounds, int comps, int layout);
void hx_output_read(const host_clip *out, OfxRectI rect, float *top_down);
/* 1 if no byte outside the pixels of the output's rows was written. */
int hx_output_guards_intact(const host_clip *out);
#define HX_CANARY (-12345.0f)

#endif /* EW_TESTS_OFX_HOST_H */
