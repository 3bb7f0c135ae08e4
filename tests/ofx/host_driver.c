/*
 * The test host's driver: opening the bundle, building descriptors and
 * instances the way a host does, calling the actions with properly filled
 * argument sets, and host-side pixel buffers (any origin, either row
 * order, padded rows, guard bytes around everything).
 */
#include "ofx_host.h"

#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the bundle ------------------------------------------------------------ */
int hb_open(host_bundle *b, char *err, size_t len) {
    memset(b, 0, sizeof *b);
    const char *dir = getenv("EW_OFX_BUNDLE");
    const char *arch = getenv("EW_OFX_ARCH");
    if (!dir || !*dir) {
        snprintf(err, len, "EW_OFX_BUNDLE is not set");
        return 1;
    }
    snprintf(b->binary, sizeof b->binary, "%s/Contents/%s/Edgewise.ofx", dir, arch && *arch ? arch : "Linux-x86-64");
    b->dl = dlopen(b->binary, RTLD_NOW | RTLD_LOCAL);
    if (!b->dl) {
        snprintf(err, len, "dlopen %s: %s", b->binary, dlerror());
        return 1;
    }
    /* dlsym returns void *; a function pointer is reached through memcpy
     * (ISO C has no object-to-function pointer conversion). */
    void *sym;
    sym = dlsym(b->dl, "OfxGetNumberOfPlugins");
    if (sym) memcpy(&b->get_count, &sym, sizeof sym);
    sym = dlsym(b->dl, "OfxGetPlugin");
    if (sym) memcpy(&b->get_plugin, &sym, sizeof sym);
    sym = dlsym(b->dl, "OfxSetHost");
    if (sym) memcpy(&b->set_host, &sym, sizeof sym);
    if (!b->get_count || !b->get_plugin) {
        snprintf(err, len, "%s lacks OfxGetNumberOfPlugins/OfxGetPlugin", b->binary);
        hb_close(b);
        return 1;
    }
    return 0;
}

void hb_close(host_bundle *b) {
    if (b->dl) dlclose(b->dl);
    memset(b, 0, sizeof *b);
}

int hb_find(const host_bundle *b, const char *identifier) {
    int n = b->get_count();
    for (int i = 0; i < n; i++) {
        OfxPlugin *p = b->get_plugin(i);
        if (p && p->pluginIdentifier && !strcmp(p->pluginIdentifier, identifier)) return i;
    }
    return -1;
}

/* ---- actions -------------------------------------------------------------- */
OfxStatus hx_action(const host_bundle *b, int plugin, const char *action, const void *handle,
                    OfxPropertySetHandle in, OfxPropertySetHandle out) {
    OfxPlugin *p = b->get_plugin(plugin);
    if (!p || !p->mainEntry) return -1;
    return p->mainEntry(action, handle, in, out);
}

OfxStatus hx_load(const host_bundle *b, int plugin) {
    OfxPlugin *p = b->get_plugin(plugin);
    if (!p) return -1;
    p->setHost(&host_ofx);
    return hx_action(b, plugin, "OfxActionLoad", NULL, NULL, NULL);
}

OfxStatus hx_unload(const host_bundle *b, int plugin) { return hx_action(b, plugin, "OfxActionUnload", NULL, NULL, NULL); }

OfxStatus hx_describe(const host_bundle *b, int plugin, host_effect **desc) {
    *desc = he_new(HE_DESCRIPTOR, plugin);
    const char *dir = getenv("EW_OFX_BUNDLE");
    hp_set_s((*desc)->props, "OfxPluginPropFilePath", 0, dir ? dir : "");
    return hx_action(b, plugin, "OfxActionDescribe", *desc, NULL, NULL);
}

OfxStatus hx_describe_in_context(const host_bundle *b, int plugin, const char *context, host_effect **ctx) {
    *ctx = he_new(HE_CONTEXT, plugin);
    hp_set_s((*ctx)->props, "OfxImageEffectPropContext", 0, context);
    OfxPropertySetHandle in = hp_new("describeInContext inArgs", hs_describe_in_context_in);
    hp_set_s(in, "OfxImageEffectPropContext", 0, context);
    OfxStatus st = hx_action(b, plugin, "OfxImageEffectActionDescribeInContext", *ctx, in, NULL);
    hp_free(in);
    return st;
}

