/*
 * train_kpcn — train and evaluate the kernel-predicting denoiser "kpcn"
 * (core/algorithms/kpcn.h, docs/kpcn.md).
 *
 *   train_kpcn --arch kpcn-c16 --out MODEL.ewm --train DIR [--train DIR ...] --val DIR [options]
 *
 * --train DIR: every complete scene folder in DIR trains (folders of
 * tools/blender/render_cache.sh; "<scene>.partial" folders are being
 * rendered and are skipped). --shared DIR: the shared cycles-train set,
 * split per family by seed (last: test, the one before in families of four
 * or more: validation, the rest: training); only its training scenes are
 * read, and a scene on the list of BENCHMARKS.md's test scenes is refused
 * whatever folder it is in. --val DIR: every scene in DIR validates.
 * With --rescan, the training and validation folders are read again at
 * every validation and new complete scenes join (the cache grows while a
 * run trains).
 *
 * Each step: --batch patches of --patch^2 pixels, each from a training scene
 * chosen uniformly, one of its frames (spp levels) uniformly, a uniform
 * position and one of the 8 symmetries of the square, a pure function of
 * (seed, step, index); Adam on the mean gradient, a cosine learning rate
 * from --lr to --lr-final over --steps, gradients clipped to global norm
 * --clip. Every --val-every steps: PSNR of the model on the validation
 * scenes at 1/4/16/64 spp through the library's "kpcn" op with these
 * weights (the model that ships is the model measured; nbg and the input
 * alongside), a line on stdout and a row in MODEL.csv; MODEL.ewm is
 * rewritten then, and the checkpoint (weights, Adam moments, step) every
 * --checkpoint-minutes; --resume continues from it.
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
#include "algorithms/kpcn.h"
#include "algorithms/train.h"
#include "cycles_passes.h"
#include "edgewise/edgewise.h"
#include "ewio.h"
#include "src/backend.h"
#include "src/internal.h"
#include "src/weights.h"
#include "train_common.h"

#define MAX_SCENES 1024
#define MAX_DIRS 8

/* BENCHMARKS.md's held-out test scenes: never read for training or validation */
static const char *const test_scenes[] = {"a_cornell_119_", "a_cornell_122_", "b_glossy_112_", "b_glossy_118_",
                                          "c_glass_113_",   "c_glass_120_",   "h_hdri_114_",   "h_hdri_121_",
                                          "e_dof_116_",     "d_firefly_115_", "f_motionblur_117_", "g_anim_123_"};

static int holdout; /* --holdout K */
static int only_val; /* --eval: read validation scenes only */
static double max_memory_gb; /* --max-memory-gb; 0: 80 % of the machine's memory */
static double held_gb;       /* what the loaded scenes hold */
static int over_budget;      /* a scene did not fit: no more are loaded */
/* --scenes FILE: only the scene folders it names load (a run's MODEL.scenes
 * repeats that run's data: the render cache keeps growing) */
static char (*allowed)[256];
static int nallowed;
static int auto_quality; /* the "auto" row of --eval */

/* --train-spp LIST: the sample counts a training scene loads (default every
 * one rendered). Each frame holds its features and target, ~6.4 MB at
 * 256x256, so seven counts over 600 scenes outgrow a 24 GB machine. */
#define MAX_TRAIN_SPP 16
static int train_spp[MAX_TRAIN_SPP], ntrain_spp;

static int parse_spp_list(const char *v) {
    ntrain_spp = 0;
    for (const char *c = v; *c;) {
        char *end;
        long n = strtol(c, &end, 10);
        if (end == c || n < 1 || ntrain_spp == MAX_TRAIN_SPP || (*end && *end != ',')) return 0;
        train_spp[ntrain_spp++] = (int)n;
        c = *end ? end + 1 : end;
    }
    return ntrain_spp > 0;
}

static int train_loads_spp(int spp) {
    if (!ntrain_spp) return 1;
    for (int i = 0; i < ntrain_spp; i++)
        if (train_spp[i] == spp) return 1;
    return 0;
}

static int is_test_scene(const char *name) {
    for (size_t i = 0; i < sizeof test_scenes / sizeof test_scenes[0]; i++)
        if (!strncmp(name, test_scenes[i], strlen(test_scenes[i]))) return 1;
    return 0;
}

static const char usage[] =
    "usage: train_kpcn --arch kpcn-c<C> --out MODEL.ewm --train DIR [--shared DIR] --val DIR [options]\n"
    "       train_kpcn --eval MODEL.ewm --val DIR [--holdout K --train DIR] [--eval-csv FILE]\n"
    "       train_kpcn --emit-c MODELDIR > core/algorithms/kpcn_weights_data.c\n"
    "       train_kpcn --bench W H THREADS   (time the built-in models)\n"
    "  --eval-csv FILE       with --eval: one row a validation file and method (scene,index,spp,method,psnr;\n"
    "                        index: the file's place among the scene's loaded renders)\n"
    "  --seed N              initialisation and patch sampling (default 1)\n"
    "  --init WEIGHTS.ewm    start from another kpcn's weights (a warm start: its channels copied, new ones\n"
    "                        random and unread at first; kpcn-c16 -> kpcn-c24-noise keeps its output until trained;\n"
    "                        more scales: -s4 from a 3-scale model moves it by the new blend, 1.8 %; -ra adds\n"
    "                        the remodulation kernel as 94 % its centre tap)\n"
    "  --steps N             Adam steps, the schedule's length (default 6000)\n"
    "  --batch N             patches per step (default 8)\n"
    "  --patch N             patch side, a multiple of 2^(scales - 1) (default 64)\n"
    "  --lr X, --lr-final X  cosine learning rate (default 1e-3 -> 5e-5)\n"
    "  --clip X              global gradient norm clip (default 1; 0 off)\n"
    "  --loss tm|log|psnr    L1 on the metrics' tone curve (default) or on log(1 + x), or minus\n"
    "                        each patch's PSNR on the tone curve (every sample count weighs alike)\n"
    "  --threads N           worker threads (default 0: all cores)\n"
    "  --val-every N         validate every N steps (default 250)\n"
    "  --val-max N           validate on at most N scenes (default 12)\n"
    "  --rescan              look for new scenes at every validation\n"
    "  --train-spp LIST      sample counts a training scene loads, e.g. 1,4,16,64 (default all rendered)\n"
    "  --max-memory-gb X     the scenes held in memory stay under X GB (default 80 %% of the machine's memory;\n"
    "                        ~5.2 MB a training render at 256x256): a run whose scenes do not fit stops\n"
    "                        before training, and --rescan then adds no more scenes, each with a message\n"
    "  --scenes FILE         load only the scene folders FILE names (one a line; the last word's last path\n"
    "                        component counts, so a run's MODEL.scenes, which every validation rewrites, repeats\n"
    "                        its data)\n"
    "  --holdout K           also validate on the --train scenes of render_cache.sh whose scene index i\n"
    "                        and family index k (seed = base + 16 i + k) have (i + k) %% K == 0\n"
    "  --checkpoint PATH     default MODEL.ckpt; --checkpoint-minutes M (default 3)\n"
    "  --resume              continue from the checkpoint if it exists\n"
    "  --stop-after N        checkpoint and stop at step N (the schedule stays --steps'; a --resume run then\n"
    "                        ends with the weights an uninterrupted run writes)\n"
    "  --time-limit MIN      checkpoint and stop after MIN minutes; the learning rate then follows the clock when\n"
    "                        that comes before --steps, so only a run that ends by --steps repeats step for step\n";

