/*
 * op.h — what every denoiser and filter shares: named image slots and named
 * parameters declared once in a static descriptor, the set -> commit ->
 * execute life cycle, progress and cancellation. A method is an ew_op_type;
 * an ew_op (public: edgewise.h) is one instance of it, and ew_denoiser /
 * ew_filter are older names of the same handle.
 *
 * The descriptors are also what the node layer, the OFX plugin and the
 * Blender add-on read to build their parameters (a parameter is declared
 * once).
 */
#ifndef EW_OP_H
#define EW_OP_H

#include "src/internal.h"

#define EW_OP_MAX_IMAGES 8
#define EW_OP_MAX_PARAMS 24

/* The public ew_param_info / ew_image_info are the descriptors. */
typedef ew_param_info ew_param_desc;
typedef ew_image_info ew_image_desc;

typedef struct ew_op ew_op;

/* The choice names of an enum parameter (an EW_PARAM_INT whose value is the
 * index of a name): fronts show and accept the names. */
typedef struct ew_param_choices {
    const char *param;         /* the parameter's name */
    const char *const *names;  /* NULL-terminated; value i is names[i] */
} ew_param_choices;

typedef struct ew_op_type {
    const char *kind; /* "denoiser" or "filter" */
    const char *name;
    const char *summary;
    const ew_image_desc *images; /* the last one named "output" */
    int num_images;
    const ew_param_desc *params;
    int num_params;
    /* Validate the combination of images and parameters (sizes already
     * checked equal to the first image's) and allocate scratch in op->state.
     * Called again after any change. */
    ew_result (*commit)(ew_op *op);
    ew_result (*execute)(ew_op *op);
    void (*release)(ew_op *op); /* free op->state */
    /* Optional: accept named data (e.g. "weights"), validating it now and
     * keeping what it needs in op->data_state (freed by release_data). */
    ew_result (*set_data)(ew_op *op, const char *name, const void *data, size_t size);
    void (*release_data)(ew_op *op);
    /* 1 when every buffer it hands the backend comes from
     * ew_dev_alloc and views move only through ew_dev_put_view/get_view
     * (docs/backends.md); only then may it run on a device with memory of
     * its own (CUDA): ew_op_create refuses it there otherwise. */
    int device_memory;
    /* Optional: what a committed op runs, in words (ew_denoiser_describe);
     * NULL means the method's own name. */
    const char *(*describe)(const ew_op *op);
    /* Optional, NULL-terminated: the parameters that are lengths in pixels
     * (ew_method_param_is_pixels). */
    const char *const *pixel_params;
    /* Optional, ended by a {NULL, NULL} entry: enum parameters and their
     * choice names (ew_method_param_choice). The parameter must be an
     * EW_PARAM_INT with range [0, number of names - 1]. */
    const ew_param_choices *choices;
    /* Optional, NULL-terminated: images execute writes besides "output"
     * (e.g. DoF's "coc"); every other image is read. */
    const char *const *extra_outputs;
    /* Optional, NULL-terminated: inputs the "output" view may be the very
     * same view of (filtering in place). */
    const char *const *inplace_inputs;
    /* Optional, NULL-terminated: inputs the method reads as EW_FORMAT_HALF
     * views itself (EW_IMAGE_HALF_IN_PLACE); other half views are packed
     * into float copies for it (op_half.c). */
    const char *const *half_inputs;
    /* Optional: whether this commit reads a half view of the image (one of
     * half_inputs) where it is (ew_op_image_flags); NULL: always. */
    int (*reads_half)(const ew_op *op, const char *image);
    /* Optional, NULL-terminated: parameters that, all 0, make execute a
     * copy of the input (EW_PARAM_NOOP_AT_ZERO). */
    const char *const *noop_at_zero;
    /* Optional, NULL-terminated pairs {parameter, data name}: the set_data
     * slot that gives the parameter's value as a file's bytes instead
     * (pyramid's "weights"; nbg's "model" -> "weights"). */
    const char *const *data_params;
    /* EW_METHOD_* bits (ew_method_flags). */
    uint32_t flags;
    /* A filter whose output is a denoised version of its colour (à-trous,
     * the bilateral family): it gets the do-no-harm stage's parameters,
     * off by default (src/harm_stage.c). Denoisers always have them, on. */
    int denoises;
    /* 1: the op runs another op that has the stage (auto): it forwards the
     * stage's parameters (ew_harm_forward) instead of running it twice. */
    int stage_in_inner;
    /* 1: when the do-no-harm stage asks (ew_harm_fused), the op finishes
     * each tile's region through ew_harm_region_done before its core goes
     * out, and reads a colour its output overlaps (the stage has clamped
     * the caller's colour in place): the stage then holds no frame of RGB
     * of its own. */
    int stage_in_tiles;
    /* 1: a colour of 4 channels is premultiplied RGBA, and its alpha is
     * filtered with the colour's weights (op_alpha.c runs the method a second
     * time on the alpha), so a blur keeps colour <= alpha where it was and a
     * non-finite alpha is rebuilt like colour. 0: alpha passes through. */
    int filters_alpha;
    /* Optional, with filters_alpha: give the alpha's run the images the
     * method derives from the colour when they are unset (the default
     * guide), so that both runs weigh every pixel alike. */
    void (*alpha_guides)(const ew_op *op, ew_op *alpha_op);
    /* Optional (ew_op_memory): the bytes commit would allocate for images of
     * w x h with every optional input set and the parameters as they are
     * now, from the same size computation commit uses; 0 when it cannot
     * say. */
    uint64_t (*memory)(const ew_op *op, int w, int h);
} ew_op_type;

