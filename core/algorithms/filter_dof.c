/*
 * filter "dof": depth of field from a depth pass and the values of a Blender
 * camera (focal length, f-stop, focus distance, sensor width): thin-lens CoC
 * per pixel, then the pyramid filter with the DoF functions of Eq. 8, so a
 * blurred background stays behind a sharp foreground and a blurred
 * foreground spreads over a sharp background (§4.1; see kernels/dof.h).
 */
#include <stdlib.h>
#include <string.h>

#include "algorithms/bilateral.h"
#include "algorithms/bilateral_op.h"
#include "algorithms/dof.h"
#include "algorithms/pyramid.h"
#include "src/op.h"

static const ew_image_desc images[] = {
    {"color", 1, 1, "sharp (pinhole) image, 1 to 4 channels, linear; a 4th is premultiplied alpha, blurred with the colour"},
    {"depth", 1, 1, "planar camera depth in metres (Cycles: Depth pass); non-finite or <= 0 = infinitely far"},
    {"coc", 1, 0, "written when set: signed circle-of-confusion diameter in pixels (negative in front of focus)"},
    {"output", 1, 1, "image with depth of field, as many channels as the colour; may be the colour view"},
};

static const ew_param_desc params[] = {
    {"focal_length", EW_PARAM_FLOAT, 50.0f, 1.0f, 5000.0f, "lens focal length in mm (Blender: Camera > Focal Length)"},
    {"fstop", EW_PARAM_FLOAT, 2.8f, 0.1f, 1024.0f, "aperture f-number (Blender: Depth of Field > F-Stop)"},
    {"focus_distance", EW_PARAM_FLOAT, 10.0f, 0.01f, 1e6f, "distance in focus, metres (Blender: Focus Distance)"},
    {"sensor_width", EW_PARAM_FLOAT, 36.0f, 1.0f, 1000.0f,
     "sensor size in mm along the larger image side (Blender: Sensor Fit Auto, Size)"},
    {"radius", EW_PARAM_INT, 32.0f, 1.0f, 128.0f,
     "largest kernel radius in pixels (the lens's CoC is capped at 2 radius / blur_scale)"},
    {"blur_scale", EW_PARAM_FLOAT, 2.1213203f, 0.1f, 10.0f,
     "Eq. 8's CoC per pixel of the lens's CoC; 3 sqrt(2) / 2 gives a real lens's blur size (see docs/filters.md)"},
    {"sigma_spatial", EW_PARAM_FLOAT, 0.0f, 0.0f, 256.0f,
     "extra domain Gaussian sigma of Eq. 8 that limits every blur; 0 = none"},
    {"method", EW_PARAM_INT, 0.0f, 0.0f, 2.0f, "pyramid (fast), bilateral (exact, slow) or separable"},
    EW_PYR_WEIGHTS_PARAM,
};

typedef struct {
    int w, h, C, method;
    ew_bf_model model;
    ew_dof_camera cam;
    float *image, *depth, *out, *tmp, *coc, *tiles, *attr;
    ew_pyr_plan plan;
    ew_pyr_table table;
    float mem[];
} state;

static void release(ew_op *op) {
    free(op->state);
    op->state = NULL;
    op->state_bytes = 0;
}