typedef struct {
    const char *arch, *out, *eval, *eval_csv, *shared, *loss_name, *init, *scenes;
    const char *train[MAX_DIRS], *val[MAX_DIRS];
    int ntrain_dirs, nval_dirs;
    char csv[1024];
    train_run_opts run;
    int rescan, val_max, loss;
    double time_limit;
} options;

enum {
    OPT_ARCH = TRAIN_OPT_OWN, OPT_OUT, OPT_EVAL, OPT_INIT, OPT_TRAIN, OPT_VAL, OPT_SHARED, OPT_LOSS, OPT_VAL_MAX,
    OPT_TIME_LIMIT, OPT_RESCAN, OPT_HOLDOUT, OPT_SCENES, OPT_TRAIN_SPP, OPT_EVAL_CSV, OPT_MAX_MEMORY
};
static const struct option long_opts[] = {
    TRAIN_RUN_LONG_OPTS,
    {"arch", required_argument, NULL, OPT_ARCH}, {"out", required_argument, NULL, OPT_OUT},
    {"eval", required_argument, NULL, OPT_EVAL}, {"init", required_argument, NULL, OPT_INIT},
    {"train", required_argument, NULL, OPT_TRAIN}, {"val", required_argument, NULL, OPT_VAL},
    {"shared", required_argument, NULL, OPT_SHARED}, {"loss", required_argument, NULL, OPT_LOSS},
    {"val-max", required_argument, NULL, OPT_VAL_MAX}, {"time-limit", required_argument, NULL, OPT_TIME_LIMIT},
    {"rescan", no_argument, NULL, OPT_RESCAN}, {"holdout", required_argument, NULL, OPT_HOLDOUT},
    {"scenes", required_argument, NULL, OPT_SCENES}, {"train-spp", required_argument, NULL, OPT_TRAIN_SPP},
    {"eval-csv", required_argument, NULL, OPT_EVAL_CSV}, {"max-memory-gb", required_argument, NULL, OPT_MAX_MEMORY},
    {"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    o->run.seed = 1;
    o->run.steps = 6000;
    o->run.batch = 8;
    o->run.patch = 64;
    o->run.lr = 1e-3;
    o->run.lr_final = 5e-5;
    o->run.clip = 1.0;
    o->run.val_every = 250;
    o->val_max = 12;
    o->run.ckpt_minutes = 3;
    int c, ok = 1;
    opterr = 0;
    while (ok && (c = getopt_long(argc, argv, ":h", long_opts, NULL)) != -1) {
        const char *v = optarg, *a = argv[optind - 1];
        if (train_run_option(c, v, &o->run, &ok)) continue;
        switch (c) {
        case OPT_ARCH: o->arch = v; break;
        case OPT_OUT: o->out = v; break;
        case OPT_EVAL: o->eval = v; break;
        case OPT_EVAL_CSV: o->eval_csv = v; break;
        case OPT_INIT: o->init = v; break;
        case OPT_TRAIN:
        case OPT_VAL:
            if ((c == OPT_TRAIN ? o->ntrain_dirs : o->nval_dirs) == MAX_DIRS) {
                fprintf(stderr, "train_kpcn: at most %d %s folders\n", MAX_DIRS, c == OPT_TRAIN ? "--train" : "--val");
                ok = 0;
            } else if (c == OPT_TRAIN) o->train[o->ntrain_dirs++] = v;
            else o->val[o->nval_dirs++] = v;
            break;
        case OPT_SHARED: o->shared = v; break;
        case OPT_LOSS: o->loss_name = v; break;
        case OPT_VAL_MAX: ok = train_parse_int("--val-max", v, 0, MAX_SCENES, &o->val_max); break;
        case OPT_TIME_LIMIT: ok = train_parse_double("--time-limit", v, 0, 1e6, &o->time_limit); break;
        case OPT_RESCAN: o->rescan = 1; break;
        case OPT_HOLDOUT: ok = train_parse_int("--holdout", v, 0, 1000, &holdout); break;
        case OPT_SCENES: o->scenes = v; break;
        case OPT_MAX_MEMORY: ok = train_parse_double("--max-memory-gb", v, 1e-4, 1e6, &max_memory_gb); break;
        case OPT_TRAIN_SPP:
            if (!parse_spp_list(v)) {
                fprintf(stderr, "train_kpcn: --train-spp takes sample counts >= 1 separated by commas\n");
                ok = 0;
            }
            break;
        default: ok = train_getopt_other(c, a, usage); break;
        }
    }
    if (!ok || !train_no_operands(argc, argv, usage)) return 0;
    o->loss = EW_KPCN_LOSS_TM;
    if (o->loss_name && !strcmp(o->loss_name, "log")) o->loss = EW_KPCN_LOSS_LOG;
    else if (o->loss_name && !strcmp(o->loss_name, "psnr")) o->loss = EW_KPCN_LOSS_PSNR;
    else if (o->loss_name && strcmp(o->loss_name, "tm") != 0) {
        fprintf(stderr, "train_kpcn: --loss tm, log or psnr\n");
        return 0;
    }
    if (o->eval && !o->nval_dirs && !o->ntrain_dirs) {
        fprintf(stderr, "train_kpcn: --eval needs scenes: --val DIR, or --train DIR with --holdout K\n");
        return 0;
    }
    if (o->eval) return 1;
    if (!o->arch || !o->out || (!o->ntrain_dirs && !o->shared)) {
        fputs(usage, stderr);
        return 0;
    }
    if (o->run.patch < 16 || o->run.patch % 4 || o->run.batch < 1 || o->run.steps < 1) {
        fprintf(stderr, "train_kpcn: --patch a multiple of 4 >= 16, --batch >= 1, --steps >= 1\n");
        return 0;
    }
    if (!o->run.checkpoint[0]) snprintf(o->run.checkpoint, sizeof o->run.checkpoint, "%s.ckpt", o->out);
    snprintf(o->csv, sizeof o->csv, "%s.csv", o->out);
    return 1;
}

/* ---- data ------------------------------------------------------------------ */
typedef struct {
    int spp, w, h;
    float *color, *albedo, *normal, *depth, *ref; /* validation frames keep these for the op */
    ew_kpcn_frame f;                               /* training frames */
} frame_t;

typedef struct {
    char name[256], dir[1024];
    int val, nframes;
    frame_t *frames;
} scene_t;

static scene_t scenes[MAX_SCENES];
static int nscenes;

static int cmp_name(const void *a, const void *b) { return strcmp((const char *)a, (const char *)b); }

/* Whether scene s loads its render of spp samples: validation 1/4/16/64, training --train-spp. */
static int scene_loads_spp(const scene_t *s, int spp) {
    return s->val ? spp == 1 || spp == 4 || spp == 16 || spp == 64 : train_loads_spp(spp);
}

/* --max-memory-gb, else 80 % of the machine's memory */
static double memory_budget_gb(void) {
    if (max_memory_gb > 0) return max_memory_gb;
    const long pages = sysconf(_SC_PHYS_PAGES), ps = sysconf(_SC_PAGESIZE);
    return pages > 0 && ps > 0 ? 0.8 * (double)pages * (double)ps / 1e9 : 1e9;
}

/* Load one scene folder: frame 1's noisy renders (validation: 1/4/16/64 spp
 * only) against its reference (fNNNN_ref*.exr). 2: it would take the
 * scenes held past the memory budget (nothing loaded). */
static int load_scene(scene_t *s) {
    char sdir[1400];
    snprintf(sdir, sizeof sdir, "%.1023s/%.255s", s->dir, s->name);
    DIR *d = opendir(sdir);
    if (!d) return 1;
    static char names[128][256];
    int nn = 0;
    char ref[256] = "";
    struct dirent *e;
    while ((e = readdir(d)))
        if (!strncmp(e->d_name, "f0001_spp", 9) && strstr(e->d_name, ".exr") && nn < 128)
            snprintf(names[nn++], 256, "%.255s", e->d_name);
        else if (!strncmp(e->d_name, "f0001_ref", 9) && strstr(e->d_name, ".exr"))
            snprintf(ref, sizeof ref, "%.255s", e->d_name);
    closedir(d);
    if (!ref[0] || nn == 0) return 1;
    qsort(names, (size_t)nn, 256, cmp_name);
    char path[1800];
    snprintf(path, sizeof path, "%.1300s/%.255s", sdir, ref);
    float *r = NULL, *ua = NULL, *un = NULL, *ud = NULL;
    int rw, rh;
    if (train_read_render(path, 0, &rw, &rh, &r, &ua, &un, &ud)) return 1;
    /* what the frames will hold: a training frame its ew_kpcn_frame (the
     * inputs, the clamped radiance, the albedo, the reference), a validation
     * frame also the passes the op reads */
    int keep = 0;
    for (int k = 0; k < nn; k++) {
        int fno, spp;
        if (sscanf(names[k], "f%d_spp%d.exr", &fno, &spp) != 2) continue;
        keep += scene_loads_spp(s, spp);
    }
    const double gb = (double)keep * rw * rh * sizeof(float) * (EW_KPCN_MAX_INPUTS + 9 + (s->val ? 13 : 0)) / 1e9;
    if (held_gb + gb > memory_budget_gb()) {
        free(r);
        return 2;
    }
    s->frames = (frame_t *)calloc((size_t)nn, sizeof(frame_t));
    s->nframes = 0;
    for (int k = 0; k < nn; k++) {
        int fno, spp;
        if (sscanf(names[k], "f%d_spp%d.exr", &fno, &spp) != 2) continue;
        if (!scene_loads_spp(s, spp)) continue;
        frame_t *f = &s->frames[s->nframes];
        snprintf(path, sizeof path, "%.1300s/%.255s", sdir, names[k]);
        if (train_read_render(path, 1, &f->w, &f->h, &f->color, &f->albedo, &f->normal, &f->depth)) continue;
        if (f->w != rw || f->h != rh) continue;
        f->spp = spp;
        if (s->val) {
            f->ref = (float *)malloc(sizeof(float) * 3 * (size_t)rw * rh);
            memcpy(f->ref, r, sizeof(float) * 3 * (size_t)rw * rh);
            if (ew_kpcn_frame_init(&f->f, f->w, f->h, f->color, f->albedo, f->normal, f->depth, r, 3.0f)) return 1;
        } else {
            if (ew_kpcn_frame_init(&f->f, f->w, f->h, f->color, f->albedo, f->normal, f->depth, r, 3.0f)) return 1;
            free(f->color);
            free(f->albedo);
            free(f->normal);
            free(f->depth);
            f->color = f->albedo = f->normal = f->depth = NULL;
        }
        s->nframes++;
    }
    free(r);
    if (s->nframes) held_gb += gb;
    return s->nframes ? 0 : 1;
}

static int is_allowed(const char *name) {
    if (!allowed) return 1;
    for (int i = 0; i < nallowed; i++)
        if (!strcmp(allowed[i], name)) return 1;
    return 0;
}

/* --scenes: the last word of each line, its last path component */
static int read_allowed(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) return 1;
    allowed = calloc(MAX_SCENES, sizeof *allowed);
    char line[2048];
    while (allowed && nallowed < MAX_SCENES && fgets(line, sizeof line, f)) {
        char *e = line + strcspn(line, "\r\n");
        while (e > line && (e[-1] == ' ' || e[-1] == '\t')) e--;
        *e = '\0';
        char *w = e;
        while (w > line && w[-1] != ' ' && w[-1] != '\t' && w[-1] != '/') w--;
        if (*w && line[0] != '#') snprintf(allowed[nallowed++], 256, "%.255s", w);
    }
    fclose(f);
    return allowed ? 0 : 1;
}

