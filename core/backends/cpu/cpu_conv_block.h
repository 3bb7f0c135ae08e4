/*
 * cpu_conv_block.h — the SIMD body of the CPU convolutions, included
 * by cpu_conv.c once per instruction set with these macros defined:
 *   EW_V              vector type of EW_VW floats (8: AVX2 / portable, 16: AVX-512)
 *   EW_XB4, EW_XB5    vectors per register block for blocks of 4 (and fewer)
 *                     output channels and for the 5-channel layer
 *   EW_VLOAD(p)       unaligned load, EW_VSTORE(p, v) unaligned store
 *   EW_VSET1(f)       broadcast, EW_VZERO() zero
 *   EW_VFMA(a, b, c)  a * b + c
 *   EW_SUFFIX(name)   name mangled for the instruction set
 *   EW_NO_DWEIGHT     defined: leave out conv_dweight (AVX-512 runs forward
 *                     blocks only; the weight gradient keeps 8-float vectors)
 * Not a header to include anywhere else (no include guard on purpose).
 *
 * Every output value is the same chain of operations whatever the vector
 * width or blocking — bias (or the stored value), then one multiply-add per
 * input channel and tap in the same order — so the AVX2 and AVX-512 blocks
 * give the same bits (tests/unit/test_conv.c).
 *
 * Register blocking: CB output channels x XB vectors of 8 pixels of one row
 * are accumulated in registers over cin x 25 taps; each tap costs XB loads
 * and CB broadcasts for CB * XB fused multiply-adds (4 x 3: 7 loads for 12
 * FMAs, which keeps the FMA units, not the loads, the limit). The weights
 * are re-laid out per channel block as [cin][25][CB] so the broadcasts read
 * consecutive floats.
 */

#define EW_AI static inline __attribute__((always_inline))
#define EW_XB_MAX (EW_XB4 > EW_XB5 ? EW_XB4 : EW_XB5)

/* One block: CB channels (from co0) x XB vectors at pixel x0 of row r.
 * Lanes at or beyond `valid` are computed but never stored. */
EW_AI void EW_SUFFIX(conv_block)(const int CB, const int XB, const ew_conv_args *a, const float *wt, int co0, int r,
                                 int x0, int valid) {
    EW_V acc[5][EW_XB_MAX];
    float *out = a->out + (long)co0 * a->out_ps + (long)r * a->out_rs + x0;
    const int full = valid >= EW_VW * XB;
    for (int k = 0; k < CB; k++)
        for (int v = 0; v < XB; v++) {
            if (a->accumulate) {
                if (full) {
                    acc[k][v] = EW_VLOAD(out + k * a->out_ps + EW_VW * v);
                } else {
                    float t[EW_VW];
                    for (int i = 0; i < EW_VW; i++) t[i] = EW_VW * v + i < valid ? out[k * a->out_ps + EW_VW * v + i] : 0.0f;
                    acc[k][v] = EW_VLOAD(t);
                }
            } else {
                acc[k][v] = a->bias ? EW_VSET1(a->bias[co0 + k]) : EW_VZERO();
            }
        }
    const float *in = a->in + (long)(r - EW_CONV_R) * a->in_rs + x0 - EW_CONV_R;
    for (int ci = 0; ci < a->cin; ci++) {
        const float *ip = in + (long)ci * a->in_ps;
        const float *wp = wt + (long)ci * 25 * CB;
        for (int ky = 0; ky < 5; ky++) {
            const float *row = ip + (long)ky * a->in_rs;
            for (int kx = 0; kx < 5; kx++) {
                EW_V xv[EW_XB_MAX];
                for (int v = 0; v < XB; v++) xv[v] = EW_VLOAD(row + kx + EW_VW * v);
                const float *wk = wp + (ky * 5 + kx) * CB;
                for (int k = 0; k < CB; k++) {
                    EW_V w = EW_VSET1(wk[k]);
                    for (int v = 0; v < XB; v++) acc[k][v] = EW_VFMA(w, xv[v], acc[k][v]);
                }
            }
        }
    }
    for (int k = 0; k < CB; k++)
        for (int v = 0; v < XB; v++) {
            if (full) {
                EW_VSTORE(out + k * a->out_ps + EW_VW * v, acc[k][v]);
            } else {
                float t[EW_VW];
                EW_VSTORE(t, acc[k][v]);
                for (int i = 0; i < EW_VW && EW_VW * v + i < valid; i++) out[k * a->out_ps + EW_VW * v + i] = t[i];
            }
        }
}

/* Row r for the CB channels from co0: XB-wide blocks, then single vectors. */
EW_AI void EW_SUFFIX(conv_row_cb)(const int CB, const int XB, const ew_conv_args *a, const float *wt, int co0,
                                  int r) {
    int x = 0;
    for (; x + EW_VW * XB <= a->width; x += EW_VW * XB) EW_SUFFIX(conv_block)(CB, XB, a, wt, co0, r, x, EW_VW * XB);
    for (; x < a->width; x += EW_VW) EW_SUFFIX(conv_block)(CB, 1, a, wt, co0, r, x, a->width - x);
}

