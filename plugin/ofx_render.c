/*
 * The render action: fetch the images, run the library method over the
 * whole source frame, write the render window, release everything.
 *
 * The library sees the host's pixels directly (top-down views with signed
 * row strides, see ofx_images.c); only the result goes to a scratch buffer
 * of the source's size, because the output image may cover just the render
 * window. Every resource lives in one struct and one cleanup releases it,
 * so no path — error, abort or success — leaks an image or a buffer.
 *
 * The device and op are the instance's kept ones when they fit (ofx_keep.c):
 * every render sets every image, every parameter and the progress callback
 * again, so a kept op computes what a new one would, bit for bit.
 *
 * Cancelling: the library calls our progress callback between its bands
 * (we ask the host's abort() there), and the copy to the output runs in
 * bands that ask abort() too. An aborted render returns kOfxStatFailed:
 * the spec leaves the status open, and "failed" keeps a host from caching
 * a half-written frame.
 */
#include "ofx_plugin.h"

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    OfxImageMemoryHandle handle;
    int locked;
} scratch_mem;

typedef struct {
    const ew_ofx_node *node;
    ew_ofx_instance *inst;
    OfxImageEffectHandle effect;
    OfxTime time;
    double scale;    /* the render scale (proxies): pixel-sized parameters are multiplied by it */
    OfxRectI window; /* clipped to the output image */
    OfxRectI dom;    /* what the library filters: the source image's bounds */
    int channels;    /* of the source handed to the library */
    ew_ofx_image src, out, aux[EW_OFX_MAX_AUX];
    scratch_mem mem[EW_OFX_MAX_AUX + 1];
    int num_mem;
    float *result; /* dom-sized, top-down, `channels` per pixel */
    ew_device *dev;
    ew_op *op;
    const char *method;  /* what op runs */
    int threads;         /* what dev was created with */
    unsigned generation; /* of the instance's keep when the op was taken */
    atomic_int aborted;
    /* a denoiser whose feature clips are missing runs this instead (the
     * colour-guided grid), and the user is told */
    const char *fallback;
} render_job;

/* After a good render the op goes back to the instance holding nothing of
 * this render: no image (the host's are released in cleanup) and no
 * callback (r lives on this stack). After a failed or aborted one it is
 * freed, and so is anything the instance still keeps. */
static void finish_op(render_job *r, OfxStatus st) {
    if (!r->op) {
        if (st != kOfxStatOK) ew_ofx_keep_drop(&r->inst->keep);
        ew_device_destroy(r->dev); /* the op could not be made */
        r->dev = NULL;
        return;
    }
    int keep = st == kOfxStatOK && ew_op_set_progress(r->op, NULL, NULL) == EW_OK &&
               ew_op_set_image(r->op, "color", NULL) == EW_OK && ew_op_set_image(r->op, "output", NULL) == EW_OK;
    for (int i = 0; keep && !r->fallback && i < r->node->num_aux; i++)
        keep = ew_op_set_image(r->op, r->node->aux[i].image, NULL) == EW_OK;
    if (keep) {
        ew_ofx_keep_put(&r->inst->keep, r->method, r->threads, r->dev, r->op, r->generation);
    } else {
        ew_op_destroy(r->op);
        ew_device_destroy(r->dev);
        ew_ofx_keep_drop(&r->inst->keep);
    }
    r->op = NULL;
    r->dev = NULL;
}

static void cleanup(render_job *r) {
    for (int i = 0; i < r->num_mem; i++) {
        if (r->mem[i].locked) ew_ofx.effect->imageMemoryUnlock(r->mem[i].handle);
        ew_ofx.effect->imageMemoryFree(r->mem[i].handle);
    }
    for (int i = 0; i < EW_OFX_MAX_AUX; i++) ew_ofx_image_release(&r->aux[i]);
    ew_ofx_image_release(&r->src);
    ew_ofx_image_release(&r->out);
}

/* Image-sized scratch from the host's image memory pool (where the spec
 * wants image buffers), freed by cleanup. */
