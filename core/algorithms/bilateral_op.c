/*
 * bilateral_op.c — commit/execute shared by the filters "bilateral" (brute
 * force, exact), "separable" and "pyramid".
 */
#include "algorithms/bilateral_op.h"

#include <stdlib.h>
#include <string.h>

#include "src/backend.h"

typedef struct {
    ew_bf_method method;
    ew_bf_model model;
    int w, h, guide_is_color, depth_from_color;
    float *image, *attr, *out, *tmp;
    ew_pyr_plan plan;
    ew_pyr_table table;
    float mem[];
} state;

ew_result ew_pyr_op_set_data(ew_op *op, const char *name, const void *data, size_t size) {
    if (strcmp(name, "weights") != 0)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "unknown data '%s' for %s '%s' (weights)", name,
                        op->type->kind, op->type->name);
    ew_pyr_op_release_data(op);
    if (!data) return EW_OK;
    ew_pyr_table *t = (ew_pyr_table *)malloc(sizeof *t);
    if (!t) return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory");
    char why[200];
    if (ew_pyr_table_parse(data, size, t, why, sizeof why) != EW_OK) {
        free(t);
        return ew__fail(op->dev, EW_ERR_INVALID_DATA, "data 'weights': %s", why);
    }
    op->data_state = t;
    return EW_OK;
}

void ew_pyr_op_release_data(ew_op *op) {
    free(op->data_state);
    op->data_state = NULL;
}

ew_result ew_bf_op_table(ew_op *op, int trained, int kind, ew_pyr_table *table, const ew_pyr_table **out) {
    *out = NULL;
    if (op->data_state) {
        *table = *(const ew_pyr_table *)op->data_state;
        *out = table;
        return EW_OK;
    }
    if (!trained) return EW_OK;
    char why[256];
    if (ew_pyr_builtin_table(kind, table, why, sizeof why) != EW_OK)
        return ew__fail(op->dev, EW_ERR_INVALID_DATA, "parameter 'weights' = 1 (trained): %s; use 'weights' = 0", why);
    *out = table;
    return EW_OK;
}

void ew_bf_op_alpha_guides(const ew_op *op, ew_op *alpha_op) {
    const ew_image *color = ew_op_image(op, "color");
    const int model = (int)ew_op_param(op, "model"); /* kinds[] of ew_bf_op_commit */
    if (model == 0 && !ew_op_image(op, "guide")) ew_op_set_image(alpha_op, "guide", color);
    if (model == 2 && !ew_op_image(op, "depth")) ew_op_set_image(alpha_op, "depth", color);
}

ew_result ew_bf_op_commit(ew_op *op, ew_bf_method method) {
    ew_device *dev = op->dev;
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    const ew_image *guide = ew_op_image(op, "guide"), *normal = ew_op_image(op, "normal");
    const ew_image *depth = ew_op_image(op, "depth");
    const int w = color->width, h = color->height, C = color->channels;
    if (C > EW_BF_MAX_CH)
        return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "image 'color' has %d channels; at most %d are supported", C,
                        EW_BF_MAX_CH);
    if (output->channels < C)
        return ew__fail(dev, EW_ERR_INVALID_ARGUMENT, "image 'output' has %d channels but 'color' has %d",
                        output->channels, C);
    ew_bf_model m;
    memset(&m, 0, sizeof m);
    static const int kinds[] = {EW_RANGE_COLOR, EW_RANGE_GI, EW_RANGE_DEPTH, EW_RANGE_NONE}; /* "model" 0..3 */
    m.kind = kinds[(int)ew_op_param(op, "model")];
    m.channels = C;
    m.radius = (int)ew_op_param(op, "radius");
    float ss = ew_op_param(op, "sigma_spatial");
    m.sigma = ss > 0.0f ? ss : (float)m.radius / 3.0f;
    float sr = ew_op_param(op, "sigma_range");
    m.inv_2sr2 = 1.0f / (2.0f * sr * sr);
    m.sigma_alpha = (float)(m.radius > 0 ? m.radius - 1 : 0);
    m.sigma_n = ew_op_param(op, "sigma_normal");
    m.sigma_z = ew_op_param(op, "sigma_depth");
    m.use_roughness = ew_op_image(op, "roughness") != NULL;
    if (m.kind == EW_RANGE_GI && !normal && !depth)
        return ew__fail(dev, EW_ERR_INVALID_STATE,
                        "parameter 'model' = gi (GI denoising) needs a 'normal' and/or a 'depth' image");
    if (m.kind == EW_RANGE_GI && m.radius == 0) m.sigma_alpha = 0.0f;
    m.attrs = ew_bf_attrs(m.kind);
    /* radius 0 means no filtering at all, whatever the model */
    if (m.radius == 0) {
        m.sigma = 0.0f;
        m.sigma_alpha = 0.0f;
    }

    int levels = 0;
    ew_pyr_table tbl;
    const ew_pyr_table *table = NULL;
    /* one sigma for every pixel, so weight rows rather than the per-pixel
     * table: all but GI with a roughness image (diffuse GI's sigma is
     * (s_alpha + 1) / 3 everywhere) */
    const int uniform = m.kind != EW_RANGE_GI || !m.use_roughness;
    ew_bf_model pm = m; /* the plan's model: GI's uniform sigma in .sigma (GI's range ignores it) */
    if (m.kind == EW_RANGE_GI) pm.sigma = (m.sigma_alpha + 1.0f) / 3.0f;
    if (method == EW_BF_PYRAMID) {
        ew_result r = ew_bf_op_table(op, (int)ew_op_param(op, "weights"), m.kind, &tbl, &table);
        if (r != EW_OK) return r;
        levels = m.radius == 0 ? 0 : ew_pyr_levels(ew_pyr_sigma_max(&m), w, h);
    }
    const size_t n = (size_t)w * (size_t)h;
    /* the pyramid packs into its plan's planes; the others use interleaved buffers */
    size_t need = method == EW_BF_PYRAMID ? 0 : n * (size_t)(2 * EW_BF_CH + m.attrs);
    if (method == EW_BF_SEPARABLE) need += n * (size_t)EW_BF_CH;
    /* the pyramid's result drained from bands on the CPU (ew_pyr_band_threads) */
    const int band_threads = method == EW_BF_PYRAMID ? ew_pyr_band_threads(dev, w, h) : 0;
    if (method == EW_BF_PYRAMID) need += ew_pyr_scratch_floats_banded(&m, w, h, levels, uniform, band_threads);
    state *s = (state *)ew_op_state_block(op, sizeof(state) + need * sizeof(float));
    if (!s)
        return ew__fail(dev, EW_ERR_OUT_OF_MEMORY, "out of memory: filtering %dx%d needs %.1f MiB", w, h,
                        (double)need * sizeof(float) / 1048576.0);
    s->method = method;
    s->model = m;
    s->w = w;
    s->h = h;
    s->guide_is_color = m.kind == EW_RANGE_COLOR && !guide;
    s->depth_from_color = m.kind == EW_RANGE_DEPTH && !depth;
    float *p = s->mem;
    s->image = s->out = s->attr = s->tmp = NULL;
    if (method != EW_BF_PYRAMID) {
        s->image = p;
        p += n * (size_t)EW_BF_CH;
        s->out = p;
        p += n * (size_t)EW_BF_CH;
        s->attr = p;
        p += n * (size_t)m.attrs;
    }
    if (method == EW_BF_SEPARABLE) {
        s->tmp = p;
        p += n * (size_t)EW_BF_CH;
    }
    if (method == EW_BF_PYRAMID) {
        if (table) {
            s->table = tbl;
            table = &s->table;
        }
        ew_pyr_plan_init_banded(&s->plan, &pm, w, h, levels, uniform, table, 1.0f, p, band_threads);
        /* the paper's analytic setting uses gamma = 0 for diffuse GI */
        if (!table && m.kind == EW_RANGE_GI && !m.use_roughness)
            ew_pyr_plan_init_banded(&s->plan, &pm, w, h, levels, uniform, NULL, 0.0f, p, band_threads);
    }
    return EW_OK;
}

