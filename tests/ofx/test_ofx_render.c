/*
 * Rendering through the plugin equals running the library: the Cornell-box
 * render (real Cycles passes) through each plugin, with non-default
 * parameters, in both contexts, with and without the optional clips, with
 * odd windows and origins, negative and padded row bytes, RGB images,
 * animated and out-of-range parameters, and hosts without optional suites.
 * Equality is exact: the plugin and the test link the same library code
 * and use the same number of threads.
 */
#include "ew_test.h"

#include <stdlib.h>

#include "edgewise/edgewise.h"
#include "ofx_fixtures.h"

static char err[512];

#define FILTER "OfxImageEffectContextFilter"
#define GENERAL "OfxImageEffectContextGeneral"

typedef struct {
    const char *clip, *image;
    const float *data; /* top-down, `comps` per pixel, the source's size */
    int comps;
} case_aux;

typedef struct {
    const char *id, *kind, *method, *context;
    const fx_sample *s;
    int x1, y1;     /* the source's origin in pixel coordinates */
    int layout;     /* HX_* for every host image */
    int src_comps;  /* 4 RGBA or 3 RGB */
    int out_comps;  /* 4 unless set */
    case_aux aux[4];
    int num_aux;
    fx_param params[6];   /* what the host's parameters are set to */
    int num_params;
    fx_param lib_params[6]; /* what the library gets, if not the same */
    int num_lib_params;
    int windows;           /* how many of window[] to render (0: the whole source) */
    OfxRectI window[4];
    const host_config *cfg; /* the host's configuration, if not the default */
    /* If the library refuses these inputs/parameters, the plugin must refuse
     * them too (kOfxStatFailed with the library's message) instead. */
    int library_may_refuse;
    /* > 0: the host gives the render's sample count on the Source clip */
    int source_samples;
    /* a one-channel clip the host hands over expanded to RGBA, as (0, 0, 0,
     * v), with the clip's unmapped components Alpha; NULL: none */
    const char *expanded_clip;
} render_case;

static float *rgb_of(const float *rgba, size_t n) {
    float *d = (float *)malloc(n * 3 * sizeof(float));
    if (!d) abort();
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) d[i * 3 + (size_t)k] = rgba[i * 4 + (size_t)k];
    return d;
}

/* Set up the instance's images and parameters, render each window and
 * compare it with the library's result for the whole source. */
