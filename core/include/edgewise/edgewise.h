/*
 * edgewise.h — the one public C header of libedgewise.
 *
 * Model: OIDN's C API. Opaque handles, an explicit device, caller-owned image
 * views, set parameters -> commit -> execute. Every fallible call returns an
 * ew_result; the detailed message of the last failure is kept per device and
 * per calling thread.
 *
 * Threading contract (as OIDN's):
 *   - A device may be used from several threads at once: different ops
 *     (ew_op, and its ew_denoiser/ew_filter aliases) made on one device may
 *     be created, set, committed,
 *     executed and destroyed concurrently (their parallel loops take turns
 *     on the device's worker threads), and so may the metric functions.
 *     Two devices in one process are independent.
 *   - One op is used by one thread at a time: calls on the
 *     same handle from two threads at once must be serialised by the caller.
 *   - ew_device_last_error gives the calling thread's own last message.
 *
 * Lifetime: an op (and a node graph) holds a reference to its
 * device, so the destroy order does not matter: ew_device_destroy releases
 * the caller's reference and the device goes with the last handle made on
 * it. After ew_device_destroy the caller must not pass that device to a new
 * call (ew_device_retain first to keep using it).
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
    int32_t release_scratch; /* 1: within an execute, ops hand the pages of host
                              scratch a phase no longer needs back to the system
                              (the do-no-harm stage's statistics while the method
                              runs, a denoiser's buffers once it has run), so the
                              phases' buffers are not resident together: a lower
                              peak for a process that runs once, paid for with
                              page faults at every execute. 0 (default): kept
                              resident (a graph over many frames). Outputs are
                              the same. The CPU's memory only. */
} ew_device_desc;

#define EW_DEVICE_DESC_INIT {sizeof(ew_device_desc), EW_DEVICE_DEFAULT, 0, 0, NULL, 0, 0}

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
/* Releases the caller's reference (see "Lifetime" above); NULL is a no-op. */
EW_API void ew_device_destroy(ew_device *dev);
/* One more reference, released by one more ew_device_destroy. */
EW_API void ew_device_retain(ew_device *dev);
EW_API ew_device_type ew_device_get_type(const ew_device *dev);
EW_API int32_t ew_device_get_num_threads(const ew_device *dev);
/* Message of the calling thread's last failed call on this device ("" if
 * none): another thread's failures on the same device do not show here.
 * Valid until this thread's next call on the device. Never NULL. (Messages
 * are kept for the 64 threads that failed most recently.) */
EW_API const char *ew_device_last_error(const ew_device *dev);

/* ---- image views ------------------------------------------------------ */
typedef enum ew_format {
    EW_FORMAT_FLOAT = 1, /* 32-bit float per channel */
    /* 16-bit IEEE 754 half per channel (an EXR's half pass, numpy's
     * float16): for images that are only read, never an output. The
     * methods read the values exactly (every half is a float): the output
     * is the one float views of the same values give. kpcn (and auto when
     * it runs kpcn) reads half albedo, normal and depth where they are in
     * its streamed tiles (large frames on the CPU), so a caller holding
     * them as halves holds half the bytes (ew_op_image_flags after commit:
     * EW_IMAGE_HALF_IN_PLACE); otherwise the op packs a float copy of a
     * half view at execute (ew_op_memory counts it). */
    EW_FORMAT_HALF = 2
} ew_format;

/* A view of caller-owned pixels. Stride rules (E: the bytes of a channel,
 * 4 for EW_FORMAT_FLOAT, 2 for EW_FORMAT_HALF):
 *   - Strides are in bytes. A stride of 0 is EW_STRIDE_PACKED: "the packed
 *     value" (pixel_stride = channels * E, row_stride = pixel_stride *
 *     width), never a repeated pixel or row. A view whose pixels or rows
 *     repeat (numpy's broadcast_to, stride 0) cannot be passed as it is:
 *     copy it first (the Python package does).
 *   - pixel_stride >= channels * E; |row_stride| >= pixel_stride * width;
 *     row_stride may be negative (OFX hosts pass bottom-up images): row y
 *     starts at data + y * row_stride.
 *   - data and both strides are multiples of E (the channel's alignment).
 *   - The whole view (|row_stride| * height) must fit in an int64.
 * Views breaking a rule are refused with EW_ERR_INVALID_ARGUMENT when set. */
#define EW_STRIDE_PACKED 0
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

/* Host memory for the frames a caller fills and passes as views (a file's
 * pass decoded into it, a result written from it): aligned to 64 bytes,
 * and on Linux, from 2 MiB up, to 2 MiB with transparent huge pages asked
 * for when the kernel has free blocks of that size to give (in a virtual
 * machine the first touch of every 4 KiB page costs microseconds, and a 4K
 * frame is tens of thousands of them). Contents undefined; NULL when out of
 * memory. Release with ew_host_free (NULL is a no-op); it is the C
 * library's posix_memalign, so free() and realloc() take it too. Needs no
 * device. */
EW_API void *ew_host_alloc(size_t bytes);
EW_API void ew_host_free(void *ptr);

