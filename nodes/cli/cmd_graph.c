/*
 * edgewise graph — run or check a node graph file (docs/graphs.md).
 */
#define _DEFAULT_SOURCE /* realpath */
#include <errno.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "edgewise/nodes.h"

static const char help[] =
    "usage: edgewise graph run FILE [options]\n"
    "       edgewise graph check FILE [options]\n"
    "\n"
    "Run a node graph file (JSON, see docs/graphs.md), or only validate it: node\n"
    "types, parameters, connections, frame files, passes of the first frame, and\n"
    "that no output would replace one of the graph's inputs. Frame sequences run\n"
    "one frame at a time; a failure stops the run, frames already written stay.\n"
    "\n"
    "options:\n"
    "  --frames A-B            frames to run (or a single frame A); overrides the file\n"
    "  --set NODE.PARAM=VALUE  set a parameter (repeatable), e.g. --set dn.spatial_rate=12\n"
    "  --threads N             worker threads, 0 = all cores (default 0)\n"
    "  --report FILE           write the run's report (JSON: files written, metrics)\n"
    "  -q, --quiet             print errors only (and no progress bar, shown on a terminal)\n"
    "  -h, --help              this text\n"
    "\n"
    "On Dask (python3 -m edgewise.distributed; docs/distributed.md): chunks of frames\n"
    "as tasks, resumable, outputs renamed into place when complete:\n"
    "  --scheduler ADDRESS     a Dask scheduler, e.g. tcp://head:8786\n"
    "  --workers N             a local Dask cluster of N worker processes\n"
    "  --chunk N, --warmup N   frames per task; frames run first for temporal filters\n"
    "\n"
    "Node types and their parameters: edgewise nodes\n";

#define MAX_SETS 64

typedef struct {
    int check_only, quiet, threads, have_frames, first, last, num_sets;
    const char *file, *report;
    const char *sets[MAX_SETS];
} options;

static int parse_frames(const char *s, int *a, int *b) {
    char *end;
    long x = strtol(s, &end, 10), y = x;
    if (end == s) return 0;
    if (*end == '-') {
        const char *t = end + 1;
        y = strtol(t, &end, 10);
        if (end == t) return 0;
    }
    if (*end != '\0' || x < 0 || y < x || y > 100000000) return 0;
    *a = (int)x;
    *b = (int)y;
    return 1;
}

static int parse(int argc, char **argv, options *o) {
    memset(o, 0, sizeof *o);
    if (argc < 2) {
        fprintf(stderr, "edgewise: graph needs a subcommand: run or check (see 'edgewise graph --help')\n");
        return 0;
    }
    if (!strcmp(argv[1], "-h") || !strcmp(argv[1], "--help")) {
        fputs(help, stdout);
        exit(0);
    }
    if (!strcmp(argv[1], "check")) o->check_only = 1;
    else if (strcmp(argv[1], "run") != 0) {
        fprintf(stderr, "edgewise: unknown graph subcommand '%s' (run, check)\n", argv[1]);
        return 0;
    }
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            fputs(help, stdout);
            exit(0);
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            o->quiet = 1;
        } else if (!strcmp(a, "--frames") || !strcmp(a, "--set") || !strcmp(a, "--threads") || !strcmp(a, "--report")) {
            if (!val) {
                fprintf(stderr, "edgewise: %s needs a value\n", a);
                return 0;
            }
            i++;
            if (!strcmp(a, "--frames")) {
                if (!parse_frames(val, &o->first, &o->last)) {
                    fprintf(stderr, "edgewise: --frames expects A-B or A (0 <= A <= B), got '%s'\n", val);
                    return 0;
                }
                o->have_frames = 1;
            } else if (!strcmp(a, "--set")) {
                const char *dot = strchr(val, '.'), *eq = dot ? strchr(dot, '=') : NULL;
                if (!dot || !eq || dot == val || eq == dot + 1) {
                    fprintf(stderr, "edgewise: --set expects NODE.PARAM=VALUE, got '%s'\n", val);
                    return 0;
                }
                if (o->num_sets == MAX_SETS) {
                    fprintf(stderr, "edgewise: at most %d --set options\n", MAX_SETS);
                    return 0;
                }
                o->sets[o->num_sets++] = val;
            } else if (!strcmp(a, "--threads")) {
                if (!cli_parse_int(a, val, 0, 1024, &o->threads)) return 0;
            } else {
                o->report = val;
            }
        } else if (a[0] == '-' && a[1] != '\0') {
            fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise graph --help')\n", a);
            return 0;
        } else if (!o->file) {
            o->file = a;
        } else {
            fprintf(stderr, "edgewise: unexpected argument '%s'\n", a);
            return 0;
        }
    }
    if (!o->file) {
        fprintf(stderr, "edgewise: graph %s needs a graph file (see 'edgewise graph --help')\n", argv[1]);
        return 0;
    }
    return 1;
}

