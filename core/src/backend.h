/*
 * backend.h — the table of device operations the algorithms call. Each entry
 * loops the per-pixel functions of core/kernels/ over a grid of work; the CPU
 * backend runs them on the device's threads, a CUDA backend would launch the
 * same functions as kernels. All buffers are packed float arrays in the
 * device's memory.
 */
#ifndef EW_BACKEND_H
#define EW_BACKEND_H

#include <stddef.h>
#include "edgewise/edgewise.h"
#include "kernels/kernel_ids.h"

typedef struct ew_device ew_device;
/* The entries' argument structs, defined in the headers of core/kernels/.
 * Only the files that build or run an entry include its kernel's header, so
 * a change to one kernel rebuilds those files, not every file that calls a
 * backend. */
typedef struct ew_bgrid_params ew_bgrid_params;        /* kernels/bgrid.h */
typedef struct ew_denoise_buffers ew_denoise_buffers;  /* kernels/denoise_px.h */
typedef struct ew_outlier_params ew_outlier_params;    /* kernels/outlier.h */
typedef struct ew_outlier_buffers ew_outlier_buffers;
typedef struct ew_harm_args ew_harm_args;              /* kernels/harm.h */
typedef struct ew_temporal_params ew_temporal_params;  /* kernels/temporal.h */
typedef struct ew_temporal_buffers ew_temporal_buffers;
typedef struct ew_bf_model ew_bf_model;                /* kernels/bilateral.h */
typedef struct ew_bf_buffers ew_bf_buffers;
typedef struct ew_pyr_down_args ew_pyr_down_args;      /* kernels/pyramid.h */
typedef struct ew_pyr_up_args ew_pyr_up_args;
typedef struct ew_dof_args ew_dof_args;                /* kernels/dof.h */
typedef struct ew_conv_args ew_conv_args;              /* kernels/conv.h */
typedef struct ew_gn_input_args ew_gn_input_args;      /* kernels/guidenet.h */
typedef struct ew_nbg_blend_args ew_nbg_blend_args;
typedef struct ew_view_desc ew_view_desc;              /* kernels/view.h */