static void copy_prop_s(OfxPropertySetHandle to, OfxPropertySetHandle from, const char *name) {
    for (int i = 0; i < hp_count(from, name); i++) hp_set_s(to, name, i, hp_s(from, name, i));
}

OfxStatus hx_create_instance(const host_bundle *b, int plugin, const host_effect *ctx, const char *context,
                             host_effect **out) {
    host_effect *e = he_new(HE_INSTANCE, plugin);
    OfxPropertySetHandle p = e->props;
    hp_set_s(p, "OfxImageEffectPropContext", 0, context);
    hp_set_p(p, "OfxImageEffectPropPluginHandle", 0, (void *)ctx);
    hp_set_d(p, "OfxImageEffectPropProjectSize", 0, 256.0);
    hp_set_d(p, "OfxImageEffectPropProjectSize", 1, 256.0);
    hp_set_d(p, "OfxImageEffectPropProjectExtent", 0, 256.0);
    hp_set_d(p, "OfxImageEffectPropProjectExtent", 1, 256.0);
    hp_set_d(p, "OfxImageEffectPropPixelAspectRatio", 0, 1.0);
    hp_set_d(p, "OfxImageEffectInstancePropEffectDuration", 0, 100.0);
    hp_set_d(p, "OfxImageEffectPropFrameRate", 0, 24.0);
    hp_set_i(p, "OfxImageEffectPropSupportsTiles", 0, hp_i(ctx->props, "OfxImageEffectPropSupportsTiles", 0));

    for (int i = 0; i < ctx->num_clips; i++) {
        const host_clip *d = ctx->clips[i];
        host_clip *c = he_add_clip(e, d->name);
        copy_prop_s(c->props, d->props, "OfxPropLabel");
        copy_prop_s(c->props, d->props, "OfxImageEffectPropSupportedComponents");
        hp_set_i(c->props, "OfxImageClipPropOptional", 0, hp_i(d->props, "OfxImageClipPropOptional", 0));
        hp_set_i(c->props, "OfxImageEffectPropSupportsTiles", 0, hp_i(d->props, "OfxImageEffectPropSupportsTiles", 0));
        hp_set_s(c->props, "OfxImageEffectPropPixelDepth", 0, "OfxBitDepthFloat");
        hp_set_s(c->props, "OfxImageEffectPropComponents", 0, "OfxImageComponentRGBA");
        hp_set_s(c->props, "OfxImageClipPropUnmappedPixelDepth", 0, "OfxBitDepthFloat");
        hp_set_s(c->props, "OfxImageClipPropUnmappedComponents", 0, "OfxImageComponentRGBA");
        hp_set_s(c->props, "OfxImageEffectPropPreMultiplication", 0, "OfxImageAlphaPremultiplied");
        hp_set_d(c->props, "OfxImagePropPixelAspectRatio", 0, 1.0);
        hp_set_d(c->props, "OfxImageEffectPropFrameRate", 0, 24.0);
        hp_set_s(c->props, "OfxImageClipPropFieldOrder", 0, "OfxFieldNone");
        /* mandatory clips start connected, optional ones not */
        hp_set_i(c->props, "OfxImageClipPropConnected", 0, !hp_i(d->props, "OfxImageClipPropOptional", 0));
    }
    for (int i = 0; i < ctx->num_params; i++) {
        const host_param *d = ctx->params[i];
        host_param *q = he_add_param(e, d->type, d->name);
        OfxPropertySetHandle dp = d->props;
        if (!strcmp(d->type, "OfxParamTypeDouble")) {
            q->value = hp_d(dp, "OfxParamPropDefault", 0);
            hp_set_d(q->props, "OfxParamPropDefault", 0, q->value);
            hp_set_d(q->props, "OfxParamPropMin", 0, hp_d(dp, "OfxParamPropMin", 0));
            hp_set_d(q->props, "OfxParamPropMax", 0, hp_d(dp, "OfxParamPropMax", 0));
        } else {
            q->value = hp_i(dp, "OfxParamPropDefault", 0);
            hp_set_i(q->props, "OfxParamPropDefault", 0, (int)q->value);
        }
        copy_prop_s(q->props, dp, "OfxPropLabel");
        copy_prop_s(q->props, dp, "OfxParamPropHint");
    }
    *out = e;
    return hx_action(b, plugin, "OfxActionCreateInstance", e, NULL, NULL);
}

