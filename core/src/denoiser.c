/*
 * denoiser.c — the ew_denoiser object: images and parameters by name,
 * commit (validate, allocate scratch), execute (no allocation).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "algorithms/bgrid.h"
#include "src/backend.h"
#include "src/internal.h"

enum { IMG_COLOR, IMG_ALBEDO, IMG_NORMAL, IMG_DEPTH, IMG_OUTPUT, IMG_COUNT };
static const char *const image_names[IMG_COUNT] = {"color", "albedo", "normal", "depth", "output"};
static const int image_min_channels[IMG_COUNT] = {3, 3, 3, 1, 3};

struct ew_denoiser {
    ew_device *dev;
    ew_image images[IMG_COUNT];
    int has_image[IMG_COUNT];
    float spatial_rate, range_rate;
    ew_progress_fn progress;
    void *progress_user;
    int committed;
    /* scratch, sized at commit */
    ew_bgrid_params grid_params;
    float *scratch;
    size_t scratch_floats;
    ew_denoise_buffers buf;
    float *grid;
};

#define BGRID_DEFAULT_SPATIAL_RATE 8.0f
#define BGRID_DEFAULT_RANGE_RATE 8.0f

ew_result ew_denoiser_create(ew_device *dev, const char *method, ew_denoiser **out) {
    if (!out) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "ew_denoiser_create: out is NULL");
    *out = NULL;
    if (!dev) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(dev);
    if (!method) return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "ew_denoiser_create: method is NULL");
    if (strcmp(method, "bgrid") != 0)
        return ew__fail(dev, EW_ERR_UNSUPPORTED, "unknown denoising method '%s' (available: bgrid)", method);
    ew_denoiser *d = (ew_denoiser *)calloc(1, sizeof *d);
    if (!d) return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory creating a denoiser");
    d->dev = dev;
    d->spatial_rate = BGRID_DEFAULT_SPATIAL_RATE;
    d->range_rate = BGRID_DEFAULT_RANGE_RATE;
    *out = d;
    return EW_OK;
}

static void release_scratch(ew_denoiser *d) {
    free(d->scratch);
    d->scratch = NULL;
    d->scratch_floats = 0;
    d->committed = 0;
}

void ew_denoiser_destroy(ew_denoiser *d) {
    if (!d) return;
    release_scratch(d);
    free(d);
}

ew_result ew_denoiser_set_image(ew_denoiser *d, const char *name, const ew_image *view) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(d->dev);
    for (int i = 0; name && i < IMG_COUNT; i++) {
        if (strcmp(name, image_names[i]) != 0) continue;
        if (view) {
            const char *why;
            if (!ew__image_valid(view, &why))
                return ew__fail(d->dev, EW_ERR_INVALID_ARGUMENT, "image '%s': %s", name, why);
            if (view->channels < image_min_channels[i])
                return ew__fail(d->dev, EW_ERR_INVALID_ARGUMENT, "image '%s' needs at least %d channels, got %d",
                                name, image_min_channels[i], view->channels);
            d->images[i] = *view;
        }
        d->has_image[i] = view != NULL;
        d->committed = 0;
        return EW_OK;
    }
    return ew__fail(d->dev, EW_ERR_INVALID_ARGUMENT,
                    "unknown image '%s' (color, albedo, normal, depth, output)", name ? name : "(null)");
}

ew_result ew_denoiser_set_int(ew_denoiser *d, const char *name, int32_t value) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    return ew_denoiser_set_float(d, name, (float)value);
}

ew_result ew_denoiser_set_float(ew_denoiser *d, const char *name, float value) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    ew__clear_error(d->dev);
    float *slot = NULL;
    if (name && strcmp(name, "spatial_rate") == 0) slot = &d->spatial_rate;
    else if (name && strcmp(name, "range_rate") == 0) slot = &d->range_rate;
    else
        return ew__fail(d->dev, EW_ERR_INVALID_ARGUMENT,
                        "unknown parameter '%s' for method bgrid (spatial_rate, range_rate)", name ? name : "(null)");
    if (!(value >= 1.0f && value <= 256.0f))
        return ew__fail(d->dev, EW_ERR_INVALID_ARGUMENT, "parameter '%s' = %g is outside [1, 256]", name, (double)value);
    *slot = value;
    d->committed = 0;
    return EW_OK;
}

ew_result ew_denoiser_set_progress(ew_denoiser *d, ew_progress_fn fn, void *user) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    d->progress = fn;
    d->progress_user = user;
    return EW_OK;
}

