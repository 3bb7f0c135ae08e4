/*
 * kernels_probe.h — one function that runs a little of every kernel header
 * (and the CUDA kernel bodies) on fixed inputs, written in the common
 * subset of C11 and CUDA C++. test_kernels_cxx compiles it as C and as C++
 * the way nvcc's host and device passes see it, and compares the results:
 * a construct that nvcc would reject fails to compile there, and a
 * difference between the #ifdef branches shows up as different numbers.
 *
 * in: EW_PROBE_IN floats in [0, 1); scratch: EW_PROBE_SCRATCH floats;
 * out: EW_PROBE_OUT floats, all written (unused ones 0).
 */
#ifndef EW_TESTS_KERNELS_PROBE_H
#define EW_TESTS_KERNELS_PROBE_H

#include "backends/cuda/kernel_bodies.h"

#define EW_PROBE_IN 4096
#define EW_PROBE_SCRATCH 16384
#define EW_PROBE_OUT 4096
#define EW_PW 9
#define EW_PH 7
#define EW_PN (EW_PW * EW_PH)

/* Every thread of launch l, in order (the device-pass build has no
 * EW_LAUNCH_WALK; the order is irrelevant to the results). */
#define EW_PROBE_FOR_THREADS(l, t, stmt)                                                        \
    for (unsigned bz = 0; bz < (l).grid.z; bz++)                                                \
        for (unsigned by = 0; by < (l).grid.y; by++)                                            \
            for (unsigned bx = 0; bx < (l).grid.x; bx++)                                        \
                for (unsigned tz = 0; tz < (l).block.z; tz++)                                   \
                    for (unsigned ty = 0; ty < (l).block.y; ty++)                               \
                        for (unsigned tx = 0; tx < (l).block.x; tx++) {                         \
                            ew_thread t;                                                        \
                            t.block_idx = ew_dim3_make(bx, by, bz);                             \
                            t.block_dim = (l).block;                                            \
                            t.thread_idx = ew_dim3_make(tx, ty, tz);                            \
                            stmt;                                                               \
                        }