static void run_case(const render_case *c) {
    const fx_sample *s = c->s;
    const int w = s->w, h = s->h, out_comps = c->out_comps ? c->out_comps : 4;
    const size_t n = (size_t)w * (size_t)h;
    fx_plugin fx;
    float *src = c->src_comps == 3 ? rgb_of(s->rgba, n) : s->rgba;
    float *ref = (float *)malloc(n * 4 * sizeof(float));
    if (!ref) abort();
    host_reset();
    if (c->cfg) host_cfg = *c->cfg;
    if (fx_open(&fx, c->id, c->context, err, sizeof err)) {
        FAIL_AT("%s", err);
        goto done;
    }
    hx_clip_set_image(he_clip(fx.inst, "Source"), src, w, h, c->src_comps, c->x1, c->y1, c->layout);
    if (c->source_samples > 0)
        hp_set_i(he_clip(fx.inst, "Source")->props, "org.edgewise.OfxImageClipPropRenderSamples", 0, c->source_samples);
    for (int i = 0; i < c->num_aux; i++) {
        host_clip *clip = he_clip(fx.inst, c->aux[i].clip);
        if (!clip) {
            FAIL_AT("no clip %s", c->aux[i].clip);
            goto done;
        }
        if (c->expanded_clip && !strcmp(c->expanded_clip, c->aux[i].clip) && c->aux[i].comps == 1) {
            float *rgba = (float *)calloc(n * 4, sizeof(float));
            if (!rgba) abort();
            for (size_t k = 0; k < n; k++) rgba[k * 4 + 3] = c->aux[i].data[k];
            hx_clip_set_image(clip, rgba, w, h, 4, c->x1, c->y1, c->layout);
            hp_set_s(clip->props, "OfxImageClipPropUnmappedComponents", 0, "OfxImageComponentAlpha");
            free(rgba);
        } else {
            hx_clip_set_image(clip, c->aux[i].data, w, h, c->aux[i].comps, c->x1, c->y1, c->layout);
        }
    }
    for (int i = 0; i < c->num_params; i++)
        if (fx_set_param(&fx, c->params[i].name, c->params[i].value)) {
            FAIL_AT("no parameter %s", c->params[i].name);
            goto done;
        }

    /* the library, on the same pixels and parameters, with as many threads */
    fx_image aux[4];
    for (int i = 0; i < c->num_aux; i++) {
        aux[i].name = c->aux[i].image;
        aux[i].data = c->aux[i].data;
        aux[i].channels = c->aux[i].comps;
    }
    int channels = !strcmp(c->kind, "denoiser") ? 3 : c->src_comps;
    int threads = host_cfg.offer_multithread ? (int)host_cfg.num_cpus : 0;
    const fx_param *lp = c->num_lib_params ? c->lib_params : c->params;
    int nlp = c->num_lib_params ? c->num_lib_params : c->num_params;
    if (fx_reference(c->kind, c->method, threads, w, h, src, c->src_comps, channels, aux, c->num_aux, lp, nlp, ref, err,
                     sizeof err)) {
        if (!c->library_may_refuse) {
            FAIL_AT("%s", err);
            goto done;
        }
        fprintf(stderr, "  %s: the library refuses: %s\n", c->method, err);
        OfxRectI all = {c->x1, c->y1, c->x1 + w, c->y1 + h};
        hx_output_prepare(he_clip(fx.inst, "Output"), all, out_comps, c->layout);
        CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, all), kOfxStatFailed);
        CHECK_STR_CONTAINS(host_st.last_message, c->method);
        CHECK_EQ_INT(host_st.images_out, 0);
        CHECK_EQ_INT(host_st.image_memory_out, 0);
        goto done;
    }

    OfxRectI whole = {c->x1, c->y1, c->x1 + w, c->y1 + h};
    int nw = c->windows ? c->windows : 1;
    for (int k = 0; k < nw; k++) {
        OfxRectI win = c->windows ? c->window[k] : whole;
        int ww = win.x2 - win.x1, wh = win.y2 - win.y1;
        host_clip *out = he_clip(fx.inst, "Output");
        hx_output_prepare(out, win, out_comps, c->layout);
        OfxStatus st = hx_render(&fx.bundle, fx.index, fx.inst, 1.0, win);
        if (st != kOfxStatOK) {
            FAIL_AT("render of window %d: status %d (%s)", k, st, host_st.last_message);
            goto done;
        }
        float *got = (float *)malloc((size_t)(ww * wh * out_comps + 1) * sizeof(float));
        float *want = (float *)malloc((size_t)(ww * wh * out_comps + 1) * sizeof(float));
        if (!got || !want) abort();
        hx_output_read(out, win, got);
        for (int row = 0; row < wh; row++) {
            int y = win.y2 - 1 - row;
            for (int x = win.x1; x < win.x2; x++) {
                float *d = want + ((size_t)row * (size_t)ww + (size_t)(x - win.x1)) * (size_t)out_comps;
                int inside = x >= whole.x1 && x < whole.x2 && y >= whole.y1 && y < whole.y2;
                const float *r = inside ? ref + ((size_t)(whole.y2 - 1 - y) * (size_t)w + (size_t)(x - whole.x1)) * 4 : NULL;
                for (int q = 0; q < out_comps; q++) d[q] = r ? r[out_comps == 1 ? 3 : q] : 0.0f;
            }
        }
        char msg[256] = "";
        long bad = fx_compare(got, want, (size_t)ww * (size_t)wh * (size_t)out_comps, out_comps, ww > 0 ? ww : 1, msg,
                              sizeof msg);
        free(got);
        free(want);
        if (bad) {
            FAIL_AT("window %d (%d,%d)-(%d,%d): %ld values differ from the library; first %s", k, win.x1, win.y1,
                    win.x2, win.y2, bad, msg);
            goto done;
        }
        if (!hx_output_guards_intact(out)) {
            FAIL_AT("window %d: the plugin wrote outside the output's pixels", k);
            goto done;
        }
    }
    /* everything handed out came back */
    CHECK_EQ_INT(host_st.images_out, 0);
    CHECK_EQ_INT(host_st.image_memory_out, 0);
    CHECK(host_st.images_fetched >= 2 + c->num_aux);
    /* parameters are read at the render's time, never as "current value" */
    CHECK_EQ_INT(host_st.param_get_value_calls, 0);
    for (int i = 0; i < fx.inst->num_params; i++) CHECK(fx.inst->params[i]->at_time_calls > 0);
    if (host_st.violations) FAIL_AT("%d host violations, last: %s", host_st.violations, host_st.last_violation);
