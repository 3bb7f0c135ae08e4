/*
 * pyramid.h — the pyramid edge-preserving filter on packed buffers: level
 * plan, scratch layout, domain weights (analytic or trained), and the run
 * (downsampling passes, then upsampling passes) through the backend table.
 */
#ifndef EW_ALGORITHMS_PYRAMID_H
#define EW_ALGORITHMS_PYRAMID_H

#include <stddef.h>

#include "kernels/pyramid.h"
#include "src/internal.h"

/* The per-level parameters the weight template leaves open (§3.3.2): the
 * fine domain weights wf by offset, the coarse domain weights wc by distance
 * class (d_x, d_y) in {1,3,5}^2 as (dy/2)*3 + dx/2, and gamma. wf[4], the
 * centre, is fixed by Eq. 2g. */
#define EW_PYR_NPARAM 19
typedef struct ew_pyr_params {
    float wf[9];
    float wc[9];
    float gamma;
} ew_pyr_params;

/* A trained table: for each node sigma (ascending), params for levels
 * 0..levels-1 (levels at and beyond a node's own level count are unused and
 * must be identity). See pyramid_weights.c for the file format. */
#define EW_PYR_MAX_NODES 64
typedef struct ew_pyr_table {
    int nodes, levels;
    float log2_sigma[EW_PYR_MAX_NODES];
    ew_pyr_params p[EW_PYR_MAX_NODES][EW_PYR_MAX_LEVELS];
} ew_pyr_table;

/* Coarser levels needed for a largest domain sigma on a w x h image: enough
 * that the layer-cake radius of the coarsest level covers 3.5 sigma (the
 * 99 % mass radius of a 2-D Gaussian is 3.03 sigma), at least 2 (below that
 * the fine 3x3 weights do the work; two levels keep the cost flat over
 * radii), and no more than it takes to reach 1x1. 0 when sigma is 0. */
int ew_pyr_levels(float sigma_max, int w, int h);

/* Largest domain sigma a model can produce (from its radius). */
float ew_pyr_sigma_max(const ew_bf_model *m);

/* The analytic weights, the paper's method "e": wf = alpha at the centre
 * only, wc = 1 - alpha everywhere, gamma = 1 (0 for diffuse GI). alpha per
 * level comes from the layer-cake decomposition of the Gaussian into discs
 * (the 4^l d f/dl rule of [XRW19]) with the level-l disc radius
 * EW_PYR_DISC_RADIUS * 2^l. Identity (alpha = 1) at levels >= levels(sigma). */
#define EW_PYR_DISC_RADIUS 1.5f
void ew_pyr_analytic(float sigma, int level, float gamma, ew_pyr_params *out);
/* Identity: the fine centre only (Up(l) = Down(l)). */
void ew_pyr_identity(ew_pyr_params *out);
/* The parameters of a level for a sigma: trained (interpolated in log2
 * sigma between nodes, towards identity below the first node; analytic
 * above the last node) or analytic when table is NULL. */
void ew_pyr_params_at(const ew_pyr_table *table, float sigma, int level, float analytic_gamma, ew_pyr_params *out);
/* Eq. 2g: the centre fine weight that makes the domain weights sum to 1. */
float ew_pyr_centre_weight(const ew_pyr_params *p);
/* Expand into the kernel's row (w_d folded into the coarse weights). */
void ew_pyr_expand(const ew_pyr_params *p, ew_pyr_wrow *row);

