/*
 * cli_op.c — a command that runs one library op on one pass of an image,
 * with every option of the op generated from its descriptor: a parameter
 * "sigma_range" is --sigma-range (range and default from the library, enum
 * parameters by choice name, a parameter a file may give as data by its
 * path), an input image "normal" is --normal-pass (default: the Cycles pass
 * that holds it), an extra output "coc" is --coc-pass. `edgewise filter`
 * (the method chosen with --method among the library's filters) and
 * `edgewise dof` (the "dof" filter) are two uses of it, so a method the
 * library adds is on the command line with no edit here.
 */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "cycles_passes.h"

#define MAX_OPTS 160
#define MAX_GIVEN 64

/* What a generated option sets. */
typedef enum { OPT_PARAM, OPT_IMAGE_PASS } opt_kind;

typedef struct {
    opt_kind kind;
    char name[48];   /* the library's parameter or image name */
    char option[56]; /* "--sigma-range", "--normal-pass" (without the dashes in long_opts) */
} gen_opt;

/* The fixed options every such command has, by getopt_long value. */
enum { FIX_OUTPUT = 'o', FIX_QUIET = 'q', FIX_HELP = 'h', FIX_METHOD = 1000, FIX_LAYER, FIX_PASS, FIX_THREADS,
       FIX_HALF, FIX_FLOAT, FIX_REFERENCE, FIX_DISPLAY, FIX_VIEW, FIX_RAW, GEN_BASE = 2000 };

typedef struct {
    const cli_op_command *cmd;
    gen_opt gen[MAX_OPTS];
    int num_gen;
    struct option long_opts[MAX_OPTS + 16];
    /* parsed */
    const char *in, *out, *method, *layer, *pass, *reference;
    int threads, quiet, method_given;
    ewio_pixel_type type;
    cli_view view; /* --display, --view, --raw: 8-bit output through the display transform */
    int given[MAX_GIVEN];        /* index into gen */
    const char *given_value[MAX_GIVEN];
    int num_given;
} parser;

/* The methods the command runs: its fixed one, or every method of its kind. */
static int32_t num_methods(const cli_op_command *c) { return c->method ? 1 : ew_method_count(c->kind); }
static const char *method_at(const cli_op_command *c, int32_t i) {
    if (c->method) return c->method;
    const char *m = NULL;
    return ew_method_get(c->kind, i, &m, NULL, NULL, NULL) == EW_OK ? m : NULL;
}

void cli_option_name(const char *name, const char *suffix, char *out, size_t len) {
    snprintf(out, len, "%s%s", name, suffix);
    for (char *c = out; *c; c++)
        if (*c == '_') *c = '-';
}

static int find_gen(const parser *p, opt_kind kind, const char *name) {
    for (int i = 0; i < p->num_gen; i++)
        if (p->gen[i].kind == kind && !strcmp(p->gen[i].name, name)) return i;
    return -1;
}

static void add_gen(parser *p, opt_kind kind, const char *name) {
    if (p->num_gen == MAX_OPTS || find_gen(p, kind, name) >= 0) return;
    gen_opt *g = &p->gen[p->num_gen++];
    g->kind = kind;
    snprintf(g->name, sizeof g->name, "%s", name);
    cli_option_name(name, kind == OPT_IMAGE_PASS ? "-pass" : "", g->option, sizeof g->option);
}

/* The fixed options, then one per parameter and per image (other than the
 * colour and the output) of every method the command may run. */
static void build_options(parser *p) {
    for (int32_t m = 0; m < num_methods(p->cmd); m++) {
        const char *method = method_at(p->cmd, m);
        ew_param_info info;
        for (int32_t k = 0; method && ew_method_param(NULL, method, k, &info) == EW_OK; k++)
            add_gen(p, OPT_PARAM, info.name);
        ew_image_info im;
        for (int32_t k = 0; method && ew_method_image(NULL, method, k, &im) == EW_OK; k++)
            if (strcmp(im.name, "color") && strcmp(im.name, "output")) add_gen(p, OPT_IMAGE_PASS, im.name);
    }
    static const struct option fixed[] = {
        {"output", required_argument, NULL, FIX_OUTPUT}, {"quiet", no_argument, NULL, FIX_QUIET},
        {"help", no_argument, NULL, FIX_HELP},           {"layer", required_argument, NULL, FIX_LAYER},
        {"pass", required_argument, NULL, FIX_PASS},     {"threads", required_argument, NULL, FIX_THREADS},
        {"half", no_argument, NULL, FIX_HALF},           {"float", no_argument, NULL, FIX_FLOAT},
        {"reference", required_argument, NULL, FIX_REFERENCE},
        {"display", required_argument, NULL, FIX_DISPLAY}, {"view", required_argument, NULL, FIX_VIEW},
        {"raw", no_argument, NULL, FIX_RAW},
    };
    int n = 0;
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        if (fixed[i].val == FIX_PASS && !p->cmd->pass_option) continue;
        p->long_opts[n++] = fixed[i];
    }
    /* --method chooses the op, unless the op has a parameter of that name
     * (the dof command's "method" is the DoF's own) */
    if (!p->cmd->method) p->long_opts[n++] = (struct option){"method", required_argument, NULL, FIX_METHOD};
    for (int i = 0; i < p->num_gen; i++)
        p->long_opts[n++] = (struct option){p->gen[i].option, required_argument, NULL, GEN_BASE + i};
    p->long_opts[n] = (struct option){NULL, 0, NULL, 0};
}

