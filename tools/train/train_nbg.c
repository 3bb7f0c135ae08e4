/*
 * train_nbg — train, evaluate and embed neural bilateral grid models.
 *
 *   train_nbg --data DIR --arch 2layer-3grid --out MODEL.ewm [options]
 *   train_nbg --data DIR --eval MODEL.ewm [--split test|val|train]
 *   train_nbg --emit-c MODELDIR > core/algorithms/nbg_weights_data.c
 *
 * DIR holds one folder per scene, <family>_<name>_<seed>_<W>x<H>/, with
 * fNNNN_sppSSSS.exr noisy renders and fNNNN_ref1024.exr references (see
 * ../shared/data/cycles-train/README.md). Whole scenes are held out: per
 * family, scenes sorted by seed, the last is a test scene and, in families
 * of four or more, the one before it a validation scene; the rest train.
 * Test scenes are never read while training.
 *
 * Training: Adam on the mean gradient of --batch patches of --patch pixels
 * (random crop + one of the 8 symmetries of the square), a cosine learning
 * rate from --lr to --lr-final, gradients clipped to global norm --clip
 * (each clipped step is logged). Every --val-every steps: PSNR/SSIM of the
 * model on the validation scenes through the library's "nbg" op (the model
 * that ships is the model measured), a line on stdout, a row in OUT.csv and
 * a chart OUT.svg. A checkpoint (weights + Adam state + step) is written
 * atomically every --checkpoint-minutes and at the end; --resume continues
 * from it bit for bit: patches are a function of (seed, step, index), and a
 * step's gradient does not depend on the thread count.
 */
#include <dirent.h>
#include <getopt.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "backends/cpu/cpu_conv.h"
#include "algorithms/nbg.h"
#include "algorithms/train.h"
#include "cycles_passes.h"
#include "edgewise/edgewise.h"
#include "ewio.h"
#include "src/internal.h"
#include "src/weights.h"
#include "train_common.h"

#define MAX_SCENES 256
#define MAX_FRAMES 4096

static const char usage[] =
    "usage: train_nbg --data DIR --arch ARCH --out MODEL.ewm [options]\n"
    "       train_nbg --data DIR --eval MODEL.ewm [--split test|val|train] [--spp LIST]\n"
    "       train_nbg --emit-c MODELDIR\n"
    "       train_nbg --bench [--size WxH] [--models DIR] [--data DIR] [--threads N]\n"
    "\n"
    "  --arch A              2layer-1grid, 2layer-3grid, 7layer-1grid, 7layer-3grid\n"
    "  --seed N              initialisation and patch sampling (default 1)\n"
    "  --steps N             Adam steps (default 6000)\n"
    "  --batch N             patches per step (default 8)\n"
    "  --patch N             patch side in pixels (default 128)\n"
    "  --lr X, --lr-final X  cosine learning-rate schedule (default 1e-3 -> 1e-4)\n"
    "  --clip X              clip the gradient to this global L2 norm (default 0.05; 0: off)\n"
    "  --spp LIST            spp levels used, e.g. 1,4 (default: all)\n"
    "  --rates LIST          grid rates eta_s:eta_d per grid, e.g. 4:4,8:8,16:16\n"
    "  --init MODEL          start from these weights instead of random ones\n"
    "  --threads N           worker threads (default 0: all cores)\n"
    "  --val-every N         validate every N steps (default 250)\n"
    "  --checkpoint PATH     default MODEL.ckpt; --checkpoint-minutes M (default 5)\n"
    "  --resume              continue from the checkpoint if it exists\n"
    "  --stop-after N        checkpoint and stop at step N (the schedule stays --steps'; for\n"
    "                        testing that a resumed run matches an uninterrupted one)\n"
    "  --csv PATH, --svg PATH  validation curve (default MODEL.csv, MODEL.svg)\n"
    "  --split S             --eval: which scenes (default test)\n"
    "  --extra-train DIR     more scene folders, every one a training scene (never validation or\n"
    "                        test): e.g. tools/blender/make_dataset.sh -s train output\n"
    "  --bench               time every model at --size (default 1280x720): ms per frame, the share\n"
    "                        of GuideNet, its GFLOP/s against the measured FMA peak, memory at 4K\n";

/* ---- options ---------------------------------------------------------- */
typedef struct {
    const char *data, *arch, *out, *eval, *emit_c, *init, *rates, *split, *models;
    const char *extra_train; /* more scenes, all for training (e.g. the project's generator's train split) */
    int bench, bench_w, bench_h;
    char csv[1024], svg[1024];
    train_run_opts run;
    int spp_mask;
} options;

static int spp_bit(int spp) { return spp == 1 ? 1 : spp == 4 ? 2 : spp == 16 ? 4 : spp == 64 ? 8 : 0; }

static int parse_spp(const char *s, int *mask) {
    *mask = 0;
    while (*s) {
        char *end;
        long v = strtol(s, &end, 10);
        if (end == s || !spp_bit((int)v)) return 0;
        *mask |= spp_bit((int)v);
        s = *end == ',' ? end + 1 : end;
        if (*end && *end != ',') return 0;
    }
    return *mask != 0;
}

