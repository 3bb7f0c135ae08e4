/* The pyramid filter against a slow reference written straight from the
 * paper (Eq. 2, 2a-2g, 3) in double precision: major pixel by argmax, every
 * weight term computed separately as the paper names it. Then the properties
 * the issue lists: range == 1 gives the convolution model, step edges hold,
 * constants stay, odd sizes, radius 0 and beyond the image, NaN/Inf; and the
 * weights file. */
#include "ew_test.h"

#include <malloc.h>
#include <stdlib.h>

#include "algorithms/bilateral.h"
#include "algorithms/pyramid.h"
#include "src/backend.h"
#include "src/op.h"
#include "src/weights.h"

static float urand(unsigned *s) {
    *s = *s * 1664525u + 1013904223u;
    return (float)((*s >> 8) & 0xffffff) / 16777216.0f;
}

static ew_device *make_device(int threads) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = threads;
    ew_device *dev = NULL;
    return ew_device_create(&desc, &dev) == EW_OK ? dev : NULL;
}

/* ---- reference ---- */
/* Values are (r M, g M, b M, M) (see kernels/bilateral.h); samples beyond
 * the border are (0, 0, 0, 0) with range value 1. */
typedef struct {
    int w, h;
    double *down, *attr, *up, *coc; /* coc: DOF content CoC of up */
} rlevel;

static double rrange(const ew_bf_model *m, const double *p, const double *q, double d2) {
    float pf[EW_BF_MAX_ATTR], qf[EW_BF_MAX_ATTR];
    for (int k = 0; k < m->attrs; k++) {
        pf[k] = (float)p[k];
        qf[k] = (float)q[k];
    }
    /* the range functions themselves are tested against libm in
     * test_bilateral; here the pyramid's structure is under test */
    return ew_bf_range(m, pf, qf, (float)d2);
}

static double rsigma(const ew_bf_model *m, const double *a) {
    float f[EW_BF_MAX_ATTR];
    for (int k = 0; k < m->attrs; k++) f[k] = (float)a[k];
    return ew_bf_sigma(m, f);
}

/* Eq. 3, with the major pixel m = argmax_q f(mean A, A(q)) */
static void ref_down(const ew_bf_model *m, int l, const rlevel *f, rlevel *c, int major_attr) {
    const int C = EW_BF_CH, A = m->attrs;
    for (int y = 0; y < c->h; y++)
        for (int x = 0; x < c->w; x++) {
            int qs[4][2], n = 0;
            for (int iy = 0; iy < 2; iy++)
                for (int ix = 0; ix < 2; ix++)
                    if (2 * x + ix < f->w && 2 * y + iy < f->h) {
                        qs[n][0] = 2 * x + ix;
                        qs[n][1] = 2 * y + iy;
                        n++;
                    }
            /* the mean in float, summed in the kernel's order: the argmax
             * must not flip on a near tie between float and double */
            double mean[EW_BF_MAX_ATTR] = {0};
            for (int k = 0; k < A; k++) {
                float sum = 0.0f;
                for (int q = 0; q < n; q++) sum += (float)f->attr[((long)qs[q][1] * f->w + qs[q][0]) * A + k];
                mean[k] = sum / (float)n;
            }
            int mj = 0;
            double best = -1;
            for (int q = 0; q < n && m->kind != EW_RANGE_NONE; q++) {
                double v = rrange(m, mean, f->attr + ((long)qs[q][1] * f->w + qs[q][0]) * A, 0.5 * pow(4, l));
                if (v > best) {
                    best = v;
                    mj = q;
                }
            }
            const double *am = f->attr + ((long)qs[mj][1] * f->w + qs[mj][0]) * A;
            double num[EW_BF_CH] = {0}, den = 4 - n, anum[EW_BF_MAX_ATTR] = {0}, aden = 0;
            for (int q = 0; q < n; q++) {
                long i = (long)qs[q][1] * f->w + qs[q][0];
                double dx = qs[q][0] - qs[mj][0], dy = qs[q][1] - qs[mj][1];
                double fr = q == mj ? 1.0 : rrange(m, am, f->attr + i * A, (dx * dx + dy * dy) * pow(4, l));
                for (int k = 0; k < A; k++) anum[k] += fr * f->attr[i * A + k];
                aden += fr;
                for (int k = 0; k < C; k++) num[k] += fr * f->down[i * C + k];
                den += fr;
            }
            long j = (long)y * c->w + x;
            for (int k = 0; k < C; k++) c->down[j * C + k] = num[k] / den;
            for (int k = 0; k < A; k++) c->attr[j * A + k] = major_attr ? am[k] : anum[k] / aden;
        }
}

/* Eq. 2 with 2a-2g, term by term */
static void ref_up(const ew_bf_model *m, int l, rlevel *f, const rlevel *c, const ew_pyr_table *table, float agamma,
                   int uniform, int coarsest) {
    const int C = EW_BF_CH, A = m->attrs, dof = m->kind == EW_RANGE_DOF;
    for (int y = 0; y < f->h; y++)
        for (int x = 0; x < f->w; x++) {
            const double *ap = f->attr + ((long)y * f->w + x) * A;
            ew_pyr_params prm;
            if (uniform) {
                ew_pyr_params_at(table, m->sigma, l, agamma, &prm);
            } else {
                /* per-pixel sigma: the documented table over log2(sigma),
                 * EW_PYR_LUT_STEPS per octave, linearly interpolated */
                double t = (log2(fmax(rsigma(m, ap), 1e-6)) - EW_PYR_LUT_LOG2_MIN) * EW_PYR_LUT_STEPS;
                t = fmin(fmax(t, 0.0), EW_PYR_LUT_N - 1.0);
                int i0 = (int)t, i1 = i0 + 1 < EW_PYR_LUT_N ? i0 + 1 : i0;
                ew_pyr_params p0, p1;
                ew_pyr_params_at(table, exp2f((float)EW_PYR_LUT_LOG2_MIN + (float)i0 / EW_PYR_LUT_STEPS), l, agamma, &p0);
                ew_pyr_params_at(table, exp2f((float)EW_PYR_LUT_LOG2_MIN + (float)i1 / EW_PYR_LUT_STEPS), l, agamma, &p1);
                p0.wf[4] = ew_pyr_centre_weight(&p0);
                p1.wf[4] = ew_pyr_centre_weight(&p1);
                const float *a0 = (const float *)&p0, *a1 = (const float *)&p1;
                float *o = (float *)&prm;
                for (int k = 0; k < EW_PYR_NPARAM; k++) o[k] = (float)((1 - (t - i0)) * a0[k] + (t - i0) * a1[k]);
            }
            if (uniform) prm.wf[4] = ew_pyr_centre_weight(&prm); /* Eq. 2g (interpolated rows keep it) */
            double fc[3][3], wb[3][3], ff[3][3], sff = 0, comp = 0, cocv[3][3], cocf[3][3];
            int cin[3][3], fin[3][3];
            for (int iy = -1; iy <= 1; iy++)
                for (int ix = -1; ix <= 1; ix++) {
                    int qx = x / 2 + ix, qy = y / 2 + iy;
                    int in = qx >= 0 && qy >= 0 && qx < c->w && qy < c->h;
                    cin[iy + 1][ix + 1] = in;
                    int dx = abs(4 * ix - 2 * (x % 2) + 1), dy = abs(4 * iy - 2 * (y % 2) + 1);
                    double wd = (17.0 - 3 * dx) / 24.0 * (17.0 - 3 * dy) / 24.0; /* 2f */
                    double wc = prm.wc[(dy / 2) * 3 + dx / 2];
                    double aq[EW_BF_MAX_ATTR] = {0};
                    cocv[iy + 1][ix + 1] = 0;
                    if (in) {
                        long qi = (long)qy * c->w + qx;
                        for (int k = 0; k < A; k++) aq[k] = c->attr[qi * A + k];
                        /* DOF: the CoC of the content */
                        if (dof) aq[1] = cocv[iy + 1][ix + 1] = coarsest ? c->attr[qi * A + 1] : c->coc[qi];
                    }
                    fc[iy + 1][ix + 1] = in ? rrange(m, ap, aq, (pow(4, l + 1) - 1) / 4) : 1.0;
                    wb[iy + 1][ix + 1] = wd * fc[iy + 1][ix + 1] * wc; /* 2e */
                    comp += wb[iy + 1][ix + 1] * (1 - pow(fc[iy + 1][ix + 1], prm.gamma));
                    int fx = x + ix, fy = y + iy;
                    fin[iy + 1][ix + 1] = fx >= 0 && fy >= 0 && fx < f->w && fy < f->h;
                    cocf[iy + 1][ix + 1] = fin[iy + 1][ix + 1] && dof ? f->attr[((long)fy * f->w + fx) * A + 1] : 0;
                    ff[iy + 1][ix + 1] = !fin[iy + 1][ix + 1] || (ix == 0 && iy == 0)
                                             ? 1
                                             : rrange(m, ap, f->attr + ((long)fy * f->w + fx) * A,
                                                      (ix * ix + iy * iy) * pow(4, l));
                    sff += ff[iy + 1][ix + 1];
                }
            double num[EW_BF_CH] = {0}, den = 0, cn = 0, cw = 0;
            for (int iy = 0; iy < 3; iy++)
                for (int ix = 0; ix < 3; ix++) {
                    double wcv = wb[iy][ix] * pow(fc[iy][ix], prm.gamma); /* 2c */
                    if (cin[iy][ix]) {
                        const double *v = c->up + ((long)(y / 2 + iy - 1) * c->w + (x / 2 + ix - 1)) * C;
                        for (int k = 0; k < C; k++) num[k] += wcv * v[k];
                        cn += wcv * cocv[iy][ix];
                        cw += wcv;
                    }
                    den += wcv;
                    double wfr = comp * ff[iy][ix] / sff;                 /* 2d */
                    double wf = prm.wf[iy * 3 + ix] * ff[iy][ix] + wfr; /* 2b */
                    if (fin[iy][ix]) {
                        const double *v = f->down + ((long)(y + iy - 1) * f->w + (x + ix - 1)) * C;
                        for (int k = 0; k < C; k++) num[k] += wf * v[k];
                        cn += wf * cocf[iy][ix];
                        cw += wf;
                    }
                    den += wf;
                }
            long j = (long)y * f->w + x;
            for (int k = 0; k < C; k++) f->up[j * C + k] = den > 0 ? num[k] / den : f->down[j * C + k]; /* 2a */
            if (dof) f->coc[j] = cw > 0 ? cn / cw : f->attr[j * A + 1];
        }
}

