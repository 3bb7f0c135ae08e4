#include "method_run.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

void ew_layer_data_free(ew_layer_data *d) {
    ew_host_free(d->color);
    ew_host_free(d->albedo);
    ew_host_free(d->normal);
    ew_host_free(d->depth);
    ew_host_free(d->vector);
    memset(d, 0, sizeof *d);
}

int ew_layer_data_read(ewio_file *f, const ew_layer_passes *lp, ew_layer_data *out, char *err, size_t errlen) {
    memset(out, 0, sizeof *out);
    out->width = ewio_width(f);
    out->height = ewio_height(f);
    /* every pass the layer has, decoded straight into its buffer in one
     * pass over the file (the file keeps none of them: they stay in it) */
    const int vec = !lp->skip_vector && ewio_has_pass(f, lp->layer, "Vector", "XY");
    float **buf[5] = {&out->color, &out->albedo, &out->normal, &out->depth, &out->vector};
    const char *pass[5] = {lp->color, lp->albedo, lp->normal, lp->depth, vec ? "Vector" : NULL};
    static const char *const comps[5] = {"RGB", "RGB", "XYZ", "Z", "XY"};
    ewio_pass_ref refs[5];
    int nref = 0, fail = 0;
    const size_t npix = (size_t)out->width * (size_t)out->height;
    for (int k = 0; k < 5 && !fail; k++) {
        if (!pass[k]) continue;
        *buf[k] = (float *)ew_host_alloc(npix * strlen(comps[k]) * sizeof(float));
        if (!*buf[k]) {
            snprintf(err, errlen, "out of memory");
            fail = 1;
        }
        refs[nref++] = (ewio_pass_ref){lp->layer, pass[k], comps[k], *buf[k]};
    }
    if (!fail) fail = ewio_load_passes(f, refs, nref, err, errlen) != 0;
    if (fail) ew_layer_data_free(out);
    char key[320];
    snprintf(key, sizeof key, "cycles.%s.samples", lp->layer);
    const char *spp = ewio_get_attribute(f, key);
    /* Cycles allows up to 2^24 samples; anything larger (or a number past
     * int) means "very many" rather than wrapping through atoi. */
    long long n = 0;
    if (spp) {
        char *end;
        errno = 0;
        n = strtoll(spp, &end, 10);
        if (end == spp) n = 0;
        else if (errno == ERANGE || n > (1LL << 24)) n = n < 0 ? 0 : 1LL << 24;
    }
    out->samples = n < 0 ? 0 : (int)n;
    return fail;
}

unsigned ew_layer_halves_allowed(const ewio_file *f, const ew_layer_passes *lp) {
    const char *pass[3] = {lp->albedo, lp->normal, lp->depth};
    static const char *const comps[3] = {"RGB", "XYZ", "Z"};
    unsigned bits = 0;
    for (int k = 0; k < 3; k++)
        if (pass[k] && ewio_pass_stored_half(f, lp->layer, pass[k], comps[k]) &&
            ewio_pass_in_source(f, lp->layer, pass[k], comps[k]))
            bits |= 1u << k;
    return bits;
}

int ew_layer_data_to_halves(ew_layer_data *d, unsigned bits) {
    float **buf[3] = {&d->albedo, &d->normal, &d->depth};
    static const size_t channels[3] = {3, 3, 1};
    const size_t npix = (size_t)d->width * (size_t)d->height;
    for (int k = 0; k < 3; k++) {
        const unsigned bit = 1u << k;
        if (!(bits & bit) || (d->halves & bit) || !*buf[k]) continue;
        const size_t n = npix * channels[k];
        uint16_t *h = (uint16_t *)ew_host_alloc(n * sizeof(uint16_t));
        if (!h) return 1;
        ewio_floats_to_half(*buf[k], h, n);
        ew_host_free(*buf[k]);
        *buf[k] = (float *)(void *)h; /* halves from now on (d->halves) */
        d->halves |= bit;
    }
    return 0;
}

/* As the denoisers demodulate (kernels/denoise_px.h): a damaged or negative
 * albedo counts as black, so it cannot turn a pixel into NaN. */
static float albedo_factor(float a) { return (isfinite(a) && a > 0.0f ? a : 0.0f) + EW_ALBEDO_EPSILON; }

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

/* The view of the layer's buffer for an image slot name (the colour:
 * `color`), EW_FORMAT_HALF for a feature it holds as halves; 0 when the
 * layer has none. */