static ew_result commit(ew_op *op) {
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    const int w = color->width, h = color->height, C = color->channels;
    if (C > EW_BF_MAX_CH)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image 'color' has %d channels; at most %d are supported",
                        C, EW_BF_MAX_CH);
    if (output->channels < C)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT, "image 'output' has %d channels but 'color' has %d",
                        output->channels, C);
    const float f = ew_op_param(op, "focal_length"), fd = ew_op_param(op, "focus_distance");
    if (fd * 1000.0f <= f)
        return ew__fail(op->dev, EW_ERR_INVALID_ARGUMENT,
                        "parameter 'focus_distance' = %g m is not beyond the focal length %g mm: nothing can be in focus",
                        (double)fd, (double)f);
    ew_bf_model m;
    memset(&m, 0, sizeof m);
    m.kind = EW_RANGE_DOF;
    m.channels = C;
    m.attrs = 2;
    m.radius = (int)ew_op_param(op, "radius");
    m.sigma = ew_op_param(op, "sigma_spatial");
    const int method = (int)ew_op_param(op, "method");
    ew_pyr_table tbl;
    const ew_pyr_table *table = NULL;
    int levels = 0;
    if (method == 0) {
        ew_result r = ew_bf_op_table(op, (int)ew_op_param(op, "weights"), EW_RANGE_DOF, &tbl, &table);
        if (r != EW_OK) return r;
        levels = ew_pyr_levels(ew_pyr_sigma_max(&m), w, h);
    }
    const size_t n = (size_t)w * (size_t)h;
    size_t need = n * (size_t)(2 * EW_BF_CH + 1) + ew_dof_scratch_floats(w, h);
    if (method == 2) need += n * (size_t)EW_BF_CH;
    /* the pyramid's result drained from bands on the CPU (ew_pyr_band_threads) */
    const int band_threads = method == 0 ? ew_pyr_band_threads(op->dev, w, h) : 0;
    if (method == 0) need += ew_pyr_scratch_floats_banded(&m, w, h, levels, 0, band_threads);
    state *s = (state *)ew_op_state_block(op, sizeof(state) + need * sizeof(float));
    if (!s)
        return ew__fail(op->dev, EW_ERR_OUT_OF_MEMORY, "out of memory: depth of field at %dx%d needs %.1f MiB", w, h,
                        (double)need * sizeof(float) / 1048576.0);
    s->w = w;
    s->h = h;
    s->C = C;
    s->method = method;
    s->model = m;
    s->cam.focal_mm = f;
    s->cam.fstop = ew_op_param(op, "fstop");
    s->cam.focus_m = fd;
    s->cam.sensor_mm = ew_op_param(op, "sensor_width");
    s->cam.width = w;
    s->cam.height = h;
    s->cam.scale = ew_op_param(op, "blur_scale");
    s->cam.max_coc = 2.0f * (float)m.radius / s->cam.scale;
    float *p = s->mem;
    s->image = p; p += n * (size_t)EW_BF_CH;
    s->out = p; p += n * (size_t)EW_BF_CH;
    s->depth = p; p += n;
    s->coc = p; p += n;
    s->attr = p; p += n * 2;
    s->tiles = p; p += ew_dof_scratch_floats(w, h) - 3 * n;
    s->tmp = NULL;
    if (method == 2) {
        s->tmp = p;
        p += n * (size_t)EW_BF_CH;
    }
    if (method == 0) {
        if (table) {
            s->table = tbl;
            table = &s->table;
        }
        ew_pyr_plan_init_banded(&s->plan, &m, w, h, levels, 0, table, 1.0f, p, band_threads);
    }
    return EW_OK;
}

static int report(void *user, double f) { return ew_op_report((ew_op *)user, f); }

/* The pyramid's fill when it holds its input in bands: the colour packed,
 * (D, C) computed row by row from the CoC and the tiles. */
typedef struct {
    ew_bf_io_set set;
    ew_dof_args args;
} dof_fill;

static void fill_rows(void *user, int y0, int y1, int tid, float *planes, long ps, long row0) {
    dof_fill *f = (dof_fill *)user;
    ew_bf_io_fill(&f->set, y0, y1, tid, planes, ps, row0);
    ew_dof_attr_rows(&f->args, y0, y1, planes + EW_BF_CH * ps, ps, row0);
}

