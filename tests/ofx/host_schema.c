/*
 * Which properties each OFX object has, with type, dimension and whether a
 * plugin may write it — transcribed from the OFX 1.4 reference as string
 * literals (not from plugin/ofx_abi.h, so a wrong name there shows up here
 * as a violation). {name, type, dim (0 = N), plugin writes}.
 */
#include "ofx_host.h"

#define RO 0
#define RW 1

#define COMMON_LABELS                                                                                          \
    {"OfxPropLabel", 's', 1, RW}, {"OfxPropShortLabel", 's', 1, RW}, {"OfxPropLongLabel", 's', 1, RW}

const hp_schema hs_host[] = {
    {"OfxPropType", 's', 1, RO},
    {"OfxPropName", 's', 1, RO},
    {"OfxPropLabel", 's', 1, RO},
    {"OfxPropVersion", 'i', 0, RO},
    {"OfxPropVersionLabel", 's', 1, RO},
    {"OfxPropAPIVersion", 'i', 0, RO},
    {"OfxImageEffectHostPropIsBackground", 'i', 1, RO},
    {"OfxImageEffectPropSupportsOverlays", 'i', 1, RO},
    {"OfxImageEffectPropSupportsMultiResolution", 'i', 1, RO},
    {"OfxImageEffectPropSupportsTiles", 'i', 1, RO},
    {"OfxImageEffectPropTemporalClipAccess", 'i', 1, RO},
    {"OfxImageEffectPropSupportedComponents", 's', 0, RO},
    {"OfxImageEffectPropSupportedContexts", 's', 0, RO},
    {"OfxImageEffectPropSupportedPixelDepths", 's', 0, RO},
    {"OfxImageEffectPropMultipleClipDepths", 'i', 1, RO},
    {"OfxImageEffectPropSupportsMultipleClipPARs", 'i', 1, RO},
    {"OfxImageEffectPropSetableFrameRate", 'i', 1, RO},
    {"OfxImageEffectPropSetableFielding", 'i', 1, RO},
    {"OfxParamHostPropSupportsCustomInteract", 'i', 1, RO},
    {"OfxParamHostPropSupportsStringAnimation", 'i', 1, RO},
    {"OfxParamHostPropSupportsChoiceAnimation", 'i', 1, RO},
    {"OfxParamHostPropSupportsBooleanAnimation", 'i', 1, RO},
    {"OfxParamHostPropSupportsCustomAnimation", 'i', 1, RO},
    {"OfxParamHostPropMaxParameters", 'i', 1, RO},
    {"OfxParamHostPropMaxPages", 'i', 1, RO},
    {"OfxParamHostPropPageRowColumnCount", 'i', 2, RO},
    {NULL, 0, 0, 0},
};

#define EFFECT_DESCRIPTOR_PROPS                                                                                \
    {"OfxPropType", 's', 1, RO}, COMMON_LABELS, {"OfxPropVersion", 'i', 0, RW},                                \
        {"OfxPropVersionLabel", 's', 1, RW}, {"OfxPropPluginDescription", 's', 1, RW},                          \
        {"OfxPluginPropFilePath", 's', 1, RO}, {"OfxImageEffectPropSupportedContexts", 's', 0, RW},             \
        {"OfxImageEffectPluginPropGrouping", 's', 1, RW}, {"OfxImageEffectPluginPropSingleInstance", 'i', 1, RW}, \
        {"OfxImageEffectPluginRenderThreadSafety", 's', 1, RW},                                                 \
        {"OfxImageEffectPluginPropHostFrameThreading", 'i', 1, RW},                                             \
        {"OfxImageEffectPluginPropOverlayInteractV1", 'p', 1, RW},                                              \
        {"OfxImageEffectPropSupportsMultiResolution", 'i', 1, RW}, {"OfxImageEffectPropSupportsTiles", 'i', 1, RW}, \
        {"OfxImageEffectPropTemporalClipAccess", 'i', 1, RW}, {"OfxImageEffectPropSupportedPixelDepths", 's', 0, RW}, \
        {"OfxImageEffectPluginPropFieldRenderTwiceAlways", 'i', 1, RW},                                         \
        {"OfxImageEffectPropMultipleClipDepths", 'i', 1, RW},                                                   \
        {"OfxImageEffectPropSupportsMultipleClipPARs", 'i', 1, RW},                                             \
        {"OfxImageEffectPropClipPreferencesSlaveParam", 's', 0, RW}