/* ---- progress --------------------------------------------------------- */
/* Called with a fraction in [0,1]; return 0 to cancel, non-zero to go on.
 * May be called from a worker thread, one call at a time. The callback must
 * not set, commit or execute the op that is running (those calls
 * return EW_ERR_INVALID_STATE); destroying it from the callback is deferred
 * until execute returns (return 0 as well to stop the work early). Other
 * handles may be used. */
typedef int (*ew_progress_fn)(void *user, double fraction);

/* ---- operations: every denoiser and filter ------------------------------ */
/*
 * One handle for every method (as OIDN's one OIDNFilter): create by the
 * method's name ("auto", "bgrid", "nbg", "pyramid", "dof", ...: listed by
 * ew_method_* below), set images and parameters by name, commit, execute.
 *
 * Images (ew_op_set_image) are named by the method's descriptor, e.g.
 * "color" (required), "albedo", "normal", "depth", "output" (required).
 * ew_method_image_flags says which are written (EW_IMAGE_OUTPUT) and which
 * inputs "output" may be the very same view of (EW_IMAGE_INPLACE).
 * A colour of 4 channels is RGBA: the blurring filters filter its
 * (premultiplied) alpha with the colour's weights (docs/filters.md); the
 * denoisers read RGB and pass the alpha through to an output of 4
 * channels.
 *
 * Parameters: see ew_method_param and the documentation of each method in
 * README.md. Non-finite colour samples (NaN, +-Inf) are treated as missing:
 * they get no weight and their pixels are reconstructed from the
 * neighbourhood, so the output is finite.
 */
typedef struct ew_op ew_op;

/* `method` is a name of any kind; an unknown one gives EW_ERR_UNSUPPORTED
 * with the available names in ew_device_last_error. */
EW_API ew_result ew_op_create(ew_device *dev, const char *method, ew_op **out);
EW_API void ew_op_destroy(ew_op *op); /* NULL is a no-op */
/* Pass NULL as view to unset an image. The view is copied, not the pixels. */
EW_API ew_result ew_op_set_image(ew_op *op, const char *name, const ew_image *view);
/* An EW_PARAM_INT or EW_PARAM_BOOL parameter (an enum: the index of its
 * choice name, ew_method_param_choice). */
EW_API ew_result ew_op_set_int(ew_op *op, const char *name, int32_t value);
/* An EW_PARAM_FLOAT parameter (an integer one refuses it: use set_int). */
EW_API ew_result ew_op_set_float(ew_op *op, const char *name, float value);
/* A parameter's current value: what was set, the default otherwise, or what
 * the method itself wrote back (e.g. temporal's one-shot "reset" reads 0
 * after the commit that used it). get_float reads any parameter; get_int
 * refuses a float one. */
EW_API ew_result ew_op_get_int(const ew_op *op, const char *name, int32_t *out);
EW_API ew_result ew_op_get_float(const ew_op *op, const char *name, float *out);
/* Opaque data by name, e.g. "weights": the bytes of a weights file (see
 * models/README.md). Copied and validated at once; NULL/0 unsets. */
EW_API ew_result ew_op_set_data(ew_op *op, const char *name, const void *data, size_t size);
EW_API ew_result ew_op_set_progress(ew_op *op, ew_progress_fn fn, void *user);
/* Validate images and parameters and allocate scratch memory. */
EW_API ew_result ew_op_commit(ew_op *op);
/* Run. Allocates nothing. */
EW_API ew_result ew_op_execute(ew_op *op);
/* What a committed op runs, in words: for "auto", the method, model or grid
 * settings it picked for this frame and from what (e.g. "nbg
 * 2layer-3grid-1spp (1 spp)"); for the others, the method's name. NULL
 * before a successful commit. The text lives until the next commit or
 * destroy. */
EW_API const char *ew_op_describe(const ew_op *op);
/* The memory (bytes: host, and device memory on a device that has its own)
 * that commit would allocate for images of width x height with the
 * parameters set now and every optional input image given: an upper bound
 * to check before reading any pixels (the images set are not looked at).
 * For "auto", the most of the methods it may pick for such a frame (at the
 * sample count set, else at any). The caller's own buffers (the images) are
 * not included. EW_ERR_UNSUPPORTED for a method that gives no estimate
 * (the filters, for now). Not included either: on a frame of low noise
 * (most of 16 samples or more) a denoiser's do-no-harm stage runs kpcn
 * (with its own stage) on the same input during execute (its own estimate at
 * max_memory_mb 256, plus 12 bytes a pixel), freed before execute
 * returns. */
EW_API ew_result ew_op_memory(ew_op *op, int32_t width, int32_t height, uint64_t *bytes);
/* A committed op's EW_IMAGE_* flags for one of its images: the method's
 * (ew_method_image_flags), EW_IMAGE_HALF_IN_PLACE only where this commit
 * would read a half view of the image where it is (kpcn: in its streamed
 * tiles; auto: the method it picked does), so a caller holding floats
 * learns whether holding halves would spare the op a float copy, before
 * converting (set the half view, commit again). EW_ERR_INVALID_STATE
 * before a successful commit; EW_ERR_INVALID_ARGUMENT for a name the
 * method does not have. */