EW_HD int ew_probe_run(const float *in, float *scratch, float *out) {
    int o = 0;
    for (int i = 0; i < EW_PROBE_OUT; i++) out[i] = 0.0f;
    for (int i = 0; i < EW_PROBE_SCRATCH; i++) scratch[i] = 0.0f;

    /* math helpers: the #ifdef'd bit casts, the polynomial exp / log2 */
    for (int i = 0; i < 64; i++) {
        out[o++] = ew_fexp(in[i] * 60.0f - 40.0f);
        out[o++] = ew_flog2(in[i] * 100.0f + 1e-3f);
        out[o++] = ew_tent(in[i] * 2.0f - 1.0f);
        out[o++] = ew_smoothstep(0.0f, 0.5f, in[i]);
        out[o++] = ew_sigmoidf(in[i] * 20.0f - 10.0f);
        out[o++] = ew_nbg_tm(in[i] * 2.0f);
    }

    /* bilateral grid: splat every column, slice every pixel, through the
     * kernel bodies over their launch grids */
    ew_bgrid_params bp;
    bp.width = EW_PW;
    bp.height = EW_PH;
    bp.rate_s = 3.0f;
    bp.rate_d = 64.0f;
    bp.gw = 3;
    bp.gh = 3;
    bp.gd = 4;
    bp.channels = 3;
    bp.band_y = 0;
    bp.band_v = 0;
    float *image = scratch, *guide = scratch + 256, *grid = scratch + 512, *sliced = scratch + 1024;
    for (int i = 0; i < EW_PN * 3; i++) image[i] = in[100 + i] * 2.0f;
    for (int i = 0; i < EW_PN; i++) guide[i] = in[400 + i] * 255.0f;
    {
        const ew_launch l = ew_kl_bgrid_splat(&bp);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_bgrid_splat(&t, &bp, image, guide, grid))
    }
    {
        const ew_launch l = ew_kl_bgrid_slice(&bp);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_bgrid_slice(&t, &bp, grid, guide, sliced))
    }
    for (int i = 0; i < EW_PN * 3; i++) out[o++] = sliced[i];

    /* denoise steps */
    ew_denoise_buffers db;
    db.width = EW_PW;
    db.height = EW_PH;
    db.in_stride = 0;
    db.color = image;
    db.albedo = scratch + 2048;
    db.normal = scratch + 2304;
    db.depth = scratch + 2560;
    db.depth_scale = 0.25f;
    db.radiance = scratch + 2816;
    db.guide = scratch + 3072;
    db.sliced = sliced;
    db.out = scratch + 3328;
    for (int i = 0; i < EW_PN * 3; i++) {
        scratch[2048 + i] = in[700 + i];
        scratch[2304 + i] = in[900 + i] * 2.0f - 1.0f;
    }
    for (int i = 0; i < EW_PN; i++) scratch[2560 + i] = in[1100 + i] * 4.0f;
    for (long j = 0; j < EW_PN; j++) {
        ew_denoise_prepare_px(j, j, &db);
        ew_denoise_refine_guide_px(j, &db, 0.5f, 0.7f);
        ew_denoise_finish_px(j, j, &db);
    }
    for (int i = 0; i < EW_PN; i++) out[o++] = db.guide[i];
    for (int i = 0; i < EW_PN * 3; i++) out[o++] = db.out[i];

    /* firefly clamp and a-trous */
    float *clamped = scratch + 3584;
    for (int y = 0; y < EW_PH; y++)
        for (int x = 0; x < EW_PW; x++) {
            const ew_outlier_params fp = ew_outlier_plain_params(EW_PW, EW_PH, 2, 1.0f);
            const ew_outlier_buffers fb = {image, NULL, NULL, clamped, 3, NULL};
            ew_outlier_guided_px(x, y, &fp, &fb);
        }
    for (int i = 0; i < EW_PN * 3; i++) out[o++] = clamped[i];
    ew_atrous_args aa;
    aa.w = EW_PW;
    aa.h = EW_PH;
    aa.channels = 3;
    aa.step = 2;
    aa.in = image;
    aa.out = scratch + 3840;
    aa.normal = db.normal;
    aa.depth = db.depth;
    aa.sigma_l = 0.5f;
    aa.sigma_n = 0.5f;
    aa.sigma_z = 0.5f;
    {
        const ew_launch l = ew_kl_atrous(&aa);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_atrous(&t, &aa))
    }
    for (int i = 0; i < EW_PN * 3; i++) out[o++] = aa.out[i];

    /* joint bilateral, colour and GI models */
    float *attr = scratch + 4096, *bout = scratch + 4608;
    for (int i = 0; i < EW_PN * 5; i++) attr[i] = in[1200 + i];
    for (int kind = EW_RANGE_COLOR; kind <= EW_RANGE_GI; kind++) {
        ew_bf_model m;
        m.kind = kind;
        m.channels = 3;
        m.attrs = kind == EW_RANGE_GI ? 5 : 3;
        m.radius = 3;
        m.sigma = 1.5f;
        m.inv_2sr2 = 8.0f;
        m.sigma_alpha = 4.0f;
        m.sigma_n = 16.0f;
        m.sigma_z = 1.0f;
        m.use_roughness = 1;
        ew_bf_buffers bb;
        bb.width = EW_PW;
        bb.height = EW_PH;
        bb.image = image;
        bb.attr = attr;
        bb.out = bout;
        bb.y0 = 0;
        bb.y1 = EW_PH;
        const ew_launch l = ew_kl_bf_brute(&bb);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_bf_brute(&t, &m, &bb))
        for (int i = 0; i < EW_PN * 3; i++) out[o++] = bout[i];
        for (int y = 0; y < EW_PH; y++)
            for (int x = 0; x < EW_PW; x++) ew_bf_sep_px(x, y, 1, &m, &bb);
        for (int i = 0; i < EW_PN * 3; i++) out[o++] = bout[i];

        /* pyramid: one level down and back up */
        float *cdown = scratch + 5120, *cattr = scratch + 5376, *up = scratch + 5632;
        ew_pyr_down_args pd;
        pd.m = &m;
        pd.w = EW_PW;
        pd.h = EW_PH;
        pd.cw = (EW_PW + 1) / 2;
        pd.ch = (EW_PH + 1) / 2;
        pd.down = image;
        pd.attr = attr;
        pd.cdown = cdown;
        pd.cattr = cattr;
        pd.d2_unit = 1.0f;
        pd.major_attr = kind == EW_RANGE_GI;
        pd.cattr2 = scratch + 5888; /* duplicated coarse planes for the upsampling (kernels/pyramid.h) */
        pd.cdown2 = scratch + 6144;
        pd.fill = 0;
        pd.fill_user = 0;
        pd.fps = 0; /* the fine level whole */
        pd.fy0 = 0;
        pd.fbuf = 0;
        pd.fbuf_stride = 0;
        {
            const ew_launch l2 = ew_kl_pyr_down(&pd);
            EW_PROBE_FOR_THREADS(l2, t, ew_kb_pyr_down(&t, &pd, &m))
        }
        ew_pyr_wrow row;
        for (int k = 0; k < 9; k++) {
            row.wf[k] = k == 4 ? 0.5f : 0.05f;
            for (int p = 0; p < 4; p++) row.wdc[p][k] = 0.02f * (float)(k + p + 1);
        }
        row.gamma = 0.7f;
        ew_pyr_up_args pu;
        pu.m = &m;
        pu.w = EW_PW;
        pu.h = EW_PH;
        pu.cw = pd.cw;
        pu.ch = pd.ch;
        pu.down = image;
        pu.attr = attr;
        pu.cup = pd.cdown2;
        pu.cattr = pd.cattr2;
        pu.up = up;
        pu.ccoc = 0;
        pu.ucoc = 0;
        pu.dup_out = 0;
        pu.d2_unit = 1.0f;
        pu.coarse_d2 = 0.75f;
        pu.row = &row;
        pu.lut = 0;
        pu.drain = 0;
        pu.drain_user = 0;
        pu.up_y0 = 0; /* Up(0) a whole frame */
        pu.up_ps = 0;
        pu.band = 0;
        pu.band_stride = 0;
        pu.dps = 0; /* Down(0) whole */
        pu.dy0 = 0;
        pu.fill = 0;
        pu.fill_user = 0;
        pu.fbuf = 0;
        pu.fbuf_stride = 0;
        pu.fps = 0;
        pu.fedge = 0;
        pu.cps = 0; /* the coarse attributes whole */
        pu.cy0 = 0;
        pu.cattr_src = 0;
        pu.ccoc_src = 0;
        pu.cbuf = 0;
        pu.cbuf_stride = 0;
        {
            const ew_launch l2 = ew_kl_pyr_up(&pu);
            EW_PROBE_FOR_THREADS(l2, t, ew_kb_pyr_up(&t, &pu, &m, &row))
        }
        for (int i = 0; i < EW_PN * 3; i++) out[o++] = up[i];
    }

    /* depth of field */
    ew_dof_args da;
    memset(&da, 0, sizeof da); /* fields the probe does not set stay 0 (e.g. cam.scale) */
    da.cam.scale = 1.0f;
    da.cam.focal_mm = 50.0f;
    da.cam.fstop = 2.0f;
    da.cam.focus_m = 2.0f;
    da.cam.sensor_mm = 36.0f;
    da.cam.width = EW_PW;
    da.cam.height = EW_PH;
    da.cam.max_coc = 16.0f;
    da.tw = (EW_PW + EW_DOF_TILE - 1) / EW_DOF_TILE;
    da.th = (EW_PH + EW_DOF_TILE - 1) / EW_DOF_TILE;
    da.depth = db.depth;
    da.coc = scratch + 6144;
    da.tiles = scratch + 6400;
    da.tiles2 = scratch + 6464;
    da.attr = scratch + 6528;
    for (int step = 0; step < EW_DOF_STEPS; step++) {
        const ew_launch l = ew_kl_dof(&da, step);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_dof(&t, &da, step))
    }
    for (int i = 0; i < EW_PN * 2; i++) out[o++] = da.attr[i];

    /* temporal */
    ew_temporal_params tp;
    tp.width = EW_PW;
    tp.height = EW_PH;
    tp.alpha_min = 0.2f;
    tp.normal_cos = 0.5f;
    tp.depth_rel = 0.5f;
    tp.motion_sign = 1.0f;
    tp.max_frames = 8.0f;
    tp.clamp = 1.5f; /* the clamp path too (it contains the plain one) */
    ew_temporal_buffers tb;
    tb.color = image;
    tb.normal = db.normal;
    tb.depth = db.depth;
    tb.motion = scratch + 7000;
    for (int i = 0; i < EW_PN * 2; i++) scratch[7000 + i] = in[1600 + i] * 4.0f - 2.0f;
    tb.prev_color = sliced;
    tb.prev_normal = db.normal;
    tb.prev_depth = db.depth;
    tb.prev_len = scratch + 7200;
    for (int i = 0; i < EW_PN; i++) scratch[7200 + i] = in[1800 + i] * 5.0f;
    tb.out_color = scratch + 7400;
    tb.out_len = scratch + 7700;
    for (int y = 0; y < EW_PH; y++)
        for (int x = 0; x < EW_PW; x++) ew_temporal_px(x, y, &tp, &tb);
    for (int i = 0; i < EW_PN * 3; i++) out[o++] = tb.out_color[i];

    /* GuideNet: inputs, one convolution, the blend */
    float *planes = scratch + 8192; /* 10 planes of (EW_PH + 4) x (EW_PW + 4) */
    const long rs = EW_PW + 4, ps = (EW_PH + 4) * rs;
    ew_gn_input_args gi;
    gi.width = EW_PW;
    gi.y0 = 0;
    gi.y1 = EW_PH;
    gi.color = image;
    gi.albedo = db.albedo;
    gi.normal = db.normal;
    gi.depth = db.depth;
    gi.depth_scale = 0.25f;
    gi.in_stride = 0;
    gi.dst = planes + 2 * rs + 2;
    gi.rs = rs;
    gi.ps = ps;
    {
        const ew_launch l = ew_kl_gn_input(&gi);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_gn_input(&t, &gi))
    }
    float *weights = scratch + 10000, *conv_out = scratch + 12000;
    for (int i = 0; i < 2 * 10 * 25; i++) weights[i] = in[2000 + i] - 0.5f;
    ew_conv_args ca;
    ca.width = EW_PW;
    ca.rows = EW_PH;
    ca.cin = 10;
    ca.cout = 2;
    ca.in = planes + 2 * rs + 2;
    ca.in_rs = rs;
    ca.in_ps = ps;
    ca.out = conv_out;
    ca.out_rs = EW_PW;
    ca.out_ps = EW_PN;
    ca.weight = weights;
    ca.bias = 0;
    ca.act = EW_ACT_SIGMOID;
    ca.accumulate = 0;
    ca.winograd = 0;
    ca.grid_x = 0;
    ca.grid_y = 0;
    ca.reserved = 0;
    {
        const ew_launch l = ew_kl_conv5(&ca);
        EW_PROBE_FOR_THREADS(l, t, ew_kb_conv5(&t, &ca))
    }
    for (int i = 0; i < 2 * EW_PN; i++) out[o++] = conv_out[i];
    float w3[3];
    ew_nbg_weights(in[3000], in[3001], w3);
    out[o++] = w3[0];
    out[o++] = w3[1];
    out[o++] = w3[2];

    /* row reductions and strided views */
    double rows[2 * EW_PH];
    for (int y = 0; y < EW_PH; y++) ew_reduce_row(EW_REDUCE_LUM_SUM, y, EW_PW, image, rows);
    for (int y = 0; y < 2 * EW_PH; y++) out[o++] = (float)rows[y];
    ew_view_desc v;
    v.data = (char *)(scratch + 13000 + 4 * EW_PW * (EW_PH - 1));
    v.width = EW_PW;
    v.height = EW_PH;
    v.pixel_stride = 16;
    v.row_stride = -16 * EW_PW;
    v.half = 0;
    for (int y = 0; y < EW_PH; y++)
        for (int x = 0; x < EW_PW; x++) ew_view_unpack_px(x, y, &v, 3, image);
    float *packed = scratch + 14000;
    for (int y = 0; y < EW_PH; y++)
        for (int x = 0; x < EW_PW; x++) ew_view_pack_px(x, y, &v, 3, packed);
    for (int i = 0; i < EW_PN * 3; i++) out[o++] = packed[i] - image[i];
    return o;
}

#endif
