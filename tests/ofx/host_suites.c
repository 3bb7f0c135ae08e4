/*
 * The test host's suites besides properties: image effect, parameter,
 * memory, multithread, message; the host descriptor and fetchSuite.
 */
#include "ofx_host.h"

#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EFFECT_MAGIC 0x45464658u /* "EFFX" */
#define CLIP_MAGIC 0x434c4950u   /* "CLIP" */
#define PARAM_MAGIC 0x5041524du  /* "PARM" */
#define PSET_MAGIC 0x50534554u   /* "PSET" */
#define IMAGE_MAGIC 0x494d4147u  /* "IMAG" */
#define MEM_MAGIC 0x4d454d4fu    /* "MEMO" */
#define MUTEX_MAGIC 0x4d555458u  /* "MUTX" */

host_config host_cfg;
static OfxPropertySetHandle host_props;

/* ---- objects ------------------------------------------------------------- */
static host_effect *effect_of(OfxImageEffectHandle h) {
    return h && h->magic == EFFECT_MAGIC ? h : NULL;
}
static host_clip *clip_of(OfxImageClipHandle h) { return h && h->magic == CLIP_MAGIC ? h : NULL; }
static host_param *param_of(OfxParamHandle h) { return h && h->magic == PARAM_MAGIC ? h : NULL; }
static host_effect *set_owner(OfxParamSetHandle h) { return h && h->magic == PSET_MAGIC ? h->owner : NULL; }

host_effect *he_new(int kind, int plugin) {
    host_effect *e = (host_effect *)calloc(1, sizeof *e);
    if (!e) abort();
    e->magic = EFFECT_MAGIC;
    e->kind = kind;
    e->plugin = plugin;
    e->props = hp_new(kind == HE_INSTANCE ? "effect instance" : kind == HE_CONTEXT ? "context descriptor" : "effect descriptor",
                      kind == HE_INSTANCE ? hs_instance : kind == HE_CONTEXT ? hs_context_descriptor : hs_effect_descriptor);
    hp_set_owner(e->props, e);
    hp_set_s(e->props, "OfxPropType", 0, kind == HE_INSTANCE ? "OfxTypeImageEffectInstance" : "OfxTypeImageEffect");
    e->set.magic = PSET_MAGIC;
    e->set.owner = e;
    return e;
}

static void clip_free(host_clip *c) {
    hp_free(c->props);
    free(c->buf);
    c->magic = 0;
    free(c);
}

void he_free(host_effect *e) {
    if (!e) return;
    for (int i = 0; i < e->num_clips; i++) clip_free(e->clips[i]);
    for (int i = 0; i < e->num_params; i++) {
        hp_free(e->params[i]->props);
        e->params[i]->magic = 0;
        free(e->params[i]);
    }
    hp_free(e->props);
    e->magic = 0;
    free(e);
}

host_clip *he_clip(host_effect *e, const char *name) {
    for (int i = 0; e && i < e->num_clips; i++)
        if (!strcmp(e->clips[i]->name, name)) return e->clips[i];
    return NULL;
}

host_param *he_param(host_effect *e, const char *name) {
    for (int i = 0; e && i < e->num_params; i++)
        if (!strcmp(e->params[i]->name, name)) return e->params[i];
    return NULL;
}

host_clip *he_add_clip(host_effect *e, const char *name) {
    if (e->num_clips == (int)(sizeof e->clips / sizeof e->clips[0])) return NULL;
    host_clip *c = (host_clip *)calloc(1, sizeof *c);
    if (!c) abort();
    c->magic = CLIP_MAGIC;
    snprintf(c->name, sizeof c->name, "%s", name);
    int inst = e->kind == HE_INSTANCE;
    c->props = hp_new(inst ? "clip instance" : "clip descriptor", inst ? hs_clip_instance : hs_clip_descriptor);
    hp_set_owner(c->props, c);
    hp_set_s(c->props, "OfxPropType", 0, "OfxTypeClip");
    hp_set_s(c->props, "OfxPropName", 0, name);
    hp_set_s(c->props, "OfxPropLabel", 0, name);
    hp_set_i(c->props, "OfxImageEffectPropSupportsTiles", 0, 1);
    snprintf(c->depth, sizeof c->depth, "OfxBitDepthFloat");
    c->owner = e;
    e->clips[e->num_clips++] = c;
    return c;
}