enum {
    OPT_DATA = TRAIN_OPT_OWN, OPT_EXTRA_TRAIN, OPT_ARCH, OPT_OUT, OPT_EVAL, OPT_EMIT_C, OPT_INIT, OPT_RATES,
    OPT_SPLIT, OPT_CSV, OPT_SVG, OPT_SPP, OPT_BENCH, OPT_MODELS, OPT_SIZE
};
static const struct option long_opts[] = {
    TRAIN_RUN_LONG_OPTS,
    {"data", required_argument, NULL, OPT_DATA}, {"extra-train", required_argument, NULL, OPT_EXTRA_TRAIN},
    {"arch", required_argument, NULL, OPT_ARCH}, {"out", required_argument, NULL, OPT_OUT},
    {"eval", required_argument, NULL, OPT_EVAL}, {"emit-c", required_argument, NULL, OPT_EMIT_C},
    {"init", required_argument, NULL, OPT_INIT}, {"rates", required_argument, NULL, OPT_RATES},
    {"split", required_argument, NULL, OPT_SPLIT}, {"csv", required_argument, NULL, OPT_CSV},
    {"svg", required_argument, NULL, OPT_SVG}, {"spp", required_argument, NULL, OPT_SPP},
    {"bench", no_argument, NULL, OPT_BENCH}, {"models", required_argument, NULL, OPT_MODELS},
    {"size", required_argument, NULL, OPT_SIZE}, {"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};

/* a path option into a fixed buffer: too long is an error, not a cut path */
static int set_path(const char *opt, const char *v, char *dst, size_t len) {
    if (snprintf(dst, len, "%s", v) < (int)len) return 1;
    fprintf(stderr, "train_nbg: %s: the path is too long\n", opt);
    return 0;
}

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->run.seed = 1;
    o->run.steps = 6000;
    o->run.batch = 8;
    o->run.patch = 128;
    o->run.lr = 1e-3;
    o->run.lr_final = 1e-4;
    o->run.clip = 0.05;
    o->run.val_every = 250;
    o->run.ckpt_minutes = 5;
    o->spp_mask = 15;
    o->split = "test";
    o->models = "models/nbg";
    o->bench_w = 1280;
    o->bench_h = 720;
    int c, ok = 1;
    opterr = 0;
    while (ok && (c = getopt_long(argc, argv, ":h", long_opts, NULL)) != -1) {
        const char *v = optarg, *a = argv[optind - 1];
        if (train_run_option(c, v, &o->run, &ok)) continue;
        switch (c) {
        case OPT_DATA: o->data = v; break;
        case OPT_EXTRA_TRAIN: o->extra_train = v; break;
        case OPT_ARCH: o->arch = v; break;
        case OPT_OUT: o->out = v; break;
        case OPT_EVAL: o->eval = v; break;
        case OPT_EMIT_C: o->emit_c = v; break;
        case OPT_INIT: o->init = v; break;
        case OPT_RATES: o->rates = v; break;
        case OPT_SPLIT: o->split = v; break;
        case OPT_CSV: ok = set_path("--csv", v, o->csv, sizeof o->csv); break;
        case OPT_SVG: ok = set_path("--svg", v, o->svg, sizeof o->svg); break;
        case OPT_SPP:
            if (!parse_spp(v, &o->spp_mask)) {
                fprintf(stderr, "train_nbg: --spp takes a list of 1, 4, 16, 64\n");
                ok = 0;
            }
            break;
        case OPT_BENCH: o->bench = 1; break;
        case OPT_MODELS: o->models = v; break;
        case OPT_SIZE: {
            char tail;
            if (sscanf(v, "%dx%d%c", &o->bench_w, &o->bench_h, &tail) != 2 || o->bench_w < 16 || o->bench_h < 16 ||
                o->bench_w > 16384 || o->bench_h > 16384) {
                fprintf(stderr, "train_nbg: --size WxH, each from 16 to 16384\n");
                ok = 0;
            }
            break;
        }
        default: ok = train_getopt_other(c, a, usage); break;
        }
    }
    if (!ok || !train_no_operands(argc, argv, usage)) return 0;
    if (o->emit_c || o->bench) return 1;
    if (!o->data) { fprintf(stderr, "train_nbg: --data DIR is required\n"); return 0; }
    if (o->eval) return 1;
    if (!o->arch || !o->out) { fprintf(stderr, "train_nbg: --arch and --out are required\n%s", usage); return 0; }
    if (o->run.batch < 1 || o->run.patch < 16 || o->run.steps < 1 || o->run.val_every < 1) {
        fprintf(stderr, "train_nbg: --batch >= 1, --patch >= 16, --steps >= 1, --val-every >= 1\n");
        return 0;
    }
    if (!o->run.checkpoint[0]) snprintf(o->run.checkpoint, sizeof o->run.checkpoint, "%s.ckpt", o->out);
    if (!o->csv[0]) snprintf(o->csv, sizeof o->csv, "%s.csv", o->out);
    if (!o->svg[0]) snprintf(o->svg, sizeof o->svg, "%s.svg", o->out);
    return 1;
}

/* ---- the data set ------------------------------------------------------- */
typedef struct {
    char name[256];
    char family[256];
    const char *dir; /* the data directory holding it */
    long seed;
    int split; /* 0 train, 1 val, 2 test */
} scene_info;

typedef struct {
    int scene, spp, frame_no, w, h;
    float *color, *albedo, *normal, *depth, *ref; /* kept for validation / evaluation */
} frame_info;

static const char *split_name(int s) { return s == 0 ? "train" : s == 1 ? "val" : "test"; }

static int cmp_scene(const void *a, const void *b) {
    const scene_info *x = (const scene_info *)a, *y = (const scene_info *)b;
    int c = strcmp(x->family, y->family);
    if (c) return c;
    return x->seed < y->seed ? -1 : x->seed > y->seed;
}

/* <family letter>_<name>_<seed>_<W>x<H> */
static int parse_scene_name(const char *n, scene_info *s) {
    const char *u1 = strchr(n, '_');
    if (!u1) return 0;
    const char *u2 = strchr(u1 + 1, '_');
    if (!u2) return 0;
    char *end;
    long seed = strtol(u2 + 1, &end, 10);
    if (end == u2 + 1 || *end != '_') return 0;
    snprintf(s->name, sizeof s->name, "%s", n);
    snprintf(s->family, sizeof s->family, "%.*s", (int)(u2 - n), n);
    s->seed = seed;
    return 1;
}

/* Scenes of dir: split by the rule below, or all training when all_train. */
static int list_scenes(const char *dir, scene_info *scenes, int max, int all_train) {
    DIR *d = opendir(dir);
    if (!d) {
        fprintf(stderr, "train_nbg: cannot open data directory '%s': %s\n", dir, strerror(errno));
        return -1;
    }
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < max) {
        if (e->d_name[0] == '.') continue;
        scene_info s;
        memset(&s, 0, sizeof s);
        s.dir = dir;
        if (parse_scene_name(e->d_name, &s)) scenes[n++] = s;
    }
    closedir(d);
    qsort(scenes, (size_t)n, sizeof *scenes, cmp_scene);
    if (all_train) return n; /* split 0 from the memset */
    /* the split: per family, by seed: last -> test, the one before -> val
     * when the family has >= 4 scenes */
    for (int i = 0; i < n;) {
        int j = i;
        while (j < n && !strcmp(scenes[j].family, scenes[i].family)) j++;
        int count = j - i;
        for (int k = i; k < j; k++) scenes[k].split = 0;
        if (count >= 2) scenes[j - 1].split = 2;
        if (count >= 4) scenes[j - 2].split = 1;
        i = j;
    }
    return n;
}


typedef struct {
    scene_info scenes[MAX_SCENES];
    int nscenes;
    frame_info frames[MAX_FRAMES];
    int nframes;
} dataset;

