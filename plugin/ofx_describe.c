/*
 * describe and describeInContext: the effect's properties, its clips and
 * its parameters, all generated from the library's descriptors.
 *
 * A failed set of a property a 1.0 host may not know is ignored (it only
 * loses a hint); failures of what the plugin cannot work without are
 * returned.
 */
#include "ofx_plugin.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

OfxStatus ew_ofx_describe(const ew_ofx_node *node, OfxImageEffectHandle effect) {
    const OfxPropertySuiteV1 *P = ew_ofx.prop;
    OfxPropertySetHandle props = NULL;
    OfxStatus st = ew_ofx.effect->getPropertySet(effect, &props);
    if (st != kOfxStatOK) return st;
    if (!props) return kOfxStatErrBadHandle;

    P->propSetString(props, kOfxPropLabel, 0, node->label);
    P->propSetString(props, kOfxImageEffectPluginPropGrouping, 0, EW_OFX_GROUPING);
    P->propSetString(props, kOfxPropPluginDescription, 0, node->summary);
    P->propSetString(props, kOfxPropVersionLabel, 0, ew_version_string());

    const char *contexts[2] = {kOfxImageEffectContextFilter, kOfxImageEffectContextGeneral};
    if ((st = P->propSetStringN(props, kOfxImageEffectPropSupportedContexts, 2, contexts)) != kOfxStatOK) return st;
    /* The library computes in 32-bit float; the host converts other depths. */
    if ((st = P->propSetString(props, kOfxImageEffectPropSupportedPixelDepths, 0, kOfxBitDepthFloat)) != kOfxStatOK)
        return st;

    /* Whole-frame filters: a tile would filter differently from the frame
     * (pyramid levels, grid cells and edge weights all see the whole image),
     * so ask for full frames and do the threading ourselves. */
    P->propSetInt(props, kOfxImageEffectPropSupportsTiles, 0, 0);
    P->propSetInt(props, kOfxImageEffectPluginPropHostFrameThreading, 0, 0);
    P->propSetInt(props, kOfxImageEffectPropSupportsMultiResolution, 0, 1);
    P->propSetInt(props, kOfxImageEffectPropTemporalClipAccess, 0, 0);
    P->propSetInt(props, kOfxImageEffectPluginPropSingleInstance, 0, 0);
    /* Each render builds its own library objects, but one render per
     * instance at a time keeps memory use predictable. */
    P->propSetString(props, kOfxImageEffectPluginRenderThreadSafety, 0, kOfxImageEffectRenderInstanceSafe);
    P->propSetInt(props, kOfxImageEffectPropSupportsMultipleClipDepths, 0, 0);
    P->propSetInt(props, kOfxImageEffectPropSupportsMultipleClipPARs, 0, 0);
    P->propSetInt(props, kOfxImageEffectPluginPropFieldRenderTwiceAlways, 0, 0);
    return kOfxStatOK;
}

static OfxStatus define_clip(OfxImageEffectHandle effect, const char *name, const char *label, int optional,
                             int any_components) {
    const OfxPropertySuiteV1 *P = ew_ofx.prop;
    OfxPropertySetHandle clip = NULL;
    OfxStatus st = ew_ofx.effect->clipDefine(effect, name, &clip);
    if (st != kOfxStatOK) return st;
    if (!clip) return kOfxStatErrBadHandle;
    /* Colour in and out is RGB(A); a feature clip may also be a single
     * channel (depth), which the host should not expand. */
    const char *comps[3] = {kOfxImageComponentRGBA, kOfxImageComponentRGB, kOfxImageComponentAlpha};
    if ((st = P->propSetStringN(clip, kOfxImageEffectPropSupportedComponents, any_components ? 3 : 2, comps)) !=
        kOfxStatOK)
        return st;
    if (label) P->propSetString(clip, kOfxPropLabel, 0, label);
    P->propSetInt(clip, kOfxImageEffectPropSupportsTiles, 0, 0);
    P->propSetInt(clip, kOfxImageEffectPropTemporalClipAccess, 0, 0);
    if (optional && (st = P->propSetInt(clip, kOfxImageClipPropOptional, 0, 1)) != kOfxStatOK) return st;
    return kOfxStatOK;
}

/* "spatial_rate" -> "Spatial rate" */
static void label_of(const char *name, char *out, size_t len) {
    size_t i = 0;
    for (; name[i] && i + 1 < len; i++) out[i] = name[i] == '_' ? ' ' : name[i];
    out[i] = '\0';
    if (out[0]) out[0] = (char)toupper((unsigned char)out[0]);
}

/* A slider range that fits the useful values: descriptors give the valid
 * range, which can be six decades wide. */
static double display_max(const ew_param_info *p) {
    double lo = p->min_value, hi = p->max_value, def = p->default_value;
    double d = def > 0.0 ? 10.0 * def : 100.0;
    if (d < lo + 1.0) d = lo + 1.0;
    return d < hi ? d : hi;
}

