#include "ew_test.h"

#include "src/weights.h"

static ew_weights sample(float *a, float *b) {
    static ew_tensor t[2];
    memset(t, 0, sizeof t);
    strcpy(t[0].name, "conv1.w");
    t[0].rank = 2; t[0].dims[0] = 2; t[0].dims[1] = 3; t[0].count = 6; t[0].data = a;
    strcpy(t[1].name, "conv1.b");
    t[1].rank = 1; t[1].dims[0] = 2; t[1].count = 2; t[1].data = b;
    ew_weights w;
    memset(&w, 0, sizeof w);
    strcpy(w.arch, "test-arch");
    w.num_tensors = 2;
    w.tensors = t;
    return w;
}

TEST(round_trip) {
    float a[6] = {1, 2, 3, 4, 5, -6}, b[2] = {0.5f, -0.25f};
    ew_weights w = sample(a, b);
    void *buf; size_t n; char err[256];
    CHECK_EQ_INT(ew_weights_serialize(&w, &buf, &n), 0);
    ew_weights r;
    CHECK_EQ_INT(ew_weights_parse(buf, n, &r, err, sizeof err), 0);
    CHECK(strcmp(r.arch, "test-arch") == 0);
    uint32_t dims[2] = {2, 3};
    const ew_tensor *t = ew_weights_find(&r, "conv1.w", 2, dims, err, sizeof err);
    CHECK(t && memcmp(t->data, a, sizeof a) == 0);
    uint32_t wrong[2] = {3, 2};
    CHECK(ew_weights_find(&r, "conv1.w", 2, wrong, err, sizeof err) == NULL);
    CHECK_STR_CONTAINS(err, "wrong shape");
    CHECK(ew_weights_find(&r, "conv9.w", 2, dims, err, sizeof err) == NULL);
    CHECK_STR_CONTAINS(err, "no tensor 'conv9.w'");
    ew_weights_free(&r);
    free(buf);
}

TEST(every_damage_is_detected) {
    float a[6] = {1, 2, 3, 4, 5, 6}, b[2] = {7, 8};
    ew_weights w = sample(a, b);
    void *buf; size_t n; char err[256];
    CHECK_EQ_INT(ew_weights_serialize(&w, &buf, &n), 0);
    unsigned char *copy = malloc(n);
    /* flip every byte in turn: always rejected, never a crash */
    for (size_t i = 0; i < n; i++) {
        memcpy(copy, buf, n);
        copy[i] ^= 0x5A;
        ew_weights r;
        CHECK(ew_weights_parse(copy, n, &r, err, sizeof err) != 0);
    }
    /* every truncation rejected */
    for (size_t k = 0; k < n; k++) {
        ew_weights r;
        CHECK(ew_weights_parse(buf, k, &r, err, sizeof err) != 0);
    }
    ew_weights r;
    memcpy(copy, buf, n);
    copy[0] = 'X';
    CHECK(ew_weights_parse(copy, n, &r, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "bad magic");
    free(copy);
    free(buf);
}

TEST(non_finite_values_rejected) {
    float a[6] = {1, 2, NAN, 4, 5, 6}, b[2] = {7, 8};
    ew_weights w = sample(a, b);
    void *buf; size_t n; char err[256];
    CHECK_EQ_INT(ew_weights_serialize(&w, &buf, &n), 0);
    ew_weights r;
    CHECK(ew_weights_parse(buf, n, &r, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "non-finite");
    free(buf);
}

TEST(overflowing_values_rejected) {
    /* finite, valid checksum, but a network of FLT_MAX weights overflows to
     * NaN and the denoised output goes black */
    float a[6] = {1, 2, 3.4e38f, 4, 5, 6}, b[2] = {7, -2e7f};
    ew_weights w = sample(a, b);
    void *buf; size_t n; char err[256];
    CHECK_EQ_INT(ew_weights_serialize(&w, &buf, &n), 0);
    ew_weights r;
    CHECK(ew_weights_parse(buf, n, &r, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "beyond any trained weight");
    free(buf);
    a[2] = 3;
    CHECK_EQ_INT(ew_weights_serialize(&w, &buf, &n), 0);
    CHECK(ew_weights_parse(buf, n, &r, err, sizeof err) != 0); /* b[1] still too large */
    free(buf);
    b[1] = -2e5f;
    CHECK_EQ_INT(ew_weights_serialize(&w, &buf, &n), 0);
    CHECK_EQ_INT(ew_weights_parse(buf, n, &r, err, sizeof err), 0);
    ew_weights_free(&r);
    free(buf);
}
