/* The brute-force joint bilateral filter and the separable approximation
 * against their definitions (Eq. 1 and its 1-D restriction), written here
 * again in double precision with libm, for every model of the paper; and
 * the "bilateral" / "separable" filters through the public API. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/bilateral.h"
#include "src/backend.h"

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

static ew_device *make_device(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

/* ---- the definitions, in double ---- */
static double sigma_ref(const ew_bf_model *m, const float *a) {
    switch (m->kind) {
    case EW_RANGE_GI: return (m->sigma_alpha * a[4] + 1.0) / 3.0;
    case EW_RANGE_DOF: {
        if (!(a[0] > 0)) return 0;
        double inv = 36.0 / ((double)a[0] * a[0]) + (m->sigma > 0 ? 1.0 / ((double)m->sigma * m->sigma) : 0.0);
        return 1.0 / sqrt(inv);
    }
    default: return m->sigma;
    }
}

static double smoothstep_ref(double e0, double e1, double x) {
    double t = (x - e0) / (e1 - e0);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return t * t * (3 - 2 * t);
}

static double range_ref(const ew_bf_model *m, const float *p, const float *q, double d2) {
    switch (m->kind) {
    case EW_RANGE_COLOR: {
        double e = 0;
        for (int k = 0; k < m->attrs; k++) e += ((double)p[k] - q[k]) * ((double)p[k] - q[k]);
        return exp(-e * m->inv_2sr2);
    }
    case EW_RANGE_GI: {
        double pp = p[0] * p[0] + p[1] * p[1] + p[2] * p[2], qq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        double dot = (double)p[0] * q[0] + (double)p[1] * q[1] + (double)p[2] * q[2];
        if (pp < 0.25 && qq < 0.25) dot = 1;
        if (dot <= 0) return 0;
        if (dot > 1) dot = 1;
        double w = pow(dot, m->sigma_n) * exp(-m->sigma_z * fabs(p[3]) * fabs((double)p[3] - q[3]));
        if (m->use_roughness) w *= 1 - smoothstep_ref(0, 0.5, fabs((double)q[4] - p[4]));
        return w;
    }
    case EW_RANGE_DEPTH: return exp(-m->sigma_z * fabs(p[0]) * fabs((double)p[0] - q[0]));
    case EW_RANGE_DOF: {
        if (d2 == 0) return 1;
        double mn = p[0] < q[1] ? p[0] : q[1];
        return mn > 0 ? exp(-18 * d2 / (mn * mn)) : 0;
    }
    default: return 1;
    }
}

/* Eq. 1 over the square window of radius min(radius, ceil(3 sigma)); axis
 * -1: 2-D, 0/1: the 1-D restriction along x/y. img: C floats a pixel, a
 * missing sample has a non-finite first channel. */
static void filter_ref(const ew_bf_model *m, int w, int h, const float *img, const float *attr, int axis,
                       double *out) {
    const int C = m->channels, A = m->attrs;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *ap = attr + ((long)y * w + x) * A;
            double s = sigma_ref(m, ap);
            int r = (int)ceil(3 * s - 1e-3);
            if (r > m->radius) r = m->radius;
            if (r < 0) r = 0;
            double acc[5] = {0, 0, 0, 0, 0};
            for (int qy = y - r; qy <= y + r; qy++)
                for (int qx = x - r; qx <= x + r; qx++) {
                    if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
                    if ((axis == 0 && qy != y) || (axis == 1 && qx != x)) continue;
                    const float *v = img + ((long)qy * w + qx) * C;
                    if (!isfinite(v[0])) continue;
                    double d2 = (double)(qx - x) * (qx - x) + (double)(qy - y) * (qy - y);
                    double wt = (s > 0 ? exp(-d2 / (2 * s * s)) : 1.0) *
                                range_ref(m, ap, attr + ((long)qy * w + qx) * A, d2);
                    for (int c = 0; c < C; c++) acc[c] += wt * v[c];
                    acc[C] += wt;
                }
            for (int c = 0; c < C; c++) out[((long)y * w + x) * C + c] = acc[C] > 0 ? acc[c] / acc[C] : NAN;
        }
}