struct ew_op {
    const ew_op_type *type;
    ew_device *dev;
    ew_image images[EW_OP_MAX_IMAGES]; /* what the method reads: given, or a float copy of it */
    int has_image[EW_OP_MAX_IMAGES];
    ew_image given[EW_OP_MAX_IMAGES]; /* the caller's views */
    /* floats packed from half views the method does not read itself (op_half.c) */
    float *half_copy[EW_OP_MAX_IMAGES];
    size_t half_copy_floats[EW_OP_MAX_IMAGES];
    float params[EW_OP_MAX_PARAMS];
    ew_progress_fn progress;
    void *progress_user;
    int committed;
    /* 1 while commit or execute runs: calls on the op from its progress
     * callback (which may run on a worker thread) are refused rather than
     * free state the run is using; a destroy then waits for the run's end. */
    int busy;
    int destroy_pending;
    void *state;
    size_t state_bytes; /* of state when made by ew_op_state_block, else 0 */
    void *data_state;
    void *harm; /* the do-no-harm stage's buffers (src/harm_stage.c), or NULL */
    /* filters_alpha with an RGBA colour: the run on the alpha and the alpha
     * it writes (op_alpha.c), made at commit */
    struct ew_op *alpha_op;
    float *alpha_out;
    /* this execute's alpha was one finite value everywhere: alpha_op did not
     * run and the output's alpha is alpha_value (op_alpha.c) */
    int alpha_uniform;
    float alpha_value;
};

/* Registry of every method, by kind. NULL-terminated. */
extern const ew_op_type *const ew_op_types[];
/* EW_REGISTER_OP(type, order); after an op type's definition lists it in
 * ew_op_types: the build collects these lines (cmake/ew_op_registry.cmake)
 * and tools show the methods by ascending order (the denoisers 10-40, the
 * filters 50-110 today), so a new method edits no list. */
#define EW_REGISTER_OP(TYPE, ORDER) extern const ew_op_type TYPE
/* kind NULL: a method of any kind (names are unique across kinds). */
const ew_op_type *ew_op_type_find(const char *kind, const char *name);

/* ew_op_create restricted to one kind (the ew_denoiser_create /
 * ew_filter_create faces, and ops that run another of a known kind). The
 * other life-cycle calls are the public ew_op_* of edgewise.h. */
ew_result ew_op_create_kind(ew_device *dev, const char *kind, const char *name, ew_op **out);
ew_result ew_op_set_param(ew_op *op, const char *name, float value, int is_int);

/* For op implementations: the image of a slot (NULL if unset), a parameter
 * value by index, and progress (returns 0 when the caller cancels). */
const ew_image *ew_op_image(const ew_op *op, const char *name);
float ew_op_param(const ew_op *op, const char *name);
/* Overwrite a parameter from inside the op (e.g. a one-shot trigger). */
void ew_op_param_put(ew_op *op, const char *name, float value);
int ew_op_report(ew_op *op, double fraction);

/* op->state as one host block of `bytes` (for an op whose state is that
 * block, released with free): the block it has when that is already the
 * size — a graph commits its ops again every frame with the same images,
 * and a new block would be faulted in and zeroed by the kernel again —
 * else a new one (the old one freed first). Contents are not kept. NULL
 * when out of memory; the op then has no state. */
