/*
 * thread_pool.h — a persistent pool of worker threads owned by a device.
 * ew_pool_run splits [0, n) into chunks taken in order by the workers and
 * the calling thread; it returns when every chunk is done.
 */
#ifndef EW_THREAD_POOL_H
#define EW_THREAD_POOL_H

#include <stdint.h>

typedef struct ew_thread_pool ew_thread_pool;
/* Called for the items [begin, end) by thread number `tid` (0..threads-1). */
typedef void (*ew_range_fn)(void *ctx, int64_t begin, int64_t end, int tid);

/* threads counts the caller too: threads == 1 starts no worker. NULL on failure. */
ew_thread_pool *ew_pool_create(int threads);
void ew_pool_destroy(ew_thread_pool *pool);
int ew_pool_threads(const ew_thread_pool *pool);
/* Run fn over [0, n) in chunks of `grain` items (grain <= 0: automatic). */
void ew_pool_run(ew_thread_pool *pool, int64_t n, int64_t grain, ew_range_fn fn, void *ctx);

#endif
