/*
 * cpu_filters.c — CPU loops for the edge-aware filters: rows go to the
 * device's thread pool, each pixel calls the shared function of
 * kernels/{bilateral,pyramid,atrous,dof}.h. Every pass writes a buffer the
 * same pass does not read, so rows are independent and the result does not
 * depend on the thread count.
 *
 * The per-pixel functions take the model kind as an argument; the row loops
 * below are instantiated once per kind with a constant and `flatten`, so the
 * compiler inlines everything and drops the other kinds' code from the inner
 * loops (what a template would do). The brute force, the separable filter
 * and the pyramid all get the same treatment, so their speed ratios compare
 * the algorithms, not the effort spent on each.
 */
/* Every loop here is compiled without trapping math (no FP exception is ever
 * enabled or read in the library), so the compiler may if-convert
 * conditionals around float arithmetic and vectorise the per-pixel
 * functions across pixels; IEEE results are unchanged. Before the includes,
 * so the kernels' inline functions get it too; the same for every filter. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("no-trapping-math")
#endif
#include <string.h>

#include "kernels/dof.h"
#include "kernels/pyramid.h"
#include "src/backend.h"
#include "src/internal.h"

#if defined(__GNUC__)
#define EW_FLATTEN __attribute__((flatten))
#else
#define EW_FLATTEN
#endif

#include "src/cpu_clones.h" /* EW_MULTIVERSION */
#define EW_ROW_FN EW_MULTIVERSION EW_FLATTEN

/* One row function per kind: NAME_<kind>(ctx, begin, end, tid) runs
 * BODY(kind) for rows [begin, end) (tid: the worker's index), each built
 * with ATTR (at least EW_FLATTEN, so the kind is a constant in BODY); NAME
 * picks one by kind. */
#define EW_ROWS_PER_KIND(NAME, CTX_T, BODY, ATTR)                                                              \
    static EW_FLATTEN void NAME##_k(const CTX_T *j, int64_t begin, int64_t end, const int kind, int tid) { (void)tid; BODY } \
    static ATTR void NAME##_color(void *c, int64_t b, int64_t e, int t) { NAME##_k((const CTX_T *)c, b, e, EW_RANGE_COLOR, t); } \
    static ATTR void NAME##_gi(void *c, int64_t b, int64_t e, int t) { NAME##_k((const CTX_T *)c, b, e, EW_RANGE_GI, t); } \
    static ATTR void NAME##_depth(void *c, int64_t b, int64_t e, int t) { NAME##_k((const CTX_T *)c, b, e, EW_RANGE_DEPTH, t); } \
    static ATTR void NAME##_dof(void *c, int64_t b, int64_t e, int t) { NAME##_k((const CTX_T *)c, b, e, EW_RANGE_DOF, t); } \
    static ATTR void NAME##_none(void *c, int64_t b, int64_t e, int t) { NAME##_k((const CTX_T *)c, b, e, EW_RANGE_NONE, t); } \
    static ew_range_fn NAME(int kind) {                                                                         \
        switch (kind) {                                                                                         \
        case EW_RANGE_COLOR: return NAME##_color;                                                               \
        case EW_RANGE_GI: return NAME##_gi;                                                                     \
        case EW_RANGE_DEPTH: return NAME##_depth;                                                               \
        case EW_RANGE_DOF: return NAME##_dof;                                                                   \
        default: return NAME##_none;                                                                            \
        }                                                                                                       \
    }

typedef struct {
    const ew_bf_model *m;
    const ew_bf_buffers *b;
    int axis;
} bf_job;

EW_ROWS_PER_KIND(brute_rows, bf_job,
                 for (int64_t y = j->b->y0 + begin; y < j->b->y0 + end; y++)
                     for (int x = 0; x < j->b->width; x++) ew_bf_brute_px_k(x, (int)y, j->m, j->b, kind);, EW_ROW_FN)

void ew_cpu_bf_brute(ew_device *dev, const ew_bf_model *m, const ew_bf_buffers *b) {
    bf_job j = {m, b, 0};
    ew_pool_run(dev->pool, b->y1 - b->y0, 1, brute_rows(m->kind), &j);
}

EW_ROWS_PER_KIND(sep_rows, bf_job,
                 for (int64_t y = begin; y < end; y++)
                     for (int x = 0; x < j->b->width; x++) ew_bf_sep_px_k(x, (int)y, j->axis, j->m, j->b, kind);, EW_ROW_FN)

void ew_cpu_bf_separable(ew_device *dev, const ew_bf_model *m, int axis, const ew_bf_buffers *b) {
    bf_job j = {m, b, axis};
    ew_pool_run(dev->pool, b->height, 0, sep_rows(m->kind), &j);
}