static void ref_pyramid(const ew_bf_model *m, int w, int h, int levels, const float *img, const float *attr,
                        const ew_pyr_table *table, float agamma, int uniform, double *out) {
    rlevel L[EW_PYR_MAX_LEVELS + 1];
    const int C = EW_BF_CH, A = m->attrs;
    for (int l = 0; l <= levels; l++) {
        L[l].w = l ? (L[l - 1].w + 1) / 2 : w;
        L[l].h = l ? (L[l - 1].h + 1) / 2 : h;
        long n = (long)L[l].w * L[l].h;
        L[l].down = malloc(sizeof(double) * n * C);
        L[l].up = malloc(sizeof(double) * n * C);
        L[l].attr = malloc(sizeof(double) * (n * A + 1));
        L[l].coc = malloc(sizeof(double) * n);
    }
    for (long i = 0; i < (long)w * h * C; i++) L[0].down[i] = img[i];
    for (long i = 0; i < (long)w * h * A; i++) L[0].attr[i] = attr[i];
    for (int l = 0; l < levels; l++) {
        ref_down(m, l, &L[l], &L[l + 1], m->kind == EW_RANGE_GI);
        /* attributes are stored as float, as the library does */
        for (long i = 0; i < (long)L[l + 1].w * L[l + 1].h * A; i++) L[l + 1].attr[i] = (float)L[l + 1].attr[i];
    }
    memcpy(L[levels].up, L[levels].down, sizeof(double) * L[levels].w * L[levels].h * C);
    for (int l = levels - 1; l >= 0; l--) ref_up(m, l, &L[l], &L[l + 1], table, agamma, uniform, l + 1 == levels);
    memcpy(out, L[0].up, sizeof(double) * w * h * C);
    for (int l = 0; l <= levels; l++) {
        free(L[l].down);
        free(L[l].up);
        free(L[l].attr);
        free(L[l].coc);
    }
}

/* a random table whose nodes lie on the kernel's log2(sigma) grid, so the
 * per-pixel table and the reference interpolate the same way */
static void random_table(ew_pyr_table *t, unsigned *s) {
    memset(t, 0, sizeof *t);
    t->nodes = 4;
    t->levels = 4;
    const float nodes[4] = {-1.0f, 0.5f, 1.25f, 2.5f};
    for (int i = 0; i < 4; i++) {
        t->log2_sigma[i] = nodes[i];
        for (int l = 0; l < 4; l++) {
            ew_pyr_params *q = &t->p[i][l];
            for (int k = 0; k < 9; k++) {
                q->wf[k] = 0.08f * urand(s);
                q->wc[k] = 0.6f * urand(s);
            }
            q->gamma = 0.3f + 1.5f * urand(s);
            q->wf[4] = ew_pyr_centre_weight(q);
        }
    }
}

/* DOF: D constant over runs of 1 to 48 pixels along each row (random_attrs
 * when set; the CPU backend's run path, see cpu_filters.c) */
static int g_dof_runs_w;

static void random_attrs(const ew_bf_model *m, long n, float *attr, unsigned *s) {
    for (long i = 0; i < n; i++) {
        float *a = attr + i * m->attrs;
        switch (m->kind) {
        case EW_RANGE_COLOR:
            for (int k = 0; k < m->attrs; k++) a[k] = urand(s);
            break;
        case EW_RANGE_GI: {
            float x = urand(s) - 0.5f, y = urand(s) - 0.5f, z = 0.6f + urand(s), l = sqrtf(x * x + y * y + z * z);
            a[0] = x / l;
            a[1] = y / l;
            a[2] = z / l;
            a[3] = 1.0f + urand(s);
            a[4] = urand(s);
            break;
        }
        case EW_RANGE_DEPTH: a[0] = 1.0f + urand(s); break;
        case EW_RANGE_DOF:
            a[1] = 14.0f * urand(s) * urand(s);
            a[0] = urand(s) < 0.3f ? a[1] + 6.0f * urand(s) : a[1];
            break;
        default: break;
        }
    }
    if (m->kind == EW_RANGE_DOF && g_dof_runs_w > 0) { /* D >= C still holds: a run takes its largest D */
        const int A = m->attrs;
        for (long i = 0; i < n;) {
            const long x = i % g_dof_runs_w, len = 1 + (long)(47.0f * urand(s) * urand(s));
            long e = i + len;
            if (e > i - x + g_dof_runs_w) e = i - x + g_dof_runs_w; /* runs stay in their row */
            float d = 0.0f;
            for (long k = i; k < e; k++) d = fmaxf(d, attr[k * A]);
            for (long k = i; k < e; k++) attr[k * A] = d;
            i = e;
        }
    }
}