/* Load every frame of the scenes whose split is in split_mask (bit s) and
 * whose spp is in spp_mask. */
static int load_frames(dataset *ds, int split_mask, int spp_mask) {
    for (int si = 0; si < ds->nscenes; si++) {
        if (!(split_mask & (1 << ds->scenes[si].split))) continue;
        char sdir[4400];
        snprintf(sdir, sizeof sdir, "%s/%s", ds->scenes[si].dir, ds->scenes[si].name);
        DIR *d = opendir(sdir);
        if (!d) continue;
        char names[64][256];
        int nn = 0;
        struct dirent *e;
        while ((e = readdir(d)) && nn < 64)
            if (strstr(e->d_name, "_spp") && strstr(e->d_name, ".exr")) snprintf(names[nn++], 256, "%s", e->d_name);
        closedir(d);
        qsort(names, (size_t)nn, 256, (int (*)(const void *, const void *))strcmp);
        for (int k = 0; k < nn && ds->nframes < MAX_FRAMES; k++) {
            int fno = 0, spp = 0;
            if (sscanf(names[k], "f%d_spp%d.exr", &fno, &spp) != 2 || !(spp_mask & spp_bit(spp))) continue;
            frame_info *fi = &ds->frames[ds->nframes];
            memset(fi, 0, sizeof *fi);
            fi->scene = si;
            fi->spp = spp;
            fi->frame_no = fno;
            char path[4800], rpath[4800];
            if (snprintf(path, sizeof path, "%s/%s", sdir, names[k]) >= (int)sizeof path ||
                snprintf(rpath, sizeof rpath, "%s/f%04d_ref1024.exr", sdir, fno) >= (int)sizeof rpath)
                continue; /* (a path this long is not one of ours) */
            float *unused_a = NULL, *unused_n = NULL, *unused_d = NULL;
            int rw, rh;
            if (train_read_render(path, 1, &fi->w, &fi->h, &fi->color, &fi->albedo, &fi->normal, &fi->depth) != 0 ||
                train_read_render(rpath, 0, &rw, &rh, &fi->ref, &unused_a, &unused_n, &unused_d) != 0)
                return 1;
            if (rw != fi->w || rh != fi->h) {
                fprintf(stderr, "train_nbg: '%s' and its reference differ in size\n", path);
                return 1;
            }
            ds->nframes++;
        }
    }
    return 0;
}

/* ---- evaluation through the library's ops ---------------------------------- */
typedef struct {
    double psnr, ssim;
} quality;

/* method "nbg" with weights bytes, "bgrid" (defaults), or NULL: the input */
static int run_method(ew_device *dev, const frame_info *f, const char *method, const void *weights, size_t wsize,
                      float *out, quality *q) {
    ew_image c = ew_image_packed(f->color, f->w, f->h, 3), r = ew_image_packed(f->ref, f->w, f->h, 3);
    ew_image o = ew_image_packed(out, f->w, f->h, 3);
    if (method) {
        ew_image a = ew_image_packed(f->albedo, f->w, f->h, 3), n = ew_image_packed(f->normal, f->w, f->h, 3);
        ew_image d = ew_image_packed(f->depth, f->w, f->h, 1);
        ew_denoiser *dn = NULL;
        ew_result res = ew_denoiser_create(dev, method, &dn);
        if (res == EW_OK && weights) res = ew_denoiser_set_data(dn, "weights", weights, wsize);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "color", &c);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "albedo", &a);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "normal", &n);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "depth", &d);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "output", &o);
        if (res == EW_OK) res = ew_denoiser_commit(dn);
        if (res == EW_OK) res = ew_denoiser_execute(dn);
        ew_denoiser_destroy(dn);
        if (res != EW_OK) {
            fprintf(stderr, "train_nbg: %s failed: %s\n", method, ew_device_last_error(dev));
            return 1;
        }
    } else {
        memcpy(out, f->color, sizeof(float) * 3 * (size_t)f->w * f->h);
    }
    ew_image_psnr(dev, &o, &r, &q->psnr);
    ew_image_ssim(dev, &o, &r, &q->ssim);
    return 0;
}

typedef struct {
    double psnr, ssim, psnr_spp[4];
    int n, n_spp[4];
} summary;

static int spp_index(int spp) { return spp == 1 ? 0 : spp == 4 ? 1 : spp == 16 ? 2 : 3; }

static void summary_add(summary *s, int spp, const quality *q) {
    s->psnr += q->psnr;
    s->ssim += q->ssim;
    s->n++;
    s->psnr_spp[spp_index(spp)] += q->psnr;
    s->n_spp[spp_index(spp)]++;
}

static void summary_finish(summary *s) {
    if (s->n) {
        s->psnr /= s->n;
        s->ssim /= s->n;
    }
    for (int k = 0; k < 4; k++)
        if (s->n_spp[k]) s->psnr_spp[k] /= s->n_spp[k];
}

/* ---- checkpoint ------------------------------------------------------------- */
static int save_checkpoint(const char *path, const ew_guidenet *net, const float *params, const ew_adam *adam,
                           long step) {
    void *bytes;
    size_t size;
    if (ew_guidenet_save(net, params, &bytes, &size) != 0) return 1;
    int bad = train_checkpoint_save(path, bytes, size, adam, net->nparams, step);
    free(bytes);
    return bad;
}

/* 0 resumed, 1 no checkpoint, 2 one that cannot be used (printed) */
static int load_checkpoint(const char *path, const ew_guidenet *net, float *params, ew_adam *adam, long *step) {
    ew_weights w;
    int r = train_checkpoint_load(path, net->nparams, &w, adam, step);
    if (r) return r;
    ew_guidenet back;
    float *p = NULL;
    char err[256];
    int bad = ew_guidenet_from_weights(&back, &w, &p, err, sizeof err);
    ew_weights_free(&w);
    if (bad || strcmp(back.arch, net->arch) != 0) {
        fprintf(stderr, "train_nbg: checkpoint '%s' does not match --arch %s (%s)\n", path, net->arch,
                bad ? err : back.arch);
        free(p);
        return 2;
    }
    memcpy(params, p, sizeof(float) * net->nparams);
    free(p);
    return 0;
}

/* ---- the validation chart ----------------------------------------------------- */
typedef struct {
    long step;
    double loss, psnr, psnr1, bgrid, input;
} curve_point;