host_param *he_add_param(host_effect *e, const char *type, const char *name) {
    const hp_schema *schema = !strcmp(type, "OfxParamTypeDouble")    ? hs_param_double
                              : !strcmp(type, "OfxParamTypeInteger") ? hs_param_int
                              : !strcmp(type, "OfxParamTypeBoolean") ? hs_param_bool
                              : !strcmp(type, "OfxParamTypeChoice")  ? hs_param_choice
                                                                     : NULL;
    if (!schema || e->num_params == (int)(sizeof e->params / sizeof e->params[0])) return NULL;
    host_param *p = (host_param *)calloc(1, sizeof *p);
    if (!p) abort();
    p->magic = PARAM_MAGIC;
    snprintf(p->name, sizeof p->name, "%s", name);
    snprintf(p->type, sizeof p->type, "%s", type);
    p->props = hp_new(e->kind == HE_INSTANCE ? "parameter instance" : "parameter descriptor", schema);
    hp_set_s(p->props, "OfxPropType", 0, e->kind == HE_INSTANCE ? "OfxTypeParameterInstance" : "OfxTypeParameter");
    hp_set_s(p->props, "OfxPropName", 0, name);
    hp_set_s(p->props, "OfxParamPropType", 0, type);
    hp_set_s(p->props, "OfxPropLabel", 0, name);
    hp_set_s(p->props, "OfxParamPropScriptName", 0, name);
    hp_set_i(p->props, "OfxParamPropAnimates", 0, 1);
    e->params[e->num_params++] = p;
    return p;
}

/* ---- image effect suite -------------------------------------------------- */
static OfxStatus get_property_set(OfxImageEffectHandle h, OfxPropertySetHandle *props) {
    host_effect *e = effect_of(h);
    if (!e || !props) {
        host_violation("getPropertySet on a bad handle");
        return kOfxStatErrBadHandle;
    }
    *props = e->props;
    return kOfxStatOK;
}

static OfxStatus get_param_set(OfxImageEffectHandle h, OfxParamSetHandle *set) {
    host_effect *e = effect_of(h);
    if (!e || !set) {
        host_violation("getParamSet on a bad handle");
        return kOfxStatErrBadHandle;
    }
    *set = &e->set;
    return kOfxStatOK;
}

static OfxStatus clip_define(OfxImageEffectHandle h, const char *name, OfxPropertySetHandle *props) {
    host_effect *e = effect_of(h);
    if (!e || !name) {
        host_violation("clipDefine on a bad handle");
        return kOfxStatErrBadHandle;
    }
    if (e->kind != HE_CONTEXT) {
        host_violation("clipDefine outside describeInContext (%s)", name);
        return kOfxStatErrUnsupported;
    }
    if (he_clip(e, name)) {
        host_violation("clip %s defined twice", name);
        return kOfxStatErrExists;
    }
    host_clip *c = he_add_clip(e, name);
    if (!c) return kOfxStatErrMemory;
    if (props) *props = c->props;
    return kOfxStatOK;
}

static OfxStatus clip_get_handle(OfxImageEffectHandle h, const char *name, OfxImageClipHandle *clip,
                                 OfxPropertySetHandle *props) {
    host_effect *e = effect_of(h);
    if (!e || !name || !clip) {
        host_violation("clipGetHandle on a bad handle");
        return kOfxStatErrBadHandle;
    }
    if (e->kind != HE_INSTANCE) {
        host_violation("clipGetHandle on a descriptor");
        return kOfxStatErrBadHandle;
    }
    host_clip *c = he_clip(e, name);
    if (!c) return kOfxStatErrUnknown;
    *clip = c;
    if (props) *props = c->props;
    return kOfxStatOK;
}

static OfxStatus clip_get_property_set(OfxImageClipHandle h, OfxPropertySetHandle *props) {
    host_clip *c = clip_of(h);
    if (!c || !props) {
        host_violation("clipGetPropertySet on a bad handle");
        return kOfxStatErrBadHandle;
    }
    *props = c->props;
    return kOfxStatOK;
}

typedef struct host_image {
    uint32_t magic;
    OfxPropertySetHandle props;
    host_clip *clip;
} host_image;

static pthread_mutex_t stats_lock = PTHREAD_MUTEX_INITIALIZER;