static ew_bf_model model_of(int kind, int C, float sigma) {
    ew_bf_model m;
    memset(&m, 0, sizeof m);
    m.kind = kind;
    m.channels = C;
    m.sigma = sigma;
    m.radius = (int)ceilf(3 * sigma);
    m.inv_2sr2 = 1.0f / (2 * 0.3f * 0.3f);
    m.sigma_alpha = 3.0f * sigma - 1.0f;
    m.sigma_n = 8;
    m.sigma_z = 0.7f;
    m.use_roughness = 1;
    m.attrs = ew_bf_attrs(kind);
    return m;
}

/* run the library's pyramid; returns malloc'd output */
static float *run_pyr(ew_device *dev, const ew_bf_model *m, int w, int h, int levels, int uniform,
                      const ew_pyr_table *t, float agamma, const float *img, const float *attr) {
    size_t sc = ew_pyr_scratch_floats(m, w, h, levels, uniform);
    float *scratch = malloc(sizeof(float) * (sc + 1)), *out = malloc(sizeof(float) * w * h * EW_BF_CH);
    ew_pyr_plan p;
    ew_pyr_plan_init(&p, m, w, h, levels, uniform, t, agamma, scratch);
    ew_pyr_run(dev, &p, img, attr, out, NULL, NULL);
    free(scratch);
    return out;
}

static int check_against_reference(int kind, int C, int w, int h, float sigma, int use_table, unsigned seed) {
    ew_bf_model m = model_of(kind, C, sigma);
    const int uniform = kind != EW_RANGE_GI && kind != EW_RANGE_DOF;
    const long n = (long)w * h;
    float *img = malloc(sizeof(float) * n * C), *attr = malloc(sizeof(float) * (n * EW_BF_MAX_ATTR + 8));
    for (long i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++) img[i * C + c] = 3.0f * urand(&seed);
        img[i * C + 3] = 1.0f;
    }
    for (int c = 0; c < C; c++) img[(n / 3) * C + c] = 0.0f; /* a missing sample */
    random_attrs(&m, n, attr, &seed);
    ew_pyr_table t;
    random_table(&t, &seed);
    const ew_pyr_table *tp = use_table ? &t : NULL;
    int levels = 3;
    double *ref = malloc(sizeof(double) * n * C);
    ref_pyramid(&m, w, h, levels, img, attr, tp, 1.0f, uniform, ref);
    ew_device *dev = make_device(3);
    float *out = run_pyr(dev, &m, w, h, levels, uniform, tp, 1.0f, img, attr);
    int ok = 1;
    double worst = 0;
    for (long i = 0; i < n * C; i++) {
        if (isnan(out[i]) && isnan(ref[i])) continue; /* both: nothing valid in reach */
        double e = fabs(out[i] - ref[i]);
        if (!(e <= 1e-4 * (1 + fabs(ref[i])))) ok = 0;
        if (e > worst || isnan(e)) {
            worst = isnan(e) ? INFINITY : e;
            if (getenv("EW_DEBUG")) fprintf(stderr, "   at %ld (x %ld y %ld c %ld): %g vs %g\n", i, (i / C) % w, (i / C) / w, i % C, out[i], ref[i]);
        }
    }
    if (!ok) fprintf(stderr, "  kind %d table %d: pyramid differs from Eq. 2-3 by %g\n", kind, use_table, worst);
    ew_device_destroy(dev);
    free(img); free(attr); free(ref); free(out);
    return ok;
}

/* Sizes are multiples of 2^levels here: a block with two children (odd
 * sizes) has an exact tie for the major pixel under a symmetric range
 * function, which float rounding breaks either way. Odd sizes are covered
 * by the property tests below. */
TEST(matches_eq2_eq3_color_analytic) { CHECK(check_against_reference(EW_RANGE_COLOR, EW_BF_CH, 24, 16, 2.0f, 0, 1)); }
TEST(matches_eq2_eq3_color_trained) { CHECK(check_against_reference(EW_RANGE_COLOR, EW_BF_CH, 16, 24, 1.5f, 1, 2)); }
TEST(matches_eq2_eq3_depth_trained) { CHECK(check_against_reference(EW_RANGE_DEPTH, EW_BF_CH, 24, 24, 2.0f, 1, 3)); }
TEST(matches_eq2_eq3_gi_per_pixel_sigma) { CHECK(check_against_reference(EW_RANGE_GI, EW_BF_CH, 16, 16, 1.5f, 1, 4)); }
TEST(matches_eq2_eq3_dof_per_pixel_sigma) { CHECK(check_against_reference(EW_RANGE_DOF, EW_BF_CH, 32, 16, 2.0f, 1, 5)); }
/* wide rows: the CPU backend's vectorised interior span with DOF's per-pixel
 * table lookup (gathers) runs many full vectors, against the same reference */
TEST(matches_eq2_eq3_dof_per_pixel_sigma_wide) { CHECK(check_against_reference(EW_RANGE_DOF, EW_BF_CH, 72, 24, 2.5f, 1, 8)); }
/* rows of runs of equal D, short and long: the CPU backend's run path (one
 * table row per run, the uniform variant) next to the lookup per pixel */
TEST(matches_eq2_eq3_dof_runs_of_equal_d) {
    g_dof_runs_w = 96;
    const int ok = check_against_reference(EW_RANGE_DOF, EW_BF_CH, 96, 24, 2.5f, 1, 9);
    g_dof_runs_w = 0;
    CHECK(ok);
}
TEST(matches_eq2_eq3_dof_analytic) { CHECK(check_against_reference(EW_RANGE_DOF, EW_BF_CH, 16, 16, 2.0f, 0, 6)); }
TEST(matches_eq2_eq3_gaussian_odd_size) { CHECK(check_against_reference(EW_RANGE_NONE, EW_BF_CH, 23, 17, 1.7f, 1, 7)); }

/* The convolution-approximation model: with every range function 1 the
 * pipeline is linear: box 2x2 down, Up = sum wf Down + sum w_d wc Up_c. */
static void conv_model(const ew_pyr_table *t, float sigma, int w, int h, int levels, const float *img, double *out) {
    double *down[8], *up[8];
    int W[8], H[8];
    W[0] = w;
    H[0] = h;
    down[0] = malloc(sizeof(double) * w * h);
    for (long i = 0; i < (long)w * h; i++) down[0][i] = img[i];
    for (int l = 1; l <= levels; l++) {
        W[l] = (W[l - 1] + 1) / 2;
        H[l] = (H[l - 1] + 1) / 2;
        down[l] = malloc(sizeof(double) * W[l] * H[l]);
        for (int y = 0; y < H[l]; y++)
            for (int x = 0; x < W[l]; x++) {
                double s = 0;
                int n = 0;
                for (int k = 0; k < 4; k++) {
                    int fx = 2 * x + (k & 1), fy = 2 * y + (k >> 1);
                    if (fx < W[l - 1] && fy < H[l - 1]) {
                        s += down[l - 1][fy * W[l - 1] + fx];
                        n++;
                    }
                }
                (void)n;
                down[l][y * W[l] + x] = s / 4; /* zero padding beyond the border */
            }
    }
    up[levels] = down[levels];
    for (int l = levels - 1; l >= 0; l--) {
        ew_pyr_params p;
        ew_pyr_params_at(t, sigma, l, 1.0f, &p);
        p.wf[4] = ew_pyr_centre_weight(&p);
        up[l] = malloc(sizeof(double) * W[l] * H[l]);
        for (int y = 0; y < H[l]; y++)
            for (int x = 0; x < W[l]; x++) {
                double s = 0, ws = 0;
                for (int iy = -1; iy <= 1; iy++)
                    for (int ix = -1; ix <= 1; ix++) {
                        int fx = x + ix, fy = y + iy, cx = x / 2 + ix, cy = y / 2 + iy;
                        /* zero padding: samples beyond the border add weight, not value */
                        if (fx >= 0 && fy >= 0 && fx < W[l] && fy < H[l])
                            s += p.wf[(iy + 1) * 3 + ix + 1] * down[l][fy * W[l] + fx];
                        ws += p.wf[(iy + 1) * 3 + ix + 1];
                        int dx = abs(4 * ix - 2 * (x % 2) + 1), dy = abs(4 * iy - 2 * (y % 2) + 1);
                        double wgt = (17.0 - 3 * dx) / 24 * (17.0 - 3 * dy) / 24 * p.wc[(dy / 2) * 3 + dx / 2];
                        if (cx >= 0 && cy >= 0 && cx < W[l + 1] && cy < H[l + 1]) s += wgt * up[l + 1][cy * W[l + 1] + cx];
                        ws += wgt;
                    }
                up[l][y * W[l] + x] = s / ws;
            }
    }
    memcpy(out, up[0], sizeof(double) * w * h);
    for (int l = 0; l <= levels; l++) {
        free(down[l]);
        if (l < levels) free(up[l]);
    }
}