typedef struct ew_pyr_plan {
    ew_bf_model model;
    int width, height;
    int levels;                /* coarser levels: 0 = the identity */
    int w[EW_PYR_MAX_LEVELS + 1], h[EW_PYR_MAX_LEVELS + 1];
    int major_attr;            /* coarse attributes from the major pixel (GI) */
    int uniform;               /* one sigma for every pixel: rows, no table */
    const ew_pyr_table *table; /* NULL: analytic */
    float analytic_gamma;
    ew_pyr_wrow rows[EW_PYR_MAX_LEVELS];
    ew_pyr_wrow *lut;          /* levels x EW_PYR_LUT_N, in scratch (not uniform) */
    /* planes (kernels/pyramid.h): down[l], attr[l] of w[l] x h[l]; level 0's
     * are the input (ew_pyr_run_planes reads them), out the result. attr2[l],
     * up[l], coc[l] (l >= 1) are duplicated, 2 w[l] x h[l]; up[levels] is
     * Down(levels) duplicated. */
    float *down[EW_PYR_MAX_LEVELS + 1], *attr[EW_PYR_MAX_LEVELS + 1], *up[EW_PYR_MAX_LEVELS + 1];
    float *attr2[EW_PYR_MAX_LEVELS + 1];
    float *coc[EW_PYR_MAX_LEVELS + 1]; /* DOF: content CoC of Up(l), 1 <= l < levels */
    float *levels_end;                 /* the end of the coarse levels' planes (the table follows) */
    float *out;                        /* the result: EW_BF_CH planes of width x height, or in bands: */
    int band;                          /* rows of a band of the result (0: out is a whole frame) ... */
    long band_stride;                  /* ... one band a thread, this many floats apart, planes band x width */
    /* With bands and coarser levels, level 0's input in bands too (down[0]
     * and attr[0] are then NULL; the io's fill packs it, ew_pyr_run_planes):
     * one buffer a thread, in_stride floats apart, of EW_BF_CH + attrs
     * planes in_ps floats apart (band + 2 rows), and the rows either side of
     * every band boundary (kernels/pyramid.h, ew_pyr_up_args.fedge). */
    float *in;
    long in_stride, in_ps;
    float *in_edge;
    /* With the input in bands, no level holds duplicated attributes
     * (attr2[l] NULL): each upsampling pass expands the three coarse rows a
     * fine row reads into a thread's buffer (kernels/pyramid.h,
     * ew_pyr_up_args.cbuf), one a thread, cbuf_stride floats apart. */
    float *cbuf;
    long cbuf_stride;
} ew_pyr_plan;

/* Squared distance (full-resolution pixels) substituted for the coarse
 * samples' range function at level l (DOF only; see pyramid.c). */
float ew_pyr_coarse_d2(int l);

/* Floats of scratch a plan needs (level 0's input and output planes;
 * levels 1..L: down, attributes, up; the table). */
size_t ew_pyr_scratch_floats(const ew_bf_model *m, int w, int h, int levels, int uniform);

/* Lay out the plan in scratch (ew_pyr_scratch_floats floats) and fill the
 * weight rows. uniform: every pixel has sigma m->sigma (COLOR/DEPTH/NONE). */
void ew_pyr_plan_init(ew_pyr_plan *p, const ew_bf_model *m, int w, int h, int levels, int uniform,
                      const ew_pyr_table *table, float analytic_gamma, float *scratch);

/* The result in bands instead of a whole frame, for ew_pyr_run_planes with
 * a drain on a device whose backend drains row by row (pyr_row_hooks): each
 * thread writes the rows of a band into a buffer of its own and drains them
 * from there (ew_bf_io_unpack_band), so level 0 does not hold 4 floats a
 * pixel of result. With coarser levels its input is held in bands too
 * (ew_pyr_plan.in): the first pass packs each coarse row's two fine rows
 * into a thread's buffer and the last pass packs each band's rows again
 * from the caller's views, so level 0 holds no frame of its own at all;
 * such a plan needs the io's fill. ew_pyr_band_threads: the threads to give
 * bands to on dev at width x height, 0 when a whole frame is the better
 * choice (no row hooks, or bands as large as the frame). The _banded
 * functions take it (0: as ew_pyr_scratch_floats / ew_pyr_plan_init). */
#define EW_PYR_BAND 64
int ew_pyr_band_threads(const ew_device *dev, int w, int h);
size_t ew_pyr_scratch_floats_banded(const ew_bf_model *m, int w, int h, int levels, int uniform, int band_threads);
void ew_pyr_plan_init_banded(ew_pyr_plan *p, const ew_bf_model *m, int w, int h, int levels, int uniform,
                             const ew_pyr_table *table, float analytic_gamma, float *scratch, int band_threads);