/* The pyramid's passes: interior spans of a row through the branch-free
 * per-pixel functions, which the compiler vectorises across pixels (the
 * buffers are planes, see kernels/pyramid.h); the border pixels through the
 * general ones.
 *
 * Only the loops over pixels are built per vector width (EW_SPAN_FN: one
 * noinline function per kind and variant, its flags constant); the row
 * logic around them (which variant, the border, DoF's runs, the segments of
 * the symmetric pass) is built once per kind. Cloning the whole flattened
 * row function per target copied that logic, and every variant inlined into
 * it, three times into a few huge functions: most of this file's build time
 * and memory. A span is a row or a long run, so the call costs nothing
 * measurable. Each span function first copies what it reads (args, model,
 * weight row, the rows of precomputed range values) to locals, as the row
 * functions did, so the compiler knows its output stores cannot change
 * them. Same per-pixel functions on the same numbers: outputs unchanged. */
#if defined(__GNUC__) && !defined(__clang__)
#define EW_IVDEP _Pragma("GCC ivdep")
#else
#define EW_IVDEP
#endif
#if defined(__GNUC__)
#define EW_NOINLINE __attribute__((noinline))
#else
#define EW_NOINLINE
#endif
#define EW_SPAN_FN static EW_MULTIVERSION EW_FLATTEN EW_NOINLINE void

#define EW_DOWN_LOCALS(ap)                                                                                     \
    const ew_bf_model lm = *(ap)->m;                                                                           \
    ew_pyr_down_args a = *(ap);                                                                                \
    a.m = &lm
#define EW_UP_LOCALS(ap)                                                                                       \
    const ew_bf_model lm = *(ap)->m;                                                                           \
    ew_pyr_wrow lr;                                                                                            \
    ew_pyr_up_args a = *(ap);                                                                                  \
    a.m = &lm;                                                                                                 \
    if ((ap)->row) {                                                                                           \
        lr = *(ap)->row;                                                                                       \
        a.row = &lr;                                                                                           \
    }

/* ---- downsampling: per kind, the general pixels [x0, x1) of coarse row y,
 * the interior [0, xin) with any flags, and with constant flags */
#define EW_DOWN_KIND_SPANS(S, K)                                                                               \
    EW_SPAN_FN down_gen_##S(const ew_pyr_down_args *ap, int y, int x0, int x1) {                                \
        EW_DOWN_LOCALS(ap);                                                                                    \
        for (int x = x0; x < x1; x++) ew_pyr_down_px_k(x, y, &a, K);                                           \
    }                                                                                                          \
    EW_SPAN_FN down_any_##S(const ew_pyr_down_args *ap, int y, int xin, int major, int dup2, int rough) {       \
        EW_DOWN_LOCALS(ap);                                                                                    \
        for (int x = 0; x < xin; x++) ew_pyr_down_in_k(x, y, &a, K, major, dup2, rough);                       \
    }
#define EW_DOWN_IN_SPAN(S, K, MAJOR, DUP2, ROUGH)                                                              \
    EW_SPAN_FN down_in_##S##_##MAJOR##DUP2##ROUGH(const ew_pyr_down_args *ap, int y, int xin) {                 \
        EW_DOWN_LOCALS(ap);                                                                                    \
        EW_IVDEP                                                                                               \
        for (int x = 0; x < xin; x++) ew_pyr_down_in_k(x, y, &a, K, MAJOR, DUP2, ROUGH);                       \
    }
EW_DOWN_KIND_SPANS(color, EW_RANGE_COLOR)
EW_DOWN_KIND_SPANS(gi, EW_RANGE_GI)
EW_DOWN_KIND_SPANS(depth, EW_RANGE_DEPTH)
EW_DOWN_KIND_SPANS(dof, EW_RANGE_DOF)
EW_DOWN_KIND_SPANS(none, EW_RANGE_NONE)
/* DUP2 (ew_pyr_down_dup2): 1, 3 with the duplicated attributes (a whole
 * frame), 0, 2 without them (bands: the upsampling's coarse rows) */
#define EW_DOWN_IN_GI(ROUGH)                                                                                   \
    EW_DOWN_IN_SPAN(gi, EW_RANGE_GI, 1, 1, ROUGH) EW_DOWN_IN_SPAN(gi, EW_RANGE_GI, 1, 3, ROUGH)                \
    EW_DOWN_IN_SPAN(gi, EW_RANGE_GI, 1, 0, ROUGH) EW_DOWN_IN_SPAN(gi, EW_RANGE_GI, 1, 2, ROUGH)