TEST(range_one_equals_convolution_model) {
    const int w = 37, h = 29;
    unsigned s = 21;
    float img[37 * 29];
    for (int i = 0; i < w * h; i++) img[i] = urand(&s);
    ew_pyr_table t;
    random_table(&t, &s);
    ew_device *dev = make_device(2);
    float ones[37 * 29];
    for (int i = 0; i < w * h; i++) ones[i] = 1.0f;
    for (int trained = 0; trained < 2; trained++) {
        const ew_pyr_table *tp = trained ? &t : NULL;
        double ref[37 * 29], mask[37 * 29];
        conv_model(tp, 2.2f, w, h, 4, img, ref);
        conv_model(tp, 2.2f, w, h, 4, ones, mask); /* normalized convolution: the mask */
        for (int i = 0; i < w * h; i++) ref[i] /= mask[i];
        /* no range function at all (buffers hold EW_BF_CH floats a pixel) */
        float img4[37 * 29 * EW_BF_CH] = {0};
        for (int i = 0; i < w * h; i++) {
            img4[i * EW_BF_CH] = img[i];
            img4[i * EW_BF_CH + 3] = 1.0f;
        }
        ew_bf_model none = model_of(EW_RANGE_NONE, 1, 2.2f);
        float *o = run_pyr(dev, &none, w, h, 4, 1, tp, 1.0f, img4, img4);
        for (int i = 0; i < w * h; i++) CHECK_NEAR(o[i * EW_BF_CH] / o[i * EW_BF_CH + 3], ref[i], 1e-5);
        free(o);
        /* a colour range function so wide it is 1 everywhere */
        ew_bf_model wide = model_of(EW_RANGE_COLOR, 1, 2.2f);
        wide.inv_2sr2 = 0.0f;
        o = run_pyr(dev, &wide, w, h, 4, 1, tp, 1.0f, img4, img4);
        for (int i = 0; i < w * h; i++) CHECK_NEAR(o[i * EW_BF_CH] / o[i * EW_BF_CH + 3], ref[i], 1e-5);
        free(o);
    }
    ew_device_destroy(dev);
}

/* Packing inside the first pass and unpacking inside the last (ew_pyr_io,
 * the filter ops' way) gives bit for bit what packing, running and
 * unpacking one after the other gives: odd heights (the last coarse row
 * fills one fine row), colour's shared fine values (drained per row, and
 * after the last column segment on rows wider than the segments), DoF's
 * table, 1 and 3 threads. */
TEST(packing_inside_the_passes_equals_packing_around_them) {
    const int sizes[][2] = {{61, 37}, {4133, 7}};
    for (int si = 0; si < 2; si++)
        for (int kind = 0; kind < 2; kind++)
            for (int threads = 1; threads <= 3; threads += 2) {
                const int w = sizes[si][0], h = sizes[si][1], C = 3;
                const long n = (long)w * h;
                ew_bf_model m = model_of(kind ? EW_RANGE_DOF : EW_RANGE_COLOR, C, 3.0f);
                const int uniform = !kind;
                unsigned seed = 77u + (unsigned)(si * 4 + kind);
                float *rgb = malloc(sizeof(float) * n * C), *attr = malloc(sizeof(float) * n * EW_BF_MAX_ATTR);
                for (long i = 0; i < n * C; i++) rgb[i] = 2.0f * urand(&seed);
                rgb[5] = NAN;
                random_attrs(&m, n, attr, &seed);
                ew_image v = ew_image_packed(rgb, w, h, C);
                ew_device *dev = make_device(threads);
                ew_pyr_table t;
                random_table(&t, &seed);
                const int levels = 3;
                const size_t sc = ew_pyr_scratch_floats(&m, w, h, levels, uniform);
                float *s1 = malloc(sizeof(float) * sc), *s2 = malloc(sizeof(float) * sc);
                float *o1 = malloc(sizeof(float) * n * C), *o2 = malloc(sizeof(float) * n * C);
                ew_pyr_plan p1, p2;
                ew_pyr_plan_init(&p1, &m, w, h, levels, uniform, &t, 1.0f, s1);
                ew_pyr_plan_init(&p2, &m, w, h, levels, uniform, &t, 1.0f, s2);
                /* around: the attributes in planes, the colour packed, run, unpacked */
                ew_pyr_to_planes(attr, m.attrs, (size_t)n, p1.attr[0]);
                ew_pyr_to_planes(attr, m.attrs, (size_t)n, p2.attr[0]);
                ew_bf_pack_image_planes(dev, &v, C, p1.down[0]);
                CHECK(ew_pyr_run_planes(dev, &p1, NULL, NULL, NULL));
                ew_image o1v = ew_image_packed(o1, w, h, C), o2v = ew_image_packed(o2, w, h, C);
                ew_bf_unpack_image_planes(dev, p1.out, C, &o1v, &v);
                /* inside */
                ew_bf_io_set fill = {0}, drain = {0};
                ew_bf_io_pack_image(&fill, &v, C, p2.down[0], 1);
                ew_bf_io_unpack_image(&drain, p2.out, C, &o2v, &v, 1);
                const ew_pyr_io io = {ew_bf_io_fill, &fill, ew_bf_io_rows, &drain};
                CHECK(ew_pyr_run_planes(dev, &p2, &io, NULL, NULL));
                if (memcmp(o1, o2, sizeof(float) * n * C) != 0) {
                    fprintf(stderr, "  %dx%d kind %d threads %d: differs\n", w, h, m.kind, threads);
                    CHECK(0);
                }
                ew_device_destroy(dev);
                free(rgb); free(attr); free(s1); free(s2); free(o1); free(o2);
            }
}

/* Eq. 2g: the domain weights of every row sum to 1, analytic or trained */
TEST(domain_weights_sum_to_one) {
    for (float ls = -3.5f; ls < 7.0f; ls += 0.37f)
        for (int l = 0; l < 8; l++) {
            ew_pyr_params p;
            ew_pyr_params_at(NULL, exp2f(ls), l, 1.0f, &p);
            ew_pyr_wrow row;
            ew_pyr_expand(&p, &row);
            for (int par = 0; par < 4; par++) {
                double s = 0;
                for (int k = 0; k < 9; k++) s += row.wf[k] + row.wdc[par][k];
                CHECK_NEAR(s, 1.0, 1e-5);
            }
            CHECK(row.wf[4] >= 0.0f);
        }
}

