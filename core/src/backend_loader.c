/*
 * backend_loader.c — finds and loads the CUDA module (libedgewise_cuda.so)
 * at run time, so that libedgewise itself never links CUDA and works on
 * machines without it (ctypes users, the Blender add-on, OFX hosts).
 *
 * The probe runs once per process (pthread_once) and its outcome — the
 * module's table or the reason it is unusable — is written once and only
 * read afterwards: the library's only global state, and the reason
 * ew_backend_unavailable_reason needs no device to report it. The module is
 * never unloaded: devices created later run its code.
 *
 * Where it looks, in order: $EW_CUDA_MODULE (a path) if set; the directory
 * of the object libedgewise is linked into (build/lib for the shared
 * library) and ../lib from there (build/bin for executables linked with the
 * static core); then the dynamic linker's search path.
 */
#define _GNU_SOURCE /* dladdr */
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/backend.h"
#include "src/internal.h"

#ifndef EW_CUDA_MODULE_BUILT
#define EW_CUDA_MODULE_BUILT 0 /* set by CMake when this build makes the module */
#endif

static pthread_once_t cuda_once = PTHREAD_ONCE_INIT;
static const ew_module_api *cuda_api; /* NULL: unusable, cuda_why says why */
static int cuda_count;
static char cuda_why[EW_ERROR_MAX];
static const char anchor = 0; /* an address inside this object, for dladdr */

/* A message into a fixed buffer; a long path may cut it short, on purpose. */
__attribute__((format(printf, 3, 4))) static void say(char *buf, size_t len, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, len, fmt, ap);
    va_end(ap);
}

static void *open_in(const char *dir, const char *rel, char *path, size_t len) {
    int k = snprintf(path, len, "%s/%s%s", dir, rel, EW_CUDA_MODULE_FILE);
    if (k < 0 || (size_t)k >= len) return NULL;
    return dlopen(path, RTLD_NOW | RTLD_LOCAL);
}

static void *open_module(char *path, size_t len, char *err, size_t errlen) {
    const char *env = getenv("EW_CUDA_MODULE");
    if (env && *env) {
        say(path, len, "%s", env);
        void *h = dlopen(env, RTLD_NOW | RTLD_LOCAL);
        if (!h) say(err, errlen, "EW_CUDA_MODULE=%s cannot be loaded: %s", env, dlerror());
        return h;
    }
    Dl_info info;
    char dir[1024] = "";
    if (dladdr(&anchor, &info) && info.dli_fname) {
        say(dir, sizeof dir, "%s", info.dli_fname);
        char *slash = strrchr(dir, '/');
        if (slash) *slash = '\0';
        else say(dir, sizeof dir, ".");
        void *h = open_in(dir, "", path, len);
        if (!h) h = open_in(dir, "../lib/", path, len);
        if (h) return h;
    }
    say(path, len, "%s", EW_CUDA_MODULE_FILE);
    void *h = dlopen(EW_CUDA_MODULE_FILE, RTLD_NOW | RTLD_LOCAL);
    if (!h)
        say(err, errlen, "%s not found in %s, %s/../lib or the library path (%s)%s", EW_CUDA_MODULE_FILE,
                 dir[0] ? dir : "(unknown)", dir[0] ? dir : "(unknown)", dlerror(),
                 EW_CUDA_MODULE_BUILT ? ""
                                      : "; this build of libedgewise made no CUDA module (no nvcc at configure time)");
    return h;
}

