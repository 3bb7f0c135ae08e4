/* The pyramid's level 0 in bands (public API, CPU): on a device whose bands
 * fit the frame (2 * 64 rows a thread at most half its rows) the pyramid
 * filter and dof pack level 0's input into each thread's buffer from the
 * caller's views (each coarse row's two rows for the first pass, each
 * band's rows again for the last, the rows either side of a band saved
 * before any row is written) and write its result band by band into each
 * thread's buffer, unpacking it from there; on one with more threads than
 * that, input and result are whole frames. Both give the same bits: inputs
 * packed or padded (pixel and row strides larger than their channels and
 * width), into a packed output, a strided one, the colour view itself, at
 * radius 0 (no coarser level), with missing samples, for the colour model
 * (the colour its own guide), GI (normals and depth) and DoF. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 83
#define H 300 /* 1 and 2 threads: bands; 3 threads: 3 * 128 > 300, a whole frame */

static ew_device *dev_cpu(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

/* Noisy colour of C channels over smooth shapes, a few missing samples,
 * and a depth ramp for DoF. */
static void make_input(float *color, int C, float *depth) {
    unsigned s = 11u;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *p = color + ((size_t)y * W + x) * (size_t)C;
            const float base = (x / 20 + y / 30) & 1 ? 0.8f : 0.1f;
            for (int c = 0; c < C; c++) p[c] = c == 3 ? 0.5f + 0.5f * urand(&s) : base + 0.3f * urand(&s);
            if ((x * 7 + y * 13) % 997 == 0) p[1] = NAN;
            depth[(size_t)y * W + x] = 0.5f + 20.0f * (float)y / H;
        }
}

enum { OUT_PACKED, OUT_STRIDED, OUT_IN_PLACE };

/* A view of count floats a pixel laid out with padding: one float more a
 * pixel and 5 pixels more a row, the padding NaN (a pass that read it, or
 * took a row for the next, would see missing samples). */
static float *padded_copy(const float *src, int count, ew_image *v) {
    const int ps = count + 1, rs = (W + 5) * ps;
    float *buf = malloc(sizeof(float) * (size_t)rs * H);
    if (!buf) return NULL;
    for (size_t i = 0; i < (size_t)rs * H; i++) buf[i] = NAN;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            memcpy(buf + (size_t)y * rs + (size_t)x * ps, src + ((size_t)y * W + x) * (size_t)count, sizeof(float) * (size_t)count);
    *v = ew_image_packed(buf, W, H, count);
    v->pixel_stride = (int64_t)sizeof(float) * ps;
    v->row_stride = (int64_t)sizeof(float) * rs;
    return buf;
}

/* Normals over the same shapes, for the pyramid's model gi. */
static void make_normals(float *nrm) {
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *p = nrm + ((size_t)y * W + x) * 3;
            const int side = (x / 20 + y / 30) & 1;
            p[0] = side ? 0.6f : 0.0f;
            p[1] = side ? 0.0f : 0.6f;
            p[2] = 0.8f;
        }
}

/* Run method (model gi: the pyramid with normals and depth) on a copy of
 * `in` (C channels), the inputs packed or padded (in_pad), with the output
 * laid out as `layout` (in place: the colour view, padded or not); the
 * result, packed, into res. */
