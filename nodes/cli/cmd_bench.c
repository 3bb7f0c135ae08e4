/*
 * edgewise bench — every method over a directory of Cycles renders with
 * references: PSNR, SSIM, relMSE, SMAPE and ms per frame, as CSV (and PNG
 * images for the report page). tools/bench_report.py draws the charts.
 */
#include <dirent.h>
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "frame_energy.h"
#include "method_run.h"

static const char help[] =
    "usage: edgewise bench DATA_DIR -o OUT_DIR [options]\n"
    "\n"
    "Run every method over the renders in DATA_DIR (one folder per scene holding\n"
    "fNNNN_sppSSSS.exr inputs and an fNNNN_refRRRR.exr reference, as written by\n"
    "tools/blender/render_scene.py) and write OUT_DIR/results.csv with scene, spp,\n"
    "method, PSNR, SSIM (tone-mapped), relMSE, SMAPE (linear) and ms per frame\n"
    "(the fastest of --repeat runs, file I/O excluded), lum_ratio (the output's\n"
    "mean luminance over the reference's) and peak (the largest ratio of an\n"
    "output pixel's luminance to the reference's largest within 5 pixels). Then run\n"
    "tools/bench_report.py OUT_DIR for the charts and the HTML page.\n"
    "\n"
    "options:\n"
    "  -o, --output DIR     where results go (created)\n"
    "  --spp LIST           sample counts to use, e.g. 1,4 (default: 1,4,16,64)\n"
    "  --scenes LIST        only scene folders whose name contains one of these\n"
    "  --frames N           frames per scene (default 1)\n"
    "  --methods LIST       only these methods (labels as listed by --list)\n"
    "  --repeat N           timing runs per method (default 3)\n"
    "  --threads N          worker threads, 0 = all cores (default 0)\n"
    "  --images             also write PNGs (input, outputs, reference, error maps)\n"
    "  --temporal           sequences instead of frames: OUT_DIR/temporal.csv (see below)\n"
    "  --list               print the methods and exit\n"
    "  --no-harm            every method without the do-no-harm stage (do_no_harm 0,\n"
    "                       outlier_k 0: the methods' own outputs, for before/after)\n"
    "\n"
    "Methods named 'outlier+M' run the library's filter 'outlier' (firefly\n"
    "suppression with albedo/normal similarity) on the colour first, then M;\n"
    "'outlier-blind+M' the same filter without the features; the time is the sum.\n"
    "\n"
    "--temporal: every scene folder with two or more frames (fNNNN_spp*.exr with\n"
    "fNNNN_ref*.exr; g_anim renders) at each --spp (default 1,4). Each method\n"
    "runs frame by frame with each accumulation mode:\n"
    "  off           the method alone;\n"
    "  after         the filter 'temporal' on the method's output (reprojected\n"
    "                along the Vector pass, normal/depth rejection, alpha 0.2);\n"
    "  after-demod   the same on the output divided by albedo + 0.01, multiplied\n"
    "                back with the frame's albedo;\n"
    "  after-demod-clamp  the same with the history clamped to the frame's 3x3\n"
    "                mean +- 1 sigma (the temporal filter's 'clamp' parameter);\n"
    "  before-demod  'temporal' on the noisy demodulated colour, then the method.\n"
    "Columns: scene, spp, method, accumulation, frames, PSNR/SSIM (mean over\n"
    "frames), tdiff (mean |frame-to-frame change| of the tone-mapped output),\n"
    "tdiff_ref (of the reference), tdiff_excess (the difference: flicker the\n"
    "method adds), flicker_static (tdiff over static pixels: reference change\n"
    "< 0.02 and motion < 0.5 px), static_frac, ms per frame (fastest of\n"
    "--repeat runs of the sequence; ew_image_temporal_diff in edgewise.h).\n";

#define MAX_METHODS 48

static int n_specs;
static ew_method_spec specs[MAX_METHODS];
/* A pre-filter step run on the colour before specs[m] (ew_method_spec
 * has none; NULL: none). Its time counts in the method's. */
static const ew_method_spec *prefilter[MAX_METHODS];
static ew_method_spec outlier_spec, outlier_blind_spec;