/* ---- properties through the public API ---- */
static ew_result run_api(ew_device *dev, int w, int h, int C, const float *in, float *out, int model, int radius,
                         float sigma_r, const float *aux, int weights) {
    ew_filter *f = NULL;
    ew_result r = ew_filter_create(dev, "pyramid", &f);
    ew_image vi = ew_image_packed((float *)in, w, h, C), vo = ew_image_packed(out, w, h, C);
    ew_image va = ew_image_packed((float *)aux, w, h, model == 1 ? 3 : 1);
    if (r == EW_OK) r = ew_filter_set_image(f, "color", &vi);
    if (r == EW_OK) r = ew_filter_set_image(f, "output", &vo);
    if (r == EW_OK && aux) r = ew_filter_set_image(f, model == 0 ? "guide" : model == 1 ? "normal" : "depth", &va);
    if (r == EW_OK) r = ew_filter_set_int(f, "model", model);
    if (r == EW_OK) r = ew_filter_set_int(f, "radius", radius);
    if (r == EW_OK) r = ew_filter_set_float(f, "sigma_range", sigma_r);
    if (r == EW_OK) r = ew_filter_set_int(f, "weights", weights);
    if (r == EW_OK) r = ew_filter_commit(f);
    if (r == EW_OK) r = ew_filter_execute(f);
    ew_filter_destroy(f);
    return r;
}

TEST(constant_image_stays_constant) {
    ew_device *dev = make_device(2);
    const int w = 45, h = 31;
    float *in = malloc(sizeof(float) * w * h * 3), *out = malloc(sizeof(float) * w * h * 3);
    float *nrm = malloc(sizeof(float) * w * h * 3);
    unsigned s = 4;
    for (int i = 0; i < w * h; i++) {
        in[i * 3] = 0.3f;
        in[i * 3 + 1] = 1.5f;
        in[i * 3 + 2] = 7.0f;
        nrm[i * 3] = urand(&s) - 0.5f;
        nrm[i * 3 + 1] = urand(&s) - 0.5f;
        nrm[i * 3 + 2] = 1.0f;
    }
    for (int model = 0; model < 4; model++)
        for (int radius = 1; radius <= 40; radius += 13) {
            CHECK_EQ_INT(run_api(dev, w, h, 3, in, out, model, radius, 0.2f, model == 1 ? nrm : NULL, 0), EW_OK);
            for (int i = 0; i < w * h * 3; i++) CHECK_NEAR(out[i], in[i], 2e-6 * in[i]);
        }
    free(in); free(out); free(nrm);
    ew_device_destroy(dev);
}

TEST(step_edge_is_not_crossed) {
    ew_device *dev = make_device(2);
    const int w = 64, h = 40;
    float *in = malloc(sizeof(float) * w * h), *out = malloc(sizeof(float) * w * h), *g = malloc(sizeof(float) * w * h);
    unsigned s = 8;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int left = x < 27; /* an odd column: not on a 2^l boundary */
            g[y * w + x] = left ? 0.0f : 1.0f;
            in[y * w + x] = (left ? 0.2f : 3.0f) + 0.02f * (urand(&s) - 0.5f);
        }
    for (int radius = 4; radius <= 32; radius *= 2) {
        /* guided by a separate guide (joint), and by the image itself */
        CHECK_EQ_INT(run_api(dev, w, h, 1, in, out, 0, radius, 0.05f, g, 0), EW_OK);
        for (int y = 0; y < h; y++) {
            CHECK_NEAR(out[y * w + 26], 0.2, 0.012);
            CHECK_NEAR(out[y * w + 27], 3.0, 0.012);
        }
        CHECK_EQ_INT(run_api(dev, w, h, 1, in, out, 0, radius, 0.1f, NULL, 0), EW_OK);
        for (int y = 0; y < h; y++) {
            CHECK_NEAR(out[y * w + 26], 0.2, 0.012);
            CHECK_NEAR(out[y * w + 27], 3.0, 0.012);
        }
        /* depth model: a depth step (exp(-1 * 1 * 39): nothing crosses) */
        for (int i = 0; i < w * h; i++) g[i] = (i % w) < 27 ? 1.0f : 40.0f;
        CHECK_EQ_INT(run_api(dev, w, h, 1, in, out, 2, radius, 0.1f, g, 0), EW_OK);
        for (int y = 0; y < h; y++) {
            CHECK_NEAR(out[y * w + 26], 0.2, 0.012);
            CHECK_NEAR(out[y * w + 27], 3.0, 0.012);
        }
        for (int i = 0; i < w * h; i++) g[i] = (i % w) < 27 ? 0.0f : 1.0f;
    }
    free(in); free(out); free(g);
    ew_device_destroy(dev);
}

TEST(odd_sizes_radius_zero_and_beyond_the_image) {
    ew_device *dev = make_device(2);
    const int sizes[][2] = {{1, 1}, {3, 7}, {7, 3}, {2, 1}, {1023, 577}};
    for (int k = 0; k < 5; k++) {
        const int w = sizes[k][0], h = sizes[k][1];
        const long n = (long)w * h;
        float *in = malloc(sizeof(float) * n * 3), *out = malloc(sizeof(float) * n * 3);
        unsigned s = 30 + k;
        for (long i = 0; i < n * 3; i++) in[i] = urand(&s);
        CHECK_EQ_INT(run_api(dev, w, h, 3, in, out, 0, 0, 0.1f, NULL, 0), EW_OK);
        CHECK(memcmp(in, out, sizeof(float) * n * 3) == 0);
        const int radii[] = {1, 5, 64, 256};
        for (int r = 0; r < 4; r++) {
            if (n > 100000 && r != 2) continue;
            CHECK_EQ_INT(run_api(dev, w, h, 3, in, out, 3, radii[r], 0.1f, NULL, 0), EW_OK);
            double lo = 1, hi = 0;
            for (long i = 0; i < n * 3; i++) {
                CHECK(isfinite(out[i]));
                lo = fmin(lo, out[i]);
                hi = fmax(hi, out[i]);
            }
            CHECK(lo >= 0.0 && hi <= 1.0); /* a convex combination */
            if (n == 1) CHECK(memcmp(in, out, sizeof(float) * 3) == 0);
        }
        free(in);
        free(out);
    }
    ew_device_destroy(dev);
}

TEST(non_finite_samples_are_contained) {
    ew_device *dev = make_device(2);
    const int w = 33, h = 21;
    float *in = malloc(sizeof(float) * w * h * 3), *out = malloc(sizeof(float) * w * h * 3);
    unsigned s = 12;
    for (int i = 0; i < w * h * 3; i++) in[i] = urand(&s);
    in[(10 * w + 10) * 3] = NAN;
    in[(3 * w + 20) * 3 + 1] = INFINITY;
    in[(15 * w + 2) * 3 + 2] = -INFINITY;
    for (int i = 0; i < 3; i++) in[(20 * w + 32) * 3 + i] = NAN; /* a corner */
    for (int model = 0; model < 4; model += 3) {
        CHECK_EQ_INT(run_api(dev, w, h, 3, in, out, model, 9, 0.3f, NULL, 0), EW_OK);
        for (int i = 0; i < w * h * 3; i++) {
            CHECK(isfinite(out[i]));
            CHECK(out[i] >= 0.0f && out[i] <= 1.0f);
        }
    }
    /* an image of nothing but NaN: zeros, not garbage */
    for (int i = 0; i < w * h * 3; i++) in[i] = NAN;
    CHECK_EQ_INT(run_api(dev, w, h, 3, in, out, 3, 9, 0.3f, NULL, 0), EW_OK);
    for (int i = 0; i < w * h * 3; i++) CHECK(out[i] == 0.0f);
    free(in);
    free(out);
    ew_device_destroy(dev);
}