/* The Cycles passes that hold a library image, in the order looked for:
 * the only per-image knowledge of the command, and about Blender's pass
 * names, not about any method. An image not listed is read only from a
 * pass named on the command line. */
static const char *const *cli_default_passes(const char *image) {
    static const char *const normal[] = {"Denoising Normal", "Normal", NULL};
    static const char *const depth[] = {"Depth", "Denoising Depth", NULL};
    static const char *const albedo[] = {"Denoising Albedo", "DiffCol", NULL};
    static const char *const vector[] = {"Vector", NULL};
    if (!strcmp(image, "normal")) return normal;
    if (!strcmp(image, "depth")) return depth;
    if (!strcmp(image, "albedo")) return albedo;
    if (!strcmp(image, "vector")) return vector;
    return NULL;
}

/* ---- help, generated ---- */

void cli_print_param_help(const char *kind, const char *method, int32_t k) {
    ew_param_info info;
    if (ew_method_param(kind, method, k, &info) != EW_OK) return;
    char opt[64], arg[16];
    cli_option_name(info.name, "", opt, sizeof opt);
    int32_t nc = ew_method_param_num_choices(kind, method, k);
    const char *data = ew_method_param_data(kind, method, k);
    snprintf(arg, sizeof arg, "%s", nc > 0 ? (data ? "NAME|FILE" : "NAME") : info.type == EW_PARAM_FLOAT ? "F" : "N");
    char head[96];
    snprintf(head, sizeof head, "  --%s %s", opt, arg);
    printf("%-28s", head);
    if (nc > 0) {
        for (int32_t c = 0; c < nc; c++) printf("%s%s", c ? ", " : "", ew_method_param_choice(kind, method, k, c));
        if (data) printf(", or a file");
        printf(" (default %s): ", ew_method_param_choice(kind, method, k, (int32_t)info.default_value));
    } else if (info.type == EW_PARAM_FLOAT) {
        printf("%g..%g (default %g): ", (double)info.min_value, (double)info.max_value, (double)info.default_value);
    } else {
        printf("%d..%d (default %d): ", (int)info.min_value, (int)info.max_value, (int)info.default_value);
    }
    printf("%s\n", info.hint ? info.hint : "");
}

static void print_help(const cli_op_command *c) {
    printf("usage: edgewise %s IN -o OUT [options]\n\n%s\n", c->name, c->intro);
    printf("PNG and JPEG are 8-bit display images: the linear colour goes through\n"
           "OpenColorIO's display/view transform first, as the graph's `display` node\n"
           "does (config: $OCIO, else Blender's, else a built-in sRGB), so the file\n"
           "looks as the render does in Blender. An 8-bit input (PNG, JPEG) is already\n"
           "display-encoded and is written as it is. TIFF and EXR keep linear floats.\n\n");
    printf("options:\n");
    printf("  -o, --output FILE           output file (required; not IN)\n");
    if (!c->method) {
        printf("  --method NAME               the library's %s: ", c->kind);
        for (int32_t i = 0; i < num_methods(c); i++) printf("%s%s", i ? ", " : "", method_at(c, i));
        printf(" (default %s)\n", method_at(c, 0));
    }
    printf("  --layer NAME                view layer (default: the first with a colour pass)\n");
    if (c->pass_option)
        printf("  --pass NAME                 pass to filter (default: the colour the file shows: Combined)\n");
    printf("  --threads N                 worker threads, 0 = all cores (default 0)\n");
    printf("  --half | --float            EXR pixel type of written passes (default: as read)\n");
    printf("  --reference REF             also print PSNR/SSIM of input and output against REF\n");
    printf("  --display NAME              PNG/JPEG output: OpenColorIO display (default: the config's)\n");
    printf("  --view NAME                 PNG/JPEG output: view transform (default: the display's, e.g. Standard)\n");
    printf("  --raw                       PNG/JPEG output: linear values clipped to 0..1, no display transform\n");
    printf("  -q, --quiet                 print errors only (and no progress bar, shown on a terminal)\n");
    printf("  -h, --help                  this text\n");
    for (int32_t m = 0; m < num_methods(c); m++) {
        const char *method = method_at(c, m);
        const char *summary = NULL;
        int32_t ni = 0, np = 0;
        for (int32_t i = 0; method && i < ew_method_count(NULL); i++) {
            const char *nm = NULL;
            if (ew_method_get(NULL, i, &nm, &summary, &ni, &np) == EW_OK && !strcmp(nm, method)) break;
        }
        printf("\n%s%s: %s\n", c->method ? "" : "--method ", method, summary ? summary : "");
        ew_image_info im;
        for (int32_t k = 0; k < ni; k++) {
            uint32_t fl = 0;
            if (ew_method_image(NULL, method, k, &im) != EW_OK || !strcmp(im.name, "color") ||
                !strcmp(im.name, "output"))
                continue;
            ew_method_image_flags(NULL, method, k, &fl);
            char opt[64], head[96];
            cli_option_name(im.name, "-pass", opt, sizeof opt);
            snprintf(head, sizeof head, "  --%s NAME", opt);
            const char *const *defaults = cli_default_passes(im.name);
            printf("%-28s%s%s", head, fl & EW_IMAGE_OUTPUT ? "(an output, into pass NAME) " : im.required ? "(required) " : "",
                   im.hint ? im.hint : "");
            if (!(fl & EW_IMAGE_OUTPUT) && defaults && defaults[0]) {
                printf(" [default:");
                for (int d = 0; defaults[d]; d++) printf("%s %s", d ? "," : "", defaults[d]);
                printf("]");
            }
            printf("\n");
        }
        for (int32_t k = 0; k < np; k++) cli_print_param_help(NULL, method, k);
    }
    if (c->outro) printf("\n%s", c->outro);
}