static ew_method_spec *add(const char *label, const char *kind, const char *name, int demod) {
    if (n_specs >= MAX_METHODS) return NULL;
    prefilter[n_specs] = NULL;
    ew_method_spec *s = &specs[n_specs++];
    memset(s, 0, sizeof *s);
    s->label = label;
    s->kind = kind;
    s->name = name;
    s->demodulate = demod;
    return s;
}

static void param(ew_method_spec *s, const char *name, float v) {
    if (!s || s->num_params >= EW_RUN_MAX_PARAMS) return;
    s->param_names[s->num_params] = name;
    s->param_values[s->num_params++] = v;
}

static int has_method(const char *kind, const char *name) {
    for (int32_t i = 0; i < ew_method_count(kind); i++) {
        const char *nm;
        ew_method_get(kind, i, &nm, NULL, NULL, NULL);
        if (!strcmp(nm, name)) return 1;
    }
    return 0;
}

/* The methods compared: whatever this build of the library offers. */
static void build_specs(void) {
    add("input", NULL, NULL, 0);
    ew_method_spec *s = add("bgrid-features", "denoiser", "bgrid", 0);
    param(s, "color_weight", 0.0f);
    add("bgrid", "denoiser", "bgrid", 0);
    if (has_method("denoiser", "nbg")) {
        add("nbg", "denoiser", "nbg", 0); /* built-in model 0: 2layer-3grid */
        static const struct { const char *label; int model; } models[] = {
            {"nbg-1grid", 1}, {"nbg-7layer", 2}, {"nbg-1spp", 3}};
        for (size_t k = 0; k < sizeof models / sizeof models[0]; k++) {
            s = add(models[k].label, "denoiser", "nbg", 0);
            param(s, "model", (float)models[k].model);
        }
    }
    if (has_method("denoiser", "kpcn")) {
        add("kpcn", "denoiser", "kpcn", 0); /* built-in model 0 */
        s = add("kpcn-small", "denoiser", "kpcn", 0);
        param(s, "model", 1.0f);
        s = add("kpcn-large", "denoiser", "kpcn", 0);
        param(s, "model", 2.0f);
    }
    if (has_method("denoiser", "auto")) {
        add("auto", "denoiser", "auto", 0); /* the sample count from the file's Cycles metadata */
        s = add("auto-fast", "denoiser", "auto", 0); /* quality fast: grids and nbg only */
        param(s, "quality", 0.0f);
        s = add("auto-high", "denoiser", "auto", 0); /* quality high: up to the large kpcn */
        param(s, "quality", 2.0f);
        s = add("auto-noise", "denoiser", "auto", 0); /* as if the count were unknown: the noise estimate */
        param(s, "samples", 0.0f);
    }
    if (has_method("filter", "atrous")) add("atrous", "filter", "atrous", 1);
    if (has_method("filter", "pyramid")) {
        s = add("pyramid-gi", "filter", "pyramid", 1);
        param(s, "model", 1.0f);
    }
    if (has_method("filter", "bilateral")) {
        s = add("bilateral-gi", "filter", "bilateral", 1);
        param(s, "model", 1.0f);
    }
    /* firefly / outlier suppression as a node before a method
     * (with the features, and without them to show what they are for) */
    if (has_method("filter", "outlier")) {
        memset(&outlier_spec, 0, sizeof outlier_spec);
        outlier_spec.label = "outlier";
        outlier_spec.kind = "filter";
        outlier_spec.name = "outlier";
        outlier_blind_spec = outlier_spec;
        outlier_blind_spec.label = "outlier-blind";
        param(&outlier_blind_spec, "albedo_tol", 1e4f);
        param(&outlier_blind_spec, "normal_cos", -1.0f);
        add("outlier", "filter", "outlier", 0);
        s = add("outlier-blind", "filter", "outlier", 0);
        param(s, "albedo_tol", 1e4f);
        param(s, "normal_cos", -1.0f);
        static const struct { const char *label, *base; int blind; } chains[] = {
            {"outlier+bgrid", "bgrid", 0},           {"outlier-blind+bgrid", "bgrid", 1},
            {"outlier+nbg", "nbg", 0},               {"outlier+auto", "auto", 0},
            {"outlier+pyramid-gi", "pyramid-gi", 0}, {"outlier-blind+pyramid-gi", "pyramid-gi", 1},
        };
        for (size_t c = 0; c < sizeof chains / sizeof chains[0]; c++) {
            int b = -1;
            for (int m = 0; m < n_specs; m++)
                if (!strcmp(specs[m].label, chains[c].base) && !prefilter[m]) b = m;
            if (b < 0 || n_specs >= MAX_METHODS) continue;
            ew_method_spec base = specs[b];
            s = &specs[n_specs];
            *s = base;
            s->label = chains[c].label;
            prefilter[n_specs++] = chains[c].blind ? &outlier_blind_spec : &outlier_spec;
        }
    }
}