/* the result must not depend on the number of threads */
TEST(result_independent_of_thread_count) {
    const int w = 70, h = 43;
    float *in = malloc(sizeof(float) * w * h * 3), *o1 = malloc(sizeof(float) * w * h * 3);
    float *o4 = malloc(sizeof(float) * w * h * 3);
    unsigned s = 77;
    for (int i = 0; i < w * h * 3; i++) in[i] = urand(&s);
    ew_device *d1 = make_device(1), *d4 = make_device(4);
    CHECK_EQ_INT(run_api(d1, w, h, 3, in, o1, 0, 20, 0.2f, NULL, 0), EW_OK);
    CHECK_EQ_INT(run_api(d4, w, h, 3, in, o4, 0, 20, 0.2f, NULL, 0), EW_OK);
    CHECK(memcmp(o1, o4, sizeof(float) * w * h * 3) == 0);
    free(in); free(o1); free(o4);
    ew_device_destroy(d1);
    ew_device_destroy(d4);
}

/* ---- the weights file ---- */
/* the container's checksum of buf[0..n) after a patch */
static void set_crc(unsigned char *buf, size_t n) {
    const uint32_t crc = ew_crc32(buf, n - 4);
    for (int k = 0; k < 4; k++) buf[n - 4 + k] = (unsigned char)(crc >> (8 * k));
}

TEST(weights_file_round_trip_and_validation) {
    ew_pyr_table t, back;
    unsigned s = 5;
    random_table(&t, &s);
    size_t n = ew_pyr_table_write(&t, NULL, 0);
    unsigned char *buf = malloc(n);
    CHECK(ew_pyr_table_write(&t, buf, n) == n);
    char why[200];
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &back, why, sizeof why), EW_OK);
    CHECK_EQ_INT(back.nodes, t.nodes);
    CHECK(memcmp(back.p[2][3].wc, t.p[2][3].wc, sizeof t.p[2][3].wc) == 0);
    /* truncated, corrupted, wrong magic */
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n - 5, &back, why, sizeof why), EW_ERR_INVALID_DATA);
    buf[n / 2] ^= 1;
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &back, why, sizeof why), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(why, "checksum");
    buf[n / 2] ^= 1;
    /* the weights container, as the networks' files */
    CHECK(memcmp(buf, "EWWEIGHT", 8) == 0);
    /* tables written before they moved into that container: same layout,
     * magic "EWPYRWTS"; still read, to the same table */
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &back, why, sizeof why), EW_OK);
    memcpy(buf, "EWPYRWTS", 8);
    set_crc(buf, n);
    ew_pyr_table legacy;
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &legacy, why, sizeof why), EW_OK);
    CHECK(memcmp(&legacy, &back, sizeof back) == 0);
    buf[0] = 'X';
    set_crc(buf, n);
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &back, why, sizeof why), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(why, "magic");
    free(buf);
    /* weights outside [0, 1]: coarse weights all 1 leave a negative centre */
    for (int k = 0; k < 9; k++) t.p[1][1].wc[k] = 1.0f;
    n = ew_pyr_table_write(&t, NULL, 0);
    buf = malloc(n);
    ew_pyr_table_write(&t, buf, n);
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &back, why, sizeof why), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(why, "outside [0, 1]");
    free(buf);
    /* Eq. 2g violated: the writer always enforces it, so patch the stored
     * centre weight of node 0 level 0 and fix up the checksum */
    random_table(&t, &s);
    n = ew_pyr_table_write(&t, NULL, 0);
    buf = malloc(n);
    ew_pyr_table_write(&t, buf, n);
    size_t at = 8 + 4 + 4 + strlen(EW_PYR_ARCH) + 4 + (4 + 10 + 4 + 4 + 4 * (size_t)t.nodes) + (4 + 6 + 4 + 12) + 4 * 4;
    float centre;
    memcpy(&centre, buf + at, 4);
    CHECK_NEAR(centre, ew_pyr_centre_weight(&t.p[0][0]), 1e-6);
    centre -= 0.01f;
    memcpy(buf + at, &centre, 4);
    set_crc(buf, n);
    CHECK_EQ_INT(ew_pyr_table_parse(buf, n, &back, why, sizeof why), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(why, "Eq. 2g");
    free(buf);
    /* through the API: bad bytes are rejected at set_data, naming the data */
    ew_device *dev = make_device(1);
    ew_filter *f = NULL;
    CHECK_EQ_INT(ew_filter_create(dev, "pyramid", &f), EW_OK);
    CHECK_EQ_INT(ew_filter_set_data(f, "weights", "garbage!", 8), EW_ERR_INVALID_DATA);
    CHECK_STR_CONTAINS(ew_device_last_error(dev), "'weights'");
    ew_filter_destroy(f);
    ew_device_destroy(dev);
}


/* ---- training: the backward pass against finite differences ---- */
static double loss_of(ew_pyr_plan *p, const ew_pyr_params *prm, const float *img, const float *attr, float *out,
                      const float *dout, long n) {
    for (int l = 0; l < p->levels; l++) ew_pyr_expand(&prm[l], &p->rows[l]);
    ew_pyr_forward1(p, img, attr, out, 0);
    double L = 0;
    for (long i = 0; i < n * EW_BF_CH; i++) L += (double)dout[i] * out[i];
    return L;
}

static int check_gradient(int kind, unsigned seed) {
    const int w = 20, h = 14, levels = 3;
    const long n = (long)w * h;
    ew_bf_model m = model_of(kind, EW_BF_CH, 2.0f);
    float *img = malloc(sizeof(float) * n * EW_BF_CH), *attr = malloc(sizeof(float) * (n * EW_BF_MAX_ATTR + 8));
    float *out = malloc(sizeof(float) * n * EW_BF_CH), *dout = malloc(sizeof(float) * n * EW_BF_CH);
    for (long i = 0; i < n * EW_BF_CH; i++) {
        img[i] = i % EW_BF_CH == 3 ? 1.0f : urand(&seed);
        dout[i] = 2.0f * urand(&seed) - 1.0f;
    }
    for (int c = 0; c < EW_BF_CH; c++) img[17 * EW_BF_CH + c] = 0.0f; /* a missing sample too */
    random_attrs(&m, n, attr, &seed);
    ew_pyr_table t;
    random_table(&t, &seed);
    ew_pyr_params prm[4];
    for (int l = 0; l < levels; l++) prm[l] = t.p[1][l];
    float *scratch = malloc(sizeof(float) * ew_pyr_scratch_floats(&m, w, h, levels, 1));
    float *gs = malloc(sizeof(float) * ew_pyr_grad_scratch_floats(w, h));
    ew_pyr_plan p;
    ew_pyr_plan_init(&p, &m, w, h, levels, 1, NULL, 1.0f, scratch);
    loss_of(&p, prm, img, attr, out, dout, n);
    double grad[4 * EW_PYR_NPARAM] = {0};
    ew_pyr_backward1(&p, img, attr, out, dout, gs, grad);
    int ok = 1;
    const double hstep = 1e-3;
    for (int l = 0; l < levels; l++)
        for (int k = 0; k < EW_PYR_NPARAM; k++) {
            if (k == 4) continue; /* the centre: fixed by Eq. 2g */
            float *f = (float *)&prm[l];
            const float keep = f[k];
            f[k] = keep + (float)hstep;
            double lp = loss_of(&p, prm, img, attr, out, dout, n);
            f[k] = keep - (float)hstep;
            double lm = loss_of(&p, prm, img, attr, out, dout, n);
            f[k] = keep;
            double fd = (lp - lm) / (2 * hstep), an = grad[l * EW_PYR_NPARAM + k];
            if (!(fabs(fd - an) <= 0.02 * fmax(1.0, fabs(an)))) {
                fprintf(stderr, "  kind %d level %d param %d: analytic %g, finite differences %g\n", kind, l, k, an, fd);
                ok = 0;
            }
        }
    if (grad[4] != 0.0) ok = 0;
    free(img); free(attr); free(out); free(dout); free(scratch); free(gs);
    return ok;
}