/* random attributes for a model: normals on a hemisphere with some zero,
 * depths, roughness; CoCs with a near field */
static void random_attrs(const ew_bf_model *m, long n, float *attr, unsigned *s) {
    for (long i = 0; i < n; i++) {
        float *a = attr + i * m->attrs;
        switch (m->kind) {
        case EW_RANGE_COLOR:
            for (int k = 0; k < m->attrs; k++) a[k] = urand(s);
            break;
        case EW_RANGE_GI: {
            float x = urand(s) - 0.5f, y = urand(s) - 0.5f, z = 0.6f + urand(s);
            float l = sqrtf(x * x + y * y + z * z);
            int none = urand(s) < 0.1f;
            a[0] = none ? 0 : x / l;
            a[1] = none ? 0 : y / l;
            a[2] = none ? 0 : z / l;
            a[3] = 1.0f + 3.0f * urand(s);
            a[4] = urand(s);
            break;
        }
        case EW_RANGE_DEPTH: a[0] = 1.0f + 2.0f * urand(s); break;
        case EW_RANGE_DOF: {
            float c = 12.0f * urand(s) * urand(s);
            a[1] = c;
            a[0] = urand(s) < 0.3f ? c + 6.0f * urand(s) : c;
            break;
        }
        default: break;
        }
    }
}

static ew_bf_model model_of(int kind, int C, int radius) {
    ew_bf_model m;
    memset(&m, 0, sizeof m);
    m.kind = kind;
    m.channels = C;
    m.radius = radius;
    m.sigma = radius / 3.0f;
    m.inv_2sr2 = 1.0f / (2 * 0.2f * 0.2f);
    m.sigma_alpha = (float)(radius - 1);
    m.sigma_n = 16;
    m.sigma_z = 0.5f;
    m.attrs = ew_bf_attrs(kind);
    return m;
}

/* The library's buffers hold (r M, g M, b M, M); results are divided by
 * the last channel at the end. */
static double unmask(const float *px, int c) { return px[3] > 0 ? px[c] / px[3] : NAN; }

