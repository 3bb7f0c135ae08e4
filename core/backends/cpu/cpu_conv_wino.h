/*
 * cpu_conv_wino.h — the SIMD body of the CPU's Winograd F(4x4, 5x5)
 * convolution, included by cpu_conv.c once per instruction set (AVX2 + FMA,
 * AVX-512) after cpu_conv_block.h, with its macros and these:
 *   EW_VADD, EW_VSUB, EW_VMUL, EW_VMAX  lane-wise arithmetic
 *   EW_VTRANS4(a, b, c, d)  4x4 transpose within each 128-bit lane, in place
 *   EW_WXB, EW_WCB          the products' register block: EW_WCB output
 *                           channels x EW_WXB vectors of tiles
 * Not a header to include anywhere else (no include guard on purpose).
 *
 * An output tile of 4x4 pixels reads an 8x8 input tile (the tiles overlap
 * by 4); per channel pair it costs the 64 products of the transformed tile
 * and kernel instead of 400 multiply-adds:
 *   Y = At [ sum_ci (G g G^T) .* (Bt d B) ] A
 * with Bt (8x8), G (8x5), At (4x8) from tools/winograd_f4x5.py. The lanes
 * of a vector hold EW_VW tiles side by side; everything between the
 * gather and the store is lane-wise.
 *
 * A thread's item is a block of EW_WNT tiles of one tile row:
 *   1. the input transform of every input channel into V[64][cin][EW_WNT];
 *   2. per block of EW_WCB output channels, the 64 products
 *      M[xi] = U[xi] (cout x cin) . V[xi] (cin x EW_WNT) into M[64][EW_WCB][EW_WNT]
 *      (U from the weights once per call: [64][cin][cout]),
 *   3. and its output transform, bias, activation and store.
 * Scratch per thread: V, M and a staging area for the frame's edges.
 *
 * The lanes' tile order: the 8 inputs j of a tile row sit in 8 vectors,
 * gathered from rows of the input by a 4x4 transpose within 128-bit lanes
 * of 4 loads (j = 0..3) and of 4 loads 4 floats further (j = 4..7). Lane
 * 4q + p of them holds tile (EW_VW / 4) p + q of the group, not tile
 * 4q + p; the same transpose of the 4 output vectors of a row puts the
 * pixels back in order, and nothing in between mixes lanes.
 */

#define EW_AI static inline __attribute__((always_inline))
#define EW_WNT (EW_VW * EW_WXB)

/* Bt applied to the 8 vectors v[0], v[s], ..., v[7s] in place: the rows of
 * +p and -p share their even and odd halves (a + b, a - b). */
EW_AI void EW_SUFFIX(wino_in1d)(EW_V *v, const int s) {
    const EW_V d0 = v[0], d1 = v[s], d2 = v[2 * s], d3 = v[3 * s], d4 = v[4 * s], d5 = v[5 * s], d6 = v[6 * s],
               d7 = v[7 * s];
    const EW_V c525 = EW_VSET1(5.25f), cm425 = EW_VSET1(-4.25f), c05 = EW_VSET1(0.5f), cm25 = EW_VSET1(-2.5f),
               c2 = EW_VSET1(2.0f), c4 = EW_VSET1(4.0f), cm5 = EW_VSET1(-5.0f), c025 = EW_VSET1(0.25f),
               cm125 = EW_VSET1(-1.25f);
    v[0] = EW_VFMA(c525, EW_VSUB(d4, d2), EW_VSUB(d0, d6));
    v[7 * s] = EW_VFMA(c525, EW_VSUB(d3, d5), EW_VSUB(d7, d1));
    EW_V a = EW_VFMA(cm425, d4, EW_VADD(d2, d6)), b = EW_VFMA(cm425, d3, EW_VADD(d1, d5));
    v[s] = EW_VADD(a, b);
    v[2 * s] = EW_VSUB(a, b);
    a = EW_VFMA(c2, d6, EW_VFMA(cm25, d4, EW_VMUL(c05, d2)));
    b = EW_VFMA(c4, d5, EW_VFMA(cm5, d3, d1));
    v[3 * s] = EW_VADD(a, b);
    v[4 * s] = EW_VSUB(a, b);
    a = EW_VFMA(c05, d6, EW_VFMA(cm25, d4, EW_VMUL(c2, d2)));
    b = EW_VFMA(c025, d5, EW_VFMA(cm125, d3, d1));
    v[5 * s] = EW_VADD(a, b);
    v[6 * s] = EW_VSUB(a, b);
}

