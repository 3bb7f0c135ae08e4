#include "ofx_fixtures.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"
#include "ewio.h"

static fx_sample cornell;
static int cornell_loaded;

static float *pass(const ewio_file *f, const char *name, const char *comps, char *err, size_t len) {
    size_t n = (size_t)ewio_width(f) * (size_t)ewio_height(f) * strlen(comps);
    float *p = (float *)malloc(n * sizeof(float));
    if (!p) abort();
    if (ewio_get_pass(f, "ViewLayer", name, comps, p, err, len) != 0) {
        free(p);
        return NULL;
    }
    return p;
}

const fx_sample *fx_cornell(char *err, size_t len) {
    if (cornell_loaded) return &cornell;
    const char *dir = getenv("EW_SAMPLE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell/f0001_spp0004.exr", dir ? dir : "samples");
    ewio_file *f = NULL;
    if (ewio_read(path, &f, err, len) != 0) return NULL;
    fx_sample s;
    memset(&s, 0, sizeof s);
    s.w = ewio_width(f);
    s.h = ewio_height(f);
    if (!(s.rgba = pass(f, "Combined", "RGBA", err, len)) || !(s.albedo = pass(f, "Denoising Albedo", "RGB", err, len)) ||
        !(s.normal = pass(f, "Denoising Normal", "XYZ", err, len)) ||
        !(s.ddepth = pass(f, "Denoising Depth", "Z", err, len)) || !(s.depth = pass(f, "Depth", "Z", err, len))) {
        fx_free(&s);
        ewio_free(f);
        return NULL;
    }
    s.samples = atoi(ewio_get_attribute(f, "cycles.ViewLayer.samples"));
    ewio_free(f);
    cornell = s;
    cornell_loaded = 1;
    return &cornell;
}

static float *crop(const float *src, int sw, int c, int x0, int y0, int w, int h) {
    float *d = (float *)malloc((size_t)w * (size_t)h * (size_t)c * sizeof(float));
    if (!d) abort();
    for (int y = 0; y < h; y++)
        memcpy(d + (size_t)y * (size_t)w * (size_t)c, src + ((size_t)(y0 + y) * (size_t)sw + (size_t)x0) * (size_t)c,
               (size_t)w * (size_t)c * sizeof(float));
    return d;
}

void fx_crop(const fx_sample *s, int x0, int y0, int w, int h, fx_sample *out) {
    out->w = w;
    out->h = h;
    out->rgba = crop(s->rgba, s->w, 4, x0, y0, w, h);
    out->albedo = crop(s->albedo, s->w, 3, x0, y0, w, h);
    out->normal = crop(s->normal, s->w, 3, x0, y0, w, h);
    out->ddepth = crop(s->ddepth, s->w, 1, x0, y0, w, h);
    out->depth = crop(s->depth, s->w, 1, x0, y0, w, h);
}

void fx_free(fx_sample *s) {
    free(s->rgba);
    free(s->albedo);
    free(s->normal);
    free(s->ddepth);
    free(s->depth);
    memset(s, 0, sizeof *s);
}

/* ---- the library's result ------------------------------------------------ */
typedef struct {
    ew_denoiser *d;
    ew_filter *f;
} op;

static ew_result set_image(op *o, const char *name, const ew_image *v) {
    return o->d ? ew_denoiser_set_image(o->d, name, v) : ew_filter_set_image(o->f, name, v);
}

