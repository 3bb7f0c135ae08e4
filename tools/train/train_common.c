/* train_common.c — see train_common.h. */
#include "train_common.h"

#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cycles_passes.h"
#include "ewio.h"

double train_now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void *train_read_file(const char *path, size_t *size) {
    *size = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    /* a directory opens too, and reports a size no allocation can take */
    struct stat st;
    int e = 0;
    if (fstat(fileno(f), &st) != 0) e = errno;
    else if (S_ISDIR(st.st_mode)) e = EISDIR;
    else if (!S_ISREG(st.st_mode) || st.st_size <= 0) e = EINVAL; /* a device, a FIFO, an empty file: none is ours to read */
    if (e) {
        fclose(f);
        errno = e;
        return NULL;
    }
    const size_t n = (size_t)st.st_size;
    void *buf = malloc(n);
    const int bad = !buf || fread(buf, 1, n, f) != n;
    fclose(f);
    if (bad) {
        free(buf);
        errno = EIO;
        return NULL;
    }
    *size = n;
    return buf;
}

int train_write_file_atomic(const char *path, const void *data, size_t size) {
    char tmp[PATH_MAX];
    if (snprintf(tmp, sizeof tmp, "%s.XXXXXX", path) >= (int)sizeof tmp) return 1;
    int fd = mkstemp(tmp);
    if (fd < 0) return 1;
    /* mkstemp makes the file 0600; a model is as readable as any file the user writes */
    mode_t mask = umask(0);
    umask(mask);
    int bad = fchmod(fd, 0666 & ~mask) != 0;
    const char *p = (const char *)data;
    for (size_t left = size; !bad && left > 0;) {
        ssize_t k = write(fd, p, left);
        if (k < 0 && errno == EINTR) continue;
        bad = k <= 0;
        if (!bad) {
            p += k;
            left -= (size_t)k;
        }
    }
    bad |= fsync(fd) != 0;
    bad |= close(fd) != 0;
    if (bad || rename(tmp, path) != 0) {
        unlink(tmp);
        return 1;
    }
    return 0;
}

int train_read_render(const char *path, int want_features, int *w, int *h, float **color, float **albedo,
                      float **normal, float **depth) {
    char err[1024];
    ewio_file *f = NULL;
    if (ewio_read(path, &f, err, sizeof err) != 0) {
        fprintf(stderr, "%s: %s\n", train_prog, err);
        return 1;
    }
    ew_layer_passes lp;
    int found = 0;
    for (int i = 0; i < ewio_num_layers(f) && !found; i++)
        found = ew_find_layer_passes(f, ewio_layer_name(f, i), &lp, err, sizeof err) == 0;
    if (!found) {
        fprintf(stderr, "%s: '%s' has no colour pass\n", train_prog, path);
        ewio_free(f);
        return 1;
    }
    *w = ewio_width(f);
    *h = ewio_height(f);
    const size_t n = (size_t)*w * *h;
    *color = (float *)malloc(n * 3 * sizeof(float));
    int bad = !*color || ewio_get_pass(f, lp.layer, lp.color, "RGB", *color, err, sizeof err) != 0;
    if (!bad && want_features) {
        if (!lp.albedo || !lp.normal || !lp.depth) {
            snprintf(err, sizeof err, "'%s' lacks albedo, normal or depth passes", path);
            bad = 1;
        } else {
            *albedo = (float *)malloc(n * 3 * sizeof(float));
            *normal = (float *)malloc(n * 3 * sizeof(float));
            *depth = (float *)malloc(n * sizeof(float));
            bad = !*albedo || !*normal || !*depth ||
                  ewio_get_pass(f, lp.layer, lp.albedo, "RGB", *albedo, err, sizeof err) != 0 ||
                  ewio_get_pass(f, lp.layer, lp.normal, "XYZ", *normal, err, sizeof err) != 0 ||
                  ewio_get_pass(f, lp.layer, lp.depth, "Z", *depth, err, sizeof err) != 0;
        }
    }
    ewio_free(f);
    if (bad) fprintf(stderr, "%s: %s\n", train_prog, err);
    return bad;
}

int train_checkpoint_save(const char *path, const void *model, size_t model_size, const ew_adam *adam,
                          size_t nparams, long step) {
    ew_weights w;
    char err[256];
    if (ew_weights_parse(model, model_size, &w, err, sizeof err) != 0) return 1;
    ew_tensor *t = (ew_tensor *)realloc(w.tensors, sizeof(ew_tensor) * (w.num_tensors + 3));
    if (!t) {
        ew_weights_free(&w);
        return 1;
    }
    w.tensors = t;
    float stepf[2] = {(float)(step / 65536), (float)(step % 65536)};
    ew_tensor extra[3];
    memset(extra, 0, sizeof extra);
    snprintf(extra[0].name, sizeof extra[0].name, "adam.m");
    snprintf(extra[1].name, sizeof extra[1].name, "adam.v");
    snprintf(extra[2].name, sizeof extra[2].name, "train.step");
    extra[0].rank = extra[1].rank = extra[2].rank = 1;
    extra[0].dims[0] = extra[1].dims[0] = (uint32_t)nparams;
    extra[0].count = extra[1].count = nparams;
    extra[2].dims[0] = 2;
    extra[2].count = 2;
    extra[0].data = adam->m;
    extra[1].data = adam->v;
    extra[2].data = stepf;
    for (int k = 0; k < 3; k++) w.tensors[w.num_tensors + (uint32_t)k] = extra[k];
    w.num_tensors += 3;
    void *bytes;
    size_t size;
    int bad = ew_weights_serialize(&w, &bytes, &size) != 0;
    w.num_tensors -= 3; /* the extra tensors' data is not the parse's to free */
    ew_weights_free(&w);
    if (bad) return 1;
    bad = train_write_file_atomic(path, bytes, size);
    free(bytes);
    return bad;
}