static int slot_view(const ew_layer_data *in, const char *slot, float *color, ew_image *v) {
    float *buf = NULL;
    int ch = 0;
    unsigned half = 0;
    if (!strcmp(slot, "color")) { buf = color; ch = 3; }
    else if (!strcmp(slot, "albedo")) { buf = in->albedo; ch = 3; half = EW_LAYER_HALF_ALBEDO; }
    else if (!strcmp(slot, "normal")) { buf = in->normal; ch = 3; half = EW_LAYER_HALF_NORMAL; }
    else if (!strcmp(slot, "depth")) { buf = in->depth; ch = 1; half = EW_LAYER_HALF_DEPTH; }
    else if (!strcmp(slot, "vector")) { buf = in->vector; ch = 2; }
    if (!buf) return 0;
    *v = ew_image_packed(buf, in->width, in->height, ch);
    if (in->halves & half) {
        v->format = EW_FORMAT_HALF;
        v->pixel_stride = v->row_stride = EW_STRIDE_PACKED;
    }
    return 1;
}

/* The method's parameter called `name` (0 if it has none). */
static int find_param(const ew_method_spec *spec, const char *name, ew_param_info *p) {
    for (int32_t k = 0; ew_method_param(spec->kind, spec->name, k, p) == EW_OK; k++)
        if (!strcmp(p->name, name)) return 1;
    return 0;
}

/* A value given as a number, set as the parameter's declared type (an
 * unknown name goes to set_float, whose error names the known ones). */
static ew_result set_number(ew_op *op, const ew_method_spec *spec, const char *name, float v) {
    ew_param_info p;
    if (find_param(spec, name, &p) && p.type != EW_PARAM_FLOAT) return ew_op_set_int(op, name, (int32_t)v);
    return ew_op_set_float(op, name, v);
}

/* The default of a parameter of the denoisers (the first one listed), or
 * `fallback`: what a filter used as a denoiser gets for the do-no-harm
 * stage's parameters. */
static float denoiser_default(const char *name, float fallback) {
    const char *d;
    ew_param_info p;
    if (ew_method_get("denoiser", 0, &d, NULL, NULL, NULL) != EW_OK) return fallback;
    for (int32_t k = 0; ew_method_param("denoiser", d, k, &p) == EW_OK; k++)
        if (!strcmp(p.name, name)) return p.default_value;
    return fallback;
}

/* The features the committed op reads as halves where they are, among
 * those the layer may hold so (spec->halves_allowed), converted in
 * spec->holds, set as half views and the op committed again. */
static ew_result rebind_halves(ew_op *op, const ew_method_spec *spec, ew_image *views, int32_t num_images) {
    static const char *const slots[3] = {"albedo", "normal", "depth"};
    unsigned bits = 0;
    for (int k = 0; k < 3; k++) {
        uint32_t fl = 0;
        if ((spec->halves_allowed & (1u << k)) && ew_op_image_flags(op, slots[k], &fl) == EW_OK &&
            (fl & EW_IMAGE_HALF_IN_PLACE))
            bits |= 1u << k;
    }
    bits &= ~spec->holds->halves;
    if (!bits) return EW_OK;
    if (ew_layer_data_to_halves(spec->holds, bits) != 0) return EW_ERR_OUT_OF_MEMORY;
    ew_result r = EW_OK;
    for (int32_t i = 0; r == EW_OK && i < num_images && i < 8; i++) {
        ew_image_info info;
        ew_method_image(spec->kind, spec->name, i, &info);
        if (slot_view(spec->holds, info.name, NULL, &views[i]) && views[i].format == EW_FORMAT_HALF)
            r = ew_op_set_image(op, info.name, &views[i]);
    }
    return r == EW_OK ? ew_op_commit(op) : r;
}

