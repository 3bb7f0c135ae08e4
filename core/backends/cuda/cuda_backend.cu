/*
 * cuda_backend.cu — the CUDA backend, built as the separate module
 * libedgewise_cuda.so and loaded at run time by src/backend_loader.c.
 *
 * Every __global__ below only fetches its thread's coordinates and calls the
 * body of kernel_bodies.h, which bounds-checks and calls the same EW_HD
 * per-pixel function the CPU backend loops over. The host functions compute
 * the launch geometry with the same launch_grid.h functions the CPU harness
 * walks, queue the kernel on the device's stream and record the first
 * failure; failures surface at the next sync or download (docs/backends.md).
 *
 * The CUDA runtime is linked statically: the module's only run-time
 * dependency is the driver (libcuda.so.1), which the runtime loads itself,
 * so the module loads on any machine and its probe can say what is missing.
 */
#include <cuda_runtime.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backends/cuda/kernel_bodies.h"
#include "src/backend.h"
#include "src/internal.h"

namespace {

/* The GPUs our SASS and PTX can run on: sm_75 (Turing) and newer. */
const int min_cc = 75;

struct cuda_ctx {
    int ordinal;
    cudaStream_t stream;
    bool own_stream;         /* false: the caller's (an OFX host's) stream, never destroyed here */
    cudaError_t first_error; /* the first failure since the last sync */
    const char *first_what;  /* what failed (a static string) */
};

cuda_ctx *ctx_of(ew_device *dev) { return static_cast<cuda_ctx *>(dev->backend_ctx); }

dim3 to_dim3(ew_dim3 d) { return dim3(d.x, d.y, d.z); }

/* Kernels and copies are asynchronous and the backend entries that queue
 * them return void: keep the first failure for the next sync or download
 * to report. */
void note(ew_device *dev, cudaError_t e, const char *what) {
    cuda_ctx *c = ctx_of(dev);
    if (e != cudaSuccess && c->first_error == cudaSuccess) {
        c->first_error = e;
        c->first_what = what;
    }
}

/* The runtime's current device is per host thread and the caller may drive
 * several devices from one thread: select ours before every call. */
void use(ew_device *dev) { note(dev, cudaSetDevice(ctx_of(dev)->ordinal), "cudaSetDevice"); }

ew_result result_of(cudaError_t e) {
    return e == cudaErrorMemoryAllocation ? EW_ERR_OUT_OF_MEMORY : EW_ERR_BACKEND_UNAVAILABLE;
}

/* Report (and clear) the first recorded failure, with its detail in the
 * device's last error. */
ew_result take_error(ew_device *dev) {
    cuda_ctx *c = ctx_of(dev);
    if (c->first_error == cudaSuccess) return EW_OK;
    const cudaError_t e = c->first_error;
    char msg[EW_ERROR_MAX];
    snprintf(msg, sizeof msg, "CUDA device %d: %s failed: %s (%s)", c->ordinal, c->first_what,
             cudaGetErrorString(e), cudaGetErrorName(e));
    dev->set_error(dev, msg); /* the calling thread's last error */
    c->first_error = cudaSuccess;
    c->first_what = NULL;
    return result_of(e);
}

#define EW_KERNEL __global__ void __launch_bounds__(EW_BLOCK_X * EW_BLOCK_Y)

/* Queue `kernel` over launch `l` on the device's stream; an empty grid is
 * skipped (CUDA rejects it). */
#define EW_LAUNCH(dev, l, kernel, ...)                                                                  \
    do {                                                                                                \
        const ew_launch l_ = (l);                                                                       \
        if (ew_launch_empty(&l_)) break;                                                                \
        use(dev);                                                                                       \
        kernel<<<to_dim3(l_.grid), to_dim3(l_.block), 0, ctx_of(dev)->stream>>>(__VA_ARGS__);           \
        note(dev, cudaGetLastError(), #kernel);                                                         \
    } while (0)

/* ---- kernels: fetch the thread, call the body ---------------------------- */
EW_KERNEL k_bgrid_splat(ew_bgrid_params p, const float *__restrict__ image, const float *__restrict__ guide,
                        float *__restrict__ grid) {
    const ew_thread t = ew_thread_self();
    ew_kb_bgrid_splat(&t, &p, image, guide, grid);
}
EW_KERNEL k_bgrid_slice(ew_bgrid_params p, const float *__restrict__ grid, const float *__restrict__ guide,
                        float *__restrict__ out) {
    const ew_thread t = ew_thread_self();
    ew_kb_bgrid_slice(&t, &p, grid, guide, out);
}
EW_KERNEL k_denoise_prepare(ew_denoise_buffers b) {
    const ew_thread t = ew_thread_self();
    ew_kb_denoise_prepare(&t, &b);
}
EW_KERNEL k_denoise_finish(ew_denoise_buffers b) {
    const ew_thread t = ew_thread_self();
    ew_kb_denoise_finish(&t, &b);
}
EW_KERNEL k_denoise_refine_guide(ew_denoise_buffers b, float mean_lum, float color_weight) {
    const ew_thread t = ew_thread_self();
    ew_kb_denoise_refine_guide(&t, &b, mean_lum, color_weight);
}
EW_KERNEL k_outlier_guided(ew_outlier_params p, ew_outlier_buffers b) {
    const ew_thread t = ew_thread_self();
    ew_kb_outlier_guided(&t, &p, &b);
}
EW_KERNEL k_harm(int step, ew_harm_args a) {
    const ew_thread t = ew_thread_self();
    ew_kb_harm(&t, step, &a);
}
EW_KERNEL k_temporal(ew_temporal_params p, ew_temporal_buffers b) {
    const ew_thread t = ew_thread_self();
    ew_kb_temporal(&t, &p, &b);
}
EW_KERNEL k_bf_brute(ew_bf_model m, ew_bf_buffers b) {
    const ew_thread t = ew_thread_self();
    ew_kb_bf_brute(&t, &m, &b);
}
EW_KERNEL k_bf_separable(ew_bf_model m, int axis, ew_bf_buffers b) {
    const ew_thread t = ew_thread_self();
    ew_kb_bf_separable(&t, &m, axis, &b);
}
EW_KERNEL k_pyr_down(ew_pyr_down_args a, ew_bf_model m) {
    const ew_thread t = ew_thread_self();
    ew_kb_pyr_down(&t, &a, &m);
}
EW_KERNEL k_pyr_up(ew_pyr_up_args a, ew_bf_model m, ew_pyr_wrow row) {
    const ew_thread t = ew_thread_self();
    ew_kb_pyr_up(&t, &a, &m, &row);
}
EW_KERNEL k_dof(ew_dof_args a, int step) {
    const ew_thread t = ew_thread_self();
    ew_kb_dof(&t, &a, step);
}
EW_KERNEL k_conv5(ew_conv_args a) {
    const ew_thread t = ew_thread_self();
    ew_kb_conv5(&t, &a);
}
EW_KERNEL k_gn_input(ew_gn_input_args a) {
    const ew_thread t = ew_thread_self();
    ew_kb_gn_input(&t, &a);
}
EW_KERNEL k_nbg_guides(long n, int ngrids, float *outputs) {
    const ew_thread t = ew_thread_self();
    ew_kb_nbg_guides(&t, n, ngrids, outputs);
}
EW_KERNEL k_nbg_blend(ew_nbg_blend_args a) {
    const ew_thread t = ew_thread_self();
    ew_kb_nbg_blend(&t, &a);
}
#define EW_KGLOBAL_(NAME, ARGS, PX, W, H, VEC) \
    EW_KERNEL k_##NAME(ARGS a) {                  \
        const ew_thread t = ew_thread_self();     \
        ew_kb_##NAME(&t, &a);                     \
    }
EW_KERNEL_LIST(EW_KGLOBAL_)
#undef EW_KGLOBAL_
EW_KERNEL k_reduce_rows(int op, int width, int height, const float *__restrict__ src, double *__restrict__ out) {
    const ew_thread t = ew_thread_self();
    ew_kb_reduce_rows(&t, op, width, height, src, out);
}
EW_KERNEL k_view_pack(ew_view_desc v, int c, float *__restrict__ dst) {
    const ew_thread t = ew_thread_self();
    ew_kb_view_pack(&t, &v, c, dst);
}
EW_KERNEL k_view_unpack(const float *__restrict__ src, int c, ew_view_desc v) {
    const ew_thread t = ew_thread_self();
    ew_kb_view_unpack(&t, src, c, &v);
}

/* ---- backend entries: geometry, queue ------------------------------------ */
void cu_bgrid_splat(ew_device *dev, const ew_bgrid_params *p, const float *image, const float *guide, float *grid) {
    EW_LAUNCH(dev, ew_kl_bgrid_splat(p), k_bgrid_splat, *p, image, guide, grid);
}
void cu_bgrid_slice(ew_device *dev, const ew_bgrid_params *p, const float *grid, const float *guide, float *out) {
    EW_LAUNCH(dev, ew_kl_bgrid_slice(p), k_bgrid_slice, *p, grid, guide, out);
}
void cu_denoise_prepare(ew_device *dev, const ew_denoise_buffers *b) {
    EW_LAUNCH(dev, ew_kl_denoise_px(b), k_denoise_prepare, *b);
}
void cu_denoise_finish(ew_device *dev, const ew_denoise_buffers *b) {
    EW_LAUNCH(dev, ew_kl_denoise_px(b), k_denoise_finish, *b);
}
void cu_denoise_refine_guide(ew_device *dev, const ew_denoise_buffers *b, float mean_lum, float color_weight) {
    EW_LAUNCH(dev, ew_kl_denoise_px(b), k_denoise_refine_guide, *b, mean_lum, color_weight);
}
void cu_outlier_guided(ew_device *dev, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    EW_LAUNCH(dev, ew_kl_outlier_guided(p), k_outlier_guided, *p, *b);
}
void cu_harm(ew_device *dev, int step, const ew_harm_args *a) {
    EW_LAUNCH(dev, ew_kl_harm(a), k_harm, step, *a);
}
void cu_temporal(ew_device *dev, const ew_temporal_params *p, const ew_temporal_buffers *b) {
    EW_LAUNCH(dev, ew_kl_temporal(p), k_temporal, *p, *b);
}
void cu_bf_brute(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b) {
    EW_LAUNCH(dev, ew_kl_bf_brute(b), k_bf_brute, *m, *b);
}
void cu_bf_separable(ew_device *dev, const ew_bf_model *m, int axis, const ew_bf_buffers *b) {
    EW_LAUNCH(dev, ew_kl_bf_separable(b), k_bf_separable, *m, axis, *b);
}
void cu_pyr_down(ew_device *dev, const ew_pyr_down_args *a) {
    EW_LAUNCH(dev, ew_kl_pyr_down(a), k_pyr_down, *a, *a->m);
}
void cu_pyr_up(ew_device *dev, const ew_pyr_up_args *a) {
    ew_pyr_wrow row;
    if (a->row) row = *a->row;
    else memset(&row, 0, sizeof row); /* unused: the weights come from a->lut */
    EW_LAUNCH(dev, ew_kl_pyr_up(a), k_pyr_up, *a, *a->m, row);
}
void cu_dof_attributes(ew_device *dev, const ew_dof_args *a) {
    /* no attr: the caller computes (D, C) itself (ew_dof_attr_rows) */
    for (int step = 0; step < (a->attr ? EW_DOF_STEPS : EW_DOF_STEPS - 1); step++)
        EW_LAUNCH(dev, ew_kl_dof(a, step), k_dof, *a, step);
}
void cu_conv5(ew_device *dev, const ew_conv_args *a) { EW_LAUNCH(dev, ew_kl_conv5(a), k_conv5, *a); }
void cu_gn_input(ew_device *dev, const ew_gn_input_args *a) { EW_LAUNCH(dev, ew_kl_gn_input(a), k_gn_input, *a); }
void cu_nbg_guides(ew_device *dev, long n, int ngrids, float *outputs) {
    EW_LAUNCH(dev, ew_kl_nbg_px(n), k_nbg_guides, n, ngrids, outputs);
}
void cu_nbg_blend(ew_device *dev, const ew_nbg_blend_args *a) { EW_LAUNCH(dev, ew_kl_nbg_px(a->n), k_nbg_blend, *a); }
ew_result cu_run(ew_device *dev, int id, const void *args, size_t args_size) {
    switch (id) {
#define EW_KLAUNCH_(NAME, ARGS, PX, W, H, VEC)                                        \
    case EW_K_##NAME: {                                                               \
        if (args_size != sizeof(ARGS)) break;                                         \
        const ARGS *a = static_cast<const ARGS *>(args);                              \
        EW_LAUNCH(dev, ew_kl_##NAME(a), k_##NAME, *a);                                \
        return EW_OK;                                                                 \
    }
        EW_KERNEL_LIST(EW_KLAUNCH_)
#undef EW_KLAUNCH_
    default: break;
    }
    char msg[EW_ERROR_MAX];
    snprintf(msg, sizeof msg, "CUDA backend: no kernel %d taking %zu bytes of arguments", id, args_size);
    dev->set_error(dev, msg);
    return EW_ERR_INVALID_ARGUMENT;
}
void cu_reduce_rows(ew_device *dev, int op, int width, int height, const float *src, double *out) {
    EW_LAUNCH(dev, ew_kl_reduce_rows(height), k_reduce_rows, op, width, height, src, out);
}
void cu_view_pack(ew_device *dev, const ew_view_desc *v, int c, float *dst) {
    EW_LAUNCH(dev, ew_kl_view(v), k_view_pack, *v, c, dst);
}
void cu_view_unpack(ew_device *dev, const float *src, int c, const ew_view_desc *v) {
    EW_LAUNCH(dev, ew_kl_view(v), k_view_unpack, src, c, *v);
}

/* ---- memory -------------------------------------------------------------
 * Buffers are allocated at commit (cudaMalloc, which may synchronise: not
 * per frame). Copies are queued on the device's stream; uploads come from
 * pageable host memory, so the source may be reused when the call returns. */
void *cu_mem_alloc(ew_device *dev, size_t bytes) {
    use(dev);
    void *p = NULL;
    if (cudaMalloc(&p, bytes ? bytes : 1) != cudaSuccess) {
        (void)cudaGetLastError(); /* out of memory is not sticky: do not leave it for the next launch */
        return NULL;
    }
    return p;
}
void cu_mem_free(ew_device *dev, void *ptr) {
    if (!ptr) return;
    use(dev);
    note(dev, cudaFree(ptr), "cudaFree");
}
ew_result cu_mem_upload(ew_device *dev, void *dst, const void *src, size_t bytes) {
    use(dev);
    if (bytes) note(dev, cudaMemcpyAsync(dst, src, bytes, cudaMemcpyHostToDevice, ctx_of(dev)->stream), "upload");
    return take_error(dev);
}
ew_result cu_mem_download(ew_device *dev, void *dst, const void *src, size_t bytes) {
    use(dev);
    cuda_ctx *c = ctx_of(dev);
    if (bytes) note(dev, cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, c->stream), "download");
    note(dev, cudaStreamSynchronize(c->stream), "a kernel before a download");
    return take_error(dev);
}
ew_result cu_mem_copy(ew_device *dev, void *dst, const void *src, size_t bytes) {
    use(dev);
    if (bytes) note(dev, cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToDevice, ctx_of(dev)->stream), "copy");
    return take_error(dev);
}
ew_result cu_mem_zero(ew_device *dev, void *ptr, size_t bytes) {
    use(dev);
    if (bytes) note(dev, cudaMemsetAsync(ptr, 0, bytes, ctx_of(dev)->stream), "memset");
    return take_error(dev);
}
ew_result cu_sync(ew_device *dev, int wait) {
    use(dev);
    cuda_ctx *c = ctx_of(dev);
    if (wait) {
        note(dev, cudaStreamSynchronize(c->stream), "queued work");
    } else {
        /* a failed kernel shows without blocking; "not ready" is no failure */
        const cudaError_t e = cudaStreamQuery(c->stream);
        if (e != cudaErrorNotReady) note(dev, e, "queued work");
    }
    return take_error(dev);
}