done:
    fx_close(&fx);
    if (c->src_comps == 3) free(src);
    free(ref);
}

static const fx_sample *cornell(void) {
    const fx_sample *s = fx_cornell(err, sizeof err);
    if (!s) fprintf(stderr, "  cannot read the sample: %s\n", err);
    return s;
}

static render_case bgrid_case(const fx_sample *s, const char *context) {
    render_case c;
    memset(&c, 0, sizeof c);
    c.id = "org.edgewise.denoise.bgrid";
    c.kind = "denoiser";
    c.method = "bgrid";
    c.context = context;
    c.s = s;
    c.src_comps = 4;
    c.aux[0] = (case_aux){"Albedo", "albedo", s->albedo, 3};
    c.aux[1] = (case_aux){"Normal", "normal", s->normal, 3};
    c.aux[2] = (case_aux){"Depth", "depth", s->ddepth, 1};
    c.num_aux = 3;
    c.params[0] = (fx_param){"spatial_rate", 6.0};
    c.params[1] = (fx_param){"range_rate", 10.0};
    c.params[2] = (fx_param){"color_weight", 0.5};
    c.params[3] = (fx_param){"firefly_k", 4.0};
    c.num_params = 4;
    return c;
}

static render_case pyramid_case(const fx_sample *s) {
    render_case c;
    memset(&c, 0, sizeof c);
    c.id = "org.edgewise.filter.pyramid";
    c.kind = "filter";
    c.method = "pyramid";
    c.context = FILTER;
    c.s = s;
    c.src_comps = 4;
    c.aux[0] = (case_aux){"Normal", "normal", s->normal, 3};
    c.aux[1] = (case_aux){"Depth", "depth", s->depth, 1};
    c.num_aux = 2;
    c.params[0] = (fx_param){"model", 1};
    c.params[1] = (fx_param){"radius", 12};
    c.params[2] = (fx_param){"sigma_normal", 16.0};
    c.params[3] = (fx_param){"sigma_depth", 0.5};
    /* analytic domain weights: the trained table is not built into the
     * library yet (core/algorithms/pyramid_weights_data.c is empty until
     * trained, and 'weights' = 1 then fails by design) */
    c.params[4] = (fx_param){"weights", 0};
    c.num_params = 5;
    return c;
}

TEST(bgrid_filter_context_matches_library) {
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = bgrid_case(s, FILTER);
    run_case(&c);
}

TEST(bgrid_general_context_matches_library) {
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = bgrid_case(s, GENERAL);
    run_case(&c);
}

TEST(bgrid_without_optional_clips_matches_library) {
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = bgrid_case(s, FILTER);
    c.num_aux = 0; /* Albedo, Normal, Depth left unconnected */
    run_case(&c);
}

TEST(pyramid_matches_library) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = pyramid_case(s);
    run_case(&c);
}

static void dof_case(const fx_sample *s, render_case *c);

TEST(dof_matches_library) {
    NEED("org.edgewise.filter.dof");
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c;
    dof_case(s, &c);
    run_case(&c);
}

/* A host that expands the one-channel Depth to RGBA (depth in alpha, R = G
 * = B = 0) against the clip preference: the plugin reads the alpha. */
TEST(dof_depth_expanded_to_rgba_by_the_host) {
    NEED("org.edgewise.filter.dof");
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c;
    dof_case(s, &c);
    c.expanded_clip = "Depth";
    run_case(&c);
}

/* nbg in the filter context, where its features cannot be mandatory, and
 * nothing connected but Source: the colour-guided grid, and a warning. */