/* At applied to m[0], m[s], ..., m[7s] into y[0], y[t], y[2t], y[3t]. */
EW_AI void EW_SUFFIX(wino_out1d)(const EW_V *m, const int s, EW_V *y, const int t) {
    const EW_V s1 = EW_VADD(m[s], m[2 * s]), d1 = EW_VSUB(m[s], m[2 * s]);
    const EW_V s2 = EW_VADD(m[3 * s], m[4 * s]), d2 = EW_VSUB(m[3 * s], m[4 * s]);
    const EW_V s3 = EW_VADD(m[5 * s], m[6 * s]), d3 = EW_VSUB(m[5 * s], m[6 * s]);
    y[0] = EW_VADD(EW_VADD(m[0], s1), EW_VADD(s2, s3));
    y[t] = EW_VFMA(EW_VSET1(0.5f), d3, EW_VFMA(EW_VSET1(2.0f), d2, d1));
    y[2 * t] = EW_VFMA(EW_VSET1(0.25f), s3, EW_VFMA(EW_VSET1(4.0f), s2, s1));
    y[3 * t] = EW_VADD(EW_VFMA(EW_VSET1(0.125f), d3, EW_VFMA(EW_VSET1(8.0f), d2, d1)), m[7 * s]);
}

/* The input transform of EW_VW tiles of one channel, whose 8 input rows
 * start at rows[0..7] (each at the first tile's x - 2; 4 EW_VW + 4 floats
 * are read), into v[xi * vstride]. */
EW_AI void EW_SUFFIX(wino_in_group)(const float **rows, float *v, long vstride) {
    EW_V t[64];
    for (int y = 0; y < 8; y++) {
        const float *p = rows[y];
        EW_V a = EW_VLOAD(p), b = EW_VLOAD(p + EW_VW), c = EW_VLOAD(p + 2 * EW_VW), d = EW_VLOAD(p + 3 * EW_VW);
        EW_VTRANS4(a, b, c, d);
        EW_V e = EW_VLOAD(p + 4), f = EW_VLOAD(p + 4 + EW_VW), g = EW_VLOAD(p + 4 + 2 * EW_VW),
             h = EW_VLOAD(p + 4 + 3 * EW_VW);
        EW_VTRANS4(e, f, g, h);
        t[y * 8 + 0] = a;
        t[y * 8 + 1] = b;
        t[y * 8 + 2] = c;
        t[y * 8 + 3] = d;
        t[y * 8 + 4] = e;
        t[y * 8 + 5] = f;
        t[y * 8 + 6] = g;
        t[y * 8 + 7] = h;
        EW_SUFFIX(wino_in1d)(t + y * 8, 1);
    }
    for (int j = 0; j < 8; j++) {
        EW_SUFFIX(wino_in1d)(t + j, 8);
        for (int y = 0; y < 8; y++) EW_VSTORE(v + (long)(y * 8 + j) * vstride, t[y * 8 + j]);
    }
}

/* M[xi][k][.] = sum_ci U[xi][ci][co0 + k] V[xi][ci][.] for k < CB. */
EW_AI void EW_SUFFIX(wino_products)(const int CB, int cin, int cout, const float *u, const float *v, float *m,
                                    int co0) {
    for (int xi = 0; xi < 64; xi++) {
        EW_V acc[EW_WCB][EW_WXB];
        for (int k = 0; k < CB; k++)
            for (int x = 0; x < EW_WXB; x++) acc[k][x] = EW_VZERO();
        const float *vp = v + (long)xi * cin * EW_WNT, *up = u + (long)xi * cin * cout + co0;
        for (int ci = 0; ci < cin; ci++) {
            EW_V xv[EW_WXB];
            for (int x = 0; x < EW_WXB; x++) xv[x] = EW_VLOAD(vp + (long)ci * EW_WNT + EW_VW * x);
            for (int k = 0; k < CB; k++) {
                const EW_V w = EW_VSET1(up[(long)ci * cout + k]);
                for (int x = 0; x < EW_WXB; x++) acc[k][x] = EW_VFMA(w, xv[x], acc[k][x]);
            }
        }
        float *mp = m + (long)xi * EW_WCB * EW_WNT;
        for (int k = 0; k < CB; k++)
            for (int x = 0; x < EW_WXB; x++) EW_VSTORE(mp + k * EW_WNT + EW_VW * x, acc[k][x]);
    }
}

/* Output transform of channel co (k-th of the block in m) for the tiles of
 * the item from tile column tx0 on, tile row ty (tiles start at x = 4 tx - px,
 * r = 4 ty - py): bias, LeakyReLU, store the pixels inside the region. */