EW_DOWN_IN_GI(0)
EW_DOWN_IN_GI(1)
#define EW_DOWN_IN_NOT_MAJOR(S, K)                                                                             \
    EW_DOWN_IN_SPAN(S, K, 0, 1, 0) EW_DOWN_IN_SPAN(S, K, 0, 3, 0) EW_DOWN_IN_SPAN(S, K, 0, 0, 0)               \
    EW_DOWN_IN_SPAN(S, K, 0, 2, 0)
EW_DOWN_IN_NOT_MAJOR(color, EW_RANGE_COLOR)
EW_DOWN_IN_NOT_MAJOR(depth, EW_RANGE_DEPTH)
EW_DOWN_IN_NOT_MAJOR(dof, EW_RANGE_DOF)
EW_DOWN_IN_NOT_MAJOR(none, EW_RANGE_NONE)

/* CALL(S) for the constant kind's suffix S (the row functions are built
 * per kind, so the switch folds to one call) */
#define EW_PER_KIND(CALL)                                                                                      \
    switch (kind) {                                                                                            \
    case EW_RANGE_COLOR: CALL(color); break;                                                                   \
    case EW_RANGE_GI: CALL(gi); break;                                                                         \
    case EW_RANGE_DEPTH: CALL(depth); break;                                                                   \
    case EW_RANGE_DOF: CALL(dof); break;                                                                       \
    default: CALL(none); break;                                                                                \
    }
#define EW_PER_NON_GI_KIND(CALL)                                                                               \
    switch (kind) {                                                                                            \
    case EW_RANGE_COLOR: CALL(color); break;                                                                   \
    case EW_RANGE_DEPTH: CALL(depth); break;                                                                   \
    case EW_RANGE_DOF: CALL(dof); break;                                                                       \
    default: CALL(none); break;                                                                                \
    }

static inline void down_rows_body(const ew_pyr_down_args *j, int64_t begin, int64_t end, const int kind, int tid) {
    const int xin = j->w / 2; /* coarse pixels with both children in x */
    const int major = j->major_attr != 0, dup2 = ew_pyr_down_dup2(j), rough = j->m->use_roughness != 0;
    ew_pyr_down_args rowargs;
    for (int64_t y = begin; y < end; y++) {
        const int yi = (int)y;
        const ew_pyr_down_args *ap = j;
        if (j->fill) {
            const int f0 = 2 * yi, f1 = 2 * yi + 2 < j->h ? 2 * yi + 2 : j->h;
            if (j->fbuf_stride) { /* the two fine rows into this thread's buffer, read from there */
                float *buf = j->fbuf + (long)tid * j->fbuf_stride;
                j->fill(j->fill_user, f0, f1, tid, buf, j->fps, f0);
                rowargs = *j;
                rowargs.down = buf;
                rowargs.attr = buf + EW_BF_CH * j->fps;
                rowargs.fy0 = f0;
                ap = &rowargs;
            } else {
                j->fill(j->fill_user, f0, f1, tid, j->fbuf, (long)j->w * j->h, 0);
            }
        }
        if (2 * y + 1 < ap->h) {
#define EW_IN(S, F) down_in_##S##_##F(ap, yi, xin)
#define EW_ANY(S) down_any_##S(ap, yi, xin, major, dup2, rough)
            if (kind == EW_RANGE_GI) {
                if (major && dup2 == 1 && !rough) EW_IN(gi, 110);
                else if (major && dup2 == 3 && !rough) EW_IN(gi, 130);
                else if (major && dup2 == 0 && !rough) EW_IN(gi, 100);
                else if (major && dup2 == 2 && !rough) EW_IN(gi, 120);
                else if (major && dup2 == 1 && rough) EW_IN(gi, 111);
                else if (major && dup2 == 3 && rough) EW_IN(gi, 131);
                else if (major && dup2 == 0 && rough) EW_IN(gi, 101);
                else if (major && dup2 == 2 && rough) EW_IN(gi, 121);
                else EW_ANY(gi);
            } else {
#define EW_IN_010(S) EW_IN(S, 010)
#define EW_IN_030(S) EW_IN(S, 030)
#define EW_IN_000(S) EW_IN(S, 000)
#define EW_IN_020(S) EW_IN(S, 020)
                if (!major && dup2 == 1) EW_PER_NON_GI_KIND(EW_IN_010)
                else if (!major && dup2 == 3) EW_PER_NON_GI_KIND(EW_IN_030)
                else if (!major && dup2 == 0) EW_PER_NON_GI_KIND(EW_IN_000)
                else if (!major && dup2 == 2) EW_PER_NON_GI_KIND(EW_IN_020)
                else EW_PER_NON_GI_KIND(EW_ANY)
#undef EW_IN_010
#undef EW_IN_030
#undef EW_IN_000
#undef EW_IN_020
            }
#undef EW_IN
#undef EW_ANY
#define EW_GEN_REST(S) down_gen_##S(ap, yi, xin, ap->cw)
            EW_PER_KIND(EW_GEN_REST)
#undef EW_GEN_REST
        } else {
#define EW_GEN_ROW(S) down_gen_##S(ap, yi, 0, ap->cw)
            EW_PER_KIND(EW_GEN_ROW)
#undef EW_GEN_ROW
        }
    }
}

