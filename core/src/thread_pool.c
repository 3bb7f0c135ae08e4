#include "src/thread_pool.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>

struct ew_thread_pool {
    int threads;
    pthread_t *workers;
    pthread_mutex_t lock;
    pthread_mutex_t run_lock; /* one job at a time when callers share a device */
    pthread_cond_t wake, done;
    /* the job in flight; generation changes once per job */
    unsigned long generation;
    int quit;
    int busy; /* workers still inside the current job */
    ew_range_fn fn;
    void *ctx;
    int64_t n, grain;
    atomic_llong next;
};

static void run_chunks(ew_thread_pool *p, int tid) {
    for (;;) {
        int64_t begin = (int64_t)atomic_fetch_add(&p->next, (long long)p->grain);
        if (begin >= p->n) break;
        int64_t end = begin + p->grain < p->n ? begin + p->grain : p->n;
        p->fn(p->ctx, begin, end, tid);
    }
}

typedef struct { ew_thread_pool *pool; int tid; } worker_arg;

static void *worker_main(void *arg) {
    worker_arg *wa = (worker_arg *)arg;
    ew_thread_pool *p = wa->pool;
    int tid = wa->tid;
    free(wa);
    unsigned long seen = 0;
    pthread_mutex_lock(&p->lock);
    for (;;) {
        while (!p->quit && p->generation == seen) pthread_cond_wait(&p->wake, &p->lock);
        if (p->quit) break;
        seen = p->generation;
        pthread_mutex_unlock(&p->lock);
        run_chunks(p, tid);
        pthread_mutex_lock(&p->lock);
        if (--p->busy == 0) pthread_cond_signal(&p->done);
    }
    pthread_mutex_unlock(&p->lock);
    return NULL;
}

ew_thread_pool *ew_pool_create(int threads) {
    if (threads < 1) threads = 1;
    ew_thread_pool *p = (ew_thread_pool *)calloc(1, sizeof *p);
    if (!p) return NULL;
    p->threads = threads;
    if (pthread_mutex_init(&p->lock, NULL) != 0) { free(p); return NULL; }
    pthread_mutex_init(&p->run_lock, NULL);
    pthread_cond_init(&p->wake, NULL);
    pthread_cond_init(&p->done, NULL);
    atomic_init(&p->next, 0);
    if (threads > 1) {
        p->workers = (pthread_t *)calloc((size_t)threads - 1, sizeof(pthread_t));
        if (!p->workers) { ew_pool_destroy(p); return NULL; }
        for (int i = 0; i < threads - 1; i++) {
            worker_arg *wa = (worker_arg *)malloc(sizeof *wa);
            if (wa) { wa->pool = p; wa->tid = i + 1; }
            if (!wa || pthread_create(&p->workers[i], NULL, worker_main, wa) != 0) {
                free(wa);
                p->threads = i + 1; /* only the started ones are joined */
                ew_pool_destroy(p);
                return NULL;
            }
        }
    }
    return p;
}

void ew_pool_destroy(ew_thread_pool *p) {
    if (!p) return;
    if (p->workers) {
        pthread_mutex_lock(&p->lock);
        p->quit = 1;
        pthread_cond_broadcast(&p->wake);
        pthread_mutex_unlock(&p->lock);
        for (int i = 0; i < p->threads - 1; i++) pthread_join(p->workers[i], NULL);
        free(p->workers);
    }
    pthread_cond_destroy(&p->wake);
    pthread_cond_destroy(&p->done);
    pthread_mutex_destroy(&p->lock);
    pthread_mutex_destroy(&p->run_lock);
    free(p);
}

int ew_pool_threads(const ew_thread_pool *p) { return p ? p->threads : 1; }

void ew_pool_run(ew_thread_pool *p, int64_t n, int64_t grain, ew_range_fn fn, void *ctx) {
    if (n <= 0) return;
    if (grain <= 0) {
        /* several chunks per thread so uneven rows balance out */
        grain = n / ((int64_t)p->threads * 8);
        if (grain < 1) grain = 1;
    }
    if (p->threads == 1 || n <= grain) {
        fn(ctx, 0, n, 0);
        return;
    }
    pthread_mutex_lock(&p->run_lock);
    pthread_mutex_lock(&p->lock);
    p->fn = fn;
    p->ctx = ctx;
    p->n = n;
    p->grain = grain;
    atomic_store(&p->next, 0);
    p->busy = p->threads - 1;
    p->generation++;
    pthread_cond_broadcast(&p->wake);
    pthread_mutex_unlock(&p->lock);

    run_chunks(p, 0);

    pthread_mutex_lock(&p->lock);
    while (p->busy > 0) pthread_cond_wait(&p->done, &p->lock);
    pthread_mutex_unlock(&p->lock);
    pthread_mutex_unlock(&p->run_lock);
}