/* brute force (threads 1 and 3, identical) and separable vs the reference */
static int check_model(int kind, int C, int w, int h, int radius, int rough, unsigned seed) {
    (void)C;
    ew_bf_model m = model_of(kind, 3, radius);
    m.use_roughness = rough;
    long n = (long)w * h;
    const long miss = n / 2; /* one missing pixel */
    float *img = malloc(sizeof(float) * n * 4), *rimg = malloc(sizeof(float) * n * 3);
    float *attr = malloc(sizeof(float) * (n * EW_BF_MAX_ATTR + 8));
    float *out1 = malloc(sizeof(float) * n * 4), *out3 = malloc(sizeof(float) * n * 4);
    float *tmp = malloc(sizeof(float) * n * 4), *sep = malloc(sizeof(float) * n * 4);
    double *ref = malloc(sizeof(double) * n * 3);
    for (long i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++) rimg[i * 3 + c] = img[i * 4 + c] = 2.0f * urand(&seed);
        img[i * 4 + 3] = 1.0f;
    }
    for (int c = 0; c < 4; c++) img[miss * 4 + c] = 0.0f;
    rimg[miss * 3] = NAN;
    random_attrs(&m, n, attr, &seed);
    ew_device *d1 = make_device(1), *d3 = make_device(3);
    ew_bf_buffers b = {w, h, img, attr, out1, 0, h};
    ew_cpu_bf_brute(d1, &m, &b);
    b.out = out3;
    ew_cpu_bf_brute(d3, &m, &b);
    ew_bf_model m3 = m;
    m3.channels = 3;
    filter_ref(&m3, w, h, rimg, attr, -1, ref);
    int ok = memcmp(out1, out3, sizeof(float) * n * 4) == 0;
    if (!ok) fprintf(stderr, "  brute force depends on the thread count\n");
    double worst = 0;
    for (long i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            double e = fabs(unmask(out1 + i * 4, c) - ref[i * 3 + c]);
            if (!(e <= 2e-5 * (1 + fabs(ref[i * 3 + c])))) ok = 0;
            if (e > worst || isnan(e)) worst = isnan(e) ? INFINITY : e;
        }
    if (!ok) fprintf(stderr, "  kind %d: brute force differs from Eq. 1 by %g\n", kind, worst);
    /* separable: the 1-D pass on the 4-vectors, twice (normalized
     * convolution: the second pass weighs the first pass's mask), against
     * the same computed in double from the 1-D definition */
    ew_bilateral_separable(d3, &m, w, h, img, attr, tmp, sep);
    double *p1 = malloc(sizeof(double) * n * 4), *p2 = malloc(sizeof(double) * n * 4);
    for (int axis = 0; axis < 2; axis++) {
        float *in4 = malloc(sizeof(float) * n * 4);
        for (long i = 0; i < n * 4; i++) in4[i] = axis ? (float)p1[i] : img[i];
        /* each channel, the mask included, through the 1-D filter with every
         * sample valid (the mask does the excluding) */
        for (int c = 0; c < 4; c++) {
            float *ch = malloc(sizeof(float) * n);
            double *r = malloc(sizeof(double) * n);
            for (long i = 0; i < n; i++) ch[i] = in4[i * 4 + c];
            ew_bf_model m1 = m;
            m1.channels = 1;
            filter_ref(&m1, w, h, ch, attr, axis, r);
            for (long i = 0; i < n; i++) (axis ? p2 : p1)[i * 4 + c] = r[i];
            free(ch);
            free(r);
        }
        free(in4);
    }
    worst = 0;
    for (long i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            double want = p2[i * 4 + c] / p2[i * 4 + 3], e = fabs(unmask(sep + i * 4, c) - want);
            if (!(e <= 2e-5 * (1 + fabs(want)))) ok = 0;
            if (e > worst || isnan(e)) worst = isnan(e) ? INFINITY : e;
        }
    if (!ok) fprintf(stderr, "  kind %d: separable differs from its definition by %g\n", kind, worst);
    ew_device_destroy(d1);
    ew_device_destroy(d3);
    free(img); free(rimg); free(attr); free(out1); free(out3); free(tmp); free(sep); free(ref); free(p1); free(p2);
    return ok;
}

TEST(fast_exp_and_log2_are_accurate) {
    double worst = 0, worst_l = 0;
    for (float x = -87.0f; x < 88.0f; x += 0.0137f) worst = fmax(worst, fabs(ew_fexp(x) - exp(x)) / exp(x));
    for (float x = 1e-30f; x < 1e30f; x *= 1.013f) worst_l = fmax(worst_l, fabs(ew_flog2(x) - log2(x)) / fmax(1.0, fabs(log2(x))));
    CHECK(worst < 3e-7);
    CHECK(worst_l < 1e-6);
    CHECK(ew_fexp(-100.0f) == 0.0f);
    CHECK(ew_fexp(0.0f) == 1.0f);
}

TEST(brute_force_and_separable_match_definition_color) { CHECK(check_model(EW_RANGE_COLOR, EW_BF_CH, 17, 13, 4, 0, 1)); }
TEST(brute_force_and_separable_match_definition_gi) { CHECK(check_model(EW_RANGE_GI, EW_BF_CH, 15, 11, 5, 0, 2)); }
TEST(brute_force_and_separable_match_definition_gi_rough) { CHECK(check_model(EW_RANGE_GI, EW_BF_CH, 13, 14, 6, 1, 3)); }
TEST(brute_force_and_separable_match_definition_depth) { CHECK(check_model(EW_RANGE_DEPTH, EW_BF_CH, 21, 9, 5, 0, 4)); }
TEST(brute_force_and_separable_match_definition_dof) { CHECK(check_model(EW_RANGE_DOF, EW_BF_CH, 19, 12, 8, 0, 5)); }
TEST(brute_force_and_separable_match_definition_gaussian) { CHECK(check_model(EW_RANGE_NONE, EW_BF_CH, 11, 16, 3, 0, 6)); }

