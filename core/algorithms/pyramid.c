/*
 * pyramid.c — plan, weights and run of the pyramid edge-preserving filter
 * (the per-pixel math is in kernels/pyramid.h).
 */
#include "algorithms/pyramid.h"

#include <math.h>
#include <string.h>

#include "src/backend.h"
#include "src/thread_pool.h"

int ew_pyr_levels(float sigma_max, int w, int h) {
    if (!(sigma_max > 0.0f)) return 0;
    int need = (int)ceil(log2(3.5 * (double)sigma_max));
    if (need < 2) need = 2;
    int top = 0; /* levels until 1x1 */
    while (w > 1 || h > 1) {
        w = (w + 1) / 2;
        h = (h + 1) / 2;
        top++;
    }
    if (need > top) need = top;
    if (need > EW_PYR_MAX_LEVELS) need = EW_PYR_MAX_LEVELS;
    return need;
}

float ew_pyr_sigma_max(const ew_bf_model *m) {
    switch (m->kind) {
    case EW_RANGE_GI: return (m->sigma_alpha + 1.0f) / 3.0f;
    case EW_RANGE_DOF: {
        float d = 2.0f * (float)m->radius; /* CoC diameter */
        /* a whole attribute vector: ew_bf_sigma's GI branch reads a[4], and
         * GCC's -Warray-bounds (with the sanitizers) does not see it is dead */
        float a[EW_BF_MAX_ATTR] = {d, d, 0.0f, 0.0f, 0.0f};
        return ew_bf_sigma(m, a);
    }
    default: return m->sigma;
    }
}

void ew_pyr_identity(ew_pyr_params *out) {
    memset(out, 0, sizeof *out);
    out->wf[4] = 1.0f;
    out->gamma = 1.0f;
}

/* Layer cake: a radially decreasing kernel is a mixture of uniform discs;
 * for a 2-D Gaussian the disc mass in u = r^2 / 2 sigma^2 is Gamma(2, 1),
 * whose survival function is (1 + u) e^-u. Level l owns the discs with radii
 * in [R 2^(l - 1/2), R 2^(l + 1/2)); alpha_l is its share of what the finer
 * levels left over. */
static double disc_survival(double r, double sigma) {
    double u = r * r / (2.0 * sigma * sigma);
    return (1.0 + u) * exp(-u);
}

void ew_pyr_analytic(float sigma, int level, float gamma, ew_pyr_params *out) {
    ew_pyr_identity(out);
    out->gamma = gamma;
    if (!(sigma > 0.0f) || level >= ew_pyr_levels(sigma, 1 << 30, 1 << 30)) return;
    const double R = EW_PYR_DISC_RADIUS;
    double lo = level == 0 ? 1.0 : disc_survival(R * pow(2.0, level - 0.5), sigma);
    double hi = disc_survival(R * pow(2.0, level + 0.5), sigma);
    double alpha = lo > 1e-12 ? 1.0 - hi / lo : 1.0;
    if (alpha < 0.0) alpha = 0.0;
    if (alpha > 1.0) alpha = 1.0;
    out->wf[4] = (float)alpha;
    for (int k = 0; k < 9; k++) out->wc[k] = (float)(1.0 - alpha);
}

float ew_pyr_centre_weight(const ew_pyr_params *p) {
    double s = 0.0;
    for (int k = 0; k < 9; k++)
        if (k != 4) s += p->wf[k];
    for (int ky = 0; ky < 3; ky++)
        for (int kx = 0; kx < 3; kx++)
            s += (double)ew_pyr_alpha_d(2 * kx + 1) * ew_pyr_alpha_d(2 * ky + 1) * p->wc[ky * 3 + kx];
    return (float)(1.0 - s);
}

void ew_pyr_expand(const ew_pyr_params *p, ew_pyr_wrow *row) {
    for (int k = 0; k < 9; k++) row->wf[k] = p->wf[k];
    row->wf[4] = ew_pyr_centre_weight(p);
    for (int par = 0; par < 4; par++) {
        const int px = par & 1, py = par >> 1;
        for (int iy = -1; iy <= 1; iy++)
            for (int ix = -1; ix <= 1; ix++) {
                int kx = ew_pyr_dclass(ix, px), ky = ew_pyr_dclass(iy, py);
                row->wdc[par][(iy + 1) * 3 + ix + 1] =
                    ew_pyr_alpha_d(2 * kx + 1) * ew_pyr_alpha_d(2 * ky + 1) * p->wc[ky * 3 + kx];
            }
    }
    row->gamma = p->gamma;
}