/* MODEL.scenes: the scenes this run has loaded, for --scenes */
static void write_scenes(const char *model) {
    char path[1100];
    snprintf(path, sizeof path, "%s.scenes", model);
    FILE *f = fopen(path, "w");
    if (!f) return;
    for (int i = 0; i < nscenes; i++) fprintf(f, "%s %s/%s\n", scenes[i].val ? "val" : "train", scenes[i].dir, scenes[i].name);
    fclose(f);
}

static int known(const char *dir, const char *name) {
    for (int i = 0; i < nscenes; i++)
        if (!strcmp(scenes[i].name, name) && !strcmp(scenes[i].dir, dir)) return 1;
    return 0;
}

/* Add the complete scenes of dir not loaded yet. shared: the cycles-train
 * split rule, training scenes only. Returns the number added. */
static int scan_dir(const char *dir, int val, int shared, int val_max) {
    DIR *d = opendir(dir);
    if (!d) return 0;
    static char found[MAX_SCENES][256];
    int nf = 0;
    struct dirent *e;
    while ((e = readdir(d)) && nf < MAX_SCENES) {
        if (e->d_name[0] == '.' || strchr(e->d_name, '.')) continue; /* ".partial": still rendering */
        if (!strchr(e->d_name, '_')) continue;
        snprintf(found[nf++], 256, "%.255s", e->d_name);
    }
    closedir(d);
    qsort(found, (size_t)nf, 256, cmp_name);
    int added = 0, nval = 0;
    for (int i = 0; i < nscenes; i++) nval += scenes[i].val;
    for (int i = 0; i < nf; i++) {
        if (is_test_scene(found[i])) continue;
        if (shared) {
            /* family = up to the second '_'; last of a family is test, in
             * families of four or more the one before is validation */
            const char *u2 = strchr(strchr(found[i], '_') + 1, '_');
            size_t fl = u2 ? (size_t)(u2 - found[i]) : 0;
            int j = i;
            while (j < nf && !strncmp(found[j], found[i], fl) && found[j][fl] == '_') j++;
            int count = 0, pos = 0;
            for (int k = 0; k < nf; k++)
                if (!strncmp(found[k], found[i], fl) && found[k][fl] == '_') {
                    if (k < i) pos++;
                    count++;
                }
            (void)j;
            if (count >= 2 && pos == count - 1) continue;
            if (count >= 4 && pos == count - 2) continue;
        }
        int as_val = val;
        if (!shared && !val && holdout > 1) {
            /* render_cache.sh names scene i of family k with seed base + 16 i + k: hold out the
             * scenes with (i + k) % holdout == 0 — whole scenes, a fixed set as the cache grows,
             * spread over the families */
            const char *u1 = strchr(found[i], '_'), *u2 = u1 ? strchr(u1 + 1, '_') : NULL;
            long seed = u2 ? strtol(u2 + 1, NULL, 10) : 0, off = seed % 50000; /* base 150000 or 250000 */
            if ((off / 16 + off % 16) % holdout == 0) as_val = 1;
        }
        if (known(dir, found[i]) || nscenes >= MAX_SCENES || !is_allowed(found[i])) continue;
        if (as_val && nval >= val_max) continue;
        if (only_val && !as_val) continue;
        scene_t *s = &scenes[nscenes];
        memset(s, 0, sizeof *s);
        snprintf(s->name, sizeof s->name, "%.255s", found[i]);
        snprintf(s->dir, sizeof s->dir, "%.1023s", dir);
        s->val = as_val;
        if (over_budget) break;
        const int lr = load_scene(s);
        if (lr == 2) {
            fprintf(stderr,
                    "train_kpcn: scene %s/%s would take the scenes held past %.1f GB (%.1f GB loaded, %d scenes): "
                    "no more scenes are loaded; fewer sample counts (--train-spp 1,4,16,64), a --scenes list or "
                    "--max-memory-gb choose what fits\n",
                    dir, found[i], memory_budget_gb(), held_gb, nscenes);
            over_budget = 1;
            break;
        }
        if (lr != 0) {
            fprintf(stderr, "train_kpcn: skipped scene %s/%s (unreadable or incomplete)\n", dir, found[i]);
            continue;
        }
        printf("  %s %s/%s (%d frames)\n", as_val ? "val  " : "train", dir, found[i], s->nframes);
        nscenes++;
        added++;
        nval += as_val;
    }
    return added;
}

