/* The edge-avoiding à-trous filter against its definition (Dammertz et al.
 * 2010, Eq. 3-5 with the luminance term), written again in double; and its
 * properties through the public API. */
#include "ew_test.h"

#include <stdlib.h>

#include "algorithms/atrous.h"
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

static double lum(const double *v) { return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]; }

/* n iterations of h = (1 4 6 4 1)/16 with holes 2^i, weights
 * exp(-dL^2/(sl 2^-i)^2 - |dn|^2/sn^2 - dz^2/sz^2), 3 meaningful channels */
static void atrous_ref(int w, int h, int n, const float *in, const float *nrm, const float *z, double sl, double sn,
                       double sz, double *out) {
    const double hk[5] = {1 / 16.0, 1 / 4.0, 3 / 8.0, 1 / 4.0, 1 / 16.0};
    double *cur = malloc(sizeof(double) * w * h * 3), *nxt = malloc(sizeof(double) * w * h * 3);
    for (long i = 0; i < (long)w * h; i++)
        for (int c = 0; c < 3; c++) cur[i * 3 + c] = in[i * EW_BF_CH + c];
    for (int it = 0; it < n; it++) {
        int step = 1 << it;
        double s = sl / (1 << it);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                long p = (long)y * w + x;
                double acc[3] = {0, 0, 0}, ws = 0;
                for (int ty = -2; ty <= 2; ty++)
                    for (int tx = -2; tx <= 2; tx++) {
                        int qx = x + tx * step, qy = y + ty * step;
                        if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
                        long q = (long)qy * w + qx;
                        double dl = lum(cur + q * 3) - lum(cur + p * 3);
                        double dn = 0;
                        for (int k = 0; k < 3; k++) dn += (nrm[p * 3 + k] - nrm[q * 3 + k]) * (double)(nrm[p * 3 + k] - nrm[q * 3 + k]);
                        double dz = (double)z[p] - z[q];
                        double wt = hk[tx + 2] * hk[ty + 2] * exp(-dl * dl / (s * s) - dn / (sn * sn) - dz * dz / (sz * sz));
                        for (int c = 0; c < 3; c++) acc[c] += wt * cur[q * 3 + c];
                        ws += wt;
                    }
                for (int c = 0; c < 3; c++) nxt[p * 3 + c] = acc[c] / ws;
            }
        double *t = cur;
        cur = nxt;
        nxt = t;
    }
    memcpy(out, cur, sizeof(double) * w * h * 3);
    free(cur);
    free(nxt);
}

TEST(matches_definition) {
    const int w = 29, h = 23;
    unsigned s = 3;
    float *in = malloc(sizeof(float) * w * h * EW_BF_CH), *nrm = malloc(sizeof(float) * w * h * 3);
    float *z = malloc(sizeof(float) * w * h), *tmp = malloc(sizeof(float) * w * h * EW_BF_CH);
    float *out = malloc(sizeof(float) * w * h * EW_BF_CH);
    double *ref = malloc(sizeof(double) * w * h * 3);
    for (int i = 0; i < w * h; i++) {
        for (int c = 0; c < 4; c++) in[i * 4 + c] = c < 3 ? urand(&s) : 1.0f; /* mask 1: all valid */
        for (int c = 0; c < 3; c++) nrm[i * 3 + c] = urand(&s) - 0.5f;
        z[i] = 1.0f + urand(&s);
    }
    ew_device *dev = make_device(3);
    for (int n = 1; n <= 4; n++) {
        ew_atrous_run(dev, w, h, 3, n, in, tmp, out, nrm, z, 0.4f, 0.6f, 0.5f);
        atrous_ref(w, h, n, in, nrm, z, 0.4, 0.6, 0.5, ref);
        double worst = 0;
        for (int i = 0; i < w * h; i++)
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(out[i * 4 + c] - ref[i * 3 + c]));
        CHECK(worst < 2e-5);
    }
    CHECK_EQ_INT(ew_atrous_iterations_for(0), 0);
    CHECK_EQ_INT(ew_atrous_iterations_for(2), 1);
    CHECK_EQ_INT(ew_atrous_iterations_for(24), 4); /* support 2 (2^4 - 1) = 30 */
    ew_device_destroy(dev);
    free(in); free(nrm); free(z); free(tmp); free(out); free(ref);
}

static ew_result run_api(ew_device *dev, int w, int h, const float *in, float *out, const float *nrm, int radius) {
    ew_filter *f = NULL;
    ew_result r = ew_filter_create(dev, "atrous", &f);
    ew_image vi = ew_image_packed((float *)in, w, h, 3), vo = ew_image_packed(out, w, h, 3);
    ew_image vn = ew_image_packed((float *)nrm, w, h, 3);
    if (r == EW_OK) r = ew_filter_set_image(f, "color", &vi);
    if (r == EW_OK) r = ew_filter_set_image(f, "output", &vo);
    if (r == EW_OK && nrm) r = ew_filter_set_image(f, "normal", &vn);
    if (r == EW_OK) r = ew_filter_set_int(f, "radius", radius);
    if (r == EW_OK) r = ew_filter_commit(f);
    if (r == EW_OK) r = ew_filter_execute(f);
    ew_filter_destroy(f);
    return r;
}

TEST(constant_stays_constant_edges_hold_nan_contained) {
    const int w = 40, h = 30;
    float *in = malloc(sizeof(float) * w * h * 3), *out = malloc(sizeof(float) * w * h * 3);
    float *nrm = malloc(sizeof(float) * w * h * 3);
    for (int i = 0; i < w * h * 3; i++) in[i] = 0.7f;
    ew_device *dev = make_device(2);
    CHECK_EQ_INT(run_api(dev, w, h, in, out, NULL, 16), EW_OK);
    for (int i = 0; i < w * h * 3; i++) CHECK_NEAR(out[i], 0.7, 1e-6);
    /* a normal edge: the two sides do not mix */
    for (int i = 0; i < w * h; i++) {
        int left = i % w < 19;
        for (int c = 0; c < 3; c++) {
            in[i * 3 + c] = left ? 0.2f : 0.8f;
            nrm[i * 3 + c] = c == 2 ? (left ? 1.0f : 0.0f) : (c == 0 && !left ? 1.0f : 0.0f);
        }
    }
    CHECK_EQ_INT(run_api(dev, w, h, in, out, nrm, 16), EW_OK);
    for (int y = 0; y < h; y++) {
        CHECK_NEAR(out[(y * w + 18) * 3], 0.2, 1e-3);
        CHECK_NEAR(out[(y * w + 19) * 3], 0.8, 1e-3);
    }
    in[(5 * w + 5) * 3] = NAN;
    in[(7 * w + 30) * 3 + 2] = INFINITY;
    CHECK_EQ_INT(run_api(dev, w, h, in, out, nrm, 16), EW_OK);
    for (int i = 0; i < w * h * 3; i++) CHECK(isfinite(out[i]));
    CHECK_NEAR(out[(5 * w + 5) * 3], 0.2, 1e-3);
    /* radius 0: the identity */
    CHECK_EQ_INT(run_api(dev, w, h, in, out, nrm, 0), EW_OK);
    CHECK(out[(9 * w + 9) * 3] == in[(9 * w + 9) * 3]);
    ew_device_destroy(dev);
    free(in); free(out); free(nrm);
}
