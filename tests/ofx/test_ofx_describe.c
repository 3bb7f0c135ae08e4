/*
 * The bundle as a host first sees it: its layout and exports, the plugins
 * it enumerates, and what describe / describeInContext declare — checked
 * against the library's own descriptors.
 */
#include "ew_test.h"

#include <dlfcn.h>
#include <sys/stat.h>

#include "edgewise/edgewise.h"
#include "ofx_fixtures.h"

static char err[512];

/* The plugins a bundle built against this library must offer: every
 * method the library marks as a host tool, read from the library. */
static int expected_identifiers(char ids[][64], int max) {
    int n = 0;
    for (int32_t i = 0; i < ew_method_count(NULL) && n < max; i++) {
        const char *name = NULL;
        uint32_t flags = 0;
        if (ew_method_get(NULL, i, &name, NULL, NULL, NULL) != EW_OK || ew_method_flags(NULL, name, &flags) != EW_OK)
            continue;
        if (flags & EW_METHOD_HOST)
            snprintf(ids[n++], 64, "org.edgewise.%s.%s", !strcmp(ew_method_kind(name), "denoiser") ? "denoise" : "filter",
                     name);
    }
    return n;
}

/* kind and method of a plugin identifier */
static int method_of(const char *id, char *kind, char *method) {
    if (sscanf(id, "org.edgewise.denoise.%63s", method) == 1) {
        strcpy(kind, "denoiser");
        return 1;
    }
    if (sscanf(id, "org.edgewise.filter.%63s", method) == 1) {
        strcpy(kind, "filter");
        return 1;
    }
    return 0;
}

TEST(bundle_layout_and_exports) {
    const char *dir = getenv("EW_OFX_BUNDLE");
    CHECK(dir);
    char path[1200];
    struct stat st;
    snprintf(path, sizeof path, "%s/Contents/Info.plist", dir);
    CHECK(stat(path, &st) == 0 && S_ISREG(st.st_mode));
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    const char *arch = getenv("EW_OFX_ARCH");
    char tail[128];
    snprintf(tail, sizeof tail, ".ofx.bundle/Contents/%s/Edgewise.ofx", arch ? arch : "Linux-x86-64");
    CHECK_STR_CONTAINS(b.binary, tail);
    CHECK(b.set_host != NULL);
    /* the statically linked library stays private */
    CHECK(dlsym(b.dl, "ew_denoiser_create") == NULL);
    CHECK(dlsym(b.dl, "ew_method_count") == NULL);
    CHECK(dlsym(b.dl, "ew_ofx_render") == NULL);
    hb_close(&b);
}

TEST(enumerates_one_plugin_per_user_facing_method) {
    host_reset();
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    char want[32][64]; /* more than the plugin's limit, so a surplus shows */
    int n = expected_identifiers(want, 32);
    CHECK(n >= 1);
    CHECK_EQ_INT(b.get_count(), n);
    for (int i = 0; i < n; i++) {
        OfxPlugin *p = b.get_plugin(i);
        CHECK(p);
        CHECK(!strcmp(p->pluginApi, "OfxImageEffectPluginAPI"));
        CHECK_EQ_INT(p->apiVersion, 1);
        CHECK(p->setHost && p->mainEntry);
        CHECK_EQ_INT(p->pluginVersionMajor, 1);
        int found = 0;
        for (int k = 0; k < n; k++) found += !strcmp(p->pluginIdentifier, want[k]);
        if (found != 1) FAIL_AT("unexpected plugin %s", p->pluginIdentifier);
        for (int k = 0; k < i; k++) CHECK(b.get_plugin(k)->mainEntry != p->mainEntry);
    }
    CHECK(b.get_plugin(n) == NULL);
    CHECK(b.get_plugin(-1) == NULL);
    CHECK(b.get_plugin(1 << 30) == NULL);
    /* the user-facing filters this library has are all there */
    CHECK(hb_find(&b, "org.edgewise.denoise.bgrid") >= 0);
    CHECK(hb_find(&b, "org.edgewise.filter.bilateral") < 0); /* the exact reference is not a tool */
    /* tests/gain runs these tests on a library with one method more */
    const char *extra = getenv("EW_EXPECT_PLUGIN");
    if (extra && hb_find(&b, extra) < 0) FAIL_AT("no plugin %s", extra);
    hb_close(&b);
}