static void scan_all(const options *o) {
    for (int i = 0; i < o->ntrain_dirs; i++) scan_dir(o->train[i], 0, 0, o->val_max);
    if (o->shared) scan_dir(o->shared, 0, 1, 0);
    for (int i = 0; i < o->nval_dirs; i++) scan_dir(o->val[i], 1, 0, o->val_max);
    fflush(stdout);
}

/* flat list of training frames for patches */
static ew_kpcn_frame *tframes;
static int ntframes, *scene_first, *scene_count, ntscenes;

static void build_index(void) {
    free(tframes);
    free(scene_first);
    free(scene_count);
    int n = 0, ns = 0;
    for (int i = 0; i < nscenes; i++)
        if (!scenes[i].val) {
            n += scenes[i].nframes;
            ns++;
        }
    tframes = (ew_kpcn_frame *)malloc(sizeof *tframes * (size_t)(n ? n : 1));
    scene_first = (int *)malloc(sizeof(int) * (size_t)(ns ? ns : 1));
    scene_count = (int *)malloc(sizeof(int) * (size_t)(ns ? ns : 1));
    ntframes = 0;
    ntscenes = 0;
    for (int i = 0; i < nscenes; i++) {
        if (scenes[i].val) continue;
        scene_first[ntscenes] = ntframes;
        scene_count[ntscenes] = scenes[i].nframes;
        for (int k = 0; k < scenes[i].nframes; k++) tframes[ntframes++] = scenes[i].frames[k].f; /* shallow */
        ntscenes++;
    }
}

static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static ew_kpcn_patch pick(uint64_t seed, uint64_t step, int index, int size) {
    uint64_t h = mix64(seed * 0x9E3779B97F4A7C15ull + mix64(step * 0xD1B54A32D192ED03ull + (uint64_t)index + 1));
    uint64_t h2 = mix64(h + 1), h3 = mix64(h + 2), h4 = mix64(h + 3), h5 = mix64(h + 4);
    ew_kpcn_patch p;
    const int sc = (int)(h % (uint64_t)ntscenes);
    p.frame = scene_first[sc] + (int)(h5 % (uint64_t)scene_count[sc]);
    const ew_kpcn_frame *f = &tframes[p.frame];
    p.x0 = (int)(h2 % (uint64_t)(f->width - size + 1));
    p.y0 = (int)(h3 % (uint64_t)(f->height - size + 1));
    p.aug = (int)(h4 & 7u);
    return p;
}

/* ---- evaluation ------------------------------------------------------------ */
static int run_op(ew_device *dev, const frame_t *f, const char *method, const void *weights, size_t wsize,
                  float *out, double *psnr) {
    ew_image c = ew_image_packed(f->color, f->w, f->h, 3), r = ew_image_packed(f->ref, f->w, f->h, 3);
    ew_image o = ew_image_packed(out, f->w, f->h, 3);
    if (method) {
        ew_image a = ew_image_packed(f->albedo, f->w, f->h, 3), n = ew_image_packed(f->normal, f->w, f->h, 3);
        ew_image d = ew_image_packed(f->depth, f->w, f->h, 1);
        ew_denoiser *dn = NULL;
        ew_result res = ew_denoiser_create(dev, method, &dn);
        if (res == EW_OK && weights) res = ew_denoiser_set_data(dn, "weights", weights, wsize);
        if (res == EW_OK && !strcmp(method, "auto")) res = ew_denoiser_set_int(dn, "samples", f->spp);
        if (res == EW_OK && !strcmp(method, "auto")) res = ew_denoiser_set_int(dn, "quality", auto_quality);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "color", &c);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "albedo", &a);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "normal", &n);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "depth", &d);
        if (res == EW_OK) res = ew_denoiser_set_image(dn, "output", &o);
        if (res == EW_OK) res = ew_denoiser_commit(dn);
        if (res == EW_OK) res = ew_denoiser_execute(dn);
        ew_denoiser_destroy(dn);
        if (res != EW_OK) {
            fprintf(stderr, "train_kpcn: %s failed: %s\n", method, ew_device_last_error(dev));
            return 1;
        }
    } else {
        memcpy(out, f->color, sizeof(float) * 3 * (size_t)f->w * f->h);
    }
    return ew_image_psnr(dev, &o, &r, psnr) != EW_OK;
}