static float *scratch(render_job *r, size_t bytes) {
    if (r->num_mem == (int)(sizeof r->mem / sizeof r->mem[0]) || !ew_ofx.effect->imageMemoryAlloc) return NULL;
    OfxImageMemoryHandle h = NULL;
    if (ew_ofx.effect->imageMemoryAlloc(r->effect, bytes, &h) != kOfxStatOK || !h) return NULL;
    scratch_mem *m = &r->mem[r->num_mem++];
    m->handle = h;
    void *p = NULL;
    if (ew_ofx.effect->imageMemoryLock(h, &p) != kOfxStatOK || !p) return NULL;
    m->locked = 1;
    return (float *)p;
}

/* ---- the library call -------------------------------------------------- */
static ew_result op_image(render_job *r, const char *name, const ew_image *v) { return ew_op_set_image(r->op, name, v); }

static ew_result op_param(render_job *r, const ew_param_info *p, int pixels, double v) {
    if (pixels && r->scale != 1.0) {
        v *= r->scale;
        if (p->type != EW_PARAM_FLOAT) v = floor(v + 0.5);
        if (v < p->min_value) v = p->min_value;
        if (v > p->max_value) v = p->max_value;
    }
    if (p->type == EW_PARAM_FLOAT) return ew_op_set_float(r->op, p->name, (float)v);
    return ew_op_set_int(r->op, p->name, (int32_t)v);
}

static int progress(void *user, double fraction) {
    (void)fraction;
    render_job *r = (render_job *)user;
    if (ew_ofx.effect->abort && ew_ofx.effect->abort(r->effect)) {
        atomic_store(&r->aborted, 1);
        return 0;
    }
    return 1;
}

static OfxStatus library_status(render_job *r, ew_result e) {
    if (e == EW_OK) return kOfxStatOK;
    if (e == EW_ERR_CANCELLED || atomic_load(&r->aborted)) return kOfxStatFailed;
    ew_ofx_post_error(r->effect, "Edgewise %s: %s", r->node->method,
                      r->dev && ew_device_last_error(r->dev)[0] ? ew_device_last_error(r->dev) : ew_result_string(e));
    return e == EW_ERR_OUT_OF_MEMORY ? kOfxStatErrMemory : kOfxStatFailed;
}

/* A feature image as a view over the source's domain: the host's pixels
 * when it covers exactly that, else a zero-padded copy. */
static OfxStatus aux_view(render_job *r, int i, const ew_ofx_aux *a, const ew_ofx_image *im, ew_image *v) {
    if (im->comps < a->channels && !(a->channels == 1 && im->comps >= 1)) {
        ew_ofx_post_error(r->effect, "Edgewise %s: clip %s needs %d channels (%s), it has %d", r->node->method,
                          a->clip, a->channels, a->channels == 3 ? "RGB" : "RGBA", im->comps);
        return kOfxStatErrImageFormat;
    }
    /* A one-channel feature: its own channel, or alpha when the host
     * expanded an Alpha input to RGBA (0, 0, 0, z) against our preference. */
    int first = 0;
    if (a->channels == 1 && im->comps > 1) {
        const int unmapped = ew_ofx_clip_unmapped_components(r->inst->aux[i]);
        if (unmapped == 1 && im->comps == 4) first = 3;
        else if (unmapped == 1) {
            ew_ofx_post_error(r->effect, "Edgewise %s: clip %s is one channel but arrives as %d channels without "
                              "alpha: connect it as Alpha or RGB", r->node->method, a->clip, im->comps);
            return kOfxStatErrImageFormat;
        }
    }
    const OfxRectI *d = &r->dom, *b = &im->bounds;
    if (b->x1 == d->x1 && b->y1 == d->y1 && b->x2 == d->x2 && b->y2 == d->y2) {
        *v = ew_ofx_image_view(im, first, a->channels);
        return kOfxStatOK;
    }
    int w = d->x2 - d->x1, h = d->y2 - d->y1, c = a->channels;
    float *buf = scratch(r, (size_t)w * (size_t)h * (size_t)c * sizeof(float));
    if (!buf) return kOfxStatErrMemory;
    for (int row = 0; row < h; row++) {
        int y = d->y2 - 1 - row;
        for (int x = d->x1; x < d->x2; x++) {
            float *o = buf + ((size_t)row * (size_t)w + (size_t)(x - d->x1)) * (size_t)c;
            int inside = x >= b->x1 && x < b->x2 && y >= b->y1 && y < b->y2;
            const float *p = inside ? ew_ofx_image_pixel(im, x, y) + first : NULL;
            for (int k = 0; k < c; k++) o[k] = p ? p[k] : 0.0f;
        }
    }
    *v = ew_image_packed(buf, w, h, c);
    return kOfxStatOK;
}