OfxStatus hx_destroy_instance(const host_bundle *b, int plugin, host_effect *inst) {
    OfxStatus st = hx_action(b, plugin, "OfxActionDestroyInstance", inst, NULL, NULL);
    he_free(inst);
    return st;
}

static void set_scale(OfxPropertySetHandle in) {
    for (int i = 0; i < 2; i++)
        hp_set_d(in, "OfxImageEffectPropRenderScale", i, host_cfg.render_scale[i] > 0.0 ? host_cfg.render_scale[i] : 1.0);
}

OfxStatus hx_rod(const host_bundle *b, int plugin, host_effect *inst, double time, double rod[4]) {
    OfxPropertySetHandle in = hp_new("getRegionOfDefinition inArgs", hs_rod_in);
    OfxPropertySetHandle out = hp_new("getRegionOfDefinition outArgs", hs_rod_out);
    hp_set_d(in, "OfxPropTime", 0, time);
    set_scale(in);
    OfxStatus st = hx_action(b, plugin, "OfxImageEffectActionGetRegionOfDefinition", inst, in, out);
    for (int i = 0; i < 4; i++) rod[i] = hp_d(out, "OfxImageEffectPropRegionOfDefinition", i);
    hp_free(in);
    hp_free(out);
    return st;
}

OfxStatus hx_roi(const host_bundle *b, int plugin, host_effect *inst, double time, const double region[4],
                 OfxPropertySetHandle *out) {
    OfxPropertySetHandle in = hp_new("getRegionsOfInterest inArgs", hs_roi_in);
    hp_set_d(in, "OfxPropTime", 0, time);
    set_scale(in);
    for (int i = 0; i < 4; i++) hp_set_d(in, "OfxImageEffectPropRegionOfInterest", i, region[i]);
    *out = hp_new("getRegionsOfInterest outArgs", NULL);
    /* one RoI per input clip, initialised to the default (the region asked for) */
    for (int c = 0; c < inst->num_clips; c++) {
        if (!strcmp(inst->clips[c]->name, "Output")) continue;
        char name[128];
        snprintf(name, sizeof name, "OfxImageClipPropRoI_%s", inst->clips[c]->name);
        hp_declare(*out, name, 'd', 4, 1);
        for (int i = 0; i < 4; i++) hp_set_d(*out, name, i, region[i]);
    }
    OfxStatus st = hx_action(b, plugin, "OfxImageEffectActionGetRegionsOfInterest", inst, in, *out);
    hp_free(in);
    return st;
}

OfxStatus hx_clip_prefs(const host_bundle *b, int plugin, host_effect *inst, OfxPropertySetHandle *out) {
    *out = hp_new("getClipPreferences outArgs", hs_clip_prefs_out);
    for (int c = 0; c < inst->num_clips; c++) {
        host_clip *clip = inst->clips[c];
        int is_output = !strcmp(clip->name, "Output");
        if (!is_output && !hp_i(clip->props, "OfxImageClipPropConnected", 0)) continue;
        char name[128];
        snprintf(name, sizeof name, "OfxImageClipPropComponents_%s", clip->name);
        hp_declare(*out, name, 's', 1, 1);
        /* the host's default, as hosts negotiating components by the spec
         * do: the richest the effect supports, whatever the input has */
        hp_set_s(*out, name, 0, "OfxImageComponentRGBA");
        snprintf(name, sizeof name, "OfxImageClipPropDepth_%s", clip->name);
        hp_declare(*out, name, 's', 1, 1);
        hp_set_s(*out, name, 0, hp_s(clip->props, "OfxImageEffectPropPixelDepth", 0));
        snprintf(name, sizeof name, "OfxImageClipPropPAR_%s", clip->name);
        hp_declare(*out, name, 'd', 1, 1);
        hp_set_d(*out, name, 0, 1.0);
    }
    return hx_action(b, plugin, "OfxImageEffectActionGetClipPreferences", inst, NULL, *out);
}