static ew_result execute(ew_op *op) {
    state *s = (state *)op->state;
    ew_device *dev = op->dev;
    const int planes = s->method == 0; /* the pyramid packs and unpacks inside its first and last pass */
    const ew_image *color = ew_op_image(op, "color"), *output = ew_op_image(op, "output");
    if (!planes) ew_bf_pack_image(dev, color, s->C, s->image);
    /* A depth view of packed floats is read where it is; others are packed
     * on the device's threads, as the colour (the copies were a tenth of the
     * pyramid's wall time on one thread). A non-finite depth, or the 0 the
     * packer makes of it, means infinitely far alike (ew_dof_coc). */
    const ew_image *dv = ew_op_image(op, "depth");
    const float *depth = s->depth;
    if (ew__image_packed_as(dv, 1)) depth = (const float *)dv->data;
    else ew_bf_pack_channels(dev, dv, 1, s->depth, NULL);
    /* the pyramid's (D, C) straight into its planes, or, when it holds its
     * input in bands, row by row as its passes fill them (no frame of them) */
    const int in_bands = planes && s->plan.in;
    dof_fill fill;
    memset(&fill, 0, sizeof fill);
    ew_dof_args_init(&fill.args, &s->cam, depth, s->coc, s->tiles, in_bands ? NULL : planes ? s->plan.attr[0] : s->attr,
                     planes);
    ew_dof_compute_attributes(dev, &s->cam, depth, s->coc, s->tiles, fill.args.attr, planes);
    switch (s->method) {
    case 0: {
        ew_bf_io_set drain = {0};
        ew_bf_io_pack_image(&fill.set, color, s->C, s->plan.down[0], 1);
        ew_bf_io_unpack_band(&drain, s->plan.out, s->plan.band, s->plan.band_stride, s->C, output, color);
        const ew_pyr_io io = {in_bands ? fill_rows : ew_bf_io_fill, in_bands ? (void *)&fill : (void *)&fill.set,
                              ew_bf_io_rows, &drain};
        if (!ew_pyr_run_planes(dev, &s->plan, &io, report, op)) return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
        break;
    }
    case 1: {
        const int band = 16;
        for (int y = 0; y < s->h; y += band) {
            ew_bf_buffers b = {s->w, s->h, s->image, s->attr, s->out, y, y + band < s->h ? y + band : s->h};
            ew_bilateral_brute_rows(dev, &s->model, &b);
            if (!ew_op_report(op, (double)b.y1 / s->h * 0.99))
                return ew__fail(dev, EW_ERR_CANCELLED, "cancelled");
        }
        break;
    }
    default:
        ew_bilateral_separable(dev, &s->model, s->w, s->h, s->image, s->attr, s->tmp, s->out);
        break;
    }
    if (!planes) ew_bf_unpack_image(dev, s->out, s->C, output, color);
    const ew_image *cv = ew_op_image(op, "coc");
    if (cv) {
        long j = 0;
        for (int y = 0; y < s->h; y++)
            for (int x = 0; x < s->w; x++) *ew__pixel(cv, x, y) = s->coc[j++];
    }
    return EW_OK;
}

const ew_op_type ew_filter_dof = {
    .kind = "filter",
    .name = "dof",
    .summary = "depth of field from depth and thin-lens camera values (focal length, f-stop, focus distance, sensor "
    "width): per-pixel CoC, then the pyramid filter with the DoF functions of Eq. 8 (both blur directions)",
    .images = images,
    .num_images = (int)(sizeof images / sizeof images[0]),
    .params = params,
    .num_params = (int)(sizeof params / sizeof params[0]),
    .commit = commit,
    .execute = execute,
    .release = release,
    .set_data = ew_pyr_op_set_data,
    .release_data = ew_pyr_op_release_data,
    /* the circle of confusion itself follows the image size (thin lens x
     * max(width, height) / sensor width): only the caps are lengths */
    .pixel_params = (const char *const[]){"radius", "sigma_spatial", NULL},
    /* "method" in the order of execute's switch */
    .choices = (const ew_param_choices[]){{"method", (const char *const[]){"pyramid", "bilateral", "separable", NULL}},
                                          EW_PYR_WEIGHTS_CHOICES,
                                          {NULL, NULL}},
    .extra_outputs = (const char *const[]){"coc", NULL},
    .inplace_inputs = (const char *const[]){"color", NULL},
    .filters_alpha = 1,
    .data_params = (const char *const[]){"weights", "weights", NULL},
    .flags = EW_METHOD_HOST,
};
EW_REGISTER_OP(ew_filter_dof, 90);