int train_checkpoint_load(const char *path, size_t nparams, ew_weights *w, ew_adam *adam, long *step) {
    size_t size;
    void *bytes = train_read_file(path, &size);
    if (!bytes) {
        if (errno == ENOENT) return 1;
        /* there is a file: starting over would overwrite it at the first checkpoint */
        fprintf(stderr, "%s: checkpoint '%s' exists but cannot be read (%s)\n", train_prog, path, strerror(errno));
        return 2;
    }
    char err[256];
    int bad = ew_weights_parse(bytes, size, w, err, sizeof err);
    free(bytes);
    if (bad) {
        fprintf(stderr, "%s: checkpoint '%s': %s\n", train_prog, path, err);
        return 2;
    }
    uint32_t nd[1] = {(uint32_t)nparams}, sd[1] = {2};
    const ew_tensor *m = ew_weights_find(w, "adam.m", 1, nd, err, sizeof err);
    const ew_tensor *v = m ? ew_weights_find(w, "adam.v", 1, nd, err, sizeof err) : NULL;
    const ew_tensor *s = v ? ew_weights_find(w, "train.step", 1, sd, err, sizeof err) : NULL;
    if (!s) {
        fprintf(stderr, "%s: checkpoint '%s' is not one of this architecture's (%s)\n", train_prog, path, err);
        ew_weights_free(w);
        return 2;
    }
    memcpy(adam->m, m->data, sizeof(float) * nparams);
    memcpy(adam->v, v->data, sizeof(float) * nparams);
    *step = (long)s->data[0] * 65536 + (long)s->data[1];
    adam->step = (uint64_t)*step;
    return 0;
}

int train_run_option(int c, const char *v, train_run_opts *r, int *ok) {
    long seed;
    switch (c) {
    case TRAIN_OPT_SEED:
        *ok = train_parse_long("--seed", v, 0, LONG_MAX, &seed);
        if (*ok) r->seed = (unsigned long)seed;
        return 1;
    case TRAIN_OPT_STEPS: *ok = train_parse_long("--steps", v, 1, 100000000, &r->steps); return 1;
    case TRAIN_OPT_BATCH: *ok = train_parse_int("--batch", v, 1, 4096, &r->batch); return 1;
    case TRAIN_OPT_PATCH: *ok = train_parse_int("--patch", v, 16, 4096, &r->patch); return 1;
    case TRAIN_OPT_LR: *ok = train_parse_double("--lr", v, 0, 1, &r->lr); return 1;
    case TRAIN_OPT_LR_FINAL: *ok = train_parse_double("--lr-final", v, 0, 1, &r->lr_final); return 1;
    case TRAIN_OPT_CLIP: *ok = train_parse_double("--clip", v, 0, 1e9, &r->clip); return 1;
    case TRAIN_OPT_THREADS: *ok = train_parse_int("--threads", v, 0, 1024, &r->threads); return 1;
    case TRAIN_OPT_VAL_EVERY: *ok = train_parse_long("--val-every", v, 1, 100000000, &r->val_every); return 1;
    case TRAIN_OPT_STOP_AFTER: *ok = train_parse_long("--stop-after", v, 1, 100000000, &r->stop_after); return 1;
    case TRAIN_OPT_CHECKPOINT:
        *ok = snprintf(r->checkpoint, sizeof r->checkpoint, "%s", v) < (int)sizeof r->checkpoint;
        if (!*ok) fprintf(stderr, "%s: --checkpoint: the path is too long\n", train_prog);
        return 1;
    case TRAIN_OPT_CKPT_MINUTES:
        *ok = train_parse_double("--checkpoint-minutes", v, 0, 1e6, &r->ckpt_minutes);
        return 1;
    case TRAIN_OPT_RESUME: r->resume = 1; return 1;
    default: return 0;
    }
}

int train_getopt_other(int c, const char *arg, const char *usage) {
    if (c == 'h') {
        fputs(usage, stdout);
        exit(0);
    }
    if (c == ':') fprintf(stderr, "%s: %s needs a value\n", train_prog, arg);
    else fprintf(stderr, "%s: unknown option '%s'\n%s", train_prog, arg, usage);
    return 0;
}

int train_no_operands(int argc, char **argv, const char *usage) {
    if (optind >= argc) return 1;
    fprintf(stderr, "%s: unexpected argument '%s'\n%s", train_prog, argv[optind], usage);
    return 0;
}

int train_parse_long(const char *opt, const char *s, long lo, long hi, long *out) {
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (!*s || *end || errno || v < lo || v > hi) {
        fprintf(stderr, "%s: %s takes a whole number from %ld to %ld, not '%s'\n", train_prog, opt, lo, hi, s);
        return 0;
    }
    *out = v;
    return 1;
}

int train_parse_int(const char *opt, const char *s, int lo, int hi, int *out) {
    long v;
    if (!train_parse_long(opt, s, lo, hi, &v)) return 0;
    *out = (int)v;
    return 1;
}

int train_parse_double(const char *opt, const char *s, double lo, double hi, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (!*s || *end || errno || !isfinite(v) || v < lo || v > hi) {
        fprintf(stderr, "%s: %s takes a number from %g to %g, not '%s'\n", train_prog, opt, lo, hi, s);
        return 0;
    }
    *out = v;
    return 1;
}