/* Filling level 0's input planes and handing on the result (p->out) by
 * rows, inside the first and the last pass (the fill and drain of
 * kernels/pyramid.h); either may be NULL. fill writes the values' EW_BF_CH
 * planes and the attributes' after them, where it is told: p->down[0] (with
 * p->attr[0] after it) or, with the input in bands, a thread's buffer. */
typedef struct ew_pyr_io {
    ew_pyr_fill_fn fill;
    void *fill_user;
    void (*drain)(void *user, int y0, int y1, int tid);
    void *drain_user;
} ew_pyr_io;

/* Filter: image (w*h*EW_BF_CH, premultiplied, mask last) and attributes
 * (w*h*A) at level 0; out (the normalised sum, still premultiplied) may not
 * alias image. Progress is reported through fn when
 * given (return 0 to stop: ew_pyr_run then returns 0). */
int ew_pyr_run(ew_device *dev, const ew_pyr_plan *p, const float *image, const float *attr, float *out,
               int (*progress)(void *user, double fraction), void *user);
/* The same on the plan's own planes: p->down[0] (EW_BF_CH planes) and
 * p->attr[0] (attrs planes) in, p->out out (what the filter ops use: io,
 * when not NULL, packs the views straight into the planes and unpacks the
 * result). Cancelled through progress before the upsampling, nothing is
 * drained. */
int ew_pyr_run_planes(ew_device *dev, const ew_pyr_plan *p, const ew_pyr_io *io,
                      int (*progress)(void *user, double fraction), void *user);
/* Interleaved (n x k) <-> planes (k planes of n). */
void ew_pyr_to_planes(const float *src, int k, size_t n, float *planes);
void ew_pyr_from_planes(const float *planes, int k, size_t n, float *dst);

/* ---- training (pyramid_train.c) ---- */
/* The forward pass on the calling thread alone (training runs one image per
 * thread), keeping every level in the plan's scratch. downs_done: the
 * downsampling pyramid of this image is already there (it does not depend
 * on the weights). Uniform plans only. */
void ew_pyr_forward1(const ew_pyr_plan *p, const float *image, const float *attr, float *out, int downs_done);
/* The exact gradient of a loss with respect to the parameters of every
 * level, given dL/dout (w*h*EW_BF_CH floats, 0 where the loss does not
 * look) and the forward's results still in the plan: accumulates
 * grad[l * EW_PYR_NPARAM + k], k laid out as ew_pyr_params, with the centre
 * fine weight eliminated by Eq. 2g (its entry stays 0). scratch:
 * ew_pyr_grad_scratch_floats floats. */
size_t ew_pyr_grad_scratch_floats(int w, int h);
void ew_pyr_backward1(const ew_pyr_plan *p, const float *image, const float *attr, const float *out,
                      const float *dout, float *scratch, double *grad);

/* ---- the weights file (pyramid_weights.c) ---- */
#define EW_PYR_ARCH "xu2024-dual3x3/v1: wf[9] by fine offset, wc[9] by distance class, gamma; " \
                    "levels=max(2,ceil(log2(3.5 sigma)))"
/* Parse and validate a weights file (src/weights.h) in memory: the
 * container's checks (magic, version, sizes, checksum, finite values), then
 * architecture string, tensor names and shapes, Eq. 2g and the weights'
 * ranges. Returns EW_OK or EW_ERR_INVALID_DATA with why filled. */
ew_result ew_pyr_table_parse(const void *data, size_t size, ew_pyr_table *out, char *why, size_t whylen);
/* Serialise a table (what the training tool writes). Returns the number of
 * bytes needed, 0 when out of memory; writes only when buf is large enough. */
size_t ew_pyr_table_write(const ew_pyr_table *t, void *buf, size_t cap);
/* The trained table built into the library for a model kind, parsed and
 * validated into *out: GI's own (pyramid_weights_gi_data.c, a copy of
 * models/pyramid/pyramid_gi.ewpw, trained on GI denoising only), else the
 * table trained on colour, GI and depth together (pyramid_weights_data.c,
 * models/pyramid/pyramid.ewpw; DoF uses it too). */
ew_result ew_pyr_builtin_table(int kind, ew_pyr_table *out, char *why, size_t whylen);

#endif
