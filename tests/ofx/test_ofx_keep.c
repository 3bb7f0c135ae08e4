/*
 * An instance keeps its device and op between renders (plugin/ofx_keep.c):
 * every render on one instance must equal what a new op gives for that
 * frame alone, bit for bit — frames with other pixels and sizes, feature
 * clips disconnected (the op must not read the old ones) and connected
 * again, the denoiser's fallback and back, other thread counts, purges,
 * sequence ends and aborts in between. The reference is the library run
 * with a new op on the same inputs, which is what the plugin did before
 * (test_ofx_render.c checks a fresh instance equals it).
 *
 * A disconnected feature clip's pixels are freed by the host here, and
 * they are large enough for the allocator to unmap them: an op that still
 * read them would crash, not just differ.
 */
#include "ew_test.h"

#include <stdlib.h>

#include "edgewise/edgewise.h"
#include "ofx_fixtures.h"

static char err[512];

#define FILTER "OfxImageEffectContextFilter"
#define GENERAL "OfxImageEffectContextGeneral"
#define BGRID "org.edgewise.denoise.bgrid"
#define KPCN "org.edgewise.denoise.kpcn"
#define AUTO "org.edgewise.denoise.auto"

static const char *const feature_clips[3] = {"Albedo", "Normal", "Depth"};

/* Frames: crops of the Cornell render at other places (other pixels). */
static int frame(fx_sample *f, int x0, int y0, int w, int h) {
    const fx_sample *s = fx_cornell(err, sizeof err);
    if (!s) return 1;
    fx_crop(s, x0, y0, w, h, f);
    return 0;
}

/* Give the instance frame f: Source, and the features if `features`, else
 * those clips disconnected and their pixels freed. */
static void give(fx_plugin *fx, const fx_sample *f, int features) {
    hx_clip_set_image(he_clip(fx->inst, "Source"), f->rgba, f->w, f->h, 4, 0, 0, 0);
    const float *data[3] = {f->albedo, f->normal, f->ddepth};
    const int comps[3] = {3, 3, 1};
    for (int i = 0; i < 3; i++) {
        host_clip *c = he_clip(fx->inst, feature_clips[i]);
        if (!c) continue;
        if (features) {
            hx_clip_set_image(c, data[i], f->w, f->h, comps[i], 0, 0, 0);
        } else {
            free(c->buf);
            c->buf = NULL;
            c->data = NULL;
            hx_clip_connect(c, 0);
        }
    }
}

/* The library with a new op on frame f: `method` with the parameters and,
 * if `features`, the features. out: w*h*4. */
static int reference(const char *method, const fx_sample *f, int features, const fx_param *params, int num_params,
                     float *out) {
    fx_image aux[3] = {{"albedo", f->albedo, 3}, {"normal", f->normal, 3}, {"depth", f->ddepth, 1}};
    int threads = host_cfg.offer_multithread ? (int)host_cfg.num_cpus : 0;
    return fx_reference("denoiser", method, threads, f->w, f->h, f->rgba, 4, 3, aux, features ? 3 : 0, params,
                        num_params, out, err, sizeof err);
}

/* Render frame f (already given) at `time` and compare with the reference
 * of `method` (the node's, or "bgrid" for the fallback, without
 * parameters). 0 if equal. */
static int render_equals(fx_plugin *fx, const fx_sample *f, double time, const char *method, int features,
                         const fx_param *params, int num_params, const char *what) {
    size_t n = (size_t)f->w * (size_t)f->h * 4;
    float *got = (float *)malloc(n * sizeof(float)), *want = (float *)malloc(n * sizeof(float));
    if (!got || !want) abort();
    int rc = 1;
    OfxRectI whole = {0, 0, f->w, f->h};
    host_clip *out = he_clip(fx->inst, "Output");
    hx_output_prepare(out, whole, 4, 0);
    OfxStatus st = hx_render(&fx->bundle, fx->index, fx->inst, time, whole);
    if (st != kOfxStatOK) {
        FAIL_AT("%s: render status %d (%s)", what, st, host_st.last_message);
        goto done;
    }
    if (reference(method, f, features, params, num_params, want)) {
        FAIL_AT("%s: %s", what, err);
        goto done;
    }
    hx_output_read(out, whole, got);
    char msg[256] = "";
    long bad = fx_compare(got, want, n, 4, f->w, msg, sizeof msg);
    if (bad) {
        FAIL_AT("%s: %ld values differ from a new op's; first %s", what, bad, msg);
        goto done;
    }
    if (host_st.images_out || host_st.image_memory_out) {
        FAIL_AT("%s: %d images, %d image memory blocks not given back", what, host_st.images_out,
                host_st.image_memory_out);
        goto done;
    }
    if (host_st.violations) {
        FAIL_AT("%s: %d host violations, last: %s", what, host_st.violations, host_st.last_violation);
        goto done;
    }
    rc = 0;
done:
    free(got);
    free(want);
    return rc;
}

