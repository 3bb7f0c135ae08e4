#ifndef EW_CLI_H
#define EW_CLI_H

#include "edgewise/edgewise.h"
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

/* Print "edgewise: <msg>" on stderr; returns EW_EXIT_FAIL. */
int cli_fail(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Parse a positive int / float option value; print an error on failure. */
int cli_parse_int(const char *opt, const char *s, int lo, int hi, int *out);
int cli_parse_float(const char *opt, const char *s, float lo, float hi, float *out);
/* Read the colour of a file's layer (or first layer with colour when layer
 * is NULL) into a new buffer of w*h*3 floats. */
float *cli_read_color(const ewio_file *f, const char *layer, char *err, size_t errlen);
ew_device *cli_device(int threads);
/* Fail early (one line, returns EW_EXIT_FAIL) when `path` cannot be
 * written: its directory is missing or not writable, or it is a directory. */
int cli_check_writable(const char *path);

#endif