static int spp_index(int spp) { return spp == 1 ? 0 : spp == 4 ? 1 : spp == 16 ? 2 : 3; }

/* Mean PSNR per spp level (1/4/16/64) and over all, of a method on the
 * validation scenes. */
static FILE *eval_rows; /* --eval-csv: per-frame rows, for differences between models scene by scene */

static int validate(ew_device *dev, const char *method, const void *weights, size_t wsize, double *per, double *all,
                    int *nval_scenes) {
    double sum[4] = {0, 0, 0, 0};
    int cnt[4] = {0, 0, 0, 0}, ns = 0;
    static float out[4096 * 4096 * 3 / 16];
    for (int i = 0; i < nscenes; i++) {
        if (!scenes[i].val) continue;
        ns++;
        for (int k = 0; k < scenes[i].nframes; k++) {
            const frame_t *f = &scenes[i].frames[k];
            if ((size_t)f->w * f->h * 3 > sizeof out / sizeof out[0]) continue;
            double p;
            if (run_op(dev, f, method, weights, wsize, out, &p)) return 1;
            if (eval_rows) fprintf(eval_rows, "%s,%d,%d,%s,%.4f\n", scenes[i].name, k, f->spp, method ? method : "input", p);
            sum[spp_index(f->spp)] += p;
            cnt[spp_index(f->spp)]++;
        }
    }
    double a = 0;
    int na = 0;
    for (int k = 0; k < 4; k++) {
        per[k] = cnt[k] ? sum[k] / cnt[k] : 0.0;
        a += sum[k];
        na += cnt[k];
    }
    *all = na ? a / na : 0.0;
    *nval_scenes = ns;
    return 0;
}

/* The trainer's own forward pass on whole square validation frames (the
 * op's kernels, run on the host); the library's op gives the same numbers
 * (tests/unit/test_kpcn.c compares them). */
static int validate_host(ew_device *dev, const ew_kpcn_net *net, const float *params, double *per, double *all) {
    double sum[4] = {0, 0, 0, 0};
    int cnt[4] = {0, 0, 0, 0};
    static ew_kpcn_scratch *scr;
    static int scr_size;
    static ew_kpcn_model model;
    static int model_ok;
    if (!model_ok) {
        if (ew_kpcn_model_init(&model, net)) return 1;
        model_ok = 1;
    }
    ew_kpcn_model_prepare(&model, params);
    for (int i = 0; i < nscenes; i++) {
        if (!scenes[i].val) continue;
        for (int k = 0; k < scenes[i].nframes; k++) {
            frame_t *f = &scenes[i].frames[k];
            if (f->w != f->h || f->w % ew_kpcn_align(net)) continue;
            if (scr_size != f->w) {
                ew_kpcn_scratch_destroy(scr);
                scr = ew_kpcn_scratch_create(net, f->w);
                scr_size = f->w;
                if (!scr) return 1;
            }
            float *out = (float *)malloc(sizeof(float) * 3 * (size_t)f->w * f->h);
            ew_kpcn_patch p = {0, 0, 0, 0};
            ew_kpcn_train_patch(&model, &f->f, &p, f->w, EW_KPCN_LOSS_TM, scr, NULL, out, NULL);
            ew_image o = ew_image_packed(out, f->w, f->h, 3), r = ew_image_packed(f->ref, f->w, f->h, 3);
            double q = 0;
            ew_image_psnr(dev, &o, &r, &q);
            free(out);
            sum[spp_index(f->spp)] += q;
            cnt[spp_index(f->spp)]++;
        }
    }
    double a = 0;
    int na = 0;
    for (int k = 0; k < 4; k++) {
        per[k] = cnt[k] ? sum[k] / cnt[k] : 0.0;
        a += sum[k];
        na += cnt[k];
    }
    *all = na ? a / na : 0.0;
    return 0;
}

/* ---- checkpoints -------------------------------------------------------------- */
static int save_checkpoint(const char *path, const ew_kpcn_net *net, const float *params, const ew_adam *adam,
                           long step) {
    void *bytes;
    size_t size;
    if (ew_kpcn_save(net, params, &bytes, &size) != 0) return 1;
    int bad = train_checkpoint_save(path, bytes, size, adam, net->nparams, step);
    free(bytes);
    return bad;
}

/* 0 resumed, 1 no checkpoint, 2 one that cannot be used (printed) */
static int load_checkpoint(const char *path, const ew_kpcn_net *net, float *params, ew_adam *adam, long *step) {
    ew_weights w;
    int r = train_checkpoint_load(path, net->nparams, &w, adam, step);
    if (r) return r;
    ew_kpcn_net back;
    float *p = NULL;
    char err[256];
    int bad = ew_kpcn_from_weights(&back, &w, &p, err, sizeof err);
    ew_weights_free(&w);
    if (bad || strcmp(back.arch, net->arch) != 0) {
        fprintf(stderr, "train_kpcn: checkpoint '%s' does not match --arch %s (%s)\n", path, net->arch,
                bad ? err : back.arch);
        free(p);
        return 2;
    }
    memcpy(params, p, sizeof(float) * net->nparams);
    free(p);
    return 0;
}

/* models/kpcn/<name>.ewm of every built-in model as C arrays (core/algorithms/kpcn_weights_data.c) */
static int emit_c(const char *dir) {
    printf("/* The kpcn models built into the library: byte-for-byte copies of\n"
           " * models/kpcn/<name>.ewm (algorithms/kpcn.c's ew_kpcn_model_names), generated by\n"
           " *   train_kpcn --emit-c models/kpcn > core/algorithms/kpcn_weights_data.c\n"
           " * (tests/unit/test_kpcn.c checks they match the files). A size of 0 means\n"
           " * this build has no weights for that model. */\n#include \"algorithms/kpcn.h\"\n");
    for (int k = 0; k < EW_KPCN_NUM_MODELS; k++) {
        char path[1200];
        snprintf(path, sizeof path, "%.1100s/%s.ewm", dir, ew_kpcn_model_name(k));
        size_t size = 0;
        unsigned char *b = (unsigned char *)train_read_file(path, &size);
        printf("\n/* %s */\nstatic const unsigned char weights_%d[] = {", ew_kpcn_model_name(k), k);
        if (!b) printf("0");
        for (size_t i = 0; b && i < size; i++) printf("%s%u%s", i % 24 == 0 ? "\n    " : "", b[i], i + 1 < size ? "," : "");
        printf("%s};\n", b ? "\n" : "");
        free(b);
        if (!b) size = 0;
        printf("#define WEIGHTS_%d_SIZE %zu\n", k, size);
    }
    printf("\nconst unsigned char *const ew_kpcn_builtin_bytes[EW_KPCN_NUM_MODELS] = {");
    for (int k = 0; k < EW_KPCN_NUM_MODELS; k++) printf("%sweights_%d", k ? ", " : "", k);
    printf("};\nconst size_t ew_kpcn_builtin_sizes[EW_KPCN_NUM_MODELS] = {");
    for (int k = 0; k < EW_KPCN_NUM_MODELS; k++) printf("%sWEIGHTS_%d_SIZE", k ? ", " : "", k);
    printf("};\n");
    return 0;
}