EW_API ew_result ew_op_image_flags(const ew_op *op, const char *image, uint32_t *flags);
/* The op's method name and kind ("denoiser" or "filter"); static strings,
 * NULL for a NULL op. */
EW_API const char *ew_op_method(const ew_op *op);
EW_API const char *ew_op_kind(const ew_op *op);

/* ---- older names of the same handle ------------------------------------ */
/*
 * ew_denoiser_* and ew_filter_* are the ew_op_* calls under the names of
 * earlier versions (same handle, same behaviour), kept so existing callers
 * build and link unchanged. Their create only accepts a method of its kind.
 */
typedef struct ew_op ew_denoiser;
typedef struct ew_op ew_filter;

EW_API ew_result ew_denoiser_create(ew_device *dev, const char *method, ew_denoiser **out);
EW_API void ew_denoiser_destroy(ew_denoiser *d);
EW_API ew_result ew_denoiser_set_image(ew_denoiser *d, const char *name, const ew_image *view);
EW_API ew_result ew_denoiser_set_int(ew_denoiser *d, const char *name, int32_t value);
EW_API ew_result ew_denoiser_set_float(ew_denoiser *d, const char *name, float value);
EW_API ew_result ew_denoiser_set_data(ew_denoiser *d, const char *name, const void *data, size_t size);
EW_API ew_result ew_denoiser_set_progress(ew_denoiser *d, ew_progress_fn fn, void *user);
EW_API ew_result ew_denoiser_commit(ew_denoiser *d);
EW_API ew_result ew_denoiser_execute(ew_denoiser *d);
EW_API const char *ew_denoiser_describe(const ew_denoiser *d);

EW_API ew_result ew_filter_create(ew_device *dev, const char *type, ew_filter **out);
EW_API void ew_filter_destroy(ew_filter *f);
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

/*
 * What fronts need beyond the structs above, as separate queries so the
 * structs keep their layout. kind may be NULL in every ew_method_* call:
 * method names are unique across kinds, and ew_method_count(NULL) /
 * ew_method_get(NULL, i, ...) walk every method.
 */
/* "denoiser" or "filter" for a method name, NULL for an unknown one. */
EW_API const char *ew_method_kind(const char *name);

/* Image direction and aliasing. */
#define EW_IMAGE_OUTPUT 0x1u  /* written by execute; every other image is read */
#define EW_IMAGE_INPLACE 0x2u /* an input the "output" view may be the very same view of */
/* an input the method may read as EW_FORMAT_HALF where it is (no float
 * copy of the frame): for a committed op, ew_op_image_flags says whether
 * this frame's run does */
#define EW_IMAGE_HALF_IN_PLACE 0x4u
EW_API ew_result ew_method_image_flags(const char *kind, const char *name, int32_t index, uint32_t *flags);

/* Enum parameters: an EW_PARAM_INT whose value is the index of a choice
 * name (e.g. pyramid's model: "color", "gi", "depth", "none"). Fronts show
 * and accept the names. num_choices is 0 for other parameters, -1 for an
 * unknown method or index; choice returns NULL out of range. */
EW_API int32_t ew_method_param_num_choices(const char *kind, const char *name, int32_t index);
EW_API const char *ew_method_param_choice(const char *kind, const char *name, int32_t index, int32_t choice);
/* The index of a choice name, or -1. */
EW_API int32_t ew_method_param_choice_index(const char *kind, const char *name, int32_t index, const char *choice);

/* Parameter bits: EW_PARAM_PIXELS as ew_method_param_is_pixels;
 * EW_PARAM_NOOP_AT_ZERO: when every parameter of the method with this bit is
 * 0, execute copies the input unchanged (a host may skip rendering). */
#define EW_PARAM_PIXELS 0x1u
#define EW_PARAM_NOOP_AT_ZERO 0x2u
EW_API ew_result ew_method_param_flags(const char *kind, const char *name, int32_t index, uint32_t *flags);

/* The set_data name that gives parameter `index`'s value as the bytes of a
 * file instead (pyramid's "weights" table, nbg's "model" -> "weights"), or
 * NULL when there is none. Static string. */
EW_API const char *ew_method_param_data(const char *kind, const char *name, int32_t index);

/* Method bits: EW_METHOD_HOST: offered as a tool in host applications (OFX
 * plugins, menus); methods without it are references and baselines. */
#define EW_METHOD_HOST 0x1u
EW_API ew_result ew_method_flags(const char *kind, const char *name, uint32_t *flags);

/* ---- metrics ---------------------------------------------------------- */
/*
 * Quality of `test` against `reference` over the first 3 channels (1 if an
 * image has fewer), computed on the tone-mapped values clip(x, 0, 1)^(1/2.2)
 * that a display shows — the convention of the denoising literature.
 * Non-finite test samples count as the worst error: the displayed value
 * farthest from the reference's (1 against a dark reference sample, 0
 * against a bright one), so NaN never scores as identical.
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
