/*
 * Instances: their private data (clip and parameter handles, looked up once
 * at creation), and the actions that describe an instance's output before
 * it renders: region of definition, regions of interest, clip preferences,
 * identity.
 */
#include "ofx_plugin.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define EW_OFX_INSTANCE_MAGIC 0x45574f46u /* "EWOF" */

static OfxStatus effect_props(OfxImageEffectHandle effect, OfxPropertySetHandle *props) {
    *props = NULL;
    OfxStatus st = ew_ofx.effect->getPropertySet(effect, props);
    if (st == kOfxStatOK && !*props) st = kOfxStatErrBadHandle;
    return st;
}

ew_ofx_instance *ew_ofx_instance_get(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxStatus *status) {
    OfxPropertySetHandle props;
    void *data = NULL;
    *status = effect_props(effect, &props);
    if (*status != kOfxStatOK) return NULL;
    /* No such property (a descriptor), no data (createInstance never ran or
     * failed), or another plugin's data: not an instance of this plugin. */
    ew_ofx_instance *inst = NULL;
    if (ew_ofx.prop->propGetPointer(props, kOfxPropInstanceData, 0, &data) == kOfxStatOK)
        inst = (ew_ofx_instance *)data;
    if (!inst || inst->magic != EW_OFX_INSTANCE_MAGIC || inst->node != node) {
        *status = kOfxStatErrBadHandle;
        return NULL;
    }
    return inst;
}

OfxStatus ew_ofx_create_instance(const ew_ofx_node *node, OfxImageEffectHandle effect) {
    OfxPropertySetHandle props;
    OfxStatus st = effect_props(effect, &props);
    if (st != kOfxStatOK) return st;
    void *old = NULL;
    if (ew_ofx.prop->propGetPointer(props, kOfxPropInstanceData, 0, &old) == kOfxStatOK && old)
        return kOfxStatErrExists; /* created twice: keep the first */

    ew_ofx_instance *inst = (ew_ofx_instance *)ew_ofx_alloc(sizeof *inst);
    if (!inst) return kOfxStatErrMemory;
    inst->magic = EW_OFX_INSTANCE_MAGIC;
    inst->node = node;
    ew_ofx_keep_init(&inst->keep);

    const OfxImageEffectSuiteV1 *E = ew_ofx.effect;
    if ((st = E->clipGetHandle(effect, kOfxImageEffectSimpleSourceClipName, &inst->source, NULL)) != kOfxStatOK ||
        (st = E->clipGetHandle(effect, kOfxImageEffectOutputClipName, &inst->output, NULL)) != kOfxStatOK)
        goto fail;
    if (!inst->source || !inst->output) {
        st = kOfxStatErrBadHandle;
        goto fail;
    }
    /* A feature clip the host did not create is treated as unconnected. */
    for (int i = 0; i < node->num_aux; i++)
        if (E->clipGetHandle(effect, node->aux[i].clip, &inst->aux[i], NULL) != kOfxStatOK) inst->aux[i] = NULL;

    OfxParamSetHandle set = NULL;
    if ((st = E->getParamSet(effect, &set)) != kOfxStatOK) goto fail;
    for (int i = 0; i < node->num_params; i++) {
        if ((st = ew_ofx.param->paramGetHandle(set, node->params[i].name, &inst->params[i], NULL)) != kOfxStatOK)
            goto fail;
        if (!inst->params[i]) {
            st = kOfxStatErrBadHandle;
            goto fail;
        }
    }
    if ((st = ew_ofx.prop->propSetPointer(props, kOfxPropInstanceData, 0, inst)) != kOfxStatOK) goto fail;
    return kOfxStatOK;
fail:
    inst->magic = 0;
    ew_ofx_keep_fini(&inst->keep);
    ew_ofx_free(inst);
    return st;
}

OfxStatus ew_ofx_destroy_instance(const ew_ofx_node *node, OfxImageEffectHandle effect) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    OfxPropertySetHandle props;
    if (effect_props(effect, &props) == kOfxStatOK) ew_ofx.prop->propSetPointer(props, kOfxPropInstanceData, 0, NULL);
    inst->magic = 0;
    ew_ofx_keep_fini(&inst->keep);
    ew_ofx_free(inst);
    return kOfxStatOK;
}

OfxStatus ew_ofx_param_value(const ew_ofx_instance *inst, int i, OfxTime time, double *value) {
    const ew_param_info *p = &inst->node->params[i];
    OfxStatus st;
    double v;
    if (p->type == EW_PARAM_FLOAT) {
        st = ew_ofx.param->paramGetValueAtTime(inst->params[i], time, &v);
    } else {
        int iv = 0;
        st = ew_ofx.param->paramGetValueAtTime(inst->params[i], time, &iv);
        v = p->type == EW_PARAM_BOOL ? (iv != 0) : iv;
    }
    if (st != kOfxStatOK) return st;
    /* A host should keep values in [min, max]; if one does not, the nearest
     * valid value beats failing the frame. */
    if (!isfinite(v)) v = p->default_value;
    if (v < p->min_value) v = p->min_value;
    if (v > p->max_value) v = p->max_value;
    if (p->type != EW_PARAM_FLOAT) v = floor(v + 0.5);
    *value = v;
    return kOfxStatOK;
}

static OfxStatus time_of(OfxPropertySetHandle in, OfxTime *time) {
    *time = 0.0;
    if (!in) return kOfxStatErrBadHandle;
    return ew_ofx.prop->propGetDouble(in, kOfxPropTime, 0, time);
}

/* The output covers exactly the source: filtering neither grows nor
 * shrinks the frame, and the feature clips are guides, not content. */