TEST(backward_matches_finite_differences_color) { CHECK(check_gradient(EW_RANGE_COLOR, 41)); }
TEST(backward_matches_finite_differences_gi) { CHECK(check_gradient(EW_RANGE_GI, 42)); }
TEST(backward_matches_finite_differences_depth) { CHECK(check_gradient(EW_RANGE_DEPTH, 43)); }

/* the weights built into the library are models/pyramid/pyramid.ewpw and
 * pyramid_gi.ewpw, byte for byte, and validate; ew_pyr_builtin_table gives
 * GI its own table and every other kind the joint one */
extern const unsigned char ew_pyr_builtin_weights[], ew_pyr_builtin_weights_gi[];
extern const size_t ew_pyr_builtin_weights_size, ew_pyr_builtin_weights_gi_size;

static int same_as_models_file(const char *file, const unsigned char *bytes, size_t size) {
    char path[4096];
    snprintf(path, sizeof path, "%s", __FILE__);
    char *cut = strstr(path, "tests/unit/test_pyramid.c");
    if (!cut) return -1;
    snprintf(cut, sizeof path - (size_t)(cut - path), "models/pyramid/%s", file);
    FILE *f = fopen(path, "rb");
    if (!f) return -1;
    static unsigned char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    return n == size && memcmp(buf, bytes, n) == 0;
}

static int same_table(const ew_pyr_table *a, const unsigned char *bytes, size_t size) {
    ew_pyr_table b;
    char why[200];
    if (ew_pyr_table_parse(bytes, size, &b, why, sizeof why) != EW_OK) return 0;
    return a->nodes == b.nodes && a->levels == b.levels && memcmp(a->log2_sigma, b.log2_sigma, sizeof a->log2_sigma) == 0 &&
           memcmp(a->p, b.p, sizeof a->p) == 0;
}

TEST(builtin_weights_are_the_models_files) {
    const int joint = same_as_models_file("pyramid.ewpw", ew_pyr_builtin_weights, ew_pyr_builtin_weights_size);
    const int gi = same_as_models_file("pyramid_gi.ewpw", ew_pyr_builtin_weights_gi, ew_pyr_builtin_weights_gi_size);
    if (joint < 0 || gi < 0) SKIP("models/pyramid/*.ewpw not found");
    CHECK(joint == 1);
    CHECK(gi == 1);
    ew_pyr_table t;
    char why[200];
    static const int kinds[] = {EW_RANGE_COLOR, EW_RANGE_GI, EW_RANGE_DEPTH, EW_RANGE_DOF, EW_RANGE_NONE};
    for (int k = 0; k < 5; k++) {
        CHECK_EQ_INT(ew_pyr_builtin_table(kinds[k], &t, why, sizeof why), EW_OK);
        CHECK(t.nodes >= 1);
        if (kinds[k] == EW_RANGE_GI) CHECK(same_table(&t, ew_pyr_builtin_weights_gi, ew_pyr_builtin_weights_gi_size));
        else CHECK(same_table(&t, ew_pyr_builtin_weights, ew_pyr_builtin_weights_size));
    }
    /* in the current container: writing the parsed table gives the same bytes */
    const unsigned char *files[] = {ew_pyr_builtin_weights, ew_pyr_builtin_weights_gi};
    const size_t sizes[] = {ew_pyr_builtin_weights_size, ew_pyr_builtin_weights_gi_size};
    for (int k = 0; k < 2; k++) {
        CHECK_EQ_INT(ew_pyr_table_parse(files[k], sizes[k], &t, why, sizeof why), EW_OK);
        unsigned char *again = malloc(sizes[k]);
        CHECK(again && ew_pyr_table_write(&t, again, sizes[k]) == sizes[k]);
        CHECK(again && memcmp(again, files[k], sizes[k]) == 0);
        free(again);
    }
    /* two different tables (else the GI table would be a copy) */
    CHECK(ew_pyr_builtin_weights_size != ew_pyr_builtin_weights_gi_size ||
          memcmp(ew_pyr_builtin_weights, ew_pyr_builtin_weights_gi, ew_pyr_builtin_weights_size) != 0);
}

/* A filter with the trained weights (the default) of model m equals the
 * same filter given the table's bytes with set_data; returns the largest
 * difference to the filter given other_bytes instead (> 0: the tables
 * differ where it matters). -1 on a failure. */
static double filter_uses_table(int model, const unsigned char *own, size_t own_size, const unsigned char *other,
                                size_t other_size) {
    const int w = 48, h = 40;
    unsigned seed = 77;
    float *rgb = malloc(sizeof(float) * w * h * 3), *nrm = malloc(sizeof(float) * w * h * 3);
    float *z = malloc(sizeof(float) * w * h), *out[3];
    for (int i = 0; i < w * h; i++) {
        for (int c = 0; c < 3; c++) rgb[i * 3 + c] = urand(&seed) + ((i % w) > w / 2 ? 0.5f : 0.0f);
        const float x = urand(&seed) - 0.5f, y = urand(&seed) - 0.5f, l = sqrtf(x * x + y * y + 1.0f);
        nrm[i * 3] = x / l;
        nrm[i * 3 + 1] = y / l;
        nrm[i * 3 + 2] = 1.0f / l;
        z[i] = 1.0f + urand(&seed);
    }
    ew_device *dev = make_device(2);
    int ok = dev != NULL;
    for (int v = 0; v < 3; v++) {
        out[v] = malloc(sizeof(float) * w * h * 3);
        ew_filter *f = NULL;
        ew_image vi = ew_image_packed(rgb, w, h, 3), vo = ew_image_packed(out[v], w, h, 3);
        ew_image vn = ew_image_packed(nrm, w, h, 3), vz = ew_image_packed(z, w, h, 1);
        ok = ok && ew_filter_create(dev, "pyramid", &f) == EW_OK && ew_filter_set_image(f, "color", &vi) == EW_OK &&
             ew_filter_set_image(f, "output", &vo) == EW_OK && ew_filter_set_int(f, "model", model) == EW_OK &&
             ew_filter_set_int(f, "radius", 12) == EW_OK;
        if (ok && model == 1)
            ok = ew_filter_set_image(f, "normal", &vn) == EW_OK && ew_filter_set_image(f, "depth", &vz) == EW_OK &&
                 ew_filter_set_float(f, "sigma_normal", 32.0f) == EW_OK && ew_filter_set_float(f, "sigma_depth", 0.5f) == EW_OK;
        if (ok && v == 1) ok = ew_filter_set_data(f, "weights", own, own_size) == EW_OK;
        if (ok && v == 2) ok = ew_filter_set_data(f, "weights", other, other_size) == EW_OK;
        ok = ok && ew_filter_commit(f) == EW_OK && ew_filter_execute(f) == EW_OK;
        ew_filter_destroy(f);
    }
    double same = 0, diff = 0;
    for (int i = 0; ok && i < w * h * 3; i++) {
        same = fmax(same, fabs((double)out[0][i] - out[1][i]));
        diff = fmax(diff, fabs((double)out[0][i] - out[2][i]));
    }
    ew_device_destroy(dev);
    free(rgb); free(nrm); free(z);
    for (int v = 0; v < 3; v++) free(out[v]);
    return ok && same == 0.0 ? diff : -1.0;
}