void cu_device_release(ew_device *dev) {
    cuda_ctx *c = ctx_of(dev);
    if (!c) return;
    if (cudaSetDevice(c->ordinal) == cudaSuccess && c->own_stream) {
        (void)cudaStreamSynchronize(c->stream); /* let queued work finish before its buffers go */
        (void)cudaStreamDestroy(c->stream);
    }
    free(c);
    dev->backend_ctx = NULL;
}

ew_backend make_table() {
    ew_backend b;
    memset(&b, 0, sizeof b);
    b.name = "cuda";
    b.bgrid_splat = cu_bgrid_splat;
    b.bgrid_slice = cu_bgrid_slice;
    b.denoise_prepare = cu_denoise_prepare;
    b.denoise_finish = cu_denoise_finish;
    b.denoise_refine_guide = cu_denoise_refine_guide;
    b.outlier_guided = cu_outlier_guided;
    b.harm = cu_harm;
    b.temporal = cu_temporal;
    b.bf_brute = cu_bf_brute;
    b.bf_separable = cu_bf_separable;
    b.pyr_down = cu_pyr_down;
    b.pyr_up = cu_pyr_up;
    b.dof_attributes = cu_dof_attributes;
    b.conv5 = cu_conv5;
    b.gn_input = cu_gn_input;
    b.nbg_guides = cu_nbg_guides;
    b.nbg_blend = cu_nbg_blend;
    b.run = cu_run;
    b.mem_alloc = cu_mem_alloc;
    b.mem_free = cu_mem_free;
    b.mem_upload = cu_mem_upload;
    b.mem_download = cu_mem_download;
    b.mem_copy = cu_mem_copy;
    b.mem_zero = cu_mem_zero;
    b.sync = cu_sync;
    b.reduce_rows = cu_reduce_rows;
    b.view_pack = cu_view_pack;
    b.view_unpack = cu_view_unpack;
    b.device_release = cu_device_release;
    return b;
}