EW_ROWS_PER_KIND(down_rows, ew_pyr_down_args, down_rows_body(j, begin, end, kind, tid);, EW_FLATTEN)

void ew_cpu_pyr_down(ew_device *dev, const ew_pyr_down_args *a) {
    ew_pool_run(dev->pool, a->ch, 0, down_rows(a->m->kind), (void *)a);
}

/* The coarse rows fine row y reads (ew_pyr_up_args.cbuf): rows cy - 1 ..
 * cy + 1 of the attributes and DOF's content CoC, duplicated, into the
 * thread's buffer that t's cattr and ccoc point at (rows beyond the level
 * are never read: the pixels that would read them take the general path,
 * which checks). *have: the coarse row the buffer holds now. */
static void coarse_rows(const ew_pyr_up_args *j, ew_pyr_up_args *t, int y, int tid, int *have) {
    const int cy = y >> 1;
    if (!j->cbuf || cy == *have) return;
    *have = cy;
    const int cw = j->cw, A = ew_bf_attrs(j->m->kind);
    const long cw2 = 2L * cw, cn = (long)cw * j->ch, cps = t->cps;
    float *buf = j->cbuf + (long)tid * j->cbuf_stride; /* t->cattr */
    t->cy0 = cy - 1;
    for (int r = 0; r < 3; r++) {
        const int qy = cy - 1 + r;
        if (qy < 0 || qy >= j->ch) continue;
        for (int k = 0; k < A; k++) {
            const float *src = j->cattr_src + k * cn + (long)qy * cw;
            float *dst = buf + k * cps + r * cw2;
            for (int x = 0; x < cw; x++) dst[2 * x] = dst[2 * x + 1] = src[x];
        }
        if (j->ccoc_src) memcpy(buf + A * cps + r * cw2, j->ccoc_src + (long)qy * cw2, sizeof(float) * (size_t)cw2);
    }
}

/* Point t (a copy of j) at thread tid's coarse rows, when j has them. */
static void coarse_rows_init(const ew_pyr_up_args *j, ew_pyr_up_args *t, int tid) {
    if (!j->cbuf) return;
    const long cps = 3L * 2 * j->cw;
    const float *buf = j->cbuf + (long)tid * j->cbuf_stride;
    t->cps = cps;
    t->cattr = buf;
    /* DOF: the content CoC after the attributes (coarse_rows); at the
     * coarsest level the attributes' own C (plane 1), as the whole-frame
     * plan passes it */
    if (j->m->kind == EW_RANGE_DOF) t->ccoc = j->ccoc_src ? buf + ew_bf_attrs(j->m->kind) * cps : buf + cps;
}

/* ---- upsampling: per kind, the general pixels [x0, x1) of row y, and the
 * interior spans with uniform weights (UNIFORM, G1: gamma 1, DUP: the
 * output duplicated), the symmetric kind's with precomputed fine range
 * values, DoF's table spans and its runs' spans with precomputed coarse
 * range values */
#define EW_UP_GEN_SPAN(S, K)                                                                                   \
    EW_SPAN_FN up_gen_##S(const ew_pyr_up_args *ap, int y, int x0, int x1) {                                    \
        EW_UP_LOCALS(ap)                                                                                       \
        for (int x = x0; x < x1; x++) ew_pyr_up_general_k(x, y, &a, K);                                        \
    }
#define EW_UP_SPAN(S, K, UNIFORM, G1, DUP)                                                                     \
    EW_SPAN_FN up_in_##S##_##UNIFORM##G1##DUP(const ew_pyr_up_args *ap, int y, int x0, int x1) {                \
        EW_UP_LOCALS(ap)                                                                                       \
        EW_IVDEP                                                                                               \
        for (int x = x0; x < x1; x++) ew_pyr_up_in_k(x, y, &a, K, UNIFORM, G1, DUP, 0, 0);                     \
    }
#define EW_UP_UNIFORM_SPANS(S, K)                                                                              \
    EW_UP_SPAN(S, K, 1, 1, 1) EW_UP_SPAN(S, K, 1, 1, 0) EW_UP_SPAN(S, K, 1, 0, 1) EW_UP_SPAN(S, K, 1, 0, 0)