static int report(void *user, double f) { return ew_op_report((ew_op *)user, f); }

ew_result ew_bf_op_execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    const ew_bf_model *m = &s->model;
    const ew_image *color = ew_op_image(op, "color");
    /* the pyramid's planes, packed inside its first pass; interleaved
     * buffers, packed now, for the others */
    const int planes = s->method == EW_BF_PYRAMID;
    float *image = planes ? s->plan.down[0] : s->image, *attr = planes ? s->plan.attr[0] : s->attr;
    ew_bf_io_set fill = {0};
    ew_bf_io_pack_image(&fill, color, m->channels, image, planes);
    switch (m->kind) {
    case EW_RANGE_COLOR:
        ew_bf_io_pack_channels(&fill, s->guide_is_color ? color : ew_op_image(op, "guide"), 4, attr, planes);
        break;
    case EW_RANGE_GI:
        ew_bf_io_pack_gi(&fill, ew_op_image(op, "normal"), ew_op_image(op, "depth"), ew_op_image(op, "roughness"),
                         attr, planes);
        break;
    case EW_RANGE_DEPTH:
        ew_bf_io_pack_channels(&fill, s->depth_from_color ? color : ew_op_image(op, "depth"), 1, attr, planes);
        break;
    default:
        break;
    }
    if (planes) { /* unpacks inside its last pass too */
        ew_bf_io_set drain = {0};
        ew_bf_io_unpack_band(&drain, s->plan.out, s->plan.band, s->plan.band_stride, m->channels,
                             ew_op_image(op, "output"), color);
        const ew_pyr_io io = {ew_bf_io_fill, &fill, ew_bf_io_rows, &drain};
        if (!ew_pyr_run_planes(dev, &s->plan, &io, report, op)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
        return EW_OK;
    }
    ew_bf_io_run(dev, &fill, color);
    switch (s->method) {
    case EW_BF_BRUTE: {
        /* bands of rows, so a long run reports progress and can stop */
        const int band = 16;
        for (int y = 0; y < s->h; y += band) {
            ew_bf_buffers b = {s->w, s->h, s->image, s->attr, s->out, y, y + band < s->h ? y + band : s->h};
            ew_bilateral_brute_rows(dev, m, &b);
            if (!ew_op_report(op, (double)b.y1 / s->h * 0.99))
                return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
        }
        break;
    }
    default: /* EW_BF_SEPARABLE */
        ew_bilateral_separable(dev, m, s->w, s->h, s->image, s->attr, s->tmp, s->out);
        break;
    }
    ew_bf_unpack_image(dev, s->out, m->channels, ew_op_image(op, "output"), color);
    return EW_OK;
}

void ew_bf_op_release(ew_op *op) {
    free(op->state);
    op->state = NULL;
    op->state_bytes = 0;
}