static OfxStatus source_rod(const ew_ofx_instance *inst, OfxTime time, double rod[4]) {
    OfxRectD r = {0.0, 0.0, 0.0, 0.0};
    OfxStatus st = ew_ofx.effect->clipGetRegionOfDefinition(inst->source, time, &r);
    rod[0] = r.x1;
    rod[1] = r.y1;
    rod[2] = r.x2;
    rod[3] = r.y2;
    return st;
}

OfxStatus ew_ofx_region_of_definition(const ew_ofx_node *node, OfxImageEffectHandle effect,
                                      OfxPropertySetHandle in, OfxPropertySetHandle out) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    OfxTime time;
    double rod[4];
    if ((st = time_of(in, &time)) != kOfxStatOK) return st;
    if (!out) return kOfxStatErrBadHandle;
    if ((st = source_rod(inst, time, rod)) != kOfxStatOK) return st;
    return ew_ofx.prop->propSetDoubleN(out, kOfxImageEffectPropRegionOfDefinition, 4, rod);
}

/* Each output pixel depends on the whole frame (see describe), so every
 * input is wanted whole, whatever part of the output is asked for. */
OfxStatus ew_ofx_regions_of_interest(const ew_ofx_node *node, OfxImageEffectHandle effect,
                                     OfxPropertySetHandle in, OfxPropertySetHandle out) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    OfxTime time;
    double rod[4];
    if ((st = time_of(in, &time)) != kOfxStatOK) return st;
    if (!out) return kOfxStatErrBadHandle;
    if ((st = source_rod(inst, time, rod)) != kOfxStatOK) return st;
    char name[96];
    snprintf(name, sizeof name, "%s%s", kOfxImageClipPropRoIPrefix, kOfxImageEffectSimpleSourceClipName);
    if ((st = ew_ofx.prop->propSetDoubleN(out, name, 4, rod)) != kOfxStatOK) return st;
    for (int i = 0; i < node->num_aux; i++) {
        if (!inst->aux[i]) continue;
        snprintf(name, sizeof name, "%s%s", kOfxImageClipPropRoIPrefix, node->aux[i].clip);
        ew_ofx.prop->propSetDoubleN(out, name, 4, rod); /* absent when the host omits unconnected clips */
    }
    return kOfxStatOK;
}

static int connected(OfxImageClipHandle clip) {
    OfxPropertySetHandle props = NULL;
    int c = 0;
    if (!clip || ew_ofx.effect->clipGetPropertySet(clip, &props) != kOfxStatOK || !props) return 0;
    if (ew_ofx.prop->propGetInt(props, kOfxImageClipPropConnected, 0, &c) != kOfxStatOK) return 0;
    return c != 0;
}

static OfxStatus prefer(OfxPropertySetHandle out, const char *clip, const char *components) {
    char name[96];
    OfxStatus st;
    if (components) {
        snprintf(name, sizeof name, "%s%s", kOfxImageClipPropComponentsPrefix, clip);
        if ((st = ew_ofx.prop->propSetString(out, name, 0, components)) != kOfxStatOK) return st;
    }
    snprintf(name, sizeof name, "%s%s", kOfxImageClipPropDepthPrefix, clip);
    return ew_ofx.prop->propSetString(out, name, 0, kOfxBitDepthFloat);
}

OfxStatus ew_ofx_clip_preferences(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxPropertySetHandle out) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    if (!out) return kOfxStatErrBadHandle;
    /* Float RGBA through the effect. Feature clips ask for the components
     * their input really has: left to the host's default, a one-channel
     * depth may be expanded to RGBA with the depth in alpha and zeros in
     * R, G, B, where the plugin would read a flat zero. */
    if ((st = prefer(out, kOfxImageEffectOutputClipName, kOfxImageComponentRGBA)) != kOfxStatOK) return st;
    if (connected(inst->source) &&
        (st = prefer(out, kOfxImageEffectSimpleSourceClipName, kOfxImageComponentRGBA)) != kOfxStatOK)
        return st;
    for (int i = 0; i < node->num_aux; i++) {
        if (!connected(inst->aux[i])) continue;
        const int c = ew_ofx_clip_unmapped_components(inst->aux[i]);
        prefer(out, node->aux[i].clip,
               c == 1 ? kOfxImageComponentAlpha : c == 3 ? kOfxImageComponentRGB : c == 4 ? kOfxImageComponentRGBA : NULL);
    }
    return kOfxStatOK;
}

OfxStatus ew_ofx_is_identity(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxPropertySetHandle in,
                             OfxPropertySetHandle out) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    OfxTime time;
    if ((st = time_of(in, &time)) != kOfxStatOK) return st;
    if (!out) return kOfxStatErrBadHandle;
    if (!node->identity_params[0]) return kOfxStatReplyDefault;
    for (int k = 0; k < EW_OFX_MAX_IDENTITY && node->identity_params[k]; k++) {
        int found = 0;
        for (int i = 0; i < node->num_params && !found; i++) {
            if (strcmp(node->params[i].name, node->identity_params[k]) != 0) continue;
            double v;
            if ((st = ew_ofx_param_value(inst, i, time, &v)) != kOfxStatOK) return st;
            if (v != 0.0) return kOfxStatReplyDefault;
            found = 1;
        }
        if (!found) return kOfxStatReplyDefault; /* the library renamed it: never claim identity */
    }
    if ((st = ew_ofx.prop->propSetString(out, kOfxPropName, 0, kOfxImageEffectSimpleSourceClipName)) != kOfxStatOK)
        return st;
    ew_ofx.prop->propSetDouble(out, kOfxPropTime, 0, time);
    return kOfxStatOK;
}