/* ---- writing the window ------------------------------------------------ */
static void write_rows(void *arg, int y0, int y1) {
    const render_job *r = (const render_job *)arg;
    const OfxRectI *d = &r->dom;
    const int C = r->channels, dw = d->x2 - d->x1;
    for (int y = y0; y < y1; y++) {
        for (int x = r->window.x1; x < r->window.x2; x++) {
            float rgba[4] = {0.0f, 0.0f, 0.0f, 0.0f}; /* outside the source: transparent black */
            if (r->result && x >= d->x1 && x < d->x2 && y >= d->y1 && y < d->y2) {
                const float *s = r->result + ((size_t)(d->y2 - 1 - y) * (size_t)dw + (size_t)(x - d->x1)) * (size_t)C;
                const float *sp = ew_ofx_image_pixel(&r->src, x, y);
                if (r->src.comps == 1) {
                    rgba[3] = s[0];
                } else {
                    rgba[0] = s[0];
                    rgba[1] = s[1];
                    rgba[2] = s[2];
                    /* alpha filtered along, or passed through, or opaque */
                    rgba[3] = C == 4 ? s[3] : r->src.comps == 4 ? sp[3] : 1.0f;
                }
            }
            float *o = ew_ofx_image_pixel(&r->out, x, y);
            if (r->out.comps == 1)
                o[0] = rgba[3];
            else
                for (int k = 0; k < r->out.comps; k++) o[k] = rgba[k];
        }
    }
}

static OfxStatus write_window(render_job *r) {
    if (ew_ofx_run_bands(r->effect, r->window.y1, r->window.y2, write_rows, r)) return kOfxStatFailed;
    return kOfxStatOK;
}

/* Fetch a clip's image; an image the plugin refuses is reported to the
 * user by the clip's name. */
static OfxStatus fetch(render_job *r, OfxImageClipHandle clip, const char *name, ew_ofx_image *img) {
    OfxStatus st = ew_ofx_image_fetch(clip, r->time, img);
    if (st != kOfxStatOK && img->problem[0])
        ew_ofx_post_error(r->effect, "Edgewise %s: the host's %s image %s", r->node->method, name, img->problem);
    return st;
}

/* ---- the steps ------------------------------------------------------------ */
static OfxStatus read_args(render_job *r, OfxPropertySetHandle in) {
    if (!in) return kOfxStatErrBadHandle;
    int w[4];
    OfxStatus st;
    if ((st = ew_ofx.prop->propGetDouble(in, kOfxPropTime, 0, &r->time)) != kOfxStatOK) return st;
    if ((st = ew_ofx.prop->propGetIntN(in, kOfxImageEffectPropRenderWindow, 4, w)) != kOfxStatOK) return st;
    if (w[2] < w[0] || w[3] < w[1]) return kOfxStatErrValue;
    r->window.x1 = w[0];
    r->window.y1 = w[1];
    r->window.x2 = w[2];
    r->window.y2 = w[3];
    /* Proxies: a radius of 8 at full size is 4 at half size, so the look
     * stays. One factor for both axes (the library's lengths are
     * isotropic): their mean; hosts that omit it render at 1. */
    double s[2];
    if (ew_ofx.prop->propGetDoubleN(in, kOfxImageEffectPropRenderScale, 2, s) == kOfxStatOK && s[0] > 0.0 && s[1] > 0.0)
        r->scale = 0.5 * (s[0] + s[1]);
    else
        r->scale = 1.0;
    return kOfxStatOK;
}