static void probe_cuda(void) {
    char path[1200], err[EW_ERROR_MAX] = "";
    void *h = open_module(path, sizeof path, err, sizeof err);
    if (!h) {
        say(cuda_why, sizeof cuda_why, "%s", err);
        return;
    }
    /* dlsym returns an object pointer; POSIX guarantees it converts to a
     * function pointer, memcpy says so without a cast warning */
    void *sym = dlsym(h, EW_CUDA_MODULE_ENTRY);
    ew_module_entry_fn entry = NULL;
    if (sym) memcpy(&entry, &sym, sizeof entry);
    const ew_module_api *api = entry ? entry() : NULL;
    if (!api) {
        say(cuda_why, sizeof cuda_why, "%s has no entry point %s: not an Edgewise CUDA module", path,
                 EW_CUDA_MODULE_ENTRY);
    } else if (api->abi != EW_MODULE_ABI || api->sizeof_backend != sizeof(ew_backend) ||
               api->sizeof_device != sizeof(struct ew_device) || !api->version ||
               strcmp(api->version, ew_version_string()) != 0 || !api->kernels ||
               strcmp(api->kernels, EW_KERNEL_NAMES) != 0) {
        say(cuda_why, sizeof cuda_why,
                 "%s was built for another libedgewise (version %s, module ABI %u, tables %u/%u bytes or other kernels; "
                 "this library: %s, ABI %d, %u/%u bytes): rebuild it from the same tree",
                 path, api->version ? api->version : "?", api->abi, api->sizeof_backend, api->sizeof_device,
                 ew_version_string(), EW_MODULE_ABI, (unsigned)sizeof(ew_backend), (unsigned)sizeof(struct ew_device));
    } else if (ew_backend_first_missing(api->backend) >= 0) {
        say(cuda_why, sizeof cuda_why, "%s lacks backend entry #%d: rebuild it from the same tree", path,
                 ew_backend_first_missing(api->backend));
    } else {
        char why[EW_ERROR_MAX] = "";
        int n = api->probe(why, sizeof why);
        if (n > 0) {
            cuda_api = api;
            cuda_count = n;
            return; /* stays loaded for the life of the process */
        }
        say(cuda_why, sizeof cuda_why, "%s: %s", path, why[0] ? why : "no CUDA device");
    }
    dlclose(h);
}

const ew_module_api *ew__cuda_module(int *devices) {
    pthread_once(&cuda_once, probe_cuda);
    if (devices) *devices = cuda_count;
    return cuda_api;
}

const char *ew_backend_unavailable_reason(ew_device_type type) {
    switch (type) {
    case EW_DEVICE_CPU: return "";
    case EW_DEVICE_CUDA: return ew__cuda_module(NULL) ? "" : cuda_why;
    case EW_DEVICE_DEFAULT: return "the default device is the CPU while only some methods run on CUDA";
    }
    return "unknown device type";
}

ew_result ew__cuda_device_create(const ew_device_desc *d, ew_device **out) {
    int count = 0;
    const ew_module_api *api = ew__cuda_module(&count);
    if (!api) return EW_ERR_BACKEND_UNAVAILABLE;
    if (d->cuda_device >= count) return EW_ERR_INVALID_ARGUMENT;
    ew_device *dev = (ew_device *)calloc(1, sizeof *dev);
    if (!dev) return EW_ERR_OUT_OF_MEMORY;
    dev->type = EW_DEVICE_CUDA;
    /* the host side (packing views into staging buffers) runs on the
     * calling thread; the pool exists so nothing needs to special-case it */
    dev->num_threads = 1;
    dev->backend = api->backend;
    dev->device_memory = 1;
    dev->device_images = d->device_images != 0;
    dev->pool = ew_pool_create(1);
    if (!dev->pool || ew__device_init_common(dev) != 0) {
        ew_pool_destroy(dev->pool);
        free(dev);
        return EW_ERR_OUT_OF_MEMORY;
    }
    ew_result r = api->device_init(dev, d->cuda_device, d->cuda_stream, dev->last_error, sizeof dev->last_error);
    if (r != EW_OK) {
        ew_pool_destroy(dev->pool);
        ew__device_free_common(dev);
        free(dev);
        return r;
    }
    dev->last_error[0] = '\0';
    *out = dev;
    return EW_OK;
}