static OfxStatus clip_get_image(OfxImageClipHandle h, OfxTime time, const OfxRectD *region,
                                OfxPropertySetHandle *out) {
    (void)time;
    (void)region;
    host_clip *c = clip_of(h);
    if (!c || !out) {
        host_violation("clipGetImage on a bad handle");
        return kOfxStatErrBadHandle;
    }
    *out = NULL;
    if (c->owner->kind != HE_INSTANCE) {
        host_violation("clipGetImage on a clip descriptor");
        return kOfxStatErrBadHandle;
    }
    if (!hp_i(c->props, "OfxImageClipPropConnected", 0)) return kOfxStatFailed;
    if (c->fetch_status != kOfxStatOK) return c->fetch_status;
    if (!c->buf) return kOfxStatFailed; /* connected but no image set up: nothing at this time */
    host_image *im = (host_image *)calloc(1, sizeof *im);
    if (!im) abort();
    im->magic = IMAGE_MAGIC;
    im->clip = c;
    im->props = hp_new("image", hs_image);
    hp_set_owner(im->props, im);
    OfxPropertySetHandle p = im->props;
    hp_set_s(p, "OfxPropType", 0, "OfxTypeImage");
    hp_set_s(p, "OfxImageEffectPropPixelDepth", 0, c->depth);
    hp_set_s(p, "OfxImageEffectPropComponents", 0,
             c->comps == 4 ? "OfxImageComponentRGBA" : c->comps == 3 ? "OfxImageComponentRGB" : "OfxImageComponentAlpha");
    hp_set_s(p, "OfxImageEffectPropPreMultiplication", 0, "OfxImageAlphaPremultiplied");
    hp_set_d(p, "OfxImageEffectPropRenderScale", 0, 1.0);
    hp_set_d(p, "OfxImageEffectPropRenderScale", 1, 1.0);
    hp_set_d(p, "OfxImagePropPixelAspectRatio", 0, 1.0);
    hp_set_p(p, "OfxImagePropData", 0, c->data);
    int b[4] = {c->bounds.x1, c->bounds.y1, c->bounds.x2, c->bounds.y2};
    for (int i = 0; i < 4; i++) {
        hp_set_i(p, "OfxImagePropBounds", i, b[i]);
        hp_set_i(p, "OfxImagePropRegionOfDefinition", i, b[i]);
    }
    hp_set_i(p, "OfxImagePropRowBytes", 0, c->row_bytes);
    hp_set_s(p, "OfxImagePropField", 0, "OfxFieldNone");
    hp_set_s(p, "OfxImagePropUniqueIdentifier", 0, c->name);
    pthread_mutex_lock(&stats_lock);
    host_st.images_fetched++;
    host_st.images_out++;
    pthread_mutex_unlock(&stats_lock);
    *out = p;
    return kOfxStatOK;
}

static OfxStatus clip_release_image(OfxPropertySetHandle h) {
    host_image *im = (host_image *)hp_owner(h);
    if (!im || im->magic != IMAGE_MAGIC) {
        host_violation("clipReleaseImage of something that is not a live image");
        return kOfxStatErrBadHandle;
    }
    im->magic = 0;
    hp_free(im->props);
    free(im);
    pthread_mutex_lock(&stats_lock);
    host_st.images_out--;
    pthread_mutex_unlock(&stats_lock);
    return kOfxStatOK;
}

static OfxStatus clip_get_rod(OfxImageClipHandle h, OfxTime time, OfxRectD *rod) {
    (void)time;
    host_clip *c = clip_of(h);
    if (!c || !rod) {
        host_violation("clipGetRegionOfDefinition on a bad handle");
        return kOfxStatErrBadHandle;
    }
    *rod = c->rod;
    return kOfxStatOK;
}

static _Thread_local int spawned_index = -1; /* >= 0 on threads multiThread started */

static int effect_abort(OfxImageEffectHandle h) {
    if (!effect_of(h)) host_violation("abort on a bad handle");
    int n = __atomic_add_fetch(&host_st.abort_calls, 1, __ATOMIC_SEQ_CST);
    if (host_cfg.abort_in_spawned && spawned_index >= 0) return 1;
    return host_cfg.abort_after >= 0 && n > host_cfg.abort_after;
}

typedef struct {
    uint32_t magic;
    int locks;
    size_t size;
    void *data;
} host_memory;