static void clip_window(render_job *r) {
    OfxRectI *w = &r->window;
    const OfxRectI *b = &r->out.bounds;
    if (w->x1 < b->x1) w->x1 = b->x1;
    if (w->y1 < b->y1) w->y1 = b->y1;
    if (w->x2 > b->x2) w->x2 = b->x2;
    if (w->y2 > b->y2) w->y2 = b->y2;
    if (w->x2 < w->x1) w->x2 = w->x1;
    if (w->y2 < w->y1) w->y2 = w->y1;
}

static OfxStatus fetch_features(render_job *r) {
    const ew_ofx_node *n = r->node;
    for (int i = 0; i < n->num_aux; i++) {
        OfxImageClipHandle clip = r->inst->aux[i];
        OfxPropertySetHandle props = NULL;
        int connected = 0;
        if (clip && ew_ofx.effect->clipGetPropertySet(clip, &props) == kOfxStatOK && props)
            ew_ofx.prop->propGetInt(props, kOfxImageClipPropConnected, 0, &connected);
        if (connected) {
            OfxStatus st = fetch(r, clip, n->aux[i].clip, &r->aux[i]);
            /* no image at this time: as if unconnected */
            if (st == kOfxStatFailed) ew_ofx_image_release(&r->aux[i]);
            else if (st != kOfxStatOK) return st;
        }
        if (n->aux[i].required && !r->aux[i].handle) {
            /* a denoiser still denoises without its features (the filter
             * context cannot make them mandatory); a filter cannot */
            if (!strcmp(n->kind, "denoiser")) {
                r->fallback = "bgrid";
                continue;
            }
            ew_ofx_post_error(r->effect, "Edgewise %s: connect the %s clip", n->method, n->aux[i].clip);
            return kOfxStatFailed;
        }
    }
    return kOfxStatOK;
}

/* The render's sample count from the source image, else the Source clip
 * (EW_OFX_PROP_RENDER_SAMPLES); 0 when the host gives none. Hosts without
 * the property answer kOfxStatErrUnknown, which is just "not given". */
static int host_samples(const render_job *r) {
    int v = 0;
    if (r->src.handle && ew_ofx.prop->propGetInt(r->src.handle, EW_OFX_PROP_RENDER_SAMPLES, 0, &v) == kOfxStatOK &&
        v > 0)
        return v;
    OfxPropertySetHandle props = NULL;
    v = 0;
    if (ew_ofx.effect->clipGetPropertySet(r->inst->source, &props) == kOfxStatOK && props &&
        ew_ofx.prop->propGetInt(props, EW_OFX_PROP_RENDER_SAMPLES, 0, &v) == kOfxStatOK && v > 0)
        return v;
    return 0;
}

