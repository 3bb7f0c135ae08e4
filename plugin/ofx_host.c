/* The host's suites, fetched at load, and the small services built on them. */
#include "ofx_plugin.h"

#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

ew_ofx_suites ew_ofx;

/* Every plugin in the binary gets its own load/unload; the suites are the
 * same host's, so they are fetched on the first load and dropped on the
 * last unload. The mutex only guards against a host that loads plugins
 * from several threads at once. */
static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int load_count;
static const OfxHost *pending_host;

void ew_ofx_set_host(const OfxHost *host) {
    /* setHost must not call into the host: only remember it. */
    pthread_mutex_lock(&load_lock);
    pending_host = host;
    pthread_mutex_unlock(&load_lock);
}

static const void *fetch(const OfxHost *h, const char *name, int version) {
    return h->fetchSuite ? h->fetchSuite(h->host, name, version) : NULL;
}

OfxStatus ew_ofx_load(void) {
    OfxStatus st = kOfxStatOK;
    pthread_mutex_lock(&load_lock);
    const OfxHost *h = pending_host ? pending_host : ew_ofx.host;
    if (!h || !h->fetchSuite) {
        st = kOfxStatErrMissingHostFeature;
    } else if (load_count == 0 || h != ew_ofx.host) {
        ew_ofx_suites s;
        memset(&s, 0, sizeof s);
        s.host = h;
        s.prop = (const OfxPropertySuiteV1 *)fetch(h, kOfxPropertySuite, 1);
        s.effect = (const OfxImageEffectSuiteV1 *)fetch(h, kOfxImageEffectSuite, 1);
        s.param = (const OfxParameterSuiteV1 *)fetch(h, kOfxParameterSuite, 1);
        s.memory = (const OfxMemorySuiteV1 *)fetch(h, kOfxMemorySuite, 1);
        s.mt = (const OfxMultiThreadSuiteV1 *)fetch(h, kOfxMultiThreadSuite, 1);
        s.msg2 = (const OfxMessageSuiteV2 *)fetch(h, kOfxMessageSuite, 2);
        s.msg1 = (const OfxMessageSuiteV1 *)fetch(h, kOfxMessageSuite, 1);
        if (!s.prop || !s.effect || !s.param)
            st = kOfxStatErrMissingHostFeature;
        else
            ew_ofx = s;
    }
    if (st == kOfxStatOK) load_count++;
    pthread_mutex_unlock(&load_lock);
    return st;
}

OfxStatus ew_ofx_unload(void) {
    pthread_mutex_lock(&load_lock);
    OfxStatus st = kOfxStatOK;
    if (load_count == 0) {
        st = kOfxStatFailed; /* unload without a successful load */
    } else if (--load_count == 0) {
        memset(&ew_ofx, 0, sizeof ew_ofx);
    }
    pthread_mutex_unlock(&load_lock);
    return st;
}

int ew_ofx_loaded(void) {
    pthread_mutex_lock(&load_lock);
    int n = load_count;
    pthread_mutex_unlock(&load_lock);
    return n > 0;
}

/* A header before each block says which allocator it came from, so a block
 * is freed right even if the host's suites changed in between. 16 bytes
 * keep the payload aligned for any use. */
enum { FROM_MALLOC = 1, FROM_HOST = 2 };
typedef union {
    int from;
    max_align_t align;
} block_header;

void *ew_ofx_alloc(size_t size) {
    if (size > (size_t)-1 - sizeof(block_header)) return NULL;
    size_t n = size + sizeof(block_header);
    block_header *b = NULL;
    int from = FROM_MALLOC;
    if (ew_ofx.memory && ew_ofx.memory->memoryAlloc) {
        void *p = NULL;
        if (ew_ofx.memory->memoryAlloc(NULL, n, &p) != kOfxStatOK || !p) return NULL;
        b = (block_header *)p;
        from = FROM_HOST;
    } else {
        b = (block_header *)malloc(n);
        if (!b) return NULL;
    }
    memset(b, 0, n);
    b->from = from;
    return b + 1;
}

void ew_ofx_free(void *p) {
    if (!p) return;
    block_header *b = (block_header *)p - 1;
    if (b->from == FROM_HOST && ew_ofx.memory && ew_ofx.memory->memoryFree)
        ew_ofx.memory->memoryFree(b);
    else if (b->from == FROM_MALLOC)
        free(b);
    /* FROM_HOST after the host went away: leaking beats freeing host memory
     * with the wrong allocator. */
}

void ew_ofx_post_error(OfxImageEffectHandle effect, const char *fmt, ...) {
    char text[600];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (ew_ofx.msg2 && ew_ofx.msg2->setPersistentMessage)
        ew_ofx.msg2->setPersistentMessage(effect, kOfxMessageError, "", "%s", text);
    else if (ew_ofx.msg1 && ew_ofx.msg1->message)
        ew_ofx.msg1->message(effect, kOfxMessageError, "", "%s", text);
}

void ew_ofx_post_warning(OfxImageEffectHandle effect, const char *text) {
    if (ew_ofx.msg2 && ew_ofx.msg2->setPersistentMessage)
        ew_ofx.msg2->setPersistentMessage(effect, kOfxMessageWarning, "", "%s", text);
}

void ew_ofx_clear_error(OfxImageEffectHandle effect) {
    if (ew_ofx.msg2 && ew_ofx.msg2->clearPersistentMessage) ew_ofx.msg2->clearPersistentMessage(effect);
}