void *ew_op_state_block(ew_op *op, size_t bytes);

/* A type's parameters: its own, then the do-no-harm stage's when it has
 * the stage (src/harm_stage.c). Every front lists them through these. */
int ew_op_type_num_params(const ew_op_type *t);
const ew_param_desc *ew_op_type_param(const ew_op_type *t, int i);

/* The do-no-harm stage (src/harm_stage.c): commit sizes its buffers (or
 * frees them when it has nothing to do), execute runs the op inside it. */
ew_result ew_harm_commit(ew_op *op);
ew_result ew_harm_execute(ew_op *op);
void ew_harm_release(ew_op *op);
/* Where a denoiser's own firefly clamp records what it took from each pixel
 * (ew_outlier_buffers.removed; the stage gives it back after the method),
 * or NULL when the op runs without the stage. A device buffer of 1 float
 * per pixel, zeroed before every execute. */
float *ew_harm_clamp_removed(const ew_op *op);
/* 1 while the stage runs inside the method's tiles (a stage_in_tiles op
 * whose output is its colour, on the CPU): the method's colour holds the
 * clamped colour in place of the caller's, and every region ends with
 * ew_harm_region_done. */
int ew_harm_fused(const ew_op *op);
/* Whether the stage would run in the tiles with the op's views and
 * parameters as they are (a method's commit plans for it: the blend's
 * margin, what its tiles hold back). */
int ew_harm_may_fuse(const ew_op *op);
/* The stage's blend on a tile's region (rw x rh, packed, its top left at
 * (x, y) in the frame): in is the clamped colour there (RGB), out the
 * method's output (blended in place, and with the pilot's estimate where a
 * pilot runs), give the share of each pixel the method's clamp took
 * (ew_harm_clamp_removed's values for the region; rewritten as that
 * light), or NULL when the clamp took nothing. The pixels
 * ew_harm_region_margin or more from a region edge that is not the frame's
 * come out as the whole-frame stage would give them. */
ew_result ew_harm_region_done(ew_op *op, int x, int y, int rw, int rh, const float *in, float *out, float *give);
/* The pixels a core's blend reads beyond it in this execute (more where
 * the pilot's estimate follows the blend; a commit's plan without one):
 * a region that is the core and this margin (clipped to the frame) gives
 * the core's pixels exactly. */
int ew_harm_region_margin(const ew_op *op);
/* The most ew_harm_region_margin may be at any execute of the op as it is
 * (with the pilot's estimate where a pilot may run): for a method whose
 * halo is fixed at commit. */
int ew_harm_region_margin_most(const ew_op *op);
/* Host bytes the stage holds through the method in this execute (the
 * pilot's estimate ahead of the regions), 0 else, and 0 on a device whose
 * memory is not the host's (its budget is the device's): a method that
 * plans its tiles at execute leaves them out of its budget. */
size_t ew_harm_held_bytes(const ew_op *op);
/* The stage's allocations for images of w x h (ew_op_memory adds them). */
uint64_t ew_harm_memory(const ew_op *op, int w, int h);
/* Copy the stage's parameters of one op to another (auto -> its method). */
void ew_harm_forward(const ew_op *from, ew_op *to);
/* op_alpha.c: the second run of a filters_alpha method on an RGBA colour's
 * alpha. commit makes it (after the method's own commit), execute runs it
 * before the method (which may filter in place) and store puts its alpha
 * into the output after; release frees it. pass: a denoiser's (which
 * reads RGB) copies an RGBA colour's alpha into its output. */
ew_result ew_op_alpha_commit(ew_op *op);
ew_result ew_op_alpha_execute(ew_op *op);
void ew_op_alpha_store(ew_op *op);
void ew_op_alpha_pass(ew_op *op);
void ew_op_alpha_release(ew_op *op);

/* op_half.c: half views the method does not read itself (half_inputs).
 * commit gives the method a float copy's view in op->images (after the
 * sizes are checked, before the method's commit); execute packs the
 * caller's views into the copies; memory: their bytes for w x h; release
 * frees them (with the op). */
ew_result ew_op_half_commit(ew_op *op);
void ew_op_half_execute(ew_op *op);
uint64_t ew_op_half_memory(const ew_op *op, int w, int h);
void ew_op_half_release(ew_op *op);

/* Pack the first c channels of a view into a dense buffer, and back. */
void ew_view_pack(const ew_image *img, int c, float *dst);
void ew_view_unpack(const float *src, int c, const ew_image *img);

#endif