/* --bench W H THREADS: time the built-in models on a W x H frame (a smooth
 * pattern with noise: convolution time does not depend on the content),
 * the convolutions' GFLOP/s against the measured FMA peak, and the device
 * memory at 3840x2160. */
static int bench(int w, int h, int threads) {
    ew_device_desc dd = EW_DEVICE_DESC_INIT;
    dd.num_threads = threads;
    ew_device *dev = NULL;
    if (ew_device_create(&dd, &dev) != EW_OK) return 1;
    const size_t n = (size_t)w * h;
    float *c = malloc(n * 3 * sizeof(float)), *a = malloc(n * 3 * sizeof(float)), *nr = malloc(n * 3 * sizeof(float));
    float *z = malloc(n * sizeof(float)), *o = malloc(n * 3 * sizeof(float));
    uint64_t r = 1;
    for (size_t j = 0; j < n; j++) {
        const int x = (int)(j % (size_t)w), y = (int)(j / (size_t)w);
        for (int k = 0; k < 3; k++) {
            r = r * 6364136223846793005ull + 1442695040888963407ull;
            a[j * 3 + k] = 0.2f + 0.6f * (float)((x / 37 + y / 23 + k) % 3) / 2.0f;
            c[j * 3 + k] = a[j * 3 + k] * (0.5f + (float)(r >> 40) / 16777216.0f);
            nr[j * 3 + k] = k == 2 ? 1.0f : 0.0f;
        }
        z[j] = 1.0f + (float)(x / 50);
    }
    double peak_s = 0, peak = ew_conv_cpu_fma_gflops(dev, &peak_s);
    printf("kpcn at %dx%d, %d threads, %s convolutions; FMA peak %.1f GFLOP/s (first sample)\n", w, h, ew_device_get_num_threads(dev),
           ew_conv_cpu_simd_name(ew_conv_cpu_simd_level()), peak);
    for (int m = 0; m < EW_KPCN_NUM_MODELS; m++) {
        ew_denoiser *d = NULL;
        ew_image ic = ew_image_packed(c, w, h, 3), ia = ew_image_packed(a, w, h, 3), in = ew_image_packed(nr, w, h, 3);
        ew_image iz = ew_image_packed(z, w, h, 1), io = ew_image_packed(o, w, h, 3);
        ew_result res = ew_denoiser_create(dev, "kpcn", &d);
        if (res == EW_OK) res = ew_denoiser_set_int(d, "model", m);
        if (res == EW_OK) res = ew_denoiser_set_image(d, "color", &ic);
        if (res == EW_OK) res = ew_denoiser_set_image(d, "albedo", &ia);
        if (res == EW_OK) res = ew_denoiser_set_image(d, "normal", &in);
        if (res == EW_OK) res = ew_denoiser_set_image(d, "depth", &iz);
        if (res == EW_OK) res = ew_denoiser_set_image(d, "output", &io);
        if (res == EW_OK) res = ew_denoiser_commit(d);
        if (res != EW_OK) {
            fprintf(stderr, "train_kpcn: %s\n", ew_device_last_error(dev));
            return 1;
        }
        double best = 1e30;
        for (int rep = 0; rep < 3; rep++) {
            const double t0 = train_now_s();
            ew_denoiser_execute(d);
            best = fmin(best, train_now_s() - t0);
        }
        /* the convolutions alone, on the op's own buffers */
        const unsigned char *bytes;
        size_t size;
        ew_kpcn_builtin_weights(m, &bytes, &size);
        ew_weights wt;
        char err[128];
        ew_kpcn_net net;
        float *p = NULL;
        if (ew_weights_parse(bytes, size, &wt, err, sizeof err) || ew_kpcn_from_weights(&net, &wt, &p, err, sizeof err))
            return 1;
        ew_weights_free(&wt);
        int sw[EW_KPCN_MAX_SCALES], sh[EW_KPCN_MAX_SCALES];
        ew_kpcn_scale_sizes(&net, w, h, sw, sh);
        ew_gn_planes sb[EW_KPCN_MAX_SCALES];
        float *mem[EW_KPCN_MAX_SCALES];
        for (int k = 0; k < net.scales; k++) {
            mem[k] = calloc(ew_gn_planes_floats(sw[k], sh[k], net.nplanes[k]) + 16, sizeof(float));
            ew_gn_planes_layout(&sb[k], mem[k], sw[k], sh[k], net.nplanes[k]);
        }
        /* the direct path and the op's own choice (Winograd where it pays),
         * passes interleaved so both see the same load */
        double conv_best = 1e30, auto_best = 1e30;
        int wino_layers = 0;
        for (int rep = 0; rep < 3; rep++) {
            /* The peak is sampled next to every timed pass and the best kept:
             * on a shared machine one early sample can catch a busy moment
             * the best conv pass missed (a share above 100 % was printed). */
            peak = fmax(peak, ew_conv_cpu_fma_gflops(dev, &peak_s));
            for (int path = EW_CONV_CPU_DIRECT; path >= EW_CONV_CPU_AUTO; path--) {
                const double t0 = train_now_s();
                wino_layers = 0;
                for (int l = 0; l < net.nlayers; l++) {
                    ew_conv_args ca;
                    ew_kpcn_layer_args(&net, l, p, sb, &ca);
                    ca.winograd = 1; /* as the op allows it */
                    wino_layers += ew_cpu_conv5_path(dev, &ca, path, 2) == EW_CONV_CPU_WINOGRAD;
                }
                const double dt = train_now_s() - t0;
                if (path == EW_CONV_CPU_DIRECT) conv_best = fmin(conv_best, dt);
                else auto_best = fmin(auto_best, dt);
            }
        }
        const double flops = 2.0 * ew_kpcn_macs_per_pixel(&net) * (double)n;
        printf("  %-10s (%s): %7.1f ms a frame; convolutions direct %7.1f ms = %.1f GFLOP/s = %.0f %% of the FMA peak "
               "(%.1f GFLOP/s, best sample so far); as the op runs them (Winograd in %d of %d layers) %7.1f ms = "
               "%.2fx faster, %.1f GFLOP/s of direct-convolution work = %.0f %% of the peak; device memory at "
               "3840x2160: %.0f MiB\n",
               ew_kpcn_model_name(m), net.arch, best * 1e3, conv_best * 1e3, flops / conv_best * 1e-9,
               100.0 * flops / conv_best * 1e-9 / peak, peak, wino_layers, net.nlayers, auto_best * 1e3,
               conv_best / auto_best, flops / auto_best * 1e-9, 100.0 * flops / auto_best * 1e-9 / peak,
               (double)(ew_kpcn_device_floats(&net, 3840, 2160) + 23.0 * 3840 * 2160 + net.nparams) * 4.0 / 1048576.0);
        for (int k = 0; k < net.scales; k++) free(mem[k]);
        free(p);
        ew_denoiser_destroy(d);
    }
    free(c); free(a); free(nr); free(z); free(o);
    ew_device_destroy(dev);
    return 0;
}