static OfxStatus run_library(render_job *r) {
    const ew_ofx_node *n = r->node;
    OfxStatus st;
    const int w = r->dom.x2 - r->dom.x1, h = r->dom.y2 - r->dom.y1;
    ew_result e;
    r->method = r->fallback ? r->fallback : n->method;
    r->threads = ew_ofx_thread_count();
    if (!ew_ofx_keep_take(&r->inst->keep, r->method, r->threads, &r->dev, &r->op, &r->generation)) {
        ew_device_desc desc = EW_DEVICE_DESC_INIT;
        desc.num_threads = r->threads;
        if ((e = ew_device_create(&desc, &r->dev)) != EW_OK) return library_status(r, e);
        if ((e = ew_op_create(r->dev, r->method, &r->op)) != EW_OK) return library_status(r, e);
    }
    e = ew_op_set_progress(r->op, progress, r);
    if (e != EW_OK) return library_status(r, e);

    ew_image color = ew_ofx_image_view(&r->src, 0, r->channels);
    if ((e = op_image(r, "color", &color)) != EW_OK) return library_status(r, e);
    /* A feature not given this time is unset, not left over from an
     * earlier frame of a kept op. The fallback gets none: it is guided by
     * the colour alone. */
    for (int i = 0; i < n->num_aux && !r->fallback; i++) {
        ew_image v;
        if (!r->aux[i].handle) {
            if ((e = op_image(r, n->aux[i].image, NULL)) != EW_OK) return library_status(r, e);
            continue;
        }
        if ((st = aux_view(r, i, &n->aux[i], &r->aux[i], &v)) != kOfxStatOK) return st;
        if ((e = op_image(r, n->aux[i].image, &v)) != EW_OK) return library_status(r, e);
    }
    r->result = scratch(r, (size_t)w * (size_t)h * (size_t)r->channels * sizeof(float));
    if (!r->result) return kOfxStatErrMemory;
    ew_image out = ew_image_packed(r->result, w, h, r->channels);
    if ((e = op_image(r, "output", &out)) != EW_OK) return library_status(r, e);

    for (int i = 0; i < n->num_params; i++) {
        double v;
        if ((st = ew_ofx_param_value(r->inst, i, r->time, &v)) != kOfxStatOK) {
            ew_ofx_post_error(r->effect, "Edgewise %s: cannot read parameter %s", n->method, n->params[i].name);
            return st;
        }
        if (r->fallback) continue; /* read at the frame as always; the fallback runs with its defaults */
        if (v == 0.0 && !strcmp(n->params[i].name, "samples")) v = host_samples(r);
        if ((e = op_param(r, &n->params[i], n->param_pixels[i], v)) != EW_OK) return library_status(r, e);
    }
    e = ew_op_commit(r->op);
    if (e == EW_OK) e = ew_op_execute(r->op);
    return library_status(r, e);
}

static OfxStatus render(render_job *r, OfxPropertySetHandle in) {
    OfxStatus st;
    if ((st = read_args(r, in)) != kOfxStatOK) return st;
    if ((st = fetch(r, r->inst->output, kOfxImageEffectOutputClipName, &r->out)) != kOfxStatOK) return st;
    clip_window(r);

    st = fetch(r, r->inst->source, kOfxImageEffectSimpleSourceClipName, &r->src);
    if (st == kOfxStatFailed) {
        /* "assume the image was black and transparent" (clipGetImage) */
        ew_ofx_image_release(&r->src);
        return write_window(r);
    }
    if (st != kOfxStatOK) return st;
    r->dom = r->src.bounds;
    r->channels = r->src.comps < r->node->channels ? r->src.comps : r->node->channels;
    if (r->channels < 3 && r->node->channels == 3) {
        ew_ofx_post_error(r->effect, "Edgewise %s: the Source clip must be RGB or RGBA", r->node->method);
        return kOfxStatErrImageFormat;
    }
    if ((st = fetch_features(r)) != kOfxStatOK) return st;
    if (r->dom.x2 > r->dom.x1 && r->dom.y2 > r->dom.y1) {
        if (ew_ofx.effect->abort && ew_ofx.effect->abort(r->effect)) return kOfxStatFailed;
        if ((st = run_library(r)) != kOfxStatOK) return st;
    }
    return write_window(r);
}

OfxStatus ew_ofx_render(const ew_ofx_node *node, OfxImageEffectHandle effect, OfxPropertySetHandle in) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    render_job r;
    memset(&r, 0, sizeof r);
    r.node = node;
    r.inst = inst;
    r.effect = effect;
    atomic_init(&r.aborted, 0);
    st = render(&r, in);
    finish_op(&r, st);
    cleanup(&r);
    if (st == kOfxStatOK) ew_ofx_clear_error(effect);
    if (st == kOfxStatOK && r.fallback) {
        char text[300];
        snprintf(text, sizeof text,
                 "Edgewise %s needs the Albedo, Normal and Depth clips; without them this frame was denoised by "
                 "the bilateral grid guided by the colour alone",
                 node->method);
        ew_ofx_post_warning(effect, text);
    }
    return st;
}
