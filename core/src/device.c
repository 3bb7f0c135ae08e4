#include "src/backend.h"
#include "src/internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define EW_MAX_THREADS 1024

/* The calling thread's slot on `dev`, made (or the oldest recycled) when it
 * has none. Called with dev->error_lock held. */
static ew_error_slot *slot_of(ew_device *dev, int create) {
    pthread_t self = pthread_self();
    ew_error_slot *free_slot = NULL, *oldest = NULL;
    for (int i = 0; i < EW_ERROR_SLOTS; i++) {
        ew_error_slot *s = &dev->errors[i];
        if (s->used && pthread_equal(s->thread, self)) return s;
        if (!s->used && !free_slot) free_slot = s;
        if (s->used && (!oldest || s->stamp < oldest->stamp)) oldest = s;
    }
    if (!create) return NULL;
    /* more threads than slots: the least recently failing thread's message
     * goes (documented with ew_device_last_error) */
    ew_error_slot *s = free_slot ? free_slot : oldest;
    s->used = 1;
    s->thread = self;
    s->msg[0] = '\0';
    return s;
}

static ew_error_slot *lock_slot(ew_device *dev, int create) {
    pthread_mutex_lock(&dev->error_lock);
    ew_error_slot *s = slot_of(dev, create);
    if (s) s->stamp = ++dev->error_clock;
    pthread_mutex_unlock(&dev->error_lock);
    return s;
}

ew_result ew__fail(ew_device *dev, ew_result r, const char *fmt, ...) {
    if (dev) {
        ew_error_slot *s = lock_slot(dev, 1);
        va_list ap;
        va_start(ap, fmt);
        /* only this thread writes its slot's text (see struct ew_device) */
        vsnprintf(s->msg, sizeof s->msg, fmt, ap);
        va_end(ap);
    }
    return r;
}

void ew__set_error(ew_device *dev, const char *msg) {
    if (!dev) return;
    ew_error_slot *s = lock_slot(dev, 1);
    snprintf(s->msg, sizeof s->msg, "%s", msg ? msg : "");
}

void ew__clear_error(ew_device *dev) {
    if (!dev) return;
    /* a thread that never failed keeps no slot */
    pthread_mutex_lock(&dev->error_lock);
    ew_error_slot *s = slot_of(dev, 0);
    pthread_mutex_unlock(&dev->error_lock);
    if (s) s->msg[0] = '\0';
}

int ew__device_init_common(ew_device *dev) {
    dev->errors = (ew_error_slot *)calloc(EW_ERROR_SLOTS, sizeof *dev->errors);
    if (!dev->errors) return -1;
    if (pthread_mutex_init(&dev->error_lock, NULL) != 0) {
        free(dev->errors);
        dev->errors = NULL;
        return -1;
    }
    __atomic_store_n(&dev->refs, 1, __ATOMIC_RELAXED);
    dev->set_error = ew__set_error;
    return 0;
}

void ew__device_free_common(ew_device *dev) {
    if (!dev->errors) return;
    pthread_mutex_destroy(&dev->error_lock);
    free(dev->errors);
    dev->errors = NULL;
}

void ew__device_retain(ew_device *dev) {
    if (dev) __atomic_fetch_add(&dev->refs, 1, __ATOMIC_RELAXED);
}

static void device_free(ew_device *dev) {
    if (dev->backend->device_release) dev->backend->device_release(dev);
    ew_pool_destroy(dev->pool);
    ew__device_free_common(dev);
    free(dev);
}

void ew__device_release(ew_device *dev) {
    if (dev && __atomic_sub_fetch(&dev->refs, 1, __ATOMIC_ACQ_REL) == 0) device_free(dev);
}