const hp_schema hs_effect_descriptor[] = {EFFECT_DESCRIPTOR_PROPS, {NULL, 0, 0, 0}};
const hp_schema hs_context_descriptor[] = {EFFECT_DESCRIPTOR_PROPS, {"OfxImageEffectPropContext", 's', 1, RO}, {NULL, 0, 0, 0}};

const hp_schema hs_instance[] = {
    {"OfxPropType", 's', 1, RO},
    {"OfxPropLabel", 's', 1, RO},
    {"OfxImageEffectPropContext", 's', 1, RO},
    {"OfxPropInstanceData", 'p', 1, RW},
    {"OfxPropIsInteractive", 'i', 1, RO},
    {"OfxImageEffectPropPluginHandle", 'p', 1, RO},
    {"OfxImageEffectPropProjectSize", 'd', 2, RO},
    {"OfxImageEffectPropProjectOffset", 'd', 2, RO},
    {"OfxImageEffectPropProjectExtent", 'd', 2, RO},
    {"OfxImageEffectPropPixelAspectRatio", 'd', 1, RO},
    {"OfxImageEffectInstancePropEffectDuration", 'd', 1, RO},
    {"OfxImageEffectInstancePropSequentialRender", 'i', 1, RW},
    {"OfxImageEffectPropSupportsTiles", 'i', 1, RW},
    {"OfxImageEffectPropFrameRate", 'd', 1, RO},
    {NULL, 0, 0, 0},
};

const hp_schema hs_clip_descriptor[] = {
    {"OfxPropType", 's', 1, RO},
    {"OfxPropName", 's', 1, RO},
    COMMON_LABELS,
    {"OfxImageEffectPropSupportedComponents", 's', 0, RW},
    {"OfxImageEffectPropTemporalClipAccess", 'i', 1, RW},
    {"OfxImageClipPropOptional", 'i', 1, RW},
    {"OfxImageClipPropFieldExtraction", 's', 1, RW},
    {"OfxImageClipPropIsMask", 'i', 1, RW},
    {"OfxImageEffectPropSupportsTiles", 'i', 1, RW},
    {NULL, 0, 0, 0},
};

const hp_schema hs_clip_instance[] = {
    {"OfxPropType", 's', 1, RO},
    {"OfxPropName", 's', 1, RO},
    {"OfxPropLabel", 's', 1, RO},
    {"OfxPropShortLabel", 's', 1, RO},
    {"OfxPropLongLabel", 's', 1, RO},
    {"OfxImageEffectPropSupportedComponents", 's', 0, RO},
    {"OfxImageEffectPropTemporalClipAccess", 'i', 1, RO},
    {"OfxImageClipPropOptional", 'i', 1, RO},
    {"OfxImageClipPropFieldExtraction", 's', 1, RO},
    {"OfxImageClipPropIsMask", 'i', 1, RO},
    {"OfxImageEffectPropSupportsTiles", 'i', 1, RO},
    {"OfxImageEffectPropPixelDepth", 's', 1, RO},
    {"OfxImageEffectPropComponents", 's', 1, RO},
    {"OfxImageClipPropUnmappedPixelDepth", 's', 1, RO},
    {"OfxImageClipPropUnmappedComponents", 's', 1, RO},
    {"OfxImageEffectPropPreMultiplication", 's', 1, RO},
    {"OfxImagePropPixelAspectRatio", 'd', 1, RO},
    {"OfxImageEffectPropFrameRate", 'd', 1, RO},
    {"OfxImageEffectPropFrameRange", 'd', 2, RO},
    {"OfxImageClipPropFieldOrder", 's', 1, RO},
    {"OfxImageClipPropConnected", 'i', 1, RO},
    {"OfxImageEffectPropUnmappedFrameRange", 'd', 2, RO},
    {"OfxImageEffectPropUnmappedFrameRate", 'd', 1, RO},
    {"OfxImageClipPropContinuousSamples", 'i', 1, RO},
    {NULL, 0, 0, 0},
};