static void write_svg(const char *path, const curve_point *pts, int n, const char *title) {
    if (n < 1) return;
    FILE *f = fopen(path, "w");
    if (!f) return;
    const double W = 640, H = 360, L = 60, R = 20, T = 40, B = 50;
    double lo = 1e9, hi = -1e9, smax = (double)pts[n - 1].step;
    for (int i = 0; i < n; i++) {
        double v[4] = {pts[i].psnr, pts[i].psnr1, pts[i].bgrid, pts[i].input};
        for (int k = 0; k < 4; k++) {
            if (v[k] < lo) lo = v[k];
            if (v[k] > hi) hi = v[k];
        }
    }
    lo = floor(lo - 0.5);
    hi = ceil(hi + 0.5);
    if (smax <= 0) smax = 1;
#define X(s) (L + (W - L - R) * (double)(s) / smax)
#define Y(p) (T + (H - T - B) * (1.0 - ((p) - lo) / (hi - lo)))
    fprintf(f, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\" font-family=\"sans-serif\" font-size=\"12\">\n", W, H);
    fprintf(f, "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n<text x=\"%g\" y=\"22\" font-size=\"14\">%s</text>\n", L, title);
    for (double p = lo; p <= hi + 1e-9; p += (hi - lo) > 12 ? 2 : 1) {
        fprintf(f, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"#ddd\"/>", L, Y(p), W - R, Y(p));
        fprintf(f, "<text x=\"%g\" y=\"%g\" text-anchor=\"end\">%g</text>\n", L - 6, Y(p) + 4, p);
    }
    fprintf(f, "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\">step (of %ld)</text>\n", (L + W - R) / 2, H - 12, pts[n - 1].step);
    fprintf(f, "<text x=\"14\" y=\"%g\" transform=\"rotate(-90 14 %g)\" text-anchor=\"middle\">validation PSNR (dB)</text>\n", (T + H - B) / 2, (T + H - B) / 2);
    const char *colors[4] = {"#1f77b4", "#2ca02c", "#d62728", "#888"};
    const char *labels[4] = {"nbg, all spp", "nbg, 1 spp", "bgrid (hand-made guide), all spp", "input, all spp"};
    for (int k = 0; k < 4; k++) {
        fprintf(f, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"2\"%s points=\"", colors[k], k >= 2 ? " stroke-dasharray=\"6 4\"" : "");
        for (int i = 0; i < n; i++) {
            double v = k == 0 ? pts[i].psnr : k == 1 ? pts[i].psnr1 : k == 2 ? pts[i].bgrid : pts[i].input;
            fprintf(f, "%.1f,%.1f ", X(pts[i].step), Y(v));
        }
        fprintf(f, "\"/>\n<text x=\"%g\" y=\"%g\" fill=\"%s\">%s</text>\n", W - R - 200, T + 16 + 16.0 * k, colors[k], labels[k]);
    }
    fprintf(f, "</svg>\n");
#undef X
#undef Y
    fclose(f);
}

/* ---- emit-c --------------------------------------------------------------------- */
static int emit_c(const char *dir) {
    static const char *const archs[4] = {"2layer-3grid", "2layer-1grid", "7layer-3grid", "2layer-3grid-1spp"};
    printf("/* The neural bilateral grid models built into the library: byte-for-byte\n"
           " * copies of models/nbg/<arch>.ewm, generated by\n"
           " *   train_nbg --emit-c models/nbg > core/algorithms/nbg_weights_data.c\n"
           " * (tests/unit/test_nbg.c checks they match the files). A size of 0 means\n"
           " * this build has no weights for that model. */\n#include <stddef.h>\n\n"
           "extern const unsigned char ew_nbg_weights_2layer_3grid[], ew_nbg_weights_2layer_1grid[], "
           "ew_nbg_weights_7layer_3grid[],\n    ew_nbg_weights_2layer_3grid_1spp[];\n"
           "extern const size_t ew_nbg_weights_2layer_3grid_size, ew_nbg_weights_2layer_1grid_size,\n"
           "    ew_nbg_weights_7layer_3grid_size, ew_nbg_weights_2layer_3grid_1spp_size;\n");
    for (int k = 0; k < 4; k++) {
        char path[1200], ident[40];
        snprintf(path, sizeof path, "%s/%s.ewm", dir, archs[k]);
        snprintf(ident, sizeof ident, "%s", archs[k]);
        for (char *c = ident; *c; c++)
            if (*c == '-') *c = '_';
        size_t size = 0;
        unsigned char *b = (unsigned char *)train_read_file(path, &size);
        printf("\nconst unsigned char ew_nbg_weights_%s[] = {", ident);
        if (!b) printf("0");
        for (size_t i = 0; b && i < size; i++) printf("%s%u", i % 24 == 0 ? "\n    " : "", b[i]), printf(i + 1 < size ? "," : "");
        printf("%s};\nconst size_t ew_nbg_weights_%s_size = %zu;\n", b ? "\n" : "", ident, size);
        free(b);
    }
    return 0;
}

/* ---- main ------------------------------------------------------------------------ */
typedef struct {
    const dataset *ds;
    const int *train_frames;
    int ntrain;
    int scene_frames[MAX_SCENES][64];
    int scene_count[MAX_SCENES];
    int scenes_used[MAX_SCENES];
    int nused;
} picker;

/* a training scene uniformly, then one of its frames uniformly: scenes
 * with many frames (the 4-frame animations) are not over-weighted */
static int pick_frame(void *user, double u) {
    const picker *p = (const picker *)user;
    double x = u * p->nused;
    int s = (int)x;
    if (s >= p->nused) s = p->nused - 1;
    int scene = p->scenes_used[s];
    int k = (int)((x - s) * p->scene_count[scene]);
    if (k >= p->scene_count[scene]) k = p->scene_count[scene] - 1;
    return p->scene_frames[scene][k];
}