#define EW_UP_CR_SPAN(S, K, DUP)                                                                               \
    EW_SPAN_FN up_cr_##S##_##DUP(const ew_pyr_up_args *ap, int y, int x0, int x1, const ew_pyr_coarse_rows *crp) { \
        EW_UP_LOCALS(ap)                                                                                       \
        const ew_pyr_coarse_rows cr = *crp;                                                                    \
        EW_IVDEP                                                                                               \
        for (int x = x0; x < x1; x++) ew_pyr_up_in_k(x, y, &a, K, 1, 0, DUP, 0, &cr);                          \
    }
EW_UP_GEN_SPAN(color, EW_RANGE_COLOR)
EW_UP_GEN_SPAN(gi, EW_RANGE_GI)
EW_UP_GEN_SPAN(depth, EW_RANGE_DEPTH)
EW_UP_GEN_SPAN(dof, EW_RANGE_DOF)
EW_UP_GEN_SPAN(none, EW_RANGE_NONE)
/* the symmetric kind (COLOR) takes up_spans_sym_color instead */
EW_UP_UNIFORM_SPANS(gi, EW_RANGE_GI)
EW_UP_UNIFORM_SPANS(depth, EW_RANGE_DEPTH)
EW_UP_UNIFORM_SPANS(dof, EW_RANGE_DOF)
EW_UP_UNIFORM_SPANS(none, EW_RANGE_NONE)
EW_UP_SPAN(dof, EW_RANGE_DOF, 0, 0, 1)
EW_UP_SPAN(dof, EW_RANGE_DOF, 0, 0, 0)
EW_UP_CR_SPAN(dof, EW_RANGE_DOF, 1)
EW_UP_CR_SPAN(dof, EW_RANGE_DOF, 0)

/* Symmetric range functions (ew_pyr_symmetric) with uniform weights: the
 * interior spans in segments of columns walked down the rows, the fine
 * range values of each row computed once into the segment's buffers
 * (ew_pyr_fine_rows) and read by both pixels of each pair. Segments bound
 * the buffers on the stack (128 KiB); narrower ones would pay in memory
 * traffic what they save in arithmetic (512 columns were slower than no
 * sharing: the rows are then read in short pieces, column strip by strip). */
#define EW_PYR_SEG 4096

/* The forward range values of row y over the segment [xb, xe) (what its
 * pixels and those of row y + 1 read), at index x - (xb - 1). */
static inline void fine_fwd_row(const ew_pyr_up_args *ap, int y, int xb, int xe, float (*buf)[EW_PYR_SEG + 2],
                                const int kind) {
    const ew_pyr_up_args a = *ap;
    float *rt = buf[0], *dl = buf[1], *dn = buf[2], *dr = buf[3];
    const int o = xb - 1;
    EW_IVDEP
    for (int x = xb - 1; x < xe; x++) rt[x - o] = ew_pyr_fine_fwd_k(x, y, 1, 0, &a, kind);
    EW_IVDEP
    for (int x = xb; x <= xe; x++) dl[x - o] = ew_pyr_fine_fwd_k(x, y, -1, 1, &a, kind);
    EW_IVDEP
    for (int x = xb; x < xe; x++) dn[x - o] = ew_pyr_fine_fwd_k(x, y, 0, 1, &a, kind);
    EW_IVDEP
    for (int x = xb - 1; x < xe; x++) dr[x - o] = ew_pyr_fine_fwd_k(x, y, 1, 1, &a, kind);
}

#define EW_PYR_UP_LOOP(XB, XE, UNIFORM, G1, DUP, FR)                                                          \
    do {                                                                                                       \
        EW_IVDEP                                                                                               \
        for (int x = XB; x < XE; x++) ew_pyr_up_in_k(x, (int)y, &a, kind, UNIFORM, G1, DUP, FR, 0);           \
    } while (0)

/* One span function for the whole symmetric pass: its rows, segments and
 * both loops, which share the segment buffers on its stack. */
