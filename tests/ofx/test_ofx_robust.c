/*
 * Everything but the happy render: regions, clip preferences, identity,
 * cancelling, inputs the plugin must refuse, hosts that misbehave, and
 * malformed calls — each answered with the proper OFX status, with every
 * image and buffer given back.
 */
#include "ew_test.h"

#include <stdlib.h>

#include "edgewise/edgewise.h"
#include "ofx_fixtures.h"

static char err[512];

#define FILTER "OfxImageEffectContextFilter"
#define GENERAL "OfxImageEffectContextGeneral"
#define BGRID "org.edgewise.denoise.bgrid"
#define PYRAMID "org.edgewise.filter.pyramid"
#define DOF "org.edgewise.filter.dof"
#define ATROUS "org.edgewise.filter.atrous"

/* A loaded instance with a small real image on Source (origin -7, 13). */
static int open_with_image(fx_plugin *fx, const char *id, const char *context, fx_sample *crop) {
    host_reset();
    const fx_sample *s = fx_cornell(err, sizeof err);
    if (!s) return 1;
    fx_crop(s, 101, 57, 37, 29, crop);
    if (fx_open(fx, id, context, err, sizeof err)) return 1;
    hx_clip_set_image(he_clip(fx->inst, "Source"), crop->rgba, crop->w, crop->h, 4, -7, 13, 0);
    OfxRectI whole = {-7, 13, 30, 42};
    hx_output_prepare(he_clip(fx->inst, "Output"), whole, 4, 0);
    return 0;
}

static const OfxRectI whole = {-7, 13, 30, 42};

#define OPEN(fx, id, context, crop)                                                                           \
    do {                                                                                                       \
        if (open_with_image(&(fx), id, context, &(crop))) {                                                   \
            fx_close(&(fx));                                                                                   \
            fx_free(&(crop));                                                                                  \
            FAIL_AT("%s", err);                                                                               \
            return;                                                                                            \
        }                                                                                                      \
    } while (0)

#define RELEASED_ALL()                                                                                         \
    do {                                                                                                       \
        CHECK_EQ_INT(host_st.images_out, 0);                                                                   \
        CHECK_EQ_INT(host_st.image_memory_out, 0);                                                             \
    } while (0)

TEST(region_of_definition_interest_and_clip_preferences) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, BGRID, FILTER, crop);
    hx_clip_set_image(he_clip(fx.inst, "Albedo"), crop.albedo, crop.w, crop.h, 3, -7, 13, 0);
    hx_clip_set_image(he_clip(fx.inst, "Depth"), crop.ddepth, crop.w, crop.h, 1, -7, 13, 0);

    double rod[4];
    CHECK_EQ_INT(hx_rod(&fx.bundle, fx.index, fx.inst, 1.0, rod), kOfxStatOK);
    CHECK(rod[0] == -7 && rod[1] == 13 && rod[2] == 30 && rod[3] == 42);

    /* any part of the output needs all of every input */
    double region[4] = {0, 20, 5, 25};
    OfxPropertySetHandle roi = NULL;
    CHECK_EQ_INT(hx_roi(&fx.bundle, fx.index, fx.inst, 1.0, region, &roi), kOfxStatOK);
    const char *names[] = {"OfxImageClipPropRoI_Source", "OfxImageClipPropRoI_Albedo"};
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < 4; i++)
            if (hp_d(roi, names[k], i) != rod[i]) FAIL_AT("%s[%d] = %g", names[k], i, hp_d(roi, names[k], i));
    hp_free(roi);

    OfxPropertySetHandle prefs = NULL;
    CHECK_EQ_INT(hx_clip_prefs(&fx.bundle, fx.index, fx.inst, &prefs), kOfxStatOK);
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropComponents_Output", 0), "OfxImageComponentRGBA"));
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropComponents_Source", 0), "OfxImageComponentRGBA"));
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropDepth_Output", 0), "OfxBitDepthFloat"));
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropDepth_Source", 0), "OfxBitDepthFloat"));
    /* a feature clip keeps its components (a one-channel depth stays one channel) */
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropComponents_Albedo", 0), "OfxImageComponentRGB"));
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropDepth_Albedo", 0), "OfxBitDepthFloat"));
    CHECK(!strcmp(hp_s(prefs, "OfxImageClipPropComponents_Depth", 0), "OfxImageComponentAlpha"));
    CHECK_EQ_INT(hp_count(prefs, "OfxImageClipPropDepth_Normal"), -1); /* unconnected: not asked */
    hp_free(prefs);
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
    fx_close(&fx);
    fx_free(&crop);
}