/* Whether two methods' references for f (with/without features) differ:
 * the test that relies on it means nothing otherwise. */
static int references_differ(const char *m1, int features1, const fx_param *p1, int n1, const char *m2, int features2,
                             const fx_param *p2, int n2, const fx_sample *f) {
    size_t n = (size_t)f->w * (size_t)f->h * 4;
    float *a = (float *)malloc(n * sizeof(float)), *b = (float *)malloc(n * sizeof(float));
    if (!a || !b) abort();
    int differ = !reference(m1, f, features1, p1, n1, a) && !reference(m2, f, features2, p2, n2, b) &&
                 memcmp(a, b, n * sizeof(float)) != 0;
    free(a);
    free(b);
    return differ;
}

#define OPEN(fx, id, context)                                                                                  \
    do {                                                                                                       \
        if (fx_open(&(fx), id, context, err, sizeof err)) {                                                   \
            fx_close(&(fx));                                                                                   \
            FAIL_AT("%s", err);                                                                               \
            goto done;                                                                                         \
        }                                                                                                      \
    } while (0)

#define SET(fx, params, n)                                                                                     \
    do {                                                                                                       \
        for (int i_ = 0; i_ < (n); i_++)                                                                       \
            if (fx_set_param(&(fx), (params)[i_].name, (params)[i_].value)) {                                  \
                FAIL_AT("no parameter %s", (params)[i_].name);                                                 \
                goto done;                                                                                     \
            }                                                                                                  \
    } while (0)

#define EQUALS(...)                                                                                            \
    do {                                                                                                       \
        if (render_equals(__VA_ARGS__)) goto done;                                                             \
    } while (0)

static const fx_param bgrid_p1[3] = {{"spatial_rate", 6.0}, {"range_rate", 10.0}, {"color_weight", 0.5}};
static const fx_param bgrid_p2[3] = {{"spatial_rate", 10.0}, {"range_rate", 6.0}, {"color_weight", 0.25}};
static const fx_param kpcn_small[1] = {{"model", 1}};

/* Frames with other pixels, other parameters and another size, one after
 * the other on one instance. */
TEST(bgrid_frames_on_one_instance) {
    fx_plugin fx;
    fx_sample a, b, c;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128) && !frame(&c, 30, 40, 96, 112));
    OPEN(fx, BGRID, GENERAL);
    SET(fx, bgrid_p1, 3);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "bgrid", 1, bgrid_p1, 3, "frame a");
    give(&fx, &b, 1);
    EQUALS(&fx, &b, 2.0, "bgrid", 1, bgrid_p1, 3, "frame b");
    SET(fx, bgrid_p2, 3);
    EQUALS(&fx, &b, 2.0, "bgrid", 1, bgrid_p2, 3, "frame b, other parameters");
    give(&fx, &c, 1);
    EQUALS(&fx, &c, 3.0, "bgrid", 1, bgrid_p2, 3, "frame c, another size");
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "bgrid", 1, bgrid_p2, 3, "frame a again");
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
    fx_free(&c);
}

TEST(kpcn_frames_on_one_instance) {
    NEED(KPCN);
    fx_plugin fx;
    fx_sample a, b;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128));
    OPEN(fx, KPCN, GENERAL);
    SET(fx, kpcn_small, 1);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "frame a");
    give(&fx, &b, 1);
    EQUALS(&fx, &b, 2.0, "kpcn", 1, kpcn_small, 1, "frame b");
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "frame a again");
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
}

