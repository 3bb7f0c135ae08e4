/* Premultiplied RGBA through the filters (public API): alpha is filtered with
 * the colour's weights, so a blur of valid premultiplied colour (every
 * channel <= alpha) stays valid, non-finite alpha is rebuilt like colour,
 * and filtering in place gives the same pixels as into another buffer. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 48
#define H 40

static ew_device *dev_cpu(void) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = 2;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

/* A checker of opaque and transparent 6-pixel cells, colour premultiplied
 * (random, <= alpha), and a depth ramp for DoF. */
static void make_rgba(float *rgba, float *depth) {
    unsigned s = 7u;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *p = rgba + ((size_t)y * W + x) * 4;
            const float a = ((x / 6 + y / 6) & 1) ? 1.0f : 0.0f;
            for (int c = 0; c < 3; c++) p[c] = a * (0.2f + 0.8f * urand(&s));
            p[3] = a;
            depth[(size_t)y * W + x] = 0.5f + 10.0f * (float)x / W;
        }
}

/* Run `method` with its blurring settings on rgba into out (out may be rgba). */
static ew_result run(ew_device *dev, const char *method, float *rgba, float *depth, float *out) {
    ew_op *op = NULL;
    ew_result r = ew_op_create(dev, method, &op);
    if (r != EW_OK) return r;
    ew_image vin = ew_image_packed(rgba, W, H, 4), vout = ew_image_packed(out, W, H, 4);
    ew_image vd = ew_image_packed(depth, W, H, 1);
    r = ew_op_set_image(op, "color", &vin);
    if (r == EW_OK) r = ew_op_set_image(op, "output", &vout);
    if (r == EW_OK && !strcmp(method, "dof")) {
        r = ew_op_set_image(op, "depth", &vd);
        if (r == EW_OK) r = ew_op_set_float(op, "fstop", 0.5f);
        if (r == EW_OK) r = ew_op_set_float(op, "focus_distance", 0.5f);
    } else if (r == EW_OK) {
        r = ew_op_set_int(op, "radius", 5);
        if (r == EW_OK && strcmp(method, "atrous") != 0) r = ew_op_set_float(op, "sigma_range", 100.0f);
    }
    if (r == EW_OK) r = ew_op_commit(op);
    if (r == EW_OK) r = ew_op_execute(op);
    ew_op_destroy(op);
    return r;
}

static const char *const blurs[] = {"pyramid", "bilateral", "separable", "dof", NULL};
/* every filter that carries an alpha through */
static const char *const all_filters[] = {"pyramid", "bilateral", "separable", "dof", "atrous", NULL};

TEST(blurred_premultiplied_colour_stays_within_alpha) {
    ew_device *dev = dev_cpu();
    CHECK(dev);
    float *in = malloc(sizeof(float) * W * H * 4), *out = malloc(sizeof(float) * W * H * 4);
    float *depth = malloc(sizeof(float) * W * H);
    CHECK(in && out && depth);
    for (int m = 0; blurs[m]; m++) {
        make_rgba(in, depth);
        CHECK_EQ_INT(run(dev, blurs[m], in, depth, out), EW_OK);
        long over = 0, soft = 0, colour_moved = 0;
        for (size_t i = 0; i < (size_t)W * H; i++) {
            const float *p = out + i * 4;
            for (int c = 0; c < 3; c++) over += p[c] > p[3] + 1e-5f;
            soft += p[3] > 0.01f && p[3] < 0.99f;
            colour_moved += in[i * 4 + 3] == 0.0f && p[0] > 0.01f;
        }
        if (over || !soft || !colour_moved)
            fprintf(stderr, "  %s: %ld channels above alpha, %ld soft alpha, %ld colour moved\n", blurs[m], over,
                    soft, colour_moved);
        CHECK(colour_moved > 0); /* the case is a blur across alpha edges */
        CHECK(soft > 0);         /* alpha was blurred with it */
        CHECK_EQ_INT(over, 0);   /* still valid premultiplied colour */
    }
    free(in);
    free(out);
    free(depth);
    ew_device_destroy(dev);
}

TEST(alpha_in_place_equals_out_of_place) {
    ew_device *dev = dev_cpu();
    CHECK(dev);
    float *in = malloc(sizeof(float) * W * H * 4), *out = malloc(sizeof(float) * W * H * 4);
    float *depth = malloc(sizeof(float) * W * H);
    CHECK(in && out && depth);
    for (int m = 0; all_filters[m]; m++) {
        make_rgba(in, depth);
        CHECK_EQ_INT(run(dev, all_filters[m], in, depth, out), EW_OK);
        CHECK_EQ_INT(run(dev, all_filters[m], in, depth, in), EW_OK);
        CHECK(memcmp(in, out, sizeof(float) * W * H * 4) == 0);
    }
    free(in);
    free(out);
    free(depth);
    ew_device_destroy(dev);
}