static OfxStatus define_param(OfxParamSetHandle set, const ew_ofx_node *node, int index) {
    const OfxPropertySuiteV1 *P = ew_ofx.prop;
    const ew_param_info *p = &node->params[index];
    const int choices = node->param_choices[index];
    const char *type = choices > 0                ? kOfxParamTypeChoice
                       : p->type == EW_PARAM_FLOAT ? kOfxParamTypeDouble
                       : p->type == EW_PARAM_BOOL  ? kOfxParamTypeBoolean
                                                   : kOfxParamTypeInteger;
    OfxPropertySetHandle props = NULL;
    OfxStatus st = ew_ofx.param->paramDefine(set, type, p->name, &props);
    if (st != kOfxStatOK) return st;
    if (!props) return kOfxStatErrBadHandle;

    char label[64];
    label_of(p->name, label, sizeof label);
    P->propSetString(props, kOfxPropLabel, 0, label);
    /* "samples": 0 also means "from the host", which only the plugin knows */
    P->propSetString(props, kOfxParamPropHint, 0, !strcmp(p->name, "samples") ? EW_OFX_SAMPLES_HINT : p->hint ? p->hint : "");
    P->propSetString(props, kOfxParamPropScriptName, 0, p->name);
    P->propSetInt(props, kOfxParamPropAnimates, 0, 1);

    if (p->type == EW_PARAM_FLOAT) {
        if ((st = P->propSetDouble(props, kOfxParamPropDefault, 0, p->default_value)) != kOfxStatOK) return st;
        P->propSetDouble(props, kOfxParamPropMin, 0, p->min_value);
        P->propSetDouble(props, kOfxParamPropMax, 0, p->max_value);
        P->propSetDouble(props, kOfxParamPropDisplayMin, 0, p->min_value);
        P->propSetDouble(props, kOfxParamPropDisplayMax, 0, display_max(p));
        P->propSetString(props, kOfxParamPropDoubleType, 0, kOfxParamDoubleTypePlain);
        /* a slider step of about a tenth of the default's magnitude */
        double mag = fabs(p->default_value) > 0.0 ? fabs(p->default_value) : 1.0;
        double step = pow(10.0, floor(log10(mag)) - 1.0);
        P->propSetDouble(props, kOfxParamPropIncrement, 0, step);
        int digits = step < 1.0 ? (int)ceil(-log10(step)) + 1 : 2;
        P->propSetInt(props, kOfxParamPropDigits, 0, digits > 6 ? 6 : digits);
    } else if (p->type == EW_PARAM_BOOL) {
        if ((st = P->propSetInt(props, kOfxParamPropDefault, 0, p->default_value != 0.0f)) != kOfxStatOK) return st;
    } else if (choices > 0) { /* the names, in index order: the value is the library's index */
        for (int c = 0; c < choices; c++) {
            const char *name = ew_method_param_choice(node->kind, node->method, index, c);
            if ((st = P->propSetString(props, kOfxParamPropChoiceOption, c, name ? name : "")) != kOfxStatOK) return st;
        }
        if ((st = P->propSetInt(props, kOfxParamPropDefault, 0, (int)lrintf(p->default_value))) != kOfxStatOK)
            return st;
    } else {
        if ((st = P->propSetInt(props, kOfxParamPropDefault, 0, (int)lrintf(p->default_value))) != kOfxStatOK)
            return st;
        P->propSetInt(props, kOfxParamPropMin, 0, (int)ceilf(p->min_value));
        P->propSetInt(props, kOfxParamPropMax, 0, (int)floorf(p->max_value));
        P->propSetInt(props, kOfxParamPropDisplayMin, 0, (int)ceilf(p->min_value));
        P->propSetInt(props, kOfxParamPropDisplayMax, 0, (int)floor(display_max(p)));
    }
    return kOfxStatOK;
}

OfxStatus ew_ofx_describe_in_context(const ew_ofx_node *node, OfxImageEffectHandle effect,
                                     OfxPropertySetHandle in) {
    if (!in) return kOfxStatErrBadHandle;
    char *context = NULL;
    OfxStatus st = ew_ofx.prop->propGetString(in, kOfxImageEffectPropContext, 0, &context);
    if (st != kOfxStatOK) return st;
    int general = context && !strcmp(context, kOfxImageEffectContextGeneral);
    if (!general && !(context && !strcmp(context, kOfxImageEffectContextFilter)))
        return kOfxStatErrMissingHostFeature; /* a context we never said we support */

    if ((st = define_clip(effect, kOfxImageEffectSimpleSourceClipName, NULL, 0, 0)) != kOfxStatOK) return st;
    if ((st = define_clip(effect, kOfxImageEffectOutputClipName, NULL, 0, 0)) != kOfxStatOK) return st;
    /* The filter context has exactly one mandatory input, Source; the
     * general context may mark a feature the method cannot run without
     * (the DoF's depth) as mandatory. Render checks either way. */
    for (int i = 0; i < node->num_aux; i++) {
        const ew_ofx_aux *a = &node->aux[i];
        if ((st = define_clip(effect, a->clip, a->clip, !(general && a->required), 1)) != kOfxStatOK) return st;
    }

    OfxParamSetHandle set = NULL;
    if ((st = ew_ofx.effect->getParamSet(effect, &set)) != kOfxStatOK) return st;
    if (!set) return kOfxStatErrBadHandle;
    for (int i = 0; i < node->num_params; i++)
        if ((st = define_param(set, node, i)) != kOfxStatOK) return st;
    return kOfxStatOK;
}