typedef struct ew_backend {
    /* Flags, before the name: every member after it is an entry that must
     * be set (ew_backend_first_missing).
     * pyr_row_hooks 1: pyr_down calls a->fill and pyr_up a->drain row by row
     * (kernels/pyramid.h); 0: they ignore them, and ew_pyr_run_planes calls
     * them on every row before the first pass and after the last. */
    int pyr_row_hooks;
    /* harm_bands 1: harm takes EW_HARM_STATS_BLEND (STATS then BLEND in
     * bands of rows, the statistics never a frame: stats unused),
     * EW_HARM_RETURN and EW_HARM_PILOT_HV (the energy return's and the
     * pilot's box sums a band at a time: spread unused); 0: the op layer
     * runs their steps */
    int harm_bands;
    const char *name; /* every member after this is a function pointer (ew_backend_first_missing) */
    void (*bgrid_splat)(ew_device *dev, const ew_bgrid_params *p, const float *image,
                        const float *guide, float *grid);
    void (*bgrid_slice)(ew_device *dev, const ew_bgrid_params *p, const float *grid,
                        const float *guide, float *out);
    /* demodulate + hand-made guide for every pixel */
    void (*denoise_prepare)(ew_device *dev, const ew_denoise_buffers *b);
    /* remodulate: b->out = b->sliced * (albedo + eps) */
    void (*denoise_finish)(ew_device *dev, const ew_denoise_buffers *b);
    /* second-pass guide from the first pass's b->sliced */
    void (*denoise_refine_guide)(ew_device *dev, const ew_denoise_buffers *b, float mean_lum, float color_weight);
    /* outlier rejection, ew_outlier_guided_px over the image: the filter
     * "outlier", the denoisers' firefly clamp and the op layer's rejection */
    void (*outlier_guided)(ew_device *dev, const ew_outlier_params *p, const ew_outlier_buffers *b);
    /* one step (EW_HARM_*) of the do-no-harm stage over every pixel (kernels/harm.h) */
    void (*harm)(ew_device *dev, int step, const ew_harm_args *a);
    /* temporal accumulation of one frame into b->out_* */
    void (*temporal)(ew_device *dev, const ew_temporal_params *p, const ew_temporal_buffers *b);

    /* ---- edge-aware filters: core/backends/cpu/cpu_filters.c ---- */
    /* brute-force joint bilateral filter (Eq. 1) of every pixel */
    void (*bf_brute)(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b);
    /* one 1-D pass (axis 0: x, 1: y) of the separable bilateral filter */
    void (*bf_separable)(ew_device *dev, const ew_bf_model *m, int axis, const ew_bf_buffers *b);
    /* pyramid filter: one downsampling / upsampling pass */
    void (*pyr_down)(ew_device *dev, const ew_pyr_down_args *a);
    void (*pyr_up)(ew_device *dev, const ew_pyr_up_args *a);
    /* depth of field: CoC and (D, C) attributes from depth */
    void (*dof_attributes)(ew_device *dev, const ew_dof_args *a);

    /* ---- neural bilateral grid: CPU in core/backends/cpu/cpu_conv.c and cpu_backend.c ---- */
    /* one 5x5 GuideNet convolution (kernels/conv.h) */
    void (*conv5)(ew_device *dev, const ew_conv_args *a);
    /* GuideNet input features of a band of rows (kernels/guidenet.h) */
    void (*gn_input)(ew_device *dev, const ew_gn_input_args *a);
    /* outputs[0..ngrids) *= 255: sigmoid outputs -> guides */
    void (*nbg_guides)(ew_device *dev, long n, int ngrids, float *outputs);
    /* blend one sliced grid into the running sum */
    void (*nbg_blend)(ew_device *dev, const ew_nbg_blend_args *a);

    /* ---- every kernel of EW_KERNEL_LIST (kernels/kernel_ids.h) ---- */
    /* kernel `id` over its whole domain; args: its argument struct, of
     * args_size bytes (EW_RUN passes both). EW_ERR_INVALID_ARGUMENT, with
     * nothing run, for an unknown id or a size that is not its struct's. */
    ew_result (*run)(ew_device *dev, int id, const void *args, size_t args_size);

    /* ---- device memory: CPU in core/backends/cpu/cpu_memory.c,
     * CUDA in core/backends/cuda/. Keep this block last. Every buffer an
     * algorithm hands to the entries above comes from mem_alloc (allocated at
     * commit, reused across frames); only inputs and outputs cross between
     * host and device (docs/backends.md). On a backend with its own memory
     * (dev->device_memory) the host must not touch these buffers directly.
     * Entries returning ew_result also report queued kernels' failures and
     * have then recorded the detail as the calling thread's last error
     * (dev->set_error). ---- */
    void *(*mem_alloc)(ew_device *dev, size_t bytes); /* NULL when out of memory */
    void (*mem_free)(ew_device *dev, void *ptr);      /* NULL is a no-op */
    /* host -> device; the host buffer may be reused as soon as it returns */
    ew_result (*mem_upload)(ew_device *dev, void *dst, const void *src, size_t bytes);
    /* device -> host; waits for the work queued before it */
    ew_result (*mem_download)(ew_device *dev, void *dst, const void *src, size_t bytes);
    /* device -> device, and clearing, queued after the work before them */
    ew_result (*mem_copy)(ew_device *dev, void *dst, const void *src, size_t bytes);
    ew_result (*mem_zero)(ew_device *dev, void *ptr, size_t bytes);
    /* the first failure since the last sync; wait: 1 waits for the queued
     * work first (0 reports only failures known now, without blocking) */
    ew_result (*sync)(ew_device *dev, int wait);
    /* out[2y], out[2y+1] for every row y of src (kernels/reduce.h) */
    void (*reduce_rows)(ew_device *dev, int op, int width, int height, const float *src, double *out);
    /* a caller's strided view <-> a packed buffer, where the view's pixels
     * live (device_images devices); the first c channels */
    void (*view_pack)(ew_device *dev, const ew_view_desc *v, int c, float *dst);
    void (*view_unpack)(ew_device *dev, const float *src, int c, const ew_view_desc *v);
    /* free dev->backend_ctx when the device is destroyed */
    void (*device_release)(ew_device *dev);
} ew_backend;

extern const ew_backend ew_cpu_backend;

/* CPU implementations of the edge-aware filter entries (cpu_filters.c) */
void ew_cpu_bf_brute(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b);
void ew_cpu_bf_separable(ew_device *dev, const ew_bf_model *m, int axis, const ew_bf_buffers *b);
void ew_cpu_pyr_down(ew_device *dev, const ew_pyr_down_args *a);
void ew_cpu_pyr_up(ew_device *dev, const ew_pyr_up_args *a);
void ew_cpu_dof_attributes(ew_device *dev, const ew_dof_args *a);

/* The CPU's convolution entry (cpu_conv.c); the trainers call it directly. */
void ew_cpu_conv5(ew_device *dev, const ew_conv_args *a);

/* The CPU backend's run (cpu_kernels.c). */
ew_result ew_cpu_run(ew_device *dev, int id, const void *args, size_t args_size);

