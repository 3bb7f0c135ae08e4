/*
 * edgewise.h — the one public C header of libedgewise.
 *
 * Model: OIDN's C API. Opaque handles, an explicit device, caller-owned image
 * views, set parameters -> commit -> execute. Every fallible call returns an
 * ew_result; the detailed message of the last failure is kept per device.
 * The library never prints, never exits and has no global mutable state
 * (beyond the once-written CUDA probe of ew_backend_unavailable_reason).
 */
#ifndef EDGEWISE_EDGEWISE_H
#define EDGEWISE_EDGEWISE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32)
#define EW_API __declspec(dllexport)
#else
#define EW_API __attribute__((visibility("default")))
#endif

#define EW_VERSION_MAJOR 0
#define EW_VERSION_MINOR 1
#define EW_VERSION_PATCH 0

/* ---- results ---------------------------------------------------------- */
typedef enum ew_result {
    EW_OK = 0,
    EW_ERR_INVALID_ARGUMENT = 1,  /* a null handle, a bad view, a value out of range   */
    EW_ERR_OUT_OF_MEMORY = 2,
    EW_ERR_UNSUPPORTED = 3,       /* a valid request this build cannot do             */
    EW_ERR_BACKEND_UNAVAILABLE = 4,
    EW_ERR_IO = 5,
    EW_ERR_CANCELLED = 6,         /* the progress callback returned 0                 */
    EW_ERR_INVALID_STATE = 7,     /* e.g. execute before commit, missing input image  */
    EW_ERR_INVALID_DATA = 8       /* a weights file or other data failed validation   */
} ew_result;

/* Static text for a result code; never NULL. */
EW_API const char *ew_result_string(ew_result r);

/* ---- version ---------------------------------------------------------- */
/* Version of the library actually loaded (may differ from the header's). */
EW_API void ew_version(int *major, int *minor, int *patch);
EW_API const char *ew_version_string(void);

/* ---- device ----------------------------------------------------------- */
typedef struct ew_device ew_device;

typedef enum ew_device_type {
    EW_DEVICE_DEFAULT = 0, /* the CPU for now: only some methods run on CUDA yet
                              (ew_device_get_type tells which was made) */
    EW_DEVICE_CPU = 1,
    EW_DEVICE_CUDA = 2
} ew_device_type;

typedef struct ew_device_desc {
    size_t size;           /* sizeof(ew_device_desc): lets the struct grow */
    ew_device_type type;
    int32_t num_threads;   /* CPU worker threads; 0 = one per online core  */
    /* CUDA devices only (a CPU device ignores them); a desc whose size ends
     * before them gets these defaults. */
    int32_t cuda_device;   /* device ordinal; 0 = the first GPU */
    void *cuda_stream;     /* a cudaStream_t to queue all work on (an OFX host's);
                              NULL = a stream of the device's own */
    int32_t device_images; /* 1: every image view's data is a CUDA device pointer:
                              pixels never cross to the host, and execute only
                              queues work on the stream (it never synchronises the
                              device; see each method for the small reads back it
                              needs). Requires type EW_DEVICE_CUDA. */
} ew_device_desc;

#define EW_DEVICE_DESC_INIT {sizeof(ew_device_desc), EW_DEVICE_DEFAULT, 0, 0, NULL, 0}

/* EW_DEVICE_CUDA on a machine without a usable GPU, driver or CUDA module
 * returns EW_ERR_BACKEND_UNAVAILABLE. EW_DEVICE_DEFAULT gives a CPU device. */
EW_API ew_result ew_device_create(const ew_device_desc *desc, ew_device **out);
/* Why ew_device_create(type) cannot give that backend on this machine, e.g.
 * "libedgewise_cuda.so: no CUDA driver (libcuda.so.1) ...", or "" when it
 * can. For EW_DEVICE_DEFAULT: why it is the CPU. Static text, never NULL,
 * thread-safe. No device is needed (there is none to hold a message when
 * creation fails): the first call for CUDA (or the first CUDA
 * ew_device_create) probes once — loads the module,
 * counts GPUs — and the answer holds for the life of the process. That
 * once-written probe is the library's only global state. */
EW_API const char *ew_backend_unavailable_reason(ew_device_type type);
EW_API void ew_device_destroy(ew_device *dev); /* NULL is a no-op */
EW_API ew_device_type ew_device_get_type(const ew_device *dev);
EW_API int32_t ew_device_get_num_threads(const ew_device *dev);
/* Message of the last failed call on this device ("" if none). Valid until
 * the next call on the device. Never NULL. */
EW_API const char *ew_device_last_error(const ew_device *dev);

