/*
 * The device and op an instance keeps between render calls.
 *
 * The library's ops keep their scratch (buffers, network planes) across
 * executes of one size, so the next frame of the same node skips the
 * allocations and the page faults of fresh memory. The pair is kept for
 * exactly one method (the node's, or the colour-guided fallback) and one
 * thread count; a render that wants another frees it (two frames' scratch
 * are never held) and makes its own.
 *
 * Memory: the pair holds one frame's scratch (ew_op_memory: 349 MiB for
 * kpcn-small at 1280x720), so it is held only while the host is likely to
 * ask for another frame. It is
 * dropped when the host purges caches, when a sequence render ends (a batch
 * is over; interactive renders between sequences keep it), when the
 * instance is destroyed, and after any render that failed or was aborted,
 * so a bad state is never reused.
 *
 * A render takes the pair out of the instance and puts it back when done,
 * each under the instance's lock; the lock is never held while the library
 * runs. A drop while a render holds the pair (a purge from the host's UI
 * thread) bumps the generation, so that render frees its pair instead of
 * putting it back. RenderInstanceSafe means renders do not overlap on one
 * instance; if a host overlaps them anyway, each gets its own pair.
 */
#include "ofx_plugin.h"

#include <string.h>

void ew_ofx_keep_init(ew_ofx_keep *k) {
    memset(k, 0, sizeof *k);
    pthread_mutex_init(&k->lock, NULL);
}

static void free_pair(ew_device *dev, ew_op *op) {
    ew_op_destroy(op);
    ew_device_destroy(dev);
}

void ew_ofx_keep_drop(ew_ofx_keep *k) {
    pthread_mutex_lock(&k->lock);
    ew_device *dev = k->dev;
    ew_op *op = k->op;
    k->dev = NULL;
    k->op = NULL;
    k->method = NULL;
    k->generation++;
    pthread_mutex_unlock(&k->lock);
    free_pair(dev, op);
}

void ew_ofx_keep_fini(ew_ofx_keep *k) {
    ew_ofx_keep_drop(k);
    pthread_mutex_destroy(&k->lock);
}

int ew_ofx_keep_take(ew_ofx_keep *k, const char *method, int threads, ew_device **dev, ew_op **op,
                     unsigned *generation) {
    pthread_mutex_lock(&k->lock);
    ew_device *kd = k->dev;
    ew_op *ko = k->op;
    int match = ko && !strcmp(k->method, method) && k->threads == threads;
    k->dev = NULL;
    k->op = NULL;
    k->method = NULL;
    *generation = k->generation;
    pthread_mutex_unlock(&k->lock);
    if (!match) {
        free_pair(kd, ko);
        return 0;
    }
    *dev = kd;
    *op = ko;
    return 1;
}

void ew_ofx_keep_put(ew_ofx_keep *k, const char *method, int threads, ew_device *dev, ew_op *op,
                     unsigned generation) {
    ew_device *old_dev = NULL;
    ew_op *old_op = NULL;
    pthread_mutex_lock(&k->lock);
    if (k->generation == generation) {
        old_dev = k->dev; /* NULL unless another render overlapped this one */
        old_op = k->op;
        k->dev = dev;
        k->op = op;
        k->method = method;
        k->threads = threads;
        dev = NULL;
        op = NULL;
    }
    pthread_mutex_unlock(&k->lock);
    free_pair(old_dev, old_op);
    free_pair(dev, op); /* dropped while it rendered */
}

OfxStatus ew_ofx_drop_kept(const ew_ofx_node *node, OfxImageEffectHandle effect) {
    OfxStatus st;
    ew_ofx_instance *inst = ew_ofx_instance_get(node, effect, &st);
    if (!inst) return st;
    ew_ofx_keep_drop(&inst->keep);
    return kOfxStatOK;
}
