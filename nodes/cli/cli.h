#ifndef EW_CLI_H
#define EW_CLI_H

#include <stdio.h>

#include "edgewise/edgewise.h"
#include "ewcolor.h"
#include "ewio.h"

/* Exit codes: 0 success, 1 the work failed (bad input file, I/O), 2 the
 * command line was wrong. */
#define EW_EXIT_FAIL 1
#define EW_EXIT_USAGE 2

int cmd_denoise(int argc, char **argv);
int cmd_info(int argc, char **argv);
int cmd_compare(int argc, char **argv);
int cmd_bench(int argc, char **argv);
/* the NBG trainer: runs train_nbg from this program's directory */
int cmd_train(int argc, char **argv);
/* edge-aware filters: cmd_filter.c, cmd_dof.c (both cli_op.c) */
int cmd_filter(int argc, char **argv);
int cmd_dof(int argc, char **argv);
/* node graphs: cmd_graph.c, cmd_nodes.c */
int cmd_graph(int argc, char **argv);
int cmd_nodes(int argc, char **argv);
/* The components of a pass ("RGBA", "RGB", "XYZ", "Z", ...; NULL if
 * absent), a pass read into a new buffer, and a count of non-finite floats. */
const char *cli_pass_comps(const ewio_file *f, const char *layer, const char *pass);
float *cli_read_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps, char *err,
                     size_t errlen);
/* When the alpha of *rgba (n interleaved RGBA pixels of pass `pass`, as
 * read from f) is one finite value everywhere and the file it was read
 * from still holds it: set the file's alpha to come from there at write
 * time, pack *rgba to RGB in place (shrunk; *rgba may move) and return 1.
 * Else 0, nothing changed. For the filters (filters_alpha in the library):
 * they give such an alpha back as it is, and the colour they compute does
 * not depend on it (its finite test passes alike; as a guide it differs by
 * zero everywhere), so the method can run on RGB with the same result. */
int cli_keep_uniform_alpha(ewio_file *f, const char *layer, const char *pass, float **rgba, size_t n);
long cli_count_nonfinite(const float *v, size_t n);

/* A command that runs one library op on one pass (cli_op.c), its options
 * generated from the op's descriptor. */
typedef struct cli_op_command {
    const char *name;   /* the command: "filter", "dof" */
    const char *kind;   /* the library kind it runs */
    const char *method; /* a fixed method, or NULL: --method picks one of kind (default: the first) */
    int pass_option;    /* 1: --pass picks the pass to run on (default: the colour) */
    const char *intro;  /* help: what the command does */
    const char *outro;  /* help: notes after the options, or NULL */
} cli_op_command;
int cli_op_run(const cli_op_command *cmd, int argc, char **argv);
/* A library name as a command-line option, without the dashes:
 * "sigma_range" + "" -> "sigma-range", "normal" + "-pass" -> "normal-pass". */
void cli_option_name(const char *name, const char *suffix, char *out, size_t len);
/* One line of a command's help for parameter k of a method, from its
 * descriptor: "--name N|F|NAME", the range or the choices, the default, the
 * hint. kind NULL: any kind. */
void cli_print_param_help(const char *kind, const char *method, int32_t k);