/* ---- image views ------------------------------------------------------ */
typedef enum ew_format {
    EW_FORMAT_FLOAT = 1 /* 32-bit float per channel */
} ew_format;

/* A view of caller-owned pixels. Strides are in bytes; 0 means packed.
 * row_stride may be negative (OFX hosts pass bottom-up images). */
typedef struct ew_image {
    void *data;
    int32_t width, height, channels;
    int64_t pixel_stride;
    int64_t row_stride;
    ew_format format;
} ew_image;

/* The denoisers divide colour by (albedo + EW_ALBEDO_EPSILON) and multiply
 * it back the same way: black albedo (emitters, background) amplifies noise
 * at most 1/EPSILON times and there is no threshold to make seams. Callers
 * that demodulate around a filter should use the same value. */
#define EW_ALBEDO_EPSILON 0.01f

/* A packed float view of a caller buffer of width*height*channels floats. */
EW_API ew_image ew_image_packed(float *data, int32_t width, int32_t height, int32_t channels);

/* ---- progress --------------------------------------------------------- */
/* Called with a fraction in [0,1]; return 0 to cancel, non-zero to go on.
 * May be called from a worker thread, one call at a time. */
typedef int (*ew_progress_fn)(void *user, double fraction);

/* ---- denoiser --------------------------------------------------------- */
/*
 * Methods (name given at creation):
 *   "bgrid"  bilateral grid with a hand-made guide: the mean of the
 *            normalised auxiliary features (the baseline of Meng et al. 2020,
 *            Fig. 7), or the luminance of the colour when no features are set.
 *
 * Images (ew_denoiser_set_image): "color" (3 ch, required), "albedo" (3 ch),
 * "normal" (3 ch, in [-1,1]), "depth" (1 ch), "output" (3 ch, required; may
 * alias "color" exactly).
 *
 * Parameters: see ew_denoiser_set_int / set_float and the documentation of
 * each method in README.md. Non-finite colour samples (NaN, +-Inf) are treated
 * as missing: they get no weight and their pixels are reconstructed from the
 * neighbourhood, so the output is finite.
 */
typedef struct ew_denoiser ew_denoiser;

EW_API ew_result ew_denoiser_create(ew_device *dev, const char *method, ew_denoiser **out);
EW_API void ew_denoiser_destroy(ew_denoiser *d); /* NULL is a no-op */
/* Pass NULL as view to unset an image. The view is copied, not the pixels. */
EW_API ew_result ew_denoiser_set_image(ew_denoiser *d, const char *name, const ew_image *view);
EW_API ew_result ew_denoiser_set_int(ew_denoiser *d, const char *name, int32_t value);
EW_API ew_result ew_denoiser_set_float(ew_denoiser *d, const char *name, float value);
/* Opaque data by name, e.g. "weights": the bytes of a weights file (see
 * models/README.md). Copied and validated at once; NULL/0 unsets. */
EW_API ew_result ew_denoiser_set_data(ew_denoiser *d, const char *name, const void *data, size_t size);
EW_API ew_result ew_denoiser_set_progress(ew_denoiser *d, ew_progress_fn fn, void *user);
/* Validate images and parameters and allocate scratch memory. */
EW_API ew_result ew_denoiser_commit(ew_denoiser *d);
/* Run. Allocates nothing. */
EW_API ew_result ew_denoiser_execute(ew_denoiser *d);
/* What a committed denoiser runs, in words: for "auto", the method, model
 * or grid settings it picked for this frame and from what (e.g. "nbg
 * 2layer-3grid-1spp (1 spp)"); for the others, the method's name. NULL
 * before a successful commit. The text lives until the next commit or
 * destroy. */
EW_API const char *ew_denoiser_describe(const ew_denoiser *d);

/* ---- filters ---------------------------------------------------------- */
/*
 * Edge-aware filters share the denoiser's life cycle: create by type name,
 * set images and parameters by name, commit, execute. Types and their
 * images/parameters are listed by ew_method_* below and in README.md.
 */
typedef struct ew_filter ew_filter;

EW_API ew_result ew_filter_create(ew_device *dev, const char *type, ew_filter **out);
EW_API void ew_filter_destroy(ew_filter *f); /* NULL is a no-op */
EW_API ew_result ew_filter_set_image(ew_filter *f, const char *name, const ew_image *view);
EW_API ew_result ew_filter_set_int(ew_filter *f, const char *name, int32_t value);
EW_API ew_result ew_filter_set_float(ew_filter *f, const char *name, float value);
EW_API ew_result ew_filter_set_data(ew_filter *f, const char *name, const void *data, size_t size);
EW_API ew_result ew_filter_set_progress(ew_filter *f, ew_progress_fn fn, void *user);
EW_API ew_result ew_filter_commit(ew_filter *f);
EW_API ew_result ew_filter_execute(ew_filter *f);

