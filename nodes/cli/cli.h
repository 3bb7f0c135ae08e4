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
/* the NBG trainer (issue 3): runs train_nbg from this program's directory */
int cmd_train(int argc, char **argv);
/* edge-aware filters (issue 4): cmd_filter.c, cmd_dof.c */
int cmd_filter(int argc, char **argv);
int cmd_dof(int argc, char **argv);
/* node graphs (issue 5): cmd_graph.c, cmd_nodes.c */
int cmd_graph(int argc, char **argv);
int cmd_nodes(int argc, char **argv);
/* helpers of cmd_filter.c shared with cmd_dof.c: the components of a pass
 * ("RGBA", "RGB", "XYZ", "Z", ...; NULL if absent), a pass read into a new
 * buffer, --weights (trained / analytic: *set_int = 1 / 0; a file: loaded
 * with set_data, *set_int = -1), and a count of non-finite floats */
const char *cli_pass_comps(const ewio_file *f, const char *layer, const char *pass);
float *cli_read_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps, char *err,
                     size_t errlen);
int cli_set_weights(ew_filter *flt, ew_device *dev, const char *spec, int *set_int);
long cli_count_nonfinite(const float *v, size_t n);

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