ew_result ew_denoiser_commit(ew_denoiser *d) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    ew_device *dev = d->dev;
    ew__clear_error(dev);
    if (!d->has_image[IMG_COLOR]) return ew__fail(dev, EW_ERR_INVALID_STATE, "no 'color' image set");
    if (!d->has_image[IMG_OUTPUT]) return ew__fail(dev, EW_ERR_INVALID_STATE, "no 'output' image set");
    const int w = d->images[IMG_COLOR].width, h = d->images[IMG_COLOR].height;
    for (int i = 1; i < IMG_COUNT; i++) {
        if (!d->has_image[i]) continue;
        if (d->images[i].width != w || d->images[i].height != h)
            return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "image '%s' is %dx%d but 'color' is %dx%d",
                            image_names[i], d->images[i].width, d->images[i].height, w, h);
    }
    ew_bgrid_params gp;
    if (!ew_bgrid_params_init(&gp, w, h, d->spatial_rate, d->range_rate, 3))
        return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "invalid grid parameters");

    /* packed copies of the inputs (views may have any stride, and the output
     * may alias the colour), then radiance, guide, sliced result, grid */
    const size_t n = (size_t)w * (size_t)h;
    size_t need = n * 3 /*color*/ + n * 3 /*radiance*/ + n /*guide*/ + n * 3 /*sliced*/ + n * 3 /*out*/;
    if (d->has_image[IMG_ALBEDO]) need += n * 3;
    if (d->has_image[IMG_NORMAL]) need += n * 3;
    if (d->has_image[IMG_DEPTH]) need += n;
    need += ew_bgrid_floats(&gp);

    if (need != d->scratch_floats) {
        release_scratch(d);
        d->scratch = (float *)malloc(need * sizeof(float));
        if (!d->scratch)
            return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory: denoising %dx%d needs %.1f MiB", w, h,
                            (double)need * sizeof(float) / 1048576.0);
        d->scratch_floats = need;
    }
    float *s = d->scratch;
    ew_denoise_buffers *b = &d->buf;
    memset(b, 0, sizeof *b);
    b->width = w;
    b->height = h;
    b->color = s; s += n * 3;
    b->radiance = s; s += n * 3;
    b->guide = s; s += n;
    b->sliced = s; s += n * 3;
    b->out = s; s += n * 3;
    if (d->has_image[IMG_ALBEDO]) { b->albedo = s; s += n * 3; }
    if (d->has_image[IMG_NORMAL]) { b->normal = s; s += n * 3; }
    if (d->has_image[IMG_DEPTH]) { b->depth = s; s += n; }
    d->grid = s;
    d->grid_params = gp;
    d->committed = 1;
    return EW_OK;
}

/* Copy the first `c` channels of a view into a packed buffer. */
static void pack(const ew_image *img, int c, float *dst) {
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *p = ew__pixel(img, x, y);
            for (int k = 0; k < c; k++) *dst++ = p[k];
        }
}

static void unpack(const float *src, int c, const ew_image *img) {
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = ew__pixel(img, x, y);
            for (int k = 0; k < c; k++) p[k] = *src++;
        }
}

/* Background pixels have Depth 1e10 (Depth pass) or 0 (Denoising Depth):
 * normalise by the largest depth below 1e9 so the scene uses the range. */
static float depth_scale(const float *depth, size_t n) {
    float mx = 0.0f;
    for (size_t i = 0; i < n; i++)
        if (isfinite(depth[i]) && depth[i] < 1e9f && depth[i] > mx) mx = depth[i];
    return mx > 0.0f ? 1.0f / mx : 1.0f;
}

static int report(ew_denoiser *d, double f) {
    return d->progress ? d->progress(d->progress_user, f) : 1;
}

ew_result ew_denoiser_execute(ew_denoiser *d) {
    if (!d) return EW_ERR_INVALID_ARGUMENT;
    ew_device *dev = d->dev;
    ew__clear_error(dev);
    if (!d->committed) return ew__fail(dev, EW_ERR_INVALID_STATE, "ew_denoiser_execute called before ew_denoiser_commit");
    ew_denoise_buffers *b = &d->buf;
    const size_t n = (size_t)b->width * (size_t)b->height;
    if (!report(d, 0.0)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    pack(&d->images[IMG_COLOR], 3, (float *)b->color);
    if (b->albedo) pack(&d->images[IMG_ALBEDO], 3, (float *)b->albedo);
    if (b->normal) pack(&d->images[IMG_NORMAL], 3, (float *)b->normal);
    if (b->depth) {
        pack(&d->images[IMG_DEPTH], 1, (float *)b->depth);
        b->depth_scale = depth_scale(b->depth, n);
    }
    dev->backend->denoise_prepare(dev, b);
    if (!report(d, 0.2)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    ew_bgrid_splat(dev, &d->grid_params, b->radiance, b->guide, d->grid);
    if (!report(d, 0.6)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
    ew_bgrid_slice(dev, &d->grid_params, d->grid, b->guide, b->sliced);
    dev->backend->denoise_finish(dev, b);
    unpack(b->out, 3, &d->images[IMG_OUTPUT]);
    report(d, 1.0);
    return EW_OK;
}