/* isIdentity claims identity exactly when the library's output is the input. */
static void identity_case(const char *id, const char *method, fx_param *params, int n, int expect_identity) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, id, FILTER, crop);
    for (int i = 0; i < n; i++) CHECK(fx_set_param(&fx, params[i].name, params[i].value) == 0);
    char clip[64];
    double t = -1;
    OfxStatus st = hx_is_identity(&fx.bundle, fx.index, fx.inst, 3.0, whole, clip, sizeof clip, &t);
    if (expect_identity) {
        CHECK_EQ_INT(st, kOfxStatOK);
        CHECK(!strcmp(clip, "Source"));
        CHECK(t == 3.0);
        size_t m = (size_t)crop.w * (size_t)crop.h;
        float *out = (float *)malloc(m * 4 * sizeof(float));
        if (!out) abort();
        int rc = fx_reference("filter", method, 3, crop.w, crop.h, crop.rgba, 4, 4, NULL, 0, params, n, out, err,
                              sizeof err);
        char msg[256] = "";
        long bad = rc ? -1 : fx_compare(out, crop.rgba, m * 4, 4, crop.w, msg, sizeof msg);
        free(out);
        if (rc) FAIL_AT("%s", err);
        if (bad) FAIL_AT("claimed identity but the library changes %ld values: %s", bad, msg);
    } else {
        CHECK_EQ_INT(st, kOfxStatReplyDefault);
    }
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
    fx_close(&fx);
    fx_free(&crop);
}

TEST(is_identity) {
    fx_param none[1] = {{"spatial_rate", 8.0}};
    identity_case(BGRID, "bgrid", none, 1, 0);
    if (fx_plugin_exists(PYRAMID)) {
        /* weights 0: the trained table is not built in yet (see test_ofx_render.c) */
        fx_param r0[3] = {{"radius", 0}, {"sigma_range", 0.05}, {"weights", 0}};
        identity_case(PYRAMID, "pyramid", r0, 3, 1);
        fx_param r2[1] = {{"radius", 2}};
        identity_case(PYRAMID, "pyramid", r2, 1, 0);
    }
    if (fx_plugin_exists(ATROUS)) {
        fx_param a0[2] = {{"radius", 0}, {"iterations", 0}};
        identity_case(ATROUS, "atrous", a0, 2, 1);
        fx_param a1[2] = {{"radius", 0}, {"iterations", 1}};
        identity_case(ATROUS, "atrous", a1, 2, 0);
    }
}

static void abort_case(int abort_after, int in_spawned) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, BGRID, FILTER, crop);
    host_cfg.abort_after = abort_after;
    host_cfg.abort_in_spawned = in_spawned;
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, whole), kOfxStatFailed);
    CHECK(host_st.abort_calls > 0);
    CHECK_EQ_INT(host_st.persistent_messages, 0); /* a cancel is not an error to show */
    RELEASED_ALL();
    /* and the instance renders again once the host stops aborting */
    host_cfg.abort_after = -1;
    host_cfg.abort_in_spawned = 0;
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, whole), kOfxStatOK);
    RELEASED_ALL();
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
    fx_close(&fx);
    fx_free(&crop);
}

TEST(abort_before_filtering) { abort_case(0, 0); }
TEST(abort_inside_the_library) { abort_case(2, 0); }
TEST(abort_between_output_bands) {
    /* only the host's own threads see abort: that is the band copy */
    abort_case(-1, 1);
    CHECK(host_st.mt_calls > 0);
}