/* ---- parsing ---- */

static int parse(parser *p, int argc, char **argv) {
    build_options(p);
    p->method = p->cmd->method ? p->cmd->method : method_at(p->cmd, 0);
    opterr = 0;
    optind = 1;
    int c, idx = -1;
    while ((c = getopt_long(argc, argv, ":o:qh", p->long_opts, &idx)) != -1) {
        const char *opt = argv[optind - 1];
        switch (c) {
        case FIX_OUTPUT: p->out = optarg; break;
        case FIX_QUIET: p->quiet = 1; break;
        case FIX_HELP: print_help(p->cmd); exit(0);
        case FIX_METHOD: p->method = optarg; p->method_given = 1; break;
        case FIX_LAYER: p->layer = optarg; break;
        case FIX_PASS: p->pass = optarg; break;
        case FIX_THREADS: if (!cli_parse_int("--threads", optarg, 0, 1024, &p->threads)) return 0; break;
        case FIX_HALF: p->type = EWIO_HALF; break;
        case FIX_FLOAT: p->type = EWIO_FLOAT; break;
        case FIX_REFERENCE: p->reference = optarg; break;
        case FIX_DISPLAY: p->view.display = optarg; break;
        case FIX_VIEW: p->view.view = optarg; break;
        case FIX_RAW: p->view.raw = 1; break;
        case ':':
            fprintf(stderr, "edgewise: %s needs a value\n", opt);
            return 0;
        case '?':
            fprintf(stderr, "edgewise: unknown option '%s' (see 'edgewise %s --help')\n", opt, p->cmd->name);
            return 0;
        default:
            if (c >= GEN_BASE && c < GEN_BASE + p->num_gen) {
                if (p->num_given == MAX_GIVEN) {
                    fprintf(stderr, "edgewise: too many options\n");
                    return 0;
                }
                p->given[p->num_given] = c - GEN_BASE;
                p->given_value[p->num_given++] = optarg;
            }
            break;
        }
    }
    for (int i = optind; i < argc; i++) {
        if (!p->in) p->in = argv[i];
        else {
            fprintf(stderr, "edgewise: unexpected argument '%s'\n", argv[i]);
            return 0;
        }
    }
    if (!p->in) {
        fprintf(stderr, "edgewise: %s needs an input file (see 'edgewise %s --help')\n", p->cmd->name, p->cmd->name);
        return 0;
    }
    if (!p->out) {
        fprintf(stderr, "edgewise: %s needs an output file: -o OUT\n", p->cmd->name);
        return 0;
    }
    const char *kind = ew_method_kind(p->method);
    if (!kind || strcmp(kind, p->cmd->kind) != 0) {
        char names[512];
        size_t used = 0;
        names[0] = '\0';
        for (int32_t i = 0; i < num_methods(p->cmd) && used < sizeof names; i++) {
            int k = snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "", method_at(p->cmd, i));
            if (k > 0) used += (size_t)k;
        }
        fprintf(stderr, "edgewise: unknown --method '%s' (%s)\n", p->method, names);
        return 0;
    }
    return 1;
}