TEST(nbg_without_features_falls_back) {
    NEED("org.edgewise.denoise.nbg");
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c;
    memset(&c, 0, sizeof c);
    c.id = "org.edgewise.denoise.nbg";
    c.kind = "denoiser";
    c.method = "bgrid"; /* what the library runs: the reference */
    c.context = FILTER;
    c.s = s;
    c.src_comps = 4;
    run_case(&c);
    CHECK_STR_CONTAINS(host_st.last_message, "denoised by the bilateral grid guided by the colour alone");
}

static void dof_case(const fx_sample *s, render_case *c0) {
    memset(c0, 0, sizeof *c0);
    render_case c;
    memset(&c, 0, sizeof c);
    c.id = "org.edgewise.filter.dof";
    c.kind = "filter";
    c.method = "dof";
    c.context = GENERAL;
    c.s = s;
    c.src_comps = 4;
    c.aux[0] = (case_aux){"Depth", "depth", s->depth, 1};
    c.num_aux = 1;
    /* focus on the middle of the frame */
    double focus = floor(s->depth[(size_t)(s->h / 2) * (size_t)s->w + (size_t)(s->w / 2)] * 100.0) / 100.0;
    CHECK(focus > 0.01);
    c.params[0] = (fx_param){"focus_distance", focus};
    c.params[1] = (fx_param){"fstop", 1.4};
    c.params[2] = (fx_param){"radius", 12};
    c.params[3] = (fx_param){"weights", 0}; /* see pyramid_case */
    c.num_params = 4;
    *c0 = c;
}

TEST(atrous_matches_library) {
    NEED("org.edgewise.filter.atrous");
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c;
    memset(&c, 0, sizeof c);
    c.id = "org.edgewise.filter.atrous";
    c.kind = "filter";
    c.method = "atrous";
    c.context = FILTER;
    c.s = s;
    c.src_comps = 4;
    c.aux[0] = (case_aux){"Normal", "normal", s->normal, 3};
    c.aux[1] = (case_aux){"Depth", "depth", s->depth, 1};
    c.num_aux = 2;
    c.params[0] = (fx_param){"radius", 16};
    c.params[1] = (fx_param){"sigma_luminance", 1.0};
    c.num_params = 2;
    run_case(&c);
}

/* Whatever the bundle offers (a denoiser added to the library shows up
 * here without a change), rendered with its default parameters and every
 * feature it can use, in the general context, equals the library. */
TEST(every_plugin_with_defaults_matches_library) {
    const fx_sample *s = cornell();
    CHECK(s);
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) FAIL_AT("%s", err);
    CHECK(b.dl);
    int n = b.get_count();
    char ids[8][64];
    for (int i = 0; i < n && i < 8; i++) snprintf(ids[i], sizeof ids[i], "%s", b.get_plugin(i)->pluginIdentifier);
    hb_close(&b);
    for (int i = 0; i < n && i < 8; i++) {
        char method[64];
        render_case c;
        memset(&c, 0, sizeof c);
        c.id = ids[i];
        c.kind = sscanf(ids[i], "org.edgewise.denoise.%63s", method) == 1 ? "denoiser" : "filter";
        if (!strcmp(c.kind, "filter") && sscanf(ids[i], "org.edgewise.filter.%63s", method) != 1) continue;
        c.method = method;
        c.context = GENERAL;
        c.s = s;
        c.src_comps = 4;
        c.library_may_refuse = 1;
        int32_t ni = 0;
        for (int32_t k = 0; k < ew_method_count(c.kind); k++) {
            const char *nm = NULL;
            if (ew_method_get(c.kind, k, &nm, NULL, &ni, NULL) == EW_OK && !strcmp(nm, method)) break;
        }
        for (int32_t k = 0; k < ni; k++) {
            ew_image_info im;
            CHECK_EQ_INT(ew_method_image(c.kind, method, k, &im), EW_OK);
            case_aux *a = &c.aux[c.num_aux];
            if (!strcmp(im.name, "albedo")) *a = (case_aux){"Albedo", "albedo", s->albedo, 3};
            else if (!strcmp(im.name, "normal")) *a = (case_aux){"Normal", "normal", s->normal, 3};
            else if (!strcmp(im.name, "depth"))
                *a = (case_aux){"Depth", "depth", !strcmp(c.kind, "denoiser") ? s->ddepth : s->depth, 1};
            else continue;
            c.num_aux++;
        }
        fprintf(stderr, "  %s with %d feature clips\n", ids[i], c.num_aux);
        run_case(&c);
        if (ew_failed_now_) return;
    }
}