static ew_result run(int threads, const char *method, int radius, const float *in, int C, float *depth, int layout,
                     int in_pad, int gi, float *res) {
    ew_device *dev = dev_cpu(threads);
    if (!dev) return EW_ERR_OUT_OF_MEMORY;
    const size_t n = (size_t)W * H;
    float *color = malloc(sizeof(float) * n * (size_t)C), *out = malloc(sizeof(float) * n * (size_t)(C + 1));
    float *nrm = malloc(sizeof(float) * n * 3), *pc = NULL, *pd = NULL, *pn = NULL;
    ew_op *op = NULL;
    ew_result r = color && out && nrm ? ew_op_create(dev, method, &op) : EW_ERR_OUT_OF_MEMORY;
    if (r == EW_OK) {
        memcpy(color, in, sizeof(float) * n * (size_t)C);
        memset(out, 0, sizeof(float) * n * (size_t)(C + 1));
        make_normals(nrm);
        ew_image vin = ew_image_packed(color, W, H, C), vd = ew_image_packed(depth, W, H, 1);
        ew_image vn = ew_image_packed(nrm, W, H, 3);
        if (in_pad) {
            pc = padded_copy(color, C, &vin);
            pd = padded_copy(depth, 1, &vd);
            pn = padded_copy(nrm, 3, &vn);
            if (!pc || !pd || !pn) r = EW_ERR_OUT_OF_MEMORY;
        }
        ew_image vout = ew_image_packed(out, W, H, C);
        if (layout == OUT_STRIDED) { /* one float more a pixel */
            vout.pixel_stride = (int64_t)sizeof(float) * (C + 1);
            vout.row_stride = vout.pixel_stride * W;
        }
        if (r == EW_OK) r = ew_op_set_image(op, "color", &vin);
        if (r == EW_OK) r = ew_op_set_image(op, "output", layout == OUT_IN_PLACE ? &vin : &vout);
        if (r == EW_OK && !strcmp(method, "dof")) {
            r = ew_op_set_image(op, "depth", &vd);
            if (r == EW_OK) r = ew_op_set_float(op, "fstop", 1.0f);
            if (r == EW_OK) r = ew_op_set_float(op, "focus_distance", 3.0f);
            if (r == EW_OK) r = ew_op_set_int(op, "radius", radius);
        } else if (r == EW_OK) {
            r = ew_op_set_int(op, "radius", radius);
            if (r == EW_OK && gi) r = ew_op_set_int(op, "model", 1);
            if (r == EW_OK && gi) r = ew_op_set_image(op, "normal", &vn);
            if (r == EW_OK && gi) r = ew_op_set_image(op, "depth", &vd);
        }
        if (r == EW_OK) r = ew_op_commit(op);
        if (r == EW_OK) r = ew_op_execute(op);
        for (size_t j = 0; r == EW_OK && j < n; j++)
            for (int c = 0; c < C; c++) {
                const float *ip = (const float *)(const void *)((const char *)vin.data +
                                                                 (int64_t)(j / W) * vin.row_stride +
                                                                 (int64_t)(j % W) * vin.pixel_stride);
                res[j * (size_t)C + (size_t)c] = layout == OUT_IN_PLACE ? ip[c]
                                                 : layout == OUT_STRIDED ? out[j * (size_t)(C + 1) + (size_t)c]
                                                                         : out[j * (size_t)C + (size_t)c];
            }
    }
    ew_op_destroy(op);
    ew_device_destroy(dev);
    free(color);
    free(out);
    free(nrm);
    free(pc);
    free(pd);
    free(pn);
    return r;
}

static int same_bits(const float *a, const float *b, size_t count) { return memcmp(a, b, count * sizeof(float)) == 0; }

TEST(bands_give_the_bits_of_a_whole_frame) {
    const size_t n = (size_t)W * H;
    float *in = malloc(sizeof(float) * n * 4), *depth = malloc(sizeof(float) * n);
    float *whole = malloc(sizeof(float) * n * 4), *banded = malloc(sizeof(float) * n * 4);
    CHECK(in && depth && whole && banded);
    /* pyramid (colour, its guide the colour), pyramid with model gi, dof */
    static const char *const methods[] = {"pyramid", "pyramid", "dof"};
    static const int radii[] = {9, 0};
    for (int m = 0; m < 3; m++)
        for (int ri = 0; ri < 2; ri++)
            for (int C = 3; C <= 4; C++) {
                const int gi = m == 1;
                if (!strcmp(methods[m], "dof") && radii[ri] == 0) continue; /* dof's radius starts at 1 */
                make_input(in, C, depth);
                CHECK_EQ_INT(run(3, methods[m], radii[ri], in, C, depth, OUT_PACKED, 0, gi, whole), EW_OK);
                for (int threads = 1; threads <= 3; threads++) /* 3: whole frames, inputs padded too */
                    for (int in_pad = 0; in_pad <= 1; in_pad++)
                        for (int layout = OUT_PACKED; layout <= OUT_IN_PLACE; layout++) {
                            CHECK_EQ_INT(run(threads, methods[m], radii[ri], in, C, depth, layout, in_pad, gi, banded),
                                         EW_OK);
                            if (!same_bits(whole, banded, n * (size_t)C))
                                FAIL_AT("%s%s radius %d, %d channels, %d threads, inputs %s, output layout %d: not "
                                        "the whole frame's bits",
                                        methods[m], gi ? " (gi)" : "", radii[ri], C, threads,
                                        in_pad ? "padded" : "packed", layout);
                        }
            }
    free(in);
    free(depth);
    free(whole);
    free(banded);
}