/* One line per frame on stdout from the run's report. */
static void print_summary(const char *report) {
    json_t *root = json_loads(report, 0, NULL);
    json_t *frames = json_object_get(root, "frames");
    size_t i;
    json_t *fr;
    json_array_foreach(frames, i, fr) {
        printf("frame %lld:", (long long)json_integer_value(json_object_get(fr, "frame")));
        json_t *w = json_object_get(fr, "written"), *m = json_object_get(fr, "metrics");
        size_t k;
        json_t *v;
        const char *id;
        json_object_foreach(json_object_get(fr, "methods"), id, v) printf(" %s: %s;", id, json_string_value(v));
        json_array_foreach(w, k, v) printf(" wrote %s;", json_string_value(v));
        json_object_foreach(m, id, v) {
            json_t *p = json_object_get(v, "psnr"), *s = json_object_get(v, "ssim");
            if (json_is_null(p)) printf(" %s: PSNR inf dB", id);
            else printf(" %s: PSNR %.2f dB", id, json_number_value(p));
            printf(" SSIM %.4f;", json_number_value(s));
        }
        printf(" %.3f s\n", json_number_value(json_object_get(fr, "seconds")));
    }
    json_decref(root);
}

/* The report goes through the same atomic write as images: a full disk
 * leaves no empty or cut file, an existing report stays as it was. */
static int write_report(const char *path, const char *text) {
    size_t n = strlen(text);
    char *buf = (char *)malloc(n + 2);
    if (!buf) return cli_fail("out of memory");
    memcpy(buf, text, n);
    buf[n] = '\n';
    char err[1024];
    int bad = ewio_write_text(path, buf, n + 1, err, sizeof err);
    free(buf);
    if (bad) return cli_fail("the report: %s", err);
    return 0;
}

/* `graph run` with --scheduler or --workers goes to Dask: the Python package
 * (edgewise.distributed) takes the same arguments and runs the graph there,
 * so frames are parsed and run in one place for both. */
static int wants_dask(int argc, char **argv) {
    if (argc < 2 || strcmp(argv[1], "run") != 0) return 0;
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "--set") || !strcmp(argv[i], "--frames") || !strcmp(argv[i], "--report")) i++;
        else if (!strcmp(argv[i], "--scheduler") || !strcmp(argv[i], "--workers") ||
                 !strncmp(argv[i], "--scheduler=", 12) || !strncmp(argv[i], "--workers=", 10))
            return 1;
    }
    return 0;
}

static int run_on_dask(int argc, char **argv) {
    const char *py = getenv("EDGEWISE_PYTHON");
    if (!py || !py[0]) py = EW_CLI_PYTHON3;
    /* the libraries this program runs with: $ORIGIN/../lib, as its RUNPATH */
    char self[PATH_MAX], dir[PATH_MAX + 32];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n > 0 && !getenv("EDGEWISE_LIB")) {
        self[n] = '\0';
        char *slash = strrchr(self, '/');
        if (slash) *slash = '\0';
        snprintf(dir, sizeof dir, "%s/../lib/libedgewise_nodes.so", self);
        if (access(dir, R_OK) == 0) {
            dir[strlen(dir) - strlen("/libedgewise_nodes.so")] = '\0';
            setenv("EDGEWISE_LIB", dir, 1);
        }
    }
    /* the package of the source tree this program was built from, when it is there */
    if (access(EW_CLI_PYTHON_DIR "/edgewise/distributed.py", R_OK) == 0) {
        const char *old = getenv("PYTHONPATH");
        char *pp = (char *)malloc(strlen(EW_CLI_PYTHON_DIR) + (old ? strlen(old) : 0) + 2);
        if (!pp) return cli_fail("out of memory");
        sprintf(pp, "%s%s%s", EW_CLI_PYTHON_DIR, old && old[0] ? ":" : "", old && old[0] ? old : "");
        setenv("PYTHONPATH", pp, 1);
        free(pp);
    }
    char **args = (char **)calloc((size_t)argc + 4, sizeof *args);
    if (!args) return cli_fail("out of memory");
    args[0] = (char *)py;
    args[1] = (char *)"-m";
    args[2] = (char *)"edgewise.distributed";
    for (int i = 1; i < argc; i++) args[i + 2] = argv[i];
    fflush(stdout);
    execvp(py, args);
    const int e = errno;
    free(args);
    return cli_fail("cannot run %s for --scheduler/--workers: %s (it needs Python 3 with numpy and Dask: Debian "
                    "python3-distributed; $EDGEWISE_PYTHON picks the interpreter)", py, strerror(e));
}