TEST(non_finite_alpha_is_rebuilt) {
    ew_device *dev = dev_cpu();
    CHECK(dev);
    float *in = malloc(sizeof(float) * W * H * 4), *out = malloc(sizeof(float) * W * H * 4);
    float *depth = malloc(sizeof(float) * W * H);
    CHECK(in && out && depth);
    for (int m = 0; all_filters[m]; m++) {
        make_rgba(in, depth);
        for (size_t i = 0; i < (size_t)W * H; i += 7) in[i * 4 + 3] = (i / 7) % 2 ? NAN : INFINITY;
        CHECK_EQ_INT(run(dev, all_filters[m], in, depth, out), EW_OK);
        long bad = 0;
        for (size_t i = 0; i < (size_t)W * H * 4; i++) bad += !isfinite(out[i]);
        if (bad) fprintf(stderr, "  %s: %ld non-finite\n", all_filters[m], bad);
        CHECK_EQ_INT(bad, 0);
    }
    free(in);
    free(out);
    free(depth);
    ew_device_destroy(dev);
}

/* RGB views (3 channels) are not touched by any of this: same pixels as a
 * 4-channel run's colour when alpha is 1 everywhere. */
TEST(opaque_rgba_colour_equals_rgb) {
    ew_device *dev = dev_cpu();
    CHECK(dev);
    float *in = malloc(sizeof(float) * W * H * 4), *out = malloc(sizeof(float) * W * H * 4);
    float *rgb = malloc(sizeof(float) * W * H * 3), *rgb_out = malloc(sizeof(float) * W * H * 3);
    float *depth = malloc(sizeof(float) * W * H);
    CHECK(in && out && rgb && rgb_out && depth);
    make_rgba(in, depth);
    for (size_t i = 0; i < (size_t)W * H; i++) {
        in[i * 4 + 3] = 1.0f;
        for (int c = 0; c < 3; c++) rgb[i * 3 + c] = in[i * 4 + c];
    }
    ew_op *op = NULL;
    CHECK_EQ_INT(ew_op_create(dev, "pyramid", &op), EW_OK);
    ew_image v3 = ew_image_packed(rgb, W, H, 3), o3 = ew_image_packed(rgb_out, W, H, 3);
    CHECK_EQ_INT(ew_op_set_image(op, "color", &v3), EW_OK);
    CHECK_EQ_INT(ew_op_set_image(op, "output", &o3), EW_OK);
    CHECK_EQ_INT(ew_op_set_int(op, "radius", 5), EW_OK);
    CHECK_EQ_INT(ew_op_set_float(op, "sigma_range", 100.0f), EW_OK);
    CHECK_EQ_INT(ew_op_commit(op), EW_OK);
    CHECK_EQ_INT(ew_op_execute(op), EW_OK);
    ew_op_destroy(op);
    CHECK_EQ_INT(run(dev, "pyramid", in, depth, out), EW_OK);
    double worst = 0.0;
    for (size_t i = 0; i < (size_t)W * H; i++) {
        for (int c = 0; c < 3; c++) worst = fmax(worst, fabs((double)out[i * 4 + c] - rgb_out[i * 3 + c]));
        worst = fmax(worst, fabs((double)out[i * 4 + 3] - 1.0));
    }
    CHECK(worst < 1e-5);
    free(in);
    free(out);
    free(rgb);
    free(rgb_out);
    free(depth);
    ew_device_destroy(dev);
}

/* A uniform alpha (one finite value everywhere, as a render without a
 * transparent film has) is not filtered: the output's alpha is that value
 * bit for bit (a filter run gives it for 0 and 1 and within a few ulp for
 * 0.3 or 3.7), and a non-uniform alpha next to it still is. */
TEST(uniform_alpha_is_kept_exactly) {
    ew_device *dev = dev_cpu();
    CHECK(dev);
    float *in = malloc(sizeof(float) * W * H * 4), *out = malloc(sizeof(float) * W * H * 4);
    float *depth = malloc(sizeof(float) * W * H);
    CHECK(in && out && depth);
    const float values[] = {1.0f, 0.0f, 0.3f, 3.7f};
    for (int m = 0; all_filters[m]; m++)
        for (int v = 0; v < 4; v++)
            for (int uniform = 0; uniform < 2; uniform++) {
                make_rgba(in, depth);
                for (size_t i = 0; i < (size_t)W * H; i++) {
                    for (int c = 0; c < 3; c++) in[i * 4 + c] = 0.1f + 0.5f * in[i * 4 + c];
                    in[i * 4 + 3] = values[v];
                }
                if (!uniform) in[3] = values[v] + 0.25f; /* pixel (0, 0) */
                CHECK_EQ_INT(run(dev, all_filters[m], in, depth, out), EW_OK);
                long alpha_off = 0;
                for (size_t i = 0; i < (size_t)W * H; i++)
                    alpha_off += memcmp(&out[i * 4 + 3], &values[v], sizeof(float)) != 0;
                if (uniform) {
                    if (alpha_off) fprintf(stderr, "  %s alpha %g: %ld changed\n", all_filters[m], (double)values[v], alpha_off);
                    CHECK_EQ_INT(alpha_off, 0);
                } else {
                    CHECK(alpha_off > 0); /* the corner's alpha was filtered */
                }
            }
    free(in);
    free(out);
    free(depth);
    ew_device_destroy(dev);
}
