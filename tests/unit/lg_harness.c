/*
 * lg_harness.c — the launch-grid harness backend (see lg_harness.h). Each
 * entry mirrors its CUDA wrapper in core/backends/cuda/cuda_backend.cu:
 * same geometry function, same body, same by-value parameter structs.
 */
#define _GNU_SOURCE /* MAP_ANONYMOUS, process_vm_readv */
#include "lg_harness.h"

#include <errno.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/uio.h>
#include <unistd.h>

#include "backends/cuda/kernel_bodies.h"
#include "src/internal.h"

char lg_error[256];

/* ---- device memory ----------------------------------------------------- */
#define LG_MAX_BLOCKS 256
typedef struct {
    char *map;       /* the mapping: guard, data pages, guard */
    size_t map_len;
    char *data;      /* the block, ending at the trailing guard */
    size_t bytes;
} lg_block;
static lg_block blocks[LG_MAX_BLOCKS];
static char *host_only; /* a PROT_NONE page standing for host-only parameter structs */

static size_t page_size(void) { return (size_t)sysconf(_SC_PAGESIZE); }

static const lg_block *find(const void *p) {
    for (int i = 0; i < LG_MAX_BLOCKS; i++)
        if (blocks[i].map && (const char *)p >= blocks[i].data && (const char *)p < blocks[i].data + blocks[i].bytes)
            return &blocks[i];
    return NULL;
}

/* Open (1) or close (0) every block to the host: open only inside entries. */
static void set_access(int open) {
    const size_t pg = page_size();
    for (int i = 0; i < LG_MAX_BLOCKS; i++) {
        if (!blocks[i].map) continue;
        char *first = blocks[i].map + pg, *guard = blocks[i].map + blocks[i].map_len - pg;
        if (mprotect(first, (size_t)(guard - first), open ? PROT_READ | PROT_WRITE : PROT_NONE) != 0) abort();
    }
}

static void note(const char *fn, const char *what, const char *problem) {
    if (!lg_error[0]) snprintf(lg_error, sizeof lg_error, "%s: %s %s", fn, what, problem);
}
static void check_dev(const void *p, const char *what, const char *fn) {
    if (p && !find(p)) note(fn, what, "is not device memory");
}
static void check_host(const void *p, const char *what, const char *fn) {
    if (p && find(p)) note(fn, what, "is device memory where host memory is expected");
}
#define DEV(p) check_dev((const void *)(p), #p, __func__)
#define ENTER() set_access(1)
#define LEAVE() set_access(0)