/* "auto" with its "samples" parameter at 0 takes the sample count the host
 * gives on the Source clip, so it picks what the CLI and a graph pick for
 * the same file: the library run with that count. */
static void auto_case(const fx_sample *s, render_case *c, int samples) {
    memset(c, 0, sizeof *c);
    c->id = "org.edgewise.denoise.auto";
    c->kind = "denoiser";
    c->method = "auto";
    c->context = GENERAL;
    c->s = s;
    c->src_comps = 4;
    c->aux[0] = (case_aux){"Albedo", "albedo", s->albedo, 3};
    c->aux[1] = (case_aux){"Normal", "normal", s->normal, 3};
    c->aux[2] = (case_aux){"Depth", "depth", s->ddepth, 1};
    c->num_aux = 3;
    c->source_samples = samples;
    c->lib_params[0] = (fx_param){"samples", (double)samples};
    c->num_lib_params = 1;
}

TEST(auto_takes_the_file_sample_count_from_the_source_clip) {
    const fx_sample *s = cornell();
    CHECK(s);
    NEED("org.edgewise.denoise.auto");
    CHECK(s->samples > 0); /* the bundled render says how many */
    render_case c;
    auto_case(s, &c, s->samples);
    run_case(&c);
}

TEST(auto_takes_another_sample_count_from_the_source_clip) {
    const fx_sample *s = cornell();
    CHECK(s);
    NEED("org.edgewise.denoise.auto");
    /* A count the noise estimate of this 4-spp frame would not lead to, so
     * a plugin ignoring the host's count renders something else. At quality
     * fast: balanced and high run kpcn-large at every count, which reads the
     * noise level from the colour itself. */
    const int n = s->w * s->h, spp = 1; /* nbg's 1-spp model; the estimate leads to nbg 2layer-3grid */
    float *with = (float *)malloc((size_t)n * 4 * sizeof(float)), *without = (float *)malloc((size_t)n * 4 * sizeof(float));
    if (!with || !without) abort();
    fx_image aux[3] = {{"albedo", s->albedo, 3}, {"normal", s->normal, 3}, {"depth", s->ddepth, 1}};
    fx_param p[2] = {{"quality", 0.0}, {"samples", (double)spp}};
    int threads = 3; /* host_reset's CPUs, as run_case's reference uses */
    CHECK_EQ_INT(fx_reference("denoiser", "auto", threads, s->w, s->h, s->rgba, 4, 3, aux, 3, p, 2, with, err, sizeof err), 0);
    CHECK_EQ_INT(fx_reference("denoiser", "auto", threads, s->w, s->h, s->rgba, 4, 3, aux, 3, p, 1, without, err, sizeof err), 0);
    char msg[256];
    CHECK(fx_compare(with, without, (size_t)n * 4, 4, s->w, msg, sizeof msg) > 0);
    free(with);
    free(without);
    render_case c;
    auto_case(s, &c, spp);
    c.params[c.num_params++] = (fx_param){"quality", 0.0};
    c.lib_params[c.num_lib_params++] = (fx_param){"quality", 0.0};
    run_case(&c);
}

/* An odd-sized crop away from the origin, rendered through windows that
 * are single rows, single pixels, the whole frame, and partly outside it. */
static void odd_windows(render_case *c, fx_sample *crop) {
    c->s = crop;
    c->x1 = -7;
    c->y1 = 13;
    c->windows = 4;
    c->window[0] = (OfxRectI){-4, 18, 13, 19};
    c->window[1] = (OfxRectI){22, 40, 23, 41};
    c->window[2] = (OfxRectI){-7, 13, 30, 42};
    c->window[3] = (OfxRectI){20, 30, 41, 47}; /* beyond the source's right and top edges */
    run_case(c);
}

