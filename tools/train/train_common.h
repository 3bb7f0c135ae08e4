/*
 * train_common.h — what the trainers (train_nbg, train_kpcn) share: files
 * read whole and written atomically, a render's colour and features, the
 * checkpoint (a weights file with the optimiser's state appended) and strict
 * option values.
 */
#ifndef EW_TRAIN_COMMON_H
#define EW_TRAIN_COMMON_H

#include <stddef.h>

#include "algorithms/train.h"
#include "src/weights.h"

/* Messages start with the program's name ("train_kpcn: ..."). */
extern const char *train_prog;

/* CLOCK_MONOTONIC in seconds. */
double train_now_s(void);

/* The whole file in a new buffer (*size its length); NULL on failure, errno
 * set (ENOENT: there is no such file). */
void *train_read_file(const char *path, size_t *size);
/* Write data to a fresh temporary file beside path, fsync it, then rename it
 * over path: a killed run or a full disk leaves the old file whole, and two
 * runs writing the same path never share a temporary. 0 or 1. */
int train_write_file_atomic(const char *path, const void *data, size_t size);

/* The colour (and with want_features the albedo, normal and depth) of the
 * first layer of an EXR that has a colour pass, in new buffers; 0, or 1
 * with the reason printed. */
int train_read_render(const char *path, int want_features, int *w, int *h, float **color, float **albedo,
                      float **normal, float **depth);

/* A checkpoint is the model's weights file (the bytes a model's save
 * function gives) with three more tensors: the Adam moments adam.m and
 * adam.v (nparams each) and train.step (two floats, step / 65536 and
 * step % 65536: exact in floats). A resumed run continues bit for bit. */
int train_checkpoint_save(const char *path, const void *model, size_t model_size, const ew_adam *adam,
                          size_t nparams, long step);
/* 0: *w holds the parsed checkpoint (the caller reads its model from it,
 * checks the architecture, then ew_weights_free), adam's moments and step
 * and *step are restored; 1: there is no file at path (start from scratch);
 * 2: it exists but cannot be used (printed: unreadable, not a weights file,
 * or its optimiser state is not nparams long — another architecture's). */
int train_checkpoint_load(const char *path, size_t nparams, ew_weights *w, ew_adam *adam, long *step);

/* The options of an optimisation run, the same in both trainers: the
 * schedule, the sampling, the threads and the checkpoints. Each program
 * sets its defaults, lists TRAIN_RUN_LONG_OPTS in its getopt_long table
 * and its own options from TRAIN_OPT_OWN on, and hands every answer to
 * train_run_option first. */
typedef struct train_run_opts {
    unsigned long seed;
    long steps, val_every, stop_after;
    int batch, patch, threads, resume;
    double lr, lr_final, clip, ckpt_minutes;
    char checkpoint[1024];
} train_run_opts;
enum {
    TRAIN_OPT_SEED = 256, TRAIN_OPT_STEPS, TRAIN_OPT_BATCH, TRAIN_OPT_PATCH, TRAIN_OPT_LR, TRAIN_OPT_LR_FINAL,
    TRAIN_OPT_CLIP, TRAIN_OPT_THREADS, TRAIN_OPT_VAL_EVERY, TRAIN_OPT_STOP_AFTER, TRAIN_OPT_CHECKPOINT,
    TRAIN_OPT_CKPT_MINUTES, TRAIN_OPT_RESUME,
    TRAIN_OPT_OWN /* a program's own options from here */
};
#define TRAIN_RUN_LONG_OPTS                                                                                          \
    {"seed", required_argument, NULL, TRAIN_OPT_SEED}, {"steps", required_argument, NULL, TRAIN_OPT_STEPS},          \
        {"batch", required_argument, NULL, TRAIN_OPT_BATCH}, {"patch", required_argument, NULL, TRAIN_OPT_PATCH},    \
        {"lr", required_argument, NULL, TRAIN_OPT_LR}, {"lr-final", required_argument, NULL, TRAIN_OPT_LR_FINAL},    \
        {"clip", required_argument, NULL, TRAIN_OPT_CLIP}, {"threads", required_argument, NULL, TRAIN_OPT_THREADS}, \
        {"val-every", required_argument, NULL, TRAIN_OPT_VAL_EVERY},                                                 \
        {"stop-after", required_argument, NULL, TRAIN_OPT_STOP_AFTER},                                               \
        {"checkpoint", required_argument, NULL, TRAIN_OPT_CHECKPOINT},                                               \
        {"checkpoint-minutes", required_argument, NULL, TRAIN_OPT_CKPT_MINUTES},                                     \
        {"resume", no_argument, NULL, TRAIN_OPT_RESUME}
/* getopt_long's answer c with value v: 1 when it is one of the run's
 * options, with *ok 0 on a bad value (printed); 0 when it is not. */
int train_run_option(int c, const char *v, train_run_opts *r, int *ok);

/* getopt_long's other answers (optstring ":h"): 'h' prints usage on stdout
 * and exits 0; a missing value (':') or an unknown option prints why and
 * returns 0. arg: argv[optind - 1], the option as given. */
int train_getopt_other(int c, const char *arg, const char *usage);
/* After getopt_long: 1, or 0 naming the first operand (the trainers take
 * none: a stray word is a mistyped option, not something to ignore). */
int train_no_operands(int argc, char **argv, const char *usage);

/* An option's value as a number in [lo, hi]: the whole string must be one
 * (no "12abc", no empty value); 1, or 0 with the reason printed. */
int train_parse_long(const char *opt, const char *s, long lo, long hi, long *out);
int train_parse_int(const char *opt, const char *s, int lo, int hi, int *out);
int train_parse_double(const char *opt, const char *s, double lo, double hi, double *out);

#endif