/* ---- device memory ---------------------------------------------
 * CPU implementations of the memory entries (cpu_memory.c). */
void *ew_cpu_mem_alloc(ew_device *dev, size_t bytes);
void ew_cpu_mem_free(ew_device *dev, void *ptr);
ew_result ew_cpu_mem_upload(ew_device *dev, void *dst, const void *src, size_t bytes);
ew_result ew_cpu_mem_download(ew_device *dev, void *dst, const void *src, size_t bytes);
ew_result ew_cpu_mem_copy(ew_device *dev, void *dst, const void *src, size_t bytes);
ew_result ew_cpu_mem_zero(ew_device *dev, void *ptr, size_t bytes);
ew_result ew_cpu_sync(ew_device *dev, int wait);
void ew_cpu_reduce_rows(ew_device *dev, int op, int width, int height, const float *src, double *out);
void ew_cpu_view_pack(ew_device *dev, const ew_view_desc *v, int c, float *dst);
void ew_cpu_view_unpack(ew_device *dev, const float *src, int c, const ew_view_desc *v);
void ew_cpu_device_release(ew_device *dev);

/* What algorithms call (backend_mem.c), so that one code path serves host
 * and device memory. */
void *ew_dev_alloc(ew_device *dev, size_t bytes);
void ew_dev_free(ew_device *dev, void *ptr);
/* With ew_device_desc.release_scratch on host memory: the whole pages in
 * [from, to) of a block from ew_dev_alloc go back to the system; they read
 * as zeros when touched again (as a freshly mapped block does), so only
 * buffers every later reader writes first may be given. Otherwise (the
 * default, or device memory) nothing happens. */
void ew_dev_release_pages(ew_device *dev, void *from, void *to);
/* The whole pages in [from, to) of host memory made resident now, on the
 * device's threads, for a pass that is about to write all of them: one call
 * a chunk instead of a fault a page (faults are costly in a virtual machine;
 * measured in BENCHMARKS.md, "MADV_POPULATE_WRITE"), in transparent huge
 * pages where the kernel has them free. Only ranges the pass
 * writes in full, or it would make resident what it never touches. Nothing
 * on device memory or where the system cannot do it. */
void ew_dev_prefault(ew_device *dev, void *from, void *to);
/* The whole pages of [from, to), a range written sparsely (ew_store_sparse,
 * ew_dev_copy_sparse: what a clamp took), kept out of transparent huge
 * pages (a large block is advised into them, ew_host_alloc), where one
 * value written would hold 2 MiB. Nothing on device memory. */
void ew_dev_sparse_pages(ew_device *dev, void *from, void *to);
/* bytes of a block from ew_dev_alloc set to zero: on host memory its whole
 * pages are dropped instead of written (whatever release_scratch says), so
 * a buffer written sparsely afterwards holds only the pages written; the
 * partial pages at its ends, and device memory, through mem_zero. */
ew_result ew_dev_zero(ew_device *dev, void *ptr, size_t bytes);
/* Rows of c floats a pixel between two packed device images of widths dw
 * and sw: w x h pixels from (sx, sy) of src to (dx, dy) of dst (a tile's
 * region and the frame, or a rect and its packed copy). */
ew_result ew_dev_copy_rect(ew_device *dev, float *dst, int dw, int dx, int dy, const float *src, int sw, int sx, int sy,
                           int w, int h, int c);
/* As a copy of `floats` floats from src to dst (mem_copy) and of w x h
 * pixels of one float (ew_dev_copy_rect), for a sparse plane (what a clamp
 * took): on host memory a span of zeros over zeros is not written (the
 * rule of ew_store_sparse, kernels/compat.h, a page's floats at a time),
 * so the pages of a plane zeroed by ew_dev_zero stay unmapped where only
 * zeros land. */
ew_result ew_dev_copy_sparse(ew_device *dev, float *dst, const float *src, size_t floats);
ew_result ew_dev_copy_rect_sparse(ew_device *dev, float *dst, int dw, int dx, int dy, const float *src, int sw, int sx,
                                  int sy, int w, int h);
/* A device block an op keeps from one commit to the next: a graph commits
 * its ops again every frame with the same images, and a new block would be
 * mapped and faulted in again. */
typedef struct ew_dev_kept {
    void *mem;
    size_t bytes;
} ew_dev_kept;
/* The previous commit's block, taken out of the op's state (which is then
 * released without freeing it); empty when there is no state. */
ew_dev_kept ew_dev_kept_take(ew_dev_kept *k);
/* *k becomes a block of `bytes`: old's when that is its size, else a new
 * one (NULL when out of memory) and old freed first. Contents are not kept.
 * k NULL (the new state could not be allocated): old is freed. Returns
 * k->mem. */