/* --eval: the model against nbg, auto (quality fast) and the input on the
 * validation scenes */
static int evaluate(const options *opt, ew_device *dev) {
    const options o = *opt;
    only_val = 1;
    for (int i = 0; i < o.nval_dirs; i++) scan_dir(o.val[i], 1, 0, o.val_max);
    for (int i = 0; i < o.ntrain_dirs; i++) scan_dir(o.train[i], 0, 0, o.val_max);
    if (over_budget) return 2; /* scan_dir said why */
    size_t size;
    void *b = train_read_file(o.eval, &size);
    if (!b) {
        fprintf(stderr, "train_kpcn: cannot read '%s'\n", o.eval);
        return 1;
    }
    double per[4], all, pn[4], an, pi[4], ai, pa[4], aa;
    int ns;
    if (o.eval_csv) {
        eval_rows = fopen(o.eval_csv, "w");
        if (!eval_rows) {
            fprintf(stderr, "train_kpcn: cannot write '%s': %s\n", o.eval_csv, strerror(errno));
            free(b);
            return 1;
        }
        fprintf(eval_rows, "scene,index,spp,method,psnr\n");
    }
    auto_quality = 0;
    const int bad = validate(dev, "kpcn", b, size, per, &all, &ns) || validate(dev, "nbg", NULL, 0, pn, &an, &ns) ||
                    validate(dev, NULL, NULL, 0, pi, &ai, &ns) || validate(dev, "auto", NULL, 0, pa, &aa, &ns);
    free(b);
    if (eval_rows && fclose(eval_rows) != 0) {
        fprintf(stderr, "train_kpcn: cannot write '%s': %s\n", o.eval_csv, strerror(errno));
        return 1;
    }
    eval_rows = NULL;
    if (bad) return 1;
    printf("%d scenes, PSNR at 1/4/16/64 spp and all:\n", ns);
    printf("  input %6.2f %6.2f %6.2f %6.2f | %6.2f\n", pi[0], pi[1], pi[2], pi[3], ai);
    printf("  nbg   %6.2f %6.2f %6.2f %6.2f | %6.2f\n", pn[0], pn[1], pn[2], pn[3], an);
    printf("  auto (quality fast) %6.2f %6.2f %6.2f %6.2f | %6.2f\n", pa[0], pa[1], pa[2], pa[3], aa);
    printf("  kpcn  %6.2f %6.2f %6.2f %6.2f | %6.2f\n", per[0], per[1], per[2], per[3], all);
    return 0;
}

/* What a training run holds, freed by main however train() ends. */
static struct {
    float *params, *grad, *m, *v;
    ew_kpcn_trainer *tr;
    FILE *csv;
} held;

static void held_free(void) {
    free(held.params);
    free(held.grad);
    free(held.m);
    free(held.v);
    if (held.tr) ew_kpcn_trainer_destroy(held.tr);
    if (held.csv) fclose(held.csv);
    memset(&held, 0, sizeof held);
}

