/*
 * kernel_bodies.h — the body of every CUDA kernel, in the common subset of
 * C11 and CUDA C++ (kernels/compat.h), and the launch geometry of each.
 *
 * A body only turns its thread's coordinates into work-item indices,
 * bounds-checks them, and calls the same EW_HD per-pixel function that the
 * CPU backend's loops call. The __global__ functions in cuda_backend.cu do
 * nothing but fetch their ew_thread and call the body; the CPU harness
 * (tests/unit/test_launch_grid.c) calls the same bodies over the same
 * grids (launch_grid.h). One body per backend entry (per launch for entries
 * that launch several); the kernels of EW_KERNEL_LIST get theirs from the
 * list.
 *
 * Arguments: buffers (every float/double array) are device pointers.
 * Parameter structs that an args struct points to (the model ew_bf_model,
 * the pyramid's weight row) live on the host; the CUDA wrapper passes them
 * by value and the body points the args at that copy ("rebinding"), so the
 * per-pixel functions see the same layout as on the CPU.
 */
#ifndef EW_BACKENDS_CUDA_KERNEL_BODIES_H
#define EW_BACKENDS_CUDA_KERNEL_BODIES_H

#include "backends/launch_grid.h"
#include "kernels/bgrid.h"
#include "kernels/bilateral.h"
#include "kernels/conv.h"
#include "kernels/denoise_px.h"
#include "kernels/dof.h"
#include "kernels/guidenet.h"
#include "kernels/harm.h"
#include "kernels/kernel_list.h"
#include "kernels/outlier.h"
#include "kernels/pyramid.h"
#include "kernels/reduce.h"
#include "kernels/temporal.h"
#include "kernels/view.h"

/* ---- bilateral grid ------------------------------------------------------
 * Splat is a gather (kernels/bgrid.h): one thread fills one whole grid
 * column (u, v) from the pixels in its support. Columns are disjoint, so it
 * needs no atomics and is deterministic, as on the CPU. */
EW_HD ew_launch ew_kl_bgrid_splat(const ew_bgrid_params *p) { return ew_launch_2d(p->gw, p->gh); }
EW_HD void ew_kb_bgrid_splat(const ew_thread *t, const ew_bgrid_params *p, const float *EW_RESTRICT image,
                             const float *EW_RESTRICT guide, float *EW_RESTRICT grid) {
    const int u = ew_tx(t), v = ew_ty(t);
    if (u >= p->gw || v >= p->gh) return;
    ew_bgrid_splat_column(u, v, p, image, guide, grid);
}

EW_HD ew_launch ew_kl_bgrid_slice(const ew_bgrid_params *p) { return ew_launch_2d(p->width, p->height); }
EW_HD void ew_kb_bgrid_slice(const ew_thread *t, const ew_bgrid_params *p, const float *EW_RESTRICT grid,
                             const float *EW_RESTRICT guide, float *EW_RESTRICT out) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= p->width || y >= p->height) return;
    ew_bgrid_slice_px(x, y, p, grid, guide, out + ((long)y * p->width + x) * p->channels);
}

/* ---- denoiser per-pixel steps: one thread per pixel index ---------------- */
EW_HD ew_launch ew_kl_denoise_px(const ew_denoise_buffers *b) { return ew_launch_1d((long long)b->width * b->height); }
EW_HD void ew_kb_denoise_prepare(const ew_thread *t, const ew_denoise_buffers *b) {
    const long j = ew_t1(t);
    if (j >= (long)b->width * b->height) return;
    ew_denoise_prepare_px(j, ew_denoise_in_px(b, j), b);
}
EW_HD void ew_kb_denoise_finish(const ew_thread *t, const ew_denoise_buffers *b) {
    const long j = ew_t1(t);
    if (j >= (long)b->width * b->height) return;
    ew_denoise_finish_px(j, ew_denoise_in_px(b, j), b);
}
EW_HD void ew_kb_denoise_refine_guide(const ew_thread *t, const ew_denoise_buffers *b, float mean_lum,
                                      float color_weight) {
    const long j = ew_t1(t);
    if (j >= (long)b->width * b->height) return;
    ew_denoise_refine_guide_px(j, b, mean_lum, color_weight);
}