TEST(each_model_filters_with_its_own_builtin_table) {
    /* GI with the GI table, colour with the joint one; each differs visibly
     * from what the other table gives */
    CHECK(filter_uses_table(1, ew_pyr_builtin_weights_gi, ew_pyr_builtin_weights_gi_size, ew_pyr_builtin_weights,
                            ew_pyr_builtin_weights_size) > 1e-4);
    CHECK(filter_uses_table(0, ew_pyr_builtin_weights, ew_pyr_builtin_weights_size, ew_pyr_builtin_weights_gi,
                            ew_pyr_builtin_weights_gi_size) > 1e-4);
}

/* COLOR's fine range values are computed once per pair of neighbours into
 * row buffers by the CPU backend, in segments of columns: the same numbers
 * bit for bit as the per-pixel function (which evaluates each pair from
 * both sides), over several segments and thread bands, for level 0 and a
 * duplicated level, gamma 1 and not. */
TEST(color_shared_fine_values_match_the_per_pixel_function) {
    unsigned s = 91;
    const int w = 4200, h = 9, cw = (w + 1) / 2, ch = (h + 1) / 2, A = 4; /* two column segments */
    const long n = (long)w * h, cn2 = 2L * cw * ch;
    ew_bf_model m = model_of(EW_RANGE_COLOR, EW_BF_CH, 2.0f);
    float *attr = malloc(sizeof(float) * n * A), *down = malloc(sizeof(float) * n * EW_BF_CH);
    float *cattr = malloc(sizeof(float) * cn2 * A), *cup = malloc(sizeof(float) * cn2 * EW_BF_CH);
    for (long i = 0; i < n; i++)
        for (int c = 0; c < EW_BF_CH; c++) {
            attr[c * n + i] = c == 3 ? 0.0f : urand(&s);
            down[c * n + i] = c == 3 ? 1.0f : urand(&s);
        }
    for (long i = 0; i < cn2; i += 2)
        for (int k = 0; k < 2; k++)
            for (int c = 0; c < EW_BF_CH; c++) {
                cattr[c * cn2 + i + k] = c == 3 ? 0.0f : urand(&s);
                cup[c * cn2 + i + k] = urand(&s);
            }
    ew_pyr_table t;
    random_table(&t, &s);
    ew_device *dev = make_device(3);
    for (int variant = 0; variant < 4; variant++) {
        const int dup = variant & 1;
        const long on = dup ? 2 * n : n;
        ew_pyr_params prm;
        ew_pyr_params_at(&t, 2.0f, dup, 1.0f, &prm);
        if (variant & 2) prm.gamma = 1.0f;
        ew_pyr_wrow row;
        ew_pyr_expand(&prm, &row);
        float *up[2] = {malloc(sizeof(float) * on * EW_BF_CH), malloc(sizeof(float) * on * EW_BF_CH)};
        ew_pyr_up_args a;
        memset(&a, 0, sizeof a);
        a.m = &m;
        a.w = w;
        a.h = h;
        a.cw = cw;
        a.ch = ch;
        a.down = down;
        a.attr = attr;
        a.cup = cup;
        a.cattr = cattr;
        a.d2_unit = dup ? 4.0f : 1.0f;
        a.row = &row;
        a.dup_out = dup;
        for (int v = 0; v < 2; v++) {
            memset(up[v], 0, sizeof(float) * on * EW_BF_CH);
            a.up = up[v];
            if (v == 0) dev->backend->pyr_up(dev, &a);
            else
                for (int y = 0; y < h; y++)
                    for (int x = 0; x < w; x++) ew_pyr_up_px(x, y, &a);
        }
        CHECK(memcmp(up[0], up[1], sizeof(float) * on * EW_BF_CH) == 0);
        free(up[0]);
        free(up[1]);
    }
    ew_device_destroy(dev);
    free(attr); free(down); free(cattr); free(cup);
}

/* A commit at the size of the last one keeps the op's scratch block (a
 * graph commits every frame; a new block is faulted in again), and the run
 * on it gives the same image; another size gets a block of its own. */
static void commit_keeps_block(const char *method) {
    ew_device_desc desc = EW_DEVICE_DESC_INIT;
    desc.num_threads = 2;
    ew_device *dev = NULL;
    CHECK(ew_device_create(&desc, &dev) == EW_OK);
    ew_op *op = NULL;
    CHECK(ew_op_create(dev, method, &op) == EW_OK);
    /* blocks above 64 KiB mapped afresh (the heap's top trimmed, so no
     * earlier test's freed memory serves them): a block made again, freed
     * and allocated, cannot hold the mark. No effect under a sanitizer's
     * allocator, whose quarantine gives a new block other memory anyway. */
    mallopt(M_MMAP_THRESHOLD, 64 << 10);
    malloc_trim(0);
    const int w = 160, h = 112, n = w * h;
    float *color = malloc(sizeof(float) * 3 * (size_t)n * 4), *depth = malloc(sizeof(float) * (size_t)n * 4);
    float *out[2] = {malloc(sizeof(float) * 3 * (size_t)n), malloc(sizeof(float) * 3 * (size_t)n)};
    for (int i = 0; i < 3 * n * 4; i++) color[i] = (float)((i * 37) % 101) / 100.0f;
    for (int i = 0; i < n * 4; i++) depth[i] = 2.0f + (float)(i % 53) / 5.0f;
    ew_image c = ew_image_packed(color, w, h, 3), d = ew_image_packed(depth, w, h, 1);
    CHECK(ew_op_set_image(op, "color", &c) == EW_OK);
    if (!strcmp(method, "dof")) CHECK(ew_op_set_image(op, "depth", &d) == EW_OK);
    else CHECK(ew_op_set_int(op, "radius", 6) == EW_OK);
    size_t bytes = 0;
    for (int k = 0; k < 2; k++) {
        ew_image o = ew_image_packed(out[k], w, h, 3);
        CHECK(ew_op_set_image(op, "output", &o) == EW_OK);
        CHECK(ew_op_commit(op) == EW_OK);
        /* the middle of the scratch: planes that only a run writes */
        unsigned char *tail = (unsigned char *)op->state + op->state_bytes / 2;
        if (k == 1) {
            CHECK(op->state_bytes == bytes);
            CHECK(*tail == 0xA5);
        }
        CHECK(ew_op_execute(op) == EW_OK);
        if (k == 0) {
            bytes = op->state_bytes;
            CHECK(bytes > 0);
            *tail = 0xA5; /* a mark the next commit keeps */
        }
    }
    CHECK(memcmp(out[0], out[1], sizeof(float) * 3 * (size_t)n) == 0);
    /* twice the size */
    c = ew_image_packed(color, 2 * w, 2 * h, 3);
    d = ew_image_packed(depth, 2 * w, 2 * h, 1);
    float *big = malloc(sizeof(float) * 3 * (size_t)n * 4);
    ew_image o = ew_image_packed(big, 2 * w, 2 * h, 3);
    CHECK(ew_op_set_image(op, "color", &c) == EW_OK);
    CHECK(ew_op_set_image(op, "output", &o) == EW_OK);
    if (!strcmp(method, "dof")) CHECK(ew_op_set_image(op, "depth", &d) == EW_OK);
    CHECK(ew_op_commit(op) == EW_OK);
    CHECK(op->state_bytes > bytes);
    CHECK(ew_op_execute(op) == EW_OK);
    ew_op_destroy(op);
    ew_device_destroy(dev);
    free(color);
    free(depth);
    free(out[0]);
    free(out[1]);
    free(big);
}

TEST(commit_at_the_same_size_keeps_the_scratch_pyramid) { commit_keeps_block("pyramid"); }
TEST(commit_at_the_same_size_keeps_the_scratch_dof) { commit_keeps_block("dof"); }
TEST(commit_at_the_same_size_keeps_the_scratch_atrous) { commit_keeps_block("atrous"); }