/* Rows [r0, r1): every channel block (the split ew_conv_cpu_wt_layout
 * used), then the activation. */
static void EW_SUFFIX(conv_rows)(const ew_conv_args *a, const float *wt, int r0, int r1) {
    for (int r = r0; r < r1; r++) {
        int co = 0;
        if (a->cout == 5) {
            EW_SUFFIX(conv_row_cb)(5, EW_XB5, a, wt, 0, r);
            co = 5;
        }
        for (; co + 4 <= a->cout; co += 4) EW_SUFFIX(conv_row_cb)(4, EW_XB4, a, wt + (long)co * a->cin * 25, co, r);
        switch (a->cout - co) {
        case 3: EW_SUFFIX(conv_row_cb)(3, EW_XB4, a, wt + (long)co * a->cin * 25, co, r); break;
        case 2: EW_SUFFIX(conv_row_cb)(2, EW_XB4, a, wt + (long)co * a->cin * 25, co, r); break;
        case 1: EW_SUFFIX(conv_row_cb)(1, EW_XB4, a, wt + (long)co * a->cin * 25, co, r); break;
        default: break;
        }
        if (!a->accumulate && a->act != EW_ACT_NONE)
            for (int c = 0; c < a->cout; c++) {
                float *o = a->out + (long)c * a->out_ps + (long)r * a->out_rs;
                for (int x = 0; x < a->width; x++) o[x] = ew_act(o[x], a->act);
            }
    }
}

#ifndef EW_NO_DWEIGHT
/*
 * dL/dW (added to dw, [cout][cin][25]) and dL/db (added to db) from the
 * gradient g w.r.t. the pre-activation output. g must be zero in its padding
 * columns (it is read in whole vectors up to the next multiple of 8).
 * Two output channels x five kx shifts = 10 accumulators; a tap's sum over
 * all pixels stays in one vector until the end, then the lanes are added in
 * a fixed order, so the result does not depend on anything but the data.
 */
static void EW_SUFFIX(conv_dweight)(const ew_conv_args *a, const float *g, long g_rs, long g_ps, float *dw,
                                    float *db) {
    const int nv = (a->width + 7) / 8;
    for (int co = 0; co < a->cout; co += 2) {
        const int pair = co + 1 < a->cout;
        for (int ci = 0; ci < a->cin; ci++)
            for (int ky = 0; ky < 5; ky++) {
                EW_V acc0[5], acc1[5];
                for (int kx = 0; kx < 5; kx++) acc0[kx] = acc1[kx] = EW_VZERO();
                for (int r = 0; r < a->rows; r++) {
                    const float *g0 = g + (long)co * g_ps + (long)r * g_rs;
                    const float *g1 = pair ? g0 + g_ps : g0;
                    const float *ir = a->in + (long)ci * a->in_ps + (long)(r + ky - EW_CONV_R) * a->in_rs - EW_CONV_R;
                    for (int v = 0; v < nv; v++) {
                        EW_V gv0 = EW_VLOAD(g0 + 8 * v), gv1 = EW_VLOAD(g1 + 8 * v);
                        for (int kx = 0; kx < 5; kx++) {
                            EW_V iv = EW_VLOAD(ir + 8 * v + kx);
                            acc0[kx] = EW_VFMA(gv0, iv, acc0[kx]);
                            acc1[kx] = EW_VFMA(gv1, iv, acc1[kx]);
                        }
                    }
                }
                for (int kx = 0; kx < 5; kx++) {
                    float t0[8], t1[8];
                    EW_VSTORE(t0, acc0[kx]);
                    EW_VSTORE(t1, acc1[kx]);
                    float s0 = ((t0[0] + t0[1]) + (t0[2] + t0[3])) + ((t0[4] + t0[5]) + (t0[6] + t0[7]));
                    float s1 = ((t1[0] + t1[1]) + (t1[2] + t1[3])) + ((t1[4] + t1[5]) + (t1[6] + t1[7]));
                    dw[((long)co * a->cin + ci) * 25 + ky * 5 + kx] += s0;
                    if (pair) dw[((long)(co + 1) * a->cin + ci) * 25 + ky * 5 + kx] += s1;
                }
            }
    }
    if (db)
        for (int co = 0; co < a->cout; co++) {
            EW_V acc = EW_VZERO(), one = EW_VSET1(1.0f);
            for (int r = 0; r < a->rows; r++)
                for (int v = 0; v < nv; v++) acc = EW_VFMA(one, EW_VLOAD(g + (long)co * g_ps + (long)r * g_rs + 8 * v), acc);
            float t[8];
            EW_VSTORE(t, acc);
            db[co] += ((t[0] + t[1]) + (t[2] + t[3])) + ((t[4] + t[5]) + (t[6] + t[7]));
        }
}

#endif /* EW_NO_DWEIGHT */

#undef EW_AI
#undef EW_XB_MAX