/* ---- firefly suppression ------------------------------------------------- */
EW_HD ew_launch ew_kl_outlier_guided(const ew_outlier_params *p) { return ew_launch_2d(p->width, p->height); }
EW_HD void ew_kb_outlier_guided(const ew_thread *t, const ew_outlier_params *p, const ew_outlier_buffers *b) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= p->width || y >= p->height) return;
    ew_outlier_guided_px(x, y, p, b);
}

/* ---- do-no-harm stage: one thread per pixel, every step ---------------- */
EW_HD ew_launch ew_kl_harm(const ew_harm_args *a) { return ew_launch_2d(a->width, a->height); }
EW_HD void ew_kb_harm(const ew_thread *t, int step, const ew_harm_args *a) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= a->width || y >= a->height) return;
    ew_harm_px(step, x, y, a);
}

/* ---- temporal accumulation ---------------------------------------------- */
EW_HD ew_launch ew_kl_temporal(const ew_temporal_params *p) { return ew_launch_2d(p->width, p->height); }
EW_HD void ew_kb_temporal(const ew_thread *t, const ew_temporal_params *p, const ew_temporal_buffers *b) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= p->width || y >= p->height) return;
    ew_temporal_px(x, y, p, b);
}

/* ---- joint bilateral filter ---------------------------------------------
 * Brute force covers the rows [b->y0, b->y1) only (the algorithm splits the
 * image into bands for progress reports). */
EW_HD ew_launch ew_kl_bf_brute(const ew_bf_buffers *b) { return ew_launch_2d(b->width, b->y1 - b->y0); }
EW_HD void ew_kb_bf_brute(const ew_thread *t, const ew_bf_model *m, const ew_bf_buffers *b) {
    const int x = ew_tx(t), y = b->y0 + ew_ty(t);
    if (x >= b->width || y >= b->y1) return;
    ew_bf_brute_px(x, y, m, b);
}

EW_HD ew_launch ew_kl_bf_separable(const ew_bf_buffers *b) { return ew_launch_2d(b->width, b->height); }
EW_HD void ew_kb_bf_separable(const ew_thread *t, const ew_bf_model *m, int axis, const ew_bf_buffers *b) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= b->width || y >= b->height) return;
    ew_bf_sep_px(x, y, axis, m, b);
}

/* ---- pyramid filter ------------------------------------------------------ */
EW_HD ew_launch ew_kl_pyr_down(const ew_pyr_down_args *a) { return ew_launch_2d(a->cw, a->ch); }
EW_HD void ew_kb_pyr_down(const ew_thread *t, const ew_pyr_down_args *args, const ew_bf_model *m) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= args->cw || y >= args->ch) return;
    ew_pyr_down_args a = *args;
    a.m = m; /* rebind: the model came by value */
    ew_pyr_down_px(x, y, &a);
}

/* row: the by-value copy of *args->row (ignored when args->row is NULL and
 * the weights come from the device table args->lut). */
EW_HD ew_launch ew_kl_pyr_up(const ew_pyr_up_args *a) { return ew_launch_2d(a->w, a->h); }
EW_HD void ew_kb_pyr_up(const ew_thread *t, const ew_pyr_up_args *args, const ew_bf_model *m,
                        const ew_pyr_wrow *row) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= args->w || y >= args->h) return;
    ew_pyr_up_args a = *args;
    a.m = m;
    a.row = args->row ? row : 0;
    ew_pyr_up_px(x, y, &a);
}

/* ---- depth of field attributes: five launches in stream order ------------
 * step 0: CoC per pixel; 1: near-field max per tile; 2, 3: the separable
 * scatter-max over tiles along x then y; 4: (D, C) per pixel. */
#define EW_DOF_STEPS 5
EW_HD ew_launch ew_kl_dof(const ew_dof_args *a, int step) {
    if (step == 0) return ew_launch_1d((long long)a->cam.width * a->cam.height);
    if (step == 4) return ew_launch_2d(a->cam.width, a->cam.height);
    return ew_launch_2d(a->tw, a->th);
}
EW_HD void ew_kb_dof(const ew_thread *t, const ew_dof_args *a, int step) {
    if (step == 0) {
        const long j = ew_t1(t);
        if (j >= (long)a->cam.width * a->cam.height) return;
        ew_dof_coc_px(j, a);
        return;
    }
    const int x = ew_tx(t), y = ew_ty(t);
    if (step == 4) {
        if (x >= a->cam.width || y >= a->cam.height) return;
        ew_dof_attr_px(x, y, a);
        return;
    }
    if (x >= a->tw || y >= a->th) return;
    if (step == 1) ew_dof_tile_px(x, y, a);
    else ew_dof_scatter_px(x, y, step - 2, a);
}

