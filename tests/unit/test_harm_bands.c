/* The do-no-harm stage's windowed steps on the CPU in bands of rows. The
 * blend (EW_HARM_STATS_BLEND): the statistics of each band's rows and edges
 * and the blend from them give, bit for bit, STATS then BLEND over a frame
 * of statistics; the energy return (EW_HARM_RETURN) and the pilot's blend
 * (EW_HARM_PILOT_HV), their sums along the rows a band at a time, give the
 * bits of their steps over the frame's planes — band sizes of one row, odd
 * sizes that leave a short last band, bands shorter than the window, one
 * band, the backend's own choice; 1 and 3 threads; an RGBA input with
 * NaN/Inf and fireflies, with and without the share given back. And a lone
 * bright sample in the residual reads as noise. */
#include "ew_test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "edgewise/edgewise.h"
#include "kernels/harm.h"
#include "src/backend.h"
#include "src/internal.h"

enum { W = 37, H = 29, N = W * H };

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)(*s >> 8) / 16777216.0f;
}

static float *field(size_t n, float lo, float hi, unsigned seed, int holes) {
    float *p = (float *)malloc(n * sizeof(float));
    unsigned s = seed;
    for (size_t i = 0; i < n; i++) p[i] = lo + (hi - lo) * urand(&s);
    if (holes)
        for (size_t i = 5; i < n; i += 53) p[i] = i % 2 ? NAN : INFINITY;
    for (size_t i = 17; i < n; i += 97) p[i] = 400.0f;
    return p;
}

/* a CPU device of `threads` threads (the caller counted), or NULL */
static ew_device *device_of(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

static int same_bits(const float *a, const float *b, size_t n) {
    return memcmp(a, b, n * sizeof(float)) == 0;
}

/* the blend's arguments over the W x H frame that both tests share */
static ew_harm_args frame_args(int channels, float *clamped, int radius) {
    ew_harm_args a;
    memset(&a, 0, sizeof a);
    a.width = W;
    a.height = H;
    a.channels = channels;
    a.clamped = clamped;
    a.radius = radius;
    a.z = 1.0f;
    return a;
}

TEST(bands_give_the_frames_bits) {
    const int threads[] = {1, 3};
    const int rows[] = {1, 2, 3, 5, 7, 11, 29, 0};
    float *clamped = field((size_t)N * 4, 0.0f, 2.0f, 3, 1), *out0 = field((size_t)N * 3, 0.0f, 2.0f, 7, 1);
    float *give0 = field((size_t)N, 0.0f, 1.0f, 11, 0);
    float *out = malloc((size_t)N * 3 * sizeof(float)), *ref = malloc((size_t)N * 3 * sizeof(float));
    float *give = malloc((size_t)N * sizeof(float)), *gref = malloc((size_t)N * sizeof(float));
    float *stats = malloc((size_t)N * EW_HARM_STATS_FLOATS * sizeof(float));
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        ew_device *dev = device_of(threads[t]);
        CHECK(dev != NULL);
        CHECK(dev->backend->harm_bands);
        for (int radius = 3; radius <= 4; radius++)
            for (int with_give = 0; with_give < 2; with_give++) {
                ew_harm_args a = frame_args(4, clamped, radius);
                a.stats = stats;
                a.strength = 2.0f;
                a.theta = 0.1f;
                a.kappa = 0.9f;
                a.theta_n = 0.05f;
                a.tone_share = 0.5f;
                a.fade = radius == 4 ? 0.25f : 0.0f;
                /* the frame: STATS then BLEND */
                memcpy(ref, out0, (size_t)N * 3 * sizeof(float));
                memcpy(gref, give0, (size_t)N * sizeof(float));
                a.out = ref;
                a.give = with_give ? gref : NULL;
                dev->backend->harm(dev, EW_HARM_STATS, &a);
                dev->backend->harm(dev, EW_HARM_BLEND, &a);
                int blended = 0;
                for (int i = 0; i < N * 3; i++) blended += memcmp(&ref[i], &out0[i], sizeof(float)) != 0;
                CHECK(blended > N / 4); /* the blend does something here */
                for (size_t k = 0; k < sizeof rows / sizeof rows[0]; k++) {
                    memcpy(out, out0, (size_t)N * 3 * sizeof(float));
                    memcpy(give, give0, (size_t)N * sizeof(float));
                    for (size_t i = 0; i < (size_t)N * EW_HARM_STATS_FLOATS; i++) stats[i] = NAN;
                    a.out = out;
                    a.give = with_give ? give : NULL;
                    a.stats = NULL; /* the bands hold their own */
                    a.band_rows = rows[k];
                    dev->backend->harm(dev, EW_HARM_STATS_BLEND, &a);
                    a.stats = stats;
                    a.band_rows = 0;
                    if (!same_bits(out, ref, (size_t)N * 3) || (with_give && !same_bits(give, gref, (size_t)N)))
                        FAIL_AT("threads %d, radius %d, give %d, band rows %d: not the frame's bits", threads[t], radius,
                                with_give, rows[k]);
                }
            }
        ew_device_destroy(dev);
    }
    free(clamped);
    free(out0);
    free(give0);
    free(out);
    free(ref);
    free(give);
    free(gref);
    free(stats);
}