static void *lg_mem_alloc(ew_device *dev, size_t bytes) {
    (void)dev;
    const size_t pg = page_size();
    if (!host_only) {
        void *h = mmap(NULL, pg, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (h == MAP_FAILED) return NULL;
        host_only = (char *)h;
    }
    int slot = -1;
    for (int i = 0; i < LG_MAX_BLOCKS && slot < 0; i++)
        if (!blocks[i].map) slot = i;
    if (slot < 0) return NULL;
    const size_t b8 = ((bytes ? bytes : 1) + 7) & ~(size_t)7; /* 8-aligned: doubles */
    const size_t data_pages = (b8 + pg - 1) / pg * pg;
    const size_t len = data_pages + 2 * pg;
    void *m = mmap(NULL, len, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (m == MAP_FAILED) return NULL;
    lg_block *b = &blocks[slot];
    b->map = (char *)m;
    b->map_len = len;
    b->data = b->map + pg + data_pages - b8;
    b->bytes = b8;
    if (mprotect(b->map + pg, data_pages, PROT_READ | PROT_WRITE) != 0) abort();
    memset(b->data, 0xff, b8); /* NaN bits, as floats and as doubles */
    if (mprotect(b->map + pg, data_pages, PROT_NONE) != 0) abort();
    return b->data;
}

static void lg_mem_free(ew_device *dev, void *ptr) {
    (void)dev;
    if (!ptr) return;
    lg_block *b = (lg_block *)find(ptr);
    if (!b || b->data != (char *)ptr) {
        note(__func__, "ptr", "is not a block's start");
        return;
    }
    munmap(b->map, b->map_len);
    memset(b, 0, sizeof *b);
}

static ew_result lg_mem_upload(ew_device *dev, void *dst, const void *src, size_t bytes) {
    (void)dev;
    DEV(dst);
    check_host(src, "src", __func__);
    ENTER();
    if (bytes) memcpy(dst, src, bytes);
    LEAVE();
    return EW_OK;
}
static ew_result lg_mem_download(ew_device *dev, void *dst, const void *src, size_t bytes) {
    (void)dev;
    DEV(src);
    check_host(dst, "dst", __func__);
    ENTER();
    if (bytes) memcpy(dst, src, bytes);
    LEAVE();
    return EW_OK;
}
static ew_result lg_mem_copy(ew_device *dev, void *dst, const void *src, size_t bytes) {
    (void)dev;
    DEV(dst);
    DEV(src);
    ENTER();
    if (bytes) memmove(dst, src, bytes);
    LEAVE();
    return EW_OK;
}
static ew_result lg_mem_zero(ew_device *dev, void *ptr, size_t bytes) {
    (void)dev;
    DEV(ptr);
    ENTER();
    if (bytes) memset(ptr, 0, bytes);
    LEAVE();
    return EW_OK;
}
static ew_result lg_sync(ew_device *dev, int wait) {
    (void)dev;
    (void)wait;
    return EW_OK;
}
static void lg_device_release(ew_device *dev) { (void)dev; }

/* ---- kernels: the CUDA wrappers' geometry and bodies, walked ------------ */
#define WALK(launch, body)                                                                                   \
    do {                                                                                                     \
        ENTER();                                                                                             \
        EW_LAUNCH_WALK(launch, t, body);                                                                     \
        LEAVE();                                                                                             \
    } while (0)

static void lg_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image, const float *guide,
                           float *grid) {
    (void)dev;
    DEV(image);
    DEV(guide);
    DEV(grid);
    const ew_bgrid_params pv = *p;
    WALK(ew_kl_bgrid_splat(&pv), ew_kb_bgrid_splat(&t, &pv, image, guide, grid));
}
static void lg_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid, const float *guide,
                           float *out) {
    (void)dev;
    DEV(grid);
    DEV(guide);
    DEV(out);
    const ew_bgrid_params pv = *p;
    WALK(ew_kl_bgrid_slice(&pv), ew_kb_bgrid_slice(&t, &pv, grid, guide, out));
}
static void check_denoise(const ew_denoise_buffers *b, const char *fn) {
    check_dev(b->color, "color", fn);
    check_dev(b->albedo, "albedo", fn);
    check_dev(b->normal, "normal", fn);
    check_dev(b->depth, "depth", fn);
    check_dev(b->radiance, "radiance", fn);
    check_dev(b->guide, "guide", fn);
    check_dev(b->sliced, "sliced", fn);
    check_dev(b->out, "out", fn);
}
static void lg_denoise_prepare(ew_device *dev, const ew_denoise_buffers *b) {
    (void)dev;
    check_denoise(b, __func__);
    const ew_denoise_buffers bv = *b;
    WALK(ew_kl_denoise_px(&bv), ew_kb_denoise_prepare(&t, &bv));
}
static void lg_denoise_finish(ew_device *dev, const ew_denoise_buffers *b) {
    (void)dev;
    check_denoise(b, __func__);
    const ew_denoise_buffers bv = *b;
    WALK(ew_kl_denoise_px(&bv), ew_kb_denoise_finish(&t, &bv));
}
static void lg_denoise_refine_guide(ew_device *dev, const ew_denoise_buffers *b, float mean_lum, float color_weight) {
    (void)dev;
    check_denoise(b, __func__);
    const ew_denoise_buffers bv = *b;
    WALK(ew_kl_denoise_px(&bv), ew_kb_denoise_refine_guide(&t, &bv, mean_lum, color_weight));
}
static void lg_harm(ew_device *dev, int step, const ew_harm_args *a) {
    (void)dev;
    DEV(a->color);
    DEV(a->albedo);
    DEV(a->radiance);
    DEV(a->rejected);
    DEV(a->clamped);
    DEV(a->out);
    DEV(a->stats);
    DEV(a->give);
    DEV(a->spread);
    const ew_harm_args av = *a;
    WALK(ew_kl_harm(&av), ew_kb_harm(&t, step, &av));
}
static void lg_outlier_guided(ew_device *dev, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    (void)dev;
    DEV(b->color);
    DEV(b->albedo);
    DEV(b->normal);
    DEV(b->out);
    DEV(b->removed);
    const ew_outlier_params pv = *p;
    const ew_outlier_buffers bv = *b;
    WALK(ew_kl_outlier_guided(&pv), ew_kb_outlier_guided(&t, &pv, &bv));
}
static void lg_temporal(ew_device *dev, const ew_temporal_params *p, const ew_temporal_buffers *b) {
    (void)dev;
    DEV(b->color);
    DEV(b->normal);
    DEV(b->depth);
    DEV(b->motion);
    DEV(b->prev_color);
    DEV(b->prev_normal);
    DEV(b->prev_depth);
    DEV(b->prev_len);
    DEV(b->out_color);
    DEV(b->out_len);
    const ew_temporal_params pv = *p;
    const ew_temporal_buffers bv = *b;
    WALK(ew_kl_temporal(&pv), ew_kb_temporal(&t, &pv, &bv));
}
static void check_bf(const ew_bf_buffers *b, const char *fn) {
    check_dev(b->image, "image", fn);
    check_dev(b->attr, "attr", fn);
    check_dev(b->out, "out", fn);
}
static void lg_bf_brute(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b) {
    (void)dev;
    check_bf(b, __func__);
    const ew_bf_model mv = *m;
    const ew_bf_buffers bv = *b;
    WALK(ew_kl_bf_brute(&bv), ew_kb_bf_brute(&t, &mv, &bv));
}
static void lg_bf_separable(ew_device *dev, const ew_bf_model *m, int axis, const ew_bf_buffers *b) {
    (void)dev;
    check_bf(b, __func__);
    const ew_bf_model mv = *m;
    const ew_bf_buffers bv = *b;
    WALK(ew_kl_bf_separable(&bv), ew_kb_bf_separable(&t, &mv, axis, &bv));
}
static void lg_pyr_down(ew_device *dev, const ew_pyr_down_args *a) {
    (void)dev;
    DEV(a->down);
    DEV(a->attr);
    DEV(a->cdown);
    DEV(a->cattr);
    const ew_bf_model mv = *a->m;
    ew_pyr_down_args av = *a;
    av.m = (const ew_bf_model *)(const void *)host_only; /* the device cannot read the host's model */
    WALK(ew_kl_pyr_down(&av), ew_kb_pyr_down(&t, &av, &mv));
}
static void lg_pyr_up(ew_device *dev, const ew_pyr_up_args *a) {
    (void)dev;
    DEV(a->down);
    DEV(a->attr);
    DEV(a->cup);
    DEV(a->cattr);
    DEV(a->up);
    DEV(a->lut);
    const ew_bf_model mv = *a->m;
    ew_pyr_wrow row;
    if (a->row) row = *a->row;
    else memset(&row, 0, sizeof row);
    ew_pyr_up_args av = *a;
    av.m = (const ew_bf_model *)(const void *)host_only;
    if (av.row) av.row = (const ew_pyr_wrow *)(const void *)host_only;
    WALK(ew_kl_pyr_up(&av), ew_kb_pyr_up(&t, &av, &mv, &row));
}
static void lg_dof_attributes(ew_device *dev, const ew_dof_args *a) {
    (void)dev;
    DEV(a->depth);
    DEV(a->coc);
    DEV(a->tiles);
    DEV(a->tiles2);
    DEV(a->attr);
    const ew_dof_args av = *a;
    for (int step = 0; step < EW_DOF_STEPS; step++) WALK(ew_kl_dof(&av, step), ew_kb_dof(&t, &av, step));
}
static void lg_conv5(ew_device *dev, const ew_conv_args *a) {
    (void)dev;
    DEV(a->in);
    DEV(a->out);
    DEV(a->weight);
    DEV(a->bias);
    const ew_conv_args av = *a;
    WALK(ew_kl_conv5(&av), ew_kb_conv5(&t, &av));
}
static void lg_gn_input(ew_device *dev, const ew_gn_input_args *a) {
    (void)dev;
    DEV(a->color);
    DEV(a->albedo);
    DEV(a->normal);
    DEV(a->depth);
    DEV(a->dst);
    const ew_gn_input_args av = *a;
    WALK(ew_kl_gn_input(&av), ew_kb_gn_input(&t, &av));
}
static void lg_nbg_guides(ew_device *dev, long n, int ngrids, float *outputs) {
    (void)dev;
    DEV(outputs);
    WALK(ew_kl_nbg_px(n), ew_kb_nbg_guides(&t, n, ngrids, outputs));
}
static void lg_nbg_blend(ew_device *dev, const ew_nbg_blend_args *a) {
    (void)dev;
    DEV(a->outputs);
    DEV(a->sliced);
    DEV(a->acc);
    const ew_nbg_blend_args av = *a;
    WALK(ew_kl_nbg_px(av.n), ew_kb_nbg_blend(&t, &av));
}
/* The kernels of EW_KERNEL_LIST: their structs go to the GPU by value, so
 * every pointer in them must be device memory. The harness cannot tell a
 * pointer member from the others, so it looks at every aligned word: one
 * that points at readable memory outside the device blocks is a host
 * buffer handed to the GPU. Readable, not merely mapped: two ints read as
 * one word land in reserved PROT_NONE ranges (AddressSanitizer's shadow
 * gap spans terabytes), which no buffer can be. */
