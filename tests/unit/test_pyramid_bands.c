/* The pyramid's result in bands (public API, CPU): on a device whose bands
 * fit the frame (2 * 64 rows a thread at most half its rows) the pyramid
 * filter and dof write level 0's result band by band into each thread's
 * buffer and unpack it from there; on one with more threads than that the
 * result is a whole frame. Both give the same bits, into a packed output,
 * a strided one, the colour view itself, at radius 0 (no coarser level) and
 * with missing samples. */
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

/* Run method on a copy of `in` (C channels) with the output laid out as
 * `layout`; the result, packed, into res. */
static ew_result run(int threads, const char *method, int radius, const float *in, int C, float *depth, int layout,
                     float *res) {
    ew_device *dev = dev_cpu(threads);
    if (!dev) return EW_ERR_OUT_OF_MEMORY;
    const size_t n = (size_t)W * H;
    float *color = malloc(sizeof(float) * n * (size_t)C), *out = malloc(sizeof(float) * n * (size_t)(C + 1));
    ew_op *op = NULL;
    ew_result r = color && out ? ew_op_create(dev, method, &op) : EW_ERR_OUT_OF_MEMORY;
    if (r == EW_OK) {
        memcpy(color, in, sizeof(float) * n * (size_t)C);
        memset(out, 0, sizeof(float) * n * (size_t)(C + 1));
        ew_image vin = ew_image_packed(color, W, H, C), vd = ew_image_packed(depth, W, H, 1);
        ew_image vout = ew_image_packed(out, W, H, C);
        if (layout == OUT_STRIDED) { /* one float more a pixel */
            vout.pixel_stride = (int64_t)sizeof(float) * (C + 1);
            vout.row_stride = vout.pixel_stride * W;
        }
        r = ew_op_set_image(op, "color", &vin);
        if (r == EW_OK) r = ew_op_set_image(op, "output", layout == OUT_IN_PLACE ? &vin : &vout);
        if (r == EW_OK && !strcmp(method, "dof")) {
            r = ew_op_set_image(op, "depth", &vd);
            if (r == EW_OK) r = ew_op_set_float(op, "fstop", 1.0f);
            if (r == EW_OK) r = ew_op_set_float(op, "focus_distance", 3.0f);
            if (r == EW_OK) r = ew_op_set_int(op, "radius", radius);
        } else if (r == EW_OK) {
            r = ew_op_set_int(op, "radius", radius);
        }
        if (r == EW_OK) r = ew_op_commit(op);
        if (r == EW_OK) r = ew_op_execute(op);
        for (size_t j = 0; r == EW_OK && j < n; j++)
            for (int c = 0; c < C; c++)
                res[j * (size_t)C + (size_t)c] = layout == OUT_IN_PLACE ? color[j * (size_t)C + (size_t)c]
                                                 : layout == OUT_STRIDED ? out[j * (size_t)(C + 1) + (size_t)c]
                                                                         : out[j * (size_t)C + (size_t)c];
    }
    ew_op_destroy(op);
    ew_device_destroy(dev);
    free(color);
    free(out);
    return r;
}

static int same_bits(const float *a, const float *b, size_t count) { return memcmp(a, b, count * sizeof(float)) == 0; }

TEST(bands_give_the_bits_of_a_whole_frame) {
    const size_t n = (size_t)W * H;
    float *in = malloc(sizeof(float) * n * 4), *depth = malloc(sizeof(float) * n);
    float *whole = malloc(sizeof(float) * n * 4), *banded = malloc(sizeof(float) * n * 4);
    CHECK(in && depth && whole && banded);
    static const char *const methods[] = {"pyramid", "dof"};
    static const int radii[] = {9, 0};
    for (int m = 0; m < 2; m++)
        for (int ri = 0; ri < 2; ri++)
            for (int C = 3; C <= 4; C++) {
                if (!strcmp(methods[m], "dof") && radii[ri] == 0) continue; /* dof's radius starts at 1 */
                make_input(in, C, depth);
                CHECK_EQ_INT(run(3, methods[m], radii[ri], in, C, depth, OUT_PACKED, whole), EW_OK);
                for (int threads = 1; threads <= 2; threads++)
                    for (int layout = OUT_PACKED; layout <= OUT_IN_PLACE; layout++) {
                        CHECK_EQ_INT(run(threads, methods[m], radii[ri], in, C, depth, layout, banded), EW_OK);
                        if (!same_bits(whole, banded, n * (size_t)C))
                            FAIL_AT("%s radius %d, %d channels, %d threads, output layout %d: not the whole frame's bits",
                                    methods[m], radii[ri], C, threads, layout);
                    }
            }
    free(in);
    free(depth);
    free(whole);
    free(banded);
}