static OfxStatus image_memory_alloc(OfxImageEffectHandle h, size_t n, OfxImageMemoryHandle *out) {
    if (h && !effect_of(h)) {
        host_violation("imageMemoryAlloc with a bad effect handle");
        return kOfxStatErrBadHandle;
    }
    if (!out) return kOfxStatErrBadHandle;
    *out = NULL;
    if (host_cfg.image_memory_fail) return kOfxStatErrMemory;
    host_memory *m = (host_memory *)calloc(1, sizeof *m);
    if (!m) abort();
    m->magic = MEM_MAGIC;
    m->size = n;
    m->data = malloc(n ? n : 1);
    if (!m->data) abort();
    pthread_mutex_lock(&stats_lock);
    host_st.image_memory_out++;
    pthread_mutex_unlock(&stats_lock);
    *out = (OfxImageMemoryHandle)m;
    return kOfxStatOK;
}

static host_memory *memory_of(OfxImageMemoryHandle h) {
    host_memory *m = (host_memory *)h;
    return m && m->magic == MEM_MAGIC ? m : NULL;
}

static OfxStatus image_memory_free(OfxImageMemoryHandle h) {
    host_memory *m = memory_of(h);
    if (!m) {
        host_violation("imageMemoryFree of a bad handle");
        return kOfxStatErrBadHandle;
    }
    m->magic = 0;
    free(m->data);
    free(m);
    pthread_mutex_lock(&stats_lock);
    host_st.image_memory_out--;
    pthread_mutex_unlock(&stats_lock);
    return kOfxStatOK;
}

static OfxStatus image_memory_lock(OfxImageMemoryHandle h, void **p) {
    host_memory *m = memory_of(h);
    if (!m || !p) {
        host_violation("imageMemoryLock of a bad handle");
        return kOfxStatErrBadHandle;
    }
    m->locks++;
    *p = m->data;
    return kOfxStatOK;
}

static OfxStatus image_memory_unlock(OfxImageMemoryHandle h) {
    host_memory *m = memory_of(h);
    if (!m) {
        host_violation("imageMemoryUnlock of a bad handle");
        return kOfxStatErrBadHandle;
    }
    if (m->locks > 0) m->locks--;
    return kOfxStatOK;
}

const OfxImageEffectSuiteV1 host_image_effect_suite = {
    .getPropertySet = get_property_set,
    .getParamSet = get_param_set,
    .clipDefine = clip_define,
    .clipGetHandle = clip_get_handle,
    .clipGetPropertySet = clip_get_property_set,
    .clipGetImage = clip_get_image,
    .clipReleaseImage = clip_release_image,
    .clipGetRegionOfDefinition = clip_get_rod,
    .abort = effect_abort,
    .imageMemoryAlloc = image_memory_alloc,
    .imageMemoryFree = image_memory_free,
    .imageMemoryLock = image_memory_lock,
    .imageMemoryUnlock = image_memory_unlock,
};

/* ---- parameter suite ------------------------------------------------------ */
static OfxStatus param_define(OfxParamSetHandle set, const char *type, const char *name, OfxPropertySetHandle *props) {
    host_effect *e = set_owner(set);
    if (!e || !type || !name) {
        host_violation("paramDefine on a bad handle");
        return kOfxStatErrBadHandle;
    }
    if (e->kind == HE_INSTANCE) {
        host_violation("paramDefine on an instance");
        return kOfxStatErrUnsupported;
    }
    if (strcmp(type, "OfxParamTypeDouble") && strcmp(type, "OfxParamTypeInteger") && strcmp(type, "OfxParamTypeBoolean") &&
        strcmp(type, "OfxParamTypeChoice")) {
        host_violation("paramDefine of type %s, which this host does not offer", type);
        return kOfxStatErrUnknown;
    }
    if (he_param(e, name)) {
        host_violation("parameter %s defined twice", name);
        return kOfxStatErrExists;
    }
    host_param *p = he_add_param(e, type, name);
    if (!p) return kOfxStatErrMemory;
    if (props) *props = p->props;
    return kOfxStatOK;
}