static int train(const options *opt, ew_device *dev) {
    const options o = *opt;
    char err[256];
    ew_kpcn_net net;
    if (ew_kpcn_init(&net, o.arch, err, sizeof err) != 0) {
        fprintf(stderr, "train_kpcn: %s\n", err);
        return 2;
    }
    if (o.run.patch % ew_kpcn_align(&net)) {
        fprintf(stderr, "train_kpcn: --patch must be a multiple of %d for %s (its coarsest scale pools it %d times)\n",
                ew_kpcn_align(&net), net.arch, net.scales - 1);
        return 2;
    }
    float *params = held.params = (float *)malloc(sizeof(float) * net.nparams);
    float *grad = held.grad = (float *)malloc(sizeof(float) * net.nparams);
    ew_adam adam = {o.run.lr, 0.9, 0.999, 1e-8, 0, held.m = (float *)calloc(net.nparams, sizeof(float)),
                    held.v = (float *)calloc(net.nparams, sizeof(float))};
    if (!params || !grad || !adam.m || !adam.v) {
        fprintf(stderr, "train_kpcn: out of memory for %zu parameters\n", net.nparams);
        return 1;
    }
    ew_kpcn_random(&net, o.run.seed, params);
    long step = 0;
    int resumed = 0;
    if (o.run.resume) {
        int r = load_checkpoint(o.run.checkpoint, &net, params, &adam, &step);
        if (r == 2) return 1;
        resumed = r == 0;
        printf(r == 0 ? "resumed from %s at step %ld\n" : "no checkpoint at %s: from scratch (step %ld)\n",
               o.run.checkpoint, step);
    }
    if (o.init && !resumed) {
        size_t size = 0;
        void *bytes = train_read_file(o.init, &size);
        ew_weights w;
        ew_kpcn_net src;
        float *sp = NULL;
        if (!bytes || ew_weights_parse(bytes, size, &w, err, sizeof err) != 0) {
            fprintf(stderr, "train_kpcn: --init %s: %s\n", o.init, bytes ? err : "cannot read");
            return 1;
        }
        free(bytes);
        int bad = ew_kpcn_from_weights(&src, &w, &sp, err, sizeof err);
        ew_weights_free(&w);
        if (bad || src.scales > net.scales) {
            fprintf(stderr, "train_kpcn: --init %s: %s\n", o.init,
                    bad ? err : "it has more scales than --arch: nothing to continue from");
            return 1;
        }
        ew_kpcn_params_from(&net, params, &src, sp);
        free(sp);
        printf("initialised from %s (%s)\n", o.init, src.arch);
    }
    double t0 = train_now_s();
    printf("scenes:\n");
    scan_all(&o);
    build_index();
    printf("%d training scenes (%d frames), %d validation scenes; loaded in %.1f s, %.1f GB\n", ntscenes, ntframes,
           nscenes - ntscenes, train_now_s() - t0, held_gb);
    if (over_budget) return 2; /* scan_dir said why: a run that trains on what it was given, or not at all */
    if (ntscenes == 0) {
        fprintf(stderr, "train_kpcn: no training scenes\n");
        return 1;
    }
    ew_kpcn_trainer *tr = held.tr = ew_kpcn_trainer_create(dev, &net, o.run.batch, o.run.patch, o.loss);
    if (!tr) {
        fprintf(stderr, "train_kpcn: out of memory for the trainer\n");
        return 1;
    }
    printf("arch %s: %zu parameters, %.0f multiply-adds a pixel; seed %lu, %ld steps of %d patches of %d^2, "
           "lr %g -> %g, clip %g, loss %s, %d threads\n",
           net.arch, net.nparams, ew_kpcn_macs_per_pixel(&net), o.run.seed, o.run.steps, o.run.batch, o.run.patch, o.run.lr, o.run.lr_final,
           o.run.clip, o.loss == EW_KPCN_LOSS_LOG ? "log" : o.loss == EW_KPCN_LOSS_PSNR ? "psnr" : "tm", ew_device_get_num_threads(dev));
    FILE *csv = held.csv = fopen(o.csv, step > 0 ? "a" : "w");
    if (!csv) {
        fprintf(stderr, "train_kpcn: cannot write '%s'\n", o.csv);
        return 1;
    }
    if (step == 0)
        fprintf(csv, "step,seconds,lr,train_loss,grad_norm,train_scenes,val_scenes,val_psnr,val_1,val_4,val_16,val_64,"
                     "nbg_psnr,nbg_1,nbg_4,nbg_16,nbg_64\n");
    double nbg_per[4] = {0, 0, 0, 0}, nbg_all = 0;
    int nbg_scenes = -1;
    const double start = train_now_s();
    const long step0 = step;
    double last_ckpt = start, loss_acc = 0, gn_acc = 0;
    int acc_n = 0;
    for (;;) {
        const int last = step >= o.run.steps || (o.time_limit > 0 && train_now_s() - start > o.time_limit * 60.0);
        if (!last && o.run.stop_after > 0 && step >= o.run.stop_after && step > step0) {
            /* before this step's validation, which the resumed run does */
            if (save_checkpoint(o.run.checkpoint, &net, params, &adam, step) != 0) {
                fprintf(stderr, "train_kpcn: cannot write checkpoint '%s'\n", o.run.checkpoint);
                return 1;
            }
            printf("stopped at step %ld (--stop-after); --resume continues\n", step);
            break;
        }
        if (step % o.run.val_every == 0 || last) {
            if (o.rescan && step > 0 && !last) {
                scan_all(&o);
                build_index();
            }
            void *bytes;
            size_t size;
            if (ew_kpcn_save(&net, params, &bytes, &size) == 0) {
                if (train_write_file_atomic(o.out, bytes, size) != 0)
                    fprintf(stderr, "train_kpcn: cannot write '%s'\n", o.out);
                write_scenes(o.out);
                double per[4] = {0, 0, 0, 0}, all = 0;
                int ns = 0;
                ns = nscenes - ntscenes;
                if (ns > 0) validate_host(dev, &net, params, per, &all);
                if (ns > 0 && ns != nbg_scenes) {
                    int k;
                    validate(dev, "nbg", NULL, 0, nbg_per, &nbg_all, &k);
                    nbg_scenes = ns;
                }
                free(bytes);
                printf("step %6ld  %7.0f s  loss %.5f  |g| %.4f  train %d scenes  val %d scenes: kpcn %.2f dB "
                       "(%.2f %.2f %.2f %.2f)  nbg %.2f (%.2f %.2f %.2f %.2f)\n",
                       step, train_now_s() - start, acc_n ? loss_acc / acc_n : 0.0, acc_n ? gn_acc / acc_n : 0.0, ntscenes,
                       ns, all, per[0], per[1], per[2], per[3], nbg_all, nbg_per[0], nbg_per[1], nbg_per[2],
                       nbg_per[3]);
                fprintf(csv, "%ld,%.0f,%g,%.6f,%.5f,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", step,
                        train_now_s() - start, adam.lr, acc_n ? loss_acc / acc_n : 0.0, acc_n ? gn_acc / acc_n : 0.0,
                        ntscenes, ns, all, per[0], per[1], per[2], per[3], nbg_all, nbg_per[0], nbg_per[1],
                        nbg_per[2], nbg_per[3]);
                fflush(csv);
                fflush(stdout);
            }
            loss_acc = gn_acc = 0;
            acc_n = 0;
        }
        if (last || train_now_s() - last_ckpt > o.run.ckpt_minutes * 60.0) {
            if (save_checkpoint(o.run.checkpoint, &net, params, &adam, step) != 0)
                fprintf(stderr, "train_kpcn: cannot write checkpoint '%s'\n", o.run.checkpoint);
            last_ckpt = train_now_s();
        }
        if (last) break;
        static ew_kpcn_patch patches[1024];
        for (int b = 0; b < o.run.batch && b < 1024; b++) patches[b] = pick(o.run.seed, (uint64_t)step, b, o.run.patch);
        /* cosine over --steps, or over --time-limit when that ends first */
        double t = (double)step / (double)o.run.steps;
        if (o.time_limit > 0) t = fmax(t, (train_now_s() - start) / (o.time_limit * 60.0));
        if (t > 1.0) t = 1.0;
        adam.lr = o.run.lr_final + 0.5 * (o.run.lr - o.run.lr_final) * (1.0 + cos(3.14159265358979 * t));
        const double loss = ew_kpcn_trainer_gradient(tr, params, tframes, patches, grad);
        int clipped;
        const double gn = ew_adam_step(&adam, params, grad, net.nparams, o.run.clip, &clipped);
        loss_acc += loss;
        gn_acc += gn;
        acc_n++;
        step++;
        if (step % 10 == 0) {
            printf("  step %ld loss %.5f |g| %.4f%s  %.2f s/step\n", step, loss, gn, clipped ? " (clipped)" : "",
                   (train_now_s() - start) / (double)(step - step0));
            fflush(stdout);
        }
    }
    return 0;
}

const char *train_prog = "train_kpcn";

int main(int argc, char **argv) {
    static options o;
    if (argc == 3 && !strcmp(argv[1], "--emit-c")) return emit_c(argv[2]);
    if (argc == 5 && !strcmp(argv[1], "--bench")) {
        int w, h, threads;
        if (!train_parse_int("--bench W", argv[2], 16, 16384, &w) || !train_parse_int("--bench H", argv[3], 16, 16384, &h) ||
            !train_parse_int("--bench THREADS", argv[4], 0, 1024, &threads))
            return 2;
        return bench(w, h, threads);
    }
    if (!parse(argc, argv, &o)) return 2;
    ew_device_desc dd = EW_DEVICE_DESC_INIT;
    dd.num_threads = o.run.threads;
    ew_device *dev = NULL;
    if (ew_device_create(&dd, &dev) != EW_OK) {
        fprintf(stderr, "train_kpcn: cannot create the device\n");
        return 1;
    }
    if (o.scenes && read_allowed(o.scenes) != 0) {
        fprintf(stderr, "train_kpcn: cannot read --scenes '%s'\n", o.scenes);
        ew_device_destroy(dev);
        return 2;
    }
    const int rc = o.eval ? evaluate(&o, dev) : train(&o, dev);
    held_free();
    ew_device_destroy(dev);
    return rc;
}