/* ---- through the public API ---- */
typedef struct {
    int w, h, C;
    float *in, *out;
} pic;

static ew_result run_filter(const char *type, pic *p, int model, int radius, float sigma_r, const float *guide,
                            int guide_c, ew_device *dev) {
    ew_filter *f = NULL;
    ew_result r = ew_filter_create(dev, type, &f);
    ew_image in = ew_image_packed(p->in, p->w, p->h, p->C), out = ew_image_packed(p->out, p->w, p->h, p->C);
    ew_image g = ew_image_packed((float *)guide, p->w, p->h, guide_c);
    if (r == EW_OK) r = ew_filter_set_image(f, "color", &in);
    if (r == EW_OK) r = ew_filter_set_image(f, "output", &out);
    if (r == EW_OK && guide) r = ew_filter_set_image(f, model == 0 ? "guide" : "depth", &g);
    if (r == EW_OK) r = ew_filter_set_int(f, "model", model);
    if (r == EW_OK) r = ew_filter_set_int(f, "radius", radius);
    if (r == EW_OK) r = ew_filter_set_float(f, "sigma_range", sigma_r);
    if (r == EW_OK) r = ew_filter_commit(f);
    if (r == EW_OK) r = ew_filter_execute(f);
    ew_filter_destroy(f);
    return r;
}

static pic make_pic(int w, int h, int C, unsigned seed) {
    pic p = {w, h, C, malloc(sizeof(float) * w * h * C), malloc(sizeof(float) * w * h * C)};
    for (long i = 0; i < (long)w * h * C; i++) p.in[i] = urand(&seed);
    return p;
}

static void free_pic(pic *p) {
    free(p->in);
    free(p->out);
}

static const char *const exact_types[] = {"bilateral", "separable"};

/* The packers run in bands of rows on the device's threads: every layout
 * gives the same floats and counts as on the calling thread (dev NULL), on a
 * view with padded rows and pixels and non-finite samples. */