static OfxStatus param_get_handle(OfxParamSetHandle set, const char *name, OfxParamHandle *param,
                                  OfxPropertySetHandle *props) {
    host_effect *e = set_owner(set);
    if (!e || !name || !param) {
        host_violation("paramGetHandle on a bad handle");
        return kOfxStatErrBadHandle;
    }
    host_param *p = he_param(e, name);
    if (!p) return kOfxStatErrUnknown;
    *param = p;
    if (props) *props = p->props;
    return kOfxStatOK;
}

static OfxStatus param_set_get_property_set(OfxParamSetHandle set, OfxPropertySetHandle *props) {
    host_effect *e = set_owner(set);
    if (!e || !props) return kOfxStatErrBadHandle;
    *props = e->props;
    return kOfxStatOK;
}

static OfxStatus param_get_property_set(OfxParamHandle h, OfxPropertySetHandle *props) {
    host_param *p = param_of(h);
    if (!p || !props) return kOfxStatErrBadHandle;
    *props = p->props;
    return kOfxStatOK;
}

static double value_at(const host_param *p, double t) {
    if (p->num_keys == 0) return p->value;
    if (t <= p->key_time[0]) return p->key_value[0];
    for (int k = 1; k < p->num_keys; k++)
        if (t <= p->key_time[k]) {
            double a = (t - p->key_time[k - 1]) / (p->key_time[k] - p->key_time[k - 1]);
            return p->key_value[k - 1] + a * (p->key_value[k] - p->key_value[k - 1]);
        }
    return p->key_value[p->num_keys - 1];
}

static OfxStatus write_value(host_param *p, double v, va_list ap) {
    if (!strcmp(p->type, "OfxParamTypeDouble")) {
        double *out = va_arg(ap, double *);
        if (!out) return kOfxStatErrValue;
        *out = v;
    } else {
        int *out = va_arg(ap, int *);
        if (!out) return kOfxStatErrValue;
        *out = (int)(v < 0 ? v - 0.5 : v + 0.5);
    }
    return kOfxStatOK;
}

static OfxStatus param_get_value(OfxParamHandle h, ...) {
    host_param *p = param_of(h);
    if (!p) {
        host_violation("paramGetValue on a bad handle");
        return kOfxStatErrBadHandle;
    }
    __atomic_add_fetch(&host_st.param_get_value_calls, 1, __ATOMIC_SEQ_CST);
    va_list ap;
    va_start(ap, h);
    OfxStatus st = write_value(p, value_at(p, 0.0), ap);
    va_end(ap);
    return st;
}

static OfxStatus param_get_value_at_time(OfxParamHandle h, OfxTime t, ...) {
    host_param *p = param_of(h);
    if (!p) {
        host_violation("paramGetValueAtTime on a bad handle");
        return kOfxStatErrBadHandle;
    }
    p->at_time_calls++;
    p->last_time = t;
    va_list ap;
    va_start(ap, t);
    OfxStatus st = write_value(p, value_at(p, t), ap);
    va_end(ap);
    return st;
}

/* What the plugin has no business calling during these tests. */
static OfxStatus not_expected(const char *what) {
    host_violation("unexpected call to %s", what);
    return kOfxStatErrUnsupported;
}
static OfxStatus param_get_derivative(OfxParamHandle h, OfxTime t, ...) {
    (void)h;
    (void)t;
    return not_expected("paramGetDerivative");
}
static OfxStatus param_get_integral(OfxParamHandle h, OfxTime a, OfxTime b, ...) {
    (void)h;
    (void)a;
    (void)b;
    return not_expected("paramGetIntegral");
}
static OfxStatus param_set_value(OfxParamHandle h, ...) {
    (void)h;
    return not_expected("paramSetValue");
}
static OfxStatus param_set_value_at_time(OfxParamHandle h, OfxTime t, ...) {
    (void)h;
    (void)t;
    return not_expected("paramSetValueAtTime");
}
static OfxStatus param_get_num_keys(OfxParamHandle h, unsigned int *n) {
    host_param *p = param_of(h);
    if (!p || !n) return kOfxStatErrBadHandle;
    *n = (unsigned int)p->num_keys;
    return kOfxStatOK;
}
static OfxStatus param_get_key_time(OfxParamHandle h, unsigned int k, OfxTime *t) {
    host_param *p = param_of(h);
    if (!p || !t) return kOfxStatErrBadHandle;
    if (k >= (unsigned int)p->num_keys) return kOfxStatErrBadIndex;
    *t = p->key_time[k];
    return kOfxStatOK;
}
static OfxStatus param_get_key_index(OfxParamHandle h, OfxTime t, int dir, int *index) {
    (void)h;
    (void)t;
    (void)dir;
    (void)index;
    return not_expected("paramGetKeyIndex");
}
static OfxStatus param_delete_key(OfxParamHandle h, OfxTime t) {
    (void)h;
    (void)t;
    return not_expected("paramDeleteKey");
}
static OfxStatus param_delete_all_keys(OfxParamHandle h) {
    (void)h;
    return not_expected("paramDeleteAllKeys");
}
static OfxStatus param_copy(OfxParamHandle to, OfxParamHandle from, OfxTime off, OfxRangeD *range) {
    (void)to;
    (void)from;
    (void)off;
    (void)range;
    return not_expected("paramCopy");
}
static OfxStatus param_edit_begin(OfxParamSetHandle set, const char *name) {
    (void)set;
    (void)name;
    return not_expected("paramEditBegin");
}
static OfxStatus param_edit_end(OfxParamSetHandle set) {
    (void)set;
    return not_expected("paramEditEnd");
}