/* --no-harm: every method without the do-no-harm stage (src/harm_stage.c) */
static void strip_stage(void) {
    for (int m = 0; m < n_specs; m++) {
        ew_param_info p;
        int has = 0;
        for (int32_t k = 0; specs[m].kind && ew_method_param(specs[m].kind, specs[m].name, k, &p) == EW_OK; k++)
            has |= !strcmp(p.name, "do_no_harm");
        if (!has) continue;
        param(&specs[m], "do_no_harm", 0.0f);
        param(&specs[m], "outlier_k", 0.0f);
    }
}

/* specs[m] on the layer, after its pre-filter if it has one. */
static int run_method(ew_device *dev, int m, const ew_layer_data *ld, float *out, double *ms, char *err, size_t errlen) {
    if (!prefilter[m]) return ew_method_run(dev, &specs[m], ld, out, ms, err, errlen);
    const size_t n = (size_t)ld->width * ld->height * 3;
    float *pre = (float *)malloc(n * sizeof(float));
    if (!pre) {
        snprintf(err, errlen, "out of memory");
        return 1;
    }
    double ms_pre = 0.0;
    int r = ew_method_run(dev, prefilter[m], ld, pre, &ms_pre, err, errlen);
    if (r == 0) {
        ew_layer_data l2 = *ld;
        l2.color = pre;
        r = ew_method_run(dev, &specs[m], &l2, out, ms, err, errlen);
        *ms += ms_pre;
    }
    free(pre);
    return r;
}

static int in_list(const char *list, const char *name, int substring) {
    if (!list) return 1;
    char buf[1024];
    snprintf(buf, sizeof buf, "%s", list);
    char *save = NULL;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save))
        if (substring ? strstr(name, tok) != NULL : !strcmp(name, tok)) return 1;
    return 0;
}

/* snprintf for paths: a path too long for the buffer is an error, not a
 * silently shortened name (vsnprintf also keeps gcc's truncation analysis,
 * which cannot know directory-name lengths, quiet). */