/* auto picks its model at each commit, from each frame. */
TEST(auto_frames_on_one_instance) {
    NEED(AUTO);
    fx_plugin fx;
    fx_sample a, b;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128));
    OPEN(fx, AUTO, GENERAL);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "auto", 1, NULL, 0, "frame a");
    give(&fx, &b, 0);
    EQUALS(&fx, &b, 2.0, "auto", 0, NULL, 0, "frame b without features");
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "auto", 1, NULL, 0, "frame a again");
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
}

/* bgrid uses the features when given: a kept op must forget them when the
 * clips are disconnected (their pixels freed), and take the new ones when
 * connected again. */
TEST(bgrid_features_disconnected_and_connected_again) {
    fx_plugin fx;
    fx_sample a, b;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128));
    CHECK(references_differ("bgrid", 1, bgrid_p1, 3, "bgrid", 0, bgrid_p1, 3, &a));
    OPEN(fx, BGRID, FILTER);
    SET(fx, bgrid_p1, 3);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "bgrid", 1, bgrid_p1, 3, "with features");
    give(&fx, &a, 0);
    EQUALS(&fx, &a, 1.0, "bgrid", 0, bgrid_p1, 3, "features disconnected");
    give(&fx, &b, 1);
    EQUALS(&fx, &b, 2.0, "bgrid", 1, bgrid_p1, 3, "connected again, another frame");
    give(&fx, &b, 0);
    EQUALS(&fx, &b, 2.0, "bgrid", 0, bgrid_p1, 3, "disconnected again");
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
}

/* kpcn in the filter context without its features runs the colour-guided
 * grid with its defaults (another op), then kpcn again when they return. */
TEST(kpcn_falls_back_and_comes_back) {
    NEED(KPCN);
    fx_plugin fx;
    fx_sample a, b;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128));
    OPEN(fx, KPCN, FILTER);
    SET(fx, kpcn_small, 1);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "with features");
    give(&fx, &b, 0);
    EQUALS(&fx, &b, 2.0, "bgrid", 0, NULL, 0, "the fallback");
    CHECK_STR_CONTAINS(host_st.last_message, "denoised by the bilateral grid guided by the colour alone");
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "features again");
    give(&fx, &a, 0);
    EQUALS(&fx, &a, 1.0, "bgrid", 0, NULL, 0, "the fallback again");
    give(&fx, &b, 1);
    EQUALS(&fx, &b, 2.0, "kpcn", 1, kpcn_small, 1, "features once more");
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
}

/* The host's thread count changing between renders: each render gives the
 * library's result. bgrid's output is the same at every count, so this
 * checks that a change is safe (the kept pair is remade, not reused with a
 * pool of the old size), not that it was remade. */
TEST(thread_count_changes_between_renders) {
    fx_plugin fx;
    fx_sample a;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128));
    OPEN(fx, BGRID, GENERAL);
    SET(fx, bgrid_p1, 3);
    give(&fx, &a, 1);
    const unsigned counts[4] = {3, 1, 2, 2};
    for (int i = 0; i < 4; i++) {
        host_cfg.num_cpus = counts[i];
        char what[64];
        snprintf(what, sizeof what, "%u threads", counts[i]);
        EQUALS(&fx, &a, 1.0, "bgrid", 1, bgrid_p1, 3, what);
    }
done:
    fx_close(&fx);
    fx_free(&a);
}

/* Purging caches and ending a sequence drop the kept op; the next render
 * makes a new one and gives the same bits. Both actions are fine with
 * nothing kept. */