static void lerp_params(const ew_pyr_params *a, const ew_pyr_params *b, float t, ew_pyr_params *out) {
    const float *pa = (const float *)a, *pb = (const float *)b;
    float *po = (float *)out;
    for (int k = 0; k < EW_PYR_NPARAM; k++) po[k] = (1.0f - t) * pa[k] + t * pb[k];
}

void ew_pyr_params_at(const ew_pyr_table *t, float sigma, int level, float analytic_gamma, ew_pyr_params *out) {
    if (!t || t->nodes < 1) {
        ew_pyr_analytic(sigma, level, analytic_gamma, out);
        return;
    }
    const float ls = log2f(fmaxf(sigma, 1e-6f));
    if (ls > t->log2_sigma[t->nodes - 1]) {
        ew_pyr_analytic(sigma, level, analytic_gamma, out);
        return;
    }
    /* below the first node, towards the identity at sigma = 2^LOG2_MIN (a
     * delta for the pixel grid) */
    int k = 0;
    while (k < t->nodes && t->log2_sigma[k] < ls) k++;
    ew_pyr_params a, b;
    float la, lb;
    if (k == 0) {
        ew_pyr_identity(&a);
        la = (float)EW_PYR_LUT_LOG2_MIN;
        lb = t->log2_sigma[0];
        if (level < t->levels) b = t->p[0][level];
        else ew_pyr_identity(&b);
        if (ls <= la) {
            *out = a;
            return;
        }
    } else {
        la = t->log2_sigma[k - 1];
        lb = t->log2_sigma[k];
        if (level < t->levels) {
            a = t->p[k - 1][level];
            b = t->p[k][level];
        } else {
            ew_pyr_identity(&a);
            ew_pyr_identity(&b);
        }
    }
    float f = lb > la ? (ls - la) / (lb - la) : 1.0f;
    lerp_params(&a, &b, fminf(fmaxf(f, 0.0f), 1.0f), out);
}

/* dup_attr: with the duplicated attributes (a plan without cbuf) */
static size_t level_floats(const ew_bf_model *m, int w, int h, int dup_attr) {
    /* down, attributes, duplicated attributes, duplicated up, duplicated content CoC */
    return (size_t)w * (size_t)h *
           (size_t)(EW_BF_CH + (dup_attr ? 3 : 1) * m->attrs + 2 * EW_BF_CH + (m->kind == EW_RANGE_DOF ? 2 : 0));
}

/* Planes of a thread's coarse rows: the attributes and DOF's content CoC. */
static long cbuf_planes(const ew_bf_model *m) { return m->attrs + (m->kind == EW_RANGE_DOF ? 1 : 0); }

/* Floats of a thread's coarse rows: three duplicated rows of level 1, the
 * widest level a pass reads them from. */
static size_t cbuf_floats(const ew_bf_model *m, int w) {
    return (size_t)cbuf_planes(m) * 3 * 2 * (size_t)((w + 1) / 2);
}

int ew_pyr_band_threads(const ew_device *dev, int w, int h) {
    (void)w;
    const int threads = dev->pool ? ew_pool_threads(dev->pool) : 1;
    /* the bands should be at most half the frame's rows */
    if (!dev->backend->pyr_row_hooks || (long)threads * EW_PYR_BAND * 2 > (long)h) return 0;
    return threads;
}

/* Floats of level 0's result: a whole frame, or the threads' bands. */
static size_t out_floats(int w, int h, int band_threads) {
    return (band_threads ? (size_t)band_threads * EW_PYR_BAND : (size_t)h) * (size_t)w * EW_BF_CH;
}

size_t ew_pyr_scratch_floats(const ew_bf_model *m, int w, int h, int levels, int uniform) {
    return ew_pyr_scratch_floats_banded(m, w, h, levels, uniform, 0);
}

/* Rows of a thread's input band: the band and the rows either side. */
#define IN_ROWS (EW_PYR_BAND + 2)

/* Floats of level 0's input: planes of a whole frame, or (with bands and
 * coarser levels) the threads' bands and the rows either side of the
 * bands' boundaries. */
static size_t in_floats(const ew_bf_model *m, int w, int h, int levels, int band_threads) {
    const size_t planes = (size_t)(EW_BF_CH + m->attrs);
    if (!band_threads || levels == 0) return (size_t)w * (size_t)h * planes;
    const size_t boundaries = (size_t)((h - 1) / EW_PYR_BAND);
    return ((size_t)band_threads * IN_ROWS + boundaries * 2) * (size_t)w * planes;
}