static int evaluate(const options *o, dataset *ds, ew_device *dev) {
    size_t wsize = 0;
    void *w = train_read_file(o->eval, &wsize);
    if (!w) {
        fprintf(stderr, "train_nbg: cannot read '%s'\n", o->eval);
        return 1;
    }
    int split = !strcmp(o->split, "train") ? 0 : !strcmp(o->split, "val") ? 1 : 2;
    if (load_frames(ds, 1 << split, o->spp_mask) != 0) return 1;
    printf("scene,spp,frame,input_psnr,input_ssim,bgrid_psnr,bgrid_ssim,nbg_psnr,nbg_ssim,nbg_minus_bgrid_db\n");
    summary si, sb, sn;
    memset(&si, 0, sizeof si);
    memset(&sb, 0, sizeof sb);
    memset(&sn, 0, sizeof sn);
    double d1 = 0;
    int n1 = 0;
    for (int i = 0; i < ds->nframes; i++) {
        const frame_info *f = &ds->frames[i];
        float *out = (float *)malloc(sizeof(float) * 3 * (size_t)f->w * f->h);
        quality qi, qb, qn;
        if (run_method(dev, f, NULL, NULL, 0, out, &qi) || run_method(dev, f, "bgrid", NULL, 0, out, &qb) ||
            run_method(dev, f, "nbg", w, wsize, out, &qn)) {
            free(out);
            return 1;
        }
        free(out);
        printf("%s,%d,%d,%.3f,%.4f,%.3f,%.4f,%.3f,%.4f,%+.3f\n", ds->scenes[f->scene].name, f->spp, f->frame_no, qi.psnr,
               qi.ssim, qb.psnr, qb.ssim, qn.psnr, qn.ssim, qn.psnr - qb.psnr);
        summary_add(&si, f->spp, &qi);
        summary_add(&sb, f->spp, &qb);
        summary_add(&sn, f->spp, &qn);
        if (f->spp == 1) {
            d1 += qn.psnr - qb.psnr;
            n1++;
        }
    }
    summary_finish(&si);
    summary_finish(&sb);
    summary_finish(&sn);
    fprintf(stderr, "%s split, %d frames: mean PSNR input %.2f, bgrid %.2f, nbg %.2f dB; SSIM %.4f / %.4f / %.4f\n",
            o->split, sn.n, si.psnr, sb.psnr, sn.psnr, si.ssim, sb.ssim, sn.ssim);
    static const int spps[4] = {1, 4, 16, 64};
    for (int k = 0; k < 4; k++)
        if (sn.n_spp[k])
            fprintf(stderr, "  %2d spp (%d frames): input %.2f, bgrid %.2f, nbg %.2f dB\n", spps[k], sn.n_spp[k],
                    si.psnr_spp[k], sb.psnr_spp[k], sn.psnr_spp[k]);
    if (n1) fprintf(stderr, "  nbg - bgrid at 1 spp: %+.2f dB mean\n", d1 / n1);
    free(w);
    return 0;
}

/* ---- benchmark ---------------------------------------------------------- */
static double cpu_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Time a function: median wall time of `reps` runs after one warm-up, and
 * the mean process CPU time per run. */
#define TIME_IT(reps, wall, cpu, CALL)                                                                   \
    do {                                                                                                 \
        double ts_[16];                                                                                  \
        CALL;                                                                                            \
        double c0_ = cpu_s();                                                                            \
        for (int r_ = 0; r_ < (reps); r_++) {                                                            \
            double t0_ = train_now_s();                                                                        \
            CALL;                                                                                        \
            ts_[r_] = train_now_s() - t0_;                                                                     \
        }                                                                                                \
        (cpu) = (cpu_s() - c0_) / (reps);                                                                \
        qsort(ts_, (size_t)(reps), sizeof(double), cmp_double);                                          \
        (wall) = ts_[(reps) / 2];                                                                        \
    } while (0)