/* Same file, by inode when both exist, else by resolved directory + name
 * (ew_graph_check_side_file's rule). */
static int same_path(const char *a, const char *b) {
    struct stat sa, sb;
    if (stat(a, &sa) == 0 && stat(b, &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    char ra[4096], rb[4096];
    return realpath(a, ra) && realpath(b, rb) && !strcmp(ra, rb);
}

int cmd_graph(int argc, char **argv) {
    if (wants_dask(argc, argv)) return run_on_dask(argc, argv);
    options o;
    if (!parse(argc, argv, &o)) return EW_EXIT_USAGE;
    ew_device *dev = cli_device(o.threads, 0);
    if (!dev) return EW_EXIT_FAIL;
    ew_graph *g = NULL;
    int rc = EW_EXIT_FAIL;
    if (ew_graph_create(dev, &g) != EW_OK) {
        cli_fail("out of memory");
        goto done;
    }
    if (ew_graph_load_file(g, o.file) != EW_OK) {
        cli_fail("%s", ew_graph_last_error(g));
        goto done;
    }
    for (int i = 0; i < o.num_sets; i++)
        if (ew_graph_set_assignment(g, o.sets[i]) != EW_OK) {
            cli_fail("--set %s: %s", o.sets[i], ew_graph_last_error(g));
            rc = EW_EXIT_USAGE;
            goto done;
        }
    if (o.have_frames && ew_graph_set_frames(g, o.first, o.last) != EW_OK) {
        cli_fail("%s", ew_graph_last_error(g));
        goto done;
    }
    if (ew_graph_validate(g) != EW_OK) {
        cli_fail("%s: %s", o.file, ew_graph_last_error(g));
        goto done;
    }
    /* the report is one more output of the run: never an input, the graph
     * file or an image the run writes */
    if (o.report) {
        if (same_path(o.report, o.file)) {
            cli_fail("refusing to write the report over the graph file '%s': choose another --report", o.file);
            rc = EW_EXIT_USAGE;
            goto done;
        }
        if (ew_graph_check_side_file(g, o.report) != EW_OK) {
            cli_fail("refusing to write the report: %s: choose another --report", ew_graph_last_error(g));
            rc = EW_EXIT_USAGE;
            goto done;
        }
        if (cli_check_writable(o.report) != 0) goto done;
    }
    if (o.check_only) {
        ew_graph_stats st;
        ew_graph_get_stats(g, &st);
        if (!o.quiet) printf("%s: valid\n", o.file);
        rc = 0;
        goto done;
    }
    cli_progress prog;
    cli_progress_init(&prog, "graph", ew_graph_frame_count(g), o.quiet);
    ew_graph_set_progress(g, cli_progress_cb, &prog);
    ew_result r = ew_graph_run(g);
    cli_progress_end(&prog);
    if (!o.quiet) print_summary(ew_graph_report(g));
    if (o.report && write_report(o.report, ew_graph_report(g)) != 0) goto done;
    if (r != EW_OK) {
        cli_fail("%s", ew_graph_last_error(g));
        goto done;
    }
    rc = 0;
done:
    ew_graph_destroy(g);
    ew_device_destroy(dev);
    return rc;
}