TEST(missing_source_image_renders_black) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, BGRID, FILTER, crop);
    he_clip(fx.inst, "Source")->fetch_status = kOfxStatFailed;
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, whole), kOfxStatOK);
    size_t m = (size_t)crop.w * (size_t)crop.h * 4;
    float *got = (float *)malloc(m * sizeof(float));
    if (!got) abort();
    hx_output_read(he_clip(fx.inst, "Output"), whole, got);
    long nonzero = 0;
    for (size_t i = 0; i < m; i++) nonzero += got[i] != 0.0f;
    free(got);
    CHECK_EQ_INT(nonzero, 0);
    RELEASED_ALL();
    fx_close(&fx);
    fx_free(&crop);
}

static void failing_render(const char *id, const char *context, void (*setup)(fx_plugin *, fx_sample *),
                           OfxStatus want, const char *message) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, id, context, crop);
    setup(&fx, &crop);
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, whole), want);
    RELEASED_ALL();
    if (message) CHECK_STR_CONTAINS(host_st.last_message, message);
    fx_close(&fx);
    fx_free(&crop);
}

static void source_out_of_memory(fx_plugin *fx, fx_sample *c) {
    (void)c;
    he_clip(fx->inst, "Source")->fetch_status = kOfxStatErrMemory;
}
static void source_in_bytes(fx_plugin *fx, fx_sample *c) {
    (void)c;
    snprintf(he_clip(fx->inst, "Source")->depth, 32, "OfxBitDepthByte");
}
/* The OpenFX SDK's hostDemo: its images keep 8-bit RGBA pixels (rows of
 * width x 4 bytes) but carry the depth clip preferences chose, float. */
static void source_rows_of_bytes(fx_plugin *fx, fx_sample *c) {
    host_clip *s = he_clip(fx->inst, "Source");
    s->row_bytes = c->w * 4;
}
static void depth_in_bytes(fx_plugin *fx, fx_sample *c) {
    host_clip *d = he_clip(fx->inst, "Depth");
    hx_clip_set_image(d, c->ddepth, c->w, c->h, 1, -7, 13, 0);
    snprintf(d->depth, 32, "OfxBitDepthByte");
}
static void normal_as_alpha(fx_plugin *fx, fx_sample *c) {
    hx_clip_set_image(he_clip(fx->inst, "Normal"), c->ddepth, c->w, c->h, 1, -7, 13, 0);
}
static void no_image_memory(fx_plugin *fx, fx_sample *c) {
    (void)fx;
    (void)c;
    host_cfg.image_memory_fail = 1;
}
static void no_output_image(fx_plugin *fx, fx_sample *c) {
    (void)c;
    host_clip *out = he_clip(fx->inst, "Output");
    free(out->buf);
    out->buf = NULL;
}
static void albedo_fails_too(fx_plugin *fx, fx_sample *c) {
    hx_clip_set_image(he_clip(fx->inst, "Albedo"), c->albedo, c->w, c->h, 3, -7, 13, 0);
    he_clip(fx->inst, "Albedo")->fetch_status = kOfxStatErrMemory;
}
static void dof_without_depth(fx_plugin *fx, fx_sample *c) {
    (void)fx;
    (void)c;
}

TEST(source_fetch_out_of_memory) { failing_render(BGRID, FILTER, source_out_of_memory, kOfxStatErrMemory, NULL); }
/* An image the plugin cannot read fails the render with a message that
 * names the clip and what is wrong: a failed node without one leaves the
 * user nothing to go on. */
TEST(unsupported_pixel_depth) {
    failing_render(BGRID, FILTER, source_in_bytes, kOfxStatErrImageFormat, "Source image is OfxBitDepthByte");
}
TEST(feature_clip_in_unsupported_depth) {
    failing_render(BGRID, FILTER, depth_in_bytes, kOfxStatErrImageFormat, "Depth image is OfxBitDepthByte");
}
TEST(image_rows_too_short_for_its_format) {
    failing_render(BGRID, FILTER, source_rows_of_bytes, kOfxStatErrImageFormat, "Source image has rows of 148 bytes");
}
TEST(feature_clip_with_too_few_channels) {
    failing_render(BGRID, FILTER, normal_as_alpha, kOfxStatErrImageFormat, "Normal");
}
TEST(image_memory_exhausted) { failing_render(BGRID, FILTER, no_image_memory, kOfxStatErrMemory, NULL); }
TEST(output_image_missing) { failing_render(BGRID, FILTER, no_output_image, kOfxStatFailed, NULL); }
TEST(feature_fetch_out_of_memory) { failing_render(BGRID, FILTER, albedo_fails_too, kOfxStatErrMemory, NULL); }
TEST(required_clip_unconnected) {
    NEED(DOF);
    failing_render(DOF, FILTER, dof_without_depth, kOfxStatFailed, "Depth");
    CHECK(host_st.persistent_messages > 0);
}