static int on_this_stack(uintptr_t p) {
    pthread_attr_t attr;
    void *lo = NULL;
    size_t size = 0;
    if (pthread_getattr_np(pthread_self(), &attr) != 0) return 0;
    pthread_attr_getstack(&attr, &lo, &size);
    pthread_attr_destroy(&attr);
    return p >= (uintptr_t)lo && p < (uintptr_t)lo + size;
}
/* AddressSanitizer's shadow memory on x86-64 (from (0x7fff8000 >> 3) +
 * 0x7fff8000 up to the start of its high memory): mapped and readable, but
 * never a buffer; an int and the padding after it (nplanes 3, padding
 * 0xfff) read as one word land there. */
static int in_sanitizer_shadow(uintptr_t p) {
#if defined(__SANITIZE_ADDRESS__) && defined(__x86_64__)
    return p >= 0x7fff8000ull && p < 0x10007fff8000ull;
#else
    (void)p;
    return 0;
#endif
}
static int readable(uintptr_t p) {
    /* An int and the struct padding after it read as one word can hold a
     * stale stack address in the padding's half; no buffer a kernel is
     * given lives on the caller's stack, so such words are not reported. */
    if (p < (uintptr_t)page_size() || on_this_stack(p) || in_sanitizer_shadow(p)) return 0;
    char byte;
    struct iovec local = {&byte, 1}, remote = {(void *)p, 1};
    if (process_vm_readv(getpid(), &local, 1, &remote, 1, 0) == 1) return 1;
    if (errno == EFAULT) return 0;
    /* the call refused (a seccomp policy): mapped at all, as msync tells */
    const uintptr_t pg = (uintptr_t)page_size();
    return msync((void *)(p & ~(pg - 1)), 1, MS_ASYNC) == 0;
}
static void check_args(const void *args, size_t size, const char *name) {
    for (size_t o = 0; o + sizeof(uintptr_t) <= size; o += sizeof(uintptr_t)) {
        uintptr_t w;
        memcpy(&w, (const char *)args + o, sizeof w);
        if (w && !find((const void *)w) && readable(w)) {
            char what[96];
            snprintf(what, sizeof what, "%s's argument at byte %zu (%#lx)", name, o, (unsigned long)w);
            note("lg_run", what, "is not device memory");
        }
    }
}
static ew_result lg_run(ew_device *dev, int id, const void *args, size_t args_size) {
    (void)dev;
    switch (id) {
#define LG_KCASE(NAME, ARGS, PX, W, H, VEC)                          \
    case EW_K_##NAME: {                                              \
        if (args_size != sizeof(ARGS)) break;                        \
        check_args(args, args_size, #NAME);                          \
        const ARGS av = *(const ARGS *)args;                         \
        WALK(ew_kl_##NAME(&av), ew_kb_##NAME(&t, &av));              \
        return EW_OK;                                                \
    }
        EW_KERNEL_LIST(LG_KCASE)
#undef LG_KCASE
    default: break;
    }
    note("lg_run", "kernel id", "is unknown or its arguments have the wrong size");
    return EW_ERR_INVALID_ARGUMENT;
}
static void lg_reduce_rows(ew_device *dev, int op, int width, int height, const float *src, double *out) {
    (void)dev;
    DEV(src);
    DEV(out);
    WALK(ew_kl_reduce_rows(height), ew_kb_reduce_rows(&t, op, width, height, src, out));
}
static void lg_view_pack(ew_device *dev, const ew_view_desc *v, int c, float *dst) {
    (void)dev;
    check_dev(v->data, "view", __func__);
    DEV(dst);
    const ew_view_desc vv = *v;
    WALK(ew_kl_view(&vv), ew_kb_view_pack(&t, &vv, c, dst));
}
static void lg_view_unpack(ew_device *dev, const float *src, int c, const ew_view_desc *v) {
    (void)dev;
    DEV(src);
    check_dev(v->data, "view", __func__);
    const ew_view_desc vv = *v;
    WALK(ew_kl_view(&vv), ew_kb_view_unpack(&t, src, c, &vv));
}

const ew_backend lg_backend = {
    .name = "launch-grid harness",
    .bgrid_splat = lg_bgrid_splat,
    .bgrid_slice = lg_bgrid_slice,
    .denoise_prepare = lg_denoise_prepare,
    .denoise_finish = lg_denoise_finish,
    .denoise_refine_guide = lg_denoise_refine_guide,
    .outlier_guided = lg_outlier_guided,
    .harm = lg_harm,
    .temporal = lg_temporal,
    .bf_brute = lg_bf_brute,
    .bf_separable = lg_bf_separable,
    .pyr_down = lg_pyr_down,
    .pyr_up = lg_pyr_up,
    .dof_attributes = lg_dof_attributes,
    .conv5 = lg_conv5,
    .gn_input = lg_gn_input,
    .nbg_guides = lg_nbg_guides,
    .nbg_blend = lg_nbg_blend,
    .run = lg_run,
    .mem_alloc = lg_mem_alloc,
    .mem_free = lg_mem_free,
    .mem_upload = lg_mem_upload,
    .mem_download = lg_mem_download,
    .mem_copy = lg_mem_copy,
    .mem_zero = lg_mem_zero,
    .sync = lg_sync,
    .reduce_rows = lg_reduce_rows,
    .view_pack = lg_view_pack,
    .view_unpack = lg_view_unpack,
    .device_release = lg_device_release,
};

/* ---- helpers for tests --------------------------------------------------- */
ew_device *lg_device_create(int device_images) {
    ew_device_desc d = EW_DEVICE_DESC_INIT;
    d.type = EW_DEVICE_CPU;
    d.num_threads = 1;
    ew_device *dev = NULL;
    if (ew_device_create(&d, &dev) != EW_OK) return NULL;
    /* what ew__cuda_device_create sets up, with the harness as backend */
    dev->backend = &lg_backend;
    dev->device_memory = 1;
    dev->device_images = device_images;
    return dev;
}

float *lg_alloc_floats(ew_device *dev, size_t n) { return (float *)lg_mem_alloc(dev, n * sizeof(float)); }

float *lg_upload(ew_device *dev, const float *host, size_t n) {
    float *d = lg_alloc_floats(dev, n);
    if (d) lg_mem_upload(dev, d, host, n * sizeof(float));
    return d;
}

float *lg_download(ew_device *dev, const float *d, size_t n) {
    float *h = (float *)malloc(n * sizeof(float) + 1);
    if (h) lg_mem_download(dev, h, d, n * sizeof(float));
    return h;
}

int lg_live_blocks(void) {
    int n = 0;
    for (int i = 0; i < LG_MAX_BLOCKS; i++) n += blocks[i].map != NULL;
    return n;
}