const OfxParameterSuiteV1 host_parameter_suite = {
    .paramDefine = param_define,
    .paramGetHandle = param_get_handle,
    .paramSetGetPropertySet = param_set_get_property_set,
    .paramGetPropertySet = param_get_property_set,
    .paramGetValue = param_get_value,
    .paramGetValueAtTime = param_get_value_at_time,
    .paramGetDerivative = param_get_derivative,
    .paramGetIntegral = param_get_integral,
    .paramSetValue = param_set_value,
    .paramSetValueAtTime = param_set_value_at_time,
    .paramGetNumKeys = param_get_num_keys,
    .paramGetKeyTime = param_get_key_time,
    .paramGetKeyIndex = param_get_key_index,
    .paramDeleteKey = param_delete_key,
    .paramDeleteAllKeys = param_delete_all_keys,
    .paramCopy = param_copy,
    .paramEditBegin = param_edit_begin,
    .paramEditEnd = param_edit_end,
};

/* ---- memory suite ---------------------------------------------------------- */
#define BLOCK_MAGIC 0x424c4b21u
typedef union {
    uint32_t magic;
    max_align_t align;
} block_header;

static OfxStatus memory_alloc(void *handle, size_t n, void **out) {
    (void)handle;
    if (!out) return kOfxStatErrBadHandle;
    block_header *b = (block_header *)malloc(sizeof *b + n);
    if (!b) return kOfxStatErrMemory;
    b->magic = BLOCK_MAGIC;
    __atomic_add_fetch(&host_st.memory_out, 1, __ATOMIC_SEQ_CST);
    *out = b + 1;
    return kOfxStatOK;
}

static OfxStatus memory_free(void *p) {
    block_header *b = p ? (block_header *)p - 1 : NULL;
    if (!b || b->magic != BLOCK_MAGIC) {
        host_violation("memoryFree of a block the memory suite did not allocate");
        return kOfxStatErrBadHandle;
    }
    b->magic = 0;
    free(b);
    __atomic_sub_fetch(&host_st.memory_out, 1, __ATOMIC_SEQ_CST);
    return kOfxStatOK;
}

const OfxMemorySuiteV1 host_memory_suite = {.memoryAlloc = memory_alloc, .memoryFree = memory_free};

/* ---- multithread suite ----------------------------------------------------- */
typedef struct {
    OfxThreadFunctionV1 *fn;
    unsigned int index, count;
    void *arg;
} thread_start;

static void *thread_main(void *p) {
    thread_start *s = (thread_start *)p;
    spawned_index = (int)s->index;
    s->fn(s->index, s->count, s->arg);
    spawned_index = -1;
    return NULL;
}