/* The blend's second estimate counts a pixel in R_lin as often as in the
 * Haar detail H (kernels/harm.h), so one bright sample alone in the
 * residual reads as noise (D = 0, alpha 1) wherever it lies in a window:
 * with each pixel's own square in R_lin, the windows holding it on their
 * top or left edge read half of it or more as structure. Alpha is seen in
 * the share of the clamps' light each pixel keeps (give, scaled by alpha
 * where the blend acts; the output itself equals the input but at the
 * sample). The frame and the bands alike. */
TEST(a_lone_sample_reads_as_noise_anywhere_in_the_window) {
    float *clamped = calloc((size_t)N * 3, sizeof(float)), *out = calloc((size_t)N * 3, sizeof(float));
    float *give = malloc((size_t)N * sizeof(float));
    float *stats = malloc((size_t)N * EW_HARM_STATS_FLOATS * sizeof(float));
    for (int c = 0; c < 3; c++) clamped[(14 * W + 18) * 3 + c] = 5.0f;
    ew_device *dev = NULL;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    for (int banded = 0; dev && banded < 2; banded++) {
        for (int i = 0; i < N; i++) give[i] = 1.0f;
        ew_harm_args a = frame_args(3, clamped, 4);
        a.out = out;
        a.give = give;
        a.stats = banded ? NULL : stats;
        a.theta = 0.4f; /* strength 0: the first estimate says nothing */
        a.kappa = 1.0f;
        a.theta_n = 0.0f;
        if (banded) {
            dev->backend->harm(dev, EW_HARM_STATS_BLEND, &a);
        } else {
            dev->backend->harm(dev, EW_HARM_STATS, &a);
            dev->backend->harm(dev, EW_HARM_BLEND, &a);
        }
        int blended = 0;
        for (int i = 0; i < N; i++) blended += give[i] != 1.0f;
        if (blended) FAIL_AT("%s: %d pixels' alpha below 1 around a lone sample", banded ? "bands" : "frame", blended);
    }
    ew_device_destroy(dev);
    free(clamped);
    free(out);
    free(give);
    free(stats);
}

/* EW_HARM_RETURN against SUM_H, SUM_V, GIVE, SPREAD_H, SPREAD_V, and
 * EW_HARM_PILOT_HV against PILOT_H, PILOT_V (after PILOT_SQ), over the
 * frame's spread planes: the output and the shares given back, bit for bit.
 * The energy return with the clamped colour and fused (give holding the
 * light already); windows wider than the frame and narrower than a band. */
