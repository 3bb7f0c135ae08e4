/* filter "outlier": a planted firefly goes, bright structure of its own
 * albedo or normal stays (and would go without the features), NaN/Inf are
 * rebuilt, a constant image is unchanged, and random frames match a
 * double-precision transcription of the rule. */
#include "ew_test.h"

#include "edgewise/edgewise.h"

enum { W = 40, H = 30, N = W * H };

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)(*s >> 8) / 16777216.0f;
}

static float color[N * 3], albedo[N * 3], normal[N * 3], out[N * 3];

/* Run the filter; albedo/normal may be NULL; extra params as name/value. */
static int run(ew_device *dev, const float *alb, const float *nrm, float k, float *dst) {
    ew_filter *f = NULL;
    if (ew_filter_create(dev, "outlier", &f) != EW_OK) return 0;
    ew_image c = ew_image_packed(color, W, H, 3), o = ew_image_packed(dst, W, H, 3);
    ew_image a = ew_image_packed((float *)alb, W, H, 3), n = ew_image_packed((float *)nrm, W, H, 3);
    int ok = ew_filter_set_image(f, "color", &c) == EW_OK && ew_filter_set_image(f, "output", &o) == EW_OK &&
             ew_filter_set_image(f, "albedo", alb ? &a : NULL) == EW_OK &&
             ew_filter_set_image(f, "normal", nrm ? &n : NULL) == EW_OK &&
             ew_filter_set_float(f, "k", k) == EW_OK && ew_filter_commit(f) == EW_OK && ew_filter_execute(f) == EW_OK;
    ew_filter_destroy(f);
    return ok;
}

static float lum(const float *p) { return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2]; }

/* Grey noise 0.5 +- 0.05 on one material facing +z: within the default
 * sigma_floor (10 % of the mean, times k = 3) by a wide margin, so any
 * change to it is the filter's mistake. */
static void background(unsigned seed) {
    unsigned s = seed;
    for (int i = 0; i < N; i++) {
        float v = 0.5f + 0.1f * (urand(&s) - 0.5f);
        for (int c = 0; c < 3; c++) {
            color[i * 3 + c] = v;
            albedo[i * 3 + c] = 0.5f;
            normal[i * 3 + c] = c == 2 ? 1.0f : 0.0f;
        }
    }
}

TEST(is_listed_with_its_parameters) {
    int found = 0;
    for (int32_t i = 0; i < ew_method_count("filter"); i++) {
        const char *nm;
        int32_t ni, np;
        CHECK_EQ_INT(ew_method_get("filter", i, &nm, NULL, &ni, &np), EW_OK);
        if (strcmp(nm, "outlier")) continue;
        found = 1;
        CHECK_EQ_INT(ni, 4);
        CHECK_EQ_INT(np, 6);
        ew_param_info p;
        CHECK_EQ_INT(ew_method_param("filter", "outlier", 1, &p), EW_OK);
        CHECK(!strcmp(p.name, "k"));
        CHECK_NEAR(p.default_value, 3.0, 0.0);
    }
    CHECK(found);
}

TEST(planted_firefly_is_removed_and_nothing_else_moves) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    background(1);
    const int f = 12 * W + 17;
    for (int c = 0; c < 3; c++) color[f * 3 + c] = 60.0f;
    CHECK(run(dev, albedo, normal, 3.0f, out));
    CHECK(lum(out + f * 3) < 1.0f);
    CHECK(lum(out + f * 3) > 0.5f); /* clamped to the bound, not zeroed */
    for (int i = 0; i < N * 3; i++)
        if (i / 3 != f) CHECK_NEAR(out[i], color[i], 0.0);
    /* and with no features at all, as the denoisers' clamp */
    CHECK(run(dev, NULL, NULL, 3.0f, out));
    CHECK(lum(out + f * 3) < 1.0f);
    ew_device_destroy(dev);
}