size_t ew_pyr_scratch_floats_banded(const ew_bf_model *m, int w, int h, int levels, int uniform, int band_threads) {
    /* level 0: in, attributes, out */
    size_t n = in_floats(m, w, h, levels, band_threads) + out_floats(w, h, band_threads);
    const int rows = band_threads && levels > 0; /* the coarse rows in the threads' buffers */
    if (rows) n += (size_t)band_threads * cbuf_floats(m, w);
    for (int l = 1; l <= levels; l++) {
        w = (w + 1) / 2;
        h = (h + 1) / 2;
        n += level_floats(m, w, h, !rows);
    }
    if (!uniform) n += (size_t)levels * EW_PYR_LUT_N * (sizeof(ew_pyr_wrow) / sizeof(float));
    return n;
}

void ew_pyr_plan_init(ew_pyr_plan *p, const ew_bf_model *m, int w, int h, int levels, int uniform,
                      const ew_pyr_table *table, float analytic_gamma, float *scratch) {
    ew_pyr_plan_init_banded(p, m, w, h, levels, uniform, table, analytic_gamma, scratch, 0);
}

void ew_pyr_plan_init_banded(ew_pyr_plan *p, const ew_bf_model *m, int w, int h, int levels, int uniform,
                             const ew_pyr_table *table, float analytic_gamma, float *scratch, int band_threads) {
    memset(p, 0, sizeof *p);
    p->model = *m;
    p->width = w;
    p->height = h;
    p->levels = levels;
    p->uniform = uniform;
    p->table = table;
    p->analytic_gamma = analytic_gamma;
    p->major_attr = m->kind == EW_RANGE_GI;
    p->w[0] = w;
    p->h[0] = h;
    float *s = scratch;
    const size_t n0 = (size_t)w * (size_t)h;
    if (band_threads && levels > 0) {
        const long planes = EW_BF_CH + m->attrs;
        p->in = s;
        p->in_ps = (long)IN_ROWS * w;
        p->in_stride = planes * p->in_ps;
        p->in_edge = s + (size_t)band_threads * (size_t)p->in_stride;
        s += in_floats(m, w, h, levels, band_threads);
    } else {
        p->down[0] = s;
        s += n0 * EW_BF_CH;
        p->attr[0] = s;
        s += n0 * (size_t)m->attrs;
    }
    p->out = s;
    s += out_floats(w, h, band_threads);
    if (band_threads) {
        p->band = EW_PYR_BAND;
        p->band_stride = (long)EW_PYR_BAND * w * EW_BF_CH;
    }
    if (band_threads && levels > 0) {
        p->cbuf = s;
        p->cbuf_stride = (long)cbuf_floats(m, w);
        s += (size_t)band_threads * cbuf_floats(m, w);
    }
    for (int l = 1; l <= levels; l++) {
        p->w[l] = (p->w[l - 1] + 1) / 2;
        p->h[l] = (p->h[l - 1] + 1) / 2;
        size_t n = (size_t)p->w[l] * (size_t)p->h[l];
        p->down[l] = s;
        s += n * (size_t)EW_BF_CH;
        p->attr[l] = s;
        s += n * (size_t)m->attrs;
        if (!p->cbuf) {
            p->attr2[l] = s;
            s += 2 * n * (size_t)m->attrs;
        }
        p->up[l] = s;
        s += 2 * n * (size_t)EW_BF_CH;
        if (m->kind == EW_RANGE_DOF) {
            p->coc[l] = s;
            s += 2 * n;
        }
    }
    p->levels_end = s;
    ew_pyr_params prm;
    if (uniform) {
        for (int l = 0; l < levels; l++) {
            ew_pyr_params_at(table, m->sigma, l, analytic_gamma, &prm);
            ew_pyr_expand(&prm, &p->rows[l]);
        }
    } else {
        p->lut = (ew_pyr_wrow *)(void *)s;
        for (int l = 0; l < levels; l++)
            for (int i = 0; i < EW_PYR_LUT_N; i++) {
                float sg = exp2f((float)EW_PYR_LUT_LOG2_MIN + (float)i / (float)EW_PYR_LUT_STEPS);
                ew_pyr_params_at(table, sg, l, analytic_gamma, &prm);
                ew_pyr_expand(&prm, &p->lut[(size_t)l * EW_PYR_LUT_N + (size_t)i]);
            }
    }
}

