/* EW_FORMAT_HALF input views: every half converts exactly (against the
 * compiler's own _Float16), every method gives from half inputs the very
 * bits it gives from float inputs holding the same values, and a half
 * output is refused. */
#include "ew_test.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"
#include "kernels/half.h"
#include "src/internal.h"

#define W 72
#define H 56

TEST(every_half_converts_as_the_compilers_float16) {
    int bad = 0;
    for (uint32_t u = 0; u < 65536u; u++) {
        const uint16_t bits = (uint16_t)u;
        _Float16 h;
        memcpy(&h, &bits, sizeof h);
        const float want = (float)h, got = ew_half_to_float(bits);
        if (isnan(want) ? !isnan(got) : memcmp(&want, &got, sizeof want) != 0) bad++;
    }
    CHECK_EQ_INT(bad, 0);
    CHECK(ew_half_to_float(0x3c00u) == 1.0f && ew_half_to_float(0xc000u) == -2.0f);
    CHECK(ew_half_to_float(0x7bffu) == 65504.0f && ew_half_to_float(0x0001u) == 5.9604644775390625e-8f);
}

/* float to half against the compiler's conversion: every half's float and
 * the floats between and around neighbours (ties both ways), and a sweep of
 * every 4099th float bit pattern (NaNs as NaNs) */
static int half_differs(float f) {
    const _Float16 want = (_Float16)f;
    const uint16_t got = ew_float_to_half(f);
    uint16_t wb;
    memcpy(&wb, &want, sizeof wb);
    return isnan(f) ? (got & 0x7c00u) != 0x7c00u || !(got & 0x3ffu) : got != wb;
}

TEST(every_float_rounds_to_half_as_the_compilers_float16) {
    int bad = 0;
    for (uint32_t u = 0; u < 65536u; u++) {
        const float a = ew_half_to_float((uint16_t)u), b = ew_half_to_float((uint16_t)(u + 1u));
        bad += half_differs(a) + half_differs(nextafterf(a, INFINITY)) + half_differs(nextafterf(a, -INFINITY));
        if (isfinite(a) && isfinite(b) && (u & 0x7fffu) != 0x7fffu) bad += half_differs(a + (b - a) * 0.5f);
    }
    for (uint64_t u = 0; u < 0x100000000ull; u += 4099u) {
        const uint32_t bits = (uint32_t)u;
        float f;
        memcpy(&f, &bits, sizeof f);
        bad += half_differs(f);
    }
    CHECK_EQ_INT(bad, 0);
    CHECK(ew_float_to_half(65519.0f) == 0x7bffu && ew_float_to_half(65520.0f) == 0x7c00u);
    CHECK(ew_float_to_half(1.0f + 1.0f / 2048.0f) == 0x3c00u && ew_float_to_half(1.0f + 3.0f / 2048.0f) == 0x3c02u);
}

/* the run converter (in hardware where the CPU can) against the value by
 * value one, on every half, from an odd offset and length (its tail) */
TEST(halves_to_floats_in_runs_as_value_by_value) {
    static uint16_t h[65536 + 3];
    static float f[65536 + 3];
    for (uint32_t u = 0; u < 65536u + 3u; u++) h[u] = (uint16_t)(u * 40503u);
    ew__halves_to_floats(h + 1, f + 1, 65536 + 1);
    int bad = 0;
    for (uint32_t u = 1; u < 65536u + 2u; u++) {
        const float want = ew_half_to_float(h[u]);
        if (isnan(want) ? !isnan(f[u]) : memcmp(&want, &f[u], sizeof want) != 0) bad++;
    }
    CHECK_EQ_INT(bad, 0);
}

static uint32_t rng = 12345u;
static float frand(float lo, float hi) {
    rng = rng * 1664525u + 1013904223u;
    return lo + (hi - lo) * (float)(rng >> 8) / 16777216.0f;
}

/* An input of c channels: float values that halves hold exactly, and the
 * same as halves. */
typedef struct {
    float *f;
    uint16_t *h;
    int c;
} plane;