TEST(bright_structure_of_its_own_material_is_kept) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    background(2);
    /* right half: a bright material; a 2x1 bright object of its own albedo
     * on the left; a 2x1 bright facet (other normal, same albedo) too */
    for (int y = 0; y < H; y++)
        for (int x = W / 2; x < W; x++)
            for (int c = 0; c < 3; c++) {
                color[(y * W + x) * 3 + c] *= 8.0f;
                albedo[(y * W + x) * 3 + c] = 0.9f;
            }
    const int obj = 8 * W + 6, facet = 20 * W + 6;
    for (int d = 0; d < 2; d++)
        for (int c = 0; c < 3; c++) {
            color[(obj + d) * 3 + c] = 30.0f;
            albedo[(obj + d) * 3 + c] = c == 0 ? 0.9f : 0.1f;
            color[(facet + d) * 3 + c] = 30.0f;
            normal[(facet + d) * 3 + c] = c == 0 ? 1.0f : 0.0f;
        }
    CHECK(run(dev, albedo, normal, 3.0f, out));
    for (int i = 0; i < N * 3; i++) {
        CHECK_NEAR(out[i], color[i], 0.0);
    }
    /* the same frame without the features loses both small objects, so the
     * features are what keeps them */
    CHECK(run(dev, NULL, NULL, 3.0f, out));
    CHECK(lum(out + obj * 3) < 0.8f * 30.0f);
    CHECK(lum(out + facet * 3) < 0.8f * 30.0f);
    /* normals alone keep the facet but not the object (same normal as the floor) */
    CHECK(run(dev, NULL, normal, 3.0f, out));
    CHECK_NEAR(out[facet * 3], 30.0, 0.0);
    CHECK(lum(out + obj * 3) < 0.8f * 30.0f);
    ew_device_destroy(dev);
}

TEST(nan_and_inf_are_contained) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    background(3);
    color[(5 * W + 5) * 3 + 1] = NAN;
    color[(5 * W + 6) * 3 + 0] = INFINITY;
    color[(20 * W + 30) * 3 + 2] = -INFINITY;
    albedo[(10 * W + 10) * 3] = NAN; /* damaged features: not used, not spread */
    normal[(10 * W + 11) * 3 + 2] = INFINITY;
    color[(0 * W + 0) * 3] = NAN;   /* in a corner */
    CHECK(run(dev, albedo, normal, 3.0f, out));
    for (int i = 0; i < N * 3; i++) CHECK(isfinite(out[i]));
    /* rebuilt from the neighbours: inside the background's range */
    for (int c = 0; c < 3; c++) {
        CHECK(out[(5 * W + 5) * 3 + c] > 0.4f && out[(5 * W + 5) * 3 + c] < 0.6f);
        CHECK(out[(20 * W + 30) * 3 + c] > 0.4f && out[(20 * W + 30) * 3 + c] < 0.6f);
        CHECK(out[c] > 0.4f && out[c] < 0.6f);
    }
    /* k = 0: only the repair */
    CHECK(run(dev, albedo, normal, 0.0f, out));
    for (int i = 0; i < N * 3; i++) CHECK(isfinite(out[i]));
    /* nothing finite at all: zeros */
    for (int i = 0; i < N * 3; i++) color[i] = NAN;
    CHECK(run(dev, NULL, NULL, 3.0f, out));
    for (int i = 0; i < N * 3; i++) CHECK_NEAR(out[i], 0.0, 0.0);
    ew_device_destroy(dev);
}

TEST(constant_image_is_unchanged_also_in_place) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    const float values[] = {0.7f, 0.0f, -2.0f, 5e4f};
    for (int v = 0; v < 4; v++) {
        background(4);
        for (int i = 0; i < N * 3; i++) color[i] = values[v];
        CHECK(run(dev, albedo, normal, 3.0f, out));
        for (int i = 0; i < N * 3; i++) CHECK_NEAR(out[i], values[v], 0.0);
        CHECK(run(dev, albedo, normal, 3.0f, color)); /* output = the colour view */
        for (int i = 0; i < N * 3; i++) CHECK_NEAR(color[i], values[v], 0.0);
    }
    ew_device_destroy(dev);
}

/* The rule written out in double precision, pixel by pixel. Returns the
 * expected output of pixel j, and sets *borderline when the luminance is so
 * close to the bound that float rounding may decide either way. */