void ew_pyr_to_planes(const float *src, int k, size_t n, float *planes) {
    for (size_t j = 0; j < n; j++)
        for (int c = 0; c < k; c++) planes[(size_t)c * n + j] = src[j * (size_t)k + (size_t)c];
}

void ew_pyr_from_planes(const float *planes, int k, size_t n, float *dst) {
    for (size_t j = 0; j < n; j++)
        for (int c = 0; c < k; c++) dst[j * (size_t)k + (size_t)c] = planes[(size_t)c * n + j];
}

/* Squared distance substituted for the coarse samples' range function at
 * level l (only DOF's depends on distance). §4.1 writes sqrt(2^(l+1) - 1)/2;
 * we read the exponent as 2(l+1), i.e. sqrt(4^(l+1) - 1)/2 ~ 2^l pixels, which
 * keeps the ratio of tile size to CoC the same at every level (the literal
 * form grows as 2^(l/2) and would let sharp content reach far coarser
 * levels than its CoC allows). */
float ew_pyr_coarse_d2(int l) { return (float)((pow(4.0, l + 1) - 1.0) / 4.0); }

int ew_pyr_run_planes(ew_device *dev, const ew_pyr_plan *p, const ew_pyr_io *io,
                      int (*progress)(void *user, double fraction), void *user) {
    const ew_backend *be = dev->backend;
    const ew_bf_model *m = &p->model;
    const size_t n0 = (size_t)p->width * (size_t)p->height * (size_t)EW_BF_CH;
    const ew_pyr_io none = {NULL, NULL, NULL, NULL};
    if (!io) io = &none;
    /* the backend runs the hooks by rows inside the passes, or they run on
     * all rows here */
    const int inside = be->pyr_row_hooks && p->levels > 0;
    if (p->in && (!inside || !io->fill)) return 0; /* input in bands: only the passes can fill it */
    if (io->fill && !inside) io->fill(io->fill_user, 0, p->height, 0, p->down[0], (long)p->width * p->height, 0);
    if (p->levels == 0) {
        if (!p->band) {
            memcpy(p->out, p->down[0], n0 * sizeof(float));
            if (io->drain) io->drain(io->drain_user, 0, p->height, 0);
            return 1;
        }
        /* band by band through thread 0's buffer */
        const size_t n = (size_t)p->width * (size_t)p->height, bs = (size_t)p->band * (size_t)p->width;
        for (int y0 = 0; y0 < p->height; y0 += p->band) {
            const int y1 = y0 + p->band < p->height ? y0 + p->band : p->height;
            for (int c = 0; c < EW_BF_CH; c++)
                memcpy(p->out + (size_t)c * bs, p->down[0] + (size_t)c * n + (size_t)y0 * p->width,
                       (size_t)(y1 - y0) * p->width * sizeof(float));
            if (io->drain) io->drain(io->drain_user, y0, y1, 0);
        }
        return 1;
    }
    for (int l = 0; l < p->levels; l++) {
        ew_pyr_down_args a;
        memset(&a, 0, sizeof a);
        a.m = m;
        a.w = p->w[l];
        a.h = p->h[l];
        a.cw = p->w[l + 1];
        a.ch = p->h[l + 1];
        a.down = p->down[l];
        a.attr = p->attr[l];
        a.cdown = p->down[l + 1];
        a.cattr = p->attr[l + 1];
        a.cattr2 = p->attr2[l + 1];
        a.cdown2 = l + 1 == p->levels ? p->up[l + 1] : NULL; /* Up(L) = Down(L) */
        a.d2_unit = (float)(1u << (2 * l));
        a.major_attr = p->major_attr;
        /* the pass writes level l + 1's down and attribute planes in full
         * (and at the coarsest level its upsampled planes) */
        ew_dev_prefault(dev, p->down[l + 1], l + 1 == p->levels ? p->up[l + 1] + 2 * (size_t)a.cw * a.ch * EW_BF_CH
                                                                : p->up[l + 1]);
        /* level 0's input bands: the fill writes them in full */
        if (l == 0 && p->in) ew_dev_prefault(dev, p->in, p->in_edge);
        if (l == 0 && inside && io->fill) {
            a.fill = io->fill;
            a.fill_user = io->fill_user;
            a.fbuf = p->in ? p->in : p->down[0];
            a.fbuf_stride = p->in ? p->in_stride : 0;
            a.fps = p->in ? p->in_ps : 0;
        }
        be->pyr_down(dev, &a);
    }
    if (progress && !progress(user, 0.3)) return 0;
    for (int l = p->levels - 1; l >= 0; l--) {
        ew_pyr_up_args a;
        memset(&a, 0, sizeof a);
        a.m = m;
        a.w = p->w[l];
        a.h = p->h[l];
        a.cw = p->w[l + 1];
        a.ch = p->h[l + 1];
        a.down = p->down[l];
        a.attr = p->attr[l];
        a.cup = p->up[l + 1];
        a.cattr = p->attr2[l + 1];
        if (p->cbuf) { /* the backend points cattr and ccoc at its rows */
            a.cattr_src = p->attr[l + 1];
            a.ccoc_src = m->kind == EW_RANGE_DOF && l + 1 < p->levels ? p->coc[l + 1] : NULL;
            a.cbuf = p->cbuf;
            a.cbuf_stride = p->cbuf_stride;
        }
        a.up = l == 0 ? p->out : p->up[l];
        a.dup_out = l > 0;
        a.d2_unit = (float)(1u << (2 * l));
        a.coarse_d2 = ew_pyr_coarse_d2(l);
        a.row = p->uniform ? &p->rows[l] : NULL;
        a.lut = p->uniform ? NULL : p->lut + (size_t)l * EW_PYR_LUT_N;
        /* the coarsest level: its own C (the duplicated attributes' plane 1) */
        if (m->kind == EW_RANGE_DOF && !p->cbuf)
            a.ccoc = l + 1 < p->levels ? p->coc[l + 1] : p->attr2[l + 1] + 2 * (size_t)a.cw * (size_t)a.ch;
        a.ucoc = l > 0 ? p->coc[l] : NULL;
        if (l == 0 && inside) {
            a.drain = io->drain;
            a.drain_user = io->drain_user;
        }
        if (l == 0) {
            /* the rows either side of the bands' boundaries and the output
             * (bands or planes): written in full by this pass */
            ew_dev_prefault(dev, p->in ? p->in_edge : p->out, p->cbuf ? p->cbuf : p->down[1]);
            a.band = p->band;
            a.band_stride = p->band_stride;
        }
        if (l == 0 && p->in) {
            /* Each band packs its own rows again from the caller's views, which
             * the drain may be overwriting (an output in place of the colour):
             * the rows either side of every boundary are saved first, before
             * any row is drained. */
            const long planes = EW_BF_CH + m->attrs, es = 2L * p->width * planes;
            for (int b = p->band, k = 0; b < p->height; b += p->band, k++)
                io->fill(io->fill_user, b - 1, b + 1, 0, p->in_edge + (size_t)k * (size_t)es, 2L * p->width, b - 1);
            a.fill = io->fill;
            a.fill_user = io->fill_user;
            a.fbuf = p->in;
            a.fbuf_stride = p->in_stride;
            a.fps = p->in_ps;
            a.fedge = p->in_edge;
        }
        /* Upsampling level l reads levels l and l + 1 but not level l + 1's
         * down planes, nor its attribute planes when it has them duplicated,
         * nor any coarser level: with release_scratch their pages go back
         * before level l's planes are written (level 1's upsampled planes,
         * written here, are the run's largest new pages), and the next run's
         * downsampling writes them before reading them. The table after the
         * levels stays. */
        ew_dev_release_pages(dev, p->down[l + 1], p->attr2[l + 1] ? p->attr2[l + 1] : p->attr[l + 1]);
        if (l + 2 <= p->levels) ew_dev_release_pages(dev, p->down[l + 2], p->levels_end);
        if (l > 0) { /* written in full: Up(l) duplicated, and DOF's CoC of it */
            const size_t n = (size_t)a.w * (size_t)a.h;
            ew_dev_prefault(dev, p->up[l], a.ucoc ? p->coc[l] + 2 * n : p->up[l] + 2 * n * EW_BF_CH);
        }
        be->pyr_up(dev, &a);
    }
    if (io->drain && !inside) io->drain(io->drain_user, 0, p->height, 0);
    return 1;
}

int ew_pyr_run(ew_device *dev, const ew_pyr_plan *p, const float *image, const float *attr, float *out,
               int (*progress)(void *user, double fraction), void *user) {
    const size_t n = (size_t)p->width * (size_t)p->height;
    if (p->band) return 0; /* the result is read back whole: a plan without bands */
    ew_pyr_to_planes(image, EW_BF_CH, n, p->down[0]);
    ew_pyr_to_planes(attr, p->model.attrs, n, p->attr[0]);
    if (!ew_pyr_run_planes(dev, p, NULL, progress, user)) return 0;
    ew_pyr_from_planes(p->out, EW_BF_CH, n, out);
    return 1;
}