static plane make_plane(const char *name, int c) {
    plane p = {malloc(sizeof(float) * W * H * (size_t)c), malloc(sizeof(uint16_t) * W * H * (size_t)c), c};
    const int normal = !strcmp(name, "normal"), vector = !strcmp(name, "vector");
    for (size_t i = 0; i < (size_t)W * H * (size_t)c; i++) {
        float v = normal ? frand(-1.0f, 1.0f) : vector ? frand(-2.0f, 2.0f) : frand(0.05f, 1.0f);
        if (!strcmp(name, "color") && i % 97 == 0) v = 40.0f; /* fireflies */
        const _Float16 h = (_Float16)v;
        p.f[i] = (float)h;
        memcpy(&p.h[i], &h, sizeof h);
    }
    return p;
}

static ew_image view_of(const plane *p, int half) {
    ew_image v = ew_image_packed(p->f, W, H, p->c);
    if (half) {
        v.data = p->h;
        v.format = EW_FORMAT_HALF;
        v.pixel_stride = EW_STRIDE_PACKED;
        v.row_stride = EW_STRIDE_PACKED;
    }
    return v;
}

/* The method's outputs with every input set, as halves or as floats; 0
 * when the method does not commit with these inputs. */
static int run(ew_device *dev, const char *method, int half, plane *in, float **out, int ni) {
    ew_op *op = NULL;
    if (ew_op_create(dev, method, &op) != EW_OK) return 0;
    for (int i = 0; i < ni; i++) {
        ew_image_info im;
        uint32_t fl = 0;
        ew_method_image(NULL, method, i, &im);
        ew_method_image_flags(NULL, method, i, &fl);
        ew_image v = (fl & EW_IMAGE_OUTPUT) ? ew_image_packed(out[i], W, H, in[i].c) : view_of(&in[i], half);
        if (ew_op_set_image(op, im.name, &v) != EW_OK) {
            fprintf(stderr, "  %s: set_image %s: %s\n", method, im.name, ew_device_last_error(dev));
            ew_op_destroy(op);
            return 0;
        }
    }
    int ok = ew_op_commit(op) == EW_OK && ew_op_execute(op) == EW_OK;
    if (!ok) fprintf(stderr, "  %s (%s): %s\n", method, half ? "half" : "float", ew_device_last_error(dev));
    ew_op_destroy(op);
    return ok;
}

TEST(every_method_reads_half_inputs_as_the_floats_they_hold) {
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    int methods = 0;
    for (int32_t m = 0; m < ew_method_count(NULL); m++) {
        const char *name = NULL;
        int32_t ni = 0;
        ew_method_get(NULL, m, &name, NULL, &ni, NULL);
        plane in[8];
        float *a[8], *b[8];
        for (int i = 0; i < ni; i++) {
            ew_image_info im;
            ew_method_image(NULL, name, i, &im);
            const int c = !strcmp(im.name, "color") || !strcmp(im.name, "output") ? 3 : im.min_channels < 1 ? 1 : im.min_channels;
            in[i] = make_plane(im.name, c);
            a[i] = calloc((size_t)W * H * (size_t)c, sizeof(float));
            b[i] = calloc((size_t)W * H * (size_t)c, sizeof(float));
        }
        const int ran_float = run(dev, name, 0, in, a, ni);
        const int ran_half = run(dev, name, 1, in, b, ni);
        CHECK_EQ_INT(ran_half, ran_float);
        if (ran_float && ran_half) {
            methods++;
            for (int i = 0; i < ni; i++) {
                uint32_t fl = 0;
                ew_method_image_flags(NULL, name, i, &fl);
                if (!(fl & EW_IMAGE_OUTPUT)) continue;
                const int same = !memcmp(a[i], b[i], sizeof(float) * W * H * (size_t)in[i].c);
                if (!same) fprintf(stderr, "  %s: output %d differs between half and float inputs\n", name, i);
                CHECK(same);
            }
        }
        for (int i = 0; i < ni; i++) {
            free(in[i].f);
            free(in[i].h);
            free(a[i]);
            free(b[i]);
        }
    }
    CHECK(methods == ew_method_count(NULL));
    ew_device_destroy(dev);
}