const hp_schema hs_image[] = {
    {"OfxPropType", 's', 1, RO},
    {"OfxImageEffectPropPixelDepth", 's', 1, RO},
    {"OfxImageEffectPropComponents", 's', 1, RO},
    {"OfxImageEffectPropPreMultiplication", 's', 1, RO},
    {"OfxImageEffectPropRenderScale", 'd', 2, RO},
    {"OfxImagePropPixelAspectRatio", 'd', 1, RO},
    {"OfxImagePropData", 'p', 1, RO},
    {"OfxImagePropBounds", 'i', 4, RO},
    {"OfxImagePropRegionOfDefinition", 'i', 4, RO},
    {"OfxImagePropRowBytes", 'i', 1, RO},
    {"OfxImagePropField", 's', 1, RO},
    {"OfxImagePropUniqueIdentifier", 's', 1, RO},
    {NULL, 0, 0, 0},
};

#define PARAM_PROPS                                                                                            \
    {"OfxPropType", 's', 1, RO}, {"OfxPropName", 's', 1, RO}, COMMON_LABELS, {"OfxParamPropType", 's', 1, RO}, \
        {"OfxParamPropSecret", 'i', 1, RW}, {"OfxParamPropCanUndo", 'i', 1, RW}, {"OfxParamPropHint", 's', 1, RW}, \
        {"OfxParamPropScriptName", 's', 1, RW}, {"OfxParamPropParent", 's', 1, RW},                             \
        {"OfxParamPropEnabled", 'i', 1, RW}, {"OfxParamPropDataPtr", 'p', 1, RW},                               \
        {"OfxParamPropAnimates", 'i', 1, RW}, {"OfxParamPropIsAnimating", 'i', 1, RO},                          \
        {"OfxParamPropIsAutoKeying", 'i', 1, RO}, {"OfxParamPropPersistant", 'i', 1, RW},                       \
        {"OfxParamPropEvaluateOnChange", 'i', 1, RW}, {"OfxParamPropPluginMayWrite", 'i', 1, RW},               \
        {"OfxParamPropCacheInvalidation", 's', 1, RW}

const hp_schema hs_param_double[] = {
    PARAM_PROPS,
    {"OfxParamPropDefault", 'd', 1, RW},
    {"OfxParamPropMin", 'd', 1, RW},
    {"OfxParamPropMax", 'd', 1, RW},
    {"OfxParamPropDisplayMin", 'd', 1, RW},
    {"OfxParamPropDisplayMax", 'd', 1, RW},
    {"OfxParamPropIncrement", 'd', 1, RW},
    {"OfxParamPropDigits", 'i', 1, RW},
    {"OfxParamPropDoubleType", 's', 1, RW},
    {"OfxParamPropShowTimeMarker", 'i', 1, RW},
    {NULL, 0, 0, 0},
};

const hp_schema hs_param_int[] = {
    PARAM_PROPS,
    {"OfxParamPropDefault", 'i', 1, RW},
    {"OfxParamPropMin", 'i', 1, RW},
    {"OfxParamPropMax", 'i', 1, RW},
    {"OfxParamPropDisplayMin", 'i', 1, RW},
    {"OfxParamPropDisplayMax", 'i', 1, RW},
    {NULL, 0, 0, 0},
};