TEST(packing_in_row_bands_equals_one_thread) {
    const int w = 37, h = 53, ps = 5, rs = w * ps + 3; /* floats: pixel and row strides */
    float *mem = calloc((size_t)rs * h, sizeof(float));
    unsigned seed = 9;
    for (int i = 0; i < rs * h; i++) mem[i] = urand(&seed);
    mem[7 * rs + 3 * ps + 1] = NAN;
    mem[40 * rs + 30 * ps] = INFINITY;
    ew_image v = {mem, w, h, 4, (int64_t)ps * 4, (int64_t)rs * 4, EW_FORMAT_FLOAT};
    const size_t n = (size_t)w * h;
    ew_device *dev = make_device(3);
    CHECK(dev != NULL);
    for (int planes = 0; planes < 2; planes++) {
        float *a = calloc(n * 5, sizeof(float)), *b = calloc(n * 5, sizeof(float));
        long ma = planes ? ew_bf_pack_image_planes(dev, &v, 4, a) : ew_bf_pack_image(dev, &v, 4, a);
        long mb = planes ? ew_bf_pack_image_planes(NULL, &v, 4, b) : ew_bf_pack_image(NULL, &v, 4, b);
        CHECK_EQ_INT(ma, 2);
        CHECK_EQ_INT(mb, 2);
        CHECK(memcmp(a, b, n * EW_BF_CH * sizeof(float)) == 0);
        long ba = 0, bb = 0;
        if (planes) {
            ew_bf_pack_channels_planes(dev, &v, 4, a, &ba);
            ew_bf_pack_channels_planes(NULL, &v, 4, b, &bb);
        } else {
            ew_bf_pack_channels(dev, &v, 4, a, &ba);
            ew_bf_pack_channels(NULL, &v, 4, b, &bb);
        }
        CHECK_EQ_INT(ba, 2);
        CHECK_EQ_INT(bb, 2);
        CHECK(memcmp(a, b, n * 4 * sizeof(float)) == 0);
        ew_image nv = v, dv = v;
        nv.channels = 3;
        dv.channels = 1;
        dv.data = mem + 1; /* channel 1 as a depth: holds the NaN */
        ba = bb = 0;
        if (planes) {
            ew_bf_pack_gi_planes(dev, &nv, &dv, NULL, a, &ba);
            ew_bf_pack_gi_planes(NULL, &nv, &dv, NULL, b, &bb);
        } else {
            ew_bf_pack_gi(dev, &nv, &dv, NULL, a, &ba);
            ew_bf_pack_gi(NULL, &nv, &dv, NULL, b, &bb);
        }
        CHECK_EQ_INT(ba, 3); /* normal x (INF), normal y and depth (the NaN) */
        CHECK_EQ_INT(bb, 3);
        CHECK(memcmp(a, b, n * 5 * sizeof(float)) == 0);
        /* unpack into the padded view: the padding stays untouched */
        float *out = malloc((size_t)rs * h * sizeof(float)), *out2 = malloc((size_t)rs * h * sizeof(float));
        for (int i = 0; i < rs * h; i++) out[i] = out2[i] = -7.0f;
        ew_image ov = v, ov2 = v;
        ov.data = out;
        ov2.data = out2;
        if (planes) ew_bf_pack_image_planes(NULL, &v, 4, a);
        else ew_bf_pack_image(NULL, &v, 4, a);
        long za = planes ? ew_bf_unpack_image_planes(dev, a, 4, &ov, &v) : ew_bf_unpack_image(dev, a, 4, &ov, &v);
        long zb = planes ? ew_bf_unpack_image_planes(NULL, a, 4, &ov2, &v) : ew_bf_unpack_image(NULL, a, 4, &ov2, &v);
        CHECK_EQ_INT(za, 2);
        CHECK_EQ_INT(zb, 2);
        CHECK(memcmp(out, out2, (size_t)rs * h * sizeof(float)) == 0);
        CHECK(out[4] == -7.0f && out[rs - 1] == -7.0f);
        free(out);
        free(out2);
        free(a);
        free(b);
    }
    ew_device_destroy(dev);
    free(mem);
}

/* Views of packed floats (3 or 4 a pixel, 1 for a depth) take branch-free
 * loops: the same floats and counts as the general loops give for the same
 * pixels in a padded view. */