TEST(describe_declares_the_effect) {
    host_reset();
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    CHECK_EQ_INT(b.set_host(&host_ofx), kOfxStatOK);
    for (int i = 0; i < b.get_count(); i++) {
        CHECK_EQ_INT(hx_load(&b, i), kOfxStatOK);
        host_effect *d = NULL;
        CHECK_EQ_INT(hx_describe(&b, i, &d), kOfxStatOK);
        OfxPropertySetHandle p = d->props;
        CHECK(hp_has_string(p, "OfxImageEffectPropSupportedContexts", "OfxImageEffectContextFilter"));
        CHECK(hp_has_string(p, "OfxImageEffectPropSupportedContexts", "OfxImageEffectContextGeneral"));
        CHECK_EQ_INT(hp_count(p, "OfxImageEffectPropSupportedPixelDepths"), 1);
        CHECK(!strcmp(hp_s(p, "OfxImageEffectPropSupportedPixelDepths", 0), "OfxBitDepthFloat"));
        CHECK_STR_CONTAINS(hp_s(p, "OfxPropLabel", 0), "Edgewise");
        CHECK(!strcmp(hp_s(p, "OfxImageEffectPluginPropGrouping", 0), "Edgewise"));
        CHECK(strlen(hp_s(p, "OfxPropPluginDescription", 0)) > 10);
        CHECK_EQ_INT(hp_i(p, "OfxImageEffectPropSupportsTiles", 0), 0);
        CHECK_EQ_INT(hp_i(p, "OfxImageEffectPluginPropHostFrameThreading", 0), 0);
        CHECK(!strcmp(hp_s(p, "OfxImageEffectPluginRenderThreadSafety", 0), "OfxImageEffectRenderInstanceSafe"));
        he_free(d);
        CHECK_EQ_INT(hx_unload(&b, i), kOfxStatOK);
    }
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
    hb_close(&b);
}

static void check_clips(const char *context) {
    host_reset();
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    int general = !strcmp(context, "OfxImageEffectContextGeneral");
    for (int i = 0; i < b.get_count(); i++) {
        char kind[16], method[64];
        CHECK(method_of(b.get_plugin(i)->pluginIdentifier, kind, method));
        CHECK_EQ_INT(hx_load(&b, i), kOfxStatOK);
        host_effect *d = NULL, *c = NULL;
        CHECK_EQ_INT(hx_describe(&b, i, &d), kOfxStatOK);
        CHECK_EQ_INT(hx_describe_in_context(&b, i, context, &c), kOfxStatOK);
        host_clip *src = he_clip(c, "Source"), *out = he_clip(c, "Output");
        CHECK(src && out);
        CHECK_EQ_INT(hp_i(src->props, "OfxImageClipPropOptional", 0), 0);
        CHECK(hp_has_string(src->props, "OfxImageEffectPropSupportedComponents", "OfxImageComponentRGBA"));
        CHECK(hp_has_string(out->props, "OfxImageEffectPropSupportedComponents", "OfxImageComponentRGBA"));
        CHECK_EQ_INT(hp_i(src->props, "OfxImageEffectPropSupportsTiles", 0), 0);
        /* one clip per library input besides the colour */
        int32_t ni = 0, expected = 2;
        for (int32_t k = 0; k < ew_method_count(kind); k++) {
            const char *nm = NULL;
            if (ew_method_get(kind, k, &nm, NULL, &ni, NULL) == EW_OK && !strcmp(nm, method)) break;
        }
        for (int32_t k = 0; k < ni; k++) {
            ew_image_info im;
            CHECK_EQ_INT(ew_method_image(kind, method, k, &im), EW_OK);
            uint32_t flags = 0;
            CHECK_EQ_INT(ew_method_image_flags(kind, method, k, &flags), EW_OK);
            if (!strcmp(im.name, "color") || (flags & EW_IMAGE_OUTPUT)) continue;
            char clip[32];
            snprintf(clip, sizeof clip, "%s", im.name);
            clip[0] = (char)(clip[0] - 'a' + 'A');
            host_clip *a = he_clip(c, clip);
            if (!a) FAIL_AT("%s: no clip %s", method, clip);
            CHECK(a);
            int optional = hp_i(a->props, "OfxImageClipPropOptional", 0);
            /* filter context: only Source is mandatory; general: what the method needs */
            CHECK_EQ_INT(optional, general ? !im.required : 1);
            CHECK(hp_has_string(a->props, "OfxImageEffectPropSupportedComponents", "OfxImageComponentAlpha"));
            expected++;
        }
        CHECK_EQ_INT(c->num_clips, expected);
        if (!strcmp(method, "bgrid")) {
            CHECK(he_clip(c, "Albedo") && he_clip(c, "Normal") && he_clip(c, "Depth"));
        }
        he_free(c);
        he_free(d);
        CHECK_EQ_INT(hx_unload(&b, i), kOfxStatOK);
    }
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
    hb_close(&b);
}