EW_SPAN_FN up_spans_sym_color(const ew_pyr_up_args *ap, int64_t begin, int64_t end, const int g1, const int dup,
                               int tid) {
    EW_UP_LOCALS(ap)
    const int kind = EW_RANGE_COLOR;
    float buf[2][4][EW_PYR_SEG + 2];
    int x0, x1;
    ew_pyr_up_interior((int)begin, &a, &x0, &x1); /* the columns are the same in every row */
    /* a row is done after its last segment: with one segment, drain it then
     * (the rows without an interior were drained by the caller) */
    const int one = x1 - x0 <= EW_PYR_SEG;
    int crow = -1; /* the coarse row a.cattr holds (coarse_rows) */
    for (int xb = x0; xb < x1; xb += EW_PYR_SEG) {
        const int xe = xb + EW_PYR_SEG < x1 ? xb + EW_PYR_SEG : x1;
        int have = 0, cur = 0, c0, c1;
        for (int64_t y = begin; y < end; y++) {
            if (!ew_pyr_up_interior((int)y, &a, &c0, &c1)) {
                have = 0;
                continue;
            }
            coarse_rows(ap, &a, (int)y, tid, &crow);
            if (!have) fine_fwd_row(&a, (int)y - 1, xb, xe, buf[cur ^ 1], kind);
            have = 1;
            fine_fwd_row(&a, (int)y, xb, xe, buf[cur], kind);
            const ew_pyr_fine_rows fr = {buf[cur ^ 1][1], buf[cur ^ 1][2], buf[cur ^ 1][3], buf[cur][0],
                                         buf[cur][1],     buf[cur][2],     buf[cur][3],     xb - 1};
            if (g1 && dup) EW_PYR_UP_LOOP(xb, xe, 1, 1, 1, &fr);
            else if (g1) EW_PYR_UP_LOOP(xb, xe, 1, 1, 0, &fr);
            else if (dup) EW_PYR_UP_LOOP(xb, xe, 1, 0, 1, &fr);
            else EW_PYR_UP_LOOP(xb, xe, 1, 0, 0, &fr);
            cur ^= 1;
            if (a.drain && one) a.drain(a.drain_user, (int)y, (int)y + 1, tid);
        }
    }
    if (a.drain && !one)
        for (int64_t y = begin; y < end; y++) {
            int c0, c1;
            if (ew_pyr_up_interior((int)y, &a, &c0, &c1)) a.drain(a.drain_user, (int)y, (int)y + 1, tid);
        }
}

/* DOF's per-pixel sigma (the table): where a run of at least EW_PYR_RUN
 * interior pixels shares the attribute its sigma comes from (D, bit for
 * bit), the run's weights are one row, looked up once, and the run takes the
 * uniform variant: the same numbers as the lookup per pixel (the same
 * operations on the same D), without its gathers, interpolation and log2,
 * which were a third of DoF's upsampling. Runs are wherever the domain CoC
 * is flat: a depth beyond the CoC cap, the sky, a dilated near-field tile, a
 * uniform blur; elsewhere the table as before. */
#define EW_PYR_RUN 16

/* A run of equal D also shares its coarse samples' range values: they
 * depend on the centre only through D (min(D_p, C_q)), so each is computed
 * once for the run (ew_pyr_coarse_rows) instead of by each of the pixels
 * that read it (twelve of them at level 0), with its f^gamma: 18 of a
 * pixel's 26 exponentials. In chunks of EW_PYR_CR columns (the buffers are
 * on the stack). */
#define EW_PYR_CR 2048

/* the coarse samples [c0, c1) of one coarse row (a duplicated-plane row
 * starting at base) for the run's centre attributes at */
EW_SPAN_FN coarse_fg_dof(const ew_pyr_up_args *ap, long base, int c0, int c1, int xo, const float *atp, float gamma,
                         float *fr, float *gr) {
    EW_UP_LOCALS(ap)
    float at[EW_BF_MAX_ATTR];
    for (int k = 0; k < EW_BF_MAX_ATTR; k++) at[k] = atp[k];
    EW_IVDEP
    for (int c = c0; c < c1; c++) ew_pyr_coarse_fg_k(base + c, at, &a, EW_RANGE_DOF, gamma, &fr[c - xo], &gr[c - xo]);
}

/* at: the run's centre attributes (all its pixels share them where the
 * range function looks) */
static void up_run_shared(const ew_pyr_up_args *a, int64_t y, int xs, int xe, const float *at, const int dup) {
    float fb[3][EW_PYR_CR + 4], gb[3][EW_PYR_CR + 4];
    const long cw2 = 2L * a->cw;
    const float gamma = a->row->gamma;
    const int cy = (int)(y >> 1);
    for (int cb = xs; cb < xe; cb += EW_PYR_CR) {
        const int ce = cb + EW_PYR_CR < xe ? cb + EW_PYR_CR : xe, xo = cb - 2;
        for (int r = 0; r < 3; r++)
            coarse_fg_dof(a, (long)(cy + r - 1 - a->cy0) * cw2, cb - 2, ce + 2, xo, at, gamma, fb[r], gb[r]);
        const ew_pyr_coarse_rows cr = {{fb[0], fb[1], fb[2]}, {gb[0], gb[1], gb[2]}, xo};
        if (dup) up_cr_dof_1(a, (int)y, cb, ce, &cr);
        else up_cr_dof_0(a, (int)y, cb, ce, &cr);
    }
}