/* ---- the method's parameters from the command line ---- */

static int32_t param_index(const char *method, const char *name) {
    ew_param_info info;
    for (int32_t k = 0; ew_method_param(NULL, method, k, &info) == EW_OK; k++)
        if (!strcmp(info.name, name)) return k;
    return -1;
}

static int32_t image_index(const char *method, const char *name) {
    ew_image_info im;
    for (int32_t k = 0; ew_method_image(NULL, method, k, &im) == EW_OK; k++)
        if (!strcmp(im.name, name)) return k;
    return -1;
}

static int read_bytes(const char *path, unsigned char **out, size_t *len) {
    const char *why = "";
    FILE *fp = cli_fopen_regular(path, &why); /* a FIFO would block, a device never end */
    if (!fp) return -1;
    unsigned char *buf = NULL;
    size_t n = 0, cap = 0;
    for (;;) {
        if (n == cap) {
            cap = cap ? cap * 2 : 65536;
            if (cap > ((size_t)1 << 28) + 65536) { /* the weights format's own bound */
                free(buf);
                fclose(fp);
                return -1;
            }
            unsigned char *nb = (unsigned char *)realloc(buf, cap);
            if (!nb) {
                free(buf);
                fclose(fp);
                return -1;
            }
            buf = nb;
        }
        size_t k = fread(buf + n, 1, cap - n, fp);
        n += k;
        if (k == 0) break;
    }
    fclose(fp);
    *out = buf;
    *len = n;
    return 0;
}

/* Check every given parameter against the method (usage errors, exit 2)
 * and set them on op; a file given for a parameter that takes data is
 * loaded with set_data (a library error, exit 1). Returns 0, EW_EXIT_USAGE
 * or EW_EXIT_FAIL. */
static int set_params(const parser *p, ew_op *op, ew_device *dev, int check_only) {
    for (int i = 0; i < p->num_given; i++) {
        const gen_opt *g = &p->gen[p->given[i]];
        const char *v = p->given_value[i];
        if (g->kind != OPT_PARAM) continue;
        int32_t k = param_index(p->method, g->name);
        if (k < 0) {
            fprintf(stderr, "edgewise: %s '%s' has no parameter --%s (see 'edgewise %s --help')\n", p->cmd->kind,
                    p->method, g->option, p->cmd->name);
            return EW_EXIT_USAGE;
        }
        ew_param_info info;
        ew_method_param(NULL, p->method, k, &info);
        char opt[64];
        snprintf(opt, sizeof opt, "--%s", g->option);
        int32_t nc = ew_method_param_num_choices(NULL, p->method, k);
        const char *data = ew_method_param_data(NULL, p->method, k);
        ew_result r = EW_OK;
        if (nc > 0) {
            int32_t choice = ew_method_param_choice_index(NULL, p->method, k, v);
            if (choice < 0 && data) { /* a file instead of a built-in choice */
                if (check_only) continue;
                unsigned char *bytes = NULL;
                size_t len = 0;
                if (read_bytes(v, &bytes, &len) != 0)
                    return cli_fail("%s: cannot open '%s' (expected one of the names in 'edgewise %s --help' or a "
                                    "file)",
                                    opt, v, p->cmd->name);
                r = ew_op_set_data(op, data, bytes, len);
                free(bytes);
                if (r != EW_OK) return cli_fail("%s '%s': %s", opt, v, ew_device_last_error(dev));
                continue;
            }
            if (choice < 0) {
                char names[256];
                size_t used = 0;
                names[0] = '\0';
                for (int32_t c = 0; c < nc && used < sizeof names; c++) {
                    int n = snprintf(names + used, sizeof names - used, "%s%s", c ? ", " : "",
                                     ew_method_param_choice(NULL, p->method, k, c));
                    if (n > 0) used += (size_t)n;
                }
                fprintf(stderr, "edgewise: unknown %s '%s' (%s%s)\n", opt, v, names, data ? ", or a file" : "");
                return EW_EXIT_USAGE;
            }
            if (!check_only) r = ew_op_set_int(op, info.name, choice);
        } else if (info.type == EW_PARAM_FLOAT) {
            float f;
            if (!cli_parse_float(opt, v, info.min_value, info.max_value, &f)) return EW_EXIT_USAGE;
            if (!check_only) r = ew_op_set_float(op, info.name, f);
        } else {
            int n;
            if (!cli_parse_int(opt, v, (int)info.min_value, (int)info.max_value, &n)) return EW_EXIT_USAGE;
            if (!check_only) r = ew_op_set_int(op, info.name, n);
        }
        if (r != EW_OK) return cli_fail("%s %s: %s", opt, v, ew_device_last_error(dev));
    }
    for (int i = 0; i < p->num_given; i++) {
        const gen_opt *g = &p->gen[p->given[i]];
        if (g->kind == OPT_IMAGE_PASS && image_index(p->method, g->name) < 0) {
            fprintf(stderr, "edgewise: %s '%s' has no image '%s' (--%s)\n", p->cmd->kind, p->method, g->name,
                    g->option);
            return EW_EXIT_USAGE;
        }
    }
    return 0;
}