TEST(describe_in_filter_context_clips) { check_clips("OfxImageEffectContextFilter"); }
TEST(describe_in_general_context_clips) { check_clips("OfxImageEffectContextGeneral"); }

TEST(parameters_are_generated_from_the_descriptors) {
    host_reset();
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    for (int i = 0; i < b.get_count(); i++) {
        char kind[16], method[64];
        CHECK(method_of(b.get_plugin(i)->pluginIdentifier, kind, method));
        CHECK_EQ_INT(hx_load(&b, i), kOfxStatOK);
        host_effect *d = NULL, *c = NULL;
        CHECK_EQ_INT(hx_describe(&b, i, &d), kOfxStatOK);
        CHECK_EQ_INT(hx_describe_in_context(&b, i, "OfxImageEffectContextFilter", &c), kOfxStatOK);
        int32_t np = -1;
        for (int32_t k = 0; k < ew_method_count(kind); k++) {
            const char *nm = NULL;
            if (ew_method_get(kind, k, &nm, NULL, NULL, &np) == EW_OK && !strcmp(nm, method)) break;
        }
        CHECK(np > 0);
        CHECK_EQ_INT(c->num_params, np);
        for (int32_t k = 0; k < np; k++) {
            ew_param_info info;
            CHECK_EQ_INT(ew_method_param(kind, method, k, &info), EW_OK);
            host_param *p = he_param(c, info.name);
            if (!p) FAIL_AT("%s: no parameter %s", method, info.name);
            CHECK(p);
            OfxPropertySetHandle q = p->props;
            if (!strcmp(info.name, "samples")) {
                /* what 0 means in a host: its sample count for the clip, else the noise */
                CHECK_STR_CONTAINS(hp_s(q, "OfxParamPropHint", 0), "0: the Source clip's sample count");
                CHECK_STR_CONTAINS(hp_s(q, "OfxParamPropHint", 0), "org.edgewise.OfxImageClipPropRenderSamples");
                CHECK_STR_CONTAINS(hp_s(q, "OfxParamPropHint", 0), "noise");
            } else {
                CHECK(!strcmp(hp_s(q, "OfxParamPropHint", 0), info.hint));
            }
            CHECK(!strcmp(hp_s(q, "OfxParamPropScriptName", 0), info.name));
            /* the label is the name in words: "spatial_rate" -> "Spatial rate" */
            const char *label = hp_s(q, "OfxPropLabel", 0);
            CHECK(strlen(label) == strlen(info.name) && label[0] >= 'A' && label[0] <= 'Z');
            CHECK(!strchr(label, '_'));
            CHECK_EQ_INT(hp_i(q, "OfxParamPropAnimates", 0), 1);
            if (info.type == EW_PARAM_FLOAT) {
                CHECK(!strcmp(p->type, "OfxParamTypeDouble"));
                CHECK(hp_d(q, "OfxParamPropDefault", 0) == (double)info.default_value);
                CHECK(hp_d(q, "OfxParamPropMin", 0) == (double)info.min_value);
                CHECK(hp_d(q, "OfxParamPropMax", 0) == (double)info.max_value);
                double dmin = hp_d(q, "OfxParamPropDisplayMin", 0), dmax = hp_d(q, "OfxParamPropDisplayMax", 0);
                CHECK(dmin >= info.min_value && dmax <= info.max_value && dmin < dmax);
                CHECK(hp_d(q, "OfxParamPropIncrement", 0) > 0.0);
            } else if (ew_method_param_num_choices(kind, method, k) > 0) { /* an enum: its names */
                CHECK(!strcmp(p->type, "OfxParamTypeChoice"));
                CHECK_EQ_INT(hp_i(q, "OfxParamPropDefault", 0), (int)info.default_value);
                int32_t nc = ew_method_param_num_choices(kind, method, k);
                CHECK_EQ_INT(hp_count(q, "OfxParamPropChoiceOption"), nc);
                for (int32_t ci = 0; ci < nc; ci++)
                    CHECK(!strcmp(hp_s(q, "OfxParamPropChoiceOption", ci), ew_method_param_choice(kind, method, k, ci)));
            } else if (info.type == EW_PARAM_INT) {
                CHECK(!strcmp(p->type, "OfxParamTypeInteger"));
                CHECK_EQ_INT(hp_i(q, "OfxParamPropDefault", 0), (int)info.default_value);
                CHECK_EQ_INT(hp_i(q, "OfxParamPropMin", 0), (int)info.min_value);
                CHECK_EQ_INT(hp_i(q, "OfxParamPropMax", 0), (int)info.max_value);
                CHECK(hp_i(q, "OfxParamPropDisplayMax", 0) <= (int)info.max_value);
            } else {
                CHECK(!strcmp(p->type, "OfxParamTypeBoolean"));
                CHECK_EQ_INT(hp_i(q, "OfxParamPropDefault", 0), info.default_value != 0.0f);
            }
        }
        he_free(c);
        he_free(d);
        CHECK_EQ_INT(hx_unload(&b, i), kOfxStatOK);
    }
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
    hb_close(&b);
}