static void up_span_runs(const ew_pyr_up_args *ap, int64_t y, int x0, int x1, const int dup) {
    const int kind = EW_RANGE_DOF;
    ew_pyr_up_args a = *ap;
    ew_pyr_wrow rr;
    const long n = ew_pyr_up_dps(&a), row0 = ((long)y - a.dy0) * a.w;
    const float *D = a.attr + row0; /* attribute plane 0: D */
    const int py = ((int)y & 1) * 2, yi = (int)y;
    int xs = x0, pend = x0; /* [pend, xs): waiting for the table */
    while (xs < x1) {
        const int b = ew_float_to_bits(D[xs]);
        int e = xs + 1;
        while (e < x1 && ew_float_to_bits(D[e]) == b) e++;
        if (e - xs >= EW_PYR_RUN) {
            a.row = NULL;
            if (dup) up_in_dof_001(&a, yi, pend, xs);
            else up_in_dof_000(&a, yi, pend, xs);
            float at[EW_BF_MAX_ATTR] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
            for (int k = 0; k < ew_bf_attrs(kind); k++) at[k] = a.attr[k * n + row0 + xs];
            const float ls = ew_pyr_log2_sigma(a.m, kind, at);
            ew_pyr_lookup(a.lut, ls, py, rr.wf, rr.wdc[py], &rr.gamma);
            ew_pyr_lookup(a.lut, ls, py + 1, rr.wf, rr.wdc[py + 1], &rr.gamma);
            a.row = &rr;
            up_run_shared(&a, y, xs, e, at, dup);
            pend = e;
        }
        xs = e;
    }
    a.row = NULL;
    if (dup) up_in_dof_001(&a, yi, pend, x1);
    else up_in_dof_000(&a, yi, pend, x1);
}

static inline void up_rows_body(const ew_pyr_up_args *j, int64_t begin, int64_t end, const int kind, int tid) {
    ew_pyr_up_args t = *j;
    coarse_rows_init(j, &t, tid);
    const ew_pyr_up_args *a = &t;
    const int fast = ew_pyr_up_in_ok(a, kind), uniform = a->row != 0, g1 = uniform && a->row->gamma == 1.0f;
    const int dup = a->dup_out != 0, sym = fast && uniform && ew_pyr_symmetric(kind);
    int crow = -1; /* the coarse row t holds (coarse_rows) */
    for (int64_t y = begin; y < end; y++) {
        const int yi = (int)y;
        int x0, x1;
        coarse_rows(j, &t, yi, tid, &crow);
#define EW_GEN(XB, XE)                                                                                         \
    do {                                                                                                       \
        const int gb_ = (XB), ge_ = (XE);                                                                      \
        if (gb_ < ge_) {                                                                                       \
            EW_PER_KIND(EW_GEN_CALL)                                                                           \
        }                                                                                                      \
    } while (0)
#define EW_GEN_CALL(S) up_gen_##S(a, yi, gb_, ge_)
        if (!fast || !ew_pyr_up_interior(yi, a, &x0, &x1)) {
            EW_GEN(0, a->w);
            if (a->drain) a->drain(a->drain_user, yi, yi + 1, tid);
            continue;
        }
        EW_GEN(0, x0);
        if (sym) { /* up_spans_sym_color below */
        } else if (uniform && !ew_pyr_symmetric(kind)) { /* (a symmetric kind's uniform rows are sym) */
#define EW_U(S)                                                                                                \
    if (g1 && dup) up_in_##S##_111(a, yi, x0, x1);                                                             \
    else if (g1) up_in_##S##_110(a, yi, x0, x1);                                                               \
    else if (dup) up_in_##S##_101(a, yi, x0, x1);                                                              \
    else up_in_##S##_100(a, yi, x0, x1);
            switch (kind) {
            case EW_RANGE_GI: EW_U(gi) break;
            case EW_RANGE_DEPTH: EW_U(depth) break;
            case EW_RANGE_DOF: EW_U(dof) break;
            case EW_RANGE_NONE: EW_U(none) break;
            default: break;
            }
#undef EW_U
        } else if (kind == EW_RANGE_DOF) up_span_runs(a, y, x0, x1, dup); /* the table's lookup as gathers, or runs */
        else /* the other kinds' table (ew_pyr_up_in_vec): scalar either way, and the general path is as fast */
            EW_GEN(x0, x1);
        EW_GEN(x1, a->w);
#undef EW_GEN_CALL
#undef EW_GEN
        if (a->drain && !sym) a->drain(a->drain_user, yi, yi + 1, tid);
    }
    if (sym) up_spans_sym_color(a, begin, end, g1, dup, tid);
}