static int bench(const options *o, ew_device *dev) {
    /* file names; the architecture of a random stand-in is the name up to its grids */
    static const char *const archs[4] = {"2layer-1grid", "2layer-3grid", "2layer-3grid-1spp", "7layer-3grid"};
    const int W = o->bench_w, H = o->bench_h, reps = 5;
    const size_t n = (size_t)W * H;
    float *color = (float *)malloc(n * 3 * sizeof(float)), *albedo = (float *)malloc(n * 3 * sizeof(float));
    float *normal = (float *)malloc(n * 3 * sizeof(float)), *depth = (float *)malloc(n * sizeof(float));
    float *out = (float *)malloc(n * 3 * sizeof(float));
    if (!color || !albedo || !normal || !depth || !out) {
        fprintf(stderr, "train_nbg: out of memory\n");
        return 1;
    }
    /* a real 1-spp render tiled to the size when --data is given, else noise */
    int fw = 0, fh = 0;
    float *c0 = NULL, *a0 = NULL, *n0 = NULL, *d0 = NULL;
    char path[4200];
    snprintf(path, sizeof path, "%s/a_cornell_119_256x256/f0001_spp0001.exr", o->data ? o->data : "");
    int have = o->data && train_read_render(path, 1, &fw, &fh, &c0, &a0, &n0, &d0) == 0;
    unsigned seed = 1;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t j = (size_t)y * W + x, s = have ? (size_t)(y % fh) * fw + (size_t)(x % fw) : 0;
            for (int k = 0; k < 3; k++) {
                seed = seed * 1664525u + 1013904223u;
                float r = (float)(seed >> 8) / 16777216.0f;
                color[j * 3 + k] = have ? c0[s * 3 + k] : 2.0f * r;
                albedo[j * 3 + k] = have ? a0[s * 3 + k] : 0.5f;
                normal[j * 3 + k] = have ? n0[s * 3 + k] : (k == 2 ? 1.0f : 0.0f);
            }
            depth[j] = have ? d0[s] : 5.0f;
        }
    printf("benchmark at %dx%d (%s), %d threads, median of %d runs; CPU time is the process's, all threads\n", W, H,
           have ? "a_cornell_119 at 1 spp, tiled" : "random colour", ew_device_get_num_threads(dev), reps);
    double peak_s;
    double peak = ew_conv_cpu_fma_gflops(dev, &peak_s);
    printf("measured FMA peak: %.1f GFLOP/s (%s FMA chains on every thread, %.2f s; %s convolutions)\n", peak,
           ew_conv_cpu_simd_name(ew_conv_cpu_simd_level()), peak_s, ew_conv_cpu_simd_name(ew_conv_cpu_simd_level()));
    ew_image vc = ew_image_packed(color, W, H, 3), va = ew_image_packed(albedo, W, H, 3);
    ew_image vn = ew_image_packed(normal, W, H, 3), vd = ew_image_packed(depth, W, H, 1), vo = ew_image_packed(out, W, H, 3);
    /* the hand-made-guide grid, for reference */
    {
        ew_denoiser *d = NULL;
        ew_denoiser_create(dev, "bgrid", &d);
        ew_denoiser_set_image(d, "color", &vc);
        ew_denoiser_set_image(d, "albedo", &va);
        ew_denoiser_set_image(d, "normal", &vn);
        ew_denoiser_set_image(d, "depth", &vd);
        ew_denoiser_set_image(d, "output", &vo);
        ew_denoiser_commit(d);
        double wall, cpu;
        TIME_IT(reps, wall, cpu, ew_denoiser_execute(d));
        printf("bgrid (hand-made guide): %.1f ms per frame (CPU %.1f ms)\n", wall * 1e3, cpu * 1e3);
        ew_denoiser_destroy(d);
    }
    for (int m = 0; m < 4; m++) {
        char mpath[4200];
        snprintf(mpath, sizeof mpath, "%s/%s.ewm", o->models, archs[m]);
        size_t wsize = 0;
        void *wb = train_read_file(mpath, &wsize);
        const int trained = wb != NULL;
        ew_guidenet net;
        char err[256], arch[32];
        snprintf(arch, sizeof arch, "%.12s", archs[m]);
        ew_guidenet_init(&net, arch, err, sizeof err);
        float *params = (float *)malloc(sizeof(float) * net.nparams);
        if (wb) {
            ew_weights w;
            float *p = NULL;
            if (ew_weights_parse(wb, wsize, &w, err, sizeof err) == 0 && ew_guidenet_from_weights(&net, &w, &p, err, sizeof err) == 0) {
                memcpy(params, p, sizeof(float) * net.nparams);
                free(p);
                ew_weights_free(&w);
            }
        } else {
            ew_guidenet_random(&net, 1, params);
            ew_guidenet_save(&net, params, &wb, &wsize);
        }
        ew_denoiser *d = NULL;
        ew_denoiser_create(dev, "nbg", &d);
        ew_denoiser_set_data(d, "weights", wb, wsize);
        ew_denoiser_set_image(d, "color", &vc);
        ew_denoiser_set_image(d, "albedo", &va);
        ew_denoiser_set_image(d, "normal", &vn);
        ew_denoiser_set_image(d, "depth", &vd);
        ew_denoiser_set_image(d, "output", &vo);
        if (ew_denoiser_commit(d) != EW_OK) {
            fprintf(stderr, "train_nbg: %s\n", ew_device_last_error(dev));
            return 1;
        }
        double wall, cpu, gwall, gcpu;
        TIME_IT(reps, wall, cpu, ew_denoiser_execute(d));
        ew_denoiser_destroy(d);
        /* GuideNet alone, exactly as the op runs it */
        const int band = ew_nbg_band_rows(&net, H);
        float *band_mem = (float *)aligned_alloc(64, (ew_nbg_band_floats(&net, W, band) * sizeof(float) + 63) / 64 * 64);
        float *outputs = (float *)malloc(sizeof(float) * n * (size_t)net.nout);
        float ds = 0.01f;
        ew_nbg_forward f = {&net, params, W, H, color, albedo, normal, depth, ds, band_mem, band, outputs, 0};
        TIME_IT(reps, gwall, gcpu, ew_nbg_guidenet_forward(dev, &f, NULL, NULL));
        const double flops = 2.0 * ew_guidenet_macs_per_pixel(&net) * (double)n;
        size_t grid4k, band4k;
        size_t mem4k = ew_nbg_device_floats(&net, 3840, 2160, &grid4k, &band4k) * sizeof(float);
        printf("nbg %-17s %s: %6.1f ms per frame (CPU %.1f ms); GuideNet %.1f ms = %.0f%% (%.1f GFLOP/s = %.0f%% of the "
               "measured peak; CPU %.1f ms), grids and the rest %.1f ms; 3840x2160 needs %.0f MiB (largest grid %.0f MiB, band %.0f MiB)\n",
               archs[m], trained ? "(trained)" : "(random weights)", wall * 1e3,
               cpu * 1e3, gwall * 1e3, 100.0 * gwall / wall, flops / gwall * 1e-9, 100.0 * flops / gwall * 1e-9 / peak,
               gcpu * 1e3, (wall - gwall) * 1e3, mem4k / 1048576.0, grid4k * 4.0 / 1048576.0, band4k * 4.0 / 1048576.0);
        fflush(stdout);
        free(band_mem);
        free(outputs);
        free(params);
        free(wb);
    }
    free(color); free(albedo); free(normal); free(depth); free(out);
    free(c0); free(a0); free(n0); free(d0);
    return 0;
}

/* What a training run holds, freed by main however train() ends. */
static struct {
    float *params, *m, *v, *vout;
    ew_patch_ref *refs;
    ew_trainer *tr;
    FILE *csv;
} held;

static void held_free(void) {
    free(held.params);
    free(held.m);
    free(held.v);
    free(held.vout);
    free(held.refs);
    if (held.tr) ew_trainer_destroy(held.tr);
    if (held.csv) fclose(held.csv);
    memset(&held, 0, sizeof held);
}