TEST(load_fetches_suites_and_instances_get_handles) {
    fx_plugin fx;
    host_reset();
    if (fx_open(&fx, "org.edgewise.denoise.bgrid", "OfxImageEffectContextGeneral", err, sizeof err)) {
        fx_close(&fx);
        FAIL_AT("%s", err);
        return;
    }
    /* the instance keeps its private data on the instance's properties */
    CHECK(hp_p(fx.inst->props, "OfxPropInstanceData", 0) != NULL);
    fx_close(&fx);
    CHECK_EQ_INT(host_st.memory_out, 0); /* instance data came from, and went back to, the memory suite */
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
}

/* plugin/README.md names every plugin of the bundle by its identifier. */
TEST(readme_lists_every_plugin) {
    const char *dir = getenv("EW_SAMPLE_DIR");
    if (!dir) SKIP("EW_SAMPLE_DIR not set: no source tree to find plugin/README.md in");
    char path[1024];
    snprintf(path, sizeof path, "%s/../plugin/README.md", dir);
    FILE *f = fopen(path, "rb");
    if (!f) FAIL_AT("cannot open %s", path);
    CHECK(f);
    static char text[1 << 16];
    size_t len = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[len] = '\0';
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    for (int i = 0; i < b.get_count(); i++) {
        char want[96];
        snprintf(want, sizeof want, "`%s`", b.get_plugin(i)->pluginIdentifier);
        if (!strstr(text, want)) FAIL_AT("plugin/README.md does not list %s", want);
    }
    hb_close(&b);
}

TEST(registered_test_count) {
    /* every TEST above has its own CTest entry (tests/ofx/CMakeLists.txt) */
    CHECK_EQ_INT(ew_ntests_, OFX_TEST_COUNT);
}