static OfxStatus multi_thread(OfxThreadFunctionV1 func, unsigned int n, void *arg) {
    if (!func) return kOfxStatFailed;
    __atomic_add_fetch(&host_st.mt_calls, 1, __ATOMIC_SEQ_CST);
    if (spawned_index >= 0) return kOfxStatErrExists; /* no recursion, as the spec says */
    if (host_cfg.mt_fail) return kOfxStatFailed;
    if (n == 0) return kOfxStatOK;
    if (n > 64) n = 64;
    pthread_t tid[64];
    thread_start start[64];
    for (unsigned int i = 0; i < n; i++) {
        start[i].fn = func;
        start[i].index = i;
        start[i].count = n;
        start[i].arg = arg;
        if (pthread_create(&tid[i], NULL, thread_main, &start[i]) != 0) abort();
    }
    for (unsigned int i = 0; i < n; i++) pthread_join(tid[i], NULL);
    __atomic_add_fetch(&host_st.mt_threads, (int)n, __ATOMIC_SEQ_CST);
    return kOfxStatOK;
}

static OfxStatus num_cpus(unsigned int *n) {
    if (!n) return kOfxStatFailed;
    *n = host_cfg.num_cpus;
    return kOfxStatOK;
}

static OfxStatus thread_index(unsigned int *i) {
    if (!i) return kOfxStatFailed;
    *i = spawned_index >= 0 ? (unsigned int)spawned_index : 0;
    return kOfxStatOK;
}

static int is_spawned(void) { return spawned_index >= 0; }

struct OfxMutex {
    uint32_t magic;
    pthread_mutex_t m;
};

static OfxStatus mutex_create(OfxMutexHandle *out, int count) {
    if (!out) return kOfxStatErrBadHandle;
    struct OfxMutex *m = (struct OfxMutex *)calloc(1, sizeof *m);
    if (!m) return kOfxStatErrMemory;
    pthread_mutexattr_t a;
    pthread_mutexattr_init(&a);
    pthread_mutexattr_settype(&a, PTHREAD_MUTEX_RECURSIVE);
    pthread_mutex_init(&m->m, &a);
    pthread_mutexattr_destroy(&a);
    m->magic = MUTEX_MAGIC;
    for (int i = 0; i < count; i++) pthread_mutex_lock(&m->m);
    *out = m;
    return kOfxStatOK;
}
static OfxStatus mutex_destroy(const OfxMutexHandle m) {
    if (!m || m->magic != MUTEX_MAGIC) return kOfxStatErrBadHandle;
    m->magic = 0;
    pthread_mutex_destroy(&m->m);
    free(m);
    return kOfxStatOK;
}
static OfxStatus mutex_lock(const OfxMutexHandle m) {
    if (!m || m->magic != MUTEX_MAGIC) return kOfxStatErrBadHandle;
    pthread_mutex_lock(&m->m);
    return kOfxStatOK;
}
static OfxStatus mutex_unlock(const OfxMutexHandle m) {
    if (!m || m->magic != MUTEX_MAGIC) return kOfxStatErrBadHandle;
    pthread_mutex_unlock(&m->m);
    return kOfxStatOK;
}
static OfxStatus mutex_try_lock(const OfxMutexHandle m) {
    if (!m || m->magic != MUTEX_MAGIC) return kOfxStatErrBadHandle;
    return pthread_mutex_trylock(&m->m) == 0 ? kOfxStatOK : kOfxStatFailed;
}

const OfxMultiThreadSuiteV1 host_multithread_suite = {
    .multiThread = multi_thread,
    .multiThreadNumCPUs = num_cpus,
    .multiThreadIndex = thread_index,
    .multiThreadIsSpawnedThread = is_spawned,
    .mutexCreate = mutex_create,
    .mutexDestroy = mutex_destroy,
    .mutexLock = mutex_lock,
    .mutexUnLock = mutex_unlock,
    .mutexTryLock = mutex_try_lock,
};

/* ---- message suite ----------------------------------------------------------- */
static OfxStatus post(int persistent, void *handle, const char *type, const char *id, const char *fmt, va_list ap) {
    (void)id;
    if (!type || !fmt) {
        host_violation("message without type or format");
        return kOfxStatErrValue;
    }
    if (persistent && !effect_of((OfxImageEffectHandle)handle)) {
        host_violation("persistent message on a bad handle");
        return kOfxStatErrBadHandle;
    }
    pthread_mutex_lock(&stats_lock);
    vsnprintf(host_st.last_message, sizeof host_st.last_message, fmt, ap);
    if (persistent) host_st.persistent_messages++;
    else host_st.messages++;
    pthread_mutex_unlock(&stats_lock);
    return kOfxStatOK;
}

static OfxStatus message(void *handle, const char *type, const char *id, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    OfxStatus st = post(0, handle, type, id, fmt, ap);
    va_end(ap);
    return st;
}

