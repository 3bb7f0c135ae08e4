/*
 * Row bands on the host's threads (OfxMultiThreadSuiteV1), with the host's
 * abort() asked before each band so a cancelled render stops within one
 * band's time. Threads take bands from a shared counter, so a host that
 * starts fewer threads than asked, or none, still gets every band done.
 */
#include "ofx_plugin.h"

#include <stdatomic.h>

/* Bands of at most this many rows, and at least a few per thread so the
 * threads finish together. */
#define EW_OFX_BAND_ROWS_MAX 64
#define EW_OFX_BANDS_PER_THREAD 4

typedef struct {
    OfxImageEffectHandle effect;
    ew_ofx_band_fn fn;
    void *ctx;
    int y0, y1, rows, bands;
    atomic_int next;
    atomic_int aborted;
} band_job;

static void run_job(unsigned int index, unsigned int count, void *arg) {
    (void)index;
    (void)count;
    band_job *job = (band_job *)arg;
    for (;;) {
        if (atomic_load(&job->aborted)) return;
        if (ew_ofx.effect->abort && ew_ofx.effect->abort(job->effect)) {
            atomic_store(&job->aborted, 1);
            return;
        }
        int b = atomic_fetch_add(&job->next, 1);
        if (b >= job->bands) return;
        int y = job->y0 + b * job->rows;
        int y_end = job->y1 - y > job->rows ? y + job->rows : job->y1;
        job->fn(job->ctx, y, y_end);
    }
}

int ew_ofx_thread_count(void) {
    unsigned int n = 0;
    if (!ew_ofx.mt || !ew_ofx.mt->multiThreadNumCPUs || ew_ofx.mt->multiThreadNumCPUs(&n) != kOfxStatOK) return 0;
    return n > 256 ? 256 : (int)n;
}

int ew_ofx_run_bands(OfxImageEffectHandle effect, int y0, int y1, ew_ofx_band_fn fn, void *ctx) {
    if (y1 <= y0) return 0;
    band_job job;
    job.effect = effect;
    job.fn = fn;
    job.ctx = ctx;
    job.y0 = y0;
    job.y1 = y1;
    int threads = ew_ofx_thread_count();
    int want = (threads > 1 ? threads : 1) * EW_OFX_BANDS_PER_THREAD;
    job.rows = (y1 - y0 + want - 1) / want;
    if (job.rows > EW_OFX_BAND_ROWS_MAX) job.rows = EW_OFX_BAND_ROWS_MAX;
    job.bands = (y1 - y0 + job.rows - 1) / job.rows;
    atomic_init(&job.next, 0);
    atomic_init(&job.aborted, 0);
    if (threads > job.bands) threads = job.bands;
    if (threads > 1 && ew_ofx.mt->multiThread) {
        /* Fails when called from one of the host's own spawned threads
         * (no recursion) or when the host cannot spawn: then the rest of
         * the bands run here. */
        ew_ofx.mt->multiThread(run_job, (unsigned int)threads, &job);
    }
    run_job(0, 1, &job);
    return atomic_load(&job.aborted);
}