EW_AI void EW_SUFFIX(wino_out_channel)(const ew_conv_args *a, const float *m, int k, int co, int ty, int tx0, int px,
                                       int py) {
    const EW_V bias = a->bias ? EW_VSET1(a->bias[co]) : EW_VZERO(), slope = EW_VSET1(EW_LEAKY_SLOPE);
    const int leaky = a->act == EW_ACT_LEAKY;
    for (int g = 0; g < EW_WXB; g++) {
        const int x0 = 4 * (tx0 + EW_VW * g) - px;
        if (x0 >= a->width) break;
        EW_V mv[64], t[32], y[16];
        for (int xi = 0; xi < 64; xi++) mv[xi] = EW_VLOAD(m + ((long)xi * EW_WCB + k) * EW_WNT + EW_VW * g);
        for (int j = 0; j < 8; j++) EW_SUFFIX(wino_out1d)(mv + j, 8, t + j, 8);
        for (int i = 0; i < 4; i++) EW_SUFFIX(wino_out1d)(t + i * 8, 1, y + i * 4, 1);
        for (int i = 0; i < 4; i++) {
            const int r = 4 * ty - py + i;
            if (r < 0) continue;
            if (r >= a->rows) break;
            EW_V o[4];
            for (int j = 0; j < 4; j++) {
                o[j] = EW_VADD(y[i * 4 + j], bias);
                if (leaky) o[j] = EW_VMAX(o[j], EW_VMUL(slope, o[j]));
            }
            EW_VTRANS4(o[0], o[1], o[2], o[3]);
            float *out = a->out + (long)co * a->out_ps + (long)r * a->out_rs + x0;
            if (x0 >= 0 && x0 + 4 * EW_VW <= a->width) {
                for (int p = 0; p < 4; p++) EW_VSTORE(out + EW_VW * p, o[p]);
            } else {
                float tmp[4 * EW_VW];
                for (int p = 0; p < 4; p++) EW_VSTORE(tmp + EW_VW * p, o[p]);
                for (int x = x0 < 0 ? -x0 : 0; x < 4 * EW_VW && x0 + x < a->width; x++) out[x] = tmp[x];
            }
        }
    }
}

/* One item: the tiles [tx0, tx0 + EW_WNT) of tile row ty, the grid's phase
 * (px, py) = (grid_x, grid_y) mod 4. scratch: V (64 cin EW_WNT floats), M
 * (64 EW_WCB EW_WNT) and the staging rows (9 (4 EW_VW + 4), the last one
 * zero). */
static void EW_SUFFIX(wino_item)(const ew_conv_args *a, const float *u, int ty, int tx0, int px, int py,
                                 float *scratch) {
    const int cin = a->cin, cout = a->cout, SW = 4 * EW_VW + 4;
    float *v = scratch, *m = v + (long)64 * cin * EW_WNT, *stage = m + (long)64 * EW_WCB * EW_WNT;
    const float *zero = stage + 8 * SW;
    /* 1. input transform; taps read the region and its 2 rows and columns
     * of padding, anything further is zero (it reaches only outputs outside
     * the region, which are not stored) */
    for (int g = 0; g < EW_WXB; g++) {
        const int xs = 4 * (tx0 + EW_VW * g) - px - EW_CONV_R; /* first input column of the group */
        const int inside = xs >= -EW_CONV_R && xs + SW <= a->width + EW_CONV_R;
        for (int ci = 0; ci < cin; ci++) {
            const float *rows[8];
            for (int y = 0; y < 8; y++) {
                const int r = 4 * ty - py - EW_CONV_R + y;
                const float *src = a->in + (long)ci * a->in_ps + (long)r * a->in_rs + xs;
                if (r < -EW_CONV_R || r >= a->rows + EW_CONV_R || xs >= a->width + EW_CONV_R) {
                    rows[y] = zero;
                } else if (inside) {
                    rows[y] = src;
                } else {
                    float *st = stage + y * SW;
                    for (int x = 0; x < SW; x++)
                        st[x] = xs + x >= -EW_CONV_R && xs + x < a->width + EW_CONV_R ? src[x] : 0.0f;
                    rows[y] = st;
                }
            }
            EW_SUFFIX(wino_in_group)(rows, v + (long)ci * EW_WNT + EW_VW * g, (long)cin * EW_WNT);
        }
    }
    /* 2. and 3., per block of output channels */
    for (int co = 0; co < cout; co += EW_WCB) {
        const int cb = cout - co < EW_WCB ? cout - co : EW_WCB;
        switch (cb) {
#define EW_WINO_CASE(n)                                                                                              \
    case n: EW_SUFFIX(wino_products)(n, cin, cout, u, v, m, co); break;
            EW_WINO_CASE(1)
            EW_WINO_CASE(2)
            EW_WINO_CASE(3)
            EW_WINO_CASE(4)
#if EW_WCB > 4
            EW_WINO_CASE(5)
            EW_WINO_CASE(6)
            EW_WINO_CASE(7)
            EW_WINO_CASE(8)
#endif
#undef EW_WINO_CASE
        default: break;
        }
        for (int k = 0; k < cb; k++) EW_SUFFIX(wino_out_channel)(a, m, k, co + k, ty, tx0, px, py);
    }
    /* activations other than LeakyReLU, on the stored values */
    if (a->act != EW_ACT_NONE && a->act != EW_ACT_LEAKY) {
        const int x0 = 4 * tx0 - px > 0 ? 4 * tx0 - px : 0;
        const int x1 = 4 * (tx0 + EW_WNT) - px < a->width ? 4 * (tx0 + EW_WNT) - px : a->width;
        for (int c = 0; c < cout; c++)
            for (int i = 0; i < 4; i++) {
                const int r = 4 * ty - py + i;
                if (r < 0 || r >= a->rows) continue;
                float *o = a->out + (long)c * a->out_ps + (long)r * a->out_rs;
                for (int x = x0; x < x1; x++) o[x] = ew_act(o[x], a->act);
            }
    }
}

#undef EW_AI
#undef EW_WNT