static const char *given_pass(const parser *p, const char *image) {
    const char *v = NULL;
    for (int i = 0; i < p->num_given; i++)
        if (p->gen[p->given[i]].kind == OPT_IMAGE_PASS && !strcmp(p->gen[p->given[i]].name, image))
            v = p->given_value[i];
    return v;
}

/* ---- running ---- */

#define MAX_IMAGES 8

/* Decode, in one pass over the file, the pass the method runs on (its
 * components `comps`, straight into `pix`) and the passes its other input
 * images will be read from (as the loop that binds them picks them: the
 * given pass, else the first default the layer has); every other pass
 * stays in the file and is copied from it when the result is written. A
 * pass this misses is still decoded when it is read. */
static int load_used_passes(const parser *p, ewio_file *f, const char *method, const char *layer, const char *pass,
                            const char *comps, float *pix, char *err, size_t errlen) {
    ewio_pass_ref refs[MAX_IMAGES + 1];
    int n = 0;
    refs[n++] = (ewio_pass_ref){layer, pass, comps, pix};
    ew_image_info im;
    for (int32_t k = 0; k < MAX_IMAGES && ew_method_image(NULL, method, k, &im) == EW_OK; k++) {
        uint32_t fl = 0;
        ew_method_image_flags(NULL, method, k, &fl);
        if (!strcmp(im.name, "color") || !strcmp(im.name, "output") || (fl & EW_IMAGE_OUTPUT)) continue;
        const char *src = given_pass(p, im.name);
        if (src && !cli_pass_comps(f, layer, src)) src = NULL;
        const char *const *defaults = cli_default_passes(im.name);
        for (int d = 0; !src && defaults && defaults[d]; d++)
            if (cli_pass_comps(f, layer, defaults[d])) src = defaults[d];
        if (src) refs[n++] = (ewio_pass_ref){layer, src, NULL, NULL};
    }
    return ewio_load_passes(f, refs, n, err, errlen);
}

