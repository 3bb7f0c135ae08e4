/*
 * The binary's exported entry points (OfxGetNumberOfPlugins, OfxGetPlugin,
 * OfxSetHost — nothing else is exported, see exports.map) and the action
 * dispatch.
 *
 * OFX hands an action only (action, handle, inArgs, outArgs), not which
 * plugin it is for, so each plugin slot gets its own main entry function
 * that passes its slot number on.
 */
#include "ofx_plugin.h"

#include <pthread.h>
#include <string.h>

#define EW_OFX_EXPORT __attribute__((visibility("default")))

EW_OFX_EXPORT int OfxGetNumberOfPlugins(void);
EW_OFX_EXPORT OfxPlugin *OfxGetPlugin(int nth);
EW_OFX_EXPORT OfxStatus OfxSetHost(const OfxHost *host);

static OfxStatus dispatch(int slot, const char *action, const void *handle, OfxPropertySetHandle in,
                          OfxPropertySetHandle out) {
    const ew_ofx_node *node = ew_ofx_node_get(slot);
    if (!node) return kOfxStatErrFatal; /* a slot we never handed out */
    if (!action) return kOfxStatErrValue;

    if (!strcmp(action, kOfxActionLoad)) return ew_ofx_load();
    if (!strcmp(action, kOfxActionUnload)) return ew_ofx_unload();

    /* Actions we do not trap need neither a handle nor the suites. */
    int known = !strcmp(action, kOfxActionDescribe) || !strcmp(action, kOfxImageEffectActionDescribeInContext) ||
                !strcmp(action, kOfxActionCreateInstance) || !strcmp(action, kOfxActionDestroyInstance) ||
                !strcmp(action, kOfxImageEffectActionGetRegionOfDefinition) ||
                !strcmp(action, kOfxImageEffectActionGetRegionsOfInterest) ||
                !strcmp(action, kOfxImageEffectActionGetClipPreferences) ||
                !strcmp(action, kOfxImageEffectActionIsIdentity) || !strcmp(action, kOfxImageEffectActionRender) ||
                !strcmp(action, kOfxActionPurgeCaches) || !strcmp(action, kOfxImageEffectActionEndSequenceRender);
    if (!known) return kOfxStatReplyDefault;

    if (!ew_ofx_loaded()) return kOfxStatFailed; /* the host skipped kOfxActionLoad */
    OfxImageEffectHandle effect = (OfxImageEffectHandle)(uintptr_t)handle;
    if (!effect) return kOfxStatErrBadHandle;

    if (!strcmp(action, kOfxActionDescribe)) return ew_ofx_describe(node, effect);
    if (!strcmp(action, kOfxImageEffectActionDescribeInContext))
        return ew_ofx_describe_in_context(node, effect, in);
    if (!strcmp(action, kOfxActionCreateInstance)) return ew_ofx_create_instance(node, effect);
    if (!strcmp(action, kOfxActionDestroyInstance)) return ew_ofx_destroy_instance(node, effect);
    if (!strcmp(action, kOfxImageEffectActionGetRegionOfDefinition))
        return ew_ofx_region_of_definition(node, effect, in, out);
    if (!strcmp(action, kOfxImageEffectActionGetRegionsOfInterest))
        return ew_ofx_regions_of_interest(node, effect, in, out);
    if (!strcmp(action, kOfxImageEffectActionGetClipPreferences)) return ew_ofx_clip_preferences(node, effect, out);
    if (!strcmp(action, kOfxImageEffectActionIsIdentity)) return ew_ofx_is_identity(node, effect, in, out);
    /* The kept device and op go when the host wants memory back, and when
     * a batch render is over (ofx_keep.c). */
    if (!strcmp(action, kOfxActionPurgeCaches) || !strcmp(action, kOfxImageEffectActionEndSequenceRender))
        return ew_ofx_drop_kept(node, effect);
    return ew_ofx_render(node, effect, in);
}

static void set_host(OfxHost *host) { ew_ofx_set_host(host); }

#define EW_OFX_SLOT(n)                                                                                          \
    static OfxStatus entry_##n(const char *action, const void *handle, OfxPropertySetHandle in,               \
                               OfxPropertySetHandle out) {                                                     \
        return dispatch(n, action, handle, in, out);                                                           \
    }
EW_OFX_SLOT(0)
EW_OFX_SLOT(1)
EW_OFX_SLOT(2)
EW_OFX_SLOT(3)
EW_OFX_SLOT(4)
EW_OFX_SLOT(5)
EW_OFX_SLOT(6)
EW_OFX_SLOT(7)
EW_OFX_SLOT(8)
EW_OFX_SLOT(9)
EW_OFX_SLOT(10)
EW_OFX_SLOT(11)
EW_OFX_SLOT(12)
EW_OFX_SLOT(13)
EW_OFX_SLOT(14)
EW_OFX_SLOT(15)

static OfxPluginEntryPoint *const entries[EW_OFX_MAX_PLUGINS] = {
    entry_0, entry_1, entry_2,  entry_3,  entry_4,  entry_5,  entry_6,  entry_7,
    entry_8, entry_9, entry_10, entry_11, entry_12, entry_13, entry_14, entry_15};

static OfxPlugin plugins[EW_OFX_MAX_PLUGINS];
static pthread_once_t plugins_once = PTHREAD_ONCE_INIT;

static void fill_plugins(void) {
    for (int i = 0; i < ew_ofx_node_count(); i++) {
        OfxPlugin *p = &plugins[i];
        p->pluginApi = kOfxImageEffectPluginApi;
        p->apiVersion = kOfxImageEffectPluginApiVersion;
        p->pluginIdentifier = ew_ofx_node_get(i)->identifier;
        /* Major changes when saved setups stop loading the same (a parameter
         * renamed or changed meaning); minor follows the library. */
        p->pluginVersionMajor = 1;
        p->pluginVersionMinor = EW_VERSION_MINOR;
        p->setHost = set_host;
        p->mainEntry = entries[i];
    }
}

int OfxGetNumberOfPlugins(void) { return ew_ofx_node_count(); }

OfxPlugin *OfxGetPlugin(int nth) {
    if (!ew_ofx_node_get(nth)) return NULL;
    pthread_once(&plugins_once, fill_plugins);
    return &plugins[nth];
}

/* OFX 1.5: called before OfxGetNumberOfPlugins by hosts that know it. The
 * pointer is only promised valid until OfxGetPlugin; the mandatory
 * OfxPlugin::setHost that follows replaces it. */
OfxStatus OfxSetHost(const OfxHost *host) {
    if (!host) return kOfxStatErrBadHandle;
    ew_ofx_set_host(host);
    return kOfxStatOK;
}