const hp_schema hs_param_bool[] = {
    PARAM_PROPS,
    {"OfxParamPropDefault", 'i', 1, RW},
    {NULL, 0, 0, 0},
};

const hp_schema hs_param_choice[] = {
    PARAM_PROPS,
    {"OfxParamPropDefault", 'i', 1, RW},
    {"OfxParamPropChoiceOption", 's', 0, RW},
    {NULL, 0, 0, 0},
};

/* ---- action arguments ------------------------------------------------------ */
const hp_schema hs_describe_in_context_in[] = {{"OfxImageEffectPropContext", 's', 1, RO}, {NULL, 0, 0, 0}};

const hp_schema hs_rod_in[] = {
    {"OfxPropTime", 'd', 1, RO},
    {"OfxImageEffectPropRenderScale", 'd', 2, RO},
    {NULL, 0, 0, 0},
};
const hp_schema hs_rod_out[] = {{"OfxImageEffectPropRegionOfDefinition", 'd', 4, RW}, {NULL, 0, 0, 0}};

const hp_schema hs_roi_in[] = {
    {"OfxPropTime", 'd', 1, RO},
    {"OfxImageEffectPropRenderScale", 'd', 2, RO},
    {"OfxImageEffectPropRegionOfInterest", 'd', 4, RO},
    {NULL, 0, 0, 0},
};

/* plus OfxImageClipPropComponents_/Depth_/PAR_<clip> for connected inputs and Output */
const hp_schema hs_clip_prefs_out[] = {
    {"OfxImageEffectPropFrameRate", 'd', 1, RW},
    {"OfxImageClipPropFieldOrder", 's', 1, RW},
    {"OfxImageEffectPropPreMultiplication", 's', 1, RW},
    {"OfxImageClipPropContinuousSamples", 'i', 1, RW},
    {"OfxImageEffectFrameVarying", 'i', 1, RW},
    {NULL, 0, 0, 0},
};

const hp_schema hs_identity_in[] = {
    {"OfxPropTime", 'd', 1, RO},
    {"OfxImageEffectPropFieldToRender", 's', 1, RO},
    {"OfxImageEffectPropRenderWindow", 'i', 4, RO},
    {"OfxImageEffectPropRenderScale", 'd', 2, RO},
    {NULL, 0, 0, 0},
};
const hp_schema hs_identity_out[] = {
    {"OfxPropName", 's', 1, RW},
    {"OfxPropTime", 'd', 1, RW},
    {NULL, 0, 0, 0},
};

const hp_schema hs_render_in[] = {
    {"OfxPropTime", 'd', 1, RO},
    {"OfxImageEffectPropFieldToRender", 's', 1, RO},
    {"OfxImageEffectPropRenderWindow", 'i', 4, RO},
    {"OfxImageEffectPropRenderScale", 'd', 2, RO},
    {"OfxImageEffectPropSequentialRenderStatus", 'i', 1, RO},
    {"OfxImageEffectPropInteractiveRenderStatus", 'i', 1, RO},
    {"OfxImageEffectPropRenderQualityDraft", 'i', 1, RO},
    {NULL, 0, 0, 0},
};

/* Begin- and EndSequenceRender share their inArgs. */
const hp_schema hs_sequence_render_in[] = {
    {"OfxImageEffectPropFrameRange", 'd', 2, RO},
    {"OfxImageEffectPropFrameStep", 'd', 1, RO},
    {"OfxPropIsInteractive", 'i', 1, RO},
    {"OfxImageEffectPropRenderScale", 'd', 2, RO},
    {"OfxImageEffectPropSequentialRenderStatus", 'i', 1, RO},
    {"OfxImageEffectPropInteractiveRenderStatus", 'i', 1, RO},
    {"OfxImageEffectPropRenderQualityDraft", 'i', 1, RO},
    {NULL, 0, 0, 0},
};