static void set_window(OfxPropertySetHandle in, OfxRectI w) {
    int v[4] = {w.x1, w.y1, w.x2, w.y2};
    for (int i = 0; i < 4; i++) hp_set_i(in, "OfxImageEffectPropRenderWindow", i, v[i]);
}

OfxStatus hx_is_identity(const host_bundle *b, int plugin, host_effect *inst, double time, OfxRectI window,
                         char *clip, size_t clip_len, double *clip_time) {
    OfxPropertySetHandle in = hp_new("isIdentity inArgs", hs_identity_in);
    OfxPropertySetHandle out = hp_new("isIdentity outArgs", hs_identity_out);
    hp_set_d(in, "OfxPropTime", 0, time);
    hp_set_s(in, "OfxImageEffectPropFieldToRender", 0, "OfxFieldNone");
    set_window(in, window);
    set_scale(in);
    hp_set_d(out, "OfxPropTime", 0, time);
    OfxStatus st = hx_action(b, plugin, "OfxImageEffectActionIsIdentity", inst, in, out);
    snprintf(clip, clip_len, "%s", hp_s(out, "OfxPropName", 0));
    *clip_time = hp_d(out, "OfxPropTime", 0);
    hp_free(in);
    hp_free(out);
    return st;
}

OfxStatus hx_render(const host_bundle *b, int plugin, host_effect *inst, double time, OfxRectI window) {
    OfxPropertySetHandle in = hp_new("render inArgs", hs_render_in);
    hp_set_d(in, "OfxPropTime", 0, time);
    hp_set_s(in, "OfxImageEffectPropFieldToRender", 0, "OfxFieldNone");
    set_window(in, window);
    set_scale(in);
    OfxStatus st = hx_action(b, plugin, "OfxImageEffectActionRender", inst, in, NULL);
    hp_free(in);
    return st;
}

static OfxStatus sequence_action(const host_bundle *b, int plugin, host_effect *inst, const char *action,
                                 double first, double last) {
    OfxPropertySetHandle in = hp_new("sequence render inArgs", hs_sequence_render_in);
    hp_set_d(in, "OfxImageEffectPropFrameRange", 0, first);
    hp_set_d(in, "OfxImageEffectPropFrameRange", 1, last);
    hp_set_d(in, "OfxImageEffectPropFrameStep", 0, 1.0);
    hp_set_i(in, "OfxPropIsInteractive", 0, 0);
    hp_set_i(in, "OfxImageEffectPropSequentialRenderStatus", 0, 0);
    hp_set_i(in, "OfxImageEffectPropInteractiveRenderStatus", 0, 0);
    set_scale(in);
    OfxStatus st = hx_action(b, plugin, action, inst, in, NULL);
    hp_free(in);
    return st;
}

OfxStatus hx_begin_sequence(const host_bundle *b, int plugin, host_effect *inst, double first, double last) {
    return sequence_action(b, plugin, inst, "OfxImageEffectActionBeginSequenceRender", first, last);
}

OfxStatus hx_end_sequence(const host_bundle *b, int plugin, host_effect *inst, double first, double last) {
    return sequence_action(b, plugin, inst, "OfxImageEffectActionEndSequenceRender", first, last);
}

OfxStatus hx_purge_caches(const host_bundle *b, int plugin, host_effect *inst) {
    return hx_action(b, plugin, "OfxActionPurgeCaches", inst, NULL, NULL);
}

/* ---- pixels ---------------------------------------------------------------- */
#define GUARD 64
#define GUARD_BYTE 0xAB
#define ROW_PAD 20 /* not a multiple of 16: catches code that assumes packed or aligned rows */

static const char *components_name(int comps) {
    return comps == 4 ? "OfxImageComponentRGBA" : comps == 3 ? "OfxImageComponentRGB" : "OfxImageComponentAlpha";
}

/* Allocate the clip's buffer for bounds and layout; memory filled with the
 * guard byte. */