TEST(packed_views_pack_as_padded_views_do) {
    const int w = 29, h = 11;
    const size_t n = (size_t)w * h;
    ew_device *dev = make_device(2);
    for (int C = 1; C <= 4; C++) {
        if (C == 2) continue;
        const int ps = C + 2, rs = w * ps + 5;
        float *packed = malloc(sizeof(float) * n * C), *padded = calloc((size_t)rs * h, sizeof(float));
        unsigned seed = 31u + (unsigned)C;
        for (size_t i = 0; i < n * C; i++) packed[i] = 3.0f * urand(&seed) - 1.0f;
        packed[7 * C] = NAN;
        packed[20 * C + C - 1] = -INFINITY;
        packed[(n - 1) * C] = INFINITY;
        for (size_t j = 0; j < n; j++)
            for (int c = 0; c < C; c++) padded[(j / w) * rs + (j % w) * ps + c] = packed[j * C + c];
        ew_image vp = ew_image_packed(packed, w, h, C), vq = {padded, w, h, C, (int64_t)ps * 4, (int64_t)rs * 4, EW_FORMAT_FLOAT};
        float *a = calloc(n * 4, sizeof(float)), *b = calloc(n * 4, sizeof(float));
        if (C >= 3) {
            CHECK_EQ_INT(ew_bf_pack_image_planes(dev, &vp, C, a), ew_bf_pack_image_planes(dev, &vq, C, b));
            CHECK(memcmp(a, b, n * 4 * sizeof(float)) == 0);
        }
        for (int stride = 1; stride <= 4; stride += 3) {
            long ba = 0, bb = 0;
            ew_bf_pack_channels_planes(dev, &vp, stride, a, &ba);
            ew_bf_pack_channels_planes(dev, &vq, stride, b, &bb);
            CHECK_EQ_INT(ba, bb);
            CHECK(memcmp(a, b, n * (size_t)stride * sizeof(float)) == 0);
        }
        if (C >= 3) { /* unpack: alpha from another view, and onto the colour itself */
            ew_bf_pack_image_planes(dev, &vp, C, a);
            a[4 * n - 3] = 0.0f; /* a pixel with nothing in reach */
            float *op = malloc(sizeof(float) * n * C), *oq = malloc(sizeof(float) * (size_t)rs * h);
            ew_image vop = ew_image_packed(op, w, h, C), voq = vq;
            voq.data = oq;
            for (int self = 0; self < 2; self++) {
                for (size_t i = 0; i < n * C; i++) op[i] = packed[i];
                for (size_t i = 0; i < (size_t)rs * h; i++) oq[i] = padded[i];
                const ew_image *alpha_p = self ? &vop : &vp, *alpha_q = self ? &voq : &vq;
                CHECK_EQ_INT(ew_bf_unpack_image_planes(dev, a, C, &vop, alpha_p),
                             ew_bf_unpack_image_planes(dev, a, C, &voq, alpha_q));
                int same = 1;
                for (size_t j = 0; j < n; j++)
                    for (int c = 0; c < C; c++)
                        same &= memcmp(&op[j * C + c], &oq[(j / w) * rs + (j % w) * ps + c], sizeof(float)) == 0;
                CHECK(same);
            }
            free(op);
            free(oq);
        }
        free(a); free(b); free(packed); free(padded);
    }
    ew_device_destroy(dev);
}

TEST(constant_image_stays_constant) {
    ew_device *dev = make_device(2);
    for (int t = 0; t < 2; t++) {
        pic p = make_pic(23, 17, 3, 1);
        for (long i = 0; i < 23 * 17 * 3; i++) p.in[i] = 0.25f + 0.25f * (i % 3);
        CHECK_EQ_INT(run_filter(exact_types[t], &p, 3, 6, 0.1f, NULL, 0, dev), EW_OK);
        for (long i = 0; i < 23 * 17 * 3; i++) CHECK_NEAR(p.out[i], p.in[i], 1e-6);
        free_pic(&p);
    }
    ew_device_destroy(dev);
}

TEST(radius_zero_is_identity_and_odd_sizes_work) {
    ew_device *dev = make_device(2);
    const int sizes[][2] = {{1, 1}, {3, 7}, {7, 3}, {1, 9}};
    for (int t = 0; t < 2; t++)
        for (int s = 0; s < 4; s++) {
            pic p = make_pic(sizes[s][0], sizes[s][1], 3, 7 + s);
            CHECK_EQ_INT(run_filter(exact_types[t], &p, 0, 0, 0.1f, NULL, 0, dev), EW_OK);
            CHECK(memcmp(p.in, p.out, sizeof(float) * sizes[s][0] * sizes[s][1] * 3) == 0);
            /* a radius far beyond the image: the mean of everything (range off) */
            CHECK_EQ_INT(run_filter(exact_types[t], &p, 3, 200, 0.1f, NULL, 0, dev), EW_OK);
            double mean[3] = {0, 0, 0};
            long n = (long)sizes[s][0] * sizes[s][1];
            for (long i = 0; i < n; i++)
                for (int c = 0; c < 3; c++) mean[c] += p.in[i * 3 + c] / n;
            for (long i = 0; i < n; i++) CHECK(isfinite(p.out[i * 3]));
            if (t == 0) CHECK_NEAR(p.out[0], mean[0], 1e-3); /* sigma 66: weights within 1 % over <= 9 px */
            free_pic(&p);
        }
    ew_device_destroy(dev);
}