static void reference_px(int x, int y, float k, float tol, float ncos, const float *alb, const float *nrm, float *o,
                         int *borderline) {
    const int j = y * W + x;
    const float *p = color + j * 3;
    double l = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    double s = 0, s2 = 0;
    int n = 0;
    *borderline = 0;
    for (int c = 0; c < 3; c++) o[c] = p[c];
    for (int yy = y - 2; yy <= y + 2; yy++)
        for (int xx = x - 2; xx <= x + 2; xx++) {
            if (xx < 0 || yy < 0 || xx >= W || yy >= H || (xx == x && yy == y)) continue;
            const int q = yy * W + xx;
            int same = 1;
            for (int c = 0; c < 3; c++) same &= fabs((double)alb[j * 3 + c] - alb[q * 3 + c]) <= tol;
            double d = 0, l0 = 0, l1 = 0;
            for (int c = 0; c < 3; c++) {
                d += (double)nrm[j * 3 + c] * nrm[q * 3 + c];
                l0 += (double)nrm[j * 3 + c] * nrm[j * 3 + c];
                l1 += (double)nrm[q * 3 + c] * nrm[q * 3 + c];
            }
            same &= d >= ncos * sqrt(l0 * l1);
            if (!same) continue;
            const float *c1 = color + q * 3;
            double lq = 0.2126 * c1[0] + 0.7152 * c1[1] + 0.0722 * c1[2];
            s += lq;
            s2 += lq * lq;
            n++;
        }
    if (n < 3 || l <= 0) return;
    double m = s / n, sd = fmax(sqrt(fmax(s2 / n - m * m, 0.0)), 0.1 * fabs(m)), bound = m + k * sd;
    if (fabs(l - bound) < 1e-3 * bound) *borderline = 1;
    if (l > bound)
        for (int c = 0; c < 3; c++) o[c] = (float)(p[c] * (fmax(bound, 0.0) / l));
}

TEST(random_frames_match_the_rule) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    unsigned s = 11;
    int clamped = 0, checked = 0;
    for (int trial = 0; trial < 3; trial++) {
        for (int i = 0; i < N; i++) {
            /* four materials, two orientations, heavy-tailed radiance */
            int m = (int)(urand(&s) * 4.0f);
            float u = urand(&s), v = 0.3f + 0.4f * urand(&s);
            if (u > 0.97f) v *= 50.0f * urand(&s);
            int tilt = urand(&s) < 0.3f;
            for (int c = 0; c < 3; c++) {
                albedo[i * 3 + c] = 0.2f * (float)m + 0.01f * urand(&s) + (c == 1 ? 0.05f : 0.0f);
                color[i * 3 + c] = v * (0.8f + 0.4f * urand(&s));
                normal[i * 3 + c] = tilt ? (c == 0 ? 0.8f : (c == 2 ? 0.6f : 0.0f)) : (c == 2 ? 1.0f : 0.0f);
            }
        }
        CHECK(run(dev, albedo, normal, 2.5f, out));
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                float want[3];
                int border;
                reference_px(x, y, 2.5f, 0.1f, 0.9f, albedo, normal, want, &border);
                if (border) continue;
                const int j = y * W + x;
                for (int c = 0; c < 3; c++) CHECK_NEAR(out[j * 3 + c], want[c], 1e-4 * fabs(want[c]) + 1e-6);
                clamped += want[0] != color[j * 3];
                checked++;
            }
    }
    CHECK(checked > 3 * N * 9 / 10);
    CHECK(clamped > 20); /* the comparison saw the clamp at work */
    ew_device_destroy(dev);
}

/* RGBA in, RGBA out: alpha passes through untouched (OFX hosts hand over
 * 4-channel images; the output's alpha must not keep stale memory). */
TEST(alpha_passes_through) {
    ew_device *dev;
    CHECK_EQ_INT(ew_device_create(NULL, &dev), EW_OK);
    static float rgba[N * 4], orgba[N * 4];
    background(5);
    for (int i = 0; i < N; i++) {
        for (int c = 0; c < 3; c++) rgba[i * 4 + c] = color[i * 3 + c];
        rgba[i * 4 + 3] = (float)(i % 7) / 7.0f;
        orgba[i * 4 + 3] = -123.0f; /* stale */
    }
    ew_filter *f = NULL;
    CHECK_EQ_INT(ew_filter_create(dev, "outlier", &f), EW_OK);
    ew_image c = ew_image_packed(rgba, W, H, 4), o = ew_image_packed(orgba, W, H, 4);
    CHECK_EQ_INT(ew_filter_set_image(f, "color", &c), EW_OK);
    CHECK_EQ_INT(ew_filter_set_image(f, "output", &o), EW_OK);
    CHECK_EQ_INT(ew_filter_commit(f), EW_OK);
    CHECK_EQ_INT(ew_filter_execute(f), EW_OK);
    ew_filter_destroy(f);
    CHECK(run(dev, NULL, NULL, 3.0f, out)); /* the same colour as RGB */
    for (int i = 0; i < N; i++) {
        CHECK_NEAR(orgba[i * 4 + 3], (float)(i % 7) / 7.0f, 0.0);
        for (int k = 0; k < 3; k++) CHECK_NEAR(orgba[i * 4 + k], out[i * 3 + k], 0.0);
    }
    ew_device_destroy(dev);
}