static int same_file(const char *a, const char *b) {
    struct stat sa, sb;
    if (stat(a, &sa) == 0 && stat(b, &sb) == 0) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    return strcmp(a, b) == 0;
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The components an image of `channels` is written as. */
static const char *comps_for(int channels) {
    static const char *const c[] = {"Z", "XY", "RGB", "RGBA"};
    return c[(channels < 1 ? 1 : channels > 4 ? 4 : channels) - 1];
}


/* Everything after parsing: read, bind, run, report, write. */
static int execute(const parser *p) {
    const cli_op_command *cmd = p->cmd;
    const char *method = p->method, *in_path = p->in, *out_path = p->out, *want_layer = p->layer;
    const char *want_pass = p->pass, *reference = p->reference;
    const int threads = p->threads, quiet = p->quiet;
    const ewio_pixel_type type = p->type;
    char err[1024];
    ewio_file *f = NULL;
    const double t_read = cli_seconds();
    ewio_set_threads(threads); /* the read decodes on them too (the device comes after) */
    /* the passes the method does not use stay in the file (load_used_passes) */
    if (ewio_open(in_path, &f, err, sizeof err) != 0) return cli_fail("%s", err); /* err names the file */
    int rc = EW_EXIT_FAIL;
    float *pix = NULL, *out = NULL, *bufs[MAX_IMAGES] = {NULL};
    ew_device *dev = NULL;
    ew_op *op = NULL;
    const int w = ewio_width(f), h = ewio_height(f);
    const size_t n = (size_t)w * (size_t)h;
    char bound[256] = "";
    size_t bound_used = 0;
    ew_image_info info_color;

    /* the layer and the pass to run on */
    ew_layer_passes lp;
    int found = 0;
    if (want_layer) {
        found = ew_find_image_passes(f, want_layer, &lp, err, sizeof err) == 0;
        if (!found && !want_pass) { cli_fail("%s", err); goto done; }
    } else {
        for (int i = 0; i < ewio_num_layers(f) && !found; i++)
            found = ew_find_image_passes(f, ewio_layer_name(f, i), &lp, err, sizeof err) == 0;
    }
    const char *layer = want_layer ? want_layer : found ? lp.layer : ewio_layer_name(f, 0);
    const char *pass = want_pass ? want_pass : found ? lp.color : NULL;
    if (!pass) { cli_fail("'%s' has no colour pass to %s (%s); name one with --pass", in_path, cmd->name, err); goto done; }
    const char *comps = cli_pass_comps(f, layer, pass);
    if (!comps) { cli_fail("layer '%s' has no pass '%s'", layer, pass); goto done; }
    int C = (int)strlen(comps);
    if (!(pix = (float *)ew_host_alloc(n * (size_t)C * sizeof(float)))) { cli_fail("out of memory"); goto done; }
    if (load_used_passes(p, f, method, layer, pass, comps, pix, err, sizeof err) != 0) { cli_fail("%s", err); goto done; }
    long bad = cli_count_nonfinite(pix, n * (size_t)C);
    /* An alpha of one value everywhere (a render without a transparent
     * film) stays in the file and the method runs on RGB: the filters give
     * such an alpha back as it is, and their colour does not depend on it
     * (cli_keep_uniform_alpha). One float a pixel less while it works. */
    const int alpha_in_file = C == 4 && cli_keep_uniform_alpha(f, layer, pass, &pix, n);
    if (alpha_in_file) {
        comps = "RGB";
        C = 3;
    }
    /* a method that may filter in place writes over the pass read for it
     * (one frame less in memory), unless the input is still wanted for the
     * reference scores */
    uint32_t color_flags = 0;
    for (int32_t k = 0; ew_method_image(NULL, method, k, &info_color) == EW_OK; k++)
        if (!strcmp(info_color.name, "color")) ew_method_image_flags(NULL, method, k, &color_flags);
    if ((color_flags & EW_IMAGE_INPLACE) && !reference) out = pix;
    else if (!(out = (float *)ew_host_alloc(n * (size_t)C * sizeof(float)))) { cli_fail("out of memory"); goto done; }

    if (!(dev = cli_device(threads, 1))) goto done;
    if (ew_op_create(dev, method, &op) != EW_OK) { cli_fail("%s", ew_device_last_error(dev)); goto done; }
    ew_image vin = ew_image_packed(pix, w, h, C), vout = ew_image_packed(out, w, h, C);
    ew_result r = ew_op_set_image(op, "color", &vin);
    if (r == EW_OK) r = ew_op_set_image(op, "output", &vout);
    if (r != EW_OK) { cli_fail("%s '%s': %s", cmd->kind, method, ew_device_last_error(dev)); goto done; }

    /* every other image: an input from its pass (given, else the Cycles
     * pass that holds it, if the layer has one); an extra output when asked
     * for with its option */
    const char *out_pass[MAX_IMAGES] = {NULL};
    ew_image_info info_im;
    for (int32_t k = 0; k < MAX_IMAGES && ew_method_image(NULL, method, k, &info_im) == EW_OK; k++) {
        const ew_image_info *im = &info_im;
        if (!strcmp(im->name, "color") || !strcmp(im->name, "output")) continue;
        uint32_t fl = 0;
        ew_method_image_flags(NULL, method, k, &fl);
        const char *given = given_pass(p, im->name);
        if (fl & EW_IMAGE_OUTPUT) {
            if (!given) continue;
            const int ch = im->min_channels > 0 ? im->min_channels : 1;
            if (!(bufs[k] = (float *)ew_host_alloc(n * (size_t)ch * sizeof(float)))) { cli_fail("out of memory"); goto done; }
            ew_image v = ew_image_packed(bufs[k], w, h, ch);
            if ((r = ew_op_set_image(op, im->name, &v)) != EW_OK) break;
            out_pass[k] = given;
            continue;
        }
        const char *src = NULL;
        if (given) {
            if (!cli_pass_comps(f, layer, given)) { cli_fail("layer '%s' has no %s pass '%s'", layer, im->name, given); goto done; }
            src = given;
        } else {
            const char *const *defaults = cli_default_passes(im->name);
            for (int d = 0; defaults && defaults[d] && !src; d++)
                if (cli_pass_comps(f, layer, defaults[d])) src = defaults[d];
            if (!src && im->required) {
                char looked[160] = "";
                size_t used = 0;
                for (int d = 0; defaults && defaults[d]; d++) {
                    int kk = snprintf(looked + used, sizeof looked - used, "%s%s", d == 0 ? "" : defaults[d + 1] ? ", " : " and ",
                                      defaults[d]);
                    if (kk > 0 && (size_t)kk < sizeof looked - used) used += (size_t)kk;
                }
                char opt[64];
                cli_option_name(im->name, "-pass", opt, sizeof opt);
                cli_fail("layer '%s' of '%s' has no %s pass%s%s%s: name one with --%s", layer[0] ? layer : "(image)",
                         in_path, im->name, used ? " (looked for " : "", looked, used ? ")" : "", opt);
                goto done;
            }
        }
        if (!src) continue;
        const char *sc = cli_pass_comps(f, layer, src);
        const int nc = (int)strlen(sc);
        if (!(bufs[k] = cli_read_pass(f, layer, src, sc, err, sizeof err))) { cli_fail("%s", err); goto done; }
        /* the method reads its copy; the file's goes back to the source,
         * which still holds these values, and the write copies them from
         * there (the colour pass keeps its own handling: it gets the result) */
        if (strcmp(src, pass) != 0 && ewio_pass_in_source(f, layer, src, sc) &&
            ewio_set_pass_from_source(f, layer, src, sc, src, err, sizeof err) != 0) {
            cli_fail("%s", err);
            goto done;
        }
        /* as many channels as the pass has, up to 4; a pass with more
         * components than the image reads is read from its first ones */
        ew_image v = ew_image_packed(bufs[k], w, h, nc > 4 ? 4 : nc);
        v.pixel_stride = (int64_t)nc * (int64_t)sizeof(float);
        if (v.channels < im->min_channels) {
            cli_fail("pass '%s' has %d components; image '%s' needs %d", src, nc, im->name, im->min_channels);
            goto done;
        }
        if ((r = ew_op_set_image(op, im->name, &v)) != EW_OK) break;
        int kk = snprintf(bound + bound_used, sizeof bound - bound_used, ", %s", im->name);
        if (kk > 0 && (size_t)kk < sizeof bound - bound_used) bound_used += (size_t)kk;
    }
    if (r != EW_OK) { cli_fail("%s '%s': %s", cmd->kind, method, ew_device_last_error(dev)); goto done; }
    if (set_params(p, op, dev, 0) != 0) goto done;

    /* the pass is in pix now and gets the result back (ewio_lend_pass): the
     * file need not hold it too while the method works (a file read whole,
     * as a PNG, holds it) */
    ewio_release_pass(f, layer, pass, comps);
    cli_return_freed_memory();

    cli_progress prog;
    cli_progress_init(&prog, method, 1, quiet);
    ew_op_set_progress(op, cli_progress_cb, &prog);
    double t0 = now_s();
    cli_timing.read += t0 - t_read; /* the file, its passes, the device and op set up */
    r = ew_op_commit(op);
    if (r == EW_OK) r = ew_op_execute(op);
    double dt = now_s() - t0;
    cli_timing.compute += dt;
    cli_progress_end(&prog);

    if (r != EW_OK) { cli_fail("%s '%s' failed: %s", cmd->kind, method, ew_device_last_error(dev)); goto done; }
    if (!quiet) {
        /* what ran: the method and every parameter's value, read back */
        char params[512] = "";
        size_t used = 0;
        ew_param_info info;
        for (int32_t k = 0; ew_method_param(NULL, method, k, &info) == EW_OK && used < sizeof params; k++) {
            float v = 0.0f;
            ew_op_get_float(op, info.name, &v);
            const char *choice = ew_method_param_choice(NULL, method, k, (int32_t)v);
            int kk = choice ? snprintf(params + used, sizeof params - used, "%s%s %s", k ? ", " : "", info.name, choice)
                            : snprintf(params + used, sizeof params - used, "%s%s %g", k ? ", " : "", info.name, (double)v);
            if (kk > 0) used += (size_t)kk;
        }
        fprintf(stderr, "edgewise: %s '%s' of layer '%s' (%dx%d%s; %s) in %.3f s\n", method, pass,
                layer[0] ? layer : "(image)", w, h, bound, params, dt);
        for (int32_t k = 0; k < MAX_IMAGES; k++) {
            if (!out_pass[k]) continue;
            ew_image_info im;
            ew_method_image(NULL, method, k, &im);
            const int ch = im.min_channels > 0 ? im.min_channels : 1;
            float lo = 0.0f, hi = 0.0f;
            for (size_t i = 0; i < n * (size_t)ch; i++) {
                lo = i == 0 || bufs[k][i] < lo ? bufs[k][i] : lo;
                hi = i == 0 || bufs[k][i] > hi ? bufs[k][i] : hi;
            }
            fprintf(stderr, "edgewise: %s '%s' (pass '%s') ranges from %g to %g\n", method, im.name, out_pass[k],
                    (double)lo, (double)hi);
        }
        if (bad) fprintf(stderr, "edgewise: %ld non-finite samples in '%s' were treated as missing\n", bad, pass);
    }
    /* the results are in out and bufs: the op's memory goes before they are
     * put into the file (unless --timings=N runs it again, or the reference
     * is scored on the device) */
    if (!cli_timing.warm_runs && !reference) {
        ew_op_destroy(op);
        op = NULL;
        ew_device_destroy(dev);
        dev = NULL;
    }
    /* the file writes the results from out and bufs, which stay until then */
    if (ewio_lend_pass(f, layer, pass, comps, out, err, sizeof err) != 0) { cli_fail("%s", err); goto done; }
    for (int32_t k = 0; k < MAX_IMAGES; k++) {
        if (!out_pass[k]) continue;
        ew_image_info im;
        ew_method_image(NULL, method, k, &im);
        if (ewio_lend_pass(f, layer, out_pass[k], comps_for(im.min_channels), bufs[k], err, sizeof err) != 0) {
            cli_fail("%s", err);
            goto done;
        }
    }
    ewio_set_attribute(f, "edgewise.version", ew_version_string());
    if (reference) {
        ewio_file *ref = NULL;
        if (ewio_read(reference, &ref, err, sizeof err) != 0) { cli_fail("reference: %s", err); goto done; }
        float *pr = cli_read_color(ref, NULL, err, sizeof err);
        if (!pr || ewio_width(ref) != w || ewio_height(ref) != h || C < 3) {
            free(pr);
            ewio_free(ref);
            cli_fail("reference '%s' must be a %dx%d colour image to compare with the colour", reference, w, h);
            goto done;
        }
        ew_image vr = ew_image_packed(pr, w, h, 3), vo = vout, vi = vin;
        vo.channels = vi.channels = 3;
        vo.pixel_stride = vi.pixel_stride = (int64_t)C * (int64_t)sizeof(float);
        double p0 = 0, p1 = 0, s0 = 0, s1 = 0;
        ew_image_psnr(dev, &vi, &vr, &p0);
        ew_image_psnr(dev, &vo, &vr, &p1);
        ew_image_ssim(dev, &vi, &vr, &s0);
        ew_image_ssim(dev, &vo, &vr, &s1);
        printf("vs reference: input PSNR %.2f dB SSIM %.4f -> output PSNR %.2f dB SSIM %.4f\n", p0, s0, p1, s1);
        free(pr);
        ewio_free(ref);
    }
    /* what the method used and the file does not write from goes before
     * the write, which needs memory of its own */
    if (!cli_timing.warm_runs) {
        ew_op_destroy(op);
        op = NULL;
        ew_device_destroy(dev);
        dev = NULL;
        if (out != pix) {
            free(pix);
            pix = NULL;
        }
        for (int k = 0; k < MAX_IMAGES; k++) {
            if (out_pass[k]) continue;
            free(bufs[k]);
            bufs[k] = NULL;
        }
        cli_return_freed_memory();
    }
    const double t_write = cli_seconds();
    if (cli_write(f, out_path, type, layer, pass, &p->view, quiet, err, sizeof err) != 0) {
        cli_fail("cannot write '%s': %s", out_path, err);
        goto done;
    }
    cli_timing.write += cli_seconds() - t_write;
    /* --timings=N: the same work again in this process, after the file is
     * written (an op filtering in place runs on its own output then: the
     * time, not the result, is wanted) */
    ew_op_set_progress(op, NULL, NULL);
    for (int k = 0; k < cli_timing.warm_runs; k++) {
        double tw = now_s();
        if (ew_op_execute(op) != EW_OK) break;
        tw = now_s() - tw;
        if (cli_timing.warm < 0.0 || tw < cli_timing.warm) cli_timing.warm = tw;
    }
    if (!quiet) fprintf(stderr, "edgewise: wrote %s\n", out_path);
    rc = 0;
done:
    ew_op_destroy(op);
    ew_device_destroy(dev);
    ewio_free(f);
    if (out != pix) free(out);
    free(pix);
    for (int k = 0; k < MAX_IMAGES; k++) free(bufs[k]);
    return rc;
}

int cli_op_run(const cli_op_command *cmd, int argc, char **argv) {
    parser *p = (parser *)calloc(1, sizeof *p);
    if (!p) return cli_fail("out of memory");
    p->cmd = cmd;
    int rc = EW_EXIT_USAGE;
    if (!parse(p, argc, argv)) goto out;
    if ((rc = set_params(p, NULL, NULL, 1)) != 0) goto out;
    rc = EW_EXIT_FAIL;
    if (same_file(p->in, p->out)) {
        cli_fail("refusing to write the output over the input '%s': choose another -o", p->in);
        goto out;
    }
    /* the reference is scored against after the write: it must survive it */
    if (p->reference && same_file(p->reference, p->out)) {
        cli_fail("refusing to write the output over the reference '%s': choose another -o", p->reference);
        goto out;
    }
    if (cli_check_image_output(p->out) != 0) goto out;
    /* display and view names are checked before any work */
    if (cli_view_prepare(&p->view, p->out) != 0) {
        rc = EW_EXIT_USAGE;
        goto out;
    }
    rc = execute(p);
out:
    cli_view_free(&p->view);
    free(p);
    return rc;
}