TEST(odd_windows_and_origin_bgrid) {
    const fx_sample *s = cornell();
    CHECK(s);
    fx_sample crop;
    fx_crop(s, 101, 57, 37, 29, &crop);
    render_case c = bgrid_case(&crop, FILTER);
    odd_windows(&c, &crop);
    fx_free(&crop);
}

TEST(odd_windows_and_origin_pyramid) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    fx_sample crop;
    fx_crop(s, 33, 140, 37, 29, &crop);
    render_case c = pyramid_case(&crop);
    odd_windows(&c, &crop);
    fx_free(&crop);
}

TEST(negative_row_bytes) {
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = bgrid_case(s, FILTER);
    c.layout = HX_NEG_ROW_BYTES;
    run_case(&c);
}

TEST(negative_and_padded_row_bytes_with_windows) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    fx_sample crop;
    fx_crop(s, 60, 60, 45, 33, &crop);
    render_case c = pyramid_case(&crop);
    c.layout = HX_NEG_ROW_BYTES | HX_PAD_ROWS;
    odd_windows(&c, &crop);
    fx_free(&crop);
}

TEST(padded_row_bytes) {
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = bgrid_case(s, GENERAL);
    c.layout = HX_PAD_ROWS;
    run_case(&c);
}

/* Premultiplied RGBA: a checker of transparent and opaque cells through
 * the blurs comes out with soft alpha at the cell edges and no colour above
 * its alpha (the host composites what it gets as premultiplied), and equals
 * the library's result. */
TEST(premultiplied_alpha_is_blurred_with_the_colour) {
    const int w = 48, h = 40;
    fx_sample chk;
    memset(&chk, 0, sizeof chk);
    chk.w = w;
    chk.h = h;
    chk.rgba = (float *)malloc(sizeof(float) * (size_t)w * (size_t)h * 4);
    chk.depth = (float *)malloc(sizeof(float) * (size_t)w * (size_t)h);
    CHECK(chk.rgba && chk.depth);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float *p = chk.rgba + ((size_t)y * (size_t)w + (size_t)x) * 4;
            const float a = ((x / 6 + y / 6) & 1) ? 1.0f : 0.0f;
            p[0] = 0.9f * a;
            p[1] = 0.5f * a;
            p[2] = 0.2f * a;
            p[3] = a;
            chk.depth[(size_t)y * (size_t)w + (size_t)x] = 0.5f + 10.0f * (float)x / (float)w;
        }
    static const struct {
        const char *id, *method;
    } blurs[] = {{"org.edgewise.filter.pyramid", "pyramid"}, {"org.edgewise.filter.dof", "dof"}};
    for (size_t b = 0; b < sizeof blurs / sizeof blurs[0]; b++) {
        render_case c;
        memset(&c, 0, sizeof c);
        c.id = blurs[b].id;
        c.kind = "filter";
        c.method = blurs[b].method;
        c.context = GENERAL;
        c.s = &chk;
        c.src_comps = 4;
        if (!strcmp(blurs[b].method, "dof")) {
            c.aux[0] = (case_aux){"Depth", "depth", chk.depth, 1};
            c.num_aux = 1;
            c.params[0] = (fx_param){"fstop", 0.5};
            c.params[1] = (fx_param){"focus_distance", 0.5};
            c.num_params = 2;
        } else {
            c.params[0] = (fx_param){"radius", 6};
            c.params[1] = (fx_param){"sigma_range", 100.0};
            c.params[2] = (fx_param){"weights", 0};
            c.num_params = 3;
        }
        run_case(&c); /* the plugin's pixels are the library's */
        /* and the library's (so the plugin's) are valid premultiplied colour */
        float *ref = (float *)malloc(sizeof(float) * (size_t)w * (size_t)h * 4);
        CHECK(ref);
        fx_image aux = {"depth", chk.depth, 1};
        CHECK_EQ_INT(fx_reference("filter", c.method, 0, w, h, chk.rgba, 4, 4, &aux, c.num_aux, c.params,
                                  c.num_params, ref, err, sizeof err),
                     0);
        long over = 0, soft = 0;
        for (size_t i = 0; i < (size_t)w * (size_t)h; i++) {
            for (int k = 0; k < 3; k++) over += ref[i * 4 + (size_t)k] > ref[i * 4 + 3] + 1e-5f;
            soft += ref[i * 4 + 3] > 0.01f && ref[i * 4 + 3] < 0.99f;
        }
        if (over || !soft) fprintf(stderr, "  %s: %ld above alpha, %ld soft\n", c.method, over, soft);
        CHECK_EQ_INT(over, 0);
        CHECK(soft > 0);
        free(ref);
    }
    free(chk.rgba);
    free(chk.depth);
}