TEST(the_energy_return_and_the_pilots_blend_in_bands_give_the_frames_bits) {
    const int threads[] = {1, 3};
    const int rows[] = {1, 2, 5, 7, 29, 0};
    float *clamped = field((size_t)N * 4, 0.0f, 2.0f, 3, 1), *out0 = field((size_t)N * 3, 0.0f, 2.0f, 7, 1);
    float *give0 = field((size_t)N, 0.0f, 1.0f, 11, 0), *pilot0 = field((size_t)N * 3, 0.0f, 2.0f, 13, 0);
    float *out = malloc((size_t)N * 3 * sizeof(float)), *ref = malloc((size_t)N * 3 * sizeof(float));
    float *give = malloc((size_t)N * sizeof(float)), *gref = malloc((size_t)N * sizeof(float));
    float *pilot = malloc((size_t)N * 3 * sizeof(float)), *spread = malloc((size_t)N * 2 * sizeof(float));
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        ew_device *dev = device_of(threads[t]);
        CHECK(dev != NULL);
        for (int kind = 0; kind < 4; kind++) {
            /* 0, 1: the energy return (1 fused), radius 3 then 24; 2, 3: the pilot's blend, radius 4 */
            const int pilot_step = kind >= 2, radius = kind == 1 ? 24 : kind == 0 ? 3 : 4;
            ew_harm_args a = frame_args(4, clamped, radius);
            a.give_radius = radius;
            a.fused = kind == 1;
            a.give_limit = 3.0f;
            a.give_gain = 0.5f;
            a.pilot_share = kind == 3 ? 0.6f : 1.0f;
            a.spread = spread;
            memcpy(ref, out0, (size_t)N * 3 * sizeof(float));
            memcpy(gref, give0, (size_t)N * sizeof(float));
            memcpy(pilot, pilot0, (size_t)N * 3 * sizeof(float));
            a.out = ref;
            a.give = gref;
            a.pilot = pilot;
            if (pilot_step) {
                dev->backend->harm(dev, EW_HARM_PILOT_SQ, &a);
                dev->backend->harm(dev, EW_HARM_PILOT_H, &a);
                dev->backend->harm(dev, EW_HARM_PILOT_V, &a);
            } else {
                for (int st = EW_HARM_SUM_H; st <= EW_HARM_SPREAD_V; st++) dev->backend->harm(dev, st, &a);
            }
            int changed = 0;
            for (int i = 0; i < N * 3; i++) changed += memcmp(&ref[i], &out0[i], sizeof(float)) != 0;
            CHECK(changed > N / 4); /* the step does something here */
            for (size_t k = 0; k < sizeof rows / sizeof rows[0]; k++) {
                memcpy(out, out0, (size_t)N * 3 * sizeof(float));
                memcpy(give, give0, (size_t)N * sizeof(float));
                memcpy(pilot, pilot0, (size_t)N * 3 * sizeof(float));
                a.out = out;
                a.give = give;
                a.spread = NULL; /* the bands hold their own sums */
                a.band_rows = rows[k];
                if (pilot_step) dev->backend->harm(dev, EW_HARM_PILOT_SQ, &a);
                dev->backend->harm(dev, pilot_step ? EW_HARM_PILOT_HV : EW_HARM_RETURN, &a);
                a.spread = spread;
                a.band_rows = 0;
                if (!same_bits(out, ref, (size_t)N * 3) || !same_bits(give, gref, (size_t)N))
                    FAIL_AT("threads %d, %s radius %d%s, band rows %d: not the frame's bits", threads[t],
                            pilot_step ? "pilot" : "return", radius, a.fused ? " fused" : "", rows[k]);
            }
        }
        ew_device_destroy(dev);
    }
    free(clamped);
    free(out0);
    free(give0);
    free(pilot0);
    free(out);
    free(ref);
    free(give);
    free(gref);
    free(pilot);
    free(spread);
}