TEST(a_half_output_or_misaligned_half_is_refused) {
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    ew_op *op = NULL;
    CHECK_EQ_INT(ew_op_create(dev, "kpcn", &op), EW_OK);
    static uint16_t px[W * H * 3 + 1];
    ew_image v = {px, W, H, 3, 0, 0, EW_FORMAT_HALF};
    CHECK_EQ_INT(ew_op_set_image(op, "output", &v), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "EW_FORMAT_FLOAT");
    CHECK_EQ_INT(ew_op_set_image(op, "albedo", &v), EW_OK);
    v.data = (char *)px + 1;
    CHECK_EQ_INT(ew_op_set_image(op, "albedo", &v), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "half");
    v.data = px;
    v.pixel_stride = 5; /* not a multiple of 2 */
    CHECK_EQ_INT(ew_op_set_image(op, "albedo", &v), EW_ERR_INVALID_ARGUMENT);
    v.pixel_stride = 4; /* smaller than 3 halves */
    CHECK_EQ_INT(ew_op_set_image(op, "albedo", &v), EW_ERR_INVALID_ARGUMENT);
    v.pixel_stride = 6;
    v.format = (ew_format)7;
    CHECK_EQ_INT(ew_op_set_image(op, "albedo", &v), EW_ERR_INVALID_ARGUMENT);
    ew_op_destroy(op);
    ew_device_destroy(dev);
}

/* ew_op_image_flags: after commit, whether this run reads a half view of
 * the image where it is (kpcn: in streamed tiles; auto: as its method) */
static uint32_t flags_after_commit(ew_device *dev, const char *method, int w, int h, int budget, const char *image) {
    ew_op *op = NULL;
    if (ew_op_create(dev, method, &op) != EW_OK) return 0xffu;
    const size_t n = (size_t)w * h;
    float *c = calloc(n * 3, sizeof(float)), *a = calloc(n * 3, sizeof(float)), *nm = calloc(n * 3, sizeof(float));
    float *z = calloc(n, sizeof(float)), *o = calloc(n * 3, sizeof(float));
    const ew_image vc = ew_image_packed(c, w, h, 3), va = ew_image_packed(a, w, h, 3), vn = ew_image_packed(nm, w, h, 3);
    const ew_image vz = ew_image_packed(z, w, h, 1), vo = ew_image_packed(o, w, h, 3);
    ew_op_set_image(op, "color", &vc);
    ew_op_set_image(op, "albedo", &va);
    ew_op_set_image(op, "normal", &vn);
    ew_op_set_image(op, "depth", &vz);
    ew_op_set_image(op, "output", &vo);
    uint32_t fl = 0xffu;
    if (!strcmp(method, "kpcn")) ew_op_set_int(op, "max_memory_mb", budget);
    if (ew_op_image_flags(op, image, &fl) != EW_ERR_INVALID_STATE) fl = 0xfeu; /* before commit: refused */
    else if (ew_op_commit(op) != EW_OK || ew_op_image_flags(op, image, &fl) != EW_OK) fl = 0xffu;
    ew_op_destroy(op);
    free(c);
    free(a);
    free(nm);
    free(z);
    free(o);
    return fl;
}

TEST(image_flags_say_whether_this_run_reads_halves_in_place) {
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    uint32_t fl = 0;
    int32_t k = 0;
    ew_image_info im;
    while (ew_method_image(NULL, "kpcn", k, &im) == EW_OK && strcmp(im.name, "albedo") != 0) k++;
    CHECK_EQ_INT(ew_method_image_flags(NULL, "kpcn", k, &fl), EW_OK);
    CHECK(fl & EW_IMAGE_HALF_IN_PLACE); /* the method may */
    CHECK_EQ_INT((int)flags_after_commit(dev, "kpcn", 96, 80, 768, "albedo"), 0); /* a whole frame packs it */
    CHECK_EQ_INT((int)flags_after_commit(dev, "kpcn", 640, 600, 1, "normal"), (int)EW_IMAGE_HALF_IN_PLACE);
    CHECK_EQ_INT((int)flags_after_commit(dev, "kpcn", 640, 600, 1, "output"), (int)EW_IMAGE_OUTPUT);
    CHECK_EQ_INT((int)flags_after_commit(dev, "kpcn", 640, 600, 1, "color"), (int)EW_IMAGE_INPLACE);
    CHECK_EQ_INT((int)flags_after_commit(dev, "nbg", 640, 600, 1, "albedo"), 0);
    CHECK_EQ_INT((int)flags_after_commit(dev, "auto", 96, 80, 1, "albedo"), 0);
    ew_op *op = NULL;
    CHECK_EQ_INT(ew_op_create(dev, "kpcn", &op), EW_OK);
    CHECK_EQ_INT(ew_op_image_flags(op, "nothing", &fl), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_image_flags(op, "albedo", NULL), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_op_image_flags(NULL, "albedo", &fl), EW_ERR_INVALID_ARGUMENT);
    ew_op_destroy(op);
    ew_device_destroy(dev);
}