ew_result ew_device_create(const ew_device_desc *desc, ew_device **out) {
    if (!out) return EW_ERR_INVALID_ARGUMENT;
    *out = NULL;
    ew_device_desc d = EW_DEVICE_DESC_INIT;
    if (desc) {
        /* an older, smaller desc is fine; a size we do not know is not */
        if (desc->size < offsetof(ew_device_desc, num_threads) + sizeof(int32_t) ||
            desc->size > sizeof(ew_device_desc))
            return EW_ERR_INVALID_ARGUMENT;
        /* copy only what the caller's (maybe older) desc holds;
         * the fields it predates keep their defaults */
        memcpy(&d, desc, desc->size);
    }
    if (d.num_threads < 0 || d.num_threads > EW_MAX_THREADS) return EW_ERR_INVALID_ARGUMENT;
    if (d.type != EW_DEVICE_DEFAULT && d.type != EW_DEVICE_CPU && d.type != EW_DEVICE_CUDA)
        return EW_ERR_INVALID_ARGUMENT;
    /* CUDA only when asked for (backend_loader.c): DEFAULT stays on the CPU
     * while most methods run on the CPU backend only, so a GPU machine does
     * not get a device that refuses them. A caller passing device pointers
     * must know they are CUDA's. */
    if (d.cuda_device < 0 || (d.device_images && d.type != EW_DEVICE_CUDA)) return EW_ERR_INVALID_ARGUMENT;
    if (d.type == EW_DEVICE_CUDA) return ew__cuda_device_create(&d, out);

    int threads = d.num_threads;
    if (threads == 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (int)(n < EW_MAX_THREADS ? n : EW_MAX_THREADS) : 1;
    }
    ew_device *dev = (ew_device *)calloc(1, sizeof *dev);
    if (!dev) return EW_ERR_OUT_OF_MEMORY;
    dev->type = EW_DEVICE_CPU;
    dev->num_threads = threads;
    dev->release_scratch = d.release_scratch != 0;
    /* read once here, so a running device never changes its arithmetic */
    const char *conv = getenv("EW_CPU_CONV");
    dev->conv_direct = conv && strcmp(conv, "direct") == 0;
    dev->backend = &ew_cpu_backend;
    dev->pool = ew_pool_create(threads);
    if (!dev->pool || ew__device_init_common(dev) != 0) {
        ew_pool_destroy(dev->pool);
        free(dev);
        return EW_ERR_OUT_OF_MEMORY;
    }
    *out = dev;
    return EW_OK;
}

void ew_device_destroy(ew_device *dev) { ew__device_release(dev); }

void ew_device_retain(ew_device *dev) { ew__device_retain(dev); }

ew_device_type ew_device_get_type(const ew_device *dev) { return dev ? dev->type : EW_DEVICE_DEFAULT; }
int32_t ew_device_get_num_threads(const ew_device *dev) { return dev ? dev->num_threads : 0; }
const char *ew_device_last_error(const ew_device *dev) {
    if (!dev) return "";
    ew_device *d = (ew_device *)dev; /* the slot table, not the device, changes */
    pthread_mutex_lock(&d->error_lock);
    const ew_error_slot *s = slot_of(d, 0);
    pthread_mutex_unlock(&d->error_lock);
    return s ? s->msg : "";
}

const char *ew_result_string(ew_result r) {
    switch (r) {
    case EW_OK: return "success";
    case EW_ERR_INVALID_ARGUMENT: return "invalid argument";
    case EW_ERR_OUT_OF_MEMORY: return "out of memory";
    case EW_ERR_UNSUPPORTED: return "unsupported";
    case EW_ERR_BACKEND_UNAVAILABLE: return "backend unavailable";
    case EW_ERR_IO: return "input/output error";
    case EW_ERR_CANCELLED: return "cancelled";
    case EW_ERR_INVALID_STATE: return "invalid state";
    case EW_ERR_INVALID_DATA: return "invalid data";
    }
    return "unknown error";
}

void ew_version(int *major, int *minor, int *patch) {
    if (major) *major = EW_VERSION_MAJOR;
    if (minor) *minor = EW_VERSION_MINOR;
    if (patch) *patch = EW_VERSION_PATCH;
}

#define EW_STR2(x) #x
#define EW_STR(x) EW_STR2(x)
const char *ew_version_string(void) {
    return EW_STR(EW_VERSION_MAJOR) "." EW_STR(EW_VERSION_MINOR) "." EW_STR(EW_VERSION_PATCH);
}