/* ---- probing and devices ------------------------------------------------- */
const char *explain(cudaError_t e) {
    switch (e) {
    case cudaErrorNoDevice: return "no CUDA-capable GPU is present";
    case cudaErrorInsufficientDriver:
        return "no usable NVIDIA driver: libcuda.so.1 is missing or older than this module's CUDA runtime";
    case cudaErrorStubLibrary: return "the CUDA driver found is a stub library (no NVIDIA driver installed)";
    case cudaErrorDevicesUnavailable: return "every GPU is busy or in exclusive mode";
    case cudaErrorInitializationError: return "the CUDA driver failed to initialise";
    default: return "CUDA is unusable";
    }
}

int probe(char *why, size_t len) {
    int n = 0;
    const cudaError_t e = cudaGetDeviceCount(&n);
    if (e != cudaSuccess) {
        snprintf(why, len, "%s (cudaGetDeviceCount: %s, %s)", explain(e), cudaGetErrorName(e), cudaGetErrorString(e));
        return 0;
    }
    if (n <= 0) snprintf(why, len, "no CUDA-capable GPU is present");
    return n;
}

ew_result device_init(ew_device *dev, int ordinal, void *stream, char *why, size_t len) {
    cudaError_t e = cudaSetDevice(ordinal);
    int major = 0, minor = 0;
    if (e == cudaSuccess) e = cudaDeviceGetAttribute(&major, cudaDevAttrComputeCapabilityMajor, ordinal);
    if (e == cudaSuccess) e = cudaDeviceGetAttribute(&minor, cudaDevAttrComputeCapabilityMinor, ordinal);
    if (e != cudaSuccess) {
        snprintf(why, len, "CUDA device %d: %s", ordinal, cudaGetErrorString(e));
        return result_of(e);
    }
    if (major * 10 + minor < min_cc) {
        snprintf(why, len, "CUDA device %d has compute capability %d.%d; the module needs %d.%d or newer", ordinal,
                 major, minor, min_cc / 10, min_cc % 10);
        return EW_ERR_BACKEND_UNAVAILABLE;
    }
    cuda_ctx *c = static_cast<cuda_ctx *>(calloc(1, sizeof(cuda_ctx)));
    if (!c) return EW_ERR_OUT_OF_MEMORY;
    c->ordinal = ordinal;
    c->first_error = cudaSuccess;
    if (stream) {
        c->stream = static_cast<cudaStream_t>(stream);
        c->own_stream = false;
    } else {
        /* non-blocking: no implicit synchronisation with the legacy default stream */
        e = cudaStreamCreateWithFlags(&c->stream, cudaStreamNonBlocking);
        if (e != cudaSuccess) {
            snprintf(why, len, "CUDA device %d: cudaStreamCreate: %s", ordinal, cudaGetErrorString(e));
            free(c);
            return result_of(e);
        }
        c->own_stream = true;
    }
    dev->backend_ctx = c;
    return EW_OK;
}

#define EW_STR2(x) #x
#define EW_STR(x) EW_STR2(x)

} // namespace

/* The one exported symbol (EW_CUDA_MODULE_ENTRY). The tables are built on
 * first use (thread-safe in C++11) and never change afterwards. */
extern "C" __attribute__((visibility("default"))) const ew_module_api *ew_cuda_module_v1(void) {
    static const ew_backend table = make_table();
    static const ew_module_api api = {
        EW_MODULE_ABI,
        static_cast<unsigned>(sizeof(ew_backend)),
        static_cast<unsigned>(sizeof(struct ew_device)),
        EW_STR(EW_VERSION_MAJOR) "." EW_STR(EW_VERSION_MINOR) "." EW_STR(EW_VERSION_PATCH),
        &table,
        probe,
        device_init,
        EW_KERNEL_NAMES,
    };
    return &api;
}
