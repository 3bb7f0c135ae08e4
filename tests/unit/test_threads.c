/*
 * The threading contract of edgewise.h, run under ThreadSanitizer in CI:
 * two threads executing different ops on one device, a third on a second
 * device, each reading back its own last error while the others fail and
 * succeed; every output equals the same op run alone.
 */
#include "ew_test.h"

#include <pthread.h>

#include "edgewise/edgewise.h"

enum { W = 48, H = 32, ROUNDS = 6 };

static float input[W * H * 3];

static ew_device *cpu(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.type = EW_DEVICE_CPU;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

/* Run one op (kind "denoiser" bgrid or "filter" bilateral) into out. */
static ew_result run_op(ew_device *dev, int filter, float *out) {
    ew_image vi = ew_image_packed(input, W, H, 3), vo = ew_image_packed(out, W, H, 3);
    ew_result r;
    if (filter) {
        ew_filter *f = NULL;
        if ((r = ew_filter_create(dev, "bilateral", &f)) != EW_OK) return r;
        ew_filter_set_image(f, "color", &vi);
        ew_filter_set_image(f, "output", &vo);
        r = ew_filter_commit(f);
        if (r == EW_OK) r = ew_filter_execute(f);
        ew_filter_destroy(f);
    } else {
        ew_denoiser *d = NULL;
        if ((r = ew_denoiser_create(dev, "bgrid", &d)) != EW_OK) return r;
        ew_denoiser_set_image(d, "color", &vi);
        ew_denoiser_set_image(d, "output", &vo);
        r = ew_denoiser_commit(d);
        if (r == EW_OK) r = ew_denoiser_execute(d);
        ew_denoiser_destroy(d);
    }
    return r;
}

typedef struct {
    ew_device *dev;
    int filter;
    const char *bad_name; /* a parameter name only this thread uses */
    const float *expect;
    int ok;
    char why[256];
} worker;

static void *work(void *arg) {
    worker *w = (worker *)arg;
    static __thread float out[W * H * 3];
    w->ok = 1;
    for (int k = 0; k < ROUNDS && w->ok; k++) {
        if (run_op(w->dev, w->filter, out) != EW_OK) {
            snprintf(w->why, sizeof w->why, "run failed: %s", ew_device_last_error(w->dev));
            w->ok = 0;
        } else if (memcmp(out, w->expect, sizeof out) != 0) {
            snprintf(w->why, sizeof w->why, "output differs from the op run alone");
            w->ok = 0;
        }
        /* a failure of our own: the message must be ours, whatever the
         * other threads did on the device meanwhile */
        ew_filter *f = NULL;
        ew_filter_create(w->dev, "bilateral", &f);
        ew_result r = ew_filter_set_float(f, w->bad_name, 1.0f);
        const char *msg = ew_device_last_error(w->dev);
        if (r != EW_ERR_INVALID_ARGUMENT || !strstr(msg, w->bad_name)) {
            snprintf(w->why, sizeof w->why, "last error '%s' is not this thread's (%s)", msg, w->bad_name);
            w->ok = 0;
        }
        ew_filter_destroy(f);
    }
    return NULL;
}

TEST(two_threads_on_one_device_and_a_second_device) {
    for (int i = 0; i < W * H * 3; i++) input[i] = (float)((i * 2654435761u) % 1000u) / 1000.0f;
    static float expect_dn[W * H * 3], expect_bf[W * H * 3];
    ew_device *a = cpu(2), *b = cpu(2);
    CHECK(a && b);
    CHECK_EQ_INT(run_op(a, 0, expect_dn), EW_OK);
    CHECK_EQ_INT(run_op(a, 1, expect_bf), EW_OK);
    worker ws[3] = {
        {a, 0, "thread_one_param", expect_dn, 0, ""},
        {a, 1, "thread_two_param", expect_bf, 0, ""},
        {b, 0, "thread_three_param", expect_dn, 0, ""},
    };
    pthread_t t[3];
    for (int i = 0; i < 3; i++) CHECK(pthread_create(&t[i], NULL, work, &ws[i]) == 0);
    for (int i = 0; i < 3; i++) pthread_join(t[i], NULL);
    for (int i = 0; i < 3; i++)
        if (!ws[i].ok) FAIL_AT("thread %d: %s", i + 1, ws[i].why);
    /* the main thread never failed on a: its last error is empty */
    CHECK(strcmp(ew_device_last_error(a), "") == 0);
    ew_device_destroy(a);
    ew_device_destroy(b);
}

static void *destroy_op(void *arg) {
    ew_filter_destroy((ew_filter *)arg);
    return NULL;
}

TEST(ops_destroyed_on_other_threads_after_the_device) {
    ew_device *dev = cpu(2);
    ew_filter *f[4];
    for (int i = 0; i < 4; i++) CHECK_EQ_INT(ew_filter_create(dev, "bilateral", &f[i]), EW_OK);
    ew_device_destroy(dev);
    pthread_t t[4];
    for (int i = 0; i < 4; i++) CHECK(pthread_create(&t[i], NULL, destroy_op, f[i]) == 0);
    for (int i = 0; i < 4; i++) pthread_join(t[i], NULL);
}