void *ew_dev_keep(ew_device *dev, ew_dev_kept *k, ew_dev_kept old, size_t bytes);
/* Host staging floats an op must allocate at commit to move views of n
 * pixels x c channels: 0 when the device reads host memory or the views
 * are device pointers. */
size_t ew_dev_stage_floats(const ew_device *dev, size_t n, int c);
/* The first c channels of a caller's view into the packed device buffer
 * dst, and back; stage: ew_dev_stage_floats(dev, n, c) floats, or NULL when
 * that is 0. get waits for the result unless the view is on the device. */
ew_result ew_dev_put_view(ew_device *dev, const ew_image *img, int c, float *dst, float *stage);
/* The caller's view itself as the packed buffer of c floats a pixel, when
 * ew_dev_put_view would only copy it: the device reads the view's memory
 * (host memory on the CPU, device-pointer views) and it is float, c
 * channels, packed rows. NULL otherwise, or when it overlaps `written` (a
 * view the op writes while it still reads this one; may be NULL). The
 * views are fixed from commit to execute (ew_op_set_image uncommits), so an
 * op decides at commit and allocates only the buffers it needs. */
const float *ew_dev_view_in_place(const ew_device *dev, const ew_image *img, int c, const ew_image *written);
ew_result ew_dev_get_view(ew_device *dev, const float *src, int c, const ew_image *img, float *stage);
/* A view an op may read in bands of rows as floats (ew_dev_view_rows)
 * instead of packing a float copy of the frame: EW_FORMAT_HALF, at least
 * c channels, on a device that reads host memory (the CPU). */
int ew_dev_view_half_rows(const ew_device *dev, const ew_image *img, int c);
/* Rows y0 .. y1, columns x0 .. x1 of a host view (half or float), its
 * first c channels, packed into the host buffer buf as floats, in
 * parallel: buf holds that rectangle, its (0, 0) the view's (x0, y0),
 * rows x1 - x0 pixels apart. */
void ew_dev_view_rows(ew_device *dev, const ew_image *img, int c, int y0, int y1, int x0, int x1, float *buf);
/* Do the memory spans of two views (first to last pixel) overlap? 0 when
 * either is NULL or has no data. */
int ew_images_overlap(const ew_image *a, const ew_image *b);
/* Launch kernel NAME of EW_KERNEL_LIST with *a, its argument struct (any
 * other struct is a compile error, and the loader refuses a CUDA module
 * built with another list, so callers need not check the result). */
#define EW_RUN(dev, NAME, a) ((dev)->backend->run((dev), EW_K_##NAME, ew_kargs_##NAME(a), sizeof *(a)))

/* The CUDA module's entry point (libedgewise_cuda.so, loaded by
 * backend_loader.c). Sizes are checked at load so a module built from
 * another tree is refused instead of crashing. */
#define EW_MODULE_ABI 2
#define EW_CUDA_MODULE_FILE "libedgewise_cuda.so"
#define EW_CUDA_MODULE_ENTRY "ew_cuda_module_v1"
typedef struct ew_module_api {
    unsigned abi;            /* EW_MODULE_ABI */
    unsigned sizeof_backend; /* sizeof(ew_backend) */
    unsigned sizeof_device;  /* sizeof(struct ew_device) */
    const char *version;     /* the library version it was built for */
    const ew_backend *backend;
    /* Usable devices; 0 with the reason in why[0..len) when none. */
    int (*probe)(char *why, size_t len);
    /* Set up dev->backend_ctx on device `ordinal`, queueing on `stream`
     * (a cudaStream_t, NULL: a stream of its own). */
    ew_result (*device_init)(ew_device *dev, int ordinal, void *stream, char *why, size_t len);
    const char *kernels; /* EW_KERNEL_NAMES: what each id of backend->run launches */
} ew_module_api;
typedef const ew_module_api *(*ew_module_entry_fn)(void);
/* The loaded module when a GPU is usable, else NULL (backend_loader.c;
 * probes once per process). *devices: how many GPUs. */
const ew_module_api *ew__cuda_module(int *devices);
/* A CUDA device for ew_device_create: EW_ERR_BACKEND_UNAVAILABLE without a
 * usable GPU, EW_ERR_INVALID_ARGUMENT for an ordinal beyond the GPUs. */
ew_result ew__cuda_device_create(const ew_device_desc *d, ew_device **out);

/* Index of the first NULL entry of a table, or -1 when complete. Every
 * member after `name` is a function pointer; the loader refuses an
 * incomplete module table rather than crash on a missing kernel. */
int ew_backend_first_missing(const ew_backend *b);

#endif