TEST(step_edge_in_guide_is_not_crossed) {
    ew_device *dev = make_device(2);
    const int w = 40, h = 20;
    float *guide = malloc(sizeof(float) * w * h);
    for (int t = 0; t < 2; t++) {
        pic p = make_pic(w, h, 1, 3);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                guide[y * w + x] = x < 17 ? 0.0f : 1.0f;
                p.in[y * w + x] = (x < 17 ? 0.2f : 3.0f) + 0.01f * (p.in[y * w + x] - 0.5f);
            }
        CHECK_EQ_INT(run_filter(exact_types[t], &p, 0, 12, 0.05f, guide, 1, dev), EW_OK);
        for (int y = 0; y < h; y++) {
            CHECK_NEAR(p.out[y * w + 16], 0.2, 0.006);
            CHECK_NEAR(p.out[y * w + 17], 3.0, 0.006);
        }
        free_pic(&p);
    }
    free(guide);
    ew_device_destroy(dev);
}

TEST(non_finite_samples_are_contained) {
    ew_device *dev = make_device(2);
    for (int t = 0; t < 2; t++) {
        pic p = make_pic(16, 12, 3, 5);
        p.in[(5 * 16 + 5) * 3 + 1] = NAN;
        p.in[(2 * 16 + 9) * 3 + 0] = INFINITY;
        p.in[(8 * 16 + 3) * 3 + 2] = -INFINITY;
        CHECK_EQ_INT(run_filter(exact_types[t], &p, 0, 4, 0.5f, NULL, 0, dev), EW_OK);
        for (long i = 0; i < 16 * 12 * 3; i++) CHECK(isfinite(p.out[i]));
        /* the NaN pixel is rebuilt from its neighbours: within their range */
        CHECK(p.out[(5 * 16 + 5) * 3 + 1] > 0.0f && p.out[(5 * 16 + 5) * 3 + 1] < 1.0f);
        free_pic(&p);
    }
    ew_device_destroy(dev);
}

TEST(errors_name_the_problem) {
    ew_device *dev = make_device(1);
    pic p = make_pic(8, 8, 3, 9);
    ew_filter *f = NULL;
    CHECK_EQ_INT(ew_filter_create(dev, "bilateral", &f), EW_OK);
    ew_image in = ew_image_packed(p.in, 8, 8, 3), out1 = ew_image_packed(p.out, 8, 8, 1);
    CHECK_EQ_INT(ew_filter_set_image(f, "color", &in), EW_OK);
    CHECK_EQ_INT(ew_filter_set_image(f, "output", &out1), EW_OK);
    CHECK_EQ_INT(ew_filter_commit(f), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "'output' has 1 channels");
    ew_image out = ew_image_packed(p.out, 8, 8, 3);
    CHECK_EQ_INT(ew_filter_set_image(f, "output", &out), EW_OK);
    CHECK_EQ_INT(ew_filter_set_int(f, "model", 1), EW_OK);
    CHECK_EQ_INT(ew_filter_commit(f), EW_ERR_INVALID_STATE);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "'normal'");
    CHECK_EQ_INT(ew_filter_set_int(f, "model", 4), EW_ERR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "'model'");
    CHECK_EQ_INT(ew_filter_set_int(f, "radius", -1), EW_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(ew_filter_set_data(f, "weights", "x", 1), EW_ERR_INVALID_ARGUMENT);
    ew_filter_destroy(f);
    free_pic(&p);
    ew_device_destroy(dev);
}