TEST(feature_clip_with_other_bounds) {
    /* an albedo image larger than the source: the plugin takes the part
     * over the source, exactly as if it had been cropped */
    fx_plugin fx;
    fx_sample crop, big;
    OPEN(fx, BGRID, FILTER, crop);
    const fx_sample *s = fx_cornell(err, sizeof err);
    CHECK(s);
    fx_crop(s, 101 - 3, 57 - 4, 37 + 5, 29 + 6, &big); /* 3 more left, 4 more above */
    /* bottom-left of big: x = -7 - 3, y = 13 - (6 - 4) */
    hx_clip_set_image(he_clip(fx.inst, "Albedo"), big.albedo, big.w, big.h, 3, -10, 11, 0);
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, whole), kOfxStatOK);
    size_t m = (size_t)crop.w * (size_t)crop.h;
    float *got = (float *)malloc(m * 4 * sizeof(float)), *want = (float *)malloc(m * 4 * sizeof(float));
    if (!got || !want) abort();
    hx_output_read(he_clip(fx.inst, "Output"), whole, got);
    fx_image albedo = {"albedo", crop.albedo, 3};
    int rc = fx_reference("denoiser", "bgrid", 3, crop.w, crop.h, crop.rgba, 4, 3, &albedo, 1, NULL, 0, want, err,
                          sizeof err);
    char msg[256] = "";
    long bad = rc ? -1 : fx_compare(got, want, m * 4, 4, crop.w, msg, sizeof msg);
    free(got);
    free(want);
    fx_free(&big);
    if (rc) FAIL_AT("%s", err);
    if (bad) FAIL_AT("%ld values differ: %s", bad, msg);
    RELEASED_ALL();
    fx_close(&fx);
    fx_free(&crop);
}