static OfxStatus set_persistent(void *handle, const char *type, const char *id, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    OfxStatus st = post(1, handle, type, id, fmt, ap);
    va_end(ap);
    return st;
}

static OfxStatus clear_persistent(void *handle) {
    if (!effect_of((OfxImageEffectHandle)handle)) {
        host_violation("clearPersistentMessage on a bad handle");
        return kOfxStatErrBadHandle;
    }
    __atomic_add_fetch(&host_st.persistent_cleared, 1, __ATOMIC_SEQ_CST);
    return kOfxStatOK;
}

const OfxMessageSuiteV2 host_message_suite = {
    .message = message,
    .setPersistentMessage = set_persistent,
    .clearPersistentMessage = clear_persistent,
};

/* ---- the host ---------------------------------------------------------------- */
static const void *fetch_suite(OfxPropertySetHandle host, const char *name, int version) {
    if (host != host_props || !name) {
        host_violation("fetchSuite with a wrong host handle");
        return NULL;
    }
    if (!strcmp(name, "OfxPropertySuite") && version == 1 && host_cfg.offer_property) return &host_property_suite;
    if (!strcmp(name, "OfxImageEffectSuite") && version == 1 && host_cfg.offer_image_effect)
        return &host_image_effect_suite;
    if (!strcmp(name, "OfxParameterSuite") && version == 1 && host_cfg.offer_parameter) return &host_parameter_suite;
    if (!strcmp(name, "OfxMemorySuite") && version == 1 && host_cfg.offer_memory) return &host_memory_suite;
    if (!strcmp(name, "OfxMultiThreadSuite") && version == 1 && host_cfg.offer_multithread)
        return &host_multithread_suite;
    /* V2 extends V1 in place: the same struct answers both */
    if (!strcmp(name, "OfxMessageSuite") && version == 2 && host_cfg.offer_message_v2) return &host_message_suite;
    if (!strcmp(name, "OfxMessageSuite") && version == 1 && host_cfg.offer_message_v1) return &host_message_suite;
    return NULL;
}

OfxHost host_ofx;

void host_init(void) {
    if (host_props) return;
    host_props = hp_new("host descriptor", hs_host);
    OfxPropertySetHandle h = host_props;
    hp_set_s(h, "OfxPropType", 0, "OfxTypeImageEffectHost");
    hp_set_s(h, "OfxPropName", 0, "org.edgewise.testhost");
    hp_set_s(h, "OfxPropLabel", 0, "Edgewise test host");
    hp_set_i(h, "OfxPropAPIVersion", 0, 1);
    hp_set_i(h, "OfxPropAPIVersion", 1, 4);
    hp_set_i(h, "OfxImageEffectHostPropIsBackground", 0, 1);
    hp_set_i(h, "OfxImageEffectPropSupportsMultiResolution", 0, 1);
    hp_set_i(h, "OfxImageEffectPropSupportsTiles", 0, 1);
    const char *comps[3] = {"OfxImageComponentRGBA", "OfxImageComponentRGB", "OfxImageComponentAlpha"};
    for (int i = 0; i < 3; i++) hp_set_s(h, "OfxImageEffectPropSupportedComponents", i, comps[i]);
    hp_set_s(h, "OfxImageEffectPropSupportedContexts", 0, "OfxImageEffectContextFilter");
    hp_set_s(h, "OfxImageEffectPropSupportedContexts", 1, "OfxImageEffectContextGeneral");
    hp_set_s(h, "OfxImageEffectPropSupportedPixelDepths", 0, "OfxBitDepthFloat");
    hp_set_i(h, "OfxParamHostPropMaxParameters", 0, -1);
    host_ofx.host = host_props;
    host_ofx.fetchSuite = fetch_suite;
}

void host_reset(void) {
    host_init();
    memset(&host_cfg, 0, sizeof host_cfg);
    host_cfg.offer_multithread = host_cfg.offer_memory = 1;
    host_cfg.offer_message_v1 = host_cfg.offer_message_v2 = 1;
    host_cfg.offer_property = host_cfg.offer_image_effect = host_cfg.offer_parameter = 1;
    host_cfg.num_cpus = 3;
    host_cfg.abort_after = -1;
    memset(&host_st, 0, sizeof host_st);
}
