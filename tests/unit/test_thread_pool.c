#include "ew_test.h"

#include <stdatomic.h>

#include "src/thread_pool.h"

typedef struct { atomic_int *hits; atomic_int max_tid; } ctx_t;

static void mark(void *ctx, int64_t b, int64_t e, int tid) {
    ctx_t *c = (ctx_t *)ctx;
    for (int64_t i = b; i < e; i++) atomic_fetch_add(&c->hits[i], 1);
    int m = atomic_load(&c->max_tid);
    while (tid > m && !atomic_compare_exchange_weak(&c->max_tid, &m, tid)) {}
}

static int covers_once(int threads, int64_t n, int64_t grain) {
    ew_thread_pool *p = ew_pool_create(threads);
    if (!p) return 0;
    atomic_int *hits = calloc((size_t)n + 1, sizeof(atomic_int));
    ctx_t c = {hits, 0};
    int ok = 1;
    for (int rep = 0; rep < 50; rep++) {
        for (int64_t i = 0; i < n; i++) atomic_store(&hits[i], 0);
        ew_pool_run(p, n, grain, mark, &c);
        for (int64_t i = 0; i < n; i++) ok &= atomic_load(&hits[i]) == 1;
    }
    ok &= atomic_load(&c.max_tid) < threads;
    free(hits);
    ew_pool_destroy(p);
    return ok;
}

TEST(every_item_exactly_once_1_thread) { CHECK(covers_once(1, 1000, 0)); }
TEST(every_item_exactly_once_4_threads) { CHECK(covers_once(4, 1000, 0)); }
TEST(every_item_exactly_once_odd_grain) { CHECK(covers_once(3, 997, 7)); }
TEST(fewer_items_than_threads) { CHECK(covers_once(8, 3, 1)); }
TEST(zero_items_is_a_no_op) { CHECK(covers_once(2, 0, 1)); }

/* Two caller threads sharing one pool: jobs are serialised, none is lost. */
#include <pthread.h>
typedef struct { ew_thread_pool *pool; int ok; } caller_arg;
static void *caller(void *arg) {
    caller_arg *a = (caller_arg *)arg;
    atomic_int *hits = calloc(500, sizeof(atomic_int));
    ctx_t c = {hits, 0};
    a->ok = 1;
    for (int rep = 0; rep < 200; rep++) {
        for (int i = 0; i < 500; i++) atomic_store(&hits[i], 0);
        ew_pool_run(a->pool, 500, 3, mark, &c);
        for (int i = 0; i < 500; i++) a->ok &= atomic_load(&hits[i]) == 1;
    }
    free(hits);
    return NULL;
}

TEST(shared_by_two_callers) {
    ew_thread_pool *p = ew_pool_create(3);
    CHECK(p);
    caller_arg a = {p, 0}, b = {p, 0};
    pthread_t ta, tb;
    pthread_create(&ta, NULL, caller, &a);
    pthread_create(&tb, NULL, caller, &b);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    ew_pool_destroy(p);
    CHECK(a.ok && b.ok);
}