static int train(const options *opt, dataset *ds, ew_device *dev) {
    const options o = *opt;
    /* the net */
    ew_guidenet net;
    char err[256];
    if (ew_guidenet_init(&net, o.arch, err, sizeof err) != 0) {
        fprintf(stderr, "train_nbg: %s\n", err);
        return 2;
    }
    if (o.rates) {
        const char *s = o.rates;
        for (int g = 0; g < net.ngrids; g++) {
            float rs, rd;
            int used = 0;
            if (sscanf(s, "%f:%f%n", &rs, &rd, &used) != 2 || rs < 1 || rd < 1 || rs > 256 || rd > 256) {
                fprintf(stderr, "train_nbg: --rates needs %d pairs eta_s:eta_d in [1, 256]\n", net.ngrids);
                return 2;
            }
            net.rate_s[g] = rs;
            net.rate_d[g] = rd;
            s += used;
            if (*s == ',') s++;
        }
    }
    float *params = held.params = (float *)malloc(sizeof(float) * net.nparams);
    ew_adam adam = {o.run.lr, 0.9, 0.999, 1e-8, 0, held.m = (float *)calloc(net.nparams, sizeof(float)),
                    held.v = (float *)calloc(net.nparams, sizeof(float))};
    if (!params || !adam.m || !adam.v) {
        fprintf(stderr, "train_nbg: out of memory for %zu parameters\n", net.nparams);
        return 1;
    }
    ew_guidenet_random(&net, o.run.seed, params);
    if (o.init) {
        size_t size;
        void *b = train_read_file(o.init, &size);
        ew_weights w;
        ew_guidenet other;
        float *p = NULL;
        if (!b || ew_weights_parse(b, size, &w, err, sizeof err) != 0 ||
            ew_guidenet_from_weights(&other, &w, &p, err, sizeof err) != 0 || other.nparams != net.nparams) {
            fprintf(stderr, "train_nbg: --init '%s': %s\n", o.init, b ? err : "cannot read");
            return 1;
        }
        memcpy(params, p, sizeof(float) * net.nparams);
        free(p);
        free(b);
        ew_weights_free(&w);
    }
    long step = 0;
    if (o.run.resume) {
        int r = load_checkpoint(o.run.checkpoint, &net, params, &adam, &step);
        if (r == 2) return 1;
        if (r == 0) printf("resumed from %s at step %ld\n", o.run.checkpoint, step);
        else printf("no checkpoint at %s: starting from scratch\n", o.run.checkpoint);
    }

    /* data: train + validation scenes only */
    printf("split (whole scenes; test scenes are not read):\n");
    for (int i = 0; i < ds->nscenes; i++) printf("  %-5s %s\n", split_name(ds->scenes[i].split), ds->scenes[i].name);
    double t_load = train_now_s();
    if (load_frames(ds, 1 | 2, o.spp_mask) != 0) return 1;
    static ew_train_frame tframes[MAX_FRAMES];
    static picker pk;
    int ntrain = 0, nval = 0;
    pk.ds = ds;
    for (int i = 0; i < ds->nframes; i++) {
        const frame_info *f = &ds->frames[i];
        if (ds->scenes[f->scene].split != 0) {
            nval++;
            continue;
        }
        if (f->w < o.run.patch || f->h < o.run.patch) {
            fprintf(stderr, "train_nbg: frame %dx%d is smaller than --patch %d\n", f->w, f->h, o.run.patch);
            return 1;
        }
        if (ew_train_frame_init(&tframes[ntrain], f->w, f->h, f->color, f->albedo, f->normal, f->depth, f->ref, 3.0f) != 0) {
            fprintf(stderr, "train_nbg: out of memory\n");
            return 1;
        }
        int s = f->scene;
        if (pk.scene_count[s] == 0) pk.scenes_used[pk.nused++] = s;
        if (pk.scene_count[s] < 64) pk.scene_frames[s][pk.scene_count[s]++] = ntrain;
        ntrain++;
    }
    printf("%d training frames from %d scenes, %d validation frames; loaded in %.1f s\n", ntrain, pk.nused, nval,
           train_now_s() - t_load);
    if (ntrain == 0 || nval == 0) {
        fprintf(stderr, "train_nbg: need training and validation scenes\n");
        return 1;
    }
    /* baselines on the validation frames, once */
    summary base_in, base_bg;
    memset(&base_in, 0, sizeof base_in);
    memset(&base_bg, 0, sizeof base_bg);
    size_t most = 0;
    for (int i = 0; i < ds->nframes; i++)
        if ((size_t)ds->frames[i].w * ds->frames[i].h > most) most = (size_t)ds->frames[i].w * ds->frames[i].h;
    float *vout = held.vout = (float *)malloc(sizeof(float) * 3 * most);
    if (!vout) {
        fprintf(stderr, "train_nbg: out of memory\n");
        return 1;
    }
    for (int i = 0; i < ds->nframes; i++) {
        const frame_info *f = &ds->frames[i];
        if (ds->scenes[f->scene].split != 1) continue;
        quality q;
        if (run_method(dev, f, NULL, NULL, 0, vout, &q)) return 1;
        summary_add(&base_in, f->spp, &q);
        if (run_method(dev, f, "bgrid", NULL, 0, vout, &q)) return 1;
        summary_add(&base_bg, f->spp, &q);
    }
    summary_finish(&base_in);
    summary_finish(&base_bg);
    printf("validation baselines: input %.2f dB, bgrid %.2f dB (1 spp: %.2f / %.2f)\n", base_in.psnr, base_bg.psnr,
           base_in.psnr_spp[0], base_bg.psnr_spp[0]);

    ew_trainer *tr = held.tr = ew_trainer_create(dev, &net, o.run.batch, o.run.patch);
    if (!tr) {
        fprintf(stderr, "train_nbg: out of memory for the trainer\n");
        return 1;
    }
    printf("arch %s: %zu parameters, %.0f multiply-adds a pixel, grids", net.arch, net.nparams,
           ew_guidenet_macs_per_pixel(&net));
    for (int g = 0; g < net.ngrids; g++) printf(" (%g, %g)", (double)net.rate_s[g], (double)net.rate_d[g]);
    printf("; seed %lu, %ld steps of %d patches of %d^2, lr %g -> %g, clip %g, %d threads\n", o.run.seed, o.run.steps, o.run.batch,
           o.run.patch, o.run.lr, o.run.lr_final, o.run.clip, ew_device_get_num_threads(dev));
    fflush(stdout);

    /* the curve so far (a resumed run appends to its CSV) */
    static curve_point pts[100000];
    int npts = 0;
    FILE *csv = held.csv = fopen(o.csv, step > 0 ? "a" : "w");
    if (!csv) {
        fprintf(stderr, "train_nbg: cannot write '%s'\n", o.csv);
        return 1;
    }
    if (step == 0)
        fprintf(csv, "step,seconds,lr,train_loss,grad_norm_mean,grad_norm_max,clipped_steps,val_psnr,val_ssim,"
                     "val_psnr_1spp,val_psnr_4spp,val_psnr_16spp,val_psnr_64spp,bgrid_val_psnr,input_val_psnr\n");
    else {
        FILE *old = fopen(o.csv, "r");
        char line[1024];
        while (old && fgets(line, sizeof line, old)) {
            curve_point p;
            double sec, lr, gm, gx, cl, ssim, p4, p16, p64;
            if (sscanf(line, "%ld,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf", &p.step, &sec, &lr, &p.loss, &gm, &gx,
                       &cl, &p.psnr, &ssim, &p.psnr1, &p4, &p16, &p64, &p.bgrid, &p.input) == 15 &&
                p.step <= step && npts < 100000)
                pts[npts++] = p;
        }
        if (old) fclose(old);
    }

    double t0 = train_now_s(), last_ckpt = t0, loss_sum = 0, norm_sum = 0, norm_max = 0;
    int nsum = 0, nclipped = 0;
    const int np = (int)net.nparams;
    ew_patch_ref *refs = held.refs = (ew_patch_ref *)malloc(sizeof(ew_patch_ref) * (size_t)o.run.batch);
    if (!refs) return 1;
    while (step < o.run.steps) {
        /* cosine schedule, a function of the step alone */
        adam.lr = o.run.lr_final + 0.5 * (o.run.lr - o.run.lr_final) * (1.0 + cos(3.14159265358979323846 * (double)step / (double)o.run.steps));
        for (int b = 0; b < o.run.batch; b++) refs[b] = ew_train_pick(o.run.seed, (uint64_t)step, b, tframes, pick_frame, &pk, o.run.patch);
        ew_train_step_stats st;
        ew_trainer_step(tr, params, &adam, tframes, refs, o.run.clip, &st);
        step++;
        if (!isfinite(st.loss) || !isfinite(st.grad_norm)) {
            fprintf(stderr, "train_nbg: step %ld: loss %g, gradient norm %g: stopping (the last checkpoint is intact)\n",
                    step, st.loss, st.grad_norm);
            return 1;
        }
        loss_sum += st.loss;
        norm_sum += st.grad_norm;
        if (st.grad_norm > norm_max) norm_max = st.grad_norm;
        nsum++;
        if (st.clipped) {
            nclipped++;
            /* logged, never silently dropped: the step still happens, scaled */
            if (nclipped <= 3)
                printf("  step %ld: gradient norm %.4g clipped to %.4g\n", step, st.grad_norm, o.run.clip);
        }
        if (step % o.run.val_every == 0 || step == o.run.steps) {
            void *wb;
            size_t ws;
            ew_guidenet_save(&net, params, &wb, &ws);
            summary sv;
            memset(&sv, 0, sizeof sv);
            for (int i = 0; i < ds->nframes; i++) {
                const frame_info *f = &ds->frames[i];
                if (ds->scenes[f->scene].split != 1) continue;
                quality q;
                if (run_method(dev, f, "nbg", wb, ws, vout, &q)) return 1;
                summary_add(&sv, f->spp, &q);
            }
            summary_finish(&sv);
            if (train_write_file_atomic(o.out, wb, ws) != 0) fprintf(stderr, "train_nbg: cannot write '%s'\n", o.out);
            free(wb);
            double el = train_now_s() - t0;
            printf("step %6ld  %6.0f s  lr %.2e  train loss %.5f  grad norm mean %.3g max %.3g, %d/%d clipped  |  val "
                   "PSNR %.2f dB (1spp %.2f, 4 %.2f, 16 %.2f, 64 %.2f) SSIM %.4f  [bgrid %.2f, input %.2f]\n",
                   step, el, adam.lr, loss_sum / nsum, norm_sum / nsum, norm_max, nclipped, nsum, sv.psnr,
                   sv.psnr_spp[0], sv.psnr_spp[1], sv.psnr_spp[2], sv.psnr_spp[3], sv.ssim, base_bg.psnr, base_in.psnr);
            fprintf(csv, "%ld,%.1f,%.4g,%.6f,%.5g,%.5g,%d,%.4f,%.5f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f\n", step, el, adam.lr,
                    loss_sum / nsum, norm_sum / nsum, norm_max, nclipped, sv.psnr, sv.ssim, sv.psnr_spp[0],
                    sv.psnr_spp[1], sv.psnr_spp[2], sv.psnr_spp[3], base_bg.psnr, base_in.psnr);
            fflush(csv);
            if (npts < 100000) {
                curve_point p = {step, loss_sum / nsum, sv.psnr, sv.psnr_spp[0], base_bg.psnr, base_in.psnr};
                pts[npts++] = p;
            }
            char title[160];
            snprintf(title, sizeof title, "nbg %s, seed %lu: validation scenes (%d frames)", net.arch, o.run.seed, nval);
            write_svg(o.svg, pts, npts, title);
            fflush(stdout);
            loss_sum = norm_sum = norm_max = 0;
            nsum = nclipped = 0;
        }
        const int stop = o.run.stop_after > 0 && step >= o.run.stop_after;
        if (train_now_s() - last_ckpt > 60.0 * o.run.ckpt_minutes || step == o.run.steps || stop) {
            if (save_checkpoint(o.run.checkpoint, &net, params, &adam, step) != 0)
                fprintf(stderr, "train_nbg: could not write the checkpoint '%s'\n", o.run.checkpoint);
            last_ckpt = train_now_s();
        }
        if (stop) {
            printf("stopped at step %ld (--stop-after); --resume continues\n", step);
            return 0;
        }
    }
    /* the final model (also written at each validation) */
    void *wb;
    size_t ws;
    ew_guidenet_save(&net, params, &wb, &ws);
    if (train_write_file_atomic(o.out, wb, ws) != 0) {
        fprintf(stderr, "train_nbg: cannot write '%s'\n", o.out);
        free(wb);
        return 1;
    }
    printf("wrote %s (%zu bytes) after %ld steps, %.0f s\n", o.out, ws, step, train_now_s() - t0);
    free(wb);
    for (int i = 0; i < ntrain; i++) ew_train_frame_free(&tframes[i]);
    (void)np;
    return 0;
}