TEST(malformed_calls_get_an_ofx_status) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, BGRID, FILTER, crop);
    const host_bundle *b = &fx.bundle;
    int i = fx.index;
    host_effect *inst = fx.inst;
    OfxPropertySetHandle in = hp_new("render inArgs", hs_render_in);
    hp_set_d(in, "OfxPropTime", 0, 1.0);

    CHECK_EQ_INT(hx_action(b, i, NULL, inst, in, NULL), kOfxStatErrValue);
    CHECK_EQ_INT(hx_action(b, i, "OfxActionNoSuchThing", inst, in, NULL), kOfxStatReplyDefault);
    CHECK_EQ_INT(hx_action(b, i, "", NULL, NULL, NULL), kOfxStatReplyDefault);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionBeginSequenceRender", NULL, NULL, NULL), kOfxStatReplyDefault);
    const char *need_handle[] = {"OfxActionDescribe",
                                 "OfxImageEffectActionDescribeInContext",
                                 "OfxActionCreateInstance",
                                 "OfxActionDestroyInstance",
                                 "OfxImageEffectActionGetRegionOfDefinition",
                                 "OfxImageEffectActionGetRegionsOfInterest",
                                 "OfxImageEffectActionGetClipPreferences",
                                 "OfxImageEffectActionIsIdentity",
                                 "OfxImageEffectActionRender",
                                 /* they drop the instance's kept op */
                                 "OfxActionPurgeCaches",
                                 "OfxImageEffectActionEndSequenceRender"};
    for (int k = 0; k < (int)(sizeof need_handle / sizeof need_handle[0]); k++) {
        OfxStatus st = hx_action(b, i, need_handle[k], NULL, in, NULL);
        if (st != kOfxStatErrBadHandle) FAIL_AT("%s with a NULL handle: %d", need_handle[k], st);
    }
    /* NULL argument sets */
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionRender", inst, NULL, NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionIsIdentity", inst, NULL, NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionGetRegionOfDefinition", inst, in, NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionGetRegionOfDefinition", inst, NULL, in), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionGetRegionsOfInterest", inst, in, NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionGetClipPreferences", inst, NULL, NULL), kOfxStatErrBadHandle);
    host_effect *c2 = NULL;
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionDescribeInContext", fx.ctx, NULL, NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_describe_in_context(b, i, "OfxImageEffectContextRetimer", &c2), kOfxStatErrMissingHostFeature);
    he_free(c2);

    /* handles that are not this plugin's instance */
    CHECK_EQ_INT(hx_render(b, i, fx.desc, 1.0, whole), kOfxStatErrBadHandle); /* a descriptor */
    CHECK_EQ_INT(hx_purge_caches(b, i, fx.desc), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxImageEffectActionRender", he_clip(inst, "Source"), in, NULL),
                 kOfxStatErrBadHandle); /* a clip posing as an effect */
    int other = (i + 1) % b->get_count();
    if (other != i) {
        CHECK_EQ_INT(hx_load(b, other), kOfxStatOK);
        CHECK_EQ_INT(hx_render(b, other, inst, 1.0, whole), kOfxStatErrBadHandle);
        CHECK_EQ_INT(hx_unload(b, other), kOfxStatOK);
    }

    /* bad render arguments */
    OfxRectI inverted = {10, 20, 5, 25};
    CHECK_EQ_INT(hx_render(b, i, inst, 1.0, inverted), kOfxStatErrValue);
    OfxPropertySetHandle bare = hp_new("render inArgs without a window", NULL);
    hp_set_d(bare, "OfxPropTime", 0, 1.0);
    CHECK(hx_action(b, i, "OfxImageEffectActionRender", inst, bare, NULL) != kOfxStatOK);
    hp_free(bare);
    OfxRectI empty = {3, 20, 3, 25};
    CHECK_EQ_INT(hx_render(b, i, inst, 1.0, empty), kOfxStatOK);
    OfxRectI far = {1000, 1000, 1010, 1010}; /* outside the output image: nothing to write */
    CHECK_EQ_INT(hx_render(b, i, inst, 1.0, far), kOfxStatOK);

    /* instance life cycle out of order */
    CHECK_EQ_INT(hx_action(b, i, "OfxActionCreateInstance", inst, NULL, NULL), kOfxStatErrExists);
    CHECK_EQ_INT(hx_action(b, i, "OfxActionDestroyInstance", inst, NULL, NULL), kOfxStatOK);
    CHECK_EQ_INT(hx_action(b, i, "OfxActionDestroyInstance", inst, NULL, NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_render(b, i, inst, 1.0, whole), kOfxStatErrBadHandle);
    CHECK_EQ_INT(hx_action(b, i, "OfxActionCreateInstance", inst, NULL, NULL), kOfxStatOK);
    CHECK_EQ_INT(hx_render(b, i, inst, 1.0, whole), kOfxStatOK);
    hp_free(in);
    RELEASED_ALL();
    fx_close(&fx);
    fx_free(&crop);
}

/* A host that gives the render's arguments with the wrong property types
 * (a string time, doubles for the integer window, too few values, a string
 * scale, a pointer field): the plugin answers with a status (an error where
 * it cannot go on), leaves no image fetched, and renders normally after. */