TEST(rgb_source_and_output) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = pyramid_case(s);
    c.src_comps = 3;
    c.out_comps = 3;
    run_case(&c);
    render_case d = bgrid_case(s, FILTER);
    d.src_comps = 3;
    run_case(&d); /* RGB in, RGBA out: alpha 1 */
}

/* Proxies: at render scale 0.5 the pixel-sized parameters are halved (the
 * host's images are the proxy's), the others are not; the bgrid's rates
 * round-trip as floats, the pyramid's radius as an integer. */
TEST(render_scale_scales_pixel_parameters) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    host_config half;
    host_reset();
    half = host_cfg;
    half.render_scale[0] = half.render_scale[1] = 0.5;
    render_case c = pyramid_case(s);
    c.cfg = &half;
    memcpy(c.lib_params, c.params, sizeof c.params);
    c.num_lib_params = c.num_params;
    c.lib_params[1].value = 6; /* radius 12 at half size */
    run_case(&c);
    render_case d = bgrid_case(s, FILTER);
    d.cfg = &half;
    memcpy(d.lib_params, d.params, sizeof d.params);
    d.num_lib_params = d.num_params;
    d.lib_params[0].value = 3.0; /* spatial_rate 6 */
    d.lib_params[2].value = 0.5; /* color_weight: not a length */
    d.lib_params[4] = (fx_param){"prepass_rate", 4.0}; /* its default 8, halved */
    d.num_lib_params = 5;
    run_case(&d);
}

/* Only lengths in pixels are scaled: the introspection says which. */
TEST(pixel_parameters_are_the_lengths) {
    CHECK_EQ_INT(ew_method_param_is_pixels("filter", "pyramid", 1), 1);  /* radius */
    CHECK_EQ_INT(ew_method_param_is_pixels("filter", "pyramid", 2), 1);  /* sigma_spatial */
    CHECK_EQ_INT(ew_method_param_is_pixels("filter", "pyramid", 3), 0);  /* sigma_range */
    CHECK_EQ_INT(ew_method_param_is_pixels("denoiser", "bgrid", 0), 1);  /* spatial_rate */
    CHECK_EQ_INT(ew_method_param_is_pixels("denoiser", "bgrid", 1), 0);  /* range_rate: guide units */
    CHECK_EQ_INT(ew_method_param_is_pixels("denoiser", "nbg", 0), 0);    /* model */
    CHECK_EQ_INT(ew_method_param_is_pixels("filter", "dof", 4), 1);      /* radius: the CoC cap */
    CHECK_EQ_INT(ew_method_param_is_pixels("filter", "dof", 0), 0);      /* focal_length */
    CHECK_EQ_INT(ew_method_param_is_pixels("denoiser", "bgrid", 99), -1);
    CHECK_EQ_INT(ew_method_param_is_pixels("denoiser", "nosuch", 0), -1);
}