/* Print "edgewise: <msg>" on stderr; returns EW_EXIT_FAIL. */
int cli_fail(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Parse a positive int / float option value; print an error on failure. */
int cli_parse_int(const char *opt, const char *s, int lo, int hi, int *out);
int cli_parse_float(const char *opt, const char *s, float lo, float hi, float *out);
/* Read the colour of a file's layer (or first layer with colour when layer
 * is NULL) into a new buffer of w*h*3 floats. */
float *cli_read_color(const ewio_file *f, const char *layer, char *err, size_t errlen);
/* once: the command runs its op once and exits (filter, dof, denoise): the
 * device hands back the pages of scratch a phase of an execute is done with
 * (ew_device_desc.release_scratch), for a lower peak; not with --timings=N,
 * whose warm executes time the op with its scratch resident, as a graph
 * keeps it */
ew_device *cli_device(int threads, int once);
/* Fail early (one line, returns EW_EXIT_FAIL) when `path` cannot be
 * written: its directory is missing or not writable, or it is a directory. */
int cli_check_writable(const char *path);

/* 8-bit output (PNG, JPEG, integer TIFF) is a display image: scene-linear
 * colour goes through OpenColorIO's display/view transform first, the same
 * as the graph's `display` node with its defaults. */
typedef struct cli_view {
    const char *display, *view; /* NULL: the config's default display / its default view */
    int raw;                    /* --raw: values as they are, clipped */
    ewcolor_proc *proc;         /* built by cli_view_prepare for an 8-bit output */
} cli_view;
/* --display NAME, --view NAME, --raw at argv[*i]: 1 consumed (*i moved past
 * a value), 0 not one of them, -1 a missing value (printed). */
int cli_parse_view(int argc, char **argv, int *i, cli_view *v);
/* Before any work: the transform for out_path (unknown display/view names
 * fail here, printed). Returns 0 or EW_EXIT_USAGE. */
int cli_view_prepare(cli_view *v, const char *out_path);
void cli_view_free(cli_view *v);
/* ewio_write, with the display transform applied to an RGB(A) pass first
 * when the file would store it as integers and it was read as floats (scene
 * linear); an 8-bit input is already display-encoded and stays as it is.
 * Says what it applied on stderr unless quiet. */
int cli_write(ewio_file *f, const char *path, ewio_pixel_type type, const char *layer, const char *pass,
              const cli_view *v, int quiet, char *err, size_t errlen);

/* A progress bar on stderr while the library works: "denoise [####....]
 * 42% frame 3/48, 0:12 left", redrawn in place at most ten times a second
 * and cleared at the end. Only on a terminal and without -q: a log file or
 * a pipe gets nothing. */
typedef struct cli_progress {
    const char *what;
    int frames; /* > 1: "frame N/frames" from the fraction */
    int enabled, drawn;
    double t0, last;
    int last_frame; /* the frame last drawn */
} cli_progress;
void cli_progress_init(cli_progress *p, const char *what, int frames, int quiet);
int cli_progress_cb(void *user, double fraction); /* an ew_progress_fn; never cancels */
void cli_progress_end(cli_progress *p);           /* clear the line before other output */

/* cli_safety.c: remove --max-memory / --max-pixels (anywhere on the command
 * line) into the read limits of ewio (EDGEWISE_MAX_MEMORY / _PIXELS); 0 on a
 * bad value (message printed). And SIGINT/SIGTERM/SIGHUP: remove the
 * temporary being written, exit 128 + the signal number. */
int cli_take_limits(int *argc, char **argv);
void cli_install_signal_handlers(void);
/* fopen(path, "rb") of a regular file only (a FIFO, device or directory is
 * refused at once instead of blocking or reading forever); NULL with *why. */
FILE *cli_fopen_regular(const char *path, const char **why);
/* Before any work: the -o of an image command has a name, a supported
 * extension and is not a device or FIFO, and cli_check_writable passes. */
int cli_check_image_output(const char *path);

/* cli_timings.c: --timings[=N] (any command, taken off the command line
 * like --max-memory) prints where the run's time went on stderr at exit:
 * start-up (process creation to main), read, compute, write, total; with N,
 * the method runs N more times warm and the fastest is printed too. The
 * commands add their phases' seconds (cli_seconds) to cli_timing. */
typedef struct cli_timings {
    int enabled, warm_runs;
    double t_main, startup;     /* seconds: main's entry; from process creation to it */
    double read, compute, write;
    double warm;                /* fastest warm run, < 0 when none ran */
} cli_timings;
extern cli_timings cli_timing;
double cli_seconds(void);
void cli_return_freed_memory(void); /* malloc_trim: see cli_main.c */
int cli_take_timings(int *argc, char **argv);
void cli_print_timings(void);

#endif