TEST(wrong_property_types_get_an_ofx_status) {
    fx_plugin fx;
    fx_sample crop;
    OPEN(fx, BGRID, FILTER, crop);
    const host_bundle *b = &fx.bundle;
    int i = fx.index;
    host_effect *inst = fx.inst;
    for (int k = 0; k < 5; k++) {
        OfxPropertySetHandle in = hp_new("render inArgs (malformed)", NULL);
        if (k == 0) hp_set_s(in, "OfxPropTime", 0, "one");
        else hp_set_d(in, "OfxPropTime", 0, 1.0);
        if (k == 1) { /* the window as doubles */
            hp_set_d(in, "OfxImageEffectPropRenderWindow", 0, whole.x1);
            hp_set_d(in, "OfxImageEffectPropRenderWindow", 1, whole.y1);
            hp_set_d(in, "OfxImageEffectPropRenderWindow", 2, whole.x2);
            hp_set_d(in, "OfxImageEffectPropRenderWindow", 3, whole.y2);
        } else if (k == 2) { /* two of its four values */
            hp_set_i(in, "OfxImageEffectPropRenderWindow", 0, whole.x1);
            hp_set_i(in, "OfxImageEffectPropRenderWindow", 1, whole.y1);
        } else {
            hp_set_i(in, "OfxImageEffectPropRenderWindow", 0, whole.x1);
            hp_set_i(in, "OfxImageEffectPropRenderWindow", 1, whole.y1);
            hp_set_i(in, "OfxImageEffectPropRenderWindow", 2, whole.x2);
            hp_set_i(in, "OfxImageEffectPropRenderWindow", 3, whole.y2);
        }
        if (k == 3) hp_set_s(in, "OfxImageEffectPropRenderScale", 0, "full");
        if (k == 4) hp_set_p(in, "OfxImageEffectPropFieldToRender", 0, inst);
        OfxStatus st = hx_action(b, i, "OfxImageEffectActionRender", inst, in, NULL);
        hp_free(in);
        /* time and window are needed; a render scale or field it cannot
         * read may count as absent (scale 1, both fields) */
        if (k < 3 && st == kOfxStatOK) FAIL_AT("malformed render arguments %d rendered (status OK)", k);
        if (k >= 3 && st != kOfxStatOK && st != kOfxStatErrValue && st != kOfxStatErrBadHandle)
            FAIL_AT("malformed render arguments %d: status %d", k, st);
        RELEASED_ALL();
    }
    CHECK_EQ_INT(hx_render(b, i, inst, 1.0, whole), kOfxStatOK); /* and then as usual */
    RELEASED_ALL();
    fx_close(&fx);
    fx_free(&crop);
}

TEST(load_and_unload_out_of_order) {
    host_reset();
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    OfxPlugin *p = b.get_plugin(0);
    CHECK(p);
    host_effect *d = he_new(HE_DESCRIPTOR, 0);
    /* before any load */
    CHECK_EQ_INT(hx_action(&b, 0, "OfxActionDescribe", d, NULL, NULL), kOfxStatFailed);
    CHECK_EQ_INT(hx_unload(&b, 0), kOfxStatFailed);
    /* no host at all, or one without the property suite */
    p->setHost(NULL);
    CHECK_EQ_INT(hx_action(&b, 0, "OfxActionLoad", NULL, NULL, NULL), kOfxStatErrMissingHostFeature);
    host_cfg.offer_property = 0;
    CHECK_EQ_INT(hx_load(&b, 0), kOfxStatErrMissingHostFeature);
    host_cfg.offer_property = 1;
    host_cfg.offer_parameter = 0;
    CHECK_EQ_INT(hx_load(&b, 0), kOfxStatErrMissingHostFeature);
    /* the optional suites are optional */
    host_reset();
    host_cfg.offer_memory = host_cfg.offer_multithread = 0;
    host_cfg.offer_message_v1 = host_cfg.offer_message_v2 = 0;
    CHECK_EQ_INT(hx_load(&b, 0), kOfxStatOK);
    CHECK_EQ_INT(hx_action(&b, 0, "OfxActionDescribe", d, NULL, NULL), kOfxStatOK);
    CHECK_EQ_INT(hx_unload(&b, 0), kOfxStatOK);
    CHECK_EQ_INT(hx_unload(&b, 0), kOfxStatFailed);
    /* OfxSetHost (1.5) as the bootstrap instead of setHost */
    CHECK(b.set_host);
    CHECK_EQ_INT(b.set_host(NULL), kOfxStatErrBadHandle);
    CHECK_EQ_INT(b.set_host(&host_ofx), kOfxStatOK);
    CHECK_EQ_INT(hx_action(&b, 0, "OfxActionLoad", NULL, NULL, NULL), kOfxStatOK);
    /* every plugin loads; one unload each */
    for (int i = 1; i < b.get_count(); i++) CHECK_EQ_INT(hx_load(&b, i), kOfxStatOK);
    for (int i = 0; i < b.get_count(); i++) CHECK_EQ_INT(hx_unload(&b, i), kOfxStatOK);
    he_free(d);
    hb_close(&b);
}

TEST(registered_test_count) { CHECK_EQ_INT(ew_ntests_, OFX_TEST_COUNT); }