/* Level 0's input for the band of rows from b0 (ew_pyr_up_args.fill): the
 * band's own rows packed into the thread's buffer from row 1 (nothing has
 * overwritten them: this thread drains them after it computes them), the
 * rows either side from the copies saved before the pass; t reads them
 * there. */
static void band_input(const ew_pyr_up_args *j, int b0, int tid, ew_pyr_up_args *t) {
    const int w = j->w, b1 = b0 + j->band < j->h ? b0 + j->band : j->h;
    const int planes = EW_BF_CH + ew_bf_attrs(j->m->kind);
    const long ps = j->fps, es = 2L * w; /* an edge block's plane stride */
    float *buf = j->fbuf + (long)tid * j->fbuf_stride;
    j->fill(j->fill_user, b0, b1, tid, buf + w, ps, b0);
    if (b0 > 0) { /* row b0 - 1: row 0 of boundary b0's block */
        const float *e = j->fedge + (long)(b0 / j->band - 1) * planes * es;
        for (int p = 0; p < planes; p++) memcpy(buf + p * ps, e + p * es, sizeof(float) * (size_t)w);
    }
    if (b1 < j->h) { /* row b1: row 1 of boundary b1's block */
        const float *e = j->fedge + (long)(b1 / j->band - 1) * planes * es;
        for (int p = 0; p < planes; p++)
            memcpy(buf + p * ps + (long)(b1 - b0 + 1) * w, e + p * es + w, sizeof(float) * (size_t)w);
    }
    t->down = buf;
    t->attr = buf + EW_BF_CH * ps;
    t->dps = ps;
    t->dy0 = b0 - 1;
}

/* Up(0) in bands (a->band rows, one buffer a thread): each band's rows are
 * written and drained by one thread, into its own buffer, so the result
 * never needs a whole frame of planes. The rows are split on the bands'
 * boundaries whatever the chunks (one thread runs every row in one chunk);
 * every pixel is computed as without bands. */
static inline void up_rows_banded(const ew_pyr_up_args *j, int64_t begin, int64_t end, const int kind, int tid) {
    if (!j->band) {
        up_rows_body(j, begin, end, kind, tid);
        return;
    }
    for (int64_t b = begin; b < end;) {
        const int64_t b0 = b - b % j->band, e = b0 + j->band < end ? b0 + j->band : end;
        ew_pyr_up_args t = *j;
        t.band = 0;
        t.up = j->up + (long)tid * j->band_stride;
        t.up_y0 = (int)b0;
        t.up_ps = (long)j->band * j->w;
        if (j->fbuf_stride) band_input(j, (int)b0, tid, &t);
        up_rows_body(&t, b, e, kind, tid);
        b = e;
    }
}

EW_ROWS_PER_KIND(up_rows, ew_pyr_up_args, up_rows_banded(j, begin, end, kind, tid);, EW_FLATTEN)

void ew_cpu_pyr_up(ew_device *dev, const ew_pyr_up_args *a) {
    ew_pool_run(dev->pool, a->h, a->band, up_rows(a->m->kind), (void *)a);
}

typedef struct {
    const ew_dof_args *a;
    int step;
} dof_job;

static EW_ROW_FN void dof_rows(void *ctx, int64_t begin, int64_t end, int tid) {
    (void)tid;
    const dof_job *j = (const dof_job *)ctx;
    const ew_dof_args *a = j->a;
    const int W = a->cam.width;
    for (int64_t y = begin; y < end; y++) {
        switch (j->step) {
        case 0:
            for (int x = 0; x < W; x++) ew_dof_coc_px((long)y * W + x, a);
            break;
        case 1:
            for (int x = 0; x < a->tw; x++) ew_dof_tile_px(x, (int)y, a);
            break;
        case 2:
        case 3:
            for (int x = 0; x < a->tw; x++) ew_dof_scatter_px(x, (int)y, j->step - 2, a);
            break;
        default:
            if (a->planes)
                for (int x = 0; x < W; x++) ew_dof_attr_px_k(x, (int)y, a, 1);
            else
                for (int x = 0; x < W; x++) ew_dof_attr_px_k(x, (int)y, a, 0);
            break;
        }
    }
}

void ew_cpu_dof_attributes(ew_device *dev, const ew_dof_args *a) {
    for (int step = 0; step < (a->attr ? 5 : 4); step++) { /* no attr: step 5 is the caller's (ew_dof_attr_rows) */
        dof_job j = {a, step};
        int64_t rows = step == 0 || step == 4 ? a->cam.height : a->th;
        ew_pool_run(dev->pool, rows, 0, dof_rows, &j);
    }
}