int ew_method_run(ew_device *dev, const ew_method_spec *spec, const ew_layer_data *in, float *out, double *ms,
                  char *err, size_t errlen) {
    const int w = in->width, h = in->height;
    const size_t n = (size_t)w * h;
    *ms = 0.0;
    if (errlen) err[0] = '\0';
    if (!spec->kind) { /* identity: the noisy input */
        if (out != in->color) memcpy(out, in->color, n * 3 * sizeof(float));
        return 0;
    }
    const int is_filter = !strcmp(spec->kind, "filter");
    const int demod = is_filter && spec->demodulate && in->albedo;
    if (is_filter && spec->demodulate && (!in->albedo || (in->halves & EW_LAYER_HALF_ALBEDO))) {
        snprintf(err, errlen, "%s: needs an albedo pass (as floats) to demodulate", spec->label);
        return 1;
    }
    float *color = in->color;
    if (demod) {
        color = out; /* demodulate into out, filter in place */
        for (size_t i = 0; i < n * 3; i++) out[i] = in->color[i] / albedo_factor(in->albedo[i]);
    }
    ew_op *op = NULL;
    ew_result r = ew_op_create(dev, spec->name, &op);
    if (r != EW_OK) {
        snprintf(err, errlen, "%s: %s", spec->label, ew_device_last_error(dev));
        return 1;
    }

    int32_t num_images = 0;
    for (int32_t i = 0; i < ew_method_count(spec->kind); i++) {
        const char *nm;
        int32_t ni;
        ew_method_get(spec->kind, i, &nm, NULL, &ni, NULL);
        if (!strcmp(nm, spec->name)) num_images = ni;
    }
    ew_image views[8];
    for (int32_t i = 0; r == EW_OK && i < num_images && i < 8; i++) {
        ew_image_info info;
        ew_method_image(spec->kind, spec->name, i, &info);
        if (!strcmp(info.name, "output")) {
            views[i] = ew_image_packed(out, w, h, 3);
        } else if (!slot_view(in, info.name, color, &views[i])) {
            if (info.required) {
                snprintf(err, errlen, "%s: the layer has no pass for the required image '%s'", spec->label, info.name);
                r = EW_ERR_INVALID_ARGUMENT;
            }
            continue;
        }
        r = ew_op_set_image(op, info.name, &views[i]);
    }
    /* A filter on demodulated colour is a filter used as a denoiser: it
     * runs with the denoisers' do-no-harm stage (the filter's own default
     * is off: it may smooth on purpose). The spec's parameters still win. */
    ew_param_info hp;
    if (r == EW_OK && demod && find_param(spec, "do_no_harm", &hp)) {
        r = ew_op_set_int(op, "do_no_harm", (int32_t)denoiser_default("do_no_harm", 1.0f));
        if (r == EW_OK) r = ew_op_set_float(op, "outlier_k", denoiser_default("outlier_k", 0.0f));
    }
    int samples_set = 0;
    for (int k = 0; r == EW_OK && k < spec->num_params; k++) {
        r = set_number(op, spec, spec->param_names[k], spec->param_values[k]);
        samples_set |= !strcmp(spec->param_names[k], "samples");
    }
    ew_param_info sp;
    if (r == EW_OK && !samples_set && in->samples > 0 && find_param(spec, "samples", &sp))
        r = ew_op_set_int(op, "samples", in->samples);
    if (r == EW_OK && spec->data_name) r = ew_op_set_data(op, spec->data_name, spec->data, spec->data_size);
    if (r == EW_OK && spec->progress) r = ew_op_set_progress(op, spec->progress, spec->progress_user);
    double t0 = now_ms();
    if (r == EW_OK) r = ew_op_commit(op);
    if (r == EW_OK && spec->holds == in && spec->halves_allowed) r = rebind_halves(op, spec, views, num_images);
    if (r == EW_OK) r = ew_op_execute(op);
    *ms = now_ms() - t0;
    if (r == EW_OK && spec->warm_ms && spec->warm_runs > 0 && color != out) {
        ew_op_set_progress(op, NULL, NULL);
        for (int k = 0; r == EW_OK && k < spec->warm_runs; k++) {
            double tw = now_ms();
            r = ew_op_execute(op);
            tw = now_ms() - tw;
            if (k == 0 || tw < *spec->warm_ms) *spec->warm_ms = tw;
        }
    }
    if (r == EW_OK && spec->chosen && spec->chosen_len) {
        const char *what = ew_op_describe(op);
        snprintf(spec->chosen, spec->chosen_len, "%s", what ? what : spec->name);
    }
    if (r != EW_OK && !err[0]) snprintf(err, errlen, "%s: %s", spec->label, ew_device_last_error(dev));
    ew_op_destroy(op);
    if (r == EW_OK && demod)
        for (size_t i = 0; i < n * 3; i++) out[i] *= albedo_factor(in->albedo[i]);
    return r != EW_OK;
}