static void layout_buffer(host_clip *c, int w, int h, int comps, int x1, int y1, int layout) {
    free(c->buf);
    size_t row = (size_t)w * (size_t)comps * sizeof(float);
    c->pad = (layout & HX_PAD_ROWS) ? ROW_PAD : 0;
    size_t rb = row + (size_t)c->pad;
    c->guard = GUARD;
    c->buf_bytes = rb * (size_t)h + 2 * GUARD;
    c->buf = (char *)malloc(c->buf_bytes);
    if (!c->buf) abort();
    memset(c->buf, GUARD_BYTE, c->buf_bytes);
    if (layout & HX_NEG_ROW_BYTES) {
        /* stored top-down: the bottom row (y1) is the last in memory */
        c->data = c->buf + GUARD + rb * (size_t)(h > 0 ? h - 1 : 0);
        c->row_bytes = -(int)rb;
    } else {
        c->data = c->buf + GUARD;
        c->row_bytes = (int)rb;
    }
    c->bounds.x1 = x1;
    c->bounds.y1 = y1;
    c->bounds.x2 = x1 + w;
    c->bounds.y2 = y1 + h;
    c->comps = comps;
    c->rod.x1 = x1;
    c->rod.y1 = y1;
    c->rod.x2 = x1 + w;
    c->rod.y2 = y1 + h;
    hp_set_s(c->props, "OfxImageEffectPropComponents", 0, components_name(comps));
    hp_set_s(c->props, "OfxImageClipPropUnmappedComponents", 0, components_name(comps));
}

static float *pixel(const host_clip *c, int x, int y) {
    return (float *)(c->data + (ptrdiff_t)(y - c->bounds.y1) * c->row_bytes +
                     (ptrdiff_t)(x - c->bounds.x1) * c->comps * (ptrdiff_t)sizeof(float));
}

void hx_clip_set_image(host_clip *c, const float *top_down, int w, int h, int comps, int x1, int y1, int layout) {
    layout_buffer(c, w, h, comps, x1, y1, layout);
    for (int r = 0; r < h; r++) {
        int y = y1 + h - 1 - r;
        memcpy(pixel(c, x1, y), top_down + (size_t)r * (size_t)w * (size_t)comps,
               (size_t)w * (size_t)comps * sizeof(float));
    }
    hx_clip_connect(c, 1);
}

void hx_clip_connect(host_clip *c, int connected) { hp_set_i(c->props, "OfxImageClipPropConnected", 0, connected); }

void hx_output_prepare(host_clip *out, OfxRectI b, int comps, int layout) {
    int w = b.x2 - b.x1, h = b.y2 - b.y1;
    layout_buffer(out, w, h, comps, b.x1, b.y1, layout);
    for (int y = b.y1; y < b.y2; y++)
        for (int x = b.x1; x < b.x2; x++)
            for (int k = 0; k < comps; k++) pixel(out, x, y)[k] = HX_CANARY;
}

void hx_output_read(const host_clip *out, OfxRectI r, float *top_down) {
    int w = r.x2 - r.x1, h = r.y2 - r.y1;
    for (int row = 0; row < h; row++) {
        int y = r.y2 - 1 - row;
        memcpy(top_down + (size_t)row * (size_t)w * (size_t)out->comps, pixel(out, r.x1, y),
               (size_t)w * (size_t)out->comps * sizeof(float));
    }
}

int hx_output_guards_intact(const host_clip *out) {
    const unsigned char *p = (const unsigned char *)out->buf;
    size_t row = (size_t)(out->bounds.x2 - out->bounds.x1) * (size_t)out->comps * sizeof(float);
    size_t rb = row + (size_t)out->pad;
    int h = out->bounds.y2 - out->bounds.y1;
    for (size_t i = 0; i < out->guard; i++)
        if (p[i] != GUARD_BYTE || p[out->buf_bytes - 1 - i] != GUARD_BYTE) return 0;
    for (int r = 0; r < h; r++)
        for (size_t i = row; i < rb; i++)
            if (p[out->guard + (size_t)r * rb + i] != GUARD_BYTE) return 0;
    return 1;
}