TEST(purge_caches_and_sequence_end_between_renders) {
    NEED(KPCN);
    fx_plugin fx;
    fx_sample a, b;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128));
    OPEN(fx, KPCN, GENERAL);
    SET(fx, kpcn_small, 1);
    CHECK_EQ_INT(hx_purge_caches(&fx.bundle, fx.index, fx.inst), kOfxStatOK);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "before the purge");
    CHECK_EQ_INT(hx_purge_caches(&fx.bundle, fx.index, fx.inst), kOfxStatOK);
    give(&fx, &b, 1);
    EQUALS(&fx, &b, 2.0, "kpcn", 1, kpcn_small, 1, "after the purge");
    CHECK_EQ_INT(hx_purge_caches(&fx.bundle, fx.index, fx.inst), kOfxStatOK);
    CHECK_EQ_INT(hx_purge_caches(&fx.bundle, fx.index, fx.inst), kOfxStatOK);

    OfxStatus begin = hx_begin_sequence(&fx.bundle, fx.index, fx.inst, 1.0, 2.0);
    CHECK(begin == kOfxStatOK || begin == kOfxStatReplyDefault);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "sequence frame 1");
    give(&fx, &b, 1);
    EQUALS(&fx, &b, 2.0, "kpcn", 1, kpcn_small, 1, "sequence frame 2");
    CHECK_EQ_INT(hx_end_sequence(&fx.bundle, fx.index, fx.inst, 1.0, 2.0), kOfxStatOK);
    CHECK_EQ_INT(hx_end_sequence(&fx.bundle, fx.index, fx.inst, 1.0, 2.0), kOfxStatOK);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "after the sequence");
    /* the instance is destroyed holding a kept op (fx_close) */
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
}

/* An abort before the library and one inside it on a kept op: the render
 * fails, the op is dropped, and the next render of that frame is right. */
TEST(abort_then_render_on_one_instance) {
    NEED(KPCN);
    fx_plugin fx;
    fx_sample a, b;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128) && !frame(&b, 100, 80, 128, 128));
    OPEN(fx, KPCN, GENERAL);
    SET(fx, kpcn_small, 1);
    give(&fx, &a, 1);
    host_st.abort_calls = 0;
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "frame a");
    const int new_op_calls = host_st.abort_calls;
    host_st.abort_calls = 0;
    EQUALS(&fx, &a, 1.0, "kpcn", 1, kpcn_small, 1, "frame a again");
    /* the kept op reports progress (so it can be cancelled) as a new one */
    CHECK_EQ_INT(host_st.abort_calls, new_op_calls);
    give(&fx, &b, 1);
    const int after[2] = {0, 2}; /* before the library runs, inside it */
    for (int k = 0; k < 2; k++) {
        OfxRectI whole = {0, 0, b.w, b.h};
        hx_output_prepare(he_clip(fx.inst, "Output"), whole, 4, 0);
        host_st.abort_calls = 0;
        host_cfg.abort_after = after[k];
        CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 2.0, whole), kOfxStatFailed);
        CHECK(host_st.abort_calls > after[k]);
        CHECK_EQ_INT(host_st.images_out, 0);
        CHECK_EQ_INT(host_st.image_memory_out, 0);
        host_cfg.abort_after = -1;
        EQUALS(&fx, &b, 2.0, "kpcn", 1, kpcn_small, 1, "frame b after an abort");
    }
    CHECK_EQ_INT(host_st.persistent_messages, 0);
done:
    fx_close(&fx);
    fx_free(&a);
    fx_free(&b);
}

/* A render the plugin refuses (a feature clip with too few channels)
 * between two good ones. */
TEST(failed_render_then_render_on_one_instance) {
    fx_plugin fx;
    fx_sample a;
    memset(&fx, 0, sizeof fx);
    host_reset();
    CHECK(!frame(&a, 0, 0, 128, 128));
    OPEN(fx, BGRID, GENERAL);
    SET(fx, bgrid_p1, 3);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "bgrid", 1, bgrid_p1, 3, "before");
    hx_clip_set_image(he_clip(fx.inst, "Normal"), a.ddepth, a.w, a.h, 1, 0, 0, 0);
    OfxRectI whole = {0, 0, a.w, a.h};
    hx_output_prepare(he_clip(fx.inst, "Output"), whole, 4, 0);
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, whole), kOfxStatErrImageFormat);
    give(&fx, &a, 1);
    EQUALS(&fx, &a, 1.0, "bgrid", 1, bgrid_p1, 3, "after");
done:
    fx_close(&fx);
    fx_free(&a);
}

TEST(registered_test_count) { CHECK_EQ_INT(ew_ntests_, OFX_TEST_COUNT); }