int fx_reference(const char *kind, const char *method, int threads, int w, int h, const float *src, int src_comps,
                 int channels, const fx_image *aux, int num_aux, const fx_param *params, int num_params, float *out,
                 char *err, size_t len) {
    int rc = 1;
    ew_device *dev = NULL;
    op o = {NULL, NULL};
    size_t n = (size_t)w * (size_t)h;
    float *color = (float *)malloc(n * (size_t)channels * sizeof(float));
    float *res = (float *)malloc(n * (size_t)channels * sizeof(float));
    if (!color || !res) abort();
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < channels; k++) color[i * (size_t)channels + (size_t)k] = src[i * (size_t)src_comps + (size_t)k];

    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_result e = ew_device_create(&desc, &dev);
    if (e == EW_OK)
        e = !strcmp(kind, "denoiser") ? ew_denoiser_create(dev, method, &o.d) : ew_filter_create(dev, method, &o.f);
    ew_image cv = ew_image_packed(color, w, h, channels), ov = ew_image_packed(res, w, h, channels);
    if (e == EW_OK) e = set_image(&o, "color", &cv);
    if (e == EW_OK) e = set_image(&o, "output", &ov);
    for (int i = 0; e == EW_OK && i < num_aux; i++) {
        ew_image v = ew_image_packed((float *)aux[i].data, w, h, aux[i].channels);
        e = set_image(&o, aux[i].name, &v);
    }
    for (int i = 0; e == EW_OK && i < num_params; i++) {
        ew_param_info info;
        int32_t idx = -1, np = 0;
        for (int32_t k = 0; k < ew_method_count(kind); k++) {
            const char *nm = NULL;
            if (ew_method_get(kind, k, &nm, NULL, NULL, &np) == EW_OK && !strcmp(nm, method)) break;
        }
        for (int32_t k = 0; k < np && idx < 0; k++)
            if (ew_method_param(kind, method, k, &info) == EW_OK && !strcmp(info.name, params[i].name)) idx = k;
        if (idx < 0) {
            snprintf(err, len, "%s has no parameter %s", method, params[i].name);
            goto done;
        }
        if (info.type == EW_PARAM_FLOAT)
            e = o.d ? ew_denoiser_set_float(o.d, info.name, (float)params[i].value)
                    : ew_filter_set_float(o.f, info.name, (float)params[i].value);
        else
            e = o.d ? ew_denoiser_set_int(o.d, info.name, (int32_t)params[i].value)
                    : ew_filter_set_int(o.f, info.name, (int32_t)params[i].value);
    }
    if (e == EW_OK) e = o.d ? ew_denoiser_commit(o.d) : ew_filter_commit(o.f);
    if (e == EW_OK) e = o.d ? ew_denoiser_execute(o.d) : ew_filter_execute(o.f);
    if (e != EW_OK) {
        snprintf(err, len, "library: %s (%s)", ew_result_string(e), dev ? ew_device_last_error(dev) : "");
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        const float *s = src + i * (size_t)src_comps, *r = res + i * (size_t)channels;
        float *d = out + i * 4;
        if (src_comps == 1) {
            d[0] = d[1] = d[2] = 0.0f;
            d[3] = r[0];
        } else {
            d[0] = r[0];
            d[1] = r[1];
            d[2] = r[2];
            d[3] = channels == 4 ? r[3] : src_comps == 4 ? s[3] : 1.0f;
        }
    }
    rc = 0;
done:
    ew_denoiser_destroy(o.d);
    ew_filter_destroy(o.f);
    ew_device_destroy(dev);
    free(color);
    free(res);
    return rc;
}

long fx_compare(const float *got, const float *want, size_t n, int comps, int width, char *msg, size_t len) {
    long bad = 0;
    for (size_t i = 0; i < n; i++) {
        int same = got[i] == want[i] || (isnan(got[i]) && isnan(want[i]));
        if (same) continue;
        if (bad++ == 0) {
            size_t px = i / (size_t)comps;
            snprintf(msg, len, "pixel (%zu, %zu from top) channel %zu: got %.9g, want %.9g", px % (size_t)width,
                     px / (size_t)width, i % (size_t)comps, (double)got[i], (double)want[i]);
        }
    }
    return bad;
}

/* ---- a loaded plugin --------------------------------------------------- */
int fx_open(fx_plugin *fx, const char *identifier, const char *context, char *err, size_t len) {
    memset(fx, 0, sizeof *fx);
    host_init();
    if (hb_open(&fx->bundle, err, len) != 0) return 1;
    fx->index = hb_find(&fx->bundle, identifier);
    if (fx->index < 0) {
        snprintf(err, len, "no plugin %s in the bundle", identifier);
        return 1;
    }
    OfxStatus st;
    if ((st = hx_load(&fx->bundle, fx->index)) != kOfxStatOK) {
        snprintf(err, len, "load: %d", st);
        return 1;
    }
    if ((st = hx_describe(&fx->bundle, fx->index, &fx->desc)) != kOfxStatOK) {
        snprintf(err, len, "describe: %d", st);
        return 1;
    }
    if ((st = hx_describe_in_context(&fx->bundle, fx->index, context, &fx->ctx)) != kOfxStatOK) {
        snprintf(err, len, "describeInContext: %d", st);
        return 1;
    }
    if ((st = hx_create_instance(&fx->bundle, fx->index, fx->ctx, context, &fx->inst)) != kOfxStatOK) {
        snprintf(err, len, "createInstance: %d", st);
        return 1;
    }
    return 0;
}

void fx_close(fx_plugin *fx) {
    if (fx->inst) hx_destroy_instance(&fx->bundle, fx->index, fx->inst);
    if (fx->bundle.dl && fx->desc) hx_unload(&fx->bundle, fx->index);
    he_free(fx->ctx);
    he_free(fx->desc);
    hb_close(&fx->bundle);
    memset(fx, 0, sizeof *fx);
}

int fx_set_param(fx_plugin *fx, const char *name, double value) {
    host_param *p = he_param(fx->inst, name);
    if (!p) return 1;
    p->value = value;
    p->num_keys = 0;
    return 0;
}

int fx_plugin_exists(const char *identifier) {
    char err[256];
    host_bundle b;
    if (hb_open(&b, err, sizeof err)) return 0;
    int found = hb_find(&b, identifier) >= 0;
    hb_close(&b);
    return found;
}