/* ---- introspection ---------------------------------------------------- */
/*
 * Every denoiser and filter, its images and parameters, from the same static
 * descriptors the library validates against; front ends (nodes, OFX, Python,
 * Blender) build their UIs from these. kind is "denoiser" or "filter".
 * Strings are static. Index out of range returns EW_ERR_INVALID_ARGUMENT.
 */
typedef enum ew_param_type { EW_PARAM_FLOAT = 0, EW_PARAM_INT = 1, EW_PARAM_BOOL = 2 } ew_param_type;

typedef struct ew_param_info {
    const char *name;
    ew_param_type type;
    float default_value, min_value, max_value;
    const char *hint;
} ew_param_info;

typedef struct ew_image_info {
    const char *name;
    int32_t min_channels;
    int32_t required;   /* 1: commit fails without it */
    const char *hint;
} ew_image_info;

EW_API int32_t ew_method_count(const char *kind);
EW_API ew_result ew_method_get(const char *kind, int32_t index, const char **name, const char **summary,
                               int32_t *num_images, int32_t *num_params);
EW_API ew_result ew_method_image(const char *kind, const char *name, int32_t index, ew_image_info *out);
EW_API ew_result ew_method_param(const char *kind, const char *name, int32_t index, ew_param_info *out);
/* 1 when parameter `index` of a method is a length in image pixels (a
 * radius, a grid cell): a host rendering at a reduced scale (an OFX proxy)
 * multiplies it by that scale so the result looks the same. 0 when it is
 * not, -1 for an unknown method or index. */
EW_API int32_t ew_method_param_is_pixels(const char *kind, const char *name, int32_t index);

/* ---- metrics ---------------------------------------------------------- */
/*
 * Quality of `test` against `reference` over the first 3 channels (1 if an
 * image has fewer), computed on the tone-mapped values clip(x, 0, 1)^(1/2.2)
 * that a display shows — the convention of the denoising literature.
 * Non-finite test samples count as the worst error (0 vs reference).
 * PSNR in dB (+inf for identical images), SSIM with an 11x11 Gaussian
 * window (sigma 1.5), averaged over channels.
 */
EW_API ew_result ew_image_psnr(ew_device *dev, const ew_image *test, const ew_image *reference, double *out);
EW_API ew_result ew_image_ssim(ew_device *dev, const ew_image *test, const ew_image *reference, double *out);
/* On linear values (no tone mapping), the MC denoising papers' HDR metrics:
 * relative MSE  mean((t - r)^2 / (r^2 + 0.01)),
 * SMAPE         mean(|t - r| / (|t| + |r| + 0.01)). */
EW_API ew_result ew_image_relmse(ew_device *dev, const ew_image *test, const ew_image *reference, double *out);
EW_API ew_result ew_image_smape(ew_device *dev, const ew_image *test, const ew_image *reference, double *out);

/*
 * Temporal stability of a sequence, one pair of consecutive frames at a
 * time, on the same tone-mapped values as PSNR (every frame-to-frame
 * difference below is mean |tm(frame t) - tm(frame t-1)| over pixels and the
 * first 3 channels; non-finite samples count as 0):
 *   test       the difference of the method's output,
 *   reference  the difference of the reference (what really changes: motion,
 *              lighting, plus the reference's own residual noise),
 *   excess     test - reference: the change the method adds (its flicker; 0
 *              when it is as stable as the reference, < 0 when it is
 *              smoother in time than the reference, e.g. lagging),
 *   static_flicker  the output's difference over the static pixels only:
 *              those whose reference changes by less than static_tol in
 *              every channel and, when `vector` (2 channels, pixels per
 *              frame, e.g. Cycles Vector.XY of frame t) is given, whose
 *              motion is shorter than 0.5 pixel; 0 when there are none,
 *   static_pixels   how many pixels are static.
 * Over a sequence, average test/reference/excess over its pairs and
 * static_flicker weighted by static_pixels. All views must have one size.
 */
typedef struct ew_temporal_diff {
    double test, reference, excess;
    double static_flicker;
    int64_t static_pixels;
} ew_temporal_diff;
EW_API ew_result ew_image_temporal_diff(ew_device *dev, const ew_image *test_prev, const ew_image *test,
                                        const ew_image *reference_prev, const ew_image *reference,
                                        const ew_image *vector, float static_tol, ew_temporal_diff *out);

#ifdef __cplusplus
}
#endif

#endif /* EDGEWISE_EDGEWISE_H */