/* ---- neural bilateral grid (GuideNet) ------------------------------------
 * conv5: one thread per output value (x, row, output channel); the CPU
 * backend computes the same sums in SIMD blocks, in another order, so the
 * two agree to rounding, not bit for bit. */
EW_HD ew_launch ew_kl_conv5(const ew_conv_args *a) { return ew_launch_3d(a->width, a->rows, a->cout); }
EW_HD void ew_kb_conv5(const ew_thread *t, const ew_conv_args *a) {
    const int x = ew_tx(t), r = ew_ty(t), co = ew_tz(t);
    if (x >= a->width || r >= a->rows || co >= a->cout) return;
    ew_conv5_px(x, r, co, a);
}

/* the rows [y0, y1); dst is plane 0 at row y0 */
EW_HD ew_launch ew_kl_gn_input(const ew_gn_input_args *a) { return ew_launch_2d(a->width, a->y1 - a->y0); }
EW_HD void ew_kb_gn_input(const ew_thread *t, const ew_gn_input_args *a) {
    const int x = ew_tx(t), y = a->y0 + ew_ty(t);
    if (x >= a->width || y >= a->y1) return;
    ew_gn_input_px((long)y * (a->in_stride ? a->in_stride : a->width) + x, a->color, a->albedo, a->normal, a->depth, a->depth_scale,
                   a->dst + (long)(y - a->y0) * a->rs + x, a->ps);
}

EW_HD ew_launch ew_kl_nbg_px(long n) { return ew_launch_1d(n); }
EW_HD void ew_kb_nbg_guides(const ew_thread *t, long n, int ngrids, float *outputs) {
    const long j = ew_t1(t);
    if (j >= n) return;
    ew_nbg_guide_px(j, n, ngrids, outputs);
}
EW_HD void ew_kb_nbg_blend(const ew_thread *t, const ew_nbg_blend_args *a) {
    const long j = ew_t1(t);
    if (j >= a->n) return;
    ew_nbg_blend_px(j, a->s, a->ngrids, a->outputs, a->n, a->sliced, a->acc);
}

/* ---- every kernel of EW_KERNEL_LIST (kernels/kernel_ids.h) --------------
 * One thread per (x, y) of the domain the list names; ew_kl_NAME gives the
 * grid, ew_kb_NAME the body. */
#define EW_KBODY_(NAME, ARGS, PX, W, H, VEC)                                           \
    EW_HD ew_launch ew_kl_##NAME(const ARGS *a) { return ew_launch_2d(a->W, a->H); }   \
    EW_HD void ew_kb_##NAME(const ew_thread *t, const ARGS *a) {                       \
        const int x = ew_tx(t), y = ew_ty(t);                                          \
        if (x >= a->W || y >= a->H) return;                                            \
        PX(x, y, a);                                                                   \
    }
EW_KERNEL_LIST(EW_KBODY_)
#undef EW_KBODY_

/* ---- memory helpers ------------------------------------------------------ */
EW_HD ew_launch ew_kl_reduce_rows(int height) { return ew_launch_1d(height); }
EW_HD void ew_kb_reduce_rows(const ew_thread *t, int op, int width, int height, const float *EW_RESTRICT src,
                             double *EW_RESTRICT out) {
    const long y = ew_t1(t);
    if (y >= height) return;
    ew_reduce_row(op, (int)y, width, src, out);
}

EW_HD ew_launch ew_kl_view(const ew_view_desc *v) { return ew_launch_2d(v->width, v->height); }
EW_HD void ew_kb_view_pack(const ew_thread *t, const ew_view_desc *v, int c, float *EW_RESTRICT dst) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= v->width || y >= v->height) return;
    ew_view_pack_px(x, y, v, c, dst);
}
EW_HD void ew_kb_view_unpack(const ew_thread *t, const float *EW_RESTRICT src, int c, const ew_view_desc *v) {
    const int x = ew_tx(t), y = ew_ty(t);
    if (x >= v->width || y >= v->height) return;
    ew_view_unpack_px(x, y, v, c, src);
}

#endif