const char *train_prog = "train_nbg";

int main(int argc, char **argv) {
    static options o;
    if (!parse(argc, argv, &o)) return 2;
    if (o.emit_c) return emit_c(o.emit_c);
    if (o.bench) {
        ew_device_desc bd = EW_DEVICE_DESC_INIT;
        bd.num_threads = o.run.threads;
        ew_device *bdev = NULL;
        if (ew_device_create(&bd, &bdev) != EW_OK) return 1;
        int rc = bench(&o, bdev);
        ew_device_destroy(bdev);
        return rc;
    }
    static dataset ds;
    ds.nscenes = list_scenes(o.data, ds.scenes, MAX_SCENES, 0);
    if (ds.nscenes <= 0) {
        if (ds.nscenes == 0) fprintf(stderr, "train_nbg: no scene folders in '%s'\n", o.data);
        return 1;
    }
    if (o.extra_train && !o.eval) {
        int k = list_scenes(o.extra_train, ds.scenes + ds.nscenes, MAX_SCENES - ds.nscenes, 1);
        if (k <= 0) {
            if (k == 0) fprintf(stderr, "train_nbg: no scene folders in '%s'\n", o.extra_train);
            return 1;
        }
        ds.nscenes += k;
    }
    ew_device_desc dd = EW_DEVICE_DESC_INIT;
    dd.num_threads = o.run.threads;
    ew_device *dev = NULL;
    if (ew_device_create(&dd, &dev) != EW_OK) {
        fprintf(stderr, "train_nbg: cannot create the device\n");
        return 1;
    }
    const int rc = o.eval ? evaluate(&o, &ds, dev) : train(&o, &ds, dev);
    held_free();
    ew_device_destroy(dev);
    return rc;
}