static int fmt_path(char *dst, size_t n, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int fmt_path(char *dst, size_t n, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(dst, n, fmt, ap);
    va_end(ap);
    return k >= 0 && (size_t)k < n;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* The reference of frame `frame` in dir: fNNNN_ref*.exr (first match). */
static int find_ref(const char *dir, int frame, char *out, size_t len) {
    DIR *d = opendir(dir);
    if (!d) return 0;
    char prefix[32];
    snprintf(prefix, sizeof prefix, "f%04d_ref", frame);
    struct dirent *e;
    int found = 0;
    while (!found && (e = readdir(d)))
        if (!strncmp(e->d_name, prefix, strlen(prefix)) && strstr(e->d_name, ".exr")) {
            fmt_path(out, len, "%s/%s", dir, e->d_name);
            found = 1;
        }
    closedir(d);
    return found;
}

static float tm(float v) { return v > 0.0f ? (v < 1.0f ? powf(v, 1.0f / 2.2f) : 1.0f) : 0.0f; }

static void write_png(const char *path, const float *rgb, const float *ref, int w, int h) {
    char err[512];
    ewio_file *f;
    if (ewio_create(w, h, &f, err, sizeof err) != 0) return;
    float *buf = (float *)malloc(sizeof(float) * w * h * 3);
    if (!buf) { ewio_free(f); return; }
    for (int i = 0; i < w * h * 3; i++) {
        float v = isfinite(rgb[i]) ? rgb[i] : 0.0f;
        buf[i] = ref ? fminf(4.0f * fabsf(tm(v) - tm(ref[i])), 1.0f) : tm(v);
    }
    if (ewio_set_pass(f, "", "", "RGB", buf, err, sizeof err) != 0 || ewio_write(f, path, EWIO_KEEP, "", "", err, sizeof err) != 0)
        fprintf(stderr, "edgewise: %s\n", err);
    free(buf);
    ewio_free(f);
}

/* ---- --temporal: sequences -------------------------------------------- */

#define MAX_FRAMES 64

enum { ACC_OFF, ACC_AFTER, ACC_AFTER_DEMOD, ACC_AFTER_CLAMP, ACC_BEFORE_DEMOD, ACC_MODES };
static const char *const acc_names[ACC_MODES] = {"off", "after", "after-demod", "after-demod-clamp", "before-demod"};
#define BENCH_TEMPORAL_CLAMP 1.0f /* "after-demod-clamp": the temporal filter's history clamp, in sigmas */

typedef struct {
    int n, w, h;
    ew_layer_data ld[MAX_FRAMES];
    float *ref[MAX_FRAMES];
} sequence;

static void sequence_free(sequence *q) {
    for (int t = 0; t < q->n; t++) {
        ew_layer_data_free(&q->ld[t]);
        free(q->ref[t]);
    }
    q->n = 0;
}

/* Frames 1, 2, ... of dir at spp, up to the first one without an input or
 * a reference. Returns the number of frames read. */
static int sequence_read(const char *dir, int spp, sequence *q) {
    memset(q, 0, sizeof *q);
    for (int frame = 1; frame <= MAX_FRAMES; frame++) {
        char refpath[4096], in[4096], err[1024] = "";
        struct stat st;
        if (!find_ref(dir, frame, refpath, sizeof refpath)) break;
        if (!fmt_path(in, sizeof in, "%s/f%04d_spp%04d.exr", dir, frame, spp) || stat(in, &st) != 0) break;
        ewio_file *rf = NULL, *f = NULL;
        if (ewio_read(refpath, &rf, err, sizeof err) != 0) {
            fprintf(stderr, "edgewise: %s\n", err);
            break;
        }
        float *ref = cli_read_color(rf, NULL, err, sizeof err);
        const int w = ewio_width(rf), h = ewio_height(rf);
        ewio_free(rf);
        ew_layer_passes lp;
        int bad = !ref || (q->n && (w != q->w || h != q->h));
        if (!bad)
            bad = ewio_read(in, &f, err, sizeof err) != 0 || ewio_width(f) != w || ewio_height(f) != h ||
                  ew_find_layer_passes(f, ewio_layer_name(f, 0), &lp, err, sizeof err) != 0 ||
                  ew_layer_data_read(f, &lp, &q->ld[q->n], err, sizeof err) != 0;
        ewio_free(f);
        if (bad) {
            fprintf(stderr, "edgewise: %s: %s\n", in, err[0] ? err : "size differs");
            free(ref);
            break;
        }
        q->ref[q->n] = ref;
        q->w = w;
        q->h = h;
        q->n++;
    }
    return q->n;
}

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

/* As ew_method_run demodulates: a damaged or negative albedo counts as black. */
static float albedo_factor(const ew_layer_data *ld, size_t i) {
    if (!ld->albedo) return 1.0f;
    const float a = ld->albedo[i];
    return (isfinite(a) && a > 0.0f ? a : 0.0f) + EW_ALBEDO_EPSILON;
}

/* One frame of the filter "temporal" on buf, in place, with the frame's
 * normal, depth and motion vectors. */
static int temporal_step(ew_op *tf, float *buf, const ew_layer_data *ld, char *err, size_t errlen) {
    ew_image c = ew_image_packed(buf, ld->width, ld->height, 3);
    ew_image n = ew_image_packed(ld->normal, ld->width, ld->height, 3);
    ew_image d = ew_image_packed(ld->depth, ld->width, ld->height, 1);
    ew_image v = ew_image_packed(ld->vector, ld->width, ld->height, 2);
    ew_result r = ew_op_set_image(tf, "color", &c);
    if (r == EW_OK) r = ew_op_set_image(tf, "output", &c);
    if (r == EW_OK) r = ew_op_set_image(tf, "normal", ld->normal ? &n : NULL);
    if (r == EW_OK) r = ew_op_set_image(tf, "depth", ld->depth ? &d : NULL);
    if (r == EW_OK) r = ew_op_set_image(tf, "vector", ld->vector ? &v : NULL);
    if (r == EW_OK) r = ew_op_commit(tf);
    if (r == EW_OK) r = ew_op_execute(tf);
    if (r != EW_OK) snprintf(err, errlen, "temporal: %s", ew_result_string(r));
    return r != EW_OK;
}

/* specs[m] over the sequence with accumulation mode `mode` into outs[t];
 * *ms: the whole sequence's work (method, pre-filter, temporal filter,
 * demodulation), file I/O excluded. */
static int sequence_run(ew_device *dev, int m, int mode, const sequence *q, float **outs, double *ms, char *err,
                        size_t errlen) {
    const size_t n3 = (size_t)q->w * q->h * 3;
    ew_op *tf = NULL;
    float *tmp = (float *)malloc(n3 * sizeof(float));
    int fail = !tmp;
    if (fail) snprintf(err, errlen, "out of memory");
    if (!fail && mode != ACC_OFF && ew_op_create(dev, "temporal", &tf) != EW_OK) {
        snprintf(err, errlen, "temporal: %s", ew_device_last_error(dev));
        fail = 1;
    }
    if (!fail && mode == ACC_AFTER_CLAMP && ew_op_set_float(tf, "clamp", BENCH_TEMPORAL_CLAMP) != EW_OK) {
        snprintf(err, errlen, "temporal: %s", ew_device_last_error(dev));
        fail = 1;
    }
    *ms = 0.0;
    for (int t = 0; t < q->n && !fail; t++) {
        const ew_layer_data *ld = &q->ld[t];
        double mms = 0.0, t0;
        if (mode == ACC_BEFORE_DEMOD) {
            t0 = now_ms();
            for (size_t i = 0; i < n3; i++) tmp[i] = ld->color[i] / albedo_factor(ld, i);
            fail = temporal_step(tf, tmp, ld, err, errlen);
            for (size_t i = 0; i < n3; i++) tmp[i] *= albedo_factor(ld, i);
            *ms += now_ms() - t0;
            ew_layer_data l2 = *ld;
            l2.color = tmp;
            if (!fail) fail = run_method(dev, m, &l2, outs[t], &mms, err, errlen);
            *ms += mms;
            continue;
        }
        fail = run_method(dev, m, ld, outs[t], &mms, err, errlen);
        *ms += mms;
        if (fail || mode == ACC_OFF) continue;
        t0 = now_ms();
        const int demod = mode == ACC_AFTER_DEMOD || mode == ACC_AFTER_CLAMP;
        if (demod)
            for (size_t i = 0; i < n3; i++) outs[t][i] /= albedo_factor(ld, i);
        fail = temporal_step(tf, outs[t], ld, err, errlen);
        if (demod)
            for (size_t i = 0; i < n3; i++) outs[t][i] *= albedo_factor(ld, i);
        *ms += now_ms() - t0;
    }
    ew_op_destroy(tf);
    free(tmp);
    return fail;
}

static int bench_temporal(ew_device *dev, const char *data, char **names, int n_names, const char *spp_list,
                          const char *methods, int repeat, const char *outdir) {
    char path[4096];
    fmt_path(path, sizeof path, "%s/temporal.csv", outdir);
    FILE *csv = fopen(path, "w");
    if (!csv) return cli_fail("cannot write '%s': %s", path, strerror(errno));
    fprintf(csv, "scene,spp,method,accumulation,frames,psnr,ssim,tdiff,tdiff_ref,tdiff_excess,flicker_static,"
                 "static_frac,ms,width,height,threads\n");
    int rows = 0, failures = 0;
    static sequence q;
    float *outs[MAX_FRAMES];
    for (int s = 0; s < n_names; s++) {
        char dir[4096];
        fmt_path(dir, sizeof dir, "%s/%s", data, names[s]);
        char spps[256];
        snprintf(spps, sizeof spps, "%s", spp_list);
        char *save = NULL;
        for (char *tok = strtok_r(spps, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
            const int spp = atoi(tok);
            if (sequence_read(dir, spp, &q) < 2) {
                sequence_free(&q);
                continue;
            }
            const size_t n3 = (size_t)q.w * q.h * 3;
            int ok = 1;
            for (int t = 0; t < q.n; t++) ok &= (outs[t] = (float *)malloc(n3 * sizeof(float))) != NULL;
            for (int m = 0; ok && m < n_specs; m++) {
                if (!in_list(methods, specs[m].label, 0)) continue;
                for (int mode = 0; mode < ACC_MODES; mode++) {
                    if (!specs[m].kind && mode == ACC_BEFORE_DEMOD) continue; /* = after-demod for the input */
                    double best = 1e30, ms = 0.0;
                    char err[1024] = "";
                    int fail = 0;
                    for (int k = 0; k < repeat && !fail; k++) {
                        fail = sequence_run(dev, m, mode, &q, outs, &ms, err, sizeof err);
                        if (ms < best) best = ms;
                    }
                    if (fail) {
                        fprintf(stderr, "edgewise: %s %d spp %s %s: %s\n", names[s], spp, specs[m].label,
                                acc_names[mode], err);
                        failures++;
                        continue;
                    }
                    double psnr = 0, ssim = 0, td = 0, tr = 0, ex = 0, fs = 0;
                    int64_t ns = 0;
                    for (int t = 0; t < q.n; t++) {
                        ew_image vo = ew_image_packed(outs[t], q.w, q.h, 3), vr = ew_image_packed(q.ref[t], q.w, q.h, 3);
                        double p, ss;
                        ew_image_psnr(dev, &vo, &vr, &p);
                        ew_image_ssim(dev, &vo, &vr, &ss);
                        psnr += fmin(p, 100.0) / q.n;
                        ssim += ss / q.n;
                        if (t == 0) continue;
                        ew_image vp = ew_image_packed(outs[t - 1], q.w, q.h, 3);
                        ew_image rp = ew_image_packed(q.ref[t - 1], q.w, q.h, 3);
                        ew_image vv = ew_image_packed(q.ld[t].vector, q.w, q.h, 2);
                        ew_temporal_diff d;
                        if (ew_image_temporal_diff(dev, &vp, &vo, &rp, &vr, q.ld[t].vector ? &vv : NULL, 0.02f, &d) !=
                            EW_OK)
                            continue;
                        td += d.test / (q.n - 1);
                        tr += d.reference / (q.n - 1);
                        ex += d.excess / (q.n - 1);
                        fs += d.static_flicker * (double)d.static_pixels;
                        ns += d.static_pixels;
                    }
                    const double frac = (double)ns / ((double)(q.n - 1) * q.w * q.h);
                    const double per_frame = specs[m].kind || mode != ACC_OFF ? best / q.n : 0.0;
                    fprintf(csv, "%s,%d,%s,%s,%d,%.4f,%.5f,%.6f,%.6f,%.6f,%.6f,%.5f,%.3f,%d,%d,%d\n", names[s], spp,
                            specs[m].label, acc_names[mode], q.n, psnr, ssim, td, tr, ex, ns ? fs / (double)ns : 0.0,
                            frac, per_frame, q.w, q.h, ew_device_get_num_threads(dev));
                    fflush(csv);
                    rows++;
                    fprintf(stderr, "[%d/%d] %-22s %d spp %-20s %-12s PSNR %6.2f excess %.5f static %.5f %7.1f ms\n",
                            s + 1, n_names, names[s], spp, specs[m].label, acc_names[mode], psnr, ex,
                            ns ? fs / (double)ns : 0.0, per_frame);
                }
            }
            for (int t = 0; t < q.n; t++) free(outs[t]);
            if (!ok) failures++;
            sequence_free(&q);
        }
    }
    fclose(csv);
    if (rows == 0)
        return cli_fail("no sequences (two or more frames with references) found in '%s'", data);
    fprintf(stderr, "edgewise: %d rows in %s/temporal.csv%s\n", rows, outdir,
            failures ? " (some methods failed, see above)" : "");
    return 0;
}

int cmd_bench(int argc, char **argv) {
    const char *data = NULL, *outdir = NULL, *spp_list = "1,4,16,64", *scenes = NULL, *methods = NULL;
    int repeat = 3, threads = 0, images = 0, list = 0, frames = 1, temporal = 0, spp_given = 0, no_harm = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(help, stdout); return 0; }
        else if (!strcmp(a, "--images")) images = 1;
        else if (!strcmp(a, "--list")) list = 1;
        else if (!strcmp(a, "--temporal")) temporal = 1;
        else if (!strcmp(a, "--no-harm")) no_harm = 1;
        else if (!v && a[0] == '-') { fprintf(stderr, "edgewise: %s needs a value\n", a); return EW_EXIT_USAGE; }
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) outdir = argv[++i];
        else if (!strcmp(a, "--spp")) { spp_list = argv[++i]; spp_given = 1; }
        else if (!strcmp(a, "--scenes")) scenes = argv[++i];
        else if (!strcmp(a, "--methods")) methods = argv[++i];
        else if (!strcmp(a, "--repeat")) { if (!cli_parse_int(a, argv[++i], 1, 100, &repeat)) return EW_EXIT_USAGE; }
        else if (!strcmp(a, "--frames")) { if (!cli_parse_int(a, argv[++i], 1, 100000, &frames)) return EW_EXIT_USAGE; }
        else if (!strcmp(a, "--threads")) { if (!cli_parse_int(a, argv[++i], 0, 1024, &threads)) return EW_EXIT_USAGE; }
        else if (a[0] == '-') { fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise bench --help')\n", a); return EW_EXIT_USAGE; }
        else if (!data) data = a;
        else { fprintf(stderr, "edgewise: unexpected argument '%s'\n", a); return EW_EXIT_USAGE; }
    }
    build_specs();
    if (no_harm) strip_stage();
    if (list) {
        for (int m = 0; m < n_specs; m++) printf("%s\n", specs[m].label);
        return 0;
    }
    if (!data || !outdir) { fprintf(stderr, "usage: edgewise bench DATA_DIR -o OUT_DIR (see --help)\n"); return EW_EXIT_USAGE; }
    if (strlen(data) > 2048 || strlen(outdir) > 2048) return cli_fail("path too long");
    if (mkdir(outdir, 0777) != 0 && errno != EEXIST) return cli_fail("cannot create '%s': %s", outdir, strerror(errno));
    char path[4096];
    if (images) {
        fmt_path(path, sizeof path, "%s/img", outdir);
        if (mkdir(path, 0777) != 0 && errno != EEXIST) return cli_fail("cannot create '%s': %s", path, strerror(errno));
    }

    DIR *d = opendir(data);
    if (!d) return cli_fail("cannot read the directory '%s': %s", data, strerror(errno));
    char *names[4096];
    int n_names = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n_names < 4096)
        if (e->d_name[0] != '.' && in_list(scenes, e->d_name, 1)) names[n_names++] = strdup(e->d_name);
    closedir(d);
    qsort(names, (size_t)n_names, sizeof names[0], cmp_str);
    if (temporal) {
        ew_device *tdev = cli_device(threads, 0);
        int rc = tdev ? bench_temporal(tdev, data, names, n_names, spp_given ? spp_list : "1,4", methods, repeat, outdir)
                      : EW_EXIT_FAIL;
        ew_device_destroy(tdev);
        for (int s = 0; s < n_names; s++) free(names[s]);
        return rc;
    }

    fmt_path(path, sizeof path, "%s/results.csv", outdir);
    FILE *csv = fopen(path, "w");
    if (!csv) return cli_fail("cannot write '%s': %s", path, strerror(errno));
    fprintf(csv, "scene,frame,spp,method,psnr,ssim,relmse,smape,ms,width,height,threads,lum_ratio,peak\n");
    ew_device *dev = cli_device(threads, 0);
    if (!dev) { fclose(csv); return EW_EXIT_FAIL; }
    int rows = 0, failures = 0;
    for (int s = 0; s < n_names; s++) {
        char dir[4096];
        fmt_path(dir, sizeof dir, "%s/%s", data, names[s]);
        for (int frame = 1; frame <= frames; frame++) {
            char refpath[4096], err[1024] = "";
            if (!find_ref(dir, frame, refpath, sizeof refpath)) continue;
            ewio_file *rf = NULL;
            if (ewio_read(refpath, &rf, err, sizeof err) != 0) { fprintf(stderr, "edgewise: skipping: %s\n", err); continue; }
            float *ref = cli_read_color(rf, NULL, err, sizeof err);
            int w = ewio_width(rf), h = ewio_height(rf);
            ewio_free(rf);
            if (!ref) { fprintf(stderr, "edgewise: skipping %s: %s\n", refpath, err); continue; }
            if (images) {
                fmt_path(path, sizeof path, "%s/img/%s_f%04d_ref.png", outdir, names[s], frame);
                write_png(path, ref, NULL, w, h);
            }
            char spps[256];
            snprintf(spps, sizeof spps, "%s", spp_list);
            char *save = NULL;
            for (char *tok = strtok_r(spps, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
                int spp = atoi(tok);
                char in[4096];
                fmt_path(in, sizeof in, "%s/f%04d_spp%04d.exr", dir, frame, spp);
                struct stat st;
                if (stat(in, &st) != 0) continue;
                ewio_file *f = NULL;
                ew_layer_passes lp;
                ew_layer_data ld;
                if (ewio_read(in, &f, err, sizeof err) != 0 || ewio_width(f) != w || ewio_height(f) != h ||
                    ew_find_layer_passes(f, ewio_layer_name(f, 0), &lp, err, sizeof err) != 0 ||
                    ew_layer_data_read(f, &lp, &ld, err, sizeof err) != 0) {
                    fprintf(stderr, "edgewise: skipping %s: %s\n", in, err[0] ? err : "size differs from the reference");
                    ewio_free(f);
                    continue;
                }
                ewio_free(f);
                float *out = (float *)malloc(sizeof(float) * w * h * 3);
                for (int m = 0; out && m < n_specs; m++) {
                    if (!in_list(methods, specs[m].label, 0)) continue;
                    double best = 1e30, ms = 0;
                    int ok = 1;
                    for (int k = 0; k < repeat && ok; k++) {
                        err[0] = '\0';
                        ok = run_method(dev, m, &ld, out, &ms, err, sizeof err) == 0;
                        if (ms < best) best = ms;
                    }
                    if (!ok) {
                        fprintf(stderr, "edgewise: %s %d spp: %s\n", names[s], spp, err);
                        failures++;
                        continue;
                    }
                    ew_image vo = ew_image_packed(out, w, h, 3), vr = ew_image_packed(ref, w, h, 3);
                    double psnr, ssim, rel, smape;
                    ew_image_psnr(dev, &vo, &vr, &psnr);
                    ew_image_ssim(dev, &vo, &vr, &ssim);
                    ew_image_relmse(dev, &vo, &vr, &rel);
                    ew_image_smape(dev, &vo, &vr, &smape);
                    const double lum_ratio =
                        ew_frame_mean_lum(out, (size_t)w * h) / ew_frame_mean_lum(ref, (size_t)w * h);
                    fprintf(csv, "%s,%d,%d,%s,%.4f,%.5f,%.6g,%.6g,%.3f,%d,%d,%d,%.4f,%.3f\n", names[s], frame, spp,
                            specs[m].label, psnr, ssim, rel, smape, specs[m].kind ? best : 0.0, w, h,
                            ew_device_get_num_threads(dev), lum_ratio, ew_frame_peak_ratio(out, ref, w, h, 5));
                    fflush(csv);
                    rows++;
                    fprintf(stderr, "[%d/%d] %-28s %3d spp %-16s PSNR %6.2f SSIM %.4f %8.2f ms\n", s + 1, n_names,
                            names[s], spp, specs[m].label, psnr, ssim, specs[m].kind ? best : 0.0);
                    if (images) {
                        fmt_path(path, sizeof path, "%s/img/%s_f%04d_spp%04d_%s.png", outdir, names[s], frame, spp, specs[m].label);
                        write_png(path, out, NULL, w, h);
                        fmt_path(path, sizeof path, "%s/img/%s_f%04d_spp%04d_%s_err.png", outdir, names[s], frame, spp, specs[m].label);
                        write_png(path, out, ref, w, h);
                    }
                }
                free(out);
                ew_layer_data_free(&ld);
            }
            free(ref);
        }
    }
    for (int s = 0; s < n_names; s++) free(names[s]);
    fclose(csv);
    ew_device_destroy(dev);
    if (rows == 0) return cli_fail("no renders with references found in '%s' (expected <scene>/f0001_spp0001.exr and f0001_ref*.exr)", data);
    fprintf(stderr, "edgewise: %d rows in %s/results.csv%s\n", rows, outdir, failures ? " (some methods failed, see above)" : "");
    return 0;
}