TEST(parameters_are_read_at_render_time) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    fx_sample crop;
    fx_crop(s, 80, 80, 64, 48, &crop);
    /* radius animates 4 -> 14 over frames 0..10: at frame 1, 5 */
    fx_plugin fx;
    host_reset();
    if (fx_open(&fx, "org.edgewise.filter.pyramid", FILTER, err, sizeof err)) {
        fx_close(&fx);
        fx_free(&crop);
        FAIL_AT("%s", err);
        return;
    }
    host_param *radius = he_param(fx.inst, "radius");
    CHECK(radius);
    radius->num_keys = 2;
    radius->key_time[0] = 0.0;
    radius->key_value[0] = 4.0;
    radius->key_time[1] = 10.0;
    radius->key_value[1] = 14.0;
    CHECK(fx_set_param(&fx, "weights", 0) == 0); /* see pyramid_case */
    hx_clip_set_image(he_clip(fx.inst, "Source"), crop.rgba, crop.w, crop.h, 4, 0, 0, 0);
    OfxRectI win = {0, 0, crop.w, crop.h};
    hx_output_prepare(he_clip(fx.inst, "Output"), win, 4, 0);
    CHECK_EQ_INT(hx_render(&fx.bundle, fx.index, fx.inst, 1.0, win), kOfxStatOK);
    CHECK(radius->last_time == 1.0);
    size_t n = (size_t)crop.w * (size_t)crop.h;
    float *got = (float *)malloc(n * 4 * sizeof(float)), *want = (float *)malloc(n * 4 * sizeof(float));
    if (!got || !want) abort();
    hx_output_read(he_clip(fx.inst, "Output"), win, got);
    fx_param p[2] = {{"radius", 5}, {"weights", 0}};
    char msg[256] = "";
    int rc = fx_reference("filter", "pyramid", 3, crop.w, crop.h, crop.rgba, 4, 4, NULL, 0, p, 2, want, err, sizeof err);
    long bad = rc ? -1 : fx_compare(got, want, n * 4, 4, crop.w, msg, sizeof msg);
    free(got);
    free(want);
    fx_close(&fx);
    fx_free(&crop);
    if (rc) FAIL_AT("%s", err);
    if (bad) FAIL_AT("%ld values differ from radius 5: %s", bad, msg);
    CHECK_EQ_INT(host_st.param_get_value_calls, 0);
}

TEST(out_of_range_parameters_are_clamped) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    fx_sample crop;
    fx_crop(s, 10, 10, 40, 40, &crop);
    render_case c = pyramid_case(&crop);
    /* a host that does not enforce the declared range */
    c.params[1] = (fx_param){"radius", 1000};
    c.params[3] = (fx_param){"sigma_depth", -5.0};
    c.lib_params[0] = c.params[0];
    c.lib_params[1] = (fx_param){"radius", 256};
    c.lib_params[2] = c.params[2];
    c.lib_params[3] = (fx_param){"sigma_depth", 0.0};
    c.lib_params[4] = c.params[4];
    c.num_lib_params = 5;
    run_case(&c);
    fx_free(&crop);
}

static host_config default_config(void) {
    host_reset();
    return host_cfg;
}

TEST(host_threads_are_used) {
    const fx_sample *s = cornell();
    CHECK(s);
    render_case c = bgrid_case(s, FILTER);
    run_case(&c);
    CHECK(host_st.mt_calls > 0);
    CHECK(host_st.mt_threads > 1);
}

TEST(host_without_multithread_suite) {
    const fx_sample *s = cornell();
    CHECK(s);
    host_config cfg = default_config();
    cfg.offer_multithread = 0;
    render_case c = bgrid_case(s, GENERAL);
    c.cfg = &cfg;
    run_case(&c);
    CHECK_EQ_INT(host_st.mt_calls, 0);
}

TEST(host_whose_multithread_fails) {
    NEED("org.edgewise.filter.pyramid");
    const fx_sample *s = cornell();
    CHECK(s);
    host_config cfg = default_config();
    cfg.mt_fail = 1;
    render_case c = pyramid_case(s);
    c.cfg = &cfg;
    run_case(&c);
    CHECK(host_st.mt_calls > 0);
    CHECK_EQ_INT(host_st.mt_threads, 0);
}

TEST(host_without_memory_and_message_suites) {
    const fx_sample *s = cornell();
    CHECK(s);
    host_config cfg = default_config();
    cfg.offer_memory = 0;
    cfg.offer_message_v1 = cfg.offer_message_v2 = 0;
    render_case c = bgrid_case(s, FILTER);
    c.cfg = &cfg;
    run_case(&c);
    CHECK_EQ_INT(host_st.memory_out, 0);
}

TEST(registered_test_count) { CHECK_EQ_INT(ew_ntests_, OFX_TEST_COUNT); }
